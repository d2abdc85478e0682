"""Delay margins, stability charts, admissible gains and the decay-rate/margin trade-off.

A loop with a delay ``delta`` has the characteristic function

    F(s; delta) = A(s) + B(s) e^{-delta s}

(:func:`nrobust.hyperbolic.loop_factors`: for ``U_BS2(K)``, eq. (delay_eq_alpha_ter),
``A = 1 - Phi`` and ``B = K q e^{-tau s} - I_N``). Roots reach the imaginary axis at
``s = i w`` only where ``|A(i w)| = |B(i w)|``; at such a *crossing frequency* the delays
that put a root on the axis are

    delta_{c,k} = (arg(-B(i w)/A(i w)) mod 2 pi + 2 pi k) / w,   k = 0, 1, ...

(from ``e^{-i w delta} = -A/B``). A root crosses from left to right (destabilising) or
back (stabilising) according to the sign of ``Re ds/ddelta``, which by implicit
differentiation of ``F(s(delta); delta) = 0`` is

    ds/ddelta = s B(s) e^{-delta s} / F'(s),   Re (ds/ddelta)^{-1} = Re[-(A'/A - B'/B)/s],

independent of ``k``. The number of unstable roots is piecewise constant in ``delta``
and changes only at these delays, so a certified count at ``delta = 0`` and the signed
crossings give it for every ``delta``: stability windows included.

Completeness rests on two bounds (paper, proofs of Lemma 1 and Theorem 3). With ``n`` the
degree and ``D_A``, ``D_B`` the principal parts, ``|A(i w)| - |B(i w)|`` is at least
``w^n (gap - r_A(w) - r_B(w))``, where ``gap = |a_0| - sum |others|`` is positive exactly
when the difference operator of ``F(.; delta)`` is strongly stable for every delta, and
``r`` are the remainders of :class:`nrobust.rouche.TailBound` (``|int N e^{-i w nu}| <=
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

from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import minimize_scalar

from ._json import json_float
from .sweep import sweep_map
from ._validate import positive, positive_int
from .errors import CertificationError, ConvergenceError, ParameterError
from .quasipoly import DistributedDelay, QuasiPolynomial
from .rouche import TailBound, joint_degree, principal_gap, radius_where

__all__ = [
    "ABRegion",
    "Crossing",
    "CrossingSearch",
    "DelayMargin",
    "KRegion",
    "StabilityChart",
    "Tradeoff",
    "ab_region",
    "crossing_frequencies",
    "delay_margin",
    "k_region",
    "stability_chart",
    "tradeoff",
]

# Blocks on which one Lipschitz bound of |A'| + |B'| is computed and shared by all
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


def _is_real(*parts: QuasiPolynomial) -> bool:
    for P in parts:
        for p, _ in P.point_terms:
            if np.iscomplexobj(p) and np.any(p.imag != 0):
                return False
        for d in P.distributed:
            for arr in (d.values, d.poly):
                if np.iscomplexobj(arr) and np.any(arr.imag != 0):
                    return False
    return True


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
        """JSON-ready description."""
        return {
            "omega": self.omega,
            "delays": list(self.delays),
            "direction": self.direction,
            "ds_ddelta": [self.ds_ddelta.real, self.ds_ddelta.imag],
            "tangential": self.tangential,
        }


@dataclass(frozen=True)
class CrossingSearch:
    """All zeros of ``|A(i w)| - |B(i w)|`` on ``[w_min, W]`` and how they were certified.

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
                f"crossing search: more than {self.max_evals} evaluations on the imaginary axis "
                "(raise max_evals)"
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
        self.dist = [
            (np.abs(d.poly), float(d.abs_moment(0.0, 0)), float(d.abs_moment(0.0, 1))) for d in P.distributed
        ]

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
    n = joint_degree(A, B)
    pg = principal_gap({"A": (A, 0), "B": (B, 1)}, n, 0.0)
    if pg is None or pg.gap <= 0.0:
        return None
    gap, t0 = pg.gap, pg.t0
    ta, tb = TailBound(A, n, 0.0, t0), TailBound(B, n, 0.0, t0)
    W = radius_where(lambda R: float(ta(R) + tb(R)), gap, "frequency_bound")
    return W, gap


