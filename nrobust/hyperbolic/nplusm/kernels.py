"""Backstepping kernels and the full-state controller of ``n + m`` systems (constant coefficients).

The plant is :class:`~nrobust.hyperbolic.nplusm.NPlusMSystem`::

    u_t + Lambda+ u_x = Sigma++ u + Sigma+- v,     u(t, 0) = Q v(t, 0),
    v_t - Lambda- v_x = Sigma-+ u + Sigma-- v,     v(t, 1) = R u(t, 1) + U(t).

**Transformation and target.** The design of Hu, Di Meglio, Vazquez and Krstic, "Control of
homodirectional and general heterodirectional linear coupled hyperbolic PDEs", IEEE
Trans. Automatic Control 61(11), 3301-3314, 2016: the Volterra transformation ``alpha = u``,
``beta = v - int_0^x K(x, xi) u(xi) + L(x, xi) v(xi) dxi`` (``K``: ``m x n``, ``L``:
``m x m``) maps the plant onto the target system ::

    beta_t - Lambda- beta_x = D beta + G(x) beta(t, 0),     beta(t, 1) = 0,

(``alpha`` keeps the plant's equation with Volterra terms in ``alpha`` and ``beta``) when,
on the triangle ``T = {0 <= xi <= x <= 1}``, with ``Z = [K, L]`` (``m x (n + m)``), ::

    Lambda- K_x - K_xi Lambda+ = K Sigma++ + L Sigma-+ - D K,
    Lambda- L_x + L_xi Lambda- = K Sigma+- + L Sigma-- - D L,
    Lambda- K(x, x) + K(x, x) Lambda+ = -Sigma-+,
    Lambda- L(x, x) - L(x, x) Lambda- = -(Sigma-- - D),
    L(x, 0) Lambda- - K(x, 0) Lambda+ Q = G(x).

(derived here for this plant by substituting the transformation). ``D`` is the part of
``Sigma--`` inside groups of equal speed ``mu`` (the diagonal included), which the
transformation cannot remove (the diagonal relation is void there); it stays in the
target, where a group still moves as one transport equation. ``K_ij`` is transported
along ``(mu_i, -lam_j)`` from the diagonal; ``L_ij`` along ``(mu_i, mu_j)``: from
``xi = 0`` (where ``G_ij = 0`` is imposed) when ``mu_j <= mu_i``, and, when
``mu_j > mu_i``, from the diagonal with the artificial condition
``L_ij(1, xi) = L_ij(1, 1)`` on the part of ``x = 1`` the diagonal does not reach (an
artificial boundary value, chosen constant), ``G_ij(x)`` being then the value the
boundary relation gives. ``G`` vanishes except where ``mu_j > mu_i``: the target is a
cascade from the fastest group to the slowest, and ``beta`` vanishes after
``sum_g 1 / mu_g`` over the groups of equal ``mu``; ``alpha`` follows ``1 / min lam``
later (:attr:`NPlusMBackstepping.convergence_time`). The shorter time of the Fredholm
design of Coron, Hu and Olive, "Finite-time boundary stabilization of general linear
hyperbolic balance laws via Fredholm backstepping transformation" (Automatica, 2017) is
not built here. When the corner values of an ``L_ij`` with ``mu_j < mu_i`` differ (the
diagonal relation against ``G_ij = 0`` at the origin), ``L_ij`` jumps across the
characteristic through the origin: the kernels of ``n + m`` systems may be discontinuous
(Humaloja and Bekiaris-Liberis, arXiv:2410.22067, 2024, abstract).

**Scheme.** Every entry of ``Z`` obeys ``dZ_ij/dx = (Z Sigma - D Z)_ij / mu_i`` along its
characteristic. On the uniform grid of ``T`` each node is tied to the foot of its
characteristic one step back on the previous level (the next level for the entries
solved from the diagonal) by the trapezoidal rule, with cubic Lagrange interpolation
along that level, or to the point where the characteristic leaves the diagonal or
``xi = 0`` (linear interpolation there); all nodes and entries form one sparse linear
system, solved level by level (block substitution; GMRES when some entries run backwards). Second order for continuous
kernels (``tests/test_nplusm_kernels.py``: observed 2.0); with a jump, the traces
converge in ``L^1`` at order 1 and the feedback integral ``J`` at 1.8. For ``n = m = 1``
the kernels are the paper's ``K^{vu}``, ``K^{vv}`` (:mod:`nrobust.hyperbolic.kernels`,
eqs. (24)-(29)).

**Controller and loop.** ``beta(t, 1) = 0`` gives the full-state law
``U(t) = -R u(t, 1) + int_0^1 K(1, xi) u(t, xi) + L(1, xi) v(t, xi) dxi``. With the loop
delay ``delta`` (``v(t, 1) = R u(t, 1) + U(t - delta)``) the
Laplace route of :mod:`nrobust.hyperbolic.nplusm` gives, with
``Phi(xi; s) = exp(xi Lambda^{-1} (Sigma - s I))``, ``W = [Q; I]`` and
``J(s) = int_0^1 [K, L](1, xi) Phi(xi; s) dxi W``, the closed loop ::

    det( E(s) (Phi_v - R Phi_u + e^{-delta s} (R Phi_u - J(s))) ) = 0,   E = diag(e^{-s/mu_j});

``J`` is computed exactly for the piecewise-linear trace of the kernels (Filon-type
weights from one block exponential per ``s``). ``E J = O(1/|s|)`` on vertical lines, so
the principal part is that of the static cancellation ``K = -R``: with a delay the
cancellation doubles ``gamma_0`` (for 2x2 plants the paper's Theorem 3: unstable for every
``delta > 0`` when ``|rho q| > 1/2``), and the margin is zero once ``gamma_0 >= 1``.

**Kernel-free loop.** For the exact kernels the transformation maps the Laplace-domain
solution with ``v(0) = I`` onto the target's, so ``Phi_v - J = T(s)``, the transition of
``beta_x = Lambda-^{-1} ((s - D) beta - G beta(0))``. With one speed ``mu`` for every ``v``
(``m = 1`` always) ``G = 0``, ``D = Sigma--`` and ``E (Phi_v - J) = V = exp(-Sigma--/mu)``:
the loop is ``det(M_0 + e^{-delta s} (V - M_0))``, ``M_0`` the open loop, with no kernel
(:meth:`NPlusMBackstepping.target_loop_matrices`); its margin is certified by
:func:`~nrobust.hyperbolic.nplusm.backstepping_exact_margin`. The grid kernels' loop
converges to it at order 2 (``tests/test_nplusm_proven.py``).

**Cascade loop (several speeds).** The identity above, derived: with
``Psi(x; s) = int_0^x Z(x, xi) Phi(xi; s) dxi W`` (so ``J = Psi(1; s)``), differentiate in
``x``, replace ``Lambda- Z_x`` by the kernel equation, integrate ``Z_xi Lambda Phi`` by parts
(``Lambda Phi_xi = (Sigma - s) Phi``) and use the diagonal relations and
``Z(x, 0) Lambda W = -G(x)`` (``Lambda = diag(Lambda+, -Lambda-)``): ::

    Lambda- (Phi_v - Psi)_x = (s - D) (Phi_v - Psi) - G(x),     (Phi_v - Psi)(0) = I,

the target's equation with ``beta(0) = I``; at ``x = 1``, ``Phi_v - J = T(s)``. ``D`` lives
inside groups of equal speed, so it commutes with ``Lambda-`` and with ``E(s) =
exp(-s Lambda-^{-1})``; solving the linear equation and multiplying by ``E`` gives ::

    E(s) T(s) = V (I - int_0^1 e^{x C(s)} Lambda-^{-1} G(x) dx),
    C(s) = Lambda-^{-1} (D - s I),     V = exp(-Lambda-^{-1} D),

and the loop ``det(M_0 + e^{-delta s} (E T - M_0))``
(:meth:`NPlusMBackstepping.cascade_loop_matrices`). Three consequences. (i) ``G_ac = 0``
unless ``mu_c > mu_a`` and ``e^{x C}`` is block diagonal on the groups, so the integral is
strictly block triangular in the order of the speeds: ``det(E T) = det V != 0``, the
delay-free loop has no root at all (the finite-time convergence). (ii) On ``Re s >= 0``,
``||e^{x C(s)}|| <= ||e^{x Lambda-^{-1} D}||`` (``|e^{-s x / mu}| <= 1``): an error ``dG`` of
``G`` moves ``E T`` by at most ``||V|| int_0^1 ||e^{x Lambda-^{-1} D}|| ||Lambda-^{-1} dG(x)|| dx``,
the same bound at every frequency, and ``E T - V = O(1/|s|)`` for ``G`` of bounded
variation (the principal part is still that of ``K = -R``). (iii) With one speed ``E T = V``:
the kernel-free loop. With several speeds the loop is not kernel-free: ``G`` is the value at
``xi = 0`` of kernels whose entries ``L_ac``, ``mu_c > mu_a``, carry the artificial boundary
values at ``x = 1`` (a design choice) through the kernel equations; it has a closed form in
special cases only (one coupling ``Sigma--_ac``: ``L_ac = Sigma--_ac / (mu_c - mu_a)``
throughout and ``G_ac = mu_c L_ac``, ``tests/test_nplusm_unequal_speeds.py``). The grid's
``G`` converges at order 2 and the ``J`` route to the ``G`` route at order 2 (same test
file). :func:`~nrobust.hyperbolic.nplusm.kernel_error_bound` proves a bound of
``||V|| int ||e^{x Lambda-^{-1} D}|| ||Lambda-^{-1} (G - G_grid)|| dx`` (first order in the grid
step); the margins with several speeds are not certified yet: the crossing search and the
frequency bound do not carry that bound.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._json import json_safe
from ..._validate import nonnegative
from ...errors import ConvergenceError, ParameterError
from ..kernels.constant import RESOLUTION, check_kernel_grid, p1_interpolate
from .characteristic import NPlusMCharacteristic
from .system import NPlusMSystem

__all__ = [
    "BACKSTEPPING_ROUTES",
    "MAX_NPLUSM_KERNEL_GRID",
    "NPlusMBackstepping",
    "NPlusMKernels",
    "solve_nplusm_kernels",
]

#: Largest kernel grid of :func:`solve_nplusm_kernels` (work bound, checked before the
#: sparse system is built: ``m (n + m) N (N + 1) / 2`` unknowns).
MAX_NPLUSM_KERNEL_GRID = 801
_MAX_UNKNOWNS = 3_000_000
_TOL = 1e-12
KERNEL_SCOPE = "full-state backstepping law with the grid kernels (a model of the exact law, no error bound)"
CASCADE_SCOPE = (
    "full-state backstepping law, loop through the target's G of the grid kernels "
    "(E T = V (I - int e^{x C} Lambda-^{-1} G); a model of the exact law, its error not carried by the scan)"
)
#: The loops :func:`~nrobust.hyperbolic.nplusm.backstepping_delay_margin` scans: the feedback integral ``J`` or
#: the target's ``G``.
BACKSTEPPING_ROUTES = ("integral", "cascade")


def _node(i: Any, j: Any) -> Any:
    """Number ``i (i + 1) / 2 + j`` of the node ``(x_i, xi_j)``, ``j <= i``, of the triangle grid."""
    return i * (i + 1) // 2 + j


def _level_stencil(i: int, pos: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Cubic Lagrange stencils on level ``i`` (nodes ``0..i``) at ``xi = pos h``: nodes and weights ``(len, 4)``.

    The four nodes around each point, shifted inwards at the ends of the level; on the
    levels with fewer than four nodes, all of them (zero weights pad the rest).
    """
    if i < 3:
        idx = np.broadcast_to(np.arange(i + 1), (pos.size, i + 1))
    else:
        start = np.clip(np.floor(pos + _TOL).astype(np.int64) - 1, 0, i - 3)
        idx = start[:, None] + np.arange(4)
    k = idx.shape[1]
    w = np.ones(idx.shape)
    for a in range(k):
        for b in range(k):
            if a != b:
                w[:, a] *= (pos - idx[:, b]) / (idx[:, a] - idx[:, b])
    nodes = _node(i, idx)
    if k < 4:
        nodes = np.concatenate([nodes, np.repeat(nodes[:, :1], 4 - k, axis=1)], axis=1)
        w = np.concatenate([w, np.zeros((pos.size, 4 - k))], axis=1)
    return nodes, w


