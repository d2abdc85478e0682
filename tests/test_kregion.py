"""Exact ends of the admissible gains of ``U_BS2(K)``.

Each end of an admissible interval is checked against a truth that nrobust does not
compute: a closed form solved with :mod:`mpmath`, the double zero of
``g(w; K) = |A(i w)|^2 - |B(i w; K)|^2`` solved with :func:`scipy.optimize.fsolve`, or a
bisection on verified delay margins.
"""

from __future__ import annotations

import dataclasses
import math

import mpmath as mp
import numpy as np
import pytest
from _oracles import pair_birth as oracle_pair_birth
from _oracles import transport_k_interval

import nrobust as nr
import nrobust.hyperbolic.analyses
from nrobust import (
    CertificationError,
    Hyperbolic2x2,
    QuasiPolynomial,
    ReflectionController,
    TransportSystem,
    certify,
    delay_margin,
    k_region,
)
from nrobust._digits import with_accuracy
from nrobust.design.gain import _Family
from nrobust.distributed_delay import DistributedDelay
from nrobust.hyperbolic.analyses.kregion import u_bs2_loop
from nrobust.margins import gain
from nrobust.margins.crossing import crossing_search
from nrobust.margins.search import SPARE_SEGMENTS
from nrobust.reports.report import write_report

QP = QuasiPolynomial
PAPER = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
#: a plant with unequal speeds (k = (1 - 0.63)/0.7 = 0.528571...)
LAM2 = Hyperbolic2x2(2.0, 0.5, 0.3, -0.4, 0.7, 0.9)


def admissible(system: Hyperbolic2x2, K: float, delta_max: float, verify: bool = True) -> bool:
    dm = delay_margin(system, ReflectionController(K), delta_max=delta_max, verify=verify)
    return bool(dm.nominally_stable and dm.margin > delta_max)


def bisect_end(system: Hyperbolic2x2, good: float, bad: float, delta_max: float, tol: float) -> float:
    """The end between an admissible ``good`` and an inadmissible ``bad`` gain, by bisection on
    verified delay margins (the slow, independent route)."""
    assert admissible(system, good, delta_max) and not admissible(system, bad, delta_max)
    while abs(good - bad) > tol:
        mid = 0.5 * (good + bad)
        if admissible(system, mid, delta_max):
            good = mid
        else:
            bad = mid
    return 0.5 * (good + bad)


def pair_birth(system: Hyperbolic2x2, K0: float, w0: float) -> tuple[float, float, float]:
    """``(K_b, w_b, delay)`` of the pair birth near ``(K0, w0)`` (:func:`_oracles.pair_birth`)."""
    A, B0 = nr.loop_factors(system, ReflectionController(0.0))
    return oracle_pair_birth(A, B0, system.q, system.tau, K0, w0)


# ============================================================ closed forms
@pytest.mark.parametrize("a, delta_max", [(1.0, 0.5), (0.5, 2.0), (2.0, 0.1)])
def test_closed_form_loop_has_a_nominal_and_a_crossing_end(a: float, delta_max: float) -> None:
    """``s + a + K e^{-delta s}``: ``A = s + a``, ``B_0 = 0``, ``R = 1``.

    Nominal stability: ``s = -a - K``, so ``K > -a`` (an end at ``s = 0``). For ``|K| <= a``
    there is no crossing (``|i w + a| > |K|``); for ``K > a`` the crossing ``w = sqrt(K^2 - a^2)``
    has the first delay ``delta*(K) = arccos(-a/K)/w``, decreasing in ``K``: the interval ends
    where ``delta*(K) = delta_max`` (a continuous crossing).
    """
    mp.mp.dps = 40
    A, B0, R = QP([[a, 1.0]], [0.0]), QP([[0.0]], [0.0]), QP([[1.0]], [0.0])
    K_c = mp.findroot(lambda K: mp.acos(-a / K) / mp.sqrt(K**2 - a**2) - delta_max, 2 * a + 1 / delta_max)
    w_c = mp.sqrt(K_c**2 - a**2)
    loop = gain.AffineGainLoop(A, B0, R)
    ((lo, hi),) = gain.locate_gain_ends(loop, delta_max, 10.0 * (a + 1.0 / delta_max), 1e-12, 2_000_000)
    assert (lo.kind, hi.kind) == ("nominal", "crossing")
    np.testing.assert_allclose([lo.K, lo.omega], [-a, 0.0], rtol=0, atol=1e-14)
    np.testing.assert_allclose([hi.K, hi.omega, hi.delay], [float(K_c), float(w_c), delta_max], rtol=1e-13)


