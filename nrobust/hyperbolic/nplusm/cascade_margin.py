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
most its larger end). The determinant is multilinear in the columns and a column's norm is at
most the matrix's (Hadamard), so with ``alpha_k`` bounding ``||d^k A / dw^k||``:
``|f| <= alpha_0^m``, ``|f_w| <= m alpha_1 alpha_0^{m-1}``, ``|f_ww| <= m alpha_2 alpha_0^{m-1} +
m (m - 1) alpha_1^2 alpha_0^{m-2}`` for the exact loop, and each coefficient ``c_d`` of ``z^d`` obeys
the same bounds (Cauchy's estimate on ``|z| = 1``).

**The kernels' error at a point.** With ``a = ||A_h(w, z)|| <= 2 ||M_0|| + ||E T_h||``,
``|f - f_h| <= (a + eps)^m - a^m``; the ``w``-derivative moves by at most ``m ((a_1 + eps / mu_min)
(a + eps)^{m-1} - a_1 a^{m-1})`` and the ``phi``-derivative (``dA/dphi = i z (E T - M_0)``) by
``m ((a_p + eps) (a + eps)^{m-1} - a_p a^{m-1})``, ``a_p = ||M_0|| + ||E T_h||``. These enter the
search of :func:`~nrobust.margins.matrix.circle_crossings` as the error of the coefficients, so
that its exclusions and its Newton-Kantorovich discs hold for the exact loop.

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
smallest delay ``(-phi mod 2 pi) / w`` over the zeros ``(w, phi)`` of ``f``. Each zero is proven
in a disc of radius ``r`` about the grid loop's zero (Newton-Kantorovich with the error above),
so its delay lies in ``[(theta - r) / (w + r), (theta + r) / (w - r)]``; the bracket of the margin
is the minimum over the zeros of both ends. The bracket's width is of the order of ``eps``:
first order in the kernel grid's step.

**Cost.** The search's cells are set by the derivative bounds above (Hadamard, uniform in ``w``:
10 to 100 times the loop's size), and each evaluation of the jet is 13 Filon sweeps over the
kernel grid: measured 40 s CPU (21 points) and 138 s (41 points) for ``Sigma--_01 = 0.3`` of
``tests/test_nplusm_cascade_cert.py`` (``W = 37``, no crossing). Sharper bounds (per cell, not
uniform) and a second-order kernel error are the next steps.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._validate import positive, positive_int
from ...errors import CertificationError, ParameterError
from ...margins.matrix import GaugeRemainder, circle_crossings
from .characteristic import EPS, EXPM_ROUNDING, GRID_PER_PERIOD, NPlusMCharacteristic
from .kernel_error import KernelErrorBound, kernel_error_bound
from .kernels import NPlusMBackstepping, in_group_part
from .margin import NPlusMMargin, _principal_gamma
from .system import NPlusMSystem

__all__ = ["cascade_delay_margin"]

_SCOPE = (
    "full-state backstepping law with exact kernels on the PDE, leftward speeds that differ: loop through the "
    "target's G, the grid kernels' proven error (kernel_error_bound) carried by the search; margin_bracket proven"
)
# Cauchy's formula for the w-derivative: points on a circle of radius _RING around s = i w, and
# the radius _OUTER of the circle on which the loop is bounded for the truncation error.
_RING, _RING_POINTS, _OUTER = 1e-2, 12, 1.0


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
            2.0 * self.a0 * self.q**k + self.t0 / mu_min**k + (self.v_norm if k == 0 else 0.0) for k in range(3)
        ]

    # ------------------------------------------------------------------ the grid kernels' loop
    def matrices(self, s: NDArray[np.complex128]) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
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
    def bounds(self) -> NDArray[np.float64]:
        """``sup |c_d|, sup |c_d'|, sup |c_d''|`` of the exact loop on the axis (module notes)."""
        m, (a0, a1, a2) = self.m, self.alpha
        b = [a0**m, m * a1 * a0 ** (m - 1), m * a2 * a0 ** (m - 1) + m * (m - 1) * a1**2 * a0 ** max(m - 2, 0)]
        return np.array([[v * (1.0 + 1e-12)] * (m + 1) for v in b])

    def _outer_bound(self) -> float:
        """``sup |f|`` (exact and grid loops) on the discs ``|s - i w| <= _OUTER``: the rows' factors grow
        by ``e^{_OUTER q}`` at most, those of ``E T`` by ``e^{_OUTER / mu_min}``."""
        a = 2.0 * self.a0 * math.exp(_OUTER * self.q) + self.v_norm + self.t0 * math.exp(_OUTER / self.mu_min)
        return float(a**self.m) * (1.0 + 1e-12)

    def level(self, w: NDArray[np.float64], dscale: float) -> NDArray[np.float64]:
        """Error of each ``c_d(w)`` (and, over ``dscale``, of the Jacobian): kernels, Cauchy's formula, rounding."""
        w = np.asarray(w, dtype=float)
        m, eps = self.m, self.eps
        m0, et = self.matrices(np.asarray(1j * w, dtype=np.complex128))
        n0, ne = _norm2(m0), _norm2(et)
        a = 2.0 * n0 + ne
        a1 = self.alpha[1]
        a_p = n0 + ne
        df = (a + eps) ** m - a**m
        dw = m * ((a1 + eps / self.mu_min) * (a + eps) ** (m - 1) - a1 * a ** (m - 1))
        dp = m * ((a_p + eps) * (a + eps) ** (m - 1) - a_p * a ** (m - 1))
        ratio = (_RING / _OUTER) ** _RING_POINTS
        cauchy = self._outer_bound() * ratio / (1.0 - ratio) / _OUTER
        rounding = EXPM_ROUNDING * EPS * (self.cells + 8) * (1.0 + self.q * (np.abs(w) + 1.0)) * self.alpha[0] ** m
        return np.asarray(np.maximum(df, (np.hypot(dw, dp) + cauchy) / dscale) * (1.0 + 1e-9) + rounding, dtype=float)


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


