"""The spectral abscissa of a quasi-polynomial: the rightmost root, certified."""

from __future__ import annotations

import weakref
from dataclasses import dataclass, replace
from typing import Any, Protocol, TypeGuard, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._digits import with_accuracy
from .._flint import krawczyk_image
from .._json import fields_dict
from .._validate import positive, positive_int
from ..balls import ball_abs_moment, ball_function, ball_variation_bound, require_flint, working_precision
from ..bounds import TailBound, joint_degree, min_delay, principal_gap, radius_where
from ..difference import DifferenceOperator, SpectralBound
from ..errors import CertificationError, ParameterError
from ..qpmatrix import CharacteristicFunction, QuasiPolynomialMatrix
from ..quasipoly import QuasiPolynomial
from ._common import EPS, Budget, check_function, check_rigorous, magnitude
from .finder import RootSet, find_counted, find_roots, prove, separate_clusters
from .search import Finder
from .winding import Region, ball_count_with_shifts, count_with_shifts

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
        only as ``|Im s| -> infinity``); ``-inf`` only if ``F`` has no root at all
        (``F = c e^{-tau s}``) or, when a ``region`` is given, none in it.
    root : complex or None
        The rightmost root found in ``region`` (of a conjugate pair, the one with
        ``Im s >= 0``). A cluster of roots that floating point cannot separate
        (multiplicity above 1, :class:`~nrobust.roots.RootSet`) is separated in ball
        arithmetic of higher precision when python-flint is installed
        (:func:`~nrobust.roots.finder.separate_clusters`: each of its roots proven by
        Krawczyk's test). Otherwise, or if it does not separate (a multiple root), ``root``
        is its centroid, and the supremum lies in ``[value, upper_bound]``.
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
        ``region`` lies to the right of the disc of ``root``'s entry. Outside ``region``
        only ``upper_bound`` is certified: for neutral ``F`` the chain roots above
        ``region`` have real parts in ``[c_D - o(1), upper_bound]``. For retarded ``F``
        (no ``region`` given) ``region`` holds every root of ``F`` with ``Re s >= value``,
        so ``value`` is certified for ``F``. False also when ``value`` is the upper end of
        a bracket of ``c_D`` wider than ``1e-9 (1 + |c_D|)`` (delays not commensurate within
        the degree bound, as in the expanded determinant of a matrix loop): it then only
        bounds the supremum from above.
    region : tuple of float
        The rectangle searched.
    strong_bound : float
        ``C_D`` of the principal part: the supremum of the chain abscissa over small
        perturbations of the delays (equal to ``chain_value`` for rationally independent
        delays; ``-inf`` for retarded ``F``). A loop is robust to small delays only if
        ``C_D < 0`` (Hale and Verduyn Lunel, 2002).
    rigorous : bool
        True if proven in ball arithmetic (``spectral_abscissa(..., rigorous=True)``):
        ``upper_bound`` (``F`` has no root right of it), the root counts of every box
        searched, ``root_box``, ``chain_bracket`` and ``value_bracket``. ``value``,
        ``chain_value`` and ``strong_bound`` themselves are floating-point numbers.
    root_box : tuple of float or None
        With ``rigorous``, the rectangle proven to hold ``root`` (alone, for a simple root,
        or with its cluster: ``multiplicity`` roots of :class:`~nrobust.roots.RootSet`;
        for ``F = p(s) e^{-tau s}`` the ball of FLINT's exact isolation of the roots of ``p``).
    chain_bracket : tuple of float or None
        With ``rigorous`` and a neutral ``F``: ``(lo, hi)`` proven to hold the chain abscissa
        ``c_D`` of the principal part as represented
        (:meth:`~nrobust.difference.DifferenceOperator.proven_spectral_bound`: tight for
        delays exactly commensurate as stored, else ``[a proven zero of D, proven C_D]``);
        None for a function that encloses itself (``F.ball_function``), whose principal part
        is computed in floating point.
    value_bracket : tuple of float or None
        With ``rigorous``: ``(lo, hi)`` proven to hold ``sup {Re s : F(s) = 0}`` for ``F`` as
        represented (in ``region``, when one is given). ``hi = upper_bound``; ``lo`` the larger
        of the left edge of ``root_box`` (a root lies there) and ``chain_bracket[0]`` (every
        zero of ``D`` is a limit of real parts of roots of ``F`` high up: ``D`` is almost
        periodic in ``Im s`` and ``F(s) / s^n - D(s) -> 0``, Rouche; Henry, 1974).
    error_estimate : float or None
        The floating-point estimate of ``|value - sup {Re s : F(s) = 0}|`` that :attr:`accuracy`
        falls back on without a proven ``value_bracket`` (see there); None when not known.
    model_error : float or None
        For the loop of a model of a plant: an estimate of the abscissa's distance to the
        plant's, set by the caller that knows the model (an output feedback's observer term:
        :func:`~nrobust.hyperbolic.analyses.observer_accuracy.observer_rate_error`); added to
        :attr:`accuracy`. None: not estimated.
    """

    value: float
    root: complex | None
    approached_at_infinity: bool
    chain_value: float
    upper_bound: float
    certified: bool
    region: Region
    strong_bound: float = -np.inf
    rigorous: bool = False
    root_box: tuple[float, float, float, float] | None = None
    chain_bracket: tuple[float, float] | None = None
    value_bracket: tuple[float, float] | None = None
    error_estimate: float | None = None
    model_error: float | None = None

    @property
    def accuracy(self) -> float | None:
        """A bound of ``|value - sup {Re s : F(s) = 0}|``: proven, or a conservative estimate; None if unknown.

        It is about ``F`` as represented, plus :attr:`model_error` when the caller estimated the
        model's own error. For the loop of a model of the PDE (the kernel route,
        ``nrobust.hyperbolic.loops.controllers.loop_route(...) == "kernels"``) it is otherwise not
        included: the core cannot know it (for the margin it is estimated by the convergence
        study in the kernel grid of :attr:`nrobust.Certificate.margin_accuracy`).

        * With ``rigorous`` and a ``value_bracket``: the distance from ``value`` to the far end
          of the bracket, rounded up (proven, for ``F`` as represented).
        * ``value = -inf`` (no root): 0.
        * Otherwise the floating-point :attr:`error_estimate`, made when the result is built:

          - a simple rightmost root ``z``: ``16 (|F(z)| + eps M(z)) / |F'(z)| + eps |z|`` with
            ``M(z)`` the sum of the moduli of the monomials of ``F``
            (:meth:`~nrobust.quasipoly.QuasiPolynomial.magnitude`): the Newton step at ``z``
            plus the rounding error of ``F`` turned into a distance through ``|F'(z)|``, and the
            rounding of ``z`` to a double. The largest ratio of the true error (mpmath at 40
            digits) to ``(|F| + eps M) / |F'|`` measured on the loops of the paper's plant
            and on ``s + b + a e^{-s}`` (Lambert W) is 0.37: the factor 16 leaves 40 times that;
          - a cluster that floating point cannot separate (multiplicity above 1): the radius of
            its disc (:attr:`~nrobust.roots.RootSet.radii`), in which its roots are certified;
          - ``F = p(s) e^{-tau s}`` (roots of ``p`` isolated by FLINT): the radius of the ball;
          - the chain value ``c_D`` (``approached_at_infinity``): for commensurate delays the
            rounding of the root ``z`` of ``P(z) = sum_k a_k z^{n_k}``, ``16 eps sum_k |a_k z^{n_k}|
            / (|P'(z)| |z| h)`` (None for a multiple root of ``P``); otherwise the width of the
            certified bracket of ``c_D`` (``value`` is its upper end).
        """
        if self.value == -np.inf:
            return 0.0
        model = 0.0 if self.model_error is None else self.model_error
        if self.rigorous and self.value_bracket is not None:
            lo, hi = self.value_bracket
            radius = max(hi - self.value, self.value - lo)
            return (float(np.nextafter(radius, np.inf)) if radius > 0.0 else 0.0) + model
        return None if self.error_estimate is None else self.error_estimate + model

    @property
    def root_accuracy(self) -> tuple[float | None, float | None]:
        """Bounds of the errors of ``Re root`` and ``Im root``: proven (the distances to the far
        edges of ``root_box``, with ``rigorous``) or the floating-point :attr:`error_estimate` of
        the root (both parts), plus :attr:`model_error`; None if unknown or if ``value`` is the chain value."""
        if self.root is None or self.approached_at_infinity:
            return None, None
        model = 0.0 if self.model_error is None else self.model_error
        if self.rigorous and self.root_box is not None:
            x0, x1, y0, y1 = self.root_box
            re, im = self.root.real, self.root.imag
            return (
                float(np.nextafter(max(x1 - re, re - x0, 0.0), np.inf)) + model,
                float(np.nextafter(max(y1 - im, im - y0, 0.0), np.inf)) + model,
            )
        if self.error_estimate is None:
            return None, None
        return self.error_estimate + model, self.error_estimate + model

    def __repr__(self) -> str:
        """Each number labelled by what backs it: ``proven`` (ball arithmetic), ``floating point``
        (its :attr:`accuracy` an estimate), and the certified statement ``no root right of
        upper_bound`` with the bound printed to 6 digits rounded up (so the printed text is true)."""

        def rounded(x: float, up: bool) -> str:  # 6 digits, rounded outwards: a printed bound stays one
            unit = 10.0 ** (np.floor(np.log10(abs(x))) - 5.0) if np.isfinite(x) and x != 0.0 else 0.0
            text, step = f"{x:.6g}", 0.5 * unit * (1.0 if up else -1.0)
            while np.isfinite(x) and step != 0.0 and (float(text) < x if up else float(text) > x):
                text, step = f"{x + step:.6g}", 2.0 * step
            return text

        proven = self.rigorous and self.value_bracket is not None
        kind = "exact" if self.value == -np.inf else ("proven" if proven else "floating point")
        value = f"{with_accuracy(self.value, self.accuracy)} ({kind})"
        if self.root is None:
            root = "None"
        elif self.approached_at_infinity:  # not the value's source, a root of the band searched
            root = f"{self.root.real:.6g}{self.root.imag:+.6g}j"
        else:
            re, im = self.root_accuracy
            box = "proven box" if self.rigorous and self.root_box is not None else "floating point"
            root = f"({with_accuracy(self.root.real, re)}) + ({with_accuracy(self.root.imag, im)})j ({box})"
        tail = ", approached as Im s -> infinity" if self.approached_at_infinity else ""
        statement = f"certified: no root right of {rounded(self.upper_bound, True)}"
        if proven and self.value_bracket is not None:
            lo, hi = self.value_bracket
            statement += f", proven: sup Re s in [{rounded(lo, False)}, {rounded(hi, True)}]"
        return (
            f"SpectralAbscissa(value={value}, root={root}{tail}, {statement}, "
            f"chain_value={self.chain_value:.6g}, strong_bound={self.strong_bound:.6g}, "
            f"every_root_of_region_found={self.certified}" + (", rigorous=True)" if self.rigorous else ")")
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (``root`` as ``[real, imag]``, infinities as strings)."""
        return fields_dict(self)


# Bisection steps on the left edge x(R) of the root-free far field.
_EDGE_BISECTIONS = 30
# Relative width of the bracket of c_D below which a chain value counts as resolved.
_CHAIN_TOL = 1e-9
# Doublings of the far-field radius R in the march of the retarded abscissa.
_MAX_STEPS = 200
# Smallest half-height of the boxes of that march.
_MIN_HALF_HEIGHT = 1.0
# Radii (relative to the floating-point one) at which ball arithmetic tries to confirm a far field.
_RADIUS_FACTORS = (1.0, 1.0 + 1e-6, 1.01, 1.1, 1.5, 2.0, 4.0)
# Edge shifts allowed when a box edge lands on a root (a multiple root needs a wide berth).
_ABSCISSA_SHIFTS = 8
# Longest delay searched without a region: the bound of |F''| of the root count holds tau^2.
_MAX_DELAY = float(np.sqrt(np.finfo(float).max))


@runtime_checkable
class FarField(Protocol):
    """A characteristic function that bounds its own root-free far field (as
    :class:`~nrobust.hyperbolic.nplusm.NPlusMCharacteristic` does): ``spectral_abscissa``
    needs no region for it. Both answers must be monotone: a far field that holds at
    ``(x, R)`` holds at every ``(x', R')`` with ``x' >= x``, ``R' >= R``."""

    def far_field_holds(self, x: float, radius: float) -> bool:
        """True if proven root-free on ``{Re s >= x, |s| >= radius}``."""

    def far_field_radius(self, x: float) -> float | None:
        """A radius ``R`` with no root in ``{Re s >= x, |s| >= R}``, or None."""


def _is_far_field(F: Any) -> TypeGuard[FarField]:
    """``isinstance(F, FarField)``, at once for a :class:`~nrobust.quasipoly.QuasiPolynomial` (not one): the
    protocol's check looks its methods up each time (some 10 us), and the far field is asked about hundreds
    of times per abscissa."""
    return type(F) is not QuasiPolynomial and isinstance(F, FarField)


def _degree(F: QuasiPolynomial) -> int:
    """The joint degree of a quasi-polynomial; 0 for a :class:`FarField` (unused by its bounds)."""
    return 0 if _is_far_field(F) else joint_degree(F)


def _root_free_radius(F: QuasiPolynomial, x: float) -> float | None:
    """A radius ``R`` with no root of ``F`` in ``{Re s >= x, |s| >= R}``, or None.

    On that set the first principal term dominates when its gap over the other principal
    terms exceeds the remainder of :class:`nrobust.bounds.TailBound` (Rouché,
    :func:`nrobust.bounds.root_free_region`); both are monotone in ``|s|`` and ``Re s``.
    A :class:`FarField` gives its own.
    """
    if _is_far_field(F):
        return F.far_field_radius(x)
    n = joint_degree(F)
    g = principal_gap({"F": (F, 0)}, n, x)
    if g is None or g.gap <= 0.0:
        return None
    try:
        tail = TailBound(F, n, x, g.t0)
        return radius_where(lambda R: float(tail(R)), g.gap, "spectral_abscissa")
    except CertificationError:
        return None


def spectral_abscissa(
    F: QuasiPolynomial | CharacteristicFunction,
    region: ArrayLike | None = None,
    *,
    im_max: float | None = None,
    cluster_tol: float = 1e-6,
    max_evals: int = 5_000_000,
    rigorous: bool = False,
    prec: int = 53,
) -> SpectralAbscissa:
    r"""The supremum of the real parts of the roots of ``F``, with its rightmost root.

    Parameters
    ----------
    F : QuasiPolynomial, QuasiPolynomialMatrix or another CharacteristicFunction
        Retarded or neutral (an advanced ``F`` has roots with arbitrarily large real part).
    region : (re_min, re_max, im_min, im_max), optional
        Search only this rectangle. By default the search region is built so that the
        answer is certified: a half-plane ``Re s >= x`` is root-free outside a disc
        (:func:`_root_free_radius`), the rest is counted and searched. Required unless
        ``F`` is a QuasiPolynomial or bounds its own far field (:class:`FarField`, as the
        closed loop :class:`~nrobust.hyperbolic.nplusm.NPlusMCharacteristic` does): for a
        QuasiPolynomialMatrix, ``F.expand()`` is the scalar form.
    im_max : float, optional
        Height of the band searched near the chains of a neutral ``F``.
    cluster_tol, max_evals
        As in :func:`find_roots`.
    rigorous : bool, optional
        Prove the result in ball arithmetic (python-flint, ``pip install nrobust[rigorous]``):
        the root-free far field (the dominance of the principal part, the
        difference-operator bound of the chains included, re-evaluated in balls at the
        abscissa and radius used), the count of every box searched and the box of the
        rightmost root (:func:`find_roots` with ``rigorous=True``). A function other than a
        QuasiPolynomial (one with ``F.ball_function``) needs a ``region``: its far field is
        not proven in balls.
    prec : int, optional
        Working precision in bits of the ball arithmetic.

    Returns
    -------
    SpectralAbscissa

    Raises
    ------
    ParameterError
        An advanced ``F``, a bad option, without a region a delay above ``1.34e154``
        or coefficients whose root-free radius exceeds ``2^200``; ``rigorous=True`` without
        a region for a function other than a QuasiPolynomial.
    CertificationError
        The work bound ``max_evals`` (shared by every step of the search) was exhausted,
        or ``F`` overflows on a contour: the message says what would help. With
        ``rigorous=True`` also when ball arithmetic cannot confirm a step.
    ImportError
        ``rigorous=True`` without python-flint.

    Notes
    -----
    The spectral abscissa is

    .. math::

        \alpha(F) = \sup \{\operatorname{Re} s : F(s) = 0\},

    and the loop decays at every rate below :math:`-\alpha(F)`. For retarded ``F`` the search
    marches on the root-free far field
    (:func:`_retarded_abscissa`): boxes that hold every root with ``Re s >= x(R)`` grow
    until one holds a root; ``-inf`` is returned only for ``c e^{-tau s}``, which has no
    root. For neutral ``F`` with principal part ``D``, no root lies in ``Re s > C_D + m`` outside
    a disc, so the roots there are found exactly; below, the high-frequency roots
    approach the chains of ``D`` whose abscissa is ``c_D`` (Hale and Verduyn Lunel), so
    the supremum is ``max(c_D, real part of the rightmost root found)`` and may be
    approached only as ``|Im s| -> infinity`` (``approached_at_infinity``).
    """
    F = check_function(F)
    if region is None and not isinstance(F, QuasiPolynomial | FarField):
        advice = (
            "or pass F.expand(), its scalar form"
            if isinstance(F, QuasiPolynomialMatrix)
            else f"no root-free far field is known for a {type(F).__name__}"
        )
        raise ParameterError(
            "region", f"a rectangle (re_min, re_max, im_min, im_max) holding the roots sought ({advice})", None
        )
    if region is None and F.max_delay > _MAX_DELAY:
        raise ParameterError(
            "delays",
            f"at most {_MAX_DELAY:.3g} (the longest delay of F: the bounds of |F''| of the root count hold tau^2, "
            "which overflows double precision beyond)",
            F.max_delay,
        )
    if F.kind == "advanced":
        raise ParameterError("F", "retarded or neutral (an advanced quasi-polynomial has unbounded root real parts)", F)
    cluster_tol = positive("cluster_tol", cluster_tol)
    im_max = None if im_max is None else positive("im_max", im_max)
    max_evals = positive_int("max_evals", max_evals)
    proof = prec if check_rigorous(F, rigorous) else None
    if proof is not None and region is None and not _ball_far_field(F):
        raise ParameterError(
            "region",
            f"a rectangle (re_min, re_max, im_min, im_max) with rigorous=True: the root-free far field of a "
            f"{type(F).__name__} is bounded in floating point only, so the whole plane cannot be searched rigorously",
            None,
        )
    with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
        return _spectral_abscissa(F, region, im_max, cluster_tol, max_evals, proof)


def _spectral_abscissa(
    F: QuasiPolynomial,
    region: ArrayLike | None,
    im_max: float | None,
    cluster_tol: float,
    max_evals: int,
    proof: int | None = None,
) -> SpectralAbscissa:
    """``proof`` is the precision of the ball arithmetic that proves each step, or None (floating point)."""
    D = F.principal_part()
    bound = D.spectral_bound()
    chain_value = bound.upper
    c_strong = D.strong_spectral_bound()
    if region is not None:
        roots = _roots(F, region, cluster_tol, max_evals, proof)
        result = _abscissa_from(roots, chain_value, np.inf, roots.certified)
    elif np.isfinite(c_strong):
        margin = 0.1 * (1.0 + abs(c_strong))
        x_min, radius = _right_half_plane(F, c_strong + margin, margin)
        x_min, radius = _confirm_far_field(F, [(x_min, radius * f) for f in _RADIUS_FACTORS], proof)
        real = F.is_real
        result = _neutral_abscissa(F, D, x_min, radius, real, im_max, chain_value, cluster_tol, max_evals, proof)
    else:
        x_right, radius = _right_half_plane(F, 0.0, 1.0)
        result = _retarded_abscissa(F, x_right, radius, F.is_real, cluster_tol, max_evals, proof)
    result = replace(result, strong_bound=float(c_strong), rigorous=proof is not None)
    result = replace(result, error_estimate=_error_estimate(F, D, bound, result))
    if result.approached_at_infinity and bound.upper - bound.lower > _CHAIN_TOL * (1.0 + abs(bound.upper)):
        # c_D only bracketed (chains not resolved): the value is an upper bound of the supremum, not it
        result = replace(result, certified=False)
    if proof is None:
        return replace(result, root_box=None)
    # the chains only of a principal part whose coefficients are exact or known to proven radii (not
    # computed in floating point)
    radii = F.principal_radii() if isinstance(F, QuasiPolynomial) else None
    known = isinstance(F, QuasiPolynomialMatrix) or radii is not None
    return _proven_brackets(result, D if known else None, radii, region is None, _is_difference(F), proof)


def _is_difference(F: QuasiPolynomial) -> bool:
    """True if ``F`` is its own principal part, ``sum_k a_k e^{-tau_k s}`` (point terms of degree 0 only):
    its zeros are those of the difference operator, no root lies right of ``c_D``."""
    return isinstance(F, QuasiPolynomial) and not F.distributed and F.degree == 0


# Safety factor of the floating-point error estimates: 40 times the largest ratio (0.37) of the
# true error (mpmath, 40 digits) to the first-order estimate measured on the loops of the paper's
# plant and on s + b + a e^{-s} (tests/test_accuracy_digits.py).
_ESTIMATE_SAFETY = 16.0


def _error_estimate(
    F: QuasiPolynomial, D: DifferenceOperator, bound: SpectralBound, result: SpectralAbscissa
) -> float | None:
    """The floating-point estimate of ``|value - sup Re s|`` (:attr:`SpectralAbscissa.accuracy`).

    A cluster's radius or a polynomial root's ball, set when ``result`` was built, is kept.
    """
    if result.value == -np.inf:
        return 0.0
    if result.approached_at_infinity:
        return _chain_estimate(D, bound)
    if result.error_estimate is not None or result.root is None:
        return result.error_estimate
    z = np.array([result.root])
    slope = float(np.abs(F.deriv_at(z))[0])
    noise = float(np.abs(F(z))[0]) + EPS * float(magnitude(F, z)[0])
    if not (slope > 0.0 and np.isfinite(noise / slope)):
        return None
    return _ESTIMATE_SAFETY * noise / slope + EPS * abs(result.root)


def _chain_estimate(D: DifferenceOperator, bound: SpectralBound) -> float | None:
    """The error of the chain value ``c_D``: the rounding of the root ``z`` of ``P`` that gives it
    (commensurate delays ``r_k = n_k h``, a simple root), else the width of its bracket."""
    if not bound.exact:
        return float(bound.upper - bound.lower)
    chains = D.chains()
    if not chains.chains or chains.step is None or chains.chains[0].multiplicity != 1:
        return None
    z, h = chains.chains[0].z, chains.step
    n = np.rint(D.relative_delays / h)
    terms = np.abs(D.coefs) * np.abs(z) ** n
    slope = abs(np.sum(n * D.coefs * z ** (n - 1)))
    if not slope > 0.0:
        return None
    return _ESTIMATE_SAFETY * EPS * float(np.sum(terms)) / (slope * abs(z) * h)


def _proven_brackets(
    result: SpectralAbscissa,
    D: DifferenceOperator | None,
    radii: NDArray[np.float64] | None,
    whole: bool,
    difference: bool,
    prec: int,
) -> SpectralAbscissa:
    """``result`` with ``chain_bracket`` and ``value_bracket`` proven in ball arithmetic.

    ``D`` None: the principal part's coefficients are not known (computed in floating point,
    as for :class:`~nrobust.hyperbolic.nplusm.NPlusMCharacteristic`), so no chain bracket.
    ``radii``: the proven radii of ``D``'s coefficients
    (:meth:`~nrobust.quasipoly.QuasiPolynomial.principal_radii`): the chain bracket then holds ``c_D``
    of every principal part in the balls, the function's among them
    (:meth:`~nrobust.difference.DifferenceOperator.proven_spectral_bound`).

    The lower end of the chain bracket bounds the supremum from below only when the whole
    plane is searched (``whole``) or the chains are the value's source anyway; with a
    ``region`` the supremum is over the roots in it, and only ``root_box`` bounds it below.
    Its upper end bounds the supremum from above when ``F`` is a difference operator
    (``difference``: every zero lies on a chain), so its bracket is then the chains'.
    """
    chain = None
    if D is not None and np.isfinite(result.strong_bound):
        sb = D.proven_spectral_bound(prec, radii)
        chain = (sb.lower, sb.upper)
    lows = []
    if result.root_box is not None:
        lows.append(result.root_box[0])
    if chain is not None and whole:
        lows.append(chain[0])
    upper = result.upper_bound
    if chain is not None and difference:
        upper = min(upper, chain[1])
        result = replace(result, upper_bound=upper)
    if result.root is None and not lows:  # no root at all (c e^{-tau s}, or none in the region)
        value = (-np.inf, upper) if result.value == -np.inf else None
    else:
        value = (max(lows), upper) if lows else None
    result = replace(result, chain_bracket=chain, value_bracket=value)
    return result if value is None else _inside_bracket(result, value)


def _inside_bracket(result: SpectralAbscissa, bracket: tuple[float, float]) -> SpectralAbscissa:
    """``result`` with its floating-point ``value`` inside the proven ``bracket``, or CertificationError.

    A value off the bracket by rounding (``_CHAIN_TOL`` relative) is moved to its nearer end;
    further off, the floating-point search and the proof disagree, and nothing is certified.
    """
    lo, hi = bracket
    v = result.value
    if lo <= v <= hi:
        return result
    end = lo if v < lo else hi
    if abs(v - end) <= _CHAIN_TOL * (1.0 + abs(end)):
        return replace(result, value=float(end))
    raise CertificationError(
        f"the floating-point spectral abscissa {v!r} lies outside its proven bracket [{lo!r}, {hi!r}]: "
        "the roots or chains found in floating point miss a proven zero (delays close to but not equal to "
        "commensurate ones resolve only in ball arithmetic); give a region or separate the delays"
    )


def _roots(F: QuasiPolynomial, region: ArrayLike, cluster_tol: float, max_evals: int, proof: int | None) -> RootSet:
    """:func:`find_roots`, proven in ball arithmetic when ``proof`` (a precision) is given, with
    its rightmost clusters separated (:func:`_separated`) and the boxes of its rightmost roots
    contracted (:func:`_contracted`)."""
    rigorous = proof is not None
    found = find_roots(F, region, cluster_tol=cluster_tol, max_evals=max_evals, rigorous=rigorous, prec=proof or 53)
    return _contracted(F, _separated(F, found, max_evals), proof)


# Krawczyk contractions of the box of a rightmost root.
_CONTRACTIONS = 4


def _contracted(F: QuasiPolynomial, roots: RootSet, proof: int | None) -> RootSet:
    """``roots`` with the proven boxes of its rightmost simple roots contracted by Krawczyk's operator.

    A box proven to hold one simple zero (``box_counts`` 1) holds it in ``K(X) & X`` too
    (:func:`~nrobust._flint.krawczyk_image`: ``K(X)`` holds every zero in ``X``); iterated from
    the box's centre, the box shrinks from the ``1e-11 (1 + |z|)`` of the proof to the rounding
    of ``F``, and so does the upper end of the value bracket, which is the right edge of these
    boxes. Each contracted box keeps the root found in floating point (the hull with it). The
    boxes contracted are those reaching right of every box's left edge (the candidates for
    the rightmost root).
    """
    if proof is None or not roots.rigorous or not len(roots) or isinstance(F, FarField):
        return roots
    boxes = roots.boxes.copy()
    floor = float(np.max(boxes[:, 0]))
    balls = ball_function(F, proof)
    flint = require_flint()
    for i in np.flatnonzero((boxes[:, 1] >= floor) & (roots.box_counts == 1)):
        x0, x1, y0, y1 = (float(v) for v in boxes[i])
        for _ in range(_CONTRACTIONS):
            c = flint.acb(0.5 * (x0 + x1), 0.5 * (y0 + y1))
            K = krawczyk_image((x0, x1, y0, y1), c, balls(c), lambda X: balls(X, 1), prec=balls.prec)
            if K is None or not K.is_finite():
                break
            box = (
                max(x0, float(np.nextafter(float(K.real.lower()), -np.inf))),
                min(x1, float(np.nextafter(float(K.real.upper()), np.inf))),
                max(y0, float(np.nextafter(float(K.imag.lower()), -np.inf))),
                min(y1, float(np.nextafter(float(K.imag.upper()), np.inf))),
            )
            if not (box[0] <= box[1] and box[2] <= box[3]) or box == (x0, x1, y0, y1):
                break
            x0, x1, y0, y1 = box
        w = complex(roots.roots[i])
        boxes[i] = (min(x0, w.real), max(x1, w.real), min(y0, w.imag), max(y1, w.imag))
    z = roots.roots
    dx = np.maximum(np.abs(boxes[:, 0] - z.real), np.abs(boxes[:, 1] - z.real))
    dy = np.maximum(np.abs(boxes[:, 2] - z.imag), np.abs(boxes[:, 3] - z.imag))
    radii = np.where(roots.box_counts == 1, np.minimum(roots.radii, np.hypot(dx, dy)), roots.radii)
    return replace(roots, boxes=boxes, radii=radii)


def _separated(F: QuasiPolynomial, roots: RootSet, max_evals: int) -> RootSet:
    """``roots`` with the clusters that may hold the rightmost root split into simple roots.

    A cluster's centroid is not its rightmost root: the clusters whose box reaches right of
    the rightmost centroid are separated in ball arithmetic of higher precision
    (:func:`~nrobust.roots.finder.separate_clusters`) when they can be.
    """
    if _is_far_field(F) or not len(roots) or not roots.certified:
        return roots
    if int(roots.multiplicities.max()) == 1:
        return roots
    return separate_clusters(F, roots, Budget(max_evals), right_of=float(roots.roots.real.max()))


def _ball_far_field_holds(F: QuasiPolynomial, n: int, x: float, R: float, prec: int) -> bool:
    """True if ``{Re s >= x, |s| >= R}`` is proven root-free in ball arithmetic.

    The inequality of :func:`_root_free_radius` (:func:`~nrobust.bounds.principal_gap`
    against :class:`~nrobust.bounds.TailBound`), every term enclosed in balls: with ``t0``
    the delay of the first principal term (no delay of ``F`` below it) and ``r_k = tau_k - t0``,
    ``|a_0| - sum_k |a_k| e^{-r_k x}`` (the difference-operator bound, which also proves
    ``x > C_D``) exceeds ``sum |p_kj| R^(j-n) e^{-r_k x} + sum |q_j| R^(j-n) e^{t0 x} min(M_0, V / R)``
    (:func:`~nrobust.balls.ball_abs_moment`, :func:`~nrobust.balls.ball_variation_bound`).
    Each term is monotone in ``|s|`` and ``Re s``, so the strict inequality at ``(x, R)``
    holds on the whole set, where ``|e^{t0 s} F(s)| / |s|^n`` is then positive. A point
    coefficient known to a radius (``QuasiPolynomial(..., radii=...)``) enters with it: the
    gap less it for ``a_0``, the others and the tail plus it.
    """
    lead = F.leading_terms(n)
    if not lead or min_delay(F) < lead[0][1] or not (np.isfinite(x) and np.isfinite(R) and R > 0):
        return False
    t0 = lead[0][1]
    with working_precision(prec) as flint:
        arb, acb = flint.arb, flint.acb
        X, Rb, T0 = arb(float(x)), arb(float(R)), arb(float(t0))

        def weight(tau: float) -> Any:
            return (-(arb(float(tau)) - T0) * X).exp()

        gap = abs(acb(complex(lead[0][0]))) - sum((abs(acb(complex(a))) * weight(t) for a, t in lead[1:]), arb(0))
        tail = arb(0)
        for (p, t), radius in zip(F.point_terms, F.radii_of()):
            if p.size == n + 1 and radius[n] > 0:  # the s^n coefficient's ball: a_0 less it, the others more
                gap -= arb(float(radius[n])) * (arb(1) if t == t0 else weight(t))
            for j in range(min(p.size, n)):
                if p[j] != 0 or radius[j] > 0:
                    tail += (abs(acb(complex(p[j]))) + arb(float(radius[j]))) / Rb ** (n - j) * weight(t)
        for d in F.distributed:
            qpow = sum((abs(acb(complex(c))) / Rb ** (n - j) for j, c in enumerate(d.poly) if c != 0), arb(0))
            bound = ball_abs_moment(d, x, 0, prec=prec) * (T0 * X).exp()
            if d.moment == 0:
                bound = arb.min(bound, ball_variation_bound(d, x, prec=prec) * (T0 * X).exp() / Rb)
            tail += qpow * bound
        return bool(gap - tail > 0)


def _ball_far_field(F: Any) -> bool:
    """True if the far field of ``F`` can be proven in ball arithmetic: a QuasiPolynomial, or a
    :class:`FarField` with its own ``ball_far_field_holds(x, radius, prec)`` (an ``n + m`` loop)."""
    return isinstance(F, QuasiPolynomial) or callable(getattr(F, "ball_far_field_holds", None))


def _confirm_far_field(F: Any, points: list[tuple[float, float]], proof: int | None) -> tuple[float, float]:
    """The first ``(x, R)`` of ``points`` at which :func:`_ball_far_field_holds`; ``points[0]`` without ``proof``.

    A characteristic function with its own ``ball_far_field_holds`` proves its far field itself.

    The floating-point search stops where the bound just holds (a bisection), where the
    slightly looser ball bounds of ``|N|`` may not: the callers offer a few points
    further inside the region (larger ``x`` or ``R``) for which their search stays valid.
    """
    if proof is None:
        return points[0]
    if not isinstance(F, QuasiPolynomial):
        for x, R in points:
            if F.ball_far_field_holds(x, R, proof):
                return x, R
    else:
        n = joint_degree(F)
        for x, R in points:
            if _ball_far_field_holds(F, n, x, R, proof):
                return x, R
    x, R = points[-1]
    raise CertificationError(
        f"ball arithmetic cannot confirm that F has no root with Re s >= {x:.12g} and |s| >= {R:.12g}; "
        "raise prec or give a region"
    )


def _right_half_plane(F: QuasiPolynomial, x0: float, step: float) -> tuple[float, float]:
    """``(x, R)``: no root with ``Re s >= x`` and ``|s| >= R``, for the first
    ``x = x0 + step (2^j - 1)`` where :func:`_root_free_radius` finds one.

    If none does though the principal gap is positive at the last ``x`` (``F`` retarded or
    neutral), the remainder stays above the gap up to ``|s| = 2^200``: the lower-order
    coefficients dwarf the principal ones, a scale the far-field bound cannot represent.
    """
    x = x0
    for j in range(40):
        x = x0 + step * (2.0**j - 1.0)
        R = _root_free_radius(F, x)
        if R is not None:
            return x, R
    g = None if _is_far_field(F) else principal_gap({"F": (F, 0)}, joint_degree(F), x)
    if g is not None and g.gap > 0.0:
        raise ParameterError(
            "F",
            "a quasi-polynomial whose coefficients keep the root-free radius below 2^200: the lower-order terms "
            f"sum_kj |p_kj| e^{{-tau_k Re s}} / |s|^(n - j) must fall below the principal gap {g.gap:.3g} for some "
            "|s| <= 2^200 (with coefficients ~1e60 times the leading ones, the radius exceeds it, and beyond it the "
            "powers |s|^n of the bound overflow double precision); rescale s or the coefficients",
            F,
        )
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
    proof: int | None = None,
) -> SpectralAbscissa:
    """Exhaustive search of ``Re s >= x_min`` (inside the disc of ``radius``), then of a
    band below ``x_min`` near the chains.

    Right of ``x_min`` the search is the march of :func:`_march` with ``x_min`` as its
    floor, from the far field of ``Re s >= max(x_min, 0)``: it ends with the rightmost
    root, or with a radius ``R <= radius`` such that no root has ``Re s >= x_min``.
    """
    x_right, r_right = (x_min, radius) if x_min >= 0.0 else _right_half_plane(F, 0.0, 1.0)
    marched = _march(F, x_right, r_right, x_min, chain_value, real, cluster_tol, max_evals, proof)
    if isinstance(marched, SpectralAbscissa):
        return marched
    radius = min(radius, marched)
    chains = D.chains()
    period = chains.chains[0].spacing if chains.commensurate and chains.chains else 2 * np.pi / max(F.max_delay, 1e-3)
    height = float(im_max) if im_max is not None else max(radius, 100.0, 2 * period)
    # roots left of c_D do not change the value: a shallow band (e^{tau s} overflows far left for long delays)
    depth = min(0.5, 16.0 / max(F.max_delay, 1e-300))
    low = (min(chain_value, x_min) - depth, x_min, *_band(height, real))
    band = _roots(F, low, cluster_tol, max_evals, proof)
    # an uncertified band (never returned today: find_roots raises) would not bound anything
    upper = _band_edge(F, low[0], x_min, height, proof) if band.certified else x_min
    if len(band):  # a root near or right of the edge: its certified box (inside its disc) bounds the value
        upper = min(max(upper, float(np.max(band.boxes[:, 1]))), x_min)  # the right region holds no root
    return _abscissa_from(band, chain_value, upper, band.certified)


