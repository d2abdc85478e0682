"""Physical plants: the delay margin of the Saint-Venant example from scratch, stage by stage.

The canal pool of ``examples/saint_venant.py``, pool 2 of the Corning canal of Litrico and
Fromion (2004) (L = 3000 m, trapezoidal: bottom width 7 m, side slope 1.5; S0 = 1e-4, Manning
n = 0.02, Q = 10 m^3/s, gate downstream, time in minutes), in uniform flow with the feedback
U = xi_1(t, L), the same pool at its published operating point, 2.1 m held by the gate (an
M1 backwater curve: ``lam/mu`` varies, the characteristic route replaces the normal form and
its kernels),
then the ARZ road of ``examples/arz.py`` with U_BS2(0). Each stage is
timed on its own (best of ``--repeat`` runs, every cache cleared between runs):

1. steady profile and Riemann coordinates (:func:`nrobust.hyperbolic.plants.frontends.saint_venant`);
2. normal form (:meth:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2.normal_form`);
3. kernels and delay form, the loop factors ``A, B`` (``kernel_grid`` points);
4. the certified delay margin of ``A + B e^{-delta s}``.

Run: ``python benchmarks/plants.py [--repeat 3] [--kernel-grid 201]``.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from typing import Any

from nrobust.hyperbolic import controllers
from nrobust.hyperbolic.loops.controllers import ReflectionController, StateFeedback, loop_factors
from nrobust.hyperbolic.plants.frontends import arz, saint_venant
from nrobust.margins.margin import delay_margin


def stages(build: Callable[[], Any], controller: Any, kernel_grid: int) -> tuple[dict[str, float], float]:
    """Seconds per stage and the margin, caches cleared first."""
    controllers._distributed_part.cache_clear()
    controllers._kernels.cache_clear()
    controllers.cached_varying_delay_form.cache_clear()
    times: dict[str, float] = {}
    start = time.perf_counter()
    plant = build().system
    times["front end"] = time.perf_counter() - start
    if plant.constant_ratio:
        start = time.perf_counter()
        plant.normal_form()
        times["normal form"] = time.perf_counter() - start
    start = time.perf_counter()
    A, B = loop_factors(plant, controller, kernel_grid)
    label = "kernels + loop factors" if plant.constant_ratio else "characteristic route + loop factors"
    times[label] = time.perf_counter() - start
    start = time.perf_counter()
    margin = delay_margin(A, B)
    times["delay margin"] = time.perf_counter() - start
    return times, float(margin.margin)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--kernel-grid", type=int, default=201)
    args = parser.parse_args()
    cases = {
        "Saint-Venant, U = xi_1(L)": (
            lambda: saint_venant(3000.0, 7.0, 1e-4, 10.0, side_slope=1.5, manning=0.02, time_unit=60.0),
            StateFeedback(1.0),
        ),
        "Saint-Venant, M1 backwater (varying lam/mu), U = xi_1(L)": (
            lambda: saint_venant(
                3000.0, 7.0, 1e-4, 10.0, side_slope=1.5, manning=0.02, downstream_depth=2.1, time_unit=60.0
            ),
            StateFeedback(1.0),
        ),
        "ARZ, U_BS2(0)": (
            lambda: arz(500.0, 40.0, 0.16, 1.0, 60.0, 0.12, time_unit=60.0),
            ReflectionController(0.0),
        ),
    }
    for name, (build, controller) in cases.items():
        runs = [stages(build, controller, args.kernel_grid) for _ in range(args.repeat)]
        best = {stage: min(run[0][stage] for run in runs) for stage in runs[0][0]}
        print(f"== {name}: delay margin {runs[0][1]:.10g} min (kernel_grid = {args.kernel_grid})")
        for stage, seconds in best.items():
            print(f"   {stage:<36s} {seconds:8.3f} s")
        print(f"   {'total':<36s} {sum(best.values()):8.3f} s")


if __name__ == "__main__":
    main()
