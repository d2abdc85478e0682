"""The not-a-knot cubic splines of the collocated observer's command response (``collocated._splines``).

Oracles: a cubic is its own not-a-knot spline (closed form), and scipy's ``CubicSpline`` (default
``bc_type``, another solver) on noisy data. Tolerances from the measured rounding: at most 3.4e-15 of the
data's size against scipy and 5e-16 against the cubic (grids of 5 to 201 points), so ``1e-13`` is loose for
rounding and far below a wrong end condition (the natural spline differs from scipy's by 0.09 of it here).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from nrobust.hyperbolic.loops import collocated

RTOL = 1e-13


@pytest.mark.parametrize("n", [5, 11, 201])
def test_reproduces_a_cubic(n):
    x = np.linspace(0.0, 1.0, n)
    cubic = np.polynomial.Polynomial([1.0, -2.0, 0.5, 3.0])
    (spline,) = collocated._splines(cubic(x)[:, None])
    points = np.r_[0.0, 1.0, x[1:-1], np.random.default_rng(n).uniform(0.0, 1.0, 500)]
    assert np.max(np.abs(spline(points) - cubic(points))) <= RTOL * np.max(np.abs(cubic(x)))


@pytest.mark.parametrize("n", [5, 51, 201])
def test_against_scipy(n):
    rng = np.random.default_rng(n)
    x = np.linspace(0.0, 1.0, n)
    values = np.stack([np.cos(3.0 * x) + 0.1 * rng.standard_normal(n), np.exp(-x) * rng.standard_normal(n)], axis=1)
    points = np.r_[0.0, 1.0, x, rng.uniform(0.0, 1.0, 2000)]
    for k, spline in enumerate(collocated._splines(values)):
        expected = CubicSpline(x, values[:, k])(points)
        assert np.max(np.abs(spline(points) - expected)) <= RTOL * np.max(np.abs(values[:, k]))
