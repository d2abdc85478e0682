"""A proven bound of the grid kernels' error in ``G`` and of the cascade loop it moves (``n + m`` systems).

The kernels ``Z = [K, L]`` of :mod:`nrobust.hyperbolic.nplusm.kernels` solve, entry by entry
``e = (a, b)``, the integral equations along their characteristics ``dxi/dx = slope_e``::

    Z_e(P) = B_e(Z)(P_f) + int_{P_f}^{P} (M Z)_e / mu_a dx,     (M Z)_e = (Z Sigma - D Z)_e,

``P_f`` the foot of the characteristic through ``P`` on the boundary the entry starts from: the
diagonal (a constant ``B_e``), ``x = 1`` (the artificial constant of the entries ``mu_c > mu_a``)
or ``xi = 0``, where ``B_e(Z) = sum_k (Lambda+ Q)_kc K_ak(x_f, 0) / mu_c`` (``G_ac = 0``).

**Residual.** ``Z_h`` is the grid solution, linear on the triangles of the grid (the
interpolation of :class:`~nrobust.hyperbolic.nplusm.NPlusMKernels`). On a triangle its
derivative along the characteristic is constant and ``(M Z_h)_e`` is linear, so the defect
``delta_e = d Z_h,e / dx - (M Z_h)_e / mu_a`` is affine there: its maximum ``Delta_e`` is at a
vertex and ``int_T |delta_e| <= ||delta_e||_1``, the sum of the triangles' areas times their mean
vertex modulus. Along each boundary ``Z_h`` is linear between nodes, so the boundary defect
``beta_e = max |Z_h,e - B_e(Z_h)|`` is a maximum over nodes. With the integrating factor of the
entry's own coupling ``M_ee`` (at most ``chi_e = e^{|M_ee| / mu_a}`` over ``x``-lengths ``<= 1``) the
map ``Phi`` of the integral equations has a linear part ``A`` without diagonal, and the residual
``rho_h = Z_h - Phi(Z_h)`` obeys ``|rho_h,e| <= chi_e (beta_e + int |delta_e|)`` along the
characteristic. Entries of equal slope share their characteristics (the entries of a group of
equal speeds, for instance): their couplings are integrated exactly as well, with the
matrix factor ``e^{tau Ms}``, entrywise at most ``X = exp(|Ms|)`` (``Ms_ef = M_ef / mu_a`` on the
class), and ``chi_e`` above stands for ``X`` applied to the vector of bounds. Where a kernel has a
kink along its own characteristic (the one through ``(1, 1)``
of ``L_ac``, ``mu_c > mu_a``, or through the origin of ``L_ac``, ``mu_c < mu_a``), ``delta_e`` is of
order 1 on the cells that straddle it, so ``rho_h`` is not small there. The bound is therefore
built for the one-step Picard image ``Z~ = Phi(Z_h) = Z_h - rho_h``, whose residual is
``A rho_h``: entry ``f`` integrates ``rho_h,e`` (``e != f``) along its own characteristics, which
cross those of ``e``; the change of variables ``(t, tau) -> c_f(t) - tau (1, slope_e)`` has the
Jacobian ``|slope_f - slope_e|``, so that integral is at most
``chi_e (beta_e + min(Delta_e, ||delta_e||_1 / |slope_f - slope_e|))``, first order in the grid step
when the kernels are continuous. The boundary relation reads ``rho_h`` of ``K`` at a point
(``sup``: first order when ``K`` has no kink, which a jump of another kernel would give it).
The bound degrades when two slopes are close (the rates ``1 / |slope_f - slope_e|`` and
``1 / r_e`` below).
``Z~ - Z_h`` at ``xi = 0`` is ``-rho_h``, bounded likewise in ``L^1(0, 1)`` (Jacobian
``|slope_e|``).

**Volterra structure.** Along every characteristic, from its foot to ``P``, the potential
``phi = x - xi`` grows at the rate ``r_e = |1 - slope_e|`` per unit of ``x``, and the foot
``(x_f, 0)`` of a boundary relation has ``phi = x_f <= phi(P)``; only the entries ``L_ac`` with
``mu_c = mu_a`` (``r_e = 0``) integrate at constant ``phi``. With ``u_f(phi)`` the supremum of
``|Z_f - Z~_f|`` over ``phi(P) <= phi``, the error obeys ::

    u(phi) <= rho + N u(phi) + V int_0^phi u,       rho = sup |A rho_h|,

``N = X (B + |M'| / mu_a)``, ``B_ef = |(Lambda+ Q)_kc| / mu_c`` (boundary relation, ``f = K_ak``) and
``|M'|`` the couplings between entries of different slopes on the rows ``r_e = 0``, and
``V = X |M'| / (mu_a r_e)`` on the rows ``r_e > 0``. ``N`` is nilpotent: its rows of slope 1 read
entries of other slopes, its rows ``L_ac``, ``mu_c < mu_a``, read ``K``, and its rows ``K`` and
``L_ac``, ``mu_c > mu_a``, are zero, so ``N^3 = 0``, ``(I - N)^{-1} = I + N + N^2 >= 0`` and
Gronwall's lemma gives ::

    u(phi) <= exp(phi (I - N)^{-1} V) (I - N)^{-1} rho.

At ``xi = 0``, ``phi = x``: ``|G_ac - G~_ac|(x) <= mu_c u_{L_ac}(x) + sum_k |(Lambda+ Q)_kc| u_{K_ak}(x)``
on the entries ``mu_c > mu_a`` (the others are exactly 0 for the exact kernels and the loop
uses 0 there), and ``G~ - G_h`` is bounded from ``rho_h`` at ``xi = 0``.

**The loop.** On ``Re s >= 0``, ``||e^{x C(s)}|| <= e^{x mu_2}`` with ``mu_2`` the logarithmic
norm of ``Lambda-^{-1} D`` (``D`` commutes with ``Lambda-``), so ``E T`` of the exact kernels
lies within ``||V|| int_0^1 e^{x max(mu_2, 0)} ||Lambda-^{-1} (G - G_h)(x)|| dx`` of
:meth:`~nrobust.hyperbolic.nplusm.NPlusMBackstepping.target_transition` at every such ``s``
(module notes of :mod:`nrobust.hyperbolic.nplusm.kernels`); for ``G - G~`` the integrand is
bounded by its value at the right end of each of ``pieces`` intervals (both factors are
nondecreasing), for ``G~ - G_h`` by the ``L^1`` bound times ``e^{max(mu_2, 0)}``.

The small matrices (``(I - N)^{-1}``, the exponentials, the sum) are computed in ball
arithmetic (python-flint); the defects in floating point with a bound of their rounding. The
slopes are compared, and the divisors ``|slope_f - slope_e|``, ``r_e``, ``|slope_e|`` taken, as
rationals of the speeds rounded down (two close slopes rounded to doubles would move their
difference by ``2^-53 / |slope_f - slope_e|`` relative, beyond any allowance for rounding). The
loop's bound is first order in the grid step (``tests/test_nplusm_kernel_proof.py``: 0.092,
0.047, 0.023 on 21, 41, 81 points where the error of ``G`` is of order 2, 4.7e-4 to 3.0e-5); the
supremum ``g_error`` is not (a kink smeared over one cell at ``xi = 0``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._flint import ball_upper, precision, require_flint
from ..._json import fields_dict
from ..._validate import positive_int
from ...errors import ParameterError
from .kernels import NPlusMKernels, entry_kind, in_group_part, rhs_matrix

__all__ = ["KernelErrorBound", "kernel_error_bound"]

_EPS = float(np.finfo(float).eps)
_PREC = 80  # bits of the ball arithmetic


@dataclass(frozen=True)
class KernelErrorBound:
    """Proven bounds of the error of the grid kernels (module notes).

    Attributes
    ----------
    kernel_grid : int
        Grid points ``N`` per side of the triangle.
    residual : ndarray, shape (m (n + m),)
        ``rho_e``: a bound of the residual of the one-step Picard image ``Z~`` of the grid kernels
        in the integral equations, per entry ``e = a (n + m) + b`` of ``Z = [K, L]``.
    growth : ndarray, shape (m (n + m), m (n + m))
        Upper bound of ``(I - N)^{-1} V``, the rate of Gronwall's exponential in ``phi = x - xi``.
    kernel_error : ndarray, shape (m (n + m),)
        A bound of ``sup_T |Z_e - Z_h,e|``.
    g_error : ndarray, shape (m, m)
        ``sup_x |G_ac - G_h,ac|`` on the entries ``mu_c > mu_a`` (0 on the others: exact).
    transition_error : float
        ``eps``: ``||E T - E T_h||_2 <= eps`` at every ``s`` with ``Re s >= 0``, ``E T`` of the
        exact kernels and ``E T_h`` of :meth:`~nrobust.hyperbolic.nplusm.NPlusMBackstepping.target_transition`.
    """

    kernel_grid: int
    residual: NDArray[np.float64]
    growth: NDArray[np.float64]
    kernel_error: NDArray[np.float64]
    g_error: NDArray[np.float64]
    transition_error: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


def _down(x: Fraction) -> float:
    """The largest float ``<= x``."""
    f = float(x)
    return math.nextafter(f, -math.inf) if Fraction(f) > x else f


def _exact_slopes(system: Any) -> list[Fraction]:
    """The slope ``dxi/dx`` of each entry ``e = a (n + m) + b`` as the rational of the system's numbers:
    ``-lam_b / mu_a`` (``K``), ``mu_c / mu_a`` (``L_ac``), as :func:`entry_kind` gives them in floating point."""
    n, m = system.n, system.m
    lam = [Fraction(float(x)) for x in system.lam]
    mu = [Fraction(float(x)) for x in system.mu]
    return [(-lam[b] if b < n else mu[b - n]) / mu[a] for a in range(m) for b in range(n + m)]


def _slope_gaps(system: Any) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The slopes of the kernel entries compared exactly: ``(same, gaps, rates, moduli)``.

    ``same[e, f]``: the entries share their characteristics (equal slopes as rationals, not as
    rounded doubles); ``gaps[e, f] <= |slope_e - slope_f|``, ``rates[e] <= |1 - slope_e|`` (the growth
    rate ``r_e`` of ``phi``) and ``moduli[e] <= |slope_e|``, floats rounded down from the exact
    values: the bound divides by them, and a slope rounded to a double moves a difference of
    close slopes by up to ``2^-53 / |slope_e - slope_f|`` relative.
    """
    slopes = _exact_slopes(system)
    same = np.array([[x == y for y in slopes] for x in slopes])
    gaps = np.array([[_down(abs(x - y)) for y in slopes] for x in slopes])
    rates = np.array([_down(abs(1 - x)) for x in slopes])
    moduli = np.array([_down(abs(x)) for x in slopes])
    return same, gaps, rates, moduli


