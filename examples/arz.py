"""Congested freeway traffic (Aw-Rascle-Zhang model) from its physics to delay margins
===================================================================================

The model is that of Yu and Krstic, "Traffic congestion control for Aw-Rascle-Zhang model",
Automatica 100 (2019) 38-51: p(rho) = v_m (rho/rho_m)^gamma, V(rho) = v_m - p(rho), constant
inflow, outflow actuated at x = L (ramp metering), linearised about a uniform congested
equilibrium. The parameters are those of the TrafficPDE1D environment of PDE Control Gym
(L. Bhan et al., github.com/lukebhan/PDEControlGym; tutorial
docs/source/tutorials/Trafficarz1d_tutorial.rst, environment
pde_control_gym/src/environments1d/traffic_arz_env.py), which implements this model, links the
Automatica paper as its source, and takes Greenshields' V(rho) = v_m (1 - rho/rho_m), i.e.
gamma = 1: a road of X = 500 m, v_max = 40 m/s, ro_max = 0.16 veh/m, relaxation time
tau = 60 s, and the equilibrium ro_steady = 0.12 veh/m, v_steady = 10 m/s (the environment
refuses a pair with v_steady != V(ro_steady)). The simulation section of the Automatica paper
itself could not be consulted, so none of its figures or numbers is claimed here.

Reproduced, and asserted in tests/test_frontends.py:

- the published equilibrium velocity v* = V(rho*) = 10 m/s (exact);
- fixed by the model for these parameters: p* = v_m rho*/rho_m = 30 m/s, the characteristic
  speeds lam_1 = v* = 10 m/s and lam_2 = v* - gamma p* = -20 m/s (the tutorial's
  v* + rho* (-v_m/rho_m); negative: congestion, waves travel upstream), the flow
  q* = rho* v* = 1.2 veh/s = 4320 veh/h, and the critical density
  rho_m (1 + gamma)^(-1/gamma) = 80 veh/km;
- the finite time of the backstepping controller U_BS (eq. (47) of the reference paper):
  ``t_F = L/v* + L/|lam_2|`` = 50 s + 25 s = 75 s, by simulation (the norm is 5 % of its initial
  value at 70 s and 4e-6 of it from 75.5 s on, a residual of second order in the cells);
- the open loop, marginally stable: F(s) = s/(s + c) (1 - e^(-t_F (s + c))) with
  c = L/(tau v* t_F) = 1/90 1/s, the root s = 0 (vehicles are conserved between a fixed
  inflow and a fixed outflow) and damped stop-and-go modes -c + 2 pi i k/t_F (k != 0):
  period t_F = 75 s, decay time 1/c = 90 s; found by certified counts.

Then what the source does not do: the delay margins of U_BS, of U_BS2(0) (eq. (53); in
closed form pi/(2c) = 45 pi s = 141.37 s, since its closed loop is
(1 - e^(-t_F (s + c))) (s + c e^(-delta s))/(s + c)) and of proportional ramp metering
U = k u(t, L), in minutes (``time_unit = 60``).

Run: python examples/arz.py [OUT_DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import nrobust
from nrobust import with_accuracy
from nrobust.hyperbolic.loops.controllers import (
    FiniteTimeController,
    OpenLoop,
    ReflectionController,
    StateFeedback,
    characteristic,
)
from nrobust.hyperbolic.plants.frontends import arz
from nrobust.hyperbolic.simulate import simulate

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("example_output")
out.mkdir(parents=True, exist_ok=True)

L, RHO_STAR, TAU = 500.0, 0.12, 60.0
PUBLISHED_V_STAR = 10.0  # m/s, PDE Control Gym's v_steady
road = arz(length=L, v_max=40.0, rho_max=0.16, gamma=1.0, relaxation=TAU, rho_star=RHO_STAR, time_unit=60.0)
print(f"v* = {road.v_star:.6f} m/s (published: {PUBLISHED_V_STAR:g} m/s), p* = {road.p_star:.6f} m/s")
print(f"q* = rho* v* = {RHO_STAR * road.v_star:.6f} veh/s = {3600 * RHO_STAR * road.v_star:.1f} veh/h")
print(f"characteristic speeds: {road.speeds[0]:.6f}, {road.speeds[1]:.6f} m/s")
print(f"critical density: {1000 * road.critical_density:.4f} veh/km")
t_f = L / road.speeds[0] + L / abs(road.speeds[1])
c = L / (TAU * road.v_star * t_f)
plant = road.system
print(f"t_F = L/v* + L/|lam_2| = {t_f:.6f} s; rho~ q~ = {plant.rho_q:.6f} = e^(-c t_F), c = {c:.6f} 1/s")


def _seconds(margin: nrobust.DelayMargin) -> str:
    """The margin (in minutes, the plant's time unit) in seconds, with the digits its accuracy supports."""
    accuracy = None if margin.accuracy is None else 60.0 * margin.accuracy
    return with_accuracy(60.0 * margin.margin, accuracy)


def bump(x: np.ndarray) -> np.ndarray:
    """A density-and-velocity bump vanishing at both ends (compatible with the boundaries)."""
    return 0.01 * np.sin(np.pi * x / L) ** 2


sim = simulate(plant, FiniteTimeController(), 0.0, 100.0 / 60.0, bump, bump, cells=200, snapshot_every=1)
seconds = 60.0 * sim.times
after = sim.norm[seconds >= t_f + 120.0 * sim.dt].max() / sim.norm[0]
print(f"U_BS: ||(u, v)||/||(u, v)(0)|| = {sim.norm[np.argmin(abs(seconds - 70.0))] / sim.norm[0]:.4f} at 70 s,")
print(f"      at most {after:.2e} after t_F (simulated, 200 cells)")
roots = nrobust.find_roots(characteristic(plant, OpenLoop()), (-1.2, 0.6, -12.0, 12.0)).roots / 60.0
print("open-loop roots (1/s) in [-0.02, 0.01] x [-0.2, 0.2]:", np.round(roots[np.argsort(roots.imag)], 6))
print(f"chain: -c = {-c:.6f}, spacing 2 pi/t_F = {2 * np.pi / t_f:.6f} (1/s)")
margins = {"U_BS": FiniteTimeController(), "U_BS2(0)": ReflectionController(0.0)}
for name, controller in margins.items():
    margin = nrobust.delay_margin(plant, controller)
    print(f"{name}: delay margin {with_accuracy(margin.margin, margin.accuracy)} min = {_seconds(margin)} s")
bs2 = margin.margin
print(f"U_BS2(0) in closed form: pi/(2c) = {np.pi / (2 * c):.6g} s")
for k in (0.2, 0.5):
    margin = nrobust.delay_margin(plant, StateFeedback(k))
    print(f"U = {k} u(L): delay margin {with_accuracy(margin.margin, margin.accuracy)} min = {_seconds(margin)} s")
(out / "arz.txt").write_text(f"v_star {road.v_star:.9g}\nlam_2 {road.speeds[1]:.9g}\nt_F {t_f:.9g}\nmargin {bs2:.9g}\n")