def _search(h: _AxisFunction, lo: float, hi: float, L_of: Callable[[NDArray, NDArray], NDArray], step: float) -> tuple[list[float], list[bool]]:
    """Certified zeros of ``h`` on ``[lo, hi]`` (see the module notes)."""
    nb = _LIPSCHITZ_BLOCKS
    per_block = max(1, int(np.ceil((hi - lo) / nb / step)))
    grid = np.linspace(lo, hi, nb * per_block + 1)
    hv = h(grid)
    edges = np.linspace(lo, hi, nb + 1)
    Lb = L_of(edges[:-1], edges[1:])
    # Uniform refinements (evaluated as chirp-z transforms) sized so that most
    # segments pass the exclusion test at once; the rest is refined adaptively.
    for _ in range(_UNIFORM_PASSES):
        need = np.repeat(Lb, per_block) * np.diff(grid) / np.maximum(np.abs(hv[:-1]) + np.abs(hv[1:]), 1e-300)
        factor = int(np.clip(np.ceil(np.quantile(need, _UNIFORM_QUANTILE)), 1, _UNIFORM_MAX // per_block))
        if factor <= 1:
            break
        per_block *= factor
        grid = np.linspace(lo, hi, nb * per_block + 1)
        hv = h(grid)
    wl, wr, hl, hr = grid[:-1], grid[1:], hv[:-1], hv[1:]
    blk = np.repeat(np.arange(nb), per_block)
    min_width = _MIN_WIDTH * max(1.0, hi - lo)

    def _block(a: NDArray, b: NDArray) -> NDArray:
        """Index of the largest block bound over each segment ``[a, b]`` (blocks are contiguous)."""
        ia = np.clip(((a - lo) / (hi - lo) * nb).astype(int), 0, nb - 1)
        ib = np.clip(((b - lo) / (hi - lo) * nb).astype(int), 0, nb - 1)
        return np.where(Lb[ib] > Lb[ia], ib, ia)

    final_l: list[NDArray] = []
    final_hl: list[NDArray] = []
    final_r: list[NDArray] = []
    final_hr: list[NDArray] = []
    while wl.size:
        keep = np.abs(hl) + np.abs(hr) <= Lb[blk] * (wr - wl)
        wl, wr, hl, hr, blk = wl[keep], wr[keep], hl[keep], hr[keep], blk[keep]
        small = (wr - wl) <= min_width
        final_l.append(wl[small])
        final_r.append(wr[small])
        final_hl.append(hl[small])
        final_hr.append(hr[small])
        wl, wr, hl, hr, blk = wl[~small], wr[~small], hl[~small], hr[~small], blk[~small]
        if not wl.size:
            break
        # Refine each cluster of contiguous segments on one uniform line covering it, with
        # a power-of-two step at most 1/_SPLIT of its segments and 1/_LINE_POINTS of its
        # span: the nodes k 2^e are exact, so the evaluator sums the kernels as a chirp-z
        # transform.
        order = np.argsort(wl)
        wl, wr = wl[order], wr[order]
        cuts = np.r_[0, np.flatnonzero(wr[:-1] != wl[1:]) + 1, wl.size]
        lines = []
        for a, b in zip(cuts[:-1], cuts[1:]):
            target = min((wr[a] - wl[a]) / _SPLIT, (wr[b - 1] - wl[a]) / _LINE_POINTS)
            step = 2.0 ** np.floor(np.log2(target))
            k0, k1 = np.floor(wl[a] / step), np.ceil(wr[b - 1] / step)
            line = (k0 + np.arange(k1 - k0 + 1)) * step
            line = line[(line >= lo) & (line <= hi)]
            lines.append((line, h(line)))
        wl = np.concatenate([ln[:-1] for ln, _ in lines])
        wr = np.concatenate([ln[1:] for ln, _ in lines])
        hl = np.concatenate([v[:-1] for _, v in lines])
        hr = np.concatenate([v[1:] for _, v in lines])
        blk = _block(wl, wr)
    L = np.concatenate(final_l)
    order = np.argsort(L)
    L = L[order]
    R = np.concatenate(final_r)[order]
    HL = np.concatenate(final_hl)[order]
    HR = np.concatenate(final_hr)[order]
    roots: list[float] = []
    tangential: list[bool] = []
    brackets: list[tuple[float, float, float, float]] = []
    i = 0
    while i < L.size:  # clusters of contiguous unresolved segments
        j = i
        while j + 1 < L.size and L[j + 1] <= R[j]:
            j += 1
        pts = np.concatenate([L[i : j + 1], R[j : j + 1]])
        vals = np.concatenate([HL[i : j + 1], HR[j : j + 1]])
        zero = vals == 0.0
        change = np.flatnonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) < 0)
        roots += [float(w) for w in pts[zero]]
        tangential += [False] * int(np.count_nonzero(zero))
        brackets += [(pts[k], pts[k + 1], vals[k], vals[k + 1]) for k in change]
        if not zero.any() and not change.size:  # |h| small without a sign change: a touch, kept conservatively
            res = minimize_scalar(lambda w: abs(h.scalar(w)), bounds=(pts[0], pts[-1]), method="bounded", options={"xatol": _XTOL})
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
        history = history[1:] + [b - a]
        done[act] |= (np.abs(fn) <= 8 * np.finfo(float).eps * scale) | settled
    raise ConvergenceError(f"crossing refinement: {int(np.count_nonzero(~done))} brackets not resolved in {_MAX_REFINE} steps")


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
    fb = frequency_bound(A, B)
    if fb is None:
        raise ParameterError(
            "A, B", "loop factors whose difference operator is strongly stable for small delays (|a_0| > sum |others|)", None
        )
    return _crossing_search(A, B, fb, max_evals)


def _crossing_search(A: QuasiPolynomial, B: QuasiPolynomial, fb: tuple[float, float], max_evals: int) -> CrossingSearch:
    W, gap = fb
    h = _AxisFunction(A, B, max_evals)
    tau = max(A.max_delay, B.max_delay, 1.0 / max(W, 1.0))
    step = np.pi / (8.0 * tau)

    la, lb = _AxisLipschitz(A), _AxisLipschitz(B)

    def L_of(a: NDArray, b: NDArray) -> NDArray:
        return la(a, b) + lb(a, b)

    lo = 0.0 if _is_real(A, B) else -W
    roots, tang = _search(h, lo, W, L_of, step)
    keep = sorted((w, k) for k, w in enumerate(roots) if abs(w) > _ZERO_TOL * max(1.0, W))
    omegas = np.array([w for w, _ in keep], dtype=float)
    return CrossingSearch(omegas, np.array([tang[k] for _, k in keep], dtype=bool), float(W), float(gap), h.evals)


