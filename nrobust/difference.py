"""Difference operators ``D(s) = sum_k a_k e^{-tau_k s}``: strong stability and root chains.

The principal part of a neutral quasi-polynomial is a difference operator: for
``|s| -> infinity`` in a vertical strip ``F(s) = s^n (D(s) + O(1/s))``, so the
high-frequency roots of ``F`` lie on the chains of zeros of ``D``. In the paper this is
the operator ``1 - rho q e^{-tau s} (+ rho q e^{-(tau + delta) s})`` whose strong
stability (``|rho q| < 1/2`` with the finite-time controller ``U_BS``) decides
delay-robustness (paper, Section 3, after eq. (10), citing Hale and
Verduyn Lunel, "Strong stabilization of neutral functional differential equations",
2002).

Notation. With ``tau_0 < tau_1 < ...`` and ``r_k = tau_k - tau_0``, the zeros of ``D``
are those of ``a_0 + sum_{k>=1} a_k e^{-r_k s}``.

* ``gamma_0 = sum_{k>=1} |a_k| / |a_0|``; ``D`` is *strongly stable* (exponentially
  stable for every small perturbation of the delays) iff ``gamma_0 < 1``.
* ``c_D = sup {Re s : D(s) = 0}``, the spectral bound.
* ``C_D``: the real root of ``sum_{k>=1} |a_k| e^{-r_k c} = |a_0|``. It is the supremum
  of ``c_D`` over small perturbations of the delays; ``c_D <= C_D``, with equality for
  rationally independent delays (Hale and Verduyn Lunel, 2002; "Introduction to
  Functional Differential Equations", 1993, Chapter 9).
* Commensurate delays ``r_k = n_k h`` (integers ``n_k``): ``D = 0`` iff the polynomial
  ``P(z) = sum_k a_k z^{n_k}`` vanishes at ``z = e^{-h s}``, so every root ``z_i`` gives a
  vertical chain ``s = (-ln z_i + 2 pi i m) / h``, ``m`` in Z.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache
from math import gcd, lcm
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._flint import krawczyk, precision, radius_acb, working_precision
from ._json import fields_dict, json_safe
from ._newton import newton
from ._validate import number_array, read_only, read_only_state, real_array
from .errors import CertificationError, ParameterError

__all__ = ["Chain", "Chains", "DifferenceOperator", "SpectralBound"]

# Commensurability test: every ratio r_k / r_max must agree with a fraction of
# denominator <= _MAX_DENOMINATOR to within _COMMENSURATE_RTOL; the common step is then
# h = r_max / lcm(denominators) and the degree of P is lcm(denominators) <= _MAX_DEGREE.
_COMMENSURATE_RTOL = 1e-10
_MAX_DENOMINATOR = 1000
_MAX_DEGREE = 1000
# Roots of P closer than this (relative to |z|) are merged into one multiple root.
_MULTIPLE_RTOL = 1e-6
# Seeds (per chain, on the rightmost chains) for the certified lower bound of c_D when
# the delays are incommensurate.
_LOWER_BOUND_SEEDS = 32
_LOWER_BOUND_CHAINS = 4
# Largest degree of the commensurate approximation that seeds the lower bound.
_APPROX_DEGREE = 128
# Delays too close for a commensurate approximation of degree <= _MAX_DEGREE seed the lower
# bound from a grid over one beat period 2 pi / g of the closest pair (gap g), pi / r_max
# apart (half the spacing of the roots of the longest delay): at most this many seeds.
_BEAT_SEEDS = 10_000


@lru_cache(maxsize=128)
def _polynomial_roots(
    coefs: tuple[complex, ...], powers: tuple[int, ...]
) -> tuple[NDArray[np.complex128], NDArray[np.int64]]:
    """Clustered roots of ``sum_k coefs[k] z^powers[k]`` (cached: sweeps and root finding
    ask again for the same principal part, and a companion matrix of degree 1000 costs
    about a second).

    The companion matrix is that of the polynomial made monic by the larger of its end
    coefficients (of ``z^N P(1/z)``, its roots inverted, when the constant term is the
    larger): its entries ``a_k / a_end`` are then the smaller, so a negligible top coefficient
    (``0.1 - 0.06 z^15 + 5.5e-18 z^16``) does not make them ``1e16`` and bury the fifteen roots
    of modulus about 1 in their rounding. A root 0 of the matrix so chosen (``P`` and its
    reverse have none) is rounding too, of a root of extreme modulus. A root ``w = 0`` of the
    reverse (``|z|`` beyond its resolution: a chain far left) is taken from the matrix of ``P``,
    its largest roots, which resolve it; a root ``z = 0`` of ``P``'s matrix (a chain far right)
    from the reverse's inverted roots when they are all doubles. When neither resolves the
    extreme roots (the moduli span more than double precision; an overflow of a matrix too), a
    CertificationError: a root 0 would put a chain at ``+inf``, a root ``inf`` one at ``-inf``.
    """
    poly = np.zeros(powers[-1] + 1, dtype=complex)
    poly[list(powers)] = coefs
    degree = powers[-1]
    try:
        with np.errstate(all="ignore"):
            forward = np.roots(poly[::-1]) if abs(poly[-1]) >= abs(poly[0]) else None
            roots = forward
            if forward is None:  # w = 1/z of w^N P(1/w); its roots w = 0 from P's own matrix, largest first
                inverse = np.roots(poly)
                zero = inverse == 0
                roots = 1.0 / inverse[~zero]
                if np.any(zero):
                    full = np.roots(poly[::-1])
                    roots = np.concatenate([roots, full[np.argsort(-np.abs(full), kind="stable")][: int(zero.sum())]])
            elif np.any(forward == 0):
                inverse = np.roots(poly)
                inverted = 1.0 / inverse
                if inverse.size == degree and np.all(np.isfinite(inverted)):
                    roots = inverted
    except np.linalg.LinAlgError as exc:  # the companion matrix overflows (coefficients of extreme ratio)
        raise _unresolved(poly) from exc
    if roots is None or roots.size != degree or not np.all(np.isfinite(roots)) or np.any(roots == 0):
        raise _unresolved(poly)
    return cluster_polynomial_roots(roots.astype(complex))


def _unresolved(poly: NDArray[np.complex128]) -> CertificationError:
    """The error of a principal part whose extreme root chains double precision cannot locate."""
    nonzero = np.log10(np.abs(poly[poly != 0]))
    return CertificationError(
        f"the principal part's coefficients span a ratio of 1e{float(np.max(nonzero) - np.min(nonzero)):.0f}, "
        "beyond double precision: its root chains cannot be located (drop the negligible terms, or rescale)"
    )


def _complex_if_needed(a: NDArray) -> NDArray:
    return a if np.iscomplexobj(a) and np.any(a.imag != 0) else a.real.astype(float)


def cluster_polynomial_roots(z: NDArray[np.complex128]) -> tuple[NDArray[np.complex128], NDArray[np.int64]]:
    """Group numerically coincident polynomial roots; return cluster means and sizes."""
    z = z[np.argsort(-np.abs(z), kind="stable")]
    used = np.zeros(z.size, dtype=bool)
    centers: list[complex] = []
    sizes: list[int] = []
    for i in range(z.size):
        if used[i]:
            continue
        near = (~used) & (np.abs(z - z[i]) <= _MULTIPLE_RTOL * abs(z[i]))
        m = int(np.count_nonzero(near))
        while True:  # a root of multiplicity m is split by ~eps^(1/m): widen the net to that scale
            radius = max(_MULTIPLE_RTOL, 4 * np.finfo(float).eps ** (1.0 / (m + 1))) * abs(z[i])
            wider = (~used) & (np.abs(z - z[i]) <= radius)
            if int(np.count_nonzero(wider)) <= m:
                break
            m = int(np.count_nonzero(wider))
            near = wider
        used |= near
        centers.append(complex(np.mean(z[near])))
        sizes.append(m)
    return np.array(centers, dtype=complex), np.array(sizes, dtype=np.int64)


@dataclass(frozen=True)
class Chain:
    """One vertical chain of zeros ``s_m = real + i (offset + m * spacing)``, ``m`` in Z.

    Attributes
    ----------
    real : float
        The abscissa ``-ln|z| / h`` of the chain.
    offset : float
        ``-arg(z) / h``: the imaginary part of the zero with ``m = 0``.
    spacing : float
        ``2 pi / h``.
    multiplicity : int
        Multiplicity of ``z`` as a root of ``P`` (and of every zero on the chain).
    z : complex
        The root of ``P(z) = sum_k a_k z^{n_k}``.
    """

    real: float
    offset: float
    spacing: float
    multiplicity: int
    z: complex

    def points(self, im_min: float, im_max: float) -> NDArray[np.complex128]:
        """Zeros of the chain with ``im_min <= Im s <= im_max``."""
        m0 = int(np.ceil((im_min - self.offset) / self.spacing))
        m1 = int(np.floor((im_max - self.offset) / self.spacing))
        m = np.arange(m0, m1 + 1)
        return (self.real + 1j * (self.offset + m * self.spacing)).astype(np.complex128)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (``z`` as ``[real, imag]``)."""
        return fields_dict(self)


