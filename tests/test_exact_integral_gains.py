"""State feedbacks with integral gains on plants with constant coefficients: the exact loop.

Oracles share no code with :mod:`nrobust.hyperbolic.loops.exact_gains`: the Laplace-domain state
``[u; v](x, s) = exp(x M(s)) [q; 1]`` by the closed form ``e^{tr/2} (cosh D I + sinh(D)/D (M - tr/2 I))``
of a 2x2 exponential, the integral ``int_0^L g_u u + g_v v dx`` by mpmath's Gauss-Legendre
quadrature at 40 digits, and the crossing equations ``|A(i w)| = |B(i w)|`` by
``mpmath.findroot``; the kernel route (backstepping kernels on grids of 101 to 401 points,
Simpson's rule) and the Magnus route of :func:`~nrobust.hyperbolic.loops.feedback.laplace_loop_factors`
are independent numerical models converging to the same loop.
"""

from __future__ import annotations

import time

import mpmath as mp
import numpy as np
import pytest

import nrobust as nr
from nrobust.hyperbolic import GeneralHyperbolic2x2, Hyperbolic2x2, OutputFeedback, StateFeedback
from nrobust.hyperbolic.loops.controllers import loop_factors, loop_route, loop_scope
from nrobust.hyperbolic.loops.exact_gains import gain_failure, gain_kernel
from nrobust.hyperbolic.loops.feedback import laplace_loop_factors

flint = pytest.importorskip("flint")

# Speeds with dyadic 1/lam, 1/mu: tau and t_v are the plant's own (no rounding), so ball
# enclosures must contain the 40-digit values.
STABLE = (1.0, 1.0, 0.5, 0.5, 0.5, 0.5)
FAST_U = (2.0, 0.5, -1.5, 3.0, 0.3, -0.4)
UNCOUPLED = (1.0, 1.0, 0.0, 0.0, 0.5, 0.5)


def law():
    """``U = -1.2 u(t, 1) - int x u + 0.5 e^{-x} v dx``: on STABLE, margin 0.6589 at w = 1.306."""
    return StateFeedback(-1.2, lambda x: -x, lambda x: -0.5 * np.exp(-x))


def smooth_law():
    return StateFeedback(0.3, lambda x: 0.3 + 0.2 * x**2, lambda x: 0.1 * np.cos(3.0 * x))


def _expm2(M):
    """``exp(M)`` of a 2x2 mpmath matrix by ``e^{tr/2} (cosh D I + sinh(D)/D (M - tr/2 I))``."""
    half = (M[0, 0] + M[1, 1]) / 2
    D = mp.sqrt(((M[0, 0] - M[1, 1]) / 2) ** 2 + M[0, 1] * M[1, 0])
    sinhc = mp.sinh(D) / D if D != 0 else mp.mpf(1)
    e = mp.exp(half)
    return [
        [e * (mp.cosh(D) + sinhc * (M[0, 0] - half)), e * sinhc * M[0, 1]],
        [e * sinhc * M[1, 0], e * (mp.cosh(D) + sinhc * (M[1, 1] - half))],
    ]


def _pde_factors(plant, k, g_u, g_v, s, length=1.0, unit=1.0):
    """``(A, B)`` of the PDE at ``s`` at 40 digits: ``e^{D(L)} e^{-s t_v} (v(L) - rho u(L))`` and
    ``-e^{D(L)} e^{-s t_v} (k u(L) + int_0^L g_u u + g_v v dx)`` (``plant``: the coefficients
    ``lam, mu, a, b, c, d, q, rho`` of ``d/dx [u; v] = [[(a - s)/lam, b/lam], [-c/mu, (s - d)/mu]] [u; v]``)."""
    lam, mu, a, b, c, d, q, rho = (mp.mpf(v) for v in plant)
    with mp.workdps(40):
        se = mp.mpc(s) / unit
        M = mp.matrix([[(a - se) / lam, b / lam], [-c / mu, (se - d) / mu]])
        L = mp.mpf(length)
        norm = mp.exp(d * L / mu - se * L / mu)

        def state(x):
            E = _expm2(M * x)
            return E[0][0] * q + E[0][1], E[1][0] * q + E[1][1]

        def integrand(x):
            u, v = state(x)
            return g_u(x) * u + g_v(x) * v

        uL, vL = state(L)
        integral = mp.quad(integrand, [0, L / 2, L], method="gauss-legendre")
        return norm * (vL - rho * uL), -norm * (k * uL + integral)


