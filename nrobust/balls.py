"""Quasi-polynomials in ball arithmetic: rigorous enclosures of ``F``, ``F'``, ... on points and boxes.

Every value returned here is an ``acb`` of python-flint (FLINT's Arb): a complex
rectangle (a midpoint and a radius for the real and for the imaginary part) that
contains the exact value, every rounding error of the evaluation included. python-flint
is the optional extra ``nrobust[rigorous]``; it is imported on first use and its absence
is reported by :func:`require_flint` with the command that installs it (both from
:mod:`nrobust._flint`, re-exported here with :func:`working_precision`, :func:`acb_box`
and Krawczyk's test :func:`krawczyk`).

What is enclosed
----------------
``F`` *as represented* by :class:`~nrobust.quasipoly.QuasiPolynomial`: the stored
floating-point numbers are taken as exact rationals and nothing else is approximated.

* A point term ``p_k(s) e^{-tau_k s}``: the stored coefficients of ``p_k`` and the stored
  delay ``tau_k``; a coefficient with a radius (``QuasiPolynomial(..., radii=...)``, e.g. a
  plant's gain ``rho q e^{sigma_0 tau}`` rounded to a double) is the ball of that radius
  about it, so the enclosure holds for every function with coefficients in those balls
  (exact coefficients cost nothing more).
* A distributed term ``q(s) int nu^m N(nu) e^{-nu s} dnu``: ``N`` is the interpolant as
  stored per segment (``DistributedDelay.pieces``: the start ``nu_i``, the length ``h_i``
  and the coefficients ``P_il`` of ``N(nu_i + h_i t) = sum_l P_il t^l``, e.g. the cubic
  spline ``N~`` of the paper's eq. (40) on the kernel grid), so a segment
  contributes exactly

      ``h_i e^{-nu_i s} int_0^1 (nu_i + h_i t)^m P_i(t) e^{-s h_i t} dt
      = e^{-nu_i s} sum_l c_il phi_l(s h_i)``,  ``phi_l(z) = int_0^1 t^l e^{-z t} dt``,

  with ``c_il`` expanded in ball arithmetic (not rounded to floats). ``phi_l`` is
  enclosed by its Taylor series ``sum_n (-z)^n / (n! (n + l + 1))`` with a proven bound of
  the tail where ``|z|`` is small (the closed form cancels there), and by the recursion
  ``phi_0 = (1 - e^{-z}) / z``, ``phi_l = (l phi_{l-1} - e^{-z}) / z`` elsewhere (ball
  arithmetic accounts for its growth of errors). The chirp-z sums of the floating-point
  path are not used.
* Derivatives are those of this function, in ball arithmetic (Leibniz's rule: no
  coefficient of ``F.derivative()`` is rounded).
* A kernel stored with a proven error bound (``DistributedDelay.radius``: the true kernel,
  e.g. ``N~`` of a plant with constant coefficients in closed form, is within ``radius``
  of the stored pieces) widens each moment ``J_k(s)`` by
  ``radius int_a^b nu^k e^{-nu Re s} dnu``: the enclosure is then of the true ``F``.

Without such a bound (``N~`` from a kernel on a finite grid, a cubic spline) the enclosure
is of ``F`` as represented, and how far that is from the plant is a separate question,
answered by convergence studies.

Interface
---------
:func:`ball_function` compiles ``F`` once (cached); :func:`ball_eval`,
:func:`ball_eval_many` and :func:`ball_values` evaluate at points (``acb`` balls or
floats); :func:`enclose_box` and :func:`enclose_segment` enclose ``F`` (or a derivative)
on a whole rectangle or segment, directly or by the mean-value form
``F(c) + F'(B) (B - c)``. All of them accept ``prec`` (bits of the ball midpoints,
default 53) and restore python-flint's working precision on return
(:func:`working_precision` does the same for arithmetic done by the caller).
:func:`ball_abs_moment`, :func:`ball_variation_bound` and :func:`ball_second_order_variation`
bound the kernel of a distributed term, for root-free far fields. :func:`acb_to_disc` turns a ball into a
double midpoint and radius.

Cost: about 10 us per evaluation of a point term and 5 us per spline segment of a
distributed term (one exponential each, shared by the terms on the same nodes); the
exponentials are not chained, because a product of many rotations widens the
rectangles of ball arithmetic geometrically (the wrapping effect).
"""

from __future__ import annotations

import functools
import itertools
import math
from abc import ABC, abstractmethod
from collections.abc import Iterable, Sequence
from fractions import Fraction
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._flint import INSTALL_HINT as INSTALL_HINT
from ._flint import acb_box, ball_upper, krawczyk, precision, radius_acb, require_flint, working_precision
from ._validate import positive_int
from .errors import ParameterError
from .qpmatrix import QuasiPolynomialMatrix
from .quasipoly import DistributedDelay, QuasiPolynomial

__all__ = [
    "BallDeterminant",
    "BallFunction",
    "BallQuasiPolynomial",
    "DelayedSumBalls",
    "acb_box",
    "acb_to_disc",
    "ball_abs_moment",
    "ball_eval",
    "ball_eval_many",
    "ball_function",
    "ball_second_order_variation",
    "ball_values",
    "ball_variation_bound",
    "enclose_box",
    "enclose_segment",
    "krawczyk",
    "radius_acb",
    "require_flint",
    "working_precision",
]

