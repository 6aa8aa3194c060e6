// What the viewer draws besides the bodies: props (spheres, boxes, capsules, meshes) along their
// trajectories, force and impulse arrows over time, the centre of mass with its ground projection and
// the support polygon, joint trails and onion skins. World convention: Z up, metres, seconds;
// quaternions arrive as (w, x, y, z).

import * as THREE from 'three';

const _v = new THREE.Vector3();
const _w = new THREE.Vector3();
const _q = new THREE.Quaternion();
const Y_AXIS = new THREE.Vector3(0, 1, 0);

export function flatMaterial(color, opts = {}) {
  return new THREE.MeshBasicMaterial({ color, ...opts });
}

// An arrow (shaft + head) pointing from a to b: shared by forces.
export function arrowMesh(mat) {
  const g = new THREE.Group();
  const shaft = new THREE.Mesh(new THREE.CylinderGeometry(1, 1, 1, 8), mat);
  const head = new THREE.Mesh(new THREE.ConeGeometry(1, 1, 12), mat);
  g.add(shaft, head);
  g.userData = { shaft, head };
  return g;
}

export function pointArrow(arrow, a, b, r) {
  const { shaft, head } = arrow.userData;
  _v.subVectors(b, a);
  const len = Math.max(_v.length(), 1e-6);
  _v.divideScalar(len);
  const hl = Math.min(0.35 * len, 6 * r);
  arrow.position.copy(a);
  arrow.quaternion.setFromUnitVectors(Y_AXIS, _v);
  shaft.scale.set(r, len - hl, r);
  shaft.position.set(0, (len - hl) / 2, 0);
  head.scale.set(2.4 * r, hl, 2.4 * r);
  head.position.set(0, len - hl / 2, 0);
}

// ------------------------------------------------------------------------------------------ props

function propGeometry(p) {
  const s = p.size;
  if (p.shape === 'sphere') return new THREE.SphereGeometry(s[0], 24, 16);
  if (p.shape === 'box') return new THREE.BoxGeometry(2 * s[0], 2 * s[1], 2 * s[2]);
  if (p.shape === 'capsule') return new THREE.CapsuleGeometry(s[0], 2 * s[1], 6, 16).rotateX(Math.PI / 2);
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.Float32BufferAttribute(p.vertices, 3));
  g.setIndex(p.faces);
  g.computeVertexNormals();
  return g;
}

export class Prop {
  // spec: the page's prop entry; pos: Float32Array (F * 3) decoded centres. software: WebGL runs on
  // the CPU (then a Lambert material, as the bodies get: several times cheaper than a physical one).
  constructor(spec, pos, floor, software = false) {
    this.spec = spec;
    this.pos = pos;
    this.F = spec.frames;
    // Translucent objects (the walls of a room) let the characters behind them show.
    const see = spec.opacity !== undefined && spec.opacity < 1
      ? { transparent: true, opacity: spec.opacity, depthWrite: false } : {};
    this.mesh = new THREE.Mesh(propGeometry(spec), software ? new THREE.MeshLambertMaterial({ color: spec.color, ...see })
      : new THREE.MeshStandardMaterial({ color: spec.color, roughness: 0.6, metalness: 0.05, ...see }));
    if (see.transparent) this.mesh.renderOrder = 6;
    this.mesh.name = `prop ${spec.label || spec.shape}`;
    this.shadow = null;
    this.group = new THREE.Group();
    this.group.add(this.mesh);
    if (spec.trail && this.F > 1) {
      const g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.BufferAttribute(pos.slice(), 3));
      this.trail = new THREE.Line(g, new THREE.LineDashedMaterial({ color: spec.color, dashSize: 0.06, gapSize: 0.04,
        transparent: true, opacity: 0.8 }));
      this.trail.computeLineDistances();
      this.trail.frustumCulled = false;
      this.group.add(this.trail);
    }
    // A blob shadow under objects that move (still ones stand where they are: walls, tables).
    const r = spec.shape === 'box' ? Math.max(spec.size[0], spec.size[1]) : spec.size[0] || 0.1;
    this.shadow = new THREE.Mesh(new THREE.CircleGeometry(r, 24),
      new THREE.MeshBasicMaterial({ color: 0x000000, transparent: true, opacity: 0.16, depthWrite: false }));
    this.shadow.renderOrder = 1;
    this.shadow.visible = this.F > 1;
    this.group.add(this.shadow);
    this.floor = floor;
    this.current = new THREE.Vector3();
    this.visible = false;
  }

  update(t, opts) {
    const s = this.spec;
    const f = (t - s.start) * s.fps;
    const inside = f >= -1e-6 && f <= this.F - 1 + 1e-6;
    const on = opts.props !== false && (inside || !s.hide);
    this.group.visible = on;
    this.visible = on;
    if (!on) return;
    const ff = Math.min(Math.max(f, 0), this.F - 1);
    const i0 = Math.floor(ff), i1 = Math.min(i0 + 1, this.F - 1), a = ff - i0, p = this.pos;
    this.current.set(p[3 * i0] + a * (p[3 * i1] - p[3 * i0]), p[3 * i0 + 1] + a * (p[3 * i1 + 1] - p[3 * i0 + 1]),
      p[3 * i0 + 2] + a * (p[3 * i1 + 2] - p[3 * i0 + 2]));
    this.mesh.position.copy(this.current);
    if (s.quat) {
      const q = s.quat, k = 4 * Math.round(ff);
      _q.set(q[k + 1], q[k + 2], q[k + 3], q[k]);
      this.mesh.quaternion.copy(_q);
    }
    this.shadow.position.set(this.current.x, this.current.y, this.floor + 0.004);
  }
}

