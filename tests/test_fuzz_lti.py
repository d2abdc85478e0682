"""Property-based tests of the delay LTI layer against oracles written here, sharing no code with nrobust.

1. Step responses of random retarded (and, for a biproper plant, neutral-type) loops
   ``G(s) e^{-tau s}`` under unit feedback against a fixed-step RK4 integration of the delay
   equation in this file, with steps dividing ``tau`` so that every breakpoint is a node.
2. Scalar neutral loops ``x'(t) + c x'(t - 1) = -a x(t) - b x(t - 1) + 1`` against their
   exact solution by the method of steps, piecewise exponential polynomials in mpmath at
   40 digits.
3. :func:`~nrobust.lti.allmargin.allmargin` against python-control's ``stability_margins``
   on the degree-12 Padé model of the same loop, and the delay margins against the gain
   crossovers found here from the rational plant alone.
4. :func:`~nrobust.lti.pade.pade_error_bound` and :func:`~nrobust.lti.pade.pade_band_bound` never
   below the true error computed with mpmath.

Budget (the mechanism of ``tests/test_harness.py``): CI runs a few derandomised examples per
test (the whole file in a few seconds); ``NROBUST_FUZZ_EXAMPLES=N`` (``make fuzz``) runs
``N * weight`` random ones per test.
"""

from __future__ import annotations

import math
from fractions import Fraction
from types import SimpleNamespace

import control
import mpmath as mp
import numpy as np
import pytest
from _budget import FUZZ, budget
from hypothesis import assume, given, reject
from hypothesis import strategies as st
from numpy.typing import NDArray

from nrobust.errors import CertificationError
from nrobust.lti import DelayLTI, allmargin, delay, loop_delay_margin, step_response
from nrobust.lti.pade import pade_band_bound, pade_error_bound
from nrobust.margins import unstable_count
from nrobust.quasipoly import QuasiPolynomial

# ============================================================================ budget

pytestmark = pytest.mark.timeout(0 if FUZZ else 120)


def dyadic(lo: float, hi: float, bits: int = 3) -> st.SearchStrategy[float]:
    """Multiples of ``2^-bits`` in ``[lo, hi]``: exact in binary (and in mpmath)."""
    return st.integers(math.ceil(lo * 2**bits), math.floor(hi * 2**bits)).map(lambda k: k / 2**bits)


# ============================================================================ random plants
@st.composite
def plants(draw: st.DrawFn) -> tuple[list[float], list[float]]:
    """``(num, den)`` of a real rational plant of degree 1..3 (descending powers, ``den`` monic),
    poles anywhere in ``-3 <= Re p <= 1`` (stable or not); biproper with ``|G(inf)| <= 0.75`` at times."""
    degree = draw(st.integers(1, 3))
    poles: list[complex] = []
    while len(poles) < degree:
        if degree - len(poles) >= 2 and draw(st.booleans()):
            re, im = draw(dyadic(-3.0, 1.0)), draw(dyadic(0.25, 3.0))
            poles += [complex(re, im), complex(re, -im)]
        else:
            poles.append(complex(draw(dyadic(-3.0, 1.0)), 0.0))
    den = [float(c) for c in np.real(np.poly(poles))]
    num = [draw(dyadic(-2.0, 2.0)) for _ in range(degree)]
    lead = draw(dyadic(-0.75, 0.75)) if draw(st.booleans()) else 0.0
    num = [lead, *num]
    assume(any(num))
    return num, den


def companion(num: list[float], den: list[float]) -> tuple[NDArray, NDArray, NDArray, float]:
    """Controllable canonical realisation ``(A, B, C, D)`` of ``num/den`` (``den`` monic, ``deg num <= deg den``)."""
    n = len(den) - 1
    num = [0.0] * (n + 1 - len(num)) + list(num)
    d = num[0]
    rest = np.array(num[1:]) - d * np.array(den[1:])  # num - d den, degree < n, descending
    A = np.zeros((n, n))
    A[:-1, 1:] = np.eye(n - 1)
    A[-1, :] = -np.array(den[1:])[::-1]
    B = np.zeros(n)
    B[-1] = 1.0
    return A, B, rest[::-1].copy(), d


