"""Stability on the whole square of speed mismatches, proven in ball arithmetic: :func:`prove_transport_square`.

On an uncoupled plant (a :class:`~nrobust.hyperbolic.plants.hyperbolic2x2.TransportSystem`, or a
``Hyperbolic2x2`` with both couplings zero) the laws designed on the nominal plant are
``U = k u(t, 1)``, filtered by ``(1 + a s)/(1 + b s)`` for a
:class:`~nrobust.hyperbolic.loops.controllers.FilteredController` (eqs. (10), (13), (16)), and hold
no speed. The plant transporting at ``lam (1 + e_lam)`` and ``mu (1 + e_mu)`` closes the loop

    ``F(s; tau, delta) = d(s) (1 - rho q e^{-tau s}) - k q n(s) e^{-(tau + delta) s}``,
    ``d = 1 + b s``, ``n = 1 + a s`` (``d = n = 1`` unfiltered),

whose only dependence on the mismatch is the round trip ``tau = 1/(lam (1 + e_lam)) + 1/(mu (1 +
e_mu))``: the square ``[-eps, eps]^2`` maps onto ``[T_lo, T_hi] = [tau_0/(1 + eps), tau_0/(1 - eps)]``
(``tau_0 = 1/lam + 1/mu``; ``T_lo`` at ``(eps, eps)``, ``T_hi`` at ``(-eps, -eps)``), and the
question is about the rectangle ``P = [T_lo, T_hi] x [d_min, d_max]`` of ``(tau, delta)``.

The proof is a no-crossing argument on the connected set ``P`` (every coefficient is a ball that
holds both the exact product of the plant's numbers and the double the loop of a corner stores,
so the family holds the PDE at every mismatch and the corners' loops alike):

1. *No zero from infinity.* For ``Re s >= 0``, ``|e^{-tau s}| <= 1``, so
   ``|F| >= |d(s)| - |rho q d(s)| - |k q n(s)|``, a bound ``L(|s|) - U(|s|)`` with ``L`` the modulus of
   ``d`` below (``|1 + b s|^2 >= 1 + b^2 |s|^2`` for ``b > 0``) and ``U`` affine in ``|s|``. When the
   difference operator is strongly stable, ``c_D = |rho q| + |k q a / b| < 1`` (unfiltered: ``|rho
   q| + |k q|``, independent of ``tau`` and ``delta``), ``L > U`` for ``|s| >= W``, proven in ball
   arithmetic from the convexity of ``L^2 - U^2`` (a quadratic in ``|s|``). Then no zero has
   ``Re s >= 0`` and ``|s| >= W`` for any ``(tau, delta)`` in ``P``. If ``W = 0`` there is none in
   ``Re s >= 0`` at all (e.g. ``|rho q| + |k q| < 1`` unfiltered): stable on ``P``, nothing else
   to do.
2. *No zero on the imaginary axis.* ``F(i w) = 0`` needs ``|A(i w)| = |B(i w)|`` (``A = d (1 - rho
   q e^{-i w tau})``, ``B = -k q n e^{-i w tau}``) and ``w delta + arg(-A/B)`` a multiple of
   ``2 pi``. Boxes of ``(w, tau)`` covering ``[0, W] x [T_lo, T_hi]`` are cleared, in ball
   arithmetic, by the sign of ``|A|^2 - |B|^2`` or by every crossing delay ``(2 pi k - arg(-A/B))/w``
   of the box lying outside ``[d_min, d_max]``; an undecided box is halved (``w`` or ``tau``, the
   one moving the phase ``w (tau + delta)`` most), up to ``max_boxes`` boxes. ``w < 0`` follows
   by conjugation (real coefficients).
3. *One point.* The loop of a corner, proven stable on the window
   (:func:`nrobust.design.window_stability` with ``rigorous=True``), lies in the family.

The zeros in ``Re s >= 0`` then stay in the half-disc ``|s| < W``, none reaches its boundary as
``(tau, delta)`` moves in ``P``, so their number is the same at every point (the argument
principle), zero at the corner: ``F`` has no zero in ``Re s >= 0`` anywhere on ``P``. No zero in
``Re s >= 0`` and a strongly stable difference operator make the loop exponentially stable (the
criterion of the paper's Theorems 3 and 4, :func:`~nrobust.hyperbolic.loops.controllers.characteristic`),
for every ``(e_lam, e_mu)`` in the square and every delay in the window.
"""

