"""Transfer functions of the paper's plants: open loop, output map, closed loop.

The open loop ``H_0(s) = 1 / (1 - rho q e^{-tau s})`` of the transport system (Laplace
transform of eq. (6)) and
``H_1(s) = 1 / (1 - rho q e^{-tau s} + int_0^tau N~(nu) e^{-nu s} dnu)`` of the coupled
system (Laplace transform of eq. (39)), as
:class:`~nrobust.lti.transfer.QuasiTransferFunction`.
"""

from __future__ import annotations

from ..._validate import nonnegative, renamed_keywords
from ...errors import ParameterError
from ...lti.transfer import QuasiTransferFunction, product
from ...quasipoly import QuasiPolynomial
from ..kernels.constant import DEFAULT_KERNEL_GRID, check_kernel_grid, solve_kernels
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from .controllers import Controller, FilteredController, loop_factors
from .delay_form import delay_form, delay_kernel
from .exact_form import exact_form, exact_output_map, has_exact_form

__all__ = ["closed_loop_tf", "open_loop_tf", "output_map"]


@renamed_keywords(n="kernel_grid")
def open_loop_tf(system: Hyperbolic2x2, kernel_grid: int | None = None) -> QuasiTransferFunction:
    """Open-loop transfer function from ``U`` to the boundary output.

    For a :class:`~nrobust.hyperbolic.TransportSystem` (or any uncoupled system) this is
    ``H_0(s) = 1 / (1 - rho q e^{-tau s})`` (from ``U`` to ``v(t, 1)``, Laplace transform
    of eq. (6)); for a :class:`~nrobust.hyperbolic.Hyperbolic2x2` it is
    ``H_1(s) = 1 / (1 - rho q e^{-tau s} + int_0^tau N~(nu) e^{-nu s} dnu)`` (from ``U_0``
    to ``beta(t, 1)``, Laplace transform of eq. (39)), whose denominator is
    ``delay_form(system).characteristic``.

    Parameters
    ----------
    system : TransportSystem or Hyperbolic2x2
    kernel_grid : int, optional
        Kernel grid passed to :func:`~nrobust.hyperbolic.loops.delay_form` (coupled systems only;
        formerly ``n``, a deprecated alias). Default: ``N~`` in closed form for constant
        couplings (:func:`~nrobust.hyperbolic.loops.exact_form.exact_form`), else
        :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID` points, as the
        closed-loop functions, so that ``H_1`` and :func:`closed_loop_tf` share the same ``N~``.
    """

    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem", system)
    if system.uncoupled:
        return QuasiTransferFunction(1.0, QuasiPolynomial([[1.0], [-system.rho_q]], [0.0, system.tau]))
    if kernel_grid is None and has_exact_form(system):
        return QuasiTransferFunction(1.0, exact_form(system).characteristic)
    form = delay_form(system, DEFAULT_KERNEL_GRID if kernel_grid is None else check_kernel_grid(kernel_grid))
    return QuasiTransferFunction(1.0, form.characteristic)


@renamed_keywords(n="kernel_grid")
def output_map(system: Hyperbolic2x2, kernel_grid: int | None = None) -> QuasiPolynomial:
    """``M(s)`` with ``v(s, 1) = M(s) beta(s, 1)`` for zero initial data.

    The inverse transformation (eq. (31)) at ``x = 1`` with
    ``alpha(s, xi) = q e^{-(xi/lam + 1/mu) s} beta(s, 1)`` and
    ``beta(s, xi) = e^{-(1 - xi) s / mu} beta(s, 1)`` (eqs. (37)-(38)) gives
    ``M(s) = 1 + int_0^tau M~(nu) e^{-nu s} dnu`` with
    ``M~(nu) = lam q L^{beta alpha}(1, lam nu - lam/mu) h_[1/mu, tau](nu)
    + mu L^{beta beta}(1, 1 - mu nu) h_[0, 1/mu](nu)``, the same change of variables as
    ``N~`` in eq. (40), built by the same function
    (:func:`~nrobust.hyperbolic.loops.delay_form.delay_kernel`, a cubic spline on each side of
    the jump at ``nu = 1/mu``). For a transport system ``M = 1``.

    Parameters
    ----------
    system : TransportSystem or Hyperbolic2x2
    kernel_grid : int, optional
        Kernel grid (formerly ``n``, a deprecated alias); ``M~`` is tabulated on its points
        on each side of the jump. Default: as the closed-loop functions, ``M~`` in closed form
        for constant couplings (:func:`~nrobust.hyperbolic.loops.exact_form.exact_output_map`),
        else :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID` points.
    """

    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem", system)
    if system.uncoupled:
        return QuasiPolynomial([[1.0]], [0.0])
    if kernel_grid is None and has_exact_form(system):
        return exact_output_map(system)
    kernels = solve_kernels(system, DEFAULT_KERNEL_GRID if kernel_grid is None else check_kernel_grid(kernel_grid))
    L1 = kernels.L[:, :, -1, :]  # L^{ab}(1, xi) on the grid, a, b in (alpha, beta)
    return QuasiPolynomial([[1.0]], [0.0], [delay_kernel(system, kernels.grid, L1[1, 0], L1[1, 1])])


def closed_loop_tf(
    system: Hyperbolic2x2, controller: Controller, delta: float, output: str = "v"
) -> QuasiTransferFunction:
    """Closed-loop transfer function from a disturbance at the actuated boundary.

    The disturbance ``d`` enters where the (delayed) control does,
    ``v(t, 1) = rho u(t, 1) + U(t - delta) + d(t)`` (eq. (20)). With the loop written as
    ``F(s) = A(s) + B(s) e^{-delta s}`` (:func:`~nrobust.hyperbolic.loop_factors`, the
    characteristic function of eq. (60) and its variants), ``A = D c_d`` and
    ``B = -c_n`` where ``D`` is the open-loop denominator of ``H_1`` and ``c_n / c_d`` the
    controller's map from ``beta(t, 1)`` to ``U``, the transfer to ``beta(t, 1)`` is
    ``c_d(s) / F(s)``; to ``v(t, 1)`` it is ``M(s) c_d(s) / F(s)`` with ``M`` from
    :func:`output_map`.

    Parameters
    ----------
    system : TransportSystem or Hyperbolic2x2
    controller : a controller of :mod:`nrobust.hyperbolic`
    delta : float
        Loop delay ``>= 0``.
    output : {"v", "beta"}
        ``"v"`` for ``v(t, 1)`` (default), ``"beta"`` for the target-system output.

    Returns
    -------
    QuasiTransferFunction
        Its denominator is the closed-loop characteristic function ``F``.
    """

    delta = nonnegative("delta", delta)
    if output not in ("v", "beta"):
        raise ParameterError("output", '"v" or "beta"', output)
    A, B = loop_factors(system, controller)
    F = A + B.shift(delta)
    c_d = _controller_denominator(controller)
    num = c_d if output == "beta" else product("output", output_map(system), c_d)
    return QuasiTransferFunction(num, F)


def _controller_denominator(controller: Controller) -> QuasiPolynomial:
    """``c_d(s)``: ``1 + b s`` for the filtered controller ``(1 + a s)/(1 + b s)``, else 1."""

    if isinstance(controller, FilteredController):
        return QuasiPolynomial([[1.0, float(controller.b)]], [0.0])
    return QuasiPolynomial([[1.0]], [0.0])
