"""The fast path's choice among the classifier's few most probable clips (``ResponseConfig.candidates``)."""

from __future__ import annotations

import numpy as np
import pytest

from kinodyn.data import library as data
from kinodyn.errors import ParameterError
from kinodyn.response import builtin
from kinodyn.response.classifier import ReactionModel
from kinodyn.response.command import DEFAULT_KIND, DEFAULT_MODEL
from kinodyn.response.dataset import ball_for, generate
from kinodyn.response.pipeline import ResponseConfig, fast_choice, ranked, respond

pytest.importorskip("sklearn")
pytest.importorskip("skops")

#: the benchmark's held-out seed (throws no shipped model was trained on)
_SEED = 1000


@pytest.fixture(scope="module")
def lib():
    return builtin()


@pytest.fixture(scope="module")
def model(lib):
    return ReactionModel.load(DEFAULT_MODEL / DEFAULT_KIND, lib)


def test_ranked_puts_the_classifiers_clip_first_then_falling_probability():
    p = np.array([0.1, 0.4, 0.05, 0.4, 0.05])
    np.testing.assert_array_equal(ranked(p, 1, 3), [1, 3, 0])
    np.testing.assert_array_equal(ranked(p, 3, 2), [3, 1])  # the chooser's clip leads even in a tie
    np.testing.assert_array_equal(ranked(p, 1, 9), [1, 3, 0, 2, 4])


def test_candidates_choose_the_lowest_fast_error_among_the_most_probable_clips(lib, model):
    """With three candidates the response times the model's three most probable clips (its own first) and
    plays the one whose timing has the lowest error D; with one it is the paper's pipeline, unchanged."""
    walk = data.load("walk")
    changed = 0
    for i in (0, 1, 9, 18, 24):  # 9, 18 and 24: held-out throws on which the choice changes
        ball = ball_for(_SEED, i)
        one = respond(walk, lib, ball, model)
        three = respond(walk, lib, ball, model, ResponseConfig(candidates=3))
        p = three.probabilities
        clips = [c for c, _ in three.candidates]
        assert clips[0] == one.clip_index == int(np.argmax(p))
        assert set(clips) == set(np.argsort(-p)[:3].tolist())
        errors = dict(three.candidates)
        assert three.clip_index == min(clips, key=errors.get) and three.error == errors[three.clip_index]
        assert errors[one.clip_index] == pytest.approx(one.error, rel=1e-12)
        assert three.error <= one.error
        assert len(one.candidates) == 1 and one.candidates[0][0] == one.clip_index
        changed += three.clip_index != one.clip_index
        if three.clip_index == one.clip_index:
            np.testing.assert_array_equal(three.motion.root_pos, one.motion.root_pos)
    assert changed >= 1, "no throw changed its clip: the candidates are not compared"


def test_the_benchmarks_choice_among_candidates_is_the_pipelines(lib, model):
    """``kinodyn bench response`` scores the choice among candidates from every clip's fast-alignment
    error (the dataset's, and the finer alignment's); on each throw it is the clip the pipeline itself
    plays with that alignment, at the same error D."""
    from kinodyn.response.bench import FINE, fine_errors_chunk, top_choices

    ds = generate(4, seed=_SEED, workers=1, show_progress=False)
    ok = np.nonzero(ds.valid())[0]
    x = getattr(ds, DEFAULT_KIND)[ok]
    sel = model.selector()
    probs, first = sel.probabilities(x), sel.predict_features(x)
    fine = fine_errors_chunk([(_SEED, int(i)) for i in ok])["fast"]
    walk = data.load("walk")
    for errors, align in ((ds.fast_per_clip[ok], ResponseConfig().align), (fine, FINE)):
        for i, pick in zip(ok, top_choices(probs, first, errors, 2)):
            r = respond(walk, lib, ball_for(_SEED, int(i)), model, ResponseConfig(candidates=2, align=align))
            assert r.clip_index == pick
            assert r.error == pytest.approx(errors[list(ok).index(i), pick], rel=1e-12)


def test_candidates_are_a_whole_number_and_need_probabilities(lib, model):
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(ParameterError, match="candidates"):
            ResponseConfig(candidates=bad)
    from kinodyn.response.search import body_tracks

    walk = data.load("walk")
    track = body_tracks(walk[:60])
    with pytest.raises(ParameterError, match="probabilities"):
        fast_choice(track, lib, lambda _: (0, None), None, ResponseConfig(candidates=2))
    k, a, probs, timed = fast_choice(track, lib, lambda _: (4, None), None)
    assert k == 4 and probs is None and timed == ((4, a.error),)
