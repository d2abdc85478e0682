"""The Rouché delay bound of the paper's plants (Theorem 4's proof, made quantitative).

For the reflection-preserving control law ``U_BS2(K)`` (eq. (53)) the loop with a
delay ``delta`` has the characteristic function (eq. (60))

    F(s) = 1 - q rho e^{-tau s} + K q e^{-(tau + delta) s} + I(s, delta),
    I(s, delta) = int_0^tau N~(nu) (e^{-nu s} - e^{-(nu + delta) s}) dnu,

(the paper prints ``-I``; the sign does not enter the bound). On ``Re s >= 0``,
``|F(s)| >= 1 - |q rho| - |K q| - |I(s, delta)|`` and ``|I(s, delta)| <= omega(delta)``,
the L1 modulus of continuity of ``N~`` (:func:`nrobust.bounds.l1_modulus`). Every ``delta``
with ``omega(delta) < 1 - |q rho| - |K q|`` is admissible. ``N~`` is a cubic spline, so
``omega`` is bounded by that of its linear interpolant (closed form) plus twice their
L1 distance (:func:`nrobust.bounds.delay_bound_from_kernel`).
"""

from __future__ import annotations

import dataclasses
import math
from fractions import Fraction

from ..._validate import renamed_keywords
from ...bounds import RoucheDelayBound, delay_bound_from_kernel
from ...errors import ParameterError
from ...quasipoly import DistributedDelay
from ..kernels.constant import DEFAULT_KERNEL_GRID, check_kernel_grid
from ..loops.controllers import Controller, FiniteTimeController, ReflectionController, cached_varying_delay_form
from ..loops.delay_form import delay_form
from ..loops.exact_form import exact_form, has_exact_form
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2

__all__ = ["rouche_delay_bound"]

#: Nodes of the linearised closed-form ``N~`` whose L1 modulus bounds ``|I(s, delta)|``.
_LINEAR_POINTS = 1001


