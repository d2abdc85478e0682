"""Every printed digit of the headline numbers is true: accuracies checked against independent oracles.

Each headline number carries an accuracy (a proven radius, or a conservative floating-point
estimate) and its repr prints no digit beyond it. The oracles are independent of the code
checked: Lambert W for ``s + b + a e^{-s}``, the closed form ``ln|rho q| / tau`` of a
transport system, and mpmath at 40 digits on the stored coefficients (point terms, and the
polynomial pieces of the distributed kernels integrated in closed form by parts).

The accuracy must not be absurdly loose either: below ``1e-10`` absolute (all the numbers
checked are of order 0.01 to 100, so that is at least 8 true digits), or within ``1e4`` of
the true error when the true error is larger than ``1e-14``.
"""

from __future__ import annotations

import dataclasses
import math
from decimal import Decimal

import mpmath as mp
import numpy as np
import pytest

import nrobust
from nrobust import QuasiPolynomial, spectral_abscissa
from nrobust._digits import inner_interval_text, lower_bound_text, with_accuracy
from nrobust.hyperbolic.analyses import k_region, margin_and_decay, tradeoff
from nrobust.hyperbolic.analyses.kregion import u_bs2_loop
from nrobust.margins import delay_margin
from nrobust.reports.report import _end_text as report_end_text

PAPER = nrobust.Hyperbolic2x2(1, 1, 1, 1, 1, 0.85)


@pytest.fixture(autouse=True)
def _forty_digits():
    """mpmath at 40 digits in every test here (another module's test may leave the precision at 15)."""
    with mp.workdps(40):
        yield


def _mp_poly(coefs, s):
    """``sum_j c_j s^j`` in mpmath (coefficients in increasing powers)."""
    return mp.polyval([mp.mpf(float(c)) for c in np.real(coefs)], s, asc=True)


def _piece_integral(poly_t, z):
    """``int_0^1 P(t) e^{-z t} dt`` for a polynomial ``P`` (mpmath, increasing powers), by parts:
    ``sum_j (P^(j)(0) - P^(j)(1) e^{-z}) / z^(j+1)``."""
    total, p, ez = mp.mpc(0), list(poly_t), mp.exp(-z)
    for j in range(len(p)):
        total += (p[0] - mp.fsum(p) * ez) / z ** (j + 1)
        p = [k * p[k] for k in range(1, len(p))]  # P' in increasing powers
    return total


def mp_function(F: QuasiPolynomial):
    """``F(s)`` in mpmath from its stored point terms and kernel pieces (40 digits)."""
    points = [(p, mp.mpf(float(t))) for p, t in F.point_terms]
    dist = []
    for d in F.distributed:
        assert d.interpolation == "polynomial"
        starts, widths, coefs = d.pieces
        pieces = []
        for a, h, c in zip(starts, widths, coefs):
            a, h = mp.mpf(float(a)), mp.mpf(float(h))
            poly = [mp.mpf(float(x)) for x in np.real(c)]
            for _ in range(d.moment):  # times nu = a + h t
                padded = [mp.mpf(0), *poly, mp.mpf(0)]
                poly = [a * padded[k + 1] + h * padded[k] for k in range(len(poly) + 1)]
            pieces.append((a, h, poly))
        dist.append((d.poly, pieces))

    def f(s):
        out = mp.mpc(0)
        for p, t in points:
            out += _mp_poly(p, s) * mp.exp(-t * s)
        for q, pieces in dist:
            out += _mp_poly(q, s) * mp.fsum(h * mp.exp(-a * s) * _piece_integral(p, h * s) for a, h, p in pieces)
        return out

    return f


def assert_true_and_tight(value: float, accuracy: float | None, oracle) -> None:
    """``|value - oracle| <= accuracy`` and the accuracy is not absurdly loose; the printed text too."""
    assert accuracy is not None
    error = float(abs(mp.mpf(value) - oracle))
    assert error <= accuracy, (value, accuracy, error)
    assert accuracy <= 1e-10 or accuracy <= 1e4 * max(error, 1e-14), (accuracy, error)
    text = with_accuracy(value, accuracy)
    printed, bound = text.split(" +- ")
    # the printed value is the value rounded to the place of the bound's digit: off by half a unit at most
    assert float(abs(mp.mpf(printed) - oracle)) <= 1.5 * float(bound), text


