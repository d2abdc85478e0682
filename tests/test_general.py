"""General 2x2 plants: validation, the normal form against one made by hand, any state feedback.

The hand-made plant: on ``[0, 2]``, ``lam = 1 + x/2``, ``mu = 2 lam`` (constant ratio, varying
speeds), ``a = 0.3 lam``, ``d = 0.4 mu``, ``b = cos x``, ``c = 1/2``. Then
``phi = 2 ln(1 + x/2)``, ``t_u = 2 ln 2``, ``t_v = ln 2``, ``x(y) = 2 (2^y - 1)``,
``A = 0.3 x``, ``D = -0.4 x``, ``D - A = -0.7 x`` in ``[-1.4, 0]`` (balance ``k = -0.7``), so the
normal form has ``lam~ = 1/(2 ln 2)``, ``mu~ = 1/ln 2``, ``sigma_pm = cos(x) e^{0.7 - 0.7 x}``,
``sigma_mp = e^{0.7 x - 0.7}/2``, ``q~ = q e^{0.7}``, ``rho~ = rho e^{0.6 - 0.7 + 0.8}`` and
``U = e^{-0.8} U~`` (docs/theory.md).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from nrobust import find_roots, spectral_abscissa
from nrobust.errors import ParameterError
from nrobust.hyperbolic import (
    FiniteTimeController,
    Hyperbolic2x2,
    OpenLoop,
    ReflectionController,
    TransportSystem,
    boundary_function,
    characteristic,
    delay_form,
    loop_factors,
    solve_kernels,
)
from nrobust.hyperbolic.analyses import ab_region, delay_margin, k_region, stability_chart, tradeoff
from nrobust.hyperbolic.analyses.rouche import _varying_bound, rouche_delay_bound
from nrobust.hyperbolic.kernels.constant import DEFAULT_KERNEL_GRID
from nrobust.hyperbolic.loops.controllers import StateFeedback, normalize
from nrobust.hyperbolic.loops.feedback import feedback_factor, laplace_loop_factors
from nrobust.hyperbolic.loops.varying_form import varying_delay_form
from nrobust.hyperbolic.plants.general import GeneralHyperbolic2x2, as_general
from nrobust.hyperbolic.simulate import simulate
from nrobust.hyperbolic.simulate.general import simulate_general
from nrobust.reports.certificate import certify

LN2 = np.log(2.0)
Q, RHO = 0.8, 0.1


def lam(x):
    return 1.0 + 0.5 * np.asarray(x)


def general_plant() -> GeneralHyperbolic2x2:
    return GeneralHyperbolic2x2(
        lam,
        lambda x: 2.0 * lam(x),
        lambda x: 0.3 * lam(x),
        np.cos,
        0.5,
        lambda x: 0.8 * lam(x),
        Q,
        RHO,
        length=2.0,
    )


def x_of_y(y):
    return 2.0 * (2.0 ** np.asarray(y) - 1.0)


def hand_plant() -> Hyperbolic2x2:
    return Hyperbolic2x2(
        1.0 / (2.0 * LN2),
        1.0 / LN2,
        lambda y: np.cos(x_of_y(y)) * np.exp(0.7 - 0.7 * x_of_y(y)),
        lambda y: 0.5 * np.exp(0.7 * x_of_y(y) - 0.7),
        Q * np.exp(0.7),
        RHO * np.exp(0.7),
    )


S = np.array([0.1 + 0.2j, 1.0 + 5.0j, -0.3 + 20.0j, 0.5 + 60.0j])


# ------------------------------------------------------------------ validation
@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"lam": -1.0}, "lam"),
        ({"mu": lambda x: 1.0 - x}, "mu"),
        ({"a": np.nan}, "a"),
        ({"b": "1"}, "b"),
        ({"c": lambda x: 1.0 / (x - 0.5)}, "c"),
        ({"d": ([0.0, 0.5], [1.0, 2.0])}, "d[0]"),
        ({"d": ([0.0, 1.0], [1.0, 2.0, 3.0])}, "d"),
        ({"q": 0.0}, "q"),
        ({"rho": np.inf}, "rho"),
        ({"length": 0.0}, "length"),
        ({"b": True}, "b"),
    ],
)
def test_bad_coefficients_are_named(kwargs, name):
    args = {"lam": 1.0, "mu": 1.0, "a": 0.0, "b": 0.0, "c": 0.0, "d": 0.0, "q": 1.0, "rho": 0.5}
    args.update(kwargs)
    with pytest.raises(ParameterError) as err:
        GeneralHyperbolic2x2(**args)
    assert err.value.name == name


def test_varying_ratio_has_no_constant_speed_normal_form():
    plant = GeneralHyperbolic2x2(lambda x: 1.0 + x, 1.0, 0.0, 0.5, 0.5, 0.0, 1.0, 0.5)
    assert not plant.constant_ratio
    with pytest.raises(ParameterError, match="proportional to lam") as err:
        plant.normal_form()
    assert err.value.name == "mu"


# ------------------------------------------------------------------ the normal form
def test_normal_form_matches_the_hand_made_one():
    form = general_plant().normal_form()
    hand = hand_plant()
    sys = form.system
    np.testing.assert_allclose([sys.lam, sys.mu, sys.q, sys.rho], [hand.lam, hand.mu, hand.q, hand.rho], rtol=1e-12)
    y = np.linspace(0.0, 1.0, 33)
    # phi, A, D, x(y) are cubic Hermite interpolants of a 1024-panel Gauss table: ~1e-13.
    np.testing.assert_allclose(sys.sigma_pm_at(y), hand.sigma_pm_at(y), atol=1e-11)
    np.testing.assert_allclose(sys.sigma_mp_at(y), hand.sigma_mp_at(y), rtol=1e-11)
    np.testing.assert_allclose(form.x_of_y(y), x_of_y(y), atol=1e-12)
    np.testing.assert_allclose(form.y_of_x(x_of_y(y)), y, atol=1e-12)
    assert form.control_gain == pytest.approx(np.exp(-0.8), rel=1e-12)
    assert general_plant().tau == pytest.approx(3.0 * LN2, rel=1e-13)


def test_state_maps_are_inverse():
    form = general_plant().normal_form()
    x = np.linspace(0.0, 2.0, 9)
    y, u, v = form.to_normal(x, np.sin(x), np.cos(x))
    x2, u2, v2 = form.from_normal(y, u, v)
    np.testing.assert_allclose(x2, x, atol=1e-12)
    np.testing.assert_allclose(u2, np.sin(x), atol=1e-12)
    np.testing.assert_allclose(v2, np.cos(x), atol=1e-12)


def test_spectrum_general_laplace_normal_form_and_hand_agree():
    plant, hand = general_plant(), hand_plant()
    # Laplace route on the physical plant (no change of variables): e^{D(L)} times the hand one.
    physical = boundary_function(plant, S, scaled=True, steps=1600) / np.exp(-0.8)
    by_hand = boundary_function(hand, S, scaled=True, steps=1600)
    np.testing.assert_allclose(physical, by_hand, atol=1e-9)  # both fourth-order Magnus, 1600 steps
    # Kernel route: the normal form and the hand-made plant agree to rounding (measured 4e-15);
    # against the Laplace route, third order in the grid (1.2e-6, 1.5e-7, 1.9e-8 at 101, 201, 401).
    form_char = delay_form(plant.normal_form().system).characteristic
    hand_char = delay_form(hand).characteristic
    np.testing.assert_allclose(form_char(S), hand_char(S), atol=1e-12)
    np.testing.assert_allclose(delay_form(plant).characteristic(S), hand_char(S), atol=1e-12)
    np.testing.assert_allclose(form_char(S), by_hand, atol=3e-7)
    box = (-1.5, 1.0, 0.0, 30.0)
    r1, r2 = find_roots(form_char, box), find_roots(hand_char, box)
    assert len(r1.roots) == len(r2.roots) > 5
    np.testing.assert_allclose(np.sort_complex(r1.roots), np.sort_complex(r2.roots), atol=1e-8)


def test_laplace_route_is_fourth_order_for_varying_speeds():
    plant = GeneralHyperbolic2x2(lambda x: 1.0 + x, lambda x: 2.0 - x, 0.2, np.cos, 0.5, -0.3, 0.9, 0.6)
    ref = boundary_function(plant, S, scaled=True, steps=6400)
    errs = [np.abs(boundary_function(plant, S, scaled=True, steps=n) - ref).max() for n in (200, 400, 800)]
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(orders > 3.7), orders


def test_as_general_round_trip():
    hand = hand_plant()
    back = as_general(hand).normal_form().system
    np.testing.assert_allclose(boundary_function(back, S, scaled=True), boundary_function(hand, S, scaled=True))


# ------------------------------------------------------------------ margins and simulation
@pytest.mark.parametrize("controller", [ReflectionController(0.1), FiniteTimeController()])
def test_margins_general_equal_hand(controller):
    m1 = delay_margin(general_plant(), controller)
    m2 = delay_margin(hand_plant(), controller)
    assert m1.nominally_stable == m2.nominally_stable
    # Both on 201-point kernels of plants equal to 1e-11: the margins agree to the kernels'
    # interpolation of the couplings, far below the 1e-6 asserted.
    np.testing.assert_allclose(m1.margin, m2.margin, rtol=1e-6)


def test_state_feedback_in_physical_coordinates_equals_mapped_gains():
    """``U = -0.3 u(L) + int 0.2 v dx`` on the plant = the hand-mapped gains on the hand plant."""
    plant, hand = general_plant(), hand_plant()
    physical = StateFeedback(-0.3, 0.0, 0.2)
    # k~ = k e^{A(L) + k_b - D(L)}, g~_v = e^{-D(L)} g_v e^{D} t_u lam at x(y).
    mapped = StateFeedback(
        -0.3 * np.exp(0.7),
        0.0,
        lambda y: np.exp(0.8) * 0.2 * np.exp(-0.4 * x_of_y(y)) * 2.0 * LN2 * lam(x_of_y(y)),
    )
    A1, B1 = loop_factors(plant, physical)
    _, B2 = loop_factors(hand, mapped)
    np.testing.assert_allclose(B1(S), B2(S), atol=1e-9)
    # Independent: the Laplace route on the physical plant with the physical gains.
    AL, BL = laplace_loop_factors(plant, -0.3, 0.0, 0.2, S, steps=1600)
    # Kernel route at 201 points against Magnus at 1600 steps: third order, measured 1.5e-7.
    np.testing.assert_allclose(AL, A1(S), atol=3e-7)
    np.testing.assert_allclose(BL, B1(S), atol=3e-7)
    m1, m2 = delay_margin(plant, physical), delay_margin(hand, mapped)
    np.testing.assert_allclose(m1.margin, m2.margin, rtol=1e-7)


def test_simulated_norms_general_equal_hand():
    plant, hand = general_plant(), hand_plant()
    form = plant.normal_form()

    def u0(x):
        return np.sin(np.pi * np.asarray(x) / 2.0)

    def v0(x):
        return np.full(np.shape(x), 0.5)

    # Initial data of the physical plant, carried to y by the maps of the normal form.
    def u0n(y):
        return form.to_normal(form.x_of_y(y), u0(form.x_of_y(y)), 0.0)[1]

    def v0n(y):
        return form.to_normal(form.x_of_y(y), 0.0, v0(form.x_of_y(y)))[2]

    def u0h(y):
        return u0(x_of_y(y)) * np.exp(-0.3 * x_of_y(y) + 0.7)

    def v0h(y):
        return v0(x_of_y(y)) * np.exp(0.4 * x_of_y(y))

    ctl = ReflectionController(0.1)
    a = simulate(form.system, ctl, 0.05, 4.0, u0n, v0n, cells=100)
    b = simulate(hand, ctl, 0.05, 4.0, u0h, v0h, cells=100)
    # Same scheme, plants equal to 1e-11, kernels interpolated: measured agreement 1e-9.
    np.testing.assert_allclose(a.norm, b.norm, rtol=1e-7)


# ------------------------------------------------------------------ any state feedback
def test_paper_controllers_are_state_feedbacks():
    """U_BS2(K)'s feedback law as a StateFeedback gives the paper's B = K q e^{-tau s} - I_N."""
    plant = Hyperbolic2x2(1.0, 2.0, lambda x: 1.0 + np.cos(x), lambda x: 0.5 * x, 0.8, 0.7)
    kernels = solve_kernels(plant)
    for controller in (ReflectionController(0.1), FiniteTimeController()):
        law = controller.feedback_law(plant, kernels)
        P = feedback_factor(plant, law.boundary_gain, law.gain_u, law.gain_v)
        _, B = loop_factors(plant, controller, kernel_grid=DEFAULT_KERNEL_GRID)  # the kernels of the law
        # The kernel gains are P1 interpolants of the same tables: measured 4e-10.
        np.testing.assert_allclose(-P(S), B(S), atol=1e-8)


def test_state_feedback_kernel_route_converges_to_laplace_route():
    plant = Hyperbolic2x2(1.0, 2.0, lambda x: 1.0 + np.cos(x), lambda x: 0.5 * x, 0.8, 0.7)

    def g_u(x):
        return 0.3 * np.sin(3.0 * np.asarray(x))

    def g_v(x):
        return -0.2 + 0.1 * np.asarray(x)

    _, BL = laplace_loop_factors(plant, -0.2, g_u, g_v, S, steps=1600)
    errs = [np.abs(-feedback_factor(plant, -0.2, g_u, g_v, kernel_grid=n)(S) - BL).max() for n in (101, 201, 401)]
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    # Measured: 5.9e-8 at 201 points, 7.4e-9 at 401 (third order, as the kernels).
    assert errs[1] < 1e-7
    assert np.all(orders > 2.5), orders


def test_proportional_state_feedback_kernel_route_converges_to_laplace_route():
    """``U = k u(t, 1)`` alone: the inner integrals of the zero gains are zero (not summed), the kernel route still
    converges to the Laplace route at third order."""
    plant = Hyperbolic2x2(1.0, 1.0, 1.5, 0.5, 0.8, 0.4)
    _, BL = laplace_loop_factors(plant, -0.5, 0.0, 0.0, S, steps=1600)
    errs = [np.abs(-feedback_factor(plant, -0.5, 0.0, 0.0, kernel_grid=n)(S) - BL).max() for n in (101, 201, 401)]
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    # Measured: 7.1e-9 at 201 points, 9.6e-10 at 401 (orders 2.8, 2.9).
    assert errs[1] < 1e-7
    assert np.all(orders > 2.5), orders


def test_proportional_feedback_on_transport_has_the_closed_form_margin():
    """``U = -k u(1)`` on ``1 - rho q e^{-tau s} + k q e^{-(tau+delta) s}``: margin 0 or inf by |rho q| vs |k q|."""
    plant = TransportSystem(1.0, 1.0, 1.0, 0.4)
    _, B = loop_factors(plant, StateFeedback(-0.3))
    np.testing.assert_allclose(B(S), 0.3 * np.exp(-2.0 * S), atol=1e-15)
    assert delay_margin(plant, StateFeedback(-0.3)).margin == np.inf


def test_state_feedback_validation_and_normalize():
    with pytest.raises(ParameterError) as err:
        StateFeedback(np.nan)
    assert err.value.name == "k"
    with pytest.raises(ParameterError) as err:
        StateFeedback(0.1, g_v="x")
    assert err.value.name == "g_v"
    system, controller = normalize(general_plant(), StateFeedback(-0.3))
    assert isinstance(system, Hyperbolic2x2)
    assert controller.k == pytest.approx(-0.3 * np.exp(0.7), rel=1e-12)


# ------------------------------------------------------------------ varying speed ratio
VARYING = GeneralHyperbolic2x2(lambda x: 1.0 + x, lambda x: 2.0 - x, 0.2, np.cos, 0.5, -0.3, 0.9, 0.6)


def test_characteristic_delay_form_converges_to_laplace_route():
    """Varying lam/mu: the characteristic (Goursat) route against Magnus; observed order >= 3.5."""
    ref = boundary_function(VARYING, S, scaled=True, steps=3200) * np.exp(-VARYING.D(1.0))
    errs = np.array([np.abs(varying_delay_form(VARYING, n).characteristic(S) - ref).max() for n in (50, 100, 200)])
    orders = np.log2(errs[:-1] / errs[1:])
    # Measured: 7.8e-9, 2.5e-10, 9.1e-12 (orders 5.0, 4.8: trapezoid + Richardson, cubic-spline N~).
    assert np.all(orders > 3.5), orders
    assert errs[-1] < 1e-10
    assert varying_delay_form(VARYING).rho_q == pytest.approx(VARYING.rho_q, rel=1e-12)


def test_characteristic_route_agrees_with_the_normal_form_kernels():
    """Constant ratio: the two routes to the delay form of the same plant."""
    plant = general_plant()
    by_kernels = delay_form(plant.normal_form().system).characteristic(S)
    by_characteristics = varying_delay_form(plant).characteristic(S)
    np.testing.assert_allclose(by_characteristics, by_kernels, atol=3e-7)  # kernel error, 1.5e-7 measured


def test_varying_ratio_margins_and_refusals():
    """A proportional feedback on a varying-ratio plant: the margin's crossing is a zero of the Laplace route."""
    margin = delay_margin(VARYING, StateFeedback(-0.3))
    assert np.isfinite(margin.margin) and margin.omega is not None
    A, B = laplace_loop_factors(VARYING, -0.3, 0.0, 0.0, np.array([1j * margin.omega]), steps=1600)
    assert abs(A[0] + B[0] * np.exp(-1j * margin.omega * margin.margin)) < 1e-8
    with pytest.raises(ParameterError, match="normal form") as err:
        loop_factors(VARYING, ReflectionController(0.1))
    assert err.value.name == "controller"
    # integral gains: B by the kernels with varying speeds (tests/test_varying_kernels.py checks it)
    assert loop_factors(VARYING, StateFeedback(0.1, g_u=1.0))[1].distributed
    with pytest.raises(ParameterError) as err:
        varying_delay_form(VARYING, 101)
    assert err.value.name == "steps"


