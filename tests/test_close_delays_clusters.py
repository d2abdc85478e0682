"""Delays close but not equal, and clusters of roots, against mpmath oracles.

Close delays: ``1`` and ``1 + 1e-12`` agree to the commensurability tolerance but are two delays;
the roots of ``F`` near ``Im s ~ 2 pi / 1e-12`` follow the sum over phases of their terms, not
either term alone, so no lattice step may hold both. The oracles find those roots by
``mpmath.findroot`` at 40 digits from the frequency where the phases align.

Clusters: qpmr's ``mazanti2021multiplicity`` example (Mazanti, Boussaada and Niculescu,
"Multiplicity-induced-dominancy for delay-differential equations of retarded type", J.
Differential Equations 286, 2021, Proposition 6.1) is built to have a six-fold root at
``s0 = -6.021035``; its stored (rounded) coefficients split it into six roots up to 0.024 apart.
The oracle finds the six by Newton's method on ``F`` deflated by the roots already found, at
60 digits, with the stored doubles taken as exact numbers.
"""

from __future__ import annotations

import sys

import mpmath
import numpy as np
import pytest

from nrobust import QuasiPolynomial
from nrobust.difference import DifferenceOperator
from nrobust.hyperbolic import FiniteTimeController, TransportSystem, characteristic
from nrobust.roots import spectral_abscissa

pytest.importorskip("flint")


# ---------------------------------------------------------------- (A) close delays
GAP = 1e-12
A = 0.5 * (1 + 1e-6)


def _close_pair() -> QuasiPolynomial:
    """``1 + s + a s e^{-s} + a s e^{-(1 + 1e-12) s}``: its principal part ``1 + a e^{-s} + a e^{-(1+1e-12) s}``."""
    return QuasiPolynomial([[1.0, 1.0], [0.0, A], [0.0, A]], [0.0, 1.0, 1.0 + GAP])


def _close_pair_root() -> mpmath.mpc:
    """The root of the close-pair ``F`` at ``Im s ~ 2 pi / gap``, where ``e^{-s} ~ -1`` and ``e^{-gap s} ~ 1``."""
    mpmath.mp.dps = 40
    t1 = mpmath.mpf(1.0 + GAP)  # the stored double, exactly
    a = mpmath.mpf(A)
    gap = t1 - 1
    w = (2 * mpmath.floor(1 / gap) + 1) * mpmath.pi  # an odd multiple of pi near 2 pi / gap

    def F(s: mpmath.mpc) -> mpmath.mpc:
        return 1 + s + a * s * mpmath.exp(-s) + a * s * mpmath.exp(-t1 * s)

    root = mpmath.findroot(F, mpmath.mpc(1e-6, w), tol=mpmath.mpf(10) ** -30)
    assert abs(F(root)) < 1e-25 * abs(root) and abs(root.imag - 2 * mpmath.pi / gap) < 10
    return root


def test_close_delays_never_share_a_lattice_step() -> None:
    # the delays 1 and 1 + 1e-12 fell on one step and one coefficient overwrote the other
    # (c_D = -ln 2, "exact"); the merged operator 1 + e^{-s} has c_D = 0 = C_D
    D = DifferenceOperator([1, 0.5, 0.5], [0, 1, 1 + GAP])
    assert D.commensurate_step() is None
    bound = D.spectral_bound()
    assert not bound.exact
    assert bound.lower <= 0.0 <= bound.upper + 1e-15
    np.testing.assert_allclose(bound.upper, 0.0, rtol=0, atol=1e-12)