def _crossings(A: QuasiPolynomial, B: QuasiPolynomial, search: CrossingSearch, delta_max: float | None) -> tuple[tuple[Crossing, ...], float]:
    """Delay sequences and directions at every crossing frequency; returns ``delta_max`` too.

    ``delta_max = None`` selects one full period past the first delay of every crossing,
    ``max_c (delta_{c,0} + 2 pi / |w_c|)`` (``inf`` without crossings).
    """
    w = search.omegas
    if not w.size:
        return (), float("inf") if delta_max is None else delta_max
    s = 1j * w
    a, b, da, db = A(s), B(s), A.deriv(s), B.deriv(s)
    period = 2.0 * np.pi / np.abs(w)
    base = np.mod(np.angle(-b / a) / w, period)
    base[(base > period * (1 - _ZERO_TOL)) | (base < period * _ZERO_TOL)] = 0.0
    if delta_max is None:
        delta_max = float(np.max(base + period))
    elif not np.isfinite(delta_max):
        raise ParameterError("delta_max", "finite: the loop has crossing frequencies, hence infinitely many crossing delays", delta_max)
    e = np.exp(-s * base)
    ds = s * b * e / (da + db * e - base * b * e)
    inv_re = (-(da / a - db / b) / s).real
    scale = (np.abs(da / a) + np.abs(db / b)) / np.abs(w)
    out = []
    for k in range(w.size):
        count = 1 if delta_max < base[k] else int(np.floor((delta_max - base[k]) / period[k] * (1 + 1e-12))) + 1
        if count > _MAX_EVENTS:
            raise ParameterError("delta_max", f"small enough that at most {_MAX_EVENTS} crossing delays are enumerated", delta_max)
        tangential = bool(search.tangential[k]) or abs(inv_re[k]) <= 1e-9 * scale[k]
        direction = 0 if tangential else (1 if inv_re[k] > 0 else -1)
        delays = tuple(float(base[k] + j * period[k]) for j in range(count))
        out.append(Crossing(float(w[k]), delays, direction, complex(ds[k]), tangential))
    # rounding may put the last delay an ulp above delta_max: delta_max covers it
    within = [d for c in out for d in c.delays if d <= delta_max * (1 + 1e-12)]
    delta_max = max([float(delta_max)] + within)
    return tuple(sorted(out, key=lambda c: (c.delays[0], c.omega))), float(delta_max)


