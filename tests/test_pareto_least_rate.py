"""Fronts that maximise the least decay rate of a loop and its scenarios (``worst_case``).

Oracles, sharing no code with the optimiser:

* two retarded loops ``s + 1 + c(K) e^{-h s}`` whose rates move in opposite directions with ``K``: loop 1
  ``c = 0.5 - K``, ``h = 1`` (its rate rises with ``K``), the scenario ``c = 0.02 + K``, ``h = 2`` (falls). The
  rightmost zero is ``W_0(-c h e^h) / h - 1`` (Lambert's principal branch has the largest real part), so the
  best least rate is the tie ``r_1(K) = r_2(K)``, solved here by mpmath at 40 digits. Both loops are stable for
  every delay (``|c| < 1 <= |i w + 1|``), so no requirement binds; the loop's own rate is largest at the bound
  ``K = 0.3``, where the scenario's is lower by more than 0.5. The optimiser stops at a pattern step of
  ``POLISH_TOL = 1e-5`` of the width 0.3 (``3e-6`` in ``K``; the designs found are within ``4e-6`` of the tie)
  and the rates' slopes there are 1.55 and -5.31 (mpmath, below), so a step moves the least rate by at most
  ``1.6e-5``: it is compared to the tie's value to ``2e-5`` (the designs found: ``3e-6`` and ``6e-6`` below);
* the filtered law with ``a = b`` (the filter 1) on the transport plant ``Hyperbolic2x2(1, 2, 0, 0, 1, 0.5)``:
  its loop at ``delta = 0`` on the corner plant is ``(1 + a s)(1 - (rho - K) q e^{-tau' s})``, ``tau' = 1/(lam
  (1 + e_lam)) + 1/(mu (1 + e_mu))``, whose rate is ``min(1/a, -ln|(rho - K) q| / tau')``; ``|K| + rho < 1`` leaves
  every delay stable, so the least rate is the corner ``(-eps, -eps)``'s (the longest ``tau'``) at the bound
  ``K = 0.99 (1 - rho q) / q`` of ``design_filtered``'s defaults, computed here by mpmath at 40 digits;
* the same law on the paper's coupled plant, whose corner loops are models on the kernel grid: with ``a = b`` its
  rate is U_BS2(K)'s (the common factor's zero ``-1/a = -10`` is far left), computed on the corner plant built
  here (``dataclasses.replace`` of ``lam`` and ``mu``) under the law's gains from kernels on 201 points (a
  ``StateFeedback`` through ``loop_factors``, not the mismatched loops' route), within ``1e-9`` of the PDE's
  rate (``tests/test_design_corner_rates.py``'s study): the front's stated accuracy plus ``1e-9`` must hold.
"""

from __future__ import annotations

import dataclasses
import json

import matplotlib
import mpmath as mp
import numpy as np
import pytest

from nrobust import Hyperbolic2x2, QuasiPolynomial, StateFeedback
from nrobust.design import pareto_front
from nrobust.errors import ParameterError
from nrobust.hyperbolic.analyses import design_filtered, filtered_front
from nrobust.hyperbolic.kernels.constant import solve_kernels
from nrobust.hyperbolic.loops.controllers import ReflectionController, loop_factors
from nrobust.roots import spectral_abscissa

matplotlib.use("Agg")

ONE_PLUS_S = QuasiPolynomial([[1.0, 1.0]], [0.0])
BOUNDS = [(0.0, 0.3)]
# the least rate at the design against the tie's (module notes)
TIE_TOL = 2e-5
TRANSPORT = Hyperbolic2x2(1.0, 2.0, 0.0, 0.0, 1.0, 0.5)
EPS = 0.2
FILTER_ONE = {"K": None, "a": 0.1, "b": 0.1}
PAPER = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
# the oracle's kernel grid: within 1e-9 of the limit (module notes)
ORACLE_GRID, ORACLE_ERROR = 201, 1e-9