// ------------------------------------------------------------------------------------------ forces

// Arrows of one Forces entry: each drawn from its time for `hold` seconds, ending at its point, with
// a dot at the point of contact.
export class Forces {
  constructor(spec, sphGeo) {
    this.spec = spec;
    this.group = new THREE.Group();
    this.mat = new THREE.MeshBasicMaterial({ color: spec.color, transparent: true, opacity: 0.95 });
    this.pool = [];
    this.sphGeo = sphGeo;
    this.shown = 0;
  }

  arrow(i) {
    while (this.pool.length <= i) {
      const a = arrowMesh(this.mat);
      const dot = new THREE.Mesh(this.sphGeo, this.mat);
      dot.scale.setScalar(0.03);
      const g = new THREE.Group();
      g.add(a, dot);
      g.userData = { arrow: a, dot };
      this.group.add(g);
      this.pool.push(g);
    }
    return this.pool[i];
  }

  update(t, opts) {
    const s = this.spec, ts = s.t;
    let n = 0;
    if (opts.forces !== false) {
      // first index with ts[i] > t - hold (times are sorted)
      let lo = 0, hi = ts.length;
      while (lo < hi) { const m = (lo + hi) >> 1; if (ts[m] <= t - s.hold) lo = m + 1; else hi = m; }
      for (let i = lo; i < ts.length && ts[i] <= t + 1e-4 && n < 64; i++, n++) {
        const g = this.arrow(n);
        const P = _v.set(s.points[3 * i], s.points[3 * i + 1], s.points[3 * i + 2]);
        _w.set(s.vectors[3 * i], s.vectors[3 * i + 1], s.vectors[3 * i + 2]);
        const mag = _w.length();
        const len = Math.min(Math.max(mag * s.scale, 0.05), 1.0);
        if (mag > 1e-12) _w.multiplyScalar(len / mag); else _w.set(0, 0, len);
        const A = new THREE.Vector3().subVectors(P, _w);
        pointArrow(g.userData.arrow, A, P, 0.012);
        g.userData.dot.position.copy(P);
        g.visible = true;
      }
    }
    for (let i = n; i < this.pool.length; i++) this.pool[i].visible = false;
    this.shown = n;
  }
}

// ------------------------------------------------------------------------------------------ balance

// Centre of mass of a capsule body of uniform density (the same as kinodyn.viz.objects.centre_of_mass):
// each bone weighs pi r^2 L + 4/3 pi r^3 at its middle.
export function centreOfMass(cur, parents, radius, out) {
  let x = 0, y = 0, z = 0, wsum = 0;
  for (let p = 0; p < parents.length; p++) {
    const q = parents[p], r = radius[p];
    if (q < 0 || !(r > 0)) continue;
    const dx = cur[3 * p] - cur[3 * q], dy = cur[3 * p + 1] - cur[3 * q + 1], dz = cur[3 * p + 2] - cur[3 * q + 2];
    const L = Math.sqrt(dx * dx + dy * dy + dz * dz);
    const w = Math.PI * r * r * L + (4 / 3) * Math.PI * r * r * r;
    x += w * 0.5 * (cur[3 * p] + cur[3 * q]);
    y += w * 0.5 * (cur[3 * p + 1] + cur[3 * q + 1]);
    z += w * 0.5 * (cur[3 * p + 2] + cur[3 * q + 2]);
    wsum += w;
  }
  if (wsum <= 0) return out.set(cur[0], cur[1], cur[2]);
  return out.set(x / wsum, y / wsum, z / wsum);
}

