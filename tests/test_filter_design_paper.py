"""The three-parameter filtered design on the paper's plant (``Hyperbolic2x2(1, 1, 1, 1, 1, 0.85)``).

Oracles: the decay rate ``-ln(q (rho - K))/tau`` of U_BS2(K) at ``delta = 0`` (eq. (60): the kernels
cancel, ``F = 1 - (rho - K) q e^{-tau s}``), at the gains of the exact one-gain designs of
:func:`nrobust.design_reflection` (the equations of the gain's ends, not the local optimiser), and the
strong-stability sum ``|rho q| + |a/b| |K q|`` of the delayed loop, written from the controller.
"""

from __future__ import annotations

import math

import pytest

import nrobust as nr

RHO, Q, TAU = 0.85, 1.0, 2.0


@pytest.fixture(scope="module")
def plant() -> nr.Hyperbolic2x2:
    return nr.Hyperbolic2x2(lam=1.0, mu=1.0, sigma_pm=1.0, sigma_mp=1.0, q=Q, rho=RHO)


@pytest.mark.long
def test_filtered_design_under_a_margin_is_certified_and_no_worse_than_u_bs2(plant: nr.Hyperbolic2x2) -> None:
    best = nr.design_filtered(plant, margin_at_least=0.2, starts=1)
    exact = nr.design_reflection(plant, "decay_rate", margin_at_least=0.2, K_bounds=(-0.1485, 0.1485))
    u_bs2 = -math.log(Q * (RHO - exact.K)) / TAU
    c = best.controller
    assert c.K is not None and best.certified and best.design.margin.margin >= 0.2
    assert best.value >= u_bs2 - 1e-12  # the warm start is U_BS2(K*) with a = b
    assert abs(RHO * Q) + abs(c.a / c.b) * abs(c.K * Q) <= 0.999  # GAMMA_MAX
    assert best.design.runs[0].screened > best.design.runs[0].evaluations // 2


@pytest.mark.long
def test_filtered_design_of_the_margin_is_certified_and_beats_u_bs2(plant: nr.Hyperbolic2x2) -> None:
    best = nr.design_filtered(plant, objective="margin", starts=1, rigorous=True)
    exact = nr.design_reflection(plant, "margin", K_bounds=(-0.1485, 0.1485))
    ball = best.design.margin.margin_ball  # proven in ball arithmetic
    assert ball is not None and best.certified and best.design.rigorous
    lo = ball[0]
    assert lo >= exact.value - 1e-9  # at least the best U_BS2(K), its start
    c = best.controller
    assert c.K is not None
    assert abs(RHO * Q) + abs(c.a / c.b) * abs(c.K * Q) <= 0.999
