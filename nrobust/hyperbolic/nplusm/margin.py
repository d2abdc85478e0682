"""Delay margins of ``U(t) = K u(t - delta, 1)`` on ``n + m`` systems, the same delay on every actuator.

One actuator: :func:`nplusm_delay_margin` (certified: proven frequency bound and complete
crossing search of ``|A(i w)| = |B(i w)|``; with ``rigorous=True`` proven in ball arithmetic for
the PDE itself, :mod:`~nrobust.hyperbolic.nplusm.proven_margin`). Any ``m``: :func:`multi_actuator_delay_margin`
(certified, in compound form) and :func:`multi_actuator_margin` (with ``omega_max``: a capped
scan of the pencil ``M_0 v = -z M_1 v``, :func:`pencil_crossings`, which the backstepping
controller's margin with grid kernels also uses). The full-state backstepping law with exact
kernels, one leftward speed: :func:`backstepping_exact_margin` (certified, kernel-free).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._digits import upper_bound_text, with_accuracy
from ..._json import fields_dict
from ..._validate import positive, positive_int
from ...errors import CertificationError, ParameterError
from ...margins.matrix import GaugeRemainder, circle_crossings, compound_generator, compound_minors
from ...roots import count_roots
from .characteristic import EPS, EXPM_ROUNDING, GRID_PER_PERIOD, NPlusMCharacteristic
from .compound import compound_characteristic, compound_loop
from .proven_margin import proven_axis_crossings, proven_frequency_bound
from .system import NPlusMSystem

__all__ = [
    "NPlusMMargin",
    "backstepping_exact_margin",
    "compound_delay_error",
    "compound_omega_error",
    "crossing_delay_error",
    "crossing_omega_error",
    "multi_actuator_delay_margin",
    "multi_actuator_margin",
    "nplusm_delay_margin",
    "pencil_crossings",
    "smallest_delay_error",
    "smallest_omega_error",
]

_STATIC_SCOPE = "static gain U = K u(t - delta, 1) on the PDE"
_PROVEN_SCOPE = (
    "static gain U = K u(t - delta, 1) on the PDE itself, proven in ball arithmetic (its exact Laplace-domain loop, "
    "the stored parameters as exact rationals)"
)
_TARGET_SCOPE = (
    "full-state backstepping law with exact kernels on the PDE (kernel-free: E (Phi_v - J) = exp(-Sigma--/mu))"
)


@dataclass(frozen=True)
class NPlusMMargin:
    """The smallest loop delay that puts a root of a one-actuator ``n + 1`` loop on the axis.

    Attributes
    ----------
    margin : float
        ``0`` when the principal part with the delay is not strongly stable
        (``gamma_0 >= 1``: arbitrarily small delays destabilise), ``inf`` when
        ``|A(i w)| != |B(i w)|`` for every ``w >= 0``, else the smallest
        ``(arg(-B/A)(i w) mod 2 pi) / w`` over the crossing frequencies.
    omega : float or None
        The crossing frequency of ``margin``.
    crossings : tuple of (float, float)
        Every crossing frequency ``w > 0`` with its first delay.
    gamma_0 : float
        ``sum |R_a U_a Q_a| / |V| + sum |K_a U_a Q_a| / |V|`` of the delayed principal part
        (exact for one actuator).
    frequency_bound : float
        ``W``: proven ``|A(i w)| != |B(i w)|`` for ``w >= W``, and no zero of
        ``F(.; delta)`` with ``Re s >= 0``, ``|s| >= W``, for any ``delta >= 0``
        (:meth:`NPlusMCharacteristic.frequency_bound`).
    certified : bool
        True: the frequency bound is proven (gauge transformation and Gronwall's lemma,
        module notes), every crossing on ``[0, W]`` is found by a search with a certified
        exclusion and monotonicity test, the delay-free loop's unstable roots are counted
        (:func:`~nrobust.roots.count_roots` on ``[0, W] x [-W, W]``), and ``gamma_0 >= 1``
        is decided with room above rounding. False for ``gamma_0`` within ``1e-12`` of 1,
        or when a root of the delay-free loop lies within rounding of the axis.
    nominal_unstable : int or None
        Certified number of roots of the delay-free loop in ``Re s >= 0`` (None: not
        counted, ``gamma_0 >= 1``, or a root within rounding of the axis). When it is not
        0 the margin is 0: the loop is not stable to begin with.
    scope : str
        The loop the result is about (``certified`` certifies it for that loop only): the
        static gain's loop of the PDE; the full-state backstepping law with exact kernels
        (:func:`backstepping_exact_margin`, kernel-free); or that law with the grid kernels
        of :func:`~nrobust.hyperbolic.nplusm.solve_nplusm_kernels` (a model of the law with
        no error bound).
    margin_bracket : (float, float) or None
        A proven ``[lower, upper]`` of the margin: of the law with exact kernels when the loop
        carries the grid kernels' proven error (:func:`~nrobust.hyperbolic.nplusm.cascade_delay_margin`,
        whose ``margin`` is the grid kernels' loop's), or of this loop with ``rigorous``
        (``margin`` then lies in it); None for the other loops, whose ``margin`` is itself the claim,
        and for a margin 0 or ``inf`` decided by the structure (exact).
    error : float or None
        0 for a margin 0 or ``inf`` decided by the structure (``gamma_0 >= 1``, an unstable
        delay-free loop, no crossing), else an estimate of the error of ``margin`` from every
        crossing's (:func:`crossing_delay_error` for :func:`nplusm_delay_margin`,
        :func:`compound_delay_error` for :func:`multi_actuator_delay_margin` and
        :func:`backstepping_exact_margin`), combined by :func:`smallest_delay_error`: a crossing
        whose first delay is within its error of ``margin`` may be the smallest, and the error
        covers it. None when not estimated (the capped scan of :func:`multi_actuator_margin`, the
        grid kernels' loops, a crossing whose error is unknown). With ``rigorous``: the proven
        distance from ``margin`` to the far end of ``margin_bracket``.
    omega_bracket : (float, float) or None
        With ``rigorous``: a proven enclosure of the crossing frequency of the margin (the hull
        of the enclosures of the crossings whose delay may be the smallest); with a proven
        ``margin_bracket`` of the law with exact kernels (:func:`~nrobust.hyperbolic.nplusm.cascade_delay_margin`)
        that of the exact law's crossing frequency (the hull of the search's cells whose delays
        may be the smallest); else None.
    rigorous : bool
        True: every claim (the frequency bound, the count of the delay-free loop, the
        crossings and ``margin_bracket``) is proven in ball arithmetic for the PDE itself
        (:func:`nplusm_delay_margin` with ``rigorous=True``).
    omega_error : float or None
        Without ``omega_bracket``: an estimate of the error of ``omega`` (:func:`crossing_omega_error`
        for :func:`nplusm_delay_margin`, :func:`compound_omega_error` for
        :func:`multi_actuator_delay_margin` and :func:`backstepping_exact_margin`), widened by
        :func:`smallest_omega_error` to the crossings whose delay may be the smallest; None when
        not estimated.
    """

    margin: float
    omega: float | None
    crossings: tuple[tuple[float, float], ...]
    gamma_0: float
    frequency_bound: float
    certified: bool
    nominal_unstable: int | None = None
    scope: str = _STATIC_SCOPE
    margin_bracket: tuple[float, float] | None = None
    error: float | None = None
    omega_bracket: tuple[float, float] | None = None
    rigorous: bool = False
    omega_error: float | None = None

    @property
    def accuracy(self) -> float | None:
        """A bound of the margin's error: with a ``margin_bracket`` the distance to its far end
        (proven, about the law with exact kernels), else :attr:`error`; None when not known."""
        if self.margin_bracket is not None:
            lo, hi = self.margin_bracket
            return float(np.nextafter(max(hi - self.margin, self.margin - lo, 0.0), np.inf))
        return self.error

    @property
    def omega_accuracy(self) -> float | None:
        """A bound of the crossing frequency's error: proven from :attr:`omega_bracket`, else the estimate
        :attr:`omega_error`; None when not known."""
        if self.omega is None:
            return None
        if self.omega_bracket is None:
            return self.omega_error
        lo, hi = self.omega_bracket
        return float(np.nextafter(max(hi - self.omega, self.omega - lo, 0.0), np.inf))

    def __repr__(self) -> str:
        omega = "None" if self.omega is None else with_accuracy(self.omega, self.omega_accuracy)
        rigorous = ", rigorous=True" if self.rigorous else ""
        return (
            f"NPlusMMargin(margin={with_accuracy(self.margin, self.accuracy)}, omega={omega}, "
            f"crossings={len(self.crossings)}, gamma_0<={upper_bound_text(self.gamma_0)}, certified={self.certified}"
            f"{rigorous}, nominal_unstable={self.nominal_unstable}, scope={self.scope!r})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


# Safety factor of crossing_delay_error and compound_delay_error: the largest ratio of the true error
# (crossings re-solved on 40-digit matrix exponentials) to the unscaled estimate was 0.09 on ten crossings
# of three systems for the first (tests/test_nplusm_digits.py checks four), and 0.09 on eight crossings of
# seven loops for the second (m = 1 and 2, static gains and the backstepping law; from 0.001 to 0.09;
# tests/test_nplusm_digits.py checks five): 16 leaves 170 times that.
_DELAY_SAFETY = 16.0

# Safety factor of crossing_omega_error and compound_omega_error (the same Newton steps, for the frequency).
_OMEGA_SAFETY = 16.0


def crossing_delay_error(F: NPlusMCharacteristic, omega: float, delay: float) -> float | None:
    """An estimate of the error of the first delay ``delay = (arg(-B/A) mod 2 pi) / omega`` of a crossing.

    With ``g = |A(i w)|^2 - |B(i w)|^2`` and ``phi = arg(-B/A)(i w)``: the frequency is off by
    ``dw = (|g| + 2 (|A| + |B|) e) / |g'|`` (``e`` the rounding level of :meth:`NPlusMCharacteristic.axis_jet`),
    the phase by ``dphi = e / |A| + e / |B|``, and ``delay = phi / w`` moves by
    ``|phi' - delay| dw / w + dphi / w`` (``phi' = Re(B'/B - A'/A)``, derivatives in ``s``).
    Times 16 (:data:`_DELAY_SAFETY`), plus ``eps delay``. None at a tangency (``g' = 0``).
    """
    step = _axis_step(F, omega)
    if step is None:
        return None
    dw, dphi, phase_slope = step
    turn = abs(phase_slope - delay)
    return _DELAY_SAFETY * (turn * dw + dphi) / omega + EPS * delay


def crossing_omega_error(F: NPlusMCharacteristic, omega: float) -> float | None:
    """An estimate of the error of a crossing frequency ``omega`` of ``|A(i w)| = |B(i w)|``.

    The Newton step ``dw`` of :func:`crossing_delay_error` (``|g|`` raised by the rounding level),
    times :data:`_OMEGA_SAFETY`, plus ``eps omega``. None at a tangency (``g' = 0``).
    """
    step = _axis_step(F, omega)
    return None if step is None else _OMEGA_SAFETY * step[0] + EPS * omega


def _axis_step(F: NPlusMCharacteristic, omega: float) -> tuple[float, float, float] | None:
    """``(dw, dphi, phi')`` of :func:`crossing_delay_error` at ``omega``; None at a tangency."""
    A, B, dA, dB, level, _ = F.axis_jet(np.array([omega]))
    a, b, da, db = complex(A[0]), complex(B[0]), complex(dA[0]), complex(dB[0])
    e = float(max(level[0][0], level[1][0]))
    slope = abs(2.0 * ((a.conjugate() * 1j * da).real - (b.conjugate() * 1j * db).real))
    if not slope > 0.0:
        return None
    dw = (abs(abs(a) ** 2 - abs(b) ** 2) + 2.0 * (abs(a) + abs(b)) * e) / slope
    return dw, e / abs(a) + e / abs(b), (db / b - da / a).real


def smallest_omega_error(
    crossings: Sequence[tuple[float, float]], delay_errors: Sequence[float | None], omega_errors: Sequence[float | None]
) -> float | None:
    """A bound of the error of the crossing frequency of the smallest delay, each crossing ``(w, delay)`` known
    to within its errors.

    Every crossing whose delay interval reaches below the smallest delay's upper end may be the
    true smallest (as in :func:`smallest_delay_error`): the bound is the largest distance from the
    smallest delay's ``w`` to the far end of such a crossing's frequency interval. None when an
    error it needs is unknown.
    """
    best = min(range(len(crossings)), key=lambda i: crossings[i][1])
    if delay_errors[best] is None:
        return None
    upper = crossings[best][1] + float(delay_errors[best])  # type: ignore[arg-type]
    bound = 0.0
    for (w, d), de, we in zip(crossings, delay_errors, omega_errors):
        if de is None or d - de <= upper:
            if we is None or de is None:
                return None
            bound = max(bound, abs(w - crossings[best][0]) + we)
    return bound


def smallest_delay_error(delays: Sequence[float], errors: Sequence[float | None]) -> float | None:
    """A bound of the error of ``min(delays)`` when each delay is known to within its error.

    The true smallest delay lies in ``[min_i (d_i - e_i), min_i (d_i + e_i)]`` (``min`` is monotone
    in each argument): a delay other than the smallest, within its own error of it, may be the
    true smallest. The bound is the distance from ``min(delays)`` to the far end of that interval,
    at least the smallest delay's own error.

    Parameters
    ----------
    delays : sequence of float
        The computed delays (not empty).
    errors : sequence of float or None
        A bound of each delay's error (None: not known).

    Returns
    -------
    float or None
        None when any error is unknown (its delay may be the smallest, by any amount).

    Examples
    --------
    >>> smallest_delay_error([1.0, 2.0], [0.125, 0.125])
    0.125
    >>> smallest_delay_error([1.0, 1.25], [0.125, 0.5])  # the second may be the smaller, down to 0.75
    0.25
    >>> smallest_delay_error([math.inf], [0.0])  # no crossing
    0.0
    """
    if len(delays) != len(errors) or not delays:
        raise ParameterError("errors", f"one error per delay ({len(delays)}), at least one", len(errors))
    known = [e for e in errors if e is not None]
    if len(known) < len(errors):
        return None
    best = min(delays)
    if math.isinf(best):  # no crossing: an infinite margin is exact
        return 0.0
    lower = min(d - e for d, e in zip(delays, known))
    upper = min(d + e for d, e in zip(delays, known))
    return max(best - lower, upper - best)


def pencil_crossings(
    loop_matrices: Callable[[NDArray[np.complex128]], tuple[NDArray[np.complex128], NDArray[np.complex128]]],
    omega_max: float,
    points: int,
    *,
    bisections: int,
    max_points: int | None = None,
) -> tuple[tuple[float, float], ...]:
    """Crossings ``(w, delay)`` of the loop ``det(M_0(s) + e^{-delta s} M_1(s))`` on ``(0, omega_max]``, by a scan.

    A root sits at ``s = i w`` iff ``z = e^{-i w delta}`` is an eigenvalue of the pencil
    ``M_0 v = -z M_1 v`` on the unit circle. The eigenvalues inside the unit disk are
    counted on ``points`` equally spaced frequencies of ``(0, omega_max]``; each change of
    the count is bisected ``bisections`` times (every bracket at once), and the eigenvalue
    closest to the circle at the midpoint gives the delay ``(-arg z mod 2 pi) / w``. Not
    certified: two eigenvalues crossing in opposite directions between grid points, or a
    crossing above ``omega_max``, are missed.

    Parameters
    ----------
    loop_matrices : callable
        ``s -> (M_0(s), M_1(s))`` on an array of ``s``, each of shape ``s.shape + (m, m)``.
    omega_max : float
        Upper end of the scan (validated by the caller).
    points : int
        Grid points (validated by the caller).
    bisections : int
        Bisection steps per bracket.
    max_points : int, optional
        Work bound on pencil evaluations (``points`` plus ``bisections + 1`` per crossing),
        checked once the grid is scanned, before bisecting.

    Returns
    -------
    tuple of (float, float)
        ``(w, delay)`` of each change of the count, in increasing ``w``.
    """
    from scipy.linalg import eigvals  # lazily: a slow import

    def pencil(w: NDArray[np.float64]) -> NDArray[np.complex128]:
        m0, m1 = loop_matrices(1j * np.asarray(w, dtype=float))
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.array([eigvals(a, -b) for a, b in zip(m0, m1)])

    def inside(w: NDArray[np.float64]) -> NDArray[np.int64]:
        return np.sum(np.abs(pencil(w)) < 1.0, axis=-1)

    w = np.linspace(omega_max / points, omega_max, points)
    n_in = inside(w)
    change = np.flatnonzero(n_in[:-1] != n_in[1:])
    need = points + (bisections + 1) * change.size
    if max_points is not None and need > max_points:
        raise ParameterError("max_points", f">= {need} ({change.size} crossings to bisect)", max_points)
    if not change.size:
        return ()
    lo, hi, n_lo = w[change], w[change + 1], n_in[change]
    for _ in range(bisections):  # every bracket at once
        mid = 0.5 * (lo + hi)
        same = inside(mid) == n_lo
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    wc = 0.5 * (lo + hi)
    found = []
    for x, z in zip(wc, pencil(wc)):
        zc = z[np.argmin(np.abs(np.abs(z) - 1.0))]
        found.append((float(x), float(np.mod(-np.angle(zc), 2 * np.pi) / x)))
    return tuple(found)


def nplusm_delay_margin(
    system: NPlusMSystem, K: ArrayLike, *, max_points: int = 2_000_000, rigorous: bool = False, prec: int = 53
) -> NPlusMMargin:
    """Certified delay margin of ``U(t) = K u(t - delta, 1)`` on a one-actuator ``n + 1`` system.

    ``F(s; delta) = A(s) + B(s) e^{-delta s}`` (module notes): a root reaches ``s = i w``
    only where ``g(w) = |A(i w)|^2 - |B(i w)|^2`` vanishes, at the delays
    ``(arg(-B/A) mod 2 pi + 2 pi k) / w``. Beyond the proven frequency bound ``W``
    (:meth:`NPlusMCharacteristic.frequency_bound`) there is no crossing; on ``[0, W]``
    the search is complete (:meth:`NPlusMCharacteristic.crossing_frequencies`: Lipschitz
    exclusion of ``|A| - |B|``, then monotonicity of ``g`` from a bound of ``|g''|``).

    With ``rigorous=True`` every step is proven in ball arithmetic for the PDE itself
    (:mod:`~nrobust.hyperbolic.nplusm.proven_margin`: ``A`` and ``B`` from FLINT's proven
    matrix exponential, the stored parameters as exact rationals): the frequency bound
    (:func:`~nrobust.hyperbolic.nplusm.proven_frequency_bound`, for every delay at once), the
    count of the delay-free loop's roots in ``Re s >= 0`` (:func:`~nrobust.roots.count_roots`
    with ``rigorous=True`` on ``[0, W] x [-W, W]``), every crossing on ``[0, W]`` with the ball
    of its frequency and first delay (:func:`~nrobust.hyperbolic.nplusm.proven_axis_crossings`),
    hence ``margin_bracket`` and ``omega_bracket``; ``margin`` and ``omega`` are their midpoints.

    Parameters
    ----------
    system : NPlusMSystem
        With ``m = 1``; the loop with ``K`` and no delay should be stable (the margin is
        then the delay margin: the loop stays stable for every ``delta < margin``).
    K : array_like, shape (1, n)
        The gain.
    max_points : int, optional
        Work bound on evaluations of ``A`` and ``B`` on the axis, checked before each grid
        is allocated (with ``rigorous``: on the ball evaluations of the crossing search).
    rigorous : bool, optional
        Prove the margin in ball arithmetic (python-flint, ``pip install nrobust[rigorous]``).
    prec : int, optional
        Working precision in bits of the ball arithmetic (``rigorous=True``).

    Returns
    -------
    NPlusMMargin

    Raises
    ------
    CertificationError
        The work bound was hit, or ``g`` has a zero of even multiplicity (a tangency) to
        rounding that the search cannot decide. With ``rigorous``, also: ``gamma_0 >= 1``
        (the margin 0 is decided in floating point only), or a step not proven in balls
        (the message names it; a higher ``prec`` or a slight change of the gain helps).
    """
    F = NPlusMCharacteristic(system, K, 0.0)
    if system.m != 1:
        raise ParameterError("system", "one actuator (m = 1): the loop is then A + B e^{-delta s}", system.m)
    max_points = positive_int("max_points", max_points)
    if not isinstance(rigorous, bool):
        raise ParameterError("rigorous", "True or False", rigorous)
    prec = positive_int("prec", prec, minimum=16, maximum=4096)
    if rigorous:
        return _proven_static_margin(F, max_points, prec)
    gamma = F.gamma_0()
    if gamma >= 1.0:
        return NPlusMMargin(0.0, None, (), gamma, 0.0, gamma > 1.0 + 1e-12, error=0.0 if gamma > 1.0 + 1e-12 else None)
    W = F.frequency_bound()
    radius = max(W, 1.0)  # the bound holds for every radius >= W
    count = count_roots(F, (0.0, radius, -radius, radius))
    nominal = int(count) if count.region[0] >= 0.0 else None
    if nominal != 0:
        return NPlusMMargin(
            0.0, None, (), gamma, W, nominal is not None, nominal, error=None if nominal is None else 0.0
        )
    found = []
    for wc in F.crossing_frequencies(W, max_points=max_points):
        a, b = F.factors(np.array([1j * wc]))
        found.append((wc, float(np.mod(np.angle(-b[0] / a[0]), 2 * np.pi) / wc)))
    certified = gamma < 1.0 - 1e-12
    if not found:
        return NPlusMMargin(np.inf, None, (), gamma, W, certified, 0, error=0.0)
    best = min(found, key=lambda p: p[1])
    delay_errors = [crossing_delay_error(F, w, d) for w, d in found]
    error = smallest_delay_error([d for _, d in found], delay_errors)
    omega_error = smallest_omega_error(found, delay_errors, [crossing_omega_error(F, w) for w, _ in found])
    return NPlusMMargin(best[1], best[0], tuple(found), gamma, W, certified, 0, error=error, omega_error=omega_error)


def _proven_static_margin(F: NPlusMCharacteristic, max_evals: int, prec: int) -> NPlusMMargin:
    """The ``rigorous=True`` route of :func:`nplusm_delay_margin` (its notes)."""
    gamma = F.gamma_0()
    if gamma >= 1.0 - 1e-12:
        raise CertificationError(
            f"proven delay margin: gamma_0 = {gamma:.12g} of the delayed principal part is not below 1 (the margin 0 "
            "of gamma_0 > 1 is decided in floating point: rigorous=False)"
        )
    W = proven_frequency_bound(F, prec=prec)
    radius = max(W, 1.0)
    count = count_roots(F, (0.0, radius, -radius, radius), rigorous=True, prec=prec)
    x0, x1, y0, y1 = count.region  # an edge may have been shifted off a root: what was counted where
    covers = x0 <= 0.0 and x1 >= W and y0 <= -W and y1 >= W  # shifted edges move outward: a defensive check
    if not (covers if int(count) == 0 else x0 >= 0.0):
        raise CertificationError(
            f"proven delay margin: the delay-free loop's roots were counted in {count.region} (an edge shifted off a "
            f"root near it), which does not decide Re s >= 0 within |s| < W = {W!r}; raise prec"
        )
    if int(count) != 0:  # unstable without delay: the margin 0 is exact
        return NPlusMMargin(0.0, None, (), gamma, W, True, int(count), _PROVEN_SCOPE, None, 0.0, None, True)
    found, _ = proven_axis_crossings(F.ball_function(prec), W, max_evals=max_evals)
    if not found:
        return NPlusMMargin(np.inf, None, (), gamma, W, True, 0, _PROVEN_SCOPE, None, 0.0, None, True)
    lo = min(c.delay[0] for c in found)
    hi = min(c.delay[1] for c in found)
    near = [c for c in found if c.delay[0] <= hi]  # each may hold the smallest delay
    w_lo, w_hi = min(c.omega[0] for c in near), max(c.omega[1] for c in near)
    margin = min(max(0.5 * (lo + hi), lo), hi)
    omega = min(max(0.5 * (w_lo + w_hi), w_lo), w_hi)
    crossings = tuple((0.5 * (c.omega[0] + c.omega[1]), 0.5 * (c.delay[0] + c.delay[1])) for c in found)
    bracket = (lo, hi)
    error = float(np.nextafter(max(hi - margin, margin - lo), np.inf))
    return NPlusMMargin(margin, omega, crossings, gamma, W, True, 0, _PROVEN_SCOPE, bracket, error, (w_lo, w_hi), True)


def multi_actuator_margin(
    system: NPlusMSystem,
    K: ArrayLike,
    omega_max: float | None = None,
    *,
    points: int = 4000,
    max_points: int = 1_000_000,
) -> NPlusMMargin:
    """Delay margin of ``U(t) = K u(t - delta, 1)``, the same delay on all ``m`` actuators.

    Without ``omega_max`` this is :func:`multi_actuator_delay_margin` (certified: a proven
    frequency bound replaces ``omega_max``). With ``omega_max`` the search below runs on
    ``(0, omega_max]`` only, as a cap, and the result is never certified.

    ``F(s; delta) = det(M_0(s) + e^{-delta s} M_1(s))`` with ``M_0`` the loop matrix of
    ``K = 0`` and ``M_1 = -E K Phi_u``. A root sits at ``s = i w`` iff
    ``z = e^{-i w delta}`` is an eigenvalue of the pencil ``M_0 v = -z M_1 v`` on the unit
    circle; the delays are ``(-arg z mod 2 pi) / w``. The number of eigenvalues inside the
    unit disk is tracked on a grid of ``(0, omega_max]``; each change is located by
    bisection and gives one crossing frequency. Not certified (``certified=False``): two
    eigenvalues crossing the circle in opposite directions between grid points, or a
    crossing above ``omega_max``, would be missed; ``gamma_0`` is the certified upper bound
    of the delayed principal part's spectral radius (as in :func:`multi_actuator_delay_margin`),
    the margin 0 when a sampled value is at least 1, and ``nominal_unstable`` the certified
    count of the delay-free loop in ``[0, omega_max] x [-omega_max, omega_max]`` only.

    Parameters
    ----------
    system : NPlusMSystem
    K : array_like, shape (m, n)
    omega_max : float, optional
        Upper end ``> 0`` of a capped, uncertified search; None (default) for the certified margin.
    points : int, optional
        Grid points (``>= 16``) of the capped search.
    max_points : int, optional
        Work bound on pencil evaluations (on evaluations of the compound transition without
        ``omega_max``), checked before the grid is allocated.
    """
    if omega_max is None:
        return multi_actuator_delay_margin(system, K, max_points=max_points)
    k = system.gain(K)
    omega_max = positive("omega_max", omega_max)
    points = positive_int("points", points, minimum=16)
    max_points = positive_int("max_points", max_points)
    if points + 64 * system.m * max(1, points // 8) > max_points:
        raise ParameterError("max_points", f">= {points + 64 * system.m * max(1, points // 8)}", max_points)
    lower, gamma, _ = principal_gamma_bounds(system, k)
    if lower >= 1.0:
        return NPlusMMargin(0.0, None, (), gamma, 0.0, False)
    count = count_roots(NPlusMCharacteristic(system, k, 0.0), (0.0, omega_max, -omega_max, omega_max))
    nominal = int(count) if count.region[0] >= 0.0 else None
    if nominal != 0:
        return NPlusMMargin(0.0, None, (), gamma, omega_max, False, nominal)

    def loop(s: NDArray[np.complex128]) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        m0 = system.loop_matrix(s)
        return m0, system.loop_matrix(s, k) - m0

    found = pencil_crossings(loop, omega_max, points, bisections=60)
    if not found:
        return NPlusMMargin(np.inf, None, (), gamma, omega_max, False, 0)
    best = min(found, key=lambda p: p[1])
    return NPlusMMargin(best[1], best[0], tuple(found), gamma, omega_max, False, 0)


def principal_gamma_bounds(system: NPlusMSystem, k: NDArray[np.float64]) -> tuple[float, float, float]:
    """``(lower, upper, |det V|)``: a sampled and a certified bound of ``sup rho(V^{-1} sum_t C_t e^{i theta_t})``
    over independent phases of the principal terms ``C_t`` (``R_ab`` and ``K_ab`` apart).

    The upper end is the smaller of the Collatz-Wielandt bound of ``rho(sum_t |V^{-1} C_t|)`` (which bounds
    ``rho`` on the whole polydisc) and, for at most four distinct delays, the certified
    :meth:`~nrobust.matrix_difference.MatrixDifferenceOperator.gamma_0` bracket.
    """
    v_block, point = system.principal_terms(k)
    v_inv = np.linalg.inv(v_block)
    mats = [v_inv @ a for _, rq, kq in point for a in (rq, kq) if np.any(a != 0)]
    if not mats:
        return 0.0, 0.0, float(abs(np.linalg.det(v_block)))
    total = np.sum(np.abs(mats), axis=0)
    vals, vecs = np.linalg.eig(total)
    x = np.abs(vecs[:, int(np.argmax(np.abs(vals)))]) + 1e-12 * float(np.abs(vecs).max())
    upper = float(np.max((total @ x) / x)) * (1.0 + 1e-12)
    rng = np.random.default_rng(0)
    theta = np.vstack([np.zeros(len(mats)), rng.uniform(0.0, 2 * np.pi, (2047, len(mats)))])
    lower = float(np.max(np.abs(np.linalg.eigvals(np.einsum("nt,tij->nij", np.exp(1j * theta), np.array(mats))))))
    try:
        bracket = system.principal_operator(k, 1e-3 * np.sqrt(2.0)).gamma_0(rtol=1e-6, max_cells=20_000)
        lower, upper = max(lower, bracket.lower), min(upper, bracket.upper)
    except (ParameterError, CertificationError):
        pass  # more than four delays, or a bracket that did not close: the Collatz-Wielandt bound stands
    return lower, max(upper, lower), float(abs(np.linalg.det(v_block)))


def multi_actuator_delay_margin(system: NPlusMSystem, K: ArrayLike, *, max_points: int = 2_000_000) -> NPlusMMargin:
    """Certified delay margin of ``U(t) = K u(t - delta, 1)``, the same delay on all ``m >= 1`` actuators.

    ``F(s; delta) = det(M_0(s) + e^{-delta s} M_1(s))`` (``M_0`` the loop matrix of ``K = 0``,
    ``M_1 = -E K Phi_u``). By Cauchy-Binet, ``f(w, z) = det(M_0(i w) + z M_1(i w)) =
    sum_d z^d a_d^T exp(D_m(C) - i w P_m) b`` with ``a_d`` the coefficients of the minors of
    ``[-(R + z K), I]``, ``b`` those of ``[Q; I]`` and ``D_m``, ``P_m >= 0`` the compound
    generator and rates (:mod:`nrobust.margins.matrix`). A root reaches ``s = i w`` for some
    delay iff ``f(w, e^{i phi}) = 0``, at the delays ``((-phi) mod 2 pi + 2 pi k) / w``
    (an eigenvalue ``e^{-i phi}`` of ``-M_0^{-1} M_1`` on the unit circle).

    1. *Principal part.* ``|F_0(s; z)| = |det V| |det(I - X)| >= |det V| (1 - gamma)^m`` on
       ``Re s >= 0``, ``|z| <= 1``, with ``gamma`` a certified bound of the spectral radius of
       ``X = V^{-1} sum (R_ab + z K_ab) e^{-tau_ab s}`` over independent phases (Hale and
       Verduyn Lunel's ``gamma_0`` of the delayed principal part; the margin is 0 when a
       sampled ``rho`` is above 1: arbitrarily small delays destabilise).
    2. *Frequency bound.* ``|F - F_0| <= sum_d ||a_d|| ||b|| r(|s|)`` with ``r`` the
       :class:`~nrobust.margins.matrix.GaugeRemainder` of ``(D_m(C), P_m)``: beyond the
       proven ``W`` where this is below the gap, ``F(s; delta) != 0`` on ``Re s >= 0`` for
       every ``delta >= 0``, and no eigenvalue of ``-M_0^{-1} M_1`` has modulus 1 on the axis.
    3. *Nominal stability.* :func:`~nrobust.roots.count_roots` of the delay-free loop on
       ``[0, W] x [-W, W]``.
    4. *Crossings.* :func:`~nrobust.margins.matrix.circle_crossings` on ``[0, W] x [0, 2 pi)``
       (Lipschitz exclusion, Newton-Kantorovich discs; a tangency raises).

    Parameters
    ----------
    system : NPlusMSystem
    K : array_like, shape (m, n)
    max_points : int, optional
        Work bound on evaluations of the compound transition on the axis.

    Returns
    -------
    NPlusMMargin
        ``gamma_0`` is the certified upper bound used in step 1 (exact for ``m = 1``); ``error``
        from every crossing's :func:`compound_delay_error` (:func:`smallest_delay_error`).

    Raises
    ------
    CertificationError
        The bound of step 1 is not below 1 although no sampled ``rho`` exceeds 1, a work bound
        was hit, or the crossing search met a tangency.
    """
    k = system.gain(K)
    max_points = positive_int("max_points", max_points)
    m = system.m
    lower, gamma, det_v = principal_gamma_bounds(system, k)
    if lower >= 1.0 + 1e-12:
        return NPlusMMargin(0.0, None, (), lower, 0.0, True, error=0.0)
    if gamma >= 1.0 - 1e-12:
        raise CertificationError(
            f"multi-actuator margin: gamma_0 of the delayed principal part in [{lower:.12g}, {gamma:.12g}] is not "
            "separated from 1 (the certified bound of its spectral radius must be below 1)"
        )
    dc, p, a, b = compound_loop(system, k)

    def nominal(radius: float) -> int | None:
        count = count_roots(compound_characteristic(system, k, 0.0), (0.0, radius, -radius, radius))
        return int(count) if count.region[0] >= 0.0 else None

    max_delay = NPlusMCharacteristic(system, k).max_delay
    return _compound_margin(dc, p, a, b, m, gamma, det_v, max_delay, nominal, max_points, _STATIC_SCOPE)


def _target_compound(system: NPlusMSystem) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """``(D_m(C^), p, a, b)`` of the backstepping law's loop (:func:`backstepping_exact_margin`) in compound form.

    ``M(s; z) = (1 - z) [-R, I] exp(C - s P) W + z V = L(z) exp(C^ - s P^) W^`` with
    ``C^ = diag(C, -Sigma--/mu)``, ``P^ = diag(P, 0)`` (``P = Lambda^{-1} + I/mu >= 0``),
    ``L(z) = [(1 - z) [-R, I], z I]`` and ``W^ = [Q; I; I]``: the augmented block carries
    ``V = exp(-Sigma--/mu)`` at rate 0 (module notes of :mod:`nrobust.margins.matrix`).
    """
    n, m = system.n, system.m
    size = n + 2 * m
    inv = 1.0 / system.signed_speeds
    c = np.zeros((size, size))
    c[: n + m, : n + m] = inv[:, None] * system.sigma
    c[n + m :, n + m :] = c[n : n + m, n : n + m]
    rate = np.concatenate([1.0 / system.lam + 1.0 / float(system.mu[0]), np.zeros(2 * m)])
    subsets = list(itertools.combinations(range(size), m))
    p = np.array([sum(rate[i] for i in S) for S in subsets])
    for i in np.argsort(p):  # rates equal up to the order of a sum are made equal (groups of the gauge)
        p[np.abs(p - p[i]) <= 1e-13 * max(1.0, abs(p[i]))] = p[i]
    b = compound_minors(np.vstack([system.q, np.eye(m), np.eye(m)]), axis=0)
    roots = np.exp(2j * np.pi * np.arange(m + 1) / (m + 1))
    ell = np.hstack([-system.r, np.eye(m)])
    vals = np.array([compound_minors(np.hstack([(1.0 - z) * ell, z * np.eye(m)]), axis=1) for z in roots])
    return compound_generator(c, m), p, np.fft.fft(vals, axis=0) / (m + 1), b


def backstepping_exact_margin(system: NPlusMSystem, *, max_points: int = 2_000_000) -> NPlusMMargin:
    """Certified delay margin of the full-state backstepping law with exact kernels, without kernels.

    The law ``U = -R u(t, 1) + int_0^1 K(1, xi) u + L(1, xi) v dxi`` of Hu et al. (2016)
    (:class:`~nrobust.hyperbolic.nplusm.NPlusMBackstepping`) maps the plant onto the target
    ``beta_t - Lambda- beta_x = D beta + G(x) beta(t, 0)``, ``beta(t, 1) = 0``. In the Laplace
    domain (``v(0) = I``) the transformation gives ``beta(1) = Phi_v(s) - J(s)`` and the
    target gives ``beta(1) = T(s)``, the transition of ``beta_x = Lambda-^{-1} ((s - D) beta
    - G beta(0))``. When every ``v`` has the same speed ``mu`` (one group; ``m = 1`` always),
    ``D = Sigma--`` and ``G = 0``, so ``E (Phi_v - J) = e^{-s/mu} exp((s - D)/mu) =
    V = exp(-Sigma--/mu)``, a constant: the delayed loop is

        ``det(M_0(s) + e^{-delta s} (V - M_0(s)))``,  ``M_0 = E (Phi_v - R Phi_u)`` (the open loop),

    with no kernel in it. Its delay-free value is ``det V != 0`` (no root: the finite-time
    convergence), and its principal part is that of the static cancellation ``K = -R``. The
    margin is then certified as in :func:`multi_actuator_delay_margin`, in compound form
    with the augmented generator ``diag(C, -Sigma--/mu)``:
    ``gamma_0`` bound, proven frequency bound, complete crossing search.

    Parameters
    ----------
    system : NPlusMSystem
        With all leftward speeds ``mu`` equal.
    max_points : int, optional
        Work bound on evaluations of the compound transition on the axis.

    Returns
    -------
    NPlusMMargin
        ``scope`` names the exact law; ``certified`` as in :func:`multi_actuator_delay_margin`
        (floating-point certificate with rounding bounds; the kernels of a grid are not used,
        so their error does not enter). ``nominal_unstable`` is 0 by the identity above; ``error``
        as in :func:`multi_actuator_delay_margin`.

    Raises
    ------
    ParameterError
        Leftward speeds not all equal: then ``G != 0`` depends on the kernels (the target is a
        cascade) and the loop is not kernel-free
        (:meth:`~nrobust.hyperbolic.nplusm.NPlusMBackstepping.cascade_loop_matrices`: that loop
        with the grid kernels' ``G``, no error bound).
    CertificationError
        As :func:`multi_actuator_delay_margin`.
    """
    if not isinstance(system, NPlusMSystem):
        raise ParameterError("system", "an NPlusMSystem", type(system).__name__)
    if np.any(system.mu != system.mu[0]):
        raise ParameterError(
            "system",
            "leftward speeds mu all equal (one group, so that the target's G = 0 and the loop needs no kernel)",
            system.mu.tolist(),
        )
    max_points = positive_int("max_points", max_points)
    cancel = -system.r
    lower, gamma, det_v = principal_gamma_bounds(system, cancel)
    if lower >= 1.0 + 1e-12:
        return NPlusMMargin(0.0, None, (), lower, 0.0, True, None, _TARGET_SCOPE, error=0.0)
    if gamma >= 1.0 - 1e-12:
        raise CertificationError(
            f"backstepping margin: gamma_0 of the delayed principal part in [{lower:.12g}, {gamma:.12g}] is not "
            "separated from 1 (the certified bound of its spectral radius must be below 1)"
        )
    dc, p, a, b = _target_compound(system)
    max_delay = NPlusMCharacteristic(system, cancel).max_delay
    return _compound_margin(dc, p, a, b, system.m, gamma, det_v, max_delay, lambda _: 0, max_points, _TARGET_SCOPE)


def _compound_margin(
    dc: NDArray[np.complex128],
    p: NDArray[np.float64],
    a: NDArray[np.complex128],
    b: NDArray[np.complex128],
    m: int,
    gamma: float,
    det_v: float,
    max_delay: float,
    nominal: Callable[[float], int | None],
    max_points: int,
    scope: str,
) -> NPlusMMargin:
    """Steps 2-4 of :func:`multi_actuator_delay_margin` for a loop ``sum_d z^d a_d^T exp(D - s diag(p)) b``
    whose principal part obeys ``|F_0| >= det_v (1 - gamma)^m`` on ``Re s >= 0``, ``|z| <= 1``
    (``gamma < 1``); ``nominal(radius)`` counts the delay-free loop's roots in ``[0, radius] x [-radius, radius]``.
    The margin's error: :func:`compound_delay_error` of each crossing, :func:`smallest_delay_error` of them."""
    from scipy.linalg import expm  # lazily: a slow import

    a_norm = np.linalg.norm(a, axis=1)
    b_norm = float(np.linalg.norm(b))
    scale = float(a_norm.sum()) * b_norm
    level = det_v * (1.0 - gamma) ** m * (1.0 - 1e-9) - 1e-12 * scale
    W = GaugeRemainder(dc, p).radius(scale, level)
    count = nominal(max(W, 1.0))
    if count != 0:
        error = None if count is None else 0.0
        return NPlusMMargin(0.0, None, (), gamma, W, count is not None, count, scope, error=error)
    beta = float(np.linalg.eigvalsh(0.5 * (dc + dc.conj().T))[-1]) + 1e-12 * (1.0 + float(np.abs(dc).sum()))
    pn = float(np.max(p))
    growth = np.exp(beta) * b_norm * a_norm * (1.0 + 1e-12)
    bounds = np.array([growth, growth * pn, growth * pn**2])
    dc_norm = float(np.linalg.norm(dc, 2))
    pdiag = np.diag(p)

    def coefs(w: NDArray[np.float64]) -> NDArray[np.complex128]:
        g = expm(dc[None] - 1j * w[:, None, None] * pdiag[None]) @ b
        return np.asarray(g @ a.T, dtype=complex)

    def jet(w: NDArray[np.float64]) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        size = dc.shape[0]
        big = np.zeros((w.size, 2 * size, 2 * size), dtype=complex)
        big[:, :size, :size] = big[:, size:, size:] = dc[None] - 1j * w[:, None, None] * pdiag[None]
        big[:, :size, size:] = -1j * pdiag  # exp([[A, A'], [0, A]]) = [[G, G'], [0, G]] (Van Loan), ' = d/dw
        e = expm(big)
        return e[:, :size, :size] @ b @ a.T, e[:, :size, size:] @ b @ a.T

    def rounding(w: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(
            EXPM_ROUNDING * EPS * np.exp(beta) * b_norm * float(a_norm.max()) * (1.0 + dc_norm + w * pn), dtype=float
        )

    step = 2.0 * np.pi / (GRID_PER_PERIOD * max_delay)
    zeros = circle_crossings(coefs, jet, W, bounds, rounding, step=step, max_points=max_points)
    found = tuple((w, float(np.mod(-phi, 2 * np.pi) / w)) for w, phi in zeros)
    certified = gamma < 1.0 - 1e-12
    if not found:
        return NPlusMMargin(np.inf, None, (), gamma, W, certified, 0, scope, error=0.0)
    best = min(found, key=lambda c: c[1])
    errors = [compound_delay_error(jet, rounding, w, d) for w, d in found]
    error = smallest_delay_error([d for _, d in found], errors)
    omega_error = smallest_omega_error(found, errors, [compound_omega_error(jet, rounding, w, d) for w, d in found])
    return NPlusMMargin(best[1], best[0], found, gamma, W, certified, 0, scope, error=error, omega_error=omega_error)


def compound_delay_error(
    jet: Callable[[NDArray[np.float64]], tuple[NDArray[np.complex128], NDArray[np.complex128]]],
    rounding: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    omega: float,
    delay: float,
) -> float | None:
    """An estimate of the error of the first delay of a crossing of ``f(w, z) = sum_d c_d(w) z^d`` (compound form).

    At ``phi = -omega delay``, with ``f``, ``f_w = sum_d c_d' z^d``, ``f_phi = sum_d i d c_d z^d`` at
    ``z = e^{i phi}``, the Newton step of the two real equations ``Re f = Im f = 0`` in ``(w, phi)``,
    ``|f|`` raised by the rounding level ``e`` of the ``D + 1`` coefficients (``(D + 1) e``, the
    triangle inequality), bounds the distance to the crossing: ``dw``, ``dphi``. The delay
    ``(-phi mod 2 pi) / w`` moves by ``(dphi + delay dw) / w``. Times 16 (:data:`_DELAY_SAFETY`,
    the study in the notes above it), plus ``eps delay``. None when the Jacobian is
    singular to rounding (a tangency).

    Parameters
    ----------
    jet : callable
        ``w -> (c_d(w), c_d'(w))``, each of shape ``(w.size, D + 1)``.
    rounding : callable
        ``w -> e``: a bound of the rounding error of each computed ``c_d(w)``.
    omega, delay : float
        The crossing frequency ``> 0`` and its first delay.

    Returns
    -------
    float or None
    """
    step = _compound_step(jet, rounding, omega, delay)
    if step is None:
        return None
    return _DELAY_SAFETY * float(step[1] + delay * step[0]) / omega + EPS * delay


def compound_omega_error(
    jet: Callable[[NDArray[np.float64]], tuple[NDArray[np.complex128], NDArray[np.complex128]]],
    rounding: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    omega: float,
    delay: float,
) -> float | None:
    """An estimate of the error of the crossing frequency ``omega`` of a crossing in compound form.

    The Newton step ``dw`` of :func:`compound_delay_error`, times :data:`_OMEGA_SAFETY`, plus
    ``eps omega``. None when the Jacobian is singular to rounding (a tangency).
    """
    step = _compound_step(jet, rounding, omega, delay)
    return None if step is None else _OMEGA_SAFETY * float(step[0]) + EPS * omega


def _compound_step(
    jet: Callable[[NDArray[np.float64]], tuple[NDArray[np.complex128], NDArray[np.complex128]]],
    rounding: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    omega: float,
    delay: float,
) -> NDArray[np.float64] | None:
    """The bound ``(dw, dphi)`` of :func:`compound_delay_error`'s Newton step; None at a tangency."""
    c, dc = jet(np.array([float(omega)]))
    e = float(np.asarray(rounding(np.array([float(omega)])))[0])
    orders = np.arange(c.shape[1])
    z = np.exp(-1j * omega * delay * orders)
    f, f_w, f_phi = complex(c[0] @ z), complex(dc[0] @ z), complex((1j * orders * c[0]) @ z)
    J = np.array([[f_w.real, f_phi.real], [f_w.imag, f_phi.imag]])
    if not np.linalg.cond(J) < 1.0 / EPS:
        return None
    return np.asarray(np.abs(np.linalg.inv(J)).sum(axis=1) * (abs(f) + c.shape[1] * e), dtype=float)
