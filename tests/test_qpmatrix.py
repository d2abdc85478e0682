"""Matrices of quasi-polynomials: det M evaluated, bounded and counted without expansion."""

from __future__ import annotations

import itertools

import mpmath
import numpy as np
import pytest

from nrobust import DistributedDelay, ParameterError, QuasiPolynomial
from nrobust.qpmatrix import CharacteristicFunction, QuasiPolynomialMatrix
from nrobust.roots import count_roots, find_roots, spectral_abscissa

S = QuasiPolynomial([[0.0, 1.0]], [0.0])
# retarded and neutral scalar entries, one with a distributed (kernel) term
A = QuasiPolynomial([[1.0, 1.0], [0.5]], [0.0, 1.0])  # s + 1 + 0.5 e^{-s}
B = QuasiPolynomial([[2.0, 1.0], [-0.3]], [0.0, 0.7])  # s + 2 - 0.3 e^{-0.7 s}
KERNEL = DistributedDelay([0.0, 0.5, 1.0], [0.4, -0.3, 0.2])
C = QuasiPolynomial([[0.5, 1.0], [0.0, -0.4]], [0.0, 1.0], [KERNEL])  # s + 0.5 - 0.4 s e^{-s} + int N e^{-nu s}
OFF = QuasiPolynomial([[0.0, 0.2]], [0.5])
REGION = (-6.0, 3.0, -25.0, 25.0)


def _sorted(z: np.ndarray) -> np.ndarray:
    return z[np.lexsort((np.round(z.real, 8), np.round(z.imag, 8)))]


def test_protocol_members() -> None:
    M = QuasiPolynomialMatrix([[A, OFF], [0.0, B]])
    assert isinstance(M, CharacteristicFunction) and isinstance(A, CharacteristicFunction)
    assert M.size == 2 and M.is_real and M.max_delay == 1.0
    assert M == QuasiPolynomialMatrix([[A, OFF], [0, B]]) and hash(M) == hash(QuasiPolynomialMatrix([[A, OFF], [0, B]]))


@pytest.mark.parametrize("upper", [0.0, OFF, QuasiPolynomial([[0.1]], [0.3], [KERNEL])])
def test_triangular_is_product_of_scalars(upper: object) -> None:
    """Diagonal and triangular matrices: counts add, roots are the union of the scalar roots."""
    M = QuasiPolynomialMatrix([[A, upper], [0.0, C]])
    s = np.array([0.3 + 2j, -1.0 + 7j, 2.0 - 11j])
    np.testing.assert_allclose(M(s), A(s) * C(s), rtol=1e-13)
    np.testing.assert_allclose(M.deriv_at(s), A.deriv_at(s) * C(s) + A(s) * C.deriv_at(s), rtol=1e-12)
    assert int(count_roots(M, REGION)) == int(count_roots(A, REGION)) + int(count_roots(C, REGION))
    roots = find_roots(M, REGION)
    ra, rc = find_roots(A, REGION), find_roots(C, REGION)
    assert roots.certified and roots.count == ra.count + rc.count
    # Newton polish on det M vs on the scalars: both at rounding level of the roots
    np.testing.assert_allclose(_sorted(roots.roots), _sorted(np.concatenate([ra.roots, rc.roots])), atol=1e-9)


def test_diagonal_three_by_three() -> None:
    M = QuasiPolynomialMatrix.diagonal([A, B, C])
    total = sum(int(count_roots(f, REGION)) for f in (A, B, C))
    assert int(count_roots(M, REGION)) == total
    # the abscissa in a region is the largest scalar one
    ab = spectral_abscissa(M, REGION)
    scalar = max(spectral_abscissa(f, REGION).value for f in (A, B, C))
    np.testing.assert_allclose(ab.value, scalar, atol=1e-10)


def test_one_by_one_is_the_scalar() -> None:
    M = QuasiPolynomialMatrix([[C]])
    a, b = find_roots(M, REGION), find_roots(C, REGION)
    assert a.count == b.count
    np.testing.assert_allclose(_sorted(a.roots), _sorted(b.roots), atol=1e-11)


def test_bounds_hold_on_segments() -> None:
    """deriv_bound and second_deriv_bound dominate |det'| and |det''| sampled on segments."""
    rng = np.random.default_rng(5)
    M = QuasiPolynomialMatrix(
        [[A, OFF + QuasiPolynomial([[0.1]], [0.0], [KERNEL])], [QuasiPolynomial([[0.3]], [0.2]), C]]
    )
    a = rng.uniform(-3, 2, 200) + 1j * rng.uniform(-30, 30, 200)
    b = a + 0.5 * (rng.uniform(-1, 1, 200) + 1j * rng.uniform(-1, 1, 200))
    t = np.linspace(0, 1, 41)
    pts = a[:, None] + (b - a)[:, None] * t[None, :]
    d1 = np.max(np.abs(M.deriv_at(pts)), axis=1)
    h = 1e-5
    d2 = np.max(np.abs((M.deriv_at(pts + h) - M.deriv_at(pts - h)) / (2 * h)), axis=1)
    assert np.all(d1 <= M.deriv_bound(a, b))
    assert np.all(d2 <= M.derivative().deriv_bound(a, b))
    # the bounds are not vacuous: within two orders of magnitude of the sampled maxima
    assert np.median(M.deriv_bound(a, b) / d1) < 100


