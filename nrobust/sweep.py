"""Parameter sweeps and Monte Carlo robustness studies, serial, on local processes or on Dask.

:func:`sweep` calls ``func(**point)`` for every point of a grid (:func:`grid`) or of a
sample set (a list of dicts) and gathers the outcomes in a :class:`SweepResult`: one row
per point, in input order, whatever executed it. A point whose call raises is recorded
with the exception type and message, never dropped.

:func:`robustness` is a Monte Carlo study of the delay margin and the decay rate of a
closed loop whose plant parameters are uncertain; :func:`run_sweep_file` runs a sweep or
a Monte Carlo study described by a ``SWEEP.toml`` file and writes its table and chart.
See ``docs/sweeps.md``.
"""

from __future__ import annotations

import csv
import importlib
import inspect
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
from tqdm import tqdm

from ._json import json_safe
from .errors import ParameterError, SweepError

__all__ = [
    "ANALYSES",
    "PointFailure",
    "RobustnessResult",
    "SweepFileResult",
    "SweepMap",
    "SweepResult",
    "grid",
    "margin_and_decay",
    "robustness",
    "run_sweep_file",
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

    Mappings and objects with ``to_dict()`` give dotted names, complex numbers give
    ``.real`` and ``.imag`` columns, sequences are stored as a JSON string, any other
    object as its ``repr``.
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
        _flatten(value.to_dict(), prefix, out)
    elif isinstance(value, (list, tuple, np.ndarray)):
        out[prefix] = json.dumps(json_safe(value))
    else:
        out[prefix] = repr(value)


def _result_columns(value: Any) -> dict[str, Any]:
    """The flat columns of one return value of the swept function."""
    if callable(getattr(value, "to_dict", None)) and not isinstance(value, (Mapping, type)):
        value = value.to_dict()
    if not isinstance(value, Mapping):
        raise TypeError(
            "the swept function must return a dict of scalars or an object with to_dict(), "
            f"got {type(value).__name__}"
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


def _run_chunk(func: Callable[..., Any], chunk: Sequence[Mapping[str, Any]], columns: bool = True) -> list[tuple[Any, ...]]:
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
        return {"index": self.index, "point": point, "type": self.type, "message": self.message,
                "traceback": self.traceback}


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

        Non-finite floats stay Python floats here; :meth:`to_json` writes them as the
        strings ``"inf"``, ``"-inf"`` and ``"nan"`` so that the file is strict JSON.
        """
        return {
            "columns": list(self.columns),
            "rows": self.records(),
            "failures": [f.to_dict() for f in self.failures],
            "n_points": len(self.points),
            "n_ok": self.n_ok,
            "n_failed": self.n_failed,
            "executor": self.executor,
            "elapsed": self.elapsed,
        }

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


def _check_picklable(func: Callable[..., Any], points: Sequence[Any], dumps: Callable[[Any], bytes], where: str) -> None:
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
        raise ParameterError(
            "points", f"picklable to be sent to {where} [{type(exc).__name__}: {exc}]"
        ) from exc


def _chunks(points: Sequence[Mapping[str, Any]], size: int) -> list[list[Mapping[str, Any]]]:
    return [list(points[i:i + size]) for i in range(0, len(points), size)]


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
        yield executor, f"dask({executor.scheduler.address})"
        return
    distributed = _require_distributed(str(executor))
    if executor == "dask":
        with distributed.LocalCluster(
            n_workers=_cpu_count(), threads_per_worker=1, processes=True,
            dashboard_address=":0", silence_logs=logging.ERROR,
        ) as cluster, distributed.Client(cluster) as client:
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
    half-way through a lock) when the process pool forks its workers."""

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
            with ProcessPoolExecutor(max_workers=min(n_workers, len(chunks))) as pool:
                try:
                    outcomes = list(itertools.chain.from_iterable(_run_on_futures_executor(pool, func, chunks, bar, columns)))
                except BaseException:
                    pool.shutdown(wait=True, cancel_futures=True)
                    raise
        elif kind == "executor":
            n_workers = getattr(executor, "_max_workers", None) or _cpu_count()
            chunks = _chunks(pts, chunksize or _auto_chunksize(len(pts), n_workers))
            description = f"executor({type(executor).__name__})"
            outcomes = list(itertools.chain.from_iterable(_run_on_futures_executor(executor, func, chunks, bar, columns)))
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


def _abscissa_value(result: Any) -> float:
    """The number held by a spectral-abscissa result (a float or a result with ``.value``)."""
    if isinstance(result, (int, float, np.floating)):
        return float(result)
    return float(result.value)


#: Where analyses, systems and controllers are looked up by name, in this order.
_NAMESPACES = ("nrobust", "nrobust.hyperbolic", "nrobust.margins", "nrobust.roots")


def _nrobust_function(name: str) -> Callable[..., Any]:
    """``nrobust.<name>`` (or the same name in a subpackage), looked up when an analysis runs."""
    for module in _NAMESPACES:
        try:
            found = getattr(importlib.import_module(module), name, None)
        except ImportError:
            continue
        if found is not None:
            return found
    raise ParameterError("analysis", f"an analysis this installation provides (nrobust.{name} is missing)", name)


def margin_and_decay(system: Any, controller: Any) -> dict[str, float]:
    """Delay margin and decay rate of one closed loop: the default analysis of :func:`robustness`.

    Parameters
    ----------
    system : Hyperbolic2x2 or TransportSystem
        The plant.
    controller : controller object
        The feedback law (``ReflectionController(K)``, ...).

    Returns
    -------
    dict
        ``delta_star`` (the ``margin`` of ``nrobust.delay_margin(system, controller)``;
        ``inf`` when every delay is tolerated, 0 when an arbitrarily small delay
        destabilises), ``abscissa`` (spectral abscissa of the delay-free characteristic
        function ``nrobust.characteristic(system, controller, 0.0)``) and
        ``decay_rate = -abscissa``.
    """
    margin = _nrobust_function("delay_margin")(system, controller)
    characteristic = _nrobust_function("characteristic")(system, controller, 0.0)
    abscissa = _abscissa_value(_nrobust_function("spectral_abscissa")(characteristic))
    return {"delta_star": float(margin.margin), "abscissa": abscissa, "decay_rate": -abscissa}


@dataclass(frozen=True)
class _SampleTask:
    """One Monte Carlo sample: draw a system from its own stream and analyse it."""

    sample_system: Callable[[np.random.Generator], Any]
    controller: Any
    analysis: Callable[[Any, Any], Any]
    entropy: int

    def __call__(self, sample: int) -> dict[str, Any]:
        rng = np.random.default_rng(np.random.SeedSequence(self.entropy, spawn_key=(sample,)))
        system = self.sample_system(rng)
        out: dict[str, Any] = {}
        if callable(getattr(system, "to_dict", None)):
            _flatten(system.to_dict(), "system", out)
        out.update(_result_columns(self.analysis(system, self.controller)))
        return out


def _quantile_summary(result: SweepResult, levels: tuple[float, ...], skip: Sequence[str] = ()) -> dict[str, tuple[float, ...]]:
    """Empirical quantiles (``inverted_cdf``: always a sample value, so ``inf`` is exact)
    of every numeric result column over the rows that succeeded, NaN values left out."""
    out: dict[str, tuple[float, ...]] = {}
    rows = [r for r in result.results if r is not None]
    names = result._result_names()
    for key, col in names.items():
        if col in skip:
            continue
        vals = [r.get(key) for r in rows]
        if not vals or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals):
            continue
        arr = np.asarray(vals, dtype=float)
        arr = arr[~np.isnan(arr)]
        if arr.size:
            out[col] = tuple(float(x) for x in np.quantile(arr, levels, method="inverted_cdf"))
    return out


def _check_levels(levels: Sequence[float]) -> tuple[float, ...]:
    try:
        out = tuple(float(x) for x in levels)
    except (TypeError, ValueError):
        raise ParameterError("levels", "a sequence of numbers in [0, 1]", levels) from None
    if not out or not all(0.0 <= x <= 1.0 for x in out):
        raise ParameterError("levels", "a non-empty sequence of numbers in [0, 1]", levels)
    return out


@dataclass(frozen=True)
class RobustnessResult:
    """Outcome of :func:`robustness`.

    Attributes
    ----------
    levels : tuple of float
        The quantile levels.
    quantiles : dict of str to tuple of float
        Per numeric column (``delta_star``, ``decay_rate``, ``abscissa``, sampled system
        parameters ``system.<name>``, ...), the empirical quantiles at ``levels`` over the
        samples that succeeded. A quantile is always one of the sampled values, so an
        infinite delay margin gives an exact ``inf``.
    n_samples : int
        Number of samples drawn.
    n_failed : int
        Samples whose draw or analysis raised (see ``sweep.failures``).
    seed : int
        Entropy of the root ``numpy.random.SeedSequence``; sample ``i`` used
        ``default_rng(SeedSequence(seed).spawn(n_samples)[i])``.
    sweep : SweepResult
        The per-sample table (column ``sample``, the flattened ``system.to_dict()`` and
        the analysis results).
    """

    levels: tuple[float, ...]
    quantiles: dict[str, tuple[float, ...]]
    n_samples: int
    n_failed: int
    seed: int
    sweep: SweepResult

    def quantile(self, column: str, level: float) -> float:
        """The quantile of ``column`` at one of :attr:`levels`."""
        if column not in self.quantiles:
            raise ParameterError("column", f"one of {sorted(self.quantiles)}", column)
        for lev, val in zip(self.levels, self.quantiles[column]):
            if math.isclose(lev, level):
                return val
        raise ParameterError("level", f"one of {list(self.levels)}", level)

    def to_dict(self) -> dict[str, Any]:
        """Dict of the study (quantiles, counts, seed and the per-sample table)."""
        return {
            "levels": list(self.levels),
            "quantiles": {k: list(v) for k, v in self.quantiles.items()},
            "n_samples": self.n_samples,
            "n_failed": self.n_failed,
            "seed": self.seed,
            "sweep": self.sweep.to_dict(),
        }

    def __repr__(self) -> str:
        width = max([len(c) for c in self.quantiles] + [6]) + 2
        head = "".join(f"{f'q{lev:g}':>11}" for lev in self.levels)
        lines = [f"RobustnessResult({self.n_samples} samples, {self.n_failed} failed, seed={self.seed})",
                 f"  {'':<{width}}{head}"]
        for col, vals in self.quantiles.items():
            lines.append(f"  {col:<{width}}" + "".join(f"{v:>11.4g}" for v in vals))
        return "\n".join(lines)


def robustness(
    sample_system: Callable[[np.random.Generator], Any],
    controller: Any,
    n_samples: int,
    seed: int | None = 0,
    executor: Any = None,
    *,
    analysis: Callable[[Any, Any], Any] | None = None,
    levels: Sequence[float] = (0.05, 0.25, 0.5, 0.75, 0.95),
    chunksize: int | None = None,
    progress: bool | None = None,
) -> RobustnessResult:
    """Monte Carlo study of the delay margin and decay rate under uncertain parameters.

    Parameters
    ----------
    sample_system : callable
        ``sample_system(rng) -> system`` draws one plant with the
        ``numpy.random.Generator`` it is given, e.g.
        ``lambda rng: TransportSystem(1.0, 1.0, q=0.8, rho=rng.uniform(0.3, 0.5))``
        (with process pools, a module-level function or a ``functools.partial``).
    controller : controller object
        The feedback law under study, the same for every sample.
    n_samples : int
        Number of samples, >= 1.
    seed : int or None, optional
        Entropy of the root ``numpy.random.SeedSequence``. Sample ``i`` draws from
        ``default_rng(SeedSequence(seed).spawn(n_samples)[i])``, so results do not depend
        on the executor and the first samples of a larger study equal a smaller one.
        ``None`` draws fresh entropy, reported in the result.
    executor : optional
        As in :func:`sweep`.
    analysis : callable, optional
        ``analysis(system, controller) -> dict`` (or an object with ``to_dict()``) per
        sample; by default :func:`margin_and_decay` (``delta_star``, ``abscissa``,
        ``decay_rate``).
    levels : sequence of float, optional
        Quantile levels in [0, 1].
    chunksize, progress : optional
        As in :func:`sweep`.

    Returns
    -------
    RobustnessResult
        Quantiles of every numeric column and the per-sample table. Samples whose draw
        or analysis raised are recorded in ``result.sweep.failures`` and left out of the
        quantiles.
    """
    if not callable(sample_system):
        raise ParameterError("sample_system", "a callable rng -> system", sample_system)
    if analysis is not None and not callable(analysis):
        raise ParameterError("analysis", "a callable (system, controller) -> dict", analysis)
    n = int(n_samples) if isinstance(n_samples, (int, np.integer)) and not isinstance(n_samples, bool) else None
    if n is None or n < 1:
        raise ParameterError("n_samples", "an integer >= 1", n_samples)
    if seed is None:
        seed = int(np.random.SeedSequence().entropy)
    elif isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ParameterError("seed", "a non-negative int or None", seed)
    lev = _check_levels(levels)
    task = _SampleTask(sample_system, controller, analysis or margin_and_decay, int(seed))
    try:
        result = sweep(task, [{"sample": i} for i in range(n)], executor, chunksize=chunksize, progress=progress)
    except ParameterError as exc:
        if exc.name != "func":
            raise
        for name in ("sample_system", "controller", "analysis"):
            try:
                pickle.dumps(getattr(task, name))
            except Exception:
                raise ParameterError(name, exc.requirement, getattr(task, name)) from exc
        raise
    return RobustnessResult(lev, _quantile_summary(result, lev), n, result.n_failed, int(seed), result)


# ---------------------------------------------------------------------------------------
# SWEEP.toml
# ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Analysis:
    """An analysis of ``run_sweep_file``: the nrobust function it calls and its result columns.

    ``target`` is looked up by name when the analysis runs. With ``n_positional == 2`` it
    is called as ``target(system, controller, **options)``; with ``n_positional == 1`` as
    ``target(characteristic(system, controller, delta), **options)``, the loop delay
    ``delta`` (default 0) being one of the options in ``own``. The options are the keyword
    parameters of ``target`` after its ``n_positional`` first ones, plus ``own``.
    """

    target: str
    n_positional: int
    own: tuple[str, ...]
    columns: Callable[[Any], dict[str, Any]]

    def options(self) -> set[str] | None:
        """Accepted option names (``None``: any, the target takes ``**kwargs``)."""
        params = list(inspect.signature(_nrobust_function(self.target)).parameters.values())
        if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params):
            return None
        kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
        return {p.name for p in params[self.n_positional:] if p.kind in kinds} | set(self.own)

    def __call__(self, system: Any, controller: Any, **options: Any) -> dict[str, Any]:
        fn = _nrobust_function(self.target)
        if self.n_positional == 1:
            delta = options.pop("delta", 0.0)
            value = fn(_nrobust_function("characteristic")(system, controller, delta), **options)
        else:
            value = fn(system, controller, **options)
        return self.columns(value)


