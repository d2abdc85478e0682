"""Analyses of a plant with a controller: delay margins (``margin``), admissible gains
(``kregion``, on the core's gain engine :mod:`nrobust.margins.gain`), charts over two
parameters (``charts``), the decay-rate/margin trade-off (``tradeoff``) and the Rouché delay
bound (``rouche``).
"""

from ...margins.gain import END_KINDS, GainEnd
from .charts import ABRegion, StabilityChart, ab_region, stability_chart
from .kregion import DEFAULT_N_GAINS, KRegion, k_region
from .margin import delay_margin, margin_and_decay
from .rouche import rouche_delay_bound
from .tradeoffs import Tradeoff, tradeoff

__all__ = [
    "ABRegion",
    "DEFAULT_N_GAINS",
    "END_KINDS",
    "GainEnd",
    "KRegion",
    "StabilityChart",
    "Tradeoff",
    "ab_region",
    "delay_margin",
    "k_region",
    "margin_and_decay",
    "rouche_delay_bound",
    "stability_chart",
    "tradeoff",
]
