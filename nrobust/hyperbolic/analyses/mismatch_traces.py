"""The gains of ``U_BS2(K)`` on a plant with constant couplings, enclosed: :func:`reflection_traces`.

``U_BS2(K)`` (eq. (53)) is ``U = -K u(t, 1) + int_0^1 g_u u + g_v v dx`` with the kernel traces
``g_u = K^{vu}(1, .) - (rho - K) K^{uu}(1, .)`` and ``g_v = K^{vv}(1, .) - (rho - K) K^{uv}(1, .)``, known on a
kernel grid only. They are enclosed here without solving the kernel equations in ball arithmetic, from the
loop of the nominal plant, which is exact (:mod:`~nrobust.hyperbolic.loops.exact_form`): on the plant they
are designed for, ``B = K q e^{-tau s} - int N~ e^{-nu s}`` must equal ``-(k u_factor + I_g)`` with
``k = -K`` (:mod:`~nrobust.hyperbolic.loops.exact_gains`), so the kernel of ``I_g`` is

    ``K[g](theta) = K U~(theta) + N~(theta)``,  ``theta`` in ``[0, tau]``,

and ``g -> K[g]`` is a Volterra operator of the second kind (the module notes of ``exact_gains``): for
``y`` in ``[0, 1]``, ``K[g](t_v (1 - y)) = g_v(y) / t_v + int_y^1 (g_u U + g_v V)(xi, t_v (1 - y)) dxi`` and
``K[g](t_v + t_u y) = q g_u(y) / t_u + int_y^1 (g_u U + g_v V)(xi, t_v + t_u y) dxi``.

The traces are Chebyshev polynomials ``h`` (:class:`ChebyshevGain`, evaluable in ball arithmetic) of degree
:data:`CHEBYSHEV_DEGREE` solving that identity by collocation (:func:`_solved`: ``K`` is linear, so the images
``K[T_j]`` of the basis, from the exact route of :func:`~nrobust.hyperbolic.loops.exact_gains.gain_kernel`, give
a least-squares problem at Chebyshev points on each side of ``t_v``; condition about 2 on the paper's plant), and
the residual ``R = K[h] - K U~ - N~`` is bounded in ball arithmetic
(:func:`_residual`: the three kernels' pieces on a common partition, their proven radii added). The error
``e = h - g`` solves ``K[e] = R``; with ``E(y) = max(|e_u(y)|, |e_v(y)|)``,
``c_1 = max(t_v, t_u / |q|)`` and ``c_2 = (sup |U| + sup |V|)``,
``E(y) <= c_1 sup |R| + c_1 c_2 int_y^1 E``, and Gronwall's lemma gives
``sup |e| <= c_1 sup |R| e^{c_1 c_2}``: the law's gains are ``h`` within that bound.

How ``h`` is found does not enter the bound; its size does. Fitted to the traces of the kernel route on 201
points (cubic splines), the bound was ``2.9e-5`` on the paper's plant, ``9.7e-8`` on ``(1, 2, 0.4, 0.5, 1, 0.3)``
and ``0.94`` on ``(1, 1, 2, 2, 1, 0.5)``; solved by collocation ``4.1e-12``, ``1.1e-13`` and ``3.1e-7`` (the
proven radii of the exact kernels, about ``1e-15``, times Gronwall's factor).

The error ``e`` also has a bounded variation (:func:`trace_enclosure`), and the law with the gains ``h``
on any plant with constant couplings has the true law's term within two zero kernels of proven radii and
variations (:func:`gain_error_terms`): a proof about that loop holds for the true law.

The Volterra identity is that of the plant the exact forms describe, whose round trip is the double ``tau`` and
``t_v`` on the grid of ``ulp(tau)``: the enclosure is refused (:class:`~nrobust.errors.CertificationError`)
unless both are the plant's own (e.g. ``lam = mu = 1``).
"""

from __future__ import annotations

import itertools
import math
import warnings
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ..._flint import ball_upper, precision, require_flint
from ...errors import CertificationError
from ...quasipoly import DistributedDelay
from ..loops.controllers import StateFeedback
from ..loops.exact_form import PRECISION, exact_form, has_exact_form, rational_ball
from ..loops.exact_gains import gain_kernel, gain_plant
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from .mismatch_gains import section_bounds

__all__ = [
    "CHEBYSHEV_DEGREE",
    "ChebyshevGain",
    "TraceEnclosure",
    "gain_error_terms",
    "reflection_traces",
    "trace_enclosure",
]

