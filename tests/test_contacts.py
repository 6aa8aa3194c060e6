"""kinodyn.contacts: foot-contact labels (height and speed thresholds), intervals, the foot-sliding measure.

Synthetic feet are scripted through per-frame joint translations of a tiny skeleton whose feet hang straight
from the root, so the position of every foot point is known in every frame; the expected labels follow from
the two thresholds and the central differences used for speeds.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from numpy.testing import assert_allclose

from conftest import mocap_files
from kinodyn import contacts
from kinodyn.contacts import ContactConfig
from kinodyn.errors import ParameterError, UnknownNameError
from kinodyn.math import quat
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton

_TOL = 1e-12  # metres, metres per second
_FPS = 100.0
_ROOT_Z = 0.98
# Hips -> LeftFoot -> LeftToeBase (+ end site); the same on the right. In the rest pose the ankles are 8 cm
# up and the toes and toe tips on the floor (z = 0) when the root is at _ROOT_Z.
_NAMES = ("Hips", "LeftFoot", "LeftToeBase", "RightFoot", "RightToeBase")
_PARENTS = np.array([-1, 0, 1, 0, 3])
_OFFSETS = np.array(
    [[0.0, 0.0, 0.0], [0.0, 0.1, -0.9], [0.12, 0.0, -0.08], [0.0, -0.1, -0.9], [0.12, 0.0, -0.08]]
)
_ENDS = (np.array([2, 4]), np.array([[0.05, 0.0, 0.0], [0.05, 0.0, 0.0]]))


def feet_skeleton(names=_NAMES) -> Skeleton:
    return Skeleton(names, _PARENTS, _OFFSETS, end_parents=_ENDS[0], end_offsets=_ENDS[1])


def scripted(left, right, names=_NAMES) -> Motion:
    """Feet displaced by ``left``/``right`` ``(F, 3)`` from their rest place; the root stays put."""
    n = len(left)
    tr = np.broadcast_to(_OFFSETS, (n, 5, 3)).copy()
    tr[:, 1] += left
    tr[:, 3] += right
    root = np.tile([0.0, 0.0, _ROOT_Z], (n, 1))
    return Motion(feet_skeleton(names), root, quat.identity((n, 5)), _FPS, translations=tr)


def step_script(n=100):
    """Left foot: planted (0-19), lifts fast (20-29), swings low and fast (30-49), hovers high and still
    (50-59), planted again further on (60-99). Right foot: planted throughout."""
    f = np.arange(n)
    left = np.zeros((n, 3))
    lift = (f >= 20) & (f < 30)
    left[lift, 2] = 0.03 * (f[lift] - 19)  # 3 m/s up
    swing = (f >= 30) & (f < 50)
    left[swing, 0] = 0.02 * (f[swing] - 30)  # 2 m/s forward, toe tip 2 cm above the floor
    left[swing, 2] = 0.02
    left[f >= 50, 0] = 0.4
    left[(f >= 50) & (f < 60), 2] = 0.2  # high and still
    return left, np.zeros((n, 3))


def expected_left(n=100):
    """Contact where both the heights and the central-difference speeds pass: frame 19 already moves (its
    next frame is 3 cm up), frame 60 still moves (its previous frame is 20 cm up)."""
    lab = np.zeros(n, dtype=bool)
    lab[:19] = True
    lab[61:] = True
    return lab


# --------------------------------------------------------------------------- finding the feet


@pytest.mark.parametrize(
    "names, left, right",
    [
        (
            (
                "Hips",
                "LeftUpLeg",
                "LeftLeg",
                "LeftFoot",
                "LeftToeBase",
                "RightUpLeg",
                "RightLeg",
                "RightFoot",
                "RightToeBase",
                "LeftHand",
            ),
            [3, 4],
            [7, 8],
        ),
        (
            ("root", "lfemur", "ltibia", "lfoot", "ltoes", "rfemur", "rtibia", "rfoot", "rtoes", "lhand"),
            [3, 4],
            [7, 8],
        ),
        (
            (
                "pelvis",
                "l_hip",
                "l_knee",
                "l_ankle",
                "l_toe",
                "r_hip",
                "r_knee",
                "r_ankle",
                "r_toe",
                "l_wrist",
            ),
            [3, 4],
            [7, 8],
        ),
        (
            (
                "Hips",
                "LeftHip",
                "LeftKnee",
                "LeftAnkle",
                "LeftToe",
                "RightHip",
                "RightKnee",
                "RightAnkle",
                "RightToe",
                "Neck",
            ),
            [3, 4],
            [7, 8],
        ),
        (
            (
                "Pelvis",
                "L_Hip",
                "L_Knee",
                "L_Ankle",
                "L_Foot",
                "R_Hip",
                "R_Knee",
                "R_Ankle",
                "R_Foot",
                "Head",
            ),
            [3, 4],
            [7, 8],
        ),
        (
            ("Hips", "LThigh", "LShin", "LFoot", "LToe", "RThigh", "RShin", "RFoot", "RToe", "Head"),
            [3, 4],
            [7, 8],
        ),
        (
            (
                "hips",
                "thigh_l",
                "calf_l",
                "foot_l",
                "ball_l",
                "thigh_r",
                "calf_r",
                "foot_r",
                "ball_r",
                "head",
            ),
            [3, 4],
            [7, 8],
        ),
    ],
)
def test_find_feet_by_names(names, left, right):
    """Regression: upper-case one-letter prefixes (``LFoot``, ``L_Ankle``) were not recognized as a side."""
    sk = Skeleton(names, np.array([-1, 0, 1, 2, 3, 0, 5, 6, 7, 0]), np.zeros((10, 3)))
    feet = contacts.find_feet(sk)
    assert feet["left"].tolist() == left
    assert feet["right"].tolist() == right


def test_find_feet_override_and_errors():
    names = ("cadera", "pie_izq", "dedos_izq", "pie_der", "dedos_der")
    sk = feet_skeleton(names)
    msg = (
        "cannot find the left foot by joint names (looked for foot/ankle/toe/heel with a side marker); "
        "pass feet={'left': [...], 'right': [...]}; "
        "joints are: cadera, pie_izq, dedos_izq, pie_der, dedos_der"
    )
    with pytest.raises(UnknownNameError, match="^" + re.escape(msg) + "$"):
        contacts.find_feet(sk)
    feet = contacts.find_feet(sk, {"left": ["pie_izq", "dedos_izq"], "right": ["pie_der", "dedos_der"]})
    assert feet["left"].tolist() == [1, 2] and feet["right"].tolist() == [3, 4]
    with pytest.raises(ParameterError, match=r"^feet override needs a non-empty list for 'right', got None$"):
        contacts.find_feet(sk, {"left": ["pie_izq"]})
    with pytest.raises(ParameterError, match=r"^feet override needs a non-empty list for 'left', got \[\]$"):
        contacts.find_feet(sk, {"left": [], "right": ["pie_der"]})
    with pytest.raises(UnknownNameError, match=r"^no joint named 'pie'"):
        contacts.find_feet(sk, {"left": ["pie"], "right": ["pie_der"]})


def test_override_gives_the_same_labels_as_names():
    left, right = step_script()
    by_name = contacts.detect(scripted(left, right))
    names = ("cadera", "pie_izq", "dedos_izq", "pie_der", "dedos_der")
    m = scripted(left, right, names)
    feet = contacts.find_feet(
        m.skeleton, {"left": ["pie_izq", "dedos_izq"], "right": ["pie_der", "dedos_der"]}
    )
    override = contacts.detect(m, feet=feet)
    for s in contacts.SIDES:
        assert np.array_equal(override.labels[s], by_name.labels[s]), s
    # choosing only the ankles (8 cm up) as the left foot: it never comes under the 5 cm threshold
    ankles = contacts.detect(
        m, ContactConfig(floor=0.0), feet={"left": np.array([1]), "right": np.array([3, 4])}
    )
    assert not ankles.labels["left"].any()


def test_foot_points_include_end_sites():
    left, right = step_script()
    m = scripted(left, right)
    pts = contacts.foot_points(m)
    assert pts["left"].shape == (100, 3, 3), "ankle, toe, toe tip"
    rest_left = np.array([[0.0, 0.1, 0.08], [0.12, 0.1, 0.0], [0.17, 0.1, 0.0]])
    assert_allclose(pts["left"], rest_left[None] + left[:, None], atol=_TOL)
    assert_allclose(pts["right"][:, :, 1], -0.1, atol=_TOL)


# --------------------------------------------------------------------------- labels


def test_labels_exactly_as_designed():
    left, right = step_script()
    c = contacts.detect(scripted(left, right))
    assert c.floor == pytest.approx(0.0, abs=_TOL), "floor estimated from the feet"
    assert np.array_equal(c.labels["left"], expected_left()), np.nonzero(c.labels["left"] != expected_left())
    assert c.labels["right"].all(), "planted throughout"
    assert c.fps == _FPS
    assert c.as_array().shape == (100, 2) and np.array_equal(c.as_array()[:, 0], c.labels["left"])
    iv = c.intervals()
    assert iv["left"].tolist() == [[0, 19], [61, 100]]
    assert iv["right"].tolist() == [[0, 100]]
    # the lowest point and its velocity
    assert_allclose(c.lowest["left"][:, 2], left[:, 2], atol=_TOL)
    assert_allclose(c.lowest_velocity["left"][35], [2.0, 0.0, 0.0], atol=1e-9, err_msg="swing velocity")
    assert_allclose(c.lowest_velocity["right"], 0.0, atol=_TOL)


def test_each_threshold_decides():
    left, right = step_script()
    m = scripted(left, right)
    # a higher height threshold makes the still hover (20 cm) a contact
    hover = contacts.detect(m, ContactConfig(height=0.25, floor=0.0))
    assert hover.labels["left"][51:59].all()
    # a higher speed threshold makes the low swing (2 m/s) a contact
    sweep = contacts.detect(m, ContactConfig(speed=2.5, floor=0.0))
    assert sweep.labels["left"][31:49].all()
    # the default rejects both
    base = contacts.detect(m, ContactConfig(floor=0.0))
    assert not base.labels["left"][20:61].any()
    # a floor 30 cm down puts every foot out of reach
    assert not contacts.detect(m, ContactConfig(floor=-0.3)).as_array().any()


def test_floor_estimate_follows_a_raised_floor():
    left, right = step_script()
    m = scripted(left, right)
    raised = m.replace(root_pos=m.root_pos + [0.0, 0.0, 0.4])
    c = contacts.detect(raised)
    assert c.floor == pytest.approx(0.4, abs=_TOL)
    assert np.array_equal(c.labels["left"], expected_left())


def test_short_runs_are_merged():
    """min_frames=2 drops a one-frame contact and fills a one-frame gap, but keeps runs at the clip's ends."""
    n = 60
    f = np.arange(n)
    left = np.zeros((n, 3))
    left[:, 2] = 0.3  # in the air ...
    left[30, 2] = (
        0.0  # ... except one frame on the floor (its speed is 15 m/s, so use a huge speed threshold)
    )
    right = np.zeros((n, 3))
    right[f == 20, 2] = 0.3  # one frame in the air
    m = scripted(left, right)
    cfg = ContactConfig(speed=100.0, floor=0.0)
    c = contacts.detect(m, cfg)
    assert not c.labels["left"].any(), "one-frame contact dropped"
    assert c.labels["right"].all(), "one-frame gap filled"
    raw = contacts.detect(m, ContactConfig(speed=100.0, floor=0.0, min_frames=1))
    assert raw.labels["left"].tolist() == (f == 30).tolist()
    assert raw.labels["right"].tolist() == (f != 20).tolist()
    # at the clip's ends a short run is kept (it may continue outside the clip)
    left2 = np.zeros((n, 3))
    left2[1:, 2] = 0.3
    c2 = contacts.detect(scripted(left2, right), cfg)
    assert c2.labels["left"].tolist() == (f == 0).tolist()


