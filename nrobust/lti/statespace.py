"""Linear time-delay systems in state-space form, as the time-delay community writes them.

The system (retarded, neutral, descriptor; TDS-CONTROL and tdcpy write the same)::

    E x'(t) = sum_k A_k x(t - hA_k) + sum_k B_k x'(t - hB_k) + sum_j G_j int N_j(nu) x(t - nu) dnu

has the characteristic matrix

    M(s) = s E - sum_k A_k e^{-hA_k s} - s sum_k B_k e^{-hB_k s} - sum_j G_j int N_j(nu) e^{-nu s} dnu,

taken here as a :class:`~nrobust.qpmatrix.QuasiPolynomialMatrix` (the determinant is
not expanded in floating point), so its roots, spectral abscissa and root counts are
certified by :mod:`nrobust.roots`. Without distributed terms, :meth:`StateSpaceTDS.roots`
counts on ``det M`` expanded in exact rational arithmetic and rounded once, with a proven bound of
the rounding that keeps every count one of ``det M``
(:meth:`~nrobust.qpmatrix.QuasiPolynomialMatrix.exact_expansion`): the bounds of the matrix form
miss the cancellations of the determinant (of a descriptor system above all), and one scalar
quasi-polynomial costs less to evaluate and to bound than ``n`` determinants. The distributed
kernel ``G(nu) = sum_j G_j N_j(nu)`` is a sum of constant matrices times scalar tabulated
kernels (:class:`~nrobust.quasipoly.DistributedDelay`).
For an invertible ``E``, the neutral part gives the matrix difference operator
``D(s) = I - sum_k E^{-1} B_k e^{-hB_k s}``, whose strong stability (Hale and Verduyn
Lunel) decides robustness to small changes of the delays. For a singular ``E`` (a delay
differential-algebraic system, no neutral terms) the chains come from the algebraic part:
with orthonormal bases ``U`` of the kernel of ``E^T`` and ``V`` of the kernel of ``E``,
the Schur complement of ``s E - A(s)`` tends to ``-U^T A(s) V`` as ``|s| -> oo``, so
``D(s) = I + sum_k (U^T A_0 V)^{-1} U^T A_k V e^{-hA_k s}`` when ``U^T A_0 V`` is
invertible (``A_0`` the sum of the undelayed matrices). This is the delay-difference
equation that TDS-CONTROL (Appeltans and Michiels, "Analysis and controller-design of
time-delay systems using TDS-CONTROL. A tutorial and manual", arXiv:2305.00341, 2023) and
its Python port tdcpy associate with a descriptor system (tdcpy's ``spectral_abscissa_diff``,
after Michiels, "Spectrum-based stability analysis and stabilisation of systems described by
delay differential algebraic equations", IET Control Theory Appl. 5(16), 1829-1842, 2011).

Roots right of a vertical line (TDS-CONTROL's ``r``) are finitely many when the neutral
part is small there: ``s x = E^{-1}(A(s) + s B(s) + G(s)) x`` gives
``|s| (1 - sum_k ||E^{-1} B_k|| e^{-hB_k x}) <= sum_k ||E^{-1} A_k|| e^{-hA_k x} + sum_j
||E^{-1} G_j|| int |N_j| e^{-nu x}`` on ``Re s >= x`` (:meth:`StateSpaceTDS.root_radius`),
so :meth:`StateSpaceTDS.roots_right_of` counts a rectangle that holds them all: as this
radius ``R(x)`` decreases in ``x`` and ``Re s <= |s|``, every such root has
``Re s <= x*``, the fixed point ``x* = R(x*)``, which closes the rectangle on the right.

Newton's method in :func:`~nrobust.roots.find_roots` is seeded with the eigenvalues of a
Chebyshev collocation of the infinitesimal generator (Breda, Maset and Vermiglio,
"Pseudospectral differencing methods for characteristic roots of delay differential
equations", SIAM J. Sci. Comput. 27(2), 482-495, 2005; the discretisation TDS-CONTROL uses):
approximations only, each root still accepted by a certified count of a box about it and
the whole set by the count of the rectangle (the argument principle). Only what the delayed
terms read (their nonzero columns, or their nonzero rows when fewer) keeps a history in the
collocation, and the algebraic equations of a singular ``E`` are eliminated, so that the
eigenvalue problem is a standard one of that order (the seeds of Example 2.9: order 24
instead of 48).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._threads import one_blas_thread
from .._validate import finite_real, real_array
from .._validate import region as check_region
from ..errors import ParameterError
from ..matrix_difference import MatrixDifferenceOperator
from ..qpmatrix import MAX_MATRIX_SIZE, ExpandedDeterminant, QuasiPolynomialMatrix
from ..quasipoly import DistributedDelay, QuasiPolynomial
from ..roots import RootSet, SpectralAbscissa, find_roots, spectral_abscissa

__all__ = ["StateSpaceTDS"]


# Collocation points of the generator per unit of |Im s| tau (a Chebyshev grid resolves
# e^{i w theta} on [-tau, 0] with about w tau / 2 points; seeds within 1e-4 of the roots
# need fewer), the points added to that, and the largest order of the collocation matrix
# (its eigenvalues cost O(order^3)); the largest condition number of the first block row
# of the pencil's right side for the reduction to a standard eigenvalue problem.
_POINTS_PER_FREQUENCY = 0.3
_MIN_POINTS = 12
_MAX_ORDER = 480
# The points of the seeds of roots(): Newton's method needs seeds in its basin, not the 1e-8 of
# generator_eigenvalues (4e-7 at |Im s| < 10 for x' = -x(t - 1)); the order (about n + nd points)
# sets the cost, cubic. About w tau / 2 points resolve e^{i w theta} on [-tau, 0]: the seeds take
# _SEED_EXTRA_POINTS more (Example 2.9, w tau = 10: 7 points, seeds within 2e-7 of the roots, order
# 24 instead of 47), at most the 0.3 w tau + _SEED_MIN_POINTS of the seeds of a wide region, which
# need not resolve the highest frequencies to land in the basins of the roots.
_SEED_MIN_POINTS = 8
_SEED_EXTRA_POINTS = 2
_MAX_CONDITION = 1e8
# For a singular E: the shift of the shift-and-invert reduction of the pencil (an arbitrary
# real number, unlikely to be a root; a singular A - shift B falls back to the QZ algorithm),
# and the relative size below which 1 / (s - shift) stands for an infinite s.
_SHIFT = 0.3183098861837907
_NEGLIGIBLE = 1e-12
# Machine epsilon: singular values of E below n eps times the largest are zero (its rank).
_EPS = float(np.finfo(float).eps)
# Bisection steps of the abscissa bound x* = R(x*) (each halves the bracket).
_BISECTIONS = 80
# Eigenvalue problems of the collocated generator a system keeps (one per number of points, the last ones).
_KEPT_COLLOCATIONS = 4


@functools.lru_cache(maxsize=16)
def _chebyshev_unit(points: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Chebyshev extremal points ``x_j = cos(pi j / points)`` on ``[-1, 1]`` and their differentiation matrix
    (kept for the last few numbers of points: a table, the same for every system; read only)."""
    j = np.arange(points + 1)
    x = np.cos(np.pi * j / points)
    c = np.where((j == 0) | (j == points), 2.0, 1.0) * (-1.0) ** j
    dx = x[:, None] - x[None, :]
    d = np.outer(c, 1.0 / c) / (dx + np.eye(points + 1))
    d.flat[:: points + 2] -= d.sum(axis=1)  # the diagonal: the rows of a differentiation matrix sum to 0
    x.flags.writeable = d.flags.writeable = False
    return x, d


