"""Certified root counting and finding against closed forms."""

from __future__ import annotations

import json

import mpmath
import numpy as np
import pytest
from scipy.special import lambertw

from nrobust import CertificationError, DistributedDelay, ParameterError, QuasiPolynomial, RegionError
from nrobust.roots import RootCount, count_roots, find_roots, spectral_abscissa

NEUTRAL = QuasiPolynomial([[1.0], [-0.85], [0.1]], [0.0, 2.0, 2.1])


def _match(found: np.ndarray, exact: np.ndarray) -> float:
    """Largest distance from an exact root to the nearest found root (and sizes equal)."""
    assert found.size == exact.size
    return float(np.max(np.min(np.abs(exact[:, None] - found[None, :]), axis=1)))


def _in(z: np.ndarray, region: tuple[float, float, float, float]) -> np.ndarray:
    return z[(z.real > region[0]) & (z.real < region[1]) & (z.imag > region[2]) & (z.imag < region[3])]


# ---------------------------------------------------------------- 1 - a e^{-tau s}
@pytest.mark.parametrize("a, tau", [(2.0, 1.0), (0.3, 2.5), (-0.5, 1.0), (-3.0, 0.7)])
def test_single_delay_closed_form(a: float, tau: float) -> None:
    F = QuasiPolynomial([[1.0], [-a]], [0.0, tau])
    region = (-3.0, 3.0, -20.0, 40.0)
    k = np.arange(-40, 41)
    shift = 0.0 if a > 0 else np.pi
    exact = _in((np.log(abs(a)) + 1j * (2 * np.pi * k + shift)) / tau, region)
    roots = find_roots(F, region)
    assert roots.certified and roots.count == exact.size == len(roots)
    assert _match(roots.roots, exact) < 1e-12
    assert int(count_roots(F, region)) == exact.size


# ---------------------------------------------------------------- s + a + b e^{-tau s}
@pytest.mark.parametrize("method", ["auto", "subdivision"])
@pytest.mark.parametrize("a, b, tau", [(1.0, 2.0, 1.0), (-0.5, 0.3, 2.0), (0.2, -1.5, 0.5), (0.0, 1.0, 1.0)])
def test_lambert_w(a: float, b: float, tau: float, method: str) -> None:
    F = QuasiPolynomial([[a, 1.0], [b]], [0.0, tau])
    region = (-6.0, 3.0, -30.0, 30.0)
    k = np.arange(-30, 31)
    exact = _in(-a + lambertw(-b * tau * np.exp(a * tau), k=k) / tau, region)
    exact = np.unique(np.round(exact, 12))
    roots = find_roots(F, region, method=method)
    assert roots.certified and roots.count == exact.size
    assert _match(roots.roots, exact) < 1e-11


# ---------------------------------------------------------------- the neutral example
def _neutral_exact(region: tuple[float, float, float, float]) -> np.ndarray:
    poly = np.zeros(22)
    poly[0], poly[20], poly[21] = 1.0, -0.85, 0.1  # 1 - 0.85 z^20 + 0.1 z^21, z = e^{-0.1 s}
    base = -np.log(np.roots(poly[::-1])) / 0.1
    k = np.arange(-2, int(region[3] * 0.1 / (2 * np.pi)) + 3)
    return _in((base[:, None] + 2j * np.pi * k[None, :] / 0.1).ravel(), region)


@pytest.mark.parametrize("method", ["auto", "subdivision"])
def test_neutral_64_roots(method: str) -> None:
    region = (-3.0, 1.0, -0.5, 200.0)
    exact = _neutral_exact(region)
    assert exact.size == 64
    assert int(count_roots(NEUTRAL, region)) == 64
    roots = find_roots(NEUTRAL, region, method=method)
    assert roots.certified and roots.count == 64 and len(roots) == 64
    assert np.all(roots.multiplicities == 1)
    assert _match(roots.roots, exact) < 1e-10
    assert np.max(roots.residuals) < 1e-10
    assert np.all(np.diff(roots.roots.imag) >= 0)


