"""DelayLTI: LFT algebra against closed forms, python-control round trips, certified poles against Lambert W."""

from __future__ import annotations

import dataclasses
import json

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import lambertw

from nrobust import QuasiPolynomial
from nrobust.errors import ParameterError
from nrobust.lti import DelayLTI, QuasiTransferFunction, StateSpaceTDS, as_delay_lti, delay, tf

W = np.array([0.0, 0.05, 0.3, 1.0, 2.7, 11.0])
S = 1j * W
# Every closed form below is a handful of floating-point operations on numbers of order 1:
# agreement to 1e-13 leaves a factor of ~500 over the double rounding unit.
TOL = 1e-13


def test_feedback_of_delayed_integrator_matches_closed_form() -> None:
    s = control.tf("s")
    G = (delay(1.0) * 2 / s).feedback(1)
    s1 = 1j * W[1:]
    exact = 2 * np.exp(-s1) / (s1 + 2 * np.exp(-s1))
    np.testing.assert_allclose(G.frequency_response(W[1:]), exact, rtol=TOL, atol=TOL)
    # same system through the descending-order constructor
    H = (delay(1.0) * tf([2.0], [1.0, 0.0])).feedback(1)
    np.testing.assert_allclose(H(s1), exact, rtol=TOL, atol=TOL)


def test_series_parallel_feedback_mimo_against_direct_formula() -> None:
    P = control.tf([[[1.0], [2.0, 1.0]], [[0.5], [1.0]]], [[[1.0, 1.0], [1.0, 3.0]], [[1.0, 2.0], [1.0, 0.5]]])
    dP = DelayLTI.from_control(P)
    D = delay(0.4).append(delay(1.3))
    K = np.array([[0.3, 0.1], [0.0, 0.2]])
    sys = (dP * D + 0.5 * dP).feedback(K, sign=-1)
    for s in S:
        Ds = np.diag([np.exp(-0.4 * s), np.exp(-1.3 * s)])
        Ps = np.asarray(P(s))
        open_ = Ps @ Ds + 0.5 * Ps
        exact = np.linalg.solve(np.eye(2) + open_ @ K, open_)
        np.testing.assert_allclose(sys(s), exact, rtol=1e-12, atol=1e-12)
    # series(self, other) is other * self (self first), as control.series
    np.testing.assert_allclose(dP.series(D)(S[2]), np.asarray(D(S[2])) @ np.asarray(P(S[2])), rtol=TOL)


def test_python_control_operands_on_both_sides() -> None:
    G = control.tf([1.0], [1.0, 1.0])
    d = delay(0.5)
    exact = np.exp(-0.5 * S) / (S + 1)
    for sys in (G * d, d * G, control.ss(G) * d, d * control.ss(G)):
        assert isinstance(sys, DelayLTI)
        np.testing.assert_allclose(sys(S), exact, rtol=TOL, atol=TOL)
    np.testing.assert_allclose((G + d)(S), 1 / (S + 1) + np.exp(-0.5 * S), rtol=TOL, atol=TOL)
    np.testing.assert_allclose((G - d)(S), 1 / (S + 1) - np.exp(-0.5 * S), rtol=TOL, atol=TOL)
    np.testing.assert_allclose((np.array([[2.0]]) * d)(S), 2 * np.exp(-0.5 * S), rtol=TOL, atol=TOL)
    np.testing.assert_allclose((3 - d)(S), 3 - np.exp(-0.5 * S), rtol=TOL, atol=TOL)


def test_round_trip_with_python_control_on_delay_free_systems() -> None:
    rng = np.random.default_rng(3)
    ss = control.ss(rng.normal(size=(3, 3)) - 3 * np.eye(3), rng.normal(size=(3, 2)), rng.normal(size=(2, 3)),
                    rng.normal(size=(2, 2)))  # fmt: skip
    back = DelayLTI.from_control(ss).to_control()
    np.testing.assert_allclose(back(S), ss(S), rtol=1e-12, atol=1e-12)
    closed = DelayLTI.from_control(ss).feedback(np.eye(2) * 0.3).to_control()
    ref = control.feedback(ss, np.eye(2) * 0.3)
    np.testing.assert_allclose(closed(S), ref(S), rtol=1e-12, atol=1e-12)
    poles, ref_poles = closed.poles(), ref.poles()
    assert poles.size == ref_poles.size
    np.testing.assert_allclose([np.min(np.abs(poles - p)) for p in ref_poles], 0.0, atol=1e-10)


def test_to_control_with_delays_points_to_frd_and_pade() -> None:
    with pytest.raises(ParameterError, match="to_frd"):
        delay(1.0).to_control()
    frd = (delay(1.0) * tf([1.0], [1.0, 1.0])).to_frd(W)
    np.testing.assert_allclose(frd.frdata[0, 0], np.exp(-S) / (S + 1), rtol=TOL, atol=TOL)