#: Degree of the Chebyshev polynomials of the traces: on the paper's plant the proven bound is ``3.3e-11`` at degree
#: 10, ``4.1e-12`` at 12, ``3.4e-12`` at 16 (the kernels' radii dominate), the images of the basis cost 0.5, 0.8
#: and 1.6 s (each a kernel enclosed to double precision, finer for higher degrees).
CHEBYSHEV_DEGREE = 12


@dataclass(frozen=True)
class ChebyshevGain:
    """``x -> sum_j c_j T_j(2 x - 1)`` on ``[0, 1]`` (Clenshaw's recurrence: arithmetic only, so it evaluates on
    arrays and on python-flint series alike)."""

    coefficients: tuple[float, ...]

    def __call__(self, x: Any) -> Any:
        y = 2 * x - 1
        b1: Any = 0.0
        b2: Any = 0.0
        for c in reversed(self.coefficients[1:]):
            b1, b2 = 2 * y * b1 - b2 + c, b1
        return y * b1 - b2 + self.coefficients[0]


def _chebyshev_points(n: int) -> NDArray[np.float64]:
    """The ``n`` Chebyshev points of ``(0, 1)``."""
    return 0.5 * (1.0 + np.cos(np.pi * (np.arange(n) + 0.5) / n))


def _solved(
    system: Hyperbolic2x2, K: float, t_v: float, u_tilde: DistributedDelay, n_tilde: DistributedDelay
) -> tuple[ChebyshevGain, ChebyshevGain]:
    """The Chebyshev polynomials ``(h_u, h_v)`` of degree :data:`CHEBYSHEV_DEGREE` with ``K[h] = K U~ + N~`` in the
    least-squares sense at ``2 (CHEBYSHEV_DEGREE + 1)`` Chebyshev points of each of ``(0, t_v)`` and ``(t_v, tau)``
    (``K[h]`` jumps at ``t_v``), from the images of the basis (module notes; floating point, the bound is proven
    afterwards)."""
    degree = CHEBYSHEV_DEGREE
    points = _chebyshev_points(2 * (degree + 1))
    theta = np.concatenate([t_v * points, t_v + (system.tau - t_v) * points])
    columns = []
    for side in ("u", "v"):
        for j in range(degree + 1):
            basis = ChebyshevGain(tuple(1.0 if i == j else 0.0 for i in range(degree + 1)))
            image = gain_kernel(system, basis, 0.0) if side == "u" else gain_kernel(system, 0.0, basis)
            if image is None:
                raise CertificationError("a basis function of the traces has no kernel: nothing to solve")
            columns.append(np.real(image.kernel_at(theta)))
    target = K * np.real(u_tilde.kernel_at(theta)) + np.real(n_tilde.kernel_at(theta))
    coefs = np.linalg.lstsq(np.array(columns).T, target, rcond=None)[0]
    return ChebyshevGain(tuple(map(float, coefs[: degree + 1]))), ChebyshevGain(tuple(map(float, coefs[degree + 1 :])))


def _pieces(kernel: DistributedDelay) -> list[tuple[float, float, float, Any]]:
    """``(start, end, length, coefficients)`` of each piece of a polynomial kernel: ``N(start + length t) =
    sum_l c_l t^l`` on ``[start, end]`` (the nodes as stored, the length as the ball evaluation takes it)."""
    if kernel.moment != 0 or not np.array_equal(np.asarray(kernel.poly), [1.0]):
        raise CertificationError("a kernel with a polynomial factor or moment: not a kernel of the exact forms")
    start, h, coefs = kernel.pieces
    nodes = np.asarray(kernel.nodes, dtype=float)
    return [(float(a), float(b), float(w), c) for a, b, w, c in zip(start, nodes[1:], h, coefs)]


def _on(flint: Any, pieces: list[tuple[float, float, float, Any]], lo: float, hi: float, factor: float) -> Any:
    """``factor`` times the piece covering ``[lo, hi]`` as an ``arb_poly`` in ``t``, ``theta = lo + (hi - lo) t``."""
    arb, arb_poly = flint.arb, flint.arb_poly
    for a, b, h, c in pieces:
        if a <= lo and hi <= b:
            local = arb_poly([(arb(lo) - arb(a)) / arb(h), (arb(hi) - arb(lo)) / arb(h)])
            return arb_poly([arb(float(v)) * factor for v in c])(local)
    raise CertificationError("the kernels' pieces do not cover [0, tau]")


