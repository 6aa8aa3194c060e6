"""The classifier's choice of clip, compiled (dynamic response, section 4.1: prediction at game speed).

A trained :class:`kinodyn.response.classifier.ReactionModel` (standardizing scaler, then scikit-learn's
polynomial-kernel ``SVC``, calibrated or not) chooses its clip from the pairwise decision values

    dec_ij(x) = sum_k a_ijk (gamma <sv_k, z> + coef0)^degree + b_ij,    z = (x - mean) / scale.

A plain ``SVC`` votes one against one, as libsvm does. The shipped models wrap the SVC in
``CalibratedClassifierCV(method="sigmoid", ensemble=False)``: scikit-learn turns the pairwise values into
one value per class (votes plus a bounded sum of confidences, ``_ovr_decision_function``), maps each
through its fitted sigmoid ``1 / (1 + exp(a f + b))`` and picks the most probable class (normalizing
does not change which). :class:`Selector` reads those fitted arrays once and evaluates the choice compiled, so one choice costs
the kernel sums and nothing else (scikit-learn's per-call checks cost more than the arithmetic for a
single sample). It predicts exactly what the model's ``predict_features`` does (tested).

The choice (:meth:`Selector.choose`) streams the support vectors in float32 first: half the memory of
float64, which is what a choice costs. Each float32 dot product carries a proven error bound (Higham's
for a sum in any order), carried through the kernel power, the pairwise sums, the votes and the sigmoids
into an interval per class probability; when the best class's lower end clears every other upper end the
float64 arithmetic must choose it too, and otherwise (a few choices in a hundred, a decision or the
winning margin inside the bound) the float64 decision values decide. So the choice is always the
float64 one. The class probabilities (:meth:`Selector.probabilities`, and with the choice as the
``select`` of :func:`kinodyn.response.pipeline.respond`, :meth:`Selector.__call__`) come from the float64
values, as scikit-learn's ``predict_proba`` computes them.
"""

from __future__ import annotations

import numba
import numpy as np

from kinodyn.errors import ParameterError
from kinodyn.response.features import features

__all__ = ["Selector"]


@numba.njit(cache=True, inline="always")
def _power(t, degree):  # pragma: no cover - compiled
    """``t ** degree`` for a whole ``degree >= 1`` by multiplication (a pow call per support vector
    costs as much as its dot product)."""
    p = t
    for _ in range(degree - 1):
        p *= t
    return p


@numba.njit(cache=True, fastmath=True)
def _kernel_values(sv, z, gamma, coef0, degree, kv):  # pragma: no cover - compiled
    """``kv[k] = (gamma <sv_k, z> + coef0)^degree`` (the sums reassociated: vectorized; libsvm sums in
    its own order, so decision values agree to rounding, and the vote exactly unless one sits within
    rounding of zero)."""
    for k in range(sv.shape[0]):
        acc = 0.0
        for i in range(sv.shape[1]):
            acc += sv[k, i] * z[i]
        kv[k] = _power(gamma * acc + coef0, degree)


@numba.njit(cache=True, fastmath=True)
def _dots32(sv32, z32, out):  # pragma: no cover - compiled
    """``out[k] = <sv32_k, z32>`` summed in float32, in whatever order vectorizes."""
    for k in range(sv32.shape[0]):
        acc = np.float32(0.0)
        for i in range(sv32.shape[1]):
            acc += sv32[k, i] * z32[i]
        out[k] = acc


@numba.njit(cache=True, fastmath=True)
def _decisions(x, mean, scale, sv, starts, coef, intercept, gamma, coef0, degree, dec):  # pragma: no cover
    """The pairwise decision values of features ``x (n,)`` into ``dec (P,)``, libsvm's pair order."""
    kv = np.empty(sv.shape[0])
    _kernel_values(sv, (x - mean) / scale, gamma, coef0, degree, kv)
    n_class = starts.shape[0] - 1
    p = 0
    for i in range(n_class):
        for j in range(i + 1, n_class):
            # slices, not offset indices: the loops vectorize
            wi, ki = coef[j - 1, starts[i]:starts[i + 1]], kv[starts[i]:starts[i + 1]]
            wj, kj = coef[i, starts[j]:starts[j + 1]], kv[starts[j]:starts[j + 1]]
            s = 0.0
            for k in range(wi.shape[0]):
                s += wi[k] * ki[k]
            for k in range(wj.shape[0]):
                s += wj[k] * kj[k]
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
def _sigmoids(dec, n_class, a, b, out):  # pragma: no cover - compiled
    """A sigmoid-calibrated SVC's per-class values into ``out (n_class,)``: scikit-learn's
    one-against-rest values from the pairwise ``dec``, each through ``1 / (1 + exp(a f + b))``."""
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
    for i in range(n_class):
        f = votes[i] + conf[i] / (3.0 * (abs(conf[i]) + 1.0))
        out[i] = 1.0 / (1.0 + np.exp(a[i] * f + b[i]))


