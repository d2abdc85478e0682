"""``best_decay_rate`` where the decay rate peaks between its samples.

The proportional state feedback ``U = k u(t, 1)`` on ``Hyperbolic2x2(1, 1, 1.5, 0.5, 0.8, 0.4)`` with a
delay margin of at least 1: the feasible gains are about ``[-0.5489, -0.49]`` and the decay rate peaks
at ``k = -0.51077`` (1.2060), where two root branches cross, between two of the five samples (the
largest of which was the end ``k = -0.5489``, rate 1.0621: returned as the design). The oracle: certified
spectral abscissae at 61 gains, with certified delay margins, that the design must match or beat.
"""

from __future__ import annotations

import numpy as np
import pytest

import nrobust as nr
from nrobust.design.gain import best_decay_rate
from nrobust.hyperbolic.analyses.state_design import state_feedback_loop
from nrobust.margins import AffineGainLoop, delay_margin
from nrobust.roots import spectral_abscissa


@pytest.fixture(scope="module")
def loop() -> AffineGainLoop:
    family = state_feedback_loop(nr.Hyperbolic2x2(1, 1, 1.5, 0.5, 0.8, 0.4))
    return AffineGainLoop(family.A, family.units[0] * 0.0, family.units[0])


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
