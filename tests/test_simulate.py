"""Tests of the time-domain simulator (nrobust.hyperbolic.simulate.normal_form).

References used here are independent of the simulator: the method of characteristics in
closed form for transport loops, the exact target-system identity of U_BS2 (eq.
(53)), and the closed-loop characteristic function computed in the Laplace domain
with the matrix exponential of the plant (no delay form, no inverse kernels).
"""

from __future__ import annotations

import itertools
import json
import math
from dataclasses import FrozenInstanceError
from functools import cache

import numpy as np
import pytest

from nrobust import (
    FeedbackLaw,
    FilteredController,
    FiniteTimeController,
    OpenLoop,
    ParameterError,
    ReflectionController,
    Simulation,
    characteristic,
    simulate,
    spectral_abscissa,
)
from nrobust.hyperbolic.kernels.constant import solve_kernels
from nrobust.hyperbolic.nplusm import NPlusMSystem
from nrobust.hyperbolic.plants.hyperbolic2x2 import Hyperbolic2x2, TransportSystem
from nrobust.hyperbolic.simulate import SCHEMES, SimulationResult, simulate_nplusm
from nrobust.hyperbolic.simulate.normal_form import v_nodes

PAPER = Hyperbolic2x2(lam=1.0, mu=1.0, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)
PAPER_TRANSPORT = TransportSystem(lam=1.0, mu=1.0, q=1.0, rho=0.85)


def zero(xi):
    return np.zeros_like(np.asarray(xi, dtype=float))


UNEQUAL = Hyperbolic2x2(lam=1.0, mu=2.0, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)


@cache
def kernels_of(system, n: int = 401):
    return solve_kernels(system, n)


def paper_kernels():
    return kernels_of(PAPER)


# --------------------------------------------------------------------------------------
# Exact solution of a transport loop by the method of characteristics
# --------------------------------------------------------------------------------------


def transport_exact(system, K, lag, n, steps, u0, v0):
    """Exact node values of the transport loop with ``U = -K u(t, 1)`` delayed by ``lag`` steps.

    Integer arithmetic on the grids of the simulator when ``nv = 1/(mu dt)`` is an integer
    (``dt = 1/(lam n)``): ``u`` at ``i / n``, ``v`` at ``k / nv``. ``u(t, 1) = u0(1 - lam t)``
    before the first crossing, then ``q v(t - 1/lam, 0)``; ``v(t, 0) = v0(mu t)``, then
    ``beta(t - 1/mu)`` with ``beta(t) = v(t, 1) = rho u(t, 1) + U(t - delta)`` for ``t > 0``
    and ``beta(0) = v0(1)``.
    """
    nv = round(n * system.lam / system.mu)
    beta = np.empty(steps + 1)
    u_right = np.empty(steps + 1)

    def v_left(j):  # v(t_j, 0)
        return v0(j / nv) if j <= nv else beta[j - nv]

    for j in range(steps + 1):
        u_right[j] = u0(1.0 - j / n) if j <= n else system.q * v_left(j - n)
        if j == 0:
            beta[j] = v0(1.0)
        else:
            delayed = -K * u_right[j - lag] if j >= lag else 0.0
            beta[j] = system.rho * u_right[j] + delayed
    u = np.empty((steps + 1, n + 1))
    v = np.empty((steps + 1, nv + 1))
    for j in range(steps + 1):
        for i in range(n + 1):
            u[j, i] = u0((i - j) / n) if i >= j else system.q * v_left(j - i)
        for k in range(nv + 1):
            v[j, k] = v0((k + j) / nv) if k + j <= nv else beta[j - (nv - k)]
    return u, v, -K * u_right


