"""Nyquist plots of loops with poles on the imaginary axis: indentation, clipping, arrows, labels
(rendered with the Agg backend).

The loop ``L = e^{-s} / (s (s + 1))`` (an integrator, a lag and a unit delay) has closed forms:
``|L(i w)| = 1 / (w sqrt(1 + w^2))`` and ``arg L(i w) = -pi/2 - atan(w) - w``; its unit-circle and
negative-real-axis crossings are solved here by ``scipy.optimize.brentq`` on them.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import json

import control
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.text import Annotation
from scipy.optimize import brentq

from nrobust import plots
from nrobust.errors import ParameterError
from nrobust.lti import delay
from nrobust.quasipoly import QuasiPolynomial as Q

A_INT = Q([[0.0, 1.0, 1.0]], [0.0])  # s (s + 1)
B_ONE = Q([[1.0]], [0.0])
R, OFFSET = 10.0, 0.02


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def response():
    return plots.nyquist_response(A_INT, B_ONE, delta=1.0, omega_max=20.0, n_freq=1001)


def _loop(w: float) -> complex:
    s = 1j * w
    return complex(np.exp(-s) / (s * (s + 1)))


def test_the_contour_skirts_the_integrator(response):
    """A quarter circle of radius 1e-4 on the right of s = 0, then the axis: no infinite value."""
    r = response.indent_radius
    assert r == 1e-4 and response.axis_poles.tolist() == [0.0]
    arc = response.contour[np.abs(response.contour) < 1.5 * r]
    np.testing.assert_allclose(np.abs(arc), r, rtol=1e-15, atol=0)
    assert response.contour[0] == r and np.all(np.diff(np.angle(arc)) > 0)
    assert np.all(np.isfinite(response.loop))
    np.testing.assert_array_equal(response.omega, response.contour.imag)
    on_axis = response.contour.real == 0.0
    s = response.contour[on_axis]
    np.testing.assert_allclose(response.loop[on_axis], np.exp(-s) / (s * (s + 1)), rtol=1e-14, atol=0)
    # the image of the quarter circle: |L| ~ 1/r, turning from arg 0 to about -pi/2
    assert np.angle(response.loop[0]) == 0.0 and abs(response.loop[0]) > 0.9 / r
    assert response.rhp_zeros == 0
    assert json.loads(json.dumps(response.to_dict()))["axis_poles"] == [0.0]


def test_limits_hold_the_critical_point_within_the_clipping_radius(response):
    out = response.plot(max_curve_magnitude=R, max_curve_offset=OFFSET)
    (x0, x1), (y0, y1) = out.axes.get_xlim(), out.axes.get_ylim()
    assert x0 < -1.0 < x1 and y0 < 0.0 < y1
    # padding 5 % of the larger side (2 R (1 + offset)) beyond the drawn curve
    assert max(abs(x0), abs(x1), abs(y0), abs(y1)) <= 1.1 * R * (1 + OFFSET)
    assert list(out.lines["critical"][0].get_xdata()) == [-1.0]


def test_clipped_stretches_are_dashed_on_the_circle(response):
    out = response.plot(max_curve_magnitude=R, max_curve_offset=OFFSET)
    assert len(out.lines["clipped"]) >= 1 and len(out.lines["clipped_mirror"]) == len(out.lines["clipped"])
    for line, mirror in zip(out.lines["clipped"], out.lines["clipped_mirror"]):
        assert line.get_linestyle() == "-." and mirror.get_linestyle() == ":"
        inner = np.hypot(line.get_xdata(), line.get_ydata())[1:-1]  # the ends join the unclipped curve
        assert np.all(inner >= R * (1 - 1e-12)) and np.all(inner <= R * (1 + OFFSET) * (1 + 1e-12))
        inner_m = np.hypot(mirror.get_xdata(), mirror.get_ydata())[1:-1]
        assert np.all(inner_m <= R * (1 + 1e-12)) and np.all(inner_m >= R * (1 - OFFSET) * (1 - 1e-12))
    # the solid branch has gaps (nan) where clipped and keeps |L| <= R elsewhere
    x, y = out.lines["loop"][0].get_xdata(), out.lines["loop"][0].get_ydata()
    assert np.any(np.isnan(x)) and np.nanmax(np.hypot(x, y)) <= R


def test_arrows_follow_increasing_frequency(response):
    out = response.plot(max_curve_magnitude=R, arrows=2)
    drawn = [a for a in out.axes.texts if isinstance(a, Annotation) and a.arrow_patch is not None]
    assert len(drawn) == len(out.lines["arrows"])
    runs = len(out.lines["clipped"])
    assert len(drawn) == 2 * (2 + runs)  # two per branch, one per clipped stretch, on both branches
    # on the clipped image of the quarter circle (arg from 0 to about -pi/2) the branch turns clockwise
    turning = [
        a for a in out.lines["arrows"][: 2 + runs] if np.hypot(*a.xy) > R * 0.99 and np.hypot(*a.xyann) > R * 0.99
    ]
    assert turning
    for a in turning:
        assert np.angle(complex(*a.xy)) < np.angle(complex(*a.xyann))


def test_unit_circle_label_sits_at_the_crossing_frequency(response):
    """|L(i w)| = 1 at w^2 = (sqrt 5 - 1)/2 (brentq on the closed form): the certified crossing, its label."""
    wc = brentq(lambda w: 1.0 / (w * np.hypot(1.0, w)) - 1.0, 0.1, 2.0, xtol=1e-15)
    np.testing.assert_allclose(wc, np.sqrt((np.sqrt(5) - 1) / 2), rtol=1e-15)
    # the certified search's tolerance 1e-12 max(1, w)
    np.testing.assert_allclose(response.crossings, [wc], rtol=1e-12, atol=0)
    out = response.plot()
    (label,) = out.lines["labels"]
    assert label.get_text() == f"{wc:.3g}"
    # |dL/dw| ~ 2 at wc: the point within 1e-11 of L(i wc)
    np.testing.assert_allclose(complex(*label.xy), _loop(wc), rtol=0, atol=1e-11)


def test_negative_real_axis_crossings_are_labelled(response):
    """Im L = 0 with Re L < 0 where w + atan(w) = pi/2 + 2 pi k (brentq): the first is the phase crossover."""
    exact = [
        brentq(lambda w, k=k: w + np.arctan(w) - np.pi / 2 - 2 * np.pi * k, 0.0, 20.0, xtol=1e-15) for k in range(4)
    ]
    # Brent's method on Im L (xtol 1e-14): agreement to 1e-12
    np.testing.assert_allclose(response.real_crossings, exact, rtol=1e-12, atol=0)
    np.testing.assert_allclose(response.real_crossing_values.imag, 0.0, rtol=0, atol=1e-13)
    assert np.all(response.real_crossing_values.real < 0)
    out = response.plot()
    first = out.lines["real_labels"][0]
    assert first.get_text() == f"{exact[0]:.3g}"
    np.testing.assert_allclose(complex(*first.xy), _loop(exact[0]), rtol=0, atol=1e-12)


def test_an_imaginary_pair_is_skirted_by_half_circles():
    """L = 0.5 e^{-0.3 s} / (s^2 + 1): poles at +-i, the contour goes round i on a half circle to
    the right; its image turns half a turn through Re L > 0, on the clipping circle."""
    resp = plots.nyquist_response(Q([[1.0, 0.0, 1.0]], [0.0]), Q([[0.5]], [0.0]), delta=0.3, omega_max=5.0)
    assert resp.axis_poles.tolist() == [1.0]
    near = resp.contour[np.abs(resp.contour - 1j) < 1.5e-4]
    # s - i on a circle of radius 1e-4 around a point within rounding of i (np.roots): 1e-15 absolute
    np.testing.assert_allclose(np.abs(near - 1j), 1e-4, rtol=0, atol=1e-15)
    assert np.all(near.real >= 0.0)
    out = resp.plot(max_curve_magnitude=R)
    assert len(out.lines["clipped"]) == 1


def test_loops_without_axis_poles_are_unchanged_and_bad_options_are_refused():
    A = Q([[1.0], [-0.85]], [0.0, 2.0])
    resp = plots.nyquist_response(A, Q([[0.1]], [2.0]), delta=0.1, omega_max=20.0, n_freq=501)
    assert resp.contour is None and resp.axis_poles.size == 0
    out = resp.plot()
    assert out.lines["clipped"] == [] and not np.any(np.isnan(out.lines["loop"][0].get_xdata()))
    with pytest.raises(ParameterError, match="max_curve_magnitude"):
        resp.plot(max_curve_magnitude=1.0)
    with pytest.raises(ParameterError, match="max_curve_offset"):
        resp.plot(max_curve_offset=0.5)
    with pytest.raises(ParameterError, match="indent_radius"):
        plots.nyquist_response(A_INT, B_ONE, delta=1.0, omega_max=20.0, indent_radius=5.0)
    out = plots.nyquist_plot(A_INT, B_ONE, delta=1.0, omega_max=10.0, max_curve_magnitude=4.0, arrows=1)
    assert max(np.abs(out.axes.get_xlim()).max(), np.abs(out.axes.get_ylim()).max()) <= 1.1 * 4.0 * (1 + OFFSET)


def test_a_python_control_loop_alone_is_its_factors(response):
    # e^{-s} / (s (s + 1)) built as python-control users do: the same contour, curve and count as
    # its factors (the DelayLTI's quotient is these factors times a constant, the same loop)
    L = delay(1.0) * control.tf([1.0], [1.0, 1.0, 0.0])
    alone = plots.nyquist_response(L, omega_max=20.0, n_freq=1001)
    assert alone.rhp_zeros == response.rhp_zeros == 0
    # the same samples of the same function, evaluated through differently scaled factors
    np.testing.assert_allclose(alone.loop, response.loop, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(alone.crossings, response.crossings, rtol=1e-12)
    out = plots.nyquist_plot(L, omega_max=20.0)
    x0, x1 = out.axes.get_xlim()
    assert x0 < -1.0 < x1  # the critical point is in view, the curve clipped at |L| = 10
    assert list(out.lines["critical"][0].get_xdata()) == [-1.0]
    with pytest.raises(ParameterError, match="B"):
        plots.nyquist_response(A_INT)
