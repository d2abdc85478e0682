"""Delay margins of the paper's loops and the gain studies built on them.

:func:`delay_margin` takes a plant and a controller (or the two loop factors ``A, B``)
and returns the margin of ``F(s; delta) = A(s) + B(s) e^{-delta s}``
(:func:`nrobust.margins.delay_margin`). The studies sweep the gain ``K`` of
``U_BS2(K)`` (eq. (control3)) or the filter ``(a, b)`` of section 2.3.2: admissible gains
(:func:`k_region`), filters (:func:`ab_region`), the stability chart in ``(K, delta)``
(:func:`stability_chart`) and the decay-rate/margin trade-off (:func:`tradeoff`). Each
takes ``executor=`` and runs its grid through :func:`nrobust.parallel.sweep_map`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._json import fields_dict
from .._validate import positive, positive_int, renamed_keywords
from ..errors import ParameterError
from ..margins import DelayMargin
from ..margins import delay_margin as factor_delay_margin
from ..parallel import sweep_map
from ..quasipoly import QuasiPolynomial
from ..roots import spectral_abscissa
from .controllers import (
    Controller,
    FilteredController,
    ReflectionController,
    characteristic,
    classify,
    loop_factors,
)
from .kernels import DEFAULT_KERNEL_GRID
from .robustness import rouche_delay_bound
from .system import Hyperbolic2x2

__all__ = [
    "DEFAULT_N_GAINS",
    "ABRegion",
    "KRegion",
    "StabilityChart",
    "Tradeoff",
    "ab_region",
    "delay_margin",
    "k_region",
    "margin_and_decay",
    "stability_chart",
    "tradeoff",
]

#: Default number of gains of the grid of :func:`k_region` (and of
#: :func:`nrobust.certify`'s K-region). The grid only has to put one gain inside each
#: admissible interval; bisection then resolves its ends. On the paper's plant
#: (``delta_max = 0.1``) 9 and 41 gains give the same interval ends to 7e-7 (below the
#: default ``tol``) in 56 s against 81 s, and a certificate's K-region costs 2 s against 20 s.
DEFAULT_N_GAINS = 9


@renamed_keywords(n="kernel_grid")
def delay_margin(
    system: Hyperbolic2x2 | QuasiPolynomial,
    controller: Controller | QuasiPolynomial,
    *,
    delta_max: float | None = None,
    verify: bool = True,
    max_evals: int = 2_000_000,
    kernel_grid: int = DEFAULT_KERNEL_GRID,
) -> DelayMargin:
    """Delay margin and stability intervals of a plant with a controller, or of ``(A, B)``.

    Called as ``delay_margin(system, controller)``: the loop factors of
    :func:`nrobust.hyperbolic.loop_factors` (e.g. eq. (delay_eq_alpha_ter) for
    ``U_BS2(K)``) are passed to :func:`nrobust.margins.delay_margin`; called as
    ``delay_margin(A, B)`` with two :class:`QuasiPolynomial`, it is that function.

    Parameters
    ----------
    system : Hyperbolic2x2 or QuasiPolynomial
        The plant, or the factor ``A`` of ``F(s; delta) = A(s) + B(s) e^{-delta s}``.
    controller : Controller or QuasiPolynomial
        The controller of the plant, or the factor ``B`` when ``system`` is ``A``.
    delta_max, verify, max_evals
        As in :func:`nrobust.margins.delay_margin`.
    kernel_grid : int, default :data:`~nrobust.hyperbolic.kernels.DEFAULT_KERNEL_GRID`
        Kernel grid of the delay form when called with a plant (ignored with ``A, B``;
        formerly ``n``, a deprecated alias); the margin converges at about third order
        in ``1/kernel_grid`` (paper's example: grids of 201 and 401 points differ by
        1.3e-10, ``docs/margins.md``).

    Raises
    ------
    ParameterError
        Naming ``system`` or ``controller`` when they are neither a plant and a
        controller nor two quasi-polynomials ``A, B``.

    Returns
    -------
    DelayMargin
    """
    if isinstance(system, Hyperbolic2x2):
        if not isinstance(controller, Controller):
            raise ParameterError(
                "controller",
                "a controller (OpenLoop, FiniteTimeController, ReflectionController or FilteredController) "
                "when system is a plant",
                type(controller).__name__,
            )
        A, B = loop_factors(system, controller, kernel_grid)
    elif isinstance(system, QuasiPolynomial):
        if not isinstance(controller, QuasiPolynomial):
            raise ParameterError(
                "controller",
                "a QuasiPolynomial when system is one: the factors (A, B) of F(s; delta) = A(s) + B(s) e^{-delta s} "
                "are passed as (system, controller)",
                type(controller).__name__,
            )
        A, B = system, controller
    else:
        raise ParameterError(
            "system",
            "a plant (Hyperbolic2x2 or TransportSystem, with a controller) or a QuasiPolynomial: the factor A of "
            "F(s; delta) = A(s) + B(s) e^{-delta s}, with B as controller",
            type(system).__name__,
        )
    return factor_delay_margin(A, B, delta_max=delta_max, verify=verify, max_evals=max_evals)


def margin_and_decay(system: Hyperbolic2x2, controller: Controller) -> dict[str, float]:
    """Delay margin and decay rate of one closed loop: the default analysis of
    :func:`nrobust.robustness`.

    Returns
    -------
    dict
        ``delta_star`` (the ``margin`` of :func:`delay_margin`; ``inf`` when every delay
        is tolerated, 0 when an arbitrarily small delay destabilises), ``abscissa``
        (spectral abscissa of the delay-free characteristic function) and
        ``decay_rate = -abscissa``.
    """
    margin = delay_margin(system, controller)
    abscissa = float(spectral_abscissa(characteristic(system, controller, 0.0)).value)
    return {"delta_star": float(margin.margin), "abscissa": abscissa, "decay_rate": -abscissa}


# ============================================================================ gain studies
def _mapper(executor: Any) -> Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]]:
    """The built-in ``map`` in this process, else the sweep machinery's (``nrobust.sweep``)."""
    return map if isinstance(executor, str) and executor == "serial" else sweep_map(executor)


