"""Delay margins against closed forms, stability windows against certified counts."""

from __future__ import annotations

import numpy as np
import pytest

from nrobust import CertificationError, ParameterError, QuasiPolynomial, crossing_frequencies, delay_margin
from nrobust.quasipoly import DistributedDelay
from nrobust.roots import count_roots


def first_order(a: float, b: float) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``s + a + b e^{-delta s}``."""
    return QuasiPolynomial([[a, 1.0]], [0.0]), QuasiPolynomial([[b]], [0.0])


def second_order(a: float, b: float, c: float) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``s^2 + a s + b + c e^{-delta s}`` (oscillator with delayed position feedback)."""
    return QuasiPolynomial([[b, a, 1.0]], [0.0]), QuasiPolynomial([[c]], [0.0])


def transport(rho_q: float, kq: float, tau: float = 2.0) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``1 - rho q e^{-tau s} + K q e^{-(tau + delta) s}`` (paper eq. (13))."""
    return QuasiPolynomial([[1.0], [-rho_q]], [0.0, tau]), QuasiPolynomial([[kq]], [tau])


def synthetic_kernel() -> DistributedDelay:
    """A piecewise-linear N~ on [0, 2] with a jump at nu = 1 (as at nu = 1/mu)."""
    x1, x2 = np.linspace(0.0, 1.0, 41), np.linspace(1.0, 2.0, 41)
    return DistributedDelay(np.r_[x1, x2], np.r_[0.6 * np.cos(2 * x1) + 0.3, -0.5 + 0.4 * x2])


def distributed_loop(rho_q: float, kq: float) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``A = 1 - Phi``, ``B = K q e^{-tau s} - I_N`` with ``Phi = rho q e^{-2 s} - I_N``."""
    i_n = QuasiPolynomial([], [], [synthetic_kernel()])
    phi = QuasiPolynomial([[rho_q]], [2.0]) - i_n
    return 1.0 - phi, QuasiPolynomial([[kq]], [2.0]) - i_n


@pytest.mark.parametrize("a, b", [(1.0, 2.0), (0.5, 3.0), (-0.2, 1.0), (0.0, 1.5), (3.0, 3.5)])
def test_first_order_closed_form(a: float, b: float) -> None:
    A, B = first_order(a, b)
    dm = delay_margin(A, B)
    w = np.sqrt(b * b - a * a)
    assert dm.margin == pytest.approx(np.arccos(-a / b) / w, rel=1e-11)
    assert dm.omega == pytest.approx(w, rel=1e-11)
    assert dm.nominally_stable and dm.verified and dm.residual < 1e-12
    assert [c.direction for c in dm.crossings] == [1]
    assert dm.intervals[0] == (0.0, dm.margin)
    assert dm.crossings[0].delays[1] == pytest.approx(dm.margin + 2 * np.pi / w, rel=1e-11)


@pytest.mark.parametrize("a, b", [(1.0, 0.5), (2.0, -1.9), (1.0, 0.0)])
def test_first_order_delay_independent(a: float, b: float) -> None:
    dm = delay_margin(*first_order(a, b))
    assert dm.margin == np.inf and not dm.crossings and dm.nominally_stable
    assert dm.intervals == ((0.0, np.inf),)


def test_unstable_nominal_has_zero_margin() -> None:
    dm = delay_margin(*first_order(1.0, -2.0))  # s - 1 at delta = 0
    assert dm.margin == 0.0 and not dm.nominally_stable and dm.nominal_unstable == 1
    assert dm.intervals == ()


def test_zero_root_for_every_delay() -> None:
    dm = delay_margin(*first_order(1.0, -1.0))  # F(0; delta) = 0
    assert dm.zero_root and dm.margin == 0.0 and not dm.nominally_stable


