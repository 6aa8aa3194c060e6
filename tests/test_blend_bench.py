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
    for key in ("sliding_ratio", "sliding_cm_s_synced", "sync_us_per_update", "characters_at_60fps",
                "mix_us_per_character_frame"):
        assert key in data["metrics"] and data["metrics"][key] > 0, key
    assert res.metrics["sliding_ratio"] >= 5.0
    assert res.metrics["err_frames_synced"] == 0
    assert data["baseline"]["mix_us_per_character_frame_unsynchronized"] > 0


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
