"""Plain kernel solutions kept between solves (``constant._kept_grid``): the same tables, never shared with callers.

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