def _edge_stencil(pos: NDArray[np.float64], N: int, diagonal: bool) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Linear interpolation at ``x = pos h`` along the diagonal (or ``xi = 0``): nodes and weights ``(len, 2)``."""
    k = np.minimum(np.floor(pos + _TOL).astype(np.int64), N - 2)
    f = pos - k
    nodes = np.stack([_node(k, k if diagonal else 0), _node(k + 1, k + 1 if diagonal else 0)], axis=1)
    return nodes, np.stack([1.0 - f, f], axis=1)


def _solve_by_levels(A: Any, rhs: NDArray[np.float64], bounds: NDArray[np.int64]) -> NDArray[np.float64]:
    """Solve the kernel system, its unknowns grouped by levels ``x_i`` (``bounds[i]:bounds[i + 1]``).

    The equations of a level read the level itself and the level before (the entries
    marched in ``x``) or after (those solved from the diagonal). Block forward
    substitution solves the first kind exactly; with entries of the second kind it is
    the symmetric block Gauss-Seidel preconditioner of GMRES. Each level's block is
    factored once (sparse LU).

    Raises
    ------
    ConvergenceError
        GMRES did not reach a relative residual of ``1e-13``.
    """
    from scipy.sparse import csr_matrix  # lazily: a slow import
    from scipy.sparse.linalg import LinearOperator, gmres, splu

    level = np.searchsorted(bounds, np.arange(A.shape[0]), side="right") - 1
    rl, cl = level[A.row], level[A.col]
    size = A.shape
    lower = csr_matrix((A.data[cl < rl], (A.row[cl < rl], A.col[cl < rl])), shape=size)
    upper = csr_matrix((A.data[cl > rl], (A.row[cl > rl], A.col[cl > rl])), shape=size)
    same = cl == rl
    diag = csr_matrix((A.data[same], (A.row[same], A.col[same])), shape=size)
    spans = list(pairwise(bounds))
    lus = [splu(diag[s:e, s:e].tocsc()) for s, e in spans]
    low_rows = [lower[s:e] for s, e in spans]
    up_rows = [upper[s:e] for s, e in spans]

    def forward(r: NDArray[np.float64]) -> NDArray[np.float64]:
        y = np.zeros_like(r)
        for (s, e), lu, low in zip(spans, lus, low_rows):
            y[s:e] = lu.solve(r[s:e] - low @ y)
        return y

    if upper.nnz == 0:
        return forward(rhs)

    def sgs(r: NDArray[np.float64]) -> NDArray[np.float64]:
        y = forward(r)
        dy = diag @ y
        z = np.zeros_like(r)
        for (s, e), lu, up in reversed(list(zip(spans, lus, up_rows))):
            z[s:e] = lu.solve(dy[s:e] - up @ z)
        return z

    matrix = A.tocsr()
    op = LinearOperator(size, matvec=sgs, dtype=float)
    sol, info = gmres(matrix, rhs, M=op, rtol=1e-13, atol=0.0, restart=60, maxiter=20)
    if info != 0:
        raise ConvergenceError(f"kernel system: GMRES stopped with code {info} (a finer kernel_grid may help)")
    return np.asarray(sol, dtype=float)


def in_group_part(system: NPlusMSystem) -> NDArray[np.float64]:
    """``D``: the couplings of ``Sigma--`` between components of equal speed ``mu`` (diagonal included)."""
    mu = system.mu
    s_mm = system.sigma[system.n :, system.n :]
    return np.where(mu[:, None] == mu[None, :], s_mm, 0.0)


def rhs_matrix(system: NPlusMSystem) -> NDArray[np.float64]:
    """``M`` with ``(Z Sigma - D Z)_e = sum_f M[e, f] Z_f``, the entries ``e = a (n + m) + b`` of ``Z = [K, L]``."""
    n, m = system.n, system.m
    D = in_group_part(system)
    width = n + m
    M = np.zeros((m * width, m * width))
    for a in range(m):
        for b in range(width):
            e = a * width + b
            for k in range(width):
                M[e, a * width + k] += system.sigma[k, b]
            for k in range(m):
                M[e, k * width + b] -= D[a, k]
    return M


def entry_kind(system: NPlusMSystem, a: int, b: int) -> tuple[str, float, float]:
    """``(kind, slope, diagonal value)`` of the entry ``Z_ab``: its characteristic ``dxi/dx = slope``.

    ``kind`` is ``"K"`` (``b < n``), and for ``L_ac`` (``c = b - n``) ``"low"`` (``mu_c < mu_a``: from
    ``xi = 0`` or the diagonal), ``"same"`` (from ``xi = 0``) or ``"reverse"`` (``mu_c > mu_a``: from the
    diagonal or ``x = 1``), module notes.
    """
    n, lam, mu, sig = system.n, system.lam, system.mu, system.sigma
    if b < n:
        return "K", float(-lam[b] / mu[a]), float(-sig[n + a, b] / (mu[a] + lam[b]))
    c = b - n
    kind = "low" if mu[c] < mu[a] else ("same" if mu[c] == mu[a] else "reverse")
    diag = float(sig[n + a, n + c] / (mu[c] - mu[a])) if kind != "same" else 0.0
    return kind, float(mu[c] / mu[a]), diag


def _check_grid(system: NPlusMSystem, N: int) -> None:
    """Refuse a grid too coarse for the couplings, or too large, before anything is allocated."""
    unknowns = system.m * (system.n + system.m) * N * (N + 1) // 2
    if unknowns > _MAX_UNKNOWNS:
        raise ParameterError("kernel_grid", f"at most {N - 1} with m (n + m) N (N + 1) / 2 <= {_MAX_UNKNOWNS}", N)
    sigma = float(np.max(np.abs(system.sigma)))
    speed = float(min(system.lam.min(), system.mu.min()))
    steps = sigma / (speed * RESOLUTION)
    if steps > N - 1:
        raise ParameterError(
            "kernel_grid",
            f">= {int(np.ceil(steps)) + 1} for couplings up to |sigma| = {sigma:.6g} and min speed {speed:.6g} "
            f"(grid step times max|sigma| / min speed at most {RESOLUTION:g})",
            N,
        )


def _cell_moments(C: NDArray[Any], h: float) -> tuple[NDArray, NDArray, NDArray]:
    """``(e^{h C}, int_0^h e^{t C} dt, int_0^h t e^{t C} dt)`` for a stack ``C`` of ``(k, N, N)`` matrices.

    Read from the exponential of ``h [[C, I, 0], [0, 0, I], [0, 0, 0]]`` (Van Loan): its blocks
    ``(1, 1)``, ``(1, 2)`` and ``(1, 3)`` are ``e^{h C}``, ``I_0`` and ``h I_0 - I_1``.
    """
    from scipy.linalg import expm  # lazily: a slow import

    k, N = C.shape[0], C.shape[-1]
    big = np.zeros((k, 3 * N, 3 * N), dtype=complex)
    big[:, :N, :N] = h * C
    big[:, :N, N : 2 * N] = h * np.eye(N)
    big[:, N : 2 * N, 2 * N :] = h * np.eye(N)
    ex = expm(big) if k else big
    i0 = ex[:, :N, N : 2 * N]
    return ex[:, :N, :N], i0, h * i0 - ex[:, :N, 2 * N :]


@dataclass(frozen=True, repr=False, eq=False)
class NPlusMKernels:
    """Kernels ``K`` (``m x n``) and ``L`` (``m x m``) of Hu et al. (2016) on a uniform grid of ``T``.

    Attributes
    ----------
    system : NPlusMSystem
    grid : ndarray, shape (N,)
        ``x_i = xi_i = i / (N - 1)``.
    K : ndarray, shape (m, n, N, N)
        ``K[a, b, i, j] = K_ab(x_i, xi_j)`` for ``j <= i`` (zero above the diagonal).
    L : ndarray, shape (m, m, N, N)
        ``L_ab(x_i, xi_j)`` likewise.
    G : ndarray, shape (m, m, N)
        ``G(x_i) = L(x_i, 0) Lambda- - K(x_i, 0) Lambda+ Q`` of the target system: nonzero
        only where ``mu_b > mu_a`` (module notes; zero elsewhere up to the scheme's error).
    """

    system: NPlusMSystem
    grid: NDArray[np.float64]
    K: NDArray[np.float64]
    L: NDArray[np.float64]
    G: NDArray[np.float64]

    @property
    def trace(self) -> NDArray[np.float64]:
        """``[K, L](1, xi_j)``: shape ``(m, n + m, N)``, the gains of the full-state controller."""
        return np.concatenate([self.K[:, :, -1, :], self.L[:, :, -1, :]], axis=1)

    def _evaluate(self, table: NDArray[np.float64], x: ArrayLike, xi: ArrayLike) -> NDArray[np.float64]:
        xa, xia = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(xi, dtype=float))
        inside = (xia >= -_TOL) & (xia <= xa + _TOL) & (xa <= 1.0 + _TOL)
        if not np.all(inside):
            raise ParameterError(
                "(x, xi)", "in the triangle 0 <= xi <= x <= 1", (xa[~inside].flat[0], xia[~inside].flat[0])
            )
        xc = np.clip(xa, 0.0, 1.0)
        return np.asarray(p1_interpolate(table, xc, np.clip(xia, 0.0, xc)))

    def K_at(self, x: ArrayLike, xi: ArrayLike) -> NDArray[np.float64]:
        """``K(x, xi)`` at points of ``T`` (piecewise-linear on the grid): shape ``(m, n) + x.shape``."""
        return np.array([[self._evaluate(t, x, xi) for t in row] for row in self.K])

    def L_at(self, x: ArrayLike, xi: ArrayLike) -> NDArray[np.float64]:
        """``L(x, xi)`` at points of ``T``: shape ``(m, m) + x.shape``."""
        return np.array([[self._evaluate(t, x, xi) for t in row] for row in self.L])

    def __repr__(self) -> str:
        return f"NPlusMKernels(n={self.system.n}, m={self.system.m}, N={self.grid.size})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary: the system, the grid, the traces ``K(1, xi)``, ``L(1, xi)`` and ``G``."""
        return json_safe(
            {
                "type": "NPlusMKernels",
                "system": self.system,
                "xi": self.grid,
                "K_trace": self.K[:, :, -1, :],
                "L_trace": self.L[:, :, -1, :],
                "G": self.G,
            }
        )


def solve_nplusm_kernels(system: NPlusMSystem, kernel_grid: int = 101) -> NPlusMKernels:
    """Solve the kernel equations of Hu et al. (2016) for an ``n + m`` system (module notes).

    Parameters
    ----------
    system : NPlusMSystem
    kernel_grid : int, optional
        Grid points ``N`` per side of the triangle (``>= 3``, at most
        :data:`MAX_NPLUSM_KERNEL_GRID`, fine enough for the couplings:
        ``max|Sigma| / min speed <= RESOLUTION (N - 1)``).

    Returns
    -------
    NPlusMKernels

    Raises
    ------
    ParameterError
        A system that is not an :class:`NPlusMSystem`, or a grid out of range.
    ConvergenceError
        Some ``L_ij`` run from the diagonal and GMRES did not converge on the coupled system.

    Examples
    --------
    >>> sys = NPlusMSystem([1.0, 2.0], [1.5], [[0, 0, 1], [0, 0, 0.5], [1, -0.5, 0]], [[1.0], [0.5]], [[0.3, 0.2]])
    >>> ker = solve_nplusm_kernels(sys, 41)
    >>> ker.trace.shape
    (1, 3, 41)
    """
    if not isinstance(system, NPlusMSystem):
        raise ParameterError("system", "an NPlusMSystem", type(system).__name__)
    N = check_kernel_grid(kernel_grid, MAX_NPLUSM_KERNEL_GRID)
    _check_grid(system, N)
    n, m = system.n, system.m
    lam, mu = system.lam, system.mu
    width = n + m
    E = m * width
    M = rhs_matrix(system)
    lq = lam[:, None] * system.q  # Lambda+ Q, (n, m)
    h, T = 1.0 / (N - 1), N * (N + 1) // 2
    rows: list[NDArray[np.int64]] = []
    cols: list[NDArray[np.int64]] = []
    vals: list[NDArray[np.float64]] = []
    rhs = np.zeros(E * T)

    def put(row: NDArray[np.int64], f: int, nodes: NDArray[np.int64], w: NDArray[np.float64]) -> None:
        """Add ``w * Z_f(nodes)`` to the equations ``row`` (``nodes``, ``w``: ``(len(row), k)``)."""
        rows.append(np.broadcast_to(row[:, None], nodes.shape).ravel())
        cols.append((nodes * E + f).ravel())
        vals.append(np.asarray(w, dtype=float).ravel())

    def coupled(row: NDArray[np.int64], e: int, nodes: NDArray[np.int64], w: NDArray[np.float64]) -> None:
        """Add ``w * sum_f M[e, f] Z_f`` at the interpolated points."""
        for f in np.flatnonzero(M[e]):
            put(row, int(f), nodes, w * M[e, f])

    for a in range(m):
        for b in range(width):
            e = a * width + b
            kind, slope, diag = entry_kind(system, a, b)
            d = -1 if kind == "reverse" else 1  # the foot lies on level i - d
            for i in range(N):
                j = np.arange(i + 1)
                row = _node(i, j) * E + e  # unknowns numbered node-major: a banded system
                x = i * h
                fixed = np.zeros(i + 1, dtype=bool)
                if kind != "same":
                    fixed[i] = True
                if kind == "reverse" and i == N - 1:
                    fixed[:] = True  # the artificial condition L_ab(1, xi) = L_ab(1, 1)
                one = np.ones((int(fixed.sum()), 1))
                put(row[fixed], e, _node(i, j[fixed])[:, None], one)
                rhs[row[fixed]] = diag
                bottom = ~fixed & (j == 0) & (kind in ("low", "same"))
                if bottom.any():  # G_ab = 0: mu_c L_ab(x, 0) = (K(x, 0) Lambda+ Q)_ac
                    here = np.array([[_node(i, 0)]])
                    put(row[bottom], e, here, np.array([[mu[b - n]]]))
                    for k in range(n):
                        put(row[bottom], a * width + k, here, np.array([[-lq[k, b - n]]]))
                free = ~fixed & ~bottom
                if not free.any():
                    continue
                jr, rr = j[free], row[free]
                # the characteristic back (forward for "reverse") by one step, or to where it leaves T
                t = np.full(jr.size, h)
                where = np.zeros(jr.size, dtype=int)  # 0: level i - d, 1: diagonal, 2: xi = 0
                if slope != 1.0:
                    t_diag = (x - jr * h) / (d * (1.0 - slope))
                    hit = (t_diag >= -_TOL) & (t_diag < h - _TOL)
                    t[hit], where[hit] = t_diag[hit], 1
                if kind == "low":
                    t_bot = jr * h / slope
                    hit = t_bot < t - _TOL
                    t[hit], where[hit] = t_bot[hit], 2
                step = -(d * t / mu[a] / 2.0)[:, None]
                here = _node(i, jr)[:, None]
                put(rr, e, here, np.ones((jr.size, 1)))
                coupled(rr, e, here, step)
                for kind_of_foot in (0, 1, 2):
                    sel = where == kind_of_foot
                    if not sel.any():
                        continue
                    rs, ts = rr[sel], t[sel]
                    if kind_of_foot == 0:
                        lev = i - d
                        pos = np.clip((jr[sel] * h - d * slope * ts) / h, 0.0, lev)
                        nodes, w = _level_stencil(lev, pos)
                        put(rs, e, nodes, -w)
                    else:
                        nodes, w = _edge_stencil((x - d * ts) / h, N, kind_of_foot == 1)
                        if kind_of_foot == 1:
                            rhs[rs] = diag
                        else:  # Z_e at (x_f, 0) from the boundary relation with G = 0
                            for k in range(n):
                                put(rs, a * width + k, nodes, w * (-lq[k, b - n] / mu[b - n]))
                    coupled(rs, e, nodes, w * step[sel])
    from scipy.sparse import coo_matrix  # lazily: a slow import

    A = coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(E * T, E * T))
    sol = _solve_by_levels(A, rhs, np.array([E * _node(i, 0) for i in range(N + 1)]))
    if not np.all(np.isfinite(sol)):
        raise ParameterError("kernel_grid", "a grid on which the kernel scheme is solvable", N)
    Z = np.zeros((m, width, N, N))
    ii, jj = np.tril_indices(N)
    for a in range(m):
        for b in range(width):
            e = a * width + b
            Z[a, b, ii, jj] = sol[_node(ii, jj) * E + e]
    K, L = Z[:, :n], Z[:, n:]
    G = L[:, :, :, 0] * mu[None, :, None] - np.einsum("abi,bc->aci", K[:, :, :, 0], lq)
    return NPlusMKernels(system, np.linspace(0.0, 1.0, N), K, L, G)


