"""Throughput of nrobust.sweeps: points per second on one worker and on all cores.

The per-point analysis is the one a delay-margin study runs: the closed-form delay
margin of ``F(s) = s + a + b e^{-delta s}`` (``delta* = arccos(-a/b) / sqrt(b^2 - a^2)``
for ``b > |a|``) and a certified count of the roots of ``F`` in the right half-plane box
``(0, 3) x (-100, 100)`` (``nrobust.roots.count_roots``), which also cross-checks the
margin: the count is zero exactly when ``delta < delta*``.

Printed: points per second serially in this process (the peer), on one worker process,
on all cores, on a Dask LocalCluster when distributed is installed, and the parallel
efficiency ``rate(all cores) / (cores * rate(1 worker))``.

Run: ``python benchmarks/sweep.py [--points N] [--repeat R]``. Each rate is the best of R
runs; process pools are started inside the timed call, as a user pays for them.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Sequence

import numpy as np

import nrobust
from nrobust.roots import count_roots
from nrobust.sweeps.executors import cpu_count


def analyse(a: float, delta: float, b: float = 1.0) -> dict:
    """Closed-form delay margin of s + a + b e^{-delta s} and its right half-plane root count."""
    margin = math.inf if a >= abs(b) else math.acos(-a / b) / math.sqrt(b * b - a * a)
    F = nrobust.QuasiPolynomial([[a, 1.0], [b]], [0.0, delta])
    n_unstable = int(count_roots(F, (0.0, 3.0, -100.0, 100.0)))
    return {"delta_star": margin, "n_unstable": n_unstable, "consistent": (n_unstable == 0) == (delta < margin)}


def _timed(points: Sequence[dict], executor: object, repeat: int) -> tuple[float, nrobust.SweepResult]:
    """Best rate (points per second) of ``repeat`` sweeps, pool start-up included."""
    best = 0.0
    for _ in range(repeat):
        start = time.perf_counter()
        res = nrobust.sweep(analyse, points, executor)
        best = max(best, len(points) / (time.perf_counter() - start))
    return best, res


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=400, help="number of grid points (default 400)")
    parser.add_argument("--repeat", type=int, default=3, help="best of this many runs (default 3)")
    args = parser.parse_args()
    n_a = max(2, round(math.sqrt(args.points / 2)))
    points = nrobust.grid(a=np.linspace(-0.8, 0.8, n_a), delta=np.linspace(0.05, 3.0, max(1, args.points // n_a)))
    cores = cpu_count()

    rate_serial, reference = _timed(points, "serial", args.repeat)
    consistent = reference.table()["consistent"]
    rows = [("serial (this process)", rate_serial, reference)]
    rate_one, one = _timed(points, 1, args.repeat)
    rows.append(("1 worker process", rate_one, one))
    rate_all, full = _timed(points, cores, args.repeat)
    rows.append((f"{cores} worker processes", rate_all, full))
    try:
        import distributed
    except ImportError:
        distributed = None  # type: ignore[assignment]  # the Dask row is left out
    if distributed is not None:
        with (
            distributed.LocalCluster(
                n_workers=cores, threads_per_worker=1, processes=True, dashboard_address=":0", silence_logs=50
            ) as cluster,
            distributed.Client(cluster) as client,
        ):
            rate_dask, on_dask = _timed(points, client, args.repeat)
        rows.append((f"Dask LocalCluster, {cores} workers", rate_dask, on_dask))

    print(
        f"nrobust.sweeps on {len(points)} points, {cores} cores; per point: closed-form margin "
        f"+ certified right half-plane root count ({1e3 / rate_serial:.2f} ms serially)"
    )
    print(f"  margin and root count agree on {int(consistent.sum())}/{len(points)} points")
    print(f"  {'executor':<34}{'points/s':>10}{'vs serial':>11}  identical")
    for name, rate, res in rows:
        print(f"  {name:<34}{rate:>10.1f}{rate / rate_serial:>10.2f}x  {res == reference}")
    print(
        f"  speed-up all cores vs 1 worker: {rate_all / rate_one:.2f}x; "
        f"parallel efficiency {rate_all / (cores * rate_one):.0%}"
    )


if __name__ == "__main__":
    main()
