"""One BLAS thread for the small dense products of the certified computations.

The root search, the eigenvalue problems of a collocated generator (order at most 480) and
the scans of the one-parameter designs multiply many small matrices: with BLAS threads
competing for the cores of a shared machine they run several times slower (tenfold seen),
and idle threads still cost CPU time. :func:`one_blas_thread` limits every BLAS library
that numpy and ``scipy.linalg`` load to one thread for its block (also usable as a
decorator), and restores the previous limits after. ``scipy.linalg`` (whose wheels bring a
BLAS of their own) is imported for a block that calls it; other blocks limit its BLAS when it
is loaded already, and do not import it (0.12 s of CPU in a fresh process: a tenth of a
one-parameter design's first call).
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["one_blas_thread"]


@functools.cache
def _blas_libraries(scipy_linalg: bool) -> tuple[Any, ...]:
    """threadpoolctl's controllers of the BLAS libraries numpy loads, and scipy.linalg when ``scipy_linalg``
    (imported here if it is not yet: a slow import); found once for each (a scan)."""
    if scipy_linalg:
        import scipy.linalg  # noqa: F401  (lazily: a slow import; loaded so that its BLAS is controlled too)
    from threadpoolctl import ThreadpoolController

    return tuple(lib for lib in ThreadpoolController().lib_controllers if lib.user_api == "blas")


@contextmanager
def one_blas_thread(scipy_linalg: bool = False) -> Iterator[None]:
    """BLAS limited to one thread inside the block (or the decorated function).

    Each library's own limit is read and, where it is not 1 already, set and restored after:
    a quarter of the work of ``ThreadpoolController.limit``, which reads every property of every
    library (this block encloses each root search, a few milliseconds).

    Parameters
    ----------
    scipy_linalg : bool, default False
        Import ``scipy.linalg`` first, so that its BLAS is limited too: for a block that calls it
        (eigenvalues, matrix exponentials). Without it that BLAS is limited only where
        ``scipy.linalg`` is loaded already.
    """
    libs = [(lib, lib.get_num_threads()) for lib in _blas_libraries(scipy_linalg or "scipy.linalg" in sys.modules)]
    changed = [(lib, n) for lib, n in libs if n != 1]
    for lib, _ in changed:
        lib.set_num_threads(1)
    try:
        yield
    finally:
        for lib, n in changed:
            lib.set_num_threads(n)
