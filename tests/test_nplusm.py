"""n + m hyperbolic systems: the Laplace route against the kernel route, closed forms and simulation."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

from nrobust import (
    Hyperbolic2x2,
    ParameterError,
    QuasiPolynomial,
    TransportSystem,
    count_roots,
    delay_margin,
    find_roots,
    simulate,
    spectral_abscissa,
)
from nrobust.hyperbolic.loops.controllers import (
    FeedbackLaw,
    OpenLoop,
    ReflectionController,
    StateFeedback,
    characteristic,
)
from nrobust.hyperbolic.nplusm import (
    NPlusMCharacteristic,
    NPlusMSystem,
    multi_actuator_margin,
    nplusm_delay_margin,
)
from nrobust.hyperbolic.simulate import simulate_nplusm

PAPER = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
# a coupled 2 + 1 system (distinct speeds) with one actuator
TWO_ONE = NPlusMSystem(
    [1.0, 0.5], [1.5], [[0.0, 0.0, 0.4], [0.0, 0.0, 0.3], [0.5, -0.4, 0.0]], [[0.6], [0.5]], [[0.5, 0.4]]
)
GAIN = [[-0.5, 0.0]]
# two u components of equal speed coupled to each other (a non-diagonal block C_d)
SAME_SPEED = [[0.0, 0.3, 0.0, 0.4], [0.2, 0.0, 0.1, 0.3], [0.0, 0.2, 0.0, 0.2], [0.5, -0.4, 0.3, 0.0]]
# strongly coupled 2 + 1: two crossing frequencies
MULTI = [[0.0, 0.81, -0.86], [0.99, 0.0, 0.98], [-1.01, -0.37, 0.0]]


def _profiles(x: np.ndarray) -> np.ndarray:
    return np.vstack([np.sin(np.pi * x) + 0.3, np.cos(2 * x), 1 + x * x])


@pytest.mark.slow
def test_paper_plant_as_one_plus_one() -> None:
    """The 1 + 1 Laplace route equals the delay form of the kernel route (eq. (39))
    to the kernel grid's accuracy, and so do the certified open-loop roots."""
    F = NPlusMCharacteristic(NPlusMSystem.from_2x2(PAPER))
    Fq = characteristic(PAPER, OpenLoop(), 0.0)
    s = np.array([0.1 + 1j, -0.3 + 10j, 0.5 - 30j, -1.0 + 3j])
    np.testing.assert_allclose(F(s), Fq(s), rtol=1e-8)
    np.testing.assert_allclose(F.deriv_at(s), Fq.deriv_at(s), rtol=1e-7)
    region = (-1.5, 1.0, -0.25, 13.0)
    new, old = find_roots(F, region), find_roots(Fq, region)
    assert new.certified and old.certified and new.count == old.count == 5
    # measured difference 2.5e-10: the kernel route's error at the default grid
    np.testing.assert_allclose(new.roots, old.roots, atol=1e-8)
    assert F.principal_part().gamma_0 == pytest.approx(0.85)


def test_bounds_hold_on_segments() -> None:
    F = NPlusMCharacteristic(TWO_ONE, GAIN, 2.0)
    rng = np.random.default_rng(3)
    a = rng.uniform(-1.5, 1.5, 20) + 1j * rng.uniform(-20, 20, 20)
    b = a + 0.4 * (rng.uniform(-1, 1, 20) + 1j * rng.uniform(-1, 1, 20))
    t = np.linspace(0.0, 1.0, 11)
    pts = a[:, None] + (b - a)[:, None] * t[None, :]
    d1 = np.abs(F.deriv_at(pts.ravel())).reshape(pts.shape).max(axis=1)
    h = 1e-5
    d2 = np.abs((F.deriv_at(pts.ravel() + h) - F.deriv_at(pts.ravel() - h)) / (2 * h)).reshape(pts.shape).max(axis=1)
    assert np.all(d1 <= F.deriv_bound(a, b)) and np.all(d2 <= F.derivative().deriv_bound(a, b))
    # F' by Van Loan's block exponential against a central difference
    s = np.array([0.2 + 3j, -0.7 - 9j])
    np.testing.assert_allclose(F.deriv_at(s), (F(s + 1e-6) - F(s - 1e-6)) / 2e-6, rtol=1e-6)


