"""The certified spectral abscissa and root clusters against independent routes.

Truths: the principal branch of Lambert W for ``s + a + b e^{-tau s}``, the roots of the float
polynomial taken exactly (``tests/_oracles.py``: rationals, square-free parts, 60 digits), the
chains of a z-polynomial of commensurate delays, and closed forms. ``-inf`` is a claim like any
other: only ``c e^{-tau s}`` has no root.
"""

from __future__ import annotations

import sys
import time

import mpmath
import numpy as np
import pytest
from _oracles import chain_abscissa, lambert_rightmost, poly_roots, z_roots

from nrobust import CertificationError, DistributedDelay, QuasiPolynomial
from nrobust.roots import count_roots, find_roots, spectral_abscissa

QP = QuasiPolynomial


def _lambert(a: float, b: float, tau: float) -> QuasiPolynomial:
    return QP([[a, 1.0], [b]], [0.0, tau])


@pytest.fixture(params=["flint", "no-flint"])
def exact_route(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """Run with python-flint (exact polynomial roots) and without it (certified counts only)."""
    if request.param == "no-flint":
        monkeypatch.setitem(sys.modules, "flint", None)  # ``import flint`` raises ImportError
    return str(request.param)


# ---------------------------------------------------------------- long delays, far roots
@pytest.mark.parametrize(
    "a, b, tau",
    [
        (1.0, 0.5, 14.0),  # once: -inf was reported as certified
        (1.0, 0.5, 10.0),  # once: the work bound was exhausted
        (1.0, 0.5, 40.0),
        (1.0, 0.5, 100.0),
        (1.0, -0.99, 50.0),
        (-0.5, 0.3, 2.0),
        (100.0, 1.0, 1.0),  # rightmost roots far left, on a log curve
        (1.0, 1e3, 1.0),  # many roots right of the axis: the march starts small
        (0.0, 1e-8, 100.0),
    ],
)
def test_retarded_abscissa_is_the_principal_lambert_branch(a: float, b: float, tau: float) -> None:
    truth = lambert_rightmost(a, b, tau)
    start = time.perf_counter()
    sa = spectral_abscissa(_lambert(a, b, tau))
    elapsed = time.perf_counter() - start
    assert sa.certified and not sa.approached_at_infinity
    np.testing.assert_allclose(sa.value, truth.real, rtol=0, atol=1e-10 * (1 + abs(truth)))
    np.testing.assert_allclose(sa.root, complex(truth.real, abs(truth.imag)), rtol=0, atol=1e-9 * (1 + abs(truth)))
    assert truth.real <= sa.upper_bound < truth.real + 1e-2
    assert elapsed < 4.0


def test_long_delay_abscissa_agrees_with_find_roots_about_it() -> None:
    F = _lambert(1.0, 0.5, 14.0)
    sa = spectral_abscissa(F)
    roots = find_roots(F, (sa.value - 0.5, sa.value + 1.0, -3.0, 3.0))
    assert roots.certified and roots.count > 0
    np.testing.assert_allclose(np.max(roots.roots.real), sa.value, rtol=0, atol=1e-12)
    assert int(count_roots(F, (sa.value + 1e-6, 3.0, -0.25, 30.0))) == 0


@pytest.mark.parametrize("tau", [1.0, 14.0])
def test_distributed_form_of_the_lambert_family(tau: float) -> None:
    # s + a + b e^{-tau s} = s + (a + b) + s int_0^tau (-b) e^{-nu s} dnu
    a, b = 1.0, 0.5
    kernel = DistributedDelay(np.linspace(0.0, tau, 5), np.full(5, -b), [0.0, 1.0])
    F = QP([[a + b, 1.0]], [0.0], [kernel])
    sa = spectral_abscissa(F)
    assert sa.certified
    np.testing.assert_allclose(sa.value, lambert_rightmost(a, b, tau).real, rtol=0, atol=1e-9)


def test_degree_zero_distributed_delay() -> None:
    # 1 + int_0^1 e^{-nu s} dnu = (s + 1 - e^{-s}) / s: the roots of s + 1 - e^{-s} but s = 0, on W_{+-1}(e)
    F = QP([[1.0]], [0.0], [DistributedDelay([0.0, 1.0], [1.0, 1.0])])
    truth = complex(mpmath.lambertw(mpmath.e, 1)) - 1.0
    sa = spectral_abscissa(F)
    assert sa.certified
    np.testing.assert_allclose(sa.root, truth, rtol=0, atol=1e-9)


def test_delays_that_cancel_leave_the_polynomial_root() -> None:
    # s + e^{-s} + s int_0^1 e^{-nu s} dnu = s + 1: one root, although F has a delay
    F = QP([[0.0, 1.0], [1.0]], [0.0, 1.0], [DistributedDelay([0.0, 1.0], [1.0, 1.0], [0.0, 1.0])])
    sa = spectral_abscissa(F)
    assert sa.certified
    np.testing.assert_allclose(sa.value, -1.0, rtol=0, atol=1e-10)


def test_products_with_known_factors() -> None:
    lam = lambert_rightmost(1.0, 0.5, 14.0)
    F = _lambert(1.0, 0.5, 14.0) * QP([[3.0, 1.0]], [0.0])  # (s + 3) (s + 1 + 0.5 e^{-14 s})
    np.testing.assert_allclose(spectral_abscissa(F).value, lam.real, rtol=0, atol=1e-9)
    # a lightly damped pair at -0.005 +- 2i lies right of the Lambert pair at -0.0477
    G = _lambert(1.0, 0.5, 14.0) * QP([[4.0, 0.01, 1.0]], [0.0])
    sa = spectral_abscissa(G)
    assert sa.certified
    np.testing.assert_allclose(sa.root, complex(-0.005, np.sqrt(4.0 - 0.005**2)), rtol=0, atol=1e-10)


@pytest.mark.parametrize("c, h, p", [([1.0, 0.5, 0.2], 1.0, [2.0, 1.0]), ([1.0, -0.3, 0.4], 0.5, [-0.3, 1.0])])
def test_commensurate_delays_against_the_z_polynomial(c: list[float], h: float, p: list[float]) -> None:
    # p(s) D(e^{-h s}): the root of p and the chains of D, at Re s = -ln|z_i| / h
    F = QP([[ck * v for v in p] for ck in c], [k * h for k in range(len(c))])
    truth = max(-p[0] / p[1], chain_abscissa(z_roots(c), h))
    sa = spectral_abscissa(F)
    np.testing.assert_allclose(sa.value, truth, rtol=0, atol=1e-9)
    assert sa.upper_bound >= truth


# ---------------------------------------------------------------- polynomials: exact and by counts
_POLYNOMIALS = {
    "s + 3000": [3000.0, 1.0],  # was -inf
    "(s + 1)^6": [1.0, 6.0, 15.0, 20.0, 15.0, 6.0, 1.0],  # the window's edge landed on -1
    "prod (s - 1e-3 k)": list(np.polynomial.polynomial.polyfromroots(1e-3 * np.arange(6))),
    "cluster about -1": list(np.polynomial.polynomial.polyfromroots(-1.0 + 1e-3 * np.arange(6))),
    "cluster about 1, 1e-2 apart": list(np.polynomial.polynomial.polyfromroots(1.0 + 1e-2 * np.arange(6))),
    "mixed scales": list(np.polynomial.polynomial.polyfromroots([-5.0, -2e-3, 0.5 + 3j, 0.5 - 3j, 40.0]).real),
}


@pytest.mark.parametrize("name", sorted(_POLYNOMIALS))
def test_polynomial_abscissa(name: str, exact_route: str) -> None:
    coefs = [float(v) for v in _POLYNOMIALS[name]]
    truth = max(r.real for r in poly_roots(coefs))  # the float polynomial as given, exactly
    scale = 1.0 + abs(truth)
    sa = spectral_abscissa(QP([coefs], [0.0]))
    assert sa.certified and sa.root is not None
    assert sa.upper_bound >= truth - 1e-12 * scale
    if exact_route == "flint":
        np.testing.assert_allclose(sa.value, truth, rtol=0, atol=1e-12 * scale)
    else:
        # a cluster that floating point cannot split is one entry at its centroid (value <= truth), an
        # ill-conditioned root is polished only to its conditioning: both within the certified radius
        assert abs(sa.value - truth) <= sa.upper_bound - sa.value + 1e-12 * scale
        if name in ("s + 3000", "(s + 1)^6", "prod (s - 1e-3 k)", "mixed scales"):
            np.testing.assert_allclose(sa.value, truth, rtol=0, atol=1e-9 * scale)


@pytest.mark.parametrize("F", [QP([[2.0]], [1.5]), QP([[-3.0]], [0.0])], ids=["2 e^{-1.5 s}", "-3"])
def test_minus_infinity_only_without_roots(F: QuasiPolynomial, exact_route: str) -> None:
    sa = spectral_abscissa(F)
    assert sa.certified and sa.value == -np.inf and sa.root is None and sa.upper_bound == -np.inf


def test_work_bound_is_shared_and_named() -> None:
    with pytest.raises(CertificationError, match="max_evals"):
        spectral_abscissa(_lambert(1.0, 0.5, 14.0), max_evals=300)


# ---------------------------------------------------------------- clusters in find_roots
@pytest.mark.parametrize("center, spacing", [(-1.0, 1e-3), (-1.0, 1e-2), (1.0, 1e-2), (0.3, 1e-3)])
def test_clusters_are_reported_not_refused(center: float, spacing: float) -> None:
    coefs = [float(v) for v in np.polynomial.polynomial.polyfromroots(center + spacing * np.arange(6))]
    truth = np.array(poly_roots(coefs))
    rs = find_roots(QP([coefs], [0.0]), (center - 2.0, center + 2.0, -1.0, 1.0))
    assert rs.certified and rs.count == 6 and int(np.sum(rs.multiplicities)) == 6
    held = np.abs(truth[:, None] - rs.roots[None, :]) <= rs.radii[None, :] + 1e-12
    assert np.all(held.any(axis=1))  # every exact root lies in the disc of an entry
    assert np.all(held.sum(axis=0) >= rs.multiplicities)  # every entry holds its multiplicity
    assert np.max(rs.radii) < 0.2


def test_separable_roots_1e3_apart_are_separate() -> None:
    exact = 1e-3 * np.arange(6)
    rs = find_roots(QP([np.polynomial.polynomial.polyfromroots(exact)], [0.0]), (-1.0, 1.0, -1.0, 1.0))
    assert rs.certified and rs.multiplicities.tolist() == [1] * 6
    np.testing.assert_allclose(np.sort(rs.roots.real), exact, rtol=0, atol=1e-12)


# ---------------------------------------------------------------- no numpy error escapes
def test_tall_box_against_the_closed_form() -> None:
    # (s + 1)(1 + 0.5 e^{-s}): -1 and -ln 2 + i pi (2k + 1); 15 916 roots, contour moments overflowed
    F = QP([[1.0, 1.0], [0.5, 0.5]], [0.0, 1.0])
    rs = find_roots(F, (-1.0, 1.0, 0.0, 1e5))
    k = np.arange(int((1e5 / np.pi - 1) / 2) + 1)
    exact = np.concatenate([[-1.0], -np.log(2.0) + 1j * np.pi * (2 * k + 1)])
    assert rs.certified and rs.count == len(rs) == exact.size == 15916
    found = rs.roots[np.lexsort((rs.roots.real, rs.roots.imag))]
    exact = exact[np.lexsort((exact.real, exact.imag))]
    np.testing.assert_allclose(found, exact, rtol=0, atol=1e-9)
    assert np.all(np.abs(found - exact) <= rs.radii[np.lexsort((rs.roots.real, rs.roots.imag))])


def test_unresolved_chain_value_is_not_certified() -> None:
    # delays 1 and 1 + 3.1e-5: not commensurate within the degree bound, so c_D is only bracketed
    # ([-inf, ln 0.8]); the value is then the bracket's upper end, an upper bound, not certified
    F = QuasiPolynomial([[1.0, 1.0], [0.5, 0.5], [0.3, 0.3]], [0.0, 1.0, 1.0 + 1e-5 * np.pi])
    bound = F.principal_part().spectral_bound()
    assert not bound.exact and bound.lower < bound.upper - 1e-6
    r = spectral_abscissa(F)
    assert r.approached_at_infinity and not r.certified and r.value == bound.upper <= r.upper_bound
    # |0.5 e^{-s} + 0.3 e^{-(1 + eps) s}| <= 0.5 e^{-x} + 0.3 e^{-(1 + eps) x}: no zero of D right of
    # the x where that equals 1 (Hale's bound, by mpmath; ln 0.8 + 2.6e-6)
    eps = 1e-5 * mpmath.pi
    x = mpmath.findroot(lambda x: 0.5 * mpmath.exp(-x) + 0.3 * mpmath.exp(-(1 + eps) * x) - 1, -0.22)
    np.testing.assert_allclose(r.value, float(x), rtol=0, atol=1e-9)
    # delays 1 and pi: the bracket closes to 1.5e-10, and the value counts as resolved
    G = QuasiPolynomial([[1.0, 1.0], [0.5, 0.5], [0.3, 0.3]], [0.0, 1.0, np.pi])
    assert spectral_abscissa(G).certified
