"""The gains' term of the square's proof in the centred form in the speeds: :class:`GainSlopes`.

In the notation of :mod:`~nrobust.hyperbolic.analyses.mismatch_gains`, ``I_g(z) = int_0^1 k(t; p, m, r) e^{-z t} dt``
with ``k = G_v(1 - t/r) / r + T(t)`` below ``r`` and ``q G_u(xi_0) / (1 - r) + T(t)`` above,
``T(t) = int_{xi_0}^1 H(xi, n) dxi``, ``n = t - r (1 - xi)``, ``H = G_u U + G_v V``, ``xi_0 = 1 - t/r`` below ``r``
and ``(t - r)/(1 - r)`` above. ``I_g`` is ``C^1`` in ``(p, m, r)`` (the jump of ``k`` at ``t = r`` moves with ``r``:
Leibniz's rule), so for ``(p, m, r)`` and ``(p_0, m_0, r_0)`` in a box ``P x M x R`` the mean-value theorem
(in its integral form, for a complex function) gives::

    I_g(z; p, m, r) - I_g(z; p_0, m_0, r_0) in D_p(z) [p - p_0] + D_m(z) [m - m_0] + D_r(z) [r - r_0],

``D_x(z)`` an enclosure of ``dI_g/dx`` over the box:

    ``dI_g/dp = int_0^1 k_p e^{-z t} dt``, ``k_p = int_{xi_0}^1 H_p dxi`` (``m`` alike),
    ``dI_g/dr = J e^{-z r} + int_0^1 k_r e^{-z t} dt``, ``J = k(r-) - k(r+) = G_v(0) / r - q G_u(0) / (1 - r)``
    (``T`` is continuous at ``r``),
    ``k_r = G_v'(xi_0) t / r^3 - G_v(xi_0) / r^2 - H(xi_0, 0) t / r^2 - int_{xi_0}^1 (1 - xi) H_n dxi``  (t < r),
    ``k_r = q G_u'(xi_0) (t - 1) / (1 - r)^3 + q G_u(xi_0) / (1 - r)^2 - H(xi_0, xi_0) (t - 1) / (1 - r)^2
    - int_{xi_0}^1 (1 - xi) H_n dxi``  (t > r; ``dxi_0/dr`` is ``t / r^2`` below, ``(t - 1) / (1 - r)^2`` above).

With ``F_b = 0F1(; b; x)``, ``x = kappa n (xi - n)``, ``kappa = p m``, ``F_1' = F_2``, ``F_2' = F_3 / 2`` and
``U = q kappa n F_2 + p F_1``, ``V = kappa (xi - n) F_2 + m q F_1``::

    U_n = q kappa F_2 + (q kappa n F_3 / 2 + p F_2) x_n,        x_n = kappa (xi - 2 n),
    U_p = q m n F_2 + F_1 + (q kappa n F_3 / 2 + p F_2) x_p,    x_p = m n (xi - n),
    U_m = q p n F_2 + (q kappa n F_3 / 2 + p F_2) x_m,          x_m = p n (xi - n),
    V_n = -kappa F_2 + (kappa (xi - n) F_3 / 2 + m q F_2) x_n,
    V_p = m (xi - n) F_2 + (kappa (xi - n) F_3 / 2 + m q F_2) x_p,
    V_m = p (xi - n) F_2 + q F_1 + (kappa (xi - n) F_3 / 2 + m q F_2) x_m.

Each ``k_x`` is enclosed on :data:`T_CELLS` cells of ``t`` for every ``(p, m, r)`` of the box, its inner integral
over :data:`XI_CELLS` cells of ``xi`` (a cell above ``xi_0`` weighs its width, the one holding ``xi_0`` a width in
``[0, h_xi]``); a cell of ``t`` meeting ``R`` takes the hull of both sides' formulas, every argument of the gains
clipped to ``[0, 1]`` (where the true ones lie). The gains are their Taylor models
(:func:`~nrobust.hyperbolic.loops.exact_gains.gain_models`, each piece in its local variable, as
:func:`~nrobust.hyperbolic.analyses.mismatch_gains.gain_bounds` takes them). On ``z = i w`` a cell's ball
``c_i +- r_i`` gives ``c_i int_{C_i} e^{-i w t} dt +- r_i h`` (closed form), so ``|D_x|`` keeps the oscillation
of ``e^{-z t}`` and the signs of ``k_x``.
"""

from __future__ import annotations

import math
from typing import Any

from ..._flint import ball_lower, ball_upper, precision
from ...errors import CertificationError
from ..loops.exact_form import PRECISION
from ..loops.exact_gains import ORDER, gain_models, gain_plant
from ..plants.hyperbolic2x2 import Hyperbolic2x2

__all__ = ["GainPieces", "GainSlopes", "T_CELLS", "XI_CELLS", "cell_integrals", "gain_pieces"]

#: Cells of ``t`` on which the slopes ``k_p``, ``k_m``, ``k_r`` are enclosed.
T_CELLS = 32
#: Cells of ``xi`` of the inner integrals.
XI_CELLS = 16


