"""An open channel from its physics: steady flow, Riemann coordinates, normal form, delay margins
==============================================================================================

A rectangular canal pool, L = 3000 m, B = 7 m, bed slope S0 = 1e-4, Manning n = 0.02 s/m^(1/3),
discharge Q = 14 m^3/s, constant inflow upstream, the discharge at the downstream gate
actuated. The classical numbers of this channel are reproduced from their definitions:

- the normal depth h_n, which satisfies Manning's formula Q = (1/n) B h (R^(2/3)) S0^(1/2)
  with R = B h/(B + 2h) (printed with its residual): 2.9302 m;
- the critical depth h_c = (q^2/g)^(1/3), q = Q/B: 0.7415 m, and the Froude number of the
  uniform flow, V/sqrt(g h_n) = 0.1273 (subcritical);
- the backwater (M1) curve behind a gate holding 3.5 m: the depth decreases upstream
  towards h_n, as every M1 profile does.

The uniform flow is then linearised, its Riemann coordinates brought to the paper's normal
form (time in minutes, ``time_unit = 60``), and the loop analysed: the delay margin of U_BS2(K) and of the
proportional feedback U = k xi_1(t, L) on the downstream Riemann invariant, the latter
checked against the kernel-free Laplace route. Last, the pool held at 3.5 m (the M1
curve): there lam/mu varies, so no normal form exists and the margin (46.37 min for
U = 0.6 xi_1(L)) and the certificate take the characteristic route, checked on the
Laplace route.

These are the numbers of the model's own definitions (Manning's formula, the critical
depth, the backwater ODE); no published figure of this canal is reproduced.

Run: python examples/saint_venant.py [OUT_DIR]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

import nrobust
from nrobust.hyperbolic.controllers import ReflectionController, StateFeedback
from nrobust.hyperbolic.feedback import laplace_loop_factors
from nrobust.hyperbolic.frontends import GRAVITY, saint_venant

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("example_output")
out.mkdir(parents=True, exist_ok=True)

L, B, S0, N, Q = 3000.0, 7.0, 1e-4, 0.02, 14.0
start = time.perf_counter()
canal = saint_venant(L, B, S0, Q, manning=N, time_unit=60.0)
hn, hc = canal.normal_depth, canal.critical_depth
R = B * hn / (B + 2.0 * hn)
manning_residual = Q - B * hn * R ** (2.0 / 3.0) * np.sqrt(S0) / N
print(f"normal depth h_n = {hn:.6f} m (Manning residual {manning_residual:.1e} m^3/s)")
print(f"critical depth h_c = {hc:.6f} m (q^2/g)^(1/3) = {((Q / B) ** 2 / GRAVITY) ** (1 / 3):.6f} m")
print(f"Froude number of the uniform flow: {canal.froude[0]:.6f}")

backwater = saint_venant(L, B, S0, Q, manning=N, downstream_depth=3.5)
print("M1 backwater curve, depth every 500 m from upstream:", np.round(backwater.depth[::33], 4))
assert np.all(np.diff(backwater.depth) > 0) and backwater.depth[0] > hn

form = canal.system.normal_form()
print("normal form:", form.system)
print(nrobust.classify(form.system).statement)
for K in (0.0, 0.3):
    margin = nrobust.delay_margin(canal.system, ReflectionController(K))
    print(f"U_BS2(K = {K}): delay margin {margin.margin:.6g} min at w = {margin.omega:.6g} rad/min")
feedback = StateFeedback(0.6)
margin = nrobust.delay_margin(canal.system, feedback)
omega = margin.omega
assert omega is not None  # the loop has a crossing
A, B_ = laplace_loop_factors(canal.system, 0.6, 0.0, 0.0, np.array([1j * omega]))
residual = abs(A[0] + B_[0] * np.exp(-1j * omega * margin.margin))
print(f"U = 0.6 xi_1(L): delay margin {margin.margin:.6g} min = {60 * margin.margin:.6g} s")
print(f"|F(i w*; delta*)| by the kernel-free Laplace route: {residual:.1e}")

# The same pool held at 3.5 m by the gate: the M1 profile above, lam/mu varies along the pool and no
# normal form exists. Margin and certificate take the characteristic route (varying_delay_form),
# checked on the kernel-free Laplace route (examples/saint_venant_backwater.toml: the same by TOML).
pool = saint_venant(L, B, S0, Q, manning=N, downstream_depth=3.5, time_unit=60.0).system
print(nrobust.classify(pool).statement)
held = nrobust.delay_margin(pool, feedback)
assert held.omega is not None
A, B_ = laplace_loop_factors(pool, 0.6, 0.0, 0.0, np.array([1j * held.omega]), steps=2000)
held_residual = abs(A[0] + B_[0] * np.exp(-1j * held.omega * held.margin))
print(f"backwater pool, U = 0.6 xi_1(L): delay margin {held.margin:.6g} min (Laplace residual {held_residual:.1e})")
print(nrobust.certify(pool, feedback, delta_max=10.0, k_region=False).verdict)
print(f"total {time.perf_counter() - start:.2f} s")
(out / "saint_venant.txt").write_text(
    f"h_n {hn:.9g}\nh_c {hc:.9g}\nFroude {canal.froude[0]:.9g}\nmargin_state_feedback {margin.margin:.9g}\n"
    f"margin_backwater {held.margin:.9g}\n"
)