def _band_edge(F: QuasiPolynomial, x_lo: float, x_min: float, height: float, proof: int | None) -> float:
    """The least ``x`` in ``[x_lo, x_min]`` right of which every root of ``F`` was searched.

    Right of ``x_min`` the right region holds every root. The band ``[x_lo, x_min] x
    [-height, height]`` holds the others of ``|s| < height``, and the far field at radius
    ``height`` excludes ``{Re s >= x, |s| >= height}`` for ``x`` right of the edge
    :func:`_far_field_edge` (just right of ``C_D`` for a neutral ``F``: the dominance gap
    of the difference operator closes there). So no root right of that edge lies outside
    the boxes searched, and ``upper_bound`` comes down from the search edge ``x_min`` to
    it. Proven in ball arithmetic with ``proof`` (a few points towards ``x_min`` are
    offered, :func:`_confirm_far_field`); ``x_min`` if the far field does not hold at
    ``(x_min, height)`` (a band lower than the disc of the right region).
    """
    n = _degree(F)
    if not _far_field_holds(F, n, x_min, height):
        return x_min
    edge = _far_field_edge(F, n, height, x_min, x_lo)
    if proof is None:
        return edge
    offers = [(edge + f * (x_min - edge), height) for f in (0.0, 1e-9, 1e-6, 1e-3, 0.01, 0.1, 0.3, 0.5)]
    try:
        return _confirm_far_field(F, offers, proof)[0]
    except CertificationError:  # the ball bound is looser than the floating-point one near C_D
        return x_min


