"""The simulated world: limp falls, kinematic playback, switching to dynamic, read-back, divergence."""

from __future__ import annotations

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from kinodyn.data import library
from kinodyn.data.skeleton import humanoid
from kinodyn.errors import MotionError, ParameterError, SimulationDivergedError, SimulationError
from kinodyn.math import quat
from kinodyn.physics.state import character_state
from kinodyn.physics.world import World, step_parallel
from kinodyn.skeleton import Skeleton

#: relative velocity change allowed across a kinematic -> dynamic switch (the issue's 5 %)
_SWITCH_VEL_TOL = 0.05


@pytest.fixture(scope="module")
def walk():
    return library.load("walk")


def test_limp_body_falls_and_comes_to_rest(body):
    w = World()
    c = w.add_character(body)
    c.set_gains(0.0)  # limp: only passive joint damping
    head0 = character_state(w, c).pos[c.map.body("Head")][2]
    w.run(4.0)
    st = character_state(w, c)
    assert np.isfinite(w.data.qpos).all() and np.isfinite(w.data.qvel).all()
    assert st.pos[c.map.body("Head")][2] < 0.4 * head0  # it collapsed
    assert np.abs(c.qvel).max() < 0.2  # and lies still
    assert np.linalg.norm(st.com_vel) < 0.02
    # resting on the ground, not sunk into it: every body origin above the floor
    assert st.pos[:, 2].min() > 0.0
    m = c.trajectory()
    assert m.num_frames == 4 * 60 + 1
    assert np.isfinite(m.local_rot).all()


def test_kinematic_playback_reads_back_exactly(body, walk):
    w = World()
    c = w.add_character(body)
    c.play(walk, align_floor=False)
    w.run(1.5)
    sim = c.trajectory()
    ref = walk[: sim.num_frames]
    np.testing.assert_allclose(sim.global_positions(), ref.global_positions(), atol=1e-9)
    # at any fps
    half = c.trajectory(fps=30)
    assert half.fps == 30 and half.num_frames == 46
    np.testing.assert_allclose(half.global_positions()[10], ref.global_positions()[20], atol=1e-9)


def test_feet_on_the_floor_during_playback(body, walk):
    w = World()
    c = w.add_character(body)
    c.play(walk)
    lows = []
    for _ in range(60):
        w.step()
        mujoco.mj_kinematics(w.model, w.data)
        low = min(w.data.geom_xpos[g][2] - (np.abs(w.data.geom_xmat[g].reshape(3, 3)[2]) @ w.model.geom_size[g])
                  for g in c.geom_ids if w.model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX)
        lows.append(low)
    assert abs(np.median(lows)) < 0.005  # the stance foot's sole is on the floor


def test_switch_mid_walk_is_continuous(body, walk):
    w = World()
    c = w.add_character(body)
    c.play(walk, loop=True)
    w.run(1.0)
    w.switch_to_dynamic(c)
    after0 = character_state(w, c)
    # positions and velocities at the switch are the clip's: joint positions by the clip's own forward
    # kinematics (frame 60 at t = 1 s; played on the floor, so up to one vertical shift), velocities by
    # central differences of them
    gp = walk.global_positions()
    joints = c.map.body_joint
    shift = after0.pos[:, 2] - gp[60, joints, 2]
    np.testing.assert_allclose(after0.pos[:, :2], gp[60, joints, :2], atol=1e-9)
    np.testing.assert_allclose(shift, shift[0], atol=1e-9)
    fd = (gp[61, joints] - gp[59, joints]) * walk.fps / 2.0
    rel = np.linalg.norm(after0.linvel - fd) / np.linalg.norm(fd)
    assert rel < 0.02, f"body velocities at the switch differ from the clip's by {rel:.1%}"
    w.step()  # one frame simulated
    sim = character_state(w, c)
    ref_w = World()
    r = ref_w.add_character(body)
    r.play(walk, loop=True)
    ref_w.run(1.0 + 1.0 / 60.0)
    ref = character_state(ref_w, r)
    # positions continue smoothly: the frame's displacement matches the clip's within 1 cm
    assert np.abs(sim.pos - ref.pos).max() < 0.01
    # velocities across the switch: within 5 % of the clip's (all bodies together, and the com)
    rel = np.linalg.norm(sim.linvel - ref.linvel) / np.linalg.norm(ref.linvel)
    assert rel < _SWITCH_VEL_TOL, f"body velocities changed by {rel:.1%} across the switch"
    rel_com = np.linalg.norm(sim.com_vel - ref.com_vel) / np.linalg.norm(ref.com_vel)
    assert rel_com < _SWITCH_VEL_TOL
    # the trajectory has no jump at the switch frame
    traj = c.trajectory()
    gp = traj.global_positions()
    steps = np.linalg.norm(np.diff(gp, axis=0), axis=-1).max(axis=1)
    assert steps[60] < 1.5 * steps[55:60].max()


