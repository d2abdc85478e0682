"""The crossings of a one-actuator ``n + 1`` loop ``F(s; delta) = A(s) + B(s) e^{-delta s}``, proven in balls.

Every quantity is enclosed in ball arithmetic for the PDE's own loop (:class:`BallNPlusM`: FLINT's
proven matrix exponential of ``C - s P``, the stored parameters taken as exact rationals), so
each statement below is a theorem about the PDE with the parameters as given.

**Frequency bound** (:func:`proven_frequency_bound`). In compound form (``m = 1``)
``A(s) + z B(s) = (a_0 + z a_1)^T exp(D - s P) b``; its principal part is an exponential sum
whose term of delay 0 is ``det exp(C_vv)`` (the ``v`` row: ``K`` does not act on it) and whose
other terms carry ``e^{-p_g s}`` or ``z e^{-p_g s}``. :meth:`NPlusMCharacteristic.ball_far_field_holds`
proves, on ``Re s >= 0`` and ``|s| >= W``, that the modulus of the term of delay 0 exceeds the
sum of the moduli of the others plus the remainder's bound ``sum_d ||a_d|| ||b|| r(|s|)``. Built
with a loop delay above every rate ``p_g``, no term of ``z`` shares an exponent with a term
without ``z``, so none of its moduli is merged, and the inequality uses ``|z e^{-p_g s}| <= 1``
only: it holds for every ``|z| <= 1``. So ``A(s) + z B(s) != 0`` there: no root of
``F(.; delta)`` with ``Re s >= 0``, ``|s| >= W`` for any ``delta >= 0`` (``z = e^{-delta s}``), and
``|A(i w)| != |B(i w)|`` for ``w >= W`` (else ``z = -A/B`` on the unit circle is a zero).

**Crossings** (:func:`proven_axis_crossings`). ``g(w) = |A(i w)|^2 - |B(i w)|^2`` and
``g'(w) = -2 Im(conj(A) A') + 2 Im(conj(B) B')`` (``'`` = ``d/ds``) are enclosed on each segment
``I`` of ``[0, W]`` (the jet over the ball ``i I``), ``g(I)`` intersected with the mean-value
form ``g(c) + g'(I) (I - c)``. A segment is zero-free when ``0`` is not in ``g(I)``; when ``0``
is not in ``g'(I)``, ``g`` is monotone on ``I`` and has exactly one zero, simple, iff the proven
signs of ``g`` at the ends differ; otherwise it is bisected, down to ``1e-12 max(1, W)``, below
which it is refused (a tangency, a zero at ``w = 0``, or one indistinguishable from them in
ball arithmetic). Each zero's enclosure is narrowed by interval Newton ``m - g(m) / g'(J)``.

**Delays.** At a zero enclosure ``[w]``, ``u = -B/A`` is enclosed and the first delay with
``e^{i w delta} = u`` is ``phi / w``, ``phi = arg u`` in ``[0, 2 pi)``, the branch chosen from the
proven sign of ``Im u`` (or ``Re u < 0``); a ``u`` that may lie on the positive real axis (a
delay near a multiple of the period) is refused.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..._flint import ball_lower, ball_upper, working_precision
from ..._validate import positive_int
from ...errors import CertificationError, ParameterError
from .characteristic import GRID_PER_PERIOD, BallNPlusM, NPlusMCharacteristic

__all__ = ["ProvenAxisCrossing", "proven_axis_crossings", "proven_frequency_bound"]

# Segments narrower than this (relative to max(1, W)) are refused.
_MIN_WIDTH = 1e-12
# Interval Newton steps, and the relative width at which a zero's enclosure is tight enough.
_NEWTON_STEPS = 60
_TIGHT = 1e-15


@dataclass(frozen=True)
class ProvenAxisCrossing:
    """One zero of ``|A(i w)|^2 - |B(i w)|^2`` on ``(0, W]``, proven simple, with its first delay.

    Attributes
    ----------
    omega : (float, float)
        Enclosure of the crossing frequency (exactly one zero of ``g`` in it).
    delay : (float, float)
        Enclosure of the first delay ``(arg(-B/A) mod 2 pi) / w`` at it.
    slope : int
        Proven sign of ``g'`` there: ``+1`` roots cross to the right as the delay grows.
    """

    omega: tuple[float, float]
    delay: tuple[float, float]
    slope: int


def proven_frequency_bound(F: NPlusMCharacteristic, *, prec: int = 53) -> float:
    """``W`` proven in ball arithmetic: ``A(s) + z B(s) != 0`` on ``Re s >= 0``, ``|s| >= W``, every ``|z| <= 1``.

    See the module notes. ``F`` is a one-actuator loop (its delay is not used).

    Raises
    ------
    ParameterError
        ``m != 1``.
    CertificationError
        The far-field bound is not proven (the principal part's term of delay 0 does not
        dominate: ``gamma_0 >= 1``, or too close to 1 for ``prec`` bits).
    """
    system = F.system
    if system.m != 1:
        raise ParameterError("system", "one actuator (m = 1)", system.m)
    rates = 1.0 / np.asarray(system.lam, dtype=float) + 1.0 / float(system.mu[0])
    apart = NPlusMCharacteristic(system, F.K, 2.0 * float(np.max(rates)) + 1.0)  # delay above every rate
    W = apart.proven_far_field_radius(0.0, prec)
    if W is None:
        raise CertificationError(
            "proven frequency bound: |A| - |B| > 0 far out on the axis is not proven in ball arithmetic (gamma_0 of "
            "the delayed principal part must be below 1 with room above rounding; raise prec)"
        )
    return W


def _sign(x: Any) -> int:
    return 1 if x > 0 else (-1 if x < 0 else 0)


def _sq(z: Any) -> Any:
    """``|z|^2`` (products: the square of a ball holding 0 is not finite in python-flint)."""
    return z.real * z.real + z.imag * z.imag


class _Axis:
    """``g`` and ``g'`` on the imaginary axis in balls, with a work bound on the evaluations."""

    def __init__(self, balls: BallNPlusM, max_evals: int) -> None:
        self.balls = balls
        self.flint = balls.flint
        self.evals = 0
        self.max_evals = max_evals
        self.ends: dict[float, int] = {}

    def jet(self, w: Any, order: int) -> list[tuple[Any, Any]]:
        if self.evals >= self.max_evals:
            raise CertificationError(
                f"proven crossing search: the work bound max_evals={self.max_evals} ball evaluations is reached "
                "(raise max_evals)"
            )
        self.evals += 1
        return self.balls.factor_jet(self.flint.acb(0, w), order)

    def g(self, w: Any) -> Any:
        (a, b), *_ = self.jet(w, 0)
        return _sq(a) - _sq(b)

    def g_and_slope(self, w: Any) -> tuple[Any, Any]:
        (a, b), (da, db) = self.jet(w, 1)
        return _sq(a) - _sq(b), -2 * (a.conjugate() * da).imag + 2 * (b.conjugate() * db).imag

    def sign_at(self, x: float) -> int:
        if x not in self.ends:
            self.ends[x] = _sign(self.g(self.flint.arb(x)))
        return self.ends[x]


