"""The loop on the imaginary axis: ``g(w) = |A(i w)|^2 - |B(i w)|^2``, its bounds and the frequency bound.

Roots of ``F(s; delta) = A(s) + B(s) e^{-delta s}`` reach the imaginary axis only at the
zeros of ``g`` (:mod:`nrobust.margins.crossing`), which :mod:`nrobust.margins.search`
locates on ``[0, W]``. This module holds what both need: the evaluators of ``A`` and
``B`` on the axis (kernels shared by the two factors summed once), ``g`` and its
derivatives with bounds of their rounding errors, the Lipschitz bound of
``h = |A| - |B|`` and the frequency bound ``W``.

**Frequency bound** (paper, proofs of Lemma 1 and Theorem 3). Write each factor as
``P(s) = s^n D_P(s) + R_P(s)`` with ``D_P`` its principal part, let ``a_0 e^{-t_0 s}`` be
the first principal term of ``A`` and ``B e^{-delta s}`` (``delta -> 0+``) and
``gap = |a_0| - sum |a_k|`` over the other principal terms (positive iff the difference
operator of ``F(.; delta)`` is strongly stable for small delays). On the axis every
``|e^{-tau s}| = 1``: if ``a_0`` belongs to ``A``, ``|D_A(i w)| - |D_B(i w)| >= gap``
(otherwise ``|D_B| - |D_A| >= gap``), and :class:`nrobust.bounds.TailBound` gives
``|R_P(i w)| <= |w|^n r_P(|w|)`` with ``r_P`` non-increasing (lower powers decay like
``|w|^(j-n)``, kernels like the lesser of ``V/|w|`` and ``V_1/|w| + V_2/|w|^2``, integrated by
parts once and twice: ``TailBound(..., second_order=True)``; the least of two valid bounds is
one, and ``V_1``, the end values and jumps of the kernel, can be much less than ``V``). Hence ::

    | |A(i w)| - |B(i w)| | >= |w|^n (gap - r_A(|w|) - r_B(|w|)).

``W`` is, to ``1e-7``, the smallest radius (rounded up) where the computed ``r_A + r_B``
is below ``gap (1 - 1e-9) - 8 eps sum |a_k|``, the room covering the rounding of those
sums, so ``r_A(W) + r_B(W) < gap``: the right side is positive for ``|w| >= W`` and
every crossing has ``|w| < W`` (the same estimate on ``Re s >= 0``, normalised by
``e^{t_0 s}``, puts every zero of ``F(.; delta)`` with ``Re s >= 0`` in ``|s| < W`` when
``A`` dominates). The bound is sharp: ``s^2 + 1`` against ``s`` crosses at
``w = (1 + sqrt 5)/2``, the root of ``r_A + r_B = gap``.

**Lipschitz bound.** ``h(w) = |A(i w)| - |B(i w)|`` has ``|h'| <= |A'| + |B'|``, bounded
on a segment (:class:`AxisLipschitz`): point terms by
:meth:`QuasiPolynomial.deriv_bound`, a kernel term ``c q(s) J_m(s)``,
``J_k = int nu^k N e^{-nu s} dnu``, by
``|c| (max|q'| min(M_m, V_m/|w|) + max|q| min(M_{m+1}, V_{m+1}/|w|))`` with
``M_k = int nu^k |N|`` and, for ``m = 0``, the total variations ``V_0`` of ``N`` and
``V_1 <= M_0 + b V_0`` of ``nu N`` (integration by parts, ``0 <= nu <= b``). Kernels
shared by ``A`` and ``B`` up to a constant (``+I_N`` and ``-I_N`` in the paper's loops)
are summed once per frequency. Values of ``h`` carry a bound of their rounding error:
``2^16 eps S`` on chirp-z grids (``GRID_ROUNDING``), ``64 eps S`` by direct sums
(``POINT_ROUNDING``), ``S`` the sum of the moduli of the terms.

**Derivatives of g.** With ``a_k = A^{(k)}(i w)`` (derivatives in ``s``) and ``b_k``
likewise, ::

    g'   = -2 Im(conj(a_0) a_1) + 2 Im(conj(b_0) b_1),
    g''  = 2 (|a_1|^2 - Re(conj(a_0) a_2)) - 2 (|b_1|^2 - Re(conj(b_0) b_2)),
    |g'''| <= 2 sum_P (3 |P'| |P''| + |P| |P'''|),

so with ``D_k >= sup_I |P^{(k)}(i w)|`` on a segment ``I`` (centre ``c``, radius ``r``;
the sum of the moduli of the terms of ``P^{(k)}`` at ``max_I |w|``, and
``D_0 = |P(i c)| + r D_1``), ``|g''| <= M_2 = 2 sum_P (D_1^2 + D_0 D_2)`` and
``|g'''| <= M_3 = 2 sum_P (3 D_1 D_2 + D_0 D_3)`` on ``I`` (:meth:`AxisGap.bounds`).
Values carry rounding levels ``e_0, e_1, e_2`` propagated from ``64 eps`` times the sums
of the moduli of the terms (direct sums, never chirp-z).
"""

