"""Congested freeway traffic (Aw-Rascle-Zhang model) from its physics to delay margins
===================================================================================

The ARZ model as set up by Yu and Krstic, "Traffic congestion control for Aw-Rascle-Zhang
model", Automatica 100 (2019): p(rho) = v_m (rho/rho_m)^gamma, V(rho) = v_m - p(rho),
constant inflow, outflow actuated at x = L (ramp metering), on a road of L = 500 m with
v_m = 40 m/s, rho_m = 160 veh/km, gamma = 0.5, relaxation time tau = 60 s and the congested
equilibrium rho* = 120 veh/km. These values are of the kind that paper's simulation uses, but
the paper itself could not be consulted when this example was written, so they are not
checked against it and no figure of it is claimed to be reproduced. What is reproduced, and
checked in tests/test_frontends.py, are the numbers the model fixes in closed form for these
parameters:

- the equilibrium velocity V(rho*) = v_m (1 - (3/4)^(1/2)) = 5.359 m/s (19.29 km/h);
- the characteristic speeds lam_1 = v* = 5.359 m/s and lam_2 = v* - gamma p* = -11.96 m/s
  (p* = v_m (3/4)^(1/2)); the second is negative: congestion, stop-and-go waves travel
  upstream;
- the critical density rho_m (1 + gamma)^(-1/gamma) = 71.11 veh/km above which the traffic
  is congested;
- the boundary gains in Riemann coordinates, q = lam_2/v* and rho = v*/lam_2 (rho q = 1), and
  after the exponential scaling of the relaxation term rho~ q~ = e^(-L/(tau v*)) = 0.2112;
- the open-loop spectrum: the eigenvalue s = 0 (vehicles are conserved between a fixed
  inflow and a fixed outflow) and the chain on Re s = ln(rho~ q~)/tau = -0.01151 1/s,
  spaced 2 pi/tau apart (``tau = L/v* + L/|lam_2|`` = 135.1 s), found by certified counts.

Then the delay margin of the ramp-metering feedback U = k u(t, L), and of U_BS2(0), in
minutes (``time_unit = 60``).

Run: python examples/arz.py [OUT_DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import nrobust
from nrobust.hyperbolic.controllers import OpenLoop, ReflectionController, StateFeedback, characteristic
from nrobust.hyperbolic.frontends import arz

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("example_output")
out.mkdir(parents=True, exist_ok=True)

road = arz(length=500.0, v_max=40.0, rho_max=0.160, gamma=0.5, relaxation=60.0, rho_star=0.120, time_unit=60.0)
print(f"v* = {road.v_star:.6f} m/s = {3.6 * road.v_star:.4f} km/h, p* = {road.p_star:.6f} m/s")
print(f"characteristic speeds: {road.speeds[0]:.6f}, {road.speeds[1]:.6f} m/s")
print(f"critical density: {1000 * road.critical_density:.4f} veh/km")
plant = road.system
print(f"Riemann boundary gains q = {plant.q:.6f}, rho = {plant.rho:.6f}, rho q = {plant.q * plant.rho:.12f}")
print(f"rho~ q~ = {plant.rho_q:.6f}, e^(-L/(tau v*)) = {np.exp(-500.0 / (60.0 * road.v_star)):.6f}")
roots = nrobust.find_roots(characteristic(plant, OpenLoop()), (-1.2, 0.6, -6.0, 6.0)).roots / 60.0
print("open-loop roots (1/s) in [-0.02, 0.01] x [-0.1, 0.1]:", np.round(roots, 6))
print(f"chain: ln(rho~ q~)/tau = {np.log(plant.rho_q) / plant.tau:.6f}, 2 pi/tau = {2 * np.pi / plant.tau:.6f} (1/s)")
for k in (0.2, 1.0):
    margin = nrobust.delay_margin(plant, StateFeedback(k))
    print(f"U = {k} u(L): delay margin {margin.margin:.6g} min = {60 * margin.margin:.6g} s")
margin = nrobust.delay_margin(plant, ReflectionController(0.0))
print(f"U_BS2(0): delay margin {margin.margin:.6g} min = {60 * margin.margin:.6g} s")
(out / "arz.txt").write_text(f"v_star {road.v_star:.9g}\nlam_2 {road.speeds[1]:.9g}\nmargin {margin.margin:.9g}\n")
