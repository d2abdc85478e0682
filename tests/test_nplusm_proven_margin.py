"""The one-actuator n + m delay margin proven in ball arithmetic (``nplusm_delay_margin(..., rigorous=True)``).

Oracle sharing no code with the proof: the transition ``Phi(s) = exp(Lambda^{-1} (Sigma - s I))`` of the
Laplace-domain system built here from the plant's parameters (no shift ``e^{-s/mu}``, no rate matrix
``P``), ``A = [-R, 1] Phi [Q; 1]``, ``B = [-K, 0] Phi [Q; 1]``, by ``mpmath.expm`` at 40 digits; the
crossing ``|A(i w)| = |B(i w)|`` by ``findroot`` and its first delay ``(arg(-B/A) mod 2 pi) / w``.
"""

from __future__ import annotations

import numpy as np
import pytest

from nrobust._digits import with_accuracy
from nrobust.errors import CertificationError, ParameterError
from nrobust.hyperbolic.nplusm import (
    NPlusMCharacteristic,
    NPlusMSystem,
    cancellation_study,
    nplusm_delay_margin,
    proven_axis_crossings,
)

mp = pytest.importorskip("mpmath")
pytest.importorskip("flint")

COUPLED = NPlusMSystem(
    [1.0, 0.5], [1.0], [[-0.05, 0.02, 0.05], [0.1, -0.02, 0.1], [0.05, 0.02, -0.05]], [[0.9], [0.3]], [[0.6, 0.4]]
)
ONE_PLUS_ONE = NPlusMSystem([1.0], [1.0], [[0.0, 0.5], [0.4, 0.0]], [[0.8]], [[0.5]])
# |A(i w)|^2 / |B(i w)|^2 at K = 1 has a local minimum 0.7307483213944262^2 at w = 3.2135: with this gain
# |A|^2 - |B|^2 touches 0 there (a tangency), found by minimising the ratio in floating point.
TANGENT = -0.7307483213944262


def _factors(system: NPlusMSystem, K, s):
    """``(A(s), B(s))`` at 40 digits from ``exp(Lambda^{-1} (Sigma - s I))``."""
    n = system.n
    speeds = [mp.mpf(float(v)) for v in system.lam] + [-mp.mpf(float(v)) for v in system.mu]
    size = n + 1
    sigma = [[mp.mpf(float(system.sigma[i, j])) for j in range(size)] for i in range(size)]
    M = mp.matrix([[(sigma[i][j] - (s if i == j else 0)) / speeds[i] for j in range(size)] for i in range(size)])
    col = mp.expm(M) * mp.matrix([mp.mpf(float(x)) for x in system.q[:, 0]] + [mp.mpf(1)])
    a = mp.fsum(-mp.mpf(float(system.r[0, i])) * col[i] for i in range(n)) + col[n]
    b = mp.fsum(-mp.mpf(float(K[0][i])) * col[i] for i in range(n))
    return a, b


def _crossing(system: NPlusMSystem, K, w0: float):
    """``(w, delay)`` of the crossing near ``w0``, 40 digits."""
    with mp.workdps(40):

        def g(x):
            a, b = _factors(system, K, mp.mpc(0, x))
            return abs(a) ** 2 - abs(b) ** 2

        w = mp.findroot(g, mp.mpf(w0), tol=mp.mpf(10) ** -35)
        a, b = _factors(system, K, mp.mpc(0, w))
        return w, (mp.arg(-b / a) % (2 * mp.pi)) / w