# ============================================================================ 1. retarded loops vs RK4
def rk4_closed_loop(num: list[float], den: list[float], tau: float, per_delay: int, horizon: int) -> NDArray:
    """Unit step response of ``y = G e^{-tau s} (1 - y)`` at the nodes ``k tau / per_delay``,
    ``k = 0 .. horizon per_delay`` (right limits), by RK4 on
    ``x' = A x + B w``, ``y = C x + D w``, ``w(t) = e(t - tau)``, ``e = 1 - y``, ``e = 0`` before 0.

    The step ``h = tau / per_delay`` makes every breakpoint ``k tau`` a node, so ``w`` is smooth
    on each step; its values at ``t_k``, ``t_k + h/2``, ``t_k + h`` are the one-sided values
    stored for the step ``per_delay`` earlier, whose midpoint state comes from the cubic
    Hermite interpolant (error ``O(h^4)``, as RK4's).
    """
    A, B, C, D = companion(num, den)
    h = tau / per_delay
    steps = horizon * per_delay
    x = np.zeros(A.shape[0])
    stored = np.zeros((steps, 3))  # e(t_k+), e(t_k + h/2), e(t_{k+1}-) per step
    out = np.empty(steps + 1)
    for k in range(steps):
        wl, wm, wr = stored[k - per_delay] if k >= per_delay else (0.0, 0.0, 0.0)
        k1 = A @ x + B * wl
        k2 = A @ (x + 0.5 * h * k1) + B * wm
        k3 = A @ (x + 0.5 * h * k2) + B * wm
        k4 = A @ (x + h * k3) + B * wr
        x_new = x + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        f_new = A @ x_new + B * wr
        x_mid = 0.5 * (x + x_new) + h / 8.0 * (k1 - f_new)
        yl, ym, yr = C @ x + D * wl, C @ x_mid + D * wm, C @ x_new + D * wr
        stored[k] = (1.0 - yl, 1.0 - ym, 1.0 - yr)
        out[k] = yl
        x = x_new
    wl = stored[steps - per_delay][0]
    out[steps] = C @ x + D * wl
    return out


@given(plant=plants(), tau=dyadic(0.25, 2.0) | st.floats(0.25, 2.0), horizon=st.integers(2, 4))
@budget(ci=4, weight=0.5)
def test_step_response_of_random_delay_loops_matches_rk4(
    plant: tuple[list[float], list[float]], tau: float, horizon: int
) -> None:
    """Closed loop ``G e^{-tau s} / (1 + G e^{-tau s})``: nrobust's step response at the nodes
    ``k tau / 8`` against RK4 at ``h`` and ``h / 2``. Tolerance: ``max |y_h - y_{h/2}|`` over the run
    (about 15 times the error of ``y_{h/2}`` for a fourth-order method, the oracle's own
    convergence) plus ``1e-8`` of the scale (nrobust's ``rtol = 1e-10`` per piece, summed)."""
    num, den = plant
    per_delay = 8 * max(1, math.ceil(tau / 0.02 / 8))  # h <= 0.02 and a multiple of the output spacing
    coarse = rk4_closed_loop(num, den, tau, per_delay, horizon)
    fine = rk4_closed_loop(num, den, tau, 2 * per_delay, horizon)[::2]
    stride = per_delay // 8
    coarse, fine = coarse[::stride], fine[::stride]
    times = tau * np.arange(coarse.size) / 8.0
    G = DelayLTI.from_control(control.tf(num, den))
    closed = (G * delay(tau)).feedback(1)
    got = step_response(closed, times).outputs
    scale = 1.0 + float(np.max(np.abs(fine)))
    oracle_error = float(np.max(np.abs(coarse - fine)))
    assume(oracle_error < 1e-4 * scale)  # the oracle is in its asymptotic regime
    np.testing.assert_allclose(got, fine, rtol=0.0, atol=oracle_error + 1e-8 * scale)


