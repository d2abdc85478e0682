"""Section 2.3.2 of the paper: filtering the finite-time law, U_1 = -(1 + a s)/(1 + b s) rho u(1, s)
=================================================================================================

The delayed loop is the neutral equation (16) of degree 1 with difference
operator ``b - b rho q e^{-tau s} + a rho q e^{-(tau+delta) s}``: it is strongly stable when
``|rho q| (1 + |a|/b) < 1``, and the paper's sufficient conditions are eq. (17),
``a/b < (1 - |rho q|)/|rho q|`` and ``a < (1 - |rho q|)/|rho q|``. This example

1. certifies one filter (a, b) = (0.1, 1) and writes its report,
2. maps the admissible (a, b) on a grid (exact margins) against eq. (17),
3. simulates the PDE under the filtered law with and without a loop delay.

Run: python examples/filtered_controller.py [OUT_DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np

import nrobust
from nrobust import plots
from nrobust.hyperbolic import TransportSystem
from nrobust.hyperbolic.analyses import ab_region
from nrobust.reports.report import write_report

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("example_output")
out.mkdir(parents=True, exist_ok=True)
system = TransportSystem(lam=1.0, mu=1.0, q=1.0, rho=0.85)

# 1. one filter, certified ----------------------------------------------------------------
controller = nrobust.FilteredController(a=0.1, b=1.0)
cert = nrobust.certify(system, controller, delta_max=0.2)
print(cert.verdict)
print(
    f"difference operator at delta = 0.2: gamma_0 = {cert.principal_delayed.gamma_0:.4g} "
    f"(= |rho q| (1 + a/b) = {0.85 * 1.1:.4g})"
)
files = write_report(cert, out / "filtered_report")
print(f"report: {files.html}")

# 2. admissible filters on a grid ---------------------------------------------------------
a = np.linspace(-0.6, 0.6, 13)
b = np.linspace(0.2, 2.0, 10)
region = ab_region(system, 0.2, a, b)
agree = np.mean(region.admissible[region.paper_conditions])
print(
    f"{int(region.admissible.sum())} of {region.admissible.size} grid filters tolerate every delay in [0, 0.2]; "
    f"{100 * agree:.0f}% of those meeting eq. (17) do"
)
fig, ax = plt.subplots(figsize=(6, 4.5))
AA, BB = np.meshgrid(a, b, indexing="ij")
ax.plot(AA[region.admissible], BB[region.admissible], "s", color="tab:green", ms=5, label="margin > 0.2 (exact)")
ax.plot(AA[~region.admissible], BB[~region.admissible], "s", color="tab:red", ms=5, alpha=0.4, label="not")
ax.contour(AA, BB, region.paper_conditions.astype(float), levels=[0.5], colors="k")
ax.set_xlabel("a")
ax.set_ylabel("b")
ax.set_title("Filtered U_BS: admissible (a, b); black: boundary of eq. (17)", fontsize="small")
ax.legend(fontsize="x-small")
fig.savefig(out / "filtered_ab_region.png", dpi=110)

# 3. the plant itself -----------------------------------------------------------------
runs = [
    nrobust.simulate(system, controller, d, 20.0, lambda x: np.ones_like(x), lambda x: np.sin(np.pi * x), cells=100)
    for d in (0.0, 0.2)
]
fig, ax = plt.subplots(figsize=(6, 4))
plots.simulation_plot(runs, labels=["delta = 0", "delta = 0.2"], ax=ax)
fig.savefig(out / "filtered_simulation.png", dpi=110)
print(f"final norms: {[f'{r.norm[-1]:.2e}' for r in runs]}; figures in {out}/")