// Convex hull (Andrew's monotone chain) of 2-D points [[x, y], ...], counter-clockwise.
export function convexHull(pts) {
  const p = pts.slice().sort((a, b) => a[0] - b[0] || a[1] - b[1]);
  if (p.length < 3) return p;
  const cross = (o, a, b) => (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
  const lower = [], upper = [];
  for (const q of p) {
    while (lower.length >= 2 && cross(lower[lower.length - 2], lower[lower.length - 1], q) <= 0) lower.pop();
    lower.push(q);
  }
  for (let i = p.length - 1; i >= 0; i--) {
    const q = p[i];
    while (upper.length >= 2 && cross(upper[upper.length - 2], upper[upper.length - 1], q) <= 0) upper.pop();
    upper.push(q);
  }
  return lower.slice(0, -1).concat(upper.slice(0, -1));
}

export function insideHull(hull, x, y) {
  if (hull.length < 3) return false;
  for (let i = 0; i < hull.length; i++) {
    const a = hull[i], b = hull[(i + 1) % hull.length];
    if ((b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]) < -1e-9) return false;
  }
  return true;
}

const MAX_HULL = 32;

// Centre of mass (a ball), its ground projection (a cross-hair disc, green inside the support polygon,
// red outside), a vertical line between them, and the support polygon of the feet in contact.
export class Balance {
  constructor(color, sphGeo, floor) {
    this.group = new THREE.Group();
    this.com = new THREE.Mesh(sphGeo, new THREE.MeshBasicMaterial({ color: 0x111111 }));
    this.com.scale.setScalar(0.04);
    this.ground = new THREE.Mesh(new THREE.RingGeometry(0.025, 0.05, 20),
      new THREE.MeshBasicMaterial({ color: 0x2ca02c, side: THREE.DoubleSide, depthWrite: false }));
    this.ground.renderOrder = 3;
    const lg = new THREE.BufferGeometry();
    lg.setAttribute('position', new THREE.BufferAttribute(new Float32Array(6), 3));
    this.line = new THREE.Line(lg, new THREE.LineDashedMaterial({ color: 0x111111, dashSize: 0.04, gapSize: 0.03 }));
    this.line.frustumCulled = false;
    const pg = new THREE.BufferGeometry();
    pg.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * (MAX_HULL + 1)), 3));
    const idx = [];
    for (let i = 1; i < MAX_HULL; i++) idx.push(0, i, i + 1);
    pg.setIndex(idx);
    this.poly = new THREE.Mesh(pg, new THREE.MeshBasicMaterial({ color, transparent: true, opacity: 0.35,
      side: THREE.DoubleSide, depthWrite: false }));
    this.poly.renderOrder = 2;
    this.poly.frustumCulled = false;
    const og = new THREE.BufferGeometry();
    og.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * (MAX_HULL + 1)), 3));
    this.outline = new THREE.Line(og, new THREE.LineBasicMaterial({ color }));
    this.outline.frustumCulled = false;
    this.group.add(this.com, this.ground, this.line, this.poly, this.outline);
    this.floor = floor;
    this.c = new THREE.Vector3();
    this.hull = [];
    this.inside = false;
  }

  // cur: the pose; feetOn: [[point indices] of each foot in contact].
  update(ch, opts, feetOn) {
    const showCom = !!opts.com, showSup = !!opts.support;
    this.group.visible = showCom || showSup;
    if (!this.group.visible) return;
    const cur = ch.cur, z0 = this.floor;
    centreOfMass(cur, ch.spec.parents, ch.spec.radius, this.c);
    const pts = [];
    for (const idx of feetOn) for (const p of idx) pts.push([cur[3 * p], cur[3 * p + 1]]);
    const hull = convexHull(pts).slice(0, MAX_HULL);
    if (hull.length === 1 || hull.length === 2) {  // a point or a segment: a thin polygon around it
      const [a, b] = [hull[0], hull[hull.length - 1]];
      hull.splice(0, hull.length, [a[0] - 0.01, a[1] - 0.01], [b[0] + 0.01, b[1] - 0.01], [b[0] + 0.01, b[1] + 0.01],
        [a[0] - 0.01, a[1] + 0.01]);
    }
    this.hull = hull;
    this.inside = insideHull(hull, this.c.x, this.c.y);
    this.com.visible = this.ground.visible = this.line.visible = showCom;
    this.com.position.copy(this.c);
    this.ground.position.set(this.c.x, this.c.y, z0 + 0.01);
    this.ground.material.color.set(this.inside ? 0x2ca02c : 0xd62728);
    const la = this.line.geometry.attributes.position;
    la.setXYZ(0, this.c.x, this.c.y, this.c.z);
    la.setXYZ(1, this.c.x, this.c.y, z0 + 0.01);
    la.needsUpdate = true;
    this.line.computeLineDistances();
    const n = hull.length;
    this.poly.visible = this.outline.visible = showSup && n >= 3;
    if (!this.poly.visible) return;
    const pa = this.poly.geometry.attributes.position, oa = this.outline.geometry.attributes.position;
    for (let i = 0; i <= MAX_HULL; i++) {
      const h = hull[Math.min(i, n - 1)];
      pa.setXYZ(i, h[0], h[1], z0 + 0.007);
      const o = hull[i % n];
      oa.setXYZ(i, o[0], o[1], z0 + 0.008);
    }
    this.poly.geometry.setDrawRange(0, 3 * (n - 2));
    this.outline.geometry.setDrawRange(0, n + 1);
    pa.needsUpdate = oa.needsUpdate = true;
  }
}

