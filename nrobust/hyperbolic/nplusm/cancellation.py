"""Partial cancellations ``K = -diag(c) R`` of the reflections of a one-actuator ``n + 1`` system.

The paper's conclusion (Section 5): cancelling every reflection (finite-time convergence)
doubles ``gamma_0`` of the delayed principal part, and is not delay-robust once it reaches 1.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..._json import fields_dict
from ..._validate import real_array
from ...errors import ParameterError
from ...roots import spectral_abscissa
from .characteristic import NPlusMCharacteristic
from .margin import NPlusMMargin, nplusm_delay_margin
from .system import NPlusMSystem

__all__ = ["CancellationCase", "cancellation_study"]


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
    abscissa_accuracy : float or None
        A bound of the abscissa's error (:attr:`nrobust.roots.SpectralAbscissa.accuracy`:
        proven, or a conservative estimate); None when not known.
    rigorous : bool
        True: the abscissa is proven in ball arithmetic, and the margin too when ``gamma_0 < 1``
        (:attr:`NPlusMMargin.rigorous`; the margin 0 of ``gamma_0 >= 1`` is decided in floating point).
    """

    fractions: tuple[float, ...]
    gain: tuple[float, ...]
    gamma_0: float
    abscissa: float
    abscissa_certified: bool
    margin: NPlusMMargin
    abscissa_accuracy: float | None = None
    rigorous: bool = False

    @property
    def robust(self) -> bool:
        """True if the delay-free loop is stable in ``region`` and the margin is positive."""
        return self.abscissa < 0 and self.margin.margin > 0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {**fields_dict(self), "robust": self.robust}


def cancellation_study(
    system: NPlusMSystem, cancellations: Any, region: tuple[float, float, float, float], *, rigorous: bool = False
) -> tuple[CancellationCase, ...]:
    """Delay robustness of the partial cancellations ``K = -diag(c) R`` of a one-actuator system.

    For each row ``c`` of ``cancellations`` (one fraction per ``u`` component): the exact
    ``gamma_0`` of the principal part with a loop delay, the certified spectral abscissa
    of the delay-free loop in ``region`` (:func:`~nrobust.roots.spectral_abscissa` on
    :class:`NPlusMCharacteristic`) and :func:`nplusm_delay_margin`. The paper's
    conclusion (Section 5) is that cancelling every reflection (finite-time convergence)
    is not delay-robust: full cancellation doubles ``gamma_0``. With ``rigorous=True`` the
    abscissae and the margins of the cases with ``gamma_0 < 1`` are proven in ball arithmetic for
    the PDE itself (``rigorous=True`` of both functions).
    """
    if system.m != 1:
        raise ParameterError("system", "one actuator (m = 1)", system.m)
    if not isinstance(rigorous, bool):
        raise ParameterError("rigorous", "True or False", rigorous)
    rows = real_array("cancellations", cancellations, ndim=2)
    if rows.shape[1] != system.n:
        raise ParameterError("cancellations", f"rows of {system.n} fractions", rows.shape)
    out = []
    for c in rows:
        K = -(c * system.r[0])[None, :] + 0.0  # + 0.0: no signed zeros in the gains
        F = NPlusMCharacteristic(system, K, 0.0)
        ab = spectral_abscissa(F, region, rigorous=rigorous)
        m = nplusm_delay_margin(system, K, rigorous=rigorous and F.gamma_0() < 1.0 - 1e-12)
        out.append(
            CancellationCase(
                tuple(map(float, c)),
                tuple(map(float, K[0])),
                m.gamma_0,
                float(ab.value),
                ab.certified,
                m,
                ab.accuracy,
                rigorous,
            )
        )
    return tuple(out)
