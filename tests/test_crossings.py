"""The crossing search against closed forms: the frequency bound, tangencies and near-tangencies.

Oracles are independent of the search: ``|A(i w)|^2 - |B(i w)|^2`` as a polynomial in
``x = w^2`` for polynomial loops (roots in closed form), and certified counts
(:func:`nrobust.count_roots`) at sampled delays.
"""

from __future__ import annotations

import numpy as np
import pytest

from nrobust import (
    CertificationError,
    Hyperbolic2x2,
    ParameterError,
    QuasiPolynomial,
    ReflectionController,
    count_roots,
    crossing_frequencies,
    delay_margin,
    loop_factors,
)
from nrobust.margins.axis import AxisGap, AxisKernels, frequency_bound
from nrobust.margins.count import axis_count
from nrobust.margins.margin import delay_margin as factor_margin
from nrobust.quasipoly import DistributedDelay

QP = QuasiPolynomial
PHI = (1.0 + np.sqrt(5.0)) / 2.0
# A = s^2 + 2 s + 10, B = c: |A|^2 - |B|^2 = (x - 8)^2 + 36 - c^2 with x = w^2, a double
# root at w = 2 sqrt(2) for c = 6 (exact in floating point: integer coefficients).
TANGENT_A = QP([[10.0, 2.0, 1.0]], [0.0])
W_TANGENT = 2.0 * np.sqrt(2.0)


def tangent_B(c: float) -> QuasiPolynomial:
    return QP([[c]], [0.0])


def first_delay(A: QuasiPolynomial, B: QuasiPolynomial, w: float) -> float:
    """``arg(-B/A) mod 2 pi / w`` at ``s = i w`` (the first delay that puts ``i w`` on a root)."""
    s = np.array([1j * w])
    return float(np.mod(np.angle(-B(s)[0] / A(s)[0]), 2.0 * np.pi) / w)


def count_at(A: QuasiPolynomial, B: QuasiPolynomial, delta: float, radius: float) -> int:
    return int(count_roots(A + B.shift(delta), (0.0, radius, -radius, radius)))


# ============================================================ the frequency bound is inclusive
def test_bound_is_sharp_and_the_crossing_on_it_is_found() -> None:
    """s^2 + 1 against s: |A|^2 - |B|^2 = x^2 - 3x + 1, crossings at w = 1/phi and phi = W."""
    A, B = QP([[1.0, 0.0, 1.0]], [0.0]), QP([[0.0, 1.0]], [0.0])
    W, gap = frequency_bound(A, B)
    assert gap == 1.0 and PHI < W <= PHI * (1 + 1e-6)
    res = crossing_frequencies(A, B)
    np.testing.assert_allclose(res.omegas, [1.0 / PHI, PHI], rtol=1e-13)
    assert list(res.slopes) == [-1, 1] and not res.tangential.any()


@pytest.mark.parametrize("verify, delta_max", [(True, None), (False, None), (False, 5.0), (True, 12.0)])
def test_undamped_oscillator_margin_and_windows(verify: bool, delta_max: float | None) -> None:
    A, B = QP([[1.0, 0.0, 1.0]], [0.0]), QP([[0.0, 1.0]], [0.0])
    dm = delay_margin(A, B, delta_max=delta_max, verify=verify)
    # at w = phi: A = 1 - phi^2 = -phi, B = i phi, -B/A = i: delta = (pi/2)/phi
    np.testing.assert_allclose(dm.margin, np.pi / 2 / PHI, rtol=1e-12)
    np.testing.assert_allclose(dm.omega, PHI, rtol=1e-13)
    assert dm.verified == verify
    directions = {round(c.omega, 9): c.direction for c in dm.crossings}
    assert directions == {round(PHI, 9): 1, round(1.0 / PHI, 9): -1}
    for lo, hi, n in dm.counts:
        mid = 0.5 * (lo + hi)
        assert count_at(A, B, mid, 3.0) == n
    assert int(dm.unstable_count(3.0)) == 2


