"""Backstepping kernels and the full-state controller of n + m systems (Hu et al. 2016).

Independent routes: the paper's 2x2 kernels (``solve_kernels``, Richardson-extrapolated on
401 points) for ``n = m = 1``; the 2x2 delay margin of ``U_BS`` by the delay form
(``delay_margin(system, FiniteTimeController())``); a kernel-free quadrature of the
feedback integral with ``scipy.linalg.expm``; the PDE simulated with the controller
(finite-time convergence, growth beyond the margin). Tolerances come from the
convergence studies quoted in each test.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.integrate import simpson
from scipy.linalg import expm

from nrobust.errors import ParameterError
from nrobust.hyperbolic import FiniteTimeController, Hyperbolic2x2, solve_kernels
from nrobust.hyperbolic.analyses import delay_margin
from nrobust.hyperbolic.nplusm.cascade_margin import backstepping_delay_margin
from nrobust.hyperbolic.nplusm.kernels import NPlusMBackstepping, solve_nplusm_kernels
from nrobust.hyperbolic.nplusm.system import NPlusMSystem
from nrobust.hyperbolic.simulate import simulate_nplusm

PLANT = Hyperbolic2x2(1.0, 1.5, 1.2, 0.8, 1.0, 0.4)  # 2 rho q = 0.8 < 1: a positive margin
#: Simulated growth rate against the rightmost root beyond the margin: measured 0.13120 (40 cells) and 0.13135 (80)
#: against Re s = 0.13184 on PLANT at 1.3 times the margin (0.5 % and 0.4 %).
GROWTH_RTOL = 0.01
TWO_ONE = NPlusMSystem(
    [1.0, 2.0], [1.5], [[0.2, 0.3, 1.0], [0.4, -0.1, 0.8], [1.2, -0.6, 0.3]], [[1.0], [0.5]], [[0.5, 0.4]]
)
TWO_TWO = NPlusMSystem(
    [1.0, 2.0],
    [1.5, 0.7],
    [[0.2, 0.3, 1.0, 0.5], [0.4, -0.1, 0.8, 0.2], [1.2, -0.6, 0.3, 0.4], [0.5, 0.3, -0.4, 0.1]],
    [[1.0, 0.2], [0.5, 0.1]],
    [[0.5, 0.4], [0.1, 0.3]],
)


def _profiles(x: np.ndarray) -> np.ndarray:
    return np.array([np.sin(np.pi * x) + 0.3, np.cos(2 * x), 1 + x**2])


def test_one_plus_one_reproduces_the_paper_kernels() -> None:
    """``K = K^{vu}``, ``L = K^{vv}`` of eqs. (26)-(29). Study (trace at x = 1 against 401
    extrapolated points): K 1.0e-6, 2.5e-7, 6.9e-8 and L 5.6e-6, 1.4e-6, 3.4e-7 at 41, 81,
    161 points: order 2.0; asserted with a factor 2 of room."""
    ref = solve_kernels(PLANT, 401)
    errors = []
    for N in (41, 81):
        ker = solve_nplusm_kernels(NPlusMSystem.from_2x2(PLANT), N)
        x = ker.grid
        np.testing.assert_allclose(ker.K[0, 0, -1], ref.Kvu(1.0, x), rtol=0, atol=2.0 * 1.0e-6 * (41 / N) ** 2)
        np.testing.assert_allclose(ker.L[0, 0, -1], ref.Kvv(1.0, x), rtol=0, atol=2.0 * 5.6e-6 * (41 / N) ** 2)
        half = x[x <= 0.5]  # the level x = 0.5 inside the triangle
        np.testing.assert_allclose(ker.K_at(0.5, half)[0, 0], ref.Kvu(0.5, half), rtol=0, atol=2e-5 * (41 / N) ** 2)
        errors.append(np.max(np.abs(ker.L[0, 0, -1] - ref.Kvv(1.0, x))))
        assert np.max(np.abs(ker.G)) < 1e-12  # m = 1: G = 0 (the boundary relation holds exactly)
    assert 1.7 <= np.log2(errors[0] / errors[1]) <= 2.4


def test_observed_order_of_the_kernels_two_plus_one() -> None:
    """Three grids (21, 41, 81): differences 2.9e-5, 7.2e-6 of the traces, order 2.03."""
    traces = [solve_nplusm_kernels(TWO_ONE, N).trace[..., :: (N - 1) // 20] for N in (21, 41, 81)]
    d1, d2 = np.max(np.abs(traces[0] - traces[1])), np.max(np.abs(traces[1] - traces[2]))
    assert 1.7 <= np.log2(d1 / d2) <= 2.4
    assert d2 < 1.5e-5


def test_two_actuators_target_and_feedback_integral_order() -> None:
    """``m = 2``, ``mu = (1.5, 0.7)``: ``G`` lives only where ``mu_b > mu_a`` (here ``G_10``);
    ``L_01`` jumps across the characteristic from the origin (its corner values differ),
    so the traces converge in max norm only to O(1), but the feedback integral
    ``J(s)`` converges at order 1.78 (differences 2.0e-3, 5.9e-4 on 21, 41, 81 points)."""
    kers = [solve_nplusm_kernels(TWO_TWO, N) for N in (21, 41, 81)]
    G = kers[-1].G[..., 1:]  # the node x = 0 carries the corner's jump
    assert np.max(np.abs(G[0, 1])) < 1e-12 and np.max(np.abs(G[0, 0])) < 1e-12 and np.max(np.abs(G[1, 1])) < 1e-12
    assert np.max(np.abs(G[1, 0])) > 0.1
    s = np.array([0.3, 2j, 0.5 + 7j])
    J = [NPlusMBackstepping(k).feedback_integral(s) for k in kers]
    d1, d2 = np.max(np.abs(J[0] - J[1])), np.max(np.abs(J[1] - J[2]))
    assert 1.5 <= np.log2(d1 / d2) <= 2.3


def test_feedback_integral_against_direct_quadrature() -> None:
    """Filon weights against Simpson's rule on 801 points, ``Phi`` by powers of ``expm(h C)`` (no
    block exponential; the panels align with the kernel nodes, so the rule's error is ~1e-9 at ``|s| = 7``)."""
    ctl = NPlusMBackstepping(solve_nplusm_kernels(TWO_ONE, 41))
    s = np.array([0.5 + 7j, -0.2 + 1j])
    xi = np.linspace(0.0, 1.0, 801)
    trace = np.array([[np.interp(xi, ctl.kernels.grid, t) for t in row] for row in ctl.kernels.trace])
    inv = 1.0 / TWO_ONE.signed_speeds
    w0 = np.vstack([TWO_ONE.q, np.eye(1)])
    for k, sk in enumerate(s):
        C = inv[:, None] * (TWO_ONE.sigma - sk * np.eye(3))
        step = expm((xi[1] - xi[0]) * C)
        phi = np.empty((xi.size, 3, 3), dtype=complex)
        phi[0] = np.eye(3)
        for i in range(1, xi.size):
            phi[i] = phi[i - 1] @ step
        vals = np.einsum("abi,ibc,cd->iad", trace, phi, w0)
        direct = simpson(vals, x=xi, axis=0)
        np.testing.assert_allclose(ctl.feedback_integral(s)[k], direct, rtol=0, atol=1e-8)


