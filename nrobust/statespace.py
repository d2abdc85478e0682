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
Lunel) decides robustness to small changes of the delays.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._validate import real_array
from .errors import ParameterError
from .matrix_difference import MatrixDifferenceOperator
from .qpmatrix import QuasiPolynomialMatrix
from .quasipoly import DistributedDelay, QuasiPolynomial
from .roots import RootSet, SpectralAbscissa, find_roots, spectral_abscissa

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

    def principal_operator(self) -> MatrixDifferenceOperator:
        """``D(s) = I - sum_k E^{-1} B_k e^{-hB_k s}`` of a neutral system with invertible ``E``.

        Raises
        ------
        ParameterError
            No neutral term, or a singular ``E`` (a descriptor system: its principal part
            is not of this form).
        """
        if self.B.shape[0] == 0:
            raise ParameterError("B", "at least one neutral term (a retarded system has no difference operator)", 0)
        if np.linalg.matrix_rank(self.E) < self.n:
            raise ParameterError("E", "invertible for the difference operator of the neutral part", self.E)
        einv = np.linalg.inv(self.E)
        return MatrixDifferenceOperator(np.array([einv @ b for b in self.B]), self.hB)

    def roots(self, region: ArrayLike, **options: Any) -> RootSet:
        """Certified roots of ``det M`` in a rectangle (:func:`~nrobust.roots.find_roots`)."""
        return find_roots(self.characteristic_matrix(), region, **options)

    def abscissa(self, region: ArrayLike, **options: Any) -> SpectralAbscissa:
        """Spectral abscissa of ``det M`` in a rectangle (:func:`~nrobust.roots.spectral_abscissa`)."""
        return spectral_abscissa(self.characteristic_matrix(), region, **options)

    def is_strongly_stable(self) -> bool:
        """``gamma_0 < 1`` for :meth:`principal_operator` (True for a retarded system with ``E = I``)."""
        if self.B.shape[0] == 0 and np.linalg.matrix_rank(self.E) == self.n:
            return True
        return self.principal_operator().is_strongly_stable()