def test_neutral_tall_strip() -> None:
    region = (-3.0, 1.0, -0.5, 1000.0)
    exact = _neutral_exact(region)
    roots = find_roots(NEUTRAL, region)
    assert roots.certified and roots.count == exact.size == len(roots)
    assert _match(roots.roots, exact) < 1e-10


# ---------------------------------------------------------------- multiplicities
@pytest.mark.parametrize("method", ["auto", "subdivision"])
@pytest.mark.parametrize("a", [0.5, 2.0])
def test_double_roots_expanded_square(a: float, method: str) -> None:
    # (1 - a e^{-s})^2: double roots at ln a + 2 pi i k
    F = QuasiPolynomial([[1.0], [-2 * a], [a * a]], [0.0, 1.0, 2.0])
    region = (-2.0, 2.0, -1.0, 20.0)
    exact = _in(np.log(a) + 2j * np.pi * np.arange(0, 4), region)
    assert int(count_roots(F, region)) == 2 * exact.size
    roots = find_roots(F, region, method=method)
    assert roots.certified and roots.count == 2 * exact.size
    assert np.all(roots.multiplicities == 2)
    assert _match(roots.roots, exact) < 1e-9


@pytest.mark.parametrize(
    "coefs, center, mult",
    [
        ([1.0, -2.0, 1.0], 1.0, 2),  # (s - 1)^2
        ([1 + 5e-7, -(2 + 5e-7), 1.0], 1 + 2.5e-7, 2),  # roots 1 and 1 + 5e-7
        ([-1.0, 3.0, -3.0, 1.0], 1.0, 3),  # (s - 1)^3
    ],
)
def test_multiple_and_clustered_polynomial_roots(coefs: list[float], center: float, mult: int) -> None:
    F = QuasiPolynomial([coefs], [0.0])
    roots = find_roots(F, (0.0, 2.5, -1.0, 1.0))
    assert roots.certified and roots.count == mult
    assert len(roots) == 1 and roots.multiplicities[0] == mult
    assert abs(roots.roots[0] - center) < 1e-9


def test_cluster_next_to_delay_roots() -> None:
    # (s - 1)(s - 1 - 4e-7) + 1e-13 s^2 e^{-3 s}: two real roots about 3.7e-7 apart
    F = QuasiPolynomial([[1 + 4e-7, -(2 + 4e-7), 1.0], [0.0, 0.0, 1e-13]], [0.0, 3.0])
    roots = find_roots(F, (0.5, 1.5, -0.5, 0.5))
    assert roots.certified and roots.count == 2
    assert roots.multiplicities.tolist() == [2]


# ---------------------------------------------------------------- distributed delay
@pytest.mark.parametrize("k, T", [(1.0, 1.0), (3.0, 2.0), (10.0, 0.5)])
def test_distributed_delay_against_mpmath(k: float, T: float) -> None:
    # s + k (1 - e^{-sT}) / (sT) = s + (k/T) int_0^T e^{-nu s} dnu
    F = QuasiPolynomial([[0.0, 1.0]], [0.0], [DistributedDelay([0.0, T], [k / T, k / T])])
    region = (-4.0, 2.0, -0.5, 30.0)
    roots = find_roots(F, region)
    assert roots.certified and roots.count == len(roots) > 0

    def g(s: mpmath.mpc) -> mpmath.mpc:
        return s + k * (1 - mpmath.exp(-s * T)) / (s * T)

    for z in roots.roots:
        ref = complex(mpmath.findroot(g, mpmath.mpc(z.real, z.imag), tol=1e-28))
        assert abs(ref - z) < 1e-10 * (1 + abs(z))


# ---------------------------------------------------------------- counting details
def test_root_on_edge_is_shifted_and_reported() -> None:
    F = QuasiPolynomial([[-1.0, 1.0]], [0.0])  # root at s = 1
    res = count_roots(F, (0.0, 1.0, -1.0, 1.0))
    assert isinstance(res, RootCount) and int(res) == 1
    assert res.shifted and res.region[1] > 1.0
    assert json.loads(json.dumps(res.to_dict()))["count"] == 1
    assert res + 1 == 2 and "shifted=True" in repr(res)
    with pytest.raises(AttributeError):
        res.shifted = False  # type: ignore[misc]