def _margin_columns(result: Any) -> dict[str, Any]:
    return {"delta_star": float(result.margin), "nominal_stable": bool(result.nominal_stable),
            "strongly_stable": bool(result.strongly_stable), "verified": bool(result.verified)}


def _abscissa_columns(result: Any) -> dict[str, Any]:
    value = _abscissa_value(result)
    return {"abscissa": value, "decay_rate": -value}


#: Analyses that ``run_sweep_file`` knows by name. Each runs one nrobust function, looked
#: up in the ``nrobust`` namespace at call time, on the system and controller of a point.
ANALYSES: dict[str, _Analysis] = {
    "delay_margin": _Analysis("delay_margin", 2, (), _margin_columns),
    "spectral_abscissa": _Analysis("spectral_abscissa", 1, ("delta",), _abscissa_columns),
}
_SYSTEM_TYPES = ("TransportSystem", "Hyperbolic2x2")
_CONTROLLER_TYPES = ("OpenLoop", "FiniteTimeController", "ReflectionController", "FilteredController")
_TOP_KEYS = ("analysis", "system", "controller", "options", "grid", "sampling", "plot", "executor", "chunksize")
_DISTRIBUTIONS = ("uniform", "loguniform", "normal", "choice")


def _load_toml(path: Path) -> dict[str, Any]:
    if sys.version_info >= (3, 11):
        import tomllib
    else:
        import tomli as tomllib
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ParameterError("path", "an existing SWEEP.toml file", str(path)) from None
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError("path", f"a valid TOML file ({exc})", str(path)) from None


