"""Difference operators: strong stability, spectral bounds and chains against closed forms."""

from __future__ import annotations

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nrobust import CertificationError, ParameterError, QuasiPolynomial, spectral_abscissa
from nrobust.difference import DifferenceOperator

# 1 - 0.85 e^{-2 s} + 0.1 e^{-2.1 s}: commensurate with h = 0.1, P(z) = 1 - 0.85 z^20 + 0.1 z^21.
D_EX = DifferenceOperator([1.0, -0.85, 0.1], [0.0, 2.0, 2.1])


def _z_roots() -> np.ndarray:
    poly = np.zeros(22)
    poly[0], poly[20], poly[21] = 1.0, -0.85, 0.1
    return np.roots(poly[::-1])


def test_gamma_0_and_strong_stability() -> None:
    assert D_EX.gamma_0 == pytest.approx(0.95, abs=1e-15)
    assert D_EX.is_strongly_stable()


def test_commensurate_step_and_degree() -> None:
    h, n = D_EX.commensurate_step()
    assert h == pytest.approx(0.1, rel=1e-14)
    assert n.tolist() == [0, 20, 21]


def test_chains_match_polynomial_roots() -> None:
    z = _z_roots()
    chains = D_EX.chains()
    assert chains.commensurate and len(chains) == 21
    assert chains.chains[0].spacing == pytest.approx(2 * np.pi / 0.1, rel=1e-13, abs=1e-14)
    got = np.array([c.z for c in chains.chains])
    assert np.max(np.min(np.abs(got[:, None] - z[None, :]), axis=0)) < 1e-12
    # every listed chain point is a zero of D
    pts = chains.points(-0.5, 200.0)
    assert pts.size == 21 * 3 + sum(1 for c in chains.chains if c.points(-0.5, 200.0).size == 4)
    scale = np.sum(np.abs(D_EX.coefs)[:, None] * np.exp(-np.outer(D_EX.delays, pts.real)), axis=0)
    assert np.max(np.abs(D_EX(pts)) / scale) < 1e-13
    reals = np.array([c.real for c in chains.chains])
    assert np.all(np.diff(reals) <= 0)


def test_spectral_bound_exact_for_commensurate() -> None:
    sb = D_EX.spectral_bound()
    assert sb.exact and sb.lower == sb.upper
    assert sb.value == pytest.approx(np.max(-np.log(np.abs(_z_roots())) / 0.1), abs=1e-12)
    assert sb.value <= D_EX.strong_spectral_bound() + 1e-12


@pytest.mark.parametrize(
    "coefs, delays",
    [([1.0, -0.85, 0.1], [0.0, 2.0, 2.1]), ([2.0, 1.0, -0.5, 0.3], [1.0, 1.5, 2.0, 3.7]), ([1.0, 3.0], [0.0, 1.0])],
)
def test_strong_spectral_bound_solves_its_equation(coefs: list[float], delays: list[float]) -> None:
    D = DifferenceOperator(coefs, delays)
    c = D.strong_spectral_bound()
    r = D.relative_delays[1:]
    lhs = np.sum(np.abs(D.coefs[1:]) * np.exp(-r * c))
    assert lhs == pytest.approx(abs(D.coefs[0]), rel=1e-13)
    assert (c < 0) == D.is_strongly_stable()