def test_stability_windows_second_order() -> None:
    a, b, c = 0.1, 1.0, 0.5
    A, B = second_order(a, b, c)
    dm = delay_margin(A, B, delta_max=12.0)
    # closed form: |A(iw)| = |B| <=> w^4 + (a^2 - 2b) w^2 + b^2 - c^2 = 0
    p = 2 * b - a * a
    w2 = np.array([p + np.sqrt(p * p - 4 * (b * b - c * c)), p - np.sqrt(p * p - 4 * (b * b - c * c))]) / 2
    wp, wm = np.sqrt(w2)

    def first_delay(w: float) -> float:
        return float(np.mod(np.angle(-c / (b - w * w + 1j * a * w)), 2 * np.pi) / w)

    dp, dmn = first_delay(wp), first_delay(wm)
    assert sorted(c_.omega for c_ in dm.crossings) == pytest.approx(sorted([wm, wp]), rel=1e-11)
    dirs = {round(c_.omega, 8): c_.direction for c_ in dm.crossings}
    assert dirs == {round(wp, 8): 1, round(wm, 8): -1}
    assert dm.margin == pytest.approx(dp, rel=1e-11)
    # windows: stable on [0, d+_0), unstable until d-_0, stable again until d+_1
    assert len(dm.intervals) == 2
    assert dm.intervals[0][1] == pytest.approx(dp, rel=1e-11)
    assert dm.intervals[1][0] == pytest.approx(dmn, rel=1e-11)
    assert dm.intervals[1][1] == pytest.approx(dp + 2 * np.pi / wp, rel=1e-11)
    # every interval count agrees with a certified count at its midpoint
    for lo, hi, n in dm.counts:
        mid = 0.5 * (lo + hi)
        assert int(count_roots(A + B.shift(mid), (0.0, 3.0, -3.0, 3.0))) == n
    assert list(dm.is_stable([0.0, 0.1, 1.0, 4.5, 9.0])) == [True, True, False, True, False]
    assert list(dm.unstable_count([0.1, 1.0])) == [0, 2]


def test_direction_matches_frequency_sweep_sign() -> None:
    """Re ds/ddelta has the sign of d/dw (|A|^2 - |B|^2) (Cooke and van den Driessche)."""
    A, B = second_order(0.1, 1.0, 0.5)
    dm = delay_margin(A, B, delta_max=1.0)
    for c in dm.crossings:
        w = np.array([c.omega - 1e-6, c.omega + 1e-6])
        g = np.abs(A(1j * w)) ** 2 - np.abs(B(1j * w)) ** 2
        assert np.sign(g[1] - g[0]) == c.direction == np.sign(c.ds_ddelta.real)


def test_tangential_touch_is_reported() -> None:
    a, b = 0.1, 1.0
    c = np.sqrt(b * b - (2 * b - a * a) ** 2 / 4)  # double root of |A|^2 - |B|^2
    A, B = second_order(a, b, c)
    res = crossing_frequencies(A, B)
    w0 = np.sqrt((2 * b - a * a) / 2)
    assert res.omegas.size >= 1
    assert np.all(np.abs(res.omegas - w0) < 1e-6)
    dm = delay_margin(A, B, delta_max=20.0, verify=False)
    assert sum(c_.direction for c_ in dm.crossings) == 0  # no net change of the count
    assert dm.margin == pytest.approx(min(c_.delays[0] for c_ in dm.crossings), rel=1e-13, abs=1e-14)


def test_complex_coefficients_scan_both_signs() -> None:
    A, B = QuasiPolynomial([[1.0, 1.0]], [0.0]), QuasiPolynomial([[2.0j]], [0.0])
    dm = delay_margin(A, B, delta_max=6.0)
    assert sorted(c.omega for c in dm.crossings) == pytest.approx([-np.sqrt(3), np.sqrt(3)], rel=1e-11)
    for lo, hi, n in dm.counts:
        mid = 0.5 * (lo + hi)
        assert int(count_roots(A + B.shift(mid), (0.0, 4.0, -4.0, 4.0))) == n


