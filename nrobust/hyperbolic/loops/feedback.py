"""Any linear boundary state feedback: its loop factors by kernels and by the Laplace route.

The feedback ``U(t) = k u(t, 1) + int_0^1 g_u(x) u(t, x) + g_v(x) v(t, x) dx`` of the
paper's plant, applied with a loop delay ``delta``. In the backstepping coordinates
``u = alpha + int_0^x L^{aa} alpha + L^{ab} beta``, ``v = beta + int_0^x L^{ba} alpha +
L^{bb} beta`` (eqs. (30)-(31)), and along the characteristics of the target
system (eq. (37): ``alpha(x) = q beta(t - x/lam - 1/mu, 1)``,
``beta(x) = beta(t - (1 - x)/mu, 1)``), the feedback is a functional of the past of
``beta(., 1)`` with Laplace transform ``P(s) beta(s, 1)``::

    P(s) = k q e^{-tau s} + int_0^tau M(nu) e^{-nu s} dnu,
    W_alpha(xi) = k L^{aa}(1, xi) + g_u(xi) + int_xi^1 g_u(x) L^{aa}(x, xi) + g_v(x) L^{ba}(x, xi) dx,
    W_beta(xi)  = k L^{ab}(1, xi) + g_v(xi) + int_xi^1 g_u(x) L^{ab}(x, xi) + g_v(x) L^{bb}(x, xi) dx,

with ``M`` made of the two branches ``W_alpha, W_beta`` exactly as ``N~`` is made of
``N^alpha, N^beta`` (eq. (40), :func:`~nrobust.hyperbolic.loops.delay_form.delay_kernel`).
Since ``beta(t, 1) = Phi(t) + U(t - delta)``, the closed loop is
``F(s; delta) = A(s) + B(s) e^{-delta s}`` with ``A = 1 - Phi`` (the open-loop
characteristic function) and ``B = -P``. U_BS and U_BS2(K) are the special cases whose
gains are kernel traces; there ``M`` reduces to ``N~`` (tests).

:func:`laplace_loop_factors` computes the same ``A, B`` without kernels, from the
Laplace-domain solution of the plant (:func:`~nrobust.hyperbolic.loops.laplace.general_solution`),
for any :class:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._validate import finite_real, positive_int
from ...errors import ParameterError
from ...quasipoly import QuasiPolynomial
from ..kernels.constant import DEFAULT_KERNEL_GRID, Kernels, check_kernel_grid, solve_kernels
from ..plants.general import GeneralHyperbolic2x2, as_general
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from ..plants.law import feedback_gain
from .delay_form import delay_kernel
from .laplace import general_solution

__all__ = ["feedback_factor", "laplace_loop_factors"]

Array = NDArray[np.float64]


def _column_integrals(weight: Array, table: Array) -> Array:
    """``int_{xi_j}^1 weight(x) table(x, xi_j) dx`` on the grid (Simpson, per column); zero for a zero weight
    (a gain without one of its integral terms: ``k`` alone has neither)."""
    n = weight.size
    if not np.any(weight):
        return np.zeros(n)
    from scipy.integrate import simpson  # lazily: scipy.integrate is slow to import

    h = 1.0 / (n - 1)
    out = np.zeros(n)
    for j in range(n - 1):
        out[j] = simpson(weight[j:] * table[j:, j], dx=h)
    return out


def feedback_factor(
    system: Hyperbolic2x2,
    k: float,
    g_u: Any,
    g_v: Any,
    kernel_grid: int = DEFAULT_KERNEL_GRID,
    kernels: Kernels | None = None,
) -> QuasiPolynomial:
    """``P(s) = k q e^{-tau s} + int_0^tau M(nu) e^{-nu s} dnu`` of the feedback (module notes).

    Parameters
    ----------
    system : Hyperbolic2x2
        The paper's plant (a general plant: through its normal form, see
        :meth:`~nrobust.hyperbolic.plants.general.NormalForm.feedback_to_normal`).
    k : float
        Gain on ``u(t, 1)``.
    g_u, g_v : float or callable
        Gains of the integral term on ``[0, 1]``.
    kernel_grid : int, default :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID`
        Grid of the inverse kernels ``L``; ``M`` is the cubic spline through the branches
        ``W_alpha, W_beta`` on that grid, the inner integrals by Simpson's rule, so ``M``
        carries the kernels' error (third order with the default odd grid).
    kernels : Kernels, optional
        The kernels of ``system`` already solved (``kernel_grid`` is then ignored).

    Returns
    -------
    QuasiPolynomial
        ``P``; the loop factor is ``B = -P``.
    """
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 (a general plant: use its normal form)", system)
    k = finite_real("k", k)
    gu, gv = feedback_gain("g_u", g_u), feedback_gain("g_v", g_v)
    grid_n = check_kernel_grid(kernel_grid)
    point = QuasiPolynomial([[k * system.q]], [system.tau])
    if gu.constant and gv.constant and float(gu.value) == 0.0 and float(gv.value) == 0.0 and system.uncoupled:
        return point
    if system.uncoupled:
        xi = np.linspace(0.0, 1.0, grid_n)
        w_alpha, w_beta = gu(xi), gv(xi)
    else:
        if kernels is None:
            kernels = solve_kernels(system, grid_n)
        elif kernels.system != system:
            raise ParameterError("kernels", "the kernels of the same system", kernels)
        xi = kernels.grid
        L = kernels.L
        wu, wv = gu(xi), gv(xi)
        w_alpha = k * L[0, 0, -1] + wu + _column_integrals(wu, L[0, 0]) + _column_integrals(wv, L[1, 0])
        w_beta = k * L[0, 1, -1] + wv + _column_integrals(wu, L[0, 1]) + _column_integrals(wv, L[1, 1])
    return point + QuasiPolynomial([], [], [delay_kernel(system, xi, w_alpha, w_beta)])


def laplace_loop_factors(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2, k: float, g_u: Any, g_v: Any, s: Any, steps: int | None = None
) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """``A(s)`` and ``B(s)`` of ``U = k u(L) + int_0^L g_u u + g_v v dx`` by the Laplace route.

    With ``[u; v](x, s)`` the solution of the transformed plant from ``[q; 1]``
    (:func:`~nrobust.hyperbolic.loops.laplace.general_solution`, no kernels),
    ``A = e^{-D(L)} e^{-s t_v} (v(L) - rho u(L))`` and
    ``B = -e^{-D(L)} e^{-s t_v} (k u(L) + int_0^L g_u u + g_v v dx)`` (Simpson's rule on the
    Magnus grid, made even). The factor ``e^{-D(L)}`` (``D = -int d/mu``) normalises the
    leading coefficient of ``A`` to 1, so the two agree with :func:`feedback_factor` and
    the delay form of the normal form.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant, in the coordinates of the gains.
    k : float
        Gain on ``u(t, L)``.
    g_u, g_v : float or callable
        Gains of the integral term on ``[0, L]``.
    s : complex or array_like
    steps : int, optional
        Magnus steps (default as :func:`~nrobust.hyperbolic.loops.laplace.general_solution`).

    Returns
    -------
    A, B : ndarray of complex, shaped like ``s``
    """
    plant = as_general(system)
    k = finite_real("k", k)
    gu, gv = feedback_gain("g_u", g_u, plant.length), feedback_gain("g_v", g_v, plant.length)
    s_arr = np.asarray(s, dtype=complex)
    if steps is None:
        top = float(np.max(np.abs(s_arr))) if s_arr.size else 0.0
        steps = max(200, int(np.ceil(5.0 * top * plant.tau / plant.time_unit)))
    steps = positive_int("steps", steps + steps % 2, maximum=10**6)
    x, zu, zv = general_solution(plant, s_arr, steps, nodes=True)
    t_v = plant.transport_times[1]
    shift = np.exp(-np.multiply.outer((t_v - plant.psi(x)) / plant.time_unit, s_arr))
    integrand = shift * (gu(x).reshape(-1, *([1] * s_arr.ndim)) * zu + gv(x).reshape(-1, *([1] * s_arr.ndim)) * zv)
    from scipy.integrate import simpson  # lazily: scipy.integrate is slow to import

    integral = simpson(integrand, x=x, axis=0)
    norm = float(np.exp(-plant.D(plant.length)))
    A = norm * (zv[-1] - plant.rho * zu[-1])
    B = -norm * (k * zu[-1] + integral)
    return A, B
