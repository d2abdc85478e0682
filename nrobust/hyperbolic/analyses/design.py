"""Design of the reflection controller ``U_BS2(K)`` (eq. (53)): :func:`design_reflection`.

The paper's design rule (section 4.2.1, the remark after Lemma 3): keep a fraction ``K`` of
the proximal reflection, trading the nominal decay rate for a delay margin. Its loop
(eq. (60)) is affine in ``K``, and the core's :mod:`nrobust.design.gain` finds the best
``K`` from the equations of its kind (a kink of ``delta*(K)``, a pair birth, an interior
maximum, or where ``delta*(K)`` equals a required margin) and certifies the designed loop.
With ``output_feedback=True`` the law acts on the state predicted from ``y = v(t, 0)``
(:class:`~nrobust.hyperbolic.loops.controllers.OutputFeedback`): its loop is affine in ``K``
too, with the observer's term in ``A`` and ``B_0``
(:mod:`~nrobust.hyperbolic.loops.output_feedback`), and the same equations design it. With
``collocated=True`` the law acts on the estimate of the collocated observer from ``y = u(t, 1)``
(:class:`~nrobust.hyperbolic.loops.controllers.CollocatedOutputFeedback`): the observer's term
depends on the law, so ``A`` depends on ``K`` too, and the loop is affine in ``K`` in both
factors (:class:`nrobust.design.AffineLoop`, built from the loops at ``K = 0`` and ``K = 1``).
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..._json import fields_dict
from ..._threads import one_blas_thread
from ..._validate import nonnegative, positive
from ...design.gain import AffineLoop, GainDesign, best_decay_rate, best_margin, check_delays
from ...errors import CertificationError, ParameterError
from ...margins.gain import AffineGainLoop
from ...quasipoly import QuasiPolynomial
from ...roots import SpectralAbscissa
from ..kernels.constant import DEFAULT_KERNEL_GRID, check_kernel_grid
from ..loops.controllers import (
    CollocatedOutputFeedback,
    Controller,
    OutputFeedback,
    ReflectionController,
    classify,
    gain_slope_factors,
    loop_factors,
    loop_route,
    loop_scope,
)
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from ._common import CornerRates, exact_loop_plant, study_plant
from .kregion import u_bs2_loop
from .mismatch import SpeedTolerance, check_speed_tolerance, mismatch_abscissa, mismatch_gain_loop
from .mismatch import speed_tolerance as tolerance_on_square
from .observer_accuracy import observer_model_error, observer_rate_error

__all__ = ["DESIGN_OBJECTIVES", "ReflectionDesign", "design_reflection"]

#: Objectives of :func:`design_reflection`.
DESIGN_OBJECTIVES = ("margin", "decay_rate")
# Default gains: this fraction of the strong-stability bound (eq. (54)) on each side; for output
# feedback a smaller one: the observer's term starts with a jump at the window w = 1/mu, so the
# crossing curves reach frequencies growing like 1/(bound - |K|), not its square root.
_BOUND_FRACTION, _OUTPUT_BOUND_FRACTION = 0.99, 0.9
# The affine model of a collocated loop (from K = 0 and K = 1) and its factors at the design agree on the
# axis to this relative error (the loop is affine in K up to rounding).
_AFFINE_RTOL = 1e-9


@dataclass(frozen=True)
class ReflectionDesign(CornerRates):
    """The designed ``U_BS2(K)`` with its certificate.

    Attributes
    ----------
    controller : ReflectionController, OutputFeedback or CollocatedOutputFeedback
        ``ReflectionController(K)`` at the designed gain (an :class:`OutputFeedback` of it when
        designed for output feedback, a :class:`CollocatedOutputFeedback` with ``collocated``).
    design : GainDesign
        The core's result: the objective value, its kind, the brackets of the optimum and the
        certified delay margin of the designed loop (``design.certificate``, whose ``scope``
        says whether the proof is about the PDE itself or a model of it); with ``delays`` its
        ``windows`` certify the window for the loop (and the corners of a speed tolerance).
    tolerance : SpeedTolerance or None
        With ``speed_tolerance``: the verdicts on the square of speed mismatches (the corners
        certified, the other points of a grid checked; :func:`~nrobust.hyperbolic.analyses.speed_tolerance`).
    corner_abscissae : tuple of SpectralAbscissa
        With ``speed_tolerance`` and ``objective="decay_rate"``: the spectral abscissa at ``delta = 0`` of the
        loop of the designed law on the plant with speed errors at each corner of the square, in the order of
        ``tolerance.points[:4]`` (:func:`~nrobust.hyperbolic.analyses.mismatch_abscissa`: certified roots, proven
        in ball arithmetic with ``rigorous=True`` where the balls decide, each one's ``rigorous`` says; on the
        kernel route with a ``model_error`` from a convergence study in the kernel grid); empty otherwise. The
        designed gain maximises the least decay rate of the nominal plant and the corners: :attr:`worst_decay_rate`
        is what the law guarantees there (between the corners it is not certified).
    """

    controller: Controller
    design: GainDesign
    tolerance: SpeedTolerance | None = None
    corner_abscissae: tuple[SpectralAbscissa, ...] = ()

    @property
    def requirement(self) -> str:
        """The requirements and their verdicts in words (the delay window; the speed tolerance)."""
        parts = [self.design.requirement]
        if self.tolerance is not None:
            parts.append(f"speed tolerance {float(self.tolerance.eps)!r}: {self.tolerance.statement}")
        return "; ".join(parts)

    @property
    def K(self) -> float:
        """The designed gain."""
        return self.design.K

    @property
    def value(self) -> float:
        """The objective at the design: the delay margin or the decay rate (with ``speed_tolerance``, the least
        decay rate of the nominal loop and the corners' loops; :attr:`worst_decay_rate` gives it with its
        accuracy)."""
        return self.design.value

    @property
    def kind(self) -> str:
        """What decides the optimum (:data:`nrobust.design.gain.DESIGN_KINDS`)."""
        return self.design.kind

    def __repr__(self) -> str:
        return f"ReflectionDesign({self.controller!r}, {self.design!r}{self.worst_text()})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (with the corners' decay rates and the least of them and the nominal one)."""
        return {**fields_dict(self), **self.corner_dict()}


