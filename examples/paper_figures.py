"""Figures 1 and 3 of the paper: L2 norm of the closed loop with a delay in the loop
=================================================================================

Plant of the simulation section: ``lam = mu = sigma_pm = sigma_mp = q = 1``, ``rho = 0.85``.
Figure 1: U_BS (eq. (47)) with ``delta = 0`` and ``delta = 0.01``: finite-time
convergence without delay, instability with the smallest delay (Theorem 3,
``rho q = 0.85 > 1/2``). Figure 3: U_BS2 with ``K = 0.1`` (eq. (53)) with
``delta = 0, 0.01, 0.1``: stable for every delay, decaying at the rate ``-ln(0.75)/2`` without delay.

The figures are those of ``nrobust paper`` (:func:`nrobust.reports.paper.paper_figure`: same
horizon, initial state and axis); ``docs/figures/`` holds their output.

Usage::

    python examples/paper_figures.py [OUTPUT_DIR]      # default: out/
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from nrobust.reports.paper import paper_figure


def main(out: str = "out") -> None:
    directory = Path(out)
    directory.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    for number, name in ((1, "fig1_u_bs.png"), (3, "fig3_u_bs2.png")):
        fig = paper_figure(number)
        fig.savefig(directory / name, dpi=120, bbox_inches="tight")
        plt.close(fig)
        print(f"wrote {directory / name}")
    print(f"in {time.perf_counter() - start:.2f} s")


if __name__ == "__main__":
    main(*sys.argv[1:2])
