"""Boundary controllers of the paper and their closed loops with a loop delay.

Write ``Phi(t) = rho u(t, 1) - int_0^1 K^{vu}(1, xi) u + K^{vv}(1, xi) v dxi``, so that the
actuated boundary condition reads ``beta(t, 1) = Phi(t) + U(t)`` in the backstepping
coordinates (paper, eq. (34)). Along the characteristics (eqs. (37) to
(39)), ``Phi`` is a functional of the past of ``beta(., 1)`` whose Laplace
transform is ``Phi(s) beta(s, 1)`` with

    Phi(s) = rho q e^{-tau s} - I_N(s),    I_N(s) = int_0^tau N~(nu) e^{-nu s} dnu.

A controller with a loop delay ``delta`` then closes the loop as
``F(s; delta) = A(s) + B(s) e^{-delta s}``:

============================  ======================  =========================
controller                    A(s)                    B(s)
============================  ======================  =========================
open loop, ``U = 0``          ``1 - Phi``             ``0``
U_BS, eq. (47)                ``1 - Phi``             ``Phi``
U_BS2(K), eq. (53)            ``1 - Phi``             ``K q e^{-tau s} - I_N``
filtered U_BS, section 2.3.2  ``(1 + b s)(1 - Phi)``  ``(1 + a s) Phi``
any state feedback            ``1 - Phi``             ``-P`` (``feedback.py``)
============================  ======================  =========================

For U_BS this is ``1 - rho q e^{-tau s} + rho q e^{-(tau+delta) s} + I_N (1 - e^{-delta s})``
(Theorem 3), for U_BS2 ``1 - rho q e^{-tau s} + K q e^{-(tau+delta) s} + I_N (1 - e^{-delta
s})`` (the proof of Theorem 4, with ``+I(s, delta)``). On a transport system ``I_N = 0``
and these are eqs. (10), (13) and (16);
the last one, derived again from ``U_1 = -(1 + a s)/(1 + b s) rho u(1, s)``, has
``rho q v(t - tau - delta, 1)`` (not ``q rho a``) on its right-hand side.
"""

from __future__ import annotations

import dataclasses
import math
import re
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._digits import upper_bound_text
from ..._flint import precision, require_flint
from ..._json import fields_dict, json_safe
from ..._validate import finite_real, nonnegative, positive, renamed_keywords
from ...errors import ParameterError
from ...quasipoly import QuasiPolynomial
from ..kernels.constant import DEFAULT_KERNEL_GRID, Kernels, check_kernel_grid, solve_kernels
from ..kernels.varying import VaryingKernels, solve_varying_kernels
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2, TransportSystem
from ..plants.law import FeedbackLaw
from .collocated import (
    CollocatedObserver,
    ObserverReflection,
    collocated_observer,
    collocated_responses,
    observer_reflection,
    reflection_factors,
)
from .delay_form import delay_form
from .exact_form import (
    PRECISION,
    ExactForm,
    ball_radius,
    closed_form_parameters,
    exact_form,
    gain_balls,
    has_exact_form,
    tau_ratio,
)
from .exact_gains import gain_failure, gain_terms
from .feedback import feedback_factor
from .observer_proof import (
    proof_window,
    proven_collocated_failure,
    proven_collocated_products,
    proven_observer_failure,
    proven_observer_term,
    proven_response_failure,
    proven_response_product,
)
from .output_feedback import observer_term, output_feedback_factors
from .varying_form import DEFAULT_CHARACTERISTIC_GRID, VaryingDelayForm, varying_delay_form
from .varying_proof import VaryingProof, has_varying_proof, varying_proof

__all__ = [
    "Classification",
    "CollocatedOutputFeedback",
    "Controller",
    "FeedbackLaw",
    "FilteredController",
    "FiniteTimeController",
    "OpenLoop",
    "OutputFeedback",
    "ReflectionController",
    "StateFeedback",
    "characteristic",
    "classify",
    "collocated_observer_of",
    "collocated_responses_of",
    "observer_reflection_of",
    "loop_factors",
    "loop_route",
    "loop_scope",
    "normalize",
    "observer_of",
    "rounded_parts",
    "unfiltered",
]

Gain = Callable[[NDArray[np.float64]], NDArray[np.float64]]


def _zero_gain(xi: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.zeros_like(np.asarray(xi, dtype=float))


class Controller(ABC):
    """A boundary controller for :class:`~nrobust.hyperbolic.plants.hyperbolic2x2.Hyperbolic2x2`."""

    @abstractmethod
    def factors(
        self, phi: QuasiPolynomial, i_n: QuasiPolynomial, round_trip: QuasiPolynomial
    ) -> tuple[QuasiPolynomial, QuasiPolynomial]:
        """``(A, B)`` from ``Phi``, ``I_N`` and the round trip ``q e^{-tau s}`` (see the module table)."""

    @abstractmethod
    def feedback_law(self, system: Hyperbolic2x2, kernels: Any = None) -> FeedbackLaw:
        """The control law as gains on the state; ``kernels`` from ``solve_kernels``."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description: the class name under ``"controller"`` and the parameters."""
        return json_safe({"controller": type(self).__name__, **vars(self)})


def _kernel_gains(system: Hyperbolic2x2, kernels: Any, pairs: tuple[tuple[str, float], ...]) -> Gain:
    """``xi -> sum_k c_k kernel_k(1, xi)``; zero on an uncoupled system without kernels."""
    if kernels is None:
        if system.uncoupled:
            return _zero_gain
        raise ParameterError("kernels", "the result of solve_kernels(system) for a coupled system", None)

    def gain(xi: NDArray[np.float64]) -> NDArray[np.float64]:
        xi = np.asarray(xi, dtype=float)
        ones = np.ones_like(xi)
        return sum(c * getattr(kernels, name)(ones, xi) for name, c in pairs)

    return gain


@dataclass(frozen=True)
class OpenLoop(Controller):
    """No control, ``U = 0``."""

    def factors(self, phi, i_n, round_trip):
        return 1.0 - phi, phi * 0.0

    def feedback_law(self, system, kernels=None):
        return FeedbackLaw(0.0, _zero_gain, _zero_gain)


@dataclass(frozen=True)
class FiniteTimeController(Controller):
    """U_BS, eq. (47): cancels the proximal reflection; finite time for ``delta = 0``.

    ``U_BS = -rho u(t, 1) + int_0^1 K^{vu}(1, xi) u + K^{vv}(1, xi) v dxi``; on a transport
    system, ``U = -rho u(t, 1)`` (eq. (9)).
    """

    def factors(self, phi, i_n, round_trip):
        return 1.0 - phi, phi

    def feedback_law(self, system, kernels=None):
        return FeedbackLaw(
            -system.rho,
            _kernel_gains(system, kernels, (("Kvu", 1.0),)),
            _kernel_gains(system, kernels, (("Kvv", 1.0),)),
        )


@dataclass(frozen=True)
class ReflectionController(Controller):
    """U_BS2(K), eq. (53): keeps ``rho - K`` of the proximal reflection.

    ``U = -K u(1) - (rho - K) int K^{uu}(1,.) u + K^{uv}(1,.) v + int K^{vu}(1,.) u + K^{vv}(1,.) v``;
    the target system reflects ``(rho - K)`` at ``x = 1``, exponentially stable when
    ``|K| < (1 - |rho q|)/|q|`` (eq. (54)). On a transport system, ``U = -K u(t, 1)``
    (eq. (12)).

    Parameters
    ----------
    K : float
        The tuning gain trading decay rate for delay robustness.
    """

    K: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "K", finite_real("K", self.K))

    def factors(self, phi, i_n, round_trip):
        return 1.0 - phi, self.K * round_trip - i_n

    def feedback_law(self, system, kernels=None):
        r = system.rho - self.K
        return FeedbackLaw(
            -self.K,
            _kernel_gains(system, kernels, (("Kvu", 1.0), ("Kuu", -r))),
            _kernel_gains(system, kernels, (("Kvv", 1.0), ("Kuv", -r))),
        )


