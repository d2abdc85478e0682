"""Proofs about a general plant with constant speeds and varying ``a, b, c, d`` (the PDE itself).

Oracles share no code with :mod:`nrobust.hyperbolic.loops.varying_proof`: the Laplace-domain
equations of the ORIGINAL plant (not its normal form) solved by mpmath's Taylor integrator
(``mpmath.odefun``) with ``A(L), D(L)`` by ``mpmath.quad``, the crossing equations
``|A(i w)| = |B(i w)|`` solved on it by ``mpmath.findroot``, the closed form of a general plant
with constant coefficients (:mod:`nrobust.hyperbolic.loops.exact_form`) and the kernel route on
refined grids.
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest
from _convergence import assert_kernel_route_converges

import nrobust as nr
from nrobust.hyperbolic import GeneralHyperbolic2x2, ReflectionController, StateFeedback
from nrobust.hyperbolic.loops.controllers import loop_route
from nrobust.hyperbolic.loops.exact_form import exact_form
from nrobust.hyperbolic.loops.varying_proof import has_varying_proof, varying_failure, varying_proof

flint = pytest.importorskip("flint")

LAM, MU, Q, RHO, K = 1.0, 2.0, 0.7, 0.4, 0.1


def _a(x):
    return 0.3 * np.sin(2.0 * x)


def _b(x):
    return 1.0 + 0.2 * x


def _c(x):
    return 0.5 * np.exp(-x)


def _d(x):
    return -0.2 * np.cos(x)


PLANT = GeneralHyperbolic2x2(lam=LAM, mu=MU, a=_a, b=_b, c=_c, d=_d, q=Q, rho=RHO)
# The margin of U_BS2(0.1) on PLANT: the crossing equations solved by mpmath.findroot at 32 digits on
# the ODE's solution (test_margin_of_the_pde_at_30_digits, marked long, recomputes it).
PDE_MARGIN = "2.1333555717546950367993897251175"
PDE_OMEGA = "0.72546988906087953635330408184673"


def _ode(s, dps=20, q_normal=None):
    """``(A, e^{-s L/mu - D(L)} u(L, s), B of U_BS2(K))`` of PLANT from ``[u; v](0) = [q; 1]`` (mpmath).

    ``u_x = ((a - s) u + b v) / lam``, ``v_x = ((s - d) v - c u) / mu``; the normalisation
    ``e^{-D(L)}`` (``D = -int d/mu``) makes ``A`` the characteristic function of the normal form.
    ``B = 1 - A + (K q~ - rho q e^{A(L) - D(L)}) e^{-tau s}``, ``q~`` the normal form's (``K`` is read
    in its coordinates).
    """
    with mp.workdps(dps):
        s = mp.mpc(s)

        def a(x):
            return mp.mpf("0.3") * mp.sin(2 * x)

        def d(x):
            return -mp.mpf("0.2") * mp.cos(x)

        def rhs(x, y):
            b, c = 1 + mp.mpf("0.2") * x, mp.mpf("0.5") * mp.exp(-x)
            return [((a(x) - s) * y[0] + b * y[1]) / LAM, ((s - d(x)) * y[1] - c * y[0]) / MU]

        u, v = mp.odefun(rhs, 0, [mp.mpf(Q), mp.mpf(1)])(1)
        A_L = mp.quad(lambda x: a(x) / LAM, [0, 1])
        D_L = -mp.quad(lambda x: d(x) / MU, [0, 1])
        weight = mp.exp(-s / MU - D_L)
        A = weight * (v - mp.mpf(RHO) * u)
        q_n = PLANT.normal_form().system.q if q_normal is None else q_normal
        principal = mp.mpf(K) * mp.mpf(q_n) - mp.mpf(RHO) * mp.mpf(Q) * mp.exp(A_L - D_L)
        B = 1 - A + principal * mp.exp(-s * (1 / mp.mpf(LAM) + 1 / mp.mpf(MU)))
        return A, weight * u, B


def _inside(ball, value, slack):
    assert float(ball.real.lower()) - slack <= float(value.real) <= float(ball.real.upper()) + slack
    assert float(ball.imag.lower()) - slack <= float(value.imag) <= float(ball.imag.upper()) + slack


@pytest.mark.parametrize("s", [0.4j, 3.0j, 0.5 + 7.0j, -0.3 + 25.0j])
def test_ball_enclosures_contain_the_original_plants_ode_solution(s):
    """The open loop and u(L, s) in ball arithmetic contain the original plant's values (mpmath, 20 digits)."""
    from nrobust.balls import ball_eval

    proof = varying_proof(PLANT)
    A, u, _ = _ode(s)
    for F, value in ((proof.characteristic, A), (proof.u_factor, u)):
        ball = ball_eval(F, flint.acb(s.real, s.imag))
        # tau is the double nearest L/lam + L/mu (exact here: 1.5) and rho q e^{A(L) - D(L)},
        # q e^{A(L) - D(L)} are rounded to doubles (2^-53 relative, times |e^{-tau s}| <= e^{0.45});
        # 1e-18 covers the ODE's 20 digits.
        slack = 1e-18 + 2.0 * 2.0**-53 * np.exp(-1.5 * s.real)
        _inside(ball, value, slack)
        assert ball.real.rad() < 1e-12 and ball.imag.rad() < 1e-12