def test_intervals():
    assert contacts.intervals([False, True, True, False, True]).tolist() == [[1, 3], [4, 5]]
    assert contacts.intervals([True, True]).tolist() == [[0, 2]]
    assert contacts.intervals(np.zeros(5, bool)).shape == (0, 2)
    assert contacts.intervals([]).shape == (0, 2)
    rng = np.random.default_rng(3)
    lab = rng.uniform(size=200) < 0.5
    rebuilt = np.zeros(200, bool)
    for a, b in contacts.intervals(lab):
        assert b > a
        rebuilt[a:b] = True
    assert np.array_equal(rebuilt, lab)


def test_config_validation():
    for kw, msg in [
        (dict(height=0.0), "height threshold must be a positive number of metres, got 0.0"),
        (dict(height=float("nan")), "height threshold must be a positive number of metres, got nan"),
        (dict(speed=-1.0), "speed threshold must be a positive number of m/s, got -1.0"),
        (dict(floor=float("inf")), "floor must be finite or None, got inf"),
        (dict(min_frames=0), "min_frames must be at least 1, got 0"),
    ]:
        with pytest.raises(ParameterError, match="^" + re.escape(msg) + "$"):
            ContactConfig(**kw)


# --------------------------------------------------------------------------- sliding


@pytest.mark.parametrize("slide", [0.05, 0.2, 0.3])
def test_sliding_equals_a_known_slide_speed(slide):
    """Both feet planted, the left one sliding sideways at ``slide`` m/s (under the speed threshold, so still
    a
    contact): the measure is the mean horizontal speed over contact frames."""
    n = 80
    t = np.arange(n) / _FPS
    left = np.zeros((n, 3))
    left[:, 0] = slide * t * 0.6
    left[:, 1] = slide * t * 0.8
    right = np.zeros((n, 3))
    m = scripted(left, right)
    c = contacts.detect(m)
    assert c.labels["left"].all() and c.labels["right"].all()
    rep = contacts.sliding(m, c)
    assert rep.per_foot["left"] == pytest.approx(slide, abs=1e-9)
    assert rep.per_foot["right"] == pytest.approx(0.0, abs=_TOL)
    assert rep.mean == pytest.approx(slide / 2, abs=1e-9), "mean over both feet's contact frames"
    assert rep.contact_frames == 2 * n
    assert rep.p95 == pytest.approx(slide, abs=1e-9)
    assert rep.cm_per_s == pytest.approx(100 * rep.mean)
    assert contacts.sliding(m).mean == pytest.approx(rep.mean), "contacts detected when not given"


