"""The search for the roots of a quasi-polynomial in a rectangle, behind :func:`nrobust.find_roots`.

:class:`Finder` combines three sources of approximations -- the chains of the principal
part for neutral quasi-polynomials (paper, Section 3, and Hale and Verduyn Lunel), a
coarse grid, and moments of boxes that still miss roots -- refines them with Newton's
method and accepts each one only when a certified count in a small box around it
confirms it; boxes whose count exceeds what was accepted are subdivided.
:mod:`nrobust.roots.finder` turns the accepted boxes into a :class:`~nrobust.roots.RootSet`
(complete when their counts add up to the count of the region) and proves it in ball
arithmetic on request.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._newton import newton
from ..difference import DifferenceOperator
from ..errors import CertificationError, ParameterError
from ..quasipoly import QuasiPolynomial
from ._common import EPS, ROUNDING, Budget, magnitude
from ._neighbours import ChebyshevIndex, connected_groups
from .winding import Counter, Region

__all__ = ["Finder", "centers", "kdtree"]

# Limit points of Newton's method closer than this (relative to 1 + |s|) share one box.
_MERGE_RTOL = 1e-4
# A stalled Newton iterate is within this many steps |F/F'| of the roots it approaches
# (an m-fold root is m steps away).
_REACH = 10.0
# Newton's method stalls near an m-fold root at |F| ~ eps A; such points are limits too.
_STALLED = 1e3 * ROUNDING
# Newton steps shorter than this (relative to 1 + |s|) are checked for a value at rounding level.
_NOISE_STEP = 1e-8
# After this many Newton steps a point whose step is still longer than _WANDER of the step
# limit is dropped: it is cycling or wandering (a real seed of a real F with no real root
# near it cycles on the real axis), not converging to a root, even a multiple one.
_PATIENCE = 12
_WANDER = 0.25
# Fixed-point steps on the asymptotic equation of a retarded chain.
_CHAIN_STEPS = 8
# Largest degree of the commensurate approximation whose chains seed Newton's method
# for incommensurate principal parts.
_SEED_DEGREE = 128


# ====================================================================== refinement
def _newton(
    F: QuasiPolynomial,
    s0: NDArray[np.complex128],
    budget: Budget,
    max_step: float,
    iters: int = 60,
    within: Region | None = None,
) -> NDArray[np.complex128]:
    """Newton's method on ``F`` from the seeds ``s0`` (nan where it did not converge).

    Each step is charged to ``budget``; a point that stops short of the step test (a
    linearly converging multiple root) is kept when its residual is at rounding level.
    A point that leaves ``within`` (a box, enlarged by half its size on each side) is
    dropped: the candidates are kept only inside the region searched, and a seed drifting
    towards a root far outside it would spend up to ``iters`` steps for nothing. So is a
    point whose step after ``_PATIENCE`` steps is still above ``_WANDER`` times
    ``max_step`` (it cycles instead of converging). The seeds only propose candidates: a
    dropped one costs no root, which the grid seeds and the subdivision still find.
    """
    if within is not None:
        x0, x1, y0, y1 = within
        dx, dy = 0.5 * (x1 - x0), 0.5 * (y1 - y0)
        lo_x, hi_x, lo_y, hi_y = x0 - dx, x1 + dx, y0 - dy, y1 + dy
    calls = [0]  # steps taken: fdf is called once per step

    def fdf(x: NDArray[np.complex128]) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        if within is None:
            f, d = F(x), F.deriv_at(x)
        else:
            out = (x.real < lo_x) | (x.real > hi_x) | (x.imag < lo_y) | (x.imag > hi_y)
            if np.logical_or.reduce(out):  # (not out.any(): its Python wrapper, at every Newton step)
                f = np.full(x.size, np.nan, dtype=complex)
                d = np.full(x.size, np.nan, dtype=complex)
                keep = ~out
                f[keep], d[keep] = F(x[keep]), F.deriv_at(x[keep])
            else:  # every point inside (f a copy: it is changed below, F may keep the array it returns)
                f, d = np.array(F(x), dtype=complex), np.asarray(F.deriv_at(x), dtype=complex)
        # |F(x)| below one rounding unit of its scale: no step can improve x (the step would be
        # rounding noise, longer than the step test when F is ill conditioned, e.g. a
        # determinant): a zero value ends the iteration of the point where it is.
        near = np.flatnonzero(np.abs(f) <= _NOISE_STEP * np.abs(d) * (1.0 + np.abs(x)))
        if near.size:
            noise = np.abs(f[near]) <= EPS * magnitude(F, x[near])
            f[near[noise]] = 0.0
        calls[0] += 1
        if calls[0] > _PATIENCE:
            with np.errstate(divide="ignore", invalid="ignore"):
                f[np.abs(f) > _WANDER * max_step * np.abs(d)] = np.nan
        return f, d

    def spend(n: int) -> None:
        budget.spend(2 * n, "refining roots by Newton's method")

    def residual_at_rounding_level(s: NDArray[np.complex128]) -> NDArray[np.bool_]:
        return np.abs(F(s)) <= _STALLED * magnitude(F, s)

    return newton(
        fdf, s0, max_step=max_step, iters=iters, on_step=spend, accept_stalled=residual_at_rounding_level, predict=True
    )


# ====================================================================== boxes
# A box is a row ``(re_min, re_max, im_min, im_max)``; distances between boxes and points
# are Chebyshev distances (``p = inf``), the metric in which a box is a ball.
def _distinct(z: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """The points ``z`` with repeats dropped (equal to about 40 bits relative to ``1 + |s|``), in order.

    Newton's method from many seeds lands on each root many times; the merge of limit points
    (:meth:`Finder._merge_clusters`) pairs the points of a group, a number that grows with
    the square of the group's size (100,001 seeds on two roots asked for 29 GiB). A repeat lies
    far inside the reach of its twin (at least ``1e-5 (1 + |s|)``), so the groups are the same.
    """
    if z.size < 2:
        return z
    q = np.exp2(np.floor(np.log2(1.0 + np.abs(z))) - 40.0)
    # the sign of the imaginary part keeps a point and its mirror image apart: their mean is real
    key = np.stack([np.round(z.real / q), np.round(z.imag / q), np.sign(z.imag), q], axis=1)
    first: dict[tuple[float, ...], int] = {}  # the first point of each key (a dict: np.unique's sort is slower)
    for k, row in enumerate(map(tuple, key.tolist())):
        first.setdefault(row, k)
    return z[list(first.values())]


def kdtree(points: NDArray[np.float64]) -> ChebyshevIndex:
    """The neighbour search of ``scipy.spatial.cKDTree(points)`` (queries with ``p = inf``, pairs)
    in numpy (:class:`~nrobust.roots._neighbours.ChebyshevIndex`: the same answers, without
    importing scipy.spatial, which takes a good part of a second)."""
    return ChebyshevIndex(points)


# Up to this many points, distances between them are computed all at once (no neighbour search).
_DENSE = 16


def _chebyshev_distances(z: NDArray[np.complex128]) -> NDArray[np.float64]:
    """The matrix of Chebyshev distances ``max(|Re (z_i - z_j)|, |Im (z_i - z_j)|)``."""
    return np.maximum(np.abs(z.real[:, None] - z.real), np.abs(z.imag[:, None] - z.imag))


def _xy(z: NDArray[np.complex128]) -> NDArray[np.float64]:
    """Complex points as ``(n, 2)`` rows ``(Re, Im)``."""
    return np.column_stack([z.real, z.imag])


def centers(boxes: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Centres (``(n, 2)`` rows) and Chebyshev radii (half the longer side) of boxes."""
    center = np.column_stack([(boxes[:, 0] + boxes[:, 1]) / 2, (boxes[:, 2] + boxes[:, 3]) / 2])
    return center, np.maximum(boxes[:, 1] - boxes[:, 0], boxes[:, 3] - boxes[:, 2]) / 2


