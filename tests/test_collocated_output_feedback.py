"""Output feedback from ``u(t, 1)`` (the collocated observer): its loop against independent routes.

Oracles, none of which uses :mod:`nrobust.hyperbolic.loops.collocated`:

* a transport plant: the observer is ``u^(t, 1) = q (rho y(t - tau) + U_o(t - tau))`` by the method
  of characteristics, so the loop is a closed form, evaluated with mpmath at 40 digits;
* the observer's gains: the Goursat problem of Vazquez, Krstic and Coron for the first column
  ``P^{uu}, P^{vu}`` (on ``x <= xi``), solved here by least squares on a Legendre basis of total
  degree 10 (constant couplings: analytic kernels; residual below 1e-12), ``p = -lam P(., 1)``;
* the loop in the Laplace domain: the plant and the observer (with those gains) as ODEs in
  ``x``, the 2x2 matrix exponential in closed form, variation of constants with 48-point
  Gauss-Legendre rules (analytic integrands: about 1e-13). Double precision suffices: the
  compared quantity errs by the package's kernel grid (measured 2.2e-9 to 1.1e-8 at the points
  below), four orders above the oracle's error;
* a simulation of the PDE, the observer (with those gains) and the controller on the
  characteristic lattice: the observer's error vanishes after ``tau``, and the norm grows at the
  spectral abscissa of the loop.
"""

from __future__ import annotations

from functools import lru_cache

import mpmath
import numpy as np
import pytest
from numpy.polynomial import legendre

import nrobust as nr
from nrobust.errors import ParameterError
from nrobust.hyperbolic.kernels.constant import solve_kernels
from nrobust.hyperbolic.loops.collocated import dual_plant
from nrobust.hyperbolic.loops.collocated import observer_gains as gains_of_dual
from nrobust.hyperbolic.loops.controllers import (
    CollocatedOutputFeedback,
    FilteredController,
    FiniteTimeController,
    OutputFeedback,
    ReflectionController,
    StateFeedback,
    characteristic,
    collocated_observer_of,
    loop_factors,
    loop_route,
    loop_scope,
    normalize,
)
from nrobust.roots import spectral_abscissa

PAPER = nr.Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
#: Unequal speeds (the pieces of the command response end at 1/lam = 0.5 and 1/mu = 2).
SLOW_V = nr.Hyperbolic2x2(2.0, 0.5, 0.2, 0.3, 0.8, 0.6)
TRANSPORT = nr.TransportSystem(1.0, 2.0, 0.9, 0.6)
#: A law with explicit gains, so that the Laplace-domain oracle needs no controller kernels.
LAW = StateFeedback(-0.3, g_v=lambda x: -0.2 * x)
POINTS = (0.3 + 2.0j, -0.1 + 6.2j, 0.05 + 0.7j, 0.2 + 15.0j)


@lru_cache(maxsize=4)
def goursat_column(lam, mu, s_pm, s_mp, q, degree=10, m=40):
    """``(P^{uu}, P^{vu})`` of the observer's Goursat problem by least squares (module notes).

    ``lam (P^{uu}_x + P^{uu}_xi) = s_pm P^{vu}``, ``mu P^{vu}_x - lam P^{vu}_xi = -s_mp P^{uu}``,
    ``P^{vu}(x, x) = -s_mp / (lam + mu)``, ``P^{uu}(0, xi) = q P^{vu}(0, xi)``.
    """
    index = [(i, j) for i in range(degree + 1) for j in range(degree + 1 - i)]

    def basis(x, xi, dx=0, dxi=0):
        cols = []
        for i, j in index:
            ci, cj = np.eye(i + 1)[i], np.eye(j + 1)[j]
            ci = legendre.legder(ci) * 2 if dx else ci
            cj = legendre.legder(cj) * 2 if dxi else cj
            cols.append(legendre.legval(2 * x - 1, ci) * legendre.legval(2 * xi - 1, cj))
        return np.array(cols).T

    g = np.linspace(0.0, 1.0, m)
    X, XI = np.meshgrid(g, g, indexing="ij")
    x, xi = X[X <= XI], XI[X <= XI]
    B0, Bx, Bxi = basis(x, xi), basis(x, xi, 1), basis(x, xi, 0, 1)
    d = np.linspace(0.0, 1.0, 4 * m)
    Bd, B0d = basis(d, d), basis(np.zeros_like(d), d)
    rows = np.vstack(
        [
            np.hstack([lam * (Bx + Bxi), -s_pm * B0]),
            np.hstack([s_mp * B0, mu * Bx - lam * Bxi]),
            np.hstack([np.zeros_like(Bd), Bd]),
            np.hstack([B0d, -q * B0d]),
        ]
    )
    rhs = np.concatenate([np.zeros(2 * x.size), np.full(d.size, -s_mp / (lam + mu)), np.zeros(d.size)])
    coef = np.linalg.lstsq(rows, rhs, rcond=None)[0]
    assert np.max(np.abs(rows @ coef - rhs)) < 1e-11
    n = len(index)
    return lambda x: (basis(x, np.ones_like(x)) @ coef[:n], basis(x, np.ones_like(x)) @ coef[n:])


