"""Proven enclosures of stacks of small complex matrices in floating point (midpoint-radius arithmetic).

A :class:`Ball` ``(c, r)`` holds every array ``X`` with ``|X - c| <= r`` entrywise. The
operations return balls holding every result of exact arithmetic on members of their
arguments, including the rounding of the midpoints, with numpy's vectorised floating point
(IEEE double, rounding to nearest, unit roundoff ``u = EPS / 2``):

* a complex sum or difference is within ``u |fl(x +- y)| (1 + u) <= EPS |fl(x +- y)|`` of the exact
  one, and a float product ``fl(X Y)`` of ``p x k`` and ``k x q`` complex matrices is within
  ``sqrt(2) gamma_{k+2} |X| |Y| <= 2 (k + 2) EPS |X| |Y|`` of ``X Y`` entrywise, in any order of
  summation, with or without fused multiply-adds (Higham, *Accuracy and Stability of Numerical
  Algorithms*, 2nd ed., Lemma 3.5 and Section 3.6);
* each radius is a sum of products of nonnegative floats, at most a few hundred roundings
  below the exact value (relative ``< 1e-13``), and ``np.abs`` of a complex float is within
  one ulp: every radius is multiplied by ``UP = 1 + 1e-12`` and raised by ``TINY`` for underflow.

:func:`expm` encloses the matrix exponential by scaling, a Taylor polynomial with its proven
remainder and squaring; :func:`det` by cofactor expansion (``m!`` products: small ``m``);
:func:`singular_bounds` brackets every singular value of a float matrix a posteriori from
a floating-point SVD. No step rests on the accuracy of a LAPACK routine.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

EPS = float(np.finfo(float).eps)
#: Factor applied to every radius computed in floating point (module notes).
UP = 1.0 + 1e-12
#: Absolute allowance for underflow in a radius.
TINY = 1e-300
# Taylor polynomial of the exponential: degree and the infinity norm after scaling
# (remainder below 0.5^16 / 16! < 1e-18).
_DEGREE, _THETA = 15, 0.5


class Ball:
    """Midpoint ``mid`` (complex array) and entrywise radius ``rad`` (real array of the same shape)."""

    __slots__ = ("mid", "rad")

    def __init__(self, mid: Any, rad: Any = None) -> None:
        self.mid = np.asarray(mid, dtype=complex)
        self.rad = (
            np.zeros(self.mid.shape) if rad is None else np.broadcast_to(np.asarray(rad, dtype=float), self.mid.shape)
        )

    def __getitem__(self, key: Any) -> Ball:
        return Ball(self.mid[key], self.rad[key])

    def __add__(self, other: Ball) -> Ball:
        mid = self.mid + other.mid
        return Ball(mid, (self.rad + other.rad + EPS * np.abs(mid)) * UP)

    def __sub__(self, other: Ball) -> Ball:
        mid = self.mid - other.mid
        return Ball(mid, (self.rad + other.rad + EPS * np.abs(mid)) * UP)

    def __mul__(self, other: Ball) -> Ball:
        """Entrywise product (broadcasting)."""
        a, b = np.abs(self.mid), np.abs(other.mid)
        rad = a * other.rad + self.rad * (b + other.rad) + 6.0 * EPS * a * b + TINY
        return Ball(self.mid * other.mid, rad * UP)

    def __matmul__(self, other: Ball) -> Ball:
        k = self.mid.shape[-1]
        a, b = np.abs(self.mid), np.abs(other.mid)
        rad = a @ (other.rad + 2.0 * (k + 2) * EPS * b) + self.rad @ (b + other.rad) + TINY
        return Ball(self.mid @ other.mid, rad * UP)

    def divide(self, k: int) -> Ball:
        """Division by a positive integer ``k`` (exact as a float)."""
        mid = self.mid / k
        return Ball(mid, (self.rad / k + EPS * np.abs(mid) + TINY) * UP)

    def upper(self) -> NDArray[np.float64]:
        """``|mid| + rad`` rounded upwards: an entrywise bound of the members' moduli."""
        return np.asarray((np.abs(self.mid) + self.rad) * UP, dtype=float)

    def norm_bound(self) -> NDArray[np.float64]:
        """An upper bound of the Frobenius norm (so of the spectral norm) of every member, per matrix."""
        return frobenius(self.upper())


