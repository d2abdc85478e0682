"""The design of the collocated observer's reflection ``kappa`` (:mod:`nrobust.hyperbolic.analyses.observer_design`).

Checks: the strongly stable interval against the closed form of ``gamma_0`` for U_BS2(K) (module
notes of :mod:`nrobust.hyperbolic.loops.collocated`); the affine family against the loop built at
``kappa``; the design against a grid of certified margins of loops built independently of the
affine family (``loop_factors`` at each ``kappa``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import nrobust as nr
from nrobust.design import AffineLoop, best_margin
from nrobust.errors import CertificationError, ParameterError
from nrobust.hyperbolic.analyses import observer_design
from nrobust.hyperbolic.analyses.observer_accuracy import crossing_delay
from nrobust.hyperbolic.analyses.observer_design import collocated_observer_loop, observer_reflection_bounds
from nrobust.hyperbolic.loops.controllers import (
    CollocatedOutputFeedback,
    FiniteTimeController,
    ReflectionController,
    loop_factors,
)
from nrobust.quasipoly import QuasiPolynomial

PAPER = nr.Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
TRANSPORT = nr.TransportSystem(1.0, 2.0, 0.9, 0.6)


def _grid_margins(plant, inner, kappas):
    return np.array(
        [nr.delay_margin(plant, CollocatedOutputFeedback(inner, 0.0, float(k))).margin for k in kappas], dtype=float
    )


@pytest.mark.parametrize(
    ("inner", "expected"),
    [
        # -0.58 - 1.95 kappa = 1 and 0.75 + 1.75 kappa = 1
        (ReflectionController(0.1), (-1.58 / 1.95, 0.25 / 1.75)),
        # 1.445 - 0.7 kappa = 1 and 2.7 kappa - 1.445 = 1
        (FiniteTimeController(), (0.445 / 0.7, 2.445 / 2.7)),
    ],
    ids=["U_BS2(0.1)", "U_BS"],
)
def test_strongly_stable_interval_is_the_closed_form(inner, expected):
    """``|rho - K + kappa| |q| + |kappa - K| |rho| q^2 + |K (rho - kappa)| q^2 < 1`` on the paper's plant."""
    loop = collocated_observer_loop(PAPER, CollocatedOutputFeedback(inner))
    # the principal coefficients are the kernels' (exact) point terms: rounding only
    np.testing.assert_allclose(observer_reflection_bounds(loop), expected, rtol=0, atol=1e-12)
    for kappa in (-0.3, 0.4, 0.7):
        A, B = loop_factors(PAPER, CollocatedOutputFeedback(inner, 0.0, kappa))
        s = np.array([0.2 + 3.0j, -0.1 + 9.0j])
        # the affine family is the loop built at kappa, up to the rounding of the sums
        np.testing.assert_allclose(loop.A(kappa)(s), A(s), rtol=0, atol=1e-12)
        np.testing.assert_allclose(loop.B(kappa)(s), B(s), rtol=0, atol=1e-12)


def test_transport_design_beats_the_grid():
    """An uncoupled plant (the loop is exact): the designed ``kappa`` matches or beats a grid of certified margins."""
    inner = ReflectionController(0.2)
    design = nr.design_collocated_observer(TRANSPORT, controller=inner)
    assert design.design.certified == "checked"
    lo, hi = design.bounds
    grid = _grid_margins(TRANSPORT, inner, np.linspace(lo, hi, 9))
    # the design's margin is certified (relative accuracy about 1e-12); the grid's points lie in the bounds
    assert design.value >= grid.max() - 1e-9
    np.testing.assert_allclose(nr.delay_margin(TRANSPORT, design.controller).margin, design.value, rtol=1e-9, atol=0)


