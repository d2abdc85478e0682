"""The full-state backstepping law of n + m systems with leftward speeds that differ: the loop through ``G``.

For the exact kernels ``E (Phi_v - J) = E T = V (I - int_0^1 e^{x C(s)} Lambda-^{-1} G(x) dx)``
(module notes of :mod:`nrobust.hyperbolic.nplusm.kernels`). Independent checks: the feedback
integral's route converging to the ``G`` route at the kernel scheme's order 2; a coupling
whose kernels and ``G`` are constant, written here in closed form from the kernel equations,
with its loop and roots by mpmath at 40 digits; the PDE simulated beyond and below the
margin; one speed, where the route is the certified kernel-free loop.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

# n = m = 2, mu = (1.5, 0.7): G_10 lives, D = diag(0.3, 0.1) != 0 and L_01 jumps across the characteristic
# from the origin
from test_nplusm_kernels import TWO_TWO

from nrobust.errors import ParameterError
from nrobust.hyperbolic.nplusm import (
    BACKSTEPPING_ROUTES,
    NPlusMBackstepping,
    NPlusMSystem,
    backstepping_delay_margin,
    backstepping_exact_margin,
)
from nrobust.hyperbolic.plants.hyperbolic2x2 import Hyperbolic2x2
from nrobust.hyperbolic.simulate import simulate_nplusm

mpmath = pytest.importorskip("mpmath")

#: ``mu = (1, 2)``: ``G_01`` lives (``mu_1 > mu_0``), the target is a cascade; ``gamma_0 = 0.667``.
UNEQUAL = NPlusMSystem(
    [1.5], [1.0, 2.0], [[0.0, 0.6, 0.4], [0.2, 0.0, 0.8], [1.0, 0.4, 0.0]], [[0.7, 0.28]], [[0.42], [0.14]]
)
#: One coupling ``Sigma--_01 = 1.5``: ``K = 0``, ``L_00 = L_10 = L_11 = 0`` and ``L_01 = 1.5 / (mu_1 - mu_0)``
#: solve the kernel equations (constant along every characteristic, the diagonal value everywhere,
#: which is also the artificial boundary value), so ``G_01 = mu_1 L_01 = 3`` and
#: ``E T = [[1, -3 (1 - e^{-s}) / s], [0, 1]]`` (``D = 0``, ``V = I``).
SIGMA_01 = 1.5
ONE_COUPLING = NPlusMSystem(
    [1.5], [1.0, 2.0], [[0.0, 0.0, 0.0], [0.0, 0.0, SIGMA_01], [0.0, 0.0, 0.0]], [[0.6, 0.4]], [[0.5], [0.3]]
)
G_01 = SIGMA_01 * 2.0 / (2.0 - 1.0)
BS_PLANT = NPlusMSystem.from_2x2(Hyperbolic2x2(1.0, 1.5, 1.2, 0.8, 1.0, 0.4))
S = np.array([0.3 + 2j, -0.5 + 7j, 3j, 20j])


def closed_form_target(s: Any) -> Any:
    """``E T`` of ``ONE_COUPLING`` (module constant's notes), in mpmath."""
    return mpmath.matrix([[1, -G_01 * (1 - mpmath.exp(-s)) / s], [0, 1]])


def mp_loop(s: Any, delay: Any) -> Any:
    """``det(M_0 + e^{-delay s} (E T - M_0))`` of ``ONE_COUPLING`` with ``M_0 = E (Phi_v - R Phi_u)`` by mpmath.expm."""
    sys = ONE_COUPLING
    inv = [1 / mpmath.mpf(v) for v in sys.signed_speeds]
    a = mpmath.matrix(3, 3)
    for i in range(3):
        for k in range(3):
            a[i, k] = inv[i] * (mpmath.mpf(sys.sigma[i, k]) - (s if i == k else 0))
    phi = mpmath.expm(a) * mpmath.matrix([[sys.q[0, 0], sys.q[0, 1]], [1, 0], [0, 1]])
    m0 = mpmath.matrix(2, 2)
    for j in range(2):
        for c in range(2):
            m0[j, c] = mpmath.exp(-s / mpmath.mpf(sys.mu[j])) * (phi[1 + j, c] - mpmath.mpf(sys.r[j, 0]) * phi[0, c])
    return mpmath.det(m0 + mpmath.exp(-delay * s) * (closed_form_target(s) - m0))


@pytest.mark.parametrize("system", [UNEQUAL, pytest.param(TWO_TWO, marks=pytest.mark.slow)])
def test_the_feedback_integral_route_converges_to_the_cascade_route_at_order_two(system: NPlusMSystem) -> None:
    """``M_1 = E (R Phi_u - J)`` against ``E T - M_0`` on 21, 41, 81 points. ``UNEQUAL``:
    differences 1.66e-3, 4.16e-4, 9.43e-5 (orders 2.00, 2.14; 2.07e-5 at 161, order 2.19), the
    ``G`` route moving by 1.83e-4, 4.58e-5 (order 2.00); ``G`` at the node ``x = 0`` of the
    entries ``mu_c < mu_a`` (the corner's jump, 0.1) is not used: the kernel equations make it 0.
    ``TWO_TWO``: 9.91e-3, 2.62e-3, 5.86e-4 (orders 1.92, 2.16), the ``G`` route 3.49e-4, 8.97e-5."""
    diffs, own, previous = [], [], None
    for N in (21, 41, 81):
        ctl = NPlusMBackstepping.for_system(system, N)
        m0, m1 = ctl.loop_matrices(S)
        c0, c1 = ctl.cascade_loop_matrices(S)
        np.testing.assert_array_equal(m0, c0)
        diffs.append(float(np.abs(m1 - c1).max()))
        if previous is not None:
            own.append(float(np.abs(c1 - previous).max()))
        previous = c1
    np.testing.assert_allclose(np.log2(np.array(diffs[:-1]) / np.array(diffs[1:])), 2.0, atol=0.25)
    np.testing.assert_allclose(np.log2(own[0] / own[1]), 2.0, atol=0.25)
    assert own[1] < 0.6 * diffs[2]  # the G route is the more accurate of the two on this grid


def test_the_target_transition_is_triangular_and_moves_by_the_uniform_bound() -> None:
    """``det(E T) = det V`` for every ``s`` (the delay-free loop has no root), and a change ``dG``
    moves ``E T`` by at most ``||V|| int ||e^{x Lambda-^{-1} D}|| ||Lambda-^{-1} dG||`` on ``Re s >= 0``."""
    ctl = NPlusMBackstepping.for_system(TWO_TWO, 21)
    d = np.diag(TWO_TWO.sigma[2:, 2:]) / TWO_TWO.mu  # D = diag(Sigma--): the speeds differ
    v = np.exp(-d)
    np.testing.assert_allclose(np.linalg.det(ctl.target_transition(S)), np.prod(v), rtol=1e-12)
    x = ctl.kernels.grid
    dg = np.zeros_like(ctl.kernels.G)
    dg[1, 0] = 0.05 * np.cos(7.0 * x) + 0.02  # on the entry mu_0 > mu_1 that the loop uses
    moved = NPlusMBackstepping(dataclasses.replace(ctl.kernels, G=ctl.kernels.G + dg))
    s = np.concatenate([1j * np.linspace(0.0, 60.0, 241), 2.0 + 1j * np.linspace(-30.0, 30.0, 61)])
    change = np.linalg.norm(moved.target_transition(s) - ctl.target_transition(s), ord=2, axis=(1, 2))
    # the change sits in entry (1, 0): the bound V_11 int e^{x d_1} |dG_10(x)| / mu_1 dx, dG linear between
    # nodes; the trapezoidal rule on 20 001 points is within 1e-8 of the integral (a kink per sign change)
    fine = np.linspace(0.0, 1.0, 20_001)
    integrand = np.exp(fine * d[1]) * np.abs(np.interp(fine, x, dg[1, 0])) / TWO_TWO.mu[1]
    bound = v[1] * float(np.trapezoid(integrand, fine))
    assert np.all(change <= bound * (1 + 1e-6))
    assert change.max() > 0.5 * bound  # attained near s = 0 (no oscillation there)


def test_one_coupling_has_a_constant_g_in_closed_form() -> None:
    """The grid reproduces the constant kernels exactly: ``G``, ``E T`` and ``J`` to rounding."""
    exact = np.array([[[1.0, -G_01 * (1 - np.exp(-z)) / z], [0.0, 1.0]] for z in S])
    for N in (13, 41):
        ctl = NPlusMBackstepping.for_system(ONE_COUPLING, N)
        np.testing.assert_allclose(ctl.kernels.G[0, 1], G_01, rtol=1e-13)
        np.testing.assert_allclose(ctl.target_transition(S), exact, rtol=0, atol=1e-13)
        m0, m1 = ctl.loop_matrices(S)  # constant kernels: the grid's J is exact too
        np.testing.assert_allclose(m0 + m1, exact, rtol=0, atol=1e-13)


def test_one_coupling_margin_and_the_root_beyond_it_against_mpmath() -> None:
    """The scan of the ``G`` route on ``(0, 5]`` finds the first delay 0.65488 at ``w = 4.5309``
    (the crossings below it come at larger delays); at 40 digits a root of the closed-form loop
    sits on the axis there, and followed to 1.3 times the margin it lies in ``Re s > 0``."""
    ctl = NPlusMBackstepping.for_system(ONE_COUPLING, 13)
    m = backstepping_delay_margin(ctl, 5.0, points=60, route="cascade")
    assert not m.certified and "target's G" in m.scope and m.omega is not None
    with mpmath.workdps(40):
        root = mpmath.findroot(lambda y: mp_loop(y, mpmath.mpf(m.margin)), mpmath.mpc(0, m.omega))
        z = root
        for delay in np.linspace(m.margin, 1.3 * m.margin, 4)[1:]:  # followed in three steps
            z = mpmath.findroot(lambda y, d=delay: mp_loop(y, mpmath.mpf(d)), z)
    # the scan's crossing: a bisection to 2^-48 of its bracket and an eigenvalue at rounding
    np.testing.assert_allclose([float(root.real), float(root.imag)], [0.0, m.omega], rtol=0, atol=1e-9)
    assert float(z.real) > 0.01  # measured 0.080826 + 4.23127i
    # the package's G loop vanishes at the 40-digit root (its double-precision evaluation)
    c0, c1 = ctl.cascade_loop_matrices(np.array([complex(z)]))
    value = np.linalg.det(c0 + np.exp(-1.3 * m.margin * complex(z)) * c1)[0]
    assert abs(value) < 1e-12


def test_one_speed_is_the_kernel_free_loop_and_its_certified_margin() -> None:
    ctl = NPlusMBackstepping.for_system(BS_PLANT, 11)
    for got, want in zip(ctl.cascade_loop_matrices(S), ctl.target_loop_matrices(S)):
        np.testing.assert_array_equal(got, want)
    exact = backstepping_exact_margin(BS_PLANT)
    assert exact.certified
    # every crossing of the exact loop lies below the proven frequency bound: the scan there finds the margin
    scan = backstepping_delay_margin(ctl, exact.frequency_bound, points=200, route="cascade")
    np.testing.assert_allclose(scan.margin, exact.margin, rtol=1e-10)


def test_simulation_decays_below_and_grows_beyond_the_cascade_margin() -> None:
    """``UNEQUAL`` (``lam = 1.5``: no ``u`` shares a speed with a ``v``, Notes of
    :class:`NPlusMBackstepping`), kernels on 41 points: margin 0.790477 at ``w = 0.94009``.
    At 1.3 times the margin the rightmost root of the ``G`` loop is 0.077944 + 0.81957i; the
    simulated growth rate is 0.078337 (40 cells) and 0.077868 (80 cells): 0.5 % and 0.1 %.
    At 0.7 times the margin the simulation decays at -0.148."""
    ctl = NPlusMBackstepping.for_system(UNEQUAL, 41)
    m = backstepping_delay_margin(ctl, 2.0, points=40, route="cascade")  # the one crossing below w = 5
    assert m.omega is not None and 0.0 < m.margin < np.inf
    delay = 1.3 * m.margin

    def loop(z: np.ndarray) -> np.ndarray:
        c0, c1 = ctl.cascade_loop_matrices(z)
        return np.asarray(np.linalg.det(c0 + np.exp(-delay * z)[:, None, None] * c1))

    root = 0.05 + 1j * m.omega
    for _ in range(12):  # Newton, central differences: converged in 5 steps
        f, up, down = loop(root + np.array([0.0, 1e-6, -1e-6]))
        root -= f / ((up - down) / 2e-6)
    assert abs(loop(np.array([root]))[0]) < 1e-12

    def w0(x: np.ndarray) -> np.ndarray:
        return np.array([np.sin(np.pi * x) + 0.3, np.cos(2 * x), 1 + x**2])

    beyond = simulate_nplusm(UNEQUAL, ctl, delay, 40.0, w0, cells=40)
    np.testing.assert_allclose(beyond.growth_rate(20.0), root.real, rtol=0.01)
    below = simulate_nplusm(UNEQUAL, ctl, 0.7 * m.margin, 40.0, w0, cells=40)
    assert below.growth_rate(20.0) < -0.1


@pytest.mark.long
def test_the_margins_of_both_routes_converge_to_one_another() -> None:  # 8 s of CPU
    """Margins on 21, 41, 81 points: J route 0.7906051, 0.7905086, 0.7904867; G route 0.7904728,
    0.7904772, 0.7904789; their gap 1.32e-4, 3.14e-5, 7.82e-6 (orders 2.07, 2.01)."""
    gaps = []
    for N in (21, 41, 81):
        ctl = NPlusMBackstepping.for_system(UNEQUAL, N)
        by = [backstepping_delay_margin(ctl, 5.0, points=100, route=r) for r in BACKSTEPPING_ROUTES]
        assert all(not b.certified for b in by) and by[0].scope != by[1].scope
        gaps.append(abs(by[0].margin - by[1].margin))
    np.testing.assert_allclose(np.log2(np.array(gaps[:-1]) / np.array(gaps[1:])), 2.0, atol=0.25)


def test_an_unknown_route_is_refused() -> None:
    ctl = NPlusMBackstepping.for_system(UNEQUAL, 11)
    with pytest.raises(ParameterError, match="route"):
        backstepping_delay_margin(ctl, 5.0, route="kernels")
    with pytest.raises(ParameterError, match="omega_max"):
        backstepping_delay_margin(ctl, route="cascade")  # several speeds: no certified margin