@numba.njit(cache=True)
def _calibrated(dec, n_class, a, b):  # pragma: no cover - compiled
    """The most probable class of a sigmoid-calibrated SVC (the first of equals)."""
    values = np.empty(n_class)
    _sigmoids(dec, n_class, a, b, values)
    best = 0
    for i in range(1, n_class):
        if values[i] > values[best]:
            best = i
    return best


#: float32 unit roundoff.
_U32 = 2.0 ** -24


@numba.njit(cache=True, fastmath=True)
def _bounded_kernel(dots, n_feat, z_norm, sv_norm, gamma, coef0, degree, kv, err):  # pragma: no cover
    """Kernel values ``kv (S,)`` from float32 dot products ``dots (S,)`` of ``n_feat`` terms, and bounds
    ``err (S,)`` on their error.

    A dot product of ``n`` float32 terms (each factor rounded to float32, then multiplied and summed in
    any order, as vectorizing does) is within ``gamma_{n+2} sum_i |sv_i z_i| <= gamma_{n+2} |sv| |z|`` of
    the exact one (Higham, Accuracy and Stability of Numerical Algorithms, 3.1; ``gamma_m = m u /
    (1 - m u)``, ``u`` the float32 unit roundoff), ``sv_norm (S,)`` and ``z_norm`` the norms; ``gamma_{n+3}``
    is used, and the norms taken 1e-6 larger, for the float64 rounding of the bound itself. That bounds
    each kernel value: ``|t^d - s^d| <= d max(|t|, |s|)^(d-1) |t - s|``, with a relative 1e-12 for the
    float64 arithmetic of ``t`` and its power."""
    gam = (n_feat + 3.0) * _U32 / (1.0 - (n_feat + 3.0) * _U32)
    for k in range(dots.shape[0]):
        t = gamma * dots[k] + coef0
        dt = gamma * gam * sv_norm[k] * z_norm * (1.0 + 1e-6)
        at = abs(t) + dt
        if degree == 3:  # the shipped models' degree, unrolled so the loop vectorizes
            v, e = t * t * t, 3.0 * at * at * dt
        elif degree == 2:
            v, e = t * t, 2.0 * at * dt
        else:
            v, e = _power(t, degree), (degree * _power(at, degree - 1) * dt if degree > 1 else dt)
        kv[k] = v
        err[k] = e + 1e-12 * abs(v)


@numba.njit(cache=True, fastmath=True)
def _class_sums(kv, err, starts, coef, sums, errs):  # pragma: no cover - compiled
    """Per class ``c`` and coefficient row ``r``, ``sums[c, r] = sum_{k in c} coef[r, k] kv[k]`` and
    ``errs[c, r]`` the bound carried from ``err`` plus a relative ``1e-12`` of the sum's magnitude for the
    float64 arithmetic (of any order). Each class's support vectors are a contiguous slice (slices, not
    offset indices, so the loops vectorize)."""
    for c in range(starts.shape[0] - 1):
        kc, ec = kv[starts[c]:starts[c + 1]], err[starts[c]:starts[c + 1]]
        for r in range(coef.shape[0]):
            w = coef[r, starts[c]:starts[c + 1]]
            acc, e, mag = 0.0, 0.0, 0.0
            for k in range(w.shape[0]):
                acc += w[k] * kc[k]
                e += abs(w[k]) * ec[k]
                mag += abs(w[k] * kc[k])
            sums[c, r] = acc
            errs[c, r] = e + 1e-12 * mag


