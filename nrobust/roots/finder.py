"""Certified root finding for quasi-polynomials in rectangles.

Root finding combines three sources of approximations -- the chains of the principal
part for neutral quasi-polynomials (paper, Section 3, and Hale and Verduyn Lunel), a
coarse grid, and moments of boxes that still miss roots -- refines them with Newton's
method and accepts each one only when a certified count in a small box around it
confirms it. The roots are certified complete when the certified counts of these
disjoint boxes add up to the certified count of the whole region.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from .._validate import positive, positive_int
from .._validate import region as _check_region
from ..errors import CertificationError, ParameterError
from ..quasipoly import QuasiPolynomial
from .winding import (
    _EPS,
    _MERGE_RTOL,
    _REACH,
    _ROUNDING,
    _SEED_DEGREE,
    _STALLED,
    METHODS,
    Region,
    _Budget,
    _check_function,
    _count_with_shifts,
    _Counter,
    _magnitude,
)

__all__ = ["RootSet", "find_roots"]


# ====================================================================== refinement
def _newton(
    F: QuasiPolynomial, s0: NDArray[np.complex128], budget: _Budget, max_step: float, iters: int = 60
) -> NDArray[np.complex128]:
    """Vectorised Newton iteration; returns nan where it did not converge."""
    s = np.array(s0, dtype=complex).ravel()
    done = np.zeros(s.size, dtype=bool)
    alive = np.ones(s.size, dtype=bool)
    for _ in range(iters):
        act = np.flatnonzero(alive & ~done)
        if not act.size:
            break
        budget.spend(2 * act.size, "refining roots by Newton's method")
        x = s[act]
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            f, d = F(x), F.deriv(x)
            step = f / d
        bad = ~np.isfinite(step)
        alive[act[bad]] = False
        step = np.where(bad, 0, step)
        big = np.abs(step) > max_step
        step[big] *= max_step / np.abs(step[big])
        s[act] = x - step
        done[act] = (np.abs(step) <= 4 * _EPS * (1.0 + np.abs(x))) | (f == 0)
    # a linearly converging (multiple) root may stop short of the step test: accept
    # points with a residual at rounding level
    s_live = s[alive & ~done]
    if s_live.size:
        r = np.abs(F(s_live)) <= _STALLED * _magnitude(F, s_live)
        idx = np.flatnonzero(alive & ~done)
        done[idx[r]] = True
    return np.where(done & alive, s, np.nan)


@dataclass
class _Moments:
    """Roots inside a circle estimated from contour moments."""

    points: NDArray[np.complex128]  # roots of the moment polynomial
    count: float  # zeroth moment: the number of roots inside (not rounded)
    noise: float  # resolution limit of ``points`` set by rounding errors in F'/F


def _circle_moments(
    F: QuasiPolynomial, center: complex, radius: float, m: int, budget: _Budget, n: int = 64
) -> _Moments:
    """Estimate the ``m`` roots inside a circle from its contour moments.

    Power sums ``p_k = (1/2 pi i) oint (s - c)^k F'/F ds`` by the trapezoidal rule
    (spectrally accurate on a circle); Newton's identities turn them into the polynomial
    whose roots are the roots inside (Delves and Lyness). With ``d`` the relative rounding
    error of ``F`` on the circle, ``m`` roots are resolved only to ``radius * d^(1/m)``:
    a multiple root and a cluster below that scale are indistinguishable.
    """
    theta = 2 * np.pi * np.arange(n) / n
    w = radius * np.exp(1j * theta)
    budget.spend(2 * n, "computing contour moments")
    fw = F(center + w)
    ratio = F.deriv(center + w) / fw
    d = float(np.max(_ROUNDING * _magnitude(F, center + w) / np.abs(fw)))
    p = np.array([np.mean(ratio * w ** (k + 1)) for k in range(0, m + 1)])
    e = np.zeros(m + 1, dtype=complex)
    e[0] = 1.0
    for k in range(1, m + 1):
        e[k] = sum((-1) ** (i - 1) * e[k - i] * p[i] for i in range(1, k + 1)) / k
    coeffs = np.array([(-1) ** k * e[k] for k in range(m + 1)])
    return _Moments(center + np.roots(coeffs), float(p[0].real), 10 * radius * d ** (1.0 / m))


# ====================================================================== result types
@dataclass(frozen=True, eq=False)
class RootSet:
    """Roots of a quasi-polynomial in a rectangle, with their certificates.

    Attributes
    ----------
    roots : ndarray of complex
        Distinct roots (a cluster of roots closer than ``cluster_tol`` is one entry at
        its centroid), sorted by imaginary then real part.
    multiplicities : ndarray of int
        Multiplicity of each entry (the number of roots of its cluster).
    radii : ndarray of float
        The roots of entry ``i`` are proven to lie within ``radii[i]`` of ``roots[i]``
        (its certified box lies in that disc).
    residuals : ndarray of float
        ``|F(root)|``.
    count : int
        Certified number of roots (with multiplicity) in ``region``.
    region : tuple of float
        The rectangle searched (moved outwards from the requested one if ``shifted``).
    boxes : ndarray, shape (k, 4)
        Disjoint boxes ``(re_min, re_max, im_min, im_max)`` with certified counts.
    box_counts : ndarray of int
        The certified count of each box.
    certified : bool
        True iff every root of the region is accounted for: each listed root is proven in
        its box with its multiplicity and the box counts add up to ``count``.
    shifted : bool
        True if an edge of the requested region was moved off a root.
    evaluations : int
        Work spent (evaluations of ``F``, ``F'`` and derivative bounds).
    """

    roots: NDArray[np.complex128]
    multiplicities: NDArray[np.int64]
    radii: NDArray[np.float64]
    residuals: NDArray[np.float64]
    count: int
    region: Region
    boxes: NDArray[np.float64]
    box_counts: NDArray[np.int64]
    certified: bool
    shifted: bool
    evaluations: int

    def __len__(self) -> int:
        return int(self.roots.size)

    def __repr__(self) -> str:
        r = ", ".join(f"{v:.6g}" for v in self.region)
        return (
            f"RootSet({self.roots.size} roots, {int(np.sum(self.multiplicities))} with multiplicity, "
            f"count={self.count}, region=({r}), certified={self.certified})"
        )

    def __str__(self) -> str:
        head = f"{'#':>4}  {'Re s':>22}  {'Im s':>22}  {'mult':>4}  {'|F(s)|':>9}  {'radius':>9}"
        rows = [head, "-" * len(head)]
        for i, (z, m, res, rad) in enumerate(zip(self.roots, self.multiplicities, self.residuals, self.radii)):
            rows.append(f"{i:>4}  {z.real:>22.15g}  {z.imag:>22.15g}  {m:>4d}  {res:>9.2e}  {rad:>9.2e}")
        status = "certified" if self.certified else "NOT certified"
        rows.append(
            f"{int(np.sum(self.multiplicities))} roots with multiplicity, certified count {self.count}: {status}"
        )
        return "\n".join(rows)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {
            "roots": [[float(z.real), float(z.imag)] for z in self.roots],
            "multiplicities": [int(m) for m in self.multiplicities],
            "radii": [float(r) for r in self.radii],
            "residuals": [float(r) for r in self.residuals],
            "count": int(self.count),
            "region": list(self.region),
            "boxes": self.boxes.tolist(),
            "box_counts": [int(c) for c in self.box_counts],
            "certified": self.certified,
            "shifted": self.shifted,
            "evaluations": self.evaluations,
        }


# ====================================================================== find_roots
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

    def array(self) -> NDArray[np.float64]:
        """The accepted boxes as an ``(n, 4)`` array."""
        if self._array is None:
            self._array = np.array(self.boxes, dtype=float).reshape(-1, 4)
        return self._array


class _Finder:
    """State of one ``find_roots`` call."""

    def __init__(self, F: QuasiPolynomial, region: Region, cluster_tol: float, budget: _Budget) -> None:
        self.F = F
        self.region = region
        self.cluster_tol = cluster_tol
        self.budget = budget
        self.counter = _Counter(F, budget)
        self.found = _Found()

    # ------------------------------------------------------------ candidate boxes
    def _half_widths(self, pts: NDArray[np.complex128]) -> NDArray[np.float64]:
        """Largest half-widths of square boxes about new points, disjoint from each other
        and from the accepted boxes (Chebyshev distances)."""
        cap = np.full(pts.size, np.inf)
        if pts.size > 1:
            xy = np.column_stack([pts.real, pts.imag])
            dist, _ = cKDTree(xy).query(xy, k=2, p=np.inf)
            cap = 0.3 * dist[:, 1]
        old = self.found.array()
        if old.size:
            c = np.column_stack([(old[:, 0] + old[:, 1]) / 2, (old[:, 2] + old[:, 3]) / 2])
            r = np.maximum(old[:, 1] - old[:, 0], old[:, 3] - old[:, 2]) / 2
            k = min(8, c.shape[0])
            dist, idx = cKDTree(c).query(np.column_stack([pts.real, pts.imag]), k=k, p=np.inf)
            dist, idx = dist.reshape(pts.size, k), idx.reshape(pts.size, k)
            cap = np.minimum(cap, 0.9 * np.min(dist - r[idx], axis=1))
        return cap

    def _merge_clusters(self, pts: NDArray[np.complex128]) -> tuple[NDArray[np.complex128], NDArray[np.float64]]:
        """Merge limit points that may belong to one root or one cluster of roots.

        Newton's method stalls at a distance ``~eps^(1/m)`` from an ``m``-fold root, where
        its step ``|F/F'|`` is about ``1/m`` of that distance: each point gets the reach
        ``max(1e-4 (1 + |s|), 10 |F/F'|)``, and points closer than the sum of their reaches
        (or than ``cluster_tol``) share one box. The count of that box decides whether
        they are one multiple root or several roots (resolved by contour moments, then
        polished). Returns the group means and spreads (largest distance from the mean
        plus reach beyond ``1e-4 (1 + |s|)``), which size the boxes.
        """
        if not pts.size:
            return pts, np.zeros(0)
        self.budget.spend(2 * pts.size, "merging limit points")
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            step = np.abs(self.F(pts) / self.F.deriv(pts))
        base = _MERGE_RTOL * (1.0 + np.abs(pts))
        stalled = np.where(np.isfinite(step), np.minimum(_REACH * step, 1e3 * base), 1e3 * base)
        reach = np.maximum(base, stalled)
        parent = np.arange(pts.size)
        if pts.size > 1:
            xy = np.column_stack([pts.real, pts.imag])
            pairs = cKDTree(xy).query_pairs(max(self.cluster_tol, 2 * float(reach.max())), output_type="ndarray")
            if pairs.size:
                gap = np.abs(pts[pairs[:, 0]] - pts[pairs[:, 1]])
                pairs = pairs[gap <= np.maximum(self.cluster_tol, reach[pairs[:, 0]] + reach[pairs[:, 1]])]

            def root(i: int) -> int:
                while parent[i] != i:
                    parent[i] = parent[parent[i]]
                    i = parent[i]
                return i

            for i, j in pairs:
                parent[root(i)] = root(j)
            parent = np.array([root(i) for i in range(pts.size)])
        groups = np.unique(parent)
        means = np.array([pts[parent == g].mean() for g in groups])
        spread = np.array(
            [
                np.max(
                    np.abs(pts[parent == g] - m)
                    + np.where(stalled[parent == g] > base[parent == g], stalled[parent == g], 0.0)
                )
                for g, m in zip(groups, means)
            ]
        )
        return means, spread

    # ------------------------------------------------------------ acceptance
    def accept(self, cand: NDArray[np.complex128], owners: Sequence[Region] | None = None, depth: int = 0) -> None:
        """Certify candidate roots by counts in small disjoint boxes about them.

        ``owners`` are disjoint boxes (default: the region); a candidate is kept only
        inside one of them and its box is clipped to it, so that accepted boxes never
        straddle the cuts of the subdivision.
        """
        cand, own, spread = self._new_candidates(cand, list(owners) if owners is not None else [self.region])
        if not cand.size:
            return
        hard = self._half_widths(cand)
        # |F| ~ r^m on the box edges of an m-fold root: boxes well wider than the scatter
        soft = np.minimum(hard, np.maximum(1e-4 * (1.0 + np.abs(cand)), 10.0 * spread))
        keep = soft > 8 * _EPS * (1.0 + np.abs(cand))
        cand, own, hard, soft = cand[keep], own[keep], hard[keep], soft[keep]
        for factor in (1.0, 4.0, 16.0, 64.0, 0.3):  # an edge at rounding level of a root: resize
            if not cand.size:
                return
            h = np.minimum(soft * factor, hard)
            boxes = np.column_stack(
                [
                    np.maximum(cand.real - h, own[:, 0]),
                    np.minimum(cand.real + h, own[:, 1]),
                    np.maximum(cand.imag - h, own[:, 2]),
                    np.minimum(cand.imag + h, own[:, 3]),
                ]
            )
            counts, blocked = self.counter.count([tuple(b) for b in boxes])
            stuck = blocked.any(axis=1)
            single = ~stuck & (counts == 1)
            self._accept_simple(cand[single], h[single], boxes[single])
            for z, r, b, c in zip(
                cand[~stuck & ~single], h[~stuck & ~single], boxes[~stuck & ~single], counts[~stuck & ~single]
            ):
                self._accept_box(complex(z), float(r), tuple(b), int(c), depth)
            cand, own, hard, soft = cand[stuck], own[stuck], hard[stuck], soft[stuck]

    def _accept_simple(self, z: NDArray[np.complex128], h: NDArray[np.float64], boxes: NDArray[np.float64]) -> None:
        """Accept boxes holding one root each, polishing the candidates (which may be the
        mean of merged limit points) by Newton steps that stay in the box."""
        if not z.size:
            return
        w = _newton(self.F, z, self.budget, float(np.min(h)))
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
        zw, hw, bw = z[wide], half[wide], boxes[wide]
        inner = np.column_stack(
            [
                np.maximum(zw.real - hw, bw[:, 0]),
                np.minimum(zw.real + hw, bw[:, 1]),
                np.maximum(zw.imag - hw, bw[:, 2]),
                np.minimum(zw.imag + hw, bw[:, 3]),
            ]
        )
        counts, blocked = self.counter.count([tuple(b) for b in inner])
        good = (counts == m[wide]) & ~blocked.any(axis=1)
        out = boxes.copy()
        out[np.flatnonzero(wide)[good]] = inner[good]
        return out

    def _new_candidates(
        self, cand: NDArray[np.complex128], owners: list[Region]
    ) -> tuple[NDArray[np.complex128], NDArray[np.float64], NDArray[np.float64]]:
        """Finite candidates inside an owner box and outside accepted boxes, near ones
        merged; returned with their owner boxes and the spreads of the merge."""
        cand = cand[np.isfinite(cand)]
        old = self.found.array()
        if cand.size and old.size:
            c = np.column_stack([(old[:, 0] + old[:, 1]) / 2, (old[:, 2] + old[:, 3]) / 2])
            r = np.maximum(old[:, 1] - old[:, 0], old[:, 3] - old[:, 2]) / 2
            dist, idx = cKDTree(c).query(np.column_stack([cand.real, cand.imag]), k=1, p=np.inf)
            cand = cand[dist > r[idx]]
        cands, owns, flags = [], [], []
        for box in owners:
            x0, x1, y0, y1 = box
            inside, spread = self._merge_clusters(
                cand[(cand.real > x0) & (cand.real < x1) & (cand.imag > y0) & (cand.imag < y1)]
            )
            cands.append(inside)
            flags.append(spread)
            owns.append(np.tile(np.asarray(box, dtype=float), (inside.size, 1)))
        if not cands:
            return np.zeros(0, dtype=complex), np.zeros((0, 4)), np.zeros(0)
        return np.concatenate(cands), np.concatenate(owns).reshape(-1, 4), np.concatenate(flags)

    def _accept_box(self, z: complex, h: float, box: Region, c: int, depth: int) -> None:
        """Accept a box with a certified count ``c != 1``: a cluster, or resolve it."""
        if c <= 0:
            return
        # the roots of this box are resolved inside it, so that their boxes stay disjoint
        # from the other boxes of the batch being accepted
        mom = _circle_moments(self.F, z, 0.9 * h, c, self.budget)
        if abs(mom.count - c) > 0.25:  # roots near the circle or in the box corners
            if depth < 3:
                self.accept(_newton(self.F, self.grid_seeds(box, 9), self.budget, h), [box], depth + 1)
            return
        spread = float(np.max(np.abs(mom.points[:, None] - mom.points[None, :])))
        if spread < max(self.cluster_tol, mom.noise):
            center = complex(np.mean(mom.points))
            half = max(1e-4 * (1.0 + abs(center)), 4.0 * max(spread, mom.noise))
            tight = self._tighten(np.array([center]), np.array([c]), np.array([box], dtype=float), np.array([half]))
            self.found.add(center, c, tuple(tight[0]))
        elif depth < 3:  # separate roots: polish the moment estimates, certify them one by one
            self.accept(_newton(self.F, mom.points, self.budget, max(spread, h)), [box], depth + 1)

    # ------------------------------------------------------------ seeds
    def chain_seeds(self) -> NDArray[np.complex128]:
        """Zeros of the principal part's chains near the region (neutral ``F``).

        For incommensurate delays these are the chains of
        :meth:`DifferenceOperator.commensurate_approximation`: approximate seeds only.
        """
        if self.F.kind != "neutral":
            return np.zeros(0, dtype=complex)
        D = self.F.principal_part()
        if D.commensurate_step() is not None:
            ch = D.chains()
        else:  # the chains of a nearby commensurate operator of low degree are seeds too
            try:
                ch = D.commensurate_approximation(max_degree=_SEED_DEGREE).chains()
            except ParameterError:  # delays too close for a low degree: grid seeds only
                return np.zeros(0, dtype=complex)
        x0, x1, y0, y1 = self.region
        pad = 1.0
        pts = ch.points(y0 - pad, y1 + pad)
        pts = pts[(pts.real > x0 - pad) & (pts.real < x1 + pad)]
        multiple = [c for c in ch.chains if c.multiplicity > 1]
        if multiple:  # F splits a multiple chain: seed both sides of it
            extra = np.concatenate([c.points(y0 - pad, y1 + pad) for c in multiple])
            pts = np.concatenate([pts, extra + 1e-3, extra - 1e-3])
        return pts

    def grid_seeds(self, box: Region, n: int) -> NDArray[np.complex128]:
        """About ``n`` points of a grid with square cells in ``box``."""
        x0, x1, y0, y1 = box
        w, h = x1 - x0, y1 - y0
        nx = max(1, round(np.sqrt(n * w / h)))
        ny = max(1, round(n / nx))
        xs = x0 + (np.arange(nx) + 0.5) * w / nx
        ys = y0 + (np.arange(ny) + 0.5) * h / ny
        return (xs[None, :] + 1j * ys[:, None]).ravel()

    def seed_and_accept(self, seeds: NDArray[np.complex128], max_step: float) -> None:
        if seeds.size:
            self.accept(_newton(self.F, seeds, self.budget, max_step))

    # ------------------------------------------------------------ subdivision
    def _split(self, box: Region) -> tuple[Region, Region]:
        """Halve a box across its longer side, moving the cut off accepted boxes."""
        x0, x1, y0, y1 = box
        vertical = (x1 - x0) >= (y1 - y0)
        lo, hi = (x0, x1) if vertical else (y0, y1)
        old = self.found.array()
        cut = 0.5 * (lo + hi)
        if old.size:
            a, b = (old[:, 0], old[:, 1]) if vertical else (old[:, 2], old[:, 3])
            for frac in (0.5, 0.45, 0.55, 0.4, 0.6, 0.35, 0.65, 0.3, 0.7):
                cut = lo + frac * (hi - lo)
                if not np.any((a <= cut) & (b >= cut)):
                    break
        if vertical:
            return (x0, cut, y0, y1), (cut, x1, y0, y1)
        return (x0, x1, y0, cut), (x0, x1, cut, y1)

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
            self.accept(_newton(self.F, seeds, self.budget, size), [b for b, _ in pending])
            children: list[Region] = []
            for box, c in pending:
                u = c - self.found.inside(box)
                if u > 0 and max(box[1] - box[0], box[3] - box[2]) < self.cluster_tol:
                    self.found.add(complex(0.5 * (box[0] + box[1]), 0.5 * (box[2] + box[3])), u, box)
                elif u > 0:
                    children.extend(self._split(box))
            if not children:
                return
            counts, blocked = self.counter.count(children)
            level = []
            for k in range(0, len(children), 2):
                if blocked[k].any() or blocked[k + 1].any():  # the cut runs through a root
                    level.extend(self._recut((children[k][0], children[k + 1][1], children[k][2], children[k + 1][3])))
                else:
                    level.extend([(children[k], int(counts[k])), (children[k + 1], int(counts[k + 1]))])
        raise CertificationError(f"subdivision reached depth {max_depth} without isolating every root")

    def _recut(self, parent: Region) -> list[tuple[Region, int]]:
        """Split a box at 0.38 of its longer side (the half cut went through a root)."""
        x0, x1, y0, y1 = parent
        for frac in (0.381966, 0.618034, 0.2763, 0.7236):
            if (x1 - x0) >= (y1 - y0):
                cut = x0 + frac * (x1 - x0)
                kids = [(x0, cut, y0, y1), (cut, x1, y0, y1)]
            else:
                cut = y0 + frac * (y1 - y0)
                kids = [(x0, x1, y0, cut), (x0, x1, cut, y1)]
            counts, blocked = self.counter.count(kids)
            if not blocked.any():
                return [(kids[0], int(counts[0])), (kids[1], int(counts[1]))]
        raise CertificationError(f"could not cut the box {parent} away from its roots")


def find_roots(
    F: QuasiPolynomial,
    region: ArrayLike,
    *,
    cluster_tol: float = 1e-6,
    seeds: ArrayLike | None = None,
    method: str = "auto",
    max_evals: int = 5_000_000,
) -> RootSet:
    """All roots of ``F`` in a rectangle, certified complete.

    Parameters
    ----------
    F : QuasiPolynomial
    region : (re_min, re_max, im_min, im_max)
    cluster_tol : float, optional
        Roots closer than this are reported as one entry with their multiplicity (a
        multiple root and a tight cluster are indistinguishable in floating point).
    seeds : array_like of complex, optional
        Extra starting points for Newton's method.
    method : {"auto", "subdivision"}, optional
        ``"auto"`` seeds Newton's method from the chains and a grid first and subdivides
        only what remains; ``"subdivision"`` bisects the region from the start, with
        Newton's method in every box that holds roots not yet accepted (slower; both
        are certified).
    max_evals : int, optional
        Work bound (evaluations of ``F``, ``F'`` and derivative bounds).

    Returns
    -------
    RootSet

    Raises
    ------
    RegionError
        Empty or non-finite region.
    CertificationError
        The work bound was exhausted or a root could not be separated from a contour.

    Notes
    -----
    1. Certified count ``N`` of the region (edges through roots are moved outwards).
    2. Newton's method from the chain zeros of the principal part (neutral ``F`` with
       commensurate delays: ``s = (-ln z_i + 2 pi i m)/h``), then from a grid.
    3. Each limit point is accepted only if a certified count in a small box about it is
       positive; a box counting ``m > 1`` roots is resolved by contour moments
       (Delves-Lyness) into a cluster or separate roots.
    4. If the accepted multiplicities do not add up to ``N``, boxes are halved (edges
       shared between siblings are computed once) until every box holds exactly the
       roots accepted in it.
    """
    F = _check_function(F)
    box = _check_region(region)
    cluster_tol = positive("cluster_tol", cluster_tol)
    if method not in METHODS:
        raise ParameterError("method", f"one of {METHODS}", method)
    max_evals = positive_int("max_evals", max_evals)
    budget = _Budget(max_evals)
    finder = _Finder(F, box, cluster_tol, budget)
    total, reg, shifted = _count_with_shifts(finder.counter, box, 4)
    finder.region = reg
    if total > 0:
        extra = np.zeros(0, dtype=complex) if seeds is None else np.atleast_1d(np.asarray(seeds, dtype=complex)).ravel()
        if method == "auto":
            finder.seed_and_accept(np.concatenate([finder.chain_seeds(), extra]), 1.0)
            if finder.found.total() < total:
                n_grid = 4 * total + 16
                cell = np.sqrt((reg[1] - reg[0]) * (reg[3] - reg[2]) / n_grid)
                finder.seed_and_accept(finder.grid_seeds(reg, n_grid), 2.0 * cell)
        else:
            finder.seed_and_accept(extra, 1.0)
        if finder.found.total() != total:
            finder.subdivide(total)
    return _result(finder, total, reg, shifted)


def _result(finder: _Finder, total: int, reg: Region, shifted: bool) -> RootSet:
    found = finder.found
    z = np.array(found.centers, dtype=complex)
    m = np.array(found.mults, dtype=np.int64)
    b = found.array()
    order = np.lexsort((z.real, z.imag)) if z.size else np.zeros(0, dtype=int)
    z, m, b = z[order], m[order], b[order]
    dx = np.maximum(np.abs(b[:, 0] - z.real), np.abs(b[:, 1] - z.real)) if b.size else np.zeros(0)
    dy = np.maximum(np.abs(b[:, 2] - z.imag), np.abs(b[:, 3] - z.imag)) if b.size else np.zeros(0)
    radii = np.hypot(dx, dy)
    finder.budget.spend(z.size, "computing residuals")
    residuals = np.abs(finder.F(z)) if z.size else np.zeros(0)
    certified = int(m.sum()) == total and _disjoint(b)
    return RootSet(
        roots=z,
        multiplicities=m,
        radii=radii,
        residuals=residuals,
        count=int(total),
        region=tuple(float(v) for v in reg),  # type: ignore[arg-type]
        boxes=b,
        box_counts=m.copy(),
        certified=certified,
        shifted=shifted,
        evaluations=finder.budget.used,
    )


def _disjoint(boxes: NDArray[np.float64]) -> bool:
    """True if no two boxes overlap (the certificate adds their counts)."""
    if boxes.shape[0] < 2:
        return True
    center = np.column_stack([(boxes[:, 0] + boxes[:, 1]) / 2, (boxes[:, 2] + boxes[:, 3]) / 2])
    half = np.maximum(boxes[:, 1] - boxes[:, 0], boxes[:, 3] - boxes[:, 2]) / 2
    for i, j in cKDTree(center).query_pairs(2 * float(half.max()), p=np.inf):
        a, b = boxes[i], boxes[j]
        if a[0] < b[1] and b[0] < a[1] and a[2] < b[3] and b[2] < a[3]:
            return False
    return True
