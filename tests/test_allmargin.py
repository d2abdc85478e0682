"""allmargin and loop_delay_margin: closed forms of loops with dead time, python-control on delay-free loops."""

from __future__ import annotations

import json

import control
import numpy as np
import pytest
from scipy.optimize import brentq

import nrobust
from nrobust import QuasiPolynomial
from nrobust.errors import ParameterError
from nrobust.lti import DelayLTI, QuasiTransferFunction, allmargin, delay, loop_delay_margin, tf


def fopdt(k: float, T: float, L: float) -> DelayLTI:
    """``k e^{-L s} / (T s + 1)``."""
    return k * delay(L) * tf([1.0], [T, 1.0])


@pytest.mark.parametrize(("k", "T", "L"), [(2.0, 1.0, 0.1), (5.0, 0.5, 0.2), (1.5, 2.0, 0.7), (5.0, 0.5, 0.5)])
def test_first_order_plus_dead_time_closed_forms(k: float, T: float, L: float) -> None:
    m = allmargin(fopdt(k, T, L))
    wc = np.sqrt(k**2 - 1.0) / T  # |L(i w)| = 1
    pm = np.pi - L * wc - np.arctan(T * wc)  # phase margin, radians
    np.testing.assert_allclose(m.pm_frequencies, [wc], rtol=1e-12)
    np.testing.assert_allclose(np.radians(m.phase_margins), [pm], rtol=1e-11)
    np.testing.assert_allclose(m.delay_margins, [np.mod(pm, 2 * np.pi) / wc], rtol=1e-11)
    # phase crossovers: L w + atan(T w) = (2j + 1) pi, gain margin sqrt(1 + T^2 w^2) / k
    w180 = [
        brentq(lambda w, j=j: L * w + np.arctan(T * w) - (2 * j + 1) * np.pi, 1e-9, 1e9, xtol=1e-15) for j in range(3)
    ]
    np.testing.assert_allclose(m.gm_frequencies[:3], w180, rtol=1e-11)
    np.testing.assert_allclose(m.gain_margins[:3], np.sqrt(1 + (T * np.array(w180)) ** 2) / k, rtol=1e-11)
    # every listed phase crossover has |L| >= gain_floor or lies inside the proven band
    assert np.all(m.gm_frequencies <= m.phase_band)
    # the closed loop is stable iff the dead time is below the delay margin
    dm0 = (np.pi - np.arctan(T * wc)) / wc  # delay margin of the delay-free loop
    assert m.stable == bool(L < dm0) == bool(pm > 0)
    np.testing.assert_allclose(loop_delay_margin(k * tf([1.0], [T, 1.0])).margin, dm0, rtol=1e-10)
    json.dumps(m.to_dict(), allow_nan=False)


def test_delay_free_loops_match_python_control() -> None:
    for G in (control.tf([4.0], [1.0, 3.0, 3.0, 1.0]), control.tf([30.0, 30.0], [1.0, 2.0, 3.0, 4.0, 0.5])):
        m = allmargin(G)
        gms, pms, _, wpcs, wgcs, _ = control.stability_margins(G, returnall=True)
        keep = np.asarray(wpcs) > 0
        np.testing.assert_allclose(m.gm_frequencies, np.sort(np.asarray(wpcs)[keep]), rtol=1e-9)
        np.testing.assert_allclose(m.gain_margins, np.asarray(gms)[keep][np.argsort(np.asarray(wpcs)[keep])], rtol=1e-9)
        np.testing.assert_allclose(m.pm_frequencies, np.sort(wgcs), rtol=1e-9)
        np.testing.assert_allclose(m.phase_margins, np.asarray(pms)[np.argsort(wgcs)], rtol=1e-9)
        gm, pm, wpc, wgc = control.margin(G)  # the margins python-control reports first
        i, j = int(np.argmin(m.gain_margins)), int(np.argmin(m.phase_margins))
        np.testing.assert_allclose([m.gain_margins[i], m.gm_frequencies[i]], [gm, wpc], rtol=1e-9)
        np.testing.assert_allclose([m.phase_margins[j], m.pm_frequencies[j]], [pm, wgc], rtol=1e-9)


