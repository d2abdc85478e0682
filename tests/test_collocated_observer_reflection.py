"""The collocated observer's own reflection ``kappa``: its loop against independent routes.

The observer ``v^(t, 1) = (rho - kappa) y + kappa u^(t, 1) + U_o`` (``kappa = 0``: the nilpotent
observer). Oracles, none of which uses :mod:`nrobust.hyperbolic.loops.collocated`:

* a transport plant: by the method of characteristics ``u^(1) (1 - kappa q z) = q z ((rho - kappa) y
  + U_o)`` (``z = e^{-tau s}``), so the loop is a closed form, evaluated with mpmath at 40 digits;
* the plant and the observer (gains from the Goursat problem solved by least squares) in the
  Laplace domain (:func:`test_collocated_output_feedback.laplace_loop` with ``kappa``), the error's
  characteristic function from the observer's output at ``kappa = 0``;
* the difference operator: the principal parts against the formula of the module notes, and its
  strong stability (``gamma_0 < 1``) against the spectral bounds of perturbed delays
  (:meth:`nrobust.DifferenceOperator.spectral_bound`, exact for commensurate delays);
* a simulation of the PDE and the observer on the characteristic lattice: with ``|kappa q| > 1``
  the observer's error grows at the rate of its own characteristic function even when the
  observer replays the commands with the plant's delay (the zeros of ``E`` are modes of the loop).
"""

from __future__ import annotations

import mpmath
import numpy as np
import pytest
from test_collocated_output_feedback import (
    LAW,
    PAPER,
    POINTS,
    SLOW_V,
    TRANSPORT,
    laplace_loop,
    law_gains,
    simulate_loop,
)
from test_collocated_output_feedback import observer_gains as goursat_gains

import nrobust as nr
from nrobust.errors import ParameterError
from nrobust.hyperbolic.kernels.constant import solve_kernels
from nrobust.hyperbolic.loops.controllers import (
    CollocatedOutputFeedback,
    FilteredController,
    FiniteTimeController,
    ReflectionController,
    characteristic,
    loop_factors,
    loop_scope,
    normalize,
    observer_reflection_of,
)
from nrobust.roots import spectral_abscissa


@pytest.mark.parametrize(
    ("inner", "K", "filt"),
    [
        (ReflectionController(0.2), 0.2, None),
        (FiniteTimeController(), 0.6, None),
        (FilteredController(0.05, 0.1, K=0.2), 0.2, (0.05, 0.1)),
    ],
    ids=["U_BS2", "U_BS", "filtered"],
)
@pytest.mark.parametrize("kappa", [0.3, -0.5, 1.3])
@pytest.mark.parametrize("observer_delay", [0.0, 0.15])
def test_transport_loop_is_the_closed_form(inner, K, filt, kappa, observer_delay):
    """``F = (1 - rho q z)(d (1 - kappa q z) + n K q z e^{-delta_o s}) + n K (rho - kappa) q^2 z^2 e^{-delta s}``.

    The plant ``u(1) (1 - rho q z) = q z e^{-delta s} U_c``, the observer ``u^(1) (1 - kappa q z) =
    q z ((rho - kappa) y + e^{-delta_o s} U_c)`` and ``d U_c = -n K u^(1)``, times ``1 - kappa q z``.
    """
    mpmath.mp.dps = 40
    q, rho, tau = mpmath.mpf(TRANSPORT.q), mpmath.mpf(TRANSPORT.rho), mpmath.mpf(1) + mpmath.mpf(1) / 2
    A, B = loop_factors(TRANSPORT, CollocatedOutputFeedback(inner, observer_delay, kappa))
    for s in POINTS:
        S = mpmath.mpc(s.real, s.imag)
        z = mpmath.exp(-tau * S)
        n, d = (1, 1) if filt is None else (1 + filt[0] * S, 1 + filt[1] * S)
        for delta in (0.0, 0.1, 0.7):
            exact = (1 - rho * q * z) * (
                d * (1 - kappa * q * z) + n * K * q * z * mpmath.exp(-observer_delay * S)
            ) + n * K * (rho - kappa) * q**2 * z**2 * mpmath.exp(-delta * S)
            mine = A(s) + B(s) * np.exp(-delta * s)
            # sums of a few terms of size <= 3 |s| in double precision
            np.testing.assert_allclose(mine, complex(exact), rtol=0, atol=1e-13 * max(1.0, abs(s)))


