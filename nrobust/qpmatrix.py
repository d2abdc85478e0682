"""Square matrices of quasi-polynomials: the determinant as a characteristic function.

A matrix neutral equation with distributed delays (the characteristic equation of an
``n + m`` hyperbolic system, or of a state-space time-delay system) has a characteristic
function ``det M(s)`` with quasi-polynomial entries ``M_ij``. Expanding the determinant
multiplies distributed terms together, which the quasi-polynomial type does not
represent, so :class:`QuasiPolynomialMatrix` never expands it:

* ``det M(s)`` is computed from the evaluated entries (LU, ``numpy.linalg.det`` on the stacked
  matrices of many ``s`` at once; the point parts of all entries, and of their derivatives,
  are one matrix product of the weights ``e^{-tau_k s} s^p`` with a coefficient matrix);
* ``(det M)'(s) = tr(adj M(s) M'(s)) = sum_i det M^{(i)}(s)`` (Jacobi's formula), with
  ``M^{(i)}`` the matrix whose row ``i`` is replaced by the row of derivatives: ``n``
  determinants, valid where ``M`` is singular;
* bounds of ``|(det M)'|`` and ``|(det M)''|`` on a segment come from Hadamard's
  inequality ``|det X| <= prod_i ||X_i||_2`` applied to the terms of Jacobi's formula,
  with the entry bounds ``|M_ij^{(k)}| <= B^k_ij`` of :meth:`QuasiPolynomial.abs_bound`
  (``k = 0``) and :meth:`QuasiPolynomial.deriv_bound` (``k = 1, 2``); on short segments the
  bound of ``|(det M)'|`` is the first-order Taylor form ``|(det M)'(c)| + r M2`` about the
  midpoint ``c`` when smaller, which sees the cancellations of the determinant that
  Hadamard's inequality ignores (tenfold and more for a descriptor system).

Where the entries are real point quasi-polynomials, :meth:`QuasiPolynomialMatrix.exact_expansion`
expands ``det M`` in exact rational arithmetic instead and rounds it once
(:class:`ExpandedDeterminant`): a scalar quasi-polynomial whose bounds see every cancellation
(Taylor forms about a segment's midpoint with the remainder bounded in closed form), with a
proven bound of its distance to ``det M`` added to its derivative bounds, so that its
certified counts are counts of ``det M`` (Rouche).

That is the interface (:class:`CharacteristicFunction`) that the certified root counting
of :mod:`nrobust.roots` uses, so ``count_roots``, ``find_roots`` and ``spectral_abscissa``
take a matrix with the same guarantees as a scalar. The principal part of ``det M``
(for chains, strong stability, the spectral abscissa) is read from the determinant of
the point terms, expanded symbolically; it is refused when a distributed term could
reach the highest power of ``s``.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from math import comb, prod
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._validate import read_only, read_only_state, real_array
from .difference import DifferenceOperator
from .errors import ParameterError
from .quasipoly import QuasiPolynomial, as_quasipolynomial

__all__ = [
    "MAX_MATRIX_SIZE",
    "CharacteristicFunction",
    "ExpandedDeterminant",
    "FirstDerivative",
    "QuasiPolynomialMatrix",
]

#: Largest matrix size: the principal part expands n! products of point parts.
MAX_MATRIX_SIZE = 8
# Rounding allowance of a computed value relative to its rounding scale: the root counter's
# (nrobust.roots) allowance on the samples of F, used here on the samples of F'.
_ROUNDING = 64 * float(np.finfo(float).eps)
# Largest batch of points whose M and M' __call__ keeps for the deriv_at that follows (Newton's
# method evaluates both at a few hundred points at most; a plot's grid is not kept).
_KEPT = 4096
# deriv_bound evaluates (det M)' at the midpoint of a segment only where the remainder of its
# first-order Taylor bound is below this fraction of Hadamard's bound (elsewhere it rarely wins).
_TAYLOR_GAIN = 0.5
# Largest number of monomials ``c s^p e^{-tau s}`` of a minor in the exact expansion of a
# determinant (:meth:`QuasiPolynomialMatrix.exact_expansion`): beyond it the determinant is not
# expanded (the exact arithmetic would cost more than it saves); and the largest number of
# products of monomials (integer multiplications) of the whole expansion.
_MAX_MONOMIALS = 4000
_MAX_PRODUCTS = 200_000
# Unit roundoff of double precision (round to nearest).
_UNIT = 0.5 * float(np.finfo(float).eps)
# Terms L of the Taylor forms of the bounds of an expanded determinant's derivatives (ExpandedDeterminant):
# Example 2.9 finds its roots in 480 evaluations with 3, in 629, 516, 476 with 1, 2, 4.
_TAYLOR_TERMS = 3
_INVERSE_FACTORIALS = 1.0 / np.cumprod([1.0, *range(1, _TAYLOR_TERMS + 1)])
# Length over which the phase of e^{-tau s} may turn by 1 + tau in one initial step of the root counter
# (ExpandedDeterminant.initial_steps): steps this short spare the counter rounds of refinement.
_TURN = 1.0


@runtime_checkable
class CharacteristicFunction(Protocol):
    """What certified root counting needs of an analytic characteristic function ``F``.

    :class:`~nrobust.quasipoly.QuasiPolynomial` and :class:`QuasiPolynomialMatrix`
    (its determinant) implement it.
    """

    def __call__(self, s: ArrayLike) -> NDArray[np.complex128]:
        """``F(s)`` on an array of complex ``s``."""

    def deriv_at(self, s: ArrayLike) -> NDArray[np.complex128]:
        """``F'(s)``."""

    def deriv_bound(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        """Upper bound of ``|F'|`` on each segment ``[a, b]``."""

    def derivative(self) -> Any:
        """An object whose ``deriv_bound`` bounds ``|F''|`` on segments."""

    def magnitude(self, s: ArrayLike) -> NDArray[np.float64]:
        """Scale of the rounding error of ``F(s)`` (64 eps of it is the allowance)."""

    def principal_part(self) -> DifferenceOperator:
        """The difference operator of the highest power of ``s``."""

    @property
    def kind(self) -> str:
        """``"retarded"``, ``"neutral"`` or ``"advanced"``."""

    @property
    def is_real(self) -> bool:
        """True if ``F`` is real on the real axis (roots in conjugate pairs)."""

    @property
    def max_delay(self) -> float:
        """Largest delay."""


def _degree(q: QuasiPolynomial) -> float:
    """Highest power of ``s`` in ``q`` (point or distributed), ``-inf`` for zero."""
    degs = [p.size - 1 for p, _ in q.point_terms] + [d.poly.size - 1 for d in q.distributed]
    return float(max(degs)) if degs else -np.inf


def _zero_determinant() -> ParameterError:
    """The refusal of a principal part when the point determinant is identically zero."""
    return ParameterError("entries", "a point determinant not identically zero (it defines the principal part)", 0)


def _row_norms(bounds: NDArray[np.float64]) -> NDArray[np.float64]:
    """2-norms of the rows of entry bounds ``(..., n, n)``: ``(..., n)``."""
    return np.sqrt((bounds * bounds).sum(axis=-1))


def _hadamard_sums(
    r0: NDArray[np.float64], r1: NDArray[np.float64], r2: NDArray[np.float64] | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Sums of products of row scales ``(N, n)`` with one or two rows replaced.

    ``e1 = sum_i r1_i prod_{j != i} r0_j`` and ``e2 = sum_{i < k} r1_i r1_k prod_{j != i, k} r0_j``
    are the coefficients of ``t`` and ``t^2`` in ``prod_j (r0_j + t r1_j)``, and
    ``f1 = sum_i r2_i prod_{j != i} r0_j`` that of ``t`` in ``prod_j (r0_j + t r2_j)``
    (zero without ``r2``): the products are multiplied out column by column, in ``O(n)``
    passes, without division (zeros stay exact) and with nonnegative terms only.
    """
    c0 = np.ones(r0.shape[0])
    c1 = np.zeros(r0.shape[0])
    c2 = np.zeros(r0.shape[0])
    f1 = np.zeros(r0.shape[0])
    for j in range(r0.shape[1]):
        a, b = r0[:, j], r1[:, j]
        c2 = c2 * a + c1 * b
        if r2 is not None:
            f1 = f1 * a + c0 * r2[:, j]
        c1 = c1 * a + c0 * b
        c0 = c0 * a
    return c1, c2, f1


def _det(m: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Determinants of stacked matrices ``(..., n, n)``: the Leibniz sum written out for ``n <= 3``
    (a few array operations instead of one LAPACK call per matrix), LU beyond.

    The rounding error of the written-out sum is a few eps times the sum of the moduli of its
    products, below the LU allowance of :meth:`QuasiPolynomialMatrix.magnitude`.
    """
    n = m.shape[-1]
    if n == 1:
        return m[..., 0, 0].copy()  # not a view of ``m`` (the values a matrix keeps)
    if n == 2:
        return m[..., 0, 0] * m[..., 1, 1] - m[..., 0, 1] * m[..., 1, 0]
    if n == 3:
        a, b, c = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
        return (
            a * (m[..., 1, 1] * m[..., 2, 2] - m[..., 1, 2] * m[..., 2, 1])
            - b * (m[..., 1, 0] * m[..., 2, 2] - m[..., 1, 2] * m[..., 2, 0])
            + c * (m[..., 1, 0] * m[..., 2, 1] - m[..., 1, 1] * m[..., 2, 0])
        )
    return np.asarray(np.linalg.det(m))


def _leibniz(rows: Sequence[Sequence[QuasiPolynomial]]) -> QuasiPolynomial:
    """``det`` of a matrix of quasi-polynomials expanded by the Leibniz formula.

    Raises
    ------
    ParameterError
        A product holds two entries with distributed terms (not a quasi-polynomial of this type).
    """
    n = len(rows)
    total = QuasiPolynomial([[0.0]], [0.0])
    for perm in itertools.permutations(range(n)):
        factors = [rows[i][perm[i]] for i in range(n)]
        if any(not f.point_terms and not f.distributed for f in factors):
            continue
        if sum(bool(f.distributed) for f in factors) > 1:
            raise ParameterError(
                "entries", "at most one entry with distributed terms in each product of det (to expand it)", perm
            )
        term = factors[0]
        for f in factors[1:]:
            term = term * f
        total = total + term * float(np.linalg.det(np.eye(n)[list(perm)]))
    return total


_Terms = dict[tuple[float, int], complex]


def _point_expansion(rows: Sequence[Sequence[QuasiPolynomial]]) -> QuasiPolynomial:
    """``det`` of the point parts of a matrix of quasi-polynomials, expanded.

    The same sum as :func:`_leibniz` on the point parts, by Laplace expansion along the rows
    with the minors of the remaining rows memoised by their column sets (``2^n`` minors
    instead of ``n!`` products), on monomials ``c s^p e^{-tau s}`` held as a dictionary.
    """
    n = len(rows)
    entries: list[list[_Terms]] = []
    for row in rows:
        out_row = []
        for q in row:
            terms: _Terms = {}
            for p, t in q.point_terms:
                for k, c in enumerate(p.tolist()):
                    if c != 0:
                        terms[(t, k)] = c
            out_row.append(terms)
        entries.append(out_row)

    @functools.cache
    def minor(r: int, cols: int) -> tuple[tuple[tuple[float, int], complex], ...]:
        """The expanded determinant of rows ``r..n-1`` and the columns of the bit set ``cols``."""
        if r == n:
            return (((0.0, 0), 1.0),)
        total: _Terms = {}
        sign = 1.0
        for j in range(n):
            if not cols >> j & 1:
                continue
            entry = entries[r][j]
            if entry:
                rest = minor(r + 1, cols & ~(1 << j))
                for (t, k), c in entry.items():
                    for (u, m), d in rest:
                        key = (t + u, k + m)
                        total[key] = total.get(key, 0.0) + sign * c * d
            sign = -sign
        return tuple((key, c) for key, c in total.items() if c != 0)

    full = minor(0, (1 << n) - 1)
    minor.cache_clear()
    if not full:
        return QuasiPolynomial([[0.0]], [0.0])
    degree = max(k for (_, k), _ in full)
    polys: dict[float, list[complex]] = {}
    for (t, k), c in full:
        polys.setdefault(t, [0.0] * (degree + 1))[k] += c
    return QuasiPolynomial(list(polys.values()), list(polys))


@dataclass(frozen=True)
class _Exact:
    """``det M`` expanded exactly: the monomial ``(c / scale) s^p e^{-(t / unit) s}`` for each ``(t, p) -> c``.

    Every double is a dyadic rational, so with the delays in units of ``1 / unit`` and the
    entries of row ``i`` in units of ``1 / d_i`` (``unit`` and the ``d_i`` the largest
    denominators, powers of two) all numbers are integers and ``scale = prod d_i``.
    """

    terms: dict[tuple[int, int], int]
    unit: int
    scale: int


# The monomials ``(t, p, c)`` of ``c s^p e^{-t s}`` of each entry of a matrix, row by row.
_Monomials = list[list[list[tuple[float, int, float]]]]


def _exact_expansion(rows: Sequence[Sequence[QuasiPolynomial]]) -> _Exact | None:
    """``det`` of a matrix of real point quasi-polynomials expanded in exact arithmetic.

    The monomials ``c s^p e^{-t s}`` of the entries, expanded by :func:`_expand_monomials`.
    None if an entry has a distributed term or a complex coefficient, or when
    :func:`_expand_monomials` gives up.
    """
    monomials: _Monomials = []
    for row in rows:
        out_row = []
        for q in row:
            if q.distributed:
                return None
            mono = []
            for p, t in q.point_terms:
                if p.dtype.kind == "c" and np.any(p.imag != 0):
                    return None
                mono += [(t, k, c) for k, c in enumerate(p.real.tolist()) if c != 0]
            out_row.append(mono)
        monomials.append(out_row)
    return _expand_monomials(monomials)


def _array_monomials(coefs: NDArray[np.float64], delays: NDArray[np.float64]) -> _Monomials:
    """The monomials ``(t, p, c)`` (``c != 0``) of ``M_ij(s) = sum_k sum_p coefs[i, j, k, p] s^p e^{-delays[k] s}``."""
    n = coefs.shape[0]
    out: _Monomials = [[[] for _ in range(n)] for _ in range(n)]
    i, j, k, p = np.nonzero(coefs)
    for a, b, t, m, c in zip(i.tolist(), j.tolist(), delays[k].tolist(), p.tolist(), coefs[i, j, k, p].tolist()):
        out[a][b].append((t, m, c))
    return out


def _expand_monomials(entries: _Monomials) -> _Exact | None:
    """``det`` of the matrix whose entry ``(i, j)`` is the sum of the monomials ``c s^p e^{-t s}`` of ``entries[i][j]``.

    The floating-point coefficients and delays are dyadic rationals: scaled to integers
    (:class:`_Exact`), their products and sums are exact in Python's integers (Laplace
    expansion along the rows, minors memoised by their column sets, as
    :func:`_point_expansion`). None if a minor exceeds ``_MAX_MONOMIALS`` monomials or the
    expansion ``_MAX_PRODUCTS`` products.
    """
    n = len(entries)
    unit, dens, degree = 1, [], 0
    raw: list[list[list[tuple[int, int, int, int, int]]]] = []
    for row in entries:
        den, top = 1, 0
        raw_row = []
        for mono in row:
            ratios = []
            for t, k, c in mono:
                tn, td = float(t).as_integer_ratio()
                cn, cd = float(c).as_integer_ratio()
                if td > unit:  # (comparisons, not max(): a call per monomial)
                    unit = td
                if cd > den:
                    den = cd
                if k > top:
                    top = k
                ratios.append((tn, td, k, cn, cd))
            raw_row.append(ratios)
        raw.append(raw_row)
        dens.append(den)
        degree += top
    # a monomial's key packs (t, p) into t 2^bits + p: products add keys (the powers of a minor stay below 2^bits);
    # denominators are powers of two, the largest is a multiple of the others
    bits = degree.bit_length()
    rows = [
        [[((tn * (unit // td) << bits) + k, cn * (den // cd)) for tn, td, k, cn, cd in mono] for mono in raw_row]
        for raw_row, den in zip(raw, dens)
    ]
    # the nonzero entries of each row with the bits of their columns, and the entries negated (odd cofactors)
    nonzero = [
        [(1 << j, entry, [(key, -c) for key, c in entry]) for j, entry in enumerate(row) if entry] for row in rows
    ]
    # the minor of rows r..n-1 is keyed by its column set alone (r = n - the number of its columns)
    memo: dict[int, dict[int, int] | None] = {0: {0: 1}}
    products = 0

    def minor(r: int, cols: int) -> dict[int, int] | None:
        """The expanded determinant of rows ``r..n-1`` and the columns of the bit set ``cols``."""
        nonlocal products
        if cols in memo:
            return memo[cols]
        total: dict[int, int] = {}
        get = total.get
        for bit, entry, negated in nonzero[r]:
            if not cols & bit:
                continue
            rest = minor(r + 1, cols ^ bit)
            if rest is None:
                return None
            products += len(entry) * len(rest)
            if products > _MAX_PRODUCTS:
                return None
            # the column's place among cols: the cofactor's sign
            for key, c in negated if (cols & (bit - 1)).bit_count() & 1 else entry:
                for other, d in rest.items():
                    at = key + other
                    total[at] = get(at, 0) + c * d
        out = {key: c for key, c in total.items() if c != 0} if 0 in total.values() else total
        memo[cols] = out if len(out) <= _MAX_MONOMIALS else None
        return memo[cols]

    packed = minor(0, (1 << n) - 1)
    if packed is None:
        return None
    mask = (1 << bits) - 1
    return _Exact({(key >> bits, key & mask): c for key, c in packed.items()}, unit, prod(dens))


@dataclass(frozen=True)
class _Compiled:
    """The point parts of all entries as matrices: ``M(s) = sum_k e^{-tau_k s} sum_p C[k, p] s^p``.

    With the weights ``W(s)[k P + p] = e^{-tau_k s} s^p`` (``P`` powers, ``K`` delays) a
    batch of evaluations is one matrix product (a single BLAS call for many ``s``):

    * ``values``: ``(K P, 3 n^2)``, the coefficients of ``M``, ``M'``, ``M''``
      (``(p e^{-tau s})' = (p' - tau p) e^{-tau s}``), so that ``W(s) @ values`` holds them;
    * ``moduli``: ``(K P, 2 n^2)``, the moduli of those of ``M`` and ``M'``: with the
      weights ``e^{-tau_k Re s} |s|^p`` the rounding scales of ``M(s)`` and ``M'(s)``;
    * ``taylor``: ``(P, 3 (P - 1) K n^2)``, column ``(j, d, k, i, l)`` the coefficients
      (powers of ``s``) of ``q^{(j)} / j!``, ``j < P - 1``, for the polynomial ``q`` of
      ``e^{-tau_k s}`` in ``M_il^{(d)}``: the Taylor coefficients from which the bounds on
      discs are summed; ``constant``: ``(K, 3 n^2)``, column ``(d, i, l)`` the moduli of
      the constants ``q^{(P - 1)} / (P - 1)!``.

    ``dist`` lists the entries with distributed terms, as quasi-polynomials of those terms
    alone, and their first derivatives.
    """

    taus: NDArray[np.float64]  # (K,)
    values: NDArray[np.complex128]
    moduli: NDArray[np.float64]
    taylor: NDArray[np.complex128]
    constant: NDArray[np.float64]
    dist: tuple[tuple[int, int, QuasiPolynomial, QuasiPolynomial], ...]

    @property
    def powers(self) -> int:
        """``P``: the number of powers of ``s``."""
        return int(self.taylor.shape[0])

    def weights(self, s: NDArray[np.complex128]) -> NDArray[np.complex128]:
        """``W(s)``: ``e^{-tau_k s} s^p`` for flat ``s``, shape ``(N, K P)``."""
        return (np.exp(-s[:, None] * self.taus)[:, :, None] * _powers(s, self.powers)[:, None, :]).reshape(
            s.size, self.values.shape[0]
        )

    def scale_weights(self, s: NDArray[np.complex128]) -> NDArray[np.float64]:
        """``e^{-tau_k Re s} |s|^p`` for flat ``s``, shape ``(N, K P)``."""
        return (np.exp(-s.real[:, None] * self.taus)[:, :, None] * _powers(np.abs(s), self.powers)[:, None, :]).reshape(
            s.size, -1
        )


def _powers(s: NDArray, size: int) -> NDArray:
    """``s^p`` for ``p < size`` and flat ``s``: shape ``(N, size)``."""
    out = np.empty((s.size, size), dtype=s.dtype)
    out[:, 0] = 1.0
    for p in range(1, size):
        out[:, p] = out[:, p - 1] * s
    return out


def _compile(entries: tuple[tuple[QuasiPolynomial, ...], ...]) -> _Compiled:
    n = len(entries)
    taus = sorted({t for row in entries for e in row for _, t in e.point_terms} | {0.0})
    where = {t: i for i, t in enumerate(taus)}
    degree = max((p.size - 1 for row in entries for e in row for p, _ in e.point_terms), default=0)
    coef = np.zeros((len(taus), degree + 1, n, n), dtype=complex)
    dist = []
    for i, row in enumerate(entries):
        for j, e in enumerate(row):
            for p, t in e.point_terms:
                coef[where[t], : p.size, i, j] = p
            if e.distributed:
                d = QuasiPolynomial.from_parts((), e.distributed)
                dist.append((i, j, d, d.derivative()))
    tau = np.array(taus, dtype=float)
    K, P = coef.shape[:2]
    derivs = [coef]
    for _ in range(2):  # (p e^{-tau s})' = (p' - tau p) e^{-tau s}
        c = derivs[-1]
        dc = -tau[:, None, None, None] * c
        dc[:, :-1] += c[:, 1:] * np.arange(1, P)[None, :, None, None]
        derivs.append(dc)
    taylor = np.zeros((P, P, 3, K, n * n), dtype=complex)  # [power, j, d, k, entry]
    for order, c in enumerate(derivs):
        for j in range(P):  # p^{(j)} / j! = sum_m C(m, j) c_m s^(m - j)
            for m in range(j, P):
                taylor[m - j, j, order] = comb(m, j) * c[:, m].reshape(K, n * n)
    return _Compiled(
        taus=read_only(tau),
        values=read_only(np.concatenate([c.reshape(K * P, n * n) for c in derivs], axis=1)),
        moduli=read_only(np.abs(np.concatenate([c.reshape(K * P, n * n) for c in derivs[:2]], axis=1))),
        taylor=read_only(taylor[:, : P - 1].reshape(P, (P - 1) * 3 * K * n * n)),
        constant=read_only(np.abs(taylor[0, P - 1]).transpose(1, 0, 2).reshape(K, 3 * n * n)),
        dist=tuple(dist),
    )


@dataclass(frozen=True, eq=False)
class QuasiPolynomialMatrix:
    """A square matrix ``M(s)`` of quasi-polynomials, standing for ``det M(s)``.

    Calling it evaluates the determinant; ``deriv_at``, ``deriv_bound``,
    ``derivative()``, ``magnitude``, ``principal_part``, ``kind`` make it a
    :class:`CharacteristicFunction` for :func:`~nrobust.roots.count_roots`,
    :func:`~nrobust.roots.find_roots` and :func:`~nrobust.roots.spectral_abscissa`.

    Parameters
    ----------
    entries : sequence of sequences
        ``entries[i][j]``: a :class:`~nrobust.quasipoly.QuasiPolynomial` or a finite
        number (a constant), ``n x n`` with ``1 <= n <= 8``.

    Raises
    ------
    ParameterError
        Not square, empty, larger than ``8 x 8``, or an entry that is neither.

    Examples
    --------
    >>> from nrobust import QuasiPolynomial
    >>> s = QuasiPolynomial([[0, 1]], [0])
    >>> M = QuasiPolynomialMatrix([[s + 1, QuasiPolynomial([[1]], [1])], [0, s + 2]])
    >>> complex(M(0.0))
    (2+0j)
    """

    entries: tuple[tuple[QuasiPolynomial, ...], ...]

    def __init__(self, entries: Sequence[Sequence[Any]]) -> None:
        if isinstance(entries, (str, bytes)) or not isinstance(entries, Sequence | np.ndarray):
            raise ParameterError("entries", "a square sequence of rows", entries)
        rows = list(entries)
        n = len(rows)
        if not 1 <= n <= MAX_MATRIX_SIZE:
            raise ParameterError("entries", f"1 to {MAX_MATRIX_SIZE} rows", n)
        out = []
        for i, row in enumerate(rows):
            if isinstance(row, (str, bytes)) or not isinstance(row, Sequence | np.ndarray) or len(row) != n:
                raise ParameterError(f"entries[{i}]", f"a row of {n} entries (a square matrix)", row)
            out.append(tuple(as_quasipolynomial(f"entries[{i}][{j}]", e) for j, e in enumerate(row)))
        object.__setattr__(self, "entries", tuple(out))

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Unpickled or deep-copied: its arrays marked read-only again (numpy's pickles drop the flag)."""
        read_only_state(self, state)

    @classmethod
    def diagonal(cls, entries: Sequence[Any]) -> QuasiPolynomialMatrix:
        """The diagonal matrix with the given entries."""
        n = len(entries)
        return cls([[entries[i] if i == j else 0.0 for j in range(n)] for i in range(n)])

    # ------------------------------------------------------------------ structure
    @property
    def size(self) -> int:
        """The order ``n`` of the matrix."""
        return len(self.entries)

    def _flat(self) -> list[QuasiPolynomial]:
        return [e for row in self.entries for e in row]

    @functools.cached_property
    def is_real(self) -> bool:
        """True if every entry is real: ``det M`` is real on the real axis."""
        return all(e.is_real for e in self._flat())

    @functools.cached_property
    def max_delay(self) -> float:
        """Largest delay of an entry."""
        return float(max(e.max_delay for e in self._flat()))

    def point_determinant(self) -> QuasiPolynomial:
        """``det`` of the point parts of the entries, expanded (Leibniz): a quasi-polynomial.

        Where :meth:`exact_expansion` applies (real point entries), its rounding: every
        cancellation exact (a principal coefficient that cancels is 0, not a rounding residue);
        otherwise expanded in floating point.
        """
        return self._point_determinant

    @functools.cached_property
    def _point_determinant(self) -> QuasiPolynomial:
        exact = self.exact_expansion()
        return _point_expansion(self.entries) if exact is None else exact.poly

    @functools.cached_property
    def _compiled(self) -> _Compiled:
        return _compile(self.entries)

    def exact_expansion(self) -> ExpandedDeterminant | None:
        """``det M`` expanded exactly and rounded once, with the bound of the rounding (:class:`ExpandedDeterminant`).

        None when ``det M`` has no such expansion here: a distributed term, a complex
        coefficient, more than ``_MAX_MONOMIALS`` monomials in a minor, or a coefficient beyond
        the largest double. Computed once.
        """
        return self._exact

    @functools.cached_property
    def _exact(self) -> ExpandedDeterminant | None:
        terms = _exact_expansion(self.entries)
        if terms is None:
            return None
        try:
            return ExpandedDeterminant(self, terms)
        except OverflowError:  # a coefficient beyond the doubles: no rounding of the expansion
            return None

    def expand(self) -> QuasiPolynomial:
        """``det M`` expanded as one quasi-polynomial (Leibniz formula).

        Raises
        ------
        ParameterError
            A product of the expansion holds two entries with distributed terms (the
            product of two distributed terms is not a quasi-polynomial of this type).
        """
        return _leibniz(self.entries)

    def _principal_source(self) -> QuasiPolynomial:
        """The expanded point determinant, checked to carry the highest power of ``s`` of ``det M``.

        A product of the Leibniz expansion with a distributed factor ``q(s) int N e^{-nu s}``
        is ``O(|s|^(e - 1))`` in a vertical strip, with ``e`` the sum of the entry degrees
        ``max(deg p, deg q)`` along the permutation (``int N e^{-nu s} = O(1/|s|)`` for
        ``N`` of bounded variation); so if the point determinant has degree at least the
        largest such sum, the distributed terms stay out of its principal part.
        """
        return self._principal

    @functools.cached_property
    def _principal(self) -> QuasiPolynomial:
        P = self.point_determinant()
        if not P.point_terms:
            raise _zero_determinant()
        if any(e.distributed for e in self._flat()):
            deg = np.array([[_degree(e) for e in row] for row in self.entries])
            n = self.size
            top = max(sum(deg[i, p[i]] for i in range(n)) for p in itertools.permutations(range(n)))
            if P.degree < top:
                raise ParameterError(
                    "entries",
                    f"a point determinant of degree >= {top:g} (the degree bound of det M): "
                    "otherwise a distributed term may enter the principal part",
                    P.degree,
                )
        return P

    @property
    def kind(self) -> str:
        """``"retarded"``, ``"neutral"`` or ``"advanced"``: the type of ``det M``."""
        return self._principal_source().kind

    def principal_part(self) -> DifferenceOperator:
        """Principal part of ``det M``: that of the expanded point determinant.

        For a matrix difference operator ``I - sum_k A_k e^{-tau_k s}`` times ``s`` this is
        ``det(I - sum_k A_k e^{-tau_k s})`` (Hale and Verduyn Lunel). Built once (the
        matrix and the operator are immutable).
        """
        return self._principal_operator

    @functools.cached_property
    def _principal_operator(self) -> DifferenceOperator:
        return self._principal_source().principal_part()

    # ------------------------------------------------------------------ evaluation
    # The point parts of all entries are evaluated together by one matrix product
    # (:class:`_Compiled`), the distributed terms entry by entry.
    def _tensor_values(
        self, s: NDArray[np.complex128], orders: int, weights: NDArray[np.complex128] | None = None
    ) -> NDArray[np.complex128]:
        """``M^{(d)}(s)`` for ``d < orders`` (at most 3) on flat ``s``: shape ``(N, orders, n, n)``
        (``weights``: ``W(s)`` of :class:`_Compiled` when already at hand)."""
        c = self._compiled
        n = self.size
        w = c.weights(s) if weights is None else weights
        out = (w @ c.values[:, : orders * n * n]).reshape(s.size, orders, n, n)
        for i, j, d, dd in c.dist:
            out[:, 0, i, j] += d(s)
            if orders > 1:
                out[:, 1, i, j] += d.deriv_at(s)
            if orders > 2:
                out[:, 2, i, j] += dd.deriv_at(s)
        return out

    def values(self, s: ArrayLike) -> NDArray[np.complex128]:
        """The entries ``M_ij(s)``: an array of shape ``s.shape + (n, n)``."""
        s = np.asarray(s, dtype=complex)
        n = self.size
        return self._tensor_values(s.ravel(), 1).reshape(*s.shape, n, n)

    def __call__(self, s: ArrayLike) -> NDArray[np.complex128]:
        """``det M(s)`` on an array of complex ``s``.

        Without distributed terms ``M'(s)`` comes with ``M(s)`` at almost no cost; for a
        batch of at most ``_KEPT`` points both are kept (:meth:`_kept_values`) for a
        :meth:`deriv_at` at the same points, the pattern of Newton's method, and the weights
        for the :meth:`magnitude` that the root counter asks next.
        """
        s = np.asarray(s, dtype=complex)
        flat = s.ravel()
        v = self._kept_values(flat)
        return np.asarray(_det(v[:, 0]), dtype=complex).reshape(s.shape)

    def _kept_values(self, flat: NDArray[np.complex128]) -> NDArray[np.complex128]:
        """``M`` and ``M'`` at ``flat`` (only ``M`` with distributed terms or more than ``_KEPT`` points);
        without distributed terms and up to ``_KEPT`` points, the last batch and its weights are kept."""
        last = self.__dict__.get("_last")
        if last is not None and np.array_equal(last[0], flat):
            return np.asarray(last[1])
        if self._compiled.dist or flat.size > _KEPT:
            return self._tensor_values(flat, 1)
        w = self._compiled.weights(flat)
        v = self._tensor_values(flat, 2, w)
        object.__setattr__(self, "_last", (read_only(flat.copy()), read_only(v), read_only(w)))
        return v

    def deriv_at(self, s: ArrayLike) -> NDArray[np.complex128]:
        """``(det M)'(s) = sum_i det M^{(i)}(s)`` (Jacobi's formula, row by row)."""
        s = np.asarray(s, dtype=complex)
        flat = s.ravel()
        v = self._kept_values(flat)
        if v.shape[1] < 2:
            v = self._tensor_values(flat, 2)
        row = np.eye(self.size, dtype=bool)[:, None, :, None]  # M^{(i)}: row i from M'
        mi = np.where(row, v[None, :, 1], v[None, :, 0])
        return np.asarray(_det(mi).sum(axis=0), dtype=complex).reshape(s.shape)

    def _entry_bounds(self, a: NDArray, b: NDArray) -> NDArray[np.float64]:
        """Bounds of ``|M_ij^{(d)}|`` (``d = 0, 1, 2``) on the segments ``[a, b]`` (flat): ``(N, 3, n, n)``.

        A point part ``sum_k q_k(s) e^{-tau_k s}`` (``q_k`` the polynomials of the
        ``d``-th derivative) is bounded by ``sum_k max|q_k| e^{-tau_k x_min}``, the
        polynomial maxima by the Taylor sum ``sum_j |q_k^{(j)}(c)| r^j / j!`` about the
        midpoint ``c`` (as :meth:`QuasiPolynomial.abs_bound`): all ``q_k^{(j)}(c)`` are one
        matrix product; distributed terms by their own bounds.
        """
        c = self._compiled
        n, size, K = self.size, c.powers, c.taus.size
        center, radius = 0.5 * (a + b), 0.5 * np.abs(b - a)
        decay = np.exp(-np.minimum(a.real, b.real)[:, None] * c.taus)  # (N, K)
        power = _powers(radius, size)
        out = ((power[:, -1:] * decay) @ c.constant).reshape(a.size, 3, n, n)
        if size > 1:
            poly = np.abs(_powers(center, size) @ c.taylor).reshape(a.size, size - 1, 3, K, n * n)
            for j in range(size - 1):
                weight = (power[:, j : j + 1] * decay).reshape(a.size, 1, 1, K)
                out += (weight @ poly[:, j]).reshape(a.size, 3, n, n)
        for i, j, d, dd in c.dist:
            out[:, 0, i, j] += d.abs_bound(a, b)
            out[:, 1, i, j] += d.deriv_bound(a, b)
            out[:, 2, i, j] += dd.deriv_bound(a, b)
        return out

    def _hadamard_bounds(self, a: NDArray, b: NDArray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Bounds of ``|(det M)'|`` and ``|(det M)''|`` on the segments (flat) by Hadamard's inequality.

        ``|(det M)'| <= sum_i ||B1_i|| prod_{k != i} ||B0_k||`` on each term of Jacobi's formula;
        ``(det M)'' = sum_i det M^{(ii)} + sum_{i != k} det M^{(ik)}`` (row ``i`` replaced
        by second derivatives, or rows ``i`` and ``k`` by first derivatives), each term
        bounded the same way. ``Bd`` are the entry bounds of ``|M^{(d)}|`` on the segment
        (:meth:`_entry_bounds`) and ``||.||`` the 2-norm of a row.
        """
        r = _row_norms(self._entry_bounds(a, b))  # (N, 3, n)
        first, pairs, rows2 = _hadamard_sums(r[:, 0], r[:, 1], r[:, 2])
        return first, rows2 + 2.0 * pairs  # each unordered pair {i, k} twice: M^{(ik)} and M^{(ki)}

    def _scales(self, s: NDArray[np.complex128], orders: int) -> NDArray[np.float64]:
        """Entry scales of ``M^{(d)}(s)`` for ``d < orders <= 2`` on flat ``s``: ``(N, orders, n, n)``.

        The rounding scale of an entry: its terms evaluated at ``|s|`` and ``e^{-tau Re s}``
        with the moduli of their coefficients (``|W(s)|``: the moduli of the kept weights when
        ``s`` is the batch :meth:`_kept_values` kept).
        """
        c = self._compiled
        n = self.size
        last = self.__dict__.get("_last")
        weights = np.abs(last[2]) if last is not None and np.array_equal(last[0], s) else c.scale_weights(s)
        mags = (weights @ c.moduli[:, : orders * n * n]).reshape(s.size, orders, n, n)
        for i, j, d, dd in c.dist:
            mags[:, 0, i, j] += d.magnitude(s)
            if orders > 1:
                mags[:, 1, i, j] += dd.magnitude(s)
        return mags

    def _deriv_magnitude(self, s: NDArray[np.complex128]) -> NDArray[np.float64]:
        """Rounding scale of :meth:`deriv_at` on flat ``s``, as :meth:`magnitude` is that of ``det M``.

        Each term ``det M^{(i)}`` of Jacobi's formula is an LU determinant of a matrix
        with row scales ``sum_j m_kj`` (``k != i``) and ``sum_j m'_ij`` (``m'`` the entry
        scales of ``M'``): ``n 2^(n-1) sum_i sum_j m'_ij prod_{k != i} sum_j m_kj``, times
        ``1 + tau_max |s|`` for the rounding of the exponents ``tau s``.
        """
        rows = self._scales(s, 2).sum(axis=-1)  # (N, 2, n)
        n = self.size
        return (
            n * 2.0 ** (n - 1) * _hadamard_sums(rows[:, 0], rows[:, 1])[0] * (1.0 + self._compiled.taus[-1] * np.abs(s))
        )

    def deriv_bound(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        """Upper bound of ``|(det M)'|`` on each segment ``[a, b]``: the smaller of two bounds.

        * ``sum_i ||B1_i|| prod_{k != i} ||B0_k||`` (Hadamard's inequality on each term of
          Jacobi's formula, :meth:`_hadamard_bounds`), ``B0``, ``B1`` the entry bounds of
          ``|M|``, ``|M'|`` on the segment and ``||.||`` the 2-norm of a row;
        * ``|(det M)'(c)| + r M2`` with ``c`` the midpoint, ``r`` the half-length and ``M2``
          the bound of ``|(det M)''|`` on the segment (:meth:`second_deriv_bound`):
          ``(det M)'(s) = (det M)'(c) + int_c^s (det M)''``. The value at ``c``
          (:meth:`deriv_at`) is raised by ``64 eps`` times its rounding scale
          (:meth:`_deriv_magnitude`). It is evaluated only where ``r M2`` is below half of
          the first bound.

        The first ignores the cancellations of the determinant (it bounds every product of
        its expansion); the second sees them and tends to ``|(det M)'(c)|`` as the segment
        shrinks, so that near a nearly singular ``M`` the counter needs fewer steps.
        """
        a = np.asarray(a, dtype=complex)
        shape = a.shape
        a = a.ravel()
        b = np.asarray(b, dtype=complex).ravel()
        first, second = self._hadamard_bounds(a, b)
        tail = 0.5 * np.abs(b - a) * second
        short = np.flatnonzero(tail < _TAYLOR_GAIN * first)
        if short.size:
            center = 0.5 * (a[short] + b[short])
            at_center = np.abs(self.deriv_at(center)) + _ROUNDING * self._deriv_magnitude(center)
            first[short] = np.minimum(first[short], at_center + tail[short])
        return np.asarray(first, dtype=float).reshape(shape)

    def second_deriv_bound(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        """Upper bound of ``|(det M)''|`` on each segment ``[a, b]``.

        ``(det M)'' = sum_i det M^{(ii)} + sum_{i != k} det M^{(ik)}``: row ``i`` replaced
        by second derivatives, or rows ``i`` and ``k`` by first derivatives; each term is
        bounded by Hadamard's inequality (:meth:`_hadamard_bounds`).
        """
        a = np.asarray(a, dtype=complex)
        shape = a.shape
        _, second = self._hadamard_bounds(a.ravel(), np.asarray(b, dtype=complex).ravel())
        return np.asarray(second, dtype=float).reshape(shape)

    def derivative(self) -> FirstDerivative:
        """``(det M)'`` as a function with a bound of its own derivative (for the order-2 step rule)."""
        return FirstDerivative(self)

    def magnitude(self, s: ArrayLike) -> NDArray[np.float64]:
        """Rounding scale of ``det M(s)``: ``n 2^(n-1) prod_i sum_j m_ij(s)``, ``m_ij`` the entry scales.

        ``prod_i sum_j m_ij`` bounds the sum of the moduli of all products of the Leibniz
        expansion; ``2^(n-1)`` is the growth factor bound of LU with partial pivoting.
        """
        s = np.asarray(s, dtype=complex)
        mags = self._scales(s.ravel(), 1).reshape(*s.shape, self.size, self.size)
        n = self.size
        return np.asarray(n * 2.0 ** (n - 1) * mags.sum(axis=-1).prod(axis=-1), dtype=float)

    # ------------------------------------------------------------------ output
    def __repr__(self) -> str:
        rows = "; ".join(", ".join(repr(e)[len("QuasiPolynomial(") : -1] for e in row) for row in self.entries)
        return f"QuasiPolynomialMatrix([{rows}])"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, QuasiPolynomialMatrix):
            return NotImplemented
        return self.entries == other.entries

    def __hash__(self) -> int:
        return hash(self.entries)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description: the entries as quasi-polynomials."""
        return {"entries": [[e.to_dict() for e in row] for row in self.entries]}


class FirstDerivative:
    """``F'`` of a characteristic function for the order-2 step rule of the root counter.

    Values from ``F.deriv_at`` and bounds of ``|F''|`` on segments from
    ``F.second_deriv_bound``: what :meth:`CharacteristicFunction.derivative` returns for a
    determinant (:class:`QuasiPolynomialMatrix`) and for the ``n + m`` loops.
    """

    def __init__(self, F: Any) -> None:
        self.F = F

    def __call__(self, s: ArrayLike) -> NDArray[np.complex128]:
        return self.F.deriv_at(s)

    def deriv_bound(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        return self.F.second_deriv_bound(a, b)


class ExpandedDeterminant:
    """``det M`` of a :class:`QuasiPolynomialMatrix` as one quasi-polynomial, with a proven distance to it.

    The determinant of a matrix of real point quasi-polynomials is a quasi-polynomial
    ``P(s) = sum c_i s^p_i e^{-tau_i s}`` whose coefficients and delays are exact rationals
    (sums of products of the entries' floating-point numbers, :func:`_exact_expansion`). Its
    rounding ``Q`` (each delay rounded to the nearest double, the coefficients of the monomials
    that share a rounded delay and power summed exactly and rounded once) is evaluated and
    bounded as a scalar quasi-polynomial ``Q(s) = sum_k q_k(s) e^{-tau_k s}``: the symbolic
    expansion cancels the products of the Leibniz sum that the bounds of the matrix form
    (Hadamard's inequality on the rows) cannot see, so the bounds of ``|Q'|`` on a contour
    step are tighter, by orders of magnitude for a descriptor matrix, and an evaluation costs
    a sum of monomials instead of ``n`` determinants.

    The derivatives ``Q^{(j)} = sum_k q_{jk}(s) e^{-tau_k s}`` (``q_{j+1,k} = q_{jk}' - tau_k
    q_{jk}``) are held as one coefficient matrix, so that the weights ``e^{-tau_k s} s^p`` of a
    batch of points give all of them in one matrix product. On a segment with midpoint ``c``,
    half-length ``r`` and least real part ``x`` two bounds of ``|Q^{(j)}|`` are at hand
    (:meth:`_bounds`):

    * the closed form ``B_j = sum_k e^{-tau_k x} sum_p |q_{jk,p}| (|c| + r)^p`` (every monomial by
      its modulus, ``|s| <= |c| + r`` on the segment: no cancellation at all);
    * the Taylor form ``sum_{m < L} |Q^{(j+m)}(c)| r^m / m! + B_{j+L} r^L / L!`` (Taylor's
      formula along the segment, the remainder bounded by the closed form), which sees the
      cancellations of ``Q`` and tends to ``|Q^{(j)}(c)|`` as the segment shrinks;

    the smallest of ``B_j`` and of the Taylor forms with ``L = 1, 2, 3`` is kept. The values at
    ``c`` are raised by their rounding allowance, and the sums of nonnegative terms by theirs.

    With ``u = 2^-53`` the rounding unit, ``|c - c~| <= u |c~|`` and
    ``|e^{-tau s} - e^{-tau~ s}| <= e^{-tau~ Re s} (e^{u tau~ |s|} - 1) <= 2 u tau~ |s| e^{-tau~ Re s}``
    (for ``u tau~ |s| <= 1``), so ``|P(s) - Q(s)| <= 2 u sum_j w_j (1 + tau_j |s|) |s|^p_j
    e^{-tau_j Re s} =: G(s)``, ``w_j`` the sum of the moduli of the exact coefficients of the
    group ``j`` (rounded up). :meth:`gap` bounds ``G`` on a segment. The root counter accepts
    a step by ``M |h| / 2 < room`` (order 1) or ``M2 |h|^2 / 2 + slack < dist`` (order 2);
    :meth:`deriv_bound` returns ``M + 2 gap / |h|`` and the bound of ``derivative()`` is
    ``M2 + 2 gap / |h|^2``, so an accepted step has ``|Q| > gap >= |P - Q|`` all along. On
    the whole contour then ``|P - Q| < |Q|``: the argument of ``P / Q`` stays in
    ``(-pi/2, pi/2)`` and ``P`` winds as ``Q`` does (Rouche), so every count is one of
    ``det M``. For proofs in ball arithmetic use the matrix itself (its ball determinant).

    Parameters
    ----------
    matrix : QuasiPolynomialMatrix
        The matrix ``M``.
    exact : _Exact
        The exact expansion (:func:`_exact_expansion`): integer monomials with their units.

    :meth:`from_coefficients` expands ``det M`` from the coefficient array of ``M`` instead,
    without building the matrix of quasi-polynomials (built on first use of :attr:`matrix`).
    """

    def __init__(self, matrix: QuasiPolynomialMatrix, exact: _Exact) -> None:
        self._matrix: QuasiPolynomialMatrix | None = matrix
        self._source: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self._setup(exact)

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Unpickled or deep-copied: its arrays marked read-only again (numpy's pickles drop the flag)."""
        read_only_state(self, state)

    @classmethod
    def from_coefficients(cls, coefs: ArrayLike, delays: ArrayLike) -> ExpandedDeterminant | None:
        """``det M`` of ``M_ij(s) = sum_k sum_p coefs[i, j, k, p] s^p e^{-delays[k] s}``, expanded exactly.

        The same expansion as ``QuasiPolynomialMatrix(QuasiPolynomial.from_coefficient_array(coefs,
        delays)).exact_expansion()``, from the array itself: the quasi-polynomial entries are
        not built (:attr:`matrix` builds them when asked for).

        Parameters
        ----------
        coefs : array_like, shape (n, n, K, P)
            Finite real coefficients (powers of ``s`` increasing), ``1 <= n <= 8``.
        delays : array_like, shape (K,)
            Distinct finite delays ``>= 0``.

        Returns
        -------
        ExpandedDeterminant or None
            None when :meth:`QuasiPolynomialMatrix.exact_expansion` would give None (too many
            monomials, or a coefficient beyond the largest double).

        Raises
        ------
        ParameterError
            ``coefs`` not of shape ``(n, n, K, P)`` with ``1 <= n <= 8``, ``P >= 1``, or
            ``delays`` not ``K`` distinct numbers ``>= 0``.
        """
        c = real_array("coefs", coefs, ndim=4)
        t = real_array("delays", delays)
        n = c.shape[0]
        if not (1 <= n <= MAX_MATRIX_SIZE and c.shape[1] == n and c.shape[3] >= 1):
            raise ParameterError(
                "coefs", f"an array of shape (n, n, K, P), 1 <= n <= {MAX_MATRIX_SIZE}, P >= 1", c.shape
            )
        if t.shape != (c.shape[2],) or np.any(t < 0) or len(set(t.tolist())) != t.size:
            raise ParameterError("delays", f"{c.shape[2]} distinct delays >= 0 (one per row of coefs)", delays)
        exact = _expand_monomials(_array_monomials(c, t))
        if exact is None:
            return None
        obj = cls.__new__(cls)
        obj._matrix, obj._source = None, (read_only(c), read_only(t))
        try:
            obj._setup(exact)
        except OverflowError:  # a coefficient beyond the doubles: no rounding of the expansion
            return None
        return obj

    @property
    def matrix(self) -> QuasiPolynomialMatrix:
        """The matrix ``M`` (built on first use after :meth:`from_coefficients`)."""
        if self._matrix is None:
            assert self._source is not None  # one of the two is set by the constructors
            self._matrix = QuasiPolynomialMatrix(QuasiPolynomial.from_coefficient_array(*self._source))
        return self._matrix

    def _setup(self, exact: _Exact) -> None:
        """The rounded coefficients, their derivatives and the sums of moduli of the bounds, from ``exact``."""
        groups: dict[tuple[float, int], tuple[int, int]] = {}
        for (t, k), c in exact.terms.items():
            key = (t / exact.unit, k)  # int / int: correctly rounded
            total, size = groups.get(key, (0, 0))
            groups[key] = (total + c, size + abs(c))
        taus = sorted({t for t, _ in groups} | {0.0})
        power = max((k for _, k in groups), default=0) + 1
        coef = np.zeros((len(taus), power))
        weight = np.zeros((len(taus), power))
        where = {t: i for i, t in enumerate(taus)}
        at = ([where[tau] for tau, _ in groups], [k for _, k in groups])
        coef[at] = [total / exact.scale for total, _ in groups.values()]
        weight[at] = [size / exact.scale * (1.0 + 4.0 * _UNIT) for _, size in groups.values()]  # rounded up
        self._coef = read_only(coef)
        self._taus = read_only(np.array(taus))
        self._weight = read_only(weight)
        K, P = coef.shape
        J = _TAYLOR_TERMS + 3  # Q, Q', ..., Q^{(L + 2)}
        derivs = [coef]
        minus_tau, powers = -self._taus[:, None], np.arange(1.0, P)
        for _ in range(J - 1):  # (q e^{-tau s})' = (q' - tau q) e^{-tau s}
            last = derivs[-1]
            nxt = minus_tau * last
            nxt[:, :-1] += last[:, 1:] * powers
            derivs.append(nxt)
        stack = np.array(derivs).transpose(1, 2, 0).reshape(K * P, J)  # row k P + p, column j
        # W(s) @ _values: Q^{(j)}(s) for j < J, with W(s)[k P + p] = e^{-tau_k s} s^p
        self._values = read_only(stack.astype(complex))
        # |W| @ _moduli: the sums of the moduli of the monomials of Q^{(j)}, then the two sums of the gap
        self._moduli = read_only(
            np.column_stack([np.abs(stack), weight.ravel(), (self._taus[:, None] * weight).ravel()])
        )
        # rounding allowance of a value (relative to the sum of the moduli of its terms, times 1 + tau |s|):
        # the weights (P products and an exponential) and the sum of K P products
        self._allowance = max(_ROUNDING, 2.0 * _UNIT * (K * P + 2 * P + 8))
        self._last: list[tuple[NDArray[np.complex128], NDArray[np.complex128], NDArray[np.complex128]]] = []

    def _weights(self, s: NDArray[np.complex128]) -> NDArray[np.complex128]:
        """``W(s)``: ``e^{-tau_k s} s^p`` for flat ``s``, shape ``(N, K P)``."""
        K, P = self._weight.shape
        return (np.exp(-s[:, None] * self._taus)[:, :, None] * _powers(s, P)[:, None, :]).reshape(s.size, K * P)

    def _batch(self, s: ArrayLike) -> tuple[NDArray[np.complex128], NDArray[np.complex128], NDArray[np.complex128]]:
        """Flat ``s``, ``W(s)`` and ``(Q(s), Q'(s))`` as ``(N, 2)``; the last two batches are kept (Newton's
        method asks ``Q`` and ``Q'`` at the same points, the root counter ``Q`` and its rounding scale, the
        root finder ``|Q|`` at the roots it merged two batches before)."""
        flat = np.asarray(s, dtype=complex).ravel()
        for kept in self._last:
            if kept[0].shape == flat.shape and np.logical_and.reduce(kept[0] == flat):
                return kept
        w = self._weights(flat)
        kept = (read_only(flat.copy()), read_only(w), read_only(w @ self._values[:, :2]))
        if flat.size <= _KEPT:
            self._last = [kept, *self._last[:1]]
        return kept

    def initial_steps(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.intp]:
        """Steps to start the count of each segment ``[a, b]`` from (the root counter's ``F.initial_steps``).

        The length over ``_TURN / (1 + tau_max)``: the phase of ``e^{-tau s}`` turns by ``tau`` per
        unit of a vertical edge, and a first step far longer than the certified steps costs the
        counter rounds of refinement. Only the work depends on it: every step is still certified.
        """
        length = np.abs(np.subtract(b, a))
        return np.asarray(np.ceil(length * (1.0 + self._taus[-1]) / _TURN), dtype=np.intp)

    def gap(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        """Upper bound of ``|det M - Q|`` on each segment ``[a, b]``: ``G`` (class docstring) at
        ``|s| <= max(|a|, |b|)`` and ``Re s >= min(Re a, Re b)``, raised by 1 % for its own rounding."""
        a = np.asarray(a, dtype=complex)
        b = np.asarray(b, dtype=complex)
        big = np.maximum(np.abs(a), np.abs(b)).ravel()
        xmin = np.minimum(a.real, b.real).ravel()
        decay = np.exp(-xmin[:, None] * self._taus) * (1.0 + self._taus * big[:, None])  # (N, K)
        total = ((decay @ self._weight) * _powers(big, self._weight.shape[1])).sum(axis=1)
        bad = _UNIT * self._taus[-1] * big > 1.0
        out = np.where(bad, np.inf, 2.02 * _UNIT * total)
        return out.reshape(np.broadcast(a, b).shape)

    def __call__(self, s: ArrayLike) -> NDArray[np.complex128]:
        """``Q(s)``."""
        return self._batch(s)[2][:, 0].reshape(np.shape(s)).copy()  # not a view of the kept batch

    def deriv_at(self, s: ArrayLike) -> NDArray[np.complex128]:
        """``Q'(s)``."""
        return self._batch(s)[2][:, 1].reshape(np.shape(s)).copy()

    def magnitude(self, s: ArrayLike) -> NDArray[np.float64]:
        """Rounding scale of ``Q(s)``: the sum of the moduli of its monomials."""
        return (np.abs(self._batch(s)[1]) @ self._moduli[:, 0]).reshape(np.shape(s))

    def _bounds(self, a: ArrayLike, b: ArrayLike, order: int) -> NDArray[np.float64]:
        """Bound of ``|Q^{(order)}|`` (``order`` 1 or 2) on each segment ``[a, b]``: the least of the
        closed form and the Taylor forms (class docstring), plus the margin ``2 gap / |b - a|^order``.

        Two matrix products give the values at the midpoints ``c`` (rows ``W(c)``, complex) and the
        closed forms and ``G`` (rows ``e^{-tau_k x} (|c| + r)^p``, real; ``G`` at ``|s| <= |c| + r``). A value at
        ``c`` is raised by its rounding allowance times the closed form, which exceeds the sum of
        the moduli of its terms.
        """
        a = np.asarray(a, dtype=complex)
        shape = a.shape
        a = a.ravel()
        b = np.asarray(b, dtype=complex).ravel()
        N, (K, P), J, L = a.size, self._weight.shape, _TAYLOR_TERMS + 3, _TAYLOR_TERMS
        center, half = 0.5 * (a + b), 0.5 * np.abs(b - a)
        big = np.abs(center) + half  # |s| <= big on the segment
        xmin = np.minimum(a.real, b.real)
        at = (np.exp(-center[:, None] * self._taus)[:, :, None] * _powers(center, P)[:, None, :]).reshape(N, K * P)
        # real rows e^{-tau_k x} big^p: the closed forms B_j (j < J) and the two sums of G
        bounds = (np.exp(-xmin[:, None] * self._taus)[:, :, None] * _powers(big, P)[:, None, :]).reshape(N, K * P)
        moduli = bounds @ self._moduli
        closed = moduli[:, :J] * (1.0 + self._allowance)
        sums = moduli[:, J:]
        # Q^{(j)}(c) (j = order .. order + L - 1) raised by its rounding allowance
        at_center = np.abs(at @ self._values[:, order : order + L])
        at_center += (self._allowance * (1.0 + self._taus[-1] * big))[:, None] * closed[:, order : order + L]
        # partial Taylor sums plus the closed form of the remainder: r^m / m! for m <= L
        factor = _powers(half, L + 1) * _INVERSE_FACTORIALS
        taylor = np.cumsum(at_center * factor[:, :L], axis=1) + closed[:, order + 1 : order + L + 1] * factor[:, 1:]
        best = np.minimum(closed[:, order], taylor.min(axis=1) * (1.0 + self._allowance))
        gap = 2.02 * _UNIT * (sums[:, 0] + big * sums[:, 1])
        gap[_UNIT * self._taus[-1] * big > 1.0] = np.inf
        length = (2.0 * half) ** order
        # a segment of length 0 gets no bound (inf): its step is refused, as by the division by 0 it replaces
        out = best + np.divide(2.0 * gap, length, out=np.full(N, np.inf), where=length > 0.0)
        return out.reshape(shape)

    def deriv_bound(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        """A bound of ``|Q'|`` on each segment plus ``2 gap / |b - a|`` (the margin of the class docstring)."""
        return self._bounds(a, b, 1)

    def second_deriv_bound(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        """A bound of ``|Q''|`` on each segment plus ``2 gap / |b - a|^2`` (the margin of the order-2 step rule)."""
        return self._bounds(a, b, 2)

    def derivative(self) -> FirstDerivative:
        """``Q'`` with the bounds of :meth:`second_deriv_bound` on segments (for the order-2 step rule)."""
        return FirstDerivative(self)

    @functools.cached_property
    def poly(self) -> QuasiPolynomial:
        """``Q``: the rounded expansion as a quasi-polynomial (built on first use)."""
        coef = self._coef
        return QuasiPolynomial(list(coef), self._taus.tolist()) if np.any(coef) else QuasiPolynomial([[0.0]], [0.0])

    def principal_part(self) -> DifferenceOperator:
        """The principal part of ``det M`` (:meth:`QuasiPolynomialMatrix.principal_part`: that of :attr:`poly`)."""
        return self._principal_operator

    @functools.cached_property
    def _principal_operator(self) -> DifferenceOperator:
        """:meth:`QuasiPolynomial.principal_part` of :attr:`poly`, from its coefficients: the
        ``s^p`` coefficients (``p`` the highest power) with their delays."""
        nonzero, top = self._leading
        keep = nonzero[:, top]
        return DifferenceOperator(self._coef[keep, top], self._taus[keep])

    @functools.cached_property
    def _leading(self) -> tuple[NDArray[np.bool_], int]:
        """The nonzero coefficients (delays, powers) and the highest power ``p`` of ``s`` (for :attr:`kind` and
        :meth:`principal_part`; the ufuncs' own reductions: the Python wrappers cost more on these small arrays)."""
        nonzero = self._coef != 0
        powers = np.logical_or.reduce(nonzero, axis=0).nonzero()[0]
        if not powers.size:
            raise _zero_determinant()
        return read_only(nonzero), int(powers[-1])

    @functools.cached_property
    def kind(self) -> str:
        """The type of ``det M`` (:attr:`QuasiPolynomial.kind` of :attr:`poly`, read from its coefficients).

        With ``p`` the highest power of ``s``: only the smallest delay carries ``s^p``
        (retarded), the smallest and others (neutral), or not the smallest (advanced).
        """
        nonzero, top = self._leading  # (delays, powers)
        lead = nonzero[:, top].nonzero()[0]
        if lead[0] != np.logical_or.reduce(nonzero, axis=1).nonzero()[0][0]:
            return "advanced"
        return "neutral" if lead.size > 1 else "retarded"

    @property
    def is_real(self) -> bool:
        """True: the entries are real."""
        return True

    @property
    def max_delay(self) -> float:
        """Largest delay of an entry of ``M``."""
        if self._source is None:
            return self.matrix.max_delay
        c, t = self._source
        return float(np.max(t[np.any(c != 0, axis=(0, 1, 3))], initial=0.0))