@renamed_keywords(n="kernel_grid")
def rouche_delay_bound(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    controller: Controller,
    kernel_grid: int | None = None,
    rigorous: bool = False,
) -> RoucheDelayBound:
    """Guaranteed delay range of ``U_BS2(K)`` (or ``U_BS``, ``K = rho``), Theorem 4's proof.

    On ``Re s >= 0`` the characteristic function of eq. (60) satisfies
    ``|F(s)| >= 1 - |q rho| - |K q| - |I(s, delta)|`` with
    ``|I(s, delta)| <= omega(delta)`` (:func:`nrobust.bounds.l1_modulus` of ``N~``). Every delay in
    ``[0, delta_0]`` with ``sup omega < epsilon_0 = 1 - |q rho| - |K q|`` keeps ``F``
    zero-free on ``Re s >= 0``; the strict inequality extends to ``Re s >= -epsilon``
    for some ``epsilon > 0`` by continuity, so the loop is exponentially stable.
    ``delta_0`` is a lower bound of the delay margin (:func:`nrobust.margins.delay_margin`).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant (a :class:`~nrobust.hyperbolic.TransportSystem` has ``N~ = 0`` and ``delta_0 = inf``
        whenever ``epsilon_0 > 0``). A general plant is taken through its normal form; with a
        varying ``lam/mu`` only U_BS applies (U_BS2(K) needs the normal form), with
        ``epsilon_0 = 1 - 2 |rho_q|`` and ``N~`` of the characteristic route
        (:func:`~nrobust.hyperbolic.loops.varying_form.varying_delay_form`, the same ``N~`` as its loop
        factors; ``kernel_grid`` is not used): its U_BS loop
        ``1 - rho_q e^{-tau s} + rho_q e^{-(tau + delta) s} + I(s, delta)`` has the form above.
    controller : ReflectionController or FiniteTimeController
        ``U_BS2(K)``, or ``U_BS`` (the case ``K = rho``).
    kernel_grid : int, optional
        Kernel grid of the delay form (formerly ``n``, a deprecated alias); by default ``N~``
        in closed form for constant couplings (:mod:`~nrobust.hyperbolic.loops.exact_form`,
        its proven error bound included in the modulus), else
        :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID` points.
    rigorous : bool, default False
        Prove ``delta_0`` in exact rational arithmetic: ``epsilon_0`` from the stored ``q``,
        ``rho``, ``K`` (rounded down), then :func:`nrobust.bounds.delay_bound_from_kernel` with
        ``rigorous=True``; for the PDE itself on the exact route, for ``N~`` as represented
        (the cubic spline on the kernel grid) otherwise.

    Returns
    -------
    RoucheDelayBound
    """
    grid = None if kernel_grid is None else check_kernel_grid(kernel_grid)
    closed: DistributedDelay | None = None
    form = None
    if grid is None and has_exact_form(system):  # N~ in closed form: a bound for the PDE itself
        form = exact_form(system)
        q, rho, closed = form.q, form.rho, form.N_tilde
    else:
        if isinstance(system, GeneralHyperbolic2x2):
            if not system.constant_ratio:
                return _varying_bound(system, controller, rigorous)
            system = system.normal_form().system
        if not isinstance(system, Hyperbolic2x2):
            raise ParameterError("system", "a Hyperbolic2x2, TransportSystem or GeneralHyperbolic2x2", system)
        q, rho = float(system.q), float(system.rho)
    if isinstance(controller, ReflectionController):
        K = float(controller.K)
    elif isinstance(controller, FiniteTimeController):
        K = rho
    else:
        raise ParameterError("controller", "a ReflectionController or FiniteTimeController", controller)
    eps0 = 1.0 - abs(q * rho) - abs(K * q)
    if rigorous:  # the float at or below the exact 1 - |q rho| - |K q|
        if form is None:
            rho_q, k_q = abs(Fraction(q) * Fraction(rho)), abs(Fraction(K) * Fraction(q))
        else:  # the plant's rho q and q (times e^{sigma_0 tau}, e^{sigma_0 tau / 2}) within the exact form's radii
            rho_q = abs(Fraction(form.rho_q)) + Fraction(form.rho_q_radius)
            k_q = abs(Fraction(K)) * (abs(Fraction(q)) + Fraction(form.q_radius))
            if isinstance(controller, FiniteTimeController):  # U_BS: K q = rho q
                k_q = rho_q
        eps0 = _epsilon_0(1 - rho_q - k_q, True)
    if closed is not None:
        # the L1 modulus is sharp for a fine linear kernel: the closed form's pieces, linearised
        N = closed.linearized(_LINEAR_POINTS)
    elif (grid is None and has_exact_form(system)) or getattr(system, "uncoupled", False):
        N = None  # N~ = 0
    else:
        N = delay_form(system, DEFAULT_KERNEL_GRID if grid is None else grid).N_tilde
    bound = delay_bound_from_kernel(N, eps0, K, rigorous=rigorous)
    if rigorous and not bound.rigorous:  # N~ = 0 or epsilon_0 <= 0: exact comparisons of the stored numbers
        bound = dataclasses.replace(bound, rigorous=True)
    return bound


def _epsilon_0(exact: Fraction, rigorous: bool) -> float:
    """``float(exact)``, rounded down when ``rigorous`` (the bound must not exceed the exact value)."""
    eps0 = float(exact)
    if rigorous and Fraction(eps0) > exact:
        eps0 = math.nextafter(eps0, -math.inf)
    return eps0


def _varying_bound(system: GeneralHyperbolic2x2, controller: Controller, rigorous: bool) -> RoucheDelayBound:
    """The Rouché bound of U_BS on a plant with a varying ``lam/mu`` (characteristic route)."""
    if not isinstance(controller, FiniteTimeController):
        raise ParameterError(
            "controller",
            "a FiniteTimeController on a plant with a varying lam/mu (U_BS2(K) is defined on the normal form, "
            "which needs a constant lam/mu)",
            controller,
        )
    form = cached_varying_delay_form(system)
    eps0 = _epsilon_0(1 - 2 * abs(Fraction(float(form.rho_q))), rigorous)
    bound = delay_bound_from_kernel(form.characteristic.distributed[0], eps0, system.rho, rigorous=rigorous)
    if rigorous and not bound.rigorous:  # epsilon_0 <= 0: exact comparisons of the stored numbers
        bound = dataclasses.replace(bound, rigorous=True)
    return bound
