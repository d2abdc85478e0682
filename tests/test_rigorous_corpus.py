"""The floating-point and the ball-arithmetic paths agree on the corpus of the floating-point tests.

For every case of ``tests/_corpus.py``: the counts are equal (on the same rectangle), every
floating-point root lies in exactly one proven box, the abscissae agree (and the
floating-point rightmost root lies in the proven ``root_box``), and every floating-point
delay margin lies in the proven ``margin_ball``. The fast cases run in CI; the whole
corpus under ``-m long`` (``make fuzz``).
"""

from __future__ import annotations

import numpy as np
import pytest
from _corpus import ABSCISSAE, CROSSINGS, MARGINS, ROOTS

from nrobust import crossing_frequencies, delay_margin
from nrobust.margins.proven import proven_crossings
from nrobust.roots import count_roots, find_roots, spectral_abscissa

pytest.importorskip("flint")


def _params(table: dict) -> list:
    return [pytest.param(name, marks=() if fast else pytest.mark.long) for name, (_, fast) in sorted(table.items())]


@pytest.mark.parametrize("name", _params(ROOTS))
def test_counts_and_roots_agree(name: str) -> None:
    F, region = ROOTS[name][0]
    float_count, proven_count = count_roots(F, region), count_roots(F, region, rigorous=True)
    assert int(proven_count) == int(float_count) and proven_count.region == float_count.region
    found = find_roots(F, region)
    proven = find_roots(F, region, rigorous=True)
    assert proven.rigorous and proven.count == found.count == int(float_count)
    b = proven.boxes
    z = found.roots[:, None]
    inside = (b[:, 0] <= z.real) & (z.real <= b[:, 1]) & (b[:, 2] <= z.imag) & (z.imag <= b[:, 3])
    assert np.all(inside.sum(axis=1) == 1), "a floating-point root outside the proven boxes, or in two"
    # the proven multiplicities are those of floating point, box by box
    np.testing.assert_array_equal(inside.T.astype(int) @ found.multiplicities, proven.box_counts)


@pytest.mark.parametrize("name", _params(ABSCISSAE))
def test_abscissae_agree(name: str) -> None:
    F = ABSCISSAE[name][0]
    found, proven = spectral_abscissa(F), spectral_abscissa(F, rigorous=True)
    assert proven.rigorous
    # the same search in both paths: the same rightmost root, to the last bits of Newton's polish
    np.testing.assert_allclose(proven.value, found.value, rtol=1e-12, atol=1e-12)
    assert found.value <= proven.upper_bound
    if proven.root_box is not None and found.root is not None and not proven.approached_at_infinity:
        x0, x1, y0, y1 = proven.root_box
        assert x0 <= found.root.real <= x1 and y0 <= found.root.imag <= y1


@pytest.mark.parametrize("name", _params(MARGINS))
def test_margins_inside_the_proven_balls(name: str) -> None:
    A, B, delta_max = MARGINS[name][0]
    found = delay_margin(A, B, delta_max=delta_max)
    proven = delay_margin(A, B, delta_max=delta_max, rigorous=True)
    assert proven.rigorous and proven.margin_ball is not None
    lo, hi = proven.margin_ball
    # the floating-point margin is a Newton limit good to a few ulps, and a proven ball can be
    # narrower than that: measured 7 ulps outside a ball 2e-15 wide for s + 3 + 3.5 e^{-delta s}
    # (closed form arccos(-a/b) / sqrt(b^2 - a^2) inside the ball, checked at 40 digits)
    slack = 16 * np.finfo(float).eps * (found.margin if np.isfinite(found.margin) else 0.0)
    assert lo - slack <= found.margin <= hi + slack, (found.margin, proven.margin_ball)
    assert lo <= proven.margin <= hi
    assert found.nominally_stable == proven.nominally_stable
    if name == "first-order a=3.0 b=3.5":
        exact = 1.442494048180189347866  # mpmath, 40 digits
        assert lo <= exact <= hi
    assert [c.direction for c in found.crossings] == [c.direction for c in proven.crossings]


@pytest.mark.parametrize("name", _params(CROSSINGS))
def test_crossing_frequencies_inside_the_proven_intervals(name: str) -> None:
    A, B = CROSSINGS[name][0]
    found, proven = crossing_frequencies(A, B), proven_crossings(A, B)
    intervals = list(proven.omegas) + list(proven.unresolved)
    assert found.omegas.size == len(intervals)
    for w, slope in zip(found.omegas, found.slopes):
        # each floating-point zero in exactly one proven interval, up to its own rounding (relative 1e-12)
        tol = 1e-12 * max(1.0, abs(w))
        hits = [i for i, (lo, hi) in enumerate(intervals) if lo - tol <= w <= hi + tol]
        assert len(hits) == 1, (w, intervals)
        if hits[0] < len(proven.omegas) and proven.multiplicities[hits[0]] == 1:
            assert slope == proven.slopes[hits[0]]
