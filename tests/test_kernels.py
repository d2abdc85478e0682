"""Backstepping kernels K (eqs. (24)-(29)) and inverse kernels L.

Independent checks: closed forms when one coupling vanishes, finite-difference residuals
of the kernel PDEs and of the inverse-kernel PDEs (derived from (30)-(31)
and the target system, not used by the solver), second-order convergence, and the
composition of the transformation with its inverse.
"""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from nrobust import Hyperbolic2x2, Kernels, ParameterError, TransportSystem, solve_kernels

# lam != mu, both slopes of the cross characteristics (mu/lam > 1 and < 1), varying couplings.
VARYING = [
    Hyperbolic2x2(1.0, 2.5, lambda x: 1.0 + 0.5 * np.sin(3.0 * x), lambda x: 2.0 * np.exp(-x), 0.7, 0.85),
    Hyperbolic2x2(2.0, 0.7, lambda x: np.cos(2.0 * x), lambda x: 1.0 + x**2, -1.3, 0.5),
]


def observed_orders(errors: list[float]) -> np.ndarray:
    e = np.asarray(errors)
    return np.log2(e[:-1] / e[1:])


def lower(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mask and coordinates of the lower triangle of the n-point grid."""
    x = np.linspace(0.0, 1.0, n)
    X, XI = np.meshgrid(x, x, indexing="ij")
    return XI <= X, X, XI


# --------------------------------------------------------------------------- closed forms
def closed_form_no_sigma_mp(lam, mu, spm, q, X, XI):
    """sigma_mp = 0, constant sigma_pm: K^{vu} = K^{vv} = 0 and, with z = x - xi,
    K^{uv} = spm/(lam+mu) exp(-spm mu z / (lam q (lam+mu))), K^{uu} = mu/(lam q) K^{uv};
    the resolvent of these convolution kernels is constant:
    L^{aa} = mu spm / (lam q (lam+mu)), L^{ab} = spm/(lam+mu), L^{ba} = L^{bb} = 0."""
    kuv = spm / (lam + mu) * np.exp(-spm * mu * (X - XI) / (lam * q * (lam + mu)))
    zero = np.zeros_like(X)
    K = np.array([[mu / (lam * q) * kuv, kuv], [zero, zero]])
    L = np.array([[zero + mu * spm / (lam * q * (lam + mu)), zero + spm / (lam + mu)], [zero, zero]])
    return K, L


def closed_form_no_sigma_pm(lam, mu, smp, q, X, XI):
    """sigma_pm = 0, constant sigma_mp: K^{uu} = K^{uv} = 0 and
    K^{vu} = -smp/(lam+mu) exp(lam q smp z / (mu (lam+mu))), K^{vv} = (lam q / mu) K^{vu};
    L^{ba} = -smp/(lam+mu), L^{bb} = -lam q smp / (mu (lam+mu)), L^{aa} = L^{ab} = 0."""
    kvu = -smp / (lam + mu) * np.exp(lam * q * smp * (X - XI) / (mu * (lam + mu)))
    zero = np.zeros_like(X)
    K = np.array([[zero, zero], [kvu, lam * q / mu * kvu]])
    L = np.array([[zero, zero], [zero - smp / (lam + mu), zero - lam * q * smp / (mu * (lam + mu))]])
    return K, L


@pytest.mark.parametrize("lam, mu, q", [(1.0, 2.5, 0.7), (2.0, 0.7, -1.3), (1.0, 1.0, 1.0)])
@pytest.mark.parametrize("which", ["no_sigma_mp", "no_sigma_pm"])
def test_closed_forms_second_order(lam, mu, q, which):
    errors_K, errors_L = [], []
    for n in (51, 101, 201):
        if which == "no_sigma_mp":
            system = Hyperbolic2x2(lam, mu, 1.3, 0.0, q, 0.85)
        else:
            system = Hyperbolic2x2(lam, mu, 0.0, 1.3, q, 0.85)
        kernels = solve_kernels(system, kernel_grid=n, extrapolate=False)
        tri, X, XI = lower(n)
        form = closed_form_no_sigma_mp if which == "no_sigma_mp" else closed_form_no_sigma_pm
        K_exact, L_exact = form(lam, mu, 1.3, q, X, XI)
        errors_K.append(np.abs(kernels.K - K_exact)[:, :, tri].max())
        errors_L.append(np.abs(kernels.L - L_exact)[:, :, tri].max())
    assert errors_K[-1] < 1e-4 and errors_L[-1] < 5e-4
    for errors in (errors_K, errors_L):
        if errors[-1] > 1e-12:  # exactly solved cases (e.g. zero kernels) have no order
            assert np.all(observed_orders(errors) >= 1.8), errors


def test_extrapolated_closed_form_is_more_accurate():
    system = Hyperbolic2x2(1.0, 2.5, 1.3, 0.0, 0.7, 0.85)
    tri, X, XI = lower(201)
    K_exact, L_exact = closed_form_no_sigma_mp(1.0, 2.5, 1.3, 0.7, X, XI)
    plain = solve_kernels(system, kernel_grid=201, extrapolate=False)
    extrapolated = solve_kernels(system, kernel_grid=201)
    assert "Richardson" in extrapolated.method
    for exact, name in ((K_exact, "K"), (L_exact, "L")):
        e_plain = np.abs(getattr(plain, name) - exact)[:, :, tri].max()
        e_extra = np.abs(getattr(extrapolated, name) - exact)[:, :, tri].max()
        assert e_extra < e_plain / 5


# --------------------------------------------------------------------------- convergence
@pytest.mark.parametrize("system", VARYING)
@pytest.mark.parametrize("extrapolate", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_second_order_convergence_varying_couplings(system, extrapolate):
    """Observed order from differences of successive grids 51, 101, 201, 401 (>= 1.8)."""
    grids = [solve_kernels(system, kernel_grid=n, extrapolate=extrapolate) for n in (51, 101, 201, 401)]
    for name in ("K", "L"):
        diffs = [
            np.abs(getattr(coarse, name) - getattr(fine, name)[:, :, ::2, ::2]).max()
            for coarse, fine in itertools.pairwise(grids)
        ]
        orders = observed_orders(diffs)
        assert np.all(orders >= 1.8), (name, diffs, orders)
    if extrapolate:
        assert np.abs(grids[-2].K - grids[-1].K[:, :, ::2, ::2]).max() < 2e-5


# --------------------------------------------------------------------------- residuals
def _stencil(k: Kernels):
    """Interior nodes ``(i, j)`` of the triangle and central differences in x and xi there."""
    n, h = k.n, k.h
    i, j = np.nonzero(np.tri(n, n, -1, dtype=bool))
    keep = (j >= 1) & (i <= n - 2)
    i, j = i[keep], j[keep]

    def dx(F):
        return (F[i + 1, j] - F[i - 1, j]) / (2 * h)

    def dxi(F):
        return (F[i, j + 1] - F[i, j - 1]) / (2 * h)

    return i, j, dx, dxi


def k_residuals(k: Kernels) -> np.ndarray:
    """Max over interior nodes of the residuals of (24)-(27) (central differences)."""
    s = k.system
    lam, mu = s.lam, s.mu
    i, j, dx, dxi = _stencil(k)
    xi = k.grid[j]

    Kuu, Kuv, Kvu, Kvv = k.K[0, 0], k.K[0, 1], k.K[1, 0], k.K[1, 1]
    pm, mp = s.sigma_pm_at(xi), s.sigma_mp_at(xi)
    return np.array(
        [
            np.abs(lam * (dx(Kuu) + dxi(Kuu)) + Kuv[i, j] * mp).max(),
            np.abs(lam * dx(Kuv) - mu * dxi(Kuv) + Kuu[i, j] * pm).max(),
            np.abs(mu * dx(Kvu) - lam * dxi(Kvu) - Kvv[i, j] * mp).max(),
            np.abs(mu * (dx(Kvv) + dxi(Kvv)) - Kvu[i, j] * pm).max(),
        ]
    )


def l_residuals(k: Kernels) -> np.ndarray:
    """Residuals of the inverse-kernel PDEs, derived from (30)-(31)::

    lam (L^{aa}_x + L^{aa}_xi) = sigma_pm(x) L^{ba},   lam L^{ab}_x - mu L^{ab}_xi = sigma_pm(x) L^{bb},
    mu L^{ba}_x - lam L^{ba}_xi = -sigma_mp(x) L^{aa},  mu (L^{bb}_x + L^{bb}_xi) = -sigma_mp(x) L^{ab}.
    """
    s = k.system
    lam, mu = s.lam, s.mu
    i, j, dx, dxi = _stencil(k)
    x = k.grid[i]

    Laa, Lab, Lba, Lbb = k.L[0, 0], k.L[0, 1], k.L[1, 0], k.L[1, 1]
    pm, mp = s.sigma_pm_at(x), s.sigma_mp_at(x)
    return np.array(
        [
            np.abs(lam * (dx(Laa) + dxi(Laa)) - pm * Lba[i, j]).max(),
            np.abs(lam * dx(Lab) - mu * dxi(Lab) - pm * Lbb[i, j]).max(),
            np.abs(mu * dx(Lba) - lam * dxi(Lba) + mp * Laa[i, j]).max(),
            np.abs(mu * (dx(Lbb) + dxi(Lbb)) + mp * Lab[i, j]).max(),
        ]
    )


@pytest.mark.parametrize("system", VARYING)
def test_pde_residuals_vanish_at_second_order(system):
    coarse, fine = solve_kernels(system, kernel_grid=101), solve_kernels(system, kernel_grid=201)
    for residuals in (k_residuals, l_residuals):
        r_coarse, r_fine = residuals(coarse), residuals(fine)
        assert np.all(r_fine < 2e-3), r_fine
        assert np.all(np.log2(r_coarse / r_fine) >= 1.8), (r_coarse, r_fine)


@pytest.mark.parametrize("system", VARYING)
def test_boundary_conditions(system):
    k = solve_kernels(system, kernel_grid=101)
    lam, mu, q = system.lam, system.mu, system.q
    x = k.grid
    d = np.arange(k.n)
    np.testing.assert_allclose(k.K[0, 1, d, d], system.sigma_pm_at(x) / (lam + mu), rtol=0, atol=1e-14)
    np.testing.assert_allclose(k.K[1, 0, d, d], -system.sigma_mp_at(x) / (lam + mu), rtol=0, atol=1e-14)
    np.testing.assert_allclose(k.K[0, 1, :, 0], lam * q / mu * k.K[0, 0, :, 0], rtol=0, atol=1e-13)
    np.testing.assert_allclose(k.K[1, 1, :, 0], lam * q / mu * k.K[1, 0, :, 0], rtol=0, atol=1e-13)
    # Inverse kernels: L^{ab}(x, x) = sigma_pm/(lam+mu), L^{ba}(x, x) = -sigma_mp/(lam+mu),
    # L^{ab}(x, 0) = (lam q/mu) L^{aa}(x, 0), L^{bb}(x, 0) = (lam q/mu) L^{ba}(x, 0).
    # To rounding, not O(h^2): L_kk = K_kk, and the column ratio at xi = 0 passes through the
    # linear trapezoidal resolvent L = K + K o L and the Richardson step (measured 1.3e-15).
    np.testing.assert_allclose(k.L[0, 1, d, d], system.sigma_pm_at(x) / (lam + mu), rtol=0, atol=1e-14)
    np.testing.assert_allclose(k.L[1, 0, d, d], -system.sigma_mp_at(x) / (lam + mu), rtol=0, atol=1e-14)
    np.testing.assert_allclose(k.L[0, 1, :, 0], lam * q / mu * k.L[0, 0, :, 0], rtol=0, atol=1e-13)
    np.testing.assert_allclose(k.L[1, 1, :, 0], lam * q / mu * k.L[1, 0, :, 0], rtol=0, atol=1e-13)


# --------------------------------------------------------------------------- inverse
def transform(k: Kernels, table: np.ndarray, state: np.ndarray, sign: float) -> np.ndarray:
    """``state + sign int_0^x table(x, xi) state(xi) dxi`` with the trapezoidal rule on the grid."""
    n, h = k.n, k.h
    w = np.tril(np.full((n, n), h))
    w[:, 0] *= 0.5
    w[np.arange(n), np.arange(n)] *= 0.5
    w[0, 0] = 0.0
    integral = np.einsum("abij,ij,bj->ai", table, w, state)
    return state + sign * integral


@pytest.mark.parametrize("system", VARYING)
def test_inverse_transform_recovers_state(system):
    errors = []
    for n in (101, 201):
        k = solve_kernels(system, kernel_grid=n)
        x = k.grid
        state = np.array([np.sin(2.0 * x) + 1.0, np.cos(3.0 * x) - x])
        alpha_beta = transform(k, k.K, state, -1.0)  # (22)-(23)
        recovered = transform(k, k.L, alpha_beta, +1.0)  # (30)-(31)
        errors.append(np.abs(recovered - state).max())
    assert errors[-1] < 1e-4
    assert observed_orders(errors)[0] >= 1.8, errors


# --------------------------------------------------------------------------- evaluation
def test_evaluation_at_arbitrary_points():
    system = Hyperbolic2x2(2.0, 0.7, 1.3, 0.0, -1.3, 0.5)
    k = solve_kernels(system, kernel_grid=201)
    rng = np.random.default_rng(0)
    x = rng.uniform(0.0, 1.0, 500)
    xi = x * rng.uniform(0.0, 1.0, 500)
    x, xi = np.append(x, [1.0, 1.0, 0.0, 0.3]), np.append(xi, [1.0, 0.0, 0.0, 0.3])
    K_exact, L_exact = closed_form_no_sigma_mp(2.0, 0.7, 1.3, -1.3, x, xi)
    assert np.abs(k.Kuu(x, xi) - K_exact[0, 0]).max() < 1e-5
    assert np.abs(k.Kuv(x, xi) - K_exact[0, 1]).max() < 1e-5
    assert np.abs(k.Laa(x, xi) - L_exact[0, 0]).max() < 1e-5
    assert np.abs(k.Lab(x, xi) - L_exact[0, 1]).max() < 1e-5
    np.testing.assert_array_equal(k.Kvu(x, xi), 0.0)
    # grid nodes reproduce the table; shapes broadcast
    assert k.Kvv(k.grid[5], k.grid[3]) == k.K[1, 1, 5, 3]
    assert k.Lba(np.ones((2, 3)), 0.5).shape == (2, 3)
    assert np.isfinite(k.Lbb(1.0, 1.0))


@pytest.mark.parametrize("x, xi", [(0.5, 0.6), (1.2, 0.1), (0.5, -0.1), (np.nan, 0.0)])
def test_evaluation_outside_triangle_raises(x, xi):
    k = solve_kernels(TransportSystem(1.0, 1.0, 1.0, 0.5), kernel_grid=11)
    with pytest.raises(ParameterError):
        k.Kuu(x, xi)


def test_transport_kernels_vanish():
    k = solve_kernels(TransportSystem(1.0, 3.0, 2.0, 0.5), kernel_grid=21)
    assert not np.any(k.K) and not np.any(k.L)


def test_arguments_validated():
    system = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
    with pytest.raises(ParameterError):
        solve_kernels(system, kernel_grid=2)
    with pytest.raises(ParameterError):
        solve_kernels(system, kernel_grid=100, extrapolate=True)
    with pytest.raises(ParameterError):
        solve_kernels("not a system", kernel_grid=11)  # type: ignore[arg-type]
    assert "Richardson" not in solve_kernels(system, kernel_grid=100).method  # even n: plain scheme


def test_repr_and_to_dict():
    system = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
    k = solve_kernels(system, kernel_grid=21)
    assert repr(k).startswith("Kernels(system=Hyperbolic2x2(lam=1.0")
    data = json.loads(json.dumps(k.to_dict()))
    assert data["n"] == 21 and len(data["trace_x1"]["Kvu"]) == 21
    assert set(data["trace_x1"]) == {"Kuu", "Kuv", "Kvu", "Kvv", "Laa", "Lab", "Lba", "Lbb"}
