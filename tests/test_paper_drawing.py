"""What ``nrobust paper`` does to draw faster draws the same: pinned titles, matplotlib without its property lists."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import matplotlib.pyplot as plt
import numpy as np

from nrobust.plots.base import figure_png, pin_title

#: A title as wide as the axes: over the y axis's offset text when there is one.
_TITLE = "a title as wide as the axes, over the offset text of the y axis"


def _titled(y: np.ndarray, pin: bool) -> tuple[bytes, float]:
    """A titled axes drawing ``y`` laid out by hand, as PNG, and where its title ended (axes units)."""
    fig, ax = plt.subplots(figsize=(4.0, 3.0))
    ax.plot(np.arange(y.size), y, label="y")
    ax.legend(loc="upper left")
    ax.set_title(_TITLE, fontsize="small")
    fig.subplots_adjust(left=0.2, right=0.95, bottom=0.15, top=0.85)
    if pin:
        pin_title(ax)
    try:
        return figure_png(fig), ax.title.get_position()[1]
    finally:
        plt.close(fig)


def test_a_pinned_title_is_drawn_at_the_same_pixels():
    y = np.linspace(-30.0, 30.0, 50)
    plain, _ = _titled(y, pin=False)
    pinned, _ = _titled(y, pin=True)
    assert pinned == plain


def test_a_title_below_an_offset_text_is_left_to_matplotlib():
    # values near 1e7 with a span of 1: the y axis shows an offset text above the axes, under the title;
    # Matplotlib lifts the title above it (y > 1), which a pinned title would not do
    y = 1e7 + np.linspace(0.0, 1.0, 50)
    plain, lifted = _titled(y, pin=False)
    pinned, kept = _titled(y, pin=True)
    assert lifted > 1.0
    assert kept == lifted
    assert pinned == plain


def test_matplotlib_without_property_lists_draws_the_same():
    # in a fresh process (matplotlib loaded after the finder is installed), the artists' set() lose their
    # property lists and their keyword signatures and nothing else: set() takes the same properties, and
    # the PNG is that of a process with them
    script = textwrap.dedent(
        """
        import hashlib, inspect, sys
        if sys.argv[1] == "lean":
            from nrobust.plots.base import skip_artist_property_docs
            skip_artist_property_docs()
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.lines import Line2D
        from nrobust.plots.base import figure_png
        fig, ax = plt.subplots()
        (line,) = ax.plot([0, 1, 2], [0, 1, 4], "o-", label="x")
        line.set(color="C3", lw=2.5, markersize=9)
        ax.legend()
        ax.set_title("t")
        keywords = "linewidth" in inspect.signature(Line2D.set).parameters
        print("Properties:" in (Line2D.set.__doc__ or ""), keywords, hashlib.sha256(figure_png(fig)).hexdigest())
        """
    )
    runs = {
        mode: subprocess.run(
            [sys.executable, "-c", script, mode], capture_output=True, text=True, check=True
        ).stdout.split()
        for mode in ("full", "lean")
    }
    assert runs["full"][:2] == ["True", "True"]
    assert runs["lean"][:2] == ["False", "False"]
    assert runs["lean"][2] == runs["full"][2]


def test_an_imported_matplotlib_is_left_as_it_is():
    from matplotlib.lines import Line2D

    from nrobust.plots.base import skip_artist_property_docs

    before = list(sys.meta_path)
    skip_artist_property_docs()
    assert sys.meta_path == before
    assert "Properties:" in (Line2D.set.__doc__ or "")
