"""det M expanded exactly (QuasiPolynomialMatrix.exact_expansion): its distance to det M, its counts, its refusals.

The oracle of the distance is mpmath at 40 digits: ``det M(s)`` of the matrix entries and
``Q(s)`` of the rounded expansion, both evaluated in 40-digit arithmetic, so that their
difference is the rounding of the coefficients and delays alone, which ``gap`` must bound.
"""

from __future__ import annotations

import mpmath
import numpy as np
import pytest
from _statespace_examples import example_2_9

from nrobust import DistributedDelay, QuasiPolynomial, count_roots
from nrobust.lti.statespace import StateSpaceTDS
from nrobust.qpmatrix import ExpandedDeterminant, QuasiPolynomialMatrix
from nrobust.roots._common import Budget
from nrobust.roots.search import _PATIENCE, _newton


def _four_by_four() -> StateSpaceTDS:
    """A 4 x 4 retarded system with incommensurate delays 1 and 0.3 (sums of delays round)."""
    rng = np.random.default_rng(7)
    return StateSpaceTDS(
        [rng.normal(size=(4, 4)) - 2 * np.eye(4), 0.5 * rng.normal(size=(4, 4)), 0.3 * rng.normal(size=(4, 4))],
        [0.0, 1.0, 0.3],
    )


def _mp_det(sys: StateSpaceTDS, s: complex) -> mpmath.mpc:
    """``det(s E - sum A_k e^{-h_k s})`` in 40-digit arithmetic from the matrices' doubles."""
    z = mpmath.mpc(s)
    m = mpmath.matrix(sys.n, sys.n)
    for i in range(sys.n):
        for j in range(sys.n):
            v = z * mpmath.mpf(float(sys.E[i, j]))
            for a, h in zip(sys.A, sys.hA):
                v -= mpmath.mpf(float(a[i, j])) * mpmath.exp(-mpmath.mpf(float(h)) * z)
            m[i, j] = v
    return mpmath.det(m)


def _mp_poly(Q: ExpandedDeterminant, s: complex) -> mpmath.mpc:
    """``Q(s)`` in 40-digit arithmetic from its double coefficients and delays."""
    z = mpmath.mpc(s)
    return mpmath.fsum(
        mpmath.fsum(mpmath.mpf(float(c)) * z**k for k, c in enumerate(p)) * mpmath.exp(-mpmath.mpf(float(t)) * z)
        for p, t in Q.poly.point_terms
    )


@pytest.mark.parametrize("make", [example_2_9, _four_by_four])
def test_gap_bounds_the_rounding_of_the_expansion(make: object) -> None:
    """|det M - Q| <= gap at points far out (|s| up to 300, where the rounded delays matter most)."""
    sys = make()  # type: ignore[operator]
    Q = sys.characteristic_matrix().exact_expansion()
    assert Q is not None
    pts = np.array([0.3 + 2j, -1.0 - 7j, 0.5 + 60j, -2.0 + 300j, 1.0 - 150j])
    gap = Q.gap(pts, pts)
    with mpmath.workdps(40):
        for s, g in zip(pts, gap):
            exact, rounded = _mp_det(sys, complex(s)), _mp_poly(Q, complex(s))
            assert float(abs(exact - rounded)) <= g
            # and the bound is not vacuous: below a millionth of |det M| at these points
            assert g < 1e-6 * float(abs(exact))


def test_counts_agree_with_the_matrix() -> None:
    """The counts of the expansion (transferred to det M by Rouche) equal those of the matrix; so do the roots."""
    sys = example_2_9()
    M = sys.characteristic_matrix()
    Q = M.exact_expansion()
    assert isinstance(Q, ExpandedDeterminant)
    for box in [(-1.0, 0.5, -10.0, 10.0), (-3.0, 0.5, -10.0, 10.0), (-0.3, -0.2, -0.3, 0.3)]:
        assert int(count_roots(Q, box)) == int(count_roots(M, box))
    ours = sys.roots((-3.0, 0.5, -10.0, 10.0))  # n = 6: counted on the expansion
    assert ours.certified and ours.count == 7
    # the stated abscissa of Example 2.9, -0.2845 (TDS-CONTROL manual, Appendix; tdcpy examples/example2_9.py)
    np.testing.assert_allclose(np.max(ours.roots.real), -0.2845, atol=5e-5)
    np.testing.assert_allclose(np.abs(M(ours.roots)), 0.0, atol=1e-10)


def test_refusals_leave_the_matrix() -> None:
    """No expansion for a distributed term or a complex coefficient: the roots use the matrix."""
    s = QuasiPolynomial([[0.0, 1.0]], [0.0])
    complex_entry = QuasiPolynomialMatrix([[s + 1j, 0.0], [0.0, s + 1]])
    assert complex_entry.exact_expansion() is None
    N = DistributedDelay([0.0, 1.0], [1.0, 1.0])
    distributed = QuasiPolynomialMatrix([[QuasiPolynomial([[1.0, 1.0]], [0.0], [N]), 0.0], [0.0, s + 1]])
    assert distributed.exact_expansion() is None


def test_a_cycling_seed_is_dropped() -> None:
    """A real seed of a real det with no real root near it cycles on the axis: dropped after the patience."""
    sys = StateSpaceTDS(
        [[[-1.0, 0.5], [0.3, -2.0]], [[-0.8, 0.2], [0.1, -0.5]]], [0.0, 1.0], B=[[[-0.3, -0.1], [0.0, 0.4]]], hB=[0.5]
    )
    budget = Budget(10_000)
    out = _newton(sys.characteristic_matrix(), np.array([-1.8326 + 0j]), budget, 1.0)
    assert np.isnan(out[0])
    assert budget.used <= 2 * (_PATIENCE + 1)  # 2 evaluations (F, F') per step; 60 steps before
