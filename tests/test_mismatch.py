"""Speed mismatch: the nominal law on a plant whose transport speeds are off.

Oracles independent of the code under test: on a transport plant the mismatched loop is
written here from the characteristics (the law ``U = -K u(t, 1)`` holds no speed, only the
round trip ``tau`` changes), with its spectral abscissa and its delay margin in closed form
or solved here from the crossing equation; on the paper's plant, the nominal loop of
``U_BS2(0.1)`` (exact route) and the growth rate of a simulation of the PDE.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from nrobust import (
    FilteredController,
    Hyperbolic2x2,
    ParameterError,
    ReflectionController,
    TransportSystem,
    loop_factors,
    simulate,
    solve_kernels,
)
from nrobust.hyperbolic.analyses import MismatchRegion, mismatch_loop, mismatch_region
from nrobust.margins import delay_margin
from nrobust.roots import spectral_abscissa

PAPER = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
AXIS = 1j * np.linspace(0.0, 40.0, 161)


def _round_trip(lam: float, mu: float, e_lam: float, e_mu: float) -> float:
    return 1.0 / (lam * (1.0 + e_lam)) + 1.0 / (mu * (1.0 + e_mu))


@pytest.mark.parametrize(("e_lam", "e_mu"), [(0.0, 0.0), (0.3, -0.2), (-0.5, 1.5)])
def test_transport_loop_and_decay_in_closed_form(e_lam: float, e_mu: float) -> None:
    # U = -K u(t, 1); along the characteristics u(t, 1) = q v(t - tau', 1) with
    # tau' = 1/lam' + 1/mu', so v(t, 1) = rho q v(t - tau', 1) - K q v(t - tau' - delta, 1):
    # F(s; delta) = 1 - rho q e^{-tau' s} + K q e^{-(tau' + delta) s}; without delay
    # 1 - (rho - K) q e^{-tau' s}, whose zeros all lie on Re s = ln|(rho - K) q| / tau'.
    lam, mu, q, rho, K = 2.0, 0.5, 0.9, 0.8, 0.3
    plant = TransportSystem(lam, mu, q, rho)
    tau = _round_trip(lam, mu, e_lam, e_mu)
    A, B = mismatch_loop(plant, ReflectionController(K), e_lam, e_mu)
    # exact route: tau is the double nearest 1/lam' + 1/mu' (a few ulps), |s| <= 40
    np.testing.assert_allclose(A(AXIS), 1.0 - rho * q * np.exp(-tau * AXIS), rtol=0, atol=1e-12)
    np.testing.assert_allclose(B(AXIS), K * q * np.exp(-tau * AXIS), rtol=0, atol=1e-12)
    abscissa = spectral_abscissa(A + B).value
    np.testing.assert_allclose(abscissa, math.log(abs((rho - K) * q)) / tau, rtol=0, atol=1e-10)
    # |rho q| + |K q| = 0.99 < 1 and |(rho - K) q| < 1: no crossing for any tau', margin inf
    assert delay_margin(A, B).margin == math.inf


def test_transport_zero_margin_for_every_mismatch() -> None:
    # |rho q| + |K q| = 1.2 > 1: the difference operator is not strongly stable for small
    # delta > 0 whatever tau', so the margin is 0 at every mismatch
    plant = TransportSystem(1.0, 1.0, 1.0, 0.7)
    for e in (-0.4, 0.0, 0.8):
        assert delay_margin(*mismatch_loop(plant, ReflectionController(0.5), e, -0.5 * e)).margin == 0.0


def _filtered_margin(g: float, a: float, b: float, tau: float) -> float:
    """First crossing delay of (1 + b s)(1 - g e^{-tau s}) + (1 + a s) g e^{-(tau + delta) s}, solved here.

    A crossing frequency is a zero of h(w) = (1 + b^2 w^2)|1 - g e^{-i w tau}|^2 - (1 + a^2 w^2) g^2;
    h > 0 beyond w^2 = (g^2 - (1 - |g|)^2) / (b^2 (1 - |g|)^2 - a^2 g^2).
    """

    def h(w: float) -> float:
        return (1 + b * b * w * w) * (1 - 2 * g * math.cos(w * tau) + g * g) - (1 + a * a * w * w) * g * g

    top = 1.01 * math.sqrt((g * g - (1 - abs(g)) ** 2) / (b * b * (1 - abs(g)) ** 2 - a * a * g * g))
    w = np.linspace(1e-9, top, 20001)
    values = np.array([h(x) for x in w])
    delays = []
    for i in np.flatnonzero(np.sign(values[:-1]) != np.sign(values[1:])):
        wc = brentq(h, w[i], w[i + 1], xtol=1e-15)
        ratio = -(1 + 1j * b * wc) * (1 - g * np.exp(-1j * wc * tau)) / ((1 + 1j * a * wc) * g * np.exp(-1j * wc * tau))
        delays.append((-np.angle(ratio)) % (2 * math.pi) / wc)  # e^{-i w delta} = ratio
    return min(delays)


@pytest.mark.parametrize(("e_lam", "e_mu"), [(0.0, 0.0), (0.2, 0.0), (0.0, -0.3), (-0.25, 0.4)])
def test_transport_filtered_margin_depends_on_tau_only(e_lam: float, e_mu: float) -> None:
    # U_1 = -(1 + a s)/(1 + b s) rho u(1, s) (section 2.3.2): the mismatch moves tau only
    lam, mu, q, rho, a, b = 1.0, 2.0, 1.0, 0.6, 0.05, 0.5
    A, B = mismatch_loop(TransportSystem(lam, mu, q, rho), FilteredController(a, b), e_lam, e_mu)
    dm = delay_margin(A, B)
    assert dm.nominally_stable
    expected = _filtered_margin(rho * q, a, b, _round_trip(lam, mu, e_lam, e_mu))
    # both solve the crossing equation to ~1e-15 in w; the delay carries its conditioning
    np.testing.assert_allclose(dm.margin, expected, rtol=1e-10)


def test_transport_filtered_region_ends_against_the_crossing_equation() -> None:
    # the margin of the filtered U_BS falls from 4.84 (e = 0) as tau' shrinks: the upper
    # ends along both axes are continuous crossings of delta_max = 4, located by brentq to
    # 1e-9 in e; the margin's slope there is about 2, so the oracle reads 4 within 1e-8
    lam, mu, q, rho, a, b = 1.0, 2.0, 1.0, 0.6, 0.05, 0.5
    region = mismatch_region(
        TransportSystem(lam, mu, q, rho), FilteredController(a, b), [0.0, 0.5], [0.0, 2.0], 4.0, tol=1e-9
    )
    assert region.admissible.tolist() == [[True, False], [False, False]]
    for name, (lower, upper) in region.extent.items():
        assert lower.kind == "grid_end" and upper.kind == "crossing"
        assert upper.inside <= upper.e <= upper.outside
        assert abs(upper.outside - upper.inside) <= 1.01e-9  # brentq: xtol plus 4 ulps

        def oracle(e: float, name: str = name) -> float:
            pair = (e, 0.0) if name == "e_lam" else (0.0, e)
            return _filtered_margin(rho * q, a, b, _round_trip(lam, mu, *pair))

        np.testing.assert_allclose(oracle(upper.e), 4.0, rtol=0, atol=1e-8)
        assert oracle(upper.inside) > 4.0 - 1e-12 and oracle(upper.outside) < 4.0 + 1e-12


def test_zero_mismatch_is_the_nominal_loop() -> None:
    # the kernel route (nominal gains and N~, M on 201 points) against the exact route of
    # U_BS2(0.1): |A - A0|, |B - B0| measured 7e-10 and 9e-10 on |s| <= 30, the margins 1e-10 apart
    controller = ReflectionController(0.1)
    A, B = mismatch_loop(PAPER, controller, 0.0, 0.0)
    A0, B0 = loop_factors(PAPER, controller)
    np.testing.assert_allclose(A(AXIS), A0(AXIS), rtol=0, atol=1e-8)
    np.testing.assert_allclose(B(AXIS), B0(AXIS), rtol=0, atol=1e-8)
    np.testing.assert_allclose(delay_margin(A, B).margin, delay_margin(A0, B0).margin, rtol=1e-8)


def test_bad_arguments_are_refused_before_work() -> None:
    with pytest.raises(ParameterError, match="e_mu"):
        mismatch_loop(PAPER, ReflectionController(0.1), 0.0, -1.0)
    with pytest.raises(ParameterError, match="MAX_MISMATCH_POINTS"):
        mismatch_region(PAPER, ReflectionController(0.1), np.linspace(-0.5, 0.5, 100), np.linspace(0, 1, 100), 0.1)
    with pytest.raises(ParameterError, match="delta_max"):
        mismatch_region(PAPER, ReflectionController(0.1), [0.0], [0.0], -0.1)


def test_transport_region_is_exact_route_and_everything() -> None:
    # strongly stable U_BS2 on a transport plant: admissible at every mismatch (margin inf)
    region = mismatch_region(
        TransportSystem(1.0, 1.0, 1.0, 0.6), ReflectionController(0.3), [-0.5, 0.5], [0.0, 2.0], 0.1
    )
    assert isinstance(region, MismatchRegion)
    assert region.route == "exact" and region.scope.startswith("the PDE itself")
    assert region.admissible.all() and np.all(region.margins == math.inf)
    assert {end.kind for pair in region.extent.values() for end in pair} == {"grid_end"}
    assert region.to_dict()["extent"]["e_mu"][1]["e"] == 2.0
    # the same grid on a process pool of one worker: the same verdicts
    pooled = mismatch_region(
        TransportSystem(1.0, 1.0, 1.0, 0.6), ReflectionController(0.3), [-0.5, 0.5], [0.0, 2.0], 0.1, executor=1
    )
    assert pooled.extent == region.extent and np.array_equal(pooled.margins, region.margins)


@pytest.mark.long
def test_simulation_growth_agrees_with_the_verdict() -> None:
    # U_BS2(0.1) designed for the paper's plant, delay 0.1. Certified: mu 10 % slower keeps
    # the margin above 0.1 (inside), mu twice as fast brings it below 0.1 (outside).
    controller, delta = ReflectionController(0.1), 0.1
    law = controller.feedback_law(PAPER, solve_kernels(PAPER, 201))
    for e_mu, inside in ((-0.1, True), (1.0, False)):
        dm = delay_margin(*mismatch_loop(PAPER, controller, 0.0, e_mu))
        assert dm.nominally_stable and (dm.margin > delta) == inside
        sim = simulate(Hyperbolic2x2(1.0, 1.0 + e_mu, 1.0, 1.0, 1.0, 0.85), law, delta, 30.0, 1.0, 1.0, cells=100)
        times, norm = np.asarray(sim.times), np.asarray(sim.norm)
        late = times > 15.0
        rate = np.polyfit(times[late], np.log(norm[late]), 1)[0]
        # measured -0.047 and +0.115 (spectral abscissae -0.021 and +0.116)
        assert (rate < 0.0) == inside