def _far_field_holds(F: QuasiPolynomial, n: int, x: float, R: float) -> bool:
    """True if ``F`` is proven root-free on ``{Re s >= x, |s| >= R}`` (see :func:`_root_free_radius`)."""
    if _is_far_field(F):
        return F.far_field_holds(x, R)
    g, tail = _gap_and_tail(F, n, x)
    return tail is not None and bool(tail(R) < g.gap)


# The principal gap and tail bound of a quasi-polynomial by (degree, real part), kept while it lives: the
# edges x(R) of the march at successive radii bisect the same bracket (a third of their real parts recur).
# Keyed by the object itself (its id, checked by a weak reference): equal quasi-polynomials may hold their
# terms in another order, and the bounds sum them in order.
_GAPS_AND_TAILS: dict[int, tuple[weakref.ref[QuasiPolynomial], dict[tuple[int, float], tuple[Any, TailBound | None]]]]
_GAPS_AND_TAILS = {}
# Quasi-polynomials, and real parts per quasi-polynomial, kept (each table emptied when full).
_GAPS_AND_TAILS_FUNCTIONS, _GAPS_AND_TAILS_KEPT = 64, 1024


def _gap_and_tail(F: QuasiPolynomial, n: int, x: float) -> tuple[Any, TailBound | None]:
    """:func:`~nrobust.bounds.principal_gap` of ``F`` at ``x``, and its :class:`~nrobust.bounds.TailBound` where
    the gap is positive (else None); remembered for a :class:`~nrobust.quasipoly.QuasiPolynomial`."""
    table = None
    if type(F) is QuasiPolynomial:
        entry = _GAPS_AND_TAILS.get(id(F))
        if entry is None or entry[0]() is not F:
            if len(_GAPS_AND_TAILS) >= _GAPS_AND_TAILS_FUNCTIONS:
                _GAPS_AND_TAILS.clear()
            entry = _GAPS_AND_TAILS[id(F)] = (weakref.ref(F), {})
        table = entry[1]
        found = table.get((n, x))
        if found is not None:
            return found
    g = principal_gap({"F": (F, 0)}, n, x)
    out = (g, TailBound(F, n, x, g.t0) if g is not None and g.gap > 0.0 else None)
    if table is not None:
        if len(table) >= _GAPS_AND_TAILS_KEPT:
            table.clear()
        table[(n, float(x))] = out
    return out


