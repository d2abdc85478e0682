"""Accuracies of allmargin, honest reprs of abscissae and poles, the default step horizon,
and python-control interoperation of delay systems.

The loop throughout is ``L = 0.5 e^{-0.5 s} / (s (s + 1))`` under negative unit feedback.
"""

from __future__ import annotations

import re

import mpmath
import numpy as np
import pytest

import nrobust
from nrobust.lti import allmargin, delay, step_response, tf

mpmath.mp.dps = 30


def loop() -> nrobust.lti.DelayLTI:
    return 0.5 * delay(0.5) * tf([1.0], [1.0, 1.0, 0.0])


def closed_form_margins() -> dict[str, list[float]]:
    """Crossings of ``L(i w) = 0.5 e^{-0.5 i w} / (i w (i w + 1))`` solved with mpmath at 30 digits.

    Gain crossover: ``|L| = 1`` iff ``w^2 (w^2 + 1) = 1/4``, so ``w^2 = (sqrt 2 - 1) / 2``;
    there ``PM = pi/2 - atan w - w/2`` and ``DM = PM / w``. Phase crossovers:
    ``angle L = -pi/2 - atan w - w/2 = -(2k + 1) pi``, gain margin ``2 w sqrt(w^2 + 1)``.
    """
    wc = mpmath.sqrt((mpmath.sqrt(2) - 1) / 2)
    pm = mpmath.pi / 2 - mpmath.atan(wc) - wc / 2
    w180 = mpmath.findroot(lambda w: mpmath.atan(w) + w / 2 - mpmath.pi / 2, 1.3)
    gm = 2 * w180 * mpmath.sqrt(w180**2 + 1)
    return {
        "wc": [float(wc)],
        "pm": [float(pm * 180 / mpmath.pi)],
        "dm": [float(pm / wc)],
        "w180": [float(w180)],
        "gm": [float(gm)],
    }


def test_allmargin_carries_accuracies_that_hold_against_closed_forms() -> None:
    m = allmargin(loop())
    exact = closed_form_margins()
    pairs = [
        (m.pm_frequencies, m.pm_frequency_accuracies, exact["wc"]),
        (m.phase_margins, m.phase_margin_accuracies, exact["pm"]),
        (m.delay_margins, m.delay_margin_accuracies, exact["dm"]),
        (m.gm_frequencies, m.gm_frequency_accuracies, exact["w180"]),
        (m.gain_margins, m.gain_margin_accuracies, exact["gm"]),
    ]
    for value, accuracy, truth in pairs:
        # the stated accuracy bounds the true error (the closed form at 30 digits) ...
        assert np.all(np.abs(value - np.array(truth)) <= accuracy)
        # ... and is informative: a few hundred roundings at most, not a vacuous bound
        np.testing.assert_array_less(accuracy, 1e-12 * (1.0 + np.abs(value)) * 100)
    np.testing.assert_array_equal(m.dm_frequencies, m.pm_frequencies)
    text = repr(m)
    for value, accuracy, _ in pairs:
        assert nrobust.with_accuracy(float(value[0]), float(accuracy[0])) in text
    assert "accuracy not estimated" not in text


def rightmost_closed_loop_pole() -> mpmath.mpc:
    """The rightmost zero of ``s (s + 1) + 0.5 e^{-0.5 s}`` (the closed loop ``L / (1 + L)``), 30 digits."""
    return mpmath.findroot(lambda s: s * (s + 1) + 0.5 * mpmath.exp(-0.5 * s), mpmath.mpc(-0.353, 0.585))


def printed_bound(text: str, label: str) -> float:
    match = re.search(re.escape(label) + r" (-?[0-9.e+-]+)", text)
    assert match is not None, text
    return float(match.group(1))


