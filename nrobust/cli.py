"""The ``nrobust`` command line.

``nrobust analyze SYSTEM.toml -o OUT/``
    Certify one plant and controller (schema in ``docs/getting_started.md``) and write
    ``report.md``, ``report.html``, ``certificate.json`` and the figures.
``nrobust paper -o OUT/``
    The reference paper's example end to end: classification, figures 1 and 3 by
    simulation of the PDE, delay margins of U_BS and U_BS2(K = 0.1), the ``(K, delta)``
    stability chart with the sufficient bound, the decay/margin trade-off and the report.
``nrobust sweep SWEEP.toml -o OUT/ [--dask ADDRESS]``
    A parameter sweep or Monte Carlo study (:func:`nrobust.sweep.run_sweep_file`).

Input errors end the program with exit code 2 and a one-line message naming the bad key
(no traceback); a certified computation that reaches its work bound ends it with exit
code 1 and the message of the :class:`~nrobust.errors.CertificationError`.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from ._json import json_float, json_safe
from .errors import NrobustError, ParameterError

__all__ = ["main", "load_system_file", "PiecewiseLinear", "run_analyze", "run_paper"]

_SYSTEM_TYPES = ("Hyperbolic2x2", "TransportSystem")
_SYSTEM_KEYS = {
    "Hyperbolic2x2": ("lam", "mu", "sigma_pm", "sigma_mp", "q", "rho"),
    "TransportSystem": ("lam", "mu", "q", "rho"),
}
_CONTROLLER_KEYS = {
    "OpenLoop": (),
    "FiniteTimeController": (),
    "ReflectionController": ("K",),
    "FilteredController": ("a", "b"),
}
_ANALYSIS_KEYS = {"delta_max": None, "region": None, "k_region": True}
_SIMULATION_KEYS = {"delays": None, "t_end": 10.0, "n": 200, "u0": 1.0, "v0": 1.0}
_TOP_KEYS = ("system", "controller", "analysis", "simulation")


@dataclass(frozen=True)
class PiecewiseLinear:
    """A coupling given in a file as ``{x = [...], values = [...]}``, linear between nodes.

    Parameters
    ----------
    x : tuple of float
        Increasing nodes covering ``[0, 1]``.
    values : tuple of float
        Values at the nodes.
    """

    x: tuple[float, ...]
    values: tuple[float, ...]

    def __call__(self, x: Any) -> np.ndarray:
        return np.interp(np.asarray(x, dtype=float), self.x, self.values)

    @property
    def __name__(self) -> str:  # used by the systems' repr
        return "piecewise_linear"


def _number(key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise ParameterError(key, "a finite number", value)
    return float(value)


def _profile(key: str, value: Any) -> float | PiecewiseLinear:
    """A number or a piecewise-linear table ``{x = [...], values = [...]}`` on [0, 1]."""
    if not isinstance(value, dict):
        return _number(key, value)
    if set(value) != {"x", "values"}:
        raise ParameterError(key, "a number or a table with exactly the keys x and values", value)
    x, v = value["x"], value["values"]
    if not isinstance(x, list) or not isinstance(v, list) or len(x) != len(v) or len(x) < 2:
        raise ParameterError(f"{key}.x", "a list of at least 2 nodes, as long as values", x)
    xs = tuple(_number(f"{key}.x", t) for t in x)
    vs = tuple(_number(f"{key}.values", t) for t in v)
    if xs[0] != 0.0 or xs[-1] != 1.0 or any(b <= a for a, b in zip(xs, xs[1:])):
        raise ParameterError(f"{key}.x", "increasing from 0 to 1", x)
    return PiecewiseLinear(xs, vs)


def _table(spec: dict[str, Any], name: str, required: bool) -> dict[str, Any]:
    table = spec.get(name)
    if table is None and not required:
        return {}
    if not isinstance(table, dict):
        raise ParameterError(name, f"a [{name}] table", table)
    return table


def _typed(table: dict[str, Any], section: str, keys: dict[str, tuple[str, ...]]) -> tuple[str, dict[str, Any]]:
    kind = table.get("type")
    if kind not in keys:
        raise ParameterError(f"{section}.type", f"one of {list(keys)}", kind)
    params = {k: v for k, v in table.items() if k != "type"}
    for key in params:
        if key not in keys[kind]:
            raise ParameterError(f"{section}.{key}", f"a key of {kind}: one of {list(keys[kind])}", params[key])
    for key in keys[kind]:
        if key not in params:
            raise ParameterError(f"{section}.{key}", f"given for {kind}", None)
    return kind, params


def _options(table: dict[str, Any], section: str, defaults: dict[str, Any]) -> dict[str, Any]:
    for key in table:
        if key not in defaults:
            raise ParameterError(f"{section}.{key}", f"a key of [{section}]: one of {list(defaults)}", table[key])
    return {**defaults, **table}


def _wrap(key: str, build: Callable[[], Any]) -> Any:
    """Build an object, prefixing the section to the parameter named by its error."""
    try:
        return build()
    except ParameterError as exc:
        raise ParameterError(f"{key}.{exc.name}", exc.requirement, exc.value) from None


def load_system_file(path: str | Path) -> dict[str, Any]:
    """Read a SYSTEM.toml file (schema in ``docs/getting_started.md``).

    Returns
    -------
    dict
        ``system``, ``controller``, ``delta_max``, ``region``, ``k_region`` and
        ``simulation`` (None or a dict of ``delays``, ``t_end``, ``n``, ``u0``, ``v0``).

    Raises
    ------
    ParameterError
        Naming the bad key (``system.rho``, ``controller.type``, ``analysis.delta_max``...).
    """
    import tomllib

    from .hyperbolic.controllers import FilteredController, FiniteTimeController, OpenLoop, ReflectionController
    from .hyperbolic.system import Hyperbolic2x2, TransportSystem

    path = Path(path)
    try:
        with path.open("rb") as fh:
            spec = tomllib.load(fh)
    except FileNotFoundError:
        raise ParameterError("path", "an existing TOML file", str(path)) from None
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError("path", f"a valid TOML file ({exc})", str(path)) from None
    for key in spec:
        if key not in _TOP_KEYS:
            raise ParameterError(key, f"a section of the file: one of {list(_TOP_KEYS)}", spec[key])

    kind, params = _typed(_table(spec, "system", True), "system", _SYSTEM_KEYS)
    values = {k: (_profile if k.startswith("sigma") else _number)(f"system.{k}", v) for k, v in params.items()}
    cls = Hyperbolic2x2 if kind == "Hyperbolic2x2" else TransportSystem
    system = _wrap("system", lambda: cls(**values))

    kind, params = _typed(_table(spec, "controller", True), "controller", _CONTROLLER_KEYS)
    values = {k: _number(f"controller.{k}", v) for k, v in params.items()}
    classes = {
        "OpenLoop": OpenLoop,
        "FiniteTimeController": FiniteTimeController,
        "ReflectionController": ReflectionController,
        "FilteredController": FilteredController,
    }
    controller = _wrap("controller", lambda: classes[kind](**values))

    analysis = _options(_table(spec, "analysis", True), "analysis", _ANALYSIS_KEYS)
    if analysis["delta_max"] is None:
        raise ParameterError("analysis.delta_max", "given (the largest loop delay of interest, > 0)")
    delta_max = _number("analysis.delta_max", analysis["delta_max"])
    if delta_max <= 0:
        raise ParameterError("analysis.delta_max", "> 0", analysis["delta_max"])
    region = analysis["region"]
    if region is not None:
        if not isinstance(region, list) or len(region) != 4:
            raise ParameterError("analysis.region", "a list [re_min, re_max, im_min, im_max]", region)
        region = tuple(_number("analysis.region", v) for v in region)
        if not (region[0] < region[1] and region[2] < region[3]):
            raise ParameterError("analysis.region", "a non-empty rectangle: re_min < re_max, im_min < im_max", list(region))
    if not isinstance(analysis["k_region"], bool):
        raise ParameterError("analysis.k_region", "true or false", analysis["k_region"])

    simulation = None
    if "simulation" in spec:
        sim = _options(_table(spec, "simulation", True), "simulation", _SIMULATION_KEYS)
        delays = sim["delays"]
        if not isinstance(delays, list) or not delays:
            raise ParameterError("simulation.delays", "a non-empty list of loop delays >= 0", delays)
        delays = [_number("simulation.delays", d) for d in delays]
        if any(d < 0 for d in delays):
            raise ParameterError("simulation.delays", "delays >= 0", delays)
        t_end = _number("simulation.t_end", sim["t_end"])
        if t_end <= 0:
            raise ParameterError("simulation.t_end", "> 0", sim["t_end"])
        n = sim["n"]
        if isinstance(n, bool) or not isinstance(n, int) or n < 4:
            raise ParameterError("simulation.n", "an integer >= 4", n)
        simulation = {
            "delays": delays,
            "t_end": t_end,
            "n": n,
            "u0": _profile("simulation.u0", sim["u0"]),
            "v0": _profile("simulation.v0", sim["v0"]),
        }
    return {
        "system": system,
        "controller": controller,
        "delta_max": delta_max,
        "region": region,
        "k_region": analysis["k_region"],
        "simulation": simulation,
    }


def _initial(value: float | PiecewiseLinear) -> Callable[[np.ndarray], np.ndarray]:
    if isinstance(value, PiecewiseLinear):
        return value
    c = float(value)
    return lambda x: np.full(np.shape(x), c)


def _simulation_figure(runs: Sequence[Any], labels: Sequence[str], title: str) -> Any:
    import matplotlib.pyplot as plt

    from .plots import simulation_plot

    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    simulation_plot(runs, labels=labels, ax=ax)
    ax.set_title(title, fontsize="small")
    return fig


def _progress(total: int, enabled: bool, desc: str) -> Any:
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, disable=not enabled, leave=False, file=sys.stderr)


def run_analyze(path: str | Path, out_dir: str | Path, progress: bool = True) -> tuple[Any, str]:
    """``nrobust analyze``: certify the loop of a SYSTEM.toml file and write its report.

    Returns the :class:`~nrobust.report.ReportFiles` and the certificate's verdict.
    """
    from .certificate import certify
    from .hyperbolic.simulate import simulate
    from .report import write_report

    spec = load_system_file(path)
    sim = spec["simulation"]
    with _progress(2 + (0 if sim is None else len(sim["delays"])), progress, "analyze") as bar:
        cert = certify(spec["system"], spec["controller"], spec["delta_max"], spec["region"], spec["k_region"])
        bar.update(1)
        figures = []
        if sim is not None:
            runs = []
            for d in sim["delays"]:
                runs.append(
                    _wrap("simulation", lambda d=d: simulate(
                        spec["system"], spec["controller"], d, sim["t_end"], _initial(sim["u0"]), _initial(sim["v0"]), n=sim["n"]
                    ))
                )
                bar.update(1)
            figures.append((
                "L2 norm of the simulated closed loop",
                _simulation_figure(runs, [f"delta = {d:g}" for d in sim["delays"]], "Simulation of the PDE"),
            ))
        files = write_report(cert, out_dir, figures=figures)
        bar.update(1)
    return files, cert.verdict


# ---------------------------------------------------------------------- paper
#: The paper's numerical example (section 5): lam = mu = sigma+- = sigma-+ = q = 1, rho = 0.85.
PAPER_SYSTEM = {"lam": 1.0, "mu": 1.0, "sigma_pm": 1.0, "sigma_mp": 1.0, "q": 1.0, "rho": 0.85}
#: The tuning gain of figure 3 and the loop delays of figures 1 and 3.
PAPER_K = 0.1
PAPER_DELAYS_FIG1 = (0.0, 0.01)
PAPER_DELAYS_FIG3 = (0.0, 0.01, 0.1)


def _paper_u0(x: np.ndarray) -> np.ndarray:
    """Initial ``u``: constant 1 (any L2 datum with energy on both chains would do)."""
    return np.ones_like(np.asarray(x, dtype=float))


def _paper_v0(x: np.ndarray) -> np.ndarray:
    """Initial ``v``: ``1 + sin(pi x)``."""
    return 1.0 + np.sin(np.pi * np.asarray(x, dtype=float))


def _paper_job(job: str, *args: Any) -> Any:
    """One independent computation of :func:`run_paper`, run in a worker process.

    The plant is rebuilt from :data:`PAPER_SYSTEM` in the worker (its coupling
    evaluators are closures, not picklable); a certificate travels back without it and
    is re-attached to the caller's plant.
    """
    from dataclasses import replace

    from .hyperbolic.system import Hyperbolic2x2

    system = Hyperbolic2x2(**PAPER_SYSTEM)
    if job == "simulate":
        from .hyperbolic.simulate import simulate

        controller, delta, t_end, n = args
        return simulate(system, controller, delta, t_end, _paper_u0, _paper_v0, n=n)
    if job == "certify":
        from .certificate import certify

        controller, delta_max = args
        return replace(certify(system, controller, delta_max=delta_max, k_region=False), system=None)
    if job == "chart":
        from .margins import stability_chart

        return stability_chart(system, *args)
    if job == "tradeoff":
        from .margins import tradeoff

        return tradeoff(system, *args)
    if job == "locus":
        from .hyperbolic.controllers import ReflectionController, characteristic
        from .plots import root_locus_response

        Ks, delta, region = args
        return root_locus_response(
            lambda K: characteristic(system, ReflectionController(K), delta), Ks, region, name="K"
        )
    raise ParameterError("job", "one of simulate, certify, chart, tradeoff, locus", job)


class _SingleThreadBlas:
    """Environment for worker processes: one BLAS thread each.

    Worker processes are started with ``spawn`` while this context is active, so they
    load numpy with ``OPENBLAS_NUM_THREADS=1`` (and the MKL/OpenMP equivalents): on a
    shared machine several multithreaded BLAS pools compete for the same cores and
    small eigenvalue problems (the chains of a difference operator) slow down tenfold.
    """

    _VARS = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS")

    def __enter__(self) -> None:
        import os

        self._saved = {k: os.environ.get(k) for k in self._VARS}
        for k in self._VARS:
            os.environ[k] = "1"

    def __exit__(self, *exc: Any) -> None:
        import os

        for k, v in self._saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _run_tasks(tasks: dict[str, tuple[Any, ...]], workers: int, progress: bool) -> dict[str, Any]:
    """Run independent :func:`_paper_job` calls on ``workers`` spawned processes (0: here)."""
    results: dict[str, Any] = {}
    with _progress(len(tasks), progress, "paper example") as bar:
        if workers == 0:
            for name, args in tasks.items():
                results[name] = _paper_job(*args)
                bar.update(1)
            return results
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with _SingleThreadBlas(), ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
            futures = {pool.submit(_paper_job, *args): name for name, args in tasks.items()}
            for fut in as_completed(futures):
                results[futures[fut]] = fut.result()
                bar.update(1)
    return results


def run_paper(
    out_dir: str | Path,
    progress: bool = True,
    workers: int = 2,
    t_end: float = 15.0,
    n: int = 200,
    n_K: int = 25,
    n_delta: int = 26,
) -> dict[str, Any]:
    """``nrobust paper``: the reference paper's example end to end; returns the summary.

    Simulates the PDE for figures 1 (U_BS, eq. (control), ``delta = 0, 0.01``) and 3
    (U_BS2 with ``K = 0.1``, eq. (control3), ``delta = 0, 0.01, 0.1``), certifies both
    loops (classification, difference operator, certified roots, spectral abscissa,
    delay margin, Rouché bound), computes the ``(K, delta)`` stability chart and the
    decay/margin trade-off and the root locus in ``K`` of U_BS2, writes the report and
    ``summary.json`` with the headline numbers, each read from a computation.

    Parameters
    ----------
    out_dir : path-like
        Output directory.
    progress : bool
        Show a progress bar (on stderr).
    workers : int
        Worker processes for the independent computations (0: all in this process).
    t_end, n : float, int
        Simulation horizon and grid.
    n_K, n_delta : int
        Size of the stability chart's grid.
    """
    from dataclasses import replace

    import matplotlib.pyplot as plt

    from .hyperbolic.controllers import FiniteTimeController, ReflectionController, classify
    from .hyperbolic.system import Hyperbolic2x2
    from .plots import stability_chart_plot, tradeoff_plot
    from .report import write_report

    start = time.perf_counter()
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 0:
        raise ParameterError("workers", "an integer >= 0", workers)
    system = Hyperbolic2x2(**PAPER_SYSTEM)
    classification = classify(system)
    u_bs, u_bs2 = FiniteTimeController(), ReflectionController(PAPER_K)
    k_max = classification.k_bound
    Ks = np.linspace(-1.2 * k_max, 1.2 * k_max, n_K)
    deltas = np.linspace(0.0, 0.5, n_delta)
    # longest first, so that two workers finish together
    tasks: dict[str, tuple[Any, ...]] = {
        "tradeoff": ("tradeoff", Ks[Ks >= 0]),
        "chart": ("chart", Ks, deltas),
        "cert_bs2": ("certify", u_bs2, max(PAPER_DELAYS_FIG3)),
        "cert_bs": ("certify", u_bs, max(PAPER_DELAYS_FIG1)),
        "locus": ("locus", np.linspace(0.0, 0.9 * k_max, 7), max(PAPER_DELAYS_FIG3), (-1.0, 0.4, 0.0, 20.0)),
    }
    for d in PAPER_DELAYS_FIG1:
        tasks[f"fig1_{d:g}"] = ("simulate", u_bs, d, t_end, n)
    for d in PAPER_DELAYS_FIG3:
        tasks[f"fig3_{d:g}"] = ("simulate", u_bs2, d, t_end, n)
    res = _run_tasks(tasks, workers, progress)
    fig1_runs = [res[f"fig1_{d:g}"] for d in PAPER_DELAYS_FIG1]
    fig3_runs = [res[f"fig3_{d:g}"] for d in PAPER_DELAYS_FIG3]
    cert_bs, cert_bs2 = (replace(res[k], system=system) for k in ("cert_bs", "cert_bs2"))
    chart, trade = res["chart"], res["tradeoff"]

    figures = [
        ("Figure 1 of the paper: L2 norm under U_BS (finite-time backstepping)",
         _simulation_figure(fig1_runs, [f"delta = {d:g}" for d in PAPER_DELAYS_FIG1], "U_BS, eq. (control)")),
        (f"Figure 3 of the paper: L2 norm under U_BS2 with K = {PAPER_K:g}",
         _simulation_figure(fig3_runs, [f"delta = {d:g}" for d in PAPER_DELAYS_FIG3], f"U_BS2(K={PAPER_K:g}), eq. (control3)")),
    ]
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    stability_chart_plot(chart, ax=ax, k_bound=k_max, rouche=(trade.Ks, trade.rouche_bounds))
    figures.append(("Stability chart of U_BS2(K) in (K, delta): grid verdicts, the exact boundary delta*(K), "
                    "the sufficient bound |K| < (1 - |rho q|)/|q| and the Rouche delay range", fig))
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    tradeoff_plot(trade, ax=ax)
    figures.append(("Trade-off between decay rate and delay margin as K varies (labels: K)", fig))
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    res["locus"].plot(ax=ax)
    figures.append((f"Root locus of U_BS2 in K at delta = {max(PAPER_DELAYS_FIG3):g} (upper half-plane; "
                    "the roots of a real loop are symmetric)", fig))

    def growth(run: Any) -> float:
        """Least-squares slope of log ||(u, v)|| over the second half of the run."""
        t = np.asarray(run.times)
        y = np.log(np.maximum(np.asarray(run.norm), np.finfo(float).tiny))
        half = t >= 0.5 * t[-1]
        return float(np.polyfit(t[half], y[half], 1)[0])

    admissible = [float(K) for K, m, v in zip(chart.Ks, chart.margins, chart.values[:, 0])
                  if v == 0 and m > max(PAPER_DELAYS_FIG3)]
    summary = {
        "system": system.to_dict(),
        "classification": classification.to_dict(),
        "U_BS": {
            "delay_margin": cert_bs.to_dict()["delay_margin"],
            "margin_reason": cert_bs.margin.reason,
            "gamma_0_delayed": cert_bs.principal_delayed.gamma_0,
            "chain_abscissa_delayed": cert_bs.principal_delayed.spectral_bound,
            "simulated_growth_rate": {f"{d:g}": growth(r) for d, r in zip(PAPER_DELAYS_FIG1, fig1_runs)},
        },
        f"U_BS2(K={PAPER_K:g})": {
            "delay_margin": cert_bs2.to_dict()["delay_margin"],
            "crossing_frequency": cert_bs2.margin.omega,
            "gamma_0_delayed": cert_bs2.principal_delayed.gamma_0,
            "spectral_abscissa": cert_bs2.abscissa.value,
            "rouche_delta_0": None if cert_bs2.rouche is None else cert_bs2.rouche.to_dict()["delta_0"],
            "simulated_growth_rate": {f"{d:g}": growth(r) for d, r in zip(PAPER_DELAYS_FIG3, fig3_runs)},
        },
        "chart": {
            "Ks": chart.Ks.tolist(),
            "margins": [json_float(m) for m in chart.margins],
            f"K_stable_up_to_{max(PAPER_DELAYS_FIG3):g}_on_grid": admissible,
        },
        "tradeoff": trade.to_dict(),
    }
    bs2 = summary[f"U_BS2(K={PAPER_K:g})"]
    intro = [
        "The example of section 5 of Auriol, Aarsnes, Martin and Di Meglio: "
        + ", ".join(f"{k} = {v:g}" for k, v in PAPER_SYSTEM.items()) + ".",
        f"**Classification.** {classification.statement}",
        f"**U_BS.** {cert_bs.verdict} ({cert_bs.margin.reason}; rightmost chain of the delayed difference "
        f"operator at Re s = {cert_bs.principal_delayed.spectral_bound:.4g}.)",
        f"**U_BS2(K = {PAPER_K:g}).** {cert_bs2.verdict} Crossing frequency {_fmt_num(bs2['crossing_frequency'])}, "
        f"nominal decay rate {_fmt_num(-cert_bs2.abscissa.value)}, Rouché guaranteed range "
        f"delta_0 = {_fmt_num(cert_bs2.rouche.delta_0) if cert_bs2.rouche is not None else '-'}.",
        "Simulated growth rates (slope of log ||(u, v)|| over the second half of each run): "
        + "; ".join(
            f"{name} delta = {d}: {g:.3g}"
            for name, rates in (("U_BS", summary["U_BS"]["simulated_growth_rate"]),
                                ("U_BS2", bs2["simulated_growth_rate"]))
            for d, g in rates.items()
        ) + ".",
        f"Gains of the chart's grid stable for every delay in [0, {max(PAPER_DELAYS_FIG3):g}]: "
        + (", ".join(f"{k:.3g}" for k in admissible) or "none") + ".",
    ]
    files = write_report([cert_bs, cert_bs2], out_dir, figures=figures,
                         title="nrobust: the paper's example, end to end", intro=intro)
    summary["elapsed_seconds"] = time.perf_counter() - start
    summary["workers"] = workers
    summary["files"] = files.to_dict()
    text = json.dumps(json_safe(summary), indent=2, allow_nan=False)
    (Path(out_dir) / "summary.json").write_text(text, encoding="utf-8")
    return summary


def _fmt_num(x: Any) -> str:
    return "-" if x is None else f"{float(x):.6g}"


# ---------------------------------------------------------------------- main
def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="nrobust", description="Delay-robustness analysis of boundary-controlled 2x2 hyperbolic PDEs.")
    sub = p.add_subparsers(dest="command", required=True)
    a = sub.add_parser("analyze", help="certify the loop described by a SYSTEM.toml file and write a report")
    a.add_argument("file", help="SYSTEM.toml (schema: docs/getting_started.md)")
    a.add_argument("-o", "--out", required=True, help="output directory")
    a.add_argument("--no-progress", action="store_true", help="no progress bar")
    pp = sub.add_parser("paper", help="the reference paper's example end to end")
    pp.add_argument("-o", "--out", required=True, help="output directory")
    pp.add_argument("--no-progress", action="store_true", help="no progress bar")
    s = sub.add_parser("sweep", help="run a SWEEP.toml parameter sweep or Monte Carlo study")
    s.add_argument("file", help="SWEEP.toml (schema: docs/sweeps.md)")
    s.add_argument("-o", "--out", required=True, help="output directory")
    s.add_argument("--dask", metavar="ADDRESS", default=None, help="Dask scheduler address, e.g. tcp://host:8786")
    s.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``nrobust`` command; returns the exit code."""
    import matplotlib

    matplotlib.use("Agg")
    args = _parser().parse_args(argv)
    progress = not args.no_progress
    try:
        if args.command == "analyze":
            files, verdict = run_analyze(args.file, args.out, progress=progress)
            print(verdict)
            print(f"wrote {files.markdown}, {files.html}, {', '.join(str(p) for p in files.json)}")
        elif args.command == "paper":
            summary = run_paper(args.out, progress=progress)
            print(f"wrote {summary['files']['markdown']} and {summary['files']['html']} "
                  f"in {summary['elapsed_seconds']:.1f} s")
        else:
            from .sweep import run_sweep_file

            result = run_sweep_file(args.file, args.out, dask_address=args.dask, progress=progress)
            print(f"wrote {result.csv}, {result.json}, {result.png} "
                  f"({len(result.sweep.points)} points, {result.sweep.n_failed} failed)")
    except (ParameterError, OSError) as exc:
        print(f"nrobust: error: {exc}", file=sys.stderr)
        return 2
    except NrobustError as exc:  # a certified computation hit its work bound
        print(f"nrobust: computation failed: {exc}", file=sys.stderr)
        return 1
    return 0
