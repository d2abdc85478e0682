"""Plots of delay-robustness analyses: compute, then plot.

Every figure has two halves, as in python-control: a ``*_response`` function computes a
small frozen data object (JSON-ready through ``to_dict()``) and the object's ``plot``
method (or the ``*_plot`` wrapper) draws it on a matplotlib ``Axes``. Every plot accepts
``ax=`` and returns a :class:`NrobustPlot` holding the artists it drew, keyed by what
they show, so that a test or a user can check and restyle them.

Nyquist plots of neutral loops need care: ``L(i w) = B(i w)/A(i w) e^{-i w delta}`` does
not decay as ``w`` grows, so the classical encirclement count (python-control's, which
closes the contour at infinity assuming ``L -> 0``) does not apply. The count given here,
``rhp_zeros``, is certified: the number of zeros of ``F = A + B e^{-delta s}`` (the
closed-loop characteristic function) in ``Re s > 0`` by the argument principle
(:func:`nrobust.roots.count_roots`, a winding of ``F`` with a certified step) on the
rectangle ``0 <= Re s <= c``, ``|Im s| <= R`` outside which
:func:`nrobust.bounds.root_free_region` proves ``F`` zero-free on ``Re s >= 0``. That
bound needs the principal part ``D`` of ``F`` (a difference operator) strongly stable,
``C_D < 0``: then ``|F - s^n D| < |s^n D|`` for ``|s| > R``. Otherwise no count is given
(``None``, with a ``note``): advanced type (the ``s^n`` terms miss the smallest delay:
chains of zeros go to ``Re s = +inf``), ``c_D >= 0`` (infinitely many zeros in, or
accumulating at, the closed right half-plane), or ``c_D < 0 <= C_D`` (finitely many
zeros, but no root-free bound on ``Re s >= 0`` to count them in a bounded box); also when
a zero lies on the imaginary axis or the count exceeds its work bound.
"""

from __future__ import annotations

import textwrap
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._json import fields_dict, json_safe
from .._progress import progress_bar
from .._validate import nonnegative, number_array, positive, positive_int, renamed_keywords
from .._validate import region as check_region
from ..bounds import root_free_region
from ..errors import CertificationError, ParameterError
from ..quasipoly import QuasiPolynomial, as_quasipolynomial
from ..roots import RootSet, SpectralAbscissa, count_roots, find_roots, spectral_abscissa
from ..sweeps.engine import SweepResult

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure, SubFigure

# Work bound on the initial frequency grid of nyquist_response.
_MAX_FREQ = 10**6
# At most this many crossing frequencies are written on a Nyquist plot (the lowest, spread out).
_MAX_CROSSING_LABELS = 6

__all__ = [
    "NrobustPlot",
    "NyquistResponse",
    "nyquist_response",
    "nyquist_plot",
    "root_map_region",
    "root_map_plot",
    "HiddenUnstableRoots",
    "hidden_unstable_roots",
    "RootLocusData",
    "root_locus_response",
    "root_locus_plot",
    "residual_floor",
    "simulation_plot",
    "stability_chart_plot",
    "tradeoff_plot",
    "sweep_chart",
    "simulation_figure",
]


@dataclass(frozen=True, eq=False)
class NrobustPlot:
    """What a plot function drew.

    Attributes
    ----------
    lines : dict of str to list of matplotlib artists
        The artists, keyed by what they show (``"loop"``, ``"roots"``, ``"chains"``...).
    axes : matplotlib.axes.Axes
        The Axes drawn on.
    figure : matplotlib.figure.Figure
        Its figure.
    """

    lines: dict[str, list[Any]]
    axes: Axes
    figure: Figure | SubFigure


def _get_ax(ax: Axes | None) -> Axes:
    if ax is not None:
        return ax
    import matplotlib.pyplot as plt

    _, ax = plt.subplots()
    return ax