def test_quasi_transfer_function_realised_exactly_and_back() -> None:
    # (1 + 0.5 e^{-s}) / (s + 2 + 0.5 s e^{-2 s} + e^{-1.5 s}): neutral, ascending coefficients
    H = QuasiTransferFunction(
        QuasiPolynomial([[1.0], [0.5]], [0.0, 1.0]), QuasiPolynomial([[2.0, 1.0], [0.0, 0.5], [1.0]], [0, 2, 1.5])
    )
    G = DelayLTI.from_quasi_transfer(H)
    assert G.is_neutral and G.nstates == 1
    exact = (1 + 0.5 * np.exp(-S)) / (S + 2 + 0.5 * S * np.exp(-2 * S) + np.exp(-1.5 * S))
    np.testing.assert_allclose(G(S), exact, rtol=TOL, atol=TOL)
    np.testing.assert_allclose(G.to_quasi_transfer()(S), exact, rtol=TOL, atol=TOL)
    assert G.is_strongly_stable()


@pytest.mark.parametrize(
    ("num", "den", "what"),
    [
        (QuasiPolynomial([[0.0, 0.0, 1.0]], [0.0]), QuasiPolynomial([[1.0, 1.0]], [0.0]), "improper"),
        (QuasiPolynomial([[1.0]], [0.0]), QuasiPolynomial([[1.0, 1.0]], [1.0]), "advance"),
        (QuasiPolynomial([[1.0]], [0.0]), QuasiPolynomial([[1.0, 1.0], [0.0, 0.0, 1.0]], [0.0, 1.0]), "advanced"),
    ],
)
def test_unrealisable_quasi_transfer_functions_are_refused(
    num: QuasiPolynomial, den: QuasiPolynomial, what: str
) -> None:
    with pytest.raises(ParameterError, match=what):
        DelayLTI.from_quasi_transfer(QuasiTransferFunction(num, den))


def test_descending_coefficients_in_tf() -> None:
    G = tf([1.0, 1.0, 0.0], [1.0, 2.0, 3.0])  # (s^2 + s) / (s^2 + 2 s + 3), not (1 + s) / ...
    np.testing.assert_allclose(G(1.0), 2.0 / 6.0, rtol=TOL)
    assert isinstance(tf("s"), control.TransferFunction)


def test_statespace_tds_resolvent_and_poles() -> None:
    T = StateSpaceTDS(
        [[[-2.0, 0.5], [0.1, -1.0]], [[0.3, 0.0], [0.2, 0.1]]], [0.0, 1.0], [[[0.2, 0.0], [0.0, 0.1]]], [0.5]
    )
    L = DelayLTI.from_statespace_tds(T)
    M = T.characteristic_matrix()
    for s in S[:4]:
        np.testing.assert_allclose(L(s), np.linalg.inv(M.values(s)), rtol=1e-12, atol=1e-14)
    roots = L.poles(re_min=-1.5)
    assert roots.certified
    np.testing.assert_allclose(np.abs(M(roots.roots)), 0.0, atol=1e-12)


@pytest.mark.parametrize("a", [1.0, 2.0])
def test_poles_of_s_plus_a_delay_match_lambert_w(a: float) -> None:
    sys = (delay(1.0) * tf([a], [1.0, 0.0])).feedback(1)  # poles: s + a e^{-s} = 0, s = W_k(-a)
    found = sys.poles(re_min=-2.0)
    assert found.certified
    exact = np.array([complex(lambertw(-a, k)) for k in range(-4, 4)])
    exact = exact[exact.real >= -2.0]
    assert found.roots.size == exact.size
    # each Lambert W root has a certified pole within 1e-9 (the certified radii are far smaller)
    np.testing.assert_allclose([np.min(np.abs(found.roots - z)) for z in exact], 0.0, atol=1e-9)
    assert sys.is_stable() is (a < np.pi / 2)


def test_neutral_stability_decided_by_difference_operator() -> None:
    # y = u + c y(t - 1): pure difference equation, stable iff |c| < 1
    for c, stable in ((0.5, True), (1.5, False)):
        sys = DelayLTI.gain(1.0).feedback(c * delay(1.0), sign=1)
        assert sys.is_neutral and sys.is_stable() is stable


def test_indexing_append_and_algebraic_loop() -> None:
    G = delay(1.0).append(tf([1.0], [1.0, 1.0]))
    np.testing.assert_allclose(G[1, 1](S), 1 / (S + 1), rtol=TOL, atol=TOL)
    np.testing.assert_allclose(G[0, 1](S), 0.0, atol=0.0)
    np.testing.assert_allclose((-G)[0, 0](S), -np.exp(-S), rtol=TOL, atol=TOL)
    with pytest.raises(ParameterError, match="algebraic loop"):
        DelayLTI.gain(1.0).feedback(1.0, sign=1)


