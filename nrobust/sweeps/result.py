"""The outcome of a sweep: one row per point, flattened into typed table columns.

:func:`result_columns` flattens what the swept function returns into scalar columns (it
runs on the workers); :class:`SweepResult` gathers the rows and failures
(:class:`PointFailure`) in input order and writes them as a table, CSV or JSON.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._atomic import atomic_write
from .._json import decode_floats, json_safe
from ..errors import ParameterError

__all__ = ["PointFailure", "SweepResult", "flatten", "result_columns"]

#: Columns every table starts or ends its fixed part with; result keys that collide with
#: these (or with a parameter name) are renamed ``result.<key>``.
_RESERVED = ("index", "status", "error_type", "error")


def flatten(value: Any, prefix: str, out: dict[str, Any]) -> None:
    """Flatten ``value`` into scalar columns of ``out`` named after ``prefix``.

    Mappings and objects with ``to_dict()`` give dotted names (the strings ``"inf"``,
    ``"-inf"`` and ``"nan"`` of a ``to_dict()`` become floats again, so that numeric
    columns stay numeric), complex numbers give ``.real`` and ``.imag`` columns,
    sequences are stored as a JSON string, any other object as its ``repr``.
    """
    if isinstance(value, Mapping):
        for key, item in value.items():
            flatten(item, f"{prefix}.{key}" if prefix else str(key), out)
    elif isinstance(value, np.generic):
        flatten(value.item(), prefix, out)
    elif isinstance(value, (bool, int, float, str)) or value is None:
        out[prefix] = value
    elif isinstance(value, complex):
        out[f"{prefix}.real"] = value.real
        out[f"{prefix}.imag"] = value.imag
    elif callable(getattr(value, "to_dict", None)) and not isinstance(value, type):
        flatten(decode_floats(value.to_dict()), prefix, out)
    elif isinstance(value, (list, tuple, np.ndarray)):
        out[prefix] = json.dumps(json_safe(value), allow_nan=False)
    else:
        out[prefix] = repr(value)


def result_columns(value: Any) -> dict[str, Any]:
    """The flat columns of one return value of the swept function."""
    if callable(getattr(value, "to_dict", None)) and not isinstance(value, (Mapping, type)):
        value = decode_floats(value.to_dict())
    if not isinstance(value, Mapping):
        raise TypeError(
            f"the swept function must return a dict of scalars or an object with to_dict(), got {type(value).__name__}"
        )
    out: dict[str, Any] = {}
    flatten(value, "", out)
    return out


@dataclass(frozen=True)
class PointFailure:
    """A point whose call raised.

    Attributes
    ----------
    index : int
        Position of the point in the input.
    point : dict
        The parameters of the call.
    type : str
        Name of the exception class (``"ParameterError"``).
    message : str
        ``str(exception)``.
    traceback : str
        The formatted traceback, as seen on the worker (not compared by ``==``: its file
        paths depend on the machine that ran the point).
    """

    index: int
    point: dict[str, Any]
    type: str
    message: str
    traceback: str = field(repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of the failure."""
        point: dict[str, Any] = {}
        flatten(self.point, "", point)
        return json_safe(
            {
                "index": self.index,
                "point": point,
                "type": self.type,
                "message": self.message,
                "traceback": self.traceback,
            }
        )


def _column_array(values: list[Any]) -> np.ndarray:
    """A typed column: bool, int64, float64 (NaN where missing), str ('' where missing) or object."""
    present = [v for v in values if v is not None]
    complete = len(present) == len(values)
    if present and all(isinstance(v, bool) for v in present) and complete:
        return np.array(values, dtype=bool)
    if present and all(isinstance(v, int) and not isinstance(v, bool) for v in present) and complete:
        if all(-(2**63) <= v < 2**63 for v in present):
            return np.array(values, dtype=np.int64)
    if present and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in present):
        return np.array([math.nan if v is None else float(v) for v in values], dtype=np.float64)
    if present and all(isinstance(v, str) for v in present):
        width = max(1, max(len(v) for v in present))
        return np.array(["" if v is None else v for v in values], dtype=f"U{width}")
    out = np.empty(len(values), dtype=object)
    out[:] = values
    return out