@pytest.mark.parametrize(("lam", "mu"), [(1.25, 1.25), (2.5, 1.25), (1.25, 2.5)])
@pytest.mark.parametrize(
    ("K", "delta"),
    [(0.9, 0.0), (0.9, 0.32), (0.3, 0.0), (0.3, 0.04), (0.0, 0.0), (-0.4, 1.0)],
)
def test_transport_loop_matches_characteristics_to_rounding(lam, mu, K, delta):
    system = TransportSystem(lam=lam, mu=mu, q=0.7, rho=0.9)
    n, t_end = 40, 6.0
    if lam != mu:
        n = round(40 * 1.25 / lam)  # dt = 0.02 in every case

    def u0(x):
        return np.cos(3.0 * x) + (x > 0.4)

    def v0(x):
        return x**2 - 0.5 * np.sin(7.0 * x)

    law = FeedbackLaw(-K, zero, zero)
    sim = simulate(system, law, delta, t_end, u0, v0, cells=n, snapshot_every=1)
    lag = round(delta / sim.dt)
    assert sim.delay_interpolation == "exact shift"
    assert sim.scheme == ("characteristic lattice" if lam == mu else "two characteristic grids")
    u, v, control = transport_exact(system, K, lag, n, sim.times.size - 1, u0, v0)
    scale = max(1.0, np.abs(u).max(), np.abs(v).max())
    assert np.abs(sim.u - u).max() <= 1e-13 * scale
    assert np.abs(sim.v - v).max() <= 1e-13 * scale
    assert np.abs(sim.control - control).max() <= 1e-13 * scale
    wu = np.full(sim.x.size, 1.0 / n)
    wu[[0, -1]] /= 2
    wv = np.full(sim.x_v.size, 1.0 / (sim.x_v.size - 1))
    wv[[0, -1]] /= 2
    exact_norm = np.sqrt((u * u) @ wu + (v * v) @ wv)
    np.testing.assert_allclose(sim.norm, exact_norm, rtol=1e-13, atol=1e-14 * scale)


def test_finite_time_transport_vanishes_exactly():
    sim = simulate(PAPER_TRANSPORT, FiniteTimeController(), 0.0, 5.0, np.cos, np.sin, cells=64)
    assert np.all(sim.norm[sim.times > PAPER_TRANSPORT.tau + 1e-12] == 0.0)
    assert sim.norm[0] > 0.5


def test_fractional_delay_is_interpolated_at_fourth_order():
    """``delta`` off the grid: the history is read by 4-point Lagrange interpolation."""
    system = TransportSystem(lam=1.0, mu=1.0, q=0.8, rho=0.7)
    K, delta, t_end = 0.5, 0.3137, 4.0

    def u0(x):
        return np.sin(np.pi * x) ** 4  # U(0) = 0 and a state compatible to second order

    def v0(x):
        return np.sin(np.pi * x) ** 4 * (1.0 + x) / 0.8

    def exact_u1(t):  # u(t, 1) of the continuous loop, by the method of characteristics
        if t <= 1.0:
            return u0(1.0 - t)
        return system.q * (v0(t - 1.0) if t <= 2.0 else beta(t - 2.0))

    def beta(t):
        delayed = -K * exact_u1(t - delta) if t >= delta else 0.0
        return system.rho * exact_u1(t) + delayed

    errors = []
    for n in (50, 100):
        sim = simulate(system, FeedbackLaw(-K, zero, zero), delta, t_end, u0, v0, cells=n)
        assert sim.delay_interpolation == "Lagrange-4"
        exact = np.array([-K * exact_u1(t) for t in sim.times])
        errors.append(np.abs(sim.control - exact).max())
    assert errors[1] < 1e-6
    assert errors[0] / errors[1] > 2.0**3.5


def test_partial_cell_at_the_reflecting_boundary_converges():
    """``1/(mu dt)`` not an integer: ``v(t, 0)`` is interpolated one step upstream."""
    system = TransportSystem(lam=1.0, mu=math.sqrt(2.0), q=0.8, rho=0.7)
    K = 0.5

    def u0(x):
        return np.sin(np.pi * x) ** 4

    def v0(x):
        return np.sin(np.pi * x) ** 4 * (2.0 - x)

    def exact_u1(t):  # delta = 0: beta(t) = (rho - K) u(t, 1)
        if t <= 1.0:
            return u0(1.0 - t)
        t0 = t - 1.0  # time at which the characteristic left x = 0
        return system.q * (
            v0(system.mu * t0) if t0 <= 1.0 / system.mu else (system.rho - K) * exact_u1(t0 - 1.0 / system.mu)
        )

    errors = []
    for n in (80, 160):
        sim = simulate(system, FeedbackLaw(-K, zero, zero), 0.0, 6.0, u0, v0, cells=n)
        assert 0.0 < sim.x_v[1] < system.mu * sim.dt  # the partial cell
        errors.append(np.abs(sim.control - np.array([-K * exact_u1(t) for t in sim.times])).max())
    assert errors[1] < 1e-6
    assert math.log2(errors[0] / errors[1]) > 1.8