# ---------------------------------------------------------------------------------------- lower bounds
def test_lower_bound_text_never_rounds_up() -> None:
    rng = np.random.default_rng(7)
    values = [0.0123456789, 0.1, 1.0 - 1e-12, 123456789.0, 2.5e-7, 3e20, -0.0123456789]
    values += list(10.0 ** rng.uniform(-6, 6, 200))
    for v in values:
        for digits in (1, 3, 6):
            printed = Decimal(lower_bound_text(v, digits))
            assert printed <= Decimal(v)
            # the floor to `digits` significant digits: less than one unit of the last digit below
            unit = Decimal(10) ** (Decimal(abs(v)).adjusted() - digits + 1)
            assert Decimal(v) - printed < unit
    assert lower_bound_text(0.0123456789) == "0.0123456"  # ordinary rounding would print 0.0123457
    assert lower_bound_text(math.inf) == "inf"


def test_rouche_repr_prints_delta_0_rounded_down() -> None:
    bound = nrobust.rouche_delay_bound(PAPER, nrobust.ReflectionController(0.1))
    printed = repr(bound).split("delta_0=")[1].split(",")[0]
    assert printed == bound.text
    assert Decimal(printed) <= Decimal(bound.delta_0) < Decimal(printed) + Decimal("1e-7")


# ---------------------------------------------------------------------------------------- abscissa
@pytest.mark.parametrize(("a", "b"), [(0.2, 0.0), (1.0, 0.0), (5.0, 0.0), (0.5, 1.0), (3.0, -0.5), (10.0, 2.0)])
def test_abscissa_of_lambert_loops(a: float, b: float) -> None:
    """``s + b + a e^{-s}``: the rightmost root is ``W_0(-a e^b) - b`` (principal branch)."""
    sa = spectral_abscissa(QuasiPolynomial([[b, 1.0], [a]], [0.0, 1.0]))
    exact = mp.lambertw(-a * mp.e**b) - b
    assert_true_and_tight(sa.value, sa.accuracy, exact.real)
    assert sa.root is not None
    assert_true_and_tight(abs(sa.root.imag), sa.root_accuracy[1], abs(exact.imag))
    assert with_accuracy(sa.value, sa.accuracy) in repr(sa)


def test_abscissa_proven_bracket_and_polynomial_ball() -> None:
    sa = spectral_abscissa(QuasiPolynomial([[1.0, 1.0], [0.5]], [0.0, 1.0]), rigorous=True)
    assert_true_and_tight(sa.value, sa.accuracy, (mp.lambertw(-0.5 * mp.e) - 1).real)
    # p(s) e^{-s/2} with p = s^2 + 2 s + 5: roots -1 +- 2i, isolated by FLINT
    poly = spectral_abscissa(QuasiPolynomial([[5.0, 2.0, 1.0]], [0.5]))
    assert_true_and_tight(poly.value, poly.accuracy, mp.mpf(-1))
    assert poly.root is not None
    assert_true_and_tight(poly.root.imag, poly.root_accuracy[1], mp.mpf(2))


def test_abscissa_of_a_transport_system() -> None:
    """``1 - rho q e^{-tau s}``: every root on ``Re s = ln|rho q| / tau``."""
    system = nrobust.TransportSystem(1.0, 2.0, 0.7, 0.9)
    sa = spectral_abscissa(nrobust.characteristic(system, nrobust.ReflectionController(0.0), 0.0))
    assert_true_and_tight(sa.value, sa.accuracy, mp.log(mp.mpf(0.7) * mp.mpf(0.9)) / mp.mpf(system.tau))


def test_abscissa_of_the_paper_loop() -> None:
    """``U_BS2(0.1)`` with the delay 0.3: the rightmost root near ``0.0406 + 3.16 i``."""
    F = nrobust.characteristic(PAPER, nrobust.ReflectionController(0.1), 0.3)
    sa = spectral_abscissa(F)
    assert not sa.approached_at_infinity and sa.root is not None
    root = mp.findroot(mp_function(F), mp.mpc(sa.root), tol=mp.mpf(10) ** -35)
    assert abs(mp_function(F)(root)) < 1e-30
    assert_true_and_tight(sa.value, sa.accuracy, root.real)


