"""What every plot of nrobust shares: the object a plot returns and the axes it draws on.

The rules every plot function follows (as python-control's ``ctrlplot``): an analysis
(a ``*_response`` function, or an analysis of :mod:`nrobust.hyperbolic`) computes a small
frozen data object, JSON-ready through ``to_dict()``, whose ``plot`` method draws it; a
``*_plot`` function is a thin wrapper that computes the data and calls ``plot``. A plot
computes nothing of its own: it draws what the analysis computed. Every plot takes
``ax=`` (a new figure when omitted) and returns a :class:`NrobustPlot` holding the artists
it drew, keyed by what they show, so that a test or a user can check and restyle them.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure, SubFigure

__all__ = ["NrobustPlot", "figure_png", "get_axes"]


@dataclass(frozen=True, eq=False)
class NrobustPlot:
    """What a plot function drew.

    Attributes
    ----------
    lines : dict of str to list of matplotlib artists
        The artists, keyed by what they show (``"loop"``, ``"roots"``, ``"chains"``...).
    axes : matplotlib.axes.Axes
        The Axes drawn on.
    figure : matplotlib.figure.Figure
        Its figure.
    """

    lines: dict[str, list[Any]]
    axes: Axes
    figure: Figure | SubFigure


def get_axes(ax: Axes | None) -> Axes:
    """``ax``, or the Axes of a new figure when it is None."""
    if ax is not None:
        return ax
    import matplotlib.pyplot as plt

    _, ax = plt.subplots()
    return ax


def figure_png(fig: Figure, dpi: float = 100.0) -> bytes:
    """``fig`` as PNG bytes; the tight layout unless its subplot parameters were set by hand.

    A figure laid out by ``subplots_adjust`` keeps its layout and has no layout engine, so
    it is drawn once: any layout engine makes ``savefig`` draw it twice, and the tight layout
    measures every label. Bytes can be sent between processes, so a worker can draw a
    figure that the process writing the report only embeds.
    """
    import matplotlib as mpl

    buf = io.BytesIO()
    pars = fig.subplotpars
    rc = mpl.rcParams
    sides = (rc["figure.subplot.left"], rc["figure.subplot.right"], rc["figure.subplot.bottom"])
    by_hand = (pars.left, pars.right, pars.bottom, pars.top) != (*sides, rc["figure.subplot.top"])
    if fig.get_layout_engine() is None and not by_hand:
        fig.set_layout_engine("tight")
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()
