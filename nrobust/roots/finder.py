"""Certified root finding for quasi-polynomials in rectangles: :func:`find_roots` and its result.

The search (:class:`nrobust.roots.search.Finder`) combines three sources of
approximations -- the chains of the principal part for neutral quasi-polynomials (paper,
Section 3, and Hale and Verduyn Lunel), a coarse grid, and moments of boxes that still
miss roots -- refines them with Newton's method and accepts each one only when a
certified count in a small box around it confirms it. The roots are certified complete
when the certified counts of these disjoint boxes add up to the certified count of the
whole region; with ``rigorous=True`` the result is proven in ball arithmetic
(:func:`prove`: Krawczyk's test and ball winding numbers).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._json import fields_dict
from .._validate import number_array, positive, positive_int
from .._validate import region as _check_region
from ..balls import BallFunction, ball_function, krawczyk, require_flint, working_precision
from ..errors import CertificationError, ParameterError
from ..qpmatrix import CharacteristicFunction
from ..quasipoly import QuasiPolynomial
from ._common import Budget, check_function, check_rigorous
from .search import Finder, centers, kdtree
from .winding import METHODS, Region, ball_count_with_shifts, ball_winding, count_with_shifts

__all__ = ["RootSet", "find_roots", "separate_clusters"]


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
        Work spent (evaluations of ``F``, ``F'`` and derivative bounds, and ball enclosures).
    rigorous : bool
        True if ``count``, ``boxes`` and ``box_counts`` are proven in ball arithmetic
        (``find_roots(..., rigorous=True)``); False for the floating-point certification.
    proofs : tuple of str
        With ``rigorous``, how each entry is proven: ``"krawczyk"`` (a simple root, alone
        in its box: Krawczyk's test) or ``"winding"`` (the proven winding number of its box).
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
    rigorous: bool = False
    proofs: tuple[str, ...] = ()

    def __len__(self) -> int:
        return int(self.roots.size)

    def __repr__(self) -> str:
        r = ", ".join(f"{v:.6g}" for v in self.region)
        return (
            f"RootSet({self.roots.size} roots, {int(np.sum(self.multiplicities))} with multiplicity, "
            f"count={self.count}, region=({r}), certified={self.certified}"
            + (", rigorous=True)" if self.rigorous else ")")
        )

    def __str__(self) -> str:
        head = f"{'#':>4}  {'Re s':>22}  {'Im s':>22}  {'mult':>4}  {'|F(s)|':>9}  {'radius':>9}"
        rows = [head, "-" * len(head)]
        for i, (z, m, res, rad) in enumerate(zip(self.roots, self.multiplicities, self.residuals, self.radii)):
            rows.append(f"{i:>4}  {z.real:>22.15g}  {z.imag:>22.15g}  {m:>4d}  {res:>9.2e}  {rad:>9.2e}")
        status = "certified" if self.certified else "NOT certified"
        status += " (proven in ball arithmetic)" if self.rigorous else ""
        rows.append(
            f"{int(np.sum(self.multiplicities))} roots with multiplicity, certified count {self.count}: {status}"
        )
        return "\n".join(rows)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (roots as ``[real, imag]`` pairs)."""
        return fields_dict(self)


# ====================================================================== proofs in ball arithmetic
# Half-widths (relative to 1 + |z|) of the squares tried by the Krawczyk test, smallest first.
_KRAWCZYK_WIDTHS = (1e-11, 1e-9, 1e-7, 1e-5)


def _krawczyk(
    balls: Any, z: complex, box: NDArray[np.float64], budget: Budget, widths: tuple[float, ...] = _KRAWCZYK_WIDTHS
) -> tuple[float, ...] | None:
    """A rectangle about ``z`` inside ``box`` proven to hold exactly one root, simple; or None.

    Squares of growing half-width (``widths``, default :data:`_KRAWCZYK_WIDTHS`), clipped to
    ``box``, are tried by Krawczyk's test (:func:`nrobust.balls.krawczyk`) about their centres,
    in the precision of ``balls``.
    """
    flint = require_flint()
    scale = 1.0 + abs(z)
    for w in widths:
        x0, x1 = max(z.real - w * scale, box[0]), min(z.real + w * scale, box[1])
        y0, y1 = max(z.imag - w * scale, box[2]), min(z.imag + w * scale, box[3])
        if not (x0 < x1 and y0 < y1):
            return None
        budget.spend(2, "proving a root by Krawczyk's test")
        c = flint.acb(0.5 * (x0 + x1), 0.5 * (y0 + y1))
        if krawczyk((x0, x1, y0, y1), c, balls(c), lambda X: balls(X, 1), prec=balls.prec):
            return (x0, x1, y0, y1)
    return None


