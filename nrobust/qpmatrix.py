"""Square matrices of quasi-polynomials: the determinant as a characteristic function.

A matrix neutral equation with distributed delays (the characteristic equation of an
``n + m`` hyperbolic system, or of a state-space time-delay system) has a characteristic
function ``det M(s)`` with quasi-polynomial entries ``M_ij``. Expanding the determinant
multiplies distributed terms together, which the quasi-polynomial type does not
represent, so :class:`QuasiPolynomialMatrix` never expands it:

* ``det M(s)`` is computed from the evaluated entries (LU, ``numpy.linalg.det`` on the stacked
  matrices of many ``s`` at once; the point parts of all entries come from one coefficient tensor);
* ``(det M)'(s) = tr(adj M(s) M'(s)) = sum_i det M^{(i)}(s)`` (Jacobi's formula), with
  ``M^{(i)}`` the matrix whose row ``i`` is replaced by the row of derivatives: ``n``
  determinants, valid where ``M`` is singular;
* bounds of ``|(det M)'|`` and ``|(det M)''|`` on a segment come from Hadamard's
  inequality ``|det X| <= prod_i ||X_i||_2`` applied to the terms of Jacobi's formula,
  with the entry bounds ``|M_ij^{(k)}| <= B^k_ij`` of :meth:`QuasiPolynomial.abs_bound`
  (``k = 0``) and :meth:`QuasiPolynomial.deriv_bound` (``k = 1, 2``).

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
from math import comb
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .difference import DifferenceOperator
from .errors import ParameterError
from .quasipoly import QuasiPolynomial, as_quasipolynomial

__all__ = ["CharacteristicFunction", "FirstDerivative", "QuasiPolynomialMatrix"]

# Largest matrix size: the principal part expands n! products of point parts.
_MAX_SIZE = 8


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


def _row_norms(bounds: NDArray[np.float64]) -> NDArray[np.float64]:
    """2-norms of the rows of entry bounds ``(..., n, n)``: ``(..., n)``."""
    return np.sqrt(np.sum(bounds * bounds, axis=-1))


@functools.cache
def _leave_out(n: int) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Masks ``one[i, j] = j != i`` and ``two[i, k, j] = j not in (i, k)``."""
    j = np.arange(n)
    one = j[None, :] != j[:, None]
    two = one[:, None, :] & one[None, :, :]
    return one, two