# |z| at or below which phi_l(z) is summed as a Taylor series; _SERIES_TERMS terms leave a
# tail below 1/24! ~ 1.6e-24 there (the bound is added to the ball).
_SERIES_RADIUS = 1.0
_SERIES_TERMS = 24
# Largest derivative order (a guard against runaway Leibniz expansions).
_MAX_DERIVATIVE = 8
_EPS = 2.0**-52


def _as_acb(flint: ModuleType, s: Any) -> Any:
    if isinstance(s, flint.acb):
        return s
    if isinstance(s, flint.arb):
        return flint.acb(s)
    try:
        z = complex(s)
    except (TypeError, ValueError):
        raise ParameterError("s", "a complex number or a python-flint acb/arb ball", s) from None
    if not (math.isfinite(z.real) and math.isfinite(z.imag)):
        raise ParameterError("s", "finite", s)
    return flint.acb(z.real, z.imag)


def _falling(n: int, j: int) -> int:
    """``n (n - 1) ... (n - j + 1)``."""
    return math.perm(n, j) if n >= j else 0


class _Group:
    """Segments of one distributed term with one length (to 44 bits, :func:`_length_key`).

    ``phi_l(s h_i)`` is enclosed once, on the ball hull ``H`` of the lengths
    (``phi_l(s h_i)`` lies in ``Phi_l = phi_l(s H)``; when the lengths differ, the sum over
    the segments is enclosed about the midpoint of ``Phi_l`` with the radius weighted by
    ``sum |a_i|``, since the coefficients ``a_i`` may cancel); the exponentials ``e^{-nu_i s}`` are
    computed one by one (a product of many rotations would widen the rectangles of ball
    arithmetic geometrically: the wrapping effect) and shared by the terms on the same
    nodes, e.g. ``N~`` in ``A``, ``B`` and their derivatives.
    """

    def __init__(self, flint: ModuleType, start: NDArray, h: NDArray, idx: list[int]) -> None:
        self.idx = idx
        self.hull = _hull(flint, h[idx])
        self.hull_key = (float(np.min(h[idx])), float(np.max(h[idx])))
        self.key = np.asarray(start[idx], dtype=float).tobytes()
        self.neg_starts = [-flint.arb(float(start[i])) for i in idx]

    def exponentials(self, s: Any, cache: dict[Any, Any]) -> Any:
        """``e^{-nu_i s}`` for the segments of the group (cached per point ``s``)."""
        if self.key not in cache:
            cache[self.key] = [(s * v).exp() for v in self.neg_starts]
        return cache[self.key]


class _DistributedBalls:
    """One distributed term compiled for ball evaluation (see the module docstring)."""

    def __init__(self, flint: ModuleType, d: DistributedDelay) -> None:
        self.flint = flint
        self.d = d
        start, h, poly_t = d.pieces
        self.start = [flint.arb(float(v)) for v in start]
        groups: dict[float, list[int]] = {}
        for i, hv in enumerate(h):
            groups.setdefault(_length_key(float(hv)), []).append(i)
        self.groups = [_Group(flint, start, h, idx) for idx in groups.values()]
        self.h = h
        self.poly_t = poly_t
        self.q = [_to_acb(flint, c) for c in d.poly]
        # q and its derivatives (the last of degree 0), formed once at the working precision
        self.q_derivatives = [flint.acb_poly(self.q)]
        while self.q_derivatives[-1].degree() > 0:
            self.q_derivatives.append(self.q_derivatives[-1].derivative())
        self._coef: dict[int, list[Any]] = {}
        self._abs_coef: dict[int, list[Any]] = {}
        # radius_moment: radius (b - a) b^k per k, and the result per k and exact real part
        self._radius_scale: dict[int, Any] = {}
        self._radius_moments: dict[tuple[int, tuple[int, int]], Any] = {}

    def coefficients(self, k: int) -> list[Any]:
        """Per group, the ``acb_mat`` ``(n_g x L)`` of ``h_i (nu_i + h_i t)^k P_i(t)`` in powers of ``t``."""
        if k not in self._coef:
            flint = self.flint
            arb, acb = flint.arb, flint.acb
            width = k + self.poly_t.shape[1]
            mats = []
            for g in self.groups:
                rows: list[Any] = []
                for i in g.idx:
                    p = [_to_acb(flint, c) for c in self.poly_t[i]]
                    hi = arb(float(self.h[i]))
                    binom = [arb(math.comb(k, j)) * self.start[i] ** (k - j) * hi**j for j in range(k + 1)]
                    row = [acb(0)] * width
                    for j, w in enumerate(binom):
                        for l_, c in enumerate(p):
                            row[j + l_] += w * c
                    rows.extend(hi * c for c in row)
                mats.append(flint.acb_mat(len(g.idx), width, rows))
            self._coef[k] = mats
        return self._coef[k]

    def abs_coefficients(self, k: int) -> list[Any]:
        """Per group, the ``arb_mat`` of the moduli of :meth:`coefficients` (balls that contain them)."""
        if k not in self._abs_coef:
            flint = self.flint
            self._abs_coef[k] = [
                flint.arb_mat(m.nrows(), m.ncols(), [abs(m[i, j]) for i in range(m.nrows()) for j in range(m.ncols())])
                for m in self.coefficients(k)
            ]
        return self._abs_coef[k]

    def radius_moment(self, s: Any, k: int) -> Any:
        """Bound of ``radius int_a^b nu^k e^{-nu Re s} dnu`` over the ball ``s``: the error of ``J_k``.

        It depends on ``k`` and the lower end of ``Re s`` only: kept per both (contours and the
        axis evaluate many points with one real part).
        """
        flint = self.flint
        x = flint.arb(s.real.lower())
        key = (k, x.man_exp()) if x.is_finite() else None
        out = self._radius_moments.get(key) if key is not None else None
        if out is None:
            a, b = flint.arb(self.d.a), flint.arb(self.d.b)
            if k not in self._radius_scale:
                self._radius_scale[k] = flint.arb(self.d.radius) * (b - a) * b**k
            out = self._radius_scale[k] * _segment_exp_max(flint, a, b, x)
            if key is not None:
                self._radius_moments[key] = out
        return out

    def moment(self, s: Any, k: int, cache: dict[Any, Any], lmax: int, prec: int) -> Any:
        """``J_k(s) = int nu^k N(nu) e^{-nu s} dnu`` for the represented ``N``; ``cache`` is per point.

        Per group, ``sum_i sum_l a_il e^{-nu_i s} phi_l(s h_i)`` as products of FLINT ball
        matrices: the row of exponentials times the ``(n_g x L)`` coefficients times the
        column of ``phi_l`` (every product an enclosure of the exact sum).
        """
        flint = self.flint
        out = flint.acb(0)
        for g, mat, absmat in zip(self.groups, self.coefficients(k), self.abs_coefficients(k)):
            width = mat.ncols()
            phi_key = ("phi", g.hull_key, lmax)
            if phi_key not in cache:
                cache[phi_key] = _phi_balls(flint, s * g.hull, lmax, prec)
            phi = cache[phi_key]
            exps = g.exponentials(s, cache)
            row = flint.acb_mat(1, len(g.idx), exps) * mat
            if g.hull_key[0] == g.hull_key[1]:  # one length: sum_i a_i phi(s h) = (sum_i a_i) phi(s h)
                out += (row * flint.acb_mat(width, 1, phi[:width]))[0, 0]
                continue
            # Lengths that differ (in the last digits): phi_l(s h_i) are different points of the
            # ball Phi_l, so sum_i a_i phi_l(s h_i) lies in (sum_i a_i) mid(Phi_l) plus a disc of
            # radius sum_i |a_i| rad(Phi_l), not in (sum_i a_i) Phi_l when the a_i cancel.
            mids = [flint.acb(p.real.mid(), p.imag.mid()) for p in phi[:width]]
            spreads = flint.arb_mat(width, 1, [abs(p - m) for p, m in zip(phi[:width], mids)])
            moduli = flint.arb_mat(1, len(g.idx), [abs(e) for e in exps])
            out += (row * flint.acb_mat(width, 1, mids))[0, 0]
            out += _disc(flint, (moduli * absmat * spreads)[0, 0])
        return out