# ---------------------------------------------------------------------- Nyquist
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
        Frequencies ``w > 0`` where ``|L(i w)| = 1`` (``|A| = |B|``): the only frequencies
        at which a root can cross the imaginary axis as ``delta`` varies.
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
        The rectangle ``(0, c, -R, R)`` counted by :func:`nrobust.roots.count_roots`;
        :func:`nrobust.bounds.root_free_region` proves ``F`` zero-free on ``Re s >= 0``
        outside it. None when no count was made (or none was needed: ``F`` zero-free on
        ``Re s > c`` with ``c < 0``).
    note : str
        Why ``rhp_zeros`` is None, or ``""``.
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

    def plot(self, ax: Axes | None = None, unit_circle: bool = True) -> NrobustPlot:
        """Draw the loop, its mirror image, ``-1``, the unit circle and the crossings.

        ``lines["labels"]`` holds the frequency labels of the crossings: the lowest
        frequencies first, at most six, none closer to another than 12 % of the plot's
        width (the others are marked, not labelled).
        """
        ax = _get_ax(ax)
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
    a_w = A(1j * w)
    b_w = B(1j * w)
    crossings = _crossings(A, B, w, np.abs(a_w) - np.abs(b_w))

    def L(s: NDArray) -> NDArray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return B(s) / A(s) * np.exp(-s * delta)

    w, loop = _refine_curve(L, w)
    bound, rhp, box, note = _rhp_count(F, principal_bound)
    return NyquistResponse(w, loop, delta, crossings, L(1j * crossings), bound, rhp, box, note)


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
        pad = 1e-6 * (1.0 + free.radius)
        box = (0.0, free.half_plane + pad, -(free.radius + pad), free.radius + pad)
        count = count_roots(F, box)
    except CertificationError as exc:
        return bound, None, None, f"count not certified: {exc}"
    except ParameterError as exc:  # C_D < 0 by a rounding: no positive dominance gap on Re s >= 0
        if exc.name != "x0":
            raise
        return bound, None, None, f"the principal part is not strongly stable to rounding (C_D = {strong:.6g})"
    if count.region[0] < 0.0:
        return bound, None, None, "F has a zero on or within rounding of the imaginary axis"
    return bound, int(count), count.region, ""


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


def _crossings(A: QuasiPolynomial, B: QuasiPolynomial, w: NDArray, gap: NDArray) -> NDArray[np.float64]:
    """Zeros of ``|A(i w)| - |B(i w)|`` on ``w > 0``: sign changes of the samples, then
    bisection of all brackets at once (48 halvings: the bracket shrinks below 1e-14 of
    the sampling step)."""
    idx = np.flatnonzero((np.sign(gap[1:]) * np.sign(gap[:-1]) < 0) & (w[1:] > 0))
    lo, hi = w[idx].astype(float), w[idx + 1].astype(float)
    g_lo = gap[idx]
    for _ in range(48):
        if lo.size == 0:
            break
        mid = 0.5 * (lo + hi)
        g_mid = np.abs(A(1j * mid)) - np.abs(B(1j * mid))
        left = np.sign(g_mid) == np.sign(g_lo)
        lo, g_lo = np.where(left, mid, lo), np.where(left, g_mid, g_lo)
        hi = np.where(left, hi, mid)
    exact = [float(x) for x, g in zip(w, gap) if g == 0.0 and x > 0]
    return np.array(sorted(list(0.5 * (lo + hi)) + exact))


def nyquist_plot(
    A: QuasiPolynomial,
    B: QuasiPolynomial,
    delta: float = 0.0,
    omega_max: float = 200.0,
    ax: Axes | None = None,
) -> NrobustPlot:
    """Compute :func:`nyquist_response` and plot it (see :meth:`NyquistResponse.plot`)."""
    return nyquist_response(A, B, delta, omega_max).plot(ax=ax)


# ---------------------------------------------------------------------- root map
#: The base rectangle of a root map, in units of ``1/T`` (``T`` the largest delay of ``F``).
_BASE_REGION = (-3.0, 1.0, -40.0, 40.0)
#: Work bound of a default root map: about this many roots at most (see root_map_region).
_MAX_MAP_ROOTS = 600