# ============================================================================ 2. neutral loops vs exact steps
def exact_neutral(a: float, b: float, c: float, x0: float, intervals: int) -> list[tuple[mp.mpf, list[mp.mpf]]]:
    """Exact solution of ``d/dt [x(t) + c x(t - 1)] = -a x(t) - b x(t - 1) + 1``, ``x = 0`` before 0,
    ``x(0) = x0`` (``a != 0``), as ``x(k + s) = P_k + E_k(s) e^{-a s}`` on ``0 <= s < 1``
    (``P_k`` a constant, ``E_k`` a polynomial in ascending powers), by the method of steps:

    ``q_k = x_k + c x_{k-1}`` solves ``q' = -a q + (a c - b) x_{k-1}(s) + 1``, so
    ``q_k = g/a + (H(s) + K) e^{-a s}`` with ``g = (a c - b) P_{k-1} + 1``, ``H' = (a c - b) E_{k-1}``,
    ``H(0) = 0``, and ``K`` from the continuity of ``q`` (``q_0(0) = x0``, ``q_k(0) = q_{k-1}(1)``).
    """
    A, Bc, Cc = mp.mpf(a), mp.mpf(b), mp.mpf(c)
    r = A * Cc - Bc
    pieces: list[tuple[mp.mpf, list[mp.mpf]]] = []
    P_prev, E_prev = mp.mpf(0), [mp.mpf(0)]
    q_start = mp.mpf(x0)
    for _ in range(intervals):
        g = r * P_prev + 1
        H = [mp.mpf(0)] + [r * e / (j + 1) for j, e in enumerate(E_prev)]
        K = q_start - g / A
        E_q = [H[0] + K, *H[1:]]  # q_k = g/a + E_q(s) e^{-a s}
        P = g / A - Cc * P_prev
        E = [eq - Cc * (E_prev[j] if j < len(E_prev) else 0) for j, eq in enumerate(E_q)]
        pieces.append((P, E))
        # q_k(1) starts the next interval
        q_start = g / A + mp.polyval(E_q, 1, asc=True) * mp.exp(-A)
        P_prev, E_prev = P, E
    return pieces


def evaluate_pieces(pieces: list[tuple[mp.mpf, list[mp.mpf]]], a: float, t: Fraction) -> mp.mpf:
    """``x(t)`` (the right limit at an integer ``t``) from :func:`exact_neutral`."""
    k = math.floor(t)
    s = mp.mpf(t.numerator) / t.denominator - k
    P, E = pieces[k]
    return P + mp.polyval(E, s, asc=True) * mp.exp(-mp.mpf(a) * s)


@given(
    a=dyadic(-1.0, 3.0).filter(lambda v: abs(v) >= 0.25),
    b=dyadic(-3.0, 3.0),
    c=dyadic(-0.96875, 0.96875, bits=5),
    x0=dyadic(-2.0, 2.0),
    intervals=st.integers(2, 5),
)
@budget(ci=5, weight=1.0)
def test_neutral_scalar_loop_matches_the_exact_method_of_steps(
    a: float, b: float, c: float, x0: float, intervals: int
) -> None:
    """LFT form with ``q = x + c x(t - 1)``: ``q' = -a q + (a c - b) w + u``, ``x = q - c w``,
    ``w(t) = x(t - 1)``; the step response from ``q(0) = x0`` at times ``k/8`` (breakpoints
    included, right limits, where ``x`` jumps by ``-c`` times the previous jump) against
    :func:`exact_neutral`. Tolerance ``1e-8`` of the scale: nrobust's per-piece ``rtol = 1e-10``
    summed over at most a few hundred pieces; the oracle is exact to 40 digits."""
    sys = SimpleNamespace(
        A=[[-a]], B1=[[1.0]], B2=[[a * c - b]], C1=[[1.0]], C2=[[1.0]],
        D11=[[0.0]], D12=[[-c]], D21=[[0.0]], D22=[[-c]], tau=[1.0],
    )  # fmt: skip
    eighths = [Fraction(k, 8) for k in range(8 * intervals)]
    got = step_response(sys, [float(t) for t in eighths], X0=[x0]).outputs
    with mp.workdps(40):
        pieces = exact_neutral(a, b, c, x0, intervals)
        want = np.array([float(evaluate_pieces(pieces, a, t)) for t in eighths])
    scale = 1.0 + float(np.max(np.abs(want)))
    np.testing.assert_allclose(got, want, rtol=0.0, atol=1e-8 * scale)


