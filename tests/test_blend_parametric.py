"""The parametric locomotion model: cycles of one support pattern blended by weights, the motion and its
support-phase sequence adapted together."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from kinodyn import contacts
from kinodyn import phases
from kinodyn.blend.library import add_blend, add_clip, sequence
from kinodyn.blend.mixer import BlendConfig, Mixer
from kinodyn.blend.parametric import blend_cycles, register_cycles
from kinodyn.phases import DS, LS, RS
from kinodyn.clips import ClipStore
from kinodyn.errors import MotionError, ParameterError

#: One frame at 60 fps (seconds): detected element boundaries fall on frames.
_FRAME = 1 / 60


@pytest.fixture(scope="module")
def cycles():
    """The built-in walk (1.4 m/s, 1 s cycles) and a slower walk generated the same way (1.0 m/s,
    1.2 s cycles, the same duty factor)."""
    from kinodyn.data import gaits
    from kinodyn.data import library as L

    slow = gaits.gait(dataclasses.replace(gaits.WALK, speed=1.0, period=1.2), "slow_walk").motion
    return L.load("walk"), slow


def _speed(m):
    return float(np.linalg.norm(m.root_pos[-1, :2] - m.root_pos[0, :2]) / m.duration)


def test_the_blended_cycle_and_its_sequence_are_adapted_together(cycles):
    walk, slow = cycles
    sw, ss = (phases.from_motion(m, True) for m in cycles)
    speeds = []
    for a in (0.0, 0.25, 0.5, 0.75, 1.0):
        m, seq = blend_cycles([walk, slow], [1 - a, a])
        # the sequence: the weighted sums of the cycles' element durations (to within half a frame)
        np.testing.assert_array_equal(seq.phases, sw.phases)
        np.testing.assert_allclose(seq.durations, (1 - a) * sw.durations + a * ss.durations, atol=_FRAME / 2)
        assert seq.total == pytest.approx(m.duration, abs=1e-9)
        # ... and it is the sequence the blended motion really has
        found = phases.from_motion(m, True)
        np.testing.assert_array_equal(found.phases, seq.phases)
        np.testing.assert_allclose(found.durations, seq.durations, atol=1.5 * _FRAME)
        assert contacts.sliding(m).cm_per_s < 1.5
        speeds.append(_speed(m))
    assert speeds[0] == pytest.approx(_speed(walk), rel=0.01) and speeds[-1] == pytest.approx(_speed(slow), rel=0.01)
    assert np.all(np.diff(speeds) < 0)   # slower and slower toward the slow walk
    # stride lengths interpolate: 1.4 m and 1.2 m per cycle -> 1.3 m in 1.1 s at half and half
    assert speeds[2] == pytest.approx(1.3 / 1.1, rel=0.02)


def test_cycles_are_registered_by_their_support_pattern(cycles):
    """A cycle that starts half a cycle later (on the right foot) is registered by its pattern, so the
    blend is the same walk as with the unshifted cycle."""
    walk, slow = cycles
    half = round(0.6 * slow.fps)
    shifted = slow[half:].concatenate(slow[:half + 1])   # the same cycles, starting half a cycle later
    assert shifted.num_frames == slow.num_frames
    seqs = [phases.from_motion(m, True) for m in (walk, slow, shifted)]
    r = register_cycles(seqs)
    assert r[0] == 0 and r[1] == 0 and r[2] % 2 == 0 and r[2] != 0
    a, sa = blend_cycles([walk, slow], [0.5, 0.5])
    b, sb = blend_cycles([walk, shifted], [0.5, 0.5])
    np.testing.assert_allclose(sb.durations, sa.durations, atol=1.5 * _FRAME)
    assert contacts.sliding(b).cm_per_s < 1.5
    assert _speed(b) == pytest.approx(_speed(a), rel=0.02)


def test_cycles_of_different_patterns_or_bad_weights_are_refused(cycles):
    from kinodyn.data import library as L

    walk, slow = cycles
    with pytest.raises(MotionError, match=r"support pattern \[.*FLIGHT.*\], not that of cycle 0"):
        blend_cycles([walk, L.load("run")], [0.5, 0.5])
    with pytest.raises(MotionError, match="not cyclic"):
        blend_cycles([walk, slow], [0.5, 0.5],
                     [phases.from_motion(walk, True), phases.from_motion(slow, False)])
    for bad in ([0.5], [-1.0, 2.0], [0.0, 0.0], [np.nan, 1.0]):
        with pytest.raises(ParameterError, match="weights"):
            blend_cycles([walk, slow], bad)
    with pytest.raises(ParameterError, match="fps"):
        blend_cycles([walk, slow], [1, 1], fps=0.0)


def test_a_blended_cycle_plays_in_the_mixer_like_any_clip(cycles):
    from kinodyn.data import library as L

    walk, slow = cycles
    lib = ClipStore.empty(walk.skeleton)
    lib = add_clip(lib, "walk", walk, cyclic=True)
    lib = add_clip(lib, "slow", slow, cyclic=True)
    lib = add_clip(lib, "idle", L.load("idle"), cyclic=True)
    lib = add_clip(lib, "turn", L.load("turn_left"))
    before = lib
    lib = add_blend(lib, "brisk", {"walk": 0.5, "slow": 0.5})
    assert len(before) == 4 and "brisk" not in before.names   # stores are frozen: a new one comes back
    assert lib.names[-1] == "brisk" and lib.cyclic("brisk")
    assert list(sequence(lib, "brisk").phases[:4]) in ([DS, LS, DS, RS], [DS, RS, DS, LS])
    with pytest.raises(MotionError, match="'turn' is not cyclic"):
        add_blend(lib, "bad", {"walk": 0.5, "turn": 0.5})
    mx = Mixer(lib, 1, BlendConfig(), record=True)
    mx.start("walk", key="w", priority=1)
    roots = []
    for f in range(360):
        if f == 120:
            mx.start("brisk", key="b", priority=1)
            mx.stop("w")
        roots.append(mx.step(1 / 60).root_pos[0].copy())
    roots = np.array(roots)
    late = np.linalg.norm(roots[-1, :2] - roots[-61, :2])   # the last second: the blended walk's speed
    assert late == pytest.approx(1.3 / 1.1, rel=0.08)


def test_a_script_mixes_cycles(tmp_path, cycles):
    from kinodyn.blend.script import ScriptError, build_library, load_script, parse_script, run_script
    from kinodyn.io import save

    _, slow = cycles
    save(tmp_path / "slow.bvh", slow)
    (tmp_path / "s.yaml").write_text(
        "clips:\n"
        "  slow: {file: slow.bvh, cyclic: true}\n"
        "  brisk: {mix: {walk: 0.5, slow: 0.5}}\n"
        "actions:\n"
        "  - {clip: walk, start: 0.0, stop: 1.5, priority: 1}\n"
        "  - {clip: brisk, start: 1.2, stop: 4.0, priority: 1}\n")
    script = load_script(tmp_path / "s.yaml")
    lib = build_library(script)
    assert {"walk", "slow", "brisk"} <= set(lib.names)
    result = run_script(script, library=lib)
    assert result.starts["brisk@1.2"][1] is not None
    bad = {"clips": {"a": {"mix": {"b": 1.0}}, "b": {"mix": {"a": 1.0}}}, "actions": [{"clip": "a", "start": 0}]}
    with pytest.raises(ScriptError, match="cannot contain itself"):
        build_library(parse_script(bad))
    with pytest.raises(ScriptError, match=r"clips\.m: .*not cyclic"):
        build_library(parse_script({"clips": {"m": {"mix": {"walk": 1.0, "turn_left": 1.0}}},
                                    "actions": [{"clip": "m", "start": 0}]}))
    with pytest.raises(ScriptError, match="weights must not all be zero"):
        parse_script({"clips": {"m": {"mix": {"walk": 0}}}, "actions": [{"clip": "m", "start": 0}]})
    with pytest.raises(ScriptError, match="unknown key"):
        parse_script({"clips": {"m": {"mix": {"walk": 1}, "cyclic": True}}, "actions": [{"clip": "m", "start": 0}]})
