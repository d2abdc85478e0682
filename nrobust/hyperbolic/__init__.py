"""The paper's plants on top of the core: boundary-controlled 2x2 hyperbolic systems.

``system``: the plants :class:`Hyperbolic2x2` and :class:`TransportSystem`;
``kernels``: the backstepping kernels ``K`` and inverse kernels ``L``;
``laplace``: the kernel-free boundary function of the Laplace-transformed plant;
``delay_form``: the neutral distributed-delay equation (39) and its
characteristic quasi-polynomial; ``controllers``: the paper's control laws and the loop
factors ``F = A + B e^{-delta s}``; ``loops``: open- and closed-loop transfer functions;
``nplusm_kernels``: the backstepping kernels and full-state controller of ``n + m``
systems (Hu et al. 2016); ``general``: general plants (varying speeds, diagonal terms, any length) and their normal
form; ``feedback``: any linear boundary state feedback by kernels and by the Laplace route;
``frontends``: open channels (Saint-Venant), ARZ traffic and characteristic forms;
``varying``: the delay form of a general plant with any speeds; ``varying_kernels``: its
backstepping kernels and U_BS with varying speeds; ``simulate_general``: the
general plant simulated along its characteristics;
``robustness``: the Rouché delay bound; ``studies``: delay margins of a plant with a
controller and the gain studies; ``simulate``: the PDE itself with a delayed control.
"""

from .kernels.constant import Kernels, solve_kernels
from .kernels.varying import VaryingKernels, solve_varying_kernels
from .loops.controllers import (
    Classification,
    Controller,
    FeedbackLaw,
    FilteredController,
    FiniteTimeController,
    OpenLoop,
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
from .nplusm.kernels import NPlusMBackstepping, NPlusMKernels, backstepping_delay_margin, solve_nplusm_kernels
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
    "Kernels",
    "NPlusMBackstepping",
    "NPlusMKernels",
    "NormalForm",
    "OpenLoop",
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