# --------------------------------------------------------------------------------------
# Exact identities of the coupled closed loop without delay
# --------------------------------------------------------------------------------------


def compatible_v0(law, u0, rho, q, n_quad=4001):
    """``v0 = 1/q + c x^3`` with ``v0(1) = rho u0(1) + U(0)`` (U(0) from the law, delta = 0)."""
    xi = np.linspace(0.0, 1.0, n_quad)
    w = np.full(n_quad, xi[1])
    w[[0, -1]] /= 2
    a = w @ (law.gain_u(xi) * u0(xi) + law.gain_v(xi) / q) + law.boundary_gain * u0(1.0)
    b = w @ (law.gain_v(xi) * xi**3)
    c = (rho * u0(1.0) + a - 1.0 / q) / (1.0 - b)
    return lambda x: 1.0 / q + c * x**3


def test_reflection_controller_keeps_exact_round_trip_ratio():
    """U_BS2(K), delta = 0: ``||(u, v)(t)|| = |q (rho - K)| ||(u, v)(t - tau)||`` for ``t >= tau``.

    In the target coordinates the loop is pure transport with reflections ``q`` and
    ``rho - K`` (eqs. (56)-(58)), so ``(alpha, beta)(t) = q (rho
    - K) (alpha, beta)(t - tau)`` for ``t >= tau``. The inverse Volterra map
    (eqs. (30)-(31)) is linear and does not depend on time, hence the same
    identity holds for ``(u, v)`` itself and for its L2 norm: no kernels are needed to
    state it on the original state. The initial state is compatible with both boundary
    conditions, so no discontinuity is sampled.
    """
    law = ReflectionController(0.1).feedback_law(PAPER, paper_kernels())

    def u0(x):
        return 1.0 + 0.5 * np.sin(np.pi * x)

    v0 = compatible_v0(law, u0, PAPER.rho, PAPER.q)
    sim = simulate(PAPER, law, 0.0, 10.0, u0, v0, cells=800)
    lag = round(PAPER.tau / sim.dt)
    ratio = sim.norm[lag:] / sim.norm[:-lag]
    assert sim.times[lag] == pytest.approx(2.0, rel=1e-13, abs=1e-14)
    assert np.abs(ratio - 0.75).max() < 1e-6


def test_finite_time_controller_reaches_zero_after_tau():
    law = FiniteTimeController().feedback_law(PAPER, paper_kernels())

    def u0(x):
        return 1.0 + 0.5 * np.sin(np.pi * x)

    v0 = compatible_v0(law, u0, PAPER.rho, PAPER.q)
    sim = simulate(PAPER, law, 0.0, 6.0, u0, v0, cells=400)
    peak = sim.norm.max()
    assert peak > 1.0
    after = sim.times >= PAPER.tau
    assert sim.norm[after].max() < 1e-6 * peak  # the O(h^2) defect of the scheme
    assert sim.norm[sim.times >= 2 * PAPER.tau].max() < 1e-10 * peak


def _round_trip_errors(system: Hyperbolic2x2, ratio: float, kernel_grid: int) -> tuple[list[float], set[str]]:
    """Max deviation of ``||(u,v)(t)|| / ||(u,v)(t - tau)||`` from ``ratio`` for U_BS2(0.1), delta = 0.

    Run on ``n = 100, 200`` from a compatible initial state over three round trips.
    """
    law = ReflectionController(0.1).feedback_law(system, solve_kernels(system, kernel_grid))

    def u0(x):
        return 1.0 + 0.5 * np.sin(np.pi * x)

    v0 = compatible_v0(law, u0, system.rho, system.q)
    errors, schemes = [], set()
    for n in (100, 200):
        sim = simulate(system, law, 0.0, 3 * system.tau, u0, v0, cells=n)
        schemes.add(sim.scheme)
        later = sim.times >= system.tau
        before = np.interp(sim.times[later] - system.tau, sim.times, sim.norm)
        errors.append(float(np.abs(sim.norm[later] / before - ratio).max()))
    return errors, schemes


