"""StateSpaceTDS keeps the eigenvalue problems of its collocated generator (one per number of points).

The matrices of the collocation depend on the system and the number of points only, so a
system builds each once and every later call solves it again. Oracle: the same system built
anew (nothing kept), whose first call builds its problem from scratch; the eigenvalues must
agree whatever was kept or dropped before. Three systems reach the three forms of the problem:
an invertible ``E`` (a standard problem), Example 2.9 (a singular ``E`` whose algebraic rows are
eliminated) and ``E = 0`` (no differential part: the shift and invert of the pencil).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from _statespace_examples import example_2_9

from nrobust.lti.statespace import _KEPT_COLLOCATIONS, StateSpaceTDS


def _retarded_2x2() -> StateSpaceTDS:
    return StateSpaceTDS([[[-1.0, 0.5], [0.3, -2.0]], [[-0.8, 0.2], [0.1, -0.5]]], [0.0, 1.0])


def _algebraic_2x2() -> StateSpaceTDS:
    """``0 = A_0 x + A_1 x(t - 1)``: ``E = 0``, no algebraic row can be eliminated (rank 0)."""
    return StateSpaceTDS([[[-1.0, 0.2], [0.1, -1.0]], [[0.5, 0.1], [0.0, 0.4]]], [0.0, 1.0], E=np.zeros((2, 2)))


def _sorted(z: np.ndarray) -> np.ndarray:
    return z[np.lexsort((z.imag, z.real))]


@pytest.mark.parametrize("make", [_retarded_2x2, example_2_9, _algebraic_2x2])
def test_kept_problems_give_the_eigenvalues_of_a_fresh_system(make: Callable[[], StateSpaceTDS]) -> None:
    """Repeated calls and calls after older problems were dropped agree with a system built anew.

    The same matrices are solved by the same LAPACK routine, so the eigenvalues agree to rounding
    (rtol 1e-12 allows a threaded BLAS to sum in another order); the number of kept problems stays
    at most ``_KEPT_COLLOCATIONS`` however many numbers of points were asked for.
    """
    sys = make()
    frequencies = [4.0 * k for k in range(_KEPT_COLLOCATIONS + 2)]  # distinct numbers of points (12, 13, ...)
    first = {w: sys.generator_eigenvalues(w) for w in frequencies}
    assert len(sys._collocations) == _KEPT_COLLOCATIONS
    for w in frequencies + frequencies[::-1]:  # kept ones, dropped ones built again, in both orders
        again = sys.generator_eigenvalues(w)
        fresh = make().generator_eigenvalues(w)
        assert again.size == fresh.size == first[w].size > 0
        np.testing.assert_allclose(_sorted(again), _sorted(fresh), rtol=1e-12)
        np.testing.assert_allclose(_sorted(first[w]), _sorted(fresh), rtol=1e-12)
    assert len(sys._collocations) <= _KEPT_COLLOCATIONS
