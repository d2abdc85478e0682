"""The fast paths of StateSpaceTDS's certified roots: the bounds of the expanded determinant, the
reduced collocation of the generator, the chain seeds left out left of the region.

Oracles: the expansion's own :class:`~nrobust.quasipoly.QuasiPolynomial` (``Q.poly``, whose values
and derivatives are computed by independent code) sampled densely on each segment; the full
collocation pencil built here with ``np.kron`` and solved by the QZ algorithm of scipy; the zero
chains of the principal part from :meth:`~nrobust.difference.DifferenceOperator.chains`; and the
roots found on the matrix form of ``det M`` (Hadamard's bounds, no expansion).
"""

from __future__ import annotations

import numpy as np
import pytest
from _statespace_examples import example_2_9
from scipy.linalg import eig

from nrobust import DifferenceOperator, find_roots
from nrobust.lti.statespace import _MIN_POINTS, _POINTS_PER_FREQUENCY, StateSpaceTDS, _chebyshev, _interpolation_row
from nrobust.qpmatrix import ExpandedDeterminant
from nrobust.roots._common import Budget, check_function
from nrobust.roots.search import Finder, _zeros_left_of


def _michiels_13() -> StateSpaceTDS:
    """Michiels (2011) Example 13 with a = 0.75 (descriptor, n = 2; only the second state is delayed)."""
    a = [[[0.0, -0.125], [-1.0, 1.0]], [[0.0, 0.0], [0.0, -0.75]], [[0.0, 0.0], [0.0, 0.5]]]
    return StateSpaceTDS(a, [0.0, 1.0, 2.0], E=[[1.0, 0.0], [0.0, 0.0]])


def _retarded_2x2() -> StateSpaceTDS:
    return StateSpaceTDS([[[-1.0, 0.5], [0.3, -2.0]], [[-0.8, 0.2], [0.1, -0.5]]], [0.0, 1.0])


def _expanded(sys: StateSpaceTDS) -> ExpandedDeterminant:
    Q = sys.characteristic_matrix().exact_expansion()
    assert Q is not None
    return Q


@pytest.mark.parametrize("make", [example_2_9, _retarded_2x2])
def test_derivative_bounds_hold_and_are_tight(make: object) -> None:
    """On segments from 1e-3 to 4 long, the bounds of |Q'| and |Q''| exceed the largest of 400 samples
    of Q.poly's derivatives; on the short ones (the steps near roots) they are within a factor 3 of it."""
    Q = _expanded(make())  # type: ignore[operator]
    rng = np.random.default_rng(3)
    a = rng.uniform(-3, 1, 60) + 1j * rng.uniform(-15, 15, 60)
    length = np.repeat([1e-3, 1e-2, 0.1, 1.0, 4.0], 12)
    b = a + length * np.exp(1j * rng.uniform(0, 2 * np.pi, 60))
    t = np.linspace(0.0, 1.0, 400)
    pts = a[:, None] + (b - a)[:, None] * t
    d1 = np.abs(Q.poly.deriv_at(pts)).max(axis=1)
    d2 = np.abs(Q.poly.derivative().deriv_at(pts)).max(axis=1)
    bound1, bound2 = Q.deriv_bound(a, b), Q.derivative().deriv_bound(a, b)
    assert np.all(bound1 >= d1) and np.all(bound2 >= d2)
    short = length <= 1e-2
    assert np.all(bound1[short] <= 3.0 * d1[short]) and np.all(bound2[short] <= 3.0 * d2[short])
    # the values are those of the expansion (rounding of sums of a few dozen terms)
    s = a[:5]
    np.testing.assert_allclose(Q(s), Q.poly(s), rtol=1e-12)
    np.testing.assert_allclose(Q.deriv_at(s), Q.poly.deriv_at(s), rtol=1e-12)
    # the counter is proposed more first steps on longer segments, one on a short one
    assert list(Q.initial_steps(np.array([0j, 0j]), np.array([1e-4j, 20j]))) == [
        1,
        int(np.ceil(20 * (1 + Q.poly.max_delay))),
    ]


