"""The joint design of U_BS2(K) and the collocated observer's reflection ``kappa``.

Checks: the loop bilinear in ``(K, kappa)`` against the loop built at ``(K, kappa)``; the
difference operator with ``observer_delay > 0`` against its closed form (module notes of
:mod:`nrobust.hyperbolic.loops.collocated`, derived below) through the spectral bound of the
loop's principal part; the default bounds against the closed form of ``gamma_0``; the design on a
transport plant against the closed-form optimum of its decay rate; on the paper's plant (long)
against a grid of certified margins and the one-parameter design at ``K = 0.1``.

With ``delta_o > 0``, for U_BS2(K) (``k = -K``) and ``z = e^{-tau s}``: ``E A`` has the principal part
``(1 - kappa q z)(1 - rho q z)``, ``E B`` the part ``(1 - kappa q z) K q z``, ``G`` the part
``(1 - rho q z)(-K q z)``, so ``A_o = E A - G e^{-delta_o s}`` and ``B_o = E B + G`` have

    1 - (rho + kappa) q z + kappa rho q^2 z^2 + K q z e^{-delta_o s} - K rho q^2 z^2 e^{-delta_o s},
    K (rho - kappa) q^2 z^2,

strongly stable iff ``|rho + kappa| |q| + |kappa rho| q^2 + |K q| + |K rho| q^2 + |K (rho - kappa)| q^2 < 1``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import nrobust as nr
from nrobust.difference import DifferenceOperator
from nrobust.errors import ParameterError
from nrobust.hyperbolic.analyses.observer_design import (
    collocated_joint_loop,
    collocated_observer_loop,
    joint_bounds,
    observer_reflection_bounds,
)
from nrobust.hyperbolic.loops.controllers import CollocatedOutputFeedback, ReflectionController, loop_factors
from nrobust.margins import delay_margin

PAPER = nr.Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
# uncoupled, tau = 2, rho q = 0.85 (the paper's principal part): the loop is exact and fast
TRANSPORT = nr.TransportSystem(1.0, 1.0, 1.0, 0.85)
# tau = 1.5, commensurate with the delays below (exact spectral bounds of the difference operators)
SKEW = nr.TransportSystem(1.0, 2.0, 0.9, 0.6)


def _gamma(rho, q, K, kappa, observer_delay):
    """The closed form of ``gamma_0`` (module notes; arrays broadcast)."""
    if observer_delay == 0.0:
        return np.abs(rho - K + kappa) * abs(q) + np.abs((kappa - K) * rho) * q * q + np.abs(K * (rho - kappa)) * q * q
    return (
        np.abs(rho + kappa) * abs(q)
        + np.abs(kappa * rho) * q * q
        + np.abs(K * q)
        + np.abs(K * rho) * q * q
        + np.abs(K * (rho - kappa)) * q * q
    )


def _closed_form_operator(rho, q, tau, K, kappa, observer_delay, delta):
    coefs = [1.0, -(rho + kappa) * q, kappa * rho * q * q, K * q, -K * rho * q * q, K * (rho - kappa) * q * q]
    delays = [0.0, tau, 2 * tau, tau + observer_delay, 2 * tau + observer_delay, 2 * tau + delta]
    return DifferenceOperator(coefs, delays)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_delayed_observer_difference_operator_is_the_closed_form(seed):
    """Random ``(K, kappa, delta_o)``: the spectral bound of the loop's principal part is the closed form's."""
    rng = np.random.default_rng(seed)
    K, kappa = rng.uniform(-0.6, 0.6, 2)
    observer_delay = float(rng.choice([0.3, 0.7, 1.1]))
    delta = 0.2
    A, B = loop_factors(SKEW, CollocatedOutputFeedback(ReflectionController(K), observer_delay, kappa))
    D = (A + B.shift(delta)).principal_part()
    expected = _closed_form_operator(SKEW.rho, SKEW.q, SKEW.tau, K, kappa, observer_delay, delta)
    # commensurate delays (multiples of 0.1): both bounds exact, from the roots of the same polynomial in z
    np.testing.assert_allclose(D.spectral_bound().value, expected.spectral_bound().value, rtol=0, atol=1e-9)
    np.testing.assert_allclose(D.gamma_0, _gamma(SKEW.rho, SKEW.q, K, kappa, observer_delay), rtol=1e-12)
    # the loop bilinear in (K, kappa) has the same gamma_0
    loop = collocated_joint_loop(SKEW, observer_delay)
    np.testing.assert_allclose(loop.gamma(K, kappa), D.gamma_0, rtol=1e-12)


def test_delayed_observer_on_the_paper_plant():
    """The paper's plant (kernels, a model): the point terms are the closed form's; ``K = 0.1`` has no ``kappa``."""
    K, kappa, observer_delay, delta = 0.03, -0.6, 0.3, 0.5
    A, B = loop_factors(PAPER, CollocatedOutputFeedback(ReflectionController(K), observer_delay, kappa))
    D = (A + B.shift(delta)).principal_part()
    expected = _closed_form_operator(PAPER.rho, PAPER.q, PAPER.tau, K, kappa, observer_delay, delta)
    # the principal coefficients are the kernels' exact point terms: rounding only
    np.testing.assert_allclose(D.spectral_bound().value, expected.spectral_bound().value, rtol=0, atol=1e-9)
    loop = collocated_observer_loop(PAPER, CollocatedOutputFeedback(ReflectionController(K), observer_delay))
    # the closed form (rho = 0.85, q = 1, 0 < K) is linear in kappa below -rho and on (0, rho):
    # -rho - kappa (1 + rho + K) + K + 2 K rho = 1 and rho + K + 2 K rho + kappa (1 + rho - K) = 1
    lo = -(1.0 + 0.85 - K - 1.7 * K) / (1.0 + 0.85 + K)
    hi = (1.0 - 0.85 - K - 1.7 * K) / (1.0 + 0.85 - K)
    np.testing.assert_allclose(observer_reflection_bounds(loop), (lo, hi), rtol=0, atol=1e-12)
    for k in (lo, hi):
        np.testing.assert_allclose(_gamma(0.85, 1.0, K, k, observer_delay), 1.0, rtol=1e-12)
    # K = 0.1: the least gamma_0 is at kappa = -rho, 0.7225 + 0.1 + 0.085 + 0.17 = 1.0775
    with pytest.raises(ParameterError, match=r"1\.0775"):
        nr.design_collocated_observer(PAPER, observer_delay=0.3)


@pytest.mark.parametrize("observer_delay", [0.0, 0.4])
def test_joint_bounds_are_the_region_of_the_closed_form(observer_delay):
    """The box about ``gamma_0 <= 0.9`` against a dense grid of the closed form, and the bilinear loop."""
    loop = collocated_joint_loop(TRANSPORT, observer_delay)
    (k_lo, k_hi), (c_lo, c_hi) = joint_bounds(loop, 0.9)
    Ks = np.linspace(-3.0, 3.0, 1201)
    kappas = np.linspace(-3.0, 3.0, 1201)
    inside = _gamma(0.85, 1.0, Ks[:, None], kappas[None, :], observer_delay) < 0.9
    step = 6.0 / 1200 + 1e-12
    # the grid's extremes lie inside the box, within one step (and rounding) of its ends
    for got, want in (
        ((k_lo, k_hi), Ks[inside.any(axis=1)]),
        ((c_lo, c_hi), kappas[inside.any(axis=0)]),
    ):
        assert got[0] <= want.min() <= got[0] + step and got[1] - step <= want.max() <= got[1]
    # the bilinear family at a few points is the loop built there
    s = np.array([0.2 + 3.0j, -0.1 + 9.0j])
    for K, kappa in ((0.1, -0.7), (1.2, 0.6)):
        A, B = loop_factors(TRANSPORT, CollocatedOutputFeedback(ReflectionController(K), observer_delay, kappa))
        a, b = loop(np.array([K, kappa]))
        np.testing.assert_allclose(a(s), A(s), rtol=0, atol=1e-12)
        np.testing.assert_allclose(b(s), B(s), rtol=0, atol=1e-12)


def test_transport_design_beats_the_grid_and_stays_below_the_closed_form_optimum():
    """The decay rate on an uncoupled plant: ``-ln max(|kappa q|, |(rho - K) q|) / tau`` (the zeros of ``E`` and of
    the target system), every margin infinite where ``gamma_0 < 1``.

    Under ``gamma_0 <= 0.9`` it is largest where ``|kappa| = |rho - K|`` meets ``gamma_0 = 0.9``: on
    ``kappa = K - rho``, ``gamma_0 = rho^2 + K (2 rho - K) = 0.9`` (``rho = 0.85``, ``q = 1``), i.e.
    ``K = (1.7 +- sqrt(1.7^2 - 4 * 0.1775)) / 2``, both giving ``|kappa| = 0.738...``: a corner of a thin
    region, which a grid of the closed form with steps of 0.002 misses by 1e-3.
    """
    design = nr.design_collocated_output_feedback(TRANSPORT, "decay_rate", margin_at_least=0.5)
    optimum = -math.log((1.7 + math.sqrt(1.7**2 - 4 * 0.1775)) / 2 - 0.85) / 2.0
    Ks, kappas = np.linspace(-0.5, 1.9, 1201), np.linspace(-1.0, 1.0, 1001)
    rates = -np.log(np.maximum(np.abs(kappas[None, :]), np.abs(0.85 - Ks[:, None]))) / 2.0
    grid = np.max(np.where(_gamma(0.85, 1.0, Ks[:, None], kappas[None, :], 0.0) <= 0.9, rates, -np.inf))
    assert design.certified and design.local
    assert math.isinf(design.design.margin.margin)
    # the design's certified value is the closed form at the design, to rounding
    closed = -math.log(max(abs(design.kappa), abs(0.85 - design.K))) / 2.0
    np.testing.assert_allclose(design.value, closed, rtol=1e-9)
    # never above the optimum (rounding, and gamma_max = 0.9 met to rounding); at least the grid's best (0.150553)
    assert grid <= design.value <= optimum + 1e-9
    # at least the one-parameter design at K = 0.1 (its rate is at most -ln 0.75 / 2)
    assert design.value > -math.log(0.75) / 2.0
    assert design.bounds == joint_bounds(collocated_joint_loop(TRANSPORT), 0.9)
    assert design.controller == CollocatedOutputFeedback(ReflectionController(design.K), 0.0, design.kappa)
    assert _gamma(0.85, 1.0, design.K, design.kappa, 0.0) <= 0.9 + 1e-12


def test_bad_input():
    with pytest.raises(ParameterError, match="objective"):
        nr.design_collocated_output_feedback(TRANSPORT, "speed")
    with pytest.raises(ParameterError, match="margin_at_least"):
        nr.design_collocated_output_feedback(TRANSPORT, "decay_rate")
    with pytest.raises(ParameterError, match="margin_at_least"):
        nr.design_collocated_output_feedback(TRANSPORT, margin_at_least=0.1)
    with pytest.raises(ParameterError, match="gamma_max"):
        nr.design_collocated_output_feedback(TRANSPORT, gamma_max=1.0)
    with pytest.raises(ParameterError, match="K_bounds"):
        nr.design_collocated_output_feedback(TRANSPORT, K_bounds=(0.2, 0.1))
    with pytest.raises(ParameterError, match="x0"):
        nr.design_collocated_output_feedback(TRANSPORT, x0=(0.1,))
    with pytest.raises(ParameterError, match="gamma_max"):
        joint_bounds(collocated_joint_loop(TRANSPORT), 0.5)  # the least gamma_0 is rho^2 q^2 = 0.7225


@pytest.mark.long
@pytest.mark.timeout(1200)  # about 200 s of CPU; a loaded machine doubles it
def test_paper_design_beats_the_grid_and_the_one_parameter_design():
    """The paper's plant, margin objective: at least the exact best ``kappa`` at ``K = 0.1`` (0.1948775, its kink
    under ``gamma_0 <= 0.9``) and every certified margin of a 5 x 5 grid about the design with ``gamma_0 <= 0.9``
    (``benchmarks/collocated_joint.py`` runs a 15 x 15 one). Two starts: the exact one, which stays at the kink,
    and its neighbour at ``kappa - 0.019``, which reaches the edge ``gamma_0 = 0.9`` (margin 0.1981288 with the
    default six starts, docs/design.md)."""
    design = nr.design_collocated_output_feedback(PAPER, starts=2)
    # this start is the best run of the default design (0.19812877); the three runs that reach the edge agree to
    # 6e-6, so 1e-5 allows for another machine's rounding moving the search along the ridge
    np.testing.assert_allclose(design.value, 0.19812877, rtol=0, atol=1e-5)
    assert design.certified and design.design.margin.verified
    # the one-parameter design at K = 0.1 within the same region (the kink of tests/test_collocated_observer_design.py)
    assert design.value >= 0.1948775 - 1e-7
    loop = collocated_joint_loop(PAPER)
    assert loop.gamma(design.K, design.kappa) <= 0.9 + 1e-12
    best_grid = 0.0
    for K in np.linspace(design.K - 0.01, design.K + 0.01, 5):
        for kappa in np.linspace(design.kappa - 0.01, design.kappa + 0.01, 5):
            if loop.gamma(K, kappa) > 0.9:
                continue
            A, B = loop_factors(PAPER, CollocatedOutputFeedback(ReflectionController(K), 0.0, kappa))
            best_grid = max(best_grid, delay_margin(A, B).margin)
    # certified margins (relative accuracy about 1e-12): the design is a local optimum on this neighbourhood
    assert design.value >= best_grid - 1e-9
