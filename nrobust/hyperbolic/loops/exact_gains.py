"""Integral gains of a state feedback on a plant with constant coefficients, in closed form.

For ``U(t) = k u(t, L) + int_0^L g_u(x) u(t, x) + g_v(x) v(t, x) dx`` the loop factor is
``B = -(k u_factor + I_g)`` (``u_factor`` of :func:`~nrobust.hyperbolic.loops.exact_form.exact_form`),
``I_g`` the integral term ``e^{-s t_v} int_0^L g_u u(x, s) + g_v v(x, s) dx`` normalised as the
characteristic function. The Laplace-domain state at ``x = xi L`` is the plant's on ``[0, x]``:
the closed form of :mod:`~nrobust.hyperbolic.loops.exact_form` with ``(tau, p, m)`` replaced
by ``(tau xi, p xi, m xi)`` (``a = kappa / tau^2`` is unchanged). With ``t_v`` the time of
flight of ``v``, ``t_u = tau - t_v``, ``sigma = sigma_0`` of the exact form,
``E = L (a - d) / (lam + mu)`` (0 for the paper's plant) and the effective gains
``G(xi) = L e^{-E (1 - xi)} g(L xi)``::

    I_g(s) = int_0^tau e^{sigma theta} K(theta) e^{-theta s} dtheta,
    K(theta) = G_v(1 - theta / t_v) / t_v                          (theta < t_v)
             + q G_u((theta - t_v) / t_u) / t_u                     (theta > t_v)
             + int_{xi_0(theta)}^1 G_u(xi) U(xi, theta) + G_v(xi) V(xi, theta) dxi,

``xi_0(theta) = max(1 - theta / t_v, (theta - t_v) / t_u)``. The point delays of
``e^{-s t_v} [u; v](x, s)``, at ``t_v + t_u xi`` (weight ``q``) and ``t_v (1 - xi)`` (weight 1),
give the first two terms by a change of variables; its distributed delays, the kernels
``U~``, ``V~`` of the section (``q h_11 + p W / tau`` and ``h_22 + m q W / tau`` on
``[0, tau xi]``) delayed by ``t_v (1 - xi)``, give the third by Fubini:
``U(xi, theta) = U~_xi(theta - t_v (1 - xi))``, a polynomial in ``(xi, theta)`` once the
series is truncated (``nu = theta - t_v (1 - xi)``, ``tau xi - nu = t_v + t_u xi - theta``).

The gains are enclosed in ball arithmetic: ``g`` is called on a python-flint ``arb_series``
(``x = L (c + r t)``, in a one-element object array, so that numpy's ufuncs act on it) once at
the centre ``c`` of each of ``n`` pieces of ``[0, 1]``, giving the
Taylor polynomial of degree :data:`ORDER` - 1, and once on the ball ``[c - r, c + r]``, whose
coefficient of ``t^ORDER`` bounds the Lagrange remainder and, times ``ORDER``, the remainder
of the derivative (a Taylor model: proven for any ``g`` built from arithmetic and the functions
of ``arb_series``, which numpy's ufuncs call on an object array, e.g. ``lambda x: 1 + x**2`` or
``lambda x: 0.1 * np.exp(2 * x)``; constants need no call; the series are computed to the order
:data:`ORDER`, python-flint's ``ctx.cap`` raised for the call). ``n`` doubles up to
:data:`MAX_GAIN_PIECES` until the remainders are below
:data:`~nrobust.hyperbolic.loops.exact_form.TARGET` times the gain's size. A ``g`` that fails
on ``arb_series`` (comparisons, ``np.where``, conversions to float, ...), is not analytic on
``[0, L]``, or disagrees with its values on arrays at the centres has no exact loop:
:func:`gain_failure` says why, and :func:`~nrobust.hyperbolic.loops.controllers.loop_route`
takes the kernel route.

``K`` is then a polynomial in ``theta`` on each of ``2 n`` segments (the images of the ``n``
pieces under ``xi_0``): the moments ``int_{xi_b}^1 G(xi) xi^i dxi`` of the models above the
segment, and the integral from ``xi_0(theta)`` to ``xi_b`` of the model of its piece, exact
polynomial algebra in ball arithmetic. Each segment is expanded into pieces of degree
:data:`~nrobust.hyperbolic.loops.exact_form.DEGREE` by
:func:`~nrobust.hyperbolic.loops.exact_form.expand_piece`; the proven sup bound of the
difference to the true kernel (Taylor remainders times the bounds of ``U``, ``V``; series
tails times the bounds of the models; expansion and rounding) is the kernel's ``radius``, and
the bound of its total variation (the same with the derivatives, and twice the sup bound at
each segment's end) its ``variation_radius``. The nodes are multiples of ``ulp(tau)`` (exact
differences).

The window. An output feedback's observer reads the law's kernel on ``[0, w]``, ``w = 1/mu`` the
transport time of ``v`` (:mod:`~nrobust.hyperbolic.loops.observer_proof`), where ``K`` is its branch
``theta < t_v`` alone when ``w <= t_v``. :func:`window_series` gives that branch as one polynomial
``K^`` in ``theta``: one Taylor model of each gain on all of ``[0, 1]`` (``n = 1``, of the first order of
:data:`WINDOW_ORDERS` that reaches double precision), refused when its
remainder is not below :data:`~nrobust.hyperbolic.loops.exact_form.TARGET` times the gain's size. With
``r_g`` the models' remainders, ``P_g`` their sizes and ``Delta = sum_g r_g sup |U_g| + P_g tail_g``
(``U_g`` the section ``U`` or ``V`` of the gain, ``tail_g`` its dropped terms), on the window
(``xi_0 = 1 - theta / t_v`` in ``[0, 1]``, an integral over at most a unit length)::

    |K - K^|   <= r_v / t_v + Delta,
    |K - K^|'  <= r_v' / t_v^2 + Delta / t_v + Delta'

(``K' = -G_v'(xi_0) / t_v^2 + F(xi_0, theta) / t_v + int_{xi_0}^1 dF/dtheta dxi`` with
``F = G_u U + G_v V``; ``r_v'`` the bound of the model's derivative in ``xi``, its order times the
remainder over the piece's half-width; ``Delta'`` as ``Delta`` with the sections' slopes).

The plant as given. The loop is built with ``tau_d`` (``1/lam + 1/mu`` in floating point), and
``I_g`` of the plant at ``s`` is that of the loop as built at ``r s`` (``r = tau / tau_d``):
``r K(r theta)`` is ``K`` with ``t_v``, ``t_u``, ``tau`` divided by ``r`` (each term above is
``1 / t`` times a function of ``theta / t``; ``U``, ``V`` are ``1 / tau`` times functions of
``theta / tau`` and ``xi``), ``sigma theta`` and ``G`` unchanged. :func:`gain_terms` builds it
with ``T = tau_d`` and ``t_v = tau_d lam / (lam + mu)`` (``= t_v / r``: an exact rational, an
``arb`` ball), so that proofs about the loop map to the plant
(:mod:`~nrobust.hyperbolic.loops.given_plant`). That ``t_v`` lies between two multiples of
``ulp(tau)``: the stored kernel jumps at the nearer one, ``n_v ulp``, and on the part ``D``
between the two (at most half an ulp) it is the other branch's. A second term covers ``D``:
on the ulp between ``n_v ulp`` and the next multiple past ``t_v`` it is zero within a
``radius`` ``J``, the jump ``|e^{sigma theta} (K_left - K_right)|`` enclosed there plus the
kernel's own ``radius`` (the true branch within it of its series, the stored piece within it
of the other branch's series), and its ``variation_radius`` on its interior is ``J`` (its jump
at ``t_v``) plus the kernel's ``variation_radius`` and ``ulp`` times the slope of
``e^{sigma theta} (K_left - K_right)``. The kernel's own bounds hold for the true kernel
off ``D`` and the stored one on ``D``: its error jumps to zero at both ends of ``D``, by at
most its ``radius`` each, which the two sup bounds at that segment end already count. An
enclosure widens by ``J ulp(tau) e^{...}`` (the ``L^1`` norm of the term), a bound of the far
field (:func:`~nrobust.balls.ball_variation_bound`) by about ``3 J``. :func:`gain_kernel`
takes ``t_v`` the double ``1/mu`` rounded to a multiple of ``ulp(tau_d)``: one term, the kernel
of a plant within a relative ``2^-52 tau / t_v`` of the given one, for the analyses that
enclose a box of plants around it (:mod:`~nrobust.hyperbolic.analyses.mismatch_gains`).
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
from ...quasipoly import DistributedDelay
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from ..plants.law import feedback_gain
from .exact_form import (
    MAX_PIECES,
    PRECISION,
    TARGET,
    closed_form_parameters,
    exact_ratios,
    expand_piece,
    has_exact_form,
    rational_ball,
    series_tail,
)

__all__ = ["MAX_GAIN_PIECES", "ORDER", "WINDOW_ORDERS", "gain_failure", "gain_kernel", "gain_terms", "window_series"]

#: Taylor order of the models of the gains on each piece of ``[0, 1]``.
ORDER = 20
#: Orders tried for the one Taylor model of each gain on ``[0, 1]`` of :func:`window_series`.
WINDOW_ORDERS = (ORDER, 2 * ORDER, 4 * ORDER)
#: Most pieces of ``[0, 1]`` tried for the models of the gains.
MAX_GAIN_PIECES = 64
# Each model is valid on its piece widened by this much on both sides (the nodes of theta,
# rounded to multiples of ulp(tau), map slightly outside the pieces).
_WIDEN = 2.0**-30
# Relative agreement asked of the ball models with the gain evaluated on arrays.
_AGREEMENT = 1e-8


@dataclass(frozen=True)
class _Plant:
    """The numbers of the closed form: ``t_v``, ``p``, ``m``, ``shift`` and ``weight`` exact, the rest doubles."""

    tau: float
    t_v: Fraction  # where K jumps: a multiple of ulp(tau) (gain_kernel) or tau lam / (lam + mu) (gain_terms)
    p: Fraction
    m: Fraction
    q: float
    shift: Fraction
    length: float
    weight: Fraction  # E = L (a - d) / (lam + mu)


def gain_plant(system: Hyperbolic2x2 | GeneralHyperbolic2x2, exact_times: bool = False) -> _Plant:
    """The numbers of ``system`` the gains' models are built from (``tau``, ``t_v``, the exact ratios, ``q``, ...).

    ``tau`` is the double ``tau_d`` of the closed form. With ``exact_times``, ``t_v`` is
    ``tau_d lam / (lam + mu)`` exactly: the time of flight of ``v`` of the loop as built that the
    plant as given maps to (:mod:`~nrobust.hyperbolic.loops.given_plant`, ``t_v / tau`` is
    ``lam / (lam + mu)`` for both); otherwise the double ``1/mu`` (``L/mu`` in the time unit)
    rounded to a multiple of ``ulp(tau_d)``, as :func:`gain_kernel` takes it.
    """
    if not has_exact_form(system):
        raise ParameterError("system", "a plant with constant coefficients (has_exact_form)", system)
    tau, _, _, q, _, _ = closed_form_parameters(system)
    p, m, shift = exact_ratios(system)
    if isinstance(system, GeneralHyperbolic2x2):
        c = {k: Fraction(float(system.coefficient(k, np.zeros(1))[0])) for k in ("lam", "mu", "a", "d")}
        t_v = 1.0 / (system.time_unit / system.transport_times[1])  # as closed_form_parameters' tau
        length = system.length
        weight = Fraction(length) * (c["a"] - c["d"]) / (c["lam"] + c["mu"])
        lam, mu = c["lam"], c["mu"]
    else:
        t_v, length, weight = 1.0 / system.mu, 1.0, Fraction(0)
        lam, mu = Fraction(system.lam), Fraction(system.mu)
    ulp = Fraction(math.ulp(tau))
    time = Fraction(tau) * lam / (lam + mu) if exact_times else round(Fraction(t_v) / ulp) * ulp
    return _Plant(tau, time, p, m, q, shift, length, weight)


def gain_kernel(system: Hyperbolic2x2 | GeneralHyperbolic2x2, g_u: Any, g_v: Any) -> DistributedDelay | None:
    """The kernel ``e^{sigma theta} K(theta)`` of ``I_g`` on ``[0, tau]`` with proven error bounds, ``t_v`` on the grid.

    The kernel of the plant with ``tau`` the double ``tau_d`` and ``t_v`` the double ``1/mu``
    rounded to a multiple of ``ulp(tau_d)`` (:func:`gain_plant`), a relative change of ``t_v``
    below ``2^-52 tau / t_v``: one point of a box of plants for the analyses of uncertain speeds.
    The loop of ``StateFeedback(k, g_u, g_v)`` takes :func:`gain_terms`, whose proofs map to the
    plant as given.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        A plant with constant coefficients
        (:func:`~nrobust.hyperbolic.loops.exact_form.has_exact_form`).
    g_u, g_v : float or callable
        The integral gains on ``[0, L]``, in the plant's coordinates; a callable is evaluated
        on python-flint ``arb_series`` (module notes).

    Returns
    -------
    DistributedDelay or None
        Polynomial pieces with ``radius`` and ``variation_radius`` (None when both gains
        are 0).

    Raises
    ------
    ParameterError
        A plant without the closed form, or a gain not finite on ``[0, L]``.
    CertificationError
        A gain that cannot be enclosed in ball arithmetic to double precision
        (:func:`gain_failure` gives the reason).
    """
    terms = _terms(gain_plant(system), g_u, g_v)
    return terms[0] if terms else None


def gain_terms(system: Hyperbolic2x2 | GeneralHyperbolic2x2, g_u: Any, g_v: Any) -> tuple[DistributedDelay, ...]:
    """The distributed terms of ``I_g`` in the loop as built: ``t_v = tau_d lam / (lam + mu)`` exactly (module notes).

    ``I_g`` of the plant as given at ``s`` is the sum of their integrals at ``r s``
    (``r = tau / tau_d``, :func:`~nrobust.hyperbolic.loops.exact_form.tau_ratio`), so proofs about
    the loop ``B = -(k u_factor + I_g)`` built with them map to the plant as given
    (:mod:`~nrobust.hyperbolic.loops.given_plant`).

    Parameters
    ----------
    system, g_u, g_v
        As for :func:`gain_kernel`.

    Returns
    -------
    tuple of DistributedDelay
        Empty when both gains are 0; else the kernel's polynomial pieces on ``[0, tau_d]``
        with their jump at the multiple of ``ulp(tau_d)`` nearest ``t_v``, followed, when ``t_v``
        is not that multiple, by a term on the ``ulp(tau_d)`` between them: zero within a proven
        ``radius`` (the size of the jump) and ``variation_radius``.

    Raises
    ------
    ParameterError, CertificationError
        As :func:`gain_kernel`.
    """
    return _terms(gain_plant(system, exact_times=True), g_u, g_v)


def gain_failure(system: Hyperbolic2x2 | GeneralHyperbolic2x2, g_u: Any, g_v: Any) -> str | None:
    """Why :func:`gain_terms` cannot build the exact kernel of these gains (None when it can)."""
    try:
        gain_terms(system, g_u, g_v)
    except CertificationError as exc:
        return str(exc)
    return None


def window_series(
    flint: Any, system: Hyperbolic2x2 | GeneralHyperbolic2x2, g_u: Any, g_v: Any, window: float
) -> tuple[Any, Any, Any] | None:
    """``K`` of ``I_g`` on the observer's window ``[0, window]`` as one polynomial, with proven error bounds.

    The branch ``theta < t_v`` of the kernel of :func:`gain_terms` (``t_v = tau_d lam / (lam + mu)``
    exactly), without the weight ``e^{sigma theta}``, from one Taylor model of each gain on ``[0, 1]``
    (module notes, "The window").

    Parameters
    ----------
    flint : module
        python-flint (the series is computed at the precision of :func:`gain_terms` or the caller's, the
        larger).
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        A plant with constant coefficients.
    g_u, g_v : float or callable
        The integral gains, as for :func:`gain_kernel`.
    window : float
        ``w``, at most ``t_v`` (in the loop's time unit).

    Returns
    -------
    tuple of (arb_poly, arb, arb) or None
        The polynomial in ``theta`` and bounds of ``|K - K^|`` and ``|K' - K^'|`` on ``[0, window]``;
        None when both gains are 0.

    Raises
    ------
    ParameterError
        A plant without the closed form, or a gain not finite on ``[0, L]``.
    CertificationError
        ``window`` past ``t_v``, or a gain whose one Taylor model of order ``WINDOW_ORDERS[-1]`` on ``[0, L]`` does
        not reach double precision (or that cannot be evaluated in ball arithmetic).
    """
    plant = gain_plant(system, exact_times=True)
    for name, g in (("g_u", g_u), ("g_v", g_v)):
        feedback_gain(name, g, plant.length)
    if _is_zero(g_u) and _is_zero(g_v):
        return None
    if Fraction(window) > plant.t_v:
        raise CertificationError(
            f"the window {window!r} reaches past the time of flight t_v = tau_d lam / (lam + mu) of the gains' kernel "
            "(its jump would fall inside the window)"
        )
    bits = PRECISION + math.ceil(12.0 * math.sqrt(abs(float(plant.p * plant.m)))) + WINDOW_ORDERS[-1] * 7 + 64
    with precision(flint, max(bits, flint.ctx.prec)):
        arb, arb_poly = flint.arb, flint.arb_poly
        T, Tv = arb(plant.tau), rational_ball(flint, plant.t_v)
        models = {name: _window_model(flint, g, plant, name) for name, g in (("g_u", g_u), ("g_v", g_v))}
        sections = dict(zip(("g_u", "g_v"), _sections(flint, plant, T, Tv, T - Tv)))
        start = arb_poly([1, -1 / Tv])  # xi_0 = 1 - theta / t_v
        series = models["g_v"].polys[0](start) * (1 / Tv)
        spread, slope = arb(0), arb(0)
        for name, mod in models.items():
            sec = sections[name]
            series += _partial(flint, sec.rows, mod.polys[0], start, arb(1))
            spread += mod.remainder[0] * sec.sup + mod.size[0] * sec.tail
            slope += mod.remainder[0] * sec.slope + mod.size[0] * sec.tail_slope
        half = arb(1 / 2 + _WIDEN)  # the model's half-width: its derivative in xi is its derivative in t over it
        bound = models["g_v"].remainder[0] / Tv + spread
        dbound = models["g_v"].derivative[0] / (half * Tv * Tv) + spread / Tv + slope
        return series, arb(bound.upper()), arb(dbound.upper())


def _window_model(flint: Any, g: Any, plant: _Plant, name: str) -> _Models:
    """One Taylor model of the effective gain on ``[0, 1]``, of the first order of :data:`WINDOW_ORDERS` whose
    remainder is below :data:`~nrobust.hyperbolic.loops.exact_form.TARGET` times its size."""
    arb = flint.arb
    for order in WINDOW_ORDERS:
        model = _models(flint, g, plant, 1, name, order)
        if bool(model.remainder[0] < TARGET * model.size[0] + arb(2.0**-60)):
            return model
    raise CertificationError(
        f"the gain {name} needs more than one Taylor model of order {WINDOW_ORDERS[-1]} on [0, L] to reach double "
        "precision (the observer's window takes each gain as one polynomial)"
    )


def _terms(plant: _Plant, g_u: Any, g_v: Any) -> tuple[DistributedDelay, ...]:
    for name, g in (("g_u", g_u), ("g_v", g_v)):
        feedback_gain(name, g, plant.length)
    try:
        hash((g_u, g_v))
    except TypeError:  # an unhashable callable: built every time
        return _kernel(plant, g_u, g_v)
    return _kernel_cached(plant, g_u, g_v)


@lru_cache(maxsize=32)
def _kernel_cached(plant: _Plant, g_u: Any, g_v: Any) -> tuple[DistributedDelay, ...]:
    return _kernel(plant, g_u, g_v)


def _is_zero(g: Any) -> bool:
    return not callable(g) and float(g) == 0.0


# --------------------------------------------------------------------------- gain models


@dataclass
class _Models:
    """Taylor models of one effective gain on ``n`` pieces of ``[0, 1]``."""

    polys: list[Any]  # arb_poly in xi (global powers)
    remainder: list[Any]  # sup |G - P| on the widened piece
    derivative: list[Any]  # sup |d/dt (G - P)|, xi = c + r t
    size: list[Any]  # sup |P|


def _call(flint: Any, g: Any, x: Any, name: str, order: int = ORDER) -> Any:
    """``g`` at the series ``x``, as an ``arb_series`` (CertificationError when it is not one).

    ``g`` is called on a one-element object array holding ``x``: arithmetic and numpy's
    elementary ufuncs (``np.exp``, ``np.sin``, ``np.sqrt``, ...) then act on the series through its
    own operations and methods, and ``np.ones_like``/``np.full`` give constants.
    """
    arb, arb_series = flint.arb, flint.arb_series
    if not callable(g):
        return arb_series([arb(float(g))], prec=order + 1)
    holder = np.empty(1, dtype=object)
    holder[0] = x
    try:
        out = g(holder)
    except (TypeError, ValueError, ArithmeticError, AttributeError) as exc:
        raise CertificationError(
            f"the gain {name} cannot be evaluated in ball arithmetic (on a python-flint arb_series: {exc})"
        ) from None
    if isinstance(out, np.ndarray) and out.size == 1:
        out = out.reshape(-1)[0]
    if isinstance(out, arb_series):
        return out
    if isinstance(out, (int, float, arb)) and not isinstance(out, bool):
        return arb_series([arb(float(out)) if not isinstance(out, arb) else out], prec=order + 1)
    raise CertificationError(
        f"the gain {name} cannot be evaluated in ball arithmetic (on a python-flint arb_series it gave "
        f"{type(out).__name__})"
    )


def _effective(flint: Any, g: Any, plant: _Plant, xi: Any, name: str, order: int = ORDER) -> list[Any]:
    """The coefficients of ``G(xi) = L e^{-E (1 - xi)} g(L xi)`` for the series ``xi``, padded to ``order + 1``."""
    arb = flint.arb
    cap = flint.ctx.cap
    flint.ctx.cap = order + 1  # series functions (exp, cos, ...) truncate at the global cap
    try:
        out = _call(flint, g, xi * plant.length, name, order) * plant.length
        if plant.weight:
            out = out * ((xi - 1) * rational_ball(flint, plant.weight)).exp()
    finally:
        flint.ctx.cap = cap
    if out.prec < order + 1:  # a coefficient not computed is unknown, not zero
        raise CertificationError(f"the gain {name} gave a series truncated before the order {order} of its model")
    coefs = list(out.coeffs())[: order + 1]
    coefs += [arb(0)] * (order + 1 - len(coefs))  # computed to O(t^(order + 1)): the rest are zeros
    if not all(c.is_finite() for c in coefs):
        raise CertificationError(
            f"the gain {name} is not enclosed by finite balls on [0, L] (not analytic there, or too large)"
        )
    return coefs


def _models(flint: Any, g: Any, plant: _Plant, n: int, name: str, order: int = ORDER) -> _Models:
    """Taylor models of order ``order`` of the effective gain on ``n`` pieces of ``[0, 1]`` (module notes)."""
    arb, arb_poly, arb_series = flint.arb, flint.arb_poly, flint.arb_series
    out = _Models([], [], [], [])
    values = feedback_gain(name, g, plant.length)
    for j in range(n):
        c, r = (2 * j + 1) / (2 * n), 1 / (2 * n) + _WIDEN
        head = _effective(flint, g, plant, arb_series([arb(c), arb(r)], prec=order + 1), name, order)[:order]
        try:
            top = _effective(flint, g, plant, arb_series([arb(c, r), arb(r)], prec=order + 1), name, order)[order]
        except CertificationError:  # the ball of the whole piece is too wide (e.g. a denominator about 0)
            top = arb("inf")
        floating = (
            float(values(np.array([plant.length * c]))[0]) * plant.length * math.exp(-float(plant.weight) * (1 - c))
        )
        if abs(floating - float(head[0].mid())) > _AGREEMENT * (1.0 + abs(floating)) + float(head[0].rad()):
            raise CertificationError(
                f"the gain {name} gives {float(head[0].mid())!r} on balls and {floating!r} on arrays at "
                f"x = {plant.length * c!r}: not the same function in ball arithmetic"
            )
        out.polys.append(arb_poly(head)(arb_poly([-arb(c) / arb(r), 1 / arb(r)])))
        out.remainder.append(abs(top))
        out.derivative.append(order * abs(top))
        out.size.append(sum((abs(x) for x in head), arb(0)))
    return out


def gain_models(flint: Any, plant: _Plant, g_u: Any, g_v: Any) -> tuple[int, _Models, _Models]:
    """Models of both gains on a common partition, refined until their remainders reach double precision."""
    arb = flint.arb
    n = 4
    while True:
        models = (_models(flint, g_u, plant, n, "g_u"), _models(flint, g_v, plant, n, "g_v"))
        fine = True
        for mod in models:
            scale = arb(0)
            for v in mod.size:
                scale = arb.max(scale, v)
            for v in mod.remainder:
                fine = fine and bool(v < TARGET * scale + arb(2.0**-60))
        if fine:
            return n, models[0], models[1]
        n *= 2
        if n > MAX_GAIN_PIECES:
            raise CertificationError(
                f"the integral gains need more than {MAX_GAIN_PIECES} Taylor models of order {ORDER} on [0, L] to "
                "reach double precision in ball arithmetic (a gain not analytic on [0, L], or varying too fast)"
            )


# --------------------------------------------------------------------------- sections


@dataclass
class _Section:
    """``U`` or ``V`` (module notes) as a polynomial in ``(xi, theta)`` and the bounds of its series."""

    rows: list[Any]  # rows[i]: the arb_poly in theta multiplying xi^i
    sup: Any  # sup |U| (all terms of the series)
    slope: Any  # sup |dU/dtheta|
    tail: Any  # sup of the dropped terms
    tail_slope: Any  # sup of their derivative


def _bi_mul(flint: Any, a: list[Any], b: list[Any]) -> list[Any]:
    out = [flint.arb_poly(0)] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] = out[i + j] + x * y
    return out


def _bi_axpy(flint: Any, acc: list[Any], c: Any, x: list[Any]) -> list[Any]:
    acc = acc + [flint.arb_poly(0)] * max(0, len(x) - len(acc))
    for i, v in enumerate(x):
        acc[i] = acc[i] + v * c
    return acc


def _sections(flint: Any, plant: _Plant, T: Any, Tv: Any, Tu: Any) -> tuple[_Section, _Section]:
    arb, arb_poly = flint.arb, flint.arb_poly
    P, M, Q = rational_ball(flint, plant.p), rational_ball(flint, plant.m), arb(plant.q)
    kappa = P * M
    a = kappa / (T * T)
    nu = [arb_poly([-Tv, 1]), arb_poly([Tv])]  # theta - t_v (1 - xi)
    rest = [arb_poly([Tv, -1]), arb_poly([Tu])]  # tau xi - nu
    step = [x * a for x in _bi_mul(flint, nu, rest)]
    # U = q h_11 + p W / tau: (c_w, c_22, c_11) = (p / tau, 0, q); V = h_22 + m q W / tau
    coef = {"U": (P / T, arb(0), Q), "V": (M * Q / T, arb(1), arb(0))}
    rows: dict[str, list[Any]] = {"U": [arb_poly(0)], "V": [arb_poly(0)]}
    tails = {w: series_tail(flint, abs(kappa), T, *(abs(x) for x in coef[w])) for w in coef}
    sup = {w: arb(0) for w in coef}
    slope = {w: arb(0) for w in coef}
    r = abs(kappa) / 4
    term_w, term_22, term_11 = [arb_poly(1)], [x * a for x in rest], [x * a for x in nu]
    k = 0
    while True:
        fk, fk1 = arb(math.factorial(k)), arb(math.factorial(k + 1))
        for w, (cw, c22, c11) in coef.items():
            rows[w] = _bi_axpy(flint, rows[w], cw / (fk * fk), term_w)
            rows[w] = _bi_axpy(flint, rows[w], c22 / (fk * fk1), term_22)
            rows[w] = _bi_axpy(flint, rows[w], c11 / (fk * fk1), term_11)
            size = abs(cw) * r**k / (fk * fk) + (abs(c22) + abs(c11)) * (abs(kappa) / T) * r**k / (fk * fk1)
            sup[w] += size
            slope[w] += arb(4 * (2 * k + 3)) / T * size
        k += 1
        if all(bool(tails[w][0](k) < arb(2.0**-90)) and bool(tails[w][1](k) < arb(2.0**-90)) for w in coef):
            break
        if k > 400:
            raise CertificationError("exact_gains: the coupling kappa = p m is too strong for the series of U, V")
        term_w, term_22, term_11 = (_bi_mul(flint, t, step) for t in (term_w, term_22, term_11))
    return tuple(  # type: ignore[return-value]
        _Section(rows[w], sup[w] + tails[w][0](k), slope[w] + tails[w][1](k), tails[w][0](k), tails[w][1](k))
        for w in ("U", "V")
    )


# --------------------------------------------------------------------------- the kernel


def _moments(flint: Any, models: _Models, n: int, rows: int) -> list[list[Any]]:
    """``out[j][i] = int_{j/n}^1 P(xi) xi^i dxi`` over the models of the pieces above ``j / n``."""
    arb = flint.arb
    out = [[arb(0)] * rows for _ in range(n + 1)]
    for j in range(n - 1, -1, -1):
        lo, hi = arb(j) / n, arb(j + 1) / n
        coefs = models.polys[j].coeffs()
        top = len(coefs) + rows
        plo, phi = [lo**e for e in range(top + 1)], [hi**e for e in range(top + 1)]
        for i in range(rows):
            piece = sum(
                (c * (phi[e + i + 1] - plo[e + i + 1]) / (e + i + 1) for e, c in enumerate(coefs)),
                arb(0),
            )
            out[j][i] = out[j + 1][i] + piece
    return out


def _partial(flint: Any, rows: list[Any], poly: Any, start: Any, end: Any) -> Any:
    """``int_{start(theta)}^{end} poly(xi) F(xi, theta) dxi`` (``F = sum_i rows[i] xi^i``, ``start`` affine)."""
    arb, arb_poly = flint.arb, flint.arb_poly
    q = [arb_poly(0)] * (len(rows) + max(1, len(poly.coeffs())) - 1)
    for k, c in enumerate(poly.coeffs()):
        for i, f in enumerate(rows):
            q[i + k] = q[i + k] + f * c
    upper = arb_poly(0)
    power = end
    acc = arb_poly(0)
    for i, row in enumerate(q):
        upper = upper + row * (power / arb(i + 1))
        power = power * end
    for i in range(len(q) - 1, -1, -1):
        acc = (acc + q[i] * (1 / arb(i + 1))) * start
    return upper - acc


def _kernel(plant: _Plant, g_u: Any, g_v: Any) -> tuple[DistributedDelay, ...]:
    """The terms of :func:`gain_terms` for ``plant`` (its ``t_v`` exact; on the grid: one term)."""
    if _is_zero(g_u) and _is_zero(g_v):
        return ()
    flint = require_flint()
    ulp = math.ulp(plant.tau)
    n_tau, n_v = round(plant.tau / ulp), round(plant.t_v / Fraction(ulp))
    if n_tau * ulp != plant.tau or not 0 < n_v < n_tau:
        raise CertificationError("exact_gains: the times of flight cannot be placed on a grid of ulp(tau)")
    kappa = abs(float(plant.p * plant.m))
    bits = PRECISION + math.ceil(12.0 * math.sqrt(kappa)) + ORDER * 7 + 64
    with precision(flint, bits):
        arb, arb_poly = flint.arb, flint.arb_poly
        T, Tv = arb(plant.tau), rational_ball(flint, plant.t_v)
        Tu = T - Tv
        n, mod_u, mod_v = gain_models(flint, plant, g_u, g_v)
        if min(n_v, n_tau - n_v) < 4 * n:
            raise CertificationError("exact_gains: t_v or t_u is too short against tau for a grid of ulp(tau)")
        sec_u, sec_v = _sections(flint, plant, T, Tv, Tu)
        n_rows = max(len(sec_u.rows), len(sec_v.rows))
        mom_u, mom_v = _moments(flint, mod_u, n, n_rows), _moments(flint, mod_v, n, n_rows)
        segments: list[tuple[int, int, Any, Any, Any]] = []  # (lo, hi, K_J, sup error, variation of the error)
        v_map, u_map = arb_poly([1, -1 / Tv]), arb_poly([-Tv / Tu, 1 / Tu])
        for branch in ("v", "u"):
            order = range(n - 1, -1, -1) if branch == "v" else range(n)
            for j in order:
                if branch == "v":
                    lo, hi = (2 * n_v * (n - j - 1) + n) // (2 * n), (2 * n_v * (n - j) + n) // (2 * n)
                    xi0 = v_map
                    point = mod_v.polys[j](xi0) * (1 / Tv)
                    err, var = mod_v.remainder[j] / Tv, 2 * mod_v.derivative[j] / Tv
                else:
                    nu = n_tau - n_v
                    lo, hi = n_v + (2 * nu * j + n) // (2 * n), n_v + (2 * nu * (j + 1) + n) // (2 * n)
                    xi0 = u_map
                    point = mod_u.polys[j](xi0) * (arb(plant.q) / Tu)
                    err, var = (
                        abs(arb(plant.q)) * mod_u.remainder[j] / Tu,
                        2 * abs(arb(plant.q)) * mod_u.derivative[j] / Tu,
                    )
                _check_segment(flint, xi0, lo * ulp, hi * ulp, j, n)
                end = arb(j + 1) / n
                series = point
                for sec, mod, mom in ((sec_u, mod_u, mom_u), (sec_v, mod_v, mom_v)):
                    for i, row in enumerate(sec.rows):
                        series = series + row * mom[j + 1][i]
                    series = series + _partial(flint, sec.rows, mod.polys[j], xi0, end)
                segments.append((lo, hi, series, err, var))
        smooth_sup, smooth_var = arb(0), arb(0)
        for sec, mod in ((sec_u, mod_u), (sec_v, mod_v)):
            rem, size = arb(0), arb(0)
            for x, y in zip(mod.remainder, mod.size):
                rem, size = arb.max(rem, x), arb.max(size, y)
            smooth_sup += rem * sec.sup + size * sec.tail
            smooth_var += 2 * (rem * sec.sup + size * sec.tail) + T * (rem * sec.slope + size * sec.tail_slope)
        err_max = arb(0)
        var_total = smooth_var
        for seg in segments:
            err_max = arb.max(err_max, seg[3] + smooth_sup)
            var_total += seg[4]
        sigma = rational_ball(flint, plant.shift) / T
        weight_sup = arb.max(arb(1), (sigma * T).exp())
        global_sup = err_max * weight_sup
        global_var = weight_sup * (abs(sigma) * T * err_max + var_total)
        kernel = _store(flint, segments, sigma, ulp, n_tau, global_sup, global_var)
        if kernel is None:
            return ()
        if plant.t_v == n_v * Fraction(ulp):
            return (kernel,)
        return kernel, _displacement(flint, kernel, segments[n - 1][2], segments[n][2], sigma, plant.t_v, n_v, ulp)


def _displacement(
    flint: Any, kernel: DistributedDelay, left: Any, right: Any, sigma: Any, t_v: Fraction, n_v: int, ulp: float
) -> DistributedDelay:
    """The term on the ``ulp(tau)`` between the node ``n_v ulp`` and the true jump ``t_v`` (module notes).

    ``kernel`` jumps at the node from ``left`` (the series of the last segment of ``theta < t_v``) to
    ``right``; on the part ``D`` between the node and ``t_v`` the true kernel is the other
    branch's. The term is zero within ``radius`` ``J = |e^{sigma theta} (left - right)|`` on the
    ulp plus the kernel's ``radius`` (the true branch within it of its series, the stored piece
    within it of the other's), and the variation on its interior is ``J`` (its jump at ``t_v``),
    plus the kernel's ``variation_radius`` (the same two errors on ``D``) and ``ulp`` times the
    slope of ``e^{sigma theta} (left - right)``.
    """
    arb = flint.arb
    node = n_v * ulp
    lo, hi = (node, node + ulp) if t_v > node else (node - ulp, node)
    hull = arb(lo).union(arb(hi))
    diff = left - right
    weight = (sigma * hull).exp()
    jump = abs(weight * diff(hull)) + arb(kernel.radius)
    slope = abs(weight * (sigma * diff(hull) + diff.derivative()(hull)))
    variation = jump + arb(kernel.variation_radius) + arb(ulp) * slope
    return zero_term(lo, hi, jump, variation)


def zero_term(lo: float, hi: float, radius: Any, variation: Any) -> DistributedDelay:
    """A term of zero kernel on ``[lo, hi]`` within the proven ``radius`` (sup) and ``variation`` (total variation)
    of the ``arb`` bounds given: it holds a kernel's mismatch on an ulp where a jump falls between two doubles."""
    return DistributedDelay(
        np.array([lo, hi]),
        None,
        interpolation="polynomial",
        coefficients=np.zeros((1, 1)),
        radius=ball_upper(radius),
        variation_radius=ball_upper(variation),
    )


def _check_segment(flint: Any, xi0: Any, lo: float, hi: float, j: int, n: int) -> None:
    """The model of piece ``j`` must hold where ``xi_0`` maps the segment ``[lo, hi]``."""
    arb = flint.arb
    low, high = arb(j) / n - arb(_WIDEN), arb(j + 1) / n + arb(_WIDEN)
    for t in (lo, hi):
        x = xi0(arb(t))
        if not (bool(x > low) and bool(x < high)):
            raise CertificationError("exact_gains: a segment of theta leaves the piece of its gain model")


def _store(
    flint: Any,
    segments: list[tuple[int, int, Any, Any, Any]],
    sigma: Any,
    ulp: float,
    n_tau: int,
    global_sup: Any,
    global_var: Any,
) -> DistributedDelay | None:
    """Expand every segment's polynomial into pieces of degree DEGREE, bisecting until each is stored to TARGET."""
    arb = flint.arb
    pieces = [[(lo, hi)] for lo, hi, *_ in segments]
    done: dict[tuple[int, int], tuple[list[float], Any, Any]] = {}
    while True:
        for seg, plist in zip(segments, pieces):
            for lo, hi in plist:
                if (lo, hi) not in done:
                    done[(lo, hi)] = expand_piece(flint, seg[2], sigma, lo * ulp, (hi - lo) * ulp)
        scale = arb(0)
        for plist in pieces:
            for piece in plist:
                scale = arb.max(scale, done[piece][2])
        threshold = TARGET * scale + arb(2.0**-60)
        refined, changed = [], False
        for plist in pieces:
            new: list[tuple[int, int]] = []
            for lo, hi in plist:
                if bool(done[(lo, hi)][1] < threshold):
                    new.append((lo, hi))
                elif hi - lo < 2:
                    raise CertificationError("exact_gains: a piece of the gain kernel cannot be bisected further")
                else:
                    mid = (lo + hi) // 2
                    new.extend([(lo, mid), (mid, hi)])
                    changed = True
            refined.append(new)
        pieces = refined
        if sum(len(p) for p in pieces) > MAX_PIECES:
            raise CertificationError(
                f"exact_gains: the gain kernel needs more than {MAX_PIECES} pieces to reach double precision"
            )
        if not changed:
            break
    flat = [piece for plist in pieces for piece in plist]
    coefs = [done[piece][0] for piece in flat]
    if not np.any(np.asarray(coefs)):
        return None
    sup_err, var_err = arb(0), arb(0)
    for piece in flat:
        sup_err = arb.max(sup_err, done[piece][1])
        var_err += done[piece][1]
    jumps = arb(0)
    for plist in pieces:  # inside a segment the kernel is continuous: a jump of the pieces is an error
        for left, right in itertools.pairwise(plist):
            jumps += abs(sum((arb(v) for v in done[left][0]), arb(0)) - arb(done[right][0][0]))
    sup = global_sup + sup_err
    ends = 2 * (len(segments) - 1) * sup  # at a segment's end the error jumps by at most twice its bound
    nodes = [lo * ulp for lo, _ in flat] + [n_tau * ulp]
    return DistributedDelay(
        np.asarray(nodes),
        None,
        interpolation="polynomial",
        coefficients=np.asarray(coefs),
        radius=ball_upper(sup),
        variation_radius=ball_upper(global_var + var_err + jumps + ends),
    )
