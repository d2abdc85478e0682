"""Convolution Volterra equations on a window: the resolvent, a law seen through it, their products.

For a kernel ``N`` (a :class:`~nrobust.distributed_delay.DistributedDelay` term, read on its
first ``w`` units) the convolution equation of the second kind on the window ``[0, w]``

    x(nu) + int_0^nu N(nu - nu') x(nu') dnu' = f(nu),      0 <= nu <= w,

is solved by ``x = f - r * f`` with the resolvent kernel ``r``: ``r + N * r = N`` on ``[0, w]``.
Writing ``r = N - c``, the correction ``c = N * r`` solves

    c(nu) + int_0^nu N(nu - nu') c(nu') dnu' = (N * N)(nu),

and is smoother than ``N`` (each convolution adds a derivative, so a cubic-spline ``N`` gives
a ``c`` with five continuous derivatives, a polynomial-piece ``N`` an analytic one to rounding).
:func:`window_resolvent` collocates ``c`` at ``n`` Chebyshev points of the first kind, the
integrals by Gauss-Legendre rules on the sub-intervals between the breakpoints of both factors
(exact for polynomial pieces while ``n`` is small; beyond, on sub-intervals that shrink as ``1 / n``),
and doubles ``n`` until two solutions agree; the difference is part of the stated
:attr:`WindowKernel.accuracy`. A kernel that jumps inside the window gives ``c`` a kink there, which
the collocation does not resolve: it is refused.

A functional ``int_0^w m(nu) x(t - nu) dnu`` of the solution on a moving window
``(t - w, t]`` is ``int_0^w h(nu) f(t - nu) dnu`` with ``h = m - m * r`` on ``[0, w]`` (swap
the order of integration); :func:`window_law` returns ``h`` (for ``m = N``, ``h = r``).
Both are :class:`WindowKernel`: stored kernels minus a smooth correction held as Chebyshev
series on equal pieces of the window.

:func:`resolvent_product` returns ``A(s) H(s)``, ``H(s) = int_0^w h(nu) e^{-nu s} dnu``,
for a quasi-polynomial ``A`` with constant point coefficients and plain distributed terms, as
one distributed-delay term per interval between the breakpoints of ``A``'s terms shifted by ``0``
and ``w`` (where the product may jump or have a kink; separate terms keep the jumps at the ends
of supports): polynomials of degree :data:`DEGREE` on :data:`SEGMENTS_PER_WINDOW` (or the number
asked) segments per window length, doubled on an interval while their deviation from the product
exceeds a relative tolerance when one is asked, with the largest deviation of the stored polynomials from the product
between their interpolation points in :attr:`ResolventProduct.accuracy`. It is the observer term of an output feedback
(:mod:`nrobust.hyperbolic.loops.output_feedback`).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._validate import positive
from .distributed_delay import DistributedDelay
from .errors import CertificationError, ParameterError
from .quasipoly import QuasiPolynomial

__all__ = ["ResolventProduct", "WindowKernel", "resolvent_product", "window_law", "window_resolvent"]

Array = NDArray[np.float64]

#: Collocation sizes tried in turn (Chebyshev points of the first kind on the window).
SIZES = (16, 32, 64, 128, 256)
#: Relative agreement of two successive collocations that stops the doubling.
TOLERANCE = 1e-12
#: Relative agreement accepted after the largest collocation (a cubic-spline kernel's resolvent
#: converges algebraically; the change is then the stated accuracy).
ACCEPT = 1e-8
#: Segments of the stored product per window length ``w`` (by default), and the degree of its polynomial
#: on each (interpolated at Chebyshev points).
SEGMENTS_PER_WINDOW, DEGREE = 24, 11
#: Doublings of an interval's segments at most, while the fit's deviation exceeds the tolerance asked of
#: :func:`resolvent_product`.
REFINEMENTS = 2
#: Rounding error of the collocated correction, in units of the largest modulus of ``N`` or ``c`` on the
#: window (part of the stated accuracy). Without it, over 150 constant kernels ``a`` in ``[-3, 9]`` on windows
#: up to 1.95, the error exceeded the stated accuracy at the rounding level (by 2.5 times, at 1e-17, for
#: ``a = 0.08``); with it the error is at most 0.79 of the stated accuracy (against the closed form).
ROUNDING = 16 * np.finfo(float).eps
#: Gauss-Legendre points per sub-interval of the collocation at most (:func:`_collocation_rule`).
COLLOCATION_POINTS = 8
#: Pieces of the stored correction ``c`` on the window, and their degree (Chebyshev series).
C_PIECES, C_DEGREE = 32, 15
#: Relative size below which two pieces of a kernel are taken as continuous (their mismatch is
#: rounding, as between the closed-form pieces of the exact delay form).
_CONTINUOUS = 1e-11


def _plain(name: str, term: DistributedDelay) -> None:
    """Refuse a distributed term with a polynomial factor or a moment (not a plain kernel)."""
    if term.poly.size != 1 or term.poly[0] != 1.0 or term.moment != 0:
        raise ParameterError(name, "plain kernels int_a^b N(nu) e^{-nu s} dnu (no polynomial factor, no moment)", term)
    if np.iscomplexobj(term.pieces[2]):
        raise ParameterError(name, "a real kernel", term)


def _evaluate(term: DistributedDelay, x: Array, left: bool = False) -> Array:
    """The stored kernel at ``x`` in ``[a, b]``; at a shared node the left piece's value when ``left``."""
    start, h, poly_t = term.pieces
    if left:
        idx = np.asarray(np.searchsorted(start + h, x, side="left"))
    else:
        idx = np.asarray(np.searchsorted(start, x, side="right") - 1)
    np.minimum(np.maximum(idx, 0, out=idx), start.size - 1, out=idx)  # np.clip, in place
    t = (x - np.take(start, idx)) / np.take(h, idx)
    return _horner(np.ascontiguousarray(poly_t.T), idx, t)