class _Residual(NamedTuple):
    """Bounds of ``R = K[h] - K U~ - N~`` (the module notes), the stored kernels' radii included."""

    sup: Any  # sup |R| on [0, tau]
    variation_v: Any  # its total variation on (0, t_v)
    variation_u: Any  # on (t_v, tau)


def _residual(
    flint: Any, fitted: DistributedDelay, K: float, u_tilde: DistributedDelay, n_tilde: Any, t_v: float
) -> _Residual:
    """Bounds of ``|K[h] - K U~ - N~|`` on ``[0, tau]`` and of its total variation on each side of ``t_v``.

    On each piece of the common partition the difference is a polynomial ``sum_l c_l t^l`` in ``t`` on
    ``[0, 1]``: ``|.| <= sum_l |c_l|`` and its variation ``<= sum_l l |c_l|``; a jump of the pieces at a node
    other than ``t_v`` adds to the variation of its side. The true kernels are within ``radius`` of the
    stored ones, their differences of total variation at most ``variation_radius``.
    """
    arb = flint.arb
    parts = [(_pieces(fitted), 1.0), (_pieces(u_tilde), -K)]
    radius = arb(fitted.radius) + abs(arb(K)) * arb(u_tilde.radius)
    spread = arb(fitted.variation_radius) + abs(arb(K)) * arb(u_tilde.variation_radius)
    if n_tilde is not None:
        parts.append((_pieces(n_tilde), -1.0))
        radius += arb(n_tilde.radius)
        spread += arb(n_tilde.variation_radius)
    cuts = sorted({x for pieces, _ in parts for a, b, _, _ in pieces for x in (a, b)})
    if t_v not in cuts:  # a cell across t_v would book its part on the v side to the u side's variation
        raise CertificationError(
            f"the kernels' pieces do not meet at t_v = {t_v!r}: the variations on each side of it are not separated"
        )
    sup = arb(0)
    variation = {"v": arb(0), "u": arb(0)}
    previous = None  # the value of the last piece at its right end, within the same side of t_v
    for lo, hi in itertools.pairwise(cuts):
        diff = sum((_on(flint, pieces, lo, hi, f) for pieces, f in parts), flint.arb_poly(0))
        coefs = diff.coeffs() or [arb(0)]
        sup = arb.max(sup, sum((abs(c) for c in coefs), arb(0)))  # |sum c_l t^l| <= sum |c_l| on [0, 1]
        side = "v" if hi <= t_v else "u"
        if previous is not None and lo != t_v:
            variation[side] += abs(coefs[0] - previous)
        variation[side] += sum((j * abs(c) for j, c in enumerate(coefs)), arb(0))
        previous = sum(coefs, arb(0))
    return _Residual(sup + radius, variation["v"] + spread, variation["u"] + spread)


@dataclass(frozen=True)
class TraceEnclosure:
    """``U_BS2(K)``'s law with Chebyshev gains ``h`` and proven bounds of ``e = h - g`` (``g`` the true traces).

    Attributes
    ----------
    law : StateFeedback
        ``StateFeedback(-K, h_u, h_v)``, :class:`ChebyshevGain` gains.
    error : float
        ``sup |e_u|, sup |e_v| <= error`` on ``[0, 1]``.
    variation_u, variation_v : float
        Bounds of the total variations of ``e_u`` and ``e_v`` on ``(0, 1)``.
    """

    law: StateFeedback
    error: float
    variation_u: float
    variation_v: float


def reflection_traces(system: Hyperbolic2x2, K: float, kernel_grid: int | None = None) -> tuple[StateFeedback, float]:
    """``U_BS2(K)``'s law on ``system`` as a :class:`StateFeedback` with polynomial gains and the bound of their
    distance to the true gains (module notes; :func:`trace_enclosure` adds the bounds of its variation).

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant the law is designed for, with constant couplings (``has_exact_form``), ``q != 0``.
    K : float
        The reflection gain of eq. (53).
    kernel_grid : int, optional
        Deprecated and not used (the traces were fitted on that kernel grid; they are now solved by
        collocation): a value emits a :class:`DeprecationWarning`.

    Returns
    -------
    (StateFeedback, float)
        ``StateFeedback(-K, h_u, h_v)`` with :class:`ChebyshevGain` gains, and ``delta`` with
        ``|h_u - g_u|, |h_v - g_v| <= delta`` on ``[0, 1]``.

    Raises
    ------
    CertificationError
        A plant outside the closed form, ``q = 0``, a round trip or ``t_v`` that are not the plant's own
        doubles, or gains that cannot be enclosed.
    """
    _no_grid("reflection_traces", kernel_grid)
    enclosure = trace_enclosure(system, K)
    return enclosure.law, enclosure.error


