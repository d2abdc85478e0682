# The public names of nrobust.hyperbolic.analyses, loaded on first use (nrobust/hyperbolic/analyses/__init__.py).
from .charts import (
    MAX_CHART_POINTS as MAX_CHART_POINTS,
    ABRegion as ABRegion,
    StabilityChart as StabilityChart,
    ab_region as ab_region,
    stability_chart as stability_chart,
)
from .design import (
    DESIGN_OBJECTIVES as DESIGN_OBJECTIVES,
    ReflectionDesign as ReflectionDesign,
    design_reflection as design_reflection,
)
from .filter_design import (
    FILTER_PARAMETERS as FILTER_PARAMETERS,
    ExactFilteredDesign as ExactFilteredDesign,
    FilteredDesign as FilteredDesign,
    FilteredLoop as FilteredLoop,
    default_filter_bounds as default_filter_bounds,
    design_filtered as design_filtered,
    design_filtered_exact as design_filtered_exact,
    filtered_front as filtered_front,
    filtered_loop as filtered_loop,
)
from .grid_study import (
    MAX_ACCURACY_GRID as MAX_ACCURACY_GRID,
    GridStudy as GridStudy,
    grid_study as grid_study,
    study_scope as study_scope,
)
from .kregion import (
    DEFAULT_N_GAINS as DEFAULT_N_GAINS,
    END_KINDS as END_KINDS,
    MAX_GAINS as MAX_GAINS,
    GainEnd as GainEnd,
    KRegion as KRegion,
    k_region as k_region,
)
from .margin import (
    delay_margin as delay_margin,
    margin_and_decay as margin_and_decay,
)
from .mismatch import (
    MAX_MISMATCH_POINTS as MAX_MISMATCH_POINTS,
    MAX_UNDECIDED_PROBES as MAX_UNDECIDED_PROBES,
    MismatchEnd as MismatchEnd,
    MismatchRegion as MismatchRegion,
    SpeedTolerance as SpeedTolerance,
    mismatch_abscissa as mismatch_abscissa,
    mismatch_gain_loop as mismatch_gain_loop,
    mismatch_loop as mismatch_loop,
    mismatch_region as mismatch_region,
    speed_tolerance as speed_tolerance,
)
from .mismatch_proof import (
    MAX_SQUARE_BOXES as MAX_SQUARE_BOXES,
    SquareProof as SquareProof,
    prove_transport_square as prove_transport_square,
)
from .observer_accuracy import (
    OBSERVER_SAFETY as OBSERVER_SAFETY,
    STUDY_SAFETY as STUDY_SAFETY,
    crossing_delay as crossing_delay,
    observer_model_error as observer_model_error,
    observer_rate_error as observer_rate_error,
)
from .observer_design import (
    JOINT_GAMMA_MAX as JOINT_GAMMA_MAX,
    OBSERVER_OBJECTIVES as OBSERVER_OBJECTIVES,
    CollocatedDesign as CollocatedDesign,
    CollocatedJointLoop as CollocatedJointLoop,
    ObserverDesign as ObserverDesign,
    collocated_joint_loop as collocated_joint_loop,
    collocated_observer_loop as collocated_observer_loop,
    design_collocated_observer as design_collocated_observer,
    design_collocated_output_feedback as design_collocated_output_feedback,
    joint_bounds as joint_bounds,
    observer_reflection_bounds as observer_reflection_bounds,
)
from .rouche import (
    rouche_delay_bound as rouche_delay_bound,
)
from .state_design import (
    BasisGain as BasisGain,
    StateFeedbackDesign as StateFeedbackDesign,
    StateFeedbackLoop as StateFeedbackLoop,
    default_state_k_bounds as default_state_k_bounds,
    design_state_feedback as design_state_feedback,
    state_feedback_loop as state_feedback_loop,
)
from .tradeoffs import (
    Tradeoff as Tradeoff,
    tradeoff as tradeoff,
)