def test_sliding_ignores_vertical_speed_and_flight():
    n = 80
    t = np.arange(n) / _FPS
    left = np.zeros((n, 3))
    left[:, 2] = 0.02 + 0.01 * np.sin(2 * np.pi * 2 * t)  # bobbing up and down in place, low and slow
    right = np.zeros((n, 3))
    right[:, 2] = 0.5  # in the air all along
    right[:, 0] = 3.0 * t  # and fast: no contact, so not counted
    m = scripted(left, right)
    rep = contacts.sliding(m, config=ContactConfig(floor=0.0))
    assert rep.per_foot["left"] == pytest.approx(0.0, abs=_TOL)
    assert rep.per_foot["right"] == 0.0 and rep.contact_frames == n
    none = contacts.sliding(scripted(right, right), config=ContactConfig(floor=0.0))
    assert (none.mean, none.p95, none.contact_frames) == (0.0, 0.0, 0)


# --------------------------------------------------------------------------- real motion capture

_WALK = mocap_files("locomotion/cmu_02_01.bvh")


@pytest.fixture(scope="module")
def walk():
    if not _WALK:
        pytest.skip("../shared/mocap/locomotion/cmu_02_01.bvh not found")
    import kinodyn

    return kinodyn.load(_WALK[0])[1:]  # frame 0 is the converter's T-pose


