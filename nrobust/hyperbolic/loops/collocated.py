"""Output feedback from the actuated boundary: the collocated observer of Vazquez, Krstic and Coron.

The measurement is ``y(t) = u(t, 1)``, at the boundary where ``U`` acts. The observer is the
backstepping observer of Vazquez, Krstic and Coron ("Backstepping boundary stabilization and
state estimation of a 2x2 linear hyperbolic system", CDC 2011), a copy of the plant (18)-(20)
corrected by the output error:

    u^_t + lam u^_x = sigma^{+-} v^ + p_u(x) (y - u^(t, 1)),     u^(t, 0) = q v^(t, 0),
    v^_t - mu v^_x  = sigma^{-+} u^ + p_v(x) (y - u^(t, 1)),     v^(t, 1) = rho y + U_o(t),

and the controller applies a state feedback of the package to ``(u^, v^)``. ``U_o`` is the
command the observer assumes reached the plant (the controller's output delayed by
``delta_o``).

**The error and its gains.** Let ``W = U_p - U_o`` be the difference between the command the
plant received and the one the observer replays. The error ``(u~, v~) = (u, v) - (u^, v^)``
obeys the plant's equations with ``- p_u u~(t, 1)``, ``- p_v u~(t, 1)`` added,
``u~(t, 0) = q v~(t, 0)`` and ``v~(t, 1) = W`` (the reflection ``rho`` is read from ``y``, so it
leaves the error). The Volterra map ``(u~, v~) = (I - P)(a~, b~)`` from ``x = 1``
(``P`` on ``x <= xi``) takes it, for ``W = 0``, to the transport system ``a~_t + lam a~_x = 0``,
``b~_t - mu b~_x = 0``, ``a~(0) = q b~(0)``, ``b~(1) = 0``, which is zero after ``tau`` (eq. (5)),
when ``P`` solves the Goursat problem

    lam (P^{uu}_x + P^{uu}_xi) = sigma^{+-}(x) P^{vu},   mu P^{vu}_x - lam P^{vu}_xi = -sigma^{-+}(x) P^{uu},
    P^{vu}(x, x) = -sigma^{-+}(x) / (lam + mu),           P^{uu}(0, xi) = q P^{vu}(0, xi)

(and its second column, with ``P^{uv}(x, x) = sigma^{+-}/(lam + mu)``,
``P^{uv}(0, xi) = q P^{vv}(0, xi)``), with ``p_u(x) = -lam P^{uu}(x, 1)``,
``p_v(x) = -lam P^{vu}(x, 1)``. The gains are those of a dual controller: by the Lagrange
identity of the error equations in the Laplace domain (below), the adjoint of the error system
is the paper's plant (18)-(20) with

    lam' = mu,  mu' = lam,  sigma'^{+-} = sigma^{+-},  sigma'^{-+} = sigma^{-+},  q' = lam q / mu,  rho' = 0,

under the state feedback ``U' = -(1/lam) int_0^1 p_v a + p_u b dx``. The finite-time law U_BS
of that plant (eq. (47) with ``rho' = 0``) has a nilpotent closed loop (its target system is
zero after ``tau``), so its adjoint is a nilpotent error system: ``p_u = -lam K'^{vv}(1, .)``,
``p_v = -lam K'^{vu}(1, .)`` with the kernels ``K'`` (eqs. (22)-(29)) of the dual plant. A
finite-time law is unique (its closed loop's characteristic function is ``1``), so these are the
gains of the Goursat problem above.

**Separation with delays.** With ``delta_a`` on the actuation and ``delta_m`` on the
measurement, write ``xi(t) = x(t - delta_m)`` for the plant's state as the measurement sees it:
it obeys the plant with the command delayed by ``delta = delta_a + delta_m`` and
``y(t - delta_m) = xi_u(t, 1)``. The error ``e = xi - x^`` is driven by
``W = (e^{-delta s} - e^{-delta_o s}) U_c``, and ``U_c = K xi - K e`` (``K`` the law). In the
Laplace domain, with ``T = K (s - A)^{-1} B`` the law seen through the plant and
``C_u = K (s - A + L C)^{-1} B`` the law seen through the error system,
``U_c (1 - T e^{-delta s} + C_u (e^{-delta s} - e^{-delta_o s})) = 0``. The delay form (39)
gives ``T = L_K / (1 - Phi)`` with ``-L_K`` the factor ``B`` of the state feedback
(:mod:`~nrobust.hyperbolic.loops.controllers`), so, multiplying by ``d (1 - Phi)`` for a law
filtered by ``n/d``, the closed loop is

    F(s; delta) = A_o + B_o e^{-delta s},   A_o = A - n G e^{-delta_o s},   B_o = B + n G,
    G = (1 - Phi) C_u,

the form of the output feedback from ``v(t, 0)``
(:func:`~nrobust.hyperbolic.loops.output_feedback.output_feedback_factors`). Only the sum
``delta`` matters; at ``delta = delta_o`` the loop is the state feedback's with that delay (the
observer is exact there), at ``delta = delta_o = 0`` the target system (for U_BS2(K),
``1 - (rho - K) q e^{-tau s}``, eqs. (56)-(58)). The modes of the error system would be
factors of ``F``; it has none (nilpotent).

**The command response ``C_u``.** With ``(phi, psi)`` the adjoint of the error equations at
``s`` (``s phi - lam phi' - sigma^{-+} psi = -g_u``, ``s psi + mu psi' - sigma^{+-} phi = -g_v``,
``mu psi(0) = lam q phi(0)``, ``lam phi(1) = -k - int p_u phi + p_v psi``) for the law
``U = k u(1) + int g_u u + g_v v``, the Lagrange identity gives ``C_u(s) = -mu psi(s, 1)``. In
time, ``(a, b) = (psi, phi)`` is the dual plant under U_BS' driven by an impulse ``w``
entering distributed as ``(-g_v, -g_u) w`` and at ``x = 1`` as ``-(k/lam) w``. Its target
coordinates ``(a', b') = (I - K')(a, b)`` are transported: ``a'(0+) = F_a``, ``b'(0+) = F_b``
with ``(F_a, F_b) = (I - K')(-g_v, -g_u)``, ``b'(t, 1) = -(k/lam) delta(t)``,
``a'(t, 0) = q' b'(t, 0)``, and ``a(t, 1) = a'(t, 1) + int_0^1 L'^{aa}(1, xi) a' + L'^{ab}(1, xi) b'``.
Hence ``C_u(s) = k q e^{-tau s} + int_0^tau c(nu) e^{-nu s} dnu`` with

    -c(t)/mu = a'_s(t, 1) + int_0^1 L'^{aa}(1, xi) a'_s(t, xi) + L'^{ab}(1, xi) b'_s(t, xi) dxi
               - k L'^{ab}(1, 1 - lam t) [t < 1/lam] - q k L'^{aa}(1, mu (t - 1/lam)) [1/lam < t < tau],

``b'_s(t, xi) = F_b(xi + lam t)`` (zero past ``x = 1``), ``a'_s(t, xi) = F_a(xi - mu t)`` for
``xi >= mu t`` and ``q' F_b(lam (t - xi/mu))`` below (zero past ``lam t - lam xi/mu = 1``). ``c``
is smooth between ``0``, ``1/lam``, ``1/mu`` and ``tau``; on a transport system ``K' = L' = 0``.

**What the observer changes.** ``G`` has the point terms ``k q e^{-tau s} - k rho q^2 e^{-2 tau s}``,
so the difference operator is not the state feedback's: for U_BS2(K) (``k = -K``) and
``delta_o = 0`` it is ``1 - (rho - K) q e^{-tau s} - K rho q^2 e^{-2 tau s} + K rho q^2
e^{-(2 tau + delta) s}``, strongly stable (Theorem 4's condition) iff
``|rho - K| |q| + 2 |K rho| q^2 < 1``, not ``|rho q| + |K q| < 1``. The observer reads the
reflection ``rho u(t, 1)`` from the measurement and predicts ``u(t, 1)`` from the commands, so
U_BS (``K = rho``) keeps a positive margin up to ``|rho q| < 1/sqrt(2)`` instead of the
``1/2`` of Theorem 3. With ``delta_o > 0`` the terms at ``tau`` and ``tau + delta_o`` no longer
merge: the condition becomes ``|rho q| + |K q| + 2 |K rho| q^2 < 1``, stricter than the state
feedback's (the paper's example, ``rho q = 0.85``, ``K = 0.1``: ``1.12``, no robustness to a
mismatch ``delta != delta_o``), so the observer should replay the commands undelayed.

**The observer's own reflection.** With ``v^(t, 1) = (rho - kappa) y + kappa u^(t, 1) + U_o``
(``kappa = 0`` above) the error reflects ``v~(t, 1) = kappa u~(t, 1) + W``. The gains are kept:
the error system of ``kappa = 0`` driven by ``W' = kappa u~(t, 1) + W``. With ``H_y`` its output
error ``u~(t, 1)`` per unit ``W'`` (the command response of the law ``U = u(t, 1)``: ``k = 1``, no
gains, so ``H_y = q e^{-tau s} + int c e^{-nu s}`` with ``c`` from ``L'`` only; not ``q e^{-tau s}``
alone on a coupled plant: once ``b~(t, 1) != 0`` the Volterra map leaves a source proportional
to ``b~(t, 1)``, through ``P^{uv}(x, 1)`` and ``P^{vv}(x, 1)``, in the target system), ``W' = W / E``
with ``E = 1 - kappa H_y``,
the error's characteristic function, so the law sees ``C_u / E``. Multiplying the loop by ``E``:

    A_o = E A - n G e^{-delta_o s},    B_o = E B + n G,    E A = A - kappa d (1 - Phi) H_y,
    E B = B - kappa n B~ H_y,

affine in ``kappa`` (:func:`observer_reflection`, :func:`reflection_factors`); at ``delta =
delta_o`` the loop is ``E`` times the state feedback's, so the zeros of ``E`` are modes of the
loop. For U_BS2(K) and ``delta_o = 0`` the difference operator is ``1 - (rho - K + kappa) q
e^{-tau s} + (kappa - K) rho q^2 e^{-2 tau s} + K (rho - kappa) q^2 e^{-(2 tau + delta) s}``,
strongly stable iff ``|rho - K + kappa| |q| + |(kappa - K) rho| q^2 + |K (rho - kappa)| q^2 < 1``.
With ``delta_o > 0`` the terms of ``G e^{-delta_o s}`` keep their delays: ``E A`` has the principal part
``(1 - kappa q z)(1 - rho q z)`` (``z = e^{-tau s}``), ``G`` the part ``-K q z (1 - rho q z)``, so the
operator is ``1 - (rho + kappa) q z + kappa rho q^2 z^2 + K q z e^{-delta_o s} - K rho q^2 z^2
e^{-delta_o s} + K (rho - kappa) q^2 z^2 e^{-delta s}``, strongly stable iff ``|rho + kappa| |q| +
|kappa rho| q^2 + |K q| + |K rho| q^2 + |K (rho - kappa)| q^2 < 1`` (on the paper's example no
``kappa`` makes U_BS2(0.1) strongly stable: at best ``1.0775``, at ``kappa = -rho``).

**Closed forms.** ``H_y`` needs no kernel: with ``Phi(x, s)`` the fundamental matrix of the plant's
equations in the Laplace domain (``[u; v]' = M(s) [u; v]``, ``M = [[-s/lam, sigma^{+-}/lam],
[-sigma^{-+}/mu, s/mu]]``), ``[phi_u; phi_v] = Phi(1, s) [q; 1]`` and ``g(x) = int_0^x Phi(x - xi)
diag(1/lam, -1/mu) [p_u; p_v](xi) dxi``, the error of ``kappa = 0`` driven by ``W`` has
``u~(1) (1 + g_u(1)) = phi_u v~(0)`` and ``W = v~(0) D / (1 + g_u(1))``,
``D = phi_v (1 + g_u(1)) - g_v(1) phi_u``. ``D`` is entire of exponential type without zeros (the error
system has no modes) and tends to ``e^{s/mu}`` as the uncoupled plant's, so ``D = e^{s/mu}`` and
``H_y = e^{-s/mu} phi_u``: the transfer of ``u(t, 1)`` in the delay form, ``u_factor = q e^{-tau s} +
int_0^tau U~ e^{-nu s}`` of :mod:`~nrobust.hyperbolic.loops.exact_form` (``-B/k`` of ``StateFeedback(k)``;
the kernel route's ``H_y`` converges to it at third order). For ``StateFeedback(k)`` (no integral gains)
``C_u = k H_y``, so its collocated loop is ``E A = A - kappa (1 - Phi) u_factor``, ``E B = B + kappa k
u_factor^2``, ``G = k (1 - Phi) u_factor``, products of closed forms enclosed in ball arithmetic
(:func:`~nrobust.hyperbolic.loops.observer_proof.proven_collocated_products`): proofs about it hold for
the PDE. A law with an integral part ``int K^{v.}(1, xi) (u, v) dxi`` (U_BS, U_BS2(K)) applied to the error
reads ``int K^{v.}(1, .) g``, a composition of the plant's kernels with the dual plant's that the
``2 x 2`` exponential does not give: with constant couplings its ``c`` is built from the kernels ``K``, ``K'``
and ``L'`` as Taylor polynomials with proven remainders (:mod:`~nrobust.hyperbolic.loops.collocated_proof`)
and ``G`` enclosed in ball arithmetic
(:func:`~nrobust.hyperbolic.loops.observer_proof.proven_response_product`), for an observer replaying the
commands undelayed and ends ``1/lam``, ``1/mu``, ``tau`` that are doubles (its reflection's ``B~ H_y`` is
``u_factor - (1 - Phi) u_factor + (K - rho) q e^{-tau s} u_factor``, as ``B~ = Phi + (K - rho) q e^{-tau s}``);
otherwise it is the kernel route's below. So is ``StateFeedback(k, g_u, g_v)``'s: its integral part reads the
error state ``e^{-s/mu} W ((1 + g(1)_u) Phi(x) [q; 1] - phi_u g(x))``
against ``g_u``, ``g_v``, and ``g(x)`` carries the observer's gains ``p_u``, ``p_v`` (the dual plant's kernels).

:func:`collocated_observer` computes ``c`` from the kernels of the dual plant and the law's
gains on the kernel grid (``F`` by the trapezoidal rule with Gregory's end corrections, cubic splines,
composite Gauss-Legendre rules: third order, as the kernels), stores it as
polynomial pieces, and ``G`` by :func:`~nrobust.volterra.resolvent_product`; its accuracy is
estimated by the change of ``c`` from the grid with ``(kernel_grid + 1) / 2`` points. It is a
model of the PDE, as the kernel route is.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ...distributed_delay import DistributedDelay
from ...errors import ParameterError
from ...quasipoly import QuasiPolynomial
from ...volterra import WindowKernel, resolvent_product, shifted_chebyshev
from ..kernels.constant import MIN_KERNEL_GRID, Kernels, solve_kernels
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from ..plants.law import FeedbackLaw

__all__ = [
    "CollocatedObserver",
    "ObserverReflection",
    "collocated_observer",
    "collocated_responses",
    "command_response",
    "dual_plant",
    "observer_gains",
    "observer_reflection",
    "reflection_factors",
]

Array = NDArray[np.float64]

#: Segments of the stored ``c`` per unit of time (at least one per smooth piece) and the degree of
#: its polynomial on each (interpolated at Chebyshev points).
SEGMENTS_PER_UNIT, DEGREE = 16, 11
#: Gauss-Legendre sub-intervals per unit length of ``xi`` and points on each (the integrands are
#: cubic splines of grid values: composite rules of low order on short sub-intervals).
QUADRATURE_CELLS, QUADRATURE_POINTS = 96, 4


def dual_plant(system: Hyperbolic2x2) -> Hyperbolic2x2:
    """The plant whose finite-time law gives the observer's gains (module notes).

    ``Hyperbolic2x2(mu, lam, sigma^{+-}, sigma^{-+}, lam q / mu, 0)``.
    """
    return Hyperbolic2x2(
        system.mu, system.lam, system.sigma_pm, system.sigma_mp, system.lam * system.q / system.mu, 0.0
    )


@lru_cache(maxsize=8)
def _dual_kernels(system: Hyperbolic2x2, kernel_grid: int) -> Kernels:
    """The kernels of :func:`dual_plant` on ``kernel_grid`` points (cached: the observer's term ``G`` and its
    reflection's terms are built on the same grids)."""
    return solve_kernels(dual_plant(system), kernel_grid)


def observer_gains(kernels: Kernels, lam: float) -> tuple[Array, Array, Array]:
    """``(x, p_u(x), p_v(x))`` on the kernel grid from the kernels of :func:`dual_plant`.

    ``p_u = -lam K'^{vv}(1, .)``, ``p_v = -lam K'^{vu}(1, .)`` (module notes); ``lam`` is the
    speed of ``u`` in the observed plant.
    """
    return kernels.grid.copy(), -lam * kernels.K[1, 1, -1, :], -lam * kernels.K[1, 0, -1, :]


def _gregory_weights(n: int) -> Array:
    """Rows ``i``: the trapezoidal rule on ``[0, x_i]`` of the uniform grid with ``n`` points, with Gregory's end
    corrections ``h/12 (-f_0 + f_1 + f_{i-1} - f_i)`` from ``i = 3`` on (third order, as the kernels are: the
    plain rule left the loop's error second order, ``4 x`` per halving of the grid against the PDE's loop)."""
    h = 1.0 / (n - 1)
    w = np.tril(np.full((n, n), h))
    w[:, 0] *= 0.5
    w[np.arange(n), np.arange(n)] *= 0.5
    w[0, 0] = 0.0
    rows = np.arange(3, n)
    w[rows, 0] -= h / 12.0
    w[rows, 1] += h / 12.0
    w[rows, rows - 1] += h / 12.0
    w[rows, rows] -= h / 12.0
    return w


@lru_cache(maxsize=1)
def _unit_rule() -> tuple[Array, Array]:
    """The composite Gauss-Legendre nodes and weights of ``[0, 1]`` (read-only: every rule is this one scaled)."""
    t, g = np.polynomial.legendre.leggauss(QUADRATURE_POINTS)
    cells = np.linspace(0.0, 1.0, QUADRATURE_CELLS + 1)
    ref = (cells[:-1, None] + (0.5 * (t + 1.0))[None, :] / QUADRATURE_CELLS).ravel()
    weight = np.tile(0.5 * g / QUADRATURE_CELLS, QUADRATURE_CELLS)
    ref.flags.writeable = weight.flags.writeable = False
    return ref, weight


def _composite_rule(lo: Array, hi: Array) -> tuple[Array, Array]:
    """Composite Gauss-Legendre nodes and weights on each ``[lo_j, hi_j]`` (rows; empty where ``hi <= lo``)."""
    ref, weight = _unit_rule()
    width = np.maximum(hi - lo, 0.0)
    return lo[:, None] + width[:, None] * ref[None, :], width[:, None] * weight[None, :]


def _splines(values: Array) -> list[Callable[[Array], Array]]:
    """The not-a-knot cubic splines through the columns of ``values`` on the uniform grid of ``[0, 1]`` (4 rows at
    least), as functions on ``[0, 1]``.

    Their second derivatives ``M`` at the nodes solve ``h M_{i-1} + 4 h M_i + h M_{i+1} = 6 (d_i - d_{i-1})``
    (``h`` the step, ``d_i`` the slopes of the data) with ``M`` linear on the first two and on the last two steps
    (the third derivative continuous at the second and the last but one node). The splines of scipy's
    ``CubicSpline`` (its default ``bc_type``) to rounding (``3.4e-15`` of their size measured on grids of 5 to
    201 points), without its import (0.3 s of CPU in a fresh process).
    """
    n = values.shape[0]
    h = 1.0 / (n - 1)
    x = np.linspace(0.0, 1.0, n)
    slopes = np.diff(values, axis=0) / h
    inner = np.arange(1, n - 1)
    matrix = np.zeros((n, n))
    matrix[inner, inner - 1] = h
    matrix[inner, inner] = 4.0 * h
    matrix[inner, inner + 1] = h
    matrix[0, :3] = [h, -2.0 * h, h]
    matrix[-1, -3:] = [h, -2.0 * h, h]
    rhs = np.zeros(values.shape)
    rhs[1:-1] = 6.0 * np.diff(slopes, axis=0)
    M = np.linalg.solve(matrix, rhs)
    # on step i, in powers of x - x_i: y_i, d_i - h (2 M_i + M_{i+1}) / 6, M_i / 2, (M_{i+1} - M_i) / (6 h)
    cubic = (values[:-1], slopes - h * (2.0 * M[:-1] + M[1:]) / 6.0, 0.5 * M[:-1], np.diff(M, axis=0) / (6.0 * h))

    def spline(column: int) -> Callable[[Array], Array]:
        c0, c1, c2, c3 = (np.ascontiguousarray(c[:, column]) for c in cubic)

        def evaluate(points: Array) -> Array:
            # the step of each point from its position (next to a node, either side: the spline is continuous)
            # (clipped in place and gathered by take: np.clip and fancy indexing of integer arrays cost twice as much)
            i = (points * (n - 1)).astype(np.intp)
            np.minimum(np.maximum(i, 0, out=i), n - 2, out=i)
            dx = points - np.take(x, i)
            out = np.take(c3, i) * dx
            out += np.take(c2, i)
            out *= dx
            out += np.take(c1, i)
            out *= dx
            out += np.take(c0, i)
            return out

        return evaluate

    return [spline(k) for k in range(values.shape[1])]


def _response_sampler(
    system: Hyperbolic2x2, law: FeedbackLaw, kernels: Kernels | None, n: int
) -> Callable[[Array, float], Array]:
    """``(t, middle) -> c(t)`` on one smooth piece of ``[0, tau]`` (``middle`` picks its branches)."""
    lam, mu, q, k = system.lam, system.mu, system.q, law.boundary_gain
    q_dual = lam * q / mu
    x = np.linspace(0.0, 1.0, n)
    f_a, f_b = -np.asarray(law.gain_v(x), dtype=float), -np.asarray(law.gain_u(x), dtype=float)
    if kernels is None:
        F_a, F_b, L_aa, L_ab = f_a, f_b, np.zeros(n), np.zeros(n)
    else:
        w = _gregory_weights(n)
        K = kernels.K
        F_a = f_a - (w * K[0, 0]) @ f_a - (w * K[0, 1]) @ f_b
        F_b = f_b - (w * K[1, 0]) @ f_a - (w * K[1, 1]) @ f_b
        L_aa, L_ab = kernels.L[0, 0, -1, :], kernels.L[0, 1, -1, :]
    Fa, Fb, Laa, Lab = _splines(np.stack([F_a, F_b, L_aa, L_ab], axis=1))
    t_v, t_u, tau = 1.0 / mu, 1.0 / lam, system.tau

    def sample(t: Array, middle: float) -> Array:
        tt = t[:, None]
        end = Fa(np.clip(1.0 - mu * t, 0.0, 1.0)) if middle < t_v else q_dual * Fb(np.clip(lam * (t - t_v), 0.0, 1.0))
        front = np.minimum(mu * t, 1.0)  # a' left x = 0 at speed mu: transported F_a above, reflected b' below
        xi, g = _composite_rule(front, np.ones_like(t))
        total = end + np.sum(g * Laa(xi) * Fa(np.clip(xi - mu * tt, 0.0, 1.0)), axis=1)
        xi, g = _composite_rule(np.maximum(mu * (t - t_u), 0.0), front)
        total += np.sum(g * Laa(xi) * q_dual * Fb(np.clip(lam * (tt - xi / mu), 0.0, 1.0)), axis=1)
        xi, g = _composite_rule(np.zeros_like(t), np.maximum(1.0 - lam * t, 0.0))
        total += np.sum(g * Lab(xi) * Fb(np.clip(xi + lam * tt, 0.0, 1.0)), axis=1)
        if middle < t_u:
            total -= k * Lab(np.clip(1.0 - lam * t, 0.0, 1.0))
        elif middle < tau:
            total -= q * k * Laa(np.clip(mu * (t - t_u), 0.0, 1.0))
        return -mu * total

    return sample


def _breaks(system: Hyperbolic2x2) -> Array:
    """``0 < 1/lam, 1/mu < tau``: the ends of the smooth pieces of ``c``."""
    points = np.array([0.0, 1.0 / system.lam, 1.0 / system.mu, system.tau])
    return np.unique(np.round(points, 14))


def _pieces(sample: Callable[[Array, float], Array], breaks: Array) -> tuple[list[DistributedDelay], float]:
    """``c`` as polynomial pieces, one term per smooth piece starting at 0, and their largest deviation."""
    fit_t = 0.5 * (1.0 - np.cos((2.0 * np.arange(DEGREE + 1) + 1.0) * np.pi / (2.0 * (DEGREE + 1))))
    check_t = (np.arange(DEGREE) + 0.5) / DEGREE
    terms, deviation = [], 0.0
    for lo, hi in itertools.pairwise(breaks):
        count = max(1, int(np.ceil((hi - lo) * SEGMENTS_PER_UNIT)))
        cuts = np.linspace(lo, hi, count + 1)
        step = np.diff(cuts)
        middle = 0.5 * (lo + hi)
        values = sample((cuts[:-1, None] + step[:, None] * fit_t).ravel(), middle).reshape(count, -1)
        exact = sample((cuts[:-1, None] + step[:, None] * check_t).ravel(), middle).reshape(count, -1)
        # the Chebyshev series of every segment at once, then their exact conversion to powers of t in [0, 1]
        series = np.polynomial.chebyshev.chebfit(2.0 * fit_t - 1.0, values.T, DEGREE)
        coefficients = (shifted_chebyshev(DEGREE) @ series).T
        stored = coefficients @ np.polynomial.polynomial.polyvander(check_t, DEGREE).T
        deviation = max(deviation, float(np.max(np.abs(stored - exact))))
        terms.append(DistributedDelay(cuts - lo, None, interpolation="polynomial", coefficients=coefficients))
    return terms, deviation


def command_response(
    system: Hyperbolic2x2, law: FeedbackLaw, kernels: Kernels | None, kernel_grid: int
) -> tuple[QuasiPolynomial, list[DistributedDelay], float]:
    """``C_u(s) = k q e^{-tau s} + int_0^tau c(nu) e^{-nu s} dnu`` (module notes).

    Parameters
    ----------
    system : Hyperbolic2x2
        The observed plant.
    law : FeedbackLaw
        The unfiltered law ``U = k u(1) + int g_u u + g_v v`` on ``system``'s state.
    kernels : Kernels or None
        The kernels of :func:`dual_plant` (None on an uncoupled plant: ``K' = L' = 0``).
    kernel_grid : int
        The grid on which the law's gains are read (the kernels' grid when given).

    Returns
    -------
    tuple
        ``C_u``; the pieces of ``c``, each supported from 0 (the piece on ``[t_j, t_{j+1}]``
        shifted by ``-t_j``, the breakpoints ``0, 1/lam, 1/mu, tau`` in increasing order); their
        storage deviation.
    """
    n = kernel_grid if kernels is None else kernels.n
    pieces, deviation = _pieces(_response_sampler(system, law, kernels, n), _breaks(system))
    point = QuasiPolynomial([[law.boundary_gain * system.q]], [system.tau])
    shifted = [e for lo, term in zip(_breaks(system)[:-1], pieces, strict=True) for e in term.shift(float(lo))]
    return point + QuasiPolynomial([], [], shifted), pieces, deviation


def _times_response(
    system: Hyperbolic2x2, factor: QuasiPolynomial, k: float, pieces: Sequence[DistributedDelay], accuracy: float
) -> tuple[QuasiPolynomial, float]:
    """``factor * C`` for ``C = k q e^{-tau s} + int c e^{-nu s}`` stored as ``pieces``, and its estimated error.

    The point term by the product of quasi-polynomials, each piece of ``c`` by
    :func:`~nrobust.volterra.resolvent_product` (``accuracy``: the estimated error of ``c``).
    """
    product = factor * QuasiPolynomial([[k * system.q]], [system.tau])
    total_accuracy = 0.0
    empty = np.zeros((1, 1))  # no correction: the stored pieces are the kernel
    for lo, hi, term in zip(_breaks(system)[:-1], _breaks(system)[1:], pieces, strict=True):
        if term.is_zero:
            continue
        window = WindowKernel((term,), float(hi - lo), empty, accuracy)
        part = resolvent_product(factor.shift(float(lo)), window)
        product = product + part.product
        total_accuracy += part.accuracy
    return product, total_accuracy


@dataclass(frozen=True)
class CollocatedObserver:
    """The collocated observer on a plant, for a law: its gains, ``C_u`` and ``G = (1 - Phi) C_u``.

    Attributes
    ----------
    grid : ndarray
        The kernel grid of ``[0, 1]``.
    p_u, p_v : ndarray
        The output-injection gains on the grid (module notes).
    response : QuasiPolynomial
        ``C_u``: the law applied to the error driven by a command mismatch.
    product : QuasiPolynomial
        ``G = (1 - Phi) C_u``.
    accuracy : float
        An estimate (not a bound) of the sup-norm error of ``G``'s kernel: the change of ``c``
        from the grid with ``(kernel_grid + 1) / 2`` points times the weight of ``1 - Phi``, plus
        the storage deviations.
    """

    grid: Array
    p_u: Array
    p_v: Array
    response: QuasiPolynomial
    product: QuasiPolynomial
    accuracy: float


def collocated_observer(
    system: Hyperbolic2x2,
    law_on: Callable[[int], FeedbackLaw],
    open_loop: QuasiPolynomial,
    kernel_grid: int,
) -> CollocatedObserver:
    """The collocated observer's term ``G`` for the law ``law_on(grid)`` (module notes).

    Parameters
    ----------
    system : Hyperbolic2x2
        The observed plant (the paper's plant; a general plant is refused by the caller).
    law_on : callable
        ``grid -> FeedbackLaw``: the unfiltered law with its gains from kernels on ``grid`` points.
    open_loop : QuasiPolynomial
        ``1 - Phi`` (eq. (39)) of ``system``.
    kernel_grid : int
        Points of the kernel grids (the coarser grid of the accuracy estimate has
        ``(kernel_grid + 1) // 2`` points, at least
        :data:`~nrobust.hyperbolic.kernels.constant.MIN_KERNEL_GRID`).
    """
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem for a collocated observer", system)
    lam = system.lam
    coupled = not system.uncoupled
    coarse_grid = max((kernel_grid + 1) // 2, MIN_KERNEL_GRID)
    law = law_on(kernel_grid)
    response, pieces, deviation = _law_response(system, law, kernel_grid)
    _, coarse_pieces, _ = _law_response(system, law_on(coarse_grid), coarse_grid)
    change = 0.0
    for lo, hi, a, b in zip(_breaks(system)[:-1], _breaks(system)[1:], pieces, coarse_pieces, strict=True):
        nu = np.linspace(0.0, hi - lo, 65)
        change = max(change, float(np.max(np.abs(a.kernel_at(nu) - b.kernel_at(nu)))))
    accuracy = change + deviation
    product, total_accuracy = _times_response(system, open_loop, law.boundary_gain, pieces, accuracy)
    if coupled:
        grid, p_u, p_v = observer_gains(_dual_kernels(system, kernel_grid), lam)
    else:
        grid = np.linspace(0.0, 1.0, kernel_grid)
        p_u = p_v = np.zeros(kernel_grid)
    return CollocatedObserver(grid, p_u, p_v, response, product, total_accuracy)


def collocated_responses(
    system: Hyperbolic2x2, law: FeedbackLaw, kernel_grid: int
) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``(C_u, H_y)`` from the kernels of the dual plant on ``kernel_grid`` points alone.

    The responses of :func:`collocated_observer` and :func:`observer_reflection` without their
    products by ``1 - Phi`` and ``B~`` and without their accuracy estimates: the loop on a grid is
    known from them at a point, which is what a convergence study in the observer's grid needs.

    Parameters
    ----------
    system : Hyperbolic2x2
        The observed plant.
    law : FeedbackLaw
        The unfiltered law, its gains read on ``kernel_grid`` points.
    kernel_grid : int
        Points of the dual plant's kernel grid.
    """
    return _law_response(system, law, kernel_grid)[0], _law_response(system, _UNIT_LAW, kernel_grid)[0]


@lru_cache(maxsize=32)
def _law_response(
    system: Hyperbolic2x2, law: FeedbackLaw, kernel_grid: int
) -> tuple[QuasiPolynomial, tuple[DistributedDelay, ...], float]:
    """:func:`command_response` of ``law`` with the dual plant's kernels on ``kernel_grid`` points (none on an
    uncoupled plant): the response, its pieces and their deviation.

    Cached (a law is its own key: its gains compare by identity): the observer's term and its accuracy
    estimate, the observer's reflection (the law ``U = u(t, 1)``, whose response ``H_y`` depends on the
    plant and the grid alone) and the convergence study in the observer's grid ask for the same grids.
    """
    kernels = None if system.uncoupled else _dual_kernels(system, kernel_grid)
    response, pieces, deviation = command_response(system, law, kernels, kernel_grid)
    return response, tuple(pieces), deviation


def _zero_gain(x: Array) -> Array:
    return np.zeros_like(np.asarray(x, dtype=float))


#: The law ``U = u(t, 1)``, whose response through the error system is ``H_y``.
_UNIT_LAW = FeedbackLaw(1.0, _zero_gain, _zero_gain)


@dataclass(frozen=True)
class ObserverReflection:
    """The terms of an observer that keeps the reflection ``kappa`` (module notes).

    Attributes
    ----------
    response : QuasiPolynomial
        ``H_y``: the output error ``u~(t, 1)`` driven by ``v~(t, 1) = W`` in the error system of
        ``kappa = 0`` (:func:`command_response` of the law ``U = u(t, 1)``); the error's
        characteristic function is ``E = 1 - kappa H_y``.
    open_loop_product, law_product : QuasiPolynomial
        ``(1 - Phi) H_y`` and ``B~ H_y`` (``B~`` the unfiltered law's factor ``B``).
    accuracy : float
        An estimate (not a bound) of the sup-norm error of the products' kernels, as
        :attr:`CollocatedObserver.accuracy` (0 on an uncoupled plant: ``H_y = q e^{-tau s}``); a proven bound
        where the products are closed forms enclosed in ball arithmetic
        (:func:`~nrobust.hyperbolic.loops.controllers.observer_reflection_of`).
    """

    response: QuasiPolynomial
    open_loop_product: QuasiPolynomial
    law_product: QuasiPolynomial
    accuracy: float


def observer_reflection(
    system: Hyperbolic2x2, open_loop: QuasiPolynomial, law_factor: QuasiPolynomial, kernel_grid: int
) -> ObserverReflection:
    """``H_y``, ``(1 - Phi) H_y`` and ``B~ H_y`` of the collocated observer (module notes).

    Parameters
    ----------
    system : Hyperbolic2x2
        The observed plant.
    open_loop : QuasiPolynomial
        ``1 - Phi`` (eq. (39)) of ``system``.
    law_factor : QuasiPolynomial
        ``B~``: the factor ``B`` of the unfiltered law (real constant point coefficients and
        plain distributed terms).
    kernel_grid : int
        Points of the dual plant's kernel grid (the accuracy estimate, as
        :func:`collocated_observer`, from the grid with ``(kernel_grid + 1) / 2`` points).
    """
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem for a collocated observer", system)
    if system.uncoupled:
        response = QuasiPolynomial([[system.q]], [system.tau])
        return ObserverReflection(response, open_loop * response, law_factor * response, 0.0)
    coarse_grid = max((kernel_grid + 1) // 2, MIN_KERNEL_GRID)
    response, pieces, deviation = _law_response(system, _UNIT_LAW, kernel_grid)
    _, coarse_pieces, _ = _law_response(system, _UNIT_LAW, coarse_grid)
    change = 0.0
    for lo, hi, a, b in zip(_breaks(system)[:-1], _breaks(system)[1:], pieces, coarse_pieces, strict=True):
        nu = np.linspace(0.0, hi - lo, 65)
        change = max(change, float(np.max(np.abs(a.kernel_at(nu) - b.kernel_at(nu)))))
    open_product, open_accuracy = _times_response(system, open_loop, 1.0, pieces, change + deviation)
    law_product, law_accuracy = _times_response(system, law_factor, 1.0, pieces, change + deviation)
    return ObserverReflection(response, open_product, law_product, max(open_accuracy, law_accuracy))


def reflection_factors(
    A: QuasiPolynomial,
    B: QuasiPolynomial,
    reflection: ObserverReflection,
    kappa: float,
    numerator: tuple[float, ...] = (1.0,),
    denominator: tuple[float, ...] = (1.0,),
) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``(E A, E B)`` with ``E = 1 - kappa H_y``: the state feedback's factors times the error's function.

    ``A = d (1 - Phi)`` and ``B = n B~`` for a law filtered by ``n/d`` (``numerator``,
    ``denominator``: increasing powers); the collocated loop is then
    :func:`~nrobust.hyperbolic.loops.output_feedback.output_feedback_factors` of these and ``G``.
    """
    if kappa == 0.0:
        return A, B
    return (
        A - reflection.open_loop_product.times_poly(list(denominator)) * kappa,
        B - reflection.law_product.times_poly(list(numerator)) * kappa,
    )
