"""Charts over two parameters: admissible filters ``(a, b)`` (:func:`ab_region`) and the
stability chart in ``(K, delta)`` (:func:`stability_chart`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._json import fields_dict
from ..._validate import positive
from ...errors import ParameterError
from ...margins.admissible import tolerates
from ...margins.margin import DelayMargin
from ...margins.margin import delay_margin as factor_delay_margin
from ...roots import spectral_abscissa
from ..loops.controllers import FilteredController, FiniteTimeController, loop_factors, normalize
from ..plants.general import GeneralHyperbolic2x2
from ._common import GainMargin, check_system, mapper, real_grid, reflection, study_plant
from .margin import studied_delay_margin

__all__ = ["MAX_CHART_POINTS", "ABRegion", "StabilityChart", "ab_region", "stability_chart"]

#: Most grid points of a chart: ``len(Ks) * len(deltas)`` for :func:`stability_chart`,
#: ``len(a) * len(b)`` for :func:`ab_region`. One point is a float of the table (8 MB
#: here in all) and, for ``quantity="abscissa"`` and :func:`ab_region`, a root search or a
#: delay margin of its own (0.01 to 1 s each); a larger grid is refused before any work.
MAX_CHART_POINTS = 1_000_000


def _check_chart_size(names: str, n_rows: int, n_cols: int) -> None:
    """Refuse a chart of more than :data:`MAX_CHART_POINTS` grid points (``names``: its two axes)."""
    if n_rows * n_cols > MAX_CHART_POINTS:
        raise ParameterError(
            names,
            f"a grid of at most MAX_CHART_POINTS = {MAX_CHART_POINTS} points; split the chart or coarsen it",
            f"{n_rows} x {n_cols} = {n_rows * n_cols} points",
        )


#: Largest filter coefficient ``max(|a|, b)`` that :func:`ab_region` uses as it is (:class:`_PartialFilter`).
_FILTER_SCALE = 2.0**32


@dataclass(frozen=True)
class _PartialFilter:
    """Picklable ``(a, b) -> delay_margin(system, FilteredController(a, b))``.

    Filter coefficients beyond ``_FILTER_SCALE`` make ``|A(i w)|^2`` overflow: the loop
    ``(1 + b s)(1 - Phi) + (1 + a s) Phi e^{-delta s}`` is then divided by the power of two
    ``c`` just above ``max(|a|, b)`` (exact in floating point; the zeros, hence the margin,
    do not change), i.e. ``(1 - Phi)`` and ``Phi`` multiply ``(c + c b s)`` and ``(c + c a s)``.
    """

    system: Any
    delta_max: float

    def __call__(self, ab: tuple[float, float]) -> DelayMargin:
        a, b = ab
        big = max(abs(a), b)
        if big <= _FILTER_SCALE:
            return studied_delay_margin(  # a chart: no convergence study per point
                self.system, FilteredController(a, b), delta_max=self.delta_max, verify=False, study=False
            )[0]
        FilteredController(a, b)  # the same validation of (a, b)
        c = float(2.0 ** -np.ceil(np.log2(big)))
        A, B = loop_factors(self.system, FiniteTimeController())  # (1 - Phi, Phi)
        A, B = A.times_poly([c, c * b]), B.times_poly([c, c * a])
        return factor_delay_margin(A, B, delta_max=self.delta_max, verify=False)


@dataclass(frozen=True, eq=False)
class ABRegion:
    """Filter coefficients ``(a, b)`` keeping the filtered ``U_BS`` stable on ``[0, delta_max]``.

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    a, b : ndarray
        The grid axes.
    admissible : ndarray of bool, shape ``(len(a), len(b))``
        Nominal loop stable and delay margin above ``delta_max``.
    margins : ndarray, shape ``(len(a), len(b))``
        ``delta*(a, b)``.
    strongly_stable : ndarray of bool
        ``|rho q| (1 + |a|/b) < 1``: the difference operator
        ``1 - rho q e^{-tau s} + (a/b) rho q e^{-(tau+delta) s}`` is strongly stable
        (necessary for a positive margin).
    paper_conditions : ndarray of bool
        The paper's eq. (17): ``a/b < (1 - |rho q|)/|rho q|`` and
        ``a < (1 - |rho q|)/|rho q|``.
    delta_max : float
    """

    a: NDArray[np.float64]
    b: NDArray[np.float64]
    admissible: NDArray[np.bool_]
    margins: NDArray[np.float64]
    strongly_stable: NDArray[np.bool_]
    paper_conditions: NDArray[np.bool_]
    delta_max: float

    def __repr__(self) -> str:
        return (
            f"ABRegion(delta_max={self.delta_max:.6g}, {int(self.admissible.sum())}/{self.admissible.size} admissible, "
            f"{int((self.paper_conditions & ~self.admissible).sum())} meet eq. (17) but are not)"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


def ab_region(system: Any, delta_max: float, a: ArrayLike, b: ArrayLike, *, executor: Any = "serial") -> ABRegion:
    """Admissible filter coefficients of the filtered finite-time controller (section 2.3.2).

    With ``U_1(s) = -(1 + a s)/(1 + b s) U_BS``, the loop is
    ``(1 + b s)(1 - Phi) + (1 + a s) Phi e^{-delta s}`` (eq. (16) for a
    transport system). Its difference operator (the ``s`` terms divided by ``b``) is
    ``1 - rho q e^{-tau s} + (a/b) rho q e^{-(tau + delta) s}``, strongly stable iff
    ``|rho q| (1 + |a|/b) < 1``; this, not the one-sided ``a/b < (1 - |rho q|)/|rho q|``
    of eq. (17), is necessary for a positive margin. Each grid point is decided by
    :func:`~nrobust.hyperbolic.analyses.delay_margin` (nominal stability and ``delta* > delta_max``).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant; a general plant through its normal form, or with a varying ``lam/mu`` by
        its characteristic route (U_BS is defined on both, :mod:`~nrobust.hyperbolic.loops.controllers`).
    delta_max : float
        Delay range to tolerate.
    a, b : array_like
        Grid axes (``b > 0``), of at most :data:`MAX_CHART_POINTS` pairs.
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the grid points run (:func:`nrobust.sweeps.sweep`'s executors); default in this
        process. Results are the same whatever the executor.

    Returns
    -------
    ABRegion

    Raises
    ------
    ParameterError
        A bad argument, e.g. ``b <= 0`` or more than :data:`MAX_CHART_POINTS` pairs.
    """
    if isinstance(system, GeneralHyperbolic2x2):  # U_BS: the normal form, or the characteristic route
        system = normalize(system, None)[0]
    else:
        check_system(system)
    delta_max = positive("delta_max", delta_max)
    av, bv = real_grid("a", a), real_grid("b", b)
    if np.any(bv <= 0):
        raise ParameterError("b", "> 0", b)
    _check_chart_size("a, b", av.size, bv.size)
    pairs = [(float(x), float(y)) for x in av for y in bv]
    results = list(mapper(executor)(_PartialFilter(system, delta_max), pairs))
    shape = (av.size, bv.size)
    margins = np.array([r.margin for r in results]).reshape(shape)
    ok = np.array([tolerates(r, delta_max) for r in results]).reshape(shape)
    g = abs(system.rho_q)
    A_, B_ = np.meshgrid(av, bv, indexing="ij")
    strong = g * (1.0 + np.abs(A_) / B_) < 1.0
    bound = (1.0 - g) / g if g > 0 else np.inf
    paper = (A_ / B_ < bound) & (A_ < bound)
    return ABRegion(av, bv, ok, margins, strong, paper, delta_max)


@dataclass(frozen=True, eq=False)
class StabilityChart:
    """Number of unstable roots (or spectral abscissa) on a ``(K, delta)`` grid, with boundaries.

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    Ks, deltas : ndarray
        Grid axes.
    values : ndarray, shape ``(len(Ks), len(deltas))``
        ``quantity`` at each grid point: the number of zeros with ``Re s > 0``
        (``inf`` when the difference operator is not strongly stable and ``delta > 0``;
        ``nan`` at ``delta = 0`` when the nominal count cannot be certified, e.g. a chain of
        zeros in ``Re s > 0``; ``-1`` exactly on a crossing delay), or the spectral abscissa.
    quantity : str
        ``"count"`` or ``"abscissa"``.
    margins : ndarray
        Delay margin ``delta*(K)``: the lower boundary of the stable region.
    boundaries : tuple of ndarray
        Per gain, the array of rows ``(delta, omega, direction)`` of every crossing
        delay up to ``max(deltas)``: the exact boundary curves of the chart.
    """

    Ks: NDArray[np.float64]
    deltas: NDArray[np.float64]
    values: NDArray[np.float64]
    quantity: str
    margins: NDArray[np.float64]
    boundaries: tuple[NDArray[np.float64], ...]

    def __repr__(self) -> str:
        return (
            f"StabilityChart({self.Ks.size} x {self.deltas.size} grid of {self.quantity}, "
            f"K in [{self.Ks[0]:.6g}, {self.Ks[-1]:.6g}], delta in [{self.deltas[0]:.6g}, {self.deltas[-1]:.6g}])"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


@dataclass(frozen=True)
class _PartialAbscissa:
    """Picklable ``(K, delta) -> spectral abscissa`` of the loop with ``family(K)``."""

    system: Any
    family: Callable[[float], Any]

    def __call__(self, point: tuple[float, float]) -> float:

        A, B = loop_factors(self.system, self.family(point[0]))
        F = A + B if point[1] == 0 else A + B.shift(point[1])
        return float(spectral_abscissa(F).value)


def stability_chart(
    system: Any,
    Ks: ArrayLike,
    deltas: ArrayLike,
    *,
    quantity: str = "count",
    controller: Callable[[float], Any] | None = None,
    executor: Any = "serial",
    progress: bool | None = None,
) -> StabilityChart:
    """Stability chart of ``U_BS2(K)`` in the ``(K, delta)`` plane (section 4.2.1).

    For each gain one :func:`~nrobust.hyperbolic.analyses.delay_margin` analysis gives the number of unstable zeros for
    every delay at once (certified count at ``delta = 0`` plus signed crossings) and the
    exact boundary curves ``delta_{c,k}(K)``. With ``quantity="abscissa"`` the spectral
    abscissa is computed at every grid point (:func:`nrobust.roots.spectral_abscissa`;
    much slower).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant; a general plant through its normal form (a ``controller`` family then acts
        in its physical coordinates), with a varying ``lam/mu`` only with a ``controller``
        family other than U_BS2(K) (its loops by the characteristic route).
    Ks, deltas : array_like
        Grid axes (``deltas >= 0``), of at most :data:`MAX_CHART_POINTS` points
        (``len(Ks) * len(deltas)``).
    quantity : {"count", "abscissa"}
        What to tabulate.
    controller : callable, optional
        ``K -> controller``; default ``ReflectionController``.
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the grid points run (:func:`nrobust.sweeps.sweep`'s executors); default in this
        process. Results are the same whatever the executor.
    progress : bool, optional
        A progress bar over the gains (and grid points for ``"abscissa"``) on stderr; by
        default only when stderr is a terminal or Jupyter.

    Returns
    -------
    StabilityChart

    Raises
    ------
    ParameterError
        A bad argument, e.g. a negative delay or more than :data:`MAX_CHART_POINTS` grid points.
    """
    system, controller = study_plant(system, controller, "stability_chart")
    kv, dv = real_grid("Ks", Ks), real_grid("deltas", deltas)
    if np.any(dv < 0):
        raise ParameterError("deltas", ">= 0", deltas)
    if quantity not in ("count", "abscissa"):
        raise ParameterError("quantity", "'count' or 'abscissa'", quantity)
    _check_chart_size("Ks, deltas", kv.size, dv.size)
    family = reflection if controller is None else controller
    dmax = float(np.max(dv)) if np.max(dv) > 0 else None
    results = list(mapper(executor, progress, "stability chart: gains")(GainMargin(system, family, dmax), kv))
    margins = np.array([r.margin for r in results])
    boundaries = tuple(
        np.array([(d, c.omega, c.direction) for c in r.crossings for d in c.delays if d <= np.max(dv)]).reshape(-1, 3)
        for r in results
    )
    if quantity == "abscissa":
        pts = [(float(K), float(d)) for K in kv for d in dv]
        run = mapper(executor, progress, "stability chart: abscissae")
        values = np.array(list(run(_PartialAbscissa(system, family), pts))).reshape(kv.size, dv.size)
    else:
        values = np.empty((kv.size, dv.size))
        for i, r in enumerate(results):
            if r.strongly_stable:
                inside = dv <= r.delta_max  # delta_max is max(deltas), or inf without crossings
                values[i, inside] = r.unstable_count(dv[inside])
                values[i, ~inside] = r.counts[-1][2] if r.counts else np.nan
            else:
                values[i] = np.inf
                nominal = r.nominal_unstable
                values[i, dv == 0] = np.nan if nominal is None else nominal
    return StabilityChart(kv, dv, values, quantity, margins, boundaries)
