"""Materials (Table 1), bad meshes and bad scene files get clear kinodyn errors; shipped scenes load."""

import numpy as np
import pytest
import yaml

from kinodyn.contact import meshes
from kinodyn.contact import setting as S
from kinodyn.contact.scenefile import load_scene, parse_scene, scenario_names, scenario_path
from kinodyn.errors import FileFormatError, KinodynError, ParameterError, UnknownNameError


def test_table_1_pairs_are_symmetric_and_as_printed():
    assert S.coefficients("wood", "wood") == (0.3, 0.3)
    assert S.coefficients("metal", "wood") == S.coefficients("wood", "metal") == (0.2, 0.1)
    assert S.coefficients("human", "human") == (0.1, 0.1)
    with pytest.raises(UnknownNameError, match="unknown material 'rubber'"):
        S.coefficients("rubber", "wood")


def _cube():
    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    import trimesh

    m = trimesh.convex.convex_hull(v)
    return np.asarray(m.vertices), np.asarray(m.faces)


def test_bad_meshes_are_named_errors():
    v, f = _cube()
    with pytest.raises(FileFormatError, match="box.obj: has no triangles"):
        meshes.check_mesh(v, np.zeros((0, 3), int), "box.obj")
    bad = v.copy()
    bad[2, 1] = np.nan
    with pytest.raises(FileFormatError, match="vertex 2 is not finite"):
        meshes.check_mesh(bad, f, "box.obj")
    with pytest.raises(FileFormatError, match="not a closed two-manifold surface"):
        meshes.check_mesh(v, f[:-1], "box.obj")  # one triangle missing: a hole
    with pytest.raises(FileFormatError, match="refers to vertex"):
        meshes.check_mesh(v, np.vstack([f, [[0, 1, 99]]]), "box.obj")


def test_bad_mesh_files(tmp_path):
    (tmp_path / "empty.obj").write_text("# nothing\n")
    with pytest.raises(FileFormatError, match="empty.obj"):
        meshes.load_mesh(tmp_path / "empty.obj")
    (tmp_path / "nan.obj").write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n")
    with pytest.raises(FileFormatError, match="not finite"):
        meshes.load_mesh(tmp_path / "nan.obj")
    (tmp_path / "open.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\n")
    with pytest.raises(FileFormatError, match="two-manifold"):
        meshes.load_mesh(tmp_path / "open.obj")
    with pytest.raises(FileNotFoundError):
        meshes.load_mesh(tmp_path / "missing.obj")


def test_mesh_file_decomposes_and_caches(tmp_path, monkeypatch):
    monkeypatch.setenv("KINODYN_CACHE", str(tmp_path / "cache"))
    v, f = meshes.prism([[0, 0], [1, 0], [1, 0.2], [0.2, 0.2], [0.2, 1], [0, 1]], 0.5)
    import trimesh

    trimesh.Trimesh(v, f, process=False).export(tmp_path / "l.obj")
    v2, f2 = meshes.load_mesh(tmp_path / "l.obj")
    pieces = meshes.decompose(v2, f2)
    assert len(pieces) >= 2
    assert len(list((tmp_path / "cache" / "coacd").glob("*.npz"))) == 1
    again = meshes.decompose(v2, f2)
    assert all(np.array_equal(a, b) for a, b in zip(pieces, again))
    vol = sum(S.hull(p).volume() for p in pieces)
    assert abs(vol - 0.36 * 0.5) < 0.01 * 0.18


BAD = [
    ({"objects": [{"kind": "fixed", "shape": {"box": [1, 1, 1]}}]}, r"objects\[0\]: needs a name"),
    ({"objects": [{"name": "t", "kind": "floating", "shape": {"box": [1, 1, 1]}}]},
     r"objects\[0\] 't': kind must be one of fixed, simulated, driven, got 'floating'"),
    ({"objects": [{"name": "t", "material": "glass", "shape": {"box": [1, 1, 1]}}]},
     r"objects\[0\] 't': material must be one of wood, human, metal, got 'glass'"),
    ({"objects": [{"name": "t", "shape": {"box": [1, 1]}}]}, r"objects\[0\] 't': box must be 3 finite numbers"),
    ({"objects": [{"name": "t", "shape": {"box": [1, 1, 1]}, "pos": [0, 0]}]},
     r"objects\[0\] 't': pos must be 3 finite numbers"),
    ({"objects": [{"name": "t"}]}, r"objects\[0\] 't': needs exactly one of shape, pieces, mesh"),
    ({"objects": [{"name": "t", "shape": {"box": [1, 1, 1]}, "colour": "red"}]}, r"unknown keys \['colour'\]"),
    ({"objects": [{"name": "t", "shape": {"box": [1, 1, 1]}}, {"name": "t", "shape": {"sphere": 1}}]},
     "repeated: t"),
    ({"objects": [{"name": "t", "mesh": "missing.obj"}]}, r"objects\[0\] 't': .*missing.obj"),
    ({"objects": [{"name": "t", "shape": {"sphere": -1}}]}, r"objects\[0\] 't': sphere sizes must be positive"),
    ({"avatar": {"place": [0, 0, 0]}}, "avatar: must be a mapping with a motion"),
    ({"objets": []}, r"unknown top-level keys \['objets'\]"),
    ({"fps": -3}, "fps must be a positive number"),
]


@pytest.mark.parametrize("data,message", BAD)
def test_bad_scene_entries_name_the_entry(tmp_path, data, message):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(FileFormatError, match=message) as e:
        load_scene(path)
    assert "bad.yaml" in str(e.value)


def test_bad_yaml_names_the_line(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("objects:\n  - name: a\n    shape: {box: [1, 1, 1]\n")
    with pytest.raises(FileFormatError, match="broken.yaml:"):
        load_scene(path)


def test_piece_and_object_checks():
    with pytest.raises(ParameterError, match="box size must be 3 positive numbers"):
        S.box([1, -1, 1])
    with pytest.raises(ParameterError, match="needs at least one convex piece"):
        S.SceneObject("x", "fixed", "wood", ())
    with pytest.raises(KinodynError):
        parse_scene([1, 2, 3])


def test_shipped_scenarios_load():
    names = scenario_names()
    assert {"hand", "two_arms", "two_arms_leg", "self_collision", "arm_in_corner"} <= set(names)
    gallery = load_scene(scenario_path("gallery"))
    assert 18 <= len(gallery.objects) <= 24
    meshed = [o for o in gallery.objects if o.pieces[0].shape == "hull"]
    assert len(meshed) >= 4 and max(len(o.pieces) for o in meshed) >= 3
    hand = load_scene(scenario_path("hand"))
    assert hand.hand is not None and any(o.kind == "simulated" for o in hand.objects)
