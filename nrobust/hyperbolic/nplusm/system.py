"""``n + m`` heterodirectional hyperbolic systems with constant coefficients: the plant and its loop.

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


The modules of this package: the plant and its loop matrix (``system``), the certified
characteristic function (``characteristic``), its compound form (``compound``), the delay
margins (``margin``), the partial cancellations (``cancellation``), the backstepping kernels
and the full-state controller (``kernels``); the simulation is
:func:`nrobust.hyperbolic.simulate.simulate_nplusm`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._json import fields_dict
from ..._validate import nonnegative, real_array
from ...errors import ParameterError
from ...matrix_difference import MatrixDifferenceOperator
from ..plants.hyperbolic2x2 import Hyperbolic2x2

__all__ = ["NPlusMSystem", "speed_groups"]


def _matrix(name: str, value: Any, shape: tuple[int, int]) -> NDArray[np.float64]:
    a = real_array(name, value, ndim=None)
    if a.shape != shape:
        raise ParameterError(name, f"a real matrix of shape {shape}", a.shape)
    return a


def speed_groups(speeds: NDArray[np.float64]) -> list[NDArray[np.intp]]:
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
        for g in speed_groups(self.lam):
            u_block[np.ix_(g, g)] = expm(sig[np.ix_(g, g)] / self.lam[g][0])
        v_block = np.zeros((self.m, self.m))
        for g in speed_groups(self.mu):
            v_block[np.ix_(g, g)] = expm(-sig[np.ix_(g + n, g + n)] / self.mu[g][0])
        terms = []
        for ga in speed_groups(self.lam):
            pa = np.zeros((n, n))
            pa[ga, ga] = 1.0
            for gb in speed_groups(self.mu):
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