def root_map_region(
    F: QuasiPolynomial,
    base: tuple[float, float, float, float] | None = None,
    abscissa: SpectralAbscissa | None = None,
    max_roots: int = _MAX_MAP_ROOTS,
) -> tuple[float, float, float, float]:
    """A rectangle for a root map of ``F`` that holds its rightmost roots.

    The rectangle is the smallest one containing ``base`` (default
    ``(-3, 1, -40, 40) / T``, ``T`` the largest delay of ``F``), the rightmost root of
    ``F`` (:func:`nrobust.roots.spectral_abscissa`) and the first root of the rightmost
    chain of the principal part (:meth:`nrobust.difference.DifferenceOperator.chains`:
    for a neutral ``F`` the high-frequency roots approach it), each with a margin of
    ``0.5 / T`` in ``Re s`` and ``10 / T`` in ``Im s``. An unstable root of an open loop
    (``+0.923`` for the paper's plant) or of a loop destabilised by a small delay (the
    U_BS chains at ``Im s ~ 311`` for ``delta = 0.01``) is therefore on the map, unless
    it lies above the height bound ``max_roots``; :func:`root_map_plot` then says so on
    the figure. When the chains are not resolved (delays not commensurate within the
    degree bound), the real range holds the upper end of their abscissa's bracket.

    Parameters
    ----------
    F : QuasiPolynomial
    base : tuple of float, optional
        ``(re_min, re_max, im_min, im_max)`` always contained in the result.
    abscissa : SpectralAbscissa, optional
        The spectral abscissa of ``F`` if already computed; by default it is computed here,
        its band near the chains no higher than the map can reach (``max_roots``; when
        that fails, only the chains and ``base`` are used).
    max_roots : int
        Work bound: the widening in height stops where the map would hold about
        ``max_roots`` roots (``|Im s| T / pi`` roots per unit of ``Re s`` width, the density
        of the chains); the chains above it still show as their asymptotes.

    Returns
    -------
    tuple of float
        ``(re_min, re_max, im_min, im_max)``.
    """
    F = as_quasipolynomial("F", F)
    max_roots = positive_int("max_roots", max_roots)
    T = float(F.max_delay) if F.max_delay > 0 else 1.0
    base_box = check_region(base) if base is not None else tuple(v / T for v in _BASE_REGION)
    box = list(base_box)
    points: list[complex] = []
    if abscissa is None and F.kind != "advanced":
        try:
            # roots above the height the map can hold are not drawn: search no higher
            reach = max(abs(base_box[2]), abs(base_box[3]), max_roots * np.pi / T)
            abscissa = spectral_abscissa(F, im_max=reach)
        except CertificationError:
            abscissa = None
    if abscissa is not None and abscissa.root is not None:
        points.append(complex(abscissa.root))
    if F.is_neutral:
        found = F.principal_part().chains()
        if found.chains:
            top = max(found.chains, key=lambda c: c.real)
            first = (top.offset + 0.5 * top.spacing) % top.spacing - 0.5 * top.spacing
            points.append(complex(top.real, abs(first)))
        elif np.isfinite(found.bracket[1]):  # chains not resolved: their abscissa's upper bound in Re s
            box[0] = min(box[0], found.bracket[1] - 0.5 / T)
            box[1] = max(box[1], found.bracket[1] + 0.5 / T)
    for z in points:
        box[0] = min(box[0], z.real - 0.5 / T)
        box[1] = max(box[1], z.real + 0.5 / T)
        box[2] = min(box[2], -abs(z.imag) - 10.0 / T if F.is_real else z.imag - 10.0 / T)
        box[3] = max(box[3], abs(z.imag) + 10.0 / T if F.is_real else z.imag + 10.0 / T)
    height = max_roots * np.pi / (T * max(1.0, box[1] - box[0]))
    box[2], box[3] = min(base_box[2], max(box[2], -height)), max(base_box[3], min(box[3], height))
    return (float(box[0]), float(box[1]), float(box[2]), float(box[3]))


def root_map_plot(
    F: QuasiPolynomial,
    region: tuple[float, float, float, float] | None = None,
    roots: RootSet | ArrayLike | None = None,
    ax: Axes | None = None,
    chains: bool | Sequence[float] = True,
    max_chains: int = 12,
) -> NrobustPlot:
    """Roots of ``F`` in a rectangle, the chain asymptotes of its principal part, the axis.

    Roots in ``Re s > 0`` (unstable) are circled in red and counted in the legend; chain
    asymptotes in ``Re s >= 0`` are drawn in red. Unstable roots the map cannot show (a
    chain in ``Re s > 0`` whose roots all lie above the rectangle, as those of U_BS near
    ``Im s = pi / delta`` for a small loop delay ``delta``) are named in a note on the
    figure (:func:`hidden_unstable_roots`): a map without red circles is not a claim of
    stability.

    Parameters
    ----------
    F : QuasiPolynomial
    region : tuple, optional
        ``(re_min, re_max, im_min, im_max)``; by default :func:`root_map_region`, which
        holds the rightmost roots of ``F``.
    roots : RootSet or array_like, optional
        Precomputed roots; by default ``find_roots(F, region)`` (certified).
    ax : matplotlib Axes, optional
    chains : bool or sequence of float
        Draw the vertical asymptotes ``Re s = c`` of the root chains of the difference
        operator ``F.principal_part()`` (Hale and Verduyn Lunel) that meet the region;
        a sequence gives the abscissae ``c`` directly (e.g. ``PrincipalPart.chains`` of a
        certificate).
    max_chains : int
        At most this many asymptotes are drawn, the rightmost ones (a loop delay ``delta``
        commensurate with ``tau`` in steps ``h`` gives ``(tau + delta)/h`` chains); the
        legend says how many were left out.

    Returns
    -------
    NrobustPlot
        ``lines["roots"]`` (one marker artist whose data are the roots),
        ``lines["unstable"]`` (one marker artist on the roots with ``Re s > 0``; no data
        when there is none), ``lines["chains"]`` (one line per chain), ``lines["axis"]``,
        ``lines["note"]`` (the text on unstable roots not drawn; empty when there is none).
    """
    F = as_quasipolynomial("F", F)
    box = root_map_region(F) if region is None else check_region(region)
    if roots is None:
        roots = find_roots(F, box)
    values = np.asarray(getattr(roots, "roots", roots), dtype=complex).ravel()
    ax = _get_ax(ax)
    lines: dict[str, list[Any]] = {"chains": []}
    lines["axis"] = [ax.axvline(0.0, color="k", lw=0.8, label="imaginary axis")]
    max_chains = positive_int("max_chains", max_chains)
    if isinstance(chains, bool):
        reals = [c.real for c in F.principal_part().chains().chains] if chains and F.is_neutral else []
    else:
        reals = [float(c) for c in chains]
    inside = sorted((c for c in reals if box[0] <= c <= box[1]), reverse=True)
    label = "chain asymptotes" + (f" ({max_chains} rightmost of {len(inside)})" if len(inside) > max_chains else "")
    n_right = sum(c >= 0.0 for c in inside[:max_chains])
    for k, c in enumerate(inside[:max_chains]):
        if c >= 0.0:
            text = f"{n_right} chain asymptote(s) in Re s >= 0" if k == 0 else None
            lines["chains"].append(ax.axvline(c, color="tab:red", ls="--", lw=0.9, label=text))
        else:
            text = label if k == n_right else None
            lines["chains"].append(ax.axvline(c, color="C1", ls="--", lw=0.8, label=text))
    lines["roots"] = ax.plot(values.real, values.imag, "x", color="C0", label=f"{values.size} roots")
    bad = values[values.real > 0.0]
    lines["unstable"] = ax.plot(
        bad.real,
        bad.imag,
        "o",
        ms=9,
        mfc="none",
        mec="tab:red",
        mew=1.5,
        label=f"{bad.size} unstable (Re s > 0)" if bad.size else None,
    )
    hidden = hidden_unstable_roots(F, box, values)
    lines["note"] = []
    if hidden is not None:
        if not any(c.get_xdata()[0] == hidden.real for c in lines["chains"]):
            lines["chains"].append(
                ax.axvline(hidden.real, color="tab:red", ls="--", lw=0.9, label="unstable chain (above the map)")
            )
        lines["note"].append(
            ax.text(
                0.02,
                0.02,
                textwrap.fill(hidden.note, 48),
                transform=ax.transAxes,
                ha="left",
                va="bottom",
                fontsize="x-small",
                color="tab:red",
                bbox={"facecolor": "white", "edgecolor": "tab:red", "alpha": 0.9},
            )
        )
    ax.set_xlim(box[0], box[1])
    ax.set_ylim(box[2], box[3])
    ax.set_xlabel("Re s")
    ax.set_ylabel("Im s")
    ax.legend(fontsize="x-small", loc="upper left" if hidden is not None else "best")
    return NrobustPlot(lines, ax, ax.figure)


