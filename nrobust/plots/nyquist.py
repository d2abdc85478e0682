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

Poles of the loop on the imaginary axis (the integrators ``s^k`` dividing ``A``, found exactly,
and, when ``A`` is a polynomial, its other zeros on the axis) are skirted as python-control's
``nyquist_response`` does: the contour goes round them on a small circle of radius
``indent_radius`` on the right (a quarter circle at ``s = 0`` for the branch ``w >= 0``), so
that the image closes at infinity with the right orientation. The plot clips the curve to a
circle of radius ``max_curve_magnitude`` (python-control's ``max_curve_magnitude``; the clipped
parts dashed and drawn slightly off the circle, ``max_curve_offset``, so that the branch and
its mirror image stay apart), puts arrows in the direction of increasing frequency, keeps the
critical point ``-1`` in view, and labels the crossings of the unit circle (the certified
ones) and of the negative real axis (located by sign changes of ``Im L`` on the sampled curve
and refined by Brent's method: labels only, used by no count).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .._bracket import illinois
from .._json import json_safe
from .._validate import nonnegative, positive, positive_int, renamed_keywords
from ..bounds import root_free_region
from ..errors import CertificationError, ParameterError
from ..lti.allmargin import loop_factors_of
from ..lti.pade import split_integrators
from ..margins import frequency_bound, unstable_count
from ..margins.crossing import crossing_search
from ..quasipoly import QuasiPolynomial, as_quasipolynomial
from .base import NrobustPlot, get_axes, legend_corner

if TYPE_CHECKING:
    from matplotlib.axes import Axes


__all__ = ["NyquistResponse", "nyquist_plot", "nyquist_response"]

#: Crossings of the negative real axis refined and labelled, the lowest frequencies first.
MAX_REAL_CROSSINGS = 32

# Work bound on the initial frequency grid of nyquist_response.
_MAX_FREQ = 10**6
# Work bound on the evaluations of the crossing search (that of crossing_frequencies).
_MAX_CROSSING_EVALS = 2_000_000
# At most this many crossing frequencies are written on a Nyquist plot (the lowest, spread out).
_MAX_CROSSING_LABELS = 6
# Points on the image of an indentation, per quarter turn of a pole's multiplicity.
_ARC_POINTS = 48
# The curve is refined where it moves fast as seen through z / max(1, |z| / _REFINE_RADIUS).
_REFINE_RADIUS = 20.0


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
    contour : ndarray or None
        The points ``s`` of the contour when it skirts poles on the imaginary axis
        (``omega`` is then ``Im s``); None when it is ``i omega``.
    axis_poles : ndarray
        Frequencies ``0 <= w < omega_max`` of the poles of ``L`` on the imaginary axis skirted.
    indent_radius : float
        Radius of the indentations (0 when there is none).
    real_crossings : ndarray
        Frequencies where ``L(i w)`` crosses the negative real axis (sign changes of ``Im L``
        on the samples, refined by Brent's method; for labels, used by no count).
    real_crossing_values : ndarray
        ``L`` there.
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
    contour: NDArray[np.complex128] | None = None
    axis_poles: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    indent_radius: float = 0.0
    real_crossings: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    real_crossing_values: NDArray[np.complex128] = field(default_factory=lambda: np.zeros(0, dtype=complex))

    def plot(
        self,
        ax: Axes | None = None,
        unit_circle: bool = True,
        max_curve_magnitude: float = 10.0,
        max_curve_offset: float = 0.02,
        arrows: int = 2,
    ) -> NrobustPlot:
        """Draw the loop, its mirror image, ``-1``, the unit circle and the crossings.

        Parameters
        ----------
        ax : matplotlib Axes, optional
        unit_circle : bool
            Draw ``|L| = 1``.
        max_curve_magnitude : float
            Radius ``R > 1`` of the clipping circle (default 10): a point with ``|L| > R`` is
            drawn at ``R L / |L|``, on a dash-dotted line (dotted for the mirror image) moved
            off the circle by at most ``max_curve_offset R`` (outwards for the branch,
            inwards for the mirror), so that the two stay apart where both are clipped.
        max_curve_offset : float
            In ``[0, 0.2]`` (default 0.02).
        arrows : int
            Arrows on each branch in the direction of increasing frequency (default 2,
            evenly spaced along the drawn curve), plus one on each clipped stretch.

        Notes
        -----
        ``lines`` holds ``"loop"`` and ``"mirror"`` (the parts with ``|L| <= R``, gaps where
        clipped), ``"clipped"`` and ``"clipped_mirror"`` (one line per clipped stretch),
        ``"arrows"`` (annotations), ``"critical"``, ``"unit_circle"``, ``"crossings"`` and
        ``"labels"`` (the frequency labels of the unit-circle crossings: the lowest
        frequencies first, at most six, none closer to another than 12 % of the drawn
        width; the others are marked, not labelled), ``"real_crossings"`` and
        ``"real_labels"`` (the crossings of the negative real axis). The axes' limits hold
        the drawn curve and ``-1``, so they stay within ``R (1 + max_curve_offset)``.
        """
        R = positive("max_curve_magnitude", max_curve_magnitude)
        if R <= 1.0:
            raise ParameterError("max_curve_magnitude", "> 1 (the critical point -1 must be inside)", R)
        offset = nonnegative("max_curve_offset", max_curve_offset)
        if offset > 0.2:
            raise ParameterError("max_curve_offset", "in [0, 0.2]", offset)
        n_arrows = positive_int("arrows", arrows, minimum=0, maximum=20)
        ax = get_axes(ax)
        lines: dict[str, list[Any]] = {}
        shown, clipped = _clip(self.loop, R)
        regular = np.where(clipped, np.nan, shown)
        lines["loop"] = ax.plot(regular.real, regular.imag, "-", color="C0", label=f"L(iw), delta={self.delta:g}")
        lines["mirror"] = ax.plot(
            regular.real, -regular.imag, "--", color="C0", alpha=0.5, label="L(-iw), mirror image"
        )
        branch, mirror = shown.copy(), np.conj(shown)
        lines["clipped"], lines["clipped_mirror"] = [], []
        for lo, hi in _runs(clipped):
            # the stretch with its unclipped neighbours, off the circle by offset R sin(pi t)
            sl = slice(max(lo - 1, 0), min(hi + 1, shown.size))
            ramp = offset * np.sin(np.pi * np.linspace(0.0, 1.0, sl.stop - sl.start))
            branch[sl] = shown[sl] * (1.0 + ramp)
            mirror[sl] = np.conj(shown[sl]) * (1.0 - ramp)
            label = f"clipped at |L| = {R:g}" if not lines["clipped"] else None
            lines["clipped"] += ax.plot(branch[sl].real, branch[sl].imag, "-.", color="C0", label=label)
            lines["clipped_mirror"] += ax.plot(mirror[sl].real, mirror[sl].imag, ":", color="C0", alpha=0.5)
        lines["arrows"] = _arrows(ax, branch, clipped, n_arrows, 1.0) + _arrows(
            ax, mirror[::-1], clipped[::-1], n_arrows, 0.5
        )
        if unit_circle:
            th = np.linspace(0.0, 2 * np.pi, 361)
            lines["unit_circle"] = ax.plot(np.cos(th), np.sin(th), ":", color="0.5", label="|L| = 1")
        lines["critical"] = ax.plot([-1.0], [0.0], "r+", markersize=12, mew=2, label="-1", zorder=5)
        finite = np.concatenate([branch[np.isfinite(branch)], mirror[np.isfinite(mirror)]])
        span = max(float(np.ptp(finite.real)) if finite.size else 0.0, 2.0)
        lines["labels"] = []
        if self.crossings.size:
            a_b = self.crossing_values
            lines["crossings"] = ax.plot(
                a_b.real, a_b.imag, "o", color="C3", ms=4, label=f"{a_b.size} crossings |L| = 1 (labels: w)"
            )
            lines["labels"] = _labels(ax, self.crossings, a_b, span, (4, 4))
        else:
            lines["crossings"] = []
        lines["real_labels"] = []
        if self.real_crossings.size:
            v = self.real_crossing_values
            lines["real_crossings"] = ax.plot(
                v.real, v.imag, "s", color="C2", ms=4, label=f"{v.size} crossings of Re L < 0 (labels: w)"
            )
            lines["real_labels"] = _labels(ax, self.real_crossings, v, span, (4, -10))
        else:
            lines["real_crossings"] = []
        count = "no finite count" if self.rhp_zeros is None else f"{self.rhp_zeros} closed-loop zeros in Re s > 0"
        ax.set_title(f"Nyquist, {count}", fontsize="small")
        ax.set_xlabel("Re L")
        ax.set_ylabel("Im L")
        _limits(ax, finite, unit_circle)
        ax.axhline(0.0, color="0.8", lw=0.5)
        ax.axvline(0.0, color="0.8", lw=0.5)
        ax.legend(fontsize="x-small", loc=legend_corner(ax))
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
                "axis_poles": self.axis_poles,
                "indent_radius": self.indent_radius,
                "real_crossings": self.real_crossings,
            }
        )


