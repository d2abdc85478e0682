"""Certified root counts of quasi-polynomials in rectangles: the argument principle.

Counting uses the argument principle on the boundary of a rectangle with a step rule
that makes the sum of sampled argument increments *exact*: on a contour step from
``s_i`` to ``s_i + h`` let ``M`` bound ``|F'|`` on the step (``F.deriv_bound``, closed
form). If ``M |h| / 2 < min(|F(s_i)|, |F(s_i + h)|)``, then on each half of the step
``F`` stays in a disc about an end value that excludes 0, so the change of argument over
the step is the principal value of ``arg(F(s_i + h) / F(s_i))``. Failing steps are
halved. The winding number is then an integer by construction, not a rounded integral.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._flint import ball_lower, ball_upper
from .._json import json_safe
from .._validate import positive_int
from .._validate import region as _check_region
from ..balls import BallFunction, ball_function
from ..errors import CertificationError, ParameterError
from ..qpmatrix import CharacteristicFunction
from ..quasipoly import QuasiPolynomial
from ._common import EPS, ROUNDING, Budget, check_function, check_rigorous, magnitude
from ._neighbours import ChebyshevIndex

__all__ = ["Region", "RootCount", "count_roots"]

Region = tuple[float, float, float, float]

# A sample with |F| below this (relative to the same sum) is "on a root": shift the edge.
_NEAR_ZERO = 512 * EPS
# Steps shorter than this (relative to 1 + |s|) are not refined further: shift the edge.
_MIN_STEP = 1e-13
# Initial number of steps per edge.
_INITIAL_STEPS = 1
# Most initial steps per edge that a function may propose (F.initial_steps).
_MAX_INITIAL = 256
# Longest initial step on a segment, relative to its distance to the nearest approximate root
# (Counter.approx): a step of about that distance fails the order-1 rule near a simple root.
_NEAR_STEP = 0.8
# Only segments longer than this many times that distance: the side of a box about a root (a
# step of twice the distance, the root facing its middle) passes the rules in one step.
_NEAR_LONG = 4.0
# Up to this many (segment, approximate root) pairs every distance is computed; beyond, the root
# nearest to each segment's midpoint stands for them.
_NEAR_PAIRS = 1 << 16
# A failing step is cut into as many pieces as its step rule predicts (the factor by which
# it fails: the bound of order 1 is linear in the step, that of order 2 quadratic), at least
# 2 and at most _MAX_PIECES: fewer rounds of refinement than halving.
_MAX_PIECES = 16
_SIDES = ("bottom", "right", "top", "left")
# Root-finding strategies of find_roots (see its docstring).
METHODS = ("auto", "subdivision")


# ====================================================================== counting engine
@dataclass
class _Edges:
    """Result of certifying a batch of oriented segments."""

    turns: NDArray[np.float64]  # total change of argument / (2 pi) along each segment
    blocked: NDArray[np.bool_]  # True where a root lies on or too near the segment


@dataclass
class _Steps:
    """The contour steps ``[start, end]`` not yet certified, as parallel arrays (one entry per step)."""

    start: NDArray[np.complex128]
    end: NDArray[np.complex128]
    f_start: NDArray[np.complex128]  # F(start)
    f_end: NDArray[np.complex128]  # F(end)
    scale_start: NDArray[np.float64]  # rounding scale of F(start) (magnitude)
    scale_end: NDArray[np.float64]  # rounding scale of F(end)
    df_start: NDArray[np.complex128]  # F'(start); NaN until the order-2 rule needs it
    segment: NDArray[np.intp]  # index of the segment the step belongs to

    @property
    def size(self) -> int:
        return int(self.start.size)

    def take(self, mask: NDArray[np.bool_]) -> _Steps:
        """The steps selected by ``mask``."""
        return _Steps(*(getattr(self, name)[mask] for name in _STEP_FIELDS))

    def cut_points(self, pieces: NDArray[np.intp]) -> tuple[NDArray[np.intp], NDArray[np.complex128]]:
        """The owners and positions of the interior points that cut step ``i`` into ``pieces[i]`` equal pieces."""
        owner = np.repeat(np.arange(self.size), pieces - 1)
        first = np.repeat(np.cumsum(pieces - 1) - (pieces - 1), pieces - 1)
        frac = (np.arange(owner.size) - first + 1) / pieces[owner]
        return owner, self.start[owner] + (self.end - self.start)[owner] * frac

    def split(self, pieces: NDArray[np.intp], cut: NDArray, f_cut: NDArray, scale_cut: NDArray) -> _Steps:
        """Every step cut at its :meth:`cut_points` ``cut`` (with ``F`` and its rounding scale there), in order."""
        # the nodes of step i: its start, its cut points, its end, at offsets base[i] .. base[i] + pieces[i]
        base = np.cumsum(pieces + 1) - (pieces + 1)
        inner = np.ones(int(np.sum(pieces + 1)), dtype=bool)
        inner[base] = inner[base + pieces] = False

        def nodes(ends: tuple[NDArray, NDArray], mid: NDArray) -> NDArray:
            out = np.empty(inner.size, dtype=mid.dtype)
            out[base], out[base + pieces], out[inner] = ends[0], ends[1], mid
            return out

        z = nodes((self.start, self.end), cut)
        f = nodes((self.f_start, self.f_end), f_cut)
        m = nodes((self.scale_start, self.scale_end), scale_cut)
        df = np.full(inner.size, np.nan, dtype=complex)
        df[base] = self.df_start
        head = np.ones(inner.size, dtype=bool)  # the nodes that start a piece
        head[base + pieces] = False
        tail = np.ones(inner.size, dtype=bool)  # the nodes that end one
        tail[base] = False
        return _Steps(
            start=z[head],
            end=z[tail],
            f_start=f[head],
            f_end=f[tail],
            scale_start=m[head],
            scale_end=m[tail],
            df_start=df[head],
            segment=np.repeat(self.segment, pieces),
        )


_STEP_FIELDS = tuple(f.name for f in fields(_Steps))


def _first_order_ok(reach: NDArray, f_start: NDArray, f_end: NDArray, steps: _Steps) -> NDArray[np.bool_]:
    """Step rule of order 1: ``M |h| / 2 < min(|F(a)|, |F(b)|)`` (minus rounding), with ``reach = M |h|``
    and the moduli ``|F(a)|``, ``|F(b)|``."""
    room = np.minimum(f_start - ROUNDING * steps.scale_start, f_end - ROUNDING * steps.scale_end)
    return reach * 0.5 < room


def _second_order_terms(bound2: NDArray, bound: NDArray, steps: _Steps) -> tuple[NDArray, NDArray]:
    """Step rule of order 2, for steps near a root where order 1 needs tiny steps: it holds where
    the first array returned (the radius, with the rounding slack) is below the second (the distance).

    With ``M2`` a bound of ``|F''|`` on the step, ``F(a + t) = F(a) + F'(a) t + R(t)`` with
    ``|R| <= M2 |t|^2 / 2``: ``F`` stays in the tube of that radius about the segment
    ``[F(a), F(a) + F'(a) h]``. If the segment's distance to 0 exceeds the radius, the
    tube is a convex set without 0, hence in an open half-plane, and the change of
    argument over the step is again the principal value of ``arg(F(b) / F(a))``.
    """
    h = steps.end - steps.start
    p0, v = steps.f_start, steps.df_start * h
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.clip(-np.real(np.conj(v) * p0) / np.abs(v) ** 2, 0.0, 1.0)
    dist = np.abs(p0 + np.where(np.isnan(t), 0.0, t) * v)
    slack = ROUNDING * (steps.scale_start + bound * np.abs(h))
    return bound2 * np.abs(h) ** 2 * 0.5 + slack, dist


def _wind_segments(
    F: QuasiPolynomial,
    starts: NDArray,
    ends: NDArray,
    budget: Budget,
    label: Callable[[int], str],
    approx: NDArray[np.complex128] | None = None,
) -> _Edges:
    """Certified change of argument of ``F`` along each segment ``[starts[i], ends[i]]``.

    All segments are refined together; only the steps that fail both step rules
    (:func:`_first_order_ok`, :func:`_second_order_terms`) are cut, each into the number of
    pieces its rules predict (the factor by which the bound of order 1 exceeds the room,
    or the square root of that of order 2; 2 to ``_MAX_PIECES``). The order-2 rule
    (one evaluation of ``F'`` and a bound of ``|F''|``) is tried only on steps that fail
    the order-1 rule by a factor above 8, i.e. close to a root. When the work bound is
    hit, the error names the edge that holds the most unfinished steps. ``approx``: approximate
    roots, which set the initial steps of the segments that pass close to them
    (:func:`_initial_pieces`).
    """
    n_edges = starts.size
    pieces = _initial_pieces(F, starts, ends, approx)
    base = np.cumsum(pieces + 1) - (pieces + 1)  # the nodes of segment i at offsets base[i] .. base[i] + pieces[i]
    owner = np.repeat(np.arange(n_edges), pieces + 1)
    pts = starts[owner] + (ends - starts)[owner] * ((np.arange(owner.size) - base[owner]) / pieces[owner])
    pts[base + pieces] = ends  # exact corners, so that adjacent edges close the contour
    budget.spend(pts.size, "sampling contour edges")
    fv, mag = _evaluate(F, pts, label, owner)
    head = np.ones(pts.size, dtype=bool)  # the nodes that start a step
    head[base + pieces] = False
    tail = np.ones(pts.size, dtype=bool)  # the nodes that end one
    tail[base] = False
    steps = _Steps(
        start=pts[head],
        end=pts[tail],
        f_start=fv[head],
        f_end=fv[tail],
        scale_start=mag[head],
        scale_end=mag[tail],
        df_start=np.full(int(pieces.sum()), np.nan, dtype=complex),
        segment=np.repeat(np.arange(n_edges), pieces),
    )
    turns = np.zeros(n_edges)
    blocked = np.zeros(n_edges, dtype=bool)
    near = (np.abs(steps.f_start) <= _NEAR_ZERO * steps.scale_start) | (
        np.abs(steps.f_end) <= _NEAR_ZERO * steps.scale_end
    )
    blocked[steps.segment[near]] = True
    dF: QuasiPolynomial | None = None

    def about(work: str, segment: NDArray) -> Callable[[], str]:
        """The work on the edge with the most steps, named only if the budget runs out."""
        return lambda: f"{work} the {label(int(np.bincount(segment).argmax()))}"

    while steps.size:
        if blocked.any():
            steps = steps.take(~blocked[steps.segment])
            if not steps.size:
                break
        budget.spend(steps.size, about("bounding |F'| on", steps.segment))
        bound = F.deriv_bound(steps.start, steps.end) * (1.0 + 1e-12)
        reach = bound * np.abs(steps.end - steps.start)  # M |h|
        f_start, f_end = np.abs(steps.f_start), np.abs(steps.f_end)
        ok = _first_order_ok(reach, f_start, f_end, steps)
        if ok.all():  # the last round (often the only one): every step certified by the order-1 rule
            turns += np.bincount(steps.segment, weights=np.angle(steps.f_end / steps.f_start), minlength=n_edges)
            break
        room = np.minimum(f_start, f_end)
        close = ~ok & (reach > 8.0 * room)
        with np.errstate(divide="ignore", invalid="ignore"):
            excess = 0.5 * reach / (room - ROUNDING * np.maximum(steps.scale_start, steps.scale_end))
        if close.any():
            dF = F.derivative() if dF is None else dF
            idx = np.flatnonzero(close)
            need = idx[np.isnan(steps.df_start[idx])]
            budget.spend(2 * idx.size, about("bounding |F''| on", steps.segment))
            steps.df_start[need] = F.deriv_at(steps.start[need])
            sub = steps.take(close)
            radius, dist = _second_order_terms(dF.deriv_bound(sub.start, sub.end) * (1.0 + 1e-12), bound[idx], sub)
            ok[idx] = radius < dist
            with np.errstate(divide="ignore", invalid="ignore"):
                excess[idx] = np.fmin(excess[idx], np.sqrt(radius / dist))
        turns += np.bincount(
            steps.segment[ok], weights=np.angle(steps.f_end[ok] / steps.f_start[ok]), minlength=n_edges
        )
        if ok.all():
            break
        steps, excess = steps.take(~ok), excess[~ok]
        a, b = steps.start, steps.end
        blocked[steps.segment[np.abs(b - a) < _MIN_STEP * (1.0 + np.abs(a))]] = True
        pieces = np.fmin(np.fmax(np.ceil(excess), 2.0), _MAX_PIECES).astype(np.intp)  # nan: 2
        owner, cut = steps.cut_points(pieces)
        budget.spend(cut.size, about("refining", steps.segment))
        fm, mm = _evaluate(F, cut, label, steps.segment[owner])
        blocked[steps.segment[owner][np.abs(fm) <= _NEAR_ZERO * mm]] = True
        steps = steps.split(pieces, cut, fm, mm)
    return _Edges(turns / (2 * np.pi), blocked)


def _evaluate(
    F: QuasiPolynomial, s: NDArray[np.complex128], label: Callable[[int], str], owner: NDArray
) -> tuple[NDArray, NDArray]:
    """``F(s)`` and its rounding scale; an overflow is an error naming the edge."""
    with np.errstate(over="ignore", invalid="ignore"):
        fv = F(s)
        mag = magnitude(F, s)
    if not (np.isfinite(fv).all() and np.isfinite(mag).all()):
        bad = ~(np.isfinite(fv) & np.isfinite(mag))
        edge = label(int(np.ravel(owner)[np.flatnonzero(bad.ravel())[0]]))
        raise CertificationError(f"F overflows on the {edge}: move the region to the right or shrink it")
    return fv, mag


def _initial_pieces(
    F: QuasiPolynomial, starts: NDArray, ends: NDArray, approx: NDArray[np.complex128] | None = None
) -> NDArray[np.intp]:
    """Steps per segment to start from: ``_INITIAL_STEPS``, or what ``F.initial_steps(starts, ends)``
    proposes when ``F`` has that method (a function that knows the scale on which it turns), 1 to
    ``_MAX_INITIAL``. With approximate roots ``approx``, a segment at distance ``d`` from the nearest
    one gets steps of at most ``_NEAR_STEP d`` when longer than ``_NEAR_LONG d``: near a simple root
    ``|F|`` grows like the distance to it, and longer steps fail the order-1 rule there and cost a
    round of refinement. Only the work depends on it: every step is still certified by the step rules."""
    propose = getattr(F, "initial_steps", None)
    pieces = (
        np.full(starts.size, float(_INITIAL_STEPS))
        if propose is None
        else np.maximum(np.asarray(propose(starts, ends), dtype=float), 1.0)
    )
    if approx is not None and approx.size:
        h = ends - starts
        length = np.abs(h)
        if starts.size * approx.size <= _NEAR_PAIRS:  # every segment with every root
            rel = approx[None, :] - starts[:, None]
        else:  # the root nearest to each segment's midpoint only: memory and time linear in the segments
            mid = starts + 0.5 * h
            _, idx = ChebyshevIndex(np.column_stack([approx.real, approx.imag])).query(
                np.column_stack([mid.real, mid.imag])
            )
            rel = (approx[idx] - starts)[:, None]
        square = length**2
        square[square == 0.0] = 1.0  # a segment of length 0: its start is its nearest point
        t = np.clip((rel * np.conj(h)[:, None]).real / square[:, None], 0.0, 1.0)
        gap = np.abs(rel - t * h[:, None]).min(axis=1)
        long = np.flatnonzero(length > _NEAR_LONG * gap)
        if long.size:
            with np.errstate(divide="ignore"):  # a root on the segment: the most steps
                want = np.ceil(length[long] / (_NEAR_STEP * gap[long]))
            pieces[long] = np.maximum(pieces[long], np.minimum(want, _MAX_INITIAL))
    return np.minimum(pieces, _MAX_INITIAL).astype(np.intp)


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


def _move_edges_out(box: list[float], blocked: np.ndarray, delta: float) -> None:
    """Move the ``blocked`` sides of ``box`` (bottom, right, top, left) outwards by ``delta``, in place."""
    for k in np.flatnonzero(blocked):
        if k == 0:
            box[2] -= delta
        elif k == 1:
            box[1] += delta
        elif k == 2:
            box[3] += delta
        else:
            box[0] -= delta


class Counter:
    """Certified counts of many boxes at once; edges shared between boxes are computed once."""

    def __init__(self, F: QuasiPolynomial, budget: Budget) -> None:
        self.F = F
        self.budget = budget
        self.cache: dict[tuple[complex, complex], tuple[float, bool]] = {}
        # the turns and blocked sides of each box counted (or prefetched), by its corners
        self.boxes: dict[tuple[float, ...], tuple[float, NDArray[np.bool_]]] = {}
        self.real = bool(F.is_real)
        # boxes whose edges the next count computes with its own (one batch): boxes about candidate
        # roots known before the region is counted, which the search counts next
        self.prefetch: list[tuple[float, float, float, float]] = []
        # approximate roots (Newton's limit points) near which the contour steps start short
        self.approx: NDArray[np.complex128] | None = None

    def _pieces(self, p: complex, q: complex) -> list[tuple[complex, complex, float]]:
        """Segments ``(a, b, sign)`` whose turns, times their signs, add up to those of ``[p, q]``.

        For a real ``F`` (``F(conj s) = conj F(s)``) the argument of ``F`` along the mirror
        image of a path is minus its argument along the path: a segment below the real axis
        is its mirror image above with the opposite sign, and a vertical segment crossing the
        axis is cut there. Only segments in the closed upper half-plane are then computed
        (half of the contour of a box symmetric about the axis, and of the boxes about the
        lower roots of conjugate pairs).
        """
        if not self.real or (p.imag >= 0.0 and q.imag >= 0.0):
            return [(p, q, 1.0)]
        if p.imag <= 0.0 and q.imag <= 0.0:
            return [(p.conjugate(), q.conjugate(), -1.0)]
        r = complex(p.real, 0.0)  # a vertical segment through the axis
        return [piece for half in ((p, r), (r, q)) for piece in self._pieces(*half)]

    def count(self, boxes: Sequence[Sequence[float]]) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
        """Counts of the boxes, and a (boxes x 4) mask of sides with a root on or near them.

        The boxes of ``prefetch`` are counted in the same batch (and the list emptied), their
        results kept for the count that asks for them; a box counted before is not counted again.
        """
        extra, self.prefetch = self.prefetch, []
        keys = [tuple(float(v) for v in box) for box in boxes]
        new = list(
            dict.fromkeys(box for box in [*keys, *(tuple(float(v) for v in b) for b in extra)] if box not in self.boxes)
        )
        if new:
            self._count_new(new)
        turns = np.array([self.boxes[box][0] for box in keys], dtype=float)
        box_blocked = np.array([self.boxes[box][1] for box in keys], dtype=bool).reshape(len(keys), 4)
        counts = np.rint(turns).astype(np.int64)
        good = ~box_blocked.any(axis=1)
        if (np.abs(turns[good] - counts[good]) > 1e-6).any():
            raise CertificationError("a certified winding number is not an integer: floating-point failure")
        return counts, box_blocked

    def _count_new(self, boxes: list[tuple[float, ...]]) -> None:
        """Winding numbers (in turns, not rounded) and blocked sides of ``boxes`` into :attr:`boxes`."""
        pieces = [self._pieces(p, q) for box in boxes for p, q in _box_edges(box)]
        todo: dict[tuple[complex, complex], int] = {}
        for i, edge in enumerate(pieces):
            for p, q, _ in edge:
                if not ((p, q) in self.cache or (q, p) in self.cache or (p, q) in todo or (q, p) in todo):
                    todo[(p, q)] = i
        if todo:
            keys = list(todo)
            res = _wind_segments(
                self.F,
                np.array([k[0] for k in keys]),
                np.array([k[1] for k in keys]),
                self.budget,
                lambda j: _describe_edge(boxes[todo[keys[j]] // 4], todo[keys[j]] % 4),
                self.approx,
            )
            for k, tr, bl in zip(keys, res.turns, res.blocked):
                self.cache[k] = (float(tr), bool(bl))
        turns = [0.0] * len(pieces)
        blocked = [False] * len(pieces)
        for i, edge in enumerate(pieces):
            for p, q, sign in edge:
                if (p, q) in self.cache:
                    tr, bl = self.cache[(p, q)]
                else:
                    tr, bl = self.cache[(q, p)]
                    tr = -tr
                turns[i] += sign * tr
                blocked[i] |= bl
        sides = np.array(blocked).reshape(-1, 4)
        for box, tr, bl in zip(boxes, np.array(turns).reshape(-1, 4).sum(axis=1).tolist(), sides):
            self.boxes[box] = (tr, bl)


# ====================================================================== counting in ball arithmetic
# Initial number of pieces per edge of a contour proven in ball arithmetic.
_BALL_PIECES = 16
# A piece whose enclosures both contain 0 is cut in 2 pieces, or in up to _BALL_SPLIT when the
# better one has a radius above _BALL_WIDE times the distance of its midpoint to 0 (the radius
# shrinks about linearly with the piece: the levels of halving that would fail are skipped).
_BALL_WIDE = 2.0
_BALL_SPLIT = 4
# Margin (radians) by which a lifted argument interval must miss the other lifts.
_LIFT_MARGIN = 1e-9


def _arg_interval(value: Any) -> tuple[float, float] | None:
    """An interval ``[lo, hi]`` (radians, width < pi) holding ``arg z`` for every ``z`` of the ``acb`` rectangle.

    None if the rectangle contains 0, is not finite, or subtends an angle of pi or more
    (a rectangle that misses 0 is convex, so it subtends less than pi, but its enclosure
    of the argument may be wider). A rectangle in the left half-plane is rotated by pi
    first, so that the enclosure never straddles the branch cut.
    """
    re, im = value.real, value.imag
    if not (value.is_finite() and (not re.contains(0) or not im.contains(0))):
        return None
    if float(re.upper()) < 0:
        arg, shift = (-value).arg(), np.pi
    else:
        arg, shift = value.arg(), 0.0
    lo, hi = ball_lower(arg), ball_upper(arg)
    if not (np.isfinite(lo) and np.isfinite(hi)) or hi - lo >= 3.0:
        return None
    # outward rounding of the conversions to double and of the shift by pi
    pad = 4 * EPS * (abs(lo) + abs(hi) + np.pi)
    return lo + shift - pad, hi + shift + pad


def _wideness(value: Any) -> float:
    """Radius of the ``acb`` rectangle over the distance of its midpoint to 0 (``inf``: not finite, or centred at 0)."""
    rad = float(value.real.rad()) + float(value.imag.rad())
    dist = math.hypot(float(value.real.mid()), float(value.imag.mid()))
    return rad / dist if dist > 0.0 and math.isfinite(rad) else math.inf


def _intersect(u: Any, v: Any) -> Any:
    """The ``acb`` rectangle ``u ∩ v`` (both enclose the same values, so they overlap)."""
    return type(u)(u.real.intersection(v.real), u.imag.intersection(v.imag))


def _lift(interval: tuple[float, float], previous: tuple[float, float]) -> tuple[float, float] | None:
    """The unique ``interval + 2 pi n`` that meets ``previous``; None if not unique (with a margin)."""
    lo, hi = interval
    plo, phi = previous
    n = round((plo + phi - lo - hi) / (4 * np.pi))
    meets = [
        lo + 2 * np.pi * k <= phi + _LIFT_MARGIN and hi + 2 * np.pi * k >= plo - _LIFT_MARGIN for k in (n - 1, n, n + 1)
    ]
    if meets != [False, True, False]:
        return None
    return lo + 2 * np.pi * n, hi + 2 * np.pi * n


def ball_winding(balls: Any, box: Sequence[float], budget: Budget) -> tuple[int | None, NDArray[np.bool_]]:
    """Winding number of ``F`` around the boundary of ``box``, proven in ball arithmetic.

    The boundary is cut into pieces; on each, ``F`` is enclosed in an ``acb`` rectangle
    (:meth:`nrobust.balls.BallQuasiPolynomial.on_segment`: the ball evaluation on the piece, and where
    that contains 0 its intersection with the mean-value form ``F(c) + F'(B) (B - c)``, which
    near a multiple root shrinks with the piece) and the piece is accepted when the rectangle
    misses 0: ``F`` maps the piece into a convex set without 0, so the continuous argument
    along the piece stays in one lift of the rectangle's argument interval (width < pi).
    Consecutive pieces share a point, so their lifts meet; when exactly one lift of the
    next interval meets the previous one (each is narrower than pi, and a margin is
    demanded) it is the lift the continuous argument takes. After the whole boundary the
    lift of the first interval that meets the last one is ``first + 2 pi n``: ``n`` is the
    winding number, a theorem about ``F`` as represented. Failing pieces are halved (cut in up
    to ``_BALL_SPLIT`` pieces when their enclosures are far from excluding 0);
    a piece shorter than ``_MIN_STEP (1 + |s|)`` blocks its side.

    Returns
    -------
    (count or None, blocked sides (bottom, right, top, left))
    """
    blocked = np.zeros(4, dtype=bool)
    first: tuple[float, float] | None = None
    prev: tuple[float, float] | None = None
    for side, (a, b) in enumerate(_box_edges(box)):
        t = np.linspace(0.0, 1.0, _BALL_PIECES + 1)
        pts = [a + (b - a) * v for v in t[:-1]] + [b]
        stack = [(pts[i], pts[i + 1]) for i in range(_BALL_PIECES - 1, -1, -1)]
        while stack:
            p, q = stack.pop()
            budget.spend(1, f"proving the {_describe_edge(box, side)} in ball arithmetic")
            value = balls.on_segment(p, q)
            iv = _arg_interval(value)
            pieces = 2
            if iv is None:  # near a root: the mean-value form, intersected with the direct enclosure
                budget.spend(2, f"proving the {_describe_edge(box, side)} in ball arithmetic")
                both = _intersect(value, balls.on_segment(p, q, centered=True))
                iv = _arg_interval(both)
                wide = min(_wideness(both), _wideness(value))
                if iv is None and _BALL_WIDE < wide < math.inf:
                    pieces = min(_BALL_SPLIT, math.ceil(wide / _BALL_WIDE))
            lifted = iv if iv is None or prev is None else _lift(iv, prev)
            if lifted is not None:
                prev = lifted
                first = lifted if first is None else first
                continue
            if abs(q - p) < _MIN_STEP * (1.0 + abs(p)):
                blocked[side] = True
                prev = None  # the chain is broken: the count is void, the other sides are still probed
                break
            # the pieces share their ends exactly, on the line of the edge
            cuts = [p + (q - p) * (j / pieces) for j in range(1, pieces)]
            on_edge = [
                complex(p.real if p.real == q.real else z.real, p.imag if p.imag == q.imag else z.imag) for z in cuts
            ]
            nodes = [p, *on_edge, q]
            stack += [(nodes[j], nodes[j + 1]) for j in range(pieces - 1, -1, -1)]
    if blocked.any() or first is None or prev is None:
        return None, blocked
    closing = _lift(first, prev)
    if closing is None:
        return None, np.ones(4, dtype=bool)
    return round((closing[0] - first[0]) / (2 * np.pi)), blocked


def ball_count_with_shifts(balls: Any, box: Region, max_shifts: int, budget: Budget) -> tuple[int, Region, bool]:
    """As :func:`count_with_shifts`, with the count proven by :func:`ball_winding`."""
    reg = list(box)
    size = max(reg[1] - reg[0], reg[3] - reg[2])
    for attempt in range(max_shifts + 1):
        n, blocked = ball_winding(balls, reg, budget)
        if n is not None:
            return n, tuple(reg), attempt > 0  # type: ignore[return-value]
        if attempt == max_shifts:
            sides = "; ".join(_describe_edge(reg, int(k)) for k in np.flatnonzero(blocked))
            raise CertificationError(
                f"ball arithmetic cannot prove the winding number: a root lies on or within rounding of the {sides} "
                f"after {max_shifts} shifts (move the region's edges away from the roots, or raise prec)"
            )
        _move_edges_out(reg, blocked, size * 1e-7 * 10.0**attempt * 1.618)
    raise AssertionError("unreachable")


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
        Number of evaluations of ``F`` and of its derivative bound (or ball enclosures).
    rigorous : bool
        True if the count is proven in ball arithmetic (``count_roots(..., rigorous=True)``);
        False for the floating-point certification with a rounding allowance.
    """

    region: Region
    shifted: bool
    evaluations: int
    rigorous: bool

    def __new__(cls, count: int, region: Region, shifted: bool, evaluations: int, rigorous: bool = False) -> RootCount:
        obj = super().__new__(cls, count)
        object.__setattr__(obj, "region", tuple(float(v) for v in region))
        object.__setattr__(obj, "shifted", bool(shifted))
        object.__setattr__(obj, "evaluations", int(evaluations))
        object.__setattr__(obj, "rigorous", bool(rigorous))
        return obj

    @property
    def method(self) -> str:
        """``"ball arithmetic"`` (proven) or ``"floating point"`` (checked with a rounding allowance)."""
        return "ball arithmetic" if self.rigorous else "floating point"

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"RootCount is immutable (cannot set {name!r})")

    def __reduce__(self) -> tuple[type[RootCount], tuple[int, Region, bool, int, bool]]:
        """Rebuild from the count and the attributes (for ``copy`` and ``pickle``)."""
        return (type(self), (int(self), self.region, self.shifted, self.evaluations, self.rigorous))

    def __repr__(self) -> str:
        r = ", ".join(f"{v:.12g}" for v in self.region)
        proven = ", rigorous=True" if self.rigorous else ""
        return f"RootCount({int(self)}, region=({r}), shifted={self.shifted}, evaluations={self.evaluations}{proven})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return json_safe(
            {
                "count": int(self),
                "region": self.region,
                "shifted": self.shifted,
                "evaluations": self.evaluations,
                "rigorous": self.rigorous,
                "method": self.method,
            }
        )


