"""Reproducers of false certificates and hangs once found, each checked against an independent truth.

Each test is marked ``xfail(strict=True)`` while its defect is open: a fix makes it pass,
strict mode turns that pass into a failure, and the mark is removed with the fix. The
truths come from ``tests/_oracles.py`` (Lambert W, the classical crossing algorithm in
exact arithmetic, ``mpmath`` root finding), never from nrobust itself. Items 10 and up were
found by the differential harness (``tests/test_harness.py``).
"""

from __future__ import annotations

import inspect
import json
import math
import warnings
from typing import Any

import numpy as np
import pytest
from _guards import Hang, hard_deadline, memory_cap
from _oracles import (
    LoopOracle,
    chain_abscissa,
    lambert_rightmost,
    pair_birth,
    poly_from_roots,
    poly_roots,
    z_roots,
)

import nrobust as nr
from nrobust import (
    CertificationError,
    FilteredController,
    Hyperbolic2x2,
    ParameterError,
    QuasiPolynomial,
    ReflectionController,
    TransportSystem,
)
from nrobust._digits import with_accuracy
from nrobust.reports.report import write_report

QP = QuasiPolynomial
PAPER = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)


def xfail(item: str) -> pytest.MarkDecorator:
    return pytest.mark.xfail(strict=True, reason=f"reproducer {item}")


