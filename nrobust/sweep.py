"""Parameter sweeps and Monte Carlo studies: the documented entry points in one namespace.

The code lives in :mod:`nrobust.parallel` (:func:`sweep`, :func:`grid`,
:func:`sweep_map` and the executors), :mod:`nrobust.montecarlo` (:func:`robustness`) and
:mod:`nrobust.sweepfile` (:func:`run_sweep_file`, the SWEEP.toml schema); this module
gathers them under the name ``docs/sweeps.md`` uses.
"""

from .hyperbolic.studies import margin_and_decay
from .montecarlo import RobustnessResult, robustness
from .parallel import Grid, PointFailure, SweepInterrupted, SweepMap, SweepResult, grid, sweep, sweep_map
from .sweepfile import ANALYSES, SweepFileResult, run_sweep_file

__all__ = [
    "ANALYSES",
    "Grid",
    "PointFailure",
    "RobustnessResult",
    "SweepFileResult",
    "SweepInterrupted",
    "SweepMap",
    "SweepResult",
    "grid",
    "margin_and_decay",
    "robustness",
    "run_sweep_file",
    "sweep",
    "sweep_map",
]