def _length_key(h: float) -> float:
    """``h`` rounded to 44 significant bits: segments of one grid (lengths within a few ulps) share a key."""
    mant, expo = math.frexp(h)
    return math.ldexp(round(mant * 2**44) / 2**44, expo)


def _disc(flint: ModuleType, r: Any) -> Any:
    """The ``acb`` square ``[-r, r] + i [-r, r]`` (``r`` an ``arb``; its upper end is used)."""
    u = flint.arb(0, r.upper())
    return flint.acb(u, u)


def _hull(flint: ModuleType, values: NDArray[np.float64]) -> Any:
    """The ``arb`` ball containing every one of the floats ``values``."""
    lo, hi = float(np.min(values)), float(np.max(values))
    return flint.arb(lo) if lo == hi else flint.arb(lo).union(flint.arb(hi))


def _to_acb(flint: ModuleType, c: Any) -> Any:
    z = complex(c)
    return flint.acb(z.real, z.imag) if z.imag else flint.acb(z.real)


@functools.lru_cache(maxsize=64)
def _series_poly(lmax: int, terms: int, prec: int) -> list[Any]:
    """``acb_poly`` of ``sum_{n<terms} (-z)^n / (n! (n + l + 1))`` for ``l = 0..lmax``."""
    flint = require_flint()
    with precision(flint, prec):
        out = []
        for l_ in range(lmax + 1):
            coefs = [flint.arb((-1) ** n) / (flint.arb.fac_ui(n) * (n + l_ + 1)) for n in range(terms)]
            out.append(flint.acb_poly(coefs))
        return out


def _phi_balls(flint: ModuleType, z: Any, lmax: int, prec: int) -> list[Any]:
    """Enclosures of ``phi_l(z)``, ``l = 0..lmax``, for a ball ``z``."""
    r = float(z.abs_upper())
    if r <= _SERIES_RADIUS or not float(z.abs_lower()) > 0.5:
        terms = _SERIES_TERMS
        if r > _SERIES_RADIUS:  # enough terms that r^n / n! has long peaked and decays fast
            terms = math.ceil(3.0 * r) + _SERIES_TERMS
        if not math.isfinite(r) or terms > 4096:
            return [flint.acb(flint.arb.nan(), flint.arb.nan())] * (lmax + 1)
        polys = _series_poly(lmax, terms, prec)

        def series(l_: int) -> Any:
            # tail: sum_{n >= N} r^n / (n! (n + l + 1)) <= r^N / (N! (N + l + 1)) (N + 1) / (N + 1 - r)
            tail = flint.arb(r) ** terms / flint.arb.fac_ui(terms) / (terms + l_ + 1)
            tail *= flint.arb(terms + 1) / (terms + 1 - flint.arb(r))
            t = ball_upper(tail)
            return polys[l_](z) + flint.acb(flint.arb(0, t), flint.arb(0, t))

        if r > 1.0:
            return [series(l_) for l_ in range(lmax + 1)]
        # |z| <= 1: phi_lmax by its series, then down by phi_{l-1} = (z phi_l + e^{-z}) / l
        # (integration by parts), which divides an error by l / |z| >= 1 at each step
        e = (-z).exp()
        out = [series(lmax)]
        for l_ in range(lmax, 0, -1):
            out.append((z * out[-1] + e) / l_)
        return out[::-1]
    e = (-z).exp()
    cur = (1 - e) / z
    out = [cur]
    for l_ in range(1, lmax + 1):
        cur = (l_ * cur - e) / z
        out.append(cur)
    return out


