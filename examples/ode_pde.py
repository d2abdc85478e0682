"""Section 4.2.2 of the paper: an ODE at the unactuated end of the transport line
==============================================================================

    u_t + u_x = 0,  v_t - v_x = 0,  u(t, 0) = q v(t, 0) + c x(t),  v(t, 1) = rho u(t, 1) + U(t),
    x' = a x + b v(t, 0).

With u(t, 1) as output, u(s, 1) = (q + b/(s - a)) e^{-2s} (rho u(s, 1) + U(s)) (the paper
absorbs c into b): from U to u(t, 1) the plant is P/(1 - rho P) with P = (q + b/(s-a)) e^{-2s},
a neutral transfer function of degree 1. Closing the loop with U = -K u(t - delta, 1)
gives the characteristic function

    F(s) = (s - a) - (q (s - a) + b) (rho - K e^{-delta s}) e^{-2s},

whose difference operator 1 - rho q e^{-2s} + K q e^{-(2 + delta)s} is the one of
eq. (13): cancelling the reflection (K = rho) gives zero delay margin as
soon as ``|rho q| > 1/2``, and a partial reflection trades decay rate for delay margin.

Run: python examples/ode_pde.py [OUT_DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np

import nrobust
from nrobust import QuasiPolynomial, QuasiTransferFunction, plots
from nrobust.hyperbolic.analyses import Tradeoff

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("example_output")
out.mkdir(parents=True, exist_ok=True)
a, b, q, rho = -1.0, 0.5, 1.0, 0.7

# the plant from U to u(t, 1), built as a python-control user would ---------------------
line = QuasiPolynomial([[b - q * a, q]], [2.0])  # (q (s - a) + b) e^{-2s}
ode = QuasiPolynomial([[-a, 1.0]], [0.0])  # s - a
P = QuasiTransferFunction(line, ode)  # (q + b/(s - a)) e^{-2s}
plant = P.feedback(rho, sign=1)  # the reflection rho closes a positive loop: P / (1 - rho P)
print("plant from U to u(t, 1):", plant)

Ks = np.array([rho, 0.5, 0.3, 0.25, 0.2, 0.15, 0.1, 0.05, 0.0])
decay, margins = [], []
for K in Ks:
    delta = 0.1
    closed = plant.feedback(QuasiTransferFunction(K, 1.0).delay(delta))  # U = -K u(t - delta, 1)
    A, B = plant.den, plant.num * K  # closed.den = A + B e^{-delta s}
    s = np.array([0.3 + 2.0j])
    assert np.allclose(closed.den(s), A(s) + B(s) * np.exp(-delta * s))
    dm = nrobust.delay_margin(A, B)
    sa = nrobust.spectral_abscissa(A + B)
    decay.append(-sa.value)
    margins.append(dm.margin)
    print(f"K = {K:4.2f}: nominal decay rate {-sa.value:7.4f}, delay margin {dm.margin:8.4g} ({dm.reason})")

fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
plots.tradeoff_plot(Tradeoff(Ks, np.array(decay), np.array(margins), np.full(Ks.size, np.nan)), ax=axes[0])
axes[0].set_title("ODE-PDE loop: decay rate against delay margin (labels: K)", fontsize="small")
K = 0.2
A, B = plant.den, plant.num * K
plots.nyquist_response(A, B, delta=0.5 * margins[list(Ks).index(K)], omega_max=50.0).plot(ax=axes[1])
fig.savefig(out / "ode_pde.png", dpi=110)
print(f"figures in {out}/")
