"""Exports other tools open: glTF 2.0 (kinodyn.viz.gltf), BVH and glTF in Blender, MJCF in MuJoCo.

* glTF: read back with pygltflib and forward-kinematics in glTF's own frame (the oracle is kinodyn's
  FK); the Khronos validator (npm gltf-validator, installed by ``make`` into viz-js/node_modules)
  must report no error and no warning.
* Blender (skipped when absent): import the BVH kinodyn writes and the glTF, then compare a few joints'
  world positions at a few frames with kinodyn's FK. Debian's Blender 3.4 runs on Python 3.11 and
  numpy 1.24, which its BVH importer (``open(path, 'rU')``) and glTF importer (``numpy.bool``) predate:
  the probe script shims both before importing.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from kinodyn.data import library
from kinodyn.errors import ParameterError
from kinodyn.io import save
from kinodyn.math import quat
from kinodyn.viz import gltf
from kinodyn.viz.world import body_points

pygltflib = pytest.importorskip("pygltflib")

_ROOT = Path(__file__).resolve().parents[1]
_VALIDATOR = _ROOT / "viz-js" / "validate-gltf.mjs"
_VALIDATOR_PKG = _ROOT / "viz-js" / "node_modules" / "gltf-validator"
_TOL_F32 = 2e-5  # metres: glTF stores float32
_TOL_BLENDER = 1e-4  # metres: Blender works in float32 and BVH text has 6 decimals (cm)
_FRAMES = (0, 30, 77)
_JOINTS = ("LeftFoot", "RightHand", "Head", "LeftToeBase")


@pytest.fixture(scope="module")
def walk():
    return library.load("walk")


def gltf_world_positions(doc, frame: int) -> dict[str, np.ndarray]:
    """World positions of every node at animation keyframe ``frame``, by FK over glTF's node tree."""
    blob = doc.binary_blob()

    def accessor(i):
        a = doc.accessors[i]
        v = doc.bufferViews[a.bufferView]
        n = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[a.type]
        start = v.byteOffset + (a.byteOffset or 0)
        return np.frombuffer(blob, dtype=np.float32, count=a.count * n, offset=start).reshape(a.count, n)

    trs = {i: (np.array(nd.translation or [0, 0, 0], dtype=np.float64),
               np.array(nd.rotation or [0, 0, 0, 1], dtype=np.float64)) for i, nd in enumerate(doc.nodes)}
    anim = doc.animations[0]
    for ch in anim.channels:
        out = accessor(anim.samplers[ch.sampler].output)[frame].astype(np.float64)
        t, r = trs[ch.target.node]
        trs[ch.target.node] = (out, r) if ch.target.path == "translation" else (t, out)
    pos = {}

    def walk_tree(i, q_parent, p_parent):
        t, r = trs[i]
        q_local = np.array([r[3], r[0], r[1], r[2]])  # glTF xyzw -> wxyz
        p = p_parent + quat.mul_vec(q_parent, t)
        q = quat.mul(q_parent, q_local)
        pos[doc.nodes[i].name] = p
        for c in doc.nodes[i].children or []:
            walk_tree(c, q, p)

    walk_tree(doc.scenes[0].nodes[0], quat.identity(), np.zeros(3))
    return pos


def test_gltf_animation_matches_forward_kinematics(tmp_path, walk):
    path = tmp_path / "walk.glb"
    size = gltf.write_gltf(path, walk, color="#e15759")
    assert size == path.stat().st_size
    doc = pygltflib.GLTF2().load(str(path))
    assert doc.asset.version == "2.0"
    pos, _, names = body_points(walk)
    for f in _FRAMES:
        got = gltf_world_positions(doc, f)
        for k, name in enumerate(names):
            assert_allclose(gltf.from_gltf_axes(got[name]), pos[f, k], atol=_TOL_F32, err_msg=f"{name} frame {f}")


def test_gltf_axes_are_y_up_z_forward():
    assert_allclose(gltf.to_gltf_axes([0, 0, 1]), [0, 1, 0], atol=1e-15)  # up
    assert_allclose(gltf.to_gltf_axes([1, 0, 0]), [0, 0, 1], atol=1e-15)  # forward
    assert_allclose(gltf.to_gltf_axes([0, 1, 0]), [1, 0, 0], atol=1e-15)  # left is +X in glTF
    assert_allclose(gltf.from_gltf_axes(gltf.to_gltf_axes([0.3, -2.0, 5.0])), [0.3, -2.0, 5.0], atol=1e-15)


def test_gltf_json_embeds_the_buffer_and_skins_a_mesh(tmp_path, walk):
    path = tmp_path / "walk.gltf"
    gltf.write_gltf(path, walk)
    doc = json.loads(path.read_text())
    assert doc["buffers"][0]["uri"].startswith("data:application/octet-stream;base64,")
    assert len(doc["skins"][0]["joints"]) == walk.num_joints
    assert doc["meshes"][0]["primitives"][0]["attributes"].keys() >= {"POSITION", "NORMAL", "JOINTS_0", "WEIGHTS_0"}
    assert len(doc["animations"][0]["channels"]) == walk.num_joints + 1  # rotations + root translation
    with pytest.raises(ParameterError, match=r"\.glb or \.gltf"):
        gltf.write_gltf(tmp_path / "walk.fbx", walk)


