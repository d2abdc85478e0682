"""An output feedback whose state feedback has integral gains, on a plant with constant couplings: proofs about the PDE.

``OutputFeedback(StateFeedback(k, g_u, g_v))`` measures ``y = v(t, 0)`` and predicts the state over the window
``w = 1/mu``; its loop is ``A - G``, ``B + G`` with ``G = (1 - Phi) H``, ``H(s) = int_0^w h(nu) e^{-nu s} dnu``,
``h + N~ * h = m`` on ``[0, w]`` and ``m`` the law's kernel there: ``k U~`` plus the kernel of the integral term.
The gains' kernel on the window now enters the proven observer term with proven tails, so the proven margin,
abscissa and certificate hold for the PDE, and the scope says so.

Oracle, sharing no code with the package, at 40 digits (the structure of ``test_observer_proven``'s, rewritten):

* ``[u; v](x, s) = expm(x M(s)) [q; 1]``, ``M(s) = [[-s/lam, sigma_pm/lam], [-sigma_mp/mu, s/mu]]`` (the
  Laplace-domain solution of the PDE), so ``A = 1 - Phi = e^{-s/mu} (v(1) - rho u(1))`` and
  ``B = -e^{-s/mu} (k u(1) + int_0^1 g_u u + g_v v dx)``, the integral by ``mpmath.quad``;
* the kernels of the window (``N~``, and ``U~_x``, ``V~_x`` of the plant cut at ``x``) from their series, checked
  against the matrix exponential: ``e^{-s x/mu} u(x) = q e^{-s tau x} + int_0^{tau x} U~_x e^{-nu s}``,
  ``e^{-s x/mu} v(x) = 1 + int_0^{tau x} V~_x e^{-nu s}`` by ``mpmath.quad`` at two ``x`` and two ``s``; the
  gains' kernel ``K(theta) = g_v(1 - theta/t_v)/t_v + int_{1 - theta/t_v}^1 g_u(x) U~_x(nu) + g_v(x) V~_x(nu) dx``
  (``nu = theta - t_v (1 - x)``, ``theta < t_v``) by the change of variables of the point delays of
  ``e^{-s t_v} [u; v](x)``, its transform checked against ``e^{-s/mu} int_0^1 g_u u + g_v v dx`` on both branches;
* ``h`` by Chebyshev collocation (36 points, integrals by a 40-point Gauss-Legendre rule refined by Newton's
  method), checked against 48 points; crossings ``|A_o(i w)| = |B_o(i w)|`` and roots by ``mpmath.findroot``.

Before the change the observer term of such a law was floating point and the scope "a model of the PDE": the scope,
route and certificate tests fail there; the model's balls held the PDE's values (measured: both margin balls and the
abscissa bracket at ``delta = 0.3``), so the containment tests pass on both.
"""

from __future__ import annotations

import functools

import mpmath as mp
import numpy as np
import pytest
from _oracles import assert_balls_contain, barycentric, gauss_legendre, window_collocation

import nrobust as nr
from nrobust._flint import working_precision
from nrobust.balls import ball_function
from nrobust.hyperbolic import Hyperbolic2x2, StateFeedback
from nrobust.hyperbolic.loops.controllers import loop_route, loop_scope
from nrobust.hyperbolic.loops.exact_gains import window_series
from nrobust.hyperbolic.loops.observer_proof import proof_window, proven_observer_failure, proven_observer_term, window
from nrobust.hyperbolic.plants.general import GeneralHyperbolic2x2
from nrobust.reports.certificate import PROVEN

pytest.importorskip("flint")

DPS = 40
#: (plant, k, g_u coefficients, g_v coefficients): gains ``g(x) = c_0 + c_1 x``, stable at ``delta = 0`` with a
#: finite delay margin (the output feedback keeps the state feedback's difference operator).
SECOND = ((1.0, 2.0, 0.4, 0.5, 1.0, 0.3), -0.6, (0.0, 0.2), (0.1, 0.0))
PAPER = ((1.0, 1.0, 1.0, 1.0, 1.0, 0.85), -0.1, (0.0, -1.5), (-1.5, 0.0))


def _law(case):
    """``StateFeedback(k, g_u, g_v)`` of ``case``, the gains as callables on arrays (``g_v`` a constant)."""
    _, k, gu, gv = case
    return StateFeedback(k, g_u=lambda x: gu[0] + gu[1] * x, g_v=gv[0])