def test_loop_at_a_time_of_a_diagonal_mimo_loop() -> None:
    L1, L2 = fopdt(2.0, 1.0, 0.1), fopdt(1.5, 2.0, 0.7)
    both = allmargin(L1.append(L2), loop=[0, 1])
    for got, ref in zip(both, (allmargin(L1), allmargin(L2))):
        np.testing.assert_allclose(got.phase_margins, ref.phase_margins, rtol=1e-12)
        np.testing.assert_allclose(got.gain_margins[:3], ref.gain_margins[:3], rtol=1e-12)


def test_delay_margin_of_one_loop_through_the_top_level_function() -> None:
    # L = 2 / (s + 1): w = sqrt 3, delay margin (pi - atan sqrt 3) / sqrt 3 = 2 pi / (3 sqrt 3)
    H = QuasiTransferFunction(2.0, QuasiPolynomial([[1.0, 1.0]], [0.0]))
    expected = 2 * np.pi / (3 * np.sqrt(3.0))
    np.testing.assert_allclose(nrobust.delay_margin(H).margin, expected, rtol=1e-10)
    np.testing.assert_allclose(nrobust.delay_margin(tf([2.0], [1.0, 1.0])).margin, expected, rtol=1e-10)


def test_loops_without_high_frequency_roll_off_are_refused() -> None:
    with pytest.raises(ParameterError, match="falls below 1"):
        allmargin(2.0 * delay(1.0))


def test_delayed_integrator_closed_forms() -> None:
    # L = k e^{-L s} / s: gain crossover w = k, PM = pi/2 - L k; phase crossovers (pi/2 + 2 pi j) / L, GM = w / k
    k, lag = 0.5, 1.0
    m = allmargin(k * delay(lag) * tf([1.0], [1.0, 0.0]))
    np.testing.assert_allclose(m.pm_frequencies, [k], rtol=1e-12)
    np.testing.assert_allclose(np.radians(m.phase_margins), [np.pi / 2 - lag * k], rtol=1e-12)
    np.testing.assert_allclose(m.delay_margins, [(np.pi / 2 - lag * k) / k], rtol=1e-12)
    w180 = (np.pi / 2 + 2 * np.pi * np.arange(3)) / lag
    np.testing.assert_allclose(m.gm_frequencies[:3], w180, rtol=1e-12)
    np.testing.assert_allclose(m.gain_margins[:3], w180 / k, rtol=1e-12)
    assert m.stable


def test_loop_at_a_time_of_a_coupled_mimo_loop() -> None:
    # loop 0 broken, loop 1 closed: L_eff = L00 - L01 L10 / (1 + L11)
    P = control.tf([[[2.0], [0.5]], [[0.3], [1.0]]], [[[1.0, 1.0], [1.0, 2.0]], [[1.0, 1.0], [1.0, 3.0]]])
    L = DelayLTI.from_control(P) * delay(0.1).append(delay(0.2))

    def gap(w: float) -> float:
        s = 1j * w
        p = np.asarray(P(s)) * np.array([np.exp(-0.1 * s), np.exp(-0.2 * s)])
        return abs(p[0, 0] - p[0, 1] * p[1, 0] / (1 + p[1, 1])) - 1.0

    grid = np.linspace(1e-3, 10.0, 2001)
    values = np.array([gap(w) for w in grid])
    cross = [brentq(gap, grid[i], grid[i + 1], xtol=1e-15) for i in np.flatnonzero(np.diff(np.sign(values)))]
    m = allmargin(L, loop=0)
    np.testing.assert_allclose(m.pm_frequencies, cross, rtol=1e-11)


