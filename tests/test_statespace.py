"""State-space time-delay systems: det(s E - sum A e^{-h s} - s sum B e^{-h s} - ...) certified."""

from __future__ import annotations

import numpy as np
import pytest

from nrobust import DistributedDelay, ParameterError, QuasiPolynomial, count_roots, find_roots
from nrobust.lti.statespace import StateSpaceTDS

A0 = np.array([[-1.0, 0.5], [0.3, -2.0]])
A1 = np.array([[-0.8, 0.2], [0.1, -0.5]])
H = np.array([[0.3, 0.1], [0.0, -0.4]])
REGION = (-3.0, 1.0, -20.0, 20.0)


def _sorted(z: np.ndarray) -> np.ndarray:
    """Sorted by real then imaginary part, rounded: the order of a conjugate pair whose real
    parts differ in the last bits is not decided by those bits."""
    return z[np.lexsort((np.round(z.imag, 8), np.round(z.real, 8)))]


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
    np.testing.assert_allclose(_sorted(ours.roots), _sorted(scalar.roots), atol=1e-10)


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
    np.testing.assert_allclose(_sorted(roots.roots), _sorted(expect), atol=1e-9)


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


# ---------------------------------------------------------------------------------------
# tdcpy's own published examples (https://github.com/LockeErasmus/tdcpy): the TDS-CONTROL
# manual examples it reproduces (Appeltans and Michiels, "Analysis and controller-design of
# time-delay systems using TDS-CONTROL. A tutorial and manual", arXiv:2305.00341, 2023, as
# tdcpy's docs/source/refs.bib cites it) and the descriptor examples of its gallery.
# Matrices exactly as in those files (path @ commit).
# tdcpy's NDDE writes x' + sum H_k x'(t - hH_k) = ..., so B = -H.
# ---------------------------------------------------------------------------------------

# Example 2.1 (manual Section 2.2; Verheyden, Luzyanina, Roose, J. Comput. Appl. Math. 214,
# 2008, Section 6.1): tdcpy examples/09_tds_control_manual/example_2_01.py @ 2cfce639.
EX21 = (
    np.array([[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -10, -4], [0, 0, 4, -10]], dtype=float),
    np.array([[3, 3, 3, 3], [0, -1.5, 0, 0], [0, 0, 3, -5], [0, 5, 5, 5]], dtype=float),
)
# Its rightmost root as tdcpy's test tests/stability/test_rightmost_root.py @ 85250038 states it.
EX21_RIGHTMOST = 0.6176424667764324


def ex26(tau2: float) -> StateSpaceTDS:
    """Example 2.6 (manual Section 2.3.2), x' = x/4 - x(t-1)/3 + 3/4 x'(t-1) - 1/2 x'(t-tau2).

    tdcpy examples/09_tds_control_manual/example_2_06.py @ 8126bc89 (tau2 = 2, 2.05, 2.005).
    """
    return StateSpaceTDS([[[0.25]], [[-1.0 / 3.0]]], [0.0, 1.0], B=[[[0.75]], [[-0.5]]], hB=[1.0, tau2])


def ex29() -> StateSpaceTDS:
    """Example 2.9: a plant with input and output delay 1 closed by a first-order controller.

    The descriptor closed loop (n = 6, E singular) exactly as tdcpy examples/example2_9.py
    @ 0bc99f19 builds it; that script states its spectral abscissa "must be -0.2845".
    """
    a0, a1 = np.array([[0.2, 0.1], [-0.5, 1.0]]), np.array([[0.5, 0.3], [0.1, -0.1]])
    b, c, d = np.eye(2), np.array([[1.0, 1.0]]), np.array([[0.01, 0.01]])
    ac, bc, cc, dc = np.array([[-3.48]]), np.array([[3.1]]), np.array([[1.79], [-0.09]]), np.array([[-1.86], [-1.4]])
    E = np.diag([1.0, 1.0, 0.0, 1.0, 0.0, 0.0])  # states: x (2), y (1), controller state (1), u (2)
    m0, m1 = np.zeros((6, 6)), np.zeros((6, 6))
    m0[:2, :2], m0[2:3, :2], m0[2, 2] = a0, c, -1.0
    m0[3:4, 2:3], m0[3:4, 3:4] = bc, ac
    m0[4:, 2:3], m0[4:, 3:4], m0[4:, 4:] = dc, cc, -np.eye(2)
    m1[:2, :2], m1[:2, 4:], m1[2:3, 4:] = a1, b, d
    return StateSpaceTDS([m0, m1], [0.0, 1.0], E=E)