def prove(F: QuasiPolynomial, found: RootSet, balls: Any, budget: Budget, max_shifts: int) -> RootSet:
    """``found`` (a floating-point result) proven in ball arithmetic, or CertificationError.

    The count of the region is proven by :func:`ball_winding` (its edges moved outwards
    when a root is too close, as in floating point); each simple root by Krawczyk's test in
    a rectangle inside its box (exactly one zero there), falling back to the proven
    winding number of its box; each cluster by the proven winding number of its box. The
    boxes are disjoint and inside the region, so when their proven counts add up to the
    proven count of the region, every root is accounted for.
    """
    if not found.certified:
        raise CertificationError(
            "the floating-point search did not account for every root, so there is nothing to prove; "
            "raise max_evals or use a smaller region"
        )
    total, reg, shifted = ball_count_with_shifts(balls, found.region, max_shifts, budget)
    if reg != found.region or total != found.count:
        raise CertificationError(
            f"ball arithmetic counts {total} roots in {reg}, the floating-point search {found.count} in "
            f"{found.region}: a root lies within rounding of the region's edge; move the edge"
        )
    boxes = found.boxes.copy()
    proofs = []
    for i, (z, m) in enumerate(zip(found.roots, found.multiplicities)):
        proven = _krawczyk(balls, complex(z), found.boxes[i], budget) if m == 1 else None
        if proven is not None:
            boxes[i] = proven
            proofs.append("krawczyk")
            continue
        n, _ = ball_winding(balls, tuple(float(v) for v in found.boxes[i]), budget)
        if n != m:
            what = "cannot exclude 0 on its edges" if n is None else f"counts {n} roots"
            raise CertificationError(
                f"ball arithmetic {what} in the box {tuple(float(v) for v in found.boxes[i])} of the root {complex(z)} "
                f"(multiplicity {int(m)} in floating point): roots closer than rounding; try a higher prec"
            )
        proofs.append("winding")
    inside = np.all(
        (boxes[:, 0] >= reg[0]) & (boxes[:, 1] <= reg[1]) & (boxes[:, 2] >= reg[2]) & (boxes[:, 3] <= reg[3])
    )
    if not (inside and _disjoint(boxes) and int(found.multiplicities.sum()) == total):
        raise CertificationError("the proven boxes do not tile the roots of the region (overlap or outside it)")
    z = found.roots
    dx = np.maximum(np.abs(boxes[:, 0] - z.real), np.abs(boxes[:, 1] - z.real))
    dy = np.maximum(np.abs(boxes[:, 2] - z.imag), np.abs(boxes[:, 3] - z.imag))
    return dataclasses.replace(
        found,
        radii=np.hypot(dx, dy),
        boxes=boxes,
        box_counts=found.multiplicities.copy(),
        shifted=shifted or found.shifted,
        evaluations=found.evaluations + budget.used,
        rigorous=True,
        proofs=tuple(proofs),
    )


# Precisions (bits) at which a cluster of roots is separated, and the iterations of each attempt.
_SEPARATION_PRECISIONS = (128, 256, 512)
_ABERTH_ITERATIONS = 80
# Half-widths (relative to 1 + |z|) of the Krawczyk squares of the roots of a cluster: the roots
# are double-rounded (a few ulps off), and the ball enclosure of F' on the square must stay
# small against |F'|, which is small in a cluster.
_CLUSTER_WIDTHS = (1e-14, 1e-13, 1e-12, 1e-11, 1e-9)


