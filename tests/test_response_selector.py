"""The compiled choice of clip (kinodyn.response.selector) against scikit-learn's own prediction."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from kinodyn.errors import ParameterError
from kinodyn.response import builtin
from kinodyn.response.classifier import ReactionModel
from kinodyn.response.command import DEFAULT_MODEL
from kinodyn.response.selector import Selector

pytest.importorskip("sklearn")
pytest.importorskip("skops")


@pytest.fixture(scope="module", params=["large", "small"])
def model(request):
    return ReactionModel.load(DEFAULT_MODEL / request.param, builtin())


def _rows(rng, model, n):
    """Feature rows spread like the training data (the scaler's mean and spread, varied in width)."""
    scaler = model.pipeline.steps[0][1]
    return scaler.mean_ + rng.normal(size=(n, len(scaler.mean_))) * scaler.scale_ * rng.uniform(0.2, 2.0, (n, 1))


def test_predicts_what_the_model_predicts(rng, model):
    x = _rows(rng, model, 2000)
    want = model.predict_features(x)
    assert len(set(want)) >= 5, "the rows reach several classes"
    np.testing.assert_array_equal(Selector(model).predict_features(x), want)


def _svc(model):
    """The fitted SVC inside the model (inside its calibration when calibrated)."""
    clf = model.pipeline.steps[1][1]
    return clf.calibrated_classifiers_[0].estimator if hasattr(clf, "calibrated_classifiers_") else clf


def test_the_shipped_models_are_calibrated():
    for kind in ("large", "small"):
        clf = ReactionModel.load(DEFAULT_MODEL / kind, builtin()).pipeline.steps[1][1]
        assert type(clf).__name__ == "CalibratedClassifierCV", kind


def test_a_plain_svc_is_chosen_by_its_vote(rng, model):
    """The vote of an uncalibrated SVC (libsvm's rule) on the same support vectors."""
    plain = copy.copy(model)
    plain.pipeline = copy.deepcopy(model.pipeline)
    plain.pipeline.steps[1] = ("svc", _svc(model))
    x = _rows(rng, model, 500)
    want = plain.pipeline.predict(x)
    np.testing.assert_array_equal(Selector(plain).predict_features(x), want)


def test_decision_values_are_libsvm_s(rng, model):
    svc = copy.deepcopy(_svc(model))
    svc.decision_function_shape = "ovo"
    x = _rows(rng, model, 20)
    want = svc.decision_function(model.pipeline.steps[0][1].transform(x))
    sel = Selector(model)
    got = np.array([sel.decision_values(row) for row in x])
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)


def test_chooses_from_states_as_the_model_does(model):
    from kinodyn.data import library as data
    from kinodyn.response.dataset import ball_for
    from kinodyn.response.pipeline import observe

    obs = observe(data.load("walk"), ball_for(1000, 3))
    assert Selector(model).choose(obs.states) == model(obs.states)[0]


def test_rejects_models_it_cannot_compile(model):
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVC

    other = copy.copy(model)
    other.pipeline = make_pipeline(StandardScaler(), SVC(kernel="rbf"))
    with pytest.raises(ParameterError, match="polynomial"):
        Selector(other)
    other.pipeline = make_pipeline(SVC(kernel="poly"))
    with pytest.raises(ParameterError, match="StandardScaler then SVC"):
        Selector(other)
    other.pipeline = copy.deepcopy(model.pipeline)
    other.pipeline.steps[1][1].ensemble = True
    with pytest.raises(ParameterError, match="sigmoid-calibrated"):
        Selector(other)
    with pytest.raises(ParameterError, match="features a row"):
        Selector(model).predict_features(np.zeros((1, 3)))


def test_the_float32_pass_settles_most_choices_and_defers_at_a_boundary(rng, model):
    """Most choices are settled by the float32 pass (its error bound clear of every decision); on a
    class boundary (two rows a few ulps apart that the model gives different clips) it must defer both to
    the float64 values (which there agree with libsvm's only to rounding, so either clip may come)."""
    x = _rows(rng, model, 400)
    want = model.predict_features(x)
    sel = Selector(model)
    np.testing.assert_array_equal(sel.predict_features(x), want)
    assert sel.counts["float32"] >= 0.9 * len(x), sel.counts
    i, j = 0, int(np.flatnonzero(want != want[0])[0])
    lo, hi = x[i], x[j]
    for _ in range(80):  # bisect the segment to the boundary between the two clips
        mid = 0.5 * (lo + hi)
        if model.predict_features(mid[None])[0] == want[i]:
            lo = mid
        else:
            hi = mid
    pair = np.stack([lo, hi])
    want_pair = model.predict_features(pair)
    assert want_pair[0] != want_pair[1]
    before = dict(sel.counts)
    assert set(sel.predict_features(pair)) <= set(want_pair)
    assert sel.counts["float64"] == before["float64"] + 2, "both rows at the boundary deferred"


def test_probabilities_are_scikit_learns(rng, model):
    """The compiled probabilities (from the float64 decision values) are ``predict_proba``'s, to rounding,
    over every library clip; as the ``select`` of the pipeline the clip is the model's and the most probable."""
    x = _rows(rng, model, 300)
    sel = Selector(model)
    np.testing.assert_allclose(sel.probabilities(x), model.probabilities(x), rtol=1e-9, atol=1e-12)
    from kinodyn.data import library as data
    from kinodyn.response.dataset import ball_for
    from kinodyn.response.pipeline import observe

    obs = observe(data.load("walk"), ball_for(1000, 5))
    k, probs = sel(obs.states)
    from kinodyn.response.features import features

    want = model.probabilities(features(obs.states, model.kind)[None])[0]
    assert k == int(np.argmax(want)) == sel.choose(obs.states)
    np.testing.assert_allclose(probs, want, rtol=1e-9, atol=1e-12)
