"""Crossing frequencies of ``F(s; delta) = A(s) + B(s) e^{-delta s}``: a complete, certified search.

Roots of a loop with a delay ``delta`` reach the imaginary axis at ``s = i w`` only where
``|A(i w)| = |B(i w)|``; at such a *crossing frequency* the delays that put a root on the
axis are ::

    delta_{c,k} = (arg(-B(i w)/A(i w)) mod 2 pi + 2 pi k) / w,   k = 0, 1, ...

(from ``e^{-i w delta} = -A/B``). A root crosses from left to right (destabilising) or
back (stabilising) according to the sign of ``Re ds/ddelta``. By implicit
differentiation of ``F(s(delta); delta) = 0``, with ``g(w) = |A(i w)|^2 - |B(i w)|^2``, ::

    ds/ddelta = s B(s) e^{-delta s} / F'(s),
    Re (ds/ddelta)^{-1} = Re[-(A'/A - B'/B)/s] = g'(w) / (2 |A(i w)|^2 w),

so the direction is ``sign(g'(w)) sign(w)``, independent of ``k`` (Cooke and van den
Driessche); it is read from the certified sign of ``g'`` on the crossing's bracket.

Zeros of ``g`` come in three kinds: simple crossings (``g`` changes sign), tangencies
(double zeros: a pair of crossings being born or dying as a parameter moves; a root
touches the axis at one delay and turns back) and near-tangencies, which are not zeros.
The search locates the first two by their equations and proves the third away from zero.

**Frequency bound** (paper, proofs of Lemma 1 and Theorem 3). Write each factor as
``P(s) = s^n D_P(s) + R_P(s)`` with ``D_P`` its principal part, let ``a_0 e^{-t_0 s}`` be
the first principal term of ``A`` and ``B e^{-delta s}`` (``delta -> 0+``) and
``gap = |a_0| - sum |a_k|`` over the other principal terms (positive iff the difference
operator of ``F(.; delta)`` is strongly stable for small delays). On the axis every
``|e^{-tau s}| = 1``: if ``a_0`` belongs to ``A``, ``|D_A(i w)| - |D_B(i w)| >= gap``
(otherwise ``|D_B| - |D_A| >= gap``), and :class:`nrobust.bounds.TailBound` gives
``|R_P(i w)| <= |w|^n r_P(|w|)`` with ``r_P`` non-increasing (lower powers decay like
``|w|^(j-n)``, kernels like ``V/|w|`` by integration by parts). Hence ::

    | |A(i w)| - |B(i w)| | >= |w|^n (gap - r_A(|w|) - r_B(|w|)).

``W`` is, to ``1e-7``, the smallest radius (rounded up) where the computed ``r_A + r_B``
is below ``gap (1 - 1e-9) - 8 eps sum |a_k|``, the room covering the rounding of those
sums, so ``r_A(W) + r_B(W) < gap``: the right side is positive for ``|w| >= W`` and
every crossing has ``|w| < W`` (the same estimate on ``Re s >= 0``, normalised by
``e^{t_0 s}``, puts every zero of ``F(.; delta)`` with ``Re s >= 0`` in ``|s| < W`` when
``A`` dominates). The bound is sharp: ``s^2 + 1`` against ``s`` crosses at
``w = (1 + sqrt 5)/2``, the root of ``r_A + r_B = gap``. The search therefore runs over
``[0, W (1 + 1e-6) + 1e-9]`` (symmetric for complex coefficients): a crossing at ``W`` to
rounding is an interior zero with a clear sign change, and nothing beyond ``W`` can be a
crossing.

**First-order exclusion.** ``h(w) = |A(i w)| - |B(i w)|`` has ``|h'| <= |A'| + |B'|``,
bounded on 64 blocks by ``L``: point terms by :meth:`QuasiPolynomial.deriv_bound`, a
kernel term ``c q(s) J_m(s)``, ``J_k = int nu^k N e^{-nu s} dnu``, by
``|c| (max|q'| min(M_m, V_m/|w|) + max|q| min(M_{m+1}, V_{m+1}/|w|))`` with
``M_k = int nu^k |N|`` and, for ``m = 0``, the total variations ``V_0`` of ``N`` and
``V_1 <= M_0 + b V_0`` of ``nu N`` (integration by parts, ``0 <= nu <= b``). Kernels
shared by ``A`` and ``B`` up to a constant (``+I_N`` and ``-I_N`` in the paper's loops)
are summed once per frequency. The computed values ``h~`` are accurate to
``E = 2^16 eps S``, ``S`` the sum of the moduli of the terms (the chirp-z sums err by up
to about ``1e4 eps S``), and ``|h~(w_i)| + |h~(w_{i+1})| - E_i - E_{i+1} > L (w_{i+1} - w_i)``
proves that ``h`` has no zero on ``[w_i, w_{i+1}]`` and fixes its sign there. The grid
starts at ``pi / (8 tau_max)``; the work bound ``max_evals`` is checked against its size
before it is allocated, and each refinement is sized by what the bound leaves. It is
refined uniformly (chirp-z evaluation) until 99 % of the segments pass, then clusters of
unresolved segments are cut eightfold per round until at most 32 clusters of at most 128
segments remain (one chunk of direct evaluations for the next stage) or the segments are
narrower than ``1e-7 W``.

**Second-order resolution.** Each remaining cluster ``I`` (centre ``c``, radius ``r``)
is decided on the smooth ``g``. With ``a_k = A^{(k)}(i w)`` (derivatives in ``s``) and
``b_k`` likewise, ::

    g'   = -2 Im(conj(a_0) a_1) + 2 Im(conj(b_0) b_1),
    g''  = 2 (|a_1|^2 - Re(conj(a_0) a_2)) - 2 (|b_1|^2 - Re(conj(b_0) b_2)),
    |g'''| <= 2 sum_P (3 |P'| |P''| + |P| |P'''|),

so with ``D_k >= sup_I |P^{(k)}(i w)|`` (the sum of the moduli of the terms of
``P^{(k)}`` at ``max_I |w|``, and ``D_0 = |P(i c)| + r D_1``),
``|g''| <= M_2 = 2 sum_P (D_1^2 + D_0 D_2)`` and ``|g'''| <= M_3 = 2 sum_P (3 D_1 D_2 + D_0 D_3)``
on ``I``. Values carry rounding levels ``e_0, e_1, e_2`` propagated from ``64 eps`` times
the sums of the moduli of the terms (direct sums, never chirp-z). By Taylor's theorem:

* ``|g(c)| - e_0 - (|g'(c)| + e_1) r - M_2 r^2 / 2 > 0``: no zero in ``I``;
* ``|g'(c)| - e_1 - M_2 r > 0``: ``g`` is monotone on ``I`` and has one simple zero iff
  the certified signs at the ends differ;
* ``|g''(c)| - e_2 - M_3 r > 0``: ``sigma g`` is convex (``sigma = sign g''``), so ``g``
  has at most two zeros. Newton's method on ``g'`` gives ``w*`` and, the tangent line
  lying below a convex function, ``sigma g(w) >= sigma g(w*) - |g'(w*)| |w - w*|`` on
  ``I``. If that bound is positive, ``g`` has no zero (a near-tangency, proven away from
  zero); if ``sigma g(w*) < 0`` beyond rounding, each end of ``I`` where ``sigma g > 0``
  brackets one simple crossing; otherwise ``g(w*)`` and ``g'(w*)`` vanish to rounding:
  a *tangency* (double zero), located to about ``1e-12`` and reported with
  ``tangential=True`` and direction 0;
* otherwise ``I`` is bisected (at a point where the sign of ``g`` is certain). A cluster
  still undecided after 60 rounds (a zero of multiplicity three or more, or ``g`` flat at
  the rounding level) raises :class:`~nrobust.errors.CertificationError`: the search
  never guesses.

Sign-change brackets are refined by a safeguarded secant method on ``h`` to ``1e-12``,
steered by the certified end signs (a value at rounding level is a zero located to
rounding). :class:`AxisGap` exposes ``g``, its derivatives, their bounds and rounding
levels to other solvers (e.g. the pair-birth equations ``g = g' = 0`` of a gain study).
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from math import comb
from typing import Any

import numpy as np
from numpy.polynomial import polynomial as npoly
from numpy.typing import ArrayLike, NDArray

from .._json import fields_dict
from .._validate import positive_int
from ..bounds import TailBound, joint_degree, principal_gap
from ..errors import CertificationError, ConvergenceError, ParameterError
from ..quasipoly import DistributedDelay, QuasiPolynomial

__all__ = ["AxisGap", "AxisJet", "Crossing", "CrossingSearch", "crossing_frequencies", "frequency_bound"]

_EPS = float(np.finfo(float).eps)
# Blocks of the frequency range, each with its own bound of |A'| + |B'|.
_LIPSCHITZ_BLOCKS = 64
# Unresolved segments are cut down to this width relative to max(1, W) before the
# second-order resolution takes their clusters over.
_MIN_WIDTH = 1e-7
# Uniform refinements (at most _UNIFORM_PASSES) divide the grid by the factor that lets
# this quantile of its segments pass the exclusion test, up to _UNIFORM_MAX segments per
# Lipschitz block.
_UNIFORM_QUANTILE = 0.99
_UNIFORM_PASSES = 3
_UNIFORM_MAX = 1024
# Each unresolved segment is cut into at least this many pieces per round, and a cluster
# of contiguous segments into at least _LINE_POINTS (the evaluator sums the kernels as a
# chirp-z transform on uniform lines of 64 points or more).
_SPLIT = 8
_LINE_POINTS = 64
# Work bound of the bracket refinement.
_MAX_REFINE = 200
# Tolerance on the crossing frequency (absolute, times max(1, w)).
_XTOL = 1e-12
# Relative tolerance under which a crossing delay counts as delta = 0, and under which
# A(0) + B(0) counts as zero.
ZERO_TOL = 1e-12
# Largest number of crossing delays enumerated up to delta_max.
_MAX_EVENTS = 100_000
# Rounding of h on the search grid relative to the sum of the moduli of the terms (the
# chirp-z kernel sums err by up to about 1e4 eps).
_GRID_ROUNDING = 2.0**16 * _EPS
# Rounding of a direct evaluation of A^(k)(i w) relative to the sum of the moduli of its terms.
_POINT_ROUNDING = 64 * _EPS
# Direct evaluations run on chunks of fewer points than the evaluator's chirp-z threshold.
_DIRECT_CHUNK = 32
# Room left below the principal gap for the rounding of the tail sums (relative, and
# in units of eps times the sum of the moduli of the principal coefficients).
_GAP_ROOM_REL, _GAP_ROOM_EPS = 1e-9, 8.0
# The search range extends past W by this much (relative, absolute).
_EXTEND_REL, _EXTEND_ABS = 1e-6, 1e-9
# The first-order refinement hands its clusters to the second-order resolution once there
# are at most this many (one chunk of direct evaluations) made of at most 4 times as many
# segments (long clusters are cut faster on chirp-z lines).
_HANDOVER = 32
# Rounds of the second-order resolution, and Newton steps per convex cluster.
_RESOLVE_ROUNDS = 60
_NEWTON_STEPS = 40


# ============================================================================ results
@dataclass(frozen=True)
class Crossing:
    """A frequency ``w`` with ``|A(i w)| = |B(i w)|`` and the delays that put ``i w`` on a root.

    Attributes
    ----------
    omega : float
        Crossing frequency ``w`` (negative only for complex coefficients).
    delays : tuple of float
        ``delta_{c,k}``, ``k = 0, 1, ...``, up to the requested ``delta_max`` (at least the
        first one).
    direction : int
        ``+1`` destabilising (roots move into ``Re s > 0`` as delta grows), ``-1``
        stabilising, ``0`` tangential (the root touches the axis and turns back).
    ds_ddelta : complex
        ``ds/ddelta`` at ``s = i w``, ``delta = delays[0]``.
    tangential : bool
        True when ``|A|^2 - |B|^2`` has a double zero at ``w`` (to rounding): a tangency.
    """

    omega: float
    delays: tuple[float, ...]
    direction: int
    ds_ddelta: complex
    tangential: bool

    @property
    def period(self) -> float:
        """Spacing ``2 pi / |w|`` of the delay sequence."""
        return float(2.0 * np.pi / abs(self.omega))

    def __repr__(self) -> str:
        kind = {1: "destabilising", -1: "stabilising", 0: "tangential"}[self.direction]
        return f"Crossing(omega={self.omega:.10g}, delta_0={self.delays[0]:.10g}, period={self.period:.6g}, {kind})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (``ds_ddelta`` as ``[real, imag]``)."""
        return fields_dict(self)


