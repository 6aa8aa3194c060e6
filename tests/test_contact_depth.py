"""Global penetration depth (equation 1), Algorithm 1's fallback (figure 4b), broad and narrow phase."""

import numpy as np
import pytest

from kinodyn.contact import meshes
from kinodyn.contact import setting as S
from kinodyn.contact.collide import CollisionWorld, brute_force_pairs, sweep_and_prune
from kinodyn.contact.depth import global_depth, pair_depths
from kinodyn.contact.overlap import remove_overlap

EXACT = 1e-6  # MuJoCo's convex collision on primitives
COACD = 3e-4  # CoACD's cut planes on a 1 m bracket (resolution 5000, pieces snapped onto the mesh)
L_POLY = [[0, 0], [1, 0], [1, 0.2], [0.2, 0.2], [0.2, 1], [0, 1]]


@pytest.fixture(scope="module")
def bracket():
    v, f = meshes.prism(L_POLY, 1.0)
    return S.SceneObject("L", "fixed", "wood", tuple(meshes.mesh_pieces(v, f, name="L")))


def _driven(shape, pos, name="a"):
    return S.SceneObject(name, "driven", "wood", (shape,), pos=pos)


def test_two_overlapping_boxes_global_depth_is_the_overlap():
    a = _driven(S.box([0.2, 0.2, 0.2]), [0.05, 0.02, 0.35])
    b = S.SceneObject("b", "fixed", "wood", (S.box([0.5, 0.5, 0.2]),))
    w = CollisionWorld([a, b])
    g = pair_depths(w.contacts(first=np.array([True, False])))[(0, 1)]
    np.testing.assert_allclose(g.vector, [0, 0, 0.05], atol=EXACT)
    # rotated about z: still 5 cm along z
    w.set_poses([0], [0.05, 0.02, 0.35], [np.cos(0.3), 0, 0, np.sin(0.3)])
    g = pair_depths(w.contacts(first=np.array([True, False])))[(0, 1)]
    np.testing.assert_allclose(g.vector, [0, 0, 0.05], atol=EXACT)


def test_sphere_on_one_arm_of_an_l_mesh_has_the_analytic_depth(bracket):
    ball = _driven(S.sphere(0.1), [0.6, 0.0, 0.25])  # 5 cm into the horizontal arm's top
    w = CollisionWorld([bracket, ball])
    g = pair_depths(w.contacts(first=np.array([False, True])))[(1, 0)]
    np.testing.assert_allclose(g.vector, [0, 0, 0.05], atol=COACD)
    w.set_poses([1], [0.27, 0.0, 0.7], [1, 0, 0, 0])  # 3 cm into the vertical arm's inner face
    g = pair_depths(w.contacts(first=np.array([False, True])))[(1, 0)]
    np.testing.assert_allclose(g.vector, [0.03, 0, 0], atol=COACD)


def test_sphere_in_the_l_corner_equation_1_then_iterated_removal(bracket):
    """In the inner corner the sphere overlaps both arms: equation 1 weights the two normals by their
    squared depths, and iterating the translation ends at the analytic exit (d2, 0, d1)."""
    d1, d2 = 0.04, 0.02  # into the top of the horizontal arm (z), into the vertical arm's face (x)
    ball = _driven(S.sphere(0.1), [0.2 + 0.1 - d2, 0.0, 0.2 + 0.1 - d1])
    w = CollisionWorld([bracket, ball])
    g = pair_depths(w.contacts(first=np.array([False, True])))[(1, 0)]
    expect = (d1 ** 2 * np.array([0, 0, 1.0]) + d2 ** 2 * np.array([1.0, 0, 0])) / (d1 + d2)
    np.testing.assert_allclose(g.vector, expect, atol=5 * COACD)
    start = w.pos[1].copy()
    r = remove_overlap(w, [1], start[None])
    np.testing.assert_allclose(w.pos[1] - start, [d2, 0, d1], atol=1e-3)
    assert r.residual <= 1e-4 and not r.fallback


def test_figure_4b_cancelling_normals_fall_back_without_a_jump():
    """A block lowered into a slot narrower than itself: the two walls push it sideways by equal and
    opposite amounts, equation 1 cancels, and Algorithm 1 moves it back along its path instead."""
    slot = S.SceneObject("slot", "fixed", "wood", (S.box([0.1, 0.5, 0.5], pos=[-0.2, 0, 0]),
                                                  S.box([0.1, 0.5, 0.5], pos=[0.2, 0, 0])))
    block = _driven(S.box([0.12, 0.1, 0.1]), [0.0, 0.0, 0.8])
    w = CollisionWorld([slot, block])
    free = w.pos[1].copy()
    heights, used, cancels = [], [], []
    for z in np.linspace(0.8, 0.4, 21):  # 2 cm per frame, from above the slot into it
        w.set_poses([1], [0.0, 0.0, z], [1, 0, 0, 0])
        c = w.contacts(first=np.array([False, True]))
        cancels.append(len(c) > 0 and global_depth(c.depth, c.normal).cancelling)
        r = remove_overlap(w, [1], free[None])
        used.append(bool(r.fallback))
        assert r.residual <= 1e-4
        heights.append(w.pos[1, 2])
        free = w.pos[1].copy()
    h = np.array(heights)
    assert any(cancels) and used == cancels  # the fallback runs exactly where the normals cancel
    assert np.all(np.abs(np.diff(h)) <= 0.02 + 1e-4)  # no jump: never more than the input's step
    assert np.all(h >= 0.6 - 2e-4)  # and never sunk into the slot
    np.testing.assert_allclose(h[-1], 0.5 + 0.1, atol=2e-3)  # rests on the slot's top edge
    np.testing.assert_allclose(w.pos[1, :2], [0, 0], atol=1e-9)  # no sideways push


def test_sweep_and_prune_finds_the_brute_force_pairs():
    rng = np.random.default_rng(3)
    for _ in range(20):
        lo = rng.uniform(0, 5, (60, 3))
        hi = lo + rng.uniform(0.01, 1.0, (60, 3))
        a = {tuple(p) for p in sweep_and_prune(lo, hi).tolist()}
        b = {tuple(p) for p in brute_force_pairs(lo, hi).tolist()}
        assert a == b


def test_contact_normal_points_out_of_b_into_a():
    a = _driven(S.capsule(0.05, 0.2), [0.0, 0.0, 0.23], "cap")
    b = S.SceneObject("floor", "fixed", "wood", (S.box([1, 1, 0.05], pos=[0, 0, -0.05]),))
    w = CollisionWorld([a, b])
    c = w.contacts(first=np.array([True, False]))
    assert c.object_a.tolist() == [0]
    np.testing.assert_allclose(c.normal[0], [0, 0, 1], atol=EXACT)
    np.testing.assert_allclose(c.depth[0], 0.02, atol=EXACT)
