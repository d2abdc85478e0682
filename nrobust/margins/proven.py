"""The crossing set of ``F(s; delta) = A(s) + B(s) e^{-delta s}`` proven in ball arithmetic.

:mod:`nrobust.margins.search` finds every zero of ``g(w) = |A(i w)|^2 - |B(i w)|^2`` with
floating-point evaluations and a fixed rounding allowance. This module proves the same
set with python-flint's balls (:mod:`nrobust.balls`: every value a midpoint and a radius
containing every rounding error), for ``A`` and ``B`` *as represented* (stored floats
exact, ``N~`` the cubic spline on its grid). Each statement below is a theorem about
those functions.

**Frequency bound.** ``W`` comes from :func:`nrobust.margins.axis.frequency_bound` or, when
the gap is below the rounding of its floating-point sum (``|b_n / a_n| = 1 - 2^-52``), from
the tail bound at half the gap proven positive in :func:`proven_gap`; it is then proven:
the principal gap ``|a_0| - sum |a_k|`` (in ``_GAP_PREC`` bits) and the tail bound
``r_A(W) + r_B(W)`` (point terms of lower degree, and kernels by
``|q|(W) W^-n min(M_0, V_0 / W, V_1 / W + V_2 / W^2)`` with ``M_0 >= int nu^m |N|``, ``V_0`` the
variation bound of integration by parts and ``V_1``, ``V_2`` those of integration by parts twice,
all summed in balls from the stored pieces of ``N``)
are enclosed and ``r(W) < gap`` is checked on the balls. Then
``| |A(i w)| - |B(i w)| | > 0`` for ``|w| >= W`` and, on ``Re s >= 0``, every zero of
``F(.; delta)`` has ``|s| < W`` (the estimate of :mod:`nrobust.margins.axis`).

**Exclusion.** ``h = |A(i w)| - |B(i w)|`` has ``|h'| <= |A'(i w)| + |B'(i w)| <= L(a, b)``
on ``[a, b]``, with ``L`` summed in balls from the moduli of the terms (point terms
``|p'|(b) + tau |p|(b)``; kernels ``|c| (|q'|(b) j_m + |q|(b) j_{m+1})``,
``j_k = min(M_k, V_k / a)``, ``V_1 = M_0 + b_N V_0``). A segment with
``|h(a)| + |h(b)| > L (b - a)``, the values enclosed in balls at the end points, holds
no zero (first order). Second order: ``g = |A|^2 - |B|^2 = Re(D conj(S))``, ``D = A - B``,
``S = A + B``, has ``|g''| <= M(a, b)``, summed in balls over the pairs of point terms
(``p(i w) conj(q(i w)) e^{-i w (t - u)}``: only the difference of the delays enters) and
by the product rule for the kernel parts (``j_2``, ``V_2 = 2 M_1 + b_N^2 V_0``); with
``g(a)``, ``g(b)`` of one proven sign ``sigma``, ``sigma g`` is at least its chord less
``M (w - a) (b - w) / 2``, positive on ``[a, b]`` when
``sqrt|g(a)| + sqrt|g(b)| > sqrt(M / 2) (b - a)``. A segment is accepted by either test.
The grid is planned in floating point (from each point, the farthest point of a dense
planning grid at which either test passes on the float values; cheap) and every
segment is then checked in balls; failures are cut, and stretches where ``|h|`` is small
become clusters.

**Isolation.** On a cluster ``I`` (balls ``A^{(k)}(i I)``, ``B^{(k)}(i I)`` over the whole
interval): ``g' = -2 Im(conj(A) A') + 2 Im(conj(B) B')``, or, where that ball holds ``0``, its
intersection with the centred form ``g'(c) + g''(I) (I - c)`` (``c`` the midpoint): the ball on ``I``
loses the cancellation of the two terms, each of size ``|A| |A'|`` and far above ``g'`` where
``|A|`` and ``|B|`` nearly agree (strongly coupled loops), while the centred form's radius
shrinks with the square of the width. If ``0`` is not in ``g'(I)`` and
the proven signs of ``g`` at the ends differ, ``I`` holds exactly one zero, simple, with
the proven sign of ``g'`` (the direction of the crossing, ``sign(g') sign(w)``); the
interval Newton operator ``m - g(m) / g'(J)`` shrinks its enclosure ``J`` to a few ulps.
Same signs: no zero. Otherwise ``I`` is bisected at a point where the sign of ``g`` is
proven. Down to width ``1e-9 max(1, W)``, the second derivative decides:
``g'' = 2 (|A'|^2 - Re(conj(A) A'')) - 2 (|B'|^2 - Re(conj(B) B''))``; with ``0`` not in
``g''(I)``, ``g'`` has at most one zero ``w*`` (enclosed by interval Newton on ``g'``) and
``sigma g`` (``sigma = sign g''``) is convex: ``sigma g(w*) > 0`` proves ``I`` zero-free,
``< 0`` proves one simple zero on each side where ``sigma g > 0`` at the end. If ``g(w*)``
encloses 0, a tangency cannot be told from a near-tangency in ball arithmetic: the
cluster is kept as *unresolved*, with the interval ``J`` (``|w - w*|^2 <= 2 |g(w*)| / min |g''|``)
that would hold its zeros, if any, and the enclosure of the delays they would fix.
Anything else is refused (:class:`~nrobust.errors.CertificationError`).

**Polynomial loops.** When ``A`` and ``B`` have no kernel and one point delay each,
``g`` is a polynomial in ``w`` with rational coefficients (the stored floats): its real
zeros are isolated exactly with their multiplicities (FLINT's square-free factorisation
and root isolation), so tangencies are *proven* double zeros.

**Delays.** At a zero enclosure ``[w]``, ``u = -B(i w)/A(i w)`` is enclosed and the first
delay with ``e^{i w delta} = u`` is ``phi / w``, ``phi = arg u`` taken in ``[0, 2 pi)``
(``w > 0``); the branch is chosen from the proven sign of ``Im u`` (or of ``Re u`` where
``Im u`` encloses 0); a ``u`` that may lie on the positive real axis (a delay near a
multiple of the period, e.g. ``delta = 0``) is refused.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._flint import ball_lower, ball_upper, working_precision
from .._json import fields_dict
from .._validate import positive_int
from ..balls import (
    ball_abs_moment,
    ball_function,
    ball_second_order_variation,
    ball_variation_bound,
    radius_acb,
    require_flint,
)
from ..bounds import TailBound, joint_degree, principal_gap, radius_where, root_free_region
from ..errors import CertificationError, ParameterError
from ..quasipoly import DistributedDelay, QuasiPolynomial
from .axis import AxisFunction, AxisKernels, frequency_bound, is_zero
from .crossing import CrossingSearch

__all__ = ["ProvenCrossings", "proven_crossings", "proven_gap", "proven_zero_radius", "proven_zero_root"]

# Float planning of the exclusion grid: steps of this fraction of |h| / L, and |h| below
# which (relative to max |h|) a stretch is handed to the isolation as a cluster.
_PLAN_FRACTION = 0.9
# Margin of the planned segments over the exclusion tests on the floating-point values.
_PLAN_MARGIN = 1.02
_PLAN_FLOOR = 2e-2
# Points of the float planning grid per unit of W (and at least this many).
_PLAN_POINTS = 2000
_PLAN_DENSITY = 64.0
_PLAN_PER_EVAL = 16
# The planning grid is evaluated in chunks of this many points (the kernel sums hold a few
# complex arrays of ten times the chunk's size).
_PLAN_CHUNK = 1 << 16
# Blocks of the frequency range with their own Lipschitz bound; failing segments are cut
# into _CUT pieces, at most _CUT_ROUNDS times, before they join a cluster.
_BLOCKS = 64
_CUT = 4
_CUT_ROUNDS = 4
# Clusters narrower than this (relative to max(1, W)) are decided by the second derivative.
_MIN_WIDTH = 1e-9
# Interval Newton steps (each at least halves a contracting enclosure in practice).
_NEWTON_STEPS = 60
# Relative width at which an enclosure of a zero is tight enough.
_TIGHT = 1e-14
# Bisection rounds of the isolation.
_MAX_ROUNDS = 200
# Precision (bits) of the principal gap: the difference of a few stored floats, exact or
# enclosed to far below their own rounding.
_GAP_PREC = 256


# ============================================================================ result
@dataclass(frozen=True)
class ProvenCrossings:
    """Every zero of ``|A(i w)|^2 - |B(i w)|^2`` on ``[0, W]`` (``[-W, W]`` for complex loops), proven.

    Intervals are ``(lo, hi)`` floats that contain the exact value (rounded outwards).

    Attributes
    ----------
    omegas : tuple of (float, float)
        Enclosure of each zero, increasing; each holds exactly one zero.
    multiplicities : tuple of int
        1 for a simple zero (a crossing), 2 for a proven double zero (a tangency; exact
        route only); higher multiplicities are crossings when odd, tangencies when even.
    slopes : tuple of int
        Proven sign of ``g'`` at each simple zero (0 at a tangency); the direction of
        the crossing is ``slope * sign(w)``.
    delays : tuple of (float, float)
        Enclosure of the first delay ``delta_0 = phi / w`` of each zero.
    unresolved : tuple of (float, float)
        Intervals that may hold a tangency (a double zero, two close zeros, or none:
        indistinguishable in ball arithmetic).
    unresolved_delays : tuple of (float, float)
        Enclosure of the delays a zero in each unresolved interval would fix.
    frequency_bound : float
        ``W``, proven: no zero with ``|w| >= W``.
    gap : (float, float)
        Enclosure of the principal gap ``|a_0| - sum |a_k|``.
    method : str
        ``"exact polynomial"`` or ``"ball bisection"``.
    evaluations : int
        Ball evaluations of ``A`` and ``B`` (or of their shared kernels).
    """

    omegas: tuple[tuple[float, float], ...]
    multiplicities: tuple[int, ...]
    slopes: tuple[int, ...]
    delays: tuple[tuple[float, float], ...]
    unresolved: tuple[tuple[float, float], ...]
    unresolved_delays: tuple[tuple[float, float], ...]
    frequency_bound: float
    gap: tuple[float, float]
    method: str
    evaluations: int

    def margin_ball(self) -> tuple[float, float] | None:
        """Enclosure of the smallest first delay over every zero (None without zeros)."""
        if not self.delays:
            return None
        return (min(lo for lo, _ in self.delays), min(hi for _, hi in self.delays))

    def search(self) -> CrossingSearch:
        """The zeros as a :class:`CrossingSearch` (midpoints; unresolved intervals as tangencies)."""
        rows = [
            (0.5 * (lo + hi), m % 2 == 0, s) for (lo, hi), m, s in zip(self.omegas, self.multiplicities, self.slopes)
        ]
        rows += [(0.5 * (lo + hi), True, 0) for lo, hi in self.unresolved]
        rows.sort()
        return CrossingSearch(
            np.array([w for w, _, _ in rows], dtype=float),
            np.array([t for _, t, _ in rows], dtype=bool),
            self.frequency_bound,
            0.5 * (self.gap[0] + self.gap[1]),
            self.evaluations,
            np.array([s for _, _, s in rows], dtype=np.int64),
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


# ============================================================================ balls to floats
def _sign(x: Any) -> int:
    """Proven sign of the arb ``x`` (0 when it encloses 0)."""
    return 1 if x > 0 else (-1 if x < 0 else 0)


def _interval(flint: Any, a: float, b: float) -> Any:
    """The arb holding ``[a, b]`` (end points exact)."""
    return flint.arb(a) if a == b else flint.arb(a).union(flint.arb(b))


# ============================================================================ term bounds
class _Moduli:
    """Proven bounds of a kernel: ``M_k >= int nu^(m+k) |N|`` (``k = 0, 1, 2``), ``V_0``, ``(V_1, V_2)`` and
    ``nu_max``.

    :func:`nrobust.balls.ball_abs_moment`, :func:`nrobust.balls.ball_variation_bound` at ``Re s = 0`` and
    :func:`nrobust.balls.ball_second_order_variation` (``N`` as represented: the stored spline pieces); ``V_0``
    and ``(V_1, V_2)`` only for moment 0.
    """

    def __init__(self, flint: Any, d: DistributedDelay) -> None:
        start, h, _ = d.pieces
        self.M = [ball_abs_moment(d, 0.0, k) for k in range(3)]
        self.V0 = ball_variation_bound(d, 0.0) if d.moment == 0 else None
        self.kernel = d
        self.nu_max = flint.arb(0)
        for s0, hv in zip(start, h):
            self.nu_max = self.nu_max.max(flint.arb(float(s0)) + flint.arb(float(hv)))

    @functools.cached_property
    def V12(self) -> tuple[Any, Any] | None:
        """``(V_1, V_2)``, formed on first use (only the frequency bound needs them)."""
        return ball_second_order_variation(self.kernel) if self.kernel.moment == 0 else None


def _abs_arb(flint: Any, c: complex) -> Any:
    return abs(_to_acb(flint, c)) if c.imag else abs(flint.arb(c.real))


def _to_acb(flint: Any, c: complex) -> Any:
    c = complex(c)
    return flint.acb(c.real, c.imag) if c.imag else flint.acb(c.real)


def _abs_poly(flint: Any, coefs: NDArray, r: Any, order: int = 0) -> Any:
    """``sum_j |c_j| (j)_order r^(j - order)``: a bound of ``|p^(order)(s)|`` for ``|s| <= r``."""
    out = flint.arb(0)
    for j, c in enumerate(coefs):
        if j >= order and c != 0:
            out += _abs_arb(flint, complex(c)) * math.perm(j, order) * r ** (j - order)
    return out


@functools.lru_cache(maxsize=64)
def _moduli(d: DistributedDelay) -> _Moduli:
    """:class:`_Moduli` of ``d``, built once (kernels recur across calls)."""
    return _Moduli(require_flint(), d)


class _Slopes:
    """Proven bounds on ``a <= |w| <= b`` of ``|h'|`` and ``|g''|`` (module notes), from those of the moduli.

    ``|h'| <= |A'| + |B'|``, and ``g = |A|^2 - |B|^2 = Re(D conj(S))`` with ``D = A - B``,
    ``S = A + B`` (the cross terms ``A conj(B) - B conj(A)`` are imaginary), so
    ``|g''| <= |D''| |S| + 2 |D'| |S'| + |D| |S''|``: kernels that enter ``A`` and ``B`` with
    opposite signs (``+-I_N`` in the paper's loops) cancel in ``S`` instead of being counted twice.
    For a factor ``P``, ``P_k >= |P^(k)(i w)|`` (``k = 0, 1, 2``) is summed in balls over its terms
    (coefficients of equal delays, and of equal kernels, combined in balls): a point term
    ``p(s) e^{-t s}`` gives ``|p|``, ``|p'| + |t| |p|`` and ``|p''| + 2 |t| |p'| + t^2 |p|``
    (moduli of the polynomials at ``|s| = b``); a kernel term ``q(s) J(s)``,
    ``J^(k)(s) = (-1)^k int nu^(m+k) N e^{-nu s}``, gives ``|q| j_0``, ``|q'| j_0 + |q| j_1`` and
    ``|q''| j_0 + 2 |q'| j_1 + |q| j_2`` with ``j_k = min(M_k, V_k / a)``: ``V_0`` the variation
    bound, ``V_1 = M_0 + nu_max V_0`` and ``V_2 = 2 M_1 + nu_max^2 V_0`` (integration by parts
    of ``nu N`` and ``nu^2 N``).
    """

    def __init__(self, flint: Any, A: QuasiPolynomial, B: QuasiPolynomial, kernels: AxisKernels) -> None:
        self.flint = flint
        arb = flint.arb
        # per kernel unit: M_k and V_k (None without a variation bound)
        self.units = []
        for u in kernels.units:
            mod = _moduli(u)
            V = None
            if mod.V0 is not None:
                V = [mod.V0, mod.M[0] + mod.nu_max * mod.V0, 2 * mod.M[1] + mod.nu_max**2 * mod.V0]
            self.units.append((mod.M, V))
        # per side: coefficients (balls) of the point terms by delay and of the kernel terms by unit
        points: list[dict[float, list[Any]]] = [{}, {}]
        units: list[dict[int, list[Any]]] = [{}, {}]
        for side, P in enumerate((A, B)):
            for (p, t), radius in zip(P.point_terms, P.radii_of()):
                _accumulate(points[side], float(t), [radius_acb(flint, c, r) for c, r in zip(p, radius)])
            for k, c, q in kernels.terms[side]:
                _accumulate(units[side], k, [_to_acb(flint, c) * _to_acb(flint, x) for x in q])
        self.degree = 0
        self.factors = {}
        for name, sign in (("A", 0), ("B", 0), ("D", -1), ("S", 1)):
            pts, uts = dict(points[name == "B"]), dict(units[name == "B"])
            if sign:
                for t, cs in points[1].items():
                    _accumulate(pts, t, [sign * c for c in cs])
                for k, cs in units[1].items():
                    _accumulate(uts, k, [sign * c for c in cs])
            self.factors[name] = (
                [(arb(t), _derivative_moduli(cs)) for t, cs in pts.items()],
                [(k, _derivative_moduli(cs)) for k, cs in uts.items()],
            )
            self.degree = max([self.degree] + [len(cs) for cs in (*pts.values(), *uts.values())])

    def moduli_bounds(self, name: str, a: float, b: float) -> tuple[list[tuple[Any, list[Any]]], list[Any]]:
        """Bounds on ``a <= |w| <= b`` of the factor ``name`` (``"A"``, ``"B"``, ``"D"``, ``"S"``): its point
        terms ``(t, [|p|, |p'|, |p''|])`` (delays ``t >= 0``) and ``[K_0, K_1, K_2]`` of its kernel terms."""
        arb = self.flint.arb
        r = arb(max(abs(a), abs(b)))
        powers = [arb(1)]
        for _ in range(self.degree):
            powers.append(powers[-1] * r)
        r_min = 0.0 if a <= 0.0 <= b else min(abs(a), abs(b))
        pts, uts = self.factors[name]
        points = [(t, _poly_jet(arb, p, powers)) for t, p in pts]
        d = [arb(0), arb(0), arb(0)]
        for k, q in uts:
            M, V = self.units[k]
            j = M if V is None or r_min == 0.0 else [m.min(v / r_min) for m, v in zip(M, V)]
            q0, q1, q2 = _poly_jet(arb, q, powers)
            d[0] += q0 * j[0]
            d[1] += q1 * j[0] + q0 * j[1]
            d[2] += q2 * j[0] + 2 * q1 * j[1] + q0 * j[2]
        return points, d

    def total(self, name: str, a: float, b: float) -> list[Any]:
        """``[P_0, P_1, P_2]``: bounds of ``|P^(k)(i w)|`` of the factor ``name`` on ``a <= |w| <= b``."""
        points, d = self.moduli_bounds(name, a, b)
        return _sum_jets(points, d)

    def __call__(self, a: float, b: float) -> tuple[Any, Any]:
        """``(L, M)``: ``|h'| <= L`` and ``|g''| <= M`` on ``a <= |w| <= b``."""
        arb = self.flint.arb
        L = self.total("A", a, b)[1] + self.total("B", a, b)[1]
        d_points, d_kernels = self.moduli_bounds("D", a, b)
        s_points, s_kernels = self.moduli_bounds("S", a, b)
        M = arb(0)
        for t, p in d_points:
            for u, q in s_points:  # p(i w) conj(q(i w)) e^{-i w (t - u)}
                r = _product_jet(p, q)
                gap = abs(t - u)
                M += r[2] + 2 * gap * r[1] + gap * gap * r[0]
        zero = [arb(0)] * 3
        d_total, s_total = _sum_jets(d_points, zero), _sum_jets(s_points, zero)
        for x, y in ((d_total, s_kernels), (d_kernels, s_total), (d_kernels, s_kernels)):
            M += _product_jet(x, y)[2]
        return L, M


def _derivative_moduli(coefs: list[Any]) -> list[list[tuple[int, Any]]]:
    """``[[(j - k, |c_j| (j)_k) for j >= k] for k = 0, 1, 2]``: the moduli of the coefficients of ``p^(k)``."""
    return [[(j - k, abs(c) * math.perm(j, k)) for j, c in enumerate(coefs) if j >= k] for k in range(3)]


def _poly_jet(arb: Any, moduli: list[list[tuple[int, Any]]], powers: list[Any]) -> list[Any]:
    """Bounds ``[|p|, |p'|, |p''|]`` at ``|s| <= r`` (``powers[e] = r^e``) from :func:`_derivative_moduli`."""
    out = []
    for terms in moduli:
        acc = arb(0)
        for e, m in terms:
            acc += m * powers[e]
        out.append(acc)
    return out


def _sum_jets(points: list[tuple[Any, list[Any]]], kernels: list[Any]) -> list[Any]:
    """Bounds of ``|P|``, ``|P'|``, ``|P''|``: ``P = sum p(s) e^{-t s}`` (``points``: ``(t, [|p|, |p'|, |p''|])``,
    ``t >= 0``) plus terms bounded by ``kernels``."""
    out = list(kernels)
    for T, (p0, p1, p2) in points:
        out[0] += p0
        out[1] += p1 + T * p0
        out[2] += p2 + 2 * T * p1 + T * T * p0
    return out


def _product_jet(x: list[Any], y: list[Any]) -> list[Any]:
    """Bounds ``[|f g|, |(f g)'|, |(f g)''|]`` from those of ``f`` (``x``) and ``g`` (``y``): the product rule."""
    return [x[0] * y[0], x[1] * y[0] + x[0] * y[1], x[2] * y[0] + 2 * x[1] * y[1] + x[0] * y[2]]


def _accumulate(terms: dict, key: Any, coefs: list[Any]) -> None:
    """Add the ball coefficients ``coefs`` to ``terms[key]`` (into a new list: copies of ``terms`` share the old)."""
    old = terms.get(key)
    if old is None:
        terms[key] = list(coefs)
        return
    n = max(len(old), len(coefs))
    zero = 0 * coefs[0] if coefs else 0 * old[0]
    old = old + [zero] * (n - len(old))
    new = list(coefs) + [zero] * (n - len(coefs))
    terms[key] = [x + y for x, y in zip(old, new)]


# ============================================================================ frequency bound
def _proven_bound(flint: Any, parts: tuple[QuasiPolynomial, ...], W: float) -> tuple[Any, Any] | None:
    """``(gap, tail)`` balls at radius ``W`` (delays measured from ``t0``, ``Re s >= 0``), in
    ``_GAP_PREC`` bits, of the loop ``parts = (A, B)`` (``delta -> 0+``) or of one function ``(F,)``."""
    with working_precision(_GAP_PREC):
        return _bound_balls(flint, parts, W)


def _bound_balls(flint: Any, parts: tuple[QuasiPolynomial, ...], W: float) -> tuple[Any, Any] | None:
    """:func:`_proven_bound` at the working precision."""
    arb = flint.arb
    n = joint_degree(*parts)
    principal = principal_gap({str(order): (P, order) for order, P in enumerate(parts)}, n, 0.0)
    if principal is None:
        return None
    # the s^n coefficients, each with its radius (a zero one with a positive radius too)
    lead = [
        (complex(p[n]), float(t), order, float(r[n]))
        for order, P in enumerate(parts)
        for (p, t), r in zip(P.point_terms, P.radii_of())
        if p.size == n + 1 and (p[n] != 0 or r[n] > 0)
    ]
    lead.sort(key=lambda e: (e[1], e[2]))
    if lead[0][1] != principal.t0:
        return None  # a ball of zero coefficients first: no term dominates for every function
    # each coefficient's radius widens the gap's ball on both sides (its lower end is what the proofs use; the
    # whole ball holds the gap of every function of the balls, which the reports print)
    gap = _abs_arb(flint, lead[0][0]) + arb(0, lead[0][3])
    for c, _, _, r in lead[1:]:
        gap -= _abs_arb(flint, c) + arb(0, r)
    R = arb(W)
    tail = arb(0)
    for P in parts:
        for (p, _), radius in zip(P.point_terms, P.radii_of()):
            for j in range(min(p.size, n)):
                if p[j] != 0 or radius[j] > 0:
                    tail += (_abs_arb(flint, complex(p[j])) + arb(float(radius[j]))) * R ** (j - n)
        for d in P.distributed:
            mod = _moduli(d)
            qpow = _abs_poly(flint, d.poly, R, 0) / R**n
            bound = mod.M[0]
            if mod.V0 is not None and mod.V12 is not None:
                # integrated by parts once and twice (every delay >= t0: TailBound's notes)
                bound = bound.min(mod.V0 / R).min(mod.V12[0] / R + mod.V12[1] / R**2)
            tail += qpow * bound
    return gap, tail


def _frequency_bound(A: QuasiPolynomial, B: QuasiPolynomial) -> float:
    """The radius ``W`` to prove: :func:`~nrobust.margins.axis.frequency_bound`, or, when the gap is
    below the rounding of its floating-point sum, the radius where the tail falls below half the
    gap proven positive (:func:`proven_gap`).

    Raises
    ------
    ParameterError
        The gap is not proven positive: the difference operator is not strongly stable for
        small delays (crossings accumulate at infinity).
    """
    w_bound = frequency_bound(A, B)
    if w_bound is not None:
        return w_bound[0]
    low = proven_gap(A, B)[0]
    if not low > 0.0:
        raise ParameterError(
            "A, B",
            "loop factors whose difference operator is strongly stable for small delays (|a_0| > sum |others|)",
            None,
        )
    n = joint_degree(A, B)
    principal = principal_gap({"A": (A, 0), "B": (B, 1)}, n, 0.0)
    assert principal is not None  # the gap is proven positive
    tail_a = TailBound(A, n, 0.0, principal.t0, second_order=True)
    tail_b = TailBound(B, n, 0.0, principal.t0, second_order=True)
    return radius_where(lambda R: float(tail_a(R) + tail_b(R)), 0.5 * low, "proven crossing search")


# ============================================================================ ball evaluation of the axis functions
class _Axis:
    """``A`` and ``B`` on the imaginary axis in balls, with a work bound on the evaluations."""

    def __init__(self, A: QuasiPolynomial, B: QuasiPolynomial, max_evals: int) -> None:
        self.flint = require_flint()
        self.fa, self.fb = ball_function(A), ball_function(B)
        self.kernels = AxisKernels((A, B))
        self.points = [
            None
            if not P.point_terms
            else ball_function(QuasiPolynomial(P.coefs, P.delays, radii=P.point_radii or None))
            for P in (A, B)
        ]
        self.units = [ball_function(QuasiPolynomial([], [], [u])) for u in self.kernels.units]
        flint = self.flint
        # the kernel terms c q(s) J_k(s) of each side, c and q as exact balls (converted once)
        self.terms = [
            [(k, _to_acb(flint, c), flint.acb_poly([_to_acb(flint, x) for x in q])) for k, c, q in side]
            for side in self.kernels.terms
        ]
        self.evals = 0
        self.max_evals = max_evals

    def spend(self, n: int) -> None:
        if self.evals + n > self.max_evals:
            raise CertificationError(
                f"proven crossing search: {n} more ball evaluations after {self.evals} exceed the work bound "
                f"max_evals={self.max_evals} (raise max_evals)"
            )
        self.evals += n

    def values(self, w: list[float]) -> list[tuple[Any, Any]]:
        """``(A(i w), B(i w))`` at points, the kernels shared by ``A`` and ``B`` summed once."""
        flint = self.flint
        self.spend(len(w))
        pts = [flint.acb(0, x) for x in w]  # floats or exact arb
        out = []
        sums = [u.many(pts) for u in self.units]
        points = [None if f is None else f.many(pts) for f in self.points]
        for i, s in enumerate(pts):
            vals = []
            for side in range(2):
                at = points[side]
                v = at[i] if at is not None else flint.acb(0)
                for k, c, q in self.terms[side]:
                    v += c * q(s) * sums[k][i]
                vals.append(v)
            out.append((vals[0], vals[1]))
        return out

    def jet(self, s: Any, order: int) -> list[tuple[Any, Any]]:
        """``[(A^(k)(s), B^(k)(s)) for k = 0..order]`` at a ball ``s``."""
        self.spend(order + 1)
        return [(self.fa(s, k), self.fb(s, k)) for k in range(order + 1)]

    def g(self, s: Any) -> Any:
        """``g`` at a ball ``s`` (points: the shared kernels summed once)."""
        if s.imag.rad() == 0:
            ((a, b),) = self.values([s.imag])
        else:
            a, b = self.jet(s, 0)[0]
        return _sq(a) - _sq(b)

    def g1(self, s: Any) -> Any:
        (a, b), (da, db) = self.jet(s, 1)
        return -2 * (a.conjugate() * da).imag + 2 * (b.conjugate() * db).imag

    def g2(self, s: Any) -> Any:
        (a, b), (da, db), (d2a, d2b) = self.jet(s, 2)
        return 2 * (_sq(da) - (a.conjugate() * d2a).real) - 2 * (_sq(db) - (b.conjugate() * d2b).real)

    def g1_on(self, iv: Any) -> Any:
        """``g'`` on the interval ``iv`` (an arb): its ball on the interval, else the centred form.

        The ball of ``g' = -2 Im(conj(A) A') + 2 Im(conj(B) B')`` on an interval loses the
        cancellation of its two terms (each of size ``|A| |A'|``, far above ``g'`` where
        ``|A|`` and ``|B|`` nearly agree: a strongly coupled loop), so its radius is a
        fixed multiple of the interval's. Where it holds 0, the mean value theorem gives
        ``g'(w) in g'(c) + g''(I) (w - c)`` (``c`` the midpoint), whose radius is that of
        ``g''(I)`` times the interval's: both enclose ``g'`` on ``iv``, so their
        intersection does.
        """
        flint = self.flint
        direct = self.g1(flint.acb(0, iv))
        if not direct.contains(0):
            return direct
        c = iv.mid()
        centred = self.g1(flint.acb(0, c)) + self.g2(flint.acb(0, iv)) * (iv - c)
        if not centred.overlaps(direct):
            raise CertificationError(
                "proven crossing search: two enclosures of g' on one interval are disjoint (inconsistent balls)"
            )
        return centred.intersection(direct)


def _sq(z: Any) -> Any:
    """``|z|^2`` (products: ``x**2`` of a ball holding 0 is not finite in python-flint)."""
    return z.real * z.real + z.imag * z.imag


# ============================================================================ delays
def _first_delay(flint: Any, a: Any, b: Any, w: Any, w_sign: int) -> tuple[float, float] | None:
    """Enclosure of the first delay with ``e^{i w delta} = -B/A`` (None when the branch is not proven)."""
    if a.contains(0):
        return None
    u = -b / a
    pi2 = 2 * flint.arb.pi()
    im, re = _sign(u.imag), _sign(u.real)
    if w_sign > 0:
        if im > 0:
            phi = u.arg()
        elif im < 0:
            phi = u.arg() + pi2
        elif re < 0:
            phi = flint.arb.pi() + (-u).arg()
        else:
            return None
    else:
        if im < 0:
            phi = u.arg()
        elif im > 0:
            phi = u.arg() - pi2
        elif re < 0:
            phi = (-u).arg() - flint.arb.pi()
        else:
            return None
    if w.contains(0):  # a zero of g near w = 0: only a lower bound of its delay
        low = abs(phi).lower() / abs(w).upper()
        return (ball_lower(low), math.inf) if low > 0 else None
    delay = phi / w
    if not delay > 0:
        return None
    return ball_lower(delay), ball_upper(delay)


# ============================================================================ exact route (polynomial loops)
def _fmpq(flint: Any, x: float) -> Any:
    f = Fraction(float(x))
    return flint.fmpq(f.numerator, f.denominator)


def _axis_square(flint: Any, P: QuasiPolynomial) -> Any:
    """``|P(i w)|^2`` as an ``fmpq_poly`` in ``w`` (``P`` a polynomial times one delay)."""
    if not P.point_terms:
        return flint.fmpq_poly([0])
    ((p, _),) = P.point_terms
    re, im = [], []
    for j, c in enumerate(p):
        # c i^j = (x + i y) (u + i v) with i^j = u + i v
        x, y = _fmpq(flint, complex(c).real), _fmpq(flint, complex(c).imag)
        u, v = ((1, 0), (0, 1), (-1, 0), (0, -1))[j % 4]
        re.append(x * u - y * v)
        im.append(x * v + y * u)
    pr, pi_ = flint.fmpq_poly(re), flint.fmpq_poly(im)
    return pr * pr + pi_ * pi_


def _exact_route(flint: Any, A: QuasiPolynomial, B: QuasiPolynomial, real: bool) -> list[tuple[Any, int, int]] | None:
    """Real zeros ``(ball, multiplicity, slope)`` of ``g`` for polynomial loops, or None."""
    if A.distributed or B.distributed or len(A.point_terms) > 1 or len(B.point_terms) > 1:
        return None
    if not (A.exact_points and B.exact_points):  # coefficients known to a radius: not rationals
        return None
    g = _axis_square(flint, A) - _axis_square(flint, B)
    if g.is_zero():
        raise CertificationError("proven crossing search: |A(i w)| = |B(i w)| for every w (g vanishes identically)")
    out = []
    _, factors = g.factor_squarefree()
    for f, mult in factors:
        if f.degree() < 1:
            continue
        for root, _ in flint.fmpz_poly(f.numer()).complex_roots():
            if not root.imag.is_zero():
                continue
            w = root.real
            if w.is_zero() or (real and not w > 0):
                continue
            if mult % 2:
                d = g
                for _ in range(mult):
                    d = d.derivative()
                slope = _sign(flint.arb_poly([flint.arb(c.p) / flint.arb(c.q) for c in d.coeffs()])(w))
                if slope == 0:
                    return None
            else:
                slope = 0
            out.append((w, int(mult), slope))
    return sorted(out, key=lambda e: float(e[0].mid()))


# ============================================================================ ball route
def _blocks(flint: Any, slopes: _Slopes, lo: float, hi: float) -> tuple[NDArray, list[Any], list[Any]]:
    """Block edges of ``[lo, hi]`` and the proven bounds ``L >= |h'|`` and ``M >= |g''|`` on each block."""
    edges = np.linspace(lo, hi, _BLOCKS + 1)
    edges[0], edges[-1] = lo, hi
    both = [slopes(float(edges[k]), float(edges[k + 1])) for k in range(_BLOCKS)]
    return edges, [L for L, _ in both], [M for _, M in both]


def _plan(
    A: QuasiPolynomial,
    B: QuasiPolynomial,
    kernels: AxisKernels,
    edges: NDArray,
    lips: NDArray,
    curvs: NDArray,
    max_evals: int,
) -> NDArray:
    """Float planning of the exclusion grid; small stretches of ``|h|`` jumped over.

    From each point, the segment reaches the farthest point of the planning grid at which
    either exclusion test (:func:`_excluded`) passes on the floating-point values, by the
    margin ``_PLAN_MARGIN``; where none does, steps ``0.9 |h| / L`` (each passes the first
    test) lead to the next point of the planning grid. A heuristic only: every segment is
    then checked in balls. The planning grid is checked against ``_PLAN_PER_EVAL * max_evals``
    before it is allocated. ``h`` is summed with the kernels shared by ``A`` and ``B``
    evaluated once (``kernels``).
    """
    lo, hi = float(edges[0]), float(edges[-1])
    n = max(_PLAN_POINTS, _PLAN_DENSITY * (hi - lo) * max(1.0, A.max_delay, B.max_delay))
    if n > _PLAN_PER_EVAL * max_evals:
        raise CertificationError(
            f"proven crossing search: the frequency range [{lo:.6g}, {hi:.6g}] needs a planning grid of about "
            f"{n:.3g} points, beyond {_PLAN_PER_EVAL} times the work bound max_evals={max_evals} (raise max_evals)"
        )
    n = int(n)
    w = np.linspace(lo, hi, n)
    h, g = np.empty(n), np.empty(n)
    planning = AxisFunction(A, B, n, kernels)
    for k in range(0, n, _PLAN_CHUNK):
        a, b, _, _ = planning.factors(w[k : k + _PLAN_CHUNK])
        h[k : k + _PLAN_CHUNK] = np.abs(a) - np.abs(b)
        g[k : k + _PLAN_CHUNK] = np.abs(a) ** 2 - np.abs(b) ** 2
    floor = _PLAN_FLOOR * max(float(np.max(np.abs(h))), 1e-300)
    block = np.clip(np.searchsorted(edges, w, side="right") - 1, 0, lips.size - 1)
    # the walk below reads single entries: Python lists of the same doubles (the same arithmetic)
    small_at = (np.abs(h) < floor).tolist()
    w_at, h_at, root_at, sign_at = w.tolist(), np.abs(h).tolist(), np.sqrt(np.abs(g)).tolist(), np.sign(g).tolist()
    block_at, lip_at, curv_at = block.tolist(), lips.tolist(), np.sqrt(0.5 * curvs).tolist()

    def passes(i: int, j: int) -> bool:
        """Either exclusion test on ``[w_i, w_j]`` with the floating-point values, by ``_PLAN_MARGIN``."""
        width = _PLAN_MARGIN * (w_at[j] - w_at[i])
        ka, kb = block_at[i], block_at[j]
        if h_at[i] + h_at[j] > max(lip_at[ka : kb + 1]) * width:
            return True
        return sign_at[i] == sign_at[j] != 0 and root_at[i] + root_at[j] > max(curv_at[ka : kb + 1]) * width

    step_min = float((w[1] - w[0]) * 1e-3)
    pts = [lo]
    i, stride = 0, 16
    while i < n - 1:
        if small_at[i] or small_at[i + 1]:  # jump over the small stretch: it becomes a cluster
            j = i + 1
            while j < n - 1 and small_at[j]:
                j += 1
            pts.append(w_at[j])
            i = j
            continue
        if passes(i, i + 1):  # the farthest passing point: doubling, then bisection
            good, bad = i + 1, None
            while bad is None and good < n - 1:
                j = min(i + stride, n - 1)
                if passes(i, j):
                    good, stride = j, 2 * stride
                else:
                    bad = j
            while bad is not None and bad - good > 1:
                j = (good + bad) // 2
                good, bad = (j, bad) if passes(i, j) else (good, j)
            stride = max(2, good - i)
            i = good
            pts.append(w_at[i])
            continue
        # no point of the planning grid is reached: steps 0.9 |h| / L to the next one
        x, end = w_at[i], w_at[i + 1]
        L = max(lip_at[block_at[i] : block_at[i + 1] + 1])
        local = min(h_at[i], h_at[i + 1])
        while x < end:
            x = min(x + max(_PLAN_FRACTION * local / L if L > 0.0 else math.inf, step_min), end)
            pts.append(x)
        i += 1
    return np.unique(np.asarray(pts))


def _excluded(flint: Any, a: float, b: float, pa: tuple[Any, Any], pb: tuple[Any, Any], L: Any, M: Any) -> bool:
    """Whether ``[a, b]`` is proven free of zeros of ``g`` from ``(h, g)`` balls at its ends (module notes).

    First order: ``|h(a)| + |h(b)| > L (b - a)`` with ``|h'| <= L``. Second order: ``g(a)``,
    ``g(b)`` of one proven sign and ``sqrt|g(a)| + sqrt|g(b)| > sqrt(M / 2) (b - a)`` with
    ``|g''| <= M``: ``sigma g`` (``sigma`` that sign) is at least its chord less
    ``M (w - a) (b - w) / 2``, positive on ``[a, b]`` under that condition.
    """
    width = flint.arb(b) - flint.arb(a)
    if pa[0].abs_lower() + pb[0].abs_lower() > L * width:
        return True
    ga, gb = pa[1], pb[1]
    if not ((ga > 0 and gb > 0) or (ga < 0 and gb < 0)):
        return False
    return bool(ga.abs_lower().sqrt() + gb.abs_lower().sqrt() > (M / 2).sqrt() * width)


def _hg(values: list[tuple[Any, Any]]) -> list[tuple[Any, Any]]:
    """``(h, g) = (|A| - |B|, |A|^2 - |B|^2)`` balls from ``(A, B)`` balls."""
    return [(abs(x) - abs(y), _sq(x) - _sq(y)) for x, y in values]


def _ball_route(axis: _Axis, lo: float, hi: float, A: QuasiPolynomial, B: QuasiPolynomial) -> tuple[list, list]:
    """Zeros ``(ball, slope)`` and unresolved intervals ``(a, b, ball of w*)`` of ``g`` on ``[lo, hi]``."""
    flint = axis.flint
    slopes = _Slopes(flint, A, B, axis.kernels)
    edges, lips, curvs = _blocks(flint, slopes, lo, hi)
    grid = _plan(
        A,
        B,
        axis.kernels,
        edges,
        np.array([ball_upper(x) for x in lips]),
        np.array([ball_upper(x) for x in curvs]),
        axis.max_evals,
    )

    def bound(a: float, b: float) -> tuple[Any, Any]:
        ka = max(min(int(np.searchsorted(edges, a, side="right")) - 1, _BLOCKS - 1), 0)
        kb = max(min(int(np.searchsorted(edges, b, side="left")) - 1, _BLOCKS - 1), 0)
        L, M = lips[ka], curvs[ka]
        for k in range(ka + 1, kb + 1):
            L, M = L.max(lips[k]), M.max(curvs[k])
        return L, M

    hv = _hg(axis.values(grid.tolist()))
    todo = [(float(grid[i]), float(grid[i + 1]), hv[i], hv[i + 1]) for i in range(grid.size - 1)]
    failed: list[tuple[float, float, Any, Any]] = []
    for _ in range(_CUT_ROUNDS):
        retry: list[tuple[float, float, Any, Any]] = []
        for a, b, ha, hb in todo:
            L, M = bound(a, b)
            if _excluded(flint, a, b, ha, hb, L, M):
                continue
            need = L * (b - a)
            have = ha[0].abs_lower() + hb[0].abs_lower()
            if float(need.upper()) > 64.0 * float(have.lower()) or b - a < _MIN_WIDTH * max(1.0, hi):
                failed.append((a, b, ha, hb))
            else:
                retry.append((a, b, ha, hb))
        if not retry:
            todo = []
            break
        inner = [a + (b - a) * k / _CUT for a, b, _, _ in retry for k in range(1, _CUT)]
        vin = _hg(axis.values(inner))
        todo = []
        for i, (a, b, ha, hb) in enumerate(retry):
            pts = [a, *inner[i * (_CUT - 1) : (i + 1) * (_CUT - 1)], b]
            hs = [ha, *vin[i * (_CUT - 1) : (i + 1) * (_CUT - 1)], hb]
            todo.extend((pts[k], pts[k + 1], hs[k], hs[k + 1]) for k in range(_CUT))
    failed.extend(todo)
    failed.sort(key=lambda e: e[0])
    clusters: list[list[Any]] = []
    for a, b, ha, hb in failed:
        if clusters and clusters[-1][1] == a:
            clusters[-1][1], clusters[-1][3] = b, hb
        else:
            clusters.append([a, b, ha, hb])
    zeros: list[tuple[Any, int]] = []
    unresolved: list[tuple[float, float, Any]] = []
    work = [(a, b, _sign(ha[0]), _sign(hb[0])) for a, b, ha, hb in clusters]
    for _ in range(_MAX_ROUNDS):
        if not work:
            break
        nxt = []
        for a, b, sa, sb in work:
            nxt.extend(_decide(axis, a, b, sa, sb, hi, zeros, unresolved))
        work = nxt
    if work:
        a, b, _, _ = work[0]
        raise CertificationError(f"proven crossing search: [{a:.17g}, {b:.17g}] undecided after {_MAX_ROUNDS} rounds")
    return zeros, unresolved


def _gsign_at(axis: _Axis, w: float) -> int:
    return _sign(axis.g(axis.flint.acb(0, w)))


def _decide(
    axis: _Axis, a: float, b: float, sa: int, sb: int, scale: float, zeros: list, unresolved: list
) -> list[tuple[float, float, int, int]]:
    """One step on the cluster ``[a, b]`` (proven signs ``sa``, ``sb`` of ``g`` at its ends, 0 if unknown)."""
    flint = axis.flint
    iv = _interval(flint, a, b)
    s = flint.acb(0, iv)
    if sa == 0:
        sa = _gsign_at(axis, a)
    if sb == 0:
        sb = _gsign_at(axis, b)
    d1 = axis.g1_on(iv)
    slope = _sign(d1)
    if slope and sa and sb:
        if sa != sb:
            zeros.append((_newton(axis, a, b, sa, slope, d1, order=0), slope))
        return []
    c = 0.5 * (a + b)
    # mean-value exclusion
    gc = axis.g(flint.acb(0, c))
    if not (gc + d1 * (iv - flint.arb(c))).contains(0):  # g(w) = g(c) + g'(xi) (w - c)
        return []
    if b - a > _MIN_WIDTH * max(1.0, scale):
        for m in (c, a + 0.375 * (b - a), a + 0.625 * (b - a)):
            sm = _sign(axis.g(flint.acb(0, m)))
            if sm:
                return [(a, m, sa, sm), (m, b, sm, sb)]
    # second order: g'' of one sign
    d2 = axis.g2(s)
    sigma = _sign(d2)
    if sigma == 0 or not (sa and sb):
        raise CertificationError(
            f"proven crossing search: cannot decide whether |A(i w)|^2 - |B(i w)|^2 vanishes on "
            f"[{a:.17g}, {b:.17g}] (a zero of multiplicity three or more, or g flat at the ball radii); "
            "a higher working precision or a slight change of the loop would decide it"
        )
    ga1, gb1 = axis.g1(flint.acb(0, a)), axis.g1(flint.acb(0, b))
    if _sign(ga1) == _sign(gb1) != 0:
        if sa != sb:
            zeros.append((_newton(axis, a, b, sa, _sign(ga1), None, order=0), _sign(ga1)))
        return []
    if not (_sign(ga1) and _sign(gb1)):
        raise CertificationError(
            f"proven crossing search: the stationary point of g on [{a:.17g}, {b:.17g}] is an end to ball precision"
        )
    wstar = _newton(axis, a, b, _sign(ga1), sigma, d2, order=1)
    gstar = axis.g(flint.acb(0, wstar)) * sigma
    if gstar > 0:
        return []
    lo_s, hi_s = ball_lower(wstar), ball_upper(wstar)
    if gstar < 0:
        if sa == sigma:
            zeros.append((_newton(axis, a, lo_s, sa, -sigma, None, order=0), -sigma))
        if sb == sigma:
            zeros.append((_newton(axis, hi_s, b, -sigma, sigma, None, order=0), sigma))
        return []
    reach = (2 * gstar.abs_upper() / d2.abs_lower()).sqrt()
    unresolved.append((max(a, ball_lower(wstar - reach)), min(b, ball_upper(wstar + reach)), wstar))
    return []


def _newton(axis: _Axis, a: float, b: float, s_a: int, slope: int, d_iv: Any, order: int) -> Any:
    """Interval Newton on ``g`` (``order = 0``) or ``g'`` (``order = 1``) on ``[a, b]``: the enclosure of its zero.

    ``s_a`` is the proven sign of the function at ``a``, ``slope`` that of its derivative on
    ``[a, b]`` (``d_iv``: its enclosure there, recomputed when None).
    """
    flint = axis.flint
    f = axis.g if order == 0 else axis.g1
    df = axis.g1_on if order == 0 else (lambda iv: axis.g2(flint.acb(0, iv)))
    x = _interval(flint, a, b)
    rad_d = float(x.rad())
    for _ in range(_NEWTON_STEPS):
        if d_iv is None or float(x.rad()) < 1e-3 * rad_d:  # an enclosure of the derivative on x
            d_iv, rad_d = df(x), float(x.rad())
        if d_iv.contains(0):
            break
        m = x.mid()
        fm = f(flint.acb(0, m))
        new = m - fm / d_iv
        if not new.overlaps(x):
            raise CertificationError("proven crossing search: interval Newton left its interval (inconsistent balls)")
        new = new.intersection(x)
        done = float(new.rad()) <= _TIGHT * max(1.0, abs(float(new.mid()))) or float(new.rad()) >= float(x.rad())
        x = new
        if done:
            break
    return x


# ============================================================================ entry points
def proven_gap(A: QuasiPolynomial, B: QuasiPolynomial) -> tuple[float, float]:
    """Enclosure ``(lo, hi)`` of the principal gap ``|a_0| - sum |a_k|`` of the loop (ball arithmetic).

    ``(-inf, -inf)`` for an advanced-type loop (no first principal term dominates); ``(0.0, 0.0)`` when the
    gap is exactly zero (``|b_0| = |a_0|`` of real coefficients, say).
    """
    flint = require_flint()
    res = _proven_bound(flint, (A, B), 1.0)
    if res is None:
        return (-math.inf, -math.inf)
    if res[0].is_zero():
        return (0.0, 0.0)
    return ball_lower(res[0]), ball_upper(res[0])


def proven_zero_radius(F: QuasiPolynomial) -> float | None:
    """A radius ``R`` proven in ball arithmetic to hold every zero of ``F`` with ``Re s >= 0``, or None.

    ``R`` is the radius of :func:`~nrobust.bounds.root_free_region` (slightly enlarged if
    needed), at which the tail bound is proven below the principal gap as for the frequency
    bound. The nominal count of a loop needs it when the frequency bound of the loop is
    far larger (a principal gap of the loop near 0, e.g. ``|b_n / a_n| = 1 - 2^-52``).
    """
    try:
        R = root_free_region(F).radius
    except (ParameterError, CertificationError):
        return None
    flint = require_flint()
    for _ in range(8):
        res = _proven_bound(flint, (F,), R)
        if res is None:
            return None
        if res[1] < res[0]:
            return float(R)
        R *= 1.0 + 1e-3
    return None


def proven_zero_root(A: QuasiPolynomial, B: QuasiPolynomial) -> bool:
    """Whether ``A(0) + B(0) = 0`` (``s = 0`` a root for every delay), decided in ball arithmetic.

    Raises
    ------
    CertificationError
        When the enclosure of ``A(0) + B(0)`` contains 0 without being exactly 0.
    """
    flint = require_flint()
    value = ball_function(A)(flint.acb(0)) + ball_function(B)(flint.acb(0))
    if value.is_zero():
        return True
    if value.contains(0):
        raise CertificationError(
            f"delay_margin(rigorous=True): A(0) + B(0) = {value} is zero to the ball radius: whether s = 0 is a root "
            "for every delay is not decided"
        )
    return False


def proven_crossings(A: QuasiPolynomial, B: QuasiPolynomial, *, max_evals: int = 200_000) -> ProvenCrossings:
    """Every zero of ``|A(i w)|^2 - |B(i w)|^2`` with its first delay, proven in ball arithmetic.

    See the module notes for what is proven and how.

    Parameters
    ----------
    A, B : QuasiPolynomial
        The loop factors of ``F(s; delta) = A(s) + B(s) e^{-delta s}``.
    max_evals : int, optional
        Work bound on the ball evaluations.

    Returns
    -------
    ProvenCrossings

    Raises
    ------
    ImportError
        python-flint is not installed (``pip install nrobust[rigorous]``).
    ParameterError
        The difference operator of the loop is not strongly stable for small delays.
    CertificationError
        Something could not be proven: the frequency bound, the sign of ``g`` on a
        cluster, a delay's branch, or the work bound was hit.

    Examples
    --------
    >>> A = QuasiPolynomial([[1.0, 1.0]], [0.0])      # s + 1
    >>> B = QuasiPolynomial([[2.0]], [0.0])           # 2 e^{-delta s}
    >>> res = proven_crossings(A, B)
    >>> lo, hi = res.omegas[0]
    >>> bool(lo <= 3.0 ** 0.5 <= hi), res.method
    (True, 'exact polynomial')
    """
    for name, P in (("A", A), ("B", B)):
        if not isinstance(P, QuasiPolynomial):
            raise ParameterError(name, "a QuasiPolynomial", type(P).__name__)
    if is_zero(A) or is_zero(B):
        raise ParameterError("A, B", "both not identically zero", (A, B))
    max_evals = positive_int("max_evals", max_evals)
    flint = require_flint()
    W = _frequency_bound(A, B)
    proof = None
    for _ in range(8):
        proof = _proven_bound(flint, (A, B), W)
        if proof is not None and proof[1] < proof[0]:
            break
        W *= 1.0 + 1e-3
    if proof is None or not proof[1] < proof[0]:
        raise CertificationError(
            "proven crossing search: the frequency bound could not be proven (tail bound not below the principal "
            "gap in ball arithmetic)"
        )
    gap = proof[0]
    real = A.is_real and B.is_real
    hi = W * (1.0 + 1e-6)
    lo = 0.0 if real else -hi
    axis = _Axis(A, B, max_evals)
    exact = _exact_route(flint, A, B, real)
    zeros: list[tuple[Any, int, int]]
    unresolved: list[tuple[float, float, Any]] = []
    if exact is not None:
        zeros = [(w, m, sl) for w, m, sl in exact if ball_upper(abs(w)) < hi]
        method = "exact polynomial"
    else:
        found, unresolved = _ball_route(axis, lo, hi, A, B)
        zeros = [(w, 1, sl) for w, sl in found]
        method = "ball bisection"
    zeros.sort(key=lambda e: float(e[0].mid()))
    omegas, mults, slopes, delays = [], [], [], []
    for w, mult, slope in zeros:
        s = flint.acb(0, w)
        a, b = axis.fa(s), axis.fb(s)
        axis.spend(2)
        sign = 1 if w > 0 else -1
        delay = _first_delay(flint, a, b, w, sign)
        if delay is None:
            raise CertificationError(
                "proven crossing search: the first delay of the crossing at w in "
                f"[{ball_lower(w):.17g}, {ball_upper(w):.17g}] is not proven (a root on the imaginary axis at a delay "
                "near 0 modulo the period, or A(i w) near 0)"
            )
        omegas.append((ball_lower(w), ball_upper(w)))
        mults.append(mult)
        slopes.append(slope)
        delays.append(delay)
    un_delays = []
    for a_, b_, _ in unresolved:
        s = flint.acb(0, _interval(flint, a_, b_))
        a, b = axis.fa(s), axis.fb(s)
        axis.spend(2)
        wiv = _interval(flint, a_, b_)
        delay = _first_delay(flint, a, b, wiv, 1 if a_ > 0 else -1)
        un_delays.append((0.0, math.inf) if delay is None else delay)
    return ProvenCrossings(
        omegas=tuple(omegas),
        multiplicities=tuple(mults),
        slopes=tuple(slopes),
        delays=tuple(delays),
        unresolved=tuple((a_, b_) for a_, b_, _ in unresolved),
        unresolved_delays=tuple(un_delays),
        frequency_bound=float(W),
        gap=(ball_lower(gap), ball_upper(gap)),
        method=method,
        evaluations=axis.evals,
    )
