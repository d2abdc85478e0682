"""Monte Carlo robustness studies: the delay margin and decay rate under uncertain plants.

:func:`robustness` draws plants from a user function, analyses each closed loop (by
default :func:`nrobust.hyperbolic.analyses.margin_and_decay`) on the executors of
:mod:`nrobust.sweeps.executors` and summarises the outcomes by quantiles. See ``docs/sweeps.md``.
"""

from __future__ import annotations

import math
import os
import pickle
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from .._json import fields_dict
from ..errors import ParameterError
from ..hyperbolic.analyses import margin_and_decay
from .engine import MAX_POINTS, sweep
from .grids import grid
from .result import SweepResult, flatten, result_columns

__all__ = ["RobustnessResult", "check_levels", "quantile_summary", "robustness"]


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
            flatten(system, "system", out)
        out.update(result_columns(self.analysis(system, self.controller)))
        return out


def quantile_summary(
    result: SweepResult, levels: tuple[float, ...], skip: Sequence[str] = ()
) -> dict[str, tuple[float, ...]]:
    """Empirical quantiles (``inverted_cdf``: always a sample value, so ``inf`` is exact)
    of every numeric result column over the rows that succeeded, NaN values left out."""
    out: dict[str, tuple[float, ...]] = {}
    rows = [r for r in result.results if r is not None]
    names = result.result_names()
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


def check_levels(levels: Sequence[float]) -> tuple[float, ...]:
    """The quantile levels as floats in [0, 1]; ParameterError naming ``levels`` otherwise."""
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
        """Dict of the study (quantiles, counts, seed and the per-sample table); ``inf`` as ``"inf"``."""
        return fields_dict(self)

    def __repr__(self) -> str:
        width = max([len(c) for c in self.quantiles] + [6]) + 2
        head = "".join(f"{f'q{lev:g}':>11}" for lev in self.levels)
        lines = [
            f"RobustnessResult({self.n_samples} samples, {self.n_failed} failed, seed={self.seed})",
            f"  {'':<{width}}{head}",
        ]
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
    max_points: int = MAX_POINTS,
    timeout: float | None = None,
    results: str | os.PathLike[str] | None = None,
    restart: bool = False,
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
    chunksize, progress, max_points, timeout : optional
        As in :func:`sweep` (``max_points`` caps ``n_samples``; a sample past ``timeout``
        is a failure of type ``"Timeout"``).
    results : path-like, optional
        A journal of the samples (JSON lines), appended as each sample finishes; run the
        same study again on it and the finished samples are read back, not recomputed
        (see :func:`sweep`). Needs an int ``seed``.
    restart : bool, default False
        Start ``results`` afresh.

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
        if results is not None:
            raise ParameterError("seed", "an int when results is given (a fresh seed cannot be resumed)", seed)
        seed = int(cast(int, np.random.SeedSequence().entropy))  # a fresh SeedSequence draws an int
    elif isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ParameterError("seed", "a non-negative int or None", seed)
    lev = check_levels(levels)
    task = _SampleTask(sample_system, controller, analysis or margin_and_decay, int(seed))
    try:
        result = sweep(
            task,
            grid(sample=range(n)),
            executor,
            chunksize=chunksize,
            progress=progress,
            max_points=max_points,
            timeout=timeout,
            results=results,
            restart=restart,
        )
    except ParameterError as exc:
        if exc.name != "func":
            raise
        for name in ("sample_system", "controller", "analysis"):
            try:
                pickle.dumps(getattr(task, name))
            except Exception:
                raise ParameterError(name, exc.requirement, getattr(task, name)) from exc
        raise
    return RobustnessResult(lev, quantile_summary(result, lev), n, result.n_failed, int(seed), result)
