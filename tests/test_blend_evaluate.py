"""The sliding of a blend split into its measured causes (:func:`kinodyn.blend.evaluate.sliding_causes`):
the contributions add up to the sliding, and each responds to what it names."""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

from kinodyn.blend.evaluate import CAUSES, GROUPS, causes_table, evaluate, measure, sliding_causes, table
from kinodyn.blend.mixer import BlendConfig
from kinodyn.blend.script import build_library, parse_script, run_script
from kinodyn.blend.transitions import transition_script


def _play(actions, extra=None, ramp=0.0, synchronize=False, duration=3.0):
    s = parse_script({"fps": 60, "ramp_in": ramp, "ramp_out": ramp, "duration": duration, "actions": actions})
    cfg = BlendConfig(synchronize=synchronize, constraints="off", ramp_in=ramp, ramp_out=ramp)
    return run_script(s, library=build_library(s, extra), config=cfg)


@pytest.fixture(scope="module")
def walk():
    """The built-in walk played alone from the first frame (no ramp, no other action)."""
    return _play([{"clip": "walk", "start": 0.0}])


@pytest.fixture(scope="module")
def builtin():
    return evaluate(transition_script())


def test_the_causes_add_up_to_the_sliding_in_every_arm(builtin):
    print(table(builtin, "built-in figure 12/13 script"))
    for arm, f in builtin["arms"].items():
        c = f["causes"]
        assert c["sliding_cm_s"] == pytest.approx(f["sliding_cm_s"], abs=1e-9), arm
        assert c["planted_frames"] == f["planted_frames"], arm
        assert sum(c[f"sliding_{k}_cm_s"] for k in CAUSES) == pytest.approx(f["sliding_cm_s"], abs=1e-9), arm
        assert c["sliding_alone_cm_s"] + c["sliding_transition_cm_s"] == pytest.approx(f["sliding_cm_s"], abs=1e-9)
        assert c["share_alone"] + c["share_transition"] == pytest.approx(1.0)
        for g in GROUPS:  # each group's contribution is the sum of its causes
            assert sum(c[f"sliding_{g}_{k}_cm_s"] for k in CAUSES) == pytest.approx(c[f"sliding_{g}_cm_s"], abs=1e-9)
        assert c["share_swing"] <= c["share_transition"]
    # without synchronization nothing warps a clip's time: no warp term
    for arm in ("plain", "lock"):
        assert abs(builtin["arms"][arm]["causes"]["sliding_warp_cm_s"]) < 1e-6
    assert "tr_root" in causes_table(builtin) and "sliding by cause" in table(builtin)


def test_a_clip_played_alone_slides_by_its_own_sliding_only(walk):
    c = sliding_causes(walk)
    assert c["share_alone"] == 1.0 and c["share_transition"] == 0.0 and c["share_swing"] == 0.0
    assert c["sliding_own_cm_s"] > 0.5  # the built-in walk's planted feet creep a little
    assert c["sliding_cm_s"] - c["sliding_own_cm_s"] == pytest.approx(0.0, abs=0.2)
    assert abs(c["sliding_root_cm_s"]) + abs(c["sliding_pose_cm_s"]) < 0.2


def test_a_clip_that_slides_by_itself_shows_up_as_own(walk):
    """The walk with its root (so its planted feet too) drifting 10 cm/s: its own sliding grows by about
    that much (the mixer's support-following root motion takes it back: a negative root term)."""
    from kinodyn.data import library as data_lib

    w = data_lib.load("walk")
    rp = np.array(w.root_pos)
    rp[:, 0] += 0.1 * np.arange(w.num_frames) / w.fps
    drifting = _play([{"clip": "walk", "start": 0.0}], extra={"walk": (w.replace(root_pos=rp), True)})
    base, c = sliding_causes(walk), sliding_causes(drifting)
    assert c["sliding_own_cm_s"] - base["sliding_own_cm_s"] > 7.0
    assert c["sliding_root_cm_s"] < base["sliding_root_cm_s"] - 5.0