@pytest.mark.parametrize("rigorous", [False, True], ids=["float", "rigorous"])
def test_close_delays_abscissa_is_not_below_a_root(rigorous: bool) -> None:
    root = _close_pair_root()  # about 1e-6 + 6.28e12 i
    sa = spectral_abscissa(_close_pair(), rigorous=rigorous)
    # the value, within its stated accuracy, is not below a root (it was -5.2e-5, certified); the
    # float chain value may fall an ulp or two below this root (1.0e-16 on some libm builds), which its
    # accuracy (3e-14: the chain's floating-point error estimate) covers
    assert sa.value + sa.accuracy >= float(root.real) and sa.upper_bound >= float(root.real)
    assert sa.accuracy < 1e-13 or rigorous
    # the chains are those of 1 + 2a e^{-s} (c_D = ln 2a) at low frequency, of the sum over phases above
    np.testing.assert_allclose(sa.value, float(mpmath.log(2 * mpmath.mpf(A))), rtol=1e-6)
    if rigorous:
        assert sa.value_bracket is not None
        lo, hi = sa.value_bracket
        assert lo <= sa.value <= hi and lo <= float(root.real) <= hi


@pytest.mark.parametrize("rigorous", [False, True], ids=["float", "rigorous"])
def test_close_delays_transport_loop(rigorous: bool) -> None:
    # U_BS with a loop delay 1e-11: D = 1 - 0.85 e^{-2 s} + 0.85 e^{-(2 + 1e-11) s}; the two terms
    # cancel at low frequency and add up near Im s = pi / 1e-11, where a root sits at Re s = 0.2653
    F = characteristic(TransportSystem(1, 1, q=1, rho=0.85), FiniteTimeController(), 1e-11)
    mpmath.mp.dps = 40
    t1 = mpmath.mpf(2.0 + 1e-11)
    k = mpmath.mpf(0.85)
    w = mpmath.floor(1 / (t1 - 2)) * mpmath.pi  # e^{-2 i w} = 1 and e^{-(t1 - 2) i w} ~ -1

    def G(s: mpmath.mpc) -> mpmath.mpc:
        return 1 - k * mpmath.exp(-2 * s) + k * mpmath.exp(-t1 * s)

    root = mpmath.findroot(G, mpmath.mpc(0.2653, w), tol=mpmath.mpf(10) ** -30)
    assert abs(G(root)) < 1e-20
    sa = spectral_abscissa(F, rigorous=rigorous)
    assert sa.value >= float(root.real) and sa.upper_bound >= float(root.real)
    assert not sa.certified  # C_D bounds the supremum; no zero near it is proven at Im s ~ 3e11
    if rigorous:
        assert sa.value_bracket is not None
        lo, hi = sa.value_bracket
        assert lo <= sa.value <= hi and lo <= float(root.real) <= hi


# ---------------------------------------------------------------- (B) clusters
def _mazanti() -> tuple[list[list[float]], float]:
    """qpmr's ``mazanti2021multiplicity()`` (kappa = 1.964, k = -0.67036, tau0 = tau1 = 0.33), eqs. (6.10a-f)."""
    kappa, k, tau = 1.964, -0.67036, 0.33 + 0.33
    r0 = -3.0 - 9 ** (1 / 3.0) + 3 ** (1 / 3.0)
    s0 = r0 / tau - 1 / kappa
    omega = (-kappa * (s0**3 + 9.0 / tau * s0**2 + 36.0 / tau / tau * s0 + 60 / tau**3)) ** 0.5
    xi = -3.0 * s0 / 2 / omega - 9.0 / 2 / omega / tau - 1 / 2 / omega / kappa
    e = np.exp(s0 * tau)
    beta0 = -(3 * kappa * (s0**2 * tau**2 - 8 * s0 * tau + 20) * e) / (k * omega**2 * tau**3)
    beta1 = (6 * kappa * (s0 * tau - 4) * e) / (k * omega**2 * tau**2)
    beta2 = (-3 * kappa * e) / (k * omega**2 * tau)
    coefs = [
        [omega**2 / kappa, omega**2 + 2 * omega * xi / kappa, 2 * omega * xi + 1 / kappa, 1.0],
        [-beta0 * k * omega**2 / kappa, -beta1 * k * omega**2 / kappa, -beta2 * k * omega**2 / kappa],
    ]
    return coefs, tau


