"""Local designs under a speed tolerance maximise the least decay rate of the nominal plant and the corners.

``design_filtered(..., speed_tolerance=eps)`` and ``design_state_feedback(..., "decay_rate", speed_tolerance=eps)``
maximise ``min_j r_j(p)`` (``r_j`` the decay rate at ``delta = 0`` of the nominal loop and of the four corner
plants' loops, the law designed on the nominal plant) over the parameters meeting the window at every plant
(``optimize_loop(..., worst_case=True)``). Oracles, sharing no code with the design's loops:

* the transport plant ``Hyperbolic2x2(1, 2, 0, 0, 1, 0.5)`` (uncoupled: the law has no kernels, so
  :func:`~nrobust.hyperbolic.loops.controllers.loop_factors` of the corner plant itself, built here by
  ``dataclasses.replace`` of ``lam`` and ``mu``, is the PDE's loop under the designed law) gives each plant's
  rate by :func:`~nrobust.roots.spectral_abscissa` and its requirement ``delta* > d`` by the public
  :func:`~nrobust.hyperbolic.analyses.delay_margin` of the plant and the controller;
* a brute-force grid of ``FilteredController(0.73, b, K)`` over the design's box (``K`` in ``[0.3, 0.6]``, ``b`` in
  ``[0.5, 1.0]``; the zero ``a = 0.73`` fixed) with that oracle: the design must beat its best feasible point up to
  the rates' accuracy (about ``1e-14``; ``1e-9`` allowed), and a grid of spacing ``2e-3`` about the design must not
  beat it by more than the largest change of the least rate between neighbours of that grid (a local optimum: no
  better point within a cell). The least rate there is binding at corners, not at the nominal plant: at the design
  the corners ``(-0.2, -0.2)`` and ``(0.2, 0.2)`` tie at 1.5455 while the nominal rate is 1.90;
* the nominal-rate design of the same problem (``optimize_loop`` with the same loops and requirement,
  ``worst_case=False``: the behaviour before the least rate was maximised) from the same start has the least rate
  1.518 (measured), below the design's 1.5455;
* a state feedback on the same plant with a constant basis: the design is the proportional law at the bound
  ``k = -0.3``, whose rates are ``-ln|(rho + k) q| / tau'`` (mpmath, 40 digits), and the nominal-rate design
  (measured) guarantees no more.
"""

from __future__ import annotations

import dataclasses

import mpmath as mp
import numpy as np
import pytest

from nrobust import Hyperbolic2x2, StateFeedback
from nrobust.design import optimize_loop
from nrobust.errors import ParameterError
from nrobust.hyperbolic.analyses import delay_margin, design_filtered, design_state_feedback, mismatch_gain_loop
from nrobust.hyperbolic.analyses.filter_design import FilteredDesign, FilteredLoop, filtered_loop
from nrobust.hyperbolic.analyses.state_design import BasisGain
from nrobust.hyperbolic.loops.controllers import FilteredController, loop_factors
from nrobust.roots import spectral_abscissa

TRANSPORT = Hyperbolic2x2(1.0, 2.0, 0.0, 0.0, 1.0, 0.5)
EPS, MARGIN, ZERO = 0.2, 1.0, 0.73
K_BOX, B_BOX = (0.3, 0.6), (0.5, 1.0)
X0 = (0.45, 0.75)
CORNERS = [(a, b) for a in (-EPS, EPS) for b in (-EPS, EPS)]  # the order of tolerance.points[:4]
PLANTS = [TRANSPORT] + [
    dataclasses.replace(TRANSPORT, lam=TRANSPORT.lam * (1 + a), mu=TRANSPORT.mu * (1 + b)) for a, b in CORNERS
]
# the rates' accuracy on these loops is about 1e-14 (the abscissae's own); this bounds it with room
RATE_TOL = 1e-9


def _rates(K: float, b: float) -> list[float]:
    """The decay rate at ``delta = 0`` of each plant (nominal first, then the corners) under the law."""
    law = FilteredController(ZERO, b, K)
    rates = []
    for plant in PLANTS:
        A, B = loop_factors(plant, law)
        rates.append(-spectral_abscissa(A + B).value)
    return rates


def _feasible(K: float, b: float) -> bool:
    """Stable for every delay in ``[0, MARGIN]`` on every plant (the public delay margin, verified)."""
    law = FilteredController(ZERO, b, K)
    return all(delay_margin(p, law).margin > MARGIN for p in PLANTS)


