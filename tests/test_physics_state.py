"""Character state for learning: per-body state against MuJoCo's own functions, com, feet, features."""

from __future__ import annotations

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from kinodyn.data import library
from kinodyn.data.skeleton import humanoid
from kinodyn.errors import ParameterError
from kinodyn.physics.body import build_body
from kinodyn.physics.state import FEATURE_PARTS, character_state, states_from_qpos
from kinodyn.physics.world import World

_TOL = 1e-9


@pytest.fixture(scope="module")
def walking():
    w = World()
    c = w.add_character(build_body(humanoid()))
    c.play(library.load("walk"), loop=True)
    w.run(0.5)
    w.switch_to_dynamic(c)
    w.run(0.2)
    return w, c


def test_body_velocities_match_mj_objectVelocity(walking):
    w, c = walking
    st = character_state(w, c)
    m, d = w.model, w.data
    v6 = np.zeros(6)
    for b, bid in enumerate(c.body_ids):
        # world-frame velocity at the body's frame origin
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_XBODY, int(bid), v6, 0)
        np.testing.assert_allclose(st.angvel[b], v6[:3], atol=_TOL, err_msg=c.map.names[b])
        np.testing.assert_allclose(st.linvel[b], v6[3:], atol=_TOL, err_msg=c.map.names[b])
    np.testing.assert_allclose(st.pos, d.xpos[c.body_ids], atol=_TOL)
    np.testing.assert_allclose(np.abs(st.quat), np.abs(d.xquat[c.body_ids]), atol=_TOL)


def test_com_and_its_velocity(walking):
    w, c = walking
    st = character_state(w, c)
    m, d = w.model, w.data
    mujoco.mj_subtreeVel(m, d)
    root = int(c.body_ids[0])
    np.testing.assert_allclose(st.com, d.subtree_com[root], atol=_TOL)
    np.testing.assert_allclose(st.com_vel, d.subtree_linvel[root], atol=_TOL)


def test_foot_contacts_while_standing():
    w = World()
    c = w.add_character(build_body(humanoid()))
    w.run(0.2)  # the rest pose stands on both feet, servos holding it
    assert character_state(w, c).feet.tolist() == [True, True]
    w2 = World(ground=False, gravity=0.0)
    c2 = w2.add_character(build_body(humanoid()))
    w2.step()
    assert character_state(w2, c2).feet.tolist() == [False, False]


def test_feature_vectors(walking):
    w, c = walking
    st = character_state(w, c)
    spine = c.map.spine_bodies()[:4]  # the paper's pelvis, stomach, chest (and the neck here)
    v = st.vector(bodies=spine)
    assert v.shape == (len(spine) * 13 + 3 + 3 + 2,)
    assert np.isfinite(v).all()
    v_all = st.vector()
    assert v_all.shape == (c.map.num_bodies * 13 + 8,)
    assert st.vector(parts=("com",))[:2] == pytest.approx([0.0, 0.0])
    with pytest.raises(ParameterError):
        st.vector(parts=("speed",))
    with pytest.raises(ParameterError):
        st.vector(bodies=["Tail"])
    assert set(FEATURE_PARTS) == {"pos", "quat", "linvel", "angvel", "com", "com_vel", "feet"}


def test_relative_features_do_not_depend_on_where_the_character_stands():
    """Features are relative to the centre of mass's floor point: the same pose moved across the floor
    gives the same vector; absolute positions move with it."""
    walk = library.load("walk")
    shift = np.array([3.0, -2.0, 0.0])
    states = []
    for at in (np.zeros(3), shift):
        w = World()
        c = w.add_character(build_body(humanoid()), at=(at[0], at[1], 0.0))
        c.play(walk, at=(at[0], at[1], 0.0))
        w.run(0.3)
        states.append(character_state(w, c))
    here, there = states
    np.testing.assert_allclose(there.pos - here.pos, np.broadcast_to(shift, here.pos.shape), atol=1e-9)
    np.testing.assert_allclose(there.vector(), here.vector(), atol=1e-9)
    absolute = there.vector(parts=("pos",), relative=False) - here.vector(parts=("pos",), relative=False)
    np.testing.assert_allclose(absolute, np.tile(shift, len(here.pos)), atol=1e-9)


def test_batched_states_equal_single_states(walking):
    w, c = walking
    st = character_state(w, c)
    qp = np.stack([w.data.qpos.copy()] * 3)[None]
    qv = np.stack([w.data.qvel.copy()] * 3)[None]
    b = states_from_qpos(w, c, qp, qv)
    assert b["pos"].shape == (1, 3, c.map.num_bodies, 3)
    np.testing.assert_allclose(b["pos"][0, 1], st.pos, atol=_TOL)
    np.testing.assert_allclose(b["linvel"][0, 2], st.linvel, atol=_TOL)
    np.testing.assert_allclose(b["com_vel"][0, 0], st.com_vel, atol=_TOL)
    with pytest.raises(ParameterError):
        states_from_qpos(w, c, qp[..., :5], qv)