def _reflection(K: float) -> ReflectionController:
    return ReflectionController(K)


def _margin_for(K: float, system: Any, delta_max: float | None, family: Callable[[float], Any]) -> DelayMargin:
    """Delay margin of ``system`` with ``family(K)`` (module level: picklable for pools)."""
    return delay_margin(system, family(float(K)), delta_max=delta_max, verify=False)


def _tolerates(margin: DelayMargin, delta_max: float) -> bool:
    """True if the loop is stable for every delay in ``[0, delta_max]`` (admissible)."""
    return bool(margin.nominally_stable and margin.margin > delta_max)


def _check_system(system: Any) -> None:
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem", system)
    if system.q == 0:
        raise ParameterError("system.q", "non-zero (otherwise the loop does not depend on K)", system.q)


def _grid(name: str, values: ArrayLike) -> NDArray[np.float64]:
    arr = np.atleast_1d(np.asarray(values, dtype=float))
    if arr.ndim != 1 or arr.size < 1 or not np.all(np.isfinite(arr)):
        raise ParameterError(name, "a non-empty 1-D array of finite numbers", values)
    return arr


@dataclass(frozen=True, eq=False)
class KRegion:
    """Gains ``K`` for which ``U_BS2(K)`` is exponentially stable for every delay in ``[0, delta_max]``.

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    intervals : tuple of (float, float)
        The admissible gains, as open intervals; ends located by bisection to ``tol``.
    delta_max : float
        The delay range that must be tolerated.
    paper_bound : float
        ``(1 - |rho q|)/|q|`` of eq. (boun_K2). It is also necessary for a positive margin:
        ``|rho q| + |K q| < 1`` is the strong stability of the loop's difference operator.
    Ks : ndarray
        Gain grid on which the margins were computed.
    margins : ndarray
        ``delta*(K)`` on the grid.
    admissible : ndarray of bool
        ``delta*(K) > delta_max`` and the nominal loop stable, on the grid.
    tol : float
        Accuracy of the interval ends.
    """

    intervals: tuple[tuple[float, float], ...]
    delta_max: float
    paper_bound: float
    Ks: NDArray[np.float64]
    margins: NDArray[np.float64]
    admissible: NDArray[np.bool_]
    tol: float

    def __repr__(self) -> str:
        ivs = ", ".join(f"({lo:.6g}, {hi:.6g})" for lo, hi in self.intervals) or "empty"
        return f"KRegion(delta_max={self.delta_max:.6g}, K in {ivs}, paper bound |K| < {self.paper_bound:.6g})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


