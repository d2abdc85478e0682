"""Stability on the whole box of speed errors of an ``n + m`` plant, certified: :func:`prove_speed_box`.

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

**Several actuators** (``m > 1``, one delay ``delta`` on every actuator). ``F = det(X - z Y) = sum_d c_d(s) z^d``
with ``z = e^{-delta s}`` (:class:`_Loop`), a polynomial of degree ``m`` in ``z``; the same three steps:

1. In the compound form ``F = sum_d z^d a_d^T exp(D - s diag(p)) b``
   (:func:`~nrobust.hyperbolic.nplusm.characteristic.compound_loop`) every subset ``S`` of ``m`` components is
   its own group (the rates ``p_S`` of distinct subsets are distinct linear forms in the inverse speeds; those
   coupled by ``D`` must stay apart over the box), so ``F_0 = det(V - E(s) (R + z K) Delta_u(s) Q)`` with the
   diagonal transitions ``Delta_u = diag(e^{c_ii - s/lam_i})``, ``V = diag(e^{c_{v_j v_j}})`` (Cauchy and Binet).
   On ``Re s >= 0`` and ``|z| <= 1`` the entries of ``T = V^{-1} E (R + z K) Delta_u Q`` are bounded in modulus by
   those of ``Gamma = V^{-1} (|R| + |K|) diag(e^{c_ii}) |Q|``, so ``|F_0| >= det V (1 - rho(Gamma))^m`` with
   ``rho(Gamma)`` bounded above over ``S`` by Collatz and Wielandt's ratio (:func:`_principal_gap`; ``rho < 1`` is
   also the strong stability of the difference operator for every delay). With ``|F - F_0| <= sum_d ||a_d|| ||b||
   r(|s|)``, the gauge remainder of ``D``, this gives ``W`` as for one actuator (:func:`_compound_tail`).
2. Boxes of ``(w, S', [delta])`` covering ``[0, W] x S x [d_min, d_max]``, with ``c_d`` enclosed by Taylor's formula
   of order 2 about the box's middle (:meth:`_Loop.centred`: the derivatives of the rows ``x_j^T exp(C - i w P_j) W``
   by Van Loan's block exponential and of the determinants by the product rule, the remainder from Dyson's bounds and
   Hadamard's inequality), are cleared when one ``|c_k|`` exceeds the sum of the others (no root on ``|z| = 1``, so
   none for any delay; Rouché), when ``m = 2`` and each root of the quadratic in ``z`` is off the unit circle or has
   every crossing delay outside the window (:func:`_roots_clear`), or when ``F`` with ``z = e^{-i w delta}`` as a ball
   is enclosed away from 0; otherwise the parameter with the largest share of the centred enclosures' widths (never
   the delay, which the roots decide, nor a parameter at the smallest width) is halved, up to ``max_boxes`` boxes. At
   most :data:`MAX_PROVEN_ACTUATORS` actuators.
3. As for one actuator.

The ball exponentials of ``C - i w P_j`` over a box (as for one actuator) wrap where ``w`` times the spread of the
inverse speeds is large; the centred form's width is first order in the box with the plant's own derivatives at the
middle, so it clears boxes several times larger there. Tried after it, the ball exponentials cleared 16 of 6,269
boxes (the 2 + 2 plant of the tests, ``eps = 1e-4``) and 26 of 6,985 (the 1 + 2 plant, ``eps = 0.02``) for a third
of the time: they are not used for ``m > 1``. The first-order term still grows with ``w`` (the phases ``e^{-i w p}``
move with the speeds), so the frequency bound ``W`` and the tolerance set the cost.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._digits import lower_bound_text, upper_bound_text
from ..._flint import ball_lower, ball_upper, working_precision
from ..._validate import positive_int
from ...errors import CertificationError, ParameterError
from ...margins.matrix import compound_generator_of
from ..analyses.mismatch_proof import crossing_free
from ._midrad import EPS, TINY, UP, Ball, det, exact, expm
from .characteristic import arb_max, spectral_norm_bound, symmetric_top_bound
from .speed_box import WindowVerdict, perturbed_system
from .system import NPlusMSystem

__all__ = ["MAX_BOX_PROOF_BOXES", "MAX_PROVEN_ACTUATORS", "SpeedBoxProof", "prove_speed_box"]

#: Default work bound of :func:`prove_speed_box`: boxes of ``(w, speeds)`` examined (a few hundred
#: microseconds each for ``n + m = 2``).
MAX_BOX_PROOF_BOXES = 50_000

#: Most actuators of a proof inside the box. For ``m = 2`` the roots of ``F`` in ``z = e^{-delta s}`` decide every
#: delay of the window at once; for ``m = 3`` a dominant coefficient or ``z`` as a ball over the window does, which the
#: centred form makes affordable at small tolerances (a coupled 1 + 3 plant with the margin 5.62, window ``[0, 2]``:
#: ``eps = 1e-4`` in 2,403 boxes, ``eps = 5e-4`` in 17,313; ``eps = 0.002`` not within 30,000). The box of speed
#: errors has ``2^(n + m)`` vertices, so ``m = 3`` is also the most :func:`~.design.nplusm_speed_tolerance` takes.
MAX_PROVEN_ACTUATORS = 3

#: Relative width below which an undecided box is not halved again: a zero on the imaginary axis sits
#: in it (or a crossing delay at an end of the window), and no subdivision decides.
_MIN_WIDTH = 1e-11

#: Boxes of several actuators whose centred enclosures are computed together (vectorised; the work per box falls
#: about tenfold from one box to this many).
_BATCH = 32


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
        The speeds ``(lam_1, ..., lam_n, mu_1, ..., mu_m)`` at the middle of the box the subdivision stopped at
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


class _Loop:
    """The loop of ``m`` actuators on the imaginary axis over boxes of ``(w, a_1, ..., a_n, b_1, ..., b_m)``,
    ``a_i = 1/lam_i``, ``b_j = 1/mu_j``, in ball arithmetic (module notes, "Several actuators").

    ``E(s) (Phi_v - (R + K z) Phi_u) = X - z Y`` at ``s = i w``, ``z = e^{-delta s}``: row ``j`` of ``X`` is
    ``(-R_j, e_j)^T G_j W`` and of ``Y`` is ``(K_j, 0)^T G_j W`` with ``G_j = exp(C - i w P_j)``, ``C = Lambda^{-1}
    Sigma`` and ``P_j = Lambda^{-1} + I/mu_j`` (:class:`~nrobust.hyperbolic.nplusm.NPlusMCharacteristic`);
    ``F = det(X - z Y) = sum_d c_d z^d``.
    """

    def __init__(self, flint: Any, system: NPlusMSystem, K: Any, inverse: Sequence[Any]) -> None:
        self.flint = flint
        arb = flint.arb
        n, m = system.n, system.m
        self.n, self.m, self.system = n, m, system
        self.sigma = [[arb(float(v)) for v in row] for row in system.sigma]
        self.w_float = np.vstack([system.q, np.eye(m)])
        self.x_float = np.hstack([-system.r, np.eye(m)])
        self.y_float = np.hstack([K, np.zeros((m, m))])
        # ||x_j|| ||W||, ||y_j|| ||W|| and the norms of the rows of Sigma, rounded upwards: the centred form's bounds
        norm_w = arb(
            ball_upper(
                spectral_norm_bound(flint, flint.arb_mat([[arb(float(v)) for v in row] for row in self.w_float]))
            )
        )

        def norm(row: Any) -> Any:
            return _ball_sum([arb(float(v)) * arb(float(v)) for v in row], arb(0)).sqrt()

        self.x_scale = [ball_upper(norm(row) * norm_w) for row in self.x_float]
        self.y_scale = [ball_upper(norm(row) * norm_w) for row in self.y_float]
        self.sigma_norms = np.array([ball_upper(norm(row)) for row in system.sigma])
        # an upper bound of lambda_max(Herm C) over the ball inverse speeds: ||exp(M_j)|| <= e^beta there
        c = self.generator(inverse)
        self.beta = ball_upper(
            symmetric_top_bound(flint, [[(c[i][k] + c[k][i]) / 2 for k in range(n + m)] for i in range(n + m)])
        )

    def generator(self, inverse: Sequence[Any]) -> list[list[Any]]:
        """``C`` for the ball inverse speeds ``(a_1, ..., a_n, b_1, ..., b_m)``."""
        n = self.n
        rows = [*inverse[:n], *(-b for b in inverse[n:])]
        return [[rows[i] * self.sigma[i][k] for k in range(len(rows))] for i in range(len(rows))]

    def centred(self, boxes: Sequence[Sequence[tuple[float, float]]]) -> list[tuple[list[Any], NDArray[np.float64]]]:
        """For each box of ``(w, a_1, ..., a_n, b_1, ..., b_m)``: enclosures of ``c_0, ..., c_m`` on it by Taylor's
        formula of order 2 about its middle ``x_0``, ``c_d(x_0) + sum_k (x_k - x_0,k) dc_d/dx_k(x_0) + rho_d``, and each
        parameter's share of their widths (which one to halve).

        ``dG_j/dx_k`` at ``x_0`` is block ``(0, 1)`` of ``exp([[M_j, E_k], [0, M_j]])``, ``E_k = dM_j/dx_k`` (Van Loan;
        a point, so tight; all ``m (1 + n + m)`` of every box at once in midpoint-radius arithmetic,
        :func:`~nrobust.hyperbolic.nplusm._midrad.expm`), put into the rows ``x_j^T G_j W``, ``y_j^T G_j W`` and the
        determinants by the product rule. ``E_k`` is ``-i P_j`` for ``w``; row ``i`` of ``Sigma`` with ``-i w`` on the
        diagonal for ``a_i``; for ``b_k`` minus row ``v_k`` of ``Sigma`` and ``-i w dP_j/db_k`` on the diagonal
        (``dP_j/db_j`` is 1 on every component but ``v_j``, ``dP_j/db_k`` is ``-1`` on ``v_k`` for ``k != j``).

        Along the segment from ``x_0`` to ``x``, ``M_j`` is quadratic with ``||M_j'|| <= mu_1 = h_w max |P_j| + sum_k
        h_k (||Sigma_k|| + w)`` and ``M_j'' = -2 i (w - w_0) P_j(x - x_0)``, ``||M_j''|| <= mu_2``; with ``||exp(M_j)||
        <= e^beta`` (``Herm M_j = Herm C``) Dyson's expansion gives, for a row of scale ``s = ||l|| ||W||``, ``||r|| <=
        s e^beta``, ``||r'|| <= s mu_1 e^beta`` and ``||r''|| <= s (mu_1^2 + mu_2) e^beta`` (:meth:`_Family.centred`).
        The second derivative of ``det(r_1, ..., r_m)`` is ``sum_i det(.., r_i'', ..) + sum_{i != l} det(.., r_i', ..,
        r_l', ..)``, at most ``prod_i s_i e^(m beta) (m (mu_1^2 + mu_2) + m (m - 1) mu_1^2)`` (Hadamard), and ``rho_d``
        is half the sum of that over the ``binom(m, d)`` determinants of ``c_d``.
        """
        flint = self.flint
        n, m, size = self.n, self.m, self.n + self.m
        sigma = self.system.sigma
        count = 1 + size  # the parameters (w, a, b)
        lows = np.array([[lo for lo, _ in box] for box in boxes])
        highs = np.array([[hi for _, hi in box] for box in boxes])
        mids = 0.5 * (lows + highs)
        halves = np.maximum(highs - mids, mids - lows) * (1.0 + 4.0 * EPS) + TINY
        w, inverse = mids[:, 0], mids[:, 1:]
        rho = np.concatenate([inverse[:, :n], -inverse[:, n:]], axis=1)
        c = rho[:, :, None] * sigma[None]
        c_ball = Ball(c, 2.0 * EPS * np.abs(c))
        eye = np.eye(size)
        shape = (len(boxes), m, count, 2 * size, 2 * size)
        aug_mid, aug_rad = np.zeros(shape, dtype=complex), np.zeros(shape)
        for j in range(m):
            # the diagonal of P_j: a_i + b_j on u_i, b_j - b_k on v_k (exactly 0 on v_j); rounded sums
            p = np.concatenate(
                [inverse[:, :n] + inverse[:, n + j : n + j + 1], inverse[:, n + j : n + j + 1] - inverse[:, n:]], axis=1
            )
            p[:, n + j] = 0.0
            p_mid, p_rad = p[:, :, None] * eye, 2.0 * EPS * np.abs(p)[:, :, None] * eye
            mj = c_ball + Ball(-1j * w[:, None, None]) * Ball(p_mid, p_rad)
            slopes = [Ball(-1j * p_mid, p_rad)]
            for i in range(n):
                row = np.zeros((len(boxes), size, size), dtype=complex)
                row[:, i] = sigma[i]
                row[:, i, i] -= 1j * w
                slopes.append(exact(row))
            for k in range(m):
                d_p = np.array([float(k == j)] * n + [float(k == j) - float(k == ell) for ell in range(m)])
                row = (-1j * w[:, None, None] * d_p[None, :, None]) * eye
                row[:, n + k] -= sigma[n + k]
                slopes.append(exact(row))
            for k, e in enumerate(slopes):
                for half in (slice(0, size), slice(size, 2 * size)):
                    aug_mid[:, j, k, half, half], aug_rad[:, j, k, half, half] = mj.mid, mj.rad
                aug_mid[:, j, k, :size, size:], aug_rad[:, j, k, :size, size:] = e.mid, e.rad
        big = expm(Ball(aug_mid, aug_rad))
        weights = exact(self.w_float)
        # the rows of X and Y (which, box, actuator, column) and their derivatives (which, box, actuator, parameter,
        # column)
        ells = [np.asarray(rows)[:, None, :] for rows in (self.x_float, self.y_float)]
        rows = [(exact(ell) @ big[:, :, 0, :size, :size]) @ weights for ell in ells]
        grads = [(exact(ell[:, None]) @ big[:, :, :, :size, size:]) @ weights for ell in ells]
        row_mid = np.stack([r.mid[:, :, 0, :] for r in rows])
        row_rad = np.stack([r.rad[:, :, 0, :] for r in rows])
        grad_mid = np.stack([r.mid[:, :, :, 0, :] for r in grads])
        grad_rad = np.stack([r.rad[:, :, :, 0, :] for r in grads])
        # each determinant of c_d, then for each parameter k and row i the same with row i replaced by its derivative
        subsets = [(d, T) for d in range(m + 1) for T in itertools.combinations(range(m), d)]
        mats_mid, mats_rad = [], []
        for _, T in subsets:
            which = [int(j in T) for j in range(m)]
            base_mid = np.stack([row_mid[which[j], :, j] for j in range(m)], axis=1)
            base_rad = np.stack([row_rad[which[j], :, j] for j in range(m)], axis=1)
            mats_mid.append(base_mid)
            mats_rad.append(base_rad)
            for k in range(count):
                for i in range(m):
                    x_mid, x_rad = base_mid.copy(), base_rad.copy()
                    x_mid[:, i], x_rad[:, i] = grad_mid[which[i], :, i, k], grad_rad[which[i], :, i, k]
                    mats_mid.append(x_mid)
                    mats_rad.append(x_rad)
        dets = det(Ball(np.stack(mats_mid), np.stack(mats_rad)))  # (determinant, box)
        per = 1 + count * m
        # the remainder's ingredients (floats rounded upwards: sums and products of nonnegative numbers)
        p_top = np.max(highs[:, 1 : 1 + n], axis=1, initial=0.0) + np.max(highs[:, 1 + n :], axis=1)
        parts = (
            np.concatenate([(halves[:, 0] * p_top)[:, None], halves[:, 1:] * (self.sigma_norms + highs[:, :1])], axis=1)
            * UP
        )
        mu_1 = np.sum(parts, axis=1) * UP
        mu_2 = 2.0 * halves[:, 0] * (np.max(halves[:, 1:], axis=1) + np.max(halves[:, 1 + n :], axis=1)) * UP
        grow = math.exp(m * self.beta) * UP * (m * (mu_1 * mu_1 + mu_2) + m * (m - 1) * mu_1 * mu_1) / 2.0 * UP**3
        values, radii = [], []
        shares = np.zeros((len(boxes), count))
        for d in range(m + 1):
            value = np.zeros(len(boxes), dtype=complex)
            radius, slope, scale = np.zeros(len(boxes)), np.zeros((len(boxes), count)), 0.0
            for index, (dd, T) in enumerate(subsets):
                if dd != d:
                    continue
                block = dets[index * per : (index + 1) * per]
                value += block.mid[0]
                radius += block.rad[0] + EPS * np.abs(value)
                slope += np.sum(block[1:].upper().reshape(count, m, -1), axis=1).T * UP
                scale += math.prod(self.y_scale[j] if j in T else self.x_scale[j] for j in range(m)) * UP**m
            rem = grow * scale * UP
            values.append(value * (-1) ** d)
            radii.append((radius + np.sum(slope * halves, axis=1) * UP + rem) * UP**2 + TINY)
            shares += slope * halves + (rem / mu_1)[:, None] * parts
        arb, acb = flint.arb, flint.acb
        return [
            (
                [acb(arb(v[b].real, r[b]), arb(v[b].imag, r[b])) for v, r in zip(values, radii)],
                shares[b],
            )
            for b in range(len(boxes))
        ]


def _cleared(flint: Any, coefficients: Sequence[Any], w: Any, delta: Any, window: tuple[float, float]) -> bool:
    """True when ``F = sum_d c_d z^d`` (ball coefficients ``c_d`` over a box of ``w``, the speeds and ``delta``) has
    no zero with ``z = e^{-i w delta}``: one coefficient dominant, the roots in ``z`` clear of the window, or ``F``
    with ``z`` as a ball enclosed away from 0."""
    if _no_root_on_circle(coefficients) or _roots_clear(flint, coefficients, w, window):
        return True
    z = flint.acb(0, -(w * delta)).exp()
    value = coefficients[-1]
    for c in reversed(coefficients[:-1]):
        value = value * z + c
    return not value.contains(0)


def _no_root_on_circle(coefficients: Sequence[Any]) -> bool:
    """True when ``sum_d c_d z^d != 0`` for every ``|z| = 1`` and every polynomial of the ball coefficients:
    one ``|c_k|`` above the sum of the others (Rouché), as ``|A| != |B|`` for one actuator."""
    mags = [abs(c) for c in coefficients]
    return any(v > _ball_sum(mags[:k] + mags[k + 1 :], v * 0) for k, v in enumerate(mags))


def _roots_clear(flint: Any, coefficients: Sequence[Any], w: Any, window: tuple[float, float]) -> bool:
    """For two actuators: True when no root ``z`` of ``c_0 + c_1 z + c_2 z^2`` equals ``e^{-i w delta}`` for a ``w``
    of the ball and a delay of ``window``.

    The roots are enclosed by ``(-c_1 +- S) / (2 c_2)``, ``S`` an enclosure of the principal square root of the
    discriminant (each root of each polynomial of the ball coefficients lies in one of the two balls, whatever
    the branch); each is cleared as ``-A/B`` of one actuator is
    (:func:`~nrobust.hyperbolic.analyses.mismatch_proof.crossing_free` with ``A = -z``, ``B = 1``: off the unit
    circle, or every crossing delay outside the window).
    """
    if len(coefficients) != 3 or coefficients[2].contains(0):
        return False
    c0, c1, c2 = coefficients
    root = (c1 * c1 - 4 * c0 * c2).sqrt()
    one = flint.acb(1)
    return all(
        bool(z.is_finite()) and crossing_free(flint, -z, one, w, *window)
        for z in ((-c1 + root) / (2 * c2), (-c1 - root) / (2 * c2))
    )


def _principal_gap(flint: Any, system: NPlusMSystem, K: Any, c: Sequence[Sequence[Any]]) -> Any:
    """A ball whose lower end bounds ``|F_0|`` below on ``Re s >= 0`` for every delay and every plant of the box
    (``C`` enclosed by ``c``), or why none.

    ``F_0 = det(V - E(s) (R + z K) Delta_u(s) Q)``, ``V = diag(e^{c_{v_j v_j}})``, ``Delta_u = diag(e^{c_ii - s /
    lam_i})``, ``|z| <= 1``: the modulus of each entry of ``T = V^{-1} E (R + z K) Delta_u Q`` is at most that of
    ``Gamma = V^{-1} (|R| + |K|) diag(e^{c_ii}) |Q|``, so every eigenvalue of ``T`` has modulus at most
    ``rho(Gamma)`` (Perron and Frobenius) and ``|F_0| >= det V (1 - rho(Gamma))^m``. ``rho(Gamma) <= max_j (Gamma
    x)_j / x_j`` for any positive ``x`` (Collatz and Wielandt; ``x`` near Perron's vector). Below 1 this is also the
    strong stability of the difference operator for every delay.
    """
    arb, n, m = flint.arb, system.n, system.m
    grow = [c[i][i].exp() for i in range(n)]
    gamma = [
        [
            (-c[n + j][n + j]).exp()
            * _ball_sum(
                [
                    (abs(arb(float(system.r[j, i]))) + abs(arb(float(K[j, i]))))
                    * grow[i]
                    * abs(arb(float(system.q[i, k])))
                    for i in range(n)
                ],
                arb(0),
            )
            for k in range(m)
        ]
        for j in range(m)
    ]
    upper = np.array([[ball_upper(x) for x in row] for row in gamma])
    values, vectors = np.linalg.eig(upper)
    x = np.abs(vectors[:, int(np.argmax(np.abs(values)))].real)
    x = x / max(float(np.max(x)), 1e-300) + 1e-6
    rho = arb_max(
        flint,
        [_ball_sum([gamma[j][k] * arb(float(x[k])) for k in range(m)], arb(0)) / arb(float(x[j])) for j in range(m)],
    )
    if not rho < 1:
        return (
            "the difference operator is not proven strongly stable over the box (the spectral radius of V^-1 (|R| "
            f"+ |K|) U |Q| is not shown below 1 at every plant of it: at most {upper_bound_text(ball_upper(rho))}): "
            "zeros may come from infinity; a smaller gain or tolerance decides"
        )
    det_v = _ball_sum([c[n + j][n + j] for j in range(m)], arb(0)).exp()
    return det_v * (1 - rho) ** m


def _compound_tail(flint: Any, loop: _Loop, system: NPlusMSystem, K: Any, inverse: Sequence[Any]) -> float | str:
    """``W`` of several actuators (module notes, "Several actuators") over the ball inverse speeds, proven; or why
    not.

    The compound form ``F = sum_d z^d a_d^T exp(D - s diag(p)) b`` (:func:`~.characteristic.compound_loop`): ``D =
    D_m(C)`` and the rates ``p_S = sum_{u_i in S} a_i + sum_{v_j not in S} b_j`` in balls, each subset ``S`` its
    own group (the rates of distinct subsets are distinct linear forms; an entry ``D_ST`` that can be nonzero needs
    ``p_S != p_T`` over the box). The principal part ``sum_{d, S} z^d a_{d,S} e^{D_SS - s p_S} b_S`` keeps its term
    of rate 0 (``S`` the ``v``'s, ``e^{tr C_vv}``) above the others' sum on ``Re s >= 0`` for every delay, and
    ``|F - F_0| <= sum_d ||a_d|| ||b|| r(|s|)``.
    """
    arb, n, m = flint.arb, system.n, system.m
    size = n + m
    c = loop.generator(inverse)
    subsets = list(itertools.combinations(range(size), m))
    count = len(subsets)
    rates = [
        _ball_sum([inverse[i] for i in S if i < n] + [inverse[n + j] for j in range(m) if n + j not in S], arb(0))
        for S in subsets
    ]
    d = compound_generator_of(c, system.sigma != 0, m, arb(0))
    N = [[arb(0) for _ in range(count)] for _ in range(count)]
    for S in range(count):
        for T in range(count):
            if S == T or d[S][T] == 0:
                continue
            if (rates[S] - rates[T]).contains(0):
                names = [
                    ", ".join(f"{'uv'[i >= n]}_{i + 1 if i < n else i - n + 1}" for i in subsets[X]) for X in (S, T)
                ]
                return (
                    f"the round-trip rates of the components {{{names[0]}}} and {{{names[1]}}} of the compound "
                    "form meet in the box (their speeds can make them equal): the gauge bound of the far field needs "
                    "them apart; a smaller tolerance decides"
                )
            N[S][T] = d[S][T] / (rates[S] - rates[T])
    Nm = flint.arb_mat(N)
    Dd = flint.arb_mat([[d[S][S] if S == T else arb(0) for T in range(count)] for S in range(count)])
    H = flint.arb_mat(d) * Nm - Nm * Dd
    n_norm = arb(ball_upper(spectral_norm_bound(flint, Nm)))
    h_norm = arb(ball_upper(spectral_norm_bound(flint, H)))
    beta = arb(max(ball_upper(d[S][S]) for S in range(count)))
    exact = [[arb(float(v)) for v in row] for row in np.hstack([-system.r, np.eye(m)])]
    gain = [[arb(float(v)) for v in row] for row in np.hstack([-K, np.zeros((m, m))])]
    b = [flint.arb_mat([[arb(float(v)) for v in loop.w_float[i]] for i in S]).det() for S in subsets]
    a = [
        [
            _ball_sum(
                [
                    flint.arb_mat([[(gain if j in T else exact)[j][col] for col in S] for j in range(m)]).det()
                    for T in itertools.combinations(range(m), dg)
                ],
                arb(0),
            )
            for S in subsets
        ]
        for dg in range(m + 1)
    ]
    gap = _principal_gap(flint, system, K, c)
    if isinstance(gap, str):
        return gap
    b_norm = _ball_sum([x * x for x in b], arb(0)).sqrt()
    scale = _ball_sum([_ball_sum([x * x for x in row], arb(0)).sqrt() * b_norm for row in a], arb(0))
    return _radius(flint, n_norm, h_norm, beta, scale, gap)


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
    return _radius(flint, n_norm, h_norm, beta, scale, gap)


def _radius(flint: Any, n_norm: Any, h_norm: Any, beta: Any, scale: Any, gap: Any) -> float | str:
    """The least radius (to ``1e-7`` relative) where ``scale r(|s|) < gap`` is proven, ``r`` the gauge remainder of
    :class:`~nrobust.margins.matrix.GaugeRemainder` with ``||N|| <= n_norm``, ``||H|| <= h_norm`` and the
    logarithmic norm ``beta`` (balls); or why there is none."""
    arb = flint.arb
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
        nominal = [*map(float, system.lam), *map(float, system.mu)]
        plants = [perturbed_system(system, e) for e in points]
        stored = [(*plant.lam, *plant.mu) for plant in plants]
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
        The nominal plant (several actuators: module notes, "Several actuators").
    K : array_like, shape (m, n)
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
        Not an ``NPlusMSystem``, ``eps`` outside ``(0, 1)``, ``points`` and ``verdicts`` of different lengths,
        ``max_boxes`` not a positive integer.
    CertificationError
        The work bound ``max_boxes`` was reached before a decision.
    """
    if not isinstance(system, NPlusMSystem):
        raise ParameterError("system", "an NPlusMSystem", system)
    if system.m > MAX_PROVEN_ACTUATORS:
        raise ParameterError(
            "system", f"at most {MAX_PROVEN_ACTUATORS} actuators (m) for a proof inside the box", system.m
        )
    k = system.gain(K)
    if not 0.0 < eps < 1.0:
        raise ParameterError("eps", "in (0, 1) (the perturbed speeds stay positive)", eps)
    if len(points) != len(verdicts):
        raise ParameterError("verdicts", f"one verdict per point ({len(points)})", len(verdicts))
    max_boxes = positive_int("max_boxes", max_boxes)
    d_lo, d_hi = (float(v) for v in window)
    base = next((j for j, v in enumerate(verdicts) if v.stable and v.certified), -1)
    if base < 0:
        return SpeedBoxProof(False, "no point of the box is certified stable on the window", math.nan, 0)
    bounds = _speed_box(system, eps, points)
    with working_precision(53) as flint:
        arb = flint.arb
        # the box of inverse speeds (a_1, ..., a_n, b_1, ..., b_m), rounded outwards
        inverse = tuple((ball_lower(1 / arb(hi)), ball_upper(1 / arb(lo))) for lo, hi in bounds)
        prove = _one_actuator if system.m == 1 else _several_actuators
        outcome = prove(flint, system, k, inverse, (d_lo, d_hi), max_boxes)
    if isinstance(outcome, SpeedBoxProof):
        return replace(outcome, base=base)
    W, boxes = outcome
    span = ", ".join(f"[{upper_bound_text(lo, 9)}, {lower_bound_text(hi, 9)}]" for lo, hi in bounds)
    names = "lam_1, ..., lam_n, mu" if system.m == 1 else "lam_1, ..., lam_n, mu_1, ..., mu_m"
    strong = "gamma_0 < 1" if system.m == 1 else "the principal term of rate 0 dominant"
    return SpeedBoxProof(
        True,
        f"no zero on the imaginary axis for any speeds ({names}) in {span} and delay of the window "
        f"({boxes} boxes in ball arithmetic), none with Re s >= 0 and |s| >= {upper_bound_text(W)} ({strong} on the "
        f"box), and the plant of points[{base}] certified stable on the window: no zero in Re s >= 0 anywhere on the "
        "box",
        W,
        boxes,
        base,
    )


def _balls(flint: Any, box: Sequence[tuple[float, float]]) -> list[Any]:
    """The arb balls of the float intervals ``box``."""
    return [flint.arb(lo).union(flint.arb(hi)) for lo, hi in box]


def _undecided(
    flint: Any, w0: float, w1: float, box: Sequence[tuple[float, float]], W: float, boxes: int
) -> SpeedBoxProof:
    """The outcome at a box that no subdivision decides (``box`` the intervals of the inverse speeds)."""
    arb = flint.arb
    speeds = [(ball_lower(1 / arb(b)), ball_upper(1 / arb(a))) for a, b in box]
    where = ", ".join(f"[{lower_bound_text(a, 9)}, {upper_bound_text(b, 9)}]" for a, b in speeds)
    return SpeedBoxProof(
        False,
        "a zero of F on the imaginary axis for w in "
        f"[{lower_bound_text(w0, 9)}, {upper_bound_text(w1, 9)}] at speeds (lam_1, ..., lam_n, mu_1, ..., mu_m) in "
        f"{where} for a delay of the window (or a crossing delay at an end of the window): not stable there, or not "
        "decided; a smaller tolerance or a window clear of the crossing delays decides",
        W,
        boxes,
        -1,
        tuple(0.5 * (a + b) for a, b in speeds),
    )


def _stopped(max_boxes: int, w0: float, w1: float) -> CertificationError:
    """The refusal at the work bound."""
    return CertificationError(
        f"prove_speed_box: the work bound max_boxes = {max_boxes} was reached (at w in [{w0:.6g}, {w1:.6g}]); a "
        "larger max_boxes or a smaller tolerance decides"
    )


def _one_actuator(
    flint: Any,
    system: NPlusMSystem,
    k: Any,
    inverse: tuple[tuple[float, float], ...],
    window: tuple[float, float],
    max_boxes: int,
) -> tuple[float, int] | SpeedBoxProof:
    """Steps 1 and 2 of the module notes for ``m = 1``: ``(W, boxes)``, or the outcome that is not proven."""
    arb = flint.arb
    d_lo, d_hi = window
    fam = _Family(flint, system, k)
    W = _tail(flint, fam, system, k, _balls(flint, inverse))
    if isinstance(W, str):
        return SpeedBoxProof(False, W, math.nan, 0)
    c, _ = fam.generator(_balls(flint, inverse))
    fam.beta = symmetric_top_bound(flint, [[(c[i][j] + c[j][i]) / 2 for j in range(len(c))] for i in range(len(c))])
    stack: list[tuple[float, float, tuple[tuple[float, float], ...]]] = [(0.0, W, inverse)]
    boxes = 0
    while stack:
        w0, w1, box = stack.pop()
        boxes += 1
        w = arb(w0).union(arb(w1))
        A, B = fam.factors(w, _balls(flint, box))
        if crossing_free(flint, A, B, w, d_lo, d_hi):
            continue
        A, B, shares = fam.centred(w0, w1, box)
        if crossing_free(flint, A, B, w, d_lo, d_hi):
            continue
        # halve the parameter with the largest share of the enclosures' widths
        j = int(np.argmax(shares))
        lo, hi = (w0, w1) if j == 0 else box[j - 1]
        if hi - lo <= _MIN_WIDTH * max(1.0, abs(hi)):
            return _undecided(flint, w0, w1, box, W, boxes)
        if boxes >= max_boxes:
            raise _stopped(max_boxes, w0, w1)
        mid = 0.5 * (lo + hi)
        if j == 0:  # the lower frequencies first: a crossing, where it is not stable, is found early
            stack += [(mid, w1, box), (w0, mid, box)]
        else:
            left, right = list(box), list(box)
            left[j - 1], right[j - 1] = (lo, mid), (mid, hi)
            stack += [(w0, w1, tuple(left)), (w0, w1, tuple(right))]
    return W, boxes


def _several_actuators(
    flint: Any,
    system: NPlusMSystem,
    k: Any,
    inverse: tuple[tuple[float, float], ...],
    window: tuple[float, float],
    max_boxes: int,
) -> tuple[float, int] | SpeedBoxProof:
    """Steps 1 and 2 of the module notes for ``m > 1`` (module notes, "Several actuators"): ``(W, boxes)``, or the
    outcome that is not proven.

    A box of ``(w, a_1, ..., a_n, b_1, ..., b_m, delta)`` is cleared by :func:`_cleared` with the coefficients of ``F =
    sum_d c_d z^d`` enclosed by the centred form (:meth:`_Loop.centred`, :data:`_BATCH` boxes at a time); otherwise
    the parameter with the largest share of their widths is halved.
    """
    loop = _Loop(flint, system, k, _balls(flint, inverse))
    W = _compound_tail(flint, loop, system, k, _balls(flint, inverse))
    if isinstance(W, str):
        return SpeedBoxProof(False, W, math.nan, 0)
    stack: list[tuple[tuple[float, float], ...]] = [((0.0, W), *inverse, window)]
    boxes = 0
    while stack:
        # up to _BATCH boxes get the centred form together
        batch = [stack.pop() for _ in range(min(_BATCH, len(stack)))]
        children: list[tuple[tuple[float, float], ...]] = []
        for box, (coefficients, shares) in zip(batch, loop.centred([box[:-1] for box in batch])):
            boxes += 1
            balls = _balls(flint, box)
            if _cleared(flint, coefficients, balls[0], balls[-1], window):
                continue
            # halve the parameter with the largest share of the centred enclosures' widths; one at the smallest width
            # is not halved again; the roots in z decide for every delay of the window, so the delay is not halved
            narrow = [hi - lo <= _MIN_WIDTH * max(1.0, abs(hi)) for lo, hi in box[:-1]]
            j = int(np.argmax(np.where(narrow, -1.0, shares)))
            (w0, w1), (lo, hi) = box[0], box[j]
            if narrow[j]:
                return _undecided(flint, w0, w1, box[1:-1], W, boxes)
            if boxes >= max_boxes:
                raise _stopped(max_boxes, w0, w1)
            mid = 0.5 * (lo + hi)
            left, right = list(box), list(box)
            left[j], right[j] = (lo, mid), (mid, hi)
            children = [tuple(right), tuple(left), *children]
        stack += children  # the first box popped on top again, its lower half first: the lower frequencies first
    return W, boxes