def test_abscissa_at_the_chain_value() -> None:
    """``K = 0.1, delta = 1``: the value is ``c_D`` of ``1 - 0.85 e^{-2 s} + 0.1 e^{-3 s}``,
    ``max -ln|z|`` over the roots of ``1 - 0.85 z^2 + 0.1 z^3``."""
    sa = spectral_abscissa(nrobust.characteristic(PAPER, nrobust.ReflectionController(0.1), 1.0))
    assert sa.approached_at_infinity
    coefs = [1, 0, mp.mpf("-0.85"), mp.mpf("0.1")]  # increasing powers; seeds from numpy, refined at 40 digits
    roots = [mp.findroot(lambda z: mp.polyval(coefs, z, asc=True), mp.mpc(z0)) for z0 in np.roots([0.1, -0.85, 0, 1])]
    c_D = max(-mp.log(abs(z)) for z in roots)
    assert_true_and_tight(sa.value, sa.accuracy, c_D)


def test_decay_rate_of_margin_and_decay() -> None:
    """The nominal loop of ``U_BS2(0.1)`` on the paper's plant is ``1 - 0.75 e^{-2 s}``."""
    row = margin_and_decay(PAPER, nrobust.ReflectionController(0.1))
    assert_true_and_tight(row["decay_rate"], row["decay_rate_accuracy"], -mp.log(mp.mpf("0.75")) / 2)


def test_decay_rates_of_a_tradeoff() -> None:
    """On a transport system the target reflection ``rho - K`` decays at ``-ln|(rho - K) q| / tau``."""
    system = nrobust.TransportSystem(1.0, 2.0, 0.7, 0.9)
    trade = tradeoff(system, [0.0, 0.3])
    assert trade.decay_rate_accuracies is not None
    for K, rate, accuracy in zip(trade.Ks, trade.decay_rates, trade.decay_rate_accuracies):
        exact = -mp.log(abs((mp.mpf(0.9) - mp.mpf(float(K))) * mp.mpf(0.7))) / mp.mpf(system.tau)
        assert_true_and_tight(float(rate), float(accuracy), exact)


# ---------------------------------------------------------------------------------------- crossing frequency
@pytest.mark.parametrize(("a", "b", "rigorous"), [(1.0, 2.0, False), (1.0, 2.0, True), (0.1, 3.0, False)])
def test_crossing_frequency_of_a_scalar_loop(a: float, b: float, rigorous: bool) -> None:
    """``s + a + b e^{-delta s}``: ``|i w + a| = b`` at ``w = sqrt(b^2 - a^2)``."""
    A, B = QuasiPolynomial([[a, 1.0]], [0.0]), QuasiPolynomial([[b]], [0.0])
    dm = delay_margin(A, B, rigorous=rigorous)
    assert dm.omega is not None
    assert_true_and_tight(dm.omega, dm.omega_accuracy, mp.sqrt(mp.mpf(b) ** 2 - mp.mpf(a) ** 2))
    assert f"omega={with_accuracy(dm.omega, dm.omega_accuracy)}" in repr(dm)


def test_crossing_frequency_of_the_paper_loop() -> None:
    """``|A(i w)| = |B(i w)|`` solved in mpmath from the stored loop factors."""
    A, B = nrobust.hyperbolic.loop_factors(PAPER, nrobust.ReflectionController(0.1))
    dm = delay_margin(A, B, verify=False)
    assert dm.omega is not None
    fa, fb = mp_function(A), mp_function(B)
    w = mp.findroot(lambda x: abs(fa(1j * x)) ** 2 - abs(fb(1j * x)) ** 2, mp.mpf(dm.omega), tol=mp.mpf(10) ** -35)
    assert_true_and_tight(dm.omega, dm.omega_accuracy, w)
    model = dataclasses.replace(dm, of_model=True)  # a model of the plant: no accuracy in the core
    assert model.omega_accuracy is None and model.accuracy is None


