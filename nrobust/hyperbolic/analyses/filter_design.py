"""Design of the filtered reflection controller: gain ``K``, filter zero ``a`` and pole ``b``.

``FilteredController(a, b, K)`` passes U_BS2(K) (eq. (53)) through ``(1 + a s)/(1 + b s)``
(section 2.3.2); its loop is eq. (60) with ``A`` multiplied by ``1 + b s`` and ``B`` by
``1 + a s``. :func:`design_filtered` maximises the decay rate subject to a delay margin, or the
margin, over any of the three parameters (the others fixed) with the core's local nonsmooth
optimiser (:func:`nrobust.design.optimize_loop`), and certifies the design, optionally
under a window of delays (``delays``) and a tolerance on the transport speeds
(``speed_tolerance``: the four corner plants with mismatched speeds, the law designed on the
nominal one, must meet the window too, and the decay rate maximised is the least of the nominal
plant's and the corners'); :func:`filtered_front` is the trade-off of decay rate against delay
margin over all three (under a speed tolerance, of the least rate, as :func:`design_filtered` maximises it).
With one free parameter the loop is affine in it (``K`` and ``a`` in ``B``, the pole ``b``
in ``A``), and :func:`design_filtered_exact` finds the global optimum over its interval from
the equations of its kind (a kink of ``delta*(p)``, a pair birth, a smooth maximum, an end, or
where ``delta*(p)`` equals a required margin) with the core's :mod:`nrobust.design.gain`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._json import json_safe
from ..._validate import is_real_number
from ...design.gain import AffineLoop, GainDesign, best_decay_rate, best_margin, check_delays
from ...design.local import LoopDesign, optimize_loop
from ...design.pareto import ParetoFront, pareto_front
from ...errors import CertificationError, ParameterError
from ...margins.gain import AffineGainLoop
from ...quasipoly import QuasiPolynomial
from ...roots import SpectralAbscissa
from ..kernels.constant import DEFAULT_KERNEL_GRID, check_kernel_grid
from ..loops.controllers import FilteredController, ReflectionController, classify, loop_factors, loop_scope
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from ._common import CornerRates, mapper
from .mismatch import (
    SpeedTolerance,
    check_local_requirements,
    check_speed_tolerance,
    mismatch_abscissa,
    mismatch_gain_loop,
)
from .mismatch import speed_tolerance as tolerance_on_square

__all__ = [
    "FILTER_PARAMETERS",
    "ExactFilteredDesign",
    "FilteredDesign",
    "FilteredLoop",
    "default_filter_bounds",
    "design_filtered",
    "design_filtered_exact",
    "filtered_front",
    "filtered_loop",
]

#: The parameters of ``FilteredController(a, b, K)`` a design may vary, in this order.
FILTER_PARAMETERS = ("K", "a", "b")
# Default bounds of design_filtered_exact: this fraction of the strong-stability limit |a K| = |b| k.
_SS_FRACTION = 0.9


@dataclass(frozen=True)
class FilteredLoop:
    """``p -> (A, B)`` of ``FilteredController(a, b, K)`` on a plant, the free parameters ``p``.

    Built once from U_BS2's factors (eq. (60) is affine in ``K``: ``A = 1 - Phi``,
    ``B = K q e^{-tau s} - I_N``), so each evaluation is two polynomial products. Picklable.

    Attributes
    ----------
    A0, B0, round_trip : QuasiPolynomial
        ``1 - Phi``, ``-I_N`` and ``q e^{-tau s}``.
    free : tuple of str
        The names of the free parameters, a subset of :data:`FILTER_PARAMETERS` in that order.
    fixed : dict
        The values of the other parameters.
    """

    A0: QuasiPolynomial
    B0: QuasiPolynomial
    round_trip: QuasiPolynomial
    free: tuple[str, ...]
    fixed: Mapping[str, float]

    def values(self, p: ArrayLike) -> dict[str, float]:
        """All three parameters at the free values ``p``."""
        return {**self.fixed, **dict(zip(self.free, map(float, np.asarray(p, dtype=float))))}

    def controller(self, p: ArrayLike) -> FilteredController:
        """The controller at ``p``."""
        v = self.values(p)
        return FilteredController(v["a"], v["b"], v["K"])

    def __call__(self, p: NDArray[np.float64]) -> tuple[QuasiPolynomial, QuasiPolynomial]:
        v = self.values(p)
        B = self.B0 + self.round_trip * v["K"]
        return self.A0.times_poly([1.0, v["b"]]), B.times_poly([1.0, v["a"]])

    def reflection(self) -> AffineGainLoop:
        """U_BS2(K)'s loop ``A_0 + (B_0 + K q e^{-tau s}) e^{-delta s}`` (eq. (60)).

        The filtered loop with ``a = b``, less the common factor ``1 + a s`` (its zero ``-1/a``).
        """
        return AffineGainLoop(self.A0, self.B0, self.round_trip)

    def affine(self) -> AffineLoop:
        """The loop as affine in its one free parameter (eq. (60) with the filter).

        An :class:`~nrobust.design.AffineLoop` ``(A_0 + p A_1) + (B_0 + p B_1) e^{-delta s}``:
        ``K``: ``A_0 = (1 - Phi)(1 + b s)``, ``A_1 = 0``, ``B_0 = -I_N (1 + a s)``,
        ``B_1 = q e^{-tau s} (1 + a s)``; ``a``: ``A_1 = 0``, ``B_0 = B_K``, ``B_1 = s B_K``
        (``B_K = K q e^{-tau s} - I_N``); ``b``: ``A_0 = 1 - Phi``, ``A_1 = s (1 - Phi)``,
        ``B_0 = B_K (1 + a s)``, ``B_1 = 0``.

        Raises
        ------
        ParameterError
            Not exactly one free parameter.
        """
        if len(self.free) != 1:
            raise ParameterError("free", "exactly one free parameter among ('K', 'a', 'b')", self.free)
        v, zero, name = self.fixed, QuasiPolynomial([[0.0]], [0.0]), self.free[0]
        if name == "K":
            zero_a = [1.0, v["a"]]
            return AffineLoop(
                self.A0.times_poly([1.0, v["b"]]), zero, self.B0.times_poly(zero_a), self.round_trip.times_poly(zero_a)
            )
        B = self.B0 + self.round_trip * v["K"]
        if name == "a":
            return AffineLoop(self.A0.times_poly([1.0, v["b"]]), zero, B, B.times_poly([0.0, 1.0]))
        return AffineLoop(self.A0, self.A0.times_poly([0.0, 1.0]), B.times_poly([1.0, v["a"]]), zero)


def _plant(system: Any) -> Hyperbolic2x2 | GeneralHyperbolic2x2:
    if isinstance(system, GeneralHyperbolic2x2) and not system.constant_ratio:
        raise ParameterError("system", "a plant with a constant lam/mu (U_BS2(K) lives on the normal form)", system)
    if not isinstance(system, (Hyperbolic2x2, GeneralHyperbolic2x2)):
        raise ParameterError("system", "a Hyperbolic2x2, TransportSystem or GeneralHyperbolic2x2", system)
    return system


def default_filter_bounds(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> dict[str, tuple[float, float]]:
    """The bounds :func:`design_filtered` takes for a parameter left free without bounds: ``K`` within 0.99 of
    the paper's ``|K| < (1 - |rho q|)/|q|`` (eq. (54)), ``a`` in ``[-tau, tau]``, ``b`` in ``[1e-3 tau, tau]``."""
    k = 0.99 * classify(system).k_bound
    return {"K": (-k, k), "a": (-system.tau, system.tau), "b": (1e-3 * system.tau, system.tau)}