def rising(p: np.ndarray) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``s + 1 + (0.5 - K) e^{-(1 + delta) s}``."""
    return ONE_PLUS_S, QuasiPolynomial([[0.5 - p[0]]], [1.0])


def falling(p: np.ndarray) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``s + 1 + (0.02 + K) e^{-(2 + delta) s}``."""
    return ONE_PLUS_S, QuasiPolynomial([[0.02 + p[0]]], [2.0])


def lambert_rate(c: mp.mpf, h: int) -> mp.mpf:
    """The decay rate of ``s + 1 + c e^{-h s}``: ``1 - Re W_0(-c h e^h) / h``."""
    return 1 - mp.re(mp.lambertw(-c * h * mp.e**h)) / h


def tie() -> tuple[float, float]:
    """``(K, rate)`` where the two rates are equal, at 40 digits."""
    with mp.workdps(40):
        K = mp.findroot(lambda k: lambert_rate(mp.mpf("0.5") - k, 1) - lambert_rate(mp.mpf("0.02") + k, 2), 0.045)
        return float(K), float(lambert_rate(mp.mpf("0.5") - K, 1))


def test_the_tie_bounds_the_slopes() -> None:
    """The study behind ``TIE_TOL``: a pattern step of ``3e-6`` in ``K`` about the tie moves either rate by less
    than ``1.6e-5`` (slopes 1.55 and -5.31)."""
    K, _ = tie()
    with mp.workdps(40):
        for c0, sign, h in ((mp.mpf("0.5"), -1, 1), (mp.mpf("0.02"), 1, 2)):
            for dK in (-3e-6, 3e-6):
                moved = lambert_rate(c0 + sign * mp.mpf(K + dK), h) - lambert_rate(c0 + sign * mp.mpf(K), h)
                assert 0.0 < abs(float(moved)) < 1.6e-5 < TIE_TOL


def test_a_front_of_the_least_rate_finds_the_tie() -> None:
    """Each point at the tie (kind of optimum of the least rate), not at the bound the loop's own rate prefers."""
    K, value = tie()
    front = pareto_front(rising, BOUNDS, [0.5, 1.0], scenarios={"falling": falling}, worst_case=True, x0=[0.15])
    assert front.worst_case and front.certified and front.infeasible == ()
    np.testing.assert_allclose(front.decay_rates, [value, value], atol=TIE_TOL)
    for design, rate, accuracy in zip(front.designs, front.decay_rates, front.decay_rate_accuracies):
        assert abs(design.parameters[0] - K) < 1e-5
        assert len(design.scenario_abscissae) == 1 and rate == design.value
        assert accuracy is not None and accuracy < TIE_TOL
    # the loop's own rate: the bound, where the scenario's rate is far below the tie's
    nominal = pareto_front(rising, BOUNDS, [0.5, 1.0], scenarios={"falling": falling}, x0=[0.15])
    assert not nominal.worst_case and nominal.designs[0].parameters[0] == pytest.approx(0.3, abs=1e-4)
    with mp.workdps(40):
        at_bound = float(lambert_rate(mp.mpf("0.32"), 2))
    assert at_bound < value - 0.5
    assert "decay_rates=[1.1700" in repr(front) and "(least of the loop and 1 scenario)" in repr(front)
    assert "least" not in repr(nominal)
    data = json.loads(json.dumps(front.to_dict(), allow_nan=False))
    assert data["worst_case"] and data["objective"] == front.objective_text
    assert front.objective_text == "the least decay rate at delta = 0 of the loop and the 1 scenario"
    assert nominal.objective_text == "the loop's decay rate at delta = 0"
    assert data["nominal_decay_rates"] == [d.decay_rate for d in front.designs]

    from nrobust.plots import pareto_plot

    drawn = pareto_plot(front)
    assert drawn.axes.get_ylabel() == "least decay rate of the loop and the scenarios"
    assert drawn.axes.get_title().startswith("Best least decay rate")


def test_worst_case_needs_scenarios() -> None:
    with pytest.raises(ParameterError, match=r"worst_case must be False without scenarios"):
        pareto_front(rising, BOUNDS, [0.5], worst_case=True)
    with pytest.raises(ParameterError, match=r"worst_case must be True or False"):
        pareto_front(rising, BOUNDS, [0.5], scenarios=[falling], worst_case="yes")  # type: ignore[arg-type]


