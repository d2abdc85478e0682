# The public names of nrobust.design, loaded on first use (nrobust/design/__init__.py).
from .gain import (
    DESIGN_KINDS as DESIGN_KINDS,
    AffineLoop as AffineLoop,
    DelayWindow as DelayWindow,
    GainDesign as GainDesign,
    best_decay_rate as best_decay_rate,
    best_margin as best_margin,
    check_delays as check_delays,
    window_requirement as window_requirement,
    window_stability as window_stability,
)
from .local import (
    GAMMA_MAX as GAMMA_MAX,
    OBJECTIVES as OBJECTIVES,
    LocalProblem as LocalProblem,
    LocalRun as LocalRun,
    LoopDesign as LoopDesign,
    ParametricLoop as ParametricLoop,
    TrialPoint as TrialPoint,
    delayed_gamma as delayed_gamma,
    local_runs as local_runs,
    optimize_loop as optimize_loop,
)
from .pareto import (
    ParetoFront as ParetoFront,
    pareto_front as pareto_front,
)
