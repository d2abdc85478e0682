"""The delay form of a plant with constant coefficients in closed form, and proofs about the PDE.

Oracles share no code with :mod:`nrobust.hyperbolic.loops.exact_form`: the Laplace-domain
solution ``exp(B(s)) [q; 1]`` by mpmath's matrix exponential at 40 digits, the kernel by
mpmath's ``hyp0f1`` (``W = 0F1(;1; x)``, ``h_22 = a (tau - nu) 0F1(;2; x)``,
``x = a nu (tau - nu)``), and the crossing equations ``|A(i w)| = |B(i w)|`` solved by
``mpmath.findroot``.
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import nrobust as nr
from nrobust.hyperbolic import (
    FilteredController,
    FiniteTimeController,
    GeneralHyperbolic2x2,
    Hyperbolic2x2,
    OpenLoop,
    ReflectionController,
    StateFeedback,
)
from nrobust.hyperbolic.loops.controllers import characteristic, loop_factors, loop_route
from nrobust.hyperbolic.loops.exact_form import exact_form, exact_output_map, has_exact_form
from nrobust.hyperbolic.loops.feedback import laplace_loop_factors
from nrobust.quasipoly import DistributedDelay, QuasiPolynomial

flint = pytest.importorskip("flint")

PAPER = (1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
PLANTS = [PAPER, (1.0, 3.0, 1.0, 1.0, 1.0, 0.85), (1.0, 1.0, 4.0, 4.0, 0.5, 0.5), (2.0, 0.7, -1.5, 3.0, 0.3, -0.4)]


def _fundamental(args, s, dps=40):
    """``e^{-s/mu} [u; v](1, s)`` from ``[q; 1]`` by mpmath's expm: the PDE's Laplace-domain solution.

    ``tau`` enters only through ``B = [[-s tau, sigma_pm/lam], [-sigma_mp/mu, 0]]``: it is the
    double nearest ``1/lam + 1/mu``, the plant the proofs are about (``exact_form``'s scope).
    """
    lam, mu, spm, smp, q, _ = (mp.mpf(v) for v in args)
    with mp.workdps(dps):
        tau = mp.mpf(1.0 / args[0] + 1.0 / args[1])
        B = mp.matrix([[-mp.mpc(s) * tau, spm / lam], [-smp / mu, 0]])
        z = mp.expm(B) * mp.matrix([q, 1])
        return z[0], z[1], tau


def _open_loop(args, s):
    zu, zv, _ = _fundamental(args, s)
    return complex(zv - mp.mpf(args[5]) * zu)


def _kernel_oracle(args, nu):
    """``N~(nu)`` by mpmath's hypergeometric functions."""
    lam, mu, spm, smp, q, rho = (mp.mpf(v) for v in args)
    with mp.workdps(40):
        tau = mp.mpf(1.0 / args[0] + 1.0 / args[1])
        p, m = spm / lam, -smp / mu
        a = p * m / tau**2
        nu = mp.mpf(nu)
        x = a * nu * (tau - nu)
        W = mp.hyp0f1(1, x)
        h22 = a * (tau - nu) * mp.hyp0f1(2, x)
        h11 = a * nu * mp.hyp0f1(2, x)
        return float(h22 - rho * q * h11 + (m * q - rho * p) / tau * W)


@pytest.mark.parametrize("args", PLANTS)
def test_stored_kernel_is_within_its_proven_radius_of_the_bessel_kernel(args):
    N = exact_form(Hyperbolic2x2(*args)).N_tilde
    assert N is not None and N.interpolation == "polynomial" and 0.0 < N.radius < 1e-14
    nu = np.linspace(0.0, N.b, 97)
    stored = N.kernel_at(nu)
    truth = np.array([_kernel_oracle(args, v) for v in nu])
    # the radius bounds the distance to the true kernel; 4 ulps allow the oracle's rounding to double
    assert np.all(np.abs(stored - truth) <= N.radius + 4 * np.spacing(np.abs(truth)))


@pytest.mark.parametrize("args", PLANTS)
def test_characteristic_equals_the_laplace_solution_to_rounding(args):
    F = exact_form(Hyperbolic2x2(*args)).characteristic
    s = np.array([0.3 + 2j, 7j, -0.2 + 15j, 0.01 + 300j, 2 + 1e4j, -1 + 50j])
    truth = np.array([_open_loop(args, v) for v in s])
    # the stored kernel is within 5e-16 of the true one; the floating-point evaluation of e^{-tau s}
    # errs by the rounding of tau s, about |s| tau 2^-53 (measured 2.8e-14 at |s| = 1e4, tau = 4/3; the
    # closed-form 2x2 exponential of boundary_function errs by up to 9e-13 there)
    bound = 4e-15 + np.abs(s) * Hyperbolic2x2(*args).tau * 2.0**-52
    assert np.all(np.abs(F(s) - truth) <= bound)


@pytest.mark.parametrize("args", PLANTS)
def test_ball_enclosures_contain_the_pde_values(args):
    """The proofs' enclosures are of the PDE's function, not of a model of it."""
    from nrobust.balls import ball_eval

    F = exact_form(Hyperbolic2x2(*args)).characteristic
    for s in (0.3 + 2j, 7j, 0.01 + 300j, -0.5 + 40j):
        ball = ball_eval(F, flint.acb(s.real, s.imag))
        truth = _open_loop(args, s)
        assert ball.real.contains(flint.arb(truth.real)) or abs(ball.real.mid() - truth.real) < 1e-30
        assert ball.real.rad() < 1e-12 and ball.imag.rad() < 1e-12
        lo_re, hi_re = float(ball.real.lower()), float(ball.real.upper())
        lo_im, hi_im = float(ball.imag.lower()), float(ball.imag.upper())
        assert lo_re <= truth.real <= hi_re and lo_im <= truth.imag <= hi_im


def _pde_margin(args, K, w0):
    """``(w, delta*)`` of U_BS2(K) from the crossing equations, at 40 digits."""
    rho, q = mp.mpf(args[5]), mp.mpf(args[4])

    def factors(w):
        zu, zv, tau = _fundamental(args, 1j * w)
        A = zv - rho * zu
        B = K * q * mp.exp(-1j * w * tau) - (A - 1 + rho * q * mp.exp(-1j * w * tau))
        return A, B

    with mp.workdps(40):
        w = mp.findroot(lambda v: abs(factors(v)[0]) - abs(factors(v)[1]), w0)
        A, B = factors(w)
        return float(w), float((-mp.arg(-A / B)) % (2 * mp.pi) / w)


@pytest.mark.parametrize(
    ("args", "w0"), [(PAPER, 6.28), ((1.0, 3.0, 1.0, 1.0, 1.0, 0.85), 0.623), ((1.0, 1.0, 4.0, 4.0, 0.5, 0.5), 12.47)]
)
def test_proven_margin_contains_the_pde_margin(args, w0):
    """Proven balls on the kernel grid missed the PDE's margin by 1e5 to 1e6 widths; now they hold it."""
    w, truth = _pde_margin(args, mp.mpf("0.1"), w0)
    dm = nr.delay_margin(Hyperbolic2x2(*args), ReflectionController(0.1), rigorous=True)
    lo, hi = dm.margin_ball
    assert lo <= truth <= hi and hi - lo < 1e-12
    assert dm.scope.startswith("the PDE itself")
    np.testing.assert_allclose(dm.omega, w, rtol=1e-12)
    # the floating-point margin on the same exact loop agrees to rounding (measured 3e-16)
    np.testing.assert_allclose(
        nr.delay_margin(Hyperbolic2x2(*args), ReflectionController(0.1)).margin, truth, rtol=1e-13
    )


def test_kernel_route_converges_to_the_exact_margin_at_third_order():
    """The independent route: kernels on grids of 101, 201, 401 points (errors 1.2e-9, 1.5e-10, 1.9e-11)."""
    exact = nr.delay_margin(Hyperbolic2x2(*PAPER), ReflectionController(0.1)).margin
    errors = [
        abs(
            nr.delay_margin(Hyperbolic2x2(*PAPER), ReflectionController(0.1), kernel_grid=n, verify=False).margin
            - exact
        )
        for n in (101, 201, 401)
    ]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((orders > 2.8) & (orders < 3.2)), orders


@pytest.mark.parametrize(
    "controller",
    [OpenLoop(), FiniteTimeController(), ReflectionController(0.1), FilteredController(0.2, 1.0), StateFeedback(-0.3)],
)
def test_exact_loops_against_the_kernel_route(controller):
    """Every controller's exact loop against the cubic-spline loop on 801 points (error ~1e-11 there)."""
    plant = Hyperbolic2x2(*PAPER)
    assert loop_route(plant, controller) == "exact"
    s = np.array([0.2 + 1j, -0.3 + 9j, 0.5 + 40j])
    exact = characteristic(plant, controller, 0.05)(s)
    model = characteristic(plant, controller, 0.05, kernel_grid=801)(s)
    np.testing.assert_allclose(exact, model, rtol=0, atol=1e-9)


def test_integral_gains_take_the_exact_route_only_when_they_can_be_evaluated_on_balls():
    plant = Hyperbolic2x2(*PAPER)
    assert loop_route(plant, StateFeedback(-0.3, 0.1, 0.0)) == "exact"
    assert loop_route(plant, StateFeedback(-0.3, lambda x: np.where(x < 0.5, 1.0, 0.0), 0.0)) == "kernels"
    assert loop_route(plant, ReflectionController(0.1), kernel_grid=201) == "kernels"


def general_plant() -> GeneralHyperbolic2x2:
    return GeneralHyperbolic2x2(2.0, 0.5, 0.3, 1.2, -0.7, -0.4, 0.6, 0.8, length=1.5, time_unit=2.0)


def test_general_constant_plant_against_the_magnus_route():
    """``1 - rho q e^{sigma_0 tau} e^{-tau s} + int e^{sigma_0 nu} N~_0 e^{-nu s}`` and ``B = -k u_factor``."""
    g = general_plant()
    assert has_exact_form(g)
    form = exact_form(g)
    s = np.array([0.3 + 2j, 7j, -0.2 + 15j, 0.01 + 60j])
    A, B = laplace_loop_factors(g, 0.7, 0.0, 0.0, s, steps=4000)
    # the Magnus route is fourth order: 4000 steps leave about 1e-13
    np.testing.assert_allclose(form.characteristic(s), A, rtol=0, atol=2e-12)
    np.testing.assert_allclose(-0.7 * form.u_factor(s), B, rtol=0, atol=2e-12)
    np.testing.assert_allclose(form.rho_q, g.normal_form().system.rho_q, rtol=1e-13)


def test_output_map_in_closed_form():
    args = PLANTS[3]
    M = exact_output_map(Hyperbolic2x2(*args))
    s = np.array([0.3 + 1j, -0.2 + 5j, 1.0 + 20j, 0.1 + 100j])
    truth = np.array([complex(_fundamental(args, v)[1]) for v in s])
    np.testing.assert_allclose(M(s), truth, rtol=0, atol=5e-15)


def test_natural_gain_cancels_exactly_on_the_exact_route():
    """``StateFeedback(-rho)`` on a general plant: the principal term of ``A + B`` is exactly zero."""
    g = general_plant()
    A, B = loop_factors(g, StateFeedback(-g.rho))
    assert all(t != exact_form(g).tau or np.all(p == 0) for p, t in (A + B).point_terms)


def test_error_bounds_follow_the_algebra():
    N = exact_form(Hyperbolic2x2(*PAPER)).N_tilde
    assert N is not None
    zero = QuasiPolynomial([], [], [N]) - QuasiPolynomial([], [], [N])
    assert not zero.distributed  # the same kernel cancels exactly, its error bound with it
    doubled = N.scale(2.0)
    assert doubled.radius >= 2 * N.radius and doubled.variation_radius >= 2 * N.variation_radius
    assert N.scale(-1.0).radius == N.radius
    # every bound of the true kernel includes the radius: the stored pieces' moment plus radius * tau
    no_radius = DistributedDelay(N.nodes, None, interpolation="polynomial", coefficients=N.pieces[2])
    np.testing.assert_allclose(N.abs_moment(0.0) - no_radius.abs_moment(0.0), N.radius * N.b, rtol=0.1)
    assert N.abs_moment(0.0) - no_radius.abs_moment(0.0) >= N.radius * N.b


def test_margin_scope_of_the_kernel_route_says_model():
    dm = nr.delay_margin(Hyperbolic2x2(*PAPER), ReflectionController(0.1), kernel_grid=101, verify=False)
    assert dm.scope.startswith("a model of the PDE") and "101 points" in dm.scope


@settings(max_examples=12, deadline=None)
@given(
    lam=st.floats(0.3, 3.0),
    mu=st.floats(0.3, 3.0),
    spm=st.floats(-5.0, 5.0),
    smp=st.floats(-5.0, 5.0),
    q=st.floats(0.05, 1.0) | st.floats(-1.0, -0.05),
    rho=st.floats(-1.0, 1.0),
    w=st.floats(-60.0, 60.0),
    x=st.floats(-1.0, 1.0),
)
def test_random_constant_plants_enclose_the_pde(lam, mu, spm, smp, q, rho, w, x):
    """Random constant couplings: the ball enclosure of the exact characteristic function holds the
    40-digit value of ``v(1, s) - rho u(1, s)``."""
    from nrobust.balls import ball_eval

    args = (lam, mu, spm, smp, q, rho)
    F = exact_form(Hyperbolic2x2(*args)).characteristic
    truth = _open_loop(args, complex(x, w))
    ball = ball_eval(F, flint.acb(x, w))
    assert float(ball.real.lower()) <= truth.real <= float(ball.real.upper())
    assert float(ball.imag.lower()) <= truth.imag <= float(ball.imag.upper())
    assert float(ball.real.rad()) < 1e-9 * max(1.0, abs(truth))


def test_linear_deviation_and_linearized_bounds_hold_for_jumps_and_curvature():
    """Two review findings: a jump between polynomial pieces counts in ``int |N - N_lin|``, and the
    total variation of ``N_true - N_lin`` after ``linearized`` is that of a bump per segment."""
    step = DistributedDelay([0.0, 1.0, 2.0], None, interpolation="polynomial", coefficients=[[0.0], [1.0]])
    assert step.linear_deviation() >= 0.5  # N - N_lin is the line t on [0, 1]: int = 1/2
    square = DistributedDelay([0.0, 1.0], None, interpolation="polynomial", coefficients=[[0.0, 0.0, 1.0]])
    lin = square.linearized(11)
    nu = np.linspace(0.0, 1.0, 100_001)
    diff = nu**2 - np.interp(nu, lin.nodes, lin.values)
    assert np.max(np.abs(diff)) <= lin.radius
    assert np.sum(np.abs(np.diff(diff))) <= lin.variation_radius  # measured 0.05