def _paper(args):
    """The paper's plant as the coefficients of :func:`_pde_factors` (``a = d = 0``, ``b, c = sigma_pm, sigma_mp``)."""
    lam, mu, spm, smp, q, rho = args
    return (lam, mu, 0.0, spm, smp, 0.0, q, rho)


MP_GAINS = {
    "law": (lambda x: -x, lambda x: -mp.mpf(1) / 2 * mp.exp(-x)),
    "smooth": (lambda x: mp.mpf("0.3") + mp.mpf("0.2") * x**2, lambda x: mp.mpf("0.1") * mp.cos(3 * x)),
}


def _check_against_the_pde(args, controller, gains, points):
    """``A``, ``B`` within 1e-13 of the 40-digit PDE values, and the balls of the proofs contain them."""
    from nrobust.balls import ball_eval

    plant = Hyperbolic2x2(*args)
    assert loop_route(plant, controller) == "exact"
    A, B = loop_factors(plant, controller)
    g_u, g_v = MP_GAINS[gains]
    for s in points:
        a_true, b_true = _pde_factors(_paper(args), controller.k, g_u, g_v, s)
        np.testing.assert_allclose(A(s), complex(a_true), rtol=0, atol=1e-13)
        np.testing.assert_allclose(B(s), complex(b_true), rtol=0, atol=1e-13)
        ball = ball_eval(B, flint.acb(s.real, s.imag))
        assert ball.real.rad() < 1e-11 and ball.imag.rad() < 1e-11
        assert float(ball.real.lower()) <= float(b_true.real) <= float(ball.real.upper())
        assert float(ball.imag.lower()) <= float(b_true.imag) <= float(ball.imag.upper())


@pytest.mark.parametrize(
    ("args", "controller", "gains"),
    [(STABLE, law(), "law"), (FAST_U, smooth_law(), "smooth"), (UNCOUPLED, smooth_law(), "smooth")],
)
def test_exact_loop_is_the_pde_and_its_balls_contain_it(args, controller, gains):
    """Measured differences of ``B`` to the PDE 0 to 2.2e-16; the loop is the PDE's, not a model."""
    _check_against_the_pde(args, controller, gains, (0.3 + 2j, 7j, -0.5 + 40j))


@pytest.mark.long
def test_exact_loop_is_the_pde_at_high_frequency():
    """At ``s = 0.01 + 300i`` (6 s of 40-digit quadrature): measured 1e-18."""
    _check_against_the_pde(FAST_U, smooth_law(), "smooth", (0.01 + 300j,))


def test_the_uncoupled_loop_in_closed_form():
    """No coupling: ``B = -q e^{-s/mu} (k e^{-s/lam} + g_u lam (1 - e^{-s/lam}) / s) - g_v mu (1 - e^{-s/mu}) / s``."""
    plant = Hyperbolic2x2(*UNCOUPLED)
    k, gu, gv, q = -0.4, 0.7, -0.3, 0.5
    _, B = loop_factors(plant, StateFeedback(k, gu, gv))
    s = np.array([0.5 + 1j, 3j, -0.2 + 25j])
    truth = -q * np.exp(-s) * (k * np.exp(-s) + gu * (1 - np.exp(-s)) / s) - gv * (1 - np.exp(-s)) / s
    np.testing.assert_allclose(B(s), truth, rtol=0, atol=1e-15)


def test_general_plant_against_the_pde_and_the_magnus_route():
    """A general plant (``a, d != 0``, ``L = 1.5``, ``time_unit = 2``): measured 8.5e-16 to the 40-digit
    values; the Magnus route (4th order, Simpson on its grid) within 1.5e-12 at 2000 steps."""
    coefs = (2.0, 0.5, 0.3, 1.2, -0.7, -0.4, 0.6, 0.8)
    plant = GeneralHyperbolic2x2(*coefs, length=1.5, time_unit=2.0)
    controller = StateFeedback(0.2, lambda x: 0.3 + 0.2 * x**2, lambda x: 0.1 * np.exp(0.5 * x))
    assert loop_route(plant, controller) == "exact"
    A, B = loop_factors(plant, controller)
    s = np.array([0.3 + 2j, -0.5 + 7j, 0.1 + 15j])
    g_u = lambda x: mp.mpf("0.3") + mp.mpf("0.2") * x**2  # noqa: E731
    g_v = lambda x: mp.mpf("0.1") * mp.exp(x / 2)  # noqa: E731
    for z, a_val, b_val in zip(s, A(s), B(s)):
        a_true, b_true = _pde_factors(coefs, 0.2, g_u, g_v, z, length=1.5, unit=2.0)
        np.testing.assert_allclose(a_val, complex(a_true), rtol=0, atol=1e-13)
        np.testing.assert_allclose(b_val, complex(b_true), rtol=0, atol=1e-13)
    a_magnus, b_magnus = laplace_loop_factors(plant, 0.2, controller.g_u, controller.g_v, s, steps=2000)
    np.testing.assert_allclose(B(s), b_magnus, rtol=0, atol=5e-12)
    np.testing.assert_allclose(A(s), a_magnus, rtol=0, atol=5e-12)


