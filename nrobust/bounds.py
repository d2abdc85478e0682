"""Rouché-type bounds: root-free regions and the L1 modulus of a kernel.

Both certificates come from the inequality ``|F| >= |D| - |F - D| > 0`` where ``D`` is
the part of ``F`` that dominates:

* :func:`root_free_region`: ``D = s^n P(s)`` with ``P`` the principal part (difference
  operator) of ``F``. Where ``|F - s^n P| < |s^n P|`` the function ``F`` has no zero: a
  half-plane ``Re s > c`` and the set ``{Re s >= x0, |s| > R}``. These bounds make every
  root search of nrobust finite (paper, proof of Lemma 1 and of Theorem 3: "integrating
  by parts, ``|H(s)|`` converges to zero for ``|s|`` large enough").
* :func:`delay_bound_from_kernel`: for ``F(s) = F_0(s) + I(s, delta)`` with
  ``|F_0| >= epsilon_0`` on ``Re s >= 0`` and
  ``I(s, delta) = int_0^tau N(nu) (e^{-nu s} - e^{-(nu + delta) s}) dnu``,
  ``|I(s, delta)| <= omega(delta) = int |N(nu) - N(nu - delta)| dnu`` (``N`` extended by
  zero), the L1 modulus of continuity (:func:`l1_modulus`). Every ``delta`` with
  ``omega(delta) < epsilon_0`` keeps ``F`` zero-free on ``Re s >= 0``: the proof of the
  paper's Theorem 4 made quantitative (:func:`nrobust.rouche_delay_bound` applies it to
  the paper's plants).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._digits import lower_bound_text
from ._flint import require_flint
from ._json import fields_dict
from ._validate import finite_real, positive, positive_int, real_array
from .errors import CertificationError, ParameterError
from .quasipoly import DistributedDelay, QuasiPolynomial

__all__ = [
    "PrincipalGap",
    "RootFreeRegion",
    "RoucheDelayBound",
    "TailBound",
    "delay_bound_from_kernel",
    "joint_degree",
    "l1_modulus",
    "principal_gap",
    "radius_where",
    "root_free_region",
    "total_variation",
]

# Doublings of the radius (from 1) before the decay of the remainder is declared too
# slow to beat the principal part.
_MAX_DOUBLINGS = 200
# Bisection steps on the radius / abscissa: 2^-80 of the bracket, below double precision.
_BISECTIONS = 80


# ---------------------------------------------------------------------------- bounds
def joint_degree(*parts: QuasiPolynomial) -> int:
    """Largest point-term degree ``n`` among ``parts``; checks the distributed degrees.

    Raises
    ------
    ParameterError
        If a distributed term has a polynomial factor of degree above ``n`` (it would
        enter the principal part, which the bounds below do not model).
    """
    n = max(P.degree for P in parts)
    for P in parts:
        for d in P.distributed:
            if d.poly.size - 1 > n:
                raise ParameterError(
                    "distributed", f"terms whose polynomial degree is at most {n} (the point-term degree)", d
                )
    return n


def min_delay(P: QuasiPolynomial) -> float:
    """Smallest delay of ``P``, point or distributed (``inf`` for the zero function)."""
    ends = [t for _, t in P.point_terms] + [d.a for d in P.distributed]
    return float(min(ends, default=np.inf))


class TailBound:
    """Upper bound of ``|e^{t0 s} (P(s) - s^n D_P(s))| / |s|^n`` on ``{Re s >= x0, |s| >= R}``.

    ``D_P`` is the sum of the ``s^n`` point terms. The remainder collects the lower
    powers of the point terms, bounded by ``sum_j |p_kj| R^(j - n) e^{-(tau_k - t0) x0}``,
    and the distributed terms, bounded by ``|q|(R) R^-n min(M_0, V / R) e^{t0 x0}`` with
    ``M_0 = int |N| e^{-nu x0}`` (``abs_moment``) and ``V`` the variation bound
    (integration by parts, ``|int N e^{-nu s}| <= V(Re s) / |s|``). Each term is
    non-increasing in ``R`` and, when every delay is ``>= t0``, in ``Re s >= x0``. The
    kernel integrals are computed once; calls cost a few flops.

    With ``second_order`` (``x0 >= 0``) a distributed term of moment 0 is bounded by
    ``|q|(R) R^-n min(M_0, V / R, V_1 / R + V_2 / R^2)``, its kernel integrated by parts twice
    (:meth:`~nrobust.distributed_delay.DistributedDelay.second_order_variation`): for a kernel
    with jumps ``V_1``, its end values and jumps, can be much less than ``V``, which also holds
    ``int |N'|``. ``V_1`` and ``V_2`` need only ``|e^{-nu s}| <= 1`` for ``nu >= 0``, ``Re s >= 0``:
    normalised, the kernel on ``[a, b]`` is one on ``[a - t0, b - t0]``, so where ``a >= t0`` (every
    delay ``>= t0``, as above) the bound holds on ``Re s >= x0``, and on the axis (``x0 = 0``,
    ``|e^{t0 s}| = 1``) for every kernel.

    Parameters
    ----------
    P : QuasiPolynomial
        The function.
    n : int
        Degree of the principal part (at least the degree of every term of ``P``).
    x0 : float
        Smallest real part considered.
    t0 : float
        Delay by which ``P`` is normalised (the delay of the first principal term).
    second_order : bool, optional
        Integrate the kernels by parts twice (default False); requires ``x0 >= 0``.

    Raises
    ------
    ParameterError
        ``second_order`` with ``x0 < 0``.
    """

    def __init__(self, P: QuasiPolynomial, n: int, x0: float, t0: float, *, second_order: bool = False) -> None:
        if second_order and not x0 >= 0.0:
            raise ParameterError("x0", ">= 0 with second_order=True (the half-plane Re s >= 0)", x0)
        self.n = n
        self.point = np.zeros(n)
        # far to the left the weights e^{-(tau - t0) x0} overflow: an infinite bound is
        # still a bound (the region is then simply not cleared)
        with np.errstate(over="ignore", invalid="ignore"):
            for p, t in P.point_terms:
                m = min(p.size, n)
                a = np.abs(p[:m])
                self.point[:m] += np.where(a > 0, a * np.exp(-(t - t0) * x0), 0.0)
            self.dist: list[tuple[NDArray, float, float, float, float]] = []
            for d in P.distributed:
                m0 = float(d.abs_moment(x0, 0)) * np.exp(t0 * x0)
                v = float(d.variation_bound(x0)) * np.exp(t0 * x0) if d.moment == 0 else np.inf
                v1, v2 = d.second_order_variation() if second_order and d.moment == 0 else (np.inf, np.inf)
                self.dist.append((np.abs(d.poly), m0, v, v1, v2))

    def __call__(self, radius: ArrayLike) -> NDArray[np.float64]:
        """The bound at ``|s| = R`` (vectorised over ``R > 0``)."""
        R = np.asarray(radius, dtype=float)
        out = np.zeros(R.shape)
        with np.errstate(over="ignore", invalid="ignore"):
            for j, c in enumerate(self.point):
                if c:
                    out = out + c * R ** (j - self.n)
            for q, m0, v, v1, v2 in self.dist:
                qpow = sum(c * R ** (j - self.n) for j, c in enumerate(q) if c)
                kernel = np.minimum(m0, v / R)
                if v1 < np.inf:  # second_order
                    kernel = np.minimum(kernel, v1 / R + v2 / (R * R))
                out = out + qpow * kernel
        return np.where(np.isnan(out), np.inf, out)


@dataclass(frozen=True)
class PrincipalGap:
    """Lower bound of ``|D_first| - sum |D_others|`` for a sum of principal parts.

    Attributes
    ----------
    gap : float
        ``|a_first| - sum_{others} |a_k| e^{-(tau_k - t0) x0}`` at the abscissa used.
    t0 : float
        Delay of the first (dominating) principal term.
    first : str
        Which part carries the first term (``"A"``, ``"B"``, ...).
    error : float
        A bound of the rounding in ``gap`` (its floating-point evaluation from the stored
        coefficients): ``(m + 3) eps S``, ``S = |a_first| + sum |a_k| e^{...}``, for ``m``
        principal terms; at least 1.6 times the first-order bound ``(m + 4) u S``, ``u = eps / 2``,
        of the moduli (``2 u`` each), the exponential factors (``3 u``), the ``m - 2`` additions
        (the bound of recursive summation, Higham, *Accuracy and Stability of Numerical
        Algorithms*, chapter 4) and the subtraction. It covers also a rounding of each stored
        coefficient by ``u`` (at least 1.4 times ``(m + 5) u S``), so for coefficients that are one
        rounded product of the plant's numbers (``rho q``, ``K q``) it bounds the error of the gap
        of the plant as given. A gap of the size of ``error`` is zero to rounding: its sign is not
        known.
    """

    gap: float
    t0: float
    first: str
    error: float = 0.0


def principal_gap(parts: dict[str, tuple[QuasiPolynomial, int]], n: int, x0: float = 0.0) -> PrincipalGap | None:
    """Dominance gap of the first principal term over all others, or None if none dominates.

    ``parts`` maps a label to ``(P, order)``: the terms of ``P`` are ordered by
    ``(delay, order)``, so ``order = 1`` places a part's terms after the terms of
    ``order = 0`` parts with the same delay (a loop delay ``delta -> 0+``). None is
    returned when the first principal term is preceded by another term of the functions
    (an advanced-type function: chains of roots go to ``Re s = +inf``).
    """
    lead = [(abs(a), t, order, label) for label, (P, order) in parts.items() for a, t in P.leading_terms(n)]
    if not lead:
        return None
    lead.sort(key=lambda e: (e[1], e[2]))
    a0, t0, order0, label0 = lead[0]
    for P, order in parts.values():
        if (min_delay(P), order) < (t0, order0):
            return None
    others = sum(a * np.exp(-(t - t0) * x0) for a, t, _, _ in lead[1:])
    error = (len(lead) + 3) * float(np.finfo(float).eps) * float(a0 + others)
    return PrincipalGap(float(a0 - others), float(t0), label0, error)


def radius_where(tail: Callable[[float], float], level: float, what: str) -> float:
    """Smallest ``R`` (up to bisection accuracy, rounded up) with ``tail(R) < level``.

    ``tail`` must be non-increasing. Raises :class:`CertificationError` if the tail
    stays above ``level`` for every ``R <= 2^_MAX_DOUBLINGS``.
    """
    hi = 1.0
    for _ in range(_MAX_DOUBLINGS):
        if tail(hi) < level:
            break
        hi *= 2.0
    else:
        raise CertificationError(
            f"{what}: the remainder does not fall below the principal-part gap {level:.3g} "
            f"for |s| <= 2^{_MAX_DOUBLINGS}"
        )
    lo = 0.0
    for _ in range(_BISECTIONS):
        mid = 0.5 * (lo + hi)
        if mid <= 0.0 or mid == hi or mid == lo:
            break
        if tail(mid) < level:
            hi = mid
        else:
            lo = mid
    return float(hi)


# ---------------------------------------------------------------------------- root-free region
@dataclass(frozen=True)
class RootFreeRegion:
    """Certificate that a quasi-polynomial ``F`` has no zero in a region.

    ``F`` has no zero with ``Re s > half_plane``, and none in
    ``{Re s >= x0, |s| > radius}`` (``|F - s^n D| < |s^n D|`` there, ``D`` the principal
    part).

    Attributes
    ----------
    half_plane : float
        Abscissa ``c``: no zero with ``Re s > c``.
    x0 : float
        Left edge of the second region.
    radius : float
        ``R``: no zero with ``Re s >= x0`` and ``|s| > R``.
    degree : int
        ``n``, the degree of the principal part.
    gap : float
        ``|a_0| - sum_{k>=1} |a_k| e^{-(tau_k - tau_0) x0}``, the dominance of the principal
        part on ``Re s >= x0`` (positive).
    """

    half_plane: float
    x0: float
    radius: float
    degree: int
    gap: float

    def contains(self, s: ArrayLike) -> NDArray[np.bool_]:
        """True where ``s`` lies in the certified root-free region."""
        s = np.asarray(s, dtype=complex)
        return (s.real > self.half_plane) | ((s.real >= self.x0) & (np.abs(s) > self.radius))

    def box(self) -> tuple[float, float, float, float]:
        """A rectangle ``(x0, c, -R, R)`` holding every zero with ``Re s >= x0``."""
        return (self.x0, max(self.half_plane, self.x0 + 1e-12 * max(1.0, self.radius)), -self.radius, self.radius)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


def root_free_region(F: QuasiPolynomial, x0: float = 0.0) -> RootFreeRegion:
    """Certified zero-free regions of ``F`` from its principal part.

    With ``F(s) = s^n D(s) + R(s)``, ``D(s) = sum_k a_k e^{-tau_k s}`` the principal part
    (paper, proof of Lemma 1: ``F + H`` with ``|H| -> 0``), ``F(s) != 0`` wherever
    ``|R(s)| < |s|^n |D(s)|``. On ``Re s >= x`` (delays measured from ``tau_0``),
    ``|D| >= |a_0| - sum_{k>=1} |a_k| e^{-(tau_k - tau_0) x}`` and ``|R| / |s|^n`` is bounded
    by :class:`TailBound`, non-increasing in ``|s|`` and in ``Re s``.

    Parameters
    ----------
    F : QuasiPolynomial
        A retarded or neutral quasi-polynomial whose first principal term has the
        smallest delay of all its terms.
    x0 : float, optional
        Left edge of the region ``{Re s >= x0, |s| > R}``; it must lie to the right of
        ``C_D`` (the root of ``|a_0| = sum |a_k| e^{-(tau_k - tau_0) x}``).

    Returns
    -------
    RootFreeRegion

    Raises
    ------
    ParameterError
        If ``F`` is of advanced type or ``x0`` does not leave a positive gap.
    CertificationError
        If a work bound is hit.

    Examples
    --------
    >>> F = QuasiPolynomial([[1.0, 1.0], [0.5]], [0.0, 1.0])   # s + 1 + 0.5 e^{-s}
    >>> cert = root_free_region(F)
    >>> round(cert.half_plane, 3), round(cert.radius, 3)   # no zero in Re s > 1.157
    (1.157, 1.5)
    """
    if not isinstance(F, QuasiPolynomial):
        raise ParameterError("F", "a QuasiPolynomial", F)
    x0 = finite_real("x0", x0)
    n = joint_degree(F)
    g0 = principal_gap({"F": (F, 0)}, n, x0)
    if g0 is None:
        raise ParameterError("F", "of retarded or neutral type (its first principal term has the smallest delay)", F)
    if g0.gap <= 0.0:
        raise ParameterError(
            "x0", "to the right of the strong spectral bound of the principal part (positive dominance gap)", x0
        )
    gap, t0 = g0.gap, g0.t0

    def margin(x: float, R: float) -> float:
        g = principal_gap({"F": (F, 0)}, n, x)
        assert g is not None
        return g.gap - float(TailBound(F, n, x, t0)(R))

    radius = radius_where(lambda R: float(TailBound(F, n, x0, t0)(R)), gap, "root_free_region")
    # Half-plane: for Re s = x >= c we have |s| >= x, and the bound is non-increasing in x.
    lo, hi = x0, max(x0, 0.0) + 1.0
    for _ in range(_MAX_DOUBLINGS):
        if hi > 0 and margin(hi, hi) > 0:
            break
        hi = 2.0 * hi
    else:
        raise CertificationError("root_free_region: no root-free half-plane found")
    for _ in range(_BISECTIONS):
        mid = 0.5 * (lo + hi)
        if mid <= 0 or mid == lo or mid == hi:
            break
        if margin(mid, mid) > 0:
            hi = mid
        else:
            lo = mid
    # Re s > max(R, x0) lies in {Re s >= x0, |s| > R} as well
    return RootFreeRegion(half_plane=float(min(hi, max(radius, x0))), x0=x0, radius=radius, degree=n, gap=float(gap))


# ---------------------------------------------------------------------------- L1 modulus
def _pl_eval(nodes: NDArray, values: NDArray, x: NDArray, side: str) -> NDArray:
    """One-sided limits of the piecewise-linear ``N`` (zero outside its support) at ``x``."""
    idx = np.searchsorted(nodes, x, side="right" if side == "right" else "left")
    inside = (idx > 0) & (idx < nodes.size)
    i = np.clip(idx, 1, nodes.size - 1)
    x0, x1 = nodes[i - 1], nodes[i]
    h = np.where(x1 > x0, x1 - x0, 1.0)
    t = np.clip((x - x0) / h, 0.0, 1.0)
    return np.where(inside, values[i - 1] + t * (values[i] - values[i - 1]), 0.0)


def _abs_linear_integral(f0: NDArray, f1: NDArray, h: NDArray) -> NDArray:
    """``int_0^h |f0 + (f1 - f0) t/h| dt`` exactly."""
    a, b = np.abs(f0), np.abs(f1)
    same = f0 * f1 >= 0
    denom = np.where(same, 1.0, a + b)
    return np.where(same, 0.5 * h * (a + b), 0.5 * h * (a * a + b * b) / denom)


def _linear_l1_modulus(N: DistributedDelay, delta: ArrayLike) -> NDArray[np.float64]:
    """``omega`` of the piecewise-linear interpolant of ``N``'s values, exactly (see :func:`l1_modulus`)."""
    if not isinstance(N, DistributedDelay) or np.iscomplexobj(N.values) or N.moment != 0:
        raise ParameterError("N", "a real DistributedDelay kernel of moment 0", N)
    d = real_array("delta", delta, ndim=None)
    if np.any(d < 0):
        raise ParameterError("delta", "finite and >= 0", delta)
    out = np.empty(d.shape)
    nodes, values = N.nodes, N.values
    for idx, dk in np.ndenumerate(d):
        br = np.unique(np.concatenate([nodes, nodes + dk]))
        lo, hi = br[:-1], br[1:]
        shifted = nodes + dk  # the same floats as in br: one-sided limits stay exact at jumps
        f0 = _pl_eval(nodes, values, lo, "right") - _pl_eval(shifted, values, lo, "right")
        f1 = _pl_eval(nodes, values, hi, "left") - _pl_eval(shifted, values, hi, "left")
        out[idx] = float(np.sum(_abs_linear_integral(f0, f1, hi - lo)))
    return out


