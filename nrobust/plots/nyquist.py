"""Nyquist plots of neutral loops: the loop, its crossings of the unit circle, the certified count.

Nyquist plots of neutral loops need care: ``L(i w) = B(i w)/A(i w) e^{-i w delta}`` does
not decay as ``w`` grows, so the classical encirclement count (python-control's, which
closes the contour at infinity assuming ``L -> 0``) does not apply. The count given here,
``rhp_zeros``, is certified: the number of zeros of ``F = A + B e^{-delta s}`` (the
closed-loop characteristic function) in ``Re s > 0``, the one count the margins and the
certificate use (:func:`nrobust.margins.unstable_count`: the argument principle with a
certified step on the rectangle ``0 <= Re s <= R``, ``|Im s| <= R`` outside which
:func:`nrobust.bounds.root_free_region` proves ``F`` zero-free on ``Re s >= 0``). That
bound needs the principal part ``D`` of ``F`` (a difference operator) strongly stable,
``C_D < 0``: then ``|F - s^n D| < |s^n D|`` for ``|s| > R``. Otherwise no count is given
(``None``, with a ``note``): advanced type (the ``s^n`` terms miss the smallest delay:
chains of zeros go to ``Re s = +inf``), ``c_D >= 0`` (infinitely many zeros in, or
accumulating at, the closed right half-plane), or ``c_D < 0 <= C_D`` (finitely many
zeros, but no root-free bound on ``Re s >= 0`` to count them in a bounded box); also when
a zero lies on the imaginary axis or the count exceeds its work bound.

The crossings (``|L(i w)| = 1``) are those of the certified search of
:mod:`nrobust.margins` (:func:`nrobust.margins.crossing_frequencies`, the search
:func:`nrobust.margins.delay_margin` and the certificate use), kept on the plotted band
``0 < w <= omega_max``. Where no finite frequency bound exists (the principal part of the
loop not strongly stable for small delays: crossings accumulate at infinity), the same
search runs on the plotted band only.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .._json import json_safe
from .._validate import nonnegative, positive, positive_int, renamed_keywords
from ..bounds import root_free_region
from ..errors import CertificationError, ParameterError
from ..margins import frequency_bound, unstable_count
from ..margins.crossing import crossing_search
from ..quasipoly import QuasiPolynomial, as_quasipolynomial
from .base import NrobustPlot, get_axes

if TYPE_CHECKING:
    from matplotlib.axes import Axes


__all__ = ["NyquistResponse", "nyquist_plot", "nyquist_response"]

# Work bound on the initial frequency grid of nyquist_response.
_MAX_FREQ = 10**6
# Work bound on the evaluations of the crossing search (that of crossing_frequencies).
_MAX_CROSSING_EVALS = 2_000_000
# At most this many crossing frequencies are written on a Nyquist plot (the lowest, spread out).
_MAX_CROSSING_LABELS = 6


@dataclass(frozen=True, eq=False)
class NyquistResponse:
    """The loop ``L(i w) = B(i w)/A(i w) e^{-i w delta}`` and its closed-loop count.

    Attributes
    ----------
    omega : ndarray
        Frequencies ``0 <= w <= omega_max`` of the plotted branch.
    loop : ndarray
        ``L(i omega)``.
    delta : float
        The loop delay.
    crossings : ndarray
        Frequencies ``0 < w <= omega_max`` where ``|L(i w)| = 1`` (``|A| = |B|``): the only
        frequencies at which a root can cross the imaginary axis as ``delta`` varies. From
        the certified crossing search of :mod:`nrobust.margins` (module notes): every
        crossing in the band, tangencies included; empty when the search is not certified
        (``crossing_note`` says why).
    crossing_values : ndarray
        ``L(i w)`` at the crossing frequencies (on the unit circle).
    principal_bound : float
        Upper bound of the spectral bound ``c_D`` of the closed-loop difference operator
        (``inf`` for an advanced-type loop).
    rhp_zeros : int or None
        Certified number of zeros of ``F = A + B e^{-delta s}`` in ``Re s > 0``, with
        multiplicity (see the module notes); None when no finite count exists (advanced
        type, ``c_D >= 0``) or none is certified (``c_D < 0 <= C_D``, a zero on the
        imaginary axis, the work bound of the count); ``note`` says which.
    count_region : tuple of float or None
        The rectangle ``(0, R, -R, R)`` counted by :func:`nrobust.margins.unstable_count`;
        :func:`nrobust.bounds.root_free_region` proves ``F`` zero-free on ``Re s >= 0``
        outside it. None when no count was made (or none was needed: ``F`` zero-free on
        ``Re s > c`` with ``c < 0``).
    note : str
        Why ``rhp_zeros`` is None, or ``""``.
    crossing_note : str
        Why ``crossings`` is empty although the loop may have crossings (the crossing
        search not certified), or ``""``.
    """

    omega: NDArray[np.float64]
    loop: NDArray[np.complex128]
    delta: float
    crossings: NDArray[np.float64]
    crossing_values: NDArray[np.complex128]
    principal_bound: float
    rhp_zeros: int | None
    count_region: tuple[float, float, float, float] | None
    note: str
    crossing_note: str = ""

    def plot(self, ax: Axes | None = None, unit_circle: bool = True) -> NrobustPlot:
        """Draw the loop, its mirror image, ``-1``, the unit circle and the crossings.

        ``lines["labels"]`` holds the frequency labels of the crossings: the lowest
        frequencies first, at most six, none closer to another than 12 % of the plot's
        width (the others are marked, not labelled).
        """
        ax = get_axes(ax)
        lines: dict[str, list[Any]] = {}
        lines["loop"] = ax.plot(self.loop.real, self.loop.imag, "-", color="C0", label=f"L(iw), delta={self.delta:g}")
        lines["mirror"] = ax.plot(
            self.loop.real, -self.loop.imag, "--", color="C0", alpha=0.5, label="L(-iw), mirror image"
        )
        if unit_circle:
            th = np.linspace(0.0, 2 * np.pi, 361)
            lines["unit_circle"] = ax.plot(np.cos(th), np.sin(th), ":", color="0.5", label="|L| = 1")
        lines["critical"] = ax.plot([-1.0], [0.0], "r+", markersize=12, label="-1")
        lines["labels"] = []
        if self.crossings.size:
            a_b = self.crossing_values
            lines["crossings"] = ax.plot(
                a_b.real, a_b.imag, "o", color="C3", ms=4, label=f"{a_b.size} crossings |L| = 1 (labels: w)"
            )
            # label the lowest frequencies first, skipping a point too close to a labelled one
            span = max(float(np.ptp(self.loop.real[np.isfinite(self.loop)])), 2.0)
            placed: list[complex] = []
            for w, p in zip(self.crossings, a_b):
                if not np.isfinite(p):  # a common zero of A and B: L = B/A is undefined there
                    continue
                if len(placed) < _MAX_CROSSING_LABELS and all(abs(p - q) > 0.12 * span for q in placed):
                    placed.append(p)
                    lines["labels"].append(
                        ax.annotate(f"{w:.3g}", (p.real, p.imag), textcoords="offset points", xytext=(4, 4), fontsize=7)
                    )
        else:
            lines["crossings"] = []
        count = "no finite count" if self.rhp_zeros is None else f"{self.rhp_zeros} closed-loop zeros in Re s > 0"
        ax.set_title(f"Nyquist, {count}", fontsize="small")
        ax.set_xlabel("Re L")
        ax.set_ylabel("Im L")
        ax.set_aspect("equal", adjustable="datalim")
        ax.axhline(0.0, color="0.8", lw=0.5)
        ax.axvline(0.0, color="0.8", lw=0.5)
        ax.legend(fontsize="x-small", loc="best")
        return NrobustPlot(lines, ax, ax.figure)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (the sampled loop is left out; infinities as strings)."""
        return json_safe(
            {
                "delta": self.delta,
                "omega_max": self.omega[-1],
                "crossings": self.crossings,
                "principal_bound": self.principal_bound,
                "rhp_zeros": self.rhp_zeros,
                "count_region": self.count_region,
                "note": self.note,
                "crossing_note": self.crossing_note,
            }
        )


