"""Design of the filtered reflection controller: gain ``K``, filter zero ``a`` and pole ``b``.

``FilteredController(a, b, K)`` passes U_BS2(K) (eq. (53)) through ``(1 + a s)/(1 + b s)``
(section 2.3.2); its loop is eq. (60) with ``A`` multiplied by ``1 + b s`` and ``B`` by
``1 + a s``. :func:`design_filtered` maximises the decay rate subject to a delay margin, or the
margin, over any of the three parameters (the others fixed) with the core's local nonsmooth
optimiser (:func:`nrobust.design.optimize_loop`), and certifies the design;
:func:`filtered_front` is the trade-off of decay rate against delay margin over all three.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._json import json_safe
from ..._validate import is_real_number
from ...design.local import LoopDesign, optimize_loop
from ...design.pareto import ParetoFront, pareto_front
from ...errors import CertificationError, ParameterError
from ...quasipoly import QuasiPolynomial
from ..loops.controllers import FilteredController, ReflectionController, classify, loop_factors, loop_scope
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from ._common import mapper
from .design import design_reflection

__all__ = ["FILTER_PARAMETERS", "FilteredDesign", "FilteredLoop", "design_filtered", "filtered_front", "filtered_loop"]

#: The parameters of ``FilteredController(a, b, K)`` a design may vary, in this order.
FILTER_PARAMETERS = ("K", "a", "b")


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


def _plant(system: Any) -> Hyperbolic2x2 | GeneralHyperbolic2x2:
    if isinstance(system, GeneralHyperbolic2x2) and not system.constant_ratio:
        raise ParameterError("system", "a plant with a constant lam/mu (U_BS2(K) lives on the normal form)", system)
    if not isinstance(system, (Hyperbolic2x2, GeneralHyperbolic2x2)):
        raise ParameterError("system", "a Hyperbolic2x2, TransportSystem or GeneralHyperbolic2x2", system)
    return system


def _default_bounds(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> dict[str, tuple[float, float]]:
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


def _split(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2, parameters: Mapping[str, Any] | None
) -> tuple[dict[str, Any], NDArray[np.float64]]:
    """``(free, bounds)``: each parameter a number (fixed), ``(low, high)`` or None (default bounds)."""
    given = dict(parameters or {})
    unknown = set(given) - set(FILTER_PARAMETERS)
    if unknown:
        raise ParameterError("parameters", f"a mapping with keys among {FILTER_PARAMETERS}", sorted(unknown))
    default = _default_bounds(system)
    bounds = []
    free: dict[str, Any] = {}
    for name in FILTER_PARAMETERS:
        value = given.get(name)
        if is_real_number(value):
            free[name] = float(value)  # type: ignore[arg-type]
            continue
        lo, hi = default[name] if value is None else value
        if name == "b" and not lo > 0.0:
            raise ParameterError("parameters['b']", "bounds (low, high) with 0 < low < high (the filter's pole)", value)
        free[name] = None
        bounds.append((float(lo), float(hi)))
    if not bounds:
        raise ParameterError("parameters", "at least one free parameter (a pair of bounds or None)", parameters)
    return free, np.array(bounds)


@dataclass(frozen=True)
class FilteredDesign:
    """A designed ``FilteredController(a, b, K)`` with its certificate.

    Attributes
    ----------
    controller : FilteredController
        The design.
    design : LoopDesign
        The core's result: objective value, certified abscissa and delay margin, the runs.
    scope : str
        What the certificate is about: the PDE itself (constant coefficients) or a model.
    """

    controller: FilteredController
    design: LoopDesign
    scope: str

    @property
    def value(self) -> float:
        """The objective at the design (decay rate or delay margin)."""
        return self.design.value

    @property
    def certified(self) -> bool:
        """Whether the design's abscissa and margin are certified (see :class:`LoopDesign`)."""
        return self.design.certified

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return json_safe(
            {"controller": self.controller.to_dict(), "design": self.design.to_dict(), "scope": self.scope}
        )


