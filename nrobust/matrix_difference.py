"""Matrix difference operators ``D(s) = I - sum_k A_k e^{-tau_k s}``: strong stability and chains.

The principal part of a matrix neutral equation (an ``n + m`` hyperbolic system, a
neutral state-space system ``x'(t) - sum_k B_k x'(t - tau_k) = ...``) is the difference
equation ``x(t) = sum_k A_k x(t - tau_k)``. Hale and Verduyn Lunel ("Strong stabilization
of neutral functional differential equations", IMA J. Math. Control Inform. 19, 2002;
"Introduction to Functional Differential Equations", 1993, Chapter 9) characterise its
robustness to the delays:

* ``gamma_0 = max_theta rho(sum_k A_k e^{i theta_k})`` over ``theta`` in the torus;
  ``D`` is *strongly stable* (exponentially stable for every small perturbation of the
  delays) iff ``gamma_0 < 1``. A common phase does not change the spectral radius, so
  ``theta_1 = 0`` and the maximum runs over a torus of dimension ``K - 1``.
* ``C_D``: the ``c`` with ``gamma_0(e^{-tau_k c} A_k) = 1``, the supremum of the spectral
  bound over small perturbations of the delays. ``gamma_0`` of the scaled coefficients
  is non-increasing in ``c``: ``z -> rho(X + z A_k)`` is subharmonic (Vesentini), so its
  maximum on a circle grows with the radius.
* Commensurate delays ``tau_k = n_k h``: ``det D(s) = 0`` iff ``det P(z) = 0`` with
  ``P(z) = I - sum_k A_k z^{n_k}``, ``z = e^{-h s}``: a polynomial eigenvalue problem
  (block companion matrix), each root ``z_i`` giving a vertical chain of zeros
  ``s = (-ln z_i + 2 pi i m) / h``.

**Certificate of gamma_0.** The torus is covered by cells (centre ``c``, half-widths
``h_k``). On a cell, ``X(theta) = X(c) + E`` with ``||E||_2 <= sum_k ||A_k||_2 h_k``
(a chord is shorter than its arc), and for every invertible ``T``
``rho(X + E) <= ||T^{-1} X(c) T||_2 + kappa(T) ||E||_2``. With the Schur form
``X(c) = Q U Q^*`` and ``T = Q diag(d^j)`` the first term is ``||D^{-1} U D||_2``, which
tends to ``rho(X(c))`` as ``d -> 0`` while ``kappa(T) = d^{-(p-1)}`` grows; the best of a
few ``d`` is used. Cells whose bound exceeds the largest sampled ``rho`` by more than the
tolerance are quartered (halved per dimension) until the bracket is tight or the work
bound is reached: the upper end is a bound for every ``theta``, not a sample.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import schur

from ._json import fields_dict
from ._validate import is_real_number, number_array, positive, positive_int, real_array
from .difference import Chains, _chains_of, _cluster_polynomial_roots, _commensurate
from .errors import CertificationError, ParameterError

__all__ = ["Gamma0", "MatrixDifferenceOperator"]

# Largest number of delays: the certificate covers a torus of dimension K - 1.
_MAX_DELAYS = 4
# Initial cells per dimension of the torus.
_INITIAL_CELLS = 32
# Scalings d of the Schur form tried on each cell.
_SCALINGS = (1.0, 0.3, 0.1, 0.03, 0.01, 1e-3)
# Relative rounding allowance on the computed 2-norms.
_NORM_SLACK = 1e-12
# A sampled spectral radius decides "gamma_0 >= 1" only above 1 + this (eigenvalue rounding).
_DECIDE_SLACK = 1e-12
# Largest block companion matrix (rows) of commensurate delays (nrobust.difference's test).
_MAX_COMPANION = 4000


@dataclass(frozen=True)
class Gamma0:
    """A certified bracket of ``gamma_0 = max_theta rho(sum_k A_k e^{i theta_k})``.

    Attributes
    ----------
    lower : float
        ``rho`` at a sampled ``theta`` (attained, up to the rounding of an eigenvalue solver).
    upper : float
        Certified bound of ``rho(sum_k A_k e^{i theta_k})`` for every ``theta``.
    theta : tuple of float
        The phases where ``lower`` was attained (``theta_1 = 0``).
    cells : int
        Number of torus cells in the final cover.
    """

    lower: float
    upper: float
    theta: tuple[float, ...]
    cells: int

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


def _as_matrices(coefs: Any) -> NDArray[np.complex128]:
    a = number_array("coefs", coefs, ndim=3)
    if a.shape[1] != a.shape[2]:
        raise ParameterError("coefs", "a sequence of square matrices of one size (shape (K, p, p))", a.shape)
    return a.astype(complex)


def _spectral_radius(x: NDArray[np.complex128]) -> NDArray[np.float64]:
    return np.max(np.abs(np.linalg.eigvals(x)), axis=-1)


def _norm2(x: NDArray[np.complex128]) -> NDArray[np.float64]:
    """Spectral norms of a stack of matrices."""
    return np.asarray(np.linalg.norm(x, 2, axis=(-2, -1)), dtype=float)


def _schur_bound(x: NDArray[np.complex128], eps: float, xnorm: float) -> float:
    """``min_d ||D^{-1} U D||_2 + d^{-(p-1)} eps`` over the scaled Schur bases ``Q diag(d^j)``."""
    p = x.shape[0]
    u, _ = schur(x, output="complex")
    j = np.arange(p)
    scaled = np.stack([u * (d ** (j[None, :] - j[:, None]).astype(float)) for d in _SCALINGS])
    kappa = np.array(_SCALINGS) ** (-(p - 1))
    return float(np.min(_norm2(scaled) + kappa * (eps + _NORM_SLACK * xnorm)))


def _cell_bounds(x: NDArray[np.complex128], eps: NDArray[np.float64]) -> NDArray[np.float64]:
    """``min_T ||T^{-1} x T||_2 + kappa(T) eps`` over a few ``T``, for a stack of cells.

    The candidates are ``T = I``, the eigenvector matrix of ``x`` (a bound linear in
    ``eps`` when ``x`` is diagonalisable) and, where that is ill conditioned, the scaled
    Schur bases ``Q diag(d^j)`` (defective ``x``). ``T^{-1} x T`` is formed in floating
    point: its rounding, ``~ eps_mach kappa(T) ||x||``, is added to the bound.
    """
    xnorm = _norm2(x)
    best = xnorm + eps
    if x.shape[-1] == 1:
        return best * (1.0 + _NORM_SLACK)
    _, v = np.linalg.eig(x)
    kappa = np.linalg.cond(v)
    good = np.isfinite(kappa) & (kappa < 1e8)
    if np.any(good):
        y = np.linalg.solve(v[good], x[good] @ v[good])
        best[good] = np.minimum(best[good], _norm2(y) + kappa[good] * (eps[good] + _NORM_SLACK * xnorm[good]))
    for i in np.flatnonzero(~good):
        best[i] = min(best[i], _schur_bound(x[i], float(eps[i]), float(xnorm[i])))
    return best * (1.0 + _NORM_SLACK)


@dataclass(frozen=True, eq=False)
class MatrixDifferenceOperator:
    """``D(s) = I - sum_k A_k e^{-tau_k s}`` with ``p x p`` matrices ``A_k`` and delays ``tau_k > 0``.

    Parameters
    ----------
    coefs : array_like, shape (K, p, p)
        The matrices ``A_k`` (real or complex), ``1 <= K <= 4``.
    delays : array_like, shape (K,)
        Distinct delays ``tau_k > 0``.

    Raises
    ------
    ParameterError
        Shapes that do not match, non-finite entries, delays not positive or not distinct.

    Examples
    --------
    >>> D = MatrixDifferenceOperator([[[0.0, 0.5], [0.5, 0.0]]], [1.0])
    >>> round(D.gamma_0().upper, 6), D.is_strongly_stable()
    (0.5, True)
    """

    coefs: NDArray[np.complex128]
    delays: NDArray[np.float64]

    def __init__(self, coefs: ArrayLike, delays: ArrayLike) -> None:
        a = _as_matrices(coefs)
        t = real_array("delays", [delays] if is_real_number(delays) else delays)
        if t.shape != (a.shape[0],):
            raise ParameterError("delays", f"one delay per matrix ({a.shape[0]})", delays)
        if np.any(t <= 0) or np.unique(t).size != t.size:
            raise ParameterError("delays", "distinct and > 0", delays)
        if a.shape[0] > _MAX_DELAYS:
            raise ParameterError(
                "coefs", f"at most {_MAX_DELAYS} matrices (the certificate covers a torus)", a.shape[0]
            )
        order = np.argsort(t)
        object.__setattr__(self, "coefs", a[order])
        object.__setattr__(self, "delays", t[order])

    @property
    def size(self) -> int:
        """The order ``p`` of the matrices."""
        return int(self.coefs.shape[1])

    def __call__(self, s: ArrayLike) -> NDArray[np.complex128]:
        """``det D(s)`` on an array of complex ``s``."""
        s = np.asarray(s, dtype=complex)
        m = np.broadcast_to(np.eye(self.size, dtype=complex), (*s.shape, self.size, self.size)).copy()
        for a, t in zip(self.coefs, self.delays):
            m -= np.exp(-t * s)[..., None, None] * a
        return np.asarray(np.linalg.det(m), dtype=complex)

    def matrix(self, s: complex) -> NDArray[np.complex128]:
        """The matrix ``D(s)``."""
        out = np.eye(self.size, dtype=complex)
        for a, t in zip(self.coefs, self.delays):
            out -= np.exp(-t * complex(s)) * a
        return out

    # ------------------------------------------------------------------ strong stability
    def gamma_0(self, *, rtol: float = 1e-3, max_cells: int = 200_000) -> Gamma0:
        """Certified bracket of ``gamma_0`` (see the module notes for the certificate).

        Parameters
        ----------
        rtol : float, optional
            Target relative width of the bracket.
        max_cells : int, optional
            Work bound: total number of torus cells evaluated.

        Returns
        -------
        Gamma0
            ``lower <= gamma_0 <= upper``; ``upper - lower <= rtol (1 + lower)`` unless the
            work bound was reached first (the bracket is then wider but still valid).
        """
        rtol = positive("rtol", rtol)
        max_cells = positive_int("max_cells", max_cells)
        return _gamma0(self.coefs, rtol, max_cells)

    def is_strongly_stable(self, *, max_cells: int = 200_000) -> bool:
        """True iff ``gamma_0 < 1`` (Hale and Verduyn Lunel).

        Raises
        ------
        CertificationError
            The certified bracket of ``gamma_0`` contains 1 within the work bound.
        """
        max_cells = positive_int("max_cells", max_cells)
        g = _gamma0(self.coefs, 1e-12, max_cells, threshold=1.0)
        if g.upper < 1.0:
            return True
        if g.lower >= 1.0 + _DECIDE_SLACK:  # a sampled rho above 1 beyond the eigenvalues' rounding
            return False
        raise CertificationError(
            f"gamma_0 in [{g.lower:.15g}, {g.upper:.15g}] cannot be separated from 1: raise max_cells"
        )

    def strong_spectral_bound(self, *, tol: float = 1e-4, max_cells: int = 200_000) -> tuple[float, float]:
        """Certified bracket of ``C_D``: ``gamma_0(e^{-tau_k c} A_k) = 1`` at ``c = C_D``.

        Bisection on ``c``: the upper end has a certified ``gamma_0 < 1`` (no zero of
        ``det D`` with ``Re s > c`` for any small perturbation of the delays), the lower
        end a sampled ``rho >= 1``; the lower end is ``-inf`` when no ``c`` above ``-1e6``
        gives ``rho >= 1`` (e.g. ``A_k`` nilpotent together), and the bracket is wider than
        ``tol`` when the work bound cannot decide ``gamma_0 < 1`` at a midpoint.
        """
        tol = positive("tol", tol)

        def g(c: float) -> Gamma0:
            return _gamma0(self.coefs * np.exp(-self.delays * c)[:, None, None], 1e-12, max_cells, threshold=1.0)

        norms = np.array([np.linalg.norm(a, 2) for a in self.coefs])
        # sum_k ||A_k|| e^{-tau_k c} < 1 proves gamma_0 < 1: an upper start
        hi = float(np.max(np.log(len(norms) * np.maximum(norms, 1e-300)) / self.delays)) + 1e-9
        step = 1.0
        while True:
            lo = hi - step
            g_lo = g(lo)
            if g_lo.lower >= 1.0 + _DECIDE_SLACK:
                break
            if g_lo.upper < 1.0:
                hi = lo
            step *= 2.0
            if step > 1e6:  # gamma_0 stays below 1 far to the left: no lower end found
                return (-np.inf, hi)
        while hi - lo > tol * (1.0 + abs(hi)):
            mid = 0.5 * (lo + hi)
            gm = g(mid)
            if gm.upper < 1.0:
                hi = mid
            elif gm.lower >= 1.0 + _DECIDE_SLACK:
                lo = mid
            else:
                break
        return (lo, hi)

    # ------------------------------------------------------------------ commensurate delays
    def commensurate_step(self) -> tuple[float, NDArray[np.int64]] | None:
        """``(h, n)`` with ``tau_k = n_k h`` (integers), or None.

        Tolerances as :meth:`~nrobust.difference.DifferenceOperator.commensurate_step`.
        """
        return _commensurate(self.delays, _MAX_COMPANION // self.size)

    def _step(self) -> tuple[float, NDArray[np.int64]]:
        """:meth:`commensurate_step`, or a ParameterError for incommensurate delays."""
        found = self.commensurate_step()
        if found is None:
            raise ParameterError("delays", "commensurate (tau_k = n_k h with small integers n_k)", self.delays)
        return found

    def z_roots(self) -> tuple[NDArray[np.complex128], NDArray[np.int64]]:
        """Roots ``z`` of ``det(I - sum_k A_k z^{n_k})`` (clustered, with multiplicities).

        With ``mu = 1/z`` the matrix polynomial ``mu^N I - sum_k A_k mu^{N - n_k}`` is monic:
        the eigenvalues of its block companion matrix; ``mu = 0`` (no finite ``z``) is dropped.

        Raises
        ------
        ParameterError
            Incommensurate delays.
        """
        n = self._step()[1]
        N, p = int(n[-1]), self.size
        comp = np.zeros((N * p, N * p), dtype=complex)
        comp[p:, :-p] = np.eye((N - 1) * p)
        for a, k in zip(self.coefs, n):  # mu^N x = sum_k A_k mu^{N - n_k} x: first block row
            j = int(k) - 1  # coefficient of mu^{N - n_k} sits in block column n_k - 1
            comp[:p, j * p : (j + 1) * p] += a
        mu = np.linalg.eigvals(comp)
        scale = max(1.0, float(np.max(np.abs(mu))))
        mu = mu[np.abs(mu) > 1e-12 * scale]
        return _cluster_polynomial_roots(np.asarray(1.0 / mu, dtype=complex))

    def chains(self) -> Chains:
        """The zero chains of ``det D`` for commensurate delays (rightmost first).

        Raises
        ------
        ParameterError
            Incommensurate delays.
        """
        return _chains_of(self._step()[0], *self.z_roots())

    def __repr__(self) -> str:
        return f"MatrixDifferenceOperator(p={self.size}, delays={np.round(self.delays, 6).tolist()})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description: the matrices (complex entries as ``[real, imag]``) and delays."""
        return fields_dict(self)