from __future__ import annotations

import cmath
import math
from collections.abc import Sequence
from typing import Any, NamedTuple

from ..._digits import lower_bound_text, upper_bound_text
from ..._flint import ball_lower, ball_upper, working_precision
from ..._validate import finite_real, positive, positive_int
from ...design.gain import DelayWindow, check_delays
from ...errors import ParameterError
from ...quasipoly import QuasiPolynomial
from ..plants.hyperbolic2x2 import Hyperbolic2x2

__all__ = ["MAX_SQUARE_BOXES", "SquareProof", "crossing_free", "prove_transport_square"]

#: Default work bound of :func:`prove_transport_square`: boxes of ``(w, tau)`` examined (about
#: 60 us each on a shared core; a filtered loop at ``eps = 0.2`` takes a few thousand).
MAX_SQUARE_BOXES = 200_000

#: Relative width below which an undecided box is not halved again: a zero on the imaginary axis
#: sits in it (or a crossing delay at an end of the window), and no subdivision decides.
_MIN_WIDTH = 1e-11


class SquareProof(NamedTuple):
    """The outcome of :func:`prove_transport_square`.

    Attributes
    ----------
    proven : bool
        Exponentially stable for every ``(e_lam, e_mu)`` of the square and every delay of the
        window, proven in ball arithmetic.
    reason : str
        What is proven, or why it is not (what would help).
    tau : (float, float)
        Floats enclosing the round trips of the family (the square's and the corners' stored ones).
    frequency_bound : float
        ``W``: no zero with ``Re s >= 0`` and ``|s| >= W`` (``nan`` when not proven).
    strong_stability : float
        An upper bound of ``c_D`` (``|rho q| + |k q a / b|``; unfiltered ``|rho q| + |k q|``).
    boxes : int
        Boxes of ``(w, tau)`` examined.
    candidate : float
        The round trip ``tau`` of the box the subdivision stopped at (``nan`` otherwise): the
        mismatch to examine for a zero on the imaginary axis.
    base : int
        The index in ``corners`` of the loop the argument starts from (``-1`` when none is used:
        the tail bound alone, or not proven).
    point : (float, float)
        The mismatch ``(e_lam, e_mu)`` of the box the subdivision stopped at on a coupled plant
        (:func:`~nrobust.hyperbolic.analyses.mismatch_coupled.prove_coupled_square`; ``nan``
        otherwise).
    undecided : tuple of (float, float, float, float)
        Boxes ``(e_lam_lo, e_lam_hi, e_mu_lo, e_mu_hi)`` of mismatches the subdivision left undecided when
        it stopped (empty otherwise): the box it stopped at first, then those still pending, the
        smallest first (where the subdivision went deepest). On an uncoupled plant each is the
        diagonal box of an undecided range of ``tau``: every mismatch of it has its round trip in that
        range, to rounding (``tau`` falls in each speed). The edges may pass the square's by the widening that
        holds the corners' rounded speeds.
    """

    proven: bool
    reason: str
    tau: tuple[float, float]
    frequency_bound: float
    strong_stability: float
    boxes: int
    candidate: float
    base: int = -1
    point: tuple[float, float] = (math.nan, math.nan)
    undecided: tuple[tuple[float, float, float, float], ...] = ()


def _poly(coefficients: Sequence[Any], s: Any) -> Any:
    """``sum_j c_j s^j`` (Horner) for ball coefficients."""
    out = coefficients[-1] * 1
    for c in reversed(coefficients[:-1]):
        out = out * s + c
    return out


class _Family:
    """``F(s; tau, delta) = P0(s) + P1(s) e^{-tau s} + Q1(s) e^{-(tau + delta) s}``, coefficients as balls."""

    def __init__(self, flint: Any, P0: list[Any], P1: list[Any], Q1: list[Any], tau: Any) -> None:
        self.flint, self.P0, self.P1, self.Q1, self.tau = flint, P0, P1, Q1, tau

    def factors(self, w: Any, tau: Any) -> tuple[Any, Any]:
        """``A(i w)`` and ``B(i w)`` on the box ``w x tau`` (``B`` holds ``e^{-i w tau}``)."""
        acb = self.flint.acb
        s = acb(0, w)
        z = acb(0, -(w * tau)).exp()
        return _poly(self.P0, s) + _poly(self.P1, s) * z, _poly(self.Q1, s) * z