def _mp_det(s: mpmath.mpc) -> mpmath.mpc:
    """det [[s + 1 + 0.5 e^{-s}, 0.2 s e^{-0.5 s}], [0.3 e^{-0.2 s}, s + 2 - 0.3 e^{-0.7 s}]], by hand."""
    a = s + 1 + 0.5 * mpmath.exp(-s)
    b = s + 2 - 0.3 * mpmath.exp(-0.7 * s)
    return a * b - 0.06 * s * mpmath.exp(-0.7 * s)


def _mp_det_prime(s: mpmath.mpc) -> mpmath.mpc:
    a = s + 1 + 0.5 * mpmath.exp(-s)
    b = s + 2 - 0.3 * mpmath.exp(-0.7 * s)
    da = 1 - 0.5 * mpmath.exp(-s)
    db = 1 + 0.21 * mpmath.exp(-0.7 * s)
    return da * b + a * db - 0.06 * mpmath.exp(-0.7 * s) + 0.042 * s * mpmath.exp(-0.7 * s)


@pytest.mark.slow
def test_coupled_point_delays_against_mpmath() -> None:
    """A coupled 2x2 point-delay matrix: certified roots match mpmath on the determinant
    expanded by hand, and the count matches the argument principle integrated by mpmath."""
    M = QuasiPolynomialMatrix([[A, OFF], [QuasiPolynomial([[0.3]], [0.2]), B]])
    region = (-4.0, 2.0, -15.0, 15.0)
    roots = find_roots(M, region)
    assert roots.certified
    mpmath.mp.dps = 20
    try:
        for z in roots.roots:
            exact = complex(mpmath.findroot(_mp_det, mpmath.mpc(z.real, z.imag), df=_mp_det_prime))
            assert abs(exact - z) < 1e-10
        x0, x1, y0, y1 = region
        corners = [mpmath.mpc(x0, y0), mpmath.mpc(x1, y0), mpmath.mpc(x1, y1), mpmath.mpc(x0, y1), mpmath.mpc(x0, y0)]

        def log_derivative(s: mpmath.mpc) -> mpmath.mpc:
            return _mp_det_prime(s) / _mp_det(s)

        integral = sum(
            mpmath.quad(log_derivative, [p + (q - p) * k / 8 for k in range(9)]) for p, q in itertools.pairwise(corners)
        )
        winding = complex(integral / (2j * mpmath.pi))
    finally:
        mpmath.mp.dps = 15
    assert abs(winding.imag) < 1e-6 and round(winding.real) == roots.count
    # and the expanded scalar form gives the same roots
    np.testing.assert_allclose(_sorted(find_roots(M.expand(), region).roots), _sorted(roots.roots), atol=1e-10)


def test_principal_part_of_a_neutral_matrix() -> None:
    """diag(s (1 - 0.5 e^{-s}) + 1, s (1 + 0.25 e^{-2 s}) + 2): the principal part is the product."""
    n1 = QuasiPolynomial([[1.0, 1.0], [0.0, -0.5]], [0.0, 1.0])
    n2 = QuasiPolynomial([[2.0, 1.0], [0.0, 0.25]], [0.0, 2.0])
    M = QuasiPolynomialMatrix([[n1, OFF], [0.0, n2]])
    D = M.principal_part()
    assert M.kind == "neutral"
    np.testing.assert_allclose(D.coefs, [1.0, -0.5, 0.25, -0.125])
    np.testing.assert_allclose(D.delays, [0.0, 1.0, 2.0, 3.0])
    # the abscissa in a band is the largest scalar one (chains at ln(0.5) and ln(0.5)/2)
    band = (-1.0, 1.0, -0.25, 60.0)
    np.testing.assert_allclose(
        spectral_abscissa(M, band).value, max(spectral_abscissa(f, band).value for f in (n1, n2)), atol=1e-9
    )


def test_bad_input() -> None:
    with pytest.raises(ParameterError, match="entries"):
        QuasiPolynomialMatrix([[A, B]])
    with pytest.raises(ParameterError, match="entries"):
        QuasiPolynomialMatrix([[A, "x"], [B, A]])
    with pytest.raises(ParameterError, match="entries"):
        QuasiPolynomialMatrix([])
    with pytest.raises(ParameterError, match="region"):
        spectral_abscissa(QuasiPolynomialMatrix([[A]]))
    with pytest.raises(ParameterError, match="F"):
        count_roots(np.eye(2), REGION)  # type: ignore[arg-type]
    # two kernels in one product cannot be expanded
    with pytest.raises(ParameterError, match="entries"):
        QuasiPolynomialMatrix([[C, 0.0], [0.0, C]]).expand()
    # a distributed term of top degree could enter the principal part: refused
    top = QuasiPolynomial([[1.0]], [0.0], [DistributedDelay([0.0, 1.0], [1.0, 1.0], poly=(0.0, 1.0))])
    with pytest.raises(ParameterError, match="principal part"):
        QuasiPolynomialMatrix([[top, 0.0], [0.0, 1.0]]).principal_part()