from __future__ import annotations

import collections
import functools
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from math import comb

import numpy as np
from numpy.polynomial import polynomial as npoly
from numpy.typing import ArrayLike, NDArray

from ..bounds import TailBound, joint_degree, principal_gap
from ..distributed_delay import moment_integrals
from ..errors import CertificationError, ParameterError
from ..quasipoly import DistributedDelay, QuasiPolynomial

__all__ = [
    "AxisFunction",
    "AxisGap",
    "AxisJet",
    "AxisKernels",
    "AxisLipschitz",
    "frequency_bound",
    "is_zero",
    "required_frequency_bound",
]

_EPS = float(np.finfo(float).eps)
# Rounding of h on the search grid relative to the sum of the moduli of the terms (the
# chirp-z kernel sums err by up to about 1e4 eps).
GRID_ROUNDING = 2.0**16 * _EPS
# Rounding of a direct evaluation of A^(k)(i w) relative to the sum of the moduli of its terms.
POINT_ROUNDING = 64 * _EPS
# Direct evaluations run on chunks of fewer points than the evaluator's chirp-z threshold.
DIRECT_CHUNK = 32
# Room left below the principal gap for the rounding of the tail sums (relative, and
# in units of eps times the sum of the moduli of the principal coefficients).
_GAP_ROOM_REL, _GAP_ROOM_EPS = 1e-9, 8.0


# ============================================================================ results
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
        self.contents = [_content(u) for u in self.units]
        # the units with extra powers, looked up in _with_moment's cache once per evaluator (a look-up
        # hashes and compares the kernel's arrays)
        self._shifted: dict[tuple[int, int], DistributedDelay] = {}

    def sums(self, s: NDArray, extra: int) -> list[NDArray[np.complex128]]:
        """``J_{m+extra}(s)`` of every kernel (read-only arrays, remembered: :class:`_RememberedSums`)."""
        return _remembered_sum([self._shift(k, extra) for k in range(len(self.units))], self.contents, extra, s)

    def _shift(self, k: int, extra: int) -> DistributedDelay:
        """Unit ``k`` with ``extra`` more powers of ``nu`` (:func:`_with_moment`)."""
        shifted = self._shifted.get((k, extra))
        if shifted is None:
            shifted = self._shifted[(k, extra)] = _with_moment(self.units[k], extra)
        return shifted


def _content(unit: DistributedDelay) -> tuple:
    """Every stored number of ``unit`` as bytes (with types and shapes): equal for kernels summed alike.

    Formed once per kernel, it keys :class:`_RememberedSums` without hashing and comparing the
    kernel's arrays at every look-up.
    """
    arrays = (unit.nodes, unit.poly, unit.values, unit.pieces[2])
    return (
        unit.moment,
        unit.interpolation,
        unit.radius,
        unit.variation_radius,
        *(f"{a.dtype.str}{a.shape}".encode() + a.tobytes() for a in arrays),
    )


class _RememberedSums:
    """``shifted(s)``, ``shifted = _with_moment(unit, extra)``, computed once per equal kernel, moment and frequencies.

    The searches of a gain study evaluate one kernel (``I_N``, in loops rebuilt for every gain)
    on the same grids where they share a gain or a frequency bound: the sums are kept by kernel
    (equal values, not identity) and frequencies, read-only and the same numbers, up to
    :data:`_SUMS_KEPT_BYTES` of values (the least recently used go first). ``cache_clear``
    empties them, as for an ``lru_cache``.
    """

    def __init__(self) -> None:
        self._kept: collections.OrderedDict[tuple[tuple, int, str, tuple[int, ...], bytes], NDArray] = (
            collections.OrderedDict()
        )
        self._bytes = 0
        self._lock = threading.Lock()
        # on the instance only, as on an lru_cache (the class itself is no cache to empty)
        self.cache_clear: Callable[[], None] = self._forget

    def __call__(
        self, shifted: Sequence[DistributedDelay], contents: Sequence[tuple], extra: int, s: NDArray
    ) -> list[NDArray[np.complex128]]:
        """The sums at ``s`` of ``shifted``, units (stored numbers ``contents``, :func:`_content`) with
        ``extra`` more powers (:func:`_with_moment`); those not kept are summed together
        (:func:`~nrobust.distributed_delay.moment_integrals`: units on the same segments share their
        exponentials), the same numbers as each unit's own sum."""
        # equal kernels stored as real and as complex numbers are summed differently: the types enter the key
        where = (extra, s.dtype.str, s.shape, s.tobytes())
        keys = [(content, *where) for content in contents]
        with self._lock:
            values: list[NDArray | None] = [self._kept.get(key) for key in keys]
            for key, value in zip(keys, values):
                if value is not None:
                    self._kept.move_to_end(key)
        missing = [i for i, value in enumerate(values) if value is None]
        if not missing:
            return [v for v in values if v is not None]
        sums = moment_integrals([shifted[i] for i in missing], s, (0,))
        for i, row in zip(missing, sums):
            value = row[0].reshape(s.shape)
            value.flags.writeable = False
            values[i] = value
            if value.nbytes <= _SUMS_KEPT_BYTES // 4:
                with self._lock:
                    if keys[i] not in self._kept:
                        self._kept[keys[i]] = value
                        self._bytes += value.nbytes
                    while self._bytes > _SUMS_KEPT_BYTES:
                        self._bytes -= self._kept.popitem(last=False)[1].nbytes
        return [v for v in values if v is not None]

    def _forget(self) -> None:
        """Forget every kept sum."""
        with self._lock:
            self._kept.clear()
            self._bytes = 0


