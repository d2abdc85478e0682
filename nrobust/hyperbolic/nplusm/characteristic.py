"""The closed loop of an ``n + m`` system as a certified characteristic function.

**Certified counts.** :class:`NPlusMCharacteristic` is a
:class:`~nrobust.qpmatrix.CharacteristicFunction` for any ``m``: row ``j`` of the loop
matrix is ``l_j(s)^T G_j(s) W`` with ``G_j(s) = e^{-s/mu_j} Phi(s) = exp(C - s P_j)``,
``C = Lambda^{-1} Sigma``, ``P_j = Lambda^{-1} + I/mu_j`` diagonal,
``l_j = (-(R_j + K_j e^{-delta s}), e_j)`` and ``W = [Q; I]``. Every derivative of
``exp(C - s P)`` obeys ``||G^{(k)}(s)|| <= ||P||^k e^{beta(Re s)}`` (Dyson's expansion),
``beta(x) = lambda_max(Herm(C) - x P)`` the logarithmic 2-norm, convex in ``x``; Jacobi's
formula and Hadamard's inequality turn the row bounds into the bounds of ``|F'|`` and
``|F''|`` on a segment that the step rule of :mod:`nrobust.roots.winding` needs.

**Certified delay margin** (``m = 1``). Split ``C = C_d + C_o`` (``C_d`` the couplings
inside groups of equal round-trip rate ``p_i``); the gauge ``Y = (I + N/s) Z`` with
``[P, N] = C_o`` and Gronwall's lemma bound ``||exp(C - s P) - exp(C_d - s P)||`` by a
non-increasing ``r(|s|) = O(1/|s|)`` on ``Re s >= 0``
(:meth:`NPlusMCharacteristic.coupling_remainder`), which gives a proven frequency bound
``W`` beyond which ``|A| - |B e^{-delta s}| > 0`` (:meth:`NPlusMCharacteristic.frequency_bound`).
On ``[0, W]`` the crossings of ``|A(i w)| = |B(i w)|`` are found completely from a
Lipschitz bound of ``|A| - |B|`` and a bound of ``|g''|``, ``g = |A|^2 - |B|^2``
(:meth:`NPlusMCharacteristic.crossing_frequencies`); ``docs/theory.md``, "Beyond 2x2",
has the derivation.

**Root-free far field** (any ``m``). In compound form (Cauchy-Binet, :func:`compound_loop`)
``F(s) = sum_d e^{-d delta s} a_d^T exp(D - s P) b`` with rates ``P >= 0``; the gauge
bound holds on ``Re s >= x`` for any real ``x`` with ``beta_d`` replaced by
``beta(x) = lambda_max(Herm D_d - x P)`` (the bound is ``e^{beta}`` times a function of
``|s|``, and Gronwall's lemma needs no sign of ``beta``). So ``|F - F_0| <= sum_d
e^{-d delta x} ||a_d|| ||b|| r_x(|s|)``, ``F_0`` the principal part, an exponential sum whose
term of delay 0 is ``det exp(C_vv)``; where that term dominates the others on ``Re s >= x``,
``F`` has no root with ``Re s >= x`` beyond the radius where the remainder falls below the
gap (:meth:`NPlusMCharacteristic.far_field_radius`), as for a scalar quasi-polynomial.
:meth:`NPlusMCharacteristic.far_field_holds` computes it in floating point;
:meth:`NPlusMCharacteristic.ball_far_field_holds` proves it in ball arithmetic (the rates
``p_S`` as exact rationals, so the groups and ``p_S - p_T`` are exact; ``D_m(C)``, the minors
and ``det exp(D_gg)`` in balls; ``||N||``, ``||H||`` and ``lambda_max(Herm D_gg)`` by proven
upper bounds), with ``beta(x) = max_g (lambda_max(Herm D_gg) - x p_g)``: ``Herm D_d - x P``
is block diagonal over the groups of equal rate.

**Proven in ball arithmetic** (any ``m``). :class:`BallNPlusM` encloses ``F`` and its
derivatives over complex balls with FLINT's proven matrix exponential and determinant, so
``count_roots``, ``find_roots`` and ``spectral_abscissa`` with ``rigorous=True`` prove their
results for the PDE's characteristic function itself. Neither the core's
``spectral_abscissa(F, rigorous=True)`` nor :meth:`NPlusMCharacteristic.proven_abscissa` needs a
region: the far field proven by :meth:`NPlusMCharacteristic.ball_far_field_holds` puts every root
of ``Re s >= x`` in a rectangle that the rigorous root search then proves (a loop whose rightmost
roots lie on its chains is refused by the core, which then asks for a region).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import replace
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._validate import nonnegative, positive_int
from ...balls import BallFunction, working_precision
from ...difference import DifferenceOperator
from ...errors import CertificationError, ParameterError
from ...margins.matrix import GaugeRemainder, compound_generator, compound_generator_of, compound_minors
from ...qpmatrix import FirstDerivative, QuasiPolynomialMatrix
from ...quasipoly import QuasiPolynomial
from ...roots import SpectralAbscissa, find_roots, spectral_abscissa
from .system import NPlusMSystem

__all__ = [
    "BallNPlusM",
    "NPlusMCharacteristic",
    "arb_max",
    "compound_loop",
    "spectral_norm_bound",
    "symmetric_top_bound",
]

#: Rounding scale of ``F(s)`` relative to ``||l|| ||r|| e^{beta} (1 + ||C|| + |s| ||P||)``: the
#: error of a scaling-and-squaring matrix exponential grows with the norm of its argument.
EXPM_ROUNDING = 16.0
#: Frequency grid of the crossing searches: points per unit of w times the longest delay.
GRID_PER_PERIOD = 32
#: Machine epsilon of float64.
EPS = float(np.finfo(float).eps)


def compound_loop(system: NPlusMSystem, k: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """``(D_m(C), p, a, b)``: ``det M(s; z) = sum_d z^d a_d^T exp(D_m(C) - s diag(p)) b`` (module notes of
    :mod:`nrobust.margins.matrix`), ``a`` of shape ``(m + 1, binom(n + m, m))``.

    ``p_S = sum_{u_i in S} 1/lam_i + sum_{v_j not in S} 1/mu_j >= 0``: the row scaling
    ``e^{-s sum 1/mu_j}`` of the loop matrix makes the compound transition bounded on ``Re s >= 0``.
    """
    n, m = system.n, system.m
    inv = 1.0 / system.signed_speeds
    subsets = list(itertools.combinations(range(n + m), m))
    p = np.array(
        [
            sum(inv[i] for i in S if i < n) + sum(1.0 / system.mu[j - n] for j in range(n, n + m) if j not in S)
            for S in subsets
        ]
    )
    for i in np.argsort(p):  # rates equal up to the order of a sum are made equal (groups of the gauge)
        p[np.abs(p - p[i]) <= 1e-13 * max(1.0, abs(p[i]))] = p[i]
    dc = compound_generator(inv[:, None] * system.sigma, m)
    b = compound_minors(np.vstack([system.q, np.eye(m)]), axis=0)
    roots = np.exp(2j * np.pi * np.arange(m + 1) / (m + 1))
    vals = np.array([compound_minors(np.hstack([-(system.r + z * k), np.eye(m)]), axis=1) for z in roots])
    return dc, p, np.fft.fft(vals, axis=0) / (m + 1), b


class NPlusMCharacteristic:
    """``F(s) = det(E(s) (Phi_v - (R + K e^{-delta s}) Phi_u))``: the closed loop of an ``n + m`` system.

    A :class:`~nrobust.qpmatrix.CharacteristicFunction`: ``count_roots``, ``find_roots``
    and ``spectral_abscissa`` (with no region needed: :meth:`far_field_radius`) certify its roots, and
    :meth:`proven_abscissa` proves the spectral abscissa in ball arithmetic, also without a region. Row ``j`` of the
    ``m x m`` matrix is ``l_j(s)^T G_j(s) W`` with ``G_j = e^{-s/mu_j} Phi(s) = exp(C - s P_j)``,
    ``P_j = Lambda^{-1} + I/mu_j`` diagonal, ``l_j = (-(R_j + K_j e^{-delta s}), e_j)`` and
    ``W = [Q; I]``; each derivative of ``G_j`` is bounded through the logarithmic norm
    (module notes), and the determinant through Jacobi's formula and Hadamard's
    inequality, as for :class:`~nrobust.qpmatrix.QuasiPolynomialMatrix`.

    Parameters
    ----------
    system : NPlusMSystem
    K : array_like, shape (m, n), optional
        The feedback gain (default: open loop).
    delta : float, optional
        The loop delay ``>= 0``, the same on every actuator.
    """

    def __init__(self, system: NPlusMSystem, K: ArrayLike | None = None, delta: float = 0.0) -> None:
        if not isinstance(system, NPlusMSystem):
            raise ParameterError("system", "an NPlusMSystem", type(system).__name__)
        self.system = system
        self.K = system.gain(K)
        self.delta = nonnegative("delta", delta)
        inv = 1.0 / system.signed_speeds
        self._c = inv[:, None] * system.sigma
        self._herm = 0.5 * (self._c + self._c.T)
        self._p = inv[None, :] + 1.0 / system.mu[:, None]  # row j: the diagonal of P_j
        self._w = np.vstack([system.q, np.eye(system.m)])
        self._w_norm = float(np.linalg.norm(self._w, 2))
        self._r_rows = np.linalg.norm(system.r, axis=1)
        self._k_rows = np.linalg.norm(self.K, axis=1)
        self._c_norm = float(np.linalg.norm(self._c, 2))
        self._ball_far: dict[int, _BallFarField] = {}

    # ------------------------------------------------------------------ rows of the loop matrix
    def _ell(self, j: int, s: NDArray[np.complex128]) -> tuple[NDArray, NDArray]:
        """``l_j(s)`` and ``l_j'(s)`` as arrays of shape ``(s.size, n + m)``."""
        sys = self.system
        ed = np.exp(-self.delta * s)[:, None]
        unit = np.zeros(sys.m)
        unit[j] = 1.0
        ell = np.concatenate([-(sys.r[j][None] + ed * self.K[j][None]), np.broadcast_to(unit, (s.size, sys.m))], axis=1)
        dell = np.concatenate([self.delta * ed * self.K[j][None], np.zeros((s.size, sys.m))], axis=1)
        return ell, dell

    def _matrices(self, s: NDArray[np.complex128], derivative: bool) -> tuple[NDArray, NDArray | None]:
        """The loop matrix (``(s.size, m, m)``) and, if asked, the matrix of its row derivatives."""
        from scipy.linalg import expm  # lazily: a slow import

        N = self.system.n + self.system.m
        rows, drows = [], []
        for j in range(self.system.m):
            a = self._c[None] - s[:, None, None] * np.diag(self._p[j])[None]
            ell, dell = self._ell(j, s)
            if not derivative:
                g = expm(a)
                rows.append(np.einsum("ni,nij,jk->nk", ell, g, self._w))
                continue
            big = np.zeros((s.size, 2 * N, 2 * N), dtype=complex)
            big[:, :N, :N] = a
            big[:, N:, N:] = a
            big[:, :N, N:] = -np.diag(self._p[j])  # exp([[A, -P], [0, A]]) = [[G, G'], [0, G]] (Van Loan)
            e = expm(big)
            g, dg = e[:, :N, :N], e[:, :N, N:]
            rows.append(np.einsum("ni,nij,jk->nk", ell, g, self._w))
            drows.append(np.einsum("ni,nij,jk->nk", dell, g, self._w) + np.einsum("ni,nij,jk->nk", ell, dg, self._w))
        return np.stack(rows, axis=1), (np.stack(drows, axis=1) if derivative else None)

    # ------------------------------------------------------------------ protocol
    def __call__(self, s: ArrayLike) -> NDArray[np.complex128]:
        s = np.asarray(s, dtype=complex)
        m, _ = self._matrices(s.reshape(-1), derivative=False)
        return np.asarray(np.linalg.det(m), dtype=complex).reshape(s.shape)

    def factors(self, s: ArrayLike) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        """``A(s)`` and ``B(s)`` of ``F = A + B e^{-delta s}`` (one actuator)."""
        sys = self.system
        if sys.m != 1:
            raise ParameterError("system", "one actuator (m = 1) for the factors A, B", sys.m)
        s = np.asarray(s, dtype=complex)
        g = sys.transition(s, shift=1.0 / float(sys.mu[0]))
        col = g @ self._w[:, 0]
        phi_u, phi_v = col[..., : sys.n], col[..., sys.n]
        return phi_v - phi_u @ sys.r[0], -(phi_u @ self.K[0])

    def deriv_at(self, s: ArrayLike) -> NDArray[np.complex128]:
        """``F'(s)``: Jacobi's formula on the rows, ``G_j'`` from Van Loan's block exponential."""
        s = np.asarray(s, dtype=complex)
        m, dm = self._matrices(s.reshape(-1), derivative=True)
        assert dm is not None
        out = np.zeros(m.shape[0], dtype=complex)
        for i in range(self.system.m):
            mi = m.copy()
            mi[:, i, :] = dm[:, i, :]
            out += np.linalg.det(mi)
        return out.reshape(s.shape)

    def _beta(self, j: int, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """``lambda_max(Herm(C) - x P_j)`` (plus rounding), the logarithmic norm of ``C - s P_j``."""
        xs, inv = np.unique(x, return_inverse=True)
        mats = self._herm[None] - xs[:, None, None] * np.diag(self._p[j])[None]
        top = np.linalg.eigvalsh(mats)[:, -1]
        slack = 1e-12 * (1.0 + self._c_norm + np.abs(xs) * float(np.abs(self._p[j]).max()))
        return (top + slack)[inv.reshape(x.shape)]

    def _row_bounds(self, a: ArrayLike, b: ArrayLike) -> tuple[NDArray, NDArray, NDArray, NDArray]:
        """Bounds of the row norms of the loop matrix and of its first two derivatives on segments,
        and the rounding scales ``l_j e^{beta_j} ||W||``: arrays of shape ``a.shape + (m,)``."""
        a = np.asarray(a, dtype=complex)
        b = np.asarray(b, dtype=complex)
        xmin = np.minimum(a.real, b.real)
        r0, r1, r2 = [], [], []
        for j in range(self.system.m):
            g = np.exp(np.maximum(self._beta(j, a.real), self._beta(j, b.real))) * self._w_norm  # convex in x
            ek = self._k_rows[j] * np.exp(-self.delta * xmin)
            ell = np.sqrt((self._r_rows[j] + ek) ** 2 + 1.0)
            p, d = float(np.abs(self._p[j]).max()), self.delta
            r0.append(ell * g)
            r1.append((d * ek + ell * p) * g)
            r2.append((d * d * ek + 2 * d * ek * p + ell * p * p) * g)
        slack = 1.0 + 1e-12
        return np.stack(r0, -1) * slack, np.stack(r1, -1) * slack, np.stack(r2, -1) * slack, np.stack(r0, -1)

    def deriv_bound(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        """``|F'| <= sum_i ||row_i'|| prod_{k != i} ||row_k||`` on each segment (module notes)."""
        r0, r1, _, _ = self._row_bounds(a, b)
        m = self.system.m
        return np.asarray(sum(r1[..., i] * _prod_except(r0, [i]) for i in range(m)), dtype=float)

    def second_deriv_bound(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        """Bound of ``|F''|`` on each segment.

        ``sum_i ||row_i''|| prod_{k != i} ||row_k|| + sum_{i != k} ||row_i'|| ||row_k'|| prod_{l != i, k} ||row_l||``.
        """
        r0, r1, r2, _ = self._row_bounds(a, b)
        m = self.system.m
        out = sum(r2[..., i] * _prod_except(r0, [i]) for i in range(m))
        for i in range(m):
            for k in range(m):
                if i != k:
                    out = out + r1[..., i] * r1[..., k] * _prod_except(r0, [i, k])
        return np.asarray(out, dtype=float)

    def derivative(self) -> FirstDerivative:
        """``F'`` with the bound of ``|F''|`` (the order-2 step rule)."""
        return FirstDerivative(self)

    def magnitude(self, s: ArrayLike) -> NDArray[np.float64]:
        """Rounding scale ``m 2^(m-1) prod_j 16 ||l_j|| e^{beta_j} ||W|| (1 + ||C|| + |s| ||P_j||)`` of ``F(s)``."""
        s = np.asarray(s, dtype=complex)
        _, _, _, scale = self._row_bounds(s, s)
        m = self.system.m
        growth = 1.0 + self._c_norm + np.abs(s)[..., None] * np.abs(self._p).max(axis=1)
        return np.asarray(m * 2.0 ** (m - 1) * np.prod(EXPM_ROUNDING * scale * growth, axis=-1), dtype=float)

    def principal_part(self) -> DifferenceOperator:
        """The principal part of ``F``: ``det(V - sum (R_ab + K_ab e^{-delta s}) e^{-tau_ab s})`` (module notes)."""
        v_block, point = self.system.principal_terms(self.K)
        m = self.system.m
        entries = []
        for j in range(m):
            row = []
            for k in range(m):
                coefs, delays = [[float(v_block[j, k])]], [0.0]
                for tau, rq, kq in point:
                    coefs += [[-float(rq[j, k])], [-float(kq[j, k])]]
                    delays += [tau, tau + self.delta]
                row.append(QuasiPolynomial(coefs, delays))
            entries.append(row)
        return QuasiPolynomialMatrix(entries).point_determinant().principal_part()

    @property
    def kind(self) -> str:
        """``"neutral"`` when the principal part has a delayed term (chains of roots), else ``"retarded"``."""
        return "neutral" if self.principal_part().coefs.size > 1 else "retarded"

    @property
    def is_real(self) -> bool:
        """True: real coefficients, roots in conjugate pairs."""
        return True

    @property
    def max_delay(self) -> float:
        """Longest round trip ``1/lam_i + 1/mu_j`` plus the loop delay."""
        return float(np.max(1.0 / self.system.lam) + np.max(1.0 / self.system.mu) + self.delta)

    def ball_function(self, prec: int = 53) -> BallNPlusM:
        """``F`` compiled for ball arithmetic (:class:`BallNPlusM`): what ``count_roots``,
        ``find_roots`` and ``spectral_abscissa`` (with a region) use with ``rigorous=True``
        (without a region: :meth:`proven_abscissa`)."""
        return BallNPlusM(self, prec)

    # ------------------------------------------------------------------ root-free far field
    @cached_property
    def _far(self) -> tuple[GaugeRemainder, NDArray, NDArray, NDArray, NDArray, NDArray]:
        """``(gauge, Herm D_d, p, sum_d weights, delays, |coefficients|)`` of the far-field bound.

        The compound form's gauge, the Hermitian part of its principal generator, its rates,
        ``||a_d|| ||b||`` (``1e-12`` relative slack) and the principal part ``F_0`` as an
        exponential sum (coefficients of equal delays added, delay 0 first).
        """
        from scipy.linalg import expm  # lazily: a slow import

        dc, p, a, b = compound_loop(self.system, self.K)
        gauge = GaugeRemainder(dc, p)
        weights = np.linalg.norm(a, axis=1) * float(np.linalg.norm(b)) * (1.0 + 1e-12)
        terms: dict[float, complex] = {0.0: 0j}
        for rate in np.unique(p):
            g = np.flatnonzero(p == rate)
            block = expm(gauge.c_d[np.ix_(g, g)]) @ b[g]
            for d in range(a.shape[0]):
                t = float(rate + d * self.delta)
                terms[t] = terms.get(t, 0j) + complex(a[d, g] @ block)
        delays = np.array(sorted(terms))
        coefs = np.abs(np.array([terms[t] for t in delays]))
        herm = 0.5 * (gauge.c_d + gauge.c_d.conj().T)
        return gauge, herm, p, weights, delays, coefs

    def _far_terms(self, x: float) -> tuple[float, float]:
        """``(level, scale)`` on ``Re s >= x``: ``|F_0| >= level`` there (the principal gap less
        rounding room, ``<= 0`` when the term of delay 0 does not dominate), and
        ``|F - F_0| <= scale g(|s|)``, ``g`` the gauge bound of ``Re s >= 0`` (``e^{beta_d}`` in it)."""
        gauge, herm, p, weights, delays, coefs = self._far
        with np.errstate(over="ignore"):
            shifted = coefs * np.exp(-delays * x)
            beta = float(np.linalg.eigvalsh(herm - x * np.diag(p))[-1])
            beta += 1e-12 * (1.0 + float(np.linalg.norm(herm, 2)) + abs(x) * float(np.max(p)))
            scale = float(np.sum(weights * np.exp(-np.arange(weights.size) * self.delta * x)))
            scale *= float(np.exp(beta - gauge.beta_d))
        gap = float(shifted[0] - np.sum(shifted[1:]))
        level = gap * (1.0 - 1e-9) - 1e-12 * float(np.sum(shifted))
        return (level, scale) if np.isfinite(level) and np.isfinite(scale) else (-np.inf, np.inf)

    def far_field_holds(self, x: float, radius: float) -> bool:
        """True if ``F`` is proven root-free on ``{Re s >= x, |s| >= radius}`` (floating point).

        On that set ``|F_0| >= level(x)`` and ``|F - F_0| <= scale(x) r(|s|)`` (module notes,
        "Root-free far field"); both bounds improve as ``x`` or ``radius`` grows.
        """
        level, scale = self._far_terms(float(x))
        return level > 0.0 and bool(scale * float(self._far[0](float(radius))) < level)

    def far_field_radius(self, x: float) -> float | None:
        """A radius ``R`` with no root of ``F`` in ``{Re s >= x, |s| >= R}`` (within ``1e-7`` of the
        smallest the bound gives), or None.

        ``x`` may be negative: the bound holds on any half-plane where the principal part's
        term of delay 0 dominates the others, i.e. for ``x`` above the first-term abscissa of
        :meth:`principal_part` (all ``x`` for a retarded loop). None when it does not
        dominate at ``x`` or the remainder stays above the gap up to ``|s| = 2^200``.
        """
        level, scale = self._far_terms(float(x))
        if not level > 0.0:
            return None
        try:
            return self._far[0].radius(scale, level)
        except CertificationError:
            return None

    def ball_far_field_holds(self, x: float, radius: float, prec: int = 53) -> bool:
        """True if ``F`` is proven root-free on ``{Re s >= x, |s| >= radius}`` in ball arithmetic.

        The bound of :meth:`far_field_holds` (module notes, "Root-free far field") with every
        term enclosed in balls for the stored parameters (each float an exact rational): exact
        rational rates and groups, ``D_m(C)``, the minors and the principal coefficients in
        balls (FLINT's proven ``arb_mat.exp``), and proven upper bounds of ``||N||``, ``||H||``
        and of the logarithmic norms (an ``L D L^T`` factorisation of ``t I - A`` with positive
        pivots in balls, or Gershgorin's bound). Needs python-flint.
        """
        prec = positive_int("prec", prec, minimum=16, maximum=4096)
        if prec not in self._ball_far:
            self._ball_far[prec] = _BallFarField(self, prec)
        return self._ball_far[prec].holds(float(x), float(radius))

    def proven_far_field_radius(self, x: float, prec: int = 53) -> float | None:
        """A radius ``R`` with ``{Re s >= x, |s| >= R}`` proven root-free (:meth:`ball_far_field_holds`), or None.

        From the floating-point :meth:`far_field_radius`, enlarged until the ball bound holds
        (up to ``2^20`` times it); None when neither finds one.
        """
        start = self.far_field_radius(x)
        if start is None:
            return None
        R = max(start, 1e-3)
        for factor in (1.0, 1.0 + 1e-6, 1.001, 1.01, 1.1):
            if self.ball_far_field_holds(x, R * factor, prec):
                return float(R * factor)
        for _ in range(20):
            R *= 2.0
            if self.ball_far_field_holds(x, R, prec):
                return float(R)
        return None

    def proven_abscissa(
        self, *, prec: int = 53, cluster_tol: float = 1e-6, max_evals: int = 5_000_000
    ) -> SpectralAbscissa:
        """The spectral abscissa of the PDE's loop, proven in ball arithmetic without a region.

        1. :func:`~nrobust.roots.spectral_abscissa` in floating point (the root-free far field
           of :meth:`far_field_radius`) locates the rightmost root, or the chain value ``c_D``.
        2. A half-plane ``Re s >= x`` is proven root-free outside ``|s| < R``
           (:meth:`proven_far_field_radius`, ball arithmetic): ``x`` a little left of the
           rightmost root (or a little right of the floating-point ``upper_bound`` when the
           value is ``c_D``, approached as ``Im s -> infinity``).
        3. :func:`~nrobust.roots.find_roots` with ``rigorous=True`` (:class:`BallNPlusM`) on
           ``[x, 1.01 R] x [-0.25, 1.01 R]`` (``F`` is real: its roots come in conjugate
           pairs) proves every root there in its box.

        So every root with ``Re s >= x`` is in a proven box: ``upper_bound`` (the largest
        right edge of the boxes, or ``x`` if none) bounds every root of ``F``, and
        ``value_bracket = (largest left edge of a box, upper_bound)`` holds the supremum of
        the real parts of the roots (None when no root lies right of ``x``: then ``value`` is
        ``c_D`` in floating point, not proven, and only ``upper_bound`` is). ``rigorous`` is
        True; ``chain_bracket`` is None (the principal part is computed in floating point).
        This is the proof that ``spectral_abscissa(F, rigorous=True)`` gives for a
        quasi-polynomial, for the PDE's characteristic function itself.

        Raises
        ------
        CertificationError
            No root-free far field is proven near the value (raise ``prec``), a step of the
            root search cannot be proven, or the proven search misses the floating-point
            rightmost root.
        ImportError
            Without python-flint.
        """
        prec = positive_int("prec", prec, minimum=16, maximum=4096)
        found = spectral_abscissa(self, cluster_tol=cluster_tol, max_evals=max_evals)
        chain = found.chain_value
        rooted = found.root is not None and not found.approached_at_infinity
        ub = found.upper_bound
        offers = [ub + 1e-3 * (1.0 + abs(ub)) * 2.0**k for k in range(16)]
        if rooted:  # left of the root first; a root left of C_D (a chain's) is not reached
            top = found.root.real  # type: ignore[union-attr]
            offers = [top - 0.25 * (1.0 + abs(top)) * 2.0**-k for k in range(16)] + offers
        for x in offers:
            R = self.proven_far_field_radius(x, prec)
            if R is not None:
                break
        else:
            raise CertificationError(
                f"proven_abscissa: no root-free far field proven in ball arithmetic near Re s = {ub:.12g}; raise prec"
            )
        half = 1.01 * max(R, 1.0)
        missed = rooted and found.root.real >= x  # type: ignore[union-attr]
        roots = None
        if x < half:  # else every root has |s| < R <= x: none with Re s >= x
            roots = find_roots(
                self, (x, half, -0.25, half), cluster_tol=cluster_tol, max_evals=max_evals, rigorous=True, prec=prec
            )
            if not roots.certified:
                raise CertificationError(f"proven_abscissa: the roots of {roots.region} are not all proven")
        if roots is None or not len(roots):
            if missed:
                raise CertificationError(
                    f"proven_abscissa: no root proven right of Re s = {x:.12g}, where floating point found {found.root}"
                )
            return replace(found, upper_bound=float(x), rigorous=True, root_box=None, value_bracket=None)
        right = float(roots.roots.real.max())
        near = np.flatnonzero(roots.roots.real >= right - 1e-12 * (1.0 + abs(right)))
        i = int(near[np.argmax(roots.roots.imag[near])])  # of a conjugate pair, the root with Im s >= 0
        root = complex(roots.roots[i])
        at_inf = bool(np.isfinite(chain) and chain > root.real + 1e-12 * (1.0 + abs(chain)))
        value = chain if at_inf else root.real
        upper = float(max(x, float(np.max(roots.boxes[:, 1]))))
        lo = float(np.max(roots.boxes[:, 0]))
        if not lo - 1e-9 * (1.0 + abs(lo)) <= value <= upper + 1e-9 * (1.0 + abs(upper)):
            raise CertificationError(
                f"proven_abscissa: the floating-point value {value!r} lies outside its proven bracket "
                f"[{lo!r}, {upper!r}]"
            )
        box = tuple(float(v) for v in roots.boxes[i])
        return replace(
            found,
            value=float(min(max(value, lo), upper)),
            root=root,
            approached_at_infinity=at_inf,
            upper_bound=upper,
            certified=found.certified and roots.certified,
            region=roots.region,
            rigorous=True,
            root_box=(box[0], box[1], box[2], box[3]),
            chain_bracket=None,
            value_bracket=(lo, upper),
        )

    # ------------------------------------------------------------------ one actuator: the axis
    def _one_actuator(self, what: str) -> None:
        if self.system.m != 1:
            raise ParameterError("system", f"one actuator (m = 1) for {what}", self.system.m)

    def gamma_0(self) -> float:
        """``(sum_a |R_a U_a Q_a| + sum_a |K_a U_a Q_a|) / |V|``: the principal part with a loop delay (``m = 1``)."""
        self._one_actuator("gamma_0")
        v_block, point = self.system.principal_terms(self.K)
        total = sum(abs(float(rq[0, 0])) + abs(float(kq[0, 0])) for _, rq, kq in point)
        return float(total / abs(float(v_block[0, 0])))

    def coupling_remainder(self, w: ArrayLike) -> NDArray[np.float64]:
        """``r(|s|)`` with ``||e^{-s/mu} Phi(s) - e^{-s/mu} Phi_0(s)|| <= r(|s|)`` on ``Re s >= 0`` (``m = 1``).

        ``Phi_0 = exp(C_d - s P)`` is the principal transition (``C_d`` the couplings inside
        groups of equal ``p_i``, ``P`` the diagonal of round-trip rates). With ``N`` solving
        ``[P, N] = C_o`` (the other couplings) and ``H = C N - N C_d``, the gauge
        ``Y = (I + N/s) Z`` turns ``Y' = (C - s P) Y`` into ``Z' = (C_d - s P + E/s) Z``,
        ``||E|| <= e = ||H|| / (1 - ||N||/|s|)``, and Gronwall's lemma with the logarithmic
        norm ``beta_d = lambda_max(Herm C_d)`` (``P >= 0`` for one actuator) gives, for
        ``|s| > ||N||``, with ``t = 1 / (1 - ||N||/|s|)``, ::

            r = ((1 + ||N||/|s|) t e e^{beta_d + e/|s|} + 2 ||N|| t e^{beta_d}) / |s|,

        non-increasing in ``|s|``; ``inf`` for ``|s| <= ||N||``. Includes ``1e-9`` relative slack.
        """
        self._one_actuator("the coupling remainder")
        return GaugeRemainder(self._c, self._p[0])(w)

    def _gauge(self) -> tuple[float, float, float]:
        """``(||N||, ||H||, beta_d)`` of :meth:`coupling_remainder` (``GaugeRemainder``)."""
        g = GaugeRemainder(self._c, self._p[0])
        return g.floor, g.h_norm, g.beta_d

    def frequency_bound(self) -> float:
        """Proven ``W`` (``m = 1``, ``gamma_0 < 1``): ``|A(i w)| != |B(i w)|`` for ``w >= W``, and
        ``F(s; delta) != 0`` for ``Re s >= 0``, ``|s| >= W``, every ``delta >= 0``.

        On ``Re s >= 0``, ``|A_0(s)| - |B_0(s) e^{-delta s}| >= gap = |V| (1 - gamma_0)``
        for the principal parts, and ``|A - A_0| + |B - B_0| <= (||l_A|| + ||K||) ||W|| r(|s|)``
        (:meth:`coupling_remainder`, ``l_A = (-R, 1)``, ``W = [Q; 1]``); ``W`` is the
        smallest radius (to ``1e-7``, rounded up) where the latter is below the gap less
        its rounding room.

        Raises
        ------
        CertificationError
            ``gamma_0 >= 1`` (no such bound), or the remainder stays above the gap up to ``2^200``.
        """
        self._one_actuator("the frequency bound")
        v_block, point = self.system.principal_terms(self.K)
        total = abs(float(v_block[0, 0])) + sum(abs(float(rq[0, 0])) + abs(float(kq[0, 0])) for _, rq, kq in point)
        gap = abs(float(v_block[0, 0])) * (1.0 - self.gamma_0())
        level = gap * (1.0 - 1e-9) - 1e-12 * total
        if level <= 0.0:
            raise CertificationError(f"frequency_bound: gamma_0 = {self.gamma_0():.12g} is not below 1 beyond rounding")
        scale = (
            float(np.hypot(np.linalg.norm(self.system.r, 2), 1.0)) + float(np.linalg.norm(self.K, 2))
        ) * self._w_norm
        return GaugeRemainder(self._c, self._p[0]).radius(scale, level)

    def axis_jet(self, w: ArrayLike) -> tuple[NDArray[np.complex128], ...]:
        """``A(i w)``, ``B(i w)``, ``A'(i w)``, ``B'(i w)`` (derivatives in ``s``) and the rounding
        levels of the first two and of the last two (``m = 1``; Van Loan's block exponential)."""
        from scipy.linalg import expm  # lazily: a slow import

        self._one_actuator("the factors")
        w = np.asarray(w, dtype=float).reshape(-1)
        N = self.system.n + 1
        a = self._c[None] - (1j * w)[:, None, None] * np.diag(self._p[0])[None]
        big = np.zeros((w.size, 2 * N, 2 * N), dtype=complex)
        big[:, :N, :N] = a
        big[:, N:, N:] = a
        big[:, :N, N:] = -np.diag(self._p[0])
        e = expm(big) if w.size else big
        col, dcol = e[:, :N, :N] @ self._w[:, 0], e[:, :N, N:] @ self._w[:, 0]
        ell_a = np.concatenate([-self.system.r[0], [1.0]])
        ell_b = np.concatenate([-self.K[0], [0.0]])
        A, B, dA, dB = col @ ell_a, col @ ell_b, dcol @ ell_a, dcol @ ell_b
        beta = float(np.linalg.eigvalsh(self._herm)[-1])
        p = float(np.abs(self._p[0]).max())
        level = EXPM_ROUNDING * EPS * np.exp(beta) * self._w_norm * (1.0 + self._c_norm + w * p)
        norms = np.array([np.linalg.norm(ell_a), np.linalg.norm(ell_b)])
        return A, B, dA, dB, level[None] * norms[:, None], level[None] * norms[:, None] * p

    def crossing_frequencies(self, W: float, *, max_points: int = 2_000_000) -> tuple[float, ...]:
        """Every ``w`` in ``(0, W]`` with ``|A(i w)| = |B(i w)|``, certified complete (``m = 1``).

        ``h = |A| - |B|`` has ``|h'| <= L = (||l_A|| + ||K||) ||W|| ||P|| e^{beta}`` on the axis
        (``beta = lambda_max(Herm C)``, Dyson's expansion), and ``g = |A|^2 - |B|^2`` has
        ``|g''| <= M_2 = 4 (||l_A||^2 + ||K||^2) ||W||^2 ||P||^2 e^{2 beta}``. A segment
        ``[a, b]`` holds no zero when ``|h(a)| + |h(b)| - err > L (b - a)``; otherwise, when
        ``|g'(c)| - err' > M_2 (b - a) / 2`` at its centre ``c``, ``g`` is monotone there and
        has one zero iff the certified end signs differ (located by Brent's method); else
        the segment is cut in eight, down to ``1e-12 max(1, W)``.

        Raises
        ------
        CertificationError
            A work bound hit, a zero at ``w = 0`` to rounding, or a segment narrowed to
            rounding without a decision (a double zero: a tangency).
        """
        from scipy.optimize import brentq  # lazily: a slow import

        self._one_actuator("the crossing search")
        W = float(W)
        max_points = positive_int("max_points", max_points)
        beta = float(np.linalg.eigvalsh(self._herm)[-1]) + 1e-12 * (1.0 + self._c_norm)
        p = float(np.abs(self._p[0]).max())
        na = float(np.hypot(np.linalg.norm(self.system.r, 2), 1.0))
        nk = float(np.linalg.norm(self.K, 2))
        lip = (na + nk) * self._w_norm * p * np.exp(beta) * (1.0 + 1e-12)
        m2 = 4.0 * (na**2 + nk**2) * self._w_norm**2 * p**2 * np.exp(2.0 * beta) * (1.0 + 1e-12)
        level = EXPM_ROUNDING * EPS * np.exp(beta) * self._w_norm  # rounding of A, B per unit ||l||
        spent = 0

        def h(x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
            nonlocal spent
            if spent + x.size > max_points:
                raise CertificationError(
                    f"crossing search: {x.size} more evaluations of A and B after {spent} exceed max_points="
                    f"{max_points} (raise max_points)"
                )
            spent += x.size
            A, B = self.factors(1j * x)
            return np.abs(A) - np.abs(B), level * (na + nk) * (1.0 + self._c_norm + x * p)

        step = 2.0 * np.pi / (GRID_PER_PERIOD * self.max_delay)
        count = int(np.ceil(W / step)) + 1
        if count > max_points:
            raise ParameterError("max_points", f">= {count} (the first grid up to W = {W:.6g})", max_points)
        x = np.linspace(0.0, W, max(count, 2))
        hx, ex = h(x)
        if abs(hx[0]) <= ex[0]:
            raise CertificationError("crossing search: |A(0)| = |B(0)| to rounding (a root at s = 0 for some delay)")
        segments = list(zip(x[:-1], x[1:], hx[:-1], hx[1:], ex[:-1], ex[1:]))
        brackets: list[tuple[float, float]] = []
        min_width = 1e-12 * max(1.0, W)
        while segments:
            open_ = [sg for sg in segments if abs(sg[2]) + abs(sg[3]) - sg[4] - sg[5] <= lip * (sg[1] - sg[0])]
            if not open_:
                break
            c = np.array([0.5 * (sg[0] + sg[1]) for sg in open_])
            A, B, dA, dB, e, de = self.axis_jet(c)
            spent += c.size
            dg = -2.0 * np.imag(np.conj(A) * dA) + 2.0 * np.imag(np.conj(B) * dB)
            derr = 2.0 * (np.abs(A) * de[0] + np.abs(dA) * e[0] + e[0] * de[0])
            derr += 2.0 * (np.abs(B) * de[1] + np.abs(dB) * e[1] + e[1] * de[1])
            cut = []
            for sg, dgk, derk in zip(open_, dg, derr):
                a, b, ha, hb, ea, eb = sg
                sure = abs(ha) > ea and abs(hb) > eb
                if sure and abs(dgk) - derk > m2 * 0.5 * (b - a):
                    if np.sign(ha) != np.sign(hb):
                        brackets.append((a, b))
                    continue
                if b - a <= min_width:
                    raise CertificationError(
                        f"crossing search: cannot decide |A(i w)| = |B(i w)| on [{a:.17g}, {b:.17g}] (a double zero "
                        "of |A|^2 - |B|^2 to rounding: a tangency); a slight change of the gain would decide it"
                    )
                cut.append(sg)
            if not cut:
                break
            pts = np.concatenate([np.linspace(a, b, 9)[1:-1] for a, b, *_ in cut])
            hp, ep = h(pts)
            segments = []
            for k, (a, b, ha, hb, ea, eb) in enumerate(cut):
                xs = np.r_[a, pts[7 * k : 7 * k + 7], b]
                hs = np.r_[ha, hp[7 * k : 7 * k + 7], hb]
                es = np.r_[ea, ep[7 * k : 7 * k + 7], eb]
                segments += list(zip(xs[:-1], xs[1:], hs[:-1], hs[1:], es[:-1], es[1:]))

        def h1(v: float) -> float:
            A, B, *_ = self.axis_jet(np.array([v]))
            return float(abs(A[0]) - abs(B[0]))

        return tuple(float(brentq(h1, a, b, xtol=1e-14, rtol=4 * EPS)) for a, b in sorted(brackets))


class BallNPlusM(BallFunction):
    """Enclosures of ``F`` of :class:`NPlusMCharacteristic` and of its derivatives over ``acb`` balls.

    What is enclosed is the characteristic function of the PDE itself with its parameters as
    stored (each float taken as an exact rational): ``C = Lambda^{-1} Sigma`` and the diagonal
    ``P_j = Lambda^{-1} + I/mu_j`` are formed in ball arithmetic (``1/lam_i`` is a ball, not a
    rounded double), ``G_j(s) = exp(C - s P_j)`` is FLINT's proven enclosure of the matrix
    exponential (``acb_mat.exp``, valid for every matrix of the ball matrix, so for every ``s``
    of the ball ``s``), the rows ``l_j(s)^T G_j(s) W`` are ball products and the determinant is
    ``acb_mat.det`` (an enclosure for every matrix in the ball). Nothing is computed in
    floating point (no ``scipy`` exponential, no logarithmic-norm bound).

    Derivatives are exact, not estimated: with ``T`` the block upper bidiagonal matrix of
    ``k + 1`` diagonal blocks ``C - s P_j`` and superdiagonal blocks ``-P_j``, block ``(0, b)`` of
    ``exp(T)`` is ``G_j^{(b)}(s) / b!`` (Najfeld and Havel, 1995; Mathias, 1996). Proof: ``T``
    is the matrix of multiplication by ``A + h E`` (``A = C - s P_j``, ``E = -P_j``) on
    ``C^N``-valued polynomials in ``h`` modulo ``h^{k+1}`` (the superdiagonal is the shift
    ``h``); that representation is an algebra homomorphism, so ``exp(T)`` represents
    ``exp(A + h E) = G_j(s + h)`` modulo ``h^{k+1}``, whose coefficients are the Taylor
    coefficients of ``G_j`` at ``s``. No commutation of ``P_j`` with ``C`` is needed, and
    ``exp(T)`` is again FLINT's proven enclosure. The Taylor coefficients of the rows follow by
    Cauchy products with those of ``l_j(s)`` (``e^{-delta s}`` in balls), and by
    multilinearity ``F^{(k)}(s) / k! = sum_{k_1 + ... + k_m = k} det(row_1^{[k_1]}; ...;
    row_m^{[k_m]})``, ``row^{[b]}`` the ``b``-th Taylor coefficient. Orders up to 4.

    Parameters
    ----------
    F : NPlusMCharacteristic
    prec : int, optional
        Working precision in bits.

    Notes
    -----
    Cost: one exponential of an ``(k + 1)(n + m)`` square ball matrix per actuator and ball
    (about 50 us for ``n + m = 2``, ``k = 0``). Over a wide ball, scaling and squaring widens
    the enclosure beyond the variation of ``F`` (the wrapping effect, a factor growing with
    ``|s| max P``); the contour proofs of :mod:`nrobust.roots.winding` intersect it with the
    mean-value form, which is tight on short pieces.
    """

    max_derivative = 4

    def __init__(self, F: NPlusMCharacteristic, prec: int = 53) -> None:
        if not isinstance(F, NPlusMCharacteristic):
            raise ParameterError("F", "an NPlusMCharacteristic", type(F).__name__)
        self.F = F
        self.prec = positive_int("prec", prec, minimum=16, maximum=4096)
        sys = F.system
        n, m = sys.n, sys.m
        self._size = n + m
        with working_precision(self.prec) as flint:
            self.flint = flint
            arb, acb = flint.arb, flint.acb
            inv = [1 / arb(float(v)) for v in sys.lam] + [-1 / arb(float(v)) for v in sys.mu]
            N = n + m
            self._c = [[inv[i] * arb(float(sys.sigma[i, k])) for k in range(N)] for i in range(N)]
            self._p = [[inv[i] + 1 / arb(float(mu)) for i in range(N)] for mu in sys.mu]
            w = np.vstack([sys.q, np.eye(m)])
            self._w = flint.acb_mat(N, m, [acb(float(v)) for v in w.ravel()])
            self._r = [[acb(float(v)) for v in row] for row in sys.r]
            self._k = [[acb(float(v)) for v in row] for row in F.K]
            self._delta = arb(float(F.delta))

    def _jet(self, j: int, s: Any, k: int) -> list[Any]:
        """``G_j^{(b)}(s) W / b!`` for ``b = 0..k`` (``acb_mat`` of shape ``(n + m, m)``), from one exponential."""
        flint = self.flint
        N, size = self._size, (k + 1) * self._size
        zero = flint.acb(0)
        entries = [zero] * (size * size)
        for blk in range(k + 1):
            for i in range(N):
                row = (blk * N + i) * size
                for c in range(N):
                    entries[row + blk * N + c] = self._c[i][c] - s * self._p[j][i] if c == i else self._c[i][c]
                if blk < k:
                    entries[row + (blk + 1) * N + i] = -self._p[j][i]
        e = flint.acb_mat(size, size, entries).exp()
        out = []
        for b in range(k + 1):
            g = flint.acb_mat(N, N, [e[i, b * N + c] for i in range(N) for c in range(N)])
            out.append(g * self._w)
        return out

    def factor_jet(self, s: Any, order: int = 0) -> list[tuple[Any, Any]]:
        """``[(A^(b)(s) / b!, B^(b)(s) / b!) for b = 0..order]``: the factors of ``F = A + B e^{-delta s}`` (``m = 1``).

        ``A = (-R, 1) G(s) W`` and ``B = (-K, 0) G(s) W`` with ``G = exp(C - s P)`` (the row of
        the loop matrix split by the loop delay, :meth:`NPlusMCharacteristic.factors`), enclosed
        over the ball ``s`` from the same proven exponential as ``F``; independent of ``delta``.

        Raises
        ------
        ParameterError
            ``m != 1``, or ``order`` outside ``0..4``.
        """
        sys = self.F.system
        if sys.m != 1:
            raise ParameterError("system", "one actuator (m = 1) for the factors A, B", sys.m)
        order = self._order(order)
        with working_precision(self.prec) as flint:
            ell_a = flint.acb_mat(1, sys.n + 1, [-r for r in self._r[0]] + [flint.acb(1)])
            ell_b = flint.acb_mat(1, sys.n + 1, [-k for k in self._k[0]] + [flint.acb(0)])
            return [((ell_a * g)[0, 0], (ell_b * g)[0, 0]) for g in self._jet(0, flint.acb(s), order)]

    def _rows(self, s: Any, k: int) -> list[list[Any]]:
        """``rows[j][b]``: the ``b``-th Taylor coefficient of row ``j`` (a list of ``m`` balls), ``b = 0..k``."""
        flint = self.flint
        n, m = self.F.system.n, self.F.system.m
        ed = (-self._delta * s).exp()
        rows = []
        for j in range(m):
            jet = self._jet(j, s, k)
            # Taylor coefficients of l_j(s): [-(R_j + K_j e^{-delta s}), e_j], then
            # [-K_j (-delta)^a / a! e^{-delta s}, 0] for a >= 1
            unit = [flint.acb(int(i == j)) for i in range(m)]
            ell = [[-(r + kk * ed) for r, kk in zip(self._r[j], self._k[j])] + unit]
            factor = ed
            for a in range(1, k + 1):
                factor = factor * (-self._delta) / a
                ell.append([-kk * factor for kk in self._k[j]] + [flint.acb(0)] * m)
            coefs = []
            for b in range(k + 1):
                acc = [flint.acb(0)] * m
                for a in range(b + 1):
                    prod = flint.acb_mat(1, n + m, ell[a]) * jet[b - a]
                    acc = [x + prod[0, c] for c, x in enumerate(acc)]
                coefs.append(acc)
            rows.append(coefs)
        return rows

    def _eval(self, s: Any, k: int) -> Any:
        flint = self.flint
        m = self.F.system.m
        rows = self._rows(s, k)
        out = flint.acb(0)
        for ks in itertools.product(range(k + 1), repeat=m):
            if sum(ks) == k:
                out += flint.acb_mat(m, m, [x for j, b in enumerate(ks) for x in rows[j][b]]).det()
        return out * math.factorial(k)


class _BallFarField:
    """The bound of :meth:`NPlusMCharacteristic.far_field_holds` in ball arithmetic (module notes).

    Every ingredient is an enclosure of the exact quantity for the stored parameters (each
    float an exact rational): the rates ``p_S`` are exact rationals (so the groups of equal
    rate, and ``p_S - p_T``, are exact), ``D_m(C)`` is assembled in balls from the exact
    sign pattern of :func:`~nrobust.margins.matrix.compound_generator`, the minors ``a_d``
    (inverse DFT over the ``(m + 1)``-th roots of unity, in ``acb``) and ``b`` are ball
    determinants, the principal coefficients use FLINT's proven ``arb_mat.exp``, and the
    norms and logarithmic norms are proven upper bounds (:func:`symmetric_top_bound`). The remainder
    is that of :class:`~nrobust.margins.matrix.GaugeRemainder` with ``e^{beta_d}`` replaced
    by ``e^{beta(x)}``, ``beta(x) = max_g (lambda_max(Herm D_gg) - x p_g)`` (``Herm D_d - x P``
    is block diagonal over the groups ``g``, ``P = p_g I`` on each).
    """

    def __init__(self, F: NPlusMCharacteristic, prec: int) -> None:
        sys = F.system
        n, m = sys.n, sys.m
        N = n + m
        self.prec = prec
        with working_precision(prec) as flint:
            self.flint = flint
            arb, acb, fmpq = flint.arb, flint.acb, flint.fmpq

            def exact(v: float) -> Any:
                return fmpq(*float(v).as_integer_ratio())

            subsets = list(itertools.combinations(range(N), m))
            size = len(subsets)
            inv_q = [1 / exact(v) for v in sys.lam] + [-1 / exact(v) for v in sys.mu]
            rates = [
                sum((inv_q[i] for i in S if i < n), fmpq(0))
                + sum((1 / exact(sys.mu[j - n]) for j in range(n, N) if j not in S), fmpq(0))
                for S in subsets
            ]
            c = [[arb(exact(sys.sigma[i, k]) * inv_q[i]) for k in range(N)] for i in range(N)]
            d = compound_generator_of(c, sys.sigma != 0, m, arb(0))
            groups: dict[Any, list[int]] = {}
            for S, rate in enumerate(rates):
                groups.setdefault(rate, []).append(S)
            self.groups = [(arb(rate), idx, rate) for rate, idx in groups.items()]
            same = [[rates[S] == rates[T] for T in range(size)] for S in range(size)]
            zero = arb(0)
            dd = flint.arb_mat([[d[S][T] if same[S][T] else zero for T in range(size)] for S in range(size)])
            nn = flint.arb_mat(
                [[zero if same[S][T] else d[S][T] / arb(rates[S] - rates[T]) for T in range(size)] for S in range(size)]
            )
            hh = flint.arb_mat(d) * nn - nn * dd
            self.n_norm = spectral_norm_bound(flint, nn)
            self.h_norm = spectral_norm_bound(flint, hh)
            self.tops = [
                symmetric_top_bound(flint, [[0.5 * (d[S][T] + d[T][S]) for T in idx] for S in idx])
                for _, idx, _ in self.groups
            ]
            w = np.vstack([sys.q, np.eye(m)])
            b = [flint.arb_mat([[arb(exact(w[i, j])) for j in range(m)] for i in S]).det() for S in subsets]
            self.delta = arb(exact(F.delta))
            lmat = [np.hstack([-sys.r, np.eye(m)]), np.hstack([-F.K, np.zeros((m, m))])]  # [-(R + z K), I]
            if F.delta == 0.0:  # one term: the minors of [-(R + K), I]
                terms = [
                    [
                        flint.arb_mat(
                            [[arb(exact(lmat[0][i, j])) + arb(exact(lmat[1][i, j])) for j in S] for i in range(m)]
                        ).det()
                        for S in subsets
                    ]
                ]
            else:
                roots = [acb(fmpq(2 * k, m + 1)).exp_pi_i() for k in range(m + 1)]
                vals = [
                    [
                        flint.acb_mat(
                            [[acb(exact(lmat[0][i, j])) + z * acb(exact(lmat[1][i, j])) for j in S] for i in range(m)]
                        ).det()
                        for S in subsets
                    ]
                    for z in roots
                ]
                terms = [
                    [
                        sum((vals[k][S] / roots[(k * dg) % (m + 1)] for k in range(m + 1)), acb(0)) / (m + 1)
                        for S in range(size)
                    ]
                    for dg in range(m + 1)
                ]
            b_norm = sum((abs(x) ** 2 for x in b), arb(0)).sqrt()
            self.weights = [sum((abs(x) ** 2 for x in t), arb(0)).sqrt() * b_norm for t in terms]
            coefs: dict[Any, Any] = {}  # exact delay p_g + d delta -> principal coefficient
            for _, idx, rate in self.groups:
                g = flint.arb_mat([[d[S][T] for T in idx] for S in idx]).exp()
                gb = [sum((g[r, k] * b[idx[k]] for k in range(len(idx))), arb(0)) for r in range(len(idx))]
                for dg, t in enumerate(terms):
                    key = rate + dg * exact(F.delta)
                    coefs[key] = coefs.get(key, acb(0)) + sum((t[S] * gb[r] for r, S in enumerate(idx)), acb(0))
            self.lead = abs(coefs.pop(fmpq(0), acb(0)))
            self.others = [(arb(key), abs(v)) for key, v in coefs.items()]

    def holds(self, x: float, radius: float) -> bool:
        """True if ``|F_0| > |F - F_0|`` is proven on ``{Re s >= x, |s| >= radius}``."""
        if not (np.isfinite(x) and np.isfinite(radius) and radius > 0.0):
            return False
        with working_precision(self.prec) as flint:
            arb = flint.arb
            X, R = arb(float(x)), arb(float(radius))
            gap = self.lead - sum((a * (-tau * X).exp() for tau, a in self.others), arb(0))
            if not gap > 0:
                return False
            if self.n_norm == 0 and self.h_norm == 0:
                return True
            if not R > self.n_norm:
                return False
            beta = arb_max(flint, [top - X * rate for (rate, _, _), top in zip(self.groups, self.tops)])
            t = 1 / (1 - self.n_norm / R)
            e = t * self.h_norm
            r = ((1 + self.n_norm / R) * t * e * (beta + e / R).exp() + 2 * self.n_norm * t * beta.exp()) / R
            scale = sum((w * (-(dg * self.delta) * X).exp() for dg, w in enumerate(self.weights)), arb(0))
            return bool(gap - scale * r > 0)


def arb_max(flint: Any, values: list[Any]) -> Any:
    """The ball of the largest of ``values`` (arb balls)."""
    out = values[0]
    for v in values[1:]:
        out = flint.arb.max(out, v)
    return out


def symmetric_top_bound(flint: Any, a: list[list[Any]]) -> Any:
    """A proven upper bound (an arb ball) of ``lambda_max`` of the symmetric matrix enclosed by ``a``.

    ``t`` slightly above the floating-point ``lambda_max`` is proven an upper bound when
    ``t I - A`` has an ``L D L^T`` factorisation with positive pivots in ball arithmetic
    (then it is positive definite); otherwise Gershgorin's bound ``max_i a_ii + sum_j |a_ij|``.
    """
    arb = flint.arb
    k = len(a)
    mid = np.array([[float(x.mid()) for x in row] for row in a]).reshape(k, k)
    spread = float(np.abs(mid).max(initial=0.0)) + max((float(x.rad()) for row in a for x in row), default=0.0)
    t = arb(float(np.linalg.eigvalsh(0.5 * (mid + mid.T))[-1]) + 1e-9 * (1.0 + spread) + k * spread * 1e-12)
    piv: list[Any] = []
    low = [[arb(0)] * k for _ in range(k)]
    for j in range(k):
        dj = t - a[j][j] - sum((low[j][q] ** 2 * piv[q] for q in range(j)), arb(0))
        if not dj > 0:
            return arb_max(flint, [a[i][i] + sum((abs(a[i][q]) for q in range(k) if q != i), arb(0)) for i in range(k)])
        piv.append(dj)
        for i in range(j + 1, k):
            low[i][j] = (-a[i][j] - sum((low[i][q] * low[j][q] * piv[q] for q in range(j)), arb(0))) / dj
    return t


def spectral_norm_bound(flint: Any, x: Any) -> Any:
    """A proven upper bound of the spectral norm of the arb matrix ``x``: the smaller of
    ``sqrt(lambda_max(x^T x))`` (:func:`symmetric_top_bound`) and the Frobenius norm."""
    arb = flint.arb
    rows, cols = x.nrows(), x.ncols()
    squares = sum((abs(x[i, j]) * abs(x[i, j]) for i in range(rows) for j in range(cols)), arb(0))
    frob = squares.nonnegative_part().sqrt()  # x * x, not x ** 2: a power of a ball holding 0 is nan
    if not frob > 0:
        return frob
    g = x.transpose() * x
    top = symmetric_top_bound(flint, [[g[i, j] for j in range(cols)] for i in range(cols)])
    spectral = arb.max(top, arb(0)).sqrt()
    return spectral if spectral.upper() < frob.upper() else frob


def _prod_except(x: NDArray[np.float64], skip: list[int]) -> NDArray[np.float64]:
    """Product over the last axis of ``x`` leaving out the indices ``skip``."""
    keep = [j for j in range(x.shape[-1]) if j not in skip]
    return np.prod(x[..., keep], axis=-1)