def named_error(fn: Any, *args: Any, name: str, **kwargs: Any) -> None:
    """``fn(*args, **kwargs)`` raises a ParameterError that names ``name``."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ParameterError) as info:
            fn(*args, **kwargs)
    assert name in f"{info.value.name} {info.value}"


def answer_or_nrobust_error(fn: Any, *args: Any, seconds: float = 30.0, **kwargs: Any) -> Any:
    """A result, or a ParameterError/CertificationError: no other exception, no hang, no 80 GiB."""
    try:
        with hard_deadline(seconds), memory_cap(2 << 30), warnings.catch_warnings():
            warnings.simplefilter("error")
            return fn(*args, **kwargs)
    except (ParameterError, CertificationError):
        return None
    except Hang as exc:
        pytest.fail(f"hang: {exc}")


# ============================================================ item 1: false certified abscissa
def test_item1_long_delay_abscissa_is_certified_and_right() -> None:
    F = QP([[1.0, 1.0], [0.5]], [0.0, 14.0])  # s + 1 + 0.5 e^{-14 s}
    truth = lambert_rightmost(1.0, 0.5, 14.0)  # principal branch: -0.0476991 +- 0.20897 i
    sa = nr.spectral_abscissa(F)
    assert sa.certified
    np.testing.assert_allclose(sa.value, truth.real, rtol=0, atol=1e-9)


def test_item1_far_root_is_not_minus_infinity() -> None:
    sa = nr.spectral_abscissa(QP([[3000.0, 1.0]], [0.0]))  # s + 3000
    assert sa.certified
    np.testing.assert_allclose(sa.value, -3000.0, rtol=1e-12)
    assert sa.upper_bound >= -3000.0


def test_item1_certificate_abscissa_is_finite() -> None:
    cert = nr.certify(Hyperbolic2x2(0.1, 0.1, 0.3, 0.3, 1.0, 0.0), FilteredController(0.5, 1.0), k_region=False)
    sa = cert.abscissa
    assert math.isfinite(sa.value) and sa.certified
    # the rightmost root found in a box about the reported value agrees with it (once reported: about -0.125)
    F = nr.characteristic(cert.system, cert.controller, 0.0)
    box = (sa.value - 0.5, sa.value + 0.5, -1.0 - abs(sa.root.imag), 1.0 + abs(sa.root.imag))
    roots = nr.find_roots(F, box)
    assert roots.certified
    np.testing.assert_allclose(sa.value, np.max(roots.roots.real), atol=1e-8)
    assert -0.2 < sa.value < -0.05


# ============================================================ item 2: crossing on the frequency bound
UNDAMPED = ([1.0, 0.0, 1.0], [0.0, 1.0])  # A = s^2 + 1, B = s


@pytest.mark.parametrize("verify, delta_max", [(True, None), (False, None), (False, 5.0)])
def test_item2_crossing_on_the_frequency_bound(verify: bool, delta_max: float | None) -> None:
    o = LoopOracle(*UNDAMPED)  # P(x) = x^2 - 3x + 1: w = 1.618 (destabilising), 0.618 (stabilising)
    np.testing.assert_allclose(o.margin, 0.9708055193627332, rtol=1e-14)
    dm = nr.delay_margin(QP([UNDAMPED[0]], [0.0]), QP([UNDAMPED[1]], [0.0]), delta_max=delta_max, verify=verify)
    np.testing.assert_allclose(dm.margin, o.margin, rtol=1e-9)
    assert int(dm.unstable_count(3.0)) == o.unstable_count(3.0) == 2


# ============================================================ item 3: tangencies (pair births)
def _paper_pair_birth() -> tuple[float, float, float]:
    """``(K_b, w_b, delta_b)``: the gain at which ``g(K, w) = |A(i w)|^2 - |B_K(i w)|^2`` gets a
    double zero near ``w = 4 pi`` and the crossing delay born there (:func:`_oracles.pair_birth`)."""
    A, B0 = nr.loop_factors(PAPER, ReflectionController(0.0))
    return pair_birth(A, B0, PAPER.q, PAPER.tau, 0.13075, 4 * np.pi)


@pytest.mark.parametrize("K", [0.13074, 0.13075, 0.130755])
def test_item3_near_touch_is_not_a_crossing(K: float) -> None:
    K_b, w_b, _ = _paper_pair_birth()  # K_b = 0.1307588691, w_b = 12.5416
    assert K < K_b
    dm = nr.delay_margin(PAPER, ReflectionController(K))
    assert dm.verified
    assert not any(abs(abs(c.omega) - w_b) < 1e-2 for c in dm.crossings)
    assert dm.margin > 0.2


def test_item3_no_false_tangency_just_before_the_birth() -> None:
    K_b, w_b, _ = _paper_pair_birth()
    dm = nr.delay_margin(PAPER, ReflectionController(K_b - 1e-6), verify=False, delta_max=0.25)
    # |A| - |B| stays ~1e-7 above zero near w_b: no crossing there; the margin is the w = 9.427 branch
    assert not any(abs(abs(c.omega) - w_b) < 1e-2 for c in dm.crossings)
    assert dm.margin > 0.2


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_item3_k_region_end_is_the_pair_birth() -> None:
    K_b, _, delay = _paper_pair_birth()
    assert delay < 0.2  # the pair is born with a crossing delay inside [0, delta_max]: it ends the interval
    region = nr.k_region(PAPER, 0.2, Ks=[0.12, 0.135], tol=1e-9)
    assert len(region.intervals) == 1
    np.testing.assert_allclose(region.intervals[0][1], K_b, rtol=0, atol=1e-8)


# ============================================================ item 4: Nyquist on advanced loops
def test_item4_nyquist_refuses_an_advanced_loop() -> None:
    A, B = QP([[1.0]], [0.0]), QP([[0.0, 1.0]], [0.0])  # 1 + s e^{-delta s}: advanced
    ny = nr.plots.nyquist_response(A, B, 0.5)
    assert ny.rhp_zeros is None and ny.note
    # the count that does not exist: chains of zeros in Re s > 0 (32 in this box alone)
    assert int(nr.count_roots(A + B.shift(0.5), (0.0, 40.0, -200.0, 200.0))) == 32


# ============================================================ item 5: wrong exception types
def test_item5_find_roots_tall_box_no_linalg_error() -> None:
    answer_or_nrobust_error(nr.find_roots, QP([[1.0, 1.0], [0.5, 0.5]], [0.0, 1.0]), (-1.0, 1.0, 0.0, 1e5))


@pytest.mark.long
@pytest.mark.timeout(400)
def test_item5_spectral_abscissa_long_delay_no_linalg_error() -> None:
    F = QP([[1.0, 1.0], [0.3, 0.3], [0.2, 0.2]], [0.0, 1.0, 1000.0])
    answer_or_nrobust_error(nr.spectral_abscissa, F, seconds=300.0)


def test_item5_slow_plant_named_error() -> None:
    system = Hyperbolic2x2(1e-4, 1.0, 1.0, 1.0, 1.0, 0.85)
    answer_or_nrobust_error(nr.delay_margin, system, ReflectionController(0.1))


def test_item5_zero_B_no_nan_error() -> None:
    dm = answer_or_nrobust_error(nr.delay_margin, QP([[1.0, 0.0, 1.0]], [0.0]), QP([[0.0]], [0.0]))
    if dm is not None:  # s^2 + 1 for every delay: roots on the axis
        assert dm.margin == 0.0 and not dm.nominally_stable


def test_item5_non_numeric_delays_named() -> None:
    named_error(QP, [[1.0], [1.0]], ["a", "b"], name="delays")


def test_item5_non_numeric_nodes_named() -> None:
    named_error(nr.DistributedDelay, ["a", "b", "c"], [1.0, 1.0, 1.0], name="nodes")


# ============================================================ item 6: silent coercions
NO_CROSSING = (QP([[1.0, 1.0]], [0.0]), QP([[0.5]], [0.0]))  # s + 1 + 0.5 e^{-delta s}


@pytest.mark.parametrize("delta_max", [float("nan"), float("-inf")])
def test_item6_delta_max_not_coerced(delta_max: float) -> None:
    named_error(nr.delay_margin, *NO_CROSSING, delta_max=delta_max, name="delta_max")


def test_item6_identically_zero_loop_refused() -> None:
    named_error(nr.delay_margin, QP([[0.0]], [0.0]), QP([[0.0]], [0.0]), name="A")


def test_item6_zero_denominator_refused() -> None:
    named_error(nr.QuasiTransferFunction, 1.0, 0.0, name="den")


def test_item6_boolean_gain_refused() -> None:
    named_error(ReflectionController, True, name="K")


def test_item6_boolean_plant_parameter_refused() -> None:
    named_error(Hyperbolic2x2, 1.0, 1.0, 1.0, 1.0, 1.0, True, name="rho")


def test_item6_complex_initial_state_refused() -> None:
    T = TransportSystem(1.0, 2.0, 0.5, 0.8)
    named_error(
        nr.simulate, T, ReflectionController(0.1), 0.1, 1.0, lambda x: (1 + 1j) * np.sin(x), np.sin, 20, name="u0"
    )


# ============================================================ item 7: memory before work bounds
def test_item7_no_huge_grid_before_the_work_bound() -> None:
    # the kernel route: its grid is checked before anything is allocated (the default route of
    # this plant needs no grid, N~ in closed form)
    system = Hyperbolic2x2(0.01, 1.0, 1.0, 1.0, 1.0, 0.85)
    answer_or_nrobust_error(nr.delay_margin, system, ReflectionController(0.1), kernel_grid=201, seconds=60.0)


# ============================================================ item 8: refusals where the answer is easy
def test_item8_sixfold_root() -> None:
    p = [float(math.comb(6, k)) for k in range(7)]  # (s + 1)^6, exact
    sa = nr.spectral_abscissa(QP([p], [0.0]))
    assert sa.certified
    np.testing.assert_allclose(sa.value, -1.0, rtol=0, atol=1e-6)


def test_item8_one_rightmost_pair_without_exhausting_the_bound() -> None:
    sa = nr.spectral_abscissa(QP([[1.0, 1.0], [0.5]], [0.0, 10.0]))  # s + 1 + 0.5 e^{-10 s}
    assert sa.certified
    np.testing.assert_allclose(sa.value, lambert_rightmost(1.0, 0.5, 10.0).real, rtol=0, atol=1e-9)


def test_item8_six_roots_1e3_apart() -> None:
    coefs = [float(v) for v in np.polynomial.polynomial.polyfromroots(-1.0 + 1e-3 * np.arange(6))]
    truth = poly_roots(coefs)  # the roots of the float polynomial as given
    F = QP([coefs], [0.0])
    rs = nr.find_roots(F, (-2.0, 0.0, -1.0, 1.0))
    assert rs.certified and rs.count == 6
    for r in truth:
        assert np.any(np.abs(rs.roots - r) <= rs.radii + 1e-12)
    sa = nr.spectral_abscissa(F)
    assert sa.certified
    np.testing.assert_allclose(sa.value, max(r.real for r in truth), rtol=0, atol=1e-6)


# ============================================================ item 9: the report's admissible gains
LAM2 = Hyperbolic2x2(2.0, 0.5, 0.3, -0.4, 0.7, 0.9)  # k = (1 - 0.63)/0.7 = 0.528571...


def _pair_birth_of(system: Hyperbolic2x2, K0: float, w0: float) -> tuple[float, float, float]:
    A, B0 = nr.loop_factors(system, ReflectionController(0.0))
    return pair_birth(A, B0, system.q, system.tau, K0, w0)


def _zeros_near(system: Hyperbolic2x2, K: float, delta: float, omega: float, re: tuple[float, float]) -> int:
    """Certified count (:func:`nrobust.count_roots`) of the zeros of ``F(.; delta)`` with gain ``K``
    in ``re x [omega - 0.01, omega + 0.01]``."""
    F = nr.characteristic(system, ReflectionController(K), delta)
    return int(nr.count_roots(F, (re[0], re[1], omega - 0.01, omega + 0.01)))


def _newton_zero(system: Hyperbolic2x2, K: float, delta: float, omega: float) -> complex:
    F = nr.characteristic(system, ReflectionController(K), delta)
    s = complex(0.0, omega)
    for _ in range(50):
        s -= complex(F(np.array([s]))[0] / F.deriv_at(np.array([s]))[0])
    return s


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_item9_certificate_carries_exact_gain_ends(tmp_path) -> None:
    """Both ends of item 9's plant at ``delta_max = 0.2`` are pair births just inside ``k = 0.528571``:
    at ``w = 17.59`` (``K = 0.52834845``, the truth lies in (0.5283, 0.5284)) and at ``w = 32.67``
    (``K = -0.52855386``, ``1.7e-5`` from ``-k``), the first touch points ``w ~ 2 pi n / tau`` whose
    crossing delay is below 0.2 (``n = 7`` and ``n = 13``). Each is checked against scipy's solution
    of ``g = dg/dw = 0`` (to 1e-8), and the interval is open at it: ``2e-8`` outside, a certified count
    finds a zero in ``Re s > 0`` near ``i w_b`` at the birth delay; ``2e-8`` inside, none in
    ``Re s > -|Re s*|``, ``s*`` the zero that is about to cross."""
    cert = nr.certify(LAM2, ReflectionController(0.0), delta_max=0.2)
    assert cert.k_region is not None, cert.k_region_error
    ((lo, hi),) = cert.k_region.ends
    assert (lo.kind, hi.kind) == ("pair_birth", "pair_birth")
    np.testing.assert_allclose(hi.K, 0.5283, rtol=0, atol=1e-4)
    kb = nr.classify(LAM2).k_bound
    for end, start, outward in ((lo, (-0.52855, 32.67), -1.0), (hi, (0.528348, 17.59), 1.0)):
        K_b, w_b, delay_b = _pair_birth_of(LAM2, *start)
        np.testing.assert_allclose([end.K, end.omega, end.delay], [K_b, w_b, delay_b], rtol=0, atol=1e-8)
        assert delay_b <= 0.2
        beyond, inside = end.K + outward * 2e-8, end.K - outward * 2e-8
        assert abs(beyond) < kb
        s_out = _newton_zero(LAM2, beyond, delay_b, w_b)
        assert s_out.real > 0 and _zeros_near(LAM2, beyond, delay_b, w_b, (0.5 * s_out.real, 2.0 * s_out.real)) >= 1
        s_in = _newton_zero(LAM2, inside, delay_b, w_b)
        assert s_in.real < 0 and _zeros_near(LAM2, inside, delay_b, w_b, (s_in.real / 2, 1e-3)) == 0
    text = write_report(cert, tmp_path / "report").markdown.read_text()
    assert f"({with_accuracy(lo.K, lo.accuracy)}, {with_accuracy(hi.K, hi.accuracy)})" in text and "pair birth" in text


# ============================================================ items 10-14: found by the harness
T0 = TransportSystem(1.0, 2.0, 0.5, 0.8)
F0 = QP([[1.0, 1.0], [0.5]], [0.0, 1.0])  # s + 1 + 0.5 e^{-s}
BOX = (-2.0, 1.0, -5.0, 5.0)


@pytest.mark.parametrize(
    "call, name",
    [
        pytest.param(lambda: nr.ab_region(T0, 0.1, [0.1], "abc"), "b"),
        pytest.param(lambda: nr.boundary_function(T0, [[1.0], [2.0, 3.0]]), "s"),
        pytest.param(lambda: nr.find_roots(F0, BOX, seeds="abc"), "seeds"),
        pytest.param(lambda: nr.find_roots(F0, BOX, seeds=["a"]), "seeds"),
        pytest.param(lambda: nr.spectral_abscissa(F0, cluster_tol=None), "cluster_tol"),
        pytest.param(lambda: nr.spectral_abscissa(F0, cluster_tol={"a": 1}), "cluster_tol"),
    ],
)
def test_item10_wrong_exception_types(call: Any, name: str) -> None:
    named_error(call, name=name)


@pytest.mark.parametrize(
    "call, name",
    [
        pytest.param(lambda: nr.stability_chart(T0, [True, False], [0.1]), "Ks"),
        pytest.param(lambda: nr.ab_region(T0, 0.1, [True, False], [0.2]), "a"),
        pytest.param(lambda: nr.spectral_abscissa(F0, cluster_tol=True), "cluster_tol"),
        pytest.param(lambda: nr.spectral_abscissa(F0, im_max=-np.inf), "im_max"),
        pytest.param(lambda: nr.spectral_abscissa(F0, im_max=-1.0), "im_max"),
        pytest.param(lambda: nr.spectral_abscissa(F0, im_max="1"), "im_max"),
        pytest.param(lambda: nr.spectral_abscissa(F0, cluster_tol=-1.0), "cluster_tol"),
        pytest.param(lambda: nr.find_roots(F0, BOX, seeds=[np.nan]), "seeds"),
    ],
)
def test_item11_silent_coercions(call: Any, name: str) -> None:
    named_error(call, name=name)


def test_item12_nyquist_grid_size_checked_first() -> None:
    A, B = QP([[1.0, 1.0]], [0.0]), QP([[2.0]], [0.0])
    size = list(inspect.signature(nr.plots.nyquist_response).parameters)[4]
    with memory_cap(2 << 30):
        named_error(nr.plots.nyquist_response, A, B, 0.5, 50.0, 10**9, name=size)


@pytest.mark.parametrize("a, b", [(0.1, 1e300), (-1e300, 1e300), (0.1, 1e200)])
def test_item13_ab_region_huge_pole(a: float, b: float) -> None:
    out = answer_or_nrobust_error(nr.ab_region, T0, 0.1, [a], [b])
    assert out is None or not np.isnan(out.margins).any()


def test_item13_huge_filter_is_the_same_loop_scaled() -> None:
    """Past 2^32 the filtered loop is divided by a power of two: the same margins as unscaled below it."""
    a, b = 0.5, 2.0**33  # scaled by 2^-34: exact
    scaled = nr.ab_region(T0, 0.1, [a], [b])
    dm = nr.delay_margin(T0, FilteredController(a, b), delta_max=0.1, verify=False)
    assert scaled.margins[0, 0] == dm.margin
    assert bool(scaled.admissible[0, 0]) == bool(dm.nominally_stable and dm.margin > 0.1)


def test_item13_zero_within_rounding_of_the_axis_is_not_counted_unstable() -> None:
    """``1 + s(b - (b - a) rho q e^{-tau s})`` (transport plant, ``b = 1e100``): its real zero
    ``-1/(b (1 - rho q) + a rho q) ~ -1.7e-100`` lies within rounding of the axis, all others in
    ``Re s <= -ln(1/(rho q))/tau < 0``. The count had to move its edge: no certified number of
    unstable zeros (formerly 1), hence no claim of nominal stability either."""
    dm = nr.delay_margin(T0, FilteredController(0.1, 1e100), delta_max=0.1, verify=False)
    assert dm.nominal_unstable is None and not dm.nominally_stable


@pytest.mark.timeout(120)
def test_item14_long_delay_neutral_product_answers() -> None:
    # 2^-27 (s - r)^2 (s - conj r)^2 (s - r2)(s - conj r2) D(e^{-176 s}), D(z) = 1 + 0.625 z + 1.375 z^2
    roots = [complex(-5 / 512, 1 / 512), complex(3 / 512, 1 / 512), complex(3 / 512, 1 / 512)]
    p, c, h = poly_from_roots(roots, 2.0**-27), [1.0, 0.625, 1.375], 176.0
    F = QP([[ck * v for v in p] for ck in c], [k * h for k in range(len(c))])
    truth = max(3 / 512, chain_abscissa(z_roots(c), h))  # the double pair 3/512 +- i/512; chains at 9e-4
    sa = answer_or_nrobust_error(nr.spectral_abscissa, F, seconds=30.0)
    if sa is not None and sa.certified:
        np.testing.assert_allclose(sa.value, truth, rtol=0, atol=1e-6)


@pytest.mark.parametrize(
    "system, delta_max, kwargs",
    [
        (TransportSystem(1.375, 0.25, 0.875, 0.0), 1.0, {"Ks": [-0.5, 0.0, 0.5], "tol": 1e-4}),
        (T0, 0.1, {"Ks": [-0.5, 0.0, 0.5]}),
    ],
)
def test_item15_transport_k_region_answers(system: TransportSystem, delta_max: float, kwargs: dict) -> None:
    k = (1.0 - abs(system.rho * system.q)) / abs(system.q)  # closed form: |K| < (1 - |rho q|)/|q|, any delta_max
    region = answer_or_nrobust_error(nr.k_region, system, delta_max, seconds=30.0, **kwargs)
    if region is not None:
        ((lo, hi),) = region.intervals
        np.testing.assert_allclose([lo, hi], [-k, k], rtol=0, atol=region.tol)


def test_item16_k_region_has_no_nan() -> None:
    region = nr.k_region(T0, 0.1, Ks=[0.0], tol=1e-3)
    assert "nan" not in json.dumps(region.to_dict()).lower()