def _warm_start(
    plant: Hyperbolic2x2 | GeneralHyperbolic2x2,
    loop: FilteredLoop,
    bounds: NDArray[np.float64],
    objective: str,
    margin_at_least: float | None,
) -> NDArray[np.float64] | None:
    """The unfiltered optimum as a start: U_BS2(K*) of :func:`design_reflection` with ``a = b``.

    With ``a = b`` the filter is 1, so the start is the best U_BS2(K) (solved exactly) and the
    filtered design can only improve on it. None when ``a`` and ``b`` cannot be equal within
    their bounds, or the exact design fails.
    """
    values: dict[str, float] = dict(loop.fixed)
    if "K" in loop.free:
        k_bounds = tuple(bounds[loop.free.index("K")])
        try:
            best = design_reflection(plant, objective, margin_at_least=margin_at_least, K_bounds=k_bounds)
        except (CertificationError, ParameterError):
            return None
        values["K"] = best.K
    box = {name: bounds[i] for i, name in enumerate(loop.free)}
    lo = max(box["a"][0] if "a" in box else -math.inf, box["b"][0] if "b" in box else -math.inf)
    hi = min(box["a"][1] if "a" in box else math.inf, box["b"][1] if "b" in box else math.inf)
    for name in ("a", "b"):
        if name in values:  # a fixed end: the other must equal it
            lo = hi = values[name]
    if not lo <= hi or not math.isfinite(lo + hi):
        return None
    shared = 0.5 * (lo + hi)
    values.setdefault("a", shared)
    values.setdefault("b", shared)
    if values["a"] != values["b"]:
        return None
    return np.array([values[name] for name in loop.free])


def design_filtered(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    *,
    objective: str = "decay_rate",
    margin_at_least: float | None = None,
    parameters: Mapping[str, Any] | None = None,
    x0: ArrayLike | None = None,
    starts: int = 4,
    max_iter: int = 60,
    rigorous: bool = False,
    executor: Any = "serial",
    progress: bool | None = None,
) -> FilteredDesign:
    """The filtered reflection controller with the best decay rate (or margin), certified.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant (constant ``lam/mu``).
    objective : {"decay_rate", "margin"}
        As in :func:`nrobust.design.optimize_loop`.
    margin_at_least : float, optional
        Required delay margin (with ``"decay_rate"``).
    parameters : mapping, optional
        For each of ``"K"``, ``"a"``, ``"b"``: a number (fixed), ``(low, high)`` bounds, or
        None for the default bounds (``|K| <= 0.99 k_bound`` of eq. (54), ``|a| <= tau``,
        ``tau/1000 <= b <= tau``). Default: all three free.
    x0 : sequence of float, optional
        A start for the free parameters, in the order ``K, a, b``. By default the exact
        U_BS2(K) design (:func:`~nrobust.hyperbolic.analyses.design.design_reflection`) with
        ``a = b`` (the filter 1), so the result is at least as good as the best unfiltered law.
    starts, max_iter, rigorous
        As in :func:`nrobust.design.optimize_loop`.
    executor : None, str, int, Executor or dask.distributed.Client
        Where the starts run (:func:`nrobust.sweep_map`); ``"serial"`` in this process.
    progress : bool, optional
        Progress bar (as in :func:`nrobust.k_region`).

    Returns
    -------
    FilteredDesign
    """
    plant = _plant(system)
    free, bounds = _split(plant, parameters)
    loop = filtered_loop(plant, free)
    if x0 is None:
        x0 = _warm_start(plant, loop, bounds, objective, margin_at_least)
    design = optimize_loop(
        loop,
        bounds,
        objective=objective,
        margin_at_least=margin_at_least,
        x0=x0,
        starts=starts,
        max_iter=max_iter,
        rigorous=rigorous,
        map=mapper(executor, progress, "filtered design"),
    )
    controller = loop.controller(design.parameters)
    return FilteredDesign(controller, design, loop_scope(plant, controller, None, loop(np.asarray(design.parameters))))


def filtered_front(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    required: ArrayLike,
    *,
    parameters: Mapping[str, Any] | None = None,
    x0: ArrayLike | None = None,
    starts: int = 1,
    max_iter: int = 60,
    rigorous: bool = False,
    executor: Any = "serial",
    progress: bool | None = None,
) -> ParetoFront:
    """Best decay rate of the filtered reflection controller under each required margin.

    Parameters are as in :func:`design_filtered`; ``required`` the delay margins (each point
    a certified local design, :func:`nrobust.design.pareto_front`).
    """
    plant = _plant(system)
    free, bounds = _split(plant, parameters)
    return pareto_front(
        filtered_loop(plant, free),
        bounds,
        required,
        x0=x0,
        starts=starts,
        max_iter=max_iter,
        rigorous=rigorous,
        map=mapper(executor, progress, "trade-off front"),
    )
