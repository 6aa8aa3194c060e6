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
    assert r["updates"] > 0 and r["us_per_char_frame"] > 0 and r["mean_actions"] >= 2
