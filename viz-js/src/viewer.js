// kinodyn viewer: plays characters stored in the page (script#kinodyn-data) with three.js.
//
// World convention: Z up, metres, seconds (as everywhere in kinodyn). The page is self-contained:
// this file is bundled with three.js by esbuild (see viz-js/package.json) and inlined by
// kinodyn.viz.html.write, together with the motion data (quantized joint positions, zlib + base64).
//
// Data format (version 1), written by kinodyn/viz/html.py:
//   {version, title, palette, phaseColors, contactColor, options, scenes: [{name, fps, duration, characters: [...],
//    impacts: [...], phases: [...], trajectories: [...], floor}]}
//   character: {name, color, fps, frames, start, parents[P], joints, radius[P], pos: {enc, origin[3],
//               scale[3], data}, feet: {left: [...], right: [...]}, contacts: {enc, data} | null}
//   pos.enc "i16dz": int16 quantized positions (F, P, 3) (value = origin + (q + 32768) * scale),
//   delta-coded along frames, byte planes split (all low bytes, then all high bytes), zlib-compressed,
//   base64. "i16d": the same without zlib. contacts.enc "u8z" / "u8": one byte per frame, bit 0 left
//   foot, bit 1 right foot.

import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { Balance, Forces, Onion, Prop, Trails } from './extras.js';
import { characterCurves, curvesAt, drawCurves } from './curves.js';
import { bvhCharacter } from './bvh.js';

const UP = new THREE.Vector3(0, 0, 1);
const Y_AXIS = new THREE.Vector3(0, 1, 0);

// ------------------------------------------------------------------------------------------ decoding

function b64bytes(s) {
  const bin = atob(s);
  const out = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
  return out;
}

async function inflate(bytes) {
  if (typeof DecompressionStream === 'undefined') {
    throw new Error('this browser cannot decompress the motion data (no DecompressionStream); ' +
      'write the page with compress=False');
  }
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('deflate'));
  return new Uint8Array(await new Response(stream).arrayBuffer());
}

async function decodeBytes(block) {
  const raw = b64bytes(block.data);
  return block.enc.endsWith('z') ? inflate(raw) : raw;
}

// Returns Float32Array (F * P * 3) of world positions.
async function decodePositions(pos, frames, points) {
  const bytes = await decodeBytes(pos);
  const n = frames * points * 3;
  if (bytes.length !== 2 * n) throw new Error(`position data has ${bytes.length} bytes, expected ${2 * n}`);
  const q = new Int16Array(n);
  for (let i = 0; i < n; i++) q[i] = bytes[i] | (bytes[n + i] << 8);  // wraps into int16
  const stride = points * 3;
  if (pos.enc.startsWith('i16d')) {
    for (let i = stride; i < n; i++) q[i] = q[i] + q[i - stride];  // Int16Array wraps like the writer
  }
  const out = new Float32Array(n);
  const o = pos.origin, s = pos.scale;
  for (let i = 0; i < n; i += 3) {
    out[i] = o[0] + (q[i] + 32768) * s[0];
    out[i + 1] = o[1] + (q[i + 1] + 32768) * s[1];
    out[i + 2] = o[2] + (q[i + 2] + 32768) * s[2];
  }
  return out;
}

// ------------------------------------------------------------------------------------------ helpers

function colorOf(c) { return new THREE.Color(c); }

// True when WebGL runs on a software rasterizer (SwiftShader, llvmpipe): then antialiasing is switched
// off and the pixel ratio kept at 1, which roughly doubles the frame rate there.
function softwareGl() {
  try {
    const c = document.createElement('canvas');
    const gl = c.getContext('webgl2') || c.getContext('webgl');
    if (!gl) return false;
    const ext = gl.getExtension('WEBGL_debug_renderer_info');
    const name = String(ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER));
    gl.getExtension('WEBGL_lose_context')?.loseContext();
    return /swiftshader|llvmpipe|softpipe|software/i.test(name);
  } catch (e) {
    return false;
  }
}

function lighter(c, k) { return colorOf(c).lerp(new THREE.Color(0xffffff), k); }

// An unlit material of one flat colour, with that colour stored in display (sRGB) space and the
// per-pixel linear-to-sRGB conversion left out of its shader. The picture is the same (fog and blending
// come after that conversion and work in display space anyway), but on a software rasterizer the
// conversion (three pow() a pixel) is most of the cost of the floor, which fills half the picture.
function displaySpace(mat) {
  mat.color.convertLinearToSRGB();
  mat.onBeforeCompile = (shader) => {
    shader.fragmentShader = shader.fragmentShader.replace('#include <colorspace_fragment>', '');
  };
  mat.customProgramCacheKey = () => 'kd-display-space';
  return mat;
}

function displayColor(c) { return colorOf(c).convertLinearToSRGB(); }

const _m = new THREE.Matrix4();
const _q = new THREE.Quaternion();
const _s = new THREE.Vector3();
const _a = new THREE.Vector3();
const _d = new THREE.Vector3();

function makeArrow(color) {
  const g = new THREE.Group();
  const mat = displaySpace(new THREE.MeshBasicMaterial({ color, transparent: true, opacity: 1, depthTest: true }));
  const shaft = new THREE.Mesh(new THREE.CylinderGeometry(1, 1, 1, 10), mat);
  const head = new THREE.Mesh(new THREE.ConeGeometry(1, 1, 14), mat);
  g.add(shaft, head);
  g.userData = { shaft, head, mat };
  return g;
}

// Point the arrow from a to b (world), shaft radius r.
function setArrow(arrow, a, b, r) {
  const { shaft, head } = arrow.userData;
  _d.subVectors(b, a);
  const len = Math.max(_d.length(), 1e-6);
  _d.divideScalar(len);
  const hl = Math.min(0.35 * len, 6 * r);
  arrow.position.copy(a);
  arrow.quaternion.setFromUnitVectors(Y_AXIS, _d);
  shaft.scale.set(r, len - hl, r);
  shaft.position.set(0, (len - hl) / 2, 0);
  head.scale.set(2.4 * r, hl, 2.4 * r);
  head.position.set(0, len - hl / 2, 0);
}

const FLOOR_COLOR = 0xeeebe4;

// A floor grid of size x size metres in squares of `step` metres in the XY plane, centre lines in colour c1, the others
// in c2, drawn at the given opacity over a floor of colour `under`: the colours are blended with the
// floor's here (in display space, as the blending of a transparent grid would) so that the grid is an
// opaque draw.
function makeGrid(size, c1, c2, under, opacity, step = 1) {
  const h = size / 2, pos = [], col = [];
  const floor = new THREE.Color().setHex(under, THREE.LinearSRGBColorSpace);
  const mix = (c) => new THREE.Color().setHex(c, THREE.LinearSRGBColorSpace).lerp(floor, 1 - opacity);
  const k1 = mix(c1), k2 = mix(c2);
  for (let i = 0; i <= size; i += step) {
    const k = -h + i, c = 2 * i === size ? k1 : k2;
    pos.push(-h, k, 0, h, k, 0, k, -h, 0, k, h, 0);
    for (let v = 0; v < 4; v++) col.push(c.r, c.g, c.b);
  }
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.Float32BufferAttribute(pos, 3));
  g.setAttribute('color', new THREE.Float32BufferAttribute(col, 3));
  const mat = new THREE.LineBasicMaterial({ vertexColors: true, toneMapped: false });
  mat.onBeforeCompile = (shader) => {
    shader.fragmentShader = shader.fragmentShader.replace('#include <colorspace_fragment>', '');
  };
  mat.customProgramCacheKey = () => 'kd-display-space';
  return new THREE.LineSegments(g, mat);
}

// ------------------------------------------------------------------------------------------ bodies

// The capsules of every character of a scene in one mesh and one draw call. Each bone is a capsule:
// every vertex of a capsule of radius r around the segment a-b is an end point (a or b) plus r times its
// normal, so the geometry holds unit normals and which end each vertex belongs to, and the vertex
// shader places it from the bone's end points and radius, read from a small float texture (two texels
// a bone: a.xyz + radius, b.xyz) that the characters fill in each frame. The joints are the capsules'
// round ends: where bones of several radii meet, the thickest one's end covers the others (as the
// sphere of the largest radius did). Per-vertex colours give each character its colour.
//
// Levels of detail: under software WebGL the frame time is mostly the capsules' vertices, so each
// character is drawn with the coarsest capsule whose outline stays within about half a pixel of a
// true circle at its current size on screen (CAPSULE_LODS: segments around the axis, rings from pole to
// equator, and the largest on-screen bone radius in pixels it is used for).
const CAPSULE_LODS = [
  { S: 4, H: 1, maxPx: 0.9 },
  { S: 6, H: 2, maxPx: 2 },
  { S: 10, H: 4, maxPx: 8 },
  { S: 16, H: 6, maxPx: Infinity },
];

function capsuleTemplate(S, H) {
  const nrm = [], end = [], idx = [];
  // Rows from the bottom pole (end a) to the top pole (end b); the two equator rows make the side.
  for (let half = 0; half < 2; half++) {
    for (let i = 0; i <= H; i++) {
      const phi = half === 0 ? Math.PI - (i * Math.PI) / (2 * H) : Math.PI / 2 - (i * Math.PI) / (2 * H);
      const y = Math.cos(phi), rr = Math.sin(phi);
      for (let j = 0; j < S; j++) {
        const th = (2 * Math.PI * j) / S;
        nrm.push(rr * Math.sin(th), y, rr * Math.cos(th));
        end.push(half);
      }
    }
  }
  const rows = 2 * (H + 1);
  for (let r = 0; r < rows - 1; r++) {
    for (let j = 0; j < S; j++) {
      const a = r * S + j, b = r * S + ((j + 1) % S), c = (r + 1) * S + j, d = (r + 1) * S + ((j + 1) % S);
      if (r !== 0) idx.push(a, b, c);  // no zero-area triangles at the poles
      if (r !== rows - 2) idx.push(b, d, c);
    }
  }
  return { nrm, end, idx, verts: rows * S };
}