def _triangle_defects(
    Z: NDArray[np.float64], MZ: NDArray[np.float64], scale: NDArray[np.float64], slopes: NDArray, mu_row: NDArray
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(max |delta_e|, int_T |delta_e|)`` over the triangles of the grid, per entry, rounding included.

    ``delta_e`` is affine on a triangle: its maximum modulus is at a vertex, and by convexity
    ``int |delta_e| <= area (|delta_1| + |delta_2| + |delta_3|) / 3``.
    """
    E, N = Z.shape[0], Z.shape[1]
    h = 1.0 / (N - 1)
    ii, jj = np.tril_indices(N - 1)  # lower triangles (i, j), (i + 1, j), (i + 1, j + 1)
    up = jj < ii  # upper triangles (i, j), (i, j + 1), (i + 1, j + 1)
    iu, ju = ii[up], jj[up]
    tri = [
        ((ii, jj), (ii + 1, jj), (ii + 1, jj + 1), 1),  # d/dx: v1 - v0, d/dxi: v2 - v1
        ((iu, ju), (iu, ju + 1), (iu + 1, ju + 1), 0),  # d/dxi: v1 - v0, d/dx: v2 - v1
    ]
    sup, l1 = np.zeros(E), np.zeros(E)
    for e in range(E):
        z, mz, sc = Z[e], MZ[e] / mu_row[e], scale[e] / mu_row[e]
        for v0, v1, v2, lower in tri:
            d01, d12 = (z[v1] - z[v0]) / h, (z[v2] - z[v1]) / h
            zx, zxi = (d01, d12) if lower else (d12, d01)
            dd = zx + slopes[e] * zxi
            size = (np.abs(z[v0]) + 2 * np.abs(z[v1]) + np.abs(z[v2])) / h * (1 + abs(slopes[e]))
            total = np.zeros(dd.shape)
            for v in (v0, v1, v2):
                at = np.abs(dd - mz[v]) + 16 * _EPS * (size + np.abs(mz[v]) + sc[v])
                sup[e] = max(sup[e], float(np.max(at)))
                total += at
            l1[e] += float(np.sum(total)) * (h * h / 6.0) * (1 + 1e-12)
    return sup, l1


def kernel_error_bound(kernels: NPlusMKernels, *, pieces: int = 256) -> KernelErrorBound:
    """Proven bound of ``sup |G - G_h|`` and of the cascade loop's ``E T`` error on ``Re s >= 0``.

    Parameters
    ----------
    kernels : NPlusMKernels
        The grid kernels (:func:`~nrobust.hyperbolic.nplusm.solve_nplusm_kernels`).
    pieces : int, optional
        Intervals (``>= 1``) of the upper sum of the integral over ``x`` (module notes).

    Returns
    -------
    KernelErrorBound

    Raises
    ------
    ImportError
        python-flint is missing (``pip install nrobust[rigorous]``).
    """
    if not isinstance(kernels, NPlusMKernels):
        raise ParameterError("kernels", "an NPlusMKernels (solve_nplusm_kernels)", type(kernels).__name__)
    pieces = positive_int("pieces", pieces)
    flint = require_flint()
    sys = kernels.system
    n, m, mu = sys.n, sys.m, sys.mu
    width = n + m
    E = m * width
    N = kernels.grid.size
    Z = np.concatenate([kernels.K, kernels.L], axis=1).reshape(E, N, N)
    M = rhs_matrix(sys)
    lq = sys.lam[:, None] * sys.q
    entries = [entry_kind(sys, a, b) for a in range(m) for b in range(width)]
    slopes = np.array([sl for _, sl, _ in entries])
    same_slope, gaps, rates, moduli = _slope_gaps(sys)
    mu_row = np.repeat(mu, width)
    MZ = np.tensordot(M, Z, axes=(1, 0))
    scale = np.tensordot(np.abs(M), np.abs(Z), axes=(1, 0)) * E

    defect, defect_l1 = _triangle_defects(Z, MZ, scale, slopes, mu_row)
    beta = np.zeros(E)
    diag_idx = np.arange(N)
    for e, (kind, _, diag) in enumerate(entries):
        a, b = divmod(e, width)
        if kind != "same":
            on_diag = Z[e, diag_idx, diag_idx]
            beta[e] = float(np.max(np.abs(on_diag - diag) + 4 * _EPS * (np.abs(on_diag) + abs(diag))))
        if kind == "reverse":
            top = Z[e, -1, :]
            beta[e] = max(beta[e], float(np.max(np.abs(top - diag) + 4 * _EPS * (np.abs(top) + abs(diag)))))
        if kind in ("low", "same"):
            c = b - n
            terms = Z[a * width : a * width + n, :, 0] * (lq[:, c] / mu[c])[:, None]
            rel = Z[e, :, 0] - terms.sum(axis=0)
            err = 4 * (n + 2) * _EPS * (np.abs(Z[e, :, 0]) + np.abs(terms).sum(axis=0))
            beta[e] = max(beta[e], float(np.max(np.abs(rel) + err)))
    # entries of equal slope share their characteristics: their couplings are integrated exactly (integrating
    # factor e^{tau Ms}, entrywise at most X = exp(|Ms|) over x-lengths <= 1), the others form A
    off = np.where(same_slope, 0.0, np.abs(M))
    with precision(flint, _PREC):
        # an entry of M is one double or the rounded sum of two (sigma_bb - D_aa): within 2^-53 of it relative,
        # so |M| (1 + 2^-52) bounds the exact one; the exponent in balls (entrywise monotone)
        bound = 1 + flint.arb(2) ** -52
        big = flint.arb_mat(
            [
                [flint.arb(abs(float(M[i, j]))) * bound / float(mu_row[i]) if same_slope[i, j] else 0 for j in range(E)]
                for i in range(E)
            ]
        ).exp()
        X = np.array([[ball_upper(big[i, j]) for j in range(E)] for i in range(E)])
    coupling = np.zeros((E, E))  # |B_e|: the boundary relation at xi = 0 reads K_ak(x_f, 0)
    for e, (kind, _, _) in enumerate(entries):
        a, b = divmod(e, width)
        if kind in ("low", "same"):
            coupling[e, a * width : a * width + n] = np.abs(lq[:, b - n]) / mu[b - n]
    up = 1 + 16 * E * _EPS  # sums and products of nonnegative floats, rounded upwards
    # residual of Z_h with the integrating factor: its supremum, and its integral along a crossing characteristic
    first = X @ (beta + defect) * up
    cross = np.empty((E, E))  # cross[f]: int of |rho_h| along a characteristic of f (x-length <= 1)
    for f in range(E):
        with np.errstate(divide="ignore", invalid="ignore"):
            spread = np.where(gaps[f] > 0, defect_l1 / gaps[f], np.inf)
        cross[f] = X @ (beta + np.minimum(defect, spread)) * up
    # residual of the one-step Picard image Z~ = Phi(Z_h): A applied to the residual of Z_h
    rho = X @ ((coupling * first[None, :]).sum(axis=1) + (off / mu_row[:, None] * cross).sum(axis=1)) * up**2
    # int_0^1 |Z~_e - Z_h,e|(x, 0) dx: the Picard step moves the trace at xi = 0 by the residual of Z_h there
    with np.errstate(divide="ignore"):
        trace_l1 = X @ (beta + np.minimum(defect, defect_l1 / moduli)) * up

    is_same = np.array([kind == "same" for kind, _, _ in entries])
    Nm = X @ (coupling + np.where(is_same[:, None], off / mu_row[:, None], 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        Vm = X @ np.where(is_same[:, None], 0.0, off / (mu_row * rates)[:, None])
    Nm, Vm = Nm * up, Vm * up

    with precision(flint, _PREC):

        def mat(x: NDArray[Any]) -> Any:
            return flint.arb_mat([[flint.arb(float(v)) for v in row] for row in np.atleast_2d(x)])

        # N^3 = 0 (module notes): (I - N)^{-1} = I + N + N^2
        n_ball = mat(Nm)
        inv = flint.arb_mat(E, E, [flint.arb(int(i == j)) for i in range(E) for j in range(E)]) + n_ball
        inv = inv + n_ball * n_ball
        growth = inv * mat(Vm)
        u = inv * mat(rho[:, None])
        step = (growth * (flint.arb(1) / pieces)).exp()
        # Lambda-^{-1} D from the exact data (1 / mu_a a ball): Gershgorin's bound of the logarithmic norm of its
        # symmetric part, and ||V||_F, V = exp(-Lambda-^{-1} D)
        d_mat = in_group_part(sys)
        a_ball = flint.arb_mat([[flint.arb(float(d_mat[a, c])) / float(mu[a]) for c in range(m)] for a in range(m)])
        rows = [
            0.5 * (a_ball[i, i] + a_ball[i, i])
            + sum((abs(0.5 * (a_ball[i, k] + a_ball[k, i])) for k in range(m) if k != i), flint.arb(0))
            for i in range(m)
        ]
        lognorm = max(0.0, max(ball_upper(r) for r in rows))
        v_norm = flint.arb(0)
        for x in (-a_ball).exp().entries():
            v_norm += x * x
        v_norm = v_norm.sqrt()
        used = [(a, c) for a in range(m) for c in range(m) if mu[c] > mu[a]]
        lq_ball = [[abs(flint.arb(float(sys.lam[j])) * float(sys.q[j, c])) for c in range(m)] for j in range(n)]
        total = flint.arb(0)
        g_sup = np.zeros((m, m))
        for k in range(1, pieces + 1):
            u = step * u
            norm2 = flint.arb(0)
            for a, c in used:
                g = mu[c] * u[a * width + n + c, 0]
                for j in range(n):
                    g += lq_ball[j][c] * u[a * width + j, 0]
                if k == pieces:
                    g_sup[a, c] = ball_upper(g)
                norm2 += (g / float(mu[a])) ** 2
            total += norm2.sqrt() * (flint.arb(lognorm) * k / pieces).exp()
        # the Picard step Z~ - Z_h at xi = 0: in sup for g_error, in L^1 for the loop
        step_l1 = flint.arb(0)
        for a, c in used:
            l1 = mu[c] * trace_l1[a * width + n + c] + sum(abs(lq[j, c]) * trace_l1[a * width + j] for j in range(n))
            sup = mu[c] * first[a * width + n + c] + sum(abs(lq[j, c]) * first[a * width + j] for j in range(n))
            g_sup[a, c] = math.nextafter(g_sup[a, c] + float(sup) * (1 + 8 * (n + 2) * _EPS), math.inf)
            step_l1 += flint.arb(float(l1) * (1 + 8 * (n + 2) * _EPS)) / float(mu[a])
        eps = ball_upper(v_norm * (total / pieces + step_l1 * flint.arb(lognorm).exp()))
        kernel_error = np.array([ball_upper(u[e, 0] + first[e]) for e in range(E)])
        growth_up = np.array([[ball_upper(growth[i, j]) for j in range(E)] for i in range(E)])
    return KernelErrorBound(N, rho, growth_up, kernel_error, g_sup, eps)