class NPlusMBackstepping:
    """The full-state controller ``U(t) = -R u(t, 1) + int_0^1 K(1, xi) u(t, xi) + L(1, xi) v(t, xi) dxi``.

    The law of Hu et al. (2016), with the kernels of :func:`solve_nplusm_kernels`
    (piecewise linear in ``xi`` between the grid nodes). Without delay the closed loop
    reaches zero at :attr:`convergence_time`; with a loop delay ``delta`` its
    characteristic function is :meth:`characteristic_value` (module notes). It is a
    feedback :func:`~nrobust.hyperbolic.simulate.simulate_nplusm` accepts in place of a
    static gain (through :meth:`functional`).

    Parameters
    ----------
    kernels : NPlusMKernels

    Notes
    -----
    In :func:`~nrobust.hyperbolic.simulate.simulate_nplusm`, a ``u`` and a ``v`` component
    on grids of the same number of cells (equal speeds) split the scheme's lattice into two
    parities coupled only through the boundary; the integral of their checkerboard
    difference is ``O(h)``, so that mode sees the plant under ``U = -R u(t, 1)`` alone and
    may grow from the ``O(h)`` residual: simulate such plants with distinct ``u`` and ``v``
    speeds (measured: ``lam = mu = 1``, residual 0.65 at 80 cells and ``t = 10`` against
    ``1.4e-4`` for ``mu = 1.01`` with 81 cells). With two actuators, coarse grids also
    showed growing modes below the margin that change with the cells (at ``0.7`` times the
    margin: decay at 60 cells, growth at 90), while beyond the margin the simulated growth
    is the rightmost root's real part (``tests/test_nplusm_kernels.py``).
    """

    def __init__(self, kernels: NPlusMKernels) -> None:
        if not isinstance(kernels, NPlusMKernels):
            raise ParameterError("kernels", "an NPlusMKernels (solve_nplusm_kernels)", type(kernels).__name__)
        self.kernels = kernels
        self.system = kernels.system

    @classmethod
    def for_system(cls, system: NPlusMSystem, kernel_grid: int = 101) -> NPlusMBackstepping:
        """The controller of ``system`` with kernels on ``kernel_grid`` points."""
        return cls(solve_nplusm_kernels(system, kernel_grid))

    @property
    def convergence_time(self) -> float:
        """``t_F = 1 / min lam + sum_g 1 / mu_g`` (``mu_g`` the distinct speeds of ``v``): zero from then on.

        The target's ``beta`` is a cascade from the fastest group of ``v`` to the slowest
        and ``alpha`` is zero ``1 / min lam`` after ``beta`` (module notes).
        """
        return float(1.0 / self.system.lam.min() + np.sum(1.0 / np.unique(self.system.mu)))

    def functional(self, grids: list[NDArray[np.float64]]) -> NDArray[np.float64]:
        """The control as a row map of the stacked nodal values of ``(u_1, ..., u_n, v_1, ..., v_m)``.

        ``grids[i]`` holds the nodes of component ``i`` on ``[0, 1]``; the integrals use the
        trapezoidal rule on those nodes with the kernel traces interpolated linearly, and
        ``-R u(1)`` sits on the last node of each ``u`` grid. Returns shape ``(m, sum nodes)``.
        """
        sys = self.system
        if len(grids) != sys.n + sys.m:
            raise ParameterError("grids", f"{sys.n + sys.m} grids (one per component)", len(grids))
        trace, xi = self.kernels.trace, self.kernels.grid
        blocks = []
        for i, x in enumerate(grids):
            x = np.asarray(x, dtype=float)
            w = np.zeros(x.size)
            dx = np.diff(x)
            w[:-1] += dx / 2
            w[1:] += dx / 2
            blk = np.array([np.interp(x, xi, trace[a, i]) for a in range(sys.m)]) * w[None]
            if i < sys.n:
                blk[:, -1] -= sys.r[:, i]
            blocks.append(blk)
        return np.concatenate(blocks, axis=1)

    def feedback_integral(self, s: ArrayLike) -> NDArray[np.complex128]:
        """``J(s) = int_0^1 [K, L](1, xi) Phi(xi; s) dxi [Q; I]``, shape ``s.shape + (m, m)``.

        Exact for the piecewise-linear trace: on a cell, ``int_0^h (z_k + t dz/h) e^{(xi_k + t) C} dt
        = z_k Phi_k I_0 + dz/h Phi_k I_1`` with ``I_0 = int_0^h e^{tC}``, ``I_1 = int_0^h t e^{tC}``
        read from the exponential of ``h [[C, I, 0], [0, 0, I], [0, 0, 0]]`` (Van Loan).
        """
        sys = self.system
        s = np.asarray(s, dtype=complex)
        flat = s.reshape(-1)
        N = sys.n + sys.m
        xi = self.kernels.grid
        h = float(xi[1] - xi[0])
        inv = 1.0 / sys.signed_speeds
        C = inv[:, None] * sys.sigma[None] - flat[:, None, None] * np.diag(inv)[None]
        step, i0, i1 = _cell_moments(C, h)
        z = self.kernels.trace  # (m, N, cells + 1)
        phi = np.broadcast_to(np.eye(N, dtype=complex), (flat.size, N, N)).copy()
        acc = np.zeros((flat.size, sys.m, N), dtype=complex)
        for k in range(xi.size - 1):
            zk, dz = z[:, :, k], (z[:, :, k + 1] - z[:, :, k]) / h
            acc += np.einsum("an,snq,sqp->sap", zk, phi, i0) + np.einsum("an,snq,sqp->sap", dz, phi, i1)
            phi = phi @ step
        w0 = np.vstack([sys.q, np.eye(sys.m)])
        return np.asarray(acc @ w0, dtype=complex).reshape(*s.shape, sys.m, sys.m)

    def loop_matrices(self, s: ArrayLike) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        """``M_0 = E (Phi_v - R Phi_u)`` and ``M_1 = E (R Phi_u - J)``: the loop is ``det(M_0 + e^{-delta s} M_1)``."""
        sys = self.system
        s = np.asarray(s, dtype=complex)
        phi = sys.transition(s) @ np.vstack([sys.q, np.eye(sys.m)])
        phi_u, phi_v = phi[..., : sys.n, :], phi[..., sys.n :, :]
        scale = np.exp(-s[..., None] / sys.mu)[..., :, None]
        r_phi = sys.r @ phi_u
        return scale * (phi_v - r_phi), scale * (r_phi - self.feedback_integral(s))

    def target_loop_matrices(self, s: ArrayLike) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        """``M_0`` and ``M_1 = V - M_0`` of the law with exact kernels, kernel-free (all ``mu`` equal).

        ``E (Phi_v - J) = V = exp(-Sigma--/mu)`` by the target system
        (:func:`~nrobust.hyperbolic.nplusm.backstepping_exact_margin`), so ``M_1 = E (R Phi_u - J)
        = V - M_0``; :meth:`loop_matrices` (grid kernels) converges to these with the kernel grid.

        Raises
        ------
        ParameterError
            Leftward speeds not all equal (``G != 0``: the loop depends on the kernels, through
            ``G`` alone in :meth:`cascade_loop_matrices`).
        """
        sys = self.system
        if np.any(sys.mu != sys.mu[0]):
            raise ParameterError("system", "leftward speeds mu all equal (the target's G = 0)", sys.mu.tolist())
        s = np.asarray(s, dtype=complex)
        m0 = sys.loop_matrix(s)
        v_block, _ = sys.principal_terms()
        return m0, v_block - m0

    def target_transition(self, s: ArrayLike) -> NDArray[np.complex128]:
        """``E(s) T(s) = V (I - int_0^1 e^{x C(s)} Lambda-^{-1} G(x) dx)``: the loop's kernel part through ``G`` alone.

        ``C(s) = Lambda-^{-1} (D - s I)`` and ``V = exp(-Lambda-^{-1} D)``; ``T(s)`` is the
        transition ``beta(1)`` of the target ``Lambda- beta_x = (s - D) beta - G(x) beta(0)``,
        ``beta(0) = I`` (module notes, *Cascade loop*), equal to ``Phi_v - J`` for the exact
        kernels. ``G`` is the grid's (:attr:`NPlusMKernels.G`, linear between the nodes) on the
        entries ``mu_c > mu_a`` and zero on the others, where the kernel equations impose
        ``G_ac = 0``; the integral is exact for that ``G`` (a Filon rule, as in
        :meth:`feedback_integral`). With one speed ``mu`` this is ``V`` exactly.
        Shape ``s.shape + (m, m)``.
        """
        sys = self.system
        s = np.asarray(s, dtype=complex)
        flat = s.reshape(-1)
        m = sys.m
        v_block, _ = sys.principal_terms()
        mask = sys.mu[None, :] > sys.mu[:, None]  # (a, c): mu_c > mu_a
        if not mask.any():
            return np.asarray(np.broadcast_to(v_block, (*s.shape, m, m)), dtype=complex)
        g = self.kernels.G * mask[:, :, None] / sys.mu[:, None, None]  # Lambda-^{-1} G(x_k), (m, m, N)
        xi = self.kernels.grid
        h = float(xi[1] - xi[0])
        C = (in_group_part(sys) / sys.mu[:, None])[None] - flat[:, None, None] * np.diag(1.0 / sys.mu)[None]
        step, i0, i1 = _cell_moments(C, h)
        phi = np.broadcast_to(np.eye(m, dtype=complex), (flat.size, m, m)).copy()
        acc = np.zeros((flat.size, m, m), dtype=complex)
        for k in range(xi.size - 1):
            gk, dg = g[:, :, k], (g[:, :, k + 1] - g[:, :, k]) / h
            acc += phi @ (i0 @ gk + i1 @ dg)
            phi = phi @ step
        return np.asarray(v_block @ (np.eye(m) - acc), dtype=complex).reshape(*s.shape, m, m)

    def cascade_loop_matrices(self, s: ArrayLike) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        """``M_0 = E (Phi_v - R Phi_u)`` and ``M_1 = E T - M_0`` (:meth:`target_transition`): the loop through ``G``.

        For the exact kernels ``E (R Phi_u - J) = E T - M_0``, so this is :meth:`loop_matrices`
        with the feedback integral ``J`` replaced by the target's transition: the kernels enter
        through ``G`` alone, and an error ``dG`` of ``G`` moves ``M_1`` by at most
        ``||V|| int_0^1 ||e^{x Lambda-^{-1} D}|| ||Lambda-^{-1} dG(x)|| dx`` on all of
        ``Re s >= 0`` (module notes). With one speed ``mu`` it is :meth:`target_loop_matrices`.
        """
        s = np.asarray(s, dtype=complex)
        m0 = self.system.loop_matrix(s)
        return m0, self.target_transition(s) - m0

    def characteristic_value(self, s: ArrayLike, delta: float = 0.0) -> NDArray[np.complex128]:
        """``det(E (Phi_v - R Phi_u + e^{-delta s} (R Phi_u - J)))`` at ``s``: the delayed closed loop."""
        delta = nonnegative("delta", delta)
        s = np.asarray(s, dtype=complex)
        m0, m1 = self.loop_matrices(s)
        return np.asarray(np.linalg.det(m0 + np.exp(-delta * s)[..., None, None] * m1), dtype=complex)

    def factors(self, s: ArrayLike) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        """``A = e^{-s/mu} (Phi_v - R Phi_u)`` and ``B = e^{-s/mu} (R Phi_u - J)`` (one actuator)."""
        if self.system.m != 1:
            raise ParameterError("system", "one actuator (m = 1) for the factors A, B", self.system.m)
        m0, m1 = self.loop_matrices(s)
        return m0[..., 0, 0], m1[..., 0, 0]

    def gamma_0(self) -> float:
        """``gamma_0`` of the delayed principal part: that of the static cancellation ``K = -R`` (``J = O(1/|s|)``).

        Exact for one actuator. For ``m > 1``, the upper end of the certified bracket of
        :meth:`~nrobust.matrix_difference.MatrixDifferenceOperator.gamma_0` when the
        principal part has at most four delays; with more, a lower bound: the largest
        spectral radius of ``sum_k A_k e^{i theta_k}`` over 20 000 points of the torus
        (seeded, reproducible; the coefficients ``V^{-1} R_ab U_a Q`` at ``tau_ab`` and
        their negatives at ``tau_ab + delta``, merged over equal delays, the distinct delays
        taken rationally independent).
        """
        sys = self.system
        if sys.m == 1:
            return NPlusMCharacteristic(sys, -sys.r, 0.0).gamma_0()
        v_block, point = sys.principal_terms(-sys.r)
        v_inv = np.linalg.inv(v_block)
        merged: dict[tuple[float, int], NDArray[np.float64]] = {}  # (tau, 0 for R / 1 for K): equal delays merge
        for tau, rq, kq in point:
            for key, a in (((tau, 0), rq), ((tau, 1), kq)):
                merged[key] = merged.get(key, np.zeros_like(a)) + v_inv @ a
        coefs = [a for a in merged.values() if np.any(a != 0)]
        if len(coefs) <= 4:
            return float(sys.principal_operator(-sys.r, 1e-3 * np.sqrt(2.0)).gamma_0().upper)
        theta = np.random.default_rng(0).uniform(0.0, 2 * np.pi, (20_000, len(coefs)))
        total = np.einsum("pk,kij->pij", np.exp(1j * theta), np.array(coefs))
        return float(np.max(np.abs(np.linalg.eigvals(total))))

    def __repr__(self) -> str:
        return f"NPlusMBackstepping({self.kernels!r})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description: the kernels' summary and the convergence time."""
        return json_safe(
            {"type": "NPlusMBackstepping", "kernels": self.kernels, "convergence_time": self.convergence_time}
        )
