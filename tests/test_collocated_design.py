"""Design of the reflection gain ``K`` for the collocated output feedback, and the scan through poles.

Oracles, none of which uses the scan of :mod:`nrobust.design.gain`:

* brute-force grids of certified delay margins (:func:`nrobust.delay_margin` at each gain, the
  loop built at that gain): the design must match or beat every point, and the grid's best must be
  within the Lipschitz bound of the grid spacing below it;
* the strong-stability interval of the collocated loop in closed form: for U_BS2(K),
  ``|rho - K| |q| + 2 |K rho| q^2 < 1`` (``|rho q| + |K q| + 2 |K rho| q^2 < 1`` with an observer
  delay), the default bounds being 0.9 times its ends;
* a loop with point delays only whose crossing curves pass through ``p = inf`` (``c_2 = |A_1|^2 -
  |B_1|^2`` changes sign at ``w = c / b_1 = 2``): its smooth maximum re-solved with mpmath at 40 digits
  from ``g = |A|^2 - |B|^2 = 0`` and ``d = arg(-B/A) / w``, ``dd/dw = 0``.
"""

from __future__ import annotations

import mpmath
import numpy as np
import pytest

import nrobust as nr
from nrobust.design import AffineLoop, best_margin
from nrobust.errors import ParameterError
from nrobust.hyperbolic.analyses.design import design_reflection
from nrobust.hyperbolic.loops.controllers import CollocatedOutputFeedback, ReflectionController, StateFeedback
from nrobust.margins import delay_margin as factor_margin
from nrobust.quasipoly import QuasiPolynomial

TRANSPORT = nr.TransportSystem(1.0, 1.0, 1.0, 0.85)
PAPER = nr.Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
WEAK = nr.Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.3)


def certified(plant, K, observer_delay=0.0):
    """The certified delay margin of the collocated loop built at ``K`` (0 when unstable at delta = 0)."""
    dm = nr.delay_margin(plant, CollocatedOutputFeedback(ReflectionController(float(K)), observer_delay))
    return (float(dm.margin) if dm.nominally_stable else 0.0), dm


@pytest.mark.parametrize(
    ("observer_delay", "ends"),
    # rho q = 0.85, q = 1: 0.85 - K + 1.7 K = 1 gives 3/14, 0.85 + 2.7 |K| = 1 gives 1/18
    [(0.0, (-0.15 / 2.7, 0.15 / 0.7)), (0.1, (-0.15 / 2.7, 0.15 / 2.7))],
)
def test_transport_bounds_and_no_crossing(observer_delay, ends):
    """On a transport plant ``A = 1 - rho q E + K q E e^{-delta_o s} - K rho q^2 E^2 e^{-delta_o s}`` and
    ``B = K rho q^2 E^2`` (``E = e^{-tau s}``, characteristics): ``|A| > |B|`` on the axis wherever the
    difference operator is strongly stable, so every gain of the bounds has an infinite margin."""
    result = design_reflection(TRANSPORT, output_feedback=True, collocated=True, observer_delay=observer_delay)
    np.testing.assert_allclose(result.design.bounds, 0.9 * np.array(ends), rtol=1e-14)  # closed-form ends
    assert isinstance(result.controller, CollocatedOutputFeedback)
    assert result.controller.observer_delay == observer_delay
    assert result.kind == "no crossing" and result.value == np.inf
    assert "collocated observer is exact" in result.design.certificate.scope
    margin, _ = certified(TRANSPORT, result.K, observer_delay)
    assert margin == np.inf


def test_bad_input():
    with pytest.raises(ParameterError, match="collocated"):
        design_reflection(TRANSPORT, collocated=True)
    with pytest.raises(ParameterError, match="observer_delay"):
        design_reflection(TRANSPORT, output_feedback=True, collocated=True, observer_delay=-1.0)


