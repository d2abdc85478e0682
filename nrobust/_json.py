"""The one JSON convention of nrobust's results.

Every ``to_dict()`` of a result returns *strict-JSON-ready* data: values that
``json.dumps(..., allow_nan=False)`` accepts as they are, with

* non-finite floats as strings: ``inf`` -> ``"inf"``, ``-inf`` -> ``"-inf"``, ``nan`` -> ``"nan"``
  (an infinite delay margin, a ``-inf`` chain abscissa, a ``nan`` chart cell);
* complex numbers as ``[real, imag]``;
* numpy arrays, tuples and lists as lists (nested for arrays of several dimensions), numpy
  scalars as Python scalars, paths as strings;
* nested results (objects with ``to_dict()``) as their dictionaries.

:func:`json_safe` converts any value this way and :func:`fields_dict` converts the fields of
a dataclass; most ``to_dict()`` methods are ``fields_dict(self)``, and the others (which
leave out, rename or add entries) build their dictionary and pass it through
:func:`json_safe`. Every writer of JSON text (``to_json``, reports, the paper's
``summary.json``) calls ``json.dumps(..., allow_nan=False)``. :func:`decode_floats` undoes
the float encoding, for consumers that want numbers back (the columns of a sweep table).
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Iterable, Mapping
from typing import Any, SupportsFloat

import numpy as np

from .errors import ParameterError

__all__ = ["decode_floats", "fields_dict", "json_float", "json_safe"]

#: The strings that stand for non-finite floats.
_NON_FINITE = {"inf": math.inf, "-inf": -math.inf, "nan": math.nan}


def json_float(x: SupportsFloat | None) -> float | str | None:
    """``x`` as a JSON value: ``None`` stays, ``nan``/``inf``/``-inf`` become strings."""
    if x is None:
        return None
    f = float(x)
    if math.isfinite(f):
        return f
    return "nan" if math.isnan(f) else ("inf" if f > 0 else "-inf")


def json_safe(value: Any) -> Any:
    """``value`` as nested strict-JSON values (the convention of the module docstring).

    Mappings and sequences are converted item by item (keys become strings); numpy
    scalars and arrays become Python values and lists, complex numbers ``[real, imag]``,
    paths strings, objects with ``to_dict()`` their dictionary, and anything else its
    ``repr``. Idempotent: converting converted data changes nothing.
    """
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return json_float(value)
    if isinstance(value, (complex, np.complexfloating)):
        return [json_float(value.real), json_float(value.imag)]
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, np.ndarray) and (
        value.dtype.kind in "biu" or (value.dtype.kind == "f" and bool(np.all(np.isfinite(value))))
    ):
        return value.tolist()  # fast path: already JSON numbers
    if isinstance(value, (list, tuple, np.ndarray)):
        return [json_safe(v) for v in value]
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if callable(getattr(value, "to_dict", None)) and not isinstance(value, type):
        return json_safe(value.to_dict())
    return repr(value)


def fields_dict(obj: Any, exclude: Iterable[str] = ()) -> dict[str, Any]:
    """The fields of the dataclass instance ``obj``, in declaration order, through :func:`json_safe`.

    Parameters
    ----------
    obj : dataclass instance
        The result to describe.
    exclude : iterable of str, optional
        Fields left out (each must be a field of ``obj``). Fields whose name starts with
        ``_`` (private caches) are always left out.

    Raises
    ------
    ParameterError
        If ``obj`` is not a dataclass instance or ``exclude`` names a field it does not have.
    """
    if not dataclasses.is_dataclass(obj) or isinstance(obj, type):
        raise ParameterError("obj", "a dataclass instance", type(obj).__name__)
    names = [f.name for f in dataclasses.fields(obj)]
    skip = set(exclude)
    if not skip <= set(names):
        raise ParameterError("exclude", f"names of fields of {type(obj).__name__} ({names})", sorted(skip))
    return {name: json_safe(getattr(obj, name)) for name in names if name not in skip and not name.startswith("_")}


def decode_floats(value: Any) -> Any:
    """Undo the float encoding of :func:`json_safe`: ``"inf"``, ``"-inf"``, ``"nan"`` become floats.

    Mappings and lists are decoded item by item; every other value is returned as it is.
    """
    if isinstance(value, str):
        return _NON_FINITE.get(value, value)
    if isinstance(value, Mapping):
        return {k: decode_floats(v) for k, v in value.items()}
    if isinstance(value, list):
        return [decode_floats(v) for v in value]
    return value