const CAPSULE_PARS = `
uniform sampler2D kdBones;
uniform vec3 kdHot;
attribute vec2 kdBone;
varying float kdHotV;
`;
// Bone i is at texels (2 (i % BONE_ROW), i / BONE_ROW) and the next one: the texture stays within
// every GPU's size limit for thousands of characters.
const BONE_ROW = 1024;
const CAPSULE_NORMAL = `
int kdI = int( kdBone.x + 0.5 );
ivec2 kdT = ivec2( 2 * ( kdI % ${BONE_ROW} ), kdI / ${BONE_ROW} );
vec4 kdA = texelFetch( kdBones, kdT, 0 );
vec4 kdB = texelFetch( kdBones, kdT + ivec2( 1, 0 ), 0 );
vec3 kdAxis = kdB.xyz - kdA.xyz;
float kdLen = length( kdAxis );
vec3 kdY = kdLen > 1e-6 ? kdAxis / kdLen : vec3( 0.0, 0.0, 1.0 );
vec3 kdX = normalize( cross( abs( kdY.z ) < 0.9 ? vec3( 0.0, 0.0, 1.0 ) : vec3( 1.0, 0.0, 0.0 ), kdY ) );
vec3 kdZ = cross( kdX, kdY );
vec3 objectNormal = kdX * normal.x + kdY * normal.y + kdZ * normal.z;
`;
// kdB.w: the bone is highlighted (a segment inside an obstacle): drawn in kdHot, nearly opaque.
const CAPSULE_POSITION = `
vec3 transformed = ( kdBone.y > 0.5 ? kdB.xyz : kdA.xyz ) + kdA.w * objectNormal;
kdHotV = kdB.w;
#ifdef USE_COLOR
vColor.xyz = mix( vColor.xyz, kdHot, kdB.w );
#endif
`;
const CAPSULE_FRAGMENT = `
#include <color_fragment>
diffuseColor.a = mix( diffuseColor.a, 0.85, kdHotV );
`;

class Bodies {
  // chars: [{bones: [joint index], spec}] in slot order. ghost: drawn translucent (references).
  // Left bones are drawn lighter and right bones darker than the character's colour.
  constructor(chars, software, ghost = false, hot = '#e8112d') {
    const temps = CAPSULE_LODS.map((l) => capsuleTemplate(l.S, l.H));
    const n = Math.max(chars.reduce((k, ch) => k + ch.bones.length, 0), 1);
    const rows = Math.ceil(n / BONE_ROW);
    this.data = new Float32Array(8 * BONE_ROW * rows);
    this.texture = new THREE.DataTexture(this.data, 2 * BONE_ROW, rows, THREE.RGBAFormat, THREE.FloatType);
    this.texture.minFilter = this.texture.magFilter = THREE.NearestFilter;
    this.texture.generateMipmaps = false;
    this.texture.needsUpdate = true;
    // One section a level of detail, each holding every bone of every character.
    const nv = temps.reduce((k, t) => k + t.verts * n, 0), ni = temps.reduce((k, t) => k + t.idx.length * n, 0);
    const nrm = new Float32Array(3 * nv), bone = new Float32Array(2 * nv), col = new Float32Array(3 * nv);
    const idx = new (nv > 65535 ? Uint32Array : Uint16Array)(ni);
    this.sections = [];  // per level: {start: first index, per: indices a bone}
    let v0 = 0, i0 = 0;
    for (const ch of chars) ch.colorRuns = [];  // per level: [first vertex, vertices a bone]
    temps.forEach((t) => {
      this.sections.push({ start: i0, per: t.idx.length });
      let slot = 0;
      for (const ch of chars) {
        ch.colorRuns.push([v0, t.verts]);
        const base = colorOf(ch.spec.color), sides = ch.spec.sides;
        const tints = [base.clone().lerp(new THREE.Color(0xffffff), 0.38), base, base.clone().multiplyScalar(0.62)];
        for (let b = 0; b < ch.bones.length; b++, slot++) {
          const c = sides ? tints[1 + sides[ch.bones[b]]] : base;
          nrm.set(t.nrm, 3 * v0);
          for (let v = 0; v < t.verts; v++) {
            bone[2 * (v0 + v)] = slot;
            bone[2 * (v0 + v) + 1] = t.end[v];
            col[3 * (v0 + v)] = c.r; col[3 * (v0 + v) + 1] = c.g; col[3 * (v0 + v) + 2] = c.b;
          }
          for (let i = 0; i < t.idx.length; i++) idx[i0 + i] = v0 + t.idx[i];
          v0 += t.verts;
          i0 += t.idx.length;
        }
      }
    });
    let slot = 0;
    for (const ch of chars) { ch.slot = slot; ch.bodies = this; slot += ch.bones.length; }
    this.chars = chars;
    const geo = new THREE.BufferGeometry();
    geo.setAttribute('position', new THREE.BufferAttribute(nrm, 3));  // unused: placed by the shader
    geo.setAttribute('normal', new THREE.BufferAttribute(nrm, 3));
    geo.setAttribute('kdBone', new THREE.BufferAttribute(bone, 2));
    geo.setAttribute('color', new THREE.BufferAttribute(col, 3));
    geo.setIndex(new THREE.BufferAttribute(idx, 1));
    this.geometry = geo;
    // A reference is drawn behind the solid bodies where they coincide (polygon offset), so it shows
    // only where the two differ.
    const opts = ghost ? { color: 0xffffff, vertexColors: true, transparent: true, opacity: 0.3, depthWrite: false,
      polygonOffset: true, polygonOffsetFactor: 2, polygonOffsetUnits: 8 }
      : { color: 0xffffff, vertexColors: true };
    const mat = software ? new THREE.MeshLambertMaterial(opts)
      : new THREE.MeshStandardMaterial({ ...opts, roughness: 0.55, metalness: 0.05 });
    const texture = this.texture, hotColor = colorOf(hot);
    mat.onBeforeCompile = (shader) => {
      shader.uniforms.kdBones = { value: texture };
      shader.uniforms.kdHot = { value: hotColor };
      shader.vertexShader = shader.vertexShader
        .replace('#include <common>', `#include <common>\n${CAPSULE_PARS}`)
        .replace('#include <beginnormal_vertex>', CAPSULE_NORMAL)
        .replace('#include <begin_vertex>', CAPSULE_POSITION);
      shader.fragmentShader = shader.fragmentShader
        .replace('#include <common>', '#include <common>\nvarying float kdHotV;')
        .replace('#include <color_fragment>', CAPSULE_FRAGMENT);
    };
    mat.customProgramCacheKey = () => 'kd-capsules';
    this.mesh = new THREE.Mesh(geo, [mat]);  // drawn by groups: the level of detail of each character
    this.mesh.name = ghost ? 'ghosts' : 'bodies';
    if (ghost) this.mesh.renderOrder = 5;
    this.mesh.frustumCulled = false;
  }

  // Draw one character's bones in another colour (left lighter, right darker, as built).
  recolor(ch, color) {
    const col = this.geometry.attributes.color, a = col.array, base = colorOf(color), sides = ch.spec.sides;
    const tints = [base.clone().lerp(new THREE.Color(0xffffff), 0.38), base, base.clone().multiplyScalar(0.62)];
    for (const [v0, per] of ch.colorRuns) {
      for (let b = 0; b < ch.bones.length; b++) {
        const c = sides ? tints[1 + sides[ch.bones[b]]] : base;
        for (let v = v0 + b * per, e = v0 + (b + 1) * per; v < e; v++) {
          a[3 * v] = c.r; a[3 * v + 1] = c.g; a[3 * v + 2] = c.b;
        }
      }
    }
    col.needsUpdate = true;
  }

  // Bone end points and radii of one character's current pose.
  write(ch, cur) {
    const d = this.data, par = ch.spec.parents, rad = ch.spec.radius;
    const hot = ch.hot, h0 = hot ? Math.max(ch.frame || 0, 0) * ch.P : 0;
    let o = 8 * ch.slot;
    for (const p of ch.bones) {
      const q = par[p];
      d[o] = cur[3 * q]; d[o + 1] = cur[3 * q + 1]; d[o + 2] = cur[3 * q + 2]; d[o + 3] = rad[p];
      d[o + 4] = cur[3 * p]; d[o + 5] = cur[3 * p + 1]; d[o + 6] = cur[3 * p + 2];
      d[o + 7] = hot ? hot[h0 + p] : 0;
      o += 8;
    }
  }

  // Choose each character's level of detail: pxPerMetre(ch) is its scale on screen (pixels a metre).
  // Runs of characters at the same level that follow one another are one draw call. A few characters
  // get a level per bone (thin bones coarser); a crowd one level per character (its thickest bone's),
  // so that neighbours at the same distance make one run and the crowd a handful of draw calls.
  setDetail(pxPerMetre) {
    const geo = this.geometry;
    geo.clearGroups();
    let last = null;
    const perChar = this.chars.length > 20;
    for (const ch of this.chars) {
      const ppm = pxPerMetre(ch), rad = ch.spec.radius;
      ch.lod = 0;
      if (perChar && ch.bones.length) {
        let l = 0;
        while (rad[ch.bones[0]] * ppm > CAPSULE_LODS[l].maxPx) l++;
        ch.lod = l;
        const sec = this.sections[l];
        const start = sec.start + ch.slot * sec.per, count = ch.bones.length * sec.per;
        if (last && last.start + last.count === start) last.count += count;
        else { geo.addGroup(start, count, 0); last = geo.groups[geo.groups.length - 1]; }
        continue;
      }
      // Bones are sorted thickest first: each level is one run of them.
      for (let b = 0; b < ch.bones.length;) {
        const rpx = rad[ch.bones[b]] * ppm;
        let l = 0;
        while (rpx > CAPSULE_LODS[l].maxPx) l++;
        ch.lod = Math.max(ch.lod, l);
        let e = b + 1;
        while (e < ch.bones.length && rad[ch.bones[e]] * ppm > (l ? CAPSULE_LODS[l - 1].maxPx : -1)) e++;
        const sec = this.sections[l];
        const start = sec.start + (ch.slot + b) * sec.per, count = (e - b) * sec.per;
        if (last && last.start + last.count === start) last.count += count;
        else { geo.addGroup(start, count, 0); last = geo.groups[geo.groups.length - 1]; }
        b = e;
      }
    }
  }

