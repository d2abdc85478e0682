"""Several-parameter designs (nrobust.design.local, pareto; nrobust.hyperbolic.analyses.filter_design).

Oracles, sharing no code with the optimiser: the decay rate -ln|q (rho - K)|/tau of U_BS2(K) on a
transport system (its loop 1 - q (rho - K) e^{-tau s} written here), the filter's own root -1/b, the
strong-stability sum gamma_0 = |rho q| + |a/b| |K q| of the filtered loop's difference operator
written from the controller's definition, the gradient of the abscissa and of the margin against
central differences of independently recomputed values, and (long) a brute-force grid of
certified evaluations that the design must match or beat.
"""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

import nrobust as nr
from nrobust.design.local import delayed_gamma, optimize_loop
from nrobust.design.pareto import pareto_front
from nrobust.errors import CertificationError, ParameterError
from nrobust.hyperbolic.analyses.filter_design import design_filtered, filtered_loop
from nrobust.margins import delay_margin
from nrobust.roots import spectral_abscissa

LAM, MU, Q, RHO = 1.0, 2.0, 1.0, 0.6
TAU = 1.0 / LAM + 1.0 / MU


@pytest.fixture(scope="module")
def transport() -> nr.TransportSystem:
    return nr.TransportSystem(LAM, MU, Q, RHO)


def test_filtered_controller_with_K_rho_is_the_filtered_u_bs(transport: nr.TransportSystem) -> None:
    a, b = 0.03, 0.1
    A1, B1 = nr.loop_factors(transport, nr.FilteredController(a, b))
    A2, B2 = nr.loop_factors(transport, nr.FilteredController(a, b, RHO))
    s = np.array([0.3 + 2.0j, -0.2 + 11.0j])
    np.testing.assert_allclose(A1(s), A2(s), rtol=1e-15)
    np.testing.assert_allclose(B1(s), B2(s), rtol=1e-15)
    # U_BS2(K) through the filter, written from the definition: (1 - rho q e^{-tau s})(1 + b s), K q e^{-tau s}(1 + a s)
    K = 0.2
    A, B = nr.loop_factors(transport, nr.FilteredController(a, b, K))
    np.testing.assert_allclose(A(s), (1 - RHO * Q * np.exp(-TAU * s)) * (1 + b * s), rtol=1e-14)
    np.testing.assert_allclose(B(s), K * Q * np.exp(-TAU * s) * (1 + a * s), rtol=1e-14)


def test_delayed_gamma_is_the_strong_stability_sum(transport: nr.TransportSystem) -> None:
    a, b, K = -0.04, 0.1, 0.3
    A, B = nr.loop_factors(transport, nr.FilteredController(a, b, K))
    np.testing.assert_allclose(delayed_gamma(A, B), abs(RHO * Q) + abs(a / b) * abs(K * Q), rtol=1e-14)
    A, B = nr.loop_factors(transport, nr.FilteredController(0.0, b, K))  # a = 0: B is retarded
    np.testing.assert_allclose(delayed_gamma(A, B), abs(RHO * Q), rtol=1e-14)