def test_work_bound_names_the_edge() -> None:
    with pytest.raises(CertificationError, match="edge"):
        count_roots(NEUTRAL, (-3.0, 1.0, -0.5, 200.0), max_evals=50)


def test_rootset_output() -> None:
    roots = find_roots(NEUTRAL, (-3.0, 1.0, -0.5, 50.0))
    d = json.loads(json.dumps(roots.to_dict()))
    assert d["count"] == 16 and d["certified"] is True and sum(d["box_counts"]) == 16
    text = str(roots)
    assert "certified count 16" in text and text.count("\n") == 16 + 2
    assert "certified=True" in repr(roots)


# ---------------------------------------------------------------- spectral abscissa
def test_spectral_abscissa_retarded() -> None:
    F = QuasiPolynomial([[1.0, 1.0], [2.0]], [0.0, 1.0])
    res = spectral_abscissa(F)
    exact = -1.0 + lambertw(-2.0 * np.exp(1.0), k=0)
    assert res.certified and not res.approached_at_infinity
    assert res.value == pytest.approx(exact.real, abs=1e-12)
    assert res.upper_bound >= res.value
    json.dumps(res.to_dict())


def test_spectral_abscissa_unstable_real_root() -> None:
    F = QuasiPolynomial([[-1.0, 1.0], [0.5]], [0.0, 1.0])  # s - 1 + 0.5 e^{-s}
    res = spectral_abscissa(F)
    assert res.certified and res.root is not None and abs(res.root.imag) < 1e-12
    assert abs(res.root - 1 + 0.5 * np.exp(-res.root)) < 1e-12


def test_spectral_abscissa_neutral_chain() -> None:
    res = spectral_abscissa(NEUTRAL)
    c_d = NEUTRAL.principal_part().spectral_bound().value
    assert res.value == pytest.approx(c_d, abs=1e-10)
    assert res.chain_value == pytest.approx(c_d, abs=1e-14)
    assert res.strong_bound == pytest.approx(NEUTRAL.principal_part().strong_spectral_bound(), rel=1e-13, abs=1e-14)
    assert res.upper_bound >= res.strong_bound


def test_spectral_abscissa_neutral_approached_at_infinity() -> None:
    # s (1 + 0.5 e^{-s}) + 1: roots approach the chain Re s = ln 0.5 from the left
    F = QuasiPolynomial([[1.0, 1.0], [0.0, 0.5]], [0.0, 1.0])
    res = spectral_abscissa(F)
    assert res.chain_value == pytest.approx(np.log(0.5), abs=1e-14)
    assert res.value >= res.chain_value
    if res.approached_at_infinity:
        assert res.value == res.chain_value and res.root.real < res.chain_value


# ---------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "region",
    [(1.0, 0.0, 0.0, 1.0), (0.0, 1.0, 2.0, 2.0), (0.0, np.inf, 0.0, 1.0), (0.0, 1.0, np.nan, 1.0), (0.0, 1.0), "abc"],
)
def test_bad_region(region: object) -> None:
    for fn in (count_roots, find_roots):
        with pytest.raises(RegionError) as err:
            fn(NEUTRAL, region)
        assert err.value.name == "region"


def test_bad_function_and_options() -> None:
    with pytest.raises(ParameterError) as err:
        count_roots(lambda s: s, (0, 1, 0, 1))
    assert err.value.name == "F"
    with pytest.raises(ParameterError) as err:
        find_roots(QuasiPolynomial([[0.0]], [0.0]), (0, 1, 0, 1))
    assert err.value.name == "F"
    with pytest.raises(ParameterError) as err:
        find_roots(NEUTRAL, (0, 1, 0, 1), cluster_tol=-1.0)
    assert err.value.name == "cluster_tol"
    with pytest.raises(ParameterError) as err:
        find_roots(NEUTRAL, (0, 1, 0, 1), method="newton")
    assert err.value.name == "method"
    with pytest.raises(ParameterError) as err:
        count_roots(NEUTRAL, (0, 1, 0, 1), max_evals=0)
    assert err.value.name == "max_evals"


