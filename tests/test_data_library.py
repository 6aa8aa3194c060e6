"""The built-in motion library: skeleton, two-bone IK, every clip's quality gates and what each clip does."""

from __future__ import annotations

import numpy as np
import pytest

from kinodyn import limits
from kinodyn.contacts import ContactConfig, detect, foot_points, sliding
from kinodyn.data import keyed, legik, library, procedural
from kinodyn.data.skeleton import FOREARM, SHIN, THIGH, UPPER_ARM, humanoid
from kinodyn.errors import ParameterError, UnknownNameError
from kinodyn.io.bvh import read_bvh, write_bvh
from kinodyn.kinematics import end_site_positions, forward_kinematics
from kinodyn.math import quat, xform

_IK_TOL = 1e-9
_LOOP_TOL = 1e-6
_FLOOR_TOL = 1e-3  # no joint or end site more than 1 mm under the floor
_SLIDE_MAX = 0.02  # m/s, mean foot sliding with the default contact thresholds
# The turns pivot each planted foot about its ankle: the ankle stays put while the toe tips sweep the floor
# (p95 0.37 m/s). Contact detection counts a foot planted on its heel while its toes sweep, and the sliding
# measure follows the lowest point (a toe tip), so a turn reads about 4 cm/s. A fall to the side pivots
# its feet the same way as the body tips over them (3.3 cm/s).
_SLIDE_MAX_TURN = 0.045
_PIVOTING = ("turn", "fall_side")

ALL = library.names()
BASE = ["idle", "fighting_stance", "walk", "run", "turn_left", "turn_right", "jump", "punch", "kick", "push",
        "step_forward_small", "step_forward_large", "step_back_small", "step_back_large", "steps_back", "steps_forward",
        "stumble_side_left", "stumble_side_right", "fall_forward", "fall_backward", "fall_side", "roll_forward",
        "roll_backward", "get_up_face_down", "get_up_face_up", "flinch_front", "flinch_side_left",
        "flinch_side_right", "flinch_back"]
JOINTS = ("Hips", "Spine", "Spine1", "Neck", "Head", "LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand",
          "RightShoulder", "RightArm", "RightForeArm", "RightHand", "LeftUpLeg", "LeftLeg", "LeftFoot",
          "LeftToeBase", "RightUpLeg", "RightLeg", "RightFoot", "RightToeBase")


def _positions(m):
    gr, gp = forward_kinematics(m)
    return gp, end_site_positions(m, gr, gp)


def _root_displacement(m) -> np.ndarray:
    return m.root_pos[-1] - m.root_pos[0]


def _heading_change_deg(m) -> float:
    g = m.ground()
    return float(np.rad2deg(np.sum(xform.wrap_angle(np.diff(g[:, 2])))))


# --------------------------------------------------------------------------- skeleton


def test_humanoid_skeleton():
    sk = humanoid()
    assert sk is humanoid()
    assert sk.names == JOINTS
    assert 1.65 < sk.height() < 1.85
    assert sk.mirrored() is sk, "the skeleton must be exactly left/right symmetric"
    assert len(sk.end_parents) == 5
    ends = {sk.names[p] for p in sk.end_parents}
    assert ends == {"Head", "LeftHand", "RightHand", "LeftToeBase", "RightToeBase"}
    rest = sk.rest_positions()
    assert rest[sk.index("Head"), 2] > 0 > rest[sk.index("LeftFoot"), 2]
    assert rest[sk.index("LeftArm"), 1] > 0 > rest[sk.index("RightArm"), 1], "left is +Y"
    assert rest[sk.index("LeftToeBase"), 0] > rest[sk.index("LeftFoot"), 0], "feet point to +X"


