"""``N~`` with a proven error for couplings that vary with ``x``, and proofs about the PDE itself.

Oracles share no code with :mod:`nrobust.hyperbolic.loops.varying_proof`: the Laplace-domain
solution of the plant's ODE in ``x`` by mpmath's Taylor integrator (``mpmath.odefun``, 20 to 40
digits), the closed form of a constant coupling (:mod:`nrobust.hyperbolic.loops.exact_form`),
the kernel route on refined grids, and the crossing equations ``|A(i w)| = |B(i w)|`` solved by
``mpmath.findroot`` on the ODE's solution.
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest
from _convergence import assert_kernel_route_converges

import nrobust as nr
from nrobust.errors import CertificationError
from nrobust.hyperbolic import FiniteTimeController, Hyperbolic2x2, OpenLoop, ReflectionController, StateFeedback
from nrobust.hyperbolic.loops.controllers import loop_factors, loop_route
from nrobust.hyperbolic.loops.exact_form import exact_form
from nrobust.hyperbolic.loops.varying_proof import has_varying_proof, varying_failure, varying_proof

flint = pytest.importorskip("flint")

LAM, MU, Q, RHO, K = 1.0, 2.5, 0.7, 0.85, 0.1


def _pm(x):
    return 1.0 + 0.5 * np.sin(3.0 * x)


def _mp(x):
    return 2.0 * np.exp(-x)


VARYING = Hyperbolic2x2(LAM, MU, _pm, _mp, Q, RHO)
AS_CALLABLES = Hyperbolic2x2(LAM, MU, lambda x: 1.3 + 0 * x, lambda x: 0.6 + 0 * x, Q, RHO)
CONSTANT = Hyperbolic2x2(LAM, MU, 1.3, 0.6, Q, RHO)
# The margin of U_BS2(0.1) on VARYING: |A(i w)| = |B(i w)| solved by mpmath.findroot at 40 digits on
# the ODE's solution (test_margin_of_the_pde_at_30_digits, marked long, recomputes it to 25 digits).
PDE_MARGIN = "0.81266715025299030693071652296"


def _ode(s, dps=20):
    """``(A, e^{-s/mu} u(1, s))`` of VARYING from ``[u; v](0) = [q; 1]``, by mpmath's ODE solver."""
    with mp.workdps(dps):
        s = mp.mpc(s)

        def rhs(x, y):
            return [
                (-s * y[0] + (1 + mp.mpf(0.5) * mp.sin(3 * x)) * y[1]) / LAM,
                (s * y[1] - 2 * mp.exp(-x) * y[0]) / MU,
            ]

        u, v = mp.odefun(rhs, 0, [mp.mpf(Q), mp.mpf(1)])(1)
        w = mp.exp(-s / MU)
        return w * (v - RHO * u), w * u


def test_constant_coupling_given_as_callable_matches_the_closed_form():
    """The same plant by two routes: the kernels agree within the sum of their proven radii."""
    proof, exact = varying_proof(AS_CALLABLES), exact_form(CONSTANT)
    nu = np.linspace(0.0, CONSTANT.tau, 301)
    bound = proof.N_tilde.radius + exact.N_tilde.radius + 4e-16  # the two evaluations' rounding
    np.testing.assert_allclose(proof.N_tilde(nu), exact.N_tilde(nu), rtol=0, atol=bound)
    assert proof.N_tilde.radius < 1e-14 and proof.N_tilde.variation_radius < 1e-13


def test_constant_coupling_given_as_callable_margin_contains_the_exact_one():
    """The proven margin ball of the callable plant contains the closed form's margin."""
    exact = nr.delay_margin(CONSTANT, ReflectionController(K), delta_max=20.0, rigorous=True)
    proven = nr.delay_margin(AS_CALLABLES, ReflectionController(K), delta_max=20.0, rigorous=True)
    lo, hi = proven.margin_ball
    assert lo <= exact.margin <= hi and hi - lo < 1e-12
    assert proven.scope.startswith("the PDE itself") and not proven.of_model


