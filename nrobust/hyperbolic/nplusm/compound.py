"""The closed loop of an ``n + m`` system in compound form (Cauchy-Binet), bounded on ``Re s >= 0`` for any ``m``.

``det(M_0(s) + z M_1(s)) = sum_d z^d a_d^T exp(D_m(C) - s P_m) b`` with ``D_m(C)`` the
compound generator and ``P_m >= 0`` the compound rates (:mod:`nrobust.margins.matrix`):
the form :func:`~nrobust.hyperbolic.nplusm.multi_actuator_delay_margin` certifies with.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...difference import DifferenceOperator
from ...qpmatrix import FirstDerivative
from .characteristic import EXPM_ROUNDING, NPlusMCharacteristic, compound_loop
from .system import NPlusMSystem

__all__ = ["compound_characteristic", "compound_loop"]


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
        return np.asarray(EXPM_ROUNDING * self._bound(s, s, 0) * grow, dtype=float)

    def principal_part(self) -> DifferenceOperator:
        return self.F.principal_part()

    def far_field_holds(self, x: float, radius: float) -> bool:
        """:meth:`NPlusMCharacteristic.far_field_holds` (the same function): ``spectral_abscissa`` needs no region."""
        return self.F.far_field_holds(x, radius)

    def far_field_radius(self, x: float) -> float | None:
        """:meth:`NPlusMCharacteristic.far_field_radius` of the same function."""
        return self.F.far_field_radius(x)

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
    :mod:`nrobust.margins.matrix`): the same function, with derivative bounds that stay
    bounded on ``Re s >= 0`` for any ``m`` (the rates ``P_m`` are ``>= 0``), where the rows of
    the loop matrix grow like ``e^{s (1/mu_i - 1/mu_j)}``. A
    :class:`~nrobust.qpmatrix.CharacteristicFunction` for :func:`~nrobust.roots.count_roots`.
    """
    F = NPlusMCharacteristic(system, K, delta)
    dc, p, a, b = compound_loop(system, F.K)
    return _CompoundCharacteristic(F, dc, p, a, b)