def test_limit_hinges_match_the_ik_hinges():
    """The IK flexes knees about +Y and elbows about -Y; kinodyn.limits must agree."""
    sk = humanoid()
    lim = limits.limits_for(sk)
    for side in ("Left", "Right"):
        knee, elbow = lim[sk.index(f"{side}Leg")], lim[sk.index(f"{side}ForeArm")]
        assert knee.kind == "hinge" and np.allclose(knee.axis, [0, 1, 0])
        assert elbow.kind == "hinge" and np.allclose(elbow.axis, [0, -1, 0])


# --------------------------------------------------------------------------- two-bone IK


@pytest.mark.parametrize("hinge", [(0.0, 1.0, 0.0), (0.0, -1.0, 0.0)])
def test_two_bone_ik_reaches_reachable_targets(rng, hinge):
    n = 500
    l1, l2 = 0.43, 0.39
    root = rng.normal(size=(n, 3))
    parent = quat.normalize(rng.normal(size=(n, 4)))
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    dist = rng.uniform(abs(l1 - l2) + 0.01, l1 + l2 - 0.001, size=n)
    target = root + direction * dist[:, None]
    pole = rng.normal(size=(n, 3))
    sol = legik.two_bone_ik(root, parent, target, pole, l1, l2, hinge=hinge)
    mid, end = legik.two_bone_fk(root, parent, sol.upper_local, sol.lower_local, l1, l2)
    np.testing.assert_allclose(end, target, atol=_IK_TOL)
    assert sol.reached.all()
    assert np.all((sol.angle >= 0) & (sol.angle <= np.pi))
    # The middle joint lies on the pole's side of the root-target line.
    u = direction
    m = pole - np.sum(pole * u, -1, keepdims=True) * u
    off = (mid - root) - np.sum((mid - root) * u, -1, keepdims=True) * u
    assert np.all(np.sum(off * m, -1) > 0)
    # The middle joint is a pure hinge about its axis.
    np.testing.assert_allclose(sol.lower_local, quat.from_axis_angle(hinge, sol.angle), atol=1e-12)


def test_two_bone_ik_out_of_reach_points_at_target():
    root = np.zeros(3)
    target = np.array([0.0, 0.0, -2.0])
    sol = legik.two_bone_ik(root, quat.identity(), target, [1.0, 0, 0], THIGH, SHIN)
    assert not sol.reached
    _, end = legik.two_bone_fk(root, quat.identity(), sol.upper_local, sol.lower_local, THIGH, SHIN)
    np.testing.assert_allclose(end / np.linalg.norm(end), [0, 0, -1], atol=1e-6)


def test_two_bone_ik_rejects_bad_input():
    with pytest.raises(ParameterError):
        legik.two_bone_ik(np.zeros(3), quat.identity(), [0, 0, -0.5], [1, 0, 0], -1.0, 0.4)
    with pytest.raises(ParameterError):
        legik.two_bone_ik(np.zeros(3), quat.identity(), [0, 0, -0.5], [1, 0, 0], 0.4, 0.4, hinge=(0, 0, 1))


def test_knee_bends_forward_and_elbow_backward():
    """Knees point toward the pole (forward): flexion moves the foot back, as in limits.py."""
    sol = legik.two_bone_ik(np.zeros(3), quat.identity(), [0.0, 0.0, -0.7], [1.0, 0, 0], THIGH, SHIN)
    mid, _ = legik.two_bone_fk(np.zeros(3), quat.identity(), sol.upper_local, sol.lower_local, THIGH, SHIN)
    assert mid[0] > 0.1 and sol.angle > 0
    sol = legik.two_bone_ik(np.zeros(3), quat.identity(), [0.0, 0.0, -0.4], [-1.0, 0, 0], UPPER_ARM, FOREARM,
                            hinge=(0, -1, 0))
    mid, _ = legik.two_bone_fk(np.zeros(3), quat.identity(), sol.upper_local, sol.lower_local, UPPER_ARM,
                               FOREARM)
    assert mid[0] < -0.1 and sol.angle > 0


