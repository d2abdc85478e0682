"""The square of speed mismatches proven on a coupled plant with constant couplings: :func:`prove_coupled_square`.

The notes below are for ``U = k u(t, 1)``; a law with integral gains fixed whatever the speeds (a
:class:`~nrobust.hyperbolic.loops.controllers.StateFeedback`, ``U_BS2(K)`` with its traces enclosed) adds
``-I_g`` to ``B1``, enclosed on each box by the kernel of its middle plant and the smaller of the ``L^1`` bound
of the other kernels of the box (:mod:`~nrobust.hyperbolic.analyses.mismatch_gains`) and the centred form in
``(p, m, r)`` (:mod:`~nrobust.hyperbolic.analyses.mismatch_slopes`), and bounded by ``V_g / |z|`` and by
``V_{g,1} / |z| + V_{g,2} / |z|^2`` in step 1; gains known within ``gain_error`` widen it by their ``L^1`` part
and lower the gap ``1 - c_D`` of step 1 by as much.

The law ``U = k u(t, 1)`` (a proportional :class:`~nrobust.hyperbolic.loops.controllers.StateFeedback`:
no integral gain, so the law does not depend on the speeds it was designed for) acts on the plant
(18)-(20) transporting at ``lam' = lam (1 + e_lam)`` and ``mu' = mu (1 + e_mu)``. Its loop is exact
(:mod:`~nrobust.hyperbolic.loops.exact_form`): ``F(s) = A(s) + B(s) e^{-delta s}`` with
``A = 1 - rho q e^{-tau s} + int_0^tau N~(nu) e^{-nu s} dnu`` and ``B = -k (q e^{-tau s} + int_0^tau
U~(nu) e^{-nu s} dnu)``, ``tau = 1/lam' + 1/mu'``. In the scaled frequency ``z = tau s`` the kernels
depend on the speeds only through ``p = sigma_pm / lam'`` and ``m = -sigma_mp / mu'``
(``tau N~(tau theta)`` is the ``N~`` of the plant with ``tau = 1``, the same ``p`` and ``m``: the
series of the module notes of ``exact_form`` in ``theta``, with ``a = kappa``)::

    F = A1(z; p, m) + B1(z; p, m) e^{-eta z},   eta = delta / tau,
    A1 = 1 - rho q e^{-z} + int_0^1 G_N(theta) e^{-z theta} dtheta,
    B1 = -k (q e^{-z} + int_0^1 G_U(theta) e^{-z theta} dtheta).

A box of speeds ``E`` gives balls of ``p`` and ``m`` around a midpoint ``(p_0, m_0)``. The kernels enter
``A1`` and ``B1`` in the centred (mean-value) form, first order in the box with an excess second order::

    int_0^1 G(theta; p, m) e^{-z theta} dtheta  in  int_0^1 G(theta; p_0, m_0) e^{-z theta} dtheta
        + D_p(z) [p - p_0] + D_m(z) [m - m_0],    D_p(z) = int_0^1 dG/dp(theta; E) e^{-z theta} dtheta,

the first integral the series at the midpoint (:func:`~nrobust.hyperbolic.loops.exact_form.closed_form_series`,
:func:`_scaled_kernel`) evaluated in ball arithmetic (:mod:`nrobust.balls`), ``D_p``, ``D_m`` complex balls
(:class:`_Slopes`: the slopes in closed form enclosed on cells of ``theta`` for every ``(p, m)`` of the box, each
cell's integral against ``e^{-z theta}`` in closed form), so the width of ``D_p [p - p_0]`` is ``|D_p|``, not
``sup |dG/dp|``, times the box: the oscillation of ``e^{-z theta}`` is kept. ``eta`` ranges over
``[d_min / tau_max(E), d_max / tau_min(E)]``. The proof is
the no-crossing argument of :mod:`~nrobust.hyperbolic.analyses.mismatch_proof` on the connected union
of the boxes ``(p, m, eta)``:

1. *No zero from infinity.* On ``Re z >= 0``, integrating by parts once,
   ``|int_0^1 G e^{-z theta}| <= V_0(G) / |z|`` with ``V_0(G) = |G(0)| + |G(1)| + sup |G'|``, and twice,
   ``<= V_1(G) / |z| + V_2(G) / |z|^2`` with ``V_1(G) = |G(0)| + |G(1)|``, ``V_2(G) = |G'(0)| +
   |G'(1)| + sup |G''|`` (the kernels and their derivatives in closed form: :func:`_variation`), so
   ``|F| >= 1 - c_D - (V_0(G_N) + |k| V_0(G_U)) / |z|``, ``c_D = |rho q| + |k q|``, and the same with
   the two-term bound. When the difference operator is strongly stable (``c_D < 1``) no zero has
   ``Re z >= 0`` and ``|z| >= W``, the smaller of ``(V_0(G_N) + |k| V_0(G_U)) / (1 - c_D)`` and the
   positive root of ``(1 - c_D) W^2 - V_1 W - V_2`` (``V_1 = V_1(G_N) + |k| V_1(G_U)``, ``V_2`` alike;
   the ``V`` bounded on the whole square). For strong couplings ``sup |G'|`` and ``sup |G''|`` grow like
   ``e^{2 sqrt|kappa|}``: the second ``W`` grows like its square root.
2. *No zero on the imaginary axis.* Boxes of ``(w, e_lam, e_mu)`` covering ``[0, W] x`` the square
   are cleared in ball arithmetic by the sign of ``|A1|^2 - |B1|^2``, by every crossing ``eta`` of the
   box lying outside its range, or by ``A + B e^{-i w delta}`` (``w delta`` a ball over the box and the
   delays) enclosed away from 0 (:func:`~nrobust.hyperbolic.analyses.mismatch_proof.crossing_free`); an
   undecided box is halved in ``w``, or in a speed when the enclosure at the middle ``w`` alone does not
   decide either, up to ``max_boxes`` boxes.
3. *One point.* The loop of a corner, proven stable on a window meeting the delays asked, lies in the
   family: it must be the exact loop of the corner plant under ``U = k u(t, 1)`` (checked: a loop on
   the kernel route is a model, not a point of the family); the square is widened by ``1e-12`` so
   that the corners' rounded speeds are in it, each ball of ``tau`` by ``2^-50`` relative so that
   the corners' stored round trips (the doubles nearest ``1/lam' + 1/mu'``) are in it, and the
   point coefficients ``rho q``, ``k q`` range over balls holding the exact products and the
   doubles the corners store.

The family is the connected set of ``(e_lam, e_mu, eta, c_A, c_B)``: a speed error of the widened
square, ``eta`` between ``d_min`` and ``d_max`` divided by that error's ``tau`` (widened), the
point coefficients in their balls; every box clears it for every ``w`` of its range.

The number of zeros in ``Re z >= 0`` is then the same on the whole family, zero at the corner, and a
strongly stable difference operator makes the loop exponentially stable (the criterion of the paper's
Theorems 3 and 4) for every ``(e_lam, e_mu)`` of the square and every delay of the window.
"""

