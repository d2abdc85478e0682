"""Linear time-delay systems in state-space form, as the time-delay community writes them.

The system (retarded, neutral, descriptor; TDS-CONTROL and tdcpy write the same)::

    E x'(t) = sum_k A_k x(t - hA_k) + sum_k B_k x'(t - hB_k) + sum_j G_j int N_j(nu) x(t - nu) dnu

has the characteristic matrix

    M(s) = s E - sum_k A_k e^{-hA_k s} - s sum_k B_k e^{-hB_k s} - sum_j G_j int N_j(nu) e^{-nu s} dnu,

taken here as a :class:`~nrobust.qpmatrix.QuasiPolynomialMatrix` (the determinant is
never expanded), so its roots, spectral abscissa and root counts are certified by
:mod:`nrobust.roots`. The distributed kernel ``G(nu) = sum_j G_j N_j(nu)`` is a sum of
constant matrices times scalar tabulated kernels (:class:`~nrobust.quasipoly.DistributedDelay`).
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
so :meth:`StateSpaceTDS.roots_right_of` counts a rectangle that holds them all.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import finite_real, real_array
from ..errors import ParameterError
from ..matrix_difference import MatrixDifferenceOperator
from ..qpmatrix import QuasiPolynomialMatrix
from ..quasipoly import DistributedDelay, QuasiPolynomial
from ..roots import RootSet, SpectralAbscissa, find_roots, spectral_abscissa

__all__ = ["StateSpaceTDS"]


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
        """``M(s) = s E - sum A_k e^{-hA_k s} - s sum B_k e^{-hB_k s} - sum G_j int N_j e^{-nu s}``."""
        n = self.n
        rows = []
        for i in range(n):
            row = []
            for j in range(n):
                coefs: list[list[float]] = [[0.0, float(self.E[i, j])]]
                delays = [0.0]
                for a, h in zip(self.A, self.hA):
                    coefs.append([-float(a[i, j])])
                    delays.append(float(h))
                for b, h in zip(self.B, self.hB):
                    coefs.append([0.0, -float(b[i, j])])
                    delays.append(float(h))
                dist = [N.scale(-float(g[i, j])) for g, N in self.distributed if g[i, j] != 0]
                row.append(QuasiPolynomial(coefs, delays, dist))
            rows.append(row)
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
        if np.linalg.matrix_rank(self.E) < self.n:
            raise ParameterError("E", "invertible for a root radius", self.E)
        einv = np.linalg.inv(self.E)

        def norm(m: NDArray[np.float64]) -> float:
            return float(np.linalg.norm(einv @ m, 2))

        neutral = sum(norm(b) * np.exp(-h * x) for b, h in zip(self.B, self.hB))
        if neutral >= 1.0:
            raise ParameterError("re_min", "a line right of the neutral chains (sum ||E^-1 B_k|| e^{-h x} < 1)", re_min)
        rest = sum(norm(a) * np.exp(-h * x) for a, h in zip(self.A, self.hA))
        for j, (g, N) in enumerate(self.distributed):
            if N.poly.size > 1:
                raise ParameterError(f"distributed[{j}]", "a kernel without polynomial factor for a root radius", N)
            rest += norm(g) * float(N.abs_moment(x))
        return float(rest / (1.0 - neutral))

    def roots(self, region: ArrayLike, **options: Any) -> RootSet:
        """Certified roots of ``det M`` in a rectangle (:func:`~nrobust.roots.find_roots`)."""
        return find_roots(self.characteristic_matrix(), region, **options)

    def roots_right_of(self, re_min: float, **options: Any) -> RootSet:
        """Every root with ``Re s >= re_min``, certified: the rectangle of :meth:`root_radius`.

        TDS-CONTROL's and tdcpy's ``roots(tds, r)`` with a number ``r`` compute the same set
        by a spectral discretisation (not certified).
        """
        r = self.root_radius(re_min) * (1.0 + 1e-9) + 1e-9
        return find_roots(self.characteristic_matrix(), (float(re_min), max(r, float(re_min) + 1e-6), -r, r), **options)

    def abscissa(self, region: ArrayLike, **options: Any) -> SpectralAbscissa:
        """Spectral abscissa of ``det M`` in a rectangle (:func:`~nrobust.roots.spectral_abscissa`)."""
        return spectral_abscissa(self.characteristic_matrix(), region, **options)

    def is_strongly_stable(self) -> bool:
        """``gamma_0 < 1`` for :meth:`principal_operator` (True when the principal part has no delayed term)."""
        terms = self._difference_terms()
        if not terms:
            return True
        return self.principal_operator().is_strongly_stable()