def _coefficients(term: tuple[Any, float] | None, size: int) -> list[float] | None:
    """The stored coefficients of a point term padded to ``size`` (None when longer)."""
    if term is None:
        return [0.0] * size
    c = [float(x) for x in term[0]]
    return None if len(c) > size else c + [0.0] * (size - len(c))


def _stored(A: QuasiPolynomial, B: QuasiPolynomial, size: int) -> tuple[list[list[float]], float | None] | str:
    """``(P0, P1, Q1)`` and the round trip of a corner's loop, or why it is not of the family's form."""
    if A.distributed or B.distributed:
        return "its loop has a distributed term"
    delays = {float(t) for _, t in A.point_terms if t != 0.0} | {float(t) for _, t in B.point_terms}
    if len(delays) > 1 or len({float(t) for _, t in A.point_terms}) != len(A.point_terms) or len(B.point_terms) > 1:
        return "its loop is not d(s) (1 - rho q e^{-tau s}) - k q n(s) e^{-(tau + delta) s}"
    tau = delays.pop() if delays else None
    by_delay = {float(t): (p, t) for p, t in A.point_terms}
    parts = [
        _coefficients(by_delay.get(0.0), size),
        _coefficients(by_delay.get(tau) if tau is not None else None, size),
        _coefficients(B.point_terms[0] if B.point_terms else None, size),
    ]
    if any(p is None for p in parts):
        return "its loop is of a higher degree than the filter's"
    return [p for p in parts if p is not None], tau


def _tail(flint: Any, fam: _Family) -> tuple[float, float] | str:
    """``(W, c_D)``: no zero with ``Re s >= 0``, ``|s| >= W`` on the family, proven; or why not."""
    arb = flint.arb
    up = [[arb(c.abs_upper()) for c in part] for part in (fam.P0, fam.P1, fam.Q1)]
    low0 = [arb(c.abs_lower()) for c in fam.P0]
    # P0 = d = 1 or 1 + b s with b > 0 (FilteredController): the stored doubles are the exact ones
    if len(fam.P0) == 1:  # a difference equation: |F| >= |p00| - |p10| - |q0| on Re s >= 0
        c_d = (up[1][0] + up[2][0]) / low0[0]
        if c_d < 1:
            return 0.0, ball_upper(c_d)
        return (
            "the difference operator 1 - rho q e^{-tau s} - k q e^{-(tau + delta) s} is not proven strongly stable "
            f"(|rho q| + |k q| <= {upper_bound_text(ball_upper(c_d))}, not < 1): the loop is not stable for every "
            "delay of a window and every speed of the square (Hale's condition); a smaller gain |k| decides"
        )
    # |1 + b s|^2 = 1 + 2 b Re s + b^2 |s|^2 >= L(|s|)^2 = 1 + b^2 |s|^2 on Re s >= 0, and
    # |P1(s)| + |Q1(s)| <= U(|s|) = u0 + u1 |s|
    u0, u1 = up[1][0] + up[2][0], up[1][1] + up[2][1]
    lead = low0[1]
    c_d = u1 / lead
    if not c_d < 1:
        return (
            "the difference operator is not proven strongly stable (c_D = |rho q| + |k q a / b| <= "
            f"{upper_bound_text(ball_upper(c_d))}, not < 1): zeros come from infinity; a filter with |a| smaller "
            "against b decides"
        )
    # L^2 - U^2 = h(r) = (p01^2 - u1^2) r^2 - 2 u0 u1 r + p00^2 - u0^2, convex: L > U on [W, inf)
    # once h(W) > 0 and h'(W) > 0 (or h has no real root)
    a2, a1, a0 = lead * lead - u1 * u1, -2 * u0 * u1, low0[0] * low0[0] - u0 * u0
    if a1 * a1 - 4 * a2 * a0 < 0 or (a0 > 0 and a1 >= 0):
        return 0.0, ball_upper(c_d)
    root = (-a1 + (a1 * a1 - 4 * a2 * a0).nonnegative_part().sqrt()) / (2 * a2)
    W = max(ball_upper(root), 0.0) * (1.0 + 1e-6) + 1e-9
    r = arb(W)
    if a2 * r * r + a1 * r + a0 > 0 and 2 * a2 * r + a1 > 0:
        return W, ball_upper(c_d)
    return f"the tail bound of |F| on Re s >= 0 could not be proven (c_D <= {upper_bound_text(ball_upper(c_d))})"


