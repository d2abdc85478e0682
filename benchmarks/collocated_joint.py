"""The joint design of U_BS2(K) and the collocated observer's reflection against a grid of certified margins.

On the paper's plant (``Hyperbolic2x2(1, 1, 1, 1, 1, 0.85)``): :func:`nrobust.design_collocated_output_feedback`
(margin objective, or the decay rate under ``--margin-at-least``), then a ``--points`` x ``--points`` grid of
``(K, kappa)`` about the design (``+- --half`` in each), each point with ``gamma_0 <= gamma_max`` given its
certified delay margin (:func:`nrobust.margins.delay_margin` on the loop built there by ``loop_factors``; the
others are outside the region the design searches). Printed: the design, its certificate, the CPU seconds of the
design and of the grid, the grid's best point; the design must match or beat it.

Run: ``python benchmarks/collocated_joint.py [--margin-at-least 0.18] [--points 15] [--half 0.03]
[--center K KAPPA]`` (``--center`` skips the design and only scans the grid).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import nrobust as nr
from nrobust.hyperbolic.analyses import collocated_joint_loop
from nrobust.hyperbolic.loops.controllers import CollocatedOutputFeedback, ReflectionController, loop_factors
from nrobust.margins import delay_margin

PLANT = nr.Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--margin-at-least", type=float, default=None)
    parser.add_argument("--points", type=int, default=15)
    parser.add_argument("--half", type=float, default=0.03)
    parser.add_argument("--center", type=float, nargs=2, default=None)
    parser.add_argument("--gamma-max", type=float, default=0.9)
    args = parser.parse_args()
    if args.center is None:
        objective = "margin" if args.margin_at_least is None else "decay_rate"
        start = time.process_time()
        design = nr.design_collocated_output_feedback(
            PLANT, objective, margin_at_least=args.margin_at_least, gamma_max=args.gamma_max
        )
        print(f"design: {design!r}, {time.process_time() - start:.1f} s of CPU")
        print(f"  margin {design.design.margin}, decay rate {design.design.decay_rate:.9f}")
        for run in design.design.runs:
            print(f"  start {run.start} -> {run.parameters}: {run.value:.9g} ({run.evaluations} evaluations)")
        for reason in design.failed:
            print(f"  failed: {reason[:200]}")
        center = (design.K, design.kappa)
    else:
        center = tuple(args.center)
    loop = collocated_joint_loop(PLANT)
    start = time.process_time()
    best = (-np.inf, None)
    for K in np.linspace(center[0] - args.half, center[0] + args.half, args.points):
        for kappa in np.linspace(center[1] - args.half, center[1] + args.half, args.points):
            if loop.gamma(K, kappa) > args.gamma_max:
                continue
            A, B = loop_factors(PLANT, CollocatedOutputFeedback(ReflectionController(float(K)), 0.0, float(kappa)))
            dm = delay_margin(A, B)
            if dm.verified and dm.margin > best[0]:
                best = (dm.margin, (float(K), float(kappa)))
    print(f"grid: best certified margin {best[0]:.10g} at {best[1]}, {time.process_time() - start:.1f} s of CPU")


if __name__ == "__main__":
    main()