from __future__ import annotations

import dataclasses
import heapq
import itertools
import math
from collections.abc import Sequence
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._digits import upper_bound_text
from ..._flint import ball_lower, ball_upper, precision, require_flint, working_precision
from ..._validate import finite_real, nonnegative, positive_int
from ...balls import BallQuasiPolynomial
from ...design.gain import DelayWindow, check_delays
from ...errors import CertificationError, ParameterError
from ...quasipoly import DistributedDelay, QuasiPolynomial
from ..loops.controllers import StateFeedback, loop_factors, loop_route
from ..loops.exact_form import PRECISION, closed_form_series, expand_piece, has_exact_form
from ..loops.exact_gains import gain_failure
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from .mismatch_gains import GainBounds, error_radius, gain_bounds, gain_term, gain_variations, time_ratio
from .mismatch_proof import SquareProof, crossing_free
from .mismatch_slopes import T_CELLS, GainPieces, GainSlopes, cell_integrals, gain_pieces

__all__ = ["MAX_COUPLED_BOXES", "MAX_GAIN_BOXES", "prove_coupled_square"]

#: Default work bound of :func:`prove_coupled_square`: a box costs a ball evaluation of the closed-form
#: series (about 14 ms), so 5,000 boxes stop an undecided proof within about a minute and a half.
MAX_COUPLED_BOXES = 5_000
#: Default work bound of :func:`~nrobust.hyperbolic.analyses.speed_tolerance` on a coupled plant under a law with
#: integral gains (``U_BS2(K)``, ``U_BS``): a box of speeds costs the gains' kernel of its middle plant as well
#: (about 0.1 s of CPU, 0.4 s on a loaded core), so 400 boxes stop an undecided proof within a few minutes.
MAX_GAIN_BOXES = 400
#: Pieces of ``[0, 1]`` on which the scaled kernels are stored for a box of speeds.
_PIECES = 16
#: Cells of ``[0, 1]`` on which the kernels' slopes in ``(p, m)`` are enclosed (:class:`_Slopes`).
_SLOPE_CELLS = 64
#: Relative widening of the square: the corners' speeds, rounded to doubles, lie in it.
_WIDEN = 1e-12
#: Width below which a box is not halved again, relative to ``W`` (frequency) or ``eps`` (speeds).
_MIN_WIDTH = 1e-9
#: Relative widening of each ball of ``tau``: the corners' stored round trips (``tau`` of a
#: :class:`~nrobust.hyperbolic.plants.hyperbolic2x2.Hyperbolic2x2`, three roundings) lie in it.
_TAU_SLACK = 2.0**-50