@pytest.mark.parametrize("s", [0.3j, 2.0j, 0.5 + 5.0j, -0.4 + 30.0j])
def test_ball_enclosures_contain_the_ode_solution(s):
    """The ball enclosures of the open loop and of u(1, s) contain the PDE's values (mpmath, 20 digits)."""
    from nrobust.balls import ball_eval

    proof = varying_proof(VARYING)
    truth = _ode(s)
    for F, value in zip((proof.characteristic, proof.u_factor), truth):
        ball = ball_eval(F, flint.acb(s.real, s.imag))
        # tau is the double nearest 1/lam + 1/mu (the plant the proofs are about): a change of |s| 2^-52
        # relative in e^{-tau s}, below 1e-14 here; 1e-18 covers the ODE's 20 digits.
        slack = 1e-18 + abs(s) * 2.0**-52 * 2.0
        assert float(ball.real.lower()) - slack <= float(value.real) <= float(ball.real.upper()) + slack
        assert float(ball.imag.lower()) - slack <= float(value.imag) <= float(ball.imag.upper()) + slack
        assert ball.real.rad() < 1e-12 and ball.imag.rad() < 1e-12


def test_proven_margin_contains_the_pde_margin():
    """The proven ball of U_BS2(K) contains the PDE's margin (mpmath at 40 digits), and says so."""
    dm = nr.delay_margin(VARYING, ReflectionController(K), delta_max=20.0, rigorous=True)
    lo, hi = dm.margin_ball
    assert lo <= float(PDE_MARGIN) <= hi and hi - lo < 1e-12  # the ball's width, 1.5e-13, is far above 1 ulp
    assert dm.scope.startswith("the PDE itself") and not dm.of_model
    assert loop_route(VARYING, ReflectionController(K)) == "exact"


def test_proven_margin_contains_the_kernel_route_extrapolated():
    """The kernel route converges to the proven margin at its observed order (about 3)."""
    proven = nr.delay_margin(VARYING, ReflectionController(K), delta_max=20.0, rigorous=True)
    margins = assert_kernel_route_converges(VARYING, ReflectionController(K), proven.margin)
    assert abs(margins[2] - proven.margin) > 10 * (proven.margin_ball[1] - proven.margin_ball[0])


@pytest.mark.long
def test_margin_of_the_pde_at_30_digits():
    """Recompute PDE_MARGIN: the crossing equations on the ODE's solution at 30 digits (about a minute)."""

    def factors(w):
        A, _ = _ode(1j * w, dps=30)
        with mp.workdps(30):
            B = 1 - A + (K - RHO) * Q * mp.exp(-1j * w * (1 / mp.mpf(LAM) + 1 / mp.mpf(MU)))
        return A, B

    def gap(w):
        A, B = factors(w)
        return abs(A) ** 2 - abs(B) ** 2

    with mp.workdps(30):
        w = mp.findroot(gap, mp.mpf("1.0475792485782"), tol=mp.mpf(10) ** -26)
        A, B = factors(w)
        delta = ((-mp.arg(-A / B)) % (2 * mp.pi)) / w
        assert abs(delta - mp.mpf(PDE_MARGIN)) < mp.mpf(10) ** -25


def test_state_feedback_and_other_controllers_take_the_proven_route():
    """U_BS, the open loop and a proportional feedback: the loop's kernels carry the proof's radius."""
    for controller in (OpenLoop(), FiniteTimeController(), StateFeedback(-0.3)):
        assert loop_route(VARYING, controller) == "exact"
        A, B = loop_factors(VARYING, controller)
        radii = [d.radius for f in (A, B) for d in f.distributed]
        assert radii and max(radii) < 1e-12
    assert loop_route(VARYING, StateFeedback(0.0, lambda x: x, 0.0)) == "kernels"  # integral gains: not covered
    assert loop_route(VARYING, ReflectionController(K), kernel_grid=101) == "kernels"


def test_a_coupling_without_ball_arithmetic_keeps_the_model():
    """A coupling that fails on arb_series: the kernel route, and the scope says model."""
    plant = Hyperbolic2x2(LAM, MU, lambda x: np.where(np.asarray(x, dtype=float) < 2.0, 1.0, 0.0), _mp, Q, RHO)
    assert not has_varying_proof(plant)
    assert "ball arithmetic" in varying_failure(plant)
    assert loop_route(plant, ReflectionController(K)) == "kernels"
    dm = nr.delay_margin(plant, ReflectionController(K), delta_max=20.0)
    assert dm.scope.startswith("a model of the PDE") and dm.of_model


