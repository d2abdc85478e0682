# The public names of nrobust.lti, loaded on first use (nrobust/lti/__init__.py).
from .allmargin import (
    AllMargins as AllMargins,
    allmargin as allmargin,
    loop_delay_margin as loop_delay_margin,
    loop_factors_of as loop_factors_of,
)
from .delay_lti import (
    DelayLTI as DelayLTI,
    as_delay_lti as as_delay_lti,
    delay as delay,
    tf as tf,
)
from .pade import (
    pade as pade,
    pade_band_bound as pade_band_bound,
    pade_error_bound as pade_error_bound,
    split_integrators as split_integrators,
    substitution_bound as substitution_bound,
)
from .statespace import (
    StateSpaceTDS as StateSpaceTDS,
)
from .timeresp import (
    LFTSystem as LFTSystem,
    default_horizon as default_horizon,
    forced_response as forced_response,
    impulse_response as impulse_response,
    initial_response as initial_response,
    step_response as step_response,
)
from .transfer import (
    PadeModel as PadeModel,
    PoleSet as PoleSet,
    QuasiTransferFunction as QuasiTransferFunction,
    pade_approximation as pade_approximation,
    to_frd as to_frd,
)