@dataclass(frozen=True)
class FilteredController(Controller):
    """U_BS, or U_BS2(K), passed through the proper filter ``(1 + a s)/(1 + b s)`` (section 2.3.2).

    On a transport system this is ``U_1(s) = -(1 + a s)/(1 + b s) rho u(1, s)`` (``K`` not
    given), or ``-(1 + a s)/(1 + b s) K u(1, s)``. The loop factors are those of the unfiltered
    law with ``A`` multiplied by ``1 + b s`` and ``B`` by ``1 + a s``; its difference operator
    ``1 - rho q e^{-tau s} + (a/b) K q e^{-(tau + delta) s}`` (``K = rho`` for U_BS) gives the
    condition ``|rho q| + |a/b| |K q| < 1`` for a positive delay margin.

    Parameters
    ----------
    a : float
        Filter zero coefficient.
    b : float
        Filter pole coefficient, ``b > 0``.
    K : float, optional
        The reflection gain of U_BS2(K), eq. (53), that is filtered; by default U_BS, eq. (47)
        (which is U_BS2(rho)). Like :class:`ReflectionController`, it needs a constant ``lam/mu``
        on a general plant (a normal-form quantity).
    """

    a: float
    b: float
    K: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "a", finite_real("a", self.a))
        object.__setattr__(self, "b", positive("b", self.b))
        if self.K is not None:
            object.__setattr__(self, "K", finite_real("K", self.K))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (``K`` only when given: U_BS filtered reads as before)."""
        data = super().to_dict()
        if self.K is None:
            del data["K"]
        return data

    def factors(self, phi, i_n, round_trip):
        b_factor = phi if self.K is None else self.K * round_trip - i_n
        return (1.0 - phi).times_poly([1.0, self.b]), b_factor.times_poly([1.0, self.a])

    def feedback_law(self, system, kernels=None):
        unfiltered = FiniteTimeController() if self.K is None else ReflectionController(self.K)
        law = unfiltered.feedback_law(system, kernels)
        return FeedbackLaw(law.boundary_gain, law.gain_u, law.gain_v, (self.a, self.b))


@dataclass(frozen=True)
class StateFeedback(Controller):
    """Any linear boundary state feedback ``U = k u(t, L) + int_0^L g_u u + g_v v dx``.

    The gains act on the state of the plant the controller is used with (on a
    :class:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2`, its physical coordinates on
    ``[0, L]``). Its loop factors are ``A = 1 - Phi`` and ``B = -P`` with ``P`` of
    :func:`~nrobust.hyperbolic.loops.feedback.feedback_factor` (the gains composed with the
    inverse kernels), so they need the plant: :func:`loop_factors` computes them. The
    proportional output feedback ``U = -K u(t, L)`` is ``StateFeedback(-K)``; U_BS and
    U_BS2(K) are the cases whose gains are the kernel traces of their ``feedback_law``.

    On a plant with constant coefficients the loop is exact (no kernel grid) when the gains
    can be evaluated in ball arithmetic: numbers, or callables built from arithmetic and numpy's
    elementary ufuncs (:mod:`~nrobust.hyperbolic.loops.exact_gains`); other callables take
    the kernel route (:func:`loop_route`).

    Parameters
    ----------
    k : float
        Gain on ``u(t, L)``.
    g_u, g_v : float or callable, default 0
        Gains of the integral term, numbers or callables on arrays of ``x``.
    """

    k: float
    g_u: Any = 0.0
    g_v: Any = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "k", finite_real("k", self.k))
        for name in ("g_u", "g_v"):
            value = getattr(self, name)
            if not callable(value):
                object.__setattr__(self, name, finite_real(name, value))

    def factors(self, phi, i_n, round_trip):
        raise ParameterError(
            "controller", "used through loop_factors(system, controller): a state feedback's B needs the plant", self
        )

    def feedback_law(self, system, kernels=None):
        def gain(value: Any) -> Gain:
            if callable(value):
                return value
            return lambda xi: np.full(np.shape(xi), float(value))

        return FeedbackLaw(self.k, gain(self.g_u), gain(self.g_v))

    def to_dict(self) -> dict[str, Any]:
        gains = {
            n: (getattr(self, n) if not callable(getattr(self, n)) else repr(getattr(self, n))) for n in ("g_u", "g_v")
        }
        return json_safe({"controller": "StateFeedback", "k": self.k, **gains})


@dataclass(frozen=True)
class _ObserverFeedback(Controller):
    """What :class:`OutputFeedback` and :class:`CollocatedOutputFeedback` share: a state feedback
    ``controller`` on an observer's estimate, whose commands the observer replays ``observer_delay`` late."""

    controller: Controller
    observer_delay: float = 0.0
    #: Why it is not a law on the state (the end of :meth:`feedback_law`'s message).
    _not_a_law = "analyse its loop with loop_factors"

    def __post_init__(self) -> None:
        if isinstance(self.controller, _ObserverFeedback) or not isinstance(self.controller, Controller):
            raise ParameterError(
                "controller",
                "a state feedback: OpenLoop, FiniteTimeController, ReflectionController, FilteredController or "
                "StateFeedback",
                self.controller,
            )
        object.__setattr__(self, "observer_delay", nonnegative("observer_delay", self.observer_delay))

    def factors(self, phi, i_n, round_trip):
        raise ParameterError(
            "controller", "used through loop_factors(system, controller): the observer needs the plant", self
        )

    def feedback_law(self, system, kernels=None):
        raise ParameterError(
            "controller",
            f"a state feedback ({type(self).__name__} is not a law on the state: {self._not_a_law})",
            self,
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description: the state feedback under ``"state_feedback"``."""
        return json_safe(
            {
                "controller": type(self).__name__,
                "state_feedback": self.controller.to_dict(),
                "observer_delay": self.observer_delay,
            }
        )


@dataclass(frozen=True)
class OutputFeedback(_ObserverFeedback):
    """A state feedback fed by the exact predictor of the state from ``y(t) = v(t, 0)``.

    The measurement is at the unactuated boundary; the observer predicts the output
    ``beta(., 1)`` of the delay form (39) on the last ``1/mu`` time units from ``y`` and the
    commands it sent (:mod:`~nrobust.hyperbolic.loops.output_feedback`), and ``controller``
    acts on the prediction. Without a delay the loop is the state feedback's; with a delay
    ``delta_a`` on the actuation and ``delta_m`` on the measurement, it depends on
    ``delta = delta_a + delta_m`` only, and keeps the difference operator (hence the strong
    stability, Theorem 4) of ``controller``. The collocated measurement ``u(t, 1)``:
    :class:`CollocatedOutputFeedback`.

    Parameters
    ----------
    controller : Controller
        The state feedback (any controller of the package but another output feedback).
    observer_delay : float, default 0
        The actuation delay ``delta_o`` the observer assumes (the delay of the commands it
        replays): at ``delta = delta_o`` the loop is the state feedback's with that delay.
    """

    _not_a_law = "simulate its controller, or analyse its loop with loop_factors"


@dataclass(frozen=True)
class CollocatedOutputFeedback(_ObserverFeedback):
    """A state feedback fed by the collocated observer from ``y(t) = u(t, 1)``.

    The measurement is at the actuated boundary; the observer is the backstepping observer of
    Vazquez, Krstic and Coron (output injection ``p_u(x), p_v(x)`` times ``y - u^(t, 1)``,
    ``v^(t, 1) = rho y + U``), whose error is zero after ``tau``
    (:mod:`~nrobust.hyperbolic.loops.collocated`), and ``controller`` acts on its estimate.
    Without a delay the loop is the state feedback's; with ``delta_a`` on the actuation and
    ``delta_m`` on the measurement it depends on ``delta = delta_a + delta_m`` only. Its
    difference operator is not the state feedback's: for U_BS2(K) and ``observer_delay = 0``,
    ``1 - (rho - K) q e^{-tau s} - K rho q^2 e^{-2 tau s} + K rho q^2 e^{-(2 tau + delta) s}``,
    strongly stable iff ``|rho - K| |q| + 2 |K rho| q^2 < 1`` (with ``observer_delay > 0``:
    ``|rho q| + |K q| + 2 |K rho| q^2 < 1``). On
    :class:`~nrobust.hyperbolic.plants.hyperbolic2x2.Hyperbolic2x2` plants (a general plant with a
    constant ``lam/mu`` through its normal form); for U_BS2(K) the loop is affine in ``K`` in both
    factors (the observer's term, in ``A``, depends on the law), and
    :func:`~nrobust.hyperbolic.analyses.design.design_reflection` with ``collocated=True`` designs it.
    Under ``StateFeedback(k)`` (no integral gains) on a plant with constant couplings the observer's
    responses are closed forms and the loop is proven for the PDE (:func:`loop_route` ``"exact"``); a law
    with an integral part takes them from the dual plant's kernels (a model).

    The observer may keep a reflection ``kappa`` of its own (``observer_reflection``):
    ``v^(t, 1) = (rho - kappa) y + kappa u^(t, 1) + U_o``, so that its error reflects
    ``v~(t, 1) = kappa u~(t, 1)`` and is no longer zero after ``tau``: its characteristic function
    is ``E = 1 - kappa H_y`` (principal part ``1 - kappa q e^{-tau s}``), a factor of the loop,
    which is affine in ``kappa`` (:mod:`~nrobust.hyperbolic.loops.collocated`). For U_BS2(K) and
    ``observer_delay = 0`` the difference operator is ``1 - (rho - K + kappa) q e^{-tau s} +
    (kappa - K) rho q^2 e^{-2 tau s} + K (rho - kappa) q^2 e^{-(2 tau + delta) s}``;
    :func:`~nrobust.hyperbolic.analyses.observer_design.design_collocated_observer` designs ``kappa``.

    Parameters
    ----------
    controller : Controller
        The state feedback (any controller of the package but an output feedback).
    observer_delay : float, default 0
        The delay ``delta_o`` of the commands the observer replays: at ``delta = delta_o`` the
        loop is the state feedback's with that delay.
    observer_reflection : float, default 0
        ``kappa``, the reflection the observer keeps at ``x = 1`` (read on the normal form of a
        general plant, as ``K``); 0 reads it all from the measurement (a nilpotent error).
    """

    observer_reflection: float = 0.0
    _not_a_law = "analyse its loop with loop_factors"

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "observer_reflection", finite_real("observer_reflection", self.observer_reflection))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (``observer_reflection`` when it is not 0)."""
        out = super().to_dict()
        if self.observer_reflection != 0.0:
            out["observer_reflection"] = self.observer_reflection
        return out


def normalize(system: Any, controller: Any) -> tuple[Any, Any]:
    """The plant as the paper's plant and the controller acting on it.

    A :class:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2` is replaced by its normal
    form; a :class:`StateFeedback` on it, alone or inside an :class:`OutputFeedback` or a
    :class:`CollocatedOutputFeedback`, gets its gains mapped to the normal coordinates
    (:meth:`~nrobust.hyperbolic.plants.general.NormalForm.feedback_to_normal`). The paper's
    controllers are defined on the normal form and pass unchanged: the ``K`` of
    :class:`ReflectionController` (and of a :class:`FilteredController`) is read in the normal
    form's coordinates, not the plant's; its gain on the physical ``u(t, L)`` is
    ``-K e^{D(L) - A(L) - k_b}`` (``k_b`` = :attr:`~nrobust.hyperbolic.plants.general.NormalForm.balance`),
    plus the kernel terms of eq. (53). The characteristic
    function changes by the constant factor ``e^{D(L)}`` only, so spectra and margins are
    those of the general plant. A general plant with a varying ``lam/mu`` has no normal form
    and passes unchanged with its controller: its loop is proven (:func:`loop_route` ``"exact"``) or
    taken by the characteristic route
    (:func:`~nrobust.hyperbolic.loops.varying_form.varying_delay_form`). Any other plant (and
    its controller) passes unchanged.
    """
    if isinstance(system, GeneralHyperbolic2x2) and system.constant_ratio:
        form = system.normal_form()
        if isinstance(controller, StateFeedback):
            controller = StateFeedback(*form.feedback_to_normal(controller.k, controller.g_u, controller.g_v))
        if isinstance(controller, _ObserverFeedback) and isinstance(controller.controller, StateFeedback):
            inner = controller.controller
            mapped = StateFeedback(*form.feedback_to_normal(inner.k, inner.g_u, inner.g_v))
            controller = dataclasses.replace(controller, controller=mapped)
        return form.system, controller
    return system, controller


def _check(system: Any, controller: Any) -> None:
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2, TransportSystem or GeneralHyperbolic2x2", system)
    _check_controller(controller)


def _check_controller(controller: Any) -> None:
    if not isinstance(controller, Controller):
        raise ParameterError(
            "controller",
            "OpenLoop, FiniteTimeController, ReflectionController, FilteredController, StateFeedback, OutputFeedback "
            "or CollocatedOutputFeedback",
            controller,
        )


@lru_cache(maxsize=32)
def _distributed_part(system: Hyperbolic2x2, kernel_grid: int) -> QuasiPolynomial:
    """``I_N(s) = int_0^tau N~(nu) e^{-nu s} dnu`` (zero on an uncoupled system)."""
    if system.uncoupled:
        return QuasiPolynomial([[0.0]], [0.0])
    return QuasiPolynomial([], [], [delay_form(system, kernels=_kernels(system, kernel_grid)).N_tilde])


def _varying_factors(
    system: GeneralHyperbolic2x2, controller: Controller, kernel_grid: int
) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``(A, B)`` of a plant with a varying speed ratio, from its characteristic delay form.

    ``Phi = rho_q e^{-tau s} - I_N`` as for the paper's plant; a proportional feedback
    ``StateFeedback(k)`` takes ``B`` from the same route, a state feedback with integral gains
    from the kernels with varying speeds
    (:meth:`~nrobust.hyperbolic.kernels.varying.VaryingKernels.feedback_factor`, on
    ``kernel_grid`` points). U_BS2(K), whose ``K q`` is a normal-form quantity, is refused.
    """
    _check_controller(controller)
    form = cached_varying_delay_form(system, 2 * (kernel_grid - 1))  # N~ on kernel_grid nodes
    i_n = QuasiPolynomial([], [], form.characteristic.distributed)
    phi = QuasiPolynomial([[form.rho_q]], [form.tau]) - i_n
    if isinstance(controller, StateFeedback):
        if _integral_gains(controller):
            kernels = _varying_kernels(system, check_kernel_grid(kernel_grid))
            return 1.0 - phi, -kernels.feedback_factor(controller.k, controller.g_u, controller.g_v)
        return 1.0 - phi, form.u_factor() * (-controller.k)
    if _needs_normal_form(controller):
        raise ParameterError(
            "controller",
            "OpenLoop, FiniteTimeController, FilteredController(a, b) or StateFeedback on a plant with a varying "
            "lam/mu (U_BS2(K) is defined on the normal form, which needs a constant lam/mu)",
            controller,
        )
    return controller.factors(phi, i_n, QuasiPolynomial([[0.0]], [0.0]))


@lru_cache(maxsize=8)
def _varying_kernels(system: GeneralHyperbolic2x2, kernel_grid: int) -> VaryingKernels:
    """The kernels with varying speeds of a plant with a varying speed ratio (cached)."""
    return solve_varying_kernels(system, kernel_grid)


@lru_cache(maxsize=8)
def cached_varying_delay_form(
    system: GeneralHyperbolic2x2, steps: int = DEFAULT_CHARACTERISTIC_GRID
) -> VaryingDelayForm:
    """The characteristic delay form of a plant with a varying speed ratio on ``steps`` steps (cached)."""
    return varying_delay_form(system, steps)


def _state_feedback_factor(system: Hyperbolic2x2, controller: StateFeedback, kernel_grid: int) -> QuasiPolynomial:
    """``P`` of a state feedback, on the kernels the delay form of ``system`` was built from."""
    kernels = None if system.uncoupled else _kernels(system, kernel_grid)
    return feedback_factor(system, controller.k, controller.g_u, controller.g_v, kernel_grid, kernels)


@lru_cache(maxsize=8)
def _kernels(system: Hyperbolic2x2, kernel_grid: int) -> Kernels:
    """The kernels of ``system`` (shared by ``N~`` and the feedback factor of a state feedback)."""
    return solve_kernels(system, kernel_grid)


def _integral_gains(controller: StateFeedback) -> bool:
    """True when the state feedback has an integral term (a callable or a nonzero gain)."""
    return any(callable(g) or g != 0.0 for g in (controller.g_u, controller.g_v))


def loop_route(system: Any, controller: Any, kernel_grid: int | None = None) -> str:
    """How :func:`loop_factors` builds the loop: ``"exact"`` or ``"kernels"``.

    ``"exact"``: constant coefficients, ``kernel_grid`` not given, and a controller whose
    gains are the paper's or a :class:`StateFeedback` whose integral gains (if any) can be
    evaluated in ball arithmetic (:func:`~nrobust.hyperbolic.loops.exact_gains.gain_failure`
    is None): ``N~`` in closed form and the gains' kernel with proven error bounds
    (:func:`~nrobust.hyperbolic.loops.exact_form.exact_form`,
    :func:`~nrobust.hyperbolic.loops.exact_gains.gain_terms`), so a proof about the loop is
    a proof about the PDE; also a :class:`~nrobust.hyperbolic.plants.hyperbolic2x2.Hyperbolic2x2`
    whose couplings, or a :class:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2` whose
    coefficients or speeds, are functions of ``x`` with a proven ``N~`` and ``U~``
    (:func:`~nrobust.hyperbolic.loops.varying_proof.varying_proof`) under a controller other than
    a state feedback with integral gains (nor U_BS2(K) on a varying ``lam/mu``). ``"kernels"``: ``N~``
    (and the gains of a state feedback) from
    kernels on a grid, a model of the plant whose distance to it is measured by convergence
    studies. An :class:`OutputFeedback` whose state feedback takes the exact route is ``"exact"``
    too when its observer term is exact (uncoupled plant) or enclosed with a proven error
    (:func:`~nrobust.hyperbolic.loops.observer_proof.proven_observer_term`: constant coefficients, a law
    reading ``N~`` or ``U~`` on the window, and a state feedback's integral gains there with one Taylor model
    each, :func:`~nrobust.hyperbolic.loops.exact_gains.window_series`). A :class:`CollocatedOutputFeedback` is
    ``"exact"`` on an uncoupled plant, and on a coupled one with constant couplings under ``StateFeedback(k)`` without
    integral gains (its observer's responses ``C_u = k u_factor``, ``H_y = u_factor`` in closed form, their
    products enclosed in ball arithmetic:
    :func:`~nrobust.hyperbolic.loops.observer_proof.proven_collocated_products`) or under U_BS2(K) and U_BS
    without an observer delay (``C_u`` from the kernels' proven Taylor enclosures:
    :func:`~nrobust.hyperbolic.loops.observer_proof.proven_response_product`). ``"observer"``: an output
    feedback whose state feedback takes the exact route and whose observer term is computed in floating
    point with an estimated error (:mod:`~nrobust.hyperbolic.loops.output_feedback`,
    :mod:`~nrobust.hyperbolic.loops.collocated`), so the loop is a model.
    """
    if isinstance(controller, OutputFeedback):
        inner = loop_route(system, controller.controller, kernel_grid)
        if inner != "exact" or _uncoupled(system) or _proven_observer(system, controller):
            return inner
        return "observer"
    if isinstance(controller, CollocatedOutputFeedback):
        inner = loop_route(system, controller.controller, kernel_grid)
        closed = _exact_collocated(system, controller) or _proven_collocated(system, controller)
        return "observer" if inner == "exact" and not closed else inner
    if kernel_grid is None and _proven_varying(system, controller):
        return "exact"
    if kernel_grid is not None or not has_exact_form(system):
        return "kernels"
    if isinstance(controller, StateFeedback) and _integral_gains(controller):
        return "kernels" if gain_failure(system, controller.g_u, controller.g_v) is not None else "exact"
    return "exact"


def _proven_varying(system: Any, controller: Any) -> bool:
    """True for couplings that vary with ``x`` whose ``N~`` (and ``U~``) are proven, and a controller using only them.

    :func:`~nrobust.hyperbolic.loops.varying_proof.varying_proof`: the paper's controllers and
    a :class:`StateFeedback` without integral gains; on a general plant with a varying ``lam/mu`` not
    U_BS2(K) (defined on the normal form, refused there by :func:`loop_factors`).
    """
    if isinstance(controller, StateFeedback) and _integral_gains(controller):
        return False
    if isinstance(system, GeneralHyperbolic2x2) and not system.constant_ratio and _needs_normal_form(controller):
        return False
    return has_varying_proof(system)


def _needs_normal_form(controller: Any) -> bool:
    """True for U_BS2(K) and a filtered law with ``K``: their ``K q`` is a quantity of the normal form."""
    return isinstance(controller, ReflectionController) or (
        isinstance(controller, FilteredController) and controller.K is not None
    )


def _exact_collocated(system: Any, controller: CollocatedOutputFeedback) -> bool:
    """True when the collocated observer's term is exact: an uncoupled plant and a law without integral gains."""
    inner = controller.controller
    return _uncoupled(system) and not (isinstance(inner, StateFeedback) and _integral_gains(inner))


def _proven_collocated(system: Any, controller: CollocatedOutputFeedback) -> bool:
    """True when the collocated observer's terms on a coupled plant are enclosed in ball arithmetic.

    A :class:`~nrobust.hyperbolic.plants.hyperbolic2x2.Hyperbolic2x2` with constant couplings under
    ``StateFeedback(k)`` without integral gains: ``C_u = k u_factor`` and ``H_y = u_factor``
    (:mod:`~nrobust.hyperbolic.loops.collocated`), the loop made of ``(1 - Phi) u_factor`` and ``u_factor^2``
    (:func:`~nrobust.hyperbolic.loops.observer_proof.proven_collocated_products`); under U_BS2(K) or U_BS
    (unfiltered, no observer delay) ``G`` from the kernels' proven enclosures (:func:`_proven_response`), the
    reflection's terms from ``u_factor`` and ``(1 - Phi) u_factor`` (:func:`observer_reflection_of`).
    """
    inner = controller.controller
    if isinstance(inner, (FiniteTimeController, ReflectionController)):
        return _proven_response(system, controller) is not None
    return _proven_law(system, inner)


def _proven_response(system: Any, controller: CollocatedOutputFeedback) -> float | None:
    """``K`` of U_BS2(K) (``rho`` for U_BS) when the collocated observer's ``G = (1 - Phi) C_u`` is enclosed with a
    proven error (:func:`~nrobust.hyperbolic.loops.observer_proof.proven_response_product`: a coupled
    :class:`~nrobust.hyperbolic.plants.hyperbolic2x2.Hyperbolic2x2` with constant couplings, the observer replaying
    the commands undelayed); None otherwise."""
    inner = controller.controller
    if controller.observer_delay != 0.0 or _uncoupled(system):
        return None
    if isinstance(inner, ReflectionController):
        K = float(inner.K)
    elif isinstance(inner, FiniteTimeController):
        K = float(system.rho)
    else:
        return None
    return K if proven_response_failure(system, K) is None else None


def _proven_law(system: Any, law: Controller) -> bool:
    """:func:`_proven_collocated` for the state feedback ``law``."""
    if _uncoupled(system) or not isinstance(law, StateFeedback) or _integral_gains(law):
        return False
    return proven_collocated_failure(system) is None


def _scaled_collocated(system: Any, controller: CollocatedOutputFeedback) -> bool:
    """True when the collocated loop is, in ``r s``, the loop as built with its constants scaled (module notes of
    :mod:`~nrobust.hyperbolic.loops.given_plant`): its observer exact or proven and no observer delay.

    ``G = (1 - Phi) C_u`` and the reflection's factor ``E = 1 - kappa H_y`` are then functions of ``tau s``
    (their point coefficients enclosed from the user's numbers, :func:`_collocated_points`; the kernels of a
    proven observer's products built with ``tau_d`` and ``p``, ``m`` exact, as ``N~``); a delay ``delta_o``
    would be ``delta_o / r`` in the loop as built (not a double).
    """
    closed = _exact_collocated(system, controller) or _proven_collocated(system, controller)
    return closed and controller.observer_delay == 0.0


def _window_law(law: Controller) -> tuple[str, float] | None:
    """The unfiltered ``law``'s kernel on the measurement's window, for
    :func:`~nrobust.hyperbolic.loops.observer_proof.proven_observer_term`: ``("N", 1)`` for ``m = N~``
    (U_BS, U_BS2(K)), ``("U", k)`` for ``m = k U~`` (``StateFeedback(k, g_u, g_v)``, its integral gains'
    kernel added by :func:`_window_gains`); None otherwise."""
    if isinstance(law, (FiniteTimeController, ReflectionController)):
        return ("N", 1.0)
    if isinstance(law, StateFeedback):
        return ("U", float(law.k))
    return None


def _window_gains(law: Controller) -> tuple[Any, Any]:
    """The integral gains ``(g_u, g_v)`` of the unfiltered ``law`` (zeros for a law without them)."""
    if isinstance(law, StateFeedback):
        return (law.g_u, law.g_v)
    return (0.0, 0.0)


def _proven_observer(system: Any, controller: OutputFeedback) -> bool:
    """True when the observer term of ``controller`` on ``system`` is enclosed with a proven error (not on an
    uncoupled plant, where the observer needs no term)."""
    if _uncoupled(system):
        return False
    law = unfiltered(controller.controller)
    return proven_observer_failure(system, _window_law(law), _window_gains(law)) is None


def _uncoupled(system: Any) -> bool:
    """True for a plant whose ``N~`` is zero by construction (no in-domain coupling)."""
    return bool(getattr(system, "uncoupled", False))


def loop_scope(
    system: Any,
    controller: Any,
    kernel_grid: int | None,
    factors: tuple[QuasiPolynomial, QuasiPolynomial],
    mapped: bool = True,
    normal_form: bool = False,
) -> str:
    """What a proof about the loop ``factors`` of ``system`` is about, in one line.

    Parameters
    ----------
    system, controller, kernel_grid
        As given to :func:`loop_factors`.
    factors : tuple of QuasiPolynomial
        Its result ``(A, B)``.
    mapped : bool, default True
        Whether the proofs were mapped to the exact ``tau``
        (:func:`~nrobust.hyperbolic.loops.given_plant.to_given_plant`). False for proofs about the
        loop as built (a design's certificate): where ``tau`` is not a double, the scope then says
        that they hold with ``tau`` rounded.
    normal_form : bool, default False
        True when ``system`` is the normal form of the user's general plant
        (:meth:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2.normal_form`, computed in
        floating point): the proofs are about that normal form as given, which the scope says.
    """
    scope = _loop_scope(system, controller, kernel_grid, factors)
    unmapped = not mapped and _AS_GIVEN in scope and tau_ratio(system) != 1
    if not (unmapped or normal_form) or _AS_GIVEN not in scope:
        return scope
    if not unmapped:  # the normal form's numbers taken as given
        return scope.replace(_AS_GIVEN, _NORMAL_FORM + " taken as given" + _AS_GIVEN.removeprefix("the plant as given"))
    return scope.replace(
        _AS_GIVEN,
        f"{_NORMAL_FORM if normal_form else 'the plant'} with {_rounded_tau(system)} (the proofs are about the loop as "
        "built, not mapped to the exact tau), its other numbers exact and the principal gains enclosed with the "
        "proven radii of their rounding",
    )


def _loop_scope(
    system: Any, controller: Any, kernel_grid: int | None, factors: tuple[QuasiPolynomial, QuasiPolynomial]
) -> str:
    """:func:`loop_scope` of proofs mapped to the exact ``tau`` where the map applies."""
    if isinstance(controller, (OutputFeedback, CollocatedOutputFeedback)):  # its law's scope, with its own numbers
        scope = (
            _output_feedback_scope(system, controller, kernel_grid, factors)
            if isinstance(controller, OutputFeedback)
            else _collocated_scope(system, controller, kernel_grid)
        )
        rounded = rounded_parts(system, controller, kernel_grid)
        return scope.replace(_AS_GIVEN, rounded) if rounded else scope
    if loop_route(system, controller, kernel_grid) == "exact" and not has_exact_form(system):
        radius = max((d.radius for f in factors for d in f.distributed), default=0.0)
        return (
            "the PDE itself (N~ from the Volterra form of the kernel equations with the couplings as Taylor "
            f"models, a proven a-posteriori bound {radius:.1e} that every enclosure includes; the principal gains "
            f"enclosed with the proven radii of their computation; {rounded_parts(system, controller, kernel_grid)})"
        )
    if loop_route(system, controller, kernel_grid) == "exact":
        gains = isinstance(controller, StateFeedback) and _integral_gains(controller)
        # the terms holding the jump of the gains' kernel: their radius is that jump, not an accuracy
        moved = {(d.a, d.b) for d in gain_terms(system, controller.g_u, controller.g_v)[1:]} if gains else set()
        radius = max((d.radius for f in factors for d in f.distributed if (d.a, d.b) not in moved), default=0.0)
        kernel = (
            f"N~ in closed form, stored within a proven {radius:.1e} that every enclosure includes"
            if radius
            else "N~ = 0 exactly (uncoupled plant: no kernel)"
        )
        if gains:
            kernel += "; the integral gains as Taylor models in ball arithmetic" + (
                ", the jump of their kernel at t_v (not a double) held by a proven term on the ulp(tau) next to it"
                if moved
                else ""
            )
        return f"the PDE itself ({kernel}; {_given(system, controller, kernel_grid)})"
    samples = _samples(system)
    if isinstance(system, GeneralHyperbolic2x2) and not system.constant_ratio:
        return (
            "a model of the PDE: N~ the cubic spline of the characteristic route (varying lam/mu); its distance "
            f"to the PDE is not part of the proof{samples}"
        )
    grid = DEFAULT_KERNEL_GRID if kernel_grid is None else kernel_grid
    if kernel_grid is None and isinstance(controller, StateFeedback) and has_exact_form(system):
        reason = gain_failure(system, controller.g_u, controller.g_v)
        return (
            f"a model of the PDE: the integral gains have no exact loop ({reason}), so N~ and the gains come from "
            f"the kernels on {grid} points; its distance to the PDE is not part of the proof{samples}"
        )
    if isinstance(system, Hyperbolic2x2) and system.uncoupled:
        return f"the PDE itself (uncoupled: N~ = 0; {_given(system, controller, kernel_grid)})"
    return (
        f"a model of the PDE: N~ the cubic spline of the kernels on {grid} points; its distance to the PDE is "
        f"not part of the proof (a convergence study estimates it){samples}"
    )


def _samples(system: Any) -> str:
    """:func:`loop_scope`'s words for coefficients of a general plant given as samples (``""`` when none is): the
    cubic spline through them is the user's model of the plant, and what any proof is about."""
    if not isinstance(system, GeneralHyperbolic2x2):
        return ""
    names = [name for name in ("lam", "mu", "a", "b", "c", "d") if isinstance(getattr(system, name), tuple)]
    if not names:
        return ""
    return f"; {', '.join(names)} given as samples: the cubic spline through them is the plant's model"


def _given(system: Any, controller: Any, kernel_grid: int | None) -> str:
    """The part of :func:`loop_scope` on the plant's numbers: exact, or what is rounded."""
    rounded = rounded_parts(system, controller, kernel_grid)
    if rounded:
        return rounded
    return _AS_GIVEN


#: :func:`loop_scope`'s words for the normal form of a general plant, in place of "the plant as given".
_NORMAL_FORM = (
    "the plant's normal form as computed in floating point (its lam, mu, q, rho within a few ulps of the plant's)"
)

#: :func:`loop_scope`'s words for a loop whose proofs map to the plant as given (``given_plant_scale``).
_AS_GIVEN = (
    "the plant as given: its numbers exact, tau mapped to its exact value (given_plant_scale) and the principal "
    "gains enclosed with the proven radii of their rounding"
)


def _output_feedback_scope(
    system: Any, controller: OutputFeedback, kernel_grid: int | None, factors: tuple[QuasiPolynomial, QuasiPolynomial]
) -> str:
    """:func:`loop_scope` of an output feedback: the state feedback's, and the observer term's accuracy (a proven
    radius on the exact route, where the proofs are about the PDE; an estimate otherwise, a model)."""
    term, grid = _observer(system, controller, kernel_grid)
    inner = loop_scope(system, controller.controller, grid, loop_factors(system, controller.controller, grid))
    if term is None:
        return inner + "; the observer is exact (N~ = 0: the measurement gives every value the law uses)"
    if grid is None and _proven_observer(system, controller):
        radius = max((d.radius for d in loop_factors(system, OpenLoop(), None)[0].distributed), default=0.0)
        return (
            f"the PDE itself (N~ in closed form within a proven {upper_bound_text(radius, 2)}"
            f"{_gains_scope(system, controller.controller)}; the observer's term "
            f"(1 - Phi) H enclosed in ball arithmetic within a proven {upper_bound_text(term.accuracy, 2)}"
            f"{_LAST_ULP if len(term.product.distributed) > 3 else ''}, which every enclosure includes; "
            f"{_given(system, controller, kernel_grid)})"
        )
    observer = (
        f"the observer's term (1 - Phi) H computed in floating point to an estimated {term.accuracy:.0e}, "
        "which is not part of the proof"
    )
    if loop_route(system, controller, kernel_grid) == "observer":
        radius = max((d.radius for d in loop_factors(system, OpenLoop(), None)[0].distributed), default=0.0)
        return f"a model of the PDE: N~ in closed form within a proven {radius:.1e}, and {observer}"
    return f"{inner}; {observer}"


def _gains_scope(system: Any, law: Controller) -> str:
    """:func:`_output_feedback_scope`'s words on a state feedback's integral gains (``""`` without them)."""
    if not (isinstance(law, StateFeedback) and _integral_gains(law)):
        return ""
    terms = gain_terms(system, law.g_u, law.g_v)
    if not terms:
        return ""
    moved = ", its jump at t_v (not a double) held by a proven term on the ulp(tau) next to it"
    return (
        "; the integral gains as Taylor models in ball arithmetic, their kernel within a proven "
        f"{upper_bound_text(terms[0].radius, 2)}{moved if len(terms) > 1 else ''} and on the observer's window one "
        "polynomial with proven tails"
    )


#: :func:`_output_feedback_scope`'s words for the term on the ulp past ``tau + w`` (not a double) of a proven ``G``.
_LAST_ULP = (
    " on [0, tau + w] but the ulp past its double, where a term zero within the proven bound of the kernel's value "
    "holds it"
)


#: :func:`_collocated_scope`'s words for the terms on the ulps around the ends of a proven ``G``'s pieces that are
#: not doubles (:func:`~nrobust.hyperbolic.loops.observer_proof.proven_response_product`).
_MOVED_ENDS = (
    " but on the ulps around the ends of its pieces that are not doubles (t_u, t_v of the loop as built and them plus "
    "tau), where terms zero within the proven bound of the kernel's jump hold it"
)


def _collocated_scope(system: Any, controller: CollocatedOutputFeedback, kernel_grid: int | None) -> str:
    """:func:`loop_scope` of a collocated output feedback: the state feedback's, and the observer's."""
    grid = _observer_grid(system, controller, kernel_grid)
    inner = loop_scope(system, controller.controller, grid, loop_factors(system, controller.controller, grid))
    kappa = controller.observer_reflection
    if _exact_collocated(system, controller):
        exact = "; the collocated observer is exact (uncoupled plant: C_u = k q e^{-tau s}"
        return inner + exact + (", and its reflection's factor 1 - kappa q e^{-tau s})" if kappa else ")")
    if grid is None and _proven_response(system, controller) is not None:
        K = _proven_response(system, controller)
        assert K is not None
        kernel, *moved = proven_response_product(system, K).distributed
        radius = kernel.radius
        if kappa:
            radius = max(radius, observer_reflection_of(system, controller, kernel_grid).accuracy)
        law = loop_factors(system, controller.controller, None)
        closed = max((d.radius for f in law for d in f.distributed), default=0.0)
        reflection = " and the reflection's H_y = u_factor in closed form" if kappa else ""
        return (
            f"the PDE itself (N~ in closed form within a proven {upper_bound_text(closed, 2)}; the collocated "
            "observer's command response C_u from the plant's and the dual plant's kernels as Taylor polynomials "
            f"with proven remainders{reflection}, their products with 1 - Phi{' and B~' if kappa else ''} enclosed "
            f"in ball arithmetic within a proven {upper_bound_text(radius, 2)}{_MOVED_ENDS if moved else ''}, which "
            f"every enclosure includes; {_given(system, controller, kernel_grid)})"
        )
    if grid is None and _proven_collocated(system, controller):
        products = proven_collocated_products(system)
        terms = products.open_loop_product.distributed + (products.square.distributed if kappa else ())
        radius = max(d.radius for d in terms)
        law = loop_factors(system, controller.controller, None)
        closed = max((d.radius for f in law for d in f.distributed), default=0.0)
        return (
            f"the PDE itself (N~ and U~ in closed form within a proven {upper_bound_text(closed, 2)}; the "
            "collocated observer's responses in closed form, "
            f"C_u = k u_factor{' and H_y = u_factor' if kappa else ''}, their products with 1 - Phi"
            f"{' and u_factor' if kappa else ''} enclosed in ball arithmetic within a proven "
            f"{upper_bound_text(radius, 2)}, which every enclosure includes; {_given(system, controller, kernel_grid)})"
        )
    observer = collocated_observer_of(system, controller, kernel_grid)
    accuracy = observer.accuracy
    reflection = ""
    if kappa:
        accuracy = max(accuracy, abs(kappa) * observer_reflection_of(system, controller, kernel_grid).accuracy)
        reflection = " and the observer's reflection factor 1 - kappa H_y come"
    return (
        f"a model of the PDE: the state feedback's loop is {inner}; the collocated observer's term (1 - Phi) C_u"
        f"{reflection or ' comes'} from the kernels of the dual plant on {_collocated_grid(grid)} points, to an "
        f"estimated {accuracy:.0e}, which is not part of the proof"
    )


def _collocated_grid(grid: int | None) -> int:
    """The kernel grid of the collocated observer (the default grid on the exact route)."""
    return DEFAULT_KERNEL_GRID if grid is None else grid


def _observer_grid(
    system: Any, controller: OutputFeedback | CollocatedOutputFeedback, kernel_grid: int | None
) -> int | None:
    """The kernel grid of the state feedback's route (None: the exact route)."""
    if loop_route(system, controller.controller, kernel_grid) == "exact":
        return None
    return DEFAULT_KERNEL_GRID if kernel_grid is None else kernel_grid


def unfiltered(controller: Controller) -> Controller:
    """The law of a :class:`FilteredController` without its filter (any other controller itself)."""
    if isinstance(controller, FilteredController):
        return FiniteTimeController() if controller.K is None else ReflectionController(controller.K)
    return controller


def observer_of(system: Any, controller: OutputFeedback, kernel_grid: int | None = None) -> Any:
    """The observer term ``G`` of an output feedback on ``system`` (None if ``G = 0``).

    A ``ProvenObserverTerm`` where its error is proven (constant coefficients on the exact route,
    :func:`~nrobust.hyperbolic.loops.observer_proof.proven_observer_term`): its ``accuracy`` is a
    proven sup-norm bound of the error of ``G``'s kernel; otherwise a ``ResolventProduct`` whose
    ``accuracy`` is the estimated sup-norm error
    (:func:`~nrobust.hyperbolic.loops.output_feedback.observer_term`).
    """
    return _observer(system, controller, kernel_grid)[0]


def collocated_observer_of(
    system: Any, controller: CollocatedOutputFeedback, kernel_grid: int | None = None
) -> CollocatedObserver:
    """The collocated observer of ``controller`` on ``system``: its gains, ``C_u`` and ``G``.

    Its ``accuracy`` is the estimated sup-norm error of ``G``'s kernel
    (:func:`~nrobust.hyperbolic.loops.collocated.collocated_observer`).
    """
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem for a CollocatedOutputFeedback", system)
    return _collocated(system, controller.controller, _observer_grid(system, controller, kernel_grid))


@lru_cache(maxsize=16)
def _collocated(system: Hyperbolic2x2, inner: Controller, route_grid: int | None) -> CollocatedObserver:
    """The collocated observer for the law of ``inner`` (cached: the scope and the loop ask for it).

    ``route_grid``: the kernel grid of the state feedback's route (None: the exact route, whose
    ``1 - Phi`` is used, the observer's kernels on the default grid).
    """
    open_loop = loop_factors(system, OpenLoop(), route_grid)[0]
    return collocated_observer(system, _law_on(system, inner), open_loop, _collocated_grid(route_grid))


def _law_on(system: Hyperbolic2x2, inner: Controller) -> Callable[[int], FeedbackLaw]:
    """``grid -> FeedbackLaw``: the unfiltered law of ``inner``, its gains from kernels on ``grid`` points."""
    law = unfiltered(inner)
    return lambda n: _law(system, law, n)


@lru_cache(maxsize=32)
def _law(system: Hyperbolic2x2, law: Controller, n: int) -> FeedbackLaw:
    """The unfiltered ``law``'s gains from kernels on ``n`` points (cached: one object per law and grid, so that
    the observer's responses to it, cached by law, are computed once)."""
    if isinstance(law, StateFeedback) or system.uncoupled:
        return law.feedback_law(system)
    return law.feedback_law(system, _kernels(system, n))


def collocated_responses_of(
    system: Any, controller: CollocatedOutputFeedback, observer_grid: int
) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``(C_u, H_y)`` of ``controller``'s collocated observer with the dual plant's kernels on ``observer_grid`` points.

    :func:`~nrobust.hyperbolic.loops.collocated.collocated_responses`: the observer's responses
    alone (on the default grid they are ``collocated_observer_of(...).response`` and
    ``observer_reflection_of(...).response``), for a convergence study in the observer's grid.
    """
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem for a CollocatedOutputFeedback", system)
    grid = check_kernel_grid(observer_grid)
    return collocated_responses(system, _law_on(system, controller.controller)(grid), grid)


def _collocated_loop(
    system: Any, controller: CollocatedOutputFeedback, kernel_grid: int | None
) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``(A_o, B_o)`` of a collocated output feedback (:mod:`~nrobust.hyperbolic.loops.collocated`)."""
    grid = _observer_grid(system, controller, kernel_grid)
    inner = controller.controller
    A, B = loop_factors(system, inner, grid)
    numerator = (1.0, inner.a) if isinstance(inner, FilteredController) else (1.0,)
    if _exact_collocated(system, controller):
        k = unfiltered(inner).feedback_law(system).boundary_gain
        open_loop = loop_factors(system, OpenLoop(), grid)[0]
        G = open_loop * QuasiPolynomial([[k * system.q]], [system.tau])
    elif grid is None and _proven_collocated(system, controller):
        K = _proven_response(system, controller)
        if K is not None:  # C_u from the kernels' proven enclosures (module notes of collocated_proof)
            G = proven_response_product(system, K)
        else:  # C_u = k u_factor (module notes of collocated)
            assert isinstance(inner, StateFeedback)
            G = proven_collocated_products(system).open_loop_product * float(inner.k)
    else:
        G = collocated_observer_of(system, controller, kernel_grid).product
    if controller.observer_reflection != 0.0:
        denominator = (1.0, inner.b) if isinstance(inner, FilteredController) else (1.0,)
        reflection = observer_reflection_of(system, controller, kernel_grid)
        A, B = reflection_factors(A, B, reflection, controller.observer_reflection, numerator, denominator)
    A, B = output_feedback_factors(A, B, G, numerator, controller.observer_delay)
    if grid is None and _scaled_collocated(system, controller) and has_exact_form(system):
        return _exact_radii(A, system, controller, (("A", 0.0),)), _exact_radii(B, system, controller, (("B", 0.0),))
    return A, B


def observer_reflection_of(
    system: Any, controller: CollocatedOutputFeedback, kernel_grid: int | None = None
) -> ObserverReflection:
    """The terms ``H_y``, ``(1 - Phi) H_y``, ``B~ H_y`` of a collocated observer's own reflection on ``system``.

    Its ``accuracy`` is the estimated sup-norm error of the products' kernels
    (:func:`~nrobust.hyperbolic.loops.collocated.observer_reflection`; 0 on an uncoupled plant), or their
    proven bound where the terms are closed forms enclosed in ball arithmetic (``StateFeedback(k)`` on the
    exact route: ``H_y = u_factor``, ``B~ H_y = -k u_factor^2``,
    :func:`~nrobust.hyperbolic.loops.observer_proof.proven_collocated_products`; U_BS2(K) and U_BS on a coupled
    plant: ``B~ = Phi + (K - rho) q e^{-tau s}``, so ``B~ H_y = u_factor - (1 - Phi) u_factor + (K - rho) q
    e^{-tau s} u_factor``).
    """
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem for a CollocatedOutputFeedback", system)
    return _observer_reflection(
        system, unfiltered(controller.controller), _observer_grid(system, controller, kernel_grid)
    )


@lru_cache(maxsize=16)
def _observer_reflection(system: Hyperbolic2x2, law: Controller, route_grid: int | None) -> ObserverReflection:
    """:func:`observer_reflection_of` for the unfiltered law ``law`` (cached: the loop and the scope ask for it)."""
    if route_grid is None and _proven_law(system, law):
        assert isinstance(law, StateFeedback)
        products = proven_collocated_products(system)
        terms = products.open_loop_product.distributed + products.square.distributed
        accuracy = max(d.radius for d in terms)
        law_product = products.square * -float(law.k)
        return ObserverReflection(exact_form(system).u_factor, products.open_loop_product, law_product, accuracy)
    if (
        route_grid is None
        and isinstance(law, (FiniteTimeController, ReflectionController))
        and not _uncoupled(system)
        and proven_collocated_failure(system) is None
    ):
        # B~ = K q e^{-tau s} - I_N = Phi + (K - rho) q e^{-tau s} (delay form (39)), so B~ H_y = u_factor -
        # (1 - Phi) u_factor + (K - rho) q e^{-tau s} u_factor: the proven product and u_factor shifted
        u_factor = exact_form(system).u_factor
        open_product = proven_collocated_products(system).open_loop_product
        K = float(law.K) if isinstance(law, ReflectionController) else float(system.rho)
        law_product = u_factor - open_product
        if K != system.rho:
            law_product = law_product + u_factor.shift(system.tau) * ((K - system.rho) * system.q)
        terms = open_product.distributed + u_factor.distributed
        accuracy = max(d.radius for d in terms)
        return ObserverReflection(u_factor, open_product, law_product, accuracy)
    open_loop = loop_factors(system, OpenLoop(), route_grid)[0]
    law_factor = loop_factors(system, law, route_grid)[1]
    return observer_reflection(system, open_loop, law_factor, _collocated_grid(route_grid))


def _observer(system: Any, controller: OutputFeedback, kernel_grid: int | None) -> tuple[Any, int | None]:
    """The observer term ``G`` of an output feedback on ``system`` and the kernel grid it was built on."""
    if isinstance(system, GeneralHyperbolic2x2) and not system.constant_ratio:
        raise ParameterError(
            "system",
            "a plant with a constant lam/mu for an OutputFeedback (its measurement window is 1/mu of the normal form)",
            system,
        )
    grid = _observer_grid(system, controller, kernel_grid)
    law = unfiltered(controller.controller)
    if grid is None and _proven_observer(system, controller):
        return proven_observer_term(system, _window_law(law), _window_gains(law)), grid  # type: ignore[arg-type]
    open_loop, _ = loop_factors(system, OpenLoop(), grid)
    _, factor = loop_factors(system, law, grid)
    plant = normalize(system, OpenLoop())[0]
    return observer_term(open_loop, factor, 1.0 / plant.mu), grid


def _output_feedback_loop(
    system: Any, controller: OutputFeedback, kernel_grid: int | None
) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``(A_o, B_o)`` of an output feedback (:mod:`~nrobust.hyperbolic.loops.output_feedback`)."""
    term, grid = _observer(system, controller, kernel_grid)
    A, B = loop_factors(system, controller.controller, grid)
    inner = controller.controller
    numerator = (1.0, inner.a) if isinstance(inner, FilteredController) else (1.0,)
    return output_feedback_factors(A, B, term, numerator, controller.observer_delay)


def _exact_factors(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2, controller: Controller
) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``(A, B)`` on the closed-form delay form (:func:`loop_route` is ``"exact"``)."""
    _check_controller(controller)
    form = exact_form(system) if has_exact_form(system) else varying_proof(system)
    i_n = QuasiPolynomial([], [], [form.N_tilde]) if form.N_tilde is not None else QuasiPolynomial([[0.0]], [0.0])
    round_trip = QuasiPolynomial([[form.q]], [form.tau])
    # a varying plant's rho_q carries its radius here; the closed form's radii come from _exact_radii
    radius = form.rho_q_radius if isinstance(form, VaryingProof) else 0.0
    phi = QuasiPolynomial([[form.rho_q]], [form.tau], radii=[[radius]] if radius else None) - i_n
    if isinstance(controller, StateFeedback):
        u_factor = (
            form.u_factor
            if isinstance(form, VaryingProof)
            else QuasiPolynomial.from_parts(form.u_factor.point_terms, form.u_factor.distributed)  # its floats
        )
        B = u_factor * (-controller.k)
        terms = gain_terms(system, controller.g_u, controller.g_v) if _integral_gains(controller) else ()
        A, B = 1.0 - phi, B - QuasiPolynomial([], [], terms) if terms else B
    else:
        A, B = controller.factors(phi, i_n, round_trip)
    if not isinstance(form, ExactForm):
        return A, B
    return _exact_radii(A, system, controller, (("A", 0.0),)), _exact_radii(B, system, controller, (("B", 0.0),))


#: An exact point coefficient: rational multiples of ``1``, ``q e^{sigma_0 tau}`` (``"w"``) and
#: ``q e^{sigma_0 tau / 2}`` (``"h"``), summed exactly before they are enclosed in balls.
_Exact = dict[str, Fraction]


def _exact_points(
    system: Any, controller: Controller
) -> tuple[dict[float, list[_Exact]], dict[float, list[_Exact]]] | None:
    """The exact point coefficients of ``A`` and ``B`` on the closed form, by delay (increasing powers).

    Each is a rational combination of ``1``, ``q e^{sigma_0 tau}`` and ``q e^{sigma_0 tau / 2}``
    (:func:`~nrobust.hyperbolic.loops.exact_form.gain_balls`) with the user's numbers (``rho``,
    the controller's gains) as rationals; None for a controller whose factors are not listed here.
    A filter's ``a``, ``b`` enter as ``a / r``, ``b / r`` (``r`` of
    :func:`~nrobust.hyperbolic.loops.exact_form.tau_ratio`): the plant's loop at ``s`` is the loop
    with those filter constants at ``r s`` (:mod:`~nrobust.hyperbolic.loops.given_plant`), so the
    loop's balls enclose that loop, which the proofs map back to the plant.
    """
    tau = closed_form_parameters(system)[0]
    rho = Fraction(float(system.rho))

    def w(c: Any) -> _Exact:
        return {"w": Fraction(c)}

    A: dict[float, list[_Exact]] = {0.0: [{"1": Fraction(1)}], tau: [w(-rho)]}
    B: dict[float, list[_Exact]]
    if isinstance(controller, OpenLoop):
        B = {}
    elif isinstance(controller, FiniteTimeController):
        B = {tau: [w(rho)]}
    elif isinstance(controller, ReflectionController):
        B = {tau: [{"h": Fraction(controller.K)}]}
    elif isinstance(controller, FilteredController):
        # in x = r s the plant's loop is the loop as built of the filter (a / r, b / r): the balls are theirs
        r = tau_ratio(system)
        a, b = Fraction(controller.a) / r, Fraction(controller.b) / r
        g = w(rho) if controller.K is None else {"h": Fraction(controller.K)}
        A = {0.0: [{"1": Fraction(1)}, {"1": b}], tau: [w(-rho), w(-rho * b)]}
        B = {tau: [g, {k: v * a for k, v in g.items()}]}
    elif isinstance(controller, StateFeedback):
        B = {tau: [w(-Fraction(controller.k))]}
    elif isinstance(controller, CollocatedOutputFeedback) and _scaled_collocated(system, controller):
        return _collocated_points(system, controller)
    else:
        return None
    return A, B


def _collocated_points(
    system: Hyperbolic2x2, controller: CollocatedOutputFeedback
) -> tuple[dict[float, list[_Exact]], dict[float, list[_Exact]]] | None:
    """:func:`_exact_points` of an exact or proven collocated loop: ``E A - n G`` and ``E B + n G``.

    ``A``, ``B`` the law's (:func:`_exact_points`). On a
    :class:`~nrobust.hyperbolic.plants.hyperbolic2x2.Hyperbolic2x2` every coefficient is a rational of
    the user's numbers (``q e^{sigma_0 tau} = q``); the point part of ``C_u`` is ``k q e^{-tau s}`` and that of
    ``H_y`` is ``q e^{-tau s}`` (coupled or not), so the point part of ``G = (1 - Phi) C_u`` is
    ``k q e^{-tau s} - k rho q^2 e^{-2 tau s}``, ``k`` the law's boundary gain,
    ``n = 1 + (a / r) s`` for a filtered law (``1`` otherwise), and the observer's reflection
    ``E = 1 - kappa q e^{-tau s}`` (``H_y = q e^{-tau s}``, :mod:`~nrobust.hyperbolic.loops.collocated`;
    ``E = 1`` without it).
    """
    inner = _exact_points(system, controller.controller)
    if inner is None:
        return None
    tau = closed_form_parameters(system)[0]
    q, rho = Fraction(system.q), Fraction(system.rho)
    atoms = {"1": Fraction(1), "w": q, "h": q}

    def rational(table: dict[float, list[_Exact]]) -> dict[float, list[Fraction]]:
        return {t: [sum((atoms[k] * v for k, v in c.items()), Fraction(0)) for c in cs] for t, cs in table.items()}

    A, B = (_reflected(rational(table), Fraction(controller.observer_reflection) * q, tau) for table in inner)
    law = controller.controller
    k = Fraction(_boundary_gain(system, unfiltered(law)))
    n = [Fraction(1), Fraction(law.a) / tau_ratio(system)] if isinstance(law, FilteredController) else [Fraction(1)]
    for t, g in ((tau, k * q), (tau + tau, -rho * q * k * q)):  # n G, by delay
        for j, c in enumerate(n):
            for table, sign in ((A, -1), (B, 1)):
                coefs = table.setdefault(t, [])
                coefs.extend([Fraction(0)] * (j + 1 - len(coefs)))
                coefs[j] += sign * c * g

    def exact(table: dict[float, list[Fraction]]) -> dict[float, list[_Exact]]:
        return {t: [{"1": c} for c in cs] for t, cs in table.items()}

    return exact(A), exact(B)


def _boundary_gain(system: Hyperbolic2x2, law: Controller) -> float:
    """The boundary gain ``k`` of the unfiltered ``law`` (``-K`` for U_BS2(K), ``-rho`` for U_BS), without kernels."""
    if isinstance(law, ReflectionController):
        return -float(law.K)
    if isinstance(law, FiniteTimeController):
        return -float(system.rho)
    return float(law.feedback_law(system).boundary_gain)


def _reflected(table: dict[float, list[Fraction]], kappa_q: Fraction, tau: float) -> dict[float, list[Fraction]]:
    """``(1 - kappa_q e^{-tau s})`` times the factor of point coefficients ``table`` (by delay, increasing powers)."""
    out = {t: list(cs) for t, cs in table.items()}
    if kappa_q:
        for t, cs in table.items():
            coefs = out.setdefault(t + tau, [])
            coefs.extend([Fraction(0)] * (len(cs) - len(coefs)))
            for j, c in enumerate(cs):
                coefs[j] -= kappa_q * c
    return out


def _exact_radii(
    F: QuasiPolynomial, system: Any, controller: Controller, parts: tuple[tuple[str, float], ...]
) -> QuasiPolynomial:
    """``F`` with the radii of its point coefficients from their exact values (``F`` itself when all are exact).

    ``parts``: the factors (``"A"``, ``"B"`` of :func:`_exact_points`) and their shifts whose sum
    is ``F``'s point part (:func:`_exact_balls`); each radius bounds ``|stored - exact|``
    (:func:`~nrobust.hyperbolic.loops.exact_form.ball_radius`). ``F`` itself for a controller
    whose factors :func:`_exact_points` does not list, or without python-flint (the radii serve the ball
    arithmetic only, which needs it).
    """
    try:
        flint = require_flint()
    except ImportError:
        return F
    exact = _cached_balls(system, controller, parts)
    if exact is None:
        return F
    return _with_radii(flint, F, exact)


def _with_radii(
    flint: Any, F: QuasiPolynomial, exact: dict[float, list[Any]], keep_zero: bool = False
) -> QuasiPolynomial:
    """``F`` with the radii of its point coefficients bounding ``|stored - exact|`` (:func:`_exact_radii`); with
    ``keep_zero`` radii of 0 are stored too (so that a product with a number bounds its rounding)."""
    with precision(flint, PRECISION):
        stored = {t: p for p, t in F.point_terms}
        delays = sorted(set(stored) | set(exact))
        coefs: list[NDArray] = []
        radii: list[list[float]] = []
        for t in delays:
            p, e = stored.get(t, np.zeros(1)), exact.get(t, [])
            n = max(p.size, len(e))
            p = np.concatenate([p, np.zeros(n - p.size, dtype=p.dtype)])
            coefs.append(p)
            radii.append([ball_radius(flint, p[j], e[j] if j < len(e) else flint.arb(0)) for j in range(n)])
    if not keep_zero and not any(any(r) for r in radii):  # every stored coefficient exact
        return F if not F.point_radii else QuasiPolynomial(coefs, delays, F.distributed)
    return QuasiPolynomial(coefs, delays, F.distributed, radii=radii)


def _cached_balls(
    system: Any, controller: Controller, parts: tuple[tuple[str, float], ...]
) -> dict[float, list[Any]] | None:
    """:func:`_exact_balls`, cached per factor: a sum whose shifted delays are all distinct is the union of
    the factors' balls (only coinciding delays need the rational sum)."""
    if len(parts) > 1:
        tables = [_cached_balls(system, controller, ((name, 0.0),)) for name, _ in parts]
        shifted = []
        for table, (_, delta) in zip(tables, parts):
            if table is None:
                return None
            shifted.append({t + delta if delta else t: c for t, c in table.items()})
        if sum(len(table) for table in shifted) == len(set().union(*shifted)):
            return {t: c for table in shifted for t, c in table.items()}
    try:
        return _exact_balls(system, controller, parts)
    except TypeError:  # an unhashable plant or controller: not cached
        return _exact_balls.__wrapped__(system, controller, parts)


@lru_cache(maxsize=256)
def _exact_balls(
    system: Any, controller: Controller, parts: tuple[tuple[str, float], ...]
) -> dict[float, list[Any]] | None:
    """The exact point coefficients of the sum of ``parts`` (factor ``"A"`` or ``"B"``, shift) as ``arb`` balls.

    Summed as rational combinations first (:data:`_Exact`): terms that cancel exactly give an
    exact 0. None for a controller whose factors :func:`_exact_points` does not list.
    """
    points = _exact_points(system, controller)
    if points is None:
        return None
    exact: dict[float, list[_Exact]] = {}
    for name, delta in parts:
        _accumulate(exact, points[0 if name == "A" else 1], delta, Fraction(1))
    return _balls(system, exact)


def _accumulate(
    exact: dict[float, list[_Exact]], table: dict[float, list[_Exact]], delta: float, sign: Fraction
) -> None:
    """Add ``sign`` times the point coefficients ``table``, shifted by ``delta``, to ``exact`` (rationally)."""
    for t, table_coefs in table.items():
        acc = exact.setdefault(t + delta if delta else t, [])
        for j, c in enumerate(table_coefs):
            if j == len(acc):
                acc.append({})
            for atom, v in c.items():
                acc[j][atom] = acc[j].get(atom, Fraction(0)) + sign * v


def _balls(system: Any, exact: dict[float, list[_Exact]]) -> dict[float, list[Any]]:
    """The rational combinations ``exact`` of the plant's gains as ``arb`` balls."""
    h, _, w = gain_balls(system)
    flint = require_flint()
    with precision(flint, PRECISION):
        atoms = {"1": flint.arb(1), "w": w, "h": h}

        def ball(c: _Exact) -> Any:
            return sum((atoms[k] * (flint.arb(v.numerator) / v.denominator) for k, v in c.items() if v), flint.arb(0))

        return {t: [ball(c) for c in coefs] for t, coefs in exact.items()}


def gain_slope_factors(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2, at_zero: Controller, at_one: Controller
) -> tuple[QuasiPolynomial, QuasiPolynomial, QuasiPolynomial, QuasiPolynomial]:
    """``(A_0, A_1 - A_0, B_0, B_1 - B_0)``: the factors of a loop affine in a gain, from the controllers at gains
    0 and 1, so that the loop at ``K`` is ``(A_0 + K (A_1 - A_0)) + (B_0 + K (B_1 - B_0)) e^{-delta s}``.

    Where the factors' point coefficients are exact rationals of the plant's numbers (the exact and proven
    routes), the radii of the differences' point coefficients bound them against the exact differences, not
    the sum of the two loops' radii: a coefficient whose exact slope is a double has radius 0 (and a product
    with ``K`` the radius of its rounding). So at the gain where point terms of the loop cancel (``K = rho`` for
    U_BS2(K), eqs. (56)-(58): the target system ``1``), summed as ``(A_0 + B_0) + K ((A_1 - A_0) + (B_1 -
    B_0))`` (:meth:`nrobust.design.AffineLoop.nominal`), they are exactly 0, not balls about 0.
    """
    A0, B0 = loop_factors(system, at_zero)
    A1, B1 = loop_factors(system, at_one)
    slopes = [A1 - A0, B1 - B0]
    zero, one = _exact_points(system, at_zero), _exact_points(system, at_one)
    if zero is not None and one is not None:
        try:
            flint = require_flint()
        except ImportError:
            flint = None
        for i in (0, 1) if flint is not None else ():
            exact: dict[float, list[_Exact]] = {}
            _accumulate(exact, one[i], 0.0, Fraction(1))
            _accumulate(exact, zero[i], 0.0, Fraction(-1))
            slopes[i] = _with_radii(flint, slopes[i], _balls(system, exact), keep_zero=True)
    return A0, slopes[0], B0, slopes[1]


@renamed_keywords(n="kernel_grid")
def loop_factors(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2, controller: Controller, kernel_grid: int | None = None
) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``(A, B)`` with the closed-loop characteristic function ``F = A + B e^{-delta s}``.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant, eqs. (18)-(20), or a general plant (through :func:`normalize`).
    controller : Controller
        One of the paper's controllers, or a :class:`StateFeedback`.
    kernel_grid : int, optional
        Default: the exact route where :func:`loop_route` allows it (constant
        coefficients: ``N~`` in closed form, no grid; couplings that are functions of ``x``:
        ``N~`` with a proven error bound), otherwise kernels on
        :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID` points. Given, the
        kernel grid for ``N~`` (formerly ``n``, a deprecated alias): the cubic spline ``N~``
        carries the error of the kernels, about third order in ``1/kernel_grid`` for an odd
        grid (extrapolated kernels), second order for an even one
        (``docs/numerics_kernels.md``). A plant with a varying ``lam/mu`` takes ``N~`` from the
        characteristic route on ``2 (kernel_grid - 1)`` steps (``N~`` on ``kernel_grid``
        nodes, fourth order), and the integral gains of a :class:`StateFeedback` from
        kernels with varying speeds on ``kernel_grid`` points (second order).

    Returns
    -------
    tuple of QuasiPolynomial
        ``A`` and ``B`` as in the module's table.
    """
    if kernel_grid is not None:
        kernel_grid = check_kernel_grid(kernel_grid)
    if isinstance(controller, OutputFeedback):
        return _output_feedback_loop(system, controller, kernel_grid)
    if isinstance(controller, CollocatedOutputFeedback):
        return _collocated_loop(system, controller, kernel_grid)
    if loop_route(system, controller, kernel_grid) == "exact":
        return _exact_factors(system, controller)
    grid = DEFAULT_KERNEL_GRID if kernel_grid is None else kernel_grid
    if isinstance(system, GeneralHyperbolic2x2) and not system.constant_ratio:
        return _varying_factors(system, controller, grid)
    plant: Hyperbolic2x2
    plant, controller = normalize(system, controller)
    _check(plant, controller)
    kernel_grid = grid
    i_n = _distributed_part(plant, kernel_grid)
    round_trip = QuasiPolynomial([[plant.q]], [plant.tau])  # q e^{-tau s}
    phi = round_trip * plant.rho - i_n
    if isinstance(controller, StateFeedback):
        return 1.0 - phi, -_state_feedback_factor(plant, controller, kernel_grid)
    return controller.factors(phi, i_n, round_trip)


@renamed_keywords(n="kernel_grid")
def characteristic(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    controller: Controller,
    delta: float = 0.0,
    kernel_grid: int | None = None,
) -> QuasiPolynomial:
    """Closed-loop characteristic quasi-polynomial ``F(s; delta) = A(s) + B(s) e^{-delta s}``.

    The closed loop is exponentially stable iff ``F`` has no zero with ``Re s >= 0`` and
    its difference operator is strongly stable (Theorem 3, Theorem 4 of the paper).

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant.
    controller : Controller
        The controller.
    delta : float, optional
        Loop delay ``delta >= 0``.
    kernel_grid : int, optional
        Kernel grid for ``N~`` (formerly ``n``, a deprecated alias); by default the exact
        route where it applies (:func:`loop_factors`).
    """
    delta = nonnegative("delta", delta)
    a, b = loop_factors(system, controller, kernel_grid)
    shifted = b.shift(delta)
    F = a + shifted
    if (
        isinstance(controller, OutputFeedback)
        or (isinstance(controller, CollocatedOutputFeedback) and not _scaled_collocated(system, controller))
        or not has_exact_form(system)
    ):
        return F
    if a.exact_points and b.exact_points and not {t for _, t in a.point_terms} & {t for _, t in shifted.point_terms}:
        return F  # no coefficient summed: those of the exact factors
    if loop_route(system, controller, kernel_grid) != "exact":
        return F
    # the radii of the sum from its exact values: a cancellation (U_BS at delta = 0) is exact, not a ball,
    # and the rounding of a sum (rho q - K q at delta = 0) is enclosed
    return _exact_radii(F, system, controller, (("A", 0.0), ("B", delta)))


@dataclass(frozen=True)
class Classification:
    """The paper's three regimes of the open-loop gain ``|rho q|``.

    Attributes
    ----------
    rho_q : float
        The open-loop gain (product of proximal and distal reflections).
    regime : str
        ``"not_stabilizable"`` (``|rho q| > 1``, Theorem 2), ``"critical_one"``
        (``|rho q| = 1``), ``"no_robust_finite_time"`` (``1/2 < |rho q| < 1``, Theorem 3),
        ``"critical_half"`` (``|rho q| = 1/2``: the U_BS loop's difference operator has
        ``gamma_0 = 1``, not strongly stable), ``"robust_finite_time"`` (``|rho q| < 1/2``).
    delay_robustly_stabilizable : bool or None
        None in the critical case ``|rho q| = 1`` the paper leaves open.
    finite_time_delay_robust : bool
        Whether U_BS keeps a positive delay margin: its delayed loop has the difference
        operator ``1 - rho q e^{-tau s} + rho q e^{-(tau+delta) s}``, strongly stable iff
        ``2 |rho q| < 1`` (eq. (11)).
    k_bound : float
        ``(1 - |rho q|)/|q|``: every ``|K|`` below it makes U_BS2 delay-robust (eq. (54));
        0 when ``|rho q| >= 1``.
    statement : str
        The verdict in words.
    """

    rho_q: float
    regime: str
    delay_robustly_stabilizable: bool | None
    finite_time_delay_robust: bool | None
    k_bound: float
    statement: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


def classify(system: Hyperbolic2x2 | GeneralHyperbolic2x2, atol: float = 1e-12) -> Classification:
    """Classify a system by its open-loop gain ``|rho q|`` (paper, sections 2 and 3).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant. A general plant is classified by its normal form; with a varying
        ``lam/mu`` by the principal part of its characteristic route,
        ``1 - rho_q e^{-tau s}`` (``rho_q = rho q e^{A(L) - D(L)}``): Theorems 2 and 3
        read on it unchanged, U_BS2(K) is not defined (no normal form), and ``k_bound``
        is the bound ``(1 - |rho_q|)/|q e^{A(L) - D(L)}|`` of ``|k|`` for the proportional
        feedback ``U = k u(t, L)`` (its delayed principal part
        ``1 - rho_q e^{-tau s} - k q e^{A(L) - D(L)} e^{-(tau + delta) s}`` is strongly
        stable below it).
    atol : float, optional
        Distance to ``1`` or ``1/2`` under which ``|rho q|`` counts as a critical case.
    """
    if isinstance(system, GeneralHyperbolic2x2):
        if system.constant_ratio:
            return classify(system.normal_form().system, atol)
        end = system.length
        u_gain = system.q * float(np.exp(system.A(end) - system.D(end)))
        cls = classify(TransportSystem(1.0, 1.0, u_gain, system.rho_q / u_gain), atol)
        statement = re.sub(
            r"U_BS2\(K\) is delay-robust for \|K\| < ([0-9.eE+-]+)(?: \(Theorem 4\))?\.",
            r"U_BS2(K) needs the normal form (lam/mu varies); the proportional feedback U = k u(t, L) keeps a "
            r"strongly stable principal part for |k| < \1.",
            cls.statement,
        )
        return dataclasses.replace(cls, statement=statement)
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2, TransportSystem or GeneralHyperbolic2x2", system)
    atol = nonnegative("atol", atol)
    g = abs(system.rho * system.q)
    k_bound = max(0.0, (1.0 - g) / abs(system.q))
    if abs(g - 1.0) <= atol:
        return Classification(
            system.rho * system.q,
            "critical_one",
            None,
            False,
            0.0,
            "|rho q| = 1: critical case; the open-loop chain lies on the imaginary axis.",
        )
    if g > 1.0:
        return Classification(
            system.rho * system.q,
            "not_stabilizable",
            False,
            False,
            0.0,
            f"|rho q| = {g:.6g} > 1: no controller is robust to small loop delays (Theorem 2).",
        )
    if abs(g - 0.5) <= atol:
        return Classification(
            system.rho * system.q,
            "critical_half",
            True,
            False,
            k_bound,
            "|rho q| = 1/2: U_BS has a difference operator with gamma_0 = 1 (not strongly "
            f"stable); U_BS2(K) is delay-robust for |K| < {k_bound:.6g}.",
        )
    if g > 0.5:
        return Classification(
            system.rho * system.q,
            "no_robust_finite_time",
            True,
            False,
            k_bound,
            f"1/2 < |rho q| = {g:.6g} < 1: finite-time U_BS has zero delay margin (Theorem 3); "
            f"U_BS2(K) is delay-robust for |K| < {k_bound:.6g} (Theorem 4).",
        )
    return Classification(
        system.rho * system.q,
        "robust_finite_time",
        True,
        True,
        k_bound,
        f"|rho q| = {g:.6g} < 1/2: finite-time stabilization can be delay-robust; U_BS2(K) is "
        f"delay-robust for |K| < {k_bound:.6g}.",
    )


def _exact_product(*factors: float) -> bool:
    """True when the floating-point product of ``factors`` (left to right) is the exact one."""
    value, exact = 1.0, Fraction(1)
    for f in factors:
        value, exact = value * f, exact * Fraction(f)
    return Fraction(value) == exact


def rounded_parts(system: Any, controller: Any, kernel_grid: int | None = None) -> str:
    """What the exact-route loop takes rounded from the user's numbers; ``""`` if nothing.

    Empty when a proof about the loop holds for the plant as given: on the exact route the
    principal gains (``rho q``, the law's gain times ``q``, times the exponential weight
    ``e^{sigma_0 tau}`` of a general plant) carry proven radii
    (:attr:`~nrobust.hyperbolic.loops.exact_form.ExactForm.rho_q_radius`), and ``tau`` is
    mapped exactly (:func:`~nrobust.hyperbolic.loops.given_plant.given_plant_scale`) for a loop
    that is a function of ``tau s`` and ``delta / tau``, or a filtered law's (its ``a``, ``b``
    enclosed as ``a / r``, ``b / r``), or a state feedback's with integral gains (their kernel
    built with ``t_v = tau_d lam / (lam + mu)`` exactly,
    :func:`~nrobust.hyperbolic.loops.exact_gains.gain_terms`), or an output feedback whose proven
    observer term (:func:`~nrobust.hyperbolic.loops.observer_proof.proven_observer_term`) is built
    with ``tau`` and the window ``1/mu`` exact (doubles). On a plant with a proven varying ``N~``
    (:func:`~nrobust.hyperbolic.loops.varying_proof.varying_proof`) the principal gains carry proven
    radii (:attr:`~nrobust.hyperbolic.loops.varying_proof.VaryingProof.rho_q_radius`) and this names
    ``tau`` rounded, or for varying speeds the speeds' factor making ``tau`` a double (its
    ``assumption``). Otherwise the quantities computed in floating point, in words, for a proof's scope.
    """
    general = isinstance(system, GeneralHyperbolic2x2)
    tau = "L/lam + L/mu" if general else "1/lam + 1/mu"
    if kernel_grid is None and _proven_varying(system, controller):
        # the principal gains carry the proven radii of their computation (VaryingProof.rho_q_radius, u_radius);
        # varying speeds: the speeds scaled to make tau a double (VaryingProof.assumption) instead of tau rounded
        return varying_proof(system).assumption or f"tau = {tau} as a double (a few ulps)"
    if general and not has_exact_form(system):
        return (
            "tau and the principal gains (q and rho q times the exponential weight of a and d, and the law's gain "
            "times them) as doubles computed from the coefficients (a few ulps)"
        )
    if not isinstance(system, (Hyperbolic2x2, GeneralHyperbolic2x2)) or not has_exact_form(system):
        return "tau and the principal gains as doubles computed from the parameters (a few ulps)"
    if kernel_grid is not None or loop_route(system, controller, kernel_grid) != "exact":
        return f"tau = {tau} and the principal gains as doubles (mapped to the exact tau on the exact route only)"
    if isinstance(controller, (OpenLoop, FiniteTimeController, ReflectionController, FilteredController)):
        return ""
    if isinstance(controller, StateFeedback):  # integral gains: their kernel built with t_v / r (gain_terms)
        return ""
    if (isinstance(controller, OutputFeedback) and observer_of(system, controller, kernel_grid) is None) or (
        isinstance(controller, CollocatedOutputFeedback) and _scaled_collocated(system, controller)
    ):  # the state feedback's loop, or its loop and an exact observer term in tau s: as the law's
        return rounded_parts(system, controller.controller, kernel_grid)
    if isinstance(controller, OutputFeedback) and _proven_observer(system, controller):
        w = proof_window(system, _window_gains(unfiltered(controller.controller)))
        exact = isinstance(system, Hyperbolic2x2) and Fraction(w) == 1 / Fraction(system.mu)
        if exact and tau_ratio(system) == 1:  # the loop as built is the plant's
            return ""
        window = "the normal form's window 1/mu" if general else "the window 1/mu"
        if general:  # the normal form's mu is itself computed in floating point
            rounded = " (computed in floating point from the plant's numbers, not the exact window)"
        elif not exact and isinstance(system, Hyperbolic2x2):
            gap = abs(Fraction(w) * Fraction(system.mu) - 1)
            bound = float(gap)
            bound = math.nextafter(bound, math.inf) if Fraction(bound) < gap else bound
            rounded = f" (a relative {upper_bound_text(bound, 2)} from the exact window)"
        else:
            rounded = ""
        return (
            f"{_rounded_tau(system)} and {window} as the double {w!r}{rounded} (the OutputFeedback loop "
            "is not mapped to the exact tau: its observer term has a kernel on the window)"
        )
    if isinstance(controller, CollocatedOutputFeedback) and _proven_collocated(system, controller):
        # only the observer delay keeps the loop from the map: with tau a double the loop as built is the plant's,
        # but for the delays t + delta_o of the observer's point terms, rounded where they are not doubles
        sums = _observer_delay_sums(system, controller)
        if tau_ratio(system) == 1:
            return sums
        return (
            f"{_rounded_tau(system)} (the CollocatedOutputFeedback loop is not mapped to the exact tau: an observer "
            f"delay){'; ' + sums if sums else ''}"
        )
    if isinstance(controller, _ObserverFeedback):
        return (
            f"{_rounded_tau(system)} and the observer's terms as computed in floating point (the "
            f"{type(controller).__name__} loop is not mapped to the exact tau: an observer delay, or "
            "an observer term with a kernel)"
        )
    return (
        f"{_rounded_tau(system)} (the law's {type(controller).__name__} loop depends on tau otherwise than through "
        "tau s)"
    )


def _observer_delay_sums(system: Any, controller: CollocatedOutputFeedback) -> str:
    """The delays ``t + delta_o`` of the proven collocated observer's point terms (``G e^{-delta_o s}``,
    :func:`~nrobust.hyperbolic.loops.output_feedback.output_feedback_factors`) that are not doubles, with the
    largest relative rounding of the doubles the loop holds instead, rounded up; ``""`` if every sum is a double.
    (Its distributed terms carry the rounding of their moved nodes in their proven bounds.)"""
    delta_o = Fraction(controller.observer_delay)
    delays = [t for _, t in proven_collocated_products(system).open_loop_product.point_terms]
    gaps = {t: abs(Fraction(t + float(delta_o)) / (Fraction(t) + delta_o) - 1) for t in delays if Fraction(t) + delta_o}
    rounded = [t for t, g in gaps.items() if g]
    if not rounded:
        return ""
    gap = max(gaps[t] for t in rounded)
    bound = float(gap)
    bound = math.nextafter(bound, math.inf) if Fraction(bound) < gap else bound
    sums = " and ".join(f"{t!r} + delta_o" for t in rounded)
    return (
        f"the observer's point delays {sums} as the nearest doubles (a relative {upper_bound_text(bound, 2)} at "
        "most from the exact sums)"
    )


def _rounded_tau(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> str:
    """``tau = 1/lam + 1/mu as the double tau_d``, with ``|tau_d - tau| / tau`` rounded up (``tau`` exact).

    The size of what a proof about the loop as built leaves rounded: a few ``2^-53`` (``tau_d`` is
    the floating-point sum of the two times of flight, each rounded).
    """
    tau = "L/lam + L/mu" if isinstance(system, GeneralHyperbolic2x2) else "1/lam + 1/mu"
    text = f"tau = {tau} as the double {closed_form_parameters(system)[0]!r}"
    gap = abs(1 - 1 / tau_ratio(system))
    if gap == 0:
        return text + " (exact)"
    bound = float(gap)
    bound = math.nextafter(bound, math.inf) if Fraction(bound) < gap else bound
    return text + f" (a relative {upper_bound_text(bound, 2)} from the exact tau)"