def _no_grid(name: str, kernel_grid: int | None) -> None:
    """The deprecation of the ``kernel_grid`` of :func:`reflection_traces` and :func:`trace_enclosure`."""
    if kernel_grid is not None:
        warnings.warn(
            f"{name}: kernel_grid is deprecated and not used (the traces are solved by collocation, not fitted on "
            "a kernel grid)",
            DeprecationWarning,
            stacklevel=3,
        )


def trace_enclosure(system: Hyperbolic2x2, K: float, kernel_grid: int | None = None) -> TraceEnclosure:
    """:func:`reflection_traces` with the bounds of the variation of the error ``e = h - g``.

    ``e`` solves ``K[e] = R`` on the plant the law is designed for (module notes), so
    ``e_v(y) = t_v (R - J)(t_v (1 - y))`` and ``e_u(y) = t_u / q (R - J)(t_v + t_u y)`` with
    ``J(theta) = int_{xi_0(theta)}^1 (e_u U + e_v V)(xi, theta) dxi``. With ``|e| <= delta``,
    ``|U|, |V| <= s_U / tau, s_V / tau`` and ``|dU/dtheta|, |dV/dtheta| <= s'_U / tau^2, s'_V / tau^2``
    (:func:`~nrobust.hyperbolic.analyses.mismatch_gains.section_bounds`: the sections scaled by ``tau``), the
    variation of ``J`` on ``(0, t_v)`` is at most ``delta ((s_U + s_V) / tau + t_v (s'_U + s'_V) / tau^2)``
    (``|d xi_0 / d theta| = 1 / t_v``), and on ``(t_v, tau)`` the same with ``t_u``; the variation of ``R`` on
    each side is bounded from its pieces (:func:`_residual`). Its parameters and errors are those of
    :func:`reflection_traces`.

    Returns
    -------
    TraceEnclosure
    """
    _no_grid("trace_enclosure", kernel_grid)
    return _trace_enclosure(system, K)


@lru_cache(maxsize=8)
def _trace_enclosure(system: Hyperbolic2x2, K: float) -> TraceEnclosure:
    """:func:`trace_enclosure` (cached)."""
    if not has_exact_form(system) or system.uncoupled:
        raise CertificationError("the traces are enclosed on a coupled plant with the closed form only")
    if system.q == 0.0:
        raise CertificationError("q = 0: the Volterra equation of the traces is of the first kind")
    tau = system.tau
    ulp = math.ulp(tau)
    t_v = round((1.0 / system.mu) / ulp) * ulp
    exact_tau = 1 / Fraction(system.lam) + 1 / Fraction(system.mu)
    if Fraction(tau) != exact_tau or Fraction(t_v) != 1 / Fraction(system.mu):
        raise CertificationError(
            "the round trip 1/lam + 1/mu or the time of flight 1/mu of this plant is not a double: the Volterra "
            "identity of the exact forms holds for the rounded plant only"
        )
    form = exact_form(system)
    u_tilde = form.u_factor.distributed[0] if form.u_factor.distributed else None
    if u_tilde is None or form.N_tilde is None:
        raise CertificationError("U~ or N~ vanishes: nothing to enclose")
    fitted_law = StateFeedback(-K, *_solved(system, K, t_v, u_tilde, form.N_tilde))
    fitted = gain_kernel(system, fitted_law.g_u, fitted_law.g_v)
    if fitted is None:
        raise CertificationError("the traces vanish: nothing to enclose")
    flint = require_flint()
    with precision(flint, PRECISION):
        arb = flint.arb
        residual = _residual(flint, fitted, K, u_tilde, form.N_tilde, t_v)
        P = arb(float(system.sigma_pm)) / arb(system.lam)  # type: ignore[arg-type]
        M = -arb(float(system.sigma_mp)) / arb(system.mu)  # type: ignore[arg-type]
        sec = section_bounds(flint, P, M, system.q)
        T, Tv = arb(tau), arb(t_v)
        Tu = T - Tv
        Q = abs(arb(system.q))
        c1 = arb.max(Tv, Tu / Q)
        c2 = (sec["U"][0] + sec["V"][0]) / T  # the sections U, V of exact_gains are the scaled ones over tau
        slope = (sec["U"][1] + sec["V"][1]) / (T * T)
        delta = arb(ball_upper(c1 * residual.sup * (c1 * c2).exp()))
        variation_v = Tv * (residual.variation_v + delta * (c2 + Tv * slope))
        variation_u = Tu / Q * (residual.variation_u + delta * (c2 + Tu * slope))
        return TraceEnclosure(fitted_law, float(delta), ball_upper(variation_u), ball_upper(variation_v))


