"""``kinodyn bench blend``: the metrics exist and are sane (speed goals are checked by the benchmark)."""

from __future__ import annotations

import json

import pytest


@pytest.mark.slow
def test_bench_blend_quick_writes_the_metrics(tmp_path):
    from kinodyn import bench

    path = tmp_path / "blend.json"
    res = bench.run("blend", quick=True, json_path=path)
    data = json.loads(path.read_text())
    for key in ("sliding_ratio", "sliding_ratio_sync_only", "sliding_cm_s_synced", "lock_p95_cm", "lock_max_cm",
                "lock_p95_ratio", "pelvis_acc_ratio", "sync_us_per_update", "characters_at_60fps",
                "mix_us_per_character_frame"):
        assert key in data["metrics"] and data["metrics"][key] > 0, key
    assert res.metrics["err_frames_synced"] == 0
    assert data["baseline"]["mix_us_per_character_frame_unsynchronized"] > 0
    # measured at the count it reports: a crowd of that size fitted the 60 fps frame budget
    assert res.metrics["frame_ms_at_characters_at_60fps"] <= 1e3 / 60.0


def test_crowd_benchmark_runs_small():
    from kinodyn.blend.bench import crowd_benchmark

    r = crowd_benchmark(4, 0.5)
    assert r["frames"] == 30  # 0.5 s at 60 fps
    assert r["us_per_char_frame"] == pytest.approx(r["frame_ms"] * 1e3 / 4)
    assert r["updates_per_char_s"] == pytest.approx(r["updates"] / (4 * 0.5))
    # walk, run and a fast walk at one priority; the run is restarted now and then (2 or 3 contribute)
    assert 2.0 <= r["mean_actions"] <= 3.0
    # steps are entered at the gait's pace: a few support phases a second per character, not per frame
    assert 2.0 <= r["updates_per_char_s"] <= 12.0, r


def test_characters_at_60fps_is_timed_at_the_count_it_reports():
    """The count comes from a crowd of that size that was timed within the budget, never from a cost
    measured at another count and divided into the budget."""
    from kinodyn.blend.bench import _library, characters_at_60fps

    budget = 5.0
    r = characters_at_60fps(_library(), 0.1, start=8, budget_ms=budget)
    assert r["characters"] > 0 and r["frame_ms"] <= budget


def test_the_bench_reports_the_sliding_causes_beside_the_headline():
    """The plain and sync arms' sliding causes go into the benchmark's figures under their own keys, the
    existing keys unchanged, and add up to the arm's sliding there too."""
    from kinodyn.bench import BenchResult
    from kinodyn.blend.bench import HEADLINE, add_sliding
    from kinodyn.blend.evaluate import CAUSES, evaluate
    from kinodyn.blend.transitions import transition_script

    res = BenchResult("blend")
    add_sliding(res, {"builtin": evaluate(transition_script())})
    assert all(k in res.metrics for k in HEADLINE)
    b = res.baseline
    for arm in ("plain", "sync"):
        parts = [b[f"{arm}_sliding_{c}_cm_s"] for c in CAUSES]
        assert sum(parts) == pytest.approx(b[f"{arm}_sliding_cm_s"], abs=1e-9)
        assert b[f"{arm}_sliding_transition_cm_s"] + b[f"{arm}_sliding_alone_cm_s"] == pytest.approx(
            b[f"{arm}_sliding_cm_s"], abs=1e-9)
        assert 0.0 < b[f"{arm}_share_transition"] < 1.0
    assert "lock_sliding_own_cm_s" not in b  # the causes of the two arms without the lock only


def test_characters_at_60fps_keeps_searching_after_overruns(monkeypatch):
    """Tries that overrun the budget (a loaded machine) bracket the search instead of ending it: with a
    cost of 0.02 ms per character and every count from 400 up overrunning, the search still finds a
    count between 300 and 400 rather than stopping at its first crowd of 200."""
    from kinodyn.blend import bench

    def fake(n, seconds, synchronize=True, library=None):
        ms = 0.02 * n if n < 400 else 100.0
        return {"frame_ms": ms, "us_per_char_frame": 1e3 * ms / n}

    monkeypatch.setattr(bench, "crowd_benchmark", fake)
    r = bench.characters_at_60fps(None, 0.1, start=200, budget_ms=8.0)
    assert 300 <= r["characters"] < 400 and r["frame_ms"] <= 8.0