# ---------------------------------------------------------------------------------------- gain region ends
def test_k_region_ends_against_an_independent_solve() -> None:
    """Each crossing end solves ``A(i w) + (B_0(i w) + K R(i w)) e^{-i w delta_max} = 0`` with ``K`` real:
    ``K(w) = -(A e^{i w delta_max} + B_0) / R`` at the ``w`` where ``Im K(w) = 0``."""
    delta_max = 0.05
    region = k_region(PAPER, delta_max, Ks=[0.0])
    loop = u_bs2_loop(PAPER)
    fa, fb, fr = mp_function(loop.A), mp_function(loop.B0), mp_function(loop.R)
    ends = [end for pair in region.ends for end in pair]
    assert [e.kind for e in ends] == ["crossing", "crossing"]

    def gain(w):
        s = 1j * w
        return -(fa(s) * mp.exp(s * delta_max) + fb(s)) / fr(s)

    for end in ends:
        w = mp.findroot(lambda x: gain(x).imag, mp.mpf(end.omega), tol=mp.mpf(10) ** -30)
        assert abs(gain(w).imag) < 1e-30
        assert_true_and_tight(end.K, end.accuracy, gain(w).real)
        assert with_accuracy(end.K, end.accuracy) in repr(region)
        # the end's frequency: within its estimated accuracy of the 40-digit root, printed to it
        assert_true_and_tight(end.omega, end.omega_accuracy, w)
        assert end.delay == delta_max and end.delay_accuracy == 0.0
        assert f"omega={with_accuracy(end.omega, end.omega_accuracy)}, delay={delta_max!r})" in repr(end)
        assert f"a root at i ({with_accuracy(end.omega, end.omega_accuracy)})" in report_end_text(end)
    assert region.end_accuracies == ((region.tol, region.tol),)


# ---------------------------------------------------------------------------------------- crossings
def test_crossing_reprs_print_their_accuracy() -> None:
    """``s^2 + 1`` against ``s``: crossings at ``w = phi`` (delays ``(pi/2 + 2 pi k)/phi``, the first the
    margin) and ``1/phi`` (delays ``(3 pi/2 + 2 pi k) phi``); every printed digit of the reprs and every
    delay's accuracy against the closed forms."""
    A = QuasiPolynomial([[1.0, 0.0, 1.0]], [0.0])
    B = QuasiPolynomial([[0.0, 1.0]], [0.0])
    phi = (1 + mp.sqrt(5)) / 2
    for rigorous in (False, True):
        dm = delay_margin(A, B, delta_max=20.0, rigorous=rigorous)
        first, second = dm.crossings
        assert first.omega_accuracy == dm.omega_accuracy and first.delay_accuracy == dm.accuracy
        assert_true_and_tight(first.omega, first.omega_accuracy, phi)
        assert_true_and_tight(first.delays[0], first.delay_accuracy, mp.pi / 2 / phi)
        assert_true_and_tight(second.omega, second.omega_accuracy, 1 / phi)
        assert second.delay_accuracy == second.delay_accuracies[0]
        for k, (delay, accuracy) in enumerate(zip(first.delays, first.delay_accuracies)):
            assert_true_and_tight(delay, accuracy, (mp.pi / 2 + 2 * mp.pi * k) / phi)
        for k, (delay, accuracy) in enumerate(zip(second.delays, second.delay_accuracies)):
            assert_true_and_tight(delay, accuracy, (3 * mp.pi / 2 + 2 * mp.pi * k) * phi)
        assert f"delta_0={with_accuracy(second.delays[0], second.delay_accuracy)}" in repr(second)
        for c, w in ((first, phi), (second, 1 / phi)):
            printed, bound = repr(c).split("period=")[1].split(",")[0].split(" +- ")
            assert abs(mp.mpf(printed) - 2 * mp.pi / w) <= mp.mpf(bound), repr(c)
            assert f"omega={with_accuracy(c.omega, c.omega_accuracy)}" in repr(c)
    # a model of the plant without a model error: nothing about the plant is known to these digits
    model = dataclasses.replace(dm, of_model=True)
    assert all(c.omega_accuracy is None and c.delay_accuracy is None for c in model.crossings)
    assert all(a is None for c in model.crossings for a in c.delay_accuracies)
    assert "omega=1.61803 (accuracy not estimated)" in repr(model.crossings[0])