@renamed_keywords(n="n_freq")
def nyquist_response(
    A: Any,
    B: QuasiPolynomial | None = None,
    delta: float = 0.0,
    omega_max: float = 200.0,
    n_freq: int = 4001,
    principal_bound: float | None = None,
    indent_radius: float = 1e-4,
) -> NyquistResponse:
    """Compute the Nyquist data of the loop ``L = B/A e^{-delta s}`` and the certified
    number of closed-loop zeros in ``Re s > 0``.

    Parameters
    ----------
    A, B : QuasiPolynomial or number
        The loop factors, ``F(s) = A(s) + B(s) e^{-delta s}`` (e.g. from
        :func:`nrobust.hyperbolic.loop_factors`; for U_BS2 ``F`` is the characteristic
        function of the paper's eq. (60)). ``A`` must not vanish
        identically (``L = B/A``). Or a SISO loop transfer function ``L`` alone as ``A``
        (a ``DelayLTI``, a ``QuasiTransferFunction`` or a python-control system) and no
        ``B``: its factors ``L = N / D`` (:func:`nrobust.lti.loop_factors_of`) are ``B = N``,
        ``A = D``.
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
    indent_radius : float, default 1e-4
        Radius of the half circles (a quarter circle at ``s = 0``) on which the contour
        skirts the poles of ``L`` on the imaginary axis, on their right (python-control's
        ``indent_radius``); in ``(0, omega_max / 10]`` and below half the distance between
        two such poles. The count ``rhp_zeros`` does not depend on it.

    Returns
    -------
    NyquistResponse
        See the module notes for how ``rhp_zeros`` is certified, and when it is None.
        ``contour`` holds the points ``s`` of the contour when it skirts poles (``omega``
        is then ``Im s``), ``axis_poles`` the frequencies ``w >= 0`` of those poles.

    Raises
    ------
    ParameterError
        Bad input; ``A`` identically zero, or ``F`` identically zero (``B = -A`` at
        ``delta = 0``).
    """
    if B is None:
        if isinstance(A, (QuasiPolynomial, int, float)):
            raise ParameterError("B", "given with the factor A (or A a loop transfer function alone)", B)
        B, A = loop_factors_of(A)
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

    poles = _axis_poles(A, B, W)
    r = positive("indent_radius", indent_radius)
    gaps = np.diff(poles)
    if r > W / 10 or (gaps.size and r >= 0.5 * gaps.min()):
        raise ParameterError(
            "indent_radius", "in (0, omega_max / 10] and below half the distance between poles on the axis", r
        )
    if poles.size:
        contour, loop = _indented_contour(L, w, poles, r)
        w = contour.imag
    else:
        w, loop = _refine_curve(L, w)
        contour = None
    real_w, real_v = _real_axis_crossings(L, contour if contour is not None else 1j * w, loop)
    bound, rhp, box, note = _rhp_count(F, principal_bound)
    return NyquistResponse(
        w,
        loop,
        delta,
        crossings,
        L(1j * crossings),
        bound,
        rhp,
        box,
        note,
        crossing_note,
        contour,
        poles,
        r if poles.size else 0.0,
        real_w,
        real_v,
    )