# ============================================================================ delay margin
@dataclass(frozen=True)
class DelayMargin:
    """Delay margin of ``F(s; delta) = A(s) + B(s) e^{-delta s}`` and its stability intervals.

    Attributes
    ----------
    margin : float
        ``delta*``: the loop is exponentially stable for every ``delta`` in
        ``[0, delta*)`` and not at ``delta*``. 0 when the nominal loop is not stable or
        the difference operator is not strongly stable for small ``delta > 0`` (the
        paper's zero margin, Theorem 3); ``inf`` when no crossing exists.
    omega : float or None
        Crossing frequency at which the margin is reached.
    crossings : tuple of Crossing
        Every crossing frequency with its delays up to ``delta_max``.
    nominal_stable : bool
        The loop with ``delta = 0`` is exponentially stable.
    nominal_unstable : int or None
        Certified number of zeros of ``F(.; 0)`` with ``Re s > 0`` (None when a zero
        lies on the imaginary axis or no count was possible).
    strongly_stable : bool
        The difference operator of ``F(.; delta)`` is strongly stable for small delays.
    zero_root : bool
        ``A(0) + B(0) = 0``: ``s = 0`` is a root for every delta.
    intervals : tuple of (float, float)
        Maximal open delay intervals in ``[0, delta_max]`` on which the loop is
        exponentially stable (``[0, hi)`` when it includes the nominal loop).
    counts : tuple of (float, float, int)
        Number of zeros with ``Re s > 0`` on each interval between crossing delays.
    delta_max : float
        Range of delays covered by ``intervals``.
    frequency_bound : float or None
        ``W``: no crossing (and no zero in ``Re s >= 0``) for ``|s| > W``, every delta.
    gap : float
        ``|a_0| - sum |others|`` of the principal terms (``> 0`` iff strongly stable).
    verified : bool
        The margin was checked: ``|F(i w; delta*)|`` is at rounding level and a
        certified count finds no zero in ``Re s > 0`` at ``delta* (1 - 1e-3)``.
    residual : float or None
        ``|F(i w; delta*)| / (|A| + |B|)`` at the margin.
    reason : str
        How the margin was decided, in words.
    """

    margin: float
    omega: float | None
    crossings: tuple[Crossing, ...]
    nominal_stable: bool
    nominal_unstable: int | None
    strongly_stable: bool
    zero_root: bool
    intervals: tuple[tuple[float, float], ...]
    counts: tuple[tuple[float, float, int], ...]
    delta_max: float
    frequency_bound: float | None
    gap: float
    verified: bool
    residual: float | None
    reason: str
    evaluations: int = field(default=0)

    def is_stable(self, delta: ArrayLike) -> NDArray[np.bool_]:
        """Exponential stability at each ``delta`` in ``[0, delta_max]`` (from the intervals)."""
        d = np.asarray(delta, dtype=float)
        if np.any(d < 0) or np.any(d > self.delta_max):
            raise ParameterError("delta", f"in [0, delta_max = {self.delta_max:.6g}]", delta)
        out = np.zeros(d.shape, dtype=bool)
        for lo, hi in self.intervals:
            closed = hi == self.delta_max and not any(hi in c.delays for c in self.crossings)
            out |= ((d > lo) | ((lo == 0.0) & (d == 0.0) & self.nominal_stable)) & ((d < hi) | (closed & (d == hi)))
        return out

    def unstable_count(self, delta: ArrayLike) -> NDArray[np.int64]:
        """Number of zeros with ``Re s > 0`` at each ``delta`` (-1 on a crossing delay)."""
        d = np.asarray(delta, dtype=float)
        if np.any(d < 0) or np.any(d > self.delta_max):
            raise ParameterError("delta", f"in [0, delta_max = {self.delta_max:.6g}]", delta)
        out = np.full(d.shape, -1, dtype=np.int64)
        for lo, hi, n in self.counts:
            closed = hi == self.delta_max and not any(hi in c.delays for c in self.crossings)
            out[(d > lo) & ((d < hi) | (closed & (d == hi)))] = n
        if self.nominal_unstable is not None:
            out[d == 0.0] = self.nominal_unstable
        return out

    def __repr__(self) -> str:
        w = "None" if self.omega is None else f"{self.omega:.10g}"
        return (
            f"DelayMargin(margin={self.margin:.10g}, omega={w}, crossings={len(self.crossings)}, "
            f"nominal_stable={self.nominal_stable}, strongly_stable={self.strongly_stable}, "
            f"windows={len(self.intervals)}, verified={self.verified}, reason={self.reason!r})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (infinities as strings)."""
        return {
            "margin": json_float(self.margin),
            "omega": json_float(self.omega),
            "crossings": [c.to_dict() for c in self.crossings],
            "nominal_stable": self.nominal_stable,
            "nominal_unstable": self.nominal_unstable,
            "strongly_stable": self.strongly_stable,
            "zero_root": self.zero_root,
            "intervals": [[json_float(lo), json_float(hi)] for lo, hi in self.intervals],
            "counts": [[json_float(lo), json_float(hi), n] for lo, hi, n in self.counts],
            "delta_max": json_float(self.delta_max),
            "frequency_bound": json_float(self.frequency_bound),
            "gap": self.gap,
            "verified": self.verified,
            "residual": json_float(self.residual),
            "reason": self.reason,
            "evaluations": self.evaluations,
        }


def _count_unstable(F: QuasiPolynomial, W: float) -> int:
    """Certified number of zeros with ``Re s > 0``; all lie in ``|s| <= W``."""
    from .roots import count_roots

    r = 1.01 * W + 1e-9
    return int(count_roots(F, (0.0, r, -r, r)))


def _nominal_count(A: QuasiPolynomial, B: QuasiPolynomial, W: float | None) -> int | None:
    """Certified count of unstable zeros of ``A + B``, or None if it cannot be certified."""
    from .rouche import root_free_region

    F = A + B
    if W is None:
        try:
            W = root_free_region(F).radius
        except (ParameterError, CertificationError):
            return None
    return _count_unstable(F, W)


def _as_factors(system: Any, controller: Any, n: int | None) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    if isinstance(system, QuasiPolynomial):
        if not isinstance(controller, QuasiPolynomial):
            raise ParameterError("B", "a QuasiPolynomial when A is one", type(controller).__name__)
        return system, controller
    from .hyperbolic.controllers import loop_factors

    return loop_factors(system, controller) if n is None else loop_factors(system, controller, positive_int("n", n, 2))


def delay_margin(
    system: Any,
    controller: Any,
    *,
    delta_max: float | None = None,
    verify: bool = True,
    max_evals: int = 2_000_000,
    n: int | None = None,
) -> DelayMargin:
    """Delay margin and stability intervals of ``F(s; delta) = A(s) + B(s) e^{-delta s}``.

    Called either as ``delay_margin(A, B)`` with two :class:`QuasiPolynomial` or as
    ``delay_margin(system, controller)`` (the factors of
    :func:`nrobust.hyperbolic.loop_factors`, e.g. eq. (delay_eq_alpha_ter) for
    ``U_BS2(K)``).

    Parameters
    ----------
    system, controller
        ``A, B`` or a plant and a controller.
    delta_max : float, optional
        Range of delays for the stability intervals; default
        ``max_c (delta_{c,0} + 2 pi / |w_c|)``, one period of every crossing (``inf``
        without crossings).
    verify : bool, optional
        Check the margin by the residual at ``i w`` and a certified count at
        ``delta* (1 - 1e-3)``.
    max_evals : int, optional
        Work bound of the crossing search.
    n : int, optional
        Kernel grid of the delay form when called with a plant (default that of
        :func:`nrobust.hyperbolic.loop_factors`); the margin converges as ``1/n^2``.

    Returns
    -------
    DelayMargin

    Raises
    ------
    CertificationError
        A work bound was hit, or the verification contradicts the crossing analysis.

    Examples
    --------
    >>> A = QuasiPolynomial([[1.0, 1.0]], [0.0])      # s + 1
    >>> B = QuasiPolynomial([[2.0]], [0.0])           # 2 e^{-delta s}
    >>> dm = delay_margin(A, B)
    >>> bool(abs(dm.margin - np.arccos(-0.5) / np.sqrt(3.0)) < 1e-12)
    True
    """
    A, B = _as_factors(system, controller, n)
    max_evals = positive_int("max_evals", max_evals)
    if delta_max is not None:
        delta_max = positive("delta_max", delta_max) if np.isfinite(float(delta_max)) else float("inf")
    real = _is_real(A, B)
    a0, b0 = complex(A(np.array([0j]))[0]), complex(B(np.array([0j]))[0])
    zero_root = abs(a0 + b0) <= _ZERO_TOL * max(abs(a0) + abs(b0), 1e-300)
    fb = frequency_bound(A, B)
    n = joint_degree(A, B)
    pg = principal_gap({"A": (A, 0), "B": (B, 1)}, n, 0.0)
    gap = float("-inf") if pg is None else pg.gap
    if fb is None:
        nominal = _nominal_count(A, B, None)
        reason = (
            "advanced-type loop: chains of roots in Re s > 0 for every delta > 0"
            if pg is None
            else f"difference operator not strongly stable for small delta > 0 (gap {gap:.6g} <= 0): zero margin"
        )
        return DelayMargin(
            margin=0.0, omega=None, crossings=(), nominal_stable=nominal == 0 and not zero_root,
            nominal_unstable=nominal, strongly_stable=False, zero_root=zero_root, intervals=(), counts=(),
            delta_max=0.0 if delta_max is None else delta_max, frequency_bound=None, gap=gap, verified=False,
            residual=None, reason=reason,
        )
    search = _crossing_search(A, B, fb, max_evals)
    W = search.frequency_bound
    crossings, delta_max = _crossings(A, B, search, delta_max)
    mult = 2 if real else 1
    events: dict[float, int] = {}
    for c in crossings:
        for d in c.delays:
            if d <= delta_max:
                events[d] = events.get(d, 0) + mult * c.direction
    axis_at_zero = zero_root or (0.0 in events)
    nominal = None if axis_at_zero else _count_unstable(A + B, W)
    nominal_stable = nominal == 0
    marks = sorted(d for d in events if d > 0.0)
    # Number of unstable zeros on the first interval (0, first positive crossing delay).
    if nominal is not None:
        first = nominal
    elif zero_root:
        first = None
    else:
        probe = 0.5 * marks[0] if marks else (1.0 if not np.isfinite(delta_max) else 0.5 * delta_max)
        first = _count_unstable(A + B.shift(probe), W)
    counts: list[tuple[float, float, int]] = []
    intervals: list[tuple[float, float]] = []
    if first is not None:
        bounds = [0.0] + marks + [delta_max]
        cur = first
        for k in range(len(bounds) - 1):
            if k > 0:
                cur += events[bounds[k]]
                if cur < 0:
                    raise CertificationError(
                        f"delay_margin: negative number of unstable roots after delta = {bounds[k]:.12g} "
                        "(crossing directions inconsistent with the count)"
                    )
            if bounds[k + 1] > bounds[k]:
                counts.append((bounds[k], bounds[k + 1], cur))
        # consecutive intervals are separated by a delay with a zero on the axis: never merged
        intervals = [(lo, hi) for lo, hi, m in counts if m == 0]
    if zero_root:
        margin, omega, reason = 0.0, 0.0, "s = 0 is a root for every delay (A(0) + B(0) = 0)"
    elif not nominal_stable:
        margin, omega = 0.0, None
        reason = "the nominal loop (delta = 0) is not exponentially stable"
    elif not crossings:
        margin, omega, reason = float("inf"), None, "no crossing frequency: stable for every delay"
    else:
        margin, omega = crossings[0].delays[0], crossings[0].omega
        reason = f"first crossing at w = {omega:.10g}"
    verified, residual = False, None
    if verify and nominal_stable and np.isfinite(margin) and margin > 0 and omega is not None:
        s = np.array([1j * omega])
        Fm = A(s) + B(s) * np.exp(-s * margin)
        residual = float(abs(Fm[0]) / (abs(A(s)[0]) + abs(B(s)[0])))
        below = _count_unstable(A + B.shift(margin * (1 - 1e-3)), W)
        if residual > 1e-8 or below != 0:
            raise CertificationError(
                f"delay_margin: verification failed at delta* = {margin:.12g} (residual {residual:.3g}, "
                f"{below} unstable roots just below delta*)"
            )
        verified = True
    return DelayMargin(
        margin=float(margin), omega=None if omega is None else float(omega), crossings=crossings,
        nominal_stable=bool(nominal_stable and not zero_root), nominal_unstable=nominal, strongly_stable=True,
        zero_root=zero_root, intervals=tuple(intervals), counts=tuple(counts), delta_max=float(delta_max),
        frequency_bound=W, gap=search.gap, verified=verified, residual=residual, reason=reason,
        evaluations=search.evaluations,
    )


# ============================================================================ gain studies
def _mapper(executor: Any) -> Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]]:
    """The built-in ``map`` in this process, else the sweep machinery's (``nrobust.sweep``)."""
    return map if isinstance(executor, str) and executor == "serial" else sweep_map(executor)


