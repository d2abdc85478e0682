"""Where the time of ``nrobust paper`` goes: the command's wall time, its serial start and each job's CPU.

``nrobust paper`` (:func:`nrobust.reports.paper.run_paper`) imports what it needs, forks two
worker processes and runs five jobs on them, longest first (the two certificates, the
``(K, delta)`` chart with the trade-off, the simulations of figures 1 and 3, the root locus,
U_BS's Nyquist figure), each drawing its own figures; then it writes the report. Its wall
time is about the serial start (the interpreter, the imports, up to the fork) plus half the
jobs' CPU time plus what the two workers do not share evenly. Each run is a fresh process
(``python -m nrobust paper``, as a user runs it): the wall time of the whole command, the
start until the pool is created, each job's CPU (``time.process_time`` in its worker) and the
load average before the run; then the median and the spread. A loaded machine stretches the
wall time well beyond the CPU times: compare runs at the same load.

Run: ``python benchmarks/paper.py [--runs 5]``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from typing import Any

#: The child: the command's own entry point, with the jobs and the pool's creation timed.
_CHILD = r"""
import json, sys, time
start = time.perf_counter()
from nrobust.plots.base import skip_artist_property_docs
skip_artist_property_docs()
import nrobust.reports.paper as paper
job, make_map, jobs, marks = paper._paper_job, paper.sweep_map, {}, {}

def timed_job(task):
    cpu = time.process_time()
    out = job(task)
    return out, (task[0], time.process_time() - cpu)

def timed_map(*args, **kwargs):
    marks["pool"] = time.perf_counter() - start
    run = make_map(*args, **kwargs)
    def mapped(func, items):
        outs = run(timed_job, list(items))
        jobs.update(dict(cpu for _, cpu in outs))
        return [out for out, _ in outs]
    return mapped

paper._paper_job, paper.sweep_map = timed_job, timed_map
paper.run_paper(sys.argv[1], progress=False)
print(json.dumps({"wall": time.perf_counter() - start, "pool": marks["pool"], "jobs": jobs}))
"""


def run_once() -> dict[str, Any]:
    """One ``nrobust paper`` in a fresh process: wall time, start until the pool, jobs' CPU, load."""
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as out:
        begin = time.perf_counter()
        done = subprocess.run(
            [sys.executable, "-c", _CHILD, os.path.join(out, "paper")], capture_output=True, text=True, check=True
        )
        outer = time.perf_counter() - begin
    result: dict[str, Any] = json.loads(done.stdout.strip().splitlines()[-1])
    result["command"] = outer  # with the interpreter's own start
    result["load"] = load
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    os.environ.setdefault("MPLBACKEND", "Agg")
    runs = [run_once() for _ in range(args.runs)]
    names = list(runs[0]["jobs"])
    print(f"{'load':>5} {'command s':>9} {'start s':>8} " + " ".join(f"{n:>9}" for n in names) + "  (jobs: CPU s)")
    for r in runs:
        jobs = r["jobs"]
        print(f"{r['load']:5.1f} {r['command']:9.2f} {r['pool']:8.2f} " + " ".join(f"{jobs[n]:9.2f}" for n in names))
    commands = [float(r["command"]) for r in runs]
    cpu = [sum(r["jobs"].values()) for r in runs]
    print(
        f"command: median {statistics.median(commands):.2f} s, min {min(commands):.2f}, max {max(commands):.2f}; "
        f"jobs' CPU: median {statistics.median(cpu):.2f} s (goal of the command: under 5 s on a quiet 2-core machine)"
    )


if __name__ == "__main__":
    main()