@pytest.mark.long
def test_paper_design_beats_the_grid():
    """U_BS2(0.1) on the paper's plant: the best ``kappa`` is the lower end of the default bounds.

    ``delta*`` grows as ``kappa`` decreases until a curve at ``w ~ 20.6`` meets the one at ``w ~ 3.19``
    about ``kappa = -0.7177``, just below the bounds: the design is the end ``kappa = -0.714945``,
    margin ``0.19480264`` (0.16890143 at ``kappa = 0``): the PDE's 0.194802641094 (``_collocated_oracle``, 40
    digits) within the design's stated accuracy, now proven of the PDE (3e-13, the value 2e-16 from it; while the
    observer's terms were a model's the accuracy was 2.2e-9, and the model's margin 0.19480276876 of the plain
    trapezoidal composition was 1.3e-7 from it).
    """
    inner = ReflectionController(0.1)
    design = nr.design_collocated_observer(PAPER, controller=inner)
    lo, hi = design.bounds
    assert design.design.kind == "end"
    np.testing.assert_allclose(design.kappa, lo, rtol=0, atol=1e-12)
    grid = _grid_margins(PAPER, inner, np.linspace(lo, hi, 5))
    assert design.value >= grid.max() - 1e-9
    # the delay margin, proven of the PDE (the loop's terms in ball arithmetic), is the PDE's to its stated accuracy
    assert abs(design.value - 0.194802641093531768) <= design.design.certificate.accuracy <= 1e-12
    assert design.scope.startswith("the PDE itself") and "H_y = u_factor in closed form" in design.scope
    assert not design.design.certificate.of_model


def test_bad_input():
    with pytest.raises(ParameterError, match="objective"):
        nr.design_collocated_observer(TRANSPORT, "speed")
    with pytest.raises(ParameterError, match="margin_at_least"):
        nr.design_collocated_observer(TRANSPORT, "decay_rate")
    with pytest.raises(ParameterError, match="margin_at_least"):
        nr.design_collocated_observer(TRANSPORT, margin_at_least=0.1)
    with pytest.raises(ParameterError, match="kappa_bounds"):
        nr.design_collocated_observer(TRANSPORT, kappa_bounds=(0.2, 0.1))
    with pytest.raises(ParameterError, match="controller"):
        nr.design_collocated_observer(TRANSPORT, controller="U_BS")
    with pytest.raises(ParameterError, match="controller"):
        nr.design_collocated_observer(TRANSPORT, controller=CollocatedOutputFeedback(FiniteTimeController()))


def test_a_suboptimal_end_is_refused():
    """Bounds that end just below the kink at ``kappa ~ -0.7177``: never an end worse than the envelope's top.

    Either the optimum inside the bounds, matching a grid of certified margins, or a
    ``CertificationError`` saying where a larger margin is.
    """
    inner = ReflectionController(0.1)
    try:
        design = nr.design_collocated_observer(PAPER, controller=inner, kappa_bounds=(-0.7185, -0.6))
    except CertificationError as exc:
        assert "has" in str(exc) and "kappa =" in str(exc)
        return
    grid = _grid_margins(PAPER, inner, np.linspace(-0.7185, -0.6, 5))
    assert design.value >= grid.max() - 1e-9


def test_envelope_top_check_by_crossing_delays(monkeypatch: pytest.MonkeyPatch) -> None:
    """The check near the top of the envelope bounds each gain's margin by a crossing delay.

    ``(s + 1) + (3 + p) e^{-delta s}``, ``p`` in ``[-1, 1]``: the margin ``arccos(-1/b) / sqrt(b^2 - 1)``,
    ``b = 3 + p``, falls with ``p`` (the design is the end ``p = -1``). The crossing delays continued from the
    design's crossing equal that closed form (to 4 ulp: Newton's ``w`` and the ``arccos`` each to rounding),
    settle the check without any certified margin, and a value lowered 1 % below the top is refused (the
    crossing delay exceeds it, and the certified margin at that gain confirms it).
    """
    loop = AffineLoop(
        QuasiPolynomial([[1.0, 1.0]], [0.0]),
        QuasiPolynomial([[0.0]], [0.0]),
        QuasiPolynomial([[3.0]], [0.0]),
        QuasiPolynomial([[1.0]], [0.0]),
    )
    design = best_margin(loop, (-1.0, 1.0))
    assert design.kind == "end" and design.K == -1.0
    for p in np.linspace(-1.0, -0.98, 5):
        b = 3.0 + p
        found = crossing_delay(loop.A(p), loop.B(p), design.certificate.omega)
        assert found is not None
        np.testing.assert_allclose(found[1], math.acos(-1.0 / b) / math.sqrt(b * b - 1.0), rtol=1e-15)

    def no_margin(*args: object, **kwargs: object) -> None:
        raise AssertionError("a certified margin was computed")

    with monkeypatch.context() as patch:
        patch.setattr(observer_design, "delay_margin", no_margin)
        observer_design._check_envelope_top(loop, design)
    with pytest.raises(CertificationError, match="has"):
        observer_design._check_envelope_top(loop, dataclasses.replace(design, value=0.99 * design.value))
