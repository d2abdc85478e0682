"""Loop families with closed-form delay margins, shared by the tests of the local design and its fronts.

``s + 1 + k e^{-delta s}`` (parameter ``p = (k,)``), its copy with 0.1 more delay, and the delayed
oscillator ``x'' + c x' + x + K (x + BETA x')(t - delta) = 0`` (``p = (c, K)``); the delay margin
of the first in closed form and the largest ``k`` stable on ``[0, d]``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

import nrobust as nr

A1 = nr.QuasiPolynomial([[1.0, 1.0]], [0.0])  # s + 1
K_BOUNDS = [(0.0, 5.0)]
RATE_TOL = 1e-4  # two last pattern steps of 5e-5 in k (module notes of nrobust.design.local)
BETA = 0.3
OSC_BOUNDS = [(-0.2, 0.2), (0.0, 0.9)]


def first_order(p: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
    return A1, nr.QuasiPolynomial([[p[0]]], [0.0])


def late(p: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
    """The first-order loop with 0.1 more delay: ``s + 1 + k e^{-(0.1 + delta) s}``."""
    return A1, nr.QuasiPolynomial([[p[0]]], [0.1])


def margin(k: float) -> float:
    """The delay margin of ``s + 1 + k e^{-delta s}``, ``k > 1``, in closed form."""
    return math.acos(-1.0 / k) / math.sqrt(k * k - 1.0)


def best_k(d: float) -> float:
    """The largest ``k`` whose loop is stable on ``[0, d]``: ``margin(k) = d``."""
    return float(brentq(lambda k: margin(k) - d, 1.0 + 1e-9, 1e3, xtol=1e-14))


def oscillator(p: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
    return nr.QuasiPolynomial([[1.0, p[0], 1.0]], [0.0]), nr.QuasiPolynomial([[p[1], BETA * p[1]]], [0.0])


def crossing_delays(c: float, K: float, up_to: float) -> list[float]:
    """Every delay up to ``up_to`` at which the oscillator has a zero ``i w``, in closed form.

    ``|1 - w^2 + i c w|^2 = K^2 |1 + i BETA w|^2`` is ``u^2 + (c^2 - 2 - K^2 BETA^2) u + 1 - K^2 = 0`` in
    ``u = w^2``; at a positive root ``e^{-i w delta} = -A/B``: ``delta = (arg(-B/A) mod 2 pi + 2 pi k)/w``.
    """
    out = []
    for u in np.roots([1.0, c * c - 2.0 - K * K * BETA * BETA, 1.0 - K * K]):
        if abs(u.imag) > 1e-12 or u.real <= 0.0:
            continue
        w = math.sqrt(u.real)
        theta = np.mod(np.angle(-K * (1 + 1j * BETA * w) / (1 - w * w + 1j * c * w)), 2 * np.pi)
        out += [(theta + 2 * np.pi * k) / w for k in range(int(up_to * w / (2 * np.pi)) + 2)]
    return sorted(d for d in out if d <= up_to)
