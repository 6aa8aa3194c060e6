"""Reaction classifier, features and training data (dynamic response, sections 4 and 7.2)."""

from __future__ import annotations

import numpy as np
import pytest

from kinodyn.data import library as data
from kinodyn.errors import FileFormatError, ParameterError
from kinodyn.response import builtin, from_motions
from kinodyn.response.classifier import ReactionModel, train
from kinodyn.response.command import DEFAULT_MODEL
from kinodyn.response.dataset import Dataset, ball_for, generate
from kinodyn.response.features import feature_names, features
from kinodyn.response.pipeline import observe

pytest.importorskip("sklearn")
pytest.importorskip("skops")


@pytest.fixture(scope="module")
def lib():
    return builtin()


@pytest.fixture(scope="module")
def small_set():
    return generate(6, seed=3, workers=1, chunk_size=3, show_progress=False)


def _blobs(rng, k=3, n=60, dim=20):
    centres = rng.normal(scale=3.0, size=(k, dim))
    y = rng.integers(k, size=n)
    return centres[y] + rng.normal(size=(n, dim)), y


def test_feature_vectors_have_their_documented_sizes(small_set):
    assert small_set.large.shape == (6, 198) and small_set.small.shape == (6, 20)
    assert len(feature_names("large")) == 198 and len(feature_names("small")) == 20
    assert np.all(np.isfinite(small_set.large[small_set.valid()]))


def test_features_do_not_depend_on_where_the_character_faces():
    walk = data.load("walk")
    ball = ball_for(0, 1)
    a = observe(walk, ball)
    turned = walk.transformed([1.0, -2.0, 1.1])
    b = observe(turned, ball.__class__(**{**ball.__dict__, "direction": ball.direction + 1.1}))
    # The 0.0 s slice: the same state seen from another heading and place. (Later slices come from the
    # simulation, which drifts apart in contact within 0.1 s since kinematic playback keeps its servo
    # targets current: 0.34 at 0.1 s.)
    for kind, n in (("large", 66), ("small", 4)):
        np.testing.assert_allclose(features(a.states, kind)[:n], features(b.states, kind)[:n], atol=0.05,
                                   err_msg=kind)


def test_dataset_keeps_every_clips_best_error(small_set, lib):
    """per_clip holds each clip's best exhaustive error D: the label is its argmin, the label's error its min."""
    ok = small_set.valid()
    assert small_set.per_clip.shape == (len(small_set), len(lib))
    np.testing.assert_array_equal(small_set.per_clip[ok].argmin(axis=1), small_set.clip[ok])
    np.testing.assert_array_equal(small_set.per_clip[ok].min(axis=1), small_set.error[ok])
    assert np.all(np.isinf(small_set.per_clip[~ok]))


def test_dataset_keeps_every_clips_fast_alignment_error(small_set, lib):
    """fast_per_clip is each clip's error D at the timing the fast alignment finds on the case's lookahead
    (recomputed here for two cases), never below the exhaustive optimum by more than the continuous
    offsets allow and never far above it (the fast path's bound)."""
    from kinodyn.response.pipeline import fast_errors

    ok = small_set.valid()
    assert small_set.fast_per_clip.shape == small_set.per_clip.shape
    assert np.all(np.isinf(small_set.fast_per_clip[~ok]))
    for i in np.nonzero(ok)[0][:2]:
        again = fast_errors(observe(data.load("walk"), ball_for(3, int(i))), lib)
        np.testing.assert_array_equal(again, small_set.fast_per_clip[i])
    fast, best = small_set.fast_per_clip[ok], small_set.per_clip[ok]
    assert np.all(fast >= 0.9 * best) and np.median(fast / best) < 1.05


def test_a_dataset_of_the_first_format_reads_without_fast_errors(small_set, tmp_path):
    import json

    old = {k: getattr(small_set, k) for k in ("large", "small", "clip", "sim_frame", "clip_frame", "error",
                                                "per_clip", "ball")}
    np.savez(tmp_path / "v1.npz", meta=np.array(json.dumps({**small_set.meta, "format": "kinodyn.response-dataset/1"})),
             **old)
    back = Dataset.load(tmp_path / "v1.npz")
    np.testing.assert_array_equal(back.per_clip, small_set.per_clip)
    assert back.fast_per_clip.shape == small_set.per_clip.shape and np.all(np.isnan(back.fast_per_clip))