@pytest.mark.parametrize(("lam", "mu"), [(1.0, 2.0), (1.3, 0.7)])
def test_unequal_speeds_round_trip_ratio_converges_at_second_order(lam, mu):
    """The identity above on two grids; ``(1.3, 0.7)`` has a partial cell at ``x = 0``."""
    system = Hyperbolic2x2(lam=lam, mu=mu, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)
    errors, schemes = _round_trip_errors(system, 0.75, kernel_grid=201)
    assert schemes == {"two characteristic grids"}
    assert errors[1] < 3e-5
    assert math.log2(errors[0] / errors[1]) > 1.8


@pytest.mark.parametrize(("lam", "mu"), [(1.0, 1.0), (1.2, 0.8)])
def test_varying_couplings_round_trip_ratio(lam, mu):
    """The identity of U_BS2 with spatially varying couplings: ``|q (rho - K)| = 0.63``."""
    system = Hyperbolic2x2(
        lam=lam, mu=mu, sigma_pm=lambda x: 1 + 0.5 * np.sin(3 * x), sigma_mp=lambda x: 0.8 - 0.6 * x, q=0.9, rho=0.8
    )
    errors, _ = _round_trip_errors(system, 0.63, kernel_grid=401)
    assert errors[1] < 1e-5
    assert math.log2(errors[0] / errors[1]) > 1.8


@pytest.mark.parametrize("mu", [2.0, 1.001])
def test_unequal_speeds_finite_time_residual_is_small_and_decays(mu):
    """Nearly equal speeds put the two grids almost on top of each other: a scheme that
    skipped the crossings between sampled times would split into two sub-lattices there."""
    system = Hyperbolic2x2(lam=1.0, mu=mu, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)
    law = FiniteTimeController().feedback_law(system, solve_kernels(system, 201))

    def u0(x):
        return 1.0 + 0.5 * np.sin(np.pi * x)

    v0 = compatible_v0(law, u0, system.rho, system.q)
    sim = simulate(system, law, 0.0, 5 * system.tau, u0, v0, cells=200)
    peaks = [sim.norm[(sim.times > m * system.tau) & (sim.times <= (m + 1) * system.tau)].max() for m in range(5)]
    assert peaks[0] > 1.0
    assert peaks[1] < 1e-4 * peaks[0]  # the O(h^2) defect of the scheme
    assert all(later < 0.1 * earlier for earlier, later in itertools.pairwise(peaks))


def test_controller_objects_and_feedback_laws_agree():
    law = FiniteTimeController().feedback_law(PAPER, paper_kernels())
    a = simulate(PAPER, law, 0.05, 3.0, np.cos, np.sin, cells=100)
    b = simulate(PAPER, FiniteTimeController(), 0.05, 3.0, np.cos, np.sin, cells=100, kernels=paper_kernels())
    c = simulate(PAPER, FilteredController(0.7, 0.7), 0.05, 3.0, np.cos, np.sin, cells=100, kernels=paper_kernels())
    assert np.array_equal(a.norm, b.norm)
    np.testing.assert_allclose(a.norm, c.norm, rtol=1e-12, atol=1e-12)
    opened = simulate(PAPER, OpenLoop(), 0.0, 3.0, np.cos, np.sin, cells=100)
    assert np.all(opened.control == 0.0)


# --------------------------------------------------------------------------------------
# Growth rates against the spectrum
# --------------------------------------------------------------------------------------


