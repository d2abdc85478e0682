"""The integral term of a law with fixed gains on a coupled plant with mismatched speeds, in ball arithmetic.

A :class:`~nrobust.hyperbolic.loops.controllers.StateFeedback` ``U = k u(t, 1) + int_0^1 g_u u + g_v v dx``
keeps its gains ``g_u``, ``g_v`` whatever the speeds of the plant it acts on. On the plant (18)-(20) with
constant couplings its loop is ``B = -(k u_factor + I_g)``
(:mod:`~nrobust.hyperbolic.loops.exact_gains`), ``I_g = int_0^tau K(theta) e^{-theta s} dtheta``. In the scaled
frequency ``z = tau s`` of :mod:`~nrobust.hyperbolic.analyses.mismatch_coupled`,
``I_g = int_0^1 k(t) e^{-z t} dt`` with ``k(t) = tau K(tau t)``, and by the formula of ``K``
(``t_v = r tau``, ``t_u = (1 - r) tau``)::

    k(t) = G_v(1 - t/r) / r              (t < r)
         + q G_u((t - r)/(1 - r)) / (1 - r)   (t > r)
         + int_{xi_0(t)}^1 H(xi, t - r (1 - xi)) dxi,      xi_0 = max(1 - t/r, (t - r)/(1 - r)),
    H(xi, n) = G_u(xi) U(xi, n) + G_v(xi) V(xi, n),   x = kappa n (xi - n),
    U = q kappa n 0F1(; 2; x) + p 0F1(; 1; x),   V = kappa (xi - n) 0F1(; 2; x) + m q 0F1(; 1; x),

a function of ``p = sigma_pm / lam'``, ``m = -sigma_mp / mu'`` (``kappa = p m``) and
``r = t_v / tau = lam' / (lam' + mu')`` alone (``U``, ``V`` are the section's ``U~``, ``V~`` scaled by ``tau``).

:func:`gain_term` encloses ``k`` for every speed of a box: the kernel of a point ``(p_0, m_0, r_0)`` of the
box (:func:`~nrobust.hyperbolic.loops.exact_gains.gain_kernel` on that plant, rescaled to ``[0, 1]``) within
an ``L^1`` radius ``L_p |p - p_0| + L_m |m - m_0| + L_r |r - r_0|``: the ``L^1`` norms of the parameter
derivatives, bounded on the box (:func:`_lipschitz`), independent of the frequency. On ``Re z = 0`` an
``L^1`` bound of a kernel on ``[0, 1]`` bounds its integral against ``e^{-z t}``, so the radius of the stored
kernel widens the enclosures of ``B`` by that much. Derivatives:

- in ``r``, at ``t`` on the same side of ``r`` and ``r_0``: ``d/dr`` of the first term has ``L^1`` norm at
  most ``(sup |G_v'| / 2 + sup |G_v|) / r`` (``int_0^r |G_v'(1 - t/r)| t / r^3 dt <= sup |G_v'| / (2 r)``),
  the second ``|q| (sup |G_u'| / 2 + sup |G_u|) / (1 - r)``; ``d/dr`` of the third is
  ``-int (1 - xi) dH/dn dxi - H(xi_0, n_0) dxi_0/dr``, of ``L^1`` norm at most ``sup |H_n| / 6 + sup |H|``
  (``int_0^1 int_{xi_0}^1 (1 - xi) dxi dt = 1/6``, ``int |dxi_0/dr| dt = 1/2`` on each side);
- between ``r_0`` and ``r`` (a length ``|r - r_0|``) the two kernels differ by at most
  ``|G_v(0) / r - q G_u(0) / r_0'| + |r - r_0| (sup |G_v'| / r^2 + |q| sup |G_u'| / (1 - r)^2 + sup |H|
  max(1/r, 1/(1 - r)) + sup |H_n|)`` (``r_0' = 1 - r_0``; the jump of ``k`` at ``r``, which moves, is small when
  ``q G_u(0) / (1 - r)`` and ``G_v(0) / r`` nearly cancel, as for the traces of ``U_BS2(K)``); ``L_r`` adds it;
- ``d/dp``, ``d/dm`` act on ``U``, ``V`` only, in the third term, whose domain ``xi_0(t) <= xi <= 1`` has area
  ``1/2``: ``L_p = (sup |G_u| sup |U_p| + sup |G_v| sup |V_p|) / 2``, ``L_m`` alike.

Each sup over ``xi, n`` uses ``|0F1(; b; x)| <= 0F1(; b; |kappa| / 4)`` (``|x| <= |kappa| / 4``) and
``d/dx 0F1(; b; x) = 0F1(; b + 1; x) / b`` (:func:`section_bounds`); the gains' sups come from their Taylor
models (:func:`gain_bounds`). For the frequency bound, integrating by parts on ``[0, r]`` and ``[r, 1]``
(``k`` is smooth on each, with a jump and a kink at ``r``), once: ``|I_g| <= V_g / |z|`` on ``Re z >= 0``
with ``V_g`` the four end values plus ``int |k'|``; twice: ``|I_g| <= V_{g,1} / |z| + V_{g,2} / |z|^2`` with

    ``V_{g,1} = |k(0)| + |k(r+) - k(r-)| + |k(1)|``,
    ``k(0) = G_v(1) / r``, ``k(1) = q G_u(1) / (1 - r)``, ``k(r+) - k(r-) = q G_u(0) / (1 - r) - G_v(0) / r``,

(the third term of ``k`` is continuous and vanishes at ``t = 0`` and ``t = 1``) and
``V_{g,2} = |k'(0)| + |k'(r+) - k'(r-)| + |k'(1)| + int |k''|`` (:func:`gain_variations`). With
``H = G_u U + G_v V`` and ``n_0 = t - r (1 - xi_0)`` (``0`` below ``r``, ``xi_0`` above),

    ``k'  = -G_v' / r^2 + H(xi_0, 0) / r + int H_n``                         (t < r),
    ``k'  = q G_u' / (1 - r)^2 - H(xi_0, xi_0) / (1 - r) + int H_n``           (t > r),
    ``k'' = G_v'' / r^3 - H_xi(xi_0, 0) / r^2 + H_n(xi_0, 0) / r + int H_nn``  (t < r),
    ``k'' = q G_u'' / (1 - r)^3 - (H_xi + H_n)(xi_0, xi_0) / (1 - r)^2 - H_n(xi_0, xi_0) / (1 - r) + int H_nn``,

the integrals over ``[xi_0, 1]`` at ``n = t - r (1 - xi)``; each term bounded by the sups of
:func:`section_bounds` (``U``, ``V`` and their first and second derivatives) and of the gains.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ..._flint import ball_upper, precision
from ...errors import CertificationError
from ...quasipoly import DistributedDelay
from ..loops.exact_form import DEGREE, PRECISION
from ..loops.exact_gains import ORDER, gain_kernel, gain_models, gain_plant
from ..plants.hyperbolic2x2 import Hyperbolic2x2

__all__ = [
    "GainBounds",
    "GainTerm",
    "gain_bounds",
    "gain_term",
    "error_radius",
    "gain_variation",
    "gain_variations",
    "section_bounds",
    "time_ratio",
]

#: Balls per Taylor-model piece on which the gains' sups are taken.
_SUBBALLS = 8


class GainTerm(NamedTuple):
    """The gains' term of :func:`gain_term` over a box of speeds.

    Attributes
    ----------
    kernel : DistributedDelay
        ``k`` of the point ``(p_0, m_0, r_0)`` (the box's middle plant) on ``[0, 1]``, its radius an ``L^1`` bound
        (its error and the gains' ``error``).
    variation : float
        ``V_g`` of the box.
    spread : float
        An ``L^1`` bound of ``k(p, m, r) - k(p_0, m_0, r_0)`` over the box (:func:`_lipschitz`).
    balls : (arb, arb, arb)
        The balls ``P``, ``M``, ``R`` of the box, holding ``(p_0, m_0, r_0)``.
    offsets : (float, float, float)
        Upper bounds of ``|p - p_0|``, ``|m - m_0|``, ``|r - r_0|`` over the box.
    """

    kernel: DistributedDelay
    variation: float
    spread: float
    balls: tuple[Any, Any, Any]
    offsets: tuple[float, float, float]


@dataclasses.dataclass(frozen=True)
class GainBounds:
    """Sups of the effective gains on ``[0, 1]`` (balls' upper bounds, as python-flint ``arb``).

    ``u0 = sup |G_u|``, ``u1 = sup |G_u'|``, ``u_ends = (|G_u(0)|, |G_u(1)|)``, ``u2 = sup |G_u''|`` and
    ``u_at = (G_u(0), G_u(1))`` (signed balls), and the same for ``G_v``.
    """

    u0: Any
    u1: Any
    u_ends: tuple[Any, Any]
    v0: Any
    v1: Any
    v_ends: tuple[Any, Any]
    u2: Any
    v2: Any
    u_at: tuple[Any, Any]
    v_at: tuple[Any, Any]


def gain_bounds(flint: Any, system: Hyperbolic2x2, g_u: Any, g_v: Any) -> GainBounds:
    """The sups of the gains and of their derivatives, from their Taylor models
    (:mod:`~nrobust.hyperbolic.loops.exact_gains`: a polynomial on each piece within a proven remainder,
    and the remainder of its derivative), at the precision of ``exact_gains`` (the models' global
    coefficients cancel); each model is taken back to its local variable ``t`` (``xi = c + r t``,
    ``|t| <= 1``) before it is evaluated on balls (no cancellation there).

    A model's remainder is ``R(t) = G(c + r t) - P(t)`` with ``|R| <= rem``, the enclosure of the Taylor
    coefficient of order ``ORDER`` over the piece; by Taylor's theorem for ``R'`` and ``R''`` (the
    remainders of the expansions of ``d/dt`` and ``d^2/dt^2``), ``|R'| <= ORDER rem`` (the models'
    ``derivative``) and ``|R''| <= ORDER (ORDER - 1) rem``."""
    arb, arb_poly = flint.arb, flint.arb_poly
    plant = gain_plant(system)
    bits = PRECISION + math.ceil(12.0 * math.sqrt(abs(float(plant.p * plant.m)))) + ORDER * 7 + 64
    with precision(flint, bits):
        n, mod_u, mod_v = gain_models(flint, plant, g_u, g_v)
        out = []
        for mod in (mod_u, mod_v):
            sup0, sup1, sup2 = arb(0), arb(0), arb(0)
            for j in range(n):
                c, r = arb(2 * j + 1) / (2 * n), 1 / arb(2 * n)  # the piece [j/n, (j+1)/n]: t in [-1, 1]
                local = mod.polys[j](arb_poly([c, r]))
                slope = local.derivative()
                curve = slope.derivative()
                for i in range(_SUBBALLS):
                    t = arb(-1 + (2 * i + 1) / _SUBBALLS, 1 / _SUBBALLS)
                    sup0 = arb.max(sup0, abs(local(t)) + mod.remainder[j])
                    # d/dxi = (1/r) d/dt; the remainder's derivatives are bounded in the model's own t (a radius
                    # above 1/(2n)): at most 2 n (4 n^2) times them in xi
                    sup1 = arb.max(sup1, (abs(slope(t)) + mod.derivative[j]) * (2 * n))
                    sup2 = arb.max(sup2, (abs(curve(t)) + (ORDER - 1) * mod.derivative[j]) * (4 * n * n))
            at = (
                mod.polys[0](arb(0)) + arb(0, ball_upper(mod.remainder[0])),
                mod.polys[-1](arb(1)) + arb(0, ball_upper(mod.remainder[-1])),
            )
            out.append((sup0, sup1, (abs(at[0]), abs(at[1])), sup2, at))
    (u0, u1, ue, u2, ua), (v0, v1, ve, v2, va) = out
    if not all(x.is_finite() for x in (u0, u1, u2, v0, v1, v2, *ue, *ve)):
        raise CertificationError("the gains' Taylor models give no finite bound on [0, 1]")
    return GainBounds(u0, u1, ue, v0, v1, ve, u2, v2, ua, va)


def section_bounds(flint: Any, P: Any, M: Any, q: float) -> dict[str, tuple[Any, Any, Any, Any]]:
    """For ``U`` and ``V`` (module notes): sups of ``|.|``, ``|d/dn|``, ``|d/dp|``, ``|d/dm|`` over
    ``0 <= n <= xi <= 1`` and every ``(p, m)`` of the balls."""
    arb = flint.arb
    p, m = abs(P).upper(), abs(M).upper()
    p, m = arb(p), arb(m)
    Q = abs(arb(q))
    kap = p * m
    f1, f2, f3 = (arb(kap / 4).hypgeom_0f1(b) for b in (1, 2, 3))  # 0F1(; b; |kappa|/4) >= |0F1(; b; x)|
    # x = kappa n (xi - n): |x| <= kappa/4, |dx/dn| <= kappa, |dx/dp| <= m/4, |dx/dm| <= p/4
    u = (
        Q * kap * f2 + p * f1,
        Q * kap * (f2 + kap * f3 / 2) + p * kap * f2,
        Q * m * (f2 + kap * f3 / 8) + f1 + kap * f2 / 4,
        Q * p * (f2 + kap * f3 / 8) + p * p * f2 / 4,
    )
    v = (
        kap * f2 + m * Q * f1,
        kap * (f2 + kap * f3 / 2) + m * Q * kap * f2,
        m * (f2 + kap * f3 / 8) + m * m * Q * f2 / 4,
        p * (f2 + kap * f3 / 8) + Q * f1 + kap * Q * f2 / 4,
    )
    return {"U": u, "V": v}


def _section_curvatures(flint: Any, P: Any, M: Any, q: float) -> dict[str, tuple[Any, Any]]:
    """For ``U`` and ``V`` (module notes): sups of ``|d/dxi|`` and ``|d^2/dn^2|`` over ``0 <= n <= xi <= 1`` and
    every ``(p, m)`` of the balls.

    With ``F_b = 0F1(; b; x)``, ``|F_b| <= f_b = 0F1(; b; |kappa| / 4)``, ``F_b' = F_{b + 1} / b`` and
    ``x = kappa n (xi - n)``: ``|x_xi| = |kappa| n <= |kappa|``, ``|x_n| = |kappa (xi - 2 n)| <= |kappa|``,
    ``x_nn = -2 kappa``, ``n (xi - n) <= 1/4``.
    """
    arb = flint.arb
    p, m = arb(abs(P).upper()), arb(abs(M).upper())
    Q = abs(arb(q))
    kap = p * m
    f2, f3, f4 = (arb(kap / 4).hypgeom_0f1(b) for b in (2, 3, 4))
    # U = q kappa n F2 + p F1: U_xi = q kappa^2 n^2 F3 / 2 + p kappa n F2,
    # U_nn = 2 q kappa F2' x_n + q kappa n (F2'' x_n^2 + F2' x_nn) + p (F1'' x_n^2 + F1' x_nn)
    u = (
        Q * kap * kap * f3 / 2 + p * kap * f2,
        Q * kap * kap * f3 + Q * kap * (kap * kap * f4 / 6 + kap * f3) + p * (kap * kap * f3 / 2 + 2 * kap * f2),
    )
    # V = kappa (xi - n) F2 + m q F1: V_xi = kappa F2 + kappa^2 (xi - n) n F3 / 2 + m q kappa n F2,
    # V_nn = -2 kappa F2' x_n + kappa (xi - n) (F2'' x_n^2 + F2' x_nn) + m q (F1'' x_n^2 + F1' x_nn)
    v = (
        kap * f2 + kap * kap * f3 / 8 + m * Q * kap * f2,
        kap * kap * f3 + kap * (kap * kap * f4 / 6 + kap * f3) + m * Q * (kap * kap * f3 / 2 + 2 * kap * f2),
    )
    return {"U": u, "V": v}


def error_radius(flint: Any, P: Any, M: Any, q: float, error: float) -> Any:
    """The ``L^1`` norm of ``k`` for gains ``e_u``, ``e_v`` with ``|e_u|, |e_v| <= error``, on the balls:
    ``error (1 + |q| + sup |U| + sup |V|)`` (the first two terms of ``k`` are ``e`` moved and scaled, of ``L^1``
    norm ``int |e_v|`` and ``|q| int |e_u|``; the third is at most ``error (sup |U| + sup |V|)`` on a set of
    ``(t, xi)`` of measure at most 1)."""
    arb = flint.arb
    if error == 0.0:
        return arb(0)
    sec = section_bounds(flint, P, M, q)
    return arb(error) * (1 + abs(arb(q)) + sec["U"][0] + sec["V"][0])


def time_ratio(flint: Any, system: Hyperbolic2x2, box: tuple[float, float, float, float]) -> Any:
    """The ball of ``r = lam' / (lam' + mu')`` over a box of relative speed errors (increasing in
    ``lam'``, decreasing in ``mu'``: its ends at the box's corners)."""
    arb = flint.arb
    a0, a1, b0, b1 = box
    lo = arb(system.lam) * (1 + arb(a0)) / (arb(system.lam) * (1 + arb(a0)) + arb(system.mu) * (1 + arb(b1)))
    hi = arb(system.lam) * (1 + arb(a1)) / (arb(system.lam) * (1 + arb(a1)) + arb(system.mu) * (1 + arb(b0)))
    return lo.union(hi)


def _lipschitz(flint: Any, P: Any, M: Any, R: Any, q: float, g: GainBounds) -> tuple[Any, Any, Any]:
    """``(L_p, L_m, L_r)``: ``L_p |p - p_0| + L_m |m - m_0| + L_r |r - r_0|`` bounds the ``L^1`` distance of the
    kernels of two points of the balls (the notes; ``L_r`` holds the moving jump at ``r`` for any two ``r`` of
    ``R``: its term second order in ``|r - r_0|`` is bounded with the width of ``R``)."""
    arb = flint.arb
    sec = section_bounds(flint, P, M, q)
    (us, un, up, um), (vs, vn, vp, vm) = sec["U"], sec["V"]
    h, h_n = g.u0 * us + g.v0 * vs, g.u0 * un + g.v0 * vn
    lp, lm = (g.u0 * up + g.v0 * vp) / 2, (g.u0 * um + g.v0 * vm) / 2  # over an area 1/2 of (t, xi)
    r_lo, r_hi = arb(R.lower()), 1 - arb(R.upper())  # r >= r_lo, 1 - r >= r_hi
    if not (r_lo > 0 and r_hi > 0):
        raise CertificationError("the ratio of the times of flight leaves (0, 1) on the box")
    Q = abs(arb(q))
    inside = (g.v1 / 2 + g.v0) / r_lo + Q * (g.u1 / 2 + g.u0) / r_hi + h_n / 6 + h
    jump = abs(g.v_at[0] / R - arb(q) * g.u_at[0] / (1 - R))  # each R a point of the ball on its own
    width = arb(R.upper()) - arb(R.lower())
    near = g.v1 / r_lo**2 + Q * g.u1 / r_hi**2 + h * arb.max(1 / r_lo, 1 / r_hi) + h_n
    return lp, lm, inside + jump + width * near


def gain_variation(flint: Any, P: Any, M: Any, R: Any, q: float, g: GainBounds) -> Any:
    """``V_g``: ``|int_0^1 k(t) e^{-z t} dt| <= V_g / |z|`` on ``Re z >= 0`` for every ``(p, m, r)`` of the balls
    (integration by parts on ``[0, r]`` and ``[r, 1]``: the module notes)."""
    arb = flint.arb
    sec = section_bounds(flint, P, M, q)
    (us, un, _, _), (vs, vn, _, _) = sec["U"], sec["V"]
    h, h_n = g.u0 * us + g.v0 * vs, g.u0 * un + g.v0 * vn
    r_lo, r_hi = arb(R.lower()), 1 - arb(R.upper())
    if not (r_lo > 0 and r_hi > 0):
        raise CertificationError("the ratio of the times of flight leaves (0, 1) on the square")
    Q = abs(arb(q))
    ends = (g.v_ends[1] + g.v_ends[0]) / r_lo + Q * (g.u_ends[0] + g.u_ends[1]) / r_hi + 2 * h
    slopes = g.v1 / r_lo + Q * g.u1 / r_hi + h_n + h * arb.max(1 / r_lo, 1 / r_hi)
    return ends + slopes


def gain_variations(flint: Any, P: Any, M: Any, R: Any, q: float, g: GainBounds) -> tuple[Any, Any, Any]:
    """``(V_g, V_{g,1}, V_{g,2})``: ``|int_0^1 k(t) e^{-z t} dt|`` is at most ``V_g / |z|`` and at most
    ``V_{g,1} / |z| + V_{g,2} / |z|^2`` on ``Re z >= 0`` for every ``(p, m, r)`` of the balls (integration by
    parts once and twice on ``[0, r]`` and ``[r, 1]``: the module notes)."""
    arb = flint.arb
    first = gain_variation(flint, P, M, R, q, g)
    sec, curv = section_bounds(flint, P, M, q), _section_curvatures(flint, P, M, q)
    (us, un, _, _), (vs, vn, _, _) = sec["U"], sec["V"]
    (ux, unn), (vx, vnn) = curv["U"], curv["V"]
    h, h_n = g.u0 * us + g.v0 * vs, g.u0 * un + g.v0 * vn
    h_xi = g.u1 * us + g.u0 * ux + g.v1 * vs + g.v0 * vx
    h_nn = g.u0 * unn + g.v0 * vnn
    Q = arb(q)
    rest = 1 - R  # 1 - r as a ball (R stays in (0, 1): gain_variation checked it)
    values = abs(g.v_at[1] / R) + abs(Q * g.u_at[0] / rest - g.v_at[0] / R) + abs(Q * g.u_at[1] / rest)
    r_lo, s_lo = arb(R.lower()), arb(rest.lower())  # r >= r_lo, 1 - r >= s_lo
    r_hi, s_hi = arb(R.upper()), arb(rest.upper())
    Qa = abs(Q)
    ends = (
        g.v1 / r_lo**2
        + h / r_lo  # |k'(0)|
        + Qa * g.u1 / s_lo**2
        + h / s_lo  # |k'(1)|
        + Qa * g.u1 / s_lo**2
        + g.v1 / r_lo**2
        + h * (1 / r_lo + 1 / s_lo)  # |k'(r+) - k'(r-)|
    )
    below = g.v2 / r_lo**2 + h_xi / r_lo + h_n + r_hi * h_nn  # int_0^r |k''| <= r sup |k''|
    above = Qa * g.u2 / s_lo**2 + (h_xi + h_n) / s_lo + h_n + s_hi * h_nn
    return first, values, ends + below + above


def gain_term(
    flint: Any,
    system: Hyperbolic2x2,
    g_u: Any,
    g_v: Any,
    box: tuple[float, float, float, float],
    P: Any,
    M: Any,
    bounds: GainBounds,
    error: float = 0.0,
) -> GainTerm | None:
    """``k`` (module notes) for every speed error of ``box``: the kernel of the box's middle plant ``(p_0, m_0,
    r_0)`` on ``[0, 1]``, the ``L^1`` distance to it of every kernel of the box, and ``V_g`` of the box.

    Returns None when both gains are zero. The kernel's radius and ``spread`` are ``L^1`` bounds: valid for the
    integral against ``e^{-z t}`` on ``Re z = 0`` only (where :mod:`~nrobust.hyperbolic.analyses.mismatch_coupled`
    evaluates). With ``error > 0`` the radius holds the kernels of every pair of gains within ``error`` of
    ``g_u``, ``g_v`` (:func:`error_radius`) at the middle plant, ``spread`` the other speeds' for the gains
    ``g_u``, ``g_v``.
    """
    arb = flint.arb
    a0, a1, b0, b1 = box
    middle = dataclasses.replace(
        system, lam=system.lam * (1.0 + 0.5 * (a0 + a1)), mu=system.mu * (1.0 + 0.5 * (b0 + b1))
    )
    kernel = gain_kernel(middle, g_u, g_v)
    if kernel is None:
        return None
    tau = middle.tau
    # the point of the kernel: p_0, m_0 exact quotients, r_0 = t_v / tau with t_v on the grid of ulp(tau)
    ulp = math.ulp(tau)
    p0 = arb(float(system.sigma_pm)) / arb(middle.lam)  # type: ignore[arg-type]
    m0 = -arb(float(system.sigma_mp)) / arb(middle.mu)  # type: ignore[arg-type]
    r0 = arb(round((1.0 / middle.mu) / ulp) * ulp) / arb(tau)
    R = time_ratio(flint, system, box)
    P, M, R = P.union(p0), M.union(m0), R.union(r0)
    lp, lm, lr = _lipschitz(flint, P, M, R, system.q, bounds)
    spread = lp * abs(P - p0).upper() + lm * abs(M - m0).upper() + lr * abs(R - r0).upper()
    nodes = np.asarray(kernel.nodes, dtype=float)
    coefs: NDArray[np.float64] = np.asarray(kernel.pieces[2], dtype=float) * tau
    scaled = nodes / tau
    scaled[-1] = 1.0  # tau / tau
    # the rounded nodes move each point of a piece by at most delta (an affine map of its ends): an L^1 change
    # of at most delta sup |k'| h <= delta DEGREE sum_l |P_il| inside the piece and 2 delta sup |k| at its
    # ends; the product by tau rounds each coefficient
    delta = 2.0**-52
    sizes = float(np.abs(coefs).sum())
    slack = 4.0 * (DEGREE + 2) * delta * sizes + 4.0 * float(np.finfo(float).eps) * sizes
    radius = ball_upper(arb(kernel.radius) * arb(tau) + error_radius(flint, P, M, system.q, error)) + slack
    variation = gain_variation(flint, P, M, R, system.q, bounds)
    return GainTerm(
        DistributedDelay(scaled, None, interpolation="polynomial", coefficients=coefs, radius=radius),
        ball_upper(variation),
        ball_upper(spread),
        (P, M, R),
        (ball_upper(abs(P - p0)), ball_upper(abs(M - m0)), ball_upper(abs(R - r0))),
    )
