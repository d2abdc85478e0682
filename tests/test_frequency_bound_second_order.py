"""The frequency bound ``W`` of every delay margin with the kernels integrated by parts twice.

``frequency_bound`` takes, per kernel, the least of ``M_0``, ``V / |w|`` and ``V_1 / |w| + V_2 / |w|^2``. The
oracles: a scalar loop ``1`` against ``c int_0^1 t (1 - t) e^{-s t} dt`` whose integral is in closed form
(``(1 + e^{-s}) / s^2 - 2 (1 - e^{-s}) / s^3``), so its last crossing is found by dense sampling of the
closed form and checked at 40 digits in mpmath; and for the paper's loops (``U_BS2(0.1)`` exact and on a
spline grid, ``U_BS`` filtered, the collocated loop of the decay-rate design) the bound of a single integration
by parts (``TailBound`` without ``second_order``, solved by bisection), which the new ``W`` must not exceed,
and dense sampling of ``|A(i w)| - |B(i w)|`` from ``W`` to ``2 W``, which must keep the sign of the dominance.
The proven counterpart (``ball_second_order_variation``) is checked against the same closed forms and the
floating-point ``(V_1, V_2)``.
"""

from __future__ import annotations

from fractions import Fraction

import mpmath as mp
import numpy as np
import pytest

from nrobust import (
    CollocatedOutputFeedback,
    DistributedDelay,
    FilteredController,
    Hyperbolic2x2,
    QuasiPolynomial,
    ReflectionController,
    loop_factors,
)
from nrobust.bounds import TailBound, joint_degree, principal_gap, radius_where
from nrobust.margins import frequency_bound

PAPER = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
# the gain of the collocated decay-rate design (margin at least 0.1): its final loop
K_COLLOCATED = 0.1928571428571429
C = 1000.0


def _bump(c: float) -> QuasiPolynomial:
    """``c int_0^1 t (1 - t) e^{-s t} dt``: one polynomial piece, end values 0, slopes ``c`` and ``-c``."""
    return QuasiPolynomial(
        [], [], [DistributedDelay([0.0, 1.0], None, coefficients=[[0.0, c, -c]], interpolation="polynomial")]
    )


def _bump_closed_form(c: float, w: np.ndarray) -> np.ndarray:
    """``c int_0^1 t (1 - t) e^{-i w t} dt`` by parts to the end (no nrobust evaluation)."""
    s = 1j * w
    e = np.exp(-s)
    return c * ((1.0 + e) / s**2 - 2.0 * (1.0 - e) / s**3)


def _first_order_bound(A: QuasiPolynomial, B: QuasiPolynomial) -> float:
    """``W`` with the kernels integrated by parts once (the bound before the second order), by bisection."""
    n = joint_degree(A, B)
    principal = principal_gap({"A": (A, 0), "B": (B, 1)}, n, 0.0)
    assert principal is not None
    tail_a, tail_b = TailBound(A, n, 0.0, principal.t0), TailBound(B, n, 0.0, principal.t0)
    return radius_where(lambda R: float(tail_a(R) + tail_b(R)), principal.gap, "first order")


def test_scalar_polynomial_kernel_bound_is_sound_and_near_the_last_crossing() -> None:
    """``1`` against ``c = 1000`` times the bump: ``|B| = 1`` last near ``w = 44.3`` (dense sampling of the
    closed form, step ``1/64``, and the crossing solved at 40 digits). Integrated once, ``V = sum_l l |P_l| = 3 c``
    (a bound of ``int |N'| = c / 2``) puts ``W`` at 3000; twice, ``V_1 = 0`` (end values zero) and
    ``V_2 = c + c + 2 c`` put it at ``sqrt(4 c) = 63.2``; no crossing from ``W`` to ``8 W``."""
    A, B = QuasiPolynomial([[1.0]], [0.0]), _bump(C)
    W, gap = frequency_bound(A, B)
    assert gap == 1.0
    assert _first_order_bound(A, B) == pytest.approx(3.0 * C, rel=1e-6)
    assert np.sqrt(4.0 * C) <= W <= np.sqrt(4.0 * C) * (1.0 + 1e-6)
    w = np.arange(1.0, 8.0 * W, 1.0 / 64.0)
    h = 1.0 - np.abs(_bump_closed_form(C, w))
    change = np.flatnonzero(np.sign(h[:-1]) != np.sign(h[1:]))
    last = w[change[-1]]
    assert 44.0 < last < W and np.all(h[w >= W] > 0.0)
    mp.mp.dps = 40

    def modulus(x: mp.mpf) -> mp.mpf:
        s = mp.mpc(0, x)
        return abs(C * ((1 + mp.exp(-s)) / s**2 - 2 * (1 - mp.exp(-s)) / s**3)) - 1

    root = mp.findroot(modulus, (mp.mpf(last), mp.mpf(last) + mp.mpf(1) / 64), solver="anderson")
    assert last <= root <= last + 1.0 / 64.0 and root < W


