"""The Chebyshev neighbour search of the root finder against scipy's cKDTree and csgraph.

:mod:`nrobust.roots._neighbours` replaces ``scipy.spatial.cKDTree`` (``p = inf``) and
``scipy.sparse.csgraph.connected_components`` in the root search; scipy is the independent
oracle here. The distances must be the same floats (both compute ``max(|dx|, |dy|)`` in
float64, so the comparison is exact); an index may differ from the tree's only between
points at exactly the same distance, and then it is the lowest such index.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.sparse import coo_array
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from nrobust.errors import ParameterError
from nrobust.roots._neighbours import ChebyshevIndex, connected_groups


def _point_sets() -> list[np.ndarray]:
    """Random clouds, a vertical chain (the roots of a neutral loop), exact ties (a lattice whose
    spacing is the radius searched) and clusters."""
    rng = np.random.default_rng(20261128)
    cloud = rng.normal(size=(300, 2))
    chain = np.column_stack([-0.3 + 1e-9 * rng.normal(size=200), np.arange(200) * 2 * np.pi / 1.7])
    lattice = np.array([(i, j) for i in range(12) for j in range(12)], dtype=float) * 0.25  # many exact ties
    clusters = np.concatenate([c + 1e-7 * rng.normal(size=(25, 2)) for c in rng.uniform(-5, 5, size=(8, 2))])
    repeated = np.repeat(rng.uniform(size=(20, 2)), 3, axis=0)  # coincident points
    small = rng.uniform(size=(2, 2))
    return [cloud, chain, lattice, clusters, repeated, small]


def _check_query(points: np.ndarray, x: np.ndarray, k: int) -> None:
    tree_d, tree_i = cKDTree(points).query(x, k=k, p=np.inf)
    ours_d, ours_i = ChebyshevIndex(points).query(x, k=k, p=np.inf)
    assert ours_d.shape == tree_d.shape and ours_i.shape == tree_i.shape
    np.testing.assert_array_equal(ours_d, tree_d)  # the same floats
    d2, i2, t2 = ours_d.reshape(len(x), k), ours_i.reshape(len(x), k), tree_i.reshape(len(x), k)
    # each index at its distance, the lowest first among equal distances
    direct = np.max(np.abs(x[:, None, :] - points[i2]), axis=2)
    np.testing.assert_array_equal(direct, d2)
    same_d = d2[:, 1:] == d2[:, :-1]
    assert np.all(i2[:, 1:][same_d] > i2[:, :-1][same_d])
    # where the k-th distance is not tied beyond the k returned, the sets of neighbours agree
    full = np.max(np.abs(x[:, None, :] - points[None, :, :]), axis=2)
    untied = np.sum(full <= d2[:, -1:], axis=1) == k
    for row in np.flatnonzero(untied):
        assert set(i2[row]) == set(t2[row])


@pytest.mark.parametrize("which", range(6))
def test_query_matches_ckdtree(which: int) -> None:
    points = _point_sets()[which]
    rng = np.random.default_rng(which)
    for x in (points, points[::3] + 1e-3 * rng.normal(size=points[::3].shape), rng.normal(size=(40, 2)) * 3):
        for k in sorted({1, 2, min(8, len(points)), min(16, len(points))}):
            _check_query(points, x, k)


@pytest.mark.parametrize("which", range(6))
def test_pairs_and_groups_match_scipy(which: int) -> None:
    points = _point_sets()[which]
    tree = cKDTree(points)
    ours = ChebyshevIndex(points)
    scale = float(np.ptp(points)) or 1.0
    for r, p in itertools.product((0.0, 1e-8 * scale, 1e-3 * scale, 0.25, 0.05 * scale), (2.0, np.inf)):
        pairs = ours.query_pairs(r, p=p, output_type="ndarray")
        expected = tree.query_pairs(r, p=p, output_type="ndarray")
        assert {tuple(p) for p in pairs.tolist()} == {tuple(p) for p in expected.tolist()}
        assert len(pairs) == len(expected)
        assert ours.query_pairs(r, p=p) == tree.query_pairs(r, p=p)
        n = len(points)
        if len(expected):
            graph = coo_array((np.ones(len(expected)), (expected[:, 0], expected[:, 1])), shape=(n, n))
            labels = connected_components(graph, directed=False)[1]
        else:
            labels = np.arange(n)
        np.testing.assert_array_equal(connected_groups(n, pairs), labels)


def test_groups_of_a_long_path_and_a_shuffled_graph() -> None:
    n = 500
    rng = np.random.default_rng(7)
    perm = rng.permutation(n)
    path = np.column_stack([perm[:-1], perm[1:]])  # one group, linked in random order
    np.testing.assert_array_equal(connected_groups(n, path), np.zeros(n, dtype=np.intp))
    links = rng.integers(0, n, size=(300, 2))
    graph = coo_array((np.ones(300), (links[:, 0], links[:, 1])), shape=(n, n))
    np.testing.assert_array_equal(connected_groups(n, links), connected_components(graph, directed=False)[1])


def test_bad_arguments_are_refused() -> None:
    index = ChebyshevIndex(np.zeros((3, 2)))
    with pytest.raises(ParameterError, match="k"):
        index.query(np.zeros((1, 2)), k=4)
    with pytest.raises(ParameterError, match="p"):
        index.query(np.zeros((1, 2)), k=1, p=2)
    with pytest.raises(ParameterError, match="p"):
        index.query_pairs(0.1, p=1)
    with pytest.raises(ParameterError, match="points"):
        ChebyshevIndex(np.array([[0.0, np.nan]]))