# ============================================================================ 3. allmargin vs Padé(12) model
PADE_ORDER = 12
# Crossings compared where Padé(12) is accurate; none may fall near the edge (or near the gain floor).
Y_MAX, Y_EDGE = 5.0, 0.1


def pade12_error(y: float) -> float:
    """``|e^{-i y} - R_{12,12}(i y)| <= y^25 12!^2 / (24! 25! |Q_{12,12}(i y)|)``: the remainder
    integral of the approximant (``|e^{-i t y}| = 1`` under it; Baker and Graves-Morris, sec. 1.2),
    ``Q`` from :func:`pade_coefficients`; about ``6e-15`` at ``y = 5``."""
    m = PADE_ORDER
    _, q = pade_coefficients(m, m)
    q_abs = float(abs(np.polyval([float(c) for c in reversed(q)], 1j * y)))
    return y ** (2 * m + 1) * math.factorial(m) ** 2 / (math.factorial(2 * m) * math.factorial(2 * m + 1) * q_abs)


def loop_value(num: list[float], den: list[float], tau: float, w: float) -> tuple[complex, complex]:
    """``L(i w)`` and ``dL/dw`` for ``L = G e^{-tau s}``."""
    s = 1j * w
    g = np.polyval(num, s) / np.polyval(den, s)
    dg = (
        np.polyval(np.polyder(num), s) * np.polyval(den, s) - np.polyval(num, s) * np.polyval(np.polyder(den), s)
    ) / np.polyval(den, s) ** 2
    e = np.exp(-tau * s)
    return complex(g * e), complex(1j * (dg * e - tau * g * e))


def gain_crossovers(num: list[float], den: list[float]) -> NDArray:
    """Every ``w > 0`` with ``|N(i w)| = |D(i w)|``: positive real roots of ``|D(i w)|^2 - |N(i w)|^2``,
    a real polynomial in ``w`` (``numpy.roots``, polished by Newton's method)."""

    def square_modulus(p: list[float]) -> NDArray:
        re = np.array([np.real(c * 1j**k) for k, c in enumerate(p[::-1])])  # p(i w) = sum p_k (i w)^k
        im = np.array([np.imag(c * 1j**k) for k, c in enumerate(p[::-1])])
        return np.polyadd(np.polymul(re[::-1], re[::-1]), np.polymul(im[::-1], im[::-1]))

    gap = np.polysub(square_modulus(den), square_modulus(num))
    gap = np.trim_zeros(gap, "f")
    roots = np.roots(gap)
    dgap = np.polyder(gap)
    found = []
    for r in roots:
        if abs(r.imag) < 1e-6 * (1 + abs(r)) and r.real > 1e-9:
            w = r.real
            for _ in range(3):
                w -= np.polyval(gap, w) / np.polyval(dgap, w)
            found.append(w)
    return np.array(sorted(found))


def closed_loop_count(num: list[float], den: list[float], delay_value: float) -> int | None:
    """Certified number of closed-loop poles with ``Re s > 0`` of ``den + num e^{-delay s}`` (None if undecided)."""
    F = QuasiPolynomial([np.array(den[::-1]), np.array(num[::-1])], [0.0, delay_value])
    count = unstable_count(F)
    return count.count if count.certified else None


