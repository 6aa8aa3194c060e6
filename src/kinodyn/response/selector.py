"""The classifier's choice of clip, compiled (dynamic response, section 4.1: prediction at game speed).

A trained :class:`kinodyn.response.classifier.ReactionModel` (standardizing scaler, then scikit-learn's
polynomial-kernel ``SVC``) chooses its clip by one-against-one voting over the decision values

    dec_ij(x) = sum_k a_ijk (gamma <sv_k, z> + coef0)^degree + b_ij,    z = (x - mean) / scale,

as libsvm does. :class:`Selector` reads those fitted arrays once and evaluates the vote in one compiled
kernel, so one choice costs the kernel sums and nothing else (scikit-learn's per-call checks cost more
than the arithmetic for a single sample). It predicts exactly what the model's ``predict_features``
does (tested); class probabilities, wanted only to explain a choice, stay with the model.
"""

from __future__ import annotations

import numba
import numpy as np

from kinodyn.errors import ParameterError
from kinodyn.response.features import features

__all__ = ["Selector"]


@numba.njit(cache=True, fastmath=True)
def _kernel_values(sv, z, gamma, coef0, degree, kv):  # pragma: no cover - compiled
    """``kv[k] = (gamma <sv_k, z> + coef0)^degree`` (the sums reassociated: vectorized; libsvm sums in
    its own order, so decision values agree to rounding, and the vote exactly unless one sits within
    rounding of zero)."""
    for k in range(sv.shape[0]):
        acc = 0.0
        for i in range(sv.shape[1]):
            acc += sv[k, i] * z[i]
        kv[k] = (gamma * acc + coef0) ** degree


@numba.njit(cache=True, fastmath=True)
def _vote(x, mean, scale, sv, starts, coef, intercept, gamma, coef0, degree, dec):  # pragma: no cover - compiled
    """Index of the winning class for features ``x (n,)``; the pairwise decision values go into ``dec``."""
    kv = np.empty(sv.shape[0])
    _kernel_values(sv, (x - mean) / scale, gamma, coef0, degree, kv)
    n_class = starts.shape[0] - 1
    votes = np.zeros(n_class, dtype=np.int64)
    p = 0
    for i in range(n_class):
        for j in range(i + 1, n_class):
            s = 0.0
            for k in range(starts[i], starts[i + 1]):
                s += coef[j - 1, k] * kv[k]
            for k in range(starts[j], starts[j + 1]):
                s += coef[i, k] * kv[k]
            dec[p] = s + intercept[p]
            if dec[p] > 0.0:
                votes[i] += 1
            else:
                votes[j] += 1
            p += 1
    best = 0
    for i in range(1, n_class):
        if votes[i] > votes[best]:
            best = i
    return best


class Selector:
    """The compiled choice of a reaction model: ``Selector(model).choose(states)`` is the clip index
    ``model(states)[0]`` gives.

    Args:
        model: a :class:`kinodyn.response.classifier.ReactionModel` whose pipeline is a ``StandardScaler``
            followed by a polynomial-kernel ``SVC`` (as :func:`kinodyn.response.classifier.train` makes).

    Raises:
        ParameterError: a model of another shape (another kernel, more steps, ties broken otherwise).
    """

    def __init__(self, model):
        steps = getattr(model.pipeline, "steps", None)
        names = [type(s).__name__ for _, s in steps] if steps else []
        if names != ["StandardScaler", "SVC"]:
            raise ParameterError(f"the compiled selector needs a StandardScaler then SVC pipeline, got {names}")
        scaler, svc = steps[0][1], steps[1][1]
        if svc.kernel != "poly" or getattr(svc, "break_ties", False):
            raise ParameterError(f"the compiled selector needs a polynomial SVC voting one against one, got "
                                 f"kernel={svc.kernel!r}, break_ties={svc.break_ties}")
        self.kind = model.kind
        self._mean = np.asarray(scaler.mean_ if scaler.with_mean else np.zeros(scaler.n_features_in_), float)
        self._scale = np.asarray(scaler.scale_ if scaler.with_std else np.ones(scaler.n_features_in_), float)
        self._sv = np.ascontiguousarray(svc.support_vectors_, dtype=np.float64)
        self._starts = np.concatenate([[0], np.cumsum(svc.n_support_)]).astype(np.int64)
        self._coef = np.ascontiguousarray(svc.dual_coef_, dtype=np.float64)
        self._intercept = np.ascontiguousarray(svc.intercept_, dtype=np.float64)
        self._gamma, self._coef0, self._degree = float(svc._gamma), float(svc.coef0), int(svc.degree)
        self._classes = np.asarray(svc.classes_).astype(np.int64)
        self._dec = np.empty(len(self._intercept))

    def predict_features(self, x: np.ndarray) -> np.ndarray:
        """``(N,)`` clip indices for feature rows ``x (N, n)`` (the model's ``predict_features``)."""
        x = np.atleast_2d(np.asarray(x, dtype=np.float64))
        if x.shape[1] != len(self._mean):
            raise ParameterError(f"the model takes {len(self._mean)} features a row, got {x.shape[1]}")
        return np.array([self._classes[self._one(row)] for row in x], dtype=np.int64)

    def decision_values(self, x: np.ndarray) -> np.ndarray:
        """``(P,)`` one-against-one decision values for one feature row ``x (n,)`` (libsvm's order)."""
        self._one(np.asarray(x, dtype=np.float64))
        return self._dec.copy()

    def _one(self, row: np.ndarray) -> int:
        return int(_vote(np.ascontiguousarray(row), self._mean, self._scale, self._sv, self._starts, self._coef,
                         self._intercept, self._gamma, self._coef0, self._degree, self._dec))

    def choose(self, states) -> int:
        """Clip index for the states at 0.0, 0.1 and 0.2 s after contact."""
        return int(self._classes[self._one(features(states, self.kind))])
