"""The python-control user's path through delay systems, end to end.

A rational model built with python-control gets delays (``nrobust.lti.delay``), loops are
closed (``feedback``), and the margins (``allmargin``), the certified poles and stability, and
the step response are read off. Every oracle is independent of nrobust: closed forms written
here, Lambert W (``scipy.special.lambertw``) for ``s + a e^{-s}``, python-control on the
delay-free parts, and direct matrix evaluation of a 2 x 2 loop with one delay per channel.
"""

from __future__ import annotations

import control
import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import lambertw

from nrobust import QuasiPolynomial
from nrobust.errors import ParameterError
from nrobust.lti import DelayLTI, QuasiTransferFunction, allmargin, delay, loop_delay_margin, step_response

s = control.tf("s")


def test_controlsystems_jl_known_solution_from_a_python_control_integrator() -> None:
    # ControlSystems.jl, test_delayed_systems.jl ("Test with known solution"):
    # step(feedback(delay(1) * 2/s, 1), 3) is 0 on [0, 1), 2 (t - 1) on [1, 2), 2 (t - 1) - 2 (t - 2)^2 on [2, 3].
    G = (delay(1.0) * 2 / s).feedback(1)
    assert isinstance(G, DelayLTI) and (G.nstates, G.ndelays) == (1, 1)
    t = np.linspace(0.0, 3.0, 301)
    exact = np.where(t < 1, 0.0, np.where(t < 2, 2 * (t - 1), 2 * (t - 1) - 2 * (t - 2) ** 2))
    # polynomials on each delay interval: the method of steps is exact up to rounding (rtol 1e-10 asked)
    np.testing.assert_allclose(step_response(G, t).outputs, exact, rtol=0, atol=1e-10)


def test_first_order_plus_dead_time_loop_margins_closed_forms() -> None:
    # L = 2 e^{-s/2} / (s + 1): |L(i w)| = 1 at w = sqrt 3; PM = pi - w/2 - atan w; DM = PM / w;
    # phase crossovers w/2 + atan w = (2j + 1) pi, gain margin sqrt(1 + w^2) / 2.
    P = control.tf([2.0], [1.0, 1.0])
    L = P * delay(0.5)
    m = allmargin(L)
    wc = np.sqrt(3.0)
    pm = np.pi - 0.5 * wc - np.arctan(wc)
    # refined by Brent's method to 1e-12 relative (allmargin's tolerance); closed forms to rounding
    np.testing.assert_allclose(m.pm_frequencies, [wc], rtol=1e-11)
    np.testing.assert_allclose(np.radians(m.phase_margins), [pm], rtol=1e-11)
    np.testing.assert_allclose(m.delay_margins, [pm / wc], rtol=1e-11)
    w180 = [brentq(lambda w, j=j: 0.5 * w + np.arctan(w) - (2 * j + 1) * np.pi, 0.1, 1e3, xtol=1e-14) for j in range(2)]
    np.testing.assert_allclose(m.gm_frequencies[:2], w180, rtol=1e-11)
    np.testing.assert_allclose(m.gain_margins[:2], np.sqrt(1.0 + np.square(w180)) / 2.0, rtol=1e-11)
    assert m.stable
    # the delay-free loop's margin, 2 pi / (3 sqrt 3), is the dead time plus what is left of it
    free = loop_delay_margin(P)
    np.testing.assert_allclose(free.margin, 2 * np.pi / (3 * np.sqrt(3.0)), rtol=1e-10)
    np.testing.assert_allclose(free.margin - 0.5, m.delay_margins[0], rtol=1e-10)
    assert L.feedback(1).is_stable() and not (P * delay(free.margin + 0.05)).feedback(1).is_stable()


@pytest.mark.parametrize("a", [1.0, 2.0])
def test_poles_of_a_delayed_integrator_loop_are_lambert_w(a: float) -> None:
    # closed loop of a e^{-s} / s: s + a e^{-s} = 0, s = W_k(-a); stable iff a < pi / 2
    T = (a * delay(1.0) / s).feedback(1)
    found = T.poles(re_min=-2.5)
    exact = np.array([complex(lambertw(-a, k)) for k in range(-5, 5)])
    exact = exact[exact.real >= -2.5]
    assert found.certified and found.roots.size == exact.size
    # certified roots refined by Newton: within 1e-9 of Lambert W (the radii are smaller)
    np.testing.assert_allclose([np.min(np.abs(found.roots - z)) for z in exact], 0.0, atol=1e-9)
    sa = T.spectral_abscissa()
    np.testing.assert_allclose(sa.value, lambertw(-a, 0).real, rtol=1e-9)
    assert T.is_stable() is (a < np.pi / 2)


