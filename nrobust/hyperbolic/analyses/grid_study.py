"""How far a kernel-route delay margin is from the PDE's: a convergence study in the kernel grid.

On the ``"kernels"`` route (:func:`~nrobust.hyperbolic.loops.controllers.loop_route`) the loop is a
model of the PDE, ``N~`` (and a state feedback's gains) a cubic spline on ``kernel_grid`` points.
:func:`grid_study` estimates the distances of its delay margin and crossing frequency to the
PDE's from the margins on coarser grids (and, when the convergence is not yet monotone, one
finer grid). :func:`nrobust.hyperbolic.analyses.delay_margin` stores them in
:attr:`nrobust.margins.DelayMargin.model_error` and
:attr:`~nrobust.margins.DelayMargin.omega_model_error`, and :func:`nrobust.certify` states them in
its :class:`~nrobust.reports.certificate.ModelError`. Floating point throughout, not proven.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ...errors import CertificationError, ParameterError
from ...margins.margin import DelayMargin
from ..kernels.constant import MIN_KERNEL_GRID

__all__ = ["MAX_ACCURACY_GRID", "GridStudy", "grid_study", "study_scope"]

#: Finest kernel grid a convergence study (and :func:`nrobust.certify` for an ``accuracy`` target) refines to.
MAX_ACCURACY_GRID = 1601


@dataclass(frozen=True)
class GridStudy:
    """The estimated model errors of a kernel-route margin and its crossing frequency.

    Attributes
    ----------
    grid, coarse_grid : int
        The grid of the margin and the grid half as fine, ``(grid + 1) / 2``.
    coarse_margin : float
        The delay margin on ``coarse_grid``.
    estimate : float
        The estimated distance of the margin to the PDE's (0 when the margin, 0 or ``inf``, is
        decided by the structure of the loop; ``nan`` when not estimated).
    omega_estimate : float or None
        The same for the crossing frequency; None without a crossing (or when not estimated).
    order : float or None
        The observed order of the margin's convergence (None when not monotone or not measured).
    statement : str
        The evidence in words.
    """

    grid: int
    coarse_grid: int
    coarse_margin: float
    estimate: float
    omega_estimate: float | None
    order: float | None
    statement: str


def grid_study(margin_on: Callable[[int], DelayMargin], grid: int, margin: DelayMargin) -> GridStudy | None:
    """The estimated model error of ``margin`` (its loop on ``grid`` points) from a convergence study.

    With ``m0, m1, m2`` the margins on ``(grid + 3) / 4``, ``(grid + 1) / 2`` and ``grid``
    points (``margin_on(n)``, computed without a study of their own): when ``m1 - m0`` and
    ``m2 - m1`` have one sign and the second is at most half the first (observed order at
    least 1), the remaining error of ``m2`` is at most ``|m2 - m1|`` (a geometric tail of ratio
    ``<= 1/2``). Otherwise the grid ``2 grid - 1`` is added (up to ``MAX_ACCURACY_GRID``)
    and the same test made on ``m1, m2, m3``: the error of ``m2`` is then at most
    ``2 |m3 - m2|``. When neither holds (convergence not yet monotone), twice the largest
    difference is the estimate, a rough one. The crossing frequency is studied alike on the
    same grids. Floating point, not proven.

    Parameters
    ----------
    margin_on : callable
        ``n -> DelayMargin``: the margin of the same plant and controller on ``n`` points.
    grid : int
        The kernel grid of ``margin``.
    margin : DelayMargin
        The margin to study.

    Returns
    -------
    GridStudy or None
        None when ``grid`` is too coarse to halve (``(grid + 1) / 2 < MIN_KERNEL_GRID``).
    """
    coarse = (grid - 1) // 2 + 1
    coarsest = (coarse - 1) // 2 + 1
    if coarse < MIN_KERNEL_GRID:
        return None
    other = _checked(margin_on, coarse)
    m2, w2 = _values(margin)
    m1, w1 = _values(other)
    if m1 == m2 and not (np.isfinite(m2) and m2 > 0.0):
        statement = (
            f"the delay margin is {m2:g} on {coarse} and on {grid} points "
            "(decided by the structure of the loop, not by the values of N~)"
        )
        return GridStudy(grid, coarse, m1, 0.0, None, None, statement)
    margins, omegas, grids = [m1, m2], [w1, w2], [coarse, grid]
    if coarsest >= MIN_KERNEL_GRID:
        m0, w0 = _values(_checked(margin_on, coarsest))
        margins.insert(0, m0)
        omegas.insert(0, w0)
        grids.insert(0, coarsest)
    fine = 2 * grid - 1
    if not (_monotone(margins) and _monotone(omegas)) and fine <= MAX_ACCURACY_GRID:
        m3, w3 = _values(_checked(margin_on, fine))
        margins.append(m3)
        omegas.append(w3)
        grids.append(fine)
    estimate, order, evidence = _estimate(margins, grids, grid)
    omega_estimate, _, omega_evidence = _estimate(omegas, grids, grid)
    statement = f"the delay margin {evidence}"
    if np.isfinite(omega_estimate):
        statement += f"; its crossing frequency {omega_evidence}"
    return GridStudy(
        grid,
        coarse,
        m1,
        estimate,
        float(omega_estimate) if np.isfinite(omega_estimate) else None,
        order,
        statement + " (floating point, not proven)",
    )


def study_scope(study: GridStudy) -> str:
    """The words a margin's scope gains from ``study``: its estimate, floating point, not proven."""
    return (
        f"; a convergence study in the kernel grid estimates the margin's distance to the PDE's at "
        f"{study.estimate:.2g} (floating point, not proven)"
    )