# ============================================================ tangencies and near-tangencies
def test_axis_gap_jet_against_the_closed_form() -> None:
    gap = AxisGap(TANGENT_A, tangent_B(6.0))
    w = np.array([0.3, 1.7, W_TANGENT, 5.0])
    jet = gap.jet(w)
    np.testing.assert_allclose(jet.g, (w**2 - 8.0) ** 2, rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(jet.dg, 4.0 * w * (w**2 - 8.0), rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(jet.d2g, 12.0 * w**2 - 32.0, rtol=1e-13, atol=1e-12)
    # rounding levels: a few hundred eps times the sum of the moduli of the terms, squared
    scale = (w**2 + 2.0 * w + 16.0) ** 2
    assert np.all(jet.err < 1e-13 * scale) and np.all(jet.derr < 1e-13 * scale) and np.all(jet.d2err < 1e-13 * scale)
    # the bounds of |g''| and |g'''| hold on segments (checked on a fine sample)
    lo, hi = np.array([0.0, 2.5, 4.0]), np.array([1.0, 3.0, 6.0])
    m2, m3 = gap.bounds(lo, hi, gap.jet(0.5 * (lo + hi)))
    for a, b, bound2, bound3 in zip(lo, hi, m2, m3):
        x = np.linspace(a, b, 1001)
        assert np.max(np.abs(12.0 * x**2 - 32.0)) <= bound2
        assert np.max(np.abs(24.0 * x)) <= bound3


def test_exact_tangency_is_located_and_flagged() -> None:
    res = crossing_frequencies(TANGENT_A, tangent_B(6.0))
    assert res.omegas.size == 1 and res.tangential[0] and res.slopes[0] == 0
    np.testing.assert_allclose(res.omegas[0], W_TANGENT, rtol=1e-12)


def test_tangency_margin_and_windows_exclude_its_delay() -> None:
    B = tangent_B(6.0)
    d_c = first_delay(TANGENT_A, B, W_TANGENT)
    period = 2.0 * np.pi / W_TANGENT
    dm = delay_margin(TANGENT_A, B, delta_max=d_c + 2.5 * period)
    (c,) = dm.crossings
    assert c.tangential and c.direction == 0
    np.testing.assert_allclose(dm.margin, d_c, rtol=1e-11)
    d_c = c.delays[0]
    assert dm.verified and dm.nominally_stable
    # the count never changes, but the loop is not exponentially stable at the tangency delays
    assert all(n == 0 for _, _, n in dm.counts)
    np.testing.assert_allclose([hi for _, hi in dm.intervals[:-1]], [d_c, d_c + period, d_c + 2 * period], rtol=1e-11)
    assert [lo for lo, _ in dm.intervals[1:]] == [hi for _, hi in dm.intervals[:-1]]
    assert list(dm.is_stable([0.5 * d_c, d_c, 0.5 * (d_c + period)])) == [True, False, True]
    for delta in (0.99 * d_c, 1.01 * d_c, d_c + 0.5 * period):
        assert count_at(TANGENT_A, B, delta, 8.0) == 0


@pytest.mark.parametrize("rel", [1e-6, 1e-12])
def test_near_tangency_is_proven_away(rel: float) -> None:
    """B scaled down: min (|A|^2 - |B|^2) = 36 (2 rel - rel^2) > 0, no crossing at all."""
    B = tangent_B(6.0 * (1.0 - rel))
    res = crossing_frequencies(TANGENT_A, B)
    assert res.omegas.size == 0
    dm = delay_margin(TANGENT_A, B)
    assert dm.margin == np.inf and dm.intervals == ((0.0, np.inf),)


@pytest.mark.parametrize("rel, rtol", [(1e-6, 1e-12), (1e-12, 1e-9)])
def test_pair_just_born_is_two_simple_crossings(rel: float, rtol: float) -> None:
    """B scaled up: x = 8 +- sqrt(c^2 - 36), a stabilising and a destabilising crossing (each
    located to the rounding of |A| - |B| divided by its slope, about 1e-4 for rel = 1e-12)."""
    c = 6.0 * (1.0 + rel)
    B = tangent_B(c)
    root = np.sqrt(c * c - 36.0)
    w_minus, w_plus = np.sqrt(8.0 - root), np.sqrt(8.0 + root)
    res = crossing_frequencies(TANGENT_A, B)
    np.testing.assert_allclose(res.omegas, [w_minus, w_plus], rtol=rtol)
    assert list(res.slopes) == [-1, 1] and not res.tangential.any()
    d_minus, d_plus = first_delay(TANGENT_A, B, w_minus), first_delay(TANGENT_A, B, w_plus)
    dm = delay_margin(TANGENT_A, B, delta_max=2.0 * d_plus)
    np.testing.assert_allclose(dm.margin, min(d_minus, d_plus), rtol=rtol)
    assert dm.verified
    for lo, hi, n in dm.counts:
        if hi - lo > 1e-3:
            assert count_at(TANGENT_A, B, 0.5 * (lo + hi), 8.0) == n


def test_tangency_at_the_paper_example_near_pair_birth_is_not_reported() -> None:
    """The near-touch at w ~ 12.54 (K just below the pair birth) is proven away: verified margin,
    agreeing with the finer kernel grid and with certified counts on both sides."""
    plant, ctrl = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85), ReflectionController(0.13075)
    dm = delay_margin(plant, ctrl)
    assert dm.verified and not any(c.tangential for c in dm.crossings)
    assert not any(abs(abs(c.omega) - 12.5416) < 1e-2 for c in dm.crossings)
    fine = delay_margin(plant, ctrl, kernel_grid=401, verify=False)
    np.testing.assert_allclose(dm.margin, fine.margin, rtol=1e-8)
    A, B = loop_factors(plant, ctrl)
    r = 1.01 * dm.frequency_bound
    assert count_at(A, B, dm.margin * (1 - 1e-3), r) == 0
    assert count_at(A, B, dm.margin * (1 + 1e-3), r) == 2


# ============================================================ checks, work bounds, degenerate loops
def test_verified_and_unverified_agree() -> None:
    loops = [
        (QP([[1.0, 0.0, 1.0]], [0.0]), QP([[0.0, 1.0]], [0.0])),
        (TANGENT_A, tangent_B(6.0 * (1 + 1e-6))),
        (QP([[1.0, 0.1, 1.0]], [0.0]), QP([[0.5]], [0.0])),
        (QP([[1.0, 1.0]], [0.0]), QP([[2.0j]], [0.0])),
    ]
    for A, B in loops:
        a, b = delay_margin(A, B, delta_max=10.0), delay_margin(A, B, delta_max=10.0, verify=False)
        assert a.verified and not b.verified
        assert (a.margin, a.counts, a.intervals, a.crossings) == (b.margin, b.counts, b.intervals, b.crossings)


@pytest.mark.parametrize("delta", [0.05, 0.22931, 0.2298, 0.5, 1.2])
def test_verification_count_against_count_roots(delta: float) -> None:
    A, B = loop_factors(Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85), ReflectionController(0.1))
    W, _ = frequency_bound(A, B)
    n = axis_count(A, B, delta, W, AxisKernels((A, B)), 10**6)
    assert n == count_at(A, B, delta, 1.01 * W)