def test_general_plant_margin_is_its_normal_forms():
    """``delay_margin`` takes a general plant with a collocated feedback through its normal form, proven of that
    normal form as computed (its ``lam = mu = 1 + 2^-52``: ends ``1/lam`` off the doubles, a model before they were
    held by proven terms), as under ``StateFeedback``."""
    general = nr.GeneralHyperbolic2x2(lam=1.0, mu=1.0, a=0.0, b=0.5, c=0.5, d=0.0, q=0.5, rho=0.5)
    controller = CollocatedOutputFeedback(ReflectionController(0.1))
    on_general = nr.delay_margin(general, controller)
    on_form = nr.delay_margin(general.normal_form().system, controller)
    # the same loop up to the constant factor e^{D(L)} of the normal form: the same margin to rounding
    np.testing.assert_allclose(on_general.margin, on_form.margin, rtol=1e-12)
    assert 0.0 < on_general.margin < np.inf and not on_general.of_model
    assert "normal form as computed in floating point" in on_general.scope
    varying = nr.GeneralHyperbolic2x2(lambda x: 1.0 + x, 1.0, 0.0, 0.5, 0.5, 0.0, 0.5, 0.5)
    with pytest.raises(ParameterError, match="constant lam/mu"):
        nr.delay_margin(varying, CollocatedOutputFeedback(StateFeedback(-0.1)))


# ------------------------------------------------------------------ a loop whose curves pass through poles
A_COEF, C, B0, B1 = 0.6, 0.8, 1.5, 0.4
POLE_LOOP = AffineLoop(
    QuasiPolynomial([[1.0, A_COEF, 1.0]], [0.0]),  # s^2 + 0.6 s + 1
    QuasiPolynomial([[C]], [0.5]),  # + p 0.8 e^{-s/2}
    QuasiPolynomial([[B0]], [0.0]),  # (1.5
    QuasiPolynomial([[0.0, B1]], [0.0]),  # + p 0.4 s) e^{-delta s}
)
BOUNDS = (-1.5, 1.5)


def mp_branch(w, K0):
    """``(K, d)`` on the crossing curve through ``K0`` at ``w`` (40 digits): the root of ``g`` nearest ``K0``."""
    s = 1j * w
    A0, A1 = s**2 + A_COEF * s + 1, C * mpmath.exp(-s / 2)
    b0, b1 = mpmath.mpf(B0), B1 * s
    c2 = abs(A1) ** 2 - abs(b1) ** 2
    h = mpmath.re(mpmath.conj(A0) * A1) - mpmath.re(mpmath.conj(b0) * b1)
    c0 = abs(A0) ** 2 - abs(b0) ** 2
    roots = [(-h + sign * mpmath.sqrt(h * h - c0 * c2)) / c2 for sign in (1, -1)]
    K = min(roots, key=lambda r: abs(r - K0))
    theta = mpmath.arg(-(b0 + K * b1) / (A0 + K * A1)) % (2 * mpmath.pi)
    return K, theta / w


def test_scan_through_poles_matches_mpmath_and_grid():
    mpmath.mp.dps = 40
    design = best_margin(POLE_LOOP, BOUNDS)
    # brute force: certified margins on 61 gains
    grid = np.linspace(*BOUNDS, 61)
    margins = []
    for K in grid:
        dm = factor_margin(POLE_LOOP.A(K), POLE_LOOP.B(K))
        margins.append(float(dm.margin) if dm.nominally_stable else 0.0)
    best = int(np.argmax(margins))
    assert design.value >= max(margins) - 1e-12
    # the grid's best is within (largest slope of the grid) x (spacing) of the design
    slope = np.max(np.abs(np.diff(margins))) / (grid[1] - grid[0])
    assert design.value - margins[best] <= slope * (grid[1] - grid[0])
    # the smooth maximum from the grid's best, independently: dd/dw = 0 along its crossing curve
    K0 = grid[best]
    w0 = factor_margin(POLE_LOOP.A(K0), POLE_LOOP.B(K0)).omega
    w_star = mpmath.findroot(lambda w: mpmath.diff(lambda x: mp_branch(x, K0)[1], w), mpmath.mpf(w0))
    K_star, d_star = mp_branch(w_star, K0)
    assert design.kind == "interior smooth max"
    # K at a smooth maximum is known to the curvature's sqrt of rounding; the value to rounding
    np.testing.assert_allclose(design.K, float(K_star), rtol=1e-6)
    np.testing.assert_allclose(design.value, float(d_star), rtol=1e-12)
    # the envelope drawn by the scan is the brute-force margin to its interpolation (1e-4 relative)
    on_grid = np.interp(grid, design.gains, design.envelope)
    np.testing.assert_allclose(on_grid, margins, rtol=1e-4)