@pytest.fixture(scope="module")
def design() -> FilteredDesign:
    return design_filtered(
        TRANSPORT,
        margin_at_least=MARGIN,
        speed_tolerance=EPS,
        parameters={"K": K_BOX, "a": ZERO, "b": B_BOX},
        x0=X0,
        starts=1,
        kernel_grid=31,
    )


def _grid_best(Ks: np.ndarray, bs: np.ndarray) -> tuple[float, float]:
    """``(best feasible least rate, largest change of the least rate between grid neighbours)``."""
    least = np.array([[min(_rates(K, b)) for b in bs] for K in Ks])
    step = max(float(np.abs(np.diff(least, axis=0)).max()), float(np.abs(np.diff(least, axis=1)).max()))
    for index in np.argsort(-least, axis=None):  # the best first: the first feasible one is the grid's optimum
        i, j = np.unravel_index(index, least.shape)
        if _feasible(Ks[i], bs[j]):
            return float(least[i, j]), step
    return -np.inf, step


@pytest.mark.long
def test_the_least_rate_beats_a_grid_of_certified_parameters(design: FilteredDesign) -> None:
    """The design's least rate beats the grid's best feasible point, and no nearby grid point beats it by more than
    a cell's change; a corner binds (the nominal rate is far above)."""
    c = design.controller
    assert design.certified and c.a == ZERO
    assert design.value == design.worst_decay_rate == min(design.corner_decay_rates)
    assert design.design.decay_rate > design.value + 0.2  # the nominal plant is not what binds
    best, _ = _grid_best(np.linspace(*K_BOX, 15), np.linspace(*B_BOX, 15))
    assert design.value >= best - RATE_TOL
    assert design.value > best + 0.01  # 1.5455 against 1.4880 on this grid: the grid is no better
    near_K = np.clip(c.K + 2e-3 * np.arange(-3, 4), *K_BOX)
    near_b = np.clip(c.b + 2e-3 * np.arange(-3, 4), *B_BOX)
    near, step = _grid_best(near_K, near_b)
    assert design.value >= near - step - RATE_TOL
    assert _feasible(c.K, c.b)


def test_the_least_rate_beats_the_nominal_rate_design(design: FilteredDesign) -> None:
    """The nominal-rate design of the same loops, requirement, bounds and start (``worst_case=False``) guarantees
    less at the corners (1.518 against 1.5455)."""
    loop = filtered_loop(TRANSPORT, {"K": None, "a": ZERO, "b": None})
    corners = []
    for a, b in CORNERS:
        g = mismatch_gain_loop(TRANSPORT, a, b, kernel_grid=31)
        corners.append(FilteredLoop(g.A, g.B0, g.R, loop.free, loop.fixed))
    nominal = optimize_loop(loop, [K_BOX, B_BOX], delays=(0.0, MARGIN), scenarios=tuple(corners), x0=X0, starts=1)
    K, b = nominal.parameters
    old_least = min(_rates(K, b))
    assert nominal.certified and nominal.value == nominal.decay_rate and not nominal.scenario_abscissae
    assert design.value >= old_least + 0.01


def test_the_corner_rates_are_those_of_the_corner_plants(design: FilteredDesign) -> None:
    """The design's own corner abscissae (``design.scenario_abscissae``) and those restated
    (``corner_abscissae``) are the corner plants' own loops' to their accuracy; ``value`` the least of them."""
    c = design.controller
    direct = _rates(c.K, c.b)
    assert design.tolerance is not None and [tuple(p) for p in design.tolerance.points[:4]] == CORNERS
    assert abs(design.design.decay_rate - direct[0]) <= RATE_TOL
    assert len(design.design.scenario_abscissae) == len(design.corner_abscissae) == 4
    for rate, own, restated in zip(direct[1:], design.design.scenario_abscissae, design.corner_abscissae):
        assert own.accuracy is not None and restated.accuracy is not None
        assert abs(-own.value - rate) <= own.accuracy + RATE_TOL
        assert abs(-restated.value - rate) <= restated.accuracy + RATE_TOL
    assert abs(design.design.value - min(direct)) <= RATE_TOL
    acc = design.worst_decay_rate_accuracy
    assert acc is not None and abs(design.value - min(direct)) <= acc + RATE_TOL
    # the two binding corners tie: the optimum is a kink of the least rate
    ranked = sorted(direct)
    assert ranked[1] - ranked[0] < 1e-3 and direct[0] > ranked[0] + 0.2
    data = design.design.to_dict()
    assert len(data["scenario_abscissae"]) == 4