def test_bisection_ends_carry_their_margins_accuracies() -> None:
    """A bisection end's ``omega`` and ``delay`` are the first crossing of the margin just outside (at
    ``K -+ accuracy``): re-solved there at 40 digits, ``|A(i w)| = |B(i w)|``, ``delay = arg(-B/A) / w``."""
    from nrobust.hyperbolic import loop_factors

    region = k_region(
        PAPER, 0.05, controller=lambda K: nrobust.ReflectionController(K), Ks=[-0.11, 0.0, 0.15], tol=1e-3
    )
    ((lower, upper),) = region.ends
    for end, outside in ((lower, lower.K - lower.accuracy), (upper, upper.K + upper.accuracy)):
        assert end.kind == "bisection"
        A, B = loop_factors(PAPER, nrobust.ReflectionController(outside))
        fa, fb = mp_function(A), mp_function(B)
        w = mp.findroot(
            lambda x, fa=fa, fb=fb: abs(fa(1j * x)) ** 2 - abs(fb(1j * x)) ** 2,
            mp.mpf(end.omega),
            tol=mp.mpf(10) ** -35,
        )
        delay = (mp.arg(-fb(1j * w) / fa(1j * w)) % (2 * mp.pi)) / w
        assert_true_and_tight(end.omega, end.omega_accuracy, w)
        assert_true_and_tight(end.delay, end.delay_accuracy, delay)
        assert f"omega={with_accuracy(end.omega, end.omega_accuracy)}" in repr(end)


# ---------------------------------------------------------------------------------------- every crossing delay
@pytest.mark.parametrize("rigorous", [False, True])
def test_every_crossing_delay_of_the_paper_loop_within_its_accuracy(rigorous: bool) -> None:
    """``U_BS2(0.1)`` up to ``delta = 3``: each crossing re-solved at 40 digits, ``|A(i w)| = |B(i w)|``,
    and each of its delays ``(arg(-B/A) mod 2 pi + 2 pi k) / w``; the stability windows printed inside
    the windows of those delays."""
    A, B = nrobust.hyperbolic.loop_factors(PAPER, nrobust.ReflectionController(0.1))
    dm = delay_margin(A, B, delta_max=3.0, rigorous=rigorous)
    fa, fb = mp_function(A), mp_function(B)
    exact = {}
    assert len(dm.crossings) == 5 and sum(len(c.delays) for c in dm.crossings) == 10
    for c in dm.crossings:
        w = mp.findroot(lambda x: abs(fa(1j * x)) ** 2 - abs(fb(1j * x)) ** 2, mp.mpf(c.omega), tol=mp.mpf(10) ** -35)
        phase = mp.arg(-fb(1j * w) / fa(1j * w)) % (2 * mp.pi)
        assert len(c.delay_accuracies) == len(c.delays)
        for k, (delay, accuracy) in enumerate(zip(c.delays, c.delay_accuracies)):
            exact[delay] = (phase + 2 * mp.pi * k) / w
            assert_true_and_tight(delay, accuracy, exact[delay])
            assert dm.end_accuracy(delay) == accuracy
    exact[0.0] = mp.mpf(0)
    assert len(dm.intervals) == 2
    for lo, hi in dm.intervals:  # (0, delta*) and a window between two later crossing delays
        text = inner_interval_text(lo, hi, 6, accuracies=(dm.end_accuracy(lo), dm.end_accuracy(hi)))
        printed_lo, printed_hi = (mp.mpf(x) for x in text.strip("()").split(", "))
        assert exact[lo] <= printed_lo < printed_hi <= exact[hi], (text, exact[lo], exact[hi])


