"""Every margin a certificate prints carries its accuracy, on the kernel route too.

``certify`` on a loop built from a kernel grid (or from the characteristic route of a plant
with a varying ``lam/mu``) estimates the model error of its delay margin by a convergence
study, without being asked. The oracles share no code with that study: the closed-form
crossing of the paper's plant solved at 40 digits (``tests/test_exact_form.py``), and the
crossing equation of the kernel-free Laplace route (Magnus steps, no kernel, no
characteristic grid) solved by Newton's method here.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from _oracles import PAPER_MARGIN, PDE_MARGIN_STRONG

from nrobust import (
    GeneralHyperbolic2x2,
    Hyperbolic2x2,
    ReflectionController,
    StateFeedback,
    certify,
    delay_margin,
    with_accuracy,
)
from nrobust.cli import main
from nrobust.config import load_system_file
from nrobust.hyperbolic.loops.controllers import loop_route
from nrobust.hyperbolic.loops.feedback import laplace_loop_factors
from nrobust.hyperbolic.plants.frontends import saint_venant


@pytest.mark.parametrize(
    ("parameters", "truth", "grid"),
    [
        ((1.0, 1.0, 1.0, 1.0, 1.0, 0.85), PAPER_MARGIN, 51),
        ((1.0, 1.0, 1.0, 1.0, 1.0, 0.85), PAPER_MARGIN, 101),
        ((1.0, 1.0, 1.0, 1.0, 1.0, 0.85), PAPER_MARGIN, 201),
        # not monotone from 51 points (errors 3.6e-6, -1.9e-7, -4.6e-8 on 51, 101, 201)
        ((1.0, 1.0, 4.0, 4.0, 0.5, 0.5), PDE_MARGIN_STRONG, 201),
    ],
)
def test_kernel_route_margin_is_within_its_estimated_accuracy(
    parameters: tuple[float, ...], truth: float, grid: int
) -> None:
    """Grids where the study is monotone from the start and where it is not."""
    plant = Hyperbolic2x2(*parameters)
    cert = certify(plant, ReflectionController(0.1), kernel_grid=grid, k_region=False, region=(-2, 1, -20, 20))
    assert cert.route == "kernels" and cert.model_error is not None
    accuracy = cert.margin_accuracy
    assert accuracy is not None and accuracy < 1e-5
    assert abs(cert.delay_margin - truth) <= accuracy
    assert "estimated" in cert.model_error.statement and "+-" in cert.margin_text


def _laplace_crossing(
    plant: GeneralHyperbolic2x2, k: float, omega: float, delta: float, steps: int | None = None
) -> tuple[float, float]:
    """``(delta, omega)`` with ``A(i w) + B(i w) e^{-i w delta} = 0`` on the Laplace route, by Newton's method
    (``steps`` Magnus steps for varying speeds; each step is exact for constant coefficients)."""
    x = np.array([omega, delta])
    for _ in range(8):

        def residual(v: np.ndarray) -> np.ndarray:
            a, b = laplace_loop_factors(plant, k, 0.0, 0.0, np.array([1j * v[0]]), steps=steps)
            f = complex(a[0] + b[0] * np.exp(-1j * v[0] * v[1]))
            return np.array([f.real, f.imag])

        f0 = residual(x)
        h = 1e-6
        jac = np.column_stack([(residual(x + h * e) - residual(x - h * e)) / (2 * h) for e in np.eye(2)])
        step = np.linalg.solve(jac, -f0)
        x = x + step
        if np.max(np.abs(step)) < 1e-12:
            break
    return float(x[1]), float(x[0])


@pytest.mark.slow
def test_varying_speed_ratio_margin_is_within_its_estimated_accuracy() -> None:
    """The characteristic route (no normal form) is refined as the kernel grid is.

    ``kernel_grid`` given: the model route (without it the loop of this plant is proven, ``varying_proof``);
    the proven margin lies within the model's estimated accuracy too.
    """
    plant = GeneralHyperbolic2x2(
        lam=lambda x: 1.0 + 0.3 * x, mu=1.0, a=0.0, b=0.5, c=lambda x: 0.4 - 0.2 * x, d=0.0, q=0.7, rho=0.4
    )
    k = -1.0
    cert = certify(plant, StateFeedback(k), delta_max=0.5, k_region=False, region=(-2, 1, -20, 20), kernel_grid=201)
    assert cert.model_error is not None and "characteristic route" in cert.model_error.statement
    accuracy = cert.margin_accuracy
    assert accuracy is not None and accuracy < 1e-5
    omega = cert.margin.omega
    assert omega is not None
    delta, _ = _laplace_crossing(plant, k, omega, cert.delay_margin, steps=4000)
    assert abs(cert.delay_margin - delta) <= accuracy
    assert loop_route(plant, StateFeedback(k)) == "exact"
    proven = delay_margin(plant, StateFeedback(k), delta_max=0.5, rigorous=True)
    assert not proven.of_model and abs(cert.delay_margin - proven.margin) <= accuracy


def test_uniform_flow_canal_takes_the_exact_route_and_prints_its_accuracy() -> None:
    """Litrico and Fromion's pool in uniform flow: constant coefficients, so no kernel grid, in minutes and seconds."""
    canal = saint_venant(3000.0, 7.0, 1e-4, 10.0, side_slope=1.5, manning=0.02, time_unit=60.0).system
    k = 1.0
    assert loop_route(canal, StateFeedback(k)) == "exact"
    margin = delay_margin(canal, StateFeedback(k))
    assert margin.accuracy is not None and margin.accuracy < 1e-9 and margin.omega is not None
    delta, _ = _laplace_crossing(canal, k, margin.omega, margin.margin)
    assert abs(margin.margin - delta) <= max(margin.accuracy, 1e-10)  # the Laplace route's own error: 1e-10
    text = with_accuracy(60.0 * margin.margin, 60.0 * margin.accuracy)
    value, accuracy = (float(t) for t in text.split(" +- "))
    assert abs(value - 60.0 * delta) <= 2.0 * accuracy


