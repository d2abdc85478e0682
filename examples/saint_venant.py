"""An open channel from its physics: a published canal pool, its delays and its delay margins
==========================================================================================

Pool 2 of the Corning canal (ASCE test canal 2) as given by X. Litrico and V. Fromion,
"Simplified modeling of irrigation canals for controller design", Journal of Irrigation and
Drainage Engineering 130(5):373-383, 2004 (doi:10.1061/(ASCE)0733-9437(2004)130:5(373)),
Table 2: length 3000 m, trapezoidal section of bottom width 7 m and side slope 1.5, bed slope
1e-4, Manning n = 0.02 s/m^(1/3), the depth 2.1 m held at the downstream gate; constant
inflow upstream, the discharge at the downstream gate actuated. Their tables of the
integrator-delay-zero (IDZ) model give, for this pool, the "theoretical" delay and backwater
area of the Saint-Venant equations linearised about the backwater curve, at high flow
(Q = 10 m^3/s) and at low flow (Q = 2.5 m^3/s). Reproduced here from the model alone:

- the delay of the downstream wave, tau_1 = int_0^L dx/(V + C): 681.49 s (published 681.5 s)
  and 754.57 s (published 754.6 s), to the published rounding;
- the backwater area A_d = dVol/dY_X at constant discharge, the storage the downstream level
  integrates: 33 860 m^2 (published 33 868 m^2) and 38 198 m^2 (published 38 199 m^2), within
  0.03 % but not to the last printed digit (the source's numerical route to A_d is not known).

The published values were read in the transcription of the paper's tables in the public
repository Adilbaygh/fair-canal-delivery (src/faircanal/idz.py); tests/test_frontends.py
checks all 32 published delays of both ASCE test canals. Numbers of the model with no
published counterpart: the normal depth (1.7644 m at Q = 10 m^3/s, below 2.1 m: the pool lies
on an M1 backwater curve), the critical depth, the Froude number and the upstream delay
tau_2 = int_0^L dx/(C - V).

The same pool in uniform flow at its normal depth is brought to the paper's normal form (time
in minutes, ``time_unit = 60``) and its loops analysed: the delay margins of U_BS2(K) and of the
proportional feedback U = k xi_1(t, L) on the downstream Riemann invariant, the latter checked
against the kernel-free Laplace route. Last, the published operating point (the backwater
curve): lam/mu varies, no normal form exists, and the margin of U = xi_1(L) and the
certificate take the characteristic route, checked on the Laplace route
(examples/saint_venant_backwater.toml: the same by ``nrobust analyze``).

Run: python examples/saint_venant.py [OUT_DIR]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

import nrobust
from nrobust import with_accuracy
from nrobust.hyperbolic.loops.controllers import ReflectionController, StateFeedback
from nrobust.hyperbolic.loops.feedback import laplace_loop_factors
from nrobust.hyperbolic.plants.frontends import saint_venant

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("example_output")
out.mkdir(parents=True, exist_ok=True)

# Litrico and Fromion (2004), Table 2 (pool 2 of the Corning canal) and their IDZ tables.
L, B, M, S0, N = 3000.0, 7.0, 1.5, 1e-4, 0.02  # m, m, side slope, bed slope, Manning (s/m^(1/3))
Y_X = 2.1  # m, the depth held at the downstream gate
PUBLISHED = {10.0: (681.5, 33868.0), 2.5: (754.6, 38199.0)}  # Q (m^3/s): (tau_1 in s, A_d in m^2)

start = time.perf_counter()
for Q, (tau_pub, area_pub) in PUBLISHED.items():
    pool = saint_venant(L, B, S0, Q, side_slope=M, manning=N, downstream_depth=Y_X)
    tau_1, tau_2 = pool.transport_delays
    print(f"Q = {Q:g} m^3/s: normal depth {pool.normal_depth:.4f} m, critical depth {pool.critical_depth:.4f} m")
    print(f"  backwater curve: depth {pool.depth[0]:.4f} m upstream, {pool.depth[-1]:.4f} m at the gate")
    print(f"  Froude number {pool.froude[0]:.4f} upstream, {pool.froude[-1]:.4f} at the gate")
    print(f"  tau_1 = int dx/(V + C) = {tau_1:.2f} s (published {tau_pub} s), tau_2 = int dx/(C - V) = {tau_2:.2f} s")
    print(
        f"  backwater area A_d = {pool.backwater_area:.0f} m^2 (published {area_pub:.0f} m^2, "
        f"{100 * (pool.backwater_area / area_pub - 1):+.3f} %)"
    )
    assert abs(tau_1 - tau_pub) <= 0.05 and abs(pool.backwater_area / area_pub - 1) < 5e-4

# Uniform flow at the normal depth: constant lam/mu, the normal form and its kernels.
Q = 10.0
canal = saint_venant(L, B, S0, Q, side_slope=M, manning=N, time_unit=60.0)
form = canal.system.normal_form()
print("uniform flow, normal form:", form.system)
print(nrobust.classify(form.system).statement)
for K in (0.0, 0.3):
    margin = nrobust.delay_margin(canal.system, ReflectionController(K))
    minutes = with_accuracy(margin.margin, margin.accuracy)
    omega_text = "none" if margin.omega is None else with_accuracy(margin.omega, margin.omega_accuracy)
    print(f"U_BS2(K = {K}): delay margin {minutes} min at w = {omega_text} rad/min")
feedback = StateFeedback(1.0)
margin = nrobust.delay_margin(canal.system, feedback)
omega = margin.omega
assert omega is not None  # the loop has a crossing
A, B_ = laplace_loop_factors(canal.system, 1.0, 0.0, 0.0, np.array([1j * omega]))
residual = abs(A[0] + B_[0] * np.exp(-1j * omega * margin.margin))
seconds = with_accuracy(60.0 * margin.margin, None if margin.accuracy is None else 60.0 * margin.accuracy)
print(f"U = 1.0 xi_1(L): delay margin {with_accuracy(margin.margin, margin.accuracy)} min = {seconds} s")
print(f"|F(i w*; delta*)| by the kernel-free Laplace route: {residual:.1e}")

# The published operating point: the backwater curve, lam/mu varies and no normal form exists.
# Margin and certificate take the characteristic route (varying_delay_form), checked on the
# kernel-free Laplace route.
held_pool = saint_venant(L, B, S0, Q, side_slope=M, manning=N, downstream_depth=Y_X, time_unit=60.0).system
print(nrobust.classify(held_pool).statement)
held = nrobust.delay_margin(held_pool, feedback)
assert held.omega is not None
A, B_ = laplace_loop_factors(held_pool, 1.0, 0.0, 0.0, np.array([1j * held.omega]), steps=2000)
held_residual = abs(A[0] + B_[0] * np.exp(-1j * held.omega * held.margin))
# lam/mu varies: the margin's accuracy comes from the certificate's convergence study on the characteristic route
held_cert = nrobust.certify(held_pool, feedback, delta_max=10.0, k_region=False)
print(
    f"backwater pool, U = 1.0 xi_1(L): delay margin {held_cert.margin_text} min (Laplace residual {held_residual:.1e})"
)
print(held_cert.verdict)
print(f"total {time.perf_counter() - start:.2f} s")
(out / "saint_venant.txt").write_text(
    f"h_n {canal.normal_depth:.9g}\nh_c {canal.critical_depth:.9g}\nFroude {canal.froude[0]:.9g}\n"
    f"tau_1 {canal.transport_delays[0]:.9g}\nmargin_state_feedback {margin.margin:.9g}\n"
    f"margin_backwater {held.margin:.9g}\n"
)