def test_time_unit_scales_the_characteristic_route():
    minutes = GeneralHyperbolic2x2(
        lambda x: 1.0 + x, lambda x: 2.0 - x, 0.2, np.cos, 0.5, -0.3, 0.9, 0.6, time_unit=60.0
    )
    np.testing.assert_allclose(
        varying_delay_form(minutes).characteristic(60.0 * S), varying_delay_form(VARYING).characteristic(S), atol=1e-12
    )
    np.testing.assert_allclose(
        boundary_function(minutes, 60.0 * S, scaled=True, steps=800),
        boundary_function(VARYING, S, scaled=True, steps=800),
        atol=1e-12,
    )


# ------------------------------------------------------------------ simulation with varying speeds
UNSTABLE = GeneralHyperbolic2x2(
    lambda x: 1.0 + x, lambda x: 2.0 - 0.5 * x, 0.2, lambda x: 2.0 + np.cos(x), 1.5, -0.3, 0.9, 0.6
)


def _rate(run, after: float) -> float:
    late = run.times > after
    return float(np.polyfit(run.times[late], np.log(run.norm[late]), 1)[0])


def test_simulated_growth_rate_converges_to_the_spectral_abscissa():
    """Varying lam/mu, t_v/dt not an integer: the fitted growth rate against the certified abscissa."""
    abscissa = spectral_abscissa(characteristic(UNSTABLE, OpenLoop())).value
    errs = []
    for cells in (25, 50, 100):
        run = simulate_general(UNSTABLE, OpenLoop(), 0.0, 8.0, lambda x: np.sin(3.0 * x) + 1.0, 0.5, cells)
        errs.append(abs(_rate(run, 4.0) - abscissa))
    # Measured: 3.8e-4, 8.9e-5, 3.2e-5 (second-order scheme; the fit over [4, 8] adds ~1e-5).
    assert errs[1] < errs[0] / 3.0
    assert errs[2] < 5e-5


