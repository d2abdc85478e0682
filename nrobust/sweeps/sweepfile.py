"""SWEEP.toml: a sweep or a Monte Carlo study described by a file, run and written to disk.

:func:`run_sweep_file` reads the file (schema in ``docs/sweeps.md``) and checks all of it
and the output directory, builds the systems and controllers of :mod:`nrobust.config`,
runs the named analyses on the executors of :mod:`nrobust.sweeps.executors` with a result journal
in the output directory (so an interrupted sweep resumes), and writes the table (CSV,
JSON), its chart (:func:`nrobust.plots.sweep_chart`) and the manifest of
:mod:`nrobust.reports.outputs`.
"""

from __future__ import annotations

import inspect
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._json import json_safe
from ..config import CONTROLLER_TYPES, SYSTEM_TYPES, load_toml, unknown_key
from ..errors import ParameterError
from ..hyperbolic.analyses import delay_margin
from ..hyperbolic.loops.controllers import characteristic, normalize
from ..plots.charts import sweep_chart
from ..reports.outputs import MANIFEST, RunOutputs
from ..roots import spectral_abscissa
from .engine import MAX_POINTS, sweep
from .executors import DASK_SCHEMES, classify_executor
from .grids import grid
from .montecarlo import check_levels, quantile_summary
from .result import SweepResult

__all__ = ["ANALYSES", "JOURNAL", "VERIFIED_VALUES", "SweepFileResult", "run_sweep_file"]


@dataclass(frozen=True)
class _Analysis:
    """An analysis of ``run_sweep_file``: the nrobust function it calls and its result columns.

    With ``n_positional == 2`` ``target`` is called as
    ``target(system, controller, **options)``; with ``n_positional == 1`` as
    ``target(characteristic(system, controller, delta), **options)``, the loop delay
    ``delta`` (default 0) being one of the options in ``own``. The options are the keyword
    parameters of ``target`` after its ``n_positional`` first ones, plus ``own``.
    ``numeric`` names the numeric columns that ``columns`` gives (``None``: not declared),
    so that ``[plot] y`` is checked before the sweep runs.
    """

    target: Callable[..., Any]
    n_positional: int
    own: tuple[str, ...]
    columns: Callable[[Any], dict[str, Any]]
    numeric: tuple[str, ...] | None = None

    def options(self) -> set[str] | None:
        """Accepted option names (``None``: any, the target takes ``**kwargs``).

        The deprecated names of renamed keywords (e.g. ``n`` of ``kernel_grid``) are
        accepted too; the target warns when it receives one.
        """
        params = list(inspect.signature(self.target).parameters.values())
        if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params):
            return None
        kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
        deprecated = set(getattr(self.target, "deprecated_keywords", {}))
        return {p.name for p in params[self.n_positional :] if p.kind in kinds} | set(self.own) | deprecated

    def __call__(self, system: Any, controller: Any, **options: Any) -> dict[str, Any]:
        if self.n_positional == 1:
            delta = options.pop("delta", 0.0)
            value = self.target(characteristic(system, controller, delta), **options)
        else:
            value = self.target(system, controller, **options)
        return self.columns(value)


#: The values of the ``verified`` column of a ``delay_margin`` sweep, the words of ``nrobust
#: analyze``: ``"yes"`` (the margin was checked independently), ``"no"`` (it was not), and
#: ``"not needed"`` (an infinite margin, or a zero one decided without a crossing frequency: nothing to check).
VERIFIED_VALUES = ("yes", "no", "not needed")


def _margin_columns(result: Any) -> dict[str, Any]:
    margin = float(result.margin)
    return {
        "delta_star": margin,
        "nominally_stable": bool(result.nominally_stable),
        "strongly_stable": bool(result.strongly_stable),
        "verified": VERIFIED_VALUES[2] if result.without_crossing else VERIFIED_VALUES[0 if result.verified else 1],
    }


def _abscissa_columns(result: Any) -> dict[str, Any]:
    value = float(result.value)
    return {"abscissa": value, "decay_rate": -value}