def test_target_pose_for_another_skeleton_is_rejected(body, walk):
    w = World()
    c = w.add_character(body)
    other = Skeleton(["a", "b"], np.array([-1, 0]), np.array([[0, 0, 0], [0, 0, 1.0]]))
    from kinodyn.motion import Motion

    clip = Motion(other, np.zeros((3, 3)), quat.identity((3, 2)), 30.0)
    with pytest.raises(MotionError, match="another skeleton"):
        c.play(clip)
    with pytest.raises(MotionError, match="one rotation per joint"):
        c.track(quat.identity((5,)))
    w.switch_to_dynamic(c)
    with pytest.raises(MotionError, match="another skeleton"):
        c.track(clip)


def test_bad_world_parameters():
    with pytest.raises(ParameterError):
        World(fps=0)
    with pytest.raises(ParameterError):
        World(substeps=0)
    w = World()
    c = w.add_character(humanoid())
    with pytest.raises(ParameterError):
        c.set_gains(-1.0)
    with pytest.raises(ParameterError):
        w.add_character(humanoid(), name=c.name)
    with pytest.raises(ParameterError):
        w.add_projectile(mass=-1.0, radius=0.1)
    with pytest.raises(SimulationError):
        w.trajectory(c)  # nothing recorded yet


def test_divergence_is_detected_and_nothing_is_read_back(body, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # MuJoCo's default log file would land here
    w = World()
    c = w.add_character(body)
    pose = quat.identity((humanoid().num_joints,))
    pose[humanoid().index("LeftForeArm")] = quat.from_axis_angle([0, 1, 0], -1.5)
    c.track(pose)
    c.set_gains(1e5)  # absurd servos: explicit stiffness far beyond stability
    with pytest.raises(SimulationDivergedError) as e:
        w.run(2.0)
    assert e.value.step is not None and e.value.step > 0
    assert "diverged" in str(e.value)
    assert w.diverged
    with pytest.raises(SimulationDivergedError):
        c.trajectory()
    with pytest.raises(SimulationDivergedError):
        w.step()
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists(), "MuJoCo logged the divergence in the working directory"


def test_a_push_that_would_explode_the_state_is_refused_at_once(body, walk):
    """Regression: a huge push left body speeds in the thousands of m/s until the next step raised."""
    w = World()
    c = w.add_character(body)
    c.play(walk, loop=True)
    w.run(0.2)
    qpos, qvel = w.data.qpos.copy(), w.data.qvel.copy()
    with pytest.raises(ParameterError, match=r"would move .* above max_speed \(500\)"):
        w.push(c, "LeftHand", [0.0, 5000.0, 0.0])
    # nothing changed: still kinematic, same state, no impact logged, and it steps on
    assert c.mode == "kinematic" and not w.impacts
    np.testing.assert_array_equal(w.data.qpos, qpos)
    np.testing.assert_array_equal(w.data.qvel, qvel)
    w.push(c, "LeftHand", [0.0, 5.0, 0.0])
    assert c.mode == "dynamic" and np.abs(w.data.qvel).max() < w.config.max_speed
    w.step()


def test_exploding_velocity_is_detected(body):
    w = World(max_speed=50.0)
    c = w.add_character(body)
    w.data.qvel[c.vadr] = 80.0  # a root flung at 80 m/s
    with pytest.raises(SimulationDivergedError, match="velocity reached"):
        w.step()


def test_fixed_root_character_hangs(body, walk):
    from kinodyn.physics.body import BodyConfig

    w = World()
    c = w.add_character(humanoid(), config=BodyConfig(root="fixed"))
    w.place_root(c, [0.0, 0.0, 2.0], [1.0, 0.0, 0.0, 0.0])
    c.set_gains(0.0)
    w.run(1.0)
    st = character_state(w, c)
    assert st.pos[0] == pytest.approx([0.0, 0.0, 2.0])
    m = c.trajectory()
    assert m.root_pos[-1] == pytest.approx([0.0, 0.0, 2.0])


def test_several_characters_and_parallel_worlds(body, walk):
    worlds = []
    for k in range(2):
        w = World()
        for i in range(2):
            c = w.add_character(body, at=(3.0 * i, 3.0 * k, 0.0))
            c.play(walk, at=(3.0 * i, 3.0 * k, 0.0), loop=True)
            c.switch_to_dynamic()
        worlds.append(w)
    step_parallel(worlds, 20, threads=2)
    ref = World()
    for i in range(2):
        c = ref.add_character(body, at=(3.0 * i, 0.0, 0.0))
        c.play(walk, at=(3.0 * i, 0.0, 0.0), loop=True)
        c.switch_to_dynamic()
    ref.step(20)
    # threads change nothing: the same world stepped alone gives the same state
    np.testing.assert_allclose(worlds[0].data.qpos, ref.data.qpos, atol=1e-12)
    assert worlds[1].time == pytest.approx(20 / 60)


def test_characters_and_balls_added_later_keep_old_records(body, walk):
    w = World()
    a = w.add_character(body, name="a")
    a.play(walk, align_floor=False)
    w.run(0.5)
    w.add_projectile(2.0, 0.1)
    b = w.add_character(body, name="b", at=(3.0, 0.0, 0.0))
    b.play(walk, at=(3.0, 0.0, 0.0))
    w.run(0.5)
    ta, tb = a.trajectory(), b.trajectory()
    assert ta.num_frames == 61 and tb.num_frames == 30  # b is recorded from the first frame after t = 0.5 s
    np.testing.assert_allclose(ta.global_positions(), walk.resample(60.0)[:61].global_positions(), atol=1e-9)


def test_looped_walk_keeps_walking(body, walk):
    w = World()
    c = w.add_character(body)
    c.play(walk, loop=True, align_floor=False)
    w.run(5.0)
    sim = c.trajectory()
    x = sim.root_pos[:, 0]
    speed = np.diff(x) * 60.0
    assert speed.min() > 0.5  # never jumps back at a repetition
    assert x[-1] == pytest.approx(x[0] + 5.0 * (walk.root_pos[-1, 0] - walk.root_pos[0, 0]) / walk.duration, abs=0.05)
    # the joints repeat exactly
    np.testing.assert_allclose(sim.local_rot[150, 1:], walk.local_rot[30, 1:], atol=1e-9)


def test_play_from_a_phase_of_a_looped_clip(body, walk):
    w = World()
    c = w.add_character(body)
    c.play(walk, start=1.5, loop=True, at=(0.0, 0.0, 0.0), align_floor=False)
    w.run(1.0)
    sim = c.trajectory()
    assert np.abs(sim.root_pos[0, :2]).max() < 1e-9  # the frame at `start` stands at `at`
    speed = np.diff(sim.root_pos[:, 0]) * 60.0
    assert speed.min() > 0.5  # through the clip's end into the next repetition without a jump
    np.testing.assert_allclose(sim.local_rot[0, 1:], walk.local_rot[90, 1:], atol=1e-9)
    with pytest.raises(ParameterError):
        c.play(walk, start=5.0)
