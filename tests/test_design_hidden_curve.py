"""``best_margin`` where the sampled envelope hides the lower of two crossing curves near its top.

The collocated observer's loop affine in its reflection ``kappa`` (paper plant, ``U_BS2(0.1)`` on the
estimate): near ``kappa = -0.718`` a crossing curve of frequency about 20.54, born in a pair at
``kappa = -0.71619`` and steep in ``kappa``, meets a flat curve of frequency about 3.19. Interpolated
linearly in ``kappa`` near its birth the steep curve was 1.2e-3 above its exact delay, above the
flat curve at every sampled gain: with bounds ``(-0.7185, 0.1)`` the design was the end
``kappa = -0.7185`` (margin 0.19382) instead of the kink (0.19488). The oracle here: each curve's
delay solved by ``brentq`` on ``|A(i w)|^2 - |B(i w)|^2`` from the loop's factors (no code of the
design), the kink by ``brentq`` on their difference, and certified margins on a grid of ``kappa``.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

import nrobust as nr
from nrobust.design.gain import AffineLoop, best_margin
from nrobust.margins import delay_margin

observer_design = pytest.importorskip("nrobust.hyperbolic.analyses.observer_design")


@pytest.fixture(scope="module")
def loop() -> AffineLoop:
    plant = nr.Hyperbolic2x2(1, 1, 1, 1, 1, 0.85)
    law = nr.CollocatedOutputFeedback(nr.ReflectionController(0.1))
    return observer_design.collocated_observer_loop(plant, law)


def _delay(loop: AffineLoop, kappa: float, w_lo: float, w_hi: float) -> float:
    """The crossing delay ``arg(-B/A) / w`` (principal phase) of the zero of ``|A|^2 - |B|^2`` in ``[w_lo, w_hi]``."""
    A, B = loop.A(kappa), loop.B(kappa)

    def g(w: float) -> float:
        s = np.array([1j * w])
        return float(abs(A(s)[0]) ** 2 - abs(B(s)[0]) ** 2)

    w = brentq(g, w_lo, w_hi, xtol=1e-15, rtol=1e-15)
    s = np.array([1j * w])
    return float(np.mod(np.angle(-B(s)[0] / A(s)[0]), 2.0 * np.pi)) / w


def _kink(loop: AffineLoop) -> tuple[float, float]:
    # the flat curve near w = 3.19, the steep one near w = 20.54 (its pair's twin near 20.51, the birth at 20.5255)
    def gap(k: float) -> float:
        return _delay(loop, k, 3.18, 3.20) - _delay(loop, k, 20.526, 20.58)

    k = brentq(gap, -0.7185, -0.7175, xtol=1e-15, rtol=1e-15)
    return k, _delay(loop, k, 3.18, 3.20)


@pytest.mark.parametrize("lo", [pytest.param(-0.74, marks=pytest.mark.long), -0.7185])
def test_kink_of_a_curve_the_interpolation_hides(loop: AffineLoop, lo: float) -> None:
    design = best_margin(loop, (lo, 0.1), max_evals=2_000_000)
    k, d = _kink(loop)
    assert design.kind == "kink"
    # the two curves cross at slopes about 2.3 and -0.25 in kappa: the delays solved to ~1e-16 put the kink
    # within ~1e-15; 1e-12 leaves room for the Newton of the design and the brentq of the oracle
    np.testing.assert_allclose(design.K, k, rtol=0, atol=1e-12)
    np.testing.assert_allclose(design.value, d, rtol=1e-12)
    # certified margins about the optimum: none beats the design (1e-9: the certificate's accuracy); the grid
    # point nearest the kink is within its slope (at most 2.3) times its distance of it
    grid = np.array([-0.7185, -0.7181, -0.71805, -0.7179, -0.7177, -0.7170])
    margins = np.array([delay_margin(loop.A(x), loop.B(x)).margin for x in grid])
    assert np.all(margins <= design.value * (1.0 + 1e-9))
    near = int(np.argmin(np.abs(grid - k)))
    np.testing.assert_allclose(margins[near], design.value, rtol=0, atol=2.5 * abs(grid[near] - k) + 1e-12)