def plant_modes(system, s, x):
    """``(u, v)(x) = exp(M(s) x) [q, 1]`` solving the Laplace-transformed plant, constant couplings.

    ``M(s) = [[-s/lam, sigma_pm/lam], [-sigma_mp/mu, s/mu]]``; with ``M = (T/2) I + M0``,
    ``M0`` traceless, ``exp(M x) = e^{T x/2} (cosh(k x) I + sinh(k x)/k M0)``, ``k^2 = -det M0``.
    """
    lam, mu = system.lam, system.mu
    s = np.asarray(s, dtype=complex)[..., None]
    trace = s * (1.0 / mu - 1.0 / lam)
    a = -s / lam - trace / 2.0
    b = float(system.sigma_pm) / lam
    c = -float(system.sigma_mp) / mu
    k = np.sqrt(a * a + b * c)
    safe = np.where(k == 0, 1.0, k)
    shk = np.where(k == 0, x, np.sinh(k * x) / safe)
    chk = np.cosh(k * x)
    grow = np.exp(trace * x / 2.0)
    u = grow * (chk * system.q + shk * (a * system.q + b))
    v = grow * (chk + shk * (c * system.q - a))
    return u, v


def gauss_nodes(cells, points=4):
    t, w = np.polynomial.legendre.leggauss(points)
    h = 1.0 / cells
    left = np.arange(cells)[:, None] * h
    return (left + h * (t + 1.0) / 2.0).ravel(), np.tile(w * h / 2.0, cells)


def closed_loop_function(system, law, delta):
    """``s -> v(1) - rho u(1) - e^{-delta s} (boundary_gain u(1) + int gain_u u + gain_v v)``.

    Its zeros are the closed-loop poles: a mode ``e^{s t} (u, v)(x)`` exists iff the plant
    mode ``exp(M(s) x) [q, 1]`` meets the actuated boundary condition with the delayed law.
    Gains are piecewise linear on the kernel grid (400 cells): Gauss-Legendre on each cell.
    """
    xs, ws = gauss_nodes(400)
    gu, gv = law.gain_u(xs), law.gain_v(xs)
    points = np.concatenate([xs, [1.0]])

    def F(s):
        u, v = plant_modes(system, s, points)
        u1, v1 = u[..., -1], v[..., -1]
        integral = (u[..., :-1] * gu + v[..., :-1] * gv) @ ws
        return v1 - system.rho * u1 - np.exp(-delta * np.asarray(s)) * (law.boundary_gain * u1 + integral)

    return F


def principal_roots(system, gain, delta):
    """Roots of ``1 - rho q e^{-tau s} + gain q e^{-(tau + delta) s}`` (tau/delta integer),
    one period ``0 <= Im s < 2 pi/delta``: a polynomial in ``z = e^{-delta s}``."""
    m = round(system.tau / delta)
    assert abs(m * delta - system.tau) < 1e-12
    coefs = np.zeros(m + 2)
    coefs[0] = 1.0
    coefs[m] -= system.rho * system.q
    coefs[m + 1] += gain * system.q
    z = np.roots(coefs[::-1]).astype(complex)
    s = -np.log(z) / delta
    return s.real + 1j * np.mod(s.imag, 2 * np.pi / delta)


def rightmost_root(F, seeds, iters=40):
    """Newton from each seed; the converged root of largest real part."""
    s = np.array(seeds, dtype=complex)
    for _ in range(iters):
        h = 1e-6
        step = F(s) / ((F(s + h) - F(s - h)) / (2 * h))
        s = s - step
        if np.all(np.abs(step) < 1e-12):
            break
    ok = np.abs(F(s)) < 1e-9 * np.maximum(1.0, np.abs(s))
    assert np.count_nonzero(ok) >= 1
    return s[ok][np.argmax(s[ok].real)]


CASES = [
    # (system, controller, K in the principal part, delta, t_end)
    (PAPER_TRANSPORT, FiniteTimeController(), 0.85, 0.01, 10.0),
    (PAPER_TRANSPORT, ReflectionController(0.1), 0.1, 0.1, 20.0),
    (PAPER, FiniteTimeController(), 0.85, 0.01, 10.0),
    (PAPER, ReflectionController(0.1), 0.1, 0.1, 20.0),
    (UNEQUAL, FiniteTimeController(), 0.85, 0.01, 10.0),
]


