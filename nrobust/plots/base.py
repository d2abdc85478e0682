"""What every plot of nrobust shares: the object a plot returns and the axes it draws on.

The rules every plot function follows (as python-control's ``ctrlplot``): an analysis
(a ``*_response`` function, or an analysis of :mod:`nrobust.hyperbolic`) computes a small
frozen data object, JSON-ready through ``to_dict()``, whose ``plot`` method draws it; a
``*_plot`` function is a thin wrapper that computes the data and calls ``plot``. A plot
computes nothing of its own: it draws what the analysis computed. Every plot takes
``ax=`` (a new figure when omitted) and returns a :class:`NrobustPlot` holding the artists
it drew, keyed by what they show, so that a test or a user can check and restyle them.

Also here: how the ``nrobust`` command imports matplotlib (:func:`skip_artist_property_docs`).
"""

from __future__ import annotations

import importlib.machinery
import io
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure, SubFigure

__all__ = [
    "NrobustPlot",
    "decade_ticks",
    "figure_png",
    "get_axes",
    "legend_corner",
    "pin_title",
    "skip_artist_property_docs",
]


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


_SUPERSCRIPT = str.maketrans("-0123456789", "\u207b\u2070\u00b9\u00b2\u00b3\u2074\u2075\u2076\u2077\u2078\u2079")


def _power_label(value: float) -> str:
    """``value`` as ``10⁻³`` or ``2`` times ``10⁻³`` (Unicode superscripts and multiplication sign)."""
    exponent = int(np.floor(np.log10(value) + 1e-9))
    coefficient = value / 10.0**exponent
    decade = "10" + str(exponent).translate(_SUPERSCRIPT)
    return decade if np.isclose(coefficient, 1.0, rtol=1e-9) else f"{coefficient:.3g}\u00d7{decade}"


def decade_ticks(ax: Axes) -> None:
    """Label ``ax``'s logarithmic y axis as ``10⁻³`` in plain text, the ticks chosen as Matplotlib does.

    Matplotlib's default labels are mathematical text, whose parser costs tenths of a second on
    the first figure a process draws; these read the same in Unicode superscripts. Which ticks
    get a label (every decade; minor ticks when the axis spans few decades) is Matplotlib's
    :class:`~matplotlib.ticker.LogFormatter` choice.
    """
    from matplotlib.ticker import LogFormatter

    class PowerFormatter(LogFormatter):
        def __call__(self, x: float, pos: int | None = None) -> str:
            return _power_label(abs(x)) if x != 0.0 and super().__call__(x, pos) else ""

    ax.yaxis.set_major_formatter(PowerFormatter())
    ax.yaxis.set_minor_formatter(PowerFormatter(labelOnlyBase=False))


#: A corner of the axes, as matplotlib's ``loc`` names it.
Corner = Literal["upper right", "upper left", "lower left", "lower right"]
#: The corners :func:`legend_corner` chooses from, in matplotlib's order for ``loc="best"``.
_CORNERS: tuple[Corner, ...] = ("upper right", "upper left", "lower left", "lower right")


def legend_corner(ax: Axes, width: float = 0.45, height: float = 0.35) -> Corner:
    """The corner of ``ax`` whose ``width x height`` box (axes fractions) holds the fewest drawn points.

    What ``loc="best"`` decides, for the four corners, from the vertices of the lines drawn in
    data coordinates: matplotlib's search also tests every line segment against nine candidate
    boxes when the figure is drawn, which on a curve of a few thousand points (a Nyquist plot)
    costs more than the rest of the figure. A text placed in axes fractions (a note) takes its
    corner. Call it once the axes' limits are final.
    """
    data = [ln.get_xydata() for ln in ax.get_lines() if ln.get_transform() == ax.transData]
    points = np.vstack(data) if data else np.zeros((0, 2))
    points = points[np.isfinite(points).all(axis=1)]
    if not points.size:
        return _CORNERS[0]
    xy = (ax.transScale + ax.transLimits).transform(points)  # data -> axes fractions
    right, top = xy[:, 0] >= 1.0 - width, xy[:, 1] >= 1.0 - height
    left, bottom = xy[:, 0] <= width, xy[:, 1] <= height
    inside = (0.0 <= xy).all(axis=1) & (xy <= 1.0).all(axis=1)
    counts = [int(np.sum(inside & a & b)) for a, b in ((right, top), (left, top), (left, bottom), (right, bottom))]
    # a note placed in axes fractions (the simulation plot's "axis cut at ..."): its corner is taken
    for note in (t for t in ax.texts if t.get_transform() == ax.transAxes and t.get_text()):
        nx, ny = note.get_position()
        for k, (cx, cy) in enumerate(
            (
                (nx >= 1.0 - width, ny >= 1.0 - height),
                (nx <= width, ny >= 1.0 - height),
                (nx <= width, ny <= height),
                (nx >= 1.0 - width, ny <= height),
            )
        ):
            if cx and cy:
                counts[k] = len(xy) + 1
    return _CORNERS[counts.index(min(counts))]


