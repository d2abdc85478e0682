"""The delay margins of output-feedback designs carry an accuracy, and every printed digit is true.

The designed loops are models of the PDE (the observer's term is computed in floating point);
their margins are printed to the accuracy of :func:`observer_model_error`. The oracles share
none of that estimate: the kernel route (the state feedback from kernels on a grid instead of
the closed form, the observer on the same grid) on finer grids, Richardson-extrapolated at the
order the grids show (3), and for the collocated observer under U_BS2(K) the PDE's loop at 40 digits
(``_collocated_oracle``). The collocated observer's loops here are on ``MODEL``: on the paper's plant
they are proven (``tests/test_collocated_proof.py``, ``tests/test_collocated_design_values.py``).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import re

import numpy as np
import pytest
from _collocated_oracle import CollocatedPDE

import nrobust as nr
from nrobust.design import AffineLoop, best_margin
from nrobust.hyperbolic.analyses.observer_accuracy import STUDY_SAFETY, observer_model_error, observer_rate_error
from nrobust.hyperbolic.loops.controllers import characteristic, loop_factors, loop_route
from nrobust.margins import delay_margin as factor_delay_margin
from nrobust.quasipoly import QuasiPolynomial

PAPER = nr.Hyperbolic2x2(1, 1, 1, 1, 1, 0.85)
#: A plant whose collocated loop under U_BS2(K) is taken as a model (``loop_route`` ``"observer"``) where the tests
#: refuse its proven enclosure (:func:`refused`).
MODEL_ARGS = (1.0, 1.5, 1.0, 1.0, 1.0, 0.85)
MODEL = nr.Hyperbolic2x2(*MODEL_ARGS)
NUMBER = r"(-?[0-9.]+(?:e[-+]?[0-9]+)?) \+- ([0-9]e[-+]?[0-9]+)"


@pytest.fixture
def refused(monkeypatch):
    """The collocated observer's proven ``G`` under U_BS2(K) refused, as where it cannot be built (kernels whose
    remainder does not reach its target, ends of ``G``'s pieces within two ulps): the loop is then the kernel
    route's model, whose accuracy estimate these tests check against the PDE. (``MODEL``'s own loop is proven: the
    ends ``2/3`` and ``tau = 5/3`` of its command response's pieces, not doubles, were refused before they were held
    by proven terms on the ulps around them.)"""
    from nrobust.hyperbolic.loops import controllers

    monkeypatch.setattr(controllers, "proven_response_failure", lambda system, K: "refused by the test")


def printed(text: str, name: str) -> tuple[str, float, float]:
    """``name=VALUE +- ACC`` in a repr: the value's text, the value and the accuracy (else the test fails)."""
    match = re.search(rf"{name}={NUMBER}", text)
    assert match is not None, f"{name} printed without an accuracy: {text}"
    return match.group(1), float(match.group(1)), float(match.group(2))


def decimals(text: str) -> int:
    return len(text.split(".")[1]) if "." in text else 0


def richardson(values: list[float], order: float) -> float:
    """The limit of the last two values on grids halving their step, at the given order."""
    return values[-1] + (values[-1] - values[-2]) / (2.0**order - 1.0)


@pytest.mark.long  # 11-16 s each: the model plant's grid studies
def test_collocated_observer_design_margin_digits(refused):
    """``design_collocated_observer`` on ``MODEL``: ``margin=0.264731517 +- 2e-9`` (on the paper's plant, before its
    loop was proven, ``0.194802642 +- 3e-9``, and ``0.1948028 +- 8e-7`` while the loop was second order in its grid);
    the PDE's margin 0.264731516417 (``_collocated_oracle``, 40 digits; the design's is 9.6e-10 from it), and the
    kernel route on 201 and 401 points (order 3 from 101, 201, 401: ratio 7.8) extrapolates to it within 1e-11
    (measured 3.7e-12)."""
    design = nr.design_collocated_observer(MODEL, "margin", controller=nr.ReflectionController(0.1))
    assert loop_route(MODEL, design.controller) == "observer"
    text = repr(design)
    assert "GainDesign(kappa=" in text and "accuracy not estimated" not in text
    digits, value, accuracy = printed(text, "margin")
    routes = [nr.delay_margin(MODEL, design.controller, kernel_grid=n) for n in (101, 201, 401)]
    margins = [m.margin for m in routes]
    ratio = (margins[1] - margins[0]) / (margins[2] - margins[1])
    assert 6.0 < ratio < 10.0  # observed order 3
    w, truth = CollocatedPDE(MODEL_ARGS, 0.1, design.kappa).crossing(design.design.certificate.omega)
    truth, w = float(truth), float(w)
    assert abs(richardson(margins, 3.0) - truth) < 1e-11
    # the crossing frequency of the designed loop, printed to its accuracy too
    omega_digits, omega, omega_accuracy = printed(repr(design.design.certificate), "omega")
    assert abs(omega - w) <= omega_accuracy
    assert decimals(omega_digits) == -math.floor(math.log10(omega_accuracy))
    assert abs(value - truth) <= accuracy
    assert decimals(digits) == -math.floor(math.log10(accuracy))  # no digit beyond the accuracy
    # the estimate is not loose: within 5 times the true error of the unrounded margin
    assert accuracy <= 5.0 * abs(design.design.margin - truth)
    # the plant-level margin of the designed controller states the same accuracy
    check = nr.delay_margin(MODEL, design.controller)
    assert check.model_error is not None and abs(check.margin - truth) <= check.accuracy


