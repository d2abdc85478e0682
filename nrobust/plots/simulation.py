"""Time-domain figures: the norms of simulated states, cut at the accuracy of the scheme."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .._validate import positive
from ..errors import ParameterError
from .base import NrobustPlot, decade_ticks, get_axes, legend_corner

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


__all__ = ["residual_floor", "simulation_figure", "simulation_plot"]


def residual_floor(results: Sequence[Any]) -> float:
    """The accuracy level of simulations: ``h^2`` times their largest norm, ``h = 1/n`` the cell size.

    The simulator is second order (:func:`nrobust.hyperbolic.simulate.simulate`): below
    this level a norm shows the scheme's residual (a staircase after a finite-time
    convergence), not the plant. :func:`simulation_plot` cuts its log axis there.
    """
    results = list(results)
    if not results:
        raise ParameterError("results", "at least one simulation result", results)
    top = max(float(np.max(np.asarray(r.norm, dtype=float))) for r in results)
    h = 1.0 / min(int(r.n) for r in results)
    return h * h * top


def simulation_plot(
    results: Sequence[Any],
    labels: Sequence[str] | None = None,
    ax: Axes | None = None,
    floor: float | str | None = "residual",
) -> NrobustPlot:
    """``L^2`` norm of simulated states against time, log scale (paper, figures 1 and 3).

    Parameters
    ----------
    results : sequence of simulation results
        Outputs of :func:`nrobust.hyperbolic.simulate.simulate` (``times``, ``norm``, ``n``).
    labels : sequence of str, optional
        One legend entry per result.
    floor : float, "residual" or None
        Bottom of the log axis: ``"residual"`` (default) cuts it at :func:`residual_floor`,
        the ``O(h^2)`` accuracy of the scheme, and says so on the plot (a norm that
        reaches 0 in finite time, as under U_BS without delay, would otherwise draw the
        scheme's residual down to ``1e-40`` and flatten every other curve); a number cuts
        it there; None keeps every positive value.

    Returns
    -------
    NrobustPlot
        ``lines["norms"]`` (one line per result), ``lines["floor"]`` (the note on the cut).
    """
    results = list(results)
    if not results:
        raise ParameterError("results", "at least one simulation result", results)
    if labels is not None and len(labels) != len(results):
        raise ParameterError("labels", f"one label per result ({len(results)})", labels)
    if floor == "residual":
        bottom: float | None = residual_floor(results)
    elif floor is None:
        bottom = None
    elif isinstance(floor, str):
        raise ParameterError("floor", 'a number > 0, "residual" or None', floor)
    else:
        bottom = positive("floor", floor)
    ax = get_axes(ax)
    lines: dict[str, list[Any]] = {"norms": [], "floor": []}
    for k, res in enumerate(results):
        t = np.asarray(res.times, dtype=float)
        y = np.asarray(res.norm, dtype=float)
        label = labels[k] if labels is not None else None
        lines["norms"] += ax.semilogy(t, np.maximum(y, np.finfo(float).tiny), label=label)
    if bottom is not None:
        norms = np.concatenate([np.asarray(r.norm, dtype=float) for r in results])
        positive_norms = norms[norms > 0.0]
        low = 0.5 * float(positive_norms.min()) if positive_norms.size else bottom
        top = float(norms.max())
        ax.set_ylim(max(bottom, low), max(3.0 * top, 10.0 * bottom))
        if low < bottom:  # something lies below the cut: say so
            what = "the scheme's O(h^2) residual" if floor == "residual" else "cut"
            lines["floor"].append(
                ax.text(
                    0.01, 0.02, f"axis cut at {bottom:.1e} ({what})", transform=ax.transAxes, fontsize=7, color="0.35"
                )
            )
    decade_ticks(ax)
    ax.set_xlabel("t")
    ax.set_ylabel("||(u, v)(t)||_L2")
    ax.grid(True, which="major", alpha=0.3)
    if labels is not None:
        ax.legend(fontsize="x-small", loc=legend_corner(ax))
    return NrobustPlot(lines, ax, ax.figure)


def simulation_figure(
    runs: Sequence[Any], labels: Sequence[str], title: str, floor: float | str | None = "residual"
) -> Figure:
    """A figure of :func:`simulation_plot` with a title (used by the reports and the paper's figures)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    simulation_plot(runs, labels=labels, ax=ax, floor=floor)
    # at the top of the axes, where Matplotlib's automatic placement puts it above a log axis (no
    # offset text, no ticks on top), without measuring every minor tick label to find out (0.1-0.2 s)
    ax.set_title(title, fontsize="small", y=1.0)
    # by hand, as a tight layout would place it: a layout engine makes savefig draw the figure twice
    fig.subplots_adjust(left=0.12, right=0.975, bottom=0.15, top=0.91)
    return fig
