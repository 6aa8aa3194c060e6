"""glTF 2.0 export of a skeleton animation (``.glb`` binary or ``.gltf`` with an embedded buffer).

What is written, for one motion:

* one node per joint (named as the joint) in the skeleton's hierarchy, plus one node per end site
  (``<joint>_end``); each node's translation is its rest offset and its rotation the identity;
* one animation whose channels drive every joint node's ``rotation`` and the root node's ``translation``
  (and every node's ``translation`` when the motion animates joint translations), linear interpolation,
  one keyframe per motion frame;
* a skin over the joint nodes and a capsule mesh (one capsule per bone, rigidly bound to the bone's
  parent joint, coloured with the character's colour) so that glTF viewers and Blender show a body.

Axes: glTF is +Y up, +Z forward, +X left, metres; kinodyn is +Z up, +X forward, +Y left. The export
maps kinodyn (x, y, z) to glTF (y, z, x), the mapping kinodyn's BVH writer also uses, so both files
agree. Quaternions are written ``(x, y, z, w)`` as glTF requires, sign-unrolled along time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kinodyn.errors import KinodynError, ParameterError
from kinodyn.io.atomic import atomic_write_bytes
from kinodyn.io.bvh import Y_UP_TO_Z_UP
from kinodyn.math import quat
from kinodyn.motion import Motion
from kinodyn.viz import style
from kinodyn.viz.world import bone_radii

__all__ = ["TO_GLTF", "from_gltf_axes", "to_gltf", "to_gltf_axes", "write_gltf"]

#: Rotation taking kinodyn (Z-up, X-forward) vectors to glTF (Y-up, Z-forward) vectors.
TO_GLTF = quat.conj(np.asarray(Y_UP_TO_Z_UP, dtype=np.float64))

_ARRAY_BUFFER = 34962
_ELEMENT_ARRAY_BUFFER = 34963
_FLOAT, _USHORT, _UBYTE, _UINT = 5126, 5123, 5121, 5125


def to_gltf_axes(v) -> np.ndarray:
    """kinodyn ``(..., 3)`` vectors in glTF axes."""
    return quat.mul_vec(TO_GLTF, np.asarray(v, dtype=np.float64))


def from_gltf_axes(v) -> np.ndarray:
    """glTF ``(..., 3)`` vectors in kinodyn axes."""
    return quat.mul_vec(quat.conj(TO_GLTF), np.asarray(v, dtype=np.float64))


def _capsule(a: np.ndarray, b: np.ndarray, r: float, seg: int = 10, rings: int = 3):
    """Vertices ``(V, 3)``, unit normals ``(V, 3)`` and triangles ``(T, 3)`` of a capsule from a to b."""
    axis = b - a
    length = float(np.linalg.norm(axis))
    z = axis / length if length > 1e-9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    # Profile: (height along the axis, ring radius factor, normal z-component) from the bottom pole up.
    prof = []
    for k in range(rings + 1):  # bottom hemisphere, pole to equator
        phi = -np.pi / 2 + (np.pi / 2) * k / rings
        prof.append((0.0, np.cos(phi), np.sin(phi)))
    for k in range(rings + 1):  # top hemisphere, equator to pole
        phi = (np.pi / 2) * k / rings
        prof.append((length, np.cos(phi), np.sin(phi)))
    th = 2 * np.pi * np.arange(seg) / seg
    ring = np.cos(th)[:, None] * x + np.sin(th)[:, None] * y  # (seg, 3)
    verts, norms = [], []
    for h, c, s in prof:
        n = c * ring + s * z
        verts.append(a + h * z + r * n)
        norms.append(n)
    v = np.concatenate(verts)
    nrm = np.concatenate(norms)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    tris = []
    for i in range(len(prof) - 1):
        for j in range(seg):
            p0, p1 = i * seg + j, i * seg + (j + 1) % seg
            q0, q1 = p0 + seg, p1 + seg
            tris += [(p0, p1, q1), (p0, q1, q0)]
    t = np.array(tris, dtype=np.int64)
    # Drop triangles that collapsed at the poles (zero area) so the validator sees no degenerate ones.
    area = np.linalg.norm(np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]]), axis=1)
    return v, nrm, t[area > 1e-12]


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


class _Blob:
    """The binary buffer of a glTF document with its buffer views and accessors (filled in order)."""

    def __init__(self, g):
        self.g = g
        self.blob = bytearray()
        self.views, self.accessors = [], []

    def add(self, data: np.ndarray, comp: int, typ: str, target=None, minmax: bool = False) -> int:
        """Append ``data`` (``(count, ...)``) as one buffer view and accessor; returns the accessor index."""
        g, blob = self.g, self.blob
        while len(blob) % 4:
            blob.append(0)
        raw = np.ascontiguousarray(data).tobytes()
        self.views.append(g.BufferView(buffer=0, byteOffset=len(blob), byteLength=len(raw), target=target))
        blob.extend(raw)
        count = data.shape[0]
        acc = g.Accessor(bufferView=len(self.views) - 1, componentType=comp, count=count, type=typ)
        if minmax:
            flat = data.reshape(count, -1)
            acc.min = [float(x) if comp == _FLOAT else int(x) for x in flat.min(axis=0)]
            acc.max = [float(x) if comp == _FLOAT else int(x) for x in flat.max(axis=0)]
        self.accessors.append(acc)
        return len(self.accessors) - 1


def _nodes(g, sk, root: np.ndarray, offsets: np.ndarray, end_offsets: np.ndarray, trans) -> list:
    """One node a joint (static TRS of the first frame) and an end site, with their children."""
    J, E = sk.num_joints, len(sk.end_parents)
    nodes = []
    for j in range(J):
        t = root[0] if j == 0 else (offsets[j] if trans is None else trans[0, j])
        nodes.append(g.Node(name=sk.names[j], translation=[float(x) for x in t], rotation=[0.0, 0.0, 0.0, 1.0],
                            children=[]))
    for e in range(E):
        nodes.append(g.Node(name=f"{sk.names[sk.end_parents[e]]}_end",
                            translation=[float(x) for x in end_offsets[e]]))
        nodes[sk.end_parents[e]].children.append(J + e)
    for j in range(1, J):
        nodes[sk.parents[j]].children.append(j)
    for n in nodes:
        if n.children == []:
            n.children = None
    return nodes


def _animation(g, buf: _Blob, motion: Motion, root: np.ndarray, rot: np.ndarray, trans):
    """The animation: root translation, every joint's rotation (and translation where animated)."""
    times = (np.arange(motion.num_frames) / motion.fps).astype(np.float32)
    t_acc = buf.add(times, _FLOAT, "SCALAR", minmax=True)
    samplers, channels = [], []

    def channel(node: int, path: str, values: np.ndarray, typ: str) -> None:
        samplers.append(g.AnimationSampler(input=t_acc, output=buf.add(values.astype(np.float32), _FLOAT, typ),
                                           interpolation="LINEAR"))
        channels.append(g.AnimationChannel(sampler=len(samplers) - 1,
                                           target=g.AnimationChannelTarget(node=node, path=path)))

    channel(0, "translation", root, "VEC3")
    for j in range(motion.skeleton.num_joints):
        channel(j, "rotation", rot[:, j][:, [1, 2, 3, 0]], "VEC4")
        if trans is not None and j > 0:
            channel(j, "translation", trans[:, j], "VEC3")
    return g.Animation(name=motion.name or "motion", samplers=samplers, channels=channels)


