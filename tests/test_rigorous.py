"""Proofs in ball arithmetic: enclosures of F, proven counts, proven roots, proven abscissae.

Every enclosure is checked against an independent high-precision value (mpmath at 40
digits: closed forms, or quadrature of the represented spline pieces); every proven
count against closed forms (Lambert W, exact polynomial roots, the z-polynomial of
commensurate delays) and against the floating-point path.
"""

from __future__ import annotations

import pickle
import sys
from collections.abc import Iterator
from typing import Any

import mpmath
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from nrobust import DistributedDelay, QuasiPolynomial
from nrobust.balls import (
    acb_to_disc,
    ball_abs_moment,
    ball_eval,
    ball_values,
    ball_variation_bound,
    enclose_box,
)
from nrobust.difference import DifferenceOperator
from nrobust.errors import CertificationError, ParameterError
from nrobust.qpmatrix import QuasiPolynomialMatrix
from nrobust.roots import count_roots, find_roots, spectral_abscissa
from nrobust.roots.winding import _arg_interval, _lift

flint = pytest.importorskip("flint")

NEUTRAL = QuasiPolynomial([[1.0], [-0.85], [0.1]], [0.0, 2.0, 2.1])
SPLINE = DistributedDelay(
    np.r_[np.linspace(0.0, 1.0, 21), np.linspace(1.0, 1.5, 6)],
    np.r_[np.cos(3 * np.linspace(0.0, 1.0, 21)), 0.5 * np.sin(np.linspace(1.0, 1.5, 6))],
    interpolation="cubic",
)
MOMENT = DistributedDelay(SPLINE.nodes, SPLINE.values, poly=[0.3, 1.0], moment=1, interpolation="cubic")
WITH_KERNEL = QuasiPolynomial([[1.0, 1.0], [-0.4]], [0.0, 1.5], [SPLINE, MOMENT])


@pytest.fixture(autouse=True)
def _forty_digits() -> Iterator[None]:
    """The mpmath oracles of this module work at 40 digits (other modules change ``mp.dps``)."""
    with mpmath.workdps(40):
        yield


def _poly(coefs: list, t: Any) -> Any:
    """``sum_j coefs[j] t^j`` (Horner)."""
    out = 0
    for c in reversed(coefs):
        out = out * t + c
    return out


def _in_disc(ball: object, exact: mpmath.mpc) -> bool:
    mid, rad = acb_to_disc(ball)
    return bool(abs(mpmath.mpc(mid.real, mid.imag) - exact) <= rad)


def _exact_point_terms(F: QuasiPolynomial, s: complex, k: int) -> mpmath.mpc:
    """``F^{(k)}(s)`` at 40 digits by mpmath's differentiation of the closed form."""

    def f(z: mpmath.mpc) -> mpmath.mpc:
        return sum(
            (sum(mpmath.mpf(float(c)) * z**j for j, c in enumerate(p)) * mpmath.exp(-mpmath.mpf(t) * z))
            for p, t in F.point_terms
        )

    return mpmath.diff(f, mpmath.mpc(s.real, s.imag), k)


def _phi(l_: int, w: mpmath.mpc) -> mpmath.mpc:
    """``int_0^1 t^l e^{-w t} dt`` at 40 digits: ``l! (1 - e^{-w} sum_{j<=l} w^j / j!) / w^(l+1)``
    (its cancellation costs at most 18 of the 40 digits for |w| >= 1e-3), else the series."""
    if abs(w) < 1e-3:
        return mpmath.fsum((-w) ** n / (mpmath.factorial(n) * (n + l_ + 1)) for n in range(30))
    partial = mpmath.fsum(w**j / mpmath.factorial(j) for j in range(l_ + 1))
    return mpmath.factorial(l_) * (1 - mpmath.exp(-w) * partial) / w ** (l_ + 1)


def _exact_distributed(d: DistributedDelay, s: complex, k: int) -> mpmath.mpc:
    """``d.poly(s) int nu^m N e^{-nu s}`` (k = 0) or its derivative (k = 1) for the represented
    pieces at 40 digits: on each piece ``(a + h t)^j P(t)`` is expanded exactly (rationals) and
    the monomials integrated by the incomplete gamma function."""
    start, h, poly_t = d.pieces
    z = mpmath.mpc(s.real, s.imag)

    def moment(j: int) -> mpmath.mpc:
        total = mpmath.mpc(0)
        for a0, h0, p in zip(start, h, poly_t):
            a, hv = mpmath.mpf(float(a0)), mpmath.mpf(float(h0))
            expanded = [mpmath.mpf(0)] * (j + len(p))
            for i in range(j + 1):  # (a + h t)^j = sum_i C(j, i) a^(j-i) h^i t^i
                for l_, c in enumerate(p):
                    expanded[i + l_] += mpmath.binomial(j, i) * a ** (j - i) * hv**i * mpmath.mpf(float(c))
            total += hv * mpmath.exp(-a * z) * sum(c * _phi(l_, hv * z) for l_, c in enumerate(expanded))
        return total

    q = [mpmath.mpf(float(c)) for c in d.poly]
    qv = _poly(q, z)
    if k == 0:
        return qv * moment(d.moment)
    dq = _poly([j * c for j, c in enumerate(q)][1:], z)
    return dq * moment(d.moment) - qv * moment(d.moment + 1)