def _design_error(exc: ParameterError, eps: float | None, window: tuple[float, float] | None) -> ParameterError:
    """The core's refusal in the caller's words: its ``bounds`` are ``K_bounds``; a window that no gain
    meets at the corners of the speed tolerance: the tolerance is what to lower."""
    if exc.name == "bounds":
        return ParameterError("K_bounds", exc.requirement, exc.value)
    if eps is None or window is None or exc.name != "delays":
        return exc
    return ParameterError(
        "speed_tolerance",
        f"smaller: no gain meets the window [{window[0]:.6g}, {window[1]:.6g}] on the nominal plant and the plants "
        f"with speed errors (+-{eps:.6g}, +-{eps:.6g}) together (the largest tolerance met is not searched; "
        "design_reflection without speed_tolerance gives the nominal design)",
        eps,
    )


def _nominal_requirement(
    loop: AffineGainLoop | AffineLoop,
    bounds: tuple[float, float],
    objective: str,
    window: tuple[float, float],
    margin_at_least: float | None,
) -> None:
    """Raise the nominal plant's refusal of the delay requirement when no gain meets it there.

    Called before the design under a speed tolerance (on the nominal plant and the corners
    together, seconds to tens of seconds when it finds no gain): the same design without the corners
    (a fraction of that) tells whether the requirement itself is out of reach (the error then names
    ``margin_at_least``, with the largest margin a gain of the bounds reaches, or ``delays``), so
    that a refusal of the design with the corners is the tolerance's. Returns when the nominal plant
    meets it, and when that design cannot decide (the design with the corners then runs and says).
    """
    try:
        if margin_at_least is not None:
            best_decay_rate(loop, bounds, margin_at_least=margin_at_least)
        elif objective == "margin":
            best_margin(loop, bounds, delays=window)
        else:
            best_decay_rate(loop, bounds, delays=window)
    except ParameterError as exc:
        if exc.name in ("margin_at_least", "delays"):
            raise _design_error(exc, None, None) from exc
    except CertificationError:
        return