class BallFunction(ABC):
    """Public evaluation shared by the compiled functions: subclasses set ``flint`` and ``prec``
    and implement ``_eval`` (a characteristic function may compile itself into one: :func:`ball_function`)."""

    flint: ModuleType
    prec: int
    max_derivative: int = _MAX_DERIVATIVE

    @abstractmethod
    def _eval(self, s: Any, k: int) -> Any:
        """Enclosure of the ``k``-th derivative on the ``acb`` ball ``s`` (at the working precision)."""

    def _order(self, derivative: Any) -> int:
        if type(derivative) is int and 0 <= derivative <= self.max_derivative:  # the usual case, checked fast
            return derivative
        return positive_int("derivative", derivative, minimum=0, maximum=self.max_derivative)

    def __call__(self, s: Any, derivative: int = 0) -> Any:
        """Enclosure of ``F^{(derivative)}`` over the ball ``s`` (an ``acb``, ``arb`` or number)."""
        k = self._order(derivative)
        with precision(self.flint, self.prec):
            return self._eval(_as_acb(self.flint, s), k)

    def many(self, points: Iterable[Any], derivative: int = 0) -> list[Any]:
        """Enclosures at many balls or numbers (one Python loop of python-flint calls)."""
        k = self._order(derivative)
        flint = self.flint
        with precision(flint, self.prec):
            return [self._eval(_as_acb(flint, s), k) for s in points]

    def values(self, s: ArrayLike, derivative: int = 0) -> tuple[NDArray[np.complex128], NDArray[np.float64]]:
        """Midpoints and radii as numpy arrays: ``|F^{(derivative)}(s) - mid| <= rad`` at float points ``s``.

        The radius covers the ball's own radius and the rounding of its midpoint to a
        double (see :func:`acb_to_disc`).
        """
        arr = np.asarray(s, dtype=complex)
        if not np.all(np.isfinite(arr)):
            raise ParameterError("s", "finite complex numbers", s)
        balls = self.many(arr.ravel().tolist(), derivative)
        mid = np.empty(arr.size, dtype=complex)
        rad = np.empty(arr.size)
        for i, b in enumerate(balls):
            mid[i], rad[i] = acb_to_disc(b)
        return mid.reshape(arr.shape), rad.reshape(arr.shape)

    def on_box(self, box: Sequence[float], derivative: int = 0, *, centered: bool = False) -> Any:
        """Enclosure of ``F^{(derivative)}`` on the rectangle ``box = (x0, x1, y0, y1)``.

        ``centered=False`` evaluates on the box ball (one evaluation). ``centered=True``
        uses the mean-value form ``F(c) + F'(B) (B - c)`` (two evaluations), tighter when
        the box is small against the scale on which ``F'`` varies, e.g. near a root.
        """
        k = self._order(derivative)
        x0, x1, y0, y1 = (float(v) for v in box)
        if not (x0 <= x1 and y0 <= y1) or not all(map(math.isfinite, (x0, x1, y0, y1))):
            raise ParameterError("box", "finite (x0, x1, y0, y1) with x0 <= x1 and y0 <= y1", box)
        flint = self.flint
        with precision(flint, self.prec):
            ball = acb_box(x0, x1, y0, y1)
            if not centered:
                return self._eval(ball, k)
            c = flint.acb(ball.real.mid(), ball.imag.mid())
            return self._eval(c, k) + self._eval(ball, k + 1) * (ball - c)

    def on_segment(self, a: complex, b: complex, derivative: int = 0, *, centered: bool = False) -> Any:
        """Enclosure of ``F^{(derivative)}`` on the segment ``[a, b]`` (through its bounding box)."""
        a, b = complex(a), complex(b)
        box = (min(a.real, b.real), max(a.real, b.real), min(a.imag, b.imag), max(a.imag, b.imag))
        return self.on_box(box, derivative, centered=centered)


