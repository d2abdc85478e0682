"""The reproducers of issue 11, each asserting the correct behaviour against an independent truth.

Each test is marked ``xfail(strict=True)`` while its defect is open: a fix makes it pass,
strict mode turns that pass into a failure, and the mark is removed with the fix. The
truths come from ``tests/_oracles.py`` (Lambert W, the classical crossing algorithm in
exact arithmetic, ``mpmath`` root finding), never from nrobust itself. Items 10 and up were
found by the differential harness (``tests/test_harness.py``).
"""

from __future__ import annotations

import math
import warnings
from fractions import Fraction
from typing import Any

import numpy as np
import pytest
from _guards import hard_deadline, memory_cap
from _oracles import LoopOracle, _mp_roots, lambert_rightmost, squarefree_parts
from scipy.optimize import fsolve

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

QP = QuasiPolynomial
PAPER = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)


def xfail(item: str) -> pytest.MarkDecorator:
    return pytest.mark.xfail(strict=True, reason=f"issue 11 {item}")


def named_error(fn: Any, *args: Any, name: str, **kwargs: Any) -> None:
    """``fn(*args, **kwargs)`` raises a ParameterError that names ``name``."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ParameterError) as info:
            fn(*args, **kwargs)
    assert name in f"{info.value.name} {info.value}"


def answer_or_nrobust_error(fn: Any, *args: Any, seconds: float = 30.0, **kwargs: Any) -> Any:
    """A result, or a ParameterError/CertificationError: no other exception, no hang, no 80 GiB."""
    with hard_deadline(seconds), memory_cap(2 << 30), warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            return fn(*args, **kwargs)
        except (ParameterError, CertificationError):
            return None


def poly_roots(coefs: list[float]) -> list[complex]:
    """Roots of a real polynomial with float coefficients (taken exactly), by mpmath at 60 digits."""
    out: list[complex] = []
    for part, mult in squarefree_parts([Fraction(v) for v in coefs]):
        out.extend(complex(r) for r in _mp_roots(part) for _ in range(mult))
    return out


# ============================================================ item 1: false certified abscissa
@xfail("item 1")
def test_item1_long_delay_abscissa_is_certified_and_right() -> None:
    F = QP([[1.0, 1.0], [0.5]], [0.0, 14.0])  # s + 1 + 0.5 e^{-14 s}
    truth = lambert_rightmost(1.0, 0.5, 14.0)  # principal branch: -0.0476991 +- 0.20897 i
    sa = nr.spectral_abscissa(F)
    assert sa.certified
    np.testing.assert_allclose(sa.value, truth.real, rtol=0, atol=1e-9)


@xfail("item 1")
def test_item1_far_root_is_not_minus_infinity() -> None:
    sa = nr.spectral_abscissa(QP([[3000.0, 1.0]], [0.0]))  # s + 3000
    assert sa.certified
    np.testing.assert_allclose(sa.value, -3000.0, rtol=1e-12)
    assert sa.upper_bound >= -3000.0


@xfail("item 1")
def test_item1_certificate_abscissa_is_finite() -> None:
    cert = nr.certify(Hyperbolic2x2(0.1, 0.1, 0.3, 0.3, 1.0, 0.0), FilteredController(0.5, 1.0), k_region=False)
    sa = cert.abscissa
    assert math.isfinite(sa.value) and sa.certified
    # the rightmost root found in a box about the reported value agrees with it (the issue: about -0.125)
    F = nr.characteristic(cert.system, cert.controller, 0.0)
    box = (sa.value - 0.5, sa.value + 0.5, -1.0 - abs(sa.root.imag), 1.0 + abs(sa.root.imag))
    roots = nr.find_roots(F, box)
    assert roots.certified
    np.testing.assert_allclose(sa.value, np.max(roots.roots.real), atol=1e-8)
    assert -0.2 < sa.value < -0.05


# ============================================================ item 2: crossing on the frequency bound
UNDAMPED = ([1.0, 0.0, 1.0], [0.0, 1.0])  # A = s^2 + 1, B = s


@xfail("item 2")
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
    double zero near ``w = 4 pi`` (``g = dg/dw = 0``, solved here with scipy on the loop's
    values), and the crossing delay born there."""
    A, B0 = nr.loop_factors(PAPER, ReflectionController(0.0))
    q, tau = PAPER.q, PAPER.tau

    def g(x: np.ndarray) -> list[float]:
        K, w = x
        s = np.array([1j * w])
        a, da, b0, db0 = A(s)[0], 1j * A.deriv_at(s)[0], B0(s)[0], 1j * B0.deriv_at(s)[0]
        e = np.exp(-1j * w * tau)
        b, db = K * q * e + b0, -1j * tau * K * q * e + db0
        return [abs(a) ** 2 - abs(b) ** 2, 2 * (np.conj(a) * da).real - 2 * (np.conj(b) * db).real]

    (K, w), info, ok, _ = fsolve(g, [0.13075, 4 * np.pi], xtol=1e-14, full_output=True)
    assert ok == 1 and max(abs(v) for v in info["fvec"]) < 1e-12
    s = np.array([1j * w])
    b = K * q * np.exp(-1j * w * tau) + B0(s)[0]
    delay = float(np.mod(np.angle(-b / A(s)[0]), 2 * np.pi) / w)
    return float(K), float(w), delay