def _capsules(sk, bind: np.ndarray, end_offsets: np.ndarray):
    """Capsule vertices, normals, triangles and joint of each vertex over the bind pose, or ``None``."""
    E = len(sk.end_parents)
    pts = np.concatenate([bind, bind[sk.end_parents] + end_offsets]) if E else bind
    parents = np.concatenate([sk.parents, sk.end_parents]) if E else np.asarray(sk.parents)
    names = list(sk.names) + [f"{sk.names[p]}_end" for p in sk.end_parents]
    radii = bone_radii(names, parents, sk.height())
    vs, ns, ts, js = [], [], [], []
    base = 0
    for c in range(1, len(pts)):
        p = int(parents[c])
        if np.linalg.norm(pts[c] - pts[p]) < 1e-4:
            continue
        v, n, t = _capsule(pts[p], pts[c], float(radii[c]))
        vs.append(v)
        ns.append(n)
        ts.append(t + base)
        js.append(np.full(len(v), p))
        base += len(v)
    if not vs:
        return None
    return (np.concatenate(vs).astype(np.float32), np.concatenate(ns).astype(np.float32), np.concatenate(ts),
            np.concatenate(js))


def _skinned_body(g, buf: _Blob, sk, bind: np.ndarray, end_offsets: np.ndarray, color):
    """(mesh, skin, material) of the capsule body skinned to the joints (rigidly, one joint a vertex),
    or ``None`` when the skeleton has no bone of any length."""
    caps = _capsules(sk, bind, end_offsets)
    if caps is None:
        return None
    v, n, t, jnt = caps
    J = sk.num_joints
    joints = np.zeros((len(v), 4), dtype=np.uint8 if J < 256 else np.uint16)
    joints[:, 0] = jnt
    weights = np.zeros((len(v), 4), dtype=np.float32)
    weights[:, 0] = 1.0
    idx_type = _USHORT if len(v) < 65535 else _UINT
    i_acc = buf.add(t.astype(np.uint16 if idx_type == _USHORT else np.uint32).ravel(), idx_type, "SCALAR",
                    _ELEMENT_ARRAY_BUFFER)
    attrs = g.Attributes(POSITION=buf.add(v, _FLOAT, "VEC3", _ARRAY_BUFFER, minmax=True),
                         NORMAL=buf.add(n, _FLOAT, "VEC3", _ARRAY_BUFFER),
                         JOINTS_0=buf.add(joints, _UBYTE if J < 256 else _USHORT, "VEC4", _ARRAY_BUFFER),
                         WEIGHTS_0=buf.add(weights, _FLOAT, "VEC4", _ARRAY_BUFFER))
    rgb = _srgb_to_linear(style.rgb(color or style.PALETTE[0]))
    material = g.Material(name="body", pbrMetallicRoughness=g.PbrMetallicRoughness(
        baseColorFactor=[float(x) for x in rgb] + [1.0], metallicFactor=0.0, roughnessFactor=0.6))
    mesh = g.Mesh(name="body", primitives=[g.Primitive(attributes=attrs, indices=i_acc, material=0)])
    ibm = np.tile(np.eye(4, dtype=np.float32), (J, 1, 1))
    ibm[:, :3, 3] = -bind
    # glTF matrices are column-major: write each matrix transposed.
    ibm_acc = buf.add(np.ascontiguousarray(ibm.transpose(0, 2, 1)).reshape(J, 16), _FLOAT, "MAT4")
    skin = g.Skin(name="skeleton", joints=list(range(J)), skeleton=0, inverseBindMatrices=ibm_acc)
    return mesh, skin, material