def separate_clusters(F: QuasiPolynomial, found: RootSet, budget: Budget, right_of: float = -np.inf) -> RootSet:
    """``found`` with each cluster entry reaching right of ``right_of`` split into its proven simple roots.

    Floating point cannot tell ``m`` roots closer than about ``eps^(1/m)`` (relative) from one
    root of multiplicity ``m``: the stored, rounded coefficients of a quasi-polynomial built
    to have a multiple root split it into such a cluster, and its centroid is not the
    rightmost root. In ball arithmetic of growing precision (:data:`_SEPARATION_PRECISIONS`)
    Aberth's simultaneous iteration from ``m`` points about the centroid approximates the
    roots, and each is proven by Krawczyk's test (:func:`_krawczyk`) in a rectangle inside
    the entry's box. When all ``m`` rectangles are proven and disjoint, they hold the ``m``
    roots the box is counted to hold, so the entry is replaced by ``m`` simple roots with
    those rectangles as their boxes (``proofs`` ``"krawczyk"`` when ``found`` is rigorous).
    An entry that does not separate (a multiple root, or a cluster tighter than the
    precisions resolve) is kept; without python-flint ``found`` is returned as it is.

    Parameters
    ----------
    F : QuasiPolynomial
    found : RootSet
        A certified result (floating point or proven).
    budget : Budget
        Work bound of the ball evaluations.
    right_of : float, optional
        Only clusters whose box reaches right of this abscissa are separated.

    Returns
    -------
    RootSet
    """
    if not len(found):
        return found
    pick = np.flatnonzero((found.multiplicities > 1) & (found.boxes[:, 1] >= right_of))
    if not pick.size:
        return found
    try:
        require_flint()
    except ImportError:
        return found
    roots, mults, boxes = list(found.roots), list(found.multiplicities), list(found.boxes)
    proofs = list(found.proofs) if found.rigorous else [""] * len(found)
    for i in sorted(pick, reverse=True):
        parts = _separate(F, complex(found.roots[i]), int(found.multiplicities[i]), found.boxes[i], budget)
        if parts is None:
            continue
        roots[i : i + 1] = [z for z, _ in parts]
        mults[i : i + 1] = [1] * len(parts)
        boxes[i : i + 1] = [np.array(b) for _, b in parts]
        proofs[i : i + 1] = ["krawczyk"] * len(parts)
    z, m, b = np.array(roots, dtype=complex), np.array(mults, dtype=np.int64), np.array(boxes, dtype=float)
    order = np.lexsort((z.real, z.imag))
    z, m, b = z[order], m[order], b[order]
    dx = np.maximum(np.abs(b[:, 0] - z.real), np.abs(b[:, 1] - z.real))
    dy = np.maximum(np.abs(b[:, 2] - z.imag), np.abs(b[:, 3] - z.imag))
    budget.spend(z.size, "computing residuals")
    return dataclasses.replace(
        found,
        roots=z,
        multiplicities=m,
        radii=np.hypot(dx, dy),
        residuals=np.abs(F(z)),
        boxes=b,
        box_counts=m.copy(),
        evaluations=found.evaluations + budget.used,
        proofs=tuple(proofs[k] for k in order) if found.rigorous else (),
    )


def _separate(
    F: QuasiPolynomial, c: complex, m: int, box: NDArray[np.float64], budget: Budget
) -> list[tuple[complex, tuple[float, ...]]] | None:
    """The ``m`` roots of ``F`` in ``box`` (a cluster about ``c``), each with its Krawczyk rectangle; or None."""
    for prec in _SEPARATION_PRECISIONS:
        balls = ball_function(F, prec)
        approx = _aberth(balls, c, m, box, budget)
        if approx is None:
            continue
        proven = [_krawczyk(balls, z, box, budget, _CLUSTER_WIDTHS) for z in approx]
        if all(p is not None for p in proven) and _disjoint(np.array(proven, dtype=float)):
            return [(z, p) for z, p in zip(approx, proven) if p is not None]
    return None