def filtered_loop(system: Hyperbolic2x2 | GeneralHyperbolic2x2, free: Mapping[str, Any]) -> FilteredLoop:
    """The loop family of ``FilteredController(a, b, K)`` on ``system``.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant (a general one through its normal form: ``K`` in normal-form coordinates).
    free : mapping
        Each of ``"K"``, ``"a"``, ``"b"``: a number (fixed) or anything else (free).
    """
    plant = _plant(system)
    A0, B0 = loop_factors(plant, ReflectionController(0.0))
    _, B1 = loop_factors(plant, ReflectionController(1.0))
    names = tuple(n for n in FILTER_PARAMETERS if not is_real_number(free.get(n)))
    fixed = {n: float(free[n]) for n in FILTER_PARAMETERS if n not in names}
    return FilteredLoop(A0, B0, B1 - B0, names, fixed)


def _given_bounds(name: str, value: Any) -> tuple[float, float]:
    """The bounds ``(low, high)`` given for the parameter ``name``, checked."""
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        lo = hi = math.nan
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        requirement = "a number (fixed), bounds (low, high) of finite reals with low < high, or None"
        raise ParameterError(f"parameters[{name!r}]", requirement, value)
    return lo, hi


def _split(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2, parameters: Mapping[str, Any] | None
) -> tuple[dict[str, Any], NDArray[np.float64]]:
    """``(free, bounds)``: each parameter a number (fixed), ``(low, high)`` or None (default bounds)."""
    given = dict(parameters or {})
    unknown = set(given) - set(FILTER_PARAMETERS)
    if unknown:
        raise ParameterError("parameters", f"a mapping with keys among {FILTER_PARAMETERS}", sorted(unknown))
    default = default_filter_bounds(system)
    bounds = []
    free: dict[str, Any] = {}
    for name in FILTER_PARAMETERS:
        value = given.get(name)
        if is_real_number(value):
            free[name] = float(value)  # type: ignore[arg-type]
            continue
        lo, hi = default[name] if value is None else _given_bounds(name, value)
        if name == "b" and not lo > 0.0:
            raise ParameterError("parameters['b']", "bounds (low, high) with 0 < low < high (the filter's pole)", value)
        free[name] = None
        bounds.append((float(lo), float(hi)))
    if not bounds:
        raise ParameterError("parameters", "at least one free parameter (a pair of bounds or None)", parameters)
    return free, np.array(bounds)


