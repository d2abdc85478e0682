"""Bode plots of delayed loops: the exact frequency response, and every margin at its exact frequency.

A Padé model or a frequency grid (``control.bode_plot(L.to_frd(w))``) interpolates the
margins between samples; here the magnitude and the phase are the loop's own, ``L(i w) =
N(i w) / D(i w)`` evaluated on a logarithmic grid fine enough that the phase of the delays
(``w T`` for the longest delay ``T``) moves by at most ``pi / 8`` between samples, so that
its unwrapping follows the true phase; the crossovers are those of
:func:`nrobust.lti.allmargin` (proven complete on their bands, refined to ``1e-12``), drawn at
their frequencies and labelled with their margins.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .._json import json_safe
from .._validate import positive_int
from ..errors import CertificationError, ParameterError
from ..lti.allmargin import AllMargins, allmargin, loop_factors_of
from .base import NrobustPlot

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = ["BodeResponse", "bode_plot", "bode_response"]

#: Largest frequency grid of :func:`bode_response` (the work bound checked before any array is formed).
MAX_BODE_POINTS = 1_000_000
#: Phase advance of the delays between neighbouring samples, at most (radians).
_PHASE_STEP = math.pi / 8.0
#: Crossovers labelled per kind (the first ones in frequency).
_LABELS = 4


@dataclass(frozen=True, eq=False)
class BodeResponse:
    """The frequency response of a loop and its margins (:func:`bode_response`).

    Attributes
    ----------
    omega : ndarray
        Frequencies (rad per time unit), increasing, logarithmically spaced.
    magnitude : ndarray
        ``|L(i w)|``.
    phase : ndarray
        ``arg L(i w)`` in degrees, unwrapped along ``omega``.
    margins : AllMargins or None
        Every gain, phase and delay margin (:func:`nrobust.lti.allmargin`), or None when they
        could not be computed (``note`` says why).
    note : str
        Empty, or why there are no margins.
    """

    omega: NDArray[np.float64]
    magnitude: NDArray[np.float64]
    phase: NDArray[np.float64]
    margins: AllMargins | None
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (the sampled response is left out)."""
        return json_safe(
            {
                "omega_limits": [float(self.omega[0]), float(self.omega[-1])],
                "points": int(self.omega.size),
                "margins": None if self.margins is None else self.margins.to_dict(),
                "note": self.note,
            }
        )

    def plot(self, axes: tuple[Axes, Axes] | None = None) -> NrobustPlot:
        """Magnitude (dB) above phase (degrees) on a log frequency axis, the crossovers marked.

        Each gain crossover (``|L| = 1``) is marked on both panels with its phase margin, each
        phase crossover (``L < 0`` real) with its gain margin (the first :data:`_LABELS` of each
        labelled). ``axes``: the magnitude and phase Axes (by default a new figure). Returns a
        :class:`NrobustPlot` on the magnitude Axes with ``lines["magnitude"]``,
        ``lines["phase"]``, ``lines["gain_crossovers"]``, ``lines["phase_crossovers"]`` and
        ``lines["phase_axes"]`` (the phase Axes).
        """
        if axes is None:
            import matplotlib.pyplot as plt

            _, (ax_mag, ax_ph) = plt.subplots(2, 1, sharex=True, figsize=(6.4, 5.6))
        else:
            ax_mag, ax_ph = axes
        db = 20.0 * np.log10(np.maximum(self.magnitude, np.finfo(float).tiny))
        lines: dict[str, list[Any]] = {"gain_crossovers": [], "phase_crossovers": [], "phase_axes": [ax_ph]}
        lines["magnitude"] = ax_mag.semilogx(self.omega, db, color="C0")
        lines["phase"] = ax_ph.semilogx(self.omega, self.phase, color="C0")
        ax_mag.axhline(0.0, color="0.6", lw=0.8)
        m = self.margins
        lo, hi = float(self.omega[0]), float(self.omega[-1])
        if m is not None:
            marks = (
                ("gain_crossovers", m.pm_frequencies, m.phase_margins, "PM {:.4g} deg", ("C2", "--")),
                ("phase_crossovers", m.gm_frequencies, m.gain_margins, "GM {:.4g}", ("C3", ":")),
            )
            for key, freqs, values, text, (color, style) in marks:
                for k, (w, v) in enumerate(zip(freqs, values)):
                    if not lo <= w <= hi:
                        continue
                    label = f"{text.format(v)} at w = {w:.4g}" if k < _LABELS else None
                    for ax in (ax_mag, ax_ph):  # the label once, on the magnitude panel's legend
                        lines[key].append(ax.axvline(w, color=color, lw=0.9, ls=style, label=label))
                        label = None
        ax_mag.set_ylabel("|L(i w)| (dB)")
        ax_ph.set_ylabel("arg L(i w) (deg)")
        ax_ph.set_xlabel("w (rad per time unit)")
        ax_mag.grid(True, which="major", alpha=0.3)
        ax_ph.grid(True, which="major", alpha=0.3)
        if lines["gain_crossovers"] or lines["phase_crossovers"]:
            ax_mag.legend(fontsize="x-small", loc="best")
        elif self.note:
            ax_mag.text(0.01, 0.02, self.note, transform=ax_mag.transAxes, fontsize=7, color="0.35")
        return NrobustPlot(lines, ax_mag, ax_mag.figure)