def l1_modulus(N: DistributedDelay, delta: ArrayLike) -> NDArray[np.float64]:
    """``omega(delta) = int |N(nu) - N(nu - delta)| dnu``, ``N`` extended by zero.

    Exact for the piecewise-linear interpolant of a :class:`DistributedDelay` (jumps at
    repeated nodes and at the ends of the support included): the difference is linear
    between the merged breakpoints ``nodes`` and ``nodes + delta``, where its modulus is
    integrated in closed form. For a spline interpolant the result is an upper bound,
    ``omega_lin(delta) + 2 int |N - N_lin|`` (triangle inequality;
    :meth:`DistributedDelay.linear_deviation`). ``omega(delta) <= delta * TV(N)`` and
    ``omega(d1 + d2) <= omega(d1) + omega(d2)``.

    Parameters
    ----------
    N : DistributedDelay
        Real kernel of moment 0 (its polynomial factor is ignored: ``omega`` is a
        property of the kernel).
    delta : array_like
        Shifts ``delta >= 0``.
    """
    return _linear_l1_modulus(N, delta) + 2.0 * N.linear_deviation()


def total_variation(N: DistributedDelay) -> float:
    """Total variation of ``N`` extended by zero (an upper bound for splines)."""
    if not isinstance(N, DistributedDelay) or np.iscomplexobj(N.values):
        raise ParameterError("N", "a real kernel", N)
    return N.total_variation()