@dataclass(frozen=True)
class FilteredDesign(CornerRates):
    """A designed ``FilteredController(a, b, K)`` with its certificate.

    Attributes
    ----------
    controller : FilteredController
        The design.
    design : LoopDesign
        The core's result: objective value, certified abscissa and delay margin, the runs (with
        ``delays``: the requirement, its windows certified for the loop and the corners of a
        speed tolerance, ``design.requirement``).
    scope : str
        What the certificate is about: the PDE itself (constant coefficients) or a model.
    tolerance : SpeedTolerance or None
        With ``speed_tolerance``: the verdicts on the square of speed mismatches (the corners
        certified with the design, the other points of a 3 x 3 grid checked, the whole square
        proven on an uncoupled plant with ``rigorous=True``;
        :func:`~nrobust.hyperbolic.analyses.speed_tolerance`).
    corner_abscissae : tuple of SpectralAbscissa
        With ``speed_tolerance`` and the decay-rate objective: the spectral abscissa at ``delta = 0`` of the
        designed law on each corner plant, in the order of ``tolerance.points[:4]``, restated on loops built by
        :func:`~nrobust.hyperbolic.analyses.mismatch_abscissa` with its model error (the design's own, on the
        corner loops it optimised, are ``design.scenario_abscissae``); empty otherwise. The parameters maximise
        the least decay rate of the nominal plant and the corners: :attr:`worst_decay_rate` is what the law
        guarantees there (between the corners it is not certified).
    """

    controller: FilteredController
    design: LoopDesign
    scope: str
    tolerance: SpeedTolerance | None = None
    corner_abscissae: tuple[SpectralAbscissa, ...] = ()

    @property
    def value(self) -> float:
        """The objective at the design: the delay margin, or the decay rate (with ``speed_tolerance``, the
        least decay rate of the nominal loop and the corners' loops restated by
        :func:`~nrobust.hyperbolic.analyses.mismatch_abscissa`, :attr:`worst_decay_rate`, which gives its
        accuracy; ``design.decay_rate`` is the nominal one)."""
        return self.worst_decay_rate if self.corner_abscissae else self.design.value

    @property
    def certified(self) -> bool:
        """Whether the design's abscissa and margin are certified (see :class:`LoopDesign`), and with
        ``speed_tolerance`` each restated corner abscissa of :attr:`corner_abscissae` too (the least of which is
        :attr:`value`)."""
        return self.design.certified and all(a.certified for a in self.corner_abscissae)

    @property
    def requirement(self) -> str:
        """The requirements and their verdicts in words (the delay window; the speed tolerance)."""
        parts = [self.design.requirement]
        if self.tolerance is not None:
            parts.append(f"speed tolerance {float(self.tolerance.eps)!r}: {self.tolerance.statement}")
        return "; ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return json_safe(
            {
                "controller": self.controller.to_dict(),
                "design": self.design.to_dict(),
                "scope": self.scope,
                "tolerance": None if self.tolerance is None else self.tolerance.to_dict(),
                "requirement": self.requirement,
                **self.corner_dict(),
            }
        )


def _exact_optimum(
    loop: AffineGainLoop | AffineLoop,
    others: tuple[AffineGainLoop | AffineLoop, ...],
    bounds: tuple[float, float],
    objective: str,
    margin_at_least: float | None,
    window: tuple[float, float] | None,
) -> GainDesign | None:
    """The design of :func:`~nrobust.design.best_margin` or :func:`~nrobust.design.best_decay_rate`
    under the requirement (a margin, or a window met by ``loop`` and ``others`` alike; with ``others`` the
    decay rate is the least of them all, ``worst_case``); None when it fails."""
    try:
        if objective == "margin":
            return best_margin(loop, bounds, delays=window, scenarios=others)
        worst_case = bool(others) and window is not None
        return best_decay_rate(
            loop, bounds, margin_at_least=margin_at_least, delays=window, scenarios=others, worst_case=worst_case
        )
    except (CertificationError, ParameterError):
        return None


