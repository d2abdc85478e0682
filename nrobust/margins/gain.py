"""Exact ends of the admissible gain intervals of an affine gain family.

A loop ``F(s; delta, K) = A(s) + (B_0(s) + K R(s)) e^{-delta s}`` (:class:`AffineGainLoop`;
``U_BS2(K)``'s, eq. (60), is one) is *admissible* at the gain ``K`` when it is exponentially
stable for every delay in ``[0, delta_max]``. The verdict changes with ``K`` only at a
*critical gain*, where a root reaches the imaginary axis ``s = i w`` at some delay in
``[0, delta_max]``; :func:`locate_gain_ends` finds them by the equation of their kind
(:data:`END_KINDS`, :class:`GainEnd`):

* a *crossing*: ``A(i w) + (B_0(i w) + K R(i w)) e^{-i w delta_max} = 0``, i.e.
  ``K_delta(w) = -(A(i w) e^{i w delta_max} + B_0(i w)) / R(i w)`` is real;
* a *pair birth* (a kink of the crossing curves): ``g(w; K) = |A(i w)|^2 - |B(i w; K)|^2``
  has a double zero in ``w`` with crossing delay ``<= delta_max``; ``g`` is quadratic in
  ``K``, its roots ``K_pm(w)`` are explicit and a birth is an extremum of ``K_pm(w)``;
* *nominal*: the crossing equation at ``delta = 0`` (``w = 0`` included);
* the *strong-stability* limit, where the loop's difference operator stops being strongly
  stable (``|rho q| + |K q| = 1`` for ``U_BS2(K)``, eq. (54)).

A scan of the axis on a uniform grid (quintic Hermite interpolants between samples) locates
every critical gain; those that decide the region are solved again on the loop itself to
``1e-14`` in ``w``. :func:`~nrobust.margins.admissible.gain_verdict` decides one gain by the
certified crossing search of :mod:`nrobust.margins.crossing`, and
:func:`~nrobust.margins.admissible.check_gain_end` verifies an end on both sides.
The plant-level study is :func:`nrobust.hyperbolic.analyses.k_region`.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from .._digits import with_accuracy
from ..bounds import root_free_region
from ..errors import CertificationError
from ..quasipoly import QuasiPolynomial
from .axis import frequency_bound
from .count import unstable_count

__all__ = ["END_KINDS", "AffineGainLoop", "AxisBound", "GainEnd", "locate_gain_ends", "nominally_stable"]

#: Kinds of the end of an admissible interval of gains (:attr:`GainEnd.kind`).
END_KINDS = ("crossing", "pair_birth", "nominal", "strong_stability", "bisection")
# Scan step on the axis: dw = pi / (_SCAN_STEPS T) rounded down to a power of two, T the
# longest delay of the scanned functions (A e^{i w (tau + delta)} / R has 2 max_delay + delta):
# at least 2 _SCAN_STEPS samples per period of their fastest oscillation.
_SCAN_STEPS = 4
# The bracketed solves stop at this relative width in w (or after _MAX_SOLVE steps).
_W_RTOL = 1e-14
# The same for the roots of the interpolants (their error is about 1e-8: a root to 1e-10 is
# all they can give; those that matter are solved again on the loop).
_MODEL_RTOL = 1e-10
_MAX_SOLVE = 400
# The first scan covers |K| <= (1 - _FIRST_CAP) k, k the strong-stability bound; without a critical
# gain past a cap, the next cap is k - (k - cap) / _CAP_SHRINK.
_FIRST_CAP = 0.125
_CAP_SHRINK = 4.0
# The interpolated loop's answers are trusted to _MODEL_SAFETY times its error bound; a
# solve on the loop starts from a bracket of half-width _BRACKET_CELLS scan steps about them.
_MODEL_SAFETY = 10.0
_BRACKET_CELLS = 1e-3
_EPS = float(np.finfo(float).eps)
# Safety factor on the residual of an end's frequency (AffineGainLoop.end_omega_error): 13 times
# the largest ratio (1.17) of the true error (mpmath, 40 digits) to the unscaled estimate, measured
# on six crossing ends of three plants (tests/test_accuracy_digits.py checks the paper's).
_OMEGA_SAFETY = 16.0
# Order of the kinds when two events fall on the same gain (to rounding).
_KIND_ORDER = {"nominal": 0, "crossing": 1, "pair_birth": 2, "strong_stability": 3}


class GainEnd(NamedTuple):
    """One end of an admissible interval of gains and the event that closes it.

    Attributes
    ----------
    K : float
        The gain at the end (the interval is open: ``K`` itself is not admissible).
    kind : str
        ``"crossing"``: a root reaches the axis at ``i omega`` for ``delta = delta_max``,
        ``A(i w) + B(i w; K) e^{-i w delta_max} = 0`` (a branch of crossing delays passes
        ``delta_max``); ``"pair_birth"``: ``g(w) = |A(i w)|^2 - |B(i w; K)|^2`` has a double
        zero at ``omega`` (``g = dg/dw = 0``), a pair of crossing frequencies is born with
        crossing delay ``delay <= delta_max``; ``"nominal"``: a root on the axis at
        ``delta = 0`` (the nominal loop loses stability; ``omega = 0`` for ``s = 0``);
        ``"strong_stability"``: the difference operator stops being strongly stable
        (``|rho q| + |K q| = 1`` for ``U_BS2(K)``, eq. (54); roots come from ``omega = inf``
        at delays down to ``0``);
        ``"bisection"``: located by bisection on delay margins (a ``controller`` family other
        than ``U_BS2(K)``; ``omega`` and ``delay`` are the first crossing of the margin just
        outside, ``inf`` and that margin if it has none).
    omega : float
        Frequency of the root on the axis (``inf`` at the strong-stability limit).
    delay : float
        Delay at which it is there: ``delta_max``, the birth delay, or ``0`` (never ``nan``).
    accuracy : float or None
        A bound of ``|K - K_end|``, ``K_end`` the exact end, once the end is verified: the
        half-width ``tol`` of the bracket ``[K - tol, K + tol]`` on whose two sides
        :func:`~nrobust.hyperbolic.analyses.k_region` confirms the verdicts (admissible inside,
        a certified unstable root or no strong stability outside; the verdict changes only at
        the critical gains, so the end lies in that bracket; with ``k_region(..., rigorous=True)``
        and the end proven, the distance to the farther of its two probe gains as rounded), or the
        width of the last bisection step. None before verification (:func:`locate_gain_ends` solves ``K`` from
        its equation to ``1e-14`` in ``w``, a precision not certified by itself) or when not known.
    omega_accuracy : float or None
        An estimate of ``|omega - w_end|``, ``w_end`` the frequency of the exact end
        (:meth:`AffineGainLoop.end_omega_error` for a verified crossing or nominal end; the
        margin's :attr:`~nrobust.margins.DelayMargin.omega_accuracy` for a bisection end; 0 when
        ``omega`` is ``inf``). None when not estimated (a pair birth).
    delay_accuracy : float or None
        A bound of ``|delay - delay_end|``: 0 where the delay is given (``delta_max`` at a
        crossing, ``0`` at a nominal or strong-stability end), the margin's
        :attr:`~nrobust.margins.DelayMargin.accuracy` for a bisection end; None when not
        estimated (a pair birth's crossing delay).
    """

    K: float
    kind: str
    omega: float
    delay: float
    accuracy: float | None = None
    omega_accuracy: float | None = None
    delay_accuracy: float | None = None

    def __repr__(self) -> str:
        return (
            f"GainEnd(K={with_accuracy(self.K, self.accuracy)}, kind={self.kind!r}, "
            f"omega={with_accuracy(self.omega, self.omega_accuracy)}, "
            f"delay={with_accuracy(self.delay, self.delay_accuracy)})"
        )


@dataclass(frozen=True)
class _Axis:
    """``A``, ``B_0``, ``R`` at ``s = i w`` and (when computed) their derivatives in ``w``."""

    w: NDArray[np.float64]
    a: NDArray[np.complex128]
    b0: NDArray[np.complex128]
    r: NDArray[np.complex128]
    da: NDArray[np.complex128] | None = None
    db0: NDArray[np.complex128] | None = None
    dr: NDArray[np.complex128] | None = None

    def k_at_delay(self, delta: float) -> NDArray[np.complex128]:
        """The complex ``K`` with ``A + (B_0 + K R) e^{-i w delta} = 0``: a crossing where it is real."""
        return -(self.a * np.exp(1j * self.w * delta) + self.b0) / self.r

    def branches(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """``(D, m, sqrt D)``: ``|A|^2 = |B_0 + K R|^2`` at ``K = m +- sqrt D`` (``D >= 0``).

        With ``u = B_0/R``: ``g = |R|^2 (|A|^2/|R|^2 - (K + Re u)^2 - (Im u)^2)``, quadratic in
        ``K``; ``m = -Re u`` and ``D = |A|^2/|R|^2 - (Im u)^2``.
        """
        u = self.b0 / self.r
        D = np.abs(self.a) ** 2 / np.abs(self.r) ** 2 - u.imag**2
        return D, -u.real, np.sqrt(np.maximum(D, 0.0))

    def branch_slopes(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(m', D')``, so that ``dK/dw = m' +- D' / (2 sqrt D)`` on the branches."""
        assert self.da is not None and self.db0 is not None and self.dr is not None
        u = self.b0 / self.r
        du = (self.db0 * self.r - self.b0 * self.dr) / self.r**2
        r2 = np.abs(self.r) ** 2
        da2 = 2.0 * (np.conj(self.a) * self.da).real
        dr2 = 2.0 * (np.conj(self.r) * self.dr).real
        return -du.real, (da2 * r2 - np.abs(self.a) ** 2 * dr2) / r2**2 - 2.0 * u.imag * du.imag

    def delays(self, K: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """Smallest ``delta >= 0`` with ``i w`` a root of the loop with gain ``K`` (where ``|A| = |B|``)."""
        return np.mod(np.angle(-(self.b0 + K * self.r) / self.a), 2.0 * np.pi) / self.w


@dataclass(frozen=True)
class AffineGainLoop:
    """A loop affine in the gain: ``F(s; delta, K) = A(s) + (B_0(s) + K R(s)) e^{-delta s}``.

    ``U_BS2(K)``'s loop (eq. (60), :func:`nrobust.hyperbolic.loop_factors`) is one:
    ``A = 1 - Phi``, ``B = K q e^{-tau s} - I_N``, so ``B_0 = -I_N`` (the factor at ``K = 0``)
    and ``R = q e^{-tau s}`` (its change per unit gain).

    Parameters
    ----------
    A, B0, R : QuasiPolynomial
        The factor without delay, the delayed factor at ``K = 0`` and its change per unit gain.
    """

    A: QuasiPolynomial
    B0: QuasiPolynomial
    R: QuasiPolynomial
    #: ``A + B_0``: the distributed parts cancel (``I_N - I_N``), so ``A(i w)`` costs one
    #: evaluation of ``B_0`` (``A = S - B_0``).
    S: QuasiPolynomial = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "S", self.A + self.B0)

    def axis(self, w: NDArray[np.float64], slopes: bool = False) -> _Axis:
        """``A``, ``B_0``, ``R`` at ``s = i w`` (with their ``w``-derivatives when ``slopes``)."""
        s = 1j * np.asarray(w, dtype=float)
        b0 = self.B0(s)
        if not slopes:
            return _Axis(s.imag, self.S(s) - b0, b0, self.R(s))
        db0 = 1j * self.B0.deriv_at(s)
        return _Axis(s.imag, self.S(s) - b0, b0, self.R(s), 1j * self.S.deriv_at(s) - db0, db0, 1j * self.R.deriv_at(s))

    def B(self, K: float) -> QuasiPolynomial:
        """The delayed factor ``B_0 + K R`` at the gain ``K``."""
        return self.B0 + self.R * K

    def loop_at(self, K: float, delta: float) -> QuasiPolynomial:
        """``F(.; delta, K)``."""
        B = self.B(K)
        return self.A + (B.shift(delta) if delta > 0 else B)

    def end_omega_error(self, end: GainEnd, K_accuracy: float) -> float | None:
        """An estimate of ``|omega - w_end|`` for a crossing or nominal ``end`` whose gain is within
        ``K_accuracy`` of the exact end ``(w_end, K_end)``.

        At the end's delay ``delta`` both ends solve ``F(i w; delta, K) = 0``; to first order
        ``F(i omega; K) = F'(i omega) i (omega - w_end) + R(i omega) e^{-i omega delta} (K - K_end)``,
        so ``|omega - w_end| <= (|F(i omega)| + |R(i omega)| K_accuracy) / |F'(i omega)|``. The
        residual gets the safety factor :data:`_OMEGA_SAFETY` (with the rounding noise
        ``eps M``, ``M`` :meth:`~nrobust.quasipoly.QuasiPolynomial.magnitude`), the linearised
        gain term a factor 2, and ``eps |omega|`` is added. None for another kind, ``omega = inf``
        or ``F' = 0`` (a multiple root).
        """
        if end.kind not in ("crossing", "nominal") or not np.isfinite(end.omega):
            return None
        s = np.array([1j * end.omega])
        F = self.loop_at(end.K, end.delay)
        slope = abs(complex(F.deriv_at(s)[0]))
        if not slope > 0.0:
            return None
        noise = abs(complex(F(s)[0])) + _EPS * float(F.magnitude(s)[0])
        shift = abs(complex(self.R(s)[0])) * K_accuracy
        return (_OMEGA_SAFETY * noise + 2.0 * shift) / slope + _EPS * abs(end.omega)

    def verified_end(self, end: GainEnd, K_accuracy: float) -> GainEnd:
        """``end`` with its accuracies once its gain is verified to ``K_accuracy``
        (:attr:`GainEnd.accuracy`, :attr:`GainEnd.omega_accuracy`, :attr:`GainEnd.delay_accuracy`)."""
        given = end.kind in ("crossing", "nominal", "strong_stability")
        omega_accuracy = 0.0 if end.kind == "strong_stability" else self.end_omega_error(end, K_accuracy)
        return end._replace(
            accuracy=K_accuracy, omega_accuracy=omega_accuracy, delay_accuracy=0.0 if given else end.delay_accuracy
        )


@dataclass(frozen=True)
class AxisBound:
    """Bound of the crossing frequencies of an affine loop (none above :meth:`AxisBound.W`).

    For ``S = 1 - rho q z``, ``R = q z`` (``z = e^{-tau s}``) and ``B_0 = J = int_0^tau n(nu)
    e^{-nu s} dnu`` with ``n`` piecewise polynomial (the paper's plants),
    ``A = S - J`` and ``B = K R + J``, so that on ``s = i w`` (``|J|^2`` cancels)::

        g = |A|^2 - |B|^2 = |S|^2 - K^2 q^2 - 2 Re(conj(T) J),   T = S + K R = 1 - c z,  c = (rho - K) q.

    With ``p = |rho q|``, ``sigma = sign(rho q)``, ``phi = theta`` (``sigma = 1``) or
    ``theta - pi``, ``x = |sin(phi/2)|`` and ``z = e^{-i theta}``: ``|S|^2 = (1 - p)^2 + 4 p x^2``,
    ``|sin theta| <= 2 x`` and ``cos theta = sigma (1 - 2 x^2)``.

    *Second order.* Integration by parts twice gives ``J = (n(0) - n(tau) z)/(i w) + E`` with
    ``|E| <= V_2 / w^2``, ``V_2 = |n'(0)| + |n'(tau)| + TV(n')``, and
    ``Re(conj(T) (n(0) - n(tau) z)/(i w)) = (n(tau) - c n(0)) sin(theta) / w``. Minimising
    ``4 p x^2 - 4 beta x / w`` over ``x``::

        g >= (1 - p)^2 - K^2 q^2 - C_2 / w^2,   C_2 = beta^2 / p + 2 (1 + |c|) V_2,  beta = |n(tau) - c n(0)|,

    no crossing above ``W_2 = sqrt(C_2 / (q^2 (k^2 - K^2)))``, ``k = (1 - p)/|q|``; with the term
    ``C_1 / w`` of the jumps below (and of the stored kernel's distance to the true one, sup ``r`` and
    variation ``V``: it moves ``J`` by at most ``(2 r + V) / w``, counted in ``D_0``), above the larger
    root of ``q^2 (k^2 - K^2) w^2 - C_1 w - C_2``.

    *Third order.* Once more: ``J = (n(0) - n(tau) z)/(i w) - (n'(0) - n'(tau) z)/w^2 + E_3``,
    ``|E_3| <= V_3 / w^3``, ``V_3 = |n''(0)| + |n''(tau)| + TV(n'')``, the jumps of ``n`` and ``n'``
    between pieces adding ``D_0 / w`` and ``D_1 / w^2`` (``D_j`` the sums of their moduli). The new
    term is exact: ``2 Re(conj(T) (n'(0) - n'(tau) z)) / w^2 = 2 (a_0 - a_1 cos theta) / w^2``
    with ``a_0 = n'(0) + c n'(tau)``, ``a_1 = n'(tau) + c n'(0)``, and its part in ``x^2`` joins
    ``|S|^2``: with ``P = p + sigma a_1 / w^2 > 0``, minimising ``4 P x^2 - 4 beta x / w``::

        g >= (1 - p)^2 - K^2 q^2 - C_1 / w - M / w^2 - C_3 / w^3,
        C_1 = 2 (1 + |c|) D_0,  M = beta^2 / P + 2 (sigma a_1 - a_0) + 2 (1 + |c|) D_1,  C_3 = 2 (1 + |c|) V_3.

    ``P`` grows with ``w`` when ``sigma a_1 < 0``: for ``w >= W`` it is at least its value at
    ``W``, so with ``M`` taken there (and at least 0) the right side increases with ``w``, and
    ``W_3`` is the least ``W`` (to ``1e-9``) where it is positive. :meth:`W` returns
    ``min(W_2, W_3)``. On the paper's plant ``W_3`` is about ``2.6`` times smaller near the bound
    (``K = 0.1464``: 32 against 84): most of ``V_2`` is ``TV(n')``, which the third order
    replaces by ``a_0, a_1``, and their worst case (``cos theta = -sigma``) falls where ``|S|`` is
    largest. Both grow like ``1/sqrt(k - |K|)`` where the first-order bound
    (:func:`nrobust.margins.frequency_bound`) grows like ``1/(k - |K|)`` (``lam = 2, mu = 0.5,
    sigma = (0.3, -0.4), q = 0.7, rho = 0.9`` at ``k - |K| = 1.7e-5``: ``W_2 = 190`` instead of
    ``7.3e4``).
    """

    rho_q: float
    q: float
    n0: float
    n_tau: float
    v2: float
    #: ``n'(0)``, ``n'(tau)``, ``V_3`` and the sums ``D_0``, ``D_1`` of the jumps of ``n`` and ``n'``
    #: (third order; ``V_3 = inf`` leaves the second-order bound alone).
    d0: float = 0.0
    d_tau: float = 0.0
    v3: float = float("inf")
    jumps0: float = 0.0
    jumps1: float = 0.0

    @classmethod
    def of(cls, loop: AffineGainLoop) -> AxisBound | None:
        """The bound of ``loop``, or None if it is not of the form above."""
        S, B0, R = loop.S, loop.B0, loop.R
        if len(R.point_terms) != 1 or R.distributed or not R.is_real:
            return None
        (r, tau), terms = R.point_terms[0], dict((t, p) for p, t in S.point_terms)
        if r.size != 1 or set(terms) != {0.0, tau} or S.distributed or not S.is_real:
            return None
        if terms[0.0].size != 1 or terms[0.0][0] != 1.0 or terms[tau].size != 1 or terms[tau][0] == 0.0:
            return None
        if B0.point_terms or len(B0.distributed) != 1:
            return None
        d = B0.distributed[0]
        if d.a != 0.0 or d.b != tau or d.moment != 0 or d.poly.size != 1 or np.iscomplexobj(d.values):
            return None
        start, h, poly = d.pieces
        n = float(d.poly[0]) * np.asarray(poly, dtype=float)
        if n.shape[1] < 4:  # constant, linear or quadratic pieces: the terms up to t^3 read below are 0
            n = np.pad(n, ((0, 0), (0, 4 - n.shape[1])))
        j = np.arange(n.shape[1])
        value_end, slope_start, slope_end = n.sum(axis=1), n[:, 1] / h, (n * j).sum(axis=1) / h
        scale = float(np.max(np.abs(n[:, 0]))) + 1e-300
        contiguous = np.abs(start[1:] - (start[:-1] + h[:-1])) <= 1e-12 * tau
        if not np.all(contiguous) or np.any(np.abs(n[1:, 0] - value_end[:-1]) > 1e-12 * scale):
            return None  # a gap or a jump of n: the first-order bound applies
        # TV of n' on each segment: int |n''| = (1/h) int_0^1 |2 P_2 + 6 P_3 t| dt (cubic; 0 when linear);
        # a term P_j t^j of higher degree adds at most j |P_j| (int_0^1 j (j - 1) t^(j-2) dt = j)
        a2 = 2.0 * n[:, 2] if n.shape[1] > 2 else np.zeros(h.size)
        a3 = 6.0 * n[:, 3] if n.shape[1] > 3 else np.zeros(h.size)
        lo, hi = a2, a2 + a3
        crossing = lo * hi < 0
        inside = np.where(crossing, (lo**2 + hi**2) / (2.0 * np.abs(np.where(crossing, a3, 1.0))), np.abs(lo + hi) / 2)
        inside = inside + np.sum(np.abs(n[:, 4:]) * j[4:], axis=1)
        jumps1 = float(np.sum(np.abs(slope_start[1:] - slope_end[:-1])))
        v2 = abs(slope_start[0]) + abs(slope_end[-1]) + float(np.sum(inside / h)) + jumps1
        # TV of n'' on each segment: int |n'''| <= (1/h^2) sum_j j (j - 1) |P_j| (j >= 3), and its jumps
        curve_start, curve_end = a2 / h**2, (n * j * (j - 1)).sum(axis=1) / h**2
        third = np.sum(np.abs(n[:, 3:]) * (j * (j - 1))[3:], axis=1) / h**2
        v3 = (
            abs(float(curve_start[0]))
            + abs(float(curve_end[-1]))
            + float(np.sum(third))
            + float(np.sum(np.abs(curve_start[1:] - curve_end[:-1])))
        )
        # the stored kernel's distance to the true one (sup ``r``, variation ``V``) moves ``J`` by at most
        # ``(2 r + V) / w`` (integration by parts once): counted with the jumps of ``n``
        model = abs(float(d.poly[0])) * (2.0 * d.radius + d.variation_radius)
        jumps0 = float(np.sum(np.abs(n[1:, 0] - value_end[:-1]))) + model

        # the bound carries its own rounding: the sums a little larger (they err by ~ n_segments eps)
        def up(v: float) -> float:
            return float(v) * (1.0 + 1e-9) + 1e-300

        return cls(
            -float(terms[tau][0]),
            float(r[0]),
            float(n[0, 0]),
            float(value_end[-1]),
            up(v2),
            float(slope_start[0]),
            float(slope_end[-1]),
            up(v3),
            up(jumps0),
            up(jumps1),
        )

    def W(self, K_lo: float, K_hi: float) -> float:
        """A frequency above every crossing of every gain in ``[K_lo, K_hi]`` (``inf`` if one has ``|K| >= k``).

        Each constant is taken at its worst over the two ends: ``C_2``, ``beta``, ``1 + |c|`` and
        ``sigma a_1 - a_0`` are convex in ``K`` (moduli of affine functions, or affine), ``P``
        concave, and ``1/(k^2 - K^2)`` convex, so each is worst at an end.
        """
        p, q = abs(self.rho_q), abs(self.q)
        if p == 0.0:
            return float("inf")
        c2 = 0.0
        room = float("inf")
        cs = [self.rho_q - K * self.q for K in (K_lo, K_hi)]
        for K, c in zip((K_lo, K_hi), cs):
            beta = abs(self.n_tau - c * self.n0)
            c2 = max(c2, beta**2 / p + 2.0 * (1.0 + abs(c)) * self.v2)
            # q^2 (k^2 - K^2) = ((1 - p) - |K q|)((1 - p) + |K q|), the first factor less its rounding
            gap = (1.0 - p) - abs(K) * q - 8.0 * _EPS * (1.0 + p + abs(K) * q)
            room = min(room, gap * ((1.0 - p) + abs(K) * q))
        if room <= 0.0:
            return float("inf")
        # with the jumps (and the kernel's error) g >= room - c1 / w - C_2 / w^2: positive above the larger root
        c1 = 2.0 * max(1.0 + abs(c) for c in cs) * self.jumps0
        c2 *= 1.0 + 1e-9
        second = float((c1 + np.sqrt(c1 * c1 + 4.0 * room * c2)) / (2.0 * room) * (1.0 + 1e-9))
        return min(second, self._third(cs, room))

    def _third(self, cs: list[float], room: float) -> float:
        """``W_3`` of the class notes for the values ``c`` at the two ends (``inf`` if not finite)."""
        if not np.isfinite(self.v3):
            return float("inf")
        p, sigma = abs(self.rho_q), float(np.sign(self.rho_q))
        beta = max(abs(self.n_tau - c * self.n0) for c in cs)
        fac = max(1.0 + abs(c) for c in cs)
        a1 = [sigma * (self.d_tau + c * self.d0) for c in cs]  # sigma a_1 at the two ends
        linear = max(s1 - (self.d0 + c * self.d_tau) for s1, c in zip(a1, cs))  # sigma a_1 - a_0
        size = max(abs(s1) + abs(self.d0 + c * self.d_tau) for s1, c in zip(a1, cs))
        c1, c3 = 2.0 * fac * self.jumps0, 2.0 * fac * self.v3
        level = room * (1.0 - 1e-9)

        def positive(W: float) -> bool:
            P = p + min(0.0, *a1) / W**2
            if P <= 0.0:
                return False
            M = beta**2 / P + 2.0 * linear + 2.0 * fac * self.jumps1
            M = max(M, 0.0) + 1e-9 * (beta**2 / P + 2.0 * size + 2.0 * fac * self.jumps1)
            return bool(level - (c1 / W + M / W**2 + c3 / W**3) * (1.0 + 1e-9) > 0.0)

        hi = max(np.sqrt(max(abs(min(0.0, *a1)) / p, 0.0)), 1e-3)
        for _ in range(200):  # doubling: the test holds from some W on (it only improves with W)
            if positive(hi):
                break
            hi *= 2.0
        else:
            return float("inf")
        lo = 0.5 * hi
        while hi - lo > 1e-9 * hi:
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if positive(mid) else (mid, hi)
        return float(hi)


def _junction(at: _Axis) -> NDArray[np.float64]:
    """``D``: zero where the two branches ``K_pm`` meet."""
    return at.branches()[0]


def _branch_slope(at: _Axis, sign: float) -> NDArray[np.float64]:
    """``dK/dw`` on the branch ``K = m + sign sqrt(D)`` (zero at a pair birth)."""
    mx, Dx = at.branch_slopes()
    return mx + sign * Dx / (2.0 * np.maximum(at.branches()[2], 1e-300))


def _solve(
    f: Callable[[NDArray[np.float64], NDArray[np.intp]], NDArray[np.float64]],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    flo: NDArray[np.float64],
    fhi: NDArray[np.float64],
    rtol: float = _W_RTOL,
) -> NDArray[np.float64]:
    """Zeros of ``f`` in the brackets ``[lo, hi]`` (``f(lo) f(hi) <= 0``), all brackets at once.

    ``f(x, k)`` evaluates at the points ``x`` of the brackets ``k``. Illinois steps (regula
    falsi halving the value kept twice), a bisection every fourth step; each bracket stops
    at the relative width ``rtol``.
    """
    lo, hi, flo, fhi = (np.array(v, dtype=float) for v in (lo, hi, flo, fhi))
    out = np.where(flo == 0, lo, np.where(fhi == 0, hi, np.nan))
    # the open brackets only (their indices k), each with the side of its last step (-1, 0, 1)
    k = np.flatnonzero(np.isnan(out))
    a, b, fa, fb, side = lo[k], hi[k], flo[k], fhi[k], np.zeros(k.size, dtype=int)
    for it in range(_MAX_SOLVE):
        wide = b - a > rtol * np.maximum(np.abs(a), np.abs(b))
        if not wide.all():  # narrow enough: the midpoint
            out[k[~wide]] = 0.5 * (a[~wide] + b[~wide])
            k, side = k[wide], side[wide]
            a, b, fa, fb = a[wide], b[wide], fa[wide], fb[wide]
        if not k.size:
            break
        if it % 4 == 3:
            x = 0.5 * (a + b)
        else:
            with np.errstate(divide="ignore", invalid="ignore"):
                x = (a * fb - b * fa) / (fb - fa)
            bisect = ~np.isfinite(x) | (x <= a) | (x >= b)
            x[bisect] = 0.5 * (a + b)[bisect]
        fx = f(x, k)
        left = fx * fa < 0
        zero = fx == 0
        right = ~left & ~zero
        fa = np.where(right, fx, np.where(left & (side == 1), 0.5 * fa, fa))
        fb = np.where(left, fx, np.where(right & (side == -1), 0.5 * fb, fb))
        a, b = np.where(right, x, a), np.where(left, x, b)
        side = np.where(left, 1, np.where(right, -1, side))
        if zero.any():  # an exact zero
            out[k[zero]] = x[zero]
            k, side = k[~zero], side[~zero]
            a, b, fa, fb = a[~zero], b[~zero], fa[~zero], fb[~zero]
    out[k] = 0.5 * (a + b)
    return out


def _sign_changes(f: NDArray[np.float64], valid: NDArray[np.bool_] | None = None) -> NDArray[np.intp]:
    """Indices ``j`` where ``f`` changes sign on ``[j, j + 1]`` (both samples valid)."""
    change = (np.sign(f[:-1]) * np.sign(f[1:]) < 0) | ((f[:-1] == 0) & (f[1:] != 0))
    if valid is not None:
        change &= valid[:-1] & valid[1:]
    return np.flatnonzero(change)


def _sixth_derivative_bound(P: QuasiPolynomial) -> float:
    """Bound of ``|d^6 P(i w) / dw^6|`` over real ``w`` (``inf`` if a term has a polynomial factor)."""
    if any(p.size > 1 for p, _ in P.point_terms) or any(d.poly.size > 1 for d in P.distributed):
        return float("inf")
    total = sum(float(np.abs(p[0])) * t**6 for p, t in P.point_terms)
    return total + sum(float(np.abs(d.poly[0]) * d.abs_moment(0.0, 6)) for d in P.distributed)


class _AxisGrid:
    """``S = A + B_0``, ``B_0``, ``R`` and two ``w``-derivatives at ``w_k = k dw``, with interpolants.

    Off a uniform grid each evaluation of the kernel ``I_N`` costs ``O(nodes)``; on it one
    chirp-z transform gives every sample. Between samples, quintic Hermite interpolants
    (:meth:`model`) stand for the loop, with an error below :attr:`error` (``dw^6 / 46080``
    times the sixth derivatives); they locate every root of the scan, and only those that
    decide the region are solved again on the loop itself (:meth:`_Scan._exact`). The grid
    grows with :meth:`extend` and keeps its samples.
    """

    def __init__(self, loop: AffineGainLoop, dw: float) -> None:
        self.loop, self.dw = loop, dw
        self.w = np.zeros(0)
        self.parts: tuple[NDArray[np.complex128], ...] = tuple(np.zeros(0, dtype=complex) for _ in range(9))
        # the same samples as one array (S, B_0, R) x (value, two w-derivatives) x samples, so that
        # the interpolants of the three functions take one operation per basis function
        self._stack = np.zeros((3, 3, 0), dtype=complex)
        self._first = tuple(P.derivative() for P in (loop.S, loop.B0, loop.R))
        self.roots: dict[tuple, dict[int, float]] = {}  # the scans' roots of the interpolants, per cell
        sixth = sum(_sixth_derivative_bound(P) for P in (loop.S, loop.B0, loop.B0, loop.R))
        #: Bound of the interpolation error of ``|A| + |B_0| + |R|`` between samples.
        self.error = float(sixth * dw**6 / 46080.0)

    def extend(self, W: float) -> None:
        """Samples up to ``W`` (at least 16)."""
        n = max(int(np.ceil(W / self.dw)), 16)
        if n <= self.w.size:
            return
        s = 1j * self.dw * np.arange(self.w.size + 1, n + 1)
        new = []
        for P, P1 in zip((self.loop.S, self.loop.B0, self.loop.R), self._first):
            new += [P(s), 1j * P1(s), -P1.deriv_at(s)]  # P(i w) and its first two w-derivatives
        self.parts = tuple(np.concatenate([old, part]) for old, part in zip(self.parts, new))
        self._stack = np.reshape(np.stack(self.parts), (3, 3, -1))
        self.w = np.concatenate([self.w, s.imag])

    def samples(self, n: int) -> _Axis:
        """The loop at the first ``n`` samples, with slopes."""
        S, dS, _, B0, dB0, _, R, dR, _ = (p[:n] for p in self.parts)
        return _Axis(self.w[:n], S - B0, B0, R, dS - dB0, dB0, dR)

    def model(self, j: NDArray[np.intp], x: NDArray[np.float64], slopes: bool = False) -> _Axis:
        """The interpolated loop at ``x`` in ``[w_j, w_{j+1}]``."""
        h, t = self.dw, (x - self.w[j]) / self.dw
        t2, t3, t4, t5 = t**2, t**3, t**4, t**5
        basis = (
            1 - 10 * t3 + 15 * t4 - 6 * t5,
            (t - 6 * t3 + 8 * t4 - 3 * t5) * h,
            (t2 - 3 * t3 + 3 * t4 - t5) * h**2 / 2,
            10 * t3 - 15 * t4 + 6 * t5,
            (-4 * t3 + 7 * t4 - 3 * t5) * h,
            (t3 - 2 * t4 + t5) * h**2 / 2,
        )

        # rows S, B_0, R at the left and right samples of each cell; the sums run in the order
        # b_0 f_j + b_1 f'_j + b_2 f''_j + b_3 f_{j+1} + b_4 f'_{j+1} + b_5 f''_{j+1}
        left, right = self._stack[:, :, j], self._stack[:, :, j + 1]

        def interp(b: tuple) -> NDArray[np.complex128]:
            return (
                b[0] * left[:, 0]
                + b[1] * left[:, 1]
                + b[2] * left[:, 2]
                + b[3] * right[:, 0]
                + b[4] * right[:, 1]
                + b[5] * right[:, 2]
            )

        s, b0, r = interp(basis)
        if not slopes:
            return _Axis(x, s - b0, b0, r)
        slope = (
            (-30 * t2 + 60 * t3 - 30 * t4) / h,
            1 - 18 * t2 + 32 * t3 - 15 * t4,
            (2 * t - 9 * t2 + 12 * t3 - 5 * t4) * h / 2,
            (30 * t2 - 60 * t3 + 30 * t4) / h,
            -12 * t2 + 28 * t3 - 15 * t4,
            (3 * t2 - 8 * t3 + 5 * t4) * h / 2,
        )
        ds, db0, dr = interp(slope)
        return _Axis(x, s - b0, b0, r, ds - db0, db0, dr)


class _Scan:
    """The loop on ``0 < w <= W``: its critical gains and crossing curves ``K_pm(w)``.

    The verdict "stable for every delay in ``[0, delta_max]``" can change with ``K`` only
    at a *critical gain*: a root on the axis at ``delta = delta_max`` (``Im K_delta(w) = 0``),
    at ``delta = 0`` (the same with ``delta = 0``; ``w = 0`` included), or a pair birth with
    delay ``<= delta_max`` (an extremum in ``w`` of a root ``K_pm(w)`` of ``g``). Gains whose
    crossing frequencies all lie in ``(0, W]`` (every ``|K|`` whose frequency bound is ``<= W``)
    have all their critical gains found, up to the sampling step ``dw``. Every root is first
    located on the interpolants of :class:`_AxisGrid`; critical gains in ``window`` are then
    solved on the loop to ``_W_RTOL`` in ``w``, the others only keep an estimate
    (:attr:`beyond`), to choose the next window.
    """

    def __init__(self, grid: _AxisGrid, delta_max: float, kb: float, W: float, window: tuple[float, float]) -> None:
        loop = grid.loop
        self.loop, self.grid, self.delta_max = loop, grid, delta_max
        lo_w, hi_w = window
        grid.extend(W)
        n = max(int(np.ceil(W / grid.dw)), 16)
        ax = grid.samples(n)
        w = ax.w
        # what the interpolants may be off by: in K (|R| = |q| for U_BS2) and in the phase of B/A
        r_min = float(np.min(np.abs(ax.r)))
        self.margin = margin = _MODEL_SAFETY * grid.error / r_min + 1e-12 * kb
        self.phase_margin = _MODEL_SAFETY * grid.error / max(float(np.min(np.abs(ax.a))), 1e-300)
        crit: list[GainEnd] = []
        self.beyond: list[float] = []  # estimates of the critical gains outside the window

        def keep(K: float, kind: str, x: float, delta: float) -> None:
            if lo_w <= K <= hi_w:
                given = 0.0 if kind in ("crossing", "nominal") else None  # delta_max or 0: exact
                crit.append(GainEnd(float(K), kind, float(x), float(delta), delay_accuracy=given))
            elif -kb < K < kb:
                self.beyond.append(float(K))

        def sort_out(K_model: NDArray[np.float64]) -> NDArray[np.bool_]:
            """Mask of the model's critical gains to solve on the loop; the rest go to ``beyond``."""
            near = (K_model >= lo_w - margin) & (K_model <= hi_w + margin)
            self.beyond.extend(K_model[~near & (np.abs(K_model) < kb)].tolist())
            return near

        # (a) and (c): a root on the axis at delta = delta_max or 0, Im K_delta(w) = 0
        for delta, event in ((delta_max, "crossing"), (0.0, "nominal")):

            def imag_k(at: _Axis, delta: float = delta) -> NDArray[np.float64]:
                return at.k_at_delay(delta).imag

            j = _sign_changes(ax.k_at_delay(delta).imag)
            xm = self._model_roots(imag_k, j, ("delay", delta))
            near = sort_out(grid.model(j, xm).k_at_delay(delta).real)
            xs = self._exact(imag_k, j[near], xm[near])
            for K, x in zip(loop.axis(xs).k_at_delay(delta).real, xs):
                keep(K, event, x, delta)
        s0 = np.array([0j])
        K0 = -complex(loop.S(s0)[0]) / complex(loop.R(s0)[0])  # s = 0 is a root for every delay
        if abs(K0.imag) <= 1e-12 * max(abs(K0), 1.0):
            keep(K0.real, "nominal", 0.0, 0.0)
        # (b): the branches K_pm(w) of |A| = |B|, their extrema (pair births) and junctions (D = 0)
        D, m, root = ax.branches()
        dm, dD = ax.branch_slopes()
        valid = D > 0
        jj = _sign_changes(D)
        xj = self._model_roots(_junction, jj, ("junction",))
        Kj = grid.model(jj, xj).branches()[1]
        self.nodes: list[tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.intp], NDArray[np.int_]]] = []
        for sign in (1.0, -1.0):
            Kb = np.where(valid, m + sign * root, np.nan)
            slope = np.where(valid, dm + sign * dD / (2.0 * np.where(valid, root, 1.0)), 0.0)
            je = _sign_changes(slope, valid)

            def dK(at: _Axis, sign: float = sign) -> NDArray[np.float64]:
                return _branch_slope(at, sign)

            xe = self._model_roots(dK, je, ("extremum", sign), slopes=True)
            at = grid.model(je, xe)
            Ke = at.branches()[1] + sign * at.branches()[2]
            births = at.delays(Ke) <= delta_max + self.phase_margin / np.maximum(xe, 1e-300)
            near = births & sort_out(np.where(births, Ke, np.inf))
            xs = self._exact(dK, je[near], xe[near], slopes=True)
            at = loop.axis(xs)
            _, mx, rx = at.branches()
            for K, x, d in zip(mx + sign * rx, xs, at.delays(mx + sign * rx)):
                if d <= delta_max:
                    keep(K, "pair_birth", x, d)
            # nodes of the branch: samples (exact), extrema and junctions (interpolated), with their cells
            nw = np.concatenate([w, xe, xj])
            order = np.argsort(nw, kind="stable")
            cell = np.concatenate([np.arange(n), je, jj])
            kind = np.concatenate([np.zeros(n, dtype=int), np.ones(xe.size, dtype=int), np.full(xj.size, 2)])
            self.nodes.append((nw[order], np.concatenate([Kb, Ke, Kj])[order], cell[order], kind[order]))
        self.critical = sorted(crit, key=lambda e: (e.K, _KIND_ORDER[e.kind]))

    def _model_roots(
        self, f: Callable[[_Axis], NDArray[np.float64]], j: NDArray[np.intp], key: tuple, slopes: bool = False
    ) -> NDArray[np.float64]:
        """Zeros of ``f`` of the interpolated loop in the cells ``[w_j, w_{j+1}]`` (a sign change each).

        Kept by the grid under ``key``, per cell: a later window on the same (longer) grid solves
        its new cells only (each cell is solved on its own, elementwise: the same root whatever
        the other cells solved with it).
        """
        memo = self.grid.roots.setdefault(key, {})
        new = np.array([c for c in j.tolist() if c not in memo], dtype=np.intp)
        if new.size:
            w, model = self.grid.w, self.grid.model
            f_lo, f_hi = f(model(new, w[new], slopes)), f(model(new, w[new + 1], slopes))
            roots = _solve(lambda x, k: f(model(new[k], x, slopes)), w[new], w[new + 1], f_lo, f_hi, _MODEL_RTOL)
            memo.update(zip(new.tolist(), roots.tolist()))
        return np.array([memo[c] for c in j.tolist()], dtype=float)

    def _exact(
        self,
        f: Callable[[_Axis], NDArray[np.float64]],
        j: NDArray[np.intp],
        x0: NDArray[np.float64],
        slopes: bool = False,
    ) -> NDArray[np.float64]:
        """Zeros of ``f`` of the loop itself near the model's ``x0`` (in the cells ``j``)."""
        if not j.size:
            return x0
        loop, w = self.loop, self.grid.w
        half = _BRACKET_CELLS * self.grid.dw
        lo, hi = np.maximum(x0 - half, w[j]), np.minimum(x0 + half, w[j + 1])
        f_lo, f_hi = f(loop.axis(lo, slopes)), f(loop.axis(hi, slopes))
        wide = np.sign(f_lo) * np.sign(f_hi) > 0  # the model's root is too far off: the whole cell
        if wide.any():
            lo[wide], hi[wide] = w[j[wide]], w[j[wide] + 1]
            f_lo[wide], f_hi[wide] = f(loop.axis(lo[wide], slopes)), f(loop.axis(hi[wide], slopes))
        return _solve(lambda x, k: f(loop.axis(x, slopes)), lo, hi, f_lo, f_hi)

    def crossings(self, K: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Crossing frequencies of the loop with gain ``K`` in ``(0, W]`` and their smallest delays.

        From the interpolated loop, except where its error matters: an extremum or junction
        of a branch within :attr:`margin` of ``K`` is solved again on the loop, and so are the
        crossings next to it, and every crossing whose delay is closer to ``delta_max`` than
        the interpolants' error allows.
        """
        loop, model = self.loop, self.grid.model
        ws, ds = [], []
        for sign, (nw, nK, cell, kind) in zip((1.0, -1.0), self.nodes):
            doubt = (kind > 0) & (np.abs(nK - K) <= self.margin)
            if doubt.any():

                def slope_of(at: _Axis, sign: float = sign) -> NDArray[np.float64]:
                    return _branch_slope(at, sign)

                nw, nK = nw.copy(), nK.copy()
                ext, jun = np.flatnonzero(doubt & (kind == 1)), np.flatnonzero(doubt & (kind == 2))
                nw[ext] = self._exact(slope_of, cell[ext], nw[ext], slopes=True)
                nw[jun] = self._exact(_junction, cell[jun], nw[jun])
                _, mx, rx = loop.axis(nw[doubt]).branches()
                nK[doubt] = mx + np.where(kind[doubt] == 1, sign * rx, 0.0)
            f = nK - K
            i = _sign_changes(f, np.isfinite(f))
            j = cell[i]

            def on_branch(at: _Axis, sign: float = sign) -> NDArray[np.float64]:
                _, mx, rx = at.branches()
                return mx + sign * rx - K

            def interpolated(x: NDArray[np.float64], k: NDArray[np.intp], j: NDArray[np.intp] = j) -> NDArray:
                return on_branch(model(j[k], x))

            x = _solve(interpolated, nw[i], nw[i + 1], f[i], f[i + 1], _MODEL_RTOL)
            exact = doubt[i] | doubt[i + 1]
            if exact.any():
                e = np.flatnonzero(exact)
                x[e] = _solve(lambda x, k: on_branch(loop.axis(x)), nw[i[e]], nw[i[e] + 1], f[i[e]], f[i[e] + 1])
            d = np.where(exact, 0.0, model(j, x).delays(K))
            close = exact | (np.abs(d - self.delta_max) * x <= self.phase_margin)
            if close.any():
                x[close & ~exact] = self._exact(on_branch, j[close & ~exact], x[close & ~exact])
                d[close] = loop.axis(x[close]).delays(K)
            ws.append(x)
            ds.append(d)
        return np.concatenate(ws), np.concatenate(ds)


def nominally_stable(loop: AffineGainLoop, K: float) -> bool:
    """Certified: ``F(.; 0, K)`` has no zero with ``Re s >= 0``.

    For ``U_BS2(K)`` the kernels cancel at ``delta = 0``: ``F = 1 - (rho - K) q e^{-tau s}``, whose
    zeros lie on ``Re s = ln|(rho - K) q| / tau`` (closed form, eq. (60) with
    ``delta = 0``). Otherwise the certified count of :func:`nrobust.margins.unstable_count` in the
    root-free radius (:attr:`~nrobust.margins.UnstableCount.stable`).
    """
    F = loop.S + loop.R * K  # = A + B_0 + K R = F(.; 0, K)
    terms = F.point_terms
    if not F.distributed and len(terms) <= 2 and terms[0][1] == 0.0 and all(p.size == 1 for p, _ in terms):
        return len(terms) == 1 or abs(terms[1][0][0]) < abs(terms[0][0][0])  # c_0 + c_1 e^{-t s}
    return unstable_count(F, root_free_region(F).radius).stable


def _scan_step(loop: AffineGainLoop, delta_max: float) -> float:
    """``pi / (_SCAN_STEPS T)`` rounded down to a power of two.

    A power of two makes every sample ``k dw`` exact, so that each extension of the grid
    is recognised as a uniform line (chirp-z) by :meth:`QuasiPolynomial.__call__`.
    """
    T = 2.0 * max(loop.A.max_delay, loop.B0.max_delay, loop.R.max_delay) + delta_max
    return float(2.0 ** np.floor(np.log2(np.pi / (_SCAN_STEPS * max(T, 1e-3)))))


def locate_gain_ends(
    loop: AffineGainLoop, delta_max: float, kb: float, tol: float, max_evals: int
) -> list[tuple[GainEnd, GainEnd]]:
    """The admissible intervals of ``(-kb, kb)`` as pairs of :class:`GainEnd`, located by their equations.

    The arguments are trusted (the caller validates them). A scan of the axis up to the
    frequency bound of the largest gain considered (the *cap*) finds the critical gains; the
    verdict is constant between two of them and is taken at their midpoint (crossings of
    :meth:`_Scan.crossings` with a delay ``<= delta_max``; nominal stability counted once
    between two nominal critical gains). While an admissible interval reaches a cap, the cap
    moves towards ``kb``; an interval still admissible within ``tol`` of ``kb`` ends at the
    strong-stability limit.

    The ends are located, not verified: :func:`~nrobust.margins.admissible.check_gain_end`
    verifies each (``k_region`` does).

    Parameters
    ----------
    loop : AffineGainLoop
        The loop ``A + (B_0 + K R) e^{-delta s}``.
    delta_max : float
        The delays ``[0, delta_max]`` to tolerate (``> 0``, finite).
    kb : float
        The strong-stability bound: the difference operator is strongly stable for ``|K| < kb``
        and not beyond.
    tol : float
        An interval still admissible within ``tol`` of ``+-kb`` ends at ``+-kb``.
    max_evals : int
        Work bound of the scan (about six evaluations per sample of the axis).

    Returns
    -------
    list of (GainEnd, GainEnd)
        The lower and upper end of each admissible interval, in increasing ``K``.

    Raises
    ------
    CertificationError
        An admissible interval reaches gains whose crossing frequencies extend beyond what
        ``max_evals`` samples of the axis cover.
    """
    dw = _scan_step(loop, delta_max)
    grid = _AxisGrid(loop, dw)
    second = AxisBound.of(loop)

    def crossing_bound(lo: float, hi: float) -> float:
        """Above every crossing frequency of the gains in ``[lo, hi]`` (``lo <= 0 <= hi``; 0: none): the smaller
        of :class:`AxisBound`'s and the first-order bounds at the ends (the latter alone without the former)."""
        first = [frequency_bound(loop.A, loop.B(c)) for c in (lo, hi)]
        W1 = max(0.0 if b is None else b[0] for b in first)
        if second is None:
            return W1
        # g is concave in K: the first-order bounds at the ends hold inside (smaller where |rho q| is small)
        return second.W(lo, hi) if any(b is None for b in first) else min(second.W(lo, hi), W1)

    caps = [-kb * (1.0 - _FIRST_CAP), kb * (1.0 - _FIRST_CAP)]
    open_end = [False, False]
    nominal: dict[tuple[float | None, float | None], bool] = {}
    # verdicts between two critical gains (not caps): a later, wider scan finds the same crossings there
    between: dict[tuple[float, float], bool] = {}
    while True:
        Ws = [crossing_bound(min(c, 0.0), max(c, 0.0)) for c in caps]
        W = max(Ws)
        if W / dw > max_evals / 6:
            far = " and ".join(f"K = {c:.10g}" for c, Wc in zip(caps, Ws) if Wc / dw > max_evals / 6)
            raise CertificationError(
                f"k_region: an admissible interval reaches {far}, {kb - max(abs(c) for c in caps):.3g} from the "
                f"strong-stability limit {kb:.10g}, where crossing frequencies extend to W = {W:.6g}: locating "
                f"its end needs about {6 * W / dw:.3g} evaluations, beyond the work bound max_evals={max_evals}"
            )
        scan = _Scan(grid, delta_max, kb, W, (caps[0], caps[1]))
        inside = [c for c in scan.critical if caps[0] < c.K < caps[1]]
        cuts = [caps[0], *[c.K for c in inside], caps[1]]
        nominal_cuts = [c.K for c in inside if c.kind == "nominal"]
        ok = []
        for lo, hi in itertools.pairwise(cuts):
            mid = 0.5 * (lo + hi)
            g = sum(1 for x in nominal_cuts if x < mid)
            key = (nominal_cuts[g - 1] if g else None, nominal_cuts[g] if g < len(nominal_cuts) else None)
            if key not in nominal:
                nominal[key] = nominally_stable(loop, mid)
            if not nominal[key]:
                ok.append(False)
                continue
            if (lo, hi) not in between:
                free = not np.any(scan.crossings(mid)[1] <= delta_max)
                if lo not in caps and hi not in caps:
                    between[(lo, hi)] = free
                ok.append(free)
                continue
            ok.append(between[(lo, hi)])
        moved = False
        for side, sgn in ((1, 1.0), (0, -1.0)):
            if open_end[side] or not ok[-1 if side else 0]:
                continue
            # past the first critical gain seen beyond the cap, but at most _CAP_SHRINK times closer
            # to kb (gains past the cap have crossings above W, not scanned yet); within tol of kb
            # the interval ends at the strong-stability limit
            cap = abs(caps[side])
            past = [sgn * K for K in scan.beyond if cap < sgn * K < kb - tol]
            new = kb - (kb - cap) / _CAP_SHRINK
            if past:
                new = min(new, min(past) + (kb - min(past)) / _CAP_SHRINK)
            new = min(max(new, cap + 0.5 * tol), kb - tol)
            if not past and crossing_bound(min(0.0, sgn * (kb - tol)), max(0.0, sgn * (kb - tol))) <= W:
                # the scan covers every gain up to kb - tol
                new = kb - tol
            if new <= cap:
                open_end[side] = True
                continue
            caps[side] = sgn * new
            moved = True
        if not moved:
            break
    lower = GainEnd(-kb, "strong_stability", float("inf"), 0.0, None, 0.0, 0.0)
    upper = GainEnd(kb, "strong_stability", float("inf"), 0.0, None, 0.0, 0.0)
    ends = [lower, *inside, upper]
    return [(ends[k], ends[k + 1]) for k in range(len(ok)) if ok[k]]