class GainPieces:
    """The effective gains ``G_u``, ``G_v`` on ``[0, 1]`` as Taylor models in their pieces' local variables.

    ``value(g, X)`` and ``slope(g, X)`` (``g`` 0 for ``G_u``, 1 for ``G_v``) enclose ``G`` and ``G'`` on the ball
    ``X`` clipped to ``[0, 1]``: the union over the pieces it meets of the local polynomial at the local ball,
    within the model's remainder (of ``G - P``: ``rem``; of its derivative: ``2 n`` times the models' bound in
    the local variable, as in :func:`~nrobust.hyperbolic.analyses.mismatch_gains.gain_bounds`).
    """

    def __init__(self, flint: Any, n: int, models: tuple[Any, Any]) -> None:
        arb, arb_poly = flint.arb, flint.arb_poly
        self.flint, self.n = flint, n
        self.local: list[list[tuple[Any, Any, Any, Any]]] = []
        for mod in models:
            pieces = []
            for j in range(n):
                local = mod.polys[j](arb_poly([arb(2 * j + 1) / (2 * n), 1 / arb(2 * n)]))
                rem = arb(0, ball_upper(mod.remainder[j]))
                slope_rem = arb(0, ball_upper(mod.derivative[j] * (2 * n)))
                pieces.append((local, local.derivative() * (2 * n), rem, slope_rem))
            self.local.append(pieces)

    def _at(self, g: int, X: Any, which: int) -> Any:
        arb = self.flint.arb
        lo, hi = max(ball_lower(X), 0.0), min(ball_upper(X), 1.0)
        if lo > hi:  # no true argument in the ball: any point of [0, 1] is as good
            lo = hi = min(max(float(X.mid()), 0.0), 1.0)
        n = self.n
        out = None
        for j in range(max(0, min(n - 1, math.floor(lo * n))), min(n - 1, math.floor(hi * n)) + 1):
            a, b = max(lo, j / n), min(hi, (j + 1) / n)
            t = (arb(a) * (2 * n) - (2 * j + 1)).union(arb(b) * (2 * n) - (2 * j + 1))
            local, slope, rem, slope_rem = self.local[g][j]
            v = local(t) + rem if which == 0 else slope(t) + slope_rem
            out = v if out is None else out.union(v)
        return out

    def value(self, g: int, X: Any) -> Any:
        """``G(X)`` (``g`` 0: ``G_u``, 1: ``G_v``)."""
        return self._at(g, X, 0)

    def slope(self, g: int, X: Any) -> Any:
        """``G'(X)``."""
        return self._at(g, X, 1)


def gain_pieces(flint: Any, system: Hyperbolic2x2, g_u: Any, g_v: Any) -> GainPieces:
    """The Taylor models of the gains of ``system`` (:func:`~nrobust.hyperbolic.loops.exact_gains.gain_models`),
    at the precision :func:`~nrobust.hyperbolic.analyses.mismatch_gains.gain_bounds` takes them."""
    plant = gain_plant(system)
    bits = PRECISION + math.ceil(12.0 * math.sqrt(abs(float(plant.p * plant.m)))) + ORDER * 7 + 64
    with precision(flint, bits):
        n, mod_u, mod_v = gain_models(flint, plant, g_u, g_v)
        return GainPieces(flint, n, (mod_u, mod_v))


def cell_integrals(flint: Any, w: Any, cells: int) -> list[Any]:
    """``int_{C_i} e^{-i w t} dt = h e^{-i w t_i} sinc(w h / 2)`` on the cells ``C_i`` of ``[0, 1]``
    (``h = 1 / cells``, ``t_i = (i + 1/2) h``) for every ``w`` of the ball ``w``, each turn from its own exponential
    (powers of ``e^{-i w h}`` would wrap: a product of complex balls widens by up to ``sqrt(2)``)."""
    arb, acb = flint.arb, flint.acb
    h = arb(1) / cells
    width = h * (w * h / 2).sinc()
    return [acb(0, -(w * (h * (i + 0.5)))).exp() * width for i in range(cells)]