@st.composite
def margin_loops(draw: st.DrawFn) -> tuple[list[float], list[float], float]:
    """A plant with ``|G(inf)| <= 0.5`` and a delay, its gain crossovers all at ``w tau <= Y_MAX - Y_EDGE``."""
    num, den = draw(plants())
    num = list(num)
    if abs(num[0]) > 0.5:
        num[0] = 0.5 * np.sign(num[0])
    k = draw(dyadic(0.25, 4.0))
    num = [k * v for v in num] if abs(k * num[0]) <= 0.5 else num
    # no cancellation of a pole by a zero (python-control's margins then divide 0 by 0)
    assume(all(abs(np.polyval(num, p)) > 1e-9 for p in np.roots(den)))
    # poles and zeros on the axis are left to the two tests below
    axis = [r for r in np.concatenate([np.roots(den), np.roots(num)]) if abs(r.real) < 1e-12 < abs(r.imag)]
    assume(not axis)
    tau = draw(dyadic(0.125, 2.0))
    wc = gain_crossovers(num, den)
    assume(all(w * tau < Y_MAX - Y_EDGE for w in wc))
    return num, den, tau


@given(loop=margin_loops())
@budget(ci=4, weight=0.5)
def test_allmargin_matches_python_control_on_the_pade_model(loop: tuple[list[float], list[float], float]) -> None:
    """Crossover frequencies and margins against ``control.stability_margins(returnall=True)`` of
    ``G * pade(tau, 12)``; delay margins against the crossovers of ``|N| = |D|`` found here and
    a certified root count at ``tau + DM (1 -+ 1e-3)``.

    Tolerances. The diagonal approximant is all-pass (``|R(i y)| = 1``), so the model's gain
    crossovers are the loop's; its phase is off by ``<= 2 asin(eps/2)`` with ``eps`` of
    :func:`pade12_error` (``< 1e-14`` on ``w tau <= 5.1``). python-control finds its crossings as
    polynomial roots: the accuracy of each is its residual (``|L| - 1``, or the phase residual
    ``asin(|Im L| / |L|)``, evaluated here on the exact loop) divided by the slope in ``w``. The
    allowance on a frequency is ten times residual/slope, plus (phase crossovers) the Padé phase
    error over the phase slope, plus ``1e-9 (1 + w)`` (allmargin's Brent tolerance is
    ``1e-12 (1 + w)``); margins move by their ``w``-derivative times it (plus ``eps`` in the
    phase). Near-tangent crossings (slope below ``1e-3 (1 + w)``) are ill-posed for both and skipped."""
    num, den, tau = loop
    G = control.tf(num, den)
    pnum, pden = control.pade(tau, PADE_ORDER)
    model = G * control.tf(pnum, pden)
    L = DelayLTI.from_control(G) * delay(tau)
    high = abs(num[0]) if len(num) == len(den) else 0.0  # |G(inf)|
    try:
        got = allmargin(L, gain_floor=max(1e-2, 2.0 * high))
    except CertificationError:
        reject()  # an honest refusal (a loop within rounding of a degenerate one, e.g. |L(0)| = 1)
    gm, pm, _sm, w180, wc, _ws = control.stability_margins(model, returnall=True)
    gm, pm, w180, wc = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (gm, pm, w180, wc))

    def allowance(w: float, residual: float, slope: float, phase_error: float) -> float:
        return (10.0 * abs(residual) + phase_error) / abs(slope) + 1e-9 * (1.0 + w)

    def slopes(w: float) -> tuple[complex, float, float]:
        """``L(i w)``, ``d|L|/dw`` and ``d arg L/dw``."""
        Lw, dL = loop_value(num, den, tau, w)
        return Lw, float(np.real(np.conj(Lw) * dL) / abs(Lw)), float(np.imag(dL / Lw))

    # well-conditioned crossings only: |L| and arg L cross 1 and -180 deg transversally
    assume(all(abs(slopes(w)[1]) > 1e-3 * (1 + w) for w in wc[wc * tau < Y_MAX + Y_EDGE]))
    # and those found here (|L| touching 1, e.g. 1.25 s/(s^2 + 1.25 s + 0.453125) at w^2 = 0.453125, is a tangency
    # that allmargin lists with its accuracy and python-control's roots miss)
    assume(
        all(abs(slopes(w)[1]) > 1e-3 * (1 + w) for w in got.pm_frequencies[got.pm_frequencies * tau < Y_MAX + Y_EDGE])
    )
    assume(all(abs(slopes(w)[2]) > 1e-3 * (1 + w) for w in w180[(w180 > 0) & (w180 * tau < Y_MAX + Y_EDGE)]))

    # gain crossovers and phase margins: the model's are the loop's (all-pass Padé), PM off by its phase error
    keep = wc * tau < Y_MAX
    want_wc, want_pm = wc[keep], pm[keep]
    assert got.pm_frequencies.size == want_wc.size, (got.pm_frequencies, want_wc)
    for w_got, p_got, w_ref, p_ref in zip(got.pm_frequencies, got.phase_margins, want_wc, want_pm, strict=True):
        Lw, slope, phase_slope = slopes(w_ref)
        tol_w = allowance(w_ref, abs(Lw) - 1.0, slope, 0.0)
        np.testing.assert_allclose(w_got, w_ref, rtol=0.0, atol=tol_w)
        tol_pm = math.degrees(abs(phase_slope) * tol_w + 2.0 * pade12_error(w_ref * tau)) + 1e-7
        np.testing.assert_allclose((p_got - p_ref + 180.0) % 360.0 - 180.0, 0.0, atol=tol_pm)

    # phase crossovers and gain margins, w > 0, on the band where Padé(12) is accurate: each of the
    # model's with |L| >= gain_floor is listed (allmargin's completeness), each listed one is the model's
    edge = np.abs(w180 * tau - Y_MAX) < Y_EDGE
    edge |= (np.abs(1.0 / gm - got.gain_floor) < 1e-4 * got.gain_floor) & (w180 * tau < Y_MAX)
    assume(not np.any(edge))
    band = (w180 > 0) & (w180 * tau < Y_MAX)
    mine = (got.gm_frequencies > 0) & (got.gm_frequencies * tau < Y_MAX)
    required = band & (1.0 / gm >= got.gain_floor)
    pairs = [
        (w, g, got.gm_frequencies[mine], got.gain_margins[mine], True)
        for w, g in zip(w180[required], gm[required], strict=True)
    ]
    pairs += [
        (w, g, w180[band], gm[band], False)
        for w, g in zip(got.gm_frequencies[mine], got.gain_margins[mine], strict=True)
    ]
    for w_ref, g_ref, others, other_gm, ref_is_model in pairs:
        assert others.size, (w_ref, got.gm_frequencies, w180)
        j = int(np.argmin(np.abs(others - w_ref)))
        w_model = float(w_ref if ref_is_model else others[j])
        Lw, slope, phase_slope = slopes(w_model)
        eps = 2.0 * math.asin(min(1.0, pade12_error(w_model * tau) / 2.0))
        tol_w = allowance(w_ref, math.asin(min(1.0, abs(Lw.imag) / abs(Lw))), phase_slope, eps)
        np.testing.assert_allclose(others[j], w_ref, rtol=0.0, atol=tol_w)
        log_slope = slope / abs(Lw)  # d ln|L| / dw
        np.testing.assert_allclose(other_gm[j], g_ref, rtol=abs(log_slope) * tol_w + 1e-9)

    # delay margins: every gain crossover of the rational plant, the phase taken on the exact loop
    crossings = gain_crossovers(num, den)
    phases = np.array([np.mod(np.angle(-loop_value(num, den, tau, w)[0]), 2.0 * np.pi) for w in crossings])
    want_dm = phases / crossings if crossings.size else np.zeros(0)
    np.testing.assert_allclose(got.dm_frequencies, crossings, rtol=1e-9)
    np.testing.assert_allclose(got.delay_margins, want_dm, rtol=1e-8, atol=1e-10)
    # w = 0 is a phase crossover iff L(0) = N(0)/D(0) < 0
    if den[-1] != 0.0 and num[-1] / den[-1] < 0.0:
        assert got.gm_frequencies.size and got.gm_frequencies[0] == 0.0, got.gm_frequencies
        np.testing.assert_allclose(got.gain_margins[0], abs(den[-1] / num[-1]), rtol=1e-12)
    else:
        assert not np.any(got.gm_frequencies == 0.0), got.gm_frequencies
    nominal = closed_loop_count(num, den, tau)
    assume(nominal is not None)
    assert got.stable == (nominal == 0), (got.stable, nominal)
    margin = loop_delay_margin(L).margin
    if nominal:
        assert margin == 0.0
    elif crossings.size == 0:
        assert margin == math.inf
    else:
        dm = float(np.min(want_dm))
        np.testing.assert_allclose(margin, dm, rtol=1e-8)
        before, after = (
            closed_loop_count(num, den, tau + dm * (1 - 1e-3)),
            closed_loop_count(num, den, tau + dm * (1 + 1e-3)),
        )
        assume(before is not None and after is not None)
        assert before == 0 and after is not None and after >= 1, (before, after)


