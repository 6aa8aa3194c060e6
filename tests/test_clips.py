"""The packed clip store: packing, global frame indexing, facing frames, loops, sampling, npz round trip."""

from __future__ import annotations

import numpy as np
import pytest

from kinodyn import clips
from kinodyn.clips import ClipStore, ClipSupport
from kinodyn.errors import FileFormatError, MotionError, ParameterError, UnknownNameError
from kinodyn.math import quat, xform
from kinodyn.motion import Motion
from kinodyn.skeleton import Skeleton

_TOL = 1e-12


def _clips(rng) -> list[Motion]:
    sk = Skeleton(("root", "a", "b"), np.array([-1, 0, 1]), np.array([[0, 0, 0], [0, 0, 0.5], [0.3, 0, 0]]))
    out = []
    for i, n in enumerate((5, 9, 3)):
        out.append(Motion(sk, rng.normal(size=(n, 3)), quat.normalize(rng.normal(size=(n, 3, 4))), 30.0,
                          name=f"c{i}"))
    return out


def test_pack_index_and_round_trip(tmp_path, rng):
    motions = _clips(rng)
    db = ClipStore.from_motions(motions, tags=[("walk",), ("hit", "back"), ()])
    assert len(db) == 3 and db.num_frames == 17
    np.testing.assert_array_equal(db.starts, [0, 5, 14])
    np.testing.assert_array_equal(db.stops, [5, 14, 17])
    np.testing.assert_array_equal(db.clip_of_frame([0, 4, 5, 13, 14, 16]), [0, 0, 1, 1, 2, 2])
    np.testing.assert_array_equal(db.motion("c1").local_rot, motions[1].local_rot)
    assert db.with_tag("hit") == [1]
    db.save(tmp_path / "db.npz")
    back = clips.load(tmp_path / "db.npz")
    assert back.names == db.names and back.tags == db.tags
    for name in ("local_rot", "rot", "ground", "loop", "frame_phase", "fps", "is_cyclic"):
        np.testing.assert_array_equal(getattr(back, name), getattr(db, name), err_msg=name)
    np.testing.assert_array_equal(back.motion(2).root_pos, motions[2].root_pos)


def test_a_store_is_frozen_and_adding_returns_a_new_one(rng):
    motions = _clips(rng)
    one = ClipStore.from_motions(motions[:1])
    two = one.add("other", motions[1])
    assert len(one) == 1 and len(two) == 2 and two.names == ("c0", "other")
    with pytest.raises(ValueError):
        two.rot[0, 0, 0] = 2.0   # read-only arrays
    with pytest.raises(AttributeError):
        two.names = ()


def test_facing_frames_take_out_the_heading_and_keep_the_clip(rng):
    """The facing-frame rotations with the heading put back are the clip's rotations (up to sign)."""
    m = _clips(rng)[1]
    rot, z, g, loop = clips.facing_frames(m, cyclic=False)
    np.testing.assert_array_equal(z, m.root_pos[:, 2])
    back = quat.mul(quat.from_heading(g[:, 2]), rot[:, 0])
    assert quat.angle_between(back, m.local_rot[:, 0]).max() < 1e-9
    assert quat.angle_between(rot[:, 1:], m.local_rot[:, 1:]).max() < 1e-9
    np.testing.assert_array_equal(loop, np.zeros(3))


def test_unroll_loops_composes_whole_loops():
    """unroll_loops(loop, g, c) is compose(loop, ...) applied c times, elementwise; c = 0 leaves g."""
    loop = np.array([[1.0, 0.5, 0.3], [0.2, -0.1, -1.0]])
    g = np.array([[0.1, 0.2, 0.4], [1.0, 2.0, 3.0]])
    out = clips.unroll_loops(loop, g, np.array([3, 0]))
    ref = g[0]
    for _ in range(3):
        ref = xform.compose(loop[0], ref)
    np.testing.assert_allclose(out[0], ref, atol=_TOL)
    np.testing.assert_array_equal(out[1], g[1])


def test_sampling_a_cyclic_clip_moves_on_by_one_loop_per_cycle():
    """The root motion over a loop point equals the motion within the clip (built-in walk)."""
    from kinodyn.data import library as L

    walk = L.load("walk")
    store = ClipStore.empty(walk.skeleton).add("walk", walk, cyclic=True)
    dur = store.duration("walk")
    _, _, d_in = store.sample(np.zeros(1, int), np.array([0.5 * dur]), np.array([0.0]))
    _, _, d_over = store.sample(np.zeros(1, int), np.array([1.5 * dur]), np.array([dur]))
    np.testing.assert_allclose(d_over, d_in, atol=1e-9)
    rot, z = store.sample(np.zeros(2, int), np.array([0.25, 0.25 + dur]))
    np.testing.assert_allclose(rot[0], rot[1], atol=1e-12)   # clip times wrap
    assert z[0] == pytest.approx(z[1], abs=1e-12)


def test_support_rows_are_kept_per_clip(rng):
    m = _clips(rng)[0]
    sup = ClipSupport(np.array([0, 1], np.int8), np.array([0.05, 0.08]), -0.01, np.zeros(5, np.int8),
                      np.full(5, 0.5), 0.02)
    store = ClipStore.empty(m.skeleton).add("a", m, support=sup).add("b", m)
    phases, durations, start = store.support("a")
    np.testing.assert_array_equal(phases, [0, 1])
    np.testing.assert_array_equal(durations, [0.05, 0.08])
    assert start == -0.01 and store.rest[0] == 0.02
    assert len(store.support("b")[0]) == 0 and np.all(store.frame_phase[5:] == clips.NO_PHASE)
    with pytest.raises(ParameterError, match="frame rows"):
        store.add("c", m, support=sup._replace(frame_phase=np.zeros(4, np.int8)))


def test_rejects_bad_inputs_and_bad_files(tmp_path, rng):
    motions = _clips(rng)
    store = ClipStore.from_motions(motions)
    with pytest.raises(ParameterError, match="already in the library"):
        store.add("c0", motions[0])
    with pytest.raises(MotionError, match="at least 2 frames"):
        store.add("short", motions[0][:1])
    with pytest.raises(UnknownNameError, match="unknown clip 'x'"):
        store.motion("x")
    with pytest.raises(UnknownNameError, match="out of range"):
        store.index(7)
    bad = tmp_path / "bad.npz"
    np.savez(bad, meta=np.array('{"format": "other"}'))
    with pytest.raises(FileFormatError, match="not a kinodyn clip store"):
        clips.load(bad)
    with pytest.raises(ParameterError, match="empty"):
        ClipStore.empty(motions[0].skeleton).sample(np.zeros(1, int), np.zeros(1))


def test_the_builtin_store_holds_every_builtin_clip_with_its_support(clip_store):
    """The shared store (conftest) has every built-in clip, as loaded, looped where the library says so,
    and each looped clip has a support-phase sequence."""
    from kinodyn.data import library as data

    assert clip_store.names == tuple(data.names())
    for name in ("walk", "run", "kick"):
        k = clip_store.index(name)
        m = data.load(name)
        assert clip_store.cyclic(name) == data.info(name).cyclic
        if not clip_store.cyclic(name):  # looped clips are closed at their loop point on the way in
            np.testing.assert_allclose(clip_store.motion(k).local_rot, m.local_rot, atol=1e-12, err_msg=name)
    for k in np.nonzero(clip_store.is_cyclic)[0]:
        assert clip_store.seq_offsets[k + 1] > clip_store.seq_offsets[k], clip_store.names[k]
