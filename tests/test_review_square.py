"""The square of speed mismatches proven or refused on windows of delays away from 0.

Oracles independent of the code under test, for the transport plant with the law
``U = -K (1 + a s)/(1 + b s) u(t, 1)``, whose loop from the characteristics is
``F(s) = (1 + b s)(1 - rho q e^{-tau s}) + K q (1 + a s) e^{-(tau + delta) s}`` with
``tau = 1/(lam (1 + e_lam)) + 1/(mu (1 + e_mu))``:

- ``rho = 0``, ``b = 0.2``, ``K q = 1.5``: ``F = 1 + 0.2 s + 1.5 e^{-T s}`` depends on ``T = tau + delta``
  only; one crossing frequency ``w_c = sqrt(1.5^2 - 1)/0.2`` and crossings at
  ``T_j = (pi - atan(0.2 w_c) + 2 pi j)/w_c`` (0.41153, 1.5355), stable for ``T < T_0``,
  mpmath finds a zero with ``Re s > 0`` at ``T = 1``;
- ``rho q = -0.9``, ``K q = -1``, ``b = 1.1``: stable on a later window of delays at the four
  corners of the square, with a pair of crossings born between them; mpmath at 40 digits finds a
  zero with ``Re s > 0`` at an inner round trip, and on a window clear of that pair a scan of
  crossing delays (``|A(i w)| = |B(i w)|`` solved here) and an argument-principle count written
  here agree with the proof.
"""

from __future__ import annotations

import math
from typing import Any

import mpmath as mp
import numpy as np
import pytest
from scipy.optimize import brentq

from nrobust import FilteredController, ParameterError, TransportSystem
from nrobust.hyperbolic.analyses import mismatch_loop, prove_transport_square, speed_tolerance

# F = (1 + 1.1 s)(1 + 0.9 e^{-tau s}) - e^{-(tau + delta) s}
LATER = TransportSystem(7.2, 0.64, 1.0, -0.9)
LATER_LAW = FilteredController(0.0, 1.1, -1.0)
LATER_EPS = 0.03
RQ, KQ, BF = -0.9, -1.0, 1.1


def _later_F(s: np.ndarray, tau: float, delta: float) -> np.ndarray:
    return (1 + BF * s) * (1 - RQ * np.exp(-tau * s)) + KQ * np.exp(-(tau + delta) * s)


def _crossing_delays(tau: float, d_max: float) -> list[float]:
    """Every delay in ``[0, d_max]`` with a zero of the later loop on the imaginary axis (brute force)."""

    def gap(w: Any) -> Any:
        return np.abs((1 + 1j * BF * w) * (1 - RQ * np.exp(-1j * w * tau))) ** 2 - KQ**2

    # |1 + 1.1 i w| (1 - 0.9) > 1 = |K q| for w > 9.04: every crossing frequency is below 9.1
    w = np.linspace(1e-9, 9.1, 9101)
    g = gap(w)
    out = []
    for i in np.nonzero(np.sign(g[:-1]) != np.sign(g[1:]))[0]:
        wc = brentq(gap, w[i], w[i + 1], xtol=1e-14)
        A = (1 + 1j * BF * wc) * (1 - RQ * np.exp(-1j * wc * tau))
        B = KQ * np.exp(-1j * wc * tau)
        first = (-np.angle(-A / B)) % (2 * np.pi) / wc  # e^{-i w delta} = -A/B
        out += [first + 2 * np.pi * j / wc for j in range(int((d_max - first) * wc / (2 * np.pi)) + 1)]
    return out


def _count(tau: float, delta: float, radius: float = 10.0) -> int:
    """Zeros of the later loop in Re s > 0: the argument principle on the half-disc of ``radius``.

    On Re s >= 0, ``|F| >= 0.1 |1 + 1.1 s| - 1 >= 0.11 |s| - 1 > 0`` for ``|s| > 9.1``: none outside.
    """
    n = 400_000
    y = np.linspace(radius, -radius, n)
    theta = np.linspace(-np.pi / 2, np.pi / 2, n)
    path = np.concatenate([1j * y, radius * np.exp(1j * theta)])
    values = _later_F(path, tau, delta)
    steps = np.angle(values[1:] / values[:-1])
    assert np.abs(steps).max() < 0.5  # sampled finely enough to follow the argument
    return round(float(steps.sum()) / (2 * np.pi))