def _collocated_k_bounds(plant: Hyperbolic2x2, observer_delay: float) -> tuple[float, float]:
    """The gains for which the collocated output feedback's difference operator is strongly stable.

    For U_BS2(K) the condition is ``|rho - K| |q| + 2 |K rho| q^2 < 1`` with ``observer_delay = 0``,
    ``|rho q| + |K q| + 2 |K rho| q^2 < 1`` otherwise
    (:class:`~nrobust.hyperbolic.loops.controllers.CollocatedOutputFeedback`): a convex piecewise
    linear function of ``K``, below 1 on an open interval about ``K = 0`` when ``|rho q| < 1``,
    whose ends are solved in closed form on the linear piece where it reaches 1.

    Parameters
    ----------
    plant : Hyperbolic2x2
        The paper's plant (``q != 0``, ``|rho q| < 1``).
    observer_delay : float
        The delay of the commands the observer replays (``>= 0``).

    Returns
    -------
    (float, float)
        The ends ``K_- < 0 < K_+`` of the interval.
    """
    rho, q = plant.rho, abs(plant.q)
    if q == 0.0 or not abs(rho) * q < 1.0:
        raise ParameterError("plant", "q != 0 and |rho q| < 1", plant)
    observer_delay = nonnegative("observer_delay", observer_delay)

    def level(K: float) -> float:
        if observer_delay > 0.0:
            return abs(rho) * q + abs(K) * q + 2.0 * abs(K * rho) * q * q
        return abs(rho - K) * q + 2.0 * abs(K * rho) * q * q

    ends = []
    for side in (-1.0, 1.0):
        # the kinks of level() on this side (K = 0, K = rho) and a point beyond every root (level > 1 + q there)
        far = side * (abs(rho) + 2.0 / q)
        points = sorted({0.0, far, *([rho] if side * rho > 0.0 else [])}, key=abs)
        for a, b in itertools.pairwise(points):
            fa, fb = level(a) - 1.0, level(b) - 1.0
            if fa < 0.0 <= fb:  # linear on [a, b]: the root in closed form
                ends.append(a + (b - a) * (-fa) / (fb - fa))
                break
    return ends[0], ends[1]


def _collocated_loop(plant: Hyperbolic2x2, observer_delay: float) -> AffineLoop:
    """The collocated loop as ``(A_0 + K A_1) + (B_0 + K B_1) e^{-delta s}`` from its factors at ``K = 0, 1``
    (:func:`~nrobust.hyperbolic.loops.controllers.gain_slope_factors`: at ``K = rho`` the point terms cancel to 0)."""
    return AffineLoop(
        *gain_slope_factors(
            plant,
            CollocatedOutputFeedback(ReflectionController(0.0), observer_delay),
            CollocatedOutputFeedback(ReflectionController(1.0), observer_delay),
        )
    )


def _check_affine(loop: AffineLoop, K: float, factors: tuple[QuasiPolynomial, QuasiPolynomial], top: float) -> None:
    """The affine model at ``K`` is the loop built at ``K`` on the axis up to ``top`` (else the design is not
    about that loop)."""
    s = 1j * np.linspace(0.0, top, 257)
    for model, built in ((loop.A(K), factors[0]), (loop.B(K), factors[1])):
        a, b = model(s), built(s)
        err = float(np.max(np.abs(a - b)))
        if err > _AFFINE_RTOL * max(float(np.max(np.abs(b))), 1.0):
            raise CertificationError(
                f"design_reflection: the collocated loop is not affine in K to rounding ({err:.2e} at K = {K:.15g} "
                "between the model from K = 0, 1 and the loop built at K), so the design is not about that loop"
            )


@one_blas_thread()  # many small products: competing BLAS threads only cost time
def _speeds_scale_alone(system: GeneralHyperbolic2x2) -> bool:
    """True when relative errors of the speeds of ``system`` change its normal form's speeds by the same factors
    and nothing else (``a = d = 0``: the couplings ``b``, ``c`` and the change of variable do not depend on them),
    so that the square of speed errors of the normal form is the plant's."""
    return all(system.is_constant(name) and float(getattr(system, name)) == 0.0 for name in ("a", "d"))