@renamed_keywords(n="n_gains")
def k_region(
    system: Any,
    delta_max: float,
    *,
    Ks: ArrayLike | None = None,
    n_gains: int = DEFAULT_N_GAINS,
    tol: float | None = None,
    controller: Callable[[float], Any] | None = None,
    executor: Any = "serial",
) -> KRegion:
    """Gains keeping the loop stable for every delay in ``[0, delta_max]``.

    ``U_BS2(K)`` (eq. (control3)) is admissible when the nominal loop is stable and its
    delay margin exceeds ``delta_max``. The margin is the *first* delay at which any
    crossing branch reaches the axis, so the whole interval ``[0, delta_max]`` is checked
    (stability windows further out do not count). The margin is evaluated on the grid
    ``Ks`` and every change of admissibility between neighbours is located by bisection.
    Features narrower than the grid step can be missed; inside a reported interval every
    grid gain is certified by the crossing analysis of :func:`delay_margin`.

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant.
    delta_max : float
        Delay range to tolerate (``> 0``).
    Ks : array_like, optional
        Gain grid; default ``n_gains`` points spanning ``(-k, k)``, ``k`` the paper's bound
        (gains outside it have zero margin: the difference operator
        ``1 - rho q e^{-tau s} + K q e^{-(tau+delta) s}`` is not strongly stable).
    n_gains : int, default :data:`DEFAULT_N_GAINS`
        Size of the default grid, ``>= 3`` (formerly ``n``, a deprecated alias). An
        admissible interval narrower than the grid step ``2 k / (n_gains + 1)`` can be
        missed.
    tol : float, optional
        Accuracy of the interval ends; default ``1e-4`` times the paper's bound.
    controller : callable, optional
        ``K -> controller``; default ``ReflectionController``.
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the grid points run (:func:`nrobust.sweep`'s executors); default in this
        process. Results are the same whatever the executor.

    Returns
    -------
    KRegion
    """
    _check_system(system)
    delta_max = positive("delta_max", delta_max)
    family = _reflection if controller is None else controller
    kb = classify(system).k_bound
    tol = positive("tol", tol) if tol is not None else 1e-4 * (kb if kb > 0 else 1.0)
    if Ks is None:
        n_gains = positive_int("n_gains", n_gains, 3)
        if kb == 0.0:
            raise ParameterError("system", "with |rho q| < 1 for the default gain grid (pass Ks)", system)
        Ks = kb * np.linspace(-1.0, 1.0, n_gains + 2)[1:-1]
    grid = np.sort(_grid("Ks", Ks))
    results = list(_mapper(executor)(_PartialMargin(system, delta_max, family), grid))
    margins = np.array([r.margin for r in results])
    ok = np.array([_tolerates(r, delta_max) for r in results])

    def admissible(K: float) -> bool:
        return _tolerates(_margin_for(K, system, delta_max, family), delta_max)

    def edge(good: float, bad: float) -> float:
        for _ in range(200):
            if abs(good - bad) <= tol:
                break
            mid = 0.5 * (good + bad)
            if admissible(mid):
                good = mid
            else:
                bad = mid
        return good

    intervals: list[tuple[float, float]] = []
    k = 0
    while k < grid.size:
        if not ok[k]:
            k += 1
            continue
        j = k
        while j + 1 < grid.size and ok[j + 1]:
            j += 1
        lo_bad = grid[k - 1] if k > 0 else -kb
        hi_bad = grid[j + 1] if j + 1 < grid.size else kb
        lo = edge(grid[k], lo_bad) if lo_bad < grid[k] else grid[k]
        hi = edge(grid[j], hi_bad) if hi_bad > grid[j] else grid[j]
        intervals.append((float(lo), float(hi)))
        k = j + 1
    return KRegion(tuple(intervals), delta_max, kb, grid, margins, ok, tol)


