"""Design of the reflection controller ``U_BS2(K)`` (eq. (53)): :func:`design_reflection`.

The paper's design rule (section 4.2.1, the remark after Lemma 3): keep a fraction ``K`` of
the proximal reflection, trading the nominal decay rate for a delay margin. Its loop
(eq. (60)) is affine in ``K``, and the core's :mod:`nrobust.design.gain` finds the best
``K`` from the equations of its kind (a kink of ``delta*(K)``, a pair birth, an interior
maximum, or where ``delta*(K)`` equals a required margin) and certifies the designed loop.
With ``output_feedback=True`` the law acts on the state predicted from ``y = v(t, 0)``
(:class:`~nrobust.hyperbolic.loops.controllers.OutputFeedback`): its loop is affine in ``K``
too, with the observer's term in ``A`` and ``B_0``
(:mod:`~nrobust.hyperbolic.loops.output_feedback`), and the same equations design it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from ..._json import fields_dict
from ..._validate import nonnegative, positive
from ...design.gain import GainDesign, best_decay_rate, best_margin
from ...errors import ParameterError
from ...margins.gain import AffineGainLoop
from ..loops.controllers import (
    Controller,
    OutputFeedback,
    ReflectionController,
    classify,
    loop_factors,
    loop_route,
    loop_scope,
)
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from ._common import study_plant
from .kregion import u_bs2_loop

__all__ = ["DESIGN_OBJECTIVES", "ReflectionDesign", "design_reflection"]

#: Objectives of :func:`design_reflection`.
DESIGN_OBJECTIVES = ("margin", "decay_rate")
# Default gains: this fraction of the strong-stability bound (eq. (54)) on each side; for output
# feedback a smaller one: the observer's term starts with a jump at the window w = 1/mu, so the
# crossing curves reach frequencies growing like 1/(bound - |K|), not its square root.
_BOUND_FRACTION, _OUTPUT_BOUND_FRACTION = 0.99, 0.9


@dataclass(frozen=True)
class ReflectionDesign:
    """The designed ``U_BS2(K)`` with its certificate.

    Attributes
    ----------
    controller : ReflectionController or OutputFeedback
        ``ReflectionController(K)`` at the designed gain (an :class:`OutputFeedback` of it when
        designed for output feedback).
    design : GainDesign
        The core's result: the objective value, its kind, the brackets of the optimum and the
        certified delay margin of the designed loop (``design.certificate``, whose ``scope``
        says whether the proof is about the PDE itself or a model of it).
    """

    controller: Controller
    design: GainDesign

    @property
    def K(self) -> float:
        """The designed gain."""
        return self.design.K

    @property
    def value(self) -> float:
        """The objective at the design: the delay margin or the decay rate."""
        return self.design.value

    @property
    def kind(self) -> str:
        """What decides the optimum (:data:`nrobust.design.gain.DESIGN_KINDS`)."""
        return self.design.kind

    def __repr__(self) -> str:
        return f"ReflectionDesign({self.controller!r}, {self.design!r})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


def design_reflection(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    objective: str = "margin",
    *,
    margin_at_least: float | None = None,
    K_bounds: tuple[float, float] | None = None,
    rigorous: bool = False,
    output_feedback: bool = False,
    observer_delay: float = 0.0,
) -> ReflectionDesign:
    """The gain ``K`` of ``U_BS2(K)`` (eq. (53)) that maximises the delay margin or the decay rate.

    ``objective="margin"``: the largest delay margin ``delta*(K)`` over ``K_bounds``
    (:func:`nrobust.design.best_margin`); ``objective="decay_rate"``: the largest nominal decay
    rate (``delta = 0``: ``-ln|(rho - K) q| / tau`` for the paper's plant, Lemma 3) among the
    gains with ``delta*(K) >= margin_at_least`` (:func:`nrobust.design.best_decay_rate`).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant (a general plant with a constant ``lam/mu`` through its normal form).
    objective : {"margin", "decay_rate"}
        What to maximise.
    margin_at_least : float, optional
        The delay margin required (``> 0``); required with ``objective="decay_rate"``.
    K_bounds : (float, float), optional
        The gains searched; default ``0.99`` times the strong-stability bound
        ``(1 - |rho q|)/|q|`` of eq. (54) on each side (``0.9`` with ``output_feedback``).
    rigorous : bool, optional
        Prove the delay margin of the designed loop in ball arithmetic (else checked in
        floating point; ``design.certified`` says which).
    output_feedback : bool, optional
        Design ``OutputFeedback(ReflectionController(K), observer_delay)``: the law on the
        state predicted from the measurement ``v(t, 0)`` (the proof is then about a model:
        the observer's term is computed in floating point, ``design.certificate.scope``).
    observer_delay : float, optional
        The actuation delay the observer assumes (with ``output_feedback`` only).

    Returns
    -------
    ReflectionDesign

    Raises
    ------
    ParameterError
        An unknown ``objective``, ``margin_at_least`` missing or not positive, or a plant
        without strongly stable gains (``|rho q| >= 1``).
    CertificationError
        As :func:`nrobust.design.best_margin` and :func:`nrobust.design.best_decay_rate`.
    """
    if objective not in DESIGN_OBJECTIVES:
        raise ParameterError("objective", f"one of {DESIGN_OBJECTIVES}", objective)
    if objective == "decay_rate":
        if margin_at_least is None:
            raise ParameterError("margin_at_least", "a positive delay margin with objective='decay_rate'", None)
        d = positive("margin_at_least", margin_at_least)
    elif margin_at_least is not None:
        raise ParameterError(
            "margin_at_least", "None with objective='margin' (it constrains the decay rate)", margin_at_least
        )
    plant: Hyperbolic2x2 = study_plant(system, None, "design_reflection")[0]  # a general plant: its normal form
    kb = classify(plant).k_bound
    if K_bounds is None:
        if kb <= 0.0:
            raise ParameterError(
                "system", "|rho q| < 1 (no gain K makes the difference operator strongly stable)", plant
            )
        fraction = _OUTPUT_BOUND_FRACTION if output_feedback else _BOUND_FRACTION
        K_bounds = (-fraction * kb, fraction * kb)
    loop = u_bs2_loop(plant)
    if output_feedback:
        observed = OutputFeedback(ReflectionController(0.0), nonnegative("observer_delay", observer_delay))
        loop = AffineGainLoop(*loop_factors(plant, observed), loop.R)
    elif observer_delay != 0.0:
        raise ParameterError("observer_delay", "0 unless output_feedback=True", observer_delay)
    if objective == "margin":
        design = best_margin(loop, K_bounds, rigorous=rigorous)
    else:
        design = best_decay_rate(loop, K_bounds, margin_at_least=d, rigorous=rigorous)
    controller: Controller = ReflectionController(design.K)
    if output_feedback:
        controller = OutputFeedback(controller, observer_delay)
    factors = (loop.A, loop.B(design.K))
    certificate = dataclasses.replace(
        design.certificate,
        scope=loop_scope(plant, controller, None, factors),
        of_model=loop_route(plant, controller, None) != "exact" and not plant.uncoupled,
    )
    return ReflectionDesign(controller, dataclasses.replace(design, certificate=certificate))
