"""Several loops marched together (:func:`nrobust.hyperbolic.simulate.simulate_runs`).

The oracle is :func:`nrobust.hyperbolic.simulate.simulate` run once per loop: a run marched
with others goes through the same floating-point operations as alone, so every sampled
norm, control value and stored state must be the same float (exact comparison).
"""

from __future__ import annotations

import numpy as np
import pytest

from nrobust.errors import ParameterError
from nrobust.hyperbolic.kernels.constant import solve_kernels
from nrobust.hyperbolic.loops.controllers import (
    FilteredController,
    FiniteTimeController,
    OpenLoop,
    ReflectionController,
)
from nrobust.hyperbolic.plants.hyperbolic2x2 import Hyperbolic2x2
from nrobust.hyperbolic.simulate import simulate, simulate_runs

FIELDS = ("times", "norm", "control", "x", "x_v", "snapshot_times", "u", "v")


def _u0(x: np.ndarray) -> np.ndarray:
    return np.ones_like(x)


def _v0(x: np.ndarray) -> np.ndarray:
    return 1.0 + np.sin(np.pi * x)


@pytest.mark.parametrize("mu", [1.0, 1.3])  # the lattice (marched together), two grids (one by one)
def test_each_run_is_the_run_alone(mu: float) -> None:
    system = Hyperbolic2x2(lam=1.0, mu=mu, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)
    # exact and interpolated delays, a filter, a loop without controller
    runs = [
        (FiniteTimeController(), 0.0),
        (FiniteTimeController(), 0.01),
        (ReflectionController(0.1), 0.1),
        (ReflectionController(0.1), 0.0137),
        (FilteredController(0.5, 2.0), 0.05),
        (OpenLoop(), 0.0),
    ]
    together = simulate_runs(system, runs, 3.0, _u0, _v0, 40, snapshot_every=25)
    kernels = solve_kernels(system)
    assert len(together) == len(runs)
    for (controller, delta), run in zip(runs, together):
        alone = simulate(system, controller, delta, 3.0, _u0, _v0, 40, snapshot_every=25, kernels=kernels)
        for field in FIELDS:
            np.testing.assert_array_equal(getattr(run, field), getattr(alone, field), err_msg=field)
        assert (run.delta, run.dt, run.n, run.delay_interpolation, run.scheme) == (
            alone.delta,
            alone.dt,
            alone.n,
            alone.delay_interpolation,
            alone.scheme,
        )


def test_bad_runs_are_refused() -> None:
    system = Hyperbolic2x2(lam=1.0, mu=1.0, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)
    with pytest.raises(ParameterError, match="runs"):
        simulate_runs(system, [], 1.0, _u0, _v0, 20)
    with pytest.raises(ParameterError, match="runs"):
        simulate_runs(system, [FiniteTimeController()], 1.0, _u0, _v0, 20)
    with pytest.raises(ParameterError, match="delta"):
        simulate_runs(system, [(FiniteTimeController(), -0.1)], 1.0, _u0, _v0, 20)
