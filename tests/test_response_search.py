"""Reaction library, exhaustive windowed search and fast alignment (dynamic response, section 5)."""

from __future__ import annotations

import numpy as np
import pytest

from kinodyn.data import library as data
from kinodyn.errors import KinodynError, ParameterError
from kinodyn.response import (AlignConfig, SearchConfig, body_tracks, builtin, exhaustive, fast_align,
                              from_folder, from_motions, windows)
from kinodyn.response.align import continuous_error, continuous_error_reference, refine_reference

_TOL = 1e-9
#: Fast alignment's error D against the exhaustive optimum on held-out cases: median and worst ratio.
_RATIO_MEDIAN = 1.02
_RATIO_WORST = 1.10
_NEAR_ZERO = 0.01  # D of a refined match where the exact match is 0 (0.5 mm per body)


@pytest.fixture(scope="module")
def small_lib():
    names = ["step_back_small", "steps_forward", "flinch_front", "fall_side"]
    return from_motions([data.load(n) for n in names])


@pytest.fixture(scope="module")
def lib():
    return builtin()


def _segment(rng, lib, clip: str, start: int, frames: int, noise: float = 0.0):
    """A stand-in for a simulated segment: ``frames`` frames of a library clip from ``start``, moved and
    turned on the floor, with joint-rotation noise (radians) and a lead-in of walking."""
    m = data.load(clip)[start:start + frames].transformed([rng.uniform(-3, 3), rng.uniform(-3, 3),
                                                           rng.uniform(-np.pi, np.pi)])
    lead = data.load("walk")[:int(rng.integers(5, 25))]
    m = lead.concatenate(m)
    if noise:
        from kinodyn.math import quat

        lr = quat.mul(m.local_rot, quat.from_rotvec(rng.normal(scale=noise, size=m.local_rot.shape[:-1] + (3,))))
        m = m.replace(local_rot=lr)
    pos, rot = body_tracks(m)
    return windows(pos, rot, lib.window), (pos, rot)


def test_window_error_ignores_floor_position_and_facing(small_lib):
    m = data.load("steps_forward")
    pos, rot = body_tracks(m)
    pos2, rot2 = body_tracks(m.transformed([2.0, -1.5, 2.3]))
    a, b = windows(pos, rot, small_lib.window), windows(pos2, rot2, small_lib.window)
    np.testing.assert_allclose(a.pos, b.pos, atol=1e-9)
    from kinodyn.response.search import window_errors

    d = window_errors(a, b, *small_lib.weights)
    assert np.abs(np.diag(d)).max() < 1e-6, "the same frames of the moved clip match exactly"
    assert d[0, 40] > 0.1


def test_exhaustive_matches_brute_force(rng, small_lib):
    sim, tracks = _segment(rng, small_lib, "steps_forward", 20, 40)
    res = exhaustive(sim, small_lib, keep_surfaces=True)
    k = small_lib.names.index("fall_side")
    surf = res.surfaces[k]
    ref = np.array([[continuous_error_reference(tracks, small_lib.tracks[k], s, m, small_lib.weights)
                     for m in range(0, surf.shape[1], 7)] for s in range(0, surf.shape[0], 5)])
    np.testing.assert_allclose(surf[::5, ::7], ref, rtol=1e-9, atol=1e-9)
    assert small_lib.names[res.clip] == "steps_forward"
    assert res.error < 1e-6
    assert res.error == pytest.approx(min(s.min() for s in res.surfaces))


def test_continuous_error_matches_numpy(rng, small_lib):
    sim, tracks = _segment(rng, small_lib, "flinch_front", 0, 50, noise=0.05)
    for fs, fm in rng.uniform(0, 30, size=(20, 2)):
        got = continuous_error(tracks, small_lib.tracks[2], fs, fm, small_lib.weights)
        want = continuous_error_reference(tracks, small_lib.tracks[2], fs, fm, small_lib.weights)
        assert got == pytest.approx(want, rel=1e-9, abs=_TOL)


def test_fast_agrees_with_exhaustive_on_small_cases(rng, small_lib):
    for clip in ("steps_forward", "step_back_small", "fall_side"):
        sim, tracks = _segment(rng, small_lib, clip, int(rng.integers(5, 40)), 45)
        exh = exhaustive(sim, small_lib)
        k = small_lib.names.index(clip)
        fast = fast_align(sim, tracks, small_lib, k)
        assert fast.error <= exh.per_clip[k] + _NEAR_ZERO, clip
        assert fast.sampled_error >= exh.per_clip[k] - _TOL, "a sample is one of the exhaustive pairs"
        # The same timing up to where both windows slide along a matching stretch.
        assert abs((fast.sim_frame - fast.clip_frame) - (exh.sim_frame - exh.clip_frame)) < 2.0