def test_neutral_loop_strong_stability_and_closed_form_poles() -> None:
    # (b s + 1) e^{-s} / (s + 2) under unit feedback: s + 2 + (b s + 1) e^{-s}; the difference
    # operator 1 + b e^{-s} is strongly stable iff |b| < 1, its chains at Re s = ln |b| (C_D).
    N = (control.tf([0.5, 1.0], [1.0, 2.0]) * delay(1.0)).feedback(1)
    assert N.is_neutral and N.is_strongly_stable() and N.is_stable()
    # b = 1/2: the characteristic function is (s + 2)(1 + e^{-s} / 2), poles -2 and -ln 2 + (2k + 1) pi i
    found = N.poles((-1.0, 0.0, -20.0, 20.0))
    exact = -np.log(2.0) + 1j * np.pi * np.array([-5, -3, -1, 1, 3, 5])
    assert found.certified
    np.testing.assert_allclose(np.sort_complex(found.roots), exact, rtol=0, atol=1e-9)
    np.testing.assert_allclose(N.spectral_abscissa().value, -np.log(2.0), rtol=1e-9)
    with pytest.raises(ParameterError, match=r"C_D = -0\.693147"):
        N.poles(re_min=-1.0)  # left of the chains: infinitely many poles
    # |b| > 1: not strongly stable, unstable for every dead time (chains at ln 1.5 > 0)
    U = (control.tf([1.5, 1.0], [1.0, 2.0]) * delay(1.0)).feedback(1)
    assert not U.is_strongly_stable() and not U.is_stable()


def test_delay_outside_the_loop_shifts_python_controls_step() -> None:
    # y = e^{-0.7 s} T0(s) with T0 = feedback(P, 1) delay-free: y(t) = y0(t - 0.7), y0 from python-control
    P = control.tf([3.0], [1.0, 2.0, 2.0])
    T0 = control.feedback(P, 1)
    t = np.linspace(0.0, 6.0, 121)  # steps of 0.05: the delay is 14 of them
    y0 = control.step_response(T0, t).outputs
    shifted = np.concatenate([np.zeros(14), y0[:-14]])
    y = step_response(delay(0.7) * DelayLTI.from_control(P).feedback(1), t).outputs
    # python-control's response is a matrix exponential on the grid: exact to ~1e-12
    np.testing.assert_allclose(y, shifted, rtol=0, atol=1e-9)
    # without delay, poles and step agree with python-control's
    D0 = DelayLTI.from_control(P).feedback(1)
    np.testing.assert_allclose(np.sort_complex(D0.poles().roots), np.sort_complex(T0.poles()), atol=1e-10)
    np.testing.assert_allclose(step_response(D0, t).outputs, control.step_response(T0, t).outputs, atol=1e-9)


def plant_entries(z: np.ndarray) -> np.ndarray:
    """``P(z)`` of the 2 x 2 plant below, written out: shape ``(2, 2) + z.shape``."""
    return np.array([[1 / (z + 1), 0.5 / (z + 2)], [0.2 / (z + 3), 2 / (z + 1)]])