@dataclass(frozen=True, eq=False)
class CrossingSearch:
    """All zeros of ``|A(i w)| - |B(i w)|`` with ``|w| <= W`` and how they were certified.

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    omegas : ndarray
        Crossing frequencies, increasing.
    tangential : ndarray of bool
        Which of them are tangencies (double zeros of ``|A|^2 - |B|^2``).
    frequency_bound : float
        ``W``: no crossing for ``|w| >= W`` (and no zero of ``F(.; delta)`` with
        ``Re s >= 0``, ``|s| >= W``, for any delta, when ``A`` dominates).
    gap : float
        Dominance of the first principal term, ``|a_0| - sum |others|``.
    evaluations : int
        Evaluations of ``A`` and ``B`` (and their derivatives) on the axis.
    slopes : ndarray of int
        Certified sign of ``d/dw (|A(i w)|^2 - |B(i w)|^2)`` at each crossing (0 at
        tangencies); the direction of a crossing is ``slope * sign(omega)``.
    """

    omegas: NDArray[np.float64]
    tangential: NDArray[np.bool_]
    frequency_bound: float
    gap: float
    evaluations: int
    slopes: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))


@dataclass(frozen=True, eq=False)
class AxisJet:
    """``g = |A(i w)|^2 - |B(i w)|^2`` and its first two ``w``-derivatives at some frequencies.

    Every value is an array over the frequencies; ``err``, ``derr``, ``d2err`` bound the
    rounding errors of ``g``, ``dg``, ``d2g`` (propagated from ``64 eps`` times the sum
    of the moduli of the terms of each factor). ``moduli`` holds ``|A^{(k)}(i w)|`` and
    ``|B^{(k)}(i w)|`` (``k = 0, 1, 2``, shape ``(2, 3, n)``) and ``rounding`` their
    rounding errors, for the bounds of :meth:`AxisGap.bounds`.
    """

    omega: NDArray[np.float64]
    g: NDArray[np.float64]
    dg: NDArray[np.float64]
    d2g: NDArray[np.float64]
    err: NDArray[np.float64]
    derr: NDArray[np.float64]
    d2err: NDArray[np.float64]
    moduli: NDArray[np.float64]
    rounding: NDArray[np.float64]


# ============================================================================ evaluators
def _abs_derivative(coefs: NDArray, order: int) -> NDArray[np.float64]:
    """Coefficients of the ``order``-th derivative of the polynomial ``sum |c_j| r^j``."""
    out = np.abs(np.asarray(coefs))
    if order >= out.size:
        return np.zeros(1)
    return npoly.polyder(out, order) if order else out


def _padd(a: NDArray, b: NDArray) -> NDArray:
    out = np.zeros(max(a.size, b.size))
    out[: a.size] += a
    out[: b.size] += b
    return out


def _point_part(P: QuasiPolynomial) -> QuasiPolynomial | None:
    return QuasiPolynomial(P.coefs, P.delays) if P.point_terms else None


def is_zero(P: QuasiPolynomial) -> bool:
    """True when ``P`` has no term at all (identically zero)."""
    return not P.point_terms and not P.distributed


def _leading_sign(values: NDArray) -> float:
    """``+1`` or ``-1``: the sign that makes the first non-zero value of ``values`` "positive"."""
    nz = np.flatnonzero(values)
    if not nz.size:
        return 1.0
    v = complex(values[nz[0]])
    return -1.0 if (v.real < 0.0 or (v.real == 0.0 and v.imag < 0.0)) else 1.0


class AxisKernels:
    """The distributed terms of ``A`` and ``B`` grouped by kernel up to sign.

    A term ``q(s) int nu^m N e^{-nu s}`` is stored as ``c q(s) J(s)``, ``J`` the kernel
    sum of a unit term (poly 1) and ``c = +-1``; the paper's loops carry ``+I_N`` in ``A``
    and ``-I_N`` in ``B``, so one kernel sum per frequency serves both (negating the values
    negates the interpolant exactly).
    """

    def __init__(self, factors: Sequence[QuasiPolynomial]) -> None:
        index: dict[tuple, tuple[int, float]] = {}
        self.units: list[DistributedDelay] = []
        self.terms: list[list[tuple[int, complex, NDArray]]] = [[] for _ in factors]
        for side, P in enumerate(factors):
            for d in P.distributed:
                sign = _leading_sign(d.values)
                key = (d.nodes.tobytes(), (sign * d.values).tobytes(), d.moment, d.interpolation)
                if key not in index:
                    unit = d if d.poly.size == 1 else d.replace(poly=np.ones(1))
                    index[key] = (len(self.units), sign)
                    self.units.append(unit)
                k, unit_sign = index[key]
                self.terms[side].append((k, complex(sign * unit_sign), d.poly))
        self.abs_moments = [np.array([float(u.abs_moment(0.0, k)) for k in range(4)]) for u in self.units]

    def sums(self, s: NDArray, extra: int) -> list[NDArray[np.complex128]]:
        """``J_{m+extra}(s)`` of every kernel."""
        return [_with_moment(u, extra)(s) for u in self.units]