def _warm_start(
    loop: FilteredLoop,
    bounds: NDArray[np.float64],
    objective: str,
    margin_at_least: float | None,
    window: tuple[float, float] | None = None,
    scenarios: tuple[FilteredLoop, ...] = (),
) -> NDArray[np.float64] | None:
    """A start solved exactly by the one-parameter engine (:mod:`nrobust.design.gain`), under the same requirement
    and objective (with ``scenarios``, the decay rate the least of the loop's and theirs).

    One free parameter: the global optimum on its interval (the loop is affine in it,
    :meth:`FilteredLoop.affine`, as :func:`design_filtered_exact` solves it). Otherwise the
    unfiltered optimum, the best U_BS2(K*) with ``a = b`` (as
    :func:`~nrobust.hyperbolic.analyses.design.design_reflection` solves it): with ``a = b`` the
    filter is 1, its loop that of U_BS2(K*) times ``1 + a s``, so for the decay rate ``a = b`` is
    ``1/(2 r)`` (``r`` the rate of U_BS2(K*), the least one with ``scenarios``: the zero ``-1/a`` at
    ``-2 r`` does not bind; clipped to the bounds), and the filtered design can only improve on it. None
    when the exact design fails, or ``a`` and ``b`` cannot be equal within their bounds.
    """
    requirement = (objective, margin_at_least, window)
    if len(loop.free) == 1:
        one = (float(bounds[0, 0]), float(bounds[0, 1]))
        best = _exact_optimum(loop.affine(), tuple(s.affine() for s in scenarios), one, *requirement)
        if best is not None:
            return np.array([best.K])
    values: dict[str, float] = dict(loop.fixed)
    rate = math.nan
    if "K" in loop.free:
        k_bounds = (float(bounds[loop.free.index("K"), 0]), float(bounds[loop.free.index("K"), 1]))
        K = _exact_optimum(loop.reflection(), tuple(s.reflection() for s in scenarios), k_bounds, *requirement)
        if K is None:
            return None
        values["K"] = K.K
        rate = K.value
    box = {name: bounds[i] for i, name in enumerate(loop.free)}
    lo = max(box["a"][0] if "a" in box else -math.inf, box["b"][0] if "b" in box else -math.inf)
    hi = min(box["a"][1] if "a" in box else math.inf, box["b"][1] if "b" in box else math.inf)
    for name in ("a", "b"):
        if name in values:  # a fixed end: the other must equal it, inside its bounds
            if not lo <= values[name] <= hi:
                return None
            lo = hi = values[name]
    if not lo <= hi or not math.isfinite(lo + hi):
        return None
    shared = 0.5 * (lo + hi)
    if objective == "decay_rate" and math.isfinite(rate) and rate > 0.0:
        # the common factor's zero -1/a at twice the rate, left of the law's rightmost zero: it does not bind
        shared = min(max(0.5 / rate, lo), hi)
    values.setdefault("a", shared)
    values.setdefault("b", shared)
    if values["a"] != values["b"]:
        return None
    return np.array([values[name] for name in loop.free])


def _corner_loops(plant: Hyperbolic2x2, loop: FilteredLoop, eps: float, kernel_grid: int) -> tuple[FilteredLoop, ...]:
    """The loop family on the plants with speeds ``lam (1 +- eps)``, ``mu (1 +- eps)``, the law designed on ``plant``.

    The law of ``FilteredController(a, b, K)`` is U_BS2(K)'s (affine in ``K``) through the filter,
    so on a mismatched plant the loop is ``A (1 + b s) + (B_0 + K R)(1 + a s) e^{-delta s}`` with
    ``A``, ``B_0``, ``R`` of :func:`~nrobust.hyperbolic.analyses.mismatch_gain_loop`; in the order
    ``(-eps, -eps), (-eps, eps), (eps, -eps), (eps, eps)`` of
    :func:`~nrobust.hyperbolic.analyses.speed_tolerance`.
    """
    out = []
    for e_lam in (-eps, eps):
        for e_mu in (-eps, eps):
            g = mismatch_gain_loop(plant, e_lam, e_mu, kernel_grid=kernel_grid)
            out.append(FilteredLoop(g.A, g.B0, g.R, loop.free, loop.fixed))
    return tuple(out)