# ---------------------------------------------------------------- enclosures
@pytest.mark.parametrize("k", [0, 1, 2])
def test_point_terms_enclose_the_closed_form(k: int) -> None:
    F = QuasiPolynomial([[1.0, 2.0, 0.5], [-0.85, 0.3], [0.1]], [0.0, 2.0, 2.1])
    for s in (0.3 + 5j, -1.0 + 0.2j, 2.0 - 70j, 0.0):
        ball = ball_eval(F, s, derivative=k)
        assert _in_disc(ball, _exact_point_terms(F, s, k))
        _, rad = acb_to_disc(ball)
        assert rad < 1e-12 * (1 + abs(complex(ball.real.mid(), ball.imag.mid())))


@pytest.mark.parametrize("k", [0, 1])
def test_distributed_terms_enclose_the_quadrature(k: int) -> None:
    # |s h| < 1 (series for phi_l), > 1 (recursion), and the moment / polynomial term
    for d in (SPLINE, MOMENT):
        F = QuasiPolynomial([[0.0]], [0.0], [d])
        for s in (0.0, 0.01 + 0.02j, 0.3 + 5j, -1.0 + 0.2j, 1.0 + 90j):
            ball = ball_eval(F, s, derivative=k)
            assert _in_disc(ball, _exact_distributed(d, s, k)), (d, s, k)
            assert acb_to_disc(ball)[1] < 1e-11


def test_ball_values_cover_the_float_evaluation() -> None:
    s = np.array([0.1 + 1j, -0.5 + 30j, 2.0 - 3j])
    mid, rad = ball_values(WITH_KERNEL, s)
    # the float path agrees to its own rounding (measured ~1e-15), far inside 1e-12
    np.testing.assert_allclose(mid, WITH_KERNEL(s), rtol=0, atol=1e-12)
    assert np.all(rad < 1e-11)


@pytest.mark.parametrize("centered", [False, True])
def test_box_enclosures_contain_sampled_values(centered: bool) -> None:
    rng = np.random.default_rng(3)
    for F in (NEUTRAL, WITH_KERNEL):
        box = (-0.2, 0.1, 4.0, 4.3)
        enc = enclose_box(F, box, centered=centered)
        z = rng.uniform(box[0], box[1], 40) + 1j * rng.uniform(box[2], box[3], 40)
        mid, rad = ball_values(F, z)  # point enclosures: their discs must meet the box enclosure
        lo_re, hi_re = float(enc.real.lower()), float(enc.real.upper())
        lo_im, hi_im = float(enc.imag.lower()), float(enc.imag.upper())
        assert np.all((mid.real + rad >= lo_re) & (mid.real - rad <= hi_re))
        assert np.all((mid.imag + rad >= lo_im) & (mid.imag - rad <= hi_im))


def test_bounds_of_the_kernel_hold() -> None:
    start, h, poly_t = SPLINE.pieces
    for x in (-1.0, 2.0):
        with mpmath.workdps(20):  # an upper bound is checked: 20 digits are plenty
            exact = sum(
                mpmath.quad(
                    lambda t, a=a, hv=hv, p=p, x=x: (
                        abs(_poly([float(c) for c in p], t)) * mpmath.exp(-(a + hv * t) * x) * hv
                    ),
                    [0, 1],
                )
                for a, hv, p in zip(start, h, poly_t)
            )
        assert ball_abs_moment(SPLINE, x).upper() >= exact
        v = float(ball_variation_bound(SPLINE, x).upper())
        F = QuasiPolynomial([[0.0]], [0.0], [SPLINE])
        for s in (x + 3j, x + 0.5 + 40j, x + 2 - 7j):
            assert abs(complex(F(s))) * abs(s) <= v


def test_arg_intervals_and_lifts() -> None:
    acb, arb = flint.acb, flint.arb
    left = _arg_interval(acb(arb(-1.0, 0.1), arb(0.0, 0.1)))  # straddles the branch cut
    assert left is not None and left[0] < np.pi < left[1] and left[1] - left[0] < 0.3
    assert _arg_interval(acb(arb(0.0, 0.1), arb(0.0, 0.1))) is None  # holds 0
    assert _lift((0.1, 0.2), (6.2, 6.4)) == pytest.approx((0.1 + 2 * np.pi, 0.2 + 2 * np.pi))
    assert _lift((-2.9, 2.9), (3.0, 3.1)) is None  # two lifts meet: refused