// ------------------------------------------------------------------------------------------ trails, onion skins

const TRAIL_S = 1.0, TRAIL_N = 40;

// Paths of a character's extremities (the points with no child: hands, feet, head) over the last
// second, fading out.
export class Trails {
  constructor(ch) {
    const kids = new Uint8Array(ch.P);
    for (const p of ch.spec.parents) if (p >= 0) kids[p] = 1;
    this.points = [];
    for (let p = 0; p < ch.P; p++) if (!kids[p]) this.points.push(p);
    this.group = new THREE.Group();
    this.lines = this.points.map(() => {
      const g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * TRAIL_N), 3));
      const col = new Float32Array(3 * TRAIL_N);
      const c = new THREE.Color(ch.spec.color), bg = new THREE.Color(0xdfe6ee);
      for (let i = 0; i < TRAIL_N; i++) {
        const k = new THREE.Color().copy(bg).lerp(c, i / (TRAIL_N - 1));
        col[3 * i] = k.r; col[3 * i + 1] = k.g; col[3 * i + 2] = k.b;
      }
      g.setAttribute('color', new THREE.BufferAttribute(col, 3));
      const l = new THREE.Line(g, new THREE.LineBasicMaterial({ vertexColors: true }));
      l.frustumCulled = false;
      this.group.add(l);
      return l;
    });
  }

  update(ch, t, opts, sample) {
    this.group.visible = !!opts.trails;
    if (!this.group.visible) return;
    const tmp = this.tmp || (this.tmp = new Float32Array(ch.P * 3));
    const attrs = this.lines.map((l) => l.geometry.attributes.position);
    for (let i = 0; i < TRAIL_N; i++) {
      sample(ch, t - TRAIL_S + (TRAIL_S * i) / (TRAIL_N - 1), tmp);
      this.points.forEach((p, k) => attrs[k].setXYZ(i, tmp[3 * p], tmp[3 * p + 1], tmp[3 * p + 2]));
    }
    for (const a of attrs) a.needsUpdate = true;
  }
}

const ONION_DT = [-0.45, -0.3, -0.15, 0.15, 0.3, 0.45];

// Onion skins: the poses 0.15, 0.3 and 0.45 s before (the character's colour, darker) and after
// (lighter), as bone lines fading with distance in time.
export class Onion {
  constructor(ch) {
    this.group = new THREE.Group();
    this.skins = ONION_DT.map((dt) => {
      const g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(ch.bones.length * 6), 3));
      const base = new THREE.Color(ch.spec.color);
      const col = dt < 0 ? base.clone().multiplyScalar(0.6) : base.clone().lerp(new THREE.Color(0xffffff), 0.35);
      const l = new THREE.LineSegments(g, new THREE.LineBasicMaterial({ color: col, transparent: true,
        opacity: 0.85 - 1.2 * Math.abs(dt), depthWrite: false }));
      l.frustumCulled = false;
      l.userData.dt = dt;
      this.group.add(l);
      return l;
    });
  }

  update(ch, t, opts, sample) {
    this.group.visible = !!opts.onion;
    if (!this.group.visible) return;
    const tmp = this.tmp || (this.tmp = new Float32Array(ch.P * 3));
    for (const l of this.skins) {
      sample(ch, t + l.userData.dt, tmp);
      const a = l.geometry.attributes.position.array;
      let n = 0;
      for (const p of ch.bones) {
        const q = ch.spec.parents[p];
        a[n] = tmp[3 * q]; a[n + 1] = tmp[3 * q + 1]; a[n + 2] = tmp[3 * q + 2];
        a[n + 3] = tmp[3 * p]; a[n + 4] = tmp[3 * p + 1]; a[n + 5] = tmp[3 * p + 2];
        n += 6;
      }
      l.geometry.attributes.position.needsUpdate = true;
    }
  }
}
