"""Numbers of the reports printed to their accuracy: the simulated growth rates of ``nrobust paper`` and the
crossing delay that misses a window of an n + m design.

Oracles: the paper's simulations on grids 4 and 8 times finer, extrapolated to zero cell size at first
order (the slopes' changes halve with the grid: measured ratios 1.8 to 2.0 from 200 to 3200 cells), and the
certified n + m margin's own accuracy (checked against 40-digit crossings in ``test_nplusm_digits.py``).
"""

from __future__ import annotations

from decimal import Decimal

import numpy as np

from nrobust import Hyperbolic2x2
from nrobust._digits import with_accuracy
from nrobust.hyperbolic.nplusm import NPlusMSystem, nplusm_delay_margin
from nrobust.hyperbolic.simulate import simulate_runs
from nrobust.reports.design import _window_crossing_text
from nrobust.reports.paper import PAPER_SYSTEM, PAPER_T_END, _figure_loop, _growth, _growth_text, _paper_u0, _paper_v0


def test_simulated_growth_rates_to_their_estimated_accuracy() -> None:
    """The slopes of figures 1 and 3 at 100 cells, their accuracy from 50 cells: each printed value within
    its bound of the extrapolated slope (at 100 cells the old three digits of U_BS at delta = 0.01, 0.241,
    were off by 1e-3 from 0.2397); U_BS without delay converges in finite time: no slope is printed."""
    plant = Hyperbolic2x2(**PAPER_SYSTEM)
    loops = [(controller, d) for controller, deltas in map(_figure_loop, (1, 3)) for d in deltas]

    def runs(cells: int) -> list:
        return simulate_runs(plant, loops, PAPER_T_END, _paper_u0, _paper_v0, cells)

    coarse, fine, finer, finest = runs(50), runs(100), runs(400), runs(800)
    for k, (run, other) in enumerate(zip(fine, coarse)):
        rate, accuracy = _growth(run, other)
        text = _growth_text(rate, accuracy)
        if k == 0:  # U_BS, delta = 0: the norm at the scheme's residual after t = 2
            assert rate is None and accuracy is None and "finite-time convergence" in text
            continue
        assert rate is not None and accuracy is not None
        truth = 2.0 * finest[k].growth_rate() - finer[k].growth_rate()
        assert abs(rate - truth) <= accuracy <= 0.05, (k, rate, accuracy, truth)
        printed, bound = text.split(" +- ")
        assert abs(Decimal(printed) - Decimal(truth)) <= Decimal("1.5") * Decimal(bound), (text, truth)
    assert _growth(fine[1], None) == (fine[1].growth_rate(), None)  # no grid to compare with: not estimated
    assert _growth_text(0.24, None) == "0.24 (accuracy not estimated)"


def test_a_crossing_delay_inside_a_window_with_the_accuracy_it_has() -> None:
    """The margin's crossing delay prints with the margin's accuracy; a later delay of its crossing, whose
    error is not estimated, says so."""
    system = NPlusMSystem([1.0], [1.0], [[0.0, 0.5], [0.4, 0.0]], [[0.8]], [[0.5]])
    margin = nplusm_delay_margin(system, np.array([[-0.25]]))
    assert margin.omega is not None and margin.accuracy is not None
    assert _window_crossing_text(margin.margin, margin) == with_accuracy(margin.margin, margin.accuracy)
    later = margin.margin + 2.0 * np.pi / margin.omega
    assert _window_crossing_text(later, margin) == with_accuracy(later, None)
    assert _window_crossing_text(later, margin).endswith("(accuracy not estimated)")