def observer_gains(plant):
    """``(p_u, p_v)`` as functions: ``-lam P^{uu}(., 1)``, ``-lam P^{vu}(., 1)``."""
    column = goursat_column(plant.lam, plant.mu, plant.sigma_pm, plant.sigma_mp, plant.q)

    def gains(x):
        uu, vu = column(x)
        return -plant.lam * uu, -plant.lam * vu

    return gains


def expm2(M):
    """``exp`` of 2x2 matrices ``M[..., 2, 2]``: ``e^m (cosh D I + sinh(D)/D (M - m I))``."""
    m = 0.5 * (M[..., 0, 0] + M[..., 1, 1])
    N = M - m[..., None, None] * np.eye(2)
    D = np.sqrt(N[..., 0, 0] ** 2 + N[..., 0, 1] * N[..., 1, 0] + 0j)
    small = np.abs(D) < 1e-8
    sinhc = np.where(small, 1.0 + D**2 / 6, np.sinh(D) / np.where(small, 1.0, D))
    return np.exp(m)[..., None, None] * (np.cosh(D)[..., None, None] * np.eye(2) + sinhc[..., None, None] * N)


def laplace_loop(plant, k, g_u, g_v, s, deltas, observer_delay=0.0, nodes=48, kappa=0.0):
    """``F(s; delta)`` of the law ``U = k u(1) + int g_u u + g_v v`` on the collocated observer.

    Plant: ``[u; v]' = M [u; v]``, ``[u; v](0) = [q; 1]``; ``D = e^{-s/mu} (v(1) - rho u(1))`` (the
    open loop), ``L = e^{-s/mu} (k u(1) + int g . [u; v])`` (the law through the plant). Observer
    with ``y = 0`` and ``U_o = 1``: ``[u^; v^]' = M [u^; v^] + c [-p_u/lam; p_v/mu]``,
    ``u^(1) = c``, ``v^(1) = kappa c + 1`` (the observer's own reflection ``kappa``: ``v^(t, 1) =
    (rho - kappa) y + kappa u^(t, 1) + U_o``), ``c`` from ``u^(0) = q v^(0)``;
    ``C_u = k c + int g . [u^; v^]``. Separation: ``F = E (D (1 - C_u e^{-delta_o s}) - (L - D C_u)
    e^{-delta s})`` with the error's characteristic function ``E = 1 - kappa c_0`` (``c_0``: ``c``
    at ``kappa = 0``, the output error driven by the command mismatch; ``E = 1`` at ``kappa = 0``).
    """
    lam, mu, q, rho = plant.lam, plant.mu, plant.q, plant.rho
    gains = observer_gains(plant)
    z, w = legendre.leggauss(nodes)
    x, w = 0.5 * (z + 1), 0.5 * w
    M = np.array([[-s / lam, plant.sigma_pm / lam], [-plant.sigma_mp / mu, s / mu]])
    phi = expm2(M * x[:, None, None]) @ np.array([q, 1.0])
    end = expm2(M) @ np.array([q, 1.0])
    D = np.exp(-s / mu) * (end[1] - rho * end[0])
    L = np.exp(-s / mu) * (k * end[0] + w @ (g_u(x) * phi[:, 0] + g_v(x) * phi[:, 1]))
    at = np.concatenate([[0.0], x])
    y = at[:, None] + (1 - at)[:, None] * x[None, :]
    p_u, p_v = gains(y.ravel())
    r = np.stack([-p_u / lam, p_v / mu], axis=-1).reshape(*y.shape, 2)
    forced = -np.einsum(
        "ij,ijab,ijb->ia", (1 - at)[:, None] * w[None, :], expm2(M * (at[:, None] - y)[..., None, None]), r
    )
    free = expm2(M * (at - 1)[:, None, None])
    X0 = free[:, :, 1]
    E = 1.0
    if kappa:
        X1 = free[:, :, 0] + forced
        E = 1.0 - kappa * (-(X0[0, 0] - q * X0[0, 1]) / (X1[0, 0] - q * X1[0, 1]))
    X1 = free[:, :, 0] + kappa * free[:, :, 1] + forced
    c = -(X0[0, 0] - q * X0[0, 1]) / (X1[0, 0] - q * X1[0, 1])
    X = X0[1:] + c * X1[1:]
    C_u = k * c + w @ (g_u(x) * X[:, 0] + g_v(x) * X[:, 1])
    return np.array(
        [E * (D * (1 - C_u * np.exp(-observer_delay * s)) - (L - D * C_u) * np.exp(-d * s)) for d in deltas]
    )