def test_time_warp_shows_up_as_warp(walk):
    """A record of the clip played at twice its speed: the warp term doubles the clip's own sliding."""
    rec = copy.deepcopy(walk.recording)
    for k in rec.action_time:
        rec.action_time[k] = {i: 2.0 * v for i, v in rec.action_time[k].items()}
    c = sliding_causes(dataclasses.replace(walk, recording=rec))
    assert c["sliding_own_cm_s"] > 0.5
    assert c["sliding_warp_cm_s"] == pytest.approx(c["sliding_own_cm_s"], rel=1e-6)


def test_root_motion_unlike_the_clip_shows_up_as_root(walk):
    """The blend's root pushed on at 10 cm/s with the pose unchanged: the root term grows by that much."""
    m = walk.motion
    rp = np.array(m.root_pos)
    rp[:, 0] += 0.1 * np.arange(m.num_frames) / m.fps
    base, c = sliding_causes(walk), sliding_causes(dataclasses.replace(walk, motion=m.replace(root_pos=rp)))
    assert c["sliding_own_cm_s"] == pytest.approx(base["sliding_own_cm_s"])
    assert c["sliding_root_cm_s"] - base["sliding_root_cm_s"] == pytest.approx(10.0, abs=1.0)
    assert abs(c["sliding_pose_cm_s"] - base["sliding_pose_cm_s"]) < 0.5


def test_a_pose_unlike_the_clip_shows_up_as_pose(walk):
    """The blend's joint rotations eight frames late over the same root path: the feet move under the
    root unlike the clip's, a pose term."""
    m = walk.motion
    late = dataclasses.replace(walk, motion=m.replace(local_rot=np.roll(m.local_rot, 8, axis=0)))
    base, c = sliding_causes(walk), sliding_causes(late)
    assert c["sliding_own_cm_s"] == pytest.approx(base["sliding_own_cm_s"])
    assert c["sliding_pose_cm_s"] - base["sliding_pose_cm_s"] > 20.0
    assert c["sliding_pose_cm_s"] > 4 * abs(c["sliding_root_cm_s"])


def test_swing_frames_are_transitions_where_another_clip_lifts_the_foot(walk):
    """Two copies of the walk in step are a transition throughout, but never disagree on a foot; a walk
    blended unsynchronized into a run does."""
    twins = _play([{"clip": "walk", "start": 0.0, "priority": 1},
                   {"clip": "walk", "start": 0.0, "priority": 1, "key": "twin"}])
    c = sliding_causes(twins)
    assert c["share_transition"] == 1.0 and c["share_swing"] == 0.0
    assert c["sliding_cm_s"] == pytest.approx(sliding_causes(walk)["sliding_cm_s"], abs=1e-6)
    into_run = _play([{"clip": "walk", "start": 0.0, "stop": 2.0, "priority": 1},
                      {"clip": "run", "start": 1.8, "priority": 1}], ramp=0.5, duration=None)
    c = sliding_causes(into_run)
    assert 0.0 < c["share_swing"] < c["share_transition"] < 1.0


def test_weight_shifting_between_feet_at_different_places_shows_up_as_weights(walk):
    """Weight ramping between two copies of the walk in step moves no foot (their feet are at the same
    places); ramping from the walk into the run, whose feet stand elsewhere from the root, does."""
    twins = _play([{"clip": "walk", "start": 0.0, "stop": 1.5, "priority": 1, "ramp_out": 0.5},
                   {"clip": "walk", "start": 0.0, "priority": 1, "key": "twin"}])
    c = sliding_causes(twins)
    assert c["share_transition"] > 0.3 and c["sliding_weights_cm_s"] == pytest.approx(0.0, abs=1e-9)
    assert sliding_causes(walk)["sliding_weights_cm_s"] == 0.0
    into_run = _play([{"clip": "walk", "start": 0.0, "stop": 2.0, "priority": 1},
                      {"clip": "run", "start": 1.8, "priority": 1}], ramp=0.5, duration=None)
    c = sliding_causes(into_run)
    assert c["sliding_transition_weights_cm_s"] > 1.0
    assert c["sliding_transition_weights_cm_s"] > 2 * abs(c["sliding_alone_weights_cm_s"]), c


def test_measure_carries_the_causes(walk):
    f = measure(walk)
    assert f["causes"] == sliding_causes(walk)