def test_root_at_corner_shifts_two_edges() -> None:
    F = QuasiPolynomial([[0.0, 1.0]], [0.0])  # root at s = 0
    res = count_roots(F, (0.0, 1.0, 0.0, 1.0))
    assert int(res) == 1 and res.shifted
    assert res.region[0] < 0.0 and res.region[2] < 0.0


@pytest.mark.parametrize("method", ["auto", "subdivision"])
def test_subdivision_cut_through_a_root(method: str) -> None:
    # the first cut of (-1, 1) x (-1, 1) is Re s = 0, through the root s = 0
    F = QuasiPolynomial([[0.0, 1.0]], [0.0])
    roots = find_roots(F, (-1.0, 1.0, -1.0, 1.0), method=method)
    assert roots.certified and roots.count == 1
    assert abs(roots.roots[0]) < 1e-14


def test_find_roots_region_through_roots_is_reported() -> None:
    # 1 - 2 e^{-s}: roots ln 2 + 2 pi i k; the region's right edge is Re s = ln 2
    F = QuasiPolynomial([[1.0], [-2.0]], [0.0, 1.0])
    roots = find_roots(F, (-1.0, np.log(2.0), -1.0, 13.0))
    assert roots.shifted and roots.region[1] > np.log(2.0)
    assert roots.certified and roots.count == 3
    np.testing.assert_allclose(roots.roots, np.log(2.0) + 2j * np.pi * np.arange(3), rtol=1e-13, atol=1e-13)


def test_complex_coefficients() -> None:
    # s - i w0 + a e^{-s}: no conjugate symmetry; roots are a rotated Lambert-W family
    w0, a = 3.0, 0.5
    F = QuasiPolynomial([[-1j * w0, 1.0], [a]], [0.0, 1.0])
    k = np.arange(-20, 21)
    exact = 1j * w0 + lambertw(-a * np.exp(-1j * w0), k=k)
    region = (-4.0, 2.0, -40.0, 40.0)
    exact = _in(exact, region)
    roots = find_roots(F, region)
    assert roots.certified and roots.count == exact.size
    assert _match(roots.roots, exact) < 1e-11
    res = spectral_abscissa(F)
    assert res.value == pytest.approx(np.max(exact.real), abs=1e-12)


def test_overflow_names_the_edge() -> None:
    F = QuasiPolynomial([[1.0], [-0.5]], [0.0, 10.0])
    with pytest.raises(CertificationError, match="overflows on the bottom edge"):
        count_roots(F, (-100.0, 1.0, 0.0, 1.0))


def test_spectral_abscissa_in_a_given_region() -> None:
    res = spectral_abscissa(NEUTRAL, (-3.0, 1.0, -0.5, 50.0))
    exact = _neutral_exact((-3.0, 1.0, -0.5, 50.0))
    assert res.certified and res.region == (-3.0, 1.0, -0.5, 50.0)
    assert res.root.real == pytest.approx(np.max(exact.real), abs=1e-12)
    assert not res.approached_at_infinity


def test_spectral_abscissa_rejects_advanced() -> None:
    F = QuasiPolynomial([[1.0], [0.0, 1.0]], [0.0, 1.0])  # 1 + s e^{-s}: advanced
    with pytest.raises(ParameterError) as err:
        spectral_abscissa(F)
    assert err.value.name == "F"


