"""Requirements of the several-parameter designs: a window of delays and a tolerance on the speeds.

Oracles, sharing no code with the optimiser: the crossing delays of the delayed oscillator
s^2 + c s + 1 + K (1 + BETA s) e^{-delta s} in closed form (|A(i w)| = |B(i w)| is a quadratic in
w^2, the delays theta / w + 2 pi k / w), a brute-force grid of window_stability verdicts over the
parameters, and the loops of the filtered law on transport plants with mismatched speeds written
here from the controller's definition, (1 - rho q e^{-tau' s})(1 + b s) + K q e^{-tau' s}(1 + a s)
e^{-delta s} with tau' = 1/lam' + 1/mu', whose delay margins are computed directly.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from _design_loops import BETA, OSC_BOUNDS, crossing_delays

import nrobust as nr
from nrobust.design import optimize_loop, window_stability
from nrobust.errors import CertificationError, ParameterError
from nrobust.hyperbolic.analyses import SpeedTolerance
from nrobust.hyperbolic.analyses.filter_design import FilteredDesign, design_filtered
from nrobust.hyperbolic.analyses.state_design import design_state_feedback
from nrobust.hyperbolic.loops.controllers import loop_factors
from nrobust.margins import delay_margin
from nrobust.reports.design import run_design

WINDOW = (4.7, 4.85)
# the transport plant of the filtered design: u_t + lam u_x = 0, v_t - mu v_x = 0, u(0) = q v(0)
LAM, MU, Q, RHO = 1.0, 2.0, 1.0, 0.6
A_ZERO, B_POLE = 0.05, 0.1


def oscillator(p: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
    return nr.QuasiPolynomial([[1.0, p[0], 1.0]], [0.0]), nr.QuasiPolynomial([[p[1], BETA * p[1]]], [0.0])


def test_window_changes_the_optimum_against_a_grid() -> None:
    """The decay rate (c + BETA K)/2 grows to the corner (0.2, 0.9); the window stops K well before it."""
    free = optimize_loop(oscillator, OSC_BOUNDS, x0=[0.0, 0.3])
    design = optimize_loop(oscillator, OSC_BOUNDS, delays=WINDOW, x0=[0.0, 0.3])
    assert design.certified and design.delays == WINDOW and len(design.windows) == 1
    assert design.requirement.endswith("(the loop): met, checked")
    # the closed-form crossing delays at the design miss the window, and one lies within 1e-3 of
    # its ends: the requirement binds (a pattern step of POLISH_TOL * 0.9 = 9e-6 in K moves a
    # crossing delay by about 1e-4 here)
    c, K = design.parameters
    delays = crossing_delays(c, K, 10.0)
    assert not any(WINDOW[0] <= d <= WINDOW[1] for d in delays)
    assert min(min(abs(d - WINDOW[0]), abs(d - WINDOW[1])) for d in delays) < 1e-3
    # the window costs decay rate: the free optimum is the corner, 0.2/2 + BETA 0.9/2 = 0.235
    np.testing.assert_allclose(free.value, 0.235, atol=1e-5)  # POLISH_TOL of the widths: 9e-6 in K
    assert design.value < free.value - 0.04
    # brute force: no grid point stable on the window beats the design; the rate is (c + BETA K)/2
    # in closed form (complex roots: (c + BETA K)^2 < 4 (1 + K) on the bounds), and the pattern
    # search stops within 1e-5 of the widths: 0.5 * 0.4e-5 + 0.15 * 0.9e-5 < 1e-5 of rate
    best, verdicts = -math.inf, []
    for cg in np.linspace(-0.2, 0.2, 5):
        for Kg in np.linspace(0.1, 0.9, 9):  # K = 0, c = 0: the zeros +-i for every delay (undecided)
            A, B = oscillator(np.array([cg, Kg]))
            stable = window_stability(A, B, WINDOW).stable
            verdicts.append(stable)
            if stable:
                best = max(best, (cg + BETA * Kg) / 2.0)
    assert any(verdicts) and not all(verdicts)
    np.testing.assert_allclose(design.value, (c + BETA * K) / 2.0, rtol=1e-9)
    assert design.value >= best - 1e-5
    json.dumps(design.to_dict(), allow_nan=False)


def test_an_unreachable_window_is_refused() -> None:
    """With K >= 0.6 no damping c in [-0.2, 0.2] meets the window; bad requirements are ParameterErrors."""
    bounds = [(-0.2, 0.2), (0.6, 0.9)]
    for cg in np.linspace(-0.2, 0.2, 5):  # brute force: no grid point is stable on the window
        for Kg in (0.6, 0.75, 0.9):
            assert not window_stability(*oscillator(np.array([cg, Kg])), WINDOW).stable
    with pytest.raises(CertificationError, match=r"first phase raised the margin.*narrow the window"):
        optimize_loop(oscillator, bounds, delays=WINDOW, x0=[0.1, 0.8], max_iter=5)
    with pytest.raises(ParameterError, match="margin_at_least"):
        optimize_loop(oscillator, OSC_BOUNDS, delays=WINDOW, margin_at_least=-0.5)
    with pytest.raises(ParameterError, match="delays"):
        optimize_loop(oscillator, OSC_BOUNDS, delays=(4.85, 4.7))
    with pytest.raises(ParameterError, match="delays"):
        optimize_loop(oscillator, OSC_BOUNDS, scenarios=[oscillator])
    for bad in (oscillator, 3.0, "oscillator"):  # one callable, not a sequence of them
        with pytest.raises(ParameterError, match="scenarios"):
            optimize_loop(oscillator, OSC_BOUNDS, delays=WINDOW, scenarios=bad)  # type: ignore[arg-type]
    transport = nr.TransportSystem(LAM, MU, Q, RHO)
    with pytest.raises(ParameterError, match=r"speed_tolerance.*delay requirement"):
        design_filtered(transport, speed_tolerance=0.1)
    with pytest.raises(ParameterError, match="speed_tolerance"):
        design_filtered(transport, margin_at_least=0.5, speed_tolerance=1.5)
    with pytest.raises(ParameterError, match="kernel_grid"):  # checked without a tolerance too
        design_filtered(transport, margin_at_least=0.5, kernel_grid=-3)
    general = nr.GeneralHyperbolic2x2(lam=1.0, mu=1.0, a=0.0, b=0.5, c=0.5, d=0.0, q=0.5, rho=0.5)
    for design in (design_filtered, design_state_feedback):
        with pytest.raises(ParameterError, match=r"speed_tolerance.*Hyperbolic2x2 or TransportSystem"):
            design(general, margin_at_least=0.2, speed_tolerance=0.1, objective="decay_rate")
    with pytest.raises(ParameterError, match="margin_at_least"):
        design_state_feedback(transport, "decay_rate", margin_at_least=0.2, delays=(0.0, 0.2))


def _corner_loop(K: float, e_lam: float, e_mu: float) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
    """The filtered law designed on the nominal transport plant, acting on speeds lam (1 + e_lam), mu (1 + e_mu)."""
    tau = 1.0 / (LAM * (1.0 + e_lam)) + 1.0 / (MU * (1.0 + e_mu))
    A = nr.QuasiPolynomial([[1.0, B_POLE], [-RHO * Q, -RHO * Q * B_POLE]], [0.0, tau])
    B = nr.QuasiPolynomial([[K * Q, K * Q * A_ZERO]], [tau])
    return A, B


def test_filtered_design_under_a_speed_tolerance(tmp_path: Path) -> None:
    """[design] of a TOML file, family "filtered", margin 0.5 under 20 % speed errors: the corners hold.

    Read by ``nrobust design`` (the requirement and the tolerance pass through to design_filtered); the
    margin at each corner is recomputed here on the loop written from the controller's definition.
    """
    system = tmp_path / "transport.toml"
    system.write_text(
        f'[system]\ntype = "TransportSystem"\nlam = {LAM}\nmu = {MU}\nq = {Q}\nrho = {RHO}\n'
        '[controller]\ntype = "ReflectionController"\nK = 0.1\n[analysis]\ndelta_max = 0.5\n'
        f'[design]\nfamily = "filtered"\nobjective = "decay_rate"\nmargin_at_least = 0.5\nspeed_tolerance = 0.2\n'
        f"K = [-0.35, 0.6]\na = {A_ZERO}\nb = {B_POLE}\nstarts = 1\n"
    )
    _, result = run_design(system, tmp_path / "out")
    assert isinstance(result, FilteredDesign) and isinstance(result.tolerance, SpeedTolerance)
    assert result.tolerance.met and result.design.delays == (0.0, 0.5) and len(result.design.windows) == 5
    assert result.certified and "speed tolerance 0.2" in result.requirement
    K = result.controller.K
    assert K is not None
    margins = []
    for e_lam, e_mu in result.tolerance.points[:4]:
        dm = delay_margin(*_corner_loop(K, e_lam, e_mu))
        assert dm.nominally_stable and dm.verified
        margins.append(dm.margin)
    assert min(margins) > 0.5
    # the tolerance binds: 1e-3 past the design (100 times the pattern search's last step, 1e-5 of the
    # bounds' width) a corner's margin falls below 0.5 while the nominal loop's stays above it
    past = K + 1e-3
    assert min(delay_margin(*_corner_loop(past, a, b)).margin for a, b in result.tolerance.points[:4]) < 0.5
    assert delay_margin(*_corner_loop(past, 0.0, 0.0)).margin > 0.5
    text = (tmp_path / "out" / "design.md").read_text()
    assert "stable for every delay in [0.0, 0.5] (the loop and its 4 scenarios): met, checked" in text
    data = json.loads((tmp_path / "out" / "design.json").read_text())
    assert data["speed_tolerance"] == 0.2 and data["tolerance"]["met"] is True
    # the trade-off in K with the designed filter: its figure, and its best margin recomputed on the loop above
    assert (tmp_path / "out" / "design.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # here some gains have no crossing at all: the scan says so and names one
    found = re.search(r"largest delay margin on the gains' bounds is infinite \(no crossing\) .* at K = (\S+)\.", text)
    assert found is not None, text
    K_best = float(found.group(1))
    assert -0.35 <= K_best <= 0.6 and delay_margin(*_corner_loop(K_best, 0.0, 0.0)).margin == math.inf


def _unstable_count(c: float, K: float, delta: float) -> int:
    """Zeros of the oscillator in Re s > 0 at ``delta``, in closed form (``delta`` not a crossing delay).

    At ``delta = 0``, ``s^2 + (c + BETA K) s + 1 + K`` (``K > -1``) has 0 or 2 of them by the sign of
    ``c + BETA K``; at each crossing delay a pair crosses, to the right on the branch of the larger
    root ``u`` of ``P(u) = u^2 + (c^2 - 2 - K^2 BETA^2) u + 1 - K^2`` (``P'(u) > 0``), to the left on the
    smaller (Cooke and van den Driessche, Funkcial. Ekvac. 29, 1986: the direction is the sign of ``P'``).
    """
    count = 0 if c + BETA * K > 0.0 else 2
    roots = np.roots([1.0, c * c - 2.0 - K * K * BETA * BETA, 1.0 - K * K])
    real = sorted(u.real for u in roots if abs(u.imag) <= 1e-12 and u.real > 0.0)
    for u in real:
        direction = 1 if 2.0 * u + c * c - 2.0 - K * K * BETA * BETA > 0.0 else -1
        w = math.sqrt(u)
        theta = np.mod(np.angle(-K * (1 + 1j * BETA * w) / (1 - w * w + 1j * c * w)), 2 * np.pi)
        count += (
            2
            * direction
            * sum(1 for k in range(int(delta * w / (2 * np.pi)) + 2) if (theta + 2 * np.pi * k) / w < delta)
        )
    return count


@pytest.mark.parametrize(
    ("x0", "window"),
    [
        ([-0.2, 0.05], WINDOW),  # unstable for every delay: no crossing at all, two zeros right
        ([-0.1, 0.05], (0.0, 1.0)),  # unstable at delta = 0 with d_min = 0
    ],
)
def test_a_start_without_a_stability_window_is_stabilised_first(x0: list[float], window: tuple[float, float]) -> None:
    """A start whose loop is unstable at ``delta = d_min`` (no stability window holds the window) is not refused.

    The phase before the first lowers the abscissa at ``delta = d_min`` below 0; the design is then certified,
    and the closed-form count (:func:`_unstable_count`) confirms the start unstable and the design stable on
    the window, with no crossing delay in it. Before, such a start was refused (``CertificationError``).
    """
    d_lo, d_hi = window
    c0, K0 = x0
    assert _unstable_count(c0, K0, d_lo) == 2 and not crossing_delays(c0, K0, 2.0 * d_hi + 1.0)
    design = optimize_loop(oscillator, OSC_BOUNDS, delays=window, x0=x0)
    assert design.certified and design.windows[0].stable
    c, K = design.parameters
    assert _unstable_count(c, K, d_lo if d_lo > 0.0 else 0.0) == 0
    assert not any(d_lo <= d <= d_hi for d in crossing_delays(c, K, d_hi + 1.0))
    # the decay rate -alpha at delta = 0 is (c + BETA K)/2 in closed form (complex roots on the bounds)
    np.testing.assert_allclose(design.decay_rate, (c + BETA * K) / 2.0, rtol=1e-9)


def neutral(p: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
    """The filtered law's loop on a transport plant (``tau = 1.5``, ``rho q = 0.6``, ``a = 0.05``, ``b = 0.1``)."""
    return (
        nr.QuasiPolynomial([[1.0, 0.1], [-0.6, -0.06]], [0.0, 1.5]),
        nr.QuasiPolynomial([[p[0], 0.05 * p[0]]], [1.5]),
    )


def test_a_neutral_start_unstable_for_every_delay_is_stabilised_first() -> None:
    """A neutral loop: from ``K = -0.6``, ``F(0) = 0.4 + K < 0`` and ``F(s) -> +inf`` along the real axis, a real
    zero in ``Re s > 0`` for every delay (no stability window at all); the design is certified on [0.2, 0.6].

    Strong stability (``gamma_0 = 0.6 + 0.5 |K| < 1``, kept by ``gamma_max``) makes the window of ``d_min`` open.
    Oracle for the crossings: ``|A(i w)|^2 - |B(i w)|^2 >= 0.16 (1 + 0.01 w^2) - K^2 (1 + 0.0025 w^2)`` is positive
    above ``w^2 = (K^2 - 0.16) / (0.0016 - 0.0025 K^2)``, so its sign changes below that bound, bracketed on a
    grid and refined by brentq, give every crossing delay ``(arg(-B/A) mod 2 pi + 2 pi k) / w``.
    """
    from scipy.optimize import brentq

    window = (0.2, 0.6)
    design = optimize_loop(neutral, [(-0.75, 0.75)], delays=window, x0=[-0.6])
    assert design.certified and design.windows[0].stable
    (K,) = design.parameters
    assert 0.4 + K > 0.0 and 0.6 + 0.5 * abs(K) < 1.0  # F(0) > 0; strongly stable

    def parts(w: Any) -> tuple[Any, Any]:
        e = np.exp(-1.5j * w)
        return (1 + 0.1j * w) * (1 - 0.6 * e), K * (1 + 0.05j * w) * e

    def g(w: Any) -> Any:
        a, b = parts(w)
        return np.abs(a) ** 2 - np.abs(b) ** 2

    top = math.sqrt(max(K * K - 0.16, 0.0) / (0.0016 - 0.0025 * K * K)) + 1.0
    grid = np.linspace(1e-9, top, 200_001)
    values = g(grid)
    delays = []
    for i in np.flatnonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0):
        w = brentq(g, grid[i], grid[i + 1], xtol=1e-14)
        a, b = parts(w)
        theta = np.mod(np.angle(-b / a), 2 * np.pi)
        delays += [(theta + 2 * np.pi * k) / w for k in range(3)]
    assert delays and not any(window[0] <= d <= window[1] for d in delays)
    # the requirement binds: the first crossing delay lies just past d_max (1e-3: 100 times the last pattern step)
    np.testing.assert_allclose(min(delays), design.margin.margin, rtol=1e-9)
    assert window[1] < min(delays) < window[1] + 1e-3


def test_a_scenario_returning_no_pair_is_a_parameter_error() -> None:
    """A scenario (or the loop) returning anything but a pair (A, B) of QuasiPolynomials: a ParameterError at once."""
    calls = []

    def single(p: np.ndarray) -> nr.QuasiPolynomial:
        calls.append(p)
        return oscillator(p)[0]

    with pytest.raises(ParameterError, match=r"scenarios\[1\] must be .*returning a pair of QuasiPolynomials.*"):
        optimize_loop(oscillator, OSC_BOUNDS, delays=WINDOW, x0=[0.0, 0.3], scenarios=[oscillator, single])  # type: ignore[list-item]
    assert len(calls) == 1  # the first call raised
    for bad, got in (
        (lambda p: (*oscillator(p), 1.0), "tuple of QuasiPolynomial, QuasiPolynomial, float"),
        (lambda p: (1.0, 2.0), "tuple of float, float"),
    ):
        with pytest.raises(ParameterError, match=rf"scenarios\[0\] .*it returned a {got}"):
            optimize_loop(oscillator, OSC_BOUNDS, delays=WINDOW, x0=[0.0, 0.3], scenarios=[bad])  # type: ignore[list-item]
    with pytest.raises(ParameterError, match=r"loop must be .*returned a QuasiPolynomial"):
        optimize_loop(single, OSC_BOUNDS, x0=[0.0, 0.3])  # type: ignore[arg-type]


def test_state_feedback_window_binds() -> None:
    """A proportional law k u(t, 1) on a coupled plant: the window [0, 3] changes the design of the decay rate.

    The free design (decay rate 1.128 at k = -0.405, margin 2.635) has a crossing delay inside the window; the
    design under ``delays=(0, 3)`` trades decay rate for it. The verdicts are made again on the loop built
    directly from a controller (``nr.delay_margin`` of the plant and the controller, ``window_stability`` and
    the spectral abscissa of ``loop_factors``), not from the design's unit-gain loop family: at the free optimum
    and 1e-3 past the design towards it the decay rate is larger and the window is not met, so the window binds.
    (The free design itself is not run again: it costs twice the design under the window.)
    """
    plant = nr.Hyperbolic2x2(1.0, 1.0, 0.5, 0.5, 1.0, 0.3)
    design = design_state_feedback(plant, "decay_rate", delays=(0.0, 3.0), kernel_grid=None, starts=1)
    assert design.certified and design.design.delays == (0.0, 3.0) and design.design.windows[0].stable
    assert "stable for every delay in [0.0, 3.0] (the loop): met" in design.requirement
    margin = nr.delay_margin(plant, design.controller)
    assert margin.verified and margin.nominally_stable and margin.margin > 3.0
    assert window_stability(*loop_factors(plant, design.controller), (0.0, 3.0)).stable
    # the requirement binds: the margin is 3 to the pattern search's last step (1e-5 of the k bounds' width
    # 1.39 moves it by about 1e-4 here)
    assert margin.margin < 3.0 + 1e-3
    k = design.parameters[0]
    assert design.controller.k == k
    for other, gain in (("the free optimum", -0.405), ("1e-3 past the design", k - 1e-3)):
        law = replace(design.controller, k=gain)
        A, B = loop_factors(plant, law)
        rate = -nr.spectral_abscissa(A + B).value
        assert rate > design.value + (0.3 if gain == -0.405 else 0.0), other
        assert not window_stability(A, B, (0.0, 3.0)).stable, other
        assert nr.delay_margin(plant, law).margin < 3.0, other
    json.dumps(design.to_dict(), allow_nan=False)


@pytest.mark.long
def test_local_window_design_finds_the_exact_pair_birth() -> None:
    """The filter's pole b with K = 0.1, a = 0 on the paper's plant, margin maximised, stable on [0.1, 0.4].

    The exact one-parameter design ends at the pair birth b = 0.6298503342 (mpmath at 40 digits in
    tests/test_filter_cutoff.py, to 1e-10): past it towards smaller b a crossing pair is born with a
    delay inside the window. The local design (about 10 s of CPU) must stay on the feasible side and
    reach it to the pattern search's last step, 1e-5 of the width 1.2 (the margin falls as b grows).
    """
    plant = nr.Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
    design = design_filtered(
        plant, objective="margin", parameters={"K": 0.1, "a": 0.0, "b": (0.3, 1.5)}, delays=(0.1, 0.4), starts=1
    )
    assert design.certified and design.design.windows[0].stable
    b = design.controller.b
    assert 0.6298503342 - 1e-9 <= b <= 0.6298503342 + 5e-5
    assert "stable for every delay in [0.1, 0.4] (the loop): met" in design.requirement


def test_margin_objective_from_a_start_unstable_at_zero_delay() -> None:
    """The margin objective with ``d_min > 0`` from ``(-0.2, 0.05)``, unstable for every delay: designed, not refused.

    The margin objective requires a loop stable at ``delta = 0``: the phase before the first lowers the abscissa
    at ``delta = 0`` and at ``d_min`` below 0, and the design is certified. The closed-form oracle
    (:func:`_unstable_count`, :func:`crossing_delays`) confirms the start unstable at both delays and the design
    stable at ``delta = 0`` and on the window, with no crossing delay in it (its margin agrees: infinite when the
    oracle finds no crossing at all). Without a window, such a start is refused with what would help.
    """
    c0, K0 = -0.2, 0.05
    assert _unstable_count(c0, K0, 0.0) == 2 and _unstable_count(c0, K0, WINDOW[0]) == 2
    design = optimize_loop(oscillator, OSC_BOUNDS, delays=WINDOW, x0=[c0, K0], objective="margin")
    assert design.certified and design.windows[0].stable and design.margin.nominally_stable
    c, K = design.parameters
    assert _unstable_count(c, K, 0.0) == 0 and _unstable_count(c, K, WINDOW[0]) == 0
    delays = crossing_delays(c, K, 10.0)
    assert not any(WINDOW[0] <= d <= WINDOW[1] for d in delays)
    if delays:
        np.testing.assert_allclose(design.value, delays[0], rtol=1e-9)
    else:
        assert design.value == math.inf
    with pytest.raises(CertificationError, match="give an x0 stable at delta = 0"):
        optimize_loop(oscillator, OSC_BOUNDS, x0=[c0, K0], objective="margin", max_iter=5)


def test_a_scenario_of_the_wrong_arity_or_advanced_is_named() -> None:
    """A scenario that takes no argument is a ParameterError naming it, before any evaluation; an advanced one
    (``deg B > deg A``: ``gamma_0 = inf`` at every point) ends in a CertificationError naming it."""

    def nothing() -> None:
        return None

    def two(p: np.ndarray, q: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
        return oscillator(p)

    with pytest.raises(ParameterError, match=r"scenarios\[1\] must be a callable p -> \(A, B\) of one argument"):
        optimize_loop(oscillator, OSC_BOUNDS, delays=WINDOW, x0=[0.0, 0.3], scenarios=[oscillator, nothing])  # type: ignore[list-item]
    with pytest.raises(ParameterError, match=r"loop must be .* one argument .*; its signature is \(p, q\)"):
        optimize_loop(two, OSC_BOUNDS, x0=[0.0, 0.3])  # type: ignore[arg-type]

    def advanced(p: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
        return oscillator(p)[0], nr.QuasiPolynomial([[0.1, 0.0, 0.0, 1.0]], [0.0])

    with pytest.raises(CertificationError, match=r"gamma_0 = inf .* for scenario 1 \(advanced"):
        optimize_loop(
            oscillator, OSC_BOUNDS, delays=WINDOW, x0=[0.0, 0.3], scenarios=[oscillator, advanced], max_iter=5
        )
