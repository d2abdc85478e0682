"""Boundary controllers of the paper and their closed loops with a loop delay.

Write ``Phi(t) = rho u(t, 1) - int_0^1 K^{vu}(1, xi) u + K^{vv}(1, xi) v dxi``, so that the
actuated boundary condition reads ``beta(t, 1) = Phi(t) + U(t)`` in the backstepping
coordinates (paper, eq. (IC_alpha)). Along the characteristics (eqs. (eq_alpha_1) to
(delay_eq_alpha)), ``Phi`` is a functional of the past of ``beta(., 1)`` whose Laplace
transform is ``Phi(s) beta(s, 1)`` with

    Phi(s) = rho q e^{-tau s} - I_N(s),    I_N(s) = int_0^tau N~(nu) e^{-nu s} dnu.

A controller with a loop delay ``delta`` then closes the loop as
``F(s; delta) = A(s) + B(s) e^{-delta s}``:

============================  =====================  ==============================
controller                    A(s)                   B(s)
============================  =====================  ==============================
open loop, ``U = 0``          ``1 - Phi``            ``0``
U_BS, eq. (control)           ``1 - Phi``            ``Phi``
U_BS2(K), eq. (control3)      ``1 - Phi``            ``K q e^{-tau s} - I_N``
filtered U_BS, section 2.3.2  ``(1 + b s)(1 - Phi)``  ``(1 + a s) Phi``
============================  =====================  ==============================

For U_BS this is ``1 - rho q e^{-tau s} + rho q e^{-(tau+delta) s} + I_N (1 - e^{-delta s})``
(Theorem 3), for U_BS2 ``1 - rho q e^{-tau s} + K q e^{-(tau+delta) s} + I_N (1 - e^{-delta
s})`` (the proof of Theorem 4, with ``+I(s, delta)``). On a transport system ``I_N = 0``
and these are eqs. (delay_eq_no_couplings2), (delay_transport2) and (delay_transport3);
the last one, derived again from ``U_1 = -(1 + a s)/(1 + b s) rho u(1, s)``, has
``rho q v(t - tau - delta, 1)`` (not ``q rho a``) on its right-hand side.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._json import fields_dict, json_safe
from .._validate import finite_real, nonnegative, positive, positive_int, renamed_keywords
from ..errors import ParameterError
from ..quasipoly import QuasiPolynomial
from .delay_form import delay_form
from .kernels import DEFAULT_KERNEL_GRID
from .system import Hyperbolic2x2

__all__ = [
    "Classification",
    "Controller",
    "FeedbackLaw",
    "FilteredController",
    "FiniteTimeController",
    "OpenLoop",
    "ReflectionController",
    "characteristic",
    "classify",
    "loop_factors",
]

Gain = Callable[[NDArray[np.float64]], NDArray[np.float64]]


def _zero_gain(xi: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.zeros_like(np.asarray(xi, dtype=float))


@dataclass(frozen=True)
class FeedbackLaw:
    """A boundary feedback as a functional of the state, for the simulator.

    ``U(t) = boundary_gain * u(t, 1) + int_0^1 gain_u(xi) u(t, xi) + gain_v(xi) v(t, xi) dxi``,
    passed through the proper filter ``(1 + a s)/(1 + b s)`` when ``filter = (a, b)``.
    """

    boundary_gain: float
    gain_u: Gain
    gain_v: Gain
    filter: tuple[float, float] | None = None


class Controller(ABC):
    """A boundary controller for :class:`~nrobust.hyperbolic.system.Hyperbolic2x2`."""

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
    """U_BS, eq. (control): cancels the proximal reflection; finite time for ``delta = 0``.

    ``U_BS = -rho u(t, 1) + int_0^1 K^{vu}(1, xi) u + K^{vv}(1, xi) v dxi``; on a transport
    system, ``U = -rho u(t, 1)`` (eq. (Control_law_transport)).
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
    """U_BS2(K), eq. (control3): keeps ``rho - K`` of the proximal reflection.

    ``U = -K u(1) - (rho - K) int K^{uu}(1,.) u + K^{uv}(1,.) v + int K^{vu}(1,.) u + K^{vv}(1,.) v``;
    the target system reflects ``(rho - K)`` at ``x = 1``, exponentially stable when
    ``|K| < (1 - |rho q|)/|q|`` (eq. (boun_K2)). On a transport system, ``U = -K u(t, 1)``
    (eq. (U_transport)).

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
    """U_BS passed through the proper filter ``(1 + a s)/(1 + b s)`` (section 2.3.2).

    On a transport system this is ``U_1(s) = -(1 + a s)/(1 + b s) rho u(1, s)``.

    Parameters
    ----------
    a : float
        Filter zero coefficient.
    b : float
        Filter pole coefficient, ``b > 0``.
    """

    a: float
    b: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "a", finite_real("a", self.a))
        object.__setattr__(self, "b", positive("b", self.b))

    def factors(self, phi, i_n, round_trip):
        return (1.0 - phi).times_poly([1.0, self.b]), phi.times_poly([1.0, self.a])

    def feedback_law(self, system, kernels=None):
        law = FiniteTimeController().feedback_law(system, kernels)
        return FeedbackLaw(law.boundary_gain, law.gain_u, law.gain_v, (self.a, self.b))


def _check(system: Any, controller: Any) -> None:
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem", system)
    if not isinstance(controller, Controller):
        raise ParameterError(
            "controller", "OpenLoop, FiniteTimeController, ReflectionController or FilteredController", controller
        )


@lru_cache(maxsize=32)
def _distributed_part(system: Hyperbolic2x2, kernel_grid: int) -> QuasiPolynomial:
    """``I_N(s) = int_0^tau N~(nu) e^{-nu s} dnu`` (zero on an uncoupled system)."""
    if system.uncoupled:
        return QuasiPolynomial([[0.0]], [0.0])
    return QuasiPolynomial([], [], [delay_form(system, kernel_grid).N_tilde])


@renamed_keywords(n="kernel_grid")
def loop_factors(
    system: Hyperbolic2x2, controller: Controller, kernel_grid: int = DEFAULT_KERNEL_GRID
) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``(A, B)`` with the closed-loop characteristic function ``F = A + B e^{-delta s}``.

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant, eqs. (u_pde)-(IC).
    controller : Controller
        One of the paper's controllers.
    kernel_grid : int, default :data:`~nrobust.hyperbolic.kernels.DEFAULT_KERNEL_GRID`
        Kernel grid for ``N~`` (formerly ``n``, a deprecated alias). The cubic spline ``N~``
        carries the error of the kernels: about third order in ``1/kernel_grid`` for an odd
        grid (extrapolated kernels), second order for an even one
        (``docs/numerics_kernels.md``).

    Returns
    -------
    tuple of QuasiPolynomial
        ``A`` and ``B`` as in the module's table.
    """
    _check(system, controller)
    i_n = _distributed_part(system, positive_int("kernel_grid", kernel_grid, 3))
    round_trip = QuasiPolynomial([[system.q]], [system.tau])  # q e^{-tau s}
    phi = round_trip * system.rho - i_n
    return controller.factors(phi, i_n, round_trip)


@renamed_keywords(n="kernel_grid")
def characteristic(
    system: Hyperbolic2x2, controller: Controller, delta: float = 0.0, kernel_grid: int = DEFAULT_KERNEL_GRID
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
    kernel_grid : int, default :data:`~nrobust.hyperbolic.kernels.DEFAULT_KERNEL_GRID`
        Kernel grid for ``N~`` (formerly ``n``, a deprecated alias).
    """
    delta = nonnegative("delta", delta)
    a, b = loop_factors(system, controller, kernel_grid)
    return a + b.shift(delta)


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
        ``2 |rho q| < 1`` (eq. (eq_rho_q)).
    k_bound : float
        ``(1 - |rho q|)/|q|``: every ``|K|`` below it makes U_BS2 delay-robust (eq. (boun_K2));
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


def classify(system: Hyperbolic2x2, atol: float = 1e-12) -> Classification:
    """Classify a system by its open-loop gain ``|rho q|`` (paper, sections 2 and 3).

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant.
    atol : float, optional
        Distance to ``1`` or ``1/2`` under which ``|rho q|`` counts as a critical case.
    """
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem", system)
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
