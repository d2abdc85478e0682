"""Crossing frequencies of ``F(s; delta) = A(s) + B(s) e^{-delta s}``: a complete, certified search.

Roots of a loop with a delay ``delta`` reach the imaginary axis at ``s = i w`` only where
``|A(i w)| = |B(i w)|``; at such a *crossing frequency* the delays that put a root on the
axis are

    delta_{c,k} = (arg(-B(i w)/A(i w)) mod 2 pi + 2 pi k) / w,   k = 0, 1, ...

(from ``e^{-i w delta} = -A/B``). A root crosses from left to right (destabilising) or
back (stabilising) according to the sign of ``Re ds/ddelta``, which by implicit
differentiation of ``F(s(delta); delta) = 0`` is

    ds/ddelta = s B(s) e^{-delta s} / F'(s),   Re (ds/ddelta)^{-1} = Re[-(A'/A - B'/B)/s],

independent of ``k``.

Completeness rests on two bounds (paper, proofs of Lemma 1 and Theorem 3). With ``n`` the
degree and ``D_A``, ``D_B`` the principal parts, ``|A(i w)| - |B(i w)|`` is at least
``w^n (gap - r_A(w) - r_B(w))``, where ``gap = |a_0| - sum |others|`` is positive exactly
when the difference operator of ``F(.; delta)`` is strongly stable for every delta, and
``r`` are the remainders of :class:`nrobust.bounds.TailBound` (``|int N e^{-i w nu}| <=
V / w`` by integration by parts). Past the frequency ``W`` where ``r_A + r_B < gap`` there
is no crossing, and no root with ``Re s >= 0``, for any delta. On ``[0, W]`` the function
``h(w) = |A(i w)| - |B(i w)|`` is explored with a certified exclusion test: with ``L`` a
bound of ``|A'| + |B'|`` on a segment (``QuasiPolynomial.deriv_bound``),
``|h(w_i)| + |h(w_{i+1})| > L (w_{i+1} - w_i)`` proves that ``h`` has no zero on it;
the other segments are cut (at least eightfold per round, on one uniform line per
cluster) down to a relative width ``1e-7``. There, sign changes are refined by a
safeguarded secant method to ``1e-12``, and clusters without a sign change (tangential
touches, double roots of ``h``) are reported, conservatively, as tangential crossings.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize_scalar

from ._json import fields_dict
from ._validate import positive_int
from .bounds import TailBound, joint_degree, principal_gap, radius_where
from .errors import CertificationError, ConvergenceError, ParameterError
from .quasipoly import DistributedDelay, QuasiPolynomial

__all__ = ["Crossing", "CrossingSearch", "crossing_frequencies", "frequency_bound"]

# segments inside.
_LIPSCHITZ_BLOCKS = 64
# Unresolved segments are cut down to this width relative to max(1, W) before they are
# classified as holding a crossing: crossings closer than this are resolved as one (odd
# number) or as a tangential touch (even number).
_MIN_WIDTH = 1e-7
# Uniform refinements (at most _UNIFORM_PASSES) divide the grid by the factor that lets
# this quantile of its segments pass the exclusion test, up to _UNIFORM_MAX segments per
# Lipschitz block.
_UNIFORM_QUANTILE = 0.99
_UNIFORM_PASSES = 3
_UNIFORM_MAX = 1024
# Each unresolved segment is cut into at least this many pieces per round, and a cluster
# of contiguous segments into at least _LINE_POINTS (the evaluator sums the kernels as a
# chirp-z transform on uniform lines of 64 points or more).
_SPLIT = 8
_LINE_POINTS = 64
# Work bound of the bracket refinement.
_MAX_REFINE = 200
# Tolerance on the crossing frequency (absolute, times max(1, w)).
_XTOL = 1e-12
# Relative tolerance under which a crossing delay counts as delta = 0, and under which
# A(0) + B(0) counts as zero.
_ZERO_TOL = 1e-12
# Largest number of crossing delays enumerated up to delta_max.
_MAX_EVENTS = 100_000


# ============================================================================ crossings
@dataclass(frozen=True)
class Crossing:
    """A frequency ``w`` with ``|A(i w)| = |B(i w)|`` and the delays that put ``i w`` on a root.

    Attributes
    ----------
    omega : float
        Crossing frequency ``w`` (negative only for complex coefficients).
    delays : tuple of float
        ``delta_{c,k}``, ``k = 0, 1, ...``, up to the requested ``delta_max`` (at least the
        first one).
    direction : int
        ``+1`` destabilising (roots move into ``Re s > 0`` as delta grows), ``-1``
        stabilising, ``0`` tangential (the root touches the axis and turns back).
    ds_ddelta : complex
        ``ds/ddelta`` at ``s = i w``, ``delta = delays[0]``.
    tangential : bool
        True when ``|A| - |B|`` touches zero without changing sign (a double root).
    """

    omega: float
    delays: tuple[float, ...]
    direction: int
    ds_ddelta: complex
    tangential: bool

    @property
    def period(self) -> float:
        """Spacing ``2 pi / |w|`` of the delay sequence."""
        return float(2.0 * np.pi / abs(self.omega))

    def __repr__(self) -> str:
        kind = {1: "destabilising", -1: "stabilising", 0: "tangential"}[self.direction]
        return f"Crossing(omega={self.omega:.10g}, delta_0={self.delays[0]:.10g}, period={self.period:.6g}, {kind})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (``ds_ddelta`` as ``[real, imag]``)."""
        return fields_dict(self)


