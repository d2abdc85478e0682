"""Neighbours of points in the plane, by sorting (numpy only).

The root search (:mod:`nrobust.roots.search`, :mod:`nrobust.roots.finder`) asks for the
``k`` nearest points in the Chebyshev distance ``max(|dx|, |dy|)`` (the metric in which a
box is a ball), for the pairs closer than ``r`` (Chebyshev or Euclidean) and for the groups
those pairs link. The point sets are small (tens to a few thousands), and the answers here
are those of ``scipy.spatial.cKDTree(points).query(x, k, p=inf)``, ``.query_pairs(r, p)``
and ``scipy.sparse.csgraph.connected_components``, without importing scipy.spatial and
scipy.sparse (a good part of a second on first use). The distances are computed as the
tree computes them (``max(|dx|, |dy|)``, ``dx**2 + dy**2`` against ``r**2``, in float64), so
they are the same floats; among points at the same distance the lower index comes first.

Sort and sweep: the points are sorted along the coordinate of larger spread. A query
first bounds the distance of its ``k``-th neighbour by the ``k``-th distance to the ``2k + 1``
points nearest in that order, then examines every point whose sorted coordinate lies
within that bound, which holds all ``k`` nearest; a pair search examines, for each point,
the points that follow it in the sorted order within ``r``. Both are exact.
"""

from __future__ import annotations

import functools
from typing import Literal, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ParameterError

__all__ = ["ChebyshevIndex", "connected_groups"]

#: Relative widening of the sweep windows: a few roundings, so that no point within the
#: distance is left out by the rounding of a window's end (extra points are only examined).
_SLACK = 4.0 * np.finfo(float).eps
#: Largest number of distances computed all at once instead of by the sweep (a query of ``m``
#: points among ``n``: ``m n``; the pairs of ``n`` points: ``n^2``): few points, where the
#: sweep's bookkeeping costs more than the distances it avoids. The answers are the same.
_ALL_PAIRS = 4096