def _signature_names(cls: Any) -> tuple[set[str], set[str]]:
    """(all keyword parameter names, required ones) of a constructor."""
    params = inspect.signature(cls).parameters.values()
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    names = {p.name for p in params if p.kind in kinds}
    required = {p.name for p in params if p.kind in kinds and p.default is inspect.Parameter.empty}
    return names, required


def _typed_table(spec: dict[str, Any], section: str, types: tuple[str, ...]) -> tuple[str, dict[str, Any], set[str], set[str]]:
    table = spec.get(section)
    if not isinstance(table, dict):
        raise ParameterError(section, f"a [{section}] table with a 'type' key", table)
    kind = table.get("type")
    if kind not in types:
        raise ParameterError(f"{section}.type", f"one of {list(types)}", kind)
    names, required = _signature_names(_nrobust_function(kind))
    params = {k: v for k, v in table.items() if k != "type"}
    for key in params:
        if key not in names:
            raise ParameterError(f"{section}.{key}", f"a parameter of {kind}: one of {sorted(names)}", params[key])
    return kind, params, names, required


def _axis_values(name: str, value: Any) -> list[Any]:
    """A grid axis: a list, or a table ``{start, stop, num}`` (linspace, endpoints included,
    values rounded to 12 significant digits)."""
    if isinstance(value, list):
        if not value:
            raise ParameterError(name, "a non-empty list or {start, stop, num}", value)
        return value
    if isinstance(value, dict):
        if set(value) != {"start", "stop", "num"}:
            raise ParameterError(name, "a list or a table with exactly the keys start, stop, num", value)
        num = value["num"]
        if isinstance(num, bool) or not isinstance(num, int) or num < 1:
            raise ParameterError(f"{name}.num", "an integer >= 1", num)
        for key in ("start", "stop"):
            if isinstance(value[key], bool) or not isinstance(value[key], (int, float)):
                raise ParameterError(f"{name}.{key}", "a number", value[key])
        # 12 significant digits: 0.1 rather than 0.09999999999999999 in tables and charts
        return [float(f"{x:.12g}") for x in np.linspace(value["start"], value["stop"], num)]
    raise ParameterError(name, "a list of values or a table {start, stop, num}", value)


