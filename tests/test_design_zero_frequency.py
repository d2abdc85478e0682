"""``window_stability`` where ``|A(0)| = |B(0)|``: ``g = |A(i w)|^2 - |B(i w)|^2`` has a double zero at ``w = 0``.

``A = s^2 + 0.5 s + 1`` and ``B = +-1``: ``g(w) = w^4 - 1.75 w^2`` (closed form), zero at ``w = 0`` and
``w = sqrt(1.75)``. With ``B = -1``, ``F(0; delta) = A(0) + B(0) = 0`` for every delay: no window is stable.
With ``B = 1``, ``s = 0`` is a root for no delay, and the search cannot decide about ``w = 0``: refused,
naming the factors.
"""

from __future__ import annotations

import numpy as np
import pytest

from nrobust import QuasiPolynomial
from nrobust.design.gain import window_stability
from nrobust.errors import ParameterError

A = QuasiPolynomial([[1.0, 0.5, 1.0]], [0.0])


def test_closed_form_of_g() -> None:
    w = np.array([0.0, 0.3, np.sqrt(1.75)])
    for b in (1.0, -1.0):
        g = np.abs(A(1j * w)) ** 2 - b**2
        # exact polynomial values in double precision: a few roundings of numbers below 4
        np.testing.assert_allclose(g, w**4 - 1.75 * w**2, rtol=0, atol=1e-14)


@pytest.mark.parametrize("delays", [(0.5, 1.0), (0.0, 1.0)])
def test_root_at_zero_for_every_delay_is_refuted(delays: tuple[float, float]) -> None:
    B = QuasiPolynomial([[-1.0]], [0.0])
    assert complex((A + B)(np.zeros(1))[0]) == 0.0  # F(0; delta) = A(0) + B(0) = 0: s = 0 a root for every delay
    window = window_stability(A, B, delays)
    assert not window.stable and window.certified == "refuted"
    assert window.reason == "s = 0 is a root for every delay" and window.margin.zero_root


def test_equal_values_at_zero_refused_naming_the_factors() -> None:
    B = QuasiPolynomial([[1.0]], [0.0])
    with pytest.raises(ParameterError, match=r"A, B must be loop factors with \|A\(0\)\| != \|B\(0\)\|"):
        window_stability(A, B, (0.5, 1.0))
