"""Certified delay margins of n + m loops with the same delay on every actuator (any m).

Independent routes: the one-actuator certified margin (``|A| = |B|`` crossings), the
product structure of decoupled loops, certified root counts on both sides of the margin,
the determinant of the loop matrix against its compound (Cauchy-Binet) form, and the
simulated PDE.
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np
import pytest
from scipy.linalg import expm

from nrobust import CertificationError, count_roots
from nrobust.hyperbolic.nplusm import (
    NPlusMCharacteristic,
    NPlusMSystem,
    compound_characteristic,
    multi_actuator_delay_margin,
    multi_actuator_margin,
    nplusm_delay_margin,
)
from nrobust.hyperbolic.simulate import simulate_nplusm
from nrobust.margins.matrix import (
    GaugeRemainder,
    circle_crossings,
    compound_generator,
    compound_generator_of,
    compound_minors,
)

TWO_ONE = NPlusMSystem(
    [1.0, 0.5], [1.5], [[0.0, 0.0, 0.4], [0.0, 0.0, 0.3], [0.5, -0.4, 0.0]], [[0.6], [0.5]], [[0.5, 0.4]]
)
GAIN = [[-0.5, 0.0]]
# two independent 1 + 1 loops, and the same as one 2 + 2 system
ONE = NPlusMSystem([1.0], [1.0], [[0.0, 0.25], [0.2, 0.0]], [[0.8]], [[0.5]])
TWO = NPlusMSystem([0.5], [2.0], [[0.0, 0.25], [0.2, 0.0]], [[0.8]], [[0.5]])
BOTH = NPlusMSystem(
    [1.0, 0.5],
    [1.0, 2.0],
    [[0.0, 0.0, 0.25, 0.0], [0.0, 0.0, 0.0, 0.25], [0.2, 0.0, 0.0, 0.0], [0.0, 0.2, 0.0, 0.0]],
    [[0.8, 0.0], [0.0, 0.8]],
    [[0.5, 0.0], [0.0, 0.5]],
)
K_BOTH = [[-0.4, 0.0], [0.0, -0.4]]
# a fully coupled 2 + 2 loop
COUPLED = NPlusMSystem(
    [1.0, 0.5],
    [1.0, 2.0],
    0.5 * np.array([[0.0, 0.1, 0.5, 0.2], [0.1, 0.0, 0.2, -0.3], [0.4, 0.1, 0.0, 0.1], [0.2, 0.6, 0.1, 0.0]]),
    [[0.8, 0.1], [0.2, 0.7]],
    [[0.5, 0.2], [0.1, -0.4]],
)
K_COUPLED = [[-0.3, 0.0], [0.0, 0.2]]


def test_compound_generator_is_the_exterior_power() -> None:
    """exp(D_m(A)) holds the m x m minors of exp(A) (Cauchy-Binet), for m = 1, 2, 3."""
    rng = np.random.default_rng(0)
    A = rng.normal(size=(4, 4)) * 0.5
    G = expm(A)
    for m in (1, 2, 3):
        minors = np.array([compound_minors(G[:, list(T)], axis=0) for T in itertools.combinations(range(4), m)]).T
        np.testing.assert_allclose(expm(compound_generator(A, m)), minors, atol=1e-12)


@pytest.mark.parametrize("system, K, delta", [(TWO_ONE, GAIN, 0.7), (COUPLED, K_BOTH, 0.4), (BOTH, K_BOTH, 1.3)])
def test_compound_form_is_the_determinant(system: NPlusMSystem, K: list, delta: float) -> None:
    """The compound form equals det of the loop matrix, its derivative too, and its bounds hold."""
    F, C = NPlusMCharacteristic(system, K, delta), compound_characteristic(system, K, delta)
    s = np.array([0.3 + 2j, -0.4 + 7j, 2.5 - 11j, 6.0 + 0.5j])
    np.testing.assert_allclose(C(s), F(s), rtol=1e-10)
    np.testing.assert_allclose(C.deriv_at(s), F.deriv_at(s), rtol=1e-9)
    a = np.array([0.1 + 1j, 3.0 - 4j, 8.0 + 2j])
    pts = a[:, None] + 0.5 * np.linspace(0.0, 1.0, 21)[None, :]
    d1 = np.abs(C.deriv_at(pts.ravel())).reshape(pts.shape).max(axis=1)
    assert np.all(d1 <= C.deriv_bound(a, a + 0.5))


def test_gauge_remainder_on_the_compound_transition() -> None:
    """||exp(D - s P) - exp(D_d - s P)|| <= r(|s|) on the axis and in Re s > 0 (P >= 0 in compound form)."""
    from nrobust.hyperbolic.nplusm.compound import compound_loop

    dc, p, _, _ = compound_loop(COUPLED, np.array(K_BOTH))
    assert np.all(p >= 0)
    rem = GaugeRemainder(dc, p)
    rng = np.random.default_rng(5)
    mods = rem.floor * 1.01 + rng.uniform(0.0, 100.0, 40)
    s = mods * np.exp(1j * rng.uniform(-np.pi / 2, np.pi / 2, 40))
    s[:15] = 1j * mods[:15]
    diff = [np.linalg.norm(expm(dc - x * np.diag(p)) - expm(rem.c_d - x * np.diag(p)), 2) for x in s]
    assert np.all(np.array(diff) <= rem(np.abs(s)))


def _closed(w: np.ndarray, c1: float) -> np.ndarray:
    return np.stack([1.0 + 0.3 * np.exp(-1j * w), np.full(w.shape, c1, dtype=complex)], axis=1)


def _jet(w: np.ndarray, c1: float) -> tuple[np.ndarray, np.ndarray]:
    return _closed(w, c1), np.stack([-0.3j * np.exp(-1j * w), np.zeros(w.shape, dtype=complex)], axis=1)


def test_circle_crossings_closed_form_and_tangency() -> None:
    """f(w, z) = 1 + 0.3 e^{-i w} + 0.9 z: zeros where |1 + 0.3 e^{-i w}| = 0.9, cos w = -0.28/0.6;
    with 0.7 instead of 0.9 the circle is only touched (at w = pi): the search refuses."""
    bounds = [[1.3, 0.9], [0.3, 0.0], [0.3, 0.0]]

    def level(w: np.ndarray) -> np.ndarray:
        return np.full(w.shape, 1e-15)

    zeros = circle_crossings(lambda w: _closed(w, 0.9), lambda w: _jet(w, 0.9), 6.0, bounds, level, step=0.2)
    w0 = np.arccos(-0.28 / 0.6)
    np.testing.assert_allclose([z[0] for z in zeros], [w0, 2 * np.pi - w0], rtol=1e-12)
    for w, phi in zeros:
        assert abs(1 + 0.3 * np.exp(-1j * w) + 0.9 * np.exp(1j * phi)) < 1e-12
    touch = [[1.3, 0.7], [0.3, 0.0], [0.3, 0.0]]
    with pytest.raises(CertificationError, match="tangency"):
        circle_crossings(lambda w: _closed(w, 0.7), lambda w: _jet(w, 0.7), 6.0, touch, level, step=0.2)
    with pytest.raises(CertificationError, match="max_points"):
        circle_crossings(lambda w: _closed(w, 0.9), lambda w: _jet(w, 0.9), 6.0, bounds, level, step=0.2, max_points=40)


@pytest.mark.slow
def test_one_actuator_through_the_matrix_path() -> None:
    """m = 1: the compound search reproduces the certified |A| = |B| margin (measured difference 1e-15)."""
    scalar = nplusm_delay_margin(TWO_ONE, GAIN)
    matrix = multi_actuator_delay_margin(TWO_ONE, GAIN)
    assert scalar.certified and matrix.certified and matrix.nominal_unstable == 0
    np.testing.assert_allclose(matrix.margin, scalar.margin, rtol=1e-8)
    assert matrix.omega is not None and scalar.omega is not None
    np.testing.assert_allclose(matrix.omega, scalar.omega, rtol=1e-8)
    np.testing.assert_allclose(matrix.gamma_0, scalar.gamma_0, rtol=1e-9)
    assert matrix.frequency_bound == pytest.approx(scalar.frequency_bound, rel=1e-6)


@pytest.mark.slow
def test_decoupled_two_actuators_is_the_smaller_margin() -> None:
    """Two independent loops as one 2 + 2 system: the certified margin is the smaller of the
    two certified one-actuator margins (measured 10.5978 and 7.1119; difference 1e-15), and both
    crossings are found."""
    one, two = nplusm_delay_margin(ONE, [[-0.4]]), nplusm_delay_margin(TWO, [[-0.4]])
    both = multi_actuator_delay_margin(BOTH, K_BOTH)
    assert one.certified and two.certified and both.certified and both.nominal_unstable == 0
    np.testing.assert_allclose(both.margin, min(one.margin, two.margin), rtol=1e-8)
    expected = sorted(one.crossings + two.crossings)
    assert len(both.crossings) == len(expected)
    np.testing.assert_allclose(np.array(both.crossings), np.array(expected), rtol=1e-8)


@pytest.mark.slow
def test_coupled_two_actuators_counts_and_simulation() -> None:
    """A fully coupled 2 + 2 loop (certified margin 14.0506 at w = 0.1509, measured): F(i w*; margin) = 0,
    no root in [0, W] x [-W, W] at 0.9 times the margin and a pair at 1.1 times (certified counts of
    the compound form), and the simulated PDE decays below the margin and grows above it (fitted
    rates -2.9e-3 and +1.3e-3 on [200, 400]; the crossing pair moves slowly)."""
    m = multi_actuator_delay_margin(COUPLED, K_COUPLED)
    assert m.certified and m.nominal_unstable == 0 and 0 < m.margin < np.inf and m.omega is not None
    F = NPlusMCharacteristic(COUPLED, K_COUPLED, m.margin)
    assert abs(complex(F(np.array([1j * m.omega]))[0])) < 1e-10
    W = m.frequency_bound
    box = (0.0, W, -W, W)
    counts = [int(count_roots(compound_characteristic(COUPLED, K_COUPLED, f * m.margin), box)) for f in (0.9, 1.1)]
    assert counts == [0, 2]

    def w0(x: np.ndarray) -> np.ndarray:
        return np.vstack([np.sin(np.pi * x) + 0.3, np.cos(2 * x), 1 + x * x, x])

    rates = [
        simulate_nplusm(COUPLED, K_COUPLED, f * m.margin, 400.0, w0, cells=20).growth_rate(200.0) for f in (0.9, 1.1)
    ]
    assert rates[0] < 0 < rates[1]


def test_multi_actuator_margin_without_omega_max_is_the_certified_route(monkeypatch: pytest.MonkeyPatch) -> None:
    """``omega_max`` is optional: without it ``multi_actuator_margin`` returns the certified margin."""
    import nrobust.hyperbolic.nplusm.margin as nplusm

    calls: list[tuple[tuple, dict]] = []

    def certified(*args: object, **kwargs: object) -> str:
        calls.append((args, kwargs))
        return "certified"

    monkeypatch.setattr(nplusm, "multi_actuator_delay_margin", certified)
    assert multi_actuator_margin(BOTH, K_BOTH, max_points=1234) == "certified"
    assert calls == [((BOTH, K_BOTH), {"max_points": 1234})]


def test_compound_generator_of_rationals_is_the_generator() -> None:
    """``compound_generator_of`` on exact rationals (``Fraction``) equals ``compound_generator`` of the same matrix
    (a float one with integer-ratio entries: both exact), entry by entry, skipping the zero entries."""
    rng = np.random.default_rng(7)
    for size, m in ((3, 1), (3, 2), (4, 2), (4, 3)):
        A = rng.integers(-4, 5, (size, size)) / 8.0
        A[rng.random((size, size)) < 0.3] = 0.0
        exact = [[Fraction(v) for v in row] for row in A]
        got = compound_generator_of(exact, A != 0, m, Fraction(0))
        want = compound_generator(A, m)
        assert np.array_equal(np.array(got, dtype=float), want.real) and not np.any(want.imag)