def law_gains():
    return -0.3, (lambda x: 0.0 * x), (lambda x: -0.2 * x)


# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("inner", "K", "filt"),
    [
        (ReflectionController(0.2), 0.2, None),
        (FiniteTimeController(), 0.6, None),
        (FilteredController(0.05, 0.1, K=0.2), 0.2, (0.05, 0.1)),
    ],
    ids=["U_BS2", "U_BS", "filtered"],
)
@pytest.mark.parametrize("observer_delay", [0.0, 0.15])
def test_transport_loop_is_the_closed_form(inner, K, filt, observer_delay):
    """On a transport plant, ``u^(t, 1) = q (rho y(t - tau) + U_o(t - tau))`` and ``U_c = (n/d)(-K u^(t, 1))``.

    With ``z = e^{-tau s}``, the plant ``u(1) (1 - rho q z) = q z e^{-delta s} U_c``, the measurement
    ``y = u(1)`` and the controller ``d U_c = -n K q z (rho y + e^{-delta_o s} U_c)`` give
    ``F = (1 - rho q z)(d + n K q z e^{-delta_o s}) + n K rho q^2 z^2 e^{-delta s}``.
    """
    mpmath.mp.dps = 40
    q, rho, tau = mpmath.mpf(TRANSPORT.q), mpmath.mpf(TRANSPORT.rho), mpmath.mpf(1) + mpmath.mpf(1) / 2
    A, B = loop_factors(TRANSPORT, CollocatedOutputFeedback(inner, observer_delay))
    for s in POINTS:
        S = mpmath.mpc(s.real, s.imag)
        z = mpmath.exp(-tau * S)
        n, d = (1, 1) if filt is None else (1 + filt[0] * S, 1 + filt[1] * S)
        for delta in (0.0, 0.1, 0.7):
            exact = (1 - rho * q * z) * (
                d + n * K * q * z * mpmath.exp(-observer_delay * S)
            ) + n * K * rho * q**2 * z**2 * mpmath.exp(-delta * S)
            mine = A(s) + B(s) * np.exp(-delta * s)
            np.testing.assert_allclose(mine, complex(exact), rtol=0, atol=1e-13 * max(1.0, abs(s)))


def test_transport_route_and_scope():
    controller = CollocatedOutputFeedback(ReflectionController(0.2))
    assert loop_route(TRANSPORT, controller) == "exact"
    assert "the collocated observer is exact" in loop_scope(
        TRANSPORT, controller, None, loop_factors(TRANSPORT, controller)
    )
    gains = CollocatedOutputFeedback(StateFeedback(-0.1, g_u=0.2))
    assert loop_route(TRANSPORT, gains) == "observer"
    # |A(i w)| >= 1 - 0.36 - 0.0972 > 0.0972 = |B(i w)|: robust to every delay, proven
    certificate = nr.certify(TRANSPORT, controller, delta_max=0.5)
    assert certificate.delay_robust and certificate.margin.margin == np.inf


