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

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure, SubFigure

__all__ = ["NrobustPlot", "get_axes"]


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
