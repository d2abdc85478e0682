# The public names of nrobust.sweeps, loaded on first use (nrobust/sweeps/__init__.py).
from .engine import (
    MAX_POINTS as MAX_POINTS,
    Grid as Grid,
    PointFailure as PointFailure,
    SweepInterrupted as SweepInterrupted,
    SweepMap as SweepMap,
    SweepResult as SweepResult,
    grid as grid,
    sweep as sweep,
    sweep_map as sweep_map,
)
from .montecarlo import (
    RobustnessResult as RobustnessResult,
    robustness as robustness,
)
from .sweepfile import (
    ANALYSES as ANALYSES,
    JOURNAL as JOURNAL,
    SweepFileResult as SweepFileResult,
    run_sweep_file as run_sweep_file,
)
