"""The neutral distributed-delay equation equivalent to the plant, eq. (39).

Through the Volterra transformation (22)-(23), the plant (18)-(20) becomes the
target system (32)-(34), and the method of characteristics gives::

    beta(t, 1) = rho q beta(t - tau, 1) + U(t) - int_0^tau N~(nu) beta(t - nu, 1) dnu,

with ``N^alpha``, ``N^beta`` of eqs. (35)-(36) and ``N~`` of eq. (40)
corrected by the factor ``q`` the paper drops::

    N~(nu) = lam q N^alpha(lam nu - lam/mu)  on [1/mu, tau],
    N~(nu) = mu N^beta(1 - mu nu)            on [0, 1/mu].

The factor comes from eq. (37), ``alpha(t, x) = q beta(t - x/lam - 1/mu, 1)``,
which the paper substitutes into (34) without its ``q``; the corrected form is
the one whose Laplace transform equals the kernel-free boundary function
(:func:`nrobust.hyperbolic.boundary_function`), and the two differ unless ``q = 1``.
Its open-loop characteristic function is
``1 - rho q e^{-tau s} + int_0^tau N~(nu) e^{-nu s} dnu``; the open-loop roots of the
principal part ``1 - rho q e^{-tau s}`` lie on the vertical line
``Re s = ln|rho q| / tau``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..._json import fields_dict
from ..._validate import renamed_keywords
from ...errors import ParameterError
from ...quasipoly import DistributedDelay, QuasiPolynomial
from ..kernels.constant import DEFAULT_KERNEL_GRID, Kernels, check_kernel_grid, solve_kernels
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2

__all__ = ["DelayForm", "delay_form"]


@dataclass(frozen=True, repr=False, eq=False)
class DelayForm:
    """Delay form (39) of a :class:`Hyperbolic2x2`.

    Attributes
    ----------
    system : Hyperbolic2x2
        The plant.
    tau : float
        ``1/lam + 1/mu``, eq. (5).
    rho_q : float
        Gain of the point delay ``tau``.
    xi : ndarray
        Grid of ``[0, 1]`` on which ``N_alpha`` and ``N_beta`` are tabulated.
    N_alpha, N_beta : ndarray
        ``N^alpha(xi) = L^{beta alpha}(1, xi) - rho L^{alpha alpha}(1, xi)`` and
        ``N^beta(xi) = L^{beta beta}(1, xi) - rho L^{alpha beta}(1, xi)``,
        eqs. (35)-(36), on ``xi``.
    N_tilde : DistributedDelay
        ``N~`` of eq. (40), with the factor ``q`` on the ``N^alpha`` branch (see
        the module notes), on ``[0, tau]``, a cubic spline on each side of the jump at
        ``nu = 1/mu`` (a repeated node); identically zero for an uncoupled system.
    characteristic : QuasiPolynomial
        ``1 - rho q e^{-tau s} + int_0^tau N~(nu) e^{-nu s} dnu``, the denominator of the
        open-loop transfer function ``H_1``.
    """

    system: Hyperbolic2x2
    tau: float
    rho_q: float
    xi: np.ndarray
    N_alpha: np.ndarray
    N_beta: np.ndarray
    N_tilde: DistributedDelay
    characteristic: QuasiPolynomial

    def N_alpha_at(self, xi: Any) -> np.ndarray:
        """``N^alpha`` at arrays of ``xi`` in ``[0, 1]`` (linear interpolation)."""
        return np.interp(_unit_interval("xi", xi), self.xi, self.N_alpha)

    def N_beta_at(self, xi: Any) -> np.ndarray:
        """``N^beta`` at arrays of ``xi`` in ``[0, 1]`` (linear interpolation)."""
        return np.interp(_unit_interval("xi", xi), self.xi, self.N_beta)

    def N_tilde_at(self, nu: Any) -> np.ndarray:
        """``N~(nu)`` of eq. (40) (with the factor ``q``) at arrays of ``nu`` in ``[0, tau]``.

        At the jump ``nu = 1/mu`` the value from the right (the ``N^alpha`` branch) is
        returned.
        """
        nu = np.asarray(nu, dtype=float)
        if np.any((nu < 0.0) | (nu > self.tau * (1 + 1e-12))) or not np.all(np.isfinite(nu)):
            raise ParameterError("nu", f"in [0, tau] = [0, {self.tau:.6g}]", nu)
        lam, mu = self.system.lam, self.system.mu
        beta_part = mu * np.interp(np.clip(1.0 - mu * nu, 0.0, 1.0), self.xi, self.N_beta)
        alpha_part = lam * self.system.q * np.interp(np.clip(lam * nu - lam / mu, 0.0, 1.0), self.xi, self.N_alpha)
        return np.where(nu < 1.0 / mu, beta_part, alpha_part)

    def __repr__(self) -> str:
        return (
            f"DelayForm(system={self.system!r}, tau={self.tau:.6g}, rho_q={self.rho_q:.6g}, "
            f"n={self.xi.size}, N_tilde={self.N_tilde!r})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description: the system, ``tau``, ``rho q`` and the tabulated kernels."""
        return {"type": "DelayForm", **fields_dict(self, exclude=("characteristic",))}


