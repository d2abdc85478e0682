"""The observer term ``G = (1 - Phi) H`` of an output feedback, enclosed with a proven error (constant coefficients).

On the paper's plant (18)-(20) with constant couplings the kernel ``N~`` of eq. (40) and the
law's kernel ``m`` on the measurement's window ``[0, w]`` (``w = 1/mu``;
:mod:`~nrobust.hyperbolic.loops.output_feedback`) are truncated series ``S``, ``S_m`` in ``nu``
with ball coefficients and proven tails: ``|N~ - S| <= b``, ``|N~' - S'| <= b'`` on ``[0, tau]``
(:func:`~nrobust.hyperbolic.loops.exact_form.closed_form_series`; ``m = N~`` for U_BS and U_BS2(K),
``m = k U~`` for a state feedback ``U = k u(t, 1)``; with integral gains ``m = k U~ + e^{sigma nu} K``,
``K`` the branch before ``t_v`` of their kernel as one polynomial with proven tails,
:func:`~nrobust.hyperbolic.loops.exact_gains.window_series`, ``b_m``, ``b_m'`` the sums of the two
kernels' bounds). The law applied to the prediction,
``h = m - m * r`` (``r`` the resolvent of ``N~`` on the window), solves the convolution equation
of the second kind ``h + N~ * h = m`` on ``[0, w]`` (``h + h * N~ = m - m * r + m * N~ - m * (r + r * N~)
= m``), and ``G``'s kernel is

    g = h 1_[0, w] - rho q h(. - tau) + N~ * h      on [0, tau + w],

a polynomial on each of ``[0, w]``, ``[w, tau]`` and ``[tau, tau + w]`` when ``N~`` and ``h`` are.

**The enclosure.** ``h^``, the Taylor polynomial of ``h`` at 0 of degree ``D`` from the triangular
recursion of the equation with ``S``, ``S_m`` (midpoints kept: ``h^`` is a definite polynomial),
has the residual ``R = S_m - h^ - S * h^``, a polynomial computed exactly in ball arithmetic
(``int_0^u f(x) g(u - x) dx`` of two polynomials has the coefficients
``(sum_{i + j = k} f_i i! g_j j!) / (k + 1)!`` of ``u^(k + 1)``). The error ``e = h - h^`` solves
``e + N~ * e = (m - S_m) + R - (N~ - S) * h^``, whose right side is at most
``r_0 = b_m + sup |R| + b ||h^||_1``, so ``|e| <= E = r_0 Gamma`` with ``Gamma`` a bound of the window's
resolvent ("The resolvent" below). Differentiating the equation (``K = sup |N~|`` on the window),
``|e'| <= E' = b_m' + sup |R'| + b sup |h^| + b' ||h^||_1 + (K + w K') E`` (``K' = sup |N~'|``).

**The resolvent.** Gronwall's lemma gives ``Gamma = e^{K w}``, which grows as ``e^{sqrt|kappa|}`` and, times
the tail ``b`` of ``N~``'s series, fails the target near ``|kappa| = 36``. Sharper: ``r^``, the Taylor polynomial of
the resolvent ``r`` (``r + N~ * r = N~``, the ``h`` of ``m = N~``) from the same recursion, has the defect
``delta = N~ - r^ - N~ * r^ = (S - r^ - S * r^) + (N~ - S) - (N~ - S) * r^``, at most
``d = sup |S - r^ - S * r^| + b + b ||r^||_1``. Convolving ``e + N~ * e = f`` with ``r^`` and subtracting
(convolutions commute), ``e + delta * e = f - r^ * f``, so by Gronwall's lemma
``|e| <= sup |f| (1 + ||r^||_1) e^{w d}``. ``Gamma`` is Gronwall's where that reaches the target (weak
couplings: it is cheaper), otherwise the smaller of the two, about ``sup |r|`` instead of
``e^{K w}`` (``10^4.6`` against ``10^20`` on ``(1, 1, 6, 6, 1, 0.85)``, ``kappa = -36``). The part
``b_m + b ||h^||_1`` of ``r_0`` does not fall with the degree of ``h^``: once ``sup |R|`` is below it and it
leaves ``E`` above :data:`WINDOW_TARGET`, no degree helps and the enclosure refuses at once. On
``(1, 1, k, k, 0.5, 0.5)`` the accuracy of ``G`` is about ``2^-50`` of its size: ``2.9e-13`` at ``k = 5``,
``1.2e-12`` at ``k = 6``, ``1.4e-6`` at ``k = 12``, ``2e5`` at ``k = 20``; at ``k = 25`` (``h`` reaches
``10^19``) it refuses. Couplings beyond the closed form's work bound
(:data:`~nrobust.hyperbolic.loops.exact_form.KAPPA_MAX`) are refused before the work.

``g^``, the kernel above with ``S``, ``h^`` and the ball of ``rho q`` from the user's numbers
(:func:`~nrobust.hyperbolic.loops.exact_form.gain_balls`), is exact polynomial algebra
(the convolution on ``[w, tau]`` and ``[tau, tau + w]`` from the one on ``[0, nu]`` with ``h^``
and ``S`` shifted), and ``g - g^ = e 1 - rho q e(. - tau) + S * e + (N~ - S) * h``, so::

    |g - g^|  <= E (1 + |rho q| + ||S||_1) + b w (sup |h^| + E),
    |g - g^|' <= E' (1 + |rho q|) + (2 sup |S| + ||S'||_1) E + (2 b + b' w) (sup |h^| + E)

(sups and ``L1`` norms on ``[0, tau]`` for ``S``, on ``[0, w]`` for ``h^``; the sup of a polynomial
on ``[0, L]`` bounded by the sums of the moduli of its coefficients on :data:`SUP_PIECES` pieces).
Each interval's ``g^`` is expanded on equal segments into polynomials of degree :data:`DEGREE`
rounded to doubles, the dropped and rounded coefficients (with the balls' radii) bounding each
piece's error; segments are doubled until that error is below :data:`TARGET` times the kernel's
size. Each stored term carries ``radius = |g - g^| + `` its pieces' largest error and
``variation_radius`` = its length times the bound of ``|g - g^|'`` plus three times the sum of its
pieces' errors (their variation and the jumps between them): every ball enclosure of the loop built
on ``G`` includes the PDE's own term.

**General plants.** A :class:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2` with constant
coefficients has ``N~ = e^{sigma nu} N~_0`` and ``U~ = e^{sigma nu} U~_0`` (``sigma = sigma_0`` of
:mod:`~nrobust.hyperbolic.loops.exact_form`, from the exact rational ``sigma_0 tau``), the window
``1/mu`` of its normal form and ``rho q e^{sigma_0 tau}`` for ``rho q``: ``S`` is the series times the
Taylor polynomial ``E`` of ``e^{sigma nu}`` with :data:`_EXP_TERMS` terms, whose remainder on ``[0, tau]``
is at most ``r = |sigma tau|^n / n! e^{|sigma| tau}`` (``r' = |sigma| |sigma tau|^(n-1) / (n-1)! e^{|sigma| tau}``
for the derivative), so ``b`` becomes ``e^{|sigma| tau} b + sup |S_0| r`` and ``b'`` becomes
``e^{|sigma| tau} (|sigma| b + b') + sup |S_0'| r + sup |S_0| r'``.

What stays a double is what the state feedback's exact loop takes as such: ``tau`` and the window
``1/mu`` (nodes of the loop). With integral gains the window must not pass the time of flight ``t_v`` of the
gains' kernel (``tau_d lam / (lam + mu)`` exactly, where it jumps): where the double ``1/mu`` lies above it
(rounding), the window is the largest double not above ``t_v`` (:func:`proof_window`; the scope prints it).
The nodes of the stored terms are doubles whose differences are exact (checked; Sterbenz's lemma on
segments no longer than the interval's start), each piece expanded from its own nodes. Where ``tau + w`` is
not a double the last interval ends at the double below it, and a term of zero kernel on the next ulp holds
the rest of ``g`` with the radius ``(|rho q| + (sup |S| + b) w) (sup |h^| + E)`` (a bound of ``|g|`` there)
and the variation that plus the ulp times a bound of ``|g'|``, as the jump of an integral gain's kernel is
held (:mod:`~nrobust.hyperbolic.loops.exact_gains`).

**The collocated observer.** Under ``StateFeedback(k)`` the collocated observer's loop is made of
``(1 - Phi) u_factor`` and ``u_factor^2`` (:mod:`~nrobust.hyperbolic.loops.collocated`, "Closed forms"),
products of two factors ``c_0 + c_tau e^{-tau s} + int_0^tau f e^{-nu s}`` and
``d_0 + d_tau e^{-tau s} + int_0^tau g e^{-nu s}`` whose kernels are the series ``S``, ``R`` of ``N~`` and
``U~`` with tails ``|f - S| <= b``, ``|g - R| <= e`` (and ``b'``, ``e'`` for the derivatives). The
product's kernel is ``c_0 g + d_0 f + f * g`` on ``[0, tau]`` and ``c_tau g + d_tau f + f * g`` on
``[tau, 2 tau]``; there, with ``C = S * R`` the convolution of the polynomials continued past ``tau``,
``(S * R)(tau + v) = C(tau + v) - (S * R(tau + .))(v) - (S(tau + .) * R)(v)``, exact polynomial algebra.
``|f * g - S * R| <= tau (b (sup |R| + e) + sup |S| e)``; the derivative of a convolution is a product of
values plus ``f * g'``, so its error is at most ``b (sup |R| + e) + sup |S| e + tau (b (sup |R'| + e') +
sup |S| e')``; the point parts add ``|c| e + |d| b`` and ``|c| e' + |d| b'``. Each interval is stored as
``G``'s are, and the point coefficients ``c_0 d_0``, ``c_0 d_tau + c_tau d_0``, ``c_tau d_tau`` (balls of
the user's numbers) as doubles with their radii.

**Ends that are not doubles.** Under U_BS2(K) and U_BS the collocated observer's ``C_u`` has the kernel
``c`` of :func:`~nrobust.hyperbolic.loops.collocated_proof.response_pieces`, a polynomial on each piece between
``0, t_u = 1/lam, t_v = 1/mu, tau`` (exact rationals of the user's doubles), and ``G``'s kernel one on each piece
between those ends and them plus ``tau``. The loop is built with ``tau_d``, the double ``tau`` rounds to, so that
proofs about it map to the plant as given by ``r = tau / tau_d``
(:mod:`~nrobust.hyperbolic.loops.given_plant`): ``C_u`` of the plant at ``s`` is that of the loop as built at
``r s``, whose kernel is ``r c(r nu)`` on ``[0, tau_d]`` (``nu -> r nu`` in the Laplace integral), with the ends
``t_j / r`` (exact rationals, ``tau / r = tau_d``), each piece ``r P_j(r u)`` and the bounds ``r e``, ``r^2 e'``.
``G``'s pieces are computed on the true ends (balls of the rationals: the convolution's limits, the shifts of
``c``'s pieces) and stored from nodes that are doubles: each end itself where it is one, otherwise the nearest
multiple of ``U = ulp(2 tau_d)`` (whose sums with the segments' steps are exact below ``2 tau_d``). Between a node
and its true end (at most ``U / 2``) the stored kernel is the neighbouring piece's polynomial; a term of zero
kernel on the ``U`` between the node and the next multiple past the end holds that: its ``radius`` is
``J = |P_left - P_right|`` enclosed on that ulp plus the stored kernel's radius (the true kernel there is one piece
within its bound, the stored one the other piece within its rounding), and its ``variation_radius`` is ``J`` (the
jump at the end), the kernel's variation, twice its radius (the kernel's error, taken as zero between node and end,
jumps at both) and ``U |P_left' - P_right'|`` there. The pieces of ``G`` are continuous or nearly so at these ends
(``J`` is about the kernel's radius on the plants of the tests), so an enclosure widens by about ``J U``. Ends
within two ulps of each other are refused (:class:`~nrobust.errors.CertificationError`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
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
from .collocated_proof import polynomial_integral, response_pieces
from .exact_form import (
    KAPPA_MAX,
    closed_form_parameters,
    closed_form_series,
    exact_ratios,
    gain_balls,
    has_exact_form,
    rational_ball,
    tau_ratio,
)
from .exact_gains import gain_plant, window_series, zero_term

__all__ = [
    "DEGREE",
    "TARGET",
    "ProvenCollocatedProducts",
    "ProvenObserverTerm",
    "proven_collocated_failure",
    "proven_collocated_products",
    "proven_observer_failure",
    "proven_observer_term",
    "proven_response_failure",
    "proven_response_product",
    "proof_window",
    "window",
]

#: Degree of the stored polynomial pieces of ``G``.
DEGREE = 11
#: Largest error of a stored piece, relative to the largest ``sum |P_j|`` of the pieces (plus ``2^-60``).
TARGET = 2.0**-50
#: Segments per window length at first, and the most segments per window length tried.
SEGMENTS, MAX_SEGMENTS = 8, 256
#: Degrees of the Taylor polynomial ``h^`` tried in turn, beyond the degree of ``S``.
EXTRA_DEGREES = (24, 48, 96, 192)
#: Largest proven error of ``h^`` accepted, relative to ``sup |h^|`` (plus ``2^-60``).
WINDOW_TARGET = 2.0**-48
#: Pieces of ``[0, L]`` on which the sup of a polynomial is bounded (the monomial sum on all of it overstates
#: it by the cancellation of a strongly coupled kernel's coefficients).
SUP_PIECES = 16
# Terms of the Taylor polynomial of e^{sigma nu} (a general plant's weight), its remainder bounded in _weighted.
_EXP_TERMS = 60
# Working precision (bits) of the ball arithmetic.
_PRECISION = 256


@dataclass(frozen=True)
class ProvenObserverTerm:
    """``G = (1 - Phi) H`` with proven error bounds (module notes).

    Attributes
    ----------
    product : QuasiPolynomial
        ``G``: one distributed term of polynomial pieces per interval ``[0, w]``, ``[w, tau]``,
        ``[tau, tau + w]`` (and the term on the ulp past it, module notes), each with ``radius`` and
        ``variation_radius`` bounding the distance of its kernel to the PDE's (sup and total variation).
    accuracy : float
        The largest ``radius`` of the three intervals' terms: a proven sup-norm bound of the stored
        kernel's error (a term on the ulp past ``tau + w``, when ``tau + w`` is not a double, holds
        the kernel's value there: its radius is that value's bound, module notes).
    window_error : float
        ``E``, the proven bound of ``|h - h^|`` on the window.
    """

    product: QuasiPolynomial
    accuracy: float
    window_error: float


def proven_observer_failure(
    system: Any, law: tuple[str, float] | None, gains: tuple[Any, Any] = (0.0, 0.0)
) -> str | None:
    """Why :func:`proven_observer_term` cannot enclose ``G`` for this plant and law (None when it can).

    Parameters
    ----------
    system : Any
        The plant.
    law : tuple of (str, float) or None
        The law's kernel on the window: ``("N", c)`` for ``m = c N~``, ``("U", c)`` for ``m = c U~``;
        None for a law the enclosure does not cover.
    gains : tuple, default (0.0, 0.0)
        The integral gains ``(g_u, g_v)`` of a state feedback, whose kernel adds to ``m``.
    """
    if law is None:
        return "a law whose kernel on the window is not c N~ or c U~ (plus the kernel of integral gains)"
    law = _checked_law(law)
    if not _covered(system):
        if _constant(system):
            return (
                f"a coupling |kappa| = |p m| beyond the closed form's work bound {KAPPA_MAX:g} "
                "(exact_form.KAPPA_MAX): a weaker coupling would help"
            )
        return "a plant other than Hyperbolic2x2 or GeneralHyperbolic2x2 with constant coefficients"
    out = _cached_attempt(system, law, gains)
    return out if isinstance(out, str) else None


#: What :func:`proven_observer_term` covers (its ``ParameterError``'s admissible range).
_COVERED = (
    "a Hyperbolic2x2 or GeneralHyperbolic2x2 with constant coefficients (constant lam/mu) and a coupling "
    f"|kappa| = |p m| <= {KAPPA_MAX:g} (the closed form's work bound: a weaker coupling would help)"
)


def _constant(system: Any) -> bool:
    """True for a plant with constant coefficients (whatever its coupling)."""
    if isinstance(system, GeneralHyperbolic2x2):
        return system.constant_ratio and all(system.is_constant(k) for k in ("lam", "mu", "a", "b", "c", "d"))
    return isinstance(system, Hyperbolic2x2) and system.constant_couplings


def _covered(system: Any) -> bool:
    """True for the plants the enclosure covers: :class:`Hyperbolic2x2` with constant couplings, or a
    :class:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2` with constant coefficients."""
    if isinstance(system, GeneralHyperbolic2x2):
        return system.constant_ratio and has_exact_form(system)
    return isinstance(system, Hyperbolic2x2) and system.constant_couplings and has_exact_form(system)


def window(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> float:
    """The measurement's window ``w = 1/mu`` (of the normal form for a general plant), as the loop takes it."""
    plant = system.normal_form().system if isinstance(system, GeneralHyperbolic2x2) else system
    return 1.0 / plant.mu


def proof_window(system: Hyperbolic2x2 | GeneralHyperbolic2x2, gains: tuple[Any, Any] = (0.0, 0.0)) -> float:
    """The window :func:`proven_observer_term` builds ``G`` on: :func:`window`, or with integral gains whose kernel
    jumps below it (its ``t_v = tau_d lam / (lam + mu)`` exactly, rounding), the largest double not above ``t_v``
    (module notes)."""
    w = window(system)
    if all(not callable(g) and float(g) == 0.0 for g in gains):
        return w
    t_v = gain_plant(system, exact_times=True).t_v
    if Fraction(w) <= t_v:
        return w
    below = float(t_v)
    return math.nextafter(below, -math.inf) if Fraction(below) > t_v else below


def _checked_law(law: Any) -> tuple[str, float]:
    """``law`` as ``(kind, c)``, or a :class:`~nrobust.errors.ParameterError`."""
    admissible = '("N" or "U", a finite real c): the law\'s kernel c N~ or c U~ on the window'
    if not (isinstance(law, tuple) and len(law) == 2 and law[0] in ("N", "U")):
        raise ParameterError("law", admissible, law)
    c = law[1]
    if isinstance(c, bool) or not isinstance(c, (int, float, np.integer, np.floating)) or not math.isfinite(c):
        raise ParameterError("law", admissible, law)
    return (law[0], float(c))


def proven_observer_term(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2, law: tuple[str, float], gains: tuple[Any, Any] = (0.0, 0.0)
) -> ProvenObserverTerm:
    """``G`` of an output feedback on a plant with constant coefficients, with proven error bounds (module notes).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The paper's plant with constant couplings, or a general plant with constant coefficients.
    law : tuple of (str, float)
        ``("N", c)`` when the law's kernel on the window is ``m = c N~`` (U_BS, U_BS2(K): ``c = 1``),
        ``("U", c)`` when ``m = c U~`` (a state feedback ``U = c u(t, 1)``).
    gains : tuple, default (0.0, 0.0)
        The integral gains ``(g_u, g_v)`` of ``StateFeedback(c, g_u, g_v)`` (numbers or callables, as for
        :func:`~nrobust.hyperbolic.loops.exact_gains.gain_terms`): their kernel ``e^{sigma nu} K`` adds to
        ``m`` (:func:`~nrobust.hyperbolic.loops.exact_gains.window_series`).

    Raises
    ------
    ParameterError
        ``system`` not a plant with constant coefficients (:func:`proven_observer_failure`), ``law``
        not ``("N" | "U", c)`` with ``c`` finite, or ``gains`` not two gains finite on ``[0, L]``.
    CertificationError
        :func:`proven_observer_failure` is not None (the reason).
    """
    law = _checked_law(law)
    if not _covered(system):
        raise ParameterError("system", _COVERED, system)
    reason = proven_observer_failure(system, law, gains)
    if reason is not None:
        raise CertificationError(f"proven_observer_term: {reason}; the observer's term is computed in floating point")
    out = _cached_attempt(system, law, gains)
    assert isinstance(out, ProvenObserverTerm)
    return out


def _cached_attempt(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2, law: tuple[str, float], gains: tuple[Any, Any]
) -> ProvenObserverTerm | str:
    """:func:`_attempt`, cached unless a gain is unhashable (a ParameterError for gains that are not two gains)."""
    if not (isinstance(gains, tuple) and len(gains) == 2):
        raise ParameterError("gains", "a pair (g_u, g_v) of integral gains (numbers or callables)", gains)
    try:
        hash(gains)
    except TypeError:
        return _attempt.__wrapped__(system, law, gains)
    return _attempt(system, law, gains)


@lru_cache(maxsize=16)
def _attempt(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2, law: tuple[str, float], gains: tuple[Any, Any]
) -> ProvenObserverTerm | str:
    """The enclosure, or the reason it failed."""
    tau, w = closed_form_parameters(system)[0], proof_window(system, gains)
    return _in_balls(system, lambda flint: _enclose(flint, system, law, gains, tau, w))


def _in_balls(system: Hyperbolic2x2 | GeneralHyperbolic2x2, enclose: Callable[[Any], Any]) -> Any:
    """``enclose(flint)`` at the working precision of the plant's couplings, or the reason it failed (a string)."""
    try:
        flint = require_flint()
    except ImportError:
        return "no ball arithmetic (python-flint is not installed)"
    p, m, _ = exact_ratios(system)
    try:
        with precision(flint, _PRECISION + math.ceil(12.0 * math.sqrt(abs(float(p * m))))):
            return enclose(flint)
    except CertificationError as exc:
        return str(exc)


class _Poly:
    """Helpers of exact polynomial algebra on ``arb_poly`` (factorials cached)."""

    def __init__(self, flint: Any) -> None:
        self.flint = flint
        self.arb, self.arb_poly = flint.arb, flint.arb_poly
        self._fact = [flint.arb(1)]

    def fact(self, k: int) -> Any:
        while len(self._fact) <= k:
            self._fact.append(self._fact[-1] * len(self._fact))
        return self._fact[k]

    def coeffs(self, p: Any) -> list[Any]:
        return list(p.coeffs())

    def conv(self, f: Any, g: Any) -> Any:
        """``u -> int_0^u f(x) g(u - x) dx`` (exact)."""
        fc, gc = self.coeffs(f), self.coeffs(g)
        if not fc or not gc:
            return self.arb_poly([0])
        F = self.arb_poly([c * self.fact(j) for j, c in enumerate(fc)])
        G = self.arb_poly([c * self.fact(j) for j, c in enumerate(gc)])
        P = self.coeffs(F * G)
        return self.arb_poly([self.arb(0)] + [c / self.fact(k + 1) for k, c in enumerate(P)])

    def shift(self, p: Any, a: Any) -> Any:
        """``x -> p(a + x)``."""
        return p(self.arb_poly([a, self.arb(1)]))

    def sup(self, p: Any, length: Any) -> Any:
        """An upper bound of ``|p|`` on ``[0, length]``: the largest ``sum_k |c_k|`` of ``p`` on :data:`SUP_PIECES`
        equal pieces, each in its variable ``t`` in ``[0, 1]``."""
        width = length / SUP_PIECES
        out = self.arb(0)
        for j in range(SUP_PIECES):
            local = self.coeffs(p(self.arb_poly([width * j, width])))
            out = self.arb.max(out, sum((abs(c) for c in local), self.arb(0)))
        return self.arb(out.upper())


def _taylor(poly: _Poly, S: Any, Sm: Any, degree: int) -> Any:
    """The Taylor polynomial of degree ``degree`` at 0 of ``h``, ``h + S * h = S_m`` (midpoints kept).

    With ``d_k = k! h_k``: ``d_k = k! m_k - sum_{j < k} (k - 1 - j)! S_{k-1-j} d_j``.
    """
    arb = poly.arb
    s = poly.coeffs(S)
    fs = [c * poly.fact(i) for i, c in enumerate(s)]
    mc = poly.coeffs(Sm)
    d: list[Any] = []
    for k in range(degree + 1):
        value = (mc[k] if k < len(mc) else arb(0)) * poly.fact(k)
        for j in range(max(0, k - len(fs)), k):
            value -= fs[k - 1 - j] * d[j]
        d.append(value)
    return poly.arb_poly([arb((d[k] / poly.fact(k)).mid()) for k in range(degree + 1)])


def _text(x: Any) -> str:
    """An upper bound of the ball ``x`` in two digits (beyond the range of doubles too)."""
    return str(x.upper().str(2, radius=False))


def _resolvent_gain(poly: _Poly, S: Any, b: Any, K: Any, W: Any, degree: int) -> Any:
    """A bound of ``sup |e| / sup |f|`` on ``[0, w]`` for ``e + N~ * e = f`` (module notes, "The resolvent").

    The smaller of Gronwall's ``e^{K w}`` and ``(1 + ||r^||_1) e^{w d}``, with ``r^`` the Taylor polynomial of
    degree ``degree`` of the resolvent (``r + N~ * r = N~``) and ``d`` the bound of its defect.
    """
    r = _taylor(poly, S, S, degree)
    r_l1 = poly.sup(r, W) * W
    defect = poly.sup(S - r - poly.conv(r, S), W) + b + b * r_l1
    return poly.arb.min((K * W).exp(), (1 + r_l1) * (W * defect).exp())


def _weighted(poly: _Poly, series: Any, bound: Any, dbound: Any, sigma: Any, T: Any) -> tuple[Any, Any, Any]:
    """``e^{sigma nu}`` times a series and its tail bounds on ``[0, T]`` (module notes, "General plants")."""
    if sigma.is_zero():
        return series, bound, dbound
    arb = poly.arb
    E = poly.arb_poly([sigma**j / poly.fact(j) for j in range(_EXP_TERMS)])
    grow = (abs(sigma) * T).exp()
    x = abs(sigma) * T
    rest = x**_EXP_TERMS / poly.fact(_EXP_TERMS) * grow  # |e^{sigma nu} - E| on [0, tau]
    drest = abs(sigma) * x ** (_EXP_TERMS - 1) / poly.fact(_EXP_TERMS - 1) * grow
    sup, dsup = poly.sup(series, T), poly.sup(series.derivative(), T)
    new_bound = grow * bound + sup * rest
    new_dbound = grow * (abs(sigma) * bound + dbound) + dsup * rest + sup * drest
    return series * E, arb(new_bound.upper()), arb(new_dbound.upper())


def _enclose(
    flint: Any,
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    law: tuple[str, float],
    gains: tuple[Any, Any],
    tau: float,
    w: float,
) -> ProvenObserverTerm:
    """:func:`proven_observer_term` at the working precision."""
    poly = _Poly(flint)
    arb = flint.arb
    _, _, _, q, rho, _ = closed_form_parameters(system)
    p_ratio, m_ratio, shift = exact_ratios(system)
    T, W = arb(tau), arb(w)
    P = arb(p_ratio.numerator) / arb(p_ratio.denominator)
    M = arb(m_ratio.numerator) / arb(m_ratio.denominator)
    sigma = arb(shift.numerator) / arb(shift.denominator) / T
    S, b, db = _weighted(poly, *closed_form_series(flint, T, P, M, ("N", q, rho)), sigma, T)
    Sm, bm, dbm = _weighted(poly, *closed_form_series(flint, T, P, M, (law[0], q, rho)), sigma, T)
    c = arb(float(law[1]))
    Sm, bm, dbm = Sm * c, bm * abs(c), dbm * abs(c)
    integral = window_series(flint, system, *gains, w)
    if integral is not None:  # the gains' kernel e^{sigma nu} K on the window, bounded there
        Sg, bg, dbg = _weighted(poly, *integral, sigma, W)
        Sm, bm, dbm = Sm + Sg, bm + bg, dbm + dbg
    if all(x.is_zero() for x in poly.coeffs(Sm)) and bool(bm == 0):
        raise CertificationError("the law reads no value of the window (G = 0: no term to enclose)")
    rho_q = gain_balls(system)[1]
    # norms of S on [0, w] and [0, tau]
    K = poly.sup(S, W) + b
    dK = poly.sup(S.derivative(), W) + db
    S_sup = poly.sup(S, T)
    S_l1 = S_sup * T
    dS_l1 = poly.sup(S.derivative(), T) * T
    h = R = None
    E = arb("inf")
    for extra in EXTRA_DEGREES:
        degree = len(poly.coeffs(S)) + extra
        h = _taylor(poly, S, Sm, degree)
        R = Sm - h - poly.conv(h, S)
        h_sup = poly.sup(h, W)
        R_sup = poly.sup(R, W)
        r0 = bm + R_sup + b * W * h_sup
        gain = (K * W).exp()  # Gronwall's bound first: enough on weak couplings, and cheaper
        if not bool(r0 * gain < WINDOW_TARGET * h_sup + arb(2.0**-60)):
            gain = _resolvent_gain(poly, S, b, K, W, degree)
        E = arb((r0 * gain).upper())
        if bool(E < WINDOW_TARGET * h_sup + arb(2.0**-60)):
            break
        floor = bm + b * W * h_sup  # the part of r_0 no degree lowers, once sup |R| is below it
        stuck = gain.is_finite() and bool(R_sup <= floor)
        if stuck and bool(floor * gain >= WINDOW_TARGET * h_sup + arb(2.0**-60)):
            raise CertificationError(
                f"the observer's kernel h on the window reaches {_text(h_sup)}: the tail {_text(b)} of N~'s "
                f"closed-form series, amplified by the window's resolvent ({_text(gain)}), leaves an error above "
                f"{WINDOW_TARGET:.0e} relative to h at any degree (a coupling too strong: more terms of N~'s series "
                f"would help, and G would still carry about {TARGET:.0e} of its size in double precision)"
            )
    else:
        raise CertificationError(
            f"the Taylor polynomial of the observer's kernel h on the window does not reach {WINDOW_TARGET:.0e} "
            f"with degree {len(poly.coeffs(S)) + EXTRA_DEGREES[-1]} (a coupling too strong for one polynomial)"
        )
    assert h is not None and R is not None
    dE = dbm + poly.sup(R.derivative(), W) + b * h_sup + db * W * h_sup + (K + W * dK) * E
    h_bound = h_sup + E
    sup_err = E * (1 + abs(rho_q) + S_l1) + b * W * h_bound
    slope = dE * (1 + abs(rho_q)) + (2 * S_sup + dS_l1) * E + (2 * b + db * W) * h_bound
    # g^ on the three intervals, each in its local variable from the interval's start
    C = poly.conv(h, S)
    g1 = h + C
    g2 = poly.shift(C, W) - poly.conv(poly.shift(h, W), S)
    g3 = -rho_q * h + poly.shift(g2, T - W) - poly.conv(h, poly.shift(S, T))
    end = tau + w
    if Fraction(end) > Fraction(tau) + Fraction(w):
        end = math.nextafter(end, -math.inf)
    intervals = ((0.0, w, g1), (w, tau, g2), (tau, end, g3))
    terms = [_store(flint, g, lo, hi, w, sup_err, slope) for lo, hi, g in intervals]
    if Fraction(end) != Fraction(tau) + Fraction(w):  # the rest of g, on (end, tau + w], held by a proven term
        g_sup = (abs(rho_q) + (S_sup + b) * W) * h_bound
        dh = poly.sup(h.derivative(), W) + dE
        g_slope = abs(rho_q) * dh + (S_sup + b) * h_bound + (poly.sup(S.derivative(), T) + db) * W * h_bound
        after = math.nextafter(end, math.inf)
        variation = g_sup + (arb(after) - arb(end)) * g_slope
        terms.append(
            DistributedDelay(
                np.array([end, after]),
                None,
                interpolation="polynomial",
                coefficients=np.zeros((1, 1)),
                radius=math.nextafter(float(g_sup.upper()), math.inf),
                variation_radius=math.nextafter(float(variation.upper()), math.inf),
            )
        )
    accuracy = max(t.radius for t in terms[:3])
    return ProvenObserverTerm(QuasiPolynomial([], [], terms), accuracy, ball_upper(E))


def _nodes(lo: float, hi: float, step: float) -> list[float] | None:
    """``lo, lo + step, ...`` (rounded) below ``hi``, then ``hi``: None unless every difference is exact."""
    count = max(1, math.ceil((hi - lo) / step - 1e-9))
    nodes = [lo + j * step for j in range(count)] + [hi]
    if any(Fraction(b - a) != Fraction(b) - Fraction(a) or not a < b for a, b in itertools.pairwise(nodes)):
        return None
    return nodes


def _store(flint: Any, g: Any, lo: float, hi: float, w: float, sup_err: Any, slope: Any) -> DistributedDelay:
    """The interval's ``g^`` (in ``nu - lo``) as pieces of degree :data:`DEGREE` on equal segments, proven bounds."""
    return _store_counted(flint, g, lo, hi, w, sup_err, slope, SEGMENTS)[0]


def _store_counted(
    flint: Any, g: Any, lo: float, hi: float, w: float, sup_err: Any, slope: Any, segments: int
) -> tuple[DistributedDelay, int]:
    """:func:`_store` with ``segments`` per ``w`` at first (doubled until the pieces reach the target), and the
    segments per ``w`` it took."""
    arb, arb_poly = flint.arb, flint.arb_poly
    while segments <= MAX_SEGMENTS:
        mant, expo = math.frexp(w / segments)
        step = math.ldexp(math.floor(mant * 2**40) / 2**40, expo)
        nodes = _nodes(lo, hi, step)
        if nodes is None:
            raise CertificationError(f"the nodes of G on [{lo!r}, {hi!r}] are not exact in double precision")
        heads, errors, sizes = [], [], []
        for a, b in itertools.pairwise(nodes):
            offset, width = arb(a) - arb(lo), arb(b) - arb(a)
            local = list(g(arb_poly([offset, width])).coeffs())
            head = [float(x.mid()) for x in local[: DEGREE + 1]] + [0.0] * max(0, DEGREE + 1 - len(local))
            error = sum((abs(x - arb(y)) for x, y in zip(local[: DEGREE + 1], head)), arb(0))
            error += sum((abs(x) for x in local[DEGREE + 1 :]), arb(0))
            heads.append(head)
            errors.append(error)
            sizes.append(sum((abs(y) for y in head), 0.0))
        threshold = arb(TARGET * max(sizes)) + arb(2.0**-60)
        if all(bool(e < threshold) for e in errors):
            break
        segments *= 2
    else:
        raise CertificationError(
            f"G needs more than {MAX_SEGMENTS} pieces per window of degree {DEGREE} to reach double precision"
        )
    largest = arb(0)
    for e in errors:
        largest = arb.max(largest, e)
    total = sum(errors, arb(0))
    radius = sup_err + largest
    variation = slope * (arb(hi) - arb(lo)) + 3 * total
    term = DistributedDelay(
        np.asarray(nodes),
        None,
        interpolation="polynomial",
        coefficients=np.asarray(heads),
        radius=math.nextafter(float(radius.upper()), math.inf),
        variation_radius=math.nextafter(float(variation.upper()), math.inf),
    )
    return term, segments


@dataclass(frozen=True)
class ProvenCollocatedProducts:
    """The products of closed forms that make the collocated observer's loop, with proven error bounds.

    On the paper's plant with constant couplings the collocated observer's responses are closed
    forms (:mod:`~nrobust.hyperbolic.loops.collocated`): ``H_y = u_factor = q e^{-tau s} +
    int_0^tau U~(nu) e^{-nu s} dnu``, and for ``StateFeedback(k)`` ``C_u = k H_y``. Its loop is then
    made of the two products below (module notes, "The collocated observer").

    Attributes
    ----------
    open_loop_product : QuasiPolynomial
        ``(1 - Phi) u_factor``.
    square : QuasiPolynomial
        ``u_factor^2``.
    """

    open_loop_product: QuasiPolynomial
    square: QuasiPolynomial


def proven_collocated_products(system: Hyperbolic2x2) -> ProvenCollocatedProducts:
    """``(1 - Phi) u_factor`` and ``u_factor^2`` with proven error bounds (module notes, "The collocated observer").

    Parameters
    ----------
    system : Hyperbolic2x2
        The paper's plant with constant couplings (and the closed form of
        :func:`~nrobust.hyperbolic.loops.exact_form.has_exact_form`).

    Raises
    ------
    ParameterError
        ``system`` is not such a plant.
    CertificationError
        No ball arithmetic (python-flint), or the products' pieces cannot be stored to double precision.
    """
    if not _collocated_covered(system):
        raise ParameterError("system", "a Hyperbolic2x2 with constant couplings (the closed form of the loop)", system)
    out = _collocated_attempt(system)
    if isinstance(out, str):
        raise CertificationError(f"proven_collocated_products: {out}; the collocated observer's terms are a model")
    return out


def proven_collocated_failure(system: Any) -> str | None:
    """Why :func:`proven_collocated_products` cannot enclose the products for ``system`` (None when it can)."""
    if not _collocated_covered(system):
        return "a plant other than Hyperbolic2x2 with constant couplings"
    out = _collocated_attempt(system)
    return out if isinstance(out, str) else None


def _collocated_covered(system: Any) -> bool:
    """True for the plants whose collocated observer has closed-form responses: :class:`Hyperbolic2x2` with constant
    couplings (a general plant's normal form is refused by the collocated observer's caller)."""
    return isinstance(system, Hyperbolic2x2) and system.constant_couplings and has_exact_form(system)


@lru_cache(maxsize=8)
def _collocated_attempt(system: Hyperbolic2x2) -> ProvenCollocatedProducts | str:
    """:func:`proven_collocated_products`, or the reason it failed."""
    return _in_balls(system, lambda flint: _collocated_enclose(flint, system))


def _closed_forms(flint: Any, system: Hyperbolic2x2) -> tuple[float, tuple[Any, ...], tuple[Any, ...]]:
    """``tau`` and ``1 - Phi``, ``u_factor`` as ``(c_0, c_tau, S, b, b')`` (:func:`_proven_product`)."""
    arb = flint.arb
    tau, _, _, q, rho, _ = closed_form_parameters(system)
    p_ratio, m_ratio, _ = exact_ratios(system)
    T = arb(tau)
    P = arb(p_ratio.numerator) / arb(p_ratio.denominator)
    M = arb(m_ratio.numerator) / arb(m_ratio.denominator)
    _, rho_q, q_ball = gain_balls(system)
    open_loop = (arb(1), -rho_q, *closed_form_series(flint, T, P, M, ("N", q, rho)))
    u_factor = (arb(0), q_ball, *closed_form_series(flint, T, P, M, ("U", q, rho)))
    return tau, open_loop, u_factor


def _collocated_enclose(flint: Any, system: Hyperbolic2x2) -> ProvenCollocatedProducts:
    """:func:`proven_collocated_products` at the working precision."""
    poly = _Poly(flint)
    tau, open_loop, u_factor = _closed_forms(flint, system)
    return ProvenCollocatedProducts(
        _proven_product(flint, poly, tau, open_loop, u_factor), _proven_product(flint, poly, tau, u_factor, u_factor)
    )


def _proven_product(flint: Any, poly: _Poly, tau: float, f: tuple[Any, ...], g: tuple[Any, ...]) -> QuasiPolynomial:
    """The product of ``c_0 + c_tau e^{-tau s} + int_0^tau S e^{-nu s}`` (tail bounds ``b``, ``b'``) by another.

    ``f = (c_0, c_tau, S, b, b')``. The point terms ``c_0 d_0``, ``c_0 d_tau + c_tau d_0`` (at ``tau``) and
    ``c_tau d_tau`` (at ``2 tau``) are stored as doubles with the radii of their balls; the kernel is
    ``c_0 T + d_0 S + S * T`` on ``[0, tau]`` and ``c_tau T + d_tau S + S * T`` on ``[tau, 2 tau]`` (in
    ``v = nu - tau``), the convolution of the polynomials extended past ``tau`` less the parts beyond
    (module notes, "The collocated observer").
    """
    arb = flint.arb
    c0, ct, S, b, db = f
    d0, dt, R, e, de = g
    Tb = arb(tau)
    s_sup, r_sup = poly.sup(S, Tb), poly.sup(R, Tb)
    dr_sup = poly.sup(R.derivative(), Tb)
    # |S~ * R~ - S * R| and the bound of its derivative's error (the point value and the integral)
    conv_err = Tb * (b * (r_sup + e) + s_sup * e)
    conv_slope = b * (r_sup + e) + s_sup * e + Tb * (b * (dr_sup + de) + s_sup * de)
    C = poly.conv(S, R)
    first = R * c0 + S * d0 + C
    second = R * ct + S * dt + poly.shift(C, Tb) - poly.conv(S, poly.shift(R, Tb)) - poly.conv(poly.shift(S, Tb), R)
    terms = [
        _store(flint, kernel, lo, hi, tau, abs(c) * e + abs(d) * b + conv_err, abs(c) * de + abs(d) * db + conv_slope)
        for kernel, lo, hi, c, d in ((first, 0.0, tau, c0, d0), (second, tau, 2.0 * tau, ct, dt))
    ]
    points, radii = [], []
    for value, delay in ((c0 * d0, 0.0), (c0 * dt + ct * d0, tau), (ct * dt, 2.0 * tau)):
        if value.is_zero():
            continue
        mid = float(value.mid())
        gap = abs(value - arb(mid))
        points.append((np.array([mid]), delay))
        radii.append([0.0 if gap.is_zero() else math.nextafter(float(gap.upper()), math.inf)])
    return QuasiPolynomial.from_parts(points, terms, radii or None)


def proven_response_product(system: Hyperbolic2x2, K: float) -> QuasiPolynomial:
    """``G = (1 - Phi) C_u`` of the collocated observer under U_BS2(K) (``K = rho``: U_BS), proven.

    ``C_u = -K q e^{-tau s} + int_0^tau c e^{-nu s}`` with ``c`` from the kernels' proven enclosures
    (:func:`~nrobust.hyperbolic.loops.collocated_proof.response_pieces`), ``1 - Phi`` the closed form; the
    kernel of ``G`` is ``c(nu) - rho q c(nu - tau) - K q S(nu - tau) + (S * c)(nu)`` on the pieces between
    ``t_j`` and ``t_j + tau`` (``t_j`` the ends of ``c``'s pieces), stored as :func:`_store` stores the others: the
    loop as built with ``tau_d``, its ``c`` scaled by ``r = tau / tau_d``, and after the kernel a term on the ulp
    around each end that is not a double (module notes, "Ends that are not doubles").

    Raises
    ------
    CertificationError
        No ball arithmetic, two ends of ``G``'s pieces within two ulps of each other, or a bound not reached.
    """
    out = _response_attempt(system, float(K))
    if isinstance(out, str):
        raise CertificationError(f"proven_response_product: {out}; the collocated observer's terms are a model")
    return out


def proven_response_failure(system: Any, K: float) -> str | None:
    """Why :func:`proven_response_product` cannot enclose ``G`` for ``system`` and ``K`` (None when it can)."""
    if not _collocated_covered(system):
        return "a plant other than Hyperbolic2x2 with constant couplings"
    if system.uncoupled:
        return "an uncoupled plant (its collocated observer is exact)"
    out = _response_attempt(system, float(K))
    return out if isinstance(out, str) else None


@lru_cache(maxsize=8)
def _response_attempt(system: Hyperbolic2x2, K: float) -> QuasiPolynomial | str:
    """:func:`proven_response_product`, or the reason it failed."""
    return _in_balls(system, lambda flint: _response_enclose(flint, system, K))


def _response_enclose(flint: Any, system: Hyperbolic2x2, K: float) -> QuasiPolynomial:
    """:func:`proven_response_product` at the working precision, its kernel stored on the segments of
    :func:`_response_segments` at least (``G`` is affine in ``K``: the loops at two gains then share their nodes,
    and their affine combinations cancel term by term where the loop does).

    ``C_u`` is affine in the law's gains (``k = -K`` and ``g_u, g_v`` of eq. (53)), so ``G``'s kernel at ``K`` is
    ``(1 - K) G_0 + K G_1`` of the enclosures at ``K = 0`` and ``K = 1`` (:func:`_response_basis`, once per
    plant), within ``|1 - K| e_0 + |K| e_1`` of their bounds; its point terms are formed at ``K`` directly.
    """
    arb = flint.arb
    basis = _response_basis(system)
    if isinstance(basis, str):
        raise CertificationError(basis)
    (zero, e_0, s_0, slivers), (one, e_1, s_1, _) = basis
    a, b = arb(1) - arb(K), arb(K)
    kernels = [(lo, hi, g_0 * a + g_1 * b) for (lo, hi, g_0), (_, _, g_1) in zip(zero, one, strict=True)]
    sup_err, slope = abs(a) * e_0 + abs(b) * e_1, abs(a) * s_0 + abs(b) * s_1
    points = _response_points(flint, system, K)
    segments = _response_segments(system)
    terms = [
        _store_counted(flint, kernel, lo, hi, system.tau, sup_err, slope, count)[0]
        for (lo, hi, kernel), count in zip(kernels, segments, strict=True)
    ]
    kernel = _one_kernel(terms)
    moved = [_sliver(flint, kernels[i - 1], kernels[i], lo, hi, kernel) for i, lo, hi in slivers]
    return QuasiPolynomial.from_parts(points[0], [kernel, *moved], points[1])


def _one_kernel(terms: list[DistributedDelay]) -> DistributedDelay:
    """The pieces of consecutive ``terms`` as one kernel, their coefficients as stored (no rounding).

    Its error bound is the largest of the terms' (they hold on disjoint intervals), its variation theirs and the
    jumps of the error where they meet (the two radii). As one kernel, integration by parts counts the jumps of
    ``G``'s kernel where the terms meet, not both of their ends (the frequency bounds, the second-order
    variation of :meth:`~nrobust.distributed_delay.DistributedDelay.second_order_variation`).
    """
    if len(terms) < 2:
        return terms[0]
    nodes = np.concatenate([terms[0].nodes[:1], *(d.nodes[1:] for d in terms)])
    degree = max(d.pieces[2].shape[1] for d in terms)
    coefficients = np.concatenate([np.pad(d.pieces[2], ((0, 0), (0, degree - d.pieces[2].shape[1]))) for d in terms])
    variation = math.fsum(
        [d.variation_radius for d in terms] + [u.radius + v.radius for u, v in itertools.pairwise(terms)]
    )
    return DistributedDelay(
        nodes,
        None,
        interpolation="polynomial",
        coefficients=coefficients,
        radius=max(d.radius for d in terms),
        variation_radius=math.nextafter(math.nextafter(variation, math.inf), math.inf),
    )


@lru_cache(maxsize=8)
def _response_basis(
    system: Hyperbolic2x2,
) -> tuple[tuple[list[tuple[float, float, Any]], Any, Any, tuple[tuple[int, float, float], ...]], ...] | str:
    """``G``'s kernels with the bounds of their errors and of their derivatives' at ``K = 0`` and ``K = 1``
    (:func:`_response_kernels`), or the reason they failed."""
    return _in_balls(system, lambda flint: tuple(_response_kernels(flint, system, K) for K in (0.0, 1.0)))


@lru_cache(maxsize=8)
def _response_segments(system: Hyperbolic2x2) -> tuple[int, ...]:
    """Per piece of ``G``'s kernel, the segments per ``tau`` that both ``K = 0`` and ``K = 1`` need."""
    flint = require_flint()
    counts = []
    basis = _response_basis(system)
    if isinstance(basis, str):
        raise CertificationError(basis)
    with precision(flint, _PRECISION):
        zero, one = basis[0][0], basis[1][0]
        zero_arb = flint.arb(0)
        for (lo, hi, a), (_, _, b) in zip(zero, one, strict=True):
            counts.append(
                max(_store_counted(flint, g, lo, hi, system.tau, zero_arb, zero_arb, SEGMENTS)[1] for g in (a, b))
            )
    return tuple(counts)


def _response_kernels(
    flint: Any, system: Hyperbolic2x2, K: float
) -> tuple[list[tuple[float, float, Any]], Any, Any, tuple[tuple[int, float, float], ...]]:
    """``G``'s kernel on each of its pieces (``(lo, hi, arb_poly in nu - lo)``, ``lo``, ``hi`` the nodes of
    :func:`_product_cuts`), the bounds of its error and of its derivative's (:func:`proven_response_product`), and the
    ulps ``(i, lo, hi)`` around the cuts ``i`` whose node is not the true end (module notes, "Ends that are not
    doubles")."""
    arb, arb_poly = flint.arb, flint.arb_poly
    poly = _Poly(flint)
    tau, (c0, ct, S, b, db), _ = _closed_forms(flint, system)
    times, breaks, pieces, e, de = _built_response(flint, system, K)
    T, whole = arb(tau), Fraction(tau)
    s_sup, ds_sup = poly.sup(S, T), poly.sup(S.derivative(), T)
    c_sup = arb(0)
    for lo, hi, piece in zip(breaks[:-1], breaks[1:], pieces, strict=True):
        c_sup = arb.max(c_sup, poly.sup(piece, hi - lo))
    kq = -arb(K) * arb(float(system.q))
    conv_err = T * (b * (c_sup + e) + s_sup * e)
    conv_slope = 2 * (b * (c_sup + e) + s_sup * e) + T * (db * (c_sup + e) + ds_sup * e)
    sup_err = e + abs(ct) * e + abs(kq) * b + conv_err
    slope = de + abs(ct) * de + abs(kq) * db + conv_slope
    cuts, nodes, slivers = _product_cuts(times, tau)
    u = arb_poly([arb(0), arb(1)])
    kernels = []
    for i in range(len(cuts) - 1):
        middle, start = (cuts[i] + cuts[i + 1]) / 2, arb(nodes[i])  # the piece's polynomial in nu - nodes[i]
        kernel = arb_poly([0])
        for j, piece in enumerate(pieces):
            left, right = times[j], times[j + 1]
            if left <= middle - whole < right:
                kernel += piece(u + (start - T - breaks[j])) * ct
            if left <= middle < right:
                kernel += piece(u + (start - breaks[j])) * c0
            if middle - right >= whole or middle - left <= 0:
                continue
            lower = arb_poly([0]) if middle - right <= 0 else u + (start - breaks[j + 1])
            upper = arb_poly([T]) if middle - left >= whole else u + (start - breaks[j])
            kernel += polynomial_integral(flint, S, piece, arb(-1), u + (start - breaks[j]), lower, upper)
        if middle > whole:
            kernel += S(u + (start - T)) * kq
        kernels.append((nodes[i], nodes[i + 1], kernel))
    return kernels, sup_err, slope, slivers


def _built_response(
    flint: Any, system: Hyperbolic2x2, K: float
) -> tuple[list[Fraction], list[Any], list[Any], Any, Any]:
    """The command response's kernel of the loop as built, ``r c(r nu)`` on ``[0, tau_d]`` (module notes, "Ends
    that are not doubles"): its ends ``t_j / r`` (exact rationals and balls), its pieces in ``nu - t_j / r`` and the
    bounds of their error and of its derivative."""
    response = response_pieces(flint, system, K)
    r = tau_ratio(system)
    R = rational_ball(flint, r)
    times = [t / r for t in response.times]
    if times[-1] != Fraction(system.tau):
        raise CertificationError("the command response does not end at the loop's tau")
    scaled = flint.arb_poly([0, R])
    pieces = [piece(scaled) * R for piece in response.pieces]
    breaks = [rational_ball(flint, t) for t in times]
    return times, breaks, pieces, response.error * R, response.slope * R * R


def _product_cuts(
    times: list[Fraction], tau: float
) -> tuple[list[Fraction], list[float], tuple[tuple[int, float, float], ...]]:
    """The ends of ``G``'s pieces (those of ``c`` and them plus ``tau``: exact rationals), the nodes that stand for
    them (each end if it is a double, else the nearest multiple of ``ulp(2 tau)``), and per node that is not its
    end the ulp ``(i, lo, hi)`` between the node and the next multiple past the end (module notes)."""
    unit = Fraction(math.ulp(2.0 * tau))
    cuts = sorted({*times, *(t + Fraction(tau) for t in times)})
    nodes: list[float] = []
    slivers: list[tuple[int, float, float]] = []
    for i, cut in enumerate(cuts):
        node = float(cut)
        if Fraction(node) != cut:
            multiple = round(cut / unit)
            node = float(multiple * unit)
            other = float((multiple + (1 if cut > multiple * unit else -1)) * unit)
            slivers.append((i, min(node, other), max(node, other)))
        nodes.append(node)
    if any(Fraction(b) - Fraction(a) <= 2 * unit for a, b in itertools.pairwise(nodes)):
        raise CertificationError("two ends of the product's pieces lie within two ulps of each other")
    return cuts, nodes, tuple(slivers)


def _sliver(
    flint: Any, left: tuple[float, float, Any], right: tuple[float, float, Any], lo: float, hi: float, kernel: Any
) -> DistributedDelay:
    """The term on the ulp ``[lo, hi]`` around an end of ``G``'s pieces that is not a double (module notes).

    ``left``, ``right``: the pieces that meet at the node, each ``(start, stop, polynomial in nu - start)``;
    ``kernel``: the stored kernel (its ``radius`` and ``variation_radius``). Zero within ``radius`` ``J`` =
    ``|left - right|`` on the ulp plus the kernel's radius; its variation ``J`` (the jump at the end), the kernel's
    variation and twice its radius (the kernel's own error, taken as zero between node and end, jumps there) and
    the ulp times ``|left' - right'|``.
    """
    arb = flint.arb
    hull = arb(lo).union(arb(hi))
    (a, _, P), (b, _, Q) = left, right
    gap = P(hull - arb(a)) - Q(hull - arb(b))
    rate = P.derivative()(hull - arb(a)) - Q.derivative()(hull - arb(b))
    jump = abs(gap) + arb(kernel.radius)
    variation = jump + arb(kernel.variation_radius) + 2 * arb(kernel.radius) + (arb(hi) - arb(lo)) * abs(rate)
    return zero_term(lo, hi, jump, variation)


def _response_points(flint: Any, system: Hyperbolic2x2, K: float) -> tuple[list, list]:
    """``G``'s point terms ``c_0 k q e^{-tau s}`` and ``c_tau k q e^{-2 tau s}`` (``k = -K``; ``c_0, c_tau`` the point
    coefficients of ``1 - Phi``) with the radii of their rounding (:func:`proven_response_product`)."""
    arb = flint.arb
    tau, (c0, ct, _, _, _), _ = _closed_forms(flint, system)
    kq = -arb(K) * arb(float(system.q))
    points, radii = [], []
    for value, delay in ((c0 * kq, tau), (ct * kq, 2.0 * tau)):
        mid = float(value.mid())
        gap = abs(value - arb(mid))
        points.append((np.array([mid]), delay))
        radii.append([0.0 if gap.is_zero() else math.nextafter(float(gap.upper()), math.inf)])
    return points, radii