@settings(max_examples=80, deadline=None)
@given(
    a0=st.floats(0.1, 3.0),
    terms=st.lists(st.tuples(st.floats(-2.0, 2.0), st.floats(-3.0, 2.0), st.floats(0.01, 5.0)), min_size=1, max_size=5),
)
def test_strong_spectral_bound_against_mpmath(a0: float, terms: list[tuple[float, float, float]]) -> None:
    """``C_D`` against mpmath's root of ``sum |a_k| e^{-r_k c} = |a_0|`` at 40 digits (bisection, no shared code)."""
    coefs = [a0] + [sign_mag[0] * 10.0 ** sign_mag[1] for sign_mag in terms]
    coefs = [c if c != 0.0 else 1e-3 for c in coefs]
    delays = [0.0] + [t[2] for t in terms]
    D = DifferenceOperator(coefs, delays)
    with mpmath.workdps(40):
        mags = [abs(mpmath.mpf(float(c))) for c in D.coefs[1:]]
        rs = [mpmath.mpf(float(r)) for r in D.relative_delays[1:]]
        lhs = abs(mpmath.mpf(float(D.coefs[0])))

        def g(c: mpmath.mpf) -> mpmath.mpf:
            return mpmath.fsum(m * mpmath.exp(-r * c) for m, r in zip(mags, rs)) - lhs

        lo, hi = mpmath.mpf(-1e8), mpmath.mpf(1e8)  # g(lo) > 0 > g(hi): |ln(|a_k|/|a_0|)| / r_k < 1e4 here
        for _ in range(200):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if g(mid) > 0 else (lo, mid)
        root = float(lo)
    # C_D solves g(c) = 0 with |g'(c)| >= r_min |a_0|: a rounding of g of a few eps |a_0| moves it by a few
    # eps / r_min (1 + e^{-0.0625 c} = 1 has its root 0 computed as 7e-15)
    np.testing.assert_allclose(D.strong_spectral_bound(), root, rtol=4e-15, atol=4e-15 * max(1.0, 1.0 / float(min(rs))))


def test_two_terms_closed_form() -> None:
    # 1 + a e^{-tau s}: zeros at (ln|a| + i(arg(-a)... )) / tau, c_D = C_D = ln|a| / tau
    D = DifferenceOperator([1.0, -0.5], [0.0, 2.0])
    assert D.spectral_bound().value == pytest.approx(np.log(0.5) / 2, abs=1e-14)
    assert D.strong_spectral_bound() == pytest.approx(np.log(0.5) / 2, abs=1e-14)
    ch = D.chains()
    assert len(ch) == 1 and ch.chains[0].offset == pytest.approx(0.0, abs=1e-14)


def test_double_chain_multiplicity() -> None:
    # (1 - a e^{-s})^2 = 1 - 2a e^{-s} + a^2 e^{-2s}: one chain of double zeros
    a = 0.5
    ch = DifferenceOperator([1.0, -2 * a, a * a], [0.0, 1.0, 2.0]).chains()
    assert len(ch) == 1 and ch.chains[0].multiplicity == 2
    assert ch.chains[0].real == pytest.approx(np.log(a), abs=1e-7)


@pytest.mark.parametrize("rho_q", [-0.9, -0.51, -0.3, 0.0001, 0.2, 0.49, 0.51, 0.7, 2.0])
@pytest.mark.parametrize("delta", [0.05, 0.3, np.sqrt(2) / 3])
def test_paper_u_bs_principal_part(rho_q: float, delta: float) -> None:
    # paper: 1 - rho q e^{-tau s} + rho q e^{-(tau + delta) s}, not strongly stable iff |rho q| > 1/2
    tau = 1.7
    D = DifferenceOperator([1.0, -rho_q, rho_q], [0.0, tau, tau + delta])
    assert D.gamma_0 == pytest.approx(2 * abs(rho_q), rel=1e-15)
    assert D.is_strongly_stable() == (abs(rho_q) < 0.5)
    assert (D.strong_spectral_bound() < 0) == (abs(rho_q) < 0.5)


def test_incommensurate_bracket_is_certified() -> None:
    D = DifferenceOperator([1.0, 0.6, 0.3], [0.0, 1.0, np.sqrt(2)])
    assert D.commensurate_step() is None
    sb = D.spectral_bound()
    assert not sb.exact
    assert sb.upper == pytest.approx(D.strong_spectral_bound(), rel=1e-13, abs=1e-14)
    assert -np.inf < sb.lower <= sb.upper
    ch = D.chains()
    assert not ch.commensurate and ch.bracket == (sb.lower, sb.upper)


def test_single_term_has_no_zeros() -> None:
    D = DifferenceOperator([2.0], [0.5])
    assert D.spectral_bound().value == -np.inf
    assert D.strong_spectral_bound() == -np.inf
    ch = D.chains()
    assert len(ch) == 0 and ch.commensurate and ch.points(0.0, 10.0).size == 0
    assert "no zeros" in repr(ch)


def test_principal_part_of_quasipolynomial() -> None:
    F = QuasiPolynomial([[0.5, 1.0], [0.3, 0.7]], [0.0, 1.0])
    D = F.principal_part()
    assert isinstance(D, DifferenceOperator)
    assert D.coefs.tolist() == [1.0, 0.7]
    assert D.spectral_bound().value == pytest.approx(np.log(0.7), abs=1e-14)


