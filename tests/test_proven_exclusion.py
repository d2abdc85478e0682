"""The exclusion tests of the proven crossing search (:mod:`nrobust.margins.proven`) against brute force.

Oracles share no code with the bounds: ``|g''|`` and ``|A'| + |B'|`` sampled on fine grids from
the loop factors' own floating-point derivatives (:meth:`QuasiPolynomial.derivative`), a closed
form for a loop with one delay, sign changes of ``h`` on a fine floating-point grid, and the PDE's
crossings at 40 digits (mpmath's matrix exponential of the Laplace-domain solution, as in
``tests/test_exact_form.py``).
"""

from __future__ import annotations

import itertools
import math

import mpmath as mp
import numpy as np
import pytest

import nrobust as nr
from nrobust.balls import ball_function
from nrobust.hyperbolic import Hyperbolic2x2, ReflectionController
from nrobust.hyperbolic.loops.controllers import loop_factors
from nrobust.margins.axis import AxisKernels
from nrobust.margins.proven import _excluded, _Slopes, proven_crossings
from nrobust.quasipoly import DistributedDelay, QuasiPolynomial

flint = pytest.importorskip("flint")


def _curvature(A: QuasiPolynomial, B: QuasiPolynomial, w: np.ndarray) -> np.ndarray:
    """``|g''(w)|``, ``g = |A(i w)|^2 - |B(i w)|^2``: ``g'' = 2 (|P'|^2 - Re(conj(P) P''))`` summed with signs."""
    s = 1j * w
    out = np.zeros_like(w)
    for sign, P in ((1.0, A), (-1.0, B)):
        d1 = P.derivative()
        p, p1, p2 = P(s), d1(s), d1.derivative()(s)
        out += sign * 2.0 * (np.abs(p1) ** 2 - (np.conj(p) * p2).real)
    return np.abs(out)


def _slope(A: QuasiPolynomial, B: QuasiPolynomial, w: np.ndarray) -> np.ndarray:
    """``|A'(i w)| + |B'(i w)|``, the bound of ``|h'|`` that ``L`` bounds in turn."""
    return np.abs(A.derivative()(1j * w)) + np.abs(B.derivative()(1j * w))


def _random_loop(rng: np.random.Generator) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """Point terms of degree <= 2 at random delays and a random kernel, in ``A`` and (negated) in ``B``."""
    nodes = np.sort(rng.uniform(0.0, 2.5, 7))
    N = DistributedDelay(nodes, rng.normal(size=7), poly=rng.normal(size=rng.integers(1, 3)))
    parts = []
    for scale in (1.0, 0.6):
        degree = int(rng.integers(0, 3))
        coefs = [rng.normal(size=degree + 1) * scale * 0.5 ** np.arange(degree + 1) for _ in range(3)]
        coefs[0][-1] = abs(coefs[0][-1]) + 1.0
        delays = [0.0, *np.sort(rng.uniform(0.1, 3.0, 2))]
        kernel = N if scale == 1.0 else N.times(-rng.uniform(0.5, 1.5))
        parts.append(QuasiPolynomial(coefs, delays, [kernel]))
    return parts[0], parts[1]


def _bounds(A: QuasiPolynomial, B: QuasiPolynomial, a: float, b: float) -> tuple[float, float]:
    L, M = _Slopes(flint, A, B, AxisKernels((A, B)))(a, b)
    return float(L.upper()), float(M.upper())