def _full_pencil(sys: StateSpaceTDS, im_max: float) -> np.ndarray:
    """Finite eigenvalues of the collocated generator with every component's history (no neutral term)."""
    n, tau = sys.n, float(np.max(sys.hA))
    points = int(np.clip(_POINTS_PER_FREQUENCY * im_max * tau + _MIN_POINTS, 4, 480 // n - 1))
    theta, d = _chebyshev(points, tau)
    a = np.kron(d, np.eye(n))
    b = np.eye(n * (points + 1))
    a[:n] = sum(np.kron(_interpolation_row(theta, -h), m) for m, h in zip(sys.A, sys.hA))
    b[:n] = np.kron(_interpolation_row(theta, 0.0), sys.E)
    vals = eig(a, b, right=False)
    return vals[np.isfinite(vals)]


@pytest.mark.parametrize("make", [example_2_9, _michiels_13])
def test_reduced_generator_matches_the_full_pencil(make: object) -> None:
    """The reduced problem (delayed components only, algebraic rows eliminated) has eigenvalues of the
    full pencil (QZ), up to the rounding of a pencil with a singular E (1e-8 relative), and fewer
    spurious ones; it approximates each certified root of the region to 1e-4 (the collocation error
    of N = 0.3 tau |Im s| + 12 points at |Im s| <= 10: 2e-6 measured; Newton's basins are wider)."""
    sys = make()  # type: ignore[operator]
    ours = sys.generator_eigenvalues(10.0)
    full = _full_pencil(sys, 10.0)
    assert 0 < ours.size < full.size
    gap = np.array([np.min(np.abs(full - z)) / (1.0 + abs(z)) for z in ours])
    assert np.all(gap < 1e-8)
    roots = sys.roots((-1.0, 0.5, -10.0, 10.0)).roots
    assert roots.size > 0
    np.testing.assert_allclose([np.min(np.abs(ours - z)) for z in roots], 0.0, atol=1e-4)


def test_chains_left_of_the_region_give_no_seeds() -> None:
    """Example 2.9's principal part 1 + 0.0326 e^{-s} has its chain at Re s = ln 0.0326 = -3.42: left of
    the box [-1.75, 1.25] in which Newton's method keeps a seed of the region [-1, 0.5], so no chain
    seed is computed; the neutral 2 x 2 system's chains cross its region and seed it."""
    Q = _expanded(example_2_9())
    D = Q.principal_part()
    assert np.max(D.chains().points(-11.0, 11.0).real) < -1.75 - 1.0
    assert Finder(check_function(Q), (-1.0, 0.5, -10.0, 10.0), 1e-6, Budget(1000)).chain_seeds().size == 0
    neutral = StateSpaceTDS(
        [[[-1.0, 0.5], [0.3, -2.0]], [[-0.8, 0.2], [0.1, -0.5]]], [0.0, 1.0], B=[[[-0.3, -0.1], [0.0, 0.4]]], hB=[0.5]
    )
    region = (-3.0, 1.0, -30.0, 30.0)
    seeds = Finder(check_function(_expanded(neutral)), region, 1e-6, Budget(1000)).chain_seeds()
    assert seeds.size > 0


@pytest.mark.parametrize(
    ("coefs", "delays"),
    [([1.0, 0.0326], [0.0, 1.0]), ([1.0, -0.85, 0.1], [0.0, 2.0, 3.0]), ([2.0, 1.5, -1.0], [1.0, 2.0, 3.0])],
)
def test_abscissa_right_of_every_zero(coefs: list[float], delays: list[float]) -> None:
    """Every zero of a commensurate D (its chains) lies left of ``_zeros_left_of(D)``."""
    D = DifferenceOperator(coefs, delays)
    bound = _zeros_left_of(D)
    real_parts = [c.real for c in D.chains().chains]
    assert max(real_parts) <= bound


@pytest.mark.parametrize("make", [_retarded_2x2, example_2_9])
def test_roots_as_on_the_matrix(make: object) -> None:
    """The roots counted on the expansion equal those found on the matrix form (Hadamard's bounds)."""
    sys = make()  # type: ignore[operator]
    region = (-1.0, 0.5, -10.0, 10.0)
    ours = sys.roots(region)
    theirs = find_roots(sys.characteristic_matrix(), region)
    assert ours.certified and theirs.certified and ours.count == theirs.count
    np.testing.assert_allclose(ours.roots, theirs.roots, atol=1e-10)