def _draw(dist: Any, rng: np.random.Generator) -> Any:
    """One draw of a ``[sampling.distributions]`` entry."""
    (kind, args), = dist.items()
    if kind == "choice":
        return args[int(rng.integers(len(args)))]
    lo, hi = float(args[0]), float(args[1])
    if kind == "uniform":
        return float(rng.uniform(lo, hi))
    if kind == "loguniform":
        return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
    return float(rng.normal(lo, hi))


def _check_distribution(name: str, dist: Any) -> None:
    if not isinstance(dist, dict) or len(dist) != 1 or next(iter(dist)) not in _DISTRIBUTIONS:
        raise ParameterError(name, f"a table with one key among {list(_DISTRIBUTIONS)}, e.g. {{uniform = [0.1, 0.3]}}", dist)
    (kind, args), = dist.items()
    if kind == "choice":
        if not isinstance(args, list) or not args:
            raise ParameterError(f"{name}.choice", "a non-empty list of values", args)
        return
    ok = isinstance(args, list) and len(args) == 2 and all(isinstance(a, (int, float)) and not isinstance(a, bool) for a in args)
    if not ok:
        raise ParameterError(f"{name}.{kind}", "a list of two numbers", args)
    if kind in ("uniform", "loguniform") and not args[0] < args[1]:
        raise ParameterError(f"{name}.{kind}", "[low, high] with low < high", args)
    if kind == "loguniform" and args[0] <= 0:
        raise ParameterError(f"{name}.{kind}", "[low, high] with 0 < low", args)
    if kind == "normal" and args[1] < 0:
        raise ParameterError(f"{name}.{kind}", "[mean, std] with std >= 0", args)