def test_curvature_bound_holds_on_random_loops() -> None:
    """``M >= max |g''|`` and ``L >= max (|A'| + |B'|)`` on blocks of random loops, sampled at 2000 points.

    The samples are floating-point values of the true derivatives (relative rounding far below
    1e-9, the allowance). Both are bounds by moduli: kernels of random signs (``|int N e^{-i nu w}|``
    far below ``int |N|``) and cancelling terms make them loose where ``|g''|`` happens to be small.
    Measured over these 40 loops (ratio bound / sampled maximum, median and largest): ``M``
    52 and 480 on ``[0, b]``, 20 and 970 near ``w = 3``, 2.5 and 220 near 20, 1.7 and 180 near
    150; ``L`` 3.9 and 14, 2.8 and 17, 1.7 and 10, 1.2 and 12. Asserted: the medians at
    ``w >= 20`` within 4x (``M``) and 2.5x (``L``).
    """
    rng = np.random.default_rng(20261129)
    ratios_m, ratios_l = [], []
    for _ in range(40):
        A, B = _random_loop(rng)
        for a in (0.0, 3.0, 20.0, 150.0):
            b = a + rng.uniform(0.5, 4.0)
            w = np.linspace(a, b, 2000)
            L, M = _bounds(A, B, a, b)
            curv, slope = float(np.max(_curvature(A, B, w))), float(np.max(_slope(A, B, w)))
            assert curv <= M * (1.0 + 1e-9), (a, b, curv, M)
            assert slope <= L * (1.0 + 1e-9), (a, b, slope, L)
            if a >= 20.0:
                ratios_m.append(M / curv)
                ratios_l.append(L / slope)
    assert np.median(ratios_m) < 4.0 and np.median(ratios_l) < 2.5, (np.median(ratios_m), np.median(ratios_l))


@pytest.mark.parametrize(
    ("args", "median"), [((1.0, 1.0, 1.0, 1.0, 1.0, 0.85), 1.5), ((1.0, 1.0, 4.0, 4.0, 0.5, 0.5), 5.0)]
)
def test_curvature_bound_of_the_paper_loops(args: tuple[float, ...], median: float) -> None:
    """On the 64 blocks of ``[0, 120]``, the loops of ``U_BS2(0.1)`` on the exact route: ``M`` holds and
    is within 10x of the sampled maximum of ``|g''|`` everywhere. Measured (median, largest):
    1.3 and 5.8 for the paper's plant (``+-I_N`` cancel in ``A + B``, and the point terms pair by
    their delay difference), 4.1 and 7.6 for ``sigma = 4`` (a kernel of variation 25)."""
    A, B = loop_factors(Hyperbolic2x2(*args), ReflectionController(0.1))
    edges = np.linspace(0.0, 120.0, 65)
    ratios = []
    for a, b in itertools.pairwise(edges):
        _, M = _bounds(A, B, a, b)
        curv = float(np.max(_curvature(A, B, np.linspace(a, b, 400))))
        assert curv <= M * (1.0 + 1e-9)
        ratios.append(M / curv)
    assert max(ratios) < 10.0 and np.median(ratios) < median, (max(ratios), np.median(ratios))


def test_curvature_bound_on_negative_frequencies() -> None:
    """Complex loops scan ``[-W, W]``: the bounds hold on blocks left of 0 and across it."""
    rng = np.random.default_rng(7)
    for _ in range(10):
        A, B = _random_loop(rng)
        A = A.times_poly([1j + rng.normal()])
        for a, b in ((-12.0, -9.5), (-1.0, 1.5)):
            w = np.linspace(a, b, 2000)
            L, M = _bounds(A, B, a, b)
            assert float(np.max(_curvature(A, B, w))) <= M * (1.0 + 1e-9)
            assert float(np.max(_slope(A, B, w))) <= L * (1.0 + 1e-9)


