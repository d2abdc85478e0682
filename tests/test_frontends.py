"""Physical front ends: the numbers each model fixes in closed form, and the loops built on them."""

from __future__ import annotations

import json

import numpy as np
import pytest
from _examples import EXAMPLES, run_example

import nrobust
from nrobust.cli import main
from nrobust.config import load_system_file
from nrobust.errors import ParameterError
from nrobust.hyperbolic import Hyperbolic2x2, boundary_function
from nrobust.hyperbolic.controllers import OpenLoop, StateFeedback, characteristic
from nrobust.hyperbolic.feedback import laplace_loop_factors
from nrobust.hyperbolic.frontends import GRAVITY, arz, from_riemann, saint_venant
from nrobust.hyperbolic.general import GeneralHyperbolic2x2

CANAL = {"length": 3000.0, "width": 7.0, "slope": 1e-4, "discharge": 14.0, "manning": 0.02}


# ------------------------------------------------------------------ Saint-Venant
def test_uniform_channel_classical_numbers():
    canal = saint_venant(**CANAL)
    B, Q, n, S0 = 7.0, 14.0, 0.02, 1e-4
    hn = canal.normal_depth
    R = B * hn / (B + 2 * hn)
    # Manning's formula holds at the normal depth (brentq to 1e-14 m).
    np.testing.assert_allclose(B * hn * R ** (2 / 3) * np.sqrt(S0) / n, Q, rtol=1e-12)
    np.testing.assert_allclose(canal.critical_depth, ((Q / B) ** 2 / GRAVITY) ** (1 / 3), rtol=1e-14)
    V = Q / (B * hn)
    np.testing.assert_allclose(canal.froude, V / np.sqrt(GRAVITY * hn), rtol=1e-14)
    plant = canal.system
    # Characteristic speeds V + c and c - V of the uniform flow.
    c = np.sqrt(GRAVITY * hn)
    np.testing.assert_allclose(plant.coefficient("lam", [0.0, 3000.0]), V + c, rtol=1e-14)
    np.testing.assert_allclose(plant.coefficient("mu", [0.0, 3000.0]), c - V, rtol=1e-14)
    # Constant discharge at both ends: q = -(c - V)/(c + V), rho = -(c + V)/(c - V), rho q = 1.
    assert plant.q * plant.rho == pytest.approx(1.0, rel=1e-14)
    assert plant.constant_ratio


def test_uniform_channel_source_matrix_closed_form():
    """Uniform flow: M = -g/2 [[Sf_H/G + Sf_V, -Sf_H/G + Sf_V], [...same...]] with G = g/c."""
    canal = saint_venant(**CANAL)
    hn, g = canal.normal_depth, GRAVITY
    B, S0 = 7.0, 1e-4
    V = 14.0 / (B * hn)
    R, dR = B * hn / (B + 2 * hn), B**2 / (B + 2 * hn) ** 2
    Sf_H, Sf_V = -4 / 3 * S0 * dR / R, 2 * S0 / V  # Sf = S0 on the uniform flow
    G = g / np.sqrt(g * hn)
    a = -g * Sf_H / (2 * G) - g * Sf_V / 2
    b = g * Sf_H / (2 * G) - g * Sf_V / 2
    x = np.array([0.0, 1500.0])
    plant = canal.system
    np.testing.assert_allclose(plant.coefficient("a", x), a, rtol=1e-12)
    np.testing.assert_allclose(plant.coefficient("b", x), b, rtol=1e-12)
    np.testing.assert_allclose(plant.coefficient("c", x), a, rtol=1e-12)
    np.testing.assert_allclose(plant.coefficient("d", x), b, rtol=1e-12)


def test_backwater_profile_m1_and_weir():
    m1 = saint_venant(**CANAL, downstream_depth=3.5)
    hn = m1.normal_depth
    assert m1.depth[-1] == pytest.approx(3.5, abs=1e-12)
    # M1 curve: depth above normal, decreasing upstream, tending to the normal depth.
    assert np.all(np.diff(m1.depth) > 0) and np.all(m1.depth > hn)
    assert not m1.system.constant_ratio  # the Froude number varies along the profile
    # The profile solves the backwater ODE: check it by finite differences (DOP853 at 1e-11).
    h = m1.x[1] - m1.x[0]
    dH = np.gradient(m1.depth, h, edge_order=2)
    H, V = m1.depth, 14.0 / (7.0 * m1.depth)
    R = 7.0 * H / (7.0 + 2 * H)
    rhs = (1e-4 - 0.02**2 * V**2 / R ** (4 / 3)) / (1 - V**2 / (GRAVITY * H))
    np.testing.assert_allclose(dH, rhs, rtol=1e-4)  # second-order differences, h = 15 m
    weir = saint_venant(**CANAL, downstream="weir", weir_height=2.0)
    np.testing.assert_allclose(weir.depth[-1], 2.0 + (2.0 / 1.7) ** (2 / 3), rtol=1e-12)