  dispose() {
    this.mesh.geometry.dispose();
    this.mesh.material[0].dispose();
    this.texture.dispose();
  }
}

// ------------------------------------------------------------------------------------------ character

const SIDES = ['left', 'right'];

// Blob shadows, foot-contact rings and noses of every character of a scene: three instanced meshes,
// three draw calls however many characters there are. Filled by the characters each frame.
// Marks that draw nothing: a character updated while its scene's marks are being rebuilt.
const NO_MARKS = { shadow() {}, nose() {}, ring() {} };

class Marks {
  constructor(n, world) {
    this.shadows = new THREE.InstancedMesh(world.discGeo, world.shadowMat, Math.max(n, 1));
    this.rings = new THREE.InstancedMesh(world.ringGeo, world.ringMat, Math.max(2 * n, 1));
    this.noses = new THREE.InstancedMesh(world.noseGeo, world.noseMat, Math.max(n, 1));
    this.shadows.renderOrder = 1;
    this.rings.renderOrder = 2;
    for (const m of [this.shadows, this.rings, this.noses]) { m.frustumCulled = false; m.count = 0; }
    this.noses.name = 'noses';
    this.group = new THREE.Group();
    this.group.add(this.shadows, this.rings, this.noses);
  }

  begin() { this.ns = 0; this.nr = 0; this.nn = 0; }

  shadow(x, y, z, s) {
    _q.identity(); _a.set(x, y, z); _s.set(s, s, 1);
    this.shadows.setMatrixAt(this.ns++, _m.compose(_a, _q, _s));
  }

  ring(x, y, z) {
    _q.identity(); _a.set(x, y, z); _s.set(1, 1, 1);
    this.rings.setMatrixAt(this.nr++, _m.compose(_a, _q, _s));
  }

  // A nose: a cone at p pointing along the unit vector d, scaled by k.
  nose(p, d, k) {
    _q.setFromUnitVectors(Y_AXIS, d); _s.set(k, k, k);
    this.noses.setMatrixAt(this.nn++, _m.compose(p, _q, _s));
  }

  end() {
    this.shadows.count = this.ns; this.rings.count = this.nr; this.noses.count = this.nn;
    for (const m of [this.shadows, this.rings, this.noses]) m.instanceMatrix.needsUpdate = true;
  }

  dispose() { for (const m of [this.shadows, this.rings, this.noses]) m.dispose(); }
}

const _fwd = new THREE.Vector3();
const _nose = new THREE.Vector3();

class Character {
  constructor(spec, pos, contacts, world, index = 0) {
    this.spec = spec;
    this.pos = pos;
    this.index = index;
    this.contacts = contacts;  // Uint8Array (F) bit 0 left, bit 1 right, or null
    this.P = spec.parents.length;
    this.F = spec.frames;
    this.ghost = !!spec.ghost;
    this.cur = new Float32Array(this.P * 3);
    this.group = new THREE.Group();
    this.group.name = spec.name;
    const color = colorOf(spec.color);
    this.bones = [];
    for (let p = 0; p < this.P; p++) if (spec.parents[p] >= 0) this.bones.push(p);
    this.bones.sort((a, b) => spec.radius[b] - spec.radius[a] || a - b);  // thickest first (levels of detail)
    // Joint radius: the largest radius of the bones meeting there, so cylinders and spheres make capsules.
    this.jr = new Float32Array(this.P);
    for (const p of this.bones) {
      const r = spec.radius[p];
      this.jr[p] = Math.max(this.jr[p], r);
      const par = spec.parents[p];
      this.jr[par] = Math.max(this.jr[par], r);
    }
    for (let p = 0; p < this.P; p++) if (this.jr[p] === 0) this.jr[p] = 0.03;
    // The head's tip (its thickest child: the head capsule) for the nose.
    const face = spec.face || {};
    this.headTip = -1;
    if (face.head !== undefined) {
      for (let p = 0; p < this.P; p++) {
        if (spec.parents[p] === face.head && (this.headTip < 0 || spec.radius[p] > spec.radius[this.headTip])) this.headTip = p;
      }
    }
    // Lowest point over the clip (snap to floor) and the first root position (in place).
    let zmin = Infinity;
    for (let i = 2; i < pos.length; i += 3) zmin = Math.min(zmin, pos[i]);
    this.zmin = zmin;
    this.root0 = [pos[0], pos[1]];
    // Capsule style: drawn by the scene's Bodies mesh (slot: this character's first bone there).
    this.slot = 0;
    this.bodies = null;
    // Bone style: lines plus small joints.
    const lineGeo = new THREE.BufferGeometry();
    this.lineAttr = new THREE.BufferAttribute(new Float32Array(this.bones.length * 6), 3);
    lineGeo.setAttribute('position', this.lineAttr);
    this.lines = new THREE.LineSegments(lineGeo,
      displaySpace(new THREE.LineBasicMaterial({ color: color.clone().multiplyScalar(0.7),
        transparent: this.ghost, opacity: this.ghost ? 0.35 : 1 })));
    this.lines.frustumCulled = false;
    this.dots = new THREE.InstancedMesh(world.sphGeo, displaySpace(new THREE.MeshBasicMaterial({ color,
      transparent: this.ghost, opacity: this.ghost ? 0.35 : 1 })), this.P);
    this.dots.frustumCulled = false;
    this.group.add(this.lines, this.dots);
    // Root trajectory on the floor.
    const tr = new Float32Array(this.F * 3);
    for (let f = 0; f < this.F; f++) {
      tr[3 * f] = pos[f * this.P * 3];
      tr[3 * f + 1] = pos[f * this.P * 3 + 1];
      tr[3 * f + 2] = world.floor + 0.006;
    }
    const tg = new THREE.BufferGeometry();
    tg.setAttribute('position', new THREE.BufferAttribute(tr, 3));
    this.traj = new THREE.Line(tg, displaySpace(new THREE.LineBasicMaterial({ color, transparent: true, opacity: 0.75 })));
    this.traj.frustumCulled = false;
    this.group.add(this.traj);
    // Name label (HTML).
    this.label = document.createElement('div');
    this.label.className = this.ghost ? 'kd-label kd-ghost' : 'kd-label';
    this.label.textContent = this.ghost ? `${spec.name} (reference)` : spec.name;
    this.label.style.borderColor = spec.color;
    world.labels.appendChild(this.label);
    this.headTop = new THREE.Vector3();
    this.frame = 0;
    this.extras = null;  // balance, trails and onion skins, made when first switched on
  }

  // Local (fractional) frame at world time t.
  // A looping clip starts again after its last frame (period F / fps); others hold it.
  localFrame(t) {
    const f = Math.max((t - this.spec.start) * this.spec.fps, 0);
    if (this.spec.loop && this.F > 1) return Math.min(f % this.F, this.F - 1);
    return Math.min(f, this.F - 1);
  }

  // The pose at scene time t into out (P * 3), moved as the in-place and snap-to-floor toggles say.
  sample(t, out, opts) {
    const ff = this.localFrame(t);
    const i0 = Math.floor(ff), i1 = Math.min(i0 + 1, this.F - 1), a = ff - i0;
    const P3 = this.P * 3, pos = this.pos;
    const o0 = i0 * P3, o1 = i1 * P3;
    for (let k = 0; k < P3; k++) out[k] = pos[o0 + k] + a * (pos[o1 + k] - pos[o0 + k]);
    let dx = 0, dy = 0, dz = 0;
    if (opts.inPlace) { dx = this.root0[0] - out[0]; dy = this.root0[1] - out[1]; }
    if (opts.snap) dz = (this.floorZ || 0) - this.zmin;
    if (dx || dy || dz) for (let k = 0; k < P3; k += 3) { out[k] += dx; out[k + 1] += dy; out[k + 2] += dz; }
    return ff;
  }

  update(t, opts, world) {
    this.floorZ = world.floor;
    const ff = this.sample(t, this.cur, opts);
    this.frame = Math.min(Math.round(ff), this.F - 1);
    const cur = this.cur;
    const capsules = opts.style === 'capsules';
    this.lines.visible = this.dots.visible = !capsules;
    let zmax = -Infinity, imax = 0;
    for (let p = 0; p < this.P; p++) {
      if (cur[3 * p + 2] > zmax) { zmax = cur[3 * p + 2]; imax = p; }
    }
    this.headTop.set(cur[3 * imax], cur[3 * imax + 1], zmax + 0.12);
    if (capsules) {
      if (this.bodies) this.bodies.write(this, cur);
    } else {
      const la = this.lineAttr.array;
      let n = 0;
      for (const p of this.bones) {
        const par = this.spec.parents[p];
        for (let c = 0; c < 3; c++) { la[n + c] = cur[3 * par + c]; la[n + 3 + c] = cur[3 * p + c]; }
        n += 6;
      }
      this.lineAttr.needsUpdate = true;
      _q.identity();
      for (let p = 0; p < this.P; p++) {
        _a.set(cur[3 * p], cur[3 * p + 1], cur[3 * p + 2]);
        const r = 0.35 * this.jr[p];
        _s.set(r, r, r);
        _m.compose(_a, _q, _s);
        this.dots.setMatrixAt(p, _m);
      }
      this.dots.instanceMatrix.needsUpdate = true;
    }
    const marks = world.marks || NO_MARKS;  // none while a scene is being switched in
    // Blob shadow under the root, shrinking with height above the floor.
    const rz = cur[2] - world.floor;
    // (none for references, nor for a one-point marker without bones: the object it rides casts its own)
    if (!this.ghost && this.bones.length) marks.shadow(cur[0], cur[1], world.floor + 0.003, 0.3 * Math.max(0.4, 1.2 - 0.35 * Math.max(rz - 0.9, 0)));
    // Nose: which way the head faces (up x (right - left)), at the front of the head.
    const face = this.spec.face;
    if (face && face.left !== undefined && !this.ghost) {
      const l = 3 * face.left, r = 3 * face.right;
      _fwd.set(-(cur[r + 1] - cur[l + 1]), cur[r] - cur[l], 0);
      const len = _fwd.length();
      if (len > 1e-6) {
        _fwd.divideScalar(len);
        const h = 3 * face.head, tip = this.headTip;
        const rad = tip >= 0 ? this.spec.radius[tip] : 0.09;
        if (tip >= 0) _nose.set((cur[h] + cur[3 * tip]) / 2, (cur[h + 1] + cur[3 * tip + 1]) / 2, (cur[h + 2] + cur[3 * tip + 2]) / 2);
        else _nose.set(cur[h], cur[h + 1], cur[h + 2]);
        _nose.addScaledVector(_fwd, rad * 0.92);
        marks.nose(_nose, _fwd, rad / 0.095);
      }
    }
    // Foot contacts, and the feet in contact (support polygon).
    const feet = this.spec.feet || {};
    const feetOn = [];
    if (this.contacts) {
      for (let bit = 0; bit < 2; bit++) {
        const idx = feet[SIDES[bit]];
        if (!idx || !idx.length || !((this.contacts[this.frame] >> bit) & 1)) continue;
        feetOn.push(idx);
        if (!opts.contacts) continue;
        let x = 0, y = 0;
        for (const p of idx) { x += cur[3 * p]; y += cur[3 * p + 1]; }
        marks.ring(x / idx.length, y / idx.length, world.floor + 0.008);
      }
    }
    this.traj.visible = !!opts.trajectories && !opts.inPlace;
    // Balance, trails and onion skins: made when first switched on.
    if ((opts.com || opts.support || opts.trails || opts.onion) && !this.extras) {
      this.extras = { balance: new Balance(this.spec.color, world.sphGeo, world.floor), trails: new Trails(this),
        onion: new Onion(this) };
      this.group.add(this.extras.balance.group, this.extras.trails.group, this.extras.onion.group);
    }
    if (this.extras) {
      this.extras.balance.floor = world.floor;
      this.extras.balance.update(this, opts, feetOn);
      const sample = (ch, tt, out) => ch.sample(tt, out, opts);
      this.extras.trails.update(this, t, opts, sample);
      this.extras.onion.update(this, t, opts, sample);
    }
  }

