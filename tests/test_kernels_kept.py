"""Plain kernel solutions kept between solves (``constant._kept_grid``), and the cubic feet's weights of a few points.

The coarse half of an extrapolated solve on 201 points is the fine grid of the solve on 101 points: kept, the
second solve reads it. The check: every solve equals the one with nothing kept (bit for bit), and the tables a
caller receives are its own (writable, and writing them changes no later solve).
"""

from __future__ import annotations

import numpy as np

from nrobust import Hyperbolic2x2
from nrobust.hyperbolic.kernels import constant
from nrobust.hyperbolic.kernels.constant import solve_kernels

PLANT = Hyperbolic2x2(1.0, 1.5, 1.0, 0.7, 0.9, 0.4)


def _fresh(n: int):
    constant._kept_grid.cache_clear()
    return solve_kernels(PLANT, n)


def test_kept_solutions_give_the_same_tables():
    expected = {n: _fresh(n) for n in (201, 101, 100)}
    constant._kept_grid.cache_clear()
    for n in (201, 101, 100, 101):
        got = solve_kernels(PLANT, n)
        assert np.array_equal(got.K, expected[n].K)
        assert np.array_equal(got.L, expected[n].L)


def test_callers_tables_are_their_own():
    first = solve_kernels(PLANT, 100)  # even: not extrapolated, the kept solution itself
    assert first.K.flags.writeable and first.L.flags.writeable
    reference = first.K.copy()
    first.K[:] = 0.0
    first.L[:] = 0.0
    again = solve_kernels(PLANT, 100)
    assert np.array_equal(again.K, reference)
    assert np.any(again.L != 0.0)


def test_lagrange_weights_of_few_and_many_feet():
    """The cubic stencils' weights reproduce cubics (closed form; rounding measured 3e-16 of the values on
    ``[-1, 4]``), and the weights of a few feet (Python floats) are those of many (numpy), bit for bit."""
    rng = np.random.default_rng(11)
    cubic = np.polynomial.Polynomial([0.3, -1.2, 0.8, 0.25])
    many = rng.uniform(-1.0, 4.0, 40)
    together = constant._lagrange_weights(many, 4)
    assert np.max(np.abs(together @ cubic(np.arange(4.0)) - cubic(many))) <= 1e-13 * np.max(np.abs(cubic(many)))
    for size in range(constant._FEW_FEET + 1):
        assert np.array_equal(constant._lagrange_weights(many[:size], 4), together[:size])
