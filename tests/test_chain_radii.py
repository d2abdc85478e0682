"""The chains of a principal part whose coefficients are known to proven radii, and its ``gamma_0``.

A loop whose gains are irrational (a general plant's ``rho q e^{sigma_0 tau}``) carries them as
doubles with proven radii (``QuasiPolynomial(..., radii=...)``). The chain bracket of its
proven spectral abscissa then holds ``c_D`` of every principal part in the balls
(:meth:`DifferenceOperator.proven_spectral_bound` with ``radii``). Oracles, sharing no code with
the package: closed forms evaluated in mpmath at 40 digits, ``mpmath.polyroots`` of
``P(z) = sum_k b_k z^{n_k}`` (``c_D = max -ln|z|`` for integer delays) and ``mpmath.findroot``
for the roots of perturbed functions, exact fractions for ``gamma_0``.
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import mpmath as mp
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import nrobust as nr
from nrobust.difference import DifferenceOperator
from nrobust.errors import ParameterError
from nrobust.hyperbolic import StateFeedback
from nrobust.hyperbolic.plants.general import GeneralHyperbolic2x2
from nrobust.quasipoly import QuasiPolynomial

flint = pytest.importorskip("flint")

DPS = 40
UNCOUPLED = dict(lam=0.3, mu=0.7, a=0.1, b=0.0, c=0.0, d=-0.2, q=0.6, rho=0.7, length=1.3)
K = -0.4


def _c_d(coefs) -> mp.mpf:
    """``max -ln|z|`` over the roots of ``sum_k coefs[k] z^k`` (delays ``0, 1, 2, ...``), at 40 digits."""
    with mp.workdps(DPS):
        roots = mp.polyroots([mp.mpf(c) for c in coefs], maxsteps=2000, extraprec=400, asc=True, error=True)[0]
        return max(-mp.log(abs(z)) for z in roots)


def _corners(coefs, radii):
    """Coefficients at the corners of the boxes of the balls and at their centre (mpmath numbers)."""
    with mp.workdps(DPS):
        centre = [mp.mpf(float(c)) for c in coefs]
        yield centre
        for signs in itertools.product((-1, 1), repeat=len(coefs)):
            yield [c + s * mp.mpf(float(r)) for c, s, r in zip(centre, signs, radii)]


def test_the_uncoupled_plant_has_a_tight_proven_abscissa():
    """``F(s; 0) = 1 - (rho + k) q e^{sigma_0 tau} e^{-tau s}``: every root has ``Re s = ln((rho + k) q w) / tau``.

    Its gain carries a proven radius (irrational): the bracket is the chain's, 1e-12 wide at most
    (it was the root boxes', 2e-9 wide, before the chains were proven for coefficient balls).
    """
    cert = nr.certify(GeneralHyperbolic2x2(**UNCOUPLED), StateFeedback(K), delta_max=0.5, rigorous=True, k_region=False)
    ab = cert.abscissa
    lo, hi = ab.value_bracket
    with mp.workdps(DPS):
        lam, mu, a, d, q, rho, L = (mp.mpf(UNCOUPLED[k]) for k in ("lam", "mu", "a", "d", "q", "rho", "length"))
        tau = L / lam + L / mu
        value = mp.log((rho + mp.mpf(K)) * q * mp.exp(L * (a / lam + d / mu))) / tau
        assert mp.mpf(lo) <= value <= mp.mpf(hi)
    assert ab.rigorous and hi - lo <= 1e-12
    assert lo <= ab.value <= hi


@settings(max_examples=25, deadline=None)
@given(
    coefs=st.lists(st.floats(-2.0, 2.0).filter(lambda x: abs(x) > 0.05), min_size=2, max_size=4),
    exponent=st.integers(-15, -8),
)
def test_the_chain_bracket_holds_every_operator_of_the_balls(coefs, exponent):
    """``1 + sum_k a_k e^{-k s}`` with each ``a_k`` known to ``10^e |a_k|``: the proven bracket holds ``c_D`` of
    the centre and of every corner of the balls (mpmath polyroots, 40 digits)."""
    coefs = [1.0, *coefs]
    radii = [0.0] + [10.0**exponent * abs(c) for c in coefs[1:]]
    D = DifferenceOperator(coefs, np.arange(len(coefs), dtype=float))
    sb = D.proven_spectral_bound(radii=radii)
    assert sb.proven
    for corner in _corners(coefs, radii):
        assert mp.mpf(sb.lower) <= _c_d(corner) <= mp.mpf(sb.upper)


def test_the_chain_bracket_is_as_wide_as_the_balls():
    """With radii, the bracket of a simple chain is about ``|dc_D/da| r`` wide, not the 1e-9 of a root box:
    ``c_D = ln|a| / tau`` of ``1 + a e^{-tau s}`` moves by ``r / (|a| tau)`` within ``a +- r``."""
    a, tau, r = -0.19149498356507810, 6.190476190476244, 2.7e-17
    sb = DifferenceOperator([1.0, a], [0.0, tau]).proven_spectral_bound(radii=[0.0, r])
    with mp.workdps(DPS):
        for x in (mp.mpf(a) - mp.mpf(r), mp.mpf(a) + mp.mpf(r)):
            assert mp.mpf(sb.lower) <= mp.log(abs(x)) / mp.mpf(tau) <= mp.mpf(sb.upper)
    assert not sb.exact and sb.upper - sb.lower <= 1e-15  # a bracket of the family, 1e-15 wide


def test_a_multiple_root_falls_back_to_the_strong_bound():
    """``(1 - e^{-s}/2)^2``: a double chain cannot be isolated for every operator of the balls (a ball splits
    it); the bracket is then ``[a proven zero, C_D]``, which holds ``c_D = -ln 2`` of the centre."""
    D = DifferenceOperator([1.0, -1.0, 0.25], [0.0, 1.0, 2.0])
    sb = D.proven_spectral_bound(radii=[0.0, 1e-15, 0.0])
    assert not sb.exact and sb.lower <= -np.log(2.0) <= sb.upper


def test_the_radii_are_checked():
    D = DifferenceOperator([1.0, 0.5], [0.0, 1.0])
    with pytest.raises(ParameterError, match="radii"):
        D.proven_spectral_bound(radii=[0.0])
    with pytest.raises(ParameterError, match="radii"):
        D.proven_spectral_bound(radii=[0.0, -1.0])
    with pytest.raises(nr.errors.CertificationError, match="a_0"):
        DifferenceOperator([1e-3, 0.5], [0.0, 1.0]).proven_spectral_bound(radii=[1e-2, 0.0])


def test_the_principal_radii():
    F = QuasiPolynomial([[0.5, 1.0], [0.3, 0.7]], [0.0, 1.0], radii=[[0.0, 1e-12], [1e-11, 2e-12]])
    np.testing.assert_array_equal(F.principal_radii(), [1e-12, 2e-12])
    np.testing.assert_array_equal(QuasiPolynomial([[0.5, 1.0], [0.3, 0.7]], [0.0, 1.0]).principal_radii(), [0.0, 0.0])
    # a ball about a stored 0 in the principal degree: a term the principal part does not have
    G = QuasiPolynomial([[0.5, 1.0], [0.3, 0.0]], [0.0, 1.0], radii=[[0.0, 0.0], [0.0, 1e-12]])
    assert G.principal_radii() is None


def _neutral(a, b, c):
    def F(s):
        return s + b + (a * s + c) * mp.exp(-s)

    return F


@settings(max_examples=8, deadline=None)
@given(
    a=st.floats(-0.9, 0.9).filter(lambda x: abs(x) > 0.05),
    b=st.floats(0.1, 3.0),
    c=st.floats(-3.0, 3.0).filter(lambda x: abs(x) > 0.05),
    exponent=st.integers(-14, -9),
)
@example(a=-0.2421875, b=0.53125, c=-2.984375, exponent=-10)  # a real rightmost root, the oracle's tolerance
def test_the_proven_abscissa_holds_every_function_of_the_balls(a, b, c, exponent):
    """``s + b + (a s + c) e^{-s}`` with ``a, b, c`` known to ``10^e`` relative: the proven bracket holds the
    abscissa ``max(ln|a|, Re z)`` of the centre and of each corner of the balls, ``z`` its rightmost root
    (mpmath findroot from the proven root, 40 digits; the chains' ``c_D = ln|a|`` in closed form)."""
    radii = [abs(b) * 10.0**exponent, abs(c) * 10.0**exponent, abs(a) * 10.0**exponent]
    F = QuasiPolynomial([[b, 1.0], [c, a]], [0.0, 1.0], radii=[[radii[0], 0.0], [radii[1], radii[2]]])
    ab = nr.spectral_abscissa(F, rigorous=True)
    lo, hi = ab.value_bracket
    assert lo <= ab.value <= hi
    for bb, cc, aa in _corners([b, c, a], radii):
        with mp.workdps(DPS):
            value = mp.log(abs(aa))
            if ab.root is not None:
                # findroot's check at 10^-DPS on |F|^2 (its default, about 10^-2 DPS, failed by rounding at a real
                # root with |c| ~ 3): the root to about 10^-20, far inside brackets at least 1e-13 wide
                root = mp.findroot(_neutral(aa, bb, cc), mp.mpc(ab.root), tol=mp.mpf(10) ** -DPS)
                value = max(value, root.real)
            assert mp.mpf(lo) <= value <= mp.mpf(hi)


@settings(max_examples=8, deadline=None)
@given(
    coefs=st.lists(st.floats(-0.6, 0.6).filter(lambda x: abs(x) > 0.05), min_size=1, max_size=3),
    exponent=st.integers(-15, -10),
)
def test_a_difference_operator_with_radii_has_a_tight_proven_abscissa(coefs, exponent):
    """``1 + sum_k a_k e^{-k s}`` as a QuasiPolynomial with radii: its zeros are the chains, its proven bracket
    theirs, holding ``c_D`` of the centre and the corners (mpmath polyroots), about the width the balls give."""
    coefs = [1.0, *coefs]
    radii = [0.0] + [10.0**exponent * abs(x) for x in coefs[1:]]
    F = QuasiPolynomial([[x] for x in coefs], np.arange(len(coefs), dtype=float), radii=[[r] for r in radii])
    ab = nr.spectral_abscissa(F, rigorous=True)
    lo, hi = ab.value_bracket
    for corner in _corners(coefs, radii):
        assert mp.mpf(lo) <= _c_d(corner) <= mp.mpf(hi)
    # the width the balls give: a root z of P moves by at most deg sum_k r_k |z|^k / |P'(z)| (the discs of the
    # proof), so -ln|z| by that over |z|; doubled, with 1e-14 for the rounding of the ends
    with mp.workdps(DPS):
        roots = mp.polyroots([mp.mpf(x) for x in coefs], maxsteps=2000, extraprec=400, asc=True, error=True)[0]
        deg = len(coefs) - 1
        slope = [mp.fsum(k * mp.mpf(x) * z ** (k - 1) for k, x in enumerate(coefs) if k) for z in roots]
        moves = [deg * mp.fsum(r * abs(z) ** k for k, r in enumerate(radii)) / abs(p) for z, p in zip(roots, slope)]
        width = (
            max(2 * m / (abs(z) - m) for z, m in zip(roots, moves) if m < abs(z) / 2)
            if min(abs(z) - 2 * m for z, m in zip(roots, moves)) > 0
            else mp.inf
        )
    assert hi - lo <= 1.01 * float(width) + 1e-14


def test_gamma_0_is_proven_with_the_radii():
    """``gamma_0 = sum_{k>=1} |b_k| / |b_0|`` over the balls: the bracket holds the extreme values, in fractions."""
    coefs, radii = [1.0, -0.3, 0.1], [1e-12, 2e-12, 0.0]
    lo, hi = DifferenceOperator(coefs, [0.0, 1.0, 2.5]).proven_gamma_0(radii=radii)
    a0, a1, a2 = (Fraction(x) for x in coefs)
    r0, r1 = Fraction(radii[0]), Fraction(radii[1])
    assert Fraction(lo) <= (abs(a1) - r1 + abs(a2)) / (a0 + r0)
    assert (abs(a1) + r1 + abs(a2)) / (a0 - r0) <= Fraction(hi)
    assert hi - lo <= 1e-11


def test_the_certificate_proves_gamma_0_of_eq_54(tmp_path):
    """U_BS2(K) on a plant whose ``rho q = 0.3 * 0.1`` and ``K q = 0.1 * 0.1`` are not doubles: the proven ball of
    ``gamma_0`` holds ``|rho q| + |K q|`` (eq. (54) asks it below 1) at ``delta > 0`` and ``|(rho - K) q|`` at
    ``delta = 0``, in exact fractions of the user's numbers; the report prints it with its accuracy."""
    from nrobust.hyperbolic import ReflectionController, TransportSystem
    from nrobust.reports.report import write_report

    q, rho, k = 0.1, 0.3, 0.1
    cert = nr.certify(TransportSystem(1.0, 1.0, q, rho), ReflectionController(k), delta_max=0.5, rigorous=True)
    Q, R, Kf = Fraction(q), Fraction(rho), Fraction(k)
    expected = ((cert.principal_nominal, abs((R - Kf) * Q)), (cert.principal_delayed, abs(R * Q) + abs(Kf * Q)))
    for part, exact in expected:
        lo, hi = part.gamma_0_ball
        assert Fraction(lo) <= exact <= Fraction(hi)
        assert hi - lo <= 1e-16 and part.strongly_stable
        assert abs(Fraction(part.gamma_0) - exact) <= Fraction(part.gamma_0_accuracy)
    md = write_report(cert, tmp_path).markdown.read_text()
    row = next(line for line in md.splitlines() if line.startswith("| gamma_0 of the difference operator, delta = 0.5"))
    assert cert.principal_delayed.gamma_0_text in row and "+- " in row and "(proven)" in row
    # without proofs: no ball, the float value to 6 digits
    plain = nr.certify(TransportSystem(1.0, 1.0, q, rho), ReflectionController(k), delta_max=0.5, k_region=False)
    assert plain.principal_delayed.gamma_0_ball is None and plain.principal_delayed.gamma_0_text == "0.04"


def test_the_coupled_plant_has_a_tight_proven_abscissa():
    """The coupled general plant under ``StateFeedback(-0.4)``: the rightmost root's proven box is contracted by
    Krawczyk's operator, so the bracket is 1e-13 wide at most (measured 6.7e-15; 4.2e-11 before, the box of the
    proof) and holds the real part of the PDE's root (``expm`` of the Laplace-domain system at 40 digits)."""
    from test_general_plant_as_given import COUPLED, _factors

    cert = nr.certify(GeneralHyperbolic2x2(**COUPLED), StateFeedback(K), delta_max=1.0, rigorous=True, k_region=False)
    ab = cert.abscissa
    lo, hi = ab.value_bracket
    assert not ab.approached_at_infinity and hi - lo <= 1e-13
    with mp.workdps(DPS):
        root = mp.findroot(lambda s: sum(_factors(COUPLED, K, s)), mp.mpc(ab.root))
        assert mp.mpf(lo) <= root.real <= mp.mpf(hi)


def test_a_bracket_of_a_family_is_not_called_exact():
    """Commensurate delays with radii: the bracket holds c_D of every operator of the balls, so it is a
    bracket (its repr gives both ends), not one exact value; without radii it stays exact."""
    D = DifferenceOperator([1.0, 0.5, 0.2], [1.0, 2.0, 3.5])
    family = D.proven_spectral_bound(radii=[0.0, 0.01, 0.01])
    assert not family.exact and family.step is None and family.lower < family.upper
    assert "bracket" in repr(family)
    assert D.proven_spectral_bound().exact
