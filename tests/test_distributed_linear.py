"""``DistributedDelay.times`` and ``plus``: the pieces of ``c N`` and ``N_1 + N_2`` are those the constructor
builds from the scaled or summed data (polynomial pieces combined directly, splines solved again from the values,
so that equal terms evaluate alike)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nrobust.quasipoly import DistributedDelay

# Spline coefficients built two ways (scaled pieces against the spline of scaled values) differ by the
# rounding of the spline's linear solve: a few ulps of the largest coefficient times the conditioning
# of the not-a-knot system on these grids (below 10 for nodes at least a tenth of the mean step apart).
RTOL = 1e-12


def _terms(seed: int, interpolation: str) -> tuple[DistributedDelay, DistributedDelay]:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 12))
    steps = rng.uniform(0.1, 1.0, n - 1)
    if interpolation != "polynomial" and n > 4 and rng.random() < 0.5:  # a jump: one node twice
        steps[int(rng.integers(1, n - 2))] = 0.0
    nodes = rng.uniform(0.0, 1.0) + np.concatenate([[0.0], np.cumsum(steps)])
    if interpolation == "polynomial":
        make = lambda: DistributedDelay(  # noqa: E731
            nodes, None, moment=1, interpolation="polynomial", coefficients=rng.normal(size=(n - 1, 5)), radius=1e-9
        )
    else:
        make = lambda: DistributedDelay(  # noqa: E731
            nodes, rng.normal(size=n), moment=1, interpolation=interpolation, radius=1e-9, variation_radius=2e-9
        )
    return make(), make()


def _rebuilt(d: DistributedDelay, data: np.ndarray, radius: float, variation: float) -> DistributedDelay:
    """The constructor's term with the same nodes and new values (or coefficients)."""
    if d.interpolation == "polynomial":
        return DistributedDelay(
            d.nodes, None, d.poly, d.moment, "polynomial", coefficients=data, radius=radius, variation_radius=variation
        )
    return DistributedDelay(d.nodes, data, d.poly, d.moment, d.interpolation, radius=radius, variation_radius=variation)


def _data(d: DistributedDelay) -> np.ndarray:
    return d.pieces[2] if d.interpolation == "polynomial" else d.values


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    interpolation=st.sampled_from(["linear", "cubic", "polynomial"]),
    c=st.complex_numbers(max_magnitude=1e3, allow_nan=False, allow_infinity=False),
)
def test_scaled_and_summed_pieces_are_the_constructors(seed: int, interpolation: str, c: complex) -> None:
    d1, d2 = _terms(seed, interpolation)
    scaled = d1.times(c)
    want = _rebuilt(d1, _data(d1) * c, scaled.radius, scaled.variation_radius)
    scale = max(float(np.max(np.abs(want.pieces[2]))), 1e-300)
    np.testing.assert_allclose(scaled.pieces[2], want.pieces[2], rtol=0, atol=RTOL * scale)
    np.testing.assert_array_equal(scaled.pieces[0], want.pieces[0])
    np.testing.assert_array_equal(scaled.pieces[1], want.pieces[1])
    assert scaled == want and scaled.radius >= abs(c) * d1.radius
    total = d1.plus(d2)
    want = _rebuilt(d1, _data(d1) + _data(d2), total.radius, total.variation_radius)
    scale = max(float(np.max(np.abs(want.pieces[2]))), 1e-300)
    np.testing.assert_allclose(total.pieces[2], want.pieces[2], rtol=0, atol=RTOL * scale)
    assert total.radius >= d1.radius + d2.radius and total.variation_radius >= d1.variation_radius + d2.variation_radius
    s = np.array([0.3 + 2.0j, -0.5 + 40.0j])  # the sums evaluate as the constructor's terms do
    np.testing.assert_allclose(total(s), want(s), rtol=1e-11, atol=1e-12 * float(np.max(np.abs(want(s)))))


def test_a_new_moment_keeps_the_kernel_and_a_bad_one_is_refused() -> None:
    d, _ = _terms(7, "cubic")
    moved = d.times(-2.0, moment=3)
    assert moved.moment == 3 and np.array_equal(moved.pieces[2], d.pieces[2] * -2.0)
    with pytest.raises(ValueError, match="moment"):
        d.times(1.0, moment=-1)
    with pytest.raises(ValueError, match="moment"):
        d.times(1.0, moment=True)