def test_inner_interval_text_with_the_accuracies_of_its_ends() -> None:
    """Each end moved inward by its accuracy, then rounded inward (checked on the exact binary values)."""
    rng = np.random.default_rng(11)
    for _ in range(500):
        lo = float(rng.uniform(0.0, 2.0))
        hi = lo + float(10.0 ** rng.uniform(-8, 1))
        a_lo, a_hi = (float(10.0 ** rng.uniform(-16, -9)) for _ in range(2))
        text = inner_interval_text(lo, hi, 8, accuracies=(a_lo, a_hi))
        if text.endswith("(narrower than its ends' accuracy)"):
            assert hi - lo <= a_lo + a_hi * (1 + 1e-9)
            continue
        p_lo, p_hi = (Decimal(x) for x in text.strip("()").split(", "))
        assert Decimal(lo) + Decimal(a_lo) <= p_lo < p_hi <= Decimal(hi) - Decimal(a_hi), text
    # narrower than the printed resolution: more digits (up to 17), never an inverted pair
    assert inner_interval_text(1.0, 1.000000001, 6, accuracies=(1e-12, 1e-12)) == "(1.0000000001, 1.0000000009)"
    assert inner_interval_text(1.0, 1.0000000000000002, 6) == "(1.0000000000000000, 1.0000000000000002)"
    assert (
        inner_interval_text(0.5, 1.5, 6, accuracies=(0.0, None))
        == "(0.500000, 1.50000) (upper end: accuracy not estimated)"
    )
    assert inner_interval_text(0.5, 0.5 + 1e-12, 6, accuracies=(1e-12, 1e-12)).endswith(
        "(narrower than its ends' accuracy)"
    )


# ---------------------------------------------------------------------------------------- a value 0 to its accuracy
@pytest.mark.parametrize(
    ("value", "accuracy", "text"),
    [
        (0.0, 1e-20, "0 +- 1e-20"),
        (0.0, 1e-300, "0 +- 1e-300"),
        (0.0, 1e-310, "0 +- 1e-310"),
        (5.55e-17, 1.3e-15, "0 +- 2e-15"),
        (4.9e-16, 1.6e-15, "0 +- 3e-15"),  # 0 printed: the bound holds the value too (2.09e-15 was 2e-15)
        (-3e-6, 1e-3, "0 +- 2e-3"),
        (0.0, 2.5, "0 +- 3e+0"),
    ],
)
def test_a_value_zero_to_its_accuracy_prints_0(value: float, accuracy: float, text: str) -> None:
    assert with_accuracy(value, accuracy) == text
    bound = Decimal(text.split(" +- ")[1])  # every truth within it (the leading digit's rounding as above)
    assert bound >= (abs(Decimal(value)) + Decimal(accuracy)) * Decimal("0.999999999")


def test_with_accuracy_prints_a_short_value_within_half_a_unit_of_its_bound() -> None:
    """On the exact binary value (Decimal): the printed value is within half a unit of the bound's digit (or
    is the value itself), the bound is at least the accuracy (rounded up, a subnormal one too: ``3.03e-153``
    printed ``3e-153`` before), and no value prints a string of zeros."""
    rng = np.random.default_rng(5)
    for _ in range(3000):
        value = float(rng.choice([0.0, 1.0, -1.0]) * 10.0 ** rng.uniform(-30, 20))
        accuracy = float(10.0 ** rng.uniform(-320, 5))
        printed, bound = with_accuracy(value, accuracy).split(" +- ")
        assert len(printed) <= 40, (value, accuracy, printed)
        assert Decimal(bound) >= Decimal(accuracy) * Decimal("0.999999999")
        unit = Decimal("1e" + bound.split("e")[1])
        # below the double's resolution the value is printed as it is (its shortest round-trip digits)
        assert abs(Decimal(printed) - Decimal(value)) <= unit / 2 or float(printed) == value


