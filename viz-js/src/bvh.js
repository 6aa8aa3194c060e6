// A BVH file dropped on the page becomes a character: three.js's BVHLoader parses it, an animation
// mixer samples every frame, and the world positions of joints and end sites are converted to the
// viewer's convention (Z up, metres: BVH is Y up, usually in centimetres or inches; the unit is the one
// that makes the body closest to 1.7 m tall, and the axes are turned as kinodyn.io.bvh turns them).

import * as THREE from 'three';
import { BVHLoader } from 'three/addons/loaders/BVHLoader.js';

const UNITS = [1.0, 0.01, 0.001, 0.0254, 0.0254 / 0.45];  // m, cm, mm, inch, CMU's unit

const LEFT = /^(left|l(?=[A-Z_])|l_)|Left|_[lL]$/;
const RIGHT = /^(right|r(?=[A-Z_])|r_)|Right|_[rR]$/;

export function sideOf(name) {
  const n = name.replace(/_end$/, '');
  return LEFT.test(n) ? -1 : RIGHT.test(n) ? 1 : 0;
}

function radiusOf(name, len) {
  const n = name.toLowerCase();
  if (/head.*_end$/.test(n)) return 0.095;
  if (/(finger|thumb|hand.*_end|toe.*_end)/.test(n)) return 0.026;
  if (/(spine|chest|back|torso|pelvis|hips)/.test(n)) return 0.1;
  if (/(upleg|thigh|femur)/.test(n)) return 0.075;
  return Math.min(0.065, Math.max(0.025, 0.16 * len));
}

// Returns a character entry of the page's format (without encoded data) and its positions
// Float32Array (F * P * 3).
export function bvhCharacter(text, name, color) {
  const { skeleton, clip } = new BVHLoader().parse(text);
  const bones = skeleton.bones;
  const root = bones[0];
  const P = bones.length;
  const index = new Map(bones.map((b, i) => [b, i]));
  const parents = bones.map((b) => (index.has(b.parent) ? index.get(b.parent) : -1));
  const names = bones.map((b, i) => (b.name === 'ENDSITE' ? `${bones[parents[i]].name}_end` : b.name));
  const track = clip.tracks[0];
  const F = track ? track.times.length : 1;
  const dt = track && F > 1 ? track.times[1] - track.times[0] : 1 / 30;
  // BVHLoader adds the root's OFFSET to its position channels; the channels alone place the root (as
  // kinodyn.io.bvh reads them).
  const o = root.position.clone();
  const mixer = new THREE.AnimationMixer(root);
  const action = mixer.clipAction(clip);
  action.setLoop(THREE.LoopOnce, 1);
  action.clampWhenFinished = true;  // the last frame is at the clip's end: hold it, do not wrap to the first
  action.play();
  const raw = new Float32Array(F * P * 3);
  const v = new THREE.Vector3();
  for (let f = 0; f < F; f++) {
    mixer.setTime(Math.min(f * dt, clip.duration));
    root.updateMatrixWorld(true);
    for (let p = 0; p < P; p++) {
      bones[p].getWorldPosition(v);
      const k = 3 * (f * P + p);
      v.sub(o);
      raw[k] = v.z; raw[k + 1] = v.x; raw[k + 2] = v.y;  // a Y-up file's x, y, z are kinodyn's y, z, x
    }
  }
  // Unit: the height of the first frame closest to 1.7 m.
  let zlo = Infinity, zhi = -Infinity;
  for (let p = 0; p < P; p++) { zlo = Math.min(zlo, raw[3 * p + 2]); zhi = Math.max(zhi, raw[3 * p + 2]); }
  const size = Math.max(zhi - zlo, 1e-9);
  const scale = UNITS.reduce((best, u) => (Math.abs(Math.log((size * u) / 1.7)) < Math.abs(Math.log((size * best) / 1.7)) ? u : best), 1);
  for (let i = 0; i < raw.length; i++) raw[i] *= scale;
  const radius = names.map((n, p) => {
    if (parents[p] < 0) return 0;
    const a = 3 * parents[p], b = 3 * p;
    const len = Math.hypot(raw[b] - raw[a], raw[b + 1] - raw[a + 1], raw[b + 2] - raw[a + 2]);
    return radiusOf(n, len);
  });
  const feet = {};
  for (const [side, re] of [['left', LEFT], ['right', RIGHT]]) {
    const idx = [];
    names.forEach((n, p) => { if (re.test(n.replace(/_end$/, '')) && /(foot|toe|ankle)/i.test(n)) idx.push(p); });
    if (idx.length) feet[side] = idx;
  }
  const sides = names.map(sideOf);
  const head = Math.max(0, names.findIndex((n) => /head/i.test(n) && !/_end$/.test(n)));
  let face = {};
  for (const word of [/(shoulder|clavicle|collar)/i, /(arm|humerus)/i, /(upleg|thigh|femur|hip)/i]) {
    const l = names.findIndex((n, p) => sides[p] === -1 && word.test(n) && !/_end$/.test(n));
    if (l < 0) continue;
    const r = names.findIndex((n, p) => sides[p] === 1 && word.test(n) && !/_end$/.test(n) &&
      n.replace(RIGHT, '') === names[l].replace(LEFT, ''));
    if (r >= 0) { face = { head, left: l, right: r }; break; }
  }
  const spec = { name, color, fps: 1 / dt, frames: F, start: 0, parents, joints: names.filter((n) => !/_end$/.test(n)).length,
    radius, feet, contacts: null, ghost: false, face, sides, pointNames: names, dropped: true, unitScale: scale };
  return { spec, pos: raw };
}