def _mazanti_cluster() -> list[mpmath.mpc]:
    """The six roots of the stored ``F`` near ``s0``: Newton on ``F / prod (s - r_j)`` at 60 digits."""
    coefs, tau = _mazanti()
    mpmath.mp.dps = 60
    p = [[mpmath.mpf(c) for c in row] for row in coefs]
    t = mpmath.mpf(tau)

    def F(s: mpmath.mpc) -> mpmath.mpc:
        lead = sum(c * s**j for j, c in enumerate(p[0]))
        return lead + sum(c * s**j for j, c in enumerate(p[1])) * mpmath.exp(-t * s)

    found: list[mpmath.mpc] = []
    for j in range(6):
        seed = mpmath.mpc(-6.021, 0) + 0.03 * mpmath.expjpi(mpmath.mpf(2 * j + 1) / 6)

        def deflated(s: mpmath.mpc) -> mpmath.mpc:
            out = F(s)
            for r in found:
                out /= s - r
            return out

        r = mpmath.findroot(deflated, seed, tol=mpmath.mpf(10) ** -50)
        r = mpmath.findroot(F, r, tol=mpmath.mpf(10) ** -50)  # polished on F itself
        assert abs(F(r)) < 1e-45 and abs(r + 6.021035) < 0.05 and all(abs(r - q) > 1e-3 for q in found)
        found.append(r)
    return found


@pytest.fixture(scope="module")
def cluster() -> list[mpmath.mpc]:
    return _mazanti_cluster()


@pytest.mark.parametrize("rigorous", [False, True], ids=["float", "rigorous"])
def test_cluster_abscissa_is_the_rightmost_root_not_the_centroid(rigorous: bool, cluster: list[mpmath.mpc]) -> None:
    right = max(cluster, key=lambda r: (r.real, r.imag))  # -6.0000823 + 0.0120941 i
    truth = float(right.real)
    np.testing.assert_allclose(truth, -6.0000823, atol=1e-7)  # the centroid is at -6.021035
    coefs, tau = _mazanti()
    sa = spectral_abscissa(QuasiPolynomial(coefs, [0.0, tau]), rigorous=rigorous)
    assert sa.certified and sa.root is not None
    np.testing.assert_allclose(sa.value, truth, rtol=0, atol=1e-12)
    np.testing.assert_allclose(abs(sa.root.imag), abs(float(right.imag)), rtol=0, atol=1e-12)
    assert truth <= sa.upper_bound <= truth + 1e-9
    if rigorous:
        assert sa.root_box is not None and sa.value_bracket is not None
        x0, x1, y0, y1 = sa.root_box
        assert x0 <= truth <= x1 and y0 <= abs(float(right.imag)) <= y1
        lo, hi = sa.value_bracket
        assert lo <= sa.value <= hi and lo <= truth <= hi and hi - lo < 1e-9


def test_cluster_without_flint_is_a_bracket(cluster: list[mpmath.mpc], monkeypatch: pytest.MonkeyPatch) -> None:
    # floating point alone cannot separate the six roots: the centroid is a lower end only,
    # and the certified upper bound covers the rightmost root
    monkeypatch.setitem(sys.modules, "flint", None)
    truth = max(float(r.real) for r in cluster)
    coefs, tau = _mazanti()
    sa = spectral_abscissa(QuasiPolynomial(coefs, [0.0, tau]))
    assert sa.value <= truth <= sa.upper_bound


def test_principal_part_beyond_double_range_is_refused_by_name() -> None:
    """Coefficients 1 and 1e-310 (a reflection of 1e-310): the companion matrix overflowed and
    numpy's ``LinAlgError`` escaped from ``spectral_abscissa``; now a CertificationError says why."""
    from nrobust.difference import DifferenceOperator
    from nrobust.errors import CertificationError

    with pytest.raises(CertificationError, match="beyond double precision"):
        DifferenceOperator([1.0, 1e-310], [0.0, 3.0]).chains()