class _Box:
    """``A1`` and ``B1`` (module notes) for every speed of ``[a0, a1] x [b0, b1]``, in ball arithmetic."""

    def __init__(
        self, system: Hyperbolic2x2, law: StateFeedback, box: tuple[float, float, float, float], error: float = 0.0
    ) -> None:
        self.box = box
        k = law.k
        flint, P, M, T = _parameters(system, box)
        self.flint = flint
        (g_n, r_n), (g_u, r_u) = (_scaled_kernel(flint, P, M, system.q, system.rho, w) for w in ("N", "U"))
        self.slopes = [_Slopes(flint, P, M, system.q, system.rho, w) for w in ("N", "U")]
        self.k = k
        # the point coefficients rho q and -k q range over [c - err, c + err] (c the double): the error
        # of each joins the radius of the kernel next to it (on Re z = 0, where the factors are
        # evaluated, a radius r of a kernel on [0, 1] widens the value by r, and |e^{-z}| = 1)
        rq, kq, err_a, err_b = _point_coefficients(flint, system, k)
        self.A = BallQuasiPolynomial(QuasiPolynomial([[1.0], [-rq]], [0.0, 1.0]) + _distributed(g_n, r_n, 1.0, err_a))
        B = QuasiPolynomial([[kq]], [1.0]) + _distributed(g_u, r_u, -k, err_b)
        self.gains: tuple[GainSlopes, float] | None = None
        if _has_gains(law):  # B1 = -(k u_factor + I_g): the gains' term at the middle plant (mismatch_gains)
            with precision(flint, PRECISION):
                term = gain_term(flint, system, law.g_u, law.g_v, box, P, M, _gain_bounds(system, law), error)
                if term is not None:
                    slopes = GainSlopes(flint, _gain_pieces(system, law), system.q, *term.balls, term.offsets)
            if term is not None:
                B = B + QuasiPolynomial([], [], [_negated(term.kernel)])
                self.gains = (slopes, term.spread)
        self.B = BallQuasiPolynomial(B)
        self.tau = (T.lower(), T.upper())  # tau over the box, widened (_parameters)

    def factors(self, w0: float, w1: float) -> tuple[Any, Any]:
        """Enclosures of ``A1(i w)`` and ``B1(i w)`` for ``w`` in ``[w0, w1]`` and every speed of the box: the
        loop of the midpoint's kernels and the slopes' term of the centred form (module notes)."""
        box = (0.0, 0.0, w0, w1)
        centered = w1 > w0
        arb = self.flint.arb
        w = arb(w0).union(arb(w1))
        cells = cell_integrals(self.flint, w, _SLOPE_CELLS)
        n_slope, u_slope = (part.spread(cells) for part in self.slopes)
        u_slope = abs(arb(self.k)) * u_slope
        if self.gains is not None:  # the smaller of the centred form and the L^1 bound of the gains' kernels
            slopes, spread = self.gains
            u_slope += arb.min(slopes.spread(w, cell_integrals(self.flint, w, T_CELLS)), arb(spread))
        return (
            self.A.on_box(box, centered=centered) + self.flint.acb(arb(0, n_slope), arb(0, n_slope)),
            self.B.on_box(box, centered=centered) + self.flint.acb(arb(0, u_slope), arb(0, u_slope)),
        )


def _has_gains(law: StateFeedback) -> bool:
    """True when the law has an integral term (a callable or a nonzero gain)."""
    return any(callable(g) or g != 0.0 for g in (law.g_u, law.g_v))


@lru_cache(maxsize=16)
def _gain_bounds(system: Hyperbolic2x2, law: StateFeedback) -> GainBounds:
    """The sups of the law's gains (:func:`~nrobust.hyperbolic.analyses.mismatch_gains.gain_bounds`), once per law."""
    flint = require_flint()
    with precision(flint, PRECISION):
        return gain_bounds(flint, system, law.g_u, law.g_v)


@lru_cache(maxsize=16)
def _gain_pieces(system: Hyperbolic2x2, law: StateFeedback) -> GainPieces:
    """The Taylor models of the law's gains (:func:`~nrobust.hyperbolic.analyses.mismatch_slopes.gain_pieces`),
    once per law."""
    return gain_pieces(require_flint(), system, law.g_u, law.g_v)


def _negated(kernel: DistributedDelay) -> DistributedDelay:
    """``-kernel`` with the same radius (the stored pieces negated exactly)."""
    return DistributedDelay(
        kernel.nodes, None, interpolation="polynomial", coefficients=-kernel.pieces[2], radius=kernel.radius
    )


def _point_coefficients(flint: Any, system: Hyperbolic2x2, k: float) -> tuple[float, float, float, float]:
    """``(rho q, -k q)`` as doubles and bounds of their distance to the exact products: the balls
    ``[c - err, c + err]`` hold the PDE's coefficients and those a corner's loop stores."""
    arb = flint.arb
    rq, kq = system.rho * system.q, -k * system.q
    err_a = ball_upper(abs(arb(system.rho) * arb(system.q) - arb(rq)))
    err_b = ball_upper(abs(arb(k) * arb(system.q) + arb(kq)))
    return rq, kq, err_a, err_b