@xfail("item 3")
@pytest.mark.parametrize("K", [0.13074, 0.13075, 0.130755])
def test_item3_near_touch_is_not_a_crossing(K: float) -> None:
    K_b, w_b, _ = _paper_pair_birth()  # K_b = 0.1307588691, w_b = 12.5416
    assert K < K_b
    dm = nr.delay_margin(PAPER, ReflectionController(K))
    assert dm.verified
    assert not any(abs(abs(c.omega) - w_b) < 1e-2 for c in dm.crossings)
    assert dm.margin > 0.2


@xfail("item 3")
def test_item3_no_false_tangency_just_before_the_birth() -> None:
    K_b, w_b, _ = _paper_pair_birth()
    dm = nr.delay_margin(PAPER, ReflectionController(K_b - 1e-6), verify=False, delta_max=0.25)
    # |A| - |B| stays ~1e-7 above zero near w_b: no crossing there; the margin is the w = 9.427 branch
    assert not any(abs(abs(c.omega) - w_b) < 1e-2 for c in dm.crossings)
    assert dm.margin > 0.2


@xfail("item 3")
@pytest.mark.slow
@pytest.mark.timeout(600)
def test_item3_k_region_end_is_the_pair_birth() -> None:
    K_b, _, delay = _paper_pair_birth()
    assert delay < 0.2  # the pair is born with a crossing delay inside [0, delta_max]: it ends the interval
    region = nr.k_region(PAPER, 0.2, Ks=[0.12, 0.135], tol=1e-9)
    assert len(region.intervals) == 1
    np.testing.assert_allclose(region.intervals[0][1], K_b, rtol=0, atol=1e-8)


# ============================================================ item 4: Nyquist on advanced loops
@xfail("item 4")
def test_item4_nyquist_refuses_an_advanced_loop() -> None:
    A, B = QP([[1.0]], [0.0]), QP([[0.0, 1.0]], [0.0])  # 1 + s e^{-delta s}: advanced
    ny = nr.plots.nyquist_response(A, B, 0.5)
    assert ny.rhp_zeros is None and ny.note
    # the count that does not exist: chains of zeros in Re s > 0 (32 in this box alone)
    assert int(nr.count_roots(A + B.shift(0.5), (0.0, 40.0, -200.0, 200.0))) == 32


# ============================================================ item 5: wrong exception types
@xfail("item 5")
def test_item5_find_roots_tall_box_no_linalg_error() -> None:
    answer_or_nrobust_error(nr.find_roots, QP([[1.0, 1.0], [0.5, 0.5]], [0.0, 1.0]), (-1.0, 1.0, 0.0, 1e5))


