"""``best_decay_rate`` where the decay rate peaks between its samples.

The proportional state feedback ``U = k u(t, 1)`` on ``Hyperbolic2x2(1, 1, 1.5, 0.5, 0.8, 0.4)`` with a
delay margin of at least 1: the feasible gains are about ``[-0.5489, -0.49]`` and the decay rate peaks
at ``k = -0.51077`` (1.2060), where two root branches cross, between two of the five samples (the
largest of which was the end ``k = -0.5489``, rate 1.0621: returned as the design). The oracles: certified
spectral abscissae at 61 gains, with certified delay margins, that the design must match or beat; and the
crossing itself, a complex pair's real part equal to a real zero's, each zero by scipy's Newton on the loop's
quasi-polynomial and the gain by ``brentq`` (no code of the design).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq, newton

import nrobust as nr
from nrobust.design.gain import best_decay_rate
from nrobust.hyperbolic.analyses.state_design import state_feedback_loop
from nrobust.hyperbolic.loops.controllers import CollocatedOutputFeedback, ReflectionController, loop_factors
from nrobust.margins import AffineGainLoop, delay_margin
from nrobust.roots import spectral_abscissa


@pytest.fixture(scope="module")
def loop() -> AffineGainLoop:
    family = state_feedback_loop(nr.Hyperbolic2x2(1, 1, 1.5, 0.5, 0.8, 0.4))
    return AffineGainLoop(family.A, family.units[0] * 0.0, family.units[0])


@pytest.mark.long  # about a minute of CPU: make fuzz runs it
def test_peak_between_samples(loop: AffineGainLoop) -> None:
    design = best_decay_rate(loop, (-0.8415, -0.24), margin_at_least=1.0, n_rates=5)
    assert design.certificate.margin >= 1.0
    ks = np.linspace(-0.5485, -0.4985, 61)
    rates = np.array([-spectral_abscissa(loop.A + loop.R * float(k)).value for k in ks])
    best = int(np.argmax(rates))
    # the grid's best gain is feasible (certified), so the design must reach its rate (1e-9: the rates' errors
    # are ~1e-14, Brent's search stops within 1e-10 of the peak, where the rate moves by ~10 per unit of k)
    assert delay_margin(loop.A, loop.R * float(ks[best])).margin >= 1.0
    assert design.value >= rates[best] - 1e-9
    # and not beat it by more than the rate's slopes (below 10 per unit of k) times the grid's spacing
    assert design.value <= rates[best] + 10.0 * (ks[1] - ks[0])
    np.testing.assert_allclose(design.K, ks[best], atol=ks[1] - ks[0])


def _zero(loop: AffineGainLoop, k: float, s0: complex) -> complex:
    F = loop.A + loop.R * k
    s = newton(
        lambda z: complex(F(np.array([z]))[0]),
        s0,
        fprime=lambda z: complex(F.deriv_at(np.array([z]))[0]),
        tol=1e-12,
        maxiter=50,
    )
    for _ in range(2):  # from 1e-12 to rounding (quadratic convergence)
        s -= complex(F(np.array([s]))[0] / F.deriv_at(np.array([s]))[0])
    return complex(s)


def test_peak_is_the_crossing_of_two_zeros(loop: AffineGainLoop) -> None:
    design = best_decay_rate(loop, (-0.8415, -0.24), margin_at_least=1.0, n_rates=5)

    def gap(k: float) -> float:  # the complex pair (rightmost left of the peak) against the real zero (right of it)
        return _zero(loop, k, -1.2 + 4.47j).real - _zero(loop, k, -1.2 + 0j).real

    k = brentq(gap, -0.5115, -0.5100, xtol=1e-15, rtol=1e-15)
    assert design.kind == "kink"
    # the real parts cross with slopes about 4 and -30 per unit of k: zeros to ~1e-15 put the crossing within
    # ~1e-16; 1e-12 leaves room for the rounding of the two evaluations of the loop near the crossing
    np.testing.assert_allclose(design.K, k, rtol=0, atol=1e-12)
    np.testing.assert_allclose(design.value, -_zero(loop, k, -1.2 + 0j).real, rtol=1e-12)


def test_collocated_observer_rate_design_on_a_plateau() -> None:
    """The collocated observer's decay-rate design for U_BS2(0.1) on ``(1, 1, 1, 1, 1, 0.7)`` with a margin of at
    least 0.1: the rate is the slower of the observer's error and the law's target system, flat at the latter's
    (0.25541) over a range of ``kappa``; where the zero followed from one sample reached the other's with a slope
    of the other sign, Brent's root finder was given no bracket (a ``ValueError``). The design must reach the best
    rate of a grid of loops built at each ``kappa`` (certified spectral abscissae, errors ~1e-14; certified
    margins of at least 0.1), and its margin, certified again, must meet the requirement."""
    plant, inner = nr.Hyperbolic2x2(1, 1, 1, 1, 1, 0.7), ReflectionController(0.1)
    design = nr.design_collocated_observer(plant, "decay_rate", controller=inner, margin_at_least=0.1)
    assert nr.delay_margin(plant, design.controller).margin >= 0.1
    lo, hi = design.bounds
    best = -np.inf
    for kappa in np.linspace(lo, hi, 9):
        law = CollocatedOutputFeedback(inner, 0.0, float(kappa))
        if nr.delay_margin(plant, law).margin >= 0.1:
            A, B = loop_factors(plant, law)
            best = max(best, -spectral_abscissa(A + B).value)
    assert design.design.decay_rate >= best - 1e-9 * best