def test_without_flint_the_error_says_how_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "flint", None)
    F = QuasiPolynomial([[1.0, 1.0], [0.5]], [0.0, 1.0])
    for call in (
        lambda: count_roots(F, (-1, 1, 0, 1), rigorous=True),
        lambda: find_roots(F, (-1, 1, 0, 1), rigorous=True),
        lambda: spectral_abscissa(F, rigorous=True),
    ):
        with pytest.raises(ImportError, match=r"pip install nrobust\[rigorous\]"):
            call()
    assert int(count_roots(F, (-3, 1, -1, 1))) >= 0  # the floating-point path needs no flint


def test_bad_switches_are_named() -> None:
    with pytest.raises(ParameterError, match="rigorous"):
        count_roots(NEUTRAL, (-1, 1, 0, 1), rigorous="yes")  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="prec"):
        count_roots(NEUTRAL, (-1, 1, 0, 1), rigorous=True, prec=4)
    with pytest.raises(ParameterError, match="derivative"):
        ball_eval(NEUTRAL, 0.0, derivative=-1)
    with pytest.raises(ParameterError, match="s"):
        ball_eval(NEUTRAL, float("nan"))
    with pytest.raises(ParameterError, match="box"):
        enclose_box(NEUTRAL, (1.0, 0.0, 0.0, 1.0))


# ---------------------------------------------------------------- proven counts
_CORPUS = {
    "neutral-64": (NEUTRAL, (-3.0, 1.0, -0.5, 200.0)),
    "single-delay": (QuasiPolynomial([[1.0], [-2.0]], [0.0, 1.0]), (-2.0, 3.0, -0.5, 40.0)),
    "single-delay-negative": (QuasiPolynomial([[1.0], [0.5]], [0.0, 1.0]), (-2.0, 1.0, -40.0, 40.0)),
    "lambert": (QuasiPolynomial([[1.0, 1.0], [2.0]], [0.0, 1.0]), (-6.0, 2.0, -0.5, 30.0)),
    "lambert-2": (QuasiPolynomial([[0.2, 1.0], [-1.5]], [0.0, 0.5]), (-8.0, 2.0, -0.5, 30.0)),
    "neutral-degree-1": (
        QuasiPolynomial([[1.0, 1.0], [0.0, -0.85], [0.3, 0.1]], [0.0, 2.0, 2.1]),
        (-3.0, 1.0, -0.5, 60.0),
    ),
    "incommensurate": (QuasiPolynomial([[1.0], [0.6], [0.3]], [0.0, 1.0, np.sqrt(2.0)]), (-3.0, 1.0, -0.5, 60.0)),
    "distributed-jump": (
        QuasiPolynomial(
            [[1.0], [-0.4]], [0.0, 1.5], [DistributedDelay([0.0, 0.5, 1.0, 1.0, 1.5], [0.3, -0.2, 0.1, -0.4, 0.2])]
        ),
        (-3.0, 1.0, -0.5, 60.0),
    ),
    "cubic-kernel": (WITH_KERNEL, (-2.0, 1.0, -0.5, 20.0)),
}


@pytest.mark.parametrize("name", sorted(_CORPUS))
def test_proven_counts_agree_with_floating_point(name: str) -> None:
    F, region = _CORPUS[name]
    float_count = count_roots(F, region)
    proven = count_roots(F, region, rigorous=True)
    assert int(proven) == int(float_count) > 0
    assert proven.region == float_count.region and proven.rigorous and not float_count.rigorous
    assert proven.method == "ball arithmetic" and proven.to_dict()["rigorous"] is True
    assert pickle.loads(pickle.dumps(proven)).rigorous


def test_single_delay_closed_form() -> None:
    # 1 - 2 e^{-s}: roots ln 2 + 2 pi i k, seven with Im s in (-0.5, 40)
    assert int(count_roots(*_CORPUS["single-delay"], rigorous=True)) == 7


def test_root_on_the_edge_is_shifted_or_refused() -> None:
    F = QuasiPolynomial([[-1.0, 1.0]], [0.0])  # root at s = 1, on the left edge
    proven = count_roots(F, (1.0, 2.0, -1.0, 1.0), rigorous=True)
    assert int(proven) == 1 and proven.shifted and proven.region[0] < 1.0
    with pytest.raises(CertificationError, match="ball arithmetic"):
        count_roots(F, (1.0, 2.0, -1.0, 1.0), rigorous=True, max_shifts=0)


