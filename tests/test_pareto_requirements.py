"""Requirements held at every point of a trade-off front: windows of delays, scenarios, a speed tolerance.

Oracles, sharing no code with the optimiser:

* the first-order loop ``s + 1 + k e^{-delta s}``: its root ``-1 - k`` at ``delta = 0`` (decay rate
  ``1 + k``) and, for ``k > 1``, its delay margin ``arccos(-1/k) / sqrt(k^2 - 1)`` in closed form; it is
  stable exactly for the delays below its margin (the one crossing frequency ``w^2 = k^2 - 1`` is a
  simple root of ``P(u) = u - (k^2 - 1)``, ``P' > 0``: every crossing is to the right, Cooke and van den
  Driessche, Funkcial. Ekvac. 29, 1986), and the margin decreases in ``k``, so the best decay rate under
  stability on ``[0, D]`` is ``1 + k*(D)``, ``k*(D)`` the root of ``margin(k) = D`` (scipy's brentq);
* the delayed oscillator ``s^2 + c s + 1 + K (1 + BETA s) e^{-delta s}``: its crossing delays in closed
  form (``|A(i w)| = |B(i w)|`` is a quadratic in ``w^2``) and its decay rate ``(c + BETA K)/2``;
* the filtered law on a transport plant with mismatched speeds written here from the controller's
  definition, ``(1 - rho q e^{-tau' s})(1 + b s) + K q e^{-tau' s}(1 + a s) e^{-delta s}`` with
  ``tau' = 1/lam' + 1/mu'``, whose delay margins and abscissae are computed directly.

The optimiser stops when the pattern search's step is ``POLISH_TOL = 1e-5`` of the bounds' width: on
``k in [0, 5]`` a design is within about ``5e-5`` of the optimum in ``k``, so the decay rate ``1 + k`` is
compared to ``1e-4``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from _design_loops import (
    BETA,
    K_BOUNDS,
    OSC_BOUNDS,
    RATE_TOL,
    best_k,
    crossing_delays,
    first_order,
    late,
    margin,
    oscillator,
)

import nrobust as nr
from nrobust.design import ParetoFront, pareto_front
from nrobust.errors import ParameterError
from nrobust.hyperbolic.analyses import filtered_front
from nrobust.margins import delay_margin
from nrobust.roots import SpectralAbscissa, spectral_abscissa

WINDOW = (4.7, 4.85)
# the transport plant of the filtered law: |rho q| = 0.6, tau = 1.5; the filter's zero and pole fixed
LAM, MU, Q, RHO = 1.0, 2.0, 1.0, 0.6
A_ZERO, B_POLE = 0.05, 0.1
FILTER = {"K": (-0.35, 0.6), "a": A_ZERO, "b": B_POLE}


def corner_loop(K: float, e_lam: float, e_mu: float) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
    """The filtered law designed on the nominal transport plant, acting on speeds lam (1 + e_lam), mu (1 + e_mu)."""
    tau = 1.0 / (LAM * (1.0 + e_lam)) + 1.0 / (MU * (1.0 + e_mu))
    A = nr.QuasiPolynomial([[1.0, B_POLE], [-RHO * Q, -RHO * Q * B_POLE]], [0.0, tau])
    B = nr.QuasiPolynomial([[K * Q, K * Q * A_ZERO]], [tau])
    return A, B


def stable_at(A: nr.QuasiPolynomial, B: nr.QuasiPolynomial, delays: np.ndarray) -> bool:
    """The loop's spectral abscissa is negative at each delay, by more than its accuracy (an independent
    route: the rightmost roots at that delay, no crossing search)."""
    return all(_below_zero(spectral_abscissa(A + B.shift(float(d)))) for d in delays)


def _below_zero(sa: SpectralAbscissa) -> bool:
    return sa.accuracy is not None and sa.value + sa.accuracy < 0.0


@pytest.fixture(scope="module")
def windowed() -> ParetoFront:
    """Margins 0.3, 0.6, 1.2 and the windows [0.5, 0.7], [0.6, 0.9] at every point."""
    return pareto_front(first_order, K_BOUNDS, [0.3, 0.6, 1.2], delays=[(0.5, 0.7), (0.6, 0.9)], x0=[0.5])


def test_windows_hold_at_every_point_and_cost_decay_rate(windowed: ParetoFront) -> None:
    """The loop is stable exactly below its margin: stable on [0, d] and the windows iff delta* > max(d, 0.9).

    At d = 0.3 the optimiser holds [0, 0.3] and [0.5, 0.9] (the two windows merged) at once.
    """
    front = windowed
    assert front.certified and front.infeasible == () and front.delays == ((0.5, 0.7), (0.6, 0.9))
    need = [0.9, 0.9, 1.2]
    np.testing.assert_allclose(front.decay_rates, [1.0 + best_k(D) for D in need], atol=RATE_TOL)
    # no better than the front without windows, 1 + k*(d); strictly worse where a window binds (d < 0.9)
    free = np.array([1.0 + best_k(d) for d in (0.3, 0.6, 1.2)])
    assert np.all(front.decay_rates <= free + RATE_TOL)
    assert np.all(front.decay_rates[:2] < free[:2] - 0.5)
    np.testing.assert_allclose(front.decay_rates[2], free[2], atol=RATE_TOL)
    for design, d, certs in zip(front.designs, front.required, front.windows):
        (k,) = design.parameters
        assert margin(k) > max(d, 0.9)  # the closed form: stable on [0, d] and on both windows
        A, B = first_order(np.array([k]))
        assert stable_at(A, B, np.array([0.0, d, 0.5, 0.7, 0.9]))
        ((w1, w2),) = certs  # the loop's certificates, one per window
        assert (w1.delays, w2.delays) == ((0.5, 0.7), (0.6, 0.9)) and w1.stable and w2.stable
    data = front.to_dict()
    json.dumps(data, allow_nan=False)
    assert data["delays"] == [[0.5, 0.7], [0.6, 0.9]] and data["certified"] == [True, True, True]
    assert "stable for every delay in [0.5, 0.7] and [0.6, 0.9]" in data["requirement"]
    assert "delays=[[0.5, 0.7], [0.6, 0.9]]" in repr(front)


def test_a_scenario_is_held_to_every_requirement() -> None:
    """A scenario with 0.1 more delay must be stable on [0, d]: the loop on [0.1, 0.1 + d].

    Its requirement at d = 2.0 asks for a margin above 2.1, beyond the largest on k >= 1.5 (margin(1.5) =
    2.0577, the margin decreasing in k): recorded infeasible, where the loop alone would meet 2.0.
    """
    assert 2.0 < margin(1.5) < 2.1
    front = pareto_front(
        first_order, [(1.5, 5.0)], [0.3, 2.0], scenarios={"extra delay 0.1": late}, x0=[3.0], max_iter=10
    )
    assert front.scenarios == ("extra delay 0.1",) and front.infeasible == (2.0,) and front.certified
    assert front.required.tolist() == [0.3]
    np.testing.assert_allclose(front.decay_rates, [1.0 + best_k(0.4)], atol=RATE_TOL)
    ((loop_certs, scenario_certs),) = front.windows
    assert loop_certs == () and [w.delays for w in scenario_certs] == [(0.0, 0.3)]
    (k,) = front.designs[0].parameters
    assert margin(k) > 0.4
    assert delay_margin(*late(np.array([k]))).margin > 0.3  # the scenario's own margin, recomputed
    assert "1 scenario (extra delay 0.1) stable for every delay in [0, d]" in front.requirement


def test_an_oscillator_unstable_between_its_windows() -> None:
    """d = 0: only the window [4.7, 4.85], which binds (the free optimum is the corner, rate 0.235).

    d = 0.3: [0, 0.3] too, the loop unstable between the two intervals (the optimiser holds both); both
    checked by the closed-form crossing delays. The margin does not bind (above 0.6), so both points are the
    same design.
    """
    front = pareto_front(oscillator, OSC_BOUNDS, [0.0, 0.3], delays=WINDOW, x0=[0.0, 0.3])
    assert front.certified and front.infeasible == ()
    for design, certs in zip(front.designs, front.windows):
        c, K = design.parameters
        delays = crossing_delays(c, K, 10.0)
        assert not any(WINDOW[0] <= t <= WINDOW[1] for t in delays) and min(delays) > 0.6
        assert any(0.6 < t < WINDOW[0] for t in delays)  # unstable somewhere between
        assert c + BETA * K > 0.0  # stable at delta = 0 (two roots of real part -(c + BETA K)/2)
        np.testing.assert_allclose(design.decay_rate, (c + BETA * K) / 2.0, rtol=1e-9)
        # the window binds: a crossing delay within 1e-3 of an end (a pattern step of 9e-6 in K moves it by
        # about 1e-4), and the rate is well below the free corner's 0.2/2 + BETA 0.9/2 = 0.235
        assert min(min(abs(t - WINDOW[0]), abs(t - WINDOW[1])) for t in delays) < 1e-3
        assert design.decay_rate < 0.235 - 0.04
        ((certificate,),) = certs
        assert certificate.delays == WINDOW and certificate.stable
    np.testing.assert_allclose(front.decay_rates[1], front.decay_rates[0], rtol=1e-12)


@pytest.mark.long
def test_filtered_front_with_a_window() -> None:
    """The filtered law on the transport plant, margin 0.5 and stable on [0.9, 1.4] too (about 4 s of CPU).

    The window costs decay rate: 1e-3 past the design's K (100 pattern steps) the loop, written here from the
    controller's definition, still has a margin above 0.5 but is unstable somewhere in the window.
    """
    front = filtered_front(nr.TransportSystem(LAM, MU, Q, RHO), [0.5], delays=(0.9, 1.4), parameters=FILTER, x0=[0.0])
    assert front.certified and front.delays == ((0.9, 1.4),)
    (K,) = front.designs[0].parameters
    A, B = corner_loop(K, 0.0, 0.0)
    assert delay_margin(A, B).margin >= 0.5 and stable_at(A, B, np.linspace(0.9, 1.4, 6))
    past = corner_loop(K + 1e-3, 0.0, 0.0)
    assert delay_margin(*past).margin > 0.5 and not stable_at(*past, np.linspace(0.9, 1.4, 51))


@pytest.mark.long
def test_filtered_front_under_a_speed_tolerance() -> None:
    """Speeds known to 20 % (about 5 s of CPU): the four corner plants keep a margin above 0.5 at the design.

    The tolerance binds: 1e-3 past the design's K (100 pattern steps) a corner falls below 0.5, the nominal
    loop does not.
    """
    front = filtered_front(nr.TransportSystem(LAM, MU, Q, RHO), [0.5], speed_tolerance=0.2, parameters=FILTER, x0=[0.0])
    assert front.certified and len(front.scenarios) == 4 and front.scenarios[1] == "(e_lam, e_mu) = (-0.2, 0.2)"
    (K,) = front.designs[0].parameters
    corners = [(e_lam, e_mu) for e_lam in (-0.2, 0.2) for e_mu in (-0.2, 0.2)]
    assert min(delay_margin(*corner_loop(K, *e)).margin for e in corners) > 0.5
    assert min(delay_margin(*corner_loop(K + 1e-3, *e)).margin for e in corners) < 0.5
    assert delay_margin(*corner_loop(K + 1e-3, 0.0, 0.0)).margin > 0.5
    assert [[w.delays for w in loop] for loop in front.windows[0]] == [[]] + [[(0.0, 0.5)]] * 4


def test_the_plot_shows_the_windows(windowed: ParetoFront) -> None:
    import matplotlib

    matplotlib.use("Agg")
    from nrobust.plots import pareto_plot

    drawn = pareto_plot(windowed)
    assert len(drawn.lines["windows"]) == 2
    assert "stable on [0.5, 0.7], [0.6, 0.9]" in drawn.axes.get_title()


def test_wide_windows_and_single_delays_with_a_margin() -> None:
    """[0, 0.01] with [0.5, 2.0] (150 times the narrowest interval), and [0, 0.3] with the single delay 0.5.

    The loop is stable exactly below its margin: the requirements are ``delta* > 2.0`` and ``delta* > 0.5``.
    """
    front = pareto_front(first_order, K_BOUNDS, [0.01], delays=(0.5, 2.0), x0=[0.5])
    assert front.certified and front.infeasible == ()
    np.testing.assert_allclose(front.decay_rates, [1.0 + best_k(2.0)], atol=RATE_TOL)
    assert margin(front.designs[0].parameters[0]) > 2.0
    (((certificate,),),) = front.windows
    assert certificate.delays == (0.5, 2.0) and certificate.stable
    single = pareto_front(first_order, K_BOUNDS, [0.3], delays=(0.5, 0.5), x0=[0.5])
    assert single.certified and single.infeasible == ()
    np.testing.assert_allclose(single.decay_rates, [1.0 + best_k(0.5)], atol=RATE_TOL)
    assert margin(single.designs[0].parameters[0]) > 0.5
    assert [[w.delays for w in loop] for loop in single.windows[0]] == [[(0.5, 0.5)]]


def test_bad_requirements_are_named() -> None:
    with pytest.raises(ParameterError, match="delays"):
        pareto_front(first_order, K_BOUNDS, [0.3], delays=(0.7, 0.5))
    with pytest.raises(ParameterError, match=r"delays\[1\]"):
        pareto_front(first_order, K_BOUNDS, [0.3], delays=[(0.5, 0.7), (0.9, 0.8)])
    with pytest.raises(ParameterError, match="delays"):
        pareto_front(first_order, K_BOUNDS, [0.3], delays="0.5, 0.7")  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match=r"delays\[0\]"):
        pareto_front(first_order, K_BOUNDS, [0.3], delays=[(0.5, -0.5)])
    with pytest.raises(ParameterError, match="required"):
        pareto_front(first_order, K_BOUNDS, [0.0, 0.3], scenarios=[late])
    with pytest.raises(ParameterError, match=r"scenarios\[0\]"):
        pareto_front(first_order, K_BOUNDS, [0.3], scenarios=[3.0])  # type: ignore[list-item]
    transport = nr.TransportSystem(LAM, MU, Q, RHO)
    with pytest.raises(ParameterError, match="speed_tolerance"):
        filtered_front(transport, [0.5], speed_tolerance=1.5)
    with pytest.raises(ParameterError, match="kernel_grid"):
        filtered_front(transport, [0.5], kernel_grid=-3)
    general = nr.GeneralHyperbolic2x2(lam=1.0, mu=1.0, a=0.0, b=0.5, c=0.5, d=0.0, q=0.5, rho=0.5)
    with pytest.raises(ParameterError, match=r"speed_tolerance.*Hyperbolic2x2 or TransportSystem"):
        filtered_front(general, [0.5], speed_tolerance=0.1)
