"""The spectral abscissa of a quasi-polynomial: the rightmost root, certified."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._json import json_float
from ..bounds import TailBound, joint_degree, principal_gap, radius_where
from ..difference import DifferenceOperator
from ..errors import CertificationError, ParameterError
from ..quasipoly import QuasiPolynomial
from .finder import RootSet, find_roots
from .winding import Region, _check_function, count_roots

__all__ = ["SpectralAbscissa", "spectral_abscissa"]


# ====================================================================== spectral abscissa
@dataclass(frozen=True)
class SpectralAbscissa:
    """The rightmost root of a quasi-polynomial and how far the result is certified.

    Attributes
    ----------
    value : float
        ``sup {Re s : F(s) = 0}``: the real part of ``root``, or ``chain_value`` when the
        chains of a neutral ``F`` reach further right (then the supremum is approached
        only as ``|Im s| -> infinity``); ``-inf`` if ``F`` has no root with
        ``Re s >= region[0]``.
    root : complex or None
        The rightmost root found in ``region``.
    approached_at_infinity : bool
        True if ``value`` is the chain value ``c_D`` of the principal part and no root in
        ``region`` attains it (Hale and Verduyn Lunel: the high-frequency roots of a
        neutral ``F`` converge to the zero chains of its difference operator).
    chain_value : float
        Spectral bound ``c_D`` of the principal part (upper end of its bracket for
        incommensurate delays); ``-inf`` for retarded ``F``.
    upper_bound : float
        Certified: ``F`` has no root with ``Re s > upper_bound`` anywhere.
    certified : bool
        True if every root of ``region`` was found (certified count), so no root of
        ``region`` lies to the right of ``root``. Outside ``region`` only ``upper_bound``
        is certified: for neutral ``F`` the chain roots above ``region`` have real parts
        in ``[c_D - o(1), upper_bound]``.
    region : tuple of float
        The rectangle searched.
    strong_bound : float
        ``C_D`` of the principal part: the supremum of the chain abscissa over small
        perturbations of the delays (equal to ``chain_value`` for rationally independent
        delays; ``-inf`` for retarded ``F``). A loop is robust to small delays only if
        ``C_D < 0`` (Hale and Verduyn Lunel, 2002).
    """

    value: float
    root: complex | None
    approached_at_infinity: bool
    chain_value: float
    upper_bound: float
    certified: bool
    region: Region
    strong_bound: float = -np.inf

    def __repr__(self) -> str:
        root = "None" if self.root is None else f"{self.root.real:.12g}{self.root.imag:+.12g}j"
        tail = ", approached as Im s -> infinity" if self.approached_at_infinity else ""
        return (
            f"SpectralAbscissa(value={self.value:.12g}, root={root}{tail}, chain_value={self.chain_value:.6g}, "
            f"strong_bound={self.strong_bound:.6g}, upper_bound={self.upper_bound:.6g}, certified={self.certified})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {
            "value": json_float(self.value),
            "root": None if self.root is None else [self.root.real, self.root.imag],
            "approached_at_infinity": self.approached_at_infinity,
            "chain_value": json_float(self.chain_value),
            "upper_bound": json_float(self.upper_bound),
            "certified": self.certified,
            "region": list(self.region),
            "strong_bound": json_float(self.strong_bound),
        }


# Largest |s| tried by the root-free radius; beyond it the search is not certified.
_MAX_RADIUS = 1e6


def _root_free_radius(F: QuasiPolynomial, x: float) -> float | None:
    """A radius ``R`` with no root of ``F`` in ``{Re s >= x, |s| >= R}``, or None.

    On that set the first principal term dominates when its gap over the other principal
    terms exceeds the remainder of :class:`nrobust.bounds.TailBound` (Rouché,
    :func:`nrobust.bounds.root_free_region`); both are monotone in ``|s|`` and ``Re s``.
    """
    n = joint_degree(F)
    g = principal_gap({"F": (F, 0)}, n, x)
    if g is None or g.gap <= 0.0:
        return None
    try:
        return radius_where(TailBound(F, n, x, g.t0), g.gap, "spectral_abscissa")
    except CertificationError:
        return None


def spectral_abscissa(
    F: QuasiPolynomial,
    region: ArrayLike | None = None,
    *,
    im_max: float | None = None,
    cluster_tol: float = 1e-6,
    max_evals: int = 5_000_000,
) -> SpectralAbscissa:
    """The supremum of the real parts of the roots of ``F``, with its rightmost root.

    Parameters
    ----------
    F : QuasiPolynomial
        Retarded or neutral (an advanced ``F`` has roots with arbitrarily large real part).
    region : (re_min, re_max, im_min, im_max), optional
        Search only this rectangle. By default the search region is built so that the
        answer is certified: a half-plane ``Re s >= x`` is root-free outside a disc
        (:func:`_root_free_radius`), the rest is counted and searched.
    im_max : float, optional
        Height of the band searched near the chains of a neutral ``F``.
    cluster_tol, max_evals
        As in :func:`find_roots`.

    Returns
    -------
    SpectralAbscissa

    Notes
    -----
    For neutral ``F`` with principal part ``D``, no root lies in ``Re s > C_D + m`` outside
    a disc, so the roots there are found exactly; below, the high-frequency roots
    approach the chains of ``D`` whose abscissa is ``c_D`` (Hale and Verduyn Lunel), so
    the supremum is ``max(c_D, real part of the rightmost root found)`` and may be
    approached only as ``|Im s| -> infinity`` (``approached_at_infinity``).
    """
    F = _check_function(F)
    if F.kind == "advanced":
        raise ParameterError("F", "retarded or neutral (an advanced quasi-polynomial has unbounded root real parts)", F)
    D = F.principal_part()
    chain_value = D.spectral_bound().upper
    c_strong = D.strong_spectral_bound()
    if region is not None:
        roots = find_roots(F, region, cluster_tol=cluster_tol, max_evals=max_evals)
        result = _abscissa_from(roots, chain_value, np.inf, roots.certified)
    elif np.isfinite(c_strong):
        margin = 0.1 * (1.0 + abs(c_strong))
        x_min, radius = _right_half_plane(F, c_strong + margin, margin)
        real = F.is_real
        result = _neutral_abscissa(F, D, x_min, radius, real, im_max, chain_value, cluster_tol, max_evals)
    else:
        x_right, radius = _right_half_plane(F, 0.0, 1.0)
        result = _retarded_abscissa(F, x_right, radius, F.is_real, cluster_tol, max_evals)
    return replace(result, strong_bound=float(c_strong))


def _right_half_plane(F: QuasiPolynomial, x0: float, step: float) -> tuple[float, float]:
    """``(x, R)``: no root with ``Re s >= x`` and ``|s| >= R``, for the first
    ``x = x0 + step (2^j - 1)`` where :func:`_root_free_radius` finds one."""
    for j in range(40):
        x = x0 + step * (2.0**j - 1.0)
        R = _root_free_radius(F, x)
        if R is not None:
            return x, R
    raise CertificationError("no root-free right half-plane found: the quasi-polynomial is not retarded or neutral")


def _band(y: float, real: bool) -> tuple[float, float]:
    return (-0.25 if real else -y), y


def _neutral_abscissa(
    F: QuasiPolynomial,
    D: DifferenceOperator,
    x_min: float,
    radius: float,
    real: bool,
    im_max: float | None,
    chain_value: float,
    cluster_tol: float,
    max_evals: int,
) -> SpectralAbscissa:
    """Exhaustive search of ``Re s >= x_min`` (inside the disc of ``radius``), then of a
    band below ``x_min`` near the chains."""
    right = (x_min, max(x_min, radius) + 1.0, *_band(radius, real))
    roots = find_roots(F, right, cluster_tol=cluster_tol, max_evals=max_evals)
    if roots.count > 0:
        return _abscissa_from(roots, chain_value, x_min, roots.certified, upper_from_roots=roots.certified)
    chains = D.chains()
    period = chains.chains[0].spacing if chains.commensurate and chains.chains else 2 * np.pi / max(F.max_delay, 1e-3)
    height = float(im_max) if im_max is not None else max(radius, 100.0, 2 * period)
    low = (min(chain_value, x_min) - 0.5, x_min, *_band(height, real))
    band = find_roots(F, low, cluster_tol=cluster_tol, max_evals=max_evals)
    return _abscissa_from(band, chain_value, x_min, band.certified and roots.certified)


def _retarded_abscissa(
    F: QuasiPolynomial,
    x_right: float,
    radius: float,
    real: bool,
    cluster_tol: float,
    max_evals: int,
) -> SpectralAbscissa:
    """Widen a window ``[x_right - w, x_max]`` leftwards (``w = 0, 1, 2, 4, ...``) until it
    holds a root; every root with ``Re s`` in the window is found, so the rightmost is."""
    x_max = max(x_right, radius) + 1.0
    searched: Region | None = None
    for width in [0.0] + [2.0**j for j in range(12)]:
        x_min = x_right - width
        y = _root_free_radius(F, x_min)
        if y is None or y > _MAX_RADIUS:
            break
        box = (x_min, x_max, *_band(max(y, radius), real))
        count = count_roots(F, box, max_evals=max_evals)
        searched = count.region
        if count > 0:
            roots = find_roots(F, box, cluster_tol=cluster_tol, max_evals=max_evals)
            return _abscissa_from(roots, -np.inf, x_max, roots.certified, upper_from_roots=roots.certified)
    if searched is None:
        raise CertificationError(f"no root-free far field for Re s >= {x_right:.6g}: cannot bound the roots")
    # no root with Re s >= searched[0] at all
    return SpectralAbscissa(-np.inf, None, False, -np.inf, searched[0], True, searched)


def _abscissa_from(
    roots: RootSet, chain_value: float, upper: float, certified: bool, upper_from_roots: bool = False
) -> SpectralAbscissa:
    if len(roots):
        i = int(np.argmax(roots.roots.real))
        root: complex | None = complex(roots.roots[i])
        best = root.real + (roots.radii[i] if upper_from_roots else 0.0)
    else:
        root, best = None, -np.inf
    found = -np.inf if root is None else root.real
    at_inf = bool(np.isfinite(chain_value) and chain_value > found + 1e-12 * (1 + abs(chain_value)))
    value = chain_value if at_inf else found
    upper_bound = best if upper_from_roots else max(upper, value)
    return SpectralAbscissa(
        float(value), root, at_inf, float(chain_value), float(upper_bound), bool(certified), roots.region
    )