def _reflection(K: float) -> Any:
    from .hyperbolic.controllers import ReflectionController

    return ReflectionController(K)


def _margin_for(K: float, system: Any, delta_max: float | None, family: Callable[[float], Any]) -> DelayMargin:
    """Delay margin of ``system`` with ``family(K)`` (module level: picklable for pools)."""
    return delay_margin(system, family(float(K)), delta_max=delta_max, verify=False)


def _k_bound(system: Any) -> float:
    """The paper's sufficient bound ``(1 - |rho q|)/|q|`` of eq. (boun_K2) (0 if negative)."""
    return max(0.0, (1.0 - abs(system.rho * system.q)) / abs(system.q))


def _check_system(system: Any) -> None:
    from .hyperbolic.system import Hyperbolic2x2

    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem", system)
    if system.q == 0:
        raise ParameterError("system.q", "non-zero (otherwise the loop does not depend on K)", system.q)


def _grid(name: str, values: ArrayLike) -> NDArray[np.float64]:
    arr = np.atleast_1d(np.asarray(values, dtype=float))
    if arr.ndim != 1 or arr.size < 1 or not np.all(np.isfinite(arr)):
        raise ParameterError(name, "a non-empty 1-D array of finite numbers", values)
    return arr


@dataclass(frozen=True)
class KRegion:
    """Gains ``K`` for which ``U_BS2(K)`` is exponentially stable for every delay in ``[0, delta_max]``.

    Attributes
    ----------
    intervals : tuple of (float, float)
        The admissible gains, as open intervals; ends located by bisection to ``tol``.
    delta_max : float
        The delay range that must be tolerated.
    paper_bound : float
        ``(1 - |rho q|)/|q|`` of eq. (boun_K2). It is also necessary for a positive margin:
        ``|rho q| + |K q| < 1`` is the strong stability of the loop's difference operator.
    Ks : ndarray
        Gain grid on which the margins were computed.
    margins : ndarray
        ``delta*(K)`` on the grid.
    admissible : ndarray of bool
        ``delta*(K) > delta_max`` and the nominal loop stable, on the grid.
    tol : float
        Accuracy of the interval ends.
    """

    intervals: tuple[tuple[float, float], ...]
    delta_max: float
    paper_bound: float
    Ks: NDArray[np.float64]
    margins: NDArray[np.float64]
    admissible: NDArray[np.bool_]
    tol: float

    def __repr__(self) -> str:
        ivs = ", ".join(f"({lo:.6g}, {hi:.6g})" for lo, hi in self.intervals) or "empty"
        return f"KRegion(delta_max={self.delta_max:.6g}, K in {ivs}, paper bound |K| < {self.paper_bound:.6g})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {
            "intervals": [list(iv) for iv in self.intervals],
            "delta_max": self.delta_max,
            "paper_bound": self.paper_bound,
            "Ks": self.Ks.tolist(),
            "margins": [json_float(m) for m in self.margins],
            "admissible": self.admissible.tolist(),
            "tol": self.tol,
        }