def test_simulation_confirms_the_margin_of_a_varying_ratio_plant():
    plant = GeneralHyperbolic2x2(lambda x: 1.0 + x, lambda x: 2.0 - 0.5 * x, 0.2, np.cos, 0.5, -0.3, 0.9, 0.6)
    margin = delay_margin(plant, StateFeedback(-0.3)).margin
    below = simulate_general(plant, StateFeedback(-0.3), 0.9 * margin, 60.0, 1.0, 0.5, 40)
    above = simulate_general(plant, StateFeedback(-0.3), 1.1 * margin, 60.0, 1.0, 0.5, 40)
    # Measured rates: -0.017 and +0.028 (the crossing pair moves right through the axis at delta*).
    assert _rate(below, 30.0) < -0.005
    assert _rate(above, 30.0) > 0.005


def test_simulate_general_validation():
    with pytest.raises(ParameterError) as err:
        simulate_general(UNSTABLE, ReflectionController(0.1), 0.0, 1.0, 1.0, 1.0)
    assert err.value.name == "controller"
    with pytest.raises(ParameterError) as err:
        simulate_general(UNSTABLE, OpenLoop(), -1.0, 1.0, 1.0, 1.0)
    assert err.value.name == "delta"
    with pytest.raises(ParameterError) as err:
        simulate_general(UNSTABLE, OpenLoop(), 0.0, 1e6, 1.0, 1.0, cells=10**5)
    assert err.value.name == "cells"
    with pytest.raises(ParameterError) as err:
        simulate_general(UNSTABLE, OpenLoop(), 0.0, 1.0, lambda x: np.nan * x, 1.0)
    assert err.value.name == "u0"