  dispose() {
    this.label.remove();
  }
}

// ------------------------------------------------------------------------------------------ viewer

// What a follow camera looks from (towards the camera, from its target) at start and for the presets:
// 'front' faces the characters, 'side' looks at their right side, 'top' from above.
const DEFAULT_BACK = new THREE.Vector3(0.45, -1, 0.42).normalize();

export class WebGLUnavailableError extends Error {}

export const MSG_NO_WEBGL = 'This page needs WebGL to draw the 3-D view, and this browser has none available ' +
  '(it is switched off, blocked, or the graphics driver is not supported). Turn on hardware acceleration ' +
  'in the browser settings, or open the file in a current Chrome, Edge, Firefox or Safari.';

export function webglAvailable() {
  try {
    const c = document.createElement('canvas');
    const gl = c.getContext('webgl2') || c.getContext('webgl') || c.getContext('experimental-webgl');
    if (!gl) return false;
    gl.getExtension('WEBGL_lose_context')?.loseContext();
    return true;
  } catch (e) {
    return false;
  }
}

class Viewer {
  constructor(root, data) {
    this.root = root;
    this.data = data;
    this.errors = [];
    this.ready = false;
    this.playing = true;
    this.speed = 1;
    this.t = 0;
    this.opts = { style: 'capsules', contacts: true, trajectories: false, impacts: true, phases: true,
      labels: true, camera: 'follow', props: true, forces: true, com: false, support: false, trails: false,
      onion: false, curves: false, inPlace: false, snap: false, ortho: false, loop: true };
    Object.assign(this.opts, data.options || {});
    this.rafTimes = [];
    this.renderedFrames = 0;
    this.pxPerMetre = (ch) => this.pxPerMetreAt(ch);
    this.played = 0;  // scene seconds played since the page opened (loops included)
    this.loopRange = null;  // [t0, t1] or null: the whole scene
    this.userMarkers = [];
    this.curvesChar = 0;
    this.buildDom();
    this.buildThree();
    this.bindUi();
  }

  // -------------------------------------------------------------------- DOM
  buildDom() {
    const r = this.root;
    const $ = (sel) => r.querySelector(sel);
    this.el = {
      canvasWrap: $('#kd-canvas'), labels: $('#kd-labels'), play: $('#kd-play'), scrub: $('#kd-scrub'),
      counter: $('#kd-counter'), speed: $('#kd-speed'), camera: $('#kd-camera'), style: $('#kd-style'),
      legend: $('#kd-legend'), timeline: $('#kd-timeline'), scene: $('#kd-scene'), fps: $('#kd-fps'),
      overlays: r.querySelectorAll('input[data-overlay]'), title: $('#kd-title'), status: $('#kd-status'),
      playhead: $('#kd-playhead'), views: r.querySelectorAll('button[data-view]'), curves: $('#kd-curves'),
      curvesCanvas: $('#kd-curves-plot'), curvesMark: $('#kd-curves-mark'), curvesChar: $('#kd-curves-char'),
      drop: $('#kd-drop'),
    };
    this.el.title.textContent = this.data.title || 'kinodyn';
    document.title = this.data.title || 'kinodyn';
    const scenes = this.data.scenes;
    if (scenes.length > 1) {
      scenes.forEach((s, i) => {
        const o = document.createElement('option');
        o.value = String(i);
        o.textContent = s.name || `scene ${i + 1}`;
        this.el.scene.appendChild(o);
      });
      this.el.scene.parentElement.style.display = '';
    }
    this.el.camera.value = this.opts.camera;
    this.el.style.value = this.opts.style;
    this.syncToggles();
  }

  syncToggles() { this.el.overlays.forEach((cb) => { cb.checked = !!this.opts[cb.dataset.overlay]; }); }