#: Analyses that ``run_sweep_file`` knows by name. Each runs one nrobust function on the
#: system and controller of a point.
ANALYSES: dict[str, _Analysis] = {
    "delay_margin": _Analysis(delay_margin, 2, (), _margin_columns, ("delta_star",)),
    "spectral_abscissa": _Analysis(spectral_abscissa, 1, ("delta",), _abscissa_columns, ("abscissa", "decay_rate")),
}
_TOP_KEYS = (
    "analysis",
    "system",
    "controller",
    "options",
    "grid",
    "sampling",
    "plot",
    "executor",
    "chunksize",
    "max_points",
    "timeout",
)
#: Name of the result journal in a sweep's output directory.
JOURNAL = "sweep.jsonl"
_DISTRIBUTIONS = ("uniform", "loguniform", "normal", "choice")


def _signature_names(cls: Any) -> tuple[set[str], set[str]]:
    """(all keyword parameter names, required ones) of a constructor."""
    params = inspect.signature(cls).parameters.values()
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    names = {p.name for p in params if p.kind in kinds}
    required = {p.name for p in params if p.kind in kinds and p.default is inspect.Parameter.empty}
    return names, required


def _typed_table(
    spec: dict[str, Any], section: str, types: Mapping[str, Callable[..., Any]]
) -> tuple[str, dict[str, Any], set[str], set[str]]:
    table = spec.get(section)
    if not isinstance(table, dict):
        raise ParameterError(section, f"a [{section}] table with a 'type' key", table)
    kind = table.get("type")
    if not isinstance(kind, str) or kind not in types:
        raise unknown_key(f"{section}.type", f"one of {list(types)}", kind, types, kind)
    names, required = _signature_names(types[kind])
    params = {k: v for k, v in table.items() if k != "type"}
    for key in params:
        if key not in names:
            raise unknown_key(
                f"{section}.{key}", f"a parameter of {kind}: one of {sorted(names)}", key, names, params[key]
            )
    return kind, params, names, required


def _axis_size(name: str, value: Any) -> int:
    """Check a grid axis (a list, or a table ``{start, stop, num}``) and return its length, building nothing."""
    if isinstance(value, list):
        if not value:
            raise ParameterError(name, "a non-empty list or {start, stop, num}", value)
        for item in value:
            if isinstance(item, float) and not math.isfinite(item):
                raise ParameterError(name, "a list of finite values", value)
        return len(value)
    if isinstance(value, dict):
        if set(value) != {"start", "stop", "num"}:
            raise ParameterError(name, "a list or a table with exactly the keys start, stop, num", value)
        num = value["num"]
        if isinstance(num, bool) or not isinstance(num, int) or num < 1:
            raise ParameterError(f"{name}.num", "an integer >= 1", num)
        for key in ("start", "stop"):
            end = value[key]
            if isinstance(end, bool) or not isinstance(end, (int, float)) or not math.isfinite(end):
                raise ParameterError(f"{name}.{key}", "a finite number", end)
        return int(num)
    raise ParameterError(name, "a list of values or a table {start, stop, num}", value)


def _axis_values(value: Any) -> list[Any]:
    """A checked grid axis: the list, or ``linspace(start, stop, num)`` (endpoints included,
    values rounded to 12 significant digits)."""
    if isinstance(value, list):
        return value
    # 12 significant digits: 0.1 rather than 0.09999999999999999 in tables and charts
    return [float(f"{x:.12g}") for x in np.linspace(value["start"], value["stop"], value["num"])]