def _aberth(balls: Any, c: complex, m: int, box: NDArray[np.float64], budget: Budget) -> list[complex] | None:
    """``m`` distinct zeros of ``F`` in ``box`` near ``c`` by Aberth's iteration at ``balls.prec`` bits, or None.

    The starting points lie on a circle about ``c`` of radius ``(|F(c)| m! / |F^(m)(c)|)^(1/m)``
    (the geometric mean distance of ``m`` roots about their centroid ``c``); the iteration
    ``z_i <- z_i - 1 / (F'(z_i) / F(z_i) - sum_{j != i} 1 / (z_i - z_j))`` uses the midpoints
    of the ball values.
    """
    scale = 1.0 + abs(c)
    half = 0.5 * min(box[1] - box[0], box[3] - box[2])
    with working_precision(balls.prec) as flint:

        def mid(x: Any) -> Any:
            return flint.acb(x.real.mid(), x.imag.mid())

        center = flint.acb(c.real, c.imag)
        radius = 0.25 * half
        if m <= balls.max_derivative:
            budget.spend(2, "separating a cluster of roots")
            f0, fm = abs(complex(balls(center).mid())), abs(complex(balls(center, m).mid()))
            if fm > 0:
                radius = min(radius, (f0 * math.factorial(m) / fm) ** (1.0 / m))
        if not radius > 0:  # F(c) = 0 to the precision: a multiple root at c
            return None
        z = [center + radius * flint.acb(0, 0.4 + 2 * np.pi * k / m).exp() for k in range(m)]
        tol = 2.0 ** (-0.45 * balls.prec) * scale
        for _ in range(_ABERTH_ITERATIONS):
            budget.spend(2 * m, "separating a cluster of roots")
            step = 0.0
            for i in range(m):
                f, d = mid(balls(z[i])), mid(balls(z[i], 1))
                if f == 0:
                    continue
                w = 1 / (d / f - sum((1 / (z[i] - z[j]) for j in range(m) if j != i), flint.acb(0)))
                z[i] = mid(z[i] - w)
                step = max(step, abs(complex(w.mid())))
            if step < tol:
                break
        else:
            return None
        out = [complex(float(x.real.mid()), float(x.imag.mid())) for x in z]
    pts = np.array(out)
    inside = (pts.real > box[0]) & (pts.real < box[1]) & (pts.imag > box[2]) & (pts.imag < box[3])
    gaps = np.abs(pts[:, None] - pts[None, :])
    np.fill_diagonal(gaps, np.inf)
    if not (np.all(inside) and float(gaps.min()) > 1e-12 * scale):
        return None
    return out


