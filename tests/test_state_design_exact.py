"""``design_state_feedback`` without a basis: the exact one-gain engine, against brute-force grids.

``U = k u(t, 1)`` on ``Hyperbolic2x2(1, 1, 1.5, 0.5, 0.8, 0.4)`` (the exact route of its loop) with the
default bounds ``|k| <= 0.8415`` (strong stability of the delayed loop). The decay rate peaks at
``k = -0.5107675``, where a complex pair and a real zero cross (rate 1.2060128; the local search stopped
at ``k = -0.5107856``, 1.2059360, in 13-18 s); the margin rises up to the end of nominal stability,
``F(0; 0, k) = 0``, where a real zero leaves through ``s = 0`` (the exact engine refused that end: "no
equation found"). On the paper's plant no ``k`` of the default bounds stabilises the loop: a
``ParameterError`` about ``k_bounds``. The oracles: certified spectral abscissae and delay margins at
81 gains, the closed form of the end, and the crossing of the two zeros by scipy's Newton and
``brentq`` (no code of the design).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

import nrobust as nr
from nrobust.design import best_decay_rate
from nrobust.errors import ParameterError
from nrobust.hyperbolic.analyses.state_design import StateFeedbackLoop, state_feedback_loop
from nrobust.margins import AffineGainLoop, delay_margin
from nrobust.roots import spectral_abscissa

PLANT = nr.Hyperbolic2x2(1, 1, 1.5, 0.5, 0.8, 0.4)


@pytest.fixture(scope="module")
def loop() -> StateFeedbackLoop:
    return state_feedback_loop(PLANT)


def _zero(loop: StateFeedbackLoop, k: float, s: complex) -> complex:
    """Newton's method on ``A + k B_k`` from ``s``, to rounding."""
    F = loop.A + loop.units[0] * k
    for _ in range(40):
        step = complex(F(np.array([s]))[0] / F.deriv_at(np.array([s]))[0])
        s -= step
        if abs(step) <= 1e-15 * abs(s):
            break
    return s


def _crossing(loop: StateFeedbackLoop) -> tuple[float, float]:
    """The gain where the complex pair near ``-1.2 + 4.47i`` and the real zero near ``-1.2`` have one real part."""

    def gap(k: float) -> float:
        return _zero(loop, k, -1.2 + 4.47j).real - _zero(loop, k, -1.2 + 0j).real

    k = brentq(gap, -0.5115, -0.5100, xtol=1e-15, rtol=1e-15)
    return k, -_zero(loop, k, -1.2 + 0j).real


@pytest.mark.parametrize("margin_at_least", [None, pytest.param(0.2, marks=pytest.mark.long)])
def test_decay_rate_against_a_grid(loop: StateFeedbackLoop, margin_at_least: float | None) -> None:
    design = nr.design_state_feedback(PLANT, "decay_rate", margin_at_least=margin_at_least, kernel_grid=None)
    assert design.certified and not design.design.local
    if margin_at_least is not None:
        assert design.design.margin.margin >= margin_at_least
    # 81 gains over the stable part of the bounds (the rate is negative right of k = -0.24)
    ks = np.linspace(-0.8415, -0.24, 81)
    rates = np.array([-spectral_abscissa(loop.A + loop.units[0] * float(k)).value for k in ks])
    best = int(np.argmax(rates))
    assert delay_margin(loop.A, loop.units[0] * float(ks[best])).margin >= 0.2  # feasible for both requirements
    # matched or beaten (1e-9: the rates' errors are ~1e-14, the design's K within 1e-10 of the peak)
    assert design.value >= rates[best] - 1e-9
    # the true optimum is the crossing of the two zeros: the design reaches it to its stated accuracy
    # (K to 2e-10; the rate's slopes, below 35 per unit of k, times that, plus rounding)
    k, rate = _crossing(loop)
    assert design.design.runs[0].reason.endswith("kink")
    np.testing.assert_allclose(design.parameters[0], k, rtol=0, atol=2e-10)
    np.testing.assert_allclose(design.value, rate, rtol=0, atol=35 * 2e-10 + 1e-12)


# The decay-rate designs on the kernel grid of 201 points (the default until the exact route became it: the exact
# designs differ by up to 1.3e-8, the grid's error) (k, rate, Im of the rightmost zero, margin, its
# crossing frequency), as computed when
# each function of the root paths was evaluated by its own numpy call and the designed loop's abscissa computed
# again: the single-point evaluation (QuasiPolynomialsAtPoint) and the engine's abscissa taken for the equal
# loop move them by 1-2 ulps (measured); 1e-12 relative is the stated tolerance of that change.
RECORDED = {
    1.0: (-0.5107675457954793, 1.2060128064764166, 4.468934951761815, 1.0874071412468305, 0.6378931323010821),
    None: (-0.5107675457954779, 1.2060128064764228, 4.4689349517618115, 1.0874071412468336, 0.6378931323010802),
}


