"""Inverse kinematics: the two-bone corrections of a posed chain reach their targets, numpy and
compiled agree; the pole-based solver is checked in test_data_library.py."""

from __future__ import annotations

import numba
import numpy as np

from kinodyn import ik
from kinodyn.kinematics import fk_arrays
from kinodyn.math import quat

_TOL = 1e-10


def _leg_poses(rng):
    from kinodyn.blend.footlock import legs
    from kinodyn.data import library as L

    m = L.load("walk")
    sk = m.skeleton
    leg = legs(sk)[0]
    q = np.array(m.local_rot[::4])
    gr, gp = fk_arrays(np.array(m.root_pos[::4]), q, sk.offsets, sk.parents)
    t = gp[:, leg.ankle] + rng.normal(0.0, 0.03, (len(q), 3))
    return sk, leg, q, gr, gp, t, np.array(m.root_pos[::4])


@numba.njit(cache=False)
def _delta_compiled(a, b, c, t, A, B, f):  # pragma: no cover - compiled
    n = a.shape[0]
    da = np.empty((n, 4))
    db = np.empty((n, 4))
    for i in range(n):
        x, y = ik.two_bone_delta_kernel(a[i, 0], a[i, 1], a[i, 2], b[i, 0], b[i, 1], b[i, 2], c[i, 0], c[i, 1],
                                        c[i, 2], t[i, 0], t[i, 1], t[i, 2], A[i, 0], A[i, 1], A[i, 2], A[i, 3],
                                        B[i, 0], B[i, 1], B[i, 2], B[i, 3], f[i, 0], f[i, 1], f[i, 2], 1e-5)
        da[i] = x
        db[i] = y
    return da, db


def test_two_bone_delta_reaches_and_compiled_matches(rng):
    sk, leg, q, gr, gp, t, root = _leg_poses(rng)
    a, b, c = gp[:, leg.hip], gp[:, leg.knee], gp[:, leg.ankle]
    fallback = np.tile([0.0, 1.0, 0.0], (len(q), 1))
    da, db = ik.two_bone_delta(a, b, c, t, gr[:, leg.hip], gr[:, leg.knee], fallback)
    da2, db2 = _delta_compiled(a, b, c, t, gr[:, leg.hip], gr[:, leg.knee], fallback)
    assert quat.angle_between(da, da2).max() < _TOL and quat.angle_between(db, db2).max() < _TOL
    q2 = q.copy()
    q2[:, leg.hip] = quat.mul(q[:, leg.hip], da)
    q2[:, leg.knee] = quat.mul(q[:, leg.knee], db)
    _, gp2 = fk_arrays(root, q2, sk.offsets, sk.parents)
    reach = np.linalg.norm(b - a, axis=1) + np.linalg.norm(c - b, axis=1)
    ok = np.linalg.norm(t - a, axis=1) < 0.99 * reach
    assert ok.sum() > 10
    err = np.linalg.norm(gp2[:, leg.ankle] - t, axis=1)[ok]
    # the analytic correction reaches within 2 mm (it bends in the chain's plane, then swings the chain)
    assert np.median(err) < 1e-4 and err.max() < 2e-3