def _gain(gain, x):
    """A gain of the oracle: ``c_0 + c_1 x`` from its coefficients, or an mpmath function."""
    return gain(x) if callable(gain) else mp.mpf(gain[0]) + mp.mpf(gain[1]) * x


def _numbers(case):
    """``(lam, mu, spm, smp, q, rho, tau, t_v, t_u, p, m)`` at :data:`DPS` + 10 digits (``p = spm/lam``,
    ``m = -smp/mu``)."""
    lam, mu, spm, smp, q, rho = (mp.mpf(v) for v in case[0])
    with mp.workdps(DPS + 10):
        return lam, mu, spm, smp, q, rho, 1 / lam + 1 / mu, 1 / mu, 1 / lam, spm / lam, -smp / mu


def _state(case, x, s):
    """``[u; v](x, s) = expm(x M(s)) [q; 1]`` (``v(0) = 1``)."""
    lam, mu, spm, smp, q, *_ = _numbers(case)
    E = mp.expm(x * mp.matrix([[-s / lam, spm / lam], [-smp / mu, s / mu]]))
    return E[0, 0] * q + E[0, 1], E[1, 0] * q + E[1, 1]


def _series(case, x):
    """``nu -> (N~, U~_x, V~_x)(nu)`` on ``[0, tau x]``: ``W``, ``h_11``, ``h_22`` of the plant cut at ``x`` summed
    term by term (``a = p m / tau^2`` is the cut plant's too; ``p x / (tau x) = p / tau``)."""
    *_, q, rho, tau, _, _, p, m = _numbers(case)
    a = p * m / tau**2

    def kernels(nu):
        z = a * nu * (tau * x - nu)
        W = I1 = mp.mpf(0)
        term, k = mp.mpf(1), 0
        while True:  # term = z^k / (k!)^2
            W += term
            I1 += term / (k + 1)
            k += 1
            term *= z / (k * k)
            if abs(term) < mp.mpf(10) ** (-DPS - 10) and k > 3:
                break
        h22, h11 = a * (tau * x - nu) * I1, a * nu * I1
        return h22 - rho * q * h11 + (m * q - rho * p) / tau * W, q * h11 + p / tau * W, h22 + m * q / tau * W

    return kernels


def _K(case, theta):
    """The gains' kernel at ``theta`` in ``[0, tau]``: the point delays' parts and the sections' integral."""
    *_, q, _, _, t_v, t_u, _, _ = _numbers(case)
    _, _, gu, gv = case
    if theta < t_v:
        point, start = _gain(gv, 1 - theta / t_v) / t_v, 1 - theta / t_v
    else:
        point, start = q * _gain(gu, (theta - t_v) / t_u) / t_u, (theta - t_v) / t_u

    def integrand(x):
        _, U, V = _series(case, x)(theta - t_v * (1 - x))
        return _gain(gu, x) * U + _gain(gv, x) * V

    return point + mp.quad(integrand, [start, 1])


def _m(case, nu):
    """The law's kernel on the window: ``k U~ + K``."""
    return mp.mpf(case[1]) * _series(case, 1)(nu)[1] + _K(case, nu)


@functools.cache
def _window_kernel(case, n=36):
    """``h`` at ``n`` Chebyshev points of ``[0, w]`` and the barycentric weights: ``(I + N~ *) h = m``."""
    N = _series(case, 1)
    return window_collocation(lambda nu: N(nu)[0], lambda nu: _m(case, nu), _numbers(case)[7], n, DPS)


def _H(case, s, n=36):
    """``int_0^w h(nu) e^{-nu s} dnu`` (Gauss-Legendre, 40 points; ``h`` a polynomial of degree ``n - 1``)."""
    w = _numbers(case)[7]
    x, bary, h = _window_kernel(case, n)
    gx, gw = gauss_legendre(40, DPS)
    return w * mp.fsum(wt * mp.fdot(barycentric(x, bary, w * y), h) * mp.exp(-w * y * s) for y, wt in zip(gx, gw))


def _integral(case, s):
    """``e^{-s/mu} int_0^1 g_u u + g_v v dx`` from the matrix exponential."""
    _, _, gu, gv = case
    t_v = _numbers(case)[7]

    def f(x):
        u, v = _state(case, x, s)
        return _gain(gu, x) * u + _gain(gv, x) * v

    return mp.exp(-s * t_v) * mp.quad(f, [0, 1])


