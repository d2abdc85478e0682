"""Physical front ends: open channels (Saint-Venant), ARZ traffic, and characteristic forms.

Each builds a :class:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2` in Riemann
(characteristic) coordinates from the physical parameters, with the quantities a user
checks the model by (steady profile, depths, Froude number, characteristic speeds) and the
gain from the physical actuator to the Riemann boundary input ``U``. The derivations are in
``docs/theory.md`` (section "Physical front ends").

- :func:`from_riemann`: ``xi_t + diag(lam_1, lam_2) xi_x = M(x) xi`` with
  ``lam_1 > 0 > lam_2``, the usual characteristic form.
- :func:`saint_venant`: a rectangular or trapezoidal open channel (bottom width, side
  slope, bed slope, Manning or Chezy friction, discharge) linearised about its steady
  (backwater) profile, fed at a constant discharge upstream, controlled downstream
  through the discharge (a gate) or the crest of an overflow weir.
- :func:`arz`: the Aw-Rascle-Zhang traffic model linearised about a uniform congested
  equilibrium, constant inflow upstream, outflow actuated downstream (ramp metering),
  as in Yu and Krstic, "Traffic congestion control for Aw-Rascle-Zhang model",
  Automatica 100 (2019) 38-51.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._json import fields_dict
from ..._validate import finite_real, positive
from ...errors import ParameterError
from .general import Coefficient, GeneralHyperbolic2x2, coefficient_profile

__all__ = ["ARZ", "GRAVITY", "SaintVenant", "arz", "from_riemann", "saint_venant"]

Array = NDArray[np.float64]
#: Gravitational acceleration (m/s^2) used by :func:`saint_venant`.
GRAVITY = 9.81


@dataclass(frozen=True)
class _Negated:
    """``x -> -f(x)`` for a speed given with its sign (picklable when ``f`` is)."""

    f: Any

    def __call__(self, x: Any) -> Array:
        return -np.asarray(self.f(x), dtype=float)


def from_riemann(
    lam_1: Coefficient,
    lam_2: Coefficient,
    source: Any,
    q: float,
    rho: float,
    length: float = 1.0,
    time_unit: float = 1.0,
) -> GeneralHyperbolic2x2:
    """A plant given in characteristic form.

    ``xi_t + diag(lam_1, lam_2) xi_x = M(x) xi`` on ``[0, L]`` with ``lam_1 > 0 > lam_2``,
    ``xi_1(t, 0) = q xi_2(t, 0)`` and ``xi_2(t, L) = rho xi_1(t, L) + U(t)``: the general
    plant with ``u = xi_1``, ``v = xi_2``, ``lam = lam_1``, ``mu = -lam_2`` and
    ``[[a, b], [c, d]] = M``.

    Parameters
    ----------
    lam_1, lam_2 : float, callable or (x, values)
        Characteristic speeds, ``lam_1 > 0`` and ``lam_2 < 0`` on ``[0, L]``.
    source : 2x2 nested sequence
        ``M``; each entry a number, a callable or samples.
    q, rho : float
        Boundary gains.
    length : float, default 1
    time_unit : float, default 1
        Unit of time of the analyses (see :class:`GeneralHyperbolic2x2`).

    Raises
    ------
    ParameterError
        ``lam_2`` not negative (named ``lam_2``), ``source`` not 2x2, or any error of
        :class:`GeneralHyperbolic2x2`.
    """
    length = positive("length", length)
    if callable(lam_2):
        mu: Coefficient = _Negated(lam_2)
    elif isinstance(lam_2, (tuple, list)) and len(lam_2) == 2:
        mu = (lam_2[0], -np.asarray(lam_2[1], dtype=float))
    else:
        mu = -finite_real("lam_2", lam_2)
    values = coefficient_profile("lam_2", mu, length)(np.linspace(0.0, length, 257))
    if not np.all(values > 0):
        raise ParameterError("lam_2", "negative on [0, L] (the leftward characteristic speed)", lam_2)
    try:
        (a, b), (c, d) = source
    except (TypeError, ValueError):
        raise ParameterError("source", "a 2x2 nested sequence [[a, b], [c, d]]", source) from None
    return GeneralHyperbolic2x2(lam_1, mu, a, b, c, d, q, rho, length, time_unit)


# ============================================================================ Saint-Venant
@dataclass(frozen=True, eq=False)
class SaintVenant:
    """A linearised open channel and the numbers that identify it.

    Attributes
    ----------
    system : GeneralHyperbolic2x2
        The plant in Riemann coordinates ``xi_1 = w + (g/C) h`` (downstream wave,
        ``lam = V + C``) and ``xi_2 = w - (g/C) h`` (upstream wave, ``mu = C - V``), with
        ``h, w`` the depth and velocity perturbations and ``C = sqrt(g A/T)`` the celerity
        (``sqrt(g H)`` in a rectangular channel).
    x, depth, velocity : ndarray
        The steady profile on 201 points of ``[0, L]``.
    normal_depth, critical_depth : float
        Depth of uniform flow (the friction slope equals the bed slope) and depth at
        which the Froude number is 1 (``Q^2 T = g A^3``; ``(q^2/g)^{1/3}``, ``q = Q/B``, in
        a rectangular channel).
    froude : ndarray
        ``V / C`` along the steady profile.
    actuator_gain : float
        ``U = actuator_gain * (physical input)`` at ``x = L``: the discharge perturbation
        (m^3/s) for a gate, the crest-height perturbation (m) for a weir.
    transport_delays : tuple of float
        ``(int_0^L dx/(V + C), int_0^L dx/(C - V))`` in seconds: the times a wave takes
        downstream (``tau_1``, the delay of the inflow on the downstream level) and upstream
        (``tau_2``).
    backwater_area : float
        ``A_d = dVol/dH(L)`` at constant discharge (m^2): the storage the downstream level
        integrates, ``H(L)' = (Q(0) - Q(L))/A_d`` at low frequency (docs/theory.md).
    """

    system: GeneralHyperbolic2x2
    x: Array
    depth: Array
    velocity: Array
    normal_depth: float
    critical_depth: float
    froude: Array
    actuator_gain: float
    transport_delays: tuple[float, float]
    backwater_area: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


@dataclass(frozen=True)
class _Channel:
    """A prismatic trapezoidal channel (bottom width, side slope, friction) carrying ``Q``.

    Area ``A = (B + m H) H``, top width ``T = B + 2 m H``, wetted perimeter
    ``P = B + 2 H sqrt(1 + m^2)``; ``m = 0`` is the rectangular channel.
    """

    width: float
    side_slope: float
    friction: str
    coefficient: float
    discharge: float
    bed_slope: float

    def area(self, H: Any) -> Array:
        return (self.width + self.side_slope * H) * H

    def top(self, H: Any) -> Array:
        return self.width + 2.0 * self.side_slope * H

    def depth(self, H: Any) -> Array:
        """Hydraulic depth ``D = A/T`` (``C^2 = g D``)."""
        return self.area(H) / self.top(H)

    def velocity(self, H: Any) -> Array:
        return self.discharge / self.area(H)

    def slope(self, H: Any, V: Any) -> tuple[Array, Array, Array]:
        """``(Sf, dSf/dH, dSf/dV)`` (Manning ``n^2 V^2 / R^{4/3}``, Chezy ``V^2 / (C^2 R)``)."""
        A, dP = self.area(H), 2.0 * np.sqrt(1.0 + self.side_slope**2)
        P = self.width + dP * H
        R = A / P
        dR = (self.top(H) * P - A * dP) / P**2
        if self.friction == "manning":
            Sf = self.coefficient**2 * V * np.abs(V) / R ** (4.0 / 3.0)
            return Sf, -4.0 / 3.0 * Sf * dR / R, 2.0 * Sf / V
        Sf = V * np.abs(V) / (self.coefficient**2 * R)
        return Sf, -Sf * dR / R, 2.0 * Sf / V

    def froude2(self, H: Any) -> Array:
        """``F^2 = V^2/(g D) = Q^2 T/(g A^3)``."""
        return self.velocity(H) ** 2 / (GRAVITY * self.depth(H))

    def rise(self, H: Any) -> Array:
        """``H'`` of the backwater ODE ``H' = (S_0 - S_f)/(1 - F^2)``."""
        return (self.bed_slope - self.slope(H, self.velocity(H))[0]) / (1.0 - self.froude2(H))

    def rise_derivative(self, H: Any) -> Array:
        """``d(H')/dH`` at constant discharge: the variational equation of the backwater ODE."""
        V, F2 = self.velocity(H), self.froude2(H)
        Sf, Sf_H, Sf_V = self.slope(H, V)
        dSf = Sf_H - Sf_V * V / self.depth(H)  # dV/dH = -V T/A = -V/D
        dF2 = F2 * (2.0 * self.side_slope / self.top(H) - 3.0 / self.depth(H))
        return (-dSf * (1.0 - F2) + (self.bed_slope - Sf) * dF2) / (1.0 - F2) ** 2


@dataclass(frozen=True)
class _Profile:
    """The steady depth ``H(x)`` (dense output of the backwater ODE, or a constant)."""

    depth: float
    solution: Any = None

    def __call__(self, x: Any) -> Array:
        arr = np.asarray(x, dtype=float)
        if self.solution is None:
            return np.full(arr.shape, self.depth)
        return np.asarray(self.solution(arr.ravel())[0]).reshape(arr.shape)


@dataclass(frozen=True)
class _SVCoefficient:
    """One entry of the source matrix of the linearised channel at ``x`` (picklable)."""

    channel: _Channel
    profile: _Profile
    entry: tuple[int, int]

    def __call__(self, x: Any) -> Array:
        return _sv_matrix(self.channel, self.profile, x)[self.entry]


def _sv_matrix(channel: _Channel, profile: _Profile, x: Any) -> Array:
    """``M(x)`` of ``xi_t + diag(V + C, V - C) xi_x = M xi`` (docs/theory.md)."""
    g = GRAVITY
    H = profile(x)
    D, V = channel.depth(H), channel.velocity(H)
    c = np.sqrt(g * D)
    Sf, Sf_H, Sf_V = channel.slope(H, V)
    dH = (channel.bed_slope - Sf) / (1.0 - V**2 / (g * D))  # the backwater ODE
    dV = -V * dH / D
    D_H = 1.0 - 2.0 * channel.side_slope * channel.area(H) / channel.top(H) ** 2  # dD/dH
    G = g / c
    dG = -0.5 * G * D_H * dH / D  # (g/C)' with C = sqrt(g D(H))
    lam1, lam2 = V + c, V - c
    alpha1 = lam1 * dG - g * Sf_H - G * D_H * dV
    beta1 = -dV - g * Sf_V - G * dH
    alpha2 = -lam2 * dG - g * Sf_H + G * D_H * dV
    beta2 = -dV - g * Sf_V + G * dH
    return np.array(
        [
            [alpha1 / (2 * G) + beta1 / 2, -alpha1 / (2 * G) + beta1 / 2],
            [alpha2 / (2 * G) + beta2 / 2, -alpha2 / (2 * G) + beta2 / 2],
        ]
    )


@dataclass(frozen=True)
class _Speed:
    """``V + C`` (sign +1) or ``C - V`` (sign -1) along the steady profile."""

    channel: _Channel
    profile: _Profile
    sign: float

    def __call__(self, x: Any) -> Array:
        H = self.profile(x)
        return np.sqrt(GRAVITY * self.channel.depth(H)) + self.sign * self.channel.velocity(H)


def saint_venant(
    length: float,
    width: float,
    slope: float,
    discharge: float,
    *,
    side_slope: float = 0.0,
    manning: float | None = None,
    chezy: float | None = None,
    downstream: str = "gate",
    downstream_depth: float | None = None,
    weir_height: float | None = None,
    weir_coefficient: float = 1.7,
    time_unit: float = 1.0,
) -> SaintVenant:
    """An open channel (rectangular or trapezoidal) linearised about its steady flow.

    The Saint-Venant equations of a prismatic channel, ``A(H)_t + Q_x = 0`` and
    ``V_t + V V_x + g H_x = g (S_0 - S_f)``, with the trapezoidal section of bottom width
    ``B`` and side slope ``m`` (``A = (B + m H) H``, top width ``T = B + 2 m H``, wetted
    perimeter ``P = B + 2 H sqrt(1 + m^2)``; ``m = 0``: rectangular) and ``S_f`` from
    Manning (``n^2 V^2 / R^{4/3}``) or Chezy (``V^2 / (C^2 R)``), ``R = A/P``. The
    steady profile solves the backwater ODE ``H' = (S_0 - S_f)/(1 - F^2)``,
    ``F^2 = Q^2 T/(g A^3)``, upstream from ``x = L`` (DOP853, ``rtol = 1e-11``); the flow
    must stay subcritical (``F < 1``). The characteristic speeds are ``V +- C``,
    ``C = sqrt(g A/T)``. Upstream the discharge is constant (``Q(t, 0) = Q``:
    ``q = -(C - V)/(C + V)`` at 0).

    Parameters
    ----------
    length, width : float
        ``L`` and the bottom width ``B`` (m), positive.
    slope : float
        Bed slope ``S_0 > 0``.
    discharge : float
        Steady discharge ``Q > 0`` (m^3/s).
    side_slope : float, default 0
        ``m >= 0``, horizontal over vertical (1.5: the bank rises 1 m over 1.5 m); 0 is
        the rectangular channel.
    manning, chezy : float
        Exactly one: Manning's ``n`` (s/m^{1/3}) or Chezy's ``C`` (m^{1/2}/s).
    downstream : {"gate", "weir"}
        ``"gate"``: the control is the discharge at ``x = L``; the steady depth there is
        ``downstream_depth`` (default: the normal depth, i.e. uniform flow).
        ``"weir"``: free overflow ``Q = C_w B (H - p)^{3/2}`` over a crest as wide as the
        bottom, the control is the crest height ``p``; the steady depth at ``L`` follows
        from the weir law.
    downstream_depth : float, optional
        Steady depth at ``x = L`` for a gate (m).
    weir_height, weir_coefficient : float
        Crest height ``p`` (m, required for a weir) and ``C_w`` (m^{1/2}/s).
    time_unit : float, default 1
        Unit of time of the analyses in seconds (60: delays and margins in minutes; see
        :class:`GeneralHyperbolic2x2`).

    Returns
    -------
    SaintVenant

    Raises
    ------
    ParameterError
        A parameter out of range (named), both or neither friction laws, a supercritical
        or drying steady profile.
    """
    from scipy.integrate import solve_ivp  # lazily: slow imports
    from scipy.optimize import brentq

    L, B = positive("length", length), positive("width", width)
    S0, Q = positive("slope", slope), positive("discharge", discharge)
    m = finite_real("side_slope", side_slope)
    if m < 0:
        raise ParameterError("side_slope", ">= 0 (horizontal over vertical; 0: rectangular)", side_slope)
    if (manning is None) == (chezy is None):
        raise ParameterError("manning", "exactly one of manning and chezy given", (manning, chezy))
    channel = (
        _Channel(B, m, "manning", positive("manning", manning), Q, S0)
        if manning is not None
        else _Channel(B, m, "chezy", positive("chezy", chezy), Q, S0)
    )
    qs = Q / B
    g = GRAVITY
    if m == 0.0:
        critical = float((qs * qs / g) ** (1.0 / 3.0))
    else:  # F = 1; F^2 decreases from +inf to 0 as H grows, and F^2 < 1 at (q^2/g)^{1/3}
        top_c = float((qs * qs / g) ** (1.0 / 3.0))
        critical = float(brentq(lambda H: float(channel.froude2(H)) - 1.0, 1e-9 * top_c, top_c, xtol=1e-15))

    def excess(H: float) -> float:
        return float(channel.slope(H, channel.velocity(H))[0]) - S0

    top = max(critical, 1.0)
    while excess(top) > 0:
        top *= 2.0
        if top > 1e6:
            raise ParameterError("discharge", "a flow with a finite normal depth", Q)
    normal = float(brentq(excess, 1e-9 * top, top, xtol=1e-14, rtol=1e-15))
    if downstream == "gate":
        end = normal if downstream_depth is None else positive("downstream_depth", downstream_depth)
        if weir_height is not None:
            raise ParameterError("weir_height", "left out for a gate", weir_height)
    elif downstream == "weir":
        if weir_height is None:
            raise ParameterError("weir_height", "given (the crest height p >= 0, m) for a weir", None)
        p = finite_real("weir_height", weir_height)
        if p < 0:
            raise ParameterError("weir_height", ">= 0", weir_height)
        cw = positive("weir_coefficient", weir_coefficient)
        end = p + (qs / cw) ** (2.0 / 3.0)
    else:
        raise ParameterError("downstream", "'gate' or 'weir'", downstream)
    if end <= critical:
        raise ParameterError(
            "downstream_depth" if downstream == "gate" else "weir_height",
            f"a subcritical depth at x = L (above the critical depth {critical:.6g} m)",
            end,
        )
    if abs(end - normal) <= 1e-12 * normal:
        profile = _Profile(normal)
        k = float(channel.rise_derivative(normal))  # phi = e^{-k (L - x)} solves the variational equation
        area = float(channel.top(normal) * -np.expm1(-k * L) / k)
    else:

        def rhs(_x: float, y: Array) -> Array:
            # the depth H, its sensitivity phi = dH/dH(L) at constant Q, and int_x^L T phi
            return np.array([channel.rise(y[0]), channel.rise_derivative(y[0]) * y[1], -channel.top(y[0]) * y[1]])

        def dry(_x: float, y: Array) -> float:
            return float(y[0] - 1.001 * critical)

        dry.terminal = True  # type: ignore[attr-defined]
        sol = solve_ivp(
            rhs, (L, 0.0), [end, 1.0, 0.0], method="DOP853", rtol=1e-11, atol=1e-12, dense_output=True, events=dry
        )
        if sol.status != 0:
            raise ParameterError("downstream_depth", "a steady profile that stays subcritical on [0, L] (F < 1)", end)
        profile = _Profile(end, sol.sol)
        area = float(sol.y[2, -1])
    coefs = [[_SVCoefficient(channel, profile, (i, j)) for j in range(2)] for i in range(2)]
    H0, HL = float(profile(0.0)), float(profile(L))
    V0, VL = float(channel.velocity(H0)), float(channel.velocity(HL))
    c0, cL = float(np.sqrt(g * channel.depth(H0))), float(np.sqrt(g * channel.depth(HL)))
    q = -(c0 - V0) / (c0 + V0)
    G = g / cL
    if downstream == "gate":
        # T V h + A w = U_Q at x = L, in xi: xi_2 = -(V + C)/(C - V) xi_1 + 2 g U_Q /(T C (C - V)).
        rho = -(VL + cL) / (cL - VL)
        gain = 2.0 * g / (float(channel.top(HL)) * cL * (cL - VL))
    else:
        kappa = 1.5 * VL * float(channel.depth(HL)) / (HL - p)
        rho = -(VL + cL - kappa) / (cL - VL + kappa)
        gain = -2.0 * G * kappa / (cL - VL + kappa)
    speeds: list[Any] = [_Speed(channel, profile, 1.0), _Speed(channel, profile, -1.0)]
    entries: list[Any] = [coefs[0][0], coefs[0][1], coefs[1][0], coefs[1][1]]
    if profile.solution is None:  # uniform flow: constant coefficients, so the exact route (no kernel grid)
        speeds = [float(f(0.0)) for f in speeds]
        entries = [float(f(0.0)) for f in entries]
    system = GeneralHyperbolic2x2(
        speeds[0], speeds[1], entries[0], entries[1], entries[2], entries[3], q, rho, L, time_unit
    )
    x = np.linspace(0.0, L, 201)
    H = profile(x)
    V = channel.velocity(H)
    froude = V / np.sqrt(g * channel.depth(H))
    return SaintVenant(system, x, H, V, normal, critical, froude, float(gain), system.transport_times, area)


# ============================================================================ ARZ traffic
@dataclass(frozen=True)
class ARZ:
    """The linearised ARZ model and its equilibrium.

    Attributes
    ----------
    system : GeneralHyperbolic2x2
        The plant in the Riemann coordinates of Yu and Krstic: ``u = w~`` (the
        perturbation of ``w = v + p(rho)``, carried at ``lam = v*``) and ``v = v~`` (the
        velocity perturbation, carried upstream at ``mu = gamma p* - v*``):
        ``u_t + v* u_x = -u/tau``, ``v_t - (gamma p* - v*) v_x = -u/tau``.
    rho_star, v_star, p_star : float
        Equilibrium density, velocity ``V(rho*) = v_m (1 - (rho*/rho_m)^gamma)`` and traffic
        pressure ``p(rho*) = v_m (rho*/rho_m)^gamma``.
    speeds : tuple of float
        The characteristic speeds ``(v*, v* - gamma p*)``, the second negative in
        congestion.
    critical_density : float
        ``rho_m (1 + gamma)^{-1/gamma}``, above which the traffic is congested
        (``v* < gamma p*``).
    actuator_gain : float
        ``U = actuator_gain * (outflow perturbation)``: the flux ``rho v`` at ``x = L``.
    """

    system: GeneralHyperbolic2x2
    rho_star: float
    v_star: float
    p_star: float
    speeds: tuple[float, float]
    critical_density: float
    actuator_gain: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


def arz(
    length: float,
    v_max: float,
    rho_max: float,
    gamma: float,
    relaxation: float,
    rho_star: float,
    time_unit: float = 1.0,
) -> ARZ:
    """The Aw-Rascle-Zhang model linearised about a congested equilibrium.

    ``rho_t + (rho v)_x = 0``, ``(v + p(rho))_t + v (v + p(rho))_x = (V(rho) - v)/tau`` with
    ``p(rho) = v_m (rho/rho_m)^gamma`` and ``V(rho) = v_m - p(rho)``. With ``w = v + p(rho)``
    the model reads ``w_t + v w_x = (V - v)/tau``, ``v_t + (v - rho p') v_x = (V - v)/tau``;
    since ``V' = -p'`` the linearised source is ``-w~/tau`` in both equations. Inflow
    ``rho v = q*`` at ``x = 0`` gives ``w~ = (v* - gamma p*)/v* v~`` there; at ``x = L``
    the outflow ``rho v = q* + U_q`` gives ``v~ = v*/(v* - gamma p*) w~ + U`` with
    ``U = p'(rho*) U_q / (gamma p* - v*)`` (``actuator_gain``; docs/theory.md).

    Parameters
    ----------
    length : float
        Road length (m).
    v_max, rho_max : float
        Maximum speed (m/s) and jam density (vehicles per m).
    gamma : float
        Exponent of the traffic pressure, ``> 0``; ``1`` gives Greenshields'
        ``V(rho) = v_m (1 - rho/rho_m)``, the setting of ``examples/arz.py`` (the TrafficPDE1D
        environment of PDE Control Gym: ``v* = 10 m/s`` at ``rho* = 0.12`` veh/m, ``v_m = 40 m/s``,
        ``rho_m = 0.16`` veh/m).
    relaxation : float
        Relaxation time ``tau`` (s).
    rho_star : float
        Equilibrium density, congested: ``rho_m (1 + gamma)^{-1/gamma} < rho* < rho_m``.
    time_unit : float, default 1
        Unit of time of the analyses in seconds (see :class:`GeneralHyperbolic2x2`).

    Raises
    ------
    ParameterError
        A parameter out of range; ``rho_star`` not congested (named, with the threshold).
    """
    L, vm, rm = positive("length", length), positive("v_max", v_max), positive("rho_max", rho_max)
    gam, tau = positive("gamma", gamma), positive("relaxation", relaxation)
    rs = positive("rho_star", rho_star)
    critical = rm * (1.0 + gam) ** (-1.0 / gam)
    if not critical < rs < rm:
        raise ParameterError(
            "rho_star", f"congested: between the critical density {critical:.6g} and rho_max = {rm:.6g}", rho_star
        )
    p_star = vm * (rs / rm) ** gam
    v_star = vm - p_star
    lam2 = v_star - gam * p_star
    q = lam2 / v_star
    rho = v_star / lam2
    dp = gam * p_star / rs  # p'(rho*)
    # Outflow: rho* v~ + v* r~ = U_q with r~ = (w~ - v~)/p'  =>  v~ = rho w~ + p' U_q / (rho* p' - v*).
    gain = dp / (gam * p_star - v_star)
    system = GeneralHyperbolic2x2(v_star, -lam2, -1.0 / tau, 0.0, -1.0 / tau, 0.0, q, rho, L, time_unit)
    return ARZ(system, rs, v_star, p_star, (v_star, lam2), critical, gain)