@dataclass(frozen=True)
class _FileAnalysis:
    """The per-point function of a SWEEP.toml: build the system and controller, run the analyses."""

    system_type: str
    system: dict[str, Any]
    controller_type: str
    controller: dict[str, Any]
    analyses: tuple[str, ...]
    options: dict[str, dict[str, Any]]
    routes: dict[str, str]

    def __call__(self, **point: Any) -> dict[str, Any]:
        sys_params = dict(self.system)
        ctl_params = dict(self.controller)
        opts = {name: dict(self.options.get(name, {})) for name in self.analyses}
        for key, value in point.items():
            route = self.routes[key]
            if route == "system":
                sys_params[key] = value
            elif route == "controller":
                ctl_params[key] = value
            else:
                for name in self.analyses:
                    allowed = ANALYSES[name].options()
                    if allowed is None or key in allowed:
                        opts[name][key] = value
        system = _nrobust_function(self.system_type)(**sys_params)
        controller = _nrobust_function(self.controller_type)(**ctl_params)
        out: dict[str, Any] = {}
        for name in self.analyses:
            out.update(ANALYSES[name](system, controller, **opts[name]))
        return out


@dataclass(frozen=True)
class SweepFileResult:
    """What :func:`run_sweep_file` wrote.

    Attributes
    ----------
    sweep : SweepResult
        The table.
    csv, json, png : pathlib.Path
        The files written.
    quantiles : dict
        For a ``[sampling]`` study, the quantiles per numeric result column (empty for
        a grid).
    levels : tuple of float
        Their levels.
    """

    sweep: SweepResult
    csv: Path
    json: Path
    png: Path
    quantiles: dict[str, tuple[float, ...]]
    levels: tuple[float, ...]

    def to_dict(self) -> dict[str, Any]:
        """Paths, quantiles and counts (the table itself is in the JSON file)."""
        return {"csv": str(self.csv), "json": str(self.json), "png": str(self.png),
                "n_points": len(self.sweep.points), "n_failed": self.sweep.n_failed,
                "levels": list(self.levels), "quantiles": {k: list(v) for k, v in self.quantiles.items()}}