@pytest.mark.parametrize(
    "rho_q, kq, expected",
    [
        (0.85, 0.1, np.inf),
        (0.85, -0.14, np.inf),
        (-0.6, 0.3, np.inf),
        (0.85, 0.2, 0.0),
        (0.5, 0.6, 0.0),
        (0.3, -0.8, 0.0),
    ],
)
def test_transport_reflection_controller(rho_q: float, kq: float, expected: float) -> None:
    """Margin inf iff |rho q| + |K q| < 1 (eq. (13)), 0 when it exceeds 1."""
    dm = delay_margin(*transport(rho_q, kq))
    assert dm.margin == expected
    assert dm.strongly_stable == (abs(rho_q) + abs(kq) < 1)
    assert dm.nominally_stable == (abs(rho_q - kq) < 1)


@pytest.mark.parametrize("rho_q", [0.85, 0.6, -0.7])
def test_transport_finite_time_controller_zero_margin(rho_q: float) -> None:
    """U_BS: principal part 1 - rho q e^{-tau s} + rho q e^{-(tau+delta) s}, Theorem 3."""
    A = QuasiPolynomial([[1.0], [-rho_q]], [0.0, 2.0])
    B = QuasiPolynomial([[rho_q]], [2.0])
    dm = delay_margin(A, B)
    assert dm.margin == 0.0 and not dm.strongly_stable
    assert dm.nominally_stable  # F(.; 0) = 1: finite-time convergence without delay


def test_transport_finite_time_controller_small_gain() -> None:
    A = QuasiPolynomial([[1.0], [-0.4]], [0.0, 2.0])
    dm = delay_margin(A, QuasiPolynomial([[0.4]], [2.0]))
    assert dm.margin == np.inf and dm.strongly_stable


def test_strong_stability_matches_difference_operator() -> None:
    for rho_q, kq in [(0.85, 0.1), (0.85, 0.2), (0.4, 0.4), (0.45, 0.5)]:
        A, B = transport(rho_q, kq)
        D = (A + B.shift(1e-3 * np.sqrt(2))).principal_part()
        assert delay_margin(A, B).strongly_stable == D.is_strongly_stable()


def test_distributed_loop_margin_verified_and_complete() -> None:
    A, B = distributed_loop(0.85, 0.1)
    dm = delay_margin(A, B)
    assert dm.nominally_stable and dm.verified and 0 < dm.margin < np.inf
    # no crossing missed: brute-force sign changes on a dense grid of [0, W]
    w = np.linspace(0.0, dm.frequency_bound, 200_001)
    h = np.abs(A(1j * w)) - np.abs(B(1j * w))
    changes = w[1:][np.sign(h[1:]) != np.sign(h[:-1])]
    assert changes.size == len(dm.crossings)
    # a sign change is reported at the right end of its grid cell: within one step w[1]
    np.testing.assert_allclose(np.sort(changes), sorted(c.omega for c in dm.crossings), rtol=0, atol=w[1])
    # the margin crossing is a root of F on the axis
    s = 1j * dm.omega
    F = A + B.shift(dm.margin)
    assert abs(F(np.array([s]))[0]) < 1e-10


def test_nominal_loop_cancels_opposite_kernels() -> None:
    A, B = distributed_loop(0.85, 0.1)
    F = A + B
    assert not F.distributed  # I_N - I_N: the target system 1 - (rho - K) q e^{-tau s}
    s = np.array([0.3 + 2.0j, 1.0 - 7.0j])
    np.testing.assert_allclose(F(s), 1 - 0.75 * np.exp(-2 * s), rtol=1e-14, atol=0)