@pytest.mark.parametrize(
    ("plant", "observer_delay", "kappa", "atol"),
    [
        (SLOW_V, 0.0, 0.4, 5e-8),
        (SLOW_V, 0.1, -0.7, 5e-8),
        (SLOW_V, 0.0, 1.5, 5e-8),
        (PAPER, 0.0, 0.3, 1e-8),
        (PAPER, 0.05, -0.4, 1e-8),
        (TRANSPORT, 0.1, 0.5, 1e-13),
    ],
    ids=["coupled", "observer delay", "unstable error", "paper", "paper delayed", "transport"],
)
def test_loop_is_the_laplace_domain_loop(plant, observer_delay, kappa, atol):
    """``A_o + B_o e^{-delta s}`` against the Laplace-domain plant and observer, ``E`` included.

    The package's terms come from kernels on 201 points: measured 7.4e-9 to 1.1e-8 on ``SLOW_V`` and 1.6e-9 to
    1.9e-9 on the paper's plant, 8 times less on 401 points (third order: the kernels, and their composition with
    the law's gains by the trapezoidal rule with Gregory's end corrections; 2.1e-7 on the paper's plant and 4
    times less per halving with the plain trapezoidal rule); the oracle errs by about 1e-13 (48-point rules on
    analytic integrands).
    """
    k, g_u, g_v = law_gains()
    A, B = loop_factors(plant, CollocatedOutputFeedback(LAW, observer_delay, kappa))
    deltas = (0.0, 0.25, 0.6)
    for s in POINTS:
        mine = np.array([A(s) + B(s) * np.exp(-d * s) for d in deltas])
        expected = laplace_loop(plant, k, g_u, g_v, s, deltas, observer_delay, kappa=kappa)
        np.testing.assert_allclose(mine, expected, rtol=0, atol=atol)


def test_paper_law_is_the_laplace_domain_loop():
    """U_BS2(0.1) on the paper's plant (gains from its own kernels) with ``kappa = 0.2``, against the oracle.

    The law's integral gains come from the plant's kernels on 401 points, read by the oracle as a
    cubic spline: measured 7.9e-9 (the law's and the observer's kernels on 201 points; 1.05e-6 with the plain
    trapezoidal composition), hence 3e-8.
    """
    from scipy.interpolate import CubicSpline

    law = ReflectionController(0.1).feedback_law(PAPER, solve_kernels(PAPER, 401))
    grid = np.linspace(0.0, 1.0, 401)
    g_u, g_v = CubicSpline(grid, law.gain_u(grid)), CubicSpline(grid, law.gain_v(grid))
    A, B = loop_factors(PAPER, CollocatedOutputFeedback(ReflectionController(0.1), 0.0, 0.2))
    deltas = (0.0, 0.3)
    for s in POINTS:
        mine = np.array([A(s) + B(s) * np.exp(-d * s) for d in deltas])
        expected = laplace_loop(PAPER, law.boundary_gain, g_u, g_v, s, deltas, 0.0, kappa=0.2)
        np.testing.assert_allclose(mine, expected, rtol=0, atol=3e-8)


def test_default_is_the_nilpotent_observer_bit_for_bit():
    """``observer_reflection=0`` builds the very factors of the observer without the parameter."""
    for inner in (ReflectionController(0.1), FilteredController(0.05, 0.1, K=0.2)):
        A0, B0 = loop_factors(SLOW_V, CollocatedOutputFeedback(inner, 0.1))
        A1, B1 = loop_factors(SLOW_V, CollocatedOutputFeedback(inner, 0.1, 0.0))
        assert A0 == A1 and B0 == B1


def test_separation_and_affinity():
    """At ``delta = delta_o`` the loop is ``E`` times the state feedback's; the factors are affine in ``kappa``."""
    s = np.array(POINTS)
    reflection = observer_reflection_of(PAPER, CollocatedOutputFeedback(ReflectionController(0.1)))
    E = 1.0 - 0.3 * reflection.response(s)
    for delay in (0.0, 0.2):
        F = characteristic(PAPER, CollocatedOutputFeedback(ReflectionController(0.1), delay, 0.3), delay)
        state = characteristic(PAPER, ReflectionController(0.1), delay)
        # the observer's term G cancels at delta = delta_o up to its rounding
        np.testing.assert_allclose(F(s), E * state(s), rtol=0, atol=1e-11)
    factors = [loop_factors(PAPER, CollocatedOutputFeedback(ReflectionController(0.1), 0.0, p)) for p in (0, 0.5, 1)]
    for i in range(2):
        middle = 0.5 * (factors[0][i](s) + factors[2][i](s))
        np.testing.assert_allclose(factors[1][i](s), middle, rtol=0, atol=1e-12)


def _gamma_formula(rho, q, K, kappa):
    """``gamma_0`` of ``1 - (rho - K + kappa) q z + (kappa - K) rho q^2 z^2 + K (rho - kappa) q^2 z^2 e^{-delta s}``."""
    return abs(rho - K + kappa) * abs(q) + abs((kappa - K) * rho) * q * q + abs(K * (rho - kappa)) * q * q