def _boxes_about(z: NDArray[np.complex128], h: NDArray[np.float64], owners: NDArray[np.float64]) -> NDArray[np.float64]:
    """Square boxes of half-width ``h`` about ``z``, each clipped to its row of ``owners``."""
    return np.column_stack(
        [
            np.maximum(z.real - h, owners[:, 0]),
            np.minimum(z.real + h, owners[:, 1]),
            np.maximum(z.imag - h, owners[:, 2]),
            np.minimum(z.imag + h, owners[:, 3]),
        ]
    )


# Largest number of roots resolved by the contour moments of one circle; beyond it the
# power sums are ill conditioned and the box is seeded and subdivided instead.
_MAX_MOMENT_ROOTS = 16


def _retarded_chains(F: QuasiPolynomial, region: Region) -> NDArray[np.complex128]:
    """Asymptotic roots of the chains of a retarded quasi-polynomial near ``region`` (seeds only).

    Each term contributes its leading monomial ``a s^d e^{-tau s}`` (a distributed term, the
    monomials of :meth:`~nrobust.quasipoly.DistributedDelay.asymptotic_terms`). The chains
    that go to the left (Bellman and Cooke's distribution diagram) balance the two ends
    ``(tau_k, d_k)``, ``(tau_l, d_l)`` of an edge of the upper convex hull of the points
    ``(tau, d)``: ``e^{-(tau_l - tau_k) s} = -(a_k / a_l) s^(d_k - d_l)``, solved for each
    branch ``2 pi i j`` of the logarithm by a few fixed-point steps.
    """
    terms: dict[float, tuple[int, complex]] = {}
    monomials = [(complex(p[-1]), p.size - 1, t) for p, t in F.point_terms]
    monomials += [m for d in F.distributed for m in d.asymptotic_terms()]
    for a, d, t in monomials:
        if t not in terms or d > terms[t][0]:
            terms[t] = (d, a)
        elif d == terms[t][0]:
            terms[t] = (d, terms[t][1] + a)
    pts = sorted((t, d, a) for t, (d, a) in terms.items() if a != 0)
    hull: list[tuple[float, int, complex]] = []
    for p in pts:  # upper hull, left to right (Andrew's monotone chain)
        while len(hull) >= 2:
            (t1, d1, _), (t2, d2, _) = hull[-2], hull[-1]
            if (t2 - t1) * (p[1] - d1) - (d2 - d1) * (p[0] - t1) >= 0:
                hull.pop()
            else:
                break
        hull.append(p)
    x0, x1, y0, y1 = region
    pad = 1.0
    out = []
    for (tk, dk, ak), (tl, dl, al) in itertools.pairwise(hull):
        gap, mu = tl - tk, dk - dl
        if mu <= 0:
            continue
        log_w = np.log(-ak / al)
        lo = int(np.floor(-(y1 + pad) * gap / (2 * np.pi))) - 2
        hi = int(np.ceil(-(y0 - pad) * gap / (2 * np.pi))) + 2
        branch = 2j * np.pi * np.arange(lo, hi + 1)
        s = -(log_w + branch) / gap
        with np.errstate(divide="ignore", invalid="ignore"):
            for _ in range(_CHAIN_STEPS):
                s = -(log_w + mu * np.log(s) + branch) / gap
        out.append(s[np.isfinite(s)])
    if not out:
        return np.zeros(0, dtype=complex)
    s = np.concatenate(out)
    return s[(s.real > x0 - pad) & (s.real < x1 + pad) & (s.imag > y0 - pad) & (s.imag < y1 + pad)]