@dataclass(frozen=True)
class HiddenUnstableRoots:
    """Unstable roots of ``F`` above a root map's rectangle.

    Attributes
    ----------
    real : float
        ``Re s`` of the rightmost such chain (exact for commensurate delays; else the
        upper end of the bracket of the chains' abscissa ``c_D``).
    lower : float
        A certified lower bound of that abscissa, ``> 0``: ``F`` has roots with
        ``Re s > 0`` (the roots of a neutral ``F`` approach the chains of its difference
        operator as ``|Im s|`` grows, Hale and Verduyn Lunel).
    height : float
        The map's ``max(|Im s|)``: the chain has no root (asymptotically) up to it.
    first : float or None
        ``|Im s|`` of the chain's zero nearest the real axis (commensurate delays), None
        when the chains are not resolved.
    chains : int
        Number of chains in ``Re s > 0`` with no root in the map (1 when not resolved).
    note : str
        The sentence written on the figure.
    """

    real: float
    lower: float
    height: float
    first: float | None
    chains: int
    note: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


def hidden_unstable_roots(
    F: QuasiPolynomial, region: tuple[float, float, float, float], roots: ArrayLike = ()
) -> HiddenUnstableRoots | None:
    """The chain of unstable roots of a neutral ``F`` that a root map of ``region`` misses.

    A chain ``Re s = c > 0`` of the difference operator ``F.principal_part()`` carries
    infinitely many roots of ``F`` with ``Re s -> c`` (Hale and Verduyn Lunel). It is
    missed when none of its zeros ``c + i (offset + m spacing)`` lies in ``region``'s
    height (commensurate delays) or, when the chains are not resolved, when the certified
    bracket ``[lower, upper]`` of their abscissa has ``lower > 0`` and no root of
    ``roots`` (those drawn) lies in ``Re s > 0``.

    Parameters
    ----------
    F : QuasiPolynomial
    region : tuple of float
        ``(re_min, re_max, im_min, im_max)`` of the map.
    roots : array_like of complex
        The roots drawn on the map.

    Returns
    -------
    HiddenUnstableRoots or None
        None for a retarded ``F``, or when no unstable chain is missed.
    """
    F = as_quasipolynomial("F", F)
    box = check_region(region)
    drawn = number_array("roots", roots, ndim=None, min_size=0).ravel()
    if not F.is_neutral:
        return None
    found = F.principal_part().chains()
    height = float(max(abs(box[2]), abs(box[3])))
    if found.chains:
        missed = [c for c in found.chains if c.real > 0 and c.points(box[2], box[3]).size == 0]
        if not missed:
            return None
        top = max(missed, key=lambda c: c.real)
        first = abs((top.offset + 0.5 * top.spacing) % top.spacing - 0.5 * top.spacing)
        more = f" (and {len(missed) - 1} more chain(s) in Re s > 0)" if len(missed) > 1 else ""
        note = (
            f"Unstable roots not drawn: the chain at Re s = {top.real:.4g}{more} has its roots above "
            f"|Im s| = {height:.4g}, the first near Im s = +-{first:.5g}."
        )
        return HiddenUnstableRoots(float(top.real), float(top.real), height, float(first), len(missed), note)
    lower, upper = found.bracket
    if not lower > 0 or np.any(drawn.real > 0):
        return None
    note = (
        f"Unstable roots not drawn: chains with Re s -> c_D in [{lower:.4g}, {upper:.4g}] (certified) "
        f"have their roots above |Im s| = {height:.4g}."
    )
    return HiddenUnstableRoots(float(upper), float(lower), height, None, 1, note)