  buildThree() {
    const wrap = this.el.canvasWrap;
    if (!webglAvailable()) throw new WebGLUnavailableError(MSG_NO_WEBGL);
    this.software = softwareGl();
    const aa = this.opts.antialias === undefined || this.opts.antialias === 'auto' ? !this.software : !!this.opts.antialias;
    try {
      this.renderer = new THREE.WebGLRenderer({ antialias: aa, powerPreference: 'high-performance' });
    } catch (e) {
      throw new WebGLUnavailableError(MSG_NO_WEBGL);
    }
    this.renderer.setPixelRatio(this.software ? 1 : Math.min(window.devicePixelRatio || 1, 2));
    this.renderer.outputColorSpace = THREE.SRGBColorSpace;
    wrap.appendChild(this.renderer.domElement);
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0xdfe6ee);
    this.camera = new THREE.PerspectiveCamera(40, 1, 0.05, 2000);
    this.camera.up.copy(UP);  // before the controls read it
    this.camera.position.set(3, -6, 2.5);
    this.orthoCamera = new THREE.OrthographicCamera(-1, 1, 1, -1, 0.05, 2000);
    this.orthoCamera.up.copy(UP);
    this.controls = new OrbitControls(this.camera, this.renderer.domElement);
    this.controls.enableDamping = true;
    this.controls.target.set(0, 0, 0.9);
    this.controls.maxPolarAngle = Math.PI * 0.495;
    this.controls.addEventListener('start', () => { this.userZoom = true; });
    this.renderer.domElement.addEventListener('wheel', () => { this.zoomAt = performance.now(); }, { passive: true });
    const hemi = new THREE.HemisphereLight(0xffffff, 0x8a8070, 1.6);
    hemi.position.set(0, 0, 1);
    const sun = new THREE.DirectionalLight(0xffffff, 1.7);
    sun.position.set(4, -6, 10);
    this.scene.add(hemi, sun);
    // Shared geometries.
    this.world = {
      sphGeo: new THREE.SphereGeometry(1, 16, 12),
      discGeo: new THREE.CircleGeometry(1, 32),
      ringGeo: new THREE.RingGeometry(0.07, 0.11, 28),
      noseGeo: new THREE.ConeGeometry(0.024, 0.07, 10).translate(0, 0.035, 0),
      shadowMat: displaySpace(new THREE.MeshBasicMaterial({ color: 0x000000, transparent: true, opacity: 0.12,
        depthWrite: false })),
      ringMat: displaySpace(new THREE.MeshBasicMaterial({ color: this.data.contactColor || '#f2b705', depthWrite: false,
        side: THREE.DoubleSide })),
      noseMat: new THREE.MeshLambertMaterial({ color: 0x2b2f36 }),
      bodies: null,
      ghosts: null,
      marks: null,
      labels: this.el.labels,
      floor: 0,
      software: this.software,
    };
    // Shared by every character and scene: never disposed.
    this.shared = new Set([this.world.sphGeo, this.world.discGeo, this.world.ringGeo, this.world.noseGeo,
      this.world.shadowMat, this.world.ringMat, this.world.noseMat]);
    this.resize();
    new ResizeObserver(() => this.resize()).observe(wrap);
  }

  resize() {
    const w = Math.max(this.el.canvasWrap.clientWidth, 1), h = Math.max(this.el.canvasWrap.clientHeight, 1);
    this.renderer.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.drawTimeline();
    this.drawCurvesPanel();
  }

  // -------------------------------------------------------------------- scene
  async loadScene(index) {
    this.clearScene();
    const spec = this.data.scenes[index];
    this.sceneIndex = index;
    if (this.el.scene.options.length) this.el.scene.value = String(index);
    this.spec = spec;
    this.world.floor = spec.floor || 0;
    this.fps = spec.fps;
    this.duration = spec.duration;
    this.loopRange = null;
    this.userMarkers = [];
    this.setClock();
    this.sceneGroup = new THREE.Group();
    this.scene.add(this.sceneGroup);
    this.chars = [];
    for (const c of spec.characters) {
      const pos = await decodePositions(c.pos, c.frames, c.parents.length);
      const contacts = c.contacts ? await decodeBytes(c.contacts) : null;
      const ch = new Character(c, pos, contacts, this.world, this.chars.length);
      ch.hot = c.hot ? await decodeBytes(c.hot) : null;  // (F * P) highlighted bones
      this.chars.push(ch);
      this.sceneGroup.add(ch.group);
    }
    // Many characters: names only on request (they would cover the crowd).
    if (this.chars.length > 40 && !this.labelsForced) this.opts.labels = false;
    this.syncToggles();
    this.rebuildBodies();
    this.props = [];
    for (const p of spec.props || []) {
      const prop = new Prop(p, await decodePositions(p.pos, p.frames, 1), this.world.floor, this.software);
      this.props.push(prop);
      this.sceneGroup.add(prop.group);
    }
    this.forces = (spec.forces || []).map((f) => new Forces(f, this.world.sphGeo));
    for (const f of this.forces) this.sceneGroup.add(f.group);
    this.buildGround();
    this.buildOverlays();
    this.buildLegend();
    this.t = 0;
    this.frameCamera(this.sceneBack());
    this.drawTimeline();
    this.fillCurvesChars();
  }

  setClock() {
    this.totalFrames = Math.max(1, Math.round(this.duration * this.fps) + 1);
    this.el.scrub.max = String(this.totalFrames - 1);
  }

  // The capsule meshes (solid characters, translucent references) and the instanced marks, for the
  // characters of the scene now (rebuilt when a file is dropped on the page).
  rebuildBodies() {
    for (const k of ['bodies', 'ghosts']) {
      if (this.world[k]) { this.sceneGroup.remove(this.world[k].mesh); this.world[k].dispose(); this.world[k] = null; }
    }
    if (this.world.marks) { this.sceneGroup.remove(this.world.marks.group); this.world.marks.dispose(); }
    const solid = this.chars.filter((c) => !c.ghost), ghosts = this.chars.filter((c) => c.ghost);
    const hot = this.data.highlightColor || '#e8112d';
    this.world.bodies = new Bodies(solid, this.software, false, hot);
    this.sceneGroup.add(this.world.bodies.mesh);
    if (ghosts.length) {
      this.world.ghosts = new Bodies(ghosts, this.software, true, hot);
      this.sceneGroup.add(this.world.ghosts.mesh);
    }
    this.world.marks = new Marks(this.chars.length, this.world);
    this.sceneGroup.add(this.world.marks.group);
  }

  clearScene() {
    if (!this.sceneGroup) return;
    for (const ch of this.chars) ch.dispose();
    for (const k of ['bodies', 'ghosts']) { if (this.world[k]) this.world[k].dispose(); this.world[k] = null; }
    if (this.world.marks) this.world.marks.dispose();
    this.world.marks = null;
    this.sceneGroup.traverse((o) => {
      if (o.geometry && !this.shared.has(o.geometry)) o.geometry.dispose();
      for (const m of o.material ? [].concat(o.material) : []) if (!this.shared.has(m)) m.dispose();
    });
    this.scene.remove(this.sceneGroup);
    this.sceneGroup = null;
    this.chars = [];
    this.props = [];
    this.forces = [];
  }

  // Add a character (a dropped file) to the scene shown now.
  addCharacter(spec, pos) {
    const ch = new Character(spec, pos, null, this.world, this.chars.length);
    this.chars.push(ch);
    this.sceneGroup.add(ch.group);
    this.rebuildBodies();
    const end = spec.start + (spec.frames - 1) / spec.fps;
    if (end > this.duration) { this.duration = end; this.setClock(); }
    this.buildLegend();
    this.drawTimeline();
    this.fillCurvesChars();
    this.frameCamera(this.camera.position.clone().sub(this.controls.target));  // the same view, framing all
    return ch;
  }

  async dropFiles(files) {
    const added = [];
    for (const file of files) {
      if (!/\.bvh$/i.test(file.name)) { this.note(`${file.name}: only BVH files can be dropped here`); continue; }
      try {
        const text = await file.text();
        const color = this.data.palette[this.chars.length % this.data.palette.length];
        const { spec, pos } = bvhCharacter(text, file.name.replace(/\.bvh$/i, ''), color, this.data.radiusRules || []);
        added.push(this.addCharacter(spec, pos));
        this.note(`added ${file.name}: ${spec.frames} frames at ${spec.fps.toFixed(0)} fps`);
      } catch (e) {
        this.note(`${file.name}: not a BVH file this page can read (${e.message || e})`);
      }
    }
    return added;
  }

  note(text) {
    const st = this.el.status;
    st.textContent = text;
    st.style.display = '';
    clearTimeout(this.noteTimer);
    this.noteTimer = setTimeout(() => { st.style.display = 'none'; }, 3000);
  }

  // Bounds of every character's points over the whole scene.
  rootBounds() {
    const lo = new THREE.Vector3(Infinity, Infinity, Infinity), hi = new THREE.Vector3(-Infinity, -Infinity, -Infinity);
    for (const ch of this.chars) {
      const P3 = ch.P * 3;
      for (let f = 0; f < ch.F; f += Math.max(1, Math.floor(ch.F / 2000))) {
        for (let p = 0; p < ch.P; p += this.chars.length > 50 ? ch.P : 1) {
          _a.set(ch.pos[f * P3 + 3 * p], ch.pos[f * P3 + 3 * p + 1], ch.pos[f * P3 + 3 * p + 2]);
          lo.min(_a); hi.max(_a);
        }
      }
    }
    for (const pr of this.props || []) {
      for (let f = 0; f < pr.F; f++) { _a.fromArray(pr.pos, 3 * f); lo.min(_a); hi.max(_a); }
    }
    if (!isFinite(lo.x)) { lo.set(-1, -1, 0); hi.set(1, 1, 2); }
    return [lo, hi];
  }

  buildGround() {
    const [lo, hi] = this.rootBounds();
    const cx = Math.round((lo.x + hi.x) / 2), cy = Math.round((lo.y + hi.y) / 2);
    const ext = Math.max(hi.x - lo.x, hi.y - lo.y);
    const size = 2 * Math.ceil((ext + 12) / 2);
    const floor = this.world.floor;
    // The floor is pushed back in depth so that the grid lines on it never dash in and out far away.
    const plane = new THREE.Mesh(new THREE.PlaneGeometry(size * 1.6, size * 1.6),
      displaySpace(new THREE.MeshBasicMaterial({ color: FLOOR_COLOR, polygonOffset: true, polygonOffsetFactor: 2,
        polygonOffsetUnits: 4 })));
    plane.position.set(cx, cy, floor - 0.001);
    // One-metre squares; five-metre ones on a big floor (a crowd's), where 1 m lines would be a blur.
    const step = size > 40 ? 5 : 1;
    const grid = makeGrid(step > 1 ? Math.ceil(size / 10) * 10 : size, 0x7d8792, 0xaeb6bf, FLOOR_COLOR, 1.0, step);
    grid.position.set(cx, cy, floor + 0.001);
    grid.renderOrder = 1;  // after the floor
    // World axes at the origin: X red, Y green (short, on the floor).
    const axes = new THREE.Group();
    const ax = makeArrow(0xd62728), ay = makeArrow(0x2ca02c);
    setArrow(ax, new THREE.Vector3(0, 0, floor + 0.004), new THREE.Vector3(0.5, 0, floor + 0.004), 0.008);
    setArrow(ay, new THREE.Vector3(0, 0, floor + 0.004), new THREE.Vector3(0, 0.5, floor + 0.004), 0.008);
    axes.add(ax, ay);
    this.sceneGroup.add(plane, grid, axes);
    this.scene.fog = new THREE.Fog(0xdfe6ee, size * 0.9, size * 2.2);
  }

  buildOverlays() {
    const spec = this.spec;
    this.impacts = [];
    for (const im of spec.impacts || []) {
      const arrow = makeArrow(new THREE.Color(im.color || '#d62728'));
      const p = new THREE.Vector3(...im.point);
      const J = new THREE.Vector3(...im.impulse);
      const mag = J.length();
      const len = Math.min(Math.max(0.25, mag * (spec.impulseScale || 0.02)), 1.2);
      const dir = mag > 1e-9 ? J.clone().divideScalar(mag) : new THREE.Vector3(1, 0, 0);
      setArrow(arrow, p.clone().addScaledVector(dir, -len), p, 0.014);
      const dot = new THREE.Mesh(this.world.sphGeo,
        displaySpace(new THREE.MeshBasicMaterial({ color: im.color || '#d62728', transparent: true })));
      dot.position.copy(p);
      dot.scale.setScalar(0.045);
      const g = new THREE.Group();
      g.add(arrow, dot);
      g.visible = false;
      this.sceneGroup.add(g);
      this.impacts.push({ spec: im, group: g, mats: [arrow.userData.mat, dot.material] });
    }
    this.extraTraj = [];
    for (const tr of spec.trajectories || []) {
      const g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(tr.points), 3));
      const line = new THREE.Line(g, displaySpace(new THREE.LineBasicMaterial({ color: tr.color || '#333333' })));
      line.frustumCulled = false;
      this.sceneGroup.add(line);
      this.extraTraj.push(line);
    }
  }

  buildLegend() {
    const lg = this.el.legend;
    lg.innerHTML = '';
    const add = (color, text, cls) => {
      const item = document.createElement('span');
      item.className = `kd-legend-item ${cls || ''}`;
      const sw = document.createElement('span');
      sw.className = 'kd-swatch';
      sw.style.background = color;
      item.append(sw, document.createTextNode(text));
      lg.appendChild(item);
    };
    if (this.chars.length <= 40) {
      for (const ch of this.chars) add(ch.spec.color, ch.ghost ? `${ch.spec.name} (reference)` : ch.spec.name, ch.ghost ? 'kd-ghost' : '');
    } else add('#888', `${this.chars.length} characters`);
    const props = (this.props || []).filter((p) => p.spec.label);
    if (props.length <= 6) for (const p of props) add(p.spec.color, p.spec.label);
    else add(props[0].spec.color, `${props.length} objects`);
  }

  // -------------------------------------------------------------------- camera
  activeCamera() { return this.opts.ortho ? this.orthoCamera : this.camera; }

  // Distance from target c along back (unit, towards the camera) at which every character's current
  // pose and every prop shown is inside the picture (a point at offset d from the target, r to the
  // side, needs the camera at least r / tan(fov / 2) - d.forward away).
  requiredDistance(c, back) {
    const fwd = _fwd.copy(back).negate();
    const right = _nose.crossVectors(fwd, UP);
    if (right.lengthSq() < 1e-8) right.set(1, 0, 0); else right.normalize();
    const up = _d.crossVectors(right, fwd);
    const tv = Math.tan(THREE.MathUtils.degToRad(this.camera.fov) / 2);
    const th = tv * Math.max(this.camera.aspect, 0.3);
    let dist = 2.5;
    const need = (x, y, z, pad) => {
      _a.set(x - c.x, y - c.y, z - c.z);
      const n = Math.max((Math.abs(_a.dot(right)) + pad) / th, (Math.abs(_a.dot(up)) + pad) / tv) - _a.dot(fwd);
      dist = Math.max(dist, n * 1.1 + 0.3);
    };
    const crowd = this.chars.length > 50;
    for (const ch of this.chars) {
      if (crowd) { need(ch.cur[0], ch.cur[1], ch.cur[2], 0.9); continue; }
      for (let p = 0; p < ch.P; p++) need(ch.cur[3 * p], ch.cur[3 * p + 1], ch.cur[3 * p + 2], ch.jr[p] + 0.02);
      if (this.opts.labels) need(ch.headTop.x, ch.headTop.y, ch.headTop.z + 0.12, 0.05);  // its name label
      need(ch.cur[0], ch.cur[1], this.world.floor, 0.05);  // the feet's shadow, the floor under them
    }
    // Objects that move are kept in view (a ball in flight); still ones (walls, tables) need not be.
    for (const pr of this.props || []) if (pr.visible && pr.F > 1) need(pr.current.x, pr.current.y, pr.current.z, pr.spec.size[0] || 0.1);
    return dist;
  }

  placeCamera(c, back, dist) {
    this.controls.target.copy(c);
    this.camera.position.copy(c).addScaledVector(back, dist);
    this.camera.near = Math.max(0.02, dist / 500);
    this.camera.far = dist * 40 + 200;
    this.camera.updateProjectionMatrix();
    this.controls.update();
  }

  sceneBack() { return this.spec && this.spec.view ? new THREE.Vector3(...this.spec.view) : DEFAULT_BACK; }

  // Frame every character of the current frame, looking along back (default: the side view).
  frameCamera(back = DEFAULT_BACK) {
    this.updateCharacters();
    const c = this.centroid(new THREE.Vector3());
    const b = back.clone().normalize();
    this.placeCamera(c, b, this.requiredDistance(c, b));
  }

  // Which way the characters face now (mean of their facings; their travel when none is known).
  facing(out) {
    out.set(0, 0, 0);
    for (const ch of this.chars) {
      const f = ch.spec.face;
      if (!f || f.left === undefined) continue;
      const l = 3 * f.left, r = 3 * f.right;
      out.x -= ch.cur[r + 1] - ch.cur[l + 1];
      out.y += ch.cur[r] - ch.cur[l];
    }
    if (out.lengthSq() < 1e-8) out.set(0, 1, 0);
    return out.normalize();
  }

  // Camera presets: 'front' (facing the characters), 'side' (their right side), 'top' (from above).
  setView(name) {
    this.updateCharacters();
    const f = this.facing(new THREE.Vector3());
    const back = new THREE.Vector3();
    if (name === 'front') back.copy(f).addScaledVector(UP, 0.18);
    else if (name === 'side') back.crossVectors(f, UP).addScaledVector(UP, 0.12);
    else if (name === 'top') back.copy(UP).addScaledVector(f, -0.02);
    else back.copy(this.sceneBack());
    this.view = name;
    this.frameCamera(back);
  }

  // Middle of the characters' roots in the current frame (z lowered a little: look at the chest).
  centroid(out) {
    if (!this.chars.length) return out.set(0, 0, 0.9);
    const lo = this._lo || (this._lo = new THREE.Vector3()), hi = this._hi || (this._hi = new THREE.Vector3());
    lo.set(Infinity, Infinity, Infinity);
    hi.set(-Infinity, -Infinity, -Infinity);
    for (const ch of this.chars) {
      lo.min(_a.set(ch.cur[0], ch.cur[1], ch.cur[2]));
      hi.max(_a);
    }
    out.addVectors(lo, hi).multiplyScalar(0.5);
    out.z = Math.max(out.z * 0.85, this.world.floor + 0.5);
    return out;
  }

  // -------------------------------------------------------------------- UI
  bindUi() {
    const el = this.el;
    el.play.addEventListener('click', () => this.setPlaying(!this.playing));
    el.scrub.addEventListener('input', () => { this.seekFrame(Number(el.scrub.value)); });
    el.speed.addEventListener('change', () => { this.speed = Number(el.speed.value); });
    el.camera.addEventListener('change', () => { this.opts.camera = el.camera.value; });
    el.style.addEventListener('change', () => { this.opts.style = el.style.value; });
    el.scene.addEventListener('change', () => { this.loadScene(Number(el.scene.value)); });
    el.overlays.forEach((cb) => cb.addEventListener('change', () => {
      this.opts[cb.dataset.overlay] = cb.checked;
      if (cb.dataset.overlay === 'labels') this.labelsForced = true;
      this.drawTimeline();
      this.drawCurvesPanel();
    }));
    el.views.forEach((b) => b.addEventListener('click', () => this.setView(b.dataset.view)));
    el.curvesChar.addEventListener('change', () => { this.curvesChar = Number(el.curvesChar.value); this.drawCurvesPanel(); });
    this.root.querySelector('#kd-in').addEventListener('click', () => this.setLoopPoint(0));
    this.root.querySelector('#kd-out').addEventListener('click', () => this.setLoopPoint(1));
    window.addEventListener('keydown', (e) => {
      if (e.target && (e.target.tagName === 'SELECT' || e.target.tagName === 'INPUT' && e.target.type !== 'range')) return;
      const k = e.key.toLowerCase();
      if (e.code === 'Space') { this.setPlaying(!this.playing); e.preventDefault(); }
      else if (e.code === 'ArrowRight') { this.setPlaying(false); this.seekFrame(this.frameIndex() + 1); }
      else if (e.code === 'ArrowLeft') { this.setPlaying(false); this.seekFrame(this.frameIndex() - 1); }
      else if (e.code === 'Home') { this.seek(this.loopRange ? this.loopRange[0] : 0); }
      else if (k === 'i') this.setLoopPoint(0);
      else if (k === 'o') this.setLoopPoint(1);
      else if (k === 'x') this.setLoopRange(null);
      else if (k === 'l') { this.opts.loop = !this.opts.loop; this.syncToggles(); }
      else if (k === 'm') this.addMarker(this.t);
      else if (k === 'f') this.frameCamera(this.camera.position.clone().sub(this.controls.target));
      else if (k === '1') this.setView('front');
      else if (k === '3') this.setView('side');
      else if (k === '7') this.setView('top');
      else if (k === '5') { this.opts.ortho = !this.opts.ortho; this.syncToggles(); }
      else if (k === ']' || k === '[') this.jumpMarker(k === ']' ? 1 : -1);
    });
    const tl = el.timeline;
    const seekAt = (e) => {
      const r = tl.getBoundingClientRect();
      const x0 = this.tlLeft || 0;
      const u = (e.clientX - r.left - x0) / Math.max(r.width - x0 - 8, 1);
      this.seek(Math.min(Math.max(u, 0), 1) * this.duration);
    };
    let drag = false;
    tl.addEventListener('pointerdown', (e) => { drag = true; seekAt(e); });
    window.addEventListener('pointermove', (e) => { if (drag) seekAt(e); });
    window.addEventListener('pointerup', () => { drag = false; });
    // Drop a BVH file anywhere on the page to add it to the scene.
    const drop = el.drop;
    window.addEventListener('dragover', (e) => { e.preventDefault(); drop.style.display = ''; });
    window.addEventListener('dragleave', (e) => { if (!e.relatedTarget) drop.style.display = 'none'; });
    window.addEventListener('drop', (e) => {
      e.preventDefault();
      drop.style.display = 'none';
      const files = [...(e.dataTransfer ? e.dataTransfer.files : [])];
      this.dropping = this.dropFiles(files);
    });
  }

  setPlaying(p) {
    if (p && !this.playing) {
      const [, b] = this.range();
      if (this.t >= b - 1e-9) this.t = this.range()[0];
    }
    this.playing = p;
    this.el.play.textContent = p ? '❚❚' : '▶';
    this.el.play.title = p ? 'pause (space)' : 'play (space)';
  }

  frameIndex() { return Math.min(Math.floor(this.t * this.fps + 1e-6), this.totalFrames - 1); }

  seekFrame(f) { this.seek(Math.min(Math.max(f, 0), this.totalFrames - 1) / this.fps); }

  seek(t) { this.t = Math.min(Math.max(t, 0), this.duration); }

  // -------------------------------------------------------------------- loop range, markers
  range() { return this.loopRange || [0, this.duration]; }

  setLoopRange(r) {
    this.loopRange = r ? [Math.max(0, Math.min(r[0], r[1])), Math.min(this.duration, Math.max(r[0], r[1]))] : null;
    if (this.loopRange && this.loopRange[1] - this.loopRange[0] < 1 / this.fps) this.loopRange = null;
    this.drawTimeline();
  }

  // Set the start (0) or end (1) of the loop range at the current time.
  setLoopPoint(which) {
    const r = this.range().slice();
    r[which] = this.t;
    this.setLoopRange(r);
  }

  allMarkers() {
    return [...(this.spec?.markers || []), ...this.userMarkers].sort((a, b) => a.t - b.t);
  }

  addMarker(t, label = '') {
    this.userMarkers.push({ t, label: label || `${t.toFixed(2)} s`, color: '#1d2430' });
    this.drawTimeline();
  }

  jumpMarker(dir) {
    const ms = this.allMarkers().map((m) => m.t);
    const next = dir > 0 ? ms.find((t) => t > this.t + 1e-6) : ms.reverse().find((t) => t < this.t - 1e-6);
    if (next !== undefined) this.seek(next);
  }

  // -------------------------------------------------------------------- timeline (phases, stages, impacts, markers)
  timelineRows() {
    const rows = [];
    if (this.opts.phases) for (const ph of this.spec?.phases || []) rows.push({ kind: 'phase', ph, label: ph.label });
    if (this.opts.impacts && (this.spec?.impacts || []).length) rows.push({ kind: 'impacts', label: 'impacts' });
    if (this.allMarkers().length || this.loopRange) rows.push({ kind: 'markers', label: 'markers' });
    return rows;
  }

  drawTimeline() {
    const cv = this.el.timeline;
    if (!this.spec) return;
    const rows = this.timelineRows();
    const rowH = 16, pad = 4;
    const legend = rows.some((r) => r.kind === 'phase');
    const h = rows.length ? rows.length * (rowH + 3) + 2 * pad + (legend ? 12 : 0) : 0;
    cv.style.height = `${h}px`;
    cv.style.display = rows.length ? '' : 'none';
    if (!rows.length) { this.movePlayhead(); return; }
    const dpr = window.devicePixelRatio || 1;
    const w = cv.clientWidth;
    if (cv.width !== Math.round(w * dpr) || cv.height !== Math.round(h * dpr)) {
      cv.width = Math.round(w * dpr);
      cv.height = Math.round(h * dpr);
    }
    const ctx = cv.getContext('2d');
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, w, h);
    ctx.font = '11px system-ui, sans-serif';
    ctx.textBaseline = 'middle';
    let labelW = 60;
    for (const r of rows) labelW = Math.max(labelW, ctx.measureText(r.label).width + 14);
    labelW = Math.min(labelW, w * 0.35);
    this.tlLeft = labelW;
    const x0 = labelW, x1 = w - 8, D = Math.max(this.duration, 1e-6);
    const X = (t) => x0 + (x1 - x0) * Math.min(Math.max(t / D, 0), 1);
    const colors = { ...(this.data.phaseColors || {}), ...(this.data.stageColors || {}) };
    rows.forEach((r, i) => {
      const y = pad + i * (rowH + 3);
      ctx.fillStyle = '#333';
      ctx.fillText(r.label, 4, y + rowH / 2, labelW - 8);
      ctx.fillStyle = '#eceff3';
      ctx.fillRect(x0, y, x1 - x0, rowH);
      if (r.kind === 'phase') {
        for (const [a, b, lab] of r.ph.spans) {
          ctx.fillStyle = (r.ph.colors && r.ph.colors[lab]) || colors[lab] || '#888';
          ctx.fillRect(X(a), y, Math.max(X(b) - X(a), 1), rowH);
        }
      } else if (r.kind === 'impacts') {
        for (const im of this.spec.impacts) {
          ctx.fillStyle = im.color || '#d62728';
          ctx.fillRect(X(im.t) - 1.5, y, 3, rowH);
        }
      } else {
        let lastEnd = -Infinity;
        for (const m of this.allMarkers()) {
          ctx.fillStyle = m.color || '#1d2430';
          ctx.beginPath();
          ctx.moveTo(X(m.t), y + rowH);
          ctx.lineTo(X(m.t) - 4, y + 4);
          ctx.lineTo(X(m.t) + 4, y + 4);
          ctx.fill();
          const tw = ctx.measureText(m.label).width;
          if (m.label && X(m.t) + 6 > lastEnd && X(m.t) + 6 + tw < x1) {
            ctx.fillText(m.label, X(m.t) + 6, y + rowH / 2);
            lastEnd = X(m.t) + 10 + tw;
          }
        }
      }
    });
    if (this.loopRange) {  // the loop range: shaded over every row, with brackets
      const [a, b] = this.loopRange, yb = pad + rows.length * (rowH + 3) - 3;
      ctx.fillStyle = 'rgba(30, 120, 220, 0.16)';
      ctx.fillRect(X(a), pad - 2, X(b) - X(a), yb - pad + 2);
      ctx.fillStyle = '#1e78dc';
      ctx.fillRect(X(a) - 1, pad - 2, 2, yb - pad + 2);
      ctx.fillRect(X(b) - 1, pad - 2, 2, yb - pad + 2);
    }
    // Legend of phase and stage labels.
    const labs = new Map();
    for (const r of rows) if (r.kind === 'phase') for (const s of r.ph.spans) labs.set(s[2], (r.ph.colors && r.ph.colors[s[2]]) || colors[s[2]] || '#888');
    let lx = x0;
    const ly = h - 8;
    const order = Object.keys(colors);  // the phase colours' order (DS, LS, RS, flight...), others after
    const rank = (l) => (order.indexOf(l) + order.length + 1) % (order.length + 1);
    for (const [lab, col] of [...labs].sort((a, b) => rank(a[0]) - rank(b[0]))) {
      ctx.fillStyle = col;
      ctx.fillRect(lx, ly - 4, 9, 9);
      ctx.fillStyle = '#333';
      ctx.fillText(lab, lx + 12, ly);
      lx += ctx.measureText(lab).width + 26;
    }
    this.tlX0 = x0;
    this.tlX1 = x1;
    this.el.playhead.style.height = `${h - (legend ? 14 : 2)}px`;
    this.movePlayhead();
  }

  // The playhead is a composited div over the static timeline canvas: moving it repaints nothing.
  movePlayhead() {
    const ph = this.el.playhead;
    if (!this.spec || this.el.timeline.style.display === 'none') { ph.style.display = 'none'; return; }
    ph.style.display = '';
    const u = Math.min(Math.max(this.t / Math.max(this.duration, 1e-6), 0), 1);
    ph.style.transform = `translateX(${(this.tlX0 + (this.tlX1 - this.tlX0) * u - 1).toFixed(1)}px)`;
  }

  // -------------------------------------------------------------------- curves panel
  fillCurvesChars() {
    const sel = this.el.curvesChar;
    sel.innerHTML = '';
    this.chars.slice(0, 200).forEach((ch, i) => {
      const o = document.createElement('option');
      o.value = String(i);
      o.textContent = ch.spec.name;
      sel.appendChild(o);
    });
    this.curvesChar = Math.min(this.curvesChar, Math.max(this.chars.length - 1, 0));
    sel.value = String(this.curvesChar);
    this.curvesCache = new Map();
    this.drawCurvesPanel();
  }

  curvesOf(i) {
    if (!this.curvesCache) this.curvesCache = new Map();
    if (!this.curvesCache.has(i)) this.curvesCache.set(i, characterCurves(this.chars[i], this.world.floor));
    return this.curvesCache.get(i);
  }

  drawCurvesPanel() {
    const panel = this.el.curves;
    if (!panel) return;
    const on = !!this.opts.curves && this.chars && this.chars.length > 0;
    panel.style.display = on ? '' : 'none';
    if (!on) return;
    const ch = this.chars[this.curvesChar];
    this.curvesMap = drawCurves(this.el.curvesCanvas, this.curvesOf(this.curvesChar), this.duration, ch.spec.name);
    this.moveCurvesMark();
  }

  moveCurvesMark() {
    if (!this.opts.curves || !this.curvesMap) return;
    const { x0, x1 } = this.curvesMap;
    const u = Math.min(Math.max(this.t / Math.max(this.duration, 1e-6), 0), 1);
    this.el.curvesMark.style.transform = `translateX(${(x0 + (x1 - x0) * u - 1).toFixed(1)}px)`;
  }

  curvesState() {
    if (!this.chars.length) return null;
    return { character: this.chars[this.curvesChar].spec.name, time: this.t, values: curvesAt(this.curvesOf(this.curvesChar), this.t),
      markX: this.curvesMap ? this.curvesMap.x0 + (this.curvesMap.x1 - this.curvesMap.x0) * (this.t / Math.max(this.duration, 1e-6)) : null };
  }

  // -------------------------------------------------------------------- frame loop
  updateCharacters() {
    const marks = this.world.marks;
    if (marks) marks.begin();
    for (const ch of this.chars || []) ch.update(this.t, this.opts, this.world);
    if (marks) marks.end();
    this.tintByStage();
    for (const k of ['bodies', 'ghosts']) {
      const bodies = this.world[k];
      if (!bodies) continue;
      bodies.mesh.visible = this.opts.style === 'capsules';
      if (bodies.mesh.visible) {
        bodies.texture.needsUpdate = true;
        bodies.setDetail(this.pxPerMetre);
      }
    }
    for (const p of this.props || []) p.update(this.t, this.opts);
    for (const f of this.forces || []) f.update(this.t, this.opts);
  }

  // Bars drawn with tint (a response's stages): the character's body takes the colour of the span it
  // is in, its own colour outside every span; bodies are recoloured only when that colour changes.
  tintByStage() {
    const colors = { ...(this.data.phaseColors || {}), ...(this.data.stageColors || {}) };
    for (const ph of this.spec?.phases || []) {
      const ch = ph.tint && this.chars ? this.chars[ph.char] : null;
      if (!ch || !ch.bodies) continue;
      const span = ph.spans.find(([a, b]) => this.t >= a && this.t < b);
      const want = span ? ((ph.colors && ph.colors[span[2]]) || colors[span[2]] || '#888') : ch.spec.color;
      if (ch.tintNow !== want) { ch.bodies.recolor(ch, want); ch.tintNow = want; }
    }
  }

  // Pixels a metre on screen at a character's root (from the camera's last placement).
  pxPerMetreAt(ch) {
    const cam = this.camera, e = cam.matrixWorld.elements;
    // Depth along the view direction (the camera looks down its -Z axis).
    const depth = -((ch.cur[0] - e[12]) * e[8] + (ch.cur[1] - e[13]) * e[9] + (ch.cur[2] - e[14]) * e[10]);
    const h = this.renderer.domElement.height;
    return h / (2 * Math.tan(THREE.MathUtils.degToRad(cam.fov) / 2) * Math.max(depth, cam.near));
  }

  updateOverlays() {
    const hold = 0.8;
    for (const im of this.impacts || []) {
      const dt = this.t - im.spec.t;
      const on = this.opts.impacts && dt >= -0.02 && dt <= hold;
      im.group.visible = on;
      if (on) {
        const op = dt <= 0.15 ? 1 : Math.max(0, 1 - (dt - 0.15) / (hold - 0.15));
        for (const m of im.mats) m.opacity = op;
      }
    }
    for (const l of this.extraTraj || []) l.visible = !!this.opts.trajectories;
  }

  // Follow and orbit keep every character in the picture: the target follows the characters and the
  // distance grows at once when someone would leave the picture and shrinks slowly when they gather
  // (not for a few seconds after the user zooms with the wheel).
  updateCamera() {
    const mode = this.opts.camera;
    this.controls.autoRotate = mode === 'orbit';
    this.controls.autoRotateSpeed = 1.2;
    if (mode === 'follow' || mode === 'orbit') {
      const c = this.centroid(this._c || (this._c = new THREE.Vector3()));
      const step = c.sub(this.controls.target).multiplyScalar(0.12);
      this.controls.target.add(step);
      this.camera.position.add(step);
      if (!(performance.now() - (this.zoomAt || -1e9) < 4000)) {
        const back = (this._back || (this._back = new THREE.Vector3())).subVectors(this.camera.position, this.controls.target);
        const cur = back.length();
        back.divideScalar(Math.max(cur, 1e-9));
        const need = this.requiredDistance(this.controls.target, back);
        const dist = cur + (need - cur) * (need > cur ? 0.3 : 0.04);
        this.camera.position.copy(this.controls.target).addScaledVector(back, dist);
        this.camera.near = Math.max(0.02, dist / 500);
        this.camera.far = dist * 40 + 200;
        this.camera.updateProjectionMatrix();
      }
    }
    this.controls.update();
    if (this.opts.ortho) {  // the orthographic camera mirrors the perspective one, same size at the target
      const oc = this.orthoCamera, dist = this.camera.position.distanceTo(this.controls.target);
      const hh = dist * Math.tan(THREE.MathUtils.degToRad(this.camera.fov) / 2), hw = hh * this.camera.aspect;
      oc.position.copy(this.camera.position);
      oc.quaternion.copy(this.camera.quaternion);
      oc.left = -hw; oc.right = hw; oc.top = hh; oc.bottom = -hh;
      oc.near = -dist * 4; oc.far = this.camera.far;
      oc.updateProjectionMatrix();
      oc.updateMatrixWorld();
    }
  }

  // Name labels above the heads, moved up where they would overlap (bottom ones stay in place).
  updateLabels() {
    const show = this.opts.labels;
    const w = this.el.canvasWrap.clientWidth, h = this.el.canvasWrap.clientHeight;
    const cam = this.activeCamera();
    const items = [];
    for (const ch of this.chars || []) {
      if (!show) { ch.label.style.display = 'none'; continue; }
      _a.copy(ch.headTop).project(cam);
      if (_a.z > 1 || _a.z < -1 || Math.abs(_a.x) > 1.2 || Math.abs(_a.y) > 1.2) { ch.label.style.display = 'none'; continue; }
      if (ch.label.style.display === 'none' || !ch.labelW) {
        ch.label.style.display = '';
        ch.labelW = ch.label.offsetWidth || 60;
        ch.labelH = ch.label.offsetHeight || 16;
      }
      items.push({ ch, x: ((_a.x + 1) / 2) * w, y: ((1 - _a.y) / 2) * h });
    }
    items.sort((a, b) => b.y - a.y);
    const placed = [];
    for (const it of items) {
      const hw = it.ch.labelW / 2 + 2, hh = it.ch.labelH + 2;
      let y = it.y;
      for (let moved = true, n = 0; moved && n < placed.length + 1; n++) {
        moved = false;
        for (const p of placed) {
          if (Math.abs(p.x - it.x) < hw + p.hw && y > p.y - p.hh && y - hh < p.y) { y = p.y - p.hh; moved = true; }
        }
      }
      placed.push({ x: it.x, y, hw, hh });
      it.ch.labelRect = [it.x - hw + 2, y - hh + 2, it.x + hw - 2, y];
      it.ch.label.style.transform = `translate(-50%, -100%) translate(${it.x.toFixed(1)}px, ${y.toFixed(1)}px)`;
    }
  }

  // Text and slider updates make the browser lay out and repaint, which costs more than the 3-D frame
  // under software rendering: while playing they are refreshed at most 12 times a second.
  updateHud(force = false) {
    const now = performance.now();
    if (!force && this.playing && now - (this.hudT || 0) < 80) return;
    this.hudT = now;
    const f = this.frameIndex();
    const digits = String(this.totalFrames - 1).length;
    const text = `frame ${String(f).padStart(digits, '\u2007')} / ${this.totalFrames - 1}   ${this.t.toFixed(2)} s`;
    if (this.el.counter.textContent !== text) this.el.counter.textContent = text;
    if (Number(this.el.scrub.value) !== f) this.el.scrub.value = String(f);
    if (now - (this.fpsT || 0) > 1000) {
      this.fpsT = now;
      this.el.fps.textContent = `${this.measuredFps().toFixed(0)} fps`;
    }
  }

  measuredFps(windowMs = 2000) {
    const ts = this.rafTimes;
    if (ts.length < 2) return 0;
    const last = ts[ts.length - 1];
    let i = ts.length - 1;
    while (i > 0 && last - ts[i - 1] <= windowMs) i--;
    const n = ts.length - 1 - i;
    return n > 0 ? (1000 * n) / (last - ts[i]) : 0;
  }

  tick(now) {
    // Real time, except after a long stall (a hidden tab): then resume without a jump. A frame may take
    // up to a second (software WebGL on a busy machine) and the clock still keeps real time.
    const dt = this.lastNow === undefined ? 0 : Math.min((now - this.lastNow) / 1000, 1.0);
    this.lastNow = now;
    this.rafTimes.push(now);
    if (this.rafTimes.length > 600) this.rafTimes.splice(0, this.rafTimes.length - 600);
    if (this.playing && this.duration > 0) {
      const [a, b] = this.range();
      this.t += dt * this.speed;
      this.played += dt * this.speed;
      if (this.loopRange && this.t < a) this.t = a;
      if (this.t > b) {
        if (this.opts.loop === false) { this.t = b; this.setPlaying(false); }
        else this.t = a + ((this.t - a) % Math.max(b - a, 1e-6));
      }
    }
    this.updateCharacters();
    this.updateOverlays();
    this.updateCamera();
    this.renderer.render(this.scene, this.activeCamera());
    this.updateLabels();
    this.updateHud(this.t !== this.lastT && !this.playing);
    this.lastT = this.t;
    this.movePlayhead();
    this.moveCurvesMark();
    this.renderedFrames++;
  }

  start() {
    const loop = (now) => {
      try { this.tick(now); } catch (e) { this.fail(e); return; }
      requestAnimationFrame(loop);
    };
    requestAnimationFrame(loop);
  }

  fail(e) {
    this.errors.push(String(e && e.stack || e));
    this.el.status.textContent = `error: ${e && e.message || e}`;
    this.el.status.style.display = '';
    console.error(e);
  }
}