_CROSS_CASES = {
    # neutral of degree 1 with commensurate delays: chains are approximate seeds
    "neutral-degree-1": QuasiPolynomial([[1.0, 1.0], [0.0, -0.85], [0.3, 0.1]], [0.0, 2.0, 2.1]),
    # incommensurate delays: seeds from a commensurate approximation
    "incommensurate": QuasiPolynomial([[1.0], [0.6], [0.3]], [0.0, 1.0, np.sqrt(2.0)]),
    # a tabulated kernel with a jump, as N~ of the paper
    "distributed-jump": QuasiPolynomial(
        [[1.0], [-0.4]],
        [0.0, 1.5],
        [DistributedDelay([0.0, 0.5, 1.0, 1.0, 1.5], [0.3, -0.2, 0.1, -0.4, 0.2])],
    ),
}


@pytest.mark.parametrize("name", sorted(_CROSS_CASES))
def test_methods_agree(name: str) -> None:
    F = _CROSS_CASES[name]
    region = (-3.0, 1.0, -0.5, 60.0)
    auto = find_roots(F, region)
    sub = find_roots(F, region, method="subdivision")
    assert auto.certified and sub.certified and auto.count == sub.count > 0
    assert _match(auto.roots, sub.roots) < 1e-10
    assert np.max(auto.residuals) < 1e-10
    assert np.all(auto.radii < 1e-2)


def test_close_but_separate_roots_are_resolved() -> None:
    # roots 1 and 1 + 1.5e-5: one candidate box counts 2, contour moments separate them
    F = QuasiPolynomial([[1 + 1.5e-5, -(2 + 1.5e-5), 1.0]], [0.0])
    roots = find_roots(F, (0.0, 2.5, -1.0, 1.0))
    assert roots.certified and roots.count == 2
    assert roots.multiplicities.tolist() == [1, 1]
    assert _match(roots.roots, np.array([1.0, 1.0 + 1.5e-5])) < 1e-10
    assert np.all(roots.radii < 1.5e-5)


def test_certificate_boxes_hold_the_exact_roots() -> None:
    region = (-3.0, 1.0, -0.5, 200.0)
    exact = _neutral_exact(region)
    roots = find_roots(NEUTRAL, region)
    nearest = np.argmin(np.abs(exact[:, None] - roots.roots[None, :]), axis=1)
    assert np.all(np.abs(exact - roots.roots[nearest]) <= roots.radii[nearest])
    b = roots.boxes
    inside = (exact.real[:, None] > b[None, :, 0]) & (exact.real[:, None] < b[None, :, 1])
    inside &= (exact.imag[:, None] > b[None, :, 2]) & (exact.imag[:, None] < b[None, :, 3])
    assert np.all(inside.sum(axis=1) == 1)  # each exact root in exactly one certified box
    assert roots.box_counts.sum() == roots.count


def test_roots_on_different_scales_are_polished() -> None:
    # limit points of Newton's method from a coarse grid scatter; accepted roots are polished
    exact = np.array([1e-3, 2e-3, 10.0, 10.0 + 1e-3j, -5.0])
    F = QuasiPolynomial([np.poly(exact)[::-1]], [0.0])
    roots = find_roots(F, (-20.0, 20.0, -20.0, 20.0))
    assert roots.certified and roots.count == 5 and len(roots) == 5
    assert _match(roots.roots, exact) < 1e-10


@pytest.mark.parametrize("m", [3, 4, 5])
def test_high_multiplicity_chains(m: int) -> None:
    # (1 - e^{-s}/2)^m: m-fold roots at -ln 2 + 2 pi i k; Newton stalls at ~eps^(1/m)
    G = QuasiPolynomial([[1.0], [-0.5]], [0.0, 1.0])
    F = G
    for _ in range(m - 1):
        F = F * G
    roots = find_roots(F, (-2.0, 1.0, -1.0, 8.0))
    assert roots.certified and roots.count == 2 * m
    assert roots.multiplicities.tolist() == [m, m]
    assert _match(roots.roots, np.log(0.5) + 2j * np.pi * np.arange(2)) < 1e-8
    exact = np.log(0.5) + 2j * np.pi * np.arange(2)
    assert np.all(np.abs(roots.roots - exact) <= roots.radii)
