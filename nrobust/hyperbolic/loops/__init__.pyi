# The public names of nrobust.hyperbolic.loops, loaded on first use (nrobust/hyperbolic/loops/__init__.py).
from .collocated import (
    CollocatedObserver as CollocatedObserver,
    collocated_observer as collocated_observer,
    command_response as command_response,
    dual_plant as dual_plant,
    observer_gains as observer_gains,
)
from .controllers import (
    Classification as Classification,
    CollocatedOutputFeedback as CollocatedOutputFeedback,
    Controller as Controller,
    FeedbackLaw as FeedbackLaw,
    FilteredController as FilteredController,
    FiniteTimeController as FiniteTimeController,
    OpenLoop as OpenLoop,
    OutputFeedback as OutputFeedback,
    ReflectionController as ReflectionController,
    StateFeedback as StateFeedback,
    characteristic as characteristic,
    classify as classify,
    collocated_observer_of as collocated_observer_of,
    loop_factors as loop_factors,
    normalize as normalize,
)
from .delay_form import (
    DelayForm as DelayForm,
    delay_form as delay_form,
)
from .feedback import (
    feedback_factor as feedback_factor,
    laplace_loop_factors as laplace_loop_factors,
)
from .laplace import (
    boundary_function as boundary_function,
    general_solution as general_solution,
    magnus_steps as magnus_steps,
)
from .output_feedback import (
    observer_term as observer_term,
    output_feedback_factors as output_feedback_factors,
)
from .transfer import (
    closed_loop_tf as closed_loop_tf,
    open_loop_tf as open_loop_tf,
    output_map as output_map,
)
from .varying_form import (
    DEFAULT_CHARACTERISTIC_GRID as DEFAULT_CHARACTERISTIC_GRID,
    VaryingDelayForm as VaryingDelayForm,
    varying_delay_form as varying_delay_form,
)