def _spans(starts: NDArray[np.intp], stops: NDArray[np.intp]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Flattened ranges ``starts[i] .. stops[i] - 1``: ``(owner i of each entry, entry)``."""
    sizes = np.maximum(stops - starts, 0)
    owner = np.repeat(np.arange(starts.size), sizes)
    first = np.cumsum(sizes) - sizes
    return owner, starts[owner] + (np.arange(owner.size) - first[owner])


@functools.lru_cache(maxsize=64)
def _upper_pairs(n: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """``np.triu_indices(n, 1)`` (every pair ``i < j``, by ``i`` then ``j``), kept per ``n``, read-only."""
    a, b = np.triu_indices(n, 1)
    a.flags.writeable = False
    b.flags.writeable = False
    return a, b


class ChebyshevIndex:
    """Points of the plane searched in the Chebyshev distance (a ``cKDTree`` with ``p = inf``).

    Parameters
    ----------
    points : array_like, shape (n, 2)
        The points ``(x, y)``, finite.
    """

    def __init__(self, points: ArrayLike) -> None:
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or not np.isfinite(pts).all():
            raise ParameterError("points", "an (n, 2) array of finite coordinates", pts.shape)
        self.points = pts

    @functools.cached_property
    def axis(self) -> int:
        """The coordinate of the sweep: that of larger spread (the roots of a chain share their real part)."""
        spread = np.ptp(self.points, axis=0) if self.points.shape[0] else np.zeros(2)
        return int(spread[1] > spread[0])

    @functools.cached_property
    def order(self) -> NDArray[np.intp]:
        """The points' indices sorted by the :attr:`axis` coordinate (sorted once, when a sweep first needs it)."""
        return np.argsort(self.points[:, self.axis], kind="stable")

    @functools.cached_property
    def keys(self) -> NDArray[np.float64]:
        """The sorted :attr:`axis` coordinates."""
        return self.points[self.order, self.axis]

    @property
    def n(self) -> int:
        """The number of points."""
        return int(self.points.shape[0])

    def _distance(self, x: NDArray[np.float64], idx: NDArray[np.intp]) -> NDArray[np.float64]:
        """Chebyshev distances from the rows of ``x`` to the points ``idx`` (row by row)."""
        return np.maximum(np.abs(x[:, 0] - self.points[idx, 0]), np.abs(x[:, 1] - self.points[idx, 1]))

    def query(self, x: ArrayLike, k: int = 1, p: float = np.inf) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
        """The ``k`` nearest points of each row of ``x``: distances and indices, nearest first.

        As ``cKDTree.query(x, k, p=inf)``: shape ``(m,)`` for ``k = 1``, ``(m, k)`` otherwise;
        among points at one distance the lower index comes first.

        Parameters
        ----------
        x : array_like, shape (m, 2)
            Query points, finite.
        k : int
            Neighbours wanted, ``1 <= k <= n``.
        p : float
            The distance: only ``inf`` (Chebyshev) is searched (the default 2, as the
            tree's, is refused).
        """
        if p != np.inf:
            raise ParameterError("p", "inf (the Chebyshev distance)", p)
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= self.n:
            raise ParameterError("k", f"an integer in [1, {self.n}] (the number of points)", k)
        q = np.asarray(x, dtype=float).reshape(-1, 2)
        if not np.isfinite(q).all():
            raise ParameterError("x", "finite query points", q.shape)
        k, m, n = int(k), q.shape[0], self.n
        if m * n <= _ALL_PAIRS:  # every distance; a stable sort puts the lower index first among equal ones
            full = np.abs(q[:, None, :] - self.points[None, :, :]).max(axis=2)  # max(|dx|, |dy|)
            if k == 1:  # the first of the least distances: the lowest index among equal ones
                first = np.argmin(full, axis=1).astype(np.intp)
                return full[np.arange(m), first], first
            near_i = np.argsort(full, axis=1, kind="stable")[:, :k].astype(np.intp)
            return full[np.arange(m)[:, None], near_i], near_i
        # an upper bound of the k-th distance: the k-th nearest of the 2k + 1 nearest in the sorted coordinate
        width = min(n, 2 * k + 1)
        at = np.searchsorted(self.keys, q[:, self.axis])
        start = np.clip(at - k, 0, n - width)
        window = start[:, None] + np.arange(width)
        near = self._distance(np.repeat(q, width, axis=0), self.order[window.ravel()]).reshape(m, width)
        bound = np.partition(near, k - 1, axis=1)[:, k - 1]
        # every point whose sorted coordinate is within the bound: the k nearest are among them
        key = q[:, self.axis]
        slack = _SLACK * (np.abs(key) + bound)  # so that rounding in key -+ bound drops no point
        lo = np.searchsorted(self.keys, key - bound - slack, side="left")
        hi = np.searchsorted(self.keys, key + bound + slack, side="right")
        owner, pos = _spans(lo, hi)
        idx = self.order[pos]
        dist = self._distance(q[owner], idx)
        # by query, then distance, then index; the first k of each query
        rank = np.lexsort((idx, dist, owner))
        first = np.cumsum(hi - lo) - (hi - lo)
        take = rank[(first[:, None] + np.arange(k)).ravel()]
        out_d, out_i = dist[take].reshape(m, k), idx[take].reshape(m, k).astype(np.intp)
        if k == 1:
            return out_d[:, 0], out_i[:, 0]
        return out_d, out_i

    @overload
    def query_pairs(self, r: float, p: float = ..., output_type: Literal["set"] = ...) -> set[tuple[int, int]]: ...
    @overload
    def query_pairs(self, r: float, p: float = ..., *, output_type: Literal["ndarray"]) -> NDArray[np.intp]: ...
    def query_pairs(
        self, r: float, p: float = 2.0, output_type: str = "set"
    ) -> set[tuple[int, int]] | NDArray[np.intp]:
        """The pairs ``(i, j)``, ``i < j``, at a distance at most ``r``.

        As ``cKDTree.query_pairs(r, p, output_type=...)``: the Euclidean distance (``p = 2``,
        compared as ``dx**2 + dy**2 <= r**2``) or the Chebyshev distance (``p = inf``); a set
        of tuples, or with ``output_type="ndarray"`` an ``(npairs, 2)`` array (sorted by
        ``i``, then ``j``).
        """
        if p not in (2.0, np.inf):
            raise ParameterError("p", "2 (Euclidean) or inf (Chebyshev)", p)
        if output_type not in ("set", "ndarray"):
            raise ParameterError("output_type", "'set' or 'ndarray'", output_type)
        r = float(r)
        every = self.n * self.n <= _ALL_PAIRS
        a, b = _upper_pairs(self.n) if every else self._candidate_pairs(r)
        if p == np.inf:
            close = self._distance(self.points[a], b) <= r
        else:
            dx, dy = self.points[a, 0] - self.points[b, 0], self.points[a, 1] - self.points[b, 1]
            close = dx * dx + dy * dy <= r * r
        if every:  # already in the order of i, then j
            pairs = np.column_stack([a[close], b[close]]).astype(np.intp)
        else:
            pairs = np.column_stack([np.minimum(a, b)[close], np.maximum(a, b)[close]]).astype(np.intp)
            pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))] if pairs.size else pairs.reshape(0, 2)
        if output_type == "ndarray":
            return pairs
        return {(int(i), int(j)) for i, j in pairs}

    def _candidate_pairs(self, r: float) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """The pairs of points within ``r`` of each other in the sorted coordinate (a superset of the pairs
        within ``r``), as two index arrays."""
        # both distances are at least the gap in the sorted coordinate
        hi = np.searchsorted(self.keys, self.keys + r + _SLACK * (np.abs(self.keys) + r), side="right")
        owner, pos = _spans(np.arange(self.n) + 1, hi)
        return self.order[owner], self.order[pos]


def connected_groups(n: int, pairs: ArrayLike) -> NDArray[np.intp]:
    """Group labels of ``n`` nodes linked by ``pairs`` (an undirected graph).

    The labels of ``scipy.sparse.csgraph.connected_components(graph, directed=False)[1]``:
    groups numbered ``0, 1, ...`` in the order of their lowest node.
    """
    links = np.asarray(pairs, dtype=np.intp).reshape(-1, 2)
    label = np.arange(n, dtype=np.intp)
    if links.size:
        a, b = links[:, 0], links[:, 1]
        while True:  # each node takes the lowest label of its links, then of its label's node
            low = np.minimum(label[a], label[b])
            new = label.copy()
            np.minimum.at(new, a, low)
            np.minimum.at(new, b, low)
            new = new[new]
            if np.array_equal(new, label):
                break
            label = new
    # the lowest node of each group, numbered in increasing order
    return np.unique(label, return_inverse=True)[1].astype(np.intp)
