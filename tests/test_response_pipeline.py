"""The dynamic-response pipeline: impact, simulation, choice, transition, clip (sections 3 and 6)."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import mocap_files
from kinodyn.contacts import sliding
from kinodyn.data import library as data
from kinodyn.errors import MotionError, ParameterError
from kinodyn.math import quat
from kinodyn.response import builtin, from_motions
from kinodyn.response.pipeline import Attacker, Ball, Push, ResponseConfig, eieo, recover, respond

_JUMP_CM = 1.0  # position jump at a join beyond the neighbouring frames' own motion (cm)
_TURN_DEG = 2.0  # rotation per frame at a join beyond the neighbouring frames' own (degrees)
_SLIDE = 0.02  # m/s, foot sliding in the clip stage


@pytest.fixture(scope="module")
def lib():
    return builtin()


@pytest.fixture(scope="module")
def responses(lib):
    walk = data.load("walk")
    out = {"front": respond(walk, lib, Ball(direction=np.pi)), "back": respond(walk, lib, Ball(direction=0.0)),
           "side": respond(walk, lib, Ball(direction=-np.pi / 2, target="chest")),
           "push": respond(walk, lib, Push((0.0, 110.0, 0.0), "chest", 1.0)),
           "punch": respond(data.load("idle"), lib, Attacker(data.load("punch"), (1.0, 0.0, np.pi)))}
    return out


def _per_frame(m):
    gp = m.global_positions()
    jump = np.linalg.norm(np.diff(gp, axis=0), axis=-1).max(axis=1) * 100.0
    turn = np.rad2deg(quat.angle_between(m.local_rot[1:], m.local_rot[:-1])).max(axis=1)
    return jump, turn


@pytest.mark.parametrize("case", ["front", "back", "side", "push", "punch"])
def test_output_is_continuous_at_the_three_joins(responses, case):
    _assert_continuous_joins(responses[case], case)


def _assert_continuous_joins(r, case):
    jump, turn = _per_frame(r.motion)
    for name, (a, _b) in (("impact", r.stages.simulation), ("choice", r.stages.transition),
                          ("clip", r.stages.clip)):
        # Step a-1 -> a crosses the join; compare with the 4 steps on either side of it (the motion's own
        # speed there: the simulated toes, for one, flick by 8-12 degrees a frame on their own).
        near = np.r_[max(a - 5, 0):a - 1, a:min(a + 4, len(jump))]
        own_j, own_t = jump[near].max(), turn[near].max()
        assert jump[a - 1] <= own_j + _JUMP_CM, f"{case} {name}: {jump[a - 1]:.2f} cm vs {own_j:.2f}"
        assert turn[a - 1] <= own_t + _TURN_DEG, f"{case} {name}: {turn[a - 1]:.2f} deg vs {own_t:.2f}"
        if name != "impact":
            # The stitched joins: no step within two frames of the join jumps either (a snap there would
            # hide among the neighbours above), against the motion's own speed beyond them.
            win = jump[max(a - 3, 0):a + 1]
            far = jump[np.r_[max(a - 7, 0):max(a - 3, 0), a + 1:min(a + 5, len(jump))]].max()
            assert win.max() <= far + _JUMP_CM, f"{case} {name}: {win.max():.2f} cm near the join vs {far:.2f}"


@pytest.mark.parametrize("base", ["idle", "fighting_stance"])
@pytest.mark.parametrize("direction", [np.pi, 0.0, np.pi / 2])
def test_other_base_motions_respond_continuously(lib, base, direction):
    """Standing (idle) and in a fighting stance, hit from the front, the back and the side: the three
    joins are continuous and the feet hold in the clip stage, as for the walk (a side fall pivots its
    feet as the body tips over them, 3.3 cm/s in the clip itself: there the placed clip may slide no more
    than the clip does over the same frames)."""
    r = respond(data.load(base), lib, Ball(direction=direction, target="chest"))
    _assert_continuous_joins(r, f"{base} at {np.rad2deg(direction):.0f} deg")
    seg = r.motion[r.stages.clip[0]:r.stages.clip[1]]
    own = data.load(r.clip)[r.clip_frame + 1:r.clip_frame + 1 + seg.num_frames]
    assert seg.num_frames <= 10 or sliding(seg).mean < max(_SLIDE, sliding(own).mean + 0.002)


_CMU_WALK = mocap_files("locomotion/cmu_02_01.bvh")
_CMU_REACTIONS = mocap_files("reactions/*.bvh")


@pytest.mark.mocap
@pytest.mark.skipif(not (_CMU_WALK and _CMU_REACTIONS), reason="../shared/mocap reactions or CMU 02_01 not found")
def test_cmu_skeleton_responds_with_a_folder_of_captured_reactions():
    """The CMU skeleton walking (02_01) responds with a library of captured reactions read from a folder
    (``--library DIR``); the converter's added T-pose frames are left out of the clips (a reaction
    search could otherwise match the T-pose), and the joins are continuous."""
    import kinodyn
    from kinodyn.io import has_added_tpose
    from kinodyn.response.library import from_folder

    clips = from_folder(_CMU_REACTIONS[0].parent, fps=60.0)
    assert not any(has_added_tpose(clips.clip(k)) for k in range(len(clips)))
    walk = kinodyn.load(_CMU_WALK[0])[1:].resample(60.0)
    for direction in (np.pi, 0.0, np.pi / 2):
        r = respond(walk, clips, Ball(direction=direction, target="chest"))
        assert r.motion.skeleton.num_joints == walk.skeleton.num_joints
        _assert_continuous_joins(r, f"CMU at {np.rad2deg(direction):.0f} deg")


def test_stages_tile_the_output(responses):
    for r in responses.values():
        s = r.stages
        assert s.motion[0] == 0 and s.motion[1] == s.simulation[0] and s.simulation[1] == s.transition[0]
        assert s.transition[1] == s.clip[0] and s.clip[1] == r.motion.num_frames
        assert s.simulation[1] > s.simulation[0] and s.transition[1] > s.transition[0]
        assert np.all(np.diff(s.labels()) >= 0)
        # The simulation ends with the frame the choice is made in (the lookahead starts from it); the
        # transition starts with the first frame the blended target drives.
        t0 = s.transition[0] - 1
        assert quat.angle_between(r.motion.local_rot[t0], r.lookahead.local_rot[0]).max() < 1e-9
        assert quat.angle_between(r.motion.local_rot[t0 + 1], r.lookahead.local_rot[1]).max() > 1e-6
        # The clip stage is the chosen clip itself, placed on the floor.
        clip = data.load(r.clip)
        seg = r.motion[s.clip[0]:s.clip[1]]
        same = clip.local_rot[r.clip_frame + 1:r.clip_frame + 1 + seg.num_frames]
        assert quat.angle_between(seg.local_rot[:, 1:], same[:, 1:]).max() < 1e-6, "joints as in the clip"
        np.testing.assert_allclose(seg.root_pos[:, 2], clip.root_pos[r.clip_frame + 1:][:seg.num_frames, 2],
                                   atol=1e-9)


def test_feet_do_not_slide_in_the_clip_stage(responses):
    for case, r in responses.items():
        seg = r.motion[r.stages.clip[0]:r.stages.clip[1]]
        if seg.num_frames > 10:
            assert sliding(seg).mean < _SLIDE, case


def _centroid(m):
    return m.global_positions().mean(axis=1)


def test_the_body_moves_along_the_impulse(lib):
    """The joints' centroid (standing in for the centre of mass) moves along the impulse's horizontal
    direction, relative to where the interrupted motion would have taken it, from the impact to the end
    of the transition, in at least 90 % of held-out throws."""
    rng = np.random.default_rng(77)
    walk = data.load("walk")
    good, n = 0, 10
    for _ in range(n):
        ball = Ball(speed=rng.uniform(7, 11), direction=rng.uniform(-np.pi, np.pi), height=rng.uniform(1.2, 1.7),
                    target=str(rng.choice(["chest", "stomach", "pelvis"])), time=rng.uniform(0.8, 1.3))
        r = respond(walk, lib, ball)
        c, t1 = r.stages.simulation[0], r.stages.transition[1] - 1
        moved = (_centroid(r.motion)[t1] - _centroid(r.motion)[c]) - \
            (_centroid(r.interrupted)[t1] - _centroid(r.interrupted)[c])
        good += float(moved[:2] @ r.impulse[:2]) > 0.0
    assert good >= 0.9 * n, f"{good} of {n}"


def test_eieo_weights():
    np.testing.assert_allclose(eieo([0.0, 0.5, 1.0]), [0.0, 0.5, 1.0])
    u = np.linspace(0, 1, 11)
    assert np.all(np.diff(eieo(u)) > 0)
    assert eieo(0.05) < 0.05 and eieo(0.95) > 0.95, "eases in and out"


def test_bad_input_is_rejected(lib):
    walk = data.load("walk")
    with pytest.raises(ParameterError, match="missed"):
        respond(walk, lib, Ball(direction=np.pi, aim=(1.4, 1.5, 1.2)))
    with pytest.raises(MotionError, match="skeleton"):
        from kinodyn.io.bvh import read_bvh
        from kinodyn.skeleton import Skeleton

        sk = walk.skeleton
        other = Skeleton(sk.names[:5], sk.parents[:5], sk.offsets[:5])
        respond(walk.replace(skeleton=other, local_rot=walk.local_rot[:, :5]), lib)
    with pytest.raises(MotionError, match="fps"):
        respond(walk.resample(30.0), lib)
    with pytest.raises(ParameterError, match="Ball, a Push or an Attacker"):
        respond(walk, lib, impact="a ball")
    with pytest.raises(ParameterError, match="horizon_s"):
        ResponseConfig(horizon_s=0.1)
    with pytest.raises(ParameterError):
        from_motions([])


@pytest.mark.parametrize("fall", list(data.GET_UP))
def test_fall_get_up_idle_is_continuous(fall):
    """A fall followed by its get-up and then idle (:func:`recover`) moves continuously at both joins: no
    position jump over 1 cm or turn over 2 degrees per frame beyond the neighbouring frames' own motion."""
    down = data.load(fall)
    m = recover(down, fall)
    getup = data.load(data.GET_UP[fall])
    assert m.num_frames == down.num_frames + getup.num_frames - 1 + data.load("idle").num_frames - 1
    jump, turn = _per_frame(m)
    for a in (down.num_frames, down.num_frames + getup.num_frames - 1):
        near = np.r_[max(a - 5, 0):a - 1, a:min(a + 4, len(jump))]
        assert jump[a - 1] <= jump[near].max() + _JUMP_CM, f"{fall} join at {a}: {jump[a - 1]:.2f} cm"
        assert turn[a - 1] <= turn[near].max() + _TURN_DEG, f"{fall} join at {a}: {turn[a - 1]:.2f} deg"
    # The get-up played as authored, where the fall ended; then the character stands (idle) at the end.
    seg = m[down.num_frames:down.num_frames + getup.num_frames - 1]
    assert quat.angle_between(seg.local_rot[:, 1:], getup.local_rot[1:, 1:]).max() < 1e-9
    assert m.root_pos[-1, 2] > 0.95