@dataclass(frozen=True)
class SweepResult:
    """Outcome of :func:`~nrobust.sweeps.engine.sweep`: one row per point, in input order.

    Attributes
    ----------
    points : tuple of dict
        The points, in input order.
    results : tuple of (dict or None)
        Flat result columns per point (nested dicts and ``to_dict()`` objects give dotted
        names), ``None`` where the call raised.
    failures : tuple of PointFailure
        The points whose call raised, in input order.
    executor : str
        What ran the points (``"serial"``, ``"processes(2)"``, ``"dask(2 workers)"``, ...);
        not compared by ``==``.
    elapsed : float
        Wall-clock seconds of the sweep; not compared by ``==``.
    resumed : str
        ``"resumed: kept N of M points from JOURNAL"`` when the sweep took ``N`` finished
        points from the journal of an earlier run (``results=`` of
        :func:`~nrobust.sweeps.engine.sweep`) and ran the others; ``""`` when it ran every
        point. Not compared by ``==``.

    Notes
    -----
    Two sweeps of the same deterministic function over the same points compare equal
    whatever executed them.
    """

    points: tuple[dict[str, Any], ...]
    results: tuple[dict[str, Any] | None, ...]
    failures: tuple[PointFailure, ...]
    executor: str = field(default="serial", compare=False)
    elapsed: float = field(default=0.0, compare=False)
    resumed: str = field(default="", compare=False)

    @property
    def n_ok(self) -> int:
        """Number of points whose call returned."""
        return len(self.points) - len(self.failures)

    @property
    def n_failed(self) -> int:
        """Number of points whose call raised."""
        return len(self.failures)

    @property
    def parameter_columns(self) -> tuple[str, ...]:
        """Flattened parameter names, in order of first appearance."""
        names: dict[str, None] = {}
        for point in self.points:
            names.update(dict.fromkeys(self._flat_point(point)))
        return tuple(names)

    @property
    def result_columns(self) -> tuple[str, ...]:
        """Result column names as they appear in the table (``result.<key>`` on a clash)."""
        return tuple(self.result_names().values())

    @property
    def columns(self) -> tuple[str, ...]:
        """All table columns: index, parameters, status, error_type, error, results."""
        return ("index", *self.parameter_columns, "status", "error_type", "error", *self.result_columns)

    @staticmethod
    def _flat_point(point: Mapping[str, Any]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        flatten(point, "", out)
        return out

    def result_names(self) -> dict[str, str]:
        """Map each result key to its table column name."""
        taken = set(self.parameter_columns) | set(_RESERVED)
        keys: dict[str, None] = {}
        for res in self.results:
            if res is not None:
                keys.update(dict.fromkeys(res))
        return {k: (f"result.{k}" if k in taken else k) for k in keys}

    def records(self) -> list[dict[str, Any]]:
        """The table as a list of dicts, one per point; missing values are ``None``."""
        params = self.parameter_columns
        names = self.result_names()
        failures = {f.index: f for f in self.failures}
        rows = []
        for i, (point, res) in enumerate(zip(self.points, self.results)):
            flat = self._flat_point(point)
            row: dict[str, Any] = {"index": i}
            row.update({p: flat.get(p) for p in params})
            fail = failures.get(i)
            row["status"] = "ok" if fail is None else "error"
            row["error_type"] = "" if fail is None else fail.type
            row["error"] = "" if fail is None else fail.message
            row.update({col: (None if res is None else res.get(key)) for key, col in names.items()})
            rows.append(row)
        return rows

    def table(self) -> np.ndarray:
        """The table as a numpy structured array.

        Returns
        -------
        numpy.ndarray
            One record per point with the fields of :attr:`columns`. ``status`` is
            ``"ok"`` or ``"error"``; ``error_type`` and ``error`` hold the exception class
            name and message of failed points. Numeric result columns hold NaN on failed
            rows and text columns ``""``; select the valid rows with
            ``t[t["status"] == "ok"]``.
        """
        rows = self.records()
        cols = self.columns
        arrays = [_column_array([row[c] for row in rows]) for c in cols]
        dtype = np.dtype([(c, a.dtype) for c, a in zip(cols, arrays)])
        out = np.empty(len(rows), dtype=dtype)
        for c, a in zip(cols, arrays):
            out[c] = a
        return out

    def column(self, name: str) -> np.ndarray:
        """One column of :meth:`table`."""
        if name not in self.columns:
            raise ParameterError("name", f"one of {list(self.columns)}", name)
        return _column_array([row[name] for row in self.records()])

    def to_dict(self) -> dict[str, Any]:
        """Dict of the sweep: columns, rows, failures and counts.

        Strict-JSON-ready like every ``to_dict()``: non-finite floats are the strings
        ``"inf"``, ``"-inf"`` and ``"nan"`` (:meth:`records` and :meth:`table` keep the
        floats).
        """
        return json_safe(
            {
                "columns": self.columns,
                "rows": self.records(),
                "failures": self.failures,
                "n_points": len(self.points),
                "n_ok": self.n_ok,
                "n_failed": self.n_failed,
                "executor": self.executor,
                "elapsed": self.elapsed,
                "resumed": self.resumed,
            }
        )

    def to_csv(self, path: str | os.PathLike[str]) -> Path:
        """Write the table as CSV (header row; missing values empty), atomically. Returns the path."""
        path = Path(path)
        with atomic_write(path) as fh:
            writer = csv.writer(fh)
            writer.writerow(self.columns)
            for row in self.records():
                writer.writerow(["" if row[c] is None else row[c] for c in self.columns])
        return path

    def to_json(self, path: str | os.PathLike[str], extra: Mapping[str, Any] | None = None) -> Path:
        """Write :meth:`to_dict` (plus ``extra`` entries) as strict JSON, atomically. Returns the path."""
        data = self.to_dict()
        if extra:
            data.update(extra)
        path = Path(path)
        with atomic_write(path) as fh:
            fh.write(json.dumps(json_safe(data), indent=1, allow_nan=False) + "\n")
        return path

    def __repr__(self) -> str:
        return (
            f"SweepResult({len(self.points)} points, {self.n_ok} ok, {self.n_failed} failed, "
            f"results={list(self.result_columns)}, executor={self.executor!r}, "
            f"elapsed={self.elapsed:.3g} s)"
        )
