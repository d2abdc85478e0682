"""Proofs about the plant as given, from proofs about its loop with ``tau`` rounded to a double.

The loop of a plant with constant coefficients is built with the transport time ``tau_d``,
``tau = 1/lam + 1/mu`` computed in floating point (the delays of
:class:`~nrobust.quasipoly.QuasiPolynomial` are doubles), and the ratios ``p``, ``m`` exact
(:func:`~nrobust.hyperbolic.loops.exact_form.exact_ratios`). Since ``tau N~(tau t)`` depends on
``p``, ``m``, ``q`` and ``rho`` only (:mod:`~nrobust.hyperbolic.loops.exact_form`), the
characteristic function of an unfiltered law (open loop, U_BS, U_BS2(K), a proportional
state feedback) is ``G(tau s) + H(tau s) e^{-(delta / tau) tau s}`` with ``G``, ``H`` free of
``tau``. Its zeros for the plant as given (``tau``, delay ``delta``) are those for ``tau_d``
(delay ``delta tau_d / tau``) times ``tau_d / tau``. With ``r = tau / tau_d`` (a rational of
the user's doubles): delays (``delta*``, crossing delays, the Rouché ``delta_0``) scale by
``r``, frequencies, real parts and decay rates by ``1/r``, counts in half-planes are unchanged.
:func:`to_given_plant` applies the map to a proven result, each ball end rounded outward.

A filtered law (section 2.3.2) has ``F(s) = (1 + b s) G(tau s) + (1 + a s) H(tau s) e^{-delta s}``:
at ``s`` it is the loop built with ``tau_d`` and the filter ``(a / r, b / r)`` at ``r s``, with the
delay ``delta / r``. The loop as built carries the user's ``a``, ``b`` with radii that enclose
``a / r``, ``b / r`` (exact rationals), so a proof about it holds for that loop, and the same map
takes it to the plant as given. So do the output feedbacks whose observer is exact on an uncoupled
plant: an :class:`~nrobust.hyperbolic.loops.controllers.OutputFeedback` whose law reads no value of
the measurement's window (its loop is the law's), and a
:class:`~nrobust.hyperbolic.loops.controllers.CollocatedOutputFeedback` without an observer delay,
whose observer term ``(1 - Phi) k q e^{-tau s}`` and observer reflection's factor
``1 - kappa q e^{-tau s}`` are functions of ``tau s`` (their point coefficients, products of the
user's numbers, enclosed as exact rationals).

Counts in a rectangle are not invariant under the map (the rectangle would scale by ``r``):
they are proven on the plant's own function. With ``A``, ``B`` the factors of the loop as
built, the plant's loop at delay ``delta`` is ``A(r s) + B(r s) e^{-delta s}`` (``delta`` the
double given, exact): :func:`given_plant_balls` encloses it with ``r`` an ``arb`` ball, so a
winding number, a Krawczyk test or a zero-free piece of contour proven with it holds for
the plant as given.

The principal gains (``rho q``, ``K q``, ``k q``, times ``e^{sigma_0 tau}`` or
``e^{sigma_0 tau / 2}`` for a general plant) are doubles rounded from their exact values: the
loop carries each with a proven radius (``QuasiPolynomial(..., radii=...)``, enclosed from the
user's numbers by :func:`~nrobust.hyperbolic.loops.exact_form.gain_balls`), so a proof about the
loop as built holds for every loop with gains in those balls, the plant's among them, and the
map applies to it. A general plant with constant coefficients has ``tau = L/lam + L/mu``
(:func:`~nrobust.hyperbolic.loops.exact_form.exact_tau`). A state feedback's integral gains
enter by the kernel of ``I_g``, built with ``t_v / r`` (:func:`~nrobust.hyperbolic.loops.exact_gains.gain_terms`:
its jump between two doubles held by a proven term), so its loop too is the loop as built at
``r s``. Where the loop is not of these forms (an observer term with a kernel, an observer
delay: ``delta_o / r`` is not a double) the proof keeps a scope naming what is rounded and by
how much (:func:`rounded_parts`).
"""

from __future__ import annotations

import dataclasses
import math
from fractions import Fraction
from typing import Any, TypeVar

from ...balls import DelayedSumBalls
from ...bounds import RoucheDelayBound
from ...margins.crossing import Crossing
from ...margins.margin import DelayMargin
from ...roots.abscissa import SpectralAbscissa
from .controllers import characteristic, loop_factors, rounded_parts
from .exact_form import exact_tau, tau_ratio

__all__ = [
    "GivenPlantBalls",
    "built_delay",
    "exact_tau",
    "given_plant_balls",
    "given_plant_scale",
    "rounded_parts",
    "to_given_plant",
]

_R = TypeVar("_R", DelayMargin, SpectralAbscissa, RoucheDelayBound)


