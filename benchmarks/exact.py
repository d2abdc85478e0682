"""Delay margins on the exact route (``N~`` in closed form) against the kernel route, and a proven certificate.

Plants with constant coefficients have their ``N~`` of eq. (40) in closed form, stored as
polynomial pieces with a proven error radius
(:func:`nrobust.hyperbolic.loops.exact_form.exact_form`): the exact route, default of
:func:`nrobust.delay_margin`, whose proofs are about the PDE itself. ``kernel_grid=201``
forces the kernel route (``N~`` the cubic spline of the kernels on a grid: a model of the
plant, whose proofs are about the model). Three plants with ``U_BS2(0.1)`` (eq. (53)): the
paper's example (``lam = mu = sigma+- = sigma-+ = q = 1``, ``rho = 0.85``), ``mu = 3``, and
``sigma+- = sigma-+ = 4``, ``q = rho = 0.5``. Measured in this process:

* the delay margin in floating point and proven in ball arithmetic (``rigorous=True``) on
  each route: the first (cold) call, every cache of nrobust emptied, so that it includes
  building ``N~`` (in closed form, or the kernels and their spline), then the best of 3 calls;
  the ratios proven / floating point (goal on the exact route: within 3x) and exact /
  kernel route;
* the margins, the widths of the proven balls and how far the kernel route's ball lies from
  the exact route's, in widths of the kernel route's ball (the exact ball encloses the PDE's
  margin: a kernel ball that misses it is a proof about the model, not the PDE);
* building the exact ``N~`` alone against ``solve_kernels(plant, 201)``;
* :func:`nrobust.certify` with ``delta_max = 0.1`` and ``rigorous=True`` (goal: under 1 s on
  2 cores), best of 2, and each of its analyses timed alone on the same loops (the route of
  ``certify``'s default ``kernel_grid``): the root finding at ``delta = 0`` and at
  ``delta_max``, the spectral abscissa, the delay margin, the Rouché range and the
  admissible gains; the rest (loops, principal parts, claims and, on the kernel route, the
  model error) is the difference. Like ``certify``, the analyses run on one BLAS thread.
  CPU times beside the wall times show what a loaded machine adds.

Run: ``python benchmarks/exact.py [--quick]`` (``--quick``: the certificate of the paper's
plant only). ``python benchmarks/exact.py --cold 5``: only the paper's certificate
(``rigorous=True``), each run in a fresh Python process (nothing remembered between runs): the
first call and the second, CPU (``time.process_time``) and wall time, with the load average
beside each run, median and spread; once with the modules that the first call imports loaded
beforehand (what the call itself costs), once after ``import nrobust`` and python-flint alone
(``import nrobust`` is lazy: the first call then also imports the modules it uses).
"""

from __future__ import annotations

import argparse
import functools
import inspect
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

import nrobust as nr
from nrobust.errors import CertificationError
from nrobust.hyperbolic.analyses.kregion import DEFAULT_N_GAINS
from nrobust.hyperbolic.loops import exact_form as exact_module
from nrobust.hyperbolic.loops.controllers import characteristic, loop_route
from nrobust.margins import margin as margin_module

PLANTS = {
    "paper (1, 1, 1, 1, 1, 0.85)": nr.Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85),
    "mu = 3 (1, 3, 1, 1, 1, 0.85)": nr.Hyperbolic2x2(1.0, 3.0, 1.0, 1.0, 1.0, 0.85),
    "sigma = 4 (1, 1, 4, 4, 0.5, 0.5)": nr.Hyperbolic2x2(1.0, 1.0, 4.0, 4.0, 0.5, 0.5),
}
GAIN = 0.1
DELTA_MAX = 0.1
GRID = 201
ROUTES: dict[str, dict[str, Any]] = {
    "float, exact": {},
    "float, kernels": {"kernel_grid": GRID},
    "proven, exact": {"rigorous": True},
    "proven, kernels": {"kernel_grid": GRID, "rigorous": True},
}


def clear_caches() -> None:
    """Empty every ``lru_cache`` of the loaded nrobust modules (closed-form ``N~``, kernels, compiled balls, ...)."""
    seen: set[int] = set()
    for name, module in list(sys.modules.items()):
        if name != "nrobust" and not name.startswith("nrobust."):
            continue
        for obj in list(vars(module).values()):
            if callable(getattr(obj, "cache_clear", None)) and id(obj) not in seen:
                seen.add(id(obj))
                obj.cache_clear()


