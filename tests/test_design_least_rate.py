"""The best guaranteed decay rate under a speed tolerance: the gain maximising the least rate of several loops.

``best_decay_rate(..., worst_case=True)`` maximises ``min_j r_j(K)`` (``r_j`` the decay rate at ``delta = 0`` of the
loop and of each scenario) over the gains meeting the window; ``design_reflection(..., "decay_rate",
speed_tolerance=eps)`` does so with the four corner plants. Oracles:

* two retarded loops ``s + 1 + c(K) e^{-h s}`` whose rates move in opposite directions: the rightmost zero is
  ``W_0(-c h e^h) / h - 1`` (Lambert's principal branch has the largest real part), so the optimum is the tie
  ``r_1(K) = r_2(K)`` solved here by mpmath at 40 digits; the loops are stable for every delay (``|c| < 1 <= |i w +
  1|``), so the window is met on the whole bounds;
* the transport plant ``Hyperbolic2x2(1, 1, 0, 0, 1, 0.85)``: each loop's rate is ``-ln|(rho - K) q| / tau_j``,
  ``tau_j = 1/lam_j + 1/mu_j``; the least is the corner ``(-eps, -eps)``'s (the longest ``tau_j``), largest where
  ``|rho - K|`` is least, and ``|rho - K| + |K| = rho < 1`` on ``[0, rho]`` makes every delay stable there, so the
  optimum is the bound ``0.99 (1 - rho q) / q`` in closed form;
* the paper's plant on 31 kernel points: a grid of gains whose window is certified here at each corner
  (``window_stability`` of the loops from ``mismatch_loop`` of the law, not the affine loops the design searches)
  whose best least rate the design must match or beat to the rates' stated accuracy.
"""

from __future__ import annotations

import math

import mpmath as mp
import numpy as np

from nrobust import Hyperbolic2x2
from nrobust.design import DESIGN_KINDS, best_decay_rate, window_stability
from nrobust.hyperbolic.analyses import design_reflection, mismatch_loop
from nrobust.hyperbolic.loops.controllers import ReflectionController, loop_factors
from nrobust.margins.gain import AffineGainLoop
from nrobust.quasipoly import QuasiPolynomial
from nrobust.reports.design import design_summary
from nrobust.roots import spectral_abscissa

PAPER = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
TRANSPORT = Hyperbolic2x2(1.0, 1.0, 0.0, 0.0, 1.0, 0.85)
ONE_PLUS_S = QuasiPolynomial([[1.0, 1.0]], [0.0])
# loop 1: s + 1 + (0.5 - K) e^{-s} (its rate rises with K); loop 2: s + 1 + (0.02 + K) e^{-2 s} (falls)
LOOP_1 = AffineGainLoop(ONE_PLUS_S, QuasiPolynomial([[0.5]], [1.0]), QuasiPolynomial([[-1.0]], [1.0]))
LOOP_2 = AffineGainLoop(ONE_PLUS_S, QuasiPolynomial([[0.02]], [2.0]), QuasiPolynomial([[1.0]], [2.0]))


def _rate(c: mp.mpf, h: int) -> mp.mpf:
    """The decay rate of ``s + 1 + c e^{-h s}``: ``1 - Re W_0(-c h e^h) / h``."""
    return 1 - mp.re(mp.lambertw(-c * h * mp.e**h)) / h


def test_a_tie_of_two_rates_in_closed_form() -> None:
    """The least rate is largest where the rising and the falling rate meet: kind ``"tie"``, to 1e-12 (the
    brentq tolerance, 1e-12 of the gains' scale, and the abscissae's accuracy, about 1e-14)."""
    design = best_decay_rate(LOOP_1, (0.0, 0.3), delays=(0.0, 1.0), scenarios=(LOOP_2,), worst_case=True)
    with mp.workdps(40):
        K = mp.findroot(lambda k: _rate(mp.mpf("0.5") - k, 1) - _rate(mp.mpf("0.02") + k, 2), mp.mpf("0.045"))
        value = _rate(mp.mpf("0.5") - K, 1)
    assert "tie" in DESIGN_KINDS and design.kind == "tie"
    assert design.K_bracket[0] <= float(K) <= design.K_bracket[1] and abs(design.K - float(K)) < 1e-12
    acc = design.least_rate_accuracy
    assert acc is not None and abs(design.value - float(value)) <= acc + 1e-12
    assert design.decay_rate == -design.abscissa.value and len(design.scenario_abscissae) == 1
    assert all(w.stable for w in design.windows)
    # the nominal design goes to the bound, where the second loop's rate is far lower
    nominal = best_decay_rate(LOOP_1, (0.0, 0.3), delays=(0.0, 1.0), scenarios=(LOOP_2,))
    assert nominal.K == 0.3 and -spectral_abscissa(LOOP_2.A + LOOP_2.B(0.3)).value < float(value) - 0.5
    assert "least_rate=1.17007265914" in repr(design) and "least_rate" not in repr(nominal)


def test_the_transport_plant_in_closed_form() -> None:
    """Every rate is largest at the bound nearest rho; the least is the corner (-0.05, -0.05)'s there."""
    design = design_reflection(TRANSPORT, "decay_rate", margin_at_least=0.1, speed_tolerance=0.05)
    K = 0.99 * (1.0 - 0.85)
    with mp.workdps(40):
        value = -mp.log(mp.mpf("0.85") - mp.mpf(K)) / (2 / mp.mpf("0.95"))
        nominal = -mp.log(mp.mpf("0.85") - mp.mpf(K)) / 2
    assert design.K == K and design.kind == "end"
    acc = design.design.least_rate_accuracy
    assert acc is not None and abs(design.value - float(value)) <= acc
    assert design.value == design.worst_decay_rate
    assert abs(design.design.decay_rate - float(nominal)) <= design.design.abscissa.accuracy


def test_the_paper_plant_matches_a_grid_of_certified_gains() -> None:
    """The design's least rate beats the best least rate of 21 gains whose window [0, 0.1] is certified at the
    nominal plant and the four corners, to the rates' accuracy."""
    eps, grid = 0.05, 31
    design = design_reflection(PAPER, "decay_rate", margin_at_least=0.1, speed_tolerance=eps, kernel_grid=grid)
    corners = [(a, b) for a in (-eps, eps) for b in (-eps, eps)]
    assert design.value == design.worst_decay_rate and design.value < design.design.decay_rate

    def loops(K: float) -> list[tuple[QuasiPolynomial, QuasiPolynomial]]:
        law = ReflectionController(K)
        return [loop_factors(PAPER, law), *(mismatch_loop(PAPER, law, a, b, kernel_grid=grid) for a, b in corners)]

    least = {}
    for K in np.linspace(*design.design.bounds, 21):
        least[float(K)] = min(-spectral_abscissa(A + B).value for A, B in loops(float(K)))
    best = None
    for K in sorted(least, key=least.__getitem__, reverse=True):  # the largest least rate whose window holds
        if all(window_stability(A, B, (0.0, 0.1)).stable for A, B in loops(K)):
            best = K
            break
    assert best is not None
    acc = design.worst_decay_rate_accuracy
    assert acc is not None and design.value >= least[best] - acc
    assert abs(design.value - 0.1068449357) < 1e-9 and design.kind == "window end"
    summary = design_summary(design)
    assert "least decay rate of the nominal plant and the corners 0.10684" in summary and "nominal 0.1722" in summary
    assert not math.isnan(design.design.value_bracket[0])
