"""The avatar loop: in every frame of every avatar scenario no segment stays inside a fixed object, and
every chain IK solved is inside its limits and reach cones."""

import numpy as np
import pytest

from kinodyn.contact.scenefile import load_scene, scenario_path
from kinodyn.contact.simulate import ContactSimulation
from kinodyn.ik import ccd
from kinodyn.math import quat

AVATAR_SCENARIOS = ["two_arms", "self_collision", "two_arms_leg", "arm_in_corner", "walk_into_wall"]


def _scene(name):
    scene = load_scene(scenario_path(name))
    if scene.avatar.motion.startswith("mocap:"):  # a real CMU walk from the shared data
        from conftest import MOCAP

        if not (MOCAP / scene.avatar.motion[len("mocap:"):]).is_file():
            pytest.skip("shared motion-capture folder not found")
        from kinodyn.contact.command import with_motion

        scene = with_motion(scene, mocap=MOCAP)
    return scene


@pytest.mark.parametrize("name", AVATAR_SCENARIOS)
def test_no_segment_stays_inside_a_fixed_object_and_limits_hold(name):
    """Every frame of the scenario: after resolution no avatar segment penetrates a fixed object by
    more than 1 mm (measured afresh, not from the solver's own figure), and every joint of every chain
    that IK solved is inside its limits and reach cone."""
    sim = ContactSimulation(_scene(name))
    av, w, first = sim.avatar, sim.world, sim.first
    lims = [ccd.chain_limits(av.limits, av.cone_axes, av.cone_points, c) for c in av.chains]
    fixed = np.array([o.kind == "fixed" for o in w.objects])
    segs = np.arange(len(av.segments)) + first
    worst, touched, solved = 0.0, 0, 0
    for f in range(sim.num_frames()):
        _, q = sim.frame(f, {})
        c = w.contacts(segs)
        hit = fixed[c.object_a] | fixed[c.object_b]
        if hit.any():
            worst = max(worst, float(c.depth[hit].max()))
        for c in sim.driver.stats.solved:  # every chain IK solved (or still holds) this frame
            assert ccd.limits_hold(q[av.chains[c]], lims[c]).all(), f"frame {f}"
        solved += len(sim.driver.stats.solved)
        tq = sim.tracked.local_rot[min(f, sim.tracked.num_frames - 1)]
        touched += bool(np.any(quat.angle_between(q, tq) > 1e-3))
    assert worst <= 1e-3, f"{name}: {worst * 1e3:.2f} mm"
    assert touched > 0 and solved > 0  # the scenario does steer the avatar into something
