"""The keyframe space, the periodic mapping (equations 6 to 9), keyframe-set files and interpolation."""

import copy
import json

import numpy as np
import pytest

from kinodyn.crowd import authoring
from kinodyn.crowd.interpolate import interpolate
from kinodyn.crowd.keyframes import (
    BUILTIN_PATH,
    builtin_keyframes,
    keyframes_to_dict,
    load_keyframes,
    parse_keyframes,
    periodic,
    phases,
    travel,
)
from kinodyn.errors import FileFormatError, ParameterError
from kinodyn.math import quat

_TOL = 1e-12


@pytest.fixture(scope="module")
def ks():
    return builtin_keyframes()


@pytest.fixture(scope="module")
def data():
    return json.loads(BUILTIN_PATH.read_text())


# ---------------------------------------------------------------- periodic mapping


def test_periodic_function_is_equation_8():
    x = np.array([-2.25, -1.0, -0.75, -1e-17, 0.0, 0.3, 1.0, 2.6])
    np.testing.assert_allclose(periodic(x), [0.75, 0.0, 0.25, 0.0, 0.0, 0.3, 0.0, 0.6], atol=1e-12)
    assert np.all((periodic(x) >= 0) & (periodic(x) < 1))


def _walk(heading, direction, speed, seconds, stride, dt=1 / 60):
    """Integrate equations 6 and 7 for a body with ``heading`` moving at ``direction`` (world angle)."""
    n = round(seconds / dt)
    fwd = np.array([[np.cos(heading), np.sin(heading), 0.0]])
    left = np.array([[-np.sin(heading), np.cos(heading), 0.0]])
    vel = speed * np.array([[np.cos(direction), np.sin(direction), 0.0]])
    ds, df = np.zeros(1), np.zeros(1)
    out = []
    for _ in range(n):
        ds, df = travel(ds, df, vel, fwd, left, dt)
        out.append(phases(ds, df, stride))
    return ds[0], df[0], np.array(out)[:, :, 0]


def _cyclic_close(a, b, atol=1e-9):
    d = np.abs(np.asarray(a) - np.asarray(b)) % 1.0
    np.testing.assert_array_less(np.minimum(d, 1.0 - d), atol)


@pytest.mark.parametrize("heading", [0.0, 1.0, -2.5])
def test_forward_travel_advances_d_z_and_wraps(heading):
    ds, df, ph = _walk(heading, heading, 1.2, 2.6, stride=1.0)
    assert df == pytest.approx(3.12) and ds == pytest.approx(0.0, abs=1e-12)
    dz = ph[:, 1]
    steps = np.diff(dz)
    assert np.sum(steps < -0.5) == 3, "wraps from 1 to 0 once per stride"
    assert np.all((steps > 0) | (steps < -0.5)), "increases between wraps"
    _cyclic_close(ph[:, 0], 0.0)
    _cyclic_close(ph[:, 1], 1.2 * np.arange(1, len(ph) + 1) / 60)


def test_backward_travel_decreases_d_z_and_wraps_to_one():
    _, df, ph = _walk(0.3, 0.3 + np.pi, 1.0, 1.6, stride=0.5)
    assert df == pytest.approx(-1.6)
    steps = np.diff(ph[:, 1])
    assert np.sum(steps > 0.5) == 3 and np.all((steps < 0) | (steps > 0.5))
    _cyclic_close(ph[:, 0], 0.0)
    assert ph[0, 1] == pytest.approx(1.0 - 1.0 / 60 / 0.5)


@pytest.mark.parametrize("side,sign", [(np.pi / 2, 1.0), (-np.pi / 2, -1.0)])
def test_sideways_travel_moves_d_x_only(side, sign):
    ds, df, ph = _walk(0.7, 0.7 + side, 0.6, 2.0, stride=0.4)
    assert ds == pytest.approx(sign * 1.2) and df == pytest.approx(0.0, abs=1e-12)
    _cyclic_close(ph[:, 1], 0.0)
    expected = periodic(sign * 0.6 * np.arange(1, 121) / 60 / 0.4)
    _cyclic_close(ph[:, 0], expected)
    steps = np.diff(ph[:, 0])
    moving = steps[np.abs(steps) < 0.5]
    assert np.all(np.sign(moving) == sign), "D_x runs forward leftward, backward rightward"