def test_filtered_front_under_a_speed_tolerance_is_design_filtered() -> None:
    """Each point of the front is ``design_filtered``'s design at its margin, and its least rate is the corner
    ``(-eps, -eps)``'s rate in closed form (module notes), within the stated accuracy (about 6 s of CPU)."""
    with mp.workdps(40):
        K = mp.mpf("0.99") * (1 - mp.mpf(TRANSPORT.rho) * mp.mpf(TRANSPORT.q)) / mp.mpf(TRANSPORT.q)
        tau = 1 / (mp.mpf(TRANSPORT.lam) * (1 - mp.mpf(EPS))) + 1 / (mp.mpf(TRANSPORT.mu) * (1 - mp.mpf(EPS)))
        least = float(-mp.log(abs((mp.mpf(TRANSPORT.rho) - K) * mp.mpf(TRANSPORT.q))) / tau)
    front = filtered_front(TRANSPORT, [0.5, 1.0], speed_tolerance=EPS, parameters=FILTER_ONE, x0=[0.0])
    assert front.worst_case and front.certified and front.infeasible == ()
    assert [len(r) for r in front.scenario_abscissae] == [4, 4]
    for rate, accuracy in zip(front.decay_rates, front.decay_rate_accuracies):
        assert accuracy is not None and abs(rate - least) <= accuracy
    for d, rate, design in zip(front.required, front.decay_rates, front.designs):
        single = design_filtered(
            TRANSPORT, margin_at_least=float(d), speed_tolerance=EPS, parameters=FILTER_ONE, x0=[0.0], starts=1
        )
        assert single.certified and design.parameters == single.design.parameters
        accuracy = single.worst_decay_rate_accuracy
        assert accuracy is not None and abs(rate - single.value) <= accuracy
        assert design.decay_rate > rate + 0.5  # the nominal rate, 1.25 times the least


@pytest.mark.long  # about 60 s of CPU: the corner loops on 31 kernel points, each restated with its model error
def test_filtered_front_on_a_coupled_plant_states_the_model_error() -> None:
    """The paper's plant, ``speed_tolerance=0.05``: the point's least rate against the corner loops on 201 kernel
    points (module notes), within the accuracy the front states (the corners' convergence studies)."""
    eps = 0.05
    front = filtered_front(PAPER, [0.1], speed_tolerance=eps, parameters=FILTER_ONE, x0=[0.1], kernel_grid=31)
    assert front.worst_case and front.certified
    ((K,),) = (d.parameters for d in front.designs)
    law = ReflectionController(K).feedback_law(PAPER, solve_kernels(PAPER, ORACLE_GRID))
    feedback = StateFeedback(law.boundary_gain, law.gain_u, law.gain_v)
    A, B = loop_factors(PAPER, ReflectionController(K))
    oracle = [-spectral_abscissa(A + B).value]
    for (e_lam, e_mu), sa in zip([(a, b) for a in (-eps, eps) for b in (-eps, eps)], front.scenario_abscissae[0]):
        corner = dataclasses.replace(PAPER, lam=PAPER.lam * (1.0 + e_lam), mu=PAPER.mu * (1.0 + e_mu))
        A, B = loop_factors(corner, feedback)
        oracle.append(-spectral_abscissa(A + B).value)
        assert sa.model_error is not None and sa.model_error > 0.0  # restated on a model: its error studied
    (accuracy,) = front.decay_rate_accuracies
    assert accuracy is not None and accuracy < 1e-5  # the convergence studies are not vacuous
    assert abs(front.decay_rates[0] - min(oracle)) <= accuracy + ORACLE_ERROR
    assert front.designs[0].decay_rate > front.decay_rates[0] + 0.05  # the nominal 0.172, the least 0.107
    assert "decay_rates=[0.10684" in repr(front) and str(float(front.decay_rates[0])) not in repr(front)