def _parameters(system: Hyperbolic2x2, box: tuple[float, float, float, float]) -> tuple[Any, Any, Any, Any]:
    """python-flint and the balls of ``p``, ``m`` and ``tau`` (widened by :data:`_TAU_SLACK`) over a box of
    relative speed errors."""
    flint = require_flint()
    arb = flint.arb
    a0, a1, b0, b1 = box
    lam = arb(system.lam) * (1 + arb(a0).union(arb(a1)))
    mu = arb(system.mu) * (1 + arb(b0).union(arb(b1)))
    P = arb(float(system.sigma_pm)) / lam  # type: ignore[arg-type]
    M = -arb(float(system.sigma_mp)) / mu  # type: ignore[arg-type]
    return flint, P, M, (1 / lam + 1 / mu) * (1 + arb(0, _TAU_SLACK))


def _scaled_kernel(flint: Any, P: Any, M: Any, q: float, rho: float, which: str) -> tuple[NDArray[np.float64], float]:
    """``G_N`` or ``G_U`` of the midpoint ``(p_0, m_0)`` of the balls on ``_PIECES`` pieces of ``[0, 1]``: the
    coefficients in ``t`` of each piece and a radius holding that kernel (the series at a point: tight; the
    other speeds of the box are the slopes' term, :class:`_Slopes`)."""
    arb = flint.arb
    bits = PRECISION + math.ceil(12.0 * math.sqrt(ball_upper(abs(P * M))))
    with precision(flint, bits):
        series, bound, _ = closed_form_series(flint, arb(1), arb(P.mid()), arb(M.mid()), (which, q, rho))
        width = 1.0 / _PIECES
        heads, err = [], arb(0)
        for i in range(_PIECES):
            head, e, _ = expand_piece(flint, series, arb(0), i * width, width)
            heads.append(head)
            err = arb.max(err, e)
        return np.asarray(heads), ball_upper(bound + err)


class _Slopes:
    """The slopes' term of the centred form (module notes) of ``G_N`` or ``G_U`` over balls ``P``, ``M``.

    On each cell ``C_i`` of width ``h = 1 / _SLOPE_CELLS`` around ``theta_i`` the slope ``dG/dp`` of every
    ``(p, m)`` of the balls lies in a ball ``c_i +- r_i`` (:func:`_parameter_slopes`), so on ``z = i w``
    (``|e^{-z theta}| = 1``)

        ``D_p(z) in sum_i c_i h e^{-i w theta_i} sinc(w h / 2) +- h sum_i r_i``

    (``int_{C_i} e^{-i w theta} dtheta = h e^{-i w theta_i} sinc(w h / 2)``), and ``D_m`` alike. By the mean-value
    theorem at each ``theta`` (the point on the segment from ``(p_0, m_0)`` to ``(p, m)``, in the balls),
    ``int (G(p, m) - G(p_0, m_0)) e^{-z theta}`` is ``(p - p_0)`` times a point of ``D_p`` plus ``(m - m_0)``
    times a point of ``D_m``.
    """

    def __init__(self, flint: Any, P: Any, M: Any, q: float, rho: float, which: str) -> None:
        arb = flint.arb
        self.flint = flint
        bits = PRECISION + math.ceil(12.0 * math.sqrt(ball_upper(abs(P * M))))
        self.offsets = (abs(P - arb(P.mid())).upper(), abs(M - arb(M.mid())).upper())
        self.mids: tuple[list[Any], list[Any]] = ([], [])
        rest = [arb(0), arb(0)]
        with precision(flint, bits):
            for i in range(_SLOPE_CELLS):
                theta = arb((i + 0.5) / _SLOPE_CELLS, 0.5 / _SLOPE_CELLS)
                for j, d in enumerate(_parameter_slopes(flint, P, M, q, rho, which, theta)):
                    if not d.is_finite():
                        raise CertificationError("the kernels' slopes on the box are not finite (couplings too strong)")
                    self.mids[j].append(arb(d.mid()))
                    rest[j] += arb(d.rad())
        self.rest = (rest[0] / _SLOPE_CELLS, rest[1] / _SLOPE_CELLS)

    def spread(self, cells: list[Any]) -> Any:
        """An upper bound (an ``arb``) of ``|D_p(i w)| |p - p_0| + |D_m(i w)| |m - m_0|`` for every ``w`` of a ball
        and ``(p, m)`` of the balls, from the cells' integrals ``int_{C_i} e^{-i w theta} dtheta`` on that ball
        (:func:`~nrobust.hyperbolic.analyses.mismatch_slopes.cell_integrals`)."""
        flint = self.flint
        arb, acb = flint.arb, flint.acb
        out = arb(0)
        for mids, rest, offset in zip(self.mids, self.rest, self.offsets):
            total = acb(0)
            for c, t in zip(mids, cells):
                total += c * t
            out += (abs(total) + rest) * offset
        return arb(out.upper())