def test_result_serialises_and_validates() -> None:
    dm = delay_margin(*first_order(1.0, 2.0), delta_max=10.0)
    d = dm.to_dict()
    assert d["margin"] == dm.margin and len(d["crossings"]) == 1 and d["delta_max"] == 10.0
    assert "DelayMargin(margin=1.2091995" in repr(dm)
    assert delay_margin(*first_order(1.0, 0.5)).to_dict()["margin"] == "inf"
    with pytest.raises(ParameterError):
        delay_margin(QuasiPolynomial([[1.0, 1.0]], [0.0]), 2.0)
    with pytest.raises(ParameterError):
        delay_margin(*first_order(1.0, 2.0), delta_max=-1.0)
    with pytest.raises(ParameterError):
        dm.is_stable(11.0)
    with pytest.raises(ParameterError):
        delay_margin(*first_order(1.0, 2.0), delta_max=np.inf)
    assert delay_margin(*first_order(1.0, 0.5), delta_max=np.inf).intervals == ((0.0, np.inf),)
    with pytest.raises(ParameterError):
        crossing_frequencies(*transport(0.85, 0.3))
    with pytest.raises(CertificationError):
        crossing_frequencies(*distributed_loop(0.85, 0.1), max_evals=10)


# ---------------------------------------------------------------------------- hyperbolic plants
from concurrent.futures import ThreadPoolExecutor  # noqa: E402

from nrobust import (  # noqa: E402
    FilteredController,
    FiniteTimeController,
    Hyperbolic2x2,
    ReflectionController,
    TransportSystem,
    characteristic,
    loop_factors,
)
from nrobust.hyperbolic.analyses import ab_region, k_region, stability_chart, tradeoff  # noqa: E402
from nrobust.hyperbolic.analyses.rouche import rouche_delay_bound  # noqa: E402


def paper_system() -> Hyperbolic2x2:
    """Section 5: lam = mu = sigma+- = sigma-+ = q = 1, rho = 0.85."""
    return Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)


def test_paper_example_finite_time_controller_has_zero_margin() -> None:
    dm = delay_margin(paper_system(), FiniteTimeController())
    assert dm.margin == 0.0 and not dm.strongly_stable and dm.nominally_stable  # Theorem 3


def test_paper_example_reflection_controller_rouche_below_margin() -> None:
    system, ctrl = paper_system(), ReflectionController(0.05)
    dm = delay_margin(system, ctrl, verify=False)
    bound = rouche_delay_bound(system, ctrl)
    assert 0.0 < bound.delta_0 <= dm.margin < np.inf
    assert bound.epsilon_0 == pytest.approx(0.1, rel=1e-13, abs=1e-14)


@pytest.mark.slow
def test_paper_example_reflection_controller() -> None:
    system, ctrl = paper_system(), ReflectionController(0.1)
    dm = delay_margin(system, ctrl)
    assert dm.verified and dm.nominally_stable and 0.0 < dm.margin < np.inf
    assert dm.is_stable(0.1)  # the paper's Figure 3 runs K = 0.1 with delta = 0.1
    # independent check on the characteristic function of the closed loop
    nxt = min(d for c in dm.crossings for d in c.delays if d > dm.margin)
    W = dm.frequency_bound
    box = (0.0, 1.01 * W, -1.01 * W, 1.01 * W)
    assert int(count_roots(characteristic(system, ctrl, 0.5 * dm.margin), box)) == 0
    assert int(count_roots(characteristic(system, ctrl, 0.5 * (dm.margin + nxt)), box)) == 2
    bound = rouche_delay_bound(system, ctrl)
    assert 0.0 < bound.delta_0 <= dm.margin


def test_transport_system_controllers() -> None:
    system = TransportSystem(1.0, 1.0, 1.0, 0.85)
    assert delay_margin(system, ReflectionController(0.1)).margin == np.inf
    assert delay_margin(system, ReflectionController(0.2)).margin == 0.0
    assert delay_margin(system, FiniteTimeController()).margin == 0.0
    assert rouche_delay_bound(system, ReflectionController(0.1)).delta_0 == np.inf
    assert rouche_delay_bound(system, ReflectionController(0.2)).delta_0 == 0.0