# ---------------------------------------------------------------------------- delay bound
@dataclass(frozen=True)
class RoucheDelayBound:
    """A guaranteed delay range ``[0, delta_0]`` from the proof of Theorem 4.

    Attributes
    ----------
    delta_0 : float
        Every loop delay in ``[0, delta_0]`` keeps the loop exponentially stable
        (``inf`` when ``N~ = 0``; 0 when ``epsilon_0 <= 0``).
    epsilon_0 : float
        ``1 - |q rho| - |K q|``, the lower bound of the delay-free part on ``Re s >= 0``.
    omega_at_delta_0 : float
        ``omega(delta_0)``, the bound of ``|I(s, delta_0)|`` (below ``epsilon_0``).
    total_variation : float
        ``TV(N~)``, the Lipschitz constant of ``omega`` used between samples.
    K : float
        Gain of the proximal reflection kept by the controller (``rho`` for U_BS).
    steps : int
        Certified steps taken by the march in ``delta``.
    rigorous : bool
        True when every quantity of the bound (``epsilon_0`` as given, the spline
        correction, ``TV`` and each ``omega_lin(d)``) was computed in exact rational
        arithmetic from the stored floats (``rigorous=True``): ``delta_0`` is then proven
        for ``N~`` as represented.
    """

    delta_0: float
    epsilon_0: float
    omega_at_delta_0: float
    total_variation: float
    K: float
    steps: int
    rigorous: bool = False

    @property
    def text(self) -> str:
        """``delta_0`` printed as the lower bound it is: 6 significant digits rounded down
        (:func:`nrobust._digits.lower_bound_text`), so no printed digit makes it larger than proven."""
        return lower_bound_text(self.delta_0)

    def __repr__(self) -> str:
        return (
            f"RoucheDelayBound(delta_0={self.text}, epsilon_0={self.epsilon_0:.6g}, "
            f"omega(delta_0)={self.omega_at_delta_0:.6g}, K={self.K:.6g})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (``inf`` as the string ``"inf"``)."""
        return fields_dict(self)


def delay_bound_from_kernel(
    N: DistributedDelay | None,
    epsilon_0: float,
    K: float = 0.0,
    rtol: float = 1e-6,
    max_steps: int = 100_000,
    rigorous: bool = False,
) -> RoucheDelayBound:
    """Largest certified ``delta_0`` with ``sup_{d <= delta_0} omega(d) < epsilon_0``.

    ``omega`` is bounded through the linear interpolant ``N_lin`` of ``N``'s values,
    ``omega(d) <= omega_lin(d) + 2 int |N - N_lin|`` (triangle inequality; the second
    term, :meth:`~nrobust.quasipoly.DistributedDelay.linear_deviation`, is zero for a
    linear kernel and small for the cubic spline ``N~``). ``omega_lin`` is computed in
    closed form (see :func:`l1_modulus`) and marched from ``d = 0`` against the budget
    ``epsilon_0 - 2 int |N - N_lin|``: with the subadditive bound
    ``omega_lin(d + h) <= omega_lin(d) + h TV``, ``TV`` the total variation bound of
    :meth:`~nrobust.quasipoly.DistributedDelay.total_variation` (at least that of
    ``N_lin``), every step ``h < (budget - omega_lin(d)) / TV`` keeps ``omega < epsilon_0``
    on ``[d, d + h]``. The march stops when the step falls below ``rtol * d``; the result
    is certified whatever the stopping point.

    Parameters
    ----------
    N : DistributedDelay or None
        The kernel ``N~`` (None for a transport system).
    epsilon_0 : float
        ``1 - |q rho| - |K q|``.
    K : float, optional
        Recorded in the result.
    rtol : float, optional
        Relative step below which the march stops.
    max_steps : int, optional
        Work bound.
    rigorous : bool, optional
        Prove the bound in exact rational arithmetic (:func:`_exact_delay_bound`): the
        stored floats of ``N`` (nodes, values and spline pieces) and ``epsilon_0`` are
        rationals, and so are ``omega_lin``, ``TV``, the spline correction and every step.
    """
    epsilon_0 = finite_real("epsilon_0", epsilon_0)
    rtol = positive("rtol", rtol)
    max_steps = positive_int("max_steps", max_steps)
    if not isinstance(rigorous, (bool, np.bool_)):
        raise ParameterError("rigorous", "True or False", rigorous)
    if rigorous and N is not None and epsilon_0 > 0.0:
        return _exact_delay_bound(N, epsilon_0, K, rtol, max_steps)
    if epsilon_0 <= 0.0:
        return RoucheDelayBound(0.0, epsilon_0, 0.0, 0.0 if N is None else total_variation(N), K, 0)
    tv = 0.0 if N is None else total_variation(N)
    if tv == 0.0:
        return RoucheDelayBound(np.inf, epsilon_0, 0.0, tv, K, 0)
    assert N is not None
    # omega <= omega_lin + 2 int |N - N_lin|: march on the exact omega_lin against the
    # budget left by the spline correction (all of epsilon_0 for a linear kernel).
    correction = 2.0 * N.linear_deviation()
    budget = epsilon_0 - correction
    if budget <= 0.0:
        return RoucheDelayBound(0.0, epsilon_0, correction, tv, K, 0)
    d, om, steps = 0.0, 0.0, 0
    safety = 1.0 - 1e-9
    while steps < max_steps:
        h = safety * (budget - om) / tv
        if d > 0.0 and h <= rtol * d:
            break
        om_next = float(_linear_l1_modulus(N, d + h))
        if om_next >= budget:
            raise CertificationError(
                f"delay_bound_from_kernel: omega({d + h:.6g}) = {om_next:.6g} exceeds the subadditive bound "
                f"omega(d) + h TV = {om + h * tv:.6g} (kernel values not representable?)"
            )
        d, om, steps = d + h, om_next, steps + 1
    return RoucheDelayBound(float(d), epsilon_0, om + correction, tv, K, steps)


# ---------------------------------------------------------------------------- exact delay bound
def _rationals() -> Callable[[float], Any]:
    """``x -> x`` as an exact rational: FLINT's ``fmpq`` (many times faster), else ``Fraction`` without python-flint."""
    try:
        flint = require_flint()  # optional here: exact rationals in Python otherwise
    except ImportError:
        return Fraction
    fmpq = flint.fmpq
    return lambda x: fmpq(*float(x).as_integer_ratio())


def _fraction(x: Any) -> Fraction:
    """An exact rational (``Fraction`` or ``fmpq``) as a ``Fraction``."""
    return x if isinstance(x, Fraction) else Fraction(int(x.p), int(x.q))


def _exact_pieces(N: DistributedDelay, rational: Callable[[float], Any] = Fraction) -> tuple[Fraction, Fraction]:
    """``TV`` of the linear interpolant and the bound of ``int |N - N_lin|``, exactly.

    On a segment ``[nu_k, nu_k + h]`` of positive length, ``N = P(t)`` (the stored piece)
    and ``N_lin`` the line through the values ``v_k``, ``v_{k+1}``: ``N - N_lin`` is
    ``-t (1 - t) (P_2 + P_3 + P_3 t)`` plus the line through ``P(0) - v_k`` and
    ``P(1) - v_{k+1}`` (zero but for the rounding of the spline fit), so
    ``int |N - N_lin| <= h (|P_2 + P_3| / 6 + |P_3| / 12 + (|P(0) - v_k| + |P(1) - v_{k+1}|) / 2)``;
    a term ``P_l t^l`` of higher degree adds ``h |P_l| (1/2 - 1/(l + 1))``, and a kernel known to
    within ``radius`` adds ``radius (b - a)``.

    ``rational`` converts a float exactly (``Fraction``, or FLINT's ``fmpq`` from :func:`_rationals`);
    both results are returned as ``Fraction``.
    """
    nodes = [rational(x) for x in N.nodes.tolist()]
    values = [rational(v) for v in N.values.tolist()]
    start, h, poly = N.pieces
    segments = [k for k in range(len(nodes) - 1) if nodes[k + 1] > nodes[k]]
    if len(segments) != start.size or any(rational(s) != nodes[k] for s, k in zip(start.tolist(), segments)):
        raise CertificationError("delay_bound_from_kernel(rigorous=True): the spline pieces do not match the nodes")
    zero = rational(0.0)
    tv = abs(values[0]) + abs(values[-1])
    for k in range(len(nodes) - 1):
        tv += abs(values[k + 1] - values[k])
    dev = rational(N.radius) * (nodes[-1] - nodes[0])
    # the weights 1/2 - 1/(j + 1) of the terms of degree j >= 4
    weights = [rational(1.0) / 2 - rational(1.0) / (j + 1) for j in range(poly.shape[1])]
    for k, hk, row in zip(segments, h.tolist(), poly.tolist()):
        p = [rational(c) for c in row]
        p += [zero] * (4 - len(p))
        total = zero
        for c in p:
            total += c
        ends = abs(p[0] - values[k]) + abs(total - values[k + 1])
        per = abs(p[2] + p[3]) / 6 + abs(p[3]) / 12 + ends / 2
        for j in range(4, len(p)):
            per += abs(p[j]) * weights[j]
        dev += rational(hk) * per
    return _fraction(tv), _fraction(dev)


def _dyadic(xs: list[float]) -> tuple[list[int], int]:
    """Integers ``X_k`` and an exponent ``e`` with ``x_k = X_k / 2^e`` exactly (floats are dyadic rationals)."""
    pairs = [float(x).as_integer_ratio() for x in xs]
    e = max((q.bit_length() - 1 for _, q in pairs), default=0)
    return [p << (e - (q.bit_length() - 1)) for p, q in pairs], e


def _exact_l1_modulus(nodes: list[int], values: list[int], e: int, f: int, d: float) -> Fraction:
    """``int |N_lin(nu) - N_lin(nu - d)| dnu`` exactly (``N_lin`` linear, zero outside its support).

    The nodes are ``X_k / 2^e`` and the values ``V_k / 2^f`` (integers, :func:`_dyadic`), ``d`` a
    float: every breakpoint (a node, or a node shifted by ``d``) and every stored value is a
    dyadic rational, and so is everything but the interpolated values and the integrals of
    ``|.|`` across a sign change, all summed in integers.

    The breakpoints are merged in order, each with its point shifted back by ``d``, and the
    one-sided limits of ``N_lin`` at both are read by pointers that only move forward
    (:func:`_sides`): linear in the number of nodes, with no search per breakpoint, and at a
    node (every breakpoint is one, or one shifted by ``d``) the stored value. On each interval
    between breakpoints the difference is linear, from ``a`` to ``b``: its integral of ``|.|``
    is ``(hi - lo) (|a| + |b|) / 2`` when ``a b >= 0``, else ``(hi - lo) (a^2 + b^2) / (2 (|a| + |b|))``.
    """
    p, q = float(d).as_integer_ratio()
    e_d = q.bit_length() - 1
    scale = max(e, e_d)  # breakpoints are B / 2^scale
    X = nodes if scale == e else [x << (scale - e) for x in nodes]
    D = p << (scale - e_d)
    n = len(X)
    # merge the nodes and the shifted nodes, equal points once; each breakpoint b with b - d beside it
    br: list[int] = []
    br_back: list[int] = []
    i = j = 0
    while i < n or j < n:
        if j >= n or (i < n and X[i] < X[j] + D):
            b, bb = X[i], X[i] - D
            i += 1
        else:
            b, bb = X[j] + D, X[j]
            if i < n and X[i] == b:
                i += 1
            j += 1
        if not br or b != br[-1]:
            br.append(b)
            br_back.append(bb)
    left, right = _sides(X, values, br)
    left_back, right_back = _sides(X, values, br_back)
    # a value P / (L 2^f) is the pair (P, L); the integral's terms are summed per denominator L
    same: dict[int, int] = {}
    crossing = Fraction(0)
    starts = [_minus(u, v) for u, v in zip(right, right_back)]  # the difference just right of each breakpoint
    ends = [_minus(u, v) for u, v in zip(left[1:], left_back[1:])]  # and just left of the next one
    for lo, hi, (pa, la), (pb, lb) in zip(br, br[1:], starts, ends):
        width = hi - lo
        if (pa > 0 > pb) or (pa < 0 < pb):
            crossing += Fraction(
                width * (pa * pa * lb * lb + pb * pb * la * la), la * lb * (abs(pa) * lb + abs(pb) * la)
            )
        else:
            same[la] = same.get(la, 0) + width * abs(pa)
            same[lb] = same.get(lb, 0) + width * abs(pb)
    total = sum((Fraction(v, den) for den, v in same.items()), crossing)
    return total / (1 << (scale + f + 1))


def _minus(u: tuple[int, int], v: tuple[int, int]) -> tuple[int, int]:
    """``u - v`` for values ``P / L`` given as pairs ``(P, L)``, ``L > 0``."""
    (pu, lu), (pv, lv) = u, v
    if lu == lv:
        return pu - pv, lu
    if lv == 1:
        return pu - pv * lu, lu
    if lu == 1:
        return pu * lv - pv, lv
    return pu * lv - pv * lu, lu * lv


def _sides(
    nodes: list[int], values: list[int], queries: list[int]
) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """Left and right limits of the linear interpolant (zero outside the nodes) at increasing ``queries``.

    Nodes and queries are integers on one scale, values integers; a limit is returned as
    ``(P, L)`` for the value ``P / L`` (``L = 1`` at a node, else the length of the segment).
    A query equal to a node takes the stored values (the left one of a repeated node from the
    left, the right one from the right; zero outside the support); elsewhere both limits are
    the interpolated value.
    """
    n, idx = len(nodes), 0
    left: list[tuple[int, int]] = []
    right: list[tuple[int, int]] = []
    for x in queries:
        while idx < n and nodes[idx] < x:
            idx += 1
        if idx < n and nodes[idx] == x:  # a node: idx its first occurrence
            last = idx + 1 if idx + 1 < n and nodes[idx + 1] == x else idx
            left.append((values[idx] if idx > 0 else 0, 1))
            right.append((values[last] if last < n - 1 else 0, 1))
            continue
        if idx <= 0 or idx >= n:
            left.append((0, 1))
            right.append((0, 1))
            continue
        x0, x1 = nodes[idx - 1], nodes[idx]
        v = (values[idx - 1] * (x1 - x0) + (values[idx] - values[idx - 1]) * (x - x0), x1 - x0)
        left.append(v)
        right.append(v)
    return left, right


def _exact_delay_bound(
    N: DistributedDelay, epsilon_0: float, K: float, rtol: float, max_steps: int
) -> RoucheDelayBound:
    """:func:`delay_bound_from_kernel` in exact rational arithmetic (``epsilon_0 > 0``).

    Each step from ``d`` to ``d + h`` (floats) is accepted when
    ``omega_lin(d) + h TV_lin < budget`` exactly, which bounds ``omega_lin`` on the whole
    step (subadditivity); then ``omega_lin(d + h)`` is computed exactly.
    """
    if np.iscomplexobj(N.values) or N.moment != 0:
        raise ParameterError("N", "a real DistributedDelay kernel of moment 0", N)
    tv, dev = _exact_pieces(N, _rationals())
    (nodes, e), (values, f) = _dyadic(N.nodes.tolist()), _dyadic(N.values.tolist())

    def modulus(d: float) -> Fraction:
        return _exact_l1_modulus(nodes, values, e, f, d)

    budget = Fraction(epsilon_0) - 2 * dev
    if tv == 0:
        return RoucheDelayBound(np.inf, epsilon_0, 0.0, 0.0, K, 0, True)
    if budget <= 0:
        return RoucheDelayBound(0.0, epsilon_0, float(2 * dev), float(tv), K, 0, True)
    d, om, steps = 0.0, Fraction(0), 0
    while steps < max_steps:
        h = 0.999 * float((budget - om) / tv)
        if d > 0.0 and h <= rtol * d:
            break
        nxt = d + h
        if not om + (Fraction(nxt) - Fraction(d)) * tv < budget:
            break
        d, om, steps = nxt, modulus(nxt), steps + 1
    return RoucheDelayBound(float(d), epsilon_0, _up(om + 2 * dev), _up(tv), K, steps, True)


def _up(x: Fraction) -> float:
    """The float nearest ``x``, rounded up when below it."""
    v = float(x)
    return v if Fraction(v) >= x else float(np.nextafter(v, np.inf))