def _delay_bracket(
    loop: _CascadeLoop, x: NDArray[np.float64], ev_bounds: NDArray, dscale: float
) -> tuple[float, float, float]:
    """``(delay, lower, upper)`` of the exact loop's zero next to the grid loop's zero ``x = (w, phi)``.

    Newton-Kantorovich at ``x``: with ``J`` the grid loop's Jacobian, ``e_J`` its error and ``S`` the
    exact loop's second-derivative bound, the exact zero lies within the smallest ``r`` with
    ``kappa = ||J^{-1}|| (r S + e_J) <= 1/2`` and ``||J^{-1}|| (|f| + err) <= (1 - kappa) r``.
    """
    b = np.asarray(ev_bounds)
    deg = np.arange(b.shape[1], dtype=float)
    s_ww, s_wp, s_pp = float(b[2].sum()), float((deg * b[1]).sum()), float((deg**2 * b[0]).sum())
    second = float(np.sqrt(s_ww**2 + 2.0 * s_wp**2 + s_pp**2)) * (1.0 + 1e-12)
    c, dc = loop.jet(np.array([x[0]]))
    z = np.exp(1j * x[1] * deg)
    f = complex(np.sum(c[0] * z))
    fw, fp = complex(np.sum(dc[0] * z)), complex(np.sum(1j * deg * c[0] * z))
    J = np.array([[fw.real, fp.real], [fw.imag, fp.imag]])
    err = float(loop.level(np.array([x[0]]), dscale)[0]) * deg.size + 4e-16 * float(np.abs(c).sum())
    jinv = float(np.linalg.norm(np.linalg.inv(J), 2)) * (1.0 + 1e-12)
    e_j = 1e-12 * float(np.linalg.norm(J, 2)) + err * dscale
    step = jinv * (abs(f) + err)
    r = step
    for _ in range(60):  # r = step / (1 - kappa(r)): the fixed point from below
        kappa = jinv * (r * second + e_j)
        if kappa >= 0.5:
            raise CertificationError(
                f"cascade margin: the crossing near w = {x[0]:.6g} is not isolated within the kernels' error "
                f"(eps = {loop.eps:.3g}); a finer kernel_grid would help"
            )
        r_new = step / (1.0 - kappa)
        if r_new <= r * (1.0 + 1e-12):
            break
        r = r_new
    r = r * (1.0 + 1e-6)
    kappa = jinv * (r * second + e_j)
    if not (kappa <= 0.5 and step <= (1.0 - kappa) * r):
        raise CertificationError(f"cascade margin: no proven disc about the crossing near w = {x[0]:.6g}")
    w, theta = float(x[0]), float(np.mod(-x[1], 2 * np.pi))
    if r >= w:
        raise CertificationError(f"cascade margin: the crossing near w = {w:.3g} is within {r:.3g} of w = 0")
    lower = 0.0 if theta - r <= 0.0 or theta + r >= 2 * np.pi else (theta - r) / (w + r)
    upper = (theta + r) / (w - r)
    return theta / w, math.nextafter(lower, -math.inf) if lower > 0 else 0.0, math.nextafter(upper, math.inf)