@pytest.mark.parametrize(
    "system, delta_max",
    [
        (TransportSystem(1.0, 2.0, 0.5, 0.8), 0.05),
        (TransportSystem(1.0, 1.0, 0.8, 0.9), 2.0),
        (TransportSystem(0.5, 4.0, 1.5, -0.3), 0.3),
    ],
)
def test_transport_region_is_the_strong_stability_interval(system: TransportSystem, delta_max: float) -> None:
    """``1 - rho q e^{-tau s} + K q e^{-(tau + delta) s}``: for ``|K| < k`` no crossing at all
    (``|1 - rho q z| >= 1 - |rho q| > |K q|``) and the nominal chain sits at
    ``Re s = ln|(rho - K) q| / tau < 0``; beyond, the difference operator is not strongly
    stable. Both ends are the strong-stability limit (``tests/_oracles.py``)."""
    truth = transport_k_interval(system.q, system.rho)
    region = k_region(system, delta_max)
    assert region.method == "equations"
    ((lo, hi),) = region.ends
    assert (lo.kind, hi.kind) == ("strong_stability", "strong_stability") and math.isinf(hi.omega)
    np.testing.assert_allclose(region.intervals[0], truth, rtol=1e-14)
    assert region.tol == pytest.approx(1e-10 * truth[1], rel=1e-12)


# ============================================================ the paper's plant
def test_paper_pair_birth_end() -> None:
    """``delta_max = 0.2`` ends where a pair of crossings is born near ``w = 4 pi``
    (``delay_margin`` hit the near-touch for ``K`` from 0.13074 to 0.130755)."""
    K_b, w_b, delay_b = pair_birth(PAPER, 0.13075, 4 * np.pi)
    region = k_region(PAPER, 0.2, Ks=[0.12, 0.135], tol=1e-9)
    ((lo, hi),) = region.ends
    assert hi.kind == "pair_birth" and 0.13074 < hi.K < 0.130765
    np.testing.assert_allclose([hi.K, hi.omega, hi.delay], [K_b, w_b, delay_b], rtol=0, atol=1e-9)
    assert delay_b < 0.2
    # the lower end is a continuous crossing: a root on the axis at delta_max, to rounding
    assert lo.kind == "crossing" and lo.delay == 0.2
    A, B = nr.loop_factors(PAPER, ReflectionController(lo.K))
    s = np.array([1j * lo.omega])
    residual = abs(A(s)[0] + B(s)[0] * np.exp(-s[0] * 0.2)) / (abs(A(s)[0]) + abs(B(s)[0]))
    assert residual < 1e-13
    assert list(region.admissible) == [True, False] and region.to_dict()["ends"][0][1]["kind"] == "pair_birth"


@pytest.mark.slow
@pytest.mark.timeout(1800)
@pytest.mark.parametrize(
    "delta_max, lower, upper, kinds",
    [
        (0.1, (-0.06, -0.07), (0.145, 0.147), ("crossing", "crossing")),
        (0.2, (0.04, 0.03), (0.13, 0.135), ("crossing", "pair_birth")),
    ],
)
def test_paper_ends_agree_with_bisection_on_verified_margins(
    delta_max: float, lower: tuple[float, float], upper: tuple[float, float], kinds: tuple[str, str]
) -> None:
    """The two ends of the paper's plant, against a bisection on verified delay margins to 1e-9
    from a coarse bracket (the old route: about a minute per end near the bound)."""
    region = k_region(PAPER, delta_max, tol=1e-9)
    ((lo, hi),) = region.ends
    assert (lo.kind, hi.kind) == kinds
    np.testing.assert_allclose(lo.K, bisect_end(PAPER, *lower, delta_max, 1e-9), rtol=0, atol=1e-9)
    np.testing.assert_allclose(hi.K, bisect_end(PAPER, *upper, delta_max, 1e-9), rtol=0, atol=1e-9)


