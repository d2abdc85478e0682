"""Backstepping kernels of the Volterra transformation and of its inverse.

The transformation (22)-(23) maps ``(u, v)`` to the target system
(32)-(34) when ``K = [[K^{uu}, K^{uv}], [K^{vu}, K^{vv}]]`` solves, on the
triangle ``T = {0 <= xi <= x <= 1}``, eqs. (24)-(29)::

    lam (K^{uu}_x + K^{uu}_xi)  = -sigma_mp(xi) K^{uv},     K^{uv}(x, 0) = (lam q / mu) K^{uu}(x, 0),
    lam K^{uv}_x - mu K^{uv}_xi = -sigma_pm(xi) K^{uu},     K^{uv}(x, x) =  sigma_pm(x) / (lam + mu),
    mu K^{vu}_x - lam K^{vu}_xi =  sigma_mp(xi) K^{vv},     K^{vu}(x, x) = -sigma_mp(x) / (lam + mu),
    mu (K^{vv}_x + K^{vv}_xi)   =  sigma_pm(xi) K^{vu},     K^{vv}(x, 0) = (lam q / mu) K^{vu}(x, 0).

The system splits into two independent pairs, ``(K^{uu}, K^{uv})`` and
``(K^{vv}, K^{vu})``, each made of a kernel transported along the diagonal direction
``(1, 1)`` and a kernel transported along ``(1, -kappa)`` with ``kappa = mu/lam`` (resp.
``lam/mu``). Both pairs are solved by one marching scheme in ``x`` (see
:func:`_march_pair`): trapezoidal integration of the sources along the characteristics,
solved exactly at the new level (a 2x2 linear system per node), with cubic Lagrange
interpolation at the feet of the characteristics that are not grid-aligned
(``lam != mu``). The scheme is second-order convergent for smooth couplings.

The inverse kernels ``L`` of (30)-(31) are computed from ``K`` through the
Volterra resolvent identity ``L = K + K o L``, i.e.
``L(x, xi) = K(x, xi) + int_xi^x K(x, s) L(s, xi) ds``, discretised with the trapezoidal
rule on the same grid (second order) and solved as one block-triangular linear system.

By default (odd ``kernel_grid``) both tables are Richardson-extrapolated with the solution
on every other node, which raises the observed order to about three.

:data:`DEFAULT_KERNEL_GRID` is the one default kernel grid of the package: the delay
form, the loop factors, the delay margins and the Rouché bound all use it unless given
``kernel_grid=``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Any

import numpy as np

from ..._json import json_safe
from ..._validate import positive_int, renamed_keywords
from ...errors import ParameterError
from ..plants.hyperbolic2x2 import Hyperbolic2x2

__all__ = ["DEFAULT_KERNEL_GRID", "MAX_KERNEL_GRID", "MIN_KERNEL_GRID", "Kernels", "check_kernel_grid", "solve_kernels"]

#: Default kernel grid (points per direction on ``[0, 1]``) of every function that solves
#: kernels. Measured on the paper's plant ``Hyperbolic2x2(1, 1, 1, 1, 1, 0.85)`` with
#: ``ReflectionController(0.1)`` (``docs/architecture.md``, "Accuracy budget"): the delay
#: margin 0.2295391303 is within 1.5e-10 of its 801-point value at 201 points (1.7e-11 at
#: 401), and ``loop_factors`` costs 0.13-0.4 s at 201 points against 0.44-0.9 s at 401.
DEFAULT_KERNEL_GRID = 201
#: Largest kernel grid (work bound, checked before any table is allocated): the inverse
#: kernels solve a dense triangular system of size ``2 kernel_grid``, about 0.8 GB of
#: work arrays at 1601 points (the finest grid of ``benchmarks/kernels.py``).
MAX_KERNEL_GRID = 1601
#: Smallest kernel grid of every kernel solver: the cubic interpolation at the feet of the
#: characteristics reads four nodes of a level, and the default Richardson extrapolation
#: takes every other node of an odd grid (five points at least).
MIN_KERNEL_GRID = 5
#: Resolution bound of the marching scheme: the grid step times the largest source
#: coefficient ``max |sigma| / min(lam, mu)`` must not exceed this. Measured on
#: ``Hyperbolic2x2(lam, 1, 1, 1, 1, 0.85)`` against 1601 points: relative error of the
#: traces ``K(1, xi)`` 1.4e-2 to 1.4e-1 at 1/8, 0.13 to 0.42 at 1/4, 0.7 to 1 from 1/2 on
#: (and overflow far beyond): past the bound the tables carry no information.
RESOLUTION = 0.25

Array = np.ndarray
Fun = Callable[[Array], Array]

# Relative tolerance deciding whether a characteristic foot is inside the triangle.
_FOOT_TOL = 1e-12
# Tolerance on the triangle 0 <= xi <= x <= 1 when evaluating kernels.
_DOMAIN_TOL = 1e-12

#: Feet whose Lagrange weights are computed in Python floats (:func:`_lagrange_weights`).
_FEW_FEET = 8

_K_NAMES = {"Kuu": (0, 0), "Kuv": (0, 1), "Kvu": (1, 0), "Kvv": (1, 1)}
_L_NAMES = {"Laa": (0, 0), "Lab": (0, 1), "Lba": (1, 0), "Lbb": (1, 1)}


def _lagrange_weights(t: Array, order: int) -> Array:
    """Lagrange weights of the nodes ``0, ..., order-1`` at the points ``t``, shape ``(len(t), order)``.

    A few points (the feet shifted inwards at the end of each level of the march) in Python floats: the same
    operations in the same order, so the same numbers, without the cost of numpy's calls on tiny arrays.
    """
    if t.size <= _FEW_FEET:
        return np.array(
            [[math.prod((x - m) / (k - m) for m in range(order) if m != k) for k in range(order)] for x in t.tolist()],
            dtype=float,
        ).reshape(t.size, order)
    w = np.ones((t.size, order))
    for k in range(order):
        for m in range(order):
            if m != k:
                w[:, k] *= (t - m) / (k - m)
    return w


class _CubicFeet:
    """Cubic Lagrange stencils for the feet of the cross characteristics, in units of ``h``.

    ``positions[j]`` is the foot of node ``j`` at the previous level: ``j + kappa`` for
    constant speeds, any increasing sequence for varying ones
    (:mod:`~nrobust.hyperbolic.kernels.varying`). The stencil of foot ``j`` is the four
    nodes around it; at level ``i - 1`` (nodes ``0, ..., i - 1``) it is shifted inwards
    where it would pass the last node. The unshifted weights are computed once; only
    shifted rows are recomputed per level.
    """

    def __init__(self, positions: Array) -> None:
        self.positions = np.asarray(positions, dtype=float)
        self.start = np.maximum(np.floor(self.positions + _FOOT_TOL).astype(int) - 1, 0)
        self.weights = _lagrange_weights(self.positions - self.start, 4)

    def stencil(self, count: int, last: int) -> tuple[Array, Array]:
        """Indices and weights, shape ``(count, 4)``, of the first ``count`` feet on nodes ``0..last``."""
        start = self.start[:count]
        weights = self.weights[:count]
        shifted = start > last - 3
        if np.any(shifted):
            start = np.minimum(start, last - 3)
            weights = weights.copy()
            weights[shifted] = _lagrange_weights(self.positions[:count][shifted] - start[shifted], 4)
        return start[:, None] + np.arange(4), weights


def _march_pair(n: int, a: Fun, b: Fun, kappa: float, g: Fun, r: float) -> tuple[Array, Array]:
    """Solve one pair of kernel equations on the uniform triangle grid with ``n`` points.

    The pair is::

        (d/dx + d/dxi) A = a(xi) B,           A(x, 0) = r B(x, 0),
        (d/dx - kappa d/dxi) B = b(xi) A,     B(x, x) = g(x),

    i.e. ``A`` is transported along ``(1, 1)`` from ``xi = 0`` and ``B`` along
    ``(1, -kappa)`` from the diagonal. The solution is marched in ``x``: at level ``x_i``,
    ``A(x_i, xi_j)`` is integrated from ``(x_{i-1}, xi_{j-1})`` and ``B(x_i, xi_j)`` from its
    foot ``(x_{i-1}, xi_j + kappa h)`` (cubic interpolation at level ``i-1``) or, within
    one step of the diagonal, from the point where the characteristic leaves the diagonal
    (``A`` there is interpolated linearly along the diagonal); on the first three levels,
    where fewer than four nodes are available, every cross characteristic starts from
    the diagonal. The sources are
    integrated with the trapezoidal rule; the implicit terms make a 2x2 linear system per
    node, solved in closed form.

    Returns
    -------
    A, B : ndarray, shape (n, n)
        ``A[i, j]`` approximates ``A(x_i, xi_j)`` for ``j <= i``; zero above the diagonal.
    """
    h = 1.0 / (n - 1)
    x = np.linspace(0.0, 1.0, n)

    def leave(i: int, jn: Array) -> tuple[Array, Array, Array]:
        t_star = (i - jn) * h / (1.0 + kappa)  # the cross characteristic meets the diagonal at x_i - t_star
        return t_star, x[i] - t_star, x[i] - t_star

    return march_levels(x, a, b, g, r, np.arange(n) + kappa, b(np.minimum(x + kappa * h, 1.0)), x, leave)


def march_levels(
    grid: Array,
    a: Fun,
    b: Fun,
    g: Fun,
    r: float,
    positions: Array,
    b_foot: Array,
    points: Array,
    leave: Callable[[int, Array], tuple[Array, Array, Array]],
) -> tuple[Array, Array]:
    """The level march of :func:`_march_pair`, its feet and physical points given.

    ``grid`` is the uniform level variable (step ``h``), ``points`` the physical points of
    its nodes (where ``a``, ``b`` and ``g`` are evaluated), ``positions[j]`` the foot of node
    ``j`` at the previous level in units of ``h`` (increasing; ``inf`` past the last node),
    ``b_foot[j]`` the value of ``b`` there, and ``leave(i, jn)`` the step ``t*`` from the
    diagonal and the point where the cross characteristic of nodes ``jn`` of level ``i``
    leaves it, in the level variable (to interpolate ``A`` along the diagonal) and as a
    physical point (where ``g`` and ``b`` are taken). Constant speeds (:func:`_march_pair`) and varying ones
    (:mod:`~nrobust.hyperbolic.kernels.varying`) share it.
    """
    n = grid.size
    h = float(grid[1] - grid[0])
    a_x, b_x, g_x = a(points), b(points), g(points)
    feet = _CubicFeet(np.minimum(positions, n - 1.0))
    A = np.zeros((n, n))
    B = np.zeros((n, n))
    B[0, 0] = g_x[0]
    A[0, 0] = r * g_x[0]
    for i in range(1, n):
        A_prev, B_prev = A[i - 1, :i], B[i - 1, :i]
        B[i, i] = g_x[i]
        A[i, i] = A_prev[i - 1] + 0.5 * h * (a_x[i - 1] * B_prev[i - 1] + a_x[i] * g_x[i])
        # Diagonal kernel: A_new = alpha0 + c1 * B_new (A_new = r B_new at xi = 0).
        alpha0 = np.zeros(i)
        c1 = np.full(i, r)
        alpha0[1:] = A_prev[:-1] + 0.5 * h * a_x[: i - 1] * B_prev[:-1]
        c1[1:] = 0.5 * h * a_x[1:i]
        # Cross kernel: B_new = beta0 + c2 * A_new. On the first levels, where fewer
        # than four nodes are available for the cubic foot interpolation, every
        # characteristic is integrated from the diagonal (length <= 3h, local error O(h^3)).
        beta0 = np.empty(i)
        c2 = np.empty(i)
        n_reg = int(np.searchsorted(positions[:i], i - 1 + _FOOT_TOL, side="right")) if i >= 4 else 0
        if n_reg:
            idx, w = feet.stencil(n_reg, i - 1)
            A_foot = np.sum(A_prev[idx] * w, axis=1)
            B_foot = np.sum(B_prev[idx] * w, axis=1)
            beta0[:n_reg] = B_foot + 0.5 * h * b_foot[:n_reg] * A_foot
            c2[:n_reg] = 0.5 * h * b_x[:n_reg]
        jn = np.arange(n_reg, i)
        t_star, at, x_star = leave(i, jn)
        A_diag = np.interp(at, grid[: i + 1], np.diagonal(A)[: i + 1])
        beta0[jn] = g(x_star) + 0.5 * t_star * b(x_star) * A_diag
        c2[jn] = 0.5 * t_star * b_x[jn]
        B[i, :i] = (beta0 + c2 * alpha0) / (1.0 - c1 * c2)
        A[i, :i] = alpha0 + c1 * B[i, :i]
    return A, B


def _solve_K(system: Hyperbolic2x2, n: int) -> Array:
    """Kernels ``K`` of eqs. (24)-(29), shape ``(2, 2, n, n)``."""
    lam, mu, q = system.lam, system.mu, system.q
    K = np.zeros((2, 2, n, n))
    if system.uncoupled:
        return K
    pm, mp = system.sigma_pm_at, system.sigma_mp_at
    s = lam + mu
    # Pair (K^{uu}, K^{uv}), divided by lam: slope kappa = mu / lam.
    K[0, 0], K[0, 1] = _march_pair(
        n,
        a=lambda xi: -mp(xi) / lam,
        b=lambda xi: -pm(xi) / lam,
        kappa=mu / lam,
        g=lambda x: pm(x) / s,
        r=mu / (lam * q),
    )
    # Pair (K^{vv}, K^{vu}), divided by mu: slope kappa = lam / mu.
    K[1, 1], K[1, 0] = _march_pair(
        n,
        a=lambda xi: pm(xi) / mu,
        b=lambda xi: mp(xi) / mu,
        kappa=lam / mu,
        g=lambda x: -mp(x) / s,
        r=lam * q / mu,
    )
    return K


def resolvent(K: Array) -> Array:
    """Inverse kernels from the resolvent identity ``L = K + K o L`` (trapezoidal rule).

    For ``i > k`` the trapezoidal rule on ``[xi_k, x_i]`` gives::

        L_ik = K_ik + h (1/2 K_ik L_kk + sum_{k<m<i} K_im L_mk + 1/2 K_ii L_ik),

    with 2x2 blocks ``K_im = K(x_i, x_m)`` and ``L_kk = K_kk`` (the integral vanishes on
    the diagonal). With ``Lam_mk = L_mk`` for ``m > k`` and ``Lam_kk = L_kk / 2``, these
    equations for all ``(i, k)`` are the block lower-triangular system
    ``(I - K_h) Lam = R``, ``K_h[i, m] = h K_im`` for ``m < i`` and ``h/2 K_ii`` for
    ``m = i``, ``R_ik = K_ik`` for ``i > k`` and ``R_kk = (I - h/2 K_kk) K_kk / 2`` (which
    returns ``Lam_kk = K_kk / 2``). Scaled by the inverse diagonal blocks it is unit
    lower triangular and is solved at once by numpy's LU solve: 15 ms at the default 201
    points, where scipy's triangular solve would add its 0.15-0.4 s import to a simulation.
    """
    n = K.shape[-1]
    h = 1.0 / (n - 1)
    eye2 = np.eye(2)
    Kb = K.transpose(2, 0, 3, 1).reshape(2 * n, 2 * n)  # Kb[2i + a, 2m + b] = K^{ab}(x_i, xi_m)
    W = np.tril(np.full((n, n), h), -1) + np.diag(np.full(n, 0.5 * h))
    Wb = np.repeat(np.repeat(W, 2, axis=0), 2, axis=1)
    lower = np.repeat(np.repeat(np.tri(n, n, -1), 2, axis=0), 2, axis=1)
    R = Kb * lower
    diag = np.arange(n)
    Kd = K[:, :, diag, diag].transpose(2, 0, 1)  # (n, 2, 2)
    Rd = np.einsum("kab,kbc->kac", eye2 - 0.5 * h * Kd, 0.5 * Kd)
    for k in range(n):
        R[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = Rd[k]
    # Scale by the inverse diagonal blocks: the system becomes unit lower triangular.
    D_inv = np.linalg.inv(eye2 - 0.5 * h * Kd)
    M = np.einsum("kab,kbj->kaj", D_inv, (np.eye(2 * n) - Kb * Wb).reshape(n, 2, 2 * n))
    R = np.einsum("kab,kbj->kaj", D_inv, R.reshape(n, 2, 2 * n))
    Lam = np.linalg.solve(M.reshape(2 * n, 2 * n), R.reshape(2 * n, 2 * n))
    L = Lam.reshape(n, 2, n, 2).transpose(1, 3, 0, 2) * np.tri(n)
    L[:, :, diag, diag] = K[:, :, diag, diag]
    return L


def p1_interpolate(table: Array, x: Array, xi: Array) -> Array:
    """Piecewise-linear interpolation on the triangulated grid (cells split along ``(1, 1)``).

    Every triangle used has its three vertices in ``0 <= xi <= x``, so no value above the
    diagonal is read. Second-order accurate for smooth kernels.
    """
    n = table.shape[-1]
    h = 1.0 / (n - 1)
    i = np.minimum(np.floor(x / h).astype(int), n - 2)
    j = np.minimum(np.floor(xi / h).astype(int), n - 2)
    j = np.minimum(j, i)
    fx = x / h - i
    fxi = xi / h - j
    f00 = table[i, j]
    f11 = table[i + 1, j + 1]
    lower = fx >= fxi
    f10 = table[i + 1, j]
    f01 = table[i, np.minimum(j + 1, i)]
    out_lower = f00 + fx * (f10 - f00) + fxi * (f11 - f10)
    out_upper = f00 + fxi * (f01 - f00) + fx * (f11 - f01)
    return np.where(lower, out_lower, out_upper)


@dataclass(frozen=True, repr=False, eq=False)
class Kernels:
    """Backstepping kernels ``K`` (eqs. (24)-(29)) and inverse kernels ``L``
    (eqs. (30)-(31)) tabulated on a uniform grid of the triangle.

    Attributes
    ----------
    system : Hyperbolic2x2
        The plant the kernels belong to.
    grid : ndarray, shape (n,)
        Uniform nodes ``x_i = xi_i = i / (n - 1)``.
    K, L : ndarray, shape (2, 2, n, n)
        ``K[a, b, i, j]`` is ``K^{ab}(x_i, xi_j)`` with ``a, b`` in ``(u, v)``, and
        ``L[a, b, i, j]`` is ``L^{ab}(x_i, xi_j)`` with ``a, b`` in ``(alpha, beta)``,
        for ``j <= i``; entries above the diagonal are zero.

    Notes
    -----
    ``Kuu(x, xi)``, ..., ``Lbb(x, xi)`` evaluate the kernels at arrays of points of the
    triangle by piecewise-linear interpolation on the triangulated grid (second order).
    """

    system: Hyperbolic2x2
    grid: Array
    K: Array
    L: Array
    method: str = field(default="")

    @property
    def n(self) -> int:
        """Number of grid points per direction."""
        return int(self.grid.size)

    @property
    def h(self) -> float:
        """Grid step ``1 / (n - 1)``."""
        return 1.0 / (self.grid.size - 1)

    def _evaluate(self, table: Array, x: Any, xi: Any) -> Array:
        x_arr, xi_arr = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(xi, dtype=float))
        inside = (xi_arr >= -_DOMAIN_TOL) & (xi_arr <= x_arr + _DOMAIN_TOL) & (x_arr <= 1.0 + _DOMAIN_TOL)
        if not np.all(inside):
            bad = (x_arr[~inside].flat[0], xi_arr[~inside].flat[0])
            raise ParameterError("(x, xi)", "in the triangle 0 <= xi <= x <= 1", bad)
        x_c = np.clip(x_arr, 0.0, 1.0)
        xi_c = np.clip(xi_arr, 0.0, x_c)
        return p1_interpolate(table, x_c, xi_c)

    def Kuu(self, x: Any, xi: Any) -> Array:
        """``K^{uu}(x, xi)`` on arrays of points of the triangle."""
        return self._evaluate(self.K[0, 0], x, xi)

    def Kuv(self, x: Any, xi: Any) -> Array:
        """``K^{uv}(x, xi)`` on arrays of points of the triangle."""
        return self._evaluate(self.K[0, 1], x, xi)

    def Kvu(self, x: Any, xi: Any) -> Array:
        """``K^{vu}(x, xi)`` on arrays of points of the triangle."""
        return self._evaluate(self.K[1, 0], x, xi)

    def Kvv(self, x: Any, xi: Any) -> Array:
        """``K^{vv}(x, xi)`` on arrays of points of the triangle."""
        return self._evaluate(self.K[1, 1], x, xi)

    def Laa(self, x: Any, xi: Any) -> Array:
        """``L^{alpha alpha}(x, xi)`` on arrays of points of the triangle."""
        return self._evaluate(self.L[0, 0], x, xi)

    def Lab(self, x: Any, xi: Any) -> Array:
        """``L^{alpha beta}(x, xi)`` on arrays of points of the triangle."""
        return self._evaluate(self.L[0, 1], x, xi)

    def Lba(self, x: Any, xi: Any) -> Array:
        """``L^{beta alpha}(x, xi)`` on arrays of points of the triangle."""
        return self._evaluate(self.L[1, 0], x, xi)

    def Lbb(self, x: Any, xi: Any) -> Array:
        """``L^{beta beta}(x, xi)`` on arrays of points of the triangle."""
        return self._evaluate(self.L[1, 1], x, xi)

    def __repr__(self) -> str:
        return f"Kernels(system={self.system!r}, n={self.n}, method={self.method!r})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary: the system, the grid, and every kernel's trace at ``x = 1``.

        The traces ``K^{ab}(1, xi)`` and ``L^{ab}(1, xi)`` on the grid are what the
        boundary controllers and the delay form use.
        """
        traces = {name: self.K[a, b, -1] for name, (a, b) in _K_NAMES.items()}
        traces.update({name: self.L[a, b, -1] for name, (a, b) in _L_NAMES.items()})
        return json_safe(
            {
                "type": "Kernels",
                "system": self.system,
                "n": self.n,
                "method": self.method,
                "xi": self.grid,
                "trace_x1": traces,
            }
        )