@pytest.mark.parametrize(("a", "tau", "b"), [(0.05, 2.0, 0.3), (0.3, 1.3, 0.7), (0.8, 0.5, 0.1)])
def test_curvature_bound_is_the_closed_form_for_one_delay(a: float, tau: float, b: float) -> None:
    """``A = 1 + a e^{-tau s}``, ``B = b``: ``g = 1 + a^2 - b^2 + 2 a cos(tau w)``, ``max |g''| = 2 a tau^2``.

    The bound pairs the terms of ``D = A - B`` and ``S = A + B`` by their delay difference: it
    is the closed form itself (to the ball radius, 1e-15 relative); half of it fails.
    """
    A, B = QuasiPolynomial([[1.0], [a]], [0.0, tau]), QuasiPolynomial([[b]], [0.0])
    _, M = _bounds(A, B, 10.0, 10.0 + 2 * math.pi / tau)
    np.testing.assert_allclose(M, 2 * a * tau**2, rtol=1e-14)
    w = np.linspace(10.0, 10.0 + 2 * math.pi / tau, 20001)
    # the grid holds a maximum of |cos| to within (pi / 20000)^2 / 2 < 2e-8 relative
    np.testing.assert_allclose(np.max(_curvature(A, B, w)), M, rtol=3e-8)


def test_second_order_test_refuses_a_segment_holding_two_zeros() -> None:
    """``g = c + 2 a cos(tau w)`` dips to ``-eps`` at ``w = pi / tau``: the segment around the dip has
    ``g > 0`` at both ends and two zeros inside. With the proven ``M`` it is refused; with ``M / 2``
    (a bound too small by half) the test would accept it, a false exclusion."""
    a, tau, eps = 0.3, 1.3, 1e-3
    b = math.sqrt(1 + a**2 - 2 * a + eps)  # c = 1 + a^2 - b^2 = 2 a - eps
    A, B = QuasiPolynomial([[1.0], [a]], [0.0, tau]), QuasiPolynomial([[b]], [0.0])
    lo, hi = math.pi / tau - 0.8, math.pi / tau + 0.8
    L, M = _Slopes(flint, A, B, AxisKernels((A, B)))(lo, hi)

    def ends(w: float) -> tuple[object, object]:
        x, y = ball_function(A)(flint.acb(0, w)), ball_function(B)(flint.acb(0, w))
        return abs(x) - abs(y), x.real**2 + x.imag**2 - y.real**2 - y.imag**2

    pa, pb = ends(lo), ends(hi)
    assert pa[1] > 0 and pb[1] > 0
    assert not _excluded(flint, lo, hi, pa, pb, L, M)
    assert _excluded(flint, lo, hi, pa, pb, L, M / 2)
    assert ends(math.pi / tau)[1] < 0  # the dip: two zeros of g in the segment


def _fundamental(args: tuple[float, ...], s: complex) -> tuple[object, object, object]:
    """``e^{-s/mu} [u; v](1, s)`` from ``[q; 1]`` by mpmath's expm at 40 digits (the PDE's solution)."""
    lam, mu, spm, smp, q, _ = (mp.mpf(v) for v in args)
    with mp.workdps(40):
        tau = mp.mpf(1.0 / args[0] + 1.0 / args[1])
        z = mp.expm(mp.matrix([[-mp.mpc(s) * tau, spm / lam], [-smp / mu, 0]])) * mp.matrix([q, 1])
        return z[0], z[1], tau


def _pde_crossing(args: tuple[float, ...], K: float, w0: float) -> tuple[float, float]:
    """``(w, first delay)`` of the PDE's crossing near ``w0`` under ``U_BS2(K)``, at 40 digits."""
    rho, q = mp.mpf(args[5]), mp.mpf(args[4])

    def factors(w: object) -> tuple[object, object]:
        zu, zv, tau = _fundamental(args, 1j * w)
        A = zv - rho * zu
        return A, K * q * mp.exp(-1j * w * tau) - (A - 1 + rho * q * mp.exp(-1j * w * tau))

    with mp.workdps(40):
        w = mp.findroot(lambda v: abs(factors(v)[0]) - abs(factors(v)[1]), w0)
        A, B = factors(w)
        return float(w), float((-mp.arg(-A / B)) % (2 * mp.pi) / w)


