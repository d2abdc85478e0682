"""Where the points of a sweep run: serially, on local process pools, on any Executor or on Dask.

:func:`execute` calls ``func(**point)`` for every point on the executor named by its
argument (:func:`classify_executor`) and returns the outcomes in input order. The local
pools are nrobust's own: one BLAS thread per worker, workers that end when the sweep
process ends (even by SIGKILL), Ctrl-C handled by the parent, and, with a timeout, each
point run in a forked process that dies with its parent (``PR_SET_PDEATHSIG``), so that no
hung point outlives the sweep. :func:`sweep_map` is a
``map`` on the same executors: the analyses of the PDE layer take it as ``executor=``.
This module sits in the runtime layer (below the PDE layer, which imports it): it imports
only nrobust's base modules.
"""

from __future__ import annotations

import ctypes
import itertools
import logging
import math
import os
import pickle
import select
import signal
import sys
import threading
import time
import traceback
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeAlias

from threadpoolctl import threadpool_limits

from .._progress import progress_bar
from ..errors import ParameterError, SweepError

if TYPE_CHECKING:
    from .._progress import HiddenBar, ProgressBar

__all__ = ["DASK_SCHEMES", "SweepMap", "classify_executor", "cpu_count", "execute", "sweep_map"]

#: The scheduler address schemes that name a Dask executor (``"tcp://host:8786"``).
DASK_SCHEMES = ("tcp://", "tls://", "ucx://", "inproc://", "ws://", "wss://")
_EXECUTOR_REQUIREMENT = (
    "None (local processes on all cores), 'serial', 'dask', a scheduler address "
    "('tcp://host:8786'), a positive int (number of processes), a "
    "concurrent.futures.Executor or a dask.distributed.Client"
)

#: What a worker applies to a point's return value before sending it back (None: nothing).
Convert: TypeAlias = Callable[[Any], Any] | None

# ---------------------------------------------------------------------------------------
# running points (these run on the workers)
# ---------------------------------------------------------------------------------------


def _run_point(func: Callable[..., Any], point: Mapping[str, Any], convert: Convert = None) -> tuple[Any, ...]:
    """Call ``func(**point)``: ``("ok", result)`` or ``("error", type, message, traceback)``.

    With ``convert`` the result is converted on the worker (a sweep flattens it into table
    columns there); a conversion that raises is the point's failure.
    """
    try:
        result = func(**point)
        return ("ok", result if convert is None else convert(result))
    except Exception as exc:
        return ("error", type(exc).__name__, str(exc), traceback.format_exc())


def _run_chunk(
    func: Callable[..., Any], chunk: Sequence[Mapping[str, Any]], convert: Convert = None
) -> list[tuple[Any, ...]]:
    """Run consecutive points on one worker; one task per chunk amortises the transfer."""
    return [_run_point(func, point, convert) for point in chunk]


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
    func: Callable[..., Any], points: Sequence[Mapping[str, Any]], convert: Convert, fd: int, parent: int
) -> None:
    """Body of a forked point process: run the points, send each outcome as a frame, exit."""
    code = 0
    try:
        _die_with_parent(parent)
        with os.fdopen(fd, "wb") as pipe:
            for point in points:
                outcome = _run_point(func, point, convert)
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
    convert: Convert,
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
            _point_process(func, chunk[len(outcomes) :], convert, write_fd, parent)
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
# executors
# ---------------------------------------------------------------------------------------


def cpu_count() -> int:
    """Cores this process may use."""
    if hasattr(os, "processcpu_count"):
        return os.processcpu_count() or 1
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0)) or 1
    return os.cpu_count() or 1


def _start_time(pid: int) -> str | None:
    """When process ``pid`` started (field 22 of ``/proc/<pid>/stat``, clock ticks since boot).

    With the process id it names one process for good: a process id is reused, the pair
    is not. None where ``/proc`` cannot tell (no such process, not Linux).
    """
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as stat:
            text = stat.read()
    except OSError:
        return None
    return text[text.rindex(")") + 2 :].split()[19]  # fields 3.. follow the name in parentheses


def _exit_with_the_sweep() -> None:
    """The sweep is gone: kill this worker's point processes and leave at once."""
    for pid in list(_CHILDREN):
        with suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    os._exit(1)


