"""Parallel maps and parameter sweeps: serial, on local processes, on any Executor or on Dask.

:func:`sweep` calls ``func(**point)`` for every point of a grid (:func:`grid`) or of a
sample set (a list of dicts) and gathers the outcomes in a :class:`SweepResult`: one row
per point, in input order, whatever executed it. A point whose call raises is recorded
with the exception type and message, never dropped. :func:`sweep_map` is a ``map`` on the
same executors, used by the gain studies (``executor=``). See ``docs/sweeps.md``.
"""

from __future__ import annotations

import csv
import ctypes
import itertools
import json
import logging
import math
import operator
import os
import pickle
import select
import signal
import sys
import time
import traceback
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, overload

import numpy as np
from threadpoolctl import threadpool_limits

from .._atomic import atomic_write
from .._json import decode_floats, json_safe
from .._progress import progress_bar
from ..errors import ParameterError, SweepError
from .journal import Journal, definition_hash, describe

if TYPE_CHECKING:
    from .._progress import ProgressBar

__all__ = [
    "MAX_POINTS",
    "Grid",
    "PointFailure",
    "SweepInterrupted",
    "SweepMap",
    "SweepResult",
    "grid",
    "sweep",
    "sweep_map",
]

#: Columns every table starts or ends its fixed part with; result keys that collide with
#: these (or with a parameter name) are renamed ``result.<key>``.
_RESERVED = ("index", "status", "error_type", "error")
_DASK_SCHEMES = ("tcp://", "tls://", "ucx://", "inproc://", "ws://", "wss://")
_EXECUTOR_REQUIREMENT = (
    "None (local processes on all cores), 'serial', 'dask', a scheduler address "
    "('tcp://host:8786'), a positive int (number of processes), a "
    "concurrent.futures.Executor or a dask.distributed.Client"
)


# ---------------------------------------------------------------------------------------
# grids and flattening
# ---------------------------------------------------------------------------------------


#: Default cap on the number of points of one sweep (``max_points=``): about 1 GB of
#: points and results in memory at the measured ~1 kB per point of a typical analysis.
MAX_POINTS = 1_000_000


class Grid(Sequence[dict[str, Any]]):
    """The cartesian product of parameter values (:func:`grid`), generated point by point.

    A grid stores its axes, never the product: ``len`` is the product of the axis
    lengths, ``grid[i]`` computes point ``i`` and iteration yields the points in
    ``itertools.product`` order (the last axis fastest). A grid equals any sequence of
    the same points in the same order.

    Attributes
    ----------
    axes : dict of str to sequence
        The values per parameter name (a ``range`` stays a ``range``).
    """

    def __init__(self, axes: Mapping[str, Sequence[Any]]) -> None:
        self.axes = dict(axes)
        self._size = math.prod(len(v) for v in self.axes.values())

    def __len__(self) -> int:
        return self._size

    @overload
    def __getitem__(self, index: int) -> dict[str, Any]: ...

    @overload
    def __getitem__(self, index: slice) -> list[dict[str, Any]]: ...

    def __getitem__(self, index: int | slice) -> dict[str, Any] | list[dict[str, Any]]:
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(self._size))]
        i = operator.index(index)
        if i < 0:
            i += self._size
        if not 0 <= i < self._size:
            raise IndexError(f"grid index {index} out of range for {self._size} points")
        point: dict[str, Any] = {}
        for name, values in reversed(self.axes.items()):
            i, k = divmod(i, len(values))
            point[name] = values[k]
        return {name: point[name] for name in self.axes}

    def __iter__(self) -> Iterator[dict[str, Any]]:
        names = list(self.axes)
        return (dict(zip(names, combo)) for combo in itertools.product(*self.axes.values()))

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Grid):
            return self.axes == other.axes
        if isinstance(other, Sequence) and not isinstance(other, (str, bytes)):
            return len(other) == self._size and all(a == b for a, b in zip(self, other))
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]

    def describe(self) -> str:
        """``"a grid of 4 x 3 = 12 points over K, rho"``."""
        sizes = " x ".join(str(len(v)) for v in self.axes.values())
        return f"a grid of {sizes} = {self._size} points over {', '.join(self.axes)}"

    def __repr__(self) -> str:
        return f"Grid({', '.join(f'{k}: {len(v)} values' for k, v in self.axes.items())}; {self._size} points)"


