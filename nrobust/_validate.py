"""Small argument checks shared by the modules; each raises :class:`ParameterError`.

:func:`renamed_keywords` keeps the old name of a renamed keyword argument working as a
deprecated alias (``CHANGELOG.md`` lists the renames).
"""

from __future__ import annotations

import functools
import inspect
import warnings
from collections.abc import Callable
from typing import Any, ParamSpec, TypeVar

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
    return (vals[0], vals[1], vals[2], vals[3])


_P = ParamSpec("_P")
_R = TypeVar("_R")


def renamed_keywords(**renames: str) -> Callable[[Callable[_P, _R]], Callable[_P, _R]]:
    """Decorator keeping the old names of renamed keyword arguments as deprecated aliases.

    ``@renamed_keywords(n="kernel_grid")``: a call with ``n=value`` emits a
    :class:`DeprecationWarning` naming the new keyword and runs as ``kernel_grid=value``;
    a call that gives both (by keyword, or the new one by position) raises
    :class:`ParameterError` naming the old keyword. The signature shown by ``help`` and
    :func:`inspect.signature` is the new one; the renames are kept on the wrapper as
    ``deprecated_keywords`` (``{old: new}``) for callers that check option names against
    the signature (SWEEP.toml options).

    Parameters
    ----------
    **renames : str
        ``old_name=new_name`` for each renamed parameter of the decorated function.
    """

    def decorate(func: Callable[_P, _R]) -> Callable[_P, _R]:
        params = inspect.signature(func).parameters
        for old, new in renames.items():
            if new not in params or old in params:
                raise TypeError(f"renamed_keywords: {func.__qualname__} has no parameter {new!r} or still has {old!r}")
        positional = [name for name, p in params.items() if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]

        @functools.wraps(func)
        def wrapper(*args: _P.args, **kwargs: _P.kwargs) -> _R:
            for old, new in renames.items():
                if old not in kwargs:
                    continue
                value = kwargs.pop(old)
                if new in kwargs or new in positional[: len(args)]:
                    raise ParameterError(
                        old, f"left out when {new} is given (it is the deprecated name of {new})", value
                    )
                warnings.warn(
                    f"{func.__qualname__}: the keyword {old!r} is deprecated, use {new!r}",
                    DeprecationWarning,
                    stacklevel=2,
                )
                kwargs[new] = value
            return func(*args, **kwargs)

        vars(wrapper)["deprecated_keywords"] = dict(renames)
        return wrapper

    return decorate