@pytest.mark.parametrize(("system", "controller", "gain", "delta", "t_end"), CASES)
def test_growth_rate_matches_spectral_abscissa(system, controller, gain, delta, t_end):
    """Fitted slope of ``log ||(u, v)||`` against the rightmost closed-loop root.

    The reference root comes from the plant's matrix exponential (no delay form); for the
    loops where it is cheap, ``nrobust.spectral_abscissa`` on the delay form must agree.

    The principal part's roots lie on chains whose real part varies smoothly with
    frequency; a generic initial state excites a continuum of nearly dominant modes and
    ``log ||(u, v)||`` then grows like ``x_max t - log(t)/2`` (a Laplace-type integral),
    whose fitted slope approaches ``x_max`` only as ``1/(2t)``. The initial state is
    therefore the plant mode of the rightmost root (its history before ``t = 0`` is still
    zero, so the other modes are excited too, but weakly).
    """
    kernels = None if system.uncoupled else kernels_of(system)
    law = controller.feedback_law(system, kernels)
    F = closed_loop_function(system, law, delta)
    chain = principal_roots(system, gain, delta)
    top = chain.real.max()
    periods = np.arange(3 if delta < 0.05 else 4)[:, None] * (2 * np.pi / delta)
    seeds = (chain[chain.real > top - 0.02][None, :] + 1j * periods).ravel()
    n = 400
    seeds = seeds[seeds.imag < 0.4 * np.pi * n * system.lam]  # well below the grid's pi/dt
    root = rightmost_root(F, seeds)
    if not system.uncoupled:
        # Second route: the delay form (kernels L, N~) of the paper, eq. (39).
        G = characteristic(system, controller, delta)
        newton_step = abs(G(np.array([root]))[0] / G.deriv_at(np.array([root]))[0])
        assert newton_step < 1e-5
    # Far along the chains the roots tend to those of the principal part (the distributed
    # term decays like 1/|s|): the spectral abscissa is the larger of both.
    abscissa = max(root.real, top)
    if delta >= 0.05:  # certified abscissa of the delay form (cheap for these loops)
        certified = spectral_abscissa(characteristic(system, controller, delta))
        assert certified.certified
        assert abs(certified.value - abscissa) < 1e-6
    u0, _ = plant_modes(system, root, np.linspace(0.0, 1.0, n + 1))
    _, v0 = plant_modes(system, root, v_nodes(system, n))
    scale = np.abs(np.concatenate([u0, v0])).max()
    sim = simulate(system, law, delta, t_end, u0.real / scale, v0.real / scale, cells=n)
    rate = sim.growth_rate(2.0)
    assert abs(rate - abscissa) <= 0.1 * abs(abscissa)
    assert abs(rate - root.real) <= 2e-3 * max(abs(root.real), 0.1)
    assert (rate > 0) == (abscissa > 0)


def test_filtered_transport_decays_at_its_rightmost_root():
    """U_1 = -(1 + a s)/(1 + b s) rho u(1, s) (section 2.3.2) against
    ``(1 + b s)(1 - rho q e^{-tau s}) + (1 + a s) rho q e^{-(tau + delta) s}``."""
    system, a, b, delta = PAPER_TRANSPORT, 0.1, 1.0, 0.05
    rq, tau = system.rho * system.q, system.tau

    def F(s):
        return (1 + b * s) * (1 - rq * np.exp(-tau * s)) + (1 + a * s) * rq * np.exp(-(tau + delta) * s)

    seeds = (np.linspace(-0.5, 0.0, 6)[:, None] + 1j * np.arange(0.0, 200.0, 1.5)[None, :]).ravel()
    root = rightmost_root(F, seeds)
    assert root.real < 0
    certified = spectral_abscissa(characteristic(system, FilteredController(a, b), delta))
    assert abs(certified.value - root.real) < 1e-9
    x = np.linspace(0.0, 1.0, 401)
    u0, v0 = plant_modes(system, root, x)
    sim = simulate(system, FilteredController(a, b), delta, 30.0, u0.real, v0.real, cells=400)
    assert sim.growth_rate(10.0) == pytest.approx(root.real, rel=1e-2)


# --------------------------------------------------------------------------------------
# Convergence
# --------------------------------------------------------------------------------------