@dataclass(frozen=True)
class Chains:
    """The zero chains of a difference operator.

    Attributes
    ----------
    commensurate : bool
        True if the delays are commensurate (then ``chains`` is exhaustive); also True for
        a single-term operator, which has no zeros.
    step : float or None
        The common step ``h`` of commensurate delays (None for a single term).
    chains : tuple of Chain
        The chains, rightmost first (empty if incommensurate or if ``D`` has one term).
    bracket : tuple of float
        ``(lower, upper)`` enclosing ``c_D``; ``lower == upper`` when commensurate.
    """

    commensurate: bool
    step: float | None
    chains: tuple[Chain, ...]
    bracket: tuple[float, float]

    def points(self, im_min: float, im_max: float) -> NDArray[np.complex128]:
        """All zeros of ``D`` on the chains with ``im_min <= Im s <= im_max`` (one per zero)."""
        if not self.chains:
            return np.zeros(0, dtype=complex)
        return np.concatenate([c.points(im_min, im_max) for c in self.chains])

    def __len__(self) -> int:
        return len(self.chains)

    def __repr__(self) -> str:
        if not self.commensurate:
            return f"Chains(incommensurate delays, c_D in [{self.bracket[0]:.6g}, {self.bracket[1]:.6g}])"
        lines = ", ".join(
            f"Re s = {c.real:.6g}" + (f" (x{c.multiplicity})" if c.multiplicity > 1 else "") for c in self.chains
        )
        if self.step is None:
            return "Chains(none: a single term has no zeros)"
        return f"Chains(h={self.step:.6g}, spacing={2 * np.pi / self.step:.6g}: {lines})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (a ``-inf`` end of ``bracket`` as ``"-inf"``)."""
        return fields_dict(self)


