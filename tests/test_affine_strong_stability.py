"""Strong stability of an affine loop's difference operator on the whole of its parameter bounds.

``(A_0 + p A_1) + (B_0 + p B_1) e^{-delta s}`` has the principal part ``sum_k a_k(p) e^{-tau_k s}`` with
``a_k(p)`` affine in ``p``: strongly stable iff ``|a_0(p)| > sum_{k>=1} |a_k(p)|`` (Hale and Verduyn Lunel),
a condition that can fail inside bounds whose ends satisfy it.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nrobust import QuasiPolynomial
from nrobust.design.gain import AffineLoop, _Family, _strong_stability_failures, best_decay_rate, best_margin
from nrobust.errors import CertificationError, ParameterError
from nrobust.margins import delay_margin

ZERO = QuasiPolynomial([[0.0]], [0.0])


def _q(coefs: list[list[float]], delays: list[float]) -> QuasiPolynomial:
    return QuasiPolynomial(coefs, delays)


# (1 - p) + 0.1 p e^{-2 s} + 0.01 e^{-(3 + delta) s}: strongly stable at both ends of [0.5, 2] and at
# p = 1 (a pure shift there), not for 0.99 / 1.1 = 0.9 <= p <= 1.01 / 0.9 (1 - p = 0.1 p + 0.01 and
# p - 1 = 0.1 p + 0.01)
SHIFTED = AffineLoop(_q([[1.0]], [0.0]), _q([[-1.0], [0.1]], [0.0, 2.0]), _q([[0.01]], [3.0]), ZERO)


def test_interior_failure_refused_with_its_closed_form_ends() -> None:
    failures = _strong_stability_failures((SHIFTED.A0, SHIFTED.A1, SHIFTED.B0, SHIFTED.B1), 0.5, 2.0)
    assert len(failures) == 1
    # the ends are roots of affine functions, computed from the same coefficients: a few roundings
    np.testing.assert_allclose(failures[0][:2], (0.99 / 1.1, 1.01 / 0.9), rtol=1e-14)
    for design in (
        lambda: best_margin(SHIFTED, (0.5, 2.0)),
        lambda: best_decay_rate(SHIFTED, (0.5, 2.0), delays=(0.0, 0.5)),
        lambda: best_decay_rate(SHIFTED, (0.5, 2.0), margin_at_least=0.5),
    ):
        with pytest.raises(ParameterError, match=r"bounds.*not on \[0\.9, 1\.12222222222\]"):
            design()
    # the loop inside the reported gap is not strongly stable (an independent check: delay_margin's own test)
    for p in (0.91, 1.0 - 1e-6, 1.0 + 1e-6, 1.12):
        assert not delay_margin(SHIFTED.A(p), SHIFTED.B(p)).strongly_stable


def test_interior_failure_has_unstable_chains() -> None:
    # at p = 1.05 and an incommensurate delay, the principal part has a zero proven in Re s > 0
    # (the certified lower end of its spectral bound: Hale and Verduyn Lunel's C_D > 0 is attained)
    F = SHIFTED.loop_at(1.05, np.sqrt(2.0) * 1e-2)
    assert F.principal_part().spectral_bound().lower > 0.0


def test_bounds_inside_the_stable_parameters_are_designed() -> None:
    design = best_decay_rate(SHIFTED, (0.5, 0.85), delays=(0.0, 0.5))
    assert design.feasible == ((0.5, 0.85),)
    assert design.windows[0].stable
    with pytest.raises(ParameterError, match="bounds"):
        best_margin(SHIFTED, (0.5, 0.9))  # the closed end 0.9 is on the boundary: not strongly stable


# A filter's pole: A = A_0 (1 + p s), B = 0.3 + c s. For p != 0 the principal part is p s^2 alone; at p = 0
# the degree drops and the principal part is (1 + c e^{-delta s}) s: strongly stable iff |c| < 1.
@pytest.mark.parametrize(("c", "fails_at_zero"), [(0.5, False), (1.5, True)])
def test_degree_drop(c: float, fails_at_zero: bool) -> None:
    A0 = _q([[1.0, 1.0]], [0.0])
    loop = AffineLoop(A0, A0.times_poly([0.0, 1.0]), _q([[0.3, c]], [0.0]), ZERO)
    parts = (loop.A0, loop.A1, loop.B0, loop.B1)
    failures = _strong_stability_failures(parts, -1.0, 1.0)
    assert [f[:2] for f in failures] == ([(0.0, 0.0)] if fails_at_zero else [])
    assert delay_margin(loop.A(0.0), loop.B(0.0)).strongly_stable is not fails_at_zero
    assert _strong_stability_failures(parts, 0.1, 1.0) == []
    if fails_at_zero:
        with pytest.raises(ParameterError, match=r"bounds.*p = 0 \(of degree n - 1"):
            best_margin(loop, (-1.0, 1.0))


# Three terms of degree 0 (delays 0 and 1 in A, 1.5 in B), each coefficient affine in p; the oracle is
# gamma_0 of the principal part of the loop built at each of 401 parameters with a small loop delay.
@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-2.0, 2.0).map(lambda x: round(x, 3)), min_size=6, max_size=6),
    st.floats(-3.0, 3.0),
    st.floats(0.05, 3.0),
)
def test_failures_match_a_grid_of_gamma_0(c: list[float], lo: float, width: float) -> None:
    a0, b0, a1, b1, a2, b2 = c
    if a0 == b0 == 0.0:
        a0 = 1.0
    loop = AffineLoop(_q([[a0], [a1]], [0.0, 1.0]), _q([[b0], [b1]], [0.0, 1.0]), _q([[a2]], [1.5]), _q([[b2]], [1.5]))
    hi = lo + width
    failures = _strong_stability_failures((loop.A0, loop.A1, loop.B0, loop.B1), lo, hi)
    grid = np.linspace(lo, hi, 401)
    for p in grid:
        F = loop.loop_at(float(p), 1e-3)
        lead = [a for a, t in F.leading_terms(0)]
        first_at_zero = any(t == 0.0 for _, t in F.leading_terms(0))
        stable = first_at_zero and F.principal_part().gamma_0 < 1.0
        # away from the reported ends by more than the rounding of the gap (relative 1e-9 of the terms)
        slack = 1e-9 * (1.0 + float(np.sum(np.abs(lead))))
        inside = any(a - slack <= p <= b + slack for a, b, _ in failures)
        clear = all(p < a - slack or p > b + slack for a, b, _ in failures)
        if clear:
            assert stable, (p, failures)  # never a parameter called strongly stable that is not
        elif inside and all(not (abs(p - a) <= slack or abs(p - b) <= slack) for a, b, _ in failures):
            assert not stable, (p, failures)  # and the failures are real, not conservative


def test_uniform_crossing_bound_closed_form() -> None:
    # (s + 2 + p e^{-s}) + 0.5 s e^{-delta s}: the gap 1 - 0.5 at every p, the tails (2 + |p|) / R, so no
    # crossing above R = (2 + 3) / 0.5 = 10 for |p| <= 3 (|A| - |B| >= |w| (0.5 - (2 + |p|) / |w|))
    loop = AffineLoop(_q([[2.0, 1.0]], [0.0]), _q([[1.0]], [1.0]), _q([[0.0, 0.5]], [0.0]), ZERO)
    W = _Family(loop).crossing_bound(-1.0, 3.0)
    # the bound is found by bisection and kept above the root, with a 1e-9 relative room on the gap
    np.testing.assert_allclose(W, 10.0, rtol=1e-6)
    assert W >= 10.0
    for p in np.linspace(-1.0, 3.0, 9):
        crossings = delay_margin(loop.A(float(p)), loop.B(float(p))).crossings
        assert all(abs(c.omega) < W for c in crossings)


def test_degree_drop_of_a_general_family_is_not_bounded_uniformly() -> None:
    # A = 1 + p s (1 + 0.3 e^{-s}), B = 0.2: strongly stable at every p (the operator 1 + 0.3 e^{-s} for
    # p != 0, 1 against 0.2 at p = 0), but the gap |p| (1 - 0.3) tends to 0 at p = 0: no uniform bound there
    loop = AffineLoop(_q([[1.0]], [0.0]), _q([[0.0, 1.0], [0.0, 0.3]], [0.0, 1.0]), _q([[0.2]], [0.0]), ZERO)
    parts = (loop.A0, loop.A1, loop.B0, loop.B1)
    assert _strong_stability_failures(parts, -1.0, 1.0) == []
    with pytest.raises(CertificationError, match="degree drops"):
        best_margin(loop, (-1.0, 1.0))
    assert _Family(loop).crossing_bound(0.1, 1.0) > 0.0  # away from p = 0 the gap is at least 0.07


def _covers(failures: list[tuple[float, float, str]], p: float) -> bool:
    return any(a <= p <= b for a, b, _ in failures)


def test_advanced_everywhere_but_the_middle_fails_whole() -> None:
    # (s + 1) e^{-s} + p + 0.3 s e^{-(1 + delta) s}: for p != 0 the constant p precedes the principal term
    # s e^{-s} (advanced type); only p = 0, the middle of [-1, 1], is not
    loop = AffineLoop(_q([[1.0, 1.0]], [1.0]), _q([[1.0]], [0.0]), _q([[0.0, 0.3]], [1.0]), ZERO)
    failures = _strong_stability_failures((loop.A0, loop.A1, loop.B0, loop.B1), -1.0, 1.0)
    for p in (-1.0, -0.5, 0.5, 1.0):
        assert _covers(failures, p)
        assert not delay_margin(loop.A(p), loop.B(p)).strongly_stable
    with pytest.raises(ParameterError, match=r"bounds.*advanced"):
        best_margin(loop, (-1.0, 1.0))


def test_marginal_gap_beside_a_degree_drop_fails_the_whole_piece() -> None:
    # 2 + p s (1 + e^{-s}) against 0.5: for p != 0 the principal part 1 + e^{-s} has the gap 1 - 1 = 0 (not
    # strongly stable anywhere but at p = 0, where the degree drops); once half of each piece was reported
    loop = AffineLoop(_q([[2.0]], [0.0]), _q([[0.0, 1.0], [0.0, 1.0]], [0.0, 1.0]), _q([[0.5]], [0.0]), ZERO)
    parts = (loop.A0, loop.A1, loop.B0, loop.B1)
    for lo, hi in ((0.0, 1.0), (-1.0, 1.0)):
        failures = _strong_stability_failures(parts, lo, hi)
        for p in np.linspace(lo, hi, 11):
            if p != 0.0:
                assert _covers(failures, float(p))
    assert not delay_margin(loop.A(0.3), loop.B(0.3)).strongly_stable


def test_failure_ends_are_rounded_outward() -> None:
    # (2 + p) + e^{-s} - e^{-(1 + delta) s}: the gap |2 + p| - 2 is exactly 0 at p = 0, which must fail
    loop = AffineLoop(_q([[2.0], [1.0]], [0.0, 1.0]), _q([[1.0]], [0.0]), _q([[-1.0]], [1.0]), ZERO)
    failures = _strong_stability_failures((loop.A0, loop.A1, loop.B0, loop.B1), -0.4, 0.6)
    assert len(failures) == 1
    assert failures[0][0] == -0.4
    assert 0.0 <= failures[0][1] < 1e-13  # the closed-form end 0, moved outward by a few roundings


def test_the_first_term_of_a_for_large_delays() -> None:
    # (1 + p + 0.5 s) e^{-s} + s e^{-delta s}: for delta < 1 the principal part is s (1 + 0.5 e^{-(1 - delta) s})
    # (strongly stable), for delta > 1 it is s e^{-s} (0.5 + e^{-(delta - 1) s}): roots at Re s = ln 2 / (delta - 1)
    loop = AffineLoop(_q([[1.0, 0.5]], [1.0]), _q([[1.0]], [1.0]), _q([[0.0, 1.0]], [0.0]), ZERO)
    failures = _strong_stability_failures((loop.A0, loop.A1, loop.B0, loop.B1), 0.0, 1.0)
    assert [f[:2] for f in failures] == [(0.0, 1.0)]
    assert "comes first once delta passes" in failures[0][2]
    with pytest.raises(ParameterError, match="bounds"):
        best_decay_rate(loop, (0.0, 1.0), delays=(1.5, 2.0))


def test_a_loop_without_delayed_factor_has_no_best_margin() -> None:
    loop = AffineLoop(_q([[1.0, 1.0]], [0.0]), _q([[1.0]], [0.0]), ZERO, ZERO)
    with pytest.raises(ParameterError, match=r"loop.*delayed factor"):
        best_margin(loop, (0.0, 1.0))


def test_bounds_without_a_nominally_stable_parameter_are_refused() -> None:
    # s - 1 + p e^{-delta s} on [0, 0.5]: at delta = 0 the root s = 1 - p > 0 for every p (the margin was
    # returned as 0 with the bracket (inf, inf))
    loop = AffineLoop(_q([[-1.0, 1.0]], [0.0]), ZERO, ZERO, _q([[1.0]], [0.0]))
    with pytest.raises(ParameterError, match=r"bounds.*stable loop without delay"):
        best_margin(loop, (0.0, 0.5))


def test_best_margin_at_the_gain_where_s_0_becomes_a_root() -> None:
    """Left of ``K_0 = -(A_0(0) + B_0(0))/B_1(0)`` the nominal loop is unstable (margin 0) and no
    crossing curve exists; right of it the margin is about 0.80. The maximum is the supremum at
    ``K_0`` from the right (kind ``"end"``). Brent's search ran into the unstable side, where the
    curves give ``inf``, returned NaN (a RuntimeWarning) and a design with margin 0 at K = 0.425.
    """
    A0 = QuasiPolynomial([[0.564, 1.0], [-1.537, 0.0]], [0.0, 0.975])
    B0 = QuasiPolynomial([[0.494]], [0.65])
    B1 = QuasiPolynomial([[1.107]], [2.916])
    loop = AffineLoop(A0, QuasiPolynomial([[0.0]], [0.0]), B0, B1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        design = best_margin(loop, (-1.0, 1.0))
    K0 = (1.537 - 0.564 - 0.494) / 1.107  # F(0; delta, K_0) = 0 for every delay
    assert design.kind == "end" and 0.0 < design.K - K0 < 1e-8
    # a grid of margins certified one by one (delay_margin, not the design's curves): none above the design's
    grid = np.linspace(-1.0, 1.0, 41)
    margins = [delay_margin(loop.A(K), loop.B(K)).margin for K in grid]
    assert max(margins) <= design.margin * (1 + 1e-9)
    right = delay_margin(loop.A(K0 + 1e-7), loop.B(K0 + 1e-7)).margin
    np.testing.assert_allclose(design.margin, right, rtol=1e-5)  # the envelope's slope there is about 5
    assert delay_margin(loop.A(K0 - 1e-3), loop.B(K0 - 1e-3)).margin == 0.0