def _draw(dist: Any, rng: np.random.Generator) -> Any:
    """One draw of a ``[sampling.distributions]`` entry."""
    ((kind, args),) = dist.items()
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
        raise ParameterError(
            name, f"a table with one key among {list(_DISTRIBUTIONS)}, e.g. {{uniform = [0.1, 0.3]}}", dist
        )
    ((kind, args),) = dist.items()
    if kind == "choice":
        if not isinstance(args, list) or not args:
            raise ParameterError(f"{name}.choice", "a non-empty list of values", args)
        return
    ok = (
        isinstance(args, list)
        and len(args) == 2
        and all(isinstance(a, (int, float)) and not isinstance(a, bool) for a in args)
    )
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
        system, controller = normalize(
            SYSTEM_TYPES[self.system_type](**sys_params), CONTROLLER_TYPES[self.controller_type](**ctl_params)
        )
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
    journal, manifest : pathlib.Path
        The result journal (``sweep.jsonl``, one line per finished point) and the
        manifest of the run's files (``manifest.json``).
    """

    sweep: SweepResult
    csv: Path
    json: Path
    png: Path
    quantiles: dict[str, tuple[float, ...]]
    levels: tuple[float, ...]
    journal: Path | None = None
    manifest: Path | None = None

    def to_dict(self) -> dict[str, Any]:
        """Paths, quantiles (``inf`` as ``"inf"``) and counts (the table itself is in the JSON file)."""
        return json_safe(
            {
                "csv": self.csv,
                "json": self.json,
                "png": self.png,
                "journal": self.journal,
                "manifest": self.manifest,
                "n_points": len(self.sweep.points),
                "n_failed": self.sweep.n_failed,
                "levels": self.levels,
                "quantiles": self.quantiles,
            }
        )


def _route_names(
    keys: Sequence[str], section: str, sys_names: set[str], ctl_names: set[str], option_names: set[str] | None
) -> dict[str, str]:
    """Decide whether each swept or sampled name is a system, controller or analysis parameter."""
    routes = {}
    for key in keys:
        homes = [h for h, names in (("system", sys_names), ("controller", ctl_names)) if key in names]
        if (option_names is not None and key in option_names) or (option_names is None and not homes):
            homes.append("options")  # an analysis taking **kwargs receives the names no plant or controller takes
        if not homes:
            allowed = sorted(sys_names | ctl_names | (option_names or set()))
            raise unknown_key(
                f"{section}.{key}",
                f"a parameter of [system], [controller] or an analysis option: one of {allowed}",
                key,
                allowed,
                key,
            )
        if len(homes) > 1:
            raise ParameterError(f"{section}.{key}", f"a name of exactly one of {homes}", key)
        routes[key] = homes[0]
    return routes


@dataclass(frozen=True)
class _Points:
    """The points of a SWEEP.toml: its grid or its Monte Carlo draws.

    ``routes`` says where each swept or sampled name goes (``"system"``, ``"controller"``
    or ``"options"``); ``levels`` are the quantile levels of a ``[sampling]`` study
    (empty for a grid).
    """

    points: Sequence[dict[str, Any]]
    routes: dict[str, str]
    levels: tuple[float, ...]
    sampled: bool


def _read_spec(path: Path) -> dict[str, Any]:
    """Read the SWEEP.toml and check its top-level keys."""
    spec = load_toml(path, "SWEEP.toml")
    for key in spec:
        if key not in _TOP_KEYS:
            raise unknown_key(
                key, f"a top-level key of SWEEP.toml: one of {list(_TOP_KEYS)}", key, _TOP_KEYS, spec[key]
            )
    return spec


def _check_analyses(spec: dict[str, Any]) -> tuple[str, ...]:
    """The analyses named by ``analysis`` (a name or a list of them), in order, without repeats."""
    names = spec.get("analysis", "delay_margin")
    names = [names] if isinstance(names, str) else names
    if not isinstance(names, list) or not names or any(n not in ANALYSES for n in names):
        unknown = next((n for n in names if n not in ANALYSES), None) if isinstance(names, list) else None
        raise unknown_key(
            "analysis",
            f"an analysis name or a list of them among {sorted(ANALYSES)}",
            unknown,
            ANALYSES,
            spec.get("analysis"),
        )
    return tuple(dict.fromkeys(names))


def _check_options(spec: dict[str, Any], analyses: tuple[str, ...]) -> tuple[dict[str, Any], set[str] | None]:
    """Check the ``[options.<analysis>]`` tables.

    Returns the tables and the option names that some selected analysis accepts (``None``:
    any name, an analysis takes ``**kwargs``).
    """
    options = spec.get("options", {})
    if not isinstance(options, dict):
        raise ParameterError("options", "a table of [options.<analysis>] tables", options)
    accepted: dict[str, set[str] | None] = {name: ANALYSES[name].options() for name in analyses}
    for name, table in options.items():
        if name not in analyses:
            raise unknown_key(
                f"options.{name}", f"options of a selected analysis: one of {list(analyses)}", name, analyses, table
            )
        if not isinstance(table, dict):
            raise ParameterError(f"options.{name}", "a table of keyword options", table)
        for key in table:
            allowed = accepted[name]
            if allowed is not None and key not in allowed:
                raise unknown_key(
                    f"options.{name}.{key}", f"an option of {name}: one of {sorted(allowed)}", key, allowed, table[key]
                )
    option_names: set[str] | None = set()
    for allowed in accepted.values():
        option_names = None if (allowed is None or option_names is None) else option_names | allowed
    return options, option_names


def _check_limits(spec: dict[str, Any], max_points: int | None, timeout: float | None) -> tuple[int, float | None]:
    """``max_points`` and ``timeout``: the arguments when given, else the file's."""
    cap = spec.get("max_points", MAX_POINTS) if max_points is None else max_points
    if isinstance(cap, bool) or not isinstance(cap, int) or cap < 1:
        raise ParameterError("max_points", "a positive integer", cap)
    seconds = spec.get("timeout") if timeout is None else timeout
    if seconds is not None and (
        isinstance(seconds, bool)
        or not isinstance(seconds, (int, float))
        or not (math.isfinite(seconds) and seconds > 0)
    ):
        raise ParameterError("timeout", "a finite number of seconds > 0", seconds)
    return cap, seconds


