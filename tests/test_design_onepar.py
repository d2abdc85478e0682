"""The shortcuts of the one-parameter design engine (nrobust.design.gain) against the long way round.

Each shortcut must give what the long way gives: the nominal loop with a kernel shared by ``A`` and
``B`` written once is the same function; the radius of the nominal count is
``root_free_region``'s, errors included; the decay rates left out of the sampled search are smaller
than a computed one (closed-form rates: ``s^2 + K s + 1``, ``s + 1 + K``, and ``-ln((rho - K) q) / tau``
of U_BS2(K) on the paper's plant, Lemma 3); the filter's factors are those of ``FilteredLoop``.
"""

from __future__ import annotations

import numpy as np
import pytest

from nrobust import Hyperbolic2x2, QuasiPolynomial
from nrobust.bounds import root_free_region
from nrobust.design import AffineLoop
from nrobust.design.gain import _Family, _merged, _sampled_abscissas, _zero_free_radius
from nrobust.errors import ParameterError
from nrobust.hyperbolic.analyses.filter_design import filtered_loop
from nrobust.hyperbolic.analyses.kregion import u_bs2_loop
from nrobust.roots import spectral_abscissa

RHO, Q, TAU = 0.85, 1.0, 2.0
PLANT = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, RHO)
ZERO = QuasiPolynomial([[0.0]], [0.0])


@pytest.fixture(scope="module")
def pole() -> tuple[object, _Family]:
    """The filter's pole ``b`` free (``K``, ``a`` of the three-parameter optimum of docs/design.md)."""
    family = filtered_loop(PLANT, {"K": -0.0832482936, "a": 0.341, "b": None})
    return family, _Family(family.affine())


def test_the_filters_factors_are_the_filtered_loops_own(pole: tuple) -> None:
    family, fam = pole
    A, B = family(np.array([1.0087]))
    assert fam.A(1.0087) == A and fam.B(1.0087) == B  # structural equality: the same stored terms
    zero = filtered_loop(PLANT, {"K": -0.0832482936, "b": 1.0087, "a": None})
    assert _Family(zero.affine()).B(0.341) == zero(np.array([0.341]))[1]


def _axis_factor_by_factor(fam: _Family, loop: AffineLoop, w: np.ndarray) -> list[np.ndarray]:
    """``A_0, A_1, B_0, B_1`` and their ``w``-derivatives on ``s = i w``, each quasi-polynomial evaluated alone."""
    s = 1j * w
    zero = np.zeros(s.shape, dtype=complex)
    b0 = loop.B0(s)
    a0 = loop.A0(s) if fam.S0 is None else fam.S0(s) - b0
    a1 = zero if fam.a1_zero else s * a0 if fam.a1_times_s else loop.A1(s)
    b1 = zero if fam.b1_zero else s * b0 if fam.b1_times_s else loop.B1(s)
    db0 = 1j * loop.B0.deriv_at(s)
    da0 = 1j * loop.A0.deriv_at(s) if fam.S0 is None else 1j * fam.S0.deriv_at(s) - db0
    da1 = zero if fam.a1_zero else 1j * a0 + s * da0 if fam.a1_times_s else 1j * loop.A1.deriv_at(s)
    db1 = zero if fam.b1_zero else 1j * b0 + s * db0 if fam.b1_times_s else 1j * loop.B1.deriv_at(s)
    return [a0, a1, b0, b1, da0, da1, db0, db1]