# ---------------------------------------------------------------- built to fool a rounding allowance
def _exact_polynomial_roots(F: QuasiPolynomial) -> list[complex]:
    """Roots of the stored float coefficients as rationals, isolated by FLINT (exact algebra)."""
    coefs = [flint.fmpq(*float(c).as_integer_ratio()) for c in F.coefs[0]]
    return [complex(z.mid()) for z, m in flint.fmpq_poly(coefs).complex_roots() for _ in range(m)]


@pytest.mark.parametrize("edge", ["left", "right"])
def test_roots_1e12_apart_at_an_edge(edge: str) -> None:
    # (s - 1)(s - 1 - 1e-12) with an edge between the two roots (5e-13 from each):
    # |F| on the edge ~ 2.5e-25, far below the rounding error of F (~1e-16)
    F = QuasiPolynomial([[1.0 + 1e-12, -(2.0 + 1e-12), 1.0]], [0.0])
    exact = _exact_polynomial_roots(F)
    region = (1.0 + 5e-13, 2.0, -1.0, 1.0) if edge == "left" else (0.0, 1.0 + 5e-13, -1.0, 1.0)
    for rigorous in (False, True):
        try:
            n = count_roots(F, region, rigorous=rigorous)
        except CertificationError:
            assert rigorous, "the floating-point path shifts the edge"
            continue
        x0, x1, y0, y1 = n.region
        truth = sum(x0 < z.real < x1 and y0 < z.imag < y1 for z in exact)
        assert int(n) == truth == 2 and n.shifted  # both paths move the edge past both roots


def test_coefficients_1e15_apart_against_lambert_w() -> None:
    # s + 1 + 1e15 e^{-40 s}: roots W_k(-40e15 e^40)/40 - 1, terms of sizes 1 and 1e15 balance there
    F = QuasiPolynomial([[1.0, 1.0], [1e15]], [0.0, 40.0])
    region = (0.0, 1.0, -0.5, 20.0)
    z = -mpmath.mpf(40) * mpmath.mpf(1e15) * mpmath.e**40
    roots = [mpmath.lambertw(z, k) / 40 - 1 for k in range(-200, 200)]
    truth = sum(0 < r.real < 1 and -0.5 < r.imag < 20 for r in roots)
    assert truth == 131
    assert int(count_roots(F, region)) == truth
    assert int(count_roots(F, region, rigorous=True)) == truth


def test_nearly_cancelling_delayed_terms() -> None:
    # (1 - 0.5 e^{-s})(1 + 0.5 e^{-tau s}), tau = 1 + 1e-12, expanded: -0.5 e^{-s} + 0.5 e^{-tau s}
    # cancel to 12 digits near s = 0. Roots: -ln 2 + 2 pi i k and (-ln 2 + i pi (2k + 1)) / tau;
    # the rounded delay 1 + tau of the product term moves them by < 1e-14.
    tau = 1.0 + 1e-12
    F = QuasiPolynomial([[1.0], [-0.5], [0.5], [-0.25]], [0.0, 1.0, tau, 1.0 + tau])
    region = (-2.0, 1.0, -0.5, 50.0)
    k = np.arange(8)
    exact = np.r_[-np.log(2) + 2j * np.pi * k, (-np.log(2) + 1j * np.pi * (2 * k + 1)) / tau]
    float_roots = find_roots(F, region)
    proven = find_roots(F, region, rigorous=True)
    assert proven.count == float_roots.count == 16 and proven.rigorous and proven.certified
    b = proven.boxes
    pad = 1e-13
    inside = (exact.real[:, None] > b[None, :, 0] - pad) & (exact.real[:, None] < b[None, :, 1] + pad)
    inside &= (exact.imag[:, None] > b[None, :, 2] - pad) & (exact.imag[:, None] < b[None, :, 3] + pad)
    assert np.all(inside.sum(axis=1) == 1)


# ---------------------------------------------------------------- proven roots
def _neutral_exact(H: float) -> np.ndarray:
    poly = np.zeros(22)
    poly[0], poly[20], poly[21] = 1.0, -0.85, 0.1
    base = -np.log(np.roots(poly[::-1])) / 0.1
    k = np.arange(-2, int(H * 0.1 / (2 * np.pi)) + 3)
    s = (base[:, None] + 2j * np.pi * k[None, :] / 0.1).ravel()
    return s[(s.real > -3) & (s.real < 1) & (s.imag > -0.5) & (s.imag < H)]