def _horner(rows: Array, idx: NDArray[np.intp], t: Array) -> Array:
    """``sum_l rows[l, idx] t^l`` by Horner's steps, each gathering one power's coefficients at ``idx``.

    The steps of numpy's ``polyval`` (``c_l + out t``, the same numbers) without its table of every
    coefficient at every point, which is many times the points' size.
    """
    out = np.take(rows[-1], idx)
    for row in rows[-2::-1]:
        out *= t
        out += np.take(row, idx)
    return out


def _clenshaw(rows: Array, idx: NDArray[np.intp], t: Array) -> Array:
    """``sum_k rows[k, idx] T_k(t)`` by Clenshaw's recurrence, each step gathering one degree's coefficients.

    The steps of numpy's ``chebval`` (the same numbers) without its table of every coefficient at every
    point.
    """
    if rows.shape[0] == 1:
        return np.take(rows[0], idx) + 0.0 * t
    t2 = 2.0 * t
    c0, c1 = np.take(rows[-2], idx), np.take(rows[-1], idx)
    for row in rows[-3::-1]:
        c0, c1 = np.take(row, idx) - c1, c0 + c1 * t2
    return c0 + c1 * t


def _knots(term: DistributedDelay) -> Array:
    """Every end of a stored segment (where the kernel may change its polynomial)."""
    start, h, _ = term.pieces
    return np.unique(np.concatenate([start, start + h]))


def _jumps(term: DistributedDelay) -> Array:
    """The ends of the support and the nodes where the stored kernel jumps."""
    start, h, poly_t = term.pieces
    left_end = np.sum(poly_t[:-1], axis=1)
    right_start = poly_t[1:, 0]
    scale = float(np.max(np.abs(poly_t))) if poly_t.size else 0.0
    gap = (start[1:] - (start[:-1] + h[:-1])) > 0
    jump = gap | (np.abs(left_end - right_start) > _CONTINUOUS * max(scale, 1e-300))
    inner = np.concatenate([(start[:-1] + h[:-1])[jump], start[1:][gap]])
    return np.unique(np.concatenate([[term.a, term.b], inner]))


@lru_cache(maxsize=16)
def _gauss(points: int) -> tuple[Array, Array]:
    """Gauss-Legendre nodes and weights on ``[0, 1]``."""
    x, w = np.polynomial.legendre.leggauss(points)
    return 0.5 * (x + 1.0), 0.5 * w