def _gamma0(coefs: NDArray[np.complex128], rtol: float, max_cells: int, threshold: float | None = None) -> Gamma0:
    """The certified cover of the torus behind :meth:`MatrixDifferenceOperator.gamma_0`.

    A cell is split while its bound exceeds the largest sampled ``rho`` by more than
    ``rtol (1 + rho)``. With a ``threshold`` the cover only decides ``gamma_0 < threshold``:
    cells bounded below it are final, and the search stops once a sample reaches it.
    """
    K = coefs.shape[0]
    if K == 1:
        return Gamma0(float(_spectral_radius(coefs[0])), float(_cell_bounds(coefs[:1], np.zeros(1))[0]), (0.0,), 1)
    norms = np.array([np.linalg.norm(a, 2) for a in coefs[1:]]) * (1.0 + _NORM_SLACK)
    dim = K - 1
    n0 = _INITIAL_CELLS if dim == 1 else (16 if dim == 2 else 8)
    grid = np.array(list(itertools.product(range(n0), repeat=dim)), dtype=float)
    centers = (grid + 0.5) * (2 * np.pi / n0)
    widths = np.full(centers.shape, np.pi / n0)
    offsets = np.array(list(itertools.product((-1.0, 1.0), repeat=dim)))
    used = 0
    best, best_theta = -np.inf, np.zeros(dim)
    upper = -np.inf
    while centers.size:
        if used + centers.shape[0] > max_cells:
            # the cells left are bounded crudely: rho <= sum_k ||A_k||
            upper = max(upper, float(np.linalg.norm(coefs[0], 2) * (1.0 + _NORM_SLACK) + norms.sum()))
            break
        used += centers.shape[0]
        x = coefs[0][None] + np.einsum("nk,kij->nij", np.exp(1j * centers), coefs[1:])
        rho = _spectral_radius(x)
        i = int(np.argmax(rho))
        if rho[i] > best:
            best, best_theta = float(rho[i]), centers[i]
        if threshold is not None and best >= threshold * (1.0 + _DECIDE_SLACK):
            upper = np.inf  # decided: gamma_0 >= threshold; no upper bound was needed
            break
        eps = widths @ norms
        bounds = _cell_bounds(x, eps)
        split = bounds > best + rtol * (1.0 + best)
        if threshold is not None:
            split &= bounds >= threshold
        upper = max(upper, float(np.max(bounds[~split], initial=-np.inf)))
        if not np.any(split):
            break
        c, w = centers[split], widths[split] / 2
        centers = (c[:, None, :] + offsets[None, :, :] * w[:, None, :]).reshape(-1, dim)
        widths = np.repeat(w, offsets.shape[0], axis=0)
    return Gamma0(best, max(upper, best), (0.0, *(float(t) for t in best_theta)), used)