def _far_field_edge(F: QuasiPolynomial, n: int, R: float, x_hi: float, x_lo: float | None = None) -> float:
    """The smallest ``x`` in ``[x_lo, x_hi]`` (default ``x_lo = -R``; up to bisection, rounded
    to the right) with ``{Re s >= x, |s| >= R}`` proven root-free; the far field must hold at ``x_hi``.

    The dominance gap of the principal part increases and :class:`~nrobust.bounds.TailBound`
    decreases with ``x``, so the set of such ``x`` is a half-line.
    """
    lo, hi = -R if x_lo is None else x_lo, x_hi
    if _far_field_holds(F, n, lo, R):
        return lo
    for _ in range(_EDGE_BISECTIONS):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        if _far_field_holds(F, n, mid, R):
            hi = mid
        else:
            lo = mid
    return hi


def _is_exponential_polynomial(F: QuasiPolynomial) -> bool:
    """True if ``F = p(s) e^{-tau s}``: its far-field bound does not depend on ``Re s``."""
    return not _is_far_field(F) and len(F.point_terms) == 1 and not F.distributed


def _polynomial_abscissa(F: QuasiPolynomial, region: Region) -> SpectralAbscissa | None:
    """The abscissa of ``F = p(s) e^{-tau s}`` with real ``p`` in exact arithmetic, or None.

    The float coefficients of ``p`` are rationals; python-flint (the ``rigorous`` extra)
    isolates the roots of their square-free parts in certified balls. This resolves
    what no floating-point evaluation of ``F`` can: a multiple root (exactly) and a
    cluster of roots closer than the rounding limit ``eps^(1/m)`` (six roots ``1e-3``
    apart near ``s = -1`` have ``|F|`` below the rounding error of ``F`` between them).
    None without python-flint or for complex coefficients: the caller searches by counts.
    """
    try:
        flint = require_flint()
    except ImportError:
        return None
    p = F.point_terms[0][0]
    if np.iscomplexobj(p) and np.any(np.imag(p) != 0):
        return None
    coefs = [flint.fmpq(*float(c).as_integer_ratio()) for c in np.real(p)]
    roots: list[Any] = list(flint.fmpq_poly(coefs).complex_roots())  # (acb ball, multiplicity) pairs
    if not roots:  # a nonzero constant times e^{-tau s}
        return SpectralAbscissa(-np.inf, None, False, -np.inf, -np.inf, True, region)
    re = np.array([float(z.real.mid()) for z, _ in roots])
    im = np.array([float(z.imag.mid()) for z, _ in roots])
    top = np.array([float(z.real.upper()) for z, _ in roots])
    best = np.flatnonzero(re == re.max())
    i = int(best[np.argmax(im[best])])  # of a conjugate pair, the root with Im s >= 0
    upper = float(np.nextafter(top.max(), np.inf))
    z = roots[i][0]  # its ball, as the proven box of the rightmost root (kept with rigorous=True)
    box = (
        float(np.nextafter(float(z.real.lower()), -np.inf)),
        float(np.nextafter(float(z.real.upper()), np.inf)),
        float(np.nextafter(float(z.imag.lower()), -np.inf)),
        float(np.nextafter(float(z.imag.upper()), np.inf)),
    )
    # the root's distance to the far edges of its ball
    ball = max(box[1] - re[i], re[i] - box[0], box[3] - im[i], im[i] - box[2])
    return SpectralAbscissa(
        float(re[i]), complex(re[i], im[i]), False, -np.inf, upper, True, region, root_box=box, error_estimate=ball
    )