def given_plant_scale(system: Any, controller: Any, kernel_grid: int | None = None) -> Fraction | None:
    """``r = tau / tau_d``: the factor mapping proofs about the loop as built to the plant as given.

    :func:`~nrobust.hyperbolic.loops.exact_form.tau_ratio`: ``tau`` exactly (the user's doubles as
    rationals) over ``tau_d``, the double the loop is built with. None when the loop is not, in
    ``r s``, a loop of the same law built with ``tau_d`` and its gains enclosed (:func:`rounded_parts`
    says what is rounded): then the proofs hold for the loop as built.

    Parameters
    ----------
    system, controller, kernel_grid
        As given to :func:`~nrobust.hyperbolic.loops.controllers.loop_factors`.
    """
    if rounded_parts(system, controller, kernel_grid):
        return None
    return tau_ratio(system)


class GivenPlantBalls(DelayedSumBalls):
    """Enclosure of the plant's loop ``F(s) = A(r s) + B(r s) e^{-delta s}`` for every ``r`` in a ball (module notes).

    :class:`~nrobust.balls.DelayedSumBalls` with ``A``, ``B`` the factors of the loop as built (``B`` None at
    ``delta = 0``: ``A`` is then the whole loop ``A + B``, whose kernels on equal nodes cancel exactly),
    ``delta`` the plant's loop delay (a double, exact) and ``r`` :func:`given_plant_scale`.

    Parameters
    ----------
    A, B : QuasiPolynomial
        The factors of the loop as built.
    delta : float
        The loop delay of the plant, ``>= 0``.
    r : Fraction
        :func:`given_plant_scale` (1 where only ``delta`` is kept exact).
    prec : int
        Working precision in bits.
    """


def given_plant_balls(
    system: Any, controller: Any, delta: float = 0.0, kernel_grid: int | None = None, prec: int = 53
) -> GivenPlantBalls | None:
    """The ball enclosure of the plant's own loop ``F(s; delta)``, ``tau = 1/lam + 1/mu`` exactly.

    Parameters
    ----------
    system, controller, kernel_grid
        As given to :func:`~nrobust.hyperbolic.loops.controllers.loop_factors`.
    delta : float, optional
        The loop delay (``>= 0``).
    prec : int, optional
        Working precision in bits.

    Returns
    -------
    GivenPlantBalls or None
        None when :func:`given_plant_scale` is None (the proofs are about the loop as built,
        its scope says what is rounded) or 1 (the loop as built is the plant's: its own
        :func:`~nrobust.balls.ball_function` applies), unless ``delta > 0`` moves a point delay
        ``t`` of ``B`` to a sum ``t + delta`` that is not a double
        (:meth:`~nrobust.quasipoly.QuasiPolynomial.shift_is_exact`): ``F = A + B.shift(delta)``
        then holds it rounded, and the enclosure, with ``r = 1`` in that case, is of
        ``A + B e^{-delta s}`` with ``delta`` exact.
    """
    r = given_plant_scale(system, controller, kernel_grid)
    if delta == 0.0:
        if r is None or r == 1:
            return None
        return GivenPlantBalls(characteristic(system, controller, 0.0, kernel_grid), None, 0.0, r, prec)
    A, B = loop_factors(system, controller, kernel_grid)
    if (r is None or r == 1) and B.shift_is_exact(delta):
        return None
    # the delays t + delta of F's point terms round: B e^{-delta s} is enclosed as a product, delta exact
    return GivenPlantBalls(A, B, delta, Fraction(1) if r is None else r, prec)


def _near(x: Fraction) -> float:
    return float(x)


def _down(x: Fraction) -> float:
    f = float(x)
    return math.nextafter(f, -math.inf) if Fraction(f) > x else f


def _up(x: Fraction) -> float:
    f = float(x)
    return math.nextafter(f, math.inf) if Fraction(f) < x else f


def _map(x: float | None, factor: Fraction, rounding: Any = _near) -> Any:
    """``x * factor`` rounded by ``rounding``; infinities, nan and None pass unchanged."""
    if x is None or not math.isfinite(x):
        return x
    return rounding(Fraction(x) * factor)


def _ball(ball: tuple[float, ...] | None, factor: Fraction) -> Any:
    """``(lo, hi[, lo, hi])`` times ``factor > 0``, each end rounded outward."""
    if ball is None:
        return None
    return tuple(_map(v, factor, _down if i % 2 == 0 else _up) for i, v in enumerate(ball))


def built_delay(delta_max: float | None, system: Any, controller: Any, kernel_grid: int | None = None) -> float | None:
    """The delay range of the loop as built whose analysis covers the plant's delays up to ``delta_max``.

    Delays of the plant are those of the loop as built times ``r`` (:func:`given_plant_scale`):
    when ``r < 1`` the loop as built is analysed up to ``delta_max / r`` (rounded up), so that
    the mapped analysis reaches ``delta_max``; otherwise up to ``delta_max`` itself (it reaches
    ``r delta_max >= delta_max``). :func:`to_given_plant` with ``delta_max`` then cuts the mapped
    result at ``delta_max``.
    """
    r = given_plant_scale(system, controller, kernel_grid)
    if delta_max is None or not math.isfinite(delta_max) or r is None or r >= 1:
        return delta_max
    return _up(Fraction(delta_max) / r)