def design_reflection(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    objective: str = "margin",
    *,
    margin_at_least: float | None = None,
    K_bounds: tuple[float, float] | None = None,
    rigorous: bool = False,
    output_feedback: bool = False,
    observer_delay: float = 0.0,
    collocated: bool = False,
    delays: tuple[float, float] | None = None,
    speed_tolerance: float | None = None,
    kernel_grid: int = DEFAULT_KERNEL_GRID,
) -> ReflectionDesign:
    """The gain ``K`` of ``U_BS2(K)`` (eq. (53)) that maximises the delay margin or the decay rate.

    ``objective="margin"``: the largest delay margin ``delta*(K)`` over ``K_bounds``
    (:func:`nrobust.design.best_margin`); ``objective="decay_rate"``: the largest nominal decay
    rate (``delta = 0``: ``-ln|(rho - K) q| / tau`` for the paper's plant, Lemma 3) among the
    gains with ``delta*(K) >= margin_at_least`` (:func:`nrobust.design.best_decay_rate`). That
    rate is infinite at ``K = rho`` (``U_BS``, eq. (47): the loop at ``delta = 0`` is ``1``,
    finite-time convergence, for the state feedback and either observer) and unbounded about it:
    when ``rho`` lies in ``K_bounds`` and meets the requirement it is the design, ``kind``
    ``"finite time"``.

    ``delays = (d_min, d_max)`` requires exponential stability for every delay of the window
    (:func:`nrobust.design.window_stability`; ``d_min = 0`` is ``delta* > d_max``, ``d_min > 0``
    allows a loop unstable at ``delta = 0``): with ``"decay_rate"`` it replaces
    ``margin_at_least``, with ``"margin"`` it constrains the gains searched. ``speed_tolerance
    = eps`` requires the window too on the plants with speeds ``lam (1 + e_lam)``, ``mu (1 +
    e_mu)`` at the four corners ``|e_lam| = |e_mu| = eps`` (the law designed on ``system``:
    :func:`~nrobust.hyperbolic.analyses.mismatch_gain_loop`, four more loops affine in ``K``
    whose feasible gains are intersected exactly); the design is then checked at the other
    points of a 3 x 3 grid of the square (:attr:`ReflectionDesign.tolerance`, which says what is
    proven: the corners, and with ``rigorous=True`` the whole square where the loop is the PDE
    itself, an uncoupled plant under ``U = k u(t, 1)``; elsewhere never the continuum between the
    points).
    With ``"decay_rate"`` the gain maximises the least decay rate at ``delta = 0`` of the nominal loop and the
    four corners' among those gains, ``min_j r_j(K)`` (``best_decay_rate(..., worst_case=True)``: an end of the
    feasible gains, a peak of one rate, or a gain where two rates tie, ``kind`` ``"tie"``, solved by ``brentq``
    on ``r_i - r_j``; found from samples of all rates, so a peak or tie narrower than their spacing can be
    missed); ``value`` is that least rate on the corners' loops as designed (``kernel_grid``), ``design.decay_rate``
    the nominal one. The rate at each corner is stated again with its model error
    (:attr:`ReflectionDesign.corner_abscissae`), and the least of them and the nominal one
    (:attr:`ReflectionDesign.worst_decay_rate`, with its accuracy) is what the law guarantees there (between the
    corners it is not certified).

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
        ``(1 - |rho q|)/|q|`` of eq. (54) on each side (``0.9`` with ``output_feedback``;
        with ``collocated``, of the ends of the interval where its difference operator is strongly
        stable: ``|rho - K| |q| + 2 |K rho| q^2 < 1``, or ``|rho q| + |K q| + 2 |K rho| q^2 < 1``
        with ``observer_delay > 0``).
    rigorous : bool, optional
        Prove the delay margin of the designed loop in ball arithmetic (else checked in
        floating point; ``design.certified`` says which).
    output_feedback : bool, optional
        Design ``OutputFeedback(ReflectionController(K), observer_delay)``: the law on the
        state predicted from the measurement ``v(t, 0)`` (on a plant with constant coefficients the
        observer's term is enclosed in ball arithmetic and the proof is about the PDE; elsewhere about a
        model: ``design.certificate.scope`` says which).
    observer_delay : float, optional
        The actuation delay the observer assumes (with ``output_feedback`` only).
    collocated : bool, optional
        With ``output_feedback``: design ``CollocatedOutputFeedback(ReflectionController(K),
        observer_delay)``, the law on the estimate of the collocated observer from ``u(t, 1)``
        (a model too: its term comes from kernels of the dual plant). Its loop is affine in ``K``
        in both factors; the default ``K_bounds`` are those of its own strong stability, not
        eq. (54)'s.
    delays : (float, float), optional
        ``[d_min, d_max]``, ``0 <= d_min <= d_max``, ``d_max > 0``: the window of delays on which
        the designed loop must be exponentially stable.
    speed_tolerance : float, optional
        ``eps`` in ``(0, 1)``: the relative error of ``lam`` and ``mu`` (both signs, together) under
        which the window (or ``[0, margin_at_least]``) must hold too; not with
        ``output_feedback``, nor for a general plant whose ``a`` or ``d`` is not 0 (its normal form's
        couplings change with the speeds).
    kernel_grid : int, default :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID`
        Kernel grid of the mismatched loops (with ``speed_tolerance`` on a coupled plant).

    Returns
    -------
    ReflectionDesign

    Raises
    ------
    ParameterError
        An unknown ``objective``, ``margin_at_least`` missing or not positive, or a plant
        without strongly stable gains (``|rho q| >= 1``); ``delays`` not a window or given with
        ``margin_at_least``; ``speed_tolerance`` outside ``(0, 1)``, without a delay requirement
        or with ``output_feedback``; ``collocated`` without ``output_feedback``; a requirement no
        gain meets (naming the best achievable).
    CertificationError
        As :func:`nrobust.design.best_margin` and :func:`nrobust.design.best_decay_rate`.
    """
    if objective not in DESIGN_OBJECTIVES:
        raise ParameterError("objective", f"one of {DESIGN_OBJECTIVES}", objective)
    window = None if delays is None else check_delays(delays)
    if window is not None and margin_at_least is not None:
        raise ParameterError("margin_at_least", "None with delays (the window [0, d] is delta* > d)", margin_at_least)
    if objective == "decay_rate" and window is None:
        if margin_at_least is None:
            raise ParameterError(
                "margin_at_least", "a positive delay margin with objective='decay_rate' (or delays)", None
            )
        d = positive("margin_at_least", margin_at_least)
    elif margin_at_least is not None:
        raise ParameterError(
            "margin_at_least", "None with objective='margin' (it constrains the decay rate)", margin_at_least
        )
    eps = None if speed_tolerance is None else check_speed_tolerance(speed_tolerance)
    if eps is not None and isinstance(system, GeneralHyperbolic2x2) and not _speeds_scale_alone(system):
        raise ParameterError(
            "speed_tolerance",
            "None for a GeneralHyperbolic2x2 whose a or d is not 0: the square of speed errors is built on the "
            "normal form, whose couplings change with the speeds through a / lam and d / mu",
            speed_tolerance,
        )
    if eps is not None:
        if output_feedback:
            raise ParameterError("speed_tolerance", "None with output_feedback=True", speed_tolerance)
        if window is None:
            if objective == "margin":
                raise ParameterError(
                    "speed_tolerance", "given with a delay requirement (delays, or margin_at_least)", speed_tolerance
                )
            window = (0.0, d)
    kernel_grid = check_kernel_grid(kernel_grid)
    if collocated and not output_feedback:
        raise ParameterError("collocated", "False unless output_feedback=True", collocated)
    plant: Hyperbolic2x2 = study_plant(system, None, "design_reflection")[0]  # a general plant: its normal form
    kb = classify(plant).k_bound
    if K_bounds is None:
        if kb <= 0.0:
            raise ParameterError(
                "system", "|rho q| < 1 (no gain K makes the difference operator strongly stable)", plant
            )
        if collocated and plant.q == 0.0:
            raise ParameterError("K_bounds", "given when q = 0 (every gain is strongly stable)", None)
        fraction = _OUTPUT_BOUND_FRACTION if output_feedback else _BOUND_FRACTION
        k_lo, k_hi = _collocated_k_bounds(plant, observer_delay) if collocated else (-kb, kb)
        K_bounds = (fraction * k_lo, fraction * k_hi)
    loop: AffineGainLoop | AffineLoop
    source: Hyperbolic2x2 | GeneralHyperbolic2x2 = plant  # the plant whose loops are built
    if collocated:
        loop = _collocated_loop(plant, nonnegative("observer_delay", observer_delay))
    elif output_feedback:
        observed = OutputFeedback(ReflectionController(0.0), nonnegative("observer_delay", observer_delay))
        loop = AffineGainLoop(*loop_factors(plant, observed), u_bs2_loop(plant).R)
    else:
        if observer_delay != 0.0:
            raise ParameterError("observer_delay", "0 unless output_feedback=True", observer_delay)
        source = exact_loop_plant(system, plant)
        loop = u_bs2_loop(source)
    scenarios: tuple[AffineGainLoop, ...] = ()
    if eps is not None:
        corners = [(a, b) for a in (-eps, eps) for b in (-eps, eps)]
        scenarios = tuple(mismatch_gain_loop(plant, a, b, kernel_grid=kernel_grid) for a, b in corners)
    if scenarios and window is not None:  # the requirement itself first: the tolerance is to blame only if met
        _nominal_requirement(loop, K_bounds, objective, window, margin_at_least)
    try:
        if objective == "margin":
            design = best_margin(loop, K_bounds, delays=window, scenarios=scenarios, rigorous=rigorous)
        elif window is not None:
            design = best_decay_rate(
                loop, K_bounds, delays=window, scenarios=scenarios, worst_case=eps is not None, rigorous=rigorous
            )
        else:
            design = best_decay_rate(loop, K_bounds, margin_at_least=d, rigorous=rigorous)
    except ParameterError as exc:
        raise _design_error(exc, eps, window) from exc
    controller: Controller = ReflectionController(design.K)
    if collocated:
        controller = CollocatedOutputFeedback(controller, observer_delay)
    elif output_feedback:
        controller = OutputFeedback(controller, observer_delay)
    if isinstance(loop, AffineLoop):
        factors = loop_factors(plant, controller)
        _check_affine(loop, design.K, factors, 2.0 * max(float(design.certificate.omega or 0.0), 1.0))
    else:
        factors = (loop.A, loop.B(design.K))
    of_model = loop_route(source, controller, None) != "exact" and not plant.uncoupled
    model_error = omega_model_error = None
    abscissa = design.abscissa
    if of_model and isinstance(controller, (OutputFeedback, CollocatedOutputFeedback)):
        model_error, omega_model_error = observer_model_error(plant, controller, design.certificate, factors)
        abscissa = dataclasses.replace(abscissa, model_error=observer_rate_error(plant, controller, abscissa, factors))
    certificate = dataclasses.replace(
        design.certificate,
        scope=loop_scope(source, controller, None, factors, mapped=False, normal_form=source is not system),
        of_model=of_model,
        model_error=model_error,
        omega_model_error=omega_model_error,
    )
    tolerance = None
    corner_abscissae: tuple[SpectralAbscissa, ...] = ()
    if eps is not None and objective == "decay_rate":
        law = ReflectionController(design.K)
        corner_abscissae = tuple(
            mismatch_abscissa(plant, law, a, b, kernel_grid=kernel_grid, rigorous=rigorous) for a, b in corners
        )
    if eps is not None and window is not None:
        tolerance = tolerance_on_square(
            plant,
            controller,
            eps,
            window,
            kernel_grid=kernel_grid,
            rigorous=rigorous,
            corner_windows=design.windows[1:],
        )
    design = dataclasses.replace(design, certificate=certificate, abscissa=abscissa)
    if corner_abscissae:  # the corners' rates with their model errors: the least rate to its accuracy
        least = float(min(-a.value for a in (abscissa, *corner_abscissae)))
        below, above = design.value - design.value_bracket[0], design.value_bracket[1] - design.value
        design = dataclasses.replace(
            design, value=least, value_bracket=(least - below, least + above), scenario_abscissae=corner_abscissae
        )
    return ReflectionDesign(controller, design, tolerance, corner_abscissae)
