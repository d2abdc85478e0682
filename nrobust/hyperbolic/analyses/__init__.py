"""Analyses of a plant with a controller: delay margins (``margin``), admissible gains
(``kregion``, on the core's gain engine :mod:`nrobust.margins.gain`), charts over two
parameters (``charts``), the decay-rate/margin trade-off (``tradeoff``), the Rouché delay
bound (``rouche``), the design of ``U_BS2(K)`` (``design``) and of the filtered law over its
gain, zero and pole (``filter_design``), of a general state feedback over its gains
(``state_design``), of the collocated observer's own reflection (``observer_design``), and
the robustness to a mismatch of the transport speeds (``mismatch``).
"""

from ...margins.gain import END_KINDS, GainEnd
from .charts import MAX_CHART_POINTS, ABRegion, StabilityChart, ab_region, stability_chart
from .design import DESIGN_OBJECTIVES, ReflectionDesign, design_reflection
from .filter_design import (
    FILTER_PARAMETERS,
    ExactFilteredDesign,
    FilteredDesign,
    FilteredLoop,
    default_filter_bounds,
    design_filtered,
    design_filtered_exact,
    filtered_front,
    filtered_loop,
)
from .kregion import DEFAULT_N_GAINS, MAX_GAINS, KRegion, k_region
from .margin import delay_margin, margin_and_decay
from .mismatch import (
    MAX_MISMATCH_POINTS,
    MismatchEnd,
    MismatchRegion,
    SpeedTolerance,
    mismatch_gain_loop,
    mismatch_loop,
    mismatch_region,
    speed_tolerance,
)
from .mismatch_proof import MAX_SQUARE_BOXES, SquareProof, prove_transport_square
from .observer_design import (
    JOINT_GAMMA_MAX,
    OBSERVER_OBJECTIVES,
    CollocatedDesign,
    CollocatedJointLoop,
    ObserverDesign,
    collocated_joint_loop,
    collocated_observer_loop,
    design_collocated_observer,
    design_collocated_output_feedback,
    joint_bounds,
    observer_reflection_bounds,
)
from .rouche import rouche_delay_bound
from .state_design import (
    BasisGain,
    StateFeedbackDesign,
    StateFeedbackLoop,
    default_state_k_bounds,
    design_state_feedback,
    state_feedback_loop,
)
from .tradeoffs import Tradeoff, tradeoff

__all__ = [
    "ABRegion",
    "BasisGain",
    "CollocatedDesign",
    "CollocatedJointLoop",
    "DEFAULT_N_GAINS",
    "DESIGN_OBJECTIVES",
    "END_KINDS",
    "ExactFilteredDesign",
    "FILTER_PARAMETERS",
    "FilteredDesign",
    "FilteredLoop",
    "GainEnd",
    "JOINT_GAMMA_MAX",
    "KRegion",
    "MAX_CHART_POINTS",
    "MAX_GAINS",
    "MAX_MISMATCH_POINTS",
    "MAX_SQUARE_BOXES",
    "MismatchEnd",
    "MismatchRegion",
    "OBSERVER_OBJECTIVES",
    "ObserverDesign",
    "ReflectionDesign",
    "SpeedTolerance",
    "SquareProof",
    "StabilityChart",
    "StateFeedbackDesign",
    "StateFeedbackLoop",
    "Tradeoff",
    "ab_region",
    "collocated_joint_loop",
    "collocated_observer_loop",
    "delay_margin",
    "design_collocated_observer",
    "design_collocated_output_feedback",
    "design_filtered",
    "design_filtered_exact",
    "design_reflection",
    "design_state_feedback",
    "filtered_front",
    "filtered_loop",
    "default_filter_bounds",
    "default_state_k_bounds",
    "joint_bounds",
    "k_region",
    "margin_and_decay",
    "mismatch_gain_loop",
    "mismatch_loop",
    "mismatch_region",
    "observer_reflection_bounds",
    "prove_transport_square",
    "rouche_delay_bound",
    "speed_tolerance",
    "stability_chart",
    "state_feedback_loop",
    "tradeoff",
]
