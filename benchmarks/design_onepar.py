"""One-parameter exact designs on the paper's plant: CPU seconds per design, and the values.

The plant is the paper's section 5 example (lam = mu = sigma+- = sigma-+ = q = 1, rho = 0.85). The
designs are those of ``tests/test_filter_cutoff.py`` and ``docs/design.md``:
:func:`nrobust.hyperbolic.analyses.filter_design.design_filtered_exact` with one of ``K``, ``a``,
``b`` of ``FilteredController(a, b, K)`` free (the margin, or the decay rate under ``delta* >= 0.4``),
:func:`nrobust.design.best_margin` on the unfiltered loop as an ``AffineLoop``, and
:func:`nrobust.design_reflection` (margin; decay rate under ``delta* >= 0.2``). Each design runs in a
fresh process (``--repeat`` of them; the least CPU time is printed, then all of them): the time is
``time.process_time()`` around the design call alone, so it leaves out the imports (nrobust,
scipy.optimize), and counts every thread of the process (a multithreaded BLAS included; with
``OPENBLAS_NUM_THREADS=1`` it is the work of one thread). Printed with each: the optimum, its kind,
the objective, the certified margin and the decay rate, to 13 digits (the designs' accuracy is
1e-10).

Measured on two cores shared with other work (load 1 to 4), the least of 3 runs with
``OPENBLAS_NUM_THREADS=1``, before and after the engine stopped integrating a kernel the factors share
once per factor, computing decay rates that a bound shows cannot be the largest, and computing a
root-free half-plane the nominal count does not use (the values agree to 5e-16, the kinds are the same):

==================  ======  =====
design              before  after
==================  ======  =====
kink_K                0.97   0.53
cutoff_b              1.59   0.62
free_K                1.17   0.59
free_a                1.43   0.58
docs_b                0.53   0.38
rate_b                2.07   0.81
unfiltered_K          0.36   0.24
reflection_margin     0.19   0.17
reflection_rate       0.43   0.36
==================  ======  =====

With the default BLAS threads the CPU time of the filtered designs is up to 0.25 s higher (the
threads of the large products of the scan spin while they wait). What remains of a filtered design:
the certified spectral abscissa of the nominal loop at the design, about half (0.2-0.4 s; the decay
rate needs two, at the design and at the end it approaches), the nominal counts between the phase
wraps (0.1-0.2 s), the certifying delay margin (about 0.1 s) and the scan (0.05-0.2 s).

Run: ``python benchmarks/design_onepar.py [--repeat 3] [--only NAME ...]``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any

# name -> the design in words
CASES: dict[str, str] = {
    "kink_K": "K in [0, 0.14], a = 0, b = 0.05: margin",
    "cutoff_b": "b in [0.8, 1.2], K = -0.0832482936, a = 0.341: margin",
    "free_K": "K in [-0.1, 0.1], a = 0.341, b = 1.008729291: margin",
    "free_a": "a in [0, 1], K = -0.0832482936, b = 1.008729291: margin",
    "docs_b": "b in [0.3, 1.5], K = 0.1, a = 0: margin",
    "rate_b": "b in [0.05, 1], K = 0, a = 0: decay rate, margin >= 0.4",
    "unfiltered_K": "best_margin on the unfiltered loop (AffineLoop), K in [0, 0.12]",
    "reflection_margin": "design_reflection: margin",
    "reflection_rate": "design_reflection: decay rate, margin >= 0.2",
}


def _design(name: str) -> Callable[[], Any]:
    """The design ``name`` as a call returning its :class:`~nrobust.design.GainDesign`."""
    import nrobust as nr
    from nrobust.design import best_margin
    from nrobust.hyperbolic.analyses.filter_design import design_filtered_exact, filtered_loop

    plant = nr.Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
    filtered = {
        "kink_K": {"K": (0.0, 0.14), "a": 0.0, "b": 0.05},
        "cutoff_b": {"K": -0.0832482936, "a": 0.341, "b": (0.8, 1.2)},
        "free_K": {"K": (-0.1, 0.1), "a": 0.341, "b": 1.008729291},
        "free_a": {"K": -0.0832482936, "a": (0.0, 1.0), "b": 1.008729291},
        "docs_b": {"K": 0.1, "a": 0.0, "b": (0.3, 1.5)},
    }
    if name in filtered:
        return lambda: design_filtered_exact(plant, parameters=filtered[name]).design
    if name == "rate_b":
        parameters = {"K": 0.0, "a": 0.0, "b": (0.05, 1.0)}
        return lambda: design_filtered_exact(plant, "decay_rate", parameters=parameters, margin_at_least=0.4).design
    if name == "unfiltered_K":
        loop = filtered_loop(plant, {"K": None, "a": 0.0, "b": 0.0}).affine()
        return lambda: best_margin(loop, (0.0, 0.12))
    if name == "reflection_margin":
        return lambda: nr.design_reflection(plant).design
    return lambda: nr.design_reflection(plant, "decay_rate", margin_at_least=0.2).design


def _one(name: str) -> None:
    """Run the design ``name`` once in this process and print its time and values as JSON."""
    import scipy.optimize  # noqa: F401  (imported before the clock starts, as the designs load it on first use)

    run = _design(name)
    cpu, wall = time.process_time(), time.perf_counter()
    d = run()
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    end = None if d.end is None else [d.end.kind, d.end.K]
    out = {"cpu": cpu, "wall": wall, "K": d.K, "kind": d.kind, "value": d.value, "margin": d.margin}
    print(json.dumps({**out, "rate": d.decay_rate, "end": end, "certified": d.certified}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="fresh processes per design (the least CPU is shown)")
    parser.add_argument("--only", nargs="*", choices=sorted(CASES), help="designs to run (default: all)")
    parser.add_argument("--one", choices=sorted(CASES), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        _one(args.one)
        return
    print(f"{'design':18s} {'CPU s':>6s}  {'optimum':>17s}  {'kind':18s} {'margin':>16s} {'decay rate':>16s}  runs")
    for name in args.only or CASES:
        runs = []
        for _ in range(args.repeat):
            proc = subprocess.run([sys.executable, __file__, "--one", name], capture_output=True, text=True, check=True)
            runs.append(json.loads(proc.stdout.strip().splitlines()[-1]))
        best = min(runs, key=lambda r: r["cpu"])
        kind = best["kind"] if best["end"] is None else f"{best['kind']} ({best['end'][0]})"
        cpus = " ".join(f"{r['cpu']:.2f}" for r in runs)
        print(
            f"{name:18s} {best['cpu']:6.2f}  {best['K']:17.13g}  {kind:18s} {best['margin']:16.13g} "
            f"{best['rate']:16.13g}  {cpus}"
        )
        print(f"{'':18s} {CASES[name]}, certified {best['certified']}")


if __name__ == "__main__":
    main()
