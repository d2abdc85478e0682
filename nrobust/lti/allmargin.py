"""Stability margins of a loop with delays: :func:`allmargin` (MATLAB's sense) and :func:`loop_delay_margin`.

For a SISO loop ``L = N / D`` under negative unit feedback, every crossing is located on a
frequency band that provably holds them all, never on a sampled grid:

* **gain crossovers** ``|L(i w)| = 1`` are the zeros of ``|D(i w)|^2 - |N(i w)|^2``,
  the crossing frequencies of the loop ``D + N e^{-delta s}``
  (:func:`nrobust.margins.crossing_frequencies`: complete on ``[0, W]`` with ``W`` the
  proven frequency bound of :mod:`nrobust.margins.axis`, which exists when the loop gain
  falls below 1 at high frequency). At each, the phase margin
  ``PM = angle L(i w) + 180 deg`` (in ``(-180, 180]``) and the delay margin
  ``DM = (PM mod 2 pi) / w``, the smallest extra delay that puts a closed-loop pole at
  ``i w`` (the first delay of :class:`~nrobust.margins.Crossing`);
* **phase crossovers** ``L(i w) < 0`` real are the zeros ``w > 0`` of ``Im(N(i w) conj D(i w))``,
  which equals ``(|D + i N|^2 - |D - i N|^2) / 4``: the crossing search run on the
  factors ``D - i N`` and ``D + i N`` over ``[-W_g, W_g]`` (complex coefficients; a
  real pair ``D + (1 +- s) N`` would put a double zero at ``w = 0``), where ``W_g`` is the proven
  frequency bound of ``|L(i w)| < gain_floor`` (the loop ``D + (N / gain_floor) e^{-delta s}``).
  With a delay in the loop the phase crossovers are infinitely many, with gains tending
  to 0: the band holds every one whose gain margin ``1 / |L|`` is below ``1 / gain_floor``
  (and some above). The gain margins include the factors below 1 (a loop stable only
  above some gain) as MATLAB's ``allmargin`` lists them.

Integrators are taken out exactly first (:func:`nrobust.lti.pade.split_integrators`): with
``N = s^j N_0`` and ``D = s^k D_0``, the gain search runs on the factors without their common
power of ``s``, and the phase search on ``Im(N conj D) / w^(j + k) = Im(i^j (-i)^k N_0 conj D_0)``
(the same zeros for ``w > 0``), so a type-2 loop such as a PI controller on an integrating plant
puts no zero of high order at ``w = 0`` into either search. A zero loop ``N = 0`` has no
crossover; a loop real at every ``s = i w`` (decided exactly, e.g. ``1 / (s^2 + 2)``) has phase
crossovers filling whole intervals and is refused.

Zeros and poles of the loop on the imaginary axis (``N(i w) = 0`` or ``D(i w) = 0``, e.g. an
undamped oscillator ``1 / (s^2 + w_0^2)`` or a notch ``s^2 + w_0^2`` in ``N``) make
``Im(N conj D)`` vanish without ``L(i w)`` being a negative real number: ``L`` is ``0`` (no finite
gain margin to gain) or infinite there (the phase jumps, no gain margin at all). They are no phase
crossovers and are left out. Their factor, the exact greatest common divisor of the point terms'
polynomials restricted to its axis zeros (rational arithmetic), is real on the axis and is divided
out of the phase search; a zero or pole not found so (one of a quasi-polynomial with distributed
terms, or not shared by all its terms) is left out when ``N`` or ``D`` vanishes in floating point at
the refined frequency. Either way the closed loop's stability is still decided by the certified
pole count of ``D + N`` (``stable``).

Each crossing is refined by Brent's method on a bracket of the certified sign change
(``xtol = 1e-12 (1 + w)``), and every number carries an accuracy (``AllMargins.*_accuracies``):
a conservative floating-point estimate of its error, not a proof. For a crossing ``w`` of
``h(w)`` (``h = |D|^2 - |N|^2`` for a gain crossover, ``Im(N conj D)`` for a phase crossover) it
is ``16 (|h(w)| + eps M_h(w)) / |h'(w)| + eps w``: the Newton step at the refined frequency plus
the rounding error of ``h`` (``M_h`` from the sums of the moduli of the monomials,
:meth:`~nrobust.quasipoly.QuasiPolynomial.magnitude`) turned into a distance through the slope,
with the safety factor 16 of :attr:`nrobust.margins.DelayMargin.omega_accuracy`. The margins take
it through their derivatives in ``w``: ``d/dw log L(i w) = i (N'/N - D'/D)`` (real part: the log
gain, imaginary part: the phase), plus the rounding of ``L`` itself, ``4 eps (M_N / |N| + M_D / |D|)``
relative; the delay margin ``phi / w`` adds ``phi dw / w^2``. A tangential crossing
(``h' = 0`` within rounding) has no such estimate (NaN, printed "accuracy not estimated").
:func:`loop_delay_margin` gives the smallest delay margin with its own accuracy, proven in
ball arithmetic with ``rigorous=True``. ``stable`` is the certified verdict on the closed loop
``D + N`` (:func:`nrobust.margins.unstable_count`). A MIMO loop is taken a loop at a
time (MATLAB's ``loopmargin``): loop ``i`` broken, the others closed with negative unit
feedback.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._digits import with_accuracy
from .._json import fields_dict
from .._validate import positive, positive_int
from ..errors import CertificationError, ParameterError
from ..margins import DelayMargin, crossing_frequencies, delay_margin, frequency_bound, unstable_count
from ..margins.crossing import crossing_search
from ..quasipoly import QuasiPolynomial
from .delay_lti import DelayLTI, as_delay_lti
from .pade import split_integrators
from .transfer import QuasiTransferFunction

__all__ = ["AllMargins", "allmargin", "loop_delay_margin", "loop_factors_of"]

# Relative and absolute tolerance of the refined crossing frequencies.
_XTOL = 1e-12
# Safety factor of the floating-point error estimates (that of DelayMargin.omega_accuracy).
_SAFETY = 16.0
_EPS = float(np.finfo(float).eps)


@dataclass(frozen=True, eq=False)
class AllMargins:
    """Every stability margin of a SISO loop under negative unit feedback (MATLAB's ``allmargin``).

    Attributes
    ----------
    gain_margins : ndarray
        ``1 / |L(i w)|`` at each phase crossover (factors above 1 may be gained, below 1
        lost before instability), ordered by frequency.
    gm_frequencies : ndarray
        The phase crossovers ``w`` (rad per unit time), increasing; ``0`` when ``L(0) < 0``.
    phase_margins : ndarray
        ``angle L(i w) + 180`` in degrees, in ``(-180, 180]``, at each gain crossover.
    pm_frequencies : ndarray
        The gain crossovers ``w``, increasing.
    delay_margins : ndarray
        ``(PM mod 360 deg) / w`` in time units (radians over rad per unit time): the
        smallest extra loop delay that puts a closed-loop pole at ``i w``.
    dm_frequencies : ndarray
        The same frequencies as ``pm_frequencies``.
    stable : bool
        True when the closed loop is certified exponentially stable (no zero of ``D + N``
        with ``Re s >= 0``); False otherwise, including when a zero lies within rounding
        of the imaginary axis.
    phase_band : float
        ``W_g``: every phase crossover below it is listed; beyond it ``|L| < gain_floor``.
    gain_band : float
        ``W``: no gain crossover at or beyond it (proven).
    gain_floor : float
        The loop gain under which phase crossovers beyond ``phase_band`` may be left out.
    gain_margin_accuracies, gm_frequency_accuracies : ndarray
        Bounds of the errors of ``gain_margins`` and ``gm_frequencies`` (conservative
        floating-point estimates, module notes; NaN when not estimated).
    phase_margin_accuracies, pm_frequency_accuracies : ndarray
        The same for ``phase_margins`` (degrees) and ``pm_frequencies`` (which are also
        ``dm_frequencies``).
    delay_margin_accuracies : ndarray
        The same for ``delay_margins``.
    """

    gain_margins: NDArray[np.float64]
    gm_frequencies: NDArray[np.float64]
    phase_margins: NDArray[np.float64]
    pm_frequencies: NDArray[np.float64]
    delay_margins: NDArray[np.float64]
    dm_frequencies: NDArray[np.float64]
    stable: bool
    phase_band: float
    gain_band: float
    gain_floor: float
    gain_margin_accuracies: NDArray[np.float64]
    gm_frequency_accuracies: NDArray[np.float64]
    phase_margin_accuracies: NDArray[np.float64]
    pm_frequency_accuracies: NDArray[np.float64]
    delay_margin_accuracies: NDArray[np.float64]

    def __repr__(self) -> str:
        def fmt(a: NDArray[np.float64], acc: NDArray[np.float64]) -> str:
            return "[" + ", ".join(with_accuracy(float(v), float(e)) for v, e in zip(a, acc)) + "]"

        return (
            f"AllMargins(gain_margins={fmt(self.gain_margins, self.gain_margin_accuracies)} "
            f"at w={fmt(self.gm_frequencies, self.gm_frequency_accuracies)}, "
            f"phase_margins={fmt(self.phase_margins, self.phase_margin_accuracies)} deg "
            f"at w={fmt(self.pm_frequencies, self.pm_frequency_accuracies)}, "
            f"delay_margins={fmt(self.delay_margins, self.delay_margin_accuracies)}, stable={self.stable})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


def loop_factors_of(L: Any) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``(N, D)`` with ``L = N / D`` for a SISO loop.

    ``L`` is a :class:`~nrobust.lti.transfer.QuasiTransferFunction`, a SISO
    :class:`~nrobust.lti.delay_lti.DelayLTI` (:meth:`~nrobust.lti.delay_lti.DelayLTI.to_quasi_transfer`)
    or a SISO python-control system.
    """
    if isinstance(L, QuasiTransferFunction):
        return L.num, L.den
    if isinstance(L, QuasiPolynomial):
        return L, QuasiPolynomial([[1.0]], [0.0])
    sys = as_delay_lti(L)
    if not sys.issiso():
        raise ParameterError("L", "a SISO loop (pick a loop of a MIMO one with loop=i)", sys)
    H = sys.to_quasi_transfer()
    return H.num, H.den


def _loop(L: Any, i: int) -> DelayLTI:
    """Loop ``i`` of a square MIMO loop, the others closed by negative unit feedback."""
    sys = as_delay_lti(L)
    p = sys.noutputs
    if sys.ninputs != p:
        raise ParameterError("L", "a square loop (as many inputs as outputs)", (p, sys.ninputs))
    i = positive_int("loop", i, minimum=0, maximum=p - 1)
    others = np.eye(p)
    others[i, i] = 0.0
    return sys.feedback(others)[i, i]


def _refine(f: Any, w: float, W: float) -> float:
    """``w`` refined by Brent's method on a bracket where ``f`` changes sign (kept if there is none)."""
    tol = _XTOL * (1.0 + abs(w))
    for width in (1e-9, 1e-7, 1e-5):
        h = width * (1.0 + abs(w))
        a, b = max(w - h, 0.0), min(w + h, W)
        fa, fb = f(a), f(b)
        if fa == 0.0:
            return a
        if fb == 0.0:
            return b
        if np.sign(fa) != np.sign(fb):
            from scipy.optimize import brentq  # scipy.optimize loads in 0.1 s: not at import

            return float(brentq(f, a, b, xtol=tol, rtol=4 * np.finfo(float).eps))
    return w


def allmargin(
    L: Any, loop: int | list[int] | None = None, *, gain_floor: float | None = None, max_evals: int = 2_000_000
) -> Any:
    """Every gain, phase and delay margin of a loop under negative unit feedback (MATLAB's ``allmargin``).

    Parameters
    ----------
    L : QuasiTransferFunction, DelayLTI or python-control system
        The loop transfer function (SISO, or square MIMO with ``loop``).
    loop : int or list of int, optional
        For a MIMO loop: the loop (or loops) broken one at a time, the others closed.
    gain_floor : float, optional
        Phase crossovers are listed completely on the band where ``|L(i w)| >= gain_floor``
        may hold (module notes). Default ``1e-2`` (every gain margin up to 40 dB), or, for a
        neutral loop whose gain tends to ``g_inf >= 1e-2`` at high frequency (the bound that the
        principal parts give), ``1.25 g_inf`` (``sqrt(g_inf)`` when that is not below 1): its
        phase crossovers never end, and those with ``|L| >= gain_floor`` are listed.
    max_evals : int, optional
        Work bound of each crossing search (evaluations of the loop factors).

    Returns
    -------
    AllMargins, or a list of them when ``loop`` is a list

    Raises
    ------
    ParameterError
        A loop whose gain does not fall below 1 (or a given ``gain_floor``, the message then
        giving the loop's high-frequency gain) at high frequency: the crossovers then
        accumulate at infinity and no finite band holds them. A loop real
        at every ``s = i w`` (no isolated phase crossover).
    CertificationError
        A crossing search could not be completed within its work bound.

    Examples
    --------
    >>> import numpy as np
    >>> from nrobust.lti.delay_lti import delay, tf
    >>> m = allmargin(2.0 * delay(0.1) * tf([1.0], [1.0, 1.0]))   # 2 e^{-0.1 s} / (s + 1)
    >>> w = np.sqrt(3.0)
    >>> bool(abs(m.pm_frequencies[0] - w) < 1e-12)
    True
    >>> bool(abs(np.radians(m.phase_margins[0]) - (np.pi - 0.1 * w - np.arctan(w))) < 1e-12)
    True
    """
    floor = None if gain_floor is None else positive("gain_floor", gain_floor)
    max_evals = positive_int("max_evals", max_evals)
    if isinstance(loop, list):
        return [allmargin(_loop(L, i), gain_floor=floor, max_evals=max_evals) for i in loop]
    if loop is not None:
        L = _loop(L, loop)
    N, D = loop_factors_of(L)
    if not (N.is_real and D.is_real):
        raise ParameterError("L", "real coefficients", L)
    if not N.distributed and not any(np.any(p) for p, _ in N.point_terms):
        return _zero_loop(D, _DEFAULT_FLOOR if floor is None else floor)
    if _real_on_axis(N, D):
        raise ParameterError(
            "L",
            "a loop whose phase varies with frequency (L(i w) is real at every w here, so its phase crossovers "
            "fill whole intervals and no gain margin is isolated)",
            L,
        )
    # L = s^(j - k) N_0 / D_0 exactly: the searches run on the factors without their common power of
    # s, and the phase search on Im(N conj D) / w^(j + k), so a loop with integrators puts no
    # zero of high order at w = 0 into either search.
    j, N0 = split_integrators(N)
    k, D0 = split_integrators(D)
    m = min(j, k)
    N_gain = N0.times_poly(np.eye(j - m + 1)[-1]) if j > m else N0
    D_gain = D0.times_poly(np.eye(k - m + 1)[-1]) if k > m else D0
    rotate = 1j**j * (-1j) ** k  # Im(N conj D) = w^(j + k) Im(rotate N_0 conj D_0) for w > 0
    try:
        gains = crossing_frequencies(D_gain, N_gain, max_evals=max_evals)
    except ParameterError as exc:
        raise ParameterError(
            "L", "a loop whose gain falls below 1 at high frequency (|L(i w)| < 1 for large w)", L
        ) from exc
    if floor is None:
        floor = _DEFAULT_FLOOR
        if frequency_bound(D, N * (1.0 / floor)) is None:  # a neutral loop: |L| tends to g_inf >= floor
            g_inf = _high_frequency_gain(N, D)
            floor = 1.25 * g_inf if 1.25 * g_inf < 1.0 else math.sqrt(g_inf)
    bound = frequency_bound(D, N * (1.0 / floor))
    if bound is None:
        g_inf = _high_frequency_gain(N, D)
        raise ParameterError(
            "gain_floor",
            f"above the high-frequency gain of the loop, {g_inf:.4g} (|L(i w)| < gain_floor for large w)",
            floor,
        )
    W_g = bound[0]

    # Axis zeros of N_0 and D_0 (zeros and poles of L on the axis) are zeros of Im(N conj D) but no
    # phase crossover: their exact factors, real on the axis, are taken out of the phase search.
    N1, D1 = _without_axis_factor(N0), _without_axis_factor(D0)

    def loop_at(w: float) -> complex:
        s = np.array([1j * w])
        return complex(N(s)[0] / D(s)[0])

    def gain_gap(w: float) -> float:
        s = np.array([1j * w])
        return float(abs(D(s)[0]) ** 2 - abs(N(s)[0]) ** 2)

    def phase_gap(w: float) -> float:
        s = np.array([1j * w])
        return float(np.imag(rotate * N1(s)[0] * np.conj(D1(s)[0])))

    w_pm = np.array([_refine(gain_gap, float(w), gains.frequency_bound) for w in gains.omegas])
    at = np.array([loop_at(w) for w in w_pm], dtype=complex)
    pm = np.angle(-at)  # angle L + pi, in (-pi, pi]
    dm = np.mod(pm, 2.0 * np.pi) / w_pm if w_pm.size else np.zeros(0)
    N_phase = N1 * (1j * rotate)
    phases, _ = crossing_search(D1 - N_phase, D1 + N_phase, bound, max_evals)
    w_gm = [0.0] if _negative_real(loop_at(0.0) if abs(D(np.zeros(1))[0]) > 0 else np.inf) else []
    for w in phases.omegas:
        if w > 0:
            w = _refine(phase_gap, float(w), W_g * (1.0 + 1e-6) + 1e-9)
            s = np.array([1j * w])
            n, d = complex(N(s)[0]), complex(D(s)[0])
            # n or d = 0 in floating point: a zero or pole of L met where it is not factored out
            # exactly (distributed terms): L is 0 or infinite there, not a negative real number.
            if n != 0.0 and d != 0.0 and np.real(n / d) < 0.0:
                w_gm.append(w)
    gm_w = np.array(sorted(w_gm), dtype=float)
    gm = np.array([1.0 / abs(loop_at(w)) for w in gm_w], dtype=float)
    dw_pm = np.array([_gain_crossing_error(D_gain, N_gain, w) for w in w_pm], dtype=float)
    dw_gm = np.array([0.0 if w == 0.0 else _phase_crossing_error(N1, D1, rotate, w) for w in gm_w], dtype=float)
    slope_pm = [_log_slope(N, D, w) for w in w_pm]
    slope_gm = [_log_slope(N, D, w) for w in gm_w]
    pm_acc = np.array([abs(q.real) * e + rel + np.pi * _EPS for (q, rel), e in zip(slope_pm, dw_pm)], dtype=float)
    dm_acc = pm_acc / w_pm + np.mod(pm, 2.0 * np.pi) * dw_pm / w_pm**2 if w_pm.size else np.zeros(0)
    gm_acc = np.array([g * (abs(q.imag) * e + rel) for g, (q, rel), e in zip(gm, slope_gm, dw_gm)], dtype=float)
    count = unstable_count(D + N)
    if count.radius is None:
        raise CertificationError(f"allmargin: no bound of the closed-loop poles in Re s >= 0 ({count.method})")
    return AllMargins(
        gain_margins=gm,
        gm_frequencies=gm_w,
        phase_margins=np.degrees(pm),
        pm_frequencies=w_pm,
        delay_margins=dm,
        dm_frequencies=w_pm.copy(),
        stable=bool(count.certified and count.stable),
        phase_band=float(W_g),
        gain_band=float(gains.frequency_bound),
        gain_floor=floor,
        gain_margin_accuracies=gm_acc,
        gm_frequency_accuracies=dw_gm,
        phase_margin_accuracies=np.degrees(pm_acc),
        pm_frequency_accuracies=dw_pm,
        delay_margin_accuracies=dm_acc,
    )


def _crossing_error(h: float, noise: float, slope: float, w: float) -> float:
    """Estimated error of a refined zero ``w`` of ``h`` (module notes); NaN when ``h'`` vanishes."""
    if not slope > 0.0:
        return float("nan")
    return _SAFETY * (abs(h) + noise) / slope + _EPS * abs(w)


def _gain_crossing_error(D: QuasiPolynomial, N: QuasiPolynomial, w: float) -> float:
    """Error estimate of a zero ``w`` of ``g(w) = |D(i w)|^2 - |N(i w)|^2``."""
    s = np.array([1j * w])
    a, b = complex(D(s)[0]), complex(N(s)[0])
    da, db = 1j * complex(D.deriv_at(s)[0]), 1j * complex(N.deriv_at(s)[0])  # d/dw of D(i w), N(i w)
    slope = abs(2.0 * ((a.conjugate() * da).real - (b.conjugate() * db).real))
    noise = 2.0 * _EPS * (float(D.magnitude(s)[0]) ** 2 + float(N.magnitude(s)[0]) ** 2)
    return _crossing_error(abs(a) ** 2 - abs(b) ** 2, noise, slope, w)


def _phase_crossing_error(N: QuasiPolynomial, D: QuasiPolynomial, rotate: complex, w: float) -> float:
    """Error estimate of a zero ``w > 0`` of ``h(w) = Im(rotate N(i w) conj D(i w))``."""
    s = np.array([1j * w])
    n, d = complex(N(s)[0]), complex(D(s)[0])
    dn, dd = 1j * complex(N.deriv_at(s)[0]), 1j * complex(D.deriv_at(s)[0])
    slope = abs((rotate * (dn * d.conjugate() + n * dd.conjugate())).imag)
    noise = 2.0 * _EPS * float(N.magnitude(s)[0]) * float(D.magnitude(s)[0])
    return _crossing_error((rotate * n * d.conjugate()).imag, noise, slope, w)


def _log_slope(N: QuasiPolynomial, D: QuasiPolynomial, w: float) -> tuple[complex, float]:
    """``q = N'/N - D'/D`` at ``i w`` (``d/dw log L(i w) = i q``) and the relative rounding error of ``L(i w)``."""
    s = np.array([1j * w])
    n, d = complex(N(s)[0]), complex(D(s)[0])
    q = complex(N.deriv_at(s)[0]) / n - complex(D.deriv_at(s)[0]) / d
    rel = 4.0 * _EPS * (float(N.magnitude(s)[0]) / abs(n) + float(D.magnitude(s)[0]) / abs(d))
    return q, rel


#: ``gain_floor`` of :func:`allmargin` when the loop's gain falls below it at high frequency.
_DEFAULT_FLOOR = 1e-2


def _high_frequency_gain(N: QuasiPolynomial, D: QuasiPolynomial) -> float:
    """The least ``g`` (to 0.1 %, rounded up) with a proven frequency bound of ``|N / D| < g``: the
    high-frequency gain of the loop as the principal parts bound it (:func:`frequency_bound`);
    called on a loop whose gain falls below 1 (``g = 1`` has one)."""
    lo, hi = 0.0, 1.0
    while hi - lo > 1e-3 * hi:
        mid = 0.5 * (lo + hi)
        if mid > 0.0 and frequency_bound(D, N * (1.0 / mid)) is not None:
            hi = mid
        else:
            lo = mid
    return hi


def _zero_loop(D: QuasiPolynomial, floor: float) -> AllMargins:
    """The margins of ``L = 0``: no crossover at all; the closed loop is ``D`` itself."""
    count = unstable_count(D)
    if count.radius is None:
        raise CertificationError(f"allmargin: no bound of the closed-loop poles in Re s >= 0 ({count.method})")
    empty = np.zeros(0)
    return AllMargins(
        gain_margins=empty,
        gm_frequencies=empty.copy(),
        phase_margins=empty.copy(),
        pm_frequencies=empty.copy(),
        delay_margins=empty.copy(),
        dm_frequencies=empty.copy(),
        stable=bool(count.certified and count.stable),
        phase_band=0.0,
        gain_band=0.0,
        gain_floor=floor,
        gain_margin_accuracies=empty.copy(),
        gm_frequency_accuracies=empty.copy(),
        phase_margin_accuracies=empty.copy(),
        pm_frequency_accuracies=empty.copy(),
        delay_margin_accuracies=empty.copy(),
    )


def _real_on_axis(N: QuasiPolynomial, D: QuasiPolynomial) -> bool:
    """Whether ``Im(N(i w) conj D(i w)) = 0`` for every real ``w``, decided in exact rational arithmetic.

    With real coefficients ``N(i w) conj D(i w) = sum_d c_d(i w) e^{-i w d}``, ``c_d(s)`` the sum of
    ``p(s) q(-s)`` over the terms ``p e^{-a s}`` of ``N`` and ``q e^{-b s}`` of ``D`` with ``a - b = d``.
    The functions ``w^n e^{-i w d}`` being linearly independent, the sum is real for every ``w``
    exactly when ``c_d(s) = c_{-d}(-s)`` for every ``d``. A distributed term gives False (not decided
    here; the phase search then runs as usual).
    """
    if N.distributed or D.distributed:
        return False
    groups: dict[Fraction, dict[int, Fraction]] = {}
    for p, a in N.point_terms:
        for q, b in D.point_terms:
            c = groups.setdefault(Fraction(float(a)) - Fraction(float(b)), {})
            for u, pu in enumerate(np.real(p)):
                for v, qv in enumerate(np.real(q)):
                    c[u + v] = c.get(u + v, Fraction(0)) + Fraction(float(pu)) * Fraction(float(qv)) * (-1) ** v
    for d, c in groups.items():
        mirror = groups.get(-d, {})
        for n in set(c) | set(mirror):
            if c.get(n, Fraction(0)) != (-1) ** n * mirror.get(n, Fraction(0)):
                return False
    return True


def _without_axis_factor(F: QuasiPolynomial) -> QuasiPolynomial:
    """``F / h`` with ``h`` the exact factor of ``F`` whose zeros are the common zeros of its point terms'
    polynomials on the imaginary axis (``F`` itself when there is none or ``F`` has distributed terms).

    With ``c`` the exact greatest common divisor of the polynomials ``p_k`` (real, so rational) and
    ``c(i w) = A(w) + i B(w)``, the axis zeros of ``c`` are the real zeros of ``G = gcd(A, B)``. ``A`` is
    even and ``B`` odd, so ``G`` is even or odd; it is even when ``c(0) != 0`` (integrators split off
    first), and then ``h(s) = G(-i s)`` has real coefficients, divides every ``p_k`` and is real on the
    axis: ``h(i w) = G(w)``. Dividing it out removes from ``Im(N(i w) conj D(i w))`` only the real
    factor ``G(w)``, whose real zeros are the axis zeros of ``F``, and no other zero.
    """
    if F.distributed or not F.point_terms or not F.is_real:
        return F
    import flint  # python-flint: exact rational polynomials, not loaded at import

    def exact(coefs: Any) -> Any:
        return flint.fmpq_poly([flint.fmpq(*float(c).as_integer_ratio()) for c in np.real(coefs)])

    polys = [exact(p) for p, _ in F.point_terms]
    c = polys[0]
    for p in polys[1:]:
        c = c.gcd(p)
    if c.degree() < 1:
        return F
    coefs = c.coeffs()
    A = flint.fmpq_poly([x * (1 - n % 2) * (-1) ** (n // 2) for n, x in enumerate(coefs)])
    B = flint.fmpq_poly([x * (n % 2) * (-1) ** (n // 2) for n, x in enumerate(coefs)])
    G = A.gcd(B)
    g = G.coeffs()
    if G.degree() < 1 or any(g[1::2]):
        return F
    h = flint.fmpq_poly([x * (1 - n % 2) * (-1) ** (n // 2) for n, x in enumerate(g)])
    quotients = []
    for p in polys:
        q, r = divmod(p, h)
        if r != 0:
            return F
        quotients.append([float(Fraction(int(x.p), int(x.q))) for x in q.coeffs()])
    return QuasiPolynomial(quotients, [t for _, t in F.point_terms])


def _negative_real(z: complex) -> bool:
    return bool(np.isfinite(z) and z.imag == 0.0 and z.real < 0.0)


def loop_delay_margin(L: Any, **options: Any) -> DelayMargin:
    """Delay margin of a SISO loop ``L = N / D`` under negative unit feedback: the largest
    ``delta`` with ``1 + L(s) e^{-delta s}`` stable on ``[0, delta)``.

    The closed loop is ``F(s; delta) = D(s) + N(s) e^{-delta s}``:
    :func:`nrobust.margins.delay_margin` with ``A = D``, ``B = N`` (``options`` are its
    keywords: ``delta_max``, ``verify``, ``max_evals``, ``rigorous``).

    Examples
    --------
    >>> import numpy as np
    >>> from nrobust.lti.delay_lti import tf
    >>> m = loop_delay_margin(tf([2.0], [1.0, 1.0]))   # 2/(s+1): w = sqrt 3, DM = (pi - atan w)/w
    >>> bool(abs(m.margin - (np.pi - np.arctan(np.sqrt(3.0))) / np.sqrt(3.0)) < 1e-10)
    True
    """
    N, D = loop_factors_of(L)
    return delay_margin(D, N, **options)
