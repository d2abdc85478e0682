"""Controller design with certificates, on parametrised loops ``A(s; p) + B(s; p) e^{-delta s}``.

``gain``: one gain of an affine loop (``U_BS2(K)``'s, eq. (60)), or one parameter of a loop
affine in it in both factors (:class:`AffineLoop`: the filtered law's zero or pole), exactly: the gain with the
largest delay margin (:func:`best_margin`: a kink, a pair birth, an interior maximum or an
end, solved from its equation) or the largest decay rate under a required margin
(:func:`best_decay_rate`), each design certified by :mod:`nrobust.margins`; either under a
window of delays on which the loop must be stable (``delays``, :func:`window_stability`).

``local``: several parameters of any loop family, a local nonsmooth optimisation of the decay
rate (under a required margin) or of the margin (:func:`optimize_loop`: BFGS with a weak Wolfe
line search, then a pattern search over axes and diagonals; every iterate feasible; the design certified).
``pareto``: the best decay rate under each of a list of required margins
(:func:`pareto_front`).
"""

from .gain import (
    DESIGN_KINDS,
    AffineLoop,
    DelayWindow,
    GainDesign,
    best_decay_rate,
    best_margin,
    check_delays,
    window_requirement,
    window_stability,
)
from .local import (
    GAMMA_MAX,
    OBJECTIVES,
    LocalProblem,
    LocalRun,
    LoopDesign,
    ParametricLoop,
    TrialPoint,
    delayed_gamma,
    local_runs,
    optimize_loop,
)
from .pareto import ParetoFront, pareto_front

__all__ = [
    "DESIGN_KINDS",
    "GAMMA_MAX",
    "OBJECTIVES",
    "AffineLoop",
    "DelayWindow",
    "GainDesign",
    "LocalProblem",
    "LocalRun",
    "LoopDesign",
    "ParametricLoop",
    "ParetoFront",
    "TrialPoint",
    "best_decay_rate",
    "best_margin",
    "check_delays",
    "delayed_gamma",
    "local_runs",
    "optimize_loop",
    "pareto_front",
    "window_requirement",
    "window_stability",
]