def test_double_integrator_loops_closed_forms() -> None:
    # (4 s + 1) / (4 s^2): |L(i w)| = 1 at 16 w^4 = 16 w^2 + 1, phase atan(4 w) - pi.
    # python-control 0.10 stability_margins(tf([4, 1], [4, 0, 0])) gives PM 76.34541525 deg at 1.02908551.
    wc = np.sqrt((1.0 + np.sqrt(1.25)) / 2.0)
    pm = np.arctan(4.0 * wc)
    m = allmargin(tf([4.0, 1.0], [4.0, 0.0, 0.0]))
    np.testing.assert_allclose(m.pm_frequencies, [wc], rtol=1e-12)
    np.testing.assert_allclose(np.radians(m.phase_margins), [pm], rtol=1e-11)
    np.testing.assert_allclose(m.phase_margins, [76.34541525], rtol=1e-9)
    assert m.gm_frequencies.size == 0 and m.stable
    # with a dead time 0.5: the phase atan(4 w) - pi - w / 2; crossovers w / 2 = atan(4 w) - 2 j pi
    md = allmargin(delay(0.5) * tf([4.0, 1.0], [4.0, 0.0, 0.0]))
    np.testing.assert_allclose(np.radians(md.phase_margins), [pm - 0.5 * wc], rtol=1e-11)
    np.testing.assert_allclose(md.delay_margins, [(pm - 0.5 * wc) / wc], rtol=1e-11)
    w180 = [brentq(lambda w, j=j: np.arctan(4 * w) - 0.5 * w + 2 * j * np.pi, 1.0, 1e3, xtol=1e-15) for j in range(3)]
    np.testing.assert_allclose(md.gm_frequencies[:3], w180, rtol=1e-11)
    w = np.array(w180)
    np.testing.assert_allclose(md.gain_margins[:3], 4 * w**2 / np.sqrt(16 * w**2 + 1), rtol=1e-11)
    assert md.stable


def test_degenerate_loops_are_decided_quickly() -> None:
    # the zero loop: no crossover, the closed loop is s + 1 (stable)
    m = allmargin(tf([0.0], [1.0, 1.0]))
    assert m.pm_frequencies.size == 0 and m.gm_frequencies.size == 0 and m.stable
    # 1 / (s^2 + 2) is real at every s = i w: no isolated phase crossover
    with pytest.raises(ParameterError, match="real at every w"):
        allmargin(tf([1.0], [1.0, 0.0, 2.0]))


def test_axis_pole_with_an_integrator_is_no_phase_crossover() -> None:
    """``L = 0.1 e^{-0.1 s} / (s (s^2 + 1))``: the pole ``s = i`` (phase jump, ``|L|`` infinite) is not listed.

    ``L(i w) = -0.1 i e^{-0.1 i w} / (w (1 - w^2))`` is a negative real number exactly at
    ``0.1 w = 2 pi k - pi / 2`` with ``w > 1`` (below 1 it would need ``w = 5 pi (4k + 1) > 1``), i.e.
    ``w = 15 pi, 35 pi, ...``, with gain margin ``10 w (w^2 - 1)`` (``1e6`` at ``15 pi``); the band of
    ``gain_floor=1e-7`` ends near ``w = 100``, so ``15 pi`` alone. Tolerance: Brent's ``xtol``.
    """
    got = allmargin(0.1 * delay(0.1) * tf([1.0], [1.0, 0.0, 1.0, 0.0]), gain_floor=1e-7)
    expected = [w for w in (15 * np.pi, 35 * np.pi) if w < got.phase_band]
    assert expected, got.phase_band
    np.testing.assert_allclose(got.gm_frequencies, expected, rtol=1e-10)
    np.testing.assert_allclose(got.gain_margins, [10 * w * (w * w - 1) for w in expected], rtol=1e-10)