@pytest.mark.long  # 11-16 s each: the model plant's grid studies
def test_joint_collocated_design_margin_digits():
    """``design_collocated_output_feedback`` (one start): its margin was printed ``+- 2e-13`` (the accuracy of the
    model's crossing) though the model is 1e-7 from the PDE; now to the observer grid's study: ``0.19487749 +- 2e-8``.
    The design meets two crossings (``w`` 3.19 and 20.54) at one delay; the PDE's are 6.4e-9 and 1.1e-9 below it
    (``_collocated_oracle``), so the study takes the larger error of the two crossings (the least delay of the
    coarser grids was the other crossing's: studied as one sequence it gave ``+- 3e-9``)."""
    design = nr.design_collocated_output_feedback(PAPER, "margin", starts=1)
    digits, value, accuracy = printed(repr(design), "margin")
    # order 3 from 201 to 801 points (ratio 8.1; it showed order 1 then 2 with the plain trapezoidal composition)
    margins = [nr.delay_margin(PAPER, design.controller, kernel_grid=n).margin for n in (201, 401, 801)]
    assert 6.0 < (margins[1] - margins[0]) / (margins[2] - margins[1]) < 10.0  # observed order 3
    truth = richardson(margins, 3.0)
    assert abs(value - truth) <= accuracy
    assert decimals(digits) == -math.floor(math.log10(accuracy))


@pytest.mark.long  # 11-16 s each: the model plant's grid studies
def test_output_feedback_design_margin_digits():
    """``design_reflection(..., output_feedback=True)``: ``margin=0.144456116613 +- 4e-12``; the kernel route on
    201 and 401 points (order 3: ratio 7.9 from 101) extrapolates to 0.14445611661337 (from 401 and 801: 1e-13
    apart)."""
    design = nr.design_reflection(PAPER, "decay_rate", margin_at_least=0.1, output_feedback=True)
    text = repr(design)
    assert "accuracy not estimated" not in text
    digits, value, accuracy = printed(text, "margin")
    routes = [nr.delay_margin(PAPER, design.controller, kernel_grid=n) for n in (101, 201, 401)]
    margins = [m.margin for m in routes]
    ratio = (margins[1] - margins[0]) / (margins[2] - margins[1])
    assert 6.0 < ratio < 10.0  # observed order 3
    truth = richardson(margins, 3.0)
    omega_digits, omega, omega_accuracy = printed(repr(design.design.certificate), "omega")
    assert abs(omega - richardson([m.omega for m in routes], 3.0)) <= omega_accuracy
    assert decimals(omega_digits) == -math.floor(math.log10(omega_accuracy))
    assert abs(value - truth) <= accuracy
    assert decimals(digits) == -math.floor(math.log10(accuracy))


def test_collocated_estimate_is_the_grid_study(refused):
    """The collocated estimate contains the PDE's errors (``_collocated_oracle``, 40 digits) and is ``STUDY_SAFETY``
    times the tail ``|d_2| r / (1 - r)``, ``r = max(d_2 / d_1, 1/8)`` (``|d_2| / 7`` at third order), of the changes
    of the margin (and of its crossing frequency) as the grid halves from 51 to 101 to 201 points, on ``MODEL``.
    Here the loops on 51 and 101 points are built in full (their margins by the core), so the state feedback's
    kernel route moves their changes too: for the margin the ratio ``d_1 / d_2`` is 7.8 and the estimate 0.83 times
    the tail from them (0.83 to 0.87 over ``kappa`` in ``[-0.71, -0.3]``); for the crossing frequency the ratio is
    5.4 and the estimate 1.30 times the tail (1.28 to 1.30), hence ``rtol`` 0.2 and 0.35. The estimates are 2.06
    and 2.02 times the PDE's errors."""
    controller = nr.CollocatedOutputFeedback(nr.ReflectionController(0.1), 0.0, -0.7)
    assert loop_route(MODEL, controller) == "observer"
    A, B = loop_factors(MODEL, controller)
    margin = factor_delay_margin(A, B)
    error, omega_error = observer_model_error(MODEL, controller, margin, (A, B))
    assert error is not None and omega_error is not None
    w, truth = CollocatedPDE(MODEL_ARGS, 0.1, -0.7).crossing(margin.omega)
    for value, exact, estimate in ((margin.margin, truth, error), (margin.omega, w, omega_error)):
        assert abs(value - float(exact)) <= estimate <= 5.0 * abs(value - float(exact))
    coarse = [nr.delay_margin(MODEL, controller, kernel_grid=n) for n in (51, 101)]
    for values, estimate, least, rtol in (
        ([m.margin for m in coarse] + [margin.margin], error, 6.0, 0.2),
        ([m.omega for m in coarse] + [margin.omega], omega_error, 4.0, 0.35),
    ):
        d1, d2 = values[1] - values[0], values[2] - values[1]
        assert least < d1 / d2 < 10.0
        r = max(d2 / d1, 1.0 / 8.0)
        np.testing.assert_allclose(estimate, STUDY_SAFETY * abs(d2) * r / (1.0 - r), rtol=rtol)


