"""``n + m`` heterodirectional hyperbolic systems with constant coefficients (the paper's open problem).

The plant (paper, Section 5, "Systems with multiple equations")::

    u_t + Lambda+ u_x = Sigma++ u + Sigma+- v,     u(t, 0) = Q v(t, 0),
    v_t - Lambda- v_x = Sigma-+ u + Sigma-- v,     v(t, 1) = R u(t, 1) + U(t),

with ``u`` in ``R^n`` (speeds ``lam_i > 0``), ``v`` in ``R^m`` (speeds ``mu_j > 0``) and a
static boundary feedback with the same delay ``delta`` on every actuator,
``U(t) = K u(t - delta, 1)``.

**Laplace route.** With ``w = (u, v)`` and ``Lambda = diag(lam, -mu)``, the Laplace
transform in ``t`` (zero initial data) is the ODE ``w_x = Lambda^{-1} (Sigma - s I) w``, so
``w(1) = Phi(s) w(0)``, ``Phi(s) = exp(Lambda^{-1} (Sigma - s I))``. The distal condition
gives ``w(0) = [Q; I] v(0)``, hence ``u(1) = Phi_u(s) v(0)``, ``v(1) = Phi_v(s) v(0)`` with
``[Phi_u; Phi_v] = Phi(s) [Q; I]``, and the proximal condition with the delayed feedback
gives the closed-loop characteristic equation

    det( E(s) (Phi_v(s) - (R + K e^{-delta s}) Phi_u(s)) ) = 0,   E(s) = diag(e^{-s/mu_j}),

the scaling ``E`` keeping the function bounded on vertical lines. It is a *matrix*
neutral equation; for one actuator (``m = 1``) it is scalar,
``F(s; delta) = A(s) + B(s) e^{-delta s}`` with ``A = e^{-s/mu} (Phi_v - R Phi_u)`` and
``B = -e^{-s/mu} K Phi_u``: the form of the paper's Section 3, with ``A`` and ``B`` entire
functions given by a matrix exponential instead of kernels.

**Principal part.** Couplings between components of different speeds contribute
``O(1/|s|)`` on vertical lines; the couplings inside a group of equal (signed) speed and
the diagonal ones scale the point terms. With ``U_a = exp(Sigma_aa / lam_a)`` on a group
``a`` of ``u`` and ``V_b = exp(-Sigma_bb / mu_b)`` on a group ``b`` of ``v``, the principal
part is the matrix difference operator

    D(s) = I - sum_{a, b} P_b V^{-1} (R + K e^{-delta s}) P_a U_a Q e^{-(1/lam_a + 1/mu_b) s}

(``P`` the projections on the groups): for ``delta -> 0`` the delays ``tau_ab`` and
``tau_ab + delta`` separate, and delay-robustness needs ``gamma_0 < 1`` with the
coefficients of ``R + K`` and ``K`` counted apart (Hale and Verduyn Lunel). For ``m = 1``
and a full cancellation ``K = -R``, ``gamma_0 = 2 sum_a |R_a U_a Q_a| / |V|``: the
cancellation the paper warns against.

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
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._json import fields_dict
from ..._validate import nonnegative, positive, positive_int, real_array
from ...difference import DifferenceOperator
from ...errors import CertificationError, ParameterError
from ...margins.matrix import GaugeRemainder, circle_crossings, compound_generator, compound_minors
from ...matrix_difference import MatrixDifferenceOperator
from ...qpmatrix import FirstDerivative, QuasiPolynomialMatrix
from ...quasipoly import QuasiPolynomial
from ...roots import count_roots, spectral_abscissa
from ..plants.hyperbolic2x2 import Hyperbolic2x2

__all__ = [
    "CancellationCase",
    "NPlusMCharacteristic",
    "NPlusMMargin",
    "NPlusMSimulation",
    "NPlusMSystem",
    "cancellation_study",
    "compound_characteristic",
    "multi_actuator_delay_margin",
    "multi_actuator_margin",
    "nplusm_delay_margin",
    "simulate_nplusm",
]

# Rounding scale of F(s) relative to ||l|| ||r|| e^{beta} (1 + ||C|| + |s| ||P||): the
# error of a scaling-and-squaring matrix exponential grows with the norm of its argument.
_EXPM_ROUNDING = 16.0
# Frequency grid of the crossing search: points per unit of w times the longest delay.
_GRID_PER_PERIOD = 32
_EPS = float(np.finfo(float).eps)


def _matrix(name: str, value: Any, shape: tuple[int, int]) -> NDArray[np.float64]:
    a = real_array(name, value, ndim=None)
    if a.shape != shape:
        raise ParameterError(name, f"a real matrix of shape {shape}", a.shape)
    return a


def _groups(speeds: NDArray[np.float64]) -> list[NDArray[np.intp]]:
    """Indices of the components sharing each distinct speed."""
    return [np.flatnonzero(speeds == v) for v in np.unique(speeds)]


@dataclass(frozen=True, eq=False)
class NPlusMSystem:
    """``u_t + Lambda+ u_x = Sigma++ u + Sigma+- v``, ``v_t - Lambda- v_x = Sigma-+ u + Sigma-- v``.

    Parameters
    ----------
    lam : array_like, shape (n,)
        Speeds ``> 0`` of ``u`` (rightward).
    mu : array_like, shape (m,)
        Speeds ``> 0`` of ``v`` (leftward).
    sigma : array_like, shape (n + m, n + m)
        Constant couplings ``[[Sigma++, Sigma+-], [Sigma-+, Sigma--]]``.
    q : array_like, shape (n, m)
        Distal reflection: ``u(t, 0) = Q v(t, 0)``.
    r : array_like, shape (m, n)
        Proximal reflection: ``v(t, 1) = R u(t, 1) + U(t)``.

    Examples
    --------
    >>> sys = NPlusMSystem([1.0], [1.0], [[0.0, 1.0], [1.0, 0.0]], [[1.0]], [[0.85]])
    >>> sys.n, sys.m
    (1, 1)
    """

    lam: NDArray[np.float64]
    mu: NDArray[np.float64]
    sigma: NDArray[np.float64]
    q: NDArray[np.float64]
    r: NDArray[np.float64]

    def __init__(self, lam: ArrayLike, mu: ArrayLike, sigma: ArrayLike, q: ArrayLike, r: ArrayLike) -> None:
        la = real_array("lam", lam)
        mu_ = real_array("mu", mu)
        if np.any(la <= 0):
            raise ParameterError("lam", "speeds > 0", lam)
        if np.any(mu_ <= 0):
            raise ParameterError("mu", "speeds > 0", mu)
        n, m = la.size, mu_.size
        object.__setattr__(self, "lam", la)
        object.__setattr__(self, "mu", mu_)
        object.__setattr__(self, "sigma", _matrix("sigma", sigma, (n + m, n + m)))
        object.__setattr__(self, "q", _matrix("q", q, (n, m)))
        object.__setattr__(self, "r", _matrix("r", r, (m, n)))

    @classmethod
    def from_2x2(cls, system: Hyperbolic2x2) -> NPlusMSystem:
        """The ``1 + 1`` form of a 2x2 plant with constant couplings (eqs. (18)-(20))."""
        if not system.constant_couplings:
            raise ParameterError("system", "constant couplings (the n+m route is for constant coefficients)", system)
        s_pm, s_mp = float(system.sigma_pm), float(system.sigma_mp)  # type: ignore[arg-type]
        return cls([system.lam], [system.mu], [[0.0, s_pm], [s_mp, 0.0]], [[system.q]], [[system.rho]])

    @property
    def n(self) -> int:
        """Number of rightward components ``u``."""
        return int(self.lam.size)

    @property
    def m(self) -> int:
        """Number of leftward components ``v`` (actuated ones)."""
        return int(self.mu.size)

    @property
    def signed_speeds(self) -> NDArray[np.float64]:
        """``diag(Lambda) = (lam, -mu)``."""
        return np.concatenate([self.lam, -self.mu])

    def gain(self, K: ArrayLike | None) -> NDArray[np.float64]:
        """The feedback gain ``K`` (``m x n``; None is the open loop ``K = 0``), validated."""
        if K is None:
            return np.zeros((self.m, self.n))
        k = real_array("K", K, ndim=None)
        if k.size == self.m * self.n and k.ndim <= 2 and (k.ndim < 2 or k.shape == (self.m, self.n)):
            return k.reshape(self.m, self.n)
        raise ParameterError("K", f"a real gain of shape ({self.m}, {self.n})", k.shape)

    # ------------------------------------------------------------------ Laplace route
    def transition(self, s: ArrayLike, shift: float = 0.0) -> NDArray[np.complex128]:
        """``e^{-shift s} Phi(s) = exp(Lambda^{-1} (Sigma - s I) - shift s I)``, shape ``s.shape + (n+m, n+m)``."""
        from scipy.linalg import expm  # lazily: a slow import

        s = np.asarray(s, dtype=complex)
        inv = 1.0 / self.signed_speeds
        c = inv[:, None] * self.sigma
        a = c[None] - s.reshape(-1)[:, None, None] * np.diag(inv + shift)[None]
        return np.asarray(expm(a), dtype=complex).reshape(*s.shape, self.n + self.m, self.n + self.m)

    def loop_matrix(self, s: ArrayLike, K: ArrayLike | None = None, delta: float = 0.0) -> NDArray[np.complex128]:
        """``E(s) (Phi_v - (R + K e^{-delta s}) Phi_u)``: the ``m x m`` closed-loop matrix at ``s``."""
        s = np.asarray(s, dtype=complex)
        k = self.gain(K)
        delta = nonnegative("delta", delta)
        g = self.transition(s)
        w0 = np.vstack([self.q, np.eye(self.m)])
        phi = g @ w0
        phi_u, phi_v = phi[..., : self.n, :], phi[..., self.n :, :]
        gain = self.r[None] + np.exp(-delta * s.reshape(-1))[:, None, None] * k[None]
        gain = gain.reshape(*s.shape, self.m, self.n)
        scale = np.exp(-s[..., None] / self.mu)[..., :, None]
        return np.asarray(scale * (phi_v - gain @ phi_u), dtype=complex)

    def characteristic_value(
        self, s: ArrayLike, K: ArrayLike | None = None, delta: float = 0.0
    ) -> NDArray[np.complex128]:
        """``det`` of :meth:`loop_matrix`: the closed-loop characteristic function at ``s``."""
        return np.asarray(np.linalg.det(self.loop_matrix(s, K, delta)), dtype=complex)

    def principal_terms(self, K: ArrayLike | None = None) -> tuple[NDArray, list[tuple[float, NDArray, NDArray]]]:
        """``(V, [(tau_ab, P_b R P_a U_a Q, P_b K P_a U_a Q), ...])``: the point terms of the loop.

        ``E(s) (Phi_v - (R + K e^{-delta s}) Phi_u) = V - sum (R_ab + K_ab e^{-delta s})
        e^{-tau_ab s} + O(1/|s|)`` on vertical lines (module notes).
        """
        from scipy.linalg import expm  # lazily: a slow import

        k = self.gain(K)
        sig, n = self.sigma, self.n
        u_block = np.zeros((n, n))
        for g in _groups(self.lam):
            u_block[np.ix_(g, g)] = expm(sig[np.ix_(g, g)] / self.lam[g][0])
        v_block = np.zeros((self.m, self.m))
        for g in _groups(self.mu):
            v_block[np.ix_(g, g)] = expm(-sig[np.ix_(g + n, g + n)] / self.mu[g][0])
        terms = []
        for ga in _groups(self.lam):
            pa = np.zeros((n, n))
            pa[ga, ga] = 1.0
            for gb in _groups(self.mu):
                pb = np.zeros((self.m, self.m))
                pb[gb, gb] = 1.0
                tau = float(1.0 / self.lam[ga][0] + 1.0 / self.mu[gb][0])
                terms.append((tau, pb @ self.r @ pa @ u_block @ self.q, pb @ k @ pa @ u_block @ self.q))
        return v_block, terms

    def principal_operator(self, K: ArrayLike | None = None, delta: float = 0.0) -> MatrixDifferenceOperator:
        """The principal part ``D(s) = I - sum_k A_k e^{-tau_k s}`` (module notes).

        For ``delta > 0`` the coefficients of ``R`` (delay ``tau_ab``) and of ``K`` (delay
        ``tau_ab + delta``) are kept apart; with ``delta = 0`` they merge into ``R + K``.

        Raises
        ------
        ParameterError
            ``R Q = K Q = 0`` (no chains), or more than four distinct delays.
        """
        delta = nonnegative("delta", delta)
        v_block, point = self.principal_terms(K)
        v_inv = np.linalg.inv(v_block)
        terms: dict[float, NDArray[np.float64]] = {}
        for tau, rq, kq in point:
            for t, a in ((tau, rq), (tau + delta, kq)):
                terms[t] = terms.get(t, np.zeros((self.m, self.m))) + v_inv @ a
        delays = sorted(t for t, a in terms.items() if np.any(a != 0))
        if not delays:
            raise ParameterError("r", "a nonzero reflection R Q or gain K Q (else D = I has no chains)", self.r)
        return MatrixDifferenceOperator(np.array([terms[t] for t in delays]), delays)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


class NPlusMCharacteristic:
    """``F(s) = det(E(s) (Phi_v - (R + K e^{-delta s}) Phi_u))``: the closed loop of an ``n + m`` system.

    A :class:`~nrobust.qpmatrix.CharacteristicFunction`: ``count_roots``, ``find_roots``
    and ``spectral_abscissa`` (with a region) certify its roots. Row ``j`` of the
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
        return np.asarray(m * 2.0 ** (m - 1) * np.prod(_EXPM_ROUNDING * scale * growth, axis=-1), dtype=float)

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
        level = _EXPM_ROUNDING * _EPS * np.exp(beta) * self._w_norm * (1.0 + self._c_norm + w * p)
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
        level = _EXPM_ROUNDING * _EPS * np.exp(beta) * self._w_norm  # rounding of A, B per unit ||l||
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

        step = 2.0 * np.pi / (_GRID_PER_PERIOD * self.max_delay)
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

        return tuple(float(brentq(h1, a, b, xtol=1e-14, rtol=4 * _EPS)) for a, b in sorted(brackets))