@numba.njit(cache=True)
def _certain(sums, errs, intercept, a, b):  # pragma: no cover - compiled
    """The class the float64 decision values choose, when the bounded sums of :func:`_class_sums`
    settle it; -1 when they do not.

    Pair ``(i, j)``'s decision value is ``sums[i, j - 1] + sums[j, i] + intercept``, within the summed
    bounds ``errs`` (:func:`_class_sums`); a pair whose interval holds zero may vote either way. For a calibrated model (``a``, ``b``
    the sigmoids; empty for a plain SVC) each class's one-against-rest value then lies in an interval
    (certain votes plus the undecided ones; the bounded confidence of the extreme sums, monotone), so its
    probability does too (monotone in it); the choice is certain when the best lower end exceeds every
    other upper end. For a plain SVC it is certain when no pair is undecided."""
    n_class = sums.shape[0]
    sure, open_ = np.zeros(n_class), np.zeros(n_class)
    lo_c, hi_c = np.zeros(n_class), np.zeros(n_class)
    p = 0
    for i in range(n_class):
        for j in range(i + 1, n_class):
            s = sums[i, j - 1] + sums[j, i] + intercept[p]
            e = errs[i, j - 1] + errs[j, i] + 1e-12 * abs(intercept[p])
            lo, hi = s - e, s + e
            if lo > 0.0:
                sure[i] += 1.0
            elif hi < 0.0:
                sure[j] += 1.0
            else:
                open_[i] += 1.0
                open_[j] += 1.0
            lo_c[i] += lo
            hi_c[i] += hi
            lo_c[j] -= hi
            hi_c[j] -= lo
            p += 1
    if a.shape[0] == 0:  # plain SVC: libsvm's vote, once every pair is decided
        if open_.sum() > 0.0:
            return -1
        return int(np.argmax(sure))  # the first of equals, as libsvm
    p_lo, p_hi = np.empty(n_class), np.empty(n_class)
    for i in range(n_class):
        f_lo = sure[i] + lo_c[i] / (3.0 * (abs(lo_c[i]) + 1.0))
        f_hi = sure[i] + open_[i] + hi_c[i] / (3.0 * (abs(hi_c[i]) + 1.0))
        u, v = a[i] * f_lo + b[i], a[i] * f_hi + b[i]
        p_lo[i] = 1.0 / (1.0 + np.exp(max(u, v)))
        p_hi[i] = 1.0 / (1.0 + np.exp(min(u, v)))
    best = int(np.argmax(p_lo))
    for i in range(n_class):
        if i != best and p_hi[i] * (1.0 + 1e-12) >= p_lo[best]:
            return -1
    return best


@numba.njit(cache=True)
def _choose32(x, mean, scale, sv32, sv_norm, gamma, coef0, degree, starts, coef, intercept, a, b,
              work):  # pragma: no cover - compiled
    """The first pass of a choice, in one call: features ``x (n,)`` standardized, the float32 dot
    products, their bounded kernel values and class sums, the certain choice or -1 (:func:`_certain`).
    ``work`` = (dots, kv, err (S,), sums, errs (K, K - 1)), scratch."""
    dots, kv, err, sums, errs = work
    z = (x - mean) / scale
    z_norm = np.sqrt(np.sum(z * z))
    if not z_norm < 1e30:  # beyond float32's range (or not finite): no bound to carry
        return -1
    _dots32(sv32, z.astype(np.float32), dots)
    _bounded_kernel(dots, z.shape[0], z_norm, sv_norm, gamma, coef0, degree, kv, err)
    _class_sums(kv, err, starts, coef, sums, errs)
    return _certain(sums, errs, intercept, a, b)