def _rules(lo: Array, hi: Array, breaks: Array, points: int) -> tuple[Array, Array, NDArray[np.intp]]:
    """Gauss-Legendre points and weights on each ``[lo_i, hi_i]`` split at the row ``breaks[i]`` inside it.

    Returns the nodes and weights of every row in turn (the sub-intervals in increasing order) and the
    row ``i`` of each node. The breaks outside ``(lo_i, hi_i)`` are moved to its ends, where they split
    off intervals of zero width, dropped; an empty interval (``hi_i <= lo_i``) has no node.
    """
    hi = np.maximum(hi, lo)  # an empty interval: every width zero
    edges = np.sort(np.clip(breaks, lo[:, None], hi[:, None]), axis=1)
    edges = np.concatenate([lo[:, None], edges, hi[:, None]], axis=1)
    widths = np.diff(edges, axis=1)
    keep = widths > 0
    t, g = _gauss(points)
    left, width = edges[:, :-1][keep], widths[keep]
    nodes = (left[:, None] + width[:, None] * t).ravel()
    weights = (width[:, None] * g).ravel()
    owner = np.repeat(np.nonzero(keep)[0], points)
    return nodes, weights, owner


def _chebyshev(n: int, window: float) -> tuple[Array, Array]:
    """First-kind Chebyshev points on ``[0, window]`` (increasing) and their barycentric weights."""
    theta = (2.0 * np.arange(n) + 1.0) * np.pi / (2.0 * n)
    nodes = 0.5 * window * (1.0 - np.cos(theta))
    weights = (-1.0) ** np.arange(n) * np.sin(theta)
    return nodes, weights


def _barycentric(nodes: Array, weights: Array, x: Array) -> Array:
    """Rows interpolating values at ``nodes`` to the points ``x`` (barycentric formula)."""
    diff = x[:, None] - nodes[None, :]
    exact = diff == 0.0
    diff[exact] = 1.0
    rows = weights[None, :] / diff
    rows /= np.sum(rows, axis=1, keepdims=True)
    hit = np.flatnonzero(np.any(exact, axis=1))
    rows[hit] = exact[hit].astype(float)
    return rows


@lru_cache(maxsize=4)
def shifted_chebyshev(degree: int) -> Array:
    """The coefficients of ``T_k(2 t - 1)``, ``k = 0..degree``, in increasing powers of ``t`` (column ``k``;
    integers, exact in floating point for the degrees used here)."""
    rows = [[1], [-1, 2]]  # T_{k+1} = 2 (2 t - 1) T_k - T_{k-1}
    while len(rows) <= degree:
        a, b = rows[-1], rows[-2]
        nxt = [0] * (len(a) + 1)
        for j, c in enumerate(a):
            nxt[j] -= 2 * c
            nxt[j + 1] += 4 * c
        for j, c in enumerate(b):
            nxt[j] -= c
        rows.append(nxt)
    powers = np.zeros((degree + 1, degree + 1))
    for k, row in enumerate(rows[: degree + 1]):
        powers[: len(row), k] = row
    powers.flags.writeable = False
    return powers


def _sum_terms(terms: tuple[DistributedDelay, ...], x: Array, left: bool) -> Array:
    """The sum of stored kernels at ``x`` (zero outside each one's support)."""
    out = np.zeros(x.shape)
    for term in terms:
        inside = (x >= term.a) & (x <= term.b)
        if np.any(inside):
            out[inside] += _evaluate(term, x[inside], left=left)
    return out


def _window_knots(terms: tuple[DistributedDelay, ...], window: float) -> Array:
    """The breakpoints of the stored kernels inside ``(0, window)``."""
    if not terms:
        return np.zeros(0)
    knots = np.unique(np.concatenate([_knots(t) for t in terms]))
    return knots[(knots > 0.0) & (knots < window)]