@pytest.mark.slow
def test_collocated_decay_rate_digits(refused):
    """U_BS with the collocated observer keeping ``kappa = 0.5`` on ``MODEL``: the rightmost root is a zero of
    ``E = 1 - kappa H_y``, from the dual plant's kernels, so the decay rate is a model's (on the paper's plant, at
    ``kappa = 0.715462``, it was printed ``-0.007114825033559 +- 7e-15``, 6e-11 from the kernel route's limit,
    before that loop was proven). The kernel route on 101, 201 and 401 points (ratio 9.2: order 3.2) extrapolates
    to -0.17834317635, 1.0e-12 from the model's value; its estimate is 3.7e-10."""
    controller = nr.CollocatedOutputFeedback(nr.FiniteTimeController(), 0.0, 0.5)
    assert loop_route(MODEL, controller) == "observer"
    factors = loop_factors(MODEL, controller)
    abscissa = nr.spectral_abscissa(characteristic(MODEL, controller, 0.0))
    error = observer_rate_error(MODEL, controller, abscissa, factors)
    assert error is not None
    text = repr(dataclasses.replace(abscissa, model_error=error))
    digits, value, accuracy = printed(text, "value")
    values = [
        nr.spectral_abscissa(characteristic(MODEL, controller, 0.0, kernel_grid=n)).value for n in (101, 201, 401)
    ]
    ratio = (values[1] - values[0]) / (values[2] - values[1])
    assert 6.0 < ratio < 12.0
    truth = richardson(values, math.log2(ratio))
    assert abs(value - truth) <= accuracy
    assert decimals(digits) == -math.floor(math.log10(accuracy))
    # a rate that is the state feedback's (the zeros of E further left) has no model error
    controller = nr.CollocatedOutputFeedback(nr.ReflectionController(0.1), 0.0, -0.714945)
    abscissa = nr.spectral_abscissa(characteristic(MODEL, controller, 0.0))
    assert observer_rate_error(MODEL, controller, abscissa, loop_factors(MODEL, controller)) < 1e-15


def test_design_summary_names_the_parameter():
    """A design over another parameter than ``K`` prints its name: ``GainDesign(kappa=...``, ``(b=...``."""
    loop = AffineLoop(
        QuasiPolynomial([[1.0, 1.0]], [0.0]),
        QuasiPolynomial([[0.0]], [0.0]),
        QuasiPolynomial([[3.0]], [0.0]),
        QuasiPolynomial([[1.0]], [0.0]),
    )
    design = best_margin(loop, (-1.0, 1.0))
    assert repr(design).startswith("GainDesign(K=")
    assert design.summary("b") == repr(design).replace("GainDesign(K=", "GainDesign(b=", 1)


def test_collocated_study_computes_each_response_once(monkeypatch, refused):
    """The observer's term and the convergence study share their responses: ``command_response`` runs once per law
    and grid (the study's grids 201, 101 and 51 are those of the term's accuracy estimate), and the study's
    response ``C_u`` on the default grid is the term's, bit for bit."""
    from nrobust.hyperbolic.loops import collocated
    from nrobust.hyperbolic.loops.controllers import (
        collocated_observer_of,
        collocated_responses_of,
        observer_reflection_of,
    )

    plant = nr.Hyperbolic2x2(1, 1.5, 1, 1, 1, 0.8)  # a plant of this test alone (no response is cached yet): a model
    assert loop_route(plant, nr.CollocatedOutputFeedback(nr.ReflectionController(0.15))) == "observer"
    controller = nr.CollocatedOutputFeedback(nr.ReflectionController(0.15), observer_reflection=-0.3)
    calls = []
    original = collocated.command_response

    def counted(system, law, kernels, kernel_grid):
        calls.append((law.boundary_gain, kernel_grid))
        return original(system, law, kernels, kernel_grid)

    monkeypatch.setattr(collocated, "command_response", counted)
    term = collocated_observer_of(plant, controller)
    reflection = observer_reflection_of(plant, controller)
    study = {n: collocated_responses_of(plant, controller, n) for n in (201, 101, 51)}
    assert len(calls) == len(set(calls)) == 6  # C_u and H_y on three grids
    s = 1j * np.linspace(0.0, 40.0, 33) + 0.05
    assert np.array_equal(study[201][0](s), term.response(s))
    # the reflection's H_y is u_factor in closed form, proven (its terms' bound 1.2e-16) on any coupled plant with
    # constant couplings: the study's H_y from kernels converges to it at third order (2.9e-8, 3.1e-9, 3.4e-10)
    assert reflection.accuracy < 1e-15
    errors = [float(np.max(np.abs(study[n][1](s) - reflection.response(s)))) for n in (51, 101, 201)]
    assert errors[2] < 1e-9 and all(6.0 < a / b < 12.0 for a, b in itertools.pairwise(errors))