def to_gltf(motion: Motion, color: str | None = None, mesh: bool = True):
    """The :class:`pygltflib.GLTF2` document of a motion (see the module docstring)."""
    try:
        import pygltflib as g
    except ImportError:
        raise KinodynError("glTF export needs pygltflib (pip install 'kinodyn[viz]')") from None
    if not isinstance(motion, Motion):
        raise ParameterError(f"motion must be a Motion, got {type(motion).__name__}")
    if motion.num_frames == 0:
        raise ParameterError("motion has no frames")
    sk = motion.skeleton
    J, E = sk.num_joints, len(sk.end_parents)
    buf = _Blob(g)
    offsets = to_gltf_axes(sk.offsets)
    end_offsets = to_gltf_axes(sk.end_offsets) if E else np.zeros((0, 3))
    root = to_gltf_axes(motion.root_pos)
    rot = quat.unroll(quat.mul(quat.mul(TO_GLTF, motion.local_rot), quat.conj(TO_GLTF)), axis=0)
    trans = None if motion.translations is None else to_gltf_axes(motion.translations)
    nodes = _nodes(g, sk, root, offsets, end_offsets, trans)
    scene_nodes = [0]
    animations = [_animation(g, buf, motion, root, rot, trans)]
    meshes, skins, materials = [], [], []
    if mesh:
        # Bind pose: identity rotations, root at its first-frame position (the nodes' static TRS).
        bind = np.zeros((J, 3))
        bind[0] = root[0]
        for j in range(1, J):
            bind[j] = bind[sk.parents[j]] + (offsets[j] if trans is None else trans[0, j])
        body = _skinned_body(g, buf, sk, bind, end_offsets, color)
        if body is not None:
            meshes, skins, materials = [body[0]], [body[1]], [body[2]]
            nodes.append(g.Node(name="body", mesh=0, skin=0))
            scene_nodes.append(len(nodes) - 1)
    doc = g.GLTF2(
        asset=g.Asset(version="2.0", generator="kinodyn"),
        scene=0, scenes=[g.Scene(name=motion.name or "scene", nodes=scene_nodes)], nodes=nodes,
        buffers=[g.Buffer(byteLength=len(buf.blob))], bufferViews=buf.views, accessors=buf.accessors,
        animations=animations, meshes=meshes, skins=skins, materials=materials)
    doc.set_binary_blob(bytes(buf.blob))
    return doc


def write_gltf(path, motion: Motion, color: str | None = None, mesh: bool = True) -> int:
    """Write ``motion`` as ``.glb`` (binary) or ``.gltf`` (JSON, buffer embedded as a data URI), atomically.

    Returns the file size in bytes.
    """
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in (".glb", ".gltf"):
        raise ParameterError(f"glTF file must end in .glb or .gltf, got {p.name!r}")
    doc = to_gltf(motion, color, mesh)
    if ext == ".glb":
        data = b"".join(doc.save_to_bytes())
    else:
        import pygltflib as g

        doc.convert_buffers(g.BufferFormat.DATAURI)
        data = doc.gltf_to_json().encode("utf-8")
    atomic_write_bytes(p, data)
    return len(data)