class _Axis:
    """Clears boxes of ``(w, tau)``: no zero of ``F(i w; tau, delta)`` for any ``delta`` of the window."""

    def __init__(self, flint: Any, fam: _Family, d_lo: float, d_hi: float) -> None:
        self.flint, self.fam = flint, fam
        self.d_lo, self.d_hi = d_lo, d_hi

    def clear(self, w0: float, w1: float, t0: float, t1: float) -> bool:
        """True when no ``F(i w; tau, delta)`` with ``w, tau`` in the box and ``delta`` in the window is 0."""
        arb = self.flint.arb
        w = arb(w0).union(arb(w1))
        A, B = self.fam.factors(w, arb(t0).union(arb(t1)))
        return crossing_free(self.flint, A, B, w, self.d_lo, self.d_hi)


def _diagonal_boxes(
    tau0: float, intervals: Sequence[tuple[float, float]]
) -> tuple[tuple[float, float, float, float], ...]:
    """The diagonal boxes ``[e_lo, e_hi]^2`` of mismatches whose round trips ``tau_0 / (1 + e)`` on the diagonal
    span the ranges ``[t0, t1]`` of ``tau`` (``tau_0`` the nominal one; repeated ranges once)."""
    out: dict[tuple[float, float, float, float], None] = {}
    for t0, t1 in intervals:
        lo, hi = tau0 / t1 - 1.0, tau0 / t0 - 1.0
        out[(lo, hi, lo, hi)] = None
    return tuple(out)


def crossing_free(flint: Any, A: Any, B: Any, w: Any, d_lo: float, d_hi: float) -> bool:
    """True when ``A + B e^{-i w delta} != 0`` for every ``w`` in the ball ``w >= 0`` and ``delta`` in ``[d_lo, d_hi]``.

    ``A``, ``B`` are ``acb`` enclosures of the factors on the box (every point of it): cleared by
    the sign of ``|A|^2 - |B|^2``, by ``A + B e^{-i w delta}`` enclosed away from 0 with ``w delta`` a
    ball (near ``w = 0``, where ``arg(-A/B)`` is a multiple of ``2 pi`` and the crossing delays are not
    resolved: ``F(0) = A + B`` for every delay), or by every crossing delay ``(2 pi k - arg(-A/B))/w``
    lying outside the window.
    """
    arb, acb = flint.arb, flint.acb
    gap = abs(A) ** 2 - abs(B) ** 2
    if gap > 0 or gap < 0:  # |A| != |B|: A + B e^{-i w delta} != 0 for every real delta
        return True
    if B.contains(0) or not B.is_finite():
        return False
    delays = arb(d_lo) if d_lo == d_hi else arb(d_lo).union(arb(d_hi))
    if not (A + B * acb(0, -(w * delays)).exp()).contains(0):
        return True
    Q = -A / B  # F = 0 iff e^{-i w delta} = Q
    mid = complex(float(Q.real.mid()), float(Q.imag.mid()))
    if mid == 0:
        return False
    turn = float(cmath.phase(mid))
    rotated = Q * acb(0, -arb(turn)).exp()
    if not rotated.real > 0:
        return False
    phase = arb(turn) + rotated.arg()
    two_pi = 2 * arb.pi()
    # w delta + phase must be a multiple of 2 pi: the crossing delays (2 pi k - phase) / w
    span = (w * delays + phase) / two_pi
    if not span.contains_integer():
        return True
    if not w.lower() > 0:
        return False
    k_lo, k_hi = math.floor(ball_lower(span)), math.ceil(ball_upper(span))
    if k_hi - k_lo > 10_000:
        return False
    for k in range(k_lo, k_hi + 1):
        delay = (two_pi * k - phase) / w
        if not (delay < d_lo or delay > d_hi):
            return False
    return True