class BallQuasiPolynomial(BallFunction):
    """A :class:`QuasiPolynomial` compiled for evaluation in ball arithmetic.

    Parameters
    ----------
    F : QuasiPolynomial
    prec : int, optional
        Working precision in bits (default 53); higher precision shrinks the rounding
        part of the radii, not the part due to the width of an input box.

    Notes
    -----
    ``F^{(k)}(s) = sum_k P_{k}(s) e^{-tau s} + sum_d sum_j C(k, j) q^{(j)}(s) (-1)^{k-j} J_{m+k-j}(s)``
    with ``P_k = sum_j C(k, j) p^{(j)} (-tau)^{k-j}`` (Leibniz) formed once per order in
    ball arithmetic. Use :func:`ball_function` to share one compiled instance.
    """

    def __init__(self, F: QuasiPolynomial, prec: int = 53) -> None:
        if not isinstance(F, QuasiPolynomial):
            raise ParameterError("F", "a QuasiPolynomial", type(F).__name__)
        self.F = F
        self.prec = positive_int("prec", prec, minimum=16, maximum=4096)
        self.flint = require_flint()
        with precision(self.flint, self.prec):
            self._delays = [(self.flint.arb(-float(t)), float(t)) for _, t in F.point_terms]
            self._coefs = [
                [_to_acb(self.flint, c) for c in p]
                if not np.any(r)
                else [radius_acb(self.flint, c, rc) for c, rc in zip(p, r)]
                for (p, _), r in zip(F.point_terms, F.radii_of())
            ]
            self._dist = [_DistributedBalls(self.flint, d) for d in F.distributed]
        # highest l of phi_l(s h) at k = 0 (``lmax + k`` for the k-th derivative)
        self._lmax = max((d.moment + d.pieces[2].shape[1] - 1 for d in F.distributed), default=0)
        self._point_polys: dict[int, list[Any]] = {}

    # ------------------------------------------------------------------ compiled pieces
    def _polys(self, k: int) -> list[Any]:
        """``acb_poly`` of ``P_k = sum_j C(k, j) p^{(j)} (-tau)^{k-j}`` for every point term."""
        if k not in self._point_polys:
            flint = self.flint
            polys = []
            for coefs, (neg_tau, _) in zip(self._coefs, self._delays):
                out = [flint.acb(0)] * len(coefs)
                for j in range(k + 1):
                    w = math.comb(k, j) * neg_tau ** (k - j)
                    for i in range(len(coefs) - j):  # coefficient of s^i of p^{(j)}
                        out[i] += w * _falling(i + j, j) * coefs[i + j]
                polys.append(flint.acb_poly(out))
            self._point_polys[k] = polys
        return self._point_polys[k]

    def _eval(self, s: Any, k: int) -> Any:
        flint = self.flint
        out = flint.acb(0)
        for poly, (neg_tau, tau) in zip(self._polys(k), self._delays):
            term = poly(s)
            out += term * (s * neg_tau).exp() if tau else term
        if self._dist:
            out += self._eval_distributed(s, k)
        return out

    def _eval_distributed(self, s: Any, k: int) -> Any:
        flint = self.flint
        out = flint.acb(0)
        cache: dict[Any, Any] = {}  # exponentials and phi_l shared by the terms on the same nodes
        lmax = self._lmax + k
        for dist in self._dist:
            for j, qj in enumerate(dist.q_derivatives[: k + 1]):  # q^{(j)} = 0 beyond them
                if qj.degree() < 0:
                    continue
                sign = -1 if (k - j) % 2 else 1
                weight = math.comb(k, j) * qj(s)
                out += sign * weight * dist.moment(s, dist.d.moment + k - j, cache, lmax, self.prec)
                if dist.d.radius:
                    out += _disc(flint, abs(weight) * dist.radius_moment(s, dist.d.moment + k - j))
        return out


