"""The number of zeros of ``F(s; delta) = A(s) + B(s) e^{-delta s}`` in ``Re s > 0``: one count, one edge rule.

:func:`unstable_count` is the one place where the margins count unstable zeros (the
nominal loop, a probe delay inside a window, the verification below the margin); it
returns an :class:`UnstableCount`.

**Edge rule.** The count is of the open half-plane ``Re s > 0`` inside the radius
``R = 1.01 r + 1e-9`` (``r`` the given bound, e.g. the frequency bound ``W``, or the
root-free radius of :func:`nrobust.bounds.root_free_region`), and it is *certified* only
when no zero lies on, or within rounding of, the imaginary axis:

* a zero on or near the axis (``s = 0`` included) makes :func:`nrobust.count_roots` move the
  left edge of its rectangle off ``Re s = 0``; the rectangle then counts another region and
  ``count`` is None (``counted`` and ``region`` say what was found there: ``stable`` is
  still True when that wider rectangle holds no zero at all);
* a neutral loop whose chains of zeros accumulate at the axis has no root-free radius
  (:func:`~nrobust.bounds.root_free_region` raises): without a given radius the count is
  not certified (``count`` None, ``method`` says why);
* a work bound hit by the count raises :class:`~nrobust.errors.CertificationError`.

Real coefficients: zeros come in conjugate pairs, so the upper box ``(0, R) x (0, R)`` is
counted and doubled when none of its edges moved (no zero on the positive real axis nor
on the imaginary axis), which halves the contour on the axis; otherwise the full
rectangle ``(0, R) x (-R, R)`` is counted. With the loop factors (``loop = (A, B, delta)``)
the argument principle on the half disc (:func:`axis_count`, chirp-z grids on the axis)
is tried first.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._json import fields_dict
from ..balls import BallFunction
from ..bounds import joint_degree, principal_gap, root_free_region
from ..errors import CertificationError, ParameterError
from ..quasipoly import QuasiPolynomial
from ..roots import count_roots
from .axis import DIRECT_CHUNK, GRID_ROUNDING, POINT_ROUNDING, AxisFunction, AxisKernels, AxisLipschitz
from .search import UNIFORM_MAX, UNIFORM_PASSES, UNIFORM_QUANTILE

__all__ = ["UnstableCount", "axis_count", "unstable_count"]

_EPS = float(np.finfo(float).eps)


@dataclass(frozen=True)
class UnstableCount:
    """Zeros of ``F`` in ``Re s > 0`` (module notes: the edge rule).

    Attributes
    ----------
    count : int or None
        Certified number of zeros with ``Re s > 0``; None when a zero lies on or within
        rounding of the imaginary axis, or no bound of the zeros in ``Re s >= 0`` exists.
    radius : float or None
        ``R``: every zero with ``Re s >= 0`` lies in ``|s| < R`` (None without a bound).
    region : (float, float, float, float) or None
        The rectangle counted by :func:`nrobust.count_roots` (None for the half disc of
        the argument principle on the axis, or without a count).
    counted : int or None
        Number of zeros in ``region`` (the doubled upper box for real coefficients).
    rigorous : bool
        The count is proven in ball arithmetic.
    method : str
        How the count was made, or why there is none.
    """

    count: int | None
    radius: float | None
    region: tuple[float, float, float, float] | None
    counted: int | None
    rigorous: bool
    method: str

    @property
    def certified(self) -> bool:
        """True when :attr:`count` is a certified number of zeros in ``Re s > 0``."""
        return self.count is not None

    @property
    def stable(self) -> bool:
        """No zero with ``Re s >= 0``: nothing counted in a rectangle reaching ``Re s <= 0``."""
        if self.region is None:
            return self.count == 0
        return self.counted == 0 and self.region[0] <= 0.0

    def __repr__(self) -> str:
        bound = "no bound" if self.radius is None else f"|s| < {self.radius:.6g}"
        proof = ", rigorous" if self.rigorous else ""
        return f"UnstableCount({self.count}, Re s > 0 and {bound}{proof}, method={self.method!r})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


def unstable_count(
    F: QuasiPolynomial,
    radius: float | None = None,
    *,
    rigorous: bool = False,
    loop: tuple[QuasiPolynomial, QuasiPolynomial, float] | None = None,
    kernels: AxisKernels | None = None,
    max_evals: int = 2_000_000,
    balls: BallFunction | None = None,
) -> UnstableCount:
    """Certified number of zeros of ``F`` with ``Re s > 0`` (module notes: the edge rule).

    Parameters
    ----------
    F : QuasiPolynomial
        The function whose zeros are counted.
    radius : float, optional
        A bound ``r`` of the zeros with ``Re s >= 0`` (``|s| <= r``), e.g. the frequency
        bound ``W`` of the loop; default the radius of
        :func:`nrobust.bounds.root_free_region`.
    rigorous : bool, optional
        Count in ball arithmetic (:func:`nrobust.count_roots` with ``rigorous=True``).
    loop : (A, B, delta), optional
        The loop factors with ``F = A + B e^{-delta s}`` and a given ``radius``: the
        argument principle on the half disc (:func:`axis_count`, floating point) is
        tried first, with ``kernels`` and the work bound ``max_evals``.
    balls : BallFunction, optional
        With ``rigorous``, the enclosure the count is proven with (:func:`nrobust.count_roots`), e.g.
        :class:`~nrobust.balls.DelayedSumBalls` of ``A + B e^{-delta s}`` where ``F = A + B.shift(delta)``
        holds a rounded delay.

    Returns
    -------
    UnstableCount

    Raises
    ------
    CertificationError
        A work bound of :func:`nrobust.count_roots` was hit.

    Examples
    --------
    >>> F = QuasiPolynomial([[-1.0, 1.0], [0.5]], [0.0, 1.0])     # s - 1 + e^{-s} / 2
    >>> unstable_count(F).count
    1
    """
    if radius is None:
        try:
            radius = root_free_region(F).radius
        except (ParameterError, CertificationError) as exc:
            return UnstableCount(None, None, None, None, rigorous, f"no bound of the zeros in Re s >= 0 ({exc})")
    if loop is not None and not rigorous:
        A, B, delta = loop
        on_axis = axis_count(A, B, delta, radius, AxisKernels((A, B)) if kernels is None else kernels, max_evals)
        if on_axis is not None:
            R = 1.01 * radius + 1e-9
            return UnstableCount(on_axis, R, None, on_axis, False, "argument principle on the half disc")
    r = 1.01 * radius + 1e-9
    if F.is_real:
        upper = count_roots(F, (0.0, r, 0.0, r), rigorous=rigorous, balls=balls)
        if not upper.shifted:
            n = 2 * int(upper)
            return UnstableCount(n, r, (0.0, r, -r, r), n, rigorous, "count_roots on the upper box, doubled")
    count = count_roots(F, (0.0, r, -r, r), rigorous=rigorous, balls=balls)
    on_edge = count.region[0] != 0.0
    return UnstableCount(
        None if on_edge else int(count),
        r,
        count.region,
        int(count),
        rigorous,
        "count_roots (a zero on or near the imaginary axis moved the left edge)" if on_edge else "count_roots",
    )


# ============================================================================ count by the argument principle
def axis_count(
    A: QuasiPolynomial, B: QuasiPolynomial, delta: float, W: float, kernels: AxisKernels, max_evals: int
) -> int | None:
    """Certified number of zeros of ``F = A + B e^{-delta s}`` in ``Re s > 0``, or None.

    The argument principle on the boundary of the half disc ``{Re s > 0, |s| < R}``,
    ``R = 1.01 W``, where the principal term ``a_0 e^{-t_0 s} s^n`` of ``A`` dominates:

    * on the arc, ``G = F e^{t_0 s} / s^n`` satisfies ``|G - a_0| < |a_0|`` (the
      frequency-bound estimate with ``|e^{-tau s}| <= 1`` on ``Re s >= 0``), so the change of
      ``arg F`` along it is ``n pi - 2 t_0 R + Arg(G(i R)/a_0) - Arg(G(-i R)/a_0)``;
    * on the axis, the change of ``arg F(i y)`` is the sum of the principal arguments of
      ``F(i y_{k+1}) / F(i y_k)`` over steps with ``M (y_{k+1} - y_k) <= |F| - E`` at both ends,
      ``M >= |A'| + |B'| + delta |B|`` on the step and ``E`` the rounding bound (each half of
      the step stays in a disc about an end value that excludes 0, and the two discs meet:
      the change is below ``pi / 3``). Real coefficients: twice the change on ``[0, R]``.

    The steps come from uniform grids (chirp-z sums) refined by cutting the failing steps.
    None (the caller falls back to :func:`nrobust.count_roots`) when ``A`` does not carry
    the dominant principal term, when ``F`` nearly vanishes on the axis, or when
    ``max_evals`` evaluations do not suffice.
    """
    degree = joint_degree(A, B)
    principal = principal_gap({"A": (A, 0), "B": (B, 1)}, degree, 0.0)
    if principal is None or principal.gap <= 0.0 or principal.first != "A":
        return None
    a0 = next(c for c, t in A.leading_terms(degree) if t == principal.t0)
    t0 = principal.t0
    h = AxisFunction(A, B, max_evals, kernels)
    lipschitz = AxisLipschitz(A, B, kernels)
    R = 1.01 * W + 1e-9
    real = A.is_real and B.is_real
    lo = 0.0 if real else -R

    def values(w: NDArray, rounding: float) -> tuple[NDArray, NDArray]:
        a, b, err_a, err_b = h.factors(w, rounding)
        rot = np.exp(-1j * w * delta)
        return a + b * rot, err_a + err_b + np.abs(b) * 4.0 * _EPS * (1.0 + np.abs(w * delta))

    def direct(w: NDArray) -> tuple[NDArray, NDArray]:
        parts = [values(w[k : k + DIRECT_CHUNK], POINT_ROUNDING) for k in range(0, w.size, DIRECT_CHUNK)]
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])

    def bound(a: NDArray, b: NDArray) -> NDArray:
        return lipschitz(a, b) + delta * h.scales[1](np.maximum(np.abs(a), np.abs(b)))

    def need(a: NDArray, b: NDArray, fa: NDArray, fb: NDArray, ea: NDArray, eb: NDArray) -> NDArray:
        room = np.minimum(np.abs(fa) - ea, np.abs(fb) - eb)
        return np.where(room > 0.0, bound(a, b) * (b - a) / np.maximum(room, 1e-300), np.inf)

    tau = max(A.max_delay, B.max_delay + delta, 1.0 / max(R, 1.0))
    segments = int(np.ceil((R - lo) / (np.pi / (8.0 * tau)) / 64.0)) * 64
    try:
        if segments + 1 > h.room():
            return None
        grid = np.linspace(lo, R, segments + 1)
        f, e = values(grid, GRID_ROUNDING)
        for _ in range(UNIFORM_PASSES):
            ratio = need(grid[:-1], grid[1:], f[:-1], f[1:], e[:-1], e[1:])
            if not np.all(np.isfinite(ratio)):
                return None
            factor = min(
                int(np.ceil(np.quantile(ratio, UNIFORM_QUANTILE))), UNIFORM_MAX, 1 + (h.room() // 2) // grid.size
            )
            if factor <= 1:
                break
            grid = np.linspace(lo, R, (grid.size - 1) * factor + 1)
            f, e = values(grid, GRID_ROUNDING)
        f_hi = f[-1]
        turn = 0.0
        left, right, f_l, f_r, e_l, e_r = grid[:-1], grid[1:], f[:-1], f[1:], e[:-1], e[1:]
        while left.size:
            ratio = need(left, right, f_l, f_r, e_l, e_r)
            sound = (np.abs(f_l) > 1e6 * e_l) & (np.abs(f_r) > 1e6 * e_r)
            ok = (ratio <= 1.0) & sound
            turn += float(np.sum(np.angle(f_r[ok] / f_l[ok])))
            bad = ~ok
            if np.any(bad & ~sound) or np.any(bad & (right - left < 1e-13 * (1.0 + np.abs(left)))):
                return None
            left, right, f_l, f_r, e_l, e_r = left[bad], right[bad], f_l[bad], f_r[bad], e_l[bad], e_r[bad]
            if not left.size:
                break
            pieces = np.clip(np.ceil(ratio[bad] * 1.25), 2, 64).astype(int)
            if int(np.sum(pieces - 1)) > h.room():
                return None
            t = np.concatenate([np.arange(1, k) / k for k in pieces])
            owner = np.repeat(np.arange(left.size), pieces - 1)
            inner = left[owner] + t * (right[owner] - left[owner])
            f_in, e_in = direct(inner)
            starts = np.r_[0, np.cumsum(pieces - 1)[:-1]]
            new_l, new_r, new_fl, new_fr, new_el, new_er = [], [], [], [], [], []
            for k in range(left.size):
                sl = slice(starts[k], starts[k] + pieces[k] - 1)
                pts = np.r_[left[k], inner[sl], right[k]]
                fv = np.r_[f_l[k], f_in[sl], f_r[k]]
                ev = np.r_[e_l[k], e_in[sl], e_r[k]]
                new_l.append(pts[:-1])
                new_r.append(pts[1:])
                new_fl.append(fv[:-1])
                new_fr.append(fv[1:])
                new_el.append(ev[:-1])
                new_er.append(ev[1:])
            left, right = np.concatenate(new_l), np.concatenate(new_r)
            f_l, f_r, e_l, e_r = (np.concatenate(x) for x in (new_fl, new_fr, new_el, new_er))
    except CertificationError:  # the work bound of the evaluations
        return None
    g_hi = f_hi * np.exp(1j * t0 * R) / (1j * R) ** degree / a0
    if real:
        arc, axis = 2.0 * float(np.angle(g_hi)), 2.0 * turn
    else:
        g_lo = f[0] * np.exp(-1j * t0 * R) / (-1j * R) ** degree / a0
        arc, axis = float(np.angle(g_hi)) - float(np.angle(g_lo)), turn
        if g_lo.real <= 0.0:
            return None
    if g_hi.real <= 0.0:
        return None
    count = (degree * np.pi - 2.0 * t0 * R + arc - axis) / (2.0 * np.pi)
    nearest = int(np.rint(count))
    if abs(count - nearest) > 1e-6 or nearest < 0:
        return None
    return nearest