def test_work_bound_is_checked_before_the_grid() -> None:
    """W ~ 200 and a delay of 100: the first grid needs about 5e4 points, above max_evals."""
    kernel = DistributedDelay(np.linspace(0.0, 100.0, 5), np.ones(5))
    A = QP([[1.0], [-0.89]], [0.0, 100.0], [kernel])
    B = QP([[0.1]], [100.0])
    with pytest.raises(CertificationError, match=r"max_evals=10000.*raise max_evals"):
        crossing_frequencies(A, B, max_evals=10_000)


def test_one_factor_identically_zero() -> None:
    s2p1, s_plus_1 = QP([[1.0, 0.0, 1.0]], [0.0]), QP([[1.0, 1.0]], [0.0])
    dm = delay_margin(s2p1, QP([[0.0]], [0.0]))  # s^2 + 1 for every delay: roots on the axis
    assert dm.margin == 0.0 and not dm.nominally_stable and dm.nominal_unstable is None
    dm = factor_margin(s_plus_1, 0.0)
    assert dm.margin == np.inf and dm.nominally_stable and dm.intervals == ((0.0, np.inf),)
    dm = factor_margin(0.0, s_plus_1, delta_max=3.0)  # (s + 1) e^{-delta s}
    assert dm.margin == np.inf and dm.counts == ((0.0, 3.0, 0),)
    with pytest.raises(ParameterError, match="A, B"):
        factor_margin(0.0, 0.0)


