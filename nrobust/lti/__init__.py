"""Linear time-invariant systems with delays: transfer functions with point and
distributed delays (``transfer``) and state-space time-delay systems (``statespace``).
"""

from .allmargin import AllMargins, allmargin, loop_delay_margin, loop_factors_of
from .delay_lti import DelayLTI, as_delay_lti, delay, tf
from .pade import pade, pade_band_bound, pade_error_bound, split_integrators, substitution_bound
from .statespace import StateSpaceTDS
from .timeresp import LFTSystem, default_horizon, forced_response, impulse_response, initial_response, step_response
from .transfer import PadeModel, PoleSet, QuasiTransferFunction, pade_approximation, to_frd

__all__ = ["QuasiTransferFunction", "StateSpaceTDS", "pade_approximation", "to_frd"]
__all__ += ["AllMargins", "DelayLTI", "allmargin", "as_delay_lti", "delay", "loop_delay_margin"]
__all__ += ["loop_factors_of", "tf"]
__all__ += ["LFTSystem", "forced_response", "impulse_response", "initial_response", "step_response"]
__all__ += ["PoleSet", "default_horizon"]
__all__ += ["PadeModel", "pade", "pade_band_bound", "pade_error_bound", "split_integrators", "substitution_bound"]