def test_evaluation_and_dict() -> None:
    s = np.array([0.3 + 2j, -1.0])
    expect = 1 - 0.85 * np.exp(-2 * s) + 0.1 * np.exp(-2.1 * s)
    np.testing.assert_allclose(D_EX(s), expect, rtol=1e-15, atol=0)
    d = D_EX.to_dict()
    assert d["gamma_0"] == pytest.approx(0.95, rel=1e-13, abs=1e-14) and d["strongly_stable"] is True
    assert "gamma_0=0.95" in repr(D_EX)


@pytest.mark.parametrize(
    "coefs, delays, name",
    [
        ([], [], "coefs"),
        ([1.0, 2.0], [0.0, -1.0], "delays"),
        ([1.0, 2.0], [0.0, np.inf], "delays"),
        ([1.0, 2.0], [0.0], "delays"),
        ([0.0, 1.0], [0.0, 1.0], "coefs"),
        ([1.0, np.nan], [0.0, 1.0], "coefs"),
    ],
)
def test_bad_input_names_parameter(coefs: list[float], delays: list[float], name: str) -> None:
    with pytest.raises(ParameterError) as err:
        DifferenceOperator(coefs, delays)
    assert err.value.name == name


def test_close_delays_of_a_small_loop_delay_are_bracketed():
    """U_BS with delta = 0.003 (Theorem 3): delays 2 and 2.003 are 0.15 % apart."""
    D = DifferenceOperator([1.0, -0.85, 0.85], [0.0, 2.0, 2.003])
    sb = D.spectral_bound()
    assert sb.upper == pytest.approx(D.strong_spectral_bound(), abs=1e-12)
    assert 0.0 < sb.lower <= sb.upper  # a certified root to the right of the axis
    # Closer still (delta = 0.0007, 0.001): no commensurate approximation within the degree
    # bound; seeds over one beat period 2 pi / delta find the rightmost roots near
    # Im s = pi / delta, where |1 - e^{-delta s}| ~ 2 and the root's Re s is C_D to ~1e-6.
    for delta in (0.0007, 0.001):
        D = DifferenceOperator([1.0, -0.85, 0.85], [0.0, 2.0, 2.0 + delta])
        sb = D.spectral_bound()
        assert sb.upper == pytest.approx(D.strong_spectral_bound(), abs=1e-12)
        assert sb.upper - 1e-4 < sb.lower <= sb.upper
    # A beat period past the seeds' work bound: the bracket stays honest.
    sb = DifferenceOperator([1.0, -0.85, 0.85], [0.0, 2.0, 2.00004]).spectral_bound()
    assert sb.lower == -np.inf and sb.upper > 0.26


@pytest.mark.parametrize("tiny", [5.5e-18, 1e-12, -3e-15])
def test_a_negligible_top_coefficient_keeps_the_chains(tiny: float) -> None:
    """``0.1 - 0.06 e^{-1.5 s} + tiny e^{-1.6 s}`` (the principal part of a loop at a gain of 1e-16):
    the companion matrix normalised by ``tiny`` has entries near 1e16 and put the fifteen roots
    of modulus about 1 at 0 (``c_D = +inf``). The chains' abscissa against mpmath's roots of the
    same polynomial at 40 digits."""
    D = DifferenceOperator([0.1, -0.06, tiny], [0.0, 1.5, 1.6])
    with mpmath.workdps(40):
        coefs = [mpmath.mpf(0.1)] + [0] * 14 + [mpmath.mpf(-0.06), mpmath.mpf(tiny)]
        roots = mpmath.polyroots(coefs, maxsteps=500, extraprec=500, asc=True)
        expected = float(max(-mpmath.log(abs(z)) / mpmath.mpf(0.1) for z in roots))
    bound = D.spectral_bound()
    np.testing.assert_allclose([bound.lower, bound.upper], expected, rtol=1e-12)
    assert bound.upper < D.strong_spectral_bound() + 1e-12  # c_D <= C_D