def _solve_grid(system: Hyperbolic2x2, n: int) -> tuple[Array, Array]:
    """``K`` and ``L`` on the grid with ``n`` points, second order (read-only when kept: :func:`_kept_grid`)."""
    if n <= _KEPT_GRID:
        return _kept_grid(_kernel_plant(system), n)
    K = _solve_K(system, n)
    return K, resolvent(K)


def _kernel_plant(system: Hyperbolic2x2) -> Hyperbolic2x2:
    """``system`` with ``rho = 0``, the key of its kept kernels: eqs. (24)-(29) hold the speeds, the couplings and
    ``q``, not the proximal reflection, so plants that differ only in it share one solution (on the paper's plant,
    ``lam = mu`` and ``q = 1``, the plant and the dual plant of its collocated observer). A subclass keeps its own
    key: its couplings might read ``rho``."""
    return system if system.rho == 0.0 or type(system) is not Hyperbolic2x2 else replace(system, rho=0.0)


#: Largest grid whose plain solution :func:`_kept_grid` keeps: the coarse half of an extrapolated solve is the
#: fine grid of the solve on that grid (the collocated observer solves 201 and 101 points, for its accuracy
#: estimate), about 2.6 MB at 201 points.
_KEPT_GRID = DEFAULT_KERNEL_GRID