def test_euler_convention():
    """+ry bends the spine forward (its +Z toward +X); +rx raises the left arm (its -Z toward +Y)."""
    np.testing.assert_allclose(quat.mul_vec(procedural.euler([0, 90, 0]), [0, 0, 1]), [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(quat.mul_vec(procedural.euler([90, 0, 0]), [0, 0, -1]), [0, 1, 0], atol=1e-12)
    q = procedural.euler([10, 20, 30])
    np.testing.assert_allclose(q, quat.mul(quat.mul(procedural.euler([0, 0, 30]), procedural.euler([0, 20, 0])),
                                           procedural.euler([10, 0, 0])), atol=1e-12)


def test_foot_plan_holds_planted_feet_exactly():
    start = procedural.stance_state("Left")
    plan = procedural.FootPlan(start)
    target = procedural.stance_state("Left", x=0.5)
    plan.step(0.5, 0.9, target, height=0.08, heel_off=0.2, heel_pitch_deg=30)
    t = procedural.frame_times(1.5)
    ball, _, _ = plan.sample(t)
    before, after = t <= 0.5, t >= 0.9
    assert np.all(ball[before] == start.ball), "the ball stays put during stance and heel-off"
    assert np.all(ball[after] == target.ball)
    assert np.all(ball[:, 2] >= start.ball[2] - 1e-12)
    with pytest.raises(ParameterError):
        plan.step(0.2, 0.4, target)


# --------------------------------------------------------------------------- registry


def test_names_cover_the_issue():
    for n in BASE:
        assert n in ALL, n
    assert len(ALL) == len(set(ALL))
    for n in ("punch", "kick", "push"):
        assert f"{n}_mirror" in ALL
    assert ALL[:len(BASE)] == BASE


def test_info_and_describe():
    for n in ALL:
        i = library.info(n)
        assert i.name == n and i.description and isinstance(i.tags, tuple)
        assert i.cyclic == (n in ("idle", "fighting_stance", "walk", "run"))
        line = library.describe(n)
        assert "\n" not in line and "frames" in line
    assert library.info("punch_mirror").mirror_of == "punch"
    assert library.info("turn_right").mirror_of == "turn_left"
    assert "left" in library.info("punch_mirror").description
    assert library.info("walk").mirror_of is None


def test_unknown_clip_lists_the_clips():
    with pytest.raises(UnknownNameError, match="walk"):
        library.load("moonwalk")
    with pytest.raises(KeyError):
        library.info("moonwalk")


def test_keyframe_file_is_complete():
    data = keyed.keyframe_data()
    assert data["format"] == "kinodyn.keyframes/1"
    for name in keyed.keyed_names():
        spec = keyed.clip_spec(name)
        assert spec["description"] and spec["tags"] and spec["duration"] > 0
        times = [k["t"] for k in spec["root"]]
        assert times == sorted(times) and times[0] == 0.0 and times[-1] == spec["duration"]


def test_generation_is_cached():
    """Each clip is generated once per process (its speed is `kinodyn bench io`'s library_generate_s)."""
    library._generate.cache_clear()
    first = {n: library.load(n) for n in ALL}
    assert all(library.load(n) is first[n] for n in ALL)
    assert library._generate.cache_info().misses == len(set(ALL) | set(library.MIRRORED.values()))


# --------------------------------------------------------------------------- quality gates, every clip


@pytest.mark.parametrize("name", ALL)
def test_clip_is_well_formed(name):
    m = library.load(name)
    assert m.name == name
    assert m.fps == 60.0
    assert m.skeleton is humanoid()
    assert m.num_frames > 30
    assert np.all(np.isfinite(m.root_pos)) and np.all(np.isfinite(m.local_rot))
    np.testing.assert_allclose(np.linalg.norm(m.local_rot, axis=-1), 1.0, atol=1e-9)
    assert library.ik_error(name) < 1e-6, "every planned foot and hand position must be reachable"


@pytest.mark.parametrize("name", ALL)
def test_clip_feet_do_not_slide(name):
    report = sliding(library.load(name))
    bound = _SLIDE_MAX_TURN if name.startswith(_PIVOTING) else _SLIDE_MAX
    assert report.mean < bound, f"{name}: foot sliding {report.cm_per_s:.2f} cm/s"


@pytest.mark.parametrize("name", ALL)
def test_clip_stays_above_the_floor(name):
    gp, ep = _positions(library.load(name))
    low = min(gp[..., 2].min(), ep[..., 2].min())
    assert low >= -_FLOOR_TOL, f"{name}: a body point goes {-100 * low:.1f} cm under the floor"


@pytest.mark.parametrize("name", ALL)
def test_clip_joint_angles_are_human(name):
    report = limits.violations(library.load(name))
    assert report.ok, f"{name}: {report}"


@pytest.mark.parametrize("name", ["idle", "walk", "run"])
def test_cyclic_clips_loop(name):
    m = library.load(name)
    assert quat.angle_between(m.local_rot[-1], m.local_rot[0]).max() < _LOOP_TOL
    shift = m.root_pos[-1] - m.root_pos[0]
    assert abs(shift[2]) < _LOOP_TOL
    gp, _ = _positions(m)
    np.testing.assert_allclose(gp[-1] - shift, gp[0], atol=_LOOP_TOL)
    # Root velocity continuous across the loop point: the second difference at the seam of the clip
    # repeated end to end is no larger than anywhere inside it.
    p = m.root_pos
    seam = p[1] - 2.0 * p[0] + (p[-2] - shift)
    inner = np.abs(p[2:] - 2.0 * p[1:-1] + p[:-2]).max(axis=0)
    assert np.all(np.abs(seam) <= inner + 1e-12)


def test_mirrors_are_mirror_images():
    for name, src in library.MIRRORED.items():
        m, s = library.load(name), library.load(src)
        assert m.skeleton is s.skeleton
        ref = s.mirrored()
        np.testing.assert_allclose(m.root_pos, ref.root_pos, atol=1e-12)
        assert quat.angle_between(m.local_rot, ref.local_rot).max() < 1e-9
        np.testing.assert_allclose(m.root_pos[:, 1], -s.root_pos[:, 1], atol=1e-12)


# --------------------------------------------------------------------------- each clip does what it says


def test_walk_speed_and_support():
    m = library.load("walk")
    speed = _root_displacement(m)[0] / m.duration
    assert 1.2 <= speed <= 1.6
    c = detect(m)
    assert np.all(c.labels["left"] | c.labels["right"]), "a walk always has a foot on the ground"
    assert (c.labels["left"] & c.labels["right"]).any(), "and double support"
    assert abs(_root_displacement(m)[1]) < 1e-9


def test_run_is_faster_with_flight():
    walk, run = library.load("walk"), library.load("run")
    v_run = _root_displacement(run)[0] / run.duration
    assert v_run > 2.5 and v_run > 1.8 * _root_displacement(walk)[0] / walk.duration
    c = detect(run)
    flight = ~c.labels["left"] & ~c.labels["right"]
    assert flight.sum() >= 8, "a run has flight phases where no foot touches"


@pytest.mark.parametrize("name,sign", [("turn_left", 1.0), ("turn_right", -1.0)])
def test_turn_in_place(name, sign):
    m = library.load(name)
    assert sign * _heading_change_deg(m) == pytest.approx(90.0, abs=5.0)
    assert np.linalg.norm(m.root_pos[:, :2] - m.root_pos[0, :2], axis=1).max() < 0.1


def test_jump_has_flight_and_lands():
    m = library.load("jump")
    c = detect(m)
    flight = ~c.labels["left"] & ~c.labels["right"]
    assert flight.sum() >= 15
    assert c.labels["left"][-10:].all() and c.labels["right"][-10:].all()
    pts = foot_points(m)
    assert min(p[..., 2].min(axis=1).max() for p in pts.values()) > 0.15, "both feet leave the floor"
    assert abs(m.root_pos[-1, 2] - m.root_pos[0, 2]) < 0.02


@pytest.mark.parametrize("name", ["fall_forward", "fall_backward", "fall_forward_mirror", "fall_backward_mirror"])
def test_falls_end_lying(name):
    m = library.load(name)
    assert m.root_pos[-1, 2] < 0.35
    assert 0.08 < m.root_pos[-1, 2] < 0.16, "the pelvis rests about its radius above the floor"
    gp, _ = _positions(m)
    torso = [humanoid().index(j) for j in ("Hips", "Spine", "Spine1", "Neck")]
    assert gp[-1, torso, 2].max() < 0.25, "the torso lies on the floor"
    pitch = np.rad2deg(quat.angle(quat.remove_heading(m.local_rot[-1, 0])))
    assert pitch > 75.0
    direction = np.sign(_root_displacement(m)[0])
    assert direction == (1.0 if "forward" in name else -1.0)


@pytest.mark.parametrize("name,sign", [("fall_side", 1.0), ("fall_side_mirror", -1.0)])
def test_side_fall_ends_lying_on_its_side(name, sign):
    m = library.load(name)
    d = _root_displacement(m)
    assert sign * d[1] > 0.6 and abs(d[0]) < 0.1, "falls toward the side it was pushed to"
    gp, _ = _positions(m)
    torso = [humanoid().index(j) for j in ("Hips", "Spine", "Spine1", "Neck")]
    assert gp[-1, torso, 2].max() < 0.3, "the torso lies on the floor"
    up = quat.mul_vec(m.local_rot[-1, 0], [0.0, 0.0, 1.0])
    assert sign * up[1] > 0.9, "the spine lies along the floor toward the fall"
    hips = [humanoid().index(f"{s}UpLeg") for s in ("Left", "Right")]
    low, high = (0, 1) if sign > 0 else (1, 0)
    assert gp[-1, hips[low], 2] < gp[-1, hips[high], 2] - 0.1, "lying on the side it fell toward"


@pytest.mark.parametrize("name,sign", [("roll_forward", 1.0), ("roll_backward", -1.0), ("roll_forward_mirror", 1.0),
                                       ("roll_backward_mirror", -1.0)])
def test_rolls_turn_over_and_stand_up(name, sign):
    """A roll turns the pelvis once over about the lateral axis in the direction of travel, carries the body
    along the floor on its back and shoulders, and ends standing on both feet where it is going."""
    m = library.load(name)
    d = _root_displacement(m)
    assert sign * d[0] > 1.0 and abs(d[1]) < 0.05
    up = quat.mul_vec(m.local_rot[:, 0], [0.0, 0.0, 1.0])
    pitch = np.unwrap(np.arctan2(up[:, 0], up[:, 2]))
    turned = np.rad2deg(pitch[-1] - pitch[0])
    assert sign * turned == pytest.approx(360.0, abs=10.0), "one full turn, forward for a forward roll"
    assert up[:, 2].min() < -0.8, "the body goes upside down"
    gp, _ = _positions(m)
    sk = humanoid()
    torso = [sk.index(j) for j in ("Hips", "Spine", "Spine1", "Neck", "LeftArm", "RightArm")]
    rolling = up[:, 2] < 0.0
    low = gp[rolling][:, torso, 2].min(axis=1)
    assert np.median(low) < 0.2 and low.min() < 0.12, "upside down, the back and shoulders roll on the floor"
    assert m.root_pos[-1, 2] > 0.95, "stands up at the end"
    c = detect(m)
    assert c.labels["left"][-5:].all() and c.labels["right"][-5:].all(), "ends standing on both feet"


@pytest.mark.parametrize("fall", list(library.GET_UP))
def test_get_ups_start_where_their_fall_ends_and_stand(fall):
    """A get-up's first frame is its fall's last one (placed on the floor where the fall ends); it pushes the
    body up from the floor and ends standing on both feet in the neutral stance."""
    getup, down = library.load(library.GET_UP[fall]), library.load(fall)
    assert "getup" in library.info(getup.name).tags and "reaction" not in library.info(getup.name).tags
    placed = getup.aligned_to(down.ground()[-1], 0)
    gp_fall, _ = _positions(down)
    gp_up, _ = _positions(placed)
    np.testing.assert_allclose(gp_up[0], gp_fall[-1], atol=1e-3, err_msg=fall)
    sk = humanoid()
    head = sk.index("Head")
    assert gp_up[0, head, 2] < 0.3 and gp_up[-1, head, 2] > 1.5, "from lying to standing"
    assert getup.root_pos[-1, 2] == pytest.approx(library.load("idle").root_pos[0, 2], abs=0.01)
    c = detect(getup)
    assert c.labels["left"][-10:].all() and c.labels["right"][-10:].all(), "ends on both feet"
    g = placed.ground()[-1]
    for side in ("Left", "Right"):
        ball = gp_up[-1, sk.index(f"{side}ToeBase")]
        ref = procedural.stance_state(side, g[0], g[1], g[2]).ball
        assert np.linalg.norm(ball[:2] - ref[:2]) < 0.03, f"{side} foot in the neutral stance"


@pytest.mark.parametrize("name,sign,least", [("step_back_small", -1, 0.12), ("step_back_large", -1, 0.35),
                                             ("steps_back", -1, 0.9), ("steps_forward", 1, 0.9), ("step_forward_small", 1, 0.15),
                                             ("step_forward_large", 1, 0.45)])
def test_steps_move_the_root(name, sign, least):
    for n in (name, f"{name}_mirror"):
        m = library.load(n)
        d = _root_displacement(m)
        assert sign * d[0] > least
        assert abs(d[1]) < 0.05
        c = detect(m)
        assert c.labels["left"][-5:].all() and c.labels["right"][-5:].all(), "ends standing on both feet"


def test_large_steps_go_further_than_small_ones():
    for direction in ("forward", "back"):
        small = abs(_root_displacement(library.load(f"step_{direction}_small"))[0])
        large = abs(_root_displacement(library.load(f"step_{direction}_large"))[0])
        assert large > 1.5 * small


@pytest.mark.parametrize("name,sign", [("stumble_side_left", 1.0), ("stumble_side_right", -1.0)])
def test_stumble_sideways(name, sign):
    m = library.load(name)
    d = _root_displacement(m)
    assert sign * d[1] > 0.4 and abs(d[0]) < 0.1
    c = detect(m)
    assert len(c.intervals()["left"]) >= 3 and len(c.intervals()["right"]) >= 2, "several steps"


@pytest.mark.parametrize("name", ["flinch_front", "flinch_side_left", "flinch_side_right", "flinch_back"])
def test_flinches_keep_the_feet_planted(name):
    m = library.load(name)
    c = detect(m, ContactConfig())
    assert c.labels["left"].all() and c.labels["right"].all()
    for p in foot_points(m).values():
        assert np.abs(p - p[0]).max() < 1e-9, "feet do not move at all"
    # The upper body does move.
    gp, _ = _positions(m)
    head = humanoid().index("Head")
    assert np.linalg.norm(gp[:, head] - gp[0, head], axis=1).max() > 0.05


def test_flinch_directions():
    gp, _ = _positions(library.load("flinch_front"))
    head = humanoid().index("Head")
    assert (gp[:, head, 0] - gp[0, head, 0]).min() < -0.05, "a hit from the front throws the head back"
    gp, _ = _positions(library.load("flinch_back"))
    chest = humanoid().index("Spine1")
    assert (gp[:, chest, 0] - gp[0, chest, 0]).max() > 0.03, "a hit from behind throws the chest forward"
    gp, _ = _positions(library.load("flinch_side_left"))
    assert (gp[:, head, 1] - gp[0, head, 1]).max() > 0.05


@pytest.mark.parametrize("name,hand", [("punch", "RightHand"), ("punch_mirror", "LeftHand")])
def test_punch_extends_the_arm(name, hand):
    m = library.load(name)
    gp, _ = _positions(m)
    j = humanoid().index(hand)
    assert gp[:, j, 0].max() > 0.6
    assert 1.3 < gp[np.argmax(gp[:, j, 0]), j, 2] < 1.55, "at chin height"
    np.testing.assert_allclose(gp[-1], gp[0], atol=0.02)


def test_kick_raises_the_right_foot():
    m = library.load("kick")
    pts = foot_points(m)
    assert pts["right"][..., 2].max() > 0.75
    assert np.abs(pts["left"] - pts["left"][0]).max() < 1e-9, "the standing foot stays planted"
    assert foot_points(library.load("kick_mirror"))["left"][..., 2].max() > 0.75


def test_push_extends_both_arms():
    gp, _ = _positions(library.load("push"))
    sk = humanoid()
    for hand in ("LeftHand", "RightHand"):
        assert gp[:, sk.index(hand), 0].max() > 0.7


# --------------------------------------------------------------------------- files and demo


def test_bvh_round_trip(tmp_path):
    for name in ("walk", "fall_backward"):
        m = library.load(name)
        write_bvh(tmp_path / f"{name}.bvh", m)
        back = read_bvh(tmp_path / f"{name}.bvh")
        assert back.num_frames == m.num_frames and back.fps == pytest.approx(60.0)
        np.testing.assert_allclose(back.global_positions(), m.global_positions(), atol=1e-5)


def test_demo_exports_every_clip(tmp_path):
    from kinodyn.data.demo import demo

    lines = demo(tmp_path)
    assert len(lines) == len(ALL) + 1
    for name, line in zip(ALL, lines):
        assert line.startswith(name) and "cm/s" in line
        assert (tmp_path / "clips" / f"{name}.bvh").stat().st_size > 1000


# --------------------------------------------------------------------------- joint speeds real capture reaches

#: Body parts whose joint speeds are bounded, by joint name (the CMU and built-in skeletons share them).
_RATE_GROUPS = {"hand": ("LeftHand", "RightHand"), "elbow": ("LeftForeArm", "RightForeArm"), "head": ("Head",),
                "hips": ("Hips",), "knee": ("LeftLeg", "RightLeg"),
                "foot": ("LeftFoot", "RightFoot", "LeftToeBase", "RightToeBase")}
#: Peak joint speed (m/s) and acceleration (m/s^2) at 60 fps per body part, the largest reached by the CMU
#: captures in _CAPTURES and _FIGHT_CAPTURES (falls, stumbles, a get-up, a pull, walks, punches and karate;
#: cgspeed T-pose frame 0 skipped, 120 fps capture sampled every second frame), rounded up to 0.1 m/s and
#: 1 m/s^2.
#: ``test_rate_bounds_are_what_capture_reaches`` re-measures them.
_PEAK_SPEED = {"hand": 8.8, "elbow": 6.5, "head": 4.1, "hips": 4.8, "knee": 9.5, "foot": 12.9}
_PEAK_ACCEL = {"hand": 194, "elbow": 227, "head": 85, "hips": 110, "knee": 431, "foot": 264}
_CAPTURES = ("reactions/cmu_90_16", "reactions/cmu_85_07", "reactions/cmu_91_59", "reactions/cmu_140_01",
             "interaction/cmu_18_04", "locomotion/cmu_01_01", "locomotion/cmu_02_01")
_FIGHT_CAPTURES = ("fighting/cmu_02_05", "fighting/cmu_135_06-martialArts")  # ASF/AMC
#: ASF bone whose start is the joint of the same place in the BVH skeletons.
_ASF_JOINTS = {"lwrist": "LeftHand", "rwrist": "RightHand", "lradius": "LeftForeArm", "rradius": "RightForeArm",
               "head": "Head", "root": "Hips", "ltibia": "LeftLeg", "rtibia": "RightLeg", "lfoot": "LeftFoot",
               "rfoot": "RightFoot", "ltoes": "LeftToeBase", "rtoes": "RightToeBase"}
_REST_SPEED = 0.5  # m/s, fastest joint between the first two frames of a clip that starts from standing
_STOP_SPEED = 0.05  # m/s, fastest joint between the last two frames of a clip that ends standing or lying


def _rates(gp: np.ndarray, fps: float, names) -> dict[str, tuple[float, float]]:
    """Per body part of ``_RATE_GROUPS``: (peak speed, peak acceleration) of joint positions ``gp (F, J, 3)``."""
    v = np.linalg.norm(np.diff(gp, axis=0), axis=-1) * fps
    a = np.linalg.norm(np.diff(gp, 2, axis=0), axis=-1) * fps ** 2
    out = {}
    for group, joints in _RATE_GROUPS.items():
        idx = [names.index(j) for j in joints]
        out[group] = (float(v[:, idx].max()), float(a[:, idx].max()))
    return out


def _joint_speeds(m) -> np.ndarray:
    gp, _ = _positions(m)
    return np.linalg.norm(np.diff(gp, axis=0), axis=-1) * m.fps


@pytest.mark.parametrize("name", ALL)
def test_clip_joint_speeds_stay_within_capture(name):
    """Regression: flinch_front and steps_back snapped the hands from rest to 8-13 m/s in a few frames."""
    m = library.load(name)
    gp, _ = _positions(m)
    for group, (speed, accel) in _rates(gp, m.fps, list(m.skeleton.names)).items():
        assert speed <= _PEAK_SPEED[group], f"{name}: {group} reaches {speed:.1f} m/s"
        assert accel <= _PEAK_ACCEL[group], f"{name}: {group} accelerates at {accel:.0f} m/s^2"


@pytest.mark.parametrize("name", [n for n in ALL if not library.info(n).cyclic])
def test_clip_starts_and_ends_at_rest(name):
    """Regression: the punch ended with its hand still moving at 0.26-0.58 m/s."""
    v = _joint_speeds(library.load(name))
    assert v[0].max() < _REST_SPEED, f"{name}: a joint starts at {v[0].max():.2f} m/s"
    assert v[-1].max() < _STOP_SPEED, f"{name}: a joint still moves at {v[-1].max():.2f} m/s at the end"


def test_rate_bounds_are_what_capture_reaches(mocap_dir):
    from kinodyn.io.amc import read_amc
    from kinodyn.io.bvh import read_bvh

    peak = {g: [0.0, 0.0] for g in _RATE_GROUPS}
    measured = []
    for clip in _CAPTURES:
        m = read_bvh(mocap_dir / f"{clip}.bvh")
        # Frame 0 is the converter's T-pose; 120 fps -> 60 fps.
        measured.append((m.global_positions()[1::2], list(m.skeleton.names)))
    for clip in _FIGHT_CAPTURES:
        m = read_amc(mocap_dir / f"{clip}.amc", fps=120.0)
        measured.append((m.global_positions()[::2], [_ASF_JOINTS.get(n, n) for n in m.skeleton.names]))
    for gp, names in measured:
        for group, (speed, accel) in _rates(gp, 60.0, names).items():
            peak[group] = [max(peak[group][0], speed), max(peak[group][1], accel)]
    for group, (speed, accel) in peak.items():
        assert _PEAK_SPEED[group] == pytest.approx(np.ceil(speed * 10.0) / 10.0, abs=0.11), group
        assert _PEAK_ACCEL[group] == pytest.approx(np.ceil(accel), abs=1.01), group
