"""What stops :func:`nrobust.design.optimize_loop`'s line search, in its reason.

``A = 1 - 0.3 e^{-2s}``, ``B = K e^{-2s}``: at ``delta = 0`` the loop is ``1 + (K - 0.3) e^{-2s}``, whose roots
all have the real part ``ln|K - 0.3| / 2`` (closed form): the decay rate tends to ``inf`` at ``K = 0.3``, where
the loop is the constant 1 (finite-time convergence). ``s + 1 + K + 0.1 e^{-s}`` has a decay rate increasing
in ``K``: its best on ``[0, 2]`` is at the bound.
"""

from __future__ import annotations

import numpy as np

from nrobust import QuasiPolynomial
from nrobust.design.local import optimize_loop


def _finite_time(p: np.ndarray) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    return QuasiPolynomial([[1.0], [-0.3]], [0.0, 2.0]), QuasiPolynomial([[float(p[0])]], [2.0])


def _increasing(p: np.ndarray) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    return QuasiPolynomial([[1.0 + float(p[0]), 1.0]], [0.0]), QuasiPolynomial([[0.1]], [1.0])


def test_steep_fall_toward_a_finite_time_point_is_named() -> None:
    design = optimize_loop(_finite_time, [(0.0, 0.9)], x0=[0.1])
    (run,) = design.runs
    assert run.reason.startswith("the line search stopped: ")
    assert "unbounded" in run.reason and "finite-time convergence" in run.reason
    assert "nonsmooth local optimum, or a bound" not in run.reason
    K = design.parameters[0]
    # the chains of 1 + c e^{-2s} are exact: the rate to rounding of ln|K - 0.3| (|K - 0.3| >= 1e-13 here)
    np.testing.assert_allclose(design.decay_rate, -np.log(abs(K - 0.3)) / 2.0, rtol=1e-9)


def test_stop_at_a_bound_is_named() -> None:
    design = optimize_loop(_increasing, [(0.0, 2.0)], x0=[1.0])
    (run,) = design.runs
    assert "outside the bounds" in run.reason and "best at that edge" in run.reason
    assert design.parameters == (2.0,)