def test_matlab_documented_allmargin_example() -> None:
    # MATLAB Control System Toolbox, allmargin reference page (mathworks.com/help/control/ref/
    # dynamicsystem.allmargin.html), first example: L = tf(25, [1 10 10 10]) gives GainMargin 3.6000
    # at GMFrequency 3.1623, PhaseMargin 29.1104 at PMFrequency 1.7844, DelayMargin 0.2847, Stable 1
    # (four decimals printed). Closed forms: the phase crossover is w^2 = 10 (the real part of the
    # denominator 10 - 10 w^2 + i w (10 - w^2) vanishes there with its imaginary part), |L| = 25 / 90.
    m = allmargin(control.tf(25.0, [1.0, 10.0, 10.0, 10.0]))
    np.testing.assert_allclose(m.gm_frequencies, [np.sqrt(10.0)], rtol=1e-12)  # refined to 1e-12
    np.testing.assert_allclose(m.gain_margins, [3.6], rtol=1e-12)
    # MATLAB's printed values, to their last digit (half a unit of the fourth decimal)
    np.testing.assert_allclose(m.phase_margins, [29.1104], rtol=0, atol=5e-5)
    np.testing.assert_allclose(m.pm_frequencies, [1.7844], rtol=0, atol=5e-5)
    np.testing.assert_allclose(m.delay_margins, [0.2847], rtol=0, atol=5e-5)
    assert m.stable


def test_delay_margin_of_a_python_control_loop_alone() -> None:
    # nrobust.delay_margin(L) with python-control's loop 2 / (s + 1): w_c = sqrt 3 and the margin
    # (pi - atan sqrt 3) / sqrt 3 = 2 pi / (3 sqrt 3) in closed form; the same as loop_delay_margin
    for L in (control.tf([2.0], [1.0, 1.0]), control.ss(-1.0, 1.0, 2.0, 0.0)):
        got = nrobust.delay_margin(L)
        # the margin is refined by Newton to rounding; 1e-10 leaves room for its stopping rule
        np.testing.assert_allclose(got.margin, 2 * np.pi / (3 * np.sqrt(3.0)), rtol=1e-10)
        np.testing.assert_allclose(got.margin, loop_delay_margin(L).margin, rtol=0, atol=0)
    with pytest.raises(ParameterError, match="loop transfer function alone"):
        nrobust.delay_margin([1.0, 2.0])


def test_a_neutral_loop_gets_its_gain_floor_from_its_high_frequency_gain():
    """``L = (0.5 s + 1) e^{-s} / (s + 2) = 0.5 e^{-s}``: |L| = 0.5 at every frequency, phase crossovers at the odd
    multiples of pi, each with gain margin 2 exactly, and no gain crossover. The default ``gain_floor`` (1e-2)
    lies below the high-frequency gain, which refused the loop until a floor above 0.5 was guessed; now the
    floor is 1.25 times that gain and the refusal of a given floor states the gain."""
    L = control.tf([0.5, 1.0], [1.0, 2.0]) * delay(1.0)
    m = allmargin(L)
    np.testing.assert_allclose(
        m.gain_floor, 1.25 * 0.5 * (1 + 5e-4), rtol=5e-4
    )  # above by at most the bisection's 0.1 %
    assert m.gain_floor >= 1.25 * 0.5
    w = np.asarray(m.gm_frequencies, dtype=float)
    assert w.size >= 1
    # Brent's xtol on the frequencies, the loop's rounding on the margins
    np.testing.assert_allclose(w, np.pi * (2 * np.arange(w.size) + 1), rtol=1e-12)
    np.testing.assert_allclose(np.asarray(m.gain_margins, dtype=float), 2.0, rtol=1e-12)
    assert len(m.phase_margins) == 0 and len(m.delay_margins) == 0
    with pytest.raises(ParameterError, match=r"high-frequency gain of the loop, 0\.50"):
        allmargin(L, gain_floor=0.1)
