"""The delay form (39) of a plant with constant coefficients, in closed form: no kernel grid.

With constant couplings the Laplace-domain solution of the plant is a 2x2 matrix
exponential (:func:`~nrobust.hyperbolic.loops.laplace.boundary_function`), and the kernel
``N~`` of eq. (40) is an entire function of ``nu`` on ``[0, tau]``. For the paper's plant
(18)-(20), with ``p = sigma_pm / lam``, ``m = -sigma_mp / mu``, ``kappa = p m`` and
``a = kappa / tau^2``::

    N~(nu) = h_22(nu) - rho q h_11(nu) + (m q - rho p) / tau W(nu),
    W(nu)    = sum_k a^k (nu (tau - nu))^k / (k!)^2,
    h_22(nu) = sum_k a^(k+1) nu^k (tau - nu)^(k+1) / (k! (k+1)!),   h_11(nu) = h_22(tau - nu),

(``W`` is ``I_0(2 sqrt(a nu (tau - nu)))``, a Bessel function). The three series are the
inverse Laplace transforms of the entries of ``e^{-s tau/2} (cosh D I + sinh(D)/D (B + s
tau/2 I))``, ``D^2 = (s tau / 2)^2 + kappa``, by the identity
``int_{-1}^{1} e^{-z t} I_0(b sqrt(1 - t^2)) dt = 2 sinh(sqrt(z^2 + b^2)) / sqrt(z^2 + b^2)``
and ``d/dx E(x) = B E(x)``. A general plant with constant coefficients ``lam, mu, a, b, c,
d`` on ``[0, L]`` has the same form in the shifted variable ``s - sigma_0``,
``sigma_0 = (a L / lam + d L / mu) / tau``: its normalised characteristic function is
``1 - rho q e^{sigma_0 tau} e^{-tau s} + int_0^tau e^{sigma_0 nu} N~_0(nu) e^{-nu s} dnu``,
``N~_0`` the kernel above with ``p = b L / lam``, ``m = -c L / mu`` (``tau`` in the plant's
time unit).

:func:`exact_form` stores ``N~`` as polynomial pieces of degree :data:`DEGREE` on a
uniform partition of ``[0, tau]``, expanded in ball arithmetic (python-flint) from the
truncated series, with a proven bound of the difference to the true kernel (the series'
tail, the truncation of each piece's expansion and the rounding of its coefficients to
double precision) in :attr:`~nrobust.quasipoly.DistributedDelay.radius`, and of its total
variation in ``variation_radius``. The ratios ``p``, ``m`` and the shift ``sigma_0 tau`` enter
the series as balls of the exact quotients of the user's numbers (:func:`exact_ratios`), so
their rounding is part of that bound. The principal gains ``q e^{sigma_0 tau / 2}``,
``rho q e^{sigma_0 tau}`` and ``q e^{sigma_0 tau}`` are irrational for a general plant (and a
product ``rho q`` of doubles need not be a double): :func:`gain_balls` encloses them from the
user's numbers, and the loop's point coefficients carry the distance of their doubles to them as
radii (:class:`~nrobust.quasipoly.QuasiPolynomial`'s ``radii``). Every ball enclosure of a loop
built on it (:mod:`nrobust.balls`) is then an enclosure for the PDE itself, with one exception: the
transport time is the double ``tau_d`` nearest ``tau = 1/lam + 1/mu`` (the principal delays of
:class:`~nrobust.quasipoly.QuasiPolynomial` are doubles). Since ``tau N~(tau t)`` depends on
``p``, ``m``, ``q``, ``rho`` and ``sigma_0 tau`` only, the loop of an unfiltered law is a
function of ``z = tau s`` and of ``delta / tau`` (a filtered law's, of ``z``, ``delta / tau`` and
``a / tau``, ``b / tau``): :func:`~nrobust.hyperbolic.loops.given_plant.given_plant_scale` maps
the proofs for ``tau_d`` to the plant as given.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache
from typing import Any

import numpy as np

from ..._flint import ball_upper, precision, require_flint
from ...errors import CertificationError, ParameterError
from ...quasipoly import DistributedDelay, QuasiPolynomial
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2

__all__ = [
    "DEGREE",
    "ExactForm",
    "closed_form_parameters",
    "closed_form_series",
    "exact_form",
    "exact_ratios",
    "exact_tau",
    "ball_radius",
    "gain_balls",
    "rational_ball",
    "exact_output_map",
    "expand_piece",
    "has_exact_form",
    "series_tail",
    "tau_ratio",
]

#: Degree of the polynomial pieces of the exact ``N~``.
DEGREE = 9
#: Target bound of the stored pieces' error, relative to ``max |N~|`` (plus 2^-60 absolute): a few
#: roundings of the coefficients to double precision.
TARGET = 2.0**-50
#: Working precision (bits) of the expansions, plus ``12 sqrt|kappa|`` bits that the monomial form of
#: the series loses to cancellation (its coefficients reach about ``e^{2 sqrt(2 |kappa|)} 2^(2K)``).
PRECISION = 128
#: Largest ``|kappa| = |sigma_pm sigma_mp| / (lam mu)`` taken by the closed form: beyond, the series
#: and the pieces grow like ``sqrt|kappa|`` and the kernel route is used (its grid checks apply).
KAPPA_MAX = 2500.0
#: Most pieces tried before giving up (coupling too strong for double precision).
MAX_PIECES = 4096


@dataclass(frozen=True)
class ExactForm:
    """The delay form of a plant with constant coefficients, exact (module notes).

    Attributes
    ----------
    tau : float
        The round-trip time (in the plant's time unit for a general plant).
    q, rho : float
        The boundary coefficients of the normal form (``q e^{sigma_0 tau / 2}``,
        ``rho e^{sigma_0 tau / 2}`` for a general plant, whose normal form balances the
        scaling between them).
    rho_q : float
        The gain of the principal delay ``tau`` (``rho q e^{sigma_0 tau}`` for a general plant).
    N_tilde : DistributedDelay or None
        ``N~`` on ``[0, tau]``, polynomial pieces with proven error bounds; None when
        ``N~ = 0``.
    characteristic : QuasiPolynomial
        ``1 - rho_q e^{-tau s} + int_0^tau N~(nu) e^{-nu s} dnu``, the open loop.
    u_factor : QuasiPolynomial
        ``e^{-s t_v} u(L, s)`` normalised as the characteristic function, in the plant's own
        coordinates: ``q e^{sigma_0 tau} e^{-tau s} + int_0^tau U~(nu) e^{-nu s} dnu`` with
        ``U~ = e^{sigma_0 nu} (q h_11 + p W / tau)``; a proportional feedback
        ``U = k u(t, L)`` closes the loop with ``B = -k u_factor``; integral gains subtract
        their term ``I_g`` (:func:`~nrobust.hyperbolic.loops.exact_gains.gain_terms`).
    q_radius, rho_q_radius, u_radius : float
        Proven bounds of the distance of ``q``, ``rho_q`` and the point gain
        ``q e^{sigma_0 tau}`` of ``u_factor`` to their exact values (the exponential weight
        ``e^{sigma_0 tau}`` is irrational: the doubles are rounded), enclosed in ball
        arithmetic from the user's numbers; 0 when the doubles are exact. ``characteristic``
        and ``u_factor`` carry them as the radii of their point coefficients
        (:class:`~nrobust.quasipoly.QuasiPolynomial`), so every ball enclosure of a loop built
        on them holds for the plant as given. Zeros without python-flint (no proof runs without it).
    """

    tau: float
    q: float
    rho: float
    rho_q: float
    N_tilde: DistributedDelay | None
    characteristic: QuasiPolynomial
    u_factor: QuasiPolynomial
    q_radius: float = 0.0
    rho_q_radius: float = 0.0
    u_radius: float = 0.0


def has_exact_form(system: object) -> bool:
    """True for plants whose delay form :func:`exact_form` gives: constant coefficients, ``|kappa| <= KAPPA_MAX``."""
    if isinstance(system, Hyperbolic2x2) and system.constant_couplings:
        return abs(float(system.sigma_pm) * float(system.sigma_mp)) <= KAPPA_MAX * system.lam * system.mu  # type: ignore[arg-type]
    if isinstance(system, GeneralHyperbolic2x2) and _constant_general(system):
        _, p, m, _, _, _ = closed_form_parameters(system)
        return abs(p * m) <= KAPPA_MAX
    return False


def _constant_general(system: GeneralHyperbolic2x2) -> bool:
    """True when every coefficient of the general plant was given as a number."""
    return all(system.is_constant(k) for k in ("lam", "mu", "a", "b", "c", "d"))


def exact_form(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> ExactForm:
    """The delay form (39) with ``N~`` of eq. (40) in closed form (module notes).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        A plant with constant coefficients (:func:`has_exact_form`).

    Returns
    -------
    ExactForm

    Raises
    ------
    ParameterError
        A plant with varying coefficients.
    CertificationError
        Couplings so strong that the kernel's pieces cannot be stored to double precision
        within :data:`MAX_PIECES` pieces (``|kappa|`` in the thousands).
    """
    tau, _, _, q, rho, _ = closed_form_parameters(system)
    p, m, shift = exact_ratios(system)
    return _exact_form(tau, p, m, q, rho, shift)


def exact_output_map(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> QuasiPolynomial:
    """``M(s)`` with ``v(L, s) = M(s) beta(s, 1)``, in closed form: ``1 + int_0^tau V~(nu) e^{-nu s} dnu``.

    ``V~ = e^{sigma_0 nu} (h_22 + m q W / tau)``: the ``v`` row of the fundamental matrix applied
    to ``[q; 1]`` (module notes), normalised as the characteristic function; the exact
    counterpart of :func:`~nrobust.hyperbolic.loops.transfer.output_map`.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        A plant with constant coefficients.
    """
    tau, _, _, q, rho, _ = closed_form_parameters(system)
    p, m, shift = exact_ratios(system)
    kernel = None if m == 0 else _kernel(tau, p, m, shift, ("V", q, rho))  # m = 0: kappa = 0, V~ = 0
    one = QuasiPolynomial([[1.0]], [0.0])
    return one if kernel is None else one + QuasiPolynomial([], [], [kernel])


def closed_form_parameters(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
) -> tuple[float, float, float, float, float, float]:
    """``(tau, p, m, q, rho, sigma_0 tau)`` of the closed form (module notes).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        A plant with constant coefficients.

    Returns
    -------
    tuple of float
        ``tau`` (the double the proofs take), ``p``, ``m``, ``q``, ``rho`` and the shift
        ``sigma_0 tau`` (0 for the paper's plant).
    """
    if isinstance(system, Hyperbolic2x2) and system.constant_couplings:
        p = float(system.sigma_pm) / system.lam  # type: ignore[arg-type]
        m = -float(system.sigma_mp) / system.mu  # type: ignore[arg-type]
        return system.tau, p, m, system.q, system.rho, 0.0
    if isinstance(system, GeneralHyperbolic2x2) and _constant_general(system):
        c = {k: float(system.coefficient(k, np.zeros(1))[0]) for k in ("lam", "mu", "a", "b", "c", "d")}
        length, unit = system.length, system.time_unit
        t_u, t_v = system.transport_times
        tau = 1.0 / (unit / t_u) + 1.0 / (unit / t_v)  # as the normal form's Hyperbolic2x2.tau
        shift = length * (c["a"] / c["lam"] + c["d"] / c["mu"])
        return tau, length * c["b"] / c["lam"], -length * c["c"] / c["mu"], system.q, system.rho, shift
    raise ParameterError("system", "a Hyperbolic2x2 or GeneralHyperbolic2x2 with constant coefficients", system)


def exact_ratios(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> tuple[Fraction, Fraction, Fraction]:
    """``(p, m, sigma_0 tau)`` of the closed form as exact fractions of the plant's numbers (module notes).

    ``p = sigma_pm / lam``, ``m = -sigma_mp / mu`` and ``0`` for the paper's plant;
    ``b L / lam``, ``-c L / mu`` and ``L (a / lam + d / mu)`` for a general plant with constant
    coefficients, each double taken as the rational it is.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        A plant with constant coefficients.
    """
    if isinstance(system, Hyperbolic2x2) and system.constant_couplings:
        p = Fraction(float(system.sigma_pm)) / Fraction(system.lam)  # type: ignore[arg-type]
        return p, -Fraction(float(system.sigma_mp)) / Fraction(system.mu), Fraction(0)  # type: ignore[arg-type]
    if isinstance(system, GeneralHyperbolic2x2) and _constant_general(system):
        c = {k: Fraction(float(system.coefficient(k, np.zeros(1))[0])) for k in ("lam", "mu", "a", "b", "c", "d")}
        length = Fraction(system.length)
        shift = length * (c["a"] / c["lam"] + c["d"] / c["mu"])
        return length * c["b"] / c["lam"], -length * c["c"] / c["mu"], shift
    raise ParameterError("system", "a Hyperbolic2x2 or GeneralHyperbolic2x2 with constant coefficients", system)


def exact_tau(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> Fraction:
    """``tau`` of a plant with constant coefficients as the rational of its numbers.

    ``1/lam + 1/mu`` for :class:`~nrobust.hyperbolic.plants.hyperbolic2x2.Hyperbolic2x2`,
    ``(L/lam + L/mu) / time_unit`` for a
    :class:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2` (its round trip in its
    time unit, the ``tau`` of its normal form).
    """
    if isinstance(system, GeneralHyperbolic2x2):
        lam, mu = (Fraction(float(system.coefficient(k, np.zeros(1))[0])) for k in ("lam", "mu"))
        length = Fraction(system.length)
        return (length / lam + length / mu) / Fraction(system.time_unit)
    return Fraction(1) / Fraction(system.lam) + Fraction(1) / Fraction(system.mu)


def tau_ratio(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> Fraction:
    """``r = tau / tau_d``: :func:`exact_tau` over the double ``tau_d`` the closed form is built with.

    The loop of the plant as given is the loop as built with ``s`` scaled by ``r``
    (:mod:`~nrobust.hyperbolic.loops.given_plant`); 1 when ``tau`` is a double.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        A plant with constant coefficients.
    """
    return exact_tau(system) / Fraction(closed_form_parameters(system)[0])


def rational_ball(flint: Any, x: Fraction) -> Any:
    """The arb ball of the rational ``x`` (exact integers, one outward-rounded division)."""
    return flint.arb(x.numerator) / flint.arb(x.denominator)


@lru_cache(maxsize=64)
def _exact_form(tau: float, p: Fraction, m: Fraction, q: float, rho: float, shift: Fraction) -> ExactForm:
    weight = math.exp(float(shift))
    q_round = q * weight
    rho_q = rho * q_round  # the product B of StateFeedback(-rho) forms: the natural gain cancels exactly
    half = math.exp(0.5 * float(shift))
    q_radius, rho_q_radius, u_radius = _gain_radii(q, rho, shift, q * half, rho_q, q_round)
    principal = QuasiPolynomial([[1.0], [-rho_q]], [0.0, tau], radii=[[0.0], [rho_q_radius]])
    u_point = QuasiPolynomial([[q_round]], [tau], radii=[[u_radius]])
    uncoupled = p == 0 or m == 0  # kappa = 0: W = 1, h_11 = h_22 = 0
    n_zero = uncoupled and m * Fraction(q) == Fraction(rho) * p
    n_tilde = None if n_zero else _kernel(tau, p, m, shift, ("N", q, rho))
    u_tilde = None if uncoupled and p == 0 else _kernel(tau, p, m, shift, ("U", q, rho))
    return ExactForm(
        tau,
        q * half,
        rho * half,
        rho_q,
        n_tilde,
        principal if n_tilde is None else principal + QuasiPolynomial([], [], [n_tilde]),
        u_point if u_tilde is None else u_point + QuasiPolynomial([], [], [u_tilde]),
        q_radius,
        rho_q_radius,
        u_radius,
    )


def _gain_radii(
    q: float, rho: float, shift: Fraction, q_half: float, rho_q: float, q_round: float
) -> tuple[float, float, float]:
    """Bounds of ``|q_half - q e^{s/2}|``, ``|rho_q - rho q e^{s}|``, ``|q_round - q e^{s}|`` (``s = sigma_0 tau``).

    Zeros without python-flint: the radii serve the ball arithmetic only, which needs it.
    """
    try:
        flint = require_flint()
    except ImportError:
        return 0.0, 0.0, 0.0
    with precision(flint, PRECISION):
        exact = _gain_balls(flint, q, rho, shift)
        return tuple(ball_radius(flint, v, x) for v, x in zip((q_half, rho_q, q_round), exact))  # type: ignore[return-value]


def _gain_balls(flint: Any, q: float, rho: float, shift: Fraction) -> tuple[Any, Any, Any]:
    """``q e^{s/2}``, ``rho q e^{s}``, ``q e^{s}`` as ``arb`` balls (the exponential of the rational ``s``)."""
    arb = flint.arb
    S = rational_ball(flint, shift)
    Q, R = arb(q), arb(rho)
    return Q * (S / 2).exp(), R * Q * S.exp(), Q * S.exp()


def gain_balls(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> tuple[Any, Any, Any]:
    """The exact principal gains of the closed form as ``arb`` balls at :data:`PRECISION` bits.

    ``q e^{sigma_0 tau / 2}``, ``rho q e^{sigma_0 tau}`` and ``q e^{sigma_0 tau}`` (the values
    :class:`ExactForm`'s ``q``, ``rho_q`` and the point gain of ``u_factor`` round to doubles),
    from the user's numbers (``sigma_0 tau`` the rational of :func:`exact_ratios`).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        A plant with constant coefficients.
    """
    _, _, _, q, rho, _ = closed_form_parameters(system)
    flint = require_flint()
    with precision(flint, PRECISION):
        return _gain_balls(flint, q, rho, exact_ratios(system)[2])


def ball_radius(flint: Any, value: complex | float, exact: Any) -> float:
    """A double bounding ``|value - x|`` for every ``x`` in the ball ``exact``.

    Rounded up; 0 when ``exact`` is the point ``value``.
    """
    z = complex(value)
    diff = (flint.acb(z.real, z.imag) if z.imag else flint.arb(z.real)) - exact
    if diff.is_zero():
        return 0.0
    return math.nextafter(float(abs(diff).upper()), math.inf)


def _kernel(
    tau: float, p: Fraction, m: Fraction, shift: Fraction, which: tuple[str, float, float]
) -> DistributedDelay | None:
    """``N~``, ``U~`` or ``V~`` (``which = ("N" | "U" | "V", q, rho)``) as pieces with proven error bounds.

    ``p``, ``m`` and ``shift`` are exact (:func:`exact_ratios`): their balls hold them, and the
    bounds hold for every value in the balls.
    """
    flint = require_flint()
    with precision(flint, PRECISION + math.ceil(12.0 * math.sqrt(abs(float(p * m))))):
        arb = flint.arb
        T = arb(tau)
        series, bound, dbound = closed_form_series(flint, T, rational_ball(flint, p), rational_ball(flint, m), which)
        sigma = rational_ball(flint, shift) / T  # e^{sigma nu}: the weight of a general plant
        weight_sup = arb.max(arb(1), (sigma * T).exp())
        global_sup = bound * weight_sup
        global_var = T * weight_sup * (abs(sigma) * bound + dbound)
        return _pieces(flint, series, sigma, T, tau, global_sup, global_var)


def closed_form_series(flint: Any, T: Any, P: Any, M: Any, which: tuple[str, Any, Any]) -> tuple[Any, Any, Any]:
    """The truncated series of ``N~``, ``U~`` or ``V~`` on ``[0, tau]`` and the bounds of its tail (sup, derivative).

    ``T``, ``P``, ``M`` are balls (``tau``, ``p``, ``m`` of the module notes; a ball wider than
    a point holds every kernel with parameters in it), ``which = ("N" | "U" | "V", q, rho)``.
    Returns the ``arb_poly`` in ``nu`` and bounds of ``|kernel - series|`` and of its
    derivative on ``[0, tau]`` (:func:`series_tail`), valid for every parameter in the balls.

    Raises
    ------
    CertificationError
        A coupling ``kappa = p m`` too strong for 400 terms.
    """
    arb, arb_poly = flint.arb, flint.arb_poly
    Q, R = arb(which[1]), arb(which[2])
    kappa = P * M
    a = kappa / (T * T)
    if which[0] == "N":  # h_22 - rho q h_11 + (m q - rho p) W / tau
        c_w, c_22, c_11 = (M * Q - R * P) / T, arb(1), -R * Q
    elif which[0] == "V":  # the v row of the fundamental matrix: h_22 + m q W / tau
        c_w, c_22, c_11 = M * Q / T, arb(1), arb(0)
    else:  # the u row of the fundamental matrix: q h_11 + p W / tau
        c_w, c_22, c_11 = P / T, arb(0), Q
    g = arb_poly([0, T, -1])  # nu (tau - nu)
    nu, rest = arb_poly([0, 1]), arb_poly([T, -1])
    series, k, term_w, term_22, term_11 = arb_poly([0]), 0, arb_poly([1]), rest * a, nu * a
    tail, slope = series_tail(flint, abs(kappa), T, abs(c_w), abs(c_22), abs(c_11))
    while True:
        fk, fk1 = arb(math.factorial(k)), arb(math.factorial(k + 1))
        series += term_w * (c_w / (fk * fk)) + term_22 * (c_22 / (fk * fk1)) + term_11 * (c_11 / (fk * fk1))
        k += 1
        bound, dbound = tail(k), slope(k)
        if (bound.upper() < arb(2.0**-90) and dbound.upper() < arb(2.0**-90)) or k > 400:
            break
        term_w, term_22, term_11 = term_w * g * a, term_22 * g * a, term_11 * g * a
    if k > 400:
        raise CertificationError("exact_form: the coupling kappa = p m is too strong for the series of N~")
    return series, bound, dbound


def series_tail(flint: Any, kappa_abs: Any, T: Any, cw: Any, c22: Any, c11: Any) -> tuple[Any, Any]:
    """Bounds of the tails (from term ``k`` on) of ``N~``'s series and of its derivative on ``[0, tau]``.

    With ``r = |kappa| / 4``: ``|a^k (nu (tau - nu))^k| <= r^k``,
    ``|a^(k+1) nu^k (tau - nu)^(k+1)| <= (|kappa| / tau) r^k``, and the derivatives are at most
    ``(2k + 1) / tau`` times as large times ``4`` (``|d/dnu (nu (tau - nu))^k| <= k (tau^2/4)^(k-1) tau``);
    the tail of ``sum_j (2j + 3) x^j / (j! (j + e)!)`` beyond ``k`` is at most twice its first
    term once ``(k + 1)^2 >= 4 x``.
    """
    arb = flint.arb
    r = kappa_abs / 4

    def first(k: int, extra: int) -> Any:
        return r**k / (arb(math.factorial(k)) * arb(math.factorial(k + extra)))

    def enough(k: int) -> bool:  # consecutive terms (with the growing factor) at least halve
        return bool(arb((k + 1) ** 2) > 4 * r + 1)

    def tail(k: int) -> Any:
        if not enough(k):
            return arb("inf")
        return 2 * (cw * first(k, 0) + (c22 + c11) * (kappa_abs / T) * first(k, 1))

    def slope(k: int) -> Any:
        if not enough(k):
            return arb("inf")
        grow = arb(4 * (2 * k + 3)) / T
        return 2 * grow * (cw * first(k, 0) + (c22 + c11) * (kappa_abs / T) * first(k, 1))

    return tail, slope


def _dyadic_step(tau: float, pieces: int) -> float:
    """``tau / pieces`` rounded to 40 significant bits: ``i h 2^-j`` is exact for ``i < 2^12``, ``j < 2^6``."""
    mant, expo = math.frexp(tau / pieces)
    return math.ldexp(math.floor(mant * 2**40) / 2**40, expo)


def expand_piece(flint: Any, series: Any, sigma: Any, lo: float, width: float) -> tuple[list[float], Any, Any]:
    """One piece: the stored coefficients, a bound of the stored piece's error (sup and variation), ``sum |P_j|``.

    ``series(lo + w t) = S(t)`` exactly (ball coefficients) and ``e^{sigma (lo + w t)} =
    e^{sigma lo} (E(t) + r(t))``, ``E`` the Taylor polynomial of :data:`_EXP_TERMS` terms of
    ``e^{z t}``, ``z = sigma w``. The stored piece is the head (degree :data:`DEGREE`) of
    ``e^{sigma lo} E S`` rounded to doubles; the sup and the variation of the rest are bounded
    by the moduli of the dropped and rounded coefficients and by
    ``e^{sigma lo} sum |S_j| |z|^40 e^{|z|} (1/39! + 1/40!)`` for ``r``.
    """
    arb, arb_poly = flint.arb, flint.arb_poly
    local = series(arb_poly([arb(lo), arb(width)]))
    rest = arb(0)
    if sigma != 0:
        z, weight = sigma * arb(width), (sigma * arb(lo)).exp()
        size = sum((abs(x) for x in local.coeffs()), arb(0))
        rest = weight * size * abs(z) ** _EXP_TERMS * abs(z).exp()
        rest = rest * (1 / arb(math.factorial(_EXP_TERMS - 1)) + 1 / arb(math.factorial(_EXP_TERMS)))
        local = local * arb_poly([weight * z**j / arb(math.factorial(j)) for j in range(_EXP_TERMS)])
    c = local.coeffs()
    head = [float(x.mid()) for x in c[: DEGREE + 1]] + [0.0] * max(0, DEGREE + 1 - len(c))
    rounding = sum((abs(x - arb(y)) for x, y in zip(c[: DEGREE + 1], head)), arb(0))
    dropped = sum((abs(x) for x in c[DEGREE + 1 :]), arb(0))
    return head, rounding + dropped + rest, sum((abs(arb(y)) for y in head), arb(0))


def _midpoint(lo: float, hi: float, tau: float) -> float:
    """The point bisecting ``[lo, hi]``: exact on the dyadic grid; for the last piece ``[lo, tau]``,
    ``lo`` plus half its length rounded down to 30 bits (an exact sum, checked)."""
    if hi != tau:
        return 0.5 * (lo + hi)
    mid = lo + _round_bits(0.5 * (tau - lo), 30)
    if Fraction(mid) != Fraction(lo) + Fraction(_round_bits(0.5 * (tau - lo), 30)) or not lo < mid < tau:
        raise CertificationError("exact_form: the pieces of N~ cannot be bisected exactly in double precision")
    return mid


def _round_bits(x: float, bits: int) -> float:
    """``x > 0`` rounded down to ``bits`` significant bits."""
    mant, expo = math.frexp(x)
    return math.ldexp(math.floor(mant * 2**bits) / 2**bits, expo)


def _pieces(
    flint: Any, series: Any, sigma: Any, T: Any, tau: float, global_sup: Any, global_var: Any
) -> DistributedDelay | None:
    """Expand ``e^{sigma nu} series(nu)`` on pieces of ``[0, tau]``, bisecting those whose error is too large.

    The nodes are multiples of a dyadic step (exact sums and differences) and ``tau`` itself;
    the last piece ``[lo, tau]`` has ``lo >= tau / 2``, so ``tau - lo`` is exact (Sterbenz).
    A piece is bisected until its error is below :data:`TARGET` times the largest
    ``sum |P_j|`` plus ``2^-60``: near the ends of ``[0, tau]`` the kernel's Taylor
    coefficients grow like ``(|kappa| / tau)^j / (j!)^2`` and need shorter pieces.
    """
    arb = flint.arb
    h = _dyadic_step(tau, 8)
    bounds = [(i * h, (i + 1) * h) for i in range(7)] + [(7 * h, tau)]
    done: dict[tuple[float, float], tuple[list[float], object, object]] = {}
    while len(bounds) <= MAX_PIECES:
        for piece in bounds:
            if piece not in done:
                done[piece] = expand_piece(flint, series, sigma, piece[0], piece[1] - piece[0])
        scale = arb(0)
        for piece in bounds:
            scale = arb.max(scale, done[piece][2])
        threshold = TARGET * scale + arb(2.0**-60) - global_sup
        refined: list[tuple[float, float]] = []
        for lo, hi in bounds:
            if bool(done[(lo, hi)][1] < threshold):
                refined.append((lo, hi))
            else:
                refined.extend([(lo, _midpoint(lo, hi, tau)), (_midpoint(lo, hi, tau), hi)])
        if refined == bounds:
            break
        bounds = refined
    else:
        raise CertificationError(
            f"exact_form: N~ needs more than {MAX_PIECES} pieces of degree {DEGREE} to reach double precision "
            "(a coupling too strong for the closed form); use the kernel route (kernel_grid=...)"
        )
    coefs = [done[piece][0] for piece in bounds]
    if not np.any(np.asarray(coefs)):
        return None
    sup_err, var_err = arb(0), arb(0)
    for piece in bounds:
        sup_err = arb.max(sup_err, done[piece][1])
        var_err += done[piece][1]
    jumps = sum(
        (abs(sum((arb(v) for v in left), arb(0)) - arb(right[0])) for left, right in itertools.pairwise(coefs)),
        arb(0),
    )
    nodes = [lo for lo, _ in bounds] + [tau]
    return DistributedDelay(
        np.asarray(nodes),
        None,
        interpolation="polynomial",
        coefficients=np.asarray(coefs),
        radius=ball_upper(global_sup + sup_err),
        variation_radius=ball_upper(global_var + var_err + jumps),
    )


# Terms of the Taylor polynomial of e^{z t} on a piece (general plants): its remainder is
# bounded in _pieces.
_EXP_TERMS = 40