class GainSlopes:
    """``D_p``, ``D_m``, ``D_r`` (module notes) over the box ``P x M x R`` for the gains ``gains``.

    Parameters
    ----------
    flint : module
        python-flint.
    gains : GainPieces
        The effective gains.
    q : float
        The distal reflection.
    P, M, R : arb
        The balls of ``p``, ``m`` and ``r`` (holding the point ``(p_0, m_0, r_0)``).
    offsets : (float, float, float)
        Upper bounds of ``|p - p_0|``, ``|m - m_0|``, ``|r - r_0|`` over the box.
    """

    def __init__(self, flint: Any, gains: GainPieces, q: float, P: Any, M: Any, R: Any, offsets: Any) -> None:
        arb = flint.arb
        self.flint, self.R, self.offsets = flint, R, offsets
        Q = arb(q)
        kap = P * M
        r_lo, r_hi = ball_lower(R), ball_upper(R)
        if not (0.0 < r_lo and r_hi < 1.0):
            raise CertificationError("the ratio of the times of flight leaves (0, 1) on the box")
        self.jump = gains.value(1, arb(0)) / R - Q * gains.value(0, arb(0)) / (1 - R)
        h_xi = 1.0 / XI_CELLS
        xis = [arb((j + 0.5) * h_xi, 0.5 * h_xi) for j in range(XI_CELLS)]
        g_xi = [(gains.value(0, X), gains.value(1, X)) for X in xis]
        self.mids: tuple[list[Any], list[Any], list[Any]] = ([], [], [])
        rest = [arb(0), arb(0), arb(0)]

        def sections(xi: Any, n: Any) -> tuple[Any, ...]:
            """``(U, V, U_n, V_n, U_p, V_p, U_m, V_m)`` at the balls ``xi``, ``n``."""
            d = xi - n
            x = kap * n * d
            f1, f2, f3 = (x.hypgeom_0f1(b) for b in (1, 2, 3))
            x_n, x_p, x_m = kap * (xi - 2 * n), M * n * d, P * n * d
            cu, cv = Q * kap * n * f3 / 2 + P * f2, kap * d * f3 / 2 + M * Q * f2
            return (
                Q * kap * n * f2 + P * f1,
                kap * d * f2 + M * Q * f1,
                Q * kap * f2 + cu * x_n,
                -kap * f2 + cv * x_n,
                Q * M * n * f2 + f1 + cu * x_p,
                M * d * f2 + cv * x_p,
                Q * P * n * f2 + cu * x_m,
                P * d * f2 + Q * f1 + cv * x_m,
            )

        def inner(t: Any, xi0: Any) -> tuple[Any, Any, Any]:
            """``(int H_p, int H_m, int (1 - xi) H_n)`` over ``[xi_0, 1]``, for ``t`` and ``xi_0`` balls."""
            lo = ball_lower(xi0)
            hi = ball_upper(xi0)
            out = [arb(0), arb(0), arb(0)]
            for j, X in enumerate(xis):
                if (j + 1) * h_xi <= lo:
                    continue
                weight = arb(h_xi) if j * h_xi >= hi else arb(h_xi / 2, h_xi / 2)
                n = t - R * (1 - X)
                _, _, un, vn, up, vp, um, vm = sections(X, n)
                gu, gv = g_xi[j]
                out[0] += weight * (gu * up + gv * vp)
                out[1] += weight * (gu * um + gv * vm)
                out[2] += weight * (1 - X) * (gu * un + gv * vn)
            return out[0], out[1], out[2]

        def below(t: Any) -> tuple[Any, Any, Any]:
            xi0 = 1 - t / R
            ip, im, i_n = inner(t, xi0)
            zero = arb(0)
            u, v, *_ = sections(xi0, zero)
            gu0, gv0 = gains.value(0, xi0), gains.value(1, xi0)
            k_r = gains.slope(1, xi0) * t / R**3 - gv0 / R**2 - (gu0 * u + gv0 * v) * t / R**2 - i_n
            return ip, im, k_r

        def above(t: Any) -> tuple[Any, Any, Any]:
            xi0 = (t - R) / (1 - R)
            ip, im, i_n = inner(t, xi0)
            u, v, *_ = sections(xi0, xi0)
            gu0, gv0 = gains.value(0, xi0), gains.value(1, xi0)
            s = 1 - R
            k_r = Q * gains.slope(0, xi0) * (t - 1) / s**3 + Q * gu0 / s**2 - (gu0 * u + gv0 * v) * (t - 1) / s**2 - i_n
            return ip, im, k_r

        for i in range(T_CELLS):
            a, b = i / T_CELLS, (i + 1) / T_CELLS
            t = arb((a + b) / 2, (b - a) / 2)
            if b <= r_lo:
                parts = below(t)
            elif a >= r_hi:
                parts = above(t)
            else:
                parts = tuple(x.union(y) for x, y in zip(below(t), above(t)))
            for j, d in enumerate(parts):
                if not d.is_finite():
                    raise CertificationError("the gains' slopes on the box are not finite")
                self.mids[j].append(arb(d.mid()))
                rest[j] += arb(d.rad())
        self.rest = tuple(x / T_CELLS for x in rest)

    def spread(self, w: Any, cells: list[Any]) -> Any:
        """An upper bound (an ``arb``) of ``|D_p| |p - p_0| + |D_m| |m - m_0| + |D_r| |r - r_0|`` on ``i w`` for
        every ``w`` of the ball ``w``, ``cells`` its :func:`cell_integrals` with :data:`T_CELLS` cells."""
        flint = self.flint
        arb, acb = flint.arb, flint.acb
        out = arb(0)
        for j, (mids, rest, offset) in enumerate(zip(self.mids, self.rest, self.offsets)):
            total = acb(0)
            for c, t in zip(mids, cells):
                total += c * t
            if j == 2:
                total += self.jump * acb(0, -(w * self.R)).exp()
            out += (abs(total) + rest) * arb(offset)
        return arb(out.upper())
