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
from nrobust.hyperbolic.nplusm import NPlusMCharacteristic, NPlusMSystem, cancellation_study, nplusm_delay_margin
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
    _, delay = _crossing_40_digits(system, K, m.omega)
    error = float(abs(delay - m.margin))
    assert error <= m.accuracy <= max(1e-10, 1e4 * max(error, 1e-14)), (error, m.accuracy)
    _true_to_printed_digits(with_accuracy(m.margin, m.accuracy), delay)


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