def _axis_poles(A: QuasiPolynomial, B: QuasiPolynomial, W: float) -> NDArray[np.float64]:
    """Frequencies ``0 <= w < W`` of the poles of ``B/A`` on the imaginary axis.

    ``s = 0`` when ``A`` has more factors ``s`` than ``B`` (exact,
    :func:`nrobust.lti.pade.split_integrators`); the other zeros of ``A`` on the axis only when
    ``A`` is a polynomial (its roots within ``1e-9 (1 + |p|)`` of the axis, rounded onto it).
    """
    k_a, A1 = split_integrators(A)
    k_b = split_integrators(B)[0] if B.point_terms else 0
    poles = [0.0] if k_a > k_b else []
    if not A1.distributed and len(A1.point_terms) == 1 and A1.point_terms[0][1] == 0.0:
        c = np.asarray(A1.point_terms[0][0])
        if c.size > 1:
            roots = np.roots(c[::-1])
            on = roots[(np.abs(roots.real) <= 1e-9 * (1.0 + np.abs(roots))) & (roots.imag > 0.0)]
            poles += sorted({float(p.imag) for p in on if p.imag < W})
    return np.asarray(poles, dtype=float)


def _indented_contour(
    L: Callable[[NDArray], NDArray], w: NDArray[np.float64], poles: NDArray[np.float64], r: float
) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """The contour ``i [0, W]`` skirting each pole ``i p`` on its right at distance ``r``, and ``L`` on it.

    The axis pieces between the poles are refined as in :func:`_refine_curve`; the arcs,
    ``i p + r e^{i theta}`` (``theta`` from ``-pi/2``, or from 0 at ``p = 0``, to ``pi/2``), are
    sampled uniformly.
    """
    pieces_s: list[NDArray] = []
    pieces_l: list[NDArray] = []
    start = 0.0
    for p in poles:
        first = -0.5 * np.pi if p > 0.0 else 0.0
        if p > 0.0:
            _append_axis(L, w, start, p - r, pieces_s, pieces_l)
        theta = np.linspace(first, 0.5 * np.pi, 2 * _ARC_POINTS + 1 if p > 0.0 else _ARC_POINTS + 1)
        arc = 1j * p + r * np.exp(1j * theta)
        if p > 0.0:  # the axis piece ends at i (p - r) already
            arc = arc[1:]
        pieces_s.append(arc[:-1])
        pieces_l.append(L(arc[:-1]))
        start = p + r
    _append_axis(L, w, start, w[-1], pieces_s, pieces_l)
    return np.concatenate(pieces_s), np.concatenate(pieces_l)


