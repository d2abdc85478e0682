"""Certified root counting and root finding for quasi-polynomials in rectangles.

Counting uses the argument principle on the boundary of a rectangle with a step rule
that makes the sum of sampled argument increments *exact*: on a contour step from
``s_i`` to ``s_i + h`` let ``M`` bound ``|F'|`` on the step (``F.deriv_bound``, closed
form). If ``M |h| / 2 < min(|F(s_i)|, |F(s_i + h)|)``, then on each half of the step
``F`` stays in a disc about an end value that excludes 0, so the change of argument over
the step is the principal value of ``arg(F(s_i + h) / F(s_i))``. Failing steps are
halved. The winding number is then an integer by construction, not a rounded integral.

Root finding combines three sources of approximations -- the chains of the principal
part for neutral quasi-polynomials (paper, Section 3, and Hale and Verduyn Lunel), a
coarse grid, and moments of boxes that still miss roots -- refines them with Newton's
method and accepts each one only when a certified count in a small box around it
confirms it. The roots are certified complete when the certified counts of these
disjoint boxes add up to the certified count of the whole region.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from ._json import json_float
from ._validate import positive, positive_int, region as _check_region
from .errors import CertificationError, ParameterError
from .quasipoly import QuasiPolynomial

__all__ = ["RootCount", "RootSet", "SpectralAbscissa", "count_roots", "find_roots", "spectral_abscissa"]

Region = tuple[float, float, float, float]

_EPS = float(np.finfo(float).eps)
# Rounding allowance on |F| at a sample, relative to the sum of the moduli of its terms.
_ROUNDING = 64 * _EPS
# A sample with |F| below this (relative to the same sum) is "on a root": shift the edge.
_NEAR_ZERO = 512 * _EPS
# Steps shorter than this (relative to 1 + |s|) are not refined further: shift the edge.
_MIN_STEP = 1e-13
# Limit points of Newton's method closer than this (relative to 1 + |s|) share one box.
_MERGE_RTOL = 1e-4
# A stalled Newton iterate is within this many steps |F/F'| of the roots it approaches
# (an m-fold root is m steps away).
_REACH = 10.0
# Newton's method stalls near an m-fold root at |F| ~ eps A; such points are limits too.
_STALLED = 1e3 * _ROUNDING
# Largest degree of the commensurate approximation whose chains seed Newton's method
# for incommensurate principal parts.
_SEED_DEGREE = 128
# Initial number of steps per edge.
_INITIAL_STEPS = 8
_SIDES = ("bottom", "right", "top", "left")
# Root-finding strategies of find_roots (see its docstring).
METHODS = ("auto", "subdivision")


# ====================================================================== counting engine
class _Budget:
    """Counts evaluations of ``F`` (and of its derivative bound) against a maximum."""

    def __init__(self, max_evals: int) -> None:
        self.max_evals = max_evals
        self.used = 0

    def spend(self, n: int, what: str) -> None:
        self.used += int(n)
        if self.used > self.max_evals:
            raise CertificationError(
                f"work bound max_evals={self.max_evals} exhausted while {what}; "
                "raise max_evals or use a smaller region"
            )


def _magnitude(F: QuasiPolynomial, s: NDArray[np.complex128]) -> NDArray[np.float64]:
    """Sum of the moduli of the monomials of ``F`` at ``s``: the scale of its rounding error."""
    out = np.zeros(s.shape)
    r = np.abs(s)
    for p, t in F.point_terms:
        out += np.polynomial.polynomial.polyval(r, np.abs(p)) * np.exp(-t * s.real)
    if F.distributed:
        # int |N| nu^k e^{-nu x} decreases in x (nu >= 0): rounding x down to 1/64 keeps an
        # upper bound and lets the samples of a contour share a few evaluations
        xs, inv = np.unique(np.floor(s.real * 64.0) / 64.0, return_inverse=True)
        for d in F.distributed:
            out += np.polynomial.polynomial.polyval(r, np.abs(d.poly)) * d.abs_moment(xs, 0)[inv.reshape(s.shape)]
    return out


@dataclass
class _Edges:
    """Result of certifying a batch of oriented segments."""

    turns: NDArray[np.float64]  # total change of argument / (2 pi) along each segment
    blocked: NDArray[np.bool_]  # True where a root lies on or too near the segment


def _first_order_ok(bound: NDArray, st: dict[str, NDArray]) -> NDArray[np.bool_]:
    """Step rule of order 1: ``M |h| / 2 < min(|F(a)|, |F(b)|)`` (minus rounding)."""
    room = np.minimum(np.abs(st["fa"]) - _ROUNDING * st["ma"], np.abs(st["fb"]) - _ROUNDING * st["mb"])
    return bound * np.abs(st["b"] - st["a"]) * 0.5 < room


def _second_order_ok(bound2: NDArray, bound: NDArray, st: dict[str, NDArray]) -> NDArray[np.bool_]:
    """Step rule of order 2, for steps near a root where order 1 needs tiny steps.

    With ``M2`` a bound of ``|F''|`` on the step, ``F(a + t) = F(a) + F'(a) t + R(t)`` with
    ``|R| <= M2 |t|^2 / 2``: ``F`` stays in the tube of that radius about the segment
    ``[F(a), F(a) + F'(a) h]``. If the segment's distance to 0 exceeds the radius, the
    tube is a convex set without 0, hence in an open half-plane, and the change of
    argument over the step is again the principal value of ``arg(F(b) / F(a))``.
    """
    h = st["b"] - st["a"]
    p0, v = st["fa"], st["dfa"] * h
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.clip(-np.real(np.conj(v) * p0) / np.abs(v) ** 2, 0.0, 1.0)
    dist = np.abs(p0 + np.nan_to_num(t) * v)
    slack = _ROUNDING * (st["ma"] + bound * np.abs(h))
    return bound2 * np.abs(h) ** 2 * 0.5 + slack < dist


def _take(st: dict[str, NDArray], mask: NDArray[np.bool_]) -> dict[str, NDArray]:
    return {k: v[mask] for k, v in st.items()}


def _wind_segments(F: QuasiPolynomial, starts: NDArray, ends: NDArray, budget: _Budget, label: Callable[[int], str]) -> _Edges:
    """Certified change of argument of ``F`` along each segment ``[starts[i], ends[i]]``.

    All segments are refined together; only the steps that fail both step rules
    (:func:`_first_order_ok`, :func:`_second_order_ok`) are halved. The order-2 rule
    (one evaluation of ``F'`` and a bound of ``|F''|``) is tried only on steps that fail
    the order-1 rule by a factor above 8, i.e. close to a root. When the work bound is
    hit, the error names the edge that holds the most unfinished steps.
    """
    n_edges = starts.size
    t = np.linspace(0.0, 1.0, _INITIAL_STEPS + 1)
    pts = starts[:, None] + (ends - starts)[:, None] * t[None, :]
    pts[:, -1] = ends  # exact corners, so that adjacent edges close the contour
    budget.spend(pts.size, "sampling contour edges")
    fv, mag = _evaluate(F, pts, label, np.repeat(np.arange(n_edges)[:, None], pts.shape[1], axis=1))
    st = {
        "a": pts[:, :-1].ravel(), "b": pts[:, 1:].ravel(),
        "fa": fv[:, :-1].ravel(), "fb": fv[:, 1:].ravel(),
        "ma": mag[:, :-1].ravel(), "mb": mag[:, 1:].ravel(),
        "dfa": np.full(n_edges * _INITIAL_STEPS, np.nan, dtype=complex),
        "owner": np.repeat(np.arange(n_edges), _INITIAL_STEPS),
    }
    turns = np.zeros(n_edges)
    blocked = np.zeros(n_edges, dtype=bool)
    near = (np.abs(st["fa"]) <= _NEAR_ZERO * st["ma"]) | (np.abs(st["fb"]) <= _NEAR_ZERO * st["mb"])
    blocked[np.unique(st["owner"][near])] = True
    dF: QuasiPolynomial | None = None
    while st["a"].size:
        st = _take(st, ~blocked[st["owner"]])
        if not st["a"].size:
            break
        what = f"bounding |F'| on the {label(int(np.bincount(st['owner']).argmax()))}"
        budget.spend(st["a"].size, what)
        bound = F.deriv_bound(st["a"], st["b"]) * (1.0 + 1e-12)
        ok = _first_order_ok(bound, st)
        room = np.minimum(np.abs(st["fa"]), np.abs(st["fb"]))
        close = ~ok & (bound * np.abs(st["b"] - st["a"]) > 8.0 * room)
        if np.any(close):
            dF = F.derivative() if dF is None else dF
            idx = np.flatnonzero(close)
            need = idx[np.isnan(st["dfa"][idx])]
            budget.spend(2 * idx.size, what.replace("|F'|", "|F''|"))
            st["dfa"][need] = F.deriv(st["a"][need])
            sub = _take(st, close)
            ok[idx] = _second_order_ok(dF.deriv_bound(sub["a"], sub["b"]) * (1.0 + 1e-12), bound[idx], sub)
        turns += np.bincount(st["owner"][ok], weights=np.angle(st["fb"][ok] / st["fa"][ok]), minlength=n_edges)
        st = _take(st, ~ok)
        if not st["a"].size:
            break
        a, b = st["a"], st["b"]
        blocked[np.unique(st["owner"][np.abs(b - a) < _MIN_STEP * (1.0 + np.abs(a))])] = True
        mid = 0.5 * (a + b)
        budget.spend(mid.size, f"refining the {label(int(np.bincount(st['owner']).argmax()))}")
        fm, mm = _evaluate(F, mid, label, st["owner"])
        blocked[np.unique(st["owner"][np.abs(fm) <= _NEAR_ZERO * mm])] = True
        st = {
            "a": np.concatenate([a, mid]), "b": np.concatenate([mid, b]),
            "fa": np.concatenate([st["fa"], fm]), "fb": np.concatenate([fm, st["fb"]]),
            "ma": np.concatenate([st["ma"], mm]), "mb": np.concatenate([mm, st["mb"]]),
            "dfa": np.concatenate([st["dfa"], np.full(mid.size, np.nan, dtype=complex)]),
            "owner": np.concatenate([st["owner"], st["owner"]]),
        }
    return _Edges(turns / (2 * np.pi), blocked)


def _evaluate(F: QuasiPolynomial, s: NDArray[np.complex128], label: Callable[[int], str], owner: NDArray) -> tuple[NDArray, NDArray]:
    """``F(s)`` and its rounding scale; an overflow is an error naming the edge."""
    with np.errstate(over="ignore", invalid="ignore"):
        fv = F(s)
        mag = _magnitude(F, s)
    bad = ~(np.isfinite(fv) & np.isfinite(mag))
    if np.any(bad):
        edge = label(int(np.ravel(owner)[np.flatnonzero(bad.ravel())[0]]))
        raise CertificationError(f"F overflows on the {edge}: move the region to the right or shrink it")
    return fv, mag


def _box_edges(box: Sequence[float]) -> list[tuple[complex, complex]]:
    x0, x1, y0, y1 = box
    return [
        (complex(x0, y0), complex(x1, y0)),
        (complex(x1, y0), complex(x1, y1)),
        (complex(x1, y1), complex(x0, y1)),
        (complex(x0, y1), complex(x0, y0)),
    ]


def _describe_edge(box: Sequence[float], side: int) -> str:
    x0, x1, y0, y1 = box
    if side in (0, 2):
        y = y0 if side == 0 else y1
        return f"{_SIDES[side]} edge (Im s = {y:.12g}, Re s in [{x0:.12g}, {x1:.12g}])"
    x = x1 if side == 1 else x0
    return f"{_SIDES[side]} edge (Re s = {x:.12g}, Im s in [{y0:.12g}, {y1:.12g}])"


class _Counter:
    """Certified counts of many boxes at once; edges shared between boxes are computed once."""

    def __init__(self, F: QuasiPolynomial, budget: _Budget) -> None:
        self.F = F
        self.budget = budget
        self.cache: dict[tuple[complex, complex], tuple[float, bool]] = {}

    def count(self, boxes: Sequence[Sequence[float]]) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
        """Counts of the boxes, and a (boxes x 4) mask of sides with a root on or near them."""
        edges = [e for box in boxes for e in _box_edges(box)]
        todo: dict[tuple[complex, complex], int] = {}
        for i, (p, q) in enumerate(edges):
            if (p, q) not in self.cache and (q, p) not in self.cache and (p, q) not in todo:
                todo[(p, q)] = i
        if todo:
            keys = list(todo)
            res = _wind_segments(
                self.F,
                np.array([k[0] for k in keys]),
                np.array([k[1] for k in keys]),
                self.budget,
                lambda j: _describe_edge(boxes[todo[keys[j]] // 4], todo[keys[j]] % 4),
            )
            for k, tr, bl in zip(keys, res.turns, res.blocked):
                self.cache[k] = (float(tr), bool(bl))
        turns = np.empty(len(edges))
        blocked = np.empty(len(edges), dtype=bool)
        for i, (p, q) in enumerate(edges):
            if (p, q) in self.cache:
                tr, bl = self.cache[(p, q)]
            else:
                tr, bl = self.cache[(q, p)]
                tr = -tr
            turns[i], blocked[i] = tr, bl
        turns = turns.reshape(-1, 4).sum(axis=1)
        blocked = blocked.reshape(-1, 4)
        counts = np.rint(turns).astype(np.int64)
        good = ~blocked.any(axis=1)
        if np.any(np.abs(turns[good] - counts[good]) > 1e-6):
            raise CertificationError("a certified winding number is not an integer: floating-point failure")
        return counts, blocked


# ====================================================================== count_roots
class RootCount(int):
    """A certified number of roots (with multiplicity) in a rectangle; behaves as an ``int``.

    Attributes
    ----------
    region : tuple of float
        The rectangle actually counted; it differs from the requested one when an edge
        passed through or too near a root and was moved outwards (``shifted``).
    shifted : bool
        True if ``region`` differs from the requested rectangle.
    evaluations : int
        Number of evaluations of ``F`` and of its derivative bound.
    """

    region: Region
    shifted: bool
    evaluations: int

    def __new__(cls, count: int, region: Region, shifted: bool, evaluations: int) -> "RootCount":
        obj = super().__new__(cls, count)
        object.__setattr__(obj, "region", tuple(float(v) for v in region))
        object.__setattr__(obj, "shifted", bool(shifted))
        object.__setattr__(obj, "evaluations", int(evaluations))
        return obj

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"RootCount is immutable (cannot set {name!r})")

    def __repr__(self) -> str:
        r = ", ".join(f"{v:.12g}" for v in self.region)
        return f"RootCount({int(self)}, region=({r}), shifted={self.shifted}, evaluations={self.evaluations})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {"count": int(self), "region": list(self.region), "shifted": self.shifted, "evaluations": self.evaluations}


def _check_function(F: Any) -> QuasiPolynomial:
    if not isinstance(F, QuasiPolynomial):
        raise ParameterError("F", "a QuasiPolynomial", type(F).__name__)
    if not F.point_terms and not F.distributed:
        raise ParameterError("F", "not identically zero (every point would be a root)", F)
    return F


def _count_with_shifts(counter: _Counter, box: Region, max_shifts: int) -> tuple[int, Region, bool]:
    """Count a box, moving blocked edges outwards (by 1e-7, 1e-6, ... of its size)."""
    reg = list(box)
    size = max(reg[1] - reg[0], reg[3] - reg[2])
    for attempt in range(max_shifts + 1):
        counts, blocked = counter.count([tuple(reg)])
        if not blocked[0].any():
            return int(counts[0]), tuple(reg), attempt > 0  # type: ignore[return-value]
        if attempt == max_shifts:
            sides = "; ".join(_describe_edge(reg, k) for k in np.flatnonzero(blocked[0]))
            raise CertificationError(
                f"a root lies on or within rounding of the {sides} after {max_shifts} shifts"
            )
        delta = size * 1e-7 * 10.0**attempt * 1.618
        for k in np.flatnonzero(blocked[0]):
            if k == 0:
                reg[2] -= delta
            elif k == 1:
                reg[1] += delta
            elif k == 2:
                reg[3] += delta
            else:
                reg[0] -= delta
    raise AssertionError("unreachable")


def count_roots(F: QuasiPolynomial, region: ArrayLike, *, max_evals: int = 2_000_000, max_shifts: int = 4) -> RootCount:
    """Certified number of roots of ``F`` (with multiplicity) in a rectangle.

    Parameters
    ----------
    F : QuasiPolynomial
    region : (re_min, re_max, im_min, im_max)
        The rectangle; an edge through or within rounding of a root is moved outwards
        and the rectangle actually counted is reported in the result.
    max_evals : int, optional
        Work bound: evaluations of ``F`` and of its derivative bound.
    max_shifts : int, optional
        How many times an edge may be moved before giving up.

    Returns
    -------
    RootCount
        An ``int`` with the attributes ``region``, ``shifted`` and ``evaluations``.

    Raises
    ------
    RegionError
        Empty or non-finite region.
    CertificationError
        The work bound was exhausted (the message names the edge), or a root stays on an
        edge after ``max_shifts`` shifts.

    Examples
    --------
    >>> from nrobust import QuasiPolynomial
    >>> F = QuasiPolynomial([[1], [-0.85], [0.1]], [0, 2, 2.1])
    >>> int(count_roots(F, (-3, 1, -0.5, 200)))
    64
    """
    F = _check_function(F)
    box = _check_region(region)
    max_evals = positive_int("max_evals", max_evals)
    max_shifts = positive_int("max_shifts", max_shifts, minimum=0)
    budget = _Budget(max_evals)
    n, reg, shifted = _count_with_shifts(_Counter(F, budget), box, max_shifts)
    return RootCount(n, reg, shifted, budget.used)


# ====================================================================== refinement
def _newton(F: QuasiPolynomial, s0: NDArray[np.complex128], budget: _Budget, max_step: float, iters: int = 60) -> NDArray[np.complex128]:
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


def _circle_moments(F: QuasiPolynomial, center: complex, radius: float, m: int, budget: _Budget, n: int = 64) -> _Moments:
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
        rows.append(f"{int(np.sum(self.multiplicities))} roots with multiplicity, certified count {self.count}: {status}")
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
            [np.max(np.abs(pts[parent == g] - m) + np.where(stalled[parent == g] > base[parent == g], stalled[parent == g], 0.0)) for g, m in zip(groups, means)]
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
            boxes = np.column_stack([
                np.maximum(cand.real - h, own[:, 0]), np.minimum(cand.real + h, own[:, 1]),
                np.maximum(cand.imag - h, own[:, 2]), np.minimum(cand.imag + h, own[:, 3]),
            ])
            counts, blocked = self.counter.count([tuple(b) for b in boxes])
            stuck = blocked.any(axis=1)
            single = ~stuck & (counts == 1)
            self._accept_simple(cand[single], h[single], boxes[single])
            for z, r, b, c in zip(cand[~stuck & ~single], h[~stuck & ~single], boxes[~stuck & ~single], counts[~stuck & ~single]):
                self._accept_box(complex(z), float(r), tuple(b), int(c), depth)
            cand, own, hard, soft = cand[stuck], own[stuck], hard[stuck], soft[stuck]

    def _accept_simple(self, z: NDArray[np.complex128], h: NDArray[np.float64], boxes: NDArray[np.float64]) -> None:
        """Accept boxes holding one root each, polishing the candidates (which may be the
        mean of merged limit points) by Newton steps that stay in the box."""
        if not z.size:
            return
        w = _newton(self.F, z, self.budget, float(np.min(h)))
        inside = np.isfinite(w) & (boxes[:, 0] < w.real) & (w.real < boxes[:, 1]) & (boxes[:, 2] < w.imag) & (w.imag < boxes[:, 3])
        z = np.where(inside, w, z)
        boxes = self._tighten(z, np.ones(z.size, dtype=np.int64), boxes, 1e-4 * (1.0 + np.abs(z)))
        for zi, box in zip(z, boxes):
            self.found.add(complex(zi), 1, tuple(box))

    def _tighten(self, z: NDArray[np.complex128], m: NDArray[np.int64], boxes: NDArray[np.float64], half: NDArray[np.float64]) -> NDArray[np.float64]:
        """Replace boxes by sub-boxes of half-width ``half`` about ``z`` where those still
        count ``m`` roots (a smaller certified enclosure); keep the others."""
        wide = np.maximum(boxes[:, 1] - boxes[:, 0], boxes[:, 3] - boxes[:, 2]) > 4.0 * half
        if not wide.any():
            return boxes
        zw, hw, bw = z[wide], half[wide], boxes[wide]
        inner = np.column_stack([
            np.maximum(zw.real - hw, bw[:, 0]), np.minimum(zw.real + hw, bw[:, 1]),
            np.maximum(zw.imag - hw, bw[:, 2]), np.minimum(zw.imag + hw, bw[:, 3]),
        ])
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
            inside, spread = self._merge_clusters(cand[(cand.real > x0) & (cand.real < x1) & (cand.imag > y0) & (cand.imag < y1)])
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
        nx = max(1, int(round(np.sqrt(n * w / h))))
        ny = max(1, int(round(n / nx)))
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


# ====================================================================== spectral abscissa
@dataclass(frozen=True)
class SpectralAbscissa:
    """The rightmost root of a quasi-polynomial and how far the result is certified.

    Attributes
    ----------
    value : float
        ``sup {Re s : F(s) = 0}``: the real part of ``root``, or ``chain_value`` when the
        chains of a neutral ``F`` reach further right (then the supremum is approached
        only as ``|Im s| -> infinity``); ``-inf`` if ``F`` has no root with
        ``Re s >= region[0]``.
    root : complex or None
        The rightmost root found in ``region``.
    approached_at_infinity : bool
        True if ``value`` is the chain value ``c_D`` of the principal part and no root in
        ``region`` attains it (Hale and Verduyn Lunel: the high-frequency roots of a
        neutral ``F`` converge to the zero chains of its difference operator).
    chain_value : float
        Spectral bound ``c_D`` of the principal part (upper end of its bracket for
        incommensurate delays); ``-inf`` for retarded ``F``.
    upper_bound : float
        Certified: ``F`` has no root with ``Re s > upper_bound`` anywhere.
    certified : bool
        True if every root of ``region`` was found (certified count), so no root of
        ``region`` lies to the right of ``root``. Outside ``region`` only ``upper_bound``
        is certified: for neutral ``F`` the chain roots above ``region`` have real parts
        in ``[c_D - o(1), upper_bound]``.
    region : tuple of float
        The rectangle searched.
    strong_bound : float
        ``C_D`` of the principal part: the supremum of the chain abscissa over small
        perturbations of the delays (equal to ``chain_value`` for rationally independent
        delays; ``-inf`` for retarded ``F``). A loop is robust to small delays only if
        ``C_D < 0`` (Hale and Verduyn Lunel, 2002).
    """

    value: float
    root: complex | None
    approached_at_infinity: bool
    chain_value: float
    upper_bound: float
    certified: bool
    region: Region
    strong_bound: float = -np.inf

    def __repr__(self) -> str:
        root = "None" if self.root is None else f"{self.root.real:.12g}{self.root.imag:+.12g}j"
        tail = ", approached as Im s -> infinity" if self.approached_at_infinity else ""
        return (
            f"SpectralAbscissa(value={self.value:.12g}, root={root}{tail}, chain_value={self.chain_value:.6g}, "
            f"strong_bound={self.strong_bound:.6g}, upper_bound={self.upper_bound:.6g}, certified={self.certified})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {
            "value": json_float(self.value),
            "root": None if self.root is None else [self.root.real, self.root.imag],
            "approached_at_infinity": self.approached_at_infinity,
            "chain_value": json_float(self.chain_value),
            "upper_bound": json_float(self.upper_bound),
            "certified": self.certified,
            "region": list(self.region),
            "strong_bound": json_float(self.strong_bound),
        }


# Largest |s| tried by the root-free radius; beyond it the search is not certified.
_MAX_RADIUS = 1e6


def _root_free_radius(F: QuasiPolynomial, x: float) -> float | None:
    """Smallest ``R = 2^j`` with no root of ``F`` in ``{Re s >= x, |s| >= R}``, or None.

    With ``n`` the degree, ``p_0`` the polynomial of the smallest delay ``tau_0`` and
    ``|s| = R``, ``Re s >= x``: ``|p_0(s) e^{-tau_0 s}| >= (|c_0n| - sum_{j<n} |c_0j|
    R^(j-n)) R^n e^{-tau_0 Re s}`` exceeds the sum of the moduli of the other terms when
    ``|c_0n| - sum_{j<n} |c_0j| R^(j-n) > sum_{k>=1} sum_j |c_kj| R^(j-n)
    e^{-(tau_k - tau_0) x} + sum_dist sum_j |q_j| R^(j-n) e^{tau_0 x} B(x, R)`` with
    ``B = min(int |N| e^{-nu x}, V(x) / R)`` (``V``: the integration-by-parts bound
    ``DistributedDelay.variation_bound``). Both sides are monotone in ``R`` and ``x``
    (all delays are ``>= tau_0``), so the inequality at ``(R, x)`` holds on the whole set.
    """
    n = F.degree
    (p0, tau0), rest = F.point_terms[0], F.point_terms[1:]
    R = 2.0 ** np.arange(0, int(np.log2(_MAX_RADIUS)) + 1)
    powers = R[:, None] ** (np.arange(n + 1)[None, :] - n)  # R^(j - n)
    lhs = abs(p0[n]) - powers[:, :n] @ np.abs(p0[:n]) if p0.size == n + 1 else np.full(R.size, -np.inf)
    rhs = np.zeros(R.size)
    for p, t in rest:
        rhs += powers[:, : p.size] @ np.abs(p) * np.exp(-(t - tau0) * x)
    for d in F.distributed:
        xa = np.array([x])
        dist = np.full(R.size, float(d.abs_moment(xa, 0)[0]))
        if d.moment == 0:  # integration by parts: |int N e^{-nu s}| <= V(Re s) / |s|
            dist = np.minimum(dist, float(d.variation_bound(xa)[0]) / R)
        rhs += powers[:, : d.poly.size] @ np.abs(d.poly) * dist * np.exp(tau0 * x)
    ok = lhs > rhs * (1 + 1e-12)
    return float(R[np.argmax(ok)]) if ok.any() else None


def _has_real_coefficients(F: QuasiPolynomial) -> bool:
    parts = [p for p, _ in F.point_terms] + [a for d in F.distributed for a in (d.values, d.poly)]
    return not any(np.iscomplexobj(a) and np.any(np.asarray(a).imag != 0) for a in parts)


def spectral_abscissa(
    F: QuasiPolynomial,
    region: ArrayLike | None = None,
    *,
    im_max: float | None = None,
    cluster_tol: float = 1e-6,
    max_evals: int = 5_000_000,
) -> SpectralAbscissa:
    """The supremum of the real parts of the roots of ``F``, with its rightmost root.

    Parameters
    ----------
    F : QuasiPolynomial
        Retarded or neutral (an advanced ``F`` has roots with arbitrarily large real part).
    region : (re_min, re_max, im_min, im_max), optional
        Search only this rectangle. By default the search region is built so that the
        answer is certified: a half-plane ``Re s >= x`` is root-free outside a disc
        (:func:`_root_free_radius`), the rest is counted and searched.
    im_max : float, optional
        Height of the band searched near the chains of a neutral ``F``.
    cluster_tol, max_evals
        As in :func:`find_roots`.

    Returns
    -------
    SpectralAbscissa

    Notes
    -----
    For neutral ``F`` with principal part ``D``, no root lies in ``Re s > C_D + m`` outside
    a disc, so the roots there are found exactly; below, the high-frequency roots
    approach the chains of ``D`` whose abscissa is ``c_D`` (Hale and Verduyn Lunel), so
    the supremum is ``max(c_D, real part of the rightmost root found)`` and may be
    approached only as ``|Im s| -> infinity`` (``approached_at_infinity``).
    """
    F = _check_function(F)
    if F.kind == "advanced":
        raise ParameterError("F", "retarded or neutral (an advanced quasi-polynomial has unbounded root real parts)", F)
    D = F.principal_part()
    chain_value = D.spectral_bound().upper
    c_strong = D.strong_spectral_bound()
    if region is not None:
        roots = find_roots(F, region, cluster_tol=cluster_tol, max_evals=max_evals)
        result = _abscissa_from(roots, chain_value, np.inf, roots.certified)
    elif np.isfinite(c_strong):
        margin = 0.1 * (1.0 + abs(c_strong))
        x_min, radius = _right_half_plane(F, c_strong + margin, margin)
        real = _has_real_coefficients(F)
        result = _neutral_abscissa(F, D, x_min, radius, real, im_max, chain_value, cluster_tol, max_evals)
    else:
        x_right, radius = _right_half_plane(F, 0.0, 1.0)
        result = _retarded_abscissa(F, x_right, radius, _has_real_coefficients(F), cluster_tol, max_evals)
    return replace(result, strong_bound=float(c_strong))


def _right_half_plane(F: QuasiPolynomial, x0: float, step: float) -> tuple[float, float]:
    """``(x, R)``: no root with ``Re s >= x`` and ``|s| >= R``, for the first
    ``x = x0 + step (2^j - 1)`` where :func:`_root_free_radius` finds one."""
    for j in range(40):
        x = x0 + step * (2.0**j - 1.0)
        R = _root_free_radius(F, x)
        if R is not None:
            return x, R
    raise CertificationError("no root-free right half-plane found: the quasi-polynomial is not retarded or neutral")


def _band(y: float, real: bool) -> tuple[float, float]:
    return (-0.25 if real else -y), y


def _neutral_abscissa(
    F: QuasiPolynomial, D: Any, x_min: float, radius: float, real: bool,
    im_max: float | None, chain_value: float, cluster_tol: float, max_evals: int,
) -> SpectralAbscissa:
    """Exhaustive search of ``Re s >= x_min`` (inside the disc of ``radius``), then of a
    band below ``x_min`` near the chains."""
    right = (x_min, max(x_min, radius) + 1.0, *_band(radius, real))
    roots = find_roots(F, right, cluster_tol=cluster_tol, max_evals=max_evals)
    if roots.count > 0:
        return _abscissa_from(roots, chain_value, x_min, roots.certified, upper_from_roots=roots.certified)
    chains = D.chains()
    period = chains.chains[0].spacing if chains.commensurate and chains.chains else 2 * np.pi / max(F.max_delay, 1e-3)
    height = float(im_max) if im_max is not None else max(radius, 100.0, 2 * period)
    low = (min(chain_value, x_min) - 0.5, x_min, *_band(height, real))
    band = find_roots(F, low, cluster_tol=cluster_tol, max_evals=max_evals)
    return _abscissa_from(band, chain_value, x_min, band.certified and roots.certified)


def _retarded_abscissa(
    F: QuasiPolynomial, x_right: float, radius: float, real: bool, cluster_tol: float, max_evals: int,
) -> SpectralAbscissa:
    """Widen a window ``[x_right - w, x_max]`` leftwards (``w = 0, 1, 2, 4, ...``) until it
    holds a root; every root with ``Re s`` in the window is found, so the rightmost is."""
    x_max = max(x_right, radius) + 1.0
    searched: Region | None = None
    for width in [0.0] + [2.0**j for j in range(12)]:
        x_min = x_right - width
        y = _root_free_radius(F, x_min)
        if y is None or y > _MAX_RADIUS:
            break
        box = (x_min, x_max, *_band(max(y, radius), real))
        count = count_roots(F, box, max_evals=max_evals)
        searched = count.region
        if count > 0:
            roots = find_roots(F, box, cluster_tol=cluster_tol, max_evals=max_evals)
            return _abscissa_from(roots, -np.inf, x_max, roots.certified, upper_from_roots=roots.certified)
    if searched is None:
        raise CertificationError(f"no root-free far field for Re s >= {x_right:.6g}: cannot bound the roots")
    # no root with Re s >= searched[0] at all
    return SpectralAbscissa(-np.inf, None, False, -np.inf, searched[0], True, searched)


def _abscissa_from(
    roots: RootSet, chain_value: float, upper: float, certified: bool, upper_from_roots: bool = False
) -> SpectralAbscissa:
    if len(roots):
        i = int(np.argmax(roots.roots.real))
        root: complex | None = complex(roots.roots[i])
        best = root.real + (roots.radii[i] if upper_from_roots else 0.0)
    else:
        root, best = None, -np.inf
    found = -np.inf if root is None else root.real
    at_inf = bool(np.isfinite(chain_value) and chain_value > found + 1e-12 * (1 + abs(chain_value)))
    value = chain_value if at_inf else found
    upper_bound = best if upper_from_roots else max(upper, value)
    return SpectralAbscissa(float(value), root, at_inf, float(chain_value), float(upper_bound), bool(certified), roots.region)
