"""The short paths of StateSpaceTDS.roots: det M expanded from the coefficient array, counts kept per box,
descriptor matrices of full numerical rank, and roots left unpolished once Newton's method has settled them.

Oracles: the expansion through the matrix of quasi-polynomials (QuasiPolynomialMatrix.exact_expansion, the
other path), mpmath at 40 digits on det(s E - A_0 - A_1 e^{-s}) written here, and the Lambert W closed form
of the root of s + 1 - e^{-s} / 2.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import mpmath
import numpy as np
import pytest
from _statespace_examples import example_2_9

from nrobust.errors import ParameterError
from nrobust.lti.statespace import StateSpaceTDS
from nrobust.qpmatrix import ExpandedDeterminant, QuasiPolynomialMatrix
from nrobust.quasipoly import QuasiPolynomial
from nrobust.roots._common import Budget
from nrobust.roots.winding import Counter, count_roots

A0 = np.array([[-1.0, 0.5], [0.3, -2.0]])
A1 = np.array([[-0.8, 0.2], [0.1, -0.5]])
H = np.array([[0.3, 0.1], [0.0, -0.4]])


def _coefficients(E: np.ndarray, A: list[np.ndarray], B: list[np.ndarray]) -> np.ndarray:
    """``M_ij(s) = sum_k (c_k0 + c_k1 s) e^{-h_k s}`` for delays ``0, 1, 0.5`` (E, A_0 at 0; A_1 at 1; B at 0.5)."""
    n = E.shape[0]
    c = np.zeros((n, n, 3, 2))
    c[:, :, 0, 1], c[:, :, 0, 0], c[:, :, 1, 0] = E, -A[0], -A[1]
    if B:
        c[:, :, 2, 1] = -B[0]
    return c


@pytest.mark.parametrize("neutral", [False, True])
def test_expansion_from_coefficients_is_that_of_the_matrix(neutral: bool) -> None:
    c = _coefficients(np.eye(2), [A0, A1], [H] if neutral else [])
    delays = np.array([0.0, 1.0, 0.5])
    fast = ExpandedDeterminant.from_coefficients(c, delays)
    slow = QuasiPolynomialMatrix(QuasiPolynomial.from_coefficient_array(c, delays)).exact_expansion()
    assert fast is not None and slow is not None
    assert fast.poly == slow.poly  # the same rational expansion, rounded once
    assert fast.kind == slow.kind == ("neutral" if neutral else "retarded")
    assert fast.max_delay == slow.max_delay == 1.0
    if neutral:
        np.testing.assert_array_equal(fast.principal_part().coefs, slow.principal_part().coefs)
        np.testing.assert_array_equal(fast.principal_part().delays, slow.principal_part().delays)
    a = np.array([0.5 + 1.0j, -2.0 + 7.0j, 1.0 - 3.0j])
    b = a + np.array([0.25, 0.1j, 0.3 + 0.2j])
    np.testing.assert_array_equal(fast.gap(a, b), slow.gap(a, b))
    np.testing.assert_array_equal(fast.deriv_bound(a, b), slow.deriv_bound(a, b))
    np.testing.assert_array_equal(fast(a), slow(a))
    assert fast.matrix == slow.matrix  # built on first use


def test_descriptor_expansion_and_its_principal_part() -> None:
    sys = example_2_9()
    expanded = sys.characteristic_matrix().exact_expansion()
    n = sys.n
    c = np.zeros((n, n, 2, 2))
    c[:, :, 0, 1], c[:, :, 0, 0], c[:, :, 1, 0] = sys.E, -sys.A[0], -sys.A[1]
    fast = ExpandedDeterminant.from_coefficients(c, [0.0, 1.0])
    assert fast is not None and expanded is not None
    assert fast.poly == expanded.poly
    assert fast.kind == expanded.kind == "neutral"
    np.testing.assert_array_equal(fast.principal_part().coefs, expanded.principal_part().coefs)


def test_from_coefficients_refuses_bad_arrays() -> None:
    with pytest.raises(ParameterError, match="delays"):
        ExpandedDeterminant.from_coefficients(np.ones((2, 2, 2, 1)), [1.0, 1.0])  # equal delays
    with pytest.raises(ParameterError, match="delays"):
        ExpandedDeterminant.from_coefficients(np.ones((2, 2, 2, 1)), [0.0, -1.0])
    with pytest.raises(ParameterError, match="coefs"):
        ExpandedDeterminant.from_coefficients(np.ones((2, 3, 1, 1)), [0.0])  # not square
    with pytest.raises(ParameterError, match="coefs"):
        ExpandedDeterminant.from_coefficients(np.ones((9, 9, 1, 1)), [0.0])  # above 8 x 8
    with pytest.raises(ParameterError, match="coefs"):
        ExpandedDeterminant.from_coefficients(np.ones((2, 2, 1)), [0.0])


def test_equal_delays_are_summed_as_in_the_matrix() -> None:
    half = np.array([[-0.3, 0.1], [0.05, -0.2]])
    split = StateSpaceTDS([A0, half, A1 - half], [0.0, 1.0, 1.0])
    c = np.zeros((2, 2, 3, 2))
    c[:, :, 0, 1], c[:, :, 0, 0], c[:, :, 1, 0], c[:, :, 2, 0] = np.eye(2), -A0, -half, -(A1 - half)
    assert split.characteristic_matrix() == QuasiPolynomialMatrix(
        QuasiPolynomial.from_coefficient_array(c, [0.0, 1.0, 1.0])
    )
    found = split.roots((-3.0, 1.0, -20.0, 20.0))
    # the count of the expansion is that of the matrix (its bounds by Hadamard's inequality, no expansion)
    assert found.certified and found.count == count_roots(split.characteristic_matrix(), found.region)


def _mp_det(E: np.ndarray, A: list[np.ndarray], hA: list[float]) -> Callable[[Any], Any]:
    """``s -> det(s E - sum_k A_k e^{-hA_k s})`` in mpmath."""

    def det(s: Any) -> Any:
        m = mpmath.matrix(E.tolist()) * s
        for a, h in zip(A, hA):
            m -= mpmath.matrix(a.tolist()) * mpmath.exp(-h * s)
        return mpmath.det(m)

    return det


def _assert_roots_of(det: Callable[[Any], Any], roots: np.ndarray, radii: np.ndarray, rtol: float) -> None:
    """Each root within its radius of a root of ``det`` found by mpmath at 40 digits, and within ``rtol``."""
    with mpmath.workdps(40):
        for z, r in zip(roots, radii):
            exact = complex(mpmath.findroot(det, mpmath.mpc(z.real, z.imag)))
            assert abs(exact - z) <= r
            np.testing.assert_allclose(z, exact, rtol=rtol, atol=0.0)


def test_ill_conditioned_descriptor_of_full_rank() -> None:
    # E of condition 1e10: singular values above rounding, so no algebraic equation to eliminate;
    # the collocated pencil goes to its shift-and-invert reduction
    E = np.diag([1.0, 1e-10])
    sys = StateSpaceTDS([A0, A1], [0.0, 1.0], E=E)
    box = (-3.0, 1.0, -20.0, 20.0)
    found = sys.roots(box)
    assert found.certified
    # det(diag(1, 1e10) M) = 1e10 det M: the row-scaled system with E = I has the same roots
    scaled = StateSpaceTDS([np.diag([1.0, 1e10]) @ A0, np.diag([1.0, 1e10]) @ A1], [0.0, 1.0])
    assert found.count == count_roots(scaled.characteristic_matrix(), found.region)
    # 1e-9 relative: det M is ill conditioned (E's small singular value); the radii are the certificate
    _assert_roots_of(_mp_det(E, [A0, A1], [0.0, 1.0]), found.roots, found.radii, 1e-9)


def test_settled_roots_are_as_accurate_as_polished_ones() -> None:
    # Newton's limits accepted as they are: every root of the 2x2 system to 1e-12 (the rounding of det M
    # near |s| = 30 is about 1e-14 of its scale) and every root of Example 2.9
    sys = StateSpaceTDS([A0, A1], [0.0, 1.0])
    found = sys.roots((-3.0, 1.0, -30.0, 30.0))
    assert found.certified and found.count == 10
    _assert_roots_of(_mp_det(np.eye(2), [A0, A1], [0.0, 1.0]), found.roots, found.radii, 1e-12)
    ex = example_2_9()
    found = ex.roots((-1.0, 0.5, -10.0, 10.0))
    assert found.certified and found.count == 4
    # tdcpy's examples/example2_9.py states the abscissa -0.2845
    np.testing.assert_allclose(found.roots.real.max(), -0.2845, atol=5e-5)
    _assert_roots_of(_mp_det(ex.E, list(ex.A), [0.0, 1.0]), found.roots, found.radii, 1e-10)


def test_a_prefetched_box_is_counted_with_the_batch_and_not_again() -> None:
    # s + 1 - e^{-s} / 2 has the real root W(e / 2) - 1 (Lambert W)
    F = QuasiPolynomial([[1.0, 1.0], [-0.5]], [0.0, 1.0])
    with mpmath.workdps(40):
        root = float(mpmath.lambertw(mpmath.e / 2).real - 1)
    box = (root - 1e-3, root + 1e-3, -1e-3, 1e-3)
    region = (-0.5, 1.0, -2.0, 2.0)
    budget = Budget(10**6)
    counter = Counter(F, budget)
    counter.prefetch = [box]
    counts, blocked = counter.count([region])
    used = budget.used
    again, blocked_again = counter.count([box, region])
    assert budget.used == used  # both known: nothing evaluated
    np.testing.assert_array_equal(again, [int(count_roots(F, box)), int(counts[0])])
    assert again[0] == 1 and not blocked.any() and not blocked_again.any()


@pytest.mark.parametrize(
    "system, region, count",
    [
        (example_2_9(), (-1.0, 0.5, -10.0, 10.0), 4),
        (StateSpaceTDS([A0, A1], [0.0, 1.0]), (-3.0, 1.0, -30.0, 30.0), 10),
    ],
)
def test_approximate_roots_spare_the_counter_a_round(
    monkeypatch: pytest.MonkeyPatch, system: StateSpaceTDS, region: tuple[float, ...], count: int
) -> None:
    # Newton's limit points set the first steps of the edges that pass near them: the region and the boxes
    # about the roots are counted in one round of derivative bounds (two when the edges start uniform)
    rounds: list[int] = []
    bounds = ExpandedDeterminant._bounds

    def counted(self: ExpandedDeterminant, a: Any, b: Any, order: int) -> Any:
        rounds.append(order)
        return bounds(self, a, b, order)

    monkeypatch.setattr(ExpandedDeterminant, "_bounds", counted)
    found = system.roots(region)
    assert found.certified and found.count == count
    assert rounds == [1]
    # the count is that of the plain counter, which knows no approximate roots
    monkeypatch.setattr(ExpandedDeterminant, "_bounds", bounds)
    assert int(count_roots(system._counted(False), region)) == count


@pytest.mark.parametrize("pairs", [1 << 16, 0])
def test_initial_steps_near_approximate_roots(monkeypatch: pytest.MonkeyPatch, pairs: int) -> None:
    from nrobust.roots import winding
    from nrobust.roots.winding import _initial_pieces

    # every (segment, root) distance, and (pairs = 0) only the root nearest to each midpoint, as for many roots
    monkeypatch.setattr(winding, "_NEAR_PAIRS", pairs)

    F = QuasiPolynomial([[1.0, 1.0], [-0.5]], [0.0, 1.0])  # no initial_steps of its own: one step per segment
    starts = np.array([-1.0 + 10.0j, 0.1001 - 1e-4j, 5.0 + 0.0j, 2.0 + 2.0j])
    ends = np.array([-1.0 + 0.0j, 0.1001 + 1e-4j, 5.0 + 0.0j, 3.0 + 2.0j])
    approx = np.array([-0.855 + 0.66j, 0.1])
    pieces = _initial_pieces(F, starts, ends, approx)
    # a long edge at distance 0.145 from a root: steps of at most 0.8 times that distance; the side of a
    # box about a root (the root facing its middle), a segment of length 0 and a far segment: one step
    np.testing.assert_array_equal(pieces, [int(np.ceil(10.0 / (0.8 * 0.145))), 1, 1, 1])
    np.testing.assert_array_equal(_initial_pieces(F, starts, ends), [1, 1, 1, 1])
    assert _initial_pieces(F, starts[:1], ends[:1], np.array([-1.0 + 5.0j]))[0] == 256  # a root on it: the most


def _sparse_coefficients(seed: int, n: int) -> np.ndarray:
    """A random ``(n, n, 2, 2)`` array (delays 0 and 1, powers 0 and 1) with about half its entries zero, an
    ``s`` only on some diagonal entries (a descriptor matrix) and dyadic and non-dyadic coefficients."""
    rng = np.random.default_rng(seed)
    c = np.round(rng.normal(size=(n, n, 2, 2)), 3) * (rng.random(size=(n, n, 2, 2)) < 0.35)
    c[:, :, :, 1] = 0.0
    c[np.arange(n), np.arange(n), 0, 1] = rng.random(n) < 0.6
    c[np.arange(n), rng.permutation(n), 0, 0] += 0.5  # no identically zero row
    return c


def _det_mpmath(c: np.ndarray, s: complex) -> mpmath.mpc:
    """``det M(s)`` of ``M_ij(s) = sum_k (c_ij,k,0 + c_ij,k,1 s) e^{-k s}`` (delays 0, 1) at 40 digits."""
    with mpmath.workdps(40):
        z = mpmath.mpc(s)
        e = [mpmath.mpf(1), mpmath.exp(-z)]
        n = c.shape[0]
        m = mpmath.matrix(n, n)
        for i in range(n):
            for j in range(n):
                m[i, j] = sum((mpmath.mpf(c[i, j, k, 0]) + mpmath.mpf(c[i, j, k, 1]) * z) * e[k] for k in range(2))
        return mpmath.det(m)


@pytest.mark.parametrize("seed", range(6))
def test_expansion_in_any_row_order_is_det_m(seed: int) -> None:
    """On sparse descriptor matrices the rounded exact expansion is det M (mpmath), and the expansion of the
    matrix with its rows permuted is the same up to the sign of the permutation, exactly (the cofactor signs
    of the Laplace expansion, whichever columns the minors keep)."""
    n = 6
    c = _sparse_coefficients(seed, n)
    delays = np.array([0.0, 1.0])
    expanded = ExpandedDeterminant.from_coefficients(c, delays)
    assert expanded is not None
    s = np.array([0.3 + 0.7j, -0.8 + 2.5j, 1.1 - 4.0j])
    want = np.array([complex(_det_mpmath(c, z)) for z in s])
    # Q is det M's exact expansion rounded once to doubles and evaluated in doubles: relative error a few
    # hundred eps of the sum of the moduli of its monomials (the rounding scale, ExpandedDeterminant.magnitude)
    np.testing.assert_allclose(expanded(s), want, rtol=0, atol=1e-13 * float(np.max(expanded.magnitude(s))))
    rng = np.random.default_rng(100 + seed)
    for _ in range(3):
        perm = rng.permutation(n)
        sign = round(float(np.linalg.det(np.eye(n)[perm])))
        swapped = ExpandedDeterminant.from_coefficients(c[perm], delays)
        assert swapped is not None
        np.testing.assert_array_equal(swapped._coef, sign * expanded._coef)  # exact integers, rounded once