def _watch_sweep(sweep: int, sweep_start: str | None) -> None:
    """In a pool worker: leave as soon as the sweep process ``sweep`` is gone.

    A worker of ``concurrent.futures`` waits on its task queue and never learns that the
    process which owns the pool died: killed by SIGKILL, that process cannot stop it, and
    the worker (with the forkserver and the resource tracker, which last as long as a
    worker holds their pipes) would live on. ``prctl(PR_SET_PDEATHSIG)`` does not answer
    it: the signal follows the death of the *thread* that forked the worker, and a worker
    may be forked by another process (the forkserver). So a daemon thread watches the
    sweep process itself: on Linux it waits on a pidfd, which becomes readable when the
    process exits (the start time in ``/proc`` checks that the process id still names
    the sweep when the pidfd is opened); elsewhere it polls ``os.kill(sweep, 0)`` twice a
    second.
    """
    if hasattr(os, "pidfd_open") and sweep_start is not None:
        try:
            fd = os.pidfd_open(sweep)
        except ProcessLookupError:
            _exit_with_the_sweep()
        if _start_time(sweep) != sweep_start:  # the process id names another process now
            _exit_with_the_sweep()

        def wait() -> None:
            select.select([fd], [], [])
            _exit_with_the_sweep()

    else:

        def wait() -> None:
            while True:
                try:
                    os.kill(sweep, 0)
                except ProcessLookupError:
                    _exit_with_the_sweep()
                time.sleep(0.5)

    threading.Thread(target=wait, name="nrobust-watch-sweep", daemon=True).start()


def _init_pool_worker(sweep: int, sweep_start: str | None) -> None:
    """Worker initializer: one BLAS thread, and the worker killed with the sweep.

    On a machine shared by several workers, multithreaded BLAS pools compete for the same
    cores and the small eigenvalue problems of nrobust (the chains of a difference
    operator) slow down tenfold. threadpoolctl changes the limit of the libraries already
    loaded, so it works in forked workers, which inherit the parent's BLAS. The worker
    leaves, taking its point processes along, as soon as the sweep process ``sweep``
    (started at ``sweep_start``, see :func:`_start_time`) is gone, even killed by SIGKILL
    (:func:`_watch_sweep`). A worker stopped by SIGTERM (an interrupted sweep) kills the
    point processes it forked for a timeout, so that no hung point outlives the sweep.
    Ctrl-C in a terminal reaches every process of the group: the workers ignore it (no
    traceback from each of them) and the parent, which handles it, stops them.
    """
    _watch_sweep(sweep, sweep_start)
    threadpool_limits(1)
    signal.signal(signal.SIGTERM, _kill_children_and_exit)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle: it stops the pool


@contextmanager
def _process_pool(n_workers: int) -> Iterator[ProcessPoolExecutor]:
    """A local pool of ``n_workers`` processes (the platform's start method), one BLAS thread each.

    The workers end with this process, however it ends (:func:`_init_pool_worker`).
    """
    sweep = os.getpid()
    with ProcessPoolExecutor(
        max_workers=n_workers, initializer=_init_pool_worker, initargs=(sweep, _start_time(sweep))
    ) as pool:
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
    func: Callable[..., Any], chunk: list[Mapping[str, Any]], convert: Convert, timeout: float | None
) -> tuple[Any, ...]:
    """The task that runs one chunk on a worker: in the worker itself, or in a forked point process with a timeout."""
    if timeout is None:
        return (_run_chunk, func, chunk, convert)
    return (_run_chunk_guarded, func, chunk, convert, timeout)


def _run_on_futures_executor(
    pool: Executor,
    func: Callable[..., Any],
    chunks: list[list[Mapping[str, Any]]],
    convert: Convert,
    timeout: float | None,
    on_chunk: Callable[[int, list[tuple[Any, ...]]], None],
) -> None:
    futures = {pool.submit(*_submit_args(func, chunk, convert, timeout)): i for i, chunk in enumerate(chunks)}
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
    convert: Convert,
    timeout: float | None,
    on_chunk: Callable[[int, list[tuple[Any, ...]]], None],
) -> None:
    import distributed

    futures = [client.submit(*_submit_args(func, chunk, convert, timeout), pure=False) for chunk in chunks]
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
                n_workers=cpu_count(),
                threads_per_worker=1,
                processes=True,
                dashboard_address=":0",
                silence_logs=logging.ERROR,
            ) as cluster,
            distributed.Client(cluster) as client,
        ):
            yield client, f"dask(LocalCluster, {cpu_count()} workers)"
    else:
        with distributed.Client(executor) as client:
            yield client, f"dask({executor})"


def classify_executor(executor: Any) -> str:
    """``"serial"``, ``"pool"``, ``"executor"`` or ``"dask"``; raise naming ``executor`` otherwise."""
    if executor is None or (isinstance(executor, int) and not isinstance(executor, bool)):
        if executor is not None and executor < 1:
            raise ParameterError("executor", _EXECUTOR_REQUIREMENT, executor)
        return "pool"
    if isinstance(executor, str):
        if executor == "serial":
            return "serial"
        if executor == "dask" or executor.startswith(DASK_SCHEMES):
            return "dask"
        raise ParameterError("executor", _EXECUTOR_REQUIREMENT, executor)
    if isinstance(executor, Executor):
        return "executor"
    client_type = _dask_client_type()
    if client_type is not None and isinstance(executor, client_type):
        return "dask"
    raise ParameterError("executor", _EXECUTOR_REQUIREMENT, executor)


