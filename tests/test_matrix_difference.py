"""Matrix difference operators: certified gamma_0, C_D and chains against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from nrobust import CertificationError, DifferenceOperator, ParameterError
from nrobust.matrix_difference import MatrixDifferenceOperator

# a non-normal similarity: full matrices whose spectra are those of diagonal ones
T = np.array([[1.0, 2.0], [0.5, 3.0]])
TI = np.linalg.inv(T)


def _similar(*diagonals: tuple[float, float]) -> np.ndarray:
    return np.array([T @ np.diag(d) @ TI for d in diagonals])


def test_single_delay_is_the_spectral_radius() -> None:
    # nilpotent with norm 3: strongly stable although ||A|| > 1
    D = MatrixDifferenceOperator([[[0.0, 3.0], [0.0, 0.0]]], [1.0])
    g = D.gamma_0()
    assert g.lower <= 1e-7 and g.upper < 1e-2 and D.is_strongly_stable()
    D = MatrixDifferenceOperator(_similar((0.4, -1.1)), [0.7])
    g = D.gamma_0()
    assert g.lower <= 1.1 + 1e-12 and 1.1 - 1e-12 <= g.upper < 1.1 * (1 + 1e-6)
    assert not D.is_strongly_stable()


def test_off_diagonal_two_delays_closed_forms() -> None:
    """rho(a e^{i t1} E12 + b e^{i t2} E21) = sqrt(ab) for all phases; det D = 1 - ab z^3."""
    a, b = 0.6, 0.9
    D = MatrixDifferenceOperator([[[0.0, a], [0.0, 0.0]], [[0.0, 0.0], [b, 0.0]]], [1.0, 2.0])
    g = D.gamma_0(rtol=1e-3)
    exact = np.sqrt(a * b)
    assert g.lower <= exact + 1e-12 <= g.upper + 2e-12 and g.upper - exact < 2e-3
    assert D.is_strongly_stable()
    ch = D.chains()
    np.testing.assert_allclose([c.real for c in ch.chains], np.log(a * b) / 3, rtol=1e-12)
    assert sum(c.multiplicity for c in ch.chains) == 3
    s = ch.points(-20.0, 20.0)
    assert np.max(np.abs(D(s))) < 1e-12
    lo, hi = D.strong_spectral_bound(tol=1e-3)
    assert lo <= np.log(a * b) / 3 <= hi and hi - lo < 1e-2


@pytest.mark.parametrize("coefs, delays", [([0.85, -0.1], [2.0, 2.1]), ([-0.5, 0.3, 0.15], [1.0, 1.5, 2.5])])
def test_scalar_case(coefs: list[float], delays: list[float]) -> None:
    """1 x 1 operators: gamma_0 = sum |a_k|, C_D and chains as DifferenceOperator."""
    D = MatrixDifferenceOperator(np.array(coefs).reshape(-1, 1, 1), delays)
    S = DifferenceOperator([1.0, *(-c for c in coefs)], [0.0, *delays])
    g = D.gamma_0(rtol=1e-4)
    assert g.lower <= S.gamma_0 <= g.upper and g.upper - g.lower < 1e-3
    lo, hi = D.strong_spectral_bound(tol=1e-4)
    assert lo <= S.strong_spectral_bound() <= hi
    np.testing.assert_allclose(D.chains().bracket, S.chains().bracket, atol=1e-10)


def test_diagonal_is_the_worst_scalar() -> None:
    """Commuting (simultaneously diagonalisable) coefficients: gamma_0 = max_i sum_k |a_k,i|."""
    D = MatrixDifferenceOperator(_similar((0.3, -0.2), (0.25, 0.6)), [1.0, 3.0])
    g = D.gamma_0(rtol=1e-4)
    assert g.lower <= 0.8 <= g.upper < 0.8 + 1e-3
    chains = D.chains()
    scalar = [DifferenceOperator([1.0, -a1, -a2], [0.0, 1.0, 3.0]).chains() for a1, a2 in ((0.3, 0.25), (-0.2, 0.6))]
    expect = np.sort([c.real for sc in scalar for c in sc.chains for _ in range(c.multiplicity)])
    got = np.sort([c.real for c in chains.chains for _ in range(c.multiplicity)])
    np.testing.assert_allclose(got, expect, atol=1e-8)


def test_three_delays_bracket_holds_dense_samples() -> None:
    rng = np.random.default_rng(1)
    A = rng.normal(size=(3, 2, 2)) * 0.3
    D = MatrixDifferenceOperator(A, [1.0, 1.7, 2.9])
    g = D.gamma_0(rtol=3e-3)
    th = np.linspace(0.0, 2 * np.pi, 121)
    x = A[0][None, None] + A[1][None, None] * np.exp(1j * th)[:, None, None, None]
    x = x + A[2][None, None] * np.exp(1j * th)[None, :, None, None]
    sampled = float(np.max(np.abs(np.linalg.eigvals(x))))
    assert g.lower <= sampled * (1 + 1e-3) and sampled <= g.upper
    assert g.upper - g.lower <= 3e-3 * (1 + g.lower) + 1e-12


def test_stable_for_commensurate_delays_but_not_strongly() -> None:
    """P(z) = 1 + 1.2 z + 0.5 z^2 has |z| = sqrt 2 > 1 (stable chains for delays 1, 2) but
    gamma_0 = 1.7: delays 1 and 39/19 (both phases pi together at w = 19 pi) put chains in Re s > 0."""
    coefs = _similar((-1.2, 0.1), (-0.5, 0.05))
    nominal = MatrixDifferenceOperator(coefs, [1.0, 2.0])
    assert nominal.chains().bracket[1] == pytest.approx(-np.log(np.sqrt(2.0)), abs=1e-10)
    assert not nominal.is_strongly_stable()
    perturbed = MatrixDifferenceOperator(coefs, [1.0, 39.0 / 19.0])
    assert perturbed.chains().bracket[1] > 0.0
    lo, hi = nominal.strong_spectral_bound(tol=1e-4)
    # C_D: 1.2 e^{-c} + 0.5 e^{-2c} = 1
    c_d = float(np.log((1.2 + np.sqrt(1.44 + 2.0)) / 2.0))
    assert lo <= c_d <= hi and perturbed.chains().bracket[1] <= hi


def test_undecidable_and_bad_input() -> None:
    # rho = sqrt(0.999) for every phase: too close to 1 for 64 cells
    D = MatrixDifferenceOperator([[[0.0, 1.0], [0.0, 0.0]], [[0.0, 0.0], [0.999, 0.0]]], [1.0, 2.0])
    with pytest.raises(CertificationError, match="max_cells"):
        D.is_strongly_stable(max_cells=64)
    # rho = 1 for every phase: undecidable in floating point, never a verdict
    one = MatrixDifferenceOperator([[[0.0, 1.0], [0.0, 0.0]], [[0.0, 0.0], [1.0, 0.0]]], [1.0, 2.0])
    with pytest.raises(CertificationError, match="max_cells"):
        one.is_strongly_stable(max_cells=2000)
    # rho = sqrt(1.002) > 1: not strongly stable
    above = MatrixDifferenceOperator([[[0.0, 1.0], [0.0, 0.0]], [[0.0, 0.0], [1.002, 0.0]]], [1.0, 2.0])
    assert not above.is_strongly_stable()
    with pytest.raises(ParameterError, match="coefs"):
        MatrixDifferenceOperator([[1.0, 2.0]], [1.0])
    with pytest.raises(ParameterError, match="delays"):
        MatrixDifferenceOperator([[[0.5]], [[0.2]]], [1.0, 1.0])
    with pytest.raises(ParameterError, match="delays"):
        MatrixDifferenceOperator([[[0.5]]], [0.0])
    with pytest.raises(ParameterError, match="delays"):
        MatrixDifferenceOperator([[[0.5]], [[0.2]]], [1.0, np.sqrt(2.0)]).chains()


# ---------------------------------------------------------------- tight brackets (second-order discs)
def test_tight_single_delay_is_the_spectral_radius() -> None:
    """One delay: gamma_0 = rho(A_1); a diagonalisable non-normal A_1 gives a bracket of width ~1e-12."""
    A = _similar((0.4, -0.7))
    g = MatrixDifferenceOperator(A, [0.7]).gamma_0(rtol=1e-6)
    np.testing.assert_allclose([g.lower, g.upper], 0.7, rtol=1e-9)


@pytest.mark.parametrize("delays", [[1.0, 2.3], [1.0, 1.7, 2.9], [0.5, 1.0, 1.6, 2.2]])
def test_tight_diagonal_is_the_largest_row_sum(delays: list[float]) -> None:
    """Diagonal A_k: gamma_0 = max_i sum_k |a_k,ii| exactly, bracketed to rtol = 1e-6. Each eigenvalue
    depends on its own phases only: the disc bounds see the flat directions and never cut them."""
    rng = np.random.default_rng(len(delays))
    diag = rng.uniform(-0.5, 0.5, (len(delays), 3))
    D = MatrixDifferenceOperator(np.array([np.diag(d) for d in diag]), delays)
    g = D.gamma_0(rtol=1e-6)
    exact = float(np.max(np.abs(diag).sum(axis=0)))
    assert g.lower <= exact * (1 + 1e-12) and exact <= g.upper
    assert g.upper - g.lower <= 1e-6 * g.lower
    np.testing.assert_allclose(g.upper, exact, rtol=1e-6)


def test_tight_nonnegative_is_the_perron_root() -> None:
    """Entrywise nonnegative A_k: |sum_k A_k e^{i theta_k}| <= sum_k A_k entrywise, so
    gamma_0 = rho(sum_k A_k) (Perron-Frobenius), attained at theta = 0."""
    rng = np.random.default_rng(7)
    A = rng.uniform(0.0, 0.2, (3, 3, 3))
    g = MatrixDifferenceOperator(A, [1.0, 1.4, 2.5]).gamma_0(rtol=1e-6)
    exact = float(np.max(np.abs(np.linalg.eigvals(A.sum(axis=0)))))
    np.testing.assert_allclose([g.lower, g.upper], exact, rtol=1e-6)
    assert g.lower <= exact * (1 + 1e-12) <= g.upper * (1 + 2e-12)


def test_tight_off_diagonal_closed_form() -> None:
    """rho(a e^{i t1} E12 + b e^{i t2} E21) = sqrt(ab) for every phase: a flat maximum over the whole torus."""
    a, b = 0.6, 0.9
    g = MatrixDifferenceOperator([[[0.0, a], [0.0, 0.0]], [[0.0, 0.0], [b, 0.0]]], [1.0, 2.0]).gamma_0(rtol=1e-6)
    np.testing.assert_allclose([g.lower, g.upper], np.sqrt(a * b), rtol=1e-6)


@pytest.mark.parametrize("K, p", [(2, 2), (3, 2), (3, 3), pytest.param(4, 2, marks=pytest.mark.slow)])
def test_tight_bracket_holds_dense_samples(K: int, p: int) -> None:
    """Random coefficients: the bracket is within 1e-6 and no sampled rho exceeds its upper end."""
    rng = np.random.default_rng(10 * K + p)
    A = rng.normal(size=(K, p, p)) * 0.3
    g = MatrixDifferenceOperator(A, 1.0 + np.arange(K) * 0.7).gamma_0(rtol=1e-6)
    assert g.upper - g.lower <= 1e-6 * g.lower
    theta = np.vstack([np.zeros(K), rng.uniform(0, 2 * np.pi, (5000, K))])
    x = np.einsum("nk,kij->nij", np.exp(1j * theta), A)
    assert float(np.max(np.abs(np.linalg.eigvals(x)))) <= g.upper


def test_tight_work_bound() -> None:
    """The work bound is checked before a round is allocated; a bracket that cannot close raises."""
    A = np.random.default_rng(3).normal(size=(3, 3, 3)) * 0.3
    D = MatrixDifferenceOperator(A, [1.0, 1.5, 2.7])
    with pytest.raises(CertificationError, match="max_cells"):
        D.gamma_0(rtol=1e-9, max_cells=300)
    with pytest.raises(ParameterError, match="max_cells"):
        D.gamma_0(max_cells=100)  # below the first cover (16 x 16 cells)