@dataclass(frozen=True)
class _PartialMargin:
    """Picklable ``K -> delay_margin(system, family(K))`` for ``map`` hooks."""

    system: Any
    delta_max: float | None
    family: Callable[[float], Any]

    def __call__(self, K: float) -> DelayMargin:
        return _margin_for(K, self.system, self.delta_max, self.family)


@dataclass(frozen=True)
class _PartialFilter:
    """Picklable ``(a, b) -> delay_margin(system, FilteredController(a, b))``."""

    system: Any
    delta_max: float

    def __call__(self, ab: tuple[float, float]) -> DelayMargin:

        return delay_margin(self.system, FilteredController(*ab), delta_max=self.delta_max, verify=False)


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
        The paper's eq. (cond_a_b): ``a/b < (1 - |rho q|)/|rho q|`` and
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
            f"{int((self.paper_conditions & ~self.admissible).sum())} meet eq. (cond_a_b) but are not)"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


def ab_region(system: Any, delta_max: float, a: ArrayLike, b: ArrayLike, *, executor: Any = "serial") -> ABRegion:
    """Admissible filter coefficients of the filtered finite-time controller (section 2.3.2).

    With ``U_1(s) = -(1 + a s)/(1 + b s) U_BS``, the loop is
    ``(1 + b s)(1 - Phi) + (1 + a s) Phi e^{-delta s}`` (eq. (delay_transport3) for a
    transport system). Its difference operator (the ``s`` terms divided by ``b``) is
    ``1 - rho q e^{-tau s} + (a/b) rho q e^{-(tau + delta) s}``, strongly stable iff
    ``|rho q| (1 + |a|/b) < 1``; this, not the one-sided ``a/b < (1 - |rho q|)/|rho q|``
    of eq. (cond_a_b), is necessary for a positive margin. Each grid point is decided by
    :func:`delay_margin` (nominal stability and ``delta* > delta_max``).

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant.
    delta_max : float
        Delay range to tolerate.
    a, b : array_like
        Grid axes (``b > 0``).
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the grid points run (:func:`nrobust.sweep`'s executors); default in this
        process. Results are the same whatever the executor.

    Returns
    -------
    ABRegion
    """
    _check_system(system)
    delta_max = positive("delta_max", delta_max)
    av, bv = _grid("a", a), _grid("b", b)
    if np.any(bv <= 0):
        raise ParameterError("b", "> 0", b)
    pairs = [(float(x), float(y)) for x in av for y in bv]
    results = list(_mapper(executor)(_PartialFilter(system, delta_max), pairs))
    shape = (av.size, bv.size)
    margins = np.array([r.margin for r in results]).reshape(shape)
    ok = np.array([_tolerates(r, delta_max) for r in results]).reshape(shape)
    g = abs(system.rho * system.q)
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
) -> StabilityChart:
    """Stability chart of ``U_BS2(K)`` in the ``(K, delta)`` plane (section 4.2.1).

    For each gain one :func:`delay_margin` analysis gives the number of unstable zeros for
    every delay at once (certified count at ``delta = 0`` plus signed crossings) and the
    exact boundary curves ``delta_{c,k}(K)``. With ``quantity="abscissa"`` the spectral
    abscissa is computed at every grid point (:func:`nrobust.roots.spectral_abscissa`;
    much slower).

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant.
    Ks, deltas : array_like
        Grid axes (``deltas >= 0``).
    quantity : {"count", "abscissa"}
        What to tabulate.
    controller : callable, optional
        ``K -> controller``; default ``ReflectionController``.
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the grid points run (:func:`nrobust.sweep`'s executors); default in this
        process. Results are the same whatever the executor.

    Returns
    -------
    StabilityChart
    """
    _check_system(system)
    kv, dv = _grid("Ks", Ks), _grid("deltas", deltas)
    if np.any(dv < 0):
        raise ParameterError("deltas", ">= 0", deltas)
    if quantity not in ("count", "abscissa"):
        raise ParameterError("quantity", "'count' or 'abscissa'", quantity)
    family = _reflection if controller is None else controller
    dmax = float(np.max(dv)) if np.max(dv) > 0 else None
    results = list(_mapper(executor)(_PartialMargin(system, dmax, family), kv))
    margins = np.array([r.margin for r in results])
    boundaries = tuple(
        np.array([(d, c.omega, c.direction) for c in r.crossings for d in c.delays if d <= np.max(dv)]).reshape(-1, 3)
        for r in results
    )
    if quantity == "abscissa":
        pts = [(float(K), float(d)) for K in kv for d in dv]
        values = np.array(list(_mapper(executor)(_PartialAbscissa(system, family), pts))).reshape(kv.size, dv.size)
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