# ------------------------------------------------------------------ coupled plants (long)
def check_against_grid(plant, result, grid):
    """The design matches or beats every certified margin of ``grid``, whose best is within its spacing's effect."""
    margins = np.array([certified(plant, K)[0] for K in grid])
    assert result.value >= margins.max() - 1e-9 * result.value
    slope = np.max(np.abs(np.diff(margins))) / (grid[1] - grid[0])
    assert result.value - margins.max() <= slope * (grid[1] - grid[0])
    # the design's own margin, certified on the loop built at its gain (not the affine model)
    margin, _ = certified(plant, result.K)
    np.testing.assert_allclose(margin, result.value, rtol=1e-9)
    return margins


def check_kink(plant, result, h):
    """A kink: lower on both sides, and the smallest crossing on two different curves (frequencies)."""
    (left, dm_left), (right, dm_right) = certified(plant, result.K - h), certified(plant, result.K + h)
    assert left < result.value and right < result.value
    assert abs(dm_left.omega - dm_right.omega) > 0.1 * max(dm_left.omega, dm_right.omega)


@pytest.mark.long
def test_weak_reflection_kink_against_grid():
    result = design_reflection(WEAK, output_feedback=True, collocated=True, K_bounds=(-0.3, 0.5))
    assert result.kind == "kink"
    check_against_grid(WEAK, result, np.linspace(-0.3, 0.5, 9))
    check_kink(WEAK, result, 1e-4)


@pytest.mark.long
@pytest.mark.timeout(1800)  # about a minute of CPU for the design and one more for the grid; more on a loaded machine
def test_paper_plant_kink_against_grid():
    """The paper's plant (rho q = 0.85) with the default bounds ``0.9 (-1/18, 3/14)``; its collocated loop is
    proven (``test_collocated_proof.py``), so the certificate is about the PDE, not a model."""
    result = design_reflection(PAPER, output_feedback=True, collocated=True)
    np.testing.assert_allclose(result.design.bounds, (-0.05, 0.9 * 0.15 / 0.7), rtol=1e-14)
    assert result.kind == "kink" and not result.design.certificate.of_model
    check_against_grid(PAPER, result, np.linspace(-0.05, 0.19, 13))
    check_kink(PAPER, result, 1e-4)


@pytest.mark.long
def test_weak_reflection_decay_rate_under_margin():
    """At ``delta = 0`` the collocated loop is the target system ``1 - (rho - K) q e^{-tau s}`` (eqs. (56)-(58)):
    its decay rate ``-ln |(rho - K) q| / tau`` in closed form; the requirement holds on the loop built at K."""
    result = design_reflection(
        WEAK, "decay_rate", margin_at_least=0.55, output_feedback=True, collocated=True, K_bounds=(-0.3, 0.5)
    )
    rate = -np.log(abs((WEAK.rho - result.K) * WEAK.q)) / WEAK.tau
    np.testing.assert_allclose(result.value, rate, rtol=1e-10)  # the abscissa's accuracy, 2e-13, with room
    assert result.kind == "margin constraint" and result.design.end.kind == "crossing"
    margin, _ = certified(WEAK, result.K)
    assert margin >= 0.55
    # past the end (a gain 1e-4 further towards rho, whose rate is larger) the requirement fails
    assert certified(WEAK, result.K + 1e-4)[0] < 0.55