def test_sampled_coefficients_and_json():
    """Samples of a smooth speed give the callable's normal form to the spline's accuracy; to_dict is strict JSON."""
    x = np.linspace(0.0, 2.0, 41)
    sampled = GeneralHyperbolic2x2((x, lam(x)), (x, 2.0 * lam(x)), 0.0, np.cos, 0.5, 0.0, Q, RHO, length=2.0)
    exact = GeneralHyperbolic2x2(lam, lambda t: 2.0 * lam(t), 0.0, np.cos, 0.5, 0.0, Q, RHO, length=2.0)
    np.testing.assert_allclose(sampled.transport_times, exact.transport_times, rtol=1e-7)  # cubic spline, h = 0.05
    assert sampled.constant_ratio
    text = json.dumps(general_plant().to_dict(), allow_nan=False)
    assert '"callable"' in text and '"time_unit": 1.0' in text
    assert json.loads(json.dumps(sampled.to_dict(), allow_nan=False))["lam"]["x"][-1] == 2.0


# ------------------------------------------------------------------ simulate() and the studies on general plants
def _trapezoid(nodes):
    w = np.zeros(nodes.size)
    w[:-1] += np.diff(nodes) / 2.0
    w[1:] += np.diff(nodes) / 2.0
    return w


def test_simulate_a_general_plant_equals_the_hand_normalised_plant():
    """simulate(general plant): the hand plant's states, weighted by the closed-form maps, give the same norm."""
    plant, hand = general_plant(), hand_plant()

    def u0(x):
        return np.sin(np.pi * np.asarray(x) / 2.0)

    def v0(x):
        return np.full(np.shape(x), 0.5)

    ctl = ReflectionController(0.1)
    a = simulate(plant, ctl, 0.05, 4.0, u0, v0, cells=100)
    b = simulate(
        hand,
        ctl,
        0.05,
        4.0,
        lambda y: u0(x_of_y(y)) * np.exp(0.7 - 0.3 * x_of_y(y)),
        lambda y: v0(x_of_y(y)) * np.exp(0.4 * x_of_y(y)),
        cells=100,
        snapshot_every=1,
    )
    # u = e^{0.3 x - 0.7} u~, v = e^{-0.4 x} v~, dx = 2 ln 2 (1 + x/2) dy (module notes)
    X, XV = x_of_y(b.x), x_of_y(b.x_v)
    wu = _trapezoid(b.x) * np.exp(0.6 * X - 1.4) * 2.0 * LN2 * (1.0 + X / 2.0)
    wv = _trapezoid(b.x_v) * np.exp(-0.8 * XV) * 2.0 * LN2 * (1.0 + XV / 2.0)
    # Same scheme on plants equal to 1e-11: measured 9e-15.
    np.testing.assert_allclose(a.norm, np.sqrt(b.u**2 @ wu + b.v**2 @ wv), rtol=1e-9)
    np.testing.assert_allclose(a.x, X, atol=1e-12)
    np.testing.assert_allclose(a.control, np.exp(-0.8) * b.control, rtol=1e-9, atol=1e-14)  # U = e^{D(L)} U~
    np.testing.assert_allclose(a.u[-1], b.u[-1] * np.exp(0.3 * X - 0.7), rtol=1e-9, atol=1e-12)