def test_finite_time_convergence_in_simulation() -> None:
    """Without delay the simulated norm reaches the scheme's residual at ``t_F = 1/min lam +
    1/mu`` (the target's cascade) and not before. Study: at 1.01 t_F the norm is 2.4e-2
    (40 cells) and 1.2e-2 (80): first order in the cells (the residual stays flat after
    t_F); at 0.99 t_F it is still 0.59."""
    ctl = NPlusMBackstepping(solve_nplusm_kernels(TWO_ONE, 81))
    tF = ctl.convergence_time
    assert tF == pytest.approx(1.0 + 1.0 / 1.5)
    residual = []
    for cells in (40, 80):
        sim = simulate_nplusm(TWO_ONE, ctl, 0.0, 1.6 * tF, _profiles, cells=cells)
        before = sim.norm[sim.times <= 0.97 * tF]
        after = sim.norm[sim.times >= 1.01 * tF]
        assert before.min() > 0.5
        residual.append(after.max())
    assert residual[1] < 0.02 * sim.norm[0]
    assert 1.6 <= residual[0] / residual[1] <= 2.5


def test_a_group_of_equal_speeds_keeps_its_coupling_in_the_target() -> None:
    """``mu = (1.5, 1.5)`` coupled inside the group (``D`` nondiagonal): ``G = 0``, and the loop
    is at rest after ``1/lam + 1/1.5`` (one group). Study: residual 6.2e-3 (40 cells), 3.1e-3
    (80) after t_F; above 0.49 before."""
    plant = NPlusMSystem(
        [1.0], [1.5, 1.5], [[0.1, 0.8, 0.5], [0.7, 0.2, 0.6], [-0.5, -0.4, 0.1]], [[1.0, 0.5]], [[0.4], [0.3]]
    )
    ctl = NPlusMBackstepping.for_system(plant, 41)
    assert np.max(np.abs(ctl.kernels.G[..., 1:])) < 1e-12
    tF = ctl.convergence_time
    assert tF == pytest.approx(1.0 + 1.0 / 1.5)
    sim = simulate_nplusm(plant, ctl, 0.0, 1.5 * tF, _profiles, cells=40)
    assert sim.norm[sim.times <= 0.97 * tF].min() > 0.4
    assert sim.norm[sim.times >= 1.02 * tF].max() < 1e-2