def test_stride_must_be_positive():
    with pytest.raises(ParameterError, match="stride must be a positive number"):
        phases(0.0, 0.0, 0.0)


# ---------------------------------------------------------------- the built-in set


def test_builtin_set_is_figure_8(ks):
    assert len(ks.names) == 12
    assert 50 <= ks.num_keys <= 60
    assert ks.behaviours == ("walking_and_falling", "standing_up")
    stand = ks.key_point[ks.key_point[:, 4] == 1]
    np.testing.assert_array_equal(stand[:, 1:4], 0.0)  # on the (theta_z = 0, D_x = 0, D_z = 0) line
    walk = ks.key_point[ks.key_point[:, 4] == 0]
    in_fwd = (walk[:, 1] == 0) & (walk[:, 2] == 0)
    in_side = (walk[:, 0] == 0) & (walk[:, 3] == 0)
    assert np.all(in_fwd | in_side)


def test_builtin_file_is_what_the_authoring_writes(data):
    assert authoring.build_dict() == json.loads(json.dumps(authoring.build_dict())) == data


# ---------------------------------------------------------------- interpolation


def _own(ks):
    m = ~ks.key_shared
    return ks.key_point[m, :4], ks.key_point[m, 4].astype(int), ks.key_rot[m], ks.key_root[m]


def test_interpolation_is_exact_at_every_keyframe(ks):
    pts, beh, rot, root = _own(ks)
    r, p = interpolate(ks, pts, beh)
    np.testing.assert_allclose(quat.angle_between(r, rot), 0.0, atol=1e-7)
    np.testing.assert_allclose(p, root, atol=_TOL)


def _path(a, b, n=4001):
    t = np.linspace(0, 1, n)[:, None]
    return a + t * (b - a)


@pytest.mark.parametrize("a,b", [
    ([0, 0, 0, 0.9], [0, 0, 0, 1.1]),            # walk phase across the wrap
    ([-0.5, 0, 0, 0.3], [0.9, 0, 0, 0.55]),      # forward plane across several tilt levels
    ([0, -1.2, 0.05, 0], [0, 1.2, 0.95, 0]),     # side plane
    ([0.3, 0.3, 0.2, 0.7], [-0.2, -0.1, 0.8, 0.1]),  # off both planes
    ([0.05, 0, 0, 0], [0, 0.05, 0, 0]),          # through the point where the planes meet
    ([-1.7, 0, 0, 0], [1.7, 0, 0, 0]),           # beyond the outermost levels
])
@pytest.mark.parametrize("behaviour", [0, 1])
def test_interpolation_is_continuous(ks, a, b, behaviour):
    pts = _path(np.array(a, float), np.array(b, float))
    r, p = interpolate(ks, pts, behaviour)
    jump_rot = quat.angle_between(r[1:], r[:-1]).max()
    jump_pos = np.linalg.norm(np.diff(p, axis=0), axis=2 if p.ndim == 3 else 1).max()
    assert jump_rot < 0.02 and jump_pos < 0.005, (jump_rot, jump_pos)


def test_behaviours_blend_continuously(ks):
    pts = np.tile([[0.1, 0.0, 0.0, 0.3]], (501, 1))
    w = np.linspace(0, 1, 501)
    r, _ = interpolate(ks, pts, np.stack([1 - w, w], axis=1))
    r0, _ = interpolate(ks, pts[:1], 0)
    r1, _ = interpolate(ks, pts[:1], 1)
    np.testing.assert_allclose(quat.angle_between(r[0], r0[0]), 0, atol=1e-7)
    np.testing.assert_allclose(quat.angle_between(r[-1], r1[0]), 0, atol=1e-7)
    assert quat.angle_between(r[1:], r[:-1]).max() < 0.02


def test_interpolation_batched_equals_one_by_one(ks):
    pts = np.random.default_rng(0).uniform([-1.6, -1.2, 0, 0], [1.6, 1.2, 1, 1], (40, 4))
    r, p = interpolate(ks, pts, 0)
    for i in range(0, 40, 7):
        ri, pi = interpolate(ks, pts[i:i + 1], 0)
        np.testing.assert_array_equal(ri[0], r[i])
        np.testing.assert_array_equal(pi[0], p[i])