def test_dataset_is_the_same_for_one_and_two_workers(small_set, tmp_path):
    two = generate(6, seed=3, workers=2, chunk_size=3, show_progress=False)
    for k in ("large", "small", "clip", "sim_frame", "clip_frame", "error", "per_clip", "fast_per_clip", "ball"):
        np.testing.assert_array_equal(getattr(small_set, k), getattr(two, k), err_msg=k)
    small_set.save(tmp_path / "d.npz")
    back = Dataset.load(tmp_path / "d.npz")
    np.testing.assert_array_equal(back.large, small_set.large)
    np.testing.assert_array_equal(back.per_clip, small_set.per_clip)
    np.testing.assert_array_equal(back.fast_per_clip, small_set.fast_per_clip)
    assert back.meta == small_set.meta
    with pytest.raises(FileFormatError):
        np.savez(tmp_path / "other.npz", meta=np.array('{"format": "x"}'))
        Dataset.load(tmp_path / "other.npz")


def test_a_resumed_run_labels_against_the_clips_as_they_are_now(tmp_path):
    """Chunks kept by an interrupted run are read back only for the same clips and base motion: a clip
    edited under the same name, or a clip added, is labelled anew, and the result is what a fresh run
    gives (before, the old chunks were taken as they were, labelled against the old clips, and the
    in-process library cache kept the old clips too)."""
    from kinodyn.io import save

    folder, base, resume = tmp_path / "clips", tmp_path / "walk.bvh", tmp_path / "chunks"
    folder.mkdir()
    save(base, data.load("walk"))
    for name in ("fall_forward", "step_back_small"):
        save(folder / f"{name}.bvh", data.load(name))

    def run(**kw):
        return generate(4, seed=3, base=str(base), library=folder, workers=1, chunk_size=2, show_progress=False,
                        **kw)

    first = run(resume_dir=resume)
    save(folder / "fall_forward.bvh", data.load("fall_side"))  # another reaction under the same name
    edited = run(resume_dir=resume)
    fresh = run()
    ok = fresh.valid()
    assert not np.array_equal(edited.per_clip[ok, 0], first.per_clip[ok, 0]), "the edited clip is searched"
    np.testing.assert_array_equal(edited.per_clip, fresh.per_clip)
    np.testing.assert_array_equal(edited.per_clip[:, 1], first.per_clip[:, 1])  # same simulation, same clip
    save(folder / "step_forward_small.bvh", data.load("step_forward_small"))
    more = run(resume_dir=resume)
    assert more.per_clip.shape == (4, 3) and tuple(more.meta["clips"])[-1] == "step_forward_small"


def test_dataset_is_the_same_from_the_ray_backend(small_set):
    ray = pytest.importorskip("ray")
    try:
        remote = generate(6, seed=3, workers=2, chunk_size=3, backend="ray", show_progress=False)
    finally:
        ray.shutdown()
    for k in ("large", "small", "clip", "sim_frame", "clip_frame", "error", "per_clip", "fast_per_clip", "ball"):
        np.testing.assert_array_equal(getattr(small_set, k), getattr(remote, k), err_msg=k)


def test_saved_model_reloads_and_predicts_identically(rng, lib, tmp_path):
    x, y = _blobs(rng)
    model = train(x, y, "small", lib, folds=3)
    assert model.info["cv_accuracy"] > 0.9
    model.save(tmp_path / "m")
    back = ReactionModel.load(tmp_path / "m", lib)
    xt, _ = _blobs(np.random.default_rng(9))
    np.testing.assert_array_equal(back.predict_features(xt), model.predict_features(xt))
    np.testing.assert_allclose(back.probabilities(xt), model.probabilities(xt), atol=1e-12)
    assert back.probabilities(xt).shape == (len(xt), len(lib))


def test_a_model_for_another_library_is_rejected(rng, lib, tmp_path):
    x, y = _blobs(rng)
    train(x, y, "small", lib).save(tmp_path / "m")
    other = from_motions([data.load("flinch_front"), data.load("steps_back")])
    with pytest.raises(ParameterError, match="another reaction library"):
        ReactionModel.load(tmp_path / "m", other)
    (tmp_path / "m" / "model.json").write_text("{}")
    with pytest.raises(FileFormatError):
        ReactionModel.load(tmp_path / "m")


def test_training_rejects_bad_input(lib):
    with pytest.raises(ParameterError):
        train(np.zeros((4, 3)), np.array([0, 1, 0, 99]), "small", lib)
    with pytest.raises(ParameterError):
        train(np.full((4, 3), np.nan), np.array([0, 1, 0, 1]), "small", lib)
    with pytest.raises(ParameterError):
        features((), "large")
    with pytest.raises(ParameterError):
        features((None, None, None), "medium")