def smooth_problem(mu=1.5):
    """Spatially varying couplings, smooth gains, a filter and a delay; ``U(0) = 0`` and a
    state compatible with both boundaries, so the solution stays continuous."""
    system = Hyperbolic2x2(
        lam=1.5, mu=mu, sigma_pm=lambda x: 0.8 + 0.4 * np.cos(2 * x), sigma_mp=lambda x: 1.0 - 0.5 * x, q=0.9, rho=0.6
    )

    def gain_u(xi):
        return 0.5 * np.cos(xi)

    def gain_v(xi):
        return -0.3 + 0.2 * xi

    law = FeedbackLaw(-0.2, gain_u, gain_v, (0.3, 0.5))

    def u0(x):
        return 1.0 + 0.5 * x

    # v0 = 1/q + (rho u0(1) - 1/q) x + c x (1 - x), with c such that V(0) = 0.
    xi = np.linspace(0.0, 1.0, 20001)
    w = np.full(xi.size, xi[1])
    w[[0, -1]] /= 2
    base = 1 / system.q + (system.rho * u0(1.0) - 1 / system.q) * xi
    v_zero = law.boundary_gain * u0(1.0) + w @ (gain_u(xi) * u0(xi) + gain_v(xi) * base)
    c = -v_zero / (w @ (gain_v(xi) * xi * (1 - xi)))

    def v0(x):
        return 1 / system.q + (system.rho * u0(1.0) - 1 / system.q) * x + c * x * (1 - x)

    return system, law, u0, v0


def observed_orders(delta, ns, mu=1.5):
    system, law, u0, v0 = smooth_problem(mu)
    runs = [simulate(system, law, delta, 6.0, u0, v0, cells=n) for n in ns]
    coarse = runs[0].times
    histories = [np.interp(coarse, r.times, r.norm) for r in runs]
    # Sampled times of the coarsest run are sampled times of every run (n doubles).
    for r, h in zip(runs, histories):
        np.testing.assert_allclose(h, r.norm[:: r.n // ns[0]], rtol=1e-15, atol=0)
    diffs = [np.abs(histories[i] - histories[i + 1]).max() for i in range(len(ns) - 1)]
    return [math.log2(diffs[i] / diffs[i + 1]) for i in range(len(diffs) - 1)]


def test_second_order_convergence_quick():
    orders = observed_orders(0.1, (60, 120, 240))
    assert min(orders) >= 1.8, orders


@pytest.mark.slow
@pytest.mark.parametrize(("delta", "mu"), [(0.1, 1.5), (0.0123, 1.5), (0.1, 1.1)])
def test_second_order_convergence_of_the_norm_history(delta, mu):
    orders = observed_orders(delta, (60, 120, 240, 480), mu)
    assert min(orders) >= 1.8, orders


# --------------------------------------------------------------------------------------
# Result object and input checks
# --------------------------------------------------------------------------------------


def test_result_snapshots_and_json():
    sim = simulate(PAPER_TRANSPORT, ReflectionController(0.1), 0.1, 1.0, np.cos, np.sin, cells=20, snapshot_every=5)
    assert isinstance(sim, Simulation)
    assert sim.times.size == 21 and sim.norm.shape == sim.control.shape == sim.times.shape
    np.testing.assert_allclose(sim.snapshot_times, [0.0, 0.25, 0.5, 0.75, 1.0], rtol=1e-15, atol=1e-15)
    assert sim.u.shape == sim.v.shape == (5, 21)
    data = json.loads(json.dumps(sim.to_dict()))
    assert data["delay_interpolation"] == "exact shift" and data["n"] == 20
    assert "Simulation(n=20" in repr(sim)
    final = simulate(PAPER_TRANSPORT, ReflectionController(0.1), 0.1, 1.0, np.cos, np.sin, cells=20)
    assert final.u.shape == (1, 21) and final.snapshot_times[0] == pytest.approx(1.0, rel=1e-13, abs=1e-14)
    with pytest.raises(FrozenInstanceError):
        sim.n = 3  # type: ignore[misc]


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"system": TransportSystem(lam=1.0, mu=2.0, q=1.0, rho=0.5), "v0": np.zeros(21)}, "v0"),
        ({"system": "plant"}, "system"),
        ({"delta": -0.1}, "delta"),
        ({"delta": float("nan")}, "delta"),
        ({"t_end": 0.0}, "t_end"),
        ({"cells": 1}, "cells"),
        ({"system": TransportSystem(lam=1.0, mu=10.0, q=1.0, rho=0.5)}, "cells"),
        ({"u0": np.zeros(7)}, "u0"),
        ({"v0": lambda x: np.full_like(x, np.inf)}, "v0"),
        ({"controller": 3.0}, "controller"),
        ({"snapshot_every": 0}, "snapshot_every"),
        ({"max_updates": 100}, "(cells, t_end)"),
    ],
)
def test_bad_input_raises_parameter_error(kwargs, name):
    args = {
        "system": PAPER_TRANSPORT,
        "controller": OpenLoop(),
        "delta": 0.0,
        "t_end": 1.0,
        "u0": np.cos,
        "v0": np.sin,
        "cells": 20,
    }
    args.update(kwargs)
    with pytest.raises(ParameterError) as info:
        simulate(**args)
    assert info.value.name == name


