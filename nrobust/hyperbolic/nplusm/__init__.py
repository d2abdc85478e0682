"""``n + m`` plants with constant coefficients: the loop by the Laplace route and its
certified delay margins (``system``), backstepping kernels and the full-state controller
(``kernels``).
"""

from .kernels import (
    MAX_NPLUSM_KERNEL_GRID,
    NPlusMBackstepping,
    NPlusMKernels,
    backstepping_delay_margin,
    solve_nplusm_kernels,
)
from .system import (
    CancellationCase,
    NPlusMCharacteristic,
    NPlusMMargin,
    NPlusMSimulation,
    NPlusMSystem,
    cancellation_study,
    compound_characteristic,
    multi_actuator_delay_margin,
    multi_actuator_margin,
    nplusm_delay_margin,
    simulate_nplusm,
)

__all__ = [
    "CancellationCase",
    "MAX_NPLUSM_KERNEL_GRID",
    "NPlusMBackstepping",
    "NPlusMCharacteristic",
    "NPlusMKernels",
    "NPlusMMargin",
    "NPlusMSimulation",
    "NPlusMSystem",
    "backstepping_delay_margin",
    "cancellation_study",
    "compound_characteristic",
    "multi_actuator_delay_margin",
    "multi_actuator_margin",
    "nplusm_delay_margin",
    "simulate_nplusm",
    "solve_nplusm_kernels",
]