def _prod_except(x: NDArray[np.float64], skip: list[int]) -> NDArray[np.float64]:
    """Product over the last axis of ``x`` leaving out the indices ``skip``."""
    keep = [j for j in range(x.shape[-1]) if j not in skip]
    return np.prod(x[..., keep], axis=-1)


# ====================================================================== delay margin (m = 1)
@dataclass(frozen=True)
class NPlusMMargin:
    """The smallest loop delay that puts a root of a one-actuator ``n + 1`` loop on the axis.

    Attributes
    ----------
    margin : float
        ``0`` when the principal part with the delay is not strongly stable
        (``gamma_0 >= 1``: arbitrarily small delays destabilise), ``inf`` when
        ``|A(i w)| != |B(i w)|`` for every ``w >= 0``, else the smallest
        ``(arg(-B/A)(i w) mod 2 pi) / w`` over the crossing frequencies.
    omega : float or None
        The crossing frequency of ``margin``.
    crossings : tuple of (float, float)
        Every crossing frequency ``w > 0`` with its first delay.
    gamma_0 : float
        ``sum |R_a U_a Q_a| / |V| + sum |K_a U_a Q_a| / |V|`` of the delayed principal part
        (exact for one actuator).
    frequency_bound : float
        ``W``: proven ``|A(i w)| != |B(i w)|`` for ``w >= W``, and no zero of
        ``F(.; delta)`` with ``Re s >= 0``, ``|s| >= W``, for any ``delta >= 0``
        (:meth:`NPlusMCharacteristic.frequency_bound`).
    certified : bool
        True: the frequency bound is proven (gauge transformation and Gronwall's lemma,
        module notes), every crossing on ``[0, W]`` is found by a search with a certified
        exclusion and monotonicity test, the delay-free loop's unstable roots are counted
        (:func:`~nrobust.roots.count_roots` on ``[0, W] x [-W, W]``), and ``gamma_0 >= 1``
        is decided with room above rounding. False for ``gamma_0`` within ``1e-12`` of 1,
        or when a root of the delay-free loop lies within rounding of the axis.
    nominal_unstable : int or None
        Certified number of roots of the delay-free loop in ``Re s >= 0`` (None: not
        counted, ``gamma_0 >= 1``, or a root within rounding of the axis). When it is not
        0 the margin is 0: the loop is not stable to begin with.
    """

    margin: float
    omega: float | None
    crossings: tuple[tuple[float, float], ...]
    gamma_0: float
    frequency_bound: float
    certified: bool
    nominal_unstable: int | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


