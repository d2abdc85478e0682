"""n + m loops proven without a region, and the backstepping law's loop without kernels.

Oracles: mpmath's matrix exponential at 40 digits (written here, no code of nplusm), the
2x2 exact route (closed-form kernels, the core's proven abscissa of a quasi-polynomial), and
the kernel route of the backstepping law converging at its observed order 2.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from nrobust import spectral_abscissa
from nrobust.errors import ParameterError
from nrobust.hyperbolic.loops.exact_form import exact_form
from nrobust.hyperbolic.nplusm import (
    NPlusMBackstepping,
    NPlusMCharacteristic,
    NPlusMSystem,
    backstepping_delay_margin,
    backstepping_exact_margin,
    compound_characteristic,
)
from nrobust.hyperbolic.plants.hyperbolic2x2 import Hyperbolic2x2

flint = pytest.importorskip("flint")
mpmath = pytest.importorskip("mpmath")

PLANT = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
TWO_ONE = NPlusMSystem(
    [1.0, 2.0], [1.5], [[0.0, 0.3, 1.0], [0.2, 0.0, 0.5], [0.4, 0.1, 0.0]], [[1.0], [0.5]], [[0.4, 0.3]]
)
BS_PLANT = NPlusMSystem.from_2x2(Hyperbolic2x2(1.0, 1.5, 1.2, 0.8, 1.0, 0.4))


def mp_loop(system: NPlusMSystem, K: Any, z: Any, delay: Any = 0) -> Any:
    """The loop of one actuator: ``e^{-z/mu} [-(R + K e^{-delay z}), 1] expm(Lambda^{-1} (Sigma - z I)) [Q; 1]``."""
    n = system.n
    inv = [1 / mpmath.mpf(v) for v in system.lam] + [-1 / mpmath.mpf(system.mu[0])]
    a = mpmath.matrix(n + 1, n + 1)
    for i in range(n + 1):
        for k in range(n + 1):
            a[i, k] = inv[i] * (mpmath.mpf(system.sigma[i, k]) - (z if i == k else 0))
    g = mpmath.expm(a)
    w = [mpmath.mpf(v) for v in system.q[:, 0]] + [mpmath.mpf(1)]
    col = [mpmath.fsum(g[i, k] * w[k] for k in range(n + 1)) for i in range(n + 1)]
    ed = mpmath.exp(-delay * z)
    ell = [-(mpmath.mpf(system.r[0, i]) + mpmath.mpf(K[0][i]) * ed) for i in range(n)] + [mpmath.mpf(1)]
    return mpmath.exp(-z / mpmath.mpf(system.mu[0])) * mpmath.fsum(e * c for e, c in zip(ell, col))


@pytest.mark.parametrize(
    ("system", "K"),
    [pytest.param(NPlusMSystem.from_2x2(PLANT), [[-0.3]], marks=pytest.mark.slow), (TWO_ONE, [[-0.2, 0.1]])],
)
def test_proven_abscissa_without_a_region_against_mpmath(system: NPlusMSystem, K: Any) -> None:
    F = NPlusMCharacteristic(system, K)
    ab = F.proven_abscissa()
    assert ab.rigorous and ab.certified and ab.value_bracket is not None and ab.root_box is not None
    lo, hi = ab.value_bracket
    assert lo <= ab.value <= hi == ab.upper_bound
    mpmath.mp.dps = 40
    root = mpmath.findroot(lambda z: mp_loop(system, K, z), mpmath.mpc(ab.root))
    x0, x1, y0, y1 = ab.root_box
    # the 40-digit root lies in the proven box (its width, 1e-10, is the proof's tolerance)
    assert x0 <= float(root.real) <= x1 and y0 <= float(root.imag) <= y1
    assert abs(mp_loop(system, K, root)) < mpmath.mpf(10) ** -30


def test_proven_abscissa_against_the_2x2_exact_route() -> None:
    # the open loop of the paper's plant by the closed-form kernel N~ (no matrix exponential, no
    # nplusm code), proven by the core on the whole plane: the two proven brackets must overlap
    F = NPlusMCharacteristic(NPlusMSystem.from_2x2(PLANT))
    ours = F.proven_abscissa()
    oracle = spectral_abscissa(exact_form(PLANT).characteristic, rigorous=True)
    assert ours.value_bracket is not None and oracle.value_bracket is not None
    assert max(ours.value_bracket[0], oracle.value_bracket[0]) <= min(ours.value_bracket[1], oracle.value_bracket[1])
    np.testing.assert_allclose(ours.value, oracle.value, atol=1e-9)  # both brackets are ~2e-11 wide


def test_ball_far_field_is_sound_and_as_sharp_as_the_float_one() -> None:
    F = NPlusMCharacteristic(NPlusMSystem.from_2x2(PLANT))
    root = 0.92296280117  # the rightmost root, real (test above)
    # a far field claimed on {Re s >= 0.5, |s| >= 0.9} would exclude that root: never proven
    assert not F.ball_far_field_holds(0.5, 0.9)
    assert not F.far_field_holds(0.5, 0.9)
    R = F.far_field_radius(0.5)
    assert R is not None and R > root
    assert F.ball_far_field_holds(0.5, R * (1 + 1e-6))  # the ball bound is as tight as the float one
    assert F.proven_far_field_radius(0.5) == pytest.approx(R, rel=1e-3)
    # right of the chains only: the principal part's gap closes at the strong bound C_D = -0.081
    assert F.proven_far_field_radius(-0.2) is None


def test_kernel_free_loop_matches_the_kernel_route_at_order_two() -> None:
    # E (Phi_v - J) = exp(-Sigma--/mu) for the exact kernels: the grid kernels' M_1 converges to
    # V - M_0 at the scheme's order 2 (observed 1.99-2.00 for N = 21, 41, 81)
    s = np.array([0.3 + 2j, -0.5 + 7j, 3j])
    errors = []
    for N in (21, 41, 81):
        ctl = NPlusMBackstepping.for_system(BS_PLANT, kernel_grid=N)
        m0, m1 = ctl.loop_matrices(s)
        t0, t1 = ctl.target_loop_matrices(s)
        np.testing.assert_allclose(m0, t0, rtol=1e-13)
        errors.append(float(np.abs(m1 - t1).max()))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    np.testing.assert_allclose(orders, 2.0, atol=0.1)


def test_exact_backstepping_margin_is_certified_against_mpmath() -> None:
    exact = backstepping_exact_margin(BS_PLANT)
    assert exact.certified and exact.nominal_unstable == 0 and "exact kernels" in exact.scope
    # oracle: |A(i w)| = |V - A(i w)| at 40 digits (A the open loop by mpmath.expm), delay arg(-B/A) / w
    mpmath.mp.dps = 40
    v = mpmath.exp(-mpmath.mpf(BS_PLANT.sigma[1, 1]) / mpmath.mpf(BS_PLANT.mu[0]))

    def gap(w: Any) -> Any:
        a = mp_loop(BS_PLANT, [[0.0]], mpmath.mpc(0, w))
        return abs(a) - abs(v - a)

    assert exact.omega is not None and len(exact.crossings) == 1
    w = mpmath.findroot(gap, mpmath.mpf(exact.omega))
    a = mp_loop(BS_PLANT, [[0.0]], mpmath.mpc(0, w))
    delay = mpmath.fmod(mpmath.arg(-(v - a) / a) + 2 * mpmath.pi, 2 * mpmath.pi) / w
    np.testing.assert_allclose(exact.margin, float(delay), rtol=1e-10)
    np.testing.assert_allclose(exact.omega, float(w), rtol=1e-10)


@pytest.mark.slow
def test_kernel_route_margin_converges_to_the_exact_one_at_order_two() -> None:
    exact = backstepping_exact_margin(BS_PLANT)
    assert backstepping_delay_margin(NPlusMBackstepping.for_system(BS_PLANT, 21)) == exact
    errs = []
    for N in (21, 41, 81):  # observed orders 1.98, 1.99
        scan = backstepping_delay_margin(NPlusMBackstepping.for_system(BS_PLANT, N), 10.0, points=200)
        assert not scan.certified and "grid kernels" in scan.scope
        errs.append(abs(scan.margin - exact.margin))
    np.testing.assert_allclose(np.log2(np.array(errs[:-1]) / np.array(errs[1:])), 2.0, atol=0.1)


ONE_GROUP = NPlusMSystem(
    [1.0], [1.5, 1.5], [[0.0, 0.3, 0.2], [0.4, 0.0, 0.1], [0.2, 0.3, 0.0]], [[0.5, 0.2]], [[0.3], [0.1]]
)
TWO_GROUPS = NPlusMSystem(
    [1.0], [1.0, 2.0], [[0.0, 0.3, 0.2], [0.1, 0.0, 0.4], [0.5, 0.2, 0.0]], [[0.5, 0.2]], [[0.3], [0.1]]
)


@pytest.mark.slow
def test_two_actuators_of_one_speed() -> None:
    exact = backstepping_exact_margin(ONE_GROUP)
    assert exact.certified and exact.margin > 0
    # the grid kernels' scan finds the same first crossing to the kernel error (h^2 ~ 6e-4 at N = 41)
    ctl = NPlusMBackstepping.for_system(ONE_GROUP, 41)
    scan = backstepping_delay_margin(ctl, 2.0 * exact.frequency_bound, points=400)
    np.testing.assert_allclose(scan.margin, exact.margin, rtol=1e-3)


def test_the_kernel_free_route_refuses_speeds_that_differ() -> None:
    with pytest.raises(ParameterError, match="mu all equal"):
        backstepping_exact_margin(TWO_GROUPS)
    ctl = NPlusMBackstepping.for_system(TWO_GROUPS, 11)
    with pytest.raises(ParameterError, match="omega_max"):
        backstepping_delay_margin(ctl)
    with pytest.raises(ParameterError, match="mu all equal"):
        ctl.target_loop_matrices(np.array([1j]))


def test_compound_form_needs_no_region_either() -> None:
    # the same function as NPlusMCharacteristic (Cauchy-Binet): its far field is the loop's; the
    # oracle is the 2x2 exact route's open loop (closed-form kernel), both certified to < 1e-9
    ours = spectral_abscissa(compound_characteristic(NPlusMSystem.from_2x2(PLANT)))
    oracle = spectral_abscissa(exact_form(PLANT).characteristic)
    assert ours.certified and ours.accuracy is not None and ours.accuracy < 1e-9
    np.testing.assert_allclose(ours.value, oracle.value, atol=2e-9)


def test_core_spectral_abscissa_proves_an_n_plus_m_loop_without_a_region() -> None:
    """The core's rigorous abscissa takes the loop's own ball far field: the same bracket as proven_abscissa."""
    F = NPlusMCharacteristic(NPlusMSystem.from_2x2(PLANT))
    core = spectral_abscissa(F, rigorous=True)
    own = F.proven_abscissa()
    assert core.rigorous and core.certified and core.value_bracket is not None and own.value_bracket is not None
    assert max(core.value_bracket[0], own.value_bracket[0]) <= min(core.value_bracket[1], own.value_bracket[1])