def test_immutable_and_json() -> None:
    G = delay(1.0) * tf([1.0], [1.0, 1.0])
    with pytest.raises(dataclasses.FrozenInstanceError):
        G.A = np.eye(1)  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        G.A[0, 0] = 1.0
    data = json.loads(json.dumps(G.to_dict(), allow_nan=False))
    assert set(data) == {"A", "B1", "B2", "C1", "C2", "D11", "D12", "D21", "D22", "tau"}
    assert "tau=[1.]" in repr(G)
    assert isinstance(as_delay_lti(control.tf([1.0], [1.0, 2.0])), DelayLTI)
    with pytest.raises(ParameterError, match="tau"):
        DelayLTI([[0.0]], [[1.0]], [[1.0]], [[1.0]], [[1.0]], [[0.0]], [[0.0]], [[0.0]], [[0.0]], [0.0])


block = st.tuples(st.floats(0.2, 3.0), st.floats(0.1, 2.0), st.floats(0.0, 1.5))  # gain k, pole a, delay h


@settings(max_examples=10, deadline=None)
@given(block, block, block, st.floats(0.05, 5.0))
def test_feedback_of_series_matches_direct_formula(b1: tuple, b2: tuple, b3: tuple, w: float) -> None:
    def sys(b: tuple) -> DelayLTI:
        k, a, h = b
        return delay(h) * tf([k], [1.0, a])

    def val(b: tuple, s: complex) -> complex:
        k, a, h = b
        return k * np.exp(-h * s) / (s + a)

    s = 1j * w
    G = sys(b1).series(sys(b2)).feedback(sys(b3))
    g = val(b1, s) * val(b2, s)
    exact = g / (1 + g * val(b3, s))
    # associativity of the LFT algebra: (b2 * b1) * b3 == b2 * (b1 * b3)
    left, right = (sys(b2) * sys(b1)) * sys(b3), sys(b2) * (sys(b1) * sys(b3))
    np.testing.assert_allclose(G(s), exact, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(left(s), right(s), rtol=1e-12, atol=1e-14)


def _lft_value(G: DelayLTI, s: complex) -> np.ndarray:
    """``P11 + P12 Delta (I - P22 Delta)^-1 P21`` with ``P = D + C (sI - A)^-1 B``, written out here."""
    n = G.A.shape[0]
    R = np.linalg.solve(s * np.eye(n) - G.A, np.hstack([G.B1, G.B2]))
    P = np.block([[G.D11, G.D12], [G.D21, G.D22]]) + np.vstack([G.C1, G.C2]) @ R
    p, m = G.D11.shape
    Delta = np.diag(np.exp(-np.asarray(G.tau) * s))
    P11, P12, P21, P22 = P[:p, :m], P[:p, m:], P[p:, :m], P[p:, m:]
    return P11 + P12 @ Delta @ np.linalg.solve(np.eye(Delta.shape[0]) - P22 @ Delta, P21)


@pytest.mark.parametrize("sign", [-1, 1])
def test_mimo_feedback_with_both_feedthroughs_against_the_lft(sign: int) -> None:
    rng = np.random.default_rng(7)

    def system(n: int, k: int) -> DelayLTI:
        A = -2.0 * np.eye(n) + 0.3 * rng.standard_normal((n, n))
        B1, B2, C1, C2, D11, D12, D21 = (
            0.5 * rng.standard_normal(shape) for shape in ((n, 2), (n, k), (2, n), (k, n), (2, 2), (2, k), (k, 2))
        )
        D22 = 0.2 * rng.standard_normal((k, k))
        return DelayLTI(A, B1, B2, C1, C2, D11, D12, D21, D22, rng.uniform(0.2, 1.5, k))

    G1, G2 = system(3, 2), system(2, 1)
    assert np.all(G1.D11 != 0) and np.all(G2.D11 != 0)
    closed = G1.feedback(G2, sign=sign)
    for s in S[1:]:
        g1, g2 = _lft_value(G1, s), _lft_value(G2, s)
        exact = np.linalg.solve(np.eye(2) - sign * g1 @ g2, g1)  # y = G1 (r + sign G2 y)
        # sums of a few dozen products of order-1 numbers, one 2 x 2 solve: 1e-12 leaves a wide margin
        np.testing.assert_allclose(closed(s), exact, rtol=1e-12, atol=1e-12)


def test_neutral_label_from_the_difference_operator() -> None:
    def channels(D22: list, tau: list) -> DelayLTI:
        k = len(tau)
        z = np.zeros
        return DelayLTI(
            z((0, 0)),
            z((0, 1)),
            z((0, k)),
            z((1, 0)),
            z((k, 0)),
            [[0.0]],
            z((1, k)),
            np.ones((k, 1)),
            np.array(D22, dtype=float),
            tau,
        )

    def trivial(G: DelayLTI) -> bool:  # det(I - D22 Delta(s)) == 1 at sample points, by numpy
        vals = [
            np.linalg.det(np.eye(len(G.tau)) - G.D22 @ np.diag(np.exp(-np.asarray(G.tau) * s)))
            for s in (0.3 + 1.7j, -0.4 + 0.2j, 1.1j)
        ]
        return bool(np.allclose(vals, 1.0, rtol=0.0, atol=1e-12))

    cases = [
        ([[1.0, 1.0], [-1.0, -1.0]], [1.0, 1.0]),  # nilpotent cycle, one delay: retarded
        ([[1.0, 1.0], [-1.0, -1.0]], [1.0, 2.0]),  # the same cycle, two delays: 1 - e^{-s} + e^{-2 s}
        ([[1.0, 1.0, 1.0], [-1.0, -1.0, -1.0], [1.0, 1.0, 0.0]], [1.0, 1.0, 2.5]),  # terms cancel by delay
        ([[1.0, 1.0, 1.0], [-1.0, -1.0, -1.0], [1.0, 1.0, 0.0]], [1.0, 2.0, 2.0]),
        ([[0.0, 1.0], [0.0, 0.0]], [1.0, 2.0]),  # no cycle
        ([[0.5]], [1.0]),
    ]
    labels = [channels(D22, tau).is_neutral for D22, tau in cases]
    assert labels == [False, True, False, True, False, True]
    assert labels == [not trivial(channels(D22, tau)) for D22, tau in cases]
    assert channels(*cases[0]).difference_operator() is None


def test_bad_indices_and_division_by_zero_name_the_parameter() -> None:
    G = tf([1.0], [1.0, 1.0])
    with pytest.raises(ParameterError, match=r"^key\[0\] \(output index\) must be an integer in \[-1, 0\]"):
        G[5, 0]
    with pytest.raises(ParameterError, match=r"^key\[1\] \(input index\) must be"):
        G[0, [0, 2]]
    with pytest.raises(ParameterError, match=r"^other must be a nonzero divisor"):
        G / 0
    np.testing.assert_allclose((G / 4)(S), 0.25 / (S + 1), rtol=TOL, atol=TOL)


def test_descriptor_statespace_of_index_one_becomes_a_delay_lti() -> None:
    """TDS-CONTROL's Example 2.9 closed loop (E singular, n = 6; algebraic variables feed their own delays): the
    realisation has 3 states and a D_22 that makes it neutral. Its resolvent against ``(s E - A_0 - A_1 e^{-s})^{-1}``
    (rounding, amplified by the conditioning of M near w = 0), its abscissa against the StateSpaceTDS route
    (the determinant of the characteristic matrix, an independent computation) and the manual's -0.2845, its
    chains against the difference operator ``1 - 0.0326 e^{-s}`` (C_D = ln 0.0326). A singular E was refused."""
    from _statespace_examples import example_2_9

    sys = example_2_9()
    L = DelayLTI.from_statespace_tds(sys)
    assert L.nstates == 3
    for w in (0.0, 0.7, 3.0, 11.0):
        s = 1j * w
        M = s * sys.E - sys.A[0] - sys.A[1] * np.exp(-s)
        inverse = np.linalg.inv(M)
        scale = np.max(np.abs(inverse))  # 6e-14 of it measured at w = 0
        np.testing.assert_allclose(L.frequency_response([w])[:, :, 0], inverse, rtol=0, atol=1e-12 * scale)
    sa = L.spectral_abscissa()
    reference = sys.abscissa((-1.0, 0.5, -10.0, 10.0))
    np.testing.assert_allclose(sa.value, reference.value, rtol=0, atol=1e-7)  # the reference's 2e-8, rounded up
    np.testing.assert_allclose(sa.value, -0.2845, atol=5e-5)  # the manual's 4 digits
    np.testing.assert_allclose(sa.chain_value, np.log(0.0326), rtol=1e-3)


def test_descriptor_with_a_neutral_term_or_higher_index_is_refused() -> None:
    A0 = np.array([[-1.0, 1.0], [1.0, 0.0]])
    E = np.diag([1.0, 0.0])
    with pytest.raises(ParameterError, match="index one"):  # A_22 = 0: x_2 is not determined (index two)
        DelayLTI.from_statespace_tds(StateSpaceTDS([A0, 0.1 * np.eye(2)], [0.0, 1.0], E=E))
    with pytest.raises(ParameterError, match="neutral terms"):
        DelayLTI.from_statespace_tds(StateSpaceTDS([A0 - np.diag([0.0, 2.0])], [0.0], [0.2 * np.eye(2)], [1.0], E=E))