def _first_delay(flint: Any, a: Any, b: Any, w: Any) -> tuple[float, float] | None:
    """Enclosure of the first delay with ``e^{i w delta} = -B/A`` (``w > 0``; None when not proven)."""
    if a.contains(0):
        return None
    u = -b / a
    im = _sign(u.imag)
    if im > 0:
        phi = u.arg()
    elif im < 0:
        phi = u.arg() + 2 * flint.arb.pi()
    elif u.real < 0:
        phi = flint.arb.pi() + (-u).arg()
    else:
        return None
    delay = phi / w
    return (ball_lower(delay), ball_upper(delay)) if delay > 0 else None


def proven_axis_crossings(
    balls: BallNPlusM, W: float, *, max_evals: int = 200_000
) -> tuple[tuple[ProvenAxisCrossing, ...], int]:
    """Every zero of ``g(w) = |A(i w)|^2 - |B(i w)|^2`` on ``[0, W]`` with its first delay, proven (module notes).

    Parameters
    ----------
    balls : BallNPlusM
        The one-actuator loop in ball arithmetic (:meth:`NPlusMCharacteristic.ball_function`).
    W : float
        The end of the search, ``> 0`` (:func:`proven_frequency_bound`: no zero beyond it).
    max_evals : int, optional
        Work bound on the ball evaluations of the factors.

    Returns
    -------
    (tuple of ProvenAxisCrossing, int)
        The crossings in increasing frequency, and the ball evaluations spent.

    Raises
    ------
    CertificationError
        A segment narrowed to ``1e-12 max(1, W)`` undecided (a tangency: a slight change of the
        gain decides it; or ``|A(0)| = |B(0)|``), a delay's branch not proven, or the work
        bound reached.
    """
    if not isinstance(balls, BallNPlusM):
        raise ParameterError("balls", "a BallNPlusM", type(balls).__name__)
    if not (math.isfinite(W) and W > 0.0):
        raise ParameterError("W", "a finite frequency > 0", W)
    max_evals = positive_int("max_evals", max_evals)
    axis = _Axis(balls, max_evals)
    min_width = _MIN_WIDTH * max(1.0, W)
    step = 2.0 * np.pi / (GRID_PER_PERIOD * balls.F.max_delay)
    grid = np.linspace(0.0, W, int(np.ceil(W / step)) + 1).tolist()
    brackets: list[tuple[float, float, int]] = []
    with working_precision(balls.prec) as flint:
        arb = flint.arb
        todo = list(itertools.pairwise(grid))
        while todo:
            a, b = todo.pop()
            iv = arb(a).union(arb(b))
            g_iv, slope = axis.g_and_slope(iv)
            c = iv.mid()
            centred = axis.g(c) + slope * (iv - c)
            if centred.overlaps(g_iv):
                g_iv = centred.intersection(g_iv)
            if not g_iv.contains(0):
                continue
            if not slope.contains(0):
                sa, sb = axis.sign_at(a), axis.sign_at(b)
                if sa and sb:
                    if sa != sb:
                        brackets.append((a, b, _sign(slope)))
                    continue
            if b - a <= min_width:
                where = (
                    "|A(0)| = |B(0)| to rounding: g vanishes at w = 0, the crossings near it have delays growing "
                    "without bound"
                    if a == 0.0
                    else "a tangency"
                )
                raise CertificationError(
                    f"proven crossing search: |A(i w)| = |B(i w)| is not decided on [{a!r}, {b!r}] in ball arithmetic "
                    f"({where}, or a zero indistinguishable from one); a slight change of the gain would decide it"
                )
            mid = 0.5 * (a + b)
            todo += [(a, mid), (mid, b)]
        found = []
        for a, b, sl in sorted(brackets):
            J = arb(a).union(arb(b))
            for _ in range(_NEWTON_STEPS):
                m = J.mid()
                _, slope = axis.g_and_slope(J)
                N = m - axis.g(m) / slope
                if not N.overlaps(J):
                    raise CertificationError("proven crossing search: interval Newton left its enclosure")
                narrowed = N.intersection(J)
                done = narrowed.rad() >= J.rad() or narrowed.rad() <= _TIGHT * abs(narrowed.mid())
                J = narrowed
                if done:
                    break
            (A, B), *_ = axis.jet(J, 0)
            delay = _first_delay(flint, A, B, J)
            if delay is None:
                raise CertificationError(
                    f"proven crossing search: the first delay of the crossing at w in [{ball_lower(J)!r}, "
                    f"{ball_upper(J)!r}] is not proven (a delay near 0 modulo the period, or A(i w) near 0)"
                )
            found.append(ProvenAxisCrossing((ball_lower(J), ball_upper(J)), delay, sl))
    return tuple(found), axis.evals
