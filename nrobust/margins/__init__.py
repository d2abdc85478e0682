"""Delay margins of loops ``F(s; delta) = A(s) + B(s) e^{-delta s}``: the loop on the
imaginary axis and its frequency bound (``axis``), the certified search of the zeros of
``|A(i w)|^2 - |B(i w)|^2`` (``search``), the crossings with their delays and directions
(``crossing``), the count of unstable zeros (``count``), the margin and its stability windows
(``margin``), the same proven in ball arithmetic (``proven``), the crossings of matrix
loops ``det(M_0 + e^{-delta s} M_1)`` (``matrix``), and for an affine gain family
``A + (B_0 + K R) e^{-delta s}`` the exact ends of the admissible gain intervals (``gain``)
and the verdict at one gain (``admissible``).
"""

from .admissible import GainVerdict, check_gain_end, gain_verdict, tolerates
from .axis import AxisGap, AxisJet, frequency_bound
from .count import UnstableCount, unstable_count
from .crossing import Crossing, CrossingSearch, crossing_frequencies
from .gain import END_KINDS, AffineGainLoop, GainEnd, locate_gain_ends
from .margin import DelayMargin, delay_margin
from .matrix import GaugeRemainder, circle_crossings, compound_generator, compound_minors
from .proven import ProvenCrossings, proven_crossings, proven_gap, proven_zero_root

__all__ = [
    "END_KINDS",
    "AffineGainLoop",
    "AxisGap",
    "AxisJet",
    "Crossing",
    "CrossingSearch",
    "DelayMargin",
    "GainEnd",
    "GainVerdict",
    "GaugeRemainder",
    "ProvenCrossings",
    "UnstableCount",
    "check_gain_end",
    "circle_crossings",
    "compound_generator",
    "compound_minors",
    "crossing_frequencies",
    "delay_margin",
    "frequency_bound",
    "gain_verdict",
    "locate_gain_ends",
    "proven_crossings",
    "proven_gap",
    "proven_zero_root",
    "tolerates",
    "unstable_count",
]
