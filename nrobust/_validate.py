"""Small argument checks shared by the modules; each raises :class:`ParameterError`.

:func:`renamed_keywords` keeps the old name of a renamed keyword argument working as a
deprecated alias (``CHANGELOG.md`` lists the renames).
"""

from __future__ import annotations

import functools
import inspect
import numbers
import warnings
from collections.abc import Callable
from typing import Any, ParamSpec, TypeVar

import numpy as np
from numpy.typing import NDArray

from .errors import ParameterError, RegionError


def is_real_number(value: Any) -> bool:
    """True for a real number: a Python or numpy integer or float (or a 0-d numeric array).

    Booleans are not numbers here (``True`` is not a gain), nor are strings (``"1"``),
    complex numbers or sequences: nothing is converted silently.
    """
    if isinstance(value, (bool, np.bool_)):
        return False
    if isinstance(value, np.ndarray):
        return value.ndim == 0 and value.dtype.kind in "iuf"
    return isinstance(value, numbers.Real)


def finite_real(name: str, value: Any) -> float:
    """Return ``value`` as a float, or raise if it is not a finite real number (see :func:`is_real_number`)."""
    if not is_real_number(value):
        raise ParameterError(name, "a finite real number", value)
    out = float(value)
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


def positive_int(name: str, value: Any, minimum: int = 1, maximum: int | None = None) -> int:
    """Return ``value`` as an int >= ``minimum`` (and <= ``maximum`` if given), or raise."""
    what = f"an integer >= {minimum}" if maximum is None else f"an integer in [{minimum}, {maximum}]"
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ParameterError(name, what, value)
    if value < minimum or (maximum is not None and value > maximum):
        raise ParameterError(name, what, value)
    return int(value)


def _numeric_array(name: str, value: Any, kinds: str, what: str, ndim: int | None, min_size: int) -> NDArray:
    """``np.asarray(value)`` if its dtype kind is one of ``kinds`` and it is finite, of
    ``ndim`` dimensions and at least ``min_size`` entries; ParameterError otherwise."""

    def expected() -> str:
        shape = "a sequence" if ndim == 1 else "an array" if ndim is None else f"a {ndim}-D array"
        size = {0: "", 1: "at least one "}.get(min_size, f"at least {min_size} ")
        return f"{shape} of {size}finite {what}"

    if isinstance(value, (str, bytes)) or value is None:
        raise ParameterError(name, expected(), value)
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):  # ragged nesting
        raise ParameterError(name, expected(), value) from None
    if arr.dtype.kind not in kinds or (ndim is not None and arr.ndim != ndim) or arr.size < min_size:
        raise ParameterError(name, expected(), value)
    if not np.isfinite(arr).all():
        raise ParameterError(name, f"{expected()} (no nan or inf)", value)
    return arr


def real_array(name: str, value: Any, *, ndim: int | None = 1, min_size: int = 1) -> NDArray[np.float64]:
    """``value`` as a float array of finite real numbers, or raise :class:`ParameterError`.

    Integers and floats only: booleans, strings, complex numbers, ``None`` entries and
    ragged nesting are refused, never converted.
    """
    return _numeric_array(name, value, "iuf", "real numbers", ndim, min_size).astype(float)


def number_array(name: str, value: Any, *, ndim: int | None = 1, min_size: int = 1) -> NDArray:
    """``value`` as an array of finite numbers, float if they are real, complex otherwise.

    As :func:`real_array`, with complex entries allowed.
    """
    arr = _numeric_array(name, value, "iufc", "numbers", ndim, min_size)
    return arr.astype(complex if arr.dtype.kind == "c" else float)


def callables(name: str, value: Any, what: str, item: str) -> tuple[Any, ...]:
    """``value`` as a tuple of callables, or raise :class:`ParameterError`.

    ``what`` describes the sequence and ``item`` one entry (an entry that is not callable is
    named ``name[j]``). One callable, a string or a non-iterable is refused, not wrapped.
    """
    if callable(value) or isinstance(value, (str, bytes)):
        raise ParameterError(name, what, value)
    try:
        items = tuple(value)
    except TypeError:
        raise ParameterError(name, what, value) from None
    for j, entry in enumerate(items):
        if not callable(entry):
            raise ParameterError(f"{name}[{j}]", item, entry)
    return items


def region(value: Any, name: str = "region") -> tuple[float, float, float, float]:
    """Validate a rectangle ``(re_min, re_max, im_min, im_max)`` with positive area."""
    try:
        entries = tuple(value)
    except TypeError:
        raise RegionError(name, "a tuple (re_min, re_max, im_min, im_max) of finite reals", value) from None
    if not all(is_real_number(v) for v in entries):  # no strings, booleans or complex numbers
        raise RegionError(name, "a tuple (re_min, re_max, im_min, im_max) of finite reals", value)
    vals = tuple(float(v) for v in entries)
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


_Array = TypeVar("_Array", bound="np.ndarray[Any, Any]")


def read_only(arr: _Array) -> _Array:
    """``arr`` marked read-only and returned: an array an immutable value class keeps.

    The classes of loop data (quasi-polynomials, distributed terms, difference operators)
    keep copies of what they are given and mark them so: an in-place write then raises
    numpy's ``ValueError`` instead of leaving the results kept for the object (keyed by its
    identity, or built once) describing other numbers. ``arr`` must be the class's own
    array (a copy of the caller's), not a view of one the caller may still write.
    """
    arr.setflags(write=False)
    return arr


_SCALARS = (float, int, complex, str, type(None))


def read_only_state(obj: object, state: dict[str, Any]) -> None:
    """``obj.__setstate__(state)`` of an immutable value class: ``state`` set, its arrays marked read-only.

    numpy's pickles do not keep the flag, so an unpickled or deep-copied object would hold writable
    arrays (its caches included); every array reached through tuples, lists, dicts and the attributes of
    nrobust's own objects is marked again (:func:`read_only`), except through the objects that have a
    ``__setstate__`` of their own (they mark theirs when they are built).
    """
    seen: set[int] = set()
    todo: list[Any] = [state]
    while todo:
        item = todo.pop()
        if id(item) in seen:
            continue
        seen.add(id(item))
        if isinstance(item, np.ndarray):
            item.setflags(write=False)  # read_only, inline: a loop's state holds a hundred arrays
            continue
        if isinstance(item, (tuple, list)):
            children: Any = item
        elif isinstance(item, dict):
            children = item.values()
        elif type(item).__module__.startswith("nrobust") and not hasattr(item, "__setstate__"):
            children = vars(item).values() if hasattr(item, "__dict__") else ()
        else:
            continue
        # numbers are most of the entries (the moments kept per real part): not walked one by one
        todo.extend(x for x in children if not isinstance(x, _SCALARS))
    obj.__dict__.update(state)