def test_recover_rejects_bad_input():
    with pytest.raises(ParameterError, match="no get-up follows clip 'flinch_front'"):
        recover(data.load("flinch_front"), "flinch_front")
    with pytest.raises(ParameterError, match="blend_s"):
        recover(data.load("fall_forward"), "fall_forward", blend_s=-1.0)
    fall = data.load("fall_forward")
    with pytest.raises(MotionError, match="fps"):
        recover(fall.resample(30.0), "fall_forward")


def test_a_model_responds_with_scikit_learns_choice(lib):
    """With a trained model as ``select`` the pipeline chooses through the compiled selector, and its clip
    and class probabilities are scikit-learn's for the same states."""
    pytest.importorskip("sklearn")
    from kinodyn.response.classifier import ReactionModel
    from kinodyn.response.command import DEFAULT_MODEL
    from kinodyn.response.dataset import ball_for
    from kinodyn.response.features import features

    model = ReactionModel.load(DEFAULT_MODEL / "large", lib)
    r = respond(data.load("walk"), lib, ball_for(1000, 1), model)
    assert model.selector() is not None
    x = features(r.features, "large")[None]
    assert r.clip_index == model.predict_features(x)[0] and r.clip == lib.names[r.clip_index]
    np.testing.assert_allclose(r.probabilities, model.probabilities(x)[0], rtol=1e-9, atol=1e-12)