@renamed_keywords(n="n_freq")
def nyquist_response(
    A: QuasiPolynomial,
    B: QuasiPolynomial,
    delta: float = 0.0,
    omega_max: float = 200.0,
    n_freq: int = 4001,
    principal_bound: float | None = None,
) -> NyquistResponse:
    """Compute the Nyquist data of the loop ``L = B/A e^{-delta s}`` and the certified
    number of closed-loop zeros in ``Re s > 0``.

    Parameters
    ----------
    A, B : QuasiPolynomial or number
        The loop factors, ``F(s) = A(s) + B(s) e^{-delta s}`` (e.g. from
        :func:`nrobust.hyperbolic.loop_factors`; for U_BS2 ``F`` is the characteristic
        function of the paper's eq. (60)). ``A`` must not vanish
        identically (``L = B/A``).
    delta : float
        Loop delay ``>= 0``.
    omega_max : float
        Upper end ``W`` of the plotted frequency band (the count does not depend on it).
    n_freq : int, default 4001
        Initial number of frequency samples on ``[0, W]``, in ``[16, 10**6]`` (refined
        where the curve moves fast; formerly ``n``, a deprecated alias).
    principal_bound : float, optional
        An upper bound of the spectral bound ``c_D`` of the difference operator of
        ``F = A + B e^{-delta s}`` computed elsewhere (e.g.
        ``Certificate.principal_delayed.spectral_bound``); by default it is computed here.

    Returns
    -------
    NyquistResponse
        See the module notes for how ``rhp_zeros`` is certified, and when it is None.

    Raises
    ------
    ParameterError
        Bad input; ``A`` identically zero, or ``F`` identically zero (``B = -A`` at
        ``delta = 0``).
    """
    A = as_quasipolynomial("A", A)
    B = as_quasipolynomial("B", B)
    if not A.point_terms and not A.distributed:
        raise ParameterError("A", "not identically zero (the loop is B/A)", A)
    delta = nonnegative("delta", delta)
    W = positive("omega_max", omega_max)
    w = np.linspace(0.0, W, positive_int("n_freq", n_freq, 16, maximum=_MAX_FREQ))
    F = A + B.shift(delta)
    if not F.point_terms and not F.distributed:
        raise ParameterError("B", "not -A at delta = 0 (F = A + B would vanish identically)", B)
    crossings, crossing_note = _band_crossings(A, B, W)

    def L(s: NDArray) -> NDArray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return B(s) / A(s) * np.exp(-s * delta)

    w, loop = _refine_curve(L, w)
    bound, rhp, box, note = _rhp_count(F, principal_bound)
    return NyquistResponse(w, loop, delta, crossings, L(1j * crossings), bound, rhp, box, note, crossing_note)


