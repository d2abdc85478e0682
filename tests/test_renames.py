"""Renamed keywords and attributes: every old name still works, warns, and gives the same result.

One keyword per concept (``docs/api.md``): ``kernel_grid`` (kernel grid points),
``cells`` (simulation cells), ``n_gains`` (gains of a K-region grid), ``n_freq``
(frequency samples). Each old name is a deprecated alias: it emits a
``DeprecationWarning`` naming the new keyword, and passing both is a ``ParameterError``
naming the old one. Results are compared exactly: the alias must run the same code.
"""

from __future__ import annotations

import inspect
from pathlib import Path

import numpy as np
import pytest

import nrobust.reports.paper
from nrobust import (
    DistributedDelay,
    FiniteTimeController,
    Hyperbolic2x2,
    ParameterError,
    QuasiPolynomial,
    ReflectionController,
    TransportSystem,
    certify,
    characteristic,
    delay_form,
    delay_margin,
    k_region,
    loop_factors,
    open_loop_tf,
    output_map,
    rouche_delay_bound,
    simulate,
    solve_kernels,
)
from nrobust.config import load_system_file
from nrobust.hyperbolic.analyses import DEFAULT_N_GAINS
from nrobust.hyperbolic.kernels.constant import DEFAULT_KERNEL_GRID
from nrobust.hyperbolic.simulate.normal_form import DEFAULT_CELLS, v_nodes
from nrobust.plots.nyquist import nyquist_response
from nrobust.sweeps.sweepfile import ANALYSES

PAPER = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
UNEQUAL = Hyperbolic2x2(1.0, 2.5, 0.5, 0.3, 0.7, 0.4)
TRANSPORT = TransportSystem(1.0, 1.0, 0.8, 0.9)
S = np.array([0.3 + 2.0j, -0.1 + 15.0j, 1.0 - 40.0j])
GRID = 41  # a small kernel grid: the aliases are compared exactly, not converged


class _Stop(Exception):
    """Raised by a stub to stop a long job once its inputs are known."""


def _warns(new: str) -> pytest.WarningsRecorder:
    """The deprecation of an old keyword, naming the new one."""
    return pytest.warns(DeprecationWarning, match=f"use '{new}'")


# ---------------------------------------------------------------------------- kernel grid
def test_solve_kernels_n_is_kernel_grid() -> None:
    new = solve_kernels(PAPER, kernel_grid=GRID)
    with _warns("kernel_grid"):
        old = solve_kernels(PAPER, n=GRID)
    np.testing.assert_allclose(old.K, new.K, rtol=0, atol=0)
    np.testing.assert_allclose(old.L, new.L, rtol=0, atol=0)
    assert new.n == GRID
    assert solve_kernels(TRANSPORT).n == DEFAULT_KERNEL_GRID == 201


def test_delay_form_n_is_kernel_grid() -> None:
    new = delay_form(PAPER, kernel_grid=GRID)
    with _warns("kernel_grid"):
        old = delay_form(PAPER, n=GRID)
    np.testing.assert_allclose(old.characteristic(S), new.characteristic(S), rtol=0, atol=0)


def test_loop_factors_and_characteristic_n_is_kernel_grid() -> None:
    ctrl = ReflectionController(0.1)
    A, B = loop_factors(PAPER, ctrl, kernel_grid=GRID)
    with _warns("kernel_grid"):
        A_old, B_old = loop_factors(PAPER, ctrl, n=GRID)
    np.testing.assert_allclose(A_old(S), A(S), rtol=0, atol=0)
    np.testing.assert_allclose(B_old(S), B(S), rtol=0, atol=0)
    F = characteristic(PAPER, ctrl, 0.1, kernel_grid=GRID)
    with _warns("kernel_grid"):
        F_old = characteristic(PAPER, ctrl, 0.1, n=GRID)
    np.testing.assert_allclose(F_old(S), F(S), rtol=0, atol=0)
    # the grid changes N~, so the aliases above really reached the kernel solver
    assert np.max(np.abs(characteristic(PAPER, ctrl, 0.1, kernel_grid=21)(S) - F(S))) > 1e-12


def test_rouche_delay_bound_n_is_kernel_grid() -> None:
    ctrl = ReflectionController(0.1)
    new = rouche_delay_bound(PAPER, ctrl, kernel_grid=GRID)
    with _warns("kernel_grid"):
        old = rouche_delay_bound(PAPER, ctrl, n=GRID)
    assert old.delta_0 == new.delta_0 > 0.0


def test_transfer_functions_n_is_kernel_grid() -> None:
    H = open_loop_tf(PAPER, kernel_grid=GRID)
    with _warns("kernel_grid"):
        H_old = open_loop_tf(PAPER, n=GRID)
    np.testing.assert_allclose(H_old(S), H(S), rtol=0, atol=0)
    M = output_map(PAPER, kernel_grid=GRID)
    with _warns("kernel_grid"):
        M_old = output_map(PAPER, n=GRID)
    np.testing.assert_allclose(M_old(S), M(S), rtol=0, atol=0)


