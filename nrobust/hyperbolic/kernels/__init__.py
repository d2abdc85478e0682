"""Backstepping kernels of 2x2 plants: constant speeds on the paper's triangle
(``constant``) and varying speeds (``varying``).
"""

from .constant import (
    DEFAULT_KERNEL_GRID,
    MAX_KERNEL_GRID,
    MIN_KERNEL_GRID,
    RESOLUTION,
    Kernels,
    check_kernel_grid,
    solve_kernels,
)
from .varying import VaryingKernels, solve_varying_kernels

__all__ = [
    "DEFAULT_KERNEL_GRID",
    "Kernels",
    "MAX_KERNEL_GRID",
    "MIN_KERNEL_GRID",
    "RESOLUTION",
    "VaryingKernels",
    "check_kernel_grid",
    "solve_kernels",
    "solve_varying_kernels",
]