def bode_response(
    L: Any, omega_limits: tuple[float, float] | None = None, points_per_decade: int = 200, margins: bool = True
) -> BodeResponse:
    """The exact frequency response of a SISO loop and its margins, for :meth:`BodeResponse.plot`.

    Parameters
    ----------
    L : DelayLTI, QuasiTransferFunction or python-control system
        The loop (SISO, :func:`nrobust.lti.loop_factors_of`).
    omega_limits : (float, float), optional
        ``0 < w_min < w_max``. By default a decade below the first crossover of the margins and
        one above the last listed (``[0.01, 100]`` without any).
    points_per_decade : int, default 200
        At least this many; more where the delays' phase would move by more than ``pi / 8``
        between samples (the grid is checked against :data:`MAX_BODE_POINTS` first).
    margins : bool, default True
        Compute :func:`nrobust.lti.allmargin` (its refusal, e.g. a loop whose gain does not
        fall below 1 at high frequency, leaves ``margins`` None and says why in ``note``).

    Returns
    -------
    BodeResponse

    Examples
    --------
    >>> from nrobust.lti import delay, tf
    >>> r = bode_response(2.0 * delay(0.1) * tf([1.0], [1.0, 1.0]))   # 2 e^{-0.1 s} / (s + 1)
    >>> round(float(r.margins.pm_frequencies[0]) ** 2, 9)             # |L(i w)| = 1 at w = sqrt 3
    3.0
    """
    N, D = loop_factors_of(L)
    points_per_decade = positive_int("points_per_decade", points_per_decade, minimum=10)
    found: AllMargins | None = None
    note = ""
    if margins:
        try:
            found = allmargin(L)
        except (ParameterError, CertificationError) as exc:
            note = f"no margins: {exc}"
    if omega_limits is None:
        marks = [] if found is None else [*found.pm_frequencies[:_LABELS], *found.gm_frequencies[:_LABELS]]
        marks = [float(w) for w in marks if np.isfinite(w) and w > 0.0]
        w_lo, w_hi = (min(marks) / 10.0, max(marks) * 10.0) if marks else (0.01, 100.0)
    else:
        try:
            w_lo, w_hi = (float(v) for v in omega_limits)
        except (TypeError, ValueError) as exc:
            raise ParameterError("omega_limits", "a pair (w_min, w_max) with 0 < w_min < w_max", omega_limits) from exc
        if not (0.0 < w_lo < w_hi < math.inf):
            raise ParameterError("omega_limits", "a pair (w_min, w_max) with 0 < w_min < w_max", omega_limits)
    decades = math.log10(w_hi / w_lo)
    T = float(N.max_delay + D.max_delay)
    # ratio r between samples: (r - 1) w_max T <= pi / 8 at the top of the band
    per_decade = points_per_decade
    if T > 0.0:
        per_decade = max(per_decade, math.ceil(1.0 / math.log10(1.0 + _PHASE_STEP / (w_hi * T))))
    n = math.ceil(decades * per_decade) + 1
    if n > MAX_BODE_POINTS:
        raise ParameterError(
            "omega_limits",
            f"a band whose delays' phase needs at most MAX_BODE_POINTS = {MAX_BODE_POINTS} samples (here {n})",
            (w_lo, w_hi),
        )
    w = np.logspace(math.log10(w_lo), math.log10(w_hi), n)
    s = 1j * w
    with np.errstate(divide="ignore", invalid="ignore"):
        values = N(s) / D(s)
    if not np.all(np.isfinite(values)):
        where = float(w[~np.isfinite(values)][0])
        raise ParameterError("L", f"a loop without poles on the band's imaginary axis (one near w = {where:.6g})", L)
    phase = np.degrees(np.unwrap(np.angle(values)))
    return BodeResponse(w, np.abs(values), phase, found, note)


def bode_plot(
    L: Any,
    omega_limits: tuple[float, float] | None = None,
    axes: tuple[Axes, Axes] | None = None,
    margins: bool = True,
) -> NrobustPlot:
    """Compute :func:`bode_response` and plot it (:meth:`BodeResponse.plot`)."""
    return bode_response(L, omega_limits, margins=margins).plot(axes=axes)
