"""State-space systems with delays that several test files build, as ``benchmarks/statespace.py`` builds them."""

from __future__ import annotations

import numpy as np

from nrobust.lti.statespace import StateSpaceTDS


def example_2_9() -> StateSpaceTDS:
    """TDS-CONTROL manual Example 2.9 closed loop (descriptor, n = 6), as benchmarks/statespace.py builds it."""
    m0, m1 = np.zeros((6, 6)), np.zeros((6, 6))
    m0[:2, :2], m0[2, :2], m0[2, 2] = [[0.2, 0.1], [-0.5, 1.0]], [1.0, 1.0], -1.0
    m0[3, 2], m0[3, 3] = 3.1, -3.48
    m0[4:, 2], m0[4:, 3], m0[4:, 4:] = [-1.86, -1.4], [1.79, -0.09], -np.eye(2)
    m1[:2, :2], m1[:2, 4:], m1[2, 4:] = [[0.5, 0.3], [0.1, -0.1]], np.eye(2), [0.01, 0.01]
    return StateSpaceTDS([m0, m1], [0.0, 1.0], E=np.diag([1.0, 1.0, 0.0, 1.0, 0.0, 0.0]))
