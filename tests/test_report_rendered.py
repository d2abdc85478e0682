"""Figures drawn elsewhere (a worker process) and embedded by write_report: the same report as drawn in place."""

from __future__ import annotations

import io
import pickle

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest
from PIL import Image

from nrobust.errors import ParameterError
from nrobust.hyperbolic import FiniteTimeController, Hyperbolic2x2, ReflectionController, TransportSystem
from nrobust.plots.base import figure_png
from nrobust.reports.certificate import certify
from nrobust.reports.report import RenderedFigures, render_certificate_figures, render_nyquist_figure, write_report

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


@pytest.mark.parametrize("controller", [ReflectionController(0.1), FiniteTimeController()], ids=["U_BS2", "U_BS"])
def test_a_nyquist_figure_drawn_apart_is_the_certificates(controller):
    # nrobust paper draws U_BS's Nyquist figure in one worker while another certifies the loop: the two
    # parts make the figures of the certificate, byte for byte, with its Nyquist count (U_BS: none finite,
    # its chain in Re s > 0 at delta = 0.01; U_BS2 at 0.1: a finite count)
    system = Hyperbolic2x2(lam=1.0, mu=1.0, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)
    cert = certify(system, controller, 0.1 if isinstance(controller, ReflectionController) else 0.01, k_region=False)
    whole = render_certificate_figures(cert)
    roots = render_certificate_figures(cert, nyquist=False)
    nyquist = render_nyquist_figure(system, controller, cert.delta_max)
    assert len(whole.pngs) == 2 and len(roots.pngs) == len(nyquist.pngs) == 1 and roots.rhp_zeros is None
    assert roots.pngs + nyquist.pngs == whole.pngs
    assert nyquist.rhp_zeros == whole.rhp_zeros
    assert (whole.rhp_zeros is None) == isinstance(controller, FiniteTimeController)


def test_rendered_figures_are_checked(cert, tmp_path):
    with pytest.raises(ParameterError, match="rendered"):
        write_report(cert, tmp_path, rendered=[])
    with pytest.raises(ParameterError, match="rendered"):
        write_report(cert, tmp_path, rendered=[RenderedFigures((), None), RenderedFigures((), None)])
    with pytest.raises(ParameterError, match=r"figures\[0\]"):
        write_report(cert, tmp_path, figures=[("not a figure", "image.png")])


def test_figure_png_is_lossless():
    # the faster zlib level changes the bytes, never the pixels: figure_png decodes to the canvas drawn
    fig, ax = plt.subplots(figsize=(3.0, 2.0))
    ax.plot([0.0, 1.0, 2.0], [1.0, 0.0, 0.5], label="a line")
    ax.legend(loc="upper right")
    fig.subplots_adjust(left=0.15, right=0.95, bottom=0.15, top=0.9)
    png = figure_png(fig)
    drawn = np.asarray(fig.canvas.buffer_rgba())
    plt.close(fig)
    decoded = np.asarray(Image.open(io.BytesIO(png)).convert("RGBA"))
    assert decoded.shape == drawn.shape
    assert np.array_equal(decoded, drawn)  # exact: PNG is lossless at every zlib level