@numba.njit(cache=True)
def _probabilities(dec, n_class, a, b, out):  # pragma: no cover - compiled
    """scikit-learn's ``predict_proba`` of a sigmoid-calibrated SVC from the pairwise ``dec`` into
    ``out (n_class,)``: the one-against-rest values through their sigmoids, normalized to sum 1
    (uniform where every sigmoid is 0); values within 1e-5 above 1 clipped to 1, as scikit-learn does."""
    _sigmoids(dec, n_class, a, b, out)
    total = out.sum()
    for i in range(n_class):
        out[i] = out[i] / total if total != 0.0 else 1.0 / n_class
        if 1.0 < out[i] <= 1.0 + 1e-5:
            out[i] = 1.0


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
        self._n_clips = len(model.clips)
        self._dec = np.empty(len(self._intercept))
        # The first pass: float32 support vectors (half the memory to stream) and their float64 norms.
        self._sv32 = self._sv.astype(np.float32)
        self._sv_norm = np.linalg.norm(self._sv, axis=1)
        n_sv, n_class = len(self._sv), len(svc.n_support_)
        self._work = (np.empty(n_sv), np.empty(n_sv), np.empty(n_sv), np.empty((n_class, n_class - 1)),
                      np.empty((n_class, n_class - 1)))
        self._ab = sigmoids if sigmoids is not None else (np.zeros(0), np.zeros(0))
        #: choices settled by the float32 pass and those rechecked in float64 (for the benchmark).
        self.counts = {"float32": 0, "float64": 0}

    def predict_features(self, x: np.ndarray) -> np.ndarray:
        """``(N,)`` clip indices for feature rows ``x (N, n)`` (the model's ``predict_features``)."""
        x = np.atleast_2d(np.asarray(x, dtype=np.float64))
        if x.shape[1] != len(self._mean):
            raise ParameterError(f"the model takes {len(self._mean)} features a row, got {x.shape[1]}")
        return np.array([self._classes[self._one(row)] for row in x], dtype=np.int64)

    def decision_values(self, x: np.ndarray) -> np.ndarray:
        """``(P,)`` one-against-one decision values for one feature row ``x (n,)`` (libsvm's order)."""
        self._exact(np.asarray(x, dtype=np.float64))
        return self._dec.copy()

    def _one(self, row: np.ndarray) -> int:
        """Class position of one feature row: the float32 pass when its error bound settles the choice,
        else the float64 decision values (the same choice either way)."""
        k = _choose32(row, self._mean, self._scale, self._sv32, self._sv_norm, self._gamma, self._coef0,
                      self._degree, self._starts, self._coef, self._intercept, *self._ab, self._work)
        if k >= 0:
            self.counts["float32"] += 1
            return int(k)
        self.counts["float64"] += 1
        return self._exact(row)

    def _exact(self, row: np.ndarray) -> int:
        """Class position of one feature row from the float64 decision values."""
        _decisions(np.ascontiguousarray(row), self._mean, self._scale, self._sv, self._starts, self._coef,
                   self._intercept, self._gamma, self._coef0, self._degree, self._dec)
        n_class = len(self._starts) - 1
        if self._sigmoids is None:
            return int(_vote(self._dec, n_class))
        return int(_calibrated(self._dec, n_class, *self._sigmoids))

    def choose(self, states) -> int:
        """Clip index for the states at 0.0, 0.1 and 0.2 s after contact."""
        return int(self._classes[self._one(features(states, self.kind))])

    def probabilities(self, x: np.ndarray) -> np.ndarray:
        """``(N, K)`` class probabilities over every library clip for feature rows ``x (N, n)`` (the model's
        ``probabilities``, to rounding; 0 for clips never seen in training).

        Raises:
            ParameterError: the model is a plain SVC, which has no probabilities.
        """
        if self._sigmoids is None:
            raise ParameterError("a plain SVC has no class probabilities; calibrate it (train does)")
        x = np.atleast_2d(np.asarray(x, dtype=np.float64))
        out = np.zeros((len(x), self._n_clips))
        p = np.empty(len(self._classes))
        for n, row in enumerate(x):
            self._exact(row)
            _probabilities(self._dec, len(self._classes), *self._sigmoids, p)
            out[n, self._classes] = p
        return out

    def __call__(self, states) -> tuple[int, np.ndarray | None]:
        """The ``select`` of :func:`kinodyn.response.pipeline.respond`: clip index and class probabilities
        (None for a plain SVC) for the states at 0.0, 0.1 and 0.2 s after contact, from one evaluation of
        the float64 decision values (the probabilities need them; the choice is theirs)."""
        x = features(states, self.kind)
        if self._sigmoids is None:
            return int(self._classes[self._exact(x)]), None
        k = self._exact(x)
        p = np.empty(len(self._classes))
        _probabilities(self._dec, len(self._classes), *self._sigmoids, p)
        probs = np.zeros(self._n_clips)
        probs[self._classes] = p
        return int(self._classes[k]), probs
