"""The decay rates a design under a speed tolerance guarantees: each corner's and the least.

``design_reflection(..., "decay_rate", speed_tolerance=eps)`` maximises the least decay rate of the nominal plant
and the corners among the gains meeting the window at the corners (the filtered and state-feedback designs too,
over their parameters); the rate at a corner can be far lower than the nominal (the paper's plant: 0.172 nominal,
0.107 at (-0.05, -0.05)). Oracles: on a transport plant the corner loop at
``delta = 0`` is ``1 - (rho - K) q e^{-tau' s}``, ``tau' = 1/(lam (1 + e_lam)) + 1/(mu (1 + e_mu))``, whose rate
``-ln|(rho - K) q| / tau'`` is computed here by mpmath at 40 digits; on the paper's coupled plant the loop of the
corner plant built here (``dataclasses.replace`` of ``lam`` and ``mu``) under the law's gains from kernels on 201
points (:func:`~nrobust.hyperbolic.loops.controllers.loop_factors` of a ``StateFeedback``, not the mismatched loop's
route). The corners' rates with the design's kernel grid of 31 points move by ``1.2e-7`` to 61 points and ``4.6e-9``
more to 121 (a ratio of about 25 as the grid doubles), so the oracle on 201 points is within ``1e-9`` of the PDE's
rate: the design's stated accuracy plus ``1e-9`` must hold."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import mpmath as mp
import pytest

from nrobust import Hyperbolic2x2, StateFeedback
from nrobust.hyperbolic.analyses import design_filtered, design_reflection, design_state_feedback, mismatch_abscissa
from nrobust.hyperbolic.kernels.constant import solve_kernels
from nrobust.hyperbolic.loops.controllers import ReflectionController, loop_factors
from nrobust.reports.design import _local_design_lines, _reflection_markdown, design_summary
from nrobust.roots import spectral_abscissa

PAPER = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
TRANSPORT = Hyperbolic2x2(1.0, 2.0, 0.0, 0.0, 1.0, 0.5)
# the oracle's kernel grid: within 1e-9 of the limit (module notes)
ORACLE_GRID, ORACLE_ERROR = 201, 1e-9


def _transport_rate(K: float, e_lam: float, e_mu: float) -> mp.mpf:
    """``-ln|(rho - K) q| / tau'`` at 40 digits (the transport plant's corner loop at ``delta = 0``)."""
    with mp.workdps(40):
        p = TRANSPORT
        tau = 1 / (mp.mpf(p.lam) * (1 + mp.mpf(e_lam))) + 1 / (mp.mpf(p.mu) * (1 + mp.mpf(e_mu)))
        return -mp.log(abs((mp.mpf(p.rho) - mp.mpf(K)) * mp.mpf(p.q))) / tau


@pytest.mark.parametrize("rigorous", [False, True])
def test_corner_rates_of_a_transport_plant_in_closed_form(rigorous: bool) -> None:
    """Each corner's rate to its stated accuracy; the least is at (-eps, -eps), below the nominal optimum."""
    design = design_reflection(TRANSPORT, "decay_rate", delays=(0.5, 2.0), speed_tolerance=0.2, rigorous=rigorous)
    assert design.tolerance is not None and len(design.corner_abscissae) == 4
    for (a, b), sa, rate in zip(design.tolerance.points[:4], design.corner_abscissae, design.corner_decay_rates):
        assert sa.model_error == 0.0 and sa.accuracy is not None and sa.rigorous == rigorous
        assert abs(rate - float(_transport_rate(design.K, a, b))) <= sa.accuracy
    least = float(_transport_rate(design.K, -0.2, -0.2))
    acc = design.worst_decay_rate_accuracy
    assert acc is not None and abs(design.worst_decay_rate - least) <= acc
    assert design.worst_decay_rate < design.design.decay_rate - 0.5  # 2.83 against the nominal 3.53


def test_corner_rates_of_the_paper_plant() -> None:
    """The issue's example: nominal 0.17224, but 0.10684 at the corner (-0.05, -0.05) (the corner loops are
    models on the kernel grid: their accuracy holds the grid's error)."""
    design = design_reflection(PAPER, "decay_rate", margin_at_least=0.1, speed_tolerance=0.05, kernel_grid=31)
    assert design.tolerance is not None
    law = ReflectionController(design.K).feedback_law(PAPER, solve_kernels(PAPER, ORACLE_GRID))
    feedback = StateFeedback(law.boundary_gain, law.gain_u, law.gain_v)
    oracle = []
    for (a, b), sa in zip(design.tolerance.points[:4], design.corner_abscissae):
        corner = dataclasses.replace(PAPER, lam=PAPER.lam * (1.0 + a), mu=PAPER.mu * (1.0 + b))
        A, B = loop_factors(corner, feedback)
        oracle.append(-spectral_abscissa(A + B).value)
        assert sa.accuracy is not None and sa.model_error is not None
        assert abs(-sa.value - oracle[-1]) <= sa.accuracy + ORACLE_ERROR
        assert sa.accuracy < 1e-5  # the convergence study is not vacuous
    acc = design.worst_decay_rate_accuracy
    assert acc is not None and abs(design.worst_decay_rate - min(oracle)) <= acc + ORACLE_ERROR
    assert abs(min(oracle) - 0.1068448155) < 1e-8 and abs(design.design.decay_rate - 0.1722407389) < 1e-9
    text = repr(design)
    assert "worst_decay_rate=0.10684" in text and "(nominal and 4 corners)" in text
    assert "0.106844935662938" not in text  # no digit beyond the grid's accuracy
    data = json.loads(json.dumps(design.to_dict(), allow_nan=False))
    assert data["worst_decay_rate"] == design.worst_decay_rate and len(data["corner_decay_rates"]) == 4
    assert "least decay rate of the nominal plant and the corners 0.10684" in design_summary(design)
    report = "\n".join(_reflection_markdown(Path("paper.toml"), design, 0.1))
    assert "least decay rate at delta = 0 of the nominal plant and the 4 corners: 0.10684" in report
    assert "(e_lam, e_mu) = (-0.05, -0.05): 0.10684" in report and "0.106844935662938" not in report