def _parameter_slopes(flint: Any, P: Any, M: Any, q: float, rho: float, which: str, theta: Any) -> tuple[Any, Any]:
    """``(dG/dp, dG/dm)`` at the ball ``theta`` for every ``(p, m)`` of the balls (closed form of
    :func:`_kernel_jet`: ``d/dkappa 0F1(; b; kappa u) = u 0F1(; b + 1; kappa u) / b``, ``u = theta (1 - theta)``)."""
    arb = flint.arb
    kappa, u = P * M, _theta_product(flint, theta)
    x = kappa * u
    f1, f2, f3 = (x.hypgeom_0f1(b) for b in (1, 2, 3))
    dw = u * f2  # dW/dkappa
    dg = f2 + kappa * u * f3 / 2  # d(kappa 0F1(; 2; x))/dkappa
    dh22, dh11 = (1 - theta) * dg, theta * dg
    Q, R = arb(q), arb(rho)
    if which == "N":  # G = (m q - rho p) W + h_22 - rho q h_11
        dk = (M * Q - R * P) * dw + dh22 - R * Q * dh11
        return dk * M - R * f1, dk * P + Q * f1
    dk = Q * dh11 + P * dw  # G = q h_11 + p W
    return dk * M + f1, dk * P


def _theta_product(flint: Any, theta: Any) -> Any:
    """The ball of ``theta (1 - theta)`` over the ball ``theta`` (concave, largest at 1/2: no dependency)."""
    arb = flint.arb
    lo, hi = ball_lower(theta), ball_upper(theta)
    u = (arb(lo) * (1 - arb(lo))).union(arb(hi) * (1 - arb(hi)))
    return u.union(arb(0.25)) if lo <= 0.5 <= hi else u


def _distributed(coefficients: NDArray[np.float64], radius: float, factor: float, extra: float) -> QuasiPolynomial:
    """``factor int_0^1 G e^{-z theta}`` (``G`` the pieces ``coefficients`` within ``radius``), the radius
    ``|factor| radius`` widened for the rounding of the product and by ``extra``."""
    coefs = factor * coefficients
    slack = 4 * float(np.finfo(float).eps) * float(np.abs(coefs).sum(axis=1).max())
    kernel = DistributedDelay(
        np.linspace(0.0, 1.0, coefficients.shape[0] + 1),
        None,
        interpolation="polynomial",
        coefficients=coefs,
        radius=abs(factor) * radius * (1 + 4 * float(np.finfo(float).eps)) + slack + extra,
    )
    return QuasiPolynomial([], [], [kernel])


def _kernel_jet(flint: Any, P: Any, M: Any, q: float, rho: float, which: str, theta: Any) -> tuple[Any, Any, Any]:
    """``(G, G', G'')`` at the ball ``theta`` of ``[0, 1]`` for every ``(p, m)`` of the balls, in closed form.

    With ``tau = 1`` (:mod:`~nrobust.hyperbolic.loops.exact_form`) and ``x = kappa theta (1 - theta)``,
    ``kappa = p m``: ``W = 0F1(; 1; x)``, ``h_22 = kappa (1 - theta) 0F1(; 2; x)``,
    ``h_11 = kappa theta 0F1(; 2; x)``; ``G_N = h_22 - rho q h_11 + (m q - rho p) W`` and
    ``G_U = q h_11 + p W``. Derivatives by ``d/dx 0F1(; b; x) = 0F1(; b + 1; x) / b``. Each ``0F1`` is
    enclosed by Arb on the ball of ``x`` (no series in the monomials of ``theta``, whose ball
    coefficients overestimate the kernel by orders of magnitude when ``p, m`` are wide balls).
    """
    arb = flint.arb
    kappa = P * M
    x, dx, d2x = kappa * _theta_product(flint, theta), kappa * (1 - 2 * theta), -2 * kappa
    f = [x.hypgeom_0f1(b) for b in (1, 2, 3, 4)]  # 0F1(; b; x), b = 1..4
    w = (f[0], f[1] * dx, f[2] / 2 * dx * dx + f[1] * d2x)  # W and its derivatives
    g = (f[1], f[2] / 2 * dx, f[3] / 6 * dx * dx + f[2] / 2 * d2x)  # 0F1(; 2; x) and its derivatives
    rest, at = 1 - theta, theta  # h_22 = kappa rest g, h_11 = kappa at g (rest' = -1, at' = 1)
    h22 = (kappa * rest * g[0], kappa * (rest * g[1] - g[0]), kappa * (rest * g[2] - 2 * g[1]))
    h11 = (kappa * at * g[0], kappa * (at * g[1] + g[0]), kappa * (at * g[2] + 2 * g[1]))
    Q, R = arb(q), arb(rho)
    if which == "N":
        c_w, c_22, c_11 = M * Q - R * P, arb(1), -R * Q
    else:
        c_w, c_22, c_11 = P, arb(0), Q
    return tuple(c_w * w[j] + c_22 * h22[j] + c_11 * h11[j] for j in range(3))


