"""Root maps: the roots of a characteristic function in a rectangle, its chains, the roots it misses."""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._json import fields_dict
from .._validate import number_array, positive_int
from .._validate import region as check_region
from ..errors import CertificationError
from ..quasipoly import QuasiPolynomial, as_quasipolynomial
from ..roots import RootSet, SpectralAbscissa, find_roots, spectral_abscissa
from .base import NrobustPlot, get_axes, legend_corner

if TYPE_CHECKING:
    from matplotlib.axes import Axes


__all__ = [
    "HiddenUnstableRoots",
    "RootMapData",
    "hidden_unstable_roots",
    "root_map_plot",
    "root_map_region",
    "root_map_response",
]

#: The base rectangle of a root map, in units of ``1/T`` (``T`` the largest delay of ``F``).
_BASE_REGION = (-3.0, 1.0, -40.0, 40.0)
#: Work bound of a default root map: about this many roots at most (see root_map_region).
_MAX_MAP_ROOTS = 600


def root_map_region(
    F: QuasiPolynomial,
    base: tuple[float, float, float, float] | None = None,
    abscissa: SpectralAbscissa | None = None,
    max_roots: int = _MAX_MAP_ROOTS,
    search: bool = True,
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
    search : bool, default True
        Compute the spectral abscissa when ``abscissa`` is not given. False: the caller knows
        that ``base`` holds the roots that matter (e.g. every zero in ``Re s > 0``, counted
        by another route), and only the chains widen it.

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
    if search and abscissa is None and F.kind != "advanced":
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


@dataclass(frozen=True, eq=False)
class RootMapData:
    """The roots of ``F`` in a rectangle, its chain asymptotes and the unstable roots it misses.

    Attributes
    ----------
    region : tuple of float
        ``(re_min, re_max, im_min, im_max)`` of the map.
    roots : ndarray of complex
        The roots in ``region`` (certified by :func:`nrobust.roots.find_roots`, unless given).
    count : int or None
        Certified number of roots in ``region``, with multiplicity (None when the roots were
        given as bare numbers).
    certified : bool or None
        True iff every root of the region is accounted for (:attr:`RootSet.certified
        <nrobust.roots.RootSet>`; None when the roots were given as bare numbers).
    unstable : int
        Number of the roots listed with ``Re s > 0``.
    chains : ndarray of float
        Abscissae ``c`` of the root chains ``Re s -> c`` of the principal part of ``F``
        (Hale and Verduyn Lunel) that meet the region, rightmost first.
    hidden : HiddenUnstableRoots or None
        The unstable chain whose roots all lie above the map (:func:`hidden_unstable_roots`).
    """

    region: tuple[float, float, float, float]
    roots: NDArray[np.complex128]
    count: int | None
    certified: bool | None
    unstable: int
    chains: NDArray[np.float64]
    hidden: HiddenUnstableRoots | None

    def plot(self, ax: Axes | None = None, max_chains: int = 12) -> NrobustPlot:
        """Roots, unstable roots circled in red, chain asymptotes, the imaginary axis.

        Roots in ``Re s > 0`` are circled in red and counted in the legend; chain
        asymptotes in ``Re s >= 0`` are drawn in red. The unstable chain the map misses
        (:attr:`hidden`) is drawn and named in a note on the figure: a map without red
        circles is not a claim of stability.

        Parameters
        ----------
        ax : matplotlib Axes, optional
        max_chains : int
            At most this many asymptotes are drawn, the rightmost ones (a loop delay
            ``delta`` commensurate with ``tau`` in steps ``h`` gives ``(tau + delta)/h``
            chains); the legend says how many were left out.

        Returns
        -------
        NrobustPlot
            ``lines["roots"]`` (one marker artist whose data are the roots),
            ``lines["unstable"]`` (one marker artist on the roots with ``Re s > 0``; no data
            when there is none), ``lines["chains"]`` (one line per chain), ``lines["axis"]``,
            ``lines["note"]`` (the text on unstable roots not drawn; empty when there is none).
        """
        max_chains = positive_int("max_chains", max_chains)
        box, values, hidden = self.region, self.roots, self.hidden
        ax = get_axes(ax)
        lines: dict[str, list[Any]] = {"chains": []}
        lines["axis"] = [ax.axvline(0.0, color="k", lw=0.8, label="imaginary axis")]
        inside = [float(c) for c in self.chains]
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
        ax.legend(fontsize="x-small", loc="upper left" if hidden is not None else legend_corner(ax))
        return NrobustPlot(lines, ax, ax.figure)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (roots as ``[re, im]`` pairs)."""
        return fields_dict(self)


def root_map_response(
    F: QuasiPolynomial,
    region: tuple[float, float, float, float] | None = None,
    roots: RootSet | ArrayLike | None = None,
    chains: bool | Sequence[float] = True,
) -> RootMapData:
    """The roots of ``F`` in a rectangle, the chain asymptotes of its principal part, the roots it misses.

    Parameters
    ----------
    F : QuasiPolynomial
    region : tuple, optional
        ``(re_min, re_max, im_min, im_max)``; by default :func:`root_map_region`, which
        holds the rightmost roots of ``F``.
    roots : RootSet or array_like, optional
        Precomputed roots; by default ``find_roots(F, region)`` (certified).
    chains : bool or sequence of float
        The vertical asymptotes ``Re s = c`` of the root chains of the difference
        operator ``F.principal_part()`` (Hale and Verduyn Lunel) that meet the region;
        a sequence gives the abscissae ``c`` directly (e.g. ``PrincipalPart.chains`` of a
        certificate), False none.

    Returns
    -------
    RootMapData
        Its :meth:`~RootMapData.plot` draws the map.
    """
    F = as_quasipolynomial("F", F)
    box = root_map_region(F) if region is None else check_region(region)
    if roots is None:
        roots = find_roots(F, box)
    count = int(roots.count) if isinstance(roots, RootSet) else None
    certified = bool(roots.certified) if isinstance(roots, RootSet) else None
    values = np.asarray(getattr(roots, "roots", roots), dtype=complex).ravel()
    if isinstance(chains, bool):
        reals = [c.real for c in F.principal_part().chains().chains] if chains and F.is_neutral else []
    else:
        reals = [float(c) for c in chains]
    inside = np.array(sorted((c for c in reals if box[0] <= c <= box[1]), reverse=True), dtype=float)
    hidden = hidden_unstable_roots(F, box, values)
    return RootMapData(box, values, count, certified, int(np.sum(values.real > 0.0)), inside, hidden)


def root_map_plot(
    F: QuasiPolynomial,
    region: tuple[float, float, float, float] | None = None,
    roots: RootSet | ArrayLike | None = None,
    ax: Axes | None = None,
    chains: bool | Sequence[float] = True,
    max_chains: int = 12,
) -> NrobustPlot:
    """Compute :func:`root_map_response` and plot it (see :meth:`RootMapData.plot`)."""
    positive_int("max_chains", max_chains)
    return root_map_response(F, region, roots, chains).plot(ax=ax, max_chains=max_chains)


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
