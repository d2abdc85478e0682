"""Parameter sweeps: :func:`sweep` runs a function over a grid or a sample set.

:func:`sweep` calls ``func(**point)`` for every point of a grid (:func:`~nrobust.sweeps.grid`)
or of a sample set (a list of dicts) on an executor of :mod:`nrobust.sweeps.executors` and
gathers the outcomes in a :class:`~nrobust.sweeps.SweepResult`: one row per point, in input
order, whatever executed it. A point whose call raises is recorded with the exception type
and message, never dropped. This module checks the sweep's size before it runs, journals
finished points (:mod:`nrobust.sweeps.journal`) and resumes from the journal. See
``docs/sweeps.md``.
"""

from __future__ import annotations

import logging
import math
import os
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ParameterError
from .executors import classify_executor, execute
from .grids import Grid
from .journal import Journal, definition_hash, describe
from .result import PointFailure, SweepResult, result_columns

__all__ = ["MAX_POINTS", "SweepInterrupted", "sweep"]

#: Default cap on the number of points of one sweep (``max_points=``): about 1 GB of
#: points and results in memory at the measured ~1 kB per point of a typical analysis.
MAX_POINTS = 1_000_000


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

_LOG = logging.getLogger(__name__)


def _resume_note(journal: Journal | None, kept: int, total: int) -> str:
    """``"resumed: kept N of M points from JOURNAL"`` for a sweep that read its journal; ``""`` otherwise."""
    if journal is None or not journal.resumed:
        return ""
    retried = len(journal.done) - kept
    again = f" ({retried} timed out or lost, run again)" if retried else ""
    return f"resumed: kept {kept} of {total} points from {journal.path}{again}"


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
        A grid (:func:`~nrobust.sweeps.grids.grid`) or a sample set: dicts with string keys.
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
        are retried), the result's ``resumed`` says ``"resumed: kept N of M points from
        JOURNAL"`` and the logger ``nrobust.sweeps.engine`` logs it (level INFO); a
        journal of another sweep is refused.
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
    classify_executor(executor)
    pts = [dict(p) for p in points]
    definition = None if results is None else _definition(func, points if isinstance(points, Grid) else pts)
    journal = None if results is None else Journal(results, definition, len(pts), restart)
    done = (
        {} if journal is None else {i: o for i, o in journal.done.items() if not (o[0] == "error" and o[1] in _RETRIED)}
    )
    resumed = _resume_note(journal, len(done), len(pts))
    if resumed:
        _LOG.info(resumed)
    todo = [i for i in range(len(pts)) if i not in done]
    finished = [len(done)]

    def record(position: int, outcome: tuple[Any, ...]) -> None:
        finished[0] += 1
        if journal is not None:
            journal.append(todo[position], outcome)

    start = time.perf_counter()
    try:
        if todo:
            fresh, description = execute(
                func,
                [pts[i] for i in todo],
                executor,
                chunksize,
                progress,
                convert=result_columns,
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
    return SweepResult(tuple(pts), tuple(rows), tuple(failures), description, elapsed, resumed)