def _factors(case, s):
    """``(A_o, B_o) = (A - G, B + G)`` of the PDE (module notes)."""
    rho, t_v = _numbers(case)[5], _numbers(case)[7]
    u, v = _state(case, 1, s)
    A = mp.exp(-s * t_v) * (v - rho * u)
    B = -(mp.mpf(case[1]) * mp.exp(-s * t_v) * u + _integral(case, s))
    G = A * _H(case, s)
    return A - G, B + G


def _pde_margin(case, w0):
    """``(w, delta*)``: the crossing near ``w0`` and its first delay, at 40 digits."""
    with mp.workdps(DPS):

        def g(w):
            A, B = _factors(case, mp.mpc(0, w))
            return abs(A) ** 2 - abs(B) ** 2

        w = mp.findroot(g, mp.mpf(w0))
        A, B = _factors(case, mp.mpc(0, w))
        return w, (-mp.arg(-A / B)) % (2 * mp.pi) / w


def _plant_law(case):
    return Hyperbolic2x2(*case[0]), nr.OutputFeedback(_law(case))


# ------------------------------------------------------------------------------------------- the oracle itself
@pytest.mark.long  # 9 s: the oracle's own convergence study (make fuzz)
def test_the_oracles_kernels_are_the_pdes_and_its_collocation_has_converged():
    """The sections' series are the PDE's (their transforms are the matrix exponential's), the gains' kernel on both
    branches transforms to the integral of the gains against it, and 36 collocation points agree with 48 to 1e-30."""
    case = SECOND
    *_, q, _, tau, t_v, _, _, _ = _numbers(case)
    with mp.workdps(DPS):
        for x in (mp.mpf("0.4"), mp.mpf(1)):
            kernels = _series(case, x)
            for s in (mp.mpc(0.7, 1.3), mp.mpc(-0.2, 4.0)):
                u, v = _state(case, x, s)
                U = mp.quad(lambda nu, s=s, f=kernels: f(nu)[1] * mp.exp(-nu * s), [0, tau * x])
                V = mp.quad(lambda nu, s=s, f=kernels: f(nu)[2] * mp.exp(-nu * s), [0, tau * x])
                assert abs(mp.exp(-s * t_v * x) * u - q * mp.exp(-s * tau * x) - U) < mp.mpf(10) ** -30
                assert abs(mp.exp(-s * t_v * x) * v - 1 - V) < mp.mpf(10) ** -30
    with mp.workdps(20):  # the nested quadrature at 20 digits: a check of the formula, not of the digits
        s = mp.mpc(0.3, 2.1)
        transform = mp.quad(lambda t: _K(case, t) * mp.exp(-t * s), [0, t_v, tau])
        assert abs(transform - _integral(case, s)) < mp.mpf(10) ** -15
    with mp.workdps(DPS):
        for s in (mp.mpc(0.7, 1.3), mp.mpc(-0.2, 4.0)):
            assert abs(_H(case, s) - _H(case, s, 48)) < mp.mpf(10) ** -30


# ------------------------------------------------------------------------------------- the gains on the window
WINDOW_GAINS = [
    ((0.0, 0.2), (0.1, 0.0), lambda x: 0.2 * x, 0.1),
    (
        lambda x: 0.1 * mp.exp(x),
        lambda x: 0.3 * mp.cos(2 * x),
        lambda x: 0.1 * np.exp(x),
        lambda x: 0.3 * np.cos(2 * x),
    ),
    ((0.0, 0.0), lambda x: 0.1 * mp.sin(12 * x), 0.0, lambda x: 0.1 * np.sin(12 * x)),
]