def gain_error_terms(enclosure: TraceEnclosure, plant: Hyperbolic2x2) -> tuple[DistributedDelay, DistributedDelay]:
    """Two zero kernels whose radii hold the kernel of ``I_e``, ``e = h - g``, in the loop of ``plant`` as built.

    The law with the gains ``h`` acts on ``plant`` (any speeds, the couplings of the plant the traces were
    designed on or others with the closed form) through the kernel of ``I_h`` of
    :func:`~nrobust.hyperbolic.loops.exact_gains.gain_terms`, built with ``tau_d`` and ``t_v = tau_d lam / (lam +
    mu)``; the true law's term is ``I_g = I_h - I_e``, and ``K[e]`` is linear in ``e`` (module notes), in the
    frame of the loop as built (``t_u = tau_d - t_v``, the sections ``U``, ``V`` of ``plant``)::

        |K[e]| <= delta (1 / t_v + (s_U + s_V) / tau_d)         on [0, t_v],
        |K[e]| <= delta (|q| / t_u + (s_U + s_V) / tau_d)       on [t_v, tau_d],

    its variation on ``(0, t_v)`` at most ``V_v / t_v + delta ((s_U + s_V) / tau_d + t_v (s'_U + s'_V) / tau_d^2)``
    and on ``(t_v, tau_d)`` ``|q| V_u / t_u`` plus the same with ``t_u`` (``V_u``, ``V_v`` the variations of
    ``e_u``, ``e_v``, :class:`TraceEnclosure`; the sups as in :func:`trace_enclosure`). ``t_v`` is not a double:
    the first term ends at the double ``t_-`` below it, the second starts there with the larger radius, and its
    variation holds the part of ``(t_-, t_v)``, the jump at ``t_v`` (at most the sum of the two radii) and the
    ``u`` side. Added to ``B`` (any sign: the terms are zero within their radii), every ball enclosure and
    bound of the far field holds for the loop of the true law.

    Parameters
    ----------
    enclosure : TraceEnclosure
        The law's gains and the bounds of their error (:func:`trace_enclosure`).
    plant : Hyperbolic2x2
        The plant the law acts on, with constant couplings.

    Returns
    -------
    (DistributedDelay, DistributedDelay)
        On ``[0, t_-]`` and ``[t_-, tau_d]``, zero within their ``radius`` and ``variation_radius``.
    """
    pl = gain_plant(plant, exact_times=True)
    if pl.shift != 0 or pl.weight != 0:
        raise CertificationError("the gains' error terms are built for a Hyperbolic2x2 (no exponential weight)")
    flint = require_flint()
    with precision(flint, PRECISION):
        arb = flint.arb
        T, Tv = arb(pl.tau), rational_ball(flint, pl.t_v)
        Tu = T - Tv
        Q = abs(arb(pl.q))
        sec = section_bounds(flint, rational_ball(flint, pl.p), rational_ball(flint, pl.m), pl.q)
        c = (sec["U"][0] + sec["V"][0]) / T
        slope = (sec["U"][1] + sec["V"][1]) / (T * T)
        delta = arb(enclosure.error)
        radius_v, radius_u = delta * (1 / Tv + c), delta * (Q / Tu + c)
        variation_v = arb(enclosure.variation_v) / Tv + delta * (c + Tv * slope)
        variation_u = Q * arb(enclosure.variation_u) / Tu + delta * (c + Tu * slope)
        below = float(pl.t_v)
        if Fraction(below) > pl.t_v:
            below = math.nextafter(below, -math.inf)
        if not 0.0 < below < pl.tau:
            raise CertificationError("the time of flight t_v leaves (0, tau) in floating point")
        zero = np.zeros((1, 1))
        first = DistributedDelay(
            np.array([0.0, below]),
            None,
            interpolation="polynomial",
            coefficients=zero,
            radius=ball_upper(radius_v),
            variation_radius=ball_upper(variation_v),
        )
        second = DistributedDelay(
            np.array([below, pl.tau]),
            None,
            interpolation="polynomial",
            coefficients=zero,
            radius=ball_upper(arb.max(radius_v, radius_u)),
            variation_radius=ball_upper(variation_u + variation_v + radius_v + radius_u),
        )
        return first, second
