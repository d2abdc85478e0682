"""Delay LTI systems: exact margins and frequency responses against python-control's rational models.

(a) **Margins.** nrobust's ``allmargin`` on loops with a dead time (exact: every crossing on a
proven band) against python-control's ``stability_margins`` on the loop with the delay
replaced by its ``(n, n)`` Padé approximant (``control.pade``), ``n = 1, 2, 4, 8``. The loops:

* ``2 e^{-0.5 s} / (s + 1)`` (first order plus dead time, FOPDT): closed forms
  ``w_c = sqrt 3``, ``PM = pi - w_c / 2 - atan w_c``, ``DM = PM / w_c``, the first phase
  crossover the root of ``w / 2 + atan w = pi`` and ``GM = sqrt(1 + w^2) / 2``;
* ``5 e^{-0.1 s} / (0.5 s + 1)`` (a fast FOPDT, ``w_c tau ~ 1``: further up the Padé band);
* ``0.5 e^{-s} / s`` (delayed integrator): ``w_c = 0.5``, ``PM = pi/2 - 0.5``,
  ``GM = pi``;
* ``4 e^{-0.3 s} / (s + 1)^3`` (third-order lag).

Printed: the smallest gain margin, the phase margin (degrees) and the delay margin
``PM / w_c``, their relative errors against nrobust's exact values, and seconds (best of 3;
nrobust's time includes the proven frequency bands and the certified closed-loop verdict).
For the closed-form loops the exact values are also checked against the closed forms.

(b) **Frequency response throughput.** ``DelayLTI.frequency_response`` (exact, vectorised)
on 10^4 and 10^5 frequencies (the slow python-control routes on 10^4 only) for a SISO and a
2 x 2 closed loop with a delay per channel,
against python-control evaluating (i) the ``FrequencyResponseData`` of the same values
(``to_frd``) at its own frequencies, a table look-up, (ii) that FRD with ``smooth=True``
(spline interpolation) between its points, and (iii) the rational Padé model (order 8).
Printed: seconds (best of 3), frequencies per millisecond, the time ratio to nrobust, and the
largest error against the exact response.

Run: ``python benchmarks/lti.py`` (needs python-control).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from typing import Any

import control
import numpy as np
from scipy.optimize import brentq

from nrobust.lti import DelayLTI, allmargin, delay

ORDERS = (1, 2, 4, 8)
REPEATS = 3
#: Largest grid on which the slow python-control evaluations (spline FRD, Padé model) run.
SLOW_POINTS = 10_000


def best_time(fn: Callable[[], Any]) -> tuple[float, Any]:
    """Smallest wall time of ``REPEATS`` calls and the last result."""
    best, out = np.inf, None
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def rel(a: float, b: float) -> float:
    return abs(a - b) / abs(b)


# name, rational part (python-control), dead time, closed forms (gm, pm in degrees, dm) or None
def fopdt_closed_form(k: float, T: float, L: float) -> tuple[float, float, float]:
    wc = np.sqrt(k**2 - 1.0) / T
    pm = np.pi - L * wc - np.arctan(T * wc)
    w180 = brentq(lambda w: L * w + np.arctan(T * w) - np.pi, 1e-9, 1e9, xtol=1e-15)
    return float(np.sqrt(1.0 + (T * w180) ** 2) / k), float(np.degrees(pm)), float(pm / wc)


LOOPS: list[tuple[str, control.TransferFunction, float, tuple[float, float, float] | None]] = [
    ("2 e^-0.5s/(s+1)", control.tf([2.0], [1.0, 1.0]), 0.5, fopdt_closed_form(2.0, 1.0, 0.5)),
    ("5 e^-0.1s/(0.5s+1)", control.tf([5.0], [0.5, 1.0]), 0.1, fopdt_closed_form(5.0, 0.5, 0.1)),
    ("0.5 e^-s/s", control.tf([0.5], [1.0, 0.0]), 1.0, (np.pi, float(np.degrees(np.pi / 2 - 0.5)), np.pi - 1.0)),
    ("4 e^-0.3s/(s+1)^3", control.tf([4.0], [1.0, 3.0, 3.0, 1.0]), 0.3, None),
]


def margins_table() -> None:
    print("(a) margins: nrobust allmargin (exact) vs python-control stability_margins on Pade models")
    head = f"{'loop':20s} {'method':23s} {'GM':>10s} {'PM deg':>10s} {'DM':>10s} {'err GM':>9s} {'err PM':>9s}"
    head += f" {'err DM':>9s} {'seconds':>9s} {'t/t_nr':>8s}"
    print(head)
    for name, P, tau, closed in LOOPS:
        t_nr, m = best_time(lambda P=P, tau=tau: allmargin(P * delay(tau)))
        gm, pm, dm = float(np.min(m.gain_margins)), float(m.phase_margins[0]), float(m.delay_margins[0])
        print(
            f"{name:20s} {'nrobust allmargin':23s} {gm:10.6f} {pm:10.5f} {dm:10.6f} {'':>9s} {'':>9s} {'':>9s}", end=""
        )
        print(f" {t_nr:9.4f} {1.0:8.2f}")
        if closed is not None:
            errs = [rel(x, y) for x, y in zip((gm, pm, dm), closed)]
            print(f"{'':20s} {'closed form':23s} {closed[0]:10.6f} {closed[1]:10.5f} {closed[2]:10.6f}", end="")
            print(f" {errs[0]:9.1e} {errs[1]:9.1e} {errs[2]:9.1e}")
        for n in ORDERS:
            num, den = control.pade(tau, n)
            model = P * control.tf(num, den)
            t_pc, out = best_time(lambda model=model: control.stability_margins(model))
            g, p, _, _, wg, _ = out
            d = np.radians(p) / wg
            print(f"{'':20s} {f'Pade {n} + python-control':23s} {g:10.6f} {p:10.5f} {d:10.6f}", end="")
            print(f" {rel(g, gm):9.1e} {rel(p, pm):9.1e} {rel(d, dm):9.1e} {t_pc:9.4f} {t_pc / t_nr:8.4f}")


def siso_loop() -> DelayLTI:
    return (control.tf([2.0], [1.0, 1.0]) * delay(0.5)).feedback(1)


def mimo_loop() -> DelayLTI:
    P = control.tf([[[1.0], [0.5]], [[0.2], [2.0]]], [[[1.0, 1.0], [1.0, 2.0]], [[1.0, 3.0], [1.0, 1.0]]])
    return (DelayLTI.from_control(P) * delay(0.3).append(delay(0.8))).feedback(np.diag([0.8, 0.6]))


def pade_model(sys: DelayLTI, n: int) -> control.TransferFunction:
    """The closed loop with each delay channel replaced by its ``(n, n)`` Padé approximant."""
    num, den = {}, {}
    for tau in np.unique(sys.tau):
        num[tau], den[tau] = control.pade(float(tau), n)
    k = sys.ndelays
    # P: the delay-free part with inputs (u, w) and outputs (y, z); close w = R(s) z channel by channel
    P = control.ss(sys.A, np.hstack([sys.B1, sys.B2]), np.vstack([sys.C1, sys.C2]),
                   np.block([[sys.D11, sys.D12], [sys.D21, sys.D22]]))  # fmt: skip
    R = control.append(*[control.ss(control.tf(num[t], den[t])) for t in sys.tau])
    return P.lft(R, nu=k, ny=k)  # the lower LFT: w = R z closes the last k inputs and outputs


def throughput_table() -> None:
    print()
    print("(b) frequency response: DelayLTI (exact) vs python-control evaluating an FRD and a Pade model")
    print(
        f"{'system':10s} {'points':>7s} {'method':32s} {'seconds':>9s} {'pts/ms':>9s} {'t/t_nr':>8s} {'max error':>10s}"
    )
    rng = np.random.default_rng(0)
    for label, sys in (("SISO", siso_loop()), ("2x2 MIMO", mimo_loop())):
        model = pade_model(sys, 8)
        for npts in (10_000, 100_000):
            w = np.logspace(-2, 2, npts)
            off = np.sort(rng.uniform(w[0], w[-1], npts))  # between the FRD's points
            t_nr, H = best_time(lambda w=w, sys=sys: sys.frequency_response(w, squeeze=False))
            exact_off = sys.frequency_response(off, squeeze=False)
            frd = sys.to_frd(w)
            smooth = control.FrequencyResponseData(H, w, smooth=True)
            rows = [("nrobust DelayLTI (exact)", t_nr, 0.0)]
            t, out = best_time(lambda frd=frd, w=w: frd.frequency_response(w).complex)
            rows.append(("control FRD at its points", t, float(np.max(np.abs(out.reshape(H.shape) - H)))))
            if npts <= SLOW_POINTS:  # spline and state-space evaluation: 60-200 x slower, minutes at 10^5
                t, out = best_time(lambda smooth=smooth, off=off: smooth.frequency_response(off).complex)
                err = float(np.max(np.abs(out.reshape(H.shape) - exact_off)))
                rows.append(("control FRD smooth, between", t, err))
                t, out = best_time(lambda model=model, w=w: model.frequency_response(w).complex)
                rows.append(("control Pade-8 StateSpace", t, float(np.max(np.abs(out.reshape(H.shape) - H)))))
            for name, t, err in rows:
                print(f"{label:10s} {npts:7d} {name:32s} {t:9.4f} {npts / (1e3 * t):9.0f} {t / t_nr:8.3f} {err:10.2e}")


def main() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # python-control's notes on high-order Pade models
        margins_table()
        throughput_table()


if __name__ == "__main__":
    main()