@pytest.mark.parametrize("plant", [pytest.param(PAPER, marks=pytest.mark.long), SLOW_V], ids=["paper", "slow_v"])
def test_observer_gains_solve_the_goursat_problem(plant):
    """The dual plant's finite-time kernels give the gains of the Goursat problem (measured 3.4e-9)."""
    grid, p_u, p_v = gains_of_dual(solve_kernels(dual_plant(plant)), plant.lam)
    expected_u, expected_v = observer_gains(plant)(grid)
    # the kernels on 201 points (extrapolated) err by about 1e-9 (docs/numerics_kernels.md)
    np.testing.assert_allclose(p_u, expected_u, rtol=0, atol=2e-8)
    np.testing.assert_allclose(p_v, expected_v, rtol=0, atol=2e-8)
    observer = collocated_observer_of(SLOW_V, CollocatedOutputFeedback(LAW))
    if plant is SLOW_V:
        np.testing.assert_array_equal(observer.p_u, p_u)


@pytest.mark.parametrize(
    ("plant", "observer_delay", "atol"),
    [(SLOW_V, 0.0, 1e-7), (SLOW_V, 0.1, 1e-7), (TRANSPORT, 0.1, 1e-13)],
    ids=["coupled", "observer delay", "transport"],
)
def test_loop_is_the_laplace_domain_loop(plant, observer_delay, atol):
    """``A_o + B_o e^{-delta s}`` against the Laplace-domain plant and observer.

    Measured at most 1.1e-8 on the coupled plant (the kernel grid), 1.2e-15 on the transport plant
    (no kernel: the command response's pieces are the gains themselves).
    """
    k, g_u, g_v = law_gains()
    A, B = loop_factors(plant, CollocatedOutputFeedback(LAW, observer_delay))
    deltas = (0.0, 0.25, 0.6)
    for s in POINTS:
        mine = np.array([A(s) + B(s) * np.exp(-d * s) for d in deltas])
        expected = laplace_loop(plant, k, g_u, g_v, s, deltas, observer_delay)
        np.testing.assert_allclose(mine, expected, rtol=0, atol=atol)


def test_delay_free_loop_is_the_target_system():
    """At ``delta = delta_o = 0`` the observer is exact: U_BS2(K)'s target ``1 - (rho - K) q e^{-tau s}``."""
    controller = CollocatedOutputFeedback(ReflectionController(0.1))
    F = characteristic(PAPER, controller, 0.0)
    s = np.array(POINTS)
    np.testing.assert_allclose(F(s), 1 - 0.75 * np.exp(-2.0 * s), rtol=0, atol=1e-12)
    # the error term itself is not zero: only its delay-free combination cancels
    G = collocated_observer_of(PAPER, controller).product
    assert np.min(np.abs(G(s))) > 1e-2
    np.testing.assert_allclose(spectral_abscissa(F).value, np.log(0.75) / 2.0, rtol=0, atol=1e-9)


