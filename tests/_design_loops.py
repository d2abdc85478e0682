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
