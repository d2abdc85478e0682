"""Analyses of a plant with a controller: delay margins, admissible gains, charts and
trade-offs (``studies``) and the Rouché delay bound (``rouche``).
"""

from .rouche import rouche_delay_bound
from .studies import (
    DEFAULT_N_GAINS,
    END_KINDS,
    ABRegion,
    GainEnd,
    KRegion,
    StabilityChart,
    Tradeoff,
    ab_region,
    delay_margin,
    k_region,
    margin_and_decay,
    stability_chart,
    tradeoff,
)

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