@pytest.mark.parametrize("gains", WINDOW_GAINS, ids=["linear", "exp-cos", "sin12"])
def test_the_window_series_is_within_its_bounds_of_the_pdes_kernel(gains):
    """``window_series`` (one Taylor model per gain, orders 20 to 80) against the oracle's ``K`` on the window: the
    value within its proven bound at four points and the derivative within its bound at one (``mpmath.diff`` of the
    40-digit quadrature, allowed 1e-30 more: it agrees with the proven series to 3e-33 on the linear gains).
    Measured: errors 5e-34 and 3e-22 against bounds 1e-30 and 3e-19 (linear, exp-cos)."""
    case = (SECOND[0], SECOND[1], gains[0], gains[1])
    plant = Hyperbolic2x2(*SECOND[0])
    with working_precision(200) as fl:
        S, bound, dbound = window_series(fl, plant, gains[2], gains[3], 0.5)
        assert bool(bound < 1e-17) and bool(dbound < 1e-15)
        for theta in ("0", "0.13", "0.37", "0.49"):
            value = S(fl.arb(theta))
            with mp.workdps(DPS):
                truth = _K(case, mp.mpf(theta))
                assert abs(mp.mpf(value.mid().str(50, radius=False)) - truth) <= mp.mpf(
                    (bound + value.rad()).upper().str(5, radius=False)
                )
        slope = S.derivative()(fl.arb("0.3"))
        with mp.workdps(DPS):
            truth = mp.diff(lambda t: _K(case, t), mp.mpf("0.3"))
            allowance = (dbound + slope.rad()).upper().str(5, radius=False)
            assert abs(mp.mpf(slope.mid().str(50, radius=False)) - truth) <= mp.mpf(allowance) + mp.mpf(10) ** -30


# --------------------------------------------------------------------------------------------- the loop's claims
def test_the_loops_balls_enclose_the_pdes_loop():
    """The ball enclosure of ``A_o + B_o e^{-delta s}`` that every proof evaluates holds the PDE's loop and its
    derivative at 40 digits (``tau = 1.5``, ``w = 1/2`` exact: the loop as built is the plant's)."""
    plant, controller = _plant_law(SECOND)
    delta = 0.3
    balls = ball_function(nr.characteristic(plant, controller, delta), 53)

    def F(s):
        A, B = _factors(SECOND, s)
        return A + B * mp.exp(-mp.mpf(delta) * s)

    assert_balls_contain(balls, F, (complex(-0.5, 6.3), complex(0.3, -17.0)), (0, 1), DPS)


@pytest.mark.parametrize("case", [SECOND, PAPER], ids=["second", "paper"])
def test_the_proven_margin_holds_for_the_pde(case):
    """The route is exact, the proven delay-margin ball holds the PDE's margin (40 digits), the crossing frequency
    agrees to 1e-12, and the scope says the proofs are about the PDE itself, naming the integral gains."""
    plant, controller = _plant_law(case)
    assert loop_route(plant, controller) == "exact"
    margin = nr.delay_margin(plant, controller, rigorous=True)
    assert margin.rigorous and 0 < margin.margin < np.inf
    w, truth = _pde_margin(case, margin.omega)
    lo, hi = margin.margin_ball
    assert mp.mpf(lo) <= truth <= mp.mpf(hi)
    np.testing.assert_allclose(margin.omega, float(w), rtol=1e-12)
    assert margin.scope.startswith("the PDE itself") and "observer's term (1 - Phi) H enclosed" in margin.scope
    assert "integral gains as Taylor models" in margin.scope
    assert not margin.of_model and "model of the PDE" not in margin.scope


def test_the_proven_abscissa_holds_for_the_pdes_root():
    """At ``delta = 0.3`` (where ``G`` does not cancel) the proven abscissa's bracket and the proven box of the
    rightmost root hold the PDE's root that ``findroot`` reaches from it."""
    plant, controller = _plant_law(SECOND)
    F = nr.characteristic(plant, controller, 0.3)
    result = nr.spectral_abscissa(F, rigorous=True)
    lo, hi = result.value_bracket
    root = result.root
    with mp.workdps(DPS):

        def f(s):
            A, B = _factors(SECOND, s)
            return A + B * mp.exp(-mp.mpf(0.3) * s)

        truth = mp.findroot(f, mp.mpc(root))
    assert result.rigorous and mp.mpf(lo) <= truth.real <= mp.mpf(hi)
    x0, x1, y0, y1 = result.root_box  # the proven box of the root found holds the PDE's root
    assert mp.mpf(x0) <= truth.real <= mp.mpf(x1) and mp.mpf(y0) <= truth.imag <= mp.mpf(y1)


def test_the_certificate_holds_for_the_pde():
    """``certify(..., rigorous=True)`` end to end: the margin and abscissa claims proven, the scope the PDE's, the
    margin ball holding the PDE's margin."""
    plant, controller = _plant_law(SECOND)
    cert = nr.certify(plant, controller, delta_max=0.1, rigorous=True, k_region=False)
    claims = {c.name: c.status for c in cert.claims}
    assert claims["delay margin"] == PROVEN and claims["spectral abscissa"] == PROVEN
    assert "the PDE itself" in cert.scope and "a model of the PDE" not in cert.scope
    _, truth = _pde_margin(SECOND, cert.margin.omega)
    assert mp.mpf(cert.margin.margin_ball[0]) <= truth <= mp.mpf(cert.margin.margin_ball[1])