def k_region(
    system: Any,
    delta_max: float,
    *,
    Ks: ArrayLike | None = None,
    n: int = 41,
    tol: float | None = None,
    controller: Callable[[float], Any] | None = None,
    executor: Any = "serial",
) -> KRegion:
    """Gains keeping the loop stable for every delay in ``[0, delta_max]``.

    ``U_BS2(K)`` (eq. (control3)) is admissible when the nominal loop is stable and its
    delay margin exceeds ``delta_max``. The margin is the *first* delay at which any
    crossing branch reaches the axis, so the whole interval ``[0, delta_max]`` is checked
    (stability windows further out do not count). The margin is evaluated on the grid
    ``Ks`` and every change of admissibility between neighbours is located by bisection.
    Features narrower than the grid step can be missed; inside a reported interval every
    grid gain is certified by the crossing analysis of :func:`delay_margin`.

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant.
    delta_max : float
        Delay range to tolerate (``> 0``).
    Ks : array_like, optional
        Gain grid; default ``n`` points spanning ``(-k, k)``, ``k`` the paper's bound
        (gains outside it have zero margin: the difference operator
        ``1 - rho q e^{-tau s} + K q e^{-(tau+delta) s}`` is not strongly stable).
    n : int, optional
        Size of the default grid.
    tol : float, optional
        Accuracy of the interval ends; default ``1e-4`` times the paper's bound.
    controller : callable, optional
        ``K -> controller``; default ``ReflectionController``.
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the grid points run (:func:`nrobust.sweep`'s executors); default in this
        process. Results are the same whatever the executor.

    Returns
    -------
    KRegion
    """
    _check_system(system)
    delta_max = positive("delta_max", delta_max)
    family = _reflection if controller is None else controller
    kb = _k_bound(system)
    tol = positive("tol", tol) if tol is not None else 1e-4 * (kb if kb > 0 else 1.0)
    if Ks is None:
        n = positive_int("n", n, 3)
        if kb == 0.0:
            raise ParameterError("system", "with |rho q| < 1 for the default gain grid (pass Ks)", system)
        Ks = kb * np.linspace(-1.0, 1.0, n + 2)[1:-1]
    grid = np.sort(_grid("Ks", Ks))
    results = list(_mapper(executor)(_PartialMargin(system, delta_max, family), grid))
    margins = np.array([r.margin for r in results])
    ok = np.array([r.nominal_stable and r.margin > delta_max for r in results])

    def admissible(K: float) -> bool:
        r = _margin_for(K, system, delta_max, family)
        return bool(r.nominal_stable and r.margin > delta_max)

    def edge(good: float, bad: float) -> float:
        for _ in range(200):
            if abs(good - bad) <= tol:
                break
            mid = 0.5 * (good + bad)
            if admissible(mid):
                good = mid
            else:
                bad = mid
        return good

    intervals: list[tuple[float, float]] = []
    k = 0
    while k < grid.size:
        if not ok[k]:
            k += 1
            continue
        j = k
        while j + 1 < grid.size and ok[j + 1]:
            j += 1
        lo_bad = grid[k - 1] if k > 0 else -kb
        hi_bad = grid[j + 1] if j + 1 < grid.size else kb
        lo = edge(grid[k], lo_bad) if lo_bad < grid[k] else grid[k]
        hi = edge(grid[j], hi_bad) if hi_bad > grid[j] else grid[j]
        intervals.append((float(lo), float(hi)))
        k = j + 1
    return KRegion(tuple(intervals), delta_max, kb, grid, margins, ok, tol)


@dataclass(frozen=True)
class _PartialMargin:
    """Picklable ``K -> delay_margin(system, family(K))`` for ``map`` hooks."""

    system: Any
    delta_max: float | None
    family: Callable[[float], Any]

    def __call__(self, K: float) -> DelayMargin:
        return _margin_for(K, self.system, self.delta_max, self.family)


@dataclass(frozen=True)
class _PartialFilter:
    """Picklable ``(a, b) -> delay_margin(system, FilteredController(a, b))``."""

    system: Any
    delta_max: float

    def __call__(self, ab: tuple[float, float]) -> DelayMargin:
        from .hyperbolic.controllers import FilteredController

        return delay_margin(self.system, FilteredController(*ab), delta_max=self.delta_max, verify=False)