@pytest.mark.parametrize(("system", "K"), [(COUPLED, [[0.0, -0.4]]), (ONE_PLUS_ONE, [[-0.25]])])
def test_proven_ball_holds_the_margin_and_its_crossing(system: NPlusMSystem, K) -> None:
    proven = nplusm_delay_margin(system, np.array(K), rigorous=True)
    assert proven.rigorous and proven.certified and proven.nominal_unstable == 0 and len(proven.crossings) == 1
    assert "proven in ball arithmetic" in proven.scope and "PDE itself" in proven.scope
    assert proven.margin_bracket is not None and proven.omega_bracket is not None and proven.omega is not None
    w, delay = _crossing(system, K, proven.omega)
    lo, hi = proven.margin_bracket
    w_lo, w_hi = proven.omega_bracket
    assert lo <= delay <= hi and w_lo <= w <= w_hi, (proven.margin_bracket, delay, proven.omega_bracket, w)
    assert hi - lo < 1e-9 and w_hi - w_lo < 1e-9
    assert lo <= proven.margin <= hi and w_lo <= proven.omega <= w_hi
    float_margin = nplusm_delay_margin(system, np.array(K)).margin
    assert lo <= float_margin <= hi
    # every printed digit true: the value printed to its proven accuracy is within it of the truth
    for value, accuracy, truth in ((proven.margin, proven.accuracy, delay), (proven.omega, proven.omega_accuracy, w)):
        printed, bound = with_accuracy(value, accuracy).split(" +- ")
        assert abs(mp.mpf(printed) - truth) <= 1.5 * mp.mpf(bound)
        assert printed in repr(proven)


def test_near_tangency_every_crossing_enclosed() -> None:
    """The tangency split into two crossings 2e-5 apart, plus the first one: each proven enclosure holds the
    oracle's crossing and delay, with the oracle's sign of ``g'``."""
    K = [[TANGENT * (1.0 + 1e-9)]]
    proven = nplusm_delay_margin(ONE_PLUS_ONE, np.array(K), rigorous=True)
    assert len(proven.crossings) == 3 and proven.margin_bracket is not None
    F = NPlusMCharacteristic(ONE_PLUS_ONE, np.array(K))
    found, _ = proven_axis_crossings(F.ball_function(), proven.frequency_bound)
    delays = []
    with mp.workdps(40):
        for c in found:
            w, delay = _crossing(ONE_PLUS_ONE, K, 0.5 * (c.omega[0] + c.omega[1]))
            assert c.omega[0] <= w <= c.omega[1] and c.delay[0] <= delay <= c.delay[1], (c, w, delay)
            slope = mp.diff(
                lambda x: (
                    abs(_factors(ONE_PLUS_ONE, K, mp.mpc(0, x))[0]) ** 2
                    - abs(_factors(ONE_PLUS_ONE, K, mp.mpc(0, x))[1]) ** 2
                ),
                w,
            )
            assert c.slope == (1 if slope > 0 else -1)
            delays.append(delay)
    assert [c.slope for c in found] == [1, -1, 1]  # g < 0 between the two split crossings
    lo, hi = proven.margin_bracket
    assert lo <= min(delays) <= hi


def test_a_tangency_is_refused() -> None:
    with pytest.raises(CertificationError, match="tangency"):
        nplusm_delay_margin(ONE_PLUS_ONE, np.array([[TANGENT]]), rigorous=True)


def test_unstable_without_delay_has_margin_zero() -> None:
    K = [[-TANGENT]]
    with mp.workdps(40):  # F(s) = A(s) + B(s) at delta = 0, real on the real axis: a sign change on [0, 5]
        f0, f5 = (sum(_factors(ONE_PLUS_ONE, K, mp.mpf(x))).real for x in (0, 5))
    assert f0 * f5 < 0
    proven = nplusm_delay_margin(ONE_PLUS_ONE, np.array(K), rigorous=True)
    assert proven.margin == 0.0 and proven.accuracy == 0.0 and proven.nominal_unstable == 1 and proven.rigorous


def test_rigorous_refusals_and_bad_input() -> None:
    with pytest.raises(CertificationError, match="gamma_0"):  # full cancellation: gamma_0 = 1.2
        nplusm_delay_margin(COUPLED, np.array([[-0.6, -0.4]]), rigorous=True)
    with pytest.raises(ParameterError, match="rigorous"):
        nplusm_delay_margin(COUPLED, np.array([[0.0, -0.4]]), rigorous="yes")  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="prec"):
        nplusm_delay_margin(COUPLED, np.array([[0.0, -0.4]]), rigorous=True, prec=8)
    with pytest.raises(ParameterError, match="rigorous"):
        cancellation_study(ONE_PLUS_ONE, [[0.5]], (-2.0, 1.0, -0.25, 6.0), rigorous=1)  # type: ignore[arg-type]