def test_simulate_through_the_normal_form_converges_to_the_time_of_flight_scheme():
    """Two schemes sharing nothing but the plant (normal form and kernels against the physical grids): 2nd order."""
    plant, feedback = general_plant(), StateFeedback(-0.2)

    def u0(x):  # compatible: u(0) = q v(0), v(L) = rho u(L) + k u(L) = 0
        return Q * np.cos(np.pi * np.asarray(x) / 4.0)

    def v0(x):
        return np.cos(np.pi * np.asarray(x) / 4.0)

    times = np.linspace(0.0, 4.0, 9)
    errs = []
    for cells in (50, 100, 200):
        a = simulate(plant, feedback, 0.05, 4.0, u0, v0, cells=cells)
        b = simulate_general(plant, feedback, 0.05, 4.0, u0, v0, cells=cells)
        errs.append(np.max(np.abs(np.interp(times, a.times, a.norm) - np.interp(times, b.times, b.norm))))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    # Measured: 1.2e-3, 3.1e-4, 7.6e-5 (orders 1.95, 2.04).
    assert np.all(orders > 1.8), (errs, orders)
    assert errs[-1] < 1.5e-4


def test_simulated_growth_rate_of_a_paper_controller_on_a_general_plant():
    """U_BS2(0.4) beyond its margin: the fitted growth rate against the spectral abscissa of the general loop."""
    plant, ctl, delta = general_plant(), ReflectionController(0.4), 2.0
    abscissa = spectral_abscissa(characteristic(plant, ctl, delta)).value
    assert abscissa > 0.2  # the pair 0.2143 +- 0.5788i
    run = simulate(plant, ctl, delta, 40.0, lambda x: 1.0 + np.sin(3.0 * x), lambda x: 0.5 + 0.0 * x, cells=25)
    # Measured 2.1e-4 (cells 25), 3.7e-4 (50, 100): the bias of a log-linear fit of an oscillating norm
    # (period 10.9) over [10, 40], not the grid's error.
    assert abs(run.growth_rate(10.0, 40.0) - abscissa) < 2e-3


