"""Figures of designs: the trade-off front of certified designs.

:func:`pareto_response` is the front as data with ``.plot()`` (the pattern of
python-control's ``pole_zero_map(sys).plot()``): it computes nothing itself, the front is
:func:`nrobust.design.pareto_front`'s; :func:`pareto_plot` draws any
:class:`~nrobust.design.pareto.ParetoFront` (also
:func:`nrobust.hyperbolic.analyses.filtered_front`'s).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from numpy.typing import ArrayLike

from ..design.local import ParametricLoop
from ..design.pareto import ParetoFront, pareto_front
from .base import NrobustPlot, get_axes

__all__ = ["ParetoResponse", "pareto_plot", "pareto_response"]


@dataclass(frozen=True, eq=False)
class ParetoResponse:
    """A front of certified designs with ``.plot()`` (:func:`pareto_response`).

    Attributes
    ----------
    front : ParetoFront
        The designs, their decay rates and margins, and what was certified
        (:class:`~nrobust.design.pareto.ParetoFront`).
    """

    front: ParetoFront

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary: the front's (:meth:`ParetoFront.to_dict`)."""
        return self.front.to_dict()

    def plot(self, ax: Axes | None = None, annotate: bool = True) -> NrobustPlot:
        """Best decay rate against delay margin, the requirements and windows marked (:func:`pareto_plot`)."""
        return pareto_plot(self.front, ax, annotate)


def pareto_response(
    loop: ParametricLoop,
    bounds: ArrayLike,
    required: ArrayLike,
    *,
    delays: tuple[float, float] | Sequence[tuple[float, float]] | None = None,
    scenarios: Sequence[ParametricLoop] | Mapping[str, ParametricLoop] = (),
    worst_case: bool = False,
    x0: ArrayLike | None = None,
    starts: int = 1,
    max_iter: int = 60,
    rigorous: bool = False,
    map: Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]] = map,
) -> ParetoResponse:
    """The trade-off front of decay rate against delay margin, as data with ``.plot()``.

    The front of :func:`nrobust.design.pareto_front` (same parameters: the best certified
    decay rate of ``loop`` under each required margin of ``required``, within ``bounds``, with
    the windows ``delays`` and the ``scenarios``; with ``worst_case`` the least rate of the loop and the
    scenarios), wrapped so that
    ``pareto_response(loop, bounds, required).plot()`` draws it (:func:`pareto_plot`).

    Returns
    -------
    ParetoResponse
        ``front`` (the :class:`~nrobust.design.pareto.ParetoFront`) and ``.plot(ax=None,
        annotate=True)``.
    """
    front = pareto_front(
        loop,
        bounds,
        required,
        delays=delays,
        scenarios=scenarios,
        worst_case=worst_case,
        x0=x0,
        starts=starts,
        max_iter=max_iter,
        rigorous=rigorous,
        map=map,
    )
    return ParetoResponse(front)


def pareto_plot(front: ParetoFront, ax: Axes | None = None, annotate: bool = True) -> NrobustPlot:
    """Best decay rate against required delay margin: a front of certified local designs.

    Parameters
    ----------
    front : ParetoFront
        From :func:`nrobust.design.pareto_front` or
        :func:`nrobust.hyperbolic.analyses.filtered_front`.
    ax : matplotlib Axes, optional
    annotate : bool
        Write each design's parameters next to its point.

    Returns
    -------
    NrobustPlot
        ``lines["front"]`` with x = the designs' delay margins (the infinite ones at the
        largest requirement, drawn hollow) and y = their decay rates (with :attr:`ParetoFront.worst_case` the
        least rates of the loop and the scenarios, as the axis says); ``lines["required"]``
        the requirements; ``lines["windows"]`` the windows of delays every design is stable on
        too (shaded; :attr:`ParetoFront.delays`). The title names the scenarios held to the
        requirements (:attr:`ParetoFront.scenarios`).
    """
    ax = get_axes(ax)
    m = np.asarray(front.margins, dtype=float)
    r = np.asarray(front.decay_rates, dtype=float)
    d = np.asarray(front.required, dtype=float)
    finite = np.isfinite(m)
    x = np.where(finite, m, d)
    lines: dict[str, list[Any]] = {}
    lines["front"] = ax.plot(x, r, "o-", color="C0", ms=5, label="designs (certified, local optima)")
    lines["required"] = ax.plot(d, r, "|", color="C3", ms=10, label="required margin")
    windows = tuple(front.delays)
    lines["windows"] = [
        ax.axvspan(lo, hi, color="0.85", zorder=0, label="required window" if n == 0 else None)
        for n, (lo, hi) in enumerate(windows)
    ]
    if np.any(~finite):
        ax.plot(x[~finite], r[~finite], "o", mfc="white", color="C0", label="stable for every delay")
    if annotate:
        for xi, yi, design in zip(x, r, front.designs):
            label = ", ".join(f"{v:.3g}" for v in design.parameters)
            ax.annotate(f"({label})", (xi, yi), textcoords="offset points", xytext=(4, 4), fontsize=6)
    ax.set_xlabel("delay margin delta*")
    least = bool(front.worst_case)
    ax.set_ylabel("least decay rate of the loop and the scenarios" if least else "decay rate (- spectral abscissa)")
    title = f"Best {'least ' if least else ''}decay rate under a required delay margin"
    if windows:
        title += " and stable on " + ", ".join(f"[{float(lo)!r}, {float(hi)!r}]" for lo, hi in windows)
    scenarios = tuple(front.scenarios)
    if scenarios:
        title += f"\n(the loop and {len(scenarios)} scenarios)"
    ax.set_title(title, fontsize="small")
    ax.legend(fontsize="small")
    return NrobustPlot(lines, ax, ax.figure)