def _unit_interval(name: str, x: Any) -> np.ndarray:
    arr = np.asarray(x, dtype=float)
    if not np.all(np.isfinite(arr)) or np.any((arr < 0.0) | (arr > 1.0)):
        raise ParameterError(name, "in [0, 1]", x)
    return arr


def delay_kernel(
    system: Hyperbolic2x2, xi: np.ndarray, alpha_branch: np.ndarray, beta_branch: np.ndarray
) -> DistributedDelay:
    """A kernel of the delay axis ``nu`` in ``[0, tau]`` from its two branches on ``[0, 1]``.

    The change of variables of eq. (40): with ``f_alpha`` and ``f_beta`` tabulated
    on the grid ``xi`` of ``[0, 1]``::

        K(nu) = mu f_beta(1 - mu nu)                on [0, 1/mu]   (nodes (1 - xi)/mu),
        K(nu) = lam q f_alpha(lam nu - lam/mu)      on [1/mu, tau] (nodes 1/mu + xi/lam),

    as a cubic-spline :class:`DistributedDelay`; the node ``1/mu`` appears twice, carrying
    the jump. ``f_alpha = N^alpha``, ``f_beta = N^beta`` give ``N~`` (with the factor ``q``,
    see the module notes); ``f_alpha = L^{beta alpha}(1, .)``, ``f_beta = L^{beta beta}(1, .)``
    give the kernel ``M~`` of the output map (:func:`nrobust.hyperbolic.loops.output_map`). The
    spline interpolation is fourth order, so the error of the kernel is that of the
    tabulated branches (``docs/numerics_kernels.md``), not that of the interpolation.

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant (``lam``, ``mu``, ``q``).
    xi : ndarray, shape (n,)
        Increasing grid of ``[0, 1]``.
    alpha_branch, beta_branch : ndarray, shape (n,)
        ``f_alpha`` and ``f_beta`` on ``xi``.

    Returns
    -------
    DistributedDelay
    """
    lam, mu = system.lam, system.mu
    nodes_beta = (1.0 - xi[::-1]) / mu
    nodes_alpha = 1.0 / mu + xi / lam
    nodes = np.concatenate([nodes_beta, nodes_alpha])
    values = np.concatenate([mu * beta_branch[::-1], lam * system.q * alpha_branch])
    return DistributedDelay(nodes, values, interpolation="cubic")


@renamed_keywords(n="kernel_grid")
def delay_form(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2, kernel_grid: int = DEFAULT_KERNEL_GRID, kernels: Kernels | None = None
) -> DelayForm:
    """Delay form (39) of the plant, with ``N~`` of eq. (40).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant, eqs. (18)-(20); a general plant is replaced by its normal form
        (:meth:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2.normal_form`).
    kernel_grid : int, default :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID`
        Kernel grid points (see :func:`~nrobust.hyperbolic.solve_kernels`); ignored when
        ``kernels`` is given. (Formerly ``n``, a deprecated alias.)
    kernels : Kernels, optional
        Kernels of ``system`` already solved.

    Returns
    -------
    DelayForm
        ``tau``, ``rho q``, ``N^alpha``, ``N^beta``, ``N~`` and the characteristic
        quasi-polynomial. The spline interpolant of ``N~`` is integrated exactly, so the
        error of its Laplace transform is uniform in ``s`` and set by the kernels
        (third order with the default extrapolation, ``docs/numerics_kernels.md``).
    """
    kernel_grid = check_kernel_grid(kernel_grid)
    if isinstance(system, GeneralHyperbolic2x2):
        system = system.normal_form().system
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or GeneralHyperbolic2x2", system)
    if kernels is not None and kernels.system is not system and kernels.system != system:
        raise ParameterError("kernels", "the kernels of the same system", kernels)
    rho, tau = system.rho, system.tau
    coefs = [[1.0], [-system.rho_q]]
    delays = [0.0, tau]
    if system.uncoupled:
        xi = np.linspace(0.0, 1.0, 2)
        zero = np.zeros(2)
        N_tilde = DistributedDelay([0.0, tau], [0.0, 0.0])
        return DelayForm(system, tau, system.rho_q, xi, zero, zero, N_tilde, QuasiPolynomial(coefs, delays))
    if kernels is None:
        kernels = solve_kernels(system, kernel_grid)
    L1 = kernels.L[:, :, -1, :]
    N_alpha = L1[1, 0] - rho * L1[0, 0]
    N_beta = L1[1, 1] - rho * L1[0, 1]
    N_tilde = delay_kernel(system, kernels.grid, N_alpha, N_beta)
    characteristic = QuasiPolynomial(coefs, delays, distributed=(N_tilde,))
    return DelayForm(system, tau, system.rho_q, kernels.grid, N_alpha, N_beta, N_tilde, characteristic)