def test_simulate_a_varying_ratio_plant_and_refusals():
    feedback = StateFeedback(-0.3)
    a = simulate(VARYING, feedback, 0.1, 2.0, lambda x: 1.0 + 0.0 * x, lambda x: 0.5 + 0.0 * x, cells=40)
    b = simulate_general(VARYING, feedback, 0.1, 2.0, 1.0, 0.5, 40)
    np.testing.assert_array_equal(a.norm, b.norm)
    assert a.scheme == "time-of-flight grids" and a.u.shape == (1, b.x_u.size)
    with pytest.raises(ParameterError, match="normal form") as err:
        simulate(VARYING, ReflectionController(0.1), 0.1, 2.0, 1.0, 0.5)
    assert err.value.name == "controller"
    kept = simulate(VARYING, feedback, 0.1, 2.0, 1.0, 0.5, cells=40, snapshot_every=2)
    np.testing.assert_array_equal(kept.snapshot_times, kept.times[::2])
    np.testing.assert_array_equal(kept.u[-1], b.u)
    with pytest.raises(ParameterError) as err:  # the work bound, before any grid is allocated
        simulate(general_plant(), ReflectionController(0.1), 0.0, 1e6, np.sin, np.cos, cells=10**8)
    assert err.value.name == "(cells, t_end)"
    law = ReflectionController(0.1).feedback_law(hand_plant(), solve_kernels(hand_plant(), 21))
    with pytest.raises(ParameterError) as err:
        simulate(general_plant(), law, 0.1, 2.0, np.sin, np.cos)
    assert err.value.name == "controller"


