"""Closed-loop characteristic functions of the paper's controllers and the classification."""

from __future__ import annotations

import numpy as np
import pytest

from nrobust import ParameterError
from nrobust.hyperbolic.loops.controllers import (
    FeedbackLaw,
    FilteredController,
    FiniteTimeController,
    OpenLoop,
    ReflectionController,
    characteristic,
    classify,
    loop_factors,
)
from nrobust.hyperbolic.plants.hyperbolic2x2 import Hyperbolic2x2, TransportSystem

S = np.array([0.3 + 0.2j, -1.0 + 5.0j, 2.0 - 100.0j, 0.05j, 0.7 + 321.0j])


@pytest.fixture
def transport():
    return TransportSystem(lam=2.0, mu=0.5, q=0.9, rho=0.7)


def test_transport_finite_time_is_eq_delay_eq_no_couplings2(transport):
    """U = -rho u(1): v(t,1) = rho q v(t - tau, 1) - rho q v(t - tau - delta, 1)."""
    rq, tau, delta = transport.rho_q, transport.tau, 0.03
    F = characteristic(transport, FiniteTimeController(), delta)
    np.testing.assert_allclose(F(S), 1 - rq * np.exp(-tau * S) + rq * np.exp(-(tau + delta) * S), rtol=1e-14, atol=0)
    # Without delay the loop is the constant 1: finite-time convergence, no root at all.
    np.testing.assert_allclose(characteristic(transport, FiniteTimeController(), 0.0)(S), 1.0, rtol=1e-14, atol=0)


def test_transport_reflection_is_eq_delay_transport2(transport):
    """U = -K u(1): v(t,1) - rho q v(t - tau, 1) + K q v(t - tau - delta, 1) = 0."""
    K, q, rq, tau, delta = 0.05, transport.q, transport.rho_q, transport.tau, 0.2
    F = characteristic(transport, ReflectionController(K), delta)
    np.testing.assert_allclose(F(S), 1 - rq * np.exp(-tau * S) + K * q * np.exp(-(tau + delta) * S), rtol=1e-14, atol=0)


def test_transport_filtered_is_eq_delay_transport3(transport):
    """U_1 = -(1 + a s)/(1 + b s) rho u(1, s), multiplied out by (1 + b s)."""
    a, b, rq, tau, delta = 0.2, 0.5, transport.rho_q, transport.tau, 0.1
    F = characteristic(transport, FilteredController(a, b), delta)
    expected = (1 + b * S) * (1 - rq * np.exp(-tau * S)) + (1 + a * S) * rq * np.exp(-(tau + delta) * S)
    np.testing.assert_allclose(F(S), expected, rtol=1e-13, atol=0)
    # Principal part: 1 - rho q e^{-tau s} + (a/b) rho q e^{-(tau + delta) s}.
    D = F.principal_part()
    np.testing.assert_allclose(
        D(S), b * (1 - rq * np.exp(-tau * S) + a / b * rq * np.exp(-(tau + delta) * S)), rtol=1e-13, atol=0
    )
    assert D.gamma_0 == pytest.approx(abs(rq) * (1 + a / b), rel=1e-13, abs=1e-14)


def test_open_loop_transport_and_factors(transport):
    A, B = loop_factors(transport, OpenLoop())
    np.testing.assert_allclose(A(S), 1 - transport.rho_q * np.exp(-transport.tau * S), rtol=1e-14, atol=0)
    np.testing.assert_allclose(B(S), 0.0, rtol=0, atol=0)  # OpenLoop: B is the zero quasi-polynomial


def test_feedback_laws_on_transport(transport):
    law = ReflectionController(0.1).feedback_law(transport)
    assert isinstance(law, FeedbackLaw) and law.boundary_gain == -0.1 and law.filter is None
    assert np.all(law.gain_u(np.linspace(0, 1, 5)) == 0)
    assert FiniteTimeController().feedback_law(transport).boundary_gain == -transport.rho
    assert FilteredController(0.1, 0.3).feedback_law(transport).filter == (0.1, 0.3)


def test_coupled_system_needs_kernels_for_feedback_law():
    system = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
    with pytest.raises(ParameterError, match="kernels"):
        FiniteTimeController().feedback_law(system)


@pytest.mark.parametrize(
    "rho, q, regime, robust, finite_time",
    [
        (1.5, 1.0, "not_stabilizable", False, False),
        (1.0, 1.0, "critical_one", None, False),
        (0.85, 1.0, "no_robust_finite_time", True, False),
        (-0.25, 2.0, "critical_half", True, False),
        (0.3, -1.0, "robust_finite_time", True, True),
    ],
)
def test_classification_regimes(rho, q, regime, robust, finite_time):
    c = classify(TransportSystem(1.0, 1.0, q, rho))
    assert c.regime == regime
    assert c.delay_robustly_stabilizable is robust
    assert c.finite_time_delay_robust is finite_time
    assert c.k_bound == pytest.approx(max(0.0, (1 - abs(rho * q)) / abs(q)), rel=1e-13, abs=1e-14)
    assert c.to_dict()["regime"] == regime


@pytest.mark.parametrize(
    "make, name",
    [
        (lambda: ReflectionController(np.nan), "K"),
        (lambda: FilteredController(0.1, 0.0), "b"),
        (lambda: FilteredController(np.inf, 1.0), "a"),
        (lambda: characteristic(TransportSystem(1, 1, 1, 0.5), OpenLoop(), -0.1), "delta"),
        (lambda: characteristic("plant", OpenLoop(), 0.1), "system"),
        (lambda: characteristic(TransportSystem(1, 1, 1, 0.5), "U_BS", 0.1), "controller"),
    ],
)
def test_bad_input(make, name):
    with pytest.raises(ParameterError, match=name):
        make()
