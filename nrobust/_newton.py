"""Vectorised Newton iteration for analytic functions of one complex variable.

One implementation serves the root finder (:mod:`nrobust.roots.finder`, on a
quasi-polynomial, paper eq. (10) and its closed-loop analogues) and
the spectral bound of a difference operator (:mod:`nrobust.difference`, on the principal
part ``D``); each caller supplies its function, its step limit and, through the
callbacks, its work accounting and its test for points that stall short of convergence.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["newton"]

#: A step shorter than this, relative to ``1 + |s|``, ends the iteration of a point.
STEP_RTOL = 4 * float(np.finfo(float).eps)
#: The relative error of a computed step allowed for (``f`` and ``f'`` rounded; a determinant's
#: ``f'`` may lose digits to cancellation) when the next step is predicted instead of taken.
_STEP_ERROR = 1e-3


def newton(
    fdf: Callable[[NDArray[np.complex128]], tuple[NDArray[np.complex128], NDArray[np.complex128]]],
    s0: ArrayLike,
    *,
    max_step: float,
    iters: int = 60,
    on_step: Callable[[int], None] | None = None,
    accept_stalled: Callable[[NDArray[np.complex128]], NDArray[np.bool_]] | None = None,
    predict: bool = False,
) -> NDArray[np.complex128]:
    """Newton's method ``s <- s - f(s)/f'(s)`` from every seed at once.

    Parameters
    ----------
    fdf : callable
        ``fdf(x) -> (f(x), f'(x))`` on a 1-D complex array.
    s0 : array_like of complex
        Seeds (flattened).
    max_step : float
        Longest step: a longer Newton step keeps its direction and is cut to this length,
        so that a seed is not thrown far from the root it approximates.
    iters : int, optional
        Largest number of steps of each point.
    on_step : callable, optional
        Called with the number of points evaluated, before each step (work accounting).
    accept_stalled : callable, optional
        Called once on the points still iterating after ``iters`` steps; returns a boolean
        mask of those to keep (e.g. a residual at rounding level: Newton's method
        converges only linearly to a multiple root and may stop short of the step test).
        By default none is kept.
    predict : bool, optional
        Also end a point when its error after this step, predicted from the quadratic
        contraction of its last two steps (lengths ``L_1 > 8 L_2``, neither cut to ``max_step``:
        the next step is about ``C L_2^2`` with ``C = L_2 / L_1^2``) plus ``1e-3 L_2`` for the
        error of the step itself, passes the step test: the step that would only confirm the
        convergence is not taken. A prediction, not a bound: for callers that check the limits
        (the root finder evaluates ``f / f'`` at each limit and polishes those whose step is not
        negligible).

    Returns
    -------
    ndarray of complex, shape (n,)
        The limit of each seed: a point whose last step was shorter than
        ``4 eps (1 + |s|)`` (or, with ``predict``, whose next step is predicted to be), or one
        kept by ``accept_stalled``; nan where the step became
        non-finite or the point was not kept.
    """
    s = np.array(s0, dtype=complex).ravel()
    done = np.zeros(s.size, dtype=bool)
    alive = np.ones(s.size, dtype=bool)
    last = np.zeros(s.size)  # length of the previous step (0: none, or cut to max_step)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):  # f / d: inf or nan marks a bad step
        for _ in range(iters):
            act = np.flatnonzero(alive & ~done)
            if not act.size:
                break
            if on_step is not None:
                on_step(act.size)
            x = s[act]
            f, d = fdf(x)
            step = f / d
            bad = ~np.isfinite(step)
            if bad.any():
                alive[act[bad]] = False
                step[bad] = 0
            length = np.abs(step)
            big = length > max_step
            if big.any():
                step[big] *= max_step / length[big]
                length = np.abs(step)
            s[act] = x - step
            tol = STEP_RTOL * (1.0 + np.abs(x))
            done[act] = length <= tol
            if predict:
                prev = last[act]
                # the point's error after this step: the step's own error plus the next step C L_2^2
                done[act] |= (length * 8.0 < prev) & (_STEP_ERROR * length + length**3 / prev**2 <= tol)
                last[act] = length * ~big  # 0 where the step was cut
    stalled = np.flatnonzero(alive & ~done)
    if stalled.size and accept_stalled is not None:
        done[stalled[accept_stalled(s[stalled])]] = True
    return np.where(done & alive, s, np.nan)