def _retarded_abscissa(
    F: QuasiPolynomial,
    x_right: float,
    radius: float,
    real: bool,
    cluster_tol: float,
    max_evals: int,
    proof: int | None = None,
) -> SpectralAbscissa:
    """The rightmost root of a retarded ``F`` by a march on the root-free far field (:func:`_march`).

    A retarded ``F`` of degree ``n >= 1`` has roots (infinitely many if it has a delayed
    term), so the march ends with a root; the abscissa ``-inf`` is certified only for
    ``F = p(s) e^{-tau s}`` (its far-field bound holds for every ``Re s``, ``x(R) = -inf``),
    when the box ``[-R, R] x [-R, R]`` holds no root: ``F = c e^{-tau s}``. Otherwise the
    march ends with :class:`~nrobust.errors.CertificationError` when the work bound
    ``max_evals`` (shared by all steps) is exhausted.
    """
    if _is_exponential_polynomial(F) and F.exact_points:  # the roots of p itself (not of a ball of them)
        half = 1.01 * max(radius, _MIN_HALF_HEIGHT)
        exact = _polynomial_abscissa(F, (-half, half, *_band(half, real)))
        if exact is not None:
            return exact
    marched = _march(F, x_right, radius, -np.inf, -np.inf, real, cluster_tol, max_evals, proof)
    if isinstance(marched, SpectralAbscissa):
        return marched
    raise AssertionError("unreachable: a march without a floor ends with a root or an error")


