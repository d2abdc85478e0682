"""Delay margins of loops ``F(s; delta) = A(s) + B(s) e^{-delta s}``: the certified crossing
search on the imaginary axis (``crossing``), the margin and its stability windows
(``margin``), the same proven in ball arithmetic (``proven``) and the crossings of matrix
loops ``det(M_0 + e^{-delta s} M_1)`` (``matrix``).
"""

from .crossing import AxisGap, AxisJet, Crossing, CrossingSearch, crossing_frequencies, frequency_bound
from .margin import DelayMargin, delay_margin
from .matrix import GaugeRemainder, circle_crossings, compound_generator, compound_minors
from .proven import ProvenCrossings, proven_crossings, proven_gap, proven_zero_root

__all__ = [
    "AxisGap",
    "AxisJet",
    "Crossing",
    "CrossingSearch",
    "DelayMargin",
    "GaugeRemainder",
    "ProvenCrossings",
    "circle_crossings",
    "compound_generator",
    "compound_minors",
    "crossing_frequencies",
    "delay_margin",
    "frequency_bound",
    "proven_crossings",
    "proven_gap",
    "proven_zero_root",
]
