"""Quasi-polynomials with point and distributed delays.

A quasi-polynomial is

    F(s) = sum_k p_k(s) e^{-tau_k s} + sum_j q_j(s) int_{a_j}^{b_j} nu^{m_j} N_j(nu) e^{-nu s} dnu,

the form taken by every characteristic function of the paper, e.g. the open loop
``1 - rho q e^{-tau s} + int_0^tau N~(nu) e^{-nu s} dnu`` (paper, Laplace transform of
eq. (39)). :class:`QuasiPolynomial` holds the point terms and the distributed terms, and
gives the evaluation of ``F`` and ``F'``, the closed-form bounds of ``|F|`` and ``|F'|`` on
segments, the algebra (sums, products, delays) and a structural equality. The distributed
terms, with their tabulated kernels ``N_j`` and the closed-form (Filon-type) integrals whose
error does not grow with ``|Im s|``, are :class:`~nrobust.distributed_delay.DistributedDelay`
(imported here, and importable from here).
"""

from __future__ import annotations

import cmath
import functools
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from fractions import Fraction
from math import comb, factorial, inf, nextafter
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._json import json_safe
from ._validate import is_real_number, nonnegative, number_array, read_only, read_only_state, real_array
from .difference import DifferenceOperator
from .distributed_delay import DistributedDelay, TermsAtPoint, as_poly, canonical_bytes, polyder, polymul, polyval
from .errors import ParameterError

__all__ = ["DistributedDelay", "QuasiPolynomial", "QuasiPolynomialsAtPoint", "as_quasipolynomial"]

# deriv_bound, abs_bound and magnitude evaluate the moments of |N| on real parts rounded
# down to this grid.
_XMIN_GRID = 64.0


def _polyadd(a: NDArray, b: NDArray) -> NDArray:
    """Coefficients of the sum of two polynomials (increasing powers)."""
    n = max(a.size, b.size)
    out = np.zeros(n, dtype=np.result_type(a, b))
    out[: a.size] += a
    out[: b.size] += b
    return out


# Relative bound of the rounding of a coefficient computed by a few floating-point operations
# (each at most 2^-53 relative), and the factor rounding a radius computed in floating point up.
_ROUNDING = 2.0**-50
_RADIUS_UP = 1.0 + 2.0**-48


def _up(r: Any) -> NDArray[np.float64]:
    """A radius computed in floating point, rounded up (relative ``2^-48`` plus the least subnormal)."""
    r = np.abs(np.asarray(r, dtype=float))
    return np.where(r > 0, r * _RADIUS_UP + 5e-324, 0.0)


def _radius_add(a: NDArray | None, b: NDArray | None) -> NDArray | None:
    """The sum of two radius arrays (None: zero), padded to the longer, rounded up."""
    if a is None or b is None:
        return b if a is None else a
    return _up(_polyadd(np.asarray(a, dtype=float), np.asarray(b, dtype=float)))


def _checked_radii(radii: Sequence[ArrayLike] | None, count: int) -> list[NDArray[np.float64]] | None:
    """``radii`` as arrays (one per point term), or None when not given.

    Radii given, even all zero, make the algebra account for its roundings: the stored
    coefficients are then known to be those of the function meant.
    """
    if radii is None:
        return None
    if len(radii) != count:
        raise ParameterError("radii", f"one radius array per entry of coefs ({count})", radii)
    out = [real_array("radii", np.atleast_1d(np.asarray(r, dtype=float)), min_size=1) for r in radii]
    if any(np.any(r < 0) for r in out):
        raise ParameterError("radii", ">= 0", radii)
    return out


def _rounding(exact: Any, computed: NDArray) -> NDArray[np.float64]:
    """Bound of ``|computed - exact|`` per coefficient: for a real result the distance to the rational
    ``exact`` rounded up (0 where exact), else ``2^-50 |computed|`` (a few roundings of ``2^-53`` each)."""
    computed = np.asarray(computed)
    out = _ROUNDING * np.abs(computed)
    if np.iscomplexobj(computed):
        return out
    for i, (x, e) in enumerate(zip(computed.tolist(), exact)):
        error = abs(Fraction(x) - e)
        bound = float(error)
        out[i] = bound if Fraction(bound) >= error else nextafter(bound, inf)
    return out


def _fraction_add(a: list[Fraction], b: list[Fraction]) -> list[Fraction]:
    """The sum of two polynomials with rational coefficients (increasing powers)."""
    n = max(len(a), len(b))
    zero = Fraction(0)
    return [(a[i] if i < len(a) else zero) + (b[i] if i < len(b) else zero) for i in range(n)]


def _scaled_rounding(p: NDArray, c: complex | float) -> NDArray[np.float64]:
    """Bound of the rounding of ``c p`` (0 where exact)."""
    exact = _exact_poly(p)
    if exact is None or isinstance(c, complex):
        return _ROUNDING * np.abs(p * c)
    return _rounding([x * Fraction(c) for x in exact], p * c)


def _product_rounding(p: NDArray, q: NDArray) -> NDArray[np.float64]:
    """Bound of the rounding of ``polymul(p, q)``: exact in rationals for real factors, else
    ``2^-50`` relative per product summed."""
    a, b = _exact_poly(p), _exact_poly(q)
    if a is None or b is None:
        return _ROUNDING * min(p.size, q.size) * polymul(np.abs(p), np.abs(q))
    computed = polymul(p, q)
    exact = [
        sum((a[i] * b[k - i] for i in range(len(a)) if 0 <= k - i < len(b)), Fraction(0)) for k in range(computed.size)
    ]
    return _rounding(exact, computed)


