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

// The capsule radius of the bone ending at a point, by kinodyn.viz.world's rules (sent with the page):
// the first rule whose pattern matches the point's lower-cased name, scaled by the body's height.
function radiusOf(name, parentName, rules, heightScale) {
  const n = name.toLowerCase();
  let r = 0.04;
  for (const [pat, rad] of rules) if (new RegExp(pat).test(n)) { r = rad; break; }
  if (r === 0.075 && n.includes('neck') && parentName.toLowerCase().includes('neck')) r = 0.05;  // a second neck segment
  return r * heightScale;
}

// Returns a character entry of the page's format (without encoded data) and its positions
// Float32Array (F * P * 3).
export function bvhCharacter(text, name, color, rules = []) {
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
  // Height of the rest pose (file units, the file's up axis), as Skeleton.height() measures it.
  root.updateMatrixWorld(true);
  let ylo = Infinity, yhi = -Infinity;
  const w = new THREE.Vector3();
  for (const b of bones) { b.getWorldPosition(w); ylo = Math.min(ylo, w.y); yhi = Math.max(yhi, w.y); }
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
  const hs = Math.max((yhi - ylo) * scale, 0.3) / 1.75;
  const radius = names.map((n, p) => (parents[p] < 0 ? 0 : radiusOf(n, names[parents[p]], rules, hs)));
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