def grid(**axes: Sequence[Any] | np.ndarray) -> Grid:
    """Cartesian product of parameter values, generated lazily.

    Parameters
    ----------
    **axes : sequence
        One non-empty sequence (list, tuple, range or 1-D array) of values per
        parameter name. numpy scalars are converted to Python scalars.

    Returns
    -------
    Grid
        A sequence of ``prod(len(values))`` dicts, computed on demand (nothing of the
        size of the product is allocated); the last axis varies fastest
        (``itertools.product`` order), so ``grid(K=[0, 1], delta=[0.1, 0.2])`` is
        ``[{K: 0, delta: 0.1}, {K: 0, delta: 0.2}, {K: 1, delta: 0.1}, {K: 1, delta: 0.2}]``.
        :func:`sweep` refuses a grid of more than ``max_points`` points before running any.

    Raises
    ------
    ParameterError
        If no axis is given or an axis is not a non-empty sequence.
    """
    if not axes:
        raise ParameterError("axes", "at least one keyword argument name=[values]")
    values: dict[str, Sequence[Any]] = {}
    for name, vals in axes.items():
        if isinstance(vals, (str, bytes, Mapping)) or not isinstance(vals, (Sequence, np.ndarray, range)):
            raise ParameterError(name, "a sequence of values (list, tuple, range or 1-D array)", vals)
        if isinstance(vals, np.ndarray) and vals.ndim != 1:
            raise ParameterError(name, "a 1-D array of values", vals)
        if len(vals) == 0:
            raise ParameterError(name, "a non-empty sequence of values", vals)
        values[name] = (
            vals if isinstance(vals, range) else tuple(v.item() if isinstance(v, np.generic) else v for v in vals)
        )
    return Grid(values)


def _flatten(value: Any, prefix: str, out: dict[str, Any]) -> None:
    """Flatten ``value`` into scalar columns of ``out`` named after ``prefix``.

    Mappings and objects with ``to_dict()`` give dotted names (the strings ``"inf"``,
    ``"-inf"`` and ``"nan"`` of a ``to_dict()`` become floats again, so that numeric
    columns stay numeric), complex numbers give ``.real`` and ``.imag`` columns,
    sequences are stored as a JSON string, any other object as its ``repr``.
    """
    if isinstance(value, Mapping):
        for key, item in value.items():
            _flatten(item, f"{prefix}.{key}" if prefix else str(key), out)
    elif isinstance(value, np.generic):
        _flatten(value.item(), prefix, out)
    elif isinstance(value, (bool, int, float, str)) or value is None:
        out[prefix] = value
    elif isinstance(value, complex):
        out[f"{prefix}.real"] = value.real
        out[f"{prefix}.imag"] = value.imag
    elif callable(getattr(value, "to_dict", None)) and not isinstance(value, type):
        _flatten(decode_floats(value.to_dict()), prefix, out)
    elif isinstance(value, (list, tuple, np.ndarray)):
        out[prefix] = json.dumps(json_safe(value), allow_nan=False)
    else:
        out[prefix] = repr(value)


def _result_columns(value: Any) -> dict[str, Any]:
    """The flat columns of one return value of the swept function."""
    if callable(getattr(value, "to_dict", None)) and not isinstance(value, (Mapping, type)):
        value = decode_floats(value.to_dict())
    if not isinstance(value, Mapping):
        raise TypeError(
            f"the swept function must return a dict of scalars or an object with to_dict(), got {type(value).__name__}"
        )
    out: dict[str, Any] = {}
    _flatten(value, "", out)
    return out


# ---------------------------------------------------------------------------------------
# running points (these run on the workers)
# ---------------------------------------------------------------------------------------


def _run_point(func: Callable[..., Any], point: Mapping[str, Any], columns: bool = True) -> tuple[Any, ...]:
    """Call ``func(**point)``: ``("ok", result)`` or ``("error", type, message, traceback)``.

    With ``columns`` the result is flattened into table columns on the worker.
    """
    try:
        result = func(**point)
        return ("ok", _result_columns(result) if columns else result)
    except Exception as exc:
        return ("error", type(exc).__name__, str(exc), traceback.format_exc())


def _run_chunk(
    func: Callable[..., Any], chunk: Sequence[Mapping[str, Any]], columns: bool = True
) -> list[tuple[Any, ...]]:
    """Run consecutive points on one worker; one task per chunk amortises the transfer."""
    return [_run_point(func, point, columns) for point in chunk]


#: Process ids of the point processes this process has forked and not yet reaped.
_CHILDREN: set[int] = set()