def test_uncoupled_is_the_closed_form() -> None:
    """Sigma = 0: F = 1 - sum_i (R_i + K_i e^{-delta s}) Q_i e^{-(1/lam_i + 1/mu) s} exactly."""
    sys = NPlusMSystem([1.0, 0.4], [2.0], np.zeros((3, 3)), [[0.7], [-0.5]], [[0.3, 0.6]])
    K, delta = [[-0.2, 0.1]], 0.3
    F = NPlusMCharacteristic(sys, K, delta)
    t1, t2 = 1.0 + 0.5, 2.5 + 0.5
    Q = QuasiPolynomial(
        [[1.0], [-0.3 * 0.7], [-0.6 * -0.5], [0.2 * 0.7], [-0.1 * -0.5]], [0.0, t1, t2, t1 + delta, t2 + delta]
    )
    s = np.array([0.3 + 2j, -0.5 + 17j])
    np.testing.assert_allclose(F(s), Q(s), rtol=1e-12)
    D = sys.principal_operator(K, delta)
    np.testing.assert_allclose(D.delays, [t1, t1 + delta, t2, t2 + delta])
    g = D.gamma_0()
    assert g.lower <= 0.21 + 0.3 + 0.14 + 0.05 <= g.upper


@pytest.mark.parametrize("rho, K", [(0.4, 0.3), (0.85, 0.3), (0.4, 0.7), (0.4, -0.3)])
def test_transport_margins_match_the_certified_core(rho: float, K: float) -> None:
    """Uncoupled 1 + 1 with U = -K u(t - delta, 1): the margin of the core's certified
    delay_margin(A, B) on the transport loop (0 when |rho q| + |K q| >= 1, else infinite)."""
    plant = TransportSystem(lam=1.0, mu=2.0, q=1.0, rho=rho)
    core = delay_margin(plant, ReflectionController(K))
    ours = nplusm_delay_margin(NPlusMSystem.from_2x2(plant), [[-K]])
    assert ours.margin == core.margin and ours.gamma_0 == pytest.approx(rho + abs(K))


@pytest.mark.slow
def test_full_cancellation_doubles_gamma() -> None:
    """K = -R: the delay-free loop has no reflection, but gamma_0 of the delayed loop is 2 sum |R Q|."""
    v = np.exp(-TWO_ONE.sigma[2, 2] / 1.5)
    _, terms = TWO_ONE.principal_terms()
    rq = sum(abs(float(t[1][0, 0])) for t in terms) / v
    full = nplusm_delay_margin(TWO_ONE, [[-0.5, -0.4]])
    assert full.gamma_0 == pytest.approx(2 * rq) and full.margin == (0.0 if 2 * rq >= 1 else full.margin)
    half = nplusm_delay_margin(TWO_ONE, [[-0.25, -0.2]])
    assert half.gamma_0 == pytest.approx(1.5 * rq)


@pytest.mark.slow
def test_margin_against_certified_abscissa_and_simulation() -> None:
    """At 0.9 and 1.1 times the margin the certified abscissa changes sign; the simulated
    growth rates match the abscissae (fit on [120, 240]: beating with the next mode leaves
    about 1e-3, measured 9e-4)."""
    m = nplusm_delay_margin(TWO_ONE, GAIN)
    assert 0 < m.margin < np.inf and m.gamma_0 == pytest.approx(0.8) and m.omega is not None
    F = NPlusMCharacteristic(TWO_ONE, GAIN, m.margin)
    assert abs(complex(F(np.array([1j * m.omega]))[0])) < 1e-10
    band = (-1.0, 1.0, -0.25, 6.0)
    below = spectral_abscissa(NPlusMCharacteristic(TWO_ONE, GAIN, 0.9 * m.margin), band)
    above = spectral_abscissa(NPlusMCharacteristic(TWO_ONE, GAIN, 1.1 * m.margin), band)
    assert below.certified and above.certified and below.value < 0 < above.value
    sim = simulate_nplusm(TWO_ONE, GAIN, 1.1 * m.margin, 240.0, _profiles, cells=40)
    np.testing.assert_allclose(sim.growth_rate(120.0), above.value, atol=2e-3)


