"""The proven margin bracket of the full-state law with unequal leftward speeds (``cascade_delay_margin``).

Independent checks, sharing no code with the bounds: the principal part written here from the
plant's entries (``n = 1``, no couplings but ``Sigma--_01``: ``U = 1``, ``V = I``), sampled
inverses against ``kappa``; the exact loop from the closed-form target of ``ONE_COUPLING``
(kernels in closed form, ``E T = [[1, -G_01 (1 - e^{-s}) / s], [0, 1]]``) and an mpmath matrix
exponential at 30 digits, against the remainder bound beyond ``W`` and against the claim that no
crossing exists.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from test_nplusm_unequal_speeds import ONE_COUPLING

from nrobust.errors import CertificationError, ParameterError
from nrobust.hyperbolic.nplusm import (
    NPlusMBackstepping,
    NPlusMSystem,
    backstepping_delay_margin,
    cascade_delay_margin,
    kernel_error_bound,
)
from nrobust.hyperbolic.nplusm import cascade_margin as cm
from nrobust.margins.matrix import GaugeRemainder

pytest.importorskip("flint")
mpmath = pytest.importorskip("mpmath")


def one_coupling(s01: float) -> NPlusMSystem:
    """``ONE_COUPLING`` with ``Sigma--_01 = s01``: ``G_01 = mu_1 s01 / (mu_1 - mu_0) = 2 s01``."""
    return NPlusMSystem(
        [1.5], [1.0, 2.0], [[0.0, 0.0, 0.0], [0.0, 0.0, s01], [0.0, 0.0, 0.0]], [[0.6, 0.4]], [[0.5], [0.3]]
    )


def principal(sys: NPlusMSystem, w: float, z: complex) -> np.ndarray:
    """``A_0 = I - (1 - z) sum_b P_b R Q e^{-i w (1/lam + 1/mu_b)}`` of these plants (``U = 1``, ``V = I``)."""
    rq = sys.r @ sys.q
    rows = [rq[b] * np.exp(-1j * w * (1.0 / sys.lam[0] + 1.0 / sys.mu[b])) for b in range(2)]
    return np.eye(2) - (1.0 - z) * np.array(rows)


def exact_a(sys: NPlusMSystem, w: float, z: complex) -> Any:
    """``(1 - z) M_0 + z E T`` at ``s = i w`` for exact kernels, mpmath (30 digits)."""
    with mpmath.workdps(30):
        s = mpmath.mpc(0, w)
        inv = [1 / mpmath.mpf(v) for v in sys.signed_speeds]
        a = mpmath.matrix(3, 3)
        for i in range(3):
            for k in range(3):
                a[i, k] = inv[i] * (mpmath.mpf(sys.sigma[i, k]) - (s if i == k else 0))
        phi = mpmath.expm(a) * mpmath.matrix([[sys.q[0, 0], sys.q[0, 1]], [1, 0], [0, 1]])
        m0 = mpmath.matrix(2, 2)
        for j in range(2):
            for c in range(2):
                m0[j, c] = mpmath.exp(-s / mpmath.mpf(sys.mu[j])) * (
                    phi[1 + j, c] - mpmath.mpf(sys.r[j, 0]) * phi[0, c]
                )
        g01 = 2 * mpmath.mpf(sys.sigma[1, 2])
        et = mpmath.matrix([[1, -g01 * (1 - mpmath.exp(-s)) / s], [0, 1]])
        return (1 - z) * m0 + z * et


def test_kappa_bounds_the_principal_inverse_at_sampled_points() -> None:
    """``kappa`` against ``||A_0^{-1}||`` at 4000 random ``(w, z)``, ``|z| <= 1``: the bound holds (measured
    max 3.96 for kappa 6.33: Frobenius norm and entrywise moduli make it loose by 1.6, never below)."""
    sys = one_coupling(1.5)
    kappa = cm._principal_inverse(sys)
    rng = np.random.default_rng(1)
    worst = 0.0
    for w, r, t in zip(rng.uniform(0, 60, 4000), np.sqrt(rng.uniform(0, 1, 4000)), rng.uniform(0, 2 * np.pi, 4000)):
        worst = max(worst, float(np.linalg.norm(np.linalg.inv(principal(sys, w, r * np.exp(1j * t))), 2)))
    assert worst <= kappa
    assert kappa < 2.0 * worst  # not vacuous: measured ratio 1.6


def test_the_remainder_beyond_w_bounds_the_exact_loop() -> None:
    """``ONE_COUPLING`` on 21 points: beyond ``W`` the exact ``A`` (closed-form kernels, mpmath) lies within
    the remainder of the module notes of ``A_0``, so ``kappa ||A - A_0|| < 1`` there, and ``sigma_min(A) > 0``."""
    ctl = NPlusMBackstepping.for_system(ONE_COUPLING, 21)
    loop = cm._CascadeLoop(ctl, kernel_error_bound(ctl.kernels))
    W = cm._frequency_bound(loop, 1e6)
    kappa = cm._principal_inverse(ONE_COUPLING)
    inv = 1.0 / ONE_COUPLING.signed_speeds
    gauge = GaugeRemainder(inv[:, None] * ONE_COUPLING.sigma, inv)
    for w in (W, 1.5 * W, 3.7 * W):
        bound = 2 * loop.left * loop.right * float(gauge(w)) + loop.decay / (w / loop.mu_max - loop.decay_shift)
        for t in np.linspace(0, 2 * np.pi, 7):
            z = complex(np.exp(1j * t))
            a = np.array(exact_a(ONE_COUPLING, w, z).tolist(), dtype=complex)
            assert np.linalg.norm(a - principal(ONE_COUPLING, w, z), 2) <= bound + loop.eps
            assert kappa * np.linalg.norm(a - principal(ONE_COUPLING, w, z), 2) < 1.0
            assert np.linalg.svd(a, compute_uv=False)[-1] > 0.0


def test_a_kernel_error_above_the_principal_room_is_refused() -> None:
    """A strong coupling on 21 points: ``kappa eps >= 1`` (or ``W`` beyond ``max_frequency``): refused, a finer
    grid advised."""
    sys = NPlusMSystem(
        [1.5], [1.0, 2.0], [[0.3, 0.6, 0.4], [0.0, 0.2, 0.9], [0.0, 0.0, -0.5]], [[0.7, 0.28]], [[0.42], [0.14]]
    )
    with pytest.raises(CertificationError, match="finer kernel_grid"):
        cascade_delay_margin(NPlusMBackstepping.for_system(sys, 21), max_frequency=100.0)


def test_bad_input() -> None:
    with pytest.raises(ParameterError, match="controller"):
        cascade_delay_margin(object())  # type: ignore[arg-type]
    equal = NPlusMSystem([1.5], [1.0, 1.0], np.zeros((3, 3)), [[0.6, 0.4]], [[0.5], [0.3]])
    with pytest.raises(ParameterError, match="leftward speeds"):
        cascade_delay_margin(NPlusMBackstepping.for_system(equal, 21))
    with pytest.raises(ParameterError, match="max_frequency"):
        cascade_delay_margin(NPlusMBackstepping.for_system(one_coupling(0.3), 21), max_frequency=-1.0)
    with pytest.raises(ParameterError, match="rigorous"):
        backstepping_delay_margin(NPlusMBackstepping.for_system(one_coupling(0.3), 21), rigorous=1)  # type: ignore[arg-type]


def test_the_exclusion_bounds_sigma_min_of_the_exact_loop() -> None:
    """``ONE_COUPLING`` on 21 points: at 40 random ``(w, phi)`` the search's lower bound lies below ``sigma_min`` of
    the exact loop (closed-form kernels, mpmath) and within twice its allowed error of it (the test can fail
    both ways: a bound that misses the kernels' error, or one so loose that it excludes nothing)."""
    ctl = NPlusMBackstepping.for_system(ONE_COUPLING, 21)
    loop = cm._CascadeLoop(ctl, kernel_error_bound(ctl.kernels))
    rng = np.random.default_rng(3)
    w, phi = rng.uniform(0.0, 40.0, 40), rng.uniform(0.0, 2 * np.pi, 40)
    m0, et = loop.enclose(w)
    lower, error = loop.exclusion(phi, m0, et - m0)
    exact = np.array(
        [
            np.linalg.svd(np.array(exact_a(ONE_COUPLING, float(a), complex(np.exp(1j * b))).tolist(), dtype=complex))[
                1
            ][-1]
            for a, b in zip(w, phi)
        ]
    )
    assert np.all(lower <= exact) and np.all(exact <= lower + 2.0 * error)


def grid_loop_mp(ctl: NPlusMBackstepping, w: float, z: complex) -> Any:
    """``(1 - z) M_0 + z E T_h`` at ``s = i w`` in mpmath (40 digits), written here for ``crossing_plant`` (``n = 1``,
    ``D = 0``: ``V = I``, ``e^{x C} = diag(e^{-s x / mu_a})``): ``M_0`` from mpmath's matrix exponential, ``E T_h``
    from ``G_h`` linear between the grid's own nodes ``x_k`` (the function ``kernel_error_bound`` compares with),
    integrated cell by cell in closed form."""
    sys = ctl.system
    with mpmath.workdps(40):
        s = mpmath.mpc(0, w)
        size = sys.n + sys.m
        a = mpmath.matrix(size, size)
        for i in range(size):
            for k in range(size):
                a[i, k] = (mpmath.mpf(sys.sigma[i, k]) - (s if i == k else 0)) / mpmath.mpf(sys.signed_speeds[i])
        phi = mpmath.expm(a) * mpmath.matrix([[sys.q[0, 0], sys.q[0, 1]], [1, 0], [0, 1]])
        m0 = mpmath.matrix(2, 2)
        et = mpmath.eye(2)
        x = [mpmath.mpf(v) for v in ctl.kernels.grid]
        for j in range(2):
            rate = -s / mpmath.mpf(sys.mu[j])
            for c in range(2):
                m0[j, c] = mpmath.exp(rate) * (phi[1 + j, c] - mpmath.mpf(sys.r[j, 0]) * phi[0, c])
                if sys.mu[c] > sys.mu[j]:
                    g = [mpmath.mpf(v) / mpmath.mpf(sys.mu[j]) for v in ctl.kernels.G[j, c]]
                    total = mpmath.mpc(0)
                    for k in range(len(x) - 1):  # e^{r t} ((g_k + b (t - x_k)) / r - b / r^2) from x_k to x_k+1
                        slope = (g[k + 1] - g[k]) / (x[k + 1] - x[k])
                        for t, sign in ((x[k + 1], 1), (x[k], -1)):
                            total += (
                                sign * mpmath.exp(rate * t) * ((g[k] + slope * (t - x[k])) / rate - slope / rate**2)
                            )
                    et[j, c] -= total
        return (1 - z) * m0 + z * et, m0, et


def test_the_enclosures_hold_the_grid_loop_in_mpmath() -> None:
    """``crossing_plant(0.5)`` on 21 points, 6 points ``(w, phi)``: the enclosures of ``M_0`` and ``E T_h`` hold the
    40-digit values (``E T_h`` within its radius plus the grid's rounding term of ``eps``), and the proven lower bound
    of ``sigma_min`` of the exact law's loop, plus the kernels' ``eps``, is below the 40-digit ``sigma_min`` of the
    grid loop and within 1e-9 of it (the radii are about 1e-13: the bound is sharp, not just safe)."""
    ctl = NPlusMBackstepping.for_system(crossing_plant(0.5), 21)
    bound = kernel_error_bound(ctl.kernels)
    loop = cm._CascadeLoop(ctl, bound)
    grid_term = loop.eps - bound.transition_error
    assert 0.0 < grid_term < 1e-14
    w = np.array([0.05, 1.3, 4.0, 7.7, 15.0, 20.5])
    phi = np.array([0.3, 2.0, 3.1, 4.4, 5.9, 1.0])
    m0, et = loop.enclose(w)
    lower, _ = loop.exclusion(phi, m0, et - m0)
    for k in range(w.size):
        z = complex(mpmath.exp(mpmath.mpc(0, phi[k])))
        a, m0_mp, et_mp = grid_loop_mp(ctl, float(w[k]), z)
        m0_ref = np.array(m0_mp.tolist(), dtype=complex)
        et_ref = np.array(et_mp.tolist(), dtype=complex)
        assert np.all(np.abs(m0_ref - m0.mid[k]) <= m0.rad[k])
        assert np.all(np.abs(et_ref - et.mid[k]) <= et.rad[k] + grid_term)
        with mpmath.workdps(40):
            sig = float(min(mpmath.svd_c(a, compute_uv=False)))
        assert lower[k] + bound.transition_error <= sig <= lower[k] + bound.transition_error + 1e-9


def test_the_scope_names_no_error_model() -> None:
    """The proven bracket's scope says the margin is proven for the PDE and names no floating-point error model
    (the former scope named ``EXPM_ROUNDING``)."""
    res = cascade_delay_margin(NPlusMBackstepping.for_system(one_coupling(0.3), 21), max_points=20_000)
    assert "proven for the PDE" in res.scope and "every floating-point step enclosed" in res.scope
    assert "error model" not in res.scope and "EXPM_ROUNDING" not in res.scope
    assert not hasattr(cm, "EXPM_ROUNDING") and not hasattr(cm._CascadeLoop, "matrix_rounding")


def test_no_crossing_is_proven_and_the_exact_loop_agrees() -> None:
    """``Sigma--_01 = 0.3`` on 21 points: no crossing at any frequency (margin inf, proven; 0.5 s of CPU, 40 s with the
    former search). Oracle: ``|det A|`` of the exact loop (closed-form kernels, mpmath) on a grid of ``(0, W] x |z| =
    1`` stays above 0.05 (measured min 0.17): a sampled consistency check of the proven claim."""
    sys = one_coupling(0.3)
    res = cascade_delay_margin(NPlusMBackstepping.for_system(sys, 21), max_points=20_000)
    assert res.certified and res.margin == np.inf and res.margin_bracket == (np.inf, np.inf) and not res.crossings
    smallest = min(
        abs(complex(mpmath.det(exact_a(sys, w, complex(np.exp(1j * t))))))
        for w in np.linspace(0.05, res.frequency_bound, 30)
        for t in np.linspace(0, 2 * np.pi, 12, endpoint=False)
    )
    assert smallest > 0.05


def crossing_plant(c: float) -> NPlusMSystem:
    """Couplings ``c`` between ``u`` and both ``v`` (open-loop unstable for ``c = 0.5``), ``Sigma--_01 = 0.3``."""
    return NPlusMSystem([1.5], [1.0, 2.0], [[0.0, c, c], [c, 0.0, 0.3], [c, 0.0, 0.0]], [[0.3, 0.4]], [[0.5], [0.3]])


def test_a_crossing_is_proven_and_the_kernel_route_converges_inside() -> None:
    """``crossing_plant(0.5)``: the proven brackets on 21 and 41 points (measured ``[1.4909, 1.6980]`` and
    ``[1.5222, 1.6249]``; ``[1.5381, 1.5884]`` on 81) hold the exact law's margin. Oracle: the other loop of the
    grid kernels (through the feedback integral ``J``, not ``G``: no shared evaluation) on 81 and 161 points,
    Richardson-extrapolated at its order 2 (differences measured 3.4e-5, 8.4e-6, 2.1e-6 on 41/81/161/321, ratio
    4.0): accurate to about 1e-6, far inside brackets 0.2 and 0.1 wide. The width is first order in the grid's
    step: halved from 21 to 41 points (measured ratio 0.496; 0.6 allowed). About 6 s of CPU."""
    sys = crossing_plant(0.5)
    coarse = cascade_delay_margin(NPlusMBackstepping.for_system(sys, 21))
    fine = backstepping_delay_margin(NPlusMBackstepping.for_system(sys, 41), rigorous=True)
    oracle = [
        backstepping_delay_margin(NPlusMBackstepping.for_system(sys, n), 30.0, route="integral").margin
        for n in (81, 161)
    ]
    exact = oracle[1] + (oracle[1] - oracle[0]) / 3.0
    # the crossing frequency alike: proven omega_bracket against the same oracle's frequencies, extrapolated
    loops = [NPlusMBackstepping.for_system(sys, n) for n in (81, 161)]
    omegas = [backstepping_delay_margin(loop, 30.0, route="integral").omega for loop in loops]
    exact_omega = omegas[1] + (omegas[1] - omegas[0]) / 3.0
    for res in (coarse, fine):
        lo, hi = res.margin_bracket
        assert res.certified and lo < exact < hi and lo <= res.margin <= hi
        assert len(res.crossings) == 1
        w_lo, w_hi = res.omega_bracket
        assert w_lo < exact_omega < w_hi and res.omega_accuracy is not None
        assert abs(res.omega - exact_omega) <= res.omega_accuracy < 1.0
        assert "accuracy not estimated" not in repr(res)
    width = [r.margin_bracket[1] - r.margin_bracket[0] for r in (coarse, fine)]
    assert width[1] < 0.6 * width[0] and width[1] < 0.12


def test_a_crossing_the_kernels_error_hides_is_refused() -> None:
    """``crossing_plant(1.0)`` on 21 points (``eps = 0.088``): the crossing is neither excluded nor proven in a box,
    refused with a finer grid advised."""
    with pytest.raises(CertificationError, match="finer kernel_grid"):
        cascade_delay_margin(NPlusMBackstepping.for_system(crossing_plant(1.0), 21))


def test_refusals_of_the_proof() -> None:
    """Refused, not guessed: the work bound (``max_points = 200``, the first grid has 175 frequencies) and a principal
    part whose entrywise bound ``rho(2 sum_t |V^{-1} R_t|)`` is 1.8 (``R = (2, 1)``), for which no uniform bound of
    ``A_0^{-1}`` is proven."""
    with pytest.raises(CertificationError, match="max_points"):
        cascade_delay_margin(NPlusMBackstepping.for_system(crossing_plant(0.5), 21), max_points=200)
    strong = NPlusMSystem(
        [1.5], [1.0, 2.0], [[0.0, 0.5, 0.5], [0.5, 0.0, 0.3], [0.5, 0.0, 0.0]], [[0.3, 0.4]], [[2.0], [1.0]]
    )
    with pytest.raises(CertificationError, match="not proven below 1"):
        cm._principal_inverse(strong)


def test_a_principal_part_beyond_one_gives_a_proven_zero_margin() -> None:
    """``R = (2, 1)``: the delayed principal part's ``gamma_0 = 2 sum_b |q_b r_b| = 2`` (closed form: ``V = I``,
    ``U = 1`` and ``R Q`` of rank one, so ``rho = |sum_b q_b r_b d_b|`` with ``|d_b| <= 2``), proven above 1 in
    balls: margin 0. ``R = (0.5, 0.3)`` (``gamma_0 = 0.54``) is not claimed above 1."""

    def plant(r: list[list[float]]) -> NPlusMSystem:
        return NPlusMSystem([1.5], [1.0, 2.0], [[0.0, 0.5, 0.5], [0.5, 0.0, 0.3], [0.5, 0.0, 0.0]], [[0.3, 0.4]], r)

    res = cascade_delay_margin(NPlusMBackstepping.for_system(plant([[2.0], [1.0]]), 21))
    assert res.certified and res.margin == 0.0 and res.margin_bracket == (0.0, 0.0)
    np.testing.assert_allclose(res.gamma_0, 2.0, rtol=1e-6)  # a sampled lower end: within 1e-6 of the sup
    assert cm._gamma_above_one(plant([[2.0], [1.0]])) and not cm._gamma_above_one(plant([[0.5], [0.3]]))
