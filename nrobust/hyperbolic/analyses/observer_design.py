"""Design of the collocated observer's own reflection: :func:`design_collocated_observer`.

The collocated observer (:class:`~nrobust.hyperbolic.loops.controllers.CollocatedOutputFeedback`)
may keep a reflection ``kappa`` of its own at ``x = 1``, ``v^(t, 1) = (rho - kappa) y +
kappa u^(t, 1) + U_o``, as ``U_BS2(K)`` (eq. (53)) keeps ``rho - K`` for the controller: its error is
then no longer zero after ``tau``, its characteristic function is ``E = 1 - kappa H_y``
(:mod:`~nrobust.hyperbolic.loops.collocated`), and the loop is

    A_o(kappa) = E A - n G e^{-delta_o s},    B_o(kappa) = E B + n G,

affine in ``kappa`` in both factors (:class:`nrobust.design.AffineLoop`, its slopes
``-d (1 - Phi) H_y`` and ``-n B~ H_y``). For a fixed law the best ``kappa`` is therefore found
exactly by the core's one-parameter engine (:func:`nrobust.design.best_margin`,
:func:`nrobust.design.best_decay_rate`: kinks, pair births, ends, solved from their equations,
the design certified). Its difference operator for U_BS2(K) with ``delta_o = 0`` is
``1 - (rho - K + kappa) q e^{-tau s} + (kappa - K) rho q^2 e^{-2 tau s} + K (rho - kappa) q^2
e^{-(2 tau + delta) s}``; in general its principal coefficients are affine in ``kappa``, so
``gamma_0(kappa)`` is convex and piecewise linear and the interval where it is below 1 (strong
stability) has closed-form ends (:func:`observer_reflection_bounds`).
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..._json import fields_dict
from ..._validate import finite_real, nonnegative, positive
from ...design.gain import AffineLoop, GainDesign, best_decay_rate, best_margin
from ...errors import CertificationError, ParameterError
from ...margins.margin import delay_margin
from ...quasipoly import QuasiPolynomial
from ..loops.controllers import (
    CollocatedOutputFeedback,
    Controller,
    FilteredController,
    ReflectionController,
    loop_factors,
    loop_route,
    loop_scope,
    observer_reflection_of,
)
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from ._common import study_plant

__all__ = [
    "OBSERVER_OBJECTIVES",
    "ObserverDesign",
    "collocated_observer_loop",
    "design_collocated_observer",
    "observer_reflection_bounds",
]

#: Objectives of :func:`design_collocated_observer`.
OBSERVER_OBJECTIVES = ("margin", "decay_rate")
#: Default bounds: the strongly stable interval less this fraction of its width at each end (the
#: crossing curves reach frequencies growing like 1/distance to its ends).
_SHRINK = 0.1
#: Gains near the top of the sampled envelope (within this fraction of it) whose certified margins the
#: design must match or beat, at most this many.
_TOP_FRACTION, _TOP_CHECKS = 0.01, 5


@dataclass(frozen=True)
class ObserverDesign:
    """The designed collocated observer (and law) with its certificate.

    Attributes
    ----------
    controller : CollocatedOutputFeedback
        The law on the observer's estimate, with the designed ``observer_reflection``.
    design : GainDesign
        The core's result: the kind of the optimum, its bracket and the certified margin
        (``certificate.scope`` saying what it is about).
    bounds : (float, float)
        The reflections searched.
    scope : str
        What the certificate is about (:func:`~nrobust.hyperbolic.loops.controllers.loop_scope`).
    """

    controller: CollocatedOutputFeedback
    design: GainDesign
    bounds: tuple[float, float]
    scope: str

    @property
    def kappa(self) -> float:
        """The designed observer reflection."""
        return self.controller.observer_reflection

    @property
    def value(self) -> float:
        """The objective at the design: the delay margin or the decay rate."""
        return float(self.design.value)

    @property
    def kind(self) -> str:
        """What decides the optimum (:data:`nrobust.design.gain.DESIGN_KINDS`)."""
        return self.design.kind

    def __repr__(self) -> str:
        return f"ObserverDesign({self.controller!r}, {self.design!r})"  # the value to its accuracy

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


def _reflection_controller(controller: CollocatedOutputFeedback, kappa: float) -> CollocatedOutputFeedback:
    return dataclasses.replace(controller, observer_reflection=float(kappa))


def collocated_observer_loop(system: Hyperbolic2x2, controller: CollocatedOutputFeedback) -> AffineLoop:
    """The loop of ``controller`` as ``(A_0 + kappa A_1) + (B_0 + kappa B_1) e^{-delta s}`` in its reflection.

    ``A_0, B_0``: the loop at ``kappa = 0``; ``A_1 = -d (1 - Phi) H_y``, ``B_1 = -n B~ H_y``
    (:func:`~nrobust.hyperbolic.loops.controllers.observer_reflection_of`; ``n/d`` the law's
    filter), the very terms :func:`~nrobust.hyperbolic.loops.controllers.loop_factors` adds.
    """
    A0, B0 = loop_factors(system, _reflection_controller(controller, 0.0))
    reflection = observer_reflection_of(system, controller)
    inner = controller.controller
    numerator = [1.0, inner.a] if isinstance(inner, FilteredController) else [1.0]
    denominator = [1.0, inner.b] if isinstance(inner, FilteredController) else [1.0]
    return AffineLoop(
        A0, -reflection.open_loop_product.times_poly(denominator), B0, -reflection.law_product.times_poly(numerator)
    )


def _principal(A: QuasiPolynomial, B: QuasiPolynomial, n: int) -> dict[tuple[str, float], float]:
    """The ``s^n`` point coefficients of ``A`` and ``B``, summed per delay (keys ``("A" | "B", delay)``)."""
    out: dict[tuple[str, float], float] = {}
    for name, factor in (("A", A), ("B", B)):
        if factor.degree < n:
            continue
        for c, t in factor.leading_terms(n):
            key = (name, round(float(t), 12))
            out[key] = out.get(key, 0.0) + float(c.real)
    return out


def observer_reflection_bounds(loop: AffineLoop) -> tuple[float, float]:
    """The open interval of ``kappa`` where the difference operator of ``loop`` is strongly stable.

    ``gamma_0(kappa) = (sum_{k>=1} |a_k + kappa a'_k| + sum_k |b_k + kappa b'_k|) / |a_0|`` over the
    principal coefficients (the ``B`` terms at a generic delay): convex and piecewise linear, its
    level 1 is solved on the linear piece where it is reached.

    Raises
    ------
    ParameterError
        No ``kappa`` is strongly stable, or the interval is unbounded (``q = 0``: give the bounds).
    """
    n = loop.A0.degree
    at0 = _principal(loop.A(0.0), loop.B(0.0), n)
    at1 = _principal(loop.A(1.0), loop.B(1.0), n)
    keys = sorted(set(at0) | set(at1))
    c0 = np.array([at0.get(k, 0.0) for k in keys])
    c1 = np.array([at1.get(k, 0.0) for k in keys]) - c0
    lead = [i for i, k in enumerate(keys) if k == ("A", 0.0)]
    if len(lead) != 1 or c1[lead[0]] != 0.0 or c0[lead[0]] == 0.0:
        raise ParameterError("controller", "a loop whose undelayed leading coefficient does not depend on kappa", loop)
    a0 = abs(c0[lead[0]])
    c0, c1 = np.delete(c0, lead[0]), np.delete(c1, lead[0])

    def gamma(kappa: float) -> float:
        return float(np.sum(np.abs(c0 + kappa * c1))) / a0

    moving = c1 != 0.0
    kinks = np.sort(-c0[moving] / c1[moving])
    best = min(kinks, key=gamma) if kinks.size else 0.0
    if not gamma(best) < 1.0:
        raise ParameterError("controller", "a law for which some observer reflection is strongly stable", loop)
    ends = []
    for side in (-1.0, 1.0):
        steps = [k for k in (kinks if side > 0 else kinks[::-1]) if side * (k - best) > 0.0]
        slope_far = float(np.sum(np.abs(c1))) / a0
        if slope_far == 0.0:
            raise ParameterError("kappa_bounds", "given: every observer reflection is strongly stable here", None)
        points = [best, *steps, (steps[-1] if steps else best) + side * (1.0 + gamma(best)) / slope_far]
        for a, b in itertools.pairwise(points):
            fa, fb = gamma(a) - 1.0, gamma(b) - 1.0
            if fa < 0.0 <= fb:
                ends.append(a + (b - a) * (-fa) / (fb - fa))
                break
    return float(ends[0]), float(ends[1])


def design_collocated_observer(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    objective: str = "margin",
    *,
    controller: Controller | None = None,
    margin_at_least: float | None = None,
    kappa_bounds: tuple[float, float] | None = None,
    observer_delay: float = 0.0,
    rigorous: bool = False,
    max_evals: int = 2_000_000,
) -> ObserverDesign:
    """The collocated observer's reflection ``kappa`` with the best delay margin or decay rate, for a given law.

    ``objective="margin"``: the largest delay margin of the loop; ``"decay_rate"``: the largest
    decay rate at ``delta = 0`` (that of ``E`` times the state feedback's loop: the slower of the
    observer's error and the law's target system) among the designs with a delay margin of at least
    ``margin_at_least``. The optimum over ``kappa`` is exact (:func:`nrobust.design.best_margin`,
    :func:`nrobust.design.best_decay_rate` on :func:`collocated_observer_loop`: the equation of its
    kind solved) and certified; with the margin objective the margin at the top of the sampled
    envelope is certified too, and must not beat the design.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant (a general plant with a constant ``lam/mu`` through its normal form).
    objective : {"margin", "decay_rate"}
        What to maximise.
    controller : Controller, optional
        The state feedback on the observer's estimate (default ``ReflectionController(0.1)``).
    margin_at_least : float, optional
        The delay margin required (``> 0``), with ``objective="decay_rate"`` only.
    kappa_bounds : (float, float), optional
        The reflections searched; default the interval where the loop's difference operator is
        strongly stable (:func:`observer_reflection_bounds`, at ``controller``'s gain) less 10 % of
        its width at each end.
    observer_delay : float, default 0
        The delay of the commands the observer replays.
    rigorous : bool, optional
        Prove the delay margin of the design in ball arithmetic.
    max_evals : int, optional
        Work bound of the exact design's sampling of the crossing curves (near the ends of the
        strongly stable interval they reach high frequencies).

    Returns
    -------
    ObserverDesign

    Raises
    ------
    ParameterError
        Bad input, or bounds where the difference operator is not strongly stable.
    CertificationError
        As the core's designs (a missed crossing curve, no feasible design), or a margin at the
        top of the sampled envelope larger than the design's (the optimum's equations converged to
        another point; ``kappa_bounds`` about that top help).
    """
    if objective not in OBSERVER_OBJECTIVES:
        raise ParameterError("objective", f"one of {OBSERVER_OBJECTIVES}", objective)
    if objective == "decay_rate":
        if margin_at_least is None:
            raise ParameterError("margin_at_least", "a positive delay margin with objective='decay_rate'", None)
        margin_at_least = positive("margin_at_least", margin_at_least)
    elif margin_at_least is not None:
        raise ParameterError("margin_at_least", "None with objective='margin'", margin_at_least)
    observer_delay = nonnegative("observer_delay", observer_delay)
    plant: Hyperbolic2x2 = study_plant(system, None, "design_collocated_observer")[0]
    inner = ReflectionController(0.1) if controller is None else controller
    if not isinstance(inner, Controller) or isinstance(inner, CollocatedOutputFeedback):
        raise ParameterError("controller", "a state feedback of the package", controller)
    base = CollocatedOutputFeedback(inner, observer_delay)
    loop = collocated_observer_loop(plant, base)
    bounds = _bounds("kappa_bounds", kappa_bounds) if kappa_bounds is not None else _default_bounds(loop)
    if objective == "margin":
        design = best_margin(loop, bounds, rigorous=rigorous, max_evals=max_evals)
        _check_envelope_top(loop, design)
    else:
        assert margin_at_least is not None
        design = best_decay_rate(loop, bounds, margin_at_least=margin_at_least, rigorous=rigorous, max_evals=max_evals)
    designed = _reflection_controller(base, design.K)
    factors = loop_factors(plant, designed)
    scope = loop_scope(plant, designed, None, factors)
    certificate = dataclasses.replace(
        design.certificate, scope=scope, of_model=loop_route(plant, designed, None) != "exact" and not plant.uncoupled
    )
    return ObserverDesign(designed, dataclasses.replace(design, certificate=certificate), bounds, scope)


def _check_envelope_top(loop: AffineLoop, design: GainDesign) -> None:
    """No certified margin near the top of the sampled envelope beats the design's (else it is not the optimum).

    The envelope only locates the optimum (interpolated on the sampled crossing curves, it can err
    by about 1e-3 where a curve is steep in ``kappa``); up to :data:`_TOP_CHECKS` gains where it is
    within :data:`_TOP_FRACTION` of its top are checked with a certified margin, so that a kink whose
    equations converged to another pair of curves, or an end the envelope overrates, is not
    returned as the best ``kappa``.
    """
    env = np.asarray(design.envelope, dtype=float)
    near = np.flatnonzero(env >= (1.0 - _TOP_FRACTION) * float(np.max(env)))
    picks = {int(np.argmax(env))} | {int(near[int(i)]) for i in np.linspace(0, near.size - 1, _TOP_CHECKS).round()}
    for i in sorted(picks):
        top = float(design.gains[i])
        if top == design.K:
            continue
        margin = delay_margin(loop.A(top), loop.B(top))
        if margin.margin > design.value * (1.0 + 1e-9):
            raise CertificationError(
                f"design_collocated_observer: the {design.kind} at kappa = {design.K:.12g} has delay margin "
                f"{design.value:.12g}, but kappa = {top:.12g} has {margin.margin:.12g} (the equations of the "
                "optimum converged away from the top of the envelope): kappa_bounds about the latter give its optimum"
            )


def _bounds(name: str, value: Any) -> tuple[float, float]:
    try:
        lo, hi = (finite_real(name, v) for v in value)
    except (TypeError, ValueError) as exc:
        raise ParameterError(name, "a pair (low, high) of finite numbers, low < high", value) from exc
    if not lo < hi:
        raise ParameterError(name, "a pair (low, high) of finite numbers, low < high", value)
    return lo, hi


def _default_bounds(loop: AffineLoop) -> tuple[float, float]:
    lo, hi = observer_reflection_bounds(loop)
    width = hi - lo
    return float(lo + _SHRINK * width), float(hi - _SHRINK * width)
