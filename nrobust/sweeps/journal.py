"""The result journal of a sweep: append-only JSON lines, so that no finished point is lost.

Line 1 is a header recording the sweep's definition (what is computed on which points)
and its SHA-256; every further line is the outcome of one finished point, written and
flushed as the point finishes:

``{"index": 7, "status": "ok", "result": {...}}`` or
``{"index": 3, "status": "error", "type": "ValueError", "message": "...", "traceback": "..."}``.

Opening the journal of the same definition again gives back the finished outcomes (a
resumed sweep skips those points); a journal of another definition is refused, naming
both hashes and what changed, unless the caller restarts. A last line cut short by a
kill is dropped. Result values are written exactly: non-finite floats as
``{"float": "inf"}`` (``"-inf"``, ``"nan"``), so that a text column holding ``"inf"``
stays text.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import os
import re
import types
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np

from .._atomic import atomic_write
from .._json import json_safe
from .._version import __version__
from ..errors import ParameterError

__all__ = ["Journal", "describe", "definition_hash"]

_FORMAT = "nrobust-sweep-journal/1"
_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")


def describe(obj: Any) -> Any:
    """A JSON-ready description of a swept function, its arguments or its points.

    Functions and classes are named by module and qualified name, ``functools.partial``
    by its function and arguments, dataclasses by their fields, objects with ``to_dict()``
    by it, ranges by their ends; other objects by ``repr`` with memory addresses removed.
    Two runs of the same sweep describe it identically.
    """
    if obj is None or isinstance(obj, (bool, int, str)):
        return obj
    if isinstance(obj, float):
        return json_safe(obj)
    if isinstance(obj, np.generic):
        return describe(obj.item())
    if isinstance(obj, complex):
        return [describe(obj.real), describe(obj.imag)]
    if isinstance(obj, range):
        return {"range": [obj.start, obj.stop, obj.step]}
    if isinstance(obj, Mapping):
        return {str(k): describe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, np.ndarray)):
        return [describe(v) for v in obj]
    if isinstance(obj, functools.partial):
        return {"partial": describe(obj.func), "args": describe(obj.args), "keywords": describe(obj.keywords)}
    if isinstance(obj, (types.FunctionType, types.BuiltinFunctionType, types.MethodType, type)):
        return f"{getattr(obj, '__module__', '?')}.{getattr(obj, '__qualname__', repr(obj))}"
    if dataclasses.is_dataclass(obj):
        fields = {f.name: describe(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
        return {"type": describe(type(obj)), **fields}
    if callable(getattr(obj, "to_dict", None)):
        return {"type": describe(type(obj)), **describe(obj.to_dict())}
    return _ADDRESS.sub("", repr(obj))


def definition_hash(definition: Any) -> str:
    """SHA-256 of the canonical JSON of a definition."""
    text = json.dumps(definition, sort_keys=True, allow_nan=False, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _flat(value: Any, prefix: str, out: dict[str, Any]) -> None:
    if isinstance(value, dict) and value:
        for key, item in value.items():
            _flat(item, f"{prefix}.{key}" if prefix else str(key), out)
    else:
        out[prefix] = value


def _changes(old: Any, new: Any, limit: int = 5) -> str:
    """The dotted keys whose values differ between two definitions (at most ``limit``)."""
    a: dict[str, Any] = {}
    b: dict[str, Any] = {}
    _flat(old, "", a)
    _flat(new, "", b)
    keys = [k for k in dict.fromkeys([*a, *b]) if a.get(k, None) != b.get(k, None) or (k in a) != (k in b)]
    more = f" and {len(keys) - limit} more" if len(keys) > limit else ""
    return ", ".join(k or "(the definition)" for k in keys[:limit]) + more


def _encode(columns: Mapping[str, Any]) -> dict[str, Any]:
    """Result columns (scalars) as JSON: a non-finite float becomes ``{"float": "inf"}``."""
    return {
        k: {"float": json_safe(v)} if isinstance(v, float) and not math.isfinite(v) else v for k, v in columns.items()
    }


def _decode(columns: Mapping[str, Any]) -> dict[str, Any]:
    """Inverse of :func:`_encode`."""
    return {k: float(v["float"]) if isinstance(v, dict) else v for k, v in columns.items()}


class Journal:
    """The append-only result file of one sweep.

    Parameters
    ----------
    path : path-like
        The journal (conventionally ``*.jsonl``); its directory must exist.
    definition : JSON-ready
        What the sweep computes on which points (:func:`describe`).
    n_points : int
        Number of points; an index outside ``range(n_points)`` in the file is an error.
    restart : bool
        Start a new journal even if ``path`` holds one.

    Attributes
    ----------
    done : dict of int to tuple
        The outcomes already on disk, by point index: ``("ok", columns)`` or
        ``("error", type, message, traceback)``.
    hash : str
        SHA-256 of the definition.
    resumed : bool
        True when ``path`` held a journal of this sweep, read into ``done`` (False
        for a new journal, or with ``restart``).

    Raises
    ------
    ParameterError
        Naming ``results`` when ``path`` holds a journal of another definition (both
        hashes and the changed keys in the message) or a file that is not a journal.
    """

    def __init__(self, path: str | os.PathLike[str], definition: Any, n_points: int, restart: bool = False) -> None:
        self.path = Path(path)
        if self.path.is_dir() or not self.path.parent.is_dir():
            raise ParameterError("results", "a file path in an existing directory", str(self.path))
        self.hash = definition_hash(definition)
        self.n_points = n_points
        self.done: dict[int, tuple[Any, ...]] = {}
        self.resumed = not restart and self.path.is_file() and self.path.stat().st_size > 0
        header = {"format": _FORMAT, "version": __version__, "hash": self.hash, "n_points": n_points}
        header["definition"] = definition
        if self.resumed:
            self._read(definition)
        else:
            with atomic_write(self.path) as fh:
                fh.write(json.dumps(header, allow_nan=False) + "\n")
        self._fh: IO[str] | None = self.path.open("a", encoding="utf-8")

    def _read(self, definition: Any) -> None:
        with self.path.open("rb") as fh:
            data = fh.read()
        lines = data.split(b"\n")
        complete = len(lines) - 1  # the part after the last newline is cut short (or empty)
        try:
            header = json.loads(lines[0]) if complete else None
        except ValueError:
            header = None
        if not isinstance(header, dict) or header.get("format") != _FORMAT:
            raise ParameterError(
                "results",
                "a sweep journal written by nrobust (its first line is not a journal header); "
                "pass restart=True (nrobust sweep --restart) to overwrite it",
                str(self.path),
            )
        if header.get("hash") != self.hash:
            raise ParameterError(
                "results",
                f"the journal of this sweep: it records sweep {str(header.get('hash'))[:12]}, this sweep is "
                f"{self.hash[:12]} (changed: {_changes(header.get('definition'), definition)}); "
                "pass restart=True (nrobust sweep --restart) to start over",
                str(self.path),
            )
        for number, line in enumerate(lines[1:complete], start=2):
            try:
                entry = json.loads(line)
                index = int(entry["index"])
                if entry["status"] == "ok":
                    outcome: tuple[Any, ...] = ("ok", _decode(entry["result"]))
                else:
                    outcome = ("error", str(entry["type"]), str(entry["message"]), str(entry.get("traceback", "")))
            except (ValueError, KeyError, TypeError):
                raise ParameterError(
                    "results", f"a sweep journal whose lines are outcomes (line {number} is not)", str(self.path)
                ) from None
            if not 0 <= index < self.n_points:
                raise ParameterError(
                    "results", f"a journal of {self.n_points} points (line {number} has index {index})", str(self.path)
                )
            self.done[index] = outcome
        if lines[-1]:  # a line cut short by a kill: drop it before appending
            with self.path.open("r+b") as fh:
                fh.truncate(len(data) - len(lines[-1]))

    def append(self, index: int, outcome: tuple[Any, ...]) -> None:
        """Write the outcome of point ``index`` and flush it to the operating system."""
        if outcome[0] == "ok":
            entry: dict[str, Any] = {"index": index, "status": "ok", "result": _encode(outcome[1])}
        else:
            entry = {"index": index, "status": "error", "type": outcome[1], "message": outcome[2]}
            entry["traceback"] = outcome[3]
        if self._fh is None:
            raise ParameterError("journal", "open (it was closed)")
        self._fh.write(json.dumps(entry, allow_nan=False) + "\n")
        self._fh.flush()
        self.done[index] = outcome

    def close(self) -> None:
        """Close the file (the journal stays on disk)."""
        if self._fh is not None:
            self._fh.close()
            self._fh = None