def count_with_shifts(counter: Counter, box: Region, max_shifts: int) -> tuple[int, Region, bool]:
    """Count a box, moving blocked edges outwards (by 1e-7, 1e-6, ... of its size)."""
    reg = list(box)
    size = max(reg[1] - reg[0], reg[3] - reg[2])
    for attempt in range(max_shifts + 1):
        counts, blocked = counter.count([tuple(reg)])
        if not blocked[0].any():
            return int(counts[0]), tuple(reg), attempt > 0  # type: ignore[return-value]
        if attempt == max_shifts:
            sides = "; ".join(_describe_edge(reg, int(k)) for k in np.flatnonzero(blocked[0]))
            raise CertificationError(f"a root lies on or within rounding of the {sides} after {max_shifts} shifts")
        _move_edges_out(reg, blocked[0], size * 1e-7 * 10.0**attempt * 1.618)
    raise AssertionError("unreachable")


def count_roots(
    F: QuasiPolynomial | CharacteristicFunction,
    region: ArrayLike,
    *,
    max_evals: int = 2_000_000,
    max_shifts: int = 4,
    rigorous: bool = False,
    prec: int = 53,
    balls: BallFunction | None = None,
) -> RootCount:
    """Certified number of roots of ``F`` (with multiplicity) in a rectangle.

    Parameters
    ----------
    F : QuasiPolynomial or QuasiPolynomialMatrix
        The function (a matrix stands for its determinant, never expanded).
    region : (re_min, re_max, im_min, im_max)
        The rectangle; an edge through or within rounding of a root is moved outwards
        and the rectangle actually counted is reported in the result.
    max_evals : int, optional
        Work bound: evaluations of ``F`` and of its derivative bound.
    max_shifts : int, optional
        How many times an edge may be moved before giving up.
    rigorous : bool, optional
        Prove the count in ball arithmetic (python-flint, ``pip install nrobust[rigorous]``):
        every piece of the boundary is accepted only when a ball enclosure of ``F`` on the
        whole piece misses 0, so the winding number is a theorem about ``F`` as represented
        (:mod:`nrobust.balls`); a matrix through the determinant of its enclosed entries, another
        characteristic function through its own enclosure (``F.ball_function(prec)``).
    prec : int, optional
        Working precision in bits of the ball arithmetic (``rigorous=True``).
    balls : BallFunction, optional
        With ``rigorous``, the enclosure the count is proven with (default
        ``ball_function(F, prec)``): the count of the function it encloses, which ``F``
        approximates (e.g. :func:`~nrobust.hyperbolic.loops.given_plant.given_plant_balls`).

    Returns
    -------
    RootCount
        An ``int`` with the attributes ``region``, ``shifted``, ``evaluations`` and
        ``rigorous``.

    Raises
    ------
    RegionError
        Empty or non-finite region.
    CertificationError
        The work bound was exhausted (the message names the edge), or a root stays on an
        edge after ``max_shifts`` shifts (with ``rigorous=True``: the ball enclosures
        cannot exclude 0 there).
    ImportError
        ``rigorous=True`` without python-flint.

    Examples
    --------
    >>> from nrobust import QuasiPolynomial
    >>> F = QuasiPolynomial([[1], [-0.85], [0.1]], [0, 2, 2.1])
    >>> int(count_roots(F, (-3, 1, -0.5, 200)))
    64
    """
    F = check_function(F)
    box = _check_region(region)
    max_evals = positive_int("max_evals", max_evals)
    max_shifts = positive_int("max_shifts", max_shifts, minimum=0)
    if balls is not None and not isinstance(balls, BallFunction):
        raise ParameterError("balls", "a BallFunction (nrobust.balls) or None", type(balls).__name__)
    budget = Budget(max_evals)
    if check_rigorous(F, rigorous):
        enclosure = ball_function(F, prec) if balls is None else balls
        n, reg, shifted = ball_count_with_shifts(enclosure, box, max_shifts, budget)
        return RootCount(n, reg, shifted, budget.used, rigorous=True)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
        n, reg, shifted = count_with_shifts(Counter(F, budget), box, max_shifts)
    return RootCount(n, reg, shifted, budget.used)
