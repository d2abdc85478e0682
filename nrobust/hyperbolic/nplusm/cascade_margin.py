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
(Weyl; ``|z - z_0| <= h_phi``): the derivative bound in ``phi`` is the cell's own. The exact loop
differs from the computed grid loop by at most ``eps + 3 r(w)`` in norm (``r`` the rounding of the
matrix exponentials and the Filon steps, ``EXPM_ROUNDING`` units per step as in
:mod:`~nrobust.hyperbolic.nplusm.characteristic`) and LAPACK's ``sigma_min`` by ``1e-13 ||A||``:
a cell whose lower bound is positive holds no zero. The others are halved in the direction of
the larger term, all cells of a round evaluated in one vectorised call (each distinct ``w`` once),
until the slack ``h_w alpha_1 + h_phi ||E T - M_0||`` is a quarter of that error: those cells
stay, the region where the kernels' error leaves the sign of ``f`` open.

**Existence.** The cells left fall in groups of touching cells. In each, Newton steps on the grid
loop give ``x_0`` and its Jacobian ``J`` in ``(w, phi)``; for ``g = J^{-1} (Re f, Im f)`` of the
exact loop the signs ``g_1 < 0`` at ``w = w_0 - a``, ``> 0`` at ``w_0 + a`` and ``g_2 < 0`` at
``phi = phi_0 - a``, ``> 0`` at ``phi_0 + a`` prove a zero in the box (Poincare-Miranda). They are
checked at the midpoints of short pieces of each face, with ``|f - f_h| <= prod(sigma_i + e) - prod
sigma_i`` for ``||A - A_h|| <= e``, ``sigma_i`` those of ``A_h`` (in the singular vectors' bases
``det(Sigma + E') = sum_S det E'[S, S] prod_{i not in S} sigma_i`` and ``|det E'[S, S]| <=
e^{|S|}``; Ipsen and Rehman, SIAM J. Matrix Anal. Appl. 30, 2008), and the Lipschitz bound ``L_w``
or ``L_phi`` along the face standing for the rest of each piece. A group without a proven zero is
refused.

**Frequency bound.** On the axis ``A = A_0 + Delta`` with the principal part ``A_0(w, z) = V -
(1 - z) sum_t R_t e^{-i w tau_t}`` (:meth:`~nrobust.hyperbolic.nplusm.NPlusMSystem.principal_terms`,
``K = -R``) and ``||A_0^{-1}|| <= kappa`` for every ``w`` and ``|z| <= 1``
(:func:`_principal_inverse`: ``rho(2 sum_t |V^{-1} R_t|) < 1`` proven, a Neumann series). The
rest: ``(1 - z) E [-R, I] (Phi - Phi_0) [Q; I]``, at most ``2 ||[-R, I]|| ||[Q; I]|| r(w)``
(:class:`~nrobust.margins.matrix.GaugeRemainder` on the axis, ``|E| = 1``), and ``z (E T - V)``.
Integrating by parts on the cells of the piecewise-linear ``H = Lambda-^{-1} G_h``
(``||C(i w)^{-1}|| <= 1 / (w / mu_max - ||Lambda-^{-1} D||)``), ``||E T_h - V|| <= ||V|| (e^{ell}
(||H(1)|| + TV(H)) + ||H(0)||) / (w / mu_max - ||Lambda-^{-1} D||)``, and the exact kernels add
``eps``. Beyond the ``W`` where ``kappa`` times the sum is below 1, ``A`` is invertible: ``f != 0``
on the axis. ``eps`` does not decay in ``w``, so ``kappa eps < 1`` is needed at least.

**The margin.** At ``delta = 0`` the loop is ``det(E T) = det V != 0`` (no root). The delayed
principal part is strongly stable (``gamma < 1``), so roots enter ``Re s >= 0`` only across the
imaginary axis at a finite frequency (Hale and Verduyn Lunel, neutral equations: the kernel
terms are distributed delays, which do not move the essential spectrum); the margin is the
smallest delay ``(-phi mod 2 pi) / w`` over the zeros ``(w, phi)`` of ``f``. Every zero lies in a
cell left by the search, so the margin is at least the smallest delay over those cells; one zero
lies in each proven box, so it is at most the largest delay over a box (the smallest such bound
over the boxes). The bracket's width is of the order of ``eps``: first order in the kernel grid's
step (halving with it, measured).

**Cost.** The exclusion needs no derivative of ``f`` beyond the uniform ``alpha_1`` and evaluates
the loop's matrices, vectorised, at about 300 to 3000 frequencies; only Newton's steps (eight jets of
13 evaluations) and the faces of the boxes (a few hundred points) come on top. Measured for the plants
of ``tests/test_nplusm_cascade_cert.py``: ``Sigma--_01 = 0.3`` (``W = 37``, no crossing) 0.5 to 0.8 s
of CPU on 21 to 81 kernel points, 40 s before on 21 (derivative bounds of ``det`` uniform in ``w``
and ``phi``, cells proven one Newton step at a time); the plant with a crossing 1.3 to 1.9 s.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._threads import one_blas_thread
from ..._validate import positive, positive_int
from ...errors import CertificationError, ParameterError
from ...margins.matrix import GaugeRemainder
from .characteristic import EPS, EXPM_ROUNDING, GRID_PER_PERIOD, NPlusMCharacteristic
from .kernel_error import KernelErrorBound, kernel_error_bound
from .kernels import BACKSTEPPING_ROUTES, CASCADE_SCOPE, KERNEL_SCOPE, NPlusMBackstepping, in_group_part
from .margin import NPlusMMargin, backstepping_exact_margin, pencil_crossings, principal_gamma_bounds
from .system import NPlusMSystem

__all__ = ["backstepping_delay_margin", "cascade_delay_margin"]

_SCOPE = (
    "full-state backstepping law with exact kernels on the PDE, leftward speeds that differ: loop through the "
    "target's G, the grid kernels' proven error (kernel_error_bound) carried by the search; margin_bracket proven, "
    "with the floating-point rounding of the matrix exponentials, determinants and singular values taken from "
    "error models (EXPM_ROUNDING), not enclosed in ball arithmetic"
)
# Cauchy's formula for the w-derivative of the grid loop (Newton steps only, no bound rests on it):
# points on a circle of radius _RING around s = i w.
_RING, _RING_POINTS = 1e-2, 12
# The search: phase cells of the first grid, Newton steps to a box's centre, the narrowest cell
# (relative to max(1, W)), the slack below which a cell is not split (relative to the error of
# sigma_min), and work bounds on the cells left open and the points of a box's face.
_PHASE_CELLS, _NEWTON_STEPS, _MIN_WIDTH, _RESOLVE, _MAX_OPEN, _MAX_FACE = 16, 8, 1e-11, 0.25, 10_000, 20_000
_BLOCK = 512  # rows of the touching test at a time (memory: _BLOCK times the cells left)
# Cells of the (w, phi) rectangle: centres and half-widths (four arrays of one size).
_Cells = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]


