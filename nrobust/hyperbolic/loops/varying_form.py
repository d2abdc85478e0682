"""The delay form of a general plant whose speeds have a varying ratio, without a normal form.

When ``lam/mu`` varies, no change of the space variable makes both speeds constant
(``docs/theory.md``), so the paper's kernels do not apply. The characteristic function is
then computed from the Laplace-domain solution itself. Write ``T = phi + psi`` (the
round-trip time to ``x``), ``Ut = e^{-s psi(x)} u(x, s)``, ``Vt = e^{-s psi(x)} v(x, s)`` for
the solution from ``[u; v](0) = [q; 1]``; then (``docs/theory.md``, "Varying speed ratio")::

    Ut(x, s) = alpha(x) e^{-s T(x)} + int_0^{T(x)} f(x, nu) e^{-s nu} dnu,   alpha = q e^{A},
    Vt(x, s) = beta(x)              + int_0^{T(x)} g(x, nu) e^{-s nu} dnu,   beta  = e^{D},

where, in the coordinates ``theta = T(x)`` and ``nu`` on the triangle
``0 <= nu <= theta <= tau``, ``f`` is carried along the diagonals and ``g`` along the rows::

    f_theta + f_nu = p f + r g,   f(theta, 0)     = r beta,
    g_theta        = w f + e g,   g(theta, theta) = w alpha,

with ``p = a/(lam T')``, ``r = b/(lam T')``, ``w = -c/(mu T')``, ``e = -d/(mu T')`` at
``x(theta)`` and ``T' = 1/lam + 1/mu``. The trapezoidal rule on a uniform grid (a 2x2
solve per node) is second order; Richardson extrapolation of two grids makes it fourth
order. At ``x = L`` the characteristic function is
``e^{-D(L)} (Vt - rho Ut) = 1 - rho_q e^{-tau s} + int_0^tau N~(nu) e^{-nu s} dnu`` with
``N~ = e^{-D(L)} (g - rho f)``, and ``e^{-D(L)} Ut(L, s)`` gives the loop of a
proportional feedback ``U = k u(t, L)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._json import fields_dict
from ..._validate import positive_int
from ...errors import ParameterError
from ...quasipoly import DistributedDelay, QuasiPolynomial
from ..plants.general import GeneralHyperbolic2x2

__all__ = ["DEFAULT_CHARACTERISTIC_GRID", "VaryingDelayForm", "varying_delay_form"]

Array = NDArray[np.float64]
#: Default steps of the characteristic grid on ``[0, tau]`` (even: Richardson with half of it).
DEFAULT_CHARACTERISTIC_GRID = 400
# Work bound: the grid holds (steps + 1)^2 / 2 nodes of two unknowns.
_MAX_STEPS = 4000


@dataclass(frozen=True, eq=False)
class VaryingDelayForm:
    """The delay form of a :class:`GeneralHyperbolic2x2`, any speeds (times in ``time_unit``).

    Attributes
    ----------
    tau : float
        ``(int 1/lam + int 1/mu) / time_unit``.
    rho_q : float
        ``rho q e^{A(L) - D(L)}``.
    nu : ndarray
        Uniform nodes of ``[0, tau]``.
    N_tilde : ndarray
        ``e^{-D(L)} (g - rho f)`` at ``nu`` (extrapolated).
    U_tilde : ndarray
        ``e^{-D(L)} f`` at ``nu``: with ``e^{-D(L)} alpha(L) e^{-tau s}`` it is
        ``e^{-D(L)} e^{-s t_v} u(L, s)``.
    u_gain : float
        ``e^{-D(L)} alpha(L) = q e^{A(L) - D(L)}``.
    characteristic : QuasiPolynomial
        ``1 - rho_q e^{-tau s} + int N~ e^{-nu s} dnu`` (cubic spline ``N~``).
    """

    tau: float
    rho_q: float
    nu: Array
    N_tilde: Array
    U_tilde: Array
    u_gain: float
    characteristic: QuasiPolynomial

    def u_factor(self) -> QuasiPolynomial:
        """``e^{-D(L)} e^{-s t_v} u(L, s)`` as a quasi-polynomial."""
        return QuasiPolynomial(
            [[self.u_gain]], [self.tau], [DistributedDelay(self.nu, self.U_tilde, interpolation="cubic")]
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self, exclude=("characteristic",))


def _march(plant: GeneralHyperbolic2x2, steps: int) -> tuple[Array, Array, Array, float, float]:
    """``theta`` grid, ``f`` and ``g`` at ``theta = tau`` (all ``nu``), ``alpha(L)``, ``beta(L)``."""
    from scipy.interpolate import CubicHermiteSpline  # lazily: a slow import

    tables = plant.tables
    x_nodes = tables.x
    lam_n, mu_n = plant.coefficient("lam", x_nodes), plant.coefficient("mu", x_nodes)
    T_nodes = tables.phi(x_nodes) + tables.psi(x_nodes)
    x_of_T = CubicHermiteSpline(T_nodes, x_nodes, 1.0 / (1.0 / lam_n + 1.0 / mu_n))
    total = float(T_nodes[-1])
    theta = np.linspace(0.0, total, steps + 1)
    x = np.asarray(x_of_T(theta))
    x[-1] = plant.length
    lam, mu = plant.coefficient("lam", x), plant.coefficient("mu", x)
    dT = 1.0 / lam + 1.0 / mu
    p = plant.coefficient("a", x) / (lam * dT)
    r = plant.coefficient("b", x) / (lam * dT)
    w = -plant.coefficient("c", x) / (mu * dT)
    e = -plant.coefficient("d", x) / (mu * dT)
    alpha = plant.q * np.exp(plant.A(x))
    beta = np.exp(plant.D(x))
    h = total / steps
    k = 0.5 * h
    f = np.array([r[0] * beta[0]])
    g = np.array([w[0] * alpha[0]])
    for i in range(steps):
        j = i + 1  # new row has nodes 0..j
        f_new = np.empty(j + 1)
        g_new = np.empty(j + 1)
        # nu = 0: f given, g along its row (explicit in g).
        f_new[0] = r[j] * beta[j]
        g_new[0] = (g[0] + k * (w[i] * f[0] + e[i] * g[0] + w[j] * f_new[0])) / (1.0 - k * e[j])
        # top node nu = theta: g given, f along the diagonal from (i, i).
        g_new[j] = w[j] * alpha[j]
        f_new[j] = (f[i] + k * (p[i] * f[i] + r[i] * g[i] + r[j] * g_new[j])) / (1.0 - k * p[j])
        if j > 1:
            # interior 1 <= m <= i: f from (i, m - 1) along the diagonal, g from (i, m) along the row.
            fd, gd = f[:-1], g[:-1]  # (i, m - 1), m = 1..i
            fr, gr = f[1:], g[1:]  # (i, m)
            rhs_f = fd + k * (p[i] * fd + r[i] * gd)
            rhs_g = gr + k * (w[i] * fr + e[i] * gr)
            # [1 - k p_j, -k r_j; -k w_j, 1 - k e_j] [f; g] = [rhs_f; rhs_g]
            a11, a12, a21, a22 = 1.0 - k * p[j], -k * r[j], -k * w[j], 1.0 - k * e[j]
            det = a11 * a22 - a12 * a21
            f_new[1:j] = (a22 * rhs_f - a12 * rhs_g) / det
            g_new[1:j] = (a11 * rhs_g - a21 * rhs_f) / det
        f, g = f_new, g_new
    return theta, f, g, float(alpha[-1]), float(beta[-1])


def varying_delay_form(plant: GeneralHyperbolic2x2, steps: int = DEFAULT_CHARACTERISTIC_GRID) -> VaryingDelayForm:
    """The delay form of a general plant by the characteristic problem (module notes).

    Parameters
    ----------
    plant : GeneralHyperbolic2x2
        Any speeds (a constant ratio also works: a second route to the normal form's
        delay form).
    steps : int, default :data:`DEFAULT_CHARACTERISTIC_GRID`
        Even number of steps on ``[0, tau]``, at most 4000 (checked first); the result is
        the Richardson extrapolation of ``steps`` and ``steps / 2`` (fourth order,
        measured in ``tests/test_general.py``), tabulated on ``steps / 2 + 1`` nodes.

    Returns
    -------
    VaryingDelayForm
    """
    if not isinstance(plant, GeneralHyperbolic2x2):
        raise ParameterError("plant", "a GeneralHyperbolic2x2", plant)
    steps = positive_int("steps", steps, 4, _MAX_STEPS)
    if steps % 2:
        raise ParameterError("steps", "even (the coarse grid of the extrapolation has half of them)", steps)
    theta, f_fine, g_fine, alpha_L, beta_L = _march(plant, steps)
    _, f_coarse, g_coarse, _, _ = _march(plant, steps // 2)
    f = (4.0 * f_fine[::2] - f_coarse) / 3.0
    g = (4.0 * g_fine[::2] - g_coarse) / 3.0
    nu = theta[::2] / plant.time_unit
    scale = 1.0 / beta_L  # e^{-D(L)}
    # densities in nu: the measure is in the equations' time; per unit of time_unit it scales by T
    N_tilde = scale * (g - plant.rho * f) * plant.time_unit
    U_tilde = scale * f * plant.time_unit
    tau = float(nu[-1])
    rho_q = plant.rho * alpha_L * scale
    characteristic = QuasiPolynomial(
        [[1.0], [-rho_q]], [0.0, tau], [DistributedDelay(nu, N_tilde, interpolation="cubic")]
    )
    return VaryingDelayForm(tau, rho_q, nu, N_tilde, U_tilde, alpha_L * scale, characteristic)