def test_k_region_transport_matches_paper_bound() -> None:
    """For transport the paper's |K| < (1 - |rho q|)/|q| is necessary and sufficient."""
    system = TransportSystem(1.0, 1.0, 0.8, 0.9)
    kb = (1 - 0.72) / 0.8
    region = k_region(system, 2.0, n_gains=9)
    assert region.paper_bound == pytest.approx(kb, rel=1e-13, abs=1e-14)
    assert len(region.intervals) == 1
    lo, hi = region.intervals[0]
    assert lo == pytest.approx(-kb, abs=2 * region.tol) and hi == pytest.approx(kb, abs=2 * region.tol)
    assert region.admissible.all() and "KRegion" in repr(region)
    assert region.to_dict()["intervals"][0][1] == hi


def test_tradeoff_transport_closed_form() -> None:
    system = TransportSystem(1.0, 1.0, 1.0, 0.85)
    Ks = np.array([-0.1, 0.0, 0.1])
    tr = tradeoff(system, Ks)
    assert tr.decay_rates == pytest.approx(-np.log(np.abs(0.85 - Ks)) / 2.0, rel=1e-8)
    assert np.all(tr.margins == np.inf) and np.all(tr.rouche_bounds == np.inf)
    assert tr.to_dict()["margins"] == ["inf"] * 3


def test_tradeoff_reuses_known_margins_and_computes_the_others() -> None:
    """Margins given are used as they are (a wrong one shows through); nan entries are computed."""
    system = paper_system()
    Ks = np.array([0.0, 0.1])
    computed = tradeoff(system, Ks)
    reused = tradeoff(system, Ks, margins=[0.5, np.nan])  # 0.5 is not delta*(0): it must be taken as given
    np.testing.assert_array_equal(reused.margins, [0.5, computed.margins[1]])
    np.testing.assert_array_equal(reused.decay_rates, computed.decay_rates)
    chart = stability_chart(system, Ks, [0.0, 0.5])
    from_chart = tradeoff(system, Ks, margins=chart.margins)
    np.testing.assert_allclose(from_chart.margins, computed.margins, rtol=1e-13)
    for bad in ([0.1], [True, True], ["0.1", "0.2"], [-1.0, 0.1], "ab"):
        with pytest.raises(ParameterError, match="margins"):
            tradeoff(system, Ks, margins=bad)


def test_stability_chart_transport_on_executors() -> None:
    system = TransportSystem(1.0, 1.0, 1.0, 0.85)
    Ks, deltas = np.array([-0.2, 0.0, 0.1, 0.2]), np.array([0.0, 0.3, 1.0])
    chart = stability_chart(system, Ks, deltas)
    assert chart.values.shape == (4, 3)
    assert np.all(chart.values[1:3] == 0)  # |rho q| + |K q| < 1: stable for all delays
    assert np.all(np.isinf(chart.values[[0, 3], 1:]))  # not strongly stable: infinitely many
    assert chart.values[3, 0] == 0  # K = 0.2: nominal reflection rho - K = 0.65, stable
    assert np.isnan(chart.values[0, 0])  # K = -0.2: reflection 1.05, a chain in Re s > 0
    with ThreadPoolExecutor(2) as ex:
        again = stability_chart(system, Ks, deltas, executor=ex)
    assert np.array_equal(again.values, chart.values, equal_nan=True)
    on_processes = stability_chart(system, Ks, deltas, executor=2)  # the sweep machinery's pool
    assert np.array_equal(on_processes.values, chart.values, equal_nan=True)
    assert len(chart.to_dict()["values"]) == 4
    absc = stability_chart(system, [0.0, 0.1], [0.0, 0.5], quantity="abscissa")
    assert absc.values[:, 0] == pytest.approx(np.log([0.85, 0.75]) / 2.0, abs=1e-8)  # target systems
    assert absc.values[1, 1] < 0  # margin inf: still stable at delta = 0.5
    with pytest.raises(ParameterError):
        stability_chart(system, Ks, deltas, quantity="roots")


