# The public names of nrobust.hyperbolic, loaded on first use (nrobust/hyperbolic/__init__.py).
from .kernels.constant import (
    Kernels as Kernels,
    solve_kernels as solve_kernels,
)
from .kernels.varying import (
    VaryingKernels as VaryingKernels,
    solve_varying_kernels as solve_varying_kernels,
)
from .loops.controllers import (
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
    loop_factors as loop_factors,
    normalize as normalize,
)
from .loops.delay_form import (
    DelayForm as DelayForm,
    delay_form as delay_form,
)
from .loops.feedback import (
    feedback_factor as feedback_factor,
    laplace_loop_factors as laplace_loop_factors,
)
from .loops.laplace import (
    boundary_function as boundary_function,
    general_solution as general_solution,
)
from .loops.varying_form import (
    VaryingDelayForm as VaryingDelayForm,
    varying_delay_form as varying_delay_form,
)
from .nplusm.cascade_margin import (
    backstepping_delay_margin as backstepping_delay_margin,
)
from .nplusm.design import (
    NPlusMGainDesign as NPlusMGainDesign,
    design_nplusm_gains as design_nplusm_gains,
)
from .nplusm.kernels import (
    NPlusMBackstepping as NPlusMBackstepping,
    NPlusMKernels as NPlusMKernels,
    solve_nplusm_kernels as solve_nplusm_kernels,
)
from .plants.frontends import (
    ARZ as ARZ,
    SaintVenant as SaintVenant,
    arz as arz,
    from_riemann as from_riemann,
    saint_venant as saint_venant,
)
from .plants.general import (
    GeneralHyperbolic2x2 as GeneralHyperbolic2x2,
    NormalForm as NormalForm,
)
from .plants.hyperbolic2x2 import (
    Hyperbolic2x2 as Hyperbolic2x2,
    TransportSystem as TransportSystem,
)
from .simulate.general import (
    GeneralSimulation as GeneralSimulation,
    simulate_general as simulate_general,
)