@pytest.mark.slow
def test_studies_of_a_general_plant_equal_those_of_the_hand_plant():
    plant, hand = general_plant(), hand_plant()
    a = stability_chart(plant, [0.0, 0.1], [0.0, 0.5, 1.5])
    b = stability_chart(hand, [0.0, 0.1], [0.0, 0.5, 1.5])
    # The hand plant's couplings are functions with a proven N~ (exact route); the general plant's normal form
    # has tabulated couplings (kernel route, 101 points, third order): measured apart by 2.2e-7 relative
    # (here and below).
    np.testing.assert_allclose(a.margins, b.margins, rtol=1e-6)
    np.testing.assert_array_equal(a.values, b.values)
    a = ab_region(plant, 0.1, [0.0, 0.5], [0.2])
    b = ab_region(hand, 0.1, [0.0, 0.5], [0.2])
    np.testing.assert_allclose(a.margins, b.margins, rtol=1e-6)
    np.testing.assert_array_equal(a.strongly_stable, b.strongly_stable)
    for ctl in (ReflectionController(0.1), FiniteTimeController()):
        np.testing.assert_allclose(
            rouche_delay_bound(plant, ctl).delta_0, rouche_delay_bound(hand, ctl).delta_0, rtol=1e-6
        )
    # A family in physical coordinates: StateFeedback(k) acts on u(t, L), mapped to the normal form.
    form = plant.normal_form()
    physical = tradeoff(plant, [-0.2, 0.2], controller=StateFeedback)
    by_hand = [delay_margin(hand, StateFeedback(form.feedback_to_normal(k, 0.0, 0.0)[0])).margin for k in (-0.2, 0.2)]
    np.testing.assert_allclose(physical.margins, by_hand, rtol=1e-6)
    assert np.all(np.isnan(physical.rouche_bounds))


@pytest.mark.slow
def test_k_region_of_a_general_plant_equals_the_hand_plant():
    a, b = k_region(general_plant(), 0.1, n_gains=3), k_region(hand_plant(), 0.1, n_gains=3)
    np.testing.assert_allclose(np.array(a.intervals), np.array(b.intervals), rtol=1e-9)