@dataclass(frozen=True)
class WindowKernel:
    """A kernel on the window ``[0, w]``: stored kernels minus a smooth correction (module notes).

    Attributes
    ----------
    terms : tuple of DistributedDelay
        The stored kernels (read on ``[0, w]``, zero outside their supports): ``N`` for the
        resolvent, the law's ``m`` for :func:`window_law`.
    window : float
        ``w``.
    coefficients : ndarray
        The correction as Chebyshev series on :data:`C_PIECES` equal pieces of the window (one
        row per piece, in the piece's variable mapped to ``[-1, 1]``).
    accuracy : float
        An estimate (not a bound) of the largest error of the kernel on the window: the
        change between the last two collocations, the stored pieces' deviation from them and
        a rounding term (:data:`ROUNDING`).
    """

    terms: tuple[DistributedDelay, ...]
    window: float
    coefficients: Array
    accuracy: float

    @property
    def knots(self) -> Array:
        """The breakpoints of the stored kernels inside the window."""
        return _window_knots(self.terms, self.window)

    @property
    def degree(self) -> int:
        """The largest degree of the stored kernels' pieces."""
        return max((t.pieces[2].shape[1] - 1 for t in self.terms), default=0)

    def correction(self, nu: ArrayLike) -> Array:
        """The smooth correction at ``nu`` in ``[0, w]``."""
        x = np.asarray(nu, dtype=float)
        flat = x.ravel()
        pieces = self.coefficients.shape[0]
        position = flat / self.window * pieces
        idx = position.astype(int)
        np.minimum(np.maximum(idx, 0, out=idx), pieces - 1, out=idx)  # np.clip, in place
        t = 2.0 * (position - idx) - 1.0
        return _clenshaw(np.ascontiguousarray(self.coefficients.T), idx, t).reshape(x.shape)

    def __call__(self, nu: ArrayLike) -> Array:
        """The kernel at ``nu`` in ``[0, w]`` (the stored kernels' left values at ``w``)."""
        x = np.asarray(nu, dtype=float)
        flat = x.ravel()
        return (_sum_terms(self.terms, flat, left=True) - self.correction(flat)).reshape(x.shape)

    def __repr__(self) -> str:
        return f"WindowKernel(window={self.window:.6g}, terms={len(self.terms)}, accuracy={self.accuracy:.1e})"


def _kernel_pieces(kernel: WindowKernel) -> tuple[Array, int]:
    """The breakpoints of a window kernel inside the window (its stored kernels' knots and the edges of
    its correction's equal pieces, when it has one) and its largest degree on the pieces between them.

    A Gauss-Legendre rule of ``(d + degree) // 2 + 1`` points on each piece is exact for the kernel
    times a polynomial of degree ``d``.
    """
    pieces, degree = kernel.coefficients.shape[0], kernel.coefficients.shape[1] - 1
    if not np.any(kernel.coefficients):
        return kernel.knots, kernel.degree
    edges = kernel.window * np.arange(1, pieces) / pieces
    return np.concatenate([kernel.knots, edges]), max(kernel.degree, degree)