@functools.lru_cache(maxsize=64)
def _with_moment(unit: DistributedDelay, extra: int) -> DistributedDelay:
    """``unit`` with ``extra`` more powers of ``nu`` (built once: the spline fit is the costly part).

    Kernels recur across calls (a gain study keeps ``I_N`` while ``K`` changes).
    """
    return unit if extra == 0 else unit.replace(moment=unit.moment + extra)


class _TermScale:
    """``S_k(r)``, ``k = 0..3``: the sum of the moduli of the terms of ``P^{(k)}(i w)``, ``|w| <= r``.

    A point term ``p(s) e^{-tau s}`` contributes ``sum_j C(k, j) tau^j |p^{(k-j)}|(r)``
    (``|p|`` has the moduli of the coefficients of ``p``), a kernel term ``c q(s) J_m(s)``
    contributes ``|c| sum_j C(k, j) |q^{(k-j)}|(r) M_{m+j}``. ``S_k`` bounds
    ``|P^{(k)}(i w)|`` and scales its rounding error; it increases with ``r``.
    """

    def __init__(self, P: QuasiPolynomial, kernels: AxisKernels, side: int) -> None:
        self.coefs = [np.zeros(1) for _ in range(4)]
        for p, tau in P.point_terms:
            for k in range(4):
                for j in range(k + 1):
                    self.coefs[k] = _padd(self.coefs[k], comb(k, j) * tau**j * _abs_derivative(p, k - j))
        for unit, c, q in kernels.terms[side]:
            moments = kernels.abs_moments[unit]
            for k in range(4):
                for j in range(k + 1):
                    self.coefs[k] = _padd(self.coefs[k], abs(c) * comb(k, j) * moments[j] * _abs_derivative(q, k - j))

    def __call__(self, r: ArrayLike, k: int = 0) -> NDArray[np.float64]:
        return np.asarray(npoly.polyval(np.abs(np.asarray(r, dtype=float)), self.coefs[k]), dtype=float)