@dataclass(frozen=True, eq=False)
class CrossingSearch:
    """All zeros of ``|A(i w)| - |B(i w)|`` on ``[w_min, W]`` and how they were certified.

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    omegas : ndarray
        Crossing frequencies, increasing.
    tangential : ndarray of bool
        Which of them are tangential touches (double roots).
    frequency_bound : float
        ``W``: no crossing for ``|w| > W`` (and no zero of ``F(.; delta)`` with
        ``Re s >= 0``, ``|s| > W``, for any delta).
    gap : float
        Dominance of the first principal term, ``|a_0| - sum |others|``.
    evaluations : int
        Evaluations of ``A`` and ``B`` on the axis.
    """

    omegas: NDArray[np.float64]
    tangential: NDArray[np.bool_]
    frequency_bound: float
    gap: float
    evaluations: int


class _AxisFunction:
    """``h(w) = |A(i w)| - |B(i w)|`` with an evaluation counter and a work bound.

    Kernels shared by ``A`` and ``B`` (``I_N`` in both factors of every controller of
    the paper) are evaluated once per frequency.
    """

    def __init__(self, A: QuasiPolynomial, B: QuasiPolynomial, max_evals: int) -> None:
        self.points = [QuasiPolynomial(P.coefs, P.delays) if P.point_terms else None for P in (A, B)]
        kernels: dict[tuple, tuple[DistributedDelay, list[complex]]] = {}
        for side, P in enumerate((A, B)):
            for d in P.distributed:
                const = d.poly.size == 1
                poly = np.ones(1) if const else d.poly
                key = (d.nodes.tobytes(), d.values.tobytes(), poly.tobytes(), d.moment, d.interpolation)
                if key not in kernels:
                    kernels[key] = (d.replace(poly=poly), [0.0, 0.0])
                kernels[key][1][side] += complex(d.poly[0]) if const else 1.0
        self.kernels = list(kernels.values())
        self.evals = 0
        self.max_evals = max_evals

    def __call__(self, w: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.with_scale(w)[0]

    def with_scale(self, w: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``h(w)`` and ``|A(i w)| + |B(i w)|`` (the scale of its rounding error)."""
        w = np.asarray(w, dtype=float)
        self.evals += w.size
        if self.evals > self.max_evals:
            raise CertificationError(
                f"crossing search: more than {self.max_evals} evaluations on the imaginary axis (raise max_evals)"
            )
        s = 1j * w
        vals = [np.zeros(s.shape, dtype=complex) if P is None else P(s) for P in self.points]
        for d, (ca, cb) in self.kernels:
            k = d(s)
            vals[0] = vals[0] + ca * k
            vals[1] = vals[1] + cb * k
        return np.abs(vals[0]) - np.abs(vals[1]), np.abs(vals[0]) + np.abs(vals[1])

    def scalar(self, w: float) -> float:
        return float(self(np.array([w]))[0])


class _AxisLipschitz:
    """Bound of ``|P'(i w)|`` on segments ``[a, b]`` of the frequency axis.

    Point terms use :meth:`QuasiPolynomial.deriv_bound`; a distributed term
    ``q(s) int N e^{-nu s}`` contributes ``max|q'| M_0 + max|q| M_1`` with
    ``M_k = int nu^k |N| dnu`` computed once and ``max|q| <= sum_j |q_j| r^j``,
    ``r = max(|a|, |b|)``.
    """

    def __init__(self, P: QuasiPolynomial) -> None:
        self.point = QuasiPolynomial(P.coefs, P.delays) if P.point_terms else None
        self.dist = [(np.abs(d.poly), float(d.abs_moment(0.0, 0)), float(d.abs_moment(0.0, 1))) for d in P.distributed]

    def __call__(self, a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
        out = np.zeros(np.shape(a))
        if self.point is not None:
            out = out + self.point.deriv_bound(1j * a, 1j * b)
        r = np.maximum(np.abs(a), np.abs(b))
        for q, m0, m1 in self.dist:
            qmax = sum(c * r**j for j, c in enumerate(q))
            dqmax = sum(j * c * r ** (j - 1) for j, c in enumerate(q) if j > 0)
            out = out + dqmax * m0 + qmax * m1
        return out


def frequency_bound(A: QuasiPolynomial, B: QuasiPolynomial) -> tuple[float, float] | None:
    """``(W, gap)``: no crossing above ``W``; None when the principal part is not strongly stable.

    ``gap = |a_0| - sum |others|`` over the principal terms of ``A`` and of
    ``B e^{-delta s}`` (``delta -> 0+``), positive iff the difference operator of
    ``F(.; delta)`` is strongly stable (Hale and Verduyn Lunel: ``gamma_0 < 1`` for a
    scalar operator). None is also returned for advanced-type loops.
    """
    degree = joint_degree(A, B)
    principal = principal_gap({"A": (A, 0), "B": (B, 1)}, degree, 0.0)
    if principal is None or principal.gap <= 0.0:
        return None
    gap, t0 = principal.gap, principal.t0
    tail_a, tail_b = TailBound(A, degree, 0.0, t0), TailBound(B, degree, 0.0, t0)
    W = radius_where(lambda R: float(tail_a(R) + tail_b(R)), gap, "frequency_bound")
    return W, gap


def _search(
    h: _AxisFunction, lo: float, hi: float, lipschitz: Callable[[NDArray, NDArray], NDArray], step: float
) -> tuple[list[float], list[bool]]:
    """Certified zeros of ``h`` on ``[lo, hi]`` (see the module notes)."""
    n_blocks = _LIPSCHITZ_BLOCKS
    per_block = max(1, int(np.ceil((hi - lo) / n_blocks / step)))
    grid = np.linspace(lo, hi, n_blocks * per_block + 1)
    h_grid = h(grid)
    edges = np.linspace(lo, hi, n_blocks + 1)
    block_lipschitz = lipschitz(edges[:-1], edges[1:])
    # Uniform refinements (evaluated as chirp-z transforms) sized so that most
    # segments pass the exclusion test at once; the rest is refined adaptively.
    for _ in range(_UNIFORM_PASSES):
        need = (
            np.repeat(block_lipschitz, per_block)
            * np.diff(grid)
            / np.maximum(np.abs(h_grid[:-1]) + np.abs(h_grid[1:]), 1e-300)
        )
        factor = int(np.clip(np.ceil(np.quantile(need, _UNIFORM_QUANTILE)), 1, _UNIFORM_MAX // per_block))
        if factor <= 1:
            break
        per_block *= factor
        grid = np.linspace(lo, hi, n_blocks * per_block + 1)
        h_grid = h(grid)
    left, right, h_left, h_right = grid[:-1], grid[1:], h_grid[:-1], h_grid[1:]
    seg_block = np.repeat(np.arange(n_blocks), per_block)
    min_width = _MIN_WIDTH * max(1.0, hi - lo)

    def _block_of(a: NDArray, b: NDArray) -> NDArray:
        """Index of the largest block bound over each segment ``[a, b]`` (blocks are contiguous)."""
        block_a = np.clip(((a - lo) / (hi - lo) * n_blocks).astype(int), 0, n_blocks - 1)
        block_b = np.clip(((b - lo) / (hi - lo) * n_blocks).astype(int), 0, n_blocks - 1)
        return np.where(block_lipschitz[block_b] > block_lipschitz[block_a], block_b, block_a)

    small_left: list[NDArray] = []
    small_h_left: list[NDArray] = []
    small_right: list[NDArray] = []
    small_h_right: list[NDArray] = []
    while left.size:
        keep = np.abs(h_left) + np.abs(h_right) <= block_lipschitz[seg_block] * (right - left)
        left, right, h_left, h_right, seg_block = left[keep], right[keep], h_left[keep], h_right[keep], seg_block[keep]
        small = (right - left) <= min_width
        small_left.append(left[small])
        small_right.append(right[small])
        small_h_left.append(h_left[small])
        small_h_right.append(h_right[small])
        left, right, h_left, h_right, seg_block = (
            left[~small],
            right[~small],
            h_left[~small],
            h_right[~small],
            seg_block[~small],
        )
        if not left.size:
            break
        # Refine each cluster of contiguous segments on one uniform line covering it, with
        # a power-of-two step at most 1/_SPLIT of its segments and 1/_LINE_POINTS of its
        # span: the nodes k 2^e are exact, so the evaluator sums the kernels as a chirp-z
        # transform.
        order = np.argsort(left)
        left, right = left[order], right[order]
        cuts = np.r_[0, np.flatnonzero(right[:-1] != left[1:]) + 1, left.size]
        lines = []
        for first, stop in itertools.pairwise(cuts):
            target = min((right[first] - left[first]) / _SPLIT, (right[stop - 1] - left[first]) / _LINE_POINTS)
            step = 2.0 ** np.floor(np.log2(target))
            k_lo, k_hi = np.floor(left[first] / step), np.ceil(right[stop - 1] / step)
            line = (k_lo + np.arange(k_hi - k_lo + 1)) * step
            line = line[(line >= lo) & (line <= hi)]
            lines.append((line, h(line)))
        left = np.concatenate([ln[:-1] for ln, _ in lines])
        right = np.concatenate([ln[1:] for ln, _ in lines])
        h_left = np.concatenate([v[:-1] for _, v in lines])
        h_right = np.concatenate([v[1:] for _, v in lines])
        seg_block = _block_of(left, right)
    seg_left = np.concatenate(small_left)
    order = np.argsort(seg_left)
    seg_left = seg_left[order]
    seg_right = np.concatenate(small_right)[order]
    seg_h_left = np.concatenate(small_h_left)[order]
    seg_h_right = np.concatenate(small_h_right)[order]
    roots: list[float] = []
    tangential: list[bool] = []
    brackets: list[tuple[float, float, float, float]] = []
    i = 0
    while i < seg_left.size:  # clusters of contiguous unresolved segments
        j = i
        while j + 1 < seg_left.size and seg_left[j + 1] <= seg_right[j]:
            j += 1
        pts = np.concatenate([seg_left[i : j + 1], seg_right[j : j + 1]])
        vals = np.concatenate([seg_h_left[i : j + 1], seg_h_right[j : j + 1]])
        zero = vals == 0.0
        change = np.flatnonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) < 0)
        roots += [float(w) for w in pts[zero]]
        tangential += [False] * int(np.count_nonzero(zero))
        brackets += [(pts[k], pts[k + 1], vals[k], vals[k + 1]) for k in change]
        if not zero.any() and not change.size:  # |h| small without a sign change: a touch, kept conservatively
            res = minimize_scalar(
                lambda w: abs(h.scalar(w)), bounds=(pts[0], pts[-1]), method="bounded", options={"xatol": _XTOL}
            )
            roots.append(float(res.x))
            tangential.append(True)
        i = j + 1
    if brackets:
        roots += list(_refine(h, *(np.array(v, dtype=float) for v in zip(*brackets))))
        tangential += [False] * len(brackets)
    return roots, tangential


def _refine(h: _AxisFunction, a: NDArray, b: NDArray, ha: NDArray, hb: NDArray) -> NDArray[np.float64]:
    """Zeros of ``h`` in the sign-change brackets ``[a, b]``, all at once.

    Secant steps through the last two iterates, kept inside the bracket, with a bisection
    whenever the bracket has not halved over the last three steps (Dekker's safeguard).
    A bracket is done when narrower than ``_XTOL max(1, |w|)``, when two successive
    secant iterates agree to that tolerance (superlinear convergence), or when ``|h|``
    reaches the rounding level of ``|A| + |B|``.
    """
    xp, fp = a.copy(), ha.copy()
    x, fx = b.copy(), hb.copy()
    history = [b - a] * 3
    done = np.zeros(a.shape, dtype=bool)
    for _ in range(_MAX_REFINE):
        width = b - a
        done |= width <= _XTOL * np.maximum(1.0, np.abs(a))
        act = np.flatnonzero(~done)
        if not act.size:
            return x
        aa, bb = a[act], b[act]
        with np.errstate(divide="ignore", invalid="ignore"):
            sec = x[act] - fx[act] * (x[act] - xp[act]) / (fx[act] - fp[act])
        mid = 0.5 * (aa + bb)
        stalled = width[act] > 0.5 * history[0][act]
        use_sec = np.isfinite(sec) & (sec > aa) & (sec < bb) & ~stalled
        xn = np.where(use_sec, sec, mid)
        fn, scale = h.with_scale(xn)
        settled = use_sec & (np.abs(xn - x[act]) <= _XTOL * np.maximum(1.0, np.abs(xn)))
        xp[act], fp[act] = x[act], fx[act]
        x[act], fx[act] = xn, fn
        left = np.sign(fn) == np.sign(ha[act])
        a[act] = np.where(left, xn, aa)
        ha[act] = np.where(left, fn, ha[act])
        b[act] = np.where(left, bb, xn)
        hb[act] = np.where(left, hb[act], fn)
        history = [*history[1:], b - a]
        done[act] |= (np.abs(fn) <= 8 * np.finfo(float).eps * scale) | settled
    raise ConvergenceError(
        f"crossing refinement: {int(np.count_nonzero(~done))} brackets not resolved in {_MAX_REFINE} steps"
    )


def crossing_frequencies(A: QuasiPolynomial, B: QuasiPolynomial, *, max_evals: int = 2_000_000) -> CrossingSearch:
    """Every frequency ``w > 0`` (all real ``w`` for complex coefficients) with ``|A(i w)| = |B(i w)|``.

    The search range ``[0, W]`` is finite and provably complete (module notes); the
    exclusion test makes every reported absence of a crossing a proof.

    Parameters
    ----------
    A, B : QuasiPolynomial
        The loop factors of ``F(s; delta) = A(s) + B(s) e^{-delta s}``.
    max_evals : int, optional
        Work bound on the evaluations of ``A`` and ``B``.

    Returns
    -------
    CrossingSearch

    Raises
    ------
    ParameterError
        If the difference operator of the loop is not strongly stable for small delays
        (no finite ``W`` exists: crossings accumulate at infinity).
    CertificationError
        If the work bound is hit.

    Examples
    --------
    >>> A = QuasiPolynomial([[1.0, 1.0]], [0.0])      # s + 1
    >>> B = QuasiPolynomial([[2.0]], [0.0])           # 2 e^{-delta s}
    >>> res = crossing_frequencies(A, B)
    >>> round(float(res.omegas[0]) ** 2, 10)
    3.0
    """
    for name, P in (("A", A), ("B", B)):
        if not isinstance(P, QuasiPolynomial):
            raise ParameterError(name, "a QuasiPolynomial", type(P).__name__)
    max_evals = positive_int("max_evals", max_evals)
    w_bound = frequency_bound(A, B)
    if w_bound is None:
        raise ParameterError(
            "A, B",
            "loop factors whose difference operator is strongly stable for small delays (|a_0| > sum |others|)",
            None,
        )
    return _crossing_search(A, B, w_bound, max_evals)


def _crossing_search(
    A: QuasiPolynomial, B: QuasiPolynomial, w_bound: tuple[float, float], max_evals: int
) -> CrossingSearch:
    W, gap = w_bound
    h = _AxisFunction(A, B, max_evals)
    tau = max(A.max_delay, B.max_delay, 1.0 / max(W, 1.0))
    step = np.pi / (8.0 * tau)

    lipschitz_a, lipschitz_b = _AxisLipschitz(A), _AxisLipschitz(B)

    def lipschitz(a: NDArray, b: NDArray) -> NDArray:
        return lipschitz_a(a, b) + lipschitz_b(a, b)

    lo = 0.0 if (A.is_real and B.is_real) else -W
    roots, tangential = _search(h, lo, W, lipschitz, step)
    keep = sorted((w, k) for k, w in enumerate(roots) if abs(w) > _ZERO_TOL * max(1.0, W))
    omegas = np.array([w for w, _ in keep], dtype=float)
    return CrossingSearch(omegas, np.array([tangential[k] for _, k in keep], dtype=bool), float(W), float(gap), h.evals)


def _crossings(
    A: QuasiPolynomial, B: QuasiPolynomial, search: CrossingSearch, delta_max: float | None
) -> tuple[tuple[Crossing, ...], float]:
    """Delay sequences and directions at every crossing frequency; returns ``delta_max`` too.

    ``delta_max = None`` selects one full period past the first delay of every crossing,
    ``max_c (delta_{c,0} + 2 pi / |w_c|)`` (``inf`` without crossings).
    """
    w = search.omegas
    if not w.size:
        return (), float("inf") if delta_max is None else delta_max
    s = 1j * w
    a, b, da, db = A(s), B(s), A.deriv_at(s), B.deriv_at(s)
    period = 2.0 * np.pi / np.abs(w)
    base = np.mod(np.angle(-b / a) / w, period)
    base[(base > period * (1 - _ZERO_TOL)) | (base < period * _ZERO_TOL)] = 0.0
    if delta_max is None:
        delta_max = float(np.max(base + period))
    elif not np.isfinite(delta_max):
        raise ParameterError(
            "delta_max", "finite: the loop has crossing frequencies, hence infinitely many crossing delays", delta_max
        )
    e = np.exp(-s * base)
    ds = s * b * e / (da + db * e - base * b * e)
    inv_re = (-(da / a - db / b) / s).real
    scale = (np.abs(da / a) + np.abs(db / b)) / np.abs(w)
    out = []
    for k in range(w.size):
        count = 1 if delta_max < base[k] else int(np.floor((delta_max - base[k]) / period[k] * (1 + 1e-12))) + 1
        if count > _MAX_EVENTS:
            raise ParameterError(
                "delta_max", f"small enough that at most {_MAX_EVENTS} crossing delays are enumerated", delta_max
            )
        tangential = bool(search.tangential[k]) or abs(inv_re[k]) <= 1e-9 * scale[k]
        direction = 0 if tangential else (1 if inv_re[k] > 0 else -1)
        delays = tuple(float(base[k] + j * period[k]) for j in range(count))
        out.append(Crossing(float(w[k]), delays, direction, complex(ds[k]), tangential))
    # rounding may put the last delay an ulp above delta_max: delta_max covers it
    within = [d for c in out for d in c.delays if d <= delta_max * (1 + 1e-12)]
    delta_max = max([float(delta_max), *within])
    return tuple(sorted(out, key=lambda c: (c.delays[0], c.omega))), float(delta_max)