def test_reverse_root_beyond_its_resolution_is_taken_from_the_forward_matrix() -> None:
    """``1 - 1.26e-4 z^2 + 1e-100 z^3`` (``z = e^{-s}``): the reverse's companion matrix (chosen:
    the constant term is the larger) computes the root ``w = 1/z ~ 8e-97`` as 0. Its roots
    ``z = +-1/sqrt(1.26e-4)`` put the chains at ``Re s = ln(1.26e-4) / 2`` (closed form), the third
    (``|z| ~ 1.26e96``) one far left; a root 0 taken as it is gave ``c_D = +inf`` and a
    spectral abscissa of ``-inf`` marked exact."""
    D = DifferenceOperator([1.0, -1.26e-4, 1e-100], [0.0, 2.0, 3.0])
    expected = np.log(1.26e-4) / 2.0
    np.testing.assert_allclose(D.spectral_bound().value, expected, rtol=1e-12)
    F = QuasiPolynomial([[1.0], [-1.26e-4], [1e-100]], [0.0, 2.0, 3.0])
    sa = spectral_abscissa(F)
    np.testing.assert_allclose(sa.value, expected, rtol=1e-10)
    # the roots of extreme modulus double precision cannot resolve at all: refused, not a chain at +-inf
    with pytest.raises(CertificationError, match="beyond double precision"):
        DifferenceOperator([1.0, 1e-310], [0.0, 1.0]).spectral_bound()


def test_operator_the_same_from_ordered_and_shuffled_terms() -> None:
    """Distinct increasing delays skip the merge; the operator is the one of the same terms in any order."""
    ordered = DifferenceOperator([1.0, -0.5, 0.25, 0.1], [0.0, 1.0, 1.5, 3.0])
    shuffled = DifferenceOperator([0.25, 1.0, 0.1, -0.5], [1.5, 0.0, 3.0, 1.0])
    split = DifferenceOperator([1.0, -0.3, 0.25, -0.2, 0.1], [0.0, 1.0, 1.5, 1.0, 3.0])  # -0.5 in two terms
    for other in (shuffled, split):
        np.testing.assert_array_equal(other.delays, ordered.delays)
        np.testing.assert_allclose(other.coefs, ordered.coefs, rtol=0, atol=1e-16)  # -0.3 - 0.2: one rounding


def test_principal_part_of_an_expanded_determinant_is_the_merged_operator() -> None:
    """The principal part of the expansion (distinct increasing delays: no merge) is the operator
    the constructor makes of shuffled terms, and that of the quasi-polynomial of the same determinant."""
    from nrobust.lti.statespace import StateSpaceTDS

    m0, m1 = np.zeros((6, 6)), np.zeros((6, 6))  # TDS-CONTROL manual Example 2.9 (benchmarks/statespace.py)
    m0[:2, :2], m0[2, :2], m0[2, 2] = [[0.2, 0.1], [-0.5, 1.0]], [1.0, 1.0], -1.0
    m0[3, 2], m0[3, 3] = 3.1, -3.48
    m0[4:, 2], m0[4:, 3], m0[4:, 4:] = [-1.86, -1.4], [1.79, -0.09], -np.eye(2)
    m1[:2, :2], m1[:2, 4:], m1[2, 4:] = [[0.5, 0.3], [0.1, -0.1]], np.eye(2), [0.01, 0.01]
    sys = StateSpaceTDS([m0, m1], [0.0, 1.0], E=np.diag([1.0, 1.0, 0.0, 1.0, 0.0, 0.0]))
    D = sys._expanded.principal_part()
    checked = DifferenceOperator(D.coefs[::-1], D.delays[::-1])  # decreasing delays: merged and sorted
    np.testing.assert_array_equal(D.coefs, checked.coefs)
    np.testing.assert_array_equal(D.delays, checked.delays)
    assert D.coefs.dtype == checked.coefs.dtype == np.float64
    Q = sys._expanded.poly.principal_part()  # the route through the quasi-polynomial
    np.testing.assert_array_equal(D.delays, Q.delays)
    np.testing.assert_allclose(D.coefs, Q.coefs, rtol=1e-15, atol=0)  # the same rounded coefficients


def test_gamma_0_overflows_to_inf() -> None:
    # a_0 = 5e-309 against 1: the ratio is above the largest double (a RuntimeWarning escaped)
    op = DifferenceOperator([5e-309, 1.0], [0.0, 1.0])
    assert op.gamma_0 == np.inf
    assert not op.is_strongly_stable()
