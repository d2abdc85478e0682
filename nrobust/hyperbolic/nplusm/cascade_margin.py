"""A proven bracket of the full-state backstepping law's delay margin when the leftward speeds differ.

With several speeds ``mu`` the law's loop goes through the target's ``G`` (module notes of
:mod:`nrobust.hyperbolic.nplusm.kernels`, *Cascade loop*)::

    f(w, z) = det((1 - z) M_0(i w) + z E T(i w)),     z = e^{-i w delta},

``M_0 = E (Phi_v - R Phi_u)`` the open loop and ``E T = V (I - int_0^1 e^{x C} Lambda-^{-1} G dx)``.
:func:`~nrobust.hyperbolic.nplusm.kernel_error_bound` proves ``||E T - E T_h|| <= eps`` for the
grid kernels' ``E T_h`` (:meth:`~nrobust.hyperbolic.nplusm.NPlusMBackstepping.target_transition`).
Off the axis the entries of ``M_0`` grow like ``e^{Re s (1/mu_min - 1/mu_j)}``, so ``eps`` does not
bound the error of the determinant there; on the axis ``|e^{-i w / mu}| = 1`` and every matrix
is bounded, so the search below works on the axis only.

**Bounds on the axis** (``|z| = 1``). ``||M_0(i w)|| <= a_0 = ||[-R, I]|| e^{beta} ||[Q; I]||`` with
``beta = lambda_max(Herm Lambda^{-1} Sigma)`` (``Herm(-i w Lambda^{-1}) = 0``), and its ``k``-th
``w``-derivative is at most ``q^k a_0``, ``q = 1/mu_min + ||Lambda^{-1}||`` (Dyson's expansion and
the row factor ``E``). ``D`` commutes with ``Lambda-``, so ``d/dw e^{x C(i w)} = -i x Lambda-^{-1}
e^{x C}`` and ``||d^k/dw^k (E T - V)|| <= mu_min^{-k} t_0``, ``t_0 = ||V|| int_0^1 e^{x ell}
||Lambda-^{-1} G_h|| dx + eps`` (``ell`` the logarithmic-norm bound of ``Lambda-^{-1} D`` of
:mod:`~nrobust.hyperbolic.nplusm.kernel_error`; ``||Lambda-^{-1} G_h||`` is convex on a cell, at
most its larger end). So ``||A_w|| <= alpha_1 = 2 q a_0 + t_0 / mu_min`` and ``||A|| <= alpha_0 = 2 a_0 +
||V|| + t_0`` for the exact loop's ``A = (1 - z) M_0 + z E T``, every ``w`` and ``|z| = 1``; with
``|d det A| <= m ||dA|| ||A||^{m-1}``, ``|f_w| <= L_w = m alpha_1 alpha_0^{m-1}`` and (``dA/dphi = i z
(E T - M_0)``) ``|f_phi| <= L_phi = m (a_0 + ||V|| + t_0) alpha_0^{m-1}``.

**Search.** ``f(w, e^{i phi}) = 0`` iff ``sigma_min(A) = 0``. On a cell ``[w_0 +- h_w] x [phi_0 +-
h_phi]``, ``sigma_min(A(w, z)) >= sigma_min(A(w_0, z_0)) - h_w alpha_1 - h_phi ||E T - M_0||(w_0)``
(Weyl; ``|z - z_0| <= h_phi``): the derivative bound in ``phi`` is the cell's own. At the centre,
``sigma_min`` of the exact loop is at least that of the enclosure's midpoint ``A_h`` (proven below,
*Enclosures*) minus the Frobenius norm of the enclosure's radius and ``eps``: a cell whose lower
bound is positive holds no zero. The others are halved in the direction of the larger term, all
cells of a round evaluated in one vectorised call (each distinct ``w`` once), until the slack
``h_w alpha_1 + h_phi ||E T - M_0||`` is a quarter of the gap between the floating-point
``sigma_min`` of ``A_h`` and that lower bound (mostly ``eps``): those cells stay, the region where
the kernels' error leaves the sign of ``f`` open. Halving rounds the cells' centres ``c -+ h / 2``:
the halves' half-widths are ``h / 2 + EPS (|c| + h)``, so they cover the cell, and the first cells'
are widened for the rounding of their centres and of ``2 pi``: the cells cover ``[0, W] x [0, 2 pi]``.

**Existence.** The cells left fall in groups of touching cells. In each, Newton steps on the grid
loop give ``x_0`` and its Jacobian ``J`` in ``(w, phi)``; for ``g = J^{-1} (Re f, Im f)`` of the
exact loop the signs ``g_1 < 0`` at ``w = w_0 - a``, ``> 0`` at ``w_0 + a`` and ``g_2 < 0`` at
``phi = phi_0 - a``, ``> 0`` at ``phi_0 + a`` prove a zero in the box (Poincare-Miranda). They are
checked at the midpoints of short pieces of each face, with ``f_h = det A_h`` enclosed (cofactors)
and ``|f - f_h| <= prod(sigma_i + e) - prod sigma_i`` for ``||A - A_h|| <= e``, ``sigma_i`` proven
upper bounds of the singular values of ``A_h`` (the bound increases with each; in the singular vectors' bases
``det(Sigma + E') = sum_S det E'[S, S] prod_{i not in S} sigma_i`` and ``|det E'[S, S]| <=
e^{|S|}``; Ipsen and Rehman, SIAM J. Matrix Anal. Appl. 30, 2008), and the Lipschitz bound ``L_w``
or ``L_phi`` along the face standing for the rest of each piece. A group without a proven zero is
refused.

**Frequency bound.** On the axis ``A = A_0 + Delta`` with the principal part ``A_0(w, z) = V -
(1 - z) sum_t R_t e^{-i w tau_t}`` (:meth:`~nrobust.hyperbolic.nplusm.NPlusMSystem.principal_terms`,
``K = -R``) and ``||A_0^{-1}|| <= kappa`` for every ``w`` and ``|z| <= 1``
(:func:`_principal_inverse`: ``rho(2 sum_t |V^{-1} R_t|) < 1`` proven, a Neumann series). The
rest: ``(1 - z) E [-R, I] (Phi - Phi_0) [Q; I]``, at most ``2 ||[-R, I]|| ||[Q; I]|| r(w)``
(the remainder of :class:`~nrobust.margins.matrix.GaugeRemainder` on the axis, ``|E| = 1``, its
constants ``||N||``, ``||H||``, ``beta_d`` proven in ball arithmetic), and ``z (E T - V)``.
Integrating by parts on the cells of the piecewise-linear ``H = Lambda-^{-1} G_h``
(``||C(i w)^{-1}|| <= 1 / (w / mu_max - ||Lambda-^{-1} D||)``), ``||E T_h - V|| <= ||V|| (e^{ell}
(||H(1)|| + TV(H)) + ||H(0)||) / (w / mu_max - ||Lambda-^{-1} D||)``, and the exact kernels add
``eps``. Beyond the ``W`` where ``kappa`` times the sum is below 1, ``A`` is invertible: ``f != 0``
on the axis. ``eps`` does not decay in ``w``, so ``kappa eps < 1`` is needed at least.

**The margin.** At ``delta = 0`` the loop is ``det(E T) = det V != 0`` (no root). The delayed
principal part is strongly stable: its ``gamma_0``, the largest ``rho(sum_t V^{-1} R_t (e^{i theta_t}
- e^{i theta'_t}))``, is at most ``rho(2 sum_t |V^{-1} R_t|) < 1`` (proven for ``kappa``; ``rho(X) <=
rho(|X|)``), so roots enter ``Re s >= 0`` only across the
imaginary axis at a finite frequency (Hale and Verduyn Lunel, neutral equations: the kernel
terms are distributed delays, which do not move the essential spectrum); the margin is the
smallest delay ``(-phi mod 2 pi) / w`` over the zeros ``(w, phi)`` of ``f``. When the sampled
``gamma_0`` exceeds 1 the margin is 0, returned once the matrix at a sampled point of the torus,
formed in balls from the exact data, has an enclosed eigenvalue of modulus above 1
(:func:`_gamma_above_one`). Every zero lies in a
cell left by the search, so the margin is at least the smallest delay over those cells; one zero
lies in each proven box, so it is at most the largest delay over a box (the smallest such bound
over the boxes). The bracket's width is of the order of ``eps``: first order in the kernel grid's
step (halving with it, measured).

**Enclosures.** Every number the proof uses is enclosed, for the plant's data as stored (each
float an exact rational) and the grid kernels' ``G_h`` at the nodes: the constants above
(``beta``, the norms, ``V``, ``ell``, ``t_0``, the total variation, ``kappa``, the gauge's
constants, ``W``'s test) in FLINT's ball arithmetic (python-flint; ``V`` and the ``U_a`` by
``arb_mat.exp``, ``lambda_max`` and spectral norms by a proven ``L D L^T`` or Frobenius's bound);
``M_0(i w)`` and ``E T_h(i w)`` at each frequency, and ``e^{i phi}``, in vectorised
midpoint-radius arithmetic (:mod:`~nrobust.hyperbolic.nplusm._midrad`: the exponentials by
scaling, a Taylor polynomial with its proven remainder and squaring, every rounding bounded by
Higham's model of IEEE arithmetic); the singular values of ``A_h`` a posteriori from a
floating-point SVD (``||U^H U - I||``, ``||A_h - U S V^H||`` enclosed), ``det A_h`` by cofactors, and
the delays ``theta / w`` with their rounding. ``E T_h`` is the Filon integral of ``G_h`` linear
between the nodes ``k h`` (``h`` the grid's float step); :func:`~nrobust.hyperbolic.nplusm.kernel_error_bound`
bounds the exact law against ``G_h`` linear between the grid's own ``x_k`` on ``[0, 1]``, and ``eps``
here adds the difference (``||V|| e^{ell L} (L max slope max |x_k - k h| + |L - 1| max ||H||)``,
``L = max(1, (N - 1) h)``, about ``1e-16``).

**Cost.** The exclusion needs no derivative of ``f`` beyond the uniform ``alpha_1`` and evaluates
the loop's enclosures, vectorised, at about 300 to 3000 frequencies (the Filon sum in
``log2(cells)`` rounds of pairs); only Newton's steps (eight jets of 13 floating-point
evaluations) and the faces of the boxes (a few hundred points) come on top. Measured for the
plants of ``tests/test_nplusm_cascade_cert.py`` (CPU, best of three, alternated with the former
code, load 6 to 9 on two cores): ``Sigma--_01 = 0.3`` (``W = 37``, no crossing) 0.3 to 0.6 s on 21 to
81 kernel points (0.3 to 0.7 s with the former floating-point error models); the plant with a
crossing 0.9 to 1.9 s (1.0 to 1.8 s), of which about 0.3 s is ``gamma_0``'s bracket. The
brackets moved by about ``2e-9``.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._flint import ball_upper, precision, require_flint
from ..._threads import one_blas_thread
from ..._validate import positive, positive_int
from ...errors import CertificationError, ParameterError
from ._midrad import EPS, TINY, UP, Ball, det, exact, expm, frobenius, identity, singular_bounds
from .characteristic import GRID_PER_PERIOD, NPlusMCharacteristic, arb_max, spectral_norm_bound, symmetric_top_bound
from .kernel_error import KernelErrorBound, kernel_error_bound
from .kernels import BACKSTEPPING_ROUTES, CASCADE_SCOPE, KERNEL_SCOPE, NPlusMBackstepping, in_group_part
from .margin import NPlusMMargin, backstepping_exact_margin, pencil_crossings, principal_gamma_bounds
from .system import NPlusMSystem, speed_groups

__all__ = ["backstepping_delay_margin", "cascade_delay_margin"]

_SCOPE = (
    "full-state backstepping law with exact kernels on the PDE, leftward speeds that differ: loop through the "
    "target's G, the grid kernels' proven error (kernel_error_bound) carried by the search; margin_bracket proven "
    "for the PDE, every floating-point step enclosed (ball arithmetic for the constants, midpoint-radius "
    "enclosures of the loop's matrices, a-posteriori bounds of singular values and determinants)"
)
# Cauchy's formula for the w-derivative of the grid loop (Newton steps only, no bound rests on it):
# points on a circle of radius _RING around s = i w.
_RING, _RING_POINTS = 1e-2, 12
# The search: phase cells of the first grid, Newton steps to a box's centre, the narrowest cell
# (relative to max(1, W)), the slack below which a cell is not split (relative to the error of
# sigma_min), and work bounds on the cells left open and the points of a box's face.
_PHASE_CELLS, _NEWTON_STEPS, _MIN_WIDTH, _RESOLVE, _MAX_OPEN, _MAX_FACE = 16, 8, 1e-11, 0.25, 10_000, 20_000
_PREC = 80  # bits of the ball arithmetic of the constants
_BLOCK = 512  # rows of the touching test at a time (memory: _BLOCK times the cells left)
# Cells of the (w, phi) rectangle: centres and half-widths (four arrays of one size).
_Cells = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]


def _arb_matrix(flint: Any, x: NDArray[Any]) -> Any:
    """The float matrix ``x`` as an exact ``arb_mat``."""
    return flint.arb_mat([[flint.arb(float(v)) for v in row] for row in np.atleast_2d(x)])


def _to_ball(x: Any) -> Ball:
    """An ``arb_mat`` as a :class:`~nrobust.hyperbolic.nplusm._midrad.Ball` (radius rounded upwards)."""
    rows, cols = x.nrows(), x.ncols()
    mid = np.array([[float(x[i, j].mid()) for j in range(cols)] for i in range(rows)])
    rad = np.array(
        [[ball_upper(x[i, j].rad()) + EPS * abs(float(x[i, j].mid())) for j in range(cols)] for i in range(rows)]
    )
    return Ball(mid, rad * UP)


def _ball_principal(flint: Any, system: NPlusMSystem) -> tuple[Any, list[Any]]:
    """``V = exp(-Lambda-^{-1} D)`` and the ``R_t = P_b R P_a U_a Q`` of
    :meth:`~nrobust.hyperbolic.nplusm.NPlusMSystem.principal_terms` as ``arb_mat`` (exact data, proven exponentials)."""
    n, m = system.n, system.m
    arb = flint.arb

    def block(rows: NDArray[np.intp], speed: float, sign: int) -> Any:
        return flint.arb_mat([[arb(float(system.sigma[i, k])) * sign / arb(speed) for k in rows] for i in rows]).exp()

    u_block = flint.arb_mat(n, n)
    for g in speed_groups(system.lam):
        e = block(g, float(system.lam[g[0]]), 1)
        for a, i in enumerate(g):
            for b, k in enumerate(g):
                u_block[int(i), int(k)] = e[a, b]
    v_block = flint.arb_mat(m, m)
    for g in speed_groups(system.mu):
        e = block(g + n, float(system.mu[g[0]]), -1)
        for a, i in enumerate(g):
            for b, k in enumerate(g):
                v_block[int(i), int(k)] = e[a, b]
    uq = u_block * _arb_matrix(flint, system.q)
    terms = []
    for ga in speed_groups(system.lam):
        for gb in speed_groups(system.mu):
            pr = np.zeros((m, n))  # P_b R P_a (U is block diagonal on the groups: P_a U = U P_a)
            pr[np.ix_(gb, ga)] = system.r[np.ix_(gb, ga)]
            terms.append(_arb_matrix(flint, pr) * uq)
    return v_block, terms


class _CascadeLoop:
    """The grid kernels' loop on the axis, its enclosures and the bounds of the module notes (all proven)."""

    def __init__(self, controller: NPlusMBackstepping, bound: KernelErrorBound) -> None:
        flint = require_flint()
        sys = controller.system
        self.controller, self.system, self.m = controller, sys, sys.m
        n, m = sys.n, sys.m
        mu_min, mu_max = float(sys.mu.min()), float(sys.mu.max())
        self.mu_min, self.mu_max = mu_min, mu_max
        x = controller.kernels.grid
        h = float(x[1] - x[0])
        self.h = h
        mask = sys.mu[None, :] > sys.mu[:, None]
        G = controller.kernels.G * mask[:, :, None]
        with precision(flint, _PREC):
            arb = flint.arb
            speeds = [arb(float(v)) for v in sys.signed_speeds]
            c_full = [[arb(float(sys.sigma[i, k])) / speeds[i] for k in range(n + m)] for i in range(n + m)]
            beta = symmetric_top_bound(
                flint, [[0.5 * (c_full[i][k] + c_full[k][i]) for k in range(n + m)] for i in range(n + m)]
            )
            left = spectral_norm_bound(flint, _arb_matrix(flint, np.hstack([-sys.r, np.eye(m)])))
            right = spectral_norm_bound(flint, _arb_matrix(flint, np.vstack([sys.q, np.eye(m)])))
            self.left, self.right = ball_upper(left), ball_upper(right)
            a0 = left * beta.exp() * right
            q = 1 / arb(mu_min) + max(1 / abs(v) for v in speeds)
            v_ball, _ = _ball_principal(flint, sys)
            self.v = _to_ball(v_ball)
            v_norm = spectral_norm_bound(flint, v_ball)
            d_mat = in_group_part(sys)
            a_mat = [[arb(float(d_mat[i, k])) / arb(float(sys.mu[i])) for k in range(m)] for i in range(m)]
            self.decay_shift = ball_upper(spectral_norm_bound(flint, flint.arb_mat(a_mat)))
            sym = [[0.5 * (a_mat[i][k] + a_mat[k][i]) for k in range(m)] for i in range(m)]
            ell = arb.max(
                arb(0),
                arb_max(
                    flint, [sym[i][i] + sum((abs(sym[i][k]) for k in range(m) if k != i), arb(0)) for i in range(m)]
                ),
            )
            # Lambda-^{-1} G_h at the nodes, Frobenius norms; the loop integrates the function linear between the
            # nodes k h (length L = (N - 1) h), kernel_error_bound the one between the grid's x_k on [0, 1]
            hb = arb(h)
            fro = []
            for k in range(x.size):
                fro.append(
                    sum(
                        (arb(float(G[a, c, k])) ** 2 / arb(float(sys.mu[a])) ** 2 for a in range(m) for c in range(m)),
                        arb(0),
                    ).sqrt()
                )
            steps = [
                sum(
                    (
                        (arb(float(G[a, c, k + 1])) - arb(float(G[a, c, k]))) ** 2 / arb(float(sys.mu[a])) ** 2
                        for a in range(m)
                        for c in range(m)
                    ),
                    arb(0),
                ).sqrt()
                for k in range(x.size - 1)
            ]
            length = hb * (x.size - 1)
            reach = arb.max(arb(1), length)
            grow_ell = (ell * reach).exp()
            shift = max(abs(Fraction(float(v)) - k * Fraction(h)) for k, v in enumerate(x))
            slope = arb_max(flint, [s_k / hb for s_k in steps])
            grid = (
                v_norm
                * grow_ell
                * (slope * arb(float(shift)) * (1 + 1e-9) * reach + abs(length - 1) * arb_max(flint, fro))
            )
            eps = arb(float(bound.transition_error)) + grid
            self.eps = ball_upper(eps)
            g_int = sum(
                (hb * arb.max(fro[k], fro[k + 1]) * (ell * hb * (k + 1)).exp() for k in range(x.size - 1)), arb(0)
            )
            t0 = v_norm * g_int + eps
            tv = sum(steps, arb(0))
            self.decay = ball_upper(v_norm * (grow_ell * (fro[-1] + tv) + fro[0]))
            self.v_norm = ball_upper(v_norm)
            self.a0 = ball_upper(a0)
            # bounds of the exact loop's A = (1 - z) M_0 + z E T and its w-derivative on the axis, |z| = 1
            alpha0 = 2 * a0 + v_norm + t0
            alpha1 = 2 * a0 * q + t0 / arb(mu_min)
            self.alpha = [ball_upper(alpha0), ball_upper(alpha1)]
            grow = m * alpha0 ** (m - 1)
            self.lipschitz = (ball_upper(grow * alpha1), ball_upper(grow * (a0 + v_norm + t0)))
        # the data of the enclosures: C = Lambda^{-1} Sigma (two roundings) and the quotients (one rounding each)
        inv = 1.0 / sys.signed_speeds
        self._c = Ball(inv[:, None] * sys.sigma, 2.0 * EPS * np.abs(inv[:, None] * sys.sigma))
        self._p = Ball(np.diag(inv), np.diag(EPS * np.abs(inv)))
        self._inv_mu = Ball(1.0 / sys.mu, EPS / sys.mu)
        self._inv_mu_diag = Ball(np.diag(1.0 / sys.mu), np.diag(EPS / sys.mu))
        self._w = exact(np.vstack([sys.q, np.eye(m)]))
        self._l = exact(np.hstack([-sys.r, np.eye(m)]))
        dm = in_group_part(sys) / sys.mu[:, None]
        self._cd = Ball(dm, EPS * np.abs(dm))
        hmat = G / sys.mu[:, None, None]
        g = Ball(np.moveaxis(hmat, 2, 0), EPS * np.abs(np.moveaxis(hmat, 2, 0)))  # (N, m, m)
        diff = g[1:] - g[:-1]  # times 1 / h in I_1 / h
        both = np.concatenate([g.mid[:-1], diff.mid], axis=-1), np.concatenate([g.rad[:-1], diff.rad], axis=-1)
        self._cells = Ball(both[0][None], both[1][None])  # c_k = [H_k, H_{k+1} - H_k], shape (1, cells, m, 2 m)
        self.roots = np.exp(2j * np.pi * np.arange(self.m + 1) / (self.m + 1))

    # ------------------------------------------------------------------ the grid kernels' loop in floating point
    def matrices(self, s: NDArray[Any]) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        """``M_0(s)`` and ``E T_h(s)`` for an array of ``s`` (floating point: Newton's steps only)."""
        return self.system.loop_matrix(s), self.controller.target_transition(s)

    def _coefs_at(self, s: NDArray[np.complex128]) -> NDArray[np.complex128]:
        m0, et = self.matrices(s)
        vals = np.linalg.det(m0[:, None] + self.roots[None, :, None, None] * (et - m0)[:, None])
        return np.asarray(np.fft.fft(vals, axis=1) / (self.m + 1), dtype=complex)

    def coefs(self, w: NDArray[np.float64]) -> NDArray[np.complex128]:
        """``c_d(w)``: ``f_h(w, z) = sum_d c_d z^d``, shape ``(w.size, m + 1)``."""
        return self._coefs_at(1j * np.asarray(w, dtype=float))

    def jet(self, w: NDArray[np.float64]) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        """``c_d(w)`` and ``c_d'(w)``, the derivative by Cauchy's formula on a circle about ``i w``."""
        w = np.asarray(w, dtype=float)
        ring = _RING * np.exp(2j * np.pi * np.arange(_RING_POINTS) / _RING_POINTS)
        s = (1j * w[:, None] + ring[None]).reshape(-1)
        vals = self._coefs_at(s).reshape(w.size, _RING_POINTS, self.m + 1)
        ds = np.mean(vals / ring[None, :, None], axis=1)  # d/ds; d/dw = i d/ds
        return self.coefs(w), 1j * ds

    # ------------------------------------------------------------------ enclosures
    def enclose(self, w: NDArray[np.float64]) -> tuple[Ball, Ball]:
        """Enclosures of ``M_0(i w)`` and of ``E T_h(i w)`` (``G_h`` linear between the nodes ``k h``), per ``w``.

        ``M_0``'s row ``j`` is ``e^{-i w / mu_j} [-R, I]_j exp(C - i w Lambda^{-1}) [Q; I]``; ``E T_h =
        V (I - acc)``, ``acc = I_0 S_0 + I_1 S_1`` with ``S = sum_k e^{k h C} [H_k, (H_{k+1} - H_k) / h]``
        (summed by pairs; ``e^{h C}`` commutes with ``I_0``, ``I_1``), the moments from the exponential of
        ``h [[C, I, 0], [0, 0, I], [0, 0, 0]]``, ``C = Lambda-^{-1} (D - i w)``.
        """
        w = np.asarray(w, dtype=float).reshape(-1)
        m = self.m
        iw = Ball(1j * w)[:, None, None]
        phi = expm(self._c - iw * self._p) @ self._w
        rows = self._l @ phi
        scale = expm((Ball(-1j * w)[:, None] * self._inv_mu)[:, :, None, None])[:, :, 0, 0]
        m0 = rows * scale[:, :, None]
        hb = exact(np.array(self.h))
        cmat = (self._cd - iw * self._inv_mu_diag) * hb
        mid = np.zeros((w.size, 3 * m, 3 * m), dtype=complex)
        rad = np.zeros(mid.shape)
        mid[:, :m, :m], rad[:, :m, :m] = cmat.mid, cmat.rad
        mid[:, :m, m : 2 * m] = mid[:, m : 2 * m, 2 * m :] = self.h * np.eye(m)
        big = Ball(mid, rad)
        ex = expm(big)
        step, i0 = ex[:, :m, :m], ex[:, :m, m : 2 * m]
        i1 = i0 * hb - ex[:, :m, 2 * m :]
        # S = sum_k step^k c_k by pairs: c_{2j} + step c_{2j+1} with step^2 in place of step, log2(cells) rounds
        c = self._cells
        power = step[:, None]
        while c.mid.shape[1] > 1:
            if c.mid.shape[1] % 2:
                pad = np.zeros((c.mid.shape[0], 1, *c.mid.shape[2:]))
                c = Ball(np.concatenate([c.mid, pad], axis=1), np.concatenate([c.rad, pad], axis=1))
            c = c[:, 0::2] + power @ c[:, 1::2]
            power = power @ power
        acc_g, acc_d = c[:, 0, :, :m], c[:, 0, :, m:]
        inv_h = Ball(np.array(1.0 / self.h), np.array(EPS / self.h))
        acc = i0 @ acc_g + (i1 * inv_h) @ acc_d
        et = self.v @ (identity((w.size,), m) - acc)
        return m0, et

    def unit(self, phi: NDArray[np.float64]) -> Ball:
        """Enclosures of ``e^{i phi}`` (a ``1 x 1`` exponential)."""
        phi = np.asarray(phi, dtype=float).reshape(-1)
        return expm(Ball(1j * phi)[:, None, None])[:, 0, 0]

    def exclusion(
        self, phi: NDArray[np.float64], m0: Ball, m1: Ball
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(l, e)`` at the points ``(w, phi)`` from enclosures of ``M_0(i w)`` and ``E T_h(i w) - M_0(i w)``:
        ``l <= sigma_min`` of the exact loop's ``A(w, e^{i phi})`` (proven) and ``e`` the floating-point
        ``sigma_min`` of the enclosure's midpoint minus ``l`` (the kernels' error and the radii: the search's
        resolution)."""
        a = m0 + self.unit(phi)[:, None, None] * m1
        lower, upper = singular_bounds(a.mid)
        dist = (frobenius(a.rad) + self.eps) * UP
        low = lower[:, -1] - dist
        low = low - 2.0 * EPS * np.abs(low) - TINY
        sig = 0.5 * (lower[:, -1] + upper[:, -1])  # the floating-point sigma_min, to 1e-12 relative
        return np.asarray(low, dtype=float), np.asarray(np.maximum(sig - low, 0.0), dtype=float)

    def phase_lipschitz(self, m1: Ball) -> NDArray[np.float64]:
        """``p >= ||E T(i w) - M_0(i w)||`` of the exact loop from an enclosure of ``E T_h - M_0``."""
        _, upper = singular_bounds(m1.mid)
        return np.asarray((upper[:, 0] + frobenius(m1.rad) + self.eps) * UP, dtype=float)


def _principal_inverse(system: NPlusMSystem) -> float:
    """``kappa >= ||A_0(w, z)^{-1}||`` for every ``w`` and ``|z| <= 1`` (module notes, *Frequency bound*).

    ``A_0 = V (I - X)``, ``X = V^{-1} sum_t (1 - z) R_t e^{-i w tau_t}``, ``|X| <= T = 2 sum_t |V^{-1} R_t|``
    entrywise. A vector ``x > 0`` with ``T x < x`` proves ``rho(T) < 1`` (Collatz-Wielandt), so
    ``|(I - X)^{-1}| <= sum_k T^k = (I - T)^{-1}`` entrywise and ``kappa = ||(I - T)^{-1} |V^{-1}|||_F``.
    Ball arithmetic (python-flint): ``V`` and the ``R_t`` from the plant's data with FLINT's exponentials.

    Raises
    ------
    CertificationError
        No such ``x`` (``rho(T) >= 1`` or too close to 1 to prove).
    """
    flint = require_flint()
    m = system.m
    with precision(flint, _PREC):
        v_block, point = _ball_principal(flint, system)
        v_inv = v_block.inv()
        t = flint.arb_mat(m, m)
        for rq in point:
            prod = v_inv * rq
            for i in range(m):
                for j in range(m):
                    t[i, j] += 2 * abs(prod[i, j])
        upper = np.array([[float(t[i, j].upper()) for j in range(m)] for i in range(m)])
        vals, vecs = np.linalg.eig(upper)
        x = np.abs(vecs[:, int(np.argmax(np.abs(vals)))].real) + 1e-9
        tx = t * _arb_matrix(flint, x[:, None])
        if not all(tx[i, 0] < float(x[i]) for i in range(m)):
            raise CertificationError(
                "cascade margin: the principal part's bound rho(2 sum_t |V^{-1} R_t|) is not proven below 1, so "
                "no uniform bound of its inverse on the axis (the frequency bound needs one)"
            )
        eye = flint.arb_mat([[float(i == j) for j in range(m)] for i in range(m)])
        n_mat = (eye - t).inv() * flint.arb_mat([[abs(v_inv[i, j]) for j in range(m)] for i in range(m)])
        fro = sum((n_mat[i, j] ** 2 for i in range(m) for j in range(m)), flint.arb(0)).sqrt()
        return ball_upper(fro)


def _gamma_above_one(system: NPlusMSystem) -> bool:
    """True if ``gamma_0 > 1`` of the delayed principal part is proven for the exact data.

    ``gamma_0`` is the supremum over independent phases of ``rho(sum_t V^{-1} R_t (e^{i theta_t} -
    e^{i theta'_t}))`` (the terms of ``R`` at ``tau_t``, those of ``K = -R`` at ``tau_t + delta``); at the
    best of 2048 sampled phases (seeded) the matrix is formed from FLINT's ``V`` and ``R_t`` and its
    eigenvalues enclosed (``acb_mat.eig``, clusters allowed): one of modulus ``> 1`` proves it.
    """
    flint = require_flint()
    with precision(flint, _PREC):
        v_block, point = _ball_principal(flint, system)
        coefs = [v_block.inv() * rq for rq in point]
        mats = [np.array([[float(c[i, j].mid()) for j in range(system.m)] for i in range(system.m)]) for c in coefs]
        rng = np.random.default_rng(0)
        theta = rng.uniform(0.0, 2 * np.pi, (2048, 2, len(mats)))
        total = np.einsum("nk,kij->nij", np.exp(1j * theta[:, 0]) - np.exp(1j * theta[:, 1]), np.array(mats))
        best = int(np.argmax(np.max(np.abs(np.linalg.eigvals(total)), axis=-1)))
        acb = flint.acb
        x = flint.acb_mat(system.m, system.m)
        for k, c in enumerate(coefs):
            unit = acb(0, float(theta[best, 0, k])).exp() - acb(0, float(theta[best, 1, k])).exp()
            x += flint.acb_mat(c) * unit
        return any(abs(v) > 1 for v in x.eig(multiple=True))


class _Gauge:
    """``r(w)`` of :class:`~nrobust.margins.matrix.GaugeRemainder` for ``C = Lambda^{-1} Sigma``, ``P = Lambda^{-1}``
    with its constants ``||N||``, ``||H||`` and ``beta_d`` proven in ball arithmetic from the plant's data."""

    def __init__(self, flint: Any, system: NPlusMSystem) -> None:
        arb = flint.arb
        speeds = system.signed_speeds
        size = speeds.size
        c = [[arb(float(system.sigma[i, k])) / arb(float(speeds[i])) for k in range(size)] for i in range(size)]
        p = [1 / arb(float(v)) for v in speeds]
        same = [[speeds[i] == speeds[k] for k in range(size)] for i in range(size)]
        zero = arb(0)
        c_d = flint.arb_mat([[c[i][k] if same[i][k] else zero for k in range(size)] for i in range(size)])
        n_mat = flint.arb_mat(
            [[zero if same[i][k] else c[i][k] / (p[i] - p[k]) for k in range(size)] for i in range(size)]
        )
        h_mat = flint.arb_mat(c) * n_mat - n_mat * c_d
        self.floor = spectral_norm_bound(flint, n_mat)
        self.h_norm = spectral_norm_bound(flint, h_mat)
        self.beta_d = symmetric_top_bound(
            flint, [[0.5 * (c_d[i, k] + c_d[k, i]) for k in range(size)] for i in range(size)]
        )
        self.flint = flint

    def __call__(self, w: Any) -> Any:
        """The ball of ``r(w)`` (``w`` an arb ball ``> ||N||``)."""
        t = 1 / (1 - self.floor / w)
        e = t * self.h_norm
        return ((1 + self.floor / w) * t * e * (self.beta_d + e / w).exp() + 2 * self.floor * t * self.beta_d.exp()) / w


def _frequency_bound(loop: _CascadeLoop, max_frequency: float) -> float:
    """``W``: the exact loop's ``A(w, z)`` is invertible for ``w >= W`` and every ``|z| = 1`` (module notes).

    The test ``kappa (2 ||[-R, I]|| ||[Q; I]|| r(w) + ||E T - V||) < 1`` is evaluated in ball arithmetic
    at each ``w`` tried; its left side does not increase with ``w``.
    """
    flint = require_flint()
    sys = loop.system
    kappa = _principal_inverse(sys)
    with precision(flint, _PREC):
        arb = flint.arb
        gauge = _Gauge(flint, sys)
        scale = 2 * arb(loop.left) * arb(loop.right)

        def below(w: float) -> bool:
            x = arb(w)
            if not (x > gauge.floor and x / loop.mu_max > loop.decay_shift):
                return False
            kernel = arb(loop.decay) / (x / loop.mu_max - loop.decay_shift)
            return bool(kappa * (scale * gauge(x) + kernel + loop.eps) < 1)

        if not kappa * loop.eps < 1.0:
            raise CertificationError(
                f"cascade margin: the kernels' error (eps = {loop.eps:.3g}) exceeds the principal part's room "
                f"1 / kappa = {1.0 / kappa:.3g} at every frequency; a finer kernel_grid would help (eps is first "
                "order in its step)"
            )
        hi = max(2.0 * float(gauge.floor.upper()), 2.0 * loop.mu_max * loop.decay_shift, 1.0)
        while not below(hi):
            hi *= 2.0
            if hi > max_frequency:
                raise CertificationError(
                    f"cascade margin: the kernels' error (eps = {loop.eps:.3g}) and the decay of G's term keep the "
                    f"loop's remainder above the principal part's room 1 / kappa = {1.0 / kappa:.3g} up to "
                    f"max_frequency = {max_frequency:.3g}; a finer kernel_grid or a larger max_frequency would help"
                )
        lo = 0.0
        while hi - lo > 1e-7 * hi:
            mid = 0.5 * (lo + hi)
            if below(mid):
                hi = mid
            else:
                lo = mid
    return hi


def _search(loop: _CascadeLoop, W: float, step: float, max_points: int) -> _Cells:
    """The cells of ``[0, W] x [0, 2 pi)`` that may hold a zero of the exact loop (module notes, *Search*).

    Cells the matrix test excludes are dropped, the others halved (in ``w`` or ``phi``, whichever
    term of the test is larger) until the test's slack ``h_w alpha_1 + h_phi p`` falls below
    ``_RESOLVE`` times the error of the computed ``sigma_min`` (the kernels' ``eps`` and rounding):
    finer cells would not exclude more. The loop's matrices are evaluated once per distinct ``w``,
    all of a round's in one call.

    Raises
    ------
    CertificationError
        More than ``max_points`` evaluations of the loop, or more than ``_MAX_OPEN`` cells left.
    """
    nw = max(1, math.ceil(W / step))
    if nw > max_points:
        raise ParameterError("max_points", f">= {nw} (the first grid up to W = {W:.6g})", max_points)
    hw0 = 0.5 * W / nw
    grid_w = (np.arange(nw) + 0.5) * (2 * hw0)
    grid_p = (np.arange(_PHASE_CELLS) + 0.5) * (2 * np.pi / _PHASE_CELLS)
    cw, cp = (g.ravel() for g in np.meshgrid(grid_w, grid_p, indexing="ij"))
    # half-widths widened for the rounding of the centres, of hw0 and of 2 pi: the cells cover [0, W] x [0, 2 pi]
    cells: _Cells = (
        cw,
        cp,
        np.full(cw.size, hw0 + 4.0 * EPS * (W + hw0)),
        np.full(cw.size, np.pi / _PHASE_CELLS + 32.0 * EPS),
    )
    width = _MIN_WIDTH * max(1.0, W)
    cache: dict[float, int] = {}
    m0_all: list[Ball] = []
    m1_all: list[Ball] = []
    p_all: list[NDArray[np.float64]] = []
    left: list[_Cells] = []
    spent = 0
    while cells[0].size:
        cw, cp, hw, hp = cells
        uw, inv = np.unique(cw, return_inverse=True)
        new = [w for w in uw.tolist() if w not in cache]
        if new:
            spent += len(new)
            if spent > max_points:
                raise CertificationError(
                    f"cascade margin: more than max_points = {max_points} evaluations of the loop (raise max_points)"
                )
            m0_new, et_new = loop.enclose(np.array(new))
            m1_new = et_new - m0_new
            base = len(cache)
            cache.update((w, base + k) for k, w in enumerate(new))
            m0_all.append(m0_new)
            m1_all.append(m1_new)
            p_all.append(loop.phase_lipschitz(m1_new))
            if len(m0_all) > 1:
                m0_all, m1_all = [_stack(m0_all)], [_stack(m1_all)]
                p_all = [np.concatenate(p_all)]
        rows = np.array([cache[w] for w in uw.tolist()])[inv]
        lower, error = loop.exclusion(cp, m0_all[0][rows], m1_all[0][rows])
        lip_p = p_all[0][rows]
        slack = (hw * loop.alpha[1] + hp * lip_p) * UP
        open_ = lower <= slack
        done = open_ & ((slack <= _RESOLVE * error) | ((hw <= width) & (hp <= width)))
        left.append(_select(cells, done))
        if sum(c[0].size for c in left) > _MAX_OPEN:
            raise CertificationError(
                f"cascade margin: more than {_MAX_OPEN} cells near w in [{cw[done].min():.6g}, {cw[done].max():.6g}] "
                "stay undecided (the kernels' error or a tangency); a finer kernel_grid may help"
            )
        split = open_ & ~done
        cells = _halves(_select(cells, split), (hw * loop.alpha[1] >= hp * lip_p)[split])
    return tuple(np.concatenate([c[k] for c in left]) for k in range(4))  # type: ignore[return-value]


def _stack(balls: list[Ball]) -> Ball:
    """The balls concatenated along the first axis."""
    return Ball(np.concatenate([b.mid for b in balls]), np.concatenate([b.rad for b in balls]))


def _groups(cells: _Cells) -> list[NDArray[np.intp]]:
    """The cells in groups of touching cells (closed rectangles, phases wrapped), as index arrays."""
    cw, cp, hw, hp = cells
    pairs = []
    for start in range(0, cw.size, _BLOCK):  # the touching pairs, a block of rows at a time
        rows = slice(start, start + _BLOCK)
        touch = (np.abs(cw[rows, None] - cw[None]) <= (hw[rows, None] + hw[None]) * (1 + 1e-9)) & (
            np.abs(_wrap(cp[rows, None] - cp[None])) <= (hp[rows, None] + hp[None]) * (1 + 1e-9)
        )
        i, j = np.nonzero(touch)
        pairs.append((i + start, j))
    first, second = np.concatenate([p[0] for p in pairs]), np.concatenate([p[1] for p in pairs])
    label = np.arange(cw.size)
    while True:  # each cell takes the smallest label of its neighbours until none changes
        nxt = label.copy()
        np.minimum.at(nxt, first, label[second])
        if np.array_equal(nxt, label):
            break
        label = nxt
    return [np.flatnonzero(label == k) for k in np.unique(label)]


def _face_signs(
    loop: _CascadeLoop, pts: NDArray[np.float64], coef: NDArray[np.float64], sign: float, slack: float
) -> bool:
    """True if ``sign * coef . (Re f, Im f) > slack`` is proven at every point for the exact loop's ``f``.

    ``f`` lies within ``|f_h - f| <= prod(sigma_i + e) - prod sigma_i`` (Ipsen and Rehman) of the
    determinant ``f_h`` of the enclosure's midpoint ``A_h``, enclosed by cofactors, with ``sigma_i`` the
    proven upper bounds of ``A_h``'s singular values and ``e`` the radius's Frobenius norm plus ``eps``.
    """
    m0, et = loop.enclose(pts[:, 0])
    a = m0 + loop.unit(pts[:, 1])[:, None, None] * (et - m0)
    f = det(exact(a.mid))
    _, sig = singular_bounds(a.mid)
    e = (frobenius(a.rad) + loop.eps) * UP
    sym = np.zeros((sig.shape[0], loop.m + 1))  # elementary symmetric functions of the sigma_i
    sym[:, 0] = 1.0
    for i in range(loop.m):
        sym[:, 1:] = sym[:, 1:] + sig[:, i : i + 1] * sym[:, :-1]
    grown = sum(e**k * sym[:, loop.m - k] for k in range(1, loop.m + 1)) * UP
    err = (f.rad + grown) * UP
    g = coef[0] * f.mid.real + coef[1] * f.mid.imag
    rounding = 2.0 * EPS * (abs(coef[0]) * np.abs(f.mid.real) + abs(coef[1]) * np.abs(f.mid.imag)) + TINY
    bound = (slack + float(np.hypot(*coef)) * UP * err + rounding) * UP
    return bool(np.all(sign * g > bound))


def _miranda_box(loop: _CascadeLoop, cells: _Cells) -> tuple[NDArray[np.float64], float, float] | None:
    """A box ``[w0 +- a] x [phi0 +- b]`` about a group of cells holding a zero of the exact loop, or None.

    Newton steps on the grid loop from the group's centre give ``x0`` and ``J``; with ``C = J^{-1}``
    the map ``g = C (Re f, Im f)`` of the exact loop is checked to have ``g_1 < 0`` on the face
    ``w = w0 - a``, ``> 0`` on ``w0 + a``, ``g_2 < 0`` on ``phi = phi0 - b``, ``> 0`` on ``phi0 + b``,
    so the box holds a zero (Poincare-Miranda). Each face is checked at the midpoints of pieces of
    length ``d``, each point standing for its piece through the Lipschitz bound of ``f`` along the
    face (``L_phi`` or ``L_w`` of the module notes): ``|g_k| > ||C_k|| (|f - f_h| + L d / 2)``.
    Boxes 1.5, 2, 3 and 4 times the group's extent about ``x0`` are tried.
    """
    cw, cp, hw, hp = cells
    deg = np.arange(loop.m + 1, dtype=float)
    x = np.array([0.5 * (np.min(cw - hw) + np.max(cw + hw)), cp[0] + np.mean(_wrap(cp - cp[0]))])
    for _ in range(_NEWTON_STEPS):
        c, dc = loop.jet(np.array([x[0]]))
        z = np.exp(1j * x[1] * deg)
        f = complex(np.sum(c[0] * z))
        fw, fp = complex(np.sum(dc[0] * z)), complex(np.sum(1j * deg * c[0] * z))
        J = np.array([[fw.real, fp.real], [fw.imag, fp.imag]])
        if not np.all(np.isfinite(J)) or abs(np.linalg.det(J)) == 0.0:
            return None
        x = x - np.linalg.solve(J, [f.real, f.imag])
    C = np.linalg.inv(J)
    # g = 0 must mean f = 0: C (the doubles used, whatever their rounding) invertible, decided exactly by
    # its determinant in rationals, and not so ill-conditioned that its faces' slack is meaningless
    (c00, c01), (c10, c11) = (tuple(Fraction(float(v)) for v in row) for row in C)
    if c00 * c11 - c01 * c10 == 0 or not np.linalg.cond(C) < 1e8:
        return None
    lip_w, lip_p = loop.lipschitz
    extent = float(max(np.max(np.abs(cw - x[0]) + hw), np.max(np.abs(_wrap(cp - x[1])) + hp)))
    for factor in (1.5, 2.0, 3.0, 4.0):
        a = factor * extent
        if a >= x[0] or a >= 0.5 * np.pi:
            return None
        ok = True
        for k, lip in ((0, lip_p), (1, lip_w)):  # faces across w (g_1, along phi), across phi (g_2, along w)
            d = 0.25 * a / (float(np.hypot(*C[k])) * lip)
            n = math.ceil(2 * a / d)
            if n > _MAX_FACE:
                return None
            along = -a + (np.arange(n) + 0.5) * (2 * a / n)
            # a piece's farthest point is a / n from its midpoint, plus the rounding of the points' coordinates
            reach = a / n + 4.0 * EPS * (float(np.max(np.abs(x))) + a)
            slack = float(np.hypot(*C[k])) * lip * reach * (1.0 + 1e-12)
            for sign in (-1.0, 1.0):
                pts = np.column_stack([x[0] + sign * a + 0 * along, x[1] + along])
                if k == 1:
                    pts = np.column_stack([x[0] + along, x[1] + sign * a + 0 * along])
                ok = ok and _face_signs(loop, pts, C[k], sign, slack)
        if ok:
            return x, a, a
    return None


def _delay_range(w: float, phi: float, hw: float, hp: float) -> tuple[float, float]:
    """Smallest and largest first delay ``theta / w``, ``theta = -phi mod 2 pi``, on ``[w +- hw] x [phi +- hp]``
    (``w - hw > 0`` for the largest; 0 and ``2 pi / (w - hw)`` where the cell meets ``theta = 0``), widened for
    the rounding of ``theta`` (``2 pi`` as a float, the reduction) and of the quotients."""
    theta, hp = float(np.mod(-phi, 2 * np.pi)), float(hp) + 8.0 * EPS * (abs(float(phi)) + 4.0 * np.pi)
    lo_w, hi_w = float(w - hw) * (1.0 - 2.0 * EPS), float(w + hw) * (1.0 + 2.0 * EPS)
    if theta - hp <= 0.0 or theta + hp >= 2 * np.pi * (1.0 - 4.0 * EPS):
        return 0.0, (2 * np.pi / lo_w * (1.0 + 4.0 * EPS) if lo_w > 0 else math.inf)
    lower = (theta - hp) * (1.0 - 2.0 * EPS) / hi_w * (1.0 - 2.0 * EPS)
    return lower, ((theta + hp) * (1.0 + 2.0 * EPS) / lo_w * (1.0 + 2.0 * EPS) if lo_w > 0 else math.inf)


def _wrap(d: Any) -> Any:
    """Phase differences in ``[-pi, pi)``."""
    return np.mod(d + np.pi, 2 * np.pi) - np.pi


def _select(cells: _Cells, mask: Any) -> _Cells:
    """The cells picked by a boolean mask (or index array)."""
    cw, cp, hw, hp = cells
    return cw[mask], cp[mask], hw[mask], hp[mask]


def _halves(cells: _Cells, split_w: NDArray[np.bool_]) -> _Cells:
    """Each cell halved in ``w`` (where ``split_w``) or in ``phi``; the halves' half-widths ``h / 2 + EPS (|c| +
    h)`` cover the rounding of their centres ``c -+ h / 2``, so the two halves cover the cell."""
    cw, cp, hw, hp = cells
    sw, sp = np.where(split_w, 0.5, 0.0), np.where(split_w, 0.0, 0.5)
    return (
        np.concatenate([cw - sw * hw, cw + sw * hw]),
        np.concatenate([cp - sp * hp, cp + sp * hp]),
        np.tile(np.where(split_w, 0.5 * hw + EPS * (np.abs(cw) + hw), hw), 2),
        np.tile(np.where(split_w, hp, 0.5 * hp + EPS * (np.abs(cp) + hp)), 2),
    )


@one_blas_thread(scipy_linalg=True)  # many products of small matrices: competing BLAS threads only cost time
def cascade_delay_margin(
    controller: NPlusMBackstepping,
    bound: KernelErrorBound | None = None,
    *,
    max_frequency: float = 1000.0,
    max_points: int = 200_000,
) -> NPlusMMargin:
    """Proven bracket of the delay margin of the full-state backstepping law, leftward speeds that differ.

    The loop through the target's ``G`` (:meth:`~nrobust.hyperbolic.nplusm.NPlusMBackstepping.cascade_loop_matrices`)
    with the grid kernels, searched on the whole axis with the proven error ``eps`` of
    :func:`~nrobust.hyperbolic.nplusm.kernel_error_bound` carried (module notes): every crossing of
    the law with *exact* kernels lies in the cells the search leaves, one in each proven box, and
    the margin in ``margin_bracket``.

    Parameters
    ----------
    controller : NPlusMBackstepping
        Its kernel grid sets ``eps`` (first order in the step: the bracket's width halves when the
        grid's step does).
    bound : KernelErrorBound, optional
        :func:`~nrobust.hyperbolic.nplusm.kernel_error_bound` of ``controller.kernels`` (computed
        when None).
    max_frequency : float, optional
        Largest frequency bound ``W`` (``> 0``) the search accepts: ``W`` grows like ``1 / gap`` of
        the principal part and with ``||G||``, and each evaluation of the loop costs one Filon
        sweep over the kernel grid.
    max_points : int, optional
        Work bound on evaluations of the loop on the axis.

    Returns
    -------
    NPlusMMargin
        ``margin`` and the crossings (one per proven box) are the grid kernels' loop's; ``margin_bracket`` the proven
        ``[lower, upper]`` of the exact law's margin (``(inf, inf)``: no crossing at any frequency);
        ``frequency_bound`` the proven ``W`` on the axis; ``nominal_unstable`` 0 (``det(E T) = det V``);
        ``certified`` True.

    Raises
    ------
    ParameterError
        Not an ``NPlusMBackstepping``, a bound of other kernels, or all leftward speeds equal (then
        :func:`~nrobust.hyperbolic.nplusm.backstepping_exact_margin` is kernel-free).
    CertificationError
        ``gamma_0`` not separated from 1, the kernels' error too large for the frequency bound or to
        prove a crossing in a box (a finer kernel grid helps), a tangency, or the work bound.
    ImportError
        python-flint is missing (the kernels' error bound).
    """
    if not isinstance(controller, NPlusMBackstepping):
        raise ParameterError("controller", "an NPlusMBackstepping", type(controller).__name__)
    sys = controller.system
    if np.all(sys.mu == sys.mu[0]):
        raise ParameterError(
            "controller", "leftward speeds mu that differ (equal speeds: backstepping_exact_margin)", sys.mu.tolist()
        )
    max_frequency = positive("max_frequency", max_frequency)
    max_points = positive_int("max_points", max_points)
    if bound is None:
        bound = kernel_error_bound(controller.kernels)
    if not isinstance(bound, KernelErrorBound) or bound.kernel_grid != controller.kernels.grid.size:
        raise ParameterError("bound", "kernel_error_bound(controller.kernels)", type(bound).__name__)
    lower, gamma, _ = principal_gamma_bounds(sys, -sys.r)
    if lower >= 1.0 + 1e-12:
        if not _gamma_above_one(sys):
            raise CertificationError(
                f"cascade margin: gamma_0 of the delayed principal part, sampled at {lower:.12g}, is not proven "
                "above 1 in ball arithmetic (the margin would be 0)"
            )
        return NPlusMMargin(0.0, None, (), lower, 0.0, True, None, _SCOPE, (0.0, 0.0))
    if gamma >= 1.0 - 1e-12:
        raise CertificationError(
            f"cascade margin: gamma_0 of the delayed principal part in [{lower:.12g}, {gamma:.12g}] is not "
            "separated from 1 (the certified bound of its spectral radius must be below 1)"
        )
    loop = _CascadeLoop(controller, bound)
    W = _frequency_bound(loop, max_frequency)
    max_delay = NPlusMCharacteristic(sys, -sys.r).max_delay
    cells = _search(loop, W, 2.0 * np.pi / (GRID_PER_PERIOD * max_delay), max_points)
    if not cells[0].size:
        return NPlusMMargin(np.inf, None, (), gamma, W, True, 0, _SCOPE, (np.inf, np.inf))
    lower = min(_delay_range(*cell)[0] for cell in zip(*cells))
    found, upper = [], math.inf
    for group in _groups(cells):
        box = _miranda_box(loop, _select(cells, group))
        if box is None:
            k = group[0]
            raise CertificationError(
                f"cascade margin: a crossing near w = {cells[0][k]:.6g} is neither excluded nor proven (the "
                f"kernels' error eps = {loop.eps:.3g}, a tangency or a double crossing); a finer kernel_grid may help"
            )
        x, a, b = box
        found.append((float(x[0]), float(np.mod(-x[1], 2 * np.pi)) / float(x[0])))
        upper = min(upper, _delay_range(float(x[0]), float(x[1]), a, b)[1])
    best = min(found, key=lambda c: c[1])
    bracket = (lower, upper)
    omegas = _omega_range(cells, upper)
    crossings = tuple(sorted(found))
    return NPlusMMargin(best[1], best[0], crossings, gamma, W, True, 0, _SCOPE, bracket, omega_bracket=omegas)


def _omega_range(cells: _Cells, upper: float) -> tuple[float, float]:
    """A proven enclosure of the exact law's crossing frequency at its margin, the margin at most ``upper``.

    Every crossing on ``[0, W]`` lies in a cell of the search, and the margin's crossing in one whose delays
    reach down to ``upper`` at least: the hull of those cells' frequencies, rounded outwards.
    """
    cw, _, hw, _ = cells
    near = np.array([_delay_range(*cell)[0] <= upper for cell in zip(*cells)])
    lo = float(np.min(cw[near] - hw[near])) * (1.0 - 2.0 * EPS)
    hi = float(np.max(cw[near] + hw[near])) * (1.0 + 2.0 * EPS)
    return max(lo, 0.0), hi


def backstepping_delay_margin(
    controller: NPlusMBackstepping,
    omega_max: float | None = None,
    *,
    points: int = 800,
    max_points: int = 200_000,
    route: str = "integral",
    rigorous: bool = False,
) -> NPlusMMargin:
    """Delay margin of the full-state controller ``U(t - delta)``.

    With ``rigorous=True`` the margin of the law with *exact* kernels: kernel-free when all
    leftward speeds are equal (as without ``omega_max``), else :func:`cascade_delay_margin`, its
    ``margin_bracket`` proven for the PDE (the grid kernels' error bounded); ``omega_max``,
    ``points`` and ``route`` are not used then.

    Without ``omega_max`` (all leftward speeds equal): the certified margin of the law with
    exact kernels, kernel-free (:func:`~nrobust.hyperbolic.nplusm.backstepping_exact_margin`;
    ``max_points`` its work bound, at least 2 000 000 used); the grid kernels are not used.

    With ``omega_max``: the loop of the grid kernels, through the feedback integral
    (``route="integral"``, :meth:`NPlusMBackstepping.loop_matrices`) or through the target's
    ``G`` (``route="cascade"``, :meth:`NPlusMBackstepping.cascade_loop_matrices`: the same loop
    for the exact kernels, module notes), not certified (``certified=False``). ``gamma_0 >= 1``
    (full cancellation of reflections, :meth:`NPlusMBackstepping.gamma_0`; for ``m > 1`` with
    more than four principal delays a sampled lower bound): margin 0, arbitrarily small delays
    destabilise. Otherwise a root of ``det(M_0 + e^{-delta s} M_1)`` sits at ``s = i w`` iff
    ``z = e^{-i w delta}`` is an eigenvalue of the pencil ``M_0 v = -z M_1 v`` on the unit
    circle; the eigenvalues inside the disk are counted on a grid of ``(0, omega_max]``, each
    change located by bisection, and the delays are ``(-arg z mod 2 pi) / w``. The delay-free
    loop is finite-time stable by construction (``nominal_unstable`` is None: not counted).
    Not certified: a crossing above ``omega_max``, or two crossings of opposite directions
    between grid points, would be missed, and the scan does not carry the error of the grid's
    ``J`` or ``G`` (for ``G`` a proven bound of its effect on the loop is
    :func:`~nrobust.hyperbolic.nplusm.kernel_error_bound`).

    Parameters
    ----------
    controller : NPlusMBackstepping
    omega_max : float, optional
        Upper end ``> 0`` of the scan of the grid kernels' loop (reported as
        ``frequency_bound``); None (default) for the certified kernel-free margin.
    points : int, optional
        Grid points (``>= 16``) of the scan.
    max_points : int, optional
        Work bound on evaluations of the loop: ``points`` plus 48 bisection steps per
        crossing, checked before each grid is evaluated.
    route : {"integral", "cascade"}, optional
        The grid kernels' loop scanned with ``omega_max`` (:data:`BACKSTEPPING_ROUTES`): through
        ``J`` (default) or through ``G``, whose error moves the loop by the same bound at
        every frequency; ``scope`` names it.
    rigorous : bool, optional
        Prove the margin of the law with exact kernels (above); ``max_points`` is then the work
        bound of :func:`cascade_delay_margin`.

    Raises
    ------
    ParameterError
        ``omega_max`` None for a plant whose leftward speeds differ (its loop needs the
        kernels: give ``omega_max`` or ``rigorous=True``), or an unknown ``route``.
    CertificationError
        ``rigorous=True`` and the bracket cannot be proven (:func:`cascade_delay_margin`: a finer
        kernel grid helps where the kernels' error is the cause).
    """
    if not isinstance(controller, NPlusMBackstepping):
        raise ParameterError("controller", "an NPlusMBackstepping", type(controller).__name__)
    if route not in BACKSTEPPING_ROUTES:
        raise ParameterError("route", f"one of {BACKSTEPPING_ROUTES}", route)
    if not isinstance(rigorous, bool):
        raise ParameterError("rigorous", "True or False", rigorous)
    if rigorous and np.any(controller.system.mu != controller.system.mu[0]):
        return cascade_delay_margin(controller, max_points=max_points)
    if rigorous:
        omega_max = None
    if omega_max is None:
        if np.any(controller.system.mu != controller.system.mu[0]):
            raise ParameterError(
                "omega_max",
                "a positive frequency: leftward speeds that differ make the loop depend on the kernels "
                "(no kernel-free certified margin)",
                None,
            )
        return backstepping_exact_margin(controller.system, max_points=max(max_points, 2_000_000))
    omega_max = positive("omega_max", omega_max)
    points = positive_int("points", points, minimum=16)
    max_points = positive_int("max_points", max_points)
    bisections = 48
    if points > max_points:
        raise ParameterError("max_points", f">= points = {points}", max_points)
    scope = KERNEL_SCOPE if route == "integral" else CASCADE_SCOPE
    loop = controller.loop_matrices if route == "integral" else controller.cascade_loop_matrices
    gamma = controller.gamma_0()
    if gamma >= 1.0:
        return NPlusMMargin(0.0, None, (), gamma, 0.0, False, None, scope)
    found = pencil_crossings(loop, omega_max, points, bisections=bisections, max_points=max_points)
    if not found:
        return NPlusMMargin(np.inf, None, (), gamma, omega_max, False, None, scope)
    best = min(found, key=lambda p: p[1])
    return NPlusMMargin(best[1], best[0], tuple(found), gamma, omega_max, False, None, scope)
