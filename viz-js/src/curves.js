// The curves panel: speed of a character's extremities (hands, feet, head), its root height and its
// foot heights over the scene's time, with the current time marked. Drawn once per character choice
// on a canvas; the time mark is a composited div moved each frame (nothing is repainted).

const SPEED_COLORS = ['#4e79a7', '#f28e2b', '#e15759', '#76b7b2', '#59a14f', '#b07aa1', '#9c755f'];

// Series of one character: {t: Float32Array (F) scene times, speeds: [{name, v}], heights: [{name, v}]}.
export function characterCurves(ch, floor) {
  const F = ch.F, P = ch.P, P3 = 3 * P, pos = ch.pos, fps = ch.spec.fps;
  const names = ch.spec.pointNames || [];
  const t = new Float32Array(F);
  for (let f = 0; f < F; f++) t[f] = ch.spec.start + f / fps;
  const kids = new Uint8Array(P);
  for (const p of ch.spec.parents) if (p >= 0) kids[p] = 1;
  const leaves = [];
  for (let p = 0; p < P; p++) if (!kids[p]) leaves.push(p);
  const speeds = leaves.map((p) => {
    const v = new Float32Array(F);
    for (let f = 0; f < F; f++) {
      const a = Math.max(f - 1, 0), b = Math.min(f + 1, F - 1);
      if (b === a) continue;
      const dx = pos[b * P3 + 3 * p] - pos[a * P3 + 3 * p], dy = pos[b * P3 + 3 * p + 1] - pos[a * P3 + 3 * p + 1];
      const dz = pos[b * P3 + 3 * p + 2] - pos[a * P3 + 3 * p + 2];
      v[f] = (Math.sqrt(dx * dx + dy * dy + dz * dz) * fps) / (b - a);
    }
    return { name: (names[p] || `point ${p}`).replace(/_end$/, ''), v };
  });
  const heights = [];
  const root = new Float32Array(F);
  for (let f = 0; f < F; f++) root[f] = pos[f * P3 + 2] - floor;
  heights.push({ name: 'root', v: root });
  for (const side of ['left', 'right']) {
    const idx = (ch.spec.feet || {})[side];
    if (!idx || !idx.length) continue;
    const v = new Float32Array(F);
    for (let f = 0; f < F; f++) {
      let m = Infinity;
      for (const p of idx) m = Math.min(m, pos[f * P3 + 3 * p + 2]);
      v[f] = m - floor;
    }
    heights.push({ name: `${side} foot`, v });
  }
  return { t, speeds, heights };
}

function niceMax(x) {
  if (!(x > 0)) return 1;
  const e = 10 ** Math.floor(Math.log10(x)), m = x / e;
  return (m <= 1 ? 1 : m <= 2 ? 2 : m <= 5 ? 5 : 10) * e;
}

// Draw the two plots (speeds above, heights below) on the canvas; returns the x mapping for the mark.
export function drawCurves(cv, curves, duration, title) {
  const dpr = window.devicePixelRatio || 1;
  const w = cv.clientWidth, h = cv.clientHeight;
  cv.width = Math.round(w * dpr);
  cv.height = Math.round(h * dpr);
  const ctx = cv.getContext('2d');
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  ctx.clearRect(0, 0, w, h);
  ctx.fillStyle = 'rgba(255,255,255,0.93)';
  ctx.fillRect(0, 0, w, h);
  ctx.font = '11px system-ui, sans-serif';
  ctx.textBaseline = 'middle';
  const x0 = 40, x1 = w - 96, D = Math.max(duration, 1e-6);
  const X = (t) => x0 + ((x1 - x0) * t) / D;
  ctx.fillStyle = '#1d2430';
  ctx.fillText(`${title}: speed and height`, 6, 9);
  const plots = [
    { series: curves.speeds, unit: 'm/s', label: 'speed', top: 20, bottom: h / 2 - 6 },
    { series: curves.heights, unit: 'm', label: 'height', top: h / 2 + 10, bottom: h - 16 },
  ];
  for (const pl of plots) {
    let vmax = 0;
    for (const s of pl.series) for (const v of s.v) vmax = Math.max(vmax, v);
    vmax = niceMax(vmax);
    const Y = (v) => pl.bottom - ((pl.bottom - pl.top) * Math.max(v, 0)) / vmax;
    ctx.strokeStyle = '#c9d0d8';
    ctx.lineWidth = 1;
    ctx.strokeRect(x0, pl.top, x1 - x0, pl.bottom - pl.top);
    ctx.fillStyle = '#55606d';
    ctx.fillText(`${vmax.toPrecision(2)} ${pl.unit}`, 2, pl.top + 5);
    ctx.fillText('0', 28, pl.bottom - 4);
    pl.series.forEach((s, k) => {
      const col = SPEED_COLORS[k % SPEED_COLORS.length];
      ctx.strokeStyle = col;
      ctx.lineWidth = 1.4;
      ctx.beginPath();
      const n = s.v.length, step = Math.max(1, Math.floor(n / (2 * (x1 - x0))));
      for (let f = 0; f < n; f += step) {
        const x = X(curves.t[f]), y = Y(s.v[f]);
        if (f === 0) ctx.moveTo(x, y); else ctx.lineTo(x, y);
      }
      ctx.stroke();
      ctx.fillStyle = col;
      ctx.fillRect(x1 + 6, pl.top + 2 + 12 * k, 9, 3);
      ctx.fillStyle = '#1d2430';
      ctx.fillText(s.name, x1 + 18, pl.top + 4 + 12 * k, 78);
    });
  }
  ctx.fillStyle = '#55606d';
  ctx.fillText('0 s', x0 - 6, h - 6);
  ctx.fillText(`${duration.toFixed(1)} s`, x1 - 22, h - 6);
  return { x0, x1 };
}

// Values of every series at scene time t (the panel's state, for tests and the console).
export function curvesAt(curves, t) {
  const n = curves.t.length;
  let f = 0;
  if (n > 1) {
    const fps = (n - 1) / Math.max(curves.t[n - 1] - curves.t[0], 1e-9);
    f = Math.min(Math.max(Math.round((t - curves.t[0]) * fps), 0), n - 1);
  }
  const out = {};
  for (const s of curves.speeds) out[`speed ${s.name}`] = s.v[f];
  for (const s of curves.heights) out[`height ${s.name}`] = s.v[f];
  return out;
}