def nplusm_delay_margin(system: NPlusMSystem, K: ArrayLike, *, max_points: int = 2_000_000) -> NPlusMMargin:
    """Certified delay margin of ``U(t) = K u(t - delta, 1)`` on a one-actuator ``n + 1`` system.

    ``F(s; delta) = A(s) + B(s) e^{-delta s}`` (module notes): a root reaches ``s = i w``
    only where ``g(w) = |A(i w)|^2 - |B(i w)|^2`` vanishes, at the delays
    ``(arg(-B/A) mod 2 pi + 2 pi k) / w``. Beyond the proven frequency bound ``W``
    (:meth:`NPlusMCharacteristic.frequency_bound`) there is no crossing; on ``[0, W]``
    the search is complete (:meth:`NPlusMCharacteristic.crossing_frequencies`: Lipschitz
    exclusion of ``|A| - |B|``, then monotonicity of ``g`` from a bound of ``|g''|``).

    Parameters
    ----------
    system : NPlusMSystem
        With ``m = 1``; the loop with ``K`` and no delay should be stable (the margin is
        then the delay margin: the loop stays stable for every ``delta < margin``).
    K : array_like, shape (1, n)
        The gain.
    max_points : int, optional
        Work bound on evaluations of ``A`` and ``B`` on the axis, checked before each grid
        is allocated.

    Returns
    -------
    NPlusMMargin

    Raises
    ------
    CertificationError
        The work bound was hit, or ``g`` has a zero of even multiplicity (a tangency) to
        rounding that the search cannot decide.
    """
    F = NPlusMCharacteristic(system, K, 0.0)
    if system.m != 1:
        raise ParameterError("system", "one actuator (m = 1): the loop is then A + B e^{-delta s}", system.m)
    max_points = positive_int("max_points", max_points)
    gamma = F.gamma_0()
    if gamma >= 1.0:
        return NPlusMMargin(0.0, None, (), gamma, 0.0, gamma > 1.0 + 1e-12)
    W = F.frequency_bound()
    radius = max(W, 1.0)  # the bound holds for every radius >= W
    count = count_roots(F, (0.0, radius, -radius, radius))
    nominal = int(count) if count.region[0] >= 0.0 else None
    if nominal != 0:
        return NPlusMMargin(0.0, None, (), gamma, W, nominal is not None, nominal)
    found = []
    for wc in F.crossing_frequencies(W, max_points=max_points):
        a, b = F.factors(np.array([1j * wc]))
        found.append((wc, float(np.mod(np.angle(-b[0] / a[0]), 2 * np.pi) / wc)))
    certified = gamma < 1.0 - 1e-12
    if not found:
        return NPlusMMargin(np.inf, None, (), gamma, W, certified, 0)
    best = min(found, key=lambda p: p[1])
    return NPlusMMargin(best[1], best[0], tuple(found), gamma, W, certified, 0)