def test_allmargin_with_an_undamped_oscillator_in_the_loop() -> None:
    """A pole pair on the axis (``+-i/4``): the loop gain is infinite there, not a phase crossover.

    ``L(i w) = e^{-i w/8} / (32 (1/16 - w^2))`` is a negative real number exactly at ``w = 16 pi k``,
    ``k >= 1`` (``w > 1/4``, ``e^{-i w/8} = 1``; below ``1/4`` it would need ``w = 8 pi (2k + 1)``). There
    ``|L| < 1.3e-5``, hence ``gain_floor=1e-6``: each is listed iff it lies in the band (the first three,
    gm 80849.80 at ``w = 50.26548`` as python-control's ``stability_margins`` of the Padé(12) model). The
    pole itself (where that model gives gm ~ 8e-16 at ``w = 0.25``, a jump of the phase, not a crossover) is
    not listed, and no division by ``D(i/4) = 0`` warns.
    """
    num, den, tau = [0.03125], [1.0, 0.0, 0.0625], 0.125
    got = allmargin(DelayLTI.from_control(control.tf(num, den)) * delay(tau), gain_floor=1e-6)
    expected = [16 * math.pi * k for k in range(1, 100) if 16 * math.pi * k < got.phase_band]
    assert len(expected) >= 1, got.phase_band
    np.testing.assert_allclose(got.gm_frequencies, expected, rtol=1e-10)  # Brent's xtol 1e-12 (1 + w)
    np.testing.assert_allclose(got.gain_margins, [32 * (w * w - 0.0625) for w in expected], rtol=1e-10)


