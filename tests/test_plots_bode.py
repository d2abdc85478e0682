"""Bode plots of delayed loops: the response against the closed form, the margins at their exact frequencies."""

from __future__ import annotations

import time

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest

from nrobust.errors import ParameterError
from nrobust.lti import delay, tf
from nrobust.plots import bode_plot, bode_response
from nrobust.plots.bode import MAX_BODE_POINTS


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def _loop():
    return 2.0 * delay(0.1) * tf([1.0], [1.0, 1.0])  # L = 2 e^{-0.1 s} / (s + 1)


def test_response_is_the_closed_form_unwrapped():
    r = bode_response(_loop(), (1e-2, 1e3))
    w = r.omega
    np.testing.assert_allclose(w[[0, -1]], [1e-2, 1e3], rtol=1e-12)
    # |L| = 2 / sqrt(1 + w^2) and arg L = -0.1 w - atan w, continuous (no 360 deg jumps): rounding only
    np.testing.assert_allclose(r.magnitude, 2.0 / np.sqrt(1.0 + w**2), rtol=1e-13)
    np.testing.assert_allclose(r.phase, np.degrees(-0.1 * w - np.arctan(w)), rtol=0, atol=1e-9)
    # the delay's phase moves by at most pi/8 between samples, atan w by at most 0.34 deg (samples 1.2 % apart)
    assert np.max(np.abs(np.diff(r.phase))) < 22.5 + 0.34


def test_crossovers_drawn_at_the_exact_margins():
    """|L| = 1 at w = sqrt 3 (PM = 180 - 0.1 sqrt 3 - 60 deg); phase crossovers where 0.1 w + atan w = (2k + 1) pi,
    each with gain margin sqrt(1 + w^2) / 2 (Brent's xtol 1e-12)."""
    p = bode_plot(_loop(), (1e-2, 200.0))
    gain = p.lines["gain_crossovers"]
    assert len(gain) == 2  # one line on each panel
    np.testing.assert_allclose(gain[0].get_xdata()[0], np.sqrt(3.0), rtol=1e-12)
    pm = 180.0 - np.degrees(0.1 * np.sqrt(3.0)) - 60.0
    assert f"PM {pm:.4g} deg" in gain[0].get_label()
    phase = p.lines["phase_crossovers"][::2]
    ws = np.array([line.get_xdata()[0] for line in phase])
    assert ws.size >= 2
    k = np.arange(ws.size)
    np.testing.assert_allclose(0.1 * ws + np.arctan(ws), (2 * k + 1) * np.pi, rtol=1e-12)
    assert f"GM {np.sqrt(1 + ws[0] ** 2) / 2:.4g} at" in phase[0].get_label()
    assert p.lines["phase_axes"][0].get_ylabel() == "arg L(i w) (deg)"


def test_a_loop_without_margins_is_drawn_with_the_reason():
    """``|L| -> 2`` at high frequency (a neutral loop): allmargin refuses it, the response is still drawn."""
    L = tf([2.0, 1.0], [1.0, 1.0]) * delay(1.0)
    r = bode_response(L, (0.1, 10.0))
    assert r.margins is None and "no margins" in r.note
    p = r.plot()
    assert any("no margins" in t.get_text() for t in p.axes.texts)
    np.testing.assert_allclose(r.magnitude, np.abs((2j * r.omega + 1) / (1j * r.omega + 1)), rtol=1e-13)


def test_bad_bands_are_refused_before_any_grid():
    with pytest.raises(ParameterError, match="omega_limits"):
        bode_response(_loop(), (10.0, 1.0))
    start = time.process_time()
    with pytest.raises(ParameterError, match="MAX_BODE_POINTS"):
        bode_response(_loop(), (1e-3, 1e9), margins=False)
    assert time.process_time() - start < 1.0
    assert MAX_BODE_POINTS == 1_000_000