def _collocation_rule(kernel: DistributedDelay, window: float, n: int) -> tuple[int, Array]:
    """Gauss-Legendre points per sub-interval of the collocation with ``n`` points, and the extra breaks.

    On a sub-interval the integrand of ``M`` is a stored piece of degree ``d`` times the interpolant of
    degree ``n - 1``, that of the right-hand side the product of two pieces (degree ``2 d``): ``p``
    points, exact to degree ``2 p - 1``, are exact for both from ``p = max((d + n + 1) // 2, d + 1)``.
    Beyond :data:`COLLOCATION_POINTS` the window is cut into ``ceil(p / COLLOCATION_POINTS)`` equal
    parts (the returned breaks) with that many points on each sub-interval: the sub-intervals shrink as
    ``1 / n``, so the quadrature error on the smooth correction falls with ``n`` faster than the
    interpolation's (as ``n^{-2 COLLOCATION_POINTS}``) and the doubling of ``n`` measures both. With a
    rule fixed for all ``n``, a kernel with few knots (long sub-intervals) had the same quadrature error
    for every ``n``, and successive collocations agreed to far better than their error.
    """
    degree = kernel.pieces[2].shape[1] - 1
    exact = max((degree + n + 1) // 2, degree + 1)
    if exact <= COLLOCATION_POINTS:
        return exact, np.zeros(0)
    parts = -(-exact // COLLOCATION_POINTS)
    return COLLOCATION_POINTS, window * np.arange(1, parts) / parts


def _collocate(kernel: DistributedDelay, window: float, n: int, knots: Array) -> tuple[Array, Array]:
    """``c`` at ``n`` Chebyshev points: ``(I + M) c = (N * N)`` (module notes).

    ``M`` integrates ``N(nu_i - .)`` against the interpolant of ``c`` on sub-intervals split
    where ``N(nu_i - .)`` changes piece; the right-hand side also where ``N(.)`` does; both also at
    the breaks of :func:`_collocation_rule`, whose quadrature error falls as ``n`` grows.
    """
    nodes, weights = _chebyshev(n, window)
    points, cuts = _collocation_rule(kernel, window, n)
    zero = np.zeros(n)
    lags = nodes[:, None] - knots[None, :]
    grid = np.broadcast_to(cuts, (n, cuts.size))
    q, g, owner = _rules(zero, nodes, np.concatenate([lags, grid], axis=1), points)
    rows = (_evaluate(kernel, nodes[owner] - q) * g)[:, None] * _barycentric(nodes, weights, q)
    matrix = np.eye(n)
    matrix[np.unique(owner)] += np.add.reduceat(rows, np.flatnonzero(np.diff(owner, prepend=-1)), axis=0)
    breaks = np.concatenate([np.broadcast_to(knots, lags.shape), lags, grid], axis=1)
    q, g, owner = _rules(zero, nodes, breaks, points)
    rhs = np.bincount(owner, weights=_evaluate(kernel, nodes[owner] - q) * g * _evaluate(kernel, q), minlength=n)
    return nodes, np.asarray(np.linalg.solve(matrix, rhs), dtype=float)


def _store(function: Callable[[Array], Array], window: float) -> tuple[Array, float]:
    """A smooth ``function`` on the window as Chebyshev series on equal pieces, and their largest deviation."""
    fit_t = np.cos((2.0 * np.arange(C_DEGREE + 1) + 1.0) * np.pi / (2.0 * (C_DEGREE + 1)))
    check_t = np.linspace(-1.0, 1.0, 2 * C_DEGREE + 1)
    width = window / C_PIECES
    left = np.arange(C_PIECES)[:, None] * width
    values = function((left + 0.5 * width * (fit_t + 1.0)).ravel()).reshape(C_PIECES, -1)
    exact = function((left + 0.5 * width * (check_t + 1.0)).ravel()).reshape(C_PIECES, -1)
    rows = np.polynomial.chebyshev.chebfit(fit_t, values.T, C_DEGREE).T
    stored = np.polynomial.chebyshev.chebval(check_t, rows.T)
    return rows, float(np.max(np.abs(stored - exact)))


def window_resolvent(kernel: DistributedDelay, window: float) -> WindowKernel:
    """The resolvent kernel of ``N`` on ``[0, window]``, by collocation of its correction (module notes).

    Parameters
    ----------
    kernel : DistributedDelay
        A plain real kernel (no polynomial factor, no moment) whose support starts at 0 and
        covers the window.
    window : float
        ``w > 0``.

    Returns
    -------
    WindowKernel
        ``r = N - c``.

    Raises
    ------
    ParameterError
        A kernel that is not plain or does not cover ``[0, window]``.
    CertificationError
        The collocation does not settle to :data:`ACCEPT` within :data:`SIZES` (as for a kernel
        that jumps inside the window).
    """
    _plain("kernel", kernel)
    w = positive("window", window)
    if kernel.a != 0.0 or kernel.b < w:
        raise ParameterError("kernel", f"a kernel on [0, b] with b >= window = {w:.6g}", kernel)
    knots = _window_knots((kernel,), w)
    check = np.linspace(0.0, w, 257)
    scale = max(float(np.max(np.abs(_evaluate(kernel, check, left=True)))), 1e-300)
    previous: tuple[Array, Array] | None = None
    error = size = np.inf
    for n in SIZES:
        nodes, values = _collocate(kernel, w, n, knots)
        if previous is not None:
            old = _barycentric(previous[0], _chebyshev(previous[0].size, w)[1], check) @ previous[1]
            new = _barycentric(nodes, _chebyshev(n, w)[1], check) @ values
            error = float(np.max(np.abs(new - old)))
            size = max(scale, float(np.max(np.abs(new))))
            if error <= TOLERANCE * scale:
                break
        previous = (nodes, values)
    if error > ACCEPT * scale:
        jumps = _jumps(kernel)
        jumps = jumps[(jumps > 0.0) & (jumps < w)]
        cause = (
            f"the kernel jumps inside the window (at {', '.join(f'{j:.6g}' for j in jumps)}), where the "
            "resolvent's correction has a kink; a continuous kernel (or a window ending before the first jump)"
            if jumps.size
            else "a smoother kernel (a finer kernel grid)"
        )
        raise CertificationError(
            f"window_resolvent: the collocation of the resolvent did not settle to {ACCEPT:g} with "
            f"{SIZES[-1]} points (last change {error:.1e}); {cause} would help"
        )
    weights = _chebyshev(nodes.size, w)[1]
    coefficients, deviation = _store(lambda x: _barycentric(nodes, weights, x) @ values, w)
    return WindowKernel((kernel,), w, coefficients, error + deviation + ROUNDING * size)


def window_law(terms: tuple[DistributedDelay, ...], resolvent: WindowKernel) -> WindowKernel:
    """``h = m - m * r`` on the window: the law ``int_0^w m x`` applied to the solution ``x = f - r * f``.

    Parameters
    ----------
    terms : tuple of DistributedDelay
        The plain kernels whose sum is ``m`` on the window (zero outside their supports).
    resolvent : WindowKernel
        ``r`` of the window's equation (:func:`window_resolvent`).

    Returns
    -------
    WindowKernel
        ``h``; its accuracy adds the resolvent's times the L1 norm of ``m`` on the window.
    """
    for term in terms:
        _plain("terms", term)
    w = resolvent.window
    m_knots = _window_knots(terms, w)
    r_knots, r_degree = _kernel_pieces(resolvent)
    points = (max((t.pieces[2].shape[1] - 1 for t in terms), default=0) + r_degree) // 2 + 1

    def convolution(sigma: Array) -> Array:
        breaks = np.concatenate(
            [np.broadcast_to(m_knots, (sigma.size, m_knots.size)), sigma[:, None] - r_knots[None, :]], axis=1
        )
        q, g, owner = _rules(np.zeros(sigma.size), sigma, breaks, points)
        lag = sigma[owner] - q
        weights = g * _sum_terms(terms, q, left=False) * resolvent(lag)
        return np.asarray(np.bincount(owner, weights=weights, minlength=sigma.size), dtype=float)

    coefficients, deviation = _store(convolution, w)
    grid = np.linspace(0.0, w, 513)
    l1 = float(np.mean(np.abs(_sum_terms(terms, grid, left=True)))) * w
    return WindowKernel(tuple(terms), w, coefficients, deviation + resolvent.accuracy * (1.0 + l1))


@dataclass(frozen=True)
class ResolventProduct:
    """``A(s) H(s)`` as distributed-delay terms (module notes).

    Attributes
    ----------
    product : QuasiPolynomial
        The product: one distributed term of polynomial pieces per interval between breakpoints.
    accuracy : float
        Estimated sup-norm error of the stored kernels: their largest deviation from the
        product's kernel between the interpolation points, plus the window kernel's
        :attr:`WindowKernel.accuracy` times the total weight of ``A`` (point coefficients and
        the L1 norm of its kernels).
    kernel : WindowKernel
        ``h``.
    """

    product: QuasiPolynomial
    accuracy: float
    kernel: WindowKernel


def _factor_parts(a: QuasiPolynomial) -> tuple[list[tuple[float, float]], list[DistributedDelay]]:
    """Constant point terms ``(coefficient, delay)`` and plain distributed terms of ``a``."""
    points = []
    for coefs, delay in a.point_terms:
        if coefs.size != 1 or np.iscomplexobj(coefs):
            raise ParameterError("factor", "a quasi-polynomial with real constant point coefficients", a)
        points.append((float(coefs[0]), float(delay)))
    for term in a.distributed:
        _plain("factor", term)
    return points, list(a.distributed)


def _product_kernel(
    points: list[tuple[float, float]], terms: list[DistributedDelay], h: WindowKernel, nu: Array, middle: float
) -> Array:
    """The kernel of ``A H`` at ``nu`` in one piece (``middle`` decides the active point terms)."""
    w = h.window
    out = np.zeros(nu.size)
    for c, delay in points:
        if delay < middle < delay + w:
            out += c * h(np.clip(nu - delay, 0.0, w))
    h_knots, h_degree = _kernel_pieces(h)
    for term in terms:
        knots = _knots(term)
        count = (term.pieces[2].shape[1] - 1 + h_degree) // 2 + 1
        breaks = np.concatenate(
            [np.broadcast_to(h_knots, (nu.size, h_knots.size)), nu[:, None] - knots[None, :]], axis=1
        )
        q, g, owner = _rules(np.maximum(0.0, nu - term.b), np.minimum(w, nu - term.a), breaks, count)
        if q.size:
            out += np.bincount(owner, weights=g * _evaluate(term, nu[owner] - q) * h(q), minlength=nu.size)
    return out


def _fit_interval(
    points: list[tuple[float, float]], terms: list[DistributedDelay], h: WindowKernel, lo: float, hi: float, count: int
) -> tuple[DistributedDelay, float, float]:
    """The kernel of ``A H`` on ``[lo, hi]`` as polynomials of degree :data:`DEGREE` on ``count`` equal segments.

    Interpolated at the first-kind Chebyshev points of each segment (the Chebyshev series, then its
    exact conversion to powers of the segment's variable ``t`` in ``[0, 1]``). Returns the term, the
    largest deviation of the stored polynomials from the kernel at the midpoints between the
    interpolation points, and the largest modulus of the kernel there.
    """
    cuts = np.linspace(lo, hi, count + 1)
    middle = 0.5 * (lo + hi)
    step = np.diff(cuts)
    fit_t = 0.5 * (1.0 - np.cos((2.0 * np.arange(DEGREE + 1) + 1.0) * np.pi / (2.0 * (DEGREE + 1))))
    check_t = (np.arange(DEGREE) + 0.5) / DEGREE
    values = _product_kernel(points, terms, h, (cuts[:-1, None] + step[:, None] * fit_t).ravel(), middle)
    exact = _product_kernel(points, terms, h, (cuts[:-1, None] + step[:, None] * check_t).ravel(), middle)
    series = np.polynomial.chebyshev.chebfit(2.0 * fit_t - 1.0, values.reshape(count, -1).T, DEGREE)
    coefficients = (shifted_chebyshev(DEGREE) @ series).T
    stored = coefficients @ np.polynomial.polynomial.polyvander(check_t, DEGREE).T
    error = float(np.max(np.abs(stored - exact.reshape(count, -1))))
    term = DistributedDelay(cuts, None, interpolation="polynomial", coefficients=coefficients)
    return term, error, float(np.max(np.abs(exact)))


def resolvent_product(
    factor: QuasiPolynomial, kernel: WindowKernel, segments: int = SEGMENTS_PER_WINDOW, tolerance: float | None = None
) -> ResolventProduct:
    """``factor(s) H(s)`` with ``H`` the Laplace transform of a window kernel.

    Parameters
    ----------
    factor : QuasiPolynomial
        ``A``: real constant point coefficients and plain distributed terms (an open-loop
        characteristic function ``1 - Phi`` of the delay form, eq. (39)).
    kernel : WindowKernel
        ``h`` on ``[0, w]`` (:func:`window_resolvent`, :func:`window_law`).
    segments : int, default :data:`SEGMENTS_PER_WINDOW`
        Segments of the stored polynomials per window length (``>= 1``).
    tolerance : float, optional
        With it, the segments of an interval between breakpoints are doubled (at most
        :data:`REFINEMENTS` times) while the stored polynomials deviate from the product by more
        than ``tolerance`` times its largest modulus there.

    Returns
    -------
    ResolventProduct

    Raises
    ------
    ParameterError
        ``segments`` not a positive integer, ``tolerance`` not positive, or a zero ``factor``.
    """
    if isinstance(segments, bool) or not isinstance(segments, (int, np.integer)) or segments < 1:
        raise ParameterError("segments", "an integer >= 1", segments)
    rtol = None if tolerance is None else positive("tolerance", tolerance)
    points, terms = _factor_parts(factor)
    w = kernel.window
    breaks = [d + e for _, d in points for e in (0.0, w)]
    breaks += [j + e for term in terms for j in _jumps(term) for e in (0.0, w)]
    edges = np.unique(np.round(np.asarray(breaks, dtype=float), 14))
    if edges.size < 2:
        raise ParameterError("factor", "a nonzero quasi-polynomial", factor)
    width = w / segments
    pieces, deviation = [], 0.0
    for lo, hi in itertools.pairwise(edges):
        count = max(1, int(np.ceil((hi - lo) / width - 1e-9)))
        for _ in range(REFINEMENTS + 1 if rtol is not None else 1):
            piece, error, scale = _fit_interval(points, terms, kernel, float(lo), float(hi), count)
            if rtol is None or error <= rtol * scale:
                break
            count *= 2
        pieces.append(piece)
        deviation = max(deviation, error)
    weight = sum(abs(c) for c, _ in points) + sum(float(term.abs_moment(0.0)) for term in terms)
    accuracy = deviation + kernel.accuracy * weight
    return ResolventProduct(QuasiPolynomial([], [], pieces), accuracy, kernel)