def cascade_delay_margin(
    controller: NPlusMBackstepping,
    bound: KernelErrorBound | None = None,
    *,
    max_frequency: float = 1000.0,
    max_points: int = 200_000,
) -> NPlusMMargin:
    """Proven bracket of the delay margin of the full-state backstepping law, leftward speeds that differ.

    The loop through the target's ``G`` (:meth:`~nrobust.hyperbolic.nplusm.NPlusMBackstepping.cascade_loop_matrices`)
    with the grid kernels, searched on the whole axis by :func:`~nrobust.margins.matrix.circle_crossings`
    with the proven error ``eps`` of :func:`~nrobust.hyperbolic.nplusm.kernel_error_bound` carried
    (module notes): every crossing of the law with *exact* kernels is enclosed in a proven disc, and
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
        ``margin`` and the crossings are the grid kernels' loop's; ``margin_bracket`` the proven
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
        isolate a crossing (a finer kernel grid helps), a tangency, or the work bound.
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
    lower, gamma, _ = _principal_gamma(sys, -sys.r)
    if lower >= 1.0 + 1e-12:
        return NPlusMMargin(0.0, None, (), lower, 0.0, True, None, _SCOPE, (0.0, 0.0))
    if gamma >= 1.0 - 1e-12:
        raise CertificationError(
            f"cascade margin: gamma_0 of the delayed principal part in [{lower:.12g}, {gamma:.12g}] is not "
            "separated from 1 (the certified bound of its spectral radius must be below 1)"
        )
    loop = _CascadeLoop(controller, bound)
    W = _frequency_bound(loop, max_frequency)
    bounds = loop.bounds()
    dscale = 1.0 + float(bounds[1].sum()) / float(bounds[0].sum())  # as circle_crossings' evaluator
    max_delay = NPlusMCharacteristic(sys, -sys.r).max_delay
    step = 2.0 * np.pi / (GRID_PER_PERIOD * max_delay)
    zeros = circle_crossings(
        loop.coefs, loop.jet, W, bounds, lambda w: loop.level(w, dscale), step=step, max_points=max_points
    )
    if not zeros:
        return NPlusMMargin(np.inf, None, (), gamma, W, True, 0, _SCOPE, (np.inf, np.inf))
    found, lows, highs = [], [], []
    for w, phi in zeros:
        delay, lo, hi = _delay_bracket(loop, np.array([w, phi]), bounds, dscale)
        found.append((w, delay))
        lows.append(lo)
        highs.append(hi)
    best = min(found, key=lambda c: c[1])
    bracket = (min(lows), min(highs))
    return NPlusMMargin(best[1], best[0], tuple(found), gamma, W, True, 0, _SCOPE, bracket)