@dataclass(frozen=True)
class SpectralBound:
    """The spectral bound ``c_D = sup {Re s : D(s) = 0}`` or a certified bracket of it.

    Attributes
    ----------
    lower, upper : float
        ``lower <= c_D <= upper``; equal when ``exact``. ``-inf`` when ``D`` has no zero.
    exact : bool
        True for commensurate delays (``c_D`` from the roots of ``P(z)``); False for a bracket of
        every operator whose coefficients lie in balls (``radii``), commensurate or not.
    step : float or None
        The common step ``h`` when exact.
    proven : bool
        True if ``lower <= c_D <= upper`` is proven in ball arithmetic for ``D`` as represented
        (:meth:`DifferenceOperator.proven_spectral_bound`).
    """

    lower: float
    upper: float
    exact: bool
    step: float | None
    proven: bool = False

    @property
    def value(self) -> float:
        """``c_D`` when exact, else the certified upper end of the bracket."""
        return self.upper

    def __repr__(self) -> str:
        if self.exact:
            return f"SpectralBound(c_D={self.upper:.12g}, exact, h={self.step})"
        return f"SpectralBound(c_D in [{self.lower:.12g}, {self.upper:.12g}], bracket)"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (infinite values as strings)."""
        return fields_dict(self)


@dataclass(frozen=True, eq=False)
class DifferenceOperator:
    """``D(s) = sum_k a_k e^{-tau_k s}`` with ``a_0 != 0`` at the smallest delay.

    Parameters
    ----------
    coefs : array_like
        Coefficients ``a_k`` (real or complex), one per delay.
    delays : array_like
        Delays ``tau_k >= 0``; equal delays are merged, zero coefficients away from the
        smallest delay are dropped.

    Raises
    ------
    ParameterError
        Empty ``coefs``, mismatched lengths, negative or non-finite ``delays``,
        non-finite ``coefs``, or ``a_0 = 0`` at the smallest delay.

    Examples
    --------
    >>> D = DifferenceOperator([1, -0.85, 0.1], [0, 2, 2.1])
    >>> round(D.gamma_0, 12), D.is_strongly_stable()
    (0.95, True)
    """

    coefs: NDArray
    delays: NDArray[np.float64]

    def __init__(self, coefs: ArrayLike, delays: ArrayLike) -> None:
        # a single number is a one-term operator; booleans and strings are refused, not converted
        a = number_array("coefs", [coefs] if isinstance(coefs, numbers.Number) else coefs).astype(complex)
        t = real_array("delays", [delays] if isinstance(delays, numbers.Number) else delays)
        if t.shape != a.shape:
            raise ParameterError("delays", f"one delay per coefficient ({a.size})", delays)
        if np.any(t < 0):
            raise ParameterError("delays", ">= 0", delays)
        if np.all(t[1:] > t[:-1]):  # distinct increasing delays (principal parts): nothing to merge or sort
            uniq, merged = t, a
        else:
            uniq, inverse = np.unique(t, return_inverse=True)
            merged = np.zeros(uniq.size, dtype=complex)
            np.add.at(merged, inverse, a)
        if merged[0] == 0:
            raise ParameterError("coefs", f"nonzero at the smallest delay {uniq[0]:g} (a_0 != 0)", coefs)
        keep = merged != 0
        # copies of the caller's arrays (number_array, real_array, the boolean selection), marked read-only
        object.__setattr__(self, "coefs", read_only(_complex_if_needed(merged[keep])))
        object.__setattr__(self, "delays", read_only(uniq[keep]))

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Unpickled or deep-copied: its arrays marked read-only again (numpy's pickles drop the flag)."""
        read_only_state(self, state)

    # ------------------------------------------------------------------ evaluation
    def __call__(self, s: ArrayLike) -> NDArray[np.complex128]:
        """Evaluate ``D(s)`` on an array of complex ``s``."""
        s = np.asarray(s, dtype=complex)
        out = np.zeros(s.shape, dtype=complex)
        for a, t in zip(self.coefs, self.delays):
            out += a * np.exp(-t * s)
        return out

    @property
    def relative_delays(self) -> NDArray[np.float64]:
        """``r_k = tau_k - tau_0``."""
        return self.delays - self.delays[0]

    # ------------------------------------------------------------------ strong stability
    @property
    def gamma_0(self) -> float:
        """``sum_{k>=1} |a_k| / |a_0|`` (Hale and Verduyn Lunel's ``gamma_0``; ``inf`` when it overflows)."""
        with np.errstate(over="ignore"):
            return float(np.sum(np.abs(self.coefs[1:])) / abs(self.coefs[0]))

    def is_strongly_stable(self) -> bool:
        """True iff ``gamma_0 < 1``: exponentially stable for all small delay perturbations."""
        return self.gamma_0 < 1.0

    def strong_spectral_bound(self) -> float:
        """``C_D``: the real ``c`` with ``sum_{k>=1} |a_k| e^{-r_k c} = |a_0|``.

        ``C_D`` is the supremum of the spectral bound over small perturbations of the
        delays (Hale and Verduyn Lunel, 2002); ``C_D < 0`` iff strongly stable.
        Returns ``-inf`` for a single-term operator (no zeros).
        """
        if self.coefs.size == 1:
            return -np.inf
        mags = np.abs(self.coefs[1:])
        r = self.relative_delays[1:]
        a0 = abs(self.coefs[0])

        # g(c) = sum |a_k| e^{-r_k c} - |a_0| decreases strictly from +inf to -|a_0| and is convex;
        # each term alone bounds the root: |a_k| e^{-r_k c} = |a_0| at c_k, so C_D >= max c_k.
        # Newton's method from that bound climbs monotonically to the root (a tangent of a convex
        # function lies below it), by steps of at most 1/r_min, and converges quadratically.
        log_mags = np.log(mags)  # the terms as exp(log |a_k| - r_k c): no overflow of e^{-r_k c} alone
        c = float(np.max((log_mags - np.log(a0)) / r))
        for _ in range(200):
            terms = np.exp(log_mags - r * c)
            value = float(np.sum(terms)) - a0
            if value <= 0.0:
                return c
            step = value / float(np.sum(r * terms))
            if step <= 4 * np.finfo(float).eps * (1.0 + abs(c)):
                return c + step
            c += step
        raise RuntimeError(f"strong_spectral_bound: Newton's method did not converge for {self!r}")

    # ------------------------------------------------------------------ commensurate delays
    def commensurate_step(self) -> tuple[float, NDArray[np.int64]] | None:
        """``(h, n)`` with ``r_k = n_k h`` if the delays are commensurate, else None.

        Each ratio ``r_k / r_max`` is matched by a fraction of denominator at most 1000
        within a relative tolerance of 1e-10; the degree ``lcm`` of the denominators is
        at most 1000 (the companion matrix of ``P`` then has at most 1000 rows). ``h`` is the
        least-squares fit of ``r_k = n_k h``.
        """
        r = self.relative_delays
        if r.size == 1:
            return None
        return commensurate(r, _MAX_DEGREE)

    def _z_roots(self, h: float, n: NDArray[np.int64]) -> tuple[NDArray[np.complex128], NDArray[np.int64]]:
        """Roots of ``P(z) = sum_k a_k z^{n_k}`` (clustered, with multiplicities)."""
        z, m = _polynomial_roots(tuple(complex(a) for a in self.coefs), tuple(int(k) for k in n))
        return z.copy(), m.copy()

    def chains(self) -> Chains:
        """The zero chains of ``D``.

        For commensurate delays ``r_k = n_k h`` each root ``z_i`` of ``P`` gives the chain
        ``s = (-ln|z_i| + i(2 pi m - arg z_i)) / h``; otherwise only the bracket of
        :meth:`spectral_bound` is returned.
        """
        if self.coefs.size == 1:
            return Chains(True, None, (), (-np.inf, -np.inf))
        found = self.commensurate_step()
        if found is None:
            sb = self.spectral_bound()
            return Chains(False, None, (), (sb.lower, sb.upper))
        h, n = found
        return chains_of(h, *self._z_roots(h, n))

    # ------------------------------------------------------------------ spectral bound
    def spectral_bound(self) -> SpectralBound:
        """``c_D = sup {Re s : D(s) = 0}``.

        Exact (``lower == upper``) for commensurate delays. Otherwise a certified bracket:
        ``upper = C_D`` (no zero with ``Re s > C_D``, since there ``|a_0| >
        sum |a_k e^{-r_k s}|``) and ``lower`` the real part of a zero located by Newton's
        method from a commensurate approximation of the delays and proven by a certified
        argument-principle count in a small box around it, minus the half-width of that
        box.
        """
        if self.coefs.size == 1:
            return SpectralBound(-np.inf, -np.inf, True, None)
        found = self.commensurate_step()
        if found is not None:
            h, n = found
            z, _ = self._z_roots(h, n)
            c = float(np.max(-np.log(np.abs(z)) / h))
            return SpectralBound(c, c, True, h)
        upper = self.strong_spectral_bound()
        return SpectralBound(self._certified_lower_bound(upper), upper, False, None)

    def commensurate_approximation(self, max_degree: int = _MAX_DEGREE) -> DifferenceOperator:
        """A commensurate operator with the same coefficients and nearby delays (seeds).

        ``r_k ~ n_k h`` with ``h = r_max / L``, ``L <= 128`` chosen to minimise the largest
        relative error with distinct ``n_k >= 1``; when two delays are closer than
        ``r_max / 128`` (a small loop delay next to the round trip), ``L`` grows until
        they are separated (``L > 1/gap`` suffices), up to the degree bound ``max_degree``
        (default 1000; a ParameterError beyond it).
        """
        r = self.relative_delays
        ratios = r / r[-1]
        gap = float(np.min(np.diff(ratios)))
        top = max(_APPROX_DEGREE, int(np.ceil(1.0 / gap)) + 1)
        if top > max_degree:
            raise ParameterError("delays", f"with relative gaps above 2/{max_degree} for chain seeding", self.delays)
        best: tuple[float, int] = (np.inf, 0)
        for L in range(1, top + 1):
            n = np.rint(ratios * L)
            if np.any(n[1:] < 1) or np.any(np.diff(n) <= 0):
                continue
            err = float(np.max(np.abs(n / L - ratios)))
            if err < best[0] - 1e-15:
                best = (err, L)
        L = best[1]
        approx = np.rint(ratios * L) * (r[-1] / L)
        return DifferenceOperator(self.coefs, approx + self.delays[0])

    def _certified_lower_bound(self, upper: float) -> float:
        """A certified lower bound of ``c_D`` for incommensurate delays (see spectral_bound).

        Newton from the chains of a commensurate approximation finds candidate roots; a
        root is proven to lie within ``r`` of a candidate by :func:`_kantorovich_radius`,
        so ``c_D >= Re s - r``.
        """
        rel = DifferenceOperator(self.coefs, self.relative_delays)
        try:
            approx: Chains | None = rel.commensurate_approximation().chains()
        except ParameterError:  # delays too close to seed from a commensurate approximation
            seeds = _beat_seeds(rel, upper)
            approx = _merged_chains(rel) if seeds.size == 0 else None
        if approx is not None:
            right = approx.chains[:_LOWER_BOUND_CHAINS]
            seeds = np.concatenate(
                [c.points(-1e-9, c.offset % c.spacing + _LOWER_BOUND_SEEDS * c.spacing) for c in right]
                + [np.zeros(0, dtype=complex)]
            )
        if seeds.size == 0:
            return -np.inf
        s = _newton_difference(rel, seeds)
        s = s[np.isfinite(s)]
        for cand in s[np.argsort(-s.real)][:8]:
            r = _kantorovich_radius(rel, complex(cand))
            if r is not None:
                return float(min(cand.real - r, upper))
        return -np.inf

    def proven_spectral_bound(self, prec: int = 53, radii: ArrayLike | None = None) -> SpectralBound:
        """``c_D`` of ``D`` as represented, bracketed in ball arithmetic (python-flint).

        The stored floats of the delays are taken as exact numbers, and so are those of the
        coefficients unless ``radii`` are given: then the bracket holds ``c_D`` of every
        operator ``sum_k b_k e^{-tau_k s}`` with each ``b_k`` within ``radii[k]`` of ``a_k``
        (real and imaginary parts each), e.g. the principal part of a loop whose gains are
        irrational numbers rounded to doubles (``QuasiPolynomial(..., radii=...)``).

        * Delays exactly commensurate as stored (every ``r_k`` an integer multiple
          ``n_k H`` of one rational ``H``, e.g. dyadic delays ``0, 1, 2.5``; ``n_k <= 1000``):
          the roots of ``P(z) = sum_k a_k z^{n_k}`` are isolated by FLINT (exact rational
          coefficients, multiplicities included) and ``c_D = max_i -ln|z_i| / H`` is enclosed
          in ``arb``: a tight bracket, ``exact=True``. With ``radii``, each root ``m_i`` of the
          stored ``P`` (simple roots only) is the centre of a disc of radius
          ``deg P |P(m_i)| / |P'(m_i)|``, ``P`` and ``P'`` enclosed with the coefficients'
          balls: every polynomial of the balls has a root in each disc (the disc of radius
          ``n |p / p'|`` about any point holds a root of a polynomial ``p`` of degree ``n``);
          when the discs are disjoint and no ball of ``a_0`` or of the leading coefficient
          holds 0, it has exactly one root in each, and its ``c_D`` lies in the bracket of
          ``-ln|z| / H`` over the discs.
        * Otherwise (incommensurate, or commensurate only to the 1e-10 of
          :meth:`commensurate_step`, as ``2.0, 2.1`` are: their ratio as stored is not
          ``20/21``; or a multiple root with ``radii``): ``upper`` is a proven ``C_D``, a
          ``c`` with ``sum_{k>=1} |a_k| e^{-r_k c} < |a_0|`` in ``arb`` (no zero with
          ``Re s >= c``; with ``radii`` for the largest ``|b_k|`` and the smallest ``|b_0|``),
          and ``lower`` the left edge of a square proven by Krawczyk's test to hold a zero of
          ``D`` (of every operator of the balls with ``radii``; Newton from the chain seeds),
          ``-inf`` if none is proven. For stored delays that are not exactly commensurate
          ``c_D`` may lie anywhere in ``[c_D(h), C_D]`` (the chain abscissa of a neutral
          equation is not continuous in the delays: Hale and Verduyn Lunel), so no tighter
          statement about ``D`` as represented is available.

        Parameters
        ----------
        prec : int, optional
            Working precision in bits.
        radii : array_like, optional
            Proven radii of the coefficients, one per entry of :attr:`coefs` (``>= 0``).
            Default: the stored coefficients are exact.

        Returns
        -------
        SpectralBound
            With ``proven=True``; the ends are rounded outwards to doubles.

        Raises
        ------
        ParameterError
            ``prec`` outside 16..4096; ``radii`` not one finite value ``>= 0`` per coefficient.
        CertificationError
            The ball enclosures cannot confirm ``C_D`` (non-finite values), or the ball of
            ``a_0`` holds 0 (the principal part of some operator of the balls is another).
        ImportError
            python-flint is not installed (``pip install nrobust[rigorous]``).
        """
        r = self._radii(radii)
        if self.coefs.size == 1:
            return SpectralBound(-np.inf, -np.inf, True, None, proven=True)
        with working_precision(prec) as flint:
            a = [radius_acb(flint, c, rk) for c, rk in zip(self.coefs, r)]
            if not abs(a[0]) > 0:
                raise CertificationError(
                    f"the ball of a_0 = {complex(self.coefs[0])!r} (radius {float(r[0])!r}) holds 0: the principal "
                    "part is not known; give the coefficients to a smaller radius"
                )
            exact = _exact_commensurate(self.delays)
            if exact is not None:
                if np.any(r > 0):
                    bracket = _family_chain_bound(flint, self.coefs, a, *exact)
                else:
                    bracket = _ball_chain_bound(flint, self.coefs, *exact)
                if bracket is not None:  # with radii a bracket of the family's c_D, not one value
                    family = bool(np.any(r > 0))
                    return SpectralBound(*bracket, not family, None if family else float(exact[0]), proven=True)
            upper = _ball_strong_bound(flint, a, self.delays, self.strong_spectral_bound())
            lower = _ball_zero_lower_bound(flint, self, a)
            return SpectralBound(min(lower, upper), upper, False, None, proven=True)

    def proven_gamma_0(self, prec: int = 53, radii: ArrayLike | None = None) -> tuple[float, float]:
        """``gamma_0 = sum_{k>=1} |a_k| / |a_0|`` enclosed in ball arithmetic (python-flint).

        Parameters
        ----------
        prec : int, optional
            Working precision in bits.
        radii : array_like, optional
            As in :meth:`proven_spectral_bound`: the bracket then holds ``gamma_0`` of every
            operator with coefficients in the balls.

        Returns
        -------
        (lower, upper) : tuple of float
            Doubles rounded outwards; ``upper = inf`` when the ball of ``a_0`` holds 0.

        Raises
        ------
        ParameterError
            ``prec`` outside 16..4096, or bad ``radii``.
        ImportError
            python-flint is not installed (``pip install nrobust[rigorous]``).
        """
        r = self._radii(radii)
        if self.coefs.size == 1:
            return 0.0, 0.0
        with working_precision(prec) as flint:
            a = [abs(radius_acb(flint, c, rk)) for c, rk in zip(self.coefs, r)]
            total = sum(a[1:], flint.arb(0))
            if not a[0] > 0:
                return _outward(total.lower() / a[0].upper(), np.inf)
            ratio = total / a[0]
            return _outward(ratio.lower(), ratio.upper())

    def _radii(self, radii: ArrayLike | None) -> NDArray[np.float64]:
        """``radii`` checked against :attr:`coefs` (zeros when None)."""
        if radii is None:
            return np.zeros(self.coefs.size)
        r = real_array("radii", np.atleast_1d(np.asarray(radii, dtype=float)))
        if r.shape != self.coefs.shape or np.any(r < 0):
            raise ParameterError("radii", f"one finite radius >= 0 per coefficient ({self.coefs.size})", radii)
        return r

    # ------------------------------------------------------------------ output
    def __repr__(self) -> str:
        terms = " + ".join(
            (f"{a.real:.6g}" if np.isrealobj(self.coefs) else f"({a:.6g})") + (f" e^(-{t:.6g} s)" if t else "")
            for a, t in zip(self.coefs, self.delays)
        )
        return f"DifferenceOperator({terms}; gamma_0={self.gamma_0:.6g})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description: coefficients (complex ones as ``[real, imag]``), delays and stability."""
        return json_safe(
            {
                "coefs": self.coefs,
                "delays": self.delays,
                "gamma_0": self.gamma_0,
                "strongly_stable": self.is_strongly_stable(),
                "strong_spectral_bound": self.strong_spectral_bound(),
            }
        )


