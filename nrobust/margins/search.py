"""The certified search of the zeros of ``g(w) = |A(i w)|^2 - |B(i w)|^2`` on ``[0, W]``.

Zeros of ``g`` come in three kinds: simple crossings (``g`` changes sign), tangencies
(double zeros: a pair of crossings being born or dying as a parameter moves; a root
touches the axis at one delay and turns back) and near-tangencies, which are not zeros.
The search locates the first two by their equations and proves the third away from
zero, in three stages: a first-order exclusion on grids (:func:`first_stage`), a
second-order resolution of the clusters it leaves (:func:`resolve`) and the refinement
of sign-change brackets. :func:`nrobust.margins.crossing.crossing_search` runs them;
the evaluators and bounds are those of :mod:`nrobust.margins.axis`.

**First-order exclusion.** The Lipschitz bound ``L`` of ``h = |A| - |B|`` is taken on 64
blocks; the computed values ``h~`` are accurate to ``E = 2^16 eps S``, ``S`` the sum of
the moduli of the terms (the chirp-z sums err by up to about ``1e4 eps S``), and
``|h~(w_i)| + |h~(w_{i+1})| - E_i - E_{i+1} > L (w_{i+1} - w_i)`` proves that ``h`` has
no zero on ``[w_i, w_{i+1}]`` and fixes its sign there. The grid starts at
``pi / (8 tau_max)``; the work bound ``max_evals`` is checked against its size before it
is allocated, and each refinement is sized by what the bound leaves. It is refined
uniformly (chirp-z evaluation) until 99 % of the segments pass (all but
:data:`SPARE_SEGMENTS` on the short grids of a gain study), then clusters of unresolved
segments are cut eightfold per round until at most 32 clusters of at most 128 segments
remain (one chunk of direct evaluations for the next stage) or the segments are narrower
than ``1e-7 W``.

**Second-order resolution.** Each remaining cluster ``I`` (centre ``c``, radius ``r``)
is decided on the smooth ``g``, with the bounds ``M_2``, ``M_3`` of ``|g''|``, ``|g'''|``
on ``I`` and the rounding levels ``e_0, e_1, e_2`` of :class:`~nrobust.margins.axis.AxisGap`.
By Taylor's theorem:

* ``|g(c)| - e_0 - (|g'(c)| + e_1) r - M_2 r^2 / 2 > 0``: no zero in ``I``;
* ``|g'(c)| - e_1 - M_2 r > 0``: ``g`` is monotone on ``I`` and has one simple zero iff
  the certified signs at the ends differ;
* ``|g''(c)| - e_2 - M_3 r > 0``: ``sigma g`` is convex (``sigma = sign g''``), so ``g``
  has at most two zeros. Newton's method on ``g'`` gives ``w*`` and, the tangent line
  lying below a convex function, ``sigma g(w) >= sigma g(w*) - |g'(w*)| |w - w*|`` on
  ``I``. If that bound is positive, ``g`` has no zero (a near-tangency, proven away from
  zero); if ``sigma g(w*) < 0`` beyond rounding, each end of ``I`` where ``sigma g > 0``
  brackets one simple crossing; otherwise ``g(w*)`` and ``g'(w*)`` vanish to rounding:
  a *tangency* (double zero), located to about ``1e-12`` and reported as tangential
  with slope 0;
* otherwise ``I`` is bisected (at a point where the sign of ``g`` is certain). A cluster
  still undecided after 60 rounds (a zero of multiplicity three or more, or ``g`` flat at
  the rounding level) raises :class:`~nrobust.errors.CertificationError`: the search
  never guesses.

**Refinement.** Sign-change brackets are refined by a safeguarded secant method on ``h``
to ``1e-12``, steered by the certified end signs (a value at rounding level is a zero
located to rounding).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..errors import CertificationError, ConvergenceError
from .axis import AxisFunction, AxisGap, AxisJet

__all__ = ["SPARE_SEGMENTS", "UNIFORM_MAX", "UNIFORM_PASSES", "UNIFORM_QUANTILE", "first_stage", "resolve"]

_EPS = float(np.finfo(float).eps)
# Blocks of the frequency range, each with its own bound of |A'| + |B'|.
_LIPSCHITZ_BLOCKS = 64
# Unresolved segments are cut down to this width relative to max(1, W) before the
# second-order resolution takes their clusters over.
_MIN_WIDTH = 1e-7
# Uniform refinements (at most UNIFORM_PASSES) divide the grid by the factor that lets
# this quantile of its segments pass the exclusion test, up to UNIFORM_MAX segments per
# Lipschitz block.
UNIFORM_QUANTILE = 0.99
UNIFORM_PASSES = 3
#: Segments the uniform refinements of a gain study's search may leave to the cluster
#: refinement (one chunk of the second stage): on a short range the 99 % quantile is the
#: hardest segment, next to a crossing, and would refine the whole range for it.
SPARE_SEGMENTS = 32
UNIFORM_MAX = 1024
# Each unresolved segment is cut into at least this many pieces per round, and a cluster
# of contiguous segments into at least _LINE_POINTS (the evaluator sums the kernels as a
# chirp-z transform on uniform lines of 64 points or more).
_SPLIT = 8
_LINE_POINTS = 64
# Work bound of the bracket refinement.
_MAX_REFINE = 200
# Tolerance on the crossing frequency (absolute, times max(1, w)).
_XTOL = 1e-12
# The first-order refinement hands its clusters to the second-order resolution once there
# are at most this many (one chunk of direct evaluations) made of at most 4 times as many
# segments (long clusters are cut faster on chirp-z lines).
_HANDOVER = 32
# Rounds of the second-order resolution, and Newton steps per convex cluster.
_RESOLVE_ROUNDS = 60
_NEWTON_STEPS = 40


# ============================================================================ first-order search
def first_stage(
    h: AxisFunction,
    lo: float,
    hi: float,
    lipschitz: Callable[[NDArray, NDArray], NDArray],
    step: float,
    spare: int = 0,
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Clusters ``[p, q]`` where the exclusion test leaves a zero of ``h`` possible, with the
    certified signs of ``h`` at their ends (0 where the value is at rounding level and no
    excluded neighbour fixes it).

    ``spare``: the uniform refinements leave up to that many segments to the cluster
    refinement (:data:`SPARE_SEGMENTS` for the short ranges of a gain study) where their
    quantile would leave fewer."""
    n_blocks = _LIPSCHITZ_BLOCKS
    per_block = max(1.0, np.ceil((hi - lo) / n_blocks / step))
    n_points = n_blocks * per_block + 1
    if n_points > h.room():
        raise CertificationError(
            f"crossing search: the first grid on [{lo:.6g}, {hi:.6g}] (step pi/(8 tau) = {step:.3g}, tau the "
            f"largest delay) needs about {n_points:.3g} evaluations of A and B, beyond the work bound "
            f"max_evals={h.max_evals}; raise max_evals above that estimate"
        )
    per_block = int(per_block)
    grid = np.linspace(lo, hi, n_blocks * per_block + 1)
    h_grid, e_grid = h.with_rounding(grid)
    edges = np.linspace(lo, hi, n_blocks + 1)
    block_lipschitz = lipschitz(edges[:-1], edges[1:])
    # Uniform refinements (evaluated as chirp-z transforms) sized so that most segments
    # pass the exclusion test at once, and by what the work bound leaves; the rest is
    # refined adaptively.
    for _ in range(UNIFORM_PASSES):
        room = np.maximum(np.abs(h_grid[:-1]) + np.abs(h_grid[1:]) - e_grid[:-1] - e_grid[1:], 1e-300)
        need = np.repeat(block_lipschitz, per_block) * np.diff(grid) / room
        quantile = min(UNIFORM_QUANTILE, max(0.0, 1.0 - spare / need.size))
        factor = int(np.clip(np.ceil(np.quantile(need, quantile)), 1, UNIFORM_MAX // per_block))
        factor = min(factor, 1 + (h.room() // 2) // (n_blocks * per_block))
        if factor <= 1:
            break
        per_block *= factor
        grid = np.linspace(lo, hi, n_blocks * per_block + 1)
        h_grid, e_grid = h.with_rounding(grid)
    left, right = grid[:-1], grid[1:]
    h_left, h_right, e_left, e_right = h_grid[:-1], h_grid[1:], e_grid[:-1], e_grid[1:]
    seg_block = np.repeat(np.arange(n_blocks), per_block)
    min_width = _MIN_WIDTH * max(1.0, hi - lo)

    def _block_of(a: NDArray, b: NDArray) -> NDArray:
        """Index of the largest block bound over each segment ``[a, b]`` (blocks are contiguous)."""
        block_a = np.clip(((a - lo) / (hi - lo) * n_blocks).astype(int), 0, n_blocks - 1)
        block_b = np.clip(((b - lo) / (hi - lo) * n_blocks).astype(int), 0, n_blocks - 1)
        return np.where(block_lipschitz[block_b] > block_lipschitz[block_a], block_b, block_a)

    # Signs at points whose value is at rounding level, fixed by an excluded segment ending there.
    end_sign: dict[float, int] = {}
    small: list[tuple[NDArray, ...]] = []
    while left.size:
        keep = np.abs(h_left) + np.abs(h_right) - e_left - e_right <= block_lipschitz[seg_block] * (right - left)
        out = ~keep
        for here, v_here, e_here, v_there in ((left, h_left, e_left, h_right), (right, h_right, e_right, h_left)):
            for k in np.flatnonzero(out & (np.abs(v_here) <= e_here)):
                end_sign[float(here[k])] = int(np.sign(v_there[k]))
        left, right, h_left, h_right = left[keep], right[keep], h_left[keep], h_right[keep]
        e_left, e_right, seg_block = e_left[keep], e_right[keep], seg_block[keep]
        clusters = 1 + int(np.count_nonzero(np.sort(left)[1:] != np.sort(right)[:-1])) if left.size else 0
        done = ((right - left) <= min_width) | (clusters <= _HANDOVER and left.size <= 4 * _HANDOVER)
        small.append((left[done], right[done], h_left[done], h_right[done], e_left[done], e_right[done]))
        rest = ~done
        left, right, h_left, h_right = left[rest], right[rest], h_left[rest], h_right[rest]
        e_left, e_right = e_left[rest], e_right[rest]
        if not left.size:
            break
        # Refine each cluster of contiguous segments on one uniform line covering it, with
        # a power-of-two step at most 1/_SPLIT of its segments and 1/_LINE_POINTS of its
        # span: the nodes k 2^e are exact, so the evaluator sums the kernels as a chirp-z
        # transform.
        order = np.argsort(left)
        left, right = left[order], right[order]
        cuts = np.r_[0, np.flatnonzero(right[:-1] != left[1:]) + 1, left.size]
        spans = []
        for first, stop in itertools.pairwise(cuts):
            target = min((right[first] - left[first]) / _SPLIT, (right[stop - 1] - left[first]) / _LINE_POINTS)
            line_step = 2.0 ** np.floor(np.log2(target))
            k_lo, k_hi = np.floor(left[first] / line_step), np.ceil(right[stop - 1] / line_step)
            spans.append((k_lo, k_hi, line_step))
        total = sum(k_hi - k_lo + 3 for k_lo, k_hi, _ in spans)
        if total > h.room():
            raise CertificationError(
                f"crossing search: refining {len(spans)} clusters of unresolved segments needs about {total:.3g} "
                f"more evaluations after {h.evals}, beyond the work bound max_evals={h.max_evals} (raise max_evals)"
            )
        lines = [_line(h, k_lo, k_hi, line_step, lo, hi) for k_lo, k_hi, line_step in spans]
        left = np.concatenate([ln[:-1] for ln, _, _ in lines])
        right = np.concatenate([ln[1:] for ln, _, _ in lines])
        h_left = np.concatenate([v[:-1] for _, v, _ in lines])
        h_right = np.concatenate([v[1:] for _, v, _ in lines])
        e_left = np.concatenate([e[:-1] for _, _, e in lines])
        e_right = np.concatenate([e[1:] for _, _, e in lines])
        seg_block = _block_of(left, right)
    seg_left, seg_right, seg_h_left, seg_h_right, seg_e_left, seg_e_right = (
        np.concatenate([part[k] for part in small]) for k in range(6)
    )
    order = np.argsort(seg_left)
    seg_left, seg_right = seg_left[order], seg_right[order]
    seg_h_left, seg_h_right = seg_h_left[order], seg_h_right[order]
    seg_e_left, seg_e_right = seg_e_left[order], seg_e_right[order]
    starts = np.r_[0, np.flatnonzero(seg_left[1:] > seg_right[:-1]) + 1] if seg_left.size else np.zeros(0, int)
    stops = np.r_[starts[1:] - 1, seg_left.size - 1] if seg_left.size else np.zeros(0, int)

    def _sign(point: NDArray, value: NDArray, err: NDArray) -> NDArray:
        known = np.abs(value) > err
        fixed = np.array([end_sign.get(float(p), 0) for p in point], dtype=np.int64)
        return np.where(known, np.sign(value).astype(np.int64), fixed)

    return (
        seg_left[starts],
        seg_right[stops],
        _sign(seg_left[starts], seg_h_left[starts], seg_e_left[starts]),
        _sign(seg_right[stops], seg_h_right[stops], seg_e_right[stops]),
    )


def _line(h: AxisFunction, k_lo: float, k_hi: float, step: float, lo: float, hi: float) -> tuple[NDArray, ...]:
    """``h`` on the points ``k step`` strictly inside ``(lo, hi)`` (one chirp-z line), plus
    ``lo`` or ``hi`` where the line reaches past them: the line covers ``[k_lo step, k_hi step]``
    intersected with ``[lo, hi]``."""
    line = (k_lo + np.arange(k_hi - k_lo + 1)) * step
    inner = line[(line > lo) & (line < hi)]
    head = np.array([lo] if line[0] <= lo else [])
    tail = np.array([hi] if line[-1] >= hi else [])
    parts = [(pts, *h.with_rounding(pts)) for pts in (head, inner, tail) if pts.size]
    return tuple(np.concatenate([part[k] for part in parts]) for k in range(3))


# ============================================================================ second-order resolution
@dataclass
class _Found:
    """Zeros found by the resolution: brackets to refine and points located to rounding."""

    # (a, b, sign of g at a, sign of g', first iterate, estimate of h' there or nan)
    brackets: list[tuple[float, float, int, int, float, float]] = field(default_factory=list)
    points: list[tuple[float, bool, int]] = field(default_factory=list)  # (w, tangential, slope)

    def monotone(
        self, a: float, b: float, sa: int, sb: int, slope: int, guess: float = np.nan, dh: float = np.nan
    ) -> None:
        """One interval on which ``g`` is monotone with the given slope sign (``guess``, ``dh``: see _refine)."""
        if sa and sb:
            if sa != sb:
                if sa != -slope:
                    _inconsistent(a, b, f"end signs {sa}, {sb} against slope {slope}")
                self.brackets.append((a, b, sa, slope, guess if a < guess < b else 0.5 * (a + b), dh))
        elif sa == 0 and sb == slope:
            self.points.append((a, False, slope))
        elif sb == 0 and sa == -slope:
            self.points.append((b, False, slope))
        elif sa or sb:
            _inconsistent(a, b, f"end signs {sa}, {sb} against slope {slope}")
        else:
            _inconsistent(a, b, "a monotone g at rounding level at both ends")


def _inconsistent(a: float, b: float, what: str) -> None:
    raise CertificationError(
        f"crossing search: inconsistent certificates on [{a:.17g}, {b:.17g}] ({what}): the rounding model of "
        "the evaluation of A and B does not hold here"
    )


def resolve(
    gap: AxisGap, h: AxisFunction, lo: NDArray, hi: NDArray, s_lo: NDArray, s_hi: NDArray
) -> tuple[list[float], list[bool], list[int]]:
    """Zeros of ``g`` in the clusters ``[lo, hi]`` (module notes, second-order resolution).

    Returns the zeros, whether each is a tangency, and the certified sign of ``g'`` there.
    """

    def jet(w: NDArray) -> AxisJet:
        h.spend(3 * w.size, "the second-order resolution of crossing clusters")
        return gap.jet(w)

    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    s_lo, s_hi = np.asarray(s_lo, dtype=np.int64).copy(), np.asarray(s_hi, dtype=np.int64).copy()
    found = _Found()
    # ends whose sign the first stage left open: a direct evaluation may fix it
    for ends, signs in ((lo, s_lo), (hi, s_hi)):
        open_ = np.flatnonzero(signs == 0)
        if open_.size:
            j = jet(ends[open_])
            signs[open_] = np.where(np.abs(j.g) > j.err, np.sign(j.g), 0).astype(np.int64)
    for _ in range(_RESOLVE_ROUNDS):
        if not lo.size:
            break
        c, r = 0.5 * (lo + hi), 0.5 * (hi - lo)
        j = jet(c)
        m2, m3 = gap.bounds(lo, hi, j)
        excluded = np.abs(j.g) - j.err - (np.abs(j.dg) + j.derr) * r - 0.5 * m2 * r**2 > 0.0
        monotone = ~excluded & (np.abs(j.dg) - j.derr - m2 * r > 0.0)
        convex = ~excluded & ~monotone & (np.abs(j.d2g) - j.d2err - m3 * r > 0.0)
        for k in np.flatnonzero(excluded & (s_lo * s_hi < 0)):
            _inconsistent(lo[k], hi[k], "a sign change on a segment where |g| is bounded away from zero")
        with np.errstate(divide="ignore", invalid="ignore"):
            guess = c - j.g / j.dg  # Newton's step from the centre seeds the refinement
            dh = j.dg / (j.moduli[0, 0] + j.moduli[1, 0])  # h' = g' / (|A| + |B|) where g = 0
        for k in np.flatnonzero(monotone):
            found.monotone(lo[k], hi[k], int(s_lo[k]), int(s_hi[k]), int(np.sign(j.dg[k])), guess[k], dh[k])
        # Newton's method pays when the stationary point lies inside; a first step leaving
        # the cluster means g is likely monotone there, which a bisection shows sooner.
        convex &= np.abs(j.dg) <= np.abs(j.d2g) * r
        undecided = ~(excluded | monotone | convex)
        idx = np.flatnonzero(convex)
        if idx.size:
            sub = _take(j, idx)
            decided = _convex(jet, found, lo[idx], hi[idx], s_lo[idx], s_hi[idx], np.sign(sub.d2g), sub)
            undecided[idx[~decided]] = True
        idx = np.flatnonzero(undecided)
        if not idx.size:
            lo = lo[:0]
            break
        lo, hi, s_lo, s_hi = _split(jet, lo[idx], hi[idx], s_lo[idx], s_hi[idx], j, idx)
    if lo.size:
        j = jet(0.5 * (lo + hi))
        worst = int(np.argmin(np.abs(j.g)))
        _undecidable(lo[worst], hi[worst], j, worst)
    zeros = [w for w, _, _ in found.points]
    tangential = [t for _, t, _ in found.points]
    slopes = [s for _, _, s in found.points]
    if found.brackets:
        a, b, sa, slope, guess, dh = (np.array(v, dtype=float) for v in zip(*found.brackets))
        zeros += [float(w) for w in _refine(h, a, b, sa.astype(np.int64), guess, dh)]
        tangential += [False] * a.size
        slopes += [int(v) for v in slope]
    return zeros, tangential, slopes


def _take(j: AxisJet, idx: NDArray) -> AxisJet:
    """The jet at the frequencies ``idx``."""
    return AxisJet(
        j.omega[idx],
        j.g[idx],
        j.dg[idx],
        j.d2g[idx],
        j.err[idx],
        j.derr[idx],
        j.d2err[idx],
        j.moduli[:, :, idx],
        j.rounding[:, :, idx],
    )


def _undecidable(a: float, b: float, j: AxisJet, k: int) -> None:
    raise CertificationError(
        f"crossing search: cannot decide whether |A(i w)|^2 - |B(i w)|^2 vanishes on [{a:.17g}, {b:.17g}]: "
        f"g = {j.g[k]:.3g}, g' = {j.dg[k]:.3g}, g'' = {j.d2g[k]:.3g} at its centre, within rounding "
        f"({j.err[k]:.2g}, {j.derr[k]:.2g}, {j.d2err[k]:.2g}) of a zero of multiplicity three or more; a "
        "slight change of the loop, or an evaluation of A and B in higher precision, would decide it"
    )


def _convex(
    jet: Callable[[NDArray], AxisJet],
    found: _Found,
    lo: NDArray,
    hi: NDArray,
    s_lo: NDArray,
    s_hi: NDArray,
    sigma: NDArray,
    centre: AxisJet,
) -> NDArray[np.bool_]:
    """Clusters on which ``sigma g`` is convex: Newton's method on ``g'`` from the centres
    (``centre`` holds the jet there), then the verdict.

    Returns which clusters were decided (the others are bisected).
    """
    w = 0.5 * (lo + hi)
    g, dg, d2g, err, derr = (np.array(getattr(centre, name)) for name in ("g", "dg", "d2g", "err", "derr"))
    live = np.ones(w.size, dtype=bool)
    for _ in range(_NEWTON_STEPS):
        k = np.flatnonzero(live)
        with np.errstate(divide="ignore", invalid="ignore"):
            new = np.clip(w[k] - dg[k] / d2g[k], lo[k], hi[k])
        new = np.where(np.isfinite(new), new, w[k])
        move = (np.abs(new - w[k]) > 4.0 * _EPS * np.maximum(1.0, np.abs(w[k]))) & (np.abs(dg[k]) > derr[k])
        live[k] = move
        k = k[move]
        if not k.size:
            break
        w[k] = new[move]
        j = jet(w[k])
        g[k], dg[k], d2g[k], err[k], derr[k] = j.g, j.dg, j.d2g, j.err, j.derr
    decided = np.ones(w.size, dtype=bool)
    for i in range(w.size):
        a, b, sg = float(lo[i]), float(hi[i]), int(sigma[i])
        g_w, dg_w, err_w, derr_w = sg * g[i], sg * dg[i], err[i], derr[i]
        if w[i] == b and dg_w < -derr_w:  # sigma g' increasing and negative at the right end
            found.monotone(a, b, int(s_lo[i]), int(s_hi[i]), -sg)
        elif w[i] == a and dg_w > derr_w:
            found.monotone(a, b, int(s_lo[i]), int(s_hi[i]), sg)
        elif g_w - err_w - (abs(dg_w) + derr_w) * max(w[i] - a, b - w[i]) > 0.0:
            if s_lo[i] == -sg or s_hi[i] == -sg:
                _inconsistent(a, b, "a sign change where the tangent line bounds g away from zero")
        elif g_w + err_w < 0.0:  # sign -sigma at w*: a simple zero on each side where sigma g > 0
            ws = float(w[i])
            if s_lo[i] == sg:  # sigma g decreases through zero on [a, w*]
                found.brackets.append((a, ws, sg, -sg, 0.5 * (a + ws), np.nan))
            elif s_lo[i] == 0:
                found.points.append((a, False, -sg))
            if s_hi[i] == sg:  # and increases through zero on [w*, b]
                found.brackets.append((ws, b, -sg, sg, 0.5 * (ws + b), np.nan))
            elif s_hi[i] == 0:
                found.points.append((b, False, sg))
        elif abs(dg_w) <= 4.0 * derr_w:
            found.points.append((float(w[i]), True, 0))
        else:
            decided[i] = False
    return decided


def _split(
    jet: Callable[[NDArray], AxisJet], lo: NDArray, hi: NDArray, s_lo: NDArray, s_hi: NDArray, j: AxisJet, idx: NDArray
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Bisect clusters at a point where the sign of ``g`` is certain (the centre, else a quarter off)."""
    c, r = 0.5 * (lo + hi), 0.5 * (hi - lo)
    g, err = j.g[idx], j.err[idx]
    for k in np.flatnonzero(r <= 4.0 * _EPS * np.maximum(1.0, np.abs(c))):
        _undecidable(lo[k], hi[k], j, int(idx[k]))
    mid, s_mid = c.copy(), np.where(np.abs(g) > err, np.sign(g), 0).astype(np.int64)
    for offset in (-0.25, 0.25):
        open_ = np.flatnonzero(s_mid == 0)
        if not open_.size:
            break
        trial = c[open_] + offset * r[open_]
        jt = jet(trial)
        ok = np.abs(jt.g) > jt.err
        mid[open_[ok]] = trial[ok]
        s_mid[open_[ok]] = np.sign(jt.g[ok]).astype(np.int64)
    for k in np.flatnonzero(s_mid == 0):
        _undecidable(lo[k], hi[k], j, int(idx[k]))
    return np.r_[lo, mid], np.r_[mid, hi], np.r_[s_lo, s_mid], np.r_[s_mid, s_hi]


def _refine(
    h: AxisFunction, a: NDArray, b: NDArray, sign_a: NDArray, guess: NDArray, dh: NDArray
) -> NDArray[np.float64]:
    """Zeros of ``h`` in the brackets ``[a, b]`` (certified sign ``sign_a`` at ``a``, the opposite at ``b``).

    The first iterate is ``guess`` (inside the bracket), the second a Newton step with the
    estimate ``dh`` of ``h'`` (a bisection where it is nan); then secant steps through the
    last two iterates, kept inside the bracket, with a bisection whenever the bracket has
    not halved over the last three steps (Dekker's safeguard). Each new value replaces
    the end with its sign; a value whose sign is not certain lies within rounding of the
    zero, so the bracket then still holds the zero up to that band. A bracket is done
    when narrower than ``_XTOL max(1, |w|)``, when two successive secant iterates agree
    to that tolerance, or when ``|h|`` falls below ``eps`` times the sum of the moduli of
    the terms (pure rounding).
    """
    x = guess.copy()
    fx, err = h.direct(x)
    left = np.sign(fx) == sign_a
    a, b = np.where(left, x, a), np.where(left, b, x)
    with np.errstate(divide="ignore", invalid="ignore"):
        xp = x - fx / dh  # a virtual previous iterate with value 0: the first secant step is Newton's
    fp = np.zeros(x.shape)
    xp = np.where(np.isfinite(xp), xp, x)
    history = [b - a] * 3
    done = np.abs(fx) <= err / 64.0  # err is 64 eps times the scale: below eps, the value is noise
    for _ in range(_MAX_REFINE):
        width = b - a
        done |= width <= _XTOL * np.maximum(1.0, np.abs(a))
        act = np.flatnonzero(~done)
        if not act.size:
            return np.where(np.isfinite(x), x, 0.5 * (a + b))
        aa, bb = a[act], b[act]
        with np.errstate(divide="ignore", invalid="ignore"):
            sec = x[act] - fx[act] * (x[act] - xp[act]) / (fx[act] - fp[act])
        mid = 0.5 * (aa + bb)
        stalled = width[act] > 0.5 * history[0][act]
        use_sec = np.isfinite(sec) & (sec > aa) & (sec < bb) & ~stalled
        xn = np.where(use_sec, sec, mid)
        fn, err = h.direct(xn)
        settled = use_sec & (np.abs(xn - x[act]) <= _XTOL * np.maximum(1.0, np.abs(xn)))
        xp[act], fp[act] = x[act], fx[act]
        x[act], fx[act] = xn, fn
        left = np.sign(fn) == sign_a[act]
        a[act] = np.where(left, xn, aa)
        b[act] = np.where(left, bb, xn)
        history = [*history[1:], b - a]
        done[act] |= (np.abs(fn) <= err / 64.0) | settled
    raise ConvergenceError(
        f"crossing refinement: {int(np.count_nonzero(~done))} brackets not resolved in {_MAX_REFINE} steps"
    )