# ============================================================ a plant with unequal speeds
@pytest.mark.slow
@pytest.mark.parametrize("system, gap", [(PAPER, 1e-3), (LAM2, 1.7e-5)], ids=["paper", "lam2"])
def test_second_order_frequency_bound_holds(system: Hyperbolic2x2, gap: float) -> None:
    """``g(w; K) = |A(i w)|^2 - |B(i w; K)|^2 >= q^2 (k^2 - K^2) - C_2 / w^2`` (``gain.AxisBound``),
    sampled on ``[0.5, 3 W_2]`` from the loop factors of :func:`nrobust.loop_factors`; no crossing
    above ``W_2``, which grows like ``1/sqrt(k - |K|)`` where the first-order bound grows like
    ``1/(k - |K|)`` (the unequal-speed plant ``1.7e-5`` from ``-k``: 190 against 7.3e4)."""
    bound = gain.AxisBound.of(u_bs2_loop(system))
    assert bound is not None
    k = nr.classify(system).k_bound
    A, B0 = nr.loop_factors(system, ReflectionController(0.0))
    Ks = (0.0, -0.5 * k, 0.9 * k, k - gap, -(k - gap))
    w = np.linspace(0.5, 3.0 * max(bound.W(K, K) for K in Ks), 40_001)
    a, b0, r = A(1j * w), B0(1j * w), system.q * np.exp(-1j * system.tau * w)
    p = abs(bound.rho_q)
    for K in Ks:
        W2, c = bound.W(K, K), bound.rho_q - K * bound.q
        g = np.abs(a) ** 2 - np.abs(b0 + K * r) ** 2
        C2 = (bound.n_tau - c * bound.n0) ** 2 / p + 2.0 * (1.0 + abs(c)) * bound.v2
        assert np.all(g >= (1.0 - p) ** 2 - (K * system.q) ** 2 - C2 / w**2 - 1e-13)
        assert np.all(g[w > W2] > 0.0)
        W1 = nr.margins.frequency_bound(A, B0 + QP([[K * system.q]], [system.tau]))[0]
        assert W2 < W1
    W1 = nr.margins.frequency_bound(A, B0 + QP([[-(k - gap) * system.q]], [system.tau]))[0]
    assert bound.W(-(k - gap), -(k - gap)) < 0.1 * W1


