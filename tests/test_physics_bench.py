"""The physics benchmark's pieces (the timings themselves live in ``kinodyn bench physics``)."""

from __future__ import annotations

import pytest

pytest.importorskip("mujoco")

from kinodyn import bench, registry
from kinodyn.physics import bench as physics


def test_registered():
    assert registry.benchmarks()["physics"] == "kinodyn.physics.bench"
    assert bench.get("physics") is physics.run


def test_tracked_world_and_measurement():
    w = physics.tracked_world(2)
    assert len(w.characters) == 2 and all(c.mode == "dynamic" for c in w.characters)
    wall, cpu = physics.measure_world([w], 0.1)
    assert wall > 0 and cpu > 0
    sps, rtf, rtf_cpu = physics._rtf(1, 0.1, None, None, repeats=1)
    assert sps > 0 and rtf > 0 and rtf_cpu > 0
