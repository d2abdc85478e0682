"""Printed enclosures and printed ends hold what is proven; no digit is printed beyond an end's accuracy.

The oracle is exact rational arithmetic (:class:`fractions.Fraction`) on the printed decimal
and on the exact binary value of the float: it shares no code with the decimal rounding
that prints them.
"""

from __future__ import annotations

import re
from fractions import Fraction

import numpy as np
import pytest

from nrobust import QuasiPolynomial
from nrobust.errors import ParameterError
from nrobust.hyperbolic.analyses.kregion import KRegion
from nrobust.reports.certificate import _check_delta_max
from nrobust.reports.report import _box_text, _k_region_text

LOG_MAX = 709.782712893384  # ln(1.7976931348623157e308), to 15 digits


@pytest.mark.parametrize(
    "box",
    [
        (0.123456789, 0.123457999, -18.85154093, -18.84757091),  # to the nearest, Re would print [0.123457, ...]
        (-0.14582605, -0.14185603, 3.0000004, 3.0000006),
        (-2.5e-7, -1.00000049e-7, 1e15 + 2.0, 1e15 + 6.0),
    ],
)
def test_a_printed_root_box_contains_the_proven_box(box: tuple[float, float, float, float]) -> None:
    """The printed box of a root contains the proven box: its ends rounded outwards, not to the nearest."""
    text = _box_text(box)
    found = re.fullmatch(r"Re \[([^,]+), ([^\]]+)\] x Im \[([^,]+), ([^\]]+)\]", text)
    assert found, text
    re_lo, re_hi, im_lo, im_hi = (Fraction(v) for v in found.groups())
    assert re_lo <= Fraction(box[0]) and Fraction(box[1]) <= re_hi, text
    assert im_lo <= Fraction(box[2]) and Fraction(box[3]) <= im_hi, text


def test_a_side_of_zero_width_is_printed_in_full() -> None:
    """A degenerate side is its number, every digit of it (it round-trips to the same float)."""
    text = _box_text((0.1 + 0.2, 0.1 + 0.2, -1.0, 1.0))
    assert text == "Re 0.30000000000000004 x Im [-1, 1]"


def test_k_region_ends_without_an_accuracy_are_not_printed_to_ten_digits() -> None:
    """Interval ends with no known accuracy (no GainEnd) print 6 digits, marked, not 10 unmarked."""
    lo, hi = 0.0123456789012, 0.3456789012345
    grid = np.linspace(0.0, 0.4, 5)
    kreg = KRegion(((lo, hi),), 0.1, 0.15, grid, np.ones(5), np.ones(5, dtype=bool), 1e-6)
    text = _k_region_text(kreg)
    shown = re.match(r"\((\S+) \(accuracy not estimated\), (\S+) \(accuracy not estimated\)\)", text)
    assert shown, text
    # 6 significant digits: units of 1e-7 for 0.0123..., of 1e-6 for 0.345...
    for printed, value, unit in zip(shown.groups(), (lo, hi), (Fraction(1, 10**7), Fraction(1, 10**6))):
        assert len(printed.replace("0.", "", 1).lstrip("0")) == 6, text
        assert abs(Fraction(printed) - Fraction(value)) <= unit / 2, text


def test_the_largest_admissible_delay_is_printed_rounded_down() -> None:
    """``delta_max in (0, L]``: the printed L is admissible (at most the limit ln(max double) / 1)."""
    A = QuasiPolynomial([[1.0, 1.0]], [0.0])
    B = QuasiPolynomial([[1.0]], [0.0])
    with pytest.raises(ParameterError) as info:
        _check_delta_max(709.7828, (A, B), (-1.0, 1.0, -1.0, 1.0), True)
    printed = re.search(r"in \(0, ([^\]]+)\]", str(info.value))
    assert printed, str(info.value)
    limit = Fraction(LOG_MAX)
    assert Fraction(printed.group(1)) <= limit  # to the nearest: 709.783, not admissible
    assert limit - Fraction(printed.group(1)) < Fraction(1, 1000)