# ---------------------------------------------------------------------- root locus
@dataclass(frozen=True, eq=False)
class RootLocusData:
    """Roots of a family ``F_p`` in a region as the parameter ``p`` moves.

    Attributes
    ----------
    name : str
        Name of the parameter (``"K"``, ``"delta"``...).
    params : ndarray
        Parameter values.
    roots : tuple of ndarray
        ``roots[i]`` are the roots of ``F_{params[i]}`` in ``region``.
    region : tuple
        The rectangle searched.
    """

    name: str
    params: NDArray[np.float64]
    roots: tuple[NDArray[np.complex128], ...]
    region: tuple[float, float, float, float]

    def plot(self, ax: Axes | None = None, cmap: str = "viridis") -> NrobustPlot:
        """Scatter the roots coloured by the parameter; ``lines["roots"]`` is the collection."""
        ax = _get_ax(ax)
        pts = np.concatenate(self.roots) if self.roots else np.zeros(0, complex)
        col = (
            np.concatenate([np.full(r.size, p) for p, r in zip(self.params, self.roots)]) if self.roots else np.zeros(0)
        )
        lines: dict[str, list[Any]] = {}
        lines["axis"] = [ax.axvline(0.0, color="k", lw=0.8)]
        sc = ax.scatter(pts.real, pts.imag, c=col, cmap=cmap, s=10, vmin=self.params.min(), vmax=self.params.max())
        lines["roots"] = [sc]
        lines["colorbar"] = [ax.figure.colorbar(sc, ax=ax, label=self.name)]
        ax.set_xlim(self.region[0], self.region[1])
        ax.set_ylim(self.region[2], self.region[3])
        ax.set_xlabel("Re s")
        ax.set_ylabel("Im s")
        ax.set_title(f"Root locus in {self.name}", fontsize="small")
        return NrobustPlot(lines, ax, ax.figure)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (roots as ``[re, im]`` pairs)."""
        return fields_dict(self)


def root_locus_response(
    family: Callable[[float], QuasiPolynomial],
    params: ArrayLike,
    region: tuple[float, float, float, float],
    name: str = "p",
    progress: bool = False,
) -> RootLocusData:
    """Roots of ``family(p)`` in ``region`` for each ``p`` of ``params`` (certified counts).

    ``family`` maps a parameter to a characteristic function, e.g.
    ``lambda K: characteristic(system, ReflectionController(K), delta)`` for a locus in
    ``K`` or ``lambda d: characteristic(system, controller, d)`` for a locus in ``delta``.
    """

    box = check_region(region)
    p = np.atleast_1d(np.asarray(params, dtype=float))
    if p.ndim != 1 or p.size == 0 or not np.all(np.isfinite(p)):
        raise ParameterError("params", "a non-empty 1-D array of finite numbers", params)
    roots = []
    with progress_bar(p.size, progress, f"root locus in {name}") as bar:
        for x in p.tolist():
            roots.append(np.asarray(find_roots(as_quasipolynomial("family(p)", family(x)), box).roots, dtype=complex))
            bar.update(1)
    return RootLocusData(name, p, tuple(roots), box)


def root_locus_plot(
    family: Callable[[float], QuasiPolynomial],
    params: ArrayLike,
    region: tuple[float, float, float, float],
    name: str = "p",
    ax: Axes | None = None,
) -> NrobustPlot:
    """Compute :func:`root_locus_response` and plot it."""
    return root_locus_response(family, params, region, name).plot(ax=ax)


# ---------------------------------------------------------------------- time domain
def residual_floor(results: Sequence[Any]) -> float:
    """The accuracy level of simulations: ``h^2`` times their largest norm, ``h = 1/n`` the cell size.

    The simulator is second order (:func:`nrobust.hyperbolic.simulate.simulate`): below
    this level a norm shows the scheme's residual (a staircase after a finite-time
    convergence), not the plant. :func:`simulation_plot` cuts its log axis there.
    """
    results = list(results)
    if not results:
        raise ParameterError("results", "at least one simulation result", results)
    top = max(float(np.max(np.asarray(r.norm, dtype=float))) for r in results)
    h = 1.0 / min(int(r.n) for r in results)
    return h * h * top


def simulation_plot(
    results: Sequence[Any],
    labels: Sequence[str] | None = None,
    ax: Axes | None = None,
    floor: float | str | None = "residual",
) -> NrobustPlot:
    """``L^2`` norm of simulated states against time, log scale (paper, figures 1 and 3).

    Parameters
    ----------
    results : sequence of simulation results
        Outputs of :func:`nrobust.hyperbolic.simulate.simulate` (``times``, ``norm``, ``n``).
    labels : sequence of str, optional
        One legend entry per result.
    floor : float, "residual" or None
        Bottom of the log axis: ``"residual"`` (default) cuts it at :func:`residual_floor`,
        the ``O(h^2)`` accuracy of the scheme, and says so on the plot (a norm that
        reaches 0 in finite time, as under U_BS without delay, would otherwise draw the
        scheme's residual down to ``1e-40`` and flatten every other curve); a number cuts
        it there; None keeps every positive value.

    Returns
    -------
    NrobustPlot
        ``lines["norms"]`` (one line per result), ``lines["floor"]`` (the note on the cut).
    """
    results = list(results)
    if not results:
        raise ParameterError("results", "at least one simulation result", results)
    if labels is not None and len(labels) != len(results):
        raise ParameterError("labels", f"one label per result ({len(results)})", labels)
    if floor == "residual":
        bottom: float | None = residual_floor(results)
    elif floor is None:
        bottom = None
    elif isinstance(floor, str):
        raise ParameterError("floor", 'a number > 0, "residual" or None', floor)
    else:
        bottom = positive("floor", floor)
    ax = _get_ax(ax)
    lines: dict[str, list[Any]] = {"norms": [], "floor": []}
    for k, res in enumerate(results):
        t = np.asarray(res.times, dtype=float)
        y = np.asarray(res.norm, dtype=float)
        label = labels[k] if labels is not None else None
        lines["norms"] += ax.semilogy(t, np.maximum(y, np.finfo(float).tiny), label=label)
    if bottom is not None:
        norms = np.concatenate([np.asarray(r.norm, dtype=float) for r in results])
        positive_norms = norms[norms > 0.0]
        low = 0.5 * float(positive_norms.min()) if positive_norms.size else bottom
        top = float(norms.max())
        ax.set_ylim(max(bottom, low), max(3.0 * top, 10.0 * bottom))
        if low < bottom:  # something lies below the cut: say so
            what = "the scheme's O(h^2) residual" if floor == "residual" else "cut"
            lines["floor"].append(
                ax.text(
                    0.01, 0.02, f"axis cut at {bottom:.1e} ({what})", transform=ax.transAxes, fontsize=7, color="0.35"
                )
            )
    ax.set_xlabel("t")
    ax.set_ylabel("||(u, v)(t)||_L2")
    ax.grid(True, which="major", alpha=0.3)
    if labels is not None:
        ax.legend(fontsize="x-small", loc="best")
    return NrobustPlot(lines, ax, ax.figure)


# ---------------------------------------------------------------------- charts
def stability_chart_plot(
    chart: Any,
    ax: Axes | None = None,
    k_bound: float | None = None,
    rouche: tuple[ArrayLike, ArrayLike] | None = None,
) -> NrobustPlot:
    """Stability chart in ``(K, delta)``: the grid, the exact boundary, the paper's bound.

    Parameters
    ----------
    chart : StabilityChart
        From :func:`nrobust.hyperbolic.studies.stability_chart` (``quantity="count"``).
    ax : matplotlib Axes, optional
    k_bound : float, optional
        The sufficient bound ``|K| < (1 - |rho q|)/|q|`` of eq. (54)
        (``classify(system).k_bound``), drawn as two vertical lines.
    rouche : (Ks, delta_0) pair, optional
        The guaranteed delays ``delta_0(K)`` of Theorem 4's proof
        (:func:`nrobust.hyperbolic.studies.tradeoff` gives them as ``rouche_bounds``).
        ``delta_0`` depends on ``K`` through ``|K|`` only (``epsilon_0 = 1 - |q rho| - |K q|``),
        so a curve given for ``K >= 0`` only is drawn for ``-K`` too.

    Returns
    -------
    NrobustPlot
        ``lines["stable"]`` (grid points with no unstable zero), ``lines["unstable"]``,
        ``lines["margin"]`` (the exact boundary ``delta*(K)``), ``lines["crossings"]`` (every
        crossing delay up to ``max(deltas)``), ``lines["paper_bound"]``, ``lines["rouche"]``.
    """
    if getattr(chart, "quantity", None) != "count":
        raise ParameterError("chart", 'a StabilityChart with quantity "count"', chart)
    ax = _get_ax(ax)
    Ks, deltas, values = chart.Ks, chart.deltas, chart.values
    KK, DD = np.meshgrid(Ks, deltas, indexing="ij")
    stable = values == 0
    lines: dict[str, list[Any]] = {}
    lines["stable"] = ax.plot(KK[stable], DD[stable], "s", color="tab:green", ms=3, alpha=0.6, label="stable")
    lines["unstable"] = ax.plot(KK[~stable], DD[~stable], "s", color="tab:red", ms=3, alpha=0.35, label="unstable")
    top = float(deltas.max())
    shown = np.where(np.isfinite(chart.margins), np.minimum(chart.margins, top), top)
    lines["margin"] = ax.plot(Ks, shown, "-", color="k", lw=1.5, label="delay margin delta*(K)")
    kc, dc = [], []
    for K, rows in zip(Ks, chart.boundaries):
        rows = np.asarray(rows).reshape(-1, 3)
        kc += [K] * rows.shape[0]
        dc += list(rows[:, 0])
    lines["crossings"] = ax.plot(kc, dc, ".", color="0.3", ms=3, label="crossing delays") if kc else []
    lines["paper_bound"] = []
    if k_bound is not None:
        kb = float(k_bound)
        for k, x in enumerate((-kb, kb)):
            lines["paper_bound"].append(
                ax.axvline(
                    x, color="C0", ls="--", lw=1.0, label="|K| = (1 - |rho q|)/|q|, eq. (54)" if k == 0 else None
                )
            )
    lines["rouche"] = []
    if rouche is not None:
        rk, rd = (np.asarray(v, dtype=float).ravel() for v in rouche)
        if rk.shape != rd.shape:
            raise ParameterError("rouche", "a pair (Ks, delta_0) of equal lengths", rouche)
        if rk.size and np.all(rk >= 0.0):  # delta_0 depends on |K| only: mirror the curve to K < 0
            keep = rk > 0.0
            rk, rd = np.concatenate([-rk[keep][::-1], rk]), np.concatenate([rd[keep][::-1], rd])
        order = np.argsort(rk, kind="stable")
        lines["rouche"] = ax.plot(
            rk[order], np.minimum(rd[order], top), "-.", color="C1", label="Rouche delta_0(K), Theorem 4"
        )
    ax.set_xlabel("K")
    ax.set_ylabel("delta")
    ax.set_ylim(0.0, top * 1.02)
    ax.set_title("Stability chart of U_BS2(K)", fontsize="small")
    ax.legend(fontsize="x-small", loc="upper right")
    return NrobustPlot(lines, ax, ax.figure)


def tradeoff_plot(tradeoff: Any, ax: Axes | None = None, annotate: bool = True) -> NrobustPlot:
    """Decay rate against delay margin as the gain ``K`` varies (the paper's trade-off).

    Parameters
    ----------
    tradeoff : Tradeoff
        From :func:`nrobust.hyperbolic.studies.tradeoff`.
    ax : matplotlib Axes, optional
    annotate : bool
        Write ``K`` next to the points.

    Returns
    -------
    NrobustPlot
        ``lines["curve"]`` with x = delay margins (finite ones) and y = decay rates.
    """
    ax = _get_ax(ax)
    Ks = np.asarray(tradeoff.Ks, dtype=float)
    m = np.asarray(tradeoff.margins, dtype=float)
    r = np.asarray(tradeoff.decay_rates, dtype=float)
    ok = np.isfinite(m) & np.isfinite(r)
    lines: dict[str, list[Any]] = {}
    lines["curve"] = ax.plot(m[ok], r[ok], "o-", color="C0", ms=4, label="U_BS2(K)")
    if annotate:
        for K, x, y in zip(Ks[ok], m[ok], r[ok]):
            ax.annotate(f"{K:.3g}", (x, y), textcoords="offset points", xytext=(3, 3), fontsize=6)
    ax.set_xlabel("delay margin delta*")
    ax.set_ylabel("decay rate (- spectral abscissa)")
    ax.set_title("Decay rate against delay margin", fontsize="small")
    hidden = int(np.sum(~ok))
    if hidden:
        ax.text(0.02, 0.02, f"{hidden} gain(s) with infinite margin not shown", transform=ax.transAxes, fontsize=7)
    return NrobustPlot(lines, ax, ax.figure)


def sweep_chart(result: SweepResult, swept: Sequence[str], plot: Mapping[str, str], sampling: bool) -> Figure:
    """The chart of a sweep: a curve for one swept name, a map for two, histograms for samples.

    Parameters
    ----------
    result : SweepResult
        The table.
    swept : sequence of str
        The names varied by the sweep.
    plot : mapping
        Optional ``x`` (a swept parameter) and ``y`` (a numeric result column).
    sampling : bool
        True for a Monte Carlo study: histograms of the result columns.

    Returns
    -------
    matplotlib.figure.Figure
        A figure on an Agg canvas (no display needed).
    """
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    table = result.table()
    numeric = [c for c in result.result_columns if table.dtype[c].kind == "f"]
    y = plot.get("y", numeric[0] if numeric else None)
    if y is not None and y not in numeric:
        raise ParameterError("plot.y", f"a numeric result column: one of {numeric}", y)
    varying = [k for k in swept if len({repr(p.get(k)) for p in result.points}) > 1]
    x = plot.get("x", varying[0] if varying else (swept[0] if swept else None))
    if x is not None and x not in result.parameter_columns:
        raise ParameterError("plot.x", f"a swept parameter: one of {list(result.parameter_columns)}", x)

    ok = table["status"] == "ok"
    title = f"{result.n_ok} ok, {result.n_failed} failed"
    if sampling and y is not None:
        shown = [y, *[c for c in numeric if c != y]][:3]
        fig = Figure(figsize=(4.0 * len(shown), 3.6), layout="constrained")
        FigureCanvasAgg(fig)
        for i, col in enumerate(shown):
            ax = fig.add_subplot(1, len(shown), i + 1)
            vals = table[col][ok]
            finite = vals[np.isfinite(vals)]
            n_inf = int(np.sum(np.isposinf(vals)))
            if finite.size:
                ax.hist(finite, bins=max(5, min(50, 2 * int(np.sqrt(finite.size)))), color="C0")
            else:
                ax.text(0.5, 0.5, f"no finite {col}", ha="center", va="center", transform=ax.transAxes)
            ax.set_xlabel(col)
            ax.set_ylabel("samples")
            ax.set_title(f"{n_inf} infinite" if n_inf else "", fontsize="small")
        fig.suptitle(title, fontsize="medium")
        return fig
    fig = Figure(figsize=(6.4, 4.4), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    if y is None:
        ax.text(0.5, 0.5, "no numeric result", ha="center", va="center", transform=ax.transAxes)
    elif x is not None and table.dtype[x].kind in "fiu" and len(varying) == 2 and table.dtype[varying[1]].kind in "fiu":
        x2 = varying[1] if x == varying[0] else varying[0]
        xs, ys = np.unique(table[x]), np.unique(table[x2])
        grid_vals = np.full((ys.size, xs.size), np.nan)
        for row in table[ok]:
            grid_vals[np.searchsorted(ys, row[x2]), np.searchsorted(xs, row[x])] = row[y]
        finite = grid_vals[np.isfinite(grid_vals)]
        top = finite.max() if finite.size else 1.0
        cmap = matplotlib.colormaps["viridis"].with_extremes(over="gold", bad="lightgray")
        capped = np.where(np.isposinf(grid_vals), top + 1.0, grid_vals)
        mesh = ax.pcolormesh(
            xs,
            ys,
            np.ma.masked_invalid(capped),
            shading="nearest",
            cmap=cmap,
            vmin=finite.min() if finite.size else 0.0,
            vmax=top,
        )
        fig.colorbar(mesh, ax=ax, label=y, extend="max" if np.isposinf(grid_vals).any() else "neither")
        ax.set_xlabel(x)
        ax.set_ylabel(x2)
        title += " (gold: inf, gray: failed)"
    elif x is not None and table.dtype[x].kind in "fiu":
        xv, yv = table[x][ok].astype(float), table[y][ok]
        fin = np.isfinite(yv)
        # every point in x order, NaN where the value is infinite or failed: the line has a gap
        # there instead of joining the finite points on either side
        x_all = table[x].astype(float)
        y_all = np.where(ok & np.isfinite(table[y]), table[y], np.nan)
        order = np.argsort(x_all, kind="stable")
        ax.plot(x_all[order], y_all[order], "o-", ms=3, label=y)
        edge = ax.get_xaxis_transform()  # x in data, y in axes units: markers on the frame
        if (~fin).any():
            ax.plot(xv[~fin], np.full((~fin).sum(), 0.97), "^", color="C1", transform=edge, label=f"{y} = inf")
        if (~ok).any():
            ax.plot(
                table[x][~ok].astype(float), np.full((~ok).sum(), 0.03), "x", color="C3", transform=edge, label="failed"
            )
        ax.set_xlabel(x)
        ax.set_ylabel(y)
        ax.legend(loc="best", fontsize="small")
    else:
        yv = table[y]
        ax.plot(np.arange(len(yv))[ok], yv[ok], "o", ms=3)
        ax.set_xlabel("point index")
        ax.set_ylabel(y)
    ax.set_title(title, fontsize="medium")
    return fig


def simulation_figure(
    runs: Sequence[Any], labels: Sequence[str], title: str, floor: float | str | None = "residual"
) -> Figure:
    """A figure of :func:`simulation_plot` with a title (used by the reports and the paper's figures)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    simulation_plot(runs, labels=labels, ax=ax, floor=floor)
    ax.set_title(title, fontsize="small")
    return fig
