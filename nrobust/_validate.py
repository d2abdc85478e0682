"""Small argument checks shared by the modules; each raises :class:`ParameterError`."""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import ParameterError, RegionError


def finite_real(name: str, value: Any) -> float:
    """Return ``value`` as a float, or raise if it is not a finite real number."""
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ParameterError(name, "a finite real number", value) from None
    if not np.isfinite(out):
        raise ParameterError(name, "a finite real number", value)
    return out


def positive(name: str, value: Any) -> float:
    """Return ``value`` as a float > 0, or raise."""
    out = finite_real(name, value)
    if out <= 0.0:
        raise ParameterError(name, "> 0", value)
    return out


def nonnegative(name: str, value: Any) -> float:
    """Return ``value`` as a float >= 0, or raise."""
    out = finite_real(name, value)
    if out < 0.0:
        raise ParameterError(name, ">= 0", value)
    return out


def positive_int(name: str, value: Any, minimum: int = 1) -> int:
    """Return ``value`` as an int >= ``minimum``, or raise."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ParameterError(name, f"an integer >= {minimum}", value)
    if value < minimum:
        raise ParameterError(name, f"an integer >= {minimum}", value)
    return int(value)


def region(value: Any, name: str = "region") -> tuple[float, float, float, float]:
    """Validate a rectangle ``(re_min, re_max, im_min, im_max)`` with positive area."""
    try:
        vals = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise RegionError(name, "a tuple (re_min, re_max, im_min, im_max) of finite reals", value) from None
    if len(vals) != 4 or not all(np.isfinite(vals)):
        raise RegionError(name, "a tuple (re_min, re_max, im_min, im_max) of finite reals", value)
    if not (vals[0] < vals[1] and vals[2] < vals[3]):
        raise RegionError(name, "a non-empty rectangle: re_min < re_max and im_min < im_max", value)
    return vals  # type: ignore[return-value]