def test_simulation_converges_to_the_abscissa() -> None:
    """Delay-free loop: growth rate of the simulated PDE vs the certified abscissa, second order (Heun)."""
    exact = spectral_abscissa(NPlusMCharacteristic(TWO_ONE, GAIN, 0.0), (-1.0, 1.0, -0.25, 6.0)).value
    errs = [
        abs(simulate_nplusm(TWO_ONE, GAIN, 0.0, 40.0, _profiles, cells=c).growth_rate(20.0) - exact) for c in (10, 20)
    ]
    assert errs[1] < 2e-4
    assert np.log2(errs[0] / errs[1]) > 1.5  # observed order (measured about 2)


@pytest.mark.slow
def test_coupled_two_by_two_static_feedback_against_the_kernel_simulator() -> None:
    """U = -0.3 u(t - 1, 1) on the paper plant: the 1 + 1 abscissa against the 2x2 simulator."""
    sys = NPlusMSystem.from_2x2(PAPER)
    F = NPlusMCharacteristic(sys, [[-0.3]], 1.0)
    ab = spectral_abscissa(F, (-1.0, 1.5, -0.25, 8.0))
    assert ab.certified

    def zero(x: np.ndarray) -> np.ndarray:
        return np.zeros_like(x)

    run = simulate(PAPER, FeedbackLaw(-0.3, zero, zero), 1.0, 12.0, lambda x: np.sin(3 * x) + 1, zero, cells=200)
    keep = run.times > 6.0
    rate = np.polyfit(run.times[keep], np.log(run.norm[keep]), 1)[0]
    np.testing.assert_allclose(rate, ab.value, atol=2e-2)


ONE = NPlusMSystem([1.0], [1.0], [[0.0, 0.5], [0.4, 0.0]], [[0.8]], [[0.5]])
TWO = NPlusMSystem([0.5], [2.0], [[0.0, -0.3], [0.6, 0.0]], [[0.7]], [[-0.4]])
BOTH = NPlusMSystem(
    [1.0, 0.5],
    [1.0, 2.0],
    [[0.0, 0.0, 0.5, 0.0], [0.0, 0.0, 0.0, -0.3], [0.4, 0.0, 0.0, 0.0], [0.0, 0.6, 0.0, 0.0]],
    [[0.8, 0.0], [0.0, 0.7]],
    [[0.5, 0.0], [0.0, -0.4]],
)
K2 = [[-0.2, 0.0], [0.0, 0.1]]


def test_two_actuators_decoupled_is_the_product() -> None:
    """Two independent 1 + 1 loops as one 2 + 2 system: det is the product, roots the union."""
    F = NPlusMCharacteristic(BOTH, K2, 0.5)
    F1, F2 = NPlusMCharacteristic(ONE, [[-0.2]], 0.5), NPlusMCharacteristic(TWO, [[0.1]], 0.5)
    s = np.array([0.3 + 2j, -0.4 + 7j])
    np.testing.assert_allclose(F(s), F1(s) * F2(s), rtol=1e-12)
    np.testing.assert_allclose(F.deriv_at(s), F1.deriv_at(s) * F2(s) + F1(s) * F2.deriv_at(s), rtol=1e-10)
    region = (-1.5, 1.0, -0.25, 6.0)
    both = find_roots(F, region)
    parts = np.concatenate([find_roots(F1, region).roots, find_roots(F2, region).roots])
    assert both.certified and both.count == parts.size
    np.testing.assert_allclose(np.sort_complex(both.roots), np.sort_complex(parts), atol=1e-10)