@pytest.mark.slow
def test_delay_margin_against_the_two_by_two_route_and_simulation() -> None:
    """The margin of the full-state controller with a loop delay, against the paper's ``U_BS``
    (eq. (47)) by the delay form: 0.7666791707. Study: 0.76668328, 0.76668020, 0.76667943 at
    41, 81, 161 kernel points (errors 4.1e-6, 1.0e-6, 2.6e-7: second order). ``gamma_0 = 2 rho q``.
    The simulated loop decays below the margin and grows beyond it at the rate of the
    rightmost root of the Laplace route (``GROWTH_RTOL``)."""
    ref = delay_margin(PLANT, FiniteTimeController())
    ctl = NPlusMBackstepping(solve_nplusm_kernels(NPlusMSystem.from_2x2(PLANT), 81))
    m = backstepping_delay_margin(ctl, 15.0, points=300)
    assert not m.certified
    assert m.gamma_0 == pytest.approx(2 * PLANT.rho * PLANT.q)
    np.testing.assert_allclose(m.margin, ref.margin, rtol=0, atol=3e-6)
    assert m.omega is not None and ref.omega is not None
    np.testing.assert_allclose(m.omega, ref.omega, rtol=0, atol=3e-5)

    def w0(x: np.ndarray) -> np.ndarray:
        return np.array([np.sin(np.pi * x) + 0.3, 1 + x**2])

    below = simulate_nplusm(ctl.system, ctl, 0.7 * m.margin, 40.0, w0, cells=40)
    beyond = simulate_nplusm(ctl.system, ctl, 1.3 * m.margin, 40.0, w0, cells=40)
    assert below.growth_rate(20.0) < 0 < beyond.growth_rate(20.0)
    root = _root_near(ctl, 0.1 + 1j * m.omega, 1.3 * m.margin)
    np.testing.assert_allclose(beyond.growth_rate(20.0), root.real, rtol=GROWTH_RTOL)


def _root_near(ctl: NPlusMBackstepping, s: complex, delta: float) -> complex:
    """Newton's method on the delayed characteristic function (central differences)."""
    for _ in range(40):
        f = ctl.characteristic_value(np.array([s]), delta)[0]
        h = 1e-6
        df = ctl.characteristic_value(np.array([s + h, s - h]), delta) @ np.array([1.0, -1.0]) / (2 * h)
        s = s - f / df
    return s


