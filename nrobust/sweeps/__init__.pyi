# The public names of nrobust.sweeps, loaded on first use (nrobust/sweeps/__init__.py).
from .engine import (
    MAX_POINTS as MAX_POINTS,
    SweepInterrupted as SweepInterrupted,
    sweep as sweep,
)
from .executors import (
    SweepMap as SweepMap,
    sweep_map as sweep_map,
)
from .grids import (
    Grid as Grid,
    grid as grid,
)
from .montecarlo import (
    RobustnessResult as RobustnessResult,
    robustness as robustness,
)
from .result import (
    PointFailure as PointFailure,
    SweepResult as SweepResult,
)
from .sweepfile import (
    ANALYSES as ANALYSES,
    JOURNAL as JOURNAL,
    SweepFileResult as SweepFileResult,
    run_sweep_file as run_sweep_file,
)
