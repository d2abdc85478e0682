"""Windows of delays in the gain design of an n + m system (``design_nplusm_gains(..., delays=...)``).

The plant is the coupled 2x2 plant of ``tests/test_nplusm_design.py`` as a 1 + 1 system: ``K = [[k]]``
is ``StateFeedback(k)`` of the 2x2 plant, whose loop is affine in ``k``, so the core's exact one-gain
engine (``best_decay_rate(..., delays=...)``, from the equations of its kind on the scalar loop of the
kernel route) is an independent oracle of the whole design. A second oracle is the spectral abscissa of
the designed loop at delays of the window (a root search, not the crossing search the design uses).
"""

from __future__ import annotations

import numpy as np
import pytest

from nrobust.design import best_decay_rate
from nrobust.errors import ParameterError
from nrobust.hyperbolic.analyses.state_design import state_feedback_loop
from nrobust.hyperbolic.nplusm import NPlusMCharacteristic, NPlusMSystem, design_nplusm_gains, nplusm_delay_margin
from nrobust.hyperbolic.nplusm.design import check_window, window_clearance
from nrobust.hyperbolic.plants.hyperbolic2x2 import Hyperbolic2x2
from nrobust.margins.gain import AffineGainLoop
from nrobust.roots import spectral_abscissa

PLANT = Hyperbolic2x2(1.0, 1.0, 1.5, 0.5, 0.8, 0.4)
SYSTEM = NPlusMSystem.from_2x2(PLANT)


def test_decay_rate_on_a_window_agrees_with_the_exact_scalar_design() -> None:
    """The best decay rate stable on ``[0.5, 1.2]`` for ``k`` in ``[-0.8, -0.3]``, from ``k = -0.3``.

    The decay rate falls and the first crossing delay rises with ``k``, so the optimum is the end of the
    gains whose loop has no crossing delay up to 1.2 (the exact engine: ``k = -0.46758262``, a window
    end). The local design stops with pattern steps of ``1e-5`` of the width 0.5, so ``k`` agrees to
    ``1e-5`` (measured 4.5e-6) and the decay rate, whose slope in ``k`` is about 6.3 there, to ``1e-4``
    (measured 2.9e-5); being feasible, it is never better than the optimum. The designed loop's
    spectral abscissa at 3 delays of the window is negative (each certified). About 40 s of CPU time on a
    loaded machine (the design about 13 s, each abscissa at a delay 1-20 s)."""
    loop = state_feedback_loop(PLANT)
    exact = best_decay_rate(AffineGainLoop(loop.A, loop.units[0] * 0.0, loop.units[0]), (-0.8, -0.3), delays=(0.5, 1.2))
    design = design_nplusm_gains(SYSTEM, "decay_rate", delays=(0.5, 1.2), K_bounds=(-0.8, -0.3), x0=[[-0.3]], starts=1)
    assert design.certified and design.delays == ((0.5, 1.2),)
    (window,) = design.windows
    assert window.stable and window.certified and window.crossing is None and window.count == 0
    np.testing.assert_allclose(design.K[0][0], exact.K, atol=1e-5)
    np.testing.assert_allclose(design.value, exact.decay_rate, atol=1e-4)
    assert design.value <= exact.decay_rate + 1e-9
    # the window binds: the design's margin is just above its end (the same 1e-5 of the gains, slope ~2.6)
    assert design.margin is not None and 1.2 < design.margin.margin < 1.2 + 1e-4
    for delta in (0.5, 0.85, 1.2):  # the ends and the middle (the abscissa at 1.2 is -3.4e-6: the end binds)
        sa = spectral_abscissa(NPlusMCharacteristic(SYSTEM, design.gain, delta))
        assert sa.certified and sa.value < 0.0
    # the requirement binds: a gain 1e-3 below the design has a crossing delay in the window, and its loop at
    # delta = 1.2 is unstable (a positive abscissa: the oracle), as check_window says
    below = design.gain - 1e-3
    verdict = check_window(SYSTEM, below, nplusm_delay_margin(SYSTEM, below), (0.5, 1.2))
    assert not verdict.stable and verdict.crossing is not None and 0.5 <= verdict.crossing <= 1.2
    assert spectral_abscissa(NPlusMCharacteristic(SYSTEM, below, 1.2)).value > 0.0