@pytest.mark.parametrize("rigorous", [False, True])
def test_spectral_abscissa_repr_separates_the_certified_bound_from_the_estimate(rigorous: bool) -> None:
    sa = loop().feedback(1).spectral_abscissa(rigorous=rigorous)
    exact = float(rightmost_closed_loop_pole().real)
    assert sa.accuracy is not None and abs(sa.value - exact) <= sa.accuracy
    text = repr(sa)
    kind = "proven" if rigorous else "floating point"
    assert f"value={nrobust.with_accuracy(sa.value, sa.accuracy)} ({kind})" in text
    # the certified statement, its bound printed to 6 digits rounded up: still true as printed
    bound = printed_bound(text, "certified: no root right of")
    assert sa.upper_bound <= bound <= sa.upper_bound + 1e-5 * abs(sa.upper_bound)
    assert exact <= bound
    assert "upper_bound=" not in text  # no bare number whose status the reader must guess
    if rigorous:
        match = re.search(r"proven: sup Re s in \[(\S+), (\S+)\]", text)
        assert match is not None
        assert float(match.group(1)) <= exact <= float(match.group(2))


def test_poles_table_prints_each_pole_with_its_estimate_and_the_certified_radius_apart() -> None:
    poles = loop().feedback(1).poles()
    table = str(poles)
    rows = [line for line in table.splitlines() if re.match(r"^\s+\d+\s", line)]
    assert len(rows) == len(poles) == 2
    exact = rightmost_closed_loop_pole()
    for row, z, e, radius in zip(rows, poles.roots, poles.estimates, poles.radii):
        # a root of the pair: the floating-point estimate holds against the 30-digit root
        assert abs(z.real - float(exact.real)) <= e and abs(abs(z.imag) - float(exact.imag)) <= e
        assert radius < 1e-3 and e < 1e-12  # the estimate is far tighter than the certified disc
        cells = re.match(r"^\s+\d+\s+(\S+) \+- (\S+)\s+(\S+) \+- (\S+)\s+(\d+)\s+(\S+)\s+(\S+)$", row)
        assert cells is not None, row  # every printed digit of the root comes with its accuracy
        assert cells.group(1) + " +- " + cells.group(2) == nrobust.with_accuracy(float(z.real), float(e))
        assert float(cells.group(7)) >= radius  # the certified radius, rounded up
    assert "floating point" in table and "certified radius" in table


def test_default_step_horizon_covers_the_two_percent_settling_time() -> None:
    T = loop().feedback(1)
    long = step_response(T, np.linspace(0.0, 60.0, 6001))
    y = np.asarray(long.outputs)
    # settled by t = 60: the slowest mode e^{-0.353 t} is below 1e-9 there, and T(0) = 1 (integrator)
    np.testing.assert_allclose(y[-1], 1.0, atol=1e-7)
    outside = np.flatnonzero(np.abs(y - 1.0) > 0.02)
    settling = float(long.time[outside[-1] + 1])
    assert settling > 20 * 0.5  # the former default horizon, 20 max(tau), ends before it
    default = step_response(T)
    assert default.time[-1] >= settling
    # the rule: ln(1000) / |alpha|, alpha the closed form's rightmost pole
    np.testing.assert_allclose(default.time[-1], np.log(1000.0) / -float(rightmost_closed_loop_pole().real), rtol=1e-9)


def test_default_horizon_of_a_delay_free_system_is_python_controls() -> None:
    control = pytest.importorskip("control")
    G = control.tf([1.0], [1.0, 0.2, 4.0])  # slowest mode e^{-0.1 t}
    np.testing.assert_allclose(step_response(G).time[-1], control.step_response(G).time[-1], rtol=1e-9)


def test_to_frd_hands_a_delay_loop_to_python_controls_plots_and_margins() -> None:
    control = pytest.importorskip("control")
    pytest.importorskip("matplotlib")
    import matplotlib.pyplot as plt

    L = loop()
    F = L.to_frd(np.logspace(-2, 2, 400), name="L")
    control.bode_plot(F)  # python-control 0.10 titles the figure with the system's name
    plt.close("all")
    gm, pm, wpc, wgc = control.margin(F)
    exact = closed_form_margins()
    # read off a grid of 100 points per decade: a few 1e-4 relative, not exact
    np.testing.assert_allclose(
        [gm, pm, wpc, wgc], [exact["gm"][0], exact["pm"][0], exact["w180"][0], exact["wc"][0]], rtol=1e-3
    )