def design_filtered(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    *,
    objective: str = "decay_rate",
    margin_at_least: float | None = None,
    delays: tuple[float, float] | None = None,
    speed_tolerance: float | None = None,
    parameters: Mapping[str, Any] | None = None,
    x0: ArrayLike | None = None,
    starts: int = 4,
    max_iter: int = 60,
    rigorous: bool = False,
    kernel_grid: int = DEFAULT_KERNEL_GRID,
    executor: Any = "serial",
    progress: bool | None = None,
) -> FilteredDesign:
    """The filtered reflection controller with the best decay rate (or margin), certified.

    A local optimum; with one free parameter, :func:`design_filtered_exact` finds the global one on
    its interval from the equations of its kind.

    ``delays = (d_min, d_max)`` requires exponential stability for every delay of the window at
    every iterate (:func:`nrobust.design.optimize_loop`'s ``delays``; certified at the design by
    :func:`nrobust.design.window_stability`). ``speed_tolerance = eps`` requires it too on the
    plants with speeds ``lam (1 + e_lam)``, ``mu (1 + e_mu)`` at the four corners ``|e_lam| =
    |e_mu| = eps``, the law designed on ``system`` (four more loops of the same parameters,
    :func:`~nrobust.hyperbolic.analyses.mismatch_gain_loop` through the filter); the design is then
    checked at the other points of a 3 x 3 grid of the square (:attr:`FilteredDesign.tolerance`,
    which says what is proven: the corners, and with ``rigorous=True`` the whole square where the
    loop is the PDE itself, an uncoupled plant; elsewhere never the continuum between the points).
    With ``speed_tolerance`` and ``objective="decay_rate"`` the parameters maximise the least decay rate at
    ``delta = 0`` of the nominal loop and the four corners' (``optimize_loop(..., worst_case=True)``: nonsmooth
    where two rates tie, a local optimum); ``value`` is that least rate, on the corners' loops restated with
    their model errors (:attr:`FilteredDesign.corner_abscissae`, :attr:`FilteredDesign.worst_decay_rate` with
    its accuracy), ``design.decay_rate`` the nominal rate.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant (constant ``lam/mu``).
    objective : {"decay_rate", "margin"}
        As in :func:`nrobust.design.optimize_loop`.
    margin_at_least : float, optional
        Required delay margin (with ``"decay_rate"``); with ``speed_tolerance`` it is the window
        ``[0, margin_at_least]`` (``delta* > margin_at_least``) on every plant.
    delays : (float, float), optional
        ``[d_min, d_max]``, ``0 <= d_min <= d_max``, ``d_max > 0``: the window of delays on which
        the designed loop must be exponentially stable; not with ``margin_at_least``.
    speed_tolerance : float, optional
        ``eps`` in ``(0, 1)``: the relative error of ``lam`` and ``mu`` (both signs, together) under
        which the window (or ``[0, margin_at_least]``) must hold too; a
        :class:`~nrobust.hyperbolic.plants.hyperbolic2x2.Hyperbolic2x2` or ``TransportSystem``
        plant only (constant speeds).
    parameters : mapping, optional
        For each of ``"K"``, ``"a"``, ``"b"``: a number (fixed), ``(low, high)`` bounds, or
        None for the default bounds (``|K| <= 0.99 k_bound`` of eq. (54), ``|a| <= tau``,
        ``tau/1000 <= b <= tau``). Default: all three free.
    x0 : sequence of float, optional
        A start for the free parameters, in the order ``K, a, b``. By default, with one free
        parameter, its exact optimum on the interval (as :func:`design_filtered_exact` finds it,
        under the same requirement); otherwise the exact U_BS2(K) design (as
        :func:`~nrobust.hyperbolic.analyses.design.design_reflection` finds it) with ``a = b``
        (the filter 1), so the result is at least as good as the best unfiltered law.
    starts, max_iter, rigorous
        As in :func:`nrobust.design.optimize_loop`.
    kernel_grid : int, default :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID`
        Kernel grid of the mismatched loops (with ``speed_tolerance`` on a coupled plant).
    executor : None, str, int, Executor or dask.distributed.Client
        Where the starts run (:func:`nrobust.sweep_map`); ``"serial"`` in this process.
    progress : bool, optional
        Progress bar (as in :func:`nrobust.k_region`).

    Returns
    -------
    FilteredDesign

    Raises
    ------
    ParameterError
        For bad input: ``delays`` not a window or given with ``margin_at_least``;
        ``speed_tolerance`` outside ``(0, 1)``, without a delay requirement, or on a
        :class:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2`.
    CertificationError
        As :func:`nrobust.design.optimize_loop` (no start feasible, or the design's window not
        certified).
    """
    plant = _plant(system)
    margin_at_least, window, eps = check_local_requirements(plant, objective, margin_at_least, delays, speed_tolerance)
    kernel_grid = check_kernel_grid(kernel_grid)  # checked whether or not a tolerance uses it
    free, bounds = _split(plant, parameters)
    loop = filtered_loop(plant, free)
    scenarios: tuple[FilteredLoop, ...] = ()
    if eps is not None and isinstance(plant, Hyperbolic2x2):
        scenarios = _corner_loops(plant, loop, eps, kernel_grid)
    if x0 is None:
        x0 = _warm_start(loop, bounds, objective, margin_at_least, window, scenarios)
    design = optimize_loop(
        loop,
        bounds,
        objective=objective,
        margin_at_least=margin_at_least,
        delays=window,
        scenarios=scenarios,
        worst_case=objective == "decay_rate" and bool(scenarios),
        x0=x0,
        starts=starts,
        max_iter=max_iter,
        rigorous=rigorous,
        map=mapper(executor, progress, "filtered design"),
    )
    controller = loop.controller(design.parameters)
    scope = loop_scope(plant, controller, None, loop(np.asarray(design.parameters)), mapped=False)
    tolerance = None
    if eps is not None and window is not None and isinstance(plant, Hyperbolic2x2):
        tolerance = tolerance_on_square(
            plant,
            controller,
            eps,
            window,
            kernel_grid=kernel_grid,
            rigorous=rigorous,
            corner_windows=design.windows[1:],
        )
        if objective == "decay_rate":  # the least rate is maximised: each corner's restated with its model error
            corner_abscissae = tuple(
                mismatch_abscissa(plant, controller, a, b, kernel_grid=kernel_grid, rigorous=rigorous)
                for a, b in tolerance.points[:4]
            )
            return FilteredDesign(controller, design, scope, tolerance, corner_abscissae)
    return FilteredDesign(controller, design, scope, tolerance)