def timed(fn: Callable[[], Any], repeat: int = 1) -> tuple[float, Any]:
    """Best wall time of ``repeat`` calls (the least disturbed by other load) and the last result."""
    wall, _, out = timed_cpu(fn, repeat)
    return wall, out


def timed_cpu(fn: Callable[[], Any], repeat: int = 1) -> tuple[float, float, Any]:
    """Best wall time and best CPU time of ``repeat`` calls, and the last result.

    The CPU time (this process, all its threads, and any child process it waited for) shows
    what a loaded machine adds to the wall time.
    """
    walls, cpus, out = [], [], None
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), cpu_time()
        out = fn()
        walls.append(time.perf_counter() - t0)
        cpus.append(cpu_time() - c0)
    return float(np.min(walls)), float(np.min(cpus)), out


def cpu_time() -> float:
    """CPU seconds of this process and of its children that have ended."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def cold_and_warm(fn: Callable[[], Any], repeat: int = 3) -> tuple[float, float, float, Any]:
    """The first call after :func:`clear_caches`, then the best of ``repeat`` calls (wall and CPU time)."""
    clear_caches()
    t_cold, _ = timed(fn)
    t_warm, c_warm, out = timed_cpu(fn, repeat)
    return t_cold, t_warm, c_warm, out


def ball_text(margin: Any) -> str:
    lo, hi = margin.margin_ball
    return f"[{lo:.15f}, {hi:.15f}] width {hi - lo:.2e}"


def margins_section(name: str, plant: nr.Hyperbolic2x2) -> None:
    """The four margins of one plant: times, ratios, values, balls."""
    controller = nr.ReflectionController(GAIN)
    print(f"\n{name}, U_BS2({GAIN}): delay margin")
    times, results = {}, {}
    for route, kw in ROUTES.items():
        t_cold, t_warm, c_warm, m = cold_and_warm(functools.partial(_searched_margin, plant, controller, kw))
        times[route], results[route] = t_warm, m
        kind = "ball" if m.rigorous else "float"
        print(
            f"  {route:<16} delta* = {m.margin:.15f}  cold {t_cold:6.3f} s  best of 3 {t_warm:6.3f} s "
            f"({c_warm:6.3f} s of CPU)  {m.evaluations:>6} {kind} evaluations"
        )
    fe, fk, pe, pk = (times[r] for r in ROUTES)
    print(
        f"  ratios: proven / float, exact route {pe / fe:.2f}x (goal: within 3x); kernel route {pk / fk:.2f}x; "
        f"exact / kernel route: float {fe / fk:.2f}x, proven {pe / pk:.2f}x"
    )
    exact, kernel = results["proven, exact"], results["proven, kernels"]
    print(f"  proven ball, exact route   {ball_text(exact)}  ({exact.scope})")
    print(f"  proven ball, kernel route  {ball_text(kernel)}")
    (elo, ehi), (klo, khi) = exact.margin_ball, kernel.margin_ball
    gap = max(elo - khi, klo - ehi, 0.0)
    print(
        f"  float margins differ by {abs(results['float, exact'].margin - results['float, kernels'].margin):.2e} "
        f"(exact - kernel route)"
    )
    if gap > 0.0:
        print(
            f"  the kernel route's ball misses the exact ball (which holds the PDE's margin) by {gap:.2e}: "
            f"{gap / (khi - klo):.3g} widths of the kernel ball ({gap / (ehi - elo):.3g} of the exact ball)"
        )
    else:
        print("  the kernel route's ball meets the exact ball")


def _searched_margin(plant: nr.Hyperbolic2x2, controller: Any, kw: dict[str, Any]) -> Any:
    """``nr.delay_margin(plant, controller, **kw)`` with its crossing search done again (not remembered)."""
    margin_module._float_search.cache_clear()
    return nr.delay_margin(plant, controller, **kw)


def construction_section(name: str, plant: nr.Hyperbolic2x2) -> None:
    """The exact ``N~`` alone against the kernels on the default grid."""

    def build() -> Any:
        exact_module._exact_form.cache_clear()
        return exact_module.exact_form(plant)

    t_exact, form = timed(build, 3)
    t_kern, _ = timed(lambda: nr.solve_kernels(plant, GRID), 3)
    pieces = len(form.N_tilde.nodes) - 1 if form.N_tilde is not None else 0
    radius = form.N_tilde.radius if form.N_tilde is not None else 0.0
    print(
        f"  {name:<34} exact N~ {t_exact:.4f} s ({pieces} pieces, proven radius {radius:.1e})   "
        f"solve_kernels(plant, {GRID}) {t_kern:.4f} s   ratio {t_exact / t_kern:.2f}x"
    )


def prove_or_float(compute: Callable[[bool], Any]) -> tuple[Any, str]:
    """``compute(True)``, or ``compute(False)`` when the proof is refused (as ``certify`` does)."""
    try:
        return compute(True), ""
    except CertificationError:
        return compute(False), " (proof refused: floating point)"


def certify_section(name: str, plant: nr.Hyperbolic2x2) -> None:
    """``certify(rigorous=True)`` in total and each of its analyses alone, on certify's own route."""
    controller = nr.ReflectionController(GAIN)
    grid = inspect.signature(nr.certify).parameters["kernel_grid"].default
    route = loop_route(plant, controller, grid)
    print(f"\n{name}: certify(delta_max = {DELTA_MAX}, rigorous=True), default kernel_grid = {grid} ({route} route)")

    def run() -> Any:
        return nr.certify(plant, controller, delta_max=DELTA_MAX, rigorous=True)

    clear_caches()
    t_cold, c_cold, _ = timed_cpu(run)
    t_warm, c_warm, cert = timed_cpu(run)
    best, best_cpu = min(t_cold, t_warm), min(c_cold, c_warm)
    verdict = "met" if best < 1.0 else f"not met, {best:.1f}x over"
    print(
        f"  total: first call (caches emptied) {t_cold:.3f} s, second {t_warm:.3f} s; best of 2 {best:.3f} s "
        f"({best_cpu:.3f} s of CPU); goal under 1 s on 2 cores: {verdict}"
    )
    if cert.unproven:
        print(f"  unproven parts: {'; '.join(cert.unproven)}")
    F0 = characteristic(plant, controller, 0.0, kernel_grid=grid)
    Fd = characteristic(plant, controller, DELTA_MAX, kernel_grid=grid)
    box = cert.region
    parts: dict[str, Callable[[bool], Any]] = {
        "find_roots(F(s; 0))": functools.partial(_find_roots, F0, box),
        f"find_roots(F(s; {DELTA_MAX}))": functools.partial(_find_roots, Fd, box),
        "spectral_abscissa(F(s; 0))": functools.partial(_abscissa, F0),
        "delay_margin": functools.partial(_margin, plant, controller, grid),
        "rouche_delay_bound": functools.partial(_rouche, plant, controller, grid),
    }
    rows = []
    with threadpool_limits(1):  # as certify's analyses run
        for label, compute in parts.items():
            t, c, (_, note) = timed_cpu(functools.partial(prove_or_float, compute), 2)
            rows.append((label + note, t, c))
        if cert.k_region is not None or cert.k_region_error:
            t, c, _ = timed_cpu(functools.partial(_k_region, plant), 2)
            rows.append((f"k_region(n_gains = {DEFAULT_N_GAINS}, serial)", t, c))
    rows.sort(key=lambda row: -row[1])
    rest, rest_cpu = best - sum(row[1] for row in rows), best_cpu - sum(row[2] for row in rows)
    print(f"  each analysis alone, one BLAS thread, best of 2 (share of the best total {best:.3f} s):")
    for label, t, c in rows:
        print(f"    {label:<44} {t:7.3f} s  ({c:7.3f} s of CPU)  {100.0 * t / best:5.1f} %")
    label = "rest: loops, principal parts, claims"
    if min(rest, rest_cpu) >= 0.0:
        print(f"    {label:<44} {rest:7.3f} s  ({rest_cpu:7.3f} s of CPU)  (the total less the analyses)")
    else:
        print(
            f"    {label:<44} within the timing noise (the analyses alone take {best - rest:.3f} s, "
            f"{best_cpu - rest_cpu:.3f} s of CPU: not less than the total)"
        )
    t_float, _ = timed(functools.partial(_rouche, plant, controller, grid, False), 2)
    print(f"  for comparison: rouche_delay_bound in floating point {t_float:.3f} s")