def test_nonuniform_profile_laplace_route_is_consistent():
    """Varying lam/mu: no constant-speed normal form, but the Laplace route converges (4th order)."""
    plant = saint_venant(**CANAL, downstream_depth=3.5, time_unit=60.0).system
    with pytest.raises(ParameterError, match="proportional"):
        plant.normal_form()
    s = np.array([0.05 + 0.3j, -0.1 + 2.0j])
    ref = boundary_function(plant, s, scaled=True, steps=3200)
    errs = [np.abs(boundary_function(plant, s, scaled=True, steps=n) - ref).max() for n in (200, 400)]
    assert errs[1] < errs[0] / 12.0


def test_backwater_channel_margin_by_the_characteristic_route():
    """M1 profile (varying lam/mu): margin of U = 0.6 xi_1(L), its crossing a zero of the Laplace route."""
    plant = saint_venant(**CANAL, downstream_depth=3.5, time_unit=60.0).system
    margin = nrobust.delay_margin(plant, StateFeedback(0.6))
    assert margin.omega is not None and margin.nominally_stable
    A, B = laplace_loop_factors(plant, 0.6, 0.0, 0.0, np.array([1j * margin.omega]), steps=2000)
    # measured 6.6e-12 (46.3699 min): the characteristic route is fourth order
    assert abs(A[0] + B[0] * np.exp(-1j * margin.omega * margin.margin)) < 1e-8


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"width": -1.0}, "width"),
        ({"manning": None}, "manning"),
        ({"chezy": 50.0}, "manning"),
        ({"downstream": "sluice"}, "downstream"),
        ({"downstream_depth": 0.5}, "downstream_depth"),
        ({"downstream": "weir"}, "weir_height"),
        ({"downstream": "weir", "weir_height": -0.1}, "weir_height"),
        ({"time_unit": 0.0}, "time_unit"),
    ],
)
def test_saint_venant_errors_are_named(kwargs, name):
    args = {**CANAL, **kwargs}
    if args["manning"] is None:
        del args["manning"]
    with pytest.raises(ParameterError) as err:
        saint_venant(**args)
    assert err.value.name == name


def test_chezy_friction():
    canal = saint_venant(3000.0, 7.0, 1e-4, 14.0, chezy=50.0)
    hn = canal.normal_depth
    R = 7.0 * hn / (7.0 + 2 * hn)
    np.testing.assert_allclose(14.0 / (7.0 * hn), 50.0 * np.sqrt(R * 1e-4), rtol=1e-12)


@pytest.mark.slow
def test_saint_venant_margin_time_units_and_laplace_check():
    """The margin is the same in seconds and minutes; |F(i w*; delta*)| vanishes by the Laplace route."""
    seconds = nrobust.delay_margin(saint_venant(**CANAL).system, StateFeedback(0.6))
    plant = saint_venant(**CANAL, time_unit=60.0).system
    minutes = nrobust.delay_margin(plant, StateFeedback(0.6))
    np.testing.assert_allclose(60.0 * minutes.margin, seconds.margin, rtol=1e-9)
    A, B = laplace_loop_factors(plant, 0.6, 0.0, 0.0, np.array([1j * minutes.omega]), steps=800)
    residual = abs(A[0] + B[0] * np.exp(-1j * minutes.omega * minutes.margin))
    assert residual < 1e-7  # measured 5.7e-10 (kernels at 201 points against Magnus)


# ------------------------------------------------------------------ ARZ
ROAD = {"length": 500.0, "v_max": 40.0, "rho_max": 0.16, "gamma": 0.5, "relaxation": 60.0, "rho_star": 0.12}


def test_arz_closed_forms():
    road = arz(**ROAD)
    p_star = 40.0 * np.sqrt(0.75)
    np.testing.assert_allclose(road.v_star, 40.0 - p_star, rtol=1e-15)
    np.testing.assert_allclose(road.speeds, (40.0 - p_star, 40.0 - 1.5 * p_star), rtol=1e-14)
    np.testing.assert_allclose(road.critical_density, 0.16 / 1.5**2, rtol=1e-14)
    plant = road.system
    assert plant.q * plant.rho == pytest.approx(1.0, rel=1e-14)
    np.testing.assert_allclose(plant.rho_q, np.exp(-500.0 / (60.0 * road.v_star)), rtol=1e-12)