def test_delay_margin_n_is_kernel_grid() -> None:
    ctrl = ReflectionController(0.1)
    new = delay_margin(PAPER, ctrl, verify=False, kernel_grid=GRID)
    with _warns("kernel_grid"):
        old = delay_margin(PAPER, ctrl, verify=False, n=GRID)
    assert old.margin == new.margin and old.omega == new.omega
    assert new.margin == pytest.approx(0.2295391303, abs=1e-6)  # the paper's margin, coarse grid


def test_simulate_kernel_n_is_kernel_grid() -> None:
    args = (PAPER, ReflectionController(0.1), 0.05, 1.0, np.cos, np.sin)
    new = simulate(*args, cells=20, kernel_grid=11)
    with _warns("kernel_grid"):
        old = simulate(*args, cells=20, kernel_n=11)
    np.testing.assert_allclose(old.norm, new.norm, rtol=0, atol=0)
    np.testing.assert_allclose(old.control, new.control, rtol=0, atol=0)


# ---------------------------------------------------------------------------- simulation cells
def test_simulate_n_is_cells() -> None:
    args = (PAPER, ReflectionController(0.1), 0.05, 1.0, np.cos, np.sin)
    new = simulate(*args, cells=20)
    with _warns("cells"):
        old = simulate(*args, n=20)
    np.testing.assert_allclose(old.norm, new.norm, rtol=0, atol=0)
    assert old.n == new.n == 20 and new.x.size == 21
    assert simulate(TRANSPORT, FiniteTimeController(), 0.0, 0.01, np.cos, np.sin).n == DEFAULT_CELLS == 400


def test_v_nodes_n_is_cells() -> None:
    new = v_nodes(UNEQUAL, cells=30)
    with _warns("cells"):
        old = v_nodes(UNEQUAL, n=30)
    np.testing.assert_allclose(old, new, rtol=0, atol=0)