def _variation(flint: Any, P: Any, M: Any, q: float, rho: float, which: str) -> tuple[Any, Any, Any]:
    """``(V_0, V_1, V_2)`` of ``G`` on ``[0, 1]`` for every ``(p, m)`` of the balls (step 1).

    For ``Re z >= 0``, integrating by parts once, ``|int_0^1 G e^{-z theta}| <= V_0 / |z|`` with
    ``V_0 = |G(0)| + |G(1)| + sup |G'|``, and twice, ``<= V_1 / |z| + V_2 / |z|^2`` with
    ``V_1 = |G(0)| + |G(1)|`` and ``V_2 = |G'(0)| + |G'(1)| + sup |G''|``; the values from
    :func:`_kernel_jet`, the sups over ``_PIECES`` balls covering ``[0, 1]``.
    """
    arb = flint.arb
    with precision(flint, PRECISION):
        g0, d0, _ = _kernel_jet(flint, P, M, q, rho, which, arb(0))
        g1, d1, _ = _kernel_jet(flint, P, M, q, rho, which, arb(1))
        sup1, sup2 = arb(0), arb(0)
        for i in range(_PIECES):
            _, first, second = _kernel_jet(flint, P, M, q, rho, which, arb((i + 0.5) / _PIECES, 0.5 / _PIECES))
            sup1, sup2 = arb.max(sup1, abs(first)), arb.max(sup2, abs(second))
        v1 = abs(g0) + abs(g1)
        out = (v1 + sup1, v1, abs(d0) + abs(d1) + sup2)
        if not all(v.is_finite() for v in out):
            raise CertificationError("the kernels' bounds on the square are not finite (couplings too strong)")
        return out


def _frequency_bound(v0: Any, v1: Any, v2: Any, gap: Any) -> float:
    """The smaller ``W`` of step 1: beyond it ``gap > V_0 / |z|``, or ``gap > V_1 / |z| + V_2 / |z|^2``
    (the positive root of ``gap W^2 - V_1 W - V_2``), in ball arithmetic (an upper bound)."""
    first = ball_upper(v0 / gap)
    second = ball_upper((v1 + (v1 * v1 + 4 * gap * v2).sqrt()) / (2 * gap))
    return min(first, second) * (1.0 + 1e-6)


