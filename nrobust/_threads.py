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
def _blas_controller() -> Any:
    """A threadpoolctl controller of the BLAS libraries numpy and scipy.linalg load (made once: it scans them)."""
    import scipy.linalg  # noqa: F401  (lazily: a slow import; loaded so that its BLAS is controlled too)
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """BLAS limited to one thread inside the block (or the decorated function)."""
    with _blas_controller().limit(limits=1, user_api="blas"):
        yield
