"""nrobust: delay-robustness analysis of boundary-controlled hyperbolic PDEs.

The reference is Auriol, Aarsnes, Martin and Di Meglio, "Delay-robust control design
for two heterodirectional linear coupled hyperbolic PDEs": a 2x2 hyperbolic system is
mapped to a neutral equation with distributed delay, whose characteristic
quasi-polynomial decides stability with and without a delay in the loop.
"""

from importlib.metadata import PackageNotFoundError, version

from .errors import CertificationError, ConvergenceError, NrobustError, ParameterError, RegionError
from .quasipoly import DistributedDelay, QuasiPolynomial
from .difference import DifferenceOperator
from .roots import RootSet, count_roots, find_roots, spectral_abscissa
from .hyperbolic import DelayForm, Hyperbolic2x2, Kernels, TransportSystem, boundary_function, delay_form, solve_kernels
from .hyperbolic.controllers import (Classification, FeedbackLaw, FilteredController, FiniteTimeController, OpenLoop, ReflectionController, characteristic, classify, loop_factors)
from .hyperbolic.simulate import Simulation, simulate
from .sweep import SweepResult, grid, robustness, sweep
from . import plots
from .certificate import Certificate, certify
from .transfer import QuasiTransferFunction, closed_loop_tf, open_loop_tf, output_map, pade_approximation, to_frd
from .margins import ABRegion, Crossing, DelayMargin, KRegion, StabilityChart, Tradeoff, ab_region, crossing_frequencies, delay_margin, k_region, stability_chart, tradeoff
from .rouche import RootFreeRegion, RoucheDelayBound, l1_modulus, root_free_region, rouche_delay_bound

try:
    __version__ = version("nrobust")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0"
