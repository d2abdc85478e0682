"""Backstepping kernels of a general plant with varying speeds, and U_BS on them.

A :class:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2` with any speeds ``lam(x)``,
``mu(x)`` is first freed of its diagonal terms by the exponential scaling of its normal
form (``u = e^{A} u~``, ``v = e^{D} v~``, ``A = int_0^x a/lam``, ``D = -int_0^x d/mu``), which
leaves ``u~_t + lam u~_x = s1 v~``, ``v~_t - mu v~_x = s2 u~`` with ``s1 = b e^{D - A}``,
``s2 = c e^{A - D}``, ``u~(0) = q v~(0)``. The speeds are kept as they are (no change of the
space variable can make both constant when ``lam/mu`` varies). Following Coron, Vazquez,
Krstic and Bastin, "Local exponential H^2 stabilization of a 2x2 quasilinear hyperbolic
system using backstepping", SIAM J. Control Optim. 51(3), 2013 (section 3, the kernel
equations with varying speeds), the Volterra transformation
``alpha~ = u~ - int_0^x K~^{uu} u~ + K~^{uv} v~``, ``beta~ = v~ - int_0^x K~^{vu} u~ + K~^{vv} v~``
maps the plant to ``alpha~_t + lam alpha~_x = 0``, ``beta~_t - mu beta~_x = 0``,
``alpha~(0) = q beta~(0)`` when, on ``0 <= xi <= x <= L`` (derived in ``docs/theory.md``,
"Kernels with varying speeds")::

    lam(x) K~^{uu}_x + lam(xi) K~^{uu}_xi = -lam'(xi) K~^{uu} - s2(xi) K~^{uv},
    lam(x) K~^{uv}_x - mu(xi)  K~^{uv}_xi =  mu'(xi)  K~^{uv} - s1(xi) K~^{uu},
    mu(x)  K~^{vu}_x - lam(xi) K~^{vu}_xi =  lam'(xi) K~^{vu} + s2(xi) K~^{vv},
    mu(x)  K~^{vv}_x + mu(xi)  K~^{vv}_xi = -mu'(xi)  K~^{vv} + s1(xi) K~^{vu},
    K~^{uv}(x, x) = s1/(lam + mu),   K~^{uv}(x, 0) = (q lam(0)/mu(0)) K~^{uu}(x, 0),
    K~^{vu}(x, x) = -s2/(lam + mu),  K~^{vv}(x, 0) = (q lam(0)/mu(0)) K~^{vu}(x, 0).

With ``k^{uu} = lam(xi) K~^{uu}``, ``k^{uv} = mu(xi) K~^{uv}`` (and likewise ``k^{vu}``, ``k^{vv}``)
the derivatives of the speeds disappear, and in the transport times ``y = phi(x)``,
``eta = phi(xi)`` (``phi = int 1/lam``; ``psi = int 1/mu`` for the pair ``(vv, vu)``) each pair
has the form solved by :mod:`~nrobust.hyperbolic.kernels`: one kernel along the diagonal
``(1, 1)``, the other along the curve ``y + psi(xi) = const`` (resp. ``y + phi(xi)``), whose
slope ``-mu/lam`` varies. The same marching scheme applies, with the foot of each cross
characteristic at the previous level computed from the transport times (exact, not
``j + kappa``) and, within one step of the diagonal, its start on the diagonal from
``T = phi + psi`` (trapezoidal sources, cubic feet: second order, measured in
``tests/test_varying_kernels.py``).

The kernels of the plant in its own coordinates are
``K^{uu}(x, xi) = e^{A(x) - A(xi)} K~^{uu}``, ``K^{uv} = e^{A(x) - D(xi)} K~^{uv}``,
``K^{vu} = e^{D(x) - A(xi)} K~^{vu}``, ``K^{vv} = e^{D(x) - D(xi)} K~^{vv}``: the transformation
``alpha = u - int K^{uu} u + K^{uv} v``, ``beta = v - int K^{vu} u + K^{vv} v`` gives the target
``alpha_t + lam alpha_x = a alpha``, ``beta_t - mu beta_x = d beta``, ``alpha(0) = q beta(0)``,
``beta(t, L) = Phi(t) + U(t)``, and the controller U_BS (the paper's eq. (47), generalised)

    U_BS(t) = -rho u(t, L) + int_0^L K^{vu}(L, xi) u(t, xi) + K^{vv}(L, xi) v(t, xi) dxi

makes ``beta(t, L) = 0``: the state vanishes after ``tau = int 1/lam + int 1/mu``. With a
loop delay ``delta`` the closed loop is ``F(s; delta) = 1 - Phi(s) + Phi(s) e^{-delta s}``,
``Phi = rho_q e^{-tau s} - int_0^tau N~(nu) e^{-nu s} dnu``, where ``N~`` comes from the
inverse kernels ``L`` (``L = K + K o L``) at ``x = L`` along the target's characteristics::

    N~(nu) = e^{D(xi) - D(L)} mu(xi) (L^{beta beta} - rho L^{alpha beta})(L, xi),    nu = t_v - psi(xi),
    N~(nu) = q e^{A(xi) - D(L)} lam(xi) (L^{beta alpha} - rho L^{alpha alpha})(L, xi), nu = t_v + phi(xi).

This is the paper's delay form (39)-(40) for any speeds; the characteristic route
(:func:`~nrobust.hyperbolic.loops.varying_form.varying_delay_form`) and the Laplace route
(:func:`~nrobust.hyperbolic.loops.feedback.laplace_loop_factors` on :meth:`VaryingKernels.feedback_law`)
check it in the tests.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._json import json_safe
from ..._validate import finite_real, nonnegative
from ...errors import ParameterError
from ...quasipoly import DistributedDelay, QuasiPolynomial
from ..plants.general import GeneralHyperbolic2x2
from ..plants.law import FeedbackLaw, feedback_gain
from .constant import (
    DEFAULT_KERNEL_GRID,
    MAX_KERNEL_GRID,
    RESOLUTION,
    check_kernel_grid,
    march_levels,
    p1_interpolate,
    resolvent,
)

__all__ = ["VaryingKernels", "solve_varying_kernels"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class _Maps:
    """Transport times of a plant and their inverses (cubic Hermite, exact slopes)."""

    phi: Any
    psi: Any
    x_of_phi: Any
    x_of_psi: Any
    x_of_T: Any


def _maps(plant: GeneralHyperbolic2x2) -> _Maps:
    from scipy.interpolate import CubicHermiteSpline  # lazily: scipy.interpolate is slow to import

    x = plant.tables.x
    lam, mu = plant.coefficient("lam", x), plant.coefficient("mu", x)
    phi, psi = plant.phi(x), plant.psi(x)
    return _Maps(
        phi=plant.phi,
        psi=plant.psi,
        x_of_phi=CubicHermiteSpline(phi, x, lam),
        x_of_psi=CubicHermiteSpline(psi, x, mu),
        x_of_T=CubicHermiteSpline(phi + psi, x, 1.0 / (1.0 / lam + 1.0 / mu)),
    )


@dataclass(frozen=True)
class _Pair:
    """One pair of kernel equations in the transport time ``Y`` of its diagonal kernel.

    ``(d/dy + d/deta) P = a(xi) Q``, ``P(y, 0) = r Q(y, 0)``; ``Q`` along ``y + Z(xi) = const``
    with ``dQ/dy = b(xi) P`` and ``Q(y, y) = g(x)``; ``Y``, ``Z`` the transport times
    (``phi``, ``psi`` or ``psi``, ``phi``). The coefficients are callables of the physical ``xi``.
    """

    Y: Any
    Z: Any
    x_of_Y: Any
    x_of_Z: Any
    a: Any
    b: Any
    g: Any
    r: float


def _pairs(plant: GeneralHyperbolic2x2, maps: _Maps) -> tuple[_Pair, _Pair]:
    """The pairs ``(k^{uu}, k^{uv})`` (in ``phi``) and ``(k^{vv}, k^{vu})`` (in ``psi``)."""
    lam = plant.profiles["lam"]
    mu = plant.profiles["mu"]
    b, c = plant.profiles["b"], plant.profiles["c"]
    A, D = plant.A, plant.D

    def s1(x: Array) -> Array:
        return b(x) * np.exp(D(x) - A(x))

    def s2(x: Array) -> Array:
        return c(x) * np.exp(A(x) - D(x))

    q = plant.q
    uu = _Pair(
        maps.phi,
        maps.psi,
        maps.x_of_phi,
        maps.x_of_psi,
        a=lambda x: -lam(x) * s2(x) / mu(x),
        b=lambda x: -mu(x) * s1(x) / lam(x),
        g=lambda x: mu(x) * s1(x) / (lam(x) + mu(x)),
        r=1.0 / q,
    )
    vv = _Pair(
        maps.psi,
        maps.phi,
        maps.x_of_psi,
        maps.x_of_phi,
        a=lambda x: mu(x) * s1(x) / lam(x),
        b=lambda x: lam(x) * s2(x) / mu(x),
        g=lambda x: -lam(x) * s2(x) / (lam(x) + mu(x)),
        r=q,
    )
    return uu, vv


def _march(pair: _Pair, maps: _Maps, n: int, length: float) -> tuple[Array, Array]:
    """``P, Q`` on the uniform grid of ``Y`` with ``n`` points (``P[i, j]`` at ``y_i``, ``eta_j``).

    The level march of :func:`~nrobust.hyperbolic.kernels.constant.march_levels` with varying feet: node
    ``(i, j)`` of ``Q`` comes from its foot at level ``i - 1`` (``Z(xi_foot) = Z(xi_j) + h``,
    cubic interpolation) or, when that foot is past the diagonal (or ``i < 4``), from the
    point ``T(xi*) = y_i + Z(xi_j)`` where its characteristic leaves the diagonal.
    """
    total = float(pair.Y(length))
    h = total / (n - 1)
    eta = np.arange(n) * h
    xi = np.asarray(pair.x_of_Y(eta))
    xi[0], xi[-1] = 0.0, length
    z = np.asarray(pair.Z(xi))
    z_end = float(pair.Z(length))
    inside = z + h <= z_end
    xi_foot = np.asarray(pair.x_of_Z(np.minimum(z + h, z_end)))
    positions = np.where(inside, np.asarray(pair.Y(xi_foot)) / h, np.inf)

    def leave(i: int, jn: Array) -> tuple[Array, Array, Array]:
        x_star = np.asarray(maps.x_of_T(i * h + z[jn]))
        y_star = np.minimum(np.asarray(pair.Y(x_star)), i * h)
        return i * h - y_star, y_star, x_star

    return march_levels(eta, pair.a, pair.b, pair.g, pair.r, positions, pair.b(xi_foot), xi, leave)


def _check_grid(plant: GeneralHyperbolic2x2, pairs: tuple[_Pair, _Pair], n: int) -> None:
    """Refuse a grid too coarse for the couplings (``h max |a|, |b| <= RESOLUTION``) before marching."""
    probe = plant.tables.x
    worst = 0.0
    for pair in pairs:
        h = float(pair.Y(plant.length)) / (n - 1)
        worst = max(worst, h * float(np.max(np.abs(pair.a(probe)))), h * float(np.max(np.abs(pair.b(probe)))))
    if worst > RESOLUTION:
        need = int(np.ceil((n - 1) * worst / RESOLUTION)) + 1
        if need > MAX_KERNEL_GRID:
            raise ParameterError(
                "plant",
                f"couplings the kernel grid can resolve: {need} points needed, at most MAX_KERNEL_GRID = "
                f"{MAX_KERNEL_GRID} (grid step in transport time times the largest source coefficient at most "
                f"{RESOLUTION:g})",
                plant,
            )
        raise ParameterError(
            "kernel_grid",
            f">= {need} for these couplings (grid step in transport time times the largest source coefficient at "
            f"most {RESOLUTION:g})",
            n,
        )


@dataclass(frozen=True)
class _TraceGain:
    """``xi -> K^{vu}(L, xi)`` (``which = "u"``) or ``K^{vv}(L, xi)`` (``"v"``) on ``[0, L]``.

    The trace is a not-a-knot cubic spline in ``psi(xi)`` through the pair's nodes, built
    once; picklable whenever the plant is.
    """

    kernels: VaryingKernels = field(repr=False)
    which: str
    spline: Any = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        from scipy.interpolate import make_interp_spline  # lazily: scipy.interpolate is slow to import

        trace = self.kernels.trace_vu if self.which == "u" else self.kernels.trace_vv
        object.__setattr__(self, "spline", make_interp_spline(self.kernels.psi_nodes, trace, k=3))

    def __call__(self, x: Any) -> Array:
        plant = self.kernels.plant
        xi = np.clip(np.asarray(x, dtype=float), 0.0, plant.length)
        value = np.asarray(self.spline(np.asarray(plant.psi(xi))))
        weight = plant.A(xi) if self.which == "u" else plant.D(xi)
        speed = plant.coefficient("lam" if self.which == "u" else "mu", xi)
        return value * np.exp(plant.D(plant.length) - weight) / speed


@dataclass(frozen=True, repr=False, eq=False)
class VaryingKernels:
    """Backstepping kernels of a general plant with any speeds (module notes).

    Attributes
    ----------
    plant : GeneralHyperbolic2x2
        The plant.
    grid : ndarray, shape (n,)
        Uniform physical nodes ``x_i = i L / (n - 1)``.
    K, L : ndarray, shape (2, 2, n, n)
        ``K[a, b, i, k] = K^{ab}(x_i, xi_k)`` (``a, b`` in ``(u, v)``) in the plant's
        coordinates (the exponential factors of the diagonal terms included) and the
        inverse kernels ``L^{ab}`` (``a, b`` in ``(alpha, beta)``), for ``k <= i``. The pairs
        are solved on grids uniform in ``phi`` and ``psi`` and carried to ``grid`` by
        piecewise-linear interpolation on the triangulated grid (second order).
    psi_nodes : ndarray, shape (n,)
        Uniform nodes of ``[0, t_v]`` (``t_v = int 1/mu``) on which the pair
        ``(k^{vv}, k^{vu})`` was solved.
    trace_vu, trace_vv : ndarray, shape (n,)
        ``k^{vu} = lam K~^{vu}`` and ``k^{vv} = mu K~^{vv}`` at ``x = L``, at ``xi(psi_nodes)``
        (the gains of U_BS, interpolated by cubic splines in ``psi``).
    """

    plant: GeneralHyperbolic2x2
    grid: Array
    K: Array
    L: Array
    psi_nodes: Array
    trace_vu: Array
    trace_vv: Array

    @property
    def n(self) -> int:
        """Grid points per direction."""
        return int(self.grid.size)

    def feedback_law(self) -> FeedbackLaw:
        """U_BS in the plant's coordinates: ``-rho u(t, L) + int_0^L K^{vu}(L, .) u + K^{vv}(L, .) v``.

        The gains are callables on ``[0, L]`` (cubic splines of the traces in ``psi``), for
        :func:`~nrobust.hyperbolic.simulate.general.simulate_general`,
        :class:`~nrobust.hyperbolic.loops.controllers.StateFeedback` and
        :func:`~nrobust.hyperbolic.loops.feedback.laplace_loop_factors`.
        """
        return FeedbackLaw(-self.plant.rho, _TraceGain(self, "u"), _TraceGain(self, "v"))

    def _on_delay_axis(self, f_alpha: Array, f_beta: Array) -> DistributedDelay:
        """A kernel of the delay axis from its branches on ``grid``, in ``time_unit``; a jump at ``t_v``.

        Along the target's characteristics ``beta(t, xi) = e^{D(xi) - D(L)} beta(t - t_v + psi(xi), L)``
        and ``alpha(t, xi) = q e^{A(xi) - D(L)} beta(t - t_v - phi(xi), L)``, so
        ``int f_alpha alpha + f_beta beta dxi`` is ``int M(nu) beta(t - nu, L) dnu`` with
        ``M(t_v - psi(xi)) = e^{D(xi) - D(L)} mu(xi) f_beta(xi)`` and
        ``M(t_v + phi(xi)) = q e^{A(xi) - D(L)} lam(xi) f_alpha(xi)``.
        """
        from scipy.interpolate import make_interp_spline  # lazily: scipy.interpolate is slow to import

        plant = self.plant
        unit = plant.time_unit
        xi = self.grid
        t_v = plant.transport_times[1]
        d_end = plant.D(plant.length)
        beta_nodes = np.maximum(t_v - plant.psi(xi), 0.0)[::-1]
        beta_values = (np.exp(plant.D(xi) - d_end) * plant.coefficient("mu", xi) * f_beta)[::-1]
        alpha_nodes = t_v + plant.phi(xi)
        alpha_values = plant.q * np.exp(plant.A(xi) - d_end) * plant.coefficient("lam", xi) * f_alpha
        beta_nodes[0], beta_nodes[-1], alpha_nodes[0] = 0.0, t_v, t_v
        # Each branch resampled on uniform nodes (not-a-knot cubic spline, fourth order): the
        # exponential sums of a DistributedDelay are fast transforms on uniform nodes only.
        beta_uniform = np.linspace(0.0, t_v, xi.size)
        alpha_uniform = np.linspace(t_v, plant.tau, xi.size)
        beta_values = make_interp_spline(beta_nodes, beta_values, k=3)(beta_uniform)
        alpha_values = make_interp_spline(alpha_nodes, alpha_values, k=3)(alpha_uniform)
        nodes = np.concatenate([beta_uniform, alpha_uniform]) / unit
        values = np.concatenate([beta_values, alpha_values]) * unit
        return DistributedDelay(nodes, values, interpolation="cubic")

    def N_tilde(self) -> DistributedDelay:
        """``N~`` of the delay form (module notes) on ``[0, tau]``, in ``time_unit``; a jump at ``t_v``."""
        rho = self.plant.rho
        last = self.L[:, :, -1, :]
        return self._on_delay_axis(last[1, 0] - rho * last[0, 0], last[1, 1] - rho * last[0, 1])

    def feedback_factor(self, k: float, g_u: Any, g_v: Any) -> QuasiPolynomial:
        """``P(s)`` of any state feedback ``U = k u(t, L) + int_0^L g_u u + g_v v dx`` (loop factor ``B = -P``).

        In the target coordinates (``u = alpha + int L^{alpha alpha} alpha + L^{alpha beta} beta``, ...)
        the feedback is ``k alpha(L) + int W_alpha alpha + W_beta beta dxi`` with
        ``W_alpha(xi) = k L^{aa}(L, xi) + g_u(xi) + int_xi^L g_u(x) L^{aa}(x, xi) + g_v(x) L^{ba}(x, xi) dx``
        (``W_beta`` with ``L^{ab}``, ``L^{bb}`` and ``g_v(xi)``; trapezoidal rule on ``grid``, second
        order like the kernels), so ``P = k q e^{A(L) - D(L)} e^{-tau s} + int M e^{-nu s} dnu``
        with ``M`` the branches ``W_alpha, W_beta`` on the delay axis (as ``N~``; for U_BS,
        ``P = -Phi``). This is :func:`~nrobust.hyperbolic.loops.feedback.feedback_factor` with varying
        speeds.

        Parameters
        ----------
        k : float
            Gain on ``u(t, L)``.
        g_u, g_v : float or callable
            Gains of the integral term on ``[0, L]``, in the plant's coordinates.
        """
        plant = self.plant
        k = finite_real("k", k)
        x = self.grid
        wu, wv = feedback_gain("g_u", g_u, plant.length)(x), feedback_gain("g_v", g_v, plant.length)(x)
        h = plant.length / (x.size - 1)
        L = self.L

        def tails(weight: Array, table: Array) -> Array:
            """``int_{xi_j}^L weight(x) table(x, xi_j) dx`` per column (trapezoidal rule)."""
            m = weight[:, None] * table
            return h * (np.sum(m, axis=0) - 0.5 * np.diagonal(m) - 0.5 * m[-1])

        w_alpha = k * L[0, 0, -1] + wu + tails(wu, L[0, 0]) + tails(wv, L[1, 0])
        w_beta = k * L[0, 1, -1] + wv + tails(wu, L[0, 1]) + tails(wv, L[1, 1])
        gain = k * plant.q * float(np.exp(plant.A(plant.length) - plant.D(plant.length)))
        tau = plant.tau / plant.time_unit
        return QuasiPolynomial([[gain]], [tau], [self._on_delay_axis(w_alpha, w_beta)])

    def loop_factors(self) -> tuple[QuasiPolynomial, QuasiPolynomial]:
        """``(A, B) = (1 - Phi, Phi)`` of U_BS, ``Phi = rho_q e^{-tau s} - int N~ e^{-nu s} dnu``."""
        plant = self.plant
        tau = plant.tau / plant.time_unit
        phi = QuasiPolynomial([[plant.rho_q]], [tau]) - QuasiPolynomial([], [], [self.N_tilde()])
        return 1.0 - phi, phi

    def characteristic(self, delta: float = 0.0) -> QuasiPolynomial:
        """``F(s; delta) = 1 - Phi + Phi e^{-delta s}`` of U_BS with the loop delay ``delta >= 0`` (``time_unit``)."""
        a, b = self.loop_factors()
        return a + b.shift(nonnegative("delta", delta))

    def __repr__(self) -> str:
        return f"VaryingKernels(plant={self.plant!r}, n={self.n})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary: the plant, the grid and the traces ``K^{ab}(L, xi)``, ``L^{ab}(L, xi)``."""
        names = ("uu", "uv", "vu", "vv")
        traces = {f"K{nm}": self.K[i // 2, i % 2, -1] for i, nm in enumerate(names)}
        traces.update({f"L{nm}": self.L[i // 2, i % 2, -1] for i, nm in enumerate(("aa", "ab", "ba", "bb"))})
        return json_safe({"type": "VaryingKernels", "plant": self.plant, "xi": self.grid, "trace_xL": traces})


def solve_varying_kernels(plant: GeneralHyperbolic2x2, kernel_grid: int = DEFAULT_KERNEL_GRID) -> VaryingKernels:
    """Solve the kernel equations with varying speeds (module notes), second order.

    Parameters
    ----------
    plant : GeneralHyperbolic2x2
        Any speeds (a constant ratio too: for ``a = d = 0``, ``L = 1`` and constant speeds
        the kernels are those of :func:`~nrobust.hyperbolic.kernels.solve_kernels` without
        extrapolation).
    kernel_grid : int, default :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID`
        Points per direction of each pair's grid and of the physical grid, ``>= 5`` and
        ``<=`` :data:`~nrobust.hyperbolic.kernels.constant.MAX_KERNEL_GRID`, fine enough for the
        couplings (grid step in transport time times the largest source coefficient at
        most :data:`~nrobust.hyperbolic.kernels.constant.RESOLUTION`); both checked before any
        table is allocated.

    Returns
    -------
    VaryingKernels

    Raises
    ------
    ParameterError
        ``plant`` not a :class:`GeneralHyperbolic2x2` or with couplings no admissible grid
        resolves; ``kernel_grid`` out of range or too coarse for the couplings.
    """
    if not isinstance(plant, GeneralHyperbolic2x2):
        raise ParameterError("plant", "a GeneralHyperbolic2x2", plant)
    n = check_kernel_grid(kernel_grid)
    maps = _maps(plant)
    pairs = _pairs(plant, maps)
    _check_grid(plant, pairs, n)
    length = plant.length
    grid = np.linspace(0.0, length, n)
    rows, cols = np.tril_indices(n)
    X, XI = grid[rows], grid[cols]
    lam_xi, mu_xi = plant.coefficient("lam", XI), plant.coefficient("mu", XI)
    A_x, A_xi, D_x, D_xi = plant.A(X), plant.A(XI), plant.D(X), plant.D(XI)
    K = np.zeros((2, 2, n, n))
    traces = []
    for pair, (diag, cross), speeds, weight_x in (
        (pairs[0], ((0, 0), (0, 1)), (lam_xi, mu_xi), A_x),
        (pairs[1], ((1, 1), (1, 0)), (mu_xi, lam_xi), D_x),
    ):
        P, Q = _march(pair, maps, n, length)
        traces.append((P[-1].copy(), Q[-1].copy()))
        total = float(pair.Y(length))
        y, eta = np.asarray(pair.Y(X)) / total, np.asarray(pair.Y(XI)) / total
        eta = np.minimum(eta, y)
        weight_xi = {0: A_xi, 1: D_xi}
        K[diag][rows, cols] = p1_interpolate(P, y, eta) / speeds[0] * np.exp(weight_x - weight_xi[diag[1]])
        K[cross][rows, cols] = p1_interpolate(Q, y, eta) / speeds[1] * np.exp(weight_x - weight_xi[cross[1]])
    if not np.all(np.isfinite(K)):
        raise ParameterError("kernel_grid", "large enough for the kernel scheme to be well posed", n)
    # L = K + K o L on [0, L]: the resolvent of kernels.py works on [0, 1]; scale by the length.
    L = resolvent(K * length) / length
    psi_nodes = np.linspace(0.0, plant.transport_times[1], n)
    return VaryingKernels(plant, grid, K, L, psi_nodes, traces[1][1], traces[1][0])
