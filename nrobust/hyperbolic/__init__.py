"""The PDE layer: boundary-controlled hyperbolic systems on top of the core.

``plants/``: the paper's 2x2 plant (:class:`Hyperbolic2x2`, :class:`TransportSystem`), general
2x2 plants (varying speeds, diagonal terms, any length) and their normal form, physical
front ends (Saint-Venant, ARZ traffic, characteristic forms) and the state feedback a
controller applies (:class:`FeedbackLaw`); ``kernels/``: the backstepping kernels ``K`` and
inverse kernels ``L`` (constant and varying speeds); ``loops/``: from a plant and a
controller to the loop ``F = A + B e^{-delta s}`` (the controllers, any state feedback, the
delay form of eq. (39), the kernel-free Laplace route, the transfer functions);
``analyses/``: delay margins of a plant with a controller, admissible gains, charts,
trade-offs and the Rouché bound; ``nplusm/``: ``n + m`` systems (Hu et al. 2016);
``simulate/``: the PDE itself with a delayed boundary control, one :func:`~nrobust.hyperbolic.simulate.simulate` over a
registry of schemes.
"""

from .kernels.constant import Kernels, solve_kernels
from .kernels.varying import VaryingKernels, solve_varying_kernels
from .loops.controllers import (
    Classification,
    CollocatedOutputFeedback,
    Controller,
    FeedbackLaw,
    FilteredController,
    FiniteTimeController,
    OpenLoop,
    OutputFeedback,
    ReflectionController,
    StateFeedback,
    characteristic,
    classify,
    loop_factors,
    normalize,
)
from .loops.delay_form import DelayForm, delay_form
from .loops.feedback import feedback_factor, laplace_loop_factors
from .loops.laplace import boundary_function, general_solution
from .loops.varying_form import VaryingDelayForm, varying_delay_form
from .nplusm.cascade_margin import backstepping_delay_margin
from .nplusm.design import NPlusMGainDesign, design_nplusm_gains
from .nplusm.kernels import NPlusMBackstepping, NPlusMKernels, solve_nplusm_kernels
from .plants.frontends import ARZ, SaintVenant, arz, from_riemann, saint_venant
from .plants.general import GeneralHyperbolic2x2, NormalForm
from .plants.hyperbolic2x2 import Hyperbolic2x2, TransportSystem
from .simulate.general import GeneralSimulation, simulate_general

__all__ = [
    "Classification",
    "Controller",
    "DelayForm",
    "FeedbackLaw",
    "ARZ",
    "FilteredController",
    "FiniteTimeController",
    "GeneralHyperbolic2x2",
    "GeneralSimulation",
    "Hyperbolic2x2",
    "CollocatedOutputFeedback",
    "Kernels",
    "NPlusMBackstepping",
    "NPlusMGainDesign",
    "NPlusMKernels",
    "NormalForm",
    "OpenLoop",
    "OutputFeedback",
    "ReflectionController",
    "SaintVenant",
    "StateFeedback",
    "TransportSystem",
    "VaryingDelayForm",
    "VaryingKernels",
    "arz",
    "backstepping_delay_margin",
    "boundary_function",
    "characteristic",
    "classify",
    "delay_form",
    "design_nplusm_gains",
    "feedback_factor",
    "from_riemann",
    "general_solution",
    "laplace_loop_factors",
    "loop_factors",
    "normalize",
    "saint_venant",
    "simulate_general",
    "solve_kernels",
    "solve_nplusm_kernels",
    "solve_varying_kernels",
    "varying_delay_form",
]