def _exact_poly(p: NDArray) -> list[Fraction] | None:
    """The coefficients of a real ``p`` as rationals (None for a complex one)."""
    return None if np.iscomplexobj(p) else [Fraction(x) for x in p.tolist()]


def _term(p: NDArray, r: NDArray | None) -> tuple[NDArray, NDArray[np.float64]]:
    """The coefficients and radii of a kept term, of one length: ``p`` padded with zeros under a positive
    radius beyond its last coefficient (its degree is then that of the ball)."""
    if r is None:
        return p, np.zeros(p.size)
    positive = np.flatnonzero(r > 0)
    n = max(p.size, int(positive[-1]) + 1 if positive.size else 0)
    return _polyadd(p, np.zeros(n, dtype=p.dtype)), _polyadd(np.asarray(r[:n], dtype=float), np.zeros(n))


def _segments(
    a: ArrayLike, b: ArrayLike, grid: bool
) -> tuple[NDArray[np.complex128], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.intp]]:
    """Midpoints, half-lengths and least real parts of the segments ``[a, b]``, with the
    least real parts rounded down to the grid ``1/_XMIN_GRID`` if ``grid`` (``xs``, distinct,
    and ``where``, the index of each segment's value in ``xs``; empty otherwise).

    ``abs_moment`` decreases in ``x``: evaluated at ``x`` rounded down it stays an upper
    bound, and needs one evaluation per distinct value (a vertical edge has one).
    """
    a = np.asarray(a, dtype=complex)
    b = np.asarray(b, dtype=complex)
    xmin = np.minimum(a.real, b.real)
    if not grid:
        return 0.5 * (a + b), 0.5 * np.abs(b - a), xmin, np.zeros(0), np.zeros(0, dtype=np.intp)
    xs, where = np.unique(np.floor(xmin * _XMIN_GRID) / _XMIN_GRID, return_inverse=True)
    return 0.5 * (a + b), 0.5 * np.abs(b - a), xmin, xs, where.reshape(xmin.shape)


def _least_modulus(a: NDArray[np.complex128], b: NDArray[np.complex128]) -> NDArray[np.float64]:
    """Distance from 0 to each segment ``[a, b]``, rounded down by a few ulps."""
    v = b - a
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.clip(-np.real(np.conj(v) * a) / np.abs(v) ** 2, 0.0, 1.0)
    d = np.abs(a + np.nan_to_num(t) * v)
    return np.minimum(np.minimum(d, np.abs(a)), np.abs(b)) * (1.0 - 1e-12)


def _integral_bounds(
    d: DistributedDelay, a: ArrayLike, b: ArrayLike, xs: NDArray, where: NDArray, ks: tuple[int, ...]
) -> list[NDArray[np.float64]]:
    """Bounds of ``|int nu^(m+k) N e^{-nu s} dnu|`` on the segments for each ``k`` of ``ks``.

    The lesser of :meth:`DistributedDelay.abs_moment` (at ``xs``, the least real parts
    rounded down) and :meth:`DistributedDelay.decay_bound` (at the same real parts and the
    least modulus on the segment): both hold, the second decays like ``1/|s|``.
    """
    dmin = _least_modulus(np.asarray(a, dtype=complex), np.asarray(b, dtype=complex))
    return [np.fmin(d.abs_moment(xs, k)[where], d.decay_bound(xs, dmin, k, where=where)) for k in ks]


def _poly_abs_bound(coefs: NDArray, center: NDArray, radius: NDArray) -> NDArray[np.float64]:
    """Upper bound of ``|p(s)|`` on discs ``|s - center| <= radius`` (exact Taylor sum)."""
    bound = np.zeros(center.shape)
    deriv = coefs
    for j in range(coefs.size):
        bound = bound + np.abs(polyval(deriv, center)) / factorial(j) * radius**j
        deriv = polyder(deriv)
    return bound


@dataclass(frozen=True)
class _PointTensor:
    """The point terms as arrays, so that one Horner scheme evaluates them all.

    ``taus`` the delays (``K``); ``taylor[d][j]`` (``d = 0``: the ``p_k``, ``d = 1``: the
    ``p_k' - tau_k p_k`` of ``F'``) the coefficients of ``q^{(j)} / j!`` as rows ``(K, P - j)``,
    the Taylor coefficients from which the bounds on discs are summed; ``absolute`` the
    moduli of the ``p_k`` (for the rounding scale).
    """

    taus: NDArray[np.float64]
    taylor: tuple[tuple[NDArray, ...], tuple[NDArray, ...]]
    absolute: NDArray[np.float64]


def _point_tensor(terms: tuple[tuple[NDArray, float], ...]) -> _PointTensor:
    size = max(p.size for p, _ in terms)
    coef = np.zeros((len(terms), size), dtype=np.result_type(*[p for p, _ in terms], float))
    for k, (p, _) in enumerate(terms):
        coef[k, : p.size] = p
    taus = np.array([t for _, t in terms], dtype=float)
    deriv = -taus[:, None] * coef  # (p e^{-tau s})' = (p' - tau p) e^{-tau s}
    deriv[:, :-1] += coef[:, 1:] * np.arange(1, size)
    taylor = []
    for c in (coef, deriv):
        rows = []
        for j in range(size):  # q^{(j)} / j! = sum_k C(k, j) c_k s^(k - j)
            rows.append(c[:, j:] * np.array([comb(k, j) for k in range(j, size)], dtype=float))
        taylor.append(tuple(rows))
    for arr in (taus, *taylor[0], *taylor[1]):
        read_only(arr)
    return _PointTensor(taus, (taylor[0], taylor[1]), read_only(np.abs(coef)))