def test_a_window_rounded_past_the_gains_jump_is_taken_below_it():
    """``lam, mu = 0.3, 0.7``: the double ``1/mu`` lies above ``t_v = tau_d lam / (lam + mu)`` (exact), where the
    gains' kernel jumps; the proven term takes the largest double below it as the window, the scope prints that
    double, and the margin ball (width 2e-12) holds the PDE's margin (the rounding of ``tau`` and the window, 1e-16
    relative, is far inside it)."""
    case = ((0.3, 0.7, 0.4, 0.5, 1.0, 0.3), -0.6, (0.0, 0.2), (0.1, 0.0))
    plant, controller = _plant_law(case)
    gains = (controller.controller.g_u, controller.controller.g_v)
    assert proof_window(plant, gains) == np.nextafter(window(plant), 0.0) and proof_window(plant) == window(plant)
    assert loop_route(plant, controller) == "exact"
    margin = nr.delay_margin(plant, controller, rigorous=True)
    _, truth = _pde_margin(case, margin.omega)
    assert mp.mpf(margin.margin_ball[0]) <= truth <= mp.mpf(margin.margin_ball[1])
    assert margin.scope.startswith("the PDE itself")
    assert "the window 1/mu as the double 1.4285714285714284" in margin.scope


def test_a_general_plant_with_constant_coefficients_is_proven_too():
    """A ``GeneralHyperbolic2x2`` with constant coefficients: the gains' kernel with its weights on the normal form's
    window (rounded below ``t_v``), the route exact, the scope the normal form's as computed; the proven margin
    ball holds the floating-point route's margin (a consistency check: no 40-digit oracle of the general plant's
    observer here)."""
    plant = GeneralHyperbolic2x2(lam=0.3, mu=0.7, a=0.1, b=0.2, c=0.3, d=-0.2, q=0.6, rho=0.7, length=1.3)
    controller = nr.OutputFeedback(StateFeedback(-0.3, g_u=lambda x: -0.3 * x, g_v=-0.2))
    assert loop_route(plant, controller) == "exact"
    margin = nr.delay_margin(plant, controller, rigorous=True)
    assert margin.scope.startswith("the PDE itself") and "the normal form's window 1/mu as the double" in margin.scope
    floating = nr.delay_margin(plant, controller)
    assert margin.margin_ball[0] <= floating.margin <= margin.margin_ball[1]


def test_a_gain_that_one_taylor_model_does_not_reach_keeps_the_model_and_says_so():
    """``g_v = 0.1 / (1.05 - x)`` (a pole at 1.05) needs several Taylor models on ``[0, 1]`` (the state feedback's
    kernel has them) while the observer's window takes each gain as one polynomial (order up to 80): its term stays
    floating point, the route ``"observer"`` and the scope a model. ``0.1 sin(12 x)`` is one model of order 80."""
    plant = Hyperbolic2x2(*SECOND[0])
    law = StateFeedback(-0.6, g_u=0.0, g_v=lambda x: 0.1 / (1.05 - x))
    assert loop_route(plant, law) == "exact"
    reason = proven_observer_failure(plant, ("U", -0.6), (law.g_u, law.g_v))
    assert reason is not None and "one Taylor model of order 80" in reason
    wavy = StateFeedback(-0.6, g_u=0.0, g_v=lambda x: 0.1 * np.sin(12 * x))
    assert proven_observer_failure(plant, ("U", -0.6), (wavy.g_u, wavy.g_v)) is None
    controller = nr.OutputFeedback(law)
    assert loop_route(plant, controller) == "observer"
    scope = loop_scope(plant, controller, None, nr.loop_factors(plant, controller))
    assert scope.startswith("a model of the PDE")


def test_bad_gains_are_refused_before_work():
    """``gains`` must be a pair of integral gains finite on ``[0, L]``."""
    plant = Hyperbolic2x2(*SECOND[0])
    for gains in ((0.1,), [0.1, 0.2], "ab"):
        with pytest.raises(nr.ParameterError, match="gains"):
            proven_observer_term(plant, ("U", -0.6), gains)
    with pytest.raises(nr.ParameterError, match="g_v"):
        proven_observer_term(plant, ("U", -0.6), (0.0, float("nan")))