@dataclass(frozen=True)
class ABRegion:
    """Filter coefficients ``(a, b)`` keeping the filtered ``U_BS`` stable on ``[0, delta_max]``.

    Attributes
    ----------
    a, b : ndarray
        The grid axes.
    admissible : ndarray of bool, shape ``(len(a), len(b))``
        Nominal loop stable and delay margin above ``delta_max``.
    margins : ndarray, shape ``(len(a), len(b))``
        ``delta*(a, b)``.
    strongly_stable : ndarray of bool
        ``|rho q| (1 + |a|/b) < 1``: the difference operator
        ``1 - rho q e^{-tau s} + (a/b) rho q e^{-(tau+delta) s}`` is strongly stable
        (necessary for a positive margin).
    paper_conditions : ndarray of bool
        The paper's eq. (cond_a_b): ``a/b < (1 - |rho q|)/|rho q|`` and
        ``a < (1 - |rho q|)/|rho q|``.
    delta_max : float
    """

    a: NDArray[np.float64]
    b: NDArray[np.float64]
    admissible: NDArray[np.bool_]
    margins: NDArray[np.float64]
    strongly_stable: NDArray[np.bool_]
    paper_conditions: NDArray[np.bool_]
    delta_max: float

    def __repr__(self) -> str:
        return (
            f"ABRegion(delta_max={self.delta_max:.6g}, {int(self.admissible.sum())}/{self.admissible.size} admissible, "
            f"{int((self.paper_conditions & ~self.admissible).sum())} meet eq. (cond_a_b) but are not)"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {
            "a": self.a.tolist(),
            "b": self.b.tolist(),
            "admissible": self.admissible.tolist(),
            "margins": [[json_float(m) for m in row] for row in self.margins],
            "strongly_stable": self.strongly_stable.tolist(),
            "paper_conditions": self.paper_conditions.tolist(),
            "delta_max": self.delta_max,
        }


def ab_region(system: Any, delta_max: float, a: ArrayLike, b: ArrayLike, *, executor: Any = "serial") -> ABRegion:
    """Admissible filter coefficients of the filtered finite-time controller (section 2.3.2).

    With ``U_1(s) = -(1 + a s)/(1 + b s) U_BS``, the loop is
    ``(1 + b s)(1 - Phi) + (1 + a s) Phi e^{-delta s}`` (eq. (delay_transport3) for a
    transport system). Its difference operator (the ``s`` terms divided by ``b``) is
    ``1 - rho q e^{-tau s} + (a/b) rho q e^{-(tau + delta) s}``, strongly stable iff
    ``|rho q| (1 + |a|/b) < 1``; this, not the one-sided ``a/b < (1 - |rho q|)/|rho q|``
    of eq. (cond_a_b), is necessary for a positive margin. Each grid point is decided by
    :func:`delay_margin` (nominal stability and ``delta* > delta_max``).

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant.
    delta_max : float
        Delay range to tolerate.
    a, b : array_like
        Grid axes (``b > 0``).
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the grid points run (:func:`nrobust.sweep`'s executors); default in this
        process. Results are the same whatever the executor.

    Returns
    -------
    ABRegion
    """
    _check_system(system)
    delta_max = positive("delta_max", delta_max)
    av, bv = _grid("a", a), _grid("b", b)
    if np.any(bv <= 0):
        raise ParameterError("b", "> 0", b)
    pairs = [(float(x), float(y)) for x in av for y in bv]
    results = list(_mapper(executor)(_PartialFilter(system, delta_max), pairs))
    shape = (av.size, bv.size)
    margins = np.array([r.margin for r in results]).reshape(shape)
    ok = np.array([r.nominal_stable and r.margin > delta_max for r in results]).reshape(shape)
    g = abs(system.rho * system.q)
    A_, B_ = np.meshgrid(av, bv, indexing="ij")
    strong = g * (1.0 + np.abs(A_) / B_) < 1.0
    bound = (1.0 - g) / g if g > 0 else np.inf
    paper = (A_ / B_ < bound) & (A_ < bound)
    return ABRegion(av, bv, ok, margins, strong, paper, delta_max)


@dataclass(frozen=True)
class StabilityChart:
    """Number of unstable roots (or spectral abscissa) on a ``(K, delta)`` grid, with boundaries.

    Attributes
    ----------
    Ks, deltas : ndarray
        Grid axes.
    values : ndarray, shape ``(len(Ks), len(deltas))``
        ``quantity`` at each grid point: the number of zeros with ``Re s > 0``
        (``inf`` when the difference operator is not strongly stable and ``delta > 0``;
        ``nan`` at ``delta = 0`` when the nominal count cannot be certified, e.g. a chain of
        zeros in ``Re s > 0``; ``-1`` exactly on a crossing delay), or the spectral abscissa.
    quantity : str
        ``"count"`` or ``"abscissa"``.
    margins : ndarray
        Delay margin ``delta*(K)``: the lower boundary of the stable region.
    boundaries : tuple of ndarray
        Per gain, the array of rows ``(delta, omega, direction)`` of every crossing
        delay up to ``max(deltas)``: the exact boundary curves of the chart.
    """

    Ks: NDArray[np.float64]
    deltas: NDArray[np.float64]
    values: NDArray[np.float64]
    quantity: str
    margins: NDArray[np.float64]
    boundaries: tuple[NDArray[np.float64], ...]

    def __repr__(self) -> str:
        return (
            f"StabilityChart({self.Ks.size} x {self.deltas.size} grid of {self.quantity}, "
            f"K in [{self.Ks[0]:.6g}, {self.Ks[-1]:.6g}], delta in [{self.deltas[0]:.6g}, {self.deltas[-1]:.6g}])"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {
            "Ks": self.Ks.tolist(),
            "deltas": self.deltas.tolist(),
            "values": [[json_float(v) for v in row] for row in self.values],
            "quantity": self.quantity,
            "margins": [json_float(m) for m in self.margins],
            "boundaries": [b.tolist() for b in self.boundaries],
        }


@dataclass(frozen=True)
class _PartialAbscissa:
    """Picklable ``(K, delta) -> spectral abscissa`` of the loop with ``family(K)``."""

    system: Any
    family: Callable[[float], Any]

    def __call__(self, point: tuple[float, float]) -> float:
        from .hyperbolic.controllers import loop_factors
        from .roots import spectral_abscissa

        A, B = loop_factors(self.system, self.family(point[0]))
        F = A + B if point[1] == 0 else A + B.shift(point[1])
        return float(spectral_abscissa(F).value)


def stability_chart(
    system: Any,
    Ks: ArrayLike,
    deltas: ArrayLike,
    *,
    quantity: str = "count",
    controller: Callable[[float], Any] | None = None,
    executor: Any = "serial",
) -> StabilityChart:
    """Stability chart of ``U_BS2(K)`` in the ``(K, delta)`` plane (section 4.2.1).

    For each gain one :func:`delay_margin` analysis gives the number of unstable zeros for
    every delay at once (certified count at ``delta = 0`` plus signed crossings) and the
    exact boundary curves ``delta_{c,k}(K)``. With ``quantity="abscissa"`` the spectral
    abscissa is computed at every grid point (:func:`nrobust.roots.spectral_abscissa`;
    much slower).

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant.
    Ks, deltas : array_like
        Grid axes (``deltas >= 0``).
    quantity : {"count", "abscissa"}
        What to tabulate.
    controller : callable, optional
        ``K -> controller``; default ``ReflectionController``.
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the grid points run (:func:`nrobust.sweep`'s executors); default in this
        process. Results are the same whatever the executor.

    Returns
    -------
    StabilityChart
    """
    _check_system(system)
    kv, dv = _grid("Ks", Ks), _grid("deltas", deltas)
    if np.any(dv < 0):
        raise ParameterError("deltas", ">= 0", deltas)
    if quantity not in ("count", "abscissa"):
        raise ParameterError("quantity", "'count' or 'abscissa'", quantity)
    family = _reflection if controller is None else controller
    dmax = float(np.max(dv)) if np.max(dv) > 0 else None
    results = list(_mapper(executor)(_PartialMargin(system, dmax, family), kv))
    margins = np.array([r.margin for r in results])
    boundaries = tuple(
        np.array([(d, c.omega, c.direction) for c in r.crossings for d in c.delays if d <= np.max(dv)]).reshape(-1, 3)
        for r in results
    )
    if quantity == "abscissa":
        pts = [(float(K), float(d)) for K in kv for d in dv]
        values = np.array(list(_mapper(executor)(_PartialAbscissa(system, family), pts))).reshape(kv.size, dv.size)
    else:
        values = np.empty((kv.size, dv.size))
        for i, r in enumerate(results):
            if r.strongly_stable:
                inside = dv <= r.delta_max  # delta_max is max(deltas), or inf without crossings
                values[i, inside] = r.unstable_count(dv[inside])
                values[i, ~inside] = r.counts[-1][2] if r.counts else np.nan
            else:
                values[i] = np.inf
                nominal = r.nominal_unstable
                values[i, dv == 0] = np.nan if nominal is None else nominal
    return StabilityChart(kv, dv, values, quantity, margins, boundaries)


@dataclass(frozen=True)
class Tradeoff:
    """Nominal decay rate against delay margin over the gain ``K`` (section 4.2.1).

    Attributes
    ----------
    Ks : ndarray
        Gains.
    decay_rates : ndarray
        ``-`` spectral abscissa of the nominal loop (``delta = 0``).
    margins : ndarray
        Exact delay margins ``delta*(K)``.
    rouche_bounds : ndarray
        Guaranteed ``delta_0(K)`` of Theorem 4's proof (:func:`nrobust.rouche.rouche_delay_bound`),
        ``nan`` when the controller is not ``U_BS2``.
    """

    Ks: NDArray[np.float64]
    decay_rates: NDArray[np.float64]
    margins: NDArray[np.float64]
    rouche_bounds: NDArray[np.float64]

    def __repr__(self) -> str:
        return f"Tradeoff({self.Ks.size} gains in [{self.Ks.min():.6g}, {self.Ks.max():.6g}])"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {
            "Ks": self.Ks.tolist(),
            "decay_rates": [json_float(v) for v in self.decay_rates],
            "margins": [json_float(v) for v in self.margins],
            "rouche_bounds": [json_float(v) for v in self.rouche_bounds],
        }


@dataclass(frozen=True)
class _PartialTradeoff:
    """Picklable ``K -> (decay rate, margin, delta_0)``."""

    system: Any
    family: Callable[[float], Any]

    def __call__(self, K: float) -> tuple[float, float, float]:
        from .hyperbolic.controllers import ReflectionController, loop_factors
        from .roots import spectral_abscissa
        from .rouche import rouche_delay_bound

        ctrl = self.family(float(K))
        A, B = loop_factors(self.system, ctrl)
        rate = -float(spectral_abscissa(A + B).value)
        margin = delay_margin(A, B, verify=False).margin
        d0 = rouche_delay_bound(self.system, ctrl).delta_0 if isinstance(ctrl, ReflectionController) else np.nan
        return rate, float(margin), float(d0)


def tradeoff(
    system: Any, Ks: ArrayLike, *, controller: Callable[[float], Any] | None = None, executor: Any = "serial"
) -> Tradeoff:
    """Decay rate of the nominal loop against the delay margin, over ``K``.

    The paper's remark after Lemma 3: ``K`` trades the convergence rate of the target
    system (reflection ``rho - K``: decay rate ``-ln|(rho - K) q| / tau`` on a transport
    system) for robustness to delays.

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant.
    Ks : array_like
        Gains.
    controller : callable, optional
        ``K -> controller``; default ``ReflectionController``.
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the grid points run (:func:`nrobust.sweep`'s executors); default in this
        process. Results are the same whatever the executor.

    Returns
    -------
    Tradeoff
    """
    _check_system(system)
    kv = _grid("Ks", Ks)
    family = _reflection if controller is None else controller
    rows = np.array(list(_mapper(executor)(_PartialTradeoff(system, family), kv)), dtype=float).reshape(kv.size, 3)
    return Tradeoff(kv, rows[:, 0], rows[:, 1], rows[:, 2])
