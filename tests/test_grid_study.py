"""A delay margin on the kernel route carries the accuracy a convergence study in the kernel grid estimates.

``delay_margin`` on a model of the PDE (``N~`` a cubic spline on the kernel grid) fills ``model_error`` and
``omega_model_error`` from :func:`~nrobust.hyperbolic.analyses.grid_study.grid_study`, so its repr prints the
margin and the crossing frequency to that estimate. Oracles sharing no code with the study: the crossing equations
of the paper's plant at 40 digits (``PAPER_MARGIN``, ``tests/test_model_error_default.py``), the exact route's
margin and crossing frequency proven in ball arithmetic for the PDE (closed-form ``N~``, no kernel grid), closed-form
sequences for the study's logic, and a grid eight times as fine for a plant given by samples.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from _oracles import PAPER_MARGIN, PDE_MARGIN_STRONG

import nrobust.hyperbolic.analyses.margin as margin_module
import nrobust.reports.certificate as certificate_module
from nrobust import (
    GeneralHyperbolic2x2,
    Hyperbolic2x2,
    ReflectionController,
    StateFeedback,
    certify,
    delay_margin,
    with_accuracy,
)
from nrobust.hyperbolic.analyses.grid_study import grid_study


def _within_printed(text: str, truth: float) -> None:
    """The printed value is within its printed accuracy of ``truth`` (the digits shown are right)."""
    value, bound = (float(t) for t in text.split(" +- "))
    assert abs(value - truth) <= bound, (text, truth)


@pytest.mark.parametrize(
    ("parameters", "truth", "grid"),
    [
        ((1.0, 1.0, 1.0, 1.0, 1.0, 0.85), PAPER_MARGIN, 201),
        ((1.0, 1.0, 1.0, 1.0, 1.0, 0.85), PAPER_MARGIN, 101),
        # not monotone from 51 points: the grid 401 is added (errors -1.9e-7, -4.6e-8 on 101, 201)
        ((1.0, 1.0, 4.0, 4.0, 0.5, 0.5), PDE_MARGIN_STRONG, 201),
    ],
)
def test_kernel_route_margin_and_omega_carry_a_conservative_estimate(
    parameters: tuple[float, ...], truth: float, grid: int
) -> None:
    """Measured on the paper's plant, grid 201: true errors 1.5e-10 (margin) and 7.3e-11 (omega), estimates
    1.1e-9 and 5.0e-10 (7 times); the estimate must hold the truth and not be looser than 100 times it."""
    plant, law = Hyperbolic2x2(*parameters), ReflectionController(0.1)
    exact = delay_margin(plant, law, rigorous=True)  # the PDE's, proven: no kernel grid
    assert not exact.of_model and exact.omega is not None and exact.omega_accuracy is not None
    model = delay_margin(plant, law, kernel_grid=grid)
    assert model.of_model and model.model_error is not None and model.omega_model_error is not None
    assert model.accuracy is not None and model.omega_accuracy is not None and model.omega is not None
    assert "estimates the margin's distance" in model.scope and "not proven" in model.scope
    error = abs(model.margin - truth)
    assert error <= model.accuracy <= 100.0 * error
    omega_error = abs(model.omega - exact.omega) + exact.omega_accuracy
    assert omega_error <= model.omega_accuracy <= 100.0 * omega_error
    text = repr(model)
    assert "accuracy not estimated" not in text
    margin_text = with_accuracy(model.margin, model.accuracy)
    omega_text = with_accuracy(model.omega, model.omega_accuracy)
    assert f"margin={margin_text}, omega={omega_text}," in text
    _within_printed(margin_text, truth)
    _within_printed(omega_text, exact.omega)


def test_sampled_coefficient_margin_is_within_its_estimate_of_a_finer_grid() -> None:
    """A coefficient given as samples (no exact loop): the estimate on the default grid (201) holds the margin and
    omega on 1601 points (measured differences 6.9e-10 and 5.0e-11 against estimates 4.5e-9 and 3.2e-10; the
    grid 1601 is itself off by about 1e-12 at the observed order 2.8)."""
    xs = np.linspace(0.0, 1.0, 21)
    plant = GeneralHyperbolic2x2(1.2, 0.8, (xs, 0.1 + 0.1 * xs), 0.3, 0.3, -0.1, 0.6, 0.4)
    law = StateFeedback(-0.9)
    model = delay_margin(plant, law)
    assert model.of_model and model.accuracy is not None and model.omega_accuracy is not None
    fine = margin_module.studied_delay_margin(plant, law, kernel_grid=1601, study=False)[0]
    assert model.omega is not None and fine.omega is not None
    assert abs(model.margin - fine.margin) <= model.accuracy <= 100.0 * abs(model.margin - fine.margin)
    assert abs(model.omega - fine.omega) <= model.omega_accuracy <= 100.0 * abs(model.omega - fine.omega)
    assert "accuracy not estimated" not in repr(model)
    _within_printed(with_accuracy(model.margin, model.accuracy), fine.margin)
    # the spline plant's own margin (tests/test_general_plant_as_given.py), 1.4e-12 from the grid 1601
    assert abs(model.margin - 3.11157441799810) <= model.accuracy


def _sequence(values: dict[int, float], omegas: dict[int, float] | None = None):
    """``n -> margin`` from a table, as the study calls it (a margin's ``margin`` and ``omega`` are all it reads)."""
    calls: list[int] = []

    def margin_on(n: int) -> SimpleNamespace:
        calls.append(n)
        return SimpleNamespace(margin=values[n], omega=None if omegas is None else omegas[n])

    return margin_on, calls


def test_study_of_a_third_order_sequence() -> None:
    """``m(n) = 1 + 1 / (n - 1)^3``: monotone at order 3 from the start, the estimate ``|m2 - m1|`` holds the true
    error ``1 / 200^3`` (7 times over) and the finer grid is not computed."""
    values = {n: 1.0 + 1.0 / (n - 1) ** 3 for n in (51, 101, 201, 401)}
    margin_on, calls = _sequence(values, {n: 2.0 - 3.0 / (n - 1) ** 3 for n in values})
    study = grid_study(margin_on, 201, margin_on(201))
    assert study is not None and calls == [201, 101, 51]
    assert study.estimate == pytest.approx(values[101] - values[201], rel=1e-12)
    assert 1.0 / 200**3 <= study.estimate and study.order == pytest.approx(3.0, abs=1e-6)
    assert study.omega_estimate == pytest.approx(3.0 * (values[101] - values[201]), rel=1e-9)


def test_study_of_a_sequence_not_yet_monotone() -> None:
    """An oscillating start: the grid ``2 n - 1`` is added and ``2 |m3 - m2|`` is the estimate."""
    values = {51: 1.0 - 1e-6, 101: 1.0 + 8e-8, 201: 1.0 + 1e-8, 401: 1.0 + 1.25e-9}
    margin_on, calls = _sequence(values)
    study = grid_study(margin_on, 201, margin_on(201))
    assert study is not None and calls[-1] == 401
    assert study.estimate == pytest.approx(2.0 * (1e-8 - 1.25e-9), rel=1e-6)
    assert study.estimate >= 1e-8 and study.omega_estimate is None
    assert "not proven" in study.statement


def test_study_of_a_margin_decided_by_structure_is_exact() -> None:
    margin_on, calls = _sequence({51: np.inf, 101: np.inf, 201: np.inf})
    study = grid_study(margin_on, 201, margin_on(201))
    assert study is not None and study.estimate == 0.0 and calls == [201, 101]
    assert grid_study(margin_on, 7, margin_on(201)) is None  # too coarse to halve
    # a margin infinite on the grid but finite on coarser ones: no finite estimate (before: twice the finite step)
    margin_on, _ = _sequence({51: 1.0, 101: 1.001, 201: np.inf, 401: np.inf})
    study = grid_study(margin_on, 201, margin_on(201))
    assert study is not None and study.estimate == np.inf


def test_certify_runs_one_study_and_states_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """The certificate's model error is the margin's own study (made once), its inner margins without one."""
    made: list[int] = []

    def counting(margin_on, grid, margin):
        made.append(grid)
        return grid_study(margin_on, grid, margin)

    monkeypatch.setattr(margin_module, "grid_study", counting)
    monkeypatch.setattr(certificate_module, "grid_study", counting)
    plant, law = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85), ReflectionController(0.1)
    cert = certify(plant, law, kernel_grid=101, k_region=False, region=(-2, 1, -20, 20))
    assert made == [101]
    assert cert.model_error is not None and cert.model_error.estimate == cert.margin.model_error
    assert cert.margin_accuracy is not None and abs(cert.delay_margin - PAPER_MARGIN) <= cert.margin_accuracy
