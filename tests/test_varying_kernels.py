"""Backstepping kernels with varying speeds and U_BS on a general plant.

Independent checks: the paper's kernels (constant speeds), the normal-form route (constant
ratio, diagonal terms, ``L = 2``), the kernel-free Laplace route with the same feedback law
(``A + B = 1`` is the finite-time property of U_BS in the Laplace domain), the characteristic
route of :mod:`nrobust.hyperbolic.loops.varying_form`, and simulation (finite time without delay,
growth rate against the spectral abscissa with a delay).
"""

from __future__ import annotations

import numpy as np
import pytest

from nrobust import spectral_abscissa
from nrobust.errors import ParameterError
from nrobust.hyperbolic import (
    FeedbackLaw,
    FiniteTimeController,
    GeneralHyperbolic2x2,
    Hyperbolic2x2,
    StateFeedback,
    characteristic,
    laplace_loop_factors,
    loop_factors,
    solve_kernels,
    solve_varying_kernels,
    varying_delay_form,
)
from nrobust.hyperbolic.analyses import delay_margin
from nrobust.hyperbolic.plants.general import as_general
from nrobust.hyperbolic.simulate import simulate
from nrobust.hyperbolic.simulate.general import simulate_general

S = np.array([0.1 + 0.5j, -0.3 + 3.0j, 0.5 + 8.0j, 1.0 + 0.0j, 0.2 + 15.0j])
# lam/mu varies from 1/2 to 2; diagonal terms a = 0.2, d = -0.3.
VARYING = GeneralHyperbolic2x2(lambda x: 1.0 + x, lambda x: 2.0 - x, 0.2, np.cos, 0.5, -0.3, 0.9, 0.6)


def _orders(errors: list[float]) -> np.ndarray:
    e = np.asarray(errors)
    return np.log2(e[:-1] / e[1:])