def test_proven_margin_contains_the_pde_margin_and_says_so():
    """U_BS2(K): the proven ball contains the original plant's margin (mpmath, 32 digits)."""
    assert loop_route(PLANT, ReflectionController(K)) == "exact" and has_varying_proof(PLANT)
    dm = nr.delay_margin(PLANT, ReflectionController(K), delta_max=20.0, rigorous=True)
    lo, hi = dm.margin_ball
    # the ball's width (1.6e-13 measured) is far above 1 ulp: containment is a real check
    assert lo <= float(PDE_MARGIN) <= hi and hi - lo < 5e-13
    np.testing.assert_allclose(dm.omega, float(PDE_OMEGA), rtol=1e-11)  # proven to about 5e-14
    assert dm.scope.startswith("the PDE itself") and not dm.of_model
    # the kernel route's model (201 points) lies outside: the proof is not about it
    model = nr.delay_margin(PLANT, ReflectionController(K), delta_max=20.0, kernel_grid=201)
    assert not lo <= model.margin <= hi and model.of_model


def test_kernel_route_converges_to_the_proven_margin():
    """The kernel route on 101, 201, 401 points converges to the proven margin at its observed order."""
    proven = nr.delay_margin(PLANT, ReflectionController(K), delta_max=20.0, rigorous=True)
    assert_kernel_route_converges(PLANT, ReflectionController(K), proven.margin)


@pytest.mark.long
def test_margin_of_the_pde_at_30_digits():
    """Recompute PDE_MARGIN: the crossing equations on the ODE's solution at 32 digits (about a minute)."""

    def gap(w):
        A, _, B = _ode(1j * w, dps=32)
        return abs(A) ** 2 - abs(B) ** 2

    with mp.workdps(32):
        w = mp.findroot(gap, mp.mpf("0.7254698890608"), tol=mp.mpf(10) ** -28)
        A, _, B = _ode(1j * w, dps=32)
        delta = ((-mp.arg(-A / B)) % (2 * mp.pi)) / w
        assert abs(delta - mp.mpf(PDE_MARGIN)) < mp.mpf(10) ** -26
        assert abs(w - mp.mpf(PDE_OMEGA)) < mp.mpf(10) ** -26


