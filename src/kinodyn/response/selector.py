"""The classifier's choice of clip, compiled (dynamic response, section 4.1: prediction at game speed).

A trained :class:`kinodyn.response.classifier.ReactionModel` (standardizing scaler, then scikit-learn's
polynomial-kernel ``SVC``, calibrated or not) chooses its clip from the pairwise decision values

    dec_ij(x) = sum_k a_ijk (gamma <sv_k, z> + coef0)^degree + b_ij,    z = (x - mean) / scale.

A plain ``SVC`` votes one against one, as libsvm does. The shipped models wrap the SVC in
``CalibratedClassifierCV(method="sigmoid", ensemble=False)``: scikit-learn turns the pairwise values into
one value per class (votes plus a bounded sum of confidences, ``_ovr_decision_function``), maps each
through its fitted sigmoid ``1 / (1 + exp(a f + b))`` and picks the most probable class (normalizing
does not change which). :class:`Selector` reads those fitted arrays once and evaluates the choice in one
compiled kernel, so one choice costs the kernel sums and nothing else (scikit-learn's per-call checks
cost more than the arithmetic for a single sample). It predicts exactly what the model's
``predict_features`` does (tested); class probabilities, wanted only to explain a choice, stay with the
model.
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
def _decisions(x, mean, scale, sv, starts, coef, intercept, gamma, coef0, degree, dec):  # pragma: no cover
    """The pairwise decision values of features ``x (n,)`` into ``dec (P,)``, libsvm's pair order."""
    kv = np.empty(sv.shape[0])
    _kernel_values(sv, (x - mean) / scale, gamma, coef0, degree, kv)
    n_class = starts.shape[0] - 1
    p = 0
    for i in range(n_class):
        for j in range(i + 1, n_class):
            s = 0.0
            for k in range(starts[i], starts[i + 1]):
                s += coef[j - 1, k] * kv[k]
            for k in range(starts[j], starts[j + 1]):
                s += coef[i, k] * kv[k]
            dec[p] = s + intercept[p]
            p += 1


@numba.njit(cache=True)
def _vote(dec, n_class):  # pragma: no cover - compiled
    """libsvm's one-against-one vote: the class with most wins (the first of equals)."""
    votes = np.zeros(n_class, dtype=np.int64)
    p = 0
    for i in range(n_class):
        for j in range(i + 1, n_class):
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


@numba.njit(cache=True)
def _calibrated(dec, n_class, a, b):  # pragma: no cover - compiled
    """The most probable class of a sigmoid-calibrated SVC: scikit-learn's one-against-rest values from
    the pairwise ``dec``, each through ``1 / (1 + exp(a f + b))`` (the first of equals)."""
    votes = np.zeros(n_class)
    conf = np.zeros(n_class)
    p = 0
    for i in range(n_class):
        for j in range(i + 1, n_class):
            conf[i] += dec[p]
            conf[j] -= dec[p]
            if dec[p] < 0.0:
                votes[j] += 1.0
            else:
                votes[i] += 1.0
            p += 1
    best, best_p = 0, -1.0
    for i in range(n_class):
        f = votes[i] + conf[i] / (3.0 * (abs(conf[i]) + 1.0))
        prob = 1.0 / (1.0 + np.exp(a[i] * f + b[i]))
        if prob > best_p:
            best, best_p = i, prob
    return best


def _svc_parts(pipeline):
    """``(scaler, svc, sigmoids)`` of a model's pipeline; ``sigmoids`` is ``(a, b)`` per class of a
    calibrated SVC, None for a plain one."""
    steps = getattr(pipeline, "steps", None)
    names = [type(s).__name__ for _, s in steps] if steps else []
    if names not in (["StandardScaler", "SVC"], ["StandardScaler", "CalibratedClassifierCV"]):
        raise ParameterError(f"the compiled selector needs a StandardScaler then SVC (or CalibratedClassifierCV "
                             f"of an SVC) pipeline, got {names}")
    scaler, clf = steps[0][1], steps[1][1]
    if names[1] == "SVC":
        return scaler, clf, None
    inner = getattr(clf, "calibrated_classifiers_", [])
    if clf.ensemble is not False or len(inner) != 1 or inner[0].method != "sigmoid":
        raise ParameterError("the compiled selector needs one sigmoid-calibrated SVC (CalibratedClassifierCV with "
                             f"method='sigmoid', ensemble=False), got method={clf.method!r}, ensemble={clf.ensemble}")
    svc = inner[0].estimator
    if type(svc).__name__ != "SVC" or len(svc.classes_) < 3 or not np.array_equal(svc.classes_, clf.classes_):
        raise ParameterError("the compiled selector needs a calibrated SVC over three or more classes, the same "
                             "classes as the calibration")
    a = np.array([c.a_ for c in inner[0].calibrators], dtype=np.float64)
    b = np.array([c.b_ for c in inner[0].calibrators], dtype=np.float64)
    return scaler, svc, (a, b)


class Selector:
    """The compiled choice of a reaction model: ``Selector(model).choose(states)`` is the clip index
    ``model(states)[0]`` gives.

    Args:
        model: a :class:`kinodyn.response.classifier.ReactionModel` whose pipeline is a ``StandardScaler``
            followed by a polynomial-kernel ``SVC``, plain or sigmoid-calibrated (as
            :func:`kinodyn.response.classifier.train` makes).

    Raises:
        ParameterError: a model of another shape (another kernel, more steps, ties broken otherwise).
    """

    def __init__(self, model):
        scaler, svc, sigmoids = _svc_parts(model.pipeline)
        if svc.kernel != "poly" or getattr(svc, "break_ties", False):
            raise ParameterError(f"the compiled selector needs a polynomial SVC voting one against one, got "
                                 f"kernel={svc.kernel!r}, break_ties={svc.break_ties}")
        self._sigmoids = sigmoids
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
        _decisions(np.ascontiguousarray(row), self._mean, self._scale, self._sv, self._starts, self._coef,
                   self._intercept, self._gamma, self._coef0, self._degree, self._dec)
        n_class = len(self._starts) - 1
        if self._sigmoids is None:
            return int(_vote(self._dec, n_class))
        return int(_calibrated(self._dec, n_class, *self._sigmoids))

    def choose(self, states) -> int:
        """Clip index for the states at 0.0, 0.1 and 0.2 s after contact."""
        return int(self._classes[self._one(features(states, self.kind))])