def test_constant_speeds_reproduce_the_paper_kernels():
    """lam != mu constant, L = 1, no diagonal term: the march is that of kernels.py, node for node."""
    system = Hyperbolic2x2(1.0, 2.0, lambda x: 1.0 + 0.5 * np.sin(3.0 * x), lambda x: 0.8 * np.cos(x), 0.9, 0.6)
    vk = solve_varying_kernels(as_general(system), 41)
    plain = solve_kernels(system, 41, extrapolate=False)
    # Measured 5e-16 (K) and 8e-16 (L): the feet from the transport-time tables equal j + kappa to rounding.
    np.testing.assert_allclose(vk.K, plain.K, rtol=0, atol=1e-13)
    np.testing.assert_allclose(vk.L, plain.L, rtol=0, atol=1e-13)
    ref = solve_kernels(system, 321)  # extrapolated, about third order: the reference of the kernel studies
    errs = [
        np.abs(solve_varying_kernels(as_general(system), n).K[:, :, -1] - ref.K[:, :, -1, :: 320 // (n - 1)]).max()
        for n in (41, 81, 161)
    ]
    # Measured 4.2e-4, 1.0e-4, 2.6e-5 (orders 2.00, 2.00): the plain scheme's second order.
    orders = _orders(errs)
    assert np.all((orders > 1.8) & (orders < 2.3)), (errs, orders)


def test_constant_ratio_general_plant_equals_the_normal_form_route():
    """Diagonal terms, L = 2, varying lam = mu/2: U_BS's loop factors against the normal form's kernels."""

    def lam(x):
        return 1.0 + 0.5 * np.asarray(x)

    plant = GeneralHyperbolic2x2(
        lam, lambda x: 2.0 * lam(x), lambda x: 0.3 * lam(x), np.cos, 0.5, lambda x: 0.8 * lam(x), 0.8, 0.1, length=2.0
    )
    a_ref, b_ref = loop_factors(plant, FiniteTimeController())  # extrapolated kernels, third order
    errs = [np.abs(solve_varying_kernels(plant, n).loop_factors()[1](S) - b_ref(S)).max() for n in (51, 101, 201)]
    # Measured 2.1e-4, 5.4e-5, 1.3e-5 (orders 1.95, 2.02).
    orders = _orders(errs)
    assert np.all((orders > 1.8) & (orders < 2.3)), (errs, orders)
    assert errs[-1] < 3e-5
    a, _ = solve_varying_kernels(plant, 201).loop_factors()
    np.testing.assert_allclose(a(S), a_ref(S), rtol=0, atol=3e-5)


def test_observed_order_is_two_against_the_laplace_and_characteristic_routes():
    """Varying lam/mu: the finite-time defect |A + B - 1| of U_BS by the Laplace route, and N~ against the
    characteristic route, both second order."""
    reference = varying_delay_form(VARYING, 800).characteristic(S)  # fourth order, 1e-12 here
    defects, gaps = [], []
    for n in (51, 101, 201):
        vk = solve_varying_kernels(VARYING, n)
        law = vk.feedback_law()
        A, B = laplace_loop_factors(VARYING, law.boundary_gain, law.gain_u, law.gain_v, S, steps=1600)
        defects.append(np.abs(A + B - 1.0).max())
        gaps.append(np.abs(vk.loop_factors()[0](S) - reference).max())
    # Measured defects 5.7e-7, 1.4e-7, 3.6e-8 (orders 2.00, 2.01); gaps 1.3e-5, 3.3e-6, 7.9e-7 (1.91, 2.09).
    for errs in (defects, gaps):
        orders = _orders(errs)
        assert np.all((orders > 1.8) & (orders < 2.3)), (errs, orders)
    assert defects[-1] < 1e-7 and gaps[-1] < 2e-6


def test_kernel_route_characteristic_equals_the_laplace_route():
    """(b): F(s; delta) of U_BS from the kernels against laplace_loop_factors on the same feedback law."""
    vk = solve_varying_kernels(VARYING)
    law = vk.feedback_law()
    A, B = laplace_loop_factors(VARYING, law.boundary_gain, law.gain_u, law.gain_v, S, steps=1600)
    a, b = vk.loop_factors()
    # Tolerance from the convergence study above: 8e-7 at the default 201 points, order 2.
    np.testing.assert_allclose(a(S), A, rtol=0, atol=2e-6)
    np.testing.assert_allclose(b(S), B, rtol=0, atol=2e-6)
    for delta in (0.0, 0.3):
        np.testing.assert_allclose(vk.characteristic(delta)(S), A + B * np.exp(-delta * S), rtol=0, atol=4e-6)
    np.testing.assert_allclose(vk.characteristic()(S), 1.0, rtol=0, atol=2e-6)  # finite time: F = 1


def test_any_state_feedback_on_a_varying_plant_by_the_kernel_route():
    """Integral gains on a varying lam/mu: B of loop_factors against the Laplace route, and U_BS as a
    StateFeedback against FiniteTimeController (characteristic route)."""
    feedback = StateFeedback(-0.3, lambda x: -0.2 * np.cos(2.0 * x), -0.1)
    _, b = loop_factors(VARYING, feedback)
    _, b_laplace = laplace_loop_factors(VARYING, -0.3, feedback.g_u, -0.1, S, steps=1600)
    # Measured 6.8e-6, 1.7e-6, 4.3e-7 at 51, 101, 201 points (order 2.0).
    np.testing.assert_allclose(b(S), b_laplace, rtol=0, atol=1.5e-6)
    law = solve_varying_kernels(VARYING).feedback_law()
    as_state_feedback = loop_factors(VARYING, StateFeedback(law.boundary_gain, law.gain_u, law.gain_v))[1]
    np.testing.assert_allclose(as_state_feedback(S), loop_factors(VARYING, FiniteTimeController())[1](S), atol=3e-6)
    margin = delay_margin(VARYING, feedback)
    assert np.isfinite(margin.margin) and margin.omega is not None
    w = np.array([1j * margin.omega])
    A, B = laplace_loop_factors(VARYING, -0.3, feedback.g_u, -0.1, w, steps=1600)
    # Measured 2.4e-7 (margin 2.0938 at omega 0.4642): the crossing is a zero of the kernel-free loop.
    assert abs(A[0] + B[0] * np.exp(-1j * margin.omega * margin.margin)) < 2e-6


def test_time_unit_scales_the_kernel_route():
    minutes = GeneralHyperbolic2x2(
        lambda x: 1.0 + x, lambda x: 2.0 - x, 0.2, np.cos, 0.5, -0.3, 0.9, 0.6, time_unit=60.0
    )
    a_min, b_min = solve_varying_kernels(minutes, 51).loop_factors()
    a, b = solve_varying_kernels(VARYING, 51).loop_factors()
    np.testing.assert_allclose(a_min(60.0 * S), a(S), rtol=0, atol=1e-12)
    np.testing.assert_allclose(b_min(60.0 * S), b(S), rtol=0, atol=1e-12)


def _compatible_initial_state(law: FeedbackLaw):
    """A smooth state with u(0) = q v(0) = 0 and U(0) = 0, so that the solution stays smooth."""
    x = np.linspace(0.0, 1.0, 4001)

    def bump(k):
        return lambda t: np.sin(k * np.pi * np.asarray(t)) ** 4

    b1, b2 = bump(1), bump(2)
    ints = [np.trapezoid(f, x) for f in (law.gain_u(x) * b1(x), law.gain_v(x) * b1(x), law.gain_u(x) * b2(x))]
    c = -(ints[0] + ints[1]) / ints[2]
    return (lambda t: b1(t) + c * b2(t)), b1


def test_u_bs_brings_the_state_to_zero_at_tau():
    """(c), no delay: the norm after tau is the scheme's residual, second order in the grids."""
    residuals = []
    for cells in (50, 100, 200):
        law = solve_varying_kernels(VARYING, cells + 1).feedback_law()
        u0, v0 = _compatible_initial_state(law)
        run = simulate_general(VARYING, law, 0.0, 2.0 * VARYING.tau, u0, v0, cells)
        assert abs(run.control[0]) < 1e-8
        assert run.norm[np.searchsorted(run.times, 0.5 * VARYING.tau)] > 0.1  # not zero before tau
        residuals.append(run.norm[run.times > VARYING.tau + 2.0 * run.dt].max() / run.norm[0])
    # Measured 1.6e-4, 4.2e-5, 1.1e-5 (relative to the initial norm 1.07): order 1.9, 2.0.
    orders = _orders(residuals)
    assert np.all(orders > 1.7), (residuals, orders)
    assert residuals[-1] < 2e-5


@pytest.mark.slow
def test_delayed_u_bs_grows_at_the_spectral_abscissa():
    """(c), delay 0.5: U_BS loses stability (strong couplings); the simulated rate converges to the abscissa."""
    plant = GeneralHyperbolic2x2(
        lambda x: 1.0 + x, lambda x: 2.0 - 0.5 * x, 0.2, lambda x: 1.0 + np.cos(x), 1.5, -0.3, 0.9, 0.3
    )
    delta = 0.5
    vk = solve_varying_kernels(plant)
    abscissa = spectral_abscissa(vk.characteristic(delta))
    assert abscissa.certified and abscissa.chain_value < abscissa.value  # a root, not a chain: 0.0717 vs -0.42
    by_characteristics = spectral_abscissa(characteristic(plant, FiniteTimeController(), delta)).value
    assert abs(abscissa.value - by_characteristics) < 2e-6  # measured 5e-7: the kernels' error at 201 points
    # One mode dominates: the rate is read over whole periods pi/omega of its norm (no fit bias).
    period = np.pi / abs(abscissa.root.imag)
    law = vk.feedback_law()
    errs = []
    for cells in (25, 50, 100):
        run = simulate_general(plant, law, delta, 20.0 + 2.0 * period, lambda x: np.sin(3.0 * x) + 1.0, 0.5, cells)
        log_norm = np.log(run.norm)
        t1 = np.linspace(15.0, 20.0, 11)
        t2 = t1 + 2.0 * period
        rate = np.mean((np.interp(t2, run.times, log_norm) - np.interp(t1, run.times, log_norm)) / (2.0 * period))
        errs.append(abs(rate - abscissa.value))
    # Measured 1.6e-3, 4.1e-4, 9.5e-5 (order 1.9, 2.1).
    assert errs[1] < errs[0] / 3.0 and errs[2] < errs[1] / 3.0, errs
    assert errs[2] < 2e-4


def test_simulate_general_keeps_the_history():
    law = solve_varying_kernels(VARYING, 41).feedback_law()
    run = simulate_general(VARYING, law, 0.2, 2.0, np.cos, 0.5, 40, snapshot_every=7)
    steps = run.times.size - 1
    kept = sorted({*range(0, steps + 1, 7), steps})
    np.testing.assert_array_equal(run.snapshot_times, run.times[kept])
    assert run.u_snapshots.shape == (len(kept), run.x_u.size) and run.v_snapshots.shape == (len(kept), run.x_v.size)
    np.testing.assert_array_equal(run.u_snapshots[-1], run.u)
    np.testing.assert_array_equal(run.u_snapshots[:, -1], run.u_end[kept])
    np.testing.assert_array_equal(run.v_snapshots[:, 0], run.v_start[kept])
    np.testing.assert_allclose(run.u_snapshots[1:, 0], VARYING.q * run.v_start[kept][1:], rtol=1e-14)
    norms = np.sqrt(
        [np.trapezoid(u**2, run.x_u) + np.trapezoid(v**2, run.x_v) for u, v in zip(run.u_snapshots, run.v_snapshots)]
    )
    np.testing.assert_allclose(norms, run.norm[kept], rtol=1e-12)
    default = simulate_general(VARYING, law, 0.2, 2.0, np.cos, 0.5, 40)
    assert default.u_snapshots.shape == (1, run.x_u.size)
    np.testing.assert_array_equal(default.norm, run.norm)
    through = simulate(VARYING, law, 0.2, 2.0, np.cos, lambda x: 0.5 + 0.0 * x, cells=40, snapshot_every=7)
    np.testing.assert_array_equal(through.u, run.u_snapshots)
    np.testing.assert_array_equal(through.snapshot_times, run.snapshot_times)


def test_validation_names_the_parameter():
    with pytest.raises(ParameterError) as err:
        solve_varying_kernels(Hyperbolic2x2(1.0, 1.0, 0.5, 0.5, 0.9, 0.6))
    assert err.value.name == "plant"
    for grid in (4, 10**6, 2.5):
        with pytest.raises(ParameterError) as err:
            solve_varying_kernels(VARYING, grid)
        assert err.value.name == "kernel_grid"
    strong = GeneralHyperbolic2x2(lambda x: 1.0 + x, lambda x: 2.0 - x, 0.0, 60.0, 60.0, 0.0, 0.9, 0.6)
    with pytest.raises(ParameterError, match=">= ") as err:  # too coarse for the couplings, before marching
        solve_varying_kernels(strong, 11)
    assert err.value.name == "kernel_grid"
    hopeless = GeneralHyperbolic2x2(lambda x: 1.0 + x, lambda x: 2.0 - x, 0.0, 1e5, 1e5, 0.0, 0.9, 0.6)
    with pytest.raises(ParameterError, match="MAX_KERNEL_GRID") as err:
        solve_varying_kernels(hopeless)
    assert err.value.name == "plant"
    vk = solve_varying_kernels(VARYING, 21)
    with pytest.raises(ParameterError) as err:
        vk.characteristic(-0.1)
    assert err.value.name == "delta"
    law = vk.feedback_law()
    filtered = FeedbackLaw(law.boundary_gain, law.gain_u, law.gain_v, (0.1, 1.0))
    with pytest.raises(ParameterError) as err:
        simulate_general(VARYING, filtered, 0.0, 1.0, 1.0, 1.0)
    assert err.value.name == "controller"
    with pytest.raises(ParameterError) as err:
        simulate_general(VARYING, StateFeedback(-0.3), 0.0, 1.0, 1.0, 1.0, snapshot_every=0)
    assert err.value.name == "snapshot_every"
    with pytest.raises(ParameterError, match="stored values") as err:  # memory bound, before any allocation
        simulate_general(VARYING, StateFeedback(-0.3), 0.0, 10.0, 1.0, 1.0, 2000, snapshot_every=1)
    assert err.value.name == "snapshot_every"
