"""The derivative bound of a determinant on short segments: valid, and sharp where Hadamard's is not.

The system is the descriptor closed loop of the TDS-CONTROL manual's Example 2.9 (n = 6,
``E`` singular), whose determinant cancels heavily: Hadamard's inequality alone overestimates
``|det'|`` about tenfold on every segment, which made the certified count of its rectangle
take three times the contour steps.
"""

from __future__ import annotations

import numpy as np
import pytest

from nrobust import count_roots
from nrobust.lti.statespace import StateSpaceTDS

M0, M1 = np.zeros((6, 6)), np.zeros((6, 6))
M0[:2, :2], M0[2, :2], M0[2, 2] = [[0.2, 0.1], [-0.5, 1.0]], [1.0, 1.0], -1.0
M0[3, 2], M0[3, 3] = 3.1, -3.48
M0[4:, 2], M0[4:, 3], M0[4:, 4:] = [-1.86, -1.4], [1.79, -0.09], -np.eye(2)
M1[:2, :2], M1[:2, 4:], M1[2, 4:] = [[0.5, 0.3], [0.1, -0.1]], np.eye(2), [0.01, 0.01]
E = np.diag([1.0, 1.0, 0.0, 1.0, 0.0, 0.0])
SYSTEM = StateSpaceTDS([M0, M1], [0.0, 1.0], E=E)
REGION = (-1.0, 0.5, -10.0, 10.0)


def _det(s: np.ndarray) -> np.ndarray:
    """``det(s E - M0 - M1 e^{-s})`` written out with numpy (independent of the matrix class)."""
    return np.linalg.det(s[..., None, None] * E - M0 - M1 * np.exp(-s)[..., None, None])


def _sampled_derivative(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Largest ``|det'|`` over 21 points of each segment, by central differences of step 1e-5."""
    pts = a[:, None] + (b - a)[:, None] * np.linspace(0.0, 1.0, 21)[None, :]
    h = 1e-5
    return np.max(np.abs((_det(pts + h) - _det(pts - h)) / (2 * h)), axis=1)


@pytest.mark.parametrize("length", [1e-3, 1e-2, 1e-1, 1.0])
def test_bound_dominates_the_derivative(length: float) -> None:
    """On random segments of the counted rectangle the bound is at least the sampled maximum.

    The central difference errs by at most ``h^2 max|det'''| / 6 + eps max|det| / h`` (plus the
    rounding of the two LU determinants, a few eps of ``|det|``): with ``|det| < 1e4`` and
    ``|det'''| < 1e5`` on the rectangle enlarged by 1 (sampled: 4.1e3 and 3.3e3) that is below
    2e-6, so 1e-5 is allowed.
    """
    rng = np.random.default_rng(7)
    a = rng.uniform(REGION[0], REGION[1], 200) + 1j * rng.uniform(REGION[2], REGION[3], 200)
    b = a + length * np.exp(2j * np.pi * rng.uniform(size=200))
    M = SYSTEM.characteristic_matrix()
    assert np.all(M.deriv_bound(a, b) >= _sampled_derivative(a, b) - 1e-5)


def test_bound_is_sharp_on_short_segments() -> None:
    """On segments of length 1e-2 the bound is within 50 % of the sampled maximum (median):
    the first-order Taylor form about the midpoint, not Hadamard's inequality, decides there."""
    rng = np.random.default_rng(8)
    a = rng.uniform(REGION[0], REGION[1], 200) + 1j * rng.uniform(REGION[2], REGION[3], 200)
    b = a + 1e-2 * np.exp(2j * np.pi * rng.uniform(size=200))
    ratio = SYSTEM.characteristic_matrix().deriv_bound(a, b) / _sampled_derivative(a, b)
    assert np.median(ratio) < 1.5


def test_count_of_the_rectangle() -> None:
    """tdcpy (examples/example2_9.py) finds 4 roots in this rectangle; the certified count agrees,
    with the segment bounds sharp enough for fewer than 3,000 evaluations (Hadamard's alone: 4,750)."""
    c = count_roots(SYSTEM.characteristic_matrix(), REGION)
    assert int(c) == 4 and not c.shifted
    assert c.evaluations < 3000


def test_characteristic_matrix_is_built_once() -> None:
    """The system is immutable: its matrix (with its compiled coefficients) is reused."""
    assert SYSTEM.characteristic_matrix() is SYSTEM.characteristic_matrix()


@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_determinant_and_derivative_by_hand(n: int) -> None:
    """det M and (det M)' of ``s I - A0 - A1 e^{-s}`` against numpy on the matrices written out
    (LU) and a central difference of step 1e-6 (truncation and rounding below 1e-8 here)."""
    rng = np.random.default_rng(n)
    a0, a1 = rng.normal(size=(2, n, n))
    M = StateSpaceTDS([a0, a1], [0.0, 1.0]).characteristic_matrix()

    def by_hand(s: np.ndarray) -> np.ndarray:
        return np.linalg.det(s[..., None, None] * np.eye(n) - a0 - a1 * np.exp(-s)[..., None, None])

    s = np.array([0.3 + 2.0j, -1.0 - 5.0j, 0.7 + 0.1j])
    np.testing.assert_allclose(M(s), by_hand(s), rtol=1e-12)
    h = 1e-6
    np.testing.assert_allclose(M.deriv_at(s), (by_hand(s + h) - by_hand(s - h)) / (2 * h), rtol=1e-7)
