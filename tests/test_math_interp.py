"""kinodyn.math.interp: frame resampling (lerp / slerp) and Catmull-Rom splines."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from kinodyn.errors import ParameterError
from kinodyn.math import interp, quat

_TOL = 1e-12
_SEED = 2718


def _keys(rng, k=7, uniform=False):
    if uniform:
        return np.arange(k) * 0.25
    return np.cumsum(rng.uniform(0.1, 1.0, k)) - 0.3


# --------------------------------------------------------------------------- frame sampling


def test_sample_indices_brackets_and_clamps():
    i0, i1, a = interp.sample_indices(5, 10.0, [0.0, 0.05, 0.1, 0.399, 0.4, 0.5, -1.0])
    assert_allclose(i0, [0, 0, 1, 3, 4, 4, 0])
    assert_allclose(i1, [1, 1, 2, 4, 4, 4, 1])
    assert_allclose(a, [0.0, 0.5, 0.0, 0.99, 0.0, 0.0, 0.0], atol=1e-9)
    assert interp.sample_indices(1, 30.0, [0.0, 1.0])[1].tolist() == [0, 0]
    with pytest.raises(ParameterError, match=r"^need at least one frame to sample, got 0$"):
        interp.sample_indices(0, 30.0, [0.0])


def test_lerp_frames_reproduces_samples_and_linear_data():
    rng = np.random.default_rng(_SEED)
    x = rng.normal(size=(20, 4, 3))
    fps = 30.0
    assert_allclose(interp.lerp_frames(x, fps, np.arange(20) / fps), x, atol=_TOL, err_msg="at sample times")
    t = rng.uniform(0.0, 19 / fps, 50)
    lin = 2.0 + 3.0 * np.arange(20)[:, None] / fps * np.ones((1, 2))
    assert_allclose(
        interp.lerp_frames(lin, fps, t),
        2.0 + 3.0 * t[:, None] * np.ones((1, 2)),
        atol=_TOL,
        err_msg="linear data",
    )
    mid = interp.lerp_frames(x, fps, (np.arange(19) + 0.5) / fps)
    assert_allclose(mid, 0.5 * (x[1:] + x[:-1]), atol=_TOL, err_msg="midpoints")


def test_slerp_frames_matches_quat_slerp():
    rng = np.random.default_rng(_SEED + 1)
    q = quat.normalize(rng.normal(size=(10, 3, 4)))
    fps = 24.0
    assert_allclose(
        np.abs(np.sum(interp.slerp_frames(q, fps, np.arange(10) / fps) * q, -1)),
        1.0,
        atol=_TOL,
        err_msg="at sample times",
    )
    t = np.array([0.3, 1.7, 8.25]) / fps
    got = interp.slerp_frames(q, fps, t)
    for k, tt in enumerate(t):
        i = int(np.floor(tt * fps))
        want = quat.slerp(q[i], q[i + 1], tt * fps - i)
        assert_allclose(got[k], want, atol=_TOL, err_msg=f"t={tt}")
    assert got.shape == (3, 3, 4)


# --------------------------------------------------------------------------- Catmull-Rom


@pytest.mark.parametrize("uniform", [True, False])
@pytest.mark.parametrize("ends", ["one-sided", "zero"])
def test_catmull_rom_passes_through_keys(uniform, ends):
    rng = np.random.default_rng(_SEED + 2)
    kt = _keys(rng, uniform=uniform)
    kv = rng.normal(size=(len(kt), 2, 3))
    assert_allclose(interp.catmull_rom(kt, kv, kt, ends=ends), kv, atol=_TOL, err_msg="keys")


@pytest.mark.parametrize("uniform", [True, False])
def test_catmull_rom_reproduces_linear_data(uniform):
    rng = np.random.default_rng(_SEED + 3)
    kt = _keys(rng, uniform=uniform)
    a, b = rng.normal(size=3), rng.normal(size=3)
    kv = a + kt[:, None] * b
    t = np.linspace(kt[0], kt[-1], 301)
    assert_allclose(interp.catmull_rom(kt, kv, t), a + t[:, None] * b, atol=1e-12, err_msg="linear data")


def test_catmull_rom_is_c1_continuous():
    rng = np.random.default_rng(_SEED + 4)
    kt = _keys(rng)
    kv = rng.normal(size=(len(kt), 2))
    h = 1e-5

    def f(t):
        return interp.catmull_rom(kt, kv, [t])

    for tk in kt[1:-1]:
        # second-order one-sided differences, each from one side of the key only
        left = (3 * f(tk) - 4 * f(tk - h) + f(tk - 2 * h)) / (2 * h)
        right = (-3 * f(tk) + 4 * f(tk + h) - f(tk + 2 * h)) / (2 * h)
        assert_allclose(left, right, atol=1e-5, err_msg=f"derivative continuous at key {tk}")
        # the derivative at an inner key is the centred difference of its neighbours
        i = int(np.nonzero(kt == tk)[0][0])
        centred = (kv[i + 1] - kv[i - 1]) / (kt[i + 1] - kt[i - 1])
        assert_allclose(0.5 * (left + right), centred[None], atol=1e-5, err_msg="tangent")


def test_catmull_rom_ends_and_clamping():
    kt = np.array([0.0, 1.0, 2.0])
    kv = np.array([[0.0], [1.0], [4.0]])
    h = 1e-7
    zero = interp.catmull_rom(kt, kv, [0.0, h, 2.0 - h, 2.0], ends="zero")
    assert_allclose((zero[1] - zero[0]) / h, 0.0, atol=1e-5, err_msg="eases in")
    assert_allclose((zero[3] - zero[2]) / h, 0.0, atol=1e-5, err_msg="eases out")
    one = interp.catmull_rom(kt, kv, [0.0, h])
    assert_allclose((one[1] - one[0]) / h, 1.0, atol=1e-5, err_msg="one-sided start tangent")
    assert_allclose(
        interp.catmull_rom(kt, kv, [-5.0, 9.0]), [[0.0], [4.0]], err_msg="clamped to the key range"
    )
    assert_allclose(
        interp.catmull_rom([0.5], [[3.0, 1.0]], [0.0, 1.0, 2.0]), [[3.0, 1.0]] * 3, err_msg="one key"
    )


def test_catmull_rom_errors():
    with pytest.raises(ParameterError, match=r"^key_times must be strictly increasing$"):
        interp.catmull_rom([0.0, 1.0, 1.0], np.zeros((3, 2)), [0.5])
    with pytest.raises(
        ParameterError, match=r"^key_times must be \(K,\) matching key_values \(3, 2\), got \(2,\)$"
    ):
        interp.catmull_rom([0.0, 1.0], np.zeros((3, 2)), [0.5])
    with pytest.raises(ParameterError, match=r"^ends must be 'one-sided' or 'zero', got 'free'$"):
        interp.catmull_rom([0.0, 1.0], np.zeros((2, 2)), [0.5], ends="free")