@xfail("item 5")
@pytest.mark.timeout(120)
def test_item5_spectral_abscissa_long_delay_no_linalg_error() -> None:
    answer_or_nrobust_error(nr.spectral_abscissa, QP([[1.0, 1.0], [0.3, 0.3], [0.2, 0.2]], [0.0, 1.0, 1000.0]))


@xfail("item 5")
def test_item5_slow_plant_named_error() -> None:
    system = Hyperbolic2x2(1e-4, 1.0, 1.0, 1.0, 1.0, 0.85)
    answer_or_nrobust_error(nr.delay_margin, system, ReflectionController(0.1))


@xfail("item 5")
def test_item5_zero_B_no_nan_error() -> None:
    dm = answer_or_nrobust_error(nr.delay_margin, QP([[1.0, 0.0, 1.0]], [0.0]), QP([[0.0]], [0.0]))
    if dm is not None:  # s^2 + 1 for every delay: roots on the axis
        assert dm.margin == 0.0 and not dm.nominally_stable


@xfail("item 5")
def test_item5_non_numeric_delays_named() -> None:
    named_error(QP, [[1.0], [1.0]], ["a", "b"], name="delays")


@xfail("item 5")
def test_item5_non_numeric_nodes_named() -> None:
    named_error(nr.DistributedDelay, ["a", "b", "c"], [1.0, 1.0, 1.0], name="nodes")


# ============================================================ item 6: silent coercions
NO_CROSSING = (QP([[1.0, 1.0]], [0.0]), QP([[0.5]], [0.0]))  # s + 1 + 0.5 e^{-delta s}


@xfail("item 6")
@pytest.mark.parametrize("delta_max", [float("nan"), float("-inf")])
def test_item6_delta_max_not_coerced(delta_max: float) -> None:
    named_error(nr.delay_margin, *NO_CROSSING, delta_max=delta_max, name="delta_max")


@xfail("item 6")
def test_item6_identically_zero_loop_refused() -> None:
    named_error(nr.delay_margin, QP([[0.0]], [0.0]), QP([[0.0]], [0.0]), name="A")


@xfail("item 6")
def test_item6_zero_denominator_refused() -> None:
    named_error(nr.QuasiTransferFunction, 1.0, 0.0, name="den")


@xfail("item 6")
def test_item6_boolean_gain_refused() -> None:
    named_error(ReflectionController, True, name="K")


@xfail("item 6")
def test_item6_boolean_plant_parameter_refused() -> None:
    named_error(Hyperbolic2x2, 1.0, 1.0, 1.0, 1.0, 1.0, True, name="rho")


@xfail("item 6")
def test_item6_complex_initial_state_refused() -> None:
    T = TransportSystem(1.0, 2.0, 0.5, 0.8)
    named_error(
        nr.simulate, T, ReflectionController(0.1), 0.1, 1.0, lambda x: (1 + 1j) * np.sin(x), np.sin, 20, name="u0"
    )


# ============================================================ item 7: memory before work bounds
@xfail("item 7")
def test_item7_no_huge_grid_before_the_work_bound() -> None:
    system = Hyperbolic2x2(0.01, 1.0, 1.0, 1.0, 1.0, 0.85)
    answer_or_nrobust_error(nr.delay_margin, system, ReflectionController(0.1), seconds=60.0)


# ============================================================ item 8: refusals where the answer is easy
@xfail("item 8")
def test_item8_sixfold_root() -> None:
    p = [float(math.comb(6, k)) for k in range(7)]  # (s + 1)^6, exact
    sa = nr.spectral_abscissa(QP([p], [0.0]))
    assert sa.certified
    np.testing.assert_allclose(sa.value, -1.0, rtol=0, atol=1e-6)


@xfail("item 8")
def test_item8_one_rightmost_pair_without_exhausting_the_bound() -> None:
    sa = nr.spectral_abscissa(QP([[1.0, 1.0], [0.5]], [0.0, 10.0]))  # s + 1 + 0.5 e^{-10 s}
    assert sa.certified
    np.testing.assert_allclose(sa.value, lambert_rightmost(1.0, 0.5, 10.0).real, rtol=0, atol=1e-9)


@xfail("item 8")
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