def _zeros_left_of(D: DifferenceOperator) -> float:
    """An abscissa right of every zero of ``D(s) = sum_k a_k e^{-tau_k s}``: ``max_k ln(K |a_k| / |a_0|) / r_k``
    over the ``K`` delayed terms (``r_k`` their delays relative to the first). Right of it each
    ``|a_k| e^{-r_k Re s}`` is below ``|a_0| / K``, so the delayed terms cannot cancel the first."""
    if D.coefs.size == 1:
        return -np.inf
    mags = np.abs(D.coefs)
    return float(np.max(np.log((mags.size - 1) * mags[1:] / mags[0]) / D.relative_delays[1:]))


@dataclass
class _Moments:
    """Roots inside a circle estimated from contour moments."""

    points: NDArray[np.complex128]  # roots of the moment polynomial
    count: float  # zeroth moment: the number of roots inside (not rounded)
    noise: float  # resolution limit of ``points`` set by rounding errors in F'/F


def _circle_moments(
    F: QuasiPolynomial, center: complex, radius: float, m: int, budget: Budget, n: int = 64
) -> _Moments | None:
    """Estimate the ``m`` roots inside a circle from its contour moments, or None.

    Power sums ``p_k = (1/2 pi i) oint (s - c)^k F'/F ds`` by the trapezoidal rule
    (spectrally accurate on a circle); Newton's identities turn them into the polynomial
    whose roots are the roots inside (Delves and Lyness). The sums are taken in the
    variable ``(s - c) / radius`` (roots inside the unit disc), so that they stay of the
    order of ``m`` instead of ``radius^k``. With ``d`` the relative rounding error of ``F``
    on the circle, ``m`` roots are resolved only to ``radius * d^(1/m)``: a multiple root
    and a cluster below that scale are indistinguishable. None when the estimate cannot
    be trusted: more than :data:`_MAX_MOMENT_ROOTS` roots (Newton's identities lose all
    digits), or ``F`` or ``F'`` not finite and nonzero on the circle.
    """
    if m > _MAX_MOMENT_ROOTS:
        return None
    theta = 2 * np.pi * np.arange(n) / n
    u = np.exp(1j * theta)
    budget.spend(2 * n, "computing contour moments")
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        fw = F(center + radius * u)
        ratio = F.deriv_at(center + radius * u) * radius / fw
        d = float(np.max(ROUNDING * magnitude(F, center + radius * u) / np.abs(fw)))
    if not (np.all(np.isfinite(ratio)) and np.isfinite(d)):
        return None
    p = np.array([np.mean(ratio * u ** (k + 1)) for k in range(0, m + 1)])
    e = np.zeros(m + 1, dtype=complex)
    e[0] = 1.0
    for k in range(1, m + 1):
        e[k] = sum((-1) ** (i - 1) * e[k - i] * p[i] for i in range(1, k + 1)) / k
    coeffs = np.array([(-1) ** k * e[k] for k in range(m + 1)])
    if not np.all(np.isfinite(coeffs)):
        return None
    try:
        points = center + radius * np.asarray(np.roots(coeffs), dtype=np.complex128)
    except np.linalg.LinAlgError:  # the companion matrix's eigenvalues did not converge
        return None
    return _Moments(points, float(p[0].real), 10 * radius * d ** (1.0 / m))


# ====================================================================== find_roots
# Candidates with their owner boxes, half-widths and settled flags (Finder._sized).
_Sized = tuple[NDArray[np.complex128], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]
# A limit point alone in its group whose Newton step |F/F'| is below this (relative to 1 + |s|) is
# settled: the polishing Newton steps of an accepted simple root would not move it further.
_SETTLED = 1e-12
# Each pass over the accepted boxes (n of them) is charged n / _BOOKKEEPING evaluations of
# the work bound: with tens of thousands of roots that pass, not the evaluations of F,
# dominates the time, and an uncharged pass let a refusal take minutes.
_BOOKKEEPING = 4