def _crossing(c: Crossing, r: Fraction, end: float) -> Crossing:
    """A crossing of the loop as built mapped to the plant's delays (``* r``) up to ``end``: each delay's
    accuracy times ``r``, rounded up, plus the rounding of the mapped delay."""
    delays = [_map(d, r) for d in c.delays]
    keep = [d <= end for d in delays]
    accuracies = tuple(
        None if a is None else math.nextafter(_map(a, r, _up) + math.ulp(d), math.inf)
        for a, d, kept in zip(c.delay_accuracies, delays, keep)
        if kept
    )
    return dataclasses.replace(
        c,
        omega=_map(c.omega, 1 / r),
        delays=tuple(d for d, kept in zip(delays, keep) if kept),
        ds_ddelta=complex(c.ds_ddelta) / float(r * r),
        delay_accuracy=accuracies[0] if accuracies else None,
        delay_accuracies=accuracies,
    )


def _margin(result: DelayMargin, r: Fraction, delta_max: float | None = None) -> DelayMargin:
    ball = _ball(result.margin_ball, r)
    margin = _map(result.margin, r)
    if ball is not None and math.isfinite(margin):
        margin = min(max(margin, ball[0]), ball[1])
    # the plant's range: the one asked (the analysis reached it, built_delay), else the analysis' own end
    end = result.delta_max if delta_max is None else delta_max

    def delay(x: float) -> float:  # a delay of the analysis: the range's end is the plant's range's end
        return end if x == result.delta_max else min(_map(x, r), end)

    crossings = tuple(_crossing(c, r, end) for c in result.crossings)
    intervals = tuple((delay(lo), delay(hi)) for lo, hi in result.intervals)
    counts = tuple((delay(lo), delay(hi), n) for lo, hi, n in result.counts)
    if delta_max is not None:  # analysed beyond the plant's range: what starts past its end is cut
        intervals = tuple((lo, hi) for lo, hi in intervals if lo < end)
        counts = tuple((lo, hi, n) for lo, hi, n in counts if lo < end)
    return dataclasses.replace(
        result,
        margin=margin,
        margin_ball=ball,
        omega=_map(result.omega, 1 / r),
        omega_error=_map(result.omega_error, 1 / r, _up) if result.omega_error else result.omega_error,
        frequency_bound=_map(result.frequency_bound, 1 / r, _up),
        crossings=crossings,
        intervals=intervals,
        counts=counts,
        delta_max=end,
    )


def _abscissa(result: SpectralAbscissa, r: Fraction) -> SpectralAbscissa:
    f = 1 / r
    region = result.region
    inner = (_map(region[0], f, _up), _map(region[1], f, _down), _map(region[2], f, _up), _map(region[3], f, _down))
    root = None if result.root is None else complex(_map(result.root.real, f), _map(result.root.imag, f))
    return dataclasses.replace(
        result,
        value=_map(result.value, f),
        root=root,
        chain_value=_map(result.chain_value, f),
        upper_bound=_map(result.upper_bound, f, _up),
        region=inner,
        strong_bound=_map(result.strong_bound, f),
        root_box=_ball(result.root_box, f),
        chain_bracket=_ball(result.chain_bracket, f),
        value_bracket=_ball(result.value_bracket, f),
        error_estimate=_map(result.error_estimate, f, _up),
    )


def _rouche(result: RoucheDelayBound, r: Fraction) -> RoucheDelayBound:
    return dataclasses.replace(
        result, delta_0=_map(result.delta_0, r, _down), total_variation=_map(result.total_variation, 1 / r, _up)
    )


def to_given_plant(
    result: _R, system: Any, controller: Any, kernel_grid: int | None = None, delta_max: float | None = None
) -> _R:
    """A proven result about the loop as built, mapped to the plant as given (module notes).

    Parameters
    ----------
    result : DelayMargin, SpectralAbscissa or RoucheDelayBound
        Proven (``rigorous``) for the loop of ``system`` and ``controller`` (delay ``0`` for an
        abscissa): delays are multiplied by :func:`given_plant_scale`, frequencies and real
        parts divided by it, each ball end rounded outward (a region searched inward).
    system, controller, kernel_grid
        As given to :func:`~nrobust.hyperbolic.loops.controllers.loop_factors`.
    delta_max : float, optional
        For a delay margin computed up to :func:`built_delay` of it: the plant's range, at which
        the mapped intervals, counts and crossing delays are cut.

    Returns
    -------
    The same type: ``result`` itself when it is not proven, when the scale is 1 (``tau`` a
    double) or None (:func:`rounded_parts`: then its scope says what it is about).
    """
    if not result.rigorous:
        return result
    r = given_plant_scale(system, controller, kernel_grid)
    if r is None or r == 1:
        return result
    if isinstance(result, DelayMargin):
        return _margin(result, r, delta_max)  # type: ignore[return-value]
    if isinstance(result, SpectralAbscissa):
        return _abscissa(result, r)  # type: ignore[return-value]
    return _rouche(result, r)