def _route_names(keys: Sequence[str], section: str, sys_names: set[str], ctl_names: set[str],
                 option_names: set[str] | None) -> dict[str, str]:
    """Decide whether each swept or sampled name is a system, controller or analysis parameter."""
    routes = {}
    for key in keys:
        homes = [h for h, names in (("system", sys_names), ("controller", ctl_names)) if key in names]
        if (option_names is not None and key in option_names) or (option_names is None and not homes):
            homes.append("options")  # an analysis taking **kwargs receives the names no plant or controller takes
        if not homes:
            allowed = sorted(sys_names | ctl_names | (option_names or set()))
            raise ParameterError(f"{section}.{key}", f"a parameter of [system], [controller] or an analysis option: one of {allowed}", key)
        if len(homes) > 1:
            raise ParameterError(f"{section}.{key}", f"a name of exactly one of {homes}", key)
        routes[key] = homes[0]
    return routes


def run_sweep_file(path: str | os.PathLike[str], out_dir: str | os.PathLike[str], dask_address: str | None = None,
                   *, progress: bool | None = None) -> SweepFileResult:
    """Run the sweep or Monte Carlo study described by a SWEEP.toml file.

    Parameters
    ----------
    path : path-like
        The TOML file; its schema is in ``docs/sweeps.md``.
    out_dir : path-like
        Directory for ``sweep.csv``, ``sweep.json`` and ``sweep.png`` (created if
        needed).
    dask_address : str, optional
        Address of a Dask scheduler (``"tcp://scheduler:8786"``, or ``"scheduler:8786"``
        for TCP); overrides the file's ``executor``.
    progress : bool, optional
        As in :func:`sweep`.

    Returns
    -------
    SweepFileResult
        The table, the paths written and, for ``[sampling]``, the quantiles.

    Raises
    ------
    ParameterError
        Naming the bad key (``grid.K``, ``system.type``, ``options.delay_margin.foo``,
        ...) when the file does not follow the schema.
    """
    path = Path(path)
    spec = _load_toml(path)
    for key in spec:
        if key not in _TOP_KEYS:
            raise ParameterError(key, f"a top-level key of SWEEP.toml: one of {list(_TOP_KEYS)}", spec[key])

    names = spec.get("analysis", "delay_margin")
    names = [names] if isinstance(names, str) else names
    if not isinstance(names, list) or not names or any(n not in ANALYSES for n in names):
        raise ParameterError("analysis", f"an analysis name or a list of them among {sorted(ANALYSES)}", spec.get("analysis"))
    analyses = tuple(dict.fromkeys(names))

    sys_type, sys_params, sys_names, sys_required = _typed_table(spec, "system", _SYSTEM_TYPES)
    ctl_type, ctl_params, ctl_names, ctl_required = _typed_table(spec, "controller", _CONTROLLER_TYPES)

    options = spec.get("options", {})
    if not isinstance(options, dict):
        raise ParameterError("options", "a table of [options.<analysis>] tables", options)
    accepted: dict[str, set[str] | None] = {name: ANALYSES[name].options() for name in analyses}
    for name, table in options.items():
        if name not in analyses:
            raise ParameterError(f"options.{name}", f"options of a selected analysis: one of {list(analyses)}", table)
        if not isinstance(table, dict):
            raise ParameterError(f"options.{name}", "a table of keyword options", table)
        for key in table:
            allowed = accepted[name]
            if allowed is not None and key not in allowed:
                raise ParameterError(f"options.{name}.{key}", f"an option of {name}: one of {sorted(allowed)}", table[key])
    option_names: set[str] | None = set()
    for allowed in accepted.values():
        option_names = None if (allowed is None or option_names is None) else option_names | allowed

    has_grid, has_sampling = "grid" in spec, "sampling" in spec
    if has_grid == has_sampling:
        raise ParameterError("grid", "given, or [sampling] given instead (exactly one of the two)")
    levels: tuple[float, ...] = ()
    if has_grid:
        table = spec["grid"]
        if not isinstance(table, dict) or not table:
            raise ParameterError("grid", "a non-empty table name = [values]", table)
        routes = _route_names(list(table), "grid", sys_names, ctl_names, option_names)
        points = grid(**{k: _axis_values(f"grid.{k}", v) for k, v in table.items()})
    else:
        table = spec["sampling"]
        if not isinstance(table, dict):
            raise ParameterError("sampling", "a table with n_samples, seed and [sampling.distributions]", table)
        for key in table:
            if key not in ("n_samples", "seed", "levels", "distributions"):
                raise ParameterError(f"sampling.{key}", "one of n_samples, seed, levels, distributions", table[key])
        n = table.get("n_samples")
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ParameterError("sampling.n_samples", "an integer >= 1", n)
        seed = table.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ParameterError("sampling.seed", "a non-negative integer", seed)
        try:
            levels = _check_levels(table.get("levels", (0.05, 0.25, 0.5, 0.75, 0.95)))
        except ParameterError as exc:
            raise ParameterError("sampling.levels", exc.requirement, exc.value) from None
        dists = table.get("distributions")
        if not isinstance(dists, dict) or not dists:
            raise ParameterError("sampling.distributions", "a non-empty table name = {uniform = [low, high]}", dists)
        for key, dist in dists.items():
            _check_distribution(f"sampling.distributions.{key}", dist)
        routes = _route_names(list(dists), "sampling.distributions", sys_names, ctl_names, option_names)
        rng = np.random.default_rng(seed)
        points = [{k: _draw(d, rng) for k, d in dists.items()} for _ in range(n)]

    for section, required, given in (("system", sys_required, sys_params), ("controller", ctl_required, ctl_params)):
        for name in sorted(required):
            if name not in given and routes.get(name) != section:
                raise ParameterError(f"{section}.{name}", f"given in [{section}] or swept in [grid] / [sampling]")

    if dask_address is not None:
        if not isinstance(dask_address, str) or ":" not in dask_address:
            raise ParameterError("dask_address", "a Dask scheduler address such as 'tcp://scheduler:8786'", dask_address)
        executor: Any = dask_address if dask_address.startswith(_DASK_SCHEMES) else f"tcp://{dask_address}"
    else:
        executor = spec.get("executor")
        _classify_executor(executor)
    chunksize = spec.get("chunksize")
    if chunksize is not None and (isinstance(chunksize, bool) or not isinstance(chunksize, int) or chunksize < 1):
        raise ParameterError("chunksize", "a positive integer", chunksize)

    plot = spec.get("plot", {})
    if not isinstance(plot, dict) or any(k not in ("x", "y") for k in plot):
        raise ParameterError("plot", "a table with optional keys x and y", plot)

    func = _FileAnalysis(sys_type, sys_params, ctl_type, ctl_params, analyses,
                         {k: dict(v) for k, v in options.items()}, routes)
    result = sweep(func, points, executor, chunksize=chunksize, progress=progress)
    quantiles = _quantile_summary(result, levels, skip=list(routes)) if has_sampling else {}

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    csv_path = result.to_csv(out / "sweep.csv")
    extra = {"source": str(path), "levels": list(levels), "quantiles": {k: list(v) for k, v in quantiles.items()}}
    json_path = result.to_json(out / "sweep.json", extra=extra if has_sampling else {"source": str(path)})
    png_path = _chart(result, list(routes), plot, has_sampling, out / "sweep.png")
    return SweepFileResult(result, csv_path, json_path, png_path, quantiles, levels)