def multi_actuator_margin(
    system: NPlusMSystem,
    K: ArrayLike,
    omega_max: float | None = None,
    *,
    points: int = 4000,
    max_points: int = 1_000_000,
) -> NPlusMMargin:
    """Delay margin of ``U(t) = K u(t - delta, 1)``, the same delay on all ``m`` actuators.

    Without ``omega_max`` this is :func:`multi_actuator_delay_margin` (certified: a proven
    frequency bound replaces ``omega_max``). With ``omega_max`` the search below runs on
    ``(0, omega_max]`` only, as a cap, and the result is never certified.

    ``F(s; delta) = det(M_0(s) + e^{-delta s} M_1(s))`` with ``M_0`` the loop matrix of
    ``K = 0`` and ``M_1 = -E K Phi_u``. A root sits at ``s = i w`` iff
    ``z = e^{-i w delta}`` is an eigenvalue of the pencil ``M_0 v = -z M_1 v`` on the unit
    circle; the delays are ``(-arg z mod 2 pi) / w``. The number of eigenvalues inside the
    unit disk is tracked on a grid of ``(0, omega_max]``; each change is located by
    bisection and gives one crossing frequency. Not certified (``certified=False``): two
    eigenvalues crossing the circle in opposite directions between grid points, or a
    crossing above ``omega_max``, would be missed; ``gamma_0`` is the certified upper bound
    of the delayed principal part's spectral radius (as in :func:`multi_actuator_delay_margin`),
    the margin 0 when a sampled value is at least 1, and ``nominal_unstable`` the certified
    count of the delay-free loop in ``[0, omega_max] x [-omega_max, omega_max]`` only.

    Parameters
    ----------
    system : NPlusMSystem
    K : array_like, shape (m, n)
    omega_max : float, optional
        Upper end ``> 0`` of a capped, uncertified search; None (default) for the certified margin.
    points : int, optional
        Grid points (``>= 16``) of the capped search.
    max_points : int, optional
        Work bound on pencil evaluations (on evaluations of the compound transition without
        ``omega_max``), checked before the grid is allocated.
    """
    from scipy.linalg import eigvals  # lazily: a slow import

    if omega_max is None:
        return multi_actuator_delay_margin(system, K, max_points=max_points)
    k = system.gain(K)
    omega_max = positive("omega_max", omega_max)
    points = positive_int("points", points, minimum=16)
    max_points = positive_int("max_points", max_points)
    if points + 64 * system.m * max(1, points // 8) > max_points:
        raise ParameterError("max_points", f">= {points + 64 * system.m * max(1, points // 8)}", max_points)
    lower, gamma, _ = _principal_gamma(system, k)
    if lower >= 1.0:
        return NPlusMMargin(0.0, None, (), gamma, 0.0, False)
    count = count_roots(NPlusMCharacteristic(system, k, 0.0), (0.0, omega_max, -omega_max, omega_max))
    nominal = int(count) if count.region[0] >= 0.0 else None
    if nominal != 0:
        return NPlusMMargin(0.0, None, (), gamma, omega_max, False, nominal)

    def pencil(w: NDArray[np.float64]) -> NDArray[np.complex128]:
        s = 1j * np.asarray(w, dtype=float)
        m0 = system.loop_matrix(s)
        m1 = system.loop_matrix(s, k) - m0
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.array([eigvals(a, -b) for a, b in zip(m0, m1)])

    def inside(w: NDArray[np.float64]) -> NDArray[np.int64]:
        return np.sum(np.abs(pencil(w)) < 1.0, axis=-1)

    w = np.linspace(omega_max / points, omega_max, points)
    n_in = inside(w)
    found = []
    for i in np.flatnonzero(n_in[:-1] != n_in[1:]):
        lo, hi, n_lo = float(w[i]), float(w[i + 1]), int(n_in[i])
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if int(inside(np.array([mid]))[0]) == n_lo:
                lo = mid
            else:
                hi = mid
        wc = 0.5 * (lo + hi)
        z = pencil(np.array([wc]))[0]
        zc = z[np.argmin(np.abs(np.abs(z) - 1.0))]
        found.append((wc, float(np.mod(-np.angle(zc), 2 * np.pi) / wc)))
    if not found:
        return NPlusMMargin(np.inf, None, (), gamma, omega_max, False, 0)
    best = min(found, key=lambda p: p[1])
    return NPlusMMargin(best[1], best[0], tuple(found), gamma, omega_max, False, 0)


# ====================================================================== delay margin (any m)
def _compound_loop(system: NPlusMSystem, k: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """``(D_m(C), p, a, b)``: ``det M(s; z) = sum_d z^d a_d^T exp(D_m(C) - s diag(p)) b`` (module notes of
    :mod:`nrobust.matrix_crossings`), ``a`` of shape ``(m + 1, binom(n + m, m))``.

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


class _CompoundCharacteristic:
    """``F(s; delta) = sum_d e^{-d delta s} a_d^T exp(D_m(C) - s diag(p)) b``: the loop in compound form.

    The same function as :class:`NPlusMCharacteristic` (Cauchy-Binet), written with rates
    ``p >= 0`` so that ``||d^k/ds^k exp(D_m(C) - s diag(p))|| <= ||p||^k e^{beta(Re s)}``,
    ``beta(x) = lambda_max(Herm D_m(C) - x diag(p))`` non-increasing and convex: rows growing
    like ``e^{s (1/mu_i - 1/mu_j)}`` make the loop matrix's own bounds grow on ``Re s > 0``;
    these do not. A :class:`~nrobust.qpmatrix.CharacteristicFunction`.
    """

    def __init__(self, F: NPlusMCharacteristic, dc: NDArray, p: NDArray, a: NDArray, b: NDArray) -> None:
        self.F = F
        self._dc, self._p, self._a, self._b = dc, p, a, b
        self._herm = 0.5 * (dc + dc.conj().T)
        self._rows = np.linalg.norm(a, axis=1) * float(np.linalg.norm(b)) * (1.0 + 1e-12)  # ||a_d|| ||b||
        self._orders = np.arange(a.shape[0]) * F.delta  # d delta
        self._pn = float(np.max(p))
        self._dc_norm = float(np.linalg.norm(dc, 2))

    def _jet(self, s: NDArray[np.complex128], derivative: bool) -> NDArray[np.complex128]:
        from scipy.linalg import expm  # lazily: a slow import

        size = self._dc.shape[0]
        shifts = np.exp(-s[:, None] * self._orders[None])  # e^{-d delta s}
        alpha = shifts @ self._a
        a = self._dc[None] - s[:, None, None] * np.diag(self._p)[None]
        if not derivative:
            return np.asarray(np.einsum("ni,ni->n", expm(a) @ self._b, alpha), dtype=complex)
        big = np.zeros((s.size, 2 * size, 2 * size), dtype=complex)
        big[:, :size, :size] = big[:, size:, size:] = a
        big[:, :size, size:] = -np.diag(self._p)
        e = expm(big)
        dalpha = -(shifts * self._orders[None]) @ self._a
        g, dg = e[:, :size, :size] @ self._b, e[:, :size, size:] @ self._b
        return np.asarray(np.einsum("ni,ni->n", dg, alpha) + np.einsum("ni,ni->n", g, dalpha), dtype=complex)

    def __call__(self, s: ArrayLike) -> NDArray[np.complex128]:
        s = np.asarray(s, dtype=complex)
        return self._jet(s.reshape(-1), False).reshape(s.shape)

    def deriv_at(self, s: ArrayLike) -> NDArray[np.complex128]:
        s = np.asarray(s, dtype=complex)
        return self._jet(s.reshape(-1), True).reshape(s.shape)

    def _bound(self, a: ArrayLike, b: ArrayLike, order: int) -> NDArray[np.float64]:
        """``sum_d ||a_d|| ||b|| e^{-d delta x_min} (d delta + ||p||)^order e^{max beta}`` on segments."""
        x = np.stack(np.broadcast_arrays(np.asarray(a, dtype=complex).real, np.asarray(b, dtype=complex).real))
        xs, inv = np.unique(x, return_inverse=True)
        top = np.linalg.eigvalsh(self._herm[None] - xs[:, None, None] * np.diag(self._p)[None])[:, -1]
        top = top + 1e-12 * (1.0 + self._dc_norm + np.abs(xs) * self._pn)
        growth = np.exp(top[inv.reshape(x.shape)].max(axis=0))
        weights = self._rows * (self._orders + self._pn) ** order
        shifts = np.exp(-x.min(axis=0)[..., None] * self._orders)
        return np.asarray(growth * (shifts @ weights), dtype=float)

    def deriv_bound(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        return self._bound(a, b, 1)

    def second_deriv_bound(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
        return self._bound(a, b, 2)

    def derivative(self) -> FirstDerivative:
        return FirstDerivative(self)

    def magnitude(self, s: ArrayLike) -> NDArray[np.float64]:
        s = np.asarray(s, dtype=complex)
        grow = 1.0 + self._dc_norm + np.abs(s) * self._pn
        return np.asarray(_EXPM_ROUNDING * self._bound(s, s, 0) * grow, dtype=float)

    def principal_part(self) -> DifferenceOperator:
        return self.F.principal_part()

    @property
    def kind(self) -> str:
        return self.F.kind

    @property
    def is_real(self) -> bool:
        return True

    @property
    def max_delay(self) -> float:
        return self.F.max_delay


def compound_characteristic(system: NPlusMSystem, K: ArrayLike | None = None, delta: float = 0.0) -> Any:
    """The closed loop of :class:`NPlusMCharacteristic` in compound form, for counts far into ``Re s > 0``.

    ``F(s; delta) = sum_d e^{-d delta s} a_d^T exp(D_m(C) - s P_m) b`` (Cauchy-Binet,
    :mod:`nrobust.matrix_crossings`): the same function, with derivative bounds that stay
    bounded on ``Re s >= 0`` for any ``m`` (the rates ``P_m`` are ``>= 0``), where the rows of
    the loop matrix grow like ``e^{s (1/mu_i - 1/mu_j)}``. A
    :class:`~nrobust.qpmatrix.CharacteristicFunction` for :func:`~nrobust.roots.count_roots`.
    """
    F = NPlusMCharacteristic(system, K, delta)
    dc, p, a, b = _compound_loop(system, F.K)
    return _CompoundCharacteristic(F, dc, p, a, b)


def _principal_gamma(system: NPlusMSystem, k: NDArray[np.float64]) -> tuple[float, float, float]:
    """``(lower, upper, |det V|)``: a sampled and a certified bound of ``sup rho(V^{-1} sum_t C_t e^{i theta_t})``
    over independent phases of the principal terms ``C_t`` (``R_ab`` and ``K_ab`` apart).

    The upper end is the smaller of the Collatz-Wielandt bound of ``rho(sum_t |V^{-1} C_t|)`` (which bounds
    ``rho`` on the whole polydisc) and, for at most four distinct delays, the certified
    :meth:`~nrobust.matrix_difference.MatrixDifferenceOperator.gamma_0` bracket.
    """
    v_block, point = system.principal_terms(k)
    v_inv = np.linalg.inv(v_block)
    mats = [v_inv @ a for _, rq, kq in point for a in (rq, kq) if np.any(a != 0)]
    if not mats:
        return 0.0, 0.0, float(abs(np.linalg.det(v_block)))
    total = np.sum(np.abs(mats), axis=0)
    vals, vecs = np.linalg.eig(total)
    x = np.abs(vecs[:, int(np.argmax(np.abs(vals)))]) + 1e-12 * float(np.abs(vecs).max())
    upper = float(np.max((total @ x) / x)) * (1.0 + 1e-12)
    rng = np.random.default_rng(0)
    theta = np.vstack([np.zeros(len(mats)), rng.uniform(0.0, 2 * np.pi, (2047, len(mats)))])
    lower = float(np.max(np.abs(np.linalg.eigvals(np.einsum("nt,tij->nij", np.exp(1j * theta), np.array(mats))))))
    try:
        bracket = system.principal_operator(k, 1e-3 * np.sqrt(2.0)).gamma_0(rtol=1e-6, max_cells=20_000)
        lower, upper = max(lower, bracket.lower), min(upper, bracket.upper)
    except (ParameterError, CertificationError):
        pass  # more than four delays, or a bracket that did not close: the Collatz-Wielandt bound stands
    return lower, max(upper, lower), float(abs(np.linalg.det(v_block)))


def multi_actuator_delay_margin(system: NPlusMSystem, K: ArrayLike, *, max_points: int = 2_000_000) -> NPlusMMargin:
    """Certified delay margin of ``U(t) = K u(t - delta, 1)``, the same delay on all ``m >= 1`` actuators.

    ``F(s; delta) = det(M_0(s) + e^{-delta s} M_1(s))`` (``M_0`` the loop matrix of ``K = 0``,
    ``M_1 = -E K Phi_u``). By Cauchy-Binet, ``f(w, z) = det(M_0(i w) + z M_1(i w)) =
    sum_d z^d a_d^T exp(D_m(C) - i w P_m) b`` with ``a_d`` the coefficients of the minors of
    ``[-(R + z K), I]``, ``b`` those of ``[Q; I]`` and ``D_m``, ``P_m >= 0`` the compound
    generator and rates (:mod:`nrobust.matrix_crossings`). A root reaches ``s = i w`` for some
    delay iff ``f(w, e^{i phi}) = 0``, at the delays ``((-phi) mod 2 pi + 2 pi k) / w``
    (an eigenvalue ``e^{-i phi}`` of ``-M_0^{-1} M_1`` on the unit circle).

    1. *Principal part.* ``|F_0(s; z)| = |det V| |det(I - X)| >= |det V| (1 - gamma)^m`` on
       ``Re s >= 0``, ``|z| <= 1``, with ``gamma`` a certified bound of the spectral radius of
       ``X = V^{-1} sum (R_ab + z K_ab) e^{-tau_ab s}`` over independent phases (Hale and
       Verduyn Lunel's ``gamma_0`` of the delayed principal part; the margin is 0 when a
       sampled ``rho`` is above 1: arbitrarily small delays destabilise).
    2. *Frequency bound.* ``|F - F_0| <= sum_d ||a_d|| ||b|| r(|s|)`` with ``r`` the
       :class:`~nrobust.matrix_crossings.GaugeRemainder` of ``(D_m(C), P_m)``: beyond the
       proven ``W`` where this is below the gap, ``F(s; delta) != 0`` on ``Re s >= 0`` for
       every ``delta >= 0``, and no eigenvalue of ``-M_0^{-1} M_1`` has modulus 1 on the axis.
    3. *Nominal stability.* :func:`~nrobust.roots.count_roots` of the delay-free loop on
       ``[0, W] x [-W, W]``.
    4. *Crossings.* :func:`~nrobust.matrix_crossings.circle_crossings` on ``[0, W] x [0, 2 pi)``
       (Lipschitz exclusion, Newton-Kantorovich discs; a tangency raises).

    Parameters
    ----------
    system : NPlusMSystem
    K : array_like, shape (m, n)
    max_points : int, optional
        Work bound on evaluations of the compound transition on the axis.

    Returns
    -------
    NPlusMMargin
        ``gamma_0`` is the certified upper bound used in step 1 (exact for ``m = 1``).

    Raises
    ------
    CertificationError
        The bound of step 1 is not below 1 although no sampled ``rho`` exceeds 1, a work bound
        was hit, or the crossing search met a tangency.
    """
    from scipy.linalg import expm  # lazily: a slow import

    k = system.gain(K)
    max_points = positive_int("max_points", max_points)
    m = system.m
    lower, gamma, det_v = _principal_gamma(system, k)
    if lower >= 1.0 + 1e-12:
        return NPlusMMargin(0.0, None, (), lower, 0.0, True)
    if gamma >= 1.0 - 1e-12:
        raise CertificationError(
            f"multi-actuator margin: gamma_0 of the delayed principal part in [{lower:.12g}, {gamma:.12g}] is not "
            "separated from 1 (the certified bound of its spectral radius must be below 1)"
        )
    dc, p, a, b = _compound_loop(system, k)
    a_norm = np.linalg.norm(a, axis=1)
    b_norm = float(np.linalg.norm(b))
    scale = float(a_norm.sum()) * b_norm
    level = det_v * (1.0 - gamma) ** m * (1.0 - 1e-9) - 1e-12 * scale
    W = GaugeRemainder(dc, p).radius(scale, level)
    radius = max(W, 1.0)
    count = count_roots(compound_characteristic(system, k, 0.0), (0.0, radius, -radius, radius))
    nominal = int(count) if count.region[0] >= 0.0 else None
    if nominal != 0:
        return NPlusMMargin(0.0, None, (), gamma, W, nominal is not None, nominal)
    beta = float(np.linalg.eigvalsh(0.5 * (dc + dc.conj().T))[-1]) + 1e-12 * (1.0 + float(np.abs(dc).sum()))
    pn = float(np.max(p))
    growth = np.exp(beta) * b_norm * a_norm * (1.0 + 1e-12)
    bounds = np.array([growth, growth * pn, growth * pn**2])
    dc_norm = float(np.linalg.norm(dc, 2))
    pdiag = np.diag(p)

    def coefs(w: NDArray[np.float64]) -> NDArray[np.complex128]:
        g = expm(dc[None] - 1j * w[:, None, None] * pdiag[None]) @ b
        return np.asarray(g @ a.T, dtype=complex)

    def jet(w: NDArray[np.float64]) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        size = dc.shape[0]
        big = np.zeros((w.size, 2 * size, 2 * size), dtype=complex)
        big[:, :size, :size] = big[:, size:, size:] = dc[None] - 1j * w[:, None, None] * pdiag[None]
        big[:, :size, size:] = -1j * pdiag  # exp([[A, A'], [0, A]]) = [[G, G'], [0, G]] (Van Loan), ' = d/dw
        e = expm(big)
        return e[:, :size, :size] @ b @ a.T, e[:, :size, size:] @ b @ a.T

    def rounding(w: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(
            _EXPM_ROUNDING * _EPS * np.exp(beta) * b_norm * float(a_norm.max()) * (1.0 + dc_norm + w * pn), dtype=float
        )

    step = 2.0 * np.pi / (_GRID_PER_PERIOD * NPlusMCharacteristic(system, k).max_delay)
    zeros = circle_crossings(coefs, jet, W, bounds, rounding, step=step, max_points=max_points)
    found = tuple((w, float(np.mod(-phi, 2 * np.pi) / w)) for w, phi in zeros)
    certified = gamma < 1.0 - 1e-12
    if not found:
        return NPlusMMargin(np.inf, None, (), gamma, W, certified, 0)
    best = min(found, key=lambda c: c[1])
    return NPlusMMargin(best[1], best[0], found, gamma, W, certified, 0)


# ====================================================================== simulation
def _coupling_operator(sigma: NDArray[np.float64], xs: list[NDArray[np.float64]], off: NDArray[np.intp]) -> Any:
    """Sparse map of the stacked grid values to ``Sigma w`` on every grid (linear interpolation between grids)."""
    from scipy.sparse import csr_matrix  # lazily: a slow import

    rows, cols, vals = [], [], []
    for i, xi in enumerate(xs):
        for j, xj in enumerate(xs):
            if sigma[i, j] == 0:
                continue
            nj = xj.size - 1
            pos = np.minimum(np.floor(xi * nj).astype(int), nj - 1)
            frac = xi * nj - pos
            node = np.arange(xi.size) + off[i]
            rows += [node, node]
            cols += [pos + off[j], pos + 1 + off[j]]
            vals += [sigma[i, j] * (1 - frac), sigma[i, j] * frac]
    size = int(off[-1])
    if not rows:
        return csr_matrix((size, size))
    return csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(size, size))


@dataclass(frozen=True, eq=False)
class NPlusMSimulation:
    """Result of :func:`simulate_nplusm`.

    Attributes
    ----------
    times : ndarray
        Sampled times ``j dt``.
    norm : ndarray
        ``||w(t)||_{L2}`` (trapezoidal rule on each component's grid).
    dt : float
        Time step (one cell per step for every component).
    cells : tuple of int
        Cells of each component's grid (``round(1 / (c_i dt))`` for speed ``c_i``).
    """

    times: NDArray[np.float64]
    norm: NDArray[np.float64]
    dt: float
    cells: tuple[int, ...]

    def growth_rate(self, t_start: float | None = None) -> float:
        """Slope of ``log ||w||`` fitted by least squares on ``[t_start, t_end]`` (default: the second half)."""
        t0 = self.times[-1] / 2 if t_start is None else nonnegative("t_start", t_start)
        keep = (self.times >= t0) & (self.norm > 0)
        return float(np.polyfit(self.times[keep], np.log(self.norm[keep]), 1)[0])

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


def simulate_nplusm(
    system: NPlusMSystem,
    K: Any,
    delta: float,
    t_end: float,
    w0: Any,
    cells: int = 200,
    *,
    max_updates: int = 200_000_000,
) -> NPlusMSimulation:
    """Simulate the ``n + m`` system under ``U(t) = K u(t - delta, 1)`` (``U = 0`` for ``t < delta``).

    Each component lives on its own grid of ``N_i = round(1 / (c_i dt))`` cells with
    ``dt = 1 / (cells max c_i)``, so that one time step moves it exactly one cell along
    its characteristic (CFL 1 per speed; the transport times ``1/c_i`` are rounded to
    multiples of ``dt``). The couplings are integrated along the characteristics by
    Heun's method (second order), reading the other components by linear interpolation
    between the grids; the boundary conditions close each step, the delayed output
    control ``U(t - delta)`` is interpolated linearly in the stored history.

    Parameters
    ----------
    system : NPlusMSystem
    K : array_like, None or state feedback
        The gain (``m x n``; None for the open loop), or an object whose
        ``functional(grids)`` returns the control as a row map ``(m, nodes)`` of the
        stacked nodal values on the component grids (as
        :class:`~nrobust.hyperbolic.nplusm_kernels.NPlusMBackstepping`): then
        ``v(t, 1) = R u(t, 1) + U(t - delta)`` with ``U(t)`` that map of the state
        (solved with ``v(t, 1)`` when the map reads it).
    delta : float
        Loop delay ``>= 0``.
    t_end : float
        Final time ``> 0``.
    w0 : callable
        ``w0(x)`` returns the ``n + m`` initial profiles as an array of shape ``(n + m, x.size)``.
    cells : int, optional
        Cells of the fastest component.
    max_updates : int, optional
        Work bound on node updates, checked before allocating.

    Returns
    -------
    NPlusMSimulation
    """
    functional = getattr(K, "functional", None)
    k = system.gain(None if callable(functional) else K)
    delta = nonnegative("delta", delta)
    t_end = positive("t_end", t_end)
    cells = positive_int("cells", cells, minimum=4)
    max_updates = positive_int("max_updates", max_updates)
    if not callable(w0):
        raise ParameterError("w0", "a callable x -> array of shape (n + m, x.size)", w0)
    speeds = np.abs(system.signed_speeds)
    dt = 1.0 / (cells * float(speeds.max()))
    ncell = [max(1, round(1.0 / (c * dt))) for c in speeds]
    steps = int(np.ceil(t_end / dt - 1e-9))
    if steps * (sum(ncell) + len(ncell)) > max_updates:
        raise ParameterError("max_updates", f">= {steps * (sum(ncell) + len(ncell))} (steps x nodes)", max_updates)
    xs = [np.linspace(0.0, 1.0, nc + 1) for nc in ncell]
    off = np.cumsum([0] + [x.size for x in xs])
    state = np.empty(int(off[-1]))
    for i, x in enumerate(xs):
        prof = np.asarray(w0(x), dtype=float)
        if prof.shape != (system.n + system.m, x.size) or not np.all(np.isfinite(prof)):
            raise ParameterError("w0", f"finite profiles of shape ({system.n + system.m}, x.size)", prof.shape)
        state[off[i] : off[i + 1]] = prof[i]
    n = system.n
    coupling = _coupling_operator(system.sigma, xs, off)
    # one cell per step along each characteristic: rightward u, leftward v
    dest = np.concatenate(
        [np.arange(off[i] + 1, off[i + 1]) if i < n else np.arange(off[i], off[i + 1] - 1) for i in range(len(xs))]
    )
    src = np.concatenate(
        [np.arange(off[i], off[i + 1] - 1) if i < n else np.arange(off[i] + 1, off[i + 1]) for i in range(len(xs))]
    )
    u_in, u_out = off[:n], off[1 : n + 1] - 1  # u(0), u(1)
    v_in, v_out = off[n + 1 :] - 1, off[n:-1]  # v(1), v(0)
    weights = np.concatenate([np.full(x.size, 1.0 / (x.size - 1)) * np.r_[0.5, np.ones(x.size - 2), 0.5] for x in xs])
    lag = delta / dt
    m = system.m
    if callable(functional):
        gain = np.asarray(functional(xs), dtype=float)
        if gain.shape != (m, state.size) or not np.all(np.isfinite(gain)):
            raise ParameterError("K", f"a functional of shape ({m}, {state.size}) on the grids", gain.shape)
    else:
        gain = np.zeros((m, state.size))
        gain[:, u_out] = k
    implicit = gain[:, v_in]  # weight of v(t, 1) in U(t)
    explicit = gain.copy()
    explicit[:, v_in] = 0.0
    hist = np.zeros((steps + 1, m))  # U(t_j)
    hist[0] = gain @ state

    def delayed(j: int) -> tuple[NDArray[np.float64], float]:
        """``U(t_j - delta)`` (zero before the start), linear in the history: the part known
        before step ``j`` closes, and the weight of ``U(t_j)`` in it."""
        tj = j - lag
        if tj < 0:
            return np.zeros(m), 0.0
        lo = int(np.floor(tj))
        frac = tj - lo
        if lo == j:
            return np.zeros(m), 1.0
        if frac == 0:
            return hist[lo], 0.0
        if lo + 1 == j:
            return (1 - frac) * hist[lo], frac
        return (1 - frac) * hist[lo] + frac * hist[lo + 1], 0.0

    def close(w: NDArray[np.float64], j: int) -> None:
        w[u_in] = system.q @ w[v_out]
        known, c = delayed(j)
        base = system.r @ w[u_out] + known
        hist[j] = np.linalg.solve(np.eye(m) - c * implicit, explicit @ w + implicit @ base)
        w[v_in] = base + c * hist[j]

    norms = np.empty(steps + 1)
    norms[0] = np.sqrt(weights @ state**2)
    # zeros, not empty: close() forms explicit @ w before it sets v(t, 1), and 0 times an
    # uninitialised NaN is NaN
    pred = np.zeros_like(state)
    for j in range(1, steps + 1):
        s_old = coupling @ state
        pred[dest] = state[src] + dt * s_old[src]
        close(pred, j)
        s_new = coupling @ pred
        new = np.zeros_like(state)
        new[dest] = state[src] + 0.5 * dt * (s_old[src] + s_new[dest])
        close(new, j)
        state = new
        norms[j] = np.sqrt(weights @ state**2)
    return NPlusMSimulation(np.arange(steps + 1, dtype=float) * dt, norms, dt, tuple(ncell))


# ====================================================================== cancellation study (m = 1)
@dataclass(frozen=True)
class CancellationCase:
    """One static feedback ``K = -diag(c) R`` cancelling a fraction ``c_i`` of each reflection ``R_i``.

    Attributes
    ----------
    fractions : tuple of float
        ``c_i``: 0 keeps the reflection of ``u_i``, 1 cancels it.
    gain : tuple of float
        ``K = -(c_i R_i)``.
    gamma_0 : float
        Of the delayed principal part: delay-robust iff below 1.
    abscissa : float
        Spectral abscissa of the delay-free loop in ``region`` (the rightmost root, or the
        chain value of the principal part when larger).
    abscissa_certified : bool
        Every root of ``region`` was found.
    margin : NPlusMMargin
        The delay margin search.
    """

    fractions: tuple[float, ...]
    gain: tuple[float, ...]
    gamma_0: float
    abscissa: float
    abscissa_certified: bool
    margin: NPlusMMargin

    @property
    def robust(self) -> bool:
        """True if the delay-free loop is stable in ``region`` and the margin is positive."""
        return self.abscissa < 0 and self.margin.margin > 0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {**fields_dict(self), "robust": self.robust}


def cancellation_study(
    system: NPlusMSystem, cancellations: Any, region: tuple[float, float, float, float]
) -> tuple[CancellationCase, ...]:
    """Delay robustness of the partial cancellations ``K = -diag(c) R`` of a one-actuator system.

    For each row ``c`` of ``cancellations`` (one fraction per ``u`` component): the exact
    ``gamma_0`` of the principal part with a loop delay, the certified spectral abscissa
    of the delay-free loop in ``region`` (:func:`~nrobust.roots.spectral_abscissa` on
    :class:`NPlusMCharacteristic`) and :func:`nplusm_delay_margin`. The paper's
    conclusion (Section 5) is that cancelling every reflection (finite-time convergence)
    is not delay-robust: full cancellation doubles ``gamma_0``.
    """
    if system.m != 1:
        raise ParameterError("system", "one actuator (m = 1)", system.m)
    rows = real_array("cancellations", cancellations, ndim=2)
    if rows.shape[1] != system.n:
        raise ParameterError("cancellations", f"rows of {system.n} fractions", rows.shape)
    out = []
    for c in rows:
        K = -(c * system.r[0])[None, :] + 0.0  # + 0.0: no signed zeros in the gains
        ab = spectral_abscissa(NPlusMCharacteristic(system, K, 0.0), region)
        m = nplusm_delay_margin(system, K)
        out.append(
            CancellationCase(tuple(map(float, c)), tuple(map(float, K[0])), m.gamma_0, float(ab.value), ab.certified, m)
        )
    return tuple(out)