def _chebyshev(points: int, tau: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Chebyshev extremal points ``theta_j`` on ``[-tau, 0]`` (``theta_0 = 0``) and the differentiation matrix."""
    x, d = _chebyshev_unit(points)
    return 0.5 * tau * (x - 1.0), d * (2.0 / tau)


def _interpolation_row(theta: NDArray[np.float64], at: float) -> NDArray[np.float64]:
    """Weights of the polynomial interpolant on the Chebyshev points ``theta`` at ``at`` (barycentric)."""
    hit = (theta == at).nonzero()[0]
    row = np.zeros(theta.size)
    if hit.size:
        row[hit[0]] = 1.0
        return row
    j = np.arange(theta.size)
    w = np.where((j == 0) | (j == theta.size - 1), 0.5, 1.0) * (-1.0) ** j / (at - theta)
    return w / np.sum(w)


def _inverted(a: NDArray[Any], b: NDArray[Any]) -> NDArray[np.float64] | None:
    """``(a - shift b)^{-1} b`` for the pencil ``a v = s b v`` (``b`` singular), or None if ``a - shift b``
    is singular to working precision (``shift`` is a root): its eigenvalues ``mu = 1 / (s - shift)``
    are a standard problem (half the work of the QZ algorithm), :func:`_uninverted` maps them back."""
    try:
        return np.asarray(np.linalg.solve(a - _SHIFT * b, b), dtype=float)
    except np.linalg.LinAlgError:
        return None


def _uninverted(inverted: NDArray[np.float64]) -> NDArray[np.complex128] | None:
    """Finite eigenvalues ``s = shift + 1 / mu`` of the pencil from the eigenvalues ``mu`` of :func:`_inverted`.

    The infinite ``s`` give ``mu = 0`` and are dropped; None if some ``mu`` is not finite.
    """
    mu = np.linalg.eigvals(inverted)
    if not np.all(np.isfinite(mu)):
        return None
    mu = mu[np.abs(mu) > _NEGLIGIBLE * np.max(np.abs(mu), initial=0.0)]
    return np.asarray(_SHIFT + 1.0 / mu, dtype=complex)


def _block_row(rows: NDArray[np.float64], mats: NDArray[np.float64]) -> NDArray[np.float64]:
    """``sum_k kron(rows[k], mats[k])`` for ``rows`` ``(K, m)`` and ``mats`` ``(K, n, p)``: shape ``(n, m p)``."""
    K, n, p = mats.shape
    m = rows.shape[1]
    return (rows.T @ mats.reshape(K, n * p)).reshape(m, n, p).transpose(1, 0, 2).reshape(n, m * p)


def _combination(weights: NDArray[np.float64], mats: NDArray[np.float64]) -> NDArray[np.float64]:
    """``sum_k weights[k] mats[k]`` for ``mats`` ``(K, n, p)``."""
    return (weights @ mats.reshape(mats.shape[0], -1)).reshape(mats.shape[1:])


def _eliminate_algebraic(
    top: NDArray[np.float64], rest: NDArray[np.float64], svd: tuple[NDArray[np.float64], ...]
) -> NDArray[np.float64] | None:
    """A matrix whose eigenvalues are the finite ``s`` of ``[top; rest] v = s [[b0, 0], [0, I]] v`` (``b0`` singular).

    With ``svd`` the singular value decomposition ``b0 = U S V^T`` (rank ``r``), ``v = (v_0, w)`` and
    ``y = V^T v_0``: the rows ``U_2^T top v = 0`` of the zero singular values are algebraic
    constraints, solved for ``y_2 = V_2^T v_0`` when ``U_2^T top_0 V_2`` (``top_0`` the columns
    of ``v_0``) is invertible (index 1); what remains,
    ``S_1^{-1} U_1^T top v = s y_1`` and ``rest v = s w``, is a standard problem in ``z = (y_1, w)``
    (``w`` the collocated history), whose eigenvalues are the finite ones of the pencil. None when
    that block is ill conditioned, ``b0 = 0``, or no singular value of ``b0`` is at rounding level
    (an ill-conditioned ``b0`` of full numerical rank: no algebraic constraint to solve).
    """
    u, sig, vt = svd
    n = sig.size
    r = int(np.sum(sig > n * _EPS * sig[0]))
    if r in (0, n):
        return None
    v1, v2 = vt[:r].T, vt[r:].T
    c = u[:, r:].T @ top  # the constraints c v = 0
    uc, sc, vct = np.linalg.svd(c[:, :n] @ v2)  # its condition number and its solution at once
    if not sc[-1] * _MAX_CONDITION > sc[0]:
        return None
    x = -vct.T @ ((uc.T @ np.hstack([c[:, :n] @ v1, c[:, n:]])) / sc[:, None])  # y_2 = x z
    t0 = v2 @ x  # v_0 = t0 z
    t0[:, :r] += v1

    def reduced(rows: NDArray[np.float64]) -> NDArray[np.float64]:
        """``rows @ T`` with ``v = T z``: ``v_0 = t0 z``, ``w = z[r:]``."""
        out = rows[:, :n] @ t0
        out[:, r:] += rows[:, n:]
        return out

    return np.vstack([reduced((u[:, :r].T @ top) / sig[:r, None]), reduced(rest)])


@dataclass(frozen=True)
class _Collocation:
    """The eigenvalue problem ``a v = s b v`` of a collocated generator (:meth:`StateSpaceTDS.generator_eigenvalues`).

    ``b`` None: the standard problem ``a v = s v`` (the pencil reduced to it). Otherwise the finite
    eigenvalues are found from ``inverted``, the shift and invert of the pencil (:func:`_uninverted`),
    or, failing that, by the QZ algorithm. The matrices depend on the system and the number of
    points only, so the system keeps them (``StateSpaceTDS._collocations``) and each call of
    :meth:`eigenvalues` is one eigenvalue computation.
    """

    a: NDArray[np.float64]
    b: NDArray[np.float64] | None = None
    inverted: NDArray[np.float64] | None = None

    def eigenvalues(self) -> NDArray[np.complex128]:
        """The finite eigenvalues."""
        if self.b is None:
            vals = np.linalg.eigvals(self.a)
        else:
            found = None if self.inverted is None else _uninverted(self.inverted)
            if found is None:
                from scipy.linalg import eig  # lazily: a slow import

                found = eig(self.a, self.b, right=False)
            vals = found
        return np.asarray(vals[np.isfinite(vals)], dtype=complex)


def _stack(name: str, mats: Any, n: int | None) -> NDArray[np.float64]:
    a = real_array(name, mats, ndim=3, min_size=0) if np.size(mats) else np.zeros((0, n or 0, n or 0))
    if n is not None and a.shape[1:] != (n, n):
        raise ParameterError(name, f"a sequence of {n} x {n} real matrices", a.shape)
    return a


@dataclass(frozen=True, eq=False)
class StateSpaceTDS:
    """``E x' = sum A_k x(t - hA_k) + sum B_k x'(t - hB_k) + sum G_j int N_j(nu) x(t - nu) dnu``.

    Parameters
    ----------
    A : array_like, shape (kA, n, n)
        Retarded matrices (``hA_k = 0`` gives the undelayed ``A_0``).
    hA : array_like, shape (kA,)
        Their delays ``>= 0``.
    B : array_like, shape (kB, n, n), optional
        Neutral matrices (of the delayed derivatives).
    hB : array_like, shape (kB,), optional
        Their delays ``> 0``.
    E : array_like, shape (n, n), optional
        The descriptor matrix (identity by default).
    distributed : sequence of (matrix, DistributedDelay), optional
        The terms ``G_j int N_j(nu) x(t - nu) dnu``.

    Examples
    --------
    >>> sys = StateSpaceTDS([[[-1.0]], [[-0.5]]], [0.0, 1.0])
    >>> complex(sys.characteristic_matrix()(0.0))
    (1.5+0j)
    """

    A: NDArray[np.float64]
    hA: NDArray[np.float64]
    B: NDArray[np.float64]
    hB: NDArray[np.float64]
    E: NDArray[np.float64]
    distributed: tuple[tuple[NDArray[np.float64], DistributedDelay], ...]

    def __init__(
        self,
        A: ArrayLike,
        hA: ArrayLike,
        B: ArrayLike = (),
        hB: ArrayLike = (),
        E: ArrayLike | None = None,
        distributed: Sequence[tuple[ArrayLike, DistributedDelay]] = (),
    ) -> None:
        a = _stack("A", A, None)
        if a.shape[0] == 0:
            raise ParameterError("A", "at least one matrix", A)
        n = a.shape[1]
        if a.shape[2] != n:
            raise ParameterError("A", "square matrices", a.shape)
        ha = real_array("hA", hA)
        if ha.shape != (a.shape[0],) or np.any(ha < 0):
            raise ParameterError("hA", f"{a.shape[0]} delays >= 0", hA)
        b = _stack("B", B, n)
        hb = real_array("hB", hB, min_size=0)
        if hb.shape != (b.shape[0],) or np.any(hb <= 0):
            raise ParameterError("hB", f"{b.shape[0]} delays > 0", hB)
        e = np.eye(n) if E is None else real_array("E", E, ndim=2)
        if e.shape != (n, n):
            raise ParameterError("E", f"an {n} x {n} real matrix", e.shape)
        dist = []
        for j, term in enumerate(distributed):
            if not (isinstance(term, tuple) and len(term) == 2 and isinstance(term[1], DistributedDelay)):
                raise ParameterError(f"distributed[{j}]", "a pair (matrix, DistributedDelay)", term)
            g = real_array(f"distributed[{j}]", term[0], ndim=2)
            if g.shape != (n, n):
                raise ParameterError(f"distributed[{j}]", f"an {n} x {n} real matrix", g.shape)
            dist.append((g, term[1]))
        for name, value in (("A", a), ("hA", ha), ("B", b), ("hB", hb), ("E", e), ("distributed", tuple(dist))):
            object.__setattr__(self, name, value)

    @property
    def n(self) -> int:
        """The state dimension."""
        return int(self.E.shape[0])

    def characteristic_matrix(self) -> QuasiPolynomialMatrix:
        """``M(s) = s E - sum A_k e^{-hA_k s} - s sum B_k e^{-hB_k s} - sum G_j int N_j e^{-nu s}``.

        Built once (the system is immutable), so that its compiled coefficients and its
        principal part are reused by every call of :meth:`roots`, :meth:`roots_right_of`
        and :meth:`abscissa`.
        """
        return self._characteristic_matrix

    @functools.cached_property
    def _coefficients(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The point part of ``M``: ``M_ij(s) = sum_k (c[i, j, k, 0] + c[i, j, k, 1] s) e^{-h_k s}``, as ``(c, h)``.

        The ``h_k`` distinct and increasing, the terms of equal delays summed in their order
        (as :meth:`~nrobust.quasipoly.QuasiPolynomial.from_coefficient_array` sums them).
        """
        n, ka = self.n, self.A.shape[0]
        coefs = np.zeros((n, n, 1 + ka + self.B.shape[0], 2))
        coefs[:, :, 0, 1] = self.E
        coefs[:, :, 1 : 1 + ka, 0] = -self.A.transpose(1, 2, 0)
        coefs[:, :, 1 + ka :, 1] = -self.B.transpose(1, 2, 0)
        delays = [0.0, *self.hA.tolist(), *self.hB.tolist()]
        order = sorted(set(delays))
        where = {h: k for k, h in enumerate(order)}
        merged = np.zeros((n, n, len(order), 2))
        for k, h in enumerate(delays):
            merged[:, :, where[h]] += coefs[:, :, k]
        return merged, np.array(order)

    @functools.cached_property
    def _characteristic_matrix(self) -> QuasiPolynomialMatrix:
        n = self.n
        rows = QuasiPolynomial.from_coefficient_array(*self._coefficients)
        for i in range(n):
            for j in range(n):
                dist = [N.scale(-float(g[i, j])) for g, N in self.distributed if g[i, j] != 0]
                if dist:
                    rows[i][j] = QuasiPolynomial.from_parts(rows[i][j].point_terms, dist)
        return QuasiPolynomialMatrix(rows)

    def _difference_terms(self) -> list[tuple[NDArray[np.float64], float]]:
        """``(A_k, tau_k)`` of ``D(s) = I - sum_k A_k e^{-tau_k s}``, equal delays merged (may be empty)."""
        if np.linalg.matrix_rank(self.E) == self.n:
            einv = np.linalg.inv(self.E)
            terms = [(einv @ b, float(h)) for b, h in zip(self.B, self.hB)]
        else:
            if self.B.shape[0]:
                raise ParameterError(
                    "B", "no neutral term when E is singular (descriptor systems: retarded part only)", 1
                )
            from scipy.linalg import null_space  # lazily: a slow import

            u, v = null_space(self.E.T), null_space(self.E)
            d0 = u.T @ sum((a for a, h in zip(self.A, self.hA) if h == 0), np.zeros_like(self.E)) @ v
            if np.linalg.matrix_rank(d0) < d0.shape[0]:
                raise ParameterError("A", "U^T A_0 V invertible for a singular E (the algebraic part has index 1)", d0)
            d0inv = np.linalg.inv(d0)
            terms = [(-d0inv @ u.T @ a @ v, float(h)) for a, h in zip(self.A, self.hA) if h > 0]
        merged: dict[float, NDArray[np.float64]] = {}
        for a, h in terms:
            merged[h] = merged[h] + a if h in merged else a
        return [(a, h) for h, a in sorted(merged.items())]

    def principal_operator(self) -> MatrixDifferenceOperator:
        """The difference operator ``D(s) = I - sum_k A_k e^{-tau_k s}`` whose zeros the chains follow.

        ``A_k = E^{-1} B_k`` for an invertible ``E``; for a singular ``E`` (no neutral
        term) ``A_k = -(U^T A_0 V)^{-1} U^T A_k V`` of the algebraic part (module docstring).
        Equal delays are merged.

        Raises
        ------
        ParameterError
            No delayed term in the principal part (a retarded system), neutral terms with a
            singular ``E``, or a singular ``U^T A_0 V``.
        """
        terms = self._difference_terms()
        if not terms:
            raise ParameterError(
                "B", "a delayed term in the principal part (a retarded system has no difference operator)", 0
            )
        return MatrixDifferenceOperator(np.array([a for a, _ in terms]), [h for _, h in terms])

    def root_radius(self, re_min: float) -> float:
        """A radius ``R`` with ``|s| <= R`` for every root with ``Re s >= re_min`` (module docstring).

        Raises
        ------
        ParameterError
            A singular ``E``, a distributed term with a polynomial factor, or
            ``sum_k ||E^{-1} B_k|| e^{-hB_k re_min} >= 1`` (the neutral chains reach the line:
            infinitely many roots may lie right of it).
        """
        x = finite_real("re_min", re_min)
        neutral, rest = self._radius_terms()
        if neutral(x) >= 1.0:
            raise ParameterError("re_min", "a line right of the neutral chains (sum ||E^-1 B_k|| e^{-h x} < 1)", re_min)
        return rest(x) / (1.0 - neutral(x))

    def _radius_terms(self) -> tuple[Callable[[float], float], Callable[[float], float]]:
        """``x -> sum_k ||E^{-1} B_k|| e^{-hB_k x}`` and the numerator of :meth:`root_radius`, both decreasing."""
        if np.linalg.matrix_rank(self.E) < self.n:
            raise ParameterError("E", "invertible for a root radius", self.E)
        einv = np.linalg.inv(self.E)

        def norm(m: NDArray[np.float64]) -> float:
            return float(np.linalg.norm(einv @ m, 2))

        for j, (_, N) in enumerate(self.distributed):
            if N.poly.size > 1:
                raise ParameterError(f"distributed[{j}]", "a kernel without polynomial factor for a root radius", N)
        nb = np.array([norm(b) for b in self.B])
        na = np.array([norm(a) for a in self.A])
        ng = [(norm(g), N) for g, N in self.distributed]

        def neutral(x: float) -> float:
            return float(np.sum(nb * np.exp(-self.hB * x)))

        def rest(x: float) -> float:
            return float(np.sum(na * np.exp(-self.hA * x))) + sum(c * float(N.abs_moment(x)) for c, N in ng)

        return neutral, rest

    def generator_eigenvalues(self, im_max: float) -> NDArray[np.complex128]:
        """Approximate roots: eigenvalues of a Chebyshev collocation of the generator (not certified).

        The state on ``[-tau, 0]`` (``tau`` the largest point delay) is collocated at
        ``N + 1`` Chebyshev points, ``N`` growing with ``tau im_max`` (module docstring),
        and ``s`` solves the pencil ``A v = s B v``: the rows ``j >= 1`` ask
        ``phi'(theta_j) = s phi(theta_j)``, row 0 asks
        ``s (E phi(0) - sum_k B_k phi(-hB_k)) = sum_k A_k phi(-hA_k)`` (``phi = e^{s theta} v``
        is exact); only the combinations of the state read by a delayed term are collocated at
        ``theta_j < 0`` (the rest of the history enters no equation), and for a singular ``E`` with no neutral
        term the algebraic rows are solved for their components first (index 1; otherwise
        the pencil is reduced by a shift and invert, or the QZ algorithm). Distributed terms
        are left out. Accurate for the roots with
        ``|Im s| tau`` well below ``N`` (``N = 0.3 tau im_max + 12``); :meth:`roots` seeds
        Newton's method with the eigenvalues of ``N = min(0.3 tau im_max + 8, tau im_max / 2 + 2)``
        points (seeds only: about ``tau im_max / 2`` points resolve ``e^{i im_max theta}`` on ``[-tau, 0]``).

        Parameters
        ----------
        im_max : float
            Largest ``|Im s|`` of the roots wanted.

        Returns
        -------
        ndarray of complex
            The finite eigenvalues.
        """
        return self._generator_eigenvalues(finite_real("im_max", im_max), _MIN_POINTS)

    def _generator_eigenvalues(
        self, im_max: float, min_points: int, extra: int | None = None
    ) -> NDArray[np.complex128]:
        """:meth:`generator_eigenvalues` with ``min_points`` added to the points per frequency; with ``extra``,
        at most ``w tau / 2 + extra`` points (``w = im_max``: about those that resolve ``e^{i w theta}``)."""
        tau = float(max(np.max(self.hA, initial=0.0), np.max(self.hB, initial=0.0)))
        if tau == 0.0:
            from scipy.linalg import eig  # lazily: a slow import (the generalised problem of a singular E)

            vals = eig(np.sum(self.A, axis=0), self.E, right=False)  # no delay: no neutral term either
            return np.asarray(vals[np.isfinite(vals)], dtype=complex)
        wide = abs(im_max) * tau
        points = _POINTS_PER_FREQUENCY * wide + min_points
        if extra is not None:
            points = min(points, 0.5 * wide + extra)
        points = int(min(max(points, 4), _MAX_ORDER // self.n - 1))
        problems = self._collocations
        problem = problems.get(points)
        if problem is None:
            problem = self._collocation(points, tau)
            if len(problems) >= _KEPT_COLLOCATIONS:
                del problems[next(iter(problems))]
            problems[points] = problem
        return problem.eigenvalues()

    @functools.cached_property
    def _unit_E(self) -> bool:
        """True if ``E`` is the identity."""
        return bool(np.array_equal(self.E, np.eye(self.n)))

    @functools.cached_property
    def _collocations(self) -> dict[int, _Collocation]:
        """The eigenvalue problems of :meth:`_collocation` built so far, by number of points (the last few)."""
        return {}

    @functools.cached_property
    def _history(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """``(P, S, T)``: the ``nd`` combinations ``y = P x`` of the state that the delayed terms read, with
        ``A_k = S_k P`` for every delayed ``A_k`` (``S_k = 0`` for the undelayed ones) and ``B_k = T_k P``.

        ``P`` selects the nonzero columns of the delayed matrices (``S_k``, ``T_k`` their columns), or, when
        fewer, stacks their nonzero rows (``S_k``, ``T_k`` select them): Example 2.9 reads 4 columns
        but only 3 rows, so its collocation keeps the history of 3 combinations instead of 4 states.
        Exact either way (no product is formed), so the collocated generator is that of the same system.
        """
        # (the reductions of the ufunc itself: ndarray.any's Python wrapper costs more than these small arrays)
        any_term = np.logical_or.reduce
        delayed_a = self.hA > 0
        mats = np.concatenate([self.A[delayed_a], self.B])
        nonzero = mats != 0
        columns = any_term(nonzero, axis=(0, 1)).nonzero()[0]
        rows = any_term(nonzero, axis=2)  # (matrix, row)
        if np.count_nonzero(rows) >= columns.size:
            return np.eye(self.n)[columns], self.A[:, :, columns], self.B[:, :, columns]
        which, row = rows.nonzero()
        select = np.zeros((mats.shape[0], self.n, which.size))
        select[which, row, np.arange(which.size)] = 1.0
        hist_a = np.zeros((self.A.shape[0], self.n, which.size))
        hist_a[delayed_a] = select[: np.count_nonzero(delayed_a)]
        return mats[which, row], hist_a, select[np.count_nonzero(delayed_a) :]

    def _collocation(self, points: int, tau: float) -> _Collocation:
        """The eigenvalue problem of the generator collocated at ``points + 1`` Chebyshev points on ``[-tau, 0]``."""
        n = self.n
        theta, d = _chebyshev(points, tau)
        # Only what the delayed terms read needs a history (:meth:`_history`): the unknowns are phi(0) (all n
        # components) and y(theta_j) = P phi(theta_j), j >= 1, of the nd combinations y = P x that the delayed
        # terms read (A_k = S_k P for each delayed A_k, and B_k = T_k P). The pencil A v = s B v: the rows
        # j >= 1 ask (D y)_j = s y(theta_j), with y(theta_0) = P phi(0), the first block row
        # sum_k A_k phi(-hA_k) = s (E phi(0) - sum_k B_k phi(-hB_k)),
        # phi(-h) = sum_l l_h[l] phi(theta_l) by the interpolation rows l_h (A_k phi(theta_l) = S_k y(theta_l)).
        pick, hist_a, hist_b = self._history
        nd = pick.shape[0]
        rest = np.hstack(
            [
                (d[1:, 0, None, None] * pick[None]).reshape(points * nd, n),
                (d[1:, None, 1:, None] * np.eye(nd)[None, :, None, :]).reshape(points * nd, points * nd),
            ]
        )
        rows_a = np.array([_interpolation_row(theta, -h) for h in self.hA.tolist()])
        top = np.hstack([_combination(rows_a[:, 0], self.A), _block_row(rows_a[:, 1:], hist_a)])
        br = None  # the history columns of the first block row of B (none without neutral terms)
        if self.B.shape[0]:
            rows_b = np.array([_interpolation_row(theta, -h) for h in self.hB.tolist()])
            b0 = self.E - _combination(rows_b[:, 0], self.B)
            br = -_block_row(rows_b[:, 1:], hist_b)
        elif self._unit_E:  # E = I and no neutral term: B = I, the standard problem A v = s v
            return _Collocation(np.vstack([top, rest]))
        else:
            b0 = self.E
        svd = np.linalg.svd(b0)
        sig = svd[1]
        if sig[-1] * _MAX_CONDITION > sig[0]:  # B = [[B0, Br], [0, I]]: the standard problem B^{-1} A
            return _Collocation(np.vstack([np.linalg.solve(b0, top if br is None else top - br @ rest), rest]))
        reduced = _eliminate_algebraic(top, rest, svd) if br is None or not br.any() else None
        if reduced is not None:
            return _Collocation(reduced)
        a, b = np.vstack([top, rest]), np.eye(n + points * nd)
        b[:n, :n] = b0
        if br is not None:
            b[:n, n:] = br
        return _Collocation(a, b, _inverted(a, b))

    def _find(self, region: tuple[float, float, float, float], options: dict[str, Any]) -> RootSet:
        """:func:`~nrobust.roots.find_roots` on ``det M`` seeded with :meth:`generator_eigenvalues`."""
        x0, x1, y0, y1 = region
        with one_blas_thread(scipy_linalg=True):
            seeds = self._generator_eigenvalues(max(abs(y0), abs(y1)), _SEED_MIN_POINTS, _SEED_EXTRA_POINTS)
            pad = 0.02 * min(x1 - x0, y1 - y0)
            inside = (
                (seeds.real > x0 - pad) & (seeds.real < x1 + pad) & (seeds.imag > y0 - pad) & (seeds.imag < y1 + pad)
            )
            user = options.pop("seeds", None)
            extra = seeds[inside] if user is None else np.concatenate([seeds[inside], np.ravel(user).astype(complex)])
            return find_roots(self._counted(bool(options.get("rigorous", False))), region, seeds=extra, **options)

    def _counted(self, rigorous: bool) -> QuasiPolynomialMatrix | ExpandedDeterminant:
        """What :meth:`roots` counts: ``det M`` expanded exactly (:meth:`QuasiPolynomialMatrix.exact_expansion`,
        here from the coefficient array, :meth:`ExpandedDeterminant.from_coefficients`, without building the
        matrix) without distributed terms, else the matrix; the matrix for proofs in ball arithmetic.

        The bounds of the matrix's derivatives (Hadamard's inequality on the rows) miss the
        cancellations that the exact expansion makes, and the expansion's values, derivatives and
        Taylor forms are a few matrix products where the matrix needs ``n`` determinants per
        derivative (``benchmarks/statespace.py`` measures both).
        """
        if self.n > MAX_MATRIX_SIZE:
            raise ParameterError(
                "A",
                f"at most {MAX_MATRIX_SIZE} states for roots (det M is expanded, or counted from its "
                f"{MAX_MATRIX_SIZE} x {MAX_MATRIX_SIZE} at most matrix of quasi-polynomials); "
                "generator_eigenvalues approximates the rightmost roots of larger systems",
                f"{self.n} states",
            )
        if rigorous or self.distributed:
            return self.characteristic_matrix()
        expanded = self._expanded
        return self.characteristic_matrix() if expanded is None else expanded

    @functools.cached_property
    def _expanded(self) -> ExpandedDeterminant | None:
        """``det M`` expanded exactly from :attr:`_coefficients` (:meth:`ExpandedDeterminant.from_coefficients`)."""
        return ExpandedDeterminant.from_coefficients(*self._coefficients)

    def roots(self, region: ArrayLike, **options: Any) -> RootSet:
        """Certified roots of ``det M`` in a rectangle (:func:`~nrobust.roots.find_roots`).

        Newton's method is seeded with :meth:`generator_eigenvalues` (and the ``seeds`` of
        ``options``); the count and the boxes are certified as by ``find_roots``.
        """
        box = check_region(region)
        return self._find(box, dict(options))

    def roots_right_of(self, re_min: float, **options: Any) -> RootSet:
        """Every root with ``Re s >= re_min``, certified: the rectangle of :meth:`root_radius`.

        TDS-CONTROL's and tdcpy's ``roots(tds, r)`` with a number ``r`` compute the same set
        by a spectral discretisation (not certified).
        """
        x = float(re_min)
        r = self.root_radius(x) * (1.0 + 1e-9) + 1e-9
        right = self._abscissa_bound(x) * (1.0 + 1e-9) + 1e-9 if r > x else x
        return self._find((x, max(min(right, r), x + 1e-6), -r, r), dict(options))

    def _abscissa_bound(self, re_min: float) -> float:
        """``x*`` with ``x* >= R(x*)`` (:meth:`root_radius` ``R``): no root has ``Re s > x*`` (module docstring).

        ``x - R(x)`` increases, so bisection on ``[re_min, R(re_min)]`` keeps an upper end
        where it is ``>= 0``; a root with ``Re s = x >= re_min`` has ``x <= |s| <= R(x)``.
        """
        neutral, rest = self._radius_terms()

        def radius(x: float) -> float:
            return rest(x) / (1.0 - neutral(x))

        lo, hi = re_min, radius(re_min)
        if hi <= lo:
            return lo
        for _ in range(_BISECTIONS):
            mid = 0.5 * (lo + hi)
            if mid in (lo, hi):
                break
            if mid >= radius(mid):
                hi = mid
            else:
                lo = mid
        return hi

    def abscissa(self, region: ArrayLike, **options: Any) -> SpectralAbscissa:
        """Spectral abscissa of ``det M`` in a rectangle (:func:`~nrobust.roots.spectral_abscissa`)."""
        with one_blas_thread(scipy_linalg=True):
            return spectral_abscissa(self.characteristic_matrix(), region, **options)

    def is_strongly_stable(self) -> bool:
        """``gamma_0 < 1`` for :meth:`principal_operator` (True when the principal part has no delayed term)."""
        terms = self._difference_terms()
        if not terms:
            return True
        return self.principal_operator().is_strongly_stable()
