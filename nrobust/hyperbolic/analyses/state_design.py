"""Design of a general boundary state feedback: the gain ``k`` and integral gains on a basis.

:class:`~nrobust.hyperbolic.loops.controllers.StateFeedback` applies
``U = k u(t, L) + int_0^L g_u u + g_v v dx``. Its loop is ``A = 1 - Phi``, ``B = -P``
(:mod:`~nrobust.hyperbolic.loops.feedback`), and ``P`` is linear in the gains: with
``g_u = sum_j c_j phi_j``, ``g_v = sum_j d_j phi_j`` on a basis ``phi_j`` of functions of
``x``, ``B(p) = sum_i p_i B_i`` for ``p = (k, c_1, ..., c_n, d_1, ..., d_n)``, each ``B_i`` the
``B`` of one unit gain, all on one kernel grid so that they share one ``A``
(:class:`StateFeedbackLoop`). :func:`design_state_feedback` maximises the delay margin, or the
decay rate (optionally under a required margin), over ``p`` with the core's local nonsmooth
optimiser (:func:`nrobust.design.optimize_loop`; without a basis, the loop affine in ``k``, by the
exact one-gain engine, :mod:`nrobust.design.gain`) and certifies the design, optionally under a
window of delays (``delays``) and a tolerance on the transport speeds (``speed_tolerance``: the
gains, fixed functions of ``x``, acting on the four corner plants with mismatched speeds, whose
loops are linear in ``p`` too: :func:`state_feedback_loop` of each; the decay rate maximised is then
the least of the nominal plant's and the corners').

Unlike U_BS2(K), whose target system is exponentially stable for every ``|K|`` below the
bound of eq. (54), a state feedback can leave the nominal loop unstable (``k = 0`` on the
paper's plant is its open loop). The optimiser never takes such a point for a margin (its
margin objective rejects it), and the starts are chosen stable where possible: the best
proportional gain (``g_u = g_v = 0``), solved exactly by the core's one-gain engine
(:mod:`nrobust.design.gain`) since the loop is affine in ``k``, and, with a basis, the
kernel traces of U_BS2(K)'s law (eq. (53), ``k = -K``) projected on the basis by least
squares, nominally stable when the basis represents them well.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._json import json_safe
from ..._threads import one_blas_thread
from ..._validate import callables, finite_real, positive_int
from ...design.gain import GainDesign, best_decay_rate, best_margin
from ...design.local import GAMMA_MAX, LocalRun, LoopDesign, delayed_gamma, optimize_loop
from ...errors import CertificationError, ParameterError
from ...margins.gain import AffineGainLoop
from ...quasipoly import QuasiPolynomial
from ...roots import SpectralAbscissa, spectral_abscissa
from ..kernels.constant import DEFAULT_KERNEL_GRID, check_kernel_grid, solve_kernels
from ..loops.controllers import ReflectionController, StateFeedback, loop_factors, loop_scope
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from ._common import CornerRates, mapper
from .design import design_reflection
from .mismatch import SpeedTolerance, check_local_requirements, mismatch_abscissa
from .mismatch import speed_tolerance as tolerance_on_square

__all__ = [
    "BasisGain",
    "StateFeedbackDesign",
    "StateFeedbackLoop",
    "default_state_k_bounds",
    "design_state_feedback",
    "state_feedback_loop",
]

#: Default ``|k|`` bound: this fraction of ``(1 - |rho q|)/|q|`` (strong stability of the delayed loop).
K_BOUND_FRACTION = 0.99
#: Gains of the 1-D search for the proportional start of the decay-rate objective without a margin.
PROPORTIONAL_SAMPLES = 9
#: Points of ``[0, L]`` at which the kernel traces of U_BS2(K) are projected on the basis.
PROJECTION_POINTS = 201


@dataclass(frozen=True)
class BasisGain:
    """``x -> sum_j coefficients[j] basis[j](x)``: an integral gain on a basis (picklable if the basis is).

    Attributes
    ----------
    coefficients : tuple of float
    basis : tuple of callable
        Functions of an array of ``x`` returning an array of the same shape.
    """

    coefficients: tuple[float, ...]
    basis: tuple[Callable[[NDArray[np.float64]], NDArray[np.float64]], ...]

    def __call__(self, x: ArrayLike) -> NDArray[np.float64]:
        x = np.asarray(x, dtype=float)
        out = np.zeros(x.shape)
        for c, phi in zip(self.coefficients, self.basis):
            out = out + c * np.asarray(phi(x), dtype=float)
        return out

    def __repr__(self) -> str:
        names = ", ".join(getattr(phi, "__name__", repr(phi)) for phi in self.basis)
        coefs = ", ".join(f"{c:.12g}" for c in self.coefficients)
        return f"BasisGain(coefficients=({coefs}), basis=({names}))"


@dataclass(frozen=True)
class StateFeedbackLoop:
    """``p -> (A, sum_i p_i B_i)``: the loop of ``StateFeedback`` at the gains ``p`` (picklable).

    Attributes
    ----------
    A : QuasiPolynomial
        ``1 - Phi``, shared by every unit gain.
    units : tuple of QuasiPolynomial
        ``B`` of ``k = 1``, then of ``g_u = phi_j`` for each basis function, then of ``g_v = phi_j``.
    """

    A: QuasiPolynomial
    units: tuple[QuasiPolynomial, ...]

    def B(self, p: ArrayLike) -> QuasiPolynomial:
        """``sum_i p_i B_i``."""
        p = np.asarray(p, dtype=float)
        total = self.units[0] * float(p[0])
        for c, unit in zip(p[1:], self.units[1:]):
            total = total + unit * float(c)
        return total

    def __call__(self, p: NDArray[np.float64]) -> tuple[QuasiPolynomial, QuasiPolynomial]:
        return self.A, self.B(p)


def _plant(system: Any) -> Hyperbolic2x2 | GeneralHyperbolic2x2:
    if not isinstance(system, (Hyperbolic2x2, GeneralHyperbolic2x2)):
        raise ParameterError("system", "a Hyperbolic2x2, TransportSystem or GeneralHyperbolic2x2", system)
    return system


def _length(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> float:
    return float(system.length) if isinstance(system, GeneralHyperbolic2x2) else 1.0


def _basis(basis: Any, length: float) -> tuple[Callable[[NDArray[np.float64]], NDArray[np.float64]], ...]:
    """The basis as a tuple of callables, each finite on ``[0, L]``, linearly independent there."""
    items = callables(
        "basis",
        basis,
        "a sequence of callables phi_j(x) on arrays of x in [0, L]",
        "a callable phi(x) on arrays of x in [0, L]",
    )
    x = np.linspace(0.0, length, PROJECTION_POINTS)
    columns = []
    for j, phi in enumerate(items):
        try:
            values = np.asarray(phi(x), dtype=float)
        except (TypeError, ValueError):
            raise ParameterError(f"basis[{j}]", "a callable returning an array of floats shaped like x", phi) from None
        if values.shape != x.shape or not np.all(np.isfinite(values)):
            raise ParameterError(f"basis[{j}]", f"finite values on [0, {length:g}], an array shaped like x", phi)
        columns.append(values)
    if columns and np.linalg.matrix_rank(np.column_stack(columns)) < len(columns):
        raise ParameterError("basis", f"linearly independent functions on [0, {length:g}]", basis)
    return items


def _pair(name: str, value: Any) -> tuple[float, float]:
    try:
        lo, hi = value
    except (TypeError, ValueError):
        raise ParameterError(name, "a pair (low, high) of finite reals with low < high", value) from None
    lo, hi = finite_real(f"{name}[0]", lo), finite_real(f"{name}[1]", hi)
    if not lo < hi:
        raise ParameterError(name, "a pair (low, high) of finite reals with low < high", value)
    return lo, hi


def state_feedback_loop(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2, basis: Sequence[Any] = (), kernel_grid: int | None = None
) -> StateFeedbackLoop:
    """The loop family of ``StateFeedback(k, sum c_j phi_j, sum d_j phi_j)`` on ``system``.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant; the gains act on its state (physical coordinates on ``[0, L]``).
    basis : sequence of callable
        The functions ``phi_j`` of ``x`` on which both integral gains are expanded.
    kernel_grid : int, optional
        The kernel grid of every unit gain's loop factors. None: the exact route for a proportional
        law on constant coefficients (no basis), else
        :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID` points.

    Returns
    -------
    StateFeedbackLoop
        Its parameters ``p = (k, c_1, ..., c_n, d_1, ..., d_n)``.
    """
    plant = _plant(system)
    functions = _basis(basis, _length(plant))
    grid = _grid(functions, kernel_grid)
    A, B_k = loop_factors(plant, StateFeedback(1.0), grid)
    units = [B_k]
    for slot in ("u", "v"):
        for phi in functions:
            gains = (phi, 0.0) if slot == "u" else (0.0, phi)
            units.append(loop_factors(plant, StateFeedback(0.0, *gains), grid)[1])
    return StateFeedbackLoop(A, tuple(units))


def _grid(basis: tuple[Any, ...], kernel_grid: int | None) -> int | None:
    """The kernel grid the unit gains share: None (a route of the plant's choosing) only without a basis."""
    if kernel_grid is not None:
        return check_kernel_grid(kernel_grid)
    return None if not basis else DEFAULT_KERNEL_GRID


def _controller(p: ArrayLike, basis: tuple[Any, ...]) -> StateFeedback:
    p = np.asarray(p, dtype=float)
    n = len(basis)
    if not n:
        return StateFeedback(float(p[0]))
    c, d = tuple(map(float, p[1 : 1 + n])), tuple(map(float, p[1 + n :]))
    return StateFeedback(float(p[0]), BasisGain(c, basis), BasisGain(d, basis))


def default_state_k_bounds(loop: StateFeedbackLoop) -> tuple[float, float]:
    """The default bounds of ``k`` of :func:`design_state_feedback`: ``0.99 (1 - |rho q|)/|q|`` each side.

    ``rho q`` and ``q`` are the principal terms of ``A`` and ``B_k`` of ``loop``
    (:func:`state_feedback_loop`).

    The delayed loop's difference operator is ``1 - rho q e^{-tau s} - k q e^{-(tau + delta) s}``
    (normalised by the undelayed coefficient of ``A``): strongly stable iff ``|rho q| + |k q| < 1``.
    """
    a = loop.A.leading_terms(0)
    a0 = sum(abs(c) for c, t in a if t == 0.0)
    rq = sum(abs(c) for c, t in a if t != 0.0) / a0
    q = sum(abs(c) for c, _ in loop.units[0].leading_terms(0)) / a0
    if not rq < 1.0:
        raise ParameterError(
            "system", f"|rho q| < 1 (a strongly stable delayed loop needs it; here |rho q| = {rq:.6g})", rq
        )
    if q == 0.0:
        raise ParameterError("k_bounds", "a pair (low, high): q = 0 leaves |k| unbounded by strong stability", None)
    k = K_BOUND_FRACTION * (1.0 - rq) / q
    return -k, k


def _affine(loop: StateFeedbackLoop) -> AffineGainLoop:
    """``A + k B_k e^{-delta s}``: the proportional loop as the one-gain engine's family."""
    return AffineGainLoop(loop.A, loop.units[0] * 0.0, loop.units[0])


# How the one-gain engine's refusal of bounds without a gain stable at delta = 0 (certified) begins.
_NO_STABLE_GAIN = "parameters of which some give a stable loop without delay"


def _exact_gain(
    loop: StateFeedbackLoop,
    bounds: tuple[float, float],
    objective: str,
    margin_at_least: float | None,
    window: tuple[float, float] | None,
    scenarios: tuple[StateFeedbackLoop, ...],
    rigorous: bool,
) -> GainDesign:
    """The best proportional gain by the one-gain engine (:mod:`nrobust.design.gain`): the global optimum over ``k``.

    With ``scenarios`` (a window required of them too) the decay rate is the least of the loop's and theirs
    (``worst_case``).

    The engine's :class:`~nrobust.errors.ParameterError` that no gain of the bounds is stable at
    ``delta = 0`` (certified) is raised about ``k_bounds``; its other refusals (e.g. bounds beyond
    strong stability) as they are.
    """
    affine, others = _affine(loop), tuple(_affine(f) for f in scenarios)
    try:
        if objective == "margin":
            return best_margin(affine, bounds, delays=window, scenarios=others, rigorous=rigorous)
        if window is not None:
            return best_decay_rate(
                affine, bounds, delays=window, scenarios=others, worst_case=bool(others), rigorous=rigorous
            )
        return best_decay_rate(affine, bounds, margin_at_least=margin_at_least or None, rigorous=rigorous)
    except ParameterError as exc:
        if exc.name != "bounds" or not exc.requirement.startswith(_NO_STABLE_GAIN):
            raise
        raise ParameterError(
            "k_bounds",
            f"{exc.requirement}; with U = k u(t, L) alone, a basis of integral gains (U_BS2(K)'s kernel traces "
            "projected on it) may stabilise the plant",
            bounds,
        ) from None


def _exact_design(
    loop: StateFeedbackLoop,
    gain: GainDesign,
    objective: str,
    margin_at_least: float | None,
    window: tuple[float, float] | None,
    rigorous: bool,
    scenarios: tuple[StateFeedbackLoop, ...] = (),
) -> LoopDesign:
    """The exact proportional optimum ``gain`` as a :class:`LoopDesign` (``local=False``), certified as
    :func:`~nrobust.design.optimize_loop` certifies its designs: the abscissa (proven when ``rigorous``), the
    engine's delay margin (verified, or proven) meeting ``margin_at_least``, the windows the engine certified;
    for the least decay rate of the loop and ``scenarios`` (``gain.scenario_abscissae``), each scenario's
    abscissa too, the value the least rate."""
    p = (float(gain.K),)
    A, B = loop(np.asarray(p))
    F = A + B
    # the engine's floating-point abscissa is of this loop when its nominal loop is this one
    sa = gain.abscissa if not rigorous and gain.nominal == F else spectral_abscissa(F, rigorous=rigorous)
    others = gain.scenario_abscissae
    if others and rigorous:
        others = tuple(spectral_abscissa(s.A + s.B(p), rigorous=True) for s in scenarios)
    dm = gain.certificate
    lowest = dm.margin_ball[0] if (rigorous and dm.margin_ball is not None) else dm.margin
    met = not margin_at_least or lowest >= margin_at_least
    decided = dm.verified or (math.isinf(dm.margin) and dm.nominally_stable and dm.strongly_stable)
    if objective == "margin" or not (window is not None and window[0] > 0.0):
        decided = decided and dm.nominally_stable
    proven = not rigorous or (gain.certified == "proven" and all(w.certified == "proven" for w in gain.windows))
    stable = all(w.stable for w in gain.windows) and all(o.certified for o in others)
    certified = bool(sa.certified and decided and met and proven and stable)
    value = -max(a.value for a in (sa, *others)) if objective == "decay_rate" else dm.margin
    run = LocalRun(p, p, float(value), True, 0, 0, 0.0, f"the exact optimum over k: {gain.kind}")
    return LoopDesign(
        p,
        objective,
        float(value),
        float(-sa.value),
        sa,
        dm,
        margin_at_least,
        certified,
        rigorous,
        (run,),
        local=False,
        delays=window,
        windows=gain.windows,
        scenario_abscissae=others,
    )


def _proportional_starts(
    loop: StateFeedbackLoop,
    bounds: tuple[float, float],
    objective: str,
    margin_at_least: float | None,
    window: tuple[float, float] | None = None,
    scenarios: tuple[StateFeedbackLoop, ...] = (),
) -> tuple[list[float], bool]:
    """Starting gains ``k`` with ``g_u = g_v = 0``, and whether the first is the exact optimum.

    The objective (margin, decay rate with or without a margin, or under a window met by the
    loop and the ``scenarios`` alike) is solved exactly by the one-gain engine
    (:func:`_exact_gain`; the loop is affine in ``k``): its gain alone, the global optimum over
    ``k``. When the engine cannot certify, the spectral abscissa is sampled at
    :data:`PROPORTIONAL_SAMPLES` gains of ``bounds`` (those whose delayed loop meets
    ``gamma_0 <= GAMMA_MAX``) and its local minima are the starts, the smallest first.
    """
    try:
        return [float(_exact_gain(loop, bounds, objective, margin_at_least, window, scenarios, False).K)], True
    except (CertificationError, ParameterError):
        pass
    ks, alphas = [], []
    for k in np.linspace(bounds[0], bounds[1], PROPORTIONAL_SAMPLES):
        B = loop.units[0] * float(k)
        if delayed_gamma(loop.A, B) <= GAMMA_MAX:
            ks.append(float(k))
            alphas.append(spectral_abscissa(loop.A + B).value)
    a = np.array([math.inf, *alphas, math.inf])
    minima = [i for i in range(len(ks)) if a[i + 1] <= a[i] and a[i + 1] <= a[i + 2]]
    minima.sort(key=lambda i: a[i + 1])
    return [ks[i] for i in minima] or [0.5 * (bounds[0] + bounds[1])], False


def _trace_starts(
    plant: Hyperbolic2x2 | GeneralHyperbolic2x2,
    basis: tuple[Any, ...],
    gains: Sequence[float],
    kernel_grid: int,
) -> list[NDArray[np.float64]]:
    """``(k, c, d)`` of U_BS2(K)'s law (eq. (53)) for each ``K`` in ``gains``, its gains projected on the basis.

    ``k = -K``; ``g_u``, ``g_v`` the kernel traces, fitted by least squares on
    :data:`PROJECTION_POINTS` points of ``[0, 1]``. Only for the paper's plant (a general
    plant's law lives on its normal form).
    """
    if not isinstance(plant, Hyperbolic2x2) or not basis:
        return []
    kernels = None if plant.uncoupled else solve_kernels(plant, kernel_grid)
    x = np.linspace(0.0, 1.0, PROJECTION_POINTS)
    Phi = np.column_stack([np.asarray(phi(x), dtype=float) for phi in basis])
    out = []
    for K in gains:
        law = ReflectionController(float(K)).feedback_law(plant, kernels)
        c = np.linalg.lstsq(Phi, law.gain_u(x), rcond=None)[0]
        d = np.linalg.lstsq(Phi, law.gain_v(x), rcond=None)[0]
        out.append(np.concatenate([[law.boundary_gain], c, d]))
    return out


def _best_reflection(
    plant: Hyperbolic2x2 | GeneralHyperbolic2x2, objective: str, margin_at_least: float | None
) -> list[float]:
    """The gain of the best U_BS2(K) for the objective (:func:`~nrobust.hyperbolic.analyses.design.design_reflection`).

    Its law, projected on the basis, is the first start of a design with a basis on the paper's
    plant. Empty for a general plant, for the decay rate without a margin (U_BS2's rate grows
    towards the end of its bounds) or when the exact design fails.
    """
    if not isinstance(plant, Hyperbolic2x2) or (objective == "decay_rate" and not margin_at_least):
        return []
    try:
        return [design_reflection(plant, objective, margin_at_least=margin_at_least).K]
    except (CertificationError, ParameterError):
        return []


@dataclass(frozen=True)
class _FromStart:
    """Picklable ``x0 -> optimize_loop(loop, bounds, x0=x0, starts=1, ...)``, or the reason it failed."""

    loop: StateFeedbackLoop
    bounds: tuple[tuple[float, float], ...]
    objective: str
    margin_at_least: float | None
    rigorous: bool
    window: tuple[float, float] | None = None
    scenarios: tuple[StateFeedbackLoop, ...] = ()

    def _run(self, x0: tuple[float, ...], objective: str, margin_at_least: float | None, required: bool) -> LoopDesign:
        return optimize_loop(
            self.loop,
            self.bounds,
            objective=objective,
            margin_at_least=margin_at_least,
            delays=self.window if required else None,
            scenarios=self.scenarios if required else (),
            worst_case=required and objective == "decay_rate" and bool(self.scenarios),
            x0=x0,
            starts=1,
            rigorous=self.rigorous,
        )

    def __call__(self, x0: tuple[float, ...]) -> LoopDesign | str:
        """The design from ``x0``; a start unstable at ``delta = 0`` first maximises the decay rate.

        The core rejects a nominally unstable point for a margin (objective or requirement, a
        window from ``d_min = 0``), so such a start would end there; its decay rate (without
        requirement) is maximised first, and the design continues from the first stable point it
        reaches.
        """
        from_zero = self.window is not None and self.window[0] == 0.0
        try:
            if (self.objective == "margin" or self.margin_at_least or from_zero) and not (
                spectral_abscissa(self.loop.A + self.loop.B(x0)).upper_bound < 0.0
            ):
                first = self._run(x0, "decay_rate", None, False)
                if not _stable(first):
                    return (
                        f"from {x0}: the best decay rate reached, {first.decay_rate:.6g}, leaves the loop unstable "
                        "at delta = 0"
                    )
                x0 = first.parameters
            return self._run(x0, self.objective, self.margin_at_least, True)
        except CertificationError as exc:
            return f"from {x0}: {exc}"


def _stable(design: LoopDesign) -> bool:
    """True if the design's loop is exponentially stable at ``delta = 0``.

    The certified count of zeros in ``Re s > 0`` of its delay margin finds none, and the
    certified abscissa's located rightmost zero (or chain) is left of the axis.
    """
    return bool(design.margin.nominally_stable and design.abscissa.value < 0.0)


@dataclass(frozen=True)
class StateFeedbackDesign(CornerRates):
    """A designed ``StateFeedback(k, g_u, g_v)`` with its certificate.

    Attributes
    ----------
    controller : StateFeedback
        The design; with a basis its integral gains are :class:`BasisGain`.
    parameters : tuple of float
        ``(k, c_1, ..., c_n, d_1, ..., d_n)``: ``g_u = sum c_j phi_j``, ``g_v = sum d_j phi_j``.
    design : LoopDesign
        The core's result: objective value, certified abscissa and delay margin, every start's run.
    scope : str
        What the certificate is about: the PDE itself (exact route or an uncoupled plant) or a
        model of it (kernels on a grid).
    tolerance : SpeedTolerance or None
        With ``speed_tolerance``: the verdicts on the square of speed mismatches, the corners
        certified again on loops built by :func:`~nrobust.hyperbolic.analyses.mismatch_loop`
        (:func:`~nrobust.hyperbolic.analyses.speed_tolerance`), the other points of a 3 x 3 grid
        checked.
    corner_abscissae : tuple of SpectralAbscissa
        With ``speed_tolerance`` and the decay-rate objective: the spectral abscissa at ``delta = 0`` of the
        designed law on each corner plant, in the order of ``tolerance.points[:4]``, restated on loops built by
        :func:`~nrobust.hyperbolic.analyses.mismatch_abscissa` with its model error (the design's own, on the
        corner loops it optimised, are ``design.scenario_abscissae``); empty otherwise. The gains maximise the
        least decay rate of the nominal plant and the corners: :attr:`worst_decay_rate` is what the law
        guarantees there (between the corners it is not certified).
    """

    controller: StateFeedback
    parameters: tuple[float, ...]
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
                "parameters": list(self.parameters),
                "design": self.design.to_dict(),
                "scope": self.scope,
                "tolerance": None if self.tolerance is None else self.tolerance.to_dict(),
                "requirement": self.requirement,
                **self.corner_dict(),
            }
        )


@one_blas_thread()  # many small products: competing BLAS threads only cost time
def design_state_feedback(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    objective: str = "margin",
    *,
    margin_at_least: float | None = None,
    delays: tuple[float, float] | None = None,
    speed_tolerance: float | None = None,
    k_bounds: tuple[float, float] | None = None,
    basis: Sequence[Callable[[NDArray[np.float64]], NDArray[np.float64]]] = (),
    coefficient_bounds: tuple[float, float] = (-1.0, 1.0),
    starts: int = 4,
    rigorous: bool = False,
    kernel_grid: int | None = None,
    executor: Any = "serial",
) -> StateFeedbackDesign:
    """The state feedback ``U = k u(t, L) + int_0^L g_u u + g_v v dx`` with the best margin or decay rate.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant; the gains act on its state.
    objective : {"margin", "decay_rate"}
        Maximise the delay margin, or the decay rate ``-alpha`` at ``delta = 0``.
    margin_at_least : float, optional
        With ``"decay_rate"``: the delay margin required (stability for every delay in
        ``[0, margin_at_least]``); with ``speed_tolerance`` it is the window ``[0, margin_at_least]``
        (``delta* > margin_at_least``) on every plant.
    delays : (float, float), optional
        ``[d_min, d_max]``, ``0 <= d_min <= d_max``, ``d_max > 0``: the window of delays on which
        the designed loop must be exponentially stable, at every iterate
        (:func:`nrobust.design.optimize_loop`'s ``delays``; ``d_min > 0`` allows a loop unstable
        at ``delta = 0``); with either objective, not with ``margin_at_least``.
    speed_tolerance : float, optional
        ``eps`` in ``(0, 1)``: the window (or ``[0, margin_at_least]``) must hold too on the plants
        with speeds ``lam (1 + e_lam)``, ``mu (1 + e_mu)`` at the four corners ``|e_lam| = |e_mu| =
        eps``, the gains unchanged (four more loops, :func:`state_feedback_loop` of each plant); the
        design is then certified at the corners on loops built independently and checked at the
        other points of a 3 x 3 grid (:attr:`StateFeedbackDesign.tolerance`). With ``"decay_rate"``
        the gains maximise the least decay rate at ``delta = 0`` of the nominal loop and the four
        corners' (the exact engine's ``worst_case`` without a basis, ``optimize_loop(...,
        worst_case=True)`` with one: nonsmooth where two rates tie, a local optimum); ``value`` is that
        least rate, on the corners' loops restated with their model errors
        (:attr:`StateFeedbackDesign.corner_abscissae`), ``design.decay_rate`` the nominal rate. A
        :class:`~nrobust.hyperbolic.plants.hyperbolic2x2.Hyperbolic2x2` or ``TransportSystem``
        plant only (constant speeds).
    k_bounds : (float, float), optional
        Bounds of ``k``. Default: ``0.99 (1 - |rho q|)/|q|`` on each side, read from the
        principal terms of ``A`` and of the unit gain's ``B`` (the delayed loop is strongly
        stable iff ``|rho q| + |k q| < 1``).
    basis : sequence of callable
        Functions ``phi_j`` of ``x`` in ``[0, L]``: ``g_u = sum c_j phi_j``, ``g_v = sum d_j phi_j``.
        Empty: the proportional law ``U = k u(t, L)``, designed by the exact one-gain engine
        (:func:`~nrobust.design.best_margin`, :func:`~nrobust.design.best_decay_rate`: the global
        optimum over ``k``, ``design.local`` False, its kind in ``design.runs[0].reason``).
    coefficient_bounds : (float, float)
        Bounds of every ``c_j`` and ``d_j``.
    starts : int
        With a basis, most local searches, each from a distinct start: the best proportional gain
        (``g_u = g_v = 0``; the exact optimum over ``k`` of :mod:`nrobust.design.gain` when the
        engine certifies it, so the design can only improve on it; else the local minima of the
        sampled spectral abscissa); also U_BS2(K)'s law projected on it,
        for the best ``K`` of :func:`~nrobust.hyperbolic.analyses.design.design_reflection`
        (paper's plant, with a margin), ``K = -k`` of the best proportional gain and ``K``
        spread over the ``k`` bounds (the first of these before the proportional starts unless
        these are exact), then proportional gains spread over the bounds. A start unstable at
        ``delta = 0`` first maximises its decay rate (the core takes no margin of an unstable loop).
    rigorous : bool
        Certify every start's design in ball arithmetic (:func:`nrobust.design.optimize_loop`).
    kernel_grid : int or None, default None
        Kernel grid of every unit gain's loop (one ``A`` for all). None: the exact route for a
        proportional law (no basis) where the plant has one, else 201 points; a grid makes every loop,
        and the corners' of a speed tolerance, the kernel route's (a model).
    executor : None, str, int, Executor or dask.distributed.Client
        Where the starts run (:func:`nrobust.sweep_map`); ``"serial"`` in this process.

    Returns
    -------
    StateFeedbackDesign

    Raises
    ------
    ParameterError
        For bad input, naming the argument: ``k_bounds`` (or the default bounds) where no ``k``
        of a proportional law makes the loop stable at ``delta = 0`` (certified); ``delays`` not a window or given with
        ``margin_at_least``; ``speed_tolerance`` outside ``(0, 1)``, without a delay requirement,
        or on a :class:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2`.
    CertificationError
        If no start reaches a feasible design with a loop exponentially stable at ``delta = 0``
        (on the window, with ``d_min > 0``), or the design fails the independent certificate at
        a corner of the speed tolerance.
    """
    plant = _plant(system)
    margin_at_least, window, eps = check_local_requirements(plant, objective, margin_at_least, delays, speed_tolerance)
    functions = _basis(basis, _length(plant))
    coef = _pair("coefficient_bounds", coefficient_bounds)
    given = None if k_bounds is None else _pair("k_bounds", k_bounds)
    starts = positive_int("starts", starts)
    grid = _grid(functions, kernel_grid)
    map_ = mapper(executor, False, "state feedback design")

    loop = state_feedback_loop(plant, functions, grid)
    scenarios: tuple[StateFeedbackLoop, ...] = ()
    if eps is not None and isinstance(plant, Hyperbolic2x2):
        corners = [(a, b) for a in (-eps, eps) for b in (-eps, eps)]
        scenarios = tuple(
            state_feedback_loop(
                dataclasses.replace(plant, lam=plant.lam * (1 + a), mu=plant.mu * (1 + b)), functions, grid
            )
            for a, b in corners
        )
    kb = given if given is not None else default_state_k_bounds(loop)
    if not functions:  # one gain: the exact engine's global optimum over k, else the local search below
        try:
            gain = _exact_gain(loop, kb, objective, margin_at_least, window, scenarios, rigorous)
        except ParameterError as exc:
            if exc.name == "k_bounds":  # no gain stable at delta = 0, certified
                raise
            gain = None  # bounds the engine does not take (e.g. beyond strong stability)
        except CertificationError:
            gain = None
        if gain is not None:
            one = _exact_design(loop, gain, objective, margin_at_least, window, rigorous, scenarios)
            return _finished(plant, loop, one, functions, grid, eps, window, rigorous)
    bounds = (kb, *([coef] * (2 * len(functions))))
    box = np.array(bounds)
    ks, exact = _proportional_starts(loop, kb, objective, margin_at_least, window, scenarios)
    zeros = np.zeros(2 * len(functions))
    proportional = [np.concatenate([[k], zeros]) for k in ks]
    candidates = proportional if not exact else proportional[:1]  # the exact optimum over k needs no other
    if functions:
        spread = [float(k) for k in np.linspace(kb[0], kb[1], starts + 2)[1:-1]]
        trace_grid = grid if grid is not None else DEFAULT_KERNEL_GRID
        gains = [*_best_reflection(plant, objective, margin_at_least), -ks[0], *(-k for k in spread)]
        traces = _trace_starts(plant, functions, gains, trace_grid)
        # the exact proportional optimum first; otherwise the first law of U_BS2(K), stable at delta = 0
        candidates = candidates + traces if exact else traces[:1] + candidates + traces[1:]
        candidates += [np.concatenate([[k], zeros]) for k in spread]
    points: list[tuple[float, ...]] = []
    for p in candidates:
        point = tuple(map(float, np.clip(p, box[:, 0], box[:, 1])))
        if point not in points:
            points.append(point)
    points = points[:starts]

    results = list(map_(_FromStart(loop, bounds, objective, margin_at_least, rigorous, window, scenarios), points))
    designs = [r for r in results if isinstance(r, LoopDesign)]
    # from d_min > 0 the loop may be unstable at delta = 0: its certified windows decide
    stable = [r for r in designs if _stable(r) or (window is not None and window[0] > 0.0 and r.windows)]
    if not stable:
        reasons = sorted({r for r in results if isinstance(r, str)})
        reasons += [f"a design with spectral abscissa {r.abscissa.value:.6g} (not stable)" for r in designs]
        raise CertificationError(
            "design_state_feedback: no start reached a feasible design exponentially stable at delta = 0 ("
            + "; ".join(reasons)
            + "); widen k_bounds or coefficient_bounds, enrich the basis, add starts or lower margin_at_least"
        )
    best = max(stable, key=lambda r: (r.certified, r.value))
    runs = sorted(
        (run for r in designs for run in r.runs), key=lambda r: (not r.feasible, -r.value if r.feasible else 0.0)
    )
    best_run = best.runs[0]
    best = dataclasses.replace(best, runs=(best_run, *(r for r in runs if r is not best_run)))
    return _finished(plant, loop, best, functions, grid, eps, window, rigorous)


def _finished(
    plant: Hyperbolic2x2 | GeneralHyperbolic2x2,
    loop: StateFeedbackLoop,
    best: LoopDesign,
    functions: tuple[Any, ...],
    grid: int | None,
    eps: float | None,
    window: tuple[float, float] | None,
    rigorous: bool,
) -> StateFeedbackDesign:
    """The design ``best`` as a :class:`StateFeedbackDesign`, its speed tolerance certified on loops built
    independently (:func:`~nrobust.hyperbolic.analyses.speed_tolerance`) when ``eps`` is given."""
    controller = _controller(best.parameters, functions)
    factors = loop(np.asarray(best.parameters))
    scope = loop_scope(plant, controller, grid, factors, mapped=False)
    tolerance = None
    if eps is not None and window is not None and isinstance(plant, Hyperbolic2x2):
        tolerance_grid = grid if grid is not None else DEFAULT_KERNEL_GRID
        tolerance = tolerance_on_square(
            plant,
            controller,
            eps,
            window,
            kernel_grid=tolerance_grid,
            rigorous=rigorous,
        )
        missed = [p for p, w in zip(tolerance.points[:4], tolerance.windows[:4]) if not w.stable]
        if missed:
            raise CertificationError(
                f"design_state_feedback: the design {tuple(best.parameters)} is not stable on the window at the "
                f"corners {missed} of the speed tolerance when their loops are built by mismatch_loop (route "
                f"{tolerance.route!r}): the design's own loops and these differ; give kernel_grid=None for an "
                "exact route, or a finer grid"
            )
        if best.objective == "decay_rate":  # the least rate is maximised: each corner's restated with its model error
            corner_abscissae = tuple(
                mismatch_abscissa(plant, controller, a, b, kernel_grid=tolerance_grid, rigorous=rigorous)
                for a, b in tolerance.points[:4]
            )
            return StateFeedbackDesign(controller, tuple(best.parameters), best, scope, tolerance, corner_abscissae)
    return StateFeedbackDesign(controller, tuple(best.parameters), best, scope, tolerance)