@pytest.mark.parametrize(
    "free",
    [
        {"K": -0.0832482936, "a": 0.341, "b": None},  # the pole: A_1 = s A_0
        {"K": -0.0832482936, "a": None, "b": 1.0087},  # the zero: B_1 = s B_0
        {"K": None, "a": 0.341, "b": 1.0087},  # the gain: B_1 = q e^{-2 s} (1 + a s), evaluated on its own
        {"K": None, "a": 0.0, "b": 0.0},  # no filter: I_N cancels in A_0 + B_0
    ],
)
def test_the_scan_integrates_each_kernel_once_with_the_same_values(free: dict) -> None:
    loop = filtered_loop(PLANT, free).affine()
    fam = _Family(loop)
    assert len(fam.shared.kernels) == 1  # I_N, in A_0 and (negated) in B_0
    grid = 0.03125 * np.arange(1, 2001, dtype=float)
    for w in (grid, np.array([3.0171]), np.array([0.5, 3.3, 17.0])):  # the scan's grid, Newton's points
        at = fam.axis(w, slopes=True)
        got = [at.a0, at.a1, at.b0, at.b1, at.da0, at.da1, at.db0, at.db1]
        # the same arithmetic as each quasi-polynomial's own evaluation (a negated kernel integrates to the
        # negated values exactly): equal to the last bit
        for name, x, y in zip(
            ("a0", "a1", "b0", "b1", "da0", "da1", "db0", "db1"), got, _axis_factor_by_factor(fam, loop, w)
        ):
            assert np.array_equal(x, y), name


def test_a_kernel_shared_by_a_and_b_is_written_once(pole: tuple) -> None:
    family, fam = pole
    A, B = family(np.array([1.0087]))
    F = A + B  # (1 + b s)(1 - Phi) + (1 + a s)(K q e^{-2 s} - I_N): I_N twice, with opposite signs
    assert len(F.distributed) == 2
    G = _merged(F)
    assert len(G.distributed) == 1 and len(fam.nominal(1.0087).distributed) == 1
    s = np.array([0.3 + 2.0j, -0.05 + 3.0j, 0.01 + 40.0j, -0.5 + 0.1j])
    # the same function: the two routes differ by the rounding of b - a and of the sums (1e-15 of |F|'s terms)
    np.testing.assert_allclose(G(s), F(s), rtol=0, atol=1e-14 * float(np.max(np.abs(A(s)) + np.abs(B(s)))))
    np.testing.assert_allclose(G.deriv_at(s), F.deriv_at(s), rtol=1e-13)
    # its rightmost root: the certified search of either, to the accuracy of the roots (error estimate ~2e-14)
    np.testing.assert_allclose(spectral_abscissa(G).value, spectral_abscissa(F).value, rtol=0, atol=1e-13)
    # kernels that are not exact opposites stay apart
    d = F.distributed[0]
    H = QuasiPolynomial.from_parts(F.point_terms, [d, d.times(-2.0).times_poly([1.0, 0.5])])
    assert len(_merged(H).distributed) == 2


@pytest.mark.parametrize(
    "F",
    [
        QuasiPolynomial([[1.0, 1.0], [0.5]], [0.0, 1.0]),  # s + 1 + e^{-s}/2, root_free_region's example
        QuasiPolynomial([[2.0, 3.0, 1.0], [-3.0, -2.0], [1.0]], [0.0, 1.0, 2.0]),
    ],
)
def test_zero_free_radius_is_root_free_regions(F: QuasiPolynomial) -> None:
    assert _zero_free_radius(F) == root_free_region(F).radius


def test_zero_free_radius_of_filtered_loops_and_its_errors(pole: tuple) -> None:
    _, fam = pole
    for b in (0.85, 1.0087, 1.15):
        F = fam.nominal(b)
        assert _zero_free_radius(F) == root_free_region(F).radius
    advanced = QuasiPolynomial([[1.0], [0.0, 1.0]], [0.0, 1.0])  # 1 + s e^{-s}
    no_gap = QuasiPolynomial([[1.0, 1.0], [0.0, 2.0]], [0.0, 1.0])  # s + 1 + 2 s e^{-s}: |2| > |1|
    for F, name in ((advanced, "F"), (no_gap, "x0")):
        with pytest.raises(ParameterError, match=name):
            root_free_region(F)
        with pytest.raises(ParameterError, match=name):
            _zero_free_radius(F)


def _rates(sas: list) -> np.ndarray:
    return np.array([-np.inf if sa is None else -sa.value for sa in sas])


