"""One BLAS thread for the small dense products of the certified computations.

The root search, the eigenvalue problems of a collocated generator (order at most 480) and
the scans of the one-parameter designs multiply many small matrices: with BLAS threads
competing for the cores of a shared machine they run several times slower (tenfold seen),
and idle threads still cost CPU time. :func:`one_blas_thread` limits every BLAS library
that numpy and ``scipy.linalg`` load to one thread for its block (also usable as a
decorator), and restores the previous limits after.
"""

from __future__ import annotations

import functools
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["one_blas_thread"]


@functools.cache
def _blas_libraries() -> tuple[Any, ...]:
    """threadpoolctl's controllers of the BLAS libraries numpy and scipy.linalg load (found once: a scan)."""
    import scipy.linalg  # noqa: F401  (lazily: a slow import; loaded so that its BLAS is controlled too)
    from threadpoolctl import ThreadpoolController

    return tuple(lib for lib in ThreadpoolController().lib_controllers if lib.user_api == "blas")


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """BLAS limited to one thread inside the block (or the decorated function).

    Each library's own limit is read and, where it is not 1 already, set and restored after:
    a quarter of the work of ``ThreadpoolController.limit``, which reads every property of every
    library (this block encloses each root search, a few milliseconds).
    """
    libs = [(lib, lib.get_num_threads()) for lib in _blas_libraries()]
    changed = [(lib, n) for lib, n in libs if n != 1]
    for lib, _ in changed:
        lib.set_num_threads(1)
    try:
        yield
    finally:
        for lib, n in changed:
            lib.set_num_threads(n)