def test_worst_case_needs_the_decay_rate_and_scenarios() -> None:
    loop = filtered_loop(TRANSPORT, {"K": None, "a": ZERO, "b": 0.75})
    with pytest.raises(ParameterError, match="worst_case"):
        optimize_loop(loop, [K_BOX], margin_at_least=MARGIN, worst_case=True)
    with pytest.raises(ParameterError, match="worst_case"):
        optimize_loop(loop, [K_BOX], objective="margin", delays=(0.0, 1.0), scenarios=(loop,), worst_case=True)
    with pytest.raises(ParameterError, match="worst_case"):
        optimize_loop(loop, [K_BOX], delays=(0.0, 1.0), scenarios=(loop,), worst_case="yes")  # type: ignore[arg-type]


def _one(x: np.ndarray) -> np.ndarray:
    return np.ones_like(x)


# the nominal-rate design of the state-feedback problem below (the behaviour before the least rate was maximised,
# measured): k = -0.3, g_u = -0.014406986141581408, g_v = -0.007068919663436362; least rate 0.85836688663152
OLD_STATE_FEEDBACK = (-0.3, -0.014406986141581408, -0.007068919663436362)


def _transport_rate(k: float, e_lam: float, e_mu: float) -> mp.mpf:
    """``-ln|(rho + k) q| / tau'`` at 40 digits: the transport plant's loop at ``delta = 0`` under ``U = k u(t, 1)``
    on the plant with speeds ``lam (1 + e_lam)``, ``mu (1 + e_mu)``."""
    with mp.workdps(40):
        p = TRANSPORT
        tau = 1 / (mp.mpf(p.lam) * (1 + mp.mpf(e_lam))) + 1 / (mp.mpf(p.mu) * (1 + mp.mpf(e_mu)))
        return -mp.log(abs((mp.mpf(p.rho) + mp.mpf(k)) * mp.mpf(p.q))) / tau


def test_a_state_feedback_design_maximises_the_least_rate() -> None:
    """``U = k u(t, 1) + int c u + d v dx`` (a constant basis) with ``|k| <= 0.3``: every rate rises as ``k``
    falls, the corner ``(-0.2, -0.2)`` (the longest round trip) binds, and the least rate is largest at ``k =
    -0.3`` without integral gains, where each rate is ``-ln|(rho + k) q| / tau'`` (mpmath); the nominal-rate design
    (:data:`OLD_STATE_FEEDBACK`) guarantees no more at its corners (the same corner binds there)."""
    design = design_state_feedback(
        TRANSPORT,
        "decay_rate",
        margin_at_least=MARGIN,
        speed_tolerance=EPS,
        k_bounds=(-0.3, 0.3),
        basis=[_one],
        kernel_grid=31,
        starts=2,
    )
    assert design.certified and design.design.local
    assert design.tolerance is not None and [tuple(p) for p in design.tolerance.points[:4]] == CORNERS
    k = design.parameters[0]
    assert k == -0.3 and design.parameters[1:] == (0.0, 0.0)  # the proportional law: its rates in closed form
    for (a, b), own, restated in zip(CORNERS, design.design.scenario_abscissae, design.corner_abscissae):
        oracle = float(_transport_rate(k, a, b))
        assert own.accuracy is not None and restated.accuracy is not None
        assert abs(-restated.value - oracle) <= restated.accuracy + 1e-9 and abs(own.value - restated.value) < 1e-12
    least = float(_transport_rate(k, -EPS, -EPS))
    acc = design.worst_decay_rate_accuracy
    assert acc is not None and abs(design.value - least) <= acc + 1e-9
    assert design.value == design.worst_decay_rate and design.design.decay_rate > design.value + 0.2
    old = StateFeedback(
        OLD_STATE_FEEDBACK[0], BasisGain(OLD_STATE_FEEDBACK[1:2], (_one,)), BasisGain(OLD_STATE_FEEDBACK[2:], (_one,))
    )
    old_least = min(_spectral_rate(plant, old) for plant in PLANTS)
    assert design.value >= old_least - acc


def _spectral_rate(plant: Hyperbolic2x2, law: StateFeedback) -> float:
    A, B = loop_factors(plant, law, 31)
    return float(-spectral_abscissa(A + B).value)