@pytest.mark.parametrize(
    "system",
    [PAPER, LAM2, Hyperbolic2x2(1.0, 1.0, 4.0, 4.0, 0.5, 0.5), Hyperbolic2x2(1.5, 0.7, -2.0, 1.0, -0.8, 0.9)],
    ids=["paper", "lam2", "strong_coupling", "negative_rho_q"],
)
def test_third_order_frequency_bound_holds(system: Hyperbolic2x2) -> None:
    """``g(w; K) >= q^2 (k^2 - K^2) - C_1 / w - M(w) / w^2 - C_3 / w^3`` (``gain.AxisBound``, third
    order), sampled from the loop factors ``A``, ``B_0`` (not from the bound's own code); ``g`` has
    no zero above ``W``, which is at most the second-order ``W_2`` and, where ``TV(n')`` dominates
    ``V_2`` (the paper's plant), well below it."""
    loop = u_bs2_loop(system)
    bound = gain.AxisBound.of(loop)
    assert bound is not None and np.isfinite(bound.v3)
    second_only = dataclasses.replace(bound, v3=np.inf)
    k = nr.classify(system).k_bound
    A, B0 = loop.A, loop.B0
    p, sigma = abs(bound.rho_q), np.sign(bound.rho_q)
    for K in (0.0, 0.5 * k, -0.9 * k, (1.0 - 1e-3) * k, -(1.0 - 1e-3) * k):
        W, W2 = bound.W(K, K), second_only.W(K, K)
        assert W <= W2
        w = np.linspace(0.05, 3.0 * W, 20_001)
        g = np.abs(A(1j * w)) ** 2 - np.abs(B0(1j * w) + K * system.q * np.exp(-1j * system.tau * w)) ** 2
        assert np.all(g[w > W] > 0.0)
        c = bound.rho_q - K * bound.q
        a0, a1 = bound.d0 + c * bound.d_tau, sigma * (bound.d_tau + c * bound.d0)
        P = p + a1 / w**2
        fac = 1.0 + abs(c)
        M = (bound.n_tau - c * bound.n0) ** 2 / P + 2.0 * (a1 - a0) + 2.0 * fac * bound.jumps1
        lower = (1.0 - p) ** 2 - (K * system.q) ** 2 - 2.0 * fac * (bound.jumps0 / w + M / w**2 + bound.v3 / w**3)
        # the bound is exact arithmetic on the stored kernel; the sampled g errs by a few eps
        assert np.all(g[P > 0.0] >= lower[P > 0.0] - 1e-12)
    if system is PAPER:  # most of V_2 is TV(n') there: the third order is 2.6 times shorter near k
        K = 0.14640480613
        np.testing.assert_allclose([bound.W(K, K), second_only.W(K, K)], [31.7266, 83.6282], rtol=1e-4)


def test_gain_verdict_search_is_short_and_finds_the_same_crossings() -> None:
    """The crossing search of a gain verdict on the paper's plant, on ``[0, W]`` (third-order
    ``W = 8.78`` at ``K = 0``), leaves its few hard segments, next to the crossings, to the cluster
    refinement (``SPARE_SEGMENTS``) instead of refining the whole range for them (formerly 3238
    evaluations on ``W_2 = 19.3``): the same crossings as :func:`nrobust.margins.crossing_frequencies`
    on the margins' frequency bound (``W = 26.7``, each kernel integrated by parts twice; 40.5 once), to
    the search's ``1e-12``."""
    loop = u_bs2_loop(PAPER)
    A, B = loop.A, loop.B(0.0)
    first = nr.margins.frequency_bound(A, B)
    W = gain.AxisBound.of(loop).W(0.0, 0.0)
    np.testing.assert_allclose([W, first[0]], [8.7786, 26.7372], rtol=1e-4)
    search, _ = crossing_search(A, B, (W, first[1]), 2_000_000, SPARE_SEGMENTS)
    reference = nr.margins.crossing_frequencies(A, B)
    assert search.evaluations < 1000
    np.testing.assert_allclose(search.omegas, reference.omegas, rtol=0, atol=1e-11)  # both refined to 1e-12
    np.testing.assert_array_equal(search.slopes, reference.slopes)


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_item9_plant_ends_at_delta_max_0_1() -> None:
    """With ``delta_max = 0.1`` both ends are pair births within 1e-4 of ``k = 0.528571``: at
    ``w = 62.83`` (``n = 25``) below, ``w = 32.67`` (``n = 13``) above, against scipy's
    ``g = dg/dw = 0`` (formerly refused: the first-order bound needed ``W ~ 1/(k - |K|) ~ 1e5``)."""
    region = k_region(LAM2, 0.1)
    ((lo, hi),) = region.ends
    assert (lo.kind, hi.kind) == ("pair_birth", "pair_birth")
    for end, start in ((lo, (-0.528566, 62.83)), (hi, (0.52851, 32.67))):
        K_b, w_b, delay_b = pair_birth(LAM2, *start)
        np.testing.assert_allclose([end.K, end.omega, end.delay], [K_b, w_b, delay_b], rtol=0, atol=1e-8)
        assert delay_b <= 0.1