@pytest.mark.parametrize("spread", [False, True])
def test_interpolation_does_not_depend_on_the_signs_of_the_quaternions(ks, spread):
    """q and -q are one rotation: flipping keyframes' quaternions changes no interpolated rotation, and
    each keyframe is returned with its own sign, whether one hemisphere serves every keyframe (the
    built-in set) or two neighbouring keyframes of a joint lie more than half a turn apart through
    the identity (a table per keyframe; the blend between them goes the short way)."""
    import dataclasses

    from kinodyn.crowd.interpolate import aligned_keys

    rot = np.array(ks.key_rot)
    lv = next(int(l) for l in range(ks.plane_start[0, 0], ks.plane_start[0, 0] + ks.plane_count[0, 0])
              if ks.level_count[l] >= 2)
    a = int(ks.level_start[lv])
    j = ks.skeleton.index("LeftArm")
    if spread:  # 20 degrees apart through the half turn, 340 through the identity
        rot[a, j] = quat.from_axis_angle([0.0, 0.0, 1.0], np.radians(170.0))
        rot[a + 1, j] = quat.from_axis_angle([0.0, 0.0, -1.0], np.radians(170.0))
    rng = np.random.default_rng(5)
    base = dataclasses.replace(ks, key_rot=rot)
    flipped = dataclasses.replace(ks, key_rot=rot * np.where(rng.random(rot.shape[:2]) < 0.5, -1.0, 1.0)[..., None])
    for s in (base, flipped):
        assert aligned_keys(s)[0].shape[0] == (len(rot) if spread else 1)
    pts = rng.uniform([-1.6, -1.2, 0, 0], [1.6, 1.2, 1, 1], (300, 4))
    rb, pb = interpolate(base, pts, 0)
    rf, pf = interpolate(flipped, pts, 0)
    np.testing.assert_allclose(quat.angle_between(rf, rb), 0.0, atol=1e-6)
    np.testing.assert_allclose(pf, pb, atol=_TOL)
    at, beh, _, _ = _own(flipped)
    r, _ = interpolate(flipped, at, beh)
    np.testing.assert_allclose(r, flipped.key_rot[~flipped.key_shared], atol=1e-7)
    between = np.zeros((21, 4))
    between[:, 0] = ks.level_tilt[lv]
    between[:, 3] = np.linspace(ks.key_phase[a], ks.key_phase[a + 1], 21)
    r, _ = interpolate(flipped, between, 0)
    gap = quat.angle_between(rot[a, j], rot[a + 1, j])
    assert np.all(quat.angle_between(r[:, j], rot[a, j]) <= gap + np.radians(8.0)), "the short way"


def test_side_weight_selects_a_plane(ks):
    pts = np.array([[0.0, 0.0, 0.375, 0.25]])
    fwd, _ = interpolate(ks, pts, 0, side_weight=0.0)
    alone, _ = interpolate(ks, np.array([[0.0, 0.0, 0.0, 0.25]]), 0)
    np.testing.assert_allclose(quat.angle_between(fwd, alone), 0.0, atol=1e-7)


def test_bad_points(ks):
    with pytest.raises(ParameterError, match=r"points must have shape \(N, 4\)"):
        interpolate(ks, np.zeros((3, 5)), 0)
    with pytest.raises(ParameterError, match="behaviour indices must lie in"):
        interpolate(ks, np.zeros((3, 4)), 2)


# ---------------------------------------------------------------- files


def test_round_trip_through_the_file_structure(ks, tmp_path):
    d = keyframes_to_dict(ks, scale=float(json.loads(BUILTIN_PATH.read_text())["scale"]))
    again = parse_keyframes(d)
    np.testing.assert_allclose(again.key_rot, ks.key_rot, atol=1e-6)
    np.testing.assert_allclose(again.key_root, ks.key_root, atol=1e-6)
    np.testing.assert_array_equal(again.key_point, ks.key_point)


def test_yaml_and_json_read_the_same(data, tmp_path):
    import yaml

    small = copy.deepcopy(data)
    small["animations"] = small["animations"][:2]
    (tmp_path / "k.yaml").write_text(yaml.safe_dump(small))
    (tmp_path / "k.json").write_text(json.dumps(small))
    a, b = load_keyframes(tmp_path / "k.yaml"), load_keyframes(tmp_path / "k.json")
    np.testing.assert_array_equal(a.key_rot, b.key_rot)
    assert a.num_keys == 16