NPLUSM_FILE = """
[system]
type = "NPlusMSystem"
lam = [1.0]
mu = [1.0]
sigma = [[0.0, 0.5], [0.4, 0.0]]
q = [[0.8]]
r = [[0.5]]

[controller]
type = "Cancellation"
fractions = [[0.5], [3.0]]

[analysis]
region = [-2.0, 1.0, -0.25, 6.0]
"""


def test_analyze_proves_the_study(tmp_path) -> None:
    """``nrobust analyze --rigorous`` on an n + m file: the study's margins proven (``K = -0.25``: the
    cancellation 0.5 of ``R = 0.5``), against the oracle; the gain ``-3 R`` (``gamma_0 = |R Q| + |K Q| = 1.6``)
    keeps the floating-point margin 0, and the report says which is which."""
    import json

    from nrobust.reports.analyze import run_analyze

    path = tmp_path / "plant.toml"
    path.write_text(NPLUSM_FILE, encoding="utf-8")
    files, _ = run_analyze(path, tmp_path / "out", progress=False, rigorous=True)
    cases = json.loads(files.json[0].read_text(encoding="utf-8"))["cases"]
    half, full = cases
    assert half["rigorous"] and half["margin"]["rigorous"] and not full["margin"]["rigorous"]
    assert full["margin"]["margin"] == 0.0 and full["gamma_0"] > 1.0
    lo, hi = half["margin"]["margin_bracket"]
    _, delay = _crossing(ONE_PLUS_ONE, [[-0.25]], half["margin"]["omega"])
    assert lo <= delay <= hi and hi - lo < 1e-9
    assert "**Proven:** in ball arithmetic for the PDE itself" in files.markdown.read_text(encoding="utf-8")


def test_no_gain_no_crossing() -> None:
    """``K = 0``: ``B = 0``, so ``|A| = |B|`` only at a root of the stable open loop on the axis: never."""
    proven = nplusm_delay_margin(COUPLED, np.zeros((1, 2)), rigorous=True)
    assert proven.margin == np.inf and proven.accuracy == 0.0 and proven.rigorous and not proven.crossings


def test_the_least_delay_over_every_crossing_and_branch() -> None:
    """A loop with two crossings whose least delay is at the second, its phase in ``(pi, 2 pi)``: the oracle scans
    ``|A|^2 - |B|^2`` on ``[0, 60]`` (scipy's ``expm`` at 4,001 frequencies, far below the proof's frequency bound's
    share of the crossings), refines each sign change by ``findroot`` at 40 digits and takes the least delay; the
    proof finds the same crossings and its ball holds that least delay (measured 1.2916275117253338)."""
    from scipy.linalg import expm

    system = NPlusMSystem([1.0], [1.0], [[0.0, 3.0], [-1.0, 0.0]], [[1.0]], [[-0.5]])
    K = [[0.45]]

    def g(w: float) -> float:
        M = np.array([[-1j * w, 3.0], [1.0, 1j * w]])  # Lambda^{-1} (Sigma - i w I), Lambda = diag(1, -1)
        col = expm(M) @ np.array([1.0, 1.0])
        return abs(col[1] + 0.5 * col[0]) ** 2 - abs(0.45 * col[0]) ** 2

    ws = np.linspace(1e-3, 60.0, 4001)
    values = np.array([g(w) for w in ws])
    starts = ws[:-1][np.sign(values[:-1]) != np.sign(values[1:])]
    oracle = [_crossing(system, K, float(w0)) for w0 in starts]
    least = min(delay for _, delay in oracle)
    proven = nplusm_delay_margin(system, np.array(K), rigorous=True)
    assert len(proven.crossings) == len(oracle) == 2
    lo, hi = proven.margin_bracket
    assert lo <= least <= hi and hi - lo < 1e-9, (proven.margin_bracket, least)