def filtered_front(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    required: ArrayLike,
    *,
    delays: tuple[float, float] | Sequence[tuple[float, float]] | None = None,
    speed_tolerance: float | None = None,
    parameters: Mapping[str, Any] | None = None,
    x0: ArrayLike | None = None,
    starts: int = 1,
    max_iter: int = 60,
    rigorous: bool = False,
    kernel_grid: int = DEFAULT_KERNEL_GRID,
    executor: Any = "serial",
    progress: bool | None = None,
) -> ParetoFront:
    """Best decay rate of the filtered reflection controller under each required margin.

    Each point a certified local design (:func:`nrobust.design.pareto_front`), under its required
    delay margin and, at every point, the further requirements of :func:`design_filtered`:
    ``delays``, windows of delays on which the loop must be exponentially stable too, and
    ``speed_tolerance = eps``: the four corner plants with speeds ``lam (1 +- eps)``, ``mu (1 +-
    eps)``, the law designed on ``system``, held to every requirement of the loop (stable for every
    delay in ``[0, d_j]`` and in each window), as ``scenarios`` of the front named by their
    mismatch ``(e_lam, e_mu)``. Only the corners are certified, as by :func:`design_filtered`
    (:func:`~nrobust.hyperbolic.analyses.speed_tolerance` checks the square between them). With
    ``speed_tolerance`` each point maximises, as :func:`design_filtered` does, the least decay rate at
    ``delta = 0`` of the nominal loop and the corners' (``pareto_front(..., worst_case=True)``), and the front's
    :attr:`~nrobust.design.ParetoFront.decay_rates` are those least rates, with the corners' abscissae restated
    by :func:`~nrobust.hyperbolic.analyses.mismatch_abscissa` with its model error
    (:attr:`~nrobust.design.ParetoFront.scenario_abscissae`, as :attr:`FilteredDesign.corner_abscissae`; a point
    is certified only with them): a point is :func:`design_filtered`'s ``value`` at its margin from the same start.

    Parameters
    ----------
    system, parameters, x0, starts, max_iter, rigorous, kernel_grid, executor, progress
        As in :func:`design_filtered`.
    required : sequence of float
        The required delay margins (``>= 0``; ``> 0`` with ``speed_tolerance`` unless ``delays``
        is given).
    delays : (float, float) or sequence of (float, float), optional
        Windows ``[d_min, d_max]`` (``0 <= d_min <= d_max``, ``d_max > 0``) on which every
        design must be stable too.
    speed_tolerance : float, optional
        ``eps`` in ``(0, 1)``; a :class:`~nrobust.hyperbolic.plants.hyperbolic2x2.Hyperbolic2x2`
        or ``TransportSystem`` plant only (constant speeds).

    Returns
    -------
    ParetoFront

    Raises
    ------
    ParameterError
        For bad input (``speed_tolerance`` outside ``(0, 1)`` or on a
        :class:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2`; as
        :func:`nrobust.design.pareto_front` for ``required`` and ``delays``).
    """
    plant = _plant(system)
    kernel_grid = check_kernel_grid(kernel_grid)
    free, bounds = _split(plant, parameters)
    loop = filtered_loop(plant, free)
    scenarios: dict[str, FilteredLoop] = {}
    corners: list[tuple[float, float]] = []
    if speed_tolerance is not None:
        eps = check_speed_tolerance(speed_tolerance, plant=plant)
        corners = [(e_lam, e_mu) for e_lam in (-eps, eps) for e_mu in (-eps, eps)]  # _corner_loops' order
        names = [f"(e_lam, e_mu) = ({e_lam!r}, {e_mu!r})" for e_lam, e_mu in corners]
        # a Hyperbolic2x2: check_speed_tolerance refuses any other plant
        scenarios = dict(zip(names, _corner_loops(cast(Hyperbolic2x2, plant), loop, eps, kernel_grid)))
    front = pareto_front(
        loop,
        bounds,
        required,
        delays=delays,
        scenarios=scenarios,
        worst_case=bool(scenarios),
        x0=x0,
        starts=starts,
        max_iter=max_iter,
        rigorous=rigorous,
        map=mapper(executor, progress, "trade-off front"),
    )
    if not corners:
        return front
    # each point's corners restated with their model error, as design_filtered's corner_abscissae
    restated = tuple(
        tuple(
            mismatch_abscissa(
                cast(Hyperbolic2x2, plant),
                loop.controller(design.parameters),
                e_lam,
                e_mu,
                kernel_grid=kernel_grid,
                rigorous=rigorous,
            )
            for e_lam, e_mu in corners
        )
        for design in front.designs
    )
    least = [min(-a.value for a in (d.abscissa, *r)) for d, r in zip(front.designs, restated)]
    return dataclasses.replace(front, decay_rates=np.array(least, dtype=float), scenario_abscissae=restated)