def _fork() -> int:
    """``os.fork()``. From Python 3.12 it warns when other threads are alive (a lock they
    hold could be copied into the child); the child forked here runs only the swept
    function and writes to a pipe, so that one warning is ignored, by its exact text."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", r"This process \(pid=\d+\) is multi-threaded", DeprecationWarning)
        return os.fork()


def _die_with_parent(parent: int) -> None:
    """In a point process: on Linux, be killed when the process that forked it dies, even by
    SIGKILL (``prctl(PR_SET_PDEATHSIG)``), so that a hung point never outlives its sweep."""
    if sys.platform.startswith("linux"):
        with suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # 1: PR_SET_PDEATHSIG
    if os.getppid() != parent:  # the parent died before the request was in place
        os._exit(1)


def _point_process(
    func: Callable[..., Any], points: Sequence[Mapping[str, Any]], columns: bool, fd: int, parent: int
) -> None:
    """Body of a forked point process: run the points, send each outcome as a frame, exit."""
    code = 0
    try:
        _die_with_parent(parent)
        with os.fdopen(fd, "wb") as pipe:
            for point in points:
                outcome = _run_point(func, point, columns)
                try:
                    data = pickle.dumps(outcome)
                except Exception as exc:
                    data = pickle.dumps(("error", type(exc).__name__, f"the result cannot be sent back: {exc}", ""))
                pipe.write(len(data).to_bytes(8, "little") + data)
                pipe.flush()
    except BaseException:
        code = 1
    finally:
        for stream in (sys.stdout, sys.stderr):
            with suppress(Exception):
                stream.flush()
        os._exit(code)


def _read_frame(fd: int, buf: bytearray, deadline: float) -> bytes | None:
    """The next length-prefixed frame from ``fd``; None at the deadline; EOFError when the writer is gone."""
    while True:
        if len(buf) >= 8:
            size = int.from_bytes(buf[:8], "little")
            if len(buf) >= 8 + size:
                frame = bytes(buf[8 : 8 + size])
                del buf[: 8 + size]
                return frame
        remaining = deadline - time.monotonic()
        if remaining <= 0 or not select.select([fd], [], [], remaining)[0]:
            return None
        data = os.read(fd, 1 << 16)
        if not data:
            raise EOFError
        buf.extend(data)


def _stop(pid: int) -> int:
    """Kill a point process (if still running) and reap it; its wait status."""
    with suppress(ProcessLookupError):
        os.kill(pid, signal.SIGKILL)
    _, status = os.waitpid(pid, 0)
    _CHILDREN.discard(pid)
    return status


def _run_chunk_guarded(
    func: Callable[..., Any],
    chunk: Sequence[Mapping[str, Any]],
    columns: bool,
    timeout: float,
    on_outcome: Callable[[int, tuple[Any, ...]], None] | None = None,
) -> list[tuple[Any, ...]]:
    """Run consecutive points in a forked process, each within ``timeout`` seconds.

    A point that does not return in time is recorded as a failure of type ``Timeout``
    and its process killed (``SIGKILL``); a point whose process dies (a crash, an
    ``os._exit``) as a failure of type ``WorkerDied``. A fresh process then runs the rest
    of the chunk. ``on_outcome(k, outcome)`` is called as each point finishes.
    """
    outcomes: list[tuple[Any, ...]] = []

    def record(outcome: tuple[Any, ...]) -> None:
        if on_outcome is not None:
            on_outcome(len(outcomes), outcome)
        outcomes.append(outcome)

    while len(outcomes) < len(chunk):
        read_fd, write_fd = os.pipe()
        parent = os.getpid()
        pid = _fork()
        if pid == 0:  # the point process
            os.close(read_fd)
            _point_process(func, chunk[len(outcomes) :], columns, write_fd, parent)
        _CHILDREN.add(pid)
        os.close(write_fd)
        buf = bytearray()
        try:
            while len(outcomes) < len(chunk):
                try:
                    frame = _read_frame(read_fd, buf, time.monotonic() + timeout)
                except EOFError:
                    code = os.waitstatus_to_exitcode(_stop(pid))
                    how = f"was killed by signal {-code}" if code < 0 else f"exited with code {code}"
                    record(("error", "WorkerDied", f"the process running the point {how}", ""))
                    break
                if frame is None:
                    _stop(pid)
                    message = f"no result within timeout = {timeout:g} s; the process running the point was killed"
                    record(("error", "Timeout", message, ""))
                    break
                record(pickle.loads(frame))
        finally:
            os.close(read_fd)
            if pid in _CHILDREN:
                _stop(pid)
    return outcomes


def _kill_children_and_exit(signum: int, frame: Any) -> None:
    """SIGTERM handler of nrobust's pool workers: take the point processes along."""
    for pid in list(_CHILDREN):
        with suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    os._exit(128 + signum)