@pytest.mark.slow
def test_k_region_of_a_varying_ratio_plant_ends_are_zeros_of_the_laplace_route():
    """U = k u(t, L) on a varying lam/mu: at each end's root on the axis, the Laplace route solves for k."""
    region = k_region(VARYING, 0.5, controller=StateFeedback, Ks=[-0.4, -0.3], tol=1e-3)
    ((lower, upper),) = region.ends
    # lower: a crossing at w = 9.156 for delta = 0.324; upper: the nominal loop's real root through s = 0.
    assert np.isfinite(lower.omega) and upper.omega == np.inf and upper.delay == 0.0
    for end, w in ((lower, lower.omega), (upper, 0.0)):
        # F = A + k B_1 e^{-i w delay} is affine in k: the gain that puts a root at i w, without the delay form.
        A, B1 = laplace_loop_factors(VARYING, 1.0, 0.0, 0.0, np.array([1j * w]), steps=1600)
        k = -A[0] * np.exp(1j * w * end.delay) / B1[0]
        # The end is bisected to tol; its root is that of the gain just outside (measured 2.9e-4 from k).
        assert abs(k.imag) < 1e-8 and abs(k.real - end.K) < 2.0 * region.tol, (end, k)


def test_studies_refuse_u_bs2_on_a_varying_ratio_plant_by_name():
    for study in (lambda: k_region(VARYING, 0.5), lambda: stability_chart(VARYING, [0.1], [0.0, 1.0])):
        with pytest.raises(ParameterError, match="normal form") as err:
            study()
        assert err.value.name == "controller"
    with pytest.raises(ParameterError, match="FiniteTimeController") as err:
        rouche_delay_bound(VARYING, ReflectionController(0.1))
    assert err.value.name == "controller"


def test_rouche_bound_of_a_varying_ratio_plant():
    """U_BS, characteristic route: delta_0 below the delay margin, and equal to the kernel route's at constant ratio."""
    plant = GeneralHyperbolic2x2(lambda x: 1.0 + x, lambda x: 2.0 - x, 0.2, np.cos, 0.5, -0.3, 0.9, 0.3)
    bound = rouche_delay_bound(plant, FiniteTimeController())
    np.testing.assert_allclose(bound.epsilon_0, 1.0 - 2.0 * abs(plant.rho_q), rtol=1e-14)
    margin = delay_margin(plant, FiniteTimeController())
    assert 0.0 < bound.delta_0 < margin.margin  # 0.5656 < 1.5777
    proven = rouche_delay_bound(plant, FiniteTimeController(), rigorous=True)
    assert proven.rigorous and proven.delta_0 < margin.margin
    np.testing.assert_allclose(proven.delta_0, bound.delta_0, rtol=1e-6)  # two marches: measured 1.7e-8 apart
    # Constant ratio: N~ of the characteristic route against the kernels' (measured 1.4e-6 apart: 6e-6 relative).
    by_characteristics = _varying_bound(general_plant(), FiniteTimeController(), False).delta_0
    by_kernels = rouche_delay_bound(hand_plant(), FiniteTimeController()).delta_0
    np.testing.assert_allclose(by_characteristics, by_kernels, rtol=3e-5)


def test_certify_a_varying_ratio_plant():
    cert = certify(VARYING, StateFeedback(-0.3), delta_max=0.5, k_region=False)
    margin = delay_margin(VARYING, StateFeedback(-0.3))
    np.testing.assert_allclose(cert.delay_margin, margin.margin, rtol=1e-12)
    assert cert.system is VARYING and "lam/mu varies" in cert.classification.statement
    np.testing.assert_allclose(cert.classification.rho_q, VARYING.rho_q, rtol=1e-15)
    assert cert.region[3] == pytest.approx(40.0 / VARYING.tau)
    json.loads(cert.to_json())


def test_a_run_shorter_than_one_step_makes_one_step() -> None:
    """``t_end`` below one time step: one step (the first sampled time >= t_end), as ``simulate``
    does for the paper's plant, not a division by zero."""
    plant = GeneralHyperbolic2x2(lambda x: 1.0 + x, lambda x: 2.0 - x, 0.2, 0.1, 0.5, -0.3, 0.9, 0.6)
    sim = simulate_general(plant, StateFeedback(0.0), 0.0, 1e-13, 1.0, 1.0, cells=20)
    assert sim.times.size == 2 and sim.times[-1] >= 1e-13
    assert np.all(np.isfinite(sim.norm))


def test_normal_form_coupling_repr_reads_its_offset_with_one_sign():
    """The repr of a normal-form coupling (in certificate.json) writes ``D - A + 0.1``, not ``D - A - -0.1``."""
    plant = GeneralHyperbolic2x2(
        lam=1.0, mu=2.0, a=lambda x: 0.3 - 0.1 * x, b=0.5, c=0.4, d=-0.2, q=0.9, rho=0.6, length=2.0
    )
    form = plant.normal_form()
    assert form.balance < 0
    text = repr(form.system.sigma_pm)
    assert "- -" not in text and f"D - A + {-form.balance:.6g}" in text