def test_common_zero_on_the_axis_is_a_root_for_every_delay() -> None:
    A = QP([[2.0, 1.0, 2.0, 1.0]], [0.0])  # (s^2 + 1)(s + 2)
    dm = delay_margin(A, QP([[1.0, 0.0, 1.0]], [0.0]))  # s^2 + 1
    assert dm.margin == 0.0 and dm.omega == pytest.approx(1.0, rel=1e-9) and not dm.nominally_stable


@pytest.mark.parametrize("delta_max", [float("nan"), float("-inf"), 0.0, -1.0, True, "1"])
def test_delta_max_is_positive_or_inf(delta_max: object) -> None:
    with pytest.raises(ParameterError, match="delta_max"):
        delay_margin(QP([[1.0, 1.0]], [0.0]), QP([[0.5]], [0.0]), delta_max=delta_max)
    dm = delay_margin(QP([[1.0, 1.0]], [0.0]), QP([[0.5]], [0.0]), delta_max=float("inf"))
    assert dm.margin == np.inf


def test_a_crossing_of_tiny_frequency_does_not_blow_up_the_default_range() -> None:
    """Near ``A(0) + B(0) = 0`` a crossing has a tiny frequency and a period of 2e6: the default range (one
    period past every first delay) made a faster crossing enumerate millions of delays, and ``delay_margin``
    without ``delta_max`` raised a ParameterError naming ``delta_max``, which the caller never gave."""
    K = 1.134 / 1.225 + 1e-10  # A(0) + B(0) = 0 at 1.134/1.225: s = 0 is then a root for every delay
    A = QuasiPolynomial([[0.753, 1.0], [-1.187, 0.3]], [0.0, 2.181])
    B = QuasiPolynomial([[-0.7, 0.2]], [0.203]) + QuasiPolynomial([[1.225 * K]], [1.609])
    dm = delay_margin(A, B)
    assert 0.0 < dm.margin < dm.delta_max < np.inf
    w = dm.omega
    s = 1j * w
    # the reported crossing solves the crossing equation (residual at rounding level)
    assert abs(A(np.array([s]))[0] + B(np.array([s]))[0] * np.exp(-s * dm.margin)) < 1e-9
    assert abs(abs(A(np.array([s]))[0]) - abs(B(np.array([s]))[0])) < 1e-9


def test_the_default_delay_range_bounds_the_delays_of_all_crossings_together() -> None:
    """Thousands of crossings of short period (a strongly coupled output feedback has them up to ``w ~ 1e4``): the
    default range ends where the delays up to it, counted directly here (``floor((t - base) / period) + 1``), reach
    about ``_MAX_EVENTS`` together; the former rule (each crossing below the bound alone) let these 4000 crossings
    enumerate 2.8e6 delays. A few crossings keep one full period past every first delay."""
    from nrobust.margins.crossing import _MAX_EVENTS, _default_range

    rng = np.random.default_rng(7)
    omega = rng.uniform(1.0, 1e4, 4000)
    period = 2.0 * np.pi / omega
    base = rng.uniform(0.0, 1.0, omega.size) * period

    def enumerated(t: float) -> int:
        ahead = base <= t
        return int(np.sum(np.floor((t - base[ahead]) / period[ahead]) + 1)) + int(np.count_nonzero(~ahead))

    former = min(float(np.max(base + period)), float(np.min(base + (_MAX_EVENTS - 1) * period)))
    assert enumerated(former) > 20 * _MAX_EVENTS
    t = _default_range(base, period)
    assert 0.9 * _MAX_EVENTS <= enumerated(t) <= _MAX_EVENTS + omega.size
    few_base, few_period = base[:3], period[:3]
    assert _default_range(few_base, few_period) == float(np.max(few_base + few_period))
