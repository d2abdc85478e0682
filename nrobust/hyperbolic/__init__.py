"""Boundary-controlled 2x2 hyperbolic systems and their delay form.

``system``: the plants :class:`Hyperbolic2x2` and :class:`TransportSystem`;
``kernels``: the backstepping kernels ``K`` and inverse kernels ``L``;
``laplace``: the kernel-free boundary function of the Laplace-transformed plant;
``delay_form``: the neutral distributed-delay equation (delay_eq_alpha) and its
characteristic quasi-polynomial.
"""

from .delay_form import DelayForm, delay_form
from .kernels import Kernels, solve_kernels
from .laplace import boundary_function
from .system import Hyperbolic2x2, TransportSystem

__all__ = [
    "Hyperbolic2x2",
    "TransportSystem",
    "Kernels",
    "solve_kernels",
    "boundary_function",
    "DelayForm",
    "delay_form",
]