@pytest.mark.slow
def test_two_actuators_margin_root_and_simulated_growth() -> None:
    """``m = 2`` (``gamma_0 ~ 0.61 < 1``): at the margin a root sits on the axis; at 1.3 times the
    margin the rightmost root (Re 0.1649) is the simulated growth rate (0.1703 at 60 and 90
    cells: within 4 %). Below the margin the simulator's coarse grids carry spurious growing
    modes (60 cells decay, 90 grow), so only the unstable side is compared."""
    plant = NPlusMSystem(TWO_TWO.lam, TWO_TWO.mu, TWO_TWO.sigma, TWO_TWO.q, [[0.15, 0.1], [0.05, 0.1]])
    ctl = NPlusMBackstepping.for_system(plant, 41)
    m = backstepping_delay_margin(ctl, 5.0, points=100)
    assert m.gamma_0 < 1 and 0 < m.margin < np.inf and m.omega is not None
    assert abs(ctl.characteristic_value(np.array([1j * m.omega]), m.margin)[0]) < 1e-10
    root = _root_near(ctl, 0.1 + 1j * m.omega, 1.3 * m.margin)
    assert abs(ctl.characteristic_value(np.array([root]), 1.3 * m.margin)[0]) < 1e-12

    def w0(x: np.ndarray) -> np.ndarray:
        return np.array([np.sin(np.pi * x) + 0.3, np.cos(2 * x), 1 + x**2, x])

    sim = simulate_nplusm(plant, ctl, 1.3 * m.margin, 40.0, w0, cells=60)
    np.testing.assert_allclose(sim.growth_rate(20.0), root.real, rtol=0.06)


def test_full_cancellation_margin_is_zero_when_gamma_0_reaches_one() -> None:
    """``2 rho q >= 1``: the cancellation of the reflection is not delay-robust (the paper, Section 5)."""
    plant = Hyperbolic2x2(1.0, 1.5, 0.5, 0.4, 1.0, 0.6)
    ctl = NPlusMBackstepping.for_system(NPlusMSystem.from_2x2(plant), 21)
    m = backstepping_delay_margin(ctl, 10.0, points=64)
    assert m.margin == 0.0 and m.gamma_0 == pytest.approx(1.2)


def test_characteristic_value_is_the_loop_determinant() -> None:
    ctl = NPlusMBackstepping(solve_nplusm_kernels(TWO_TWO, 21))
    s = np.array([0.1 + 2j, 1.0 - 3j])
    m0, m1 = ctl.loop_matrices(s)
    np.testing.assert_allclose(
        ctl.characteristic_value(s, 0.3), np.linalg.det(m0 + np.exp(-0.3 * s)[:, None, None] * m1), rtol=1e-12
    )
    with pytest.raises(ParameterError, match="one actuator"):
        ctl.factors(s)
    a, b = NPlusMBackstepping(solve_nplusm_kernels(TWO_ONE, 21)).factors(s)
    assert a.shape == b.shape == s.shape


def test_bad_input_is_refused() -> None:
    with pytest.raises(ParameterError, match="kernel_grid"):
        solve_nplusm_kernels(TWO_ONE, 2)
    with pytest.raises(ParameterError, match="kernel_grid"):
        solve_nplusm_kernels(NPlusMSystem([1.0], [1.0], [[0.0, 30.0], [30.0, 0.0]], [[1.0]], [[0.5]]), 21)
    with pytest.raises(ParameterError, match="system"):
        solve_nplusm_kernels(PLANT, 21)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="kernels"):
        NPlusMBackstepping(PLANT)  # type: ignore[arg-type]
    ctl = NPlusMBackstepping.for_system(TWO_ONE, 21)
    with pytest.raises(ParameterError, match="omega_max"):
        backstepping_delay_margin(ctl, 0.0)
    with pytest.raises(ParameterError, match="max_points"):
        backstepping_delay_margin(ctl, 10.0, points=100, max_points=50)
    with pytest.raises(ParameterError, match="grids"):
        ctl.functional([np.linspace(0, 1, 5)])
    with pytest.raises(ParameterError, match="triangle"):
        ctl.kernels.K_at(0.5, 0.7)


def test_results_are_json_ready() -> None:
    ctl = NPlusMBackstepping.for_system(TWO_ONE, 21)
    json.dumps(ctl.to_dict(), allow_nan=False)
    json.dumps(backstepping_delay_margin(ctl, 5.0, points=32).to_dict(), allow_nan=False)
    assert "N=21" in repr(ctl)
