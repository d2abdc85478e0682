"""The kernel route's convergence to a proven margin (a check shared by the varying-coefficient proofs)."""

from __future__ import annotations

from typing import Any

import numpy as np

import nrobust as nr


def assert_kernel_route_converges(plant: Any, controller: Any, proven: float) -> list[float]:
    """The kernel route on 101, 201, 401 points converges to ``proven`` at its observed order (about 3).

    Returns the three margins. The extrapolation (Richardson with the observed order) must meet ``proven``
    within a fifth of the last difference: the order is known to +-0.5.
    """
    margins = [nr.delay_margin(plant, controller, delta_max=20.0, kernel_grid=n).margin for n in (101, 201, 401)]
    d1, d2 = margins[1] - margins[0], margins[2] - margins[1]
    order = np.log2(d1 / d2)
    assert 2.5 < order < 3.5
    extrapolated = margins[2] + d2 / (2.0**order - 1.0)
    np.testing.assert_allclose(extrapolated, proven, rtol=0, atol=0.2 * abs(d2))
    return margins