def _march(
    F: QuasiPolynomial,
    x_right: float,
    radius: float,
    x_floor: float,
    chain_value: float,
    real: bool,
    cluster_tol: float,
    max_evals: int,
    proof: int | None = None,
) -> SpectralAbscissa | float:
    """The rightmost root of ``F`` right of ``x_floor`` by a march on the root-free far field.

    No root has ``Re s >= x_max = max(x_right, radius) + 1`` (the roots with
    ``Re s >= x_right`` lie in ``|s| < radius``). For a radius ``R``, ``F`` has no root in
    ``{Re s >= x(R), |s| >= R}`` (:func:`_far_field_edge`, not below ``x_floor``), so every
    root with ``Re s >= x(R)`` lies in the box ``[x(R), min(x_max, R)] x [-R, R]``. The
    march starts from the smallest ``R = radius 2^-k >= 1`` for which the far field holds at
    ``x_max`` (``x(R)`` is then far right and the box small) and doubles ``R``, which moves
    ``x(R)`` to the left (for long delays by about ``ln 2 / tau`` per step: the rightmost
    roots of ``s + a + b e^{-tau s}`` sit near the axis, at ``|s| ~ |b| e^{-tau Re s}``). It
    stops at the first box holding a root with ``Re s >= x(R)``: that root is the
    rightmost one of ``F``. The boxes grow geometrically, so the work is about twice
    that of the last box, and only the band that can hold the rightmost root is searched.

    For a neutral ``F`` the far field holds only right of ``C_D``: ``x_floor`` is the left
    edge of a far field already established. When ``x(R)`` reaches it and no root lies
    right of it, the march returns that ``R``: no root has ``Re s >= x_floor`` and
    ``|s| >= R``, nor (the box being counted) ``|s| < R``. The far field at ``x_floor``
    may need an astronomical radius (the distributed terms grow like ``e^{-nu Re s}``
    left of the axis) where the rightmost root sits near the axis at a moderate
    ``R``: the march finds it without searching that disc.
    """
    n = _degree(F)
    x_max = max(x_right, radius) + 1.0
    whole = _is_exponential_polynomial(F)
    # boxes are at least _MIN_HALF_HEIGHT high: start there, or lower while the far field holds at x_max
    R = max(radius, _MIN_HALF_HEIGHT)
    while 0.5 * R >= _MIN_HALF_HEIGHT and _far_field_holds(F, n, x_max, 0.5 * R):
        R *= 0.5
    budget = Budget(max_evals)
    for _ in range(_MAX_STEPS):
        half = 1.01 * max(R, _MIN_HALF_HEIGHT)  # edges off the disc |s| < R that holds the roots
        reg: Region = (0.0, 0.0, 0.0, 0.0)
        found: RootSet | None = None
        x_far = -np.inf if whole else _far_field_edge(F, n, R, x_max, max(-R, x_floor))
        box = (max(x_far, -half), min(x_max, half), *_band(half, real))
        if box[0] < box[1]:  # else no root has Re s >= x_far
            finder = Finder(F, box, cluster_tol, budget)
            total, reg, shifted = count_with_shifts(finder.counter, box, _ABSCISSA_SHIFTS)
            if total > 0:
                roots = found = find_counted(finder, total, reg, shifted, np.zeros(0, dtype=complex))
                # a root left of x_far (in an edge shift) may have unseen roots to its right
                if len(roots) and np.max(roots.roots.real) >= x_far:
                    if proof is not None:  # the two far fields and the box, proven
                        # every root has Re s < x_max: |s| < radius + 1 where Re s >= x_right
                        _confirm_far_field(F, [(x_right, radius + f) for f in (0.0, 1e-6, 0.01, 0.5, 1.0)], proof)
                        if not whole:  # every root with Re s >= x lies in the box, if x > x_far
                            top = float(np.max(roots.roots.real))
                            _confirm_far_field(
                                F, [(x_far + f * (top - x_far), R) for f in (0, 1e-6, 0.01, 0.5, 1)], proof
                            )
                        roots = prove(F, roots, ball_function(F, proof), Budget(max_evals), _ABSCISSA_SHIFTS)
                    roots = _contracted(F, _separated(F, roots, max_evals), proof)
                    return _abscissa_from(roots, chain_value, x_max, roots.certified, upper_from_roots=roots.certified)
            elif whole:  # p(s) e^{-tau s} with no root at all: p is a nonzero constant
                if proof is not None and ball_count_with_shifts(ball_function(F, proof), reg, 0, budget)[0] != 0:
                    raise CertificationError(f"ball arithmetic does not confirm that {reg} holds no root")
                return SpectralAbscissa(-np.inf, None, False, -np.inf, -np.inf, True, reg)
        if np.isfinite(x_floor) and x_far <= x_floor:  # no root right of the floor: the caller searches left of it
            if proof is not None and box[0] < box[1]:
                _confirm_far_field(F, [(x_floor, R * f) for f in (1.0, 1.0 + 1e-6, 1.0 + 1e-4, 1.005)], proof)
                _prove_left_of(F, found, reg, x_floor, max_evals, proof)
            return R
        R *= 2.0
    raise CertificationError(f"spectral_abscissa: no root found with |s| < {R:.6g}; raise max_evals or give a region")


