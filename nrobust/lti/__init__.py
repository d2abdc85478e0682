"""Linear time-invariant systems with delays: transfer functions with point and
distributed delays (``transfer``) and state-space time-delay systems (``statespace``).
"""

from .statespace import StateSpaceTDS
from .transfer import QuasiTransferFunction, pade_approximation, to_frd

__all__ = ["QuasiTransferFunction", "StateSpaceTDS", "pade_approximation", "to_frd"]