def _validate(*files) -> list[dict]:
    node = shutil.which("node")
    if node is None or not _VALIDATOR_PKG.is_dir():
        pytest.skip("Khronos glTF validator not installed (node + viz-js/node_modules from make)")
    r = subprocess.run([node, str(_VALIDATOR), *map(str, files)], capture_output=True, text=True, timeout=120,
                       check=False)
    reports = [json.loads(line) for line in r.stdout.splitlines() if line.startswith("{")]
    assert len(reports) == len(files), r.stderr
    return reports


def test_khronos_validator_accepts_the_export(tmp_path, walk):
    files = [tmp_path / "walk.glb", tmp_path / "walk.gltf", tmp_path / "bones_only.glb"]
    gltf.write_gltf(files[0], walk)
    gltf.write_gltf(files[1], walk)
    gltf.write_gltf(files[2], walk, mesh=False)
    for rep in _validate(*files):
        assert rep["errors"] == 0 and rep["warnings"] == 0, rep["messages"]


# --------------------------------------------------------------------------- Blender

_BLENDER_PROBE = r'''
import bpy, json, sys
argv = sys.argv[sys.argv.index("--") + 1:]
path, fmt, frames, bones = argv[0], argv[1], json.loads(argv[2]), json.loads(argv[3])
scene = bpy.context.scene
if fmt == "bvh":
    import builtins
    import io_anim_bvh.import_bvh as _ib
    _ib.open = lambda file, mode="r", *a, **k: builtins.open(file, mode.replace("U", ""), *a, **k)
    bpy.ops.import_anim.bvh(filepath=path, global_scale=0.01, rotate_mode="NATIVE", axis_forward="-Z",
                            axis_up="Y", use_fps_scale=False, update_scene_fps=True)
else:
    import numpy
    if not hasattr(numpy, "bool"):
        numpy.bool = bool
    bpy.ops.import_scene.gltf(filepath=path)
arm = next(o for o in scene.objects if o.type == "ARMATURE")
out = {"fps": scene.render.fps, "pos": []}
for frame, sub in frames:
    scene.frame_set(int(frame), subframe=float(sub))
    out["pos"].append({b: list(arm.matrix_world @ arm.pose.bones[b].head) for b in bones})
print("KINODYN_JSON " + json.dumps(out))
'''


def blender_positions(tmp_path, path, fmt, frames) -> tuple[dict, list]:
    blender = shutil.which("blender")
    if blender is None:
        pytest.skip("Blender is not installed (apt-get install blender)")
    script = tmp_path / "probe.py"
    script.write_text(_BLENDER_PROBE)
    r = subprocess.run([blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python", str(script), "--",
                        str(path), fmt, json.dumps(frames), json.dumps(list(_JOINTS))],
                       capture_output=True, text=True, timeout=300, check=False)
    line = next((x for x in r.stdout.splitlines() if x.startswith("KINODYN_JSON ")), None)
    assert line, f"Blender failed (exit {r.returncode}):\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    out = json.loads(line[len("KINODYN_JSON "):])
    return out, out["pos"]


def kinodyn_in_blender_axes(p: np.ndarray) -> np.ndarray:
    """Blender imports a Y-up file (BVH with axis_up=Y, glTF) as Z up with kinodyn's forward +X at -Y."""
    return np.stack([p[..., 1], -p[..., 0], p[..., 2]], axis=-1)


@pytest.mark.slow
def test_blender_imports_bvh_at_the_same_joint_positions(tmp_path, walk):
    path = tmp_path / "walk.bvh"
    save(path, walk)  # centimetres, Y up: the usual BVH
    info, got = blender_positions(tmp_path, path, "bvh", [[f + 1, 0.0] for f in _FRAMES])  # Blender frame 1 = 0
    assert info["fps"] == 60
    pos, _, names = body_points(walk)
    for k, f in enumerate(_FRAMES):
        for j in _JOINTS:
            assert_allclose(got[k][j], kinodyn_in_blender_axes(pos[f, names.index(j)]), atol=_TOL_BLENDER,
                            err_msg=f"{j} at frame {f}")


@pytest.mark.slow
def test_blender_imports_gltf_at_the_same_joint_positions(tmp_path, walk):
    path = tmp_path / "walk.glb"
    gltf.write_gltf(path, walk)
    # Blender samples glTF time t at scene frame t * scene_fps (24 by default), from frame 0.
    info, got = blender_positions(tmp_path, path, "gltf", [[0, 0.0]])
    fps = info["fps"]
    frames = [[int(f / walk.fps * fps), f / walk.fps * fps % 1.0] for f in _FRAMES]
    info, got = blender_positions(tmp_path, path, "gltf", frames)
    pos, _, names = body_points(walk)
    for k, f in enumerate(_FRAMES):
        for j in _JOINTS:
            assert_allclose(got[k][j], kinodyn_in_blender_axes(pos[f, names.index(j)]), atol=_TOL_BLENDER,
                            err_msg=f"{j} at frame {f}")


# --------------------------------------------------------------------------- MJCF


def test_mjcf_export_of_a_physics_body_loads_in_mujoco(tmp_path):
    body_mod = pytest.importorskip("kinodyn.physics.body")
    mujoco = pytest.importorskip("mujoco")
    from kinodyn.data.skeleton import humanoid

    body = body_mod.build_body(humanoid())
    path = tmp_path / "body.xml"
    path.write_text(body.to_xml() if hasattr(body, "to_xml") else body_mod.body_xml(body))
    model = mujoco.MjModel.from_xml_path(str(path))
    names = {model.body(i).name for i in range(model.nbody)}
    assert {s.name for s in body.map.segments} <= names
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data)
    assert np.all(np.isfinite(data.qpos))