@pytest.mark.slow
def test_two_actuators_coupled_against_simulation() -> None:
    """A fully coupled 2 + 2 loop with the delay 0.5 on both actuators: the certified abscissa
    of the 2 x 2 determinant against the simulated growth rate (measured difference 3e-6)."""
    sys = NPlusMSystem(
        [1.0, 0.5],
        [1.0, 2.0],
        [[0.0, 0.1, 0.5, 0.2], [0.1, 0.0, 0.2, -0.3], [0.4, 0.1, 0.0, 0.1], [0.2, 0.6, 0.1, 0.0]],
        [[0.8, 0.1], [0.2, 0.7]],
        [[0.5, 0.2], [0.1, -0.4]],
    )
    ab = spectral_abscissa(NPlusMCharacteristic(sys, K2, 0.5), (-1.0, 1.0, -0.25, 8.0))
    assert ab.certified and ab.value > 0

    def w0(x: np.ndarray) -> np.ndarray:
        return np.vstack([np.sin(np.pi * x) + 0.3, np.cos(2 * x), 1 + x * x, x])

    sim = simulate_nplusm(sys, K2, 0.5, 80.0, w0, cells=40)
    np.testing.assert_allclose(sim.growth_rate(40.0), ab.value, atol=1e-4)


def test_bad_input() -> None:
    with pytest.raises(ParameterError, match="lam"):
        NPlusMSystem([-1.0], [1.0], np.zeros((2, 2)), [[1.0]], [[0.5]])
    with pytest.raises(ParameterError, match="sigma"):
        NPlusMSystem([1.0], [1.0], np.zeros((3, 3)), [[1.0]], [[0.5]])
    with pytest.raises(ParameterError, match="K"):
        TWO_ONE.gain([[1.0, 2.0, 3.0]])
    with pytest.raises(ParameterError, match="system"):
        nplusm_delay_margin(
            NPlusMSystem([1.0], [1.0, 2.0], np.zeros((3, 3)), [[1.0, 0.0]], [[0.5], [0.1]]), [[0.1], [0.0]]
        )
    with pytest.raises(ParameterError, match="delta"):
        NPlusMCharacteristic(TWO_ONE, GAIN, -1.0)
    with pytest.raises(ParameterError, match="max_updates"):
        simulate_nplusm(TWO_ONE, GAIN, 0.0, 1e6, _profiles, cells=100, max_updates=1000)


# ---------------------------------------------------------------- certified margin (m = 1)
def _principal_transition(F: NPlusMCharacteristic, s: complex) -> np.ndarray:
    """``exp(C_d - s P)``: the couplings kept only inside groups of equal round-trip rate."""
    p = F._p[0]
    c_d = np.where(p[:, None] == p[None, :], F._c, 0.0)
    return expm(c_d - s * np.diag(p))


@pytest.mark.parametrize(
    "system", [TWO_ONE, NPlusMSystem([1.0, 1.0, 0.5], [2.0], SAME_SPEED, [[0.6], [0.2], [0.5]], [[0.5, 0.1, 0.4]])]
)
def test_coupling_remainder_bounds_the_transition(system: NPlusMSystem) -> None:
    """``||exp(C - s P) - exp(C_d - s P)|| <= r(|s|)`` on the axis and in ``Re s > 0``
    (measured ratios up to about 0.9: the bound is close to sharp)."""
    F = NPlusMCharacteristic(system, [[-0.2] * system.n])
    floor = F._gauge()[0]
    rng = np.random.default_rng(5)
    mods = floor * 1.01 + rng.uniform(0.0, 200.0, 60)
    s = mods * np.exp(1j * rng.uniform(-np.pi / 2, np.pi / 2, 60))
    s[:20] = 1j * mods[:20]
    diff = [np.linalg.norm(expm(F._c - x * np.diag(F._p[0])) - _principal_transition(F, x), 2) for x in s]
    assert np.all(np.array(diff) <= F.coupling_remainder(np.abs(s)))