class _Found:
    """Accepted roots with their disjoint certified boxes."""

    def __init__(self) -> None:
        self.centers: list[complex] = []
        self.mults: list[int] = []
        self.boxes: list[Region] = []
        self._array: NDArray[np.float64] | None = None

    def add(self, z: complex, m: int, box: Region) -> None:
        self.centers.append(z)
        self.mults.append(m)
        self.boxes.append(box)
        self._array = None

    def total(self) -> int:
        return int(sum(self.mults))

    def inside(self, box: Region) -> int:
        """Multiplicity of accepted roots whose boxes lie inside ``box``."""
        b = self.array()
        x0, x1, y0, y1 = box
        mask = (b[:, 0] >= x0) & (b[:, 1] <= x1) & (b[:, 2] >= y0) & (b[:, 3] <= y1)
        return int(np.sum(np.asarray(self.mults, dtype=np.int64)[mask])) if mask.any() else 0

    def clear_cache(self) -> None:
        """Forget the array of boxes (after boxes were changed in place)."""
        self._array = None

    def remove_inside(self, box: Region) -> None:
        """Drop the accepted roots whose boxes lie inside ``box``."""
        b = self.array()
        x0, x1, y0, y1 = box
        keep = ~((b[:, 0] >= x0) & (b[:, 1] <= x1) & (b[:, 2] >= y0) & (b[:, 3] <= y1))
        self.centers = [z for z, k in zip(self.centers, keep) if k]
        self.mults = [m for m, k in zip(self.mults, keep) if k]
        self.boxes = [r for r, k in zip(self.boxes, keep) if k]
        self._array = None

    def array(self) -> NDArray[np.float64]:
        """The accepted boxes as an ``(n, 4)`` array."""
        if self._array is None:
            self._array = np.array(self.boxes, dtype=float).reshape(-1, 4)
        return self._array