def test_difference_operator_is_not_the_state_feedbacks():
    """Principal part ``1 - (rho - K) q z - K rho q^2 z^2 + K rho q^2 z^2 e^{-delta s}`` (``z = e^{-tau s}``)."""
    A, B = loop_factors(PAPER, CollocatedOutputFeedback(ReflectionController(0.1)))
    a, b = A.principal_part(), B.principal_part()
    np.testing.assert_allclose(a.coefs, [1.0, -0.75, -0.085], rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.delays, [0.0, 2.0, 4.0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(b.coefs, [0.085], rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.delays, [4.0], rtol=0, atol=1e-15)
    # U_BS on |rho q| = 0.6: gamma_0 = 2 (rho q)^2 = 0.72 < 1 (the state feedback's 1.2 is not)
    plant = nr.TransportSystem(1.0, 1.0, 1.0, 0.6)
    margin = nr.delay_margin(plant, CollocatedOutputFeedback(FiniteTimeController()))
    assert margin.strongly_stable and margin.nominally_stable
    assert not nr.delay_margin(plant, FiniteTimeController()).strongly_stable
    # an observer that assumes a delay does not merge the terms at tau: 0.85 + 0.1 + 2 * 0.085 > 1
    A, B = loop_factors(
        nr.TransportSystem(1.0, 1.0, 1.0, 0.85), CollocatedOutputFeedback(ReflectionController(0.1), 0.05)
    )
    np.testing.assert_allclose((A + B.shift(0.3)).principal_part().gamma_0, 1.12, rtol=1e-12)


def test_margin_is_a_zero_of_the_laplace_domain_loop():
    """The margin of the total delay ``delta_a + delta_m`` is a crossing of the independent loop."""
    controller = CollocatedOutputFeedback(LAW)
    margin = nr.delay_margin(SLOW_V, controller)
    state = nr.delay_margin(SLOW_V, LAW)
    assert margin.nominally_stable and margin.strongly_stable and margin.of_model
    # here the observer lengthens the margin (8.37 against the state feedback's 7.46)
    assert state.nominally_stable and 0.0 < state.margin < margin.margin < np.inf
    k, g_u, g_v = law_gains()
    s = 1j * margin.omega
    (value,) = laplace_loop(SLOW_V, k, g_u, g_v, s, (margin.margin,))
    np.testing.assert_allclose(abs(value), 0.0, atol=1e-7)  # measured 3.4e-9


def test_scope_json_and_bad_input():
    controller = CollocatedOutputFeedback(ReflectionController(0.1), observer_delay=0.05)
    assert loop_route(PAPER, controller) == "observer"
    scope = loop_scope(PAPER, controller, None, loop_factors(PAPER, controller))
    assert scope.startswith("a model of the PDE") and "not part of the proof" in scope
    assert controller.to_dict() == {
        "controller": "CollocatedOutputFeedback",
        "state_feedback": {"controller": "ReflectionController", "K": 0.1},
        "observer_delay": 0.05,
    }
    with pytest.raises(ParameterError, match="controller"):
        CollocatedOutputFeedback(OutputFeedback(ReflectionController(0.1)))
    with pytest.raises(ParameterError, match="controller"):
        CollocatedOutputFeedback("U_BS2")
    with pytest.raises(ParameterError, match="observer_delay"):
        CollocatedOutputFeedback(ReflectionController(0.1), observer_delay=-0.1)
    with pytest.raises(ParameterError, match="state feedback"):
        controller.feedback_law(PAPER)
    general = nr.GeneralHyperbolic2x2(lam=1.0, mu=1.0, a=0.0, b=0.5, c=0.5, d=0.0, q=0.5, rho=0.5)
    with pytest.raises(ParameterError, match="Hyperbolic2x2"):
        loop_factors(general, CollocatedOutputFeedback(ReflectionController(0.1)))


# --------------------------------------------------------------------------------------------- simulation


def simulate_loop(plant, law, gains, delay, observer_delay, t_end, cells=100, kappa=0.0):
    """The PDE, the collocated observer and ``law`` on its estimate, on the characteristic lattice.

    ``lam = mu = 1``, ``dt = dx = h``: ``u`` reaches node ``i`` from ``i - 1``, ``v`` from ``i + 1``,
    so the nodes with ``i + n`` even form a closed lattice (the other half would be a second,
    uncontrolled copy); the boundaries are on it at even steps. Couplings and output injection by
    Heun's rule along the characteristics; at odd steps, where ``x = 1`` is off the lattice, the
    output error ``y - u^(t, 1)`` is extrapolated from the last two even steps. The plant receives
    the command ``delay`` late, the observer replays it ``observer_delay`` late (multiples of
    ``2 h``; with 0 the observer's step is affine in the command of the same step and the law closes
    that algebraic loop exactly). The observer keeps the reflection ``kappa``: ``v^(t, 1) =
    (rho - kappa) y + kappa u^(t, 1) + U_o``. Returns the even times, ``||(u, v)||_{L^2}`` and
    ``||(u - u^, v - v^)||_{L^2}``.
    """
    N, h = cells, 1.0 / cells
    assert N % 2 == 0
    x = np.linspace(0.0, 1.0, N + 1)
    s_pm, s_mp, q, rho = plant.sigma_pm, plant.sigma_mp, plant.q, plant.rho
    p_u, p_v = gains(x)
    k, g_u, g_v = law.boundary_gain, law.gain_u(x), law.gain_v(x)
    even = np.arange(0, N + 1, 2)
    wt = np.full(even.size, 2 * h)
    wt[[0, -1]] *= 0.5
    lag, observer_lag = round(delay / (2 * h)), round(observer_delay / (2 * h))
    assert lag >= 1 and abs(delay - 2 * h * lag) < 1e-12 and abs(observer_delay - 2 * h * observer_lag) < 1e-12
    u, v = np.sin(np.pi * x), x * (1 - x)
    uh, vh = np.zeros_like(x), np.zeros_like(x)
    history = [0.0] * (lag + 1)
    e_hist = [0.0, 0.0]  # output errors y - u^(1) at the last two even steps

    def law_of(a, b):
        return k * a[-1] + wt @ (g_u[even] * a[even] + g_v[even] * b[even])

    def step(u, v, n, src, end):
        """From step n to n + 1 on the new parity; ``src(a, b, idx, new)``, ``end(u_N)`` = v(t, 1)."""
        new = np.arange((n + 1) % 2, N + 1, 2)
        ui, vi = new[new >= 1], new[new <= N - 1]
        su_old, sv_old = src(u, v, ui - 1, False)[0], src(u, v, vi + 1, False)[1]
        up, vp = u.copy(), v.copy()
        up[ui] = u[ui - 1] + h * su_old
        vp[vi] = v[vi + 1] + h * sv_old
        if (n + 1) % 2 == 0:
            vp[N] = end(up[N], up, vp)
            up[0] = q * vp[0]
        un, vn = u.copy(), v.copy()
        un[ui] = u[ui - 1] + 0.5 * h * (su_old + src(up, vp, ui, True)[0])
        vn[vi] = v[vi + 1] + 0.5 * h * (sv_old + src(up, vp, vi, True)[1])
        if (n + 1) % 2 == 0:
            vn[N] = end(un[N], un, vn)
            un[0] = q * vn[0]
        return un, vn

    def plant_src(a, b, idx, new):
        return s_pm * b[idx], s_mp * a[idx]

    times, norms, errors = [], [], []
    for n in range(round(t_end / h)):
        even_new = (n + 1) % 2 == 0
        applied = history[-lag]
        u, v = step(u, v, n, plant_src, lambda end, a, b, c=applied: rho * end + c)
        y_new = u[N] if even_new else None
        e_old = e_hist[-1] if n % 2 == 0 else 1.5 * e_hist[-1] - 0.5 * e_hist[-2]
        e_pred = None if even_new else 1.5 * e_hist[-1] - 0.5 * e_hist[-2]

        def observe(command, e_old=e_old, e_pred=e_pred, y_new=y_new, uh=uh, vh=vh, n=n):
            def src(a, b, idx, new):
                e = (y_new - a[N] if e_pred is None else e_pred) if new else e_old
                return s_pm * b[idx] + p_u[idx] * e, s_mp * a[idx] + p_v[idx] * e

            return step(uh, vh, n, src, lambda end, a, b: (rho - kappa) * y_new + kappa * end + command)

        if not even_new:
            uh, vh = observe(0.0)
        elif observer_lag:
            uh, vh = observe(history[-observer_lag])
            history.append(law_of(uh, vh))
        else:
            free, unit = observe(0.0), observe(1.0)
            c0 = law_of(*free)
            command = c0 / (1.0 - (law_of(*unit) - c0))
            uh, vh = (f + command * (g - f) for f, g in zip(free, unit, strict=True))
            history.append(command)
        if even_new:
            e_hist.append(y_new - uh[N])
            times.append((n + 1) * h)
            norms.append(np.sqrt(wt @ (u[even] ** 2 + v[even] ** 2)))
            errors.append(np.sqrt(wt @ ((u - uh)[even] ** 2 + (v - vh)[even] ** 2)))
    return np.array(times), np.array(norms), np.array(errors)


@pytest.mark.long
def test_simulated_growth_rate_is_the_spectral_abscissa():
    """PDE + observer (independent gains) + U_BS2(0.1), delay 0.3: the L2 norm grows at the abscissa.

    The abscissa is ``0.0913`` (roots ``0.0913 + 3.12i``, ``0.0112 + 6.20i``, ...): the fit starts at
    ``t = 40``, when the second root's share has shrunk by ``e^{-3.2}``; measured ``0.0912``.
    """
    law = ReflectionController(0.1).feedback_law(PAPER, solve_kernels(PAPER))
    times, norms, _ = simulate_loop(PAPER, law, observer_gains(PAPER), 0.3, 0.0, 70.0)
    late = times > 40.0
    rate = np.polyfit(times[late], np.log(norms[late]), 1)[0]
    alpha = spectral_abscissa(characteristic(PAPER, CollocatedOutputFeedback(ReflectionController(0.1)), 0.3)).value
    np.testing.assert_allclose(rate, alpha, rtol=0, atol=2e-3)


def test_simulated_observer_error_vanishes_after_tau():
    """When the observer replays the commands with the plant's delay, its error is zero after ``tau = 2``."""
    law = ReflectionController(0.1).feedback_law(PAPER, solve_kernels(PAPER, 101))
    times, _, errors = simulate_loop(PAPER, law, observer_gains(PAPER), 0.02, 0.02, 4.0)
    assert errors[times < 1.0].max() > 0.3
    # measured at most 1.1e-4 after tau (the scheme's error)
    assert errors[times > 2.05].max() < 1e-3


@pytest.mark.long
def test_certificate_scope_names_the_observer_model():
    """A proven certificate of the collocated loop says what it is about: the observer's term is a model (with an
    observer delay; without it the loop is proven, ``test_collocated_proof.py``)."""
    controller = CollocatedOutputFeedback(ReflectionController(0.1), observer_delay=0.02)
    cert = nr.certify(PAPER, controller, delta_max=0.1, k_region=False, rigorous=True)
    assert "collocated observer's term" in cert.scope and "not part of the proof" in cert.scope
    assert "cubic spline of the kernels on the kernel grid" not in cert.scope


def test_a_state_feedback_in_an_observer_is_mapped_to_the_normal_form_of_a_general_plant() -> None:
    """``normalize`` maps the gains of a StateFeedback inside either output feedback as it maps a bare one.

    The collocated one was passed through unmapped: ``certify`` then read the physical gains as
    normal-form ones (spectral abscissa 0.28953 instead of 0.29438 on the plant below, k = -0.2).
    """
    general = nr.GeneralHyperbolic2x2(lam=2.0, mu=1.0, a=0.3, b=1.0, c=1.0, d=-0.2, q=0.8, rho=0.5)
    form = general.normal_form()
    want = StateFeedback(*form.feedback_to_normal(-0.2, 0.0, 0.0))
    assert want.k != -0.2
    for kind in (OutputFeedback, CollocatedOutputFeedback):
        plant, mapped = normalize(general, kind(StateFeedback(-0.2), observer_delay=0.05))
        assert plant == form.system and type(mapped) is kind
        assert mapped.controller == want and mapped.observer_delay == 0.05


@pytest.mark.long
def test_certify_of_a_collocated_state_feedback_on_a_general_plant_is_its_normal_forms() -> None:
    general = nr.GeneralHyperbolic2x2(lam=2.0, mu=1.0, a=0.3, b=1.0, c=1.0, d=-0.2, q=0.8, rho=0.5)
    mapped = StateFeedback(*general.normal_form().feedback_to_normal(-0.2, 0.0, 0.0))
    on_general = nr.certify(general, CollocatedOutputFeedback(StateFeedback(-0.2)), delta_max=0.05, k_region=False)
    A, B = loop_factors(general.normal_form().system, CollocatedOutputFeedback(mapped))
    np.testing.assert_allclose(on_general.abscissa.value, nr.spectral_abscissa(A + B).value, rtol=1e-9)
