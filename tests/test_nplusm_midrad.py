"""Midpoint-radius enclosures of small complex matrices (``nrobust.hyperbolic.nplusm._midrad``).

Oracle: mpmath at 40 digits (matrix exponential, determinant, singular values), sharing no code with the
enclosures. Each check asserts that the 40-digit value lies in the ball and that the ball is narrow (a ball
that holds everything would pass the first check alone).
"""

from __future__ import annotations

import numpy as np
import pytest

from nrobust.hyperbolic.nplusm import _midrad as mr

mpmath = pytest.importorskip("mpmath")


def mp_matrix(a: np.ndarray) -> object:
    return mpmath.matrix([[mpmath.mpc(float(v.real), float(v.imag)) for v in row] for row in a])


def in_ball(ref: object, mid: complex, rad: float) -> bool:
    """``|ref - mid| <= rad`` decided at 40 digits."""
    with mpmath.workdps(40):
        return bool(abs(ref - mpmath.mpc(mid.real, mid.imag)) <= rad)


@pytest.mark.parametrize("w", [0.0, 2.5, 40.0, 300.0])
def test_expm_holds_the_40_digit_exponential(w: float) -> None:
    """Matrices ``C - i w P`` like the loop's (3x3, ``P`` diagonal of both signs): mpmath's ``expm`` in the ball, radius
    below ``1e-9`` (measured 5e-11 at ``w = 300``, ten squarings) and above the true error (measured ratio 15)."""
    rng = np.random.default_rng(int(w))
    with mpmath.workdps(40):
        for _ in range(4):
            a = rng.normal(size=(3, 3)) + 0.1j * rng.normal(size=(3, 3)) - 1j * w * np.diag([1.0, -0.5, 0.7])
            ball = mr.expm(mr.exact(a[None]))
            ref = mpmath.expm(mp_matrix(a))
            for i in range(3):
                for j in range(3):
                    assert in_ball(ref[i, j], ball.mid[0, i, j], ball.rad[0, i, j])
            assert ball.rad.max() < 1e-9


def test_expm_of_a_ball_holds_every_member() -> None:
    """A ball of radius ``1e-6`` about a 2x2 matrix: the exponentials of its corners (mpmath) lie in the enclosure."""
    a = np.array([[0.3 - 4j, 1.2], [-0.7, -0.2 + 1j]])
    ball = mr.expm(mr.Ball(a[None], np.full((1, 2, 2), 1e-6)))
    with mpmath.workdps(40):
        for corner in ([1, 1, 1, 1], [-1, 1, -1, 1], [1j, -1j, 1, -1]):
            shift = np.array(corner, dtype=complex).reshape(2, 2) * 1e-6 / np.sqrt(2)
            ref = mpmath.expm(mp_matrix(a + shift))
            assert all(in_ball(ref[i, j], ball.mid[0, i, j], ball.rad[0, i, j]) for i in range(2) for j in range(2))


def test_det_and_singular_bounds_hold_the_40_digit_values() -> None:
    """Random complex 3x3 matrices and a nearly singular one: mpmath's determinant in the enclosure and its singular
    values in the proven brackets, each bracket narrower than ``1e-10`` (relative slack ``1e-12`` per bound)."""
    rng = np.random.default_rng(7)
    a = rng.normal(size=(20, 3, 3)) + 1j * rng.normal(size=(20, 3, 3))
    a[0] = [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0 + 1e-13], [0.5, 0.1, 0.2]]
    d = mr.det(mr.exact(a))
    lower, upper = mr.singular_bounds(a)
    assert np.all(upper - lower < 1e-10)
    with mpmath.workdps(40):
        for k in range(a.shape[0]):
            m = mp_matrix(a[k])
            assert in_ball(mpmath.det(m), complex(d.mid[k]), float(d.rad[k]))
            sig = sorted((float(v) for v in mpmath.svd_c(m, compute_uv=False)), reverse=True)
            assert np.all(lower[k] <= sig) and np.all(np.array(sig) <= upper[k])
    assert lower[0, -1] < 1e-12  # the nearly singular matrix: sigma_min about 1e-14 is not overstated
