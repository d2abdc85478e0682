"""Section 2 of the paper, step by step: two transport equations coupled at the boundaries
=======================================================================================

    u_t + lam u_x = 0,  v_t - mu v_x = 0,  u(t, 0) = q v(t, 0),  v(t, 1) = rho u(t, 1) + U(t)

1. The open-loop transfer function H_0 = 1/(1 - rho q e^{-tau s}) and its poles,
   certified, against their closed form (ln(rho q) + 2 k pi i)/tau.
2. The finite-time law U = -rho u(t, 1), eq. (9): its delayed loop
   has the difference operator 1 - rho q e^{-tau s} + rho q e^{-(tau+delta) s}; with
   ``|rho q| > 1/2`` the margin is zero (eq. (11)) and the root chains move to Re s > 0.
3. The reflection-preserving law U = -K u(t, 1), eq. (12): stable for every delay
   when ``|K| < (1 - |rho q|)/|q|``.
4. The same loops handed to python-control (FRD and Pade models).

Run: python examples/transport_tutorial.py [OUT_DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import control
import matplotlib.pyplot as plt
import numpy as np

import nrobust
from nrobust import plots
from nrobust.hyperbolic import TransportSystem

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("example_output")
out.mkdir(parents=True, exist_ok=True)

system = TransportSystem(lam=1.0, mu=1.0, q=1.0, rho=0.85)
print(nrobust.classify(system).statement)

# 1. open loop -------------------------------------------------------------------------
H0 = nrobust.open_loop_tf(system)
poles = H0.poles((-1.0, 1.0, -20.0, 20.0))
k = np.arange(-3, 4)
closed_form = (np.log(system.rho_q) + 2j * np.pi * k) / system.tau
print(
    f"H_0: {poles.count} certified poles in the box; nearest to the closed form differ by "
    f"{max(np.min(np.abs(poles.roots - z)) for z in closed_form):.1e}"
)

# 2. and 3. the two control laws with a loop delay --------------------------------------
delta = 0.05
fig, axes = plt.subplots(1, 2, figsize=(10, 4.5))
for ax, controller in zip(axes, (nrobust.FiniteTimeController(), nrobust.ReflectionController(0.1))):
    margin = nrobust.delay_margin(system, controller)
    F = nrobust.characteristic(system, controller, delta)
    D = F.principal_part()
    print(
        f"{type(controller).__name__}: delay margin {margin.margin:.4g} ({margin.reason}); "
        f"gamma_0 = {D.gamma_0:.3g}, rightmost chain Re s = {D.spectral_bound().upper:.4g}"
    )
    plots.root_map_plot(F, (-1.5, 0.8, -70.0, 70.0), ax=ax)
    ax.set_title(f"{type(controller).__name__}, delta = {delta:g}", fontsize="small")
fig.savefig(out / "transport_root_maps.png", dpi=110)

fig, axes = plt.subplots(1, 2, figsize=(10, 5))
for ax, controller in zip(axes, (nrobust.FiniteTimeController(), nrobust.ReflectionController(0.1))):
    A, B = nrobust.loop_factors(system, controller)
    resp = plots.nyquist_response(A, B, delta, omega_max=60.0)
    resp.plot(ax=ax)
    print(
        f"Nyquist, {type(controller).__name__}: closed-loop zeros in Re s > 0: "
        f"{resp.rhp_zeros if resp.rhp_zeros is not None else 'no finite count: ' + resp.note}"
    )
fig.savefig(out / "transport_nyquist.png", dpi=110)

# root locus in delta: the finite-time loop's roots move right as delta grows; for every
# delta > 0 the difference operator has chains in Re s > 0 (at |Im s| of order pi/delta,
# above the box for the smallest delays)
fig, ax = plt.subplots(figsize=(6, 4.5))
locus = plots.root_locus_response(
    lambda d: nrobust.characteristic(system, nrobust.FiniteTimeController(), d),
    [0.02, 0.05, 0.1, 0.2],
    (-1.5, 0.8, -40.0, 40.0),
    name="delta",
)
locus.plot(ax=ax)
for d, r in zip(locus.params, locus.roots):
    c_D = nrobust.characteristic(system, nrobust.FiniteTimeController(), d).principal_part().spectral_bound().upper
    print(f"U_BS, delta = {d:g}: rightmost root in the box {r.real.max():.3f}, rightmost chain c_D = {c_D:.3f}")
fig.savefig(out / "transport_locus_delta.png", dpi=110)

# K-admissible region: eq. (54) is exact for the transport system
region = nrobust.k_region(system, 1.0, n_gains=9)
print(f"gains stable for every delay in [0, 1]: {region.intervals}, paper bound |K| < {region.paper_bound:.3g}")

# 4. python-control -------------------------------------------------------------------
w = np.linspace(0.0, 1.0, 50)
model, err = nrobust.pade_approximation(H0, 6, w)
frd = nrobust.to_frd(H0, np.linspace(0.01, 10.0, 400))
print(
    f"Pade model of order {len(model.den[0][0]) - 1}, max error {err.max():.1e} on [0, 1] rad/s; "
    f"FRD |H_0(i)| = {abs(control.evalfr(frd, 1j * frd.omega[39])):.4g}"
)
print(f"figures in {out}/")