@dataclass(frozen=True)
class ExactFilteredDesign:
    """``FilteredController(a, b, K)`` with one parameter designed exactly, with its certificate.

    Attributes
    ----------
    controller : FilteredController
        The design.
    parameter : str
        The designed parameter: ``"K"``, ``"a"`` or ``"b"``.
    design : GainDesign
        The core's result (:func:`nrobust.design.best_margin` or
        :func:`nrobust.design.best_decay_rate` on the loop affine in ``parameter``):
        ``design.K`` is the parameter's value, with its kind, the brackets of the optimum and
        the certified delay margin of the designed loop.
    scope : str
        What the certificate is about: the PDE itself (constant coefficients) or a model.
    """

    controller: FilteredController
    parameter: str
    design: GainDesign
    scope: str

    @property
    def optimum(self) -> float:
        """The designed value of :attr:`parameter`."""
        return self.design.K

    @property
    def value(self) -> float:
        """The objective at the design: the delay margin or the decay rate."""
        return self.design.value

    @property
    def kind(self) -> str:
        """What decides the optimum (:data:`nrobust.design.gain.DESIGN_KINDS`)."""
        return self.design.kind

    @property
    def certified(self) -> str:
        """``"proven"`` or ``"checked"`` (``GainDesign.certified``)."""
        return self.design.certified

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return json_safe(
            {
                "controller": self.controller.to_dict(),
                "parameter": self.parameter,
                "design": self.design.to_dict(),
                "scope": self.scope,
            }
        )

    def __repr__(self) -> str:
        return f"ExactFilteredDesign({self.controller!r}, {self.design.summary(self.parameter)})"


def _exact_bounds(
    plant: Hyperbolic2x2 | GeneralHyperbolic2x2, name: str, fixed: Mapping[str, float]
) -> tuple[float, float]:
    """Default interval of the free parameter: :func:`design_filtered`'s, where the loop is strongly stable.

    The delayed loop's difference operator ``b (1 - rho q e^{-tau s}) + a K q e^{-(tau + delta) s}``
    (``1 - rho q e^{-tau s} + K q e^{-(tau + delta) s}`` without a filter) is strongly stable iff
    ``|a K| < |b| k`` (``|K| < k`` when ``a = b = 0``), ``k = (1 - |rho q|)/|q|`` of eq. (54);
    the default keeps ``|a K| <= 0.9 |b| k`` (``b >= |a K| / (0.9 k)``): the crossing curves reach
    frequencies growing like ``1/(|b| k - |a K|)`` (the first-order bound of
    :func:`nrobust.margins.frequency_bound`), each a sample of the scan.
    """
    k = classify(plant).k_bound
    lo, hi = default_filter_bounds(plant)[name]
    K, a, b = fixed.get("K", 0.0), fixed.get("a", 0.0), fixed.get("b", 0.0)
    if name == "K" and a != 0.0:
        hi = min(hi, _SS_FRACTION * abs(b) * k / abs(a))
        lo = -hi
    elif name == "a":
        if b == 0.0:
            raise ParameterError("parameters['b']", "b > 0 with a free zero a (else the loop is advanced)", b)
        if K != 0.0:
            hi = min(hi, _SS_FRACTION * abs(b) * k / abs(K))
            lo = -hi
    elif name == "b" and a * K != 0.0:
        lo = max(lo, abs(a * K) / (_SS_FRACTION * k)) if k > 0.0 else math.inf
    if not lo < hi:
        raise ParameterError(
            f"parameters[{name!r}]",
            f"bounds given explicitly: the default interval of {name} is empty where the loop is strongly stable",
            (lo, hi),
        )
    return lo, hi


