"""State-space time-delay systems: det(s E - sum A e^{-h s} - s sum B e^{-h s} - ...) certified."""

from __future__ import annotations

import numpy as np
import pytest

from nrobust import DistributedDelay, ParameterError, QuasiPolynomial, find_roots
from nrobust.statespace import StateSpaceTDS

A0 = np.array([[-1.0, 0.5], [0.3, -2.0]])
A1 = np.array([[-0.8, 0.2], [0.1, -0.5]])
H = np.array([[0.3, 0.1], [0.0, -0.4]])
REGION = (-3.0, 1.0, -20.0, 20.0)


def test_characteristic_matrix_by_hand() -> None:
    sys = StateSpaceTDS([A0, A1], [0.0, 1.0], B=[-H], hB=[0.5])
    M = sys.characteristic_matrix()
    for s in (0.3 + 2j, -1.0 - 5j):
        by_hand = s * np.eye(2) - A0 - A1 * np.exp(-s) + s * H * np.exp(-0.5 * s)
        np.testing.assert_allclose(complex(M(s)), np.linalg.det(by_hand), rtol=1e-13)


def test_point_delays_against_the_expanded_determinant() -> None:
    sys = StateSpaceTDS([A0, A1], [0.0, 1.0], B=[-H], hB=[0.5])
    ours = sys.roots(REGION)
    scalar = find_roots(sys.characteristic_matrix().expand(), REGION)
    assert ours.certified and ours.count == scalar.count == 10
    np.testing.assert_allclose(np.sort_complex(ours.roots), np.sort_complex(scalar.roots), atol=1e-10)


def test_distributed_delay_scalar_and_diagonal() -> None:
    """x' = -x + 0.5 int N x(t - nu): det is s + 1 - 0.5 int N e^{-nu s}; a diagonal pair is the product."""
    N = DistributedDelay([0.0, 0.5, 1.0], [1.0, 0.5, 0.2])
    one = StateSpaceTDS([[[-1.0]]], [0.0], distributed=[([[0.5]], N)])
    F = QuasiPolynomial([[1.0, 1.0]], [0.0], [N.scale(-0.5)])
    s = np.array([0.2 + 1j, -0.5 + 7j])
    np.testing.assert_allclose(one.characteristic_matrix()(s), F(s), rtol=1e-13)
    two = StateSpaceTDS([np.diag([-1.0, -2.0])], [0.0], distributed=[(np.diag([0.5, 0.3]), N)])
    F2 = QuasiPolynomial([[2.0, 1.0]], [0.0], [N.scale(-0.3)])
    roots = two.roots((-4.0, 1.0, -10.0, 10.0))
    expect = np.concatenate(
        [find_roots(F, (-4.0, 1.0, -10.0, 10.0)).roots, find_roots(F2, (-4.0, 1.0, -10.0, 10.0)).roots]
    )
    assert roots.certified
    np.testing.assert_allclose(np.sort_complex(roots.roots), np.sort_complex(expect), atol=1e-9)


def test_strong_stability_of_the_neutral_part() -> None:
    sys = StateSpaceTDS([A0, A1], [0.0, 1.0], B=[-H], hB=[0.5])
    assert sys.is_strongly_stable() and sys.principal_operator().gamma_0().upper < 0.41
    assert sys.characteristic_matrix().kind == "neutral"
    unstable = StateSpaceTDS([A0], [0.0], B=[np.diag([0.6, 0.0]), np.diag([0.0, 0.7])], hB=[1.0, 2.0])
    assert unstable.is_strongly_stable()  # diagonal: gamma_0 = max(0.6, 0.7)
    coupled = StateSpaceTDS([A0], [0.0], B=[[[0.0, 0.9], [0.0, 0.0]], [[0.0, 0.0], [1.2, 0.0]]], hB=[1.0, 2.0])
    assert not coupled.is_strongly_stable()  # rho = sqrt(0.9 * 1.2) > 1 for every phase
    assert StateSpaceTDS([A0, A1], [0.0, 1.0]).is_strongly_stable()  # retarded


def test_tdcpy_spectra_agree() -> None:
    """Same systems in tdcpy (not certified): every tdcpy root is an nrobust root (measured 1e-11)."""
    tdcpy = pytest.importorskip("tdcpy")
    A = np.stack([A0, A1], axis=-1)
    cases = [
        (StateSpaceTDS([A0, A1], [0.0, 1.0]), tdcpy.RDDE(A=A, hA=np.array([0.0, 1.0]))),
        (
            StateSpaceTDS([A0, A1], [0.0, 1.0], B=[-H], hB=[0.5]),
            tdcpy.NDDE(A=A, hA=np.array([0.0, 1.0]), H=H[:, :, None], hH=np.array([0.5])),
        ),
    ]
    for ours, theirs in cases:
        r = ours.roots(REGION)
        z, _ = tdcpy.roots(theirs, r=list(REGION))
        assert r.certified and z.size == r.count
        assert np.max(np.min(np.abs(z[:, None] - r.roots[None, :]), axis=1)) < 1e-8


def test_bad_input() -> None:
    with pytest.raises(ParameterError, match="A"):
        StateSpaceTDS([[1.0, 2.0]], [0.0])
    with pytest.raises(ParameterError, match="hA"):
        StateSpaceTDS([A0], [-1.0])
    with pytest.raises(ParameterError, match="hB"):
        StateSpaceTDS([A0], [0.0], B=[H], hB=[0.0])
    with pytest.raises(ParameterError, match="E"):
        StateSpaceTDS([A0], [0.0], E=np.eye(3))
    with pytest.raises(ParameterError, match="distributed"):
        StateSpaceTDS([A0], [0.0], distributed=[(np.eye(2), "N")])  # type: ignore[list-item]
    with pytest.raises(ParameterError, match="E"):
        StateSpaceTDS([A0], [0.0], B=[H], hB=[1.0], E=[[1.0, 0.0], [0.0, 0.0]]).principal_operator()