def _checked(margin_on: Callable[[int], DelayMargin], grid: int) -> DelayMargin | None:
    """``margin_on(grid)``, None when that grid is refused (e.g. an even grid where the route needs an odd one)."""
    try:
        return margin_on(grid)
    except (CertificationError, ParameterError):
        return None


def _values(margin: DelayMargin | None) -> tuple[float, float]:
    """The margin and its crossing frequency (``nan`` when missing)."""
    if margin is None:
        return float("nan"), float("nan")
    return float(margin.margin), float("nan") if margin.omega is None else float(margin.omega)


def _monotone(values: Sequence[float]) -> bool:
    """True when the last two differences of ``values`` contract (:func:`_contracting`)."""
    return len(values) >= 3 and _contracting(values[-2] - values[-3], values[-1] - values[-2])


def _estimate(values: Sequence[float], grids: Sequence[int], grid: int) -> tuple[float, float | None, str]:
    """The estimated error of the value on ``grid`` from its values on ``grids`` (coarsest first), in words too."""
    at = list(grids).index(grid)
    diffs = [b - a for a, b in itertools.pairwise(values)]
    if at >= 2 and _contracting(diffs[at - 2], diffs[at - 1]):  # m0, m1, m2 contract: the tail after m2
        d1, d2 = diffs[at - 2], diffs[at - 1]
        order = float(np.log2(abs(d1) / abs(d2)))
        return (
            abs(d2),
            order,
            f"moves by {abs(d2):.2g} from {grids[at - 1]} to {grid} points, monotone at observed order {order:.2g} "
            f"from {grids[at - 2]} points: its model error is estimated at {abs(d2):.2g}",
        )
    if at + 1 < len(values) and _contracting(diffs[at - 1], diffs[at]):  # m1, m2, m3 contract
        d2, d3 = diffs[at - 1], diffs[at]
        order = float(np.log2(abs(d2) / abs(d3)))
        return (
            2.0 * abs(d3),
            order,
            f"moves by {abs(d3):.2g} from {grid} to {grids[at + 1]} points, monotone at observed order {order:.2g} "
            f"from {grids[at - 1]} points: its model error is estimated at {2.0 * abs(d3):.2g}",
        )
    if any(np.isinf(d) for d in diffs):  # the value jumps to or from inf between grids
        return float("inf"), None, f"is infinite on some of {grids[0]} to {grids[-1]} points only: not estimated"
    finite = [abs(d) for d in diffs if np.isfinite(d)]  # nan: a grid refused
    estimate = 2.0 * max(finite) if finite else float("nan")
    return (
        estimate,
        None,
        f"is not monotone on {grids[0]} to {grids[-1]} points: its model error is estimated roughly at "
        f"{estimate:.2g}, twice the largest difference",
    )


def _contracting(first: float, second: float) -> bool:
    """True when two successive differences have one sign and the second is at most half the first."""
    return bool(np.isfinite(first) and np.isfinite(second) and first * second > 0.0 and abs(second) <= 0.5 * abs(first))
