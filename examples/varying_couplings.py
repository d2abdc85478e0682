"""Spatially varying couplings and lam != mu: the delay form against the kernel-free route
=======================================================================================

The plant (18)-(20) with sigma+-(x) = 1 + 0.5 cos(pi x), sigma-+(x) = 0.8 x, lam = 1,
mu = 2, q = 1, rho = 0.6. Backstepping maps it to the neutral distributed-delay equation
(39); its characteristic function 1 - rho q e^{-tau s} + int N~ e^{-nu s} must
vanish exactly where the Laplace-domain boundary function v(1, s) - rho u(1, s) does,
which is computed with no kernel at all (Magnus integration of the transformed ODE).

1. certified open-loop poles of H_1 and the boundary function at them (two routes),
2. the certificate and report of U_BS2(K = 0.1) on [0, 0.2],
3. the stability chart of U_BS2 in (K, delta).

Run: python examples/varying_couplings.py [OUT_DIR]
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
from nrobust.hyperbolic import Hyperbolic2x2, boundary_function
from nrobust.hyperbolic.analyses import stability_chart
from nrobust.reports.report import write_report

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("example_output")
out.mkdir(parents=True, exist_ok=True)


def sigma_pm(x: np.ndarray) -> np.ndarray:
    return 1.0 + 0.5 * np.cos(np.pi * x)


def sigma_mp(x: np.ndarray) -> np.ndarray:
    return 0.8 * x


system = Hyperbolic2x2(lam=1.0, mu=2.0, sigma_pm=sigma_pm, sigma_mp=sigma_mp, q=1.0, rho=0.6)
print(system, nrobust.classify(system).statement, sep="\n")

# 1. two routes to the open-loop spectrum ----------------------------------------------
H1 = nrobust.open_loop_tf(system)
poles = H1.poles((-2.0, 2.0, -30.0, 30.0))
scaled = boundary_function(system, poles.roots, scaled=True)
print(
    f"{poles.count} certified open-loop poles (rightmost Re s = {poles.roots.real.max():.5f}); "
    f"kernel-free boundary function there: max |.| = {np.abs(scaled).max():.1e}"
)

# 2. certificate and report -------------------------------------------------------------
cert = nrobust.certify(system, nrobust.ReflectionController(0.1), delta_max=0.2, n_gains=5)
print(cert.verdict)
files = write_report(cert, out / "varying_report")
print(f"report: {files.html}")

# 3. stability chart ----------------------------------------------------------------------
kb = nrobust.classify(system).k_bound
chart = stability_chart(system, np.linspace(-kb, kb, 11), np.linspace(0.0, 1.0, 21))
fig, ax = plt.subplots(figsize=(6.4, 4.4))
plots.stability_chart_plot(chart, ax=ax, k_bound=kb)
fig.savefig(out / "varying_chart.png", dpi=110)
print(f"figures in {out}/")