def commensurate(delays: NDArray[np.float64], max_degree: int) -> tuple[float, NDArray[np.int64]] | None:
    """``(h, n)`` with ``delays_k = n_k h``, integers ``n_k <= max_degree``, or None.

    ``delays`` positive and increasing; each ratio ``delays_k / delays_max`` must agree with a
    fraction of denominator at most 1000 within a relative 1e-10; ``h`` is the least-squares
    fit of ``delays_k = n_k h``.
    """
    rmax = float(delays[-1])
    fracs = [Fraction(float(x / rmax)).limit_denominator(_MAX_DENOMINATOR) for x in delays]
    if any(abs(float(f) - x / rmax) > _COMMENSURATE_RTOL for f, x in zip(fracs, delays)):
        return None
    den = lcm(*(f.denominator for f in fracs))
    if den > max_degree:
        return None
    n = np.array([f.numerator * (den // f.denominator) for f in fracs], dtype=np.int64)
    if _collide(delays, n):
        return None
    return float(np.dot(n, delays) / np.dot(n, n)), n


def _collide(delays: NDArray[np.float64], n: NDArray[np.int64]) -> bool:
    """True if two distinct delays share a lattice step ``n_k`` (or a positive delay gets ``n_k = 0``).

    Delays ``1`` and ``1 + 1e-12`` agree to the tolerance of :func:`commensurate`, but they are
    not one delay: at frequencies near ``pi / 1e-12`` their terms turn against each other,
    and the zeros of the operator there follow neither of them alone nor their sum.
    """
    order = np.argsort(delays, kind="stable")
    d, k = delays[order], n[order]
    return bool(np.any((np.diff(d) > 0) & (np.diff(k) <= 0)) or np.any((d > 0) & (k == 0)))


def chains_of(h: float, z: NDArray[np.complex128], mult: NDArray[np.int64]) -> Chains:
    """The chains ``s = (-ln|z_i| + i(2 pi m - arg z_i)) / h`` of the roots ``z_i`` (rightmost first)."""
    chains = [
        Chain(float(-np.log(abs(zi)) / h), float(-np.angle(zi) / h), float(2 * np.pi / h), int(m), complex(zi))
        for zi, m in zip(z, mult)
    ]
    chains.sort(key=lambda c: (-c.real, c.offset))
    if not chains:
        return Chains(True, h, (), (-np.inf, -np.inf))
    c = chains[0].real
    return Chains(True, h, tuple(chains), (c, c))


def _beat_seeds(D: DifferenceOperator, upper: float) -> NDArray[np.complex128]:
    """Seeds on ``Re s = upper`` over one beat period of the closest delays (none past the work bound).

    Two delays ``g`` apart turn their terms' relative phase once per ``2 pi / g`` in ``Im s``;
    over one such period every alignment of the phases (where the rightmost roots are,
    e.g. near ``Im s = pi / delta`` for U_BS with a loop delay ``delta``) is met. The seeds
    are ``pi / r_max`` apart, half the spacing of the roots along the longest delay.
    """
    r = D.relative_delays
    gap = float(np.min(np.diff(r)))
    n = int(np.ceil(2.0 * r[-1] / gap)) + 1
    real = not np.any(np.imag(D.coefs))  # then the roots come in conjugate pairs: Im s >= 0 suffices
    if (n if real else 2 * n) > _BEAT_SEEDS:
        return np.empty(0, dtype=complex)
    w = np.arange(n) * (np.pi / r[-1])
    if not real:
        w = np.concatenate([-w[:0:-1], w])
    return upper + 1j * w


def _merged_chains(D: DifferenceOperator) -> Chains | None:
    """The chains of ``D`` with the delays that share a lattice step merged (seeds), or None.

    Delays ``g <= 2e-10 r_max`` apart (one step of :func:`commensurate`) act as one delay, with
    the sum of their coefficients, at frequencies small against ``1 / g``: the chains of the
    merged operator seed the zeros of ``D`` there (Newton's method on ``D`` itself and a
    proof follow). None when the merged operator has no zero or is not an operator (the
    coefficients at the smallest delay cancel).
    """
    r = D.relative_delays
    merged = r.copy()
    for k in range(1, r.size):  # each delay joins the group of its left neighbour when close to it
        if r[k] - r[k - 1] <= 2.0 * _COMMENSURATE_RTOL * r[-1]:
            merged[k] = merged[k - 1]
    try:
        M = DifferenceOperator(D.coefs, merged)
        if M.coefs.size == 1:
            return None
        return M.chains() if M.commensurate_step() is not None else M.commensurate_approximation().chains()
    except ParameterError:
        return None


def _newton_difference(D: DifferenceOperator, s: NDArray[np.complex128], iters: int = 60) -> NDArray[np.complex128]:
    """Newton's method on ``D`` from the seeds ``s`` (nan where a step was not finite).

    Steps are limited to length 1, so that a seed cannot be thrown far from its chain. A
    point still moving after ``iters`` steps is returned as it stands: every candidate is
    proven or discarded by :func:`_kantorovich_radius` afterwards.
    """

    def fdf(x: NDArray[np.complex128]) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        e = np.exp(-np.outer(D.delays, x))
        return D.coefs @ e, -(D.coefs * D.delays) @ e

    def keep_all(x: NDArray[np.complex128]) -> NDArray[np.bool_]:
        return np.ones(x.shape, dtype=bool)

    return newton(fdf, s, max_step=1.0, iters=iters, accept_stalled=keep_all)


def _kantorovich_radius(D: DifferenceOperator, c: complex) -> float | None:
    """Radius of a disc about ``c`` proven to hold a zero of ``D``, or None.

    Newton-Kantorovich for the analytic ``D``: with ``eta >= |D(c) / D'(c)|``,
    ``beta >= 1 / |D'(c)|`` and ``L >= sup |D''|`` on the disc of radius ``4 eta`` about
    ``c``, ``h = beta L eta <= 1/2`` proves a zero within ``r = (1 - sqrt(1 - 2h)) eta / h``
    (``2 eta`` at most). ``|D''| <= sum_k |a_k| tau_k^2 e^{-tau_k (Re c - 4 eta)}``. The
    values of ``D`` and ``D'`` carry a rounding allowance of ``64 eps`` of the sums of
    moduli of their terms.
    """
    a, tau = np.abs(D.coefs), D.delays
    e = np.exp(-tau * c)
    mod0 = float(np.sum(a * np.abs(e)))
    mod1 = float(np.sum(a * tau * np.abs(e)))
    slack = 64 * np.finfo(float).eps
    f = abs(complex(np.sum(D.coefs * e))) + slack * mod0
    d = abs(complex(np.sum(-D.coefs * tau * e))) - slack * mod1
    if not (np.isfinite(f) and d > 0):
        return None
    eta = max(f / d, 1e-300)
    rho = 4.0 * eta
    with np.errstate(over="ignore"):  # a far candidate: L = inf, not proven
        L = float(np.sum(a * tau**2 * np.exp(-tau * (c.real - rho))))
        h = L * eta / d
    if not np.isfinite(h) or h > 0.5:
        return None
    return float(eta if h == 0 else (1.0 - np.sqrt(1.0 - 2.0 * h)) * eta / h)


# ---------------------------------------------------------------------- proofs in ball arithmetic
# Candidate zeros of D tried by Krawczyk's test (rightmost first), and the half-widths of its squares.
_PROVEN_CANDIDATES = 8
_KRAWCZYK_WIDTHS = (1e-12, 1e-10, 1e-8, 1e-6)


def _exact_commensurate(delays: NDArray[np.float64]) -> tuple[Fraction, list[int]] | None:
    """``(H, n)`` with ``tau_k - tau_0 = n_k H`` exactly (rationals), ``n_k <= _MAX_DEGREE``; or None."""
    r = [Fraction(float(t)) - Fraction(float(delays[0])) for t in delays]
    den = lcm(*(x.denominator for x in r))
    nums = [int(x * den) for x in r]
    g = gcd(*nums)
    if g == 0:
        return None
    n = [v // g for v in nums]
    if n[-1] > _MAX_DEGREE:
        return None
    return Fraction(g, den), n


def _outward(lo: Any, hi: Any) -> tuple[float, float]:
    """Doubles ``a <= lo`` and ``b >= hi`` for the ends of ``arb`` values."""
    a, b = float(lo), float(hi)
    return float(np.nextafter(a, -np.inf)), float(np.nextafter(b, np.inf))


# Precision (bits) at which the roots of a complex P are isolated, and the tolerance they are refined to.
_ROOTS_PREC = 128
_ROOTS_TOL = 2.0**-110


def _complex_roots(flint: Any, poly: list[complex]) -> list[Any] | None:
    """The roots of ``sum_j poly[j] z^j`` (exact complex coefficients) in balls refined to :data:`_ROOTS_TOL`,
    or None when FLINT cannot isolate them (a multiple root)."""
    with precision(flint, _ROOTS_PREC):
        try:
            return list(flint.acb_poly([flint.acb(c.real, c.imag) for c in poly]).roots(_ROOTS_TOL, 4 * _ROOTS_PREC))
        except ValueError:
            return None


def _ball_chain_bound(flint: Any, coefs: NDArray, H: Fraction, n: list[int]) -> tuple[float, float] | None:
    """Bracket of ``max_i -ln|z_i| / H`` over the roots of ``sum_k a_k z^{n_k}``, or None if not isolated."""
    poly = [0.0 + 0.0j] * (n[-1] + 1)
    for a, k in zip(coefs, n):
        poly[k] += complex(a)
    if all(c.imag == 0 for c in poly):
        roots = [z for z, _ in flint.fmpq_poly([flint.fmpq(*c.real.as_integer_ratio()) for c in poly]).complex_roots()]
    else:
        found = _complex_roots(flint, poly)
        if found is None:
            return None
        roots = found
    h = flint.arb(flint.fmpq(H.numerator, H.denominator))
    reals = [-(abs(z).log()) / h for z in roots]
    if not reals or not all(x.is_finite() for x in reals):
        return None
    return _outward(max(float(x.lower()) for x in reals), max(float(x.upper()) for x in reals))


def _family_chain_bound(
    flint: Any, coefs: NDArray, a: list[Any], H: Fraction, n: list[int]
) -> tuple[float, float] | None:
    """Bracket of ``max_i -ln|z_i| / H`` over the roots of every ``sum_k b_k z^{n_k}`` with ``b_k`` in the
    balls ``a``, or None when the roots of the stored polynomial are not simple or their discs overlap.

    Each root ``m`` of the stored polynomial (rational coefficients, isolated by FLINT) is the
    centre of the disc of radius ``deg |P(m)| / |P'(m)|``, ``P`` and ``P'`` enclosed with the
    balls ``a`` (see :meth:`DifferenceOperator.proven_spectral_bound`).
    """
    degree = n[-1]
    stored = [0j] * (degree + 1)
    balls = [flint.acb(0)] * (degree + 1)
    for c, b, k in zip(coefs, a, n):
        stored[k] += complex(c)
        balls[k] += b
    if not abs(balls[degree]) > 0:
        return None  # a ball of the leading coefficient holds 0: some polynomial of the balls has fewer roots
    if all(c.imag == 0 for c in stored):
        found = flint.fmpq_poly([flint.fmpq(*c.real.as_integer_ratio()) for c in stored]).complex_roots()
        centres = [z for z, mult in found if mult == 1]
    else:
        found = _complex_roots(flint, stored)
        if found is None:
            return None
        centres = found
    if len(centres) != degree:  # a multiple root: no disc holds exactly one root of every polynomial
        return None
    with precision(flint, max(flint.ctx.prec, _ROOTS_PREC)):  # the discs as small as the balls allow
        P = flint.acb_poly(balls)
        dP = P.derivative()
        discs = []
        for z in centres:
            m = flint.acb(z.real.mid(), z.imag.mid())
            slope = abs(dP(m))
            if not slope > 0:
                return None
            discs.append((m, degree * abs(P(m)).upper() / slope.lower()))
    for i, (m, rho) in enumerate(discs):
        for w, sigma in discs[:i]:
            if not abs(m - w) > rho + sigma:
                return None
    h = flint.arb(flint.fmpq(H.numerator, H.denominator))
    ends = []
    for m, rho in discs:
        near, far = abs(m) - rho, abs(m) + rho
        if not near > 0:
            return None  # a disc about 0: a chain at +inf for some polynomial of the balls
        ends.append((-(far.log()) / h, -(near.log()) / h))
    if not all(lo.is_finite() and hi.is_finite() for lo, hi in ends):
        return None
    return _outward(max(float(lo.lower()) for lo, _ in ends), max(float(hi.upper()) for _, hi in ends))


def _ball_strong_bound(flint: Any, a: list[Any], delays: NDArray[np.float64], guess: float) -> float:
    """A double ``c >= guess`` with ``sum_{k>=1} |a_k| e^{-r_k c} < |a_0|`` proven (``r_k`` as stored) for every
    ``a_k`` in the balls ``a``."""
    mags = [abs(ak) for ak in a]
    t0 = flint.arb(float(delays[0]))
    r = [flint.arb(float(t)) - t0 for t in delays[1:]]
    c = float(guess)
    for j in range(200):
        x = flint.arb(c)
        if sum((ak * (-rk * x).exp() for ak, rk in zip(mags[1:], r)), flint.arb(0)) < mags[0]:
            return c
        c = float(c + 2.0**j * np.finfo(float).eps * (1.0 + abs(c)))
    raise CertificationError(f"ball arithmetic cannot confirm the strong spectral bound near {guess!r}; raise prec")


def _ball_zero_lower_bound(flint: Any, D: DifferenceOperator, a: list[Any]) -> float:
    """The largest ``Re s`` of a square proven by Krawczyk's test to hold a zero of ``D``, minus its half-width.

    Krawczyk's test (:func:`nrobust.balls.krawczyk`) on squares ``X`` about candidate zeros
    ``c``, with ``y ~ 1/D'(c)`` (``D`` and ``D'`` enclosed in ``acb`` with the coefficients'
    balls ``a`` and the stored delays: the square holds a zero of every operator of the balls).
    """
    seeds = _zero_candidates(D)
    tau = [flint.arb(float(t)) for t in D.delays]

    def value(s: Any, k: int) -> Any:
        return sum((ai * (-ti) ** k * (-ti * s).exp() for ai, ti in zip(a, tau)), flint.acb(0))

    best = -np.inf
    for z in seeds[np.argsort(-seeds.real)][:_PROVEN_CANDIDATES]:
        for w in _KRAWCZYK_WIDTHS:
            half = w * (1.0 + abs(z))
            x0, x1, y0, y1 = z.real - half, z.real + half, z.imag - half, z.imag + half
            c = flint.acb(z.real, z.imag)
            slope = value(c, 1)
            mid = complex(float(slope.real.mid()), float(slope.imag.mid()))
            if mid == 0:
                continue
            y = flint.acb(1.0 / mid.real if mid.imag == 0 else 1.0 / mid)
            if krawczyk((x0, x1, y0, y1), c, value(c, 0), lambda X: value(X, 1), y):
                best = max(best, float(np.nextafter(x0, -np.inf)))
                break
    return best


def _zero_candidates(D: DifferenceOperator) -> NDArray[np.complex128]:
    """Approximate zeros of ``D`` near its rightmost chains (Newton from the chain points)."""
    rel = DifferenceOperator(D.coefs, D.relative_delays)
    try:
        chains = rel.chains() if rel.commensurate_step() is not None else rel.commensurate_approximation().chains()
    except ParameterError:  # delays too close to seed from a commensurate approximation
        merged = _merged_chains(rel)
        if merged is None:
            return np.zeros(0, dtype=complex)
        chains = merged
    right = chains.chains[:_LOWER_BOUND_CHAINS]
    if not right:
        return np.zeros(0, dtype=complex)
    seeds = np.concatenate([c.points(-1e-9, c.offset % c.spacing + 4 * c.spacing) for c in right])
    s = _newton_difference(rel, seeds)
    return s[np.isfinite(s)]