_LOOPS = {
    "U_BS2(0.1)": (ReflectionController(0.1), None, 0.7),
    "U_BS2(0.1) spline": (ReflectionController(0.1), 201, 0.7),
    "U_BS filtered": (FilteredController(0.0, 0.1), None, 1.0),
    "collocated": (CollocatedOutputFeedback(ReflectionController(K_COLLOCATED)), None, 0.6),
}


@pytest.mark.parametrize("name", list(_LOOPS))
def test_paper_loops_bound_not_above_the_first_order_and_no_crossing_beyond(name: str) -> None:
    """``W`` is at most the first-order bound (at most ``ratio`` of it: 78 against 122 and 114 for ``U_BS2(0.1)``,
    194 against 202 filtered, 1218 against 2187 for the collocated loop, proven: its two kernels ``N~`` and ``G``
    bounded each, where the kernel route's one kernel gave 705 against 1647) and ``|A(i w)| - |B(i w)|`` is positive
    (``A`` dominates) on a grid of step ``1/32`` from ``W`` to ``2 W`` (the loops' delays are at most 4: 50 points
    per period)."""
    controller, grid, ratio = _LOOPS[name]
    A, B = loop_factors(PAPER, controller, kernel_grid=grid)
    W, _ = frequency_bound(A, B)
    old = _first_order_bound(A, B)
    assert W <= ratio * old
    w = np.arange(W, 2.0 * W, 1.0 / 32.0)
    h = np.abs(A(1j * w)) - np.abs(B(1j * w))
    assert np.all(h > 0.0)


def test_ball_bounds_hold_the_closed_forms() -> None:
    """Ball ``(V_1, V_2)``: ``(0, 4 c)`` for the bump, ``(2, 0)`` for ``N = 1`` (``|1 - e^{-i w}| / w`` attained
    at ``w = pi``), ``(3, 6)`` for a linear kernel with a jump; each upper end within ``1e-12`` of the exact
    value, and at most the floating-point bound (to ``1e-11``), also for the collocated loop's kernel; and the
    exact Chebyshev table of ``((1 + x) / 2)^l`` is that of numpy's ``chebpow``."""
    pytest.importorskip("flint")
    from nrobust.balls import _powers_in_chebyshev, ball_second_order_variation

    cases = [
        (_bump(C).distributed[0], (0.0, 4.0 * C)),
        (DistributedDelay([0.0, 1.0], [1.0, 1.0]), (2.0, 0.0)),
        (DistributedDelay([0.0, 1.0, 1.0, 2.0], [1.0, 3.0, 2.0, 1.0]), (3.0, 6.0)),
    ]
    A, _ = loop_factors(PAPER, CollocatedOutputFeedback(ReflectionController(K_COLLOCATED)))
    kernel = A.distributed[0]
    for ball, fl in zip(ball_second_order_variation(kernel), kernel.second_order_variation()):
        assert fl * (1.0 - 1e-9) <= float(ball.upper()) <= fl * (1.0 + 1e-11)
    for d, exact in cases:
        balls = ball_second_order_variation(d)
        floats = d.second_order_variation()
        for ball, value, fl in zip(balls, exact, floats):
            upper = float(ball.upper())
            assert value <= upper <= value + 1e-12 * max(1.0, value)
            assert upper <= fl * (1.0 + 1e-11) + 1e-15
    table = _powers_in_chebyshev(12)
    for power in range(12):
        column = np.polynomial.chebyshev.chebpow([0.5, 0.5], power)
        assert [table[k][power] for k in range(column.size)] == [Fraction(x) for x in column]


def test_proven_bound_of_the_collocated_loop() -> None:
    """The proven crossing set of the collocated loop proves ``W = 1218`` in balls (2187 integrated by parts once)
    and finds the eleven crossings of the floating-point search, each inside its proven interval. The loop is
    proven: ``N~`` and ``G`` are two kernels (``G``'s pieces joined into one as stored), each integrated by parts
    twice, so their jumps at ``tau`` and ends at 0 add where the kernel route's one kernel (``W = 705``) let them
    cancel; one kernel on their nodes' union would re-expand the proven pieces and bound the sum by that rounding,
    about 1000 times their bounds (``output_feedback.consolidated``). ``G`` as four kernels gave 1904."""
    pytest.importorskip("flint")
    from nrobust import crossing_frequencies
    from nrobust.margins.proven import proven_crossings

    A, B = loop_factors(PAPER, CollocatedOutputFeedback(ReflectionController(K_COLLOCATED)))
    proof = proven_crossings(A, B)
    assert proof.frequency_bound == frequency_bound(A, B)[0]
    assert proof.frequency_bound <= 0.6 * _first_order_bound(A, B)
    found = crossing_frequencies(A, B).omegas
    assert len(proof.omegas) == len(found) == 11
    for (lo, hi), w in zip(proof.omegas, found):
        assert lo - 1e-9 <= w <= hi + 1e-9