def test_run_paper_n_is_cells(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The simulation jobs of ``nrobust paper`` get the same grid (stopped before they run)."""
    seen: list[list[tuple]] = []

    def runner(*args: object, **kwargs: object) -> object:
        def run(func: object, jobs: list[tuple]) -> list:
            seen.append([job for job in jobs if job[0] == "simulate"])
            raise _Stop  # only the jobs are compared

        return run

    monkeypatch.setattr(nrobust.reports.paper, "sweep_map", runner)
    with pytest.raises(_Stop):
        nrobust.reports.paper.run_paper(tmp_path, progress=False, workers=0, cells=24)
    with _warns("cells"), pytest.raises(_Stop):
        nrobust.reports.paper.run_paper(tmp_path, progress=False, workers=0, n=24)
    with pytest.raises(_Stop):
        nrobust.reports.paper.run_paper(tmp_path, progress=False, workers=0)
    new, old, default = seen
    assert new and old == new and all(job[-1] == 24 for job in new)
    assert all(job[-1] == DEFAULT_CELLS for job in default)


SYSTEM_TOML = """
[system]
type = "TransportSystem"
lam = 1.0
mu = 1.0
q = 1.0
rho = 0.5

[controller]
type = "FiniteTimeController"

[analysis]
delta_max = 0.1

[simulation]
delays = [0.0]
{grid}
"""


def test_system_file_simulation_n_is_cells(tmp_path: Path) -> None:
    path = tmp_path / "SYSTEM.toml"
    path.write_text(SYSTEM_TOML.format(grid="cells = 24"))
    assert load_system_file(path)["simulation"]["cells"] == 24
    path.write_text(SYSTEM_TOML.format(grid="n = 24"))
    with pytest.warns(DeprecationWarning, match="simulation.n is deprecated, use simulation.cells"):
        assert load_system_file(path)["simulation"]["cells"] == 24
    path.write_text(SYSTEM_TOML.format(grid=""))
    assert load_system_file(path)["simulation"]["cells"] == DEFAULT_CELLS
    path.write_text(SYSTEM_TOML.format(grid="n = 24\ncells = 24"))
    with pytest.raises(ParameterError) as err:
        load_system_file(path)
    assert err.value.name == "simulation.n"


# ---------------------------------------------------------------------------- gain grid
def test_k_region_n_is_n_gains() -> None:
    new = k_region(TRANSPORT, 2.0, n_gains=5, tol=1e-2)
    with _warns("n_gains"):
        old = k_region(TRANSPORT, 2.0, n=5, tol=1e-2)
    np.testing.assert_allclose(old.Ks, new.Ks, rtol=0, atol=0)
    assert old.intervals == new.intervals and new.Ks.size == 5
    assert k_region(TRANSPORT, 2.0, tol=1e-2).Ks.size == DEFAULT_N_GAINS == 9


def test_certify_k_grid_is_n_gains() -> None:
    ctrl = ReflectionController(0.1)
    new = certify(TRANSPORT, ctrl, delta_max=0.5, n_gains=3)
    with _warns("n_gains"):
        old = certify(TRANSPORT, ctrl, delta_max=0.5, k_grid=3)
    assert new.k_region is not None and old.k_region is not None
    np.testing.assert_allclose(old.k_region.Ks, new.k_region.Ks, rtol=0, atol=0)
    assert old.k_region.intervals == new.k_region.intervals and new.k_region.Ks.size == 3


# ---------------------------------------------------------------------------- frequency samples
def test_nyquist_response_n_is_n_freq() -> None:
    A = QuasiPolynomial([[1.0, 1.0]], [0.0])
    B = QuasiPolynomial([[0.5]], [0.0])
    new = nyquist_response(A, B, delta=0.2, omega_max=20.0, n_freq=64)
    with _warns("n_freq"):
        old = nyquist_response(A, B, delta=0.2, omega_max=20.0, n=64)
    np.testing.assert_allclose(old.omega, new.omega, rtol=0, atol=0)
    np.testing.assert_allclose(old.loop, new.loop, rtol=0, atol=0)
    assert old.rhp_zeros == new.rhp_zeros == 0


# ---------------------------------------------------------------------------- methods and attributes
def test_deriv_is_deriv_at() -> None:
    d = DistributedDelay([0.0, 0.5, 1.0], [1.0, -2.0, 0.5], poly=(1.0, 2.0))
    F = QuasiPolynomial([[1.0, 0.3], [-0.5]], [0.0, 1.0], [d])
    with pytest.warns(DeprecationWarning, match=r"use QuasiPolynomial.deriv_at\(s\)"):
        np.testing.assert_allclose(F.deriv(S), F.deriv_at(S), rtol=0, atol=0)
    with pytest.warns(DeprecationWarning, match=r"use DistributedDelay.deriv_at\(s\)"):
        np.testing.assert_allclose(d.deriv(S), d.deriv_at(S), rtol=0, atol=0)
    np.testing.assert_allclose(F.deriv_at(S), F.derivative()(S), rtol=1e-12, atol=0)


def test_delay_margin_nominal_stable_is_nominally_stable() -> None:
    dm = delay_margin(QuasiPolynomial([[1.0, 1.0]], [0.0]), QuasiPolynomial([[2.0]], [0.0]))
    assert dm.nominally_stable
    with pytest.warns(DeprecationWarning, match="use DelayMargin.nominally_stable"):
        assert dm.nominal_stable is dm.nominally_stable
    data = dm.to_dict()
    assert data["nominally_stable"] is True and "nominal_stable" not in data


# ---------------------------------------------------------------------------- the alias mechanism
def test_old_and_new_keyword_together_is_an_error() -> None:
    with pytest.raises(ParameterError) as err:
        solve_kernels(TRANSPORT, kernel_grid=11, n=11)
    assert err.value.name == "n" and "kernel_grid" in err.value.requirement
    with pytest.raises(ParameterError) as err:
        solve_kernels(TRANSPORT, 11, n=11)  # the new one by position
    assert err.value.name == "n"
    with pytest.raises(ParameterError):
        simulate(TRANSPORT, FiniteTimeController(), 0.0, 1.0, np.cos, np.sin, 20, n=20)


def test_signatures_show_the_new_names() -> None:
    for func, new in [
        (solve_kernels, "kernel_grid"),
        (delay_margin, "kernel_grid"),
        (simulate, "cells"),
        (k_region, "n_gains"),
        (certify, "n_gains"),
        (nyquist_response, "n_freq"),
    ]:
        params = inspect.signature(func).parameters
        assert new in params and "n" not in params and "k_grid" not in params


def test_sweep_file_accepts_the_old_option_name() -> None:
    options = ANALYSES["delay_margin"].options()
    assert options is not None and {"kernel_grid", "n"} <= options


# ---------------------------------------------------------------------------- error names
def test_delay_margin_errors_name_its_own_parameters() -> None:
    A = QuasiPolynomial([[1.0, 1.0]], [0.0])
    with pytest.raises(ParameterError) as err:
        delay_margin(A, ReflectionController(0.1))
    assert err.value.name == "controller" and "(A, B)" in err.value.requirement
    with pytest.raises(ParameterError) as err:
        delay_margin(PAPER, A)
    assert err.value.name == "controller" and "plant" in err.value.requirement
    with pytest.raises(ParameterError) as err:
        delay_margin("plant", ReflectionController(0.1))  # type: ignore[arg-type]
    assert err.value.name == "system" and "factor A" in err.value.requirement