def _inside(points: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    ins = (points.real[:, None] > boxes[None, :, 0]) & (points.real[:, None] < boxes[None, :, 1])
    ins &= (points.imag[:, None] > boxes[None, :, 2]) & (points.imag[:, None] < boxes[None, :, 3])
    return ins


def test_64_roots_proven_each_in_its_box() -> None:
    region = (-3.0, 1.0, -0.5, 200.0)
    float_roots = find_roots(NEUTRAL, region)
    proven = find_roots(NEUTRAL, region, rigorous=True)
    assert proven.rigorous and proven.certified and proven.count == 64 == int(proven.multiplicities.sum())
    assert set(proven.proofs) == {"krawczyk"} and len(proven.proofs) == 64
    exact = _neutral_exact(200.0)
    assert np.all(_inside(exact, proven.boxes).sum(axis=1) == 1)
    assert np.all(_inside(float_roots.roots, proven.boxes).sum(axis=1) == 1)
    assert np.all(proven.radii < 1e-8)  # measured 2.8e-9: squares of half-width 1e-11 (1 + |s|)
    assert proven.to_dict()["rigorous"] is True


def test_clusters_are_proven_by_winding_numbers() -> None:
    # (1 - e^{-s}/2)^3 expanded (exact in floats): triple roots -ln 2 + 2 pi i k
    F = QuasiPolynomial([[1.0], [-1.5], [0.75], [-0.125]], [0.0, 1.0, 2.0, 3.0])
    proven = find_roots(F, (-2.0, 1.0, -0.5, 20.0), rigorous=True)
    assert proven.count == 12 and proven.multiplicities.tolist() == [3, 3, 3, 3]
    assert proven.proofs == ("winding",) * 4
    exact = -np.log(2) + 2j * np.pi * np.arange(4)
    assert np.all(_inside(exact, proven.boxes).sum(axis=1) == 1)


def test_roots_closer_than_rounding_are_proven_together_or_refused() -> None:
    F = QuasiPolynomial([[1.0 + 1e-12, -(2.0 + 1e-12), 1.0]], [0.0])
    exact = np.array(_exact_polynomial_roots(F))
    float_roots = find_roots(F, (0.0, 2.0, -1.0, 1.0))
    assert float_roots.multiplicities.tolist() == [2]  # a cluster in floating point
    try:
        proven = find_roots(F, (0.0, 2.0, -1.0, 1.0), rigorous=True)
    except CertificationError:
        return
    assert proven.multiplicities.tolist() == [2] and proven.proofs == ("winding",)
    assert np.all(_inside(exact, proven.boxes).sum(axis=1) == 1)


# ---------------------------------------------------------------- proven abscissa
def test_neutral_abscissa_proven() -> None:
    proven = spectral_abscissa(NEUTRAL, rigorous=True)
    float_result = spectral_abscissa(NEUTRAL)
    exact = float(np.max(_neutral_exact(200.0).real))  # the chains' real parts, from P(z)
    np.testing.assert_allclose(proven.value, exact, rtol=0, atol=1e-12)
    assert proven.value == float_result.value and proven.rigorous
    assert proven.root_box is not None
    x0, x1, y0, y1 = proven.root_box
    # the box, contracted by Krawczyk's operator to 6e-16, holds the root at 40 digits (the chains' real parts
    # from P(z) in floating point are 1.5e-14 off)
    root = mpmath.findroot(
        lambda s: 1 - mpmath.mpf(0.85) * mpmath.exp(-2 * s) + mpmath.mpf(0.1) * mpmath.exp(-mpmath.mpf(2.1) * s),
        mpmath.mpc(proven.root),
    )
    assert x0 <= root.real <= x1 and y0 <= root.imag <= y1
    assert proven.upper_bound >= proven.value


@pytest.mark.parametrize("a, b, tau", [(1.0, 2.0, 1.0), (0.5, 0.5, 14.0)])
def test_retarded_abscissa_proven_against_lambert_w(a: float, b: float, tau: float) -> None:
    # s + a + b e^{-tau s}: the rightmost roots are the principal branch W_0(-b tau e^{a tau}) / tau - a
    F = QuasiPolynomial([[a, 1.0], [b]], [0.0, tau])
    w = mpmath.lambertw(-b * tau * mpmath.e ** (a * tau), 0) / tau - a
    proven = spectral_abscissa(F, rigorous=True)
    assert proven.rigorous and proven.root_box is not None
    np.testing.assert_allclose(proven.value, float(w.real), rtol=0, atol=1e-12)
    x0, x1, _, _ = proven.root_box
    # upper_bound is the right edge of the rightmost proven box
    assert x0 <= float(w.real) <= x1 == proven.upper_bound
    assert proven.value == spectral_abscissa(F).value


def test_abscissa_with_a_kernel_agrees() -> None:
    F = QuasiPolynomial([[1.0, 1.0], [0.3]], [0.0, 1.0], [SPLINE])
    proven = spectral_abscissa(F, rigorous=True)
    float_result = spectral_abscissa(F)
    np.testing.assert_allclose(proven.value, float_result.value, rtol=0, atol=1e-12)
    assert proven.root_box is not None and proven.root_box[0] <= float_result.value <= proven.root_box[1]
    assert float_result.upper_bound >= proven.upper_bound >= proven.value


@settings(max_examples=20, derandomize=True, database=None, deadline=None)
@example(a=2.0, tau=1.0, x0=float(np.log(2.0)), width=1.0, y0=-1.0, height=10.0)  # roots on the left edge
@example(a=2.0, tau=1.0, x0=float(np.log(2.0)), width=1.0, y0=0.0, height=2 * np.pi)  # roots at two corners
@given(
    a=st.floats(0.2, 5.0),
    tau=st.floats(0.3, 3.0),
    x0=st.floats(-2.0, 0.5),
    width=st.floats(0.1, 3.0),
    y0=st.floats(-10.0, 5.0),
    height=st.floats(0.5, 30.0),
)
def test_proven_counts_match_the_closed_form(
    a: float, tau: float, x0: float, width: float, y0: float, height: float
) -> None:
    # 1 - a e^{-tau s}: roots (ln a + 2 pi i k) / tau; edges anywhere, also through roots
    F = QuasiPolynomial([[1.0], [-a]], [0.0, tau])
    k = np.arange(-200, 201)
    roots = (np.log(a) + 2j * np.pi * k) / tau
    for rigorous in (False, True):
        try:
            n = count_roots(F, (x0, x0 + width, y0, y0 + height), rigorous=rigorous)
        except CertificationError:
            continue  # refused, never wrong
        r0, r1, i0, i1 = n.region
        # the proven boundary holds no root; the closed form is accurate to ~1e-14, so a root
        # within 1e-12 of the returned boundary would make the reference itself ambiguous
        gap = np.minimum.reduce([np.abs(roots.real - r0), np.abs(roots.real - r1), np.abs(roots.imag - i0)])
        gap = np.minimum(gap, np.abs(roots.imag - i1))
        if gap.min() > 1e-12:
            truth = int(np.sum((roots.real > r0) & (roots.real < r1) & (roots.imag > i0) & (roots.imag < i1)))
            assert int(n) == truth, (rigorous, n, truth)


# ---------------------------------------------------------------- matrices (det M, never expanded)
LAMBERT = QuasiPolynomial([[1.0, 1.0], [2.0]], [0.0, 1.0])
COUPLED = QuasiPolynomialMatrix(
    [
        [QuasiPolynomial([[1.0, 1.0]], [0.0]), QuasiPolynomial([[0.5]], [1.0])],
        [QuasiPolynomial([[0.3]], [0.5]), QuasiPolynomial([[2.0, 1.0], [-0.4]], [0.0, 1.0])],
    ]
)


def _exact_coupled(s: complex, k: int) -> mpmath.mpc:
    """``(det COUPLED)^{(k)}(s)`` at 40 digits (the determinant written out, mpmath's derivative)."""

    def det(z: mpmath.mpc) -> mpmath.mpc:
        e = mpmath.exp
        return (z + 1) * (z + 2 - mpmath.mpf(0.4) * e(-z)) - mpmath.mpf(0.5) * e(-z) * mpmath.mpf(0.3) * e(-z / 2)

    return mpmath.diff(det, mpmath.mpc(s.real, s.imag), k)


@pytest.mark.parametrize("k", [0, 1, 2])
def test_matrix_determinant_encloses_the_closed_form(k: int) -> None:
    for s in (0.3 + 5j, -1.0 + 0.2j, 2.0 - 30j):
        ball = ball_eval(COUPLED, s, derivative=k)
        assert _in_disc(ball, _exact_coupled(s, k))
        assert acb_to_disc(ball)[1] < 1e-12 * (1.0 + abs(complex(_exact_coupled(s, k))))
    with pytest.raises(ParameterError, match="derivative"):
        ball_eval(COUPLED, 0.0, derivative=5)


@pytest.mark.parametrize("upper", [0.0, 0.7], ids=["diagonal", "triangular"])
def test_matrix_counts_and_roots_are_those_of_the_diagonal(upper: float) -> None:
    # det of a triangular matrix is the product of its diagonal: its roots are the union, 10 roots of
    # NEUTRAL (its z-polynomial) and 5 of s + 1 + 2 e^{-s} (Lambert W branches) in the region
    M = QuasiPolynomialMatrix([[NEUTRAL, QuasiPolynomial([[upper]], [0.3])], [0.0, LAMBERT]])
    region = (-3.0, 1.0, -0.5, 30.0)
    n = count_roots(M, region, rigorous=True)
    parts = [find_roots(F, region, rigorous=True) for F in (NEUTRAL, LAMBERT)]
    assert n.rigorous and int(n) == sum(p.count for p in parts) == int(count_roots(M, region)) == 15
    proven = find_roots(M, region, rigorous=True)
    assert proven.rigorous and proven.count == int(n) and set(proven.proofs) == {"krawczyk"}
    scalar = np.concatenate([p.roots for p in parts])
    assert np.all(_inside(scalar, proven.boxes).sum(axis=1) == 1)


def test_coupled_matrix_agrees_with_its_expansion() -> None:
    # point delays only: det M expands to a quasi-polynomial, proven by the scalar path
    region = (-4.0, 1.0, -0.5, 25.0)
    F = COUPLED.expand()
    proven = find_roots(COUPLED, region, rigorous=True)
    scalar = find_roots(F, region, rigorous=True)
    assert proven.rigorous and proven.count == scalar.count == int(count_roots(COUPLED, region, rigorous=True)) > 0
    assert np.all(_inside(scalar.roots, proven.boxes).sum(axis=1) == 1)
    assert np.all(_inside(proven.roots, scalar.boxes).sum(axis=1) == 1)
    sa = spectral_abscissa(COUPLED, region, rigorous=True)
    assert sa.rigorous and sa.root_box is not None
    np.testing.assert_allclose(sa.value, np.max(scalar.roots.real), rtol=0, atol=1e-12)


# ---------------------------------------------------------------- the chain abscissa, proven
def _z_poly_abscissa(coefs: list[float], powers: list[int], h: float) -> mpmath.mpf:
    """``max -ln|z| / h`` over the roots of ``sum coefs_k z^powers_k`` (mpmath, 40 digits)."""
    poly = [mpmath.mpf(0)] * (powers[-1] + 1)
    for c, k in zip(coefs, powers):
        poly[k] += mpmath.mpf(c)
    roots = mpmath.polyroots(poly, maxsteps=200, extraprec=200, asc=True)
    return max(-mpmath.log(abs(z)) / mpmath.mpf(h) for z in roots)


@pytest.mark.parametrize(
    "coefs, delays, powers, h",
    [([1.0, -0.5], [0.0, 1.0], [0, 1], 1.0), ([1.0, -0.85, 0.1], [0.0, 2.0, 2.5], [0, 4, 5], 0.5)],
    ids=["1 - e^-s / 2", "dyadic delays"],
)
def test_chain_bound_of_exactly_commensurate_delays(coefs: list, delays: list, powers: list, h: float) -> None:
    D = DifferenceOperator(coefs, delays)
    sb = D.proven_spectral_bound()
    exact = float(_z_poly_abscissa(coefs, powers, h))
    assert sb.proven and sb.exact and sb.step == h
    assert sb.lower <= exact <= sb.upper and sb.upper - sb.lower < 1e-14  # measured ~1e-16
    np.testing.assert_allclose(D.spectral_bound().value, exact, rtol=0, atol=1e-14)
    with pytest.raises(ParameterError, match="prec"):
        D.proven_spectral_bound(prec=4)
    assert DifferenceOperator([2.0], [1.0]).proven_spectral_bound().upper == -np.inf  # one term: no zero


def test_chain_bound_of_delays_commensurate_to_rounding() -> None:
    # 2.0 and 2.1 as stored are not 20:21, so c_D of D as represented is only bracketed: by a proven
    # zero of D (Krawczyk) and the proven C_D, around the value of the commensurate floating-point path
    for D in (NEUTRAL.principal_part(), DifferenceOperator([1.0, 0.6, 0.3], [0.0, 1.0, np.sqrt(2.0)])):
        sb = D.proven_spectral_bound()
        assert sb.proven and not sb.exact
        assert sb.upper >= D.strong_spectral_bound() and sb.lower > -np.inf
        # the floating-point c_D (numpy's companion-matrix roots) is good to ~1e-14: measured 6.5e-15 above
        # the proven C_D for NEUTRAL, which no exact c_D can exceed
        assert sb.lower - 1e-13 <= D.spectral_bound().value <= sb.upper + 1e-13
        # the zero behind the lower end, found again by mpmath at 40 digits
        a = [mpmath.mpf(float(v)) for v in D.coefs.real]
        t = [mpmath.mpf(float(v)) for v in D.delays]

        def d(s: mpmath.mpc, a: list = a, t: list = t) -> mpmath.mpc:
            return mpmath.fsum(ak * mpmath.exp(-tk * s) for ak, tk in zip(a, t))

        # seeds on the six rightmost chains of the approximation: for incommensurate delays the zero
        # nearest c_D may sit on any of them (here on the second: -0.0924376836, the first reaches -0.0928)
        chains = D.commensurate_approximation().chains() if D.commensurate_step() is None else D.chains()
        zeros = []
        for chain in chains.chains[:6]:
            for x in chain.points(0.0, 8 * chain.spacing):
                try:
                    zeros.append(mpmath.findroot(d, mpmath.mpc(x)))
                except ValueError:  # a seed between two zeros: Newton does not settle
                    continue
        assert all(abs(d(z)) < 1e-30 and float(z.real) <= sb.upper for z in zeros)
        # a zero at least as far right as the proven one (lower is its box's left edge)
        assert sb.lower <= max(float(z.real) for z in zeros) <= sb.upper


def test_abscissa_value_brackets_are_proven() -> None:
    # neutral: the chain value c_D (z-polynomial at 40 digits) inside both brackets
    proven = spectral_abscissa(NEUTRAL, rigorous=True)
    exact = float(_z_poly_abscissa([1.0, -0.85, 0.1], [0, 20, 21], 0.1))
    assert proven.chain_bracket is not None and proven.value_bracket is not None
    assert proven.chain_bracket[0] <= exact <= proven.chain_bracket[1]
    assert proven.value_bracket[0] <= exact <= proven.value_bracket[1] == proven.upper_bound
    assert proven.to_dict()["value_bracket"] == list(proven.value_bracket)
    # the half-plane right of the value is proven root-free, not only right of the search edge:
    # a difference operator: every zero lies on a chain, the upper end is the chain bracket's (measured:
    # width 3.2e-11; the root boxes' 9.8e-10 before; the search edge is 0.077)
    assert proven.value_bracket[1] - proven.value_bracket[0] < 1e-10
    # retarded: Lambert W inside a bracket 1e-10 wide (the proven box of the rightmost root)
    F = QuasiPolynomial([[1.0, 1.0], [2.0]], [0.0, 1.0])
    w = float((mpmath.lambertw(-2.0 * mpmath.e, 0) - 1).real)
    r = spectral_abscissa(F, rigorous=True)
    assert r.chain_bracket is None and r.value_bracket is not None
    assert r.value_bracket[0] <= w <= r.value_bracket[1] and r.value_bracket[1] - r.value_bracket[0] < 1e-9
    # a polynomial: FLINT's isolating ball is the proven box
    p = spectral_abscissa(QuasiPolynomial([[3000.0, 1.0]], [0.0]), rigorous=True)
    assert p.root_box is not None and p.root_box[0] <= -3000.0 <= p.root_box[1]
    assert p.value_bracket == (p.root_box[0], p.upper_bound)
    assert spectral_abscissa(NEUTRAL).value_bracket is None and spectral_abscissa(F).root_box is None


def _chain_roots_mpmath(y_max: float) -> list[complex]:
    """Roots of ``(s + 2) + (0.9 s - 1) e^{-s}`` up to ``Im s = y_max`` by mpmath alone.

    High up, ``e^{-s} = -(s + 2)/(0.9 s - 1) -> -1/0.9``: one root near each
    ``ln 0.9 + i (2k + 1) pi``, refined from there by Newton's method at 30 digits.
    """
    with mpmath.workdps(30):
        f = lambda s: (s + 2) + (0.9 * s - 1) * mpmath.exp(-s)  # noqa: E731
        seeds = [mpmath.mpc(mpmath.log(0.9), (2 * k + 1) * mpmath.pi) for k in range(int(y_max / (2 * np.pi)))]
        return [complex(mpmath.findroot(f, z)) for z in seeds]


def test_abscissa_approached_at_infinity_has_a_proven_upper_end() -> None:
    # the value is the chain abscissa ln 0.9, approached from the right as |Im s| -> infinity
    # (Re s = ln 0.9 + O(1/|s|^2)): the proven upper end bounds every root, and comes down
    # towards ln 0.9 as the band searched grows (the far field closes at radius height)
    F = QuasiPolynomial([[2.0, 1.0], [-1.0, 0.9]], [0.0, 1.0])
    oracle = _chain_roots_mpmath(3000.0)
    ends = []
    for height in (100.0, 1000.0):
        r = spectral_abscissa(F, rigorous=True, im_max=height)
        assert r.approached_at_infinity and r.value_bracket is not None
        lo, hi = r.value_bracket
        assert lo <= np.log(0.9) <= hi and hi == r.upper_bound
        assert max(z.real for z in oracle) < hi
        ends.append(hi)
    assert ends[1] < ends[0] < 0.0  # measured: -0.0741 and -0.1022 (the search edge was 0.077)
    np.testing.assert_allclose(ends[1], np.log(0.9), atol=5e-3)