@pytest.mark.long  # 86 s of CPU: run by make fuzz
def test_a_start_unstable_at_delta_zero_reaches_the_window() -> None:
    """From ``k = -0.15`` (the loop unstable at ``delta = 0``: the law stabilises for ``k`` in about
    ``(-0.84, -0.23)``) the phase before the first lowers the abscissa, the first phase raises the window
    margin, and the design ends at the same optimum as from a stable start: ``k`` to ``3e-5`` of the exact
    ``-0.46758262`` (pattern steps of ``1e-5`` of the width 0.7, and the last line-search step; measured
    1.2e-5), the decay rate to ``2e-4`` (slope about 6.3; measured 8e-5). About 90 s of CPU time."""
    loop = state_feedback_loop(PLANT)
    exact = best_decay_rate(AffineGainLoop(loop.A, loop.units[0] * 0.0, loop.units[0]), (-0.8, -0.1), delays=(0.5, 1.2))
    design = design_nplusm_gains(
        SYSTEM, "decay_rate", delays=(0.5, 1.2), K_bounds=(-0.8, -0.1), x0=[[-0.15]], starts=1, max_iter=10
    )
    assert design.certified and design.windows[0].stable and design.windows[0].certified
    np.testing.assert_allclose(design.K[0][0], exact.K, atol=3e-5)
    np.testing.assert_allclose(design.value, exact.decay_rate, atol=2e-4)
    assert design.value <= exact.decay_rate + 1e-9


def test_a_window_past_crossings_is_counted() -> None:
    """At ``k = -0.8`` the crossing delays up to 1.5 are 0.5027 (a pair enters ``Re s > 0``), 0.6024 (enters)
    and 0.9592 (leaves): on ``[1.0, 1.5]`` there is no crossing delay, and the certified count at
    ``delta = 1.0`` finds the 2 zeros the directions leave; the spectral abscissa there is positive
    (0.1432, a root search: the oracle). The only stability window is ``[0, 0.5027)``: the clearance of
    ``[1.0, 1.5]`` is ``min(inf, 0.5027 - 1.5)`` (negative: missed), that of ``[0.1, 0.4]``
    ``min(inf, 0.5027 - 0.4)``, and a window from 0 alike. CPU time about 6 s."""
    K = np.array([[-0.8]])
    dm = nplusm_delay_margin(SYSTEM, K)
    verdict = check_window(SYSTEM, K, dm, (1.0, 1.5))
    assert not verdict.stable and verdict.certified and verdict.count == 2 and verdict.crossing is None
    assert spectral_abscissa(NPlusMCharacteristic(SYSTEM, K, 1.0)).value > 0.1
    for window in ((1.0, 1.5), (0.1, 0.4), (0.0, 0.4)):
        c, end = window_clearance(SYSTEM, K, dm, [window])
        # the first crossing delay is the margin: the same number, so to rounding of the subtraction
        np.testing.assert_allclose(c, dm.margin - window[1], rtol=1e-14)
        assert end is not None and end[1] == dm.margin and end[2] == 1


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"delays": (1.0, 0.5)}, "delays"),
        ({"delays": [(0.0, 0.5), (-1.0, 1.0)]}, "delays[1]"),
        ({"delays": (0.0, 0.5), "margin_at_least": 0.3}, "margin_at_least"),
    ],
)
def test_bad_windows_are_refused(kwargs: dict, name: str) -> None:
    with pytest.raises(ParameterError) as info:
        design_nplusm_gains(SYSTEM, "decay_rate", K_bounds=(-0.8, -0.3), **kwargs)
    assert info.value.name == name