def _find_roots(F: Any, box: tuple[float, float, float, float], rigorous: bool) -> Any:
    return nr.find_roots(F, box, rigorous=rigorous)


def _abscissa(F: Any, rigorous: bool) -> Any:
    return nr.spectral_abscissa(F, rigorous=rigorous)


def _margin(plant: nr.Hyperbolic2x2, controller: Any, grid: int | None, rigorous: bool) -> Any:
    return nr.delay_margin(plant, controller, delta_max=DELTA_MAX, rigorous=rigorous, kernel_grid=grid)


def _rouche(plant: nr.Hyperbolic2x2, controller: Any, grid: int | None, rigorous: bool) -> Any:
    return nr.rouche_delay_bound(plant, controller, rigorous=rigorous, kernel_grid=grid)


def _k_region(plant: nr.Hyperbolic2x2) -> Any:
    try:
        return nr.k_region(plant, DELTA_MAX, n_gains=DEFAULT_N_GAINS)
    except CertificationError as exc:
        return exc


#: One fresh-process run of the paper's certificate: the first and the second call, as JSON.
_COLD_RUN = """
import importlib, json, sys, time
import nrobust as nr
import flint
if sys.argv[1] == "loaded":  # the modules the first call imports (nrobust is imported lazily)
    for name in ("nrobust.reports.certificate", "tqdm"):
        importlib.import_module(name)
plant, controller, times = nr.Hyperbolic2x2(1, 1, 1, 1, 1, 0.85), nr.ReflectionController(0.1), []
for _ in range(2):
    t0, c0 = time.perf_counter(), time.process_time()
    nr.certify(plant, controller, delta_max=0.1, rigorous=True)
    times.append((time.perf_counter() - t0, time.process_time() - c0))
print(json.dumps(times))
"""