def test_constant_coefficients_given_as_callables_match_the_closed_form():
    """a, b, c, d constant but given as functions: the same loop as the closed form, within the radii."""
    as_numbers = GeneralHyperbolic2x2(LAM, MU, 0.3, 1.2, 0.5, -0.2, Q, RHO, length=1.5)
    as_callables = GeneralHyperbolic2x2(
        LAM, MU, lambda x: 0.3 + 0 * x, lambda x: 1.2 + 0 * x, 0.5, lambda x: -0.2 + 0 * x, Q, RHO, length=1.5
    )
    proof, exact = varying_proof(as_callables), exact_form(as_numbers)
    # mine is the double nearest L/lam + L/mu; the closed form's is that of the normal form's speeds
    assert abs(proof.tau - exact.tau) <= 2.0**-50
    s = np.array([0.2j, 3.0j, 0.4 + 9.0j])
    for mine, theirs in ((proof.characteristic, exact.characteristic), (proof.u_factor, exact.u_factor)):
        radii = sum(d.radius * d.nodes[-1] * np.exp(max(0.0, -d.nodes[-1] * s.real.min())) for d in mine.distributed)
        radii += sum(d.radius * d.nodes[-1] for d in theirs.distributed)
        # the two kernels' proven radii (times tau), the doubles of the principal gains (a few ulps) and
        # the two taus (|d/dtau e^{-tau s}| <= |s| e^{-tau Re s} per unit of gain; gains below 1)
        bound = radii + 1e-14 + 4 * np.abs(s) * 2.0**-50  # 1e-14: evaluation rounding (1e-15 measured)
        assert np.all(np.abs(mine(s) - theirs(s)) <= bound)


def test_proportional_feedback_in_the_plants_coordinates():
    """U = k u(t, L) (physical k): B = -k e^{-s L/mu - D(L)} u(L, s); the natural gain -rho cancels exactly."""
    from nrobust.balls import ball_eval
    from nrobust.hyperbolic.loops.controllers import loop_factors

    k = -0.3
    assert loop_route(PLANT, StateFeedback(k)) == "exact"
    s = 0.2 + 4.0j
    _, u, _ = _ode(s)
    _, B = loop_factors(PLANT, StateFeedback(k))
    # slack: q e^{A(L) - D(L)} rounded to a double, as in the ball test above
    _inside(ball_eval(B, flint.acb(s.real, s.imag)), -k * u, 1e-18 + 2.0**-53)
    A, B = loop_factors(PLANT, StateFeedback(-RHO))
    F = A + B  # delta = 0: the principal gain at tau cancels to the bit
    assert all(np.all(c[1:] == 0.0) if t == 0.0 else np.all(c == 0.0) for c, t in zip(F.coefs, F.delays))


def test_samples_stay_the_users_model():
    """A coefficient given as samples: its spline is the model, the kernel route, and the scope says model."""
    x = np.linspace(0.0, 1.0, 21)
    plant = GeneralHyperbolic2x2(LAM, MU, _a, (x, _b(x)), _c, _d, Q, RHO)
    reason = varying_failure(plant)
    assert reason is not None and "samples" in reason
    assert not has_varying_proof(plant) and loop_route(plant, ReflectionController(K)) == "kernels"
    dm = nr.delay_margin(plant, ReflectionController(K), delta_max=20.0)
    assert dm.scope.startswith("a model of the PDE") and dm.of_model


def test_functions_without_balls_keep_the_model():
    """A coefficient that fails on balls: no proof, and the reason (speeds given as functions are proven:
    tests/test_varying_speed_proof.py)."""

    def table(x):
        if np.asarray(x).dtype == object:
            raise NotImplementedError("floats only")
        return 0.3 * np.sin(2.0 * x)

    plant = GeneralHyperbolic2x2(LAM, MU, table, _b, _c, _d, Q, RHO)
    assert "floats only" in varying_failure(plant)
    assert loop_route(plant, ReflectionController(K)) == "kernels"