def test_sampled_rates_keep_an_interior_largest() -> None:
    # s^2 + K s + 1: decay rate K/2 for K <= 2, K/2 - sqrt(K^2/4 - 1) above (a double root at K = 2)
    fam = _Family(
        AffineLoop(QuasiPolynomial([[1.0, 0.0, 1.0]], [0.0]), QuasiPolynomial([[0.0, 1.0]], [0.0]), ZERO, ZERO)
    )
    Ks = np.linspace(1.0, 2.8, 5)
    exact = np.where(Ks <= 2.0, Ks / 2.0, Ks / 2.0 - np.sqrt(np.maximum(Ks**2 / 4.0 - 1.0, 0.0)))
    for first in (0, 4):
        sas = _sampled_abscissas(fam, Ks, first)
        rates = _rates(sas)
        computed = np.isfinite(rates)
        # 1e-12: simple roots of a quadratic, found by Newton to rounding
        np.testing.assert_allclose(rates[computed], exact[computed], rtol=0, atol=1e-12)
        assert int(np.argmax(rates)) == int(np.argmax(exact)) == 2
        assert not computed.all()  # K = 2.35: its real root -0.558 bounds it below the rate at K = 1.9


def test_sampled_rates_of_a_monotone_family_compute_the_best_only() -> None:
    # s + 1 + K: the root -1 - K, decay rate 1 + K
    fam = _Family(AffineLoop(QuasiPolynomial([[1.0, 1.0]], [0.0]), QuasiPolynomial([[1.0]], [0.0]), ZERO, ZERO))
    Ks = np.linspace(0.0, 2.0, 5)
    rates = _rates(_sampled_abscissas(fam, Ks, 4))
    assert np.isfinite(rates).sum() == 1
    np.testing.assert_allclose(rates[4], 3.0, rtol=1e-14)
    # started from the wrong end, the best is still computed and the interior left out
    rates = _rates(_sampled_abscissas(fam, Ks, 0))
    assert np.isfinite(rates).sum() == 2 and int(np.argmax(rates)) == 4


def test_sampled_rates_of_the_gain_left_out_by_the_chains() -> None:
    # U_BS2(K) at delta = 0: 1 - (rho - K) q e^{-tau s}, decay rate -ln((rho - K) q) / tau (Lemma 3), the chains'
    fam = _Family(u_bs2_loop(PLANT))
    Ks = np.linspace(0.035, 0.13, 5)
    rates = _rates(_sampled_abscissas(fam, Ks, 4))
    assert np.isfinite(rates).sum() == 1
    np.testing.assert_allclose(rates[4], -np.log((RHO - Ks[4]) * Q) / TAU, rtol=0, atol=1e-12)


def test_a_minimum_of_the_curve_is_not_the_design() -> None:
    """The margin of this loop falls from the bound ``K = -1`` (0.071796) to a minimum at ``K = -0.92`` (0.071583),
    then rises to the gain where the loop without delay loses stability (``K = -0.7234615``). The design is that
    end, moved inside (margin 0.0733678, a supremum not attained), not the minimum or the bound: it beats the
    certified margins of a grid of 31 gains on ``[-1, -0.7]`` (the public ``delay_margin``, which shares only the
    loop with the design), the last stable one 0.073241 at ``K = -0.73``."""
    from nrobust.design.gain import best_margin
    from nrobust.margins import delay_margin

    loop = AffineLoop(
        QuasiPolynomial([[1.454, 1.0], [-1.751]], [0.0, 1.928]),
        QuasiPolynomial([[-0.6]], [0.0]),
        QuasiPolynomial([[-1.584]], [1.529]),
        QuasiPolynomial([[-2.0]], [0.333]),
    )
    design = best_margin(loop, (-1.0, 1.0))
    grid = [delay_margin(loop.A(K), loop.B(K)).margin for K in np.linspace(-1.0, -0.7, 31)]
    assert design.kind == "end" and abs(design.K + 0.7234615) < 1e-6
    assert design.margin >= max(grid) and max(grid) > 0.0732
    np.testing.assert_allclose(design.margin, delay_margin(loop.A(design.K), loop.B(design.K)).margin, rtol=1e-12)
