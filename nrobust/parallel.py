"""Parallel maps and parameter sweeps: serial, on local processes, on any Executor or on Dask.

:func:`sweep` calls ``func(**point)`` for every point of a grid (:func:`grid`) or of a
sample set (a list of dicts) and gathers the outcomes in a :class:`SweepResult`: one row
per point, in input order, whatever executed it. A point whose call raises is recorded
with the exception type and message, never dropped. :func:`sweep_map` is a ``map`` on the
same executors, used by the gain studies (``executor=``). See ``docs/sweeps.md``.
"""

from __future__ import annotations

import csv
import itertools
import json
import logging
import math
import os
import pickle
import sys
import time
import traceback
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits
from tqdm import tqdm

from ._json import decode_floats, json_safe
from .errors import ParameterError, SweepError

__all__ = ["PointFailure", "SweepMap", "SweepResult", "grid", "sweep", "sweep_map"]

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


def grid(**axes: Sequence[Any]) -> list[dict[str, Any]]:
    """Cartesian product of parameter values, as a list of dicts.

    Parameters
    ----------
    **axes : sequence
        One non-empty sequence (list, tuple, range or 1-D array) of values per
        parameter name. numpy scalars are converted to Python scalars.

    Returns
    -------
    list of dict
        ``len = prod(len(values))`` points; the last axis varies fastest
        (``itertools.product`` order), so ``grid(K=[0, 1], delta=[0.1, 0.2])`` is
        ``[{K: 0, delta: 0.1}, {K: 0, delta: 0.2}, {K: 1, delta: 0.1}, {K: 1, delta: 0.2}]``.

    Raises
    ------
    ParameterError
        If no axis is given or an axis is not a non-empty sequence.
    """
    if not axes:
        raise ParameterError("axes", "at least one keyword argument name=[values]")
    names = list(axes)
    values = []
    for name, vals in axes.items():
        if isinstance(vals, (str, bytes, Mapping)) or not isinstance(vals, (Sequence, np.ndarray, range)):
            raise ParameterError(name, "a sequence of values (list, tuple, range or 1-D array)", vals)
        if isinstance(vals, np.ndarray) and vals.ndim != 1:
            raise ParameterError(name, "a 1-D array of values", vals)
        if len(vals) == 0:
            raise ParameterError(name, "a non-empty sequence of values", vals)
        values.append([v.item() if isinstance(v, np.generic) else v for v in vals])
    return [dict(zip(names, combo)) for combo in itertools.product(*values)]


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
        """Write the table as CSV (header row; missing values empty). Returns the path."""
        path = Path(path)
        with path.open("w", newline="", encoding="utf-8") as fh:
            writer = csv.writer(fh)
            writer.writerow(self.columns)
            for row in self.records():
                writer.writerow(["" if row[c] is None else row[c] for c in self.columns])
        return path

    def to_json(self, path: str | os.PathLike[str], extra: Mapping[str, Any] | None = None) -> Path:
        """Write :meth:`to_dict` (plus ``extra`` entries) as strict JSON. Returns the path."""
        data = self.to_dict()
        if extra:
            data.update(extra)
        path = Path(path)
        path.write_text(json.dumps(json_safe(data), indent=1, allow_nan=False) + "\n", encoding="utf-8")
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


def _one_blas_thread() -> None:
    """Worker initializer: limit the BLAS and OpenMP pools of this process to one thread.

    On a machine shared by several workers, multithreaded BLAS pools compete for the same
    cores and the small eigenvalue problems of nrobust (the chains of a difference
    operator) slow down tenfold. threadpoolctl changes the limit of the libraries already
    loaded, so it works in forked workers, which inherit the parent's BLAS.
    """
    threadpool_limits(1)


@contextmanager
def _process_pool(n_workers: int) -> Iterator[ProcessPoolExecutor]:
    """A local pool of ``n_workers`` processes (the platform's start method), one BLAS thread each."""
    with ProcessPoolExecutor(max_workers=n_workers, initializer=_one_blas_thread) as pool:
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


def _run_on_futures_executor(
    pool: Executor, func: Callable[..., Any], chunks: list[list[Mapping[str, Any]]], bar: Any, columns: bool
) -> list[list[tuple[Any, ...]]]:
    futures = {pool.submit(_run_chunk, func, chunk, columns): i for i, chunk in enumerate(chunks)}
    out: list[list[tuple[Any, ...]]] = [[] for _ in chunks]
    try:
        for fut in as_completed(futures):
            i = futures[fut]
            out[i] = fut.result()
            bar.update(len(chunks[i]))
    finally:
        for fut in futures:
            fut.cancel()
    return out


def _run_on_dask(
    client: Any, func: Callable[..., Any], chunks: list[list[Mapping[str, Any]]], bar: Any, columns: bool
) -> list[list[tuple[Any, ...]]]:
    import distributed

    futures = [client.submit(_run_chunk, func, chunk, columns, pure=False) for chunk in chunks]
    index = {fut.key: i for i, fut in enumerate(futures)}
    out: list[list[tuple[Any, ...]]] = [[] for _ in chunks]
    try:
        for fut in distributed.as_completed(futures):
            i = index[fut.key]
            out[i] = fut.result()
            bar.update(len(chunks[i]))
    finally:
        client.cancel([f for f in futures if not f.done()])
    return out


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