def test_a_coefficient_changed_since_its_proof_is_not_proven_with_its_old_values():
    # a function reading a variable the user changed: the plant's tables (A, D) are those of the old
    # values, so the proof refuses it (its model disagrees with them) and a new plant is proven anew
    scale = [1.0]

    def a(x):
        return scale[0] * 0.3 * np.sin(2.0 * x)

    plant = GeneralHyperbolic2x2(LAM, MU, a, _b, _c, _d, Q, RHO)
    first = varying_proof(plant)
    scale[0] = 2.0
    assert "on balls and" in varying_failure(plant)
    fresh = varying_proof(GeneralHyperbolic2x2(LAM, MU, a, _b, _c, _d, Q, RHO))
    s = np.array([0.3 + 2.0j, 5.0j])
    assert np.max(np.abs(first.characteristic(s) - fresh.characteristic(s))) > 1e-2


def test_a_tiny_kernel_is_proven_with_its_absolute_error():
    """``c = 0`` with ``a != 0``: the kernels are tiny, their proven error (1e-17) is not small against
    them but is against the loop (constant term 1): proven, and the balls contain the ODE's values.

    The error bound was refused as "too large" (7e-18 against a kernel of 1e-10): the kernel route's
    model replaced a proof of radius 1e-16.
    """
    from nrobust.balls import ball_eval

    lam, mu, length, q = 1.1778448343497503, 1.522910399583671, 0.7813067766026055, 0.25616938770202446
    plant = GeneralHyperbolic2x2(
        lam, mu, lambda x: 1e-4 + 0 * x, lambda x: 0.65 + 0 * x, 0.0, 0.0, q, 0.0, length=length
    )
    assert varying_failure(plant) is None and loop_route(plant, ReflectionController(K)) == "exact"
    proof = varying_proof(plant)
    for s in (0.3j, 0.5 + 7.0j, -0.3 + 15.0j):
        with mp.workdps(20):
            z = mp.mpc(s)

            def rhs(x, y, z=z):
                return [((mp.mpf("1e-4") - z) * y[0] + mp.mpf(0.65) * y[1]) / lam, z * y[1] / mu]

            u, v = mp.odefun(rhs, 0, [mp.mpf(q), mp.mpf(1)])(mp.mpf(length))
            weight = mp.exp(-z * length / mu)  # D = 0
        for F, value in ((proof.characteristic, weight * v), (proof.u_factor, weight * u)):
            # slack: the doubles of tau and of q e^{A(L)} (a few ulps, times |e^{-tau s}| <= e^{0.4})
            _inside(ball_eval(F, flint.acb(s.real, s.imag)), complex(value), 1e-15)


def test_an_exponent_with_slowly_decaying_taylor_coefficients_keeps_a_tight_proof():
    """``a = 0.5/(2.4 - x)`` (a pole 1.4 from [0, 1]): the exponent ``D - A`` on each ball's series is
    Taylor-shifted to the ball's centre before Horner's rule. In the monomials about 0 the coupling's model
    widened and the proven radius of ``N~`` was 3.8e-13 (5.4e-15 now); the balls hold the ODE's values.
    """
    from nrobust.balls import ball_eval

    plant = GeneralHyperbolic2x2(LAM, MU, lambda x: 0.5 / (2.4 - x), _b, 0.5, -0.2, Q, RHO)
    proof = varying_proof(plant)
    assert proof.N_tilde.radius < 2e-14
    for s in (0.4j, 0.5 + 7.0j):
        with mp.workdps(20):
            z = mp.mpc(s)

            def rhs(x, y, z=z):
                a, b = mp.mpf(0.5) / (mp.mpf(2.4) - x), 1 + mp.mpf(0.2) * x
                return [((a - z) * y[0] + b * y[1]) / LAM, ((z + mp.mpf(0.2)) * y[1] - mp.mpf(0.5) * y[0]) / MU]

            u, v = mp.odefun(rhs, 0, [mp.mpf(Q), mp.mpf(1)])(1)
            D_L = mp.mpf(0.2) / MU  # D = -int d/mu with d = -0.2
            weight = mp.exp(-z / MU - D_L)
        # slack: the doubles of tau and the principal gains (2^-53 relative, times |e^{-tau s}| <= 1)
        _inside(ball_eval(proof.characteristic, flint.acb(s.real, s.imag)), complex(weight * (v - RHO * u)), 1e-15)
