"""``kinodyn response play``'s viewer page: the impact arrow where the ball hit, the stages coloured."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from kinodyn.plotting import style
from kinodyn.response.command import STAGE_NAMES, viewer_overlays


def _hit(t, body, point, impulse, source="ball0", kind="projectile"):
    return SimpleNamespace(time=t, body=body, point=np.array(point, float), impulse=np.array(impulse, float),
                           source=source, kind=kind)


def test_hits_of_one_blow_make_one_arrow():
    from kinodyn.response.pipeline import Stages
    from kinodyn.viz.html import Impact, Marker
    from kinodyn.viz.objects import Stages as Bar

    hits = (_hit(1.0, "Spine1", (0, 0, 1.3), (-30, 0, 0)), _hit(1.01, "LeftArm", (0, 0.2, 1.4), (-10, 0, 0)),
            _hit(1.2, "Head", (0, 0, 1.7), (0, 5, 0), "b/RightHand", "character"))
    r = SimpleNamespace(motion=SimpleNamespace(fps=60.0), clip="fall_side", hits=hits,
                        stages=Stages((0, 60), (60, 72), (72, 90), (90, 150)))
    out = viewer_overlays(r, 0)
    arrows = [o for o in out if isinstance(o, Impact)]
    assert len(arrows) == 2, "the ball's two contacts are one blow, the fist another"
    np.testing.assert_allclose(arrows[0].impulse, (-40, 0, 0))
    np.testing.assert_allclose(arrows[0].point, (0, 0.05, 1.325))  # impulse-weighted
    assert arrows[0].time == 1.0 and arrows[0].label == "projectile on Spine1, LeftArm: 40 N s"
    bar = next(o for o in out if isinstance(o, Bar))
    assert bar.tint and [s[2] for s in bar.spans] == list(STAGE_NAMES)
    assert bar.spans[1][:2] == (1.0, 1.2) and bar.spans[-1][1] == 2.5
    assert [m.color for m in out if isinstance(m, Marker)] == [style.STAGE_COLORS[n] for n in STAGE_NAMES[1:]]


def test_play_writes_a_page_with_the_impact_and_the_stages(tmp_path):
    pytest.importorskip("sklearn")
    from kinodyn.cli import main
    from kinodyn.viz import html

    if not html.bundle_available():
        pytest.skip("viewer bundle not built (make)")
    page = tmp_path / "r.html"
    assert main(["response", "play", "--ball", "9,180,1.5,chest", "-o", str(tmp_path / "r.bvh"),
                 "--html", str(page)]) == 0
    text = page.read_text(encoding="utf-8")
    data = json.loads(text.split('id="kinodyn-data"')[1].split(">", 1)[1].split("</script>")[0])
    scene = data["scenes"][0]
    bar = next(p for p in scene["phases"] if p["label"].endswith("stages"))
    assert bar["tint"] and [s[2] for s in bar["spans"]] == list(STAGE_NAMES)
    assert all(a[1] == b[0] for a, b in zip(bar["spans"], bar["spans"][1:])), "the stages follow one another"
    (imp,) = scene["impacts"]
    assert abs(imp["t"] - bar["spans"][1][0]) < 0.02, "the arrow shows when the simulation starts"
    assert imp["impulse"][0] < -10 and abs(imp["impulse"][0]) > 3 * abs(imp["impulse"][1]), \
        "a ball flying along -X (direction 180) pushes along -X"
    pos = html.decode_positions(scene["characters"][0]["pos"], scene["characters"][0]["frames"],
                                len(scene["characters"][0]["parents"]))
    f = int(round(imp["t"] * scene["characters"][0]["fps"]))
    assert np.linalg.norm(pos[f] - np.array(imp["point"]), axis=1).min() < 0.25, "the arrow ends on the body"


def test_play_with_a_clip_folder_chooses_by_search_when_no_model_is_given(tmp_path, capsys):
    """The shipped model knows only the built-in clips: ``--library DIR`` without ``--model`` chooses among
    the folder's clips by exhaustive search and says so, from a BVH base motion of the same skeleton."""
    from kinodyn.cli import main
    from kinodyn.data import library as data
    from kinodyn.io import load, save

    folder = tmp_path / "clips"
    folder.mkdir()
    for name in ("fall_backward", "step_back_small"):
        save(folder / f"{name}.bvh", data.load(name))
    save(tmp_path / "walk.bvh", data.load("walk"))
    out = tmp_path / "r.bvh"
    assert main(["response", "play", "--base", str(tmp_path / "walk.bvh"), "--library", str(folder),
                 "--ball", "9,180,1.5,chest", "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert "exhaustive search" in captured.err
    assert load(out).num_frames > data.load("walk").num_frames // 2
    assert any(f"clip {n} " in captured.out for n in ("fall_backward", "step_back_small"))


def test_train_on_a_clip_folder_then_play_with_that_model(tmp_path, capsys):
    """``response train --library DIR`` labels the throws against the folder's clips (from a BVH base motion
    of their skeleton), so ``play --library DIR --model M`` chooses with the model trained on them; the
    model's command reproduces it, and a model for another library is refused."""
    pytest.importorskip("sklearn")
    from kinodyn.cli import main
    from kinodyn.data import library as data
    from kinodyn.errors import KinodynError
    from kinodyn.io import save
    from kinodyn.response.classifier import ReactionModel
    from kinodyn.response.command import DEFAULT_MODEL
    from kinodyn.response.dataset import Dataset
    from kinodyn.response.library import from_folder

    folder = tmp_path / "clips"
    folder.mkdir()
    names = ("fall_backward", "fall_forward", "step_back_small", "step_forward_small")
    for name in names:
        save(folder / f"{name}.bvh", data.load(name))
    save(tmp_path / "walk.bvh", data.load("walk"))
    model_dir, ds_path = tmp_path / "model", tmp_path / "ds.npz"
    assert main(["response", "train", "--cases", "48", "--base", str(tmp_path / "walk.bvh"),
                 "--library", str(folder), "--workers", "2", "--chunk-size", "12", "--kind", "small",
                 "--dataset", str(ds_path),
                 "-o", str(model_dir)]) == 0
    ds = Dataset.load(ds_path)
    assert tuple(ds.meta["clips"]) == names and ds.per_clip.shape == (48, 4)
    assert set(ds.clip[ds.valid()]) <= set(range(4)) and len(set(ds.clip[ds.valid()])) >= 2
    lib = from_folder(folder)
    model = ReactionModel.load(model_dir, lib)
    assert model.clips == names and "--base walk.bvh --library clips " in model.info["command"]
    capsys.readouterr()
    out = tmp_path / "r.bvh"
    assert main(["response", "play", "--base", str(tmp_path / "walk.bvh"), "--library", str(folder),
                 "--model", str(model_dir), "--ball", "9,180,1.5,chest", "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert "exhaustive search" not in captured.err and any(f"clip {n} " in captured.out for n in names)
    with pytest.raises(KinodynError):
        ReactionModel.load(DEFAULT_MODEL / "small", lib)
    assert main(["response", "play", "--base", "walk", "--fps", "30", "--ball", "9,180,1.5,chest",
                 "-o", str(out)]) == 2, "--fps without --library is refused"


def test_train_refuses_a_base_motion_of_another_skeleton_before_simulating(tmp_path):
    """A base motion the folder's clips cannot be matched against is an error up front, not thousands of
    failed throws."""
    from kinodyn.data import library as data
    from kinodyn.errors import KinodynError
    from kinodyn.io import save
    from kinodyn.response.dataset import generate

    folder = tmp_path / "clips"
    folder.mkdir()
    save(folder / "fall_backward.bvh", data.load("fall_backward").resample(30.0))
    with pytest.raises(KinodynError, match="fps"):
        generate(10, base="walk", library=folder, workers=1)
    with pytest.raises(KinodynError, match="cases"):
        generate(0, base="walk", workers=1)
    for bad in ({"fps": 60.0}, {"fps": -1.0, "library": folder}):
        with pytest.raises(KinodynError, match="fps"):
            generate(10, base="walk", workers=1, **bad)
    # resampled to the base motion's rate, the same clip labels the throws
    ds = generate(4, base="walk", library=folder, fps=60.0, workers=1, show_progress=False)
    assert "@ 60 fps" in ds.meta["library"] and ds.per_clip.shape == (4, 1)
    assert np.all(ds.clip[ds.valid()] == 0)


def test_play_with_candidates_explains_the_clips_it_timed(tmp_path, capsys):
    """``--candidates 3`` times the model's three most probable clips; explain.json lists them with their
    error D and the chosen clip is the one of lowest D. Without a model it and ``--align-stride`` are refused."""
    pytest.importorskip("sklearn")
    from kinodyn.cli import main

    out, explain = tmp_path / "r.bvh", tmp_path / "explain"
    assert main(["response", "play", "--seed", "9", "--candidates", "3", "-o", str(out), "--explain",
                 str(explain)]) == 0
    facts = json.loads((explain / "explain.json").read_text(encoding="utf-8"))
    timed = facts["candidates"]
    assert len(timed) == 3 and len({c["clip"] for c in timed}) == 3
    assert facts["clip"] == min(timed, key=lambda c: c["error"])["clip"]
    assert facts["error"] == min(c["error"] for c in timed)
    capsys.readouterr()
    assert main(["response", "play", "--seed", "9", "--candidates", "2", "--exhaustive", "-o", str(out)]) == 2
    assert "--candidates" in capsys.readouterr().err
    assert main(["response", "play", "--seed", "9", "--align-stride", "5", "--exhaustive", "-o", str(out)]) == 2
    assert "--align-stride" in capsys.readouterr().err
    assert main(["response", "play", "--seed", "9", "--candidates", "0", "-o", str(out)]) == 2
    assert main(["response", "play", "--seed", "9", "--align-stride", "0", "-o", str(out)]) == 2