@pytest.mark.parametrize(("K", "kappa"), [(0.1, 0.0), (0.1, -0.5), (0.1, 0.3), (0.85, 0.85), (0.85, 0.0), (0.85, 0.55)])
def test_difference_operator_and_its_strong_stability(K, kappa):
    """The principal parts are the formula's; ``gamma_0 < 1`` iff no perturbation of the delays has a zero right of 0.

    The spectral bounds of commensurate perturbations ``(2, 4 + e, 4 + delta)`` (multiples of 1/20:
    exact roots of a polynomial) have the sign of ``gamma_0 - 1`` and of ``C_D`` (the supremum over
    perturbations; the cases are at least 0.06 away from ``gamma_0 = 1``).
    """
    rho, q = PAPER.rho, PAPER.q
    A, B = loop_factors(PAPER, CollocatedOutputFeedback(ReflectionController(K), 0.0, kappa))
    a = A.principal_part()
    expected_a = {0.0: 1.0, 2.0: -(rho - K + kappa) * q, 4.0: (kappa - K) * rho * q * q}
    for c, d in zip(a.coefs, a.delays, strict=True):
        np.testing.assert_allclose(c, expected_a[round(d, 9)], rtol=0, atol=1e-12)
    b_coef = K * (rho - kappa) * q * q
    b = [(c, d) for c, d in B.leading_terms(0) if abs(c) > 1e-12]
    assert [round(d, 9) for _, d in b] == ([] if abs(b_coef) < 1e-12 else [4.0])
    if b:
        np.testing.assert_allclose(sum(c for c, _ in b), b_coef, rtol=0, atol=1e-12)
    gamma = _gamma_formula(rho, q, K, kappa)
    coefs = [1.0, -(rho - K + kappa) * q, (kappa - K) * rho * q * q, b_coef]
    bounds = [
        nr.DifferenceOperator(coefs, [0.0, 2.0, 4.0 + e / 20.0, 4.0 + d / 20.0]).spectral_bound().value
        for e in (-1, 0, 1)
        for d in range(2, 21)
    ]
    C_D = nr.DifferenceOperator(coefs, [0.0, 2.0, 4.0, 4.3]).strong_spectral_bound()
    assert (gamma < 1.0) == (max(bounds) < 0.0) == (C_D < 0.0)


def test_unstable_error_grows_in_simulation():
    """``kappa = 1.2``: ``E`` has a zero right of the axis and the loop grows even when ``delta = delta_o``.

    The observer replays the commands with the plant's delay, so the plant's own loop is the state
    feedback's, stable; the error, fed by nothing, grows at the spectral abscissa of ``E``
    (``0.33136`` here, far from ``ln(1.2 q) / tau = 0.091``: the distributed part of ``H_y``;
    measured ``0.33119`` on the lattice with 100 cells).
    """
    controller = CollocatedOutputFeedback(ReflectionController(0.1), 0.02, 1.2)
    F = characteristic(PAPER, controller, 0.02)
    E = 1.0 - 1.2 * observer_reflection_of(PAPER, controller).response
    alpha, alpha_E = spectral_abscissa(F).value, spectral_abscissa(E).value
    np.testing.assert_allclose(alpha, alpha_E, rtol=0, atol=1e-9)
    assert spectral_abscissa(characteristic(PAPER, ReflectionController(0.1), 0.02)).value < 0.0
    law = ReflectionController(0.1).feedback_law(PAPER, solve_kernels(PAPER, 101))
    times, _, errors = simulate_loop(PAPER, law, goursat_gains(PAPER), 0.02, 0.02, 30.0, kappa=1.2)
    late = times > 12.0
    rate = np.polyfit(times[late], np.log(errors[late]), 1)[0]
    # the lattice's error at 100 cells and the other zeros' share (measured 1.6e-4): 5e-3
    np.testing.assert_allclose(rate, alpha_E, rtol=0, atol=5e-3)


def test_scope_json_normal_form_and_bad_input():
    controller = CollocatedOutputFeedback(ReflectionController(0.1), 0.05, 0.3)
    assert controller.to_dict()["observer_reflection"] == 0.3
    assert "observer_reflection" not in CollocatedOutputFeedback(ReflectionController(0.1)).to_dict()
    scope = loop_scope(PAPER, controller, None, loop_factors(PAPER, controller))
    assert "observer's reflection" in scope and "not part of the proof" in scope
    with pytest.raises(ParameterError, match="observer_reflection"):
        CollocatedOutputFeedback(ReflectionController(0.1), 0.0, float("nan"))
    general = nr.GeneralHyperbolic2x2(lam=2.0, mu=1.0, a=0.3, b=1.0, c=1.0, d=-0.2, q=0.8, rho=0.5)
    _, mapped = normalize(general, CollocatedOutputFeedback(nr.StateFeedback(-0.2), 0.05, 0.4))
    assert mapped.observer_reflection == 0.4 and mapped.observer_delay == 0.05