def ex13(a: float) -> StateSpaceTDS:
    """diag(1, 0) x' = [[0, -1/8], [-1, 1]] x + diag(0, -a) x(t-1) + diag(0, 1/2) x(t-2).

    Example 13 of Michiels, "Spectrum-based stability analysis and stabilisation of systems
    described by delay differential algebraic equations", IET Control Theory Appl. 5(16),
    2011, as tdcpy
    examples/03_stabopt/example_strong_sa.py @ 51d23115 writes it (a = 0.25 and 0.75).
    """
    return StateSpaceTDS(
        [[[0.0, -0.125], [-1.0, 1.0]], [[0.0, 0.0], [0.0, -a]], [[0.0, 0.0], [0.0, 0.5]]],
        [0.0, 1.0, 2.0],
        E=[[1.0, 0.0], [0.0, 0.0]],
    )


def test_example_2_1_rightmost_root() -> None:
    """The certified abscissa reproduces the stated rightmost root to 4e-13 (rtol 1e-11: double rounding)."""
    sa = StateSpaceTDS(list(EX21), [0.0, 1.0]).abscissa((-1.0, 1.0, -10.0, 10.0))
    assert sa.certified
    np.testing.assert_allclose(sa.value, EX21_RIGHTMOST, rtol=1e-11)
    assert sa.root is not None
    np.testing.assert_allclose(sa.root, EX21_RIGHTMOST, atol=1e-11)


def test_example_2_6_fragile_neutral_stability() -> None:
    """gamma_0 = 3/4 + 1/2 > 1: stable at tau2 = 2, unstable roots at tau2 = 2.05 (certified counts)."""
    D = ex26(2.0).principal_operator()
    assert not ex26(2.0).is_strongly_stable() and D.gamma_0().lower > 1.2499
    # commensurate chains: 1 - 3/4 z + 1/2 z^2 has |z|^2 = 2, so Re s = -ln(2)/2 on every chain
    np.testing.assert_allclose([c.real for c in D.chains().chains], -np.log(2.0) / 2.0, rtol=1e-12)
    band = (-0.9, 0.2, -60.0, 60.0)
    stable, perturbed = ex26(2.0).abscissa(band), ex26(2.05).abscissa(band)
    assert stable.certified and perturbed.certified and stable.value < -0.17 and perturbed.value > 0.15
    assert count_roots(ex26(2.05).characteristic_matrix(), (0.0, 0.2, -60.0, 60.0)) >= 2


def test_example_2_9_descriptor_abscissa() -> None:
    """The stated -0.2845 (4 digits) in the band; the chains' bound C_D far left (-3.42)."""
    sys = ex29()
    sa = sys.abscissa((-1.0, 0.5, -10.0, 10.0))
    assert sa.certified
    np.testing.assert_allclose(sa.value, -0.2845, atol=5e-5)
    lo, hi = sys.principal_operator().strong_spectral_bound()
    # rank one: the difference operator is 1 - 0.0326 e^{-s} on its range, C_D = ln(0.0326)
    assert lo <= np.log(0.0326) <= hi and hi - lo < 1e-3


@pytest.mark.parametrize("a", [0.25, 0.75])
def test_example_13_descriptor_strong_stability(a: float) -> None:
    """D(s) = 1 + a e^{-s} - e^{-2s}/2 after normalising U^T A_0 V = 1: gamma_0 = a + 1/2, C_D in closed form."""
    sys = ex13(a)
    g = sys.principal_operator().gamma_0()
    assert g.lower <= a + 0.5 <= g.upper and g.upper - g.lower < 3e-3
    assert sys.is_strongly_stable() == (a < 0.5)
    # a e^{-c} + e^{-2c}/2 = 1 at c = C_D: y = e^{-c} = -a + sqrt(a^2 + 2)
    lo, hi = sys.principal_operator().strong_spectral_bound()
    assert lo <= -np.log(-a + np.sqrt(a * a + 2.0)) <= hi