def prove_coupled_square(
    system: Hyperbolic2x2,
    law: float | StateFeedback,
    eps: float,
    delays: tuple[float, float],
    corners: Sequence[tuple[QuasiPolynomial, QuasiPolynomial, DelayWindow]],
    *,
    max_boxes: int = MAX_COUPLED_BOXES,
    gain_error: float = 0.0,
) -> SquareProof:
    """Prove ``U = k u(t, 1)`` on ``system`` stable for every speed error of the square and delay of the window.

    Parameters
    ----------
    system : Hyperbolic2x2
        The nominal plant, with constant couplings and the closed form
        (:func:`~nrobust.hyperbolic.loops.exact_form.has_exact_form`).
    law : float or StateFeedback
        The law: its gain ``k`` on ``u(t, 1)`` (``U = k u(t, 1)``), or a ``StateFeedback(k, g_u, g_v)`` whose
        integral gains are numbers or callables evaluable in ball arithmetic
        (:func:`~nrobust.hyperbolic.loops.exact_gains.gain_failure` is None), fixed whatever the speeds
        (:mod:`~nrobust.hyperbolic.analyses.mismatch_gains`).
    eps : float
        The tolerance, ``0 < eps < 1``.
    delays : (float, float)
        The window ``[d_min, d_max]`` (``0 <= d_min <= d_max``, ``d_max > 0``).
    corners : sequence of (QuasiPolynomial, QuasiPolynomial, DelayWindow)
        The loops of the corners ``(e_lam, e_mu)`` = ``(-eps, -eps), (-eps, eps), (eps, -eps),
        (eps, eps)`` (:func:`~nrobust.hyperbolic.analyses.mismatch_loop`) and their verdicts; the
        first that is the exact loop of the law on its corner plant (compared with
        :func:`~nrobust.hyperbolic.loops.controllers.loop_factors`) and proven stable on a window
        meeting ``[d_min, d_max]`` is the point the argument starts from.
    max_boxes : int, optional
        Work bound: boxes of ``(w, e_lam, e_mu)`` examined.
    gain_error : float, default 0
        The law's true gains are within this distance of ``law.g_u``, ``law.g_v`` on ``[0, 1]`` (``U_BS2(K)``'s
        kernel traces: :func:`~nrobust.hyperbolic.analyses.mismatch_traces.reflection_traces`): the proof holds for
        every pair of gains that close (the family joins them, its corners' loops those of ``law``).

    Returns
    -------
    SquareProof
        As :func:`~nrobust.hyperbolic.analyses.mismatch_proof.prove_transport_square`; ``tau``
        encloses the round trips of the square, ``frequency_bound`` is ``W`` in the scaled frequency
        ``z = tau s`` (``|s| >= W / tau_min`` is free of zeros), and ``point`` is the mismatch of the
        box the subdivision stopped at.

    Raises
    ------
    ParameterError
        ``system`` without constant couplings or the closed form, ``eps`` outside ``(0, 1)``,
        ``delays`` not a window, or ``max_boxes`` not a positive integer.
    """
    max_boxes = positive_int("max_boxes", max_boxes)
    gain_error = nonnegative("gain_error", gain_error)
    if not isinstance(system, Hyperbolic2x2) or not has_exact_form(system):
        raise ParameterError("system", "a Hyperbolic2x2 with constant couplings (has_exact_form)", system)
    if not isinstance(law, StateFeedback):
        law = StateFeedback(finite_real("law", law))
    k = law.k
    eps = finite_real("eps", eps)
    if not 0.0 < eps < 1.0:
        raise ParameterError("eps", "in (0, 1) (the perturbed speeds stay positive)", eps)
    d_lo, d_hi = check_delays(delays)
    nan = math.nan
    edge = min(eps * (1.0 + _WIDEN) + _WIDEN, 0.5 * (1.0 + eps))
    square = (-edge, edge, -edge, edge)
    base = next(
        (
            n
            for n, ((A, B, window), corner) in enumerate(zip(corners, _corners(eps)))
            if window.stable
            and window.certified == "proven"
            and window.delays[0] <= d_hi
            and window.delays[1] >= d_lo
            and _exact_corner(system, law, corner, A, B)
        ),
        None,
    )
    with working_precision(53) as flint:
        arb = flint.arb
        _, P, M, T = _parameters(system, square)
        taus = (ball_lower(T), ball_upper(T))
        rq, kq, err_a, err_b = _point_coefficients(flint, system, k)
        c_d = abs(arb(rq)) + arb(err_a) + abs(arb(kq)) + arb(err_b)  # every c_A, c_B of the family
        if not c_d < 1:
            return SquareProof(
                False,
                f"the difference operator is not proven strongly stable (|rho q| + |k q| <= "
                f"{upper_bound_text(ball_upper(c_d))}, not < 1): the loop is not stable for every delay of a window "
                "(Hale's condition); a smaller gain |k| decides",
                taus,
                nan,
                nan,
                0,
                nan,
            )
        try:
            v_n = _variation(flint, P, M, system.q, system.rho, "N")
            v_u = _variation(flint, P, M, system.q, system.rho, "U")
        except CertificationError as exc:
            return SquareProof(False, str(exc), taus, nan, ball_upper(c_d), 0, nan)
        v0, v1, v2 = (a + abs(arb(k)) * b for a, b in zip(v_n, v_u))
        if _has_gains(law):  # the gains' term: |I_g| <= V_g / |z|, <= V_{g,1} / |z| + V_{g,2} / |z|^2 (mismatch_gains)
            failure = gain_failure(system, law.g_u, law.g_v)
            if failure is not None:
                return SquareProof(False, f"the law's gains have no exact loop: {failure}", taus, nan, nan, 0, nan)
            with precision(flint, PRECISION):
                v_g, v_g1, v_g2 = gain_variations(
                    flint, P, M, time_ratio(flint, system, square), system.q, _gain_bounds(system, law)
                )
            v0, v1, v2 = v0 + v_g, v1 + v_g1, v2 + v_g2
        # gains within gain_error: their part of I_g is at most its L^1 bound, whatever |z|
        off = error_radius(flint, P, M, system.q, gain_error) if gain_error else arb(0)
        if not c_d + off < 1:
            return SquareProof(
                False,
                f"the gains' error bound {gain_error:.3g} leaves no margin to the strong stability of the difference "
                "operator",
                taus,
                nan,
                ball_upper(c_d),
                0,
                nan,
            )
        W = _frequency_bound(v0, v1, v2, 1 - c_d - off)
        if base is None:
            return SquareProof(
                False,
                "no corner is proven stable on a window meeting the delays asked with its exact loop (rigorous=True "
                "on this window proves them; a corner plant beyond the closed form takes the kernel route, a model): "
                "the argument needs one point of the family",
                taus,
                W,
                ball_upper(c_d),
                0,
                nan,
            )
        boxes, stuck, pending = _clear(system, law, square, W, d_lo, d_hi, max_boxes, gain_error)
    if stuck is not None:
        (w0, w1, (a0, a1, b0, b1)), small = stuck
        # the speed boxes left undecided: the one stopped at, then the pending ones, smallest (deepest) first
        lowest: dict[tuple[float, float, float, float], float] = {}
        for lo, _, _, speeds in pending:
            lowest[speeds] = min(lo, lowest.get(speeds, math.inf))
        rest = sorted(lowest, key=lambda b: ((b[1] - b[0]) * (b[3] - b[2]), lowest[b]))
        undecided = tuple(dict.fromkeys([(a0, a1, b0, b1), *rest]))
        point = (0.5 * (a0 + a1), 0.5 * (b0 + b1))
        why = (
            f"a zero of F on the imaginary axis near tau w = {0.5 * (w0 + w1):.9g} at (e_lam, e_mu) = "
            f"({point[0]:.9g}, {point[1]:.9g}) for a delay of the window (or a crossing delay at an end of the "
            "window): not stable there, or not decided; a smaller tolerance or a window clear of the crossing "
            "delays decides"
            if small
            else f"the work bound max_boxes = {max_boxes} was reached (at tau w in [{w0:.6g}, {w1:.6g}], e_lam in "
            f"[{a0:.6g}, {a1:.6g}], e_mu in [{b0:.6g}, {b1:.6g}]); a larger max_boxes or a smaller tolerance decides"
        )
        return SquareProof(
            False,
            why,
            taus,
            W,
            ball_upper(c_d),
            boxes,
            system.tau / (1.0 + point[0]),
            point=point,
            undecided=undecided,
        )
    w_text, cd_text = upper_bound_text(W), upper_bound_text(ball_upper(c_d))
    return SquareProof(
        True,
        f"no zero on i [0, {w_text}] in the scaled frequency z = tau s for any (e_lam, e_mu) of the square and delay "
        f"of the window ({boxes} boxes of (tau w, e_lam, e_mu) in ball arithmetic, the kernels N~ and U~ in closed "
        f"form with the speeds as balls, centred at each box's middle), none with Re z >= 0 and |z| >= {w_text} "
        f"(c_D <= {cd_text} < 1), and the "
        f"loop of corners[{base}] proven stable on the window: the count in Re s > 0 is 0 on the whole connected set",
        taus,
        W,
        ball_upper(c_d),
        boxes,
        nan,
        base,
    )