def test_stability_chart_counts_match_certified_counts() -> None:
    system = paper_system()
    Ks, deltas = np.array([0.0, 0.1]), np.array([0.0, 0.1, 0.3, 0.9])
    chart = stability_chart(system, Ks, deltas)
    assert chart.margins == pytest.approx(
        [delay_margin(system, ReflectionController(K), verify=False).margin for K in Ks], rel=1e-13, abs=1e-14
    )
    A, B = loop_factors(system, ReflectionController(0.1))
    W = delay_margin(A, B, verify=False).frequency_bound
    F = characteristic(system, ReflectionController(0.1), 0.3)
    assert chart.values[1, 2] == int(count_roots(F, (0.0, 1.01 * W, -1.01 * W, 1.01 * W))) == 4
    assert list(chart.values[:, 0]) == [0, 0]
    for i in range(2):
        assert np.all(chart.boundaries[i][:, 0] <= deltas.max())


def test_ab_region_transport() -> None:
    system = TransportSystem(1.0, 1.0, 1.0, 0.85)
    a, b = np.array([-0.5, 0.0, 0.25]), np.array([0.5, 2.0])
    reg = ab_region(system, 0.5, a, b)
    A_, B_ = np.meshgrid(a, b, indexing="ij")
    assert np.array_equal(reg.strongly_stable, 0.85 * (1 + np.abs(A_) / B_) < 1)
    assert not np.any(reg.admissible & ~reg.strongly_stable)  # strong stability is necessary
    assert np.any(reg.paper_conditions & ~reg.strongly_stable)  # eq. (17) lacks |a|
    assert reg.admissible[2, 1]  # a = 0.25, b = 2: |a|/b = 0.125 < 0.15/0.85
    dm = delay_margin(system, FilteredController(0.25, 2.0))
    assert dm.margin == reg.margins[2, 1] > 0.5 and dm.nominally_stable
    assert "ABRegion" in repr(reg) and len(reg.to_dict()["a"]) == 3


def test_paper_example_margin_converges_second_order_in_kernel_grid() -> None:
    system, ctrl = paper_system(), ReflectionController(0.1)
    m = [delay_margin(system, ctrl, verify=False, kernel_grid=n).margin for n in (51, 101, 201)]
    ratio = (m[1] - m[0]) / (m[2] - m[1])
    # At least second order in 1/n. N~ is a cubic spline (fourth order), so the kernels
    # set the rate: observed ratio ~8 (order 3, their Richardson extrapolation).
    assert np.log2(ratio) >= 1.8
    assert abs(m[2] - m[1]) < 2e-6


@pytest.mark.slow
def test_paper_example_margin_against_simulation() -> None:
    """The plant itself decays just below delta* and grows just above (Figure 3's loop)."""
    from nrobust import simulate

    system, ctrl = paper_system(), ReflectionController(0.1)
    dm = delay_margin(system, ctrl, verify=False)
    rates = []
    for delta in (0.85 * dm.margin, 1.15 * dm.margin):
        sim = simulate(system, ctrl, delta, 60.0, lambda x: np.sin(np.pi * x), lambda x: np.cos(3 * x), cells=200)
        late = sim.times > 30.0
        rates.append(np.polyfit(sim.times[late], np.log(sim.norm[late]), 1)[0])
    assert rates[0] < 0 < rates[1]


def test_k_region_paper_example_is_strictly_inside_the_paper_bound() -> None:
    """With delta_max = 0.2 neither K = 0 nor gains near the bound 0.15 are admissible."""
    system = paper_system()
    region = k_region(system, 0.2, Ks=[0.0, 0.05, 0.1], tol=5e-3)
    assert list(region.admissible) == [False, True, True]
    ((lo, hi),) = region.intervals
    assert 0.0 < lo < 0.05 and 0.1 < hi < region.paper_bound
    for K in (lo - 2 * region.tol, hi + 2 * region.tol):  # just outside: margin below 0.2
        assert delay_margin(system, ReflectionController(K), verify=False).margin <= 0.2
    for K in (lo + 2 * region.tol, hi - 2 * region.tol):
        assert delay_margin(system, ReflectionController(K), verify=False).margin > 0.2