@lru_cache(maxsize=8)
def _kept_grid(system: Hyperbolic2x2, n: int) -> tuple[Array, Array]:
    """:func:`_solve_grid` on a grid of at most :data:`_KEPT_GRID` points, read-only and kept."""
    K = _solve_K(system, n)
    L = resolvent(K)
    K.flags.writeable = L.flags.writeable = False
    return K, L


def _richardson(fine: Array, coarse: Array) -> Array:
    """Richardson extrapolation ``F_h + (F_h - F_2h)/3`` of second-order tables ``(2, 2, n, n)``.

    The correction is known on the coarse nodes; it is carried to the fine nodes by
    piecewise-linear interpolation on the triangulated coarse grid (cells split along
    ``(1, 1)``): a fine node between two coarse nodes takes their mean. The correction is
    ``O(h^2)`` and smooth, so the interpolation adds ``O(h^4)``.
    """
    n = fine.shape[-1]
    c = (fine[:, :, ::2, ::2] - coarse) / 3.0
    up = np.zeros_like(fine)
    up[:, :, ::2, ::2] = c
    up[:, :, 1::2, ::2] = 0.5 * (c[:, :, :-1, :] + c[:, :, 1:, :])
    up[:, :, ::2, 1::2] = 0.5 * (c[:, :, :, :-1] + c[:, :, :, 1:])
    up[:, :, 1::2, 1::2] = 0.5 * (c[:, :, :-1, :-1] + c[:, :, 1:, 1:])
    return fine + up * np.tri(n)


