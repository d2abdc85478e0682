"""Root search of StateSpaceTDS.roots against oracles independent of nrobust.

Oracles: roots placed by construction (diagonal and Jordan matrices), the Lambert W closed form of the
root of s + 1 - e^{-s} / 2 (s = W(e / 2) - 1, by mpmath at 40 digits), and an argument-principle count
written here in numpy (phase increments of det M on 4 x 40000 boundary points, each checked < 1 rad).
"""

from __future__ import annotations

from collections.abc import Callable

import mpmath
import numpy as np
import pytest

from nrobust import ParameterError
from nrobust.lti.statespace import StateSpaceTDS


def _det(
    E: np.ndarray, A: list[np.ndarray], hA: list[float], B: list[np.ndarray], hB: list[float]
) -> Callable[[np.ndarray], np.ndarray]:
    def f(s: np.ndarray) -> np.ndarray:
        M = s[:, None, None] * E - sum(a * np.exp(-h * s)[:, None, None] for a, h in zip(A, hA))
        for b, h in zip(B, hB):
            M = M - s[:, None, None] * b * np.exp(-h * s)[:, None, None]
        return np.asarray(np.linalg.det(M))

    return f


def _argument_count(
    f: Callable[[np.ndarray], np.ndarray], box: tuple[float, float, float, float], n: int = 40000
) -> int:
    x0, x1, y0, y1 = box
    t = np.linspace(0.0, 1.0, n, endpoint=False)
    z = np.concatenate(
        [
            x0 + (x1 - x0) * t + 1j * y0,
            x1 + 1j * (y0 + (y1 - y0) * t),
            x1 - (x1 - x0) * t + 1j * y1,
            x0 + 1j * (y1 - (y1 - y0) * t),
        ]
    )
    v = f(z)
    step = np.angle(np.roll(v, -1) / v)
    assert np.abs(step).max() < 1.0  # the phase is resolved: the count below is exact
    return round(float(step.sum()) / (2 * np.pi))


@pytest.mark.parametrize("seed", range(8))
def test_random_counts_match_the_argument_principle(seed: int) -> None:
    rng = np.random.default_rng(1000 + seed)
    n = 1 + seed % 3
    kind = seed % 4  # 0, 3 retarded; 1 neutral; 2 descriptor with singular E
    A = [rng.normal(size=(n, n)), 0.8 * rng.normal(size=(n, n))]
    hA = [0.0, float(rng.uniform(0.3, 2.0))]
    B, hB = ([0.3 * rng.normal(size=(n, n))], [float(rng.uniform(0.2, 1.5))]) if kind == 1 else ([], [])
    E = np.diag([1.0] * (n - 1) + [0.0]) if kind == 2 and n > 1 else np.eye(n)
    box = (-2.5, 1.0, -15.0, 15.0)
    f = _det(E, A, hA, B, hB)
    roots = StateSpaceTDS(A, hA, B=B, hB=hB, E=E).roots(box)
    assert roots.certified
    assert roots.count == _argument_count(f, box)
    assert int(roots.multiplicities.sum()) == roots.count
    # every reported root is a zero of det M: |det M| well below its size on the boundary
    if roots.roots.size:
        assert np.all(np.abs(f(roots.roots)) < 1e-6 * np.abs(f(np.array([box[0] + 1j * box[2]])))[0] + 1e-8)


def test_double_root_of_a_diagonal_system() -> None:
    """det = (s + 1 - e^{-s} / 2)^2: the real root W(e/2) - 1 is double, and the count is twice the scalar's."""
    box = (-3.0, 1.0, -10.0, 10.0)
    r = StateSpaceTDS([-np.eye(2), 0.5 * np.eye(2)], [0.0, 1.0]).roots(box)
    single = StateSpaceTDS([-np.eye(1), 0.5 * np.eye(1)], [0.0, 1.0]).roots(box)
    assert r.count == 2 * single.count
    mpmath.mp.dps = 40
    exact = float(mpmath.lambertw(mpmath.e / 2) - 1)
    real = np.abs(r.roots.imag) < 1e-6
    assert r.multiplicities[real].tolist() == [2]
    # a double root: the accuracy is ~sqrt(eps) of the scalar's Newton limit
    np.testing.assert_allclose(r.roots[real].real, [exact], atol=1e-7)
    np.testing.assert_allclose(single.roots[np.abs(single.roots.imag) < 1e-6].real, [exact], rtol=1e-12)


@pytest.mark.parametrize("im_max", [46.0, 54.0, 62.0, 68.0])
def test_counts_either_side_of_the_dense_switch(im_max: float) -> None:
    """x' = -x - 2 x(t - 1): 15, 16, 17, 18 roots in the box, so the limit points of Newton's method pass
    the 16 of the all-distances path (the count equal to the argument principle's either side)."""
    A, hA = [-np.eye(1), -2.0 * np.eye(1)], [0.0, 1.0]
    box = (-6.0, 1.0, -40.0, im_max)
    r = StateSpaceTDS(A, hA).roots(box)
    assert r.certified
    assert r.count == _argument_count(_det(np.eye(1), A, hA, [], []), box)
    assert r.count == r.roots.size  # simple roots (s + 1 + 2 e^{-s} has no multiple root here)


def test_two_systems_in_one_process_do_not_share_counts() -> None:
    """The same box counted for two functions: each count is its own (1 root, then 2)."""
    box = (-3.0, 1.0, -1.0, 1.0)
    one = StateSpaceTDS([np.diag([-1.0, -50.0]), np.zeros((2, 2))], [0.0, 1.0]).roots(box)
    two = StateSpaceTDS([np.diag([-1.0, -2.0]), np.zeros((2, 2))], [0.0, 1.0]).roots(box)
    assert (one.count, two.count) == (1, 2)
    np.testing.assert_allclose(np.sort(two.roots.real), [-2.0, -1.0], rtol=1e-12)


def test_more_states_than_the_expansion_takes_is_refused_naming_A() -> None:
    """15 states: the roots are refused with a ParameterError naming ``A`` and the limit of 8."""
    system = StateSpaceTDS([np.diag(-np.arange(1.0, 16.0)), np.zeros((15, 15))], [0.0, 1.0])
    with pytest.raises(ParameterError, match=r"A must be at most 8 states"):
        system.roots((-20.0, 1.0, -1.0, 1.0))
