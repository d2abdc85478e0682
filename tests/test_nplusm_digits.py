"""The n + m cancellation table prints its abscissae and delay margins to their accuracy.

Oracles independent of the code checked: the closed form ``ln|(R + K) Q| / (1/lam + 1/mu)`` of an
uncoupled ``1 + 1`` loop, and the crossing of ``A + B e^{-delta s}`` re-solved with mpmath at 40
digits on the stored matrices (``A(i w)``, ``B(i w)`` from ``mp.expm``).
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest

from nrobust._digits import with_accuracy
from nrobust.errors import ParameterError
from nrobust.hyperbolic.nplusm import (
    NPlusMCharacteristic,
    NPlusMSystem,
    backstepping_exact_margin,
    cancellation_study,
    multi_actuator_delay_margin,
    nplusm_delay_margin,
)
from nrobust.hyperbolic.nplusm.margin import smallest_delay_error
from nrobust.reports.nplusm import _cells

COUPLED = NPlusMSystem(
    [1.0, 0.5], [1.0], [[-0.05, 0.02, 0.05], [0.1, -0.02, 0.1], [0.05, 0.02, -0.05]], [[0.9], [0.3]], [[0.6, 0.4]]
)
ONE_PLUS_ONE = NPlusMSystem([1.0], [1.0], [[0.0, 0.5], [0.4, 0.0]], [[0.8]], [[0.5]])


@pytest.fixture(autouse=True)
def _forty_digits():
    with mp.workdps(40):
        yield


def _crossing_40_digits(system: NPlusMSystem, K: np.ndarray, w0: float) -> tuple[mp.mpf, mp.mpf]:
    """``(w, delay)``: ``|A(i w)| = |B(i w)|`` and ``(arg(-B/A) mod 2 pi) / w`` in mpmath."""
    F = NPlusMCharacteristic(system, K, 0.0)
    C, w = mp.matrix(F._c.tolist()), mp.matrix([mp.mpf(float(x)) for x in F._w[:, 0]])
    p = [mp.mpf(float(x)) for x in F._p[0]]
    ell_a = [-mp.mpf(float(x)) for x in system.r[0]] + [mp.mpf(1)]
    ell_b = [-mp.mpf(float(x)) for x in K[0]] + [mp.mpf(0)]

    def factors(x):
        col = mp.expm(C - 1j * x * mp.diag(p)) * w
        return mp.fsum(ell_a[i] * col[i] for i in range(len(p))), mp.fsum(ell_b[i] * col[i] for i in range(len(p)))

    a, _ = F.factors(np.array([1j * w0]))
    assert abs(complex(factors(mp.mpf(w0))[0]) - a[0]) < 1e-12 * abs(a[0])  # the same loop
    x = mp.findroot(lambda x: abs(factors(x)[0]) ** 2 - abs(factors(x)[1]) ** 2, mp.mpf(w0), tol=mp.mpf(10) ** -35)
    A, B = factors(x)
    return x, (mp.arg(-B / A) % (2 * mp.pi)) / x


def _true_to_printed_digits(text: str, truth) -> None:
    printed, bound = text.split(" +- ")
    assert abs(mp.mpf(printed) - truth) <= 1.5 * mp.mpf(bound), (text, truth)


@pytest.mark.parametrize(
    ("system", "K"),
    [(COUPLED, [[0.0, -0.4]]), (COUPLED, [[-0.18, -0.24]]), (ONE_PLUS_ONE, [[-0.25]]), (ONE_PLUS_ONE, [[-0.4]])],
)
def test_static_margin_within_its_accuracy(system: NPlusMSystem, K) -> None:
    K = np.array(K, dtype=float)
    m = nplusm_delay_margin(system, K)
    assert m.omega is not None and m.accuracy == m.error
    w, delay = _crossing_40_digits(system, K, m.omega)
    error = float(abs(delay - m.margin))
    assert error <= m.accuracy <= max(1e-10, 1e4 * max(error, 1e-14)), (error, m.accuracy)
    _true_to_printed_digits(with_accuracy(m.margin, m.accuracy), delay)
    # the crossing frequency: measured errors 4e-17 to 1.8e-15, at most 0.12 of the unscaled Newton step
    # (_OMEGA_SAFETY = 16), estimates 2.5e-13 to 2.9e-13
    omega_error = float(abs(w - m.omega))
    assert m.omega_accuracy is not None and omega_error <= m.omega_accuracy <= 1e-11, (omega_error, m.omega_accuracy)
    _true_to_printed_digits(with_accuracy(m.omega, m.omega_accuracy), w)
    assert f"omega={with_accuracy(m.omega, m.omega_accuracy)}," in repr(m) and "not estimated" not in repr(m)


def test_structural_margins_are_exact() -> None:
    m = nplusm_delay_margin(COUPLED, np.array([[-0.6, -0.4]]))  # full cancellation: gamma_0 = 1.2 > 1
    assert m.margin == 0.0 and m.accuracy == 0.0


def test_table_prints_abscissa_and_margin_to_their_accuracy() -> None:
    uncoupled = NPlusMSystem([1.0], [2.0], [[0.0, 0.0], [0.0, 0.0]], [[0.8]], [[0.5]])
    (row,) = cancellation_study(uncoupled, [[0.5]], (-2.0, 1.0, -0.25, 6.0))
    truth = mp.log(mp.mpf("0.25") * mp.mpf("0.8")) / (1 + mp.mpf("0.5"))  # ln|(R + K) Q| / (1/lam + 1/mu)
    cells = _cells(row)
    assert cells[3] == with_accuracy(row.abscissa, row.abscissa_accuracy)
    _true_to_printed_digits(cells[3], truth)
    (row,) = cancellation_study(ONE_PLUS_ONE, [[0.5]], (-2.0, 1.0, -0.25, 6.0))
    _, delay = _crossing_40_digits(ONE_PLUS_ONE, np.array([row.gain]), row.margin.omega)
    cells = _cells(row)
    assert cells[4] == with_accuracy(row.margin.margin, row.margin.accuracy)
    _true_to_printed_digits(cells[4], delay)


# --- the compound-form margins (any m, and the backstepping law) -------------------------------------------------

TWO_ONE = NPlusMSystem(
    [1.0, 0.5], [1.5], [[0.0, 0.0, 0.4], [0.0, 0.0, 0.3], [0.5, -0.4, 0.0]], [[0.6], [0.5]], [[0.5, 0.4]]
)
TWO_TWO = NPlusMSystem(
    [1.0, 0.5],
    [1.0, 2.0],
    0.5 * np.array([[0.0, 0.1, 0.5, 0.2], [0.1, 0.0, 0.2, -0.3], [0.4, 0.1, 0.0, 0.1], [0.2, 0.6, 0.1, 0.0]]),
    [[0.8, 0.1], [0.2, 0.7]],
    [[0.5, 0.2], [0.1, -0.4]],
)
# two independent 1 + 1 loops as one 2 + 2 system, the second gain tuned (bisection of the second loop's certified
# margin) so that both loops' first crossing delays agree to 1e-14: two crossings compete for the smallest delay
DECOUPLED = NPlusMSystem(
    [1.0, 0.5],
    [1.0, 2.0],
    [[0.0, 0.0, 0.25, 0.0], [0.0, 0.0, 0.0, 0.25], [0.2, 0.0, 0.0, 0.0], [0.0, 0.2, 0.0, 0.0]],
    [[0.8, 0.0], [0.0, 0.8]],
    [[0.5, 0.0], [0.0, 0.5]],
)
TIED = [[-0.4, 0.0], [0.0, -0.326679118998461]]
# the 2x2 plant Hyperbolic2x2(1.0, 1.5, 1.2, 0.8, 1.0, 0.4) as a 1 + 1 system, and two actuators of one speed
BS_PLANT = NPlusMSystem([1.0], [1.5], [[0.0, 1.2], [0.8, 0.0]], [[1.0]], [[0.4]])
ONE_GROUP = NPlusMSystem(
    [1.0], [1.5, 1.5], [[0.0, 0.3, 0.2], [0.4, 0.0, 0.1], [0.2, 0.3, 0.0]], [[0.5, 0.2]], [[0.3], [0.1]]
)


def _mp_loop(system: NPlusMSystem, K, backstepping: bool):
    """``(s, delta) -> det M(s; delta)`` at 40 digits, from the PDE's data: ``M = E (Phi_v - (R + K e^{-delta s})
    Phi_u)``, ``[Phi_u; Phi_v] = exp(Lambda^{-1} (Sigma - s I)) [Q; I]``, ``E = diag(e^{-s/mu_j})``; for the
    backstepping law with exact kernels (one leftward speed) ``M_0 + e^{-delta s} (V - M_0)``, ``M_0`` the open
    loop and ``V = exp(-Sigma--/mu)`` (the target system's boundary value, Hu et al. 2016)."""
    n, m = system.n, system.m
    lam = [mp.mpf(float(x)) for x in system.lam]
    mu = [mp.mpf(float(x)) for x in system.mu]
    speeds = lam + [-x for x in mu]
    sigma = mp.matrix(system.sigma.tolist())
    w0 = mp.matrix([[float(x) for x in system.q[i]] for i in range(n)] + np.eye(m).tolist())
    r = mp.matrix(system.r.tolist())
    gain = None if backstepping else mp.matrix(np.asarray(K, dtype=float).tolist())
    v = mp.expm(-mp.matrix([[sigma[n + i, n + j] for j in range(m)] for i in range(m)]) / mu[0])

    def det(s, delta):
        a = mp.matrix(n + m, n + m)
        for i in range(n + m):
            for j in range(n + m):
                a[i, j] = (sigma[i, j] - (s if i == j else 0)) / speeds[i]
        phi = mp.expm(a) * w0
        phi_u = mp.matrix([[phi[i, j] for j in range(m)] for i in range(n)])
        phi_v = mp.matrix([[phi[n + i, j] for j in range(m)] for i in range(m)])
        e = mp.diag([mp.exp(-s / x) for x in mu])
        z = mp.exp(-delta * s)
        if backstepping:
            m0 = e * (phi_v - r * phi_u)
            return mp.det(m0 + z * (v - m0))
        return mp.det(e * (phi_v - (r + z * gain) * phi_u))

    return det


def _mp_crossing_delay(det, w0: float, delay0: float) -> tuple[mp.mpf, mp.mpf]:
    """The crossing ``det M(i w; delay) = 0`` near ``(w0, delay0)``, Newton's method on the real and imaginary parts."""

    def parts(w, delay):
        value = det(mp.mpc(0, w), delay)
        return [value.real, value.imag]

    w, delay = mp.findroot(parts, (mp.mpf(w0), mp.mpf(delay0)), tol=mp.mpf(10) ** -30)
    return w, delay


@pytest.mark.parametrize(
    ("system", "K"),
    [
        (TWO_ONE, [[-0.5, 0.0]]),
        (TWO_TWO, [[-0.3, 0.0], [0.0, 0.2]]),
        (DECOUPLED, TIED),
        (BS_PLANT, None),
        (ONE_GROUP, None),
    ],
    ids=["2+1", "2+2", "2+2 tied", "backstepping 1+1", "backstepping 1+2"],
)
def test_compound_margin_within_its_accuracy(system: NPlusMSystem, K) -> None:
    """The certified margins of the compound form (:func:`multi_actuator_delay_margin`, and
    :func:`backstepping_exact_margin` for ``K = None``) carry an error that holds the true smallest crossing delay
    (every crossing re-solved at 40 digits; measured errors 3e-16 to 1.6e-13, estimates 3e-12 to 1.4e-9) and is not
    looser than 1e4 times the true error or ``1e-9`` relative; the repr prints the margin to it. In the tied
    case the two loops' first delays agree to 1e-12, so either may be the smallest: the error covers both."""
    m = backstepping_exact_margin(system) if K is None else multi_actuator_delay_margin(system, K)
    assert m.certified and m.nominal_unstable == 0 and m.error is not None and m.accuracy == m.error
    det = _mp_loop(system, K, K is None)
    solved = [_mp_crossing_delay(det, w, d) for w, d in m.crossings]
    delays = [d for _, d in solved]
    truth = min(delays)
    error = float(abs(truth - m.margin))
    assert error <= m.accuracy <= max(1e-9 * max(1.0, m.margin), 1e4 * max(error, 1e-14)), (error, m.accuracy)
    _true_to_printed_digits(with_accuracy(m.margin, m.accuracy), truth)
    assert f"margin={with_accuracy(m.margin, m.accuracy)}," in repr(m)
    # the crossing frequency of every crossing that may be the smallest lies within omega_accuracy (measured errors
    # 2e-16 to 6e-15, at most 0.13 of the unscaled Newton step; in the tied case both crossings' frequencies)
    assert m.omega is not None and m.omega_accuracy is not None
    contenders = [w for w, d in solved if d - truth <= 2.0 * m.accuracy]
    assert all(abs(float(w) - m.omega) <= m.omega_accuracy for w in contenders)
    if K is not TIED:
        assert m.omega_accuracy <= 1e-10
    _true_to_printed_digits(with_accuracy(m.omega, m.omega_accuracy), min(solved, key=lambda c: c[1])[0])
    assert f"omega={with_accuracy(m.omega, m.omega_accuracy)}," in repr(m)
    if K is TIED:
        assert len(delays) == 2 and abs(delays[0] - delays[1]) < 1e-12


def test_the_smallest_delay_error_covers_the_competition() -> None:
    """Closed forms: the true smallest of delays ``d_i +- e_i`` lies in ``[min (d_i - e_i), min (d_i + e_i)]``."""
    assert smallest_delay_error([1.0, 2.0], [0.125, 0.125]) == 0.125  # the other is too far to compete
    assert smallest_delay_error([1.0, 1.25], [0.125, 0.5]) == 0.25  # the second may be down at 0.75
    assert smallest_delay_error([1.25, 1.0], [0.5, 0.125]) == 0.25  # in either order
    assert smallest_delay_error([1.0, 1.25], [0.5, 0.125]) == 0.5  # the smallest's own error dominates
    assert smallest_delay_error([1.0, 3.0], [0.0, None]) is None  # an unknown error may hide a smaller delay
    with pytest.raises(ParameterError) as info:
        smallest_delay_error([1.0, 2.0], [0.1])
    assert info.value.name == "errors"


def test_an_infinite_margin_is_exact() -> None:
    """No crossing: the margin ``inf`` is exact (``inf - inf`` gave an accuracy ``nan``), alone, among other
    infinite margins, and for a design whose every margin is infinite (``|r q| < 1`` with ``|B| < |A|`` on the
    axis: ``K`` small on the 1 + 1 plant below)."""
    from nrobust.hyperbolic.nplusm import design_nplusm_gains

    assert smallest_delay_error([np.inf], [0.0]) == 0.0
    assert smallest_delay_error([np.inf, np.inf], [0.0, 0.0]) == 0.0
    assert smallest_delay_error([np.inf, 2.0], [0.0, 0.25]) == 0.25
    system = NPlusMSystem([1.0], [1.0], [[0.0, 0.3], [0.2, 0.0]], [[-1.0]], [[0.5]])
    design = design_nplusm_gains(system, "margin", K_bounds=(-0.4, 0.4), x0=[[0.1]], starts=1)
    assert design.value == np.inf and design.accuracy == 0.0