def test_kernel_route_converges_to_the_exact_loop_at_third_order():
    """Kernels on 101, 201, 401 points: B off by 7.6e-9, 1.0e-9, 1.3e-10 (orders 2.90, 2.95)."""
    plant = Hyperbolic2x2(*STABLE)
    s = np.array([0.2 + 1j, -0.3 + 9j, 0.5 + 40j])
    exact = loop_factors(plant, law())[1](s)
    errors = np.array([np.max(np.abs(loop_factors(plant, law(), n)[1](s) - exact)) for n in (101, 201, 401)])
    orders = np.log2(errors[:-1] / errors[1:])
    assert np.all((orders > 2.7) & (orders < 3.2)), (errors, orders)
    assert errors[-1] < 2e-10


def _pde_margin(args, controller, gains, w0):
    """``(w, delta*)`` from the crossing equations of the PDE's loop, at 40 digits."""
    g_u, g_v = MP_GAINS[gains]

    def factors(w):
        return _pde_factors(_paper(args), controller.k, g_u, g_v, 1j * w)

    with mp.workdps(40):
        w = mp.findroot(lambda v: abs(factors(v)[0]) - abs(factors(v)[1]), w0)
        A, B = factors(w)
        return float(w), float((-mp.arg(-A / B)) % (2 * mp.pi) / w)


def test_certified_margin_contains_the_pde_margin():
    """Float margin 0.6589481823084029 (the 40-digit truth rounded), proven ball 3.3e-14 wide around it."""
    plant = Hyperbolic2x2(*STABLE)
    w, truth = _pde_margin(STABLE, law(), "law", 1.3)
    start = time.process_time()
    dm = nr.delay_margin(plant, law())
    proven = nr.delay_margin(plant, law(), rigorous=True)
    assert time.process_time() - start < 10.0  # measured 1.4 s of CPU
    np.testing.assert_allclose(dm.margin, truth, rtol=1e-13)
    np.testing.assert_allclose(dm.omega, w, rtol=1e-12)
    lo, hi = proven.margin_ball
    assert lo <= truth <= hi and hi - lo < 1e-12
    assert proven.scope.startswith("the PDE itself") and "integral gains" in proven.scope


def test_gains_that_balls_cannot_evaluate_take_the_kernel_route():
    plant = Hyperbolic2x2(*STABLE)
    stepped = StateFeedback(-1.2, lambda x: np.where(x < 0.5, -1.0, 0.0))
    assert loop_route(plant, stepped) == "kernels"
    reason = gain_failure(plant, stepped.g_u, stepped.g_v)
    assert reason is not None and "ball arithmetic" in reason
    scope = loop_scope(plant, stepped, None, loop_factors(plant, stepped))
    assert scope.startswith("a model of the PDE") and "no exact loop" in scope and "201 points" in scope
    # sqrt is not analytic at 0: the balls about 0 are not finite, the models refuse it
    assert loop_route(plant, StateFeedback(-1.2, lambda x: np.sqrt(x))) == "kernels"
    assert loop_route(plant, law(), kernel_grid=101) == "kernels"
    assert loop_route(plant, StateFeedback(-1.2, 0.1, 0.0)) == "exact"
    assert gain_kernel(plant, 0.0, 0.0) is None
    # an output feedback whose law has integral gains: the observer's term proven too (test_observer_integral_gains)
    assert loop_route(plant, OutputFeedback(law())) == "exact"


def test_kernel_is_stored_with_double_precision_bounds():
    """Measured: 16 and 47 pieces, radius 1.4e-17 and 1.3e-16, variation radius 4.2e-16 and 2.5e-15."""
    for args in (STABLE, FAST_U):
        kernel = gain_kernel(Hyperbolic2x2(*args), lambda x: 0.3 + 0.2 * x**2, lambda x: 0.1 * np.exp(0.5 * x))
        assert kernel.radius < 1e-15 and kernel.variation_radius < 1e-13
        assert kernel.nodes[0] == 0.0 and kernel.nodes[-1] == Hyperbolic2x2(*args).tau