def test_descriptor_principal_operator_input() -> None:
    with pytest.raises(ParameterError, match="B"):
        StateSpaceTDS([A0], [0.0], B=[H], hB=[1.0], E=[[1.0, 0.0], [0.0, 0.0]]).principal_operator()
    with pytest.raises(ParameterError, match="A"):  # U^T A_0 V = 0: not index 1
        StateSpaceTDS([np.diag([1.0, 0.0]), A1], [0.0, 1.0], E=[[1.0, 0.0], [0.0, 0.0]]).principal_operator()
    assert StateSpaceTDS([A0], [0.0], E=[[1.0, 0.0], [0.0, 0.0]]).is_strongly_stable()  # no delayed term


def test_root_radius_encloses_the_right_half() -> None:
    """Every root right of the line lies in the disc (the Example 2.1 roots found in a wider box)."""
    sys = StateSpaceTDS(list(EX21), [0.0, 1.0])
    R = sys.root_radius(-1.0)
    np.testing.assert_allclose(R, np.linalg.norm(EX21[0], 2) + np.linalg.norm(EX21[1], 2) * np.e, rtol=1e-12)
    wide = sys.roots((-1.0, 1.0, -1.25 * R, 1.25 * R))
    assert wide.certified and np.all(np.abs(wide.roots) <= R)
    with pytest.raises(ParameterError, match="re_min"):
        ex26(2.0).root_radius(-0.5)  # 3/4 e^{0.5} + 1/2 e^{1} > 1: the chains reach the line
    with pytest.raises(ParameterError, match="E"):
        ex29().root_radius(0.0)


@pytest.mark.slow
def test_example_2_1_all_roots_right_of_the_line() -> None:
    """tdcpy's ``roots(rdde, r=-2.5)`` set, certified: 67 roots (checked against tdcpy below)."""
    r = StateSpaceTDS(list(EX21), [0.0, 1.0]).roots_right_of(-2.5)
    assert r.certified and r.count == 67 and int(np.sum(r.multiplicities)) == 67


def _distance(theirs: np.ndarray, ours: np.ndarray) -> float:
    """Largest distance from a tdcpy root to the nearest nrobust root."""
    return float(np.max(np.min(np.abs(theirs[:, None] - ours[None, :]), axis=1)))


@pytest.mark.slow
def test_tdcpy_published_examples_agree() -> None:
    """Same process: tdcpy's roots and abscissae on its examples equal nrobust's certified ones.

    Measured distances 6e-13 to 1.2e-11 (Newton-refined on both sides); asserted 1e-8.
    """
    tdcpy = pytest.importorskip("tdcpy")
    h = [[[-0.75]], [[0.5]]]
    cases = [
        (StateSpaceTDS(list(EX21), [0.0, 1.0]), tdcpy.RDDE(A=list(EX21), hA=[0.0, 1.0]), (-1.0, 1.0, -10.0, 10.0)),
        (ex26(2.0), tdcpy.NDDE(A=[[[0.25]], [[-1 / 3]]], hA=[0, 1.0], H=h, hH=[1.0, 2.0]), (-0.9, 0.2, -60, 60)),
        (ex26(2.05), tdcpy.NDDE(A=[[[0.25]], [[-1 / 3]]], hA=[0, 1.0], H=h, hH=[1.0, 2.05]), (-0.9, 0.2, -60, 60)),
    ]
    s29, s13 = ex29(), ex13(0.75)
    cases.append((s29, tdcpy.DDAE(E=s29.E, A=list(s29.A), hA=s29.hA), (-1.0, 0.5, -10.0, 10.0)))
    cases.append((s13, tdcpy.DDAE(E=s13.E, A=list(s13.A), hA=s13.hA), (-1.0, 0.5, -30.0, 30.0)))
    for ours, theirs, region in cases:
        r = ours.roots(region)
        z, _ = tdcpy.roots(theirs, r=list(region), max_size_evp=1500)
        assert r.certified and z.size == r.count
        assert _distance(z, r.roots) < 1e-8
    for ours, theirs, region in cases[:1] + cases[3:]:
        np.testing.assert_allclose(tdcpy.spectral_abscissa(theirs), ours.abscissa(region).value, atol=1e-9)
    # C_D of the descriptor examples: tdcpy's value inside nrobust's certified bracket
    for ours, theirs, _ in cases[3:]:
        lo, hi = ours.principal_operator().strong_spectral_bound()
        assert lo - 1e-6 <= tdcpy.cd(theirs)[0] <= hi + 1e-6