def test_mimo_loop_with_a_delay_per_channel_against_direct_evaluation() -> None:
    P = control.tf([[[1.0], [0.5]], [[0.2], [2.0]]], [[[1.0, 1.0], [1.0, 2.0]], [[1.0, 3.0], [1.0, 1.0]]])
    tau = np.array([0.3, 0.8])
    K = np.diag([0.8, 0.6])
    L = DelayLTI.from_control(P) * delay(tau[0]).append(delay(tau[1]))  # input delays, one per channel
    T = L.feedback(K)
    w = np.array([0.0, 0.1, 0.5, 1.0, 2.0, 5.0, 20.0])
    H = T.frequency_response(w)
    assert H.shape == (2, 2, w.size)
    for i, wi in enumerate(w):
        z = 1j * wi
        Lz = plant_entries(np.array(z)) @ np.diag(np.exp(-tau * z))
        exact = np.linalg.solve(np.eye(2) + Lz @ K, Lz)
        # 2 x 2 solves on entries of order 1: a few hundred rounding units
        np.testing.assert_allclose(H[:, :, i], exact, rtol=1e-12, atol=1e-14)
    # the DelayLTI's to_frd is python-control's FRD of the same values
    frd = T.to_frd(w)
    np.testing.assert_allclose(frd.frdata, H, rtol=0, atol=0)
    # step responses from each input settle to the DC gain (I + P(0) K)^{-1} P(0)
    sa = T.spectral_abscissa()
    assert sa.certified and sa.value < -0.7  # -0.7411 (rightmost pole -0.7411 +- 2.1247i)
    t = np.linspace(0.0, 30.0, 301)
    r = step_response(T, t)
    assert r.outputs.shape == (2, 2, t.size)
    dc = np.linalg.solve(np.eye(2) + plant_entries(np.array(0.0)) @ K, plant_entries(np.array(0.0)))
    # transients decay at least like e^{-0.7 t}: e^{-21} ~ 1e-9 of order-1 amplitudes at t = 30
    np.testing.assert_allclose(r.outputs[:, :, -1], dc, rtol=0, atol=1e-7)
    # loop at a time: loop 0 broken, loop 1 closed through K; its first phase crossover and gain margin
    m = allmargin(L * K, loop=0)

    def effective(x: float) -> complex:
        z = 1j * x
        Lz = plant_entries(np.array(z)) @ np.diag(np.exp(-tau * z)) @ K
        return complex(Lz[0, 0] - Lz[0, 1] * Lz[1, 0] / (1 + Lz[1, 1]))

    grid = np.linspace(1e-3, 10.0, 2001)
    imag = np.array([effective(x).imag for x in grid])
    first = next(i for i in np.flatnonzero(np.diff(np.sign(imag))) if effective(grid[i]).real < 0)
    w180 = brentq(lambda x: effective(x).imag, grid[first], grid[first + 1], xtol=1e-15)
    np.testing.assert_allclose(m.gm_frequencies[0], w180, rtol=1e-10)
    np.testing.assert_allclose(m.gain_margins[0], 1 / abs(effective(w180)), rtol=1e-10)
    assert m.pm_frequencies.size == 0  # |L_eff| < 1 everywhere: no gain crossover
    assert max(abs(effective(x)) for x in grid) < 1.0


def test_python_control_and_quasi_transfer_systems_go_straight_to_step_response() -> None:
    # 1/(s + 1): 1 - e^{-t}; a QuasiTransferFunction e^{-s} / (s + 1): 1 - e^{-(t - 1)} after t = 1
    t = np.linspace(0.0, 4.0, 41)
    np.testing.assert_allclose(step_response(control.tf([1.0], [1.0, 1.0]), t).outputs, 1 - np.exp(-t), atol=1e-10)
    np.testing.assert_allclose(step_response(control.ss(-1.0, 1.0, 1.0, 0.0), t).outputs, 1 - np.exp(-t), atol=1e-10)
    H = QuasiTransferFunction(1.0, QuasiPolynomial([[1.0, 1.0]], [0.0])).delay(1.0)
    np.testing.assert_allclose(step_response(H, t).outputs, np.where(t < 1, 0.0, 1 - np.exp(1 - t)), atol=1e-10)
    with pytest.raises(ParameterError, match="python-control system"):
        step_response("1/(s+1)", t)


def test_improper_factor_names_the_grouping() -> None:
    # Python reads delay(1) * s / (s + 1) as (delay(1) * s) / (s + 1): s alone is improper
    with pytest.raises(ParameterError, match=r"delay\(h\) \* \(s / \(s \+ 1\)\)"):
        delay(1.0) * s / (s + 1)
    G = delay(1.0) * (s / (s + 1))
    w = np.array([0.5, 2.0])
    np.testing.assert_allclose(G.frequency_response(w), np.exp(-1j * w) * 1j * w / (1j * w + 1), rtol=1e-13)


def test_pade_models_step_responses_converge_to_the_exact_one() -> None:
    # The loop 2 e^{-s/2} / (s + 1) in unit feedback: python-control's step response of the
    # (n, n) Pade model approaches nrobust's exact one (the method of steps, checked against closed
    # forms in tests/test_timeresp.py) as n grows, slowly (docs/delay_systems.md: 0.21, 0.069,
    # 0.042, 0.021 for n = 1, 2, 4, 8; the all-pass factor answers before the delay is over).
    P = control.tf([2.0], [1.0, 1.0])
    t = np.linspace(0.0, 10.0, 1001)
    exact = step_response((P * delay(0.5)).feedback(1), t).outputs
    errors = []
    for n in (1, 2, 4, 8, 16):
        num, den = control.pade(0.5, n)
        model = control.feedback(P * control.tf(num, den), 1)
        errors.append(float(np.max(np.abs(control.step_response(model, t).outputs - exact))))
    assert np.all(np.diff(errors) < 0), errors
    # measured 0.0205 at n = 8 and 0.0104 at n = 16: the error halves per doubling of n (0.75 leaves
    # room for the rounding of python-control's order-16 model, ill-conditioned beyond about n = 18)
    assert errors[3] < 0.025 and errors[4] < 0.75 * errors[3], errors