@dataclass(frozen=True, eq=False)
class Tradeoff:
    """Nominal decay rate against delay margin over the gain ``K`` (section 4.2.1).

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    Ks : ndarray
        Gains.
    decay_rates : ndarray
        ``-`` spectral abscissa of the nominal loop (``delta = 0``).
    margins : ndarray
        Exact delay margins ``delta*(K)``.
    rouche_bounds : ndarray
        Guaranteed ``delta_0(K)`` of Theorem 4's proof (:func:`rouche_delay_bound`),
        ``nan`` when the controller is not ``U_BS2``.
    """

    Ks: NDArray[np.float64]
    decay_rates: NDArray[np.float64]
    margins: NDArray[np.float64]
    rouche_bounds: NDArray[np.float64]

    def __repr__(self) -> str:
        return f"Tradeoff({self.Ks.size} gains in [{self.Ks.min():.6g}, {self.Ks.max():.6g}])"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


@dataclass(frozen=True)
class _PartialTradeoff:
    """Picklable ``K -> (decay rate, margin, delta_0)``."""

    system: Any
    family: Callable[[float], Any]

    def __call__(self, K: float) -> tuple[float, float, float]:

        ctrl = self.family(float(K))
        A, B = loop_factors(self.system, ctrl)
        rate = -float(spectral_abscissa(A + B).value)
        margin = delay_margin(A, B, verify=False).margin
        d0 = rouche_delay_bound(self.system, ctrl).delta_0 if isinstance(ctrl, ReflectionController) else np.nan
        return rate, float(margin), float(d0)


def tradeoff(
    system: Any, Ks: ArrayLike, *, controller: Callable[[float], Any] | None = None, executor: Any = "serial"
) -> Tradeoff:
    """Decay rate of the nominal loop against the delay margin, over ``K``.

    The paper's remark after Lemma 3: ``K`` trades the convergence rate of the target
    system (reflection ``rho - K``: decay rate ``-ln|(rho - K) q| / tau`` on a transport
    system) for robustness to delays.

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant.
    Ks : array_like
        Gains.
    controller : callable, optional
        ``K -> controller``; default ``ReflectionController``.
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the grid points run (:func:`nrobust.sweep`'s executors); default in this
        process. Results are the same whatever the executor.

    Returns
    -------
    Tradeoff
    """
    _check_system(system)
    kv = _grid("Ks", Ks)
    family = _reflection if controller is None else controller
    rows = np.array(list(_mapper(executor)(_PartialTradeoff(system, family), kv)), dtype=float).reshape(kv.size, 3)
    return Tradeoff(kv, rows[:, 0], rows[:, 1], rows[:, 2])
