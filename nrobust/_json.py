"""Strict JSON for results: non-finite floats as strings, numpy values as Python values."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np


def json_float(x: float | None) -> float | str | None:
    """``x`` as a JSON value: ``None`` stays, ``nan``/``inf``/``-inf`` become strings."""
    if x is None:
        return None
    x = float(x)
    if math.isfinite(x):
        return x
    return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")


def json_safe(value: Any) -> Any:
    """``value`` as nested JSON values (for ``json.dumps(..., allow_nan=False)``).

    Mappings and sequences are converted item by item; numpy scalars and arrays become
    Python values and lists, complex numbers ``[real, imag]``, objects with ``to_dict()``
    their dictionary, and anything else its ``repr``.
    """
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)) and not isinstance(value, np.bool_):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return json_float(value)
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, (complex, np.complexfloating)):
        return [json_float(value.real), json_float(value.imag)]
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [json_safe(v) for v in value]
    if hasattr(value, "to_dict"):
        return json_safe(value.to_dict())
    return repr(value)
