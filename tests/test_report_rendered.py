"""Figures drawn elsewhere (a worker process) and embedded by write_report: the same report as drawn in place."""

from __future__ import annotations

import pickle

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import pytest

from nrobust.errors import ParameterError
from nrobust.hyperbolic import ReflectionController, TransportSystem
from nrobust.plots.base import figure_png
from nrobust.reports.certificate import certify
from nrobust.reports.report import RenderedFigures, render_certificate_figures, write_report

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def cert():
    # |K q| < 1 - |rho q|: an infinite margin, a quick certificate
    return certify(TransportSystem(1.0, 1.0, 1.0, 0.5), ReflectionController(0.1), 0.1, k_region=False)


def test_rendered_figures_give_the_report_drawn_in_place(cert, tmp_path):
    rendered = pickle.loads(pickle.dumps(render_certificate_figures(cert)))  # as sent back by a worker
    assert all(png.startswith(PNG_SIGNATURE) for _, png in rendered.pngs)
    fig, ax = plt.subplots()
    ax.plot([0.0, 1.0], [1.0, 0.0])
    fig.subplots_adjust(left=0.15, right=0.95, bottom=0.15, top=0.9)
    extra = figure_png(fig)
    assert fig.get_layout_engine() is None  # laid out by hand: drawn once, no layout engine set
    plt.close(fig)
    here = write_report(cert, tmp_path / "here", figures=[("a line", extra)])
    there = write_report(cert, tmp_path / "there", figures=[("a line", extra)], rendered=[rendered])
    assert there.markdown.read_text() == here.markdown.read_text()
    assert [p.name for p in there.figures] == [p.name for p in here.figures]
    written = [p.read_bytes() for p in there.figures]
    assert written == [png for _, png in rendered.pngs] + [extra]


def test_rendered_figures_are_checked(cert, tmp_path):
    with pytest.raises(ParameterError, match="rendered"):
        write_report(cert, tmp_path, rendered=[])
    with pytest.raises(ParameterError, match="rendered"):
        write_report(cert, tmp_path, rendered=[RenderedFigures((), None), RenderedFigures((), None)])
    with pytest.raises(ParameterError, match=r"figures\[0\]"):
        write_report(cert, tmp_path, figures=[("not a figure", "image.png")])
