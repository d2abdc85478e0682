# The public names of nrobust and where they live. nrobust/__init__.py loads each on first
# use (lazy_loader reads this file), so `import nrobust` loads no numerical module.
from . import (
    balls as balls,
    bounds as bounds,
    config as config,
    difference as difference,
    errors as errors,
    hyperbolic as hyperbolic,
    lti as lti,
    margins as margins,
    matrix_difference as matrix_difference,
    plots as plots,
    qpmatrix as qpmatrix,
    quasipoly as quasipoly,
    reports as reports,
    roots as roots,
    sweeps as sweeps,
)
from ._digits import with_accuracy as with_accuracy
from ._version import __version__ as __version__
from .bounds import (
    RootFreeRegion as RootFreeRegion,
    RoucheDelayBound as RoucheDelayBound,
    l1_modulus as l1_modulus,
    root_free_region as root_free_region,
)
from .difference import (
    DifferenceOperator as DifferenceOperator,
)
from .errors import (
    CertificationError as CertificationError,
    ConvergenceError as ConvergenceError,
    NrobustError as NrobustError,
    ParameterError as ParameterError,
    RegionError as RegionError,
    SweepError as SweepError,
)
from .hyperbolic.analyses import (
    ABRegion as ABRegion,
    CollocatedDesign as CollocatedDesign,
    ExactFilteredDesign as ExactFilteredDesign,
    FilteredDesign as FilteredDesign,
    GainEnd as GainEnd,
    KRegion as KRegion,
    MismatchRegion as MismatchRegion,
    ObserverDesign as ObserverDesign,
    ReflectionDesign as ReflectionDesign,
    StabilityChart as StabilityChart,
    StateFeedbackDesign as StateFeedbackDesign,
    Tradeoff as Tradeoff,
    ab_region as ab_region,
    delay_margin as delay_margin,
    design_collocated_observer as design_collocated_observer,
    design_collocated_output_feedback as design_collocated_output_feedback,
    design_filtered as design_filtered,
    design_filtered_exact as design_filtered_exact,
    design_reflection as design_reflection,
    design_state_feedback as design_state_feedback,
    filtered_front as filtered_front,
    k_region as k_region,
    mismatch_loop as mismatch_loop,
    mismatch_region as mismatch_region,
    rouche_delay_bound as rouche_delay_bound,
    stability_chart as stability_chart,
    tradeoff as tradeoff,
)
from .hyperbolic.kernels import (
    Kernels as Kernels,
    solve_kernels as solve_kernels,
)
from .hyperbolic.loops import (
    Classification as Classification,
    CollocatedOutputFeedback as CollocatedOutputFeedback,
    DelayForm as DelayForm,
    FilteredController as FilteredController,
    FiniteTimeController as FiniteTimeController,
    OpenLoop as OpenLoop,
    OutputFeedback as OutputFeedback,
    ReflectionController as ReflectionController,
    StateFeedback as StateFeedback,
    boundary_function as boundary_function,
    characteristic as characteristic,
    classify as classify,
    closed_loop_tf as closed_loop_tf,
    delay_form as delay_form,
    loop_factors as loop_factors,
    open_loop_tf as open_loop_tf,
    output_map as output_map,
)
from .hyperbolic.plants import (
    FeedbackLaw as FeedbackLaw,
    GeneralHyperbolic2x2 as GeneralHyperbolic2x2,
    Hyperbolic2x2 as Hyperbolic2x2,
    TransportSystem as TransportSystem,
    arz as arz,
    from_riemann as from_riemann,
    saint_venant as saint_venant,
)
from .hyperbolic.simulate import (
    Simulation as Simulation,
    simulate as simulate,
)
from .lti import (
    DelayLTI as DelayLTI,
    QuasiTransferFunction as QuasiTransferFunction,
    allmargin as allmargin,
    pade_approximation as pade_approximation,
    to_frd as to_frd,
)
from .margins import (
    Crossing as Crossing,
    DelayMargin as DelayMargin,
    crossing_frequencies as crossing_frequencies,
)
from .qpmatrix import (
    QuasiPolynomialMatrix as QuasiPolynomialMatrix,
)
from .quasipoly import (
    DistributedDelay as DistributedDelay,
    QuasiPolynomial as QuasiPolynomial,
)
from .reports import (
    Certificate as Certificate,
    certify as certify,
)
from .roots import (
    RootSet as RootSet,
    count_roots as count_roots,
    find_roots as find_roots,
    spectral_abscissa as spectral_abscissa,
)
from .sweeps import (
    SweepMap as SweepMap,
    SweepResult as SweepResult,
    grid as grid,
    robustness as robustness,
    sweep as sweep,
    sweep_map as sweep_map,
)