@pytest.mark.slow
def test_certified_margin_against_counts_at_sampled_delays() -> None:
    """Proven frequency bound, then certified counts of the closed loop in [0, W] x [-W, W]:
    none at 0.9 and 0.999 times the margin, one pair at 1.1 times (the pair that crossed)."""
    m = nplusm_delay_margin(TWO_ONE, GAIN)
    assert m.certified and m.nominal_unstable == 0 and 0 < m.margin < np.inf
    W = m.frequency_bound
    counts = [
        int(count_roots(NPlusMCharacteristic(TWO_ONE, GAIN, f * m.margin), (0.0, W, -W, W))) for f in (0.9, 0.999, 1.1)
    ]
    assert counts == [0, 0, 2]
    # beyond W, |A| - |B| keeps its sign (sampled far past W)
    a, b = NPlusMCharacteristic(TWO_ONE, GAIN).factors(1j * np.linspace(W, 50 * W, 2001))
    assert np.all(np.abs(a) - np.abs(b) > 0)


@pytest.mark.slow
def test_every_crossing_found() -> None:
    """A strongly coupled 2 + 1 loop with two crossings: the certified search finds the
    sign changes of |A| - |B| that a dense sampling of [0, 2 W] shows, and no more."""
    sys = NPlusMSystem([1.0, 0.4], [1.5], MULTI, [[0.6], [0.5]], [[0.3, 0.2]])
    K = [[-0.2, 0.1]]
    m = nplusm_delay_margin(sys, K)
    w = np.linspace(1e-6, 2 * m.frequency_bound, 20_001)
    a, b = NPlusMCharacteristic(sys, K).factors(1j * w)
    h = np.abs(a) - np.abs(b)
    sampled = w[np.flatnonzero(np.sign(h[:-1]) != np.sign(h[1:]))]
    assert m.certified and len(m.crossings) == sampled.size == 2
    np.testing.assert_allclose([c[0] for c in m.crossings], sampled, atol=w[1] - w[0])
    # F(i w; delta) = 0 at each crossing and its first delay
    for wc, dc in m.crossings:
        assert abs(complex(NPlusMCharacteristic(sys, K, dc)(np.array([1j * wc]))[0])) < 1e-10


@pytest.mark.parametrize("k, expected_stable", [(-0.3, True), (0.3, False)])
def test_static_feedback_matches_the_two_by_two_route(k: float, expected_stable: bool) -> None:
    """U = k u(t - delta, 1) on a coupled 2x2 plant: the 1 + 1 Laplace route against the kernel
    route's certified delay_margin(system, StateFeedback(k)) (measured difference 1.5e-9,
    the kernel grid's error; 0 for both when the delay-free loop is unstable)."""
    plant = Hyperbolic2x2(1.0, 2.0, 0.4, 0.5, 1.0, 0.5)
    core = delay_margin(plant, StateFeedback(k))
    ours = nplusm_delay_margin(NPlusMSystem.from_2x2(plant), [[k]])
    assert ours.certified and core.nominally_stable == expected_stable == (ours.nominal_unstable == 0)
    np.testing.assert_allclose(ours.margin, core.margin, atol=1e-8)
    if expected_stable:
        assert core.omega is not None and ours.omega is not None
        np.testing.assert_allclose(ours.omega, core.omega, atol=1e-8)


@pytest.mark.slow
def test_two_actuator_margin_of_decoupled_loops_is_the_smaller_one() -> None:
    """Two independent 1 + 1 loops with the same delay on both actuators: the pencil search
    (not certified) finds the smaller of the two certified one-actuator margins."""
    one, two = nplusm_delay_margin(ONE, [[-0.4]]), nplusm_delay_margin(TWO, [[0.3]])
    both = multi_actuator_margin(BOTH, [[-0.4, 0.0], [0.0, 0.3]], 5.0, points=1000)
    assert not both.certified and both.nominal_unstable == 0 and one.certified and two.certified
    np.testing.assert_allclose(both.margin, min(one.margin, two.margin), rtol=1e-9)
    assert both.omega is not None and one.omega is not None
    np.testing.assert_allclose(both.omega, one.omega, rtol=1e-9)