def ex31() -> StateSpaceTDS:
    """TDS-CONTROL manual Example 3.1 closed by its static feedback, as tdcpy examples/example3_1.py @ 0bc99f19.

    Five states, delays 6.5, 40, 13, 18, 2.8, 9.2 and the input delay 13.2 of
    ``u = K x`` with ``K = (-0.1659, -0.2968, -0.3612, -0.3629, 0.0168)``.
    """
    Th, Ta, Td, Tc = 14.0, 3.0, 3.0, 25.0
    Kb, Ka, Kd, Kc, Ku = 0.24, 1.0, 0.94, 0.81, 0.39
    a = np.zeros((8, 5, 5))
    a[0][1, 0], a[0][1, 1], a[0][2, 2], a[0][4, 3] = Ka / Ta, (-Ka - 1) / Ta, -1 / Td, -1.0
    a[1][0, 0], a[2][0, 1], a[3][1, 3] = -1 / Th, Kb / Th, 1 / Ta
    a[4][2, 1], a[5][3, 2], a[6][3, 3] = Kd / Td, Kc / Tc, -1 / Tc
    a[7][0] = Ku / Th * np.array([-0.1659, -0.2968, -0.3612, -0.3629, 0.0168])
    return StateSpaceTDS(a, [0.0, 6.5, 40.0, 13.0, 18.0, 2.8, 9.2, 13.2])


@pytest.mark.long
def test_example_3_1_tdcpy_count_is_not_certified() -> None:
    """Right of Re s = -0.2: 58 roots certified; tdcpy reports 60 (a double real root and an inexact pair).

    Measured: every tdcpy root within 2.7e-4 of a certified root; tdcpy about 60 s, nrobust 20 s.
    """
    tdcpy = pytest.importorskip("tdcpy")
    sys = ex31()
    ours = sys.roots_right_of(-0.2)
    z, _ = tdcpy.roots(tdcpy.RDDE(A=list(sys.A), hA=sys.hA), r=-0.2)
    assert ours.certified and ours.count == 58 and np.all(ours.multiplicities == 1)
    assert z.size == 60 and _distance(z, ours.roots) < 1e-3
    np.testing.assert_allclose(np.max(z.real), ours.roots.real.max(), atol=1e-8)


def test_example_2_12_smith_predictor_quasi_polynomial() -> None:
    """Example 2.12 (manual Section 2.6.2), tau = 1, delta = 0.5, as tdcpy example_2_12.py @ 59439534 writes it.

    D_cl(s) = 3/2 s + 3 + (s/2 + 2) e^{-s tau} - (s/2 + 2) e^{-s (tau + delta)}: the same
    characteristic function as the scalar state-space system; principal part
    1 + (e^{-s} - e^{-1.5 s}) / 3, gamma_0 = 2/3 (strongly stable).
    """
    F = QuasiPolynomial([[3.0, 1.5], [2.0, 0.5], [-2.0, -0.5]], [0.0, 1.0, 1.5])
    sys = StateSpaceTDS([[[-3.0]], [[-2.0]], [[2.0]]], [0.0, 1.0, 1.5], B=[[[-0.5]], [[0.5]]], hB=[1.0, 1.5], E=[[1.5]])
    s = np.array([0.3 + 2j, -1.0 + 17j])
    np.testing.assert_allclose(sys.characteristic_matrix()(s), F(s), rtol=1e-13)
    g = sys.principal_operator().gamma_0()
    assert g.lower <= 2.0 / 3.0 <= g.upper and sys.is_strongly_stable()
    ours = find_roots(F, (-3.0, 1.0, -60.0, 60.0))
    assert ours.certified and np.all(ours.roots.real < 0)


def test_example_2_12_tdcpy_roots_agree() -> None:
    """tdcpy's roots of Example 2.12 through its own qp_to_ndde equal nrobust's (measured 1.7e-12)."""
    tdcpy = pytest.importorskip("tdcpy")
    from tdcpy.common.quasipoly import qp_to_ndde

    region = (-3.0, 1.0, -60.0, 60.0)
    ours = find_roots(QuasiPolynomial([[3.0, 1.5], [2.0, 0.5], [-2.0, -0.5]], [0.0, 1.0, 1.5]), region)

    A, hA, Hm, hH = qp_to_ndde(np.array([[3.0, 1.5], [2.0, 0.5], [-2.0, -0.5]]), np.array([0.0, 1.0, 1.5]))
    z, _ = tdcpy.roots(tdcpy.NDDE(A=A, hA=hA, H=Hm, hH=hH), r=list(region), max_size_evp=1500)
    assert z.size == ours.count and _distance(z, ours.roots) < 1e-8