def _append_axis(
    L: Callable[[NDArray], NDArray], w: NDArray[np.float64], lo: float, hi: float, out_s: list, out_l: list
) -> None:
    """Append ``i [lo, hi]`` (the samples of ``w`` inside, refined) and ``L`` on it."""
    inner = w[(w > lo) & (w < hi)]
    grid = np.concatenate([[lo], inner, [hi]])
    grid, vals = _refine_curve(L, grid)
    out_s.append(1j * grid)
    out_l.append(vals)


def _real_axis_crossings(
    L: Callable[[NDArray], NDArray], contour: NDArray, loop: NDArray
) -> tuple[NDArray[np.float64], NDArray[np.complex128]]:
    """Frequencies ``w > 0`` where ``L(i w)`` crosses the negative real axis, and ``L`` there.

    A sign change of ``Im L`` between consecutive samples on the axis with ``Re L < 0`` at
    both, refined by regula falsi (:func:`nrobust._bracket.illinois`) on ``Im L(i w)``: the
    first :data:`MAX_REAL_CROSSINGS` in frequency (they label the plot; a loop delay of 1e300 makes every sample one).
    """
    on_axis = (contour.real == 0.0) & np.isfinite(loop)
    im, re = loop.imag, loop.real
    pick = np.flatnonzero(
        on_axis[:-1] & on_axis[1:] & (re[:-1] < 0) & (re[1:] < 0) & (np.sign(im[:-1]) * np.sign(im[1:]) < 0)
    )[:MAX_REAL_CROSSINGS]
    w = illinois(lambda x: L(1j * x).imag, contour[pick].imag, contour[pick + 1].imag, im[pick], im[pick + 1])
    values = L(1j * w) if w.size else np.zeros(0, dtype=complex)
    keep = values.real < 0
    return w[keep], values[keep]


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
    median modulus (or 0.02), halving the steps that are not, up to ``levels`` times.

    Distances are measured on ``z / max(1, |z| / 20)``: far out, where the plot clips the
    curve, only its direction needs resolving."""
    vals = fun(1j * w)
    finite = np.isfinite(vals)
    scale = max(float(np.median(np.abs(_compress(vals[finite])))) if np.any(finite) else 1.0, 1.0)
    for _ in range(levels):
        jumps = np.abs(np.diff(_compress(vals)))
        bad = np.flatnonzero(np.isfinite(jumps) & (jumps > 0.02 * scale))
        if bad.size == 0:
            break
        mids = 0.5 * (w[bad] + w[bad + 1])
        w = np.insert(w, bad + 1, mids)
        vals = np.insert(vals, bad + 1, fun(1j * mids))
    return w, vals


def _compress(z: NDArray) -> NDArray:
    """``z / max(1, |z| / _REFINE_RADIUS)``: the curve as the refinement sees it."""
    with np.errstate(invalid="ignore"):
        return z / np.maximum(1.0, np.abs(z) / _REFINE_RADIUS)


def _clip(loop: NDArray[np.complex128], R: float) -> tuple[NDArray[np.complex128], NDArray[np.bool_]]:
    """``(shown, clipped)``: ``R L / |L|`` where ``|L| > R`` (flagged), ``L`` elsewhere; nan where not finite."""
    mag = np.abs(loop)
    clipped = np.isfinite(loop) & (mag > R)
    with np.errstate(invalid="ignore", divide="ignore"):
        shown = np.where(clipped, R * loop / mag, loop)
    shown = np.where(np.isfinite(loop), shown, np.nan)
    return shown, clipped


def _runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """``(start, stop)`` of each stretch of consecutive True entries."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))