def frobenius(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Frobenius norms of a stack of nonnegative float matrices, rounded upwards."""
    return np.asarray(np.sqrt(np.sum(x * x, axis=(-2, -1))) * UP, dtype=float)


def exact(x: Any) -> Ball:
    """The float array ``x`` as a ball of radius 0."""
    return Ball(x)


def identity(shape: tuple[int, ...], d: int) -> Ball:
    """Identity matrices of size ``d``, stacked to ``shape``."""
    return Ball(np.broadcast_to(np.eye(d, dtype=complex), (*shape, d, d)).copy())


def expm(a: Ball) -> Ball:
    """Enclosure of ``exp(A)`` for every ``A`` of the stack of balls ``a`` (shape ``(..., d, d)``).

    ``B = A / 2^j`` (exact) with ``||B||_inf <= 1/2``; the Taylor polynomial of degree 15 in
    Horner's form, plus the remainder ``sum_{k > 15} b^k / k! <= b^16 / 16! / (1 - b / 17)``,
    ``b >= ||B||_inf`` (a bound of every entry of the remainder matrix); then ``j`` squarings.
    """
    shape, d = a.mid.shape[:-2], a.mid.shape[-1]
    flat = Ball(a.mid.reshape(-1, d, d), a.rad.reshape(-1, d, d))
    norm = np.max(np.sum(flat.upper(), axis=-1), axis=-1) * UP
    if not np.all(np.isfinite(norm)):
        raise FloatingPointError("expm: a matrix with an infinite or NaN entry")
    _, expo = np.frexp(norm / _THETA)  # norm / THETA < 2^expo
    j = np.maximum(expo, 0)
    scale = np.ldexp(1.0, -j)[:, None, None]
    b = Ball(flat.mid * scale, flat.rad * scale + TINY)
    bn = norm * scale[:, 0, 0]  # <= THETA, up to the rounding of norm / THETA, covered below
    rem = bn ** (_DEGREE + 1) / math.factorial(_DEGREE + 1) / (1.0 - bn / (_DEGREE + 2)) * 1.01 + TINY
    eye = identity((flat.mid.shape[0],), d)
    t = eye
    for k in range(_DEGREE, 0, -1):
        t = eye + (b @ t).divide(k)
    x = Ball(t.mid, t.rad + rem[:, None, None])
    for step in range(int(j.max(initial=0))):
        sel = np.flatnonzero(j > step)
        sq = x[sel] @ x[sel]
        x.mid[sel], x.rad = sq.mid, _put(x.rad, sel, sq.rad)
    return Ball(x.mid.reshape(*shape, d, d), x.rad.reshape(*shape, d, d))


def _put(rad: NDArray[np.float64], sel: NDArray[np.intp], value: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.array(rad)
    out[sel] = value
    return out


def det(a: Ball) -> Ball:
    """Enclosure of the determinants of the stack of square balls ``a`` (cofactor expansion along the first row)."""
    d = a.mid.shape[-1]
    if d == 1:
        return a[..., 0, 0]
    total: Ball | None = None
    for j in range(d):
        cols = [c for c in range(d) if c != j]
        term = a[..., 0, j] * det(a[..., 1:, cols])
        if j % 2:
            term = Ball(-term.mid, term.rad)
        total = term if total is None else total + term
    assert total is not None
    return total


def singular_bounds(a: NDArray[np.complex128]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Proven ``(lower, upper)`` of every singular value ``sigma_i`` (descending) of the float matrices ``a``.

    From a floating-point SVD ``a ~ U S V^H`` (any accuracy): ``sigma_i(U S V^H)`` lies between
    ``s_i sqrt((1 - d_U)(1 - d_V))`` and ``s_i sqrt((1 + d_U)(1 + d_V))`` for ``d_U >= ||U^H U - I||``
    (likewise ``V``), and ``sigma_i(a)`` within ``||a - U S V^H||`` of it (Weyl); the norms are
    Frobenius bounds of enclosures of the residuals. Shapes ``(..., m, m)`` in, ``(..., m)`` out.
    """
    u, s, vh = np.linalg.svd(a)
    d = a.shape[-1]
    eye = identity(a.shape[:-2], d)
    ub, vb = exact(u), exact(vh)
    d_u = (exact(np.conj(np.swapaxes(u, -1, -2))) @ ub - eye).norm_bound()
    d_v = (vb @ exact(np.conj(np.swapaxes(vh, -1, -2))) - eye).norm_bound()
    us = exact(u) * exact(s[..., None, :])
    res = (exact(a) - us @ vb).norm_bound()
    low_f = np.sqrt(np.maximum(1.0 - d_u, 0.0) * np.maximum(1.0 - d_v, 0.0)) * (1.0 - 4.0 * EPS)
    up_f = np.sqrt((1.0 + d_u) * (1.0 + d_v)) * UP
    lower = (s * low_f[..., None]) * (1.0 - 4.0 * EPS) - res[..., None] * UP
    lower = lower - 2.0 * EPS * np.abs(lower) - TINY  # the rounding of the difference
    upper = (s * up_f[..., None] + res[..., None]) * UP
    return np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