def _steps(c: contacts.FootContacts, min_s: float = 0.25):
    """Stances of at least ``min_s`` seconds of both feet, ``(start, stop, side)`` in time order."""
    iv = c.intervals()
    return sorted((int(a), int(b), s) for s in contacts.SIDES for a, b in iv[s] if (b - a) / c.fps >= min_s)


@pytest.mark.mocap
def test_walk_has_alternating_contacts(walk):
    c = contacts.detect(walk)
    steps = _steps(c)
    assert len(steps) >= 4, steps
    assert all(x[2] != y[2] for x, y in zip(steps, steps[1:])), f"left and right alternate: {steps}"
    assert all(y[1] > x[1] for x, y in zip(steps, steps[1:])), "each step ends after the one before"
    overlaps = [x[1] - y[0] for x, y in zip(steps, steps[1:])]
    assert sum(o > 0 for o in overlaps) >= 2, f"double support between steps: {overlaps}"
    assert c.as_array().mean() == pytest.approx(0.55, abs=0.1), "each foot down about 55 % of the time"
    rep = contacts.sliding(walk, c)
    assert 0.0 < rep.mean < 0.15, f"foot sliding of clean mocap is small: {rep.mean:.3f} m/s"


@pytest.mark.mocap
@pytest.mark.mocap
def test_walk_has_double_support_at_step_changes(walk):
    """Regression: with one level floor per clip the tilted CMU floor cut stances short and left a
    5-frame flight phase in this walk; the fitted floor plane restores double support."""
    c = contacts.detect(walk)
    steps = _steps(c)
    overlaps = [x[1] - y[0] for x, y in zip(steps, steps[1:])]
    assert all(o >= 0 for o in overlaps), f"a walk has no flight phase: {overlaps} ({steps})"
    assert sum(o > 0 for o in overlaps) >= len(overlaps) - 1, f"double support between steps: {overlaps}"
    assert abs(c.floor_slope[0]) > 0.005, "the capture floor of this clip is tilted along the walk"


