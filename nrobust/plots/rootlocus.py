"""Root loci: the roots of a family of characteristic functions as a parameter moves."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._json import fields_dict
from .._progress import progress_bar
from .._validate import region as check_region
from ..errors import ParameterError
from ..quasipoly import QuasiPolynomial, as_quasipolynomial
from ..roots import find_roots
from .base import NrobustPlot, get_axes

if TYPE_CHECKING:
    from matplotlib.axes import Axes


__all__ = ["RootLocusData", "root_locus_plot", "root_locus_response"]


@dataclass(frozen=True, eq=False)
class RootLocusData:
    """Roots of a family ``F_p`` in a region as the parameter ``p`` moves.

    Attributes
    ----------
    name : str
        Name of the parameter (``"K"``, ``"delta"``...).
    params : ndarray
        Parameter values.
    roots : tuple of ndarray
        ``roots[i]`` are the roots of ``F_{params[i]}`` in ``region``.
    region : tuple
        The rectangle searched.
    """

    name: str
    params: NDArray[np.float64]
    roots: tuple[NDArray[np.complex128], ...]
    region: tuple[float, float, float, float]

    def plot(self, ax: Axes | None = None, cmap: str = "viridis") -> NrobustPlot:
        """Scatter the roots coloured by the parameter; ``lines["roots"]`` is the collection."""
        ax = get_axes(ax)
        pts = np.concatenate(self.roots) if self.roots else np.zeros(0, complex)
        col = (
            np.concatenate([np.full(r.size, p) for p, r in zip(self.params, self.roots)]) if self.roots else np.zeros(0)
        )
        lines: dict[str, list[Any]] = {}
        lines["axis"] = [ax.axvline(0.0, color="k", lw=0.8)]
        sc = ax.scatter(pts.real, pts.imag, c=col, cmap=cmap, s=10, vmin=self.params.min(), vmax=self.params.max())
        lines["roots"] = [sc]
        lines["colorbar"] = [ax.figure.colorbar(sc, ax=ax, label=self.name)]
        ax.set_xlim(self.region[0], self.region[1])
        ax.set_ylim(self.region[2], self.region[3])
        ax.set_xlabel("Re s")
        ax.set_ylabel("Im s")
        ax.set_title(f"Root locus in {self.name}", fontsize="small")
        return NrobustPlot(lines, ax, ax.figure)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (roots as ``[re, im]`` pairs)."""
        return fields_dict(self)


def root_locus_response(
    family: Callable[[float], QuasiPolynomial],
    params: ArrayLike,
    region: tuple[float, float, float, float],
    name: str = "p",
    progress: bool = False,
) -> RootLocusData:
    """Roots of ``family(p)`` in ``region`` for each ``p`` of ``params`` (certified counts).

    ``family`` maps a parameter to a characteristic function, e.g.
    ``lambda K: characteristic(system, ReflectionController(K), delta)`` for a locus in
    ``K`` or ``lambda d: characteristic(system, controller, d)`` for a locus in ``delta``.
    """

    box = check_region(region)
    p = np.atleast_1d(np.asarray(params, dtype=float))
    if p.ndim != 1 or p.size == 0 or not np.all(np.isfinite(p)):
        raise ParameterError("params", "a non-empty 1-D array of finite numbers", params)
    roots = []
    with progress_bar(p.size, progress, f"root locus in {name}") as bar:
        for x in p.tolist():
            roots.append(np.asarray(find_roots(as_quasipolynomial("family(p)", family(x)), box).roots, dtype=complex))
            bar.update(1)
    return RootLocusData(name, p, tuple(roots), box)


def root_locus_plot(
    family: Callable[[float], QuasiPolynomial],
    params: ArrayLike,
    region: tuple[float, float, float, float],
    name: str = "p",
    ax: Axes | None = None,
) -> NrobustPlot:
    """Compute :func:`root_locus_response` and plot it."""
    return root_locus_response(family, params, region, name).plot(ax=ax)
