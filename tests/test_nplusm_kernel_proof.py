"""The proven bound of the grid kernels' error in ``G`` and in the cascade loop's ``E T`` (n + m systems).

Independent checks: kernels in closed form (constant kernels; a piecewise-exponential ``G``
written here from the kernel equations), the loop ``E T`` of that ``G`` by mpmath quadrature
at 40 digits, and the order-2 extrapolation of the grid's ``G`` on a coupled plant.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_nplusm_unequal_speeds import G_01, ONE_COUPLING, UNEQUAL, S

from nrobust.errors import ParameterError
from nrobust.hyperbolic.nplusm import (
    KernelErrorBound,
    NPlusMBackstepping,
    NPlusMSystem,
    kernel_error_bound,
    solve_nplusm_kernels,
)

pytest.importorskip("flint")
mpmath = pytest.importorskip("mpmath")

#: ``Sigma-+ = 0`` and ``(Sigma--)_10 = 0``: ``K = 0``, ``L_00 = L_10 = L_11 = 0``, and ``L_01`` obeys
#: ``dL_01/dx = (s11 - s00) L_01 / mu_0`` along ``dxi/dx = mu_1 / mu_0``, from the diagonal value
#: ``l = s01 / (mu_1 - mu_0)`` (feet on the diagonal for ``x <= x* = (mu_1 - mu_0) / mu_1`` at ``xi = 0``) or from
#: the artificial value ``l`` on ``x = 1``: ``G_01(x) = mu_1 l e^{-(s11 - s00) x / (mu_1 - mu_0)}`` for ``x <= x*``,
#: ``mu_1 l e^{-(s11 - s00) (1 - x) / mu_0}`` after (continuous at ``x*``, a kink there).
CLOSED = NPlusMSystem(
    [1.5], [1.0, 2.0], [[0.3, 0.6, 0.4], [0.0, 0.2, 0.9], [0.0, 0.0, -0.5]], [[0.7, 0.28]], [[0.42], [0.14]]
)
#: ``UNEQUAL`` with ``(Sigma--)_10 = 0.3``: the corner values of ``L_10`` agree (no jump), all entries coupled.
SMOOTH = NPlusMSystem(
    [1.5], [1.0, 2.0], [[0.0, 0.6, 0.4], [0.2, 0.0, 0.8], [1.0, 0.3, 0.0]], [[0.7, 0.28]], [[0.42], [0.14]]
)


def closed_g(x: np.ndarray | float, mp: bool = False) -> np.ndarray | float:
    mu0, mu1 = CLOSED.mu
    s00, s01, s11 = CLOSED.sigma[1, 1], CLOSED.sigma[1, 2], CLOSED.sigma[2, 2]
    ell, xs = s01 / (mu1 - mu0), (mu1 - mu0) / mu1
    if mp:
        rate = (s11 - s00) * (x / (mu1 - mu0) if x <= xs else (1 - x) / mu0)
        return mu1 * ell * mpmath.exp(-rate)
    x = np.asarray(x, dtype=float)
    return mu1 * ell * np.exp(-(s11 - s00) * np.where(x <= xs, x / (mu1 - mu0), (1 - x) / mu0))


def test_constant_kernels_are_bounded_at_rounding() -> None:
    """``ONE_COUPLING``: the grid is exact, the bound of order ``N`` times the unit roundoff (measured
    ``g_error`` 5e-12 on 41 points, ``transition_error`` 1.8e-12)."""
    for N in (13, 41):
        ker = solve_nplusm_kernels(ONE_COUPLING, N)
        b = kernel_error_bound(ker)
        assert isinstance(b, KernelErrorBound) and b.kernel_grid == N
        assert b.g_error[0, 1] < 1e-10 and b.transition_error < 1e-10
        assert b.g_error[1, 0] == 0.0  # mu_0 < mu_1: G_10 = 0 exactly, not used by the loop
        np.testing.assert_allclose(ker.G[0, 1], G_01, rtol=0, atol=b.g_error[0, 1])


@pytest.mark.parametrize("N", [21, 41, 81])
def test_the_bound_contains_the_closed_form_g_and_its_loop(N: int) -> None:
    """``CLOSED``: ``|G_h - G|`` at the nodes and midpoints (``G_h`` linear between nodes) lies below the
    proven bound, and ``E T`` of the closed-form ``G`` (mpmath quadrature at 40 digits, split at the kink
    ``x*``) within ``transition_error`` of the grid's at points of ``Re s >= 0``. Measured: errors of
    ``G`` 4.7e-4, 1.2e-4, 3.0e-5 (order 2) against ``g_error`` 3.6 (a supremum: the kink of ``L_01`` along
    its own characteristic through ``(1, 1)`` is smeared over a cell at ``xi = 0``); the loop's bound, an
    integral, decreases: 0.092, 0.047, 0.023."""
    ker = solve_nplusm_kernels(CLOSED, N)
    b = kernel_error_bound(ker)
    x = np.linspace(0.0, 1.0, 4 * (N - 1) + 1)
    true = np.abs(np.interp(x, ker.grid, ker.G[0, 1]) - closed_g(x))
    assert true.max() <= b.g_error[0, 1]
    assert true.max() > 1e-7  # a real error is being bounded
    ctl = NPlusMBackstepping(ker)
    mu0, mu1 = CLOSED.mu
    s00, s11 = CLOSED.sigma[1, 1], CLOSED.sigma[2, 2]
    xs = (mu1 - mu0) / mu1
    with mpmath.workdps(40):
        for s in [0.0, 0.3 + 2j, 5j, 1.0 - 40j]:
            z = mpmath.mpc(s)

            def f(t: mpmath.mpf, z: mpmath.mpc = z) -> mpmath.mpc:
                return mpmath.exp(t * (s00 - z) / mu0) * closed_g(t, mp=True) / mu0

            integral = mpmath.quad(f, [0, xs, 1])
            v = [mpmath.exp(-s00 / mu0), mpmath.exp(-s11 / mu1)]
            exact = np.array([[complex(v[0]), complex(-v[0] * integral)], [0.0, complex(v[1])]])
            got = ctl.target_transition(np.array([s]))[0]
            assert np.linalg.norm(got - exact, 2) <= b.transition_error


def test_the_bound_contains_the_extrapolated_g_of_a_coupled_plant() -> None:
    """``SMOOTH`` (every entry coupled, no jump): ``G_01`` on 161 and 321 points extrapolated at order 2
    (observed ratio of successive differences 4.0 +- 0.3 on 81, 161, 321) is within the 41-point bound."""
    gs = {N: solve_nplusm_kernels(SMOOTH, N).G[0, 1] for N in (41, 81, 161, 321)}
    on41 = {N: g[:: (N - 1) // 40] for N, g in gs.items()}
    d1, d2 = np.abs(on41[161] - on41[81]).max(), np.abs(on41[321] - on41[161]).max()
    np.testing.assert_allclose(d1 / d2, 4.0, atol=0.3)  # order 2: the extrapolation below is valid
    reference = on41[321] + (on41[321] - on41[161]) / 3.0
    b = kernel_error_bound(solve_nplusm_kernels(SMOOTH, 41))
    assert np.abs(on41[41] - reference).max() <= b.g_error[0, 1]


@pytest.mark.parametrize("system", [SMOOTH, pytest.param(UNEQUAL, marks=pytest.mark.slow)])
def test_the_loop_bound_contains_the_extrapolated_loop(system: NPlusMSystem) -> None:
    """``E T`` on 41 points against ``E T`` of 161 and 321 points extrapolated at order 2 (the ``G`` route
    converges at order 2, ``tests/test_nplusm_unequal_speeds.py``), on the axis up to ``w = 60`` and on
    ``Re s = 0.5``. Measured: true 6.4e-5 (``SMOOTH``) and 5.9e-5 (``UNEQUAL``: ``L_10`` jumps across the
    characteristic from the origin), bound 0.024 and 0.029; the 161-321 difference 3e-6 makes the
    extrapolated reference good to about 1e-6, far below the bound's margin."""
    s = np.concatenate([1j * np.linspace(0.0, 60.0, 61), 0.5 + 1j * np.linspace(-20.0, 20.0, 9)])
    ets = {N: NPlusMBackstepping.for_system(system, N).target_transition(s) for N in (41, 161, 321)}
    reference = ets[321] + (ets[321] - ets[161]) / 3.0
    b = kernel_error_bound(solve_nplusm_kernels(system, 41))
    true = np.linalg.norm(ets[41] - reference, 2, axis=(1, 2))
    assert true.max() <= b.transition_error
    assert true.max() > 1e-5