def _grid_points(
    table: Any, cap: int, sys_names: set[str], ctl_names: set[str], option_names: set[str] | None
) -> _Points:
    """The points of ``[grid]``, its size checked against ``max_points`` before it is built."""
    if not isinstance(table, dict) or not table:
        raise ParameterError("grid", "a non-empty table name = [values]", table)
    routes = _route_names(list(table), "grid", sys_names, ctl_names, option_names)
    sizes = {k: _axis_size(f"grid.{k}", v) for k, v in table.items()}
    if math.prod(sizes.values()) > cap:
        shape = " x ".join(str(n) for n in sizes.values())
        raise ParameterError(
            "grid",
            f"at most max_points = {cap} points, but it is a grid of {shape} = {math.prod(sizes.values())} "
            f"points over {', '.join(sizes)}; shrink it, or raise max_points",
        )
    return _Points(grid(**{k: _axis_values(v) for k, v in table.items()}), routes, (), False)


def _sampled_points(
    table: Any, cap: int, sys_names: set[str], ctl_names: set[str], option_names: set[str] | None
) -> _Points:
    """The Monte Carlo draws of ``[sampling]`` (``n_samples`` points from ``seed``) and its quantile levels."""
    if not isinstance(table, dict):
        raise ParameterError("sampling", "a table with n_samples, seed and [sampling.distributions]", table)
    sampling_keys = ("n_samples", "seed", "levels", "distributions")
    for key in table:
        if key not in sampling_keys:
            raise unknown_key(f"sampling.{key}", f"one of {', '.join(sampling_keys)}", key, sampling_keys, table[key])
    n = table.get("n_samples")
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ParameterError("sampling.n_samples", "an integer >= 1", n)
    if n > cap:
        raise ParameterError("sampling.n_samples", f"at most max_points = {cap}; shrink it, or raise max_points", n)
    seed = table.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ParameterError("sampling.seed", "a non-negative integer", seed)
    try:
        levels = check_levels(table.get("levels", (0.05, 0.25, 0.5, 0.75, 0.95)))
    except ParameterError as exc:
        raise ParameterError("sampling.levels", exc.requirement, exc.value) from None
    dists = table.get("distributions")
    if not isinstance(dists, dict) or not dists:
        raise ParameterError("sampling.distributions", "a non-empty table name = {uniform = [low, high]}", dists)
    for key, dist in dists.items():
        _check_distribution(f"sampling.distributions.{key}", dist)
    routes = _route_names(list(dists), "sampling.distributions", sys_names, ctl_names, option_names)
    rng = np.random.default_rng(seed)
    return _Points([{k: _draw(d, rng) for k, d in dists.items()} for _ in range(n)], routes, levels, True)