// ------------------------------------------------------------------------------------------ entry

// What the page shows and does, for tests and people at the console.
function pageState(v) {
  return {
    opts: { ...v.opts }, time: v.t, loopRange: v.loopRange, markers: v.allMarkers(), view: v.view || null,
    camera: { position: v.camera.position.toArray(), target: v.controls.target.toArray(),
      ortho: v.activeCamera().isOrthographicCamera === true },
    characters: v.chars.map((ch) => ({ name: ch.spec.name, ghost: ch.ghost, frame: ch.frame, root: [ch.cur[0], ch.cur[1], ch.cur[2]],
      hot: ch.hot ? ch.bones.filter((p) => ch.hot[Math.max(ch.frame || 0, 0) * ch.P + p]).length : 0,
      label: ch.label.style.display === 'none' ? null : ch.labelRect || null, dropped: !!ch.spec.dropped,
      com: ch.extras ? ch.extras.balance.c.toArray() : null, support: ch.extras ? ch.extras.balance.hull : null,
      comInside: ch.extras ? ch.extras.balance.inside : null })),
    props: (v.props || []).map((p) => ({ label: p.spec.label, shape: p.spec.shape, visible: p.visible, position: p.current.toArray() })),
    forces: (v.forces || []).map((f) => f.shown),
    noses: v.world.marks ? v.world.marks.noses.count : 0,
    drawCalls: v.renderer.info.render.calls,
    curves: v.opts.curves ? v.curvesState() : null,
  };
}