# ---------------------------------------------------------------------------------------- the principal gap
@pytest.mark.parametrize(
    ("q", "K", "rigorous"),
    [
        (1.0, 0.15 + 1.2345e-15, False),  # gamma_0 above 1 by 1.19e-15: the gap a difference of nearly equal numbers
        (1.0, 0.15 + 1.2345e-15, True),
        (1.0, 0.15, False),  # 1 - 0.85 - 0.15 in binary: 2.8e-17, computed 0
        (1.0, 0.1, True),
        (0.7, 1.0 / 0.7 - 0.85 + 3e-15, False),  # rho q and K q rounded: the rounding bound covers them
    ],
)
def test_the_certificates_principal_gap_to_its_accuracy(q: float, K: float, rigorous: bool) -> None:
    """The gap ``1 - |rho q| - |K q|`` of ``U_BS2(K)`` (eq. (54)) in mpmath on the given doubles."""
    plant = nrobust.Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, q, 0.85)
    cert = nrobust.certify(plant, nrobust.ReflectionController(K), delta_max=0.5, k_region=False, rigorous=rigorous)
    exact = 1 - mp.mpf(0.85) * mp.mpf(q) - abs(mp.mpf(K) * mp.mpf(q))
    (claim,) = [c for c in cert.claims if c.name == "strong stability"]
    printed, bound = claim.statement.split("principal gap ")[1].rstrip(")").split(" +- ")
    assert abs(mp.mpf(printed) - exact) <= 1.5 * mp.mpf(bound), (claim.statement, exact)
    assert abs(cert.margin.gap - exact) <= cert.margin.gap_accuracy <= 1e-14
    assert cert.margin.rigorous == rigorous


# ---------------------------------------------------------------------------------------- a window of delays
@pytest.mark.parametrize("rigorous", [False, True])
def test_a_delay_window_prints_its_stability_window_and_clearance_to_their_accuracy(rigorous: bool) -> None:
    """``s^2 - 0.1 s + 1 + 0.5 e^{-delta s}``: ``|1 - w^2 - 0.1 i w| = 0.5`` is quadratic in ``w^2``; the first
    delays ``arg(-0.5 / (1 - w^2 - 0.1 i w)) / w`` (mod ``2 pi``), a stabilising ``t1`` then a destabilising
    ``t2``, in mpmath: the loop is stable on ``(t1, t2)``, which holds ``[4.7, 4.9]``."""
    from nrobust.design import window_stability

    a = QuasiPolynomial([[1.0, -0.1, 1.0]], [0.0])
    window = window_stability(a, QuasiPolynomial([[0.5]], [0.0]), (4.7, 4.9), rigorous=rigorous)
    p = 2 - mp.mpf("0.1") ** 2
    root = mp.sqrt(p**2 - 4 * (1 - mp.mpf("0.5") ** 2))
    t1, t2 = (
        (mp.arg(-mp.mpf("0.5") / (1 - u - 1j * mp.mpf("0.1") * mp.sqrt(u))) % (2 * mp.pi)) / mp.sqrt(u)
        for u in ((p - root) / 2, (p + root) / 2)
    )
    assert window.stable and window.enclosing is not None
    printed = window.reason.split("stable on the window (")[1].split(")")[0]
    lo, hi = (mp.mpf(x) for x in printed.split(", "))
    assert t1 <= lo < hi <= t2, (window.reason, t1, t2)
    exact = min(mp.mpf("4.7") - t1, t2 - mp.mpf("4.9"))
    assert window.clearance_accuracy is not None
    assert_true_and_tight(window.clearance, window.clearance_accuracy, exact)
    assert f"clearance={with_accuracy(window.clearance, window.clearance_accuracy)})" in repr(window)


def test_a_window_holding_a_crossing_delay_has_a_clearance_0_to_its_accuracy() -> None:
    """``s^2 - 0.1 s + 1 + 0.5 e^{-delta s}`` on a window holding the crossing delay ``t2`` (mpmath as above): the
    clearance 0 is not exact (``t2`` as computed may lie on either side of the window's end by its accuracy), its
    accuracy is the crossing delay's."""
    from nrobust.design import window_stability

    a = QuasiPolynomial([[1.0, -0.1, 1.0]], [0.0])
    p = 2 - mp.mpf("0.1") ** 2
    u = (p + mp.sqrt(p**2 - 4 * (1 - mp.mpf("0.5") ** 2))) / 2
    t2 = (mp.arg(-mp.mpf("0.5") / (1 - u - 1j * mp.mpf("0.1") * mp.sqrt(u))) % (2 * mp.pi)) / mp.sqrt(u)
    window = window_stability(a, QuasiPolynomial([[0.5]], [0.0]), (float(t2) - 0.1, float(t2) + 0.05))
    assert not window.stable and window.clearance == 0.0
    accuracy = window.clearance_accuracy
    assert accuracy is not None and 0.0 < accuracy < 1e-8
    assert any(abs(d - t2) <= accuracy for c in window.margin.crossings for d in c.delays)