# ---------------------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------------------


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
        _flatten(self.point, "", point)
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
    """Outcome of :func:`sweep`: one row per point, in input order.

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
        return tuple(self._result_names().values())

    @property
    def columns(self) -> tuple[str, ...]:
        """All table columns: index, parameters, status, error_type, error, results."""
        return ("index", *self.parameter_columns, "status", "error_type", "error", *self.result_columns)

    @staticmethod
    def _flat_point(point: Mapping[str, Any]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        _flatten(point, "", out)
        return out

    def _result_names(self) -> dict[str, str]:
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
        names = self._result_names()
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


# ---------------------------------------------------------------------------------------
# executors
# ---------------------------------------------------------------------------------------


def _cpu_count() -> int:
    """Cores this process may use."""
    if hasattr(os, "process_cpu_count"):
        return os.process_cpu_count() or 1
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0)) or 1
    return os.cpu_count() or 1


def _init_pool_worker() -> None:
    """Worker initializer: one BLAS thread, and point processes killed with the worker.

    On a machine shared by several workers, multithreaded BLAS pools compete for the same
    cores and the small eigenvalue problems of nrobust (the chains of a difference
    operator) slow down tenfold. threadpoolctl changes the limit of the libraries already
    loaded, so it works in forked workers, which inherit the parent's BLAS. A worker
    stopped by SIGTERM (an interrupted sweep) kills the point processes it forked for a
    timeout, so that no hung point outlives the sweep. Ctrl-C in a terminal reaches every
    process of the group: the workers ignore it (no traceback from each of them) and the
    parent, which handles it, stops them.
    """
    threadpool_limits(1)
    signal.signal(signal.SIGTERM, _kill_children_and_exit)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle: it stops the pool


@contextmanager
def _process_pool(n_workers: int) -> Iterator[ProcessPoolExecutor]:
    """A local pool of ``n_workers`` processes (the platform's start method), one BLAS thread each."""
    with ProcessPoolExecutor(max_workers=n_workers, initializer=_init_pool_worker) as pool:
        yield pool


def _dask_client_type() -> type | None:
    """``dask.distributed.Client`` if distributed is importable, else None."""
    try:
        from distributed import Client
    except ImportError:
        return None
    return Client


def _require_distributed(what: str) -> Any:
    try:
        import distributed
    except ImportError:
        raise ParameterError(
            "executor", f"usable: {what} needs dask.distributed (pip install 'nrobust[dask]')", what
        ) from None
    return distributed


def _check_picklable(
    func: Callable[..., Any], points: Sequence[Any], dumps: Callable[[Any], bytes], where: str
) -> None:
    """Fail early, naming ``func`` or ``points``, when they cannot be sent to workers."""
    try:
        dumps(func)
    except Exception as exc:
        raise ParameterError(
            "func",
            f"picklable to run on {where}: a function defined at module level or a "
            "functools.partial of one (lambdas and nested functions cannot be pickled by the "
            "process pool; use executor='serial', a thread pool or Dask for those) "
            f"[{type(exc).__name__}: {exc}]",
            func,
        ) from exc
    try:
        dumps(list(points))
    except Exception as exc:
        raise ParameterError("points", f"picklable to be sent to {where} [{type(exc).__name__}: {exc}]") from exc


def _chunks(points: Sequence[Mapping[str, Any]], size: int) -> list[list[Mapping[str, Any]]]:
    return [list(points[i : i + size]) for i in range(0, len(points), size)]


def _auto_chunksize(n_points: int, n_workers: int) -> int:
    """About four chunks per worker: enough to balance the load, few enough transfers."""
    return max(1, math.ceil(n_points / (4 * max(1, n_workers))))


def _submit_args(
    func: Callable[..., Any], chunk: list[Mapping[str, Any]], columns: bool, timeout: float | None
) -> tuple[Any, ...]:
    """The task that runs one chunk on a worker: in the worker itself, or in a forked point process with a timeout."""
    if timeout is None:
        return (_run_chunk, func, chunk, columns)
    return (_run_chunk_guarded, func, chunk, columns, timeout)


def _run_on_futures_executor(
    pool: Executor,
    func: Callable[..., Any],
    chunks: list[list[Mapping[str, Any]]],
    columns: bool,
    timeout: float | None,
    on_chunk: Callable[[int, list[tuple[Any, ...]]], None],
) -> None:
    futures = {pool.submit(*_submit_args(func, chunk, columns, timeout)): i for i, chunk in enumerate(chunks)}
    try:
        for fut in as_completed(futures):
            on_chunk(futures[fut], fut.result())
    finally:
        for fut in futures:
            fut.cancel()


def _run_on_dask(
    client: Any,
    func: Callable[..., Any],
    chunks: list[list[Mapping[str, Any]]],
    columns: bool,
    timeout: float | None,
    on_chunk: Callable[[int, list[tuple[Any, ...]]], None],
) -> None:
    import distributed

    futures = [client.submit(*_submit_args(func, chunk, columns, timeout), pure=False) for chunk in chunks]
    index = {fut.key: i for i, fut in enumerate(futures)}
    try:
        for fut in distributed.as_completed(futures):
            on_chunk(index[fut.key], fut.result())
    finally:
        client.cancel([f for f in futures if not f.done()])


@contextmanager
def _dask_client(executor: Any) -> Iterator[tuple[Any, str]]:
    """Yield ``(client, description)``; start and stop what this call created."""
    client_type = _dask_client_type()
    if client_type is not None and isinstance(executor, client_type):
        yield executor, f"dask({executor.scheduler.address})"  # type: ignore[attr-defined]
        return
    distributed = _require_distributed(str(executor))
    if executor == "dask":
        with (
            distributed.LocalCluster(
                n_workers=_cpu_count(),
                threads_per_worker=1,
                processes=True,
                dashboard_address=":0",
                silence_logs=logging.ERROR,
            ) as cluster,
            distributed.Client(cluster) as client,
        ):
            yield client, f"dask(LocalCluster, {_cpu_count()} workers)"
    else:
        with distributed.Client(executor) as client:
            yield client, f"dask({executor})"


def _classify_executor(executor: Any) -> str:
    """``"serial"``, ``"pool"``, ``"executor"`` or ``"dask"``; raise naming ``executor`` otherwise."""
    if executor is None or (isinstance(executor, int) and not isinstance(executor, bool)):
        if executor is not None and executor < 1:
            raise ParameterError("executor", _EXECUTOR_REQUIREMENT, executor)
        return "pool"
    if isinstance(executor, str):
        if executor == "serial":
            return "serial"
        if executor == "dask" or executor.startswith(_DASK_SCHEMES):
            return "dask"
        raise ParameterError("executor", _EXECUTOR_REQUIREMENT, executor)
    if isinstance(executor, Executor):
        return "executor"
    client_type = _dask_client_type()
    if client_type is not None and isinstance(executor, client_type):
        return "dask"
    raise ParameterError("executor", _EXECUTOR_REQUIREMENT, executor)


def _progress_bar(total: int, progress: bool | None) -> ProgressBar:
    """A text progress bar on stderr; by default shown in terminals and notebooks only."""
    return progress_bar(total, progress, desc="sweep", unit="pt", leave=True)


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """Stop a pool of nrobust's now (on an interrupt): terminate its workers, which kill their point processes."""
    for process in list(getattr(pool, "_processes", {}).values()):
        with suppress(Exception):
            process.terminate()
    pool.shutdown(wait=True, cancel_futures=True)


def _execute(
    func: Callable[..., Any],
    pts: list[dict[str, Any]],
    executor: Any,
    chunksize: int | None,
    progress: bool | None,
    columns: bool,
    timeout: float | None = None,
    on_done: Callable[[int, tuple[Any, ...]], None] | None = None,
    max_chunk: int | None = None,
) -> tuple[list[tuple[Any, ...]], str]:
    """Run ``func(**point)`` for every point on ``executor``; outcomes in input order.

    ``on_done(position, outcome)`` is called in this process as each point's outcome
    arrives (point by point in serial mode, chunk by chunk on workers). ``max_chunk``
    caps the automatic chunk size.
    """
    kind = _classify_executor(executor)
    if kind == "pool" or isinstance(executor, ProcessPoolExecutor):
        _check_picklable(func, pts, pickle.dumps, "worker processes")
    elif kind == "dask":
        _check_picklable(func, pts, _require_distributed("dask").protocol.pickle.dumps, "Dask workers")
    outcomes: list[tuple[Any, ...]] = [()] * len(pts)

    with _progress_bar(len(pts), progress) as bar:

        def done(position: int, outcome: tuple[Any, ...]) -> None:
            outcomes[position] = outcome
            if on_done is not None:
                on_done(position, outcome)
            bar.update(1)

        def chunking(n_workers: int) -> list[list[Mapping[str, Any]]]:
            size = chunksize or min(_auto_chunksize(len(pts), n_workers), max_chunk or len(pts))
            return _chunks(pts, size)

        def chunk_done_for(chunks: list[list[Mapping[str, Any]]]) -> Callable[[int, list[tuple[Any, ...]]], None]:
            starts = list(itertools.accumulate((len(c) for c in chunks), initial=0))

            def chunk_done(i: int, chunk_outcomes: list[tuple[Any, ...]]) -> None:
                for k, outcome in enumerate(chunk_outcomes):
                    done(starts[i] + k, outcome)

            return chunk_done

        if kind == "serial":
            description = "serial"
            if timeout is not None:
                _run_chunk_guarded(func, pts, columns, timeout, on_outcome=done)
            else:
                for position, point in enumerate(pts):
                    done(position, _run_point(func, point, columns))
        elif kind == "pool":
            n_workers = _cpu_count() if executor is None else int(executor)
            chunks = chunking(n_workers)
            description = f"processes({n_workers})"
            with _process_pool(min(n_workers, len(chunks))) as pool:
                try:
                    _run_on_futures_executor(pool, func, chunks, columns, timeout, chunk_done_for(chunks))
                except BaseException:
                    _stop_pool(pool)
                    raise
        elif kind == "executor":
            chunks = chunking(getattr(executor, "_max_workers", None) or _cpu_count())
            description = f"executor({type(executor).__name__})"
            _run_on_futures_executor(executor, func, chunks, columns, timeout, chunk_done_for(chunks))
        else:
            with _dask_client(executor) as (client, description):
                chunks = chunking(sum(client.nthreads().values()) or 1)
                _run_on_dask(client, func, chunks, columns, timeout, chunk_done_for(chunks))
    return outcomes, description


class SweepInterrupted(KeyboardInterrupt):
    """A sweep stopped by Ctrl-C (``KeyboardInterrupt``); the finished points are kept.

    Attributes
    ----------
    done : int
        Points finished (in the journal, when the sweep has one).
    total : int
        Points of the sweep.
    results : pathlib.Path or None
        The journal holding the finished points; running the same sweep on it resumes.
    """

    def __init__(self, done: int, total: int, results: Path | None) -> None:
        self.done, self.total, self.results = done, total, results
        where = f", results in {results}, rerun to resume" if results is not None else ""
        super().__init__(f"interrupted: {done} of {total} points done{where}")


def _estimate_bytes(points: Sequence[Mapping[str, Any]]) -> int:
    """Memory a sweep of ``points`` holds: its points and a typical ~1 kB result row each."""
    first = points[0]
    per_point = sys.getsizeof(first) + sum(sys.getsizeof(k) + sys.getsizeof(v) for k, v in first.items()) + 1024
    return len(points) * per_point


def _check_size(points: Sequence[Mapping[str, Any]], max_points: int) -> None:
    """Refuse a sweep of more than ``max_points`` points, before any point is built or run."""
    n = len(points)
    if n > max_points:
        what = points.describe() if isinstance(points, Grid) else f"a sequence of {n} points"
        gib = _estimate_bytes(points) / 2**30
        raise ParameterError(
            "points",
            f"at most max_points = {max_points} points, but it is {what} (about {gib:.3g} GiB in memory); "
            "shrink it, or pass a larger max_points to run it",
        )


def _definition(func: Callable[..., Any], points: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """What a sweep computes on which points, for its journal."""
    if isinstance(points, Grid):
        return {"func": describe(func), "points": {"grid": describe(points.axes)}}
    listed = describe(list(points))
    return {"func": describe(func), "points": {"n": len(listed), "sha256": definition_hash(listed)}}


#: Failures that are not the point's own: retried when a sweep resumes.
_RETRIED = ("Timeout", "WorkerDied")


def sweep(
    func: Callable[..., Any],
    points: Sequence[Mapping[str, Any]],
    executor: Any = None,
    *,
    chunksize: int | None = None,
    progress: bool | None = None,
    max_points: int = MAX_POINTS,
    timeout: float | None = None,
    results: str | os.PathLike[str] | None = None,
    restart: bool = False,
) -> SweepResult:
    """Call ``func(**point)`` for every point and gather the outcomes.

    Parameters
    ----------
    func : callable
        Called with each point's entries as keyword arguments. It returns a dict of
        scalars or an object with ``to_dict()``; nested dicts are flattened into dotted
        column names, complex values into ``.real``/``.imag`` columns, sequences into
        JSON strings. For process pools it must be picklable (a module-level function or
        a ``functools.partial`` of one; not a lambda or a nested function).
    points : sequence of dict
        A grid (:func:`grid`) or a sample set: dicts with string keys.
    executor : None, str, int, Executor or dask.distributed.Client, optional
        Where the points run:

        - ``None``: a local process pool on all cores (started and shut down here);
        - ``"serial"``: in this process, one point after the other;
        - an int ``n >= 1``: a local pool of ``n`` processes;
        - a ``concurrent.futures.Executor`` (process or thread pool): used, not shut down;
        - ``"dask"``: a ``dask.distributed.LocalCluster`` on all cores, started and
          closed by this call;
        - a scheduler address such as ``"tcp://scheduler:8786"``: a client connected for
          the duration of the call;
        - a ``dask.distributed.Client``: used, not closed.
    chunksize : int, optional
        Points per task; by default about four tasks per worker (at most 4 points per
        task when ``results`` is given, so that finished points reach the journal soon).
    progress : bool, optional
        Show a tqdm progress bar on stderr. By default only when stderr is a terminal
        or the code runs in a Jupyter kernel, so logs and batch jobs stay clean.
    max_points : int, default :data:`MAX_POINTS`
        The largest sweep accepted. A larger one is refused before any point is built
        or run, with the grid's shape, its size and an estimate of its memory.
    timeout : float, optional
        Seconds a point may run. Each point then runs in a forked process (POSIX only):
        one past its time is killed and recorded as a failure of type ``"Timeout"``,
        and a fresh process goes on with the next points. This holds on every executor
        (the serial one included: the points run in a child of this process, so a hung
        point cannot hang the sweep); on process pools and Dask the worker forks the
        point process, so the worker itself is never lost.
    results : path-like, optional
        A journal (JSON lines, ``docs/sweeps.md``): each finished point is appended as
        it arrives, under a header holding the sweep's definition (``func`` and the
        points) and its SHA-256. If the file holds a journal of the same sweep, its
        points are not run again (failures of type ``"Timeout"`` and ``"WorkerDied"``
        are retried); a journal of another sweep is refused.
    restart : bool, default False
        Start ``results`` afresh even if it holds a journal.

    Returns
    -------
    SweepResult
        One row per point, in input order. The same for every executor, and the same
        for a sweep resumed from its journal as for one run without interruption.

    Raises
    ------
    ParameterError
        If ``func`` is not callable or cannot be pickled for the chosen executor, if
        ``points`` is not a non-empty sequence of dicts with string keys or has more
        than ``max_points`` points, if ``executor``, ``chunksize``, ``max_points`` or
        ``timeout`` is not one of the accepted values, or if ``results`` holds a
        journal of another sweep (naming both hashes and what changed).
    SweepInterrupted
        On Ctrl-C (a ``KeyboardInterrupt``), after the running workers are stopped;
        the points finished until then are in the journal.

    Notes
    -----
    A point whose call raises an ``Exception`` becomes a :class:`PointFailure` (type,
    message and traceback) and a row with ``status == "error"``. Without ``timeout``,
    failures of the machinery itself (a worker process killed, a lost scheduler) are
    raised; with it, a point whose process dies is a failure of type ``"WorkerDied"``.
    """
    if not callable(func):
        raise ParameterError("func", "callable", func)
    if isinstance(points, (Mapping, str, bytes)) or not isinstance(points, Sequence):
        raise ParameterError("points", "a sequence of dicts, e.g. nrobust.grid(K=[...], delta=[...])", points)
    if len(points) == 0:
        raise ParameterError("points", "a non-empty sequence of dicts", points)
    if isinstance(max_points, bool) or not isinstance(max_points, (int, np.integer)) or max_points < 1:
        raise ParameterError("max_points", "a positive int", max_points)
    _check_size(points, int(max_points))
    if not isinstance(points, Grid):
        for i, point in enumerate(points):
            if not isinstance(point, Mapping) or not all(isinstance(k, str) for k in point):
                raise ParameterError(f"points[{i}]", "a dict with string keys", point)
    if chunksize is not None:
        if isinstance(chunksize, bool) or not isinstance(chunksize, (int, np.integer)) or chunksize < 1:
            raise ParameterError("chunksize", "a positive int or None", chunksize)
        chunksize = int(chunksize)
    if timeout is not None:
        if isinstance(timeout, bool) or not isinstance(timeout, (int, float, np.number)):
            raise ParameterError("timeout", "a number of seconds > 0, or None", timeout)
        if not (math.isfinite(timeout) and timeout > 0):
            raise ParameterError("timeout", "a finite number of seconds > 0, or None", timeout)
        if not hasattr(os, "fork"):
            raise ParameterError("timeout", "None on this platform (a timeout needs os.fork, POSIX)", timeout)
        timeout = float(timeout)
    _classify_executor(executor)
    pts = [dict(p) for p in points]
    definition = None if results is None else _definition(func, points if isinstance(points, Grid) else pts)
    journal = None if results is None else Journal(results, definition, len(pts), restart)
    done = (
        {} if journal is None else {i: o for i, o in journal.done.items() if not (o[0] == "error" and o[1] in _RETRIED)}
    )
    todo = [i for i in range(len(pts)) if i not in done]
    finished = [len(done)]

    def record(position: int, outcome: tuple[Any, ...]) -> None:
        finished[0] += 1
        if journal is not None:
            journal.append(todo[position], outcome)

    start = time.perf_counter()
    try:
        if todo:
            fresh, description = _execute(
                func,
                [pts[i] for i in todo],
                executor,
                chunksize,
                progress,
                columns=True,
                timeout=timeout,
                on_done=record,
                max_chunk=None if journal is None else 4,
            )
        else:
            fresh, description = [], "resumed: nothing to run"
    except KeyboardInterrupt:
        raise SweepInterrupted(finished[0], len(pts), None if journal is None else journal.path) from None
    finally:
        if journal is not None:
            journal.close()
    elapsed = time.perf_counter() - start
    outcomes = dict(done)
    outcomes.update(zip(todo, fresh))

    rows: list[dict[str, Any] | None] = []
    failures: list[PointFailure] = []
    for i, point in enumerate(pts):
        outcome = outcomes[i]
        if outcome[0] == "ok":
            rows.append(outcome[1])
        else:
            rows.append(None)
            failures.append(PointFailure(i, point, outcome[1], outcome[2], outcome[3]))
    return SweepResult(tuple(pts), tuple(rows), tuple(failures), description, elapsed)


class _Item:
    """``func(item)`` called as ``func(**{"item": item})`` by the sweep machinery (picklable)."""

    def __init__(self, func: Callable[[Any], Any]) -> None:
        self.func = func

    def __call__(self, item: Any) -> Any:
        return self.func(item)


@dataclass(frozen=True)
class SweepMap:
    """``map(func, items)`` on a sweep executor: results in input order, work spread out.

    Any grid computation of nrobust that takes an ``executor`` (``stability_chart``,
    ``k_region``, ``ab_region``, ``tradeoff``) runs its points through this. Unlike
    :func:`sweep`, which records failures per point, a map needs every result: an item
    whose call raises stops the computation with a :class:`~nrobust.errors.SweepError`
    naming the item and the original error.

    Parameters
    ----------
    executor : None, str, int, Executor or dask.distributed.Client
        As in :func:`sweep`.
    chunksize : int, optional
        Items per task.
    progress : bool, optional
        As in :func:`sweep`.
    """

    executor: Any = None
    chunksize: int | None = None
    progress: bool | None = None

    def __post_init__(self) -> None:
        _classify_executor(self.executor)  # reject a bad executor before any work

    def __call__(self, func: Callable[[Any], Any], items: Iterable[Any]) -> list[Any]:
        items = list(items)
        if not items:
            return []
        pts = [{"item": item} for item in items]
        outcomes, _ = _execute(_Item(func), pts, self.executor, self.chunksize, self.progress, columns=False)
        for item, outcome in zip(items, outcomes):
            if outcome[0] != "ok":
                raise SweepError(f"item {item!r} raised {outcome[1]}: {outcome[2]}")
        return [outcome[1] for outcome in outcomes]


def sweep_map(executor: Any = None, *, chunksize: int | None = None, progress: bool | None = None) -> SweepMap:
    """A ``map``-like callable that runs on ``executor`` (see :class:`SweepMap`)."""
    return SweepMap(executor, chunksize, progress)


# ---------------------------------------------------------------------------------------
# Monte Carlo robustness
# ---------------------------------------------------------------------------------------