def find_roots(
    F: QuasiPolynomial | CharacteristicFunction,
    region: ArrayLike,
    *,
    cluster_tol: float = 1e-6,
    seeds: ArrayLike | None = None,
    method: str = "auto",
    max_evals: int = 5_000_000,
    rigorous: bool = False,
    prec: int = 53,
    balls: BallFunction | None = None,
) -> RootSet:
    """All roots of ``F`` in a rectangle, certified complete.

    Parameters
    ----------
    F : QuasiPolynomial or QuasiPolynomialMatrix
        The function (a matrix stands for its determinant, never expanded).
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
        Work bound (evaluations of ``F``, ``F'`` and derivative bounds); with
        ``rigorous=True`` the proof has a work bound of its own of the same size.
    rigorous : bool, optional
        Prove the result in ball arithmetic (python-flint, ``pip install nrobust[rigorous]``):
        the count of the region by a proven winding number, each simple root by
        Krawczyk's test (existence and uniqueness in a small rectangle), each cluster by
        the proven winding number of its box (``RootSet.proofs``). Matrices too (ball determinant).
    prec : int, optional
        Working precision in bits of the ball arithmetic.
    balls : BallFunction, optional
        With ``rigorous``, the enclosure the proof is made with (default
        ``ball_function(F, prec)``): the search runs on ``F`` and the result is proven for the
        function ``balls`` encloses, which ``F`` approximates (e.g. the loop of a plant whose
        transport time is not a double,
        :func:`~nrobust.hyperbolic.loops.given_plant.given_plant_balls`).

    Returns
    -------
    RootSet

    Raises
    ------
    RegionError
        Empty or non-finite region.
    CertificationError
        The work bound was exhausted or a root could not be separated from a contour;
        with ``rigorous=True`` also when ball arithmetic cannot confirm a count (roots
        within rounding of an edge, or closer together than its precision resolves).
    ImportError
        ``rigorous=True`` without python-flint.

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
    F = check_function(F)
    box = _check_region(region)
    cluster_tol = positive("cluster_tol", cluster_tol)
    if method not in METHODS:
        raise ParameterError("method", f"one of {METHODS}", method)
    max_evals = positive_int("max_evals", max_evals)
    extra = (
        np.zeros(0, dtype=complex)
        if seeds is None
        else number_array("seeds", seeds, ndim=None, min_size=0).astype(complex).ravel()
    )
    if balls is not None and not isinstance(balls, BallFunction):
        raise ParameterError("balls", "a BallFunction (nrobust.balls) or None", type(balls).__name__)
    rigorous = check_rigorous(F, rigorous)
    finder = Finder(F, box, cluster_tol, Budget(max_evals))
    with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
        early = None
        if method == "auto" and extra.size:  # seeds given: the boxes about their limits counted with the region
            early = finder.limit_points(np.concatenate([finder.chain_seeds(), extra]), 1.0)
            finder.counter.prefetch = finder.first_boxes(early)
            finder.counter.approx = early[np.isfinite(early)]
        total, reg, shifted = count_with_shifts(finder.counter, box, 4)
        found = find_counted(finder, total, reg, shifted, extra, method, early)
    if not rigorous:
        return found
    return prove(F, found, ball_function(F, prec) if balls is None else balls, Budget(max_evals), 4)


def find_counted(
    finder: Finder,
    total: int,
    reg: Region,
    shifted: bool,
    extra: NDArray[np.complex128],
    method: str = "auto",
    limit_points: NDArray[np.complex128] | None = None,
) -> RootSet:
    """Steps 2-4 of :func:`find_roots` on a region ``reg`` already counted (``total`` roots).

    ``limit_points``: those of Newton's method from the chain seeds and ``extra``, when already
    found (:meth:`Finder.limit_points`).
    """
    finder.region = reg
    if total > 0:
        if method == "auto":
            if limit_points is None:
                finder.seed_and_accept(np.concatenate([finder.chain_seeds(), extra]), 1.0)
            elif limit_points.size:
                finder.accept(limit_points)
            if finder.found.total() < total:
                n_grid = 4 * total + 16
                cell = np.sqrt((reg[1] - reg[0]) * (reg[3] - reg[2]) / n_grid)
                finder.seed_and_accept(finder.grid_seeds(reg, n_grid), 2.0 * cell)
        else:
            finder.seed_and_accept(extra, 1.0)
        if finder.found.total() != total:
            finder.subdivide(total)
    return _result(finder, total, reg, shifted)


def _result(finder: Finder, total: int, reg: Region, shifted: bool) -> RootSet:
    found = finder.found
    z = np.array(found.centers, dtype=complex)
    m = np.array(found.mults, dtype=np.int64)
    b = found.array()
    finder.budget.spend(z.size, "computing residuals")
    # |F| at the roots in the order found: often the points of the last evaluation, which F keeps
    residuals = np.abs(finder.F(z)) if z.size else np.zeros(0)
    order = np.lexsort((z.real, z.imag)) if z.size else np.zeros(0, dtype=int)
    z, m, b, residuals = z[order], m[order], b[order], residuals[order]
    dx = np.maximum(np.abs(b[:, 0] - z.real), np.abs(b[:, 1] - z.real)) if b.size else np.zeros(0)
    dy = np.maximum(np.abs(b[:, 2] - z.imag), np.abs(b[:, 3] - z.imag)) if b.size else np.zeros(0)
    radii = np.hypot(dx, dy)
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


# Up to this many boxes, :func:`_disjoint` compares every pair directly (no neighbour search).
_ALL_BOXES = 64


def _disjoint(boxes: NDArray[np.float64]) -> bool:
    """True if no two boxes overlap (the certificate adds their counts)."""
    if boxes.shape[0] < 2:
        return True
    if boxes.shape[0] <= _ALL_BOXES:  # every pair at once: fewer operations than the neighbour search
        x0, x1, y0, y1 = boxes.T
        meet = (x0[:, None] < x1) & (x0 < x1[:, None]) & (y0[:, None] < y1) & (y0 < y1[:, None])
        np.fill_diagonal(meet, False)
        return not bool(meet.any())
    center, half = centers(boxes)
    for i, j in kdtree(center).query_pairs(2 * float(half.max()), p=np.inf):
        a, b = boxes[i], boxes[j]
        if a[0] < b[1] and b[0] < a[1] and a[2] < b[3] and b[2] < a[3]:
            return False
    return True