# ---------------------------------------------------------------------------------------- every real clip
def _loadable_clips():
    """Every motion file of the shared mocap folder that kinodyn reads (BVH, ASF/AMC)."""
    return mocap_files("**/*.bvh") + mocap_files("**/*.amc")


def _really_down(m, pts, window_s: float = 2.0, near: float = 0.08, slow: float = 0.5):
    """``{side: (F,) bool}`` frames where a foot is down by a rule that needs no floor estimate: some point
    of it moves slower than ``slow`` m/s (over 1/30 s), and its lowest point is within ``near`` metres of
    the lowest point either foot reaches within ``window_s`` seconds."""
    from numpy.lib.stride_tricks import sliding_window_view

    n = m.num_frames
    k = max(1, int(round(m.fps / 60)))
    i = np.arange(n)
    a, b = np.clip(i - k, 0, n - 1), np.clip(i + k, 0, n - 1)
    low = np.minimum(*[pts[s][..., 2].min(axis=1) for s in contacts.SIDES])
    half = int(round(window_s * m.fps))
    pad = np.pad(low, half, mode="edge")
    ground = sliding_window_view(pad, 2 * half + 1).min(axis=1)
    out = {}
    for s in contacts.SIDES:
        p = pts[s]
        speed = np.linalg.norm(p[b] - p[a], axis=-1) * m.fps / np.maximum(b - a, 1)[:, None]
        out[s] = (speed.min(axis=1) < slow) & (p[..., 2].min(axis=1) < ground + near)
    return out


@pytest.mark.mocap
@pytest.mark.parametrize("path", _loadable_clips(), ids=lambda p: p.name)
def test_no_foot_is_labelled_in_flight_while_it_stands(path):
    """Falls, stumbles, get-ups, raised and tilted capture floors: on every real clip, no foot is labelled
    in flight for more than 0.15 s while it is still and on the lowest ground nearby (its real flight is
    never that long a run of such frames)."""
    import kinodyn

    m = kinodyn.load(path)
    if path.suffix == ".bvh" and path.name.startswith("cmu_"):
        m = m[1:]  # the converter's T-pose
    try:
        c = contacts.detect(m)
    except UnknownNameError:
        pytest.skip(f"{path.name}: no feet found by name")
    down = _really_down(m, contacts.foot_points(m))
    for s in contacts.SIDES:
        missed = down[s] & ~c.labels[s]
        runs = contacts.intervals(missed)
        longest = max(((b - a) / m.fps for a, b in runs), default=0.0)
        assert longest <= 0.15, (f"{path.name} {s}: labelled in flight for {longest:.2f} s while down "
                                 f"(floor {c.floor:.3f} m, {c.labels[s].mean():.0%} of frames in contact)")
