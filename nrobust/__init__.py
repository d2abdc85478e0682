"""nrobust: delay-robustness analysis of boundary-controlled hyperbolic PDEs.

The reference is Auriol, Aarsnes, Martin and Di Meglio, "Delay-robust control design
for two heterodirectional linear coupled hyperbolic PDEs": a 2x2 hyperbolic system is
mapped to a neutral equation with distributed delay, whose characteristic
quasi-polynomial decides stability with and without a delay in the loop.

The data flow and the contract of each module are in ``docs/architecture.md``.
"""

from . import plots
from ._version import __version__ as __version__
from .bounds import RootFreeRegion, RoucheDelayBound, l1_modulus, root_free_region
from .certificate import Certificate, certify
from .crossings import Crossing, crossing_frequencies
from .difference import DifferenceOperator
from .errors import CertificationError, ConvergenceError, NrobustError, ParameterError, RegionError, SweepError
from .hyperbolic import (
    DelayForm,
    GeneralHyperbolic2x2,
    Hyperbolic2x2,
    Kernels,
    TransportSystem,
    boundary_function,
    delay_form,
    solve_kernels,
)
from .hyperbolic.controllers import (
    Classification,
    FeedbackLaw,
    FilteredController,
    FiniteTimeController,
    OpenLoop,
    ReflectionController,
    StateFeedback,
    characteristic,
    classify,
    loop_factors,
)
from .hyperbolic.frontends import arz, from_riemann, saint_venant
from .hyperbolic.loops import closed_loop_tf, open_loop_tf, output_map
from .hyperbolic.robustness import rouche_delay_bound
from .hyperbolic.simulate import Simulation, simulate
from .hyperbolic.studies import (
    ABRegion,
    GainEnd,
    KRegion,
    StabilityChart,
    Tradeoff,
    ab_region,
    delay_margin,
    k_region,
    stability_chart,
    tradeoff,
)
from .margins import DelayMargin
from .qpmatrix import QuasiPolynomialMatrix
from .quasipoly import DistributedDelay, QuasiPolynomial
from .roots import RootSet, count_roots, find_roots, spectral_abscissa

# through the nrobust.sweep namespace module, so that the attribute nrobust.sweep is the function
from .sweep import SweepMap, SweepResult, grid, robustness, sweep, sweep_map
from .transfer import QuasiTransferFunction, pade_approximation, to_frd

__all__ = [
    # quasi-polynomials, difference operators, roots
    "QuasiPolynomial",
    "DistributedDelay",
    "QuasiPolynomialMatrix",
    "DifferenceOperator",
    "count_roots",
    "find_roots",
    "spectral_abscissa",
    "RootSet",
    # hyperbolic systems, kernels, delay form, controllers, simulation
    "Hyperbolic2x2",
    "TransportSystem",
    "GeneralHyperbolic2x2",
    "saint_venant",
    "arz",
    "from_riemann",
    "solve_kernels",
    "Kernels",
    "boundary_function",
    "delay_form",
    "DelayForm",
    "OpenLoop",
    "FiniteTimeController",
    "ReflectionController",
    "FilteredController",
    "StateFeedback",
    "FeedbackLaw",
    "characteristic",
    "loop_factors",
    "classify",
    "Classification",
    "simulate",
    "Simulation",
    # margins, certificates, charts
    "delay_margin",
    "DelayMargin",
    "crossing_frequencies",
    "Crossing",
    "rouche_delay_bound",
    "RoucheDelayBound",
    "root_free_region",
    "RootFreeRegion",
    "l1_modulus",
    "k_region",
    "KRegion",
    "GainEnd",
    "ab_region",
    "ABRegion",
    "stability_chart",
    "StabilityChart",
    "tradeoff",
    "Tradeoff",
    # transfer functions, reports, sweeps, plots
    "QuasiTransferFunction",
    "open_loop_tf",
    "closed_loop_tf",
    "output_map",
    "to_frd",
    "pade_approximation",
    "certify",
    "Certificate",
    "sweep",
    "grid",
    "robustness",
    "SweepResult",
    "SweepMap",
    "sweep_map",
    "plots",
    # errors
    "NrobustError",
    "ParameterError",
    "RegionError",
    "ConvergenceError",
    "CertificationError",
    "SweepError",
]
