"""Step response of a delayed loop: nrobust's method of steps vs python-control with Padé models.

The loop is unity feedback around ``k e^{-tau s} / (s + a)`` over 100 delay intervals, 1001
output times, for ``(a, k, tau) = (1, 1.5, 1)`` (slow plant: one piece per delay interval
meets every tolerance) and ``(8, 4, 2)`` (fast plant, ``a tau = 16``: the tolerance decides
the pieces). In LFT form, ``x' = -a x + k w``, ``w(t) = z(t - tau)``, ``z = r - x``, ``y = x``.

The exact reference is the method of steps in closed form, evaluated with mpmath at 40
digits: on ``[j tau, (j + 1) tau]``, ``x = alpha_j + e^{-a s} P_j(s)`` with
``alpha_j = k (1 - alpha_{j-1}) / a``, ``P_j' = -k P_{j-1}`` and ``P_j(0)`` from continuity.

Printed per method: the largest error against the reference, seconds (best of 3), and the
digits of accuracy bought per millisecond. python-control cannot represent the delay; it
simulates ``feedback(pade(tau, n) * k / (s + a), 1)``, whose error stops falling with ``n``
(the Padé model is a different system, and its high orders are ill-conditioned).

Run: ``python benchmarks/timeresp.py`` (needs python-control and mpmath).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import control
import mpmath as mp
import numpy as np

from nrobust.lti.delay_lti import DelayLTI
from nrobust.lti.timeresp import step_response

#: ``(a, k, tau)`` of the two loops.
CASES = ((1.0, 1.5, 1.0), (8.0, 4.0, 2.0))
INTERVALS = 100


def loop(a: float, k: float, tau: float) -> DelayLTI:
    one = np.ones((1, 1))
    return DelayLTI(-a * one, 0 * one, k * one, one, -one, 0 * one, 0 * one, one, 0 * one, np.array([tau]))


def exact(a_: float, k_: float, tau_: float, times: np.ndarray) -> np.ndarray:
    """The step response by the method of steps in closed form (mpmath, 40 digits)."""
    mp.mp.dps = 40
    a, k, tau = mp.mpf(a_), mp.mpf(k_), mp.mpf(tau_)

    def horner(coefs: list[Any], s: Any) -> Any:
        out = mp.mpf(0)
        for c in reversed(coefs):
            out = out * s + c
        return out

    alphas, polys = [mp.mpf(0)], [[mp.mpf(0)]]
    for _ in range(int(max(times) / tau_) + 1):
        q = polys[-1]
        alpha = k * (1 - alphas[-1]) / a
        p = [mp.mpf(0)] + [-k * q[i] / (i + 1) for i in range(len(q))]
        p[0] = alphas[-1] + mp.exp(-a * tau) * horner(q, tau) - alpha
        alphas.append(alpha)
        polys.append(p)
    out = np.empty(times.size)
    for n, t in enumerate(times):
        j = int(mp.floor(mp.mpf(t) / tau))
        s = mp.mpf(t) - j * tau
        out[n] = float(alphas[j] + mp.exp(-a * s) * horner(polys[j], s))
    return out


def best_of(run: Callable[[], np.ndarray], repeat: int = 3) -> tuple[np.ndarray, float]:
    best, out = np.inf, np.empty(0)
    for _ in range(repeat):
        start = time.perf_counter()
        out = run()
        best = min(best, time.perf_counter() - start)
    return out, best


def compare(a: float, k: float, tau: float) -> None:
    t_end = INTERVALS * tau
    t = np.linspace(0.0, t_end, 1001)
    reference = exact(a, k, tau, t)
    system = loop(a, k, tau)
    rows = []
    for rtol in (1e-4, 1e-7, 1e-10, 1e-13):

        def ours(rtol: float = rtol) -> np.ndarray:
            return np.asarray(step_response(system, t, rtol=rtol, atol=0.0).outputs)

        y, seconds = best_of(ours)
        rows.append((f"nrobust rtol={rtol:.0e}", float(np.abs(y - reference).max()), seconds))
    plant = control.tf([k], [1.0, a])
    for order in (1, 2, 3, 5, 8, 12):
        num, den = control.pade(tau, order)
        closed = control.ss(control.feedback(control.tf(num, den) * plant, 1))

        def theirs(closed: Any = closed) -> np.ndarray:
            return np.asarray(control.step_response(closed, t).outputs)

        y, seconds = best_of(theirs)
        rows.append((f"python-control pade n={order}", float(np.abs(y - reference).max()), seconds))
    print(f"\nstep response of {k:g} e^(-{tau:g} s)/(s + {a:g}) in unity feedback on [0, {t_end:g}]")
    print(f"{'method':<32} {'max error':>10} {'seconds':>9} {'digits/ms':>10}")
    for name, error, seconds in rows:
        digits = -np.log10(max(error, 1e-17))
        print(f"{name:<32} {error:10.2e} {seconds:9.4f} {digits / (1e3 * seconds):10.2f}")


def main() -> None:
    step_response(loop(*CASES[0]), [0.0, 1.0])  # imports python-control once, outside the timings
    for case in CASES:
        compare(*case)


if __name__ == "__main__":
    main()