def test_gradients_match_central_differences() -> None:
    """The sensitivities of the rightmost root and of the critical crossing vs recomputed values.

    ``s + p0 + p1 e^{-s}`` (its rightmost root a simple complex pair) and, for the margin,
    ``A = s + p0``, ``B = p1 (1 + 0.2 s)`` (a neutral loop, one crossing branch).
    """
    from nrobust.design.local import _Problem

    def retarded(p: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
        return nr.QuasiPolynomial([[p[0], 1.0], [p[1]]], [0.0, 1.0]), nr.QuasiPolynomial([[0.0]], [0.0])

    def neutral(p: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
        return nr.QuasiPolynomial([[p[0], 1.0]], [0.0]), nr.QuasiPolynomial([[p[1], 0.2 * p[1]]], [0.0])

    h = 1e-5
    for loop, want, p in ((retarded, "decay_rate", [0.5, 1.5]), (neutral, "margin", [1.0, 2.0])):
        problem = _Problem(loop, np.array([(0.0, 3.0), (0.0, 3.0)]), "decay_rate", None, 0.999)
        x = problem(np.array(p), want=want)
        assert x.feasible and np.all(x.gradient != 0.0)
        fd = []
        for i in range(2):
            e = np.zeros(2)
            e[i] = h
            fd.append((problem(p + e, want=want).value - problem(p - e, want=want).value) / (2 * h))
        # central differences of values certified to ~1e-12: error ~1e-12/h + h^2 f''' ~ 1e-7
        np.testing.assert_allclose(x.gradient, fd, rtol=1e-5, atol=1e-7)


def test_design_reaches_the_closed_form_optimum(transport: nr.TransportSystem) -> None:
    """K free, a = b (no filtering): U_BS2(K) at its bound, decay rate -ln(q (rho - K))/tau."""
    k_hi = 0.35  # |K q| < 1 - |rho q| = 0.4: stable for every delay, so the bound is the optimum
    design = design_filtered(
        transport, parameters={"K": (-k_hi, k_hi), "a": 0.1, "b": 0.1}, margin_at_least=1.0, x0=[0.3], starts=1
    )
    expected = -math.log(Q * (RHO - k_hi)) / TAU
    # the pattern search stops within POLISH_TOL * width = 7e-6 of the bound: d rate/dK = 1/(tau (rho - K)) = 2.7
    np.testing.assert_allclose(design.value, expected, atol=5e-5)
    assert design.certified and math.isinf(design.design.margin.margin)
    assert design.controller.K == pytest.approx(k_hi, abs=2e-5)
    assert design.design.local and "PDE itself" in design.scope
    words = design.design.optimality
    assert words.startswith("local: the best of 1 start,") and "not global" in words
    assert design.design.to_dict()["optimality"] == words


def test_every_iterate_is_feasible_and_the_requirement_holds() -> None:
    """A loop with a margin requirement: the design meets it, and a requirement out of reach is refused."""
    A0 = nr.QuasiPolynomial([[1.0, 1.0]], [0.0])  # s + 1 + k e^{-delta s}: margin arccos(-1/k)/sqrt(k^2 - 1)

    def loop(p: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
        return A0, nr.QuasiPolynomial([[p[0]]], [0.0])

    design = optimize_loop(loop, [(0.0, 5.0)], margin_at_least=0.8, x0=[0.5])
    k = design.parameters[0]
    margin = math.acos(-1.0 / k) / math.sqrt(k * k - 1.0)
    # the decay rate of s + 1 + k grows with k (root -1 - k) until the margin binds at 0.8
    assert margin >= 0.8 - 1e-9 and design.certified
    np.testing.assert_allclose(design.margin.margin, margin, rtol=1e-9)
    # every accepted iterate met the requirement (closed form; |k| <= 1: no crossing, the margin is infinite)
    path = design.runs[0].path
    assert len(path) >= 3 and path[0] == (0.5,) and path[-1] == design.parameters
    for (kk,) in path:
        assert 0.0 <= kk <= 5.0
        assert kk <= 1.0 or math.acos(-1.0 / kk) / math.sqrt(kk * kk - 1.0) >= 0.8 - 1e-9, kk
    with pytest.raises(CertificationError, match="no start reached a feasible design"):
        # the margin decreases with k: at most arccos(-1/1.5)/sqrt(1.25) = 2.0577 on [1.5, 5]
        optimize_loop(loop, [(1.5, 5.0)], margin_at_least=2.2, x0=[3.0], max_iter=5)


def test_pareto_front_trades_decay_rate_for_margin() -> None:
    A0 = nr.QuasiPolynomial([[1.0, 1.0]], [0.0])

    def loop(p: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
        return A0, nr.QuasiPolynomial([[p[0]]], [0.0])

    front = pareto_front(loop, [(0.0, 5.0)], [0.3, 0.6, 1.2], x0=[0.5])
    assert front.certified and front.infeasible == ()
    assert np.all(np.diff(front.decay_rates) <= 1e-9)  # more margin costs decay rate
    assert np.all(front.margins >= front.required - 1e-9)
    assert front.to_dict()["required"] == [0.3, 0.6, 1.2]
    import matplotlib

    matplotlib.use("Agg")
    from nrobust.plots import pareto_plot

    drawn = pareto_plot(front)
    x, y = drawn.lines["front"][0].get_data()
    np.testing.assert_allclose(x, front.margins)
    np.testing.assert_allclose(y, front.decay_rates)


def test_pareto_response_is_the_front_with_plot() -> None:
    """``pareto_response(...).plot()``: the front as data with ``.plot()``, against the closed form.

    ``s + 1 + k e^{-delta s}`` (``k > 1``) has the margin ``arccos(-1/k) / sqrt(k^2 - 1)``,
    decreasing in ``k``, and the decay rate ``1 + k``: the best rate under a margin ``d`` is
    ``1 + k_d`` with ``k_d`` the gain of margin ``d`` (Brent's method on the closed form), or the
    bound ``k = 5`` where the margin there exceeds ``d``."""
    import matplotlib

    matplotlib.use("Agg")
    from scipy.optimize import brentq

    from nrobust.plots import ParetoResponse, pareto_response

    A0 = nr.QuasiPolynomial([[1.0, 1.0]], [0.0])

    def loop(p: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
        return A0, nr.QuasiPolynomial([[p[0]]], [0.0])

    required = [0.3, 0.6, 1.2]
    response = pareto_response(loop, [(0.0, 5.0)], required, x0=[0.5])
    assert isinstance(response, ParetoResponse) and response.front.certified

    def margin(k: float) -> float:
        return math.acos(-1.0 / k) / math.sqrt(k * k - 1.0)

    # the bound k = 5 where its margin (0.3617) exceeds d
    k_d = [5.0 if margin(5.0) >= d else brentq(lambda k, d=d: margin(k) - d, 1.0 + 1e-12, 5.0) for d in required]
    assert k_d[0] == 5.0 and k_d[1] < 5.0
    best = 1.0 + np.array(k_d)
    # feasible designs cannot beat the optimum; the local search stops at its last pattern step
    # (2^-11 in k here: 2.1e-5 below the optimum measured), so within 1e-4
    assert np.all(response.front.decay_rates <= best * (1.0 + 1e-12))
    np.testing.assert_allclose(response.front.decay_rates, best, rtol=1e-4)
    assert response.to_dict() == response.front.to_dict()
    drawn = response.plot()
    x, y = drawn.lines["front"][0].get_data()
    np.testing.assert_allclose(x, response.front.margins)
    np.testing.assert_allclose(y, response.front.decay_rates)


def test_bad_input_is_named(transport: nr.TransportSystem) -> None:
    loop = filtered_loop(transport, {"K": None, "a": 0.0, "b": 0.1})
    with pytest.raises(ParameterError, match="bounds"):
        optimize_loop(loop, [(1.0, 0.0)])
    with pytest.raises(ParameterError, match="objective"):
        optimize_loop(loop, [(0.0, 0.1)], objective="speed")
    with pytest.raises(ParameterError, match="gamma_max"):
        optimize_loop(loop, [(0.0, 0.1)], gamma_max=1.0)
    with pytest.raises(ParameterError, match="parameters"):
        design_filtered(transport, parameters={"k": None})
    with pytest.raises(ParameterError, match="pole"):
        design_filtered(transport, parameters={"b": (0.0, 1.0)})


@pytest.mark.long
def test_design_matches_or_beats_a_certified_grid(transport: nr.TransportSystem) -> None:
    """Two free parameters (K, a), b fixed: the best certified point of a 9 x 9 grid is not better."""
    bounds = {"K": (-0.35, 0.6), "a": (-0.05, 0.05), "b": 0.1}
    required = 0.5
    loop = filtered_loop(transport, {"K": None, "a": None, "b": 0.1})
    best = -math.inf
    for K in np.linspace(*bounds["K"], 9):
        for a in np.linspace(*bounds["a"], 9):
            A, B = loop(np.array([K, a]))
            if delayed_gamma(A, B) > 0.999:  # GAMMA_MAX
                continue
            dm = delay_margin(A, B)
            if dm.margin >= required:
                best = max(best, -spectral_abscissa(A + B).value)
    design = design_filtered(transport, parameters=bounds, margin_at_least=required, starts=3)
    assert design.certified
    assert design.value >= best - 1e-9


def test_design_section_of_system_toml(tmp_path: pathlib.Path) -> None:
    """[design] is read and checked key by key; nrobust design takes it (flags override)."""
    from nrobust.config import load_system_file
    from nrobust.reports.design import run_design

    head = (
        '[system]\ntype = "TransportSystem"\nlam = 1.0\nmu = 2.0\nq = 1.0\nrho = 0.6\n'
        '[controller]\ntype = "ReflectionController"\nK = 0.1\n[analysis]\ndelta_max = 0.5\n'
    )
    good = tmp_path / "good.toml"
    good.write_text(head + '[design]\nfamily = "reflection"\nK = [0.0, 0.35]\n')
    spec = load_system_file(good)
    assert spec["design"]["K"] == (0.0, 0.35) and spec["design"]["objective"] == "margin"
    for bad, key in (
        ('family = "filter"', "did you mean 'filtered'"),
        ('objective = "speed"', "design.objective"),
        ("K = [0.3, 0.1]", "design.K"),
        ("a = 0.1", "design.a"),
        ("starts = 0", "design.starts"),
        ("margin_at_least = -1.0", "design.margin_at_least"),
    ):
        path = tmp_path / "bad.toml"
        path.write_text(head + "[design]\n" + bad + "\n")
        with pytest.raises(ParameterError, match=key):
            load_system_file(path)
    # U_BS2(K) on a transport plant with |K q| < 1 - |rho q| = 0.4: stable for every delay
    written, design = run_design(good, tmp_path / "out")
    assert math.isinf(design.value) and {p.name for p in written} == {"design.json", "design.md", "design.png"}


def test_an_optimum_on_a_bound_at_a_double_root_is_reached():
    """``A = s^2 + c_1 s + 1``, ``B = c_2``: the decay rate is ``c_1 / 2`` while the roots are complex and
    ``1 - sqrt(-c_2)`` below ``c_2 = 0`` at ``c_1 = 2``, so the best (1) is the double root ``-1`` at the bound
    ``c_1 = 2`` (a 15 x 15 certified grid finds it). The pattern search stopped 1.4e-5 short of the bound (steps
    past it were rejected, not clipped), and at the double root the abscissa's sensitivity divided by F' = 0."""

    def family(p):
        c1, c2 = p
        return nr.QuasiPolynomial([[1.0, c1, 1.0]], [0.0]), nr.QuasiPolynomial([[c2]], [0.0])

    d = optimize_loop(family, [(0.1, 2.0), (-0.5, 0.5)], margin_at_least=1.0, x0=[1.0, 0.0], starts=2)
    assert d.certified and d.margin.margin >= 1.0
    assert d.parameters[0] == 2.0
    # the abscissa of a double root, known to about sqrt(eps) (the root's own conditioning)
    np.testing.assert_allclose(d.value, 1.0, rtol=0, atol=1e-7)