@pytest.mark.slow
@pytest.mark.timeout(1200)
def test_item9_report_carries_the_exact_ends(tmp_path) -> None:
    """``certify`` and the report of ``nrobust analyze``: exact ends with their kind, not a 9-gain grid."""
    delta_max = 3.0
    cert = certify(LAM2, ReflectionController(0.3), delta_max=delta_max)
    assert cert.k_region is not None and cert.k_region_error == ""
    ((lo, hi),) = cert.k_region.ends
    assert (lo.kind, hi.kind) == ("pair_birth", "pair_birth")
    for end, start in ((lo, (-0.5256, 2.53)), (hi, (0.5175, 2.49))):
        K_b, w_b, delay_b = pair_birth(LAM2, *start)
        np.testing.assert_allclose([end.K, end.omega, end.delay], [K_b, w_b, delay_b], rtol=0, atol=1e-8)
        assert delay_b <= delta_max
    for K, ok in ((lo.K + 1e-8, True), (lo.K - 1e-8, False), (hi.K - 1e-8, True), (hi.K + 1e-8, False)):
        assert admissible(LAM2, K, delta_max) is ok
    files = write_report(cert, tmp_path / "report")
    text = files.markdown.read_text()
    assert (
        f"({with_accuracy(lo.K, lo.accuracy)}, {with_accuracy(hi.K, hi.accuracy)})" in text
        and "pair birth" in text
        and "within 0.0" not in text
    )


def test_item9_certificate_records_why_the_region_is_missing(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*args: object, **kwargs: object) -> None:
        raise CertificationError("k_region: beyond the work bound max_evals=1")

    monkeypatch.setattr(nrobust.hyperbolic.analyses, "k_region", refuse)  # what certify calls
    cert = certify(LAM2, ReflectionController(0.3), delta_max=0.1)
    assert cert.k_region is None and "work bound" in cert.k_region_error
    assert cert.to_dict()["k_region_error"] == cert.k_region_error


def test_axis_bound_of_a_constant_kernel() -> None:
    # n = 0.2 on [0, 1] (degree-0 pieces): an IndexError before; the third-order constants vanish
    d = DistributedDelay([0.0, 1.0], None, interpolation="polynomial", coefficients=[[0.2]])
    B0 = QuasiPolynomial([[0.0]], [0.0], [d])
    loop = gain.AffineGainLoop(QuasiPolynomial([[1.0], [-0.5]], [0.0, 1.0]) - B0, B0, QuasiPolynomial([[1.0]], [1.0]))
    bound = gain.AxisBound.of(loop)
    assert bound is not None
    W = bound.W(0.1, 0.1)
    # g(w) = |A|^2 - |B|^2 on a fine grid above W, from the factors: positive
    w = np.linspace(W, 50.0 * W, 20001)
    g = np.abs(loop.A(1j * w)) ** 2 - np.abs(loop.B(0.1)(1j * w)) ** 2
    assert np.all(g > 0.0)


def test_crossing_bound_with_a_tiny_proximal_reflection() -> None:
    # |rho q| = 7e-10: the second- and third-order bounds grow like 1 / sqrt(|rho q|) (8466 at K = 0), the
    # first-order bound stays near 1 (g is concave in K: its values at the ends hold inside); the smaller
    loop = u_bs2_loop(Hyperbolic2x2(lam=2.0, mu=0.5, sigma_pm=0.3, sigma_mp=-0.4, q=0.7, rho=1e-9))
    assert gain.AxisBound.of(loop).W(0.0, 0.25) > 1000.0  # type: ignore[union-attr]
    W = _Family(loop).crossing_bound(0.0, 0.25)
    assert W < 10.0
    w = np.linspace(W, 50.0 * W, 20001)
    for K in np.linspace(0.0, 0.25, 11):
        g = np.abs(loop.A(1j * w)) ** 2 - np.abs(loop.B(float(K))(1j * w)) ** 2
        assert np.all(g > 0.0)