def test_allmargin_with_a_loop_zero_on_the_axis() -> None:
    """A zero pair of the loop on the axis (``+-i sqrt 3``): ``L = 0`` there, not a negative real number.

    Oracle: python-control's ``stability_margins`` of the Padé(12) model (Padé error ~1e-20 at these
    ``w tau < 2``), phase crossovers ``w = 0.430928`` (gm 1.585916) and ``w = 13.02699`` (gm 424.56,
    ``|L| < 1e-2``: listed with ``gain_floor=1e-3``), quoted to 6 and 7 digits, hence ``rtol=2e-6``.
    """
    num, den, tau = [0.03125, 0.0, 0.09375], [1.0, 0.75, 0.203125, 0.0], 0.125
    L = DelayLTI.from_control(control.tf(num, den)) * delay(tau)
    got = allmargin(L)
    assert np.all(np.abs(got.gm_frequencies - math.sqrt(3.0)) > 1e-6), (got.gm_frequencies, got.gain_margins)
    np.testing.assert_allclose(got.gm_frequencies, [0.430928], rtol=2e-6)
    np.testing.assert_allclose(got.gain_margins, [1.585916], rtol=2e-6)
    deep = allmargin(L, gain_floor=1e-3)
    np.testing.assert_allclose(deep.gm_frequencies, [0.430928, 13.02699], rtol=2e-6)
    np.testing.assert_allclose(deep.gain_margins, [1.585916, 424.56], rtol=2e-5)


