"""``n + m`` plants with constant coefficients: the plant and its loop (``system``), the certified
characteristic function (``characteristic``) and its compound form (``compound``), the delay
margins (``margin``; proven in ball arithmetic: ``proven_margin``), the partial cancellations
(``cancellation``), the backstepping kernels
and the full-state controller (``kernels``), the proven bound of the grid kernels' error
(``kernel_error``), the design of the gain matrix ``K`` (``design``) and the box of speed errors it may
be required to tolerate (``speed_box``).

The simulation moved to :mod:`nrobust.hyperbolic.simulate` (``simulate_nplusm``,
``NPlusMSimulation``, the scheme ``"n+m characteristics"`` of ``simulate``); the old names here
are deprecated aliases (:data:`nrobust._moved.MOVED_NAMES`).
"""

from ..._moved import moved_attribute
from .cancellation import CancellationCase, cancellation_study
from .cascade_margin import backstepping_delay_margin, cascade_delay_margin
from .characteristic import BallNPlusM, NPlusMCharacteristic
from .compound import compound_characteristic
from .design import (
    NPlusMGainDesign,
    NPlusMGainProblem,
    NPlusMWindow,
    check_window,
    default_gain_bounds,
    design_nplusm_gains,
    gain_gradient,
    nplusm_speed_tolerance,
    principal_gamma,
)
from .kernel_error import KernelErrorBound, kernel_error_bound
from .kernels import (
    BACKSTEPPING_ROUTES,
    MAX_NPLUSM_KERNEL_GRID,
    NPlusMBackstepping,
    NPlusMKernels,
    solve_nplusm_kernels,
)
from .margin import (
    NPlusMMargin,
    backstepping_exact_margin,
    multi_actuator_delay_margin,
    multi_actuator_margin,
    nplusm_delay_margin,
    pencil_crossings,
)
from .proven_margin import ProvenAxisCrossing, proven_axis_crossings, proven_frequency_bound
from .speed_box import NPlusMSpeedTolerance
from .system import NPlusMSystem

__all__ = [
    "BACKSTEPPING_ROUTES",
    "BallNPlusM",
    "CancellationCase",
    "KernelErrorBound",
    "MAX_NPLUSM_KERNEL_GRID",
    "NPlusMBackstepping",
    "NPlusMCharacteristic",
    "NPlusMGainDesign",
    "NPlusMGainProblem",
    "NPlusMKernels",
    "NPlusMMargin",
    "NPlusMSpeedTolerance",
    "NPlusMSystem",
    "NPlusMWindow",
    "ProvenAxisCrossing",
    "backstepping_delay_margin",
    "backstepping_exact_margin",
    "cancellation_study",
    "cascade_delay_margin",
    "check_window",
    "compound_characteristic",
    "default_gain_bounds",
    "design_nplusm_gains",
    "gain_gradient",
    "kernel_error_bound",
    "multi_actuator_delay_margin",
    "multi_actuator_margin",
    "nplusm_delay_margin",
    "nplusm_speed_tolerance",
    "pencil_crossings",
    "principal_gamma",
    "proven_axis_crossings",
    "proven_frequency_bound",
    "solve_nplusm_kernels",
]

#: ``simulate_nplusm`` and ``NPlusMSimulation`` (now in :mod:`nrobust.hyperbolic.simulate`), deprecated here.
__getattr__ = moved_attribute(__name__)