def _build_points(
    spec: dict[str, Any], cap: int, sys_names: set[str], ctl_names: set[str], option_names: set[str] | None
) -> _Points:
    """The points of exactly one of ``[grid]`` and ``[sampling]``."""
    has_grid, has_sampling = "grid" in spec, "sampling" in spec
    if has_grid == has_sampling:
        raise ParameterError("grid", "given, or [sampling] given instead (exactly one of the two)")
    if has_grid:
        return _grid_points(spec["grid"], cap, sys_names, ctl_names, option_names)
    return _sampled_points(spec["sampling"], cap, sys_names, ctl_names, option_names)


def _check_required(
    routes: dict[str, str],
    sys_required: set[str],
    sys_params: dict[str, Any],
    ctl_required: set[str],
    ctl_params: dict[str, Any],
) -> None:
    """Every required parameter of the system and the controller is given or swept."""
    for section, required, given in (("system", sys_required, sys_params), ("controller", ctl_required, ctl_params)):
        for name in sorted(required):
            if name not in given and routes.get(name) != section:
                raise ParameterError(f"{section}.{name}", f"given in [{section}] or swept in [grid] / [sampling]")


def _choose_executor(spec: dict[str, Any], dask_address: str | None) -> tuple[Any, int | None]:
    """The executor (``dask_address`` if given, else the file's ``executor``) and ``chunksize``."""
    if dask_address is not None:
        if not isinstance(dask_address, str) or ":" not in dask_address:
            raise ParameterError(
                "dask_address", "a Dask scheduler address such as 'tcp://scheduler:8786'", dask_address
            )
        executor: Any = dask_address if dask_address.startswith(DASK_SCHEMES) else f"tcp://{dask_address}"
    else:
        executor = spec.get("executor")
        classify_executor(executor)
    chunksize = spec.get("chunksize")
    if chunksize is not None and (isinstance(chunksize, bool) or not isinstance(chunksize, int) or chunksize < 1):
        raise ParameterError("chunksize", "a positive integer", chunksize)
    return executor, chunksize


def _check_plot(spec: dict[str, Any], routes: dict[str, str], analyses: tuple[str, ...]) -> dict[str, Any]:
    """The ``[plot]`` table: ``x`` a swept name, ``y`` a numeric result column (when declared)."""
    plot = spec.get("plot", {})
    if not isinstance(plot, dict) or any(k not in ("x", "y") for k in plot):
        raise ParameterError("plot", "a table with optional keys x and y", plot)
    if "x" in plot and plot["x"] not in routes:
        raise ParameterError("plot.x", f"a swept parameter: one of {list(routes)}", plot["x"])
    declared = [ANALYSES[name].numeric for name in analyses]
    if "y" in plot and all(d is not None for d in declared):
        numeric = [c for d in declared for c in (d or ())]
        if plot["y"] not in numeric:
            raise ParameterError("plot.y", f"a numeric result column: one of {numeric}", plot["y"])
    return plot