def _progress_bar(total: int, progress: bool | None) -> ProgressBar | HiddenBar:
    """A text progress bar on stderr; by default shown in terminals and notebooks only."""
    return progress_bar(total, progress, desc="sweep", unit="pt", leave=True)


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """Stop a pool of nrobust's now (on an interrupt): terminate its workers, which kill their point processes."""
    for process in list(getattr(pool, "_processes", {}).values()):
        with suppress(Exception):
            process.terminate()
    pool.shutdown(wait=True, cancel_futures=True)


def execute(
    func: Callable[..., Any],
    pts: list[dict[str, Any]],
    executor: Any,
    chunksize: int | None,
    progress: bool | None,
    convert: Convert,
    timeout: float | None = None,
    on_done: Callable[[int, tuple[Any, ...]], None] | None = None,
    max_chunk: int | None = None,
) -> tuple[list[tuple[Any, ...]], str]:
    """Run ``func(**point)`` for every point on ``executor``; outcomes in input order.

    Parameters
    ----------
    func : callable
        The point function (picklable for process pools and Dask).
    pts : list of dict
        The points.
    executor : None, str, int, Executor or dask.distributed.Client
        As in :func:`nrobust.sweeps.sweep` (checked by :func:`classify_executor`).
    chunksize : int or None
        Points per task; by default about four tasks per worker.
    progress : bool or None
        Show a progress bar (by default in terminals and notebooks only).
    convert : callable or None
        Applied on the worker to each return value (a sweep flattens it into columns).
    timeout : float, optional
        Seconds per point; each point then runs in a forked process killed past it.
    on_done : callable, optional
        ``on_done(position, outcome)``, called in this process as each point's outcome
        arrives (point by point in serial mode, chunk by chunk on workers).
    max_chunk : int, optional
        Cap on the automatic chunk size.

    Returns
    -------
    outcomes : list of tuple
        Per point ``("ok", value)`` or ``("error", type, message, traceback)``.
    description : str
        What ran the points (``"serial"``, ``"processes(2)"``, ...).
    """
    kind = classify_executor(executor)
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
                _run_chunk_guarded(func, pts, convert, timeout, on_outcome=done)
            else:
                for position, point in enumerate(pts):
                    done(position, _run_point(func, point, convert))
        elif kind == "pool":
            n_workers = cpu_count() if executor is None else int(executor)
            chunks = chunking(n_workers)
            description = f"processes({n_workers})"
            with _process_pool(min(n_workers, len(chunks))) as pool:
                try:
                    _run_on_futures_executor(pool, func, chunks, convert, timeout, chunk_done_for(chunks))
                except BaseException:
                    _stop_pool(pool)
                    raise
        elif kind == "executor":
            chunks = chunking(getattr(executor, "_max_workers", None) or cpu_count())
            description = f"executor({type(executor).__name__})"
            _run_on_futures_executor(executor, func, chunks, convert, timeout, chunk_done_for(chunks))
        else:
            with _dask_client(executor) as (client, description):
                chunks = chunking(sum(client.nthreads().values()) or 1)
                _run_on_dask(client, func, chunks, convert, timeout, chunk_done_for(chunks))
    return outcomes, description


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
    :func:`nrobust.sweeps.sweep`, which records failures per point, a map needs every result: an item
    whose call raises stops the computation with a :class:`~nrobust.errors.SweepError`
    naming the item and the original error.

    Parameters
    ----------
    executor : None, str, int, Executor or dask.distributed.Client
        As in :func:`nrobust.sweeps.sweep`.
    chunksize : int, optional
        Items per task.
    progress : bool, optional
        As in :func:`nrobust.sweeps.sweep`.
    """

    executor: Any = None
    chunksize: int | None = None
    progress: bool | None = None

    def __post_init__(self) -> None:
        classify_executor(self.executor)  # reject a bad executor before any work

    def __call__(self, func: Callable[[Any], Any], items: Iterable[Any]) -> list[Any]:
        items = list(items)
        if not items:
            return []
        pts = [{"item": item} for item in items]
        outcomes, _ = execute(_Item(func), pts, self.executor, self.chunksize, self.progress, convert=None)
        for item, outcome in zip(items, outcomes):
            if outcome[0] != "ok":
                raise SweepError(f"item {item!r} raised {outcome[1]}: {outcome[2]}")
        return [outcome[1] for outcome in outcomes]


def sweep_map(executor: Any = None, *, chunksize: int | None = None, progress: bool | None = None) -> SweepMap:
    """A ``map``-like callable that runs on ``executor`` (see :class:`SweepMap`)."""
    return SweepMap(executor, chunksize, progress)
