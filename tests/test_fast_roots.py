"""The fast paths of root finding: closed-form distributed terms, their decay bound, chain and generator seeds."""

from __future__ import annotations

import mpmath
import numpy as np
from scipy.special import lambertw

from nrobust import DistributedDelay, QuasiPolynomial, find_roots
from nrobust.lti.statespace import StateSpaceTDS

# a kernel of three linear pieces with a jump at 0.5 (the closed form sums it away from s = 0)
NODES = [0.2, 0.5, 0.5, 1.0, 1.4]
VALUES = [1.0, -0.5, 0.7, 0.3, -0.2]


def _mp_integral(s: complex, k: int) -> complex:
    """``int nu^k N(nu) e^{-nu s} dnu`` of the piecewise linear kernel, mpmath at 40 digits.

    On a piece ``N = c0 + c1 nu``, so the integrand is ``c0 nu^k + c1 nu^(k+1)`` times
    ``e^{-nu s}``, whose antiderivative is ``-e^{-nu s} sum_i j!/(j-i)! nu^(j-i) / s^(i+1)``
    for ``nu^j`` (integration by parts, exact; 40 digits absorb the cancellation at small ``|s|``).
    """
    mpmath.mp.dps = 40
    z = mpmath.mpc(s.real, s.imag)

    def antiderivative(j: int, nu: mpmath.mpf) -> mpmath.mpc:
        terms = sum(mpmath.factorial(j) / mpmath.factorial(j - i) * nu ** (j - i) / z ** (i + 1) for i in range(j + 1))
        return -mpmath.exp(-nu * z) * terms

    total = mpmath.mpc(0)
    for (a, b), (va, vb) in zip([(0.2, 0.5), (0.5, 1.0), (1.0, 1.4)], [(1.0, -0.5), (0.7, 0.3), (0.3, -0.2)]):
        a_, b_ = mpmath.mpf(a), mpmath.mpf(b)
        c1 = (mpmath.mpf(vb) - mpmath.mpf(va)) / (b_ - a_)
        c0 = mpmath.mpf(va) - c1 * a_
        for c, j in ((c0, k), (c1, k + 1)):
            total += c * (antiderivative(j, b_) - antiderivative(j, a_))
    return complex(total)


def test_closed_form_and_series_against_mpmath() -> None:
    """Values and derivatives at small |s| (series) and large |s| (closed form) agree with mpmath."""
    N = DistributedDelay(NODES, VALUES)
    F = QuasiPolynomial([[0.0]], [0.0], [N])
    s = np.array([0.3 + 0.2j, -2.0 + 15.0j, 4.0 - 80.0j, -6.0 + 0.5j])
    want = np.array([_mp_integral(complex(z), 0) for z in s])
    dwant = -np.array([_mp_integral(complex(z), 1) for z in s])
    # relative to the scale int |N| e^{-nu Re s}, the closed form loses a few ulps to cancellation
    scale = np.abs(N.abs_moment(s.real))
    np.testing.assert_allclose(np.abs(F(s) - want) / scale, 0.0, atol=1e-14)
    np.testing.assert_allclose(np.abs(F.deriv_at(s) - dwant) / scale, 0.0, atol=1e-13)


def test_decay_bound_holds_and_decays() -> None:
    """|int nu^k N e^{-nu s}| <= decay_bound(Re s, |s|, k) on samples; the bound falls like 1/|s|."""
    N = DistributedDelay(NODES, VALUES)
    F = QuasiPolynomial([[0.0]], [0.0], [N])
    rng = np.random.default_rng(11)
    s = rng.uniform(-3.0, 2.0, 200) + 1j * rng.uniform(-200.0, 200.0, 200)
    for k in (0, 1):
        exact = np.array([abs(_mp_integral(complex(z), k)) for z in s[:20]])
        assert np.all(exact <= N.decay_bound(s[:20].real, np.abs(s[:20]), k))
    # the exact evaluation (checked against mpmath above): J_0 = F, J_1 = -F'
    assert np.all(np.abs(F(s)) <= N.decay_bound(s.real, np.abs(s), 0))
    assert np.all(np.abs(F.deriv_at(s)) <= N.decay_bound(s.real, np.abs(s), 1))
    far, near = N.decay_bound(0.0, 1000.0), N.decay_bound(0.0, 10.0)
    assert far < 0.02 * near < 0.02 * float(N.abs_moment(0.0)) * 10  # 1/|s| against a constant
    assert np.isinf(N.decay_bound(0.0, 0.0))


def test_native_distributed_delay_matches_its_product_with_s() -> None:
    """s + 1 - 2 (1 - e^{-s})/s natively and as s^2 + s - 2 + 2 e^{-s} (plus the root s = 0): 48 roots."""
    region = (-12.0, 2.0, -0.5, 300.0)
    F = QuasiPolynomial([[1.0, 1.0]], [0.0], [DistributedDelay([0.0, 1.0], [-2.0, -2.0])])
    G = QuasiPolynomial([[-2.0, 1.0, 1.0], [2.0]], [0.0, 1.0])
    native, product = find_roots(F, region), find_roots(G, region)
    assert native.certified and product.certified and native.count == 48 and product.count == 49
    others = product.roots[np.abs(product.roots) > 1e-8]
    gap = np.max(np.min(np.abs(native.roots[:, None] - others[None, :]), axis=1))
    assert gap < 1e-10  # both polished by Newton to rounding level (|F'| ~ 1 at these roots)


def test_generator_eigenvalues_against_lambert_w() -> None:
    """x' = -x(t - 1): roots s = W_k(-1); the collocation finds those with |Im s| < 10 to 1e-8, the
    pair at |Im s| = 14 (near the end of its resolution, 0.3 |Im s| + 12 points) to 1e-4: seeds."""
    sys = StateSpaceTDS([[[-1.0]]], [1.0])
    ev = sys.generator_eigenvalues(20.0)
    exact = np.array([complex(lambertw(-1.0, k)) for k in range(-3, 3)])
    dist = np.min(np.abs(exact[:, None] - ev[None, :]), axis=1)
    low = np.abs(exact.imag) < 10.0
    np.testing.assert_allclose(dist[low], 0.0, atol=1e-8)
    np.testing.assert_allclose(dist[~low], 0.0, atol=1e-4)


def test_roots_right_of_with_the_abscissa_bound() -> None:
    """The rectangle closed at x* = R(x*) holds every root right of the line: the count of a wider box agrees."""
    a0 = np.array([[-1.0, 0.5], [0.3, -2.0]])
    a1 = np.array([[-0.8, 0.2], [0.1, -0.5]]) * 3.0
    sys = StateSpaceTDS([a0, a1], [0.0, 1.0])
    right = sys.roots_right_of(-1.5)
    r = sys.root_radius(-1.5)
    assert right.certified and right.region[1] < r  # closed well before the radius
    wide = find_roots(sys.characteristic_matrix(), (-1.5, r + 1.0, -r - 1.0, r + 1.0))
    assert wide.certified and wide.count == right.count

    def rounded_order(z: np.ndarray) -> np.ndarray:  # a conjugate pair's order is not decided by its last bits
        return z[np.lexsort((np.round(z.imag, 8), np.round(z.real, 8)))]

    np.testing.assert_allclose(rounded_order(wide.roots), rounded_order(right.roots), atol=1e-9)
