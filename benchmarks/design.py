"""One-gain designs of ``U_BS2(K)`` on the paper's example: time and accuracy.

The plant is the paper's section 5 example (lam = mu = sigma+- = sigma-+ = q = 1, rho = 0.85)
with ``U_BS2(K)`` (eq. (53)), whose loop (eq. (60)) is built once
(:func:`nrobust.hyperbolic.analyses.kregion.u_bs2_loop`). Measured, best of ``--repeat`` runs,
wall and CPU time (a loaded machine inflates the wall time):

* :func:`nrobust.design.best_margin` on ``K in 0.99 (-k, k)`` (goal: the optimum to 1e-10 in
  under 1 s), with the floating-point certificate, and the certificate alone (one
  :func:`nrobust.margins.delay_margin` at the design) to split the scan and the equations
  from it; the same with ``rigorous=True`` (the margin proven in ball arithmetic);
* :func:`nrobust.design.best_decay_rate` with ``margin_at_least = 0.2``;
* :func:`nrobust.design_reflection` from the plant (the loop factors included).

Run: ``python benchmarks/design.py [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from typing import Any

from nrobust import Hyperbolic2x2, design_reflection
from nrobust.design import best_decay_rate, best_margin
from nrobust.hyperbolic.analyses.kregion import u_bs2_loop
from nrobust.margins import delay_margin


def _timed(run: Callable[[], Any], repeat: int) -> tuple[Any, float, float]:
    """``(result, best wall time, best CPU time)`` over ``repeat`` runs."""
    walls, cpus, result = [], [], None
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        result = run()
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    return result, min(walls), min(cpus)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    plant = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
    loop = u_bs2_loop(plant)
    kb = 0.15
    bounds = (-0.99 * kb, 0.99 * kb)
    rows = []
    best, wall, cpu = _timed(lambda: best_margin(loop, bounds), args.repeat)
    rows.append(("best_margin (scan + equations + certificate)", best, wall, cpu))
    _, wall, cpu = _timed(lambda: delay_margin(loop.A, loop.B(best.K)), args.repeat)
    rows.append(("  of which the certificate (delay_margin at K*)", None, wall, cpu))
    proven, wall, cpu = _timed(lambda: best_margin(loop, bounds, rigorous=True), 1)
    rows.append(("best_margin, rigorous=True", proven, wall, cpu))
    fast, wall, cpu = _timed(lambda: best_decay_rate(loop, bounds, margin_at_least=0.2), args.repeat)
    rows.append(("best_decay_rate, margin >= 0.2", fast, wall, cpu))
    plant_level, wall, cpu = _timed(lambda: design_reflection(plant), 1)
    rows.append(("design_reflection(plant) from scratch", plant_level.design, wall, cpu))
    for name, result, wall, cpu in rows:
        print(f"{name:50s} wall {wall:6.3f} s  cpu {cpu:6.3f} s")
        if result is not None:
            print(
                f"    K = {result.K:.15g}  value = {result.value:.15g}  kind = {result.kind}  "
                f"accuracy (K, value) = ({result.accuracy[0]:.2g}, {result.accuracy[1]:.2g})  {result.certified}"
            )


if __name__ == "__main__":
    main()