# the benchmark's three plants (benchmarks/exact.py), then random constant couplings (seeded draws)
PLANTS = [
    (1.0, 1.0, 1.0, 1.0, 1.0, 0.85),
    (1.0, 3.0, 1.0, 1.0, 1.0, 0.85),
    (1.0, 1.0, 4.0, 4.0, 0.5, 0.5),
    (1.7, 0.6, -1.2, 2.5, 0.4, -0.3),
    (0.8, 2.2, 2.0, 0.7, -0.6, 0.45),
    (1.3, 1.1, -3.0, -2.0, 0.9, 0.2),
]


@pytest.mark.parametrize("args", PLANTS)
def test_every_crossing_of_the_exact_loop_is_found_and_holds_the_pde_crossing(args: tuple[float, ...]) -> None:
    """Exact-route loops under ``U_BS2(0.1)``: the proven crossings are the sign changes of ``h`` on a
    float grid of step ``1e-3`` up to ``W`` (none missed, none extra), and each enclosure and
    its delay hold the PDE's crossing solved at 40 digits from the enclosure's midpoint (``N~`` in
    closed form within its proven radius: the proofs are about the PDE)."""
    A, B = loop_factors(Hyperbolic2x2(*args), ReflectionController(0.1))
    res = proven_crossings(A, B)
    assert res.method == "ball bisection" and not res.unresolved
    w = np.arange(0.0, res.frequency_bound, 1e-3)
    h = np.abs(A(1j * w)) - np.abs(B(1j * w))
    changes = w[np.flatnonzero(np.sign(h[1:]) != np.sign(h[:-1]))]
    assert len(changes) == len(res.omegas)
    for (w_lo, w_hi), (d_lo, d_hi), c in zip(res.omegas, res.delays, changes):
        assert c - 1e-3 <= w_lo <= w_hi <= c + 2e-3
        w_pde, delay = _pde_crossing(args, 0.1, 0.5 * (w_lo + w_hi))
        assert w_lo <= w_pde <= w_hi and d_lo <= delay <= d_hi
        # the enclosures are tight: measured 2e-15 to 3.5e-14 (frequency), 7e-14 to 2.4e-12 (delay)
        assert w_hi - w_lo < 1e-12 * w_pde and d_hi - d_lo < 1e-11 * delay


@pytest.mark.parametrize(
    ("args", "most"),
    [
        ((1.0, 1.0, 1.0, 1.0, 1.0, 0.85), 400),
        ((1.0, 3.0, 1.0, 1.0, 1.0, 0.85), 200),
        ((1.0, 1.0, 4.0, 4.0, 0.5, 0.5), 350),
    ],
)
def test_ball_evaluations_of_the_benchmark_plants(args: tuple[float, ...], most: int) -> None:
    """The work of the proven margin: measured 295, 125 and 223 ball evaluations (1032, 524 and
    1113 with the first-order test alone on steps ``0.9 |h| / L``); the margin is the same."""
    dm = nr.delay_margin(Hyperbolic2x2(*args), ReflectionController(0.1), rigorous=True)
    assert dm.evaluations <= most
    lo, hi = dm.margin_ball
    assert lo <= nr.delay_margin(Hyperbolic2x2(*args), ReflectionController(0.1)).margin <= hi


def test_g_at_zero_frequency_is_a_finite_ball() -> None:
    """At ``w = 0`` the imaginary parts of ``A`` and ``B`` are balls holding 0, whose ``x**2`` is not
    finite in python-flint: ``|z|^2`` is formed by products, and ``g(0)`` holds the float value."""
    from nrobust.margins.proven import _Axis, _hg

    A, B = loop_factors(Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85), ReflectionController(0.1))
    ((_, g0),) = _hg(_Axis(A, B, 10).values([0.0]))
    assert g0.is_finite()
    exact = abs(A(0.0)) ** 2 - abs(B(0.0)) ** 2
    # float value of the same stored loop: rounding of a few ulps of |A(0)|^2 ~ 2
    assert float(g0.lower()) - 1e-14 <= exact <= float(g0.upper()) + 1e-14