def check_kernel_grid(kernel_grid: Any, maximum: int = MAX_KERNEL_GRID) -> int:
    """The kernel grid ``kernel_grid`` validated: an integer in ``[MIN_KERNEL_GRID, maximum]``.

    The one check of the package's kernel grids (constant and varying speeds, ``n + m``
    systems, and every analysis or simulation that solves kernels), run once at each
    public entry point.

    Parameters
    ----------
    kernel_grid : int
        Grid points per direction.
    maximum : int, default :data:`MAX_KERNEL_GRID`
        Work bound of the solver.

    Raises
    ------
    ParameterError
        Not an integer, below :data:`MIN_KERNEL_GRID` or above ``maximum`` (named ``kernel_grid``).

    Examples
    --------
    >>> check_kernel_grid(201)
    201
    """
    return positive_int("kernel_grid", kernel_grid, minimum=MIN_KERNEL_GRID, maximum=maximum)


def _check_resolution(system: Hyperbolic2x2, n: int) -> None:
    """Refuse a grid too coarse for the couplings, before any table is allocated.

    The marching scheme resolves the sources ``sigma / lam`` and ``sigma / mu`` only when
    ``h max|sigma| / min(lam, mu) <= RESOLUTION`` (``h = 1 / (n - 1)``; ``max|sigma|`` on the
    grid). When even :data:`MAX_KERNEL_GRID` points cannot do it, the slower speed is
    named with its admissible range; otherwise ``kernel_grid`` with the size needed.
    """
    if system.uncoupled:
        return
    x = np.linspace(0.0, 1.0, n)
    sigma = float(max(np.max(np.abs(system.sigma_pm_at(x))), np.max(np.abs(system.sigma_mp_at(x)))))
    slow, speed = ("lam", system.lam) if system.lam <= system.mu else ("mu", system.mu)
    with np.errstate(over="ignore"):
        steps = sigma / (speed * RESOLUTION)  # h <= 1 / steps
    if steps <= n - 1:
        return
    if steps > MAX_KERNEL_GRID - 1:
        raise ParameterError(
            slow,
            f">= {sigma / (RESOLUTION * (MAX_KERNEL_GRID - 1)):.6g} for couplings up to |sigma| = {sigma:.6g} "
            f"(min(lam, mu) >= max|sigma| / ({RESOLUTION:g} (kernel_grid - 1)) resolves the kernel equations, "
            f"and kernel_grid is at most MAX_KERNEL_GRID = {MAX_KERNEL_GRID})",
            speed,
        )
    raise ParameterError(
        "kernel_grid",
        f">= {math.ceil(steps) + 1} for couplings up to |sigma| = {sigma:.6g} and min(lam, mu) = {speed:.6g} "
        f"(grid step times max|sigma| / min(lam, mu) at most {RESOLUTION:g})",
        n,
    )


