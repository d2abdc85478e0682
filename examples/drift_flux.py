"""The linearised drift-flux model of a well (n = 2, m = 1): which cancellation is delay-robust
============================================================================================

The paper's Section 5 ("Systems with multiple equations") names the drift-flux model of
gas-liquid flow in a well (Aarsnes, Di Meglio, Evje and Aamo, "Control-oriented
drift-flux modeling of single and two-phase flow for drilling", ASME DSCC 2014, paper
DSCC2014-6121) and, for its linearisation about an equilibrium profile as an ``n + m``
system with ``n = 2``, ``m = 1``, Aarsnes, Di Meglio, Graham and Aamo, "A methodology for
classifying operating regimes in underbalanced-drilling operations", SPE Journal 21(2),
2016 (doi:10.2118/178920-PA). In Riemann coordinates, with ``x`` from the bottom hole (0)
to the choke (1):

* ``u_1``: the upward pressure wave (speed ``c + v``), ``u_2``: the void (gas fraction)
  wave carried by the gas (speed ``v_g``), ``v``: the downward pressure wave (``c - v``);
* at the bottom the downward wave reflects into the upward wave and the void wave,
  ``u(t, 0) = Q v(t, 0)``; at the top the choke reflects both upward waves,
  ``v(t, 1) = R u(t, 1) + U(t)``, ``U`` the choke actuation;
* the friction and gravity source terms couple all three.

**The numbers are illustrative, not published.** No source with numerical values of the
linearised ``2 + 1`` system (speeds, in-domain couplings, reflection coefficients ``Q`` and
``R``) could be found for this example: the drift-flux papers above give the nonlinear
model, its slip law and its steady states, and the control papers that treat ``n + m``
systems (Di Meglio, Vazquez, Krstic and Petit, ACC 2012; Hu, Di Meglio, Vazquez and
Krstic, IEEE TAC 61(11), 2016; Auriol and Di Meglio, Automatica 71, 2016) were not
available here with their simulation parameters. Nothing below is therefore a reproduced
number. The values are in units of the well length and of the pressure wave's travel
time: speeds ``(1, 0.5 | 1)`` (the void wave taken slower than sound by a factor 2 only,
far from a real well, where sound is much faster than the gas; the round trips 2 and 3
keep the chains commensurate), ``Q = (0.9, 0.3)``, ``R = (0.6, 0.4)``, couplings of size
0.02-0.1.

The conclusion does not rest on them. For one actuator the delayed principal part has
``gamma_0 = sum_a (1 + c_a) g_a`` with ``g_a = |R_a U_a Q_a| / |V|`` (``docs/theory.md``,
"Beyond 2x2"), so for *any* parameters full cancellation doubles the open loop's
``gamma_0`` and has no delay margin as soon as ``gamma_0 > 1/2``, and cancelling the
reflection of wave ``a`` alone keeps the principal part strongly stable iff
``gamma_0 + g_a < 1``: the reflection to cancel is the one with the smaller ``g_a``. With
the numbers here ``g = (0.489, 0.110)``: the void wave's.

The script compares static choke feedbacks ``U = K u(t - delta, 1)`` that cancel a
fraction ``c_i`` of each top reflection, ``K = -(c_1 R_1, c_2 R_2)``: for each, the exact
``gamma_0`` of the delayed principal part (Hale and Verduyn Lunel: delay-robust iff below
1), the certified spectral abscissa of the delay-free loop and the delay margin. Full
cancellation (the finite-time designs of Di Meglio et al. 2013, Auriol and Di Meglio 2016)
doubles ``gamma_0`` and has no delay margin; cancelling only the reflection of the slow void
wave keeps a positive one. A simulation of the PDE checks the margin.

Run: ``python examples/drift_flux.py``
"""

from __future__ import annotations

import numpy as np

from nrobust import with_accuracy
from nrobust.hyperbolic.nplusm import NPlusMSystem, cancellation_study, nplusm_delay_margin
from nrobust.hyperbolic.simulate import simulate_nplusm

SYSTEM = NPlusMSystem(
    lam=[1.0, 0.5],
    mu=[1.0],
    sigma=[[-0.05, 0.02, 0.05], [0.1, -0.02, 0.1], [0.05, 0.02, -0.05]],
    q=[[0.9], [0.3]],
    r=[[0.6, 0.4]],
)
REGION = (-0.6, 1.0, -0.25, 5.0)
# (fraction of R_1 cancelled, fraction of R_2 cancelled)
CANCELLATIONS = [(0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0), (0.5, 0.5)]


def main() -> None:
    print(f"drift-flux loop: {SYSTEM.n} + {SYSTEM.m}, round trips {[t for t, _, _ in SYSTEM.principal_terms()[1]]}")
    print(f"{'cancelled (R1, R2)':>20} {'gamma_0':>8} {'abscissa':>10} {'margin':>9}  delay-robust")
    rows = cancellation_study(SYSTEM, CANCELLATIONS, REGION)
    for row in rows:
        cells = f"{row.fractions!s:>20} {row.gamma_0:>8.4f} {row.abscissa:>10.4f} {row.margin.margin:>9.4f}"
        print(f"{cells}  {row.robust}")
    # the simulated PDE on both sides of the margin of "cancel the void-wave reflection only"
    K = [[0.0, -0.4]]
    margin = nplusm_delay_margin(SYSTEM, K).margin

    def w0(x: np.ndarray) -> np.ndarray:
        return np.vstack([np.sin(np.pi * x), 0.5 + 0.0 * x, np.cos(np.pi * x)])

    for factor in (0.8, 1.2):
        # the slope on 40 cells, its accuracy 8 times its change from 20 cells (first-order scheme: on 10 to 160
        # cells the change halves with the cell size, and 8 times it covers the distance to 160 cells)
        coarse, fine = (
            simulate_nplusm(SYSTEM, K, factor * margin, 300.0, w0, cells=n).growth_rate(150.0) for n in (20, 40)
        )
        rate = with_accuracy(fine, 8.0 * abs(fine - coarse))
        print(f"K = {K[0]}, delta = {factor:.1f} x margin: simulated growth rate {rate}")


if __name__ == "__main__":
    main()