def pin_title(ax: Axes) -> None:
    """Place ``ax``'s title once, at the top of the axes, when Matplotlib would place it there.

    At each draw, Matplotlib lifts a title above what may stand over the axes (tick labels or
    the label of the x axis on top, the offset text of the y axis such as ``1e6``), measuring
    every y tick label to find out: 0.02-0.05 s of CPU per titled axes. When none of these is
    there (the x axis at the bottom, no offset text at the axes' final limits, no inset axes),
    the title stays at the top of the axes: pinned there, it is drawn at the same pixels without
    the measure. Call it once the axes' limits are final, on axes without twins.
    """
    x = ax.xaxis
    if x.get_ticks_position() in ("top", "unknown") or x.get_label_position() == "top" or ax.child_axes:
        return
    formatter = ax.yaxis.get_major_formatter()
    formatter.set_locs(list(ax.yaxis.get_majorticklocs()))
    if formatter.get_offset():
        return
    ax.set_title(ax.get_title(), fontsize=ax.title.get_fontsize(), y=1.0)


#: zlib level of :func:`figure_png` (Pillow's default is 6): the nine figures of ``nrobust paper``
#: are encoded in 0.14 s of CPU instead of 0.21 s, in 2.7 % more bytes.
_PNG_COMPRESS_LEVEL = 3


def figure_png(fig: Figure, dpi: float = 100.0) -> bytes:
    """``fig`` as PNG bytes; the tight layout unless its subplot parameters were set by hand.

    A figure laid out by ``subplots_adjust`` keeps its layout and has no layout engine, so
    it is drawn once: any layout engine makes ``savefig`` draw it twice, and the tight layout
    measures every label. Bytes can be sent between processes, so a worker can draw a
    figure that the process writing the report only embeds. The PNG is compressed at zlib
    level 3: the same pixels as Pillow's default level 6 in a third less encoding time,
    for a file about 3 % larger.
    """
    import matplotlib as mpl

    buf = io.BytesIO()
    pars = fig.subplotpars
    rc = mpl.rcParams
    sides = (rc["figure.subplot.left"], rc["figure.subplot.right"], rc["figure.subplot.bottom"])
    by_hand = (pars.left, pars.right, pars.bottom, pars.top) != (*sides, rc["figure.subplot.top"])
    if fig.get_layout_engine() is None and not by_hand:
        fig.set_layout_engine("tight")
    fig.savefig(buf, format="png", dpi=dpi, pil_kwargs={"compress_level": _PNG_COMPRESS_LEVEL})
    return buf.getvalue()


# ---------------------------------------------------------------- matplotlib's import in the command
# Matplotlib writes, for each of its hundred ``Artist`` subclasses, the signature and the docstring
# of its ``set`` method: a keyword per property, found by inspecting every setter's signature, and
# the list of the properties, each read from its setter's docstring (:func:`matplotlib.artist.kwdoc`).
# That is about a third of the time ``import matplotlib.pyplot`` takes (0.3 s of CPU), spent on what
# only ``help()`` and ``inspect.signature`` show. The ``nrobust`` command never shows them, so its
# process has :func:`matplotlib.artist.kwdoc` return an empty string and each subclass keep the
# generic ``set(**kwargs)``, which accepts the same properties; what matplotlib draws does not
# depend on either. A library user's process is left as it is.


class _ArtistDocsFinder:
    """Finds ``matplotlib.artist`` as the standard finder does, and has it load without property lists or signatures.

    A meta path finder (:class:`importlib.abc.MetaPathFinder`'s protocol, without importing
    :mod:`importlib.abc`, whose import costs a command 0.02 s).
    """

    def find_spec(self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None) -> Any:
        if fullname != "matplotlib.artist":
            return None
        sys.meta_path.remove(self)  # once: the module is found below
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        loader = None if spec is None else spec.loader
        if loader is None or not hasattr(loader, "exec_module"):
            return spec
        execute = loader.exec_module

        def exec_module(module: ModuleType) -> None:
            execute(module)  # Artist's own docstring is written here; its subclasses come later
            if callable(getattr(module, "kwdoc", None)):
                module.kwdoc = _no_property_list  # type: ignore[attr-defined]
            artist = getattr(module, "Artist", None)
            if callable(getattr(artist, "_update_set_signature_and_docstring", None)):
                artist._update_set_signature_and_docstring = classmethod(_generic_set)  # type: ignore[union-attr]

        loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


def _no_property_list(artist: Any) -> str:
    """What :func:`matplotlib.artist.kwdoc` returns in the command's process: no property list."""
    return ""


def _generic_set(cls: Any) -> None:
    """A subclass's ``set`` in the command's process: ``Artist.set(**kwargs)``, without a signature of its own.

    The mark matplotlib puts on a generated ``set`` is kept, so that a subclass of the
    subclass also gets the generic ``set`` (a class that defines its own is left alone).
    """
    cls.set._autogenerated_signature = True


def skip_artist_property_docs() -> None:
    """Have a later ``import matplotlib`` in this process skip the artists' property lists and ``set`` signatures.

    Nothing is imported here (a command that stops at an input error never loads matplotlib);
    nothing changes when matplotlib is already loaded.
    """
    if "matplotlib.artist" not in sys.modules and not any(isinstance(f, _ArtistDocsFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, _ArtistDocsFinder())
