"""From a plant and a controller to the loop ``F(s; delta) = A(s) + B(s) e^{-delta s}``:
the controllers (``controllers``), any state feedback (``feedback``), output feedback from the
unactuated boundary (``output_feedback``) and from the actuated one (``collocated``), the delay form of
eq. (39) (``delay_form``; ``varying_form`` for varying speeds), the kernel-free Laplace
route (``laplace``) and the loops' transfer functions (``transfer``).
"""

from .collocated import CollocatedObserver, collocated_observer, command_response, dual_plant, observer_gains
from .controllers import (
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
    collocated_observer_of,
    loop_factors,
    normalize,
)
from .delay_form import DelayForm, delay_form
from .feedback import feedback_factor, laplace_loop_factors
from .laplace import boundary_function, general_solution, magnus_steps
from .output_feedback import observer_term, output_feedback_factors
from .transfer import closed_loop_tf, open_loop_tf, output_map
from .varying_form import DEFAULT_CHARACTERISTIC_GRID, VaryingDelayForm, varying_delay_form

__all__ = [
    "Classification",
    "CollocatedObserver",
    "CollocatedOutputFeedback",
    "Controller",
    "DEFAULT_CHARACTERISTIC_GRID",
    "DelayForm",
    "FeedbackLaw",
    "FilteredController",
    "FiniteTimeController",
    "OpenLoop",
    "OutputFeedback",
    "ReflectionController",
    "StateFeedback",
    "VaryingDelayForm",
    "boundary_function",
    "characteristic",
    "classify",
    "closed_loop_tf",
    "collocated_observer",
    "collocated_observer_of",
    "command_response",
    "delay_form",
    "dual_plant",
    "feedback_factor",
    "general_solution",
    "laplace_loop_factors",
    "loop_factors",
    "magnus_steps",
    "normalize",
    "observer_gains",
    "observer_term",
    "open_loop_tf",
    "output_feedback_factors",
    "output_map",
    "varying_delay_form",
]