@pytest.mark.parametrize("kind", ["large", "small"])
def test_shipped_models_are_for_the_builtin_library(kind, lib, small_set):
    """The default models ship with the package: trained for the built-in library (rolls included) on at
    least 5,500 throws, the command that reproduces them in their JSON, reloaded without pickle, under 14 MB
    (the large set's 198 values per support vector)."""
    model = ReactionModel.load(DEFAULT_MODEL / kind, lib)
    assert model.kind == kind and model.clips == lib.names
    assert model.info["cases"] >= 5500
    assert model.info["command"].startswith("kinodyn response train ") and f"--kind {kind}" in model.info["command"]
    assert 0.0 < model.info["cv_accuracy"] <= model.info["cv_choice_d_within_10pct"] <= 1.0
    assert (DEFAULT_MODEL / kind / "model.skops").stat().st_size < 14e6
    ok = small_set.valid()
    k = model.predict_features(getattr(small_set, kind)[ok])
    assert np.all((k >= 0) & (k < len(lib)))
    p = model.probabilities(getattr(small_set, kind)[ok])
    np.testing.assert_allclose(p.sum(axis=1), 1.0, atol=1e-9)
    np.testing.assert_array_equal(p.argmax(axis=1), k)


def test_a_model_chooses_through_its_compiled_selector(lib, monkeypatch):
    """``model(states)`` (the pipeline's ``select``) goes through the compiled selector, with scikit-learn's
    choice and probabilities; a pipeline the selector cannot compile falls back to scikit-learn."""
    import copy

    from sklearn.calibration import CalibratedClassifierCV
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVC

    from kinodyn.response.selector import Selector

    calls = []
    compiled = Selector.__call__
    monkeypatch.setattr(Selector, "__call__", lambda self, states: calls.append(1) or compiled(self, states))
    model = ReactionModel.load(DEFAULT_MODEL / "large", lib)
    assert model.selector() is not None and model.selector() is model.selector(), "built once"
    walk = data.load("walk")
    for i in (2, 6):
        obs = observe(walk, ball_for(1000, i))
        want = model.probabilities(features(obs.states, "large")[None])[0]
        k, probs = model(obs.states)
        assert k == int(np.argmax(want)) == model.predict_features(features(obs.states, "large")[None])[0]
        np.testing.assert_allclose(probs, want, rtol=1e-9, atol=1e-12)
    assert len(calls) == 2, "chosen by the compiled selector"
    rng = np.random.default_rng(4)
    x, y = _blobs(rng, dim=198)
    other = copy.copy(model)
    rbf = CalibratedClassifierCV(SVC(kernel="rbf", random_state=0), method="sigmoid", ensemble=False)
    other.pipeline = make_pipeline(StandardScaler(), rbf).fit(x, y)
    assert other.selector() is None
    k, probs = other(obs.states)
    assert k == int(np.argmax(probs)) and probs.shape == (len(lib),)


def test_label_flips_finds_labels_a_faster_ball_changes():
    """A ball 50 % faster changes the exhaustive label of some of the first throws of seed 0 (cases 0 and
    3 of these six); a change of a billionth changes none; a non-positive change is refused."""
    from kinodyn.response.dataset import label_flips

    big = label_flips(0, range(6), relative=0.5)
    assert big.shape == (6,) and 0 < big.sum() < 6
    assert not label_flips(0, range(6), relative=1e-9).any()
    with pytest.raises(ParameterError):
        label_flips(0, [0], relative=0.0)


def test_benchmark_accuracy_splits_into_near_ties_and_decided_throws(lib):
    """``kinodyn bench response`` reports each model's accuracy also on the throws whose runner-up clip is
    within 1 % of the best (near-ties) and on the others; the two parts recombine into the whole."""
    from kinodyn.bench import BenchResult
    from kinodyn.response.bench import _accuracy

    res = BenchResult("response")
    models = {k: ReactionModel.load(DEFAULT_MODEL / k, lib) for k in ("large", "small")}
    _accuracy(models, 8, res)
    m = res.metrics
    f = m["label_near_tie_fraction"]
    assert m["accuracy_cases"] == 8 and 0.0 <= f <= 1.0
    for kind in ("large", "small"):
        parts = [(f, m[f"accuracy_{kind}_near_ties"]), (1.0 - f, m[f"accuracy_{kind}_decided"])]
        whole = sum(w * a for w, a in parts if w > 0)
        assert whole == pytest.approx(m[f"accuracy_{kind}"], abs=1e-12)