@pytest.mark.parametrize("margin_at_least", [1.0, None])
def test_decay_rate_designs_as_recorded(margin_at_least: float | None) -> None:
    design = nr.design_state_feedback(PLANT, "decay_rate", margin_at_least=margin_at_least, kernel_grid=201)
    loop = state_feedback_loop(PLANT, kernel_grid=201)
    d = design.design
    assert design.certified and d.runs[0].reason.endswith("kink")
    assert d.abscissa.root is not None
    got = [design.parameters[0], d.value, d.abscissa.root.imag, d.margin.margin, d.margin.omega]
    np.testing.assert_allclose(got, RECORDED[margin_at_least], rtol=1e-12, atol=0)
    # the abscissa taken from the engine is the designed loop's: computed again from the loop, the same
    again = spectral_abscissa(loop.A + loop.units[0] * design.parameters[0])
    assert (again.value, again.root, again.certified) == (d.abscissa.value, d.abscissa.root, d.abscissa.certified)


def test_gain_design_holds_its_nominal_loop(loop: StateFeedbackLoop) -> None:
    """``GainDesign.nominal`` is ``F(.; 0, K)``, the loop of ``GainDesign.abscissa``, and stays out of ``to_dict``."""
    gain = best_decay_rate(AffineGainLoop(loop.A, loop.units[0] * 0.0, loop.units[0]), (-0.8415, 0.8415))
    assert gain.nominal == loop.A + loop.units[0] * gain.K
    assert spectral_abscissa(loop.A + loop.units[0] * gain.K).value == gain.abscissa.value
    assert "nominal" not in gain.to_dict()


def test_margin_against_a_grid(loop: StateFeedbackLoop) -> None:
    design = nr.design_state_feedback(PLANT, "margin", kernel_grid=None)
    assert design.certified and not design.design.local
    # the end of nominal stability in closed form: s = 0 a zero of A + k B_k
    zero = np.zeros(1)
    k0 = float((-loop.A(zero)[0] / loop.units[0](zero)[0]).real)
    # the design is that end moved 1e-10 (relative to the bounds, 0.8415) inside, to the stable side
    np.testing.assert_allclose(design.parameters[0], k0 - 0.8415e-10, rtol=0, atol=1e-12)
    ks = np.linspace(-0.8415, k0 - 1e-6, 81)
    margins = np.array([delay_margin(loop.A, loop.units[0] * float(k)).margin for k in ks])
    # none beats the design (1e-9: the certificates' accuracy); the last gain, 1e-6 before the end, is
    # within the margin's slope there (below 10 per unit of k) times that distance
    assert np.all(margins <= design.value * (1.0 + 1e-9))
    np.testing.assert_allclose(margins[-1], design.value, rtol=0, atol=10 * 1e-6)


@pytest.mark.long  # about a minute of CPU: make fuzz runs it
def test_paper_plant_has_no_stable_proportional_gain() -> None:
    paper = nr.Hyperbolic2x2(1, 1, 1, 1, 1, 0.85)
    for objective, margin in (("margin", None), ("decay_rate", None)):
        with pytest.raises(ParameterError) as info:
            nr.design_state_feedback(paper, objective, margin_at_least=margin)
        assert info.value.name == "k_bounds"
        assert "certified" in str(info.value) and "basis" in str(info.value)
    # the oracle: a zero in Re s > 0 at each of 21 gains of the default bounds 0.99 (1 - rho q) / q
    family = state_feedback_loop(paper)
    ks = np.linspace(-0.1485, 0.1485, 21)
    assert all(spectral_abscissa(family.A + family.units[0] * float(k)).value > 0.8 for k in ks)


@pytest.mark.slow
def test_the_default_route_is_exact_and_a_speed_tolerance_holds(loop: StateFeedbackLoop) -> None:
    """Without a basis the default is the exact route (it was 201 kernel points): the design is the exact loop's
    crossing of its two rightmost zeros (``_crossing`` on ``state_feedback_loop(PLANT)``, the exact route; ``k`` to
    2e-10 as above) with the PDE's scope, and a speed tolerance certified at the corners on ``mismatch_loop``'s exact
    loops, where the 201-point design was refused ("the design's own loops and these differ")."""
    design = nr.design_state_feedback(PLANT, "decay_rate", margin_at_least=1.0)
    assert design.scope.startswith("the PDE itself")
    k, _ = _crossing(loop)
    np.testing.assert_allclose(design.parameters[0], k, rtol=0, atol=2e-10)
    tolerant = nr.design_state_feedback(
        PLANT, "decay_rate", margin_at_least=1.0, speed_tolerance=0.05, k_bounds=(-0.8, -0.3), starts=1
    )
    assert tolerant.tolerance is not None and tolerant.tolerance.met