@renamed_keywords(n="kernel_grid")
def solve_kernels(
    system: Hyperbolic2x2, kernel_grid: int = DEFAULT_KERNEL_GRID, extrapolate: bool | None = None
) -> Kernels:
    """Solve the kernel equations (24)-(29) and the inverse kernels.

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant, eqs. (18)-(20).
    kernel_grid : int, default :data:`DEFAULT_KERNEL_GRID`
        Grid points per direction on ``[0, 1]`` (step ``h = 1 / (kernel_grid - 1)``),
        ``>=`` :data:`MIN_KERNEL_GRID` and ``<=`` :data:`MAX_KERNEL_GRID`; odd when ``extrapolate`` is True;
        fine enough for the couplings (``(kernel_grid - 1) RESOLUTION >= max|sigma| /
        min(lam, mu)``, see :data:`RESOLUTION`). (Formerly ``n``, a deprecated alias.)
    extrapolate : bool, optional
        Combine the solutions on the grids with ``kernel_grid`` and ``(kernel_grid + 1) / 2``
        points by Richardson extrapolation. The plain scheme is second order; the
        extrapolated values converge faster (about third order observed) and cost about
        1.3 times the plain solve. Default: extrapolate when ``kernel_grid`` is odd and
        ``>= 5``.

    Returns
    -------
    Kernels
        ``K`` and ``L`` on the grid, evaluable at arrays of points of the triangle.

    Raises
    ------
    ParameterError
        If ``system`` is not a :class:`Hyperbolic2x2`, or ``kernel_grid`` is too small for
        the couplings, above :data:`MAX_KERNEL_GRID`, or even while ``extrapolate`` is
        True; ``lam`` (or ``mu``) when no admissible grid resolves the couplings (a
        speed below ``max|sigma| / (RESOLUTION (MAX_KERNEL_GRID - 1))``).

    Notes
    -----
    Convergence and timings are in ``docs/numerics_kernels.md`` and
    ``benchmarks/kernels.py``.
    """
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2", system)
    n = check_kernel_grid(kernel_grid)
    _check_resolution(system, n)
    if extrapolate is None:
        extrapolate = n % 2 == 1 and n >= 5
    if extrapolate and (n % 2 == 0 or n < 5):
        raise ParameterError(
            "kernel_grid", "odd and >= 5 when extrapolate=True (the coarse grid takes every other node)", n
        )
    K, L = _solve_grid(system, n)
    method = "characteristics, trapezoid + cubic feet; trapezoidal resolvent"
    if extrapolate:
        K_coarse, L_coarse = _solve_grid(system, (n + 1) // 2)
        K, L = _richardson(K, K_coarse), _richardson(L, L_coarse)
        method += "; Richardson-extrapolated"
    elif not K.flags.writeable:  # a kept solution: the caller's own copy
        K, L = K.copy(), L.copy()
    if not (np.all(np.isfinite(K)) and np.all(np.isfinite(L))):
        raise ParameterError("kernel_grid", "large enough for the kernel scheme to be well posed", n)
    return Kernels(system=system, grid=np.linspace(0.0, 1.0, n), K=K, L=L, method=method)