def test_arz_open_loop_spectrum():
    """Conservation root at 0; a chain on Re s = ln(rho~ q~)/tau spaced 2 pi/tau."""
    plant = arz(**ROAD, time_unit=60.0).system
    tau = plant.tau / 60.0
    roots = nrobust.find_roots(characteristic(plant, OpenLoop()), (-1.2, 0.6, -6.0, 6.0)).roots
    roots = roots[np.argsort(roots.imag)]
    assert len(roots) == 5
    np.testing.assert_allclose(roots[2], 0.0, atol=1e-7)  # kernels at 201 points: 5e-9 measured
    chain = np.log(plant.rho_q) / tau
    np.testing.assert_allclose(roots[[0, 1, 3, 4]].real, chain, atol=1e-7)
    np.testing.assert_allclose(np.diff(roots.imag), 2 * np.pi / tau, rtol=1e-7)


def test_arz_rejects_free_flow():
    with pytest.raises(ParameterError, match="congested") as err:
        arz(**{**ROAD, "rho_star": 0.05})
    assert err.value.name == "rho_star"


# ------------------------------------------------------------------ from_riemann
def test_from_riemann_matches_general_plant():
    plant = from_riemann(2.0, lambda x: -1.0 - 0.0 * x, [[0.1, 0.5], [0.3, -0.2]], 0.8, 0.6, 2.0)
    assert plant.coefficient("mu", [0.5])[0] == pytest.approx(1.0)
    nf = plant.normal_form()
    assert isinstance(nf.system, Hyperbolic2x2)
    with pytest.raises(ParameterError) as err:
        from_riemann(2.0, 1.0, [[0, 0], [0, 0]], 1.0, 0.5)
    assert err.value.name == "lam_2"
    with pytest.raises(ParameterError) as err:
        from_riemann(2.0, -1.0, [0, 0], 1.0, 0.5)
    assert err.value.name == "source"


# ------------------------------------------------------------------ files and examples
@pytest.mark.parametrize("name", ["saint_venant.toml", "arz.toml"])
def test_toml_files_load_through_the_normal_form(name):
    spec = load_system_file(EXAMPLES / name)
    assert isinstance(spec["system"], Hyperbolic2x2)


def test_toml_state_feedback_gains_are_physical():
    spec = load_system_file(EXAMPLES / "saint_venant.toml")
    form = saint_venant(**CANAL, time_unit=60.0).system.normal_form()
    assert spec["controller"].k == pytest.approx(form.feedback_to_normal(0.6, 0.0, 0.0)[0], rel=1e-14)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["saint_venant.toml", "arz.toml"])
def test_analyze_front_end_files(name, tmp_path):
    assert main(["analyze", str(EXAMPLES / name), "-o", str(tmp_path), "--no-progress"]) == 0
    assert "delay-robust" in (tmp_path / "report.md").read_text()


@pytest.mark.slow
@pytest.mark.parametrize(
    ("script", "expected"),
    [
        ("saint_venant.py", ["normal depth h_n = 2.930211 m", "Froude number of the uniform flow: 0.127306"]),
        ("arz.py", ["characteristic speeds: 5.358984, -11.961524 m/s", "critical density: 71.1111 veh/km"]),
    ],
)
def test_front_end_examples(script, expected, tmp_path):
    stdout = run_example(script, tmp_path)
    for line in expected:
        assert line in stdout


@pytest.mark.slow
def test_analyze_a_backwater_plant_end_to_end(tmp_path):
    """M1 profile (varying lam/mu) from TOML: certificate, report and simulation by the characteristic route."""
    spec = load_system_file(EXAMPLES / "saint_venant_backwater.toml")
    plant = spec["system"]
    assert isinstance(plant, GeneralHyperbolic2x2) and not plant.constant_ratio
    assert main(["analyze", str(EXAMPLES / "saint_venant_backwater.toml"), "-o", str(tmp_path), "--no-progress"]) == 0
    assert "delay-robust" in (tmp_path / "report.md").read_text()
    cert = json.loads((tmp_path / "certificate.json").read_text())
    margin = nrobust.delay_margin(plant, StateFeedback(0.6))
    np.testing.assert_allclose(cert["delay_margin"], margin.margin, rtol=1e-12)
    # Independent route: the certified crossing is a zero of the kernel-free Laplace route
    # (measured 6.6e-12, see test_backwater_channel_margin_by_the_characteristic_route).
    w = margin.omega
    A, B = laplace_loop_factors(plant, 0.6, 0.0, 0.0, np.array([1j * w]), steps=2000)
    assert abs(A[0] + B[0] * np.exp(-1j * w * cert["delay_margin"])) < 1e-8
    assert len(list((tmp_path / "figures").glob("*simulated*.png"))) == 1