def _chart(result: SweepResult, swept: list[str], plot: dict[str, str], sampling: bool, path: Path) -> Path:
    """Draw the sweep: a curve for one swept name, a map for two, histograms for samples."""
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    table = result.table()
    numeric = [c for c in result.result_columns if table.dtype[c].kind == "f"]
    y = plot.get("y", numeric[0] if numeric else None)
    if y is not None and y not in numeric:
        raise ParameterError("plot.y", f"a numeric result column: one of {numeric}", y)
    varying = [k for k in swept if len({repr(p.get(k)) for p in result.points}) > 1]
    x = plot.get("x", varying[0] if varying else (swept[0] if swept else None))
    if x is not None and x not in result.parameter_columns:
        raise ParameterError("plot.x", f"a swept parameter: one of {list(result.parameter_columns)}", x)

    ok = table["status"] == "ok"
    title = f"{result.n_ok} ok, {result.n_failed} failed"
    if sampling and y is not None:
        shown = [y, *[c for c in numeric if c != y]][:3]
        fig = Figure(figsize=(4.0 * len(shown), 3.6), layout="constrained")
        FigureCanvasAgg(fig)
        for i, col in enumerate(shown):
            ax = fig.add_subplot(1, len(shown), i + 1)
            vals = table[col][ok]
            finite = vals[np.isfinite(vals)]
            n_inf = int(np.sum(np.isposinf(vals)))
            if finite.size:
                ax.hist(finite, bins=max(5, min(50, 2 * int(np.sqrt(finite.size)))), color="C0")
            else:
                ax.text(0.5, 0.5, f"no finite {col}", ha="center", va="center", transform=ax.transAxes)
            ax.set_xlabel(col)
            ax.set_ylabel("samples")
            ax.set_title(f"{n_inf} infinite" if n_inf else "", fontsize="small")
        fig.suptitle(title, fontsize="medium")
        fig.savefig(path, dpi=120)
        return path
    fig = Figure(figsize=(6.4, 4.4), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    if y is None:
        ax.text(0.5, 0.5, "no numeric result", ha="center", va="center", transform=ax.transAxes)
    elif x is not None and table.dtype[x].kind in "fiu" and len(varying) == 2 and table.dtype[varying[1]].kind in "fiu":
        x2 = varying[1] if x == varying[0] else varying[0]
        xs, ys = np.unique(table[x]), np.unique(table[x2])
        grid_vals = np.full((ys.size, xs.size), np.nan)
        for row in table[ok]:
            grid_vals[np.searchsorted(ys, row[x2]), np.searchsorted(xs, row[x])] = row[y]
        finite = grid_vals[np.isfinite(grid_vals)]
        top = finite.max() if finite.size else 1.0
        cmap = matplotlib.colormaps["viridis"].with_extremes(over="gold", bad="lightgray")
        shown = np.where(np.isposinf(grid_vals), top + 1.0, grid_vals)
        mesh = ax.pcolormesh(xs, ys, np.ma.masked_invalid(shown), shading="nearest", cmap=cmap,
                             vmin=finite.min() if finite.size else 0.0, vmax=top)
        fig.colorbar(mesh, ax=ax, label=y, extend="max" if np.isposinf(grid_vals).any() else "neither")
        ax.set_xlabel(x)
        ax.set_ylabel(x2)
        title += " (gold: inf, gray: failed)"
    elif x is not None and table.dtype[x].kind in "fiu":
        xv, yv = table[x][ok].astype(float), table[y][ok]
        fin = np.isfinite(yv)
        order = np.argsort(xv[fin], kind="stable")
        ax.plot(xv[fin][order], yv[fin][order], "o-", ms=3, label=y)
        edge = ax.get_xaxis_transform()  # x in data, y in axes units: markers on the frame
        if (~fin).any():
            ax.plot(xv[~fin], np.full((~fin).sum(), 0.97), "^", color="C1", transform=edge, label=f"{y} = inf")
        if (~ok).any():
            ax.plot(table[x][~ok].astype(float), np.full((~ok).sum(), 0.03), "x", color="C3", transform=edge,
                    label="failed")
        ax.set_xlabel(x)
        ax.set_ylabel(y)
        ax.legend(loc="best", fontsize="small")
    else:
        yv = table[y]
        ax.plot(np.arange(len(yv))[ok], yv[ok], "o", ms=3)
        ax.set_xlabel("point index")
        ax.set_ylabel(y)
    ax.set_title(title, fontsize="medium")
    fig.savefig(path, dpi=120)
    return path
