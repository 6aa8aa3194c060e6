"""Feature vectors of the reaction classifier: the vectorized, compiled rotation gives, bit for bit, the
vectors of the plain per-slice formulation with kinodyn.math.quat (the training data depends on it)."""

from __future__ import annotations

import numpy as np
import pytest

from kinodyn.data import library as data
from kinodyn.math import quat
from kinodyn.response.dataset import ball_for
from kinodyn.response.features import FEET, SPINE, features
from kinodyn.response.pipeline import observe


def _plain(states, kind):
    """The features written slice by slice with kinodyn.math.quat (the reference)."""
    s0 = states[0]
    q = quat.from_heading(-quat.heading(s0.quat[0], [1.0, 0.0, 0.0]))
    origin = np.array([s0.com[0], s0.com[1], 0.0])
    names = list(s0.names)
    if kind == "small":
        chest, pelvis = names.index("Spine1"), names.index("Hips")
        out = [v for s in states for v in (np.array([s.com[2]]), quat.mul_vec(q, s.com_vel))]
        out += [quat.mul_vec(q, s.angvel[chest])[:2] for s in states[1:]]
        up = quat.mul_vec(quat.mul(q, states[-1].quat[pelvis]), [0.0, 0.0, 1.0])
        return np.concatenate(out + [up[:2], states[-1].feet.astype(np.float64)])
    spine, feet = [names.index(n) for n in SPINE], [names.index(n) for n in FEET]
    out = []
    for s in states:
        out += [quat.mul_vec(q, s.pos[spine] - origin).ravel(), quat.abs(quat.mul(q, s.quat[spine])).ravel(),
                quat.mul_vec(q, s.linvel[spine]).ravel(), quat.mul_vec(q, s.angvel[spine]).ravel(),
                quat.mul_vec(q, s.pos[feet] - origin).ravel(), quat.mul_vec(q, s.linvel[feet]).ravel(),
                s.feet.astype(np.float64)]
    return np.concatenate(out)


@pytest.mark.parametrize("case", [0, 7])
def test_features_are_the_plain_formulation_bit_for_bit(case):
    obs = observe(data.load("walk"), ball_for(1000, case))
    for kind in ("large", "small"):
        np.testing.assert_array_equal(features(obs.states, kind), _plain(obs.states, kind), err_msg=kind)


def test_features_do_not_depend_on_the_quaternions_sign():
    """``q`` and ``-q`` are one rotation: states with every orientation negated give the same vectors
    (the orientations enter as the representative with ``w >= 0``), bit for bit, as the plain formulation."""
    import dataclasses

    obs = observe(data.load("walk"), ball_for(1000, 0))
    flipped = tuple(dataclasses.replace(s, quat=-s.quat) for s in obs.states)
    for kind in ("large", "small"):
        np.testing.assert_array_equal(features(flipped, kind), features(obs.states, kind), err_msg=kind)
        np.testing.assert_array_equal(features(flipped, kind), _plain(flipped, kind), err_msg=kind)