def test_growth_rate_window_checks():
    sim = simulate(PAPER_TRANSPORT, FiniteTimeController(), 0.0, 3.0, np.cos, np.sin, cells=20)
    with pytest.raises(ParameterError):
        sim.growth_rate(5.0)
    with pytest.raises(ParameterError):
        sim.growth_rate(2.5)  # the norm is exactly zero there


# ---------------------------------------------------------------------------- the registry
def test_simulate_picks_the_scheme_by_the_plant_and_by_name() -> None:
    """One ``simulate`` over the registry: the plant picks the scheme (or ``scheme=`` names it), the
    result is the scheme's own simulator's, bit for bit, and every result is a SimulationResult."""
    assert sorted(SCHEMES) == ["characteristics", "n+m characteristics", "normal form", "time-of-flight grids"]
    system = NPlusMSystem([1.0], [1.5], [[0.0, 0.4], [0.5, 0.0]], [[0.6]], [[0.5]])

    def w0(x: np.ndarray) -> np.ndarray:
        return np.vstack([np.sin(np.pi * x) + 0.3, 1 + x * x])

    direct = simulate_nplusm(system, [[-0.2]], 0.3, 2.0, w0, cells=10)
    for run in (
        simulate(system, [[-0.2]], 0.3, 2.0, w0, cells=10),
        simulate(system, [[-0.2]], 0.3, 2.0, w0=w0, cells=10, scheme="n+m characteristics"),
    ):
        assert isinstance(run, SimulationResult)
        np.testing.assert_array_equal(run.norm, direct.norm)
        np.testing.assert_array_equal(run.times, direct.times)
    with pytest.raises(ParameterError, match="v0"):
        simulate(system, [[-0.2]], 0.3, 2.0, w0, w0, cells=10)
    with pytest.raises(ParameterError, match="scheme"):
        simulate(PAPER, ReflectionController(0.1), 0.1, 1.0, np.sin, np.sin, 20, scheme="upwind")
    with pytest.raises(ParameterError, match="system"):
        simulate(PAPER, ReflectionController(0.1), 0.1, 1.0, np.sin, np.sin, 20, scheme="n+m characteristics")
    paper = simulate(PAPER, ReflectionController(0.1), 0.1, 1.0, np.sin, np.sin, 20)
    assert isinstance(paper, SimulationResult)


def test_initial_states_are_checked_once_for_every_scheme() -> None:
    """A number is a constant state; a user's callable that raises is a ParameterError naming it."""
    constant = simulate(PAPER_TRANSPORT, ReflectionController(0.1), 0.1, 0.5, 1.0, 0.5, 20)
    nodes = simulate(PAPER_TRANSPORT, ReflectionController(0.1), 0.1, 0.5, np.ones(21), 0.5 * np.ones(21), 20)
    np.testing.assert_array_equal(constant.norm, nodes.norm)
    with pytest.raises(ParameterError, match=r"u0.*ZeroDivisionError"):
        simulate(PAPER_TRANSPORT, ReflectionController(0.1), 0.1, 0.5, lambda x: 1 / 0, 0.5, 20)
    system = NPlusMSystem([1.0], [1.5], [[0.0, 0.4], [0.5, 0.0]], [[0.6]], [[0.5]])
    with pytest.raises(ParameterError, match=r"w0.*ZeroDivisionError"):
        simulate(system, [[-0.2]], 0.3, 1.0, lambda x: 1 / 0, cells=10)