def _horner_rows(c: NDArray, s: NDArray) -> NDArray:
    """``sum_p c[k, p] s^p`` for each row ``k`` and flat ``s``: shape ``(N, K)``."""
    if c.shape[1] == 1:
        return np.broadcast_to(c[:, 0], (s.size, c.shape[0]))
    x = s[:, None]
    out = c[:, -1] * x + c[:, -2]
    for p in range(c.shape[1] - 3, -1, -1):
        out = out * x + c[:, p]
    return out


def _exp_rows(taus: NDArray[np.float64], x: NDArray) -> NDArray:
    """``e^{-tau_k x}`` as ``(N, K)``, exactly 1 for ``tau_k = 0`` (also where ``x`` is not finite)."""
    out = np.exp(-np.outer(x, taus))
    out[:, taus == 0] = 1.0
    return out


def _fmt_num(c: complex) -> str:
    c = complex(c)
    if c.imag == 0:
        return f"{c.real:.6g}"
    return f"({c.real:.6g}{c.imag:+.6g}j)"


def _merge_distributed(terms: Sequence[DistributedDelay]) -> tuple[DistributedDelay, ...]:
    """Sum the terms that share nodes, polynomial and moment; drop the zero ones.

    Exact cancellation matters: ``A + B`` of a loop with ``B = K q e^{-tau s} - I_N`` and
    ``A = 1 - rho q e^{-tau s} + I_N`` must not keep ``I_N - I_N`` as rounding noise.
    """
    merged: dict[tuple[Any, ...], DistributedDelay] = {}  # by first appearance, as the terms are given
    for d in terms:
        key = _merge_key(d)
        m = merged.get(key)
        merged[key] = d if m is None else m.plus(d)
    return tuple(d for d in merged.values() if not d.is_zero)


def _merge_key(d: DistributedDelay) -> tuple[Any, ...]:
    """A key equal for two terms exactly when :meth:`DistributedDelay.mergeable` holds between them.

    Python's numbers compare (and hash) as numpy's elementwise ``==`` of ``array_equal`` does (``-0.0``
    equal to ``0.0``, a real number to the complex one with zero imaginary part, a nan to nothing), and
    tuples of different lengths differ as arrays of different shapes do: the terms are merged in one pass
    instead of each against every kept one.
    """
    nodes, poly = np.asarray(d.nodes), np.asarray(d.poly)
    return (d.moment, d.interpolation, nodes.shape, poly.shape, *nodes.ravel().tolist(), *poly.ravel().tolist())