def test_pocket_on_a_later_window_is_not_met() -> None:
    """Stable on [2.945, 2.965] at the four corners, not at an inner round trip: 'not met', never proven."""
    result = speed_tolerance(LATER, LATER_LAW, LATER_EPS, (2.945, 2.965), grid=2, rigorous=True)
    assert all(w.stable and w.certified == "proven" for w in result.windows[:4])
    assert not result.met and result.certified == "not met"
    tau0 = LATER.tau
    assert tau0 / (1 + LATER_EPS) < 1.7407 < tau0 / (1 - LATER_EPS)  # a round trip of the square
    with mp.workdps(40):
        tau, delta = mp.mpf("1.7407"), mp.mpf("2.964")

        def F(s: mp.mpc) -> mp.mpc:
            return (1 + mp.mpf("1.1") * s) * (1 + mp.mpf("0.9") * mp.exp(-tau * s)) - mp.exp(-(tau + delta) * s)

        root = mp.findroot(F, mp.mpc(0, 9.03))
        assert abs(F(root)) < mp.mpf(10) ** -30 and root.real > 1e-5  # 4.77e-5 + 9.0267 i


def test_later_window_proven_agrees_with_a_scan() -> None:
    """[3.03, 3.10]: proven on the square; no crossing delay of 101 round trips in it, none unstable."""
    result = speed_tolerance(LATER, LATER_LAW, LATER_EPS, (3.03, 3.10), grid=2, rigorous=True)
    assert result.met and result.certified == "proven on the square"
    t_lo, t_hi = LATER.tau / (1 + LATER_EPS), LATER.tau / (1 - LATER_EPS)
    clearance = min(max(3.03 - d, d - 3.10) for tau in np.linspace(t_lo, t_hi, 101) for d in _crossing_delays(tau, 4.0))
    assert clearance > 0.01  # 0.0165 on this grid: no crossing delay inside the window
    assert _count(t_lo, 3.065) == 0 and _count(t_hi, 3.065) == 0
    # the window [2.98, 3.10] holds crossing delays of the corner (-eps, -eps): not met there
    assert _count(t_hi, 2.99) == 2
    assert speed_tolerance(LATER, LATER_LAW, LATER_EPS, (2.98, 3.10), grid=2, rigorous=True).certified == "not met"


def test_verdicts_on_other_delays_start_no_argument() -> None:
    """Corners proven stable on [0, 0.1] prove nothing about [0.6, 1.0], where every loop of the square is unstable."""
    plant, law, eps = TransportSystem(10.0, 10.0, 1.0, 0.0), FilteredController(0.0, 0.2, 1.5), 0.01
    w_c = math.sqrt(1.5**2 - 1.0) / 0.2
    T0 = (math.pi - math.atan(0.2 * w_c)) / w_c
    T1 = T0 + 2 * math.pi / w_c
    np.testing.assert_allclose([T0, T1], [0.41153, 1.53550], atol=5e-6)  # closed form, rounded here
    t_lo, t_hi = plant.tau / (1 + eps), plant.tau / (1 - eps)
    assert t_hi + 0.1 < T0 and T0 < t_lo + 0.6 and t_hi + 1.0 < T1  # stable on [0, 0.1]; [0.6, 1.0] inside (T0, T1)
    with mp.workdps(40):
        T = mp.mpf(1)

        def F(s: mp.mpc) -> mp.mpc:
            return 1 + mp.mpf("0.2") * s + mp.mpf("1.5") * mp.exp(-T * s)

        root = mp.findroot(F, mp.mpc(0.24, 2.67))
        assert abs(F(root)) < mp.mpf(10) ** -30 and root.real > 0.1  # 0.24272 + 2.67048 i
    first = speed_tolerance(plant, law, eps, (0.0, 0.1), grid=2, rigorous=True)
    assert first.certified == "proven on the square"
    corners = [
        (*mismatch_loop(plant, law, a, b), w) for (a, b), w in zip(first.points[:4], first.windows[:4], strict=True)
    ]
    proof = prove_transport_square(plant, -1.5, (0.0, 0.2), eps, (0.6, 1.0), corners)
    assert not proof.proven and "no corner is proven stable on a window meeting" in proof.reason
    with pytest.raises(ParameterError, match="corner_windows"):
        speed_tolerance(plant, law, eps, (0.6, 1.0), grid=2, rigorous=True, corner_windows=first.windows[:4])
    with pytest.raises(ParameterError, match="corner_windows"):
        speed_tolerance(plant, law, eps, (0.0, 0.1), corner_windows=first.windows[:3])
    assert speed_tolerance(plant, law, eps, (0.6, 1.0), grid=2, rigorous=True).certified == "not met"
