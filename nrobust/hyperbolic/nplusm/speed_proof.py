"""Stability on the whole box of speed errors of an ``n + 1`` plant, certified: :func:`prove_speed_box`.

The loop of one actuator under ``U = K u(t - delta, 1)`` is ``F(s) = A(s) + B(s) e^{-delta s}`` with
``A = l_A^T G(s) W``, ``B = l_B^T G(s) W``, ``G(s) = exp(C - s P)``, ``C = Lambda^{-1} Sigma``,
``P = diag(1/lam_i + 1/mu, 0)``, ``l_A = (-R, 1)``, ``l_B = (-K, 0)``, ``W = [Q; 1]``
(:class:`~nrobust.hyperbolic.nplusm.NPlusMCharacteristic`). The speeds enter through ``C`` and ``P`` only,
so a box ``S`` of speeds (every ``lam_i`` and ``mu`` in an interval) makes ``C`` and ``P`` ball matrices,
and FLINT's proven matrix exponential of ``C - i w P`` with ball entries (``acb_mat.exp``) encloses
``G(i w)`` for every plant of the box and every ``w`` of a ball at once. The proof is the no-crossing
argument of the square of the 2x2 plant (:mod:`~nrobust.hyperbolic.analyses.mismatch_proof`) on the
connected set ``S x [d_min, d_max]``:

1. *No zero from infinity.* With the rates of the ``u_i`` pairwise apart over ``S`` (their intervals
   disjoint), the principal transition is ``exp(C_d - s P)``, ``C_d = diag(c_ii)``, and the gauge
   remainder of :class:`~nrobust.margins.matrix.GaugeRemainder` bounds ``||G(s) - exp(C_d - s P)||`` on
   ``Re s >= 0`` by ``r(|s|)``, increasing in ``||N||``, ``||H||`` and ``beta_d = max c_ii`` (``N_ik =
   c_ik / (p_i - p_k)``, ``H = C N - N C_d``), which are bounded above over ``S`` in ball arithmetic
   (:func:`~nrobust.hyperbolic.nplusm.characteristic.spectral_norm_bound`). The principal parts keep
   ``|A_0| - |B_0 e^{-delta s}| >= gap = e^{c_vv} - sum_i (|R_i Q_i| + |K_i Q_i|) e^{c_ii}`` on ``Re s >=
   0`` for every ``delta >= 0`` (``gap = |V| (1 - gamma_0)``, :meth:`NPlusMSystem.principal_terms`), and
   ``|A - A_0| + |B - B_0| <= (||l_A|| + ||K||) ||W|| r(|s|)``. A radius ``W`` where that is below
   the gap's lower bound over ``S``, proven in ball arithmetic (``r`` is non-increasing), leaves no zero
   with ``Re s >= 0`` and ``|s| >= W``, for every plant of ``S`` and every delay; ``gap > 0`` is the strong
   stability of the difference operator (``gamma_0 < 1``) over ``S``.
2. *No zero on the imaginary axis.* Boxes of ``(w, S')``, ``S'`` a sub-box of ``S`` in the inverse speeds,
   covering ``[0, W] x S`` are cleared by :func:`~nrobust.hyperbolic.analyses.mismatch_proof.crossing_free`
   (the sign of ``|A|^2 - |B|^2``, every crossing delay of the box outside the window, or ``F`` enclosed
   away from 0), with ``A``, ``B`` enclosed first by the ball exponential, then, if that does not decide,
   by Taylor's formula of order 2 about the box's middle (:meth:`_Family.centred`: tight where the ball
   exponential's wrapping is not); an undecided box is halved in the parameter with the largest share of
   the enclosures' widths (lower frequencies first), up to ``max_boxes`` boxes. ``w < 0`` follows by
   conjugation (real coefficients).
3. *One point.* A plant of ``S`` certified stable on the window (a vertex's verdict,
   :func:`~nrobust.hyperbolic.nplusm.design.check_window`: its certified margin and count).

The zeros in ``Re s >= 0`` then stay in the half-disc ``|s| < W``, none reaches its boundary as the speeds
and the delay move in the connected set, so their number is the same everywhere (the argument principle):
zero at the point of step 3. No zero in ``Re s >= 0`` and a strongly stable difference operator make the
loop exponentially stable for every plant of the box and every delay of the window. Steps 1 and 2 are
proven in ball arithmetic; step 3 is as certified as the vertex's verdict (floating point with rounding
room, :func:`~nrobust.hyperbolic.nplusm.nplusm_delay_margin`). The box ``S`` holds the speeds
``c (1 + e)``, ``|e| <= eps``, exactly, and the doubles the perturbed plants store.

Several actuators (``m > 1``: ``F`` a polynomial of degree ``m`` in ``e^{-delta s}``) are not covered.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..._digits import lower_bound_text, upper_bound_text
from ..._flint import working_precision
from ..._validate import positive_int
from ...errors import CertificationError, ParameterError
from ..analyses.mismatch_proof import ball_lower, ball_upper, crossing_free
from .characteristic import spectral_norm_bound, symmetric_top_bound
from .speed_box import WindowVerdict, perturbed_system
from .system import NPlusMSystem

__all__ = ["MAX_BOX_PROOF_BOXES", "SpeedBoxProof", "prove_speed_box"]

#: Default work bound of :func:`prove_speed_box`: boxes of ``(w, speeds)`` examined (a few hundred
#: microseconds each for ``n + m = 2``).
MAX_BOX_PROOF_BOXES = 50_000

#: Relative width below which an undecided box is not halved again: a zero on the imaginary axis sits
#: in it (or a crossing delay at an end of the window), and no subdivision decides.
_MIN_WIDTH = 1e-11


@dataclass(frozen=True)
class SpeedBoxProof:
    """The outcome of :func:`prove_speed_box`.

    Attributes
    ----------
    proven : bool
        Exponentially stable for every plant of the box and every delay of the window (module notes).
    reason : str
        What is proven, or why not (what would help).
    frequency_bound : float
        ``W``: no zero with ``Re s >= 0`` and ``|s| >= W`` for any plant of the box and any delay
        (``nan`` when not proven).
    boxes : int
        Boxes of ``(w, speeds)`` examined.
    base : int
        The index in ``points`` of the plant the argument starts from (``-1`` when none).
    undecided : tuple of float
        The speeds ``(lam_1, ..., lam_n, mu)`` at the middle of the box the subdivision stopped at
        (empty otherwise): where to look for an unstable plant.
    """

    proven: bool
    reason: str
    frequency_bound: float
    boxes: int
    base: int = -1
    undecided: tuple[float, ...] = ()


class _Family:
    """``C``, ``P`` and the factors ``A(i w)``, ``B(i w)`` over boxes of inverse speeds, in ball arithmetic.

    The parameters are ``x = (w, a_1, ..., a_n, b)``, ``a_i = 1/lam_i``, ``b = 1/mu``: ``M = C - i w P`` has
    ``C_ik = a_i sigma_ik`` (``C_vk = -b sigma_vk``) and ``P_ii = a_i + b`` (``P_vv = 0``), affine in ``(a, b)``
    and bilinear in ``(w, (a, b))``.
    """

    def __init__(self, flint: Any, system: NPlusMSystem, K: Any) -> None:
        self.flint = flint
        arb = flint.arb
        n = system.n
        self.n = n
        self.sigma = [[arb(float(v)) for v in row] for row in system.sigma]
        w = [arb(float(v)) for v in system.q[:, 0]] + [arb(1)]
        self.w = flint.acb_mat(n + 1, 1, [flint.acb(v) for v in w])
        self.l_a = [-arb(float(v)) for v in system.r[0]] + [arb(1)]
        self.l_b = [-arb(float(v)) for v in K[0]] + [arb(0)]
        # ||l_A|| ||W|| and ||l_B|| ||W||: the factors' scale in the norm bounds
        norm_w = sum((x * x for x in w), arb(0)).sqrt()
        self.scale = [sum((x * x for x in ell), arb(0)).sqrt() * norm_w for ell in (self.l_a, self.l_b)]
        self.beta = arb(0)

    def generator(self, inverse: Sequence[Any]) -> tuple[list[list[Any]], list[Any]]:
        """``C`` and the diagonal of ``P`` for the ball inverse speeds ``(a_1, ..., a_n, b)``."""
        n = self.n
        rows = [*inverse[:n], -inverse[n]]
        c = [[rows[i] * self.sigma[i][k] for k in range(n + 1)] for i in range(n + 1)]
        p = [inverse[i] + inverse[n] for i in range(n)] + [self.flint.arb(0)]
        return c, p

    def _entries(self, w: Any, inverse: Sequence[Any]) -> list[list[Any]]:
        """The entries of ``M = C - i w P``."""
        acb, size = self.flint.acb, self.n + 1
        c, p = self.generator(inverse)
        return [[acb(c[i][k], -(w * p[i])) if i == k else acb(c[i][k]) for k in range(size)] for i in range(size)]

    def _pair(self, g: Any) -> tuple[Any, Any]:
        """``l_A^T g W`` and ``l_B^T g W`` for the ``(n + 1) x (n + 1)`` matrix ``g``."""
        acb, size = self.flint.acb, self.n + 1
        col = g * self.w
        x = [col[i, 0] for i in range(size)]
        return sum((v * a for v, a in zip(x, self.l_a)), acb(0)), sum((v * b for v, b in zip(x, self.l_b)), acb(0))

    def directions(self, w: Any, inverse: Sequence[Any]) -> list[list[list[Any]]]:
        """``E_d = dM/dx_d`` at ``(w, inverse)`` for ``x = (w, a_1, ..., a_n, b)``.

        ``-i P``; row ``i`` of ``Sigma`` with ``-i w`` added on the diagonal; minus row ``v`` of ``Sigma`` with
        ``-i w`` on the diagonal of the ``u_i``.
        """
        acb, size, n = self.flint.acb, self.n + 1, self.n
        zero = acb(0)
        _, p = self.generator(inverse)
        out = [[[acb(0, -p[i]) if i == k else zero for k in range(size)] for i in range(size)]]
        for j in range(n):
            e = [[zero] * size for _ in range(size)]
            e[j] = [acb(self.sigma[j][k], -w if k == j else 0) for k in range(size)]
            out.append(e)
        e = [[acb(0, -w) if i == k else zero for k in range(size)] for i in range(n)]
        out.append([*e, [acb(-self.sigma[n][k]) for k in range(size)]])
        return out

    def factors(self, w: Any, inverse: Sequence[Any]) -> tuple[Any, Any]:
        """Enclosures of ``A(i w)`` and ``B(i w)`` for every ``w`` of the ball and plant of the ball inverse speeds."""
        flint, size = self.flint, self.n + 1
        m = self._entries(w, inverse)
        return self._pair(flint.acb_mat(size, size, [x for row in m for x in row]).exp())

    def centred(self, w0: float, w1: float, box: Sequence[tuple[float, float]]) -> tuple[Any, Any, list[float]]:
        """Enclosures of ``A(i w)`` and ``B(i w)`` on the box by Taylor's formula of order 2 about its middle,
        and each parameter's share of their widths (which one to halve).

        ``G(x) = exp(M(x))``; along the segment from the middle ``x_0`` to ``x``, ``M(t)`` is quadratic in ``t``
        with ``M' = sum_d (x_d - x_0,d) E_d`` and ``M'' = -2 i (w - w_0) (P(x) - P(x_0))``. The first derivatives
        at ``x_0`` are block ``(0, 1)`` of ``exp([[M, E_d], [0, M]])`` (Van Loan; a point, so tight), and the
        remainder is at most ``(||M'||^2 + ||M''||) e^beta / 2``: ``d^2/dt^2 exp(M(t))`` is a Fréchet derivative in
        ``M''`` plus a second one in ``M'``, Dyson's expansion bounds them by ``||M''|| e^beta`` and ``||M'||^2
        e^beta``, ``beta >= lambda_max(Herm C)`` on the whole box (``Herm(C - i w P) = Herm C``). The factors get
        ``l^T (.) W``, so the remainder ``||l|| ||W||`` times that.
        """
        flint = self.flint
        arb, acb = flint.arb, flint.acb
        size = self.n + 1
        lows = [w0, *(lo for lo, _ in box)]
        highs = [w1, *(hi for _, hi in box)]
        mids = [0.5 * (lo + hi) for lo, hi in zip(lows, highs)]
        halves = [arb.max(arb(hi) - arb(x), arb(x) - arb(lo)) for lo, hi, x in zip(lows, highs, mids)]
        w_mid, inverse = arb(mids[0]), [arb(x) for x in mids[1:]]
        m = self._entries(w_mid, inverse)
        zero = acb(0)
        values: tuple[Any, Any] | None = None
        slope_a, slope_b = arb(0), arb(0)
        shares = []
        for e, h in zip(self.directions(w_mid, inverse), halves):
            rows = [[*m[i], *e[i]] for i in range(size)] + [[zero] * size + m[i] for i in range(size)]
            big = flint.acb_mat(2 * size, 2 * size, [x for row in rows for x in row]).exp()
            if values is None:
                values = self._pair(flint.acb_mat(size, size, [big[i, k] for i in range(size) for k in range(size)]))
            dA, dB = self._pair(flint.acb_mat(size, size, [big[i, size + k] for i in range(size) for k in range(size)]))
            slope_a += abs(dA) * h
            slope_b += abs(dB) * h
            shares.append(float((abs(dA) + abs(dB)) * h))
        assert values is not None
        # ||M'|| <= h_w max_i (a_i + b) + sum_i h_{a_i} (||sigma_i|| + w) + h_b (||sigma_v|| + w) on the box
        top = [arb(hi) for hi in highs]
        norms = [max((top[1 + i] + top[-1] for i in range(size - 1)), key=lambda v: float(v.upper()))]
        norms += [sum((x * x for x in self.sigma[d]), arb(0)).sqrt() + top[0] for d in range(size)]
        first = sum((h * v for h, v in zip(halves, norms)), arb(0))
        pair = max((halves[1 + i] + halves[-1] for i in range(size - 1)), key=lambda v: float(v.upper()))
        rem = (first * first + 2 * halves[0] * pair) * self.beta.exp() / 2
        out = []
        for value, slope, scale in zip(values, (slope_a, slope_b), self.scale):
            r = ball_upper(slope + rem * scale)
            out.append(value + acb(arb(0, r), arb(0, r)))
        spread = float(first * self.beta.exp() * (self.scale[0] + self.scale[1]) / 2)
        shares = [a + spread * float(h * v) for a, h, v in zip(shares, halves, norms)]
        return out[0], out[1], shares


def _ball_sum(terms: Sequence[Any], start: Any) -> Any:
    """``start`` plus the balls ``terms``."""
    out = start
    for t in terms:
        out = out + t
    return out


def _tail(flint: Any, fam: _Family, system: NPlusMSystem, K: Any, inverse: Sequence[Any]) -> float | str:
    """``W`` (step 1 of the module notes) over the ball inverse speeds, proven; or why not."""
    arb = flint.arb
    n = system.n
    c, p = fam.generator(inverse)
    for i in range(n):
        for k in range(i + 1, n):
            if (p[i] - p[k]).contains(0):
                return (
                    f"the round-trip rates of u_{i + 1} and u_{k + 1} meet in the box (their speeds can make them "
                    "equal): the gauge bound of the far field needs them apart; a smaller tolerance decides"
                )
    size = n + 1
    N = flint.arb_mat([[arb(0) if i == k else c[i][k] / (p[i] - p[k]) for k in range(size)] for i in range(size)])
    Cd = flint.arb_mat([[c[i][i] if i == k else arb(0) for k in range(size)] for i in range(size)])
    H = flint.arb_mat(c) * N - N * Cd
    n_norm = arb(ball_upper(spectral_norm_bound(flint, N)))
    h_norm = arb(ball_upper(spectral_norm_bound(flint, H)))
    beta = arb(max(ball_upper(c[i][i]) for i in range(size)))
    q = [arb(float(v)) for v in system.q[:, 0]]
    r = [arb(float(v)) for v in system.r[0]]
    gain = [arb(float(v)) for v in K[0]]
    gap = c[n][n].exp() - _ball_sum(
        [(abs(r[i] * q[i]) + abs(gain[i] * q[i])) * c[i][i].exp() for i in range(n)], arb(0)
    )
    if not gap > 0:
        return (
            "the difference operator is not proven strongly stable over the box (gamma_0 < 1 at every plant of it "
            "is not shown): zeros may come from infinity; a smaller gain or tolerance decides"
        )
    scale = ((_ball_sum([x * x for x in r], arb(1))).sqrt() + _ball_sum([x * x for x in gain], arb(0)).sqrt()) * (
        _ball_sum([x * x for x in q], arb(1)).sqrt()
    )
    level = ball_lower(gap)

    def remainder(rho: Any) -> Any:
        t = 1 / (1 - n_norm / rho)
        e = t * h_norm
        return ((1 + n_norm / rho) * t * e * (beta + e / rho).exp() + 2 * n_norm * t * beta.exp()) / rho

    if n_norm == 0 and h_norm == 0:
        return 0.0
    floor = ball_upper(n_norm)
    hi = max(2.0 * floor, 1.0)
    while not (scale * remainder(arb(hi))) < level:
        hi *= 2.0
        if hi > 2.0**200:
            return "the coupling remainder stays above the principal part's gap: no frequency bound"
    lo = floor
    while hi - lo > 1e-7 * hi:
        mid = 0.5 * (lo + hi)
        if (scale * remainder(arb(mid))) < level:
            hi = mid
        else:
            lo = mid
    return hi


def _speed_box(system: NPlusMSystem, eps: float, points: Sequence[tuple[float, ...]]) -> list[tuple[float, float]]:
    """Float intervals holding ``c (1 + e)`` for ``|e| <= eps`` exactly and every speed the plants of
    ``points`` store (:func:`~.speed_box.perturbed_system`)."""
    with working_precision(53) as flint:
        arb = flint.arb
        nominal = [*map(float, system.lam), float(system.mu[0])]
        stored = [(*perturbed_system(system, e).lam, perturbed_system(system, e).mu[0]) for e in points]
        out = []
        for i, c in enumerate(nominal):
            ball = arb(c) * (1 + arb(0, eps))
            for s in stored:
                ball = ball.union(arb(float(s[i])))
            out.append((ball_lower(ball), ball_upper(ball)))
        return out


def prove_speed_box(
    system: NPlusMSystem,
    K: ArrayLike,
    eps: float,
    window: tuple[float, float],
    points: Sequence[tuple[float, ...]],
    verdicts: Sequence[WindowVerdict],
    *,
    max_boxes: int = MAX_BOX_PROOF_BOXES,
) -> SpeedBoxProof:
    """Prove the loop stable for every speed error ``|e_i| <= eps`` and every delay of ``window`` (module notes).

    Parameters
    ----------
    system : NPlusMSystem
        The nominal plant, one actuator (``m = 1``).
    K : array_like, shape (1, n)
    eps : float
        The tolerance, in ``(0, 1)``.
    window : (float, float)
        ``(d_min, d_max)``.
    points : sequence of tuple of float
        Error vectors of the box whose plants (:func:`~.speed_box.perturbed_system`) have verdicts.
    verdicts : sequence of WindowVerdict
        The verdict on ``window`` at each of ``points``: the first stable and certified one is the point
        the argument starts from.
    max_boxes : int, optional
        Work bound: boxes of ``(w, speeds)`` examined.

    Returns
    -------
    SpeedBoxProof
        ``proven`` True with what is proven; False with the reason (no verdict to start from, rates that
        meet, no strong stability, a box no subdivision decides: a zero on the imaginary axis there).

    Raises
    ------
    ParameterError
        Several actuators, ``eps`` outside ``(0, 1)``, ``points`` and ``verdicts`` of different lengths,
        ``max_boxes`` not a positive integer.
    CertificationError
        The work bound ``max_boxes`` was reached before a decision.
    """
    if not isinstance(system, NPlusMSystem) or system.m != 1:
        raise ParameterError("system", "an NPlusMSystem with one actuator (m = 1)", system)
    k = system.gain(K)
    if not 0.0 < eps < 1.0:
        raise ParameterError("eps", "in (0, 1) (the perturbed speeds stay positive)", eps)
    if len(points) != len(verdicts):
        raise ParameterError("verdicts", f"one verdict per point ({len(points)})", len(verdicts))
    max_boxes = positive_int("max_boxes", max_boxes)
    d_lo, d_hi = (float(v) for v in window)
    nan = math.nan
    base = next((j for j, v in enumerate(verdicts) if v.stable and v.certified), -1)
    if base < 0:
        return SpeedBoxProof(False, "no point of the box is certified stable on the window", nan, 0)
    bounds = _speed_box(system, eps, points)
    with working_precision(53) as flint:
        arb = flint.arb
        fam = _Family(flint, system, k)

        def balls(box: Sequence[tuple[float, float]]) -> list[Any]:
            return [arb(lo).union(arb(hi)) for lo, hi in box]

        # the box of inverse speeds (a_1, ..., a_n, b), rounded outwards
        inverse = tuple((ball_lower(1 / arb(hi)), ball_upper(1 / arb(lo))) for lo, hi in bounds)
        W = _tail(flint, fam, system, k, balls(inverse))
        if isinstance(W, str):
            return SpeedBoxProof(False, W, nan, 0, base)
        c, _ = fam.generator(balls(inverse))
        fam.beta = symmetric_top_bound(flint, [[(c[i][j] + c[j][i]) / 2 for j in range(len(c))] for i in range(len(c))])
        stack: list[tuple[float, float, tuple[tuple[float, float], ...]]] = [(0.0, W, inverse)]
        boxes = 0
        while stack:
            w0, w1, box = stack.pop()
            boxes += 1
            w = arb(w0).union(arb(w1))
            A, B = fam.factors(w, balls(box))
            if crossing_free(flint, A, B, w, d_lo, d_hi):
                continue
            A, B, shares = fam.centred(w0, w1, box)
            if crossing_free(flint, A, B, w, d_lo, d_hi):
                continue
            # halve the parameter with the largest share of the enclosures' widths
            j = int(np.argmax(shares))
            lo, hi = (w0, w1) if j == 0 else box[j - 1]
            if hi - lo <= _MIN_WIDTH * max(1.0, abs(hi)):
                speeds = [(ball_lower(1 / arb(b)), ball_upper(1 / arb(a))) for a, b in box]
                where = ", ".join(f"[{lower_bound_text(a, 9)}, {upper_bound_text(b, 9)}]" for a, b in speeds)
                return SpeedBoxProof(
                    False,
                    "a zero of F on the imaginary axis for w in "
                    f"[{lower_bound_text(w0, 9)}, {upper_bound_text(w1, 9)}] at speeds (lam_1, ..., lam_n, mu) in "
                    f"{where} for a delay of the window (or a crossing delay at an end of the window): not stable "
                    "there, or not decided; a smaller tolerance or a window clear of the crossing delays decides",
                    W,
                    boxes,
                    base,
                    tuple(0.5 * (a + b) for a, b in speeds),
                )
            if boxes >= max_boxes:
                raise CertificationError(
                    f"prove_speed_box: the work bound max_boxes = {max_boxes} was reached (at w in [{w0:.6g}, "
                    f"{w1:.6g}]); a larger max_boxes or a smaller tolerance decides"
                )
            mid = 0.5 * (lo + hi)
            if j == 0:  # the lower frequencies first: a crossing, where it is not stable, is found early
                stack += [(mid, w1, box), (w0, mid, box)]
            else:
                left, right = list(box), list(box)
                left[j - 1], right[j - 1] = (lo, mid), (mid, hi)
                stack += [(w0, w1, tuple(left)), (w0, w1, tuple(right))]
    span = ", ".join(f"[{upper_bound_text(lo, 9)}, {lower_bound_text(hi, 9)}]" for lo, hi in bounds)
    top = upper_bound_text(W)
    return SpeedBoxProof(
        True,
        f"no zero on the imaginary axis for any speeds (lam_1, ..., lam_n, mu) in {span} and delay of the window "
        f"({boxes} boxes in ball arithmetic), none with Re s >= 0 and |s| >= {top} (gamma_0 < 1 on the box), and "
        f"the plant of points[{base}] certified stable on the window: no zero in Re s >= 0 anywhere on the box",
        W,
        boxes,
        base,
    )