@dataclass(frozen=True, eq=False)
class QuasiPolynomial:
    """``F(s) = sum_k p_k(s) e^{-tau_k s} + sum_j (distributed terms)``.

    Parameters
    ----------
    coefs : sequence of array_like
        ``coefs[k]`` holds the coefficients of ``p_k`` in increasing powers of ``s``
        (the qpmr convention: ``[[0, 1], [1]]`` with delays ``[0, 1]`` is ``s + e^{-s}``).
    delays : sequence of float
        ``tau_k >= 0``, one per entry of ``coefs``; equal delays are merged.
    distributed : sequence of DistributedDelay, optional
        Distributed-delay terms.
    radii : sequence of array_like, optional
        Proven radii of the point coefficients, aligned with ``coefs``: the function meant has
        each coefficient within its radius of the stored one (real and imaginary parts each; a
        real coefficient stays real), e.g. a plant's gain ``rho q e^{sigma_0 tau}``, irrational,
        rounded to a double. Ball evaluation
        (:mod:`nrobust.balls`) and the proofs built on it enclose every such function; the
        floating-point evaluation uses the stored coefficients. The algebra carries the radii
        and, once one is positive, adds the rounding of every coefficient it computes (about
        ``2^-50`` relative). Default: none, the stored coefficients are the function's.

    Notes
    -----
    Equality is structural: two quasi-polynomials compare equal (``==``, with a
    consistent ``hash``, so they can be dict keys) when their canonical forms agree: point
    terms merged by delay, sorted, with trailing zero coefficients and zero terms dropped,
    and the same distributed terms in any order (terms sharing nodes, polynomial and
    moment merged). Equal functions written differently, e.g. a factor moved between
    ``q(s)`` and ``N`` of a distributed term, may compare unequal.

    Examples
    --------
    >>> F = QuasiPolynomial([[1], [-0.85], [0.1]], [0, 2, 2.1])
    >>> complex(F(0.0))
    (0.25+0j)
    """

    point_terms: tuple[tuple[NDArray, float], ...]
    distributed: tuple[DistributedDelay, ...]
    #: Radii of the point coefficients (:class:`QuasiPolynomial`'s ``radii``), aligned with
    #: ``point_terms``; ``()`` when every stored coefficient is exact.
    point_radii: tuple[NDArray[np.float64], ...]

    def __init__(
        self,
        coefs: Sequence[ArrayLike],
        delays: ArrayLike,
        distributed: Iterable[DistributedDelay] = (),
        radii: Sequence[ArrayLike] | None = None,
    ) -> None:
        if isinstance(coefs, (str, bytes)) or not isinstance(coefs, Sequence | np.ndarray):
            raise ParameterError("coefs", "a sequence of coefficient sequences", coefs)
        taus = real_array("delays", np.atleast_1d(delays) if is_real_number(delays) else delays, min_size=0)
        if taus.size != len(coefs):
            raise ParameterError("delays", f"one delay per entry of coefs ({len(coefs)})", delays)
        if np.any(taus < 0):
            raise ParameterError("delays", ">= 0 (delays, not advances)", delays)
        dist = tuple(distributed)
        for d in dist:
            if not isinstance(d, DistributedDelay):
                raise ParameterError("distributed", "a sequence of DistributedDelay", d)
        if len(coefs) == 0 and not dist:
            raise ParameterError("coefs", "non-empty (or at least one distributed term)", coefs)
        radius = _checked_radii(radii, len(coefs))
        merged: dict[float, NDArray] = {}
        merged_radius: dict[float, NDArray | None] = {}
        summed = set()
        for k, (c, t) in enumerate(zip(coefs, taus.tolist())):
            p = as_poly(f"coefs[{k}]", c)
            if t in merged:
                total = _polyadd(merged[t], p)
                if radius is not None:  # the rounding of the sum
                    a, b = _exact_poly(merged[t]), _exact_poly(p)
                    exact = [] if a is None or b is None else _fraction_add(a, b)
                    merged_radius[t] = _radius_add(merged_radius.get(t), _rounding(exact, total))
                merged[t] = total
                summed.add(t)
            else:
                merged[t] = p
            if radius is not None:
                merged_radius[t] = _radius_add(merged_radius.get(t), radius[k])
        for t in summed:  # a sum may end in zeros
            merged[t] = as_poly("coefs", merged[t])
        # the arrays kept are copies of the caller's (as_poly, _checked_radii), marked read-only: the
        # results kept for this object (its derivative, its tensor, the root finders' bounds) stay its own
        if radius is None:
            terms = tuple((read_only(p), t) for t, p in sorted(merged.items()) if p[-1] != 0)
            object.__setattr__(self, "point_terms", terms)
            object.__setattr__(self, "point_radii", ())
        else:  # a term with a positive radius stays, its stored coefficients zero or not
            kept = [(t, *_term(p, merged_radius.get(t))) for t, p in sorted(merged.items())]
            kept = [(t, p, r) for t, p, r in kept if p[-1] != 0 or r[-1] > 0]
            object.__setattr__(self, "point_terms", tuple((read_only(p), t) for t, p, _ in kept))
            object.__setattr__(self, "point_radii", tuple(read_only(r) for _, _, r in kept))
        object.__setattr__(self, "distributed", _merge_distributed(dist))

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Unpickled or deep-copied: its arrays marked read-only again (numpy's pickles drop the flag)."""
        read_only_state(self, state)

    @classmethod
    def from_parts(
        cls,
        terms: Iterable[tuple[NDArray, float]],
        distributed: Iterable[DistributedDelay],
        radii: Sequence[ArrayLike] | None = None,
    ) -> QuasiPolynomial:
        """The quasi-polynomial of point terms ``(coefficients, delay)`` (with ``radii``) and distributed terms."""
        terms = list(terms)
        dist = tuple(distributed)
        if not terms and not dist:
            return cls([[0.0]], [0.0])
        return cls([p for p, _ in terms], [t for _, t in terms], dist, radii)

    def radii_of(self) -> list[NDArray[np.float64]]:
        """The radius array of each point term (zeros when exact), aligned with ``point_terms``."""
        if self.point_radii:
            return list(self.point_radii)
        return [np.zeros(p.size) for p, _ in self.point_terms]

    @property
    def exact_points(self) -> bool:
        """True when every stored point coefficient is the function's own (no positive radius)."""
        return not any(np.any(r > 0) for r in self.point_radii)

    @classmethod
    def from_coefficient_array(cls, coefs: ArrayLike, delays: ArrayLike) -> list[Any]:
        """The quasi-polynomials ``sum_k coefs[..., k, p] s^p e^{-delays[k] s}`` of an array, as nested lists.

        One validation of the whole array instead of one per entry: a matrix
        ``M(s) = sum_k C_k(s) e^{-tau_k s}`` of ``n^2`` entries sharing delays is
        ``from_coefficient_array(C, tau)`` with ``C`` of shape ``(n, n, K, P)`` (powers
        increasing). Each entry equals ``QuasiPolynomial(coefs[i, j], delays)``: equal delays
        summed in their order, zero terms dropped.

        Parameters
        ----------
        coefs : array_like
            Finite real or complex numbers, shape ``(..., K, P)`` with at least one leading axis.
        delays : array_like
            ``K`` finite delays ``>= 0``.

        Returns
        -------
        list
            Nested lists of :class:`QuasiPolynomial` of the shape ``coefs.shape[:-2]``.
        """
        arr = number_array("coefs", coefs, ndim=None)
        taus = real_array("delays", delays, min_size=1)
        if arr.ndim < 3 or arr.shape[-2] != taus.size or arr.shape[-1] == 0:
            raise ParameterError(
                "coefs", f"an array of shape (..., K, P) with K = {taus.size} (one row per delay), P >= 1", arr.shape
            )
        if np.any(taus < 0):
            raise ParameterError("delays", ">= 0 (delays, not advances)", delays)
        order = sorted(set(taus.tolist()))
        rows = []
        for t in order:  # equal delays summed in their order, as QuasiPolynomial does
            at = np.flatnonzero(taus == t)
            total = arr[..., at[0], :].copy()
            for k in at[1:]:
                total += arr[..., k, :]
            rows.append(total)
        merged = np.stack(rows, axis=-2)  # (..., K', P)
        nonzero = merged != 0
        ends = merged.shape[-1] - np.argmax(nonzero[..., ::-1], axis=-1)  # one past the last nonzero power
        present = nonzero.any(axis=-1)
        lead = merged.shape[:-2]
        flat, flat_ends, flat_present = (
            merged.reshape(-1, *merged.shape[-2:]),
            ends.reshape(-1, len(order)),
            present.reshape(-1, len(order)),
        )
        entries = []
        for c, e, keep in zip(flat, flat_ends.tolist(), flat_present.tolist()):
            F = object.__new__(cls)
            terms = tuple((read_only(c[k, : e[k]].copy()), t) for k, t in enumerate(order) if keep[k])
            object.__setattr__(F, "point_terms", terms)
            object.__setattr__(F, "point_radii", ())
            object.__setattr__(F, "distributed", ())
            entries.append(F)
        nested: list[Any] = entries
        for size in reversed(lead[1:]):
            nested = [nested[i : i + size] for i in range(0, len(nested), size)]
        return nested

    # ------------------------------------------------------------------ structure
    @property
    def delays(self) -> NDArray[np.float64]:
        """Point delays ``tau_k``, increasing."""
        return np.array([t for _, t in self.point_terms])

    @property
    def coefs(self) -> list[NDArray]:
        """Polynomial coefficients ``p_k`` (increasing powers), aligned with :attr:`delays`."""
        return [p for p, _ in self.point_terms]

    @property
    def degree(self) -> int:
        """Highest degree of the point-term polynomials ``p_k``."""
        return max((p.size - 1 for p, _ in self.point_terms), default=0)

    @property
    def max_delay(self) -> float:
        """Largest delay, point or distributed."""
        ends = [t for _, t in self.point_terms] + [d.b for d in self.distributed]
        return float(max(ends, default=0.0))

    @property
    def kind(self) -> str:
        """``"retarded"``, ``"neutral"`` or ``"advanced"``.

        With ``n`` the degree, the type is read from which delays carry an ``s^n`` term:
        only the smallest delay (retarded), the smallest and others (neutral), or not the
        smallest (advanced: chains of roots go to the right, no stability possible).
        """
        lead = self.leading_terms()
        if not lead or lead[0][1] != self.point_terms[0][1]:
            return "advanced"
        return "neutral" if len(lead) > 1 else "retarded"

    @property
    def is_neutral(self) -> bool:
        """True if the principal part has more than one term."""
        return self.kind == "neutral"

    @property
    def is_retarded(self) -> bool:
        """True if only the smallest delay carries the highest power of ``s``."""
        return self.kind == "retarded"

    @property
    def is_real(self) -> bool:
        """True if every coefficient (point and distributed) is real: roots come in conjugate pairs."""
        parts = [p for p, _ in self.point_terms] + [a for d in self.distributed for a in (d.values, d.poly)]
        return not any(np.iscomplexobj(a) and np.any(np.asarray(a).imag != 0) for a in parts)

    def leading_terms(self, n: int | None = None) -> list[tuple[complex, float]]:
        """The ``s^n`` coefficients ``a_k`` of the point terms with their delays ``tau_k``.

        ``n`` defaults to :attr:`degree`; these terms form the principal part
        ``D(s) = sum_k a_k e^{-tau_k s}`` of ``F`` (``F(s) = s^n (D(s) + O(1/s))``).

        Raises
        ------
        ParameterError
            If a distributed term has a polynomial factor of degree above ``n`` (it would
            enter the principal part, which is modelled by point terms only).
        """
        n = self.degree if n is None else n
        for d in self.distributed:
            if d.poly.size - 1 > n:
                raise ParameterError(
                    "distributed",
                    f"terms whose polynomial degree is at most {n} (the point-term degree): "
                    "a higher one enters the principal part",
                    d,
                )
        return [(complex(p[n]), t) for p, t in self.point_terms if p.size - 1 == n and p[n] != 0]

    def principal_part(self) -> DifferenceOperator:
        """The difference operator ``D(s) = sum_k a_k e^{-tau_k s}`` of the ``s^n`` terms.

        For ``|s| -> infinity`` in a vertical strip, ``F(s) = s^n (D(s) + O(1/s))``: the
        high-frequency root chains of ``F`` are those of ``D`` (Hale and Verduyn Lunel).
        """
        lead = self.leading_terms()
        coefs = np.array([a for a, _ in lead], dtype=complex)
        return DifferenceOperator(coefs.real if self.is_real else coefs, [t for _, t in lead])

    def principal_radii(self) -> NDArray[np.float64] | None:
        """The radii of the coefficients of :meth:`principal_part`, aligned with its ``coefs``.

        Zeros when the stored coefficients are exact. None when a ball of an ``s^n``
        coefficient is centred on a stored 0 (``QuasiPolynomial(..., radii=...)``): the
        principal part of some function of the balls then has a term that
        :meth:`principal_part` does not.
        """
        n = self.degree
        out = []
        for (p, _), r in zip(self.point_terms, self.radii_of()):
            if p.size - 1 != n:
                continue
            if p[n] == 0:
                if r[n] > 0:
                    return None
                continue
            out.append(float(r[n]))
        return np.array(out, dtype=float)

    # ------------------------------------------------------------------ evaluation
    def __call__(self, s: ArrayLike) -> NDArray[np.complex128]:
        """Evaluate ``F(s)`` on an array of complex ``s``."""
        s = np.asarray(s, dtype=complex)
        out = self._point_sum(s, 0)
        for d in self.distributed:
            out += d(s)
        return out

    @functools.cached_property
    def _tensor(self) -> _PointTensor:
        return _point_tensor(self.point_terms)

    def _point_sum(self, s: NDArray[np.complex128], order: int) -> NDArray[np.complex128]:
        """The point terms of ``F`` (``order`` 0) or of ``F'`` (``order`` 1) at ``s``."""
        if not self.point_terms:
            return np.zeros(s.shape, dtype=complex)
        t = self._tensor
        flat = s.ravel()
        vals = _horner_rows(t.taylor[order][0], flat) * _exp_rows(t.taus, flat)
        return np.asarray(np.sum(vals, axis=1), dtype=complex).reshape(s.shape)

    def deriv(self, s: ArrayLike) -> NDArray[np.complex128]:
        """Deprecated alias of :meth:`deriv_at`: it evaluates ``F'(s)``; :meth:`derivative` returns ``F'``."""
        warnings.warn(
            "QuasiPolynomial.deriv(s) is deprecated, use QuasiPolynomial.deriv_at(s) (or derivative() for F')",
            DeprecationWarning,
            stacklevel=2,
        )
        return self.deriv_at(s)

    def deriv_at(self, s: ArrayLike) -> NDArray[np.complex128]:
        """Evaluate ``F'(s)`` on an array of complex ``s`` (:meth:`derivative` returns ``F'`` itself)."""
        s = np.asarray(s, dtype=complex)
        out = self._point_sum(s, 1)
        for d in self.distributed:
            out += d.deriv_at(s)
        return out

    def derivative(self) -> QuasiPolynomial:
        """``F'`` as a quasi-polynomial (distributed terms gain one moment); built once per function (the root
        counts on its contours ask for it each time a step needs the second-order bound)."""
        return self._derivative

    @functools.cached_property
    def _derivative(self) -> QuasiPolynomial:
        terms = [(_polyadd(polyder(p), -t * p), t) for p, t in self.point_terms]
        radii = None
        if self.point_radii:  # (p' - t p) with p within r: within r' + t r, plus the rounding
            radii = [
                _up(_polyadd(polyder(r), t * r) + _ROUNDING * _polyadd(np.abs(polyder(p)), np.abs(t * p)))
                for (p, t), r in zip(self.point_terms, self.point_radii)
            ]
        dist: list[DistributedDelay] = []
        for d in self.distributed:
            dq = polyder(d.poly)
            if np.any(dq != 0):
                dist.append(d.replace(poly=dq))
            dist.append(d.times(-1.0, moment=d.moment + 1))
        return QuasiPolynomial.from_parts(terms, dist, radii)

    def deriv_bound(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        """Upper bound of ``|F'(s)|`` on each segment ``[a, b]`` of the complex plane.

        Closed form (vectorised over the segments): a point term contributes
        ``max|p_k' - tau_k p_k| e^{-tau_k x_min}``, a distributed term
        ``max|q'| J_m + max|q| J_(m+1)`` with ``J_k`` the lesser of ``int nu^k |N| e^{-nu x_min}``
        and :meth:`DistributedDelay.decay_bound` (``O(1/|s|)``, by parts), where ``x_min`` is
        the smallest real part on the segment and the polynomial maxima are bounded by the
        Taylor sum about the midpoint.
        """
        center, radius, xmin, xs, where = _segments(a, b, bool(self.distributed))
        out = self._point_bound(center, radius, xmin, 1)
        for d in self.distributed:
            m0, m1 = _integral_bounds(d, a, b, xs, where, (0, 1))
            out += _poly_abs_bound(polyder(d.poly), center, radius) * m0
            out += _poly_abs_bound(d.poly, center, radius) * m1
        return out

    def abs_bound(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        """Upper bound of ``|F(s)|`` on each segment ``[a, b]`` of the complex plane.

        Closed form as :meth:`deriv_bound`: a point term contributes
        ``max|p_k| e^{-tau_k x_min}``, a distributed term ``max|q| J_m``.
        """
        center, radius, xmin, xs, where = _segments(a, b, bool(self.distributed))
        out = self._point_bound(center, radius, xmin, 0)
        for d in self.distributed:
            (m0,) = _integral_bounds(d, a, b, xs, where, (0,))
            out += _poly_abs_bound(d.poly, center, radius) * m0
        return out

    def _point_bound(self, center: NDArray, radius: NDArray, xmin: NDArray, order: int) -> NDArray[np.float64]:
        """``sum_k max|q_k| e^{-tau_k x_min}`` on the discs about ``center`` (``q_k = p_k``, or
        ``p_k' - tau_k p_k`` for ``order`` 1): the Taylor sum ``sum_j |q_k^{(j)}(c)| / j! r^j``."""
        if not self.point_terms:
            return np.zeros(center.shape)
        t = self._tensor
        c, r, x = center.ravel(), radius.ravel(), xmin.ravel()
        bound = np.abs(_horner_rows(t.taylor[order][0], c))
        power = np.ones(c.size)
        for coef in t.taylor[order][1:]:
            power = power * r
            bound = bound + np.abs(_horner_rows(coef, c)) * power[:, None]
        return np.asarray(np.sum(bound * _exp_rows(t.taus, x), axis=1), dtype=float).reshape(center.shape)

    def magnitude(self, s: ArrayLike) -> NDArray[np.float64]:
        """Sum of the moduli of the monomials of ``F`` at ``s``: the scale of its rounding error."""
        s = np.asarray(s, dtype=complex)
        r = np.abs(s)
        out = np.zeros(s.shape)
        if self.point_terms:
            t = self._tensor
            rows = _horner_rows(t.absolute, r.ravel()) * _exp_rows(t.taus, s.real.ravel())
            out += np.sum(rows, axis=1).reshape(s.shape)
        if self.distributed:
            # int |N| nu^k e^{-nu x} decreases in x (nu >= 0): rounding x down to 1/_XMIN_GRID keeps an
            # upper bound and lets the samples of a contour share a few evaluations
            xs, inv = np.unique(np.floor(s.real * _XMIN_GRID) / _XMIN_GRID, return_inverse=True)
            for d in self.distributed:
                out += np.polynomial.polynomial.polyval(r, np.abs(d.poly)) * d.abs_moment(xs, 0)[inv.reshape(s.shape)]
        return out

    # ------------------------------------------------------------------ algebra
    def __add__(self, other: Any) -> QuasiPolynomial:
        if isinstance(other, (int, float, complex, np.number)):
            other = QuasiPolynomial([np.array([other])], [0.0])
        if not isinstance(other, QuasiPolynomial):
            return NotImplemented
        radii = None if not (self.point_radii or other.point_radii) else self.radii_of() + other.radii_of()
        return QuasiPolynomial.from_parts(
            list(self.point_terms) + list(other.point_terms), self.distributed + other.distributed, radii
        )

    __radd__ = __add__

    def __neg__(self) -> QuasiPolynomial:
        return self * -1.0

    def __sub__(self, other: Any) -> QuasiPolynomial:
        return self + (-other)

    def __rsub__(self, other: Any) -> QuasiPolynomial:
        return (-self) + other

    def __mul__(self, other: Any) -> QuasiPolynomial:
        if isinstance(other, (int, float, complex, np.number)):
            c = complex(other) if isinstance(other, complex) or np.iscomplexobj(other) else float(other)
            radii = None
            if self.point_radii:  # c p within |c| r, plus the rounding of c p
                radii = [_up(abs(c) * r + _scaled_rounding(p, c)) for (p, _), r in self._radii_terms()]
            return QuasiPolynomial.from_parts(
                [(p * c, t) for p, t in self.point_terms], [d.scale(c) for d in self.distributed], radii
            )
        if not isinstance(other, QuasiPolynomial):
            return NotImplemented
        if self.distributed and other.distributed:
            raise ParameterError("other", "a quasi-polynomial without distributed terms when self has some", other)
        if self.distributed:
            return other * self
        terms = [(polymul(p, r), t + u) for p, t in self.point_terms for r, u in other.point_terms]
        dist = [e.times_poly(p) for p, t in self.point_terms for d in other.distributed for e in d.shift(t)]
        radii = None
        if self.point_radii or other.point_radii:
            if self.point_radii and other.distributed:
                raise ParameterError(
                    "other", "without distributed terms when self has point radii (a kernel times a ball)", other
                )
            radii = [
                _up(polymul(np.abs(p), rq) + polymul(rp, np.abs(q)) + polymul(rp, rq) + _product_rounding(p, q))
                for (p, _), rp in self._radii_terms()
                for (q, _), rq in other._radii_terms()
            ]
        return QuasiPolynomial.from_parts(terms, dist, radii)

    def _radii_terms(self) -> list[tuple[tuple[NDArray, float], NDArray[np.float64]]]:
        """``(term, radius)`` pairs of the point terms (zero radii when exact)."""
        return list(zip(self.point_terms, self.radii_of()))

    __rmul__ = __mul__

    def times_poly(self, coefs: ArrayLike) -> QuasiPolynomial:
        """Multiply by the polynomial with coefficients ``coefs`` (increasing powers)."""
        return self * QuasiPolynomial([coefs], [0.0])

    def shift(self, delta: float) -> QuasiPolynomial:
        """Multiply by ``e^{-delta s}`` (a loop delay ``delta >= 0``).

        A point delay ``t`` becomes the double nearest ``t + delta`` (:meth:`shift_is_exact` tells whether
        every sum is a double); a distributed term moves as
        :meth:`~nrobust.quasipoly.DistributedDelay.shift` says, a term with error bounds carrying the
        rounding of its nodes in them. A proof about ``A + B e^{-delta s}`` with a sum that rounds encloses
        ``B e^{-delta s}`` as a product instead (:class:`~nrobust.balls.DelayedSumBalls`).
        """
        delta = nonnegative("delta", delta)
        return QuasiPolynomial.from_parts(
            [(p, t + delta) for p, t in self.point_terms],
            [e for d in self.distributed for e in d.shift(delta)],
            list(self.point_radii) or None,
        )

    def shift_is_exact(self, delta: float) -> bool:
        """True when :meth:`shift` by ``delta`` moves every point delay and every node of a distributed term to
        the exact sum ``t + delta`` (a double): then ``self.shift(delta)`` is ``e^{-delta s}`` times ``self``."""
        delta = nonnegative("delta", delta)
        shift = Fraction(delta)
        delays = [t for _, t in self.point_terms] + [float(x) for d in self.distributed for x in d.nodes]
        return all(Fraction(t + delta) == Fraction(t) + shift for t in delays)

    # ------------------------------------------------------------------ display
    def __repr__(self) -> str:
        parts = []
        for p, t in self.point_terms:
            poly = " + ".join(
                _fmt_num(c) + ("" if j == 0 else (" s" if j == 1 else f" s^{j}")) for j, c in enumerate(p) if c != 0
            )
            poly = f"({poly})" if np.count_nonzero(p) > 1 else poly
            parts.append(poly if t == 0 else f"{poly} e^(-{t:.6g} s)")
        parts += [repr(d) for d in self.distributed]
        text = parts[0] if parts else "0"
        for part in parts[1:]:
            text += f" - {part[1:]}" if part.startswith("-") else f" + {part}"
        return f"QuasiPolynomial({text})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, QuasiPolynomial):
            return NotImplemented
        return (
            len(self.point_terms) == len(other.point_terms)
            and all(t == u and np.array_equal(p, r) for (p, t), (r, u) in zip(self.point_terms, other.point_terms))
            # the merged distributed terms are pairwise unequal: as sets they keep every term
            and frozenset(self.distributed) == frozenset(other.distributed)
            and len(self.point_radii) == len(other.point_radii)
            and all(np.array_equal(r, u) for r, u in zip(self.point_radii, other.point_radii))
        )

    def __hash__(self) -> int:
        points = tuple((t, canonical_bytes(p)) for p, t in self.point_terms)
        radii = tuple(canonical_bytes(r) for r in self.point_radii)
        return hash((points, frozenset(self.distributed), radii))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description: ``coefs`` and ``delays`` of the point terms, ``distributed``."""
        data = {"coefs": self.coefs, "delays": self.delays, "distributed": self.distributed}
        if self.point_radii:
            data["radii"] = list(self.point_radii)
        return json_safe(data)


class QuasiPolynomialsAtPoint:
    """The values of several quasi-polynomials at one complex point: ``tuple(complex(F(s)) for F in functions)``.

    For the many single-point evaluations of a continuation (Newton's method on a zero followed in a
    parameter), where the numpy calls of each term, not their arithmetic, cost most: the exponentials
    ``e^{-tau_k s}`` of the distinct delays of all functions are formed once each (:mod:`cmath`; exactly 1
    for ``tau_k = 0``; by numpy, ``inf`` or ``nan``, beyond the doubles), the polynomials ``p_k(s)`` by
    Horner's scheme in complex arithmetic, and the distributed terms by
    :class:`~nrobust.distributed_delay.TermsAtPoint`, which forms the exponentials of the segments shared by
    several terms (a function and its derivative) once. The values are those of ``F(s)`` to rounding.

    Parameters
    ----------
    functions : sequence of QuasiPolynomial
        The functions, in the order of the values returned.

    Examples
    --------
    >>> F = QuasiPolynomial([[0, 1], [1]], [0, 1])
    >>> at = QuasiPolynomialsAtPoint([F, F.derivative()])
    >>> [round(abs(v), 12) for v in at(0.0)]
    [1.0, 0.0]
    """

    def __init__(self, functions: Sequence[QuasiPolynomial]) -> None:
        self.functions = tuple(functions)
        for F in self.functions:
            if not isinstance(F, QuasiPolynomial):
                raise ParameterError("functions", "a sequence of QuasiPolynomial", F)
        delays = sorted({t for F in self.functions for _, t in F.point_terms})
        self._delays = np.array(delays, dtype=float)
        self._delay_list: list[float] = self._delays.tolist()
        # per function: (index of the delay, coefficients from the highest power down) of each point term
        self._points = tuple(
            tuple((delays.index(t), p[::-1].tolist()) for p, t in F.point_terms) for F in self.functions
        )
        self._owners = tuple(i for i, F in enumerate(self.functions) for _ in F.distributed)
        self._terms = TermsAtPoint([d for F in self.functions for d in F.distributed])

    def __call__(self, s: complex) -> tuple[complex, ...]:
        """The value of each function at ``s``."""
        s = complex(s)
        try:
            exps = [cmath.exp(-(s * t)) if t else 1.0 for t in self._delay_list]
        except (OverflowError, ValueError):  # beyond the doubles: inf or nan, as numpy gives them
            with np.errstate(over="ignore", invalid="ignore"):
                e = np.exp(-(s * self._delays))
            e[self._delays == 0] = 1.0
            exps = e.tolist()
        out = []
        for terms in self._points:
            total = 0j
            for k, coefs in terms:
                value = coefs[0]
                for c in coefs[1:]:
                    value = value * s + c
                total += value * exps[k]
            out.append(total)
        for owner, value in zip(self._owners, self._terms(s)):
            out[owner] += value
        return tuple(out)


def as_quasipolynomial(name: str, value: Any) -> QuasiPolynomial:
    """``value`` as a QuasiPolynomial: itself, or a finite number as a constant.

    Parameters
    ----------
    name : str
        Name of the parameter, for the error message.
    value : QuasiPolynomial or number
        A quasi-polynomial, or a finite real or complex number (a loop factor ``A`` or
        ``B`` of ``A(s) + B(s) e^{-delta s}`` may be a constant).

    Returns
    -------
    QuasiPolynomial

    Raises
    ------
    ParameterError
        ``value`` is neither (booleans are not numbers here), or is not finite.

    Examples
    --------
    >>> as_quasipolynomial("B", 0.5)
    QuasiPolynomial(0.5)
    """
    if isinstance(value, QuasiPolynomial):
        return value
    if isinstance(value, (int, float, complex, np.number)) and not isinstance(value, (bool, np.bool_)):
        if not np.isfinite(value):
            raise ParameterError(name, "a QuasiPolynomial or a finite number", value)
        return QuasiPolynomial([np.atleast_1d(value)], [0.0])
    raise ParameterError(name, "a QuasiPolynomial or a finite number", value)