def _broken(data, edit):
    d = copy.deepcopy(data)
    edit(d)
    return d


def _anim(i):
    return lambda d: d["animations"][i]


BAD = [
    (lambda d: d.pop("format"), "format must be 'kinodyn-keyframe-set', got None"),
    (lambda d: d.update(version=2), "version must be 1, got 2"),
    (lambda d: d.update(stride=-1.0), "scale and stride must be positive"),
    (lambda d: d.update(stride="long"), "stride must be a finite number, got 'long'"),
    (lambda d: d.update(behaviours=[]), "behaviours must be a non-empty list of distinct names"),
    (lambda d: d.update(skeleton="robot"), "skeleton must be 'humanoid' or a mapping"),
    (lambda d: d.update(animations={}), "animations must be a non-empty list"),
    (lambda d: d["animations"][0].update(axis="time"),
     "animation 'walk': axis must be one of theta_x, theta_z, d_x, d_z, got 'time'"),
    (lambda d: d["animations"][0].update(behaviour="dancing"),
     "animation 'walk': behaviour must be one of walking_and_falling, standing_up, got 'dancing'"),
    (lambda d: d["animations"][0]["at"].update(theta_z=0.2),
     "animation 'walk': an animation along d_z lies in the plane where theta_z and d_x are 0, got at.theta_z=0.2"),
    (lambda d: d["animations"][0]["at"].update(d_z=0.2), "at must not fix the animation's own axis 'd_z'"),
    (lambda d: d["animations"][0]["keys"][1].update(t=1.5),
     "animation 'walk', key 1: phase d_z must lie in [0, 1), got 1.5"),
    (lambda d: d["animations"][3]["keys"][0].update(t=4.0),
     "animation 'fall_forward', key 0: tilt theta_x must lie in [-3.1416, 3.1416] (equation 10), got 4.0"),
    (lambda d: d["animations"][0]["keys"][1].update(t=0.0),
     "animation 'walk', key 1: its point (0.0, 0.0, 0.0, 0.0) already holds animation 'walk', key 0"),
    (lambda d: d["animations"][0]["keys"][0]["rotations"].update(Tail=[1, 0, 0, 0]),
     "animation 'walk', key 0: unknown joint 'Tail'"),
    (lambda d: d["animations"][0]["keys"][0]["rotations"].update(Hips=[0, 0, 0, 0]),
     "animation 'walk', key 0: rotation of Hips is a zero quaternion"),
    (lambda d: d["animations"][0]["keys"][0]["rotations"].update(Hips=[1, 0, 0]),
     "animation 'walk', key 0: rotation of Hips must be a list of 4 numbers"),
    (lambda d: d["animations"][0]["keys"][0].update(root=[0, 0, float("nan")]),
     "animation 'walk', key 0: root must be a finite number, got nan"),
    (lambda d: d["animations"][1].update(name="walk"), "animation 'walk': name must be a unique string"),
    (lambda d: d["animations"][0].update(keys=[]), "animation 'walk': keys must be a non-empty list"),
]


@pytest.mark.parametrize("edit,message", BAD)
def test_bad_keyframe_sets_get_clear_errors(data, edit, message):
    with pytest.raises(FileFormatError) as e:
        parse_keyframes(_broken(data, edit), path="set.json")
    assert message in str(e.value)
    assert "set.json" in str(e.value)


def test_bad_files(tmp_path):
    (tmp_path / "a.json").write_text("{ not json")
    with pytest.raises(FileFormatError, match="not valid JSON"):
        load_keyframes(tmp_path / "a.json")
    (tmp_path / "a.yaml").write_text("a: [1, 2")
    with pytest.raises(FileFormatError, match="not valid YAML"):
        load_keyframes(tmp_path / "a.yaml")
    (tmp_path / "a.txt").write_text("{}")
    with pytest.raises(FileFormatError, match="must be .json, .yaml or .yml"):
        load_keyframes(tmp_path / "a.txt")
    with pytest.raises(FileNotFoundError):
        load_keyframes(tmp_path / "missing.json")