def design_filtered_exact(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    objective: str = "margin",
    *,
    parameters: Mapping[str, Any],
    margin_at_least: float | None = None,
    delays: tuple[float, float] | None = None,
    rigorous: bool = False,
    max_evals: int = 2_000_000,
) -> ExactFilteredDesign:
    """One parameter of ``FilteredController(a, b, K)`` designed exactly: the global optimum on its interval.

    The loop (eq. (60) with ``A`` multiplied by ``1 + b s`` and ``B`` by ``1 + a s``) is affine in
    each parameter (:meth:`FilteredLoop.affine`); its delay margin ``delta*(p)`` is the lower
    envelope of explicit crossing curves, and the largest margin (``objective="margin"``,
    :func:`nrobust.design.best_margin`) or the largest decay rate at ``delta = 0`` among the
    parameters with ``delta*(p) >= margin_at_least`` (``objective="decay_rate"``,
    :func:`nrobust.design.best_decay_rate`) is solved from the equation of its kind (a kink,
    a pair birth, a smooth maximum, an end, a margin constraint) and certified.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant (constant ``lam/mu``).
    objective : {"margin", "decay_rate"}
        What to maximise.
    parameters : mapping
        ``"K"``, ``"a"``, ``"b"``: exactly one free, given as ``(low, high)`` or None (default
        bounds: those of :func:`design_filtered`, narrowed to where the delayed loop stays strongly
        stable, ``|a K| < b (1 - |rho q|)/|q|``), the other two numbers.
    margin_at_least : float, optional
        The delay margin required (``> 0``); required with ``objective="decay_rate"`` unless
        ``delays`` is given.
    delays : (float, float), optional
        ``[d_min, d_max]``: the window of delays on which the design must be exponentially stable
        (``delays`` of :func:`nrobust.design.best_decay_rate` and :func:`nrobust.design.best_margin`;
        ``d_min > 0`` allows a loop unstable at ``delta = 0``); not with ``margin_at_least``.
    rigorous : bool, optional
        Prove the delay margin of the design in ball arithmetic.
    max_evals : int, optional
        Work bound of the scan of the crossing curves and of the certificate.

    Returns
    -------
    ExactFilteredDesign

    Raises
    ------
    ParameterError
        Not exactly one free parameter, the others not numbers, an unknown ``objective``,
        ``margin_at_least`` missing or not positive, bounds where the loop is not strongly stable.
    CertificationError
        As :func:`nrobust.design.best_margin` and :func:`nrobust.design.best_decay_rate`.
    """
    if objective not in ("margin", "decay_rate"):
        raise ParameterError("objective", "'margin' or 'decay_rate'", objective)
    if objective == "margin" and margin_at_least is not None:
        raise ParameterError(
            "margin_at_least", "None with objective='margin' (it constrains the decay rate)", margin_at_least
        )
    if objective == "decay_rate" and margin_at_least is None and delays is None:
        raise ParameterError("margin_at_least", "a positive delay margin with objective='decay_rate' (or delays)", None)
    window = None if delays is None else check_delays(delays)
    plant = _plant(system)
    given = dict(parameters)
    unknown = set(given) - set(FILTER_PARAMETERS)
    free_names = [n for n in FILTER_PARAMETERS if not is_real_number(given.get(n))]
    if unknown or len(free_names) != 1:
        raise ParameterError(
            "parameters",
            "a mapping of 'K', 'a', 'b': one of them free ((low, high) or None), the other two numbers",
            parameters,
        )
    name = free_names[0]
    fixed = {n: float(given[n]) for n in FILTER_PARAMETERS if n != name}
    if given.get(name) is None:
        bounds = _exact_bounds(plant, name, fixed)
    else:
        _, box = _split(plant, {**fixed, name: given[name]})
        bounds = (float(box[0, 0]), float(box[0, 1]))
    family = filtered_loop(plant, {**fixed, name: None})
    loop = family.affine()
    try:
        if objective == "margin":
            design = best_margin(loop, bounds, delays=window, rigorous=rigorous, max_evals=max_evals)
        else:
            design = best_decay_rate(
                loop, bounds, margin_at_least=margin_at_least, delays=window, rigorous=rigorous, max_evals=max_evals
            )
    except ParameterError as exc:
        if exc.name != "bounds":
            raise
        raise ParameterError(f"parameters[{name!r}]", exc.requirement, exc.value) from exc
    controller = family.controller([design.K])
    return ExactFilteredDesign(
        controller, name, design, loop_scope(plant, controller, None, family(np.array([design.K])), mapped=False)
    )
