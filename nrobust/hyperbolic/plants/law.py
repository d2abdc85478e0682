"""A boundary feedback law of a 2x2 plant, in the plant's own coordinates.

``U(t) = k u(t, L) + int_0^L g_u(x) u(t, x) + g_v(x) v(t, x) dx``: what a controller applies
to the state (the simulators take it), with the one check of a gain given as a number or
a callable.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._validate import finite_real
from ...errors import ParameterError
from .general import Profile

__all__ = ["FeedbackLaw", "feedback_gain"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class FeedbackLaw:
    """A boundary feedback as a functional of the state, for the simulator.

    ``U(t) = boundary_gain * u(t, 1) + int_0^1 gain_u(xi) u(t, xi) + gain_v(xi) v(t, xi) dxi``
    (on ``[0, L]`` in the physical coordinates of a general plant), passed through the proper
    filter ``(1 + a s)/(1 + b s)`` when ``filter = (a, b)``. Also importable from
    :mod:`nrobust.hyperbolic.loops.controllers`, whose controllers return it.
    """

    boundary_gain: float
    gain_u: Callable[[Array], Array]
    gain_v: Callable[[Array], Array]
    filter: tuple[float, float] | None = None


def feedback_gain(name: str, value: Any, length: float = 1.0) -> Profile:
    """A feedback gain: a number or a callable on arrays of ``x``, finite on a probe grid of ``[0, L]``."""
    if not callable(value):
        return Profile(name, finite_real(name, value))
    prof = Profile(name, value)
    if not np.all(np.isfinite(prof(np.linspace(0.0, length, 17)))):
        raise ParameterError(name, "finite on the domain (checked on a 17-point grid)", value)
    return prof
