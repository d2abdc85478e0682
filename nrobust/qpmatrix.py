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
# Rounding allowance of a computed value relative to its rounding scale: the root counter's
# (nrobust.roots) allowance on the samples of F, used here on the samples of F'.
_ROUNDING = 64 * float(np.finfo(float).eps)
# Largest batch of points whose M and M' __call__ keeps for the deriv_at that follows (Newton's
# method evaluates both at a few hundred points at most; a plot's grid is not kept).
_KEPT = 4096
# deriv_bound evaluates (det M)' at the midpoint of a segment only where the remainder of its
# first-order Taylor bound is below this fraction of Hadamard's bound (elsewhere it rarely wins).
_TAYLOR_GAIN = 0.5


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
        return m[..., 0, 0]
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
        taus=tau,
        values=np.concatenate([c.reshape(K * P, n * n) for c in derivs], axis=1),
        moduli=np.abs(np.concatenate([c.reshape(K * P, n * n) for c in derivs[:2]], axis=1)),
        taylor=taylor[:, : P - 1].reshape(P, (P - 1) * 3 * K * n * n),
        constant=np.abs(taylor[0, P - 1]).transpose(1, 0, 2).reshape(K, 3 * n * n),
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

    @functools.cached_property
    def is_real(self) -> bool:
        """True if every entry is real: ``det M`` is real on the real axis."""
        return all(e.is_real for e in self._flat())

    @functools.cached_property
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
    # The point parts of all entries are evaluated together by one matrix product
    # (:class:`_Compiled`), the distributed terms entry by entry.
    def _tensor_values(self, s: NDArray[np.complex128], orders: int) -> NDArray[np.complex128]:
        """``M^{(d)}(s)`` for ``d < orders`` (at most 3) on flat ``s``: shape ``(N, orders, n, n)``."""
        c = self._compiled
        n = self.size
        out = (c.weights(s) @ c.values[:, : orders * n * n]).reshape(s.size, orders, n, n)
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
        batch of at most ``_KEPT`` points both are kept for a :meth:`deriv_at` at the same
        points, the pattern of Newton's method.
        """
        s = np.asarray(s, dtype=complex)
        flat = s.ravel()
        v = self._tensor_values(flat, 1 if self._compiled.dist or flat.size > _KEPT else 2)
        if v.shape[1] == 2:
            object.__setattr__(self, "_last", (flat.copy(), v))
        return np.asarray(_det(v[:, 0]), dtype=complex).reshape(s.shape)

    def deriv_at(self, s: ArrayLike) -> NDArray[np.complex128]:
        """``(det M)'(s) = sum_i det M^{(i)}(s)`` (Jacobi's formula, row by row)."""
        s = np.asarray(s, dtype=complex)
        flat = s.ravel()
        last = self.__dict__.get("_last")
        if last is not None and np.array_equal(last[0], flat):
            v = last[1]
        else:
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
        with the moduli of their coefficients.
        """
        c = self._compiled
        n = self.size
        mags = (c.scale_weights(s) @ c.moduli[:, : orders * n * n]).reshape(s.size, orders, n, n)
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
        rows = np.sum(self._scales(s, 2), axis=-1)  # (N, 2, n)
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