#: ``mu = (1, 1, 2)``: a group of two equal speeds (``D`` with an off-diagonal coupling, entries of equal slopes
#: coupled along shared characteristics), ``n = 2``, random couplings (seeded).
_RNG = np.random.default_rng(3)
GROUPS = NPlusMSystem(
    [1.3, 0.8],
    [1.0, 1.0, 2.0],
    _RNG.uniform(-0.6, 0.6, (5, 5)),
    _RNG.uniform(-0.5, 0.5, (2, 3)),
    _RNG.uniform(-0.5, 0.5, (3, 2)),
)


@pytest.mark.slow
def test_a_group_of_equal_speeds_is_bounded_at_first_order() -> None:
    """``GROUPS``: ``transition_error`` 0.176 and 0.044 on 21 and 81 points (order 1.0), above the true errors
    3.2e-5 and 2.0e-6 against ``E T`` of 81 and 161 points extrapolated at order 2."""
    s = np.concatenate([1j * np.linspace(0.0, 40.0, 41), 0.3 + 1j * np.linspace(-10.0, 10.0, 5)])
    ets = {N: NPlusMBackstepping.for_system(GROUPS, N).target_transition(s) for N in (21, 81, 161)}
    reference = ets[161] + (ets[161] - ets[81]) / 3.0
    eps = []
    for N in (21, 81):
        eps.append(kernel_error_bound(solve_nplusm_kernels(GROUPS, N)).transition_error)
        assert np.linalg.norm(ets[N] - reference, 2, axis=(1, 2)).max() <= eps[-1]
    np.testing.assert_allclose(np.log(eps[0] / eps[1]) / np.log(4.0), 1.0, atol=0.1)