#: Bytes of kernel sums kept by :class:`_RememberedSums`.
_SUMS_KEPT_BYTES = 1 << 25
_remembered_sum = _RememberedSums()


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

    def __init__(self, A: QuasiPolynomial, B: QuasiPolynomial, *, kernels: AxisKernels | None = None) -> None:
        for name, P in (("A", A), ("B", B)):
            if not isinstance(P, QuasiPolynomial):
                raise ParameterError(name, "a QuasiPolynomial", type(P).__name__)
        self.kernels = AxisKernels((A, B)) if kernels is None else kernels
        self._points: list[tuple[QuasiPolynomial, QuasiPolynomial, QuasiPolynomial] | None] = []
        for P in (A, B):
            P0 = _point_part(P)
            if P0 is None:
                self._points.append(None)
            else:
                P1 = P0.derivative()
                self._points.append((P0, P1, P1.derivative()))
        self.scales = [_TermScale(P, self.kernels, side) for side, P in enumerate((A, B))]
        self.evaluations = 0

    def factor_jets(self, s: NDArray) -> NDArray[np.complex128]:
        """``P^{(k)}(s)`` for ``P = A, B`` and ``k = 0, 1, 2``, shape ``(2, 3, n)`` (direct sums)."""
        out = np.zeros((2, 3, s.size), dtype=complex)
        for lo in range(0, s.size, DIRECT_CHUNK):
            part = s[lo : lo + DIRECT_CHUNK]
            sums = [self.kernels.sums(part, k) for k in range(3)] if self.kernels.units else []
            for side in range(2):
                parts = self._points[side]
                if parts is not None:
                    for k in range(3):
                        out[side, k, lo : lo + part.size] = parts[k](part)
                for unit, c, q in self.kernels.terms[side]:
                    j0, j1, j2 = sums[0][unit], sums[1][unit], sums[2][unit]
                    v0: complex | NDArray
                    v1: complex | NDArray
                    v2: complex | NDArray
                    if q.size == 1:  # the usual term: q constant, its derivatives zero
                        v0, v1, v2 = complex(q[0]), 0.0, 0.0
                    else:
                        q1 = npoly.polyder(q)
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
        vals = self.factor_jets(1j * w)
        mod = np.abs(vals)
        rnd = np.stack([np.stack([POINT_ROUNDING * sc(w, k) for k in range(3)]) for sc in self.scales])
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
        for side, sc in enumerate(self.scales):
            d0, d1, d2, d3 = (sc(r, k) for k in range(4))
            if centre is not None:
                at_c = centre.moduli[side] + centre.rounding[side]
                d2 = np.minimum(d2, at_c[2] + rad * d3)
                d1 = np.minimum(d1, at_c[1] + rad * d2)
                d0 = np.minimum(d0, at_c[0] + rad * d1)
            m2 += 2.0 * (d1**2 + d0 * d2)
            m3 += 2.0 * (3.0 * d1 * d2 + d0 * d3)
        return m2 * (1.0 + 1e-12), m3 * (1.0 + 1e-12)


class AxisFunction:
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

    def factors(self, w: NDArray[np.float64], rounding: float = GRID_ROUNDING) -> tuple[NDArray, ...]:
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

    def with_rounding(self, w: NDArray[np.float64], rounding: float = GRID_ROUNDING) -> tuple[NDArray, NDArray]:
        """``h(w)`` and a bound of its rounding error (``rounding`` times the sum of the moduli of the terms)."""
        a, b, err_a, err_b = self.factors(w, rounding)
        return np.abs(a) - np.abs(b), err_a + err_b

    def direct(self, w: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """:meth:`with_rounding` by direct sums (chunks below the chirp-z threshold)."""
        out = [self.with_rounding(w[k : k + DIRECT_CHUNK], POINT_ROUNDING) for k in range(0, w.size, DIRECT_CHUNK)]
        if not out:
            return np.zeros(0), np.zeros(0)
        return np.concatenate([v for v, _ in out]), np.concatenate([e for _, e in out])


class AxisLipschitz:
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
    tail_a = TailBound(A, degree, 0.0, t0, second_order=True)
    tail_b = TailBound(B, degree, 0.0, t0, second_order=True)

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
