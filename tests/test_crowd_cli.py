"""``kinodyn crowd``, ``kinodyn bench crowd`` plumbing and the registration literals."""

import ast
import json
from pathlib import Path

import numpy as np
import pytest

from kinodyn.cli import main

ROOT = Path(__file__).resolve().parents[1]


def test_run_writes_motions_viewer_and_snapshot(tmp_path, capsys):
    assert main(["crowd", "run", "--n", "6", "--seconds", "1.5", "--push", "2", "--balls", "1",
                 "-o", str(tmp_path)]) == 0
    z = np.load(tmp_path / "crowd.npz")
    assert z["root_pos"].shape[:2] == (91, 6) and z["local_rot"].shape[1:] == (6, 21, 4)
    assert (tmp_path / "crowd.html").stat().st_size > 10000
    assert (tmp_path / "crowd.png").exists()
    assert "6 characters" in capsys.readouterr().out


def test_run_bvh(tmp_path):
    from kinodyn.io import load

    assert main(["crowd", "run", "--n", "3", "--seconds", "0.5", "--format", "bvh", "-o", str(tmp_path)]) == 0
    files = sorted((tmp_path / "bvh").glob("*.bvh"))
    assert len(files) == 3
    m = load(files[0])
    assert m.num_joints == 21 and m.num_frames == 31


@pytest.mark.parametrize("argv,message", [
    (["--n", "0"], "--n must be between 1 and 20000"),
    (["--seconds", "-1"], "--seconds must be in (0, 600]"),
    (["--push", "-2"], "--push and --balls must be >= 0"),
    (["--keyframes", "missing.json"], "no such keyframe-set file"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, argv, message):
    code = main(["crowd", "run", "-o", str(tmp_path), "--seconds", "0.2", "--n", "2", *argv])
    err = capsys.readouterr().err.strip()
    assert code == 2 and message in err and len(err.splitlines()) == 1


def test_bad_keyframe_file_is_reported(tmp_path, capsys):
    bad = tmp_path / "k.json"
    bad.write_text(json.dumps({"format": "kinodyn-keyframe-set", "version": 1}))
    code = main(["crowd", "run", "-o", str(tmp_path), "--n", "2", "--seconds", "0.2", "--keyframes", str(bad)])
    assert code == 2 and "stride must be a finite number" in capsys.readouterr().err


def test_registration_literals():
    tree = ast.parse((ROOT / "src/kinodyn/crowd/register.py").read_text())
    values = {t.targets[0].id: ast.literal_eval(t.value) for t in tree.body if isinstance(t, ast.Assign)}
    assert values["COMMANDS"] == {"crowd": "kinodyn.crowd.command"}
    assert values["BENCHMARKS"] == {"crowd": "kinodyn.crowd.bench"}
    assert values["DEMO_PARTS"]["crowd"][0] == "kinodyn.crowd.demo"


def test_bench_measures_each_part_at_the_count():
    from kinodyn.crowd.bench import measure

    r = measure(20, frames=5, warmup=2)
    assert set(r) >= {"physics", "posing", "control", "total", "contacts_per_character", "bare", "compile"}
    assert r["total"] == pytest.approx(r["physics"] + r["posing"] + r["control"])
    assert r["bare"] > 0


def test_bench_judges_a_count_by_its_median_build(monkeypatch):
    """A count is within budget when its median build is: one fast build among slow ones is not enough."""
    import kinodyn.crowd.bench as bench

    builds = iter([0.010, 0.030, 0.031])  # seconds per frame of three builds of 500 characters
    monkeypatch.setattr(bench, "measure", lambda n, frames: {"total": 0.001 * n / 100 if n < 500 else next(builds)})
    r = bench.measure_builds(500, 5, 3)
    assert r["total"] == 0.030 and r["totals"] == [0.010, 0.030, 0.031]
    builds = iter([0.010, 0.030, 0.031])
    points = {100: {"total": 0.001}, 500: {"total": 0.010}}  # one lucky build of 500 within the budget
    assert bench._search(points, 5, lambda s: None, builds=3) == 400  # 500 judged by its median build


def test_bench_builds_again_only_the_counts_near_the_budget(monkeypatch):
    """Counts within a factor of two of the frame budget are built again; a count far below or above
    it is judged by its one build (builds differ by less than that), and candidates between the two
    nearest counts are bisected."""
    import kinodyn.crowd.bench as bench

    calls = []

    def fake(n, frames):
        calls.append(n)
        return {"total": 0.004 * n / 1000}

    monkeypatch.setattr(bench, "measure", fake)
    points = {n: {"total": 0.004 * n / 1000} for n in (100, 3000, 6000, 20000)}
    best = bench._search(points, 5, lambda s: None, builds=3)
    assert set(calls[:6]) == {3000} | {6000} and calls[:6] == [3000] * 3 + [6000] * 3
    assert 100 not in calls and 20000 not in calls
    assert 3000 <= best < 6000 and best * 0.004 / 1000 <= bench.FRAME_BUDGET


def test_bench_arms_take_turns_on_one_bare_state(monkeypatch):
    """The bare arm is timed in turns with the crowd's frames, stepping one state on (not a fresh one
    per turn), for as many frames in all as the crowd."""
    import kinodyn.crowd.bench as bench

    turns, real = [], bench.measure_bare

    def spy(model, substeps, frames, data=None):
        turns.append((frames, data))
        return real(model, substeps, frames, data)

    monkeypatch.setattr(bench, "measure_bare", spy)
    bench.measure(12, frames=25, warmup=2, block=10)
    assert [f for f, _ in turns] == [10, 10, 5]
    assert turns[0][1] is not None and all(d is turns[0][1] for _, d in turns)