def test_no_corner_rates_without_the_decay_rate_under_a_tolerance() -> None:
    """The margin objective and the nominal decay-rate design state no corners: the least rate is the nominal."""
    design = design_reflection(TRANSPORT, "decay_rate", margin_at_least=1.0)
    assert design.corner_abscissae == () and design.worst_decay_rate == design.design.decay_rate
    assert "worst_decay_rate" not in repr(design) and "worst_decay_rate" not in design.to_dict()


def test_corner_rates_of_a_state_feedback_design_in_closed_form() -> None:
    """``U = k u(t, 1)`` on the transport plant: each corner's rate ``-ln|(rho + k) q| / tau'`` (mpmath)."""
    design = design_state_feedback(TRANSPORT, "decay_rate", margin_at_least=1.0, speed_tolerance=0.2)
    assert design.tolerance is not None and len(design.corner_abscissae) == 4
    K = -design.parameters[0]  # U_BS2(K) is k = -K on the transport plant
    for (a, b), sa in zip(design.tolerance.points[:4], design.corner_abscissae):
        assert sa.accuracy is not None and abs(-sa.value - float(_transport_rate(K, a, b))) <= sa.accuracy
    assert design.worst_decay_rate == min(design.corner_decay_rates) == design.value < design.design.decay_rate
    data = json.loads(json.dumps(design.to_dict(), allow_nan=False))
    assert data["worst_decay_rate"] == design.worst_decay_rate


@pytest.mark.long  # about 30 s of CPU: four starts of the least rate of five loops
def test_corner_rates_of_a_filtered_design() -> None:
    """The filtered law on the transport plant: each corner's rate against the corner plant's own loop
    (``loop_factors`` of the plant built here with the designed controller: on a transport plant the law has no
    kernels, so this is the PDE's loop, by another route than the mismatched loops)."""
    design = design_filtered(TRANSPORT, margin_at_least=1.0, speed_tolerance=0.2)
    assert design.tolerance is not None and len(design.corner_abscissae) == 4
    for (a, b), sa in zip(design.tolerance.points[:4], design.corner_abscissae):
        corner = dataclasses.replace(TRANSPORT, lam=TRANSPORT.lam * (1.0 + a), mu=TRANSPORT.mu * (1.0 + b))
        A, B = loop_factors(corner, design.controller)
        oracle = spectral_abscissa(A + B)
        assert sa.accuracy is not None and oracle.accuracy is not None
        assert abs(sa.value - oracle.value) <= sa.accuracy + oracle.accuracy
    assert design.worst_decay_rate == min(design.corner_decay_rates) == design.value < design.design.decay_rate - 0.5
    report = "\n".join(_local_design_lines(design))
    assert "least decay rate at delta = 0 of the nominal plant and the 4 corners: 2.82576" in report
    assert "(the design maximises it;" in report


def test_the_corner_rate_is_proven_with_the_enclosed_traces() -> None:
    """``rigorous=True`` on the paper's plant: the enclosed traces (within a proven 4.1e-12) let the corner's
    abscissa be proven about the PDE under the true law (before, with traces fitted to the kernel route's within
    4e-3, the roots' boxes overlapped and the result was the floating-point one); its bracket holds the corner
    loop's rate on 201 kernel points (module notes)."""
    K = 0.1414123233383696
    sa = mismatch_abscissa(PAPER, ReflectionController(K), -0.05, -0.05, kernel_grid=31, rigorous=True)
    law = ReflectionController(K).feedback_law(PAPER, solve_kernels(PAPER, ORACLE_GRID))
    corner = dataclasses.replace(PAPER, lam=PAPER.lam * 0.95, mu=PAPER.mu * 0.95)
    A, B = loop_factors(corner, StateFeedback(law.boundary_gain, law.gain_u, law.gain_v))
    assert sa.rigorous and sa.model_error == 0.0
    lo, hi = sa.value_bracket
    assert lo - ORACLE_ERROR <= spectral_abscissa(A + B).value <= hi + ORACLE_ERROR


def test_traces_too_wide_to_prove_with_take_the_kernel_route() -> None:
    """On ``Hyperbolic2x2(1, 1, 4, 4, 0.5, 0.5)`` the traces' proven bound is about ``3.6e72`` (Gronwall's factor):
    the exact route is not taken (before, the loop carried radii ``4e74`` and the abscissa refused with a
    ``ParameterError`` about the root-free radius); the kernel route's abscissa comes with its grid study."""
    strong = Hyperbolic2x2(1.0, 1.0, 4.0, 4.0, 0.5, 0.5)
    sa = mismatch_abscissa(strong, ReflectionController(0.1), -0.05, -0.05, kernel_grid=31, rigorous=True)
    assert sa.model_error is not None and sa.model_error > 0.0
