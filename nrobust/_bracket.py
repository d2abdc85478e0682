"""Zeros of real functions in brackets, many at once: the Illinois variant of regula falsi.

One implementation serves the design of one parameter (:mod:`nrobust.design.gain`: junctions
of crossing curves, phase wraps, pair births) and the Nyquist plot's crossings of the negative
real axis (:mod:`nrobust.plots.nyquist`): each caller supplies a function evaluated on an array
of points, one per bracket, so that every bracket advances in one evaluation.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["illinois"]

Array = NDArray[np.float64]


def illinois(
    f: Callable[[Array], ArrayLike],
    a: ArrayLike,
    b: ArrayLike,
    fa: ArrayLike | None = None,
    fb: ArrayLike | None = None,
    *,
    steps: int | None = None,
    rtol: float = 4 * float(np.finfo(float).eps),
    xtol: float = 0.0,
) -> Array:
    """Zeros of ``f`` bracketed by ``[a, b]`` (``f(a) f(b) <= 0``), for every bracket at once.

    Regula falsi of the Illinois kind: the end kept twice in a row has its value halved, so
    that both ends of a bracket move and convergence is superlinear (order about 1.44).

    Parameters
    ----------
    f : callable
        ``f(x)`` on a 1-D array, elementwise.
    a, b : array_like of float
        The brackets' ends.
    fa, fb : array_like of float, optional
        ``f(a)`` and ``f(b)`` if known.
    steps : int, optional
        A fixed number of steps; by default the iteration runs until every bracket is shorter
        than ``xtol + rtol |x|`` or has hit an exact zero (at most 200 steps).
    rtol, xtol : float
        The stopping rule's relative and absolute tolerances (with ``steps`` None).

    Returns
    -------
    ndarray of float
        In each final bracket, the end where ``|f|`` is smaller.
    """
    a, b = np.array(a, dtype=float), np.array(b, dtype=float)
    fa = np.asarray(f(a) if fa is None else fa, dtype=float)
    fb = np.asarray(f(b) if fb is None else fb, dtype=float)
    moved_a: NDArray[np.bool_] | None = None  # the end the last step replaced: a (True) or b (False)
    for _ in range(200 if steps is None else steps):
        if steps is None:
            width = np.abs(b - a)
            if np.all((width <= xtol + rtol * np.maximum(np.abs(a), np.abs(b))) | (fa == 0.0) | (fb == 0.0)):
                break
        with np.errstate(invalid="ignore", divide="ignore"):
            x = a - fa * (b - a) / (fb - fa)
        x = np.clip(np.where(np.isfinite(x), x, 0.5 * (a + b)), np.minimum(a, b), np.maximum(a, b))
        fx = np.asarray(f(x), dtype=float)
        left = np.sign(fx) == np.sign(fa)
        # only the end kept for the second step in a row has its value halved: regula falsi keeps one end
        # where f is convex, and halving it then restores order 1.44; halving the kept end at every step
        # makes each step a damped bisection, of linear convergence (50 evaluations to rounding, not 11)
        again = np.zeros(left.shape, dtype=bool) if moved_a is None else left == moved_a
        fb = np.where(left & again, 0.5 * fb, fb)
        fa = np.where(~left & again, 0.5 * fa, fa)
        a, fa = np.where(left, x, a), np.where(left, fx, fa)
        b, fb = np.where(left, b, x), np.where(left, fb, fx)
        moved_a = left
    return np.where(np.abs(fa) < np.abs(fb), a, b)