class AxisGap:
    """``g(w) = |A(i w)|^2 - |B(i w)|^2`` on the frequency axis: values, derivatives, bounds.

    ``g`` has the zeros of ``|A(i w)| - |B(i w)|`` and is smooth at them: simple crossings
    are its sign changes, tangencies its double zeros (``g = g' = 0``). The formulas for
    ``g'``, ``g''`` and the bounds of ``g''``, ``g'''`` are in the module notes; every
    value carries a bound of its rounding error, so that a test such as
    ``|g| - err > 0`` is a proof.

    Parameters
    ----------
    A, B : QuasiPolynomial
        The loop factors of ``F(s; delta) = A(s) + B(s) e^{-delta s}``.

    Attributes
    ----------
    evaluations : int
        Frequencies at which :meth:`jet` has evaluated ``A``, ``B`` and their derivatives.

    Examples
    --------
    >>> A = QuasiPolynomial([[1.0, 1.0]], [0.0])      # s + 1
    >>> B = QuasiPolynomial([[2.0]], [0.0])           # 2: g = 1 + w^2 - 4
    >>> jet = AxisGap(A, B).jet([1.0])
    >>> float(jet.g[0]), float(jet.dg[0]), float(jet.d2g[0])
    (-2.0, 2.0, 2.0)
    """

    def __init__(self, A: QuasiPolynomial, B: QuasiPolynomial, *, _kernels: AxisKernels | None = None) -> None:
        for name, P in (("A", A), ("B", B)):
            if not isinstance(P, QuasiPolynomial):
                raise ParameterError(name, "a QuasiPolynomial", type(P).__name__)
        self._kernels = AxisKernels((A, B)) if _kernels is None else _kernels
        self._points: list[tuple[QuasiPolynomial, QuasiPolynomial, QuasiPolynomial] | None] = []
        for P in (A, B):
            P0 = _point_part(P)
            if P0 is None:
                self._points.append(None)
            else:
                P1 = P0.derivative()
                self._points.append((P0, P1, P1.derivative()))
        self._scales = [_TermScale(P, self._kernels, side) for side, P in enumerate((A, B))]
        self.evaluations = 0

    def _factor_jets(self, s: NDArray) -> NDArray[np.complex128]:
        """``P^{(k)}(s)`` for ``P = A, B`` and ``k = 0, 1, 2``, shape ``(2, 3, n)`` (direct sums)."""
        out = np.zeros((2, 3, s.size), dtype=complex)
        for lo in range(0, s.size, _DIRECT_CHUNK):
            part = s[lo : lo + _DIRECT_CHUNK]
            sums = [self._kernels.sums(part, k) for k in range(3)] if self._kernels.units else []
            for side in range(2):
                parts = self._points[side]
                if parts is not None:
                    for k in range(3):
                        out[side, k, lo : lo + part.size] = parts[k](part)
                for unit, c, q in self._kernels.terms[side]:
                    j0, j1, j2 = sums[0][unit], sums[1][unit], sums[2][unit]
                    q1 = npoly.polyder(q) if q.size > 1 else np.zeros(1)
                    q2 = npoly.polyder(q1) if q1.size > 1 else np.zeros(1)
                    v0, v1, v2 = (npoly.polyval(part, p) for p in (q, q1, q2))
                    out[side, 0, lo : lo + part.size] += c * v0 * j0
                    out[side, 1, lo : lo + part.size] += c * (v1 * j0 - v0 * j1)
                    out[side, 2, lo : lo + part.size] += c * (v2 * j0 - 2.0 * v1 * j1 + v0 * j2)
        return out

    def jet(self, omega: ArrayLike) -> AxisJet:
        """``g``, ``g'``, ``g''`` at the frequencies ``omega`` with bounds of their rounding errors.

        The factors are summed directly (never as chirp-z transforms), in chunks.
        """
        w = np.atleast_1d(np.asarray(omega, dtype=float)).ravel()
        if not np.all(np.isfinite(w)):
            raise ParameterError("omega", "finite real frequencies", omega)
        self.evaluations += w.size
        vals = self._factor_jets(1j * w)
        mod = np.abs(vals)
        rnd = np.stack([np.stack([_POINT_ROUNDING * sc(w, k) for k in range(3)]) for sc in self._scales])
        sign = np.array([1.0, -1.0])[:, None]
        a0, a1, a2 = vals[:, 0], vals[:, 1], vals[:, 2]
        v0, v1, v2 = mod[:, 0], mod[:, 1], mod[:, 2]
        e0, e1, e2 = rnd[:, 0], rnd[:, 1], rnd[:, 2]
        g = np.sum(sign * v0**2, axis=0)
        dg = np.sum(sign * -2.0 * np.imag(np.conj(a0) * a1), axis=0)
        d2g = np.sum(sign * 2.0 * (v1**2 - np.real(np.conj(a0) * a2)), axis=0)
        err = np.sum(e0 * (2.0 * v0 + e0) + 4.0 * _EPS * v0**2, axis=0)
        derr = np.sum(2.0 * (v0 * e1 + (v1 + e1) * e0) + 8.0 * _EPS * v0 * v1, axis=0)
        d2err = np.sum(2.0 * (e1 * (2.0 * v1 + e1) + v0 * e2 + (v2 + e2) * e0) + 8.0 * _EPS * (v1**2 + v0 * v2), axis=0)
        return AxisJet(w, g, dg, d2g, err, derr, d2err, mod, rnd)

    def bounds(
        self, lo: ArrayLike, hi: ArrayLike, centre: AxisJet | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Bounds ``(M_2, M_3)`` of ``|g''|`` and ``|g'''|`` on each segment ``[lo, hi]``.

        ``D_k``, the bound of ``|P^{(k)}|`` on a segment, is the sum of the moduli of the
        terms at its largest ``|w|``; with ``centre``, the jet at the midpoints, the Taylor
        bounds ``|P^{(k)}(i c)| + r D_{k+1}`` (``k = 2, 1, 0``) replace it where smaller.
        """
        lo, hi = np.atleast_1d(np.asarray(lo, dtype=float)), np.atleast_1d(np.asarray(hi, dtype=float))
        r = np.maximum(np.abs(lo), np.abs(hi))
        rad = 0.5 * (hi - lo)
        m2 = np.zeros(r.shape)
        m3 = np.zeros(r.shape)
        for side, sc in enumerate(self._scales):
            d0, d1, d2, d3 = (sc(r, k) for k in range(4))
            if centre is not None:
                at_c = centre.moduli[side] + centre.rounding[side]
                d2 = np.minimum(d2, at_c[2] + rad * d3)
                d1 = np.minimum(d1, at_c[1] + rad * d2)
                d0 = np.minimum(d0, at_c[0] + rad * d1)
            m2 += 2.0 * (d1**2 + d0 * d2)
            m3 += 2.0 * (3.0 * d1 * d2 + d0 * d3)
        return m2 * (1.0 + 1e-12), m3 * (1.0 + 1e-12)


class _AxisFunction:
    """``h(w) = |A(i w)| - |B(i w)|`` with an evaluation counter and a work bound.

    Kernels shared by ``A`` and ``B`` up to a constant (``I_N`` in both factors of every
    controller of the paper) are evaluated once per frequency.
    """

    def __init__(self, A: QuasiPolynomial, B: QuasiPolynomial, max_evals: int, kernels: AxisKernels) -> None:
        self.points = [_point_part(P) for P in (A, B)]
        self.kernels = kernels
        self.scales = [_TermScale(P, self.kernels, side) for side, P in enumerate((A, B))]
        self.evals = 0
        self.max_evals = max_evals

    def spend(self, n: int, what: str) -> None:
        """Count ``n`` evaluations; raise before the work bound would be exceeded."""
        if self.evals + n > self.max_evals:
            raise CertificationError(
                f"crossing search: {what} needs {n} more evaluations of A and B on the imaginary axis after "
                f"{self.evals}, beyond the work bound max_evals={self.max_evals} (raise max_evals)"
            )
        self.evals += n

    def room(self) -> int:
        return self.max_evals - self.evals

    def factors(self, w: NDArray[np.float64], rounding: float = _GRID_ROUNDING) -> tuple[NDArray, ...]:
        """``A(i w)``, ``B(i w)`` and bounds of their rounding errors (``rounding`` times the
        sums of the moduli of their terms)."""
        w = np.asarray(w, dtype=float)
        self.spend(w.size, "the evaluation of A and B")
        s = 1j * w
        vals = [np.zeros(s.shape, dtype=complex) if P is None else P(s) for P in self.points]
        if self.kernels.units:
            sums = self.kernels.sums(s, 0)
            for side in range(2):
                for unit, c, q in self.kernels.terms[side]:
                    vals[side] = vals[side] + (c if q.size == 1 else c * npoly.polyval(s, q)) * sums[unit]
        return vals[0], vals[1], rounding * self.scales[0](w), rounding * self.scales[1](w)

    def with_rounding(self, w: NDArray[np.float64], rounding: float = _GRID_ROUNDING) -> tuple[NDArray, NDArray]:
        """``h(w)`` and a bound of its rounding error (``rounding`` times the sum of the moduli of the terms)."""
        a, b, err_a, err_b = self.factors(w, rounding)
        return np.abs(a) - np.abs(b), err_a + err_b

    def direct(self, w: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """:meth:`with_rounding` by direct sums (chunks below the chirp-z threshold)."""
        out = [self.with_rounding(w[k : k + _DIRECT_CHUNK], _POINT_ROUNDING) for k in range(0, w.size, _DIRECT_CHUNK)]
        if not out:
            return np.zeros(0), np.zeros(0)
        return np.concatenate([v for v, _ in out]), np.concatenate([e for _, e in out])


class _AxisLipschitz:
    """Bound of ``|A'(i w)| + |B'(i w)|`` on segments ``[a, b]`` of the frequency axis (module notes)."""

    def __init__(self, A: QuasiPolynomial, B: QuasiPolynomial, kernels: AxisKernels) -> None:
        self.points = [P for P in (_point_part(A), _point_part(B)) if P is not None]
        self.kernel_bounds = []
        for unit, moments in zip(kernels.units, kernels.abs_moments):
            if unit.moment == 0:
                v0 = float(unit.variation_bound(0.0))
                v1 = float(moments[0]) + max(abs(unit.a), abs(unit.b)) * v0
            else:
                v0 = v1 = np.inf
            self.kernel_bounds.append((float(moments[0]), float(moments[1]), v0, v1))
        self.terms = [(unit, abs(c), np.abs(q), _abs_derivative(q, 1)) for side in kernels.terms for unit, c, q in side]

    def __call__(self, a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
        out = np.zeros(np.shape(a))
        for P in self.points:
            out = out + P.deriv_bound(1j * a, 1j * b)
        r = np.maximum(np.abs(a), np.abs(b))
        r_min = np.where((a <= 0.0) & (b >= 0.0), 0.0, np.minimum(np.abs(a), np.abs(b)))
        for unit, c, q, dq in self.terms:
            m0, m1, v0, v1 = self.kernel_bounds[unit]
            with np.errstate(divide="ignore", invalid="ignore"):
                j0 = np.where(r_min > 0.0, np.minimum(m0, v0 / r_min), m0)
                j1 = np.where(r_min > 0.0, np.minimum(m1, v1 / r_min), m1)
            out = out + c * (npoly.polyval(r, dq) * j0 + npoly.polyval(r, q) * j1)
        return out * (1.0 + 1e-12)


def frequency_bound(A: QuasiPolynomial, B: QuasiPolynomial) -> tuple[float, float] | None:
    """``(W, gap)``: no crossing with ``|w| >= W``; None when the principal part is not strongly stable.

    ``gap = |a_0| - sum |others|`` over the principal terms of ``A`` and of
    ``B e^{-delta s}`` (``delta -> 0+``), positive iff the difference operator of
    ``F(.; delta)`` is strongly stable (Hale and Verduyn Lunel: ``gamma_0 < 1`` for a
    scalar operator). None is also returned for advanced-type loops, and when ``gap`` is
    not above the rounding of its own sum (``8 eps sum |a_k|``: the boundary of strong
    stability, e.g. ``|rho q| + |K q| = 1`` in decimal inputs). The proof that
    ``|A(i w)| - |B(i w)|`` does not vanish for ``|w| >= W`` is in the module notes; ``W``
    is computed with room for the rounding of the tail sums, so the inequality is strict.
    """
    degree = joint_degree(A, B)
    principal = principal_gap({"A": (A, 0), "B": (B, 1)}, degree, 0.0)
    if principal is None or principal.gap <= 0.0:
        return None
    gap, t0 = principal.gap, principal.t0
    total = sum(abs(c) for P in (A, B) for c, _ in P.leading_terms(degree))
    level = gap * (1.0 - _GAP_ROOM_REL) - _GAP_ROOM_EPS * _EPS * total
    if level <= 0.0:
        return None
    tail_a, tail_b = TailBound(A, degree, 0.0, t0), TailBound(B, degree, 0.0, t0)

    def tail(R: NDArray) -> NDArray:
        with np.errstate(over="ignore"):
            return tail_a(R) + tail_b(R)

    return _radius_below(tail, level), gap


def required_frequency_bound(A: QuasiPolynomial, B: QuasiPolynomial) -> tuple[float, float]:
    """:func:`frequency_bound`, or a ParameterError where there is none (crossings accumulate at infinity)."""
    w_bound = frequency_bound(A, B)
    if w_bound is None:
        raise ParameterError(
            "A, B",
            "loop factors whose difference operator is strongly stable for small delays (|a_0| > sum |others|)",
            None,
        )
    return w_bound


def _radius_below(tail: Callable[[NDArray], NDArray], level: float) -> float:
    """A radius ``R`` with ``tail(R) < level``, within ``1e-7`` of the smallest (``tail`` non-increasing).

    The first point below ``level`` of a geometric grid (ratio ``2^(1/8)``, from ``2^-64``
    to ``2^200``), then of two uniform grids of 1025 points in the last bracket: three
    vectorised evaluations instead of a bisection.
    """
    grid = np.exp2(np.arange(-64.0, 200.125, 0.125))
    below = np.flatnonzero(tail(grid) < level)
    if not below.size:
        raise CertificationError(
            f"frequency_bound: the remainder does not fall below the principal-part gap {level:.3g} for |s| <= 2^200"
        )
    k = int(below[0])
    if k == 0:
        return float(grid[0])
    lo, hi = float(grid[k - 1]), float(grid[k])
    for _ in range(2):
        pts = np.linspace(lo, hi, 1025)
        pts[-1] = hi
        j = int(np.flatnonzero(tail(pts) < level)[0])
        lo, hi = float(pts[j - 1]) if j else lo, float(pts[j])
    return hi


# ============================================================================ first-order search
def _first_stage(
    h: _AxisFunction, lo: float, hi: float, lipschitz: Callable[[NDArray, NDArray], NDArray], step: float
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Clusters ``[p, q]`` where the exclusion test leaves a zero of ``h`` possible, with the
    certified signs of ``h`` at their ends (0 where the value is at rounding level and no
    excluded neighbour fixes it)."""
    n_blocks = _LIPSCHITZ_BLOCKS
    per_block = max(1.0, np.ceil((hi - lo) / n_blocks / step))
    n_points = n_blocks * per_block + 1
    if n_points > h.room():
        raise CertificationError(
            f"crossing search: the first grid on [{lo:.6g}, {hi:.6g}] (step pi/(8 tau) = {step:.3g}, tau the "
            f"largest delay) needs about {n_points:.3g} evaluations of A and B, beyond the work bound "
            f"max_evals={h.max_evals}; raise max_evals above that estimate"
        )
    per_block = int(per_block)
    grid = np.linspace(lo, hi, n_blocks * per_block + 1)
    h_grid, e_grid = h.with_rounding(grid)
    edges = np.linspace(lo, hi, n_blocks + 1)
    block_lipschitz = lipschitz(edges[:-1], edges[1:])
    # Uniform refinements (evaluated as chirp-z transforms) sized so that most segments
    # pass the exclusion test at once, and by what the work bound leaves; the rest is
    # refined adaptively.
    for _ in range(_UNIFORM_PASSES):
        room = np.maximum(np.abs(h_grid[:-1]) + np.abs(h_grid[1:]) - e_grid[:-1] - e_grid[1:], 1e-300)
        need = np.repeat(block_lipschitz, per_block) * np.diff(grid) / room
        factor = int(np.clip(np.ceil(np.quantile(need, _UNIFORM_QUANTILE)), 1, _UNIFORM_MAX // per_block))
        factor = min(factor, 1 + (h.room() // 2) // (n_blocks * per_block))
        if factor <= 1:
            break
        per_block *= factor
        grid = np.linspace(lo, hi, n_blocks * per_block + 1)
        h_grid, e_grid = h.with_rounding(grid)
    left, right = grid[:-1], grid[1:]
    h_left, h_right, e_left, e_right = h_grid[:-1], h_grid[1:], e_grid[:-1], e_grid[1:]
    seg_block = np.repeat(np.arange(n_blocks), per_block)
    min_width = _MIN_WIDTH * max(1.0, hi - lo)

    def _block_of(a: NDArray, b: NDArray) -> NDArray:
        """Index of the largest block bound over each segment ``[a, b]`` (blocks are contiguous)."""
        block_a = np.clip(((a - lo) / (hi - lo) * n_blocks).astype(int), 0, n_blocks - 1)
        block_b = np.clip(((b - lo) / (hi - lo) * n_blocks).astype(int), 0, n_blocks - 1)
        return np.where(block_lipschitz[block_b] > block_lipschitz[block_a], block_b, block_a)

    # Signs at points whose value is at rounding level, fixed by an excluded segment ending there.
    end_sign: dict[float, int] = {}
    small: list[tuple[NDArray, ...]] = []
    while left.size:
        keep = np.abs(h_left) + np.abs(h_right) - e_left - e_right <= block_lipschitz[seg_block] * (right - left)
        out = ~keep
        for here, v_here, e_here, v_there in ((left, h_left, e_left, h_right), (right, h_right, e_right, h_left)):
            for k in np.flatnonzero(out & (np.abs(v_here) <= e_here)):
                end_sign[float(here[k])] = int(np.sign(v_there[k]))
        left, right, h_left, h_right = left[keep], right[keep], h_left[keep], h_right[keep]
        e_left, e_right, seg_block = e_left[keep], e_right[keep], seg_block[keep]
        clusters = 1 + int(np.count_nonzero(np.sort(left)[1:] != np.sort(right)[:-1])) if left.size else 0
        done = ((right - left) <= min_width) | (clusters <= _HANDOVER and left.size <= 4 * _HANDOVER)
        small.append((left[done], right[done], h_left[done], h_right[done], e_left[done], e_right[done]))
        rest = ~done
        left, right, h_left, h_right = left[rest], right[rest], h_left[rest], h_right[rest]
        e_left, e_right = e_left[rest], e_right[rest]
        if not left.size:
            break
        # Refine each cluster of contiguous segments on one uniform line covering it, with
        # a power-of-two step at most 1/_SPLIT of its segments and 1/_LINE_POINTS of its
        # span: the nodes k 2^e are exact, so the evaluator sums the kernels as a chirp-z
        # transform.
        order = np.argsort(left)
        left, right = left[order], right[order]
        cuts = np.r_[0, np.flatnonzero(right[:-1] != left[1:]) + 1, left.size]
        spans = []
        for first, stop in itertools.pairwise(cuts):
            target = min((right[first] - left[first]) / _SPLIT, (right[stop - 1] - left[first]) / _LINE_POINTS)
            line_step = 2.0 ** np.floor(np.log2(target))
            k_lo, k_hi = np.floor(left[first] / line_step), np.ceil(right[stop - 1] / line_step)
            spans.append((k_lo, k_hi, line_step))
        total = sum(k_hi - k_lo + 3 for k_lo, k_hi, _ in spans)
        if total > h.room():
            raise CertificationError(
                f"crossing search: refining {len(spans)} clusters of unresolved segments needs about {total:.3g} "
                f"more evaluations after {h.evals}, beyond the work bound max_evals={h.max_evals} (raise max_evals)"
            )
        lines = [_line(h, k_lo, k_hi, line_step, lo, hi) for k_lo, k_hi, line_step in spans]
        left = np.concatenate([ln[:-1] for ln, _, _ in lines])
        right = np.concatenate([ln[1:] for ln, _, _ in lines])
        h_left = np.concatenate([v[:-1] for _, v, _ in lines])
        h_right = np.concatenate([v[1:] for _, v, _ in lines])
        e_left = np.concatenate([e[:-1] for _, _, e in lines])
        e_right = np.concatenate([e[1:] for _, _, e in lines])
        seg_block = _block_of(left, right)
    seg_left, seg_right, seg_h_left, seg_h_right, seg_e_left, seg_e_right = (
        np.concatenate([part[k] for part in small]) for k in range(6)
    )
    order = np.argsort(seg_left)
    seg_left, seg_right = seg_left[order], seg_right[order]
    seg_h_left, seg_h_right = seg_h_left[order], seg_h_right[order]
    seg_e_left, seg_e_right = seg_e_left[order], seg_e_right[order]
    starts = np.r_[0, np.flatnonzero(seg_left[1:] > seg_right[:-1]) + 1] if seg_left.size else np.zeros(0, int)
    stops = np.r_[starts[1:] - 1, seg_left.size - 1] if seg_left.size else np.zeros(0, int)

    def _sign(point: NDArray, value: NDArray, err: NDArray) -> NDArray:
        known = np.abs(value) > err
        fixed = np.array([end_sign.get(float(p), 0) for p in point], dtype=np.int64)
        return np.where(known, np.sign(value).astype(np.int64), fixed)

    return (
        seg_left[starts],
        seg_right[stops],
        _sign(seg_left[starts], seg_h_left[starts], seg_e_left[starts]),
        _sign(seg_right[stops], seg_h_right[stops], seg_e_right[stops]),
    )


def _line(h: _AxisFunction, k_lo: float, k_hi: float, step: float, lo: float, hi: float) -> tuple[NDArray, ...]:
    """``h`` on the points ``k step`` strictly inside ``(lo, hi)`` (one chirp-z line), plus
    ``lo`` or ``hi`` where the line reaches past them: the line covers ``[k_lo step, k_hi step]``
    intersected with ``[lo, hi]``."""
    line = (k_lo + np.arange(k_hi - k_lo + 1)) * step
    inner = line[(line > lo) & (line < hi)]
    head = np.array([lo] if line[0] <= lo else [])
    tail = np.array([hi] if line[-1] >= hi else [])
    parts = [(pts, *h.with_rounding(pts)) for pts in (head, inner, tail) if pts.size]
    return tuple(np.concatenate([part[k] for part in parts]) for k in range(3))


# ============================================================================ second-order resolution
@dataclass
class _Found:
    """Zeros found by the resolution: brackets to refine and points located to rounding."""

    # (a, b, sign of g at a, sign of g', first iterate, estimate of h' there or nan)
    brackets: list[tuple[float, float, int, int, float, float]] = field(default_factory=list)
    points: list[tuple[float, bool, int]] = field(default_factory=list)  # (w, tangential, slope)

    def monotone(
        self, a: float, b: float, sa: int, sb: int, slope: int, guess: float = np.nan, dh: float = np.nan
    ) -> None:
        """One interval on which ``g`` is monotone with the given slope sign (``guess``, ``dh``: see _refine)."""
        if sa and sb:
            if sa != sb:
                if sa != -slope:
                    _inconsistent(a, b, f"end signs {sa}, {sb} against slope {slope}")
                self.brackets.append((a, b, sa, slope, guess if a < guess < b else 0.5 * (a + b), dh))
        elif sa == 0 and sb == slope:
            self.points.append((a, False, slope))
        elif sb == 0 and sa == -slope:
            self.points.append((b, False, slope))
        elif sa or sb:
            _inconsistent(a, b, f"end signs {sa}, {sb} against slope {slope}")
        else:
            _inconsistent(a, b, "a monotone g at rounding level at both ends")


def _inconsistent(a: float, b: float, what: str) -> None:
    raise CertificationError(
        f"crossing search: inconsistent certificates on [{a:.17g}, {b:.17g}] ({what}): the rounding model of "
        "the evaluation of A and B does not hold here"
    )


def _resolve(
    gap: AxisGap, h: _AxisFunction, lo: NDArray, hi: NDArray, s_lo: NDArray, s_hi: NDArray
) -> tuple[list[float], list[bool], list[int]]:
    """Zeros of ``g`` in the clusters ``[lo, hi]`` (module notes, second-order resolution).

    Returns the zeros, whether each is a tangency, and the certified sign of ``g'`` there.
    """

    def jet(w: NDArray) -> AxisJet:
        h.spend(3 * w.size, "the second-order resolution of crossing clusters")
        return gap.jet(w)

    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    s_lo, s_hi = np.asarray(s_lo, dtype=np.int64).copy(), np.asarray(s_hi, dtype=np.int64).copy()
    found = _Found()
    # ends whose sign the first stage left open: a direct evaluation may fix it
    for ends, signs in ((lo, s_lo), (hi, s_hi)):
        open_ = np.flatnonzero(signs == 0)
        if open_.size:
            j = jet(ends[open_])
            signs[open_] = np.where(np.abs(j.g) > j.err, np.sign(j.g), 0).astype(np.int64)
    for _ in range(_RESOLVE_ROUNDS):
        if not lo.size:
            break
        c, r = 0.5 * (lo + hi), 0.5 * (hi - lo)
        j = jet(c)
        m2, m3 = gap.bounds(lo, hi, j)
        excluded = np.abs(j.g) - j.err - (np.abs(j.dg) + j.derr) * r - 0.5 * m2 * r**2 > 0.0
        monotone = ~excluded & (np.abs(j.dg) - j.derr - m2 * r > 0.0)
        convex = ~excluded & ~monotone & (np.abs(j.d2g) - j.d2err - m3 * r > 0.0)
        for k in np.flatnonzero(excluded & (s_lo * s_hi < 0)):
            _inconsistent(lo[k], hi[k], "a sign change on a segment where |g| is bounded away from zero")
        with np.errstate(divide="ignore", invalid="ignore"):
            guess = c - j.g / j.dg  # Newton's step from the centre seeds the refinement
            dh = j.dg / (j.moduli[0, 0] + j.moduli[1, 0])  # h' = g' / (|A| + |B|) where g = 0
        for k in np.flatnonzero(monotone):
            found.monotone(lo[k], hi[k], int(s_lo[k]), int(s_hi[k]), int(np.sign(j.dg[k])), guess[k], dh[k])
        # Newton's method pays when the stationary point lies inside; a first step leaving
        # the cluster means g is likely monotone there, which a bisection shows sooner.
        convex &= np.abs(j.dg) <= np.abs(j.d2g) * r
        undecided = ~(excluded | monotone | convex)
        idx = np.flatnonzero(convex)
        if idx.size:
            sub = _take(j, idx)
            decided = _convex(jet, found, lo[idx], hi[idx], s_lo[idx], s_hi[idx], np.sign(sub.d2g), sub)
            undecided[idx[~decided]] = True
        idx = np.flatnonzero(undecided)
        if not idx.size:
            lo = lo[:0]
            break
        lo, hi, s_lo, s_hi = _split(jet, lo[idx], hi[idx], s_lo[idx], s_hi[idx], j, idx)
    if lo.size:
        j = jet(0.5 * (lo + hi))
        worst = int(np.argmin(np.abs(j.g)))
        _undecidable(lo[worst], hi[worst], j, worst)
    zeros = [w for w, _, _ in found.points]
    tangential = [t for _, t, _ in found.points]
    slopes = [s for _, _, s in found.points]
    if found.brackets:
        a, b, sa, slope, guess, dh = (np.array(v, dtype=float) for v in zip(*found.brackets))
        zeros += [float(w) for w in _refine(h, a, b, sa.astype(np.int64), guess, dh)]
        tangential += [False] * a.size
        slopes += [int(v) for v in slope]
    return zeros, tangential, slopes


def _take(j: AxisJet, idx: NDArray) -> AxisJet:
    """The jet at the frequencies ``idx``."""
    return AxisJet(
        j.omega[idx],
        j.g[idx],
        j.dg[idx],
        j.d2g[idx],
        j.err[idx],
        j.derr[idx],
        j.d2err[idx],
        j.moduli[:, :, idx],
        j.rounding[:, :, idx],
    )


def _undecidable(a: float, b: float, j: AxisJet, k: int) -> None:
    raise CertificationError(
        f"crossing search: cannot decide whether |A(i w)|^2 - |B(i w)|^2 vanishes on [{a:.17g}, {b:.17g}]: "
        f"g = {j.g[k]:.3g}, g' = {j.dg[k]:.3g}, g'' = {j.d2g[k]:.3g} at its centre, within rounding "
        f"({j.err[k]:.2g}, {j.derr[k]:.2g}, {j.d2err[k]:.2g}) of a zero of multiplicity three or more; a "
        "slight change of the loop, or an evaluation of A and B in higher precision, would decide it"
    )


def _convex(
    jet: Callable[[NDArray], AxisJet],
    found: _Found,
    lo: NDArray,
    hi: NDArray,
    s_lo: NDArray,
    s_hi: NDArray,
    sigma: NDArray,
    centre: AxisJet,
) -> NDArray[np.bool_]:
    """Clusters on which ``sigma g`` is convex: Newton's method on ``g'`` from the centres
    (``centre`` holds the jet there), then the verdict.

    Returns which clusters were decided (the others are bisected).
    """
    w = 0.5 * (lo + hi)
    g, dg, d2g, err, derr = (np.array(getattr(centre, name)) for name in ("g", "dg", "d2g", "err", "derr"))
    live = np.ones(w.size, dtype=bool)
    for _ in range(_NEWTON_STEPS):
        k = np.flatnonzero(live)
        with np.errstate(divide="ignore", invalid="ignore"):
            new = np.clip(w[k] - dg[k] / d2g[k], lo[k], hi[k])
        new = np.where(np.isfinite(new), new, w[k])
        move = (np.abs(new - w[k]) > 4.0 * _EPS * np.maximum(1.0, np.abs(w[k]))) & (np.abs(dg[k]) > derr[k])
        live[k] = move
        k = k[move]
        if not k.size:
            break
        w[k] = new[move]
        j = jet(w[k])
        g[k], dg[k], d2g[k], err[k], derr[k] = j.g, j.dg, j.d2g, j.err, j.derr
    decided = np.ones(w.size, dtype=bool)
    for i in range(w.size):
        a, b, sg = float(lo[i]), float(hi[i]), int(sigma[i])
        g_w, dg_w, err_w, derr_w = sg * g[i], sg * dg[i], err[i], derr[i]
        if w[i] == b and dg_w < -derr_w:  # sigma g' increasing and negative at the right end
            found.monotone(a, b, int(s_lo[i]), int(s_hi[i]), -sg)
        elif w[i] == a and dg_w > derr_w:
            found.monotone(a, b, int(s_lo[i]), int(s_hi[i]), sg)
        elif g_w - err_w - (abs(dg_w) + derr_w) * max(w[i] - a, b - w[i]) > 0.0:
            if s_lo[i] == -sg or s_hi[i] == -sg:
                _inconsistent(a, b, "a sign change where the tangent line bounds g away from zero")
        elif g_w + err_w < 0.0:  # sign -sigma at w*: a simple zero on each side where sigma g > 0
            ws = float(w[i])
            if s_lo[i] == sg:  # sigma g decreases through zero on [a, w*]
                found.brackets.append((a, ws, sg, -sg, 0.5 * (a + ws), np.nan))
            elif s_lo[i] == 0:
                found.points.append((a, False, -sg))
            if s_hi[i] == sg:  # and increases through zero on [w*, b]
                found.brackets.append((ws, b, -sg, sg, 0.5 * (ws + b), np.nan))
            elif s_hi[i] == 0:
                found.points.append((b, False, sg))
        elif abs(dg_w) <= 4.0 * derr_w:
            found.points.append((float(w[i]), True, 0))
        else:
            decided[i] = False
    return decided


def _split(
    jet: Callable[[NDArray], AxisJet], lo: NDArray, hi: NDArray, s_lo: NDArray, s_hi: NDArray, j: AxisJet, idx: NDArray
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Bisect clusters at a point where the sign of ``g`` is certain (the centre, else a quarter off)."""
    c, r = 0.5 * (lo + hi), 0.5 * (hi - lo)
    g, err = j.g[idx], j.err[idx]
    for k in np.flatnonzero(r <= 4.0 * _EPS * np.maximum(1.0, np.abs(c))):
        _undecidable(lo[k], hi[k], j, int(idx[k]))
    mid, s_mid = c.copy(), np.where(np.abs(g) > err, np.sign(g), 0).astype(np.int64)
    for offset in (-0.25, 0.25):
        open_ = np.flatnonzero(s_mid == 0)
        if not open_.size:
            break
        trial = c[open_] + offset * r[open_]
        jt = jet(trial)
        ok = np.abs(jt.g) > jt.err
        mid[open_[ok]] = trial[ok]
        s_mid[open_[ok]] = np.sign(jt.g[ok]).astype(np.int64)
    for k in np.flatnonzero(s_mid == 0):
        _undecidable(lo[k], hi[k], j, int(idx[k]))
    return np.r_[lo, mid], np.r_[mid, hi], np.r_[s_lo, s_mid], np.r_[s_mid, s_hi]


def _refine(
    h: _AxisFunction, a: NDArray, b: NDArray, sign_a: NDArray, guess: NDArray, dh: NDArray
) -> NDArray[np.float64]:
    """Zeros of ``h`` in the brackets ``[a, b]`` (certified sign ``sign_a`` at ``a``, the opposite at ``b``).

    The first iterate is ``guess`` (inside the bracket), the second a Newton step with the
    estimate ``dh`` of ``h'`` (a bisection where it is nan); then secant steps through the
    last two iterates, kept inside the bracket, with a bisection whenever the bracket has
    not halved over the last three steps (Dekker's safeguard). Each new value replaces
    the end with its sign; a value whose sign is not certain lies within rounding of the
    zero, so the bracket then still holds the zero up to that band. A bracket is done
    when narrower than ``_XTOL max(1, |w|)``, when two successive secant iterates agree
    to that tolerance, or when ``|h|`` falls below ``eps`` times the sum of the moduli of
    the terms (pure rounding).
    """
    x = guess.copy()
    fx, err = h.direct(x)
    left = np.sign(fx) == sign_a
    a, b = np.where(left, x, a), np.where(left, b, x)
    with np.errstate(divide="ignore", invalid="ignore"):
        xp = x - fx / dh  # a virtual previous iterate with value 0: the first secant step is Newton's
    fp = np.zeros(x.shape)
    xp = np.where(np.isfinite(xp), xp, x)
    history = [b - a] * 3
    done = np.abs(fx) <= err / 64.0  # err is 64 eps times the scale: below eps, the value is noise
    for _ in range(_MAX_REFINE):
        width = b - a
        done |= width <= _XTOL * np.maximum(1.0, np.abs(a))
        act = np.flatnonzero(~done)
        if not act.size:
            return np.where(np.isfinite(x), x, 0.5 * (a + b))
        aa, bb = a[act], b[act]
        with np.errstate(divide="ignore", invalid="ignore"):
            sec = x[act] - fx[act] * (x[act] - xp[act]) / (fx[act] - fp[act])
        mid = 0.5 * (aa + bb)
        stalled = width[act] > 0.5 * history[0][act]
        use_sec = np.isfinite(sec) & (sec > aa) & (sec < bb) & ~stalled
        xn = np.where(use_sec, sec, mid)
        fn, err = h.direct(xn)
        settled = use_sec & (np.abs(xn - x[act]) <= _XTOL * np.maximum(1.0, np.abs(xn)))
        xp[act], fp[act] = x[act], fx[act]
        x[act], fx[act] = xn, fn
        left = np.sign(fn) == sign_a[act]
        a[act] = np.where(left, xn, aa)
        b[act] = np.where(left, bb, xn)
        history = [*history[1:], b - a]
        done[act] |= (np.abs(fn) <= err / 64.0) | settled
    raise ConvergenceError(
        f"crossing refinement: {int(np.count_nonzero(~done))} brackets not resolved in {_MAX_REFINE} steps"
    )


# ============================================================================ entry points
def crossing_frequencies(A: QuasiPolynomial, B: QuasiPolynomial, *, max_evals: int = 2_000_000) -> CrossingSearch:
    """Every frequency ``w > 0`` (all real ``w`` for complex coefficients) with ``|A(i w)| = |B(i w)|``.

    The search range ``[0, W]`` is finite and provably complete, every reported absence
    of a crossing is a proof, and every crossing is classified as simple (with the
    certified sign of ``d/dw (|A|^2 - |B|^2)``) or as a tangency (module notes).

    Parameters
    ----------
    A, B : QuasiPolynomial
        The loop factors of ``F(s; delta) = A(s) + B(s) e^{-delta s}``.
    max_evals : int, optional
        Work bound on the evaluations of ``A`` and ``B`` (checked before any grid is
        allocated).

    Returns
    -------
    CrossingSearch

    Raises
    ------
    ParameterError
        If the difference operator of the loop is not strongly stable for small delays
        (no finite ``W`` exists: crossings accumulate at infinity).
    CertificationError
        If the work bound is hit, or a cluster cannot be decided (a zero of multiplicity
        three or more to rounding).

    Examples
    --------
    >>> A = QuasiPolynomial([[1.0, 1.0]], [0.0])      # s + 1
    >>> B = QuasiPolynomial([[2.0]], [0.0])           # 2 e^{-delta s}
    >>> res = crossing_frequencies(A, B)
    >>> round(float(res.omegas[0]) ** 2, 10), int(res.slopes[0])
    (3.0, 1)
    """
    for name, P in (("A", A), ("B", B)):
        if not isinstance(P, QuasiPolynomial):
            raise ParameterError(name, "a QuasiPolynomial", type(P).__name__)
    max_evals = positive_int("max_evals", max_evals)
    return crossing_search(A, B, required_frequency_bound(A, B), max_evals)[0]


def crossing_search(
    A: QuasiPolynomial, B: QuasiPolynomial, w_bound: tuple[float, float], max_evals: int
) -> tuple[CrossingSearch, AxisGap]:
    """The search, and the evaluator of ``|A|^2 - |B|^2`` it used (for :func:`axis_crossings`)."""
    W, gap = w_bound
    h = _AxisFunction(A, B, max_evals, AxisKernels((A, B)))
    tau = max(A.max_delay, B.max_delay, 1.0 / max(W, 1.0))
    step = np.pi / (8.0 * tau)
    lipschitz = _AxisLipschitz(A, B, h.kernels)
    hi = W * (1.0 + _EXTEND_REL) + _EXTEND_ABS
    lo = 0.0 if (A.is_real and B.is_real) else -hi
    clusters = _first_stage(h, lo, hi, lipschitz, step)
    axis_gap = AxisGap(A, B, _kernels=h.kernels)
    roots, tangential, slopes = _resolve(axis_gap, h, *clusters)
    keep = sorted((w, k) for k, w in enumerate(roots) if abs(w) > ZERO_TOL * max(1.0, W))
    search = CrossingSearch(
        np.array([w for w, _ in keep], dtype=float),
        np.array([tangential[k] for _, k in keep], dtype=bool),
        float(W),
        float(gap),
        h.evals,
        np.array([slopes[k] for _, k in keep], dtype=np.int64),
    )
    return search, axis_gap


def common_axis_zeros(axis_gap: AxisGap, search: CrossingSearch) -> NDArray[np.float64]:
    """Crossing frequencies where ``A`` and ``B`` vanish together (``F(i w; delta) = 0`` for every delta).

    At a common zero ``|A|^2 - |B|^2`` has a double zero, found as a tangency located to
    rounding; there ``|A(i w)|`` is below ``1e-9`` of the sum of the moduli of its terms.
    """
    w = search.omegas
    if not w.size:
        return w
    a = axis_gap._factor_jets(1j * w)[0, 0]
    return w[np.abs(a) <= 1e-9 * axis_gap._scales[0](w)]


def axis_crossings(
    A: QuasiPolynomial,
    B: QuasiPolynomial,
    search: CrossingSearch,
    delta_max: float | None,
    axis_gap: AxisGap | None = None,
) -> tuple[tuple[Crossing, ...], float]:
    """Delay sequences and directions at every crossing frequency; returns ``delta_max`` too.

    ``delta_max = None`` selects one full period past the first delay of every crossing,
    ``max_c (delta_{c,0} + 2 pi / |w_c|)`` (``inf`` without crossings). The direction is
    ``slope * sign(w)`` with the certified slope of the search (0 at a tangency).
    """
    w = search.omegas
    if not w.size:
        return (), float("inf") if delta_max is None else delta_max
    s = 1j * w
    if axis_gap is None:
        a, b, da, db = A(s), B(s), A.deriv_at(s), B.deriv_at(s)
    else:
        jets = axis_gap._factor_jets(s)
        a, b, da, db = jets[0, 0], jets[1, 0], jets[0, 1], jets[1, 1]
    period = 2.0 * np.pi / np.abs(w)
    base = np.mod(np.angle(-b / a) / w, period)
    base[(base > period * (1 - ZERO_TOL)) | (base < period * ZERO_TOL)] = 0.0
    if delta_max is None:
        delta_max = float(np.max(base + period))
    elif not np.isfinite(delta_max):
        raise ParameterError(
            "delta_max", "finite: the loop has crossing frequencies, hence infinitely many crossing delays", delta_max
        )
    e = np.exp(-s * base)
    ds = s * b * e / (da + db * e - base * b * e)
    out = []
    for k in range(w.size):
        count = 1 if delta_max < base[k] else int(np.floor((delta_max - base[k]) / period[k] * (1 + 1e-12))) + 1
        if count > _MAX_EVENTS:
            raise ParameterError(
                "delta_max", f"small enough that at most {_MAX_EVENTS} crossing delays are enumerated", delta_max
            )
        tangential = bool(search.tangential[k])
        direction = 0 if tangential else int(search.slopes[k]) * (1 if w[k] > 0 else -1)
        delays = tuple(float(base[k] + j * period[k]) for j in range(count))
        out.append(Crossing(float(w[k]), delays, direction, complex(ds[k]), tangential))
    # rounding may put the last delay an ulp above delta_max: delta_max covers it
    within = [d for c in out for d in c.delays if d <= delta_max * (1 + 1e-12)]
    delta_max = max([float(delta_max), *within])
    return tuple(sorted(out, key=lambda c: (c.delays[0], c.omega))), float(delta_max)


# ============================================================================ count by the argument principle
def axis_count(
    A: QuasiPolynomial, B: QuasiPolynomial, delta: float, W: float, kernels: AxisKernels, max_evals: int
) -> int | None:
    """Certified number of zeros of ``F = A + B e^{-delta s}`` in ``Re s > 0``, or None.

    The argument principle on the boundary of the half disc ``{Re s > 0, |s| < R}``,
    ``R = 1.01 W``, where the principal term ``a_0 e^{-t_0 s} s^n`` of ``A`` dominates:

    * on the arc, ``G = F e^{t_0 s} / s^n`` satisfies ``|G - a_0| < |a_0|`` (the
      frequency-bound estimate with ``|e^{-tau s}| <= 1`` on ``Re s >= 0``), so the change of
      ``arg F`` along it is ``n pi - 2 t_0 R + Arg(G(i R)/a_0) - Arg(G(-i R)/a_0)``;
    * on the axis, the change of ``arg F(i y)`` is the sum of the principal arguments of
      ``F(i y_{k+1}) / F(i y_k)`` over steps with ``M (y_{k+1} - y_k) <= |F| - E`` at both ends,
      ``M >= |A'| + |B'| + delta |B|`` on the step and ``E`` the rounding bound (each half of
      the step stays in a disc about an end value that excludes 0, and the two discs meet:
      the change is below ``pi / 3``). Real coefficients: twice the change on ``[0, R]``.

    The steps come from uniform grids (chirp-z sums) refined by cutting the failing steps.
    None (the caller falls back to :func:`nrobust.count_roots`) when ``A`` does not carry
    the dominant principal term, when ``F`` nearly vanishes on the axis, or when
    ``max_evals`` evaluations do not suffice.
    """
    degree = joint_degree(A, B)
    principal = principal_gap({"A": (A, 0), "B": (B, 1)}, degree, 0.0)
    if principal is None or principal.gap <= 0.0 or principal.first != "A":
        return None
    a0 = next(c for c, t in A.leading_terms(degree) if t == principal.t0)
    t0 = principal.t0
    h = _AxisFunction(A, B, max_evals, kernels)
    lipschitz = _AxisLipschitz(A, B, kernels)
    R = 1.01 * W + 1e-9
    real = A.is_real and B.is_real
    lo = 0.0 if real else -R

    def values(w: NDArray, rounding: float) -> tuple[NDArray, NDArray]:
        a, b, err_a, err_b = h.factors(w, rounding)
        rot = np.exp(-1j * w * delta)
        return a + b * rot, err_a + err_b + np.abs(b) * 4.0 * _EPS * (1.0 + np.abs(w * delta))

    def direct(w: NDArray) -> tuple[NDArray, NDArray]:
        parts = [values(w[k : k + _DIRECT_CHUNK], _POINT_ROUNDING) for k in range(0, w.size, _DIRECT_CHUNK)]
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])

    def bound(a: NDArray, b: NDArray) -> NDArray:
        return lipschitz(a, b) + delta * h.scales[1](np.maximum(np.abs(a), np.abs(b)))

    def need(a: NDArray, b: NDArray, fa: NDArray, fb: NDArray, ea: NDArray, eb: NDArray) -> NDArray:
        room = np.minimum(np.abs(fa) - ea, np.abs(fb) - eb)
        return np.where(room > 0.0, bound(a, b) * (b - a) / np.maximum(room, 1e-300), np.inf)

    tau = max(A.max_delay, B.max_delay + delta, 1.0 / max(R, 1.0))
    segments = int(np.ceil((R - lo) / (np.pi / (8.0 * tau)) / 64.0)) * 64
    try:
        if segments + 1 > h.room():
            return None
        grid = np.linspace(lo, R, segments + 1)
        f, e = values(grid, _GRID_ROUNDING)
        for _ in range(_UNIFORM_PASSES):
            ratio = need(grid[:-1], grid[1:], f[:-1], f[1:], e[:-1], e[1:])
            if not np.all(np.isfinite(ratio)):
                return None
            factor = min(
                int(np.ceil(np.quantile(ratio, _UNIFORM_QUANTILE))), _UNIFORM_MAX, 1 + (h.room() // 2) // grid.size
            )
            if factor <= 1:
                break
            grid = np.linspace(lo, R, (grid.size - 1) * factor + 1)
            f, e = values(grid, _GRID_ROUNDING)
        f_hi = f[-1]
        turn = 0.0
        left, right, f_l, f_r, e_l, e_r = grid[:-1], grid[1:], f[:-1], f[1:], e[:-1], e[1:]
        while left.size:
            ratio = need(left, right, f_l, f_r, e_l, e_r)
            sound = (np.abs(f_l) > 1e6 * e_l) & (np.abs(f_r) > 1e6 * e_r)
            ok = (ratio <= 1.0) & sound
            turn += float(np.sum(np.angle(f_r[ok] / f_l[ok])))
            bad = ~ok
            if np.any(bad & ~sound) or np.any(bad & (right - left < 1e-13 * (1.0 + np.abs(left)))):
                return None
            left, right, f_l, f_r, e_l, e_r = left[bad], right[bad], f_l[bad], f_r[bad], e_l[bad], e_r[bad]
            if not left.size:
                break
            pieces = np.clip(np.ceil(ratio[bad] * 1.25), 2, 64).astype(int)
            if int(np.sum(pieces - 1)) > h.room():
                return None
            t = np.concatenate([np.arange(1, k) / k for k in pieces])
            owner = np.repeat(np.arange(left.size), pieces - 1)
            inner = left[owner] + t * (right[owner] - left[owner])
            f_in, e_in = direct(inner)
            starts = np.r_[0, np.cumsum(pieces - 1)[:-1]]
            new_l, new_r, new_fl, new_fr, new_el, new_er = [], [], [], [], [], []
            for k in range(left.size):
                sl = slice(starts[k], starts[k] + pieces[k] - 1)
                pts = np.r_[left[k], inner[sl], right[k]]
                fv = np.r_[f_l[k], f_in[sl], f_r[k]]
                ev = np.r_[e_l[k], e_in[sl], e_r[k]]
                new_l.append(pts[:-1])
                new_r.append(pts[1:])
                new_fl.append(fv[:-1])
                new_fr.append(fv[1:])
                new_el.append(ev[:-1])
                new_er.append(ev[1:])
            left, right = np.concatenate(new_l), np.concatenate(new_r)
            f_l, f_r, e_l, e_r = (np.concatenate(x) for x in (new_fl, new_fr, new_el, new_er))
    except CertificationError:  # the work bound of the evaluations
        return None
    g_hi = f_hi * np.exp(1j * t0 * R) / (1j * R) ** degree / a0
    if real:
        arc, axis = 2.0 * float(np.angle(g_hi)), 2.0 * turn
    else:
        g_lo = f[0] * np.exp(-1j * t0 * R) / (-1j * R) ** degree / a0
        arc, axis = float(np.angle(g_hi)) - float(np.angle(g_lo)), turn
        if g_lo.real <= 0.0:
            return None
    if g_hi.real <= 0.0:
        return None
    count = (degree * np.pi - 2.0 * t0 * R + arc - axis) / (2.0 * np.pi)
    nearest = int(np.rint(count))
    if abs(count - nearest) > 1e-6 or nearest < 0:
        return None
    return nearest