def _norm2(x: NDArray[Any]) -> NDArray[np.float64]:
    """Spectral norms of a stack of matrices, rounded upwards (relative ``1e-12``)."""
    return np.asarray(np.linalg.norm(x, 2, axis=(-2, -1)) * (1.0 + 1e-12), dtype=float)


class _CascadeLoop:
    """The grid kernels' loop on the axis, its coefficients in ``z`` and the bounds of the module notes."""

    def __init__(self, controller: NPlusMBackstepping, bound: KernelErrorBound) -> None:
        sys = controller.system
        self.controller, self.system, self.m = controller, sys, sys.m
        self.eps = float(bound.transition_error)
        mu_min, mu_max = float(sys.mu.min()), float(sys.mu.max())
        self.mu_min = mu_min
        inv = 1.0 / sys.signed_speeds
        c_full = inv[:, None] * sys.sigma
        beta = float(np.linalg.eigvalsh(0.5 * (c_full + c_full.T))[-1]) + 1e-12 * (1.0 + float(np.abs(c_full).sum()))
        self.left = float(_norm2(np.hstack([-sys.r, np.eye(sys.m)])))
        self.right = float(_norm2(np.vstack([sys.q, np.eye(sys.m)])))
        self.a0 = self.left * math.exp(beta) * self.right * (1.0 + 1e-12)
        self.q = (1.0 / mu_min + float(np.max(np.abs(inv)))) * (1.0 + 1e-12)
        v_block, _ = sys.principal_terms()
        self.v_norm = float(_norm2(v_block))
        a_mat = in_group_part(sys) / sys.mu[:, None]
        sym = 0.5 * (a_mat + a_mat.T)
        ell = max(0.0, max(sym[i, i] + np.abs(sym[i]).sum() - abs(sym[i, i]) for i in range(sys.m)))
        ell = ell * (1 + 4 * EPS) + 4 * EPS  # as kernel_error_bound's logarithmic norm
        mask = sys.mu[None, :] > sys.mu[:, None]
        H = controller.kernels.G * mask[:, :, None] / sys.mu[:, None, None]  # Lambda-^{-1} G_h(x_k)
        x = controller.kernels.grid
        h = float(x[1] - x[0])
        fro = np.sqrt(np.sum(H**2, axis=(0, 1)))
        ends = np.maximum(fro[:-1], fro[1:]) * np.exp(ell * x[1:])
        g_int = float(np.sum(ends) * h) * (1.0 + 1e-12)
        self.t0 = (self.v_norm * g_int + self.eps) * (1.0 + 1e-12)
        tv = float(np.sum(np.sqrt(np.sum(np.diff(H, axis=2) ** 2, axis=(0, 1)))))
        self.decay = self.v_norm * (math.exp(ell) * (fro[-1] + tv) + fro[0]) * (1.0 + 1e-12)
        self.decay_shift = float(_norm2(a_mat))
        self.mu_max = mu_max
        self.cells = x.size - 1
        self.roots = np.exp(2j * np.pi * np.arange(self.m + 1) / (self.m + 1))
        # bounds of the exact loop's A = (1 - z) M_0 + z E T and its w-derivatives on the axis, |z| = 1
        self.alpha = [
            2.0 * self.a0 * self.q**k + self.t0 / mu_min**k + (self.v_norm if k == 0 else 0.0) for k in range(2)
        ]
        # sup |f_w| and sup |f_phi| of the exact loop on the axis: |d det A| <= m ||dA|| ||A||^{m-1}, and
        # dA/dphi = i z (E T - M_0)
        grow = self.m * self.alpha[0] ** (self.m - 1) * (1.0 + 1e-12)
        self.lipschitz = (grow * self.alpha[1], grow * (self.a0 + self.v_norm + self.t0))

    # ------------------------------------------------------------------ the grid kernels' loop
    def matrices(self, s: NDArray[Any]) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        """``M_0(s)`` and ``E T_h(s)`` for an array of ``s``."""
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

    # ------------------------------------------------------------------ bounds
    def matrix_rounding(self, w: NDArray[np.float64]) -> NDArray[np.float64]:
        """Rounding of the computed ``M_0(i w)`` and ``E T_h(i w)`` (matrix exponentials, ``cells`` Filon steps)."""
        grow = 1.0 + self.q * (np.abs(np.asarray(w, dtype=float)) + 1.0)
        return np.asarray(EXPM_ROUNDING * EPS * (self.cells + 8) * grow * self.alpha[0], dtype=float)

    def exclusion(
        self, w: NDArray[np.float64], phi: NDArray[np.float64], m0: NDArray[np.complex128], et: NDArray[np.complex128]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """``(l, p, e)`` at the points ``(w, phi)`` from the computed ``M_0(i w)``, ``E T_h(i w)``: ``l <=
        sigma_min`` of the exact loop's ``A(w, e^{i phi})``, ``p >= ||E T(i w) - M_0(i w)||``
        and ``e`` the error allowed for in ``l`` (module notes, *Search*)."""
        m1 = et - m0
        a = m0 + np.exp(1j * phi)[:, None, None] * m1
        sig = np.linalg.svd(a, compute_uv=False)[:, -1]
        rnd = self.matrix_rounding(w)
        error = 1e-12 * sig + 1e-13 * _norm2(a) + self.eps + 3.0 * rnd
        return (
            np.asarray(sig - error, dtype=float),
            np.asarray(_norm2(m1) + self.eps + 2.0 * rnd, dtype=float),
            np.asarray(error, dtype=float),
        )


def _principal_inverse(system: NPlusMSystem) -> float:
    """``kappa >= ||A_0(w, z)^{-1}||`` for every ``w`` and ``|z| <= 1`` (module notes, *Frequency bound*).

    ``A_0 = V (I - X)``, ``X = V^{-1} sum_t (1 - z) R_t e^{-i w tau_t}``, ``|X| <= T = 2 sum_t |V^{-1} R_t|``
    entrywise. A vector ``x > 0`` with ``T x < x`` proves ``rho(T) < 1`` (Collatz-Wielandt), so
    ``|(I - X)^{-1}| <= sum_k T^k = (I - T)^{-1}`` entrywise and ``kappa = ||(I - T)^{-1} |V^{-1}|||_F``.
    Ball arithmetic (python-flint) from ``V`` and the ``R_t`` as doubles.

    Raises
    ------
    CertificationError
        No such ``x`` (``rho(T) >= 1`` or too close to 1 to prove).
    """
    import flint

    v_block, point = system.principal_terms()
    m = system.m
    v_inv = flint.arb_mat(v_block.tolist()).inv()
    t = flint.arb_mat(m, m)
    for _, rq, _ in point:
        prod = v_inv * flint.arb_mat(rq.tolist())
        for i in range(m):
            for j in range(m):
                t[i, j] += 2 * abs(prod[i, j])
    upper = np.array([[float(t[i, j].upper()) for j in range(m)] for i in range(m)])
    vals, vecs = np.linalg.eig(upper)
    x = np.abs(vecs[:, int(np.argmax(np.abs(vals)))].real) + 1e-9
    tx = t * flint.arb_mat([[float(v)] for v in x])
    if not all(float(tx[i, 0].upper()) < x[i] for i in range(m)):
        raise CertificationError(
            "cascade margin: the principal part's bound rho(2 sum_t |V^{-1} R_t|) is not proven below 1, so "
            "no uniform bound of its inverse on the axis (the frequency bound needs one)"
        )
    n_mat = (flint.arb_mat([[float(i == j) for j in range(m)] for i in range(m)]) - t).inv() * flint.arb_mat(
        [[abs(v_inv[i, j]).upper() for j in range(m)] for i in range(m)]
    )
    fro = sum((n_mat[i, j] ** 2 for i in range(m) for j in range(m)), flint.arb(0)).sqrt()
    return float(fro.upper())


def _frequency_bound(loop: _CascadeLoop, max_frequency: float) -> float:
    """``W``: the exact loop's ``A(w, z)`` is invertible for ``w >= W`` and every ``|z| = 1`` (module notes)."""
    sys = loop.system
    kappa = _principal_inverse(sys)
    inv = 1.0 / sys.signed_speeds
    remainder = GaugeRemainder(inv[:, None] * sys.sigma, inv)
    scale = 2.0 * loop.left * loop.right * (1.0 + 1e-12)

    def total(w: float) -> float:
        gap = w / loop.mu_max - loop.decay_shift
        kernel = loop.decay / gap if gap > 0.0 else math.inf
        return kappa * (scale * float(remainder(w)) + kernel + loop.eps + 1e-12 * loop.alpha[0]) * (1.0 + 1e-12)

    if not kappa * loop.eps < 1.0:
        raise CertificationError(
            f"cascade margin: the kernels' error (eps = {loop.eps:.3g}) exceeds the principal part's room "
            f"1 / kappa = {1.0 / kappa:.3g} at every frequency; a finer kernel_grid would help (eps is first order "
            "in its step)"
        )
    hi = max(2.0 * remainder.floor, 2.0 * loop.mu_max * loop.decay_shift, 1.0)
    while not total(hi) < 1.0:
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
        if total(mid) < 1.0:
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
    cells: _Cells = (cw, cp, np.full(cw.size, hw0), np.full(cw.size, np.pi / _PHASE_CELLS))
    width = _MIN_WIDTH * max(1.0, W)
    cache: dict[float, int] = {}
    m0_all: list[NDArray[np.complex128]] = []
    et_all: list[NDArray[np.complex128]] = []
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
            m0_new, et_new = loop.matrices(1j * np.array(new))
            base = len(cache)
            cache.update((w, base + k) for k, w in enumerate(new))
            m0_all.extend(m0_new)
            et_all.extend(et_new)
        rows = np.array([cache[w] for w in uw.tolist()])[inv]
        lower, lip_p, error = loop.exclusion(cw, cp, np.asarray(m0_all)[rows], np.asarray(et_all)[rows])
        slack = hw * loop.alpha[1] + hp * lip_p
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
    """True if ``sign * coef . (Re f, Im f) > slack + ||coef|| |f - f_h|`` at every point (``f`` exact)."""
    m0, et = loop.matrices(1j * pts[:, 0])
    z = np.exp(1j * pts[:, 1])
    a = m0 + z[:, None, None] * (et - m0)
    f = np.linalg.det(a)
    sig = np.linalg.svd(a, compute_uv=False) * (1.0 + 1e-12) + 1e-13 * _norm2(a)[:, None]
    e = loop.eps + 3.0 * loop.matrix_rounding(pts[:, 0])
    grown = np.prod(sig + e[:, None], axis=1)
    err = grown - np.prod(sig, axis=1) + 1e-13 * grown  # Ipsen and Rehman's bound, and det's rounding
    g = coef[0] * f.real + coef[1] * f.imag
    return bool(np.all(sign * g > slack + float(np.hypot(*coef)) * (1.0 + 1e-12) * err))


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
    (``w - hw > 0`` for the largest; 0 and ``2 pi / (w - hw)`` where the cell meets ``theta = 0``), widened by
    ``1e-12`` (relative) for the rounding of ``theta`` and of the quotients."""
    theta, hp = float(np.mod(-phi, 2 * np.pi)), float(hp)
    lo_w, hi_w = float(w - hw), float(w + hw)
    if theta - hp <= 1e-12 or theta + hp >= 2 * np.pi - 1e-12:
        return 0.0, (2 * np.pi / lo_w * (1.0 + 1e-12) if lo_w > 0 else math.inf)
    lower = (theta - hp) / hi_w * (1.0 - 1e-12)
    return lower, ((theta + hp) / lo_w * (1.0 + 1e-12) if lo_w > 0 else math.inf)


def _wrap(d: Any) -> Any:
    """Phase differences in ``[-pi, pi)``."""
    return np.mod(d + np.pi, 2 * np.pi) - np.pi


def _select(cells: _Cells, mask: Any) -> _Cells:
    """The cells picked by a boolean mask (or index array)."""
    cw, cp, hw, hp = cells
    return cw[mask], cp[mask], hw[mask], hp[mask]


def _halves(cells: _Cells, split_w: NDArray[np.bool_]) -> _Cells:
    """Each cell halved in ``w`` (where ``split_w``) or in ``phi``."""
    cw, cp, hw, hp = cells
    sw, sp = np.where(split_w, 0.5, 0.0), np.where(split_w, 0.0, 0.5)
    return (
        np.concatenate([cw - sw * hw, cw + sw * hw]),
        np.concatenate([cp - sp * hp, cp + sp * hp]),
        np.tile(np.where(split_w, 0.5 * hw, hw), 2),
        np.tile(np.where(split_w, hp, 0.5 * hp), 2),
    )


@one_blas_thread()  # many products of small matrices: competing BLAS threads only cost time
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
    return NPlusMMargin(best[1], best[0], tuple(sorted(found)), gamma, W, True, 0, _SCOPE, (lower, upper))


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