def test_the_loop_bound_is_first_order() -> None:
    """``CLOSED``: ``transition_error`` 0.0465, 0.0234, 0.0117 on 41, 81, 161 points (the residual of the
    one-step Picard image of the piecewise-linear kernels, module notes), while ``g_error`` (a supremum:
    the kink of ``L_01`` smeared over one cell at ``xi = 0``) stays near 3.6."""
    eps = [kernel_error_bound(solve_nplusm_kernels(CLOSED, N)).transition_error for N in (41, 81, 161)]
    np.testing.assert_allclose(np.log2(np.array(eps[:-1]) / np.array(eps[1:])), 1.0, atol=0.1)


def test_one_group_of_equal_speeds_and_bad_input() -> None:
    """Equal speeds ``mu = (1, 1)``: ``G = 0`` exactly (loop bound 0) and the kernels' bound is finite with a
    coupling of 1 inside the group (integrated along the shared characteristics); with 5 it overflows
    to ``inf`` (no information, still a valid bound)."""
    for coupling, finite in ((1.0, True), (5.0, False)):
        sigma = [[0, 0.5, 0.5], [0.5, 0, coupling], [0.5, coupling, 0]]
        group = NPlusMSystem([1.5], [1.0, 1.0], sigma, [[0.5, 0.5]], [[0.3], [0.2]])
        b = kernel_error_bound(solve_nplusm_kernels(group, 41))
        assert b.transition_error < 1e-300 and not np.any(np.isnan(b.kernel_error))
        assert np.all(np.isfinite(b.kernel_error)) == finite
    with pytest.raises(ParameterError, match="kernels"):
        kernel_error_bound(ONE_COUPLING)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="pieces"):
        kernel_error_bound(solve_nplusm_kernels(ONE_COUPLING, 13), pieces=0)


def test_uses_the_points_of_the_loop() -> None:
    """The bound moves ``E T`` on the points ``S`` of the loop tests by at most ``transition_error``."""
    b = kernel_error_bound(solve_nplusm_kernels(ONE_COUPLING, 13))
    exact = np.array([[[1.0, -G_01 * (1 - np.exp(-z)) / z], [0.0, 1.0]] for z in S])
    got = NPlusMBackstepping.for_system(ONE_COUPLING, 13).target_transition(S)
    assert np.all(np.linalg.norm(got - exact, 2, axis=(1, 2)) <= b.transition_error)


def test_the_divisors_of_the_bound_are_rounded_down() -> None:
    """Speeds ``mu_0``, ``mu_1`` 2.8e-8 apart: ``r = |1 - mu_1 / mu_0|`` in floating point is 3.1e-9 above its
    exact value (the ratio rounded, then a cancellation), beyond any allowance for rounding; the bound divides
    by the exact rates, slope gaps and slopes rounded down (mpmath, 40 digits), and compares slopes exactly."""
    from nrobust.hyperbolic.nplusm.kernel_error import _slope_gaps

    mu0, mu1 = 2.0924042183036358, 2.092404276281823
    close = NPlusMSystem([1.5], [mu0, mu1], [[0, 0.5, 0.5], [0.5, 0, 0.2], [0.5, 0.1, 0]], [[0.5, 0.5]], [[0.3], [0.2]])
    same, gaps, rates, moduli = _slope_gaps(close)
    with mpmath.workdps(40):
        lam, mu = [mpmath.mpf(1.5)], [mpmath.mpf(mu0), mpmath.mpf(mu1)]
        slopes = [(-lam[b] if b < 1 else mu[b - 1]) / mu[a] for a in range(2) for b in range(3)]
        for e, x in enumerate(slopes):
            assert rates[e] <= abs(1 - x) <= rates[e] * (1 + 1e-15) + 1e-300
            assert moduli[e] <= abs(x) <= moduli[e] * (1 + 1e-15)
            for f, y in enumerate(slopes):
                assert gaps[e, f] <= abs(x - y) <= gaps[e, f] * (1 + 1e-15) + 1e-300
                assert same[e, f] == (x == y)
        # L_01 (e = 2): the floating-point rate exceeds the exact one
        assert abs(1.0 - mu1 / mu0) > abs(1 - slopes[2]) * (1 + 1e-9)