def test_a_ball_proven_about_a_model_is_not_printed_as_the_plants_accuracy() -> None:
    """Varying couplings without ball arithmetic: the rigorous ball is about N~ on the grid; the plant's accuracy
    comes from the study (np.minimum does not act on arb_series, so there is no proven N~), which ``delay_margin``
    makes itself (before, its accuracy was None and its repr said "accuracy not estimated")."""
    plant = Hyperbolic2x2(1.0, 2.0, lambda x: 0.5 * (1.0 + np.minimum(x, 2.0)), -0.4, 0.8, 0.9)
    margin = delay_margin(plant, ReflectionController(0.3), rigorous=True)
    assert margin.of_model and margin.margin_ball is not None and margin.model_error is not None
    lo, hi = margin.margin_ball
    # the printed accuracy is the study's estimate (plus the ball's radius), not the model's ball alone
    assert margin.accuracy is not None and margin.accuracy >= margin.model_error > 1e3 * (hi - lo)
    assert f"margin={with_accuracy(margin.margin, margin.accuracy)}," in repr(margin)
    cert = certify(plant, ReflectionController(0.3), k_region=False, region=(-2, 1, -20, 20))
    assert cert.margin.accuracy is not None and cert.margin.accuracy == cert.margin_accuracy
    assert "+-" in repr(cert.margin).split("omega=")[0]
    # the study's estimate holds against a grid four times as fine (third order: 16x closer)
    fine = delay_margin(plant, ReflectionController(0.3), kernel_grid=801).margin
    assert abs(cert.delay_margin - fine) <= cert.margin_accuracy


def test_the_canal_file_is_analysed_as_written() -> None:
    """examples/saint_venant.toml: uniform flow, so the certificate is about the plant itself (no normal form)."""
    spec = load_system_file(Path(__file__).parent.parent / "examples" / "saint_venant.toml")
    assert spec["system"] is spec["given_system"] and loop_route(spec["system"], spec["controller"]) == "exact"


def test_analyze_takes_an_accuracy_target_on_the_command_line(tmp_path: Path) -> None:
    """``--accuracy`` overrides the file: the kernel grid is refined until the margin's estimate meets it."""
    system = tmp_path / "varying.toml"
    system.write_text(
        '[system]\ntype = "Hyperbolic2x2"\nlam = 1.0\nmu = 1.0\nsigma_pm = 1.0\nsigma_mp = 1.0\nq = 1.0\nrho = 0.85\n'
        '\n[controller]\ntype = "ReflectionController"\nK = 0.1\n\n[analysis]\ndelta_max = 0.1\nk_region = false\n'
    )
    out = tmp_path / "out"
    assert main(["analyze", str(system), "-o", str(out), "--no-progress", "--accuracy", "1e-12"]) == 0
    data = json.loads((out / "certificate.json").read_text())
    assert data["accuracy_target"] == 1e-12 and "target 1.0e-12 met" in (out / "report.md").read_text()
    assert main(["analyze", str(system), "-o", str(tmp_path / "bad"), "--accuracy", "-1"]) == 2