def test_a_coupling_with_a_pole_near_the_interval_is_refused():
    """Not analytic on a disc about [0, 1] wide enough: no proof, a reason that says so."""
    plant = Hyperbolic2x2(LAM, MU, lambda x: 1.0 / (x - 1.05), _mp, Q, RHO)
    reason = varying_failure(plant)
    assert reason is not None and loop_route(plant, OpenLoop()) == "kernels"
    with pytest.raises(CertificationError):
        varying_proof(plant)


def test_a_coupling_changed_since_its_proof_is_proven_again():
    # A function reading a variable the user changed: a new plant built on the same function object
    # equals the old one, and a cached proof of the old couplings would be called the PDE's.
    scale = [1.0]

    def pm(x):
        return scale[0] * np.sin(3.0 * x)

    first = varying_proof(Hyperbolic2x2(LAM, MU, pm, _mp, Q, RHO))
    scale[0] = 2.0
    again = varying_proof(Hyperbolic2x2(LAM, MU, pm, _mp, Q, RHO))
    fresh = varying_proof(Hyperbolic2x2(LAM, MU, lambda x: 2.0 * np.sin(3.0 * x), _mp, Q, RHO))
    s = np.array([0.3 + 2.0j, 5.0j])
    # the same function evaluated twice (proof radius about 1e-13); the stale proof differs at O(1)
    np.testing.assert_allclose(again.characteristic(s), fresh.characteristic(s), rtol=0, atol=1e-12)
    assert np.max(np.abs(first.characteristic(s) - fresh.characteristic(s))) > 1e-2


def test_a_coupling_that_raises_on_balls_takes_the_kernel_route():
    class Table:  # acts on float arrays only, raising its own exception on anything else
        def __call__(self, x):
            if np.asarray(x).dtype == object:
                raise NotImplementedError("floats only")
            return 1.0 + 0.5 * np.sin(3.0 * x)

    plant = Hyperbolic2x2(LAM, MU, Table(), _mp, Q, RHO)
    assert "floats only" in varying_failure(plant)
    assert loop_route(plant, ReflectionController(K)) == "kernels"


def test_a_coupling_acting_differently_on_balls_is_refused():
    def pm(x):  # agrees with its array values at x = 1/2 only
        bump = (x - 0.5) ** 2 if np.asarray(x).dtype == object else 0.0 * x
        return np.sin(3.0 * x) + bump

    reason = varying_failure(Hyperbolic2x2(LAM, MU, pm, _mp, Q, RHO))
    assert reason is not None and "on balls and" in reason


def test_speeds_other_than_one_against_the_ode():
    # lam = 2.3, mu = 0.7: the 1/lam and 1/mu of the Volterra form against mpmath's ODE solution
    lam, mu = 2.3, 0.7
    proof = varying_proof(Hyperbolic2x2(lam, mu, _pm, _mp, Q, RHO))
    for s in (0.7j, 1.0 + 10.0j):
        with mp.workdps(20):
            z = mp.mpc(s)

            def rhs(x, y, z=z):
                return [
                    (-z * y[0] + (1 + mp.mpf(0.5) * mp.sin(3 * x)) * y[1]) / lam,
                    (z * y[1] - 2 * mp.exp(-x) * y[0]) / mu,
                ]

            u, v = mp.odefun(rhs, 0, [mp.mpf(Q), mp.mpf(1)])(1)
            want = complex(mp.exp(-z / mu) * (v - RHO * u))
        # normalised as the characteristic function (1 at s = inf along the real axis)
        got = complex(proof.characteristic(np.array([s]))[0])
        np.testing.assert_allclose(got, want, rtol=1e-10)  # proof radius ~1e-13, mpmath at 20 digits


def test_rounded_rho_q_carries_its_radius():
    """``rho q`` of VARYING is not a double: its rounding (exact rationals) is the radius of the loop's principal
    point coefficient, within a few ulps."""
    from fractions import Fraction

    proof = varying_proof(VARYING)
    error = abs(Fraction(RHO) * Fraction(Q) - Fraction(proof.rho_q))
    assert error > 0 and error <= proof.rho_q_radius <= 4 * np.spacing(proof.rho_q)
    A, _ = loop_factors(VARYING, FiniteTimeController())
    assert A.point_terms[1][1] == proof.tau and A.point_radii[1][0] >= error