function showNoWebgl(message) {
  const st = document.getElementById('kd-status');
  if (st) {
    st.className = 'kd-nowebgl';
    st.textContent = message;
    st.style.display = '';
  }
}

async function main() {
  const root = document.getElementById('kd-root');
  const boot = { ready: false, errors: [], webgl: true };
  window.kinodynViewer = boot;
  let viewer;
  try {
    const data = JSON.parse(document.getElementById('kinodyn-data').textContent);
    viewer = new Viewer(root, data);
    const api = {
      viewer,
      ready: false,
      webgl: true,
      fps: (ms) => viewer.measuredFps(ms),
      play: () => viewer.setPlaying(true),
      pause: () => viewer.setPlaying(false),
      seek: (t) => viewer.seek(t),
      seekFrame: (f) => viewer.seekFrame(f),
      setSpeed: (s) => { viewer.speed = s; viewer.el.speed.value = String(s); },
      set: (k, v) => { viewer.opts[k] = v; viewer.syncToggles(); viewer.drawTimeline(); viewer.drawCurvesPanel(); },
      loadScene: (i) => viewer.loadScene(i),
      setView: (name) => viewer.setView(name),
      setLoopRange: (a, b) => viewer.setLoopRange(a === null ? null : [a, b]),
      addMarker: (t, label) => viewer.addMarker(t, label),
      loadBvh: (text, name) => viewer.dropFiles([new File([text], `${name || 'dropped'}.bvh`)]),
      state: () => pageState(viewer),
    };
    Object.defineProperties(api, {
      frame: { get: () => viewer.frameIndex() },
      time: { get: () => viewer.t },
      playing: { get: () => viewer.playing },
      totalFrames: { get: () => viewer.totalFrames },
      renderedFrames: { get: () => viewer.renderedFrames },
      played: { get: () => viewer.played },
      errors: { get: () => viewer.errors },
    });
    window.kinodynViewer = api;
    await viewer.loadScene(0);
    viewer.setPlaying(viewer.opts.autoplay !== false);
    viewer.el.status.style.display = 'none';
    viewer.start();
    api.ready = true;
  } catch (e) {
    if (e instanceof WebGLUnavailableError) {
      boot.webgl = false;
      boot.message = e.message;
      showNoWebgl(e.message);
    } else if (viewer) viewer.fail(e); else {
      boot.errors.push(String(e));
      const st = document.getElementById('kd-status');
      if (st) st.textContent = `error: ${e.message || e}`;
      console.error(e);
    }
  }
}

if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', main);
else main();
