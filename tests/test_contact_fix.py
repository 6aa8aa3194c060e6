"""Cleaning a real CMU walk (T-pose skeleton) against a floor-only scene changes only the frames that
overlap something: every other frame comes back bit for bit."""

import numpy as np
import pytest

from kinodyn.contact.fix import fix_motion, penetration_before
from kinodyn.contact.motions import scenario_motion
from kinodyn.contact.scenefile import load_scene
from kinodyn.math import quat

FLOOR = """name: floor_only
description: Only a floor.
objects:
  - {name: floor, material: wood, shape: {box: [20.0, 20.0, 0.05]}, pos: [0.0, 0.0, -0.05]}
"""


@pytest.fixture(scope="module")
def walk_fixed(tmp_path_factory):
    from conftest import mocap_files

    files = mocap_files("locomotion/cmu_02_01.bvh")
    if not files:
        pytest.skip("shared motion-capture folder not found")
    path = tmp_path_factory.mktemp("floor") / "floor.yaml"
    path.write_text(FLOOR)
    scene = load_scene(path)
    walk = scenario_motion(str(files[0]))[:160]  # two heel strikes and a pass of the swing foot
    fixed, report = fix_motion(walk, scene)
    return walk, scene, fixed, report


def test_frames_without_overlap_are_left_bit_identical(walk_fixed):
    walk, scene, fixed, _ = walk_fixed
    touching = penetration_before(walk, scene, self_collision=True) > 2e-4  # the driver's tolerance
    free = ~touching
    assert touching.sum() >= 10 and free.sum() >= 30  # both kinds of frame are there
    ang = quat.angle_between(fixed.local_rot[free], walk.local_rot[free])
    assert ang.max() <= 1e-9
    assert np.abs(fixed.root_pos[free] - walk.root_pos[free]).max() <= 1e-9


def test_overlapping_frames_are_resolved(walk_fixed):
    walk, scene, fixed, report = walk_fixed
    assert penetration_before(walk, scene).max() > 5e-3  # the body model's heels dip into the floor
    assert penetration_before(fixed, scene).max() <= 1e-3
    assert report["changed_deg"].max() > 1.0