def _hull(flint: Any, exact: Any, stored: Sequence[float]) -> Any:
    """The ball holding ``exact`` and every stored double."""
    out = exact
    for v in stored:
        out = out.union(flint.arb(v))
    return out


def prove_transport_square(
    system: Hyperbolic2x2,
    k: float,
    filt: tuple[float, float] | None,
    eps: float,
    delays: tuple[float, float],
    corners: Sequence[tuple[QuasiPolynomial, QuasiPolynomial, DelayWindow]],
    *,
    max_boxes: int = MAX_SQUARE_BOXES,
) -> SquareProof:
    """Prove ``F(s; tau, delta)`` (module docstring) stable for every mismatch of the square and delay of the window.

    Parameters
    ----------
    system : Hyperbolic2x2 or TransportSystem
        The nominal plant, uncoupled (``system.uncoupled``).
    k : float
        The law's gain on ``u(t, 1)`` (``-K`` for ``U_BS2(K)``, ``rho`` for ``U_BS``).
    filt : (float, float) or None
        The law's filter ``(a, b)``: ``(1 + a s)/(1 + b s)``.
    eps : float
        The tolerance, ``0 < eps < 1``.
    delays : (float, float)
        The window ``[d_min, d_max]`` (``0 <= d_min <= d_max``, ``d_max > 0``).
    corners : sequence of (QuasiPolynomial, QuasiPolynomial, DelayWindow)
        The loops ``(A, B)`` of the corners and their verdicts (each the verdict of its own loop
        ``(A, B)``); their coefficients and round trips join the family, and one proven stable on
        a window that meets ``[d_min, d_max]`` is the point the argument starts from (a verdict on
        other delays is not a point of the rectangle).
    max_boxes : int, optional
        Work bound: boxes of ``(w, tau)`` examined.

    Returns
    -------
    SquareProof
        ``proven`` True with what is proven in ``reason``; otherwise False with the reason (a
        loop not of this form, a difference operator not strongly stable, no corner proven, a
        box the subdivision could not decide, the work bound).

    Raises
    ------
    ParameterError
        ``system`` coupled, ``eps`` outside ``(0, 1)``, ``delays`` not a window, ``b <= 0``, or
        ``max_boxes`` not a positive integer.
    """
    max_boxes = positive_int("max_boxes", max_boxes)
    if not isinstance(system, Hyperbolic2x2) or not system.uncoupled:
        raise ParameterError("system", "an uncoupled Hyperbolic2x2 or TransportSystem (no coupling)", system)
    k = finite_real("k", k)
    if filt is not None:
        filt = (finite_real("a", filt[0]), positive("b", filt[1]))
    eps = finite_real("eps", eps)
    if not 0.0 < eps < 1.0:
        raise ParameterError("eps", "in (0, 1) (the perturbed speeds stay positive)", eps)
    d_lo, d_hi = check_delays(delays)
    nan = math.nan
    with working_precision(53) as flint:
        arb = flint.arb
        a, b = (0.0, 0.0) if filt is None else filt
        size = 1 if filt is None else 2
        d = [arb(1), arb(b)][:size]
        n = [arb(1), arb(a)][:size]
        rq, kq = arb(system.rho) * arb(system.q), arb(k) * arb(system.q)
        exact = (list(d), [-rq * c for c in d], [-kq * c for c in n])
        tau0 = 1 / arb(system.lam) + 1 / arb(system.mu)
        taus = [tau0 / (1 + arb(eps)), tau0 / (1 - arb(eps))]
        stored_parts: list[list[list[float]]] = []
        base = None
        for n_corner, (A, B, window) in enumerate(corners):
            got = _stored(A, B, size)
            if isinstance(got, str):
                return SquareProof(False, f"corner {n_corner}: {got}", (nan, nan), nan, nan, 0, nan)
            parts, tau = got
            if tau is not None:
                taus.append(arb(tau))
            stored_parts.append(parts)
            # the point the argument starts from must lie in the rectangle: its window meets [d_min, d_max]
            meets = window.delays[0] <= d_hi and window.delays[1] >= d_lo
            if base is None and window.stable and window.certified == "proven" and meets:
                base = n_corner
        for parts in stored_parts:  # the stored doubles are those of the exact products, to rounding
            for ex, st in zip(exact, parts):
                for e_ball, v in zip(ex, st):
                    if abs(float(e_ball.mid()) - v) > 1e-12 * max(1.0, abs(v)):
                        return SquareProof(
                            False,
                            "a corner's loop is not d(s) (1 - rho q e^{-tau s}) - k q n(s) e^{-(tau + delta) s} with "
                            "the law's gain and filter",
                            (nan, nan),
                            nan,
                            nan,
                            0,
                            nan,
                        )
        P0, P1, Q1 = (
            [_hull(flint, e_ball, [p[i][j] for p in stored_parts]) for j, e_ball in enumerate(exact[i])]
            for i in range(3)
        )
        tau = taus[0]
        for t in taus[1:]:
            tau = tau.union(t)
        t_lo, t_hi = ball_lower(tau), ball_upper(tau)
        fam = _Family(flint, P0, P1, Q1, tau)
        tail = _tail(flint, fam)
        if isinstance(tail, str):
            return SquareProof(False, tail, (t_lo, t_hi), nan, nan, 0, nan)
        W, c_d = tail
        where = (
            f"tau = 1/(lam (1 + e_lam)) + 1/(mu (1 + e_mu)) in [{lower_bound_text(t_lo, 9)}, "
            f"{upper_bound_text(t_hi, 9)}]"
        )
        if W == 0.0:
            return SquareProof(
                True,
                f"no zero in Re s >= 0 for any {where} and any delay >= 0: |F| >= |d| - |rho q d| - |k q n| > 0 there "
                f"(c_D <= {upper_bound_text(c_d)} < 1)",
                (t_lo, t_hi),
                0.0,
                c_d,
                0,
                nan,
            )
        if base is None:
            return SquareProof(
                False,
                "no corner is proven stable on a window meeting the delays asked (rigorous=True on this window proves "
                "them): the argument needs one point of the rectangle",
                (t_lo, t_hi),
                W,
                c_d,
                0,
                nan,
            )
        axis = _Axis(flint, fam, d_lo, d_hi)
        stack = [(0.0, W, t_lo, t_hi)]
        boxes = 0
        while stack:
            w0, w1, t0, t1 = stack.pop()
            boxes += 1
            if axis.clear(w0, w1, t0, t1):
                continue
            small = (w1 - w0) <= _MIN_WIDTH * max(1.0, w1) and (t1 - t0) <= _MIN_WIDTH * t1
            if small or boxes >= max_boxes:
                why = (
                    f"a zero of F on the imaginary axis near w = {0.5 * (w0 + w1):.9g}, tau = {0.5 * (t0 + t1):.9g} "
                    "for a delay of the window (or a crossing delay at an end of the window): not stable there, or "
                    "not decided; a smaller tolerance or a window clear of the crossing delays decides"
                    if small
                    else f"the work bound max_boxes = {max_boxes} was reached (at w in [{w0:.6g}, {w1:.6g}], tau in "
                    f"[{t0:.9g}, {t1:.9g}]); a larger max_boxes or a smaller tolerance decides"
                )
                pending = sorted({(a, b) for _, _, a, b in stack}, key=lambda t: t[1] - t[0])
                undecided = _diagonal_boxes(system.tau, [(t0, t1), *pending])
                return SquareProof(False, why, (t_lo, t_hi), W, c_d, boxes, 0.5 * (t0 + t1), undecided=undecided)
            if (w1 - w0) * (t1 + d_hi) >= w1 * (t1 - t0):
                wm = 0.5 * (w0 + w1)
                stack += [(w0, wm, t0, t1), (wm, w1, t0, t1)]
            else:
                tm = 0.5 * (t0 + t1)
                stack += [(w0, w1, t0, tm), (w0, w1, tm, t1)]
    w_text, cd_text = upper_bound_text(W), upper_bound_text(c_d)
    return SquareProof(
        True,
        f"no zero on i [0, {w_text}] for any {where} and delay of the window ({boxes} boxes in ball arithmetic), "
        f"none with Re s >= 0 and |s| >= {w_text} (c_D <= {cd_text} < 1), and the loop of corners[{base}] proven "
        "stable on the window: the count in Re s > 0 is 0 on the whole connected set",
        (t_lo, t_hi),
        W,
        c_d,
        boxes,
        nan,
        base,
    )