def _write_outputs(
    outputs: RunOutputs, result: SweepResult, path: Path, points: _Points, plot: dict[str, Any]
) -> SweepFileResult:
    """Write the table (CSV, JSON with the quantiles of a ``[sampling]`` study), its chart and the manifest."""
    sampled, levels, swept = points.sampled, points.levels, list(points.routes)
    quantiles = quantile_summary(result, levels, skip=swept) if sampled else {}
    csv_path = outputs.final(result.to_csv(outputs.path("sweep.csv")))
    extra = {"source": str(path), "levels": list(levels), "quantiles": {k: list(v) for k, v in quantiles.items()}}
    staged_json = result.to_json(outputs.path("sweep.json"), extra=extra if sampled else {"source": str(path)})
    json_path = outputs.final(staged_json)
    png_path = outputs.savefig("sweep.png", sweep_chart(result, swept, plot, sampled), dpi=120)
    journal = outputs.keep(JOURNAL)
    outputs.commit()
    return SweepFileResult(
        result, csv_path, json_path, png_path, quantiles, levels, journal, outputs.directory / MANIFEST
    )


def run_sweep_file(
    path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    dask_address: str | None = None,
    *,
    progress: bool | None = None,
    restart: bool = False,
    max_points: int | None = None,
    timeout: float | None = None,
) -> SweepFileResult:
    """Run the sweep or Monte Carlo study described by a SWEEP.toml file.

    Parameters
    ----------
    path : path-like
        The TOML file; its schema is in ``docs/sweeps.md``.
    out_dir : path-like
        Directory for ``sweep.jsonl`` (the journal, appended as points finish),
        ``sweep.csv``, ``sweep.json``, ``sweep.png`` and ``manifest.json``; created if
        needed, and checked to be writable before anything runs. If it holds the
        journal of the same sweep, the sweep resumes: finished points are not run again.
    dask_address : str, optional
        Address of a Dask scheduler (``"tcp://scheduler:8786"``, or ``"scheduler:8786"``
        for TCP); overrides the file's ``executor``.
    progress : bool, optional
        As in :func:`sweep`.
    restart : bool, default False
        Discard the journal in ``out_dir`` and run every point (``nrobust sweep
        --restart``); without it, a journal of another definition is an error.
    max_points, timeout : optional
        Override the file's ``max_points`` and ``timeout`` (see :func:`sweep`).

    Returns
    -------
    SweepFileResult
        The table, the paths written and, for ``[sampling]``, the quantiles.

    Raises
    ------
    ParameterError
        Naming the bad key (``grid.K``, ``system.type``, ``options.delay_margin.foo``,
        ``plot.y``, ...) when the file does not follow the schema, ``out`` when
        ``out_dir`` is not a writable directory, ``results`` when ``out_dir`` holds the
        journal of another sweep; all before any point runs.
    SweepInterrupted
        On Ctrl-C; the finished points are in ``out_dir/sweep.jsonl``.
    """
    path = Path(path)
    # every check, of the file then of the output directory, before any point runs
    spec = _read_spec(path)
    analyses = _check_analyses(spec)
    sys_type, sys_params, sys_names, sys_required = _typed_table(spec, "system", SYSTEM_TYPES)
    ctl_type, ctl_params, ctl_names, ctl_required = _typed_table(spec, "controller", CONTROLLER_TYPES)
    options, option_names = _check_options(spec, analyses)
    cap, seconds = _check_limits(spec, max_points, timeout)
    points = _build_points(spec, cap, sys_names, ctl_names, option_names)
    _check_required(points.routes, sys_required, sys_params, ctl_required, ctl_params)
    executor, chunksize = _choose_executor(spec, dask_address)
    plot = _check_plot(spec, points.routes, analyses)
    func = _FileAnalysis(
        sys_type, sys_params, ctl_type, ctl_params, analyses, {k: dict(v) for k, v in options.items()}, points.routes
    )
    with RunOutputs(out_dir, "sweep") as outputs:
        # the journal in out_dir: finished points are not run again unless restart
        result = sweep(
            func,
            points.points,
            executor,
            chunksize=chunksize,
            progress=progress,
            max_points=cap,
            timeout=seconds,
            results=outputs.directory / JOURNAL,
            restart=restart,
        )
        return _write_outputs(outputs, result, path, points, plot)
