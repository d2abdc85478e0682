"""One gain, exactly: the gain of an affine loop that maximises its delay margin or its decay rate.

The loop is an :class:`~nrobust.margins.AffineGainLoop`,
``F(s; delta, K) = A(s) + (B_0(s) + K R(s)) e^{-delta s}`` (``U_BS2(K)``'s, eq. (60), is one), or
an :class:`AffineLoop`, affine in its parameter in both factors,
``(A_0 + K A_1) + (B_0 + K B_1) e^{-delta s}`` (the filtered law's pole ``b`` enters ``A``):
``g`` below is then ``c_0 + 2 h K + c_2 K^2`` with ``c_2 = |A_1|^2 - |B_1|^2``, its roots
``K_pm = m +- sqrt(D)`` as explicit, and the same equations apply with ``A`` depending on ``K``
(a branch passes through ``K = inf`` where ``c_2`` changes sign, and the finite root, ``-c_0 / (2 h)``
there, moves to the other branch: the curves are cut there too, both pieces ending at that root).
Its delay margin ``delta*(K)`` is the lower envelope of the *crossing curves*: on
``s = i w`` a root lies on the axis when ``g(w; K) = |A(i w)|^2 - |B(i w; K)|^2 = 0``, which
is quadratic in ``K`` with the explicit roots ``K_pm(w) = m(w) +- sqrt(D(w))``
(:mod:`nrobust.margins.gain`), at the delay ``d(w) = theta(w) / w``,
``theta = arg(-B(i w; K)/A(i w)) in [0, 2 pi)``. Each branch, cut where ``K_pm(w)`` turns
(a *pair birth*: ``g = dg/dw = 0``), where ``D < 0`` or where ``theta`` wraps (solved between
the samples: the nominal loop changes stability there), is a curve
``w -> (K(w), d(w))`` with ``K`` monotone, and ``delta*(K)`` is the smallest ``d`` over the
curves that reach ``K`` (zero where the nominal loop is unstable). It is neither smooth nor
continuous, and its maximum over ``[K_lo, K_hi]`` is one of:

* a *kink*: two curves meet, ``g(w_1; K) = g(w_2; K) = 0`` and ``d_1 = d_2``: a Newton
  iteration in ``(K, w_1, w_2)`` with the exact Jacobian;
* a *pair birth*: the envelope jumps down where a curve is born (``dK/dw = 0``, solved in its
  bracket in ``w``); the supremum is approached from the side without the pair and not
  attained, so the design is that gain moved ``1e-10`` (relative) to that side;
* an *interior smooth max* of one curve: ``d(d)/dw = 0`` along the branch (``brentq``);
* an *end* of ``[K_lo, K_hi]``.

:func:`best_margin` samples the curves on a uniform frequency grid up to a frequency bound
of the whole gain range (:class:`~nrobust.margins.gain.AxisBound`, else
:func:`~nrobust.margins.frequency_bound`), builds the envelope on a fine gain grid, solves the
equation of the event at each local maximum near the top, and certifies the design: the
delay margin at the gain found (:func:`nrobust.margins.delay_margin`, proven in ball
arithmetic with ``rigorous=True``) must equal the value of the equations, else a
:class:`~nrobust.errors.CertificationError` says that the scan missed a curve.
:func:`best_decay_rate` maximises the decay rate ``-alpha(K)`` (``alpha`` the spectral
abscissa at ``delta = 0``) subject to ``delta*(K) >= d``: the feasible gains are where the
envelope is at least ``d``, ended by a curve crossing the level ``d`` (the *crossing* end of
:func:`~nrobust.margins.locate_gain_ends`) or a pair birth below it. A feasible gain at which the
nominal loop is one term ``c e^{-h s}`` (no zero: finite-time convergence, ``U_BS2(K)`` at
``K = rho``) has an infinite decay rate, unbounded about it: it is the design (*finite time*).
Between samples of the rate the rightmost zeros are followed in ``K`` (Newton continuation, the
sensitivity ``ds/dK = -F_K / F'``): a maximum is where two zeros' real parts cross (a *kink*)
or where one's slope vanishes (an *interior smooth max*), each solved by ``brentq``. With ``worst_case=True``
it maximises the least rate of the loop and its scenarios (loops of the same gain, e.g. on plants with speed
errors): an end, a peak of one rate, or a *tie* where two rates are equal (``brentq`` on their difference).

Features of the curves narrower than the scan step (``pi / (32 T)``, ``T`` the longest delay
of the factors, or ``W / 256``, ``W`` the frequency bound) can be missed (near the
strong-stability bound, crossing pairs are born within tiny gain intervals: on the paper's
plant, gains within about 1 % of it); the returned margin is certified whatever happens between
samples, and a missed curve that would lower it is caught by the certificate
(:class:`~nrobust.errors.CertificationError`, never a wrong margin). About a pole (a branch
through ``p = inf``) the step is halved until no junction shares the pole's cell and the branch
through infinity has passed the bounds at the samples on both sides.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from fractions import Fraction
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._bracket import illinois
from .._digits import inner_interval_text, with_accuracy
from .._json import fields_dict
from .._threads import one_blas_thread
from .._validate import finite_real, positive, positive_int
from ..bounds import TailBound, joint_degree, min_delay, principal_gap, radius_where
from ..distributed_delay import DistributedDelay, moment_integrals, polyder, polyval
from ..errors import CertificationError, ParameterError
from ..margins.axis import frequency_bound
from ..margins.count import unstable_count
from ..margins.gain import AffineGainLoop, AxisBound, GainEnd, nominally_stable
from ..margins.margin import DelayMargin, delay_margin
from ..margins.proven import proven_crossings
from ..quasipoly import QuasiPolynomial, QuasiPolynomialsAtPoint
from ..roots import SpectralAbscissa, count_roots, spectral_abscissa

__all__ = [
    "DESIGN_KINDS",
    "AffineLoop",
    "DelayWindow",
    "GainDesign",
    "best_decay_rate",
    "best_margin",
    "check_delays",
    "window_requirement",
    "window_stability",
]

#: Kinds of an optimal gain (:attr:`GainDesign.kind`).
DESIGN_KINDS = (
    "kink",
    "pair birth",
    "end",
    "interior smooth max",
    "margin constraint",
    "no crossing",
    "window end",
    "window",
    "finite time",
    "plateau",
    "tie",
)
# Samples of the axis per half period pi / T of the fastest oscillation of the factors.
_STEPS = 32
# Samples of the axis up to the frequency bound, at least.
_MIN_SAMPLES = 256
# Below the uniform step ``dw``: geometric samples, this many per octave over this many octaves (a crossing
# curve ends at ``w = 0`` where ``|A(0)| = |B(0)|``, its gain moving as ``w^2``: the last octaves cover gains
# within about ``4^-_LOW_OCTAVES`` of that end, relative).
_PER_OCTAVE = 4
_LOW_OCTAVES = 26
# Evaluations of the factors per sample of the axis (values and slopes of A, B_0, R).
_EVALS_PER_SAMPLE = 6
# Gains of the envelope grid.
_N_GAINS = 2001
# A gain whose supremum is not attained (a pair birth) is moved this far (relative) to the good side.
_OFFSET = 1e-10
# Local maxima of the sampled envelope within this fraction of the largest are solved.
_NEAR_TOP = 0.05
_NEWTON_STEPS = 30
# Relative Newton step below which steps that stop halving are the rounding floor of g (a loop whose
# distributed terms were computed in floating point, e.g. an output feedback's observer term).
_NOISE_STEP = 1e-12
_TWO_PI = 2.0 * np.pi
#: Secant steps that take a junction (``D = 0``) from its Illinois estimate to rounding (superlinear from 1e-6).
_SECANT_STEPS = 8
#: Steps of a few ulps (growing by 4) that move a junction located to rounding to the side where ``D <= 0``.
_JUNCTION_NUDGES = 6
_EPS = float(np.finfo(float).eps)
#: Halvings of a sample cell about a pole of the crossing curves (:meth:`_Curves._split_poles`).
_POLE_SPLITS = 40


@dataclass(frozen=True, eq=False)
class GainDesign:
    """A gain chosen by :func:`best_margin` or :func:`best_decay_rate`, with its certificate.

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    K : float
        The designed gain (the designed parameter ``p`` of an :class:`AffineLoop`).
    objective : str
        ``"margin"`` or ``"decay_rate"``.
    value : float
        The objective at ``K``: the certified delay margin, or the decay rate ``-alpha`` of
        the loop at ``delta = 0``.
    margin : float
        The delay margin at ``K`` (``certificate.margin``).
    decay_rate : float
        ``-alpha(K)``, ``alpha`` the spectral abscissa of ``F(.; 0, K)``.
    kind : str
        What decides the optimum (:data:`DESIGN_KINDS`): ``"kink"`` (two crossing curves meet; for
        the decay rate, two zeros' paths in ``K`` cross, ``Re s_1 = Re s_2``),
        ``"pair birth"`` (the margin jumps down where a crossing pair is born: the supremum is
        not attained, ``K`` is ``1e-10`` (relative) on the good side), ``"interior smooth max"``,
        ``"end"`` (an end of the gain bounds), ``"margin constraint"`` (the decay rate is
        largest where ``delta*(K) = d``: :attr:`end` gives the event), ``"no crossing"``
        (an infinite margin), ``"finite time"`` (the nominal loop has no zero at ``K``: one term
        ``c e^{-h s}``, e.g. ``U_BS2(rho)`` = ``U_BS``; the decay rate is ``inf``, unbounded and not
        smooth about ``K``), ``"plateau"`` (the decay rate is flat about ``K``: its rightmost zero, or
        chain, does not move with the gain, e.g. a zero of a filter whose pole cancels it; every gain of
        :attr:`K_bracket` checked, at its ends and 9 gains inside, is optimal to the rate's accuracy),
        ``"tie"`` (with ``worst_case=True``: the least decay rate of the loop and its scenarios is largest
        where two of them are equal, ``r_i(K) = r_j(K)``).
    K_bracket : (float, float)
        The optimal gain lies in it (for a pair birth: the birth and ``K``); for a plateau, the interval about
        ``K`` on which the decay rate is within its accuracy of the optimum (checked at its ends, by bisection
        to ``2^-40`` of the feasible interval, and at 9 gains spread over it; not between them).
    value_bracket : (float, float)
        The optimal value (supremum) lies in it: the values the equations and the certificate give, widened by
        their accuracy (the certificate's for a margin, the abscissa's for a rate) and rounded outward.
    bounds : (float, float)
        The gains searched.
    certificate : DelayMargin
        The delay margin of the designed loop, proven in ball arithmetic when
        ``certified == "proven"``.
    certified : str
        ``"proven"`` (``delay_margin(..., rigorous=True)``) or ``"checked"`` (floating point,
        verified by a certified root count); with the reason when a proof was asked and failed.
    abscissa : SpectralAbscissa
        The spectral abscissa of ``F(.; 0, K)``.
    gains, envelope : ndarray
        The scan: ``delta*(K)`` interpolated on the sampled crossing curves at 2001 gains of
        ``bounds`` (0 where the nominal loop is unstable). What located the optimum, not a
        certificate (to draw ``delta*(K)``).
    end : GainEnd or None
        For ``"margin constraint"``: the end of the feasible gains (``"crossing"``: a crossing
        delay equals ``d``; ``"pair_birth"``: a pair born with delay below ``d``); for
        ``"window end"`` the event that ends the gains stable on the window (``"crossing"``: a
        branch of crossing delays through ``d_min`` or ``d_max``, given as ``delay``;
        ``"pair_birth"``; ``"nominal"``: ``s = 0`` a root for every delay).
    delays : (float, float) or None
        The window ``[d_min, d_max]`` required (:func:`best_decay_rate`'s ``delays``).
    windows : tuple of DelayWindow
        The window certified at ``K`` for the loop and then for each scenario
        (:func:`window_stability`); empty without ``delays``.
    feasible : tuple of (float, float)
        The intervals of gains meeting the window for every loop: an end inside the bounds of the
        gain is solved from its equation and moved ``1e-10`` (relative) inside, an end at a bound
        is that bound.
    nominal : QuasiPolynomial or None
        The nominal loop ``F(.; 0, K)`` whose spectral abscissa is :attr:`abscissa` (a caller holding a
        loop equal to it, ``==``, need not compute that abscissa again); not in :meth:`to_dict`.
    scenario_abscissae : tuple of SpectralAbscissa
        With ``worst_case=True`` (:func:`best_decay_rate`): the spectral abscissa at ``delta = 0`` of each
        scenario's loop at ``K``; ``value`` is the least decay rate of :attr:`abscissa` and these
        (:attr:`least_rate_accuracy`); empty otherwise.
    """

    K: float
    objective: str
    value: float
    margin: float
    decay_rate: float
    kind: str
    K_bracket: tuple[float, float]
    value_bracket: tuple[float, float]
    bounds: tuple[float, float]
    certificate: DelayMargin
    certified: str
    abscissa: SpectralAbscissa
    gains: NDArray[np.float64]
    envelope: NDArray[np.float64]
    end: GainEnd | None = None
    delays: tuple[float, float] | None = None
    windows: tuple[DelayWindow, ...] = ()
    feasible: tuple[tuple[float, float], ...] = ()
    nominal: QuasiPolynomial | None = None
    scenario_abscissae: tuple[SpectralAbscissa, ...] = ()

    @property
    def requirement(self) -> str:
        """The window requirement and its verdict in words: met and proven, met and checked, or not met."""
        return window_requirement(self.delays, self.windows)

    @property
    def accuracy(self) -> tuple[float, float]:
        """``(width of K_bracket, width of value_bracket)``: how tightly the optimum is known."""
        (k_lo, k_hi), (v_lo, v_hi) = self.K_bracket, self.value_bracket
        return (float(k_hi - k_lo), 0.0 if v_hi == v_lo else float(v_hi - v_lo))

    @property
    def least_rate_accuracy(self) -> float | None:
        """A bound of the error of the least decay rate of :attr:`abscissa` and :attr:`scenario_abscissae` (the
        least of values each within ``a_j`` of the true one is within ``max_j a_j`` of the true least); None when
        one abscissa's accuracy is not known."""
        accuracies = [sa.accuracy for sa in (self.abscissa, *self.scenario_abscissae)]
        return None if any(a is None for a in accuracies) else float(max(a for a in accuracies if a is not None))

    def __repr__(self) -> str:
        return self.summary()

    def summary(self, parameter: str = "K") -> str:
        """The repr with the designed parameter named ``parameter`` (``"kappa"``, ``"a"``, ``"b"``: what ``K`` is).

        Each number with the digits its accuracy supports: the parameter to the width of
        :attr:`K_bracket`, the margin to its certificate's accuracy (plus the width of
        :attr:`value_bracket` when it is the objective), the decay rate to its abscissa's.
        """
        k_acc, v_acc = self.accuracy
        # the margin at K is known to its certificate's accuracy; as the optimum, to the value bracket too
        margin_acc = self.certificate.accuracy
        if self.objective == "margin" and margin_acc is not None:
            margin_acc += v_acc
        least = ""
        if self.scenario_abscissae:
            acc = self.least_rate_accuracy
            least = f", least_rate={with_accuracy(self.value, None if acc is None else acc + v_acc)}"
        return (
            f"GainDesign({parameter}={with_accuracy(self.K, k_acc)}, objective={self.objective!r}, kind={self.kind!r}, "
            f"margin={with_accuracy(self.margin, margin_acc)}, "
            f"decay_rate={with_accuracy(self.decay_rate, self.abscissa.accuracy)}{least}, certified={self.certified!r})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (the certificate and abscissa as their dictionaries)."""
        data = fields_dict(self, exclude=("end", "nominal"))
        data["end"] = None if self.end is None else self.end._asdict()
        data["accuracy"] = list(self.accuracy)
        return data


@dataclass(frozen=True)
class AffineLoop:
    """A loop affine in one parameter in both factors: ``(A_0 + p A_1) + (B_0 + p B_1) e^{-delta s}``.

    :class:`~nrobust.margins.AffineGainLoop` is the case ``A_1 = 0`` (``B_1 = R``). The filtered
    law ``FilteredController(a, b, K)`` (eq. (60) with ``A`` multiplied by ``1 + b s`` and ``B``
    by ``1 + a s``) is affine in each of its parameters: in ``K`` and in ``a`` with ``A_1 = 0``,
    in the pole ``b`` with ``A_1 = s A_0`` and ``B_1 = 0``. On ``s = i w``,
    ``g(w; p) = |A|^2 - |B|^2 = c_0 + 2 h p + c_2 p^2`` is quadratic in ``p``
    (``c_2 = |A_1|^2 - |B_1|^2``), so the crossing curves are explicit as for a gain.

    Parameters
    ----------
    A0, A1, B0, B1 : QuasiPolynomial
        The factors at ``p = 0`` and their changes per unit ``p`` (a zero change is
        ``QuasiPolynomial([[0.0]], [0.0])``).
    """

    A0: QuasiPolynomial
    A1: QuasiPolynomial
    B0: QuasiPolynomial
    B1: QuasiPolynomial

    @classmethod
    def of(cls, loop: AffineGainLoop) -> AffineLoop:
        """``A + (B_0 + K R) e^{-delta s}`` as ``A_0 = A``, ``A_1 = 0``, ``B_0``, ``B_1 = R``."""
        return cls(loop.A, QuasiPolynomial([[0.0]], [0.0]), loop.B0, loop.R)

    def A(self, p: float) -> QuasiPolynomial:
        """The factor without delay ``A_0 + p A_1``."""
        return self.A0 + self.A1 * p

    def B(self, p: float) -> QuasiPolynomial:
        """The delayed factor ``B_0 + p B_1``."""
        return self.B0 + self.B1 * p

    def loop_at(self, p: float, delta: float) -> QuasiPolynomial:
        """``F(.; delta, p)``."""
        B = self.B(p)
        return self.A(p) + (B.shift(delta) if delta > 0 else B)

    def nominal(self, p: float) -> QuasiPolynomial:
        """``F(.; 0, p)`` as ``(A_0 + B_0) + p (A_1 + B_1)``: a change shared by ``A_1`` and ``B_1`` with
        opposite signs cancels before it is multiplied by ``p``, so its rounding and radius do not enter (the
        collocated loop at ``K = rho``: its point terms at ``2 tau`` are 0, not a ball about 0)."""
        return (self.A0 + self.B0) + (self.A1 + self.B1) * p


def _is_zero(P: QuasiPolynomial) -> bool:
    return not P.point_terms and not P.distributed


def _merged(F: QuasiPolynomial) -> QuasiPolynomial:
    """``F`` with each pair of distributed terms whose stored kernels are exact opposites written as one term.

    ``q_1(s) N + q_2(s) (-N) = (q_1 - q_2)(s) N``: the filtered law's nominal loop holds
    ``(1 + b s) I_N - (1 + a s) I_N = (b - a) s I_N`` (eq. (60) with the filter), which
    :class:`~nrobust.quasipoly.QuasiPolynomial` keeps as two terms (it merges terms with equal
    polynomials only). Two such terms (same nodes, moment, interpolation, error bounds, and stored
    kernels that are exact negatives) stand for one kernel and its negation, as
    :meth:`~nrobust.distributed_delay.DistributedDelay.plus` takes them, so the error bound of the
    sum is that of one kernel. The function is the same; each kernel is evaluated and bounded
    once instead of twice.
    """
    terms = list(F.distributed)
    out = []
    while terms:
        d = terms.pop(0)
        for i, e in enumerate(terms):
            if (
                d.moment == e.moment
                and d.interpolation == e.interpolation
                and d.radius == e.radius
                and d.variation_radius == e.variation_radius
                and np.array_equal(d.nodes, e.nodes)
                and np.array_equal(d.values, -e.values)
                and np.array_equal(d.pieces[2], -e.pieces[2])
                and bool(np.any(d.pieces[2] != 0))  # a zero kernel is only its error bound: never one kernel twice
            ):
                d = d.replace(poly=np.polynomial.polynomial.polysub(d.poly, e.poly))
                del terms[i]
                break
        out.append(d)
    if len(out) == len(F.distributed):
        return F
    return QuasiPolynomial.from_parts(F.point_terms, out, F.point_radii or None)


def _zero_free_radius(F: QuasiPolynomial) -> float:
    """The radius of :func:`nrobust.bounds.root_free_region` ``(F, 0)``, with its errors, without its half-plane.

    No zero with ``Re s >= 0`` and ``|s| > R``: the first principal term's gap on ``Re s >= 0``
    exceeds :class:`~nrobust.bounds.TailBound` at ``|s| = R``. (The half-plane of
    ``root_free_region`` exists whenever this radius does: both bounds are monotone in ``Re s``.)
    """
    n = joint_degree(F)
    g = principal_gap({"F": (F, 0)}, n, 0.0)
    if g is None:
        raise ParameterError("F", "of retarded or neutral type (its first principal term has the smallest delay)", F)
    if g.gap <= 0.0:
        raise ParameterError(
            "x0", "to the right of the strong spectral bound of the principal part (positive dominance gap)", 0.0
        )
    tail = TailBound(F, n, 0.0, g.t0)
    return radius_where(lambda R: float(tail(R)), g.gap, "root_free_region")


# Units of rounding of the sum of moduli of the s^n coefficients below which a gap of the principal part is
# not taken as positive (as :func:`~nrobust.margins.frequency_bound` does).
_GAP_ULPS = 8.0
# Why a parameter fails when the first term of ``A`` does not dominate (it comes first for large delays).
_LATER_FIRST = (
    "|a_0(p)| <= sum |a_k(p)| with a_0 the first term of A, which comes first once delta passes the delay of "
    "B's first term"
)


def _top_coefficients(parts: tuple[QuasiPolynomial, ...], n: int) -> dict[tuple[float, int], tuple[float, float]]:
    """The ``s^n`` coefficients of the loop's point terms as ``(alpha, beta)``, ``a(p) = alpha + p beta``.

    ``parts`` is ``(A_0, A_1, B_0, B_1)``; keyed by ``(delay, order)`` with ``order`` 1 for the terms of
    ``B`` (delayed by ``delta -> 0+``: after the terms of ``A`` at the same delay, as in
    :func:`nrobust.bounds.principal_gap`). Terms with ``alpha = beta = 0`` are left out.
    """
    out: dict[tuple[float, int], list[float]] = {}
    for P, order, which in zip(parts, (0, 0, 1, 1), (0, 1, 0, 1), strict=True):
        for a, t in P.leading_terms(n):
            out.setdefault((t, order), [0.0, 0.0])[which] += a.real
    return {key: (a, b) for key, (a, b) in out.items() if a != 0.0 or b != 0.0}


def _degree_drop(top: dict[tuple[float, int], tuple[float, float]]) -> Fraction | None:
    """The parameter ``p_0`` at which every ``s^n`` coefficient vanishes (exactly, as stored), or None.

    Every ``alpha_k + p beta_k`` vanishes at one ``p_0`` iff all ``beta_k != 0`` and the pairs are
    proportional: decided in rational arithmetic on the stored doubles.
    """
    pairs = [(Fraction(a), Fraction(b)) for a, b in top.values()]
    if not pairs or any(b == 0 for _, b in pairs):
        return None
    a0, b0 = pairs[0]
    if any(a * b0 != a0 * b for a, b in pairs[1:]):
        return None
    return -a0 / b0


def _truncated(P: QuasiPolynomial, n: int) -> QuasiPolynomial:
    """``P`` without its ``s^n`` coefficients (its point terms cut to degree ``n - 1``, with their radii)."""
    kept = [(p[:n], t, r[:n]) for (p, t), r in zip(P.point_terms, P.radii_of()) if np.any(p[:n] != 0.0)]
    radii = [r for _, _, r in kept] if P.point_radii else None
    return QuasiPolynomial.from_parts([(p, t) for p, t, _ in kept], P.distributed, radii)


def _interval_text(intervals: Sequence[tuple[float, float, bool, bool]]) -> str:
    """Intervals ``(a, b, closed at a, closed at b)`` in words (a point where ``a == b``)."""
    out = []
    for a, b, left, right in intervals:
        if a == b:
            out.append(f"p = {a:.12g}")
        else:
            out.append(f"{'[' if left else '('}{a:.12g}, {b:.12g}{']' if right else ')'}")
    return ", ".join(out)


def _piece_gap(
    top: dict[tuple[float, int], tuple[float, float]],
    signs: dict[tuple[float, int], float],
    p: float,
    first: tuple[float, int] | None = None,
) -> tuple[float, float]:
    """``G(p) = |a_first(p)| - sum_{k != first} |a_k(p)|`` with the signs of ``a_k`` on a piece (affine in ``p``
    there), and the rounding of its sums (``_GAP_ULPS`` units of ``sum |a_k|``); ``first`` the first term (by
    default the first for ``delta -> 0+``)."""
    first = min(top) if first is None else first
    values = {key: signs[key] * (al + p * be) for key, (al, be) in top.items()}
    room = _GAP_ULPS * float(np.finfo(float).eps) * sum(abs(al) + abs(p * be) for al, be in top.values())
    return values[first] - sum(v for key, v in values.items() if key != first), room


def _first_terms(top: dict[tuple[float, int], tuple[float, float]]) -> list[tuple[float, int]]:
    """The terms that come first in the principal part for some ``delta >= 0``.

    The first term of ``B``'s delayed by ``delta -> 0+`` (when it precedes those of ``A``) and the first of
    ``A``'s, which comes first once ``delta`` is large: the principal part must be strongly stable with each.
    """
    firsts = [min(top)]
    of_a = [key for key in top if key[1] == 0]
    if of_a and min(of_a) != firsts[0]:
        firsts.append(min(of_a))
    return firsts


def _advanced(A: QuasiPolynomial, B: QuasiPolynomial) -> bool:
    """Whether a term of lower degree precedes the first principal term of ``A + B e^{-delta s}`` for some
    ``delta >= 0``: for ``delta -> 0+`` (:func:`~nrobust.bounds.principal_gap`), or for ``delta`` large, when
    the terms of ``B`` come after all of ``A``'s (a term of ``A`` before ``A``'s first principal one, or ``A``
    with terms but none of the top degree)."""
    n = joint_degree(A, B)
    if principal_gap({"A": (A, 0), "B": (B, 1)}, n) is None:
        return True
    if not A.leading_terms(n):
        return min_delay(A) < np.inf
    return principal_gap({"A": (A, 0)}, n) is None


def _bad_part(
    top: dict[tuple[float, int], tuple[float, float]],
    signs: dict[tuple[float, int], float],
    first: tuple[float, int],
    a: float,
    b: float,
    p0: float | None,
) -> tuple[float, float] | None:
    """The closed part of the piece ``[a, b]`` where the gap with ``first`` is not positive, rounded outward.

    The gap is affine on the piece: its set ``G <= 0`` is empty, the piece, or a part touching one end, whose
    other end is the zero of ``G`` moved outward by the rounding of both end values (``_piece_gap``) and a few
    ulps of the interpolation. At a degree drop ``p_0`` every ``a_k`` vanishes: ``G(p_0) = 0``, so the piece
    fails whole if its other end fails.
    """
    (g_a, r_a), (g_b, r_b) = _piece_gap(top, signs, a, first), _piece_gap(top, signs, b, first)
    bad_a, bad_b = g_a <= r_a and a != p0, g_b <= r_b and b != p0
    if (bad_a and bad_b) or (a == p0 and bad_b) or (b == p0 and bad_a):
        return (a, b)
    if not (bad_a or bad_b):
        return None
    slack = 4.0 * float(np.finfo(float).eps) * (abs(a) + abs(b) + (b - a))
    if bad_a:  # G(a) <= r_a, G(b) > r_b: the zero of G is at most a + (b - a) (r_a - g_a) / (g_b - r_b + r_a - g_a)
        share = (r_a - g_a) / ((g_b - r_b) + (r_a - g_a))
        return (a, min(b, a + (b - a) * share + slack))
    share = (r_b - g_b) / ((g_a - r_a) + (r_b - g_b))
    return (max(a, b - (b - a) * share - slack), b)


def _strong_stability_failures(
    parts: tuple[QuasiPolynomial, QuasiPolynomial, QuasiPolynomial, QuasiPolynomial], lo: float, hi: float
) -> list[tuple[float, float, str]]:
    """Where in ``[lo, hi]`` the difference operator of ``(A_0 + p A_1) + (B_0 + p B_1) e^{-delta s}`` is not
    strongly stable: ``(from, to, why)``, closed, disjoint and increasing (a point where ``from == to``).

    The principal part for ``delta -> 0+`` is ``sum_k a_k(p) e^{-tau_k s}``, ``a_k(p) = alpha_k + p beta_k`` the
    ``s^n`` coefficients (the terms of ``B`` after those of ``A`` at one delay); it is strongly stable iff
    ``G(p) = |a_first(p)| - sum_{k != first} |a_k(p)| > 0`` (Hale and Verduyn Lunel, the delay ``delta`` free;
    :func:`~nrobust.margins.frequency_bound`), ``a_first`` the coefficient at the smallest delay. Between two
    consecutive zeros of the ``a_k`` (and the ends) every sign, and so the first term, is fixed: ``G`` is affine
    on the closed piece, positive on it iff positive (above the rounding of its sums) at both ends. A zero of
    ``a_first`` alone is not strongly stable nearby, whatever the operator at that point (a pure shift there has
    lower-degree terms before the first principal one on each side). Where every ``a_k`` vanishes (``p_0``, a
    drop of the degree) ``G = 0`` on both sides: the pieces are checked at their other ends (``G`` is affine
    with ``G(p_0) = 0``) and the operator at ``p_0`` is that of degree ``n - 1``, checked by
    :func:`~nrobust.margins.frequency_bound`. A piece of advanced type (a term before the first principal one,
    for ``delta -> 0+`` or for large ``delta``) at one of two inner points fails whole (the coefficients of
    such terms are affine in ``p``). When the first principal term of ``B`` precedes ``A``'s, ``A``'s comes
    first once ``delta`` passes it: the gap must hold with either first. The ends of a failing part are
    rounded outward.
    """
    A0, A1, B0, B1 = parts
    try:
        n = joint_degree(*parts)
    except ParameterError:
        return [(lo, hi, "a distributed term of higher degree than the point terms (it enters the principal part)")]
    top = _top_coefficients(parts, n)
    if not top:
        return [(lo, hi, "no principal part")]
    drop = _degree_drop(top)
    p0 = None if drop is None else float(drop)
    zeros = {-a / b for a, b in top.values() if b != 0.0}
    points = sorted({lo, hi, *(z for z in zeros if lo < z < hi)})
    failures: list[tuple[float, float, str]] = []
    firsts = _first_terms(top)
    for a, b in itertools.pairwise(points):
        # a term before the first principal one has a coefficient affine in p: if it vanishes at two points of
        # the piece it vanishes on all of it, otherwise it is there on all of the piece but one point
        if any(_advanced(A0 + A1 * inner, B0 + B1 * inner) for inner in (a + (b - a) / 3.0, b - (b - a) / 3.0)):
            failures.append((a, b, "of advanced type (a term precedes the first principal one)"))
            continue
        mid = 0.5 * (a + b)
        signs = {key: float(np.sign(al + mid * be)) for key, (al, be) in top.items()}
        for first in firsts:
            part = _bad_part(top, signs, first, a, b, p0)
            if part is not None:
                why = "|a_0(p)| <= sum |a_k(p)|" if first == firsts[0] else _LATER_FIRST
                failures.append((*part, why))
    if p0 is not None and lo <= p0 <= hi:
        at_drop = "of degree n - 1 where every s^n coefficient vanishes, and that operator is not strongly stable"
        try:
            ok = frequency_bound(_truncated(A0 + A1 * p0, n), _truncated(B0 + B1 * p0, n)) is not None
        except ParameterError:
            ok = False
        if not ok:
            failures.append((p0, p0, at_drop))
    merged: list[tuple[float, float, str]] = []
    for a, b, why in sorted(failures):
        if merged and a <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], b), merged[-1][2])
        else:
            merged.append((a, b, why))
    return [(float(a), float(b), why) for a, b, why in merged]


def _uniform_crossing_bound(
    parts: tuple[QuasiPolynomial, QuasiPolynomial, QuasiPolynomial, QuasiPolynomial], lo: float, hi: float
) -> float:
    """A frequency ``W`` with ``|A(i w; p)| != |B(i w; p)|`` for ``|w| >= W`` and every ``p`` in ``[lo, hi]``.

    On the axis ``| |A| - |B| | >= |w|^n (G(p) - T_A(|w|) - T_B(|w|))``, ``G`` the principal gap
    (:func:`_piece_gap`, affine between the zeros of the ``s^n`` coefficients) and ``T`` the
    :class:`~nrobust.bounds.TailBound` of the lower powers and distributed terms, at most
    ``T_{P_0} + |p| T_{P_1}`` for ``P_0 + p P_1`` (the triangle inequality on each coefficient and kernel),
    each kernel integrated by parts twice (``second_order``: its end values and jumps over ``|w|``, the
    variation of its derivative over ``|w|^2``; once, the whole variation of a kernel with jumps decays only
    like ``1/|w|``). On a piece ``G(p) - T(p, R)`` is concave in ``p`` (``G`` affine, ``T`` convex): it is
    positive on the piece where it is at both ends, so ``W`` is the larger of the radii where ``T`` falls
    below ``G`` (less the rounding of the sums, as :func:`~nrobust.margins.frequency_bound`) at the two
    ends; the largest over the pieces is returned. The interval is strongly stable
    (:func:`_check_strongly_stable`).

    Raises
    ------
    CertificationError
        A piece ends where every ``s^n`` coefficient vanishes (the degree drops: the gap tends to 0 and no
        bound holds uniformly about it).
    """
    n = joint_degree(*parts)
    top = _top_coefficients(parts, n)
    tails = [TailBound(P, n, 0.0, 0.0, second_order=True) for P in parts]
    zeros = {-a / b for a, b in top.values() if b != 0.0}
    points = sorted({lo, hi, *(z for z in zeros if lo < z < hi)})
    if len(points) == 1:  # one parameter: a piece of zero length
        points *= 2
    out = 0.0
    for a, b in itertools.pairwise(points):
        mid = 0.5 * (a + b)
        signs = {key: float(np.sign(al + mid * be)) for key, (al, be) in top.items()}
        (g_a, r_a), (g_b, r_b) = _piece_gap(top, signs, a), _piece_gap(top, signs, b)
        level = min(g_a, g_b) * (1.0 - 1e-9) - max(r_a, r_b)
        if level <= 0.0:
            raise CertificationError(
                f"the crossing frequencies of the parameters in [{a:.12g}, {b:.12g}] are not bounded uniformly: the "
                "principal gap of the loop tends to 0 where every s^n coefficient vanishes (the degree drops); bounds "
                "that leave that parameter out would help"
            )
        for p, g, r in ((a, g_a, r_a), (b, g_b, r_b)):

            def tail(R: float, P: float = abs(p)) -> float:
                with np.errstate(over="ignore"):
                    return float(tails[0](R) + P * tails[1](R) + tails[2](R) + P * tails[3](R))

            out = max(out, radius_where(tail, g * (1.0 - 1e-9) - r, "crossing bound"))
    return _circle_crossing_bound(parts, lo, hi, out)


# Harmonics of the base delay up to which the crossing bound on the circle (:func:`_circle_crossing_bound`) is tried.
_MAX_HARMONICS = 64
# Points of its grid on the circle: from 2^12, doubled while the step's share of the least value is above 1/10.
_CIRCLE_POINTS = (12, 17)


def _opposite_kernels(A: QuasiPolynomial, B: QuasiPolynomial) -> list[DistributedDelay] | None:
    """The kernels of ``A`` when those of ``B`` are their exact opposites (``A + B`` has none: the kernels of
    ``B`` stand for the negated true kernels, as :meth:`~nrobust.distributed_delay.DistributedDelay.plus`
    takes them), each of moment 0 and constant polynomial; else None."""
    left, right = list(A.distributed), list(B.distributed)
    if len(left) != len(right):
        return None
    for d in left:
        match = next(
            (
                i
                for i, e in enumerate(right)
                if d.moment == e.moment == 0
                and d.poly.size == e.poly.size == 1
                and d.poly[0] == e.poly[0]
                and d.interpolation == e.interpolation
                and d.radius == e.radius
                and d.variation_radius == e.variation_radius
                and np.array_equal(d.nodes, e.nodes)
                and np.array_equal(d.pieces[2], -e.pieces[2])
            ),
            None,
        )
        if match is None:
            return None
        del right[match]
    return left


def _harmonic(x: Fraction, base: Fraction) -> int | None:
    """``x / base`` when it is an integer in ``[0, _MAX_HARMONICS]``, else None."""
    m = x / base
    return int(m) if m.denominator == 1 and 0 <= m <= _MAX_HARMONICS else None


def _kernel_terms(
    kernels: list[DistributedDelay], base: Fraction, size: int
) -> tuple[NDArray[np.complex128], float, float, float]:
    """``(c, R_0, r_1, V_2)``: ``sum_k int N_k e^{-nu s} = c(z) / s + E`` with ``z = e^{-base s}``,
    ``c = sum_m c_m z^m`` and ``|E| <= R_0 + r_1 / |s| + V_2 / |s|^2`` on the axis.

    Integration by parts on each piece: its boundary terms ``(N(u+) e^{-u s} - N(v-) e^{-v s}) / s``. Where a
    piece's end ``u + h``, in floating point, is within a few ulps of the next one's start (pieces that meet, as
    for :meth:`~nrobust.distributed_delay.DistributedDelay.second_order_variation`) the end's term is moved to
    that start, at the cost
    ``|N(v-)| |v - u'|`` (``|e^{-v s} - e^{-u' s}| <= |s| |v - u'|``), and ``|N'(v-)| |v - u'|`` over ``|s|``
    for the second integration; the distances are exact (rationals). The terms at multiples ``m base`` go to
    ``c_m``, the others (the tiny jumps of a kernel stored in pieces) to ``r_1`` by their moduli, with the
    error bounds ``2 radius + variation_radius``; ``V_2`` is the second integration's bound
    (:meth:`~nrobust.distributed_delay.DistributedDelay.second_order_variation`).
    """
    c = np.zeros(size, dtype=complex)
    moved = moved_slope = rest = v2 = 0.0
    for d in kernels:
        start, h, poly_t = d.pieces
        left = poly_t[:, 0]
        right = np.sum(poly_t, axis=1)
        slope_right = np.sum(poly_t * np.arange(poly_t.shape[1]), axis=1) / h
        ends = start + h
        meet = np.abs(start[1:] - ends[:-1]) <= 4.0 * float(np.finfo(float).eps) * np.maximum(np.abs(ends[:-1]), 1.0)
        terms: list[tuple[Fraction, complex]] = [(Fraction(float(start[0])), complex(left[0]))]
        for i in range(h.size):
            end = Fraction(float(start[i])) + Fraction(float(h[i]))
            if i + 1 < h.size and meet[i]:
                u = Fraction(float(start[i + 1]))
                gap = float(abs(end - u))
                moved += abs(complex(right[i])) * gap
                moved_slope += abs(complex(slope_right[i])) * gap
                terms.append((u, complex(left[i + 1]) - complex(right[i])))
            else:
                terms.append((end, -complex(right[i])))
                if i + 1 < h.size:
                    terms.append((Fraction(float(start[i + 1])), complex(left[i + 1])))
        for x, value in terms:
            m = _harmonic(x, base)
            if m is None or m >= size:
                rest += abs(value)
            else:
                c[m] += value
        rest += 2.0 * d.radius + d.variation_radius
        v2 += d.second_order_variation()[1]
    # rounding of the sums: 1e-12 of the moduli summed, as second_order_variation
    size_c = float(np.sum(np.abs(c)))
    return c, moved * (1.0 + 1e-12), (rest + moved_slope + 1e-12 * size_c) * (1.0 + 1e-12), v2


def _common_base(delays: set[Fraction]) -> Fraction:
    """The largest ``h`` of which every delay is an integer multiple (exactly, the doubles as rationals; 0 for none)."""
    base = Fraction(0)
    for t in delays:
        top = math.gcd(base.numerator * t.denominator, t.numerator * base.denominator)
        base = Fraction(top, base.denominator * t.denominator)
    return base


class _CircleBound:
    """The lower bound of ``l`` (:func:`_circle_crossing_bound`) on ``K`` points of the circle, at each ``eps``.

    ``vectors`` are the coefficients of ``z^m`` in ``a_0, a_1, b_0, b_1, c_0, c_1``; ``rest`` the remainder
    ``(R_0, r_1, V_2)`` for every ``|p| <= P``.
    """

    def __init__(
        self, vectors: list[NDArray[np.complex128]], rest: tuple[float, float, float], lo: float, hi: float, K: int
    ) -> None:
        a0, a1, b0, b1, c0, c1 = vectors
        self.lo, self.hi, self.rest, self.K = lo, hi, rest, K
        big = max(abs(lo), abs(hi))
        harmonics = np.arange(a0.size)
        # majorants of the coefficients for every |p| <= big, and the derivatives in the angle they bound
        a_hat, b_hat = np.abs(a0) + big * np.abs(a1), np.abs(b0) + big * np.abs(b1)
        s_hat, c_hat = np.abs(a0 + b0) + big * np.abs(a1 + b1), np.abs(c0) + big * np.abs(c1)
        spread = np.abs(harmonics[:, None] - harmonics[None, :])
        self.d_h = float(a_hat @ spread @ a_hat + b_hat @ spread @ b_hat)
        self.d_k = 2.0 * float(s_hat @ spread @ c_hat)
        self.d_s = float(harmonics @ s_hat)
        self.s_max, self.c_sum = float(np.sum(s_hat)), float(np.sum(c_hat))
        self.magnitude = float(np.sum(a_hat) ** 2 + np.sum(b_hat) ** 2)
        z = np.exp(-1j * np.outer(2.0 * np.pi * np.arange(K) / K, harmonics))
        va0, va1, vb0, vb1, vc0, vc1 = (z @ v for v in vectors)
        vs0, vs1 = va0 + vb0, va1 + vb1
        self.modulus_s = np.abs(vs0) + big * np.abs(vs1)
        self.h = (
            np.abs(va0) ** 2 - np.abs(vb0) ** 2,
            2.0 * ((np.conj(va0) * va1).real - (np.conj(vb0) * vb1).real),
            np.abs(va1) ** 2 - np.abs(vb1) ** 2,
        )
        self.k = (
            2.0 * (np.conj(vs0) * vc0).imag,
            2.0 * (np.conj(vs0) * vc1 + np.conj(vs1) * vc0).imag,
            2.0 * (np.conj(vs1) * vc1).imag,
        )

    def __call__(self, eps: float) -> float:
        """A lower bound of ``l`` over the circle, ``[lo, hi]`` and both signs of ``w`` at ``eps``."""
        lo, hi = self.lo, self.hi
        least = np.full(self.K, np.inf)
        for sign in (1.0, -1.0):
            q0, q1, q2 = (h + sign * eps * k for h, k in zip(self.h, self.k, strict=True))
            ends = np.minimum(q0 + lo * (q1 + lo * q2), q0 + hi * (q1 + hi * q2))
            convex = q2 > 0.0
            with np.errstate(divide="ignore", invalid="ignore"):
                vertex = np.where(convex, -q1 / (2.0 * np.where(convex, q2, 1.0)), lo)
                peak = q0 - q1 * q1 / (4.0 * np.where(convex, q2, 1.0))
                at_vertex = np.where((vertex > lo) & (vertex < hi), peak, np.inf)
            least = np.minimum(least, np.minimum(ends, at_vertex))
        R0, r1, V2 = self.rest
        remainder = 2.0 * (R0 + eps * (r1 + eps * V2))
        slope = (np.pi / self.K) * (self.d_h + eps * self.d_k + remainder * self.d_s)
        rounding = 1e-12 * (self.magnitude + 2.0 * eps * self.s_max * self.c_sum + remainder * self.s_max)
        return float(np.min(least - remainder * self.modulus_s)) - slope - rounding


def _circle_crossing_bound(
    parts: tuple[QuasiPolynomial, QuasiPolynomial, QuasiPolynomial, QuasiPolynomial], lo: float, hi: float, W: float
) -> float:
    """A crossing bound at most ``W`` for a loop of degree 0 whose kernels cancel in ``A + B`` and whose delays
    are multiples of one base ``h`` (the collocated observer's loops): ``W`` itself when that does not apply.

    With ``A = a + I``, ``B = b - I`` (``a``, ``b`` the point terms, ``I`` the kernels' integral),
    ``g = |A|^2 - |B|^2 = |a|^2 - |b|^2 + 2 Re(conj(S) I)``, ``S = a + b`` (``|I|^2`` cancels), and by
    :func:`_kernel_terms` ``I = c / (i w) + E``: with ``z = e^{-i w h}`` on the unit circle and
    ``eps = 1/|w|``, ``g >= l = h(z, p) + eps k(z, p) - 2 |S| (R_0 + eps r_1 + eps^2 V_2)``,
    ``h = |a|^2 - |b|^2``, ``k = +-2 Im(conj(S) c)`` (the sign of ``w``), quadratic in ``p`` through
    ``a_0 + p a_1``, ``b_0 + p b_1``, ``c_0 + p c_1``. Where ``h`` is least ``k`` nearly vanishes (on the
    paper's plant both at ``z = 1``), so ``l`` keeps most of ``h`` where the triangle inequality
    (:func:`_uniform_crossing_bound`) loses ``eps (V_A + V_B)`` at every phase: on the collocated loop
    over the default gains the bound falls from 705 to 38 (the last crossing is at 16). ``l`` is concave
    in ``eps``: it is positive for every ``eps <= e`` where it is at ``0`` and at ``e``. Its minimum over
    the circle and ``[lo, hi]`` is bounded below (:class:`_CircleBound`) on ``K`` points ``z_j`` (the
    minimum over ``p`` of the quadratic exactly, at the ends or its vertex; ``|S|`` at its majorant
    ``|S_0| + P |S_1|``, ``P = max |p|``) less ``pi / K`` times a bound of the derivative in the angle
    (``sum |m - n|`` times the moduli of the coefficients' majorants), and ``1e-12`` of the magnitudes
    summed for the rounding. ``K`` is doubled from ``2^12`` while that derivative's share is above a
    tenth of the bound at ``eps = 0``. The largest ``e`` where the bound is positive (from ``1 / W``
    on) is found by bisection in ``log eps``; ``1 / e`` is returned when less than ``W``.
    """
    A0, A1, B0, B1 = parts
    if joint_degree(*parts) != 0:
        return W
    k0, k1 = _opposite_kernels(A0, B0), _opposite_kernels(A1, B1)
    if k0 is None or k1 is None:
        return W
    margin = _radii_margin(parts, k0, k1, max(abs(lo), abs(hi)))
    points = [(index, Fraction(t), complex(c[0])) for index, P in enumerate(parts) for c, t in P.point_terms]
    delays = [t for _, t, _ in points] + [Fraction(float(x)) for d in (*k0, *k1) for x in (d.a, d.b)]
    base = _common_base(set(delays))
    if base == 0 or max(delays) / base > _MAX_HARMONICS:
        return W
    size = _MAX_HARMONICS + 1
    vectors = [np.zeros(size, dtype=complex) for _ in parts]
    for index, t, c in points:
        vectors[index][int(t / base)] += c
    (c0, *rest0), (c1, *rest1) = _kernel_terms(k0, base, size), _kernel_terms(k1, base, size)
    big = max(abs(lo), abs(hi))
    rest = (rest0[0] + big * rest1[0], rest0[1] + big * rest1[1], rest0[2] + big * rest1[2])
    used = max(int(np.max(np.flatnonzero(np.abs(v) > 0), initial=0)) for v in (*vectors, c0, c1)) + 1
    trimmed = [v[:used] for v in (*vectors, c0, c1)]
    for log_points in range(_CIRCLE_POINTS[0], _CIRCLE_POINTS[1] + 1):
        bound = _CircleBound(trimmed, rest, lo, hi, 2**log_points)
        at_zero = bound(0.0)
        if at_zero <= margin or (np.pi / bound.K) * bound.d_h > 0.1 * at_zero:
            continue
        good = 1.0 / W
        if bound(good) <= margin:
            return W
        bad = good * 2.0**40
        for _ in range(48):
            mid = float(np.sqrt(good * bad))
            good, bad = (mid, bad) if bound(mid) > margin else (good, mid)
        return min(W, float(np.nextafter(1.0 / good, np.inf)))
    return W


def _radii_margin(
    parts: tuple[QuasiPolynomial, QuasiPolynomial, QuasiPolynomial, QuasiPolynomial],
    k0: list[DistributedDelay],
    k1: list[DistributedDelay],
    big: float,
) -> float:
    """What the lower bound ``l`` of ``g = |A|^2 - |B|^2`` of the stored loop must exceed for the loop whose point
    coefficients lie within the parts' radii (:func:`_circle_crossing_bound`; 0 without radii).

    On the axis the true ``|A| - |B|`` is at least the stored one less ``rho``, the radii summed (``|p| <= big``),
    and the stored ``|A| - |B| = g / (|A| + |B|) >= l / U`` with ``U`` the point coefficients' moduli and twice
    the kernels' ``int |N|`` summed (``|A| + |B| <= |a| + |b| + 2 |I|``): ``l > U rho`` leaves no crossing.
    """
    weights = (1.0, big, 1.0, big)
    rho = math.fsum(w * float(np.sum(r)) for P, w in zip(parts, weights, strict=True) for r in P.radii_of())
    if rho == 0.0:
        return 0.0
    moduli = math.fsum(
        w * float(np.sum(np.abs(c))) for P, w in zip(parts, weights, strict=True) for c, _ in P.point_terms
    )
    mass = math.fsum(float(d.abs_moment(0.0, 0)) for d in k0) + big * math.fsum(float(d.abs_moment(0.0, 0)) for d in k1)
    return (moduli + 2.0 * mass) * rho * (1.0 + 1e-12)


def _check_strongly_stable(
    parts: tuple[QuasiPolynomial, QuasiPolynomial, QuasiPolynomial, QuasiPolynomial], lo: float, hi: float
) -> None:
    """A :class:`ParameterError` naming ``bounds`` unless the loop's difference operator is strongly stable at every
    parameter of ``[lo, hi]`` (:func:`_strong_stability_failures`), saying where it is not and where it is."""
    merged = _strong_stability_failures(parts, lo, hi)
    if not merged:
        return
    bad = [(a, b, True, True) for a, b, _ in merged]
    good: list[tuple[float, float, bool, bool]] = []
    start, closed = lo, True
    for a, b, _ in merged:
        if a > start:
            good.append((start, a, closed, False))
        start, closed = b, False
    if start < hi:
        good.append((start, hi, closed, True))
    where = "; ".join(f"on {_interval_text([interval])} ({why})" for interval, (_, _, why) in zip(bad, merged))
    inside = f"it is on {_interval_text(good)}" if good else "it is nowhere in them"
    raise ParameterError(
        "bounds",
        "parameters where the loop's difference operator is strongly stable (Hale and Verduyn Lunel: "
        f"|a_0(p)| > sum |a_k(p)| over its principal part); it is not {where}; {inside}",
        (lo, hi),
    )


@dataclass(frozen=True)
class _Axis:
    """``A_0, A_1, B_0, B_1`` at ``s = i w`` and their ``w``-derivatives (``None``: not computed)."""

    w: NDArray[np.float64]
    a0: NDArray[np.complex128]
    a1: NDArray[np.complex128]
    b0: NDArray[np.complex128]
    b1: NDArray[np.complex128]
    da0: Any = None
    da1: Any = None
    db0: Any = None
    db1: Any = None

    def branches(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """``(D, m, sqrt D)``: ``g = 0`` at ``p = m +- sqrt D`` (``D >= 0``; ``D = -inf`` where ``c_2 = 0``).

        With ``x = conj(A_0) A_1``, ``y = conj(B_0) B_1``: ``h = Re x - Re y``, ``m = -h / c_2`` and
        ``c_2^2 D = h^2 - c_2 c_0 = |A_1 B_0|^2 + |A_0 B_1|^2 - (Im x)^2 - (Im y)^2 - 2 Re x Re y``
        (for a gain, ``A_1 = 0``: ``|A R|^2 - (Im conj(B_0) R)^2``, no cancellation of ``|B_0 R|^2``).
        """
        x, y = np.conj(self.a0) * self.a1, np.conj(self.b0) * self.b1
        c2 = np.abs(self.a1) ** 2 - np.abs(self.b1) ** 2
        disc = (
            np.abs(self.a1 * self.b0) ** 2
            + np.abs(self.a0 * self.b1) ** 2
            - x.imag**2
            - y.imag**2
            - 2.0 * x.real * y.real
        )
        with np.errstate(divide="ignore", invalid="ignore"):
            D = np.where(c2 != 0.0, disc / np.where(c2 != 0.0, c2, 1.0) ** 2, -np.inf)
            m = np.where(c2 != 0.0, -(x.real - y.real) / np.where(c2 != 0.0, c2, 1.0), 0.0)
        return D, m, np.sqrt(np.maximum(D, 0.0))

    def curvature(self) -> NDArray[np.float64]:
        """``c_2 = |A_1|^2 - |B_1|^2``: where it changes sign a branch passes through ``p = inf``."""
        return np.abs(self.a1) ** 2 - np.abs(self.b1) ** 2

    def slopes(self, K: NDArray[np.float64], sigma: float) -> NDArray[np.float64]:
        """``dp/dw = -g_w / g_p`` on the branch ``p = m + sigma sqrt D`` (zero at a pair birth)."""
        A, B = self.a0 + K * self.a1, self.b0 + K * self.b1
        dA, dB = self.da0 + K * self.da1, self.db0 + K * self.db1
        g_w = 2.0 * ((np.conj(A) * dA).real - (np.conj(B) * dB).real)
        g_p = 2.0 * ((np.conj(A) * self.a1).real - (np.conj(B) * self.b1).real)  # 2 c_2 sigma sqrt(D)
        tiny = np.where(g_p >= 0.0, 1e-300, -1e-300)
        return -g_w / np.where(np.abs(g_p) > 1e-300, g_p, tiny)

    def theta(self, K: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """``arg(-B/A)`` in ``[0, 2 pi)`` at the parameter ``K``."""
        return np.mod(np.angle(-(self.b0 + K * self.b1) / (self.a0 + K * self.a1)), _TWO_PI)


def _joined(first: _Axis, second: _Axis) -> _Axis:
    """The samples of ``first`` then those of ``second``."""
    joined: dict[str, Any] = {}
    for f in fields(_Axis):
        a, b = getattr(first, f.name), getattr(second, f.name)
        joined[f.name] = None if a is None else np.concatenate([a, b])
    return _Axis(**joined)


def _inserted(at: _Axis, more: _Axis) -> _Axis:
    """The samples of ``at`` and ``more`` by increasing frequency."""
    order = np.argsort(np.concatenate([at.w, more.w]), kind="stable")
    joined = _joined(at, more)
    ordered: dict[str, Any] = {}
    for f in fields(_Axis):
        x = getattr(joined, f.name)
        ordered[f.name] = None if x is None else x[order]
    return _Axis(**ordered)


def _kernel_sign(base: DistributedDelay, d: DistributedDelay) -> float:
    """``1`` or ``-1`` when ``d`` stores the kernel of ``base`` or its negation (same segments and moment), else 0."""
    if d.moment != base.moment or not all(np.array_equal(u, v) for u, v in zip(d.pieces[:2], base.pieces[:2])):
        return 0.0
    if np.array_equal(d.pieces[2], base.pieces[2]):
        return 1.0
    return -1.0 if np.array_equal(d.pieces[2], -base.pieces[2]) else 0.0


class _SharedKernels:
    """Quasi-polynomials evaluated together, each stored kernel of their distributed terms integrated once.

    The factors of a filtered law hold one kernel several times (``I_N`` in ``A_0 = (1 - Phi)(1 + b s)`` and,
    negated, in ``B_0 = (K q e^{-tau s} - I_N)(1 + a s)``). A term is ``q(s) J_m(s)``,
    ``J_k = int nu^k N e^{-nu s} dnu``, and its derivative ``q' J_m - q J_{m+1}``
    (:class:`~nrobust.distributed_delay.DistributedDelay`): ``J_m`` and ``J_{m+1}`` are computed once per
    kernel (its term with ``q = 1``, negated for a negated kernel, which is exact) and combined as the terms
    combine them, so the values are those of each quasi-polynomial's own evaluation, bit for bit. The kernels
    and their two moments are integrated together (:func:`~nrobust.distributed_delay.moment_integrals`: those on
    the same segments, as the kernels of a collocated observer's loop, share their exponentials).
    """

    def __init__(self, parts: Sequence[QuasiPolynomial]) -> None:
        self.points = [QuasiPolynomial.from_parts(P.point_terms, ()) for P in parts]
        self.kernels: list[DistributedDelay] = []
        self.terms: list[list[tuple[int, float, NDArray]]] = []  # per part: (kernel, sign, q)
        for P in parts:
            row = []
            for d in P.distributed:
                k, sign = next(((k, g) for k, b in enumerate(self.kernels) if (g := _kernel_sign(b, d))), (-1, 1.0))
                if k < 0:
                    k = len(self.kernels)
                    self.kernels.append(d.replace(poly=[1.0]))
                row.append((k, sign, d.poly))
            self.terms.append(row)

    def __call__(self, s: NDArray[np.complex128], slopes: bool) -> tuple[list[NDArray], list[NDArray] | None]:
        """The values of the parts at ``s`` (1-d), and their derivatives when ``slopes``."""
        sums = moment_integrals(self.kernels, s, (0, 1) if slopes else (0,))
        j0 = [row[0] for row in sums]
        values = []
        for points, row in zip(self.points, self.terms):
            out = points(s) if points.point_terms else np.zeros(s.shape, dtype=complex)
            for k, sign, q in row:
                J0 = j0[k] if sign > 0 else -j0[k]
                out += J0 if q.size == 1 else polyval(q, s) * J0
            values.append(out)
        if not slopes:
            return values, None
        j1 = [row[1] for row in sums]  # J_{m+1} = -dJ_m/ds
        derivs = []
        for points, row in zip(self.points, self.terms):
            out = points.deriv_at(s) if points.point_terms else np.zeros(s.shape, dtype=complex)
            for k, sign, q in row:
                J0, J1 = (j0[k], j1[k]) if sign > 0 else (-j0[k], -j1[k])
                if q.size == 1:
                    out += -J1
                else:
                    term = polyval(polyder(q), s) * J0
                    term -= polyval(q, s) * J1
                    out += term
            derivs.append(out)
        return values, derivs


# Nominal loops F(.; 0, p) a _Family keeps (the bisections of a plateau's ends ask for about 80).
_NOMINALS_KEPT = 128


class _Family:
    """The loop being designed, :class:`AffineGainLoop` or :class:`AffineLoop`, behind one interface."""

    def __init__(self, loop: AffineGainLoop | AffineLoop) -> None:
        self.loop = loop
        self.gain = isinstance(loop, AffineGainLoop)
        # A_1 = s A_0 or B_1 = s B_0 (a filter's pole or zero): evaluated from A_0, B_0
        self.a1_times_s = self.b1_times_s = False
        self.S0: QuasiPolynomial | None = None
        if isinstance(loop, AffineGainLoop):
            self.parts: tuple[QuasiPolynomial, ...] = (loop.A, loop.B0, loop.R)
            self.affine = (loop.A, QuasiPolynomial([[0.0]], [0.0]), loop.B0, loop.R)
            self.a1_zero, self.b1_zero = True, False
        else:
            self.parts = (loop.A0, loop.A1, loop.B0, loop.B1)
            self.affine = (loop.A0, loop.A1, loop.B0, loop.B1)
            self.a1_zero, self.b1_zero = _is_zero(loop.A1), _is_zero(loop.B1)
            self.a1_times_s = not self.a1_zero and loop.A1 == loop.A0.times_poly([0.0, 1.0])
            self.b1_times_s = not self.b1_zero and loop.B1 == loop.B0.times_poly([0.0, 1.0])
            # A_0 + B_0 when distributed terms cancel in it (the unfiltered law's I_N - I_N): A_0 = S_0 - B_0
            S0 = loop.A0 + loop.B0
            self.S0 = S0 if len(S0.distributed) < len(loop.A0.distributed) else None
            # B_0, A_0 (or S_0), then A_1 and B_1 when evaluated: a kernel they share is integrated once
            own = [
                P
                for P, evaluated in (
                    (loop.A1, not (self.a1_zero or self.a1_times_s)),
                    (loop.B1, not (self.b1_zero or self.b1_times_s)),
                )
                if evaluated
            ]
            self.shared = _SharedKernels([loop.B0, loop.A0 if self.S0 is None else self.S0, *own])
        cheap = self.a1_zero + self.b1_zero + self.a1_times_s + self.b1_times_s
        # evaluations of quasi-polynomials per sample of the axis (values and slopes)
        self.evals_per_sample = _EVALS_PER_SAMPLE if self.gain else 2 * (4 - cheap)
        self.max_delay = max(P.max_delay for P in self.parts)
        # the spectral abscissas of F(.; 0, p) computed so far: the samples of the best rate, its search and the
        # check of a plateau meet at the same parameters
        self._abscissas: dict[float, SpectralAbscissa] = {}
        # F(.; 0, p) by p: the samples' chain bounds, their abscissas and the plateau's checks build the same
        # loops (each a few milliseconds: the kernels scaled with their error bounds, added and merged)
        self._nominals: dict[tuple[float, float], QuasiPolynomial] = {}

    def abscissa(self, p: float) -> SpectralAbscissa:
        """:func:`~nrobust.roots.spectral_abscissa` of :meth:`nominal` at ``p`` (computed once per ``p``); of
        :meth:`combined` where that is one term (no zero: :func:`_finite_time_gains`)."""
        sa = self._abscissas.get(p)
        if sa is None:
            F = self.combined(p)
            sa = self._abscissas[p] = spectral_abscissa(F if _single_term(F) else self.nominal(p))
        return sa

    def axis(self, w: NDArray[np.float64], slopes: bool = False) -> _Axis:
        """The factors at ``s = i w`` (with their ``w``-derivatives when ``slopes``)."""
        if isinstance(self.loop, AffineGainLoop):
            at = self.loop.axis(w, slopes)
            zero = np.zeros(at.w.shape, dtype=complex)
            d = (at.da, zero if slopes else None, at.db0, at.dr)
            return _Axis(at.w, at.a, zero, at.b0, at.r, *d)
        s = 1j * np.asarray(w, dtype=float)
        zero = np.zeros(s.shape, dtype=complex)
        values, derivs = self.shared(s, slopes)
        b0 = values[0]
        a0 = values[1] if self.S0 is None else values[1] - b0
        rest = iter(values[2:])
        a1 = zero if self.a1_zero else s * a0 if self.a1_times_s else next(rest)
        b1 = zero if self.b1_zero else s * b0 if self.b1_times_s else next(rest)
        if derivs is None:
            return _Axis(s.imag, a0, a1, b0, b1)
        db0 = 1j * derivs[0]
        da0 = 1j * derivs[1] if self.S0 is None else 1j * derivs[1] - db0
        slope = iter(derivs[2:])
        # d/dw of (i w) P(i w) = i P + i w dP/dw
        da1 = zero if self.a1_zero else 1j * a0 + s * da0 if self.a1_times_s else 1j * next(slope)
        db1 = zero if self.b1_zero else 1j * b0 + s * db0 if self.b1_times_s else 1j * next(slope)
        return _Axis(s.imag, a0, a1, b0, b1, da0, da1, db0, db1)

    def A(self, p: float) -> QuasiPolynomial:
        """``A_0 + p A_1``; ``A_0 (1 + p s)`` when ``A_1 = s A_0`` (a filter's pole: each kernel of ``A_0`` once)."""
        if isinstance(self.loop, AffineGainLoop):
            return self.loop.A
        return self.loop.A0.times_poly([1.0, p]) if self.a1_times_s else self.loop.A(p)

    def B(self, p: float) -> QuasiPolynomial:
        """``B_0 + p B_1``; ``B_0 (1 + p s)`` when ``B_1 = s B_0`` (a filter's zero)."""
        if isinstance(self.loop, AffineLoop) and self.b1_times_s:
            return self.loop.B0.times_poly([1.0, p])
        return self.loop.B(p)

    def nominal(self, p: float) -> QuasiPolynomial:
        """``F(.; 0, p) = A + B``, each kernel shared by ``A`` and ``B`` with opposite signs written once
        (:func:`_merged`); built once per ``p`` (the last :data:`_NOMINALS_KEPT` kept)."""
        key = (float(p), math.copysign(1.0, p))  # -0.0 apart from 0.0: the signs of zero products kept
        F = self._nominals.get(key)
        if F is None:
            if len(self._nominals) >= _NOMINALS_KEPT:
                self._nominals.clear()
            F = self._nominals[key] = _merged(self.A(p) + self.B(p))
        return F

    def combined(self, p: float) -> QuasiPolynomial:
        """:meth:`nominal`, an :class:`AffineLoop` without a filter's ``s`` factor as :meth:`AffineLoop.nominal`
        (the changes of ``A`` and ``B`` summed before the product with ``p``)."""
        if isinstance(self.loop, AffineLoop) and not (self.a1_times_s or self.b1_times_s):
            return _merged(self.loop.nominal(p))
        return self.nominal(p)

    def nominally_stable(self, p: float) -> bool:
        """Certified: ``F(.; 0, p)`` has no zero with ``Re s >= 0``.

        The zeros with ``Re s >= 0`` are counted in the radius of
        :func:`nrobust.bounds.root_free_region` (its half-plane, which the count does not use, is not
        computed: :func:`_zero_free_radius`).
        """
        if isinstance(self.loop, AffineGainLoop):
            return nominally_stable(self.loop, p)
        F = self.nominal(p)
        return unstable_count(F, _zero_free_radius(F)).stable

    def zero_root(self) -> float | None:
        """The parameter at which ``s = 0`` is a root for every delay (``F(0; ., p) = 0``), or None."""
        s0 = np.array([0j])
        if isinstance(self.loop, AffineGainLoop):
            f0, f1 = complex(self.loop.S(s0)[0]), complex(self.loop.R(s0)[0])
        else:
            lp = self.loop
            f0 = complex(lp.A0(s0)[0] + lp.B0(s0)[0])
            f1 = complex(lp.A1(s0)[0] + lp.B1(s0)[0])
        if f1 == 0.0:
            return None
        p0 = -f0 / f1
        return p0.real if abs(p0.imag) <= 1e-12 * max(abs(p0), 1.0) else None

    def crossing_bound(self, lo: float, hi: float) -> float:
        """A frequency above every crossing of every parameter in ``[lo, hi]``.

        For a gain (``A_1 = 0``) ``g`` is concave in ``p`` (``c_2 = -|B_1|^2``): the bounds at
        the ends hold inside (:class:`~nrobust.margins.gain.AxisBound` when it applies, else
        :func:`~nrobust.margins.frequency_bound`); so for any family with ``A_1 = 0``. For the
        filter's pole (``A = A_0 (1 + p s)``, ``B_1 = 0``) the largest bound at the ends and at the
        point of ``[lo, hi]`` nearest 0, which holds inside because
        ``|A(i w)|^2 = |A_0|^2 (1 + p^2 w^2)`` grows with ``|p|``; for the same reason the bound at
        ``p = 0`` holds for every ``p`` when ``A_0`` dominates there (``|A_0| > |B|`` beyond it), and
        the least of the two is taken (a filter without a zero on a strongly stable law: the bound at a
        small pole grows like ``1/|p|``, the one at 0 does not). For other families a bound uniform
        over the interval (:func:`_uniform_crossing_bound`).

        Raises
        ------
        ParameterError
            Naming ``bounds``: the difference operator is not strongly stable at every parameter of
            ``[lo, hi]`` (:func:`_strong_stability_failures`; the message says where it is).
        """
        _check_strongly_stable(self.affine, lo, hi)
        W = float("inf")
        if isinstance(self.loop, AffineGainLoop):
            second = AxisBound.of(self.loop)
            if second is not None:
                W = second.W(lo, hi)
        if not (self.a1_zero or (self.a1_times_s and self.b1_zero)):
            return _uniform_crossing_bound(self.affine, lo, hi)
        points = [lo, hi] if self.a1_zero else [lo, hi, min(max(0.0, lo), hi)]
        out = 0.0
        for p in points:
            b = frequency_bound(self.A(p), self.B(p))
            if b is None:
                raise ParameterError(
                    "bounds",
                    "parameters where the loop's difference operator is strongly stable (no frequency bound at "
                    f"p = {p:.12g})",
                    (lo, hi),
                )
            out = max(out, float(b[0]))
        if not self.a1_zero and points[2] != 0.0:
            A, B = self.A(0.0), self.B(0.0)
            at_zero = frequency_bound(A, B)
            first = principal_gap({"A": (A, 0), "B": (B, 1)}, joint_degree(A, B), 0.0)
            if at_zero is not None and first is not None and first.first == "A":  # |A_0| > |B| beyond it
                out = min(out, float(at_zero[0]))
        return min(W, out)


@dataclass(frozen=True, eq=False)
class _Piece:
    """One crossing curve: samples ``lo..hi`` of the branch ``sigma``, ``K`` monotone, with its joints."""

    sigma: float
    w: NDArray[np.float64]
    K: NDArray[np.float64]
    d: NDArray[np.float64]
    start: str  # how it begins and ends: "birth", "junction", "wrap", "pole", "edge"
    stop: str

    def at(self, K: float) -> tuple[float, float] | None:
        """Interpolated ``(w, d)`` where the piece reaches ``K``, or None."""
        order = np.argsort(self.K)
        Ks = self.K[order]
        if self.K.size < 2 or not Ks[0] <= K <= Ks[-1]:
            return None
        return float(np.interp(K, Ks, self.w[order])), float(np.interp(K, Ks, self.d[order]))


def _cat(*parts: Any) -> NDArray[np.float64]:
    """The numbers and arrays ``parts`` joined into one array (``np.r_`` without its parsing)."""
    return np.concatenate([np.ravel(p) for p in parts])


def _side_without_crossings(
    disc: Callable[[NDArray], NDArray], x: NDArray, a: NDArray, b: NDArray, toward: NDArray
) -> NDArray:
    """Zeros of ``disc`` in ``[a, b]`` near ``x`` to rounding, each moved to where ``disc <= 0`` (the side
    ``toward``, ``+1`` or ``-1``, of the zero), vectorised.

    Secant steps from ``x`` (a simple zero: superlinear), then up to :data:`_JUNCTION_NUDGES` moves of a few
    ulps towards ``toward`` while ``disc > 0``; a zero that does not get there keeps its last estimate.
    """
    x0, f0 = x, disc(x)
    x1 = np.clip(x0 + 1e-6 * (b - a) * toward, a, b)
    f1 = disc(x1)
    for _ in range(_SECANT_STEPS):
        with np.errstate(invalid="ignore", divide="ignore"):
            x2 = x1 - f1 * (x1 - x0) / (f1 - f0)
        x2 = np.where(np.isfinite(x2), np.clip(x2, a, b), x1)
        x0, f0, x1 = x1, f1, x2
        f1 = disc(x1)
        if np.all(np.abs(x1 - x0) <= 4.0 * _EPS * np.abs(x1)):
            break
    x, f = np.where(np.abs(f1) <= np.abs(f0), x1, x0), np.where(np.abs(f1) <= np.abs(f0), f1, f0)
    for nudge in range(_JUNCTION_NUDGES):
        over = f > 0.0
        if not over.any():
            break
        x = np.where(over, np.clip(x + toward * _EPS * np.abs(x) * 4.0**nudge, a, b), x)
        f = np.where(over, disc(x), f)
    return x


# Points (w, K, d) of a branch.
_Points = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]


class _Curves:
    """The crossing curves of an affine loop for the parameters ``[K_lo, K_hi]``, sampled and exact."""

    def __init__(self, loop: _Family, K_lo: float, K_hi: float, max_evals: int) -> None:
        self.loop, self.K_lo, self.K_hi = loop, K_lo, K_hi
        W = loop.crossing_bound(K_lo, K_hi)
        T = max(loop.max_delay, 1e-3)
        # a power of two (exact uniform samples), at least _MIN_SAMPLES up to W
        dw = float(2.0 ** np.floor(np.log2(min(np.pi / (_STEPS * T), W / _MIN_SAMPLES))))
        self.W, self.dw = W, dw
        n = max(int(np.ceil(W / dw)), 16) + _PER_OCTAVE * _LOW_OCTAVES
        if n > max_evals // loop.evals_per_sample:
            raise CertificationError(
                f"the crossing curves of the gains [{K_lo:.12g}, {K_hi:.12g}] extend to W = {W:.6g}: sampling them "
                f"needs about {loop.evals_per_sample * n:.3g} evaluations, beyond max_evals={max_evals} (gains closer "
                "to the strong-stability bound need more)"
            )
        low = dw * 2.0 ** (-np.arange(_PER_OCTAVE * _LOW_OCTAVES, 0, -1) / _PER_OCTAVE)
        uniform = dw * np.arange(1, n - low.size + 1, dtype=float)
        # the uniform samples evaluated apart from the geometric ones: on a vertical line of uniform steps the
        # distributed terms are chirp-z transforms (:mod:`nrobust.distributed_delay`), not an exponential per
        # node and sample
        at = self._split_poles(_joined(loop.axis(low, slopes=True), loop.axis(uniform, slopes=True)))
        w = at.w
        D, m, root = at.branches()
        junctions = self._junctions(w, D)
        pole = np.sign(at.curvature())
        poles = self._poles(w, D, m, root, pole)
        self.pieces: list[_Piece] = []
        for sigma in (1.0, -1.0):
            K = m + sigma * root
            slope = at.slopes(K, sigma)
            theta = at.theta(K)
            wraps = self._wraps(sigma, w, K, theta, D, pole)
            births = self._births(sigma, w, K, slope, theta / w, D, pole)
            self._cut(sigma, w, K, slope, theta / w, theta, D, junctions, pole, wraps, births, poles)
        self.gains = np.linspace(K_lo, K_hi, _N_GAINS)
        self.envelope, self.active = self._envelope(self.gains)
        self.edges = _stability_edges(self)

    def _split_poles(self, at: _Axis) -> _Axis:
        """The samples ``at`` with more in the cells where ``c_2`` changes sign (a pole) that leave out part of a curve.

        Next to a pole (``c_2 = 0``) one root of ``g``, ``m + sign(m) sqrt D``, passes through
        ``p = inf`` and ``D`` is large and positive. The samples leave out part of a curve when
        ``D < 0`` at one end of the cell (a junction, ``D = 0``, lies between the pole and that
        end: on the collocated observer's loop of the plant ``(1, 1, 1, 1, 1, 0.8)`` a pole and a
        junction 0.005 apart at ``w = 3.18``, and a curve with the smallest crossing delay at the
        parameters below ``-0.51`` between them), or when the root that passes through infinity is,
        at an end, on the near side of the bounds (widened by their width; the parameters from it
        to infinity are reached between that end and the pole: of the plant ``(1, 1, 1, 1, 1, 0.9)``,
        every parameter below ``-0.22`` at ``w`` in ``[15.703, 15.716]``). Such a cell is halved
        until neither holds (:meth:`_poles`, :meth:`_junctions` then treat each event in its own cell,
        and the pieces reach beyond the bounds), at most :data:`_POLE_SPLITS` times, else a
        :class:`~nrobust.errors.CertificationError`.
        """
        if self.loop.gain:  # c_2 = -|R|^2: no pole
            return at
        c2 = at.curvature()
        k = np.flatnonzero(np.sign(c2[:-1]) != np.sign(c2[1:]))
        if not k.size:
            return at
        # each pole's finite root -c_0 / (2 h) and the direction sign(-h c_2) in which the other leaves, by side
        w_pole = illinois(lambda x: self.loop.axis(x).curvature(), at.w[k].copy(), at.w[k + 1].copy(), steps=12)
        there = self.loop.axis(w_pole)
        h = (np.conj(there.a0) * there.a1).real - (np.conj(there.b0) * there.b1).real
        c0 = np.abs(there.a0) ** 2 - np.abs(there.b0) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            finite = -c0 / (2.0 * h)
        span = self.K_hi - self.K_lo
        for _ in range(_POLE_SPLITS):
            D, m, root = at.branches()
            pole, valid = np.sign(at.curvature()), D >= 0.0
            j = np.flatnonzero(pole[:-1] != pole[1:])
            which = np.clip(np.searchsorted(w_pole, at.w[j]), 0, w_pole.size - 1)  # the pole in each cell
            short = np.zeros(j.size, dtype=bool)
            for e in (j, j + 1):
                up, down = m[e] + root[e], m[e] - root[e]
                far = np.where(np.abs(up - finite[which]) >= np.abs(down - finite[which]), up, down)
                out = -np.sign(h[which] * pole[e])
                short |= ((out > 0) & (far <= self.K_hi + span)) | ((out < 0) & (far >= self.K_lo - span))
            j = j[~(valid[j] & valid[j + 1]) | short]
            if not j.size:
                return at
            mid = 0.5 * (at.w[j] + at.w[j + 1])
            at = _inserted(at, self.loop.axis(mid, slopes=True))
        w = float(at.w[j[0]])
        raise CertificationError(
            f"best_margin: a crossing curve of the parameters [{self.K_lo:.12g}, {self.K_hi:.12g}] passes through "
            f"p = inf near w = {w:.12g}, and {_POLE_SPLITS} halvings of the sample step about it leave a junction "
            "(D = 0) beside it or its root short of the bounds; the scan cannot follow it there (other bounds may help)"
        )

    def cell(self, w: float) -> float:
        """The spacing of the samples about the frequency ``w``: ``dw``, or less below it (geometric samples)."""
        return self.dw if w >= self.dw else w * (2.0 ** (1.0 / _PER_OCTAVE) - 1.0)

    def _wraps(
        self, sigma: float, w: NDArray, K: NDArray, theta: NDArray, D: NDArray, pole: NDArray
    ) -> dict[int, tuple[float, float]]:
        """``(w, K)`` where the branch's ``theta`` passes ``0 mod 2 pi`` (a root on the axis at ``delta = 0``).

        Keyed by ``j``, the wrap in ``[w_j, w_{j+1}]``; only those with a parameter near the
        bounds. Eight Illinois steps on the principal ``arg(-B/A)``, vectorised over the wraps:
        the nominal stability changes there, and both pieces end there (the delay ``0`` on one
        side, ``2 pi / w`` on the other).
        """
        if self.loop.gain:  # an AffineGainLoop keeps the sampled wraps
            return {}
        valid = D >= 0.0
        span = self.K_hi - self.K_lo
        near = (np.minimum(K[:-1], K[1:]) <= self.K_hi + span) & (np.maximum(K[:-1], K[1:]) >= self.K_lo - span)
        j = np.flatnonzero(valid[:-1] & valid[1:] & (np.abs(np.diff(theta)) > np.pi) & near & (pole[:-1] == pole[1:]))
        if not j.size:
            return {}

        def f(x: NDArray) -> NDArray:
            _, m, root, at = self._sample(x, slopes=False)
            return np.angle(-(at.b0 + (m + sigma * root) * at.b1) / (at.a0 + (m + sigma * root) * at.a1))

        a, b = w[j].copy(), w[j + 1].copy()
        fa, fb = f(a), f(b)
        keep = fa * fb < 0
        j, a, b, fa, fb = j[keep], a[keep], b[keep], fa[keep], fb[keep]
        wx = illinois(f, a, b, fa, fb)  # to rounding: the nominal stability changes there (:func:`_stability_edges`)
        _, m, root, _ = self._sample(wx, slopes=False)
        return {int(k): (float(x), float(mk + sigma * rk)) for k, x, mk, rk in zip(j, wx, m, root)}

    def _poles(
        self, w: NDArray, D: NDArray, m: NDArray, root: NDArray, pole: NDArray
    ) -> dict[int, tuple[float, float, float, float, float]]:
        """``(w, K, theta, sigma_before, sigma_after)`` where ``c_2`` changes sign in ``[w_j, w_{j+1}]`` (key ``j``).

        There ``g = c_0 + 2 h p`` is linear in ``p``: one root ``K = -c_0 / (2 h)`` stays finite
        while the other passes through ``p = inf``, and the finite one changes branch (``sigma``
        is the sign of ``sqrt D`` relative to ``m = -h / c_2``, which flips with ``c_2``). The
        point is located by twelve Illinois steps on ``c_2`` (vectorised over the poles); the
        finite branch on each side is the one nearer ``K`` at the neighbouring sample. Its
        ``dK/dw`` changes sign through infinity there, which is not a pair birth.
        """
        if self.loop.gain:  # c_2 = -|R|^2: no pole
            return {}
        valid = D >= 0.0
        j = np.flatnonzero(valid[:-1] & valid[1:] & (pole[:-1] * pole[1:] < 0))
        if not j.size:
            return {}

        def c2(x: NDArray) -> NDArray:
            return self.loop.axis(x).curvature()

        wx = illinois(c2, w[j].copy(), w[j + 1].copy(), steps=12)
        at = self.loop.axis(wx)
        c0 = np.abs(at.a0) ** 2 - np.abs(at.b0) ** 2
        h = (np.conj(at.a0) * at.a1).real - (np.conj(at.b0) * at.b1).real
        with np.errstate(divide="ignore", invalid="ignore"):
            Kx = np.where(h != 0.0, -c0 / (2.0 * np.where(h != 0.0, h, 1.0)), np.inf)
        theta = at.theta(np.where(np.isfinite(Kx), Kx, 0.0))
        out: dict[int, tuple[float, float, float, float, float]] = {}
        for k, x, K, th in zip(j, wx, Kx, theta):
            if not np.isfinite(K):
                continue
            side = [1.0 if abs(m[i] + root[i] - K) <= abs(m[i] - root[i] - K) else -1.0 for i in (k, k + 1)]
            out[int(k)] = (float(x), float(K), float(th), side[0], side[1])
        return out

    def _sample(self, w: NDArray[np.float64], slopes: bool = True) -> tuple[NDArray, NDArray, NDArray, _Axis]:
        """``D, m, sqrt D`` and the loop on the axis at ``w`` (with slopes unless ``slopes`` is False)."""
        at = self.loop.axis(w, slopes=slopes)
        D, m, root = at.branches()
        return D, m, root, at

    def _junctions(self, w: NDArray[np.float64], D: NDArray[np.float64]) -> dict[int, dict[float, _Points]]:
        """Points ``(w, K, d)`` of each branch between each junction (``D = 0``, in ``[w_j, w_{j+1}]``) and the
        valid sample.

        Near a junction ``K_pm - m ~ sqrt(D)``: the points are spaced quadratically towards
        the junction, located by eight Illinois steps on ``D`` (vectorised over the junctions;
        for an :class:`AffineLoop` then to rounding and on the side without crossings, ``D <= 0``:
        :func:`_side_without_crossings`), and evaluated in one batch. Keyed by ``j``, then by
        the branch ``sigma``; each array runs from the junction (where both branches meet at
        ``K = m``) to the valid sample.

        The junction's side matters: there ``K = m`` is the branch's own value
        ``m + sigma sqrt(max(D, 0))``, so each branch is continuous from it, and a wrap of its phase
        next to the junction (a root on the axis at ``delta = 0``) is a sign change of the phase
        between two of its points (:meth:`_split_at_wraps`). On the other side ``K`` would jump by
        ``sqrt(D)``, ``D`` about the error of the location times ``dD/dw``: a wrap within it was missed.
        """
        j = np.flatnonzero((D[:-1] >= 0.0) != (D[1:] >= 0.0))
        if not j.size:
            return {}

        def disc(x: NDArray) -> NDArray:
            return self.loop.axis(x).branches()[0]

        a, b, fa, fb = w[j].copy(), w[j + 1].copy(), D[j].copy(), D[j + 1].copy()
        wj = illinois(disc, a, b, fa, fb, steps=8)
        valid_end = np.where(D[j] >= 0.0, w[j], w[j + 1])
        if not self.loop.gain:  # an AffineLoop solves its wraps: each on a branch continuous from the junction
            wj = _side_without_crossings(disc, wj, a, b, np.where(D[j] >= 0.0, 1.0, -1.0))
        t = np.linspace(0.0, 1.0, 10)[:-1] ** 2
        points = (wj[:, None] + (valid_end - wj)[:, None] * t[None, :]).ravel()
        at = self.loop.axis(points)
        _, m, root = at.branches()
        root = root.reshape(j.size, t.size)
        root[:, 0] = 0.0  # both branches meet at the same gain (sqrt(D) is clipped at 0 there)
        root = root.ravel()
        out: dict[int, dict[float, _Points]] = {int(k): {} for k in j}
        for sigma in (1.0, -1.0):
            K = m + sigma * root
            d = at.theta(K) / points
            for n, k in enumerate(j):
                part = slice(n * t.size, (n + 1) * t.size)
                out[int(k)][sigma] = (points[part], K[part], d[part])
        return out

    def _cut(
        self,
        sigma: float,
        w: NDArray,
        K: NDArray,
        slope: NDArray,
        d: NDArray,
        theta: NDArray,
        D: NDArray,
        junctions: dict[int, dict[float, _Points]],
        pole: NDArray,
        wraps: dict[int, tuple[float, float]],
        births: dict[int, tuple[float, float, float]],
        poles: dict[int, tuple[float, float, float, float, float]],
    ) -> None:
        """Cut the branch into monotone pieces at extrema (births), junctions, phase wraps and poles.

        At a pole ``c_2`` changes sign: one root leaves through ``p = +-inf`` and comes back
        from the other side (never for a gain, ``c_2 = -|R|^2``), the other stays finite and
        moves to the other branch; the pieces of the finite root on both sides end at its point
        at the pole (:meth:`_poles`), so that no gain between the samples is left uncovered.
        """
        valid = D >= 0.0
        same = pole[:-1] == pole[1:]  # dK/dw changes sign through infinity at a pole: not a birth
        turn = valid[:-1] & valid[1:] & (np.sign(slope[:-1]) * np.sign(slope[1:]) < 0) & same
        wrap = valid[:-1] & valid[1:] & (np.abs(np.diff(theta)) > np.pi)
        gap = (valid[:-1] != valid[1:]) | (pole[:-1] != pole[1:])
        cuts = np.flatnonzero(turn | wrap | gap)
        start, how = 0, "edge"
        items: list[tuple[NDArray, NDArray, NDArray, str, str]] = []
        for c in [*cuts.tolist(), w.size - 1]:
            lo, hi = start, c
            if c == w.size - 1:
                stop = "edge"
            elif turn[c]:
                stop = "birth"
            elif pole[c] != pole[c + 1]:
                stop = "pole"
            elif wrap[c]:
                stop = "wrap"
            else:
                stop = "junction"
            if valid[lo] and valid[hi]:
                # the point (or points) the piece starts from before its samples and ends at after them: one
                # kind each (``how``, ``stop``), joined to the samples in one concatenation per array
                first: tuple[Any, Any, Any] | None = None
                last: tuple[Any, Any, Any] | None = None
                if how == "birth":  # the extremum between the samples
                    first = births[lo - 1]
                elif how == "junction" and lo - 1 in junctions:
                    first = junctions[lo - 1][sigma]
                elif how == "wrap" and lo - 1 in wraps:  # theta tends to 0 or 2 pi at the wrap
                    w_wrap, K_wrap = wraps[lo - 1]
                    first = (w_wrap, K_wrap, (_TWO_PI if theta[lo] > np.pi else 0.0) / w_wrap)
                elif how == "pole" and lo - 1 in poles and poles[lo - 1][4] == sigma:
                    first = (*poles[lo - 1][:2], self._pole_delay(poles[lo - 1], theta[lo]))
                if stop == "birth":
                    last = births[hi]
                elif stop == "junction" and hi in junctions:
                    wx, Kx, dx = junctions[hi][sigma]
                    last = (wx[::-1], Kx[::-1], dx[::-1])
                elif stop == "wrap" and hi in wraps:
                    w_wrap, K_wrap = wraps[hi]
                    last = (w_wrap, K_wrap, (_TWO_PI if theta[hi] > np.pi else 0.0) / w_wrap)
                elif stop == "pole" and hi in poles and poles[hi][3] == sigma:
                    last = (*poles[hi][:2], self._pole_delay(poles[hi], theta[hi]))
                ws, Ks, ds = w[lo : hi + 1], K[lo : hi + 1], d[lo : hi + 1]
                if first is not None or last is not None:
                    ws, Ks, ds = (
                        _cat(*([] if first is None else [first[k]]), x, *([] if last is None else [last[k]]))
                        for k, x in enumerate((ws, Ks, ds))
                    )
                items.append((ws, Ks, ds, how, stop))
            start, how = c + 1, stop
        self.pieces.extend(self._split_at_wraps(sigma, items))

    @staticmethod
    def _pole_delay(pole: tuple[float, float, float, float, float], theta_near: float) -> float:
        """The crossing delay at the finite root of a pole (:meth:`_poles`) on the phase branch of ``theta_near``."""
        w, theta = pole[0], pole[2]
        return (theta + _TWO_PI * np.round((theta_near - theta) / _TWO_PI)) / w

    def _split_at_wraps(self, sigma: float, items: list[tuple[NDArray, NDArray, NDArray, str, str]]) -> list[_Piece]:
        """The pieces ``(w, K, d, start, stop)`` of the branch, each cut where its phase wraps between points added
        near a junction (not between samples).

        Each such wrap is solved by the Illinois iteration on the principal ``arg(-B/A)`` along the branch,
        every wrap of the branch at once (:func:`~nrobust._bracket.illinois`, to the rounding of ``w``), and
        ends both parts (the delay ``0`` on one side, ``2 pi / w`` on the other).
        """
        span = self.K_hi - self.K_lo
        brackets: list[tuple[int, int]] = []  # (item, c): a wrap between the points c and c + 1 of the item
        for i, (ws, Ks, ds, _, _) in enumerate(items):
            jumps = np.flatnonzero(np.abs(np.diff(ds * ws)) > np.pi) if not self.loop.gain else ()
            # (a piece away from the bounds is never on the envelope)
            if len(jumps) and not (Ks.size and (Ks.min() > self.K_hi + span or Ks.max() < self.K_lo - span)):
                brackets += [(i, int(c)) for c in jumps]
        solved: dict[tuple[int, int], tuple[float, float]] = {}  # (item, c) -> (w, K) at the wrap
        if brackets:

            def phase(x: NDArray) -> NDArray:
                _, m, root, at = self._sample(np.asarray(x, dtype=float), slopes=False)
                K = m + sigma * root
                return np.asarray(np.angle(-(at.b0 + K * at.b1) / (at.a0 + K * at.a1)), dtype=float)

            ends = np.array([(items[i][0][c], items[i][0][c + 1]) for i, c in brackets], dtype=float)
            a, b = ends.min(axis=1), ends.max(axis=1)
            fa, fb = phase(np.concatenate([a, b])).reshape(2, -1)
            keep = np.flatnonzero(fa * fb <= 0)
            if keep.size:
                wx = illinois(phase, a[keep], b[keep], fa[keep], fb[keep], rtol=2e-15)
                _, m, root, _ = self._sample(wx, slopes=False)
                for k, x, Kx in zip(keep.tolist(), wx.tolist(), (m + sigma * root).tolist()):
                    solved[brackets[k]] = (x, Kx)
        wrapped = {i for i, _ in solved}
        out: list[_Piece] = []
        for i, (ws, Ks, ds, how, stop) in enumerate(items):
            if i not in wrapped:
                out.append(_Piece(sigma, ws, Ks, ds, how, stop))
                continue
            theta = ds * ws
            start, start_how = 0, how
            w_prev, K_prev, d_prev = np.zeros(0), np.zeros(0), np.zeros(0)
            for c in range(ws.size - 1):
                if (i, c) not in solved:
                    continue
                w_wrap, K_wrap = solved[i, c]
                end = (_TWO_PI if theta[c] > np.pi else 0.0) / w_wrap
                out.append(
                    _Piece(
                        sigma,
                        _cat(w_prev, ws[start : c + 1], w_wrap),
                        _cat(K_prev, Ks[start : c + 1], K_wrap),
                        _cat(d_prev, ds[start : c + 1], end),
                        start_how,
                        "wrap",
                    )
                )
                begin = (_TWO_PI if theta[c + 1] > np.pi else 0.0) / w_wrap
                w_prev, K_prev, d_prev = np.array([w_wrap]), np.array([K_wrap]), np.array([begin])
                start, start_how = c + 1, "wrap"
            out.append(
                _Piece(
                    sigma, _cat(w_prev, ws[start:]), _cat(K_prev, Ks[start:]), _cat(d_prev, ds[start:]), start_how, stop
                )
            )
        return out

    def _births(
        self, sigma: float, w: NDArray, K: NDArray, slope: NDArray, d: NDArray, D: NDArray, pole: NDArray
    ) -> dict[int, tuple[float, float, float]]:
        """``(w, K, d)`` at each extremum of the branch's ``K(w)`` (a pair birth) in ``[w_j, w_{j+1}]``, keyed by ``j``.

        For an :class:`AffineLoop`, those whose estimate or samples are near the bounds, or on either side
        of them, are solved by twelve Illinois steps on ``dK/dw`` (vectorised over the births; on the
        collocated observer's loop of the plant ``(1, 1, 1, 1, 1, 0.9)`` an estimate of ``0.863`` for a
        birth at ``-2.406`` between two poles 0.035 apart made a curve seem to reach the bounds, where no
        root follows it); the others, and those of an
        :class:`~nrobust.margins.AffineGainLoop`, are estimated from the linear slope (the
        candidates near the top are solved exactly in any case).
        """
        valid = D >= 0.0
        turn = np.sign(slope[:-1]) * np.sign(slope[1:]) < 0
        j = np.flatnonzero(valid[:-1] & valid[1:] & turn & (pole[:-1] == pole[1:]))
        if not j.size:
            return {}
        t = slope[j] / (slope[j] - slope[j + 1])
        wb = w[j] + t * (w[j + 1] - w[j])
        Kb = K[j] + 0.5 * slope[j] * (wb - w[j])
        db = d[j] + t * (d[j + 1] - d[j])
        span = self.K_hi - self.K_lo
        # the estimate or a sample near the bounds, or the bounds between them: the estimate overshoots where
        # ``K(w)`` is far from quadratic over the cell (between two poles ``K`` moves by hundreds per unit of ``w``)
        low = np.minimum(np.minimum(K[j], K[j + 1]), Kb)
        high = np.maximum(np.maximum(K[j], K[j + 1]), Kb)
        near = np.flatnonzero((low <= self.K_hi + span) & (high >= self.K_lo - span))
        if near.size and not self.loop.gain:  # an AffineGainLoop keeps the estimates

            def f(x: NDArray) -> NDArray:
                _, m, root, at = self._sample(x)
                return at.slopes(m + sigma * root, sigma)

            a, b = w[j[near]].copy(), w[j[near] + 1].copy()
            fa, fb = slope[j[near]].copy(), slope[j[near] + 1].copy()
            wx = illinois(f, a, b, fa, fb, steps=12)
            _, m, root, at = self._sample(wx, slopes=False)
            Kx = m + sigma * root
            theta = at.theta(Kx)
            # the branch of the phase of the neighbouring sample
            theta += _TWO_PI * np.round((d[j[near]] * w[j[near]] - theta) / _TWO_PI)
            wb[near], Kb[near], db[near] = wx, Kx, theta / wx
        return {int(k): (float(x), float(y), float(z)) for k, x, y, z in zip(j, wb, Kb, db)}

    def _envelope(self, gains: NDArray) -> tuple[NDArray, NDArray]:
        """The smallest interpolated delay over the pieces at each gain, and the piece that gives it."""
        env = np.full(gains.size, np.inf)
        active = np.full(gains.size, -1)
        for p, piece in enumerate(self.pieces):
            if piece.K.size < 2:
                continue
            order = np.argsort(piece.K)
            Ks, ds = piece.K[order], piece.d[order]
            inside = (gains >= Ks[0]) & (gains <= Ks[-1])
            val = np.interp(gains[inside], Ks, ds)
            better = val < env[inside]
            idx = np.flatnonzero(inside)[better]
            env[idx], active[idx] = val[better], p
        return env, active

    def refine(self, near: NDArray[np.bool_]) -> None:
        """Solve every curve that may be the lowest at the grid gains ``near`` and take the lowest exact delay.

        The sampled envelope interpolates each piece linearly in ``K``; near a junction or a birth,
        where ``K(w)`` moves as a square root, a piece's interpolated delay can be off by more than
        the gap to the next curve (1e-3 relative on the collocated observer's loop): the lower curve
        is then hidden, and with it the kink where the two meet. At ``near`` each piece within
        5 % of the interpolated envelope is solved by Newton on ``g(w; K) = 0`` from its
        interpolated frequency (vectorised over the pairs), and ``envelope``, ``active`` take the
        lowest exact delay; a pair that does not converge keeps its interpolated delay, unless a birth
        ends its piece within four cells (past the exact birth of an interpolated curve: no root there).
        Where the lowest exact delay exceeds the interpolated envelope, the pieces within 5 % of it are
        solved too, until none is added: next to a pole ``K(w)`` is steep and the interpolation can be
        off by 10 % (on the collocated observer's loop of the plant ``(1, 1, 1, 1, 1, 0.9)`` a curve
        interpolated at 0.1250 is at 0.1379, above the one at 0.1282 that the window had left out).
        """
        idx = np.flatnonzero(near & np.isfinite(self.envelope))
        if not idx.size:
            return
        gains = self.gains[idx]
        best, active = np.full(idx.size, np.inf), np.full(idx.size, -1)
        below, limit = np.zeros(idx.size), self.envelope[idx]
        # until no gain's lowest exact delay exceeds the delay the window was taken about
        while np.any(limit > below):
            pairs, d = self._exact_pairs(gains, 1.05 * below, 1.05 * limit)
            for (k, p), dk in zip(pairs, d):
                if dk < best[k]:
                    best[k], active[k] = dk, p
            below, limit = limit, np.where(best > limit, best, limit)
        found = active >= 0
        self.envelope[idx[found]], self.active[idx[found]] = best[found], active[found]

    def _exact_pairs(self, gains: NDArray, lower: NDArray, upper: NDArray) -> tuple[NDArray, NDArray]:
        """The pairs ``(gain index, piece)`` whose interpolated delay lies in ``[lower, upper)`` at the gain, and their
        exact delays (:meth:`refine`)."""
        rows, Ks, ws, thetas, interp, born = [np.zeros((0, 2), dtype=int)], [], [], [], [], []
        cell = 4.0 * (self.K_hi - self.K_lo) / (_N_GAINS - 1)
        for p, piece in enumerate(self.pieces):
            if piece.K.size < 2:
                continue
            order = np.argsort(piece.K)
            Kp = piece.K[order]
            inside = np.flatnonzero((gains >= Kp[0]) & (gains <= Kp[-1]))
            if not inside.size:
                continue
            d = np.interp(gains[inside], Kp, piece.d[order])
            keep = (d >= lower[inside]) & (d < upper[inside])  # as :meth:`value`: a curve that may be the lowest
            inside, d = inside[keep], d[keep]
            w = np.interp(gains[inside], Kp, piece.w[order])
            rows.append(np.column_stack([inside, np.full(inside.size, p)]))
            Ks.append(gains[inside])
            ws.append(w)
            thetas.append(d * w)
            interp.append(d)
            births = [k for k, how in ((piece.K[0], piece.start), (piece.K[-1], piece.stop)) if how == "birth"]
            born.append(np.array([any(abs(k - x) <= cell for k in births) for x in gains[inside]], dtype=bool))
        pairs = np.concatenate(rows).astype(int)
        if not pairs.size:
            return pairs, np.zeros(0)
        d = self._exact_delays(np.concatenate(Ks), np.concatenate(ws), np.concatenate(thetas))
        # not converged: past the exact birth of an interpolated curve (dropped, as in :meth:`value`), else the
        # interpolated delay
        return pairs, np.where(np.isfinite(d), d, np.where(np.concatenate(born), np.inf, np.concatenate(interp)))

    def _exact_delays(self, K: NDArray, w0: NDArray, theta0: NDArray) -> NDArray:
        """Newton on ``g(w; K) = |A|^2 - |B|^2 = 0`` from ``w0`` at each ``K``, vectorised: the crossing delay on the
        branch of the phase nearest ``theta0`` (as :meth:`at_gain`), NaN where Newton did not converge."""
        w = w0.copy()
        done = np.zeros(w.size, dtype=bool)
        for _ in range(_NEWTON_STEPS):
            at = self.loop.axis(w, slopes=True)
            a, b = at.a0 + K * at.a1, at.b0 + K * at.b1
            da, db = at.da0 + K * at.da1, at.db0 + K * at.db1
            g = np.abs(a) ** 2 - np.abs(b) ** 2
            gw = 2.0 * ((np.conj(a) * da).real - (np.conj(b) * db).real)
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(done, 0.0, g / gw)
            w = w - step
            done |= np.abs(step) <= 1e-13 * np.abs(w)
            if done.all():
                break
        at = self.loop.axis(w)
        theta = at.theta(K)
        theta += _TWO_PI * np.round((theta0 - theta) / _TWO_PI)
        with np.errstate(divide="ignore", invalid="ignore"):
            d = theta / w
            d = np.where(d < 0.0, d + _TWO_PI / w * np.ceil(-d * w / _TWO_PI), d)  # past a wrap, as :meth:`value`
        return np.where(done & (w > 0.0), d, np.nan)

    def add_edges(self, edges: list[tuple[float, float]]) -> None:
        """Add stability edges ``(w, p)`` found outside the scan (:func:`_missed_edges`): the piece whose phase
        jumps by more than ``pi`` next to one (between two points whose frequencies or parameters enclose it)
        is cut there, as at a wrap (the delay ``0`` on one side, ``2 pi / w`` on the other), and the envelope
        recomputed."""
        for w_e, p_e in edges:
            out: list[_Piece] = []
            for piece in self.pieces:
                theta = piece.d * piece.w
                near = ((piece.w[:-1] - w_e) * (piece.w[1:] - w_e) <= 0.0) | (
                    (piece.K[:-1] - p_e) * (piece.K[1:] - p_e) <= 0.0
                )
                jumps = np.flatnonzero((np.abs(np.diff(theta)) > np.pi) & near)
                if not jumps.size:
                    out.append(piece)
                    continue
                c = int(jumps[0])
                ws, Ks, ds = piece.w, piece.K, piece.d
                end, begin = ((_TWO_PI if theta[k] > np.pi else 0.0) / w_e for k in (c, c + 1))
                out.append(
                    _Piece(
                        piece.sigma,
                        _cat(ws[: c + 1], w_e),
                        _cat(Ks[: c + 1], p_e),
                        _cat(ds[: c + 1], end),
                        piece.start,
                        "wrap",
                    )
                )
                out.append(
                    _Piece(
                        piece.sigma,
                        _cat(w_e, ws[c + 1 :]),
                        _cat(p_e, Ks[c + 1 :]),
                        _cat(begin, ds[c + 1 :]),
                        "wrap",
                        piece.stop,
                    )
                )
            self.pieces = out
        self.envelope, self.active = self._envelope(self.gains)
        self.edges = sorted({*_stability_edges(self), *(p for _, p in edges if self.K_lo < p < self.K_hi)})

    # ------------------------------------------------------------------ exact evaluations
    def on_branch(self, w: float, sigma: float) -> tuple[float, float, float, float]:
        """Exact ``(K, d, dK/dw, dd/dw)`` on the branch ``sigma`` at ``w``."""
        at = self.loop.axis(np.array([w]), slopes=True)
        _, m, root = at.branches()
        K = float(m[0] + sigma * root[0])
        dK = float(at.slopes(np.array([K]), sigma)[0])
        a, b, da, db, a1, b1 = self._values(np.array([w]), K, at)
        theta = float(np.mod(np.angle(-b / a), _TWO_PI))
        d = theta / w
        theta_w = (db / b - da / a).imag
        theta_K = (b1 / b - a1 / a).imag
        return K, d, dK, ((theta_w + theta_K * dK) / w - d / w)

    def at_gain(self, K: float, w0: float, theta0: float | None = None) -> tuple[float, float, float, float]:
        """Newton on ``g(w; K) = 0`` from ``w0``: ``(w, d, dd/dK, dg/dw)`` (``d`` near ``theta0 / w``)."""
        w, previous = w0, np.inf
        for _ in range(_NEWTON_STEPS):
            a, b, da, db, _, _ = self._values(np.array([w]), K)
            g = abs(a) ** 2 - abs(b) ** 2
            gw = 2.0 * ((np.conj(a) * da).real - (np.conj(b) * db).real)
            step = float(g / gw)
            # near w = 0 (a curve ending where |A(0)| = |B(0)|) g is flat, w known to ~eps/w^2 only, but the
            # delay theta / w tends to a limit: the step's change of the delay is what must be at rounding
            theta = float(np.angle(-b / a))
            d_step = abs(step * ((db / b - da / a).imag - theta / w) / w)
            # at the gain where the curve ends at w = 0 (|A(0)| = |B(0)| exactly) g ~ c w^2 sinks into its
            # rounding while w is still about sqrt(eps / c), and Newton's steps are noise; the delay, near its
            # limit there, is kept once a step would not change it
            if abs(g) <= 8.0 * _EPS * (abs(a) ** 2 + abs(b) ** 2) and d_step <= 4e-15 * abs(theta) / w:
                break
            w -= step
            # converged, or at the rounding floor of g (steps of 1e-12 relative that stop shrinking)
            if abs(step) <= 4e-16 * w or (abs(step) <= _NOISE_STEP * w and abs(step) > 0.5 * previous):
                break
            if abs(step) <= 1e-3 * w and d_step <= 4e-15 * abs(theta) / w:
                break
            previous = abs(step)
        else:
            raise CertificationError(f"best_margin: Newton on |A(i w)| = |B(i w)| did not converge at K = {K:.15g}")
        a, b, da, db, a1, b1 = self._values(np.array([w]), K)
        theta = float(np.mod(np.angle(-b / a), _TWO_PI))
        if theta0 is not None and abs(theta - theta0) > np.pi:  # the same branch of the phase
            theta += _TWO_PI * np.round((theta0 - theta) / _TWO_PI)
        g_w = 2.0 * ((np.conj(a) * da).real - (np.conj(b) * db).real)
        g_K = 2.0 * ((np.conj(a) * a1).real - (np.conj(b) * b1).real)
        theta_w = (db / b - da / a).imag
        theta_K = (b1 / b - a1 / a).imag
        dw_dK = -g_K / g_w
        d = theta / w
        return w, d, (theta_K + theta_w * dw_dK) / w - d * dw_dK / w, g_w

    def _values(
        self, w: NDArray, K: float, at: _Axis | None = None
    ) -> tuple[complex, complex, complex, complex, complex, complex]:
        """``A, B, A', B'`` (``w``-derivatives) at ``i w[0]`` and the parameter ``K``, and ``A_1, B_1``."""
        at = self.loop.axis(w, slopes=True) if at is None else at
        a1, b1 = complex(at.a1[0]), complex(at.b1[0])
        return (
            complex(at.a0[0]) + K * a1,
            complex(at.b0[0]) + K * b1,
            complex(at.da0[0] + K * at.da1[0]),
            complex(at.db0[0] + K * at.db1[0]),
            a1,
            b1,
        )

    def kink(self, starts: list[float], p: _Piece, q: _Piece) -> tuple[float, float, float, float]:
        """Newton in ``(K, w_1, w_2)`` on ``g(w_1; K) = g(w_2; K) = 0``, ``d_1 = d_2``: ``(K, d, w_1, w_2)``.

        Started at the first gain of ``starts`` that both curves reach.
        """
        reached = [K for K in starts if p.at(K) is not None and q.at(K) is not None]
        if not reached:
            raise CertificationError(f"best_margin: the kink near K = {starts[0]:.12g} is not reached by both curves")
        K0 = reached[0]
        s1, s2 = p.at(K0), q.at(K0)
        assert s1 is not None and s2 is not None
        x = np.array([K0, s1[0], s2[0]])
        th = [s1[1] * s1[0], s2[1] * s2[0]]
        scale = max(abs(self.K_lo), abs(self.K_hi), 1e-300)
        for _ in range(_NEWTON_STEPS):
            rows, rhs = [], []
            ds = []
            for k, (wk, t0) in enumerate(zip(x[1:], th)):
                a, b, da, db, a1, b1 = self._values(np.array([wk]), x[0])
                theta = float(np.mod(np.angle(-b / a), _TWO_PI))
                theta += _TWO_PI * np.round((t0 - theta) / _TWO_PI)
                g_w = 2.0 * ((np.conj(a) * da).real - (np.conj(b) * db).real)
                g_K = 2.0 * ((np.conj(a) * a1).real - (np.conj(b) * b1).real)
                row = [g_K, 0.0, 0.0]
                row[1 + k] = g_w
                rows.append(row)
                rhs.append(abs(a) ** 2 - abs(b) ** 2)
                ds.append((theta / wk, (b1 / b - a1 / a).imag / wk, ((db / b - da / a).imag - theta / wk) / wk))
            (d1, d1K, d1w), (d2, d2K, d2w) = ds
            J = np.array([*rows, [d1K - d2K, d1w, -d2w]])
            step = np.linalg.solve(J, np.array([*rhs, d1 - d2]))
            x = x - step
            if abs(step[0]) <= 1e-15 * scale and np.all(np.abs(step[1:]) <= 1e-15 * np.abs(x[1:])):
                break
        else:
            raise CertificationError(f"best_margin: the kink equations near K = {K0:.12g} did not converge")
        if abs(x[1] - x[2]) <= 1e-8 * x[1]:
            raise CertificationError(f"best_margin: the two curves near K = {K0:.12g} meet at one frequency")
        return float(x[0]), 0.5 * (d1 + d2), float(x[1]), float(x[2])

    def value(self, K: float) -> float:
        """The envelope at ``K`` with each curve reaching it solved exactly (inf: none)."""
        best = float("inf")
        cell = 4.0 * (self.K_hi - self.K_lo) / (_N_GAINS - 1)
        for piece in self.pieces:
            s = piece.at(K)
            if s is not None and s[1] < 1.05 * best:  # a curve that may be the lowest (5 %: the scan interpolates it)
                try:
                    w, d = self.at_gain(K, s[0], s[1] * s[0])[:2]
                    if d < 0.0:  # past a wrap (a root on the axis at delta = 0): the next branch of the phase
                        d += _TWO_PI / w * np.ceil(-d * w / _TWO_PI)
                    best = min(best, d)
                except CertificationError:
                    if self.loop.gain:
                        raise
                    # past the exact birth of a pair that the interpolated curve still reaches: no root to follow
                    births = [k for k, how in ((piece.K[0], piece.start), (piece.K[-1], piece.stop)) if how == "birth"]
                    if not any(abs(k - K) <= cell for k in births):
                        raise
        return best


def _checked_loop(loop: Any, bounds: Any) -> tuple[float, float]:
    if not isinstance(loop, (AffineGainLoop, AffineLoop)):
        raise ParameterError(
            "loop",
            "an AffineGainLoop A + (B_0 + K R) e^{-delta s} or an AffineLoop (A_0 + p A_1) + (B_0 + p B_1) "
            "e^{-delta s}",
            type(loop).__name__,
        )
    parts = (loop.A, loop.B0, loop.R) if isinstance(loop, AffineGainLoop) else (loop.A0, loop.A1, loop.B0, loop.B1)
    if not all(isinstance(P, QuasiPolynomial) and P.is_real for P in parts):
        raise ParameterError("loop", "real coefficients (crossings in conjugate pairs)", loop)
    try:
        lo, hi = (finite_real("bounds", b) for b in bounds)
    except TypeError:
        raise ParameterError("bounds", "a pair (K_lo, K_hi) of finite numbers with K_lo < K_hi", bounds) from None
    if not lo < hi:
        raise ParameterError("bounds", "a pair (K_lo, K_hi) of finite numbers with K_lo < K_hi", bounds)
    return lo, hi


def _certify(loop: _Family, K: float, rigorous: bool, max_evals: int) -> tuple[DelayMargin, str]:
    """The delay margin at ``K``: proven when asked and possible, else checked."""
    A, B = loop.A(K), loop.B(K)
    if rigorous:
        try:
            return delay_margin(A, B, max_evals=max_evals, rigorous=True), "proven"
        except CertificationError as exc:
            return delay_margin(A, B, max_evals=max_evals), f"checked (the proof failed: {exc})"
    return delay_margin(A, B, max_evals=max_evals), "checked"


def _stability_edges(curves: _Curves) -> list[float]:
    """The gains inside the bounds where the nominal loop ``F(.; 0, K)`` may change stability, increasing:
    where a curve's delay wraps through 0 (a root on the axis at ``delta = 0``, solved to rounding by
    :meth:`_Curves._wraps`) and where ``s = 0`` is a root for every delay. An edge is where a supremum
    that is not attained sits (moved :data:`_OFFSET` off it)."""
    cuts = [float(p.K[-1]) for p in curves.pieces if p.stop == "wrap"]
    K0 = curves.loop.zero_root()  # s = 0 is a root there, for every delay
    if K0 is not None:
        cuts.append(K0)
    return sorted(c for c in cuts if curves.K_lo < c < curves.K_hi)


def _nominal_mask(curves: _Curves) -> NDArray[np.bool_]:
    """Nominal stability of ``F(.; 0, K)`` on the envelope grid: it changes only at the
    :func:`_stability_edges`; decided once between two of them."""
    loop = curves.loop
    bounds = [curves.K_lo, *curves.edges, curves.K_hi]
    mask = np.zeros(curves.gains.size, dtype=bool)
    for lo, hi in itertools.pairwise(bounds):
        inside = (curves.gains > lo) & (curves.gains < hi) if hi > lo else np.zeros_like(mask)
        if inside.any() and loop.nominally_stable(0.5 * (lo + hi)):
            mask |= inside
    mask[0] = mask[0] or (curves.gains.size > 1 and mask[1] and loop.nominally_stable(curves.K_lo))
    mask[-1] = mask[-1] or (curves.gains.size > 1 and mask[-2] and loop.nominally_stable(curves.K_hi))
    return mask


#: Parameters (evenly spread, ends included) at which the nominal verdict is certified when the scan found no
#: parameter stable without delay (:func:`_missed_edges`).
_UNSTABLE_CHECKS = 17
#: Bisections of the nominal verdict that narrow a missed edge's bracket before Newton (2^-12 of the checks' step).
_EDGE_BISECTIONS = 12


def _missed_edges(curves: _Curves) -> list[tuple[float, float]]:
    """Stability edges ``(w, p)`` the scan missed, each proven by certified verdicts and solved; empty when none
    is seen.

    Called before the claim that ``F(.; 0, p)`` is unstable for every ``p`` of the bounds (a
    :func:`_nominal_mask` with no stable interval). The nominal verdict
    (:meth:`_Family.nominally_stable`, a certified count of the zeros in ``Re s >= 0``) at
    :data:`_UNSTABLE_CHECKS` parameters: between two of different verdicts a zero crosses the axis
    (the zeros move continuously with ``p``, the difference operator being strongly stable on the
    bounds); the bracket is narrowed by :data:`_EDGE_BISECTIONS` verdicts and the crossing solved
    (:func:`_solved_edge`).

    Raises
    ------
    CertificationError
        A crossing that Newton does not find in its bracket, or verdicts all stable (no bracket).
    """
    loop = curves.loop
    ps = np.linspace(curves.K_lo, curves.K_hi, _UNSTABLE_CHECKS)
    verdicts = [loop.nominally_stable(float(p)) for p in ps]
    edges = []
    for (a, stable_a), (b, stable_b) in itertools.pairwise(zip(ps.tolist(), verdicts)):
        if stable_a == stable_b:
            continue
        for _ in range(_EDGE_BISECTIONS):
            mid = 0.5 * (a + b)
            if loop.nominally_stable(mid) == stable_a:
                a = mid
            else:
                b = mid
        edges.append(_solved_edge(loop, b if stable_a else a, a, b))
    if any(verdicts) and not edges:
        stable = float(ps[verdicts.index(True)])
        raise CertificationError(
            f"best_margin: the loop without delay is stable at p = {stable:.12g} and at every parameter checked, but "
            "the scan found it unstable between its stability edges; narrower bounds may give a design"
        )
    return edges


def _solved_edge(loop: _Family, unstable: float, lo: float, hi: float) -> tuple[float, float]:
    """``(w, p)``, ``p`` in ``[lo, hi]``, where the zero ``i w`` of ``F(.; 0, p)`` is on the imaginary axis.

    Newton in ``(w, p)`` on the two real equations ``F(i w; 0, p) = 0`` (``F`` affine in ``p``,
    its ``w``-derivative from the factors' slopes), started from the rightmost zero at the unstable
    end ``unstable`` of the bracket (its spectral abscissa: in ``Re s >= 0``, near the axis).
    """
    root = loop.abscissa(unstable).root
    x = np.array([abs(root.imag) if root is not None else 0.0, unstable])
    for _ in range(_NEWTON_STEPS if root is not None else 0):
        at = loop.axis(np.array([x[0]]), slopes=True)
        F = complex(at.a0[0] + at.b0[0] + x[1] * (at.a1[0] + at.b1[0]))
        F_w = complex(at.da0[0] + at.db0[0] + x[1] * (at.da1[0] + at.db1[0]))
        F_p = complex(at.a1[0] + at.b1[0])
        J = np.array([[F_w.real, F_p.real], [F_w.imag, F_p.imag]])
        try:
            step = np.linalg.solve(J, np.array([F.real, F.imag]))
        except np.linalg.LinAlgError:
            break
        x = x - step
        if np.all(np.abs(step) <= 4.0 * _EPS * np.maximum(np.abs(x), 1.0)):
            if lo <= x[1] <= hi:
                return float(x[0]), float(x[1])
            break
    raise CertificationError(
        f"best_margin: the loop without delay changes stability between p = {lo:.15g} and {hi:.15g} (certified "
        "counts of its zeros in Re s >= 0), but the scan found no crossing there and Newton on F(i w; 0, p) = 0 did "
        "not find one in that interval; narrower bounds around it may give a design"
    )


def _candidates(env: NDArray) -> list[int]:
    """Grid indices of the local maxima of the sampled envelope near its top."""
    top = float(np.max(env))
    n = env.size
    out = []
    for i in range(n):
        left = env[i - 1] if i > 0 else -np.inf
        right = env[i + 1] if i < n - 1 else -np.inf
        if env[i] >= left and env[i] >= right and env[i] >= (1.0 - _NEAR_TOP) * top:
            out.append(i)
    return out


def _solve_candidate(curves: _Curves, i: int, env: NDArray) -> tuple[float, float, str, tuple, tuple]:
    """The exact optimum near the grid index ``i``: ``(K_design, value, kind, K_bracket, value_bracket)``;
    ``env`` the sampled envelope with 0 where the nominal loop is unstable (:func:`_nominal_mask`)."""
    gains, active = curves.gains, curves.active
    n = gains.size
    scale = max(abs(curves.K_lo), abs(curves.K_hi))
    for j in (i - 1, i + 1):
        if not 0 <= j < n or active[j] == active[i] or active[j] < 0 or active[i] < 0 or env[j] == 0.0:
            continue  # (env 0: the nominal loop is unstable there, no kink with its curves)
        p, q = curves.pieces[active[i]], curves.pieces[active[j]]
        lo, hi = sorted((gains[i], gains[j]))
        birth = _birth_in(curves, q, lo, hi) if "birth" in (q.start, q.stop) else None
        if birth is not None and 0.0 < (birth[0] - gains[i]) * (gains[i] - gains[j]):
            birth = None  # born beyond gains[i]: q reaches gains[i] too, above p there, and crosses it (a kink)
        if birth is not None:
            Kb, _ = birth
            side = 1.0 if gains[i] > Kb else -1.0
            K = Kb + side * _OFFSET * max(scale, 1e-300)
            v = curves.value(K)
            # the supremum lies between v and the envelope at Kb from the good side
            w_p = p.at(Kb)
            sup = curves.at_gain(Kb, w_p[0], w_p[1] * w_p[0])[1] if w_p is not None else v
            return K, v, "pair birth", tuple(sorted((Kb, K))), (min(v, sup), max(v, sup))
        if p.start == "junction" or p.stop == "junction" or q.start == "junction" or q.stop == "junction":
            if p.sigma != q.sigma and abs(p.w[-1] - q.w[-1]) + abs(p.w[0] - q.w[0]) < 4 * curves.cell(
                float(max(p.w[0], q.w[0]))
            ):
                continue  # the same curve through a junction: smooth
        try:
            K, d, _, _ = curves.kink([0.5 * (lo + hi), float(gains[i]), float(gains[j])], p, q)
        except CertificationError:  # near a birth w(K) turns: d_1(K) - d_2(K) = 0 bracketed in K instead
            K, d = _bracketed_kink(curves, p, q, float(lo), float(hi))
        h = 1e-12 * max(scale, 1e-300)
        if any(r.at(Kx) is None for r in (p, q) for Kx in (K - h, K + h)):
            raise _narrow(
                f"the kink of two crossing curves near [{lo:.15g}, {hi:.15g}] is at K = {K:.15g}, "
                "beyond the gains where the scan has both"
            )
        vals = [min(curves.at_gain(Kx, *_start(r, Kx))[1] for r in (p, q)) for Kx in (K - h, K + h)]
        return K, d, "kink", (K - h, K + h), (min(*vals, d), d)
    if i in (0, n - 1):
        K = float(gains[i])
        v = curves.value(K)
        return K, v, "end", (K, K), (v, v)
    return _smooth_max(curves, i, env)


def _bracketed_kink(curves: _Curves, p: _Piece, q: _Piece, lo: float, hi: float) -> tuple[float, float]:
    """The kink of ``p`` and ``q`` in ``[lo, hi]`` by ``brentq`` on ``d_p(K) - d_q(K)``: ``(K, d)``.

    Each delay is solved at fixed ``K`` by Newton in ``w`` (:meth:`_Curves.at_gain`); the two
    grid gains where the lower interpolated curve changes, widened until the exact delays change
    order, bracket it.
    """
    from scipy.optimize import brentq  # loaded on first use (the start-up of the commands)

    def gap(K: float) -> float:
        return curves.at_gain(K, *_start(p, K))[1] - curves.at_gain(K, *_start(q, K))[1]

    cell = float(curves.gains[1] - curves.gains[0])
    for cells in (0, 2, 8, 32):  # the interpolated curves may cross a few cells away from the exact ones
        a, b = lo - cells * cell, hi + cells * cell
        if any(r.at(x) is None for r in (p, q) for x in (a, b)):
            break
        if gap(a) * gap(b) <= 0:
            K = brentq(gap, a, b, xtol=1e-15 * max(abs(a), abs(b), 1e-300), rtol=1e-15)
            return K, curves.at_gain(K, *_start(p, K))[1]
    raise _narrow(f"the two crossing curves do not change order near [{lo:.15g}, {hi:.15g}]")


def _outward(bracket: tuple[float, float], accuracy: float | None) -> tuple[float, float]:
    """``bracket`` of an optimal value widened by ``accuracy``, the error of the values it was formed from (the
    equations' solutions and the certified margin or abscissa agree to it), ends rounded outward: the supremum lies
    in it (a kink's value, ``0.23229251319039868`` as computed, is 2.2 ulp below the PDE's). As formed where the
    accuracy is not known."""
    lo, hi = float(bracket[0]), float(bracket[1])
    if accuracy is None or not (np.isfinite(lo) and np.isfinite(hi) and np.isfinite(accuracy)):
        return lo, hi
    return math.nextafter(lo - accuracy, -math.inf), math.nextafter(hi + accuracy, math.inf)


def _narrow(what: str) -> CertificationError:
    """The refusal where the scan's interpolated curves are off (features narrower than its step)."""
    return CertificationError(
        f"best_margin: {what}: the scan's interpolated curves are off there (features narrower than its step, as "
        "near the strong-stability bound, where crossing pairs near w = k pi / tau are born within tiny gain "
        "intervals); narrower bounds away from that limit would help"
    )


def _start(piece: _Piece, K: float) -> tuple[float, float]:
    s = piece.at(K)
    assert s is not None
    return s[0], s[1] * s[0]


def _zero_in(f: Callable[[float], float], a: float, b: float, fa: float, fb: float, xtol: float) -> float:
    """A zero of the scalar ``f`` in ``[a, b]`` (``f(a) f(b) <= 0``, values given) to ``xtol + 1e-15 |x|``.

    The Illinois iteration of :func:`~nrobust._bracket.illinois` on the one bracket: no import of
    ``scipy.optimize`` (0.3 s of CPU in a fresh process, more than the rest of a design's equation solving).
    """
    zero = illinois(lambda x: np.array([f(float(x[0]))]), [a], [b], [fa], [fb], rtol=1e-15, xtol=xtol)
    return float(zero[0])


def _birth_in(curves: _Curves, piece: _Piece, lo: float, hi: float) -> tuple[float, float] | None:
    """The birth that starts or ends ``piece`` with its gain in ``[lo, hi]`` (widened by a few cells): ``(K, w)``."""
    width = 4.0 * (curves.gains[1] - curves.gains[0])
    for at_start in (True, False):
        if (piece.start if at_start else piece.stop) != "birth":
            continue
        we = piece.w[0] if at_start else piece.w[-1]
        if not lo - width <= (piece.K[0] if at_start else piece.K[-1]) <= hi + width:
            continue  # the estimated birth (the interpolated turning point) is elsewhere
        a, b = we - curves.cell(we), we + curves.cell(we)
        slope = lambda x: curves.on_branch(x, piece.sigma)[2]  # noqa: E731
        fa, fb = slope(a), slope(b)
        if fa * fb > 0:
            continue
        wb = _zero_in(slope, a, b, fa, fb, 1e-15 * we)
        Kb = curves.on_branch(wb, piece.sigma)[0]
        if lo - width <= Kb <= hi + width:
            return Kb, wb
    return None


def _smooth_max(curves: _Curves, i: int, env: NDArray) -> tuple[float, float, str, tuple, tuple]:
    """An interior maximum of one curve, or an end of the nominal loop's stability, about the grid gain ``i``.

    The scanned curve is linear between its samples, so its largest value sits at a sample and the
    exact maximum may lie up to a sample's spacing in ``w`` away (many cells of gains where ``K``
    moves fast with ``w``): ``d(d)/dw = 0`` is bracketed between the piece's samples about ``i``,
    widened, and solved by ``brentq`` (kept when the curve is the lowest there, at least its sampled value at
    ``i``, so a maximum and not a minimum, and the nominal loop stable). Otherwise (across a junction, or a
    curve still rising where the nominal stability ends)
    Brent's bounded search runs on the exact envelope over the stable gains about ``i``, its window
    moved while the maximum sits at one of its ends: beyond the stable gains ``curves.value`` knows
    no crossing (``inf``) although every margin is 0. A maximum at a stability edge
    (:func:`_stability_edges`: ``s = 0`` becomes a root, or a root crosses the axis without delay,
    and the margin drops to 0) is not attained: that gain moved by :data:`_OFFSET` to the stable
    side, kind ``"end"``.
    """
    from scipy.optimize import (
        brentq,
        minimize_scalar,
    )  # scipy.optimize loads on first use (the start-up of the commands)

    piece = curves.pieces[curves.active[i]]
    K0 = float(curves.gains[i])
    gains, n = curves.gains, curves.gains.size
    dg = float(gains[1] - gains[0])

    def slope(x: float) -> float:
        with np.errstate(all="ignore"):  # NaN at a junction's end sample: not a bracket
            return curves.on_branch(x, piece.sigma)[3]

    k, last = int(np.argmin(np.abs(piece.K - K0))), piece.w.size - 1
    for reach in (1, 2, 4, 8, 32):  # samples on each side of the one nearest K0
        a, b = sorted((float(piece.w[max(k - reach, 0)]), float(piece.w[min(k + reach, last)])))
        fa, fb = slope(a), slope(b)
        if a < b and fa * fb < 0:  # (False for NaN)
            w = brentq(slope, a, b, xtol=1e-15 * b, rtol=1e-15)
            K, d, dK, _ = curves.on_branch(w, piece.sigma)
            lowest = curves.K_lo <= K <= curves.K_hi and abs(curves.value(K) - d) <= 1e-12 * d
            # a maximum, not a minimum of the curve: at least the sampled envelope at i (whose samples are the
            # curve's values; a minimum farther along the branch is lower)
            if lowest and d >= env[i] * (1.0 - 1e-9) and curves.loop.nominally_stable(K):
                half = abs(dK) * 4e-15 * w  # the bracket of w mapped to K; the value is flat there
                return K, d, "interior smooth max", (K - half, K + half), (d, d)
            break
    # Brent's bounded search on the exact envelope, where the nominal loop is stable
    run_lo, run_hi = i, i
    while run_lo > 0 and 0.0 < env[run_lo - 1] < np.inf:
        run_lo -= 1
    while run_hi < n - 1 and 0.0 < env[run_hi + 1] < np.inf:
        run_hi += 1
    j_lo, j_hi = max(i - 8, run_lo), min(i + 8, run_hi)
    K, v = K0, curves.value(K0)
    for _ in range(n // 16 + 1):
        if j_lo == j_hi:
            break
        res = minimize_scalar(
            lambda K: -curves.value(K), bounds=(gains[j_lo], gains[j_hi]), method="bounded", options={"xatol": 1e-12}
        )
        K, v = float(res.x), float(-res.fun)
        if K - gains[j_lo] <= 1e-3 * dg and j_lo > run_lo:  # still rising at the window's end: move it
            j_lo, j_hi = max(j_lo - 16, run_lo), j_lo + 1
        elif gains[j_hi] - K <= 1e-3 * dg and j_hi < run_hi:
            j_lo, j_hi = j_hi - 1, min(j_hi + 16, run_hi)
        else:
            break
    if run_lo < run_hi and not np.isfinite(v):
        raise CertificationError(f"best_margin: the envelope near K = {K0:.12g} is not finite at K = {K:.12g}")
    for j, side in ((run_lo, -1), (run_hi, 1)):  # the nominal loop loses stability at an edge past the run
        beyond = j + side
        if not (0 <= beyond < n and env[beyond] == 0.0):
            continue
        for K_edge in curves.edges:
            if min(gains[j], gains[beyond]) < K_edge < max(gains[j], gains[beyond]):
                edge = K_edge - side * _OFFSET * max(_scale(curves), 1e-300)
                v_edge = curves.value(edge)
                if v_edge >= v:
                    return edge, v_edge, "end", tuple(sorted((edge, K_edge))), (v_edge, v_edge)
    if j_lo == j_hi:
        return K, v, "interior smooth max", (K, K), (v, v)
    # Brent's search locates a smooth maximum to about sqrt(eps): the value may be higher by f''/2 width^2
    width = float(np.sqrt(2.2e-16) * max(abs(K), 1.0)) + 1e-12
    h = 1e-4 * max(_scale(curves), 1e-300)
    second = abs(curves.value(K + h) - 2.0 * v + curves.value(K - h)) / h**2
    return K, v, "interior smooth max", (K - width, K + width), (v, v + second * width**2)


def _scale(curves: _Curves) -> float:
    """The scale of the gains: the largest ``|K|`` of the bounds."""
    return max(abs(curves.K_lo), abs(curves.K_hi))


# ============================================================================ delay windows
def window_requirement(delays: tuple[float, float] | None, windows: Sequence[DelayWindow]) -> str:
    """A window requirement ``delays`` and its verdict from ``windows`` (the loop's, then its scenarios') in words.

    ``"none"`` without a requirement; else met and proven, met and checked, or not met.
    """
    if delays is None:
        return "none"
    d_lo, d_hi = delays
    met = all(w.stable for w in windows)
    proven = met and all(w.certified == "proven" for w in windows)
    loops = "the loop" if len(windows) == 1 else f"the loop and its {len(windows) - 1} scenarios"
    verdict = "met, proven" if proven else "met, checked" if met else "not met"
    return f"stable for every delay in [{float(d_lo)!r}, {float(d_hi)!r}] ({loops}): {verdict}"


def check_delays(delays: Any, name: str = "delays") -> tuple[float, float]:
    """``(d_min, d_max)``: finite, ``0 <= d_min <= d_max`` and ``d_max > 0``; a :class:`ParameterError`
    naming ``name`` otherwise."""
    what = "a pair [d_min, d_max] of finite delays with 0 <= d_min <= d_max and d_max > 0"
    try:
        d_lo, d_hi = (float(finite_real(name, d)) for d in delays)
    except (TypeError, ValueError):
        raise ParameterError(name, what, delays) from None
    if not 0.0 <= d_lo <= d_hi or d_hi <= 0.0:
        raise ParameterError(name, what, delays)
    return d_lo, d_hi


@dataclass(frozen=True)
class DelayWindow:
    """Whether ``F(s; delta) = A(s) + B(s) e^{-delta s}`` is exponentially stable for every delay in a window.

    The number of zeros in ``Re s > 0`` changes only at the crossing delays
    ``tau_k(w) = (theta(w) + 2 pi k) / w`` (:mod:`nrobust.margins.margin`), and with a strongly
    stable difference operator no zero comes from infinity: a zero count at one delay of
    ``[d_min, d_max]`` and no crossing delay in it give exponential stability on the whole
    window (for ``d_min = 0`` this is ``delta* > d_max``).

    Attributes
    ----------
    delays : (float, float)
        The window ``[d_min, d_max]``.
    stable : bool
        Exponentially stable for every delay of the window (closed), as certified by
        :attr:`certified`.
    certified : str
        ``"proven"``: the count and the crossing directions proven in ball arithmetic
        (:func:`nrobust.margins.delay_margin` with ``rigorous=True``) and every crossing delay's
        enclosure (from :func:`nrobust.margins.proven_crossings`: ``[t_lo + 2 pi k / w_hi,
        t_hi + 2 pi k / w_lo]``) outside the window; ``"checked"``: the same in floating point
        (with the reason when a proof was asked and failed); ``"refuted"`` when not stable.
    probe : float
        The middle of the window, where the zeros in ``Re s > 0`` were also counted directly.
    count : int or None
        That count (the argument principle, :func:`nrobust.margins.unstable_count`); None when
        not made (no strong stability, ``s = 0`` a root for every delay).
    enclosing : (float, float) or None
        The stability window of :attr:`DelayMargin.intervals` that contains ``[d_min, d_max]``.
    clearance : float
        The distance from the window to the nearest crossing delay (``inf`` without one; 0 when
        a crossing delay lies inside); :attr:`clearance_accuracy` bounds its error.
    margin : DelayMargin
        The delay margin and the windows up to ``2 d_max + 1``.
    reason : str
        The verdict in words.
    """

    delays: tuple[float, float]
    stable: bool
    certified: str
    probe: float
    count: int | None
    enclosing: tuple[float, float] | None
    clearance: float
    margin: DelayMargin
    reason: str

    @property
    def clearance_accuracy(self) -> float | None:
        """A bound of the error of :attr:`clearance`: the largest accuracy
        (:meth:`DelayMargin.end_accuracy`) of the crossing delays that could be the nearest one
        (distance to the window within the clearance plus their accuracy; a clearance of 0 too: a
        crossing delay computed inside may lie outside by its accuracy); 0 for ``inf``; None when
        one of them is not estimated."""
        if not np.isfinite(self.clearance):
            return 0.0
        d_lo, d_hi = self.delays
        accuracies = []
        for d in (d for c in self.margin.crossings for d in c.delays):
            accuracy = self.margin.end_accuracy(d)
            if accuracy is None:
                return None
            if max(d_lo - d, d - d_hi, 0.0) <= self.clearance + accuracy:
                accuracies.append(accuracy)
        return max(accuracies, default=0.0)

    def __repr__(self) -> str:
        d_lo, d_hi = self.delays
        clearance = "inf" if np.isposinf(self.clearance) else with_accuracy(self.clearance, self.clearance_accuracy)
        return (
            f"DelayWindow(delays=[{d_lo!r}, {d_hi!r}], stable={self.stable}, certified={self.certified!r}, "
            f"count={self.count}, clearance={clearance})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (the delay margin as its dictionary)."""
        return fields_dict(self)


def _window_margin(
    A: QuasiPolynomial, B: QuasiPolynomial, horizon: float, rigorous: bool, max_evals: int
) -> tuple[DelayMargin, str]:
    """The delay margin with its windows up to ``horizon``: proven when asked and possible, else checked."""
    if rigorous:
        try:
            return delay_margin(A, B, delta_max=horizon, max_evals=max_evals, rigorous=True), "proven"
        except CertificationError as exc:
            return delay_margin(A, B, delta_max=horizon, max_evals=max_evals), f"checked (the proof failed: {exc})"
    return delay_margin(A, B, delta_max=horizon, max_evals=max_evals), "checked"


def _proven_clear(A: QuasiPolynomial, B: QuasiPolynomial, d_lo: float, d_hi: float) -> str:
    """Empty when every crossing delay's proven enclosure lies outside ``[d_lo, d_hi]``, else why not."""
    if not (A.is_real and B.is_real):
        return "the enclosures of the delays are taken for real loops only"
    proof = proven_crossings(A, B)
    pairs = [*zip(proof.omegas, proof.delays), *zip(proof.unresolved, proof.unresolved_delays)]
    for (w_lo, w_hi), (t_lo, t_hi) in pairs:
        if not w_lo > 0.0:
            return f"a crossing frequency enclosure [{w_lo:.6g}, {w_hi:.6g}] reaches 0"
        for k in range(int(np.ceil(max(d_hi - t_lo, 0.0) * w_hi / _TWO_PI)) + 1):
            lo = (t_lo + _TWO_PI * k / w_hi) * (1.0 - 4.0 * np.finfo(float).eps)
            hi = (t_hi + _TWO_PI * k / w_lo) * (1.0 + 4.0 * np.finfo(float).eps)
            if hi >= d_lo and lo <= d_hi:
                return f"the enclosure [{lo:.17g}, {hi:.17g}] of a crossing delay meets the window"
    return ""


def _zero_frequency_error(A: QuasiPolynomial, B: QuasiPolynomial) -> ParameterError | None:
    """The error for ``|A(0)| = |B(0)|`` (to ``64`` units of rounding), else None.

    ``g(w) = |A(i w)|^2 - |B(i w)|^2`` is even for a real loop: ``g(0) = 0`` makes ``w = 0`` a double zero at
    least, which a crossing search in floating point cannot tell from a pair of zeros near it. With
    ``A(0) + B(0) = 0``, ``s = 0`` is a root for every delay (no window is stable); otherwise ``s = 0`` is a root
    for no delay (``arg(-B/A) = pi`` there: the crossing delay ``pi / w`` is infinite) and the crossings away
    from ``w = 0`` decide.
    """
    s0 = np.zeros(1, dtype=complex)
    a, b = complex(A(s0)[0]), complex(B(s0)[0])
    if abs(abs(a) - abs(b)) > 64.0 * np.finfo(float).eps * max(abs(a), abs(b)):
        return None
    if abs(a + b) <= 64.0 * np.finfo(float).eps * max(abs(a), abs(b)):
        what = "A(0) + B(0) = 0 here to rounding, not proven: s = 0 would be a root for every delay"
    else:
        what = "A(0) = B(0) here: s = 0 is a root for no delay, but the search cannot tell the double zero at w = 0"
    return ParameterError(
        "A, B",
        "loop factors with |A(0)| != |B(0)|: |A(i w)|^2 - |B(i w)|^2 vanishes at w = 0, which the crossing search "
        f"of the delay margin cannot decide in floating point ({what}); a slight change of the loop decides",
        (a, b),
    )


def _delay_uncertainty(dm: DelayMargin, d_hi: float) -> float:
    """How far the crossing delays up to ``d_hi`` may be from their computed values: the margin's accuracy
    (its proven ball, or its estimate) taken relative to the margin, at ``d_hi``; 0 when not known."""
    acc = dm.accuracy
    if acc is None or not np.isfinite(acc) or not (np.isfinite(dm.margin) and dm.margin > 0.0):
        return 0.0
    return float(acc) * max(1.0, d_hi / dm.margin)


def window_stability(
    A: QuasiPolynomial,
    B: QuasiPolynomial,
    delays: tuple[float, float],
    *,
    rigorous: bool = False,
    max_evals: int = 2_000_000,
) -> DelayWindow:
    """Certified exponential stability of ``A + B e^{-delta s}`` for every delay in ``[d_min, d_max]``.

    The delay margin with its windows (:func:`nrobust.margins.delay_margin`, ``delta_max =
    2 d_max + 1``) gives the count between crossing delays from a certified count and the
    crossing directions; the loop is stable on the window when one of its stability windows
    contains ``[d_min, d_max]`` (for ``d_min = 0``: the nominal loop stable and ``delta* >
    d_max``). The count at the middle of the window is made again, independently, by the
    argument principle; a disagreement raises. With ``rigorous=True`` the margin is proven in
    ball arithmetic and every crossing delay's enclosure must miss the window.

    Parameters
    ----------
    A, B : QuasiPolynomial
        The loop factors.
    delays : (float, float)
        ``[d_min, d_max]``, ``0 <= d_min <= d_max``, ``d_max > 0``.
    rigorous : bool, optional
        Prove the verdict in ball arithmetic (``certified == "proven"``), else check it in
        floating point; a failed proof leaves ``"checked"`` with the reason.
    max_evals : int, optional
        Work bound of the delay margin and of the count.

    Returns
    -------
    DelayWindow

    Raises
    ------
    ParameterError
        ``delays`` not such a pair; ``|A(0)| = |B(0)|`` (to rounding) where the crossing search of the
        delay margin cannot decide ``|A(i w)| = |B(i w)|`` about ``w = 0`` (:func:`_zero_frequency_error`),
        unless ``A(0) + B(0) = 0`` is proven in ball arithmetic: ``s = 0`` a root for every delay, the
        window refuted.
    CertificationError
        The count at the middle of the window contradicts the windows of the delay margin, or
        a work bound was hit.

    Examples
    --------
    >>> A = QuasiPolynomial([[1.0, -0.1, 1.0]], [0.0])    # s^2 - 0.1 s + 1: unstable alone
    >>> B = QuasiPolynomial([[0.5]], [0.0])                # + 0.5 e^{-delta s}
    >>> window_stability(A, B, (4.7, 4.9)).stable
    True
    """
    d_lo, d_hi = check_delays(delays)
    max_evals = positive_int("max_evals", max_evals)
    try:
        dm, how = _window_margin(A, B, 2.0 * d_hi + 1.0, rigorous, max_evals)
    except CertificationError as exc:
        zero = _zero_frequency_error(A, B)
        if zero is None:
            raise
        # A(0) + B(0) = 0: the proof of the root s = 0 for every delay decides (the window refuted)
        try:
            dm, how = delay_margin(A, B, delta_max=2.0 * d_hi + 1.0, max_evals=max_evals, rigorous=True), "proven"
        except (CertificationError, ImportError):
            raise zero from exc
        if not dm.zero_root:
            raise zero from exc
    probe = 0.5 * (d_lo + d_hi)
    if not dm.strongly_stable or dm.zero_root:
        why = "s = 0 is a root for every delay" if dm.zero_root else "the difference operator is not strongly stable"
        return DelayWindow((d_lo, d_hi), False, "refuted", probe, None, None, 0.0, dm, why)
    marks = [d for c in dm.crossings for d in c.delays]
    clearance = min((max(d_lo - d, d - d_hi, 0.0) for d in marks), default=float("inf"))
    enclosing = next(
        (
            (lo, hi)
            for lo, hi in dm.intervals
            if (lo < d_lo or (lo == 0.0 == d_lo and dm.nominally_stable)) and d_hi < hi
        ),
        None,
    )
    # a crossing delay at an end of the window to rounding (or within its proven enclosure's width): the
    # verdict at that end is not decided by these numbers either way
    tol = 8.0 * np.finfo(float).eps * max(1.0, d_hi) + _delay_uncertainty(dm, d_hi)
    at_end = [d for d in marks if d_lo - tol <= d <= d_hi + tol and min(abs(d - d_lo), abs(d - d_hi)) <= tol]
    inside = [d for d in marks if d_lo + tol < d < d_hi - tol]
    if enclosing is None and at_end and not inside:
        raise CertificationError(
            f"window_stability: a crossing delay {at_end[0]!r} lies at an end of the window [{d_lo!r}, {d_hi!r}] "
            f"to within {tol:.2g} (a zero on the imaginary axis there): the verdict at that end is not decided; a "
            "window ending clear of the crossing delays decides"
        )
    W = dm.frequency_bound
    count = unstable_count(A + B.shift(probe), W, loop=(A, B, probe), max_evals=max_evals).count
    if count is None:
        raise CertificationError(
            f"window_stability: the zeros in Re s > 0 at delta = {probe!r}, the middle of the window, could not be "
            "counted (a zero on or near the imaginary axis there); a window whose middle is clear of the crossing "
            "delays decides"
        )
    if enclosing is not None and count != 0:
        raise CertificationError(
            f"window_stability: the windows of the delay margin make [{d_lo:.12g}, {d_hi:.12g}] stable, but the "
            f"count at delta = {probe:.12g} is {count}"
        )
    if enclosing is None:
        why = (
            f"a crossing delay lies in the window (clearance {clearance:.3g})"
            if clearance == 0.0
            else f"{count} zeros in Re s > 0 at delta = {probe!r}"
        )
        return DelayWindow((d_lo, d_hi), False, "refuted", probe, count, None, clearance, dm, why)
    lo, hi = enclosing
    horizon = 2.0 * d_hi + 1.0  # the delays searched (_window_margin)
    start = "delta = 0" if lo == 0.0 else "a crossing delay"
    end = "a crossing delay" if hi < horizon else "the end of the delays searched"
    window_text = inner_interval_text(lo, hi, accuracies=(dm.end_accuracy(lo), dm.end_accuracy(hi)))
    reason = f"stable on the window {window_text} (from {start} to {end})"
    if how == "proven":
        unproven = _proven_clear(A, B, d_lo, d_hi)
        how = f"checked (the proof failed: {unproven})" if unproven else "proven"
    return DelayWindow((d_lo, d_hi), True, how, probe, count, enclosing, clearance, dm, reason)


def _window_mask(curves: _Curves, d_lo: float, d_hi: float) -> NDArray[np.bool_]:
    """Grid parameters at which no crossing delay ``d + 2 pi k / w`` of a sampled curve lies in ``[d_lo, d_hi]``.

    Interpolated on each curve; a cell whose two interpolated delays straddle any part of the
    window marks both its gains (a branch crossing the window between them), and the cell of
    the parameter with ``s = 0`` a root for every delay is marked too. The certificate at the
    design catches a curve narrower than a cell.
    """
    gains = curves.gains
    hit = np.zeros(gains.size, dtype=bool)
    for piece in curves.pieces:
        if piece.K.size < 2:
            continue
        order = np.argsort(piece.K)
        Ks, ws, ds = piece.K[order], piece.w[order], piece.d[order]
        inside_gains = np.flatnonzero((gains >= Ks[0]) & (gains <= Ks[-1]))
        if not inside_gains.size:
            continue
        at = gains[inside_gains]
        for k in range(int(np.ceil(max(d_hi - float(ds.min()), 0.0) * float(ws.max()) / _TWO_PI)) + 1):
            dk = ds + _TWO_PI * k / ws
            if dk.min() > d_hi or dk.max() < d_lo:
                continue
            val = np.interp(at, Ks, dk)
            inside = (val >= d_lo) & (val <= d_hi)
            if val.size > 1:  # a branch through the window between two gains
                a, b = np.minimum(val[:-1], val[1:]), np.maximum(val[:-1], val[1:])
                cross = (a <= d_hi) & (b >= d_lo)
                inside[:-1] |= cross
                inside[1:] |= cross
            # a sample inside the window between two gains (a curve dipping in between them)
            dipped = Ks[(dk >= d_lo) & (dk <= d_hi) & (Ks >= at[0]) & (Ks <= at[-1])]
            cells = np.searchsorted(at, dipped)
            inside[np.clip(cells, 0, at.size - 1)] = True
            inside[np.clip(cells - 1, 0, at.size - 1)] = True
            hit[inside_gains] |= inside
    K0 = curves.loop.zero_root()
    if K0 is not None and curves.K_lo <= K0 <= curves.K_hi:
        j = int(np.searchsorted(gains, K0))
        hit[max(j - 1, 0) : j + 1] = True
    return ~hit


def _exact_birth(curves: _Curves, piece: _Piece, at_start: bool) -> tuple[float, float] | None:
    """The pair birth that starts (or ends) ``piece``: ``dK/dw = 0`` by ``brentq`` in ``w`` about its sampled
    end, the bracket widened until the slope changes sign (the sampled estimate of a gain loop's birth
    can be cells away from the exact one); ``(K, w)`` or None."""
    from scipy.optimize import brentq  # scipy.optimize loads on first use (the start-up of the commands)

    we = float(piece.w[0] if at_start else piece.w[-1])

    def slope(x: float) -> float:
        return curves.on_branch(x, piece.sigma)[2]

    for cells in (1, 2, 4, 8):
        step = curves.cell(we)
        a, b = max(we - cells * step, 0.5 * min(we, curves.dw)), we + cells * step
        if slope(a) * slope(b) < 0:
            wb = brentq(slope, a, b, xtol=1e-15 * b, rtol=1e-15)
            return curves.on_branch(wb, piece.sigma)[0], wb
    return None


_Birth = tuple[float, _Piece, bool, range]


def _window_events(curves: _Curves, i: int, j: int, d_lo: float, d_hi: float) -> tuple[list[GainEnd], list[_Birth]]:
    """The events within 64 cells of the grid parameters ``i`` (feasible on the scan) and ``j`` (not):
    solved from their equations, a branch of crossing delays through ``d_lo > 0`` or ``d_hi``
    (``"crossing"``), ``s = 0`` a root for every delay or, with ``d_lo = 0``, a root on the axis at
    ``delta = 0`` (``"nominal"``); and the pair births, as ``(sampled K, piece, at_start, branches k)``,
    to be solved when needed (:func:`_solved_birth`: a pair born with a delay in the window)."""
    from scipy.optimize import brentq  # scipy.optimize loads on first use (the start-up of the commands)

    lo, hi = sorted((curves.gains[i], curves.gains[j]))
    width = 64.0 * (hi - lo)  # the sampled curves' events may be cells away from the exact ones
    events: list[GainEnd] = []
    births: list[_Birth] = []
    K0 = curves.loop.zero_root()
    if K0 is not None and lo - width <= K0 <= hi + width:
        events.append(GainEnd(float(K0), "nominal", 0.0, 0.0, None, 0.0, 0.0))
    for piece in curves.pieces:
        if piece.K.size < 2 or np.max(piece.K) < lo - width or np.min(piece.K) > hi + width:
            continue
        ks = range(int(np.ceil(max(d_hi - float(piece.d.min()), 0.0) * float(piece.w.max()) / _TWO_PI)) + 1)
        for at_start, how in ((True, piece.start), (False, piece.stop)):
            end_K = float(piece.K[0] if at_start else piece.K[-1])
            if not lo - width <= end_K <= hi + width:
                continue
            if how == "birth":
                births.append((end_K, piece, at_start, ks))
            elif how == "wrap" and d_lo == 0.0:  # a root on the axis at delta = 0: the nominal loop changes
                events.append(
                    GainEnd(end_K, "nominal", float(piece.w[0] if at_start else piece.w[-1]), 0.0, delay_accuracy=0.0)
                )
        for k in ks:
            for level in (d_lo, d_hi) if d_lo > 0.0 else (d_hi,):
                f_s = piece.d + _TWO_PI * k / piece.w - level
                for c in np.flatnonzero(np.sign(f_s[:-1]) * np.sign(f_s[1:]) < 0):
                    Ka, Kc = sorted((piece.K[c], piece.K[c + 1]))
                    if Kc < lo - width or Ka > hi + width:
                        continue

                    def f(x: float, sigma: float = piece.sigma, k: int = k, level: float = level) -> float:
                        return curves.on_branch(x, sigma)[1] + _TWO_PI * k / x - level

                    wa, wc = piece.w[c], piece.w[c + 1]
                    if f(wa) * f(wc) > 0:
                        continue
                    wx = brentq(f, wa, wc, xtol=1e-15 * wc, rtol=1e-15)
                    events.append(
                        GainEnd(curves.on_branch(wx, piece.sigma)[0], "crossing", float(wx), level, delay_accuracy=0.0)
                    )
    return events, births


def _solved_birth(curves: _Curves, birth: _Birth, d_lo: float, d_hi: float) -> GainEnd | None:
    """The exact pair birth of a piece (:func:`_exact_birth`), when a delay of the pair lies in the window."""
    _, piece, at_start, ks = birth
    found = _exact_birth(curves, piece, at_start)
    if found is None:
        return None
    Kb, wb = found
    db = curves.on_branch(wb, piece.sigma)[1]
    if any(d_lo <= db + _TWO_PI * k / wb <= d_hi for k in ks):
        return GainEnd(float(Kb), "pair_birth", float(wb), float(db))
    return None


class _Requirement:
    """The parameters of one loop stable on the window ``[d_lo, d_hi]``, on the envelope grid, and their ends.

    With ``d_lo = 0`` the requirement is ``delta* > d_hi`` (the nominal loop stable, the envelope
    above ``d_hi``); with ``d_lo > 0`` no crossing delay in the window (:func:`_window_mask`) and,
    checked per interval, no zero in ``Re s > 0`` inside it; :func:`_window_events` gives the ends.
    """

    def __init__(self, curves: _Curves, d_lo: float, d_hi: float) -> None:
        self.curves, self.d_lo, self.d_hi = curves, d_lo, d_hi
        if d_lo == 0.0:
            self.mask = np.where(_nominal_mask(curves), curves.envelope, 0.0) > d_hi
        else:
            self.mask = _window_mask(curves, d_lo, d_hi)

    def end(self, i: int, j: int, scale: float) -> GainEnd:
        """The end between the grid parameters ``i`` (feasible on the scan) and ``j`` (not): the event nearest
        ``i`` whose inner side (``1e-10`` relative inside) is feasible by a delay margin, the events
        further in tried in turn (the interpolated scan can misplace the end by cells near a birth)."""
        curves = self.curves
        events, births = _window_events(curves, i, j, self.d_lo, self.d_hi)
        side = 1.0 if j > i else -1.0
        x0 = float(curves.gains[i])
        cell = float(curves.gains[1] - curves.gains[0])
        births.sort(key=lambda b: abs(b[0] - x0))
        # the births solved lazily: those sampled nearer x0 than the nearest event found (8 cells of slack)
        while births and (not events or abs(births[0][0] - x0) <= min(abs(e.K - x0) for e in events) + 8 * cell):
            solved = _solved_birth(curves, births.pop(0), self.d_lo, self.d_hi)
            if solved is not None:
                events.append(solved)
        if not events:
            raise CertificationError(
                f"no equation found for the end of the parameters stable on [{self.d_lo:.6g}, {self.d_hi:.6g}] near "
                f"K = {x0:.12g}"
            )
        first = min(events, key=lambda e: abs(e.K - x0))
        # further in: every event, the births sampled inward of the first too
        for birth in births:
            if side * (birth[0] - first.K) < 8 * cell:
                solved = _solved_birth(curves, birth, self.d_lo, self.d_hi)
                if solved is not None:
                    events.append(solved)
        inward = sorted((e for e in events if side * (e.K - first.K) < 0.0), key=lambda e: -side * e.K)
        for event in [first, *inward]:
            if self.feasible_at(event.K - side * _OFFSET * max(scale, 1e-300)):
                return event
        raise CertificationError(
            f"no end of the parameters stable on [{self.d_lo:.6g}, {self.d_hi:.6g}] near {x0:.12g} has a feasible "
            "inner side: the scan misplaces the feasible set there (narrower bounds would help)"
        )

    def feasible_at(self, K: float) -> bool:
        """The loop at ``K`` meets the window, in floating point (the design is certified afterwards)."""
        loop = self.curves.loop
        A, B = loop.A(K), loop.B(K)
        if self.d_lo == 0.0:
            dm = delay_margin(A, B, verify=False)
            return bool(dm.nominally_stable and dm.margin > self.d_hi)
        return window_stability(A, B, (self.d_lo, self.d_hi)).stable

    def count(self, K: float) -> int | None:
        """Zeros in ``Re s > 0`` at the middle of the window for the parameter ``K`` (``d_lo > 0``)."""
        loop = self.curves.loop
        A, B = loop.A(K), loop.B(K)
        bound = frequency_bound(A, B)
        if bound is None:
            return None
        probe = 0.5 * (self.d_lo + self.d_hi)
        return unstable_count(A + B.shift(probe), float(bound[0]), loop=(A, B, probe)).count


_Interval = tuple[tuple[float, GainEnd | None], tuple[float, GainEnd | None], NDArray[np.intp]]


def _feasible_intervals(reqs: list[_Requirement], scale: float) -> list[_Interval]:
    """The parameter intervals where every loop meets the window: runs of the grid, each run's count checked
    at its middle (``d_lo > 0``), their ends solved from their equations, checked on their inner side and
    moved ``1e-10`` (relative) inside."""
    gains = reqs[0].curves.gains
    mask = np.logical_and.reduce([r.mask for r in reqs])
    idx = np.flatnonzero(mask)
    out: list[_Interval] = []
    if not idx.size:
        return out
    for run in np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1):
        middle = float(gains[run[run.size // 2]])
        if not all(r.d_lo == 0.0 or r.count(middle) == 0 for r in reqs):
            continue  # no crossing delay in the window, but zeros in Re s > 0 there
        ends: list[tuple[float, GainEnd | None]] = []
        for k, side in ((int(run[0]), -1), (int(run[-1]), 1)):
            j = k + side
            if j < 0 or j >= gains.size:
                ends.append((float(gains[k]), None))
                continue
            events = [r.end(k, j, scale) for r in reqs if not r.mask[j]]
            event = min(events, key=lambda e: side * e.K)  # the innermost of the loops' ends
            inner = event.K - side * _OFFSET * max(scale, 1e-300)
            # a loop feasible at j on the scan may still end before: its own end, when its inner side fails
            late = [r.end(k, j, scale) for r in reqs if r.mask[j] and not r.feasible_at(inner)]
            event = min([event, *late], key=lambda e: side * e.K)
            ends.append((event.K - side * _OFFSET * max(scale, 1e-300), event))
        (K_a, _), (K_b, _) = ends
        if K_a < K_b:
            out.append((ends[0], ends[1], run))
    return out


def _best_margin_in(
    curves: _Curves, env: NDArray, intervals: list[_Interval], max_evals: int
) -> tuple[float, float, str, tuple, tuple]:
    """The largest delay margin over the feasible intervals: the solved local maxima of the envelope inside
    them and their ends (``"window end"``); all zero: the middle of the widest interval (``"window"``)."""
    best: tuple[float, float, str, tuple, tuple] | None = None
    for (K_a, _), (K_b, _), run in intervals:
        cands: list[tuple[float, float, str, tuple, tuple]] = []
        sub = env[run]
        if sub.size >= 3 and np.max(sub) > 0.0:
            for local in _candidates(sub):
                i = int(run[local])
                if 0 < local < sub.size - 1 and env[i] > 0.0:
                    K, v, kind, K_br, v_br = _solve_candidate(curves, i, env)
                    if K_a <= K <= K_b:
                        cands.append((K, v, kind, K_br, v_br))
        for K in (K_a, K_b):  # the margin at an end, which may be a pair birth (no Newton on the double root)
            v = float(delay_margin(curves.loop.A(K), curves.loop.B(K), max_evals=max_evals).margin)
            cands.append((K, v, "window end", (K, K), (v, v)))
        top = max(cands, key=lambda c: c[1])
        if best is None or top[1] > best[1]:
            best = top
    assert best is not None
    if best[1] == 0.0:
        (K_a, _), (K_b, _), _ = max(intervals, key=lambda r: r[1][0] - r[0][0])
        K = 0.5 * (K_a + K_b)
        return K, 0.0, "window", (K_a, K_b), (0.0, 0.0)
    return best


def _window_infeasible(
    curves: _Curves, d_lo: float, d_hi: float, scenarios: int, max_evals: int
) -> ParameterError | CertificationError:
    """The error for a window that no parameter meets on the scan, naming the best achievable (a
    :class:`CertificationError` when the best margin does meet a window from 0: the scan missed it)."""
    lo, hi = curves.K_lo, curves.K_hi
    if scenarios:
        return ParameterError(
            "delays",
            f"a window that some parameter of [{lo:.6g}, {hi:.6g}] meets for the loop and its {scenarios} scenarios "
            "together (none does: a narrower window, or scenarios closer to the loop)",
            (d_lo, d_hi),
        )
    if d_lo == 0.0:
        top = best_margin(curves.loop.loop, (lo, hi), max_evals=max_evals)
        if top.value > d_hi:
            return CertificationError(
                f"the scan of [{lo:.6g}, {hi:.6g}] found no parameter with a delay margin > {d_hi:g}, though the "
                f"largest margin, {with_accuracy(top.value, top.accuracy[1])} at K = "
                f"{with_accuracy(top.K, top.accuracy[0])}, meets it: narrow the bounds about that K"
            )
        return ParameterError(
            "delays",
            f"d_max below {with_accuracy(top.value, top.accuracy[1])}, the largest delay margin of a parameter in "
            f"[{lo:.6g}, {hi:.6g}] (at K = {with_accuracy(top.K, top.accuracy[0])}, a {top.kind}) when d_min = 0",
            (d_lo, d_hi),
        )
    # the stability window from d_lo at each scanned parameter reaches the next crossing delay above it
    reach = np.full(curves.gains.size, np.inf)
    for piece in curves.pieces:
        if piece.K.size < 2:
            continue
        order = np.argsort(piece.K)
        Ks, ws, ds = piece.K[order], piece.w[order], piece.d[order]
        inside = (curves.gains >= Ks[0]) & (curves.gains <= Ks[-1])
        for k in range(int(np.ceil(max(2.0 * d_hi - float(ds.min()), 0.0) * float(ws.max()) / _TWO_PI)) + 1):
            val = np.interp(curves.gains[inside], Ks, ds + _TWO_PI * k / ws)
            reach[inside] = np.where(val > d_lo, np.minimum(reach[inside], val), reach[inside])
    req = _Requirement(curves, d_lo, d_lo + 1e-9 * max(d_lo, 1.0))
    sample = np.unique(np.linspace(0, curves.gains.size - 1, 33).astype(int))  # counts at d_min on 33 gains
    stable = [int(i) for i in sample if np.isfinite(reach[i]) and req.count(float(curves.gains[i])) == 0]
    if stable:
        i = max(stable, key=lambda k: reach[k])
        return ParameterError(
            "delays",
            f"d_max below about {reach[i]:.6g}, the end of the stability window from d_min = {d_lo:.6g} at "
            f"K = {curves.gains[i]:.6g} (the largest of 33 gains of [{lo:.6g}, {hi:.6g}] stable at d_min)",
            (d_lo, d_hi),
        )
    return ParameterError(
        "delays",
        f"a d_min at which some parameter of [{lo:.6g}, {hi:.6g}] is stable (on the scan none is stable at "
        f"delta = {d_lo:.6g})",
        (d_lo, d_hi),
    )


def _window_design(
    loop: AffineGainLoop | AffineLoop,
    lo: float,
    hi: float,
    objective: str,
    delays: Any,
    scenarios: Any,
    n_rates: int,
    max_evals: int,
    rigorous: bool,
) -> GainDesign:
    """:func:`best_margin` or :func:`best_decay_rate` under the window ``delays`` for the loop and ``scenarios``."""
    d_lo, d_hi = check_delays(delays)
    n_rates = positive_int("n_rates", n_rates, 2)
    max_evals = positive_int("max_evals", max_evals)
    try:
        others = tuple(scenarios)
    except TypeError:
        raise ParameterError("scenarios", "a tuple of AffineGainLoop or AffineLoop", scenarios) from None
    for other in others:
        _checked_loop(other, (lo, hi))
    curves = _Curves(_Family(loop), lo, hi, max_evals)
    all_curves = [curves, *(_Curves(_Family(other), lo, hi, max_evals) for other in others)]
    reqs = [_Requirement(c, d_lo, d_hi) for c in all_curves]
    env = np.where(_nominal_mask(curves), curves.envelope, 0.0)
    scan = (curves.gains, env)
    intervals = _feasible_intervals(reqs, _scale(curves))
    if not intervals:
        raise _window_infeasible(curves, d_lo, d_hi, len(others), max_evals)
    end: GainEnd | None = None
    scenario_abscissae: tuple[SpectralAbscissa, ...] = ()
    if objective == "least_rate":
        K, value, kind, end, sas, K_br = _least_rate_design(
            [c.loop for c in all_curves], [(a, b) for a, b, _ in intervals], n_rates, _scale(curves)
        )
        sa, scenario_abscissae = sas[0], tuple(sas[1:])
        v_br = (value, value)
        if end is not None:  # the supremum: the least rate at the end itself (not feasible at a pair birth)
            at_end = min(-c.loop.abscissa(end.K).value for c in all_curves)
            v_br = (min(value, at_end), max(value, at_end))
        objective = "decay_rate"
    elif objective == "decay_rate":
        best, plateau = _with_plateau(
            curves.loop,
            _best_rate(curves, [(a, b) for a, b, _ in intervals], n_rates, "window end"),
            [(a[0], b[0]) for a, b, _ in intervals],
            _scale(curves),
        )
        K, value, kind, end, sa = best
        K_br, v_br = (K, K), (value, value)
        if plateau is not None:
            K_br = plateau
        elif end is not None:
            K_br = (min(K, end.K), max(K, end.K))
            at_end = -curves.loop.abscissa(end.K).value
            v_br = (min(value, at_end), max(value, at_end))
        elif kind in ("interior smooth max", "kink"):
            K_br = (K - 1e-10 * max(_scale(curves), 1e-300), K + 1e-10 * max(_scale(curves), 1e-300))
    else:
        K, value, kind, K_br, v_br = _best_margin_in(curves, env, intervals, max_evals)
        if kind == "window end":
            end = min((e for a, b, _ in intervals for e in (a, b)), key=lambda e: abs(e[0] - K))[1]
            if end is not None:  # the end itself is not feasible: the design is 1e-10 (relative) inside
                K_br = (min(K, end.K), max(K, end.K))
        sa = curves.loop.abscissa(K)
    cert, how = _certify(curves.loop, K, rigorous, max_evals)
    if objective == "margin" and np.isfinite(value):
        tol = 1e-9 * max(value, 1e-300) + (cert.accuracy or 0.0)
        if abs(cert.margin - value) > tol:
            raise CertificationError(
                f"best_margin: the {kind} at K = {K:.15g} gives delta* = {value:.15g} by its equations, the certified "
                f"delay margin there is {cert.margin:.15g}: a crossing curve was missed by the scan"
            )
        value = cert.margin
    windows = tuple(
        window_stability(c.loop.A(K), c.loop.B(K), (d_lo, d_hi), rigorous=rigorous, max_evals=max_evals)
        for c in all_curves
    )
    for n, window in enumerate(windows):
        if not window.stable:
            which = "the loop" if n == 0 else f"scenario {n - 1}"
            raise CertificationError(
                f"the design K = {K:.15g} is not certified stable on [{d_lo:.6g}, {d_hi:.6g}] for {which}: "
                f"{window.reason} (a crossing curve narrower than the scan; narrower bounds about K would help)"
            )
    rate = -sa.value
    feasible = tuple((float(a[0]), float(b[0])) for a, b, _ in intervals)
    known = [a.accuracy for a in (sa, *scenario_abscissae) if a.accuracy is not None]
    rate_accuracy = max(known) if len(known) == 1 + len(scenario_abscissae) else None
    return GainDesign(
        K,
        objective,
        value,
        cert.margin,
        rate,
        kind,
        K_br,
        _outward(v_br, cert.accuracy if objective == "margin" else rate_accuracy),
        (lo, hi),
        cert,
        how,
        sa,
        *scan,
        end,
        (d_lo, d_hi),
        windows,
        feasible,
        curves.loop.nominal(K),
        scenario_abscissae,
    )


# Samples of each loop's decay rate in a feasible interval for the least rate, at least (its ties and peaks are
# found between them).
_LEAST_SAMPLES = 9


def _least_rate_design(
    loops: list[_Family],
    intervals: list[tuple[tuple[float, GainEnd | None], tuple[float, GainEnd | None]]],
    n_rates: int,
    scale: float,
) -> tuple[float, float, str, GainEnd | None, list[SpectralAbscissa], tuple[float, float]]:
    """The gain of the intervals with the largest least decay rate ``min_j r_j(K)`` of ``loops`` at ``delta = 0``.

    Each ``r_j = -alpha_j`` (the certified spectral abscissa of ``F_j(.; 0, K)``) is continuous and piecewise
    smooth, so the maximum of their least is an end of an interval (``"window end"``, or ``"end"`` at a bound),
    a peak of one ``r_j`` (``"interior smooth max"``: Brent's bounded search of the least rate between the
    neighbours of a sample where the least rate is largest and one loop the least on both sides), or a gain
    where two rates tie, ``r_i = r_j`` (``"tie"``: ``brentq`` on ``r_i - r_j`` between two consecutive samples
    whose least loops differ). All rates are sampled at ``max(n_rates, _LEAST_SAMPLES)`` gains of each interval,
    ends included; the candidates are the ends, every tie bracketed by the samples and every sampled peak, and
    the largest least rate among them is the design. A peak or a second tie narrower than the samples' spacing
    can be missed: the value is the certified least rate at the gain returned, the optimality is that of the
    samples' candidates.

    Returns
    -------
    (K, value, kind, end, abscissae, K_bracket)
        ``end`` the event of a ``"window end"``; ``abscissae`` those of ``loops`` at ``K`` (in their order);
        ``K_bracket`` the gains the optimum is known to lie in (the end and its event; ``brentq``'s or the
        search's tolerance about a tie or a peak).
    """
    from scipy.optimize import brentq, minimize_scalar  # loaded on first use (the start-up of the commands)

    xtol = 1e-12 * max(scale, 1e-300)
    cache: dict[float, list[SpectralAbscissa]] = {}

    def abscissae(K: float) -> list[SpectralAbscissa]:
        if K not in cache:
            cache[K] = [loop.abscissa(K) for loop in loops]
        return cache[K]

    def rates(K: float) -> NDArray[np.float64]:
        return np.array([-sa.value for sa in abscissae(float(K))])

    Candidate = tuple[float, float, str, GainEnd | None, tuple[float, float]]
    candidates: list[Candidate] = []
    n = max(n_rates, _LEAST_SAMPLES)
    for (K_a, event_a), (K_b, event_b) in intervals:
        Ks = np.linspace(K_a, K_b, n) if K_b > K_a else np.array([K_a])
        R = np.array([rates(float(K)) for K in Ks])  # R[k, j]: loop j's rate at the sample k
        least, which = R.min(axis=1), R.argmin(axis=1)
        for K_end, event in ((K_a, event_a), (K_b, event_b)):
            at = (min(K_end, event.K), max(K_end, event.K)) if event is not None else (K_end, K_end)
            candidates.append((K_end, float(rates(K_end).min()), "end" if event is None else "window end", event, at))
        for k in range(Ks.size - 1):
            i, j = int(which[k]), int(which[k + 1])
            a, b = float(Ks[k]), float(Ks[k + 1])
            if i != j and R[k, i] < R[k, j] and R[k + 1, i] > R[k + 1, j]:  # r_i - r_j changes sign in [a, b]
                K = float(brentq(lambda x, i=i, j=j: float(rates(x)[i] - rates(x)[j]), a, b, xtol=xtol, rtol=4 * _EPS))
                width = xtol + 4 * _EPS * abs(K)
                candidates.append((K, float(rates(K).min()), "tie", None, (K - width, K + width)))
        for k in range(1, Ks.size - 1):
            if least[k] >= least[k - 1] and least[k] >= least[k + 1] and which[k - 1] == which[k] == which[k + 1]:
                res = minimize_scalar(
                    lambda x: -float(rates(x).min()),
                    bounds=(float(Ks[k - 1]), float(Ks[k + 1])),
                    method="bounded",
                    options={"xatol": 1e-10 * max(scale, 1e-300)},
                )
                K = float(res.x)
                width = 1e-10 * max(scale, 1e-300)
                candidates.append((K, float(rates(K).min()), "interior smooth max", None, (K - width, K + width)))
    K, value, kind, end, K_br = max(candidates, key=lambda c: c[1])
    return K, value, kind, end, abscissae(K), K_br


# A coefficient of the nominal loop is a rounding residue at a parameter when it is below this many units of
# rounding of the two parts of its affine expression there.
_RESIDUE_ULPS = 64
# Floating-point neighbours tried on each side of a parameter where the other coefficients vanish.
_NEIGHBOURS = 4


def _single_term(F: QuasiPolynomial) -> bool:
    """``F = c e^{-h s}`` with a constant ``c`` proven nonzero (``|c|`` above its radius): no zero anywhere."""
    return (
        not F.distributed
        and len(F.point_terms) == 1
        and F.point_terms[0][0].size == 1
        and bool(abs(F.point_terms[0][0][0]) > F.radii_of()[0][0])
    )


def _distributed_residue(loop: _Family, F: QuasiPolynomial, p: float) -> bool:
    """Every distributed term of ``F``, the nominal loop at ``p``, a rounding residue: its size (largest coefficient
    of its kernel's pieces times largest of its polynomial, plus its error radius) below ``_RESIDUE_ULPS`` units of
    rounding of the sizes of the distributed terms of the family's parts (weighted by ``1`` and ``|p|``)."""

    def size(d: DistributedDelay) -> float:
        return float(np.abs(d.pieces[2]).max() * np.abs(d.poly).max()) + d.radius

    weights = (1.0, 1.0, abs(p)) if loop.gain else (1.0, abs(p), 1.0, abs(p))
    scale = sum(w * size(d) for w, P in zip(weights, loop.parts, strict=True) for d in P.distributed)
    return all(size(d) <= _RESIDUE_ULPS * np.finfo(float).eps * scale for d in F.distributed)


def _finite_time_gains(loop: _Family, lo: float, hi: float) -> tuple[list[float], list[float]]:
    """The parameters of ``[lo, hi]`` at which the nominal loop ``F(.; 0, p)`` has no zero at all.

    A quasi-polynomial has no zero iff it is one term ``c e^{-h s}`` with a constant ``c != 0`` (a
    nonconstant polynomial, or two terms, have zeros): the loop converges in finite time and its decay rate
    is infinite. For ``U_BS2(K)`` that is ``K = rho``, the finite-time law ``U_BS`` (eq. (47)): the target
    system ``1 - (rho - K) q e^{-tau s}`` (eqs. (56)-(58)) is ``1``. The decay rate tends to ``+inf`` there
    (``-ln|(rho - K) q| / tau``): neither smooth nor bounded near it, so a search of its maximum stops a
    rounding-sized step away with a large finite value.

    The point coefficients of ``F(.; 0, p) = N_0 + p N_1`` are affine in ``p`` (``N_1`` the sum of the parts
    multiplied by ``p``, not ``F(.; 0, 1) - N_0``, which loses the digits of ``N_1`` that ``N_0`` outweighs);
    each vanishes at one ``p* = -c_0 / c_1``, where the other coefficients are checked: every one but a
    constant a rounding residue (``_RESIDUE_ULPS`` units of its two parts). The loop is then built at ``p*``
    and its floating-point neighbours (``_NEIGHBOURS`` on each side) and kept where it is one term exactly;
    otherwise ``p*`` is one up to rounding when the distributed terms left at ``p*`` are rounding residues
    too (:func:`_distributed_residue`: kernels that cancel to within rounding only).

    Returns
    -------
    (list of float, list of float)
        The parameters at which the loop built is one term (its decay rate ``inf``, exactly), and the ``p*``
        at which it is one term up to rounding only (no floating-point parameter reaches it).
    """
    F0 = loop.nominal(0.0)
    F1 = loop.loop.R if isinstance(loop.loop, AffineGainLoop) else loop.loop.A1 + loop.loop.B1
    at0 = {(t, j): complex(c) for p, t in F0.point_terms for j, c in enumerate(p)}
    at1 = {(t, j): complex(c) for p, t in F1.point_terms for j, c in enumerate(p)}
    keys = sorted(set(at0) | set(at1))
    c0 = np.array([at0.get(k, 0.0) for k in keys])
    c1 = np.array([at1.get(k, 0.0) for k in keys])
    constant = np.array([j == 0 for _, j in keys])
    exact: list[float] = []
    near: list[float] = []
    for c_0, c_1 in zip(c0, c1, strict=True):
        if c_1 == 0.0:
            continue
        p_star = float((-c_0 / c_1).real) + 0.0  # 0.0, not -0.0
        if not lo <= p_star <= hi or any(abs(p_star - p) <= 1e-12 * (1.0 + abs(p)) for p in exact + near):
            continue
        value = np.abs(c0 + p_star * c1)
        left = value > _RESIDUE_ULPS * np.finfo(float).eps * (np.abs(c0) + abs(p_star) * np.abs(c1))
        if np.count_nonzero(left) != 1 or not constant[left][0]:
            continue
        tries = [p_star]
        for direction in (-np.inf, np.inf):
            p = p_star
            for _ in range(_NEIGHBOURS):
                p = float(np.nextafter(p, direction))
                tries.append(p)
        hit = next((p for p in tries if lo <= p <= hi and _single_term(loop.combined(p))), None)
        if hit is not None:
            exact.append(hit)
        elif _distributed_residue(loop, loop.nominal(p_star), p_star):
            near.append(p_star)
    return exact, near


# A sample's decay rate is left out when a bound puts it below a computed one by this much (relative): far
# above the errors of the rates (~1e-14) and of the bounds, far below the differences between samples.
_RATE_GAP = 1e-9
# Newton steps, and continuation steps, that follow a zero's path in the gain (:class:`_RootPaths`).
_PATH_NEWTON = 8
_PATH_STEPS = 200
# The shortest continuation step, relative to the distance followed.
_PATH_MIN_STEP = 1e-3
# Halvings of an interval between samples whose two rightmost zeros do not decide its maximum (:func:`_peak_between`).
_PEAK_HALVINGS = 3
# Halvings that look for gains where both paths of a crossing are followed (:func:`_crossing_bracket`).
_PATH_BISECTIONS = 12
# Half-width (relative to 1 + |z|) of the box about a root followed by Newton's method in which it is counted.
_ROOT_BOX = 1e-6


def _root_bound(F: QuasiPolynomial, z0: complex) -> float:
    """``-x_0`` for a box ``[x_0, x_1] x [y_0, y_1]`` in which a certified count finds a root of ``F``, about the
    limit of Newton's method from ``z0``; ``inf`` when Newton does not converge or the count finds none.

    A root with ``Re s >= x_0`` makes the spectral abscissa at least ``x_0``: the decay rate is at most ``-x_0``.
    """
    z = complex(z0)
    with np.errstate(all="ignore"):  # far from a root F may overflow: no bound then
        for _ in range(_NEWTON_STEPS):
            s = np.array([z])
            step = complex(F(s)[0] / F.deriv_at(s)[0])
            z -= step
            if not np.isfinite(z):
                return np.inf
            if abs(step) <= 1e-12 * (1.0 + abs(z)):
                break
        else:
            return np.inf
    h = _ROOT_BOX * (1.0 + abs(z))
    try:
        count = count_roots(F, (z.real - h, z.real + h, z.imag - h, z.imag + h))
    except CertificationError:
        return np.inf
    return -count.region[0] if count > 0 else np.inf


def _sampled_abscissas(loop: _Family, Ks: NDArray[np.float64], first: int) -> list[SpectralAbscissa | None]:
    """The spectral abscissas of ``F(.; 0, K)`` at the samples ``Ks``; None at a sample whose decay rate is
    proven smaller than a computed one (so the first largest rate of the samples is that of the full list).

    The decay rate ``-alpha(K)`` is at most ``-c_D + 1e-12 (1 + |c_D|)``, ``c_D`` the chain value of the
    principal part (:func:`~nrobust.roots.spectral_abscissa` returns the rightmost root, or ``c_D`` when
    it lies further right than that root by more than ``1e-12 (1 + |c_D|)``), and at most ``-x_0`` when a
    certified count finds a root in a box ``[x_0, x_1] x [y_0, y_1]`` (:func:`_root_bound`, from the
    rightmost root of the nearest computed sample). A sample is computed unless a bound lies ``1e-9``
    (relative) below the largest rate computed; the end ``first`` first (the likely largest), then the
    other end, then the interior samples.
    """
    n = Ks.size
    Fs = [loop.nominal(float(K)) for K in Ks]
    chains = [float(F.principal_part().spectral_bound().upper) for F in Fs]
    bounds = [-c + 2e-12 * (1.0 + abs(c)) if np.isfinite(c) else np.inf for c in chains]
    order = [first, n - 1 - first, *range(1, n - 1)]
    out: list[SpectralAbscissa | None] = [None] * n
    best = -np.inf

    def below(bound: float) -> bool:
        return bound + _RATE_GAP * (1.0 + abs(bound)) < best

    for j in order:
        if below(bounds[j]):
            continue
        computed = [i for i in range(n) if out[i] is not None]
        if computed:
            near = out[min(computed, key=lambda i: abs(Ks[i] - Ks[j]))]
            if near is not None and near.root is not None and below(_root_bound(Fs[j], near.root)):
                continue
        sa = loop.abscissa(float(Ks[j]))
        out[j] = sa
        best = max(best, -sa.value)
    return out


@one_blas_thread()  # the scan's many small products: competing BLAS threads only cost time
def best_margin(
    loop: AffineGainLoop | AffineLoop,
    bounds: tuple[float, float],
    *,
    delays: tuple[float, float] | None = None,
    scenarios: tuple[AffineGainLoop | AffineLoop, ...] = (),
    rigorous: bool = False,
    max_evals: int = 2_000_000,
) -> GainDesign:
    """The gain in ``[K_lo, K_hi]`` with the largest delay margin, from the equations of its kind.

    ``delta*(K)`` is the lower envelope of the crossing curves (module docstring); its
    maximum is a kink (two curves meet: ``delta_1(K) = delta_2(K)``), a pair birth (a jump
    down: the supremum, approached from the side without the pair), an interior smooth
    maximum or an end. The curves are sampled once on a uniform frequency grid, the local
    maxima of the envelope within 5 % of the largest are solved from their equations
    (Newton with the exact Jacobian for a kink, ``brentq`` otherwise) and the best is
    certified.

    Parameters
    ----------
    loop : AffineGainLoop or AffineLoop
        ``A + (B_0 + K R) e^{-delta s}`` with real coefficients (``U_BS2(K)``'s, eq. (60):
        :func:`nrobust.hyperbolic.analyses.kregion.u_bs2_loop`), or
        ``(A_0 + K A_1) + (B_0 + K B_1) e^{-delta s}`` (``K`` any real parameter: the filtered
        law's zero or pole, :meth:`nrobust.hyperbolic.analyses.filter_design.FilteredLoop.affine`).
    bounds : (float, float)
        ``K_lo < K_hi``, where the difference operator is strongly stable (for ``U_BS2(K)``:
        ``|K| < (1 - |rho q|)/|q|``, eq. (54)) at every parameter of ``[K_lo, K_hi]``: the
        ``s^n`` coefficients ``a_k(p)`` of the principal part are affine in ``p``, so
        ``|a_0(p)| - sum_{k>=1} |a_k(p)|`` is affine between their zeros and is checked there and
        at the ends (a drop of the degree, where every ``a_k`` vanishes, by the operator of lower
        degree at that point).
    delays : (float, float), optional
        A window ``[d_min, d_max]`` on which the loop must also be exponentially stable (the
        feasible gains of :func:`best_decay_rate`): the margin is maximised over them, a
        candidate outside them dropped and their ends (``kind`` ``"window end"``) compared; a
        margin of 0 everywhere (``d_min > 0`` and the nominal loop unstable) gives the middle of
        the widest interval (``kind`` ``"window"``).
    scenarios : tuple of AffineGainLoop or AffineLoop, optional
        Further loops that must be stable on the window (with ``delays``).
    rigorous : bool, optional
        Prove the margin at the design in ball arithmetic (``certified == "proven"``); when
        the proof fails the margin is checked in floating point and ``certified`` says why.
    max_evals : int, optional
        Work bound of the sampling of the crossing curves (six evaluations per sample) and of
        the certifying delay margin.

    Returns
    -------
    GainDesign

    Raises
    ------
    ParameterError
        ``loop`` not an ``AffineGainLoop`` or ``AffineLoop`` with real coefficients, ``bounds`` not
        increasing, or containing a parameter where the difference operator is not strongly
        stable (the message gives where it is not, and where it is).
    CertificationError
        The sampling would exceed ``max_evals``, an equation did not converge, or the certified
        margin at the design disagrees with the equations (a crossing curve missed by the scan).
    """
    lo, hi = _checked_loop(loop, bounds)
    if delays is not None or scenarios:
        if delays is None:
            raise ParameterError("delays", "a window [d_min, d_max] with scenarios", None)
        return _window_design(loop, lo, hi, "margin", delays, scenarios, 5, max_evals, rigorous)
    max_evals = positive_int("max_evals", max_evals)
    if isinstance(loop, AffineLoop) and _is_zero(loop.B0) and _is_zero(loop.B1):
        raise ParameterError(
            "loop",
            "a loop whose delayed factor B_0 + p B_1 is not zero (without it the delay does not enter the loop: "
            "every parameter stable without delay has an infinite margin; best_decay_rate designs such a loop)",
            loop,
        )
    curves = _Curves(_Family(loop), lo, hi, max_evals)
    mask = _nominal_mask(curves)
    missed = [] if mask.any() else _missed_edges(curves)  # no stable gain: unless an edge was missed
    if missed:
        curves.add_edges(missed)
        mask = _nominal_mask(curves)
        if not mask.any():
            raise CertificationError(
                f"best_margin: the loop without delay changes stability at p = {missed[0][1]:.15g}, but no interval "
                "between the stability edges is stable at its middle (several edges were missed by the scan); "
                "narrower bounds around it may give a design"
            )
    if not mask.any():
        raise ParameterError(
            "bounds",
            "parameters of which some give a stable loop without delay (certified: F(s; 0, p) has zeros with "
            f"Re s >= 0 for every p in [{lo:.12g}, {hi:.12g}], so every delay margin there is 0)",
            bounds,
        )
    env = np.where(mask, curves.envelope, 0.0)
    finite = env[np.isfinite(env)]
    if finite.size:  # a curve the interpolation hides near the top: solved there (:meth:`_Curves.refine`)
        curves.refine(mask & (env >= (1.0 - 2.0 * _NEAR_TOP) * float(np.max(finite))))
        env = np.where(mask, curves.envelope, 0.0)
    scan = (curves.gains, env)
    if np.any(np.isinf(env)):  # gains that no crossing curve reaches, nominally stable: delta* = inf
        idx = np.flatnonzero(np.isinf(env))
        run = max(np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1), key=len)
        K = float(curves.gains[run[run.size // 2]])  # the middle of the longest run
        cert, how = _certify(curves.loop, K, rigorous, max_evals)
        if not np.isinf(cert.margin):
            raise CertificationError(
                f"best_margin: no crossing curve reaches K = {K:.12g}, but its delay margin is {cert.margin}"
            )
        inf = float("inf")
        sa = curves.loop.abscissa(K)
        return GainDesign(
            K,
            "margin",
            inf,
            inf,
            -sa.value,
            "no crossing",
            (K, K),
            (inf, inf),
            (lo, hi),
            cert,
            how,
            sa,
            *scan,
            nominal=curves.loop.nominal(K),
        )
    finite = env
    solved = [_solve_candidate(curves, i, finite) for i in _candidates(finite)]
    K, value, kind, K_br, v_br = max(solved, key=lambda c: c[1])
    if not np.isfinite(value):  # a supremum the equations put at infinity (the check below cannot compare it)
        _unbounded_at_zero(curves.loop, K)
        raise CertificationError(
            f"best_margin: the {kind} at K = {K:.15g} gives delta* = {value} by its equations, not a finite optimum"
        )
    cert, how = _certify(curves.loop, K, rigorous, max_evals)
    tol = 1e-9 * max(value, 1e-300) + (cert.accuracy or 0.0)
    if not abs(cert.margin - value) <= tol:  # a NaN from the equations fails too
        raise CertificationError(
            f"best_margin: the {kind} at K = {K:.15g} gives delta* = {value:.15g} by its equations, the certified "
            f"delay margin there is {cert.margin:.15g}: a crossing curve was missed by the scan"
        )
    sa = curves.loop.abscissa(K)
    return GainDesign(
        K,
        "margin",
        cert.margin,
        cert.margin,
        -sa.value,
        kind,
        K_br,
        _outward(v_br, cert.accuracy),
        (lo, hi),
        cert,
        how,
        sa,
        *scan,
        nominal=curves.loop.nominal(K),
    )


def _unbounded_at_zero(loop: _Family, K: float) -> None:
    """Raise when ``s = 0`` is a zero of both factors at ``K`` (to rounding): the delay margin then grows without
    bound toward ``K`` (the limit ``B'(0)/B(0) - A'(0)/A(0)`` of the crossing delay at the end of nominal
    stability has ``A(0) = 0``), and no gain has the largest margin."""
    zero = np.zeros(1)
    A, B = loop.A(K), loop.B(K)
    size = max((float(np.max(np.abs(p))) for P in (A, B) for p, _ in P.point_terms), default=1.0)
    if abs(complex(A(zero)[0])) <= 1e-12 * size and abs(complex(B(zero)[0])) <= 1e-9 * size:
        raise CertificationError(
            f"best_margin: the delay margin grows without bound toward K = {K:.15g}, where s = 0 is a zero of both "
            "A and B (the nominal loop has a root at s = 0 for every delay there): no gain has the largest margin; "
            "bounds that leave that gain out give one"
        )


_Candidate = tuple[float, float, str, GainEnd | None, SpectralAbscissa]

# A plateau of the decay rate about its optimum is looked for this far from it (relative to the scale of the gains):
# a smooth maximum falls there by its curvature times 1e-6, a kink or an end by its slope times 1e-3, each far above
# the rates' accuracies (~1e-15 to 1e-12); a plateau not at all.
_PLATEAU_PROBE = 1e-3
# Bisections of each end of a plateau, and samples of the plateau found at which the rate is checked.
_PLATEAU_BISECTIONS = 40
_PLATEAU_SAMPLES = 9


def _plateau(
    loop: _Family, K: float, sa: SpectralAbscissa, interval: tuple[float, float], scale: float
) -> tuple[float, float] | None:
    """The interval ``[L, U]`` of ``interval`` about the optimum ``K`` on which the decay rate stays within its
    accuracy of the optimum's (a plateau: the rightmost zero, or chain, does not move with the parameter), or None.

    The rate at ``K' = K -+ _PLATEAU_PROBE * scale`` (inside ``interval``) is within ``acc(K) + acc(K')`` of the
    rate at ``K`` (:attr:`~nrobust.roots.SpectralAbscissa.accuracy`; not where the chains of the principal part
    bound it below that first, as in :func:`_sampled_abscissas`) on at least one side; each such side is then
    extended to the end of ``interval`` if the rate is within there too, else to the kink where the plateau ends
    (:func:`_plateau_kink`: the zero rightmost beyond it, followed back, reaches the plateau's rate) if the rate is
    within there, else to the last gain within of ``_PLATEAU_BISECTIONS`` bisections toward it; and the rate is
    within at ``_PLATEAU_SAMPLES`` gains spread over ``[L, U]`` (else None: the rate is not flat between). Checked
    at those gains, not between them.
    """
    if sa.accuracy is None or not np.isfinite(sa.value):
        return None
    rate, acc = -sa.value, sa.accuracy

    def flat(x: float) -> bool:
        F = loop.nominal(x)
        chain = float(F.principal_part().spectral_bound().upper)  # the rate is at most -c_D (as in the samples)
        if np.isfinite(chain) and -chain + 2e-12 * (1.0 + abs(chain)) < rate - acc:
            return False
        other = loop.abscissa(x)
        return other.accuracy is not None and abs(-other.value - rate) <= acc + other.accuracy

    step = _PLATEAU_PROBE * max(scale, 1e-300)
    ends = [K, K]
    for i, (direction, end) in enumerate(((-1.0, interval[0]), (1.0, interval[1]))):
        probe = min(K + step, end) if direction > 0 else max(K - step, end)
        if probe == K or not flat(probe):
            continue
        if flat(end):
            ends[i] = end
            continue
        inside, outside = probe, end
        kink = _plateau_kink(loop, rate, acc, inside, outside, scale)
        if kink is not None and flat(kink):
            ends[i] = kink
            continue
        for _ in range(_PLATEAU_BISECTIONS):
            mid = 0.5 * (inside + outside)
            inside, outside = (mid, outside) if flat(mid) else (inside, mid)
        ends[i] = inside
    lo, hi = ends
    if lo == hi or not all(flat(x) for x in np.linspace(lo, hi, _PLATEAU_SAMPLES)):
        return None
    return float(lo), float(hi)


def _plateau_kink(
    loop: _Family, rate: float, accuracy: float, inside: float, outside: float, scale: float
) -> float | None:
    """The gain between ``inside`` (on a plateau of the decay rate ``rate``, known within ``accuracy``) and ``outside``
    (off it) where the plateau ends: where the rate of the zero rightmost at ``outside``, followed back along its path
    (:class:`_RootPaths`), is ``rate - accuracy / 2`` (for a chain of zeros approached at infinity: the rate of its
    asymptote, the spectral bound of the principal part, which is flat on the plateau when a chain makes it). Brent's
    method on that continuous rate, to ``1e-12`` of ``scale``, a dozen cheap evaluations where bisections of the
    certified abscissa took forty. None where that rate does not fall through the level between ``inside`` and
    ``outside`` (another zero ends the plateau, or a path is lost): the bisections of :func:`_plateau` decide.
    """
    from scipy.optimize import brentq  # scipy.optimize loads on first use (the start-up of the commands)

    sa = loop.abscissa(outside)
    if sa.root is None:
        return None
    if sa.approached_at_infinity:  # a chain of zeros: its asymptote, the principal part's spectral bound

        def gap(K: float) -> float:
            return -float(loop.nominal(K).principal_part().spectral_bound().upper) - rate + 0.5 * accuracy

    else:
        path = _Path(_RootPaths(loop), outside, complex(sa.root))

        def gap(K: float) -> float:
            return -path.at(K).real - rate + 0.5 * accuracy

    try:
        if not (gap(outside) < 0.0 < gap(inside)):
            return None
        return float(brentq(gap, inside, outside, xtol=1e-12 * max(scale, 1e-300), rtol=4 * _EPS))
    except _PathLost:
        return None


def _with_plateau(
    loop: _Family,
    best: _Candidate,
    intervals: list[tuple[float, float]],
    scale: float,
) -> tuple[_Candidate, tuple[float, float] | None]:
    """``best`` as ``"plateau"`` (without an end event) with its interval (:func:`_plateau`) when the decay rate
    is flat about it in the interval of ``intervals`` that holds it; else ``best`` and None.

    Not looked for (no abscissa computed) where the rightmost zero moves with the gain: its slope
    (:meth:`_RootPaths.slope`) changes the rate over the probe by ``1e3`` times its accuracy or more.
    """
    K, rate, kind, _, sa = best
    if kind == "finite time" or not np.isfinite(rate) or sa.accuracy is None:
        return best, None
    if sa.root is not None and not sa.approached_at_infinity:
        slope = _RootPaths(loop).slope(K, complex(sa.root))
        if abs(slope) * _PLATEAU_PROBE * scale >= 1e3 * sa.accuracy:
            return best, None
    holding = [(a, b) for a, b in intervals if a <= K <= b]
    if not holding:
        return best, None
    found = _plateau(loop, K, sa, holding[0], scale)
    if found is None:
        return best, None
    return (K, rate, "plateau", None, sa), found


def _up_to_events(p: float, ends: tuple[tuple[float, GainEnd | None], tuple[float, GainEnd | None]]) -> bool:
    """``p`` in the interval ``ends`` or between one of its ends and the event it was moved ``1e-10`` inside from
    (the gains there meet the requirement too), the event excluded."""
    (K_a, event_a), (K_b, event_b) = ends
    above = p > event_a.K if event_a is not None else p >= K_a
    below = p < event_b.K if event_b is not None else p <= K_b
    return above and below


def _best_rate(
    curves: _Curves,
    intervals: list[tuple[tuple[float, GainEnd | None], tuple[float, GainEnd | None]]],
    n_rates: int,
    end_kind: str,
) -> _Candidate:
    """The largest decay rate over the intervals ``((K_a, event_a), (K_b, event_b))``: ``n_rates`` samples
    of each, ends included; an end (``end_kind``, or ``"end"`` at a bound) when its sample is the largest,
    else the maximum about the largest interior sample (:func:`_peak_between` toward the neighbour where the
    rate rises, else Brent's bounded search between its neighbours; a :class:`~nrobust.errors.CertificationError`
    when it ends below that sample), and any maximum between two samples where the rate rises then falls
    (:func:`_rising_then_falling`). A gain of an interval (up to the events
    its ends were moved inside from: :func:`_up_to_events`) at which the nominal loop has no zero
    (:func:`_finite_time_gains`) is the design, its rate ``inf`` (``"finite time"``); one where that holds
    up to rounding only is a :class:`~nrobust.errors.CertificationError`
    (the rate is unbounded there, and no sampled maximum is its supremum)."""
    scale = _scale(curves)
    paths = _RootPaths(curves.loop)
    exact, near = _finite_time_gains(curves.loop, curves.K_lo, curves.K_hi)
    finite_time = [p for p in exact if any(_up_to_events(p, ends) for ends in intervals)]
    if finite_time:
        return (finite_time[0], np.inf, "finite time", None, curves.loop.abscissa(finite_time[0]))
    best: _Candidate | None = None
    for ends in intervals:
        (K_a, event_a), (K_b, event_b) = ends
        unreached = [p for p in near if _up_to_events(p, ends)]
        if unreached:
            raise CertificationError(
                f"best_decay_rate: the decay rate grows without bound toward K = {unreached[0]!r}, where the nominal "
                "loop is one term c e^{-h s} (no zero: finite-time convergence) up to the rounding of its "
                "coefficients, but no floating-point gain makes it one term exactly; a loop whose coefficients "
                "cancel exactly there, or bounds that leave that gain out, would give a design"
            )
        Ks = np.linspace(K_a, K_b, n_rates)
        # an end set by an event (the other at a bound) is the likely best: computed first
        sas = _sampled_abscissas(curves.loop, Ks, 0 if event_a is not None and event_b is None else n_rates - 1)
        rates = np.array([-np.inf if sa is None else -sa.value for sa in sas])
        k = int(np.argmax(rates))  # a sample left out has a smaller rate than a computed one: never the first largest
        sa_k = sas[k]
        assert sa_k is not None
        slopes = _rate_slopes(paths, Ks, sas)
        for peak in _rising_then_falling(curves, paths, Ks, sas, slopes, k, scale):
            if best is None or peak[1] > best[1]:
                best = peak
        if k in (0, n_rates - 1):
            K_end, event_end = ends[0 if k == 0 else 1]
            cand: _Candidate = (K_end, float(rates[k]), "end" if event_end is None else end_kind, event_end, sa_k)
        else:
            side = k + 1 if slopes[k] > 0.0 else k - 1  # the neighbour toward which the rate rises
            sa_side = sas[side]
            found = None
            if sa_side is not None:
                (i, sa_i), (j, sa_j) = sorted([(k, sa_k), (side, sa_side)], key=lambda t: t[0])
                found = _peak_between(curves, paths, (float(Ks[i]), sa_i), (float(Ks[j]), sa_j))
            if found is None:
                found = _bounded_search(curves, float(Ks[k - 1]), float(Ks[k + 1]), scale)
            if found[1] + _RATE_GAP * (1.0 + abs(rates[k])) < rates[k]:  # not a smooth maximum about the sample
                raise CertificationError(
                    f"best_decay_rate: the search about K = {float(Ks[k])!r} (decay rate {rates[k]:.6g}) ended at "
                    f"K = {found[0]!r} with the smaller rate {found[1]:.6g}: the rate is not smooth there (a "
                    "spike, or gains where the loop is unstable between the samples); bounds about that K, or more "
                    "samples (n_rates), would help"
                )
            cand = found
        if best is None or cand[1] > best[1]:
            best = cand
    assert best is not None
    return best


class _RootPaths:
    """Zeros of the nominal loop ``F(.; 0, K) = N_0 + K N_1`` followed in ``K`` by Newton's method.

    ``N_1`` is the sum of the parts multiplied by the parameter (as in :func:`_finite_time_gains`);
    a zero's sensitivity is ``ds/dK = -N_1(s) / F'(s)``, the slope of its decay rate ``-Re s`` is
    ``Re(N_1(s) / F'(s))``. What is followed here only locates an optimum: its rate is that of the
    certified abscissa there.
    """

    def __init__(self, loop: _Family) -> None:
        self.N0 = loop.nominal(0.0)
        self.N1 = loop.loop.R if isinstance(loop.loop, AffineGainLoop) else loop.loop.A1 + loop.loop.B1
        self.dN0, self.dN1 = self.N0.derivative(), self.N1.derivative()
        self.values = QuasiPolynomialsAtPoint((self.N0, self.dN0, self.N1, self.dN1))
        # _parts by (K, s): continuations toward different gains try the same first steps (a fifth of the calls)
        self.parts: dict[tuple[float, complex], tuple[complex, complex, complex]] = {}
        # follow(K0, s0, K1) by its arguments (None: the path lost): the searches of one design ask again for
        # the same continuations (each path of :func:`_two_paths_peak` from the same samples), lost ones the
        # dearest (every step size down to the smallest is tried)
        self.followed: dict[tuple[float, complex, float], complex | None] = {}

    def _parts(self, K: float, s: complex) -> tuple[complex, complex, complex]:
        """``F(s), F'(s), N_1(s)`` at ``K`` (remembered: :attr:`parts`)."""
        found = self.parts.get((K, s))
        if found is None:
            n0, dn0, n1, dn1 = self.values(s)
            found = self.parts[(K, s)] = (n0 + K * n1, dn0 + K * dn1, n1)
        return found

    def slope(self, K: float, s: complex) -> float:
        """``d(-Re s)/dK`` of the zero ``s`` at ``K``."""
        _, dF, n1 = self._parts(K, s)
        with np.errstate(all="ignore"):
            return float((n1 / dF).real)

    def newton(self, K: float, s: complex) -> complex | None:
        """The zero of ``F(.; 0, K)`` Newton's method reaches from ``s`` (None if it does not converge)."""
        with np.errstate(all="ignore"):
            for _ in range(_PATH_NEWTON):
                F, dF, _ = self._parts(K, s)
                if dF == 0:  # a multiple zero
                    return None
                step = F / dF
                s -= step
                if not np.isfinite(s):
                    return None
                if abs(step) <= 1e-14 * (1.0 + abs(s)):
                    return s
        return None

    def follow(self, K0: float, s0: complex, K1: float) -> complex:
        """The zero at ``K1`` on the path of ``s0``, a zero at ``K0``: Euler predictor, Newton corrector,
        the step halved when the correction exceeds a third of the predicted move (a jump to another
        path). Raises ``_PathLost`` after :data:`_PATH_STEPS` steps, or when the step falls below
        :data:`_PATH_MIN_STEP` of ``|K1 - K0|`` (as at the end of a path, where two zeros meet and the
        sensitivity grows without bound). Remembered by its arguments (:attr:`followed`)."""
        key = (K0, s0, K1)
        if key not in self.followed:
            try:
                self.followed[key] = self._follow(K0, s0, K1)
            except _PathLost:
                self.followed[key] = None
        found = self.followed[key]
        if found is None:
            raise _PathLost
        return found

    def _follow(self, K0: float, s0: complex, K1: float) -> complex:
        """:meth:`follow`, not remembered."""
        K, s, h = K0, s0, K1 - K0
        shortest = _PATH_MIN_STEP * abs(K1 - K0)
        for _ in range(_PATH_STEPS):
            if K == K1:
                return s
            if abs(h) < shortest:
                break
            last = abs(K1 - K) <= abs(h)
            h = K1 - K if last else h
            _, dF, n1 = self._parts(K, s)
            if dF == 0:  # two zeros meet: the end of the path
                break
            move = -n1 / dF * h
            new = self.newton(K + h, s + move)
            if new is not None and abs(new - s - move) <= abs(move) / 3.0 + 1e-12 * (1.0 + abs(s)):
                K, s = (K1 if last else K + h), new
                h *= 2.0
            else:
                h *= 0.5
        raise _PathLost


class _PathLost(Exception):
    """A zero's path could not be followed (a collision of zeros, or too many steps)."""


class _Path:
    """One zero's path in ``K``, remembered at every gain reached (each new gain followed from the nearest)."""

    def __init__(self, paths: _RootPaths, K: float, s: complex) -> None:
        self.paths = paths
        self.known = {K: s}

    def at(self, K: float) -> complex:
        if K not in self.known:
            near = min(self.known, key=lambda x: abs(x - K))
            self.known[K] = self.paths.follow(near, self.known[near], K)
        return self.known[K]

    def slope(self, K: float) -> float:
        return self.paths.slope(K, self.at(K))


def _rate_slopes(paths: _RootPaths, Ks: NDArray[np.float64], sas: list[SpectralAbscissa | None]) -> dict[int, float]:
    """``d(-alpha)/dK`` at the computed samples from the rightmost zero's sensitivity; NaN where the chain value
    is rightmost (no zero)."""
    return {
        j: float("nan") if sa.root is None else paths.slope(float(Ks[j]), complex(sa.root))
        for j, sa in enumerate(sas)
        if sa is not None
    }


def _peak_between(
    curves: _Curves,
    paths: _RootPaths,
    a: tuple[float, SpectralAbscissa],
    b: tuple[float, SpectralAbscissa],
    halvings: int = _PEAK_HALVINGS,
) -> _Candidate | None:
    """A maximum of the decay rate between ``K_a < K_b``, where it rises at ``K_a`` and falls at ``K_b``:
    :func:`_two_paths_peak`, else (other zeros rightmost between them) the half where the rate rises at one
    end and falls at the other, from the abscissa at the midpoint, up to ``halvings`` times; None then."""
    found = _two_paths_peak(curves, paths, a, b)
    if found is not None or halvings == 0:
        return found
    m = 0.5 * (a[0] + b[0])
    sa = curves.loop.abscissa(m)
    if sa.root is None:
        return None
    half = (a, (m, sa)) if paths.slope(m, complex(sa.root)) < 0.0 else ((m, sa), b)
    return _peak_between(curves, paths, *half, halvings - 1)


def _two_paths_peak(
    curves: _Curves, paths: _RootPaths, a: tuple[float, SpectralAbscissa], b: tuple[float, SpectralAbscissa]
) -> _Candidate | None:
    """The largest decay rate between ``K_a < K_b``, where it rises at ``K_a`` and falls at ``K_b``, from the
    paths of the two rightmost zeros; None when they do not decide it (the caller searches then).

    The zero ``s_a`` rightmost at ``K_a`` and ``s_b`` at ``K_b`` are followed (:class:`_RootPaths`). On
    one path (``s_a`` reaches ``s_b``) the maximum is smooth, ``d Re s/dK = 0`` (Brent's root finder on the
    slope); on two, the rate peaks where they cross, ``Re s_a(K) = Re s_b(K)`` (a kink), unless the slope of
    one changes sign before, a smooth maximum of that path. A path may end inside ``[K_a, K_b]`` (two real
    zeros meet and leave the axis): the crossing is bracketed by bisection where both are followed
    (:func:`_crossing_bracket`). The result is kept when the certified abscissa at the gain found is the
    followed zero (its rate to ``1e-9``, relative) and its rate is at least both samples'.
    """
    from scipy.optimize import brentq  # scipy.optimize loads on first use (the start-up of the commands)

    (Ka, sa_a), (Kb, sa_b) = a, b
    if sa_a.root is None or sa_b.root is None:
        return None
    xtol = 1e-14 * max(abs(Ka), abs(Kb), 1e-300)
    rb = complex(sa_b.root)
    up, down = _Path(paths, Ka, complex(sa_a.root)), _Path(paths, Kb, rb)
    try:
        if not up.slope(Ka) > 0.0 > down.slope(Kb):
            return None
        try:
            one = abs(up.at(Kb) - rb) <= 1e-9 * (1.0 + abs(rb))
        except _PathLost:
            one = False
        if one and not up.slope(Kb) < 0.0:  # the followed zero's slope at K_b, not the certified one's: undecided
            return None
        if one:  # one path: a smooth maximum
            K = brentq(up.slope, Ka, Kb, xtol=xtol, rtol=4 * _EPS)
            kind, top = "interior smooth max", up
        else:

            def gap(K: float) -> float:
                return up.at(K).real - down.at(K).real

            bracket = _crossing_bracket(up, down, Ka, Kb)
            if bracket is None:
                return None
            K = brentq(gap, *bracket, xtol=xtol, rtol=4 * _EPS)
            kind, top = "kink", max((up, down), key=lambda p: p.at(K).real)
            if up.slope(K) <= 0.0:
                K, kind, top = brentq(up.slope, Ka, K, xtol=xtol, rtol=4 * _EPS), "interior smooth max", up
            elif down.slope(K) >= 0.0:
                K, kind, top = brentq(down.slope, K, Kb, xtol=xtol, rtol=4 * _EPS), "interior smooth max", down
        predicted = -top.at(K).real
    except _PathLost:
        return None
    sa = curves.loop.abscissa(K)
    rate = -sa.value
    if abs(rate - predicted) > 1e-9 * (1.0 + abs(rate)) or rate < max(-sa_a.value, -sa_b.value):
        return None
    return (K, rate, kind, None, sa)


def _crossing_bracket(up: _Path, down: _Path, Ka: float, Kb: float) -> tuple[float, float] | None:
    """``[x, y]`` in ``[K_a, K_b]`` with both paths followed at ``x`` and ``y``, ``up`` right of ``down`` at
    ``x`` and not at ``y``; None if bisection finds none in :data:`_PATH_BISECTIONS` halvings.

    ``up`` starts at ``K_a``, ``down`` at ``K_b``, each followed on an interval about its start: a gain
    where ``up`` is lost, or ``down`` is right of it, lies right of their crossing; one where ``down`` is
    lost, or ``up`` is right of it, left.
    """

    def side(K: float) -> tuple[bool, bool]:
        """(left of the crossing, both followed)."""
        try:
            re_up = up.at(K).real
        except _PathLost:
            return False, False
        try:
            return re_up > down.at(K).real, True
        except _PathLost:
            return True, False

    (left_a, x_ok), (left_b, y_ok) = side(Ka), side(Kb)
    if not left_a or left_b:
        return None
    x, y = Ka, Kb
    for _ in range(_PATH_BISECTIONS):
        if x_ok and y_ok:
            return x, y
        m = 0.5 * (x + y)
        left, ok = side(m)
        if left:
            x, x_ok = m, ok
        else:
            y, y_ok = m, ok
    return None


def _rising_then_falling(
    curves: _Curves,
    paths: _RootPaths,
    Ks: NDArray[np.float64],
    sas: list[SpectralAbscissa | None],
    slopes: dict[int, float],
    k: int,
    scale: float,
) -> list[_Candidate]:
    """Interior maxima of the decay rate between computed samples other than about the largest ``k``.

    Between two consecutive computed samples where the rate rises at the first and falls at the
    second (``slopes``) the continuous rate has a maximum, which may exceed every sample (a peak
    where two zeros' paths cross, narrower than the samples' spacing): solved by :func:`_peak_between`,
    else by Brent's bounded search, each a candidate (the samples about ``k`` are the caller's).
    """
    computed = sorted(slopes)
    out: list[_Candidate] = []
    for a, b in itertools.pairwise(computed):
        if not (slopes[a] > 0.0 > slopes[b]) or (a >= k - 1 and b <= k + 1 and 0 < k < Ks.size - 1):
            continue
        sa_a, sa_b = sas[a], sas[b]
        assert sa_a is not None and sa_b is not None
        peak = _peak_between(curves, paths, (float(Ks[a]), sa_a), (float(Ks[b]), sa_b))
        out.append(peak if peak is not None else _bounded_search(curves, float(Ks[a]), float(Ks[b]), scale))
    return out


def _bounded_search(curves: _Curves, lo: float, hi: float, scale: float) -> _Candidate:
    """Brent's bounded search of the smallest spectral abscissa on ``[lo, hi]`` (a full abscissa each step)."""
    from scipy.optimize import minimize_scalar  # scipy.optimize loads on first use (the start-up of the commands)

    res = minimize_scalar(
        lambda K: curves.loop.abscissa(K).value,
        bounds=(lo, hi),
        method="bounded",
        options={"xatol": 1e-10 * max(scale, 1e-300)},
    )
    sa = curves.loop.abscissa(float(res.x))
    return (float(res.x), -sa.value, "interior smooth max", None, sa)


def _level_end(curves: _Curves, i: int, j: int, level: float) -> GainEnd:
    """The event between the feasible grid gain ``i`` and the infeasible ``j``: a curve crossing ``level``
    (``"crossing"``), a pair born below it (``"pair_birth"``) or the end of nominal stability
    (``"nominal"``: ``s = 0`` a zero for every delay, ``K`` from ``F(0; 0, K) = 0`` in closed form,
    :meth:`_Family.zero_root`); the one nearest the feasible side.

    Where a zero leaves through ``s = 0`` the envelope drops to 0 without a curve crossing ``level``:
    the curve ending at ``w = 0`` has the delay ``B'(0)/B(0) - A'(0)/A(0)`` there, which may be above
    it (``StateFeedback(k)`` on ``Hyperbolic2x2(1, 1, 1.5, 0.5, 0.8, 0.4)``: ``k = -0.2389191``, margin
    2.26). A zero leaving through ``i w``, ``w > 0``, ends a curve at delay 0: a crossing of ``level``."""
    lo, hi = sorted((curves.gains[i], curves.gains[j]))
    events: list[GainEnd] = []
    K0 = curves.loop.zero_root()
    if K0 is not None and lo - (hi - lo) <= K0 <= hi + (hi - lo):
        events.append(GainEnd(float(K0), "nominal", 0.0, 0.0, None, 0.0, 0.0))
    for piece in curves.pieces:
        for at_start in (True, False):
            if (piece.start if at_start else piece.stop) == "birth":
                found = _birth_in(curves, piece, lo, hi)
                if found is not None:
                    Kb, wb = found
                    db = curves.on_branch(wb, piece.sigma)[1]
                    if db < level and lo - (hi - lo) <= Kb <= hi + (hi - lo):
                        events.append(GainEnd(float(Kb), "pair_birth", float(wb), float(db)))
        d = piece.d - level
        change = np.flatnonzero(np.sign(d[:-1]) * np.sign(d[1:]) < 0)
        for c in change:
            Ka, Kc = sorted((piece.K[c], piece.K[c + 1]))
            if Kc < lo - (hi - lo) or Ka > hi + (hi - lo):
                continue

            def f(x: float, sigma: float = piece.sigma) -> float:
                return curves.on_branch(x, sigma)[1] - level

            wa, wc = piece.w[c], piece.w[c + 1]
            fa, fc = f(wa), f(wc)
            if fa * fc > 0:
                continue
            wx = _zero_in(f, wa, wc, fa, fc, 1e-15 * wc)
            events.append(
                GainEnd(curves.on_branch(wx, piece.sigma)[0], "crossing", float(wx), level, delay_accuracy=0.0)
            )
    if not events:
        raise CertificationError(
            f"best_decay_rate: no equation found for the end of the feasible gains in [{lo:.12g}, {hi:.12g}]"
        )
    feasible = curves.gains[i]
    return min(events, key=lambda e: abs(e.K - feasible))


def _unconstrained_rate(
    loop: AffineGainLoop | AffineLoop, lo: float, hi: float, n_rates: int, max_evals: int, rigorous: bool
) -> GainDesign:
    """:func:`best_decay_rate` without a delay requirement: the largest decay rate over ``[lo, hi]``, the loop
    exponentially stable at ``delta = 0`` (its certified count of zeros in ``Re s > 0`` none)."""
    curves = _Curves(_Family(loop), lo, hi, max_evals)
    env = np.where(_nominal_mask(curves), curves.envelope, 0.0)
    best, plateau = _with_plateau(
        curves.loop, _best_rate(curves, [((lo, None), (hi, None))], n_rates, "end"), [(lo, hi)], _scale(curves)
    )
    K, rate, kind, _, sa = best
    cert, how = _certify(curves.loop, K, rigorous, max_evals)
    if not (rate > 0.0 and cert.nominally_stable):
        best_margin(loop, (lo, hi), max_evals=max_evals)  # raises when no gain is stable without delay (certified)
        raise CertificationError(
            f"best_decay_rate: the largest decay rate found, {rate:.6g} at K = {K:.15g}, leaves the loop unstable at "
            "delta = 0, though the scan has stable gains: the rate peaks between the samples; more samples "
            "(n_rates) or narrower bounds about the stable gains would help"
        )
    half = 1e-10 * max(abs(lo), abs(hi), 1e-300)
    K_br = (K - half, K + half) if kind in ("interior smooth max", "kink") else (K, K)
    if plateau is not None:
        K_br = plateau
    return GainDesign(
        K,
        "decay_rate",
        rate,
        cert.margin,
        rate,
        kind,
        K_br,
        _outward((rate, rate), sa.accuracy),
        (lo, hi),
        cert,
        how,
        sa,
        curves.gains,
        env,
        nominal=curves.loop.nominal(K),
    )


@one_blas_thread()
def best_decay_rate(
    loop: AffineGainLoop | AffineLoop,
    bounds: tuple[float, float],
    *,
    margin_at_least: float | None = None,
    delays: tuple[float, float] | None = None,
    scenarios: tuple[AffineGainLoop | AffineLoop, ...] = (),
    worst_case: bool = False,
    rigorous: bool = False,
    n_rates: int = 5,
    max_evals: int = 2_000_000,
) -> GainDesign:
    """The gain in ``[K_lo, K_hi]`` with the largest decay rate among those with ``delta*(K) >= d``.

    The decay rate is ``-alpha(K)``, ``alpha`` the spectral abscissa of the loop at
    ``delta = 0``, ``F(.; 0, K) = A + B_0 + K R``: the paper's trade-off (the remark after
    Lemma 3, section 4.2.1) sets the nominal convergence rate against the delay margin, and
    the constraint ``delta*(K) >= d`` already guarantees exponential stability for every delay
    in ``[0, d)``; the rate at a delay in ``(0, d]`` is another function of ``K``, not the one
    the target system fixes. The feasible gains are where the envelope of the crossing
    curves is at least ``d``; each of their ends is solved from its equation (a curve
    crossing ``d``: :func:`~nrobust.margins.locate_gain_ends`' ``"crossing"``; a pair born with
    delay below ``d``: ``"pair_birth"``) and moved ``1e-10`` (relative) inside. The rate is
    sampled at ``n_rates`` gains of each feasible interval, ends included; when the largest
    sample is an end, that end is the design (``kind`` ``"margin constraint"`` or ``"end"``),
    otherwise the maximum between it and the neighbour toward which the rate rises is solved;
    so it is between any two consecutive samples where the rate rises at the first and falls at
    the second (the rightmost zero's sensitivity ``ds/dK = -F_K / F'``: a peak narrower than the
    samples' spacing), the best taken. The two samples' rightmost zeros are followed in ``K``
    (Newton continuation): where their real parts cross the maximum is a ``"kink"``, where one's
    slope vanishes an ``"interior smooth max"`` (``brentq`` on each equation), kept when the
    certified abscissa there is the zero followed; otherwise Brent's bounded search of the
    abscissa (about the largest sample, between its neighbours). A feasible gain at which the
    nominal loop has no zero at all (one term ``c e^{-h s}``: finite-time convergence, as
    ``U_BS2(K)``'s target system ``1 - (rho - K) q e^{-tau s}`` at ``K = rho``, eqs. (47), (56)-(58))
    has the decay rate ``inf`` and is the design (``kind`` ``"finite time"``): the rate tends to
    ``+inf`` there and is not smooth, so no sampled maximum would be its supremum; one found only up
    to the rounding of the loop's coefficients raises a :class:`~nrobust.errors.CertificationError`.

    With ``delays = (d_min, d_max)`` instead, the requirement is exponential stability for every
    delay of the window (:func:`window_stability`; for ``d_min = 0`` that is ``delta*(K) > d_max``,
    the constraint above): with ``d_min > 0`` the loop may be unstable at ``delta = 0``, and the
    feasible gains are those where no branch ``tau_k(K) = (theta + 2 pi k) / w`` of crossing delays
    lies in ``[d_min, d_max]`` and the count of zeros in ``Re s > 0`` there is 0. Each end of them is
    solved from its equation (a branch through ``d_min`` or ``d_max``: ``"crossing"``; a pair born
    with a delay in the window: ``"pair_birth"``; ``s = 0`` a root for every delay:
    ``"nominal"``), the count checked once per interval, and the decay rate at ``delta = 0``
    maximised over them as above (``kind`` ``"window end"`` at an end). Every loop of
    ``scenarios`` (the same parameter, e.g. the loop on a plant with mismatched data) must meet
    the window too: the feasible set is the intersection, and the design is certified on each
    (:attr:`GainDesign.windows`).

    Without ``margin_at_least`` and ``delays`` the decay rate is maximised over the bounds with no
    delay requirement, the designed loop exponentially stable at ``delta = 0`` (its delay margin,
    possibly 0, is reported).

    Parameters
    ----------
    loop, bounds, rigorous, max_evals
        As in :func:`best_margin`.
    margin_at_least : float, optional
        ``d > 0``: the delay margin required (or ``delays``; neither: no delay requirement).
    delays : (float, float), optional
        ``[d_min, d_max]``: the window of delays on which the loop must be stable
        (``0 <= d_min <= d_max``, ``d_max > 0``); not with ``margin_at_least``.
    scenarios : tuple of AffineGainLoop or AffineLoop, optional
        Further loops of the same parameter that must be stable on the window (with ``delays``).
    worst_case : bool, optional
        With ``delays``: maximise the least decay rate at ``delta = 0`` of the loop and the ``scenarios``,
        ``min_j r_j(K)``, over the feasible gains instead of the loop's own (an end
        of the feasible gains, a peak of one ``r_j``, or a *tie* ``r_i = r_j`` solved by ``brentq``; ``kind``
        ``"tie"``). ``value`` is then that least rate, ``decay_rate`` the loop's own, and
        :attr:`GainDesign.scenario_abscissae` the scenarios' abscissae at the design.
    n_rates : int, optional
        Gains at which the decay rate is sampled in each feasible interval (``>= 2``; with ``worst_case`` at
        least 9, of every loop: a peak or a tie narrower than their spacing can be missed).

    Returns
    -------
    GainDesign
        ``value`` is the decay rate (the least one with ``worst_case``); ``end`` the event at a
        ``"margin constraint"`` optimum.

    Raises
    ------
    ParameterError
        As :func:`best_margin`; ``margin_at_least`` not positive, ``delays`` not a window, both
        given; a requirement no gain of the bounds meets (naming the best achievable:
        the largest margin, or the end of the stability window from ``d_min`` on the scan).
    CertificationError
        No gain in the bounds has ``delta*(K) >= d``, an end could not be solved, the
        certified margin at the design is below ``d`` (the window not certified, with ``delays``),
        the decay rate is unbounded toward a gain no floating-point number reaches, or the search
        about the largest interior sample ends at a smaller rate (the rate not smooth there).
    """
    lo, hi = _checked_loop(loop, bounds)
    if not isinstance(worst_case, (bool, np.bool_)):
        raise ParameterError("worst_case", "True or False", worst_case)
    if worst_case and delays is None:
        raise ParameterError("worst_case", "False without delays (the least rate is over the loop and scenarios)", True)
    if delays is not None or scenarios:
        if margin_at_least is not None:
            raise ParameterError(
                "margin_at_least", "None with delays (the window [0, d] is delta* > d)", margin_at_least
            )
        if delays is None:
            raise ParameterError("delays", "a window [d_min, d_max] with scenarios", None)
        objective = "least_rate" if worst_case else "decay_rate"
        return _window_design(loop, lo, hi, objective, delays, scenarios, n_rates, max_evals, rigorous)
    n_rates = positive_int("n_rates", n_rates, 2)
    max_evals = positive_int("max_evals", max_evals)
    if margin_at_least is None:
        return _unconstrained_rate(loop, lo, hi, n_rates, max_evals, rigorous)
    d = positive("margin_at_least", margin_at_least)
    curves = _Curves(_Family(loop), lo, hi, max_evals)
    env = np.where(_nominal_mask(curves), curves.envelope, 0.0)
    scan = (curves.gains, env)
    ok = env >= d
    if not ok.any():
        top = best_margin(loop, (lo, hi), max_evals=max_evals)
        where = f"at K = {with_accuracy(top.K, top.accuracy[0])}, a {top.kind}"
        if top.value < d:  # the requirement itself cannot be met: the user's input, not the method
            raise ParameterError(
                "margin_at_least",
                f"at most {with_accuracy(top.value, top.accuracy[1])}, the largest delay margin of a gain in "
                f"[{lo:.6g}, {hi:.6g}] ({where})",
                d,
            )
        raise CertificationError(
            f"best_decay_rate: the scan of [{lo:.6g}, {hi:.6g}] found no gain with a delay margin >= {d:g}, "
            f"though the largest margin, {with_accuracy(top.value, top.accuracy[1])} {where}, meets it: the gains "
            "that do lie in a narrower interval than the scan resolves; narrow the bounds about that K"
        )
    scale = max(abs(lo), abs(hi))
    idx = np.flatnonzero(ok)
    intervals: list[tuple[tuple[float, GainEnd | None], tuple[float, GainEnd | None]]] = []
    for run in np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1):
        ends: list[tuple[float, GainEnd | None]] = []
        for k, side in ((run[0], -1), (run[-1], 1)):
            if k + side < 0 or k + side >= curves.gains.size:
                ends.append((float(curves.gains[k]), None))
                continue
            event = _level_end(curves, k, k + side, d)
            ends.append((event.K - side * _OFFSET * scale, event))
        intervals.append((ends[0], ends[1]))
    best, plateau = _with_plateau(
        curves.loop,
        _best_rate(curves, intervals, n_rates, "margin constraint"),
        [(a[0], b[0]) for a, b in intervals],
        scale,
    )
    K, rate, kind, end, sa = best
    cert, how = _certify(curves.loop, K, rigorous, max_evals)
    if not cert.margin >= d:
        raise CertificationError(
            f"best_decay_rate: the certified delay margin at the design K = {K:.15g} is {cert.margin:.15g} < {d:.15g}"
        )
    K_br, v_br = (K, K), (rate, rate)
    if plateau is not None:
        K_br = plateau
    elif end is not None:  # the supremum: the rate at the end itself (not feasible at a pair birth)
        K_br = (min(K, end.K), max(K, end.K))
        at_end = -curves.loop.abscissa(end.K).value
        v_br = (min(rate, at_end), max(rate, at_end))
    elif kind in ("interior smooth max", "kink"):
        K_br = (K - 1e-10 * max(scale, 1e-300), K + 1e-10 * max(scale, 1e-300))
    return GainDesign(
        K,
        "decay_rate",
        rate,
        cert.margin,
        rate,
        kind,
        K_br,
        _outward(v_br, sa.accuracy),
        (lo, hi),
        cert,
        how,
        sa,
        *scan,
        end,
        nominal=curves.loop.nominal(K),
    )