# ============================================================================ 4. Padé error bound vs mpmath
def pade_coefficients(m: int, n: int) -> tuple[list[Fraction], list[Fraction]]:
    """``P_{m,n}``, ``Q_{m,n}`` of ``e^{-z}``, ascending (Baker and Graves-Morris, *Padé Approximants*, sec. 1.2)."""
    top = math.factorial(m + n)
    p = [
        Fraction(
            (-1) ** j * math.factorial(m + n - j) * math.factorial(m), top * math.factorial(j) * math.factorial(m - j)
        )
        for j in range(m + 1)
    ]
    q = [
        Fraction(math.factorial(m + n - j) * math.factorial(n), top * math.factorial(j) * math.factorial(n - j))
        for j in range(n + 1)
    ]
    return p, q


def true_pade_error(tau: float, m: int, n: int, w: float) -> mp.mpf:
    """``|e^{-i w tau} - P(i w tau)/Q(i w tau)|`` to 40 significant digits: the working precision
    adds the digits of the largest term of ``P`` and ``Q`` and those of the leading remainder
    ``|y|^{m+n+1} m! n! / ((m+n)! (m+n+1)!)`` below 1 (the cancellation of ``e^{-z}`` against ``R``)."""
    p, q = pade_coefficients(m, n)
    y = Fraction(tau) * Fraction(w)
    extra = 0
    if y != 0:
        log_y = math.log10(abs(y.numerator)) - math.log10(y.denominator)  # exact: |y| may underflow a float
        logs = [
            math.log10(abs(c.numerator)) - math.log10(c.denominator) + j * log_y
            for cs in (p, q)
            for j, c in enumerate(cs)
        ]
        lead = (m + n + 1) * log_y * math.log(10) + math.lgamma(m + 1) + math.lgamma(n + 1)
        lead -= math.lgamma(m + n + 1) + math.lgamma(m + n + 2)
        extra = max(0, math.ceil(max(logs))) + max(0, math.ceil(-lead / math.log(10)))
    with mp.workdps(40 + 10 + extra):
        z = mp.mpc(0, mp.mpf(y.numerator) / y.denominator)
        P = mp.polyval([mp.mpf(c.numerator) / c.denominator for c in p], z, asc=True)
        Q = mp.polyval([mp.mpf(c.numerator) / c.denominator for c in q], z, asc=True)
        return abs(mp.exp(-z) - P / Q)


@given(
    tau=st.floats(1e-3, 50.0),
    m=st.integers(0, 20) | st.integers(21, 80),
    n=st.integers(0, 20) | st.integers(21, 80),
    w=st.floats(0.0, 200.0) | st.floats(1e-6, 1.0) | st.floats(200.0, 1e4),
)
@budget(ci=25, weight=2.0)
def test_pade_error_bound_is_never_below_the_true_error(tau: float, m: int, n: int, w: float) -> None:
    """The bound is a proven upper bound rounded up: the 40-digit true error may not exceed it."""
    bound = float(pade_error_bound(tau, m, n, [w])[0])
    truth = true_pade_error(tau, m, n, w)
    assert truth <= bound, (tau, m, n, w, float(truth), bound)


@given(
    tau=st.floats(1e-3, 10.0),
    m=st.integers(0, 16),
    n=st.integers(0, 16),
    omega_max=st.floats(1e-3, 50.0),
    where=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=4),
    cells=st.integers(1, 64),
)
@budget(ci=8, weight=0.5)
def test_pade_band_bound_covers_every_frequency_of_the_band(
    tau: float, m: int, n: int, omega_max: float, where: list[float], cells: int
) -> None:
    """The band bound holds at any frequency of ``[0, omega_max]``, cell ends and interiors alike."""
    bound = pade_band_bound(tau, m, n, omega_max, cells=cells)
    for w in [omega_max, *(f * omega_max for f in where), omega_max * (1 - 0.5 / cells)]:
        truth = true_pade_error(tau, m, n, min(w, omega_max))
        assert truth <= bound, (tau, m, n, omega_max, cells, w, float(truth), bound)