def _prove_left_of(
    F: QuasiPolynomial, found: RootSet | None, reg: Region, x_floor: float, max_evals: int, proof: int
) -> None:
    """Prove in ball arithmetic that the box ``reg`` holds no root with ``Re s >= x_floor``
    (``found``: its roots found in floating point, None if it counted none), or raise CertificationError."""
    balls = ball_function(F, proof)
    if found is None:
        if ball_count_with_shifts(balls, reg, 0, Budget(max_evals))[0] != 0:
            raise CertificationError(f"ball arithmetic does not confirm that {reg} holds no root")
        return
    roots = prove(F, found, balls, Budget(max_evals), _ABSCISSA_SHIFTS)
    if float(np.max(roots.boxes[:, 1])) >= x_floor:
        raise CertificationError(
            f"ball arithmetic cannot place the roots of {reg} left of Re s = {x_floor:.12g}; give a region"
        )


def _abscissa_from(
    roots: RootSet, chain_value: float, upper: float, certified: bool, upper_from_roots: bool = False
) -> SpectralAbscissa:
    if len(roots):
        right = roots.roots.real.max()
        near = np.flatnonzero(roots.roots.real >= right - 1e-12 * (1.0 + abs(right)))
        i = int(near[np.argmax(roots.roots.imag[near])])  # of a conjugate pair, the root with Im s >= 0
        z = complex(roots.roots[i])
        root: complex | None = z
        # every entry's roots lie within its radius: the disc reaching furthest right bounds them all
        # (proven boxes: their right edges, which the discs contain)
        reach = roots.boxes[:, 1] if roots.rigorous else roots.roots.real + roots.radii
        best = float(np.max(reach)) if upper_from_roots else z.real
    else:
        root, best = None, -np.inf
    if chain_value == np.inf:  # a chain at +inf: the principal part's roots were not located
        raise CertificationError(
            "spectral abscissa: the chains of the principal part were not located (a root of its polynomial at 0); "
            "drop negligible terms of the principal part, or rescale"
        )
    found = -np.inf if root is None else root.real
    at_inf = bool(np.isfinite(chain_value) and chain_value > found + 1e-12 * (1 + abs(chain_value)))
    value = chain_value if at_inf else found
    upper_bound = best if upper_from_roots else max(upper, value)
    box, cluster = None, None
    if root is not None:
        k = int(np.flatnonzero(roots.roots == root)[0])
        if roots.multiplicities[k] > 1:  # its roots lie within the radius of the centroid
            cluster = float(roots.radii[k])
        if roots.rigorous:
            b = roots.boxes[k]
            box = (float(b[0]), float(b[1]), float(b[2]), float(b[3]))
    return SpectralAbscissa(
        float(value),
        root,
        at_inf,
        float(chain_value),
        float(upper_bound),
        bool(certified),
        roots.region,
        root_box=box,
        error_estimate=cluster,
    )
