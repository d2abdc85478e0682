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

**The law and the observer together.** ``A_o`` is affine in ``K`` and in ``kappa``, ``B_o`` bilinear
(``kappa H_y`` times the law's factor): :func:`collocated_joint_loop` builds it from four loops, and
:func:`design_collocated_output_feedback` designs ``(K, kappa)`` with the core's local nonsmooth
optimiser (:func:`nrobust.design.optimize_loop`) over the region where ``gamma_0 <= gamma_max``
(:func:`joint_bounds`: for fixed ``K`` or fixed ``kappa`` ``gamma_0`` is convex and piecewise
linear, so each section of the region is solved in closed form), from the exact one-parameter
design at ``K = 0.1`` and a small grid about it.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._json import fields_dict, json_safe
from ..._threads import one_blas_thread
from ..._validate import finite_real, nonnegative, positive, positive_int
from ...design.gain import AffineLoop, GainDesign, best_decay_rate, best_margin
from ...design.local import LoopDesign, optimize_loop
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
from ..loops.output_feedback import consolidated
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from ._common import mapper, study_plant
from .observer_accuracy import crossing_delay, observer_model_error, observer_rate_error

__all__ = [
    "JOINT_GAMMA_MAX",
    "OBSERVER_OBJECTIVES",
    "CollocatedDesign",
    "CollocatedJointLoop",
    "ObserverDesign",
    "collocated_joint_loop",
    "collocated_observer_loop",
    "design_collocated_observer",
    "design_collocated_output_feedback",
    "joint_bounds",
    "observer_reflection_bounds",
]

#: Objectives of :func:`design_collocated_observer`.
OBSERVER_OBJECTIVES = ("margin", "decay_rate")
#: Default bounds: the strongly stable interval less this fraction of its width at each end (the
#: crossing curves reach frequencies growing like 1/distance to its ends).
_SHRINK = 0.1
#: Gains near the top of the sampled envelope (within this fraction of it) whose delay margins the
#: design must match or beat, at most this many.
_TOP_FRACTION, _TOP_CHECKS = 0.01, 5
#: The design's crossings continued to a gain near the top of the envelope (at most).
_CROSSING_STARTS = 3


class _ObserverResult:
    """What :class:`ObserverDesign` and :class:`CollocatedDesign` read alike from their controller and design."""

    controller: CollocatedOutputFeedback
    design: Any

    @property
    def kappa(self) -> float:
        """The designed observer reflection."""
        return self.controller.observer_reflection

    @property
    def value(self) -> float:
        """The objective at the design: the delay margin or the decay rate."""
        return float(self.design.value)


@dataclass(frozen=True)
class ObserverDesign(_ObserverResult):
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
    def kind(self) -> str:
        """What decides the optimum (:data:`nrobust.design.gain.DESIGN_KINDS`)."""
        return self.design.kind

    def __repr__(self) -> str:
        # the designed parameter is the observer's reflection kappa; each value to its accuracy
        return f"ObserverDesign({self.controller!r}, {self.design.summary('kappa')})"

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
    # the products' kernels (one per interval between breakpoints) summed into one term each where their
    # nodes together are uniform, as loop_factors stores A_0 and B_0: on the paper's plant five kernels each,
    # integrated once per evaluation instead of five times
    return AffineLoop(
        A0,
        consolidated(-reflection.open_loop_product.times_poly(denominator)),
        B0,
        consolidated(-reflection.law_product.times_poly(numerator)),
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


def _level_interval(c0: np.ndarray, c1: np.ndarray, level: float) -> tuple[float, float] | None:
    """The open interval of ``x`` where ``sum_k |c0_k + x c1_k| < level``; None where it is empty.

    The sum is convex and piecewise linear, its kinks at ``-c0_k / c1_k``: the level is solved in
    closed form on the linear piece where it is reached. ``(-inf, inf)`` when no ``c1_k`` moves it.
    """

    def total(x: float) -> float:
        return float(np.sum(np.abs(c0 + x * c1)))

    moving = c1 != 0.0
    kinks = np.sort(-c0[moving] / c1[moving])
    best = float(min(kinks, key=total)) if kinks.size else 0.0
    if not total(best) < level:
        return None
    slope_far = float(np.sum(np.abs(c1)))
    if slope_far == 0.0:
        return -math.inf, math.inf
    ends = []
    for side in (-1.0, 1.0):
        steps = [float(k) for k in (kinks if side > 0 else kinks[::-1]) if side * (k - best) > 0.0]
        # past the last kink the sum grows with slope slope_far: level + 1 further on it is above the level
        points = [best, *steps, (steps[-1] if steps else best) + side * (level + 1.0) / slope_far]
        for a, b in itertools.pairwise(points):
            fa, fb = total(a) - level, total(b) - level
            if fa < 0.0 <= fb:
                ends.append(a + (b - a) * (-fa) / (fb - fa))
                break
    return float(ends[0]), float(ends[1])


def observer_reflection_bounds(loop: AffineLoop) -> tuple[float, float]:
    """The open interval of ``kappa`` where the difference operator of ``loop`` is strongly stable.

    ``gamma_0(kappa) = (sum_{k>=1} |a_k + kappa a'_k| + sum_k |b_k + kappa b'_k|) / |a_0|`` over the
    principal coefficients (the ``B`` terms at a generic delay, terms at equal delays summed):
    convex and piecewise linear, its level 1 is solved on the linear piece where it is reached.
    With ``observer_delay = delta_o > 0`` the terms of ``n G e^{-delta_o s}`` keep their own delays
    (``tau + delta_o``, ``2 tau + delta_o``): for U_BS2(K) the condition is
    ``|rho + kappa| |q| + |kappa rho| q^2 + |K q| + |K rho| q^2 + |K (rho - kappa)| q^2 < 1``
    (:func:`collocated_joint_loop`).

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
    c0, c1 = np.delete(c0, lead[0]) / a0, np.delete(c1, lead[0]) / a0
    interval = _level_interval(c0, c1, 1.0)
    if interval is None:
        lowest = min((float(np.sum(np.abs(c0 + k * c1))) for k in -c0[c1 != 0.0] / c1[c1 != 0.0]), default=math.nan)
        raise ParameterError(
            "controller",
            "a law for which some observer reflection is strongly stable "
            f"(gamma_0 >= {lowest:.6g} for every kappa: a smaller gain, or observer_delay = 0)",
        )
    if not all(map(math.isfinite, interval)):
        raise ParameterError("kappa_bounds", "given: every observer reflection is strongly stable here", None)
    return interval


@one_blas_thread()  # many small products: competing BLAS threads only cost time
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
    scope = loop_scope(plant, designed, None, factors, mapped=False, normal_form=plant is not system)
    certificate = design.certificate
    of_model = loop_route(plant, designed, None) != "exact" and not plant.uncoupled
    errors = observer_model_error(plant, designed, certificate, factors) if of_model else (None, None)
    certificate = dataclasses.replace(
        certificate, scope=scope, of_model=of_model, model_error=errors[0], omega_model_error=errors[1]
    )
    abscissa = design.abscissa
    if of_model:  # the zeros of E = 1 - kappa H_y are modes of the loop: the rate is a model's too
        abscissa = dataclasses.replace(abscissa, model_error=observer_rate_error(plant, designed, abscissa, factors))
    design = dataclasses.replace(design, certificate=certificate, abscissa=abscissa)
    return ObserverDesign(designed, design, bounds, scope)


def _check_envelope_top(loop: AffineLoop, design: GainDesign) -> None:
    """No delay margin near the top of the sampled envelope beats the design's (else it is not the optimum).

    The envelope only locates the optimum (interpolated on the sampled crossing curves, it can err
    by about 1e-3 where a curve is steep in ``kappa``); up to :data:`_TOP_CHECKS` gains where it is
    within :data:`_TOP_FRACTION` of its top are checked, so that a kink whose equations converged to
    another pair of curves, or an end the envelope overrates, is not returned as the best ``kappa``.
    A crossing delay of the loop at such a gain bounds its margin from above (a zero lies on the axis
    there): one of the design's crossings (the critical one first) continued to the gain by Newton's
    method (:func:`~nrobust.hyperbolic.analyses.observer_accuracy.crossing_delay`) settles the check
    when its delay is no larger than the design's margin, else the gain's certified margin
    (:func:`~nrobust.margins.delay_margin`) decides.
    """
    env = np.asarray(design.envelope, dtype=float)
    near = np.flatnonzero(env >= (1.0 - _TOP_FRACTION) * float(np.max(env)))
    picks = {int(np.argmax(env))} | {int(near[int(i)]) for i in np.linspace(0, near.size - 1, _TOP_CHECKS).round()}
    limit = design.value * (1.0 + 1e-9)
    # the design's critical crossing first, then its other crossings by their first delay (at a kink the
    # top gains on either side continue one of the two crossings that meet)
    cert = design.certificate
    later = sorted((c for c in cert.crossings if c.delays), key=lambda c: c.delays[0])
    starts = [w for w in dict.fromkeys([cert.omega, *(c.omega for c in later)]) if w is not None and w > 0.0]
    for i in sorted(picks):
        top = float(design.gains[i])
        if top == design.K:
            continue
        A, B = loop.A(top), loop.B(top)
        found = (crossing_delay(A, B, float(w)) for w in starts[:_CROSSING_STARTS])
        if any(f is not None and f[1] <= limit for f in found):
            continue
        margin = delay_margin(A, B)
        if margin.margin > limit:
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


@dataclass(frozen=True)
class CollocatedJointLoop:
    """The loop of U_BS2(K) on the collocated observer that keeps ``kappa``, bilinear in ``p = (K, kappa)``.

    ``A_o = E A - G e^{-delta_o s}`` does not depend on ``K kappa`` (``E A = (1 - kappa H_y)(1 -
    Phi)``, ``G = (1 - Phi) C_u`` affine in ``K``), ``B_o = E B + G`` does (``kappa H_y`` times
    the law's factor ``B``, affine in ``K``):

        A = A_0 + K A_K + kappa A_kappa,    B = B_0 + K B_K + kappa B_kappa + K kappa B_Kkappa,

    from the loops built at ``(K, kappa) = (0, 0), (1, 0), (0, 1), (1, 1)``
    (:func:`collocated_joint_loop`). Picklable: a loop family ``p -> (A, B)`` of
    :func:`nrobust.design.optimize_loop`.
    """

    A0: QuasiPolynomial
    AK: QuasiPolynomial
    Akappa: QuasiPolynomial
    B0: QuasiPolynomial
    BK: QuasiPolynomial
    Bkappa: QuasiPolynomial
    BKkappa: QuasiPolynomial
    observer_delay: float = 0.0

    def __call__(self, p: ArrayLike) -> tuple[QuasiPolynomial, QuasiPolynomial]:
        """``(A, B)`` at ``p = (K, kappa)``."""
        K, kappa = (float(x) for x in np.asarray(p, dtype=float))
        A = self.A0 + self.AK * K + self.Akappa * kappa
        B = self.B0 + self.BK * K + self.Bkappa * kappa + self.BKkappa * (K * kappa)
        return A, B

    def controller(self, p: ArrayLike) -> CollocatedOutputFeedback:
        """``CollocatedOutputFeedback(ReflectionController(K), observer_delay, kappa)`` at ``p = (K, kappa)``."""
        K, kappa = (float(x) for x in np.asarray(p, dtype=float))
        return CollocatedOutputFeedback(ReflectionController(K), self.observer_delay, kappa)

    def principal(self) -> tuple[NDArray[np.float64], ...]:
        """``(c_0, c_K, c_kappa, c_Kkappa)``: the principal coefficients but the undelayed one, over ``|a_0|``.

        ``gamma_0(K, kappa) = sum_k |c_0 + K c_K + kappa c_kappa + K kappa c_Kkappa|_k`` (the ``B``
        terms at a generic delay, terms at equal delays summed); for fixed ``K`` it is convex and
        piecewise linear in ``kappa``, and for fixed ``kappa`` in ``K``.
        """
        corners = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
        n = self.A0.degree
        at = [_principal(*self(np.array(c)), n) for c in corners]
        keys = sorted(set().union(*at))
        v = [np.array([a.get(k, 0.0) for k in keys]) for a in at]
        lead = [i for i, k in enumerate(keys) if k == ("A", 0.0)]
        if len(lead) != 1 or v[0][lead[0]] == 0.0 or any(x[lead[0]] != v[0][lead[0]] for x in v[1:]):
            raise ParameterError("controller", "a loop whose undelayed leading coefficient is constant", self)
        a0 = abs(v[0][lead[0]])
        c = (v[0], v[1] - v[0], v[2] - v[0], v[3] - v[1] - v[2] + v[0])
        return tuple(np.delete(x, lead[0]) / a0 for x in c)

    def gamma(self, K: float, kappa: float) -> float:
        """``gamma_0`` of the delayed loop's difference operator at ``(K, kappa)`` (:meth:`principal`)."""
        c0, cK, ck, cKk = self.principal()
        return float(np.sum(np.abs(c0 + K * cK + kappa * ck + K * kappa * cKk)))


def collocated_joint_loop(system: Hyperbolic2x2, observer_delay: float = 0.0) -> CollocatedJointLoop:
    """The loop of U_BS2(K) with the collocated observer's reflection ``kappa``, bilinear in ``(K, kappa)``.

    Built from :func:`~nrobust.hyperbolic.loops.controllers.loop_factors` at ``(K, kappa) = (0, 0),
    (1, 0), (0, 1), (1, 1)`` (the loop is affine in ``kappa`` at each ``K``, in ``K`` at each
    ``kappa``; ``A`` has no ``K kappa`` term: :class:`CollocatedJointLoop`).
    """
    observer_delay = nonnegative("observer_delay", observer_delay)
    F = {
        (K, kappa): loop_factors(system, CollocatedOutputFeedback(ReflectionController(K), observer_delay, kappa))
        for K in (0.0, 1.0)
        for kappa in (0.0, 1.0)
    }
    (A00, B00), (A10, B10), (A01, B01), (_, B11) = F[0.0, 0.0], F[1.0, 0.0], F[0.0, 1.0], F[1.0, 1.0]
    return CollocatedJointLoop(
        A00, A10 - A00, A01 - A00, B00, B10 - B00, B01 - B00, B11 - B10 - B01 + B00, observer_delay
    )


#: Default ``gamma_max`` of :func:`design_collocated_output_feedback`: the region where ``gamma_0`` of the
#: delayed loop's difference operator is at most this (strong stability, with room: the crossing
#: frequencies grow like ``1/(1 - gamma_0)``).
JOINT_GAMMA_MAX = 0.9
#: The observer's default law is U_BS2(0.1) (:func:`design_collocated_observer`): the first start of the joint
#: design is the exact best ``kappa`` at this gain (when it is admissible).
_START_K = 0.1
#: The projections of the region ``gamma_0 <= gamma_max`` are sampled on this many points, then bisected.
_EXTENT_SAMPLES, _EXTENT_BISECTIONS = 401, 60
#: The scan of a projection doubles its half-width from 1 up to this before giving up (the region is bounded
#: when ``q != 0``).
_EXTENT_LIMIT = 1e4
#: The small grid about the first start: this fraction of the bounds' widths along each axis.
_NEAR = 0.01
#: The spread starts are picked among the middles of this many parts of the ``K`` bounds per start.
_GRID_PARTS = 8
#: The bilinear model and the loop built at the design agree on the axis to this relative error.
_MODEL_RTOL = 1e-9


def _section(loop_c: tuple[NDArray[np.float64], ...], axis: int, x: float, level: float) -> tuple[float, float] | None:
    """The open interval of the other parameter where ``gamma_0 < level`` with parameter ``axis`` at ``x``."""
    c0, cK, ck, cKk = loop_c
    if axis == 0:  # K = x: affine in kappa
        return _level_interval(c0 + x * cK, ck + x * cKk, level)
    return _level_interval(c0 + x * ck, cK + x * cKk, level)


def _extent(loop_c: tuple[NDArray[np.float64], ...], axis: int, level: float) -> tuple[float, float]:
    """The projection on parameter ``axis`` of the region ``gamma_0 < level``: its lowest and highest points.

    ``min`` over the other parameter of ``gamma_0`` is exact at each sample (:func:`_level_interval`);
    the samples' outermost points inside are bisected to the projection's ends (a component of the
    region thinner than the sampling step can be missed: the bounds are a search box, not a proof).
    """

    def inside(x: float) -> bool:
        return _section(loop_c, axis, x, level) is not None

    half = 1.0
    while True:
        xs = np.linspace(-half, half, _EXTENT_SAMPLES)
        flags = np.array([inside(float(x)) for x in xs])
        if not (flags[0] or flags[-1]):
            break
        half *= 2.0
        if half > _EXTENT_LIMIT:
            raise ParameterError("K_bounds" if axis == 0 else "kappa_bounds", "given (the region is unbounded)", None)
    where = np.flatnonzero(flags)
    if where.size == 0:
        raise ParameterError("gamma_max", f"a level above the least gamma_0 of the loop (got {level!r})", None)
    ends = []
    for i, j in ((where[0], where[0] - 1), (where[-1], where[-1] + 1)):
        a, b = float(xs[i]), float(xs[j])  # a inside, b outside
        for _ in range(_EXTENT_BISECTIONS):
            m = 0.5 * (a + b)
            a, b = (m, b) if inside(m) else (a, m)
        ends.append(a)
    return ends[0], ends[1]


def joint_bounds(
    loop: CollocatedJointLoop, gamma_max: float = JOINT_GAMMA_MAX
) -> tuple[tuple[float, float], tuple[float, float]]:
    """``((K_lo, K_hi), (kappa_lo, kappa_hi))``: the smallest box about the region ``gamma_0 <= gamma_max``.

    ``gamma_0(K, kappa)`` of :meth:`CollocatedJointLoop.gamma`; for U_BS2(K) with ``delta_o = 0``,
    ``|rho - K + kappa| |q| + |(kappa - K) rho| q^2 + |K (rho - kappa)| q^2``, with ``delta_o > 0``
    ``|rho + kappa| |q| + |kappa rho| q^2 + |K q| + |K rho| q^2 + |K (rho - kappa)| q^2``
    (not convex: the last term is a product). Each projection from :func:`_extent`.
    """
    c = loop.principal()
    return _extent(c, 0, gamma_max), _extent(c, 1, gamma_max)


@dataclass(frozen=True)
class CollocatedDesign(_ObserverResult):
    """The jointly designed U_BS2(K) and collocated observer reflection ``kappa``, certified.

    Attributes
    ----------
    controller : CollocatedOutputFeedback
        ``CollocatedOutputFeedback(ReflectionController(K), observer_delay, kappa)``.
    design : LoopDesign
        The core's result (:func:`nrobust.design.optimize_loop` on :class:`CollocatedJointLoop`):
        the value, the certified abscissa and delay margin, every start's run (the best first).
    bounds : ((float, float), (float, float))
        The box of ``K`` and ``kappa`` searched.
    gamma_max : float
        The bound on ``gamma_0`` of the delayed loop's difference operator every iterate met.
    scope : str
        What the certificate is about (:func:`~nrobust.hyperbolic.loops.controllers.loop_scope`).
    failed : tuple of str
        The starts that reached no certified design, each with the core's reason.
    local : bool
        Always True: the best of several local optima (:attr:`nrobust.design.LoopDesign.local`).
    """

    controller: CollocatedOutputFeedback
    design: LoopDesign
    bounds: tuple[tuple[float, float], tuple[float, float]]
    gamma_max: float
    scope: str
    failed: tuple[str, ...] = ()
    local: bool = True

    @property
    def K(self) -> float:
        """The designed gain of U_BS2(K)."""
        inner = self.controller.controller
        assert isinstance(inner, ReflectionController)
        return float(inner.K)

    @property
    def certified(self) -> bool:
        """Whether the design's abscissa and margin are certified (:attr:`nrobust.design.LoopDesign.certified`)."""
        return bool(self.design.certified)

    def __repr__(self) -> str:
        return (
            f"CollocatedDesign(K={self.K!r}, kappa={self.kappa!r}, {self.design.objective}={self.design.value_text}, "
            f"certified={self.certified}, local=True)"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return json_safe(
            {
                "controller": self.controller.to_dict(),
                "design": self.design.to_dict(),
                "bounds": self.bounds,
                "gamma_max": self.gamma_max,
                "scope": self.scope,
                "failed": self.failed,
                "local": self.local,
            }
        )


@dataclass(frozen=True)
class _Start:
    """One start of the joint design: :func:`nrobust.design.optimize_loop` from ``x0`` (picklable)."""

    loop: CollocatedJointLoop
    bounds: tuple[tuple[float, float], tuple[float, float]]
    objective: str
    margin_at_least: float | None
    gamma_max: float
    max_iter: int
    rigorous: bool

    def __call__(self, x0: tuple[float, float]) -> LoopDesign | str:
        try:
            return optimize_loop(
                self.loop,
                self.bounds,
                objective=self.objective,
                margin_at_least=self.margin_at_least,
                gamma_max=self.gamma_max,
                x0=x0,
                starts=1,
                max_iter=self.max_iter,
                rigorous=self.rigorous,
            )
        except CertificationError as exc:
            return f"start {x0}: {exc}"


def _warm_start(
    loop: CollocatedJointLoop,
    bounds: tuple[tuple[float, float], tuple[float, float]],
    objective: str,
    margin_at_least: float | None,
    gamma_max: float,
) -> tuple[float, float] | None:
    """``(K_0, kappa*)``: the exact best ``kappa`` at ``K_0 = 0.1`` (else the middle of the ``K`` bounds).

    ``kappa*`` by :func:`nrobust.design.best_margin` / :func:`~nrobust.design.best_decay_rate` on the
    loop affine in ``kappa`` at ``K_0``, over the ``kappa`` where ``gamma_0 <= gamma_max`` (inside the
    bounds), as :func:`design_collocated_observer` finds it: the joint design is then at least as good
    as that one-parameter design. None when the section is empty or the exact design fails.
    """
    (k_lo, k_hi), (c_lo, c_hi) = bounds
    K0 = _START_K if k_lo <= _START_K <= k_hi else 0.5 * (k_lo + k_hi)
    section = _section(loop.principal(), 0, K0, gamma_max)
    if section is None:
        return None
    lo, hi = max(section[0], c_lo), min(section[1], c_hi)
    if not lo < hi:
        return None
    affine = AffineLoop(loop.A0 + loop.AK * K0, loop.Akappa, loop.B0 + loop.BK * K0, loop.Bkappa + loop.BKkappa * K0)
    try:
        if objective == "margin":
            kappa = best_margin(affine, (lo, hi)).K
        else:
            assert margin_at_least is not None
            kappa = best_decay_rate(affine, (lo, hi), margin_at_least=margin_at_least).K
    except (CertificationError, ParameterError):
        return None
    return K0, float(kappa)


def _near(
    point: tuple[float, float], bounds: tuple[tuple[float, float], tuple[float, float]]
) -> list[tuple[float, float]]:
    """``point`` and the small grid about it: ``+- _NEAR`` of the bounds' widths along each axis, inside the bounds.

    The exact one-parameter start often sits at a kink of the margin in ``kappa`` (two crossing curves meet),
    where the line search and the pattern search can both stall though the margin grows along the ridge;
    from a neighbour the search reaches the ridge from its smooth side.
    """
    out = [point]
    for axis in (1, 0):
        width = bounds[axis][1] - bounds[axis][0]
        for side in (-1.0, 1.0):
            q = list(point)
            q[axis] = min(max(q[axis] + side * _NEAR * width, bounds[axis][0]), bounds[axis][1])
            if tuple(q) not in out:
                out.append((q[0], q[1]))
    return out


def _grid_starts(
    loop: CollocatedJointLoop, bounds: tuple[tuple[float, float], tuple[float, float]], count: int, gamma_max: float
) -> list[tuple[float, float]]:
    """Up to ``count`` starts spread over the region ``gamma_0 <= gamma_max`` in the bounds.

    ``K`` at the middles of ``8 count`` equal parts of its bounds, those whose section ``gamma_0 <=
    gamma_max`` meets the ``kappa`` bounds kept (the region need not be connected), ``count`` of them
    evenly spaced; ``kappa`` at the middle of the section.
    """
    (k_lo, k_hi), (c_lo, c_hi) = bounds
    c = loop.principal()
    parts = _GRID_PARTS * count
    candidates = []
    for K in k_lo + (np.arange(parts) + 0.5) * (k_hi - k_lo) / parts:
        section = _section(c, 0, float(K), gamma_max)
        if section is None:
            continue
        lo, hi = max(section[0], c_lo), min(section[1], c_hi)
        if lo < hi:
            candidates.append((float(K), 0.5 * (lo + hi)))
    if len(candidates) <= count:
        return candidates
    return [candidates[int(i)] for i in np.linspace(0, len(candidates) - 1, count).round()]


def _check_model(
    loop: CollocatedJointLoop, p: tuple[float, ...], factors: tuple[QuasiPolynomial, ...], top: float
) -> None:
    """The bilinear model at ``p`` is the loop built at ``p`` on the axis up to ``top`` (else the design is not
    about that loop)."""
    s = 1j * np.linspace(0.0, top, 257)
    for model, built in zip(loop(np.asarray(p)), factors, strict=True):
        a, b = model(s), built(s)
        err = float(np.max(np.abs(a - b)))
        if err > _MODEL_RTOL * max(float(np.max(np.abs(b))), 1.0):
            raise CertificationError(
                f"design_collocated_output_feedback: the loop is not bilinear in (K, kappa) to rounding ({err:.2e} "
                f"at (K, kappa) = {p}), so the design is not about the loop built there"
            )


@one_blas_thread()  # many small products: competing BLAS threads only cost time
def design_collocated_output_feedback(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    objective: str = "margin",
    *,
    margin_at_least: float | None = None,
    K_bounds: tuple[float, float] | None = None,
    kappa_bounds: tuple[float, float] | None = None,
    observer_delay: float = 0.0,
    gamma_max: float = JOINT_GAMMA_MAX,
    x0: ArrayLike | None = None,
    starts: int = 6,
    max_iter: int = 60,
    rigorous: bool = False,
    executor: Any = "serial",
    progress: bool | None = None,
) -> CollocatedDesign:
    """The gain ``K`` of U_BS2(K) and the collocated observer's reflection ``kappa`` designed together.

    The loop is bilinear in ``(K, kappa)`` (:func:`collocated_joint_loop`); the core's local
    nonsmooth optimiser (:func:`nrobust.design.optimize_loop`) maximises its delay margin, or its
    decay rate at ``delta = 0`` under a required margin, with every iterate's ``gamma_0 <=
    gamma_max`` (strong stability of the delayed loop's difference operator) and certified, from
    several starts: the exact best ``kappa`` at ``K = 0.1`` (the one-parameter design of
    :func:`design_collocated_observer` at its default law, over the ``kappa`` with ``gamma_0 <=
    gamma_max``, so the joint design is at least as good), a small grid about it, then points of the
    region spread over the ``K`` bounds. A start the core refuses (e.g. unstable at ``delta = 0``:
    the zeros of ``E`` are modes of the loop) is listed in :attr:`CollocatedDesign.failed`. The best
    run is certified (its abscissa and delay margin) on the bilinear model, which is checked against
    the loop built at the design. A local optimum (``local`` is True).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant (a general plant with a constant ``lam/mu`` through its normal form).
    objective : {"margin", "decay_rate"}
        What to maximise.
    margin_at_least : float, optional
        The delay margin required (``> 0``), with ``objective="decay_rate"`` only.
    K_bounds, kappa_bounds : (float, float), optional
        The box searched; default the smallest box about the region ``gamma_0 <= gamma_max``
        (:func:`joint_bounds`).
    observer_delay : float, default 0
        The delay of the commands the observer replays (with ``delta_o > 0`` the region is that of
        ``|rho + kappa| |q| + |kappa rho| q^2 + |K q| + |K rho| q^2 + |K (rho - kappa)| q^2``).
    gamma_max : float, default :data:`JOINT_GAMMA_MAX`
        In ``(0, 1)``: the bound on ``gamma_0`` (:func:`nrobust.design.delayed_gamma`) of every iterate.
    x0 : (float, float), optional
        The first start ``(K, kappa)`` instead of the exact one at ``K = 0.1``.
    starts : int, default 6
        Starts in all (``>= 1``): ``x0`` (or the exact start), then the small grid about it (``+-1 %``
        of the bounds' widths along each axis), then starts spread over the region.
    max_iter, rigorous
        As in :func:`nrobust.design.optimize_loop`.
    executor : None, str, int, Executor or dask.distributed.Client
        Where the starts run (:func:`nrobust.sweep_map`); ``"serial"`` in this process.
    progress : bool, optional
        Progress bar (as in :func:`nrobust.k_region`).

    Returns
    -------
    CollocatedDesign

    Raises
    ------
    ParameterError
        Bad input; no ``(K, kappa)`` with ``gamma_0 <= gamma_max``.
    CertificationError
        No start reached a certified design (reasons given: widen the bounds, raise ``gamma_max``,
        lower ``margin_at_least``), or the bilinear model is not the loop built at the design.
    """
    if objective not in OBSERVER_OBJECTIVES:
        raise ParameterError("objective", f"one of {OBSERVER_OBJECTIVES}", objective)
    if objective == "decay_rate":
        if margin_at_least is None:
            raise ParameterError("margin_at_least", "a positive delay margin with objective='decay_rate'", None)
        margin_at_least = positive("margin_at_least", margin_at_least)
    elif margin_at_least is not None:
        raise ParameterError("margin_at_least", "None with objective='margin'", margin_at_least)
    gamma_max = finite_real("gamma_max", gamma_max)
    if not 0.0 < gamma_max < 1.0:
        raise ParameterError("gamma_max", "in (0, 1) (strong stability of the delayed loop)", gamma_max)
    starts = positive_int("starts", starts)
    plant: Hyperbolic2x2 = study_plant(system, None, "design_collocated_output_feedback")[0]
    given = (
        _bounds("K_bounds", K_bounds) if K_bounds is not None else None,
        _bounds("kappa_bounds", kappa_bounds) if kappa_bounds is not None else None,
    )
    loop = collocated_joint_loop(plant, observer_delay)
    default = joint_bounds(loop, gamma_max) if None in given else ((0.0, 0.0), (0.0, 0.0))
    bounds = (given[0] or default[0], given[1] or default[1])
    first: tuple[float, float] | None
    if x0 is not None:
        first = _bounds_point("x0", x0)
    else:
        first = _warm_start(loop, bounds, objective, margin_at_least, gamma_max)
    points = _near(first, bounds) if first is not None else []
    points += _grid_starts(loop, bounds, starts - len(points), gamma_max) if starts > len(points) else []
    points = points[:starts]
    job = _Start(loop, bounds, objective, margin_at_least, gamma_max, positive_int("max_iter", max_iter), rigorous)
    results = list(mapper(executor, progress, "collocated design")(job, points))
    designs = [r for r in results if isinstance(r, LoopDesign) and r.certified]
    if not designs:
        reasons = "; ".join(r if isinstance(r, str) else f"start {r.runs[0].start}: not certified" for r in results)
        raise CertificationError(
            f"design_collocated_output_feedback: no start reached a certified design ({reasons or 'no start'}); "
            "widen the bounds, raise gamma_max or lower margin_at_least"
        )
    best = max(designs, key=lambda d: d.value)
    others = sorted(
        (run for d in results if isinstance(d, LoopDesign) and d is not best for run in d.runs),
        key=lambda r: (not r.feasible, -r.value if r.feasible else 0.0),
    )
    best = dataclasses.replace(best, runs=(*best.runs, *others))
    controller = loop.controller(best.parameters)
    factors = loop_factors(plant, controller)
    _check_model(loop, best.parameters, factors, 2.0 * max(float(best.margin.omega or 0.0), 1.0))
    scope = loop_scope(plant, controller, None, factors, mapped=False, normal_form=plant is not system)
    if loop_route(plant, controller, None) != "exact" and not plant.uncoupled:  # a model: its error estimated
        errors = observer_model_error(plant, controller, best.margin, factors)
        margin = dataclasses.replace(
            best.margin, scope=scope, of_model=True, model_error=errors[0], omega_model_error=errors[1]
        )
        best = dataclasses.replace(best, margin=margin)
    failed = tuple(
        r if isinstance(r, str) else f"start {r.runs[0].start}: not certified"
        for r in results
        if not any(r is d for d in designs)
    )
    return CollocatedDesign(controller, best, bounds, gamma_max, scope, failed)


def _bounds_point(name: str, value: Any) -> tuple[float, float]:
    try:
        K, kappa = (finite_real(name, v) for v in value)
    except (TypeError, ValueError) as exc:
        raise ParameterError(name, "a pair (K, kappa) of finite numbers", value) from exc
    return K, kappa
