"""The impact experiment of section 6 and the automatic observer."""

import numpy as np
import pytest

from kinodyn.crowd.body import BodyConfig
from kinodyn.crowd.controller import FALLING
from kinodyn.crowd.impacts import (
    ImpactConfig,
    evaluate_observer,
    experiment,
    features,
    force_geometry,
    run_impacts,
)
from kinodyn.crowd.keyframes import builtin_keyframes
from kinodyn.errors import ParameterError


def test_experiment_has_all_54_combinations():
    lab = experiment()
    assert lab.shape == (54, 4)
    assert len({tuple(r) for r in lab}) == 54


def test_force_geometry_of_figure_9():
    body = BodyConfig()
    p, d = force_geometry(body, np.radians([0.0, 45.0, 0.0]), np.radians([0.0, 0.0, 45.0]), [1.0, 0.5, 0.0])
    # at the front, pointing backward; points lie on the ellipsoid surface
    np.testing.assert_allclose(d[0], [-1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(np.degrees(np.arctan2(d[1, 1], d[1, 0])), -135.0, atol=1e-9)
    np.testing.assert_allclose(np.degrees(np.arctan2(d[2, 1], d[2, 0])), -135.0, atol=1e-9)
    c = (p - body.shape_offset) / body.semi_axes
    np.testing.assert_allclose(np.sum(c ** 2, axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(p[:, 2] + body.l, [1.0, 0.5, 0.0], atol=1e-12)


@pytest.fixture(scope="module")
def reactions():
    return run_impacts(experiment(), seed=3)


def test_strong_forces_make_more_falls(reactions):
    fell = np.any(reactions.modes == FALLING, axis=1)
    strong = reactions.labels[:, 3] == 1
    assert fell[strong].mean() > 0.3 and fell[~strong].mean() == 0.0


def test_reactions_move_in_the_force_direction(reactions):
    from kinodyn.math import quat

    lab = reactions.labels
    head = quat.heading(reactions.local_rot[:, 0, 0].astype(float), forward=[1.0, 0.0, 0.0])
    move = reactions.root_pos[:, 60, :2] - reactions.root_pos[:, 0, :2]
    local = quat.mul_vec(quat.from_heading(-head), np.concatenate([move, np.zeros((54, 1))], axis=1))
    front = (lab[:, 0] == 1) & (lab[:, 1] == 1) & (lab[:, 2] == 2)  # from the front, straight, high
    assert np.all(local[front, 0] < -0.1), "pushed from the front it goes backward"


def test_same_seed_same_reactions():
    lab = experiment()[:6]
    a, b = run_impacts(lab, seed=5), run_impacts(lab, seed=5)
    np.testing.assert_array_equal(a.root_pos, b.root_pos)


def test_observer_beats_chance_on_other_seeds(reactions):
    sk = builtin_keyframes().skeleton
    lab = experiment()
    train = [run_impacts(lab, seed=s) for s in (11, 12)]
    table = evaluate_observer(train, [reactions], sk)
    assert table["strength"]["accuracy"] > 0.75
    assert table["dir"]["accuracy"] > 0.4  # chance is 0.2 or less
    assert set(table["pos"]) >= {"accuracy", "mu", "sigma", "paper_accuracy"}
    assert features(reactions, sk).shape[0] == 54


def test_bad_impact_config():
    with pytest.raises(ParameterError, match="0 < weak < strong"):
        ImpactConfig(weak=200.0, strong=100.0)