class Finder:
    """State of one ``find_roots`` call."""

    def __init__(self, F: QuasiPolynomial, region: Region, cluster_tol: float, budget: Budget) -> None:
        self.F = F
        self.region = region
        self.cluster_tol = cluster_tol
        self.budget = budget
        self.counter = Counter(F, budget)
        self.found = _Found()
        # what :meth:`first_boxes` sized (its candidates, the region, the result), for the accept that follows
        self._first: tuple[NDArray[np.complex128], Region, _Sized] | None = None

    # ------------------------------------------------------------ candidate boxes
    def _half_widths(self, pts: NDArray[np.complex128]) -> NDArray[np.float64]:
        """Largest half-widths of square boxes about new points, disjoint from each other
        and from the accepted boxes (Chebyshev distances)."""
        cap = np.full(pts.size, np.inf)
        if 1 < pts.size <= _DENSE:  # every distance: fewer operations than the neighbour search
            dist = _chebyshev_distances(pts)
            np.fill_diagonal(dist, np.inf)
            cap = 0.3 * dist.min(axis=1)
        elif pts.size > 1:
            xy = _xy(pts)
            dist, _ = kdtree(xy).query(xy, k=2, p=np.inf)
            cap = 0.3 * dist[:, 1]
        old = self.found.array()
        if old.size:
            self.budget.spend(old.shape[0] // _BOOKKEEPING, "bookkeeping of the accepted boxes")
            c, r = centers(old)
            k = min(8, c.shape[0])
            dist, idx = kdtree(c).query(_xy(pts), k=k, p=np.inf)
            dist, idx = dist.reshape(pts.size, k), idx.reshape(pts.size, k)
            cap = np.minimum(cap, 0.9 * np.min(dist - r[idx], axis=1))
        return cap

    def _merge_clusters(
        self, pts: NDArray[np.complex128]
    ) -> tuple[NDArray[np.complex128], NDArray[np.float64], NDArray[np.bool_]]:
        """Merge limit points that may belong to one root or one cluster of roots.

        Newton's method stalls at a distance ``~eps^(1/m)`` from an ``m``-fold root, where
        its step ``|F/F'|`` is about ``1/m`` of that distance: each point gets the reach
        ``max(b, 10 |F/F'|)`` with ``b = min(1e-4 (1 + |s|), d / 10)``, ``d`` the distance
        to the nearest point outside ``1e-4 (1 + |s|)`` (at high frequency the roots of a
        chain are closer than ``1e-4 |s|``: a relative reach alone would merge the whole
        chain), and points closer than the sum of their reaches (or than ``cluster_tol``)
        share one box. The count of that box decides whether they are one multiple root
        or several roots (resolved by contour moments, then polished). Returns the group
        means and spreads (largest distance from the mean plus reach beyond ``b``), which
        size the boxes, and which groups are settled (one point, its step below
        ``_SETTLED (1 + |s|)``).
        """
        if not pts.size:
            return pts, np.zeros(0), np.zeros(0, dtype=bool)
        self.budget.spend(2 * pts.size, "merging limit points")
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            step = np.abs(self.F(pts) / self.F.deriv_at(pts))
        scale = _MERGE_RTOL * (1.0 + np.abs(pts))
        base = scale.copy()
        dense = pts.size <= _DENSE  # every distance (the 16 nearest are all): no neighbour search
        if pts.size > 1:
            if dense:
                dist = _chebyshev_distances(pts)
            else:
                xy = _xy(pts)
                index = kdtree(xy)
                dist, _ = index.query(xy, k=16, p=np.inf)
            distinct = np.where(dist > scale[:, None], dist, np.inf).min(axis=1)
            base = np.minimum(scale, 0.1 * distinct)
        stalled = np.where(np.isfinite(step), np.minimum(_REACH * step, 1e3 * scale), 1e3 * scale)
        reach = np.maximum(base, stalled)
        group = np.arange(pts.size)
        if pts.size > 1:
            if dense:  # the pairs i < j closer than the larger of cluster_tol and their reaches
                near = np.abs(pts[:, None] - pts) <= np.maximum(self.cluster_tol, reach[:, None] + reach)
                i, j = np.nonzero(near)
                pairs = np.column_stack([i, j])[i < j]
            else:
                pairs = index.query_pairs(max(self.cluster_tol, 2 * float(reach.max())), output_type="ndarray")
                if pairs.size:
                    gap = np.abs(pts[pairs[:, 0]] - pts[pairs[:, 1]])
                    pairs = pairs[gap <= np.maximum(self.cluster_tol, reach[pairs[:, 0]] + reach[pairs[:, 1]])]
            if pairs.size:
                group = connected_groups(pts.size, pairs)
        size = np.bincount(group)
        means = np.asarray((np.bincount(group, pts.real) + 1j * np.bincount(group, pts.imag)) / size, dtype=complex)
        extra = np.where(stalled > base, stalled, 0.0)
        spread = np.zeros(size.size)
        np.maximum.at(spread, group, np.abs(pts - means[group]) + extra)
        member = np.zeros(size.size, dtype=np.intp)
        member[group] = np.arange(pts.size)  # the point of a group of one
        settled = (size == 1) & (step[member] <= _SETTLED * (1.0 + np.abs(means)))
        return means, spread, settled

    # ------------------------------------------------------------ acceptance
    def accept(self, cand: NDArray[np.complex128], owners: Sequence[Region] | None = None, depth: int = 0) -> None:
        """Certify candidate roots by counts in small disjoint boxes about them.

        ``owners`` are disjoint boxes (default: the region); a candidate is kept only
        inside one of them and its box is clipped to it, so that accepted boxes never
        straddle the cuts of the subdivision.
        """
        cand, own, hard, soft, settled = self._sized(cand, owners)
        for factor in (1.0, 4.0, 16.0, 64.0, 0.3):  # an edge at rounding level of a root: resize
            if not cand.size:
                return
            h = np.minimum(soft * factor, hard)
            boxes = _boxes_about(cand, h, own)
            counts, blocked = self.counter.count([tuple(b) for b in boxes])
            stuck = blocked.any(axis=1)
            single = ~stuck & (counts == 1)
            self._accept_simple(cand[single], h[single], boxes[single], settled[single])
            for z, r, b, c in zip(
                cand[~stuck & ~single], h[~stuck & ~single], boxes[~stuck & ~single], counts[~stuck & ~single]
            ):
                self._accept_box(complex(z), float(r), tuple(b), int(c), depth)
            cand, own, hard, soft, settled = cand[stuck], own[stuck], hard[stuck], soft[stuck], settled[stuck]

    def _sized(self, cand: NDArray[np.complex128], owners: Sequence[Region] | None) -> _Sized:
        """The candidates :meth:`accept` boxes (merged, inside an owner, outside the accepted boxes),
        their owner boxes and the half-widths ``hard`` (disjoint boxes) and ``soft`` (the first tried).

        The result of :meth:`first_boxes` is reused for the same candidates (the same array) while
        nothing is accepted and the region is unchanged: it depends on nothing else.
        """
        first = self._first
        if (
            owners is None
            and first is not None
            and first[0] is cand
            and first[1] == self.region
            and not self.found.centers
        ):
            return first[2]
        cand, own, spread, settled = self._new_candidates(cand, list(owners) if owners is not None else [self.region])
        if not cand.size:
            return cand, own, spread, spread, settled
        hard = self._half_widths(cand)
        # |F| ~ r^m on the box edges of an m-fold root: boxes well wider than the scatter
        soft = np.minimum(hard, np.maximum(1e-4 * (1.0 + np.abs(cand)), 10.0 * spread))
        keep = soft > 8 * EPS * (1.0 + np.abs(cand))
        return cand[keep], own[keep], hard[keep], soft[keep], settled[keep]

    def first_boxes(self, cand: NDArray[np.complex128]) -> list[Region]:
        """The boxes that :meth:`accept` of ``cand`` counts first (for ``Counter.prefetch``)."""
        sized = self._sized(cand, None)
        self._first = (cand, self.region, sized)
        cand, own, hard, soft, _ = sized
        return [tuple(b) for b in _boxes_about(cand, np.minimum(soft, hard), own)]

    def _accept_simple(
        self, z: NDArray[np.complex128], h: NDArray[np.float64], boxes: NDArray[np.float64], settled: NDArray[np.bool_]
    ) -> None:
        """Accept boxes holding one root each, polishing the candidates (which may be the
        mean of merged limit points) by Newton steps that stay in the box; ``settled``
        candidates (:meth:`_merge_clusters`) are kept as they are."""
        if not z.size:
            return
        w = z.copy()
        todo = np.flatnonzero(~settled)
        if todo.size:
            w[todo] = _newton(self.F, z[todo], self.budget, float(np.min(h)))
        inside = (
            np.isfinite(w)
            & (boxes[:, 0] < w.real)
            & (w.real < boxes[:, 1])
            & (boxes[:, 2] < w.imag)
            & (w.imag < boxes[:, 3])
        )
        z = np.where(inside, w, z)
        boxes = self._tighten(z, np.ones(z.size, dtype=np.int64), boxes, 1e-4 * (1.0 + np.abs(z)))
        for zi, box in zip(z, boxes):
            self.found.add(complex(zi), 1, tuple(box))

    def _tighten(
        self, z: NDArray[np.complex128], m: NDArray[np.int64], boxes: NDArray[np.float64], half: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Replace boxes by sub-boxes of half-width ``half`` about ``z`` where those still
        count ``m`` roots (a smaller certified enclosure); keep the others."""
        wide = np.maximum(boxes[:, 1] - boxes[:, 0], boxes[:, 3] - boxes[:, 2]) > 4.0 * half
        if not wide.any():
            return boxes
        inner = _boxes_about(z[wide], half[wide], boxes[wide])
        counts, blocked = self.counter.count([tuple(b) for b in inner])
        good = (counts == m[wide]) & ~blocked.any(axis=1)
        out = boxes.copy()
        out[np.flatnonzero(wide)[good]] = inner[good]
        return out

    def _tighten_cluster(self, center: complex, c: int, box: Region, half: float) -> Region:
        """The smallest of the boxes of half-width ``half``, ``half / 4``, ... about
        ``center`` (not below ``1e-4 (1 + |center|)``) that still count the ``c`` roots
        of ``box``: the rounding limit of a cluster is an estimate, the count decides."""
        floor = 1e-4 * (1.0 + abs(center))
        half = max(half, floor)
        current = np.array([box], dtype=float)
        for _ in range(12):
            if max(current[0, 1] - current[0, 0], current[0, 3] - current[0, 2]) > 4.0 * half:
                tight = self._tighten(np.array([center]), np.array([c]), current, np.array([half]))
                if np.array_equal(tight, current):  # the smaller box lost roots or met one
                    break
                current = tight
            if half <= floor:
                break
            half = max(half / 4.0, floor)
        return tuple(float(v) for v in current[0])  # type: ignore[return-value]

    def _new_candidates(
        self, cand: NDArray[np.complex128], owners: list[Region]
    ) -> tuple[NDArray[np.complex128], NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """Finite candidates inside an owner box and outside accepted boxes, near ones
        merged; returned with their owner boxes, the spreads of the merge and the settled flags."""
        cand = _distinct(cand[np.isfinite(cand)])
        old = self.found.array()
        if cand.size and old.size:
            self.budget.spend(old.shape[0] // _BOOKKEEPING, "bookkeeping of the accepted boxes")
            c, r = centers(old)
            dist, idx = kdtree(c).query(_xy(cand), k=1, p=np.inf)
            cand = cand[dist > r[idx]]
        cands, owns, flags, settled = [], [], [], []
        for box in owners:
            x0, x1, y0, y1 = box
            inside, spread, done = self._merge_clusters(
                cand[(cand.real > x0) & (cand.real < x1) & (cand.imag > y0) & (cand.imag < y1)]
            )
            cands.append(inside)
            flags.append(spread)
            settled.append(done)
            owns.append(np.tile(np.asarray(box, dtype=float), (inside.size, 1)))
        if not cands:
            return np.zeros(0, dtype=complex), np.zeros((0, 4)), np.zeros(0), np.zeros(0, dtype=bool)
        return (
            np.concatenate(cands),
            np.concatenate(owns).reshape(-1, 4),
            np.concatenate(flags),
            np.concatenate(settled),
        )

    def _accept_box(self, z: complex, h: float, box: Region, c: int, depth: int) -> None:
        """Accept a box with a certified count ``c != 1``: a cluster, or resolve it."""
        if c <= 0:
            return
        # the roots of this box are resolved inside it, so that their boxes stay disjoint
        # from the other boxes of the batch being accepted
        mom = _circle_moments(self.F, z, 0.9 * h, c, self.budget)
        if mom is None or abs(mom.count - c) > 0.25:  # many roots, roots near the circle or in the box corners
            if depth < 3:
                self.accept(_newton(self.F, self.grid_seeds(box, 9), self.budget, h), [box], depth + 1)
            return
        spread = float(np.max(np.abs(mom.points[:, None] - mom.points[None, :])))
        if spread < max(self.cluster_tol, mom.noise):
            center = complex(np.mean(mom.points))
            self.found.add(center, c, self._tighten_cluster(center, c, box, 4.0 * max(spread, mom.noise)))
        elif depth < 3:  # separate roots: polish the moment estimates, certify them one by one
            self.accept(_newton(self.F, mom.points, self.budget, max(spread, h)), [box], depth + 1)

    # ------------------------------------------------------------ seeds
    def chain_seeds(self) -> NDArray[np.complex128]:
        """Zeros of the principal part's chains near the region (neutral ``F``).

        For incommensurate delays these are the chains of
        :meth:`~nrobust.difference.DifferenceOperator.commensurate_approximation`: approximate seeds only.
        """
        if self.F.kind == "retarded" and isinstance(self.F, QuasiPolynomial):
            return _retarded_chains(self.F, self.region)
        if self.F.kind != "neutral":
            return np.zeros(0, dtype=complex)
        D = self.F.principal_part()
        x0, x1, y0, y1 = self.region
        pad = 1.0
        if _zeros_left_of(D) < x0 - 0.5 * (x1 - x0) - pad:
            # the chains lie left of the box in which Newton's method keeps a seed: no seed of theirs survives
            return np.zeros(0, dtype=complex)
        if D.commensurate_step() is not None:
            ch = D.chains()
        else:  # the chains of a nearby commensurate operator of low degree are seeds too
            try:
                ch = D.commensurate_approximation(max_degree=_SEED_DEGREE).chains()
            except ParameterError:  # delays too close for a low degree: grid seeds only
                return np.zeros(0, dtype=complex)
        pts = ch.points(y0 - pad, y1 + pad)
        pts = pts[(pts.real > x0 - pad) & (pts.real < x1 + pad)]
        multiple = [c for c in ch.chains if c.multiplicity > 1]
        if multiple:  # F splits a multiple chain: seed both sides of it
            extra = np.concatenate([c.points(y0 - pad, y1 + pad) for c in multiple])
            pts = np.concatenate([pts, extra + 1e-3, extra - 1e-3])
        return pts

    def grid_seeds(self, box: Region, n: int) -> NDArray[np.complex128]:
        """About ``n`` points of a grid with cells as square as ``n`` allows in ``box`` (at most ``n``
        along a side: a box thin about the real axis gets a row of ``n`` points, not millions)."""
        x0, x1, y0, y1 = box
        w, h = x1 - x0, y1 - y0
        nx = min(n, max(1, round(np.sqrt(n * w / h))))
        ny = min(n, max(1, round(n / nx)))
        xs = x0 + (np.arange(nx) + 0.5) * w / nx
        ys = y0 + (np.arange(ny) + 0.5) * h / ny
        return (xs[None, :] + 1j * ys[:, None]).ravel()

    def seed_and_accept(self, seeds: NDArray[np.complex128], max_step: float) -> None:
        """:meth:`accept` of the limit points of :meth:`limit_points`."""
        found = self.limit_points(seeds, max_step)
        if found.size:
            self.accept(found)

    def limit_points(self, seeds: NDArray[np.complex128], max_step: float) -> NDArray[np.complex128]:
        """Newton's method from ``seeds`` (steps up to ``max_step``): the candidate roots.

        For a real ``F`` (``F(conj s) = conj F(s)``: its roots come in conjugate pairs) a seed
        below the real axis whose mirror image lies in the region is replaced by that image,
        and each limit point above the axis is accepted with its mirror image: Newton's method
        runs on the upper seeds only, and the boxes about a pair are mirror images, whose
        edges the counter computes once (:class:`~nrobust.roots.winding.Counter`). The seeds
        only propose candidates: the counts still certify every box.
        """
        if not seeds.size:
            return seeds
        real = self.F.is_real
        y0, y1 = self.region[2:]
        if real:
            flip = (seeds.imag < 0.0) & (-seeds.imag < y1)
            seeds = np.sort(np.where(flip, seeds.conj(), seeds))
            seeds = seeds[np.concatenate([[True], seeds[1:] != seeds[:-1]])]  # np.unique without its overhead
        found = _newton(self.F, seeds, self.budget, max_step, within=self.region)
        if real:
            found = found[np.isfinite(found)]
            found = np.concatenate([found, found[(found.imag > 0.0) & (-found.imag > y0)].conj()])
        return found

    # ------------------------------------------------------------ subdivision
    def _split(self, box: Region) -> tuple[Region, Region]:
        """Halve a box across its longer side, moving the cut off accepted boxes (or, if
        every cut meets one, clipping the accepted boxes it meets: :meth:`_clear_cut`)."""
        x0, x1, y0, y1 = box
        vertical = (x1 - x0) >= (y1 - y0)
        lo, hi = (x0, x1) if vertical else (y0, y1)
        cut = 0.5 * (lo + hi)
        for frac in (0.5, 0.45, 0.55, 0.4, 0.6, 0.35, 0.65, 0.3, 0.7):
            cut = lo + frac * (hi - lo)
            if not self._straddling(box, vertical, cut).size:
                break
        else:
            for frac in (0.5, 0.4, 0.6):
                cut = lo + frac * (hi - lo)
                if self._clear_cut(box, vertical, cut):
                    break
        if vertical:
            return (x0, cut, y0, y1), (cut, x1, y0, y1)
        return (x0, x1, y0, cut), (x0, x1, cut, y1)

    def _straddling(self, box: Region, vertical: bool, cut: float) -> NDArray[np.intp]:
        """Indices of the accepted boxes that meet ``box`` and that the cut runs through."""
        old = self.found.array()
        if not old.size:
            return np.zeros(0, dtype=np.intp)
        x0, x1, y0, y1 = box
        if vertical:
            hit = (old[:, 0] <= cut) & (old[:, 1] >= cut) & (old[:, 2] < y1) & (old[:, 3] > y0)
        else:
            hit = (old[:, 2] <= cut) & (old[:, 3] >= cut) & (old[:, 0] < x1) & (old[:, 1] > x0)
        return np.flatnonzero(hit)

    def _clear_cut(self, box: Region, vertical: bool, cut: float) -> bool:
        """Clip every accepted box the cut runs through to the side holding its roots.

        The two parts of such a box are counted; if one holds all of its roots (and no
        root lies on the cut), the entry keeps that part as its certified box, so that it
        lies inside one child of the subdivision. False if some box cannot be cleared.
        """
        idx = self._straddling(box, vertical, cut)
        if not idx.size:
            return True
        parts: list[Region] = []
        for i in idx:
            b0, b1, b2, b3 = self.found.boxes[i]
            if vertical:
                parts += [(b0, cut, b2, b3), (cut, b1, b2, b3)]
            else:
                parts += [(b0, b1, b2, cut), (b0, b1, cut, b3)]
        counts, blocked = self.counter.count(parts)
        new: list[tuple[int, Region]] = []
        for k, i in enumerate(idx):
            c0, c1, m = int(counts[2 * k]), int(counts[2 * k + 1]), self.found.mults[i]
            if blocked[2 * k].any() or blocked[2 * k + 1].any() or sorted((c0, c1)) != [0, m]:
                return False
            new.append((int(i), parts[2 * k] if c0 == m else parts[2 * k + 1]))
        for i, part in new:
            self.found.boxes[i] = part
        self.found.clear_cache()
        return True

    def subdivide(self, total: int, max_depth: int = 60) -> None:
        """Find the roots not yet accepted: halve every box whose certified count exceeds
        the multiplicity accepted inside it, seeding Newton's method in each such box."""
        level: list[tuple[Region, int]] = [(self.region, total)]
        for _ in range(max_depth):
            pending = [(box, c) for box, c in level if c != self.found.inside(box)]
            for box, c in pending:
                if c < self.found.inside(box):
                    raise CertificationError(f"box {box} holds more accepted roots than its certified count {c}")
            if not pending:
                return
            seeds = np.concatenate([self.grid_seeds(b, 9) for b, _ in pending])
            size = max(max(b[1] - b[0], b[3] - b[2]) for b, _ in pending)
            self.accept(_newton(self.F, seeds, self.budget, size, within=self.region), [b for b, _ in pending])
            children: list[Region] = []
            parents: list[tuple[Region, int]] = []
            for box, c in pending:
                u = c - self.found.inside(box)
                if u > 0 and max(box[1] - box[0], box[3] - box[2]) < self.cluster_tol:
                    self._accept_cluster_box(box, c)
                elif u > 0:
                    children.extend(self._split(box))
                    parents.append((box, c))
            if not children:
                return
            counts, blocked = self.counter.count(children)
            level = []
            for k in range(0, len(children), 2):
                if blocked[k].any() or blocked[k + 1].any():  # the cut runs through a root
                    level.extend(self._recut(*parents[k // 2]))
                else:
                    level.extend([(children[k], int(counts[k])), (children[k + 1], int(counts[k + 1]))])
        raise CertificationError(f"subdivision reached depth {max_depth} without isolating every root")

    def _recut(self, parent: Region, c: int) -> list[tuple[Region, int]]:
        """Split a box off its golden sections (the half cut went through a root).

        If every cut runs within rounding of a root, the roots of the box form a cluster
        that floating point cannot separate: the box is accepted as one entry holding its
        ``c`` roots (:meth:`_accept_cluster_box`) and nothing is left to split.
        """
        x0, x1, y0, y1 = parent
        vertical = (x1 - x0) >= (y1 - y0)
        for frac in (0.381966, 0.618034, 0.2763, 0.7236, 0.1459, 0.8541):
            if vertical:
                cut = x0 + frac * (x1 - x0)
                kids = [(x0, cut, y0, y1), (cut, x1, y0, y1)]
            else:
                cut = y0 + frac * (y1 - y0)
                kids = [(x0, x1, y0, cut), (x0, x1, cut, y1)]
            counts, blocked = self.counter.count(kids)
            if not blocked.any() and self._clear_cut(parent, vertical, cut):
                return [(kids[0], int(counts[0])), (kids[1], int(counts[1]))]
        self._accept_cluster_box(parent, c)
        return [(parent, c)]

    def _accept_cluster_box(self, box: Region, c: int) -> None:
        """Accept a box with certified count ``c`` as one cluster entry of multiplicity ``c``.

        The roots accepted inside it so far are merged into the entry. Its centre is the
        moment centroid when the circle about the box counts ``c`` roots (the mean of a
        cluster is well conditioned), else the centre of the box; the claim itself, ``c``
        roots in the box, rests on the certified count only.
        """
        self.found.remove_inside(box)
        x0, x1, y0, y1 = box
        center = complex(0.5 * (x0 + x1), 0.5 * (y0 + y1))
        mom = _circle_moments(self.F, center, 0.5 * float(np.hypot(x1 - x0, y1 - y0)), c, self.budget)
        if mom is not None and abs(mom.count - c) <= 0.25:
            mean = complex(np.mean(mom.points))
            if x0 < mean.real < x1 and y0 < mean.imag < y1:
                center = mean
        self.found.add(center, c, box)