@functools.lru_cache(maxsize=64)
def _compositions(n: int, k: int) -> tuple[tuple[tuple[int, ...], int], ...]:
    """``(k_1, ..., k_n)`` with ``sum k_i = k`` and their multinomial weights ``k! / (k_1! ... k_n!)``."""
    return tuple(
        (ks, math.factorial(k) // math.prod(math.factorial(v) for v in ks))
        for ks in itertools.product(range(k + 1), repeat=n)
        if sum(ks) == k
    )


class BallDeterminant(BallFunction):
    """``det M`` of a :class:`~nrobust.qpmatrix.QuasiPolynomialMatrix` compiled for ball arithmetic.

    The entries are enclosed by :class:`BallQuasiPolynomial` (each as represented) and the
    determinant of the ``acb_mat`` of the enclosures is FLINT's (``acb_mat.det``, an
    enclosure of the determinant of every matrix in the ball matrix). Derivatives follow
    the generalised Jacobi formula
    ``(det M)^{(k)} = sum_{k_1 + ... + k_n = k} k! / (k_1! ... k_n!) det M^{(k_1, ..., k_n)}``,
    with row ``i`` of ``M^{(k_1, ..., k_n)}`` differentiated ``k_i`` times (for ``k = 1``:
    ``sum_i det M^{(i)}``). Orders up to 4 (``C(k + n - 1, n - 1)`` determinants each).

    Parameters
    ----------
    M : QuasiPolynomialMatrix
    prec : int, optional
        Working precision in bits.
    """

    max_derivative = 4

    def __init__(self, M: QuasiPolynomialMatrix, prec: int = 53) -> None:
        if not isinstance(M, QuasiPolynomialMatrix):
            raise ParameterError("M", "a QuasiPolynomialMatrix", type(M).__name__)
        self.M = M
        self.prec = positive_int("prec", prec, minimum=16, maximum=4096)
        self.flint = require_flint()
        self._entries = [[BallQuasiPolynomial(e, self.prec) for e in row] for row in M.entries]

    def _eval(self, s: Any, k: int) -> Any:
        flint = self.flint
        n = self.M.size
        rows: dict[tuple[int, int], list[Any]] = {}  # (row, order) -> enclosures of the row's entries
        out = flint.acb(0)
        for ks, weight in _compositions(n, k):
            entries: list[Any] = []
            for i, ki in enumerate(ks):
                if (i, ki) not in rows:
                    rows[(i, ki)] = [e._eval(s, ki) for e in self._entries[i]]
                entries.extend(rows[(i, ki)])
            out += weight * flint.acb_mat(n, n, entries).det()
        return out


def acb_to_disc(ball: Any) -> tuple[complex, float]:
    """``(mid, rad)`` in doubles with every point of the ``acb`` rectangle in the disc ``|z - mid| <= rad``.

    The midpoint is rounded to doubles (error at most ``2^-53`` of each part, added to the
    radius) and the radius is rounded upwards; a non-finite ball gives ``rad = inf``.
    """
    re, im = ball.real, ball.imag
    mre, mim = float(re.mid()), float(im.mid())
    rre, rim = float(re.rad()), float(im.rad())
    if not all(map(math.isfinite, (mre, mim, rre, rim))):
        return complex(mre if math.isfinite(mre) else 0.0, mim if math.isfinite(mim) else 0.0), math.inf
    # |error| <= (rre + |mre| eps) + (rim + |mim| eps) >= hypot; the sum rounded up by 4 eps
    rad = (rre + rim + (abs(mre) + abs(mim)) * _EPS) * (1.0 + 4 * _EPS) + 5e-324
    return complex(mre, mim), rad


class DelayedSumBalls(BallFunction):
    """Enclosure of ``F(s) = A(r s) + B(r s) e^{-delta s}``, ``delta`` exact, for every ``r`` in a ball.

    ``A + B.shift(delta)`` holds each point delay ``t + delta`` of ``B`` as the nearest double
    (:meth:`~nrobust.quasipoly.QuasiPolynomial.shift_is_exact`); the product form keeps ``delta`` as given.
    ``r`` (a rational, enclosed in an ``arb`` ball at the working precision; 1 by default) scales ``s`` in the
    factors: a loop built with a rounded time scale ``tau_d`` is the loop of the exact ``tau = r tau_d`` at ``r s``.

    Parameters
    ----------
    A, B : QuasiPolynomial
        The factors (``B`` None: ``F = A(r s)``, e.g. a loop at ``delta = 0`` whose kernels on equal nodes
        cancel exactly in ``A + B``).
    delta : float
        The delay, ``>= 0`` (a double, exact).
    r : Fraction, optional
        The scale of ``s`` in the factors (default 1).
    prec : int, optional
        Working precision in bits.

    Notes
    -----
    ``d^k/ds^k F = r^k A^{(k)}(r s) + e^{-delta s} sum_j C(k, j) r^j B^{(j)}(r s) (-delta)^{k-j}``
    (Leibniz), each factor enclosed on the ball ``r s``.
    """

    def __init__(
        self,
        A: QuasiPolynomial,
        B: QuasiPolynomial | None,
        delta: float,
        r: Fraction = Fraction(1),
        prec: int = 53,
    ) -> None:
        self.flint = require_flint()
        self.prec = prec
        self._a = ball_function(A, prec)
        self._b = None if B is None else ball_function(B, prec)
        self.max_derivative = min(f.max_derivative for f in (self._a, self._b) if f is not None)
        with precision(self.flint, prec):
            self._r = self.flint.arb(r.numerator) / self.flint.arb(r.denominator)
        self._delta = self.flint.arb(float(delta))  # exact

    def _eval(self, s: Any, k: int) -> Any:
        r, delta = self._r, self._delta
        x = r * s
        out = r**k * self._a(x, k)
        if self._b is None:
            return out
        terms = self.flint.acb(0)
        for j in range(k + 1):
            terms += math.comb(k, j) * r**j * self._b(x, j) * (-delta) ** (k - j)
        return out + (-delta * s).exp() * terms


@functools.lru_cache(maxsize=32)
def ball_function(F: Any, prec: int = 53) -> BallFunction:
    """The compiled :class:`BallQuasiPolynomial` of ``F``, or :class:`BallDeterminant` of a matrix
    (cached on ``F`` and ``prec``).

    Another characteristic function that encloses itself (a method ``F.ball_function(prec)``
    returning a :class:`BallFunction`, e.g. the closed loop of an ``n + m`` system) is compiled
    by that method.
    """
    if isinstance(F, QuasiPolynomialMatrix):
        return BallDeterminant(F, prec)
    own = None if isinstance(F, QuasiPolynomial) else getattr(F, "ball_function", None)
    if callable(own):
        balls = own(prec)
        if not isinstance(balls, BallFunction):
            raise ParameterError("F.ball_function(prec)", "a BallFunction", type(balls).__name__)
        return balls
    return BallQuasiPolynomial(F, prec)


def ball_eval(F: QuasiPolynomial | QuasiPolynomialMatrix, s: Any, *, derivative: int = 0, prec: int = 53) -> Any:
    """Enclosure of ``F(s)`` (or ``F^{(derivative)}(s)``) for a ball or number ``s``.

    Parameters
    ----------
    F : QuasiPolynomial or QuasiPolynomialMatrix
        A matrix stands for its determinant (:class:`BallDeterminant`).
    s : acb, arb or complex
        A point or a complex ball; for a ball the result contains ``F`` of every point.
    derivative : int, optional
        Order of the derivative (0 to 8).
    prec : int, optional
        Working precision in bits.

    Returns
    -------
    flint.acb

    Examples
    --------
    >>> from nrobust import QuasiPolynomial
    >>> F = QuasiPolynomial([[1], [-0.85], [0.1]], [0, 2, 2.1])
    >>> ball_eval(F, 0.0).contains(0.25)
    True
    """
    return ball_function(F, prec)(s, derivative)


def ball_eval_many(
    F: QuasiPolynomial | QuasiPolynomialMatrix, points: Iterable[Any], *, derivative: int = 0, prec: int = 53
) -> list[Any]:
    """Enclosures of ``F^{(derivative)}`` at many balls or numbers (a list of ``acb``)."""
    return ball_function(F, prec).many(points, derivative)


def ball_values(
    F: QuasiPolynomial | QuasiPolynomialMatrix, s: ArrayLike, *, derivative: int = 0, prec: int = 53
) -> tuple[NDArray[np.complex128], NDArray[np.float64]]:
    """Midpoints and radii (numpy arrays) with ``|F^{(derivative)}(s) - mid| <= rad`` at float points ``s``."""
    return ball_function(F, prec).values(s, derivative)


def enclose_box(
    F: QuasiPolynomial | QuasiPolynomialMatrix,
    box: Sequence[float],
    *,
    derivative: int = 0,
    centered: bool = False,
    prec: int = 53,
) -> Any:
    """Enclosure of ``F^{(derivative)}`` on the rectangle ``box = (x0, x1, y0, y1)``.

    See :meth:`BallQuasiPolynomial.on_box`; ``abs_upper()`` of the enclosure of ``F'``
    is a proven bound of ``|F'|`` on the box.
    """
    return ball_function(F, prec).on_box(box, derivative, centered=centered)


def enclose_segment(
    F: QuasiPolynomial | QuasiPolynomialMatrix,
    a: complex,
    b: complex,
    *,
    derivative: int = 0,
    centered: bool = False,
    prec: int = 53,
) -> Any:
    """Enclosure of ``F^{(derivative)}`` on the segment ``[a, b]`` (see :meth:`BallQuasiPolynomial.on_box`)."""
    return ball_function(F, prec).on_segment(a, b, derivative, centered=centered)


# ---------------------------------------------------------------------------- bounds of |N|
def _segment_exp_max(flint: ModuleType, lo: Any, hi: Any, x: Any) -> Any:
    """``max e^{-nu x}`` over ``nu in [lo, hi]`` (an ``arb`` upper bound)."""
    return flint.arb.max((-lo * x).exp(), (-hi * x).exp())


def ball_abs_moment(d: DistributedDelay, x: float, k: int = 0, *, prec: int = 53) -> Any:
    """An ``arb`` whose upper end bounds ``int nu^(m+k) |N(nu)| e^{-nu x} dnu`` (``N`` as represented).

    On segment ``i`` (start ``nu_i``, length ``h_i``, ``N = sum_l P_il t^l``):
    ``|N| <= sum_l |P_il|`` and ``nu^(m+k) e^{-nu x}`` is at most the product of the maxima
    of its two factors at the segment's ends (each is monotone), times ``h_i``. A kernel
    known to within ``radius`` (:class:`~nrobust.quasipoly.DistributedDelay`) adds
    ``radius (b - a) b^(m+k) max e^{-nu x}``: the bound holds for the true kernel.
    """
    flint = require_flint()
    k = positive_int("k", k, minimum=0)
    with precision(flint, prec):
        X = flint.arb(float(x))
        start, h, poly_t = d.pieces
        power = d.moment + k
        out = flint.arb(0)
        for s0, hv, p in zip(start, h, poly_t):
            lo, hi = flint.arb(float(s0)), flint.arb(float(s0)) + flint.arb(float(hv))
            bound = sum((abs(_to_acb(flint, c)) for c in p), flint.arb(0))
            weight = hi**power if power else flint.arb(1)
            out += flint.arb(float(hv)) * bound * weight * _segment_exp_max(flint, lo, hi, X)
        if d.radius:
            a, b = flint.arb(d.a), flint.arb(d.b)
            out += flint.arb(d.radius) * (b - a) * b**power * _segment_exp_max(flint, a, b, X)
        return out


def ball_variation_bound(d: DistributedDelay, x: float, *, prec: int = 53) -> Any:
    """An ``arb`` bound ``V`` with ``|int N(nu) e^{-nu s} dnu| <= V / |s|`` for ``Re s >= x`` (moment 0).

    Integration by parts on each segment of ``N`` as represented: the end values
    ``|P_i(0)| e^{-nu_i x}``, ``|P_i(1)| e^{-(nu_i + h_i) x}`` (at a node shared exactly by two
    segments, the jump ``|P_{i+1}(0) - P_i(1)|`` instead of both) and
    ``int |N'| e^{-nu x} <= sum_l l |P_il| max e^{-nu x}`` on the segment. Every term
    decreases as ``x`` grows, so ``V`` holds on the whole half-plane. The error bounds of
    a kernel known to within ``radius`` add ``(2 radius + variation_radius) max e^{-nu x}``.
    """
    if d.moment != 0:
        raise ParameterError("moment", "0 for ball_variation_bound", d.moment)
    flint = require_flint()
    with precision(flint, prec):
        X = flint.arb(float(x))
        start, h, poly_t = d.pieces
        out = flint.arb(0)
        carry = None  # value at the right end of the previous segment, if that end is shared
        for i, (s0, hv, p) in enumerate(zip(start, h, poly_t)):
            coefs = [_to_acb(flint, c) for c in p]
            lo, hi = flint.arb(float(s0)), flint.arb(float(s0)) + flint.arb(float(hv))
            left = coefs[0]
            right = sum(coefs, flint.acb(0))
            if carry is not None:
                out += abs(left - carry) * (-lo * X).exp()
            else:
                out += abs(left) * (-lo * X).exp()
            shared = i + 1 < start.size and Fraction(float(s0)) + Fraction(float(hv)) == Fraction(float(start[i + 1]))
            if shared:
                carry = right
            else:
                out += abs(right) * (-hi * X).exp()
                carry = None
            slope = sum((j * abs(c) for j, c in enumerate(coefs)), flint.arb(0))
            out += slope * _segment_exp_max(flint, lo, hi, X)
        if d.radius or d.variation_radius:
            a, b = flint.arb(d.a), flint.arb(d.b)
            err = 2 * flint.arb(d.radius) + flint.arb(d.variation_radius)
            out += err * _segment_exp_max(flint, a, b, X)
        return out


@functools.cache
def _powers_in_chebyshev(size: int) -> tuple[tuple[Fraction, ...], ...]:
    """``M[k][l]``, exactly: the coefficient of ``T_k(x)`` in ``((1 + x) / 2)^l``, ``k, l < size``
    (``x T_0 = T_1``, ``x T_k = (T_(k+1) + T_(k-1)) / 2``)."""
    columns = [[Fraction(1)] + [Fraction(0)] * (size - 1)]
    for _ in range(1, size):
        c = columns[-1]
        x_c = [Fraction(0)] * (size + 1)
        for k, v in enumerate(c):
            if k == 0:
                x_c[1] += v
            else:
                x_c[k + 1] += v / 2
                x_c[k - 1] += v / 2
        columns.append([(c[k] + x_c[k]) / 2 for k in range(size)])
    return tuple(tuple(columns[col][k] for col in range(size)) for k in range(size))


def _ball_bend(flint: ModuleType, coefs: list[Any]) -> Any:
    """An ``arb`` bound of ``int_0^1 |P''(t)| dt`` for ``P = sum_l c_l t^l`` (``acb`` coefficients): the lesser of
    ``sum_l l |c_l|`` and the moduli of the Chebyshev coefficients of ``P''`` on ``[0, 1]`` summed (``|T_k| <= 1``),
    the coefficients of ``t^j = ((1 + x) / 2)^j`` exact rationals."""
    if len(coefs) < 3:
        return flint.arb(0)
    powers = sum((j * abs(c) for j, c in enumerate(coefs) if j >= 2), flint.arb(0))
    second = [c * (j * (j - 1)) for j, c in enumerate(coefs) if j >= 2]
    table = _powers_in_chebyshev(len(second))
    cheb = flint.arb(0)
    for row in table:
        b = flint.acb(0)
        for c, m in zip(second, row):
            if m:
                b += c * (flint.arb(m.numerator) / m.denominator)
        cheb += abs(b)
    return powers.min(cheb)


def ball_second_order_variation(d: DistributedDelay, *, prec: int = 53) -> tuple[Any, Any]:
    """``arb`` bounds ``(V_1, V_2)`` with ``|int N(nu) e^{-nu s} dnu| <= V_1 / |s| + V_2 / |s|^2`` on ``Re s >= 0``
    (moment 0).

    :meth:`~nrobust.distributed_delay.DistributedDelay.second_order_variation` in ball arithmetic, for ``N`` as
    represented: integration by parts twice on each segment (``N(nu_i + h_i t) = P_i(t)``, every
    ``|e^{-nu s}| <= 1``). ``V_1`` sums the end values ``|P_i(0)|`` and ``|P_i(1)|`` (at a node shared exactly by
    two segments the jump ``|P_{i+1}(0) - P_i(1)|`` instead of both), ``V_2`` the same for ``N'``
    (``P_i'(0) / h_i``, ``P_i'(1) / h_i``) and ``int |N''| = int_0^1 |P_i''| / h_i``, bounded by the lesser of
    ``sum_l l |P_il|`` and the moduli of the Chebyshev coefficients of ``P_i''`` summed, over ``h_i``. The error
    bounds of a kernel known to within ``radius`` are integrated by parts once: ``2 radius + variation_radius``
    joins ``V_1``.
    """
    if d.moment != 0:
        raise ParameterError("moment", "0 for ball_second_order_variation", d.moment)
    flint = require_flint()
    with precision(flint, prec):
        start, h, poly_t = d.pieces
        v1, v2 = flint.arb(0), flint.arb(0)
        carry: tuple[Any, Any] | None = None  # value and slope at the right end of the previous segment, if shared
        for i, (s0, hv, p) in enumerate(zip(start, h, poly_t)):
            coefs = [_to_acb(flint, c) for c in p]
            step = flint.arb(float(hv))
            left = coefs[0]
            right = sum(coefs, flint.acb(0))
            slope_left = coefs[1] / step if len(coefs) > 1 else flint.acb(0)
            slope_right = sum((j * c for j, c in enumerate(coefs)), flint.acb(0)) / step
            if carry is None:
                v1 += abs(left)
                v2 += abs(slope_left)
            else:
                v1 += abs(left - carry[0])
                v2 += abs(slope_left - carry[1])
            shared = i + 1 < start.size and Fraction(float(s0)) + Fraction(float(hv)) == Fraction(float(start[i + 1]))
            if shared:
                carry = (right, slope_right)
            else:
                v1 += abs(right)
                v2 += abs(slope_right)
                carry = None
            v2 += _ball_bend(flint, coefs) / step
        if d.radius or d.variation_radius:
            v1 += 2 * flint.arb(d.radius) + flint.arb(d.variation_radius)
        return v1, v2