@pytest.mark.parametrize("a, b", [(0.0, 1.0), (0.1, 1.0), (0.15, 2.0)])
def test_filtered_transport_loop_has_a_finite_margin_when_rho_q_above_half(a: float, b: float) -> None:
    """eq. (17) gives a positive margin, not stability for every delay, when |rho q| > 1/2.

    At w = 0, |A|^2 - |B|^2 = (1 - rho q)^2 - (rho q)^2 < 0, while it is positive at high
    frequency (strong stability): a crossing exists.
    """
    rho_q = 0.85
    A = QuasiPolynomial([[1.0, b], [-rho_q, -rho_q * b]], [0.0, 2.0])  # (1 + b s)(1 - rho q e^{-2s})
    B = QuasiPolynomial([[rho_q, rho_q * a]], [2.0])  # (1 + a s) rho q e^{-2s}
    assert a / b < (1 - rho_q) / rho_q and a < (1 - rho_q) / rho_q  # the paper's conditions
    dm = delay_margin(A, B)
    assert dm.verified and 0.0 < dm.margin < np.inf
    nxt = min(d for c in dm.crossings for d in c.delays if d > dm.margin)
    F = A + B.shift(0.5 * (dm.margin + nxt))
    W = dm.frequency_bound
    assert int(count_roots(F, (0.0, 1.01 * W, -1.01 * W, 1.01 * W))) == 2
    assert dm.margin == delay_margin(TransportSystem(1.0, 1.0, 1.0, rho_q), FilteredController(a, b)).margin


def test_a_proven_infinite_margin_says_so_without_an_interval_of_infinities():
    """The reason of a proven infinite margin names no ``[inf, inf]`` (an internal interval in words)."""
    import nrobust
    from nrobust.hyperbolic import TransportSystem

    margin = nrobust.delay_margin(
        TransportSystem(lam=1.0, mu=1.0, q=1.0, rho=0.3), nrobust.ReflectionController(0.1), rigorous=True
    )
    assert margin.margin == np.inf and margin.rigorous
    assert "inf" not in margin.reason and margin.reason.endswith("(proven in ball arithmetic)")


@pytest.mark.parametrize("ulps", [0, 3, 12])
def test_a_proven_zero_margin_needs_the_plants_gap_negative(ulps: int) -> None:
    """``U_BS2(K)`` on ``q = 0.7``, ``rho = 0.85`` with ``K`` near ``1/q - rho``: the gap ``1 - rho q - K q`` of the
    plant as given (exact products of its doubles, in fractions) is ``+4.1e-17`` at ``ulps = 0`` (strongly stable:
    the margin is not 0), negative beyond. The stored ``rho q`` and ``K q`` are rounded: the proven gap's ball must
    hold the plant's gap on both sides (its upper end was the lower end of the coefficients' balls, and the margin 0
    was claimed proven at ``ulps = 0``)."""
    from fractions import Fraction

    from nrobust import Hyperbolic2x2, ReflectionController

    q, rho = 0.7, 0.85
    K0 = 1 / q - rho
    K = K0 + ulps * np.spacing(K0)
    gap = 1 - Fraction(rho) * Fraction(q) - Fraction(K) * Fraction(q)
    assert (gap > 0) == (ulps == 0)
    try:
        dm = delay_margin(Hyperbolic2x2(1, 1, 1, 1, q, rho), ReflectionController(K), rigorous=True, delta_max=0.5)
    except CertificationError:
        assert ulps < 12  # near the boundary a refusal is honest; 12 ulps (gap -8e-16) is decided
        return
    assert dm.margin > 0 if gap > 0 else dm.margin == 0
    assert abs(Fraction(dm.gap) - gap) <= Fraction(dm.gap_accuracy)