def cold_section(runs: int) -> None:
    """``certify(paper plant, U_BS2(0.1), rigorous=True)`` in ``runs`` fresh processes per import mode."""
    print(
        f"certify(paper plant, U_BS2(0.1), rigorous=True), {runs} fresh processes per mode; load = 1-min load average"
    )
    for mode, what in (("loaded", "modules loaded beforehand"), ("lazy", "after import nrobust, flint only")):
        rows = []
        for _ in range(runs):
            load = os.getloadavg()[0]
            out = subprocess.run(
                [sys.executable, "-c", _COLD_RUN, mode], capture_output=True, text=True, check=True
            ).stdout
            (first_wall, first_cpu), (second_wall, second_cpu) = json.loads(out.splitlines()[-1])
            rows.append((first_cpu, first_wall, second_cpu, second_wall, load))
            print(
                f"  {mode:<6} first call {first_cpu:.3f} s CPU, {first_wall:.3f} s wall; "
                f"second {second_cpu:.3f} s CPU, {second_wall:.3f} s wall; load {load:.2f}"
            )
        table = np.array(rows)
        print(f"  {what}: median (min - max) over {runs} runs")
        for k, label in enumerate(("first call, CPU ", "first call, wall", "second call, CPU ", "second call, wall")):
            col = table[:, k]
            print(f"    {label:<18} {np.median(col):.3f} s ({np.min(col):.3f} - {np.max(col):.3f})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the certificate of the paper's plant only")
    parser.add_argument("--cold", type=int, metavar="N", help="only the paper's certificate in N fresh processes")
    args = parser.parse_args()
    if args.cold:
        cold_section(args.cold)
        return
    # first use in the process: modules and FLINT load here, not in a measured call
    warm_plant = next(iter(PLANTS.values()))
    gain = nr.ReflectionController(0.05)
    t_first, _ = timed(lambda: [nr.delay_margin(warm_plant, gain, **kw) for kw in ROUTES.values()])
    print(f"first use in the process (imports, FLINT; the paper's plant with K = 0.05, four routes): {t_first:.3f} s")
    for name, plant in PLANTS.items():
        margins_section(name, plant)
    print("\nbuilding N~ (best of 3; the exact form's cache emptied before each call)")
    for name, plant in PLANTS.items():
        construction_section(name, plant)
    for name, plant in list(PLANTS.items())[: 1 if args.quick else None]:
        certify_section(name, plant)


if __name__ == "__main__":
    main()