def _products_except(x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Products over the last axis of ``x`` (``(..., n)``) leaving out one index ``i``
    (``(..., n)``) and two indices ``i, k`` (``(..., n, n)``), without division (zeros stay exact)."""
    one, two = _leave_out(x.shape[-1])
    return (
        np.prod(np.where(one, x[..., None, :], 1.0), axis=-1),
        np.prod(np.where(two, x[..., None, None, :], 1.0), axis=-1),
    )


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
class _Compiled:
    """The point parts of all entries as one tensor: ``M(s) = sum_k e^{-tau_k s} sum_p C[k, p] s^p``.

    ``taylor[d][j]`` holds the coefficients of ``p^{(j)} / j!`` of the ``d``-th derivative's
    polynomials ``p`` (``d = 0, 1, 2``: the point parts of ``M``, ``M'``, ``M''``), the
    Taylor coefficients from which the bounds on discs are summed; ``absolute`` the moduli
    of ``C`` (for the rounding scale). ``dist`` lists the entries with distributed terms,
    as quasi-polynomials of those terms alone, and their first derivatives.
    """

    taus: NDArray[np.float64]  # (K,)
    taylor: tuple[tuple[NDArray, ...], ...]  # [d][j]: (K, P - j, n, n)
    absolute: NDArray[np.float64]  # (K, P, n, n)
    dist: tuple[tuple[int, int, QuasiPolynomial, QuasiPolynomial], ...]


def _compile(entries: tuple[tuple[QuasiPolynomial, ...], ...]) -> _Compiled:
    n = len(entries)
    taus = sorted({t for row in entries for e in row for _, t in e.point_terms} | {0.0})
    where = {t: i for i, t in enumerate(taus)}
    degree = max((p.size - 1 for row in entries for e in row for p, _ in e.point_terms), default=0)
    complex_ = any(np.iscomplexobj(p) for row in entries for e in row for p, _ in e.point_terms)
    coef = np.zeros((len(taus), degree + 1, n, n), dtype=complex if complex_ else float)
    dist = []
    for i, row in enumerate(entries):
        for j, e in enumerate(row):
            for p, t in e.point_terms:
                coef[where[t], : p.size, i, j] = p
            if e.distributed:
                d = QuasiPolynomial.from_parts((), e.distributed)
                dist.append((i, j, d, d.derivative()))
    tau = np.array(taus, dtype=float)
    derivs = [coef]
    for _ in range(2):  # (p e^{-tau s})' = (p' - tau p) e^{-tau s}
        c = derivs[-1]
        dc = -tau[:, None, None, None] * c
        dc[:, :-1] += c[:, 1:] * np.arange(1, c.shape[1])[None, :, None, None]
        derivs.append(dc)
    taylor = []
    for c in derivs:
        size = c.shape[1]
        rows = []
        for j in range(size):  # p^{(j)} / j! = sum_k C(k, j) c_k s^(k - j)
            w = np.array([comb(k, j) for k in range(j, size)], dtype=float)
            rows.append(c[:, j:] * w[None, :, None, None])
        taylor.append(tuple(rows))
    return _Compiled(tau, tuple(taylor), np.abs(coef), tuple(dist))


def _horner(c: NDArray, s: NDArray) -> NDArray:
    """``sum_p c[:, p] s^p`` for flat ``s``: shape ``(N, K, n, n)``."""
    if c.shape[1] == 1:  # a constant: read-only, callers do not write into it
        return np.broadcast_to(c[:, 0], (s.size, *c[:, 0].shape))
    x = s[:, None, None, None]
    out = c[:, -1] * x + c[:, -2]
    for p in range(c.shape[1] - 3, -1, -1):
        out = out * x + c[:, p]
    return out


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
        if not 1 <= n <= _MAX_SIZE:
            raise ParameterError("entries", f"1 to {_MAX_SIZE} rows", n)
        out = []
        for i, row in enumerate(rows):
            if isinstance(row, (str, bytes)) or not isinstance(row, Sequence | np.ndarray) or len(row) != n:
                raise ParameterError(f"entries[{i}]", f"a row of {n} entries (a square matrix)", row)
            out.append(tuple(as_quasipolynomial(f"entries[{i}][{j}]", e) for j, e in enumerate(row)))
        object.__setattr__(self, "entries", tuple(out))

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

    @property
    def is_real(self) -> bool:
        """True if every entry is real: ``det M`` is real on the real axis."""
        return all(e.is_real for e in self._flat())

    @property
    def max_delay(self) -> float:
        """Largest delay of an entry."""
        return float(max(e.max_delay for e in self._flat()))

    def point_determinant(self) -> QuasiPolynomial:
        """``det`` of the point parts of the entries, expanded (Leibniz): a quasi-polynomial."""
        return self._point_determinant

    @functools.cached_property
    def _point_determinant(self) -> QuasiPolynomial:
        return _point_expansion(self.entries)

    @functools.cached_property
    def _compiled(self) -> _Compiled:
        return _compile(self.entries)

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
            raise ParameterError(
                "entries", "a point determinant not identically zero (it defines the principal part)", 0
            )
        deg = np.array([[_degree(e) for e in row] for row in self.entries])
        n = self.size
        if any(e.distributed for e in self._flat()):
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
        ``det(I - sum_k A_k e^{-tau_k s})`` (Hale and Verduyn Lunel).
        """
        return self._principal_source().principal_part()

    # ------------------------------------------------------------------ evaluation
    # The point parts of all entries are evaluated together from one coefficient tensor
    # (:class:`_Compiled`), the distributed terms entry by entry.
    def _tensor_values(self, s: NDArray[np.complex128], order: int) -> NDArray[np.complex128]:
        """``M^{(order)}(s)`` (``order`` 0 or 1) on flat ``s``: shape ``(N, n, n)``."""
        c = self._compiled
        ex = np.ones((s.size, c.taus.size), dtype=complex)
        ex[:, 1:] = np.exp(-np.outer(s, c.taus[1:]))
        out = np.einsum("nk,nkij->nij", ex, _horner(c.taylor[order][0], s))
        for i, j, d, _ in c.dist:
            out[:, i, j] += d(s) if order == 0 else d.deriv_at(s)
        return out

    def values(self, s: ArrayLike) -> NDArray[np.complex128]:
        """The entries ``M_ij(s)``: an array of shape ``s.shape + (n, n)``."""
        s = np.asarray(s, dtype=complex)
        n = self.size
        return self._tensor_values(s.ravel(), 0).reshape(*s.shape, n, n)

    def __call__(self, s: ArrayLike) -> NDArray[np.complex128]:
        """``det M(s)`` on an array of complex ``s``."""
        s = np.asarray(s, dtype=complex)
        return np.asarray(np.linalg.det(self._tensor_values(s.ravel(), 0)), dtype=complex).reshape(s.shape)

    def deriv_at(self, s: ArrayLike) -> NDArray[np.complex128]:
        """``(det M)'(s) = sum_i det M^{(i)}(s)`` (Jacobi's formula, row by row)."""
        s = np.asarray(s, dtype=complex)
        flat = s.ravel()
        m = self._tensor_values(flat, 0)
        dm = self._tensor_values(flat, 1)
        n = self.size
        mi = np.broadcast_to(m, (n, *m.shape)).copy()
        for i in range(n):
            mi[i, :, i, :] = dm[:, i, :]
        return np.asarray(np.linalg.det(mi).sum(axis=0), dtype=complex).reshape(s.shape)

    def _entry_bounds(self, a: NDArray, b: NDArray, order: int) -> NDArray[np.float64]:
        """Bounds of ``|M_ij^{(order)}|`` on the segments: shape ``a.shape + (n, n)``.

        A point part ``sum_k q_k(s) e^{-tau_k s}`` (``q_k`` the polynomials of the
        ``order``-th derivative) is bounded by ``sum_k max|q_k| e^{-tau_k x_min}``, the
        polynomial maxima by the Taylor sum about the midpoint (as
        :meth:`QuasiPolynomial.abs_bound`); distributed terms by their own bounds.
        """
        c = self._compiled
        shape = a.shape
        a, b = a.ravel(), b.ravel()
        center, radius = 0.5 * (a + b), 0.5 * np.abs(b - a)
        xmin = np.minimum(a.real, b.real)
        poly = np.zeros((a.size, c.taus.size, self.size, self.size))
        power = np.ones(a.size)
        for j, coef in enumerate(c.taylor[order]):
            if j:
                power = power * radius
            poly += np.abs(_horner(coef, center)) * power[:, None, None, None]
        ex = np.ones((a.size, c.taus.size))
        ex[:, 1:] = np.exp(-np.outer(xmin, c.taus[1:]))
        out = np.einsum("nk,nkij->nij", ex, poly)
        for i, j, d, dd in c.dist:
            if order == 0:
                out[:, i, j] += d.abs_bound(a, b)
            elif order == 1:
                out[:, i, j] += d.deriv_bound(a, b)
            else:
                out[:, i, j] += dd.deriv_bound(a, b)
        return out.reshape(*shape, self.size, self.size)

    def deriv_bound(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        """Upper bound of ``|(det M)'|`` on each segment ``[a, b]``.

        ``|(det M)'| <= sum_i ||B1_i|| prod_{k != i} ||B0_k||`` (Hadamard's inequality on each
        term of Jacobi's formula), ``B0``, ``B1`` the entry bounds of ``|M|``, ``|M'|``
        on the segment and ``||.||`` the 2-norm of a row.
        """
        a = np.asarray(a, dtype=complex)
        b = np.asarray(b, dtype=complex)
        r0 = _row_norms(self._entry_bounds(a, b, 0))
        r1 = _row_norms(self._entry_bounds(a, b, 1))
        one, _ = _products_except(r0)
        return np.asarray(np.sum(r1 * one, axis=-1), dtype=float)

    def second_deriv_bound(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        """Upper bound of ``|(det M)''|`` on each segment ``[a, b]``.

        ``(det M)'' = sum_i det M^{(ii)} + sum_{i != k} det M^{(ik)}``: row ``i`` replaced
        by second derivatives, or rows ``i`` and ``k`` by first derivatives; each term is
        bounded by Hadamard's inequality as in :meth:`deriv_bound`.
        """
        a = np.asarray(a, dtype=complex)
        b = np.asarray(b, dtype=complex)
        r0 = _row_norms(self._entry_bounds(a, b, 0))
        r1 = _row_norms(self._entry_bounds(a, b, 1))
        r2 = _row_norms(self._entry_bounds(a, b, 2))
        one, two = _products_except(r0)
        pairs = r1[..., :, None] * r1[..., None, :] * two  # i != k: the diagonal is left out below
        off = _leave_out(self.size)[0]
        return np.asarray(np.sum(r2 * one, axis=-1) + np.sum(np.where(off, pairs, 0.0), axis=(-2, -1)), dtype=float)

    def derivative(self) -> FirstDerivative:
        """``(det M)'`` as a function with a bound of its own derivative (for the order-2 step rule)."""
        return FirstDerivative(self)

    def magnitude(self, s: ArrayLike) -> NDArray[np.float64]:
        """Rounding scale of ``det M(s)``: ``n 2^(n-1) prod_i sum_j m_ij(s)``, ``m_ij`` the entry scales.

        ``prod_i sum_j m_ij`` bounds the sum of the moduli of all products of the Leibniz
        expansion; ``2^(n-1)`` is the growth factor bound of LU with partial pivoting.
        """
        s = np.asarray(s, dtype=complex)
        flat = s.ravel()
        c = self._compiled
        ex = np.ones((flat.size, c.taus.size))
        ex[:, 1:] = np.exp(-np.outer(flat.real, c.taus[1:]))
        mags = np.einsum("nk,nkij->nij", ex, _horner(c.absolute, np.abs(flat)))
        for i, j, d, _ in c.dist:
            mags[:, i, j] += d.magnitude(flat)
        mags = mags.reshape(*s.shape, self.size, self.size)
        n = self.size
        return np.asarray(n * 2.0 ** (n - 1) * np.prod(np.sum(mags, axis=-1), axis=-1), dtype=float)

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
