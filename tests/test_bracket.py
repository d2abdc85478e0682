"""The Illinois regula falsi of many brackets at once, against zeros known in closed form."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from nrobust._bracket import illinois


@settings(max_examples=60, deadline=None)
@given(
    roots=st.lists(st.floats(-50.0, 50.0), min_size=1, max_size=8),
    curvature=st.floats(0.0, 5.0),
    left=st.floats(1e-3, 10.0),
    right=st.floats(1e-3, 10.0),
)
def test_zeros_of_odd_functions_about_known_points(
    roots: list[float], curvature: float, left: float, right: float
) -> None:
    """``f(x) = (x - r)(1 + k (x - r)^2) + 0.3 (x - r)^2`` has the one real zero ``r`` when ``k >= 0.03``."""
    r = np.array(roots)
    k = 0.03 + curvature

    def f(x: np.ndarray) -> np.ndarray:
        d = x - r
        return d * (1.0 + k * d * d) + 0.3 * d * d

    x = illinois(f, r - left, r + right)
    # stopped at 4 eps relative width: the zero to a few units in the last place of max(|a|, |b|)
    assert np.all(np.abs(x - r) <= 16 * np.finfo(float).eps * (np.abs(r) + 10.0)), (x, r)


def test_fixed_steps_take_the_better_end_and_empty_input() -> None:
    """A fixed number of steps returns a point of the last bracket; no brackets, no zeros."""
    x = illinois(lambda x: np.cos(x), np.array([1.0, 4.0]), np.array([2.0, 5.0]), steps=3)
    np.testing.assert_allclose(x, [np.pi / 2, 3 * np.pi / 2], atol=1e-2)  # three steps from unit brackets
    assert np.all((x > [1.0, 4.0]) & (x < [2.0, 5.0]))
    assert illinois(np.cos, np.zeros(0), np.zeros(0)).size == 0


def test_an_exact_zero_at_an_end_stops_at_once() -> None:
    """``f(a) = 0`` is a zero: returned as it is, whatever the other end."""
    calls = []

    def f(x: np.ndarray) -> np.ndarray:
        calls.append(x.size)
        return x - 1.0

    np.testing.assert_array_equal(illinois(f, np.array([1.0]), np.array([7.0])), [1.0])
    assert calls == [1, 1]  # f(a) and f(b), no step


def test_superlinear_convergence_the_kept_end_halved_only_when_kept_twice() -> None:
    """Illinois converges with order about 1.44: a smooth zero to rounding in a dozen evaluations.

    ``e^x - 2 - x^3 / 10`` on ``[0, 2]`` (convex: plain regula falsi keeps the right end for
    ever), ``x^3 - 1/2`` on ``[0, 1]``, ``tan x - 1`` on ``[0, 1.5]``: 11, 13 and 17
    evaluations; a linear method (halving the kept end at every step) takes 50 to 55.
    """
    cases = [
        (lambda x: np.exp(x) - 2.0 - x**3 / 10.0, 0.0, 2.0, 0.7109555683171624),
        (lambda x: x**3 - 0.5, 0.0, 1.0, 0.5 ** (1.0 / 3.0)),
        (lambda x: np.tan(x) - 1.0, 0.0, 1.5, np.pi / 4),
    ]
    for g, a, b, root in cases:
        calls: list[int] = []

        def f(x: np.ndarray, g=g, calls=calls) -> np.ndarray:
            calls.append(x.size)
            return g(x)

        x = illinois(f, np.array([a]), np.array([b]))
        np.testing.assert_allclose(x, [root], rtol=8 * np.finfo(float).eps)
        assert len(calls) <= 20, (root, len(calls))
