# The public names of nrobust.hyperbolic.kernels, loaded on first use (nrobust/hyperbolic/kernels/__init__.py).
from .constant import (
    DEFAULT_KERNEL_GRID as DEFAULT_KERNEL_GRID,
    MAX_KERNEL_GRID as MAX_KERNEL_GRID,
    MIN_KERNEL_GRID as MIN_KERNEL_GRID,
    RESOLUTION as RESOLUTION,
    Kernels as Kernels,
    check_kernel_grid as check_kernel_grid,
    solve_kernels as solve_kernels,
)
from .varying import (
    VaryingKernels as VaryingKernels,
    solve_varying_kernels as solve_varying_kernels,
)