class _ProgressBar(tqdm):
    """tqdm without its monitor thread, so that no helper thread is alive (and copied
    half-way through a lock) when a fork-based pool passed as ``executor`` forks its workers."""

    monitor_interval = 0


def _progress_bar(total: int, progress: bool | None) -> _ProgressBar:
    """A text progress bar on stderr; by default shown in terminals and notebooks only."""
    interactive = sys.stderr.isatty() or "ipykernel" in sys.modules
    show = interactive if progress is None else bool(progress)
    return _ProgressBar(total=total, disable=not show, desc="sweep", unit="pt", file=sys.stderr)


def _execute(
    func: Callable[..., Any],
    pts: list[dict[str, Any]],
    executor: Any,
    chunksize: int | None,
    progress: bool | None,
    columns: bool,
) -> tuple[list[tuple[Any, ...]], str]:
    """Run ``func(**point)`` for every point on ``executor``; outcomes in input order."""
    kind = _classify_executor(executor)
    if kind == "pool" or isinstance(executor, ProcessPoolExecutor):
        _check_picklable(func, pts, pickle.dumps, "worker processes")
    elif kind == "dask":
        _check_picklable(func, pts, _require_distributed("dask").protocol.pickle.dumps, "Dask workers")
    with _progress_bar(len(pts), progress) as bar:
        if kind == "serial":
            description = "serial"
            outcomes = []
            for point in pts:
                outcomes.append(_run_point(func, point, columns))
                bar.update(1)
        elif kind == "pool":
            n_workers = _cpu_count() if executor is None else int(executor)
            size = chunksize or _auto_chunksize(len(pts), n_workers)
            chunks = _chunks(pts, size)
            description = f"processes({n_workers})"
            with _process_pool(min(n_workers, len(chunks))) as pool:
                try:
                    outcomes = list(
                        itertools.chain.from_iterable(_run_on_futures_executor(pool, func, chunks, bar, columns))
                    )
                except BaseException:
                    pool.shutdown(wait=True, cancel_futures=True)
                    raise
        elif kind == "executor":
            n_workers = getattr(executor, "_max_workers", None) or _cpu_count()
            chunks = _chunks(pts, chunksize or _auto_chunksize(len(pts), n_workers))
            description = f"executor({type(executor).__name__})"
            outcomes = list(
                itertools.chain.from_iterable(_run_on_futures_executor(executor, func, chunks, bar, columns))
            )
        else:
            with _dask_client(executor) as (client, description):
                n_workers = sum(client.nthreads().values()) or 1
                chunks = _chunks(pts, chunksize or _auto_chunksize(len(pts), n_workers))
                outcomes = list(itertools.chain.from_iterable(_run_on_dask(client, func, chunks, bar, columns)))
    return outcomes, description


def sweep(
    func: Callable[..., Any],
    points: Sequence[Mapping[str, Any]],
    executor: Any = None,
    *,
    chunksize: int | None = None,
    progress: bool | None = None,
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
        Points per task; by default about four tasks per worker.
    progress : bool, optional
        Show a tqdm progress bar on stderr. By default only when stderr is a terminal
        or the code runs in a Jupyter kernel, so logs and batch jobs stay clean.

    Returns
    -------
    SweepResult
        One row per point, in input order. The same for every executor.

    Raises
    ------
    ParameterError
        If ``func`` is not callable or cannot be pickled for the chosen executor, if
        ``points`` is not a non-empty sequence of dicts with string keys, or if
        ``executor`` or ``chunksize`` is not one of the accepted values.

    Notes
    -----
    A point whose call raises an ``Exception`` becomes a :class:`PointFailure` (type,
    message and traceback) and a row with ``status == "error"``. Failures of the
    machinery itself (a worker process killed, a lost scheduler) are raised.
    """
    if not callable(func):
        raise ParameterError("func", "callable", func)
    if isinstance(points, (Mapping, str, bytes)) or not isinstance(points, Sequence):
        raise ParameterError("points", "a sequence of dicts, e.g. nrobust.grid(K=[...], delta=[...])", points)
    if len(points) == 0:
        raise ParameterError("points", "a non-empty sequence of dicts", points)
    for i, point in enumerate(points):
        if not isinstance(point, Mapping) or not all(isinstance(k, str) for k in point):
            raise ParameterError(f"points[{i}]", "a dict with string keys", point)
    if chunksize is not None:
        if isinstance(chunksize, bool) or not isinstance(chunksize, (int, np.integer)) or chunksize < 1:
            raise ParameterError("chunksize", "a positive int or None", chunksize)
        chunksize = int(chunksize)
    pts = [dict(p) for p in points]
    start = time.perf_counter()
    outcomes, description = _execute(func, pts, executor, chunksize, progress, columns=True)
    elapsed = time.perf_counter() - start

    results: list[dict[str, Any] | None] = []
    failures: list[PointFailure] = []
    for i, (point, outcome) in enumerate(zip(pts, outcomes)):
        if outcome[0] == "ok":
            results.append(outcome[1])
        else:
            results.append(None)
            failures.append(PointFailure(i, point, outcome[1], outcome[2], outcome[3]))
    return SweepResult(tuple(pts), tuple(results), tuple(failures), description, elapsed)


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