def _rhp_count(
    F: QuasiPolynomial, principal_bound: float | None
) -> tuple[float, int | None, tuple[float, float, float, float] | None, str]:
    """``(c_D bound, zeros in Re s > 0 or None, rectangle counted or None, note)`` for ``F``."""
    if F.kind == "advanced":
        return np.inf, None, None, "advanced type (the s^n terms miss the smallest delay): no finite count"
    D = F.principal_part()
    strong = float(D.strong_spectral_bound())  # C_D >= c_D, cheap
    if principal_bound is not None:
        bound = float(principal_bound)
    else:
        bound = strong if strong < 0.0 else float(D.spectral_bound().upper)
    if bound >= 0.0:
        return bound, None, None, f"the principal part has spectral bound {bound:.6g} >= 0: no finite count in Re s > 0"
    if strong >= 0.0:
        return (
            bound,
            None,
            None,
            f"the principal part is stable (c_D <= {bound:.6g}) but not strongly stable (C_D = {strong:.6g}): "
            "finitely many zeros in Re s > 0, not certified here",
        )
    try:
        free = root_free_region(F, 0.0)
        if free.half_plane < 0.0:  # no zero in Re s > c, c < 0
            return bound, 0, None, ""
        count = unstable_count(F, free.radius)  # the certificate's count of zeros in Re s > 0
    except CertificationError as exc:
        return bound, None, None, f"count not certified: {exc}"
    except ParameterError as exc:  # C_D < 0 by a rounding: no positive dominance gap on Re s >= 0
        if exc.name != "x0":
            raise
        return bound, None, None, f"the principal part is not strongly stable to rounding (C_D = {strong:.6g})"
    if count.count is None:
        return bound, None, None, "F has a zero on or within rounding of the imaginary axis"
    return bound, count.count, count.region, ""


def _refine_curve(
    fun: Callable[[NDArray], NDArray], w: NDArray[np.float64], levels: int = 8
) -> tuple[NDArray, NDArray]:
    """Sample ``fun(i w)`` so that consecutive points are closer than 2 % of the curve's
    median modulus (or 0.02), halving the steps that are not, up to ``levels`` times."""
    vals = fun(1j * w)
    finite = np.isfinite(vals)
    scale = max(float(np.median(np.abs(vals[finite]))) if np.any(finite) else 1.0, 1.0)
    for _ in range(levels):
        jumps = np.abs(np.diff(vals))
        bad = np.flatnonzero(np.isfinite(jumps) & (jumps > 0.02 * scale))
        if bad.size == 0:
            break
        mids = 0.5 * (w[bad] + w[bad + 1])
        w = np.insert(w, bad + 1, mids)
        vals = np.insert(vals, bad + 1, fun(1j * mids))
    return w, vals


def _band_crossings(A: QuasiPolynomial, B: QuasiPolynomial, W: float) -> tuple[NDArray[np.float64], str]:
    """The crossing frequencies ``0 < w <= W`` of the certified search, and a note when there are none certified.

    With a frequency bound (:func:`nrobust.margins.frequency_bound`) the search is that of
    :func:`nrobust.margins.crossing_frequencies` (every crossing of the loop); without one
    it runs on ``[0, W]`` (the band plotted).
    """
    bound = frequency_bound(A, B)
    try:
        search = crossing_search(A, B, bound if bound is not None else (W, np.nan), _MAX_CROSSING_EVALS)[0]
    except CertificationError as exc:
        return np.zeros(0), f"crossings not certified: {exc}"
    w = search.omegas
    return w[(w > 0.0) & (w <= W)], ""


def nyquist_plot(
    A: QuasiPolynomial,
    B: QuasiPolynomial,
    delta: float = 0.0,
    omega_max: float = 200.0,
    ax: Axes | None = None,
) -> NrobustPlot:
    """Compute :func:`nyquist_response` and plot it (see :meth:`NyquistResponse.plot`)."""
    return nyquist_response(A, B, delta, omega_max).plot(ax=ax)