def _corners(eps: float) -> list[tuple[float, float]]:
    """The corners of the square in the order of ``corners``."""
    return [(a, b) for a in (-eps, eps) for b in (-eps, eps)]


def _exact_corner(system: Hyperbolic2x2, law: StateFeedback, corner: tuple[float, float], A: Any, B: Any) -> bool:
    """True when ``(A, B)`` is the exact loop of the law on the plant at ``corner``: a point of the family."""
    plant = dataclasses.replace(system, lam=system.lam * (1.0 + corner[0]), mu=system.mu * (1.0 + corner[1]))
    if not has_exact_form(plant) or loop_route(plant, law) != "exact":
        return False
    return bool(loop_factors(plant, law) == (A, B))


@lru_cache(maxsize=4096)
def _box(system: Hyperbolic2x2, law: StateFeedback, box: tuple[float, float, float, float], error: float) -> _Box:
    return _Box(system, law, box, error)


def _clear(
    system: Hyperbolic2x2,
    law: StateFeedback,
    square: tuple[float, float, float, float],
    W: float,
    d_lo: float,
    d_hi: float,
    max_boxes: int,
    error: float,
) -> tuple[
    int,
    tuple[tuple[float, float, tuple[float, float, float, float]], bool] | None,
    list[tuple[float, int, float, tuple[float, float, float, float]]],
]:
    """Clear ``[0, W] x`` the square (step 2): the boxes examined, the box it stopped at (None: cleared) and the
    boxes ``(w0, age, w1, speeds)`` still pending then."""
    # lowest frequencies first: a crossing of the family lies there, the high ones only cost boxes
    pending: list[tuple[float, int, float, tuple[float, float, float, float]]] = [(0.0, 0, W, square)]
    order = itertools.count(1)  # ties in w broken by age
    boxes = 0
    span = square[1] - square[0]
    while pending:
        w0, _, w1, box = heapq.heappop(pending)
        boxes += 1
        part = _box(system, law, box, error)
        flint = part.flint
        arb = flint.arb
        t_lo, t_hi = part.tau
        # eta = delta / tau over the box: [d_lo / tau_max, d_hi / tau_min], rounded outwards
        eta = (ball_lower(arb(d_lo) / t_hi), ball_upper(arb(d_hi) / t_lo))
        w = arb(w0).union(arb(w1))
        A, B = part.factors(w0, w1)
        if crossing_free(flint, A, B, w, *eta):
            continue
        a0, a1, b0, b1 = box
        speed_small = max(a1 - a0, b1 - b0) <= _MIN_WIDTH * span
        w_small = (w1 - w0) <= _MIN_WIDTH * max(1.0, W)
        if (speed_small and w_small) or boxes >= max_boxes:
            return boxes, ((w0, w1, box), speed_small and w_small), pending
        split_speed = w_small
        if not split_speed and not speed_small:  # does the speed box alone keep the middle w undecided?
            wm = 0.5 * (w0 + w1)
            Am, Bm = part.factors(wm, wm)
            split_speed = not crossing_free(flint, Am, Bm, arb(wm), *eta)
        if split_speed:
            if a1 - a0 >= b1 - b0:
                am = 0.5 * (a0 + a1)
                children = [(w0, w1, (a0, am, b0, b1)), (w0, w1, (am, a1, b0, b1))]
            else:
                bm = 0.5 * (b0 + b1)
                children = [(w0, w1, (a0, a1, b0, bm)), (w0, w1, (a0, a1, bm, b1))]
        else:
            wm = 0.5 * (w0 + w1)
            children = [(w0, wm, box), (wm, w1, box)]
        for lo, hi, child in children:
            heapq.heappush(pending, (lo, next(order), hi, child))
    return boxes, None, []