def _arrows(ax: Axes, curve: NDArray[np.complex128], clipped: NDArray[np.bool_], n: int, alpha: float) -> list[Any]:
    """Arrows along ``curve`` in the direction of its samples: ``n`` evenly spaced by arc
    length, and one in the middle of each clipped stretch."""
    ok = np.isfinite(curve)
    seg = np.where(ok[:-1] & ok[1:], np.abs(np.diff(np.where(ok, curve, 0.0))), 0.0)
    length = np.concatenate([[0.0], np.cumsum(seg)])
    if length[-1] <= 0.0:
        return []
    at = [int(np.searchsorted(length, length[-1] * (i + 1) / (n + 1))) for i in range(n)]
    at += [(lo + hi) // 2 for lo, hi in _runs(clipped)]
    out = []
    for j in sorted(set(at)):
        j = min(max(j, 1), curve.size - 1)
        k = j - 1
        while k > 0 and (not (ok[k] and ok[j]) or curve[k] == curve[j]):
            k -= 1
        if not (ok[k] and ok[j]) or curve[k] == curve[j]:
            continue
        out.append(
            ax.annotate(
                "",
                xy=(curve[j].real, curve[j].imag),
                xytext=(curve[k].real, curve[k].imag),
                arrowprops={"arrowstyle": "-|>", "color": "C0", "alpha": alpha, "shrinkA": 0, "shrinkB": 0, "lw": 1},
            )
        )
    return out


def _labels(
    ax: Axes, freqs: NDArray[np.float64], points: NDArray[np.complex128], span: float, offset: tuple[int, int]
) -> list[Any]:
    """Frequency labels, the lowest first, at most six, none closer to another than 12 % of ``span``."""
    placed: list[complex] = []
    out = []
    for w, p in zip(freqs, points):
        if not np.isfinite(p):  # a common zero of A and B: L = B/A is undefined there
            continue
        if len(placed) < _MAX_CROSSING_LABELS and all(abs(p - q) > 0.12 * span for q in placed):
            placed.append(p)
            out.append(ax.annotate(f"{w:.3g}", (p.real, p.imag), textcoords="offset points", xytext=offset, fontsize=7))
    return out


def _limits(ax: Axes, drawn: NDArray[np.complex128], unit_circle: bool) -> None:
    """Limits holding the drawn curve, ``-1`` (and the unit circle), padded by 5 % of the larger
    side; equal scales by shaping the axes box, so the limits stay as set."""
    pts = np.concatenate([drawn, [-1.0 + 0j, 0j]])
    if unit_circle:
        pts = np.concatenate([pts, [1.0, 1j, -1j]])
    lo_x, hi_x = float(pts.real.min()), float(pts.real.max())
    lo_y, hi_y = float(pts.imag.min()), float(pts.imag.max())
    pad = 0.05 * max(hi_x - lo_x, hi_y - lo_y)
    ax.set_xlim(lo_x - pad, hi_x + pad)
    ax.set_ylim(lo_y - pad, hi_y + pad)
    ax.set_aspect("equal", adjustable="box")


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
    A: Any,
    B: QuasiPolynomial | None = None,
    delta: float = 0.0,
    omega_max: float = 200.0,
    ax: Axes | None = None,
    max_curve_magnitude: float = 10.0,
    max_curve_offset: float = 0.02,
    arrows: int = 2,
    indent_radius: float = 1e-4,
) -> NrobustPlot:
    """Compute :func:`nyquist_response` and plot it (see :meth:`NyquistResponse.plot`)."""
    return nyquist_response(A, B, delta, omega_max, indent_radius=indent_radius).plot(
        ax=ax, max_curve_magnitude=max_curve_magnitude, max_curve_offset=max_curve_offset, arrows=arrows
    )
