"""The paper's plants on top of the core: boundary-controlled 2x2 hyperbolic systems.

``system``: the plants :class:`Hyperbolic2x2` and :class:`TransportSystem`;
``kernels``: the backstepping kernels ``K`` and inverse kernels ``L``;
``laplace``: the kernel-free boundary function of the Laplace-transformed plant;
``delay_form``: the neutral distributed-delay equation (delay_eq_alpha) and its
characteristic quasi-polynomial; ``controllers``: the paper's control laws and the loop
factors ``F = A + B e^{-delta s}``; ``loops``: open- and closed-loop transfer functions;
``robustness``: the Rouché delay bound; ``studies``: delay margins of a plant with a
controller and the gain studies; ``simulate``: the PDE itself with a delayed control.
"""

from .controllers import (
    Classification,
    Controller,
    FeedbackLaw,
    FilteredController,
    FiniteTimeController,
    OpenLoop,
    ReflectionController,
    characteristic,
    classify,
    loop_factors,
)
from .delay_form import DelayForm, delay_form
from .kernels import Kernels, solve_kernels
from .laplace import boundary_function
from .system import Hyperbolic2x2, TransportSystem

__all__ = [
    "Classification",
    "Controller",
    "DelayForm",
    "FeedbackLaw",
    "FilteredController",
    "FiniteTimeController",
    "Hyperbolic2x2",
    "Kernels",
    "OpenLoop",
    "ReflectionController",
    "TransportSystem",
    "boundary_function",
    "characteristic",
    "classify",
    "delay_form",
    "loop_factors",
    "solve_kernels",
]