def test_fast_is_near_the_optimum_on_held_out_cases(lib):
    rng = np.random.default_rng(2024)
    names = [n for n in lib.names]
    ratios = []
    for _ in range(12):
        clip = names[int(rng.integers(len(names)))]
        n = data.load(clip).num_frames
        sim, tracks = _segment(rng, lib, clip, int(rng.integers(0, max(1, n // 3))), 40, noise=0.08)
        exh = exhaustive(sim, lib)
        fast = fast_align(sim, tracks, lib, exh.clip)
        ratios.append(fast.error / exh.error)
    ratios = np.array(ratios)
    assert np.median(ratios) <= _RATIO_MEDIAN, ratios
    assert ratios.max() <= _RATIO_WORST, ratios


def test_compiled_refinement_does_as_well_as_scipy_s_bfgs(lib):
    """From the same best sample, the compiled BFGS ends at an error D as low as scipy's BFGS on the same
    objective: no worse at the median, at most 5 % worse on any case (D over continuous offsets is not
    convex, so from one start either method can settle in another local minimum)."""
    rng = np.random.default_rng(7)
    improved, ratios = 0, []
    for _ in range(8):
        clip = lib.names[int(rng.integers(len(lib)))]
        sim, tracks = _segment(rng, lib, clip, int(rng.integers(0, 20)), 40, noise=0.08)
        k = lib.names.index(clip)
        sampled = fast_align(sim, tracks, lib, k, AlignConfig(refine=0))
        fast = fast_align(sim, tracks, lib, k)
        a, b = lib.rows[k]
        _, ref = refine_reference(tracks, lib.tracks[k], (sampled.sim_frame, sampled.clip_frame),
                                  (len(sim) - 1, b - a - 1), lib.weights)
        ratios.append(fast.error / ref)
        improved += fast.error < sampled.error - 1e-9
    assert np.median(ratios) <= 1.0 and max(ratios) <= 1.05, np.round(ratios, 3)
    assert improved >= 4, "the refinement improves on the samples"


def test_stopping_early_samples_fewer_rows(rng, small_lib):
    sim, tracks = _segment(rng, small_lib, "steps_forward", 0, 120)
    k = small_lib.names.index("steps_forward")
    full = fast_align(sim, tracks, small_lib, k, AlignConfig(patience=100, refine=0))
    early = fast_align(sim, tracks, small_lib, k, AlignConfig(patience=1, refine=0))
    assert early.rows < full.rows
    assert full.rows == len(range(0, len(sim), 10))


def test_builtin_library_holds_every_strategy(lib):
    for n in ("steps_forward", "steps_back", "step_forward_small", "step_forward_large", "step_back_small",
              "step_back_large", "fall_side", "fall_forward", "fall_backward", "flinch_front", "flinch_back",
              "flinch_side_left", "flinch_side_right", "steps_forward_mirror", "fall_side_mirror"):
        assert n in lib.names, n
    assert lib.windows.pos.shape[1:] == (lib.window, lib.skeleton.num_joints, 3)
    assert lib.rows[-1, 1] == len(lib.windows)


def test_bad_input_is_rejected(tmp_path, small_lib):
    with pytest.raises(ParameterError, match="at least one clip"):
        from_motions([])
    with pytest.raises(ParameterError, match="no .bvh"):
        from_folder(tmp_path)
    with pytest.raises(ParameterError, match="not a folder"):
        from_folder(tmp_path / "missing")
    with pytest.raises(ParameterError, match="window_s"):
        SearchConfig(window_s=0.0)
    with pytest.raises(ParameterError, match="lacks"):
        from_motions([data.load("walk")], SearchConfig(weights={"Tail": (1.0, 1.0)}))
    short = windows(*body_tracks(data.load("walk")[:3]), small_lib.window)
    with pytest.raises(ParameterError, match="shorter"):
        exhaustive(short, small_lib)
    with pytest.raises(ParameterError, match="index"):
        fast_align(short, None, small_lib, 99)


def test_library_from_a_folder_of_capture(mocap_dir, tmp_path):
    import shutil

    for name in ("cmu_91_59", "cmu_104_13"):
        shutil.copy(mocap_dir / "reactions" / f"{name}.bvh", tmp_path / f"{name}.bvh")
    lib = from_folder(tmp_path, fps=60.0)
    assert lib.names == ("cmu_104_13", "cmu_91_59") and lib.fps == 60.0
    m = lib.clip("cmu_91_59")
    pos, rot = body_tracks(m[40:100])
    res = exhaustive(windows(pos, rot, lib.window), lib)
    assert lib.names[res.clip] == "cmu_91_59" and res.error < 1e-6
    # Clips for another skeleton in the same folder.
    from kinodyn.io.bvh import write_bvh

    write_bvh(tmp_path / "flinch_front.bvh", data.load("flinch_front"))
    with pytest.raises(KinodynError, match="another skeleton"):
        from_folder(tmp_path)
