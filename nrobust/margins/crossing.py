"""Crossing frequencies of ``F(s; delta) = A(s) + B(s) e^{-delta s}``: a complete, certified search.

Roots of a loop with a delay ``delta`` reach the imaginary axis at ``s = i w`` only where
``|A(i w)| = |B(i w)|``; at such a *crossing frequency* the delays that put a root on the
axis are ::

    delta_{c,k} = (arg(-B(i w)/A(i w)) mod 2 pi + 2 pi k) / w,   k = 0, 1, ...

(from ``e^{-i w delta} = -A/B``). A root crosses from left to right (destabilising) or
back (stabilising) according to the sign of ``Re ds/ddelta``. By implicit
differentiation of ``F(s(delta); delta) = 0``, with ``g(w) = |A(i w)|^2 - |B(i w)|^2``, ::

    ds/ddelta = s B(s) e^{-delta s} / F'(s),
    Re (ds/ddelta)^{-1} = Re[-(A'/A - B'/B)/s] = g'(w) / (2 |A(i w)|^2 w),

so the direction is ``sign(g'(w)) sign(w)``, independent of ``k`` (Cooke and van den
Driessche); it is read from the certified sign of ``g'`` on the crossing's bracket.

The zeros of ``g`` are found by :mod:`nrobust.margins.search` on ``[0, W]``, ``W`` the
frequency bound of :mod:`nrobust.margins.axis` (nothing beyond ``W`` can be a
crossing). The search runs over ``[0, W (1 + 1e-6) + 1e-9]`` (symmetric for complex
coefficients): a crossing at ``W`` to rounding is an interior zero with a clear sign
change. :class:`AxisGap` exposes ``g``, its derivatives, their bounds and rounding
levels to other solvers (e.g. the pair-birth equations ``g = g' = 0`` of a gain study).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._digits import with_accuracy
from .._json import fields_dict
from .._validate import positive_int
from ..errors import ParameterError
from ..quasipoly import QuasiPolynomial
from .axis import AxisFunction, AxisGap, AxisKernels, AxisLipschitz, required_frequency_bound
from .search import first_stage, resolve

__all__ = [
    "Crossing",
    "CrossingSearch",
    "axis_crossings",
    "common_axis_zeros",
    "crossing_frequencies",
    "crossing_search",
]

# Relative tolerance under which a crossing delay counts as delta = 0, and under which
# A(0) + B(0) counts as zero.
ZERO_TOL = 1e-12
# Largest number of crossing delays enumerated up to delta_max.
_MAX_EVENTS = 100_000
# The search range extends past W by this much (relative, absolute).
_EXTEND_REL, _EXTEND_ABS = 1e-6, 1e-9
_EPS = float(np.finfo(float).eps)


# ============================================================================ results
@dataclass(frozen=True)
class Crossing:
    """A frequency ``w`` with ``|A(i w)| = |B(i w)|`` and the delays that put ``i w`` on a root.

    Attributes
    ----------
    omega : float
        Crossing frequency ``w`` (negative only for complex coefficients).
    delays : tuple of float
        ``delta_{c,k}``, ``k = 0, 1, ...``, up to the requested ``delta_max`` (at least the
        first one).
    direction : int
        ``+1`` destabilising (roots move into ``Re s > 0`` as delta grows), ``-1``
        stabilising, ``0`` tangential (the root touches the axis and turns back).
    ds_ddelta : complex
        ``ds/ddelta`` at ``s = i w``, ``delta = delays[0]``.
    tangential : bool
        True when ``|A|^2 - |B|^2`` has a double zero at ``w`` (to rounding): a tangency.
    omega_accuracy : float or None
        A bound of ``|omega - w|``, ``w`` the exact crossing frequency (proven with
        ``rigorous``, else an estimate: :attr:`nrobust.margins.DelayMargin.omega_error`'s, set by
        :func:`~nrobust.margins.delay_margin`); for a model of the plant its
        :attr:`~nrobust.margins.DelayMargin.omega_accuracy` on the margin's crossing and None on
        the others. None when not known.
    delay_accuracy : float or None
        A bound of ``|delays[0] - delta_c|``: the margin's
        :attr:`~nrobust.margins.DelayMargin.accuracy` on the crossing that gives the margin,
        else ``delay_accuracies[0]``; None when not known.
    delay_accuracies : tuple of (float or None)
        A bound of the error of each of ``delays`` (set by :func:`~nrobust.margins.delay_margin`):
        proven with ``rigorous`` (from the enclosures of the first delay and of the frequency,
        ``delta_k = delta_0 + 2 pi k / |w|``), else the estimate of the margin's
        :attr:`~nrobust.margins.DelayMargin.accuracy` made at each delay (its residual, and the
        frequency's error carried by the slope ``|Im(1/d_k)|``, ``1/d_k = 1/d_0 - i (delta_k -
        delta_0) / w``, ``d = ds/d delta``). None entries (or an empty tuple): not known (a
        tangency, a model of the plant).
    """

    omega: float
    delays: tuple[float, ...]
    direction: int
    ds_ddelta: complex
    tangential: bool
    omega_accuracy: float | None = None
    delay_accuracy: float | None = None
    delay_accuracies: tuple[float | None, ...] = ()

    @property
    def period(self) -> float:
        """Spacing ``2 pi / |w|`` of the delay sequence."""
        return float(2.0 * np.pi / abs(self.omega))

    def __repr__(self) -> str:
        kind = {1: "destabilising", -1: "stabilising", 0: "tangential"}[self.direction]
        w_acc = self.omega_accuracy
        period_acc = None if w_acc is None else self.period * (w_acc / abs(self.omega) + _EPS)
        return (
            f"Crossing(omega={with_accuracy(self.omega, w_acc)}, "
            f"delta_0={with_accuracy(self.delays[0], self.delay_accuracy)}, "
            f"period={with_accuracy(self.period, period_acc)}, {kind})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (``ds_ddelta`` as ``[real, imag]``)."""
        return fields_dict(self)


@dataclass(frozen=True, eq=False)
class CrossingSearch:
    """All zeros of ``|A(i w)| - |B(i w)|`` with ``|w| <= W`` and how they were certified.

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    omegas : ndarray
        Crossing frequencies, increasing.
    tangential : ndarray of bool
        Which of them are tangencies (double zeros of ``|A|^2 - |B|^2``).
    frequency_bound : float
        ``W``: no crossing for ``|w| >= W`` (and no zero of ``F(.; delta)`` with
        ``Re s >= 0``, ``|s| >= W``, for any delta, when ``A`` dominates).
    gap : float
        Dominance of the first principal term, ``|a_0| - sum |others|``.
    evaluations : int
        Evaluations of ``A`` and ``B`` (and their derivatives) on the axis.
    slopes : ndarray of int
        Certified sign of ``d/dw (|A(i w)|^2 - |B(i w)|^2)`` at each crossing (0 at
        tangencies); the direction of a crossing is ``slope * sign(omega)``.
    """

    omegas: NDArray[np.float64]
    tangential: NDArray[np.bool_]
    frequency_bound: float
    gap: float
    evaluations: int
    slopes: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))


# ============================================================================ entry points
def crossing_frequencies(A: QuasiPolynomial, B: QuasiPolynomial, *, max_evals: int = 2_000_000) -> CrossingSearch:
    """Every frequency ``w > 0`` (all real ``w`` for complex coefficients) with ``|A(i w)| = |B(i w)|``.

    The search range ``[0, W]`` is finite and provably complete, every reported absence
    of a crossing is a proof, and every crossing is classified as simple (with the
    certified sign of ``d/dw (|A|^2 - |B|^2)``) or as a tangency (module notes).

    Parameters
    ----------
    A, B : QuasiPolynomial
        The loop factors of ``F(s; delta) = A(s) + B(s) e^{-delta s}``.
    max_evals : int, optional
        Work bound on the evaluations of ``A`` and ``B`` (checked before any grid is
        allocated).

    Returns
    -------
    CrossingSearch

    Raises
    ------
    ParameterError
        If the difference operator of the loop is not strongly stable for small delays
        (no finite ``W`` exists: crossings accumulate at infinity).
    CertificationError
        If the work bound is hit, or a cluster cannot be decided (a zero of multiplicity
        three or more to rounding).

    Examples
    --------
    >>> A = QuasiPolynomial([[1.0, 1.0]], [0.0])      # s + 1
    >>> B = QuasiPolynomial([[2.0]], [0.0])           # 2 e^{-delta s}
    >>> res = crossing_frequencies(A, B)
    >>> round(float(res.omegas[0]) ** 2, 10), int(res.slopes[0])
    (3.0, 1)
    """
    for name, P in (("A", A), ("B", B)):
        if not isinstance(P, QuasiPolynomial):
            raise ParameterError(name, "a QuasiPolynomial", type(P).__name__)
    max_evals = positive_int("max_evals", max_evals)
    return crossing_search(A, B, required_frequency_bound(A, B), max_evals)[0]


def crossing_search(
    A: QuasiPolynomial, B: QuasiPolynomial, w_bound: tuple[float, float], max_evals: int, spare: int = 0
) -> tuple[CrossingSearch, AxisGap]:
    """The search, and the evaluator of ``|A|^2 - |B|^2`` it used (for :func:`axis_crossings`);
    ``spare``: see :func:`~nrobust.margins.search.first_stage`."""
    W, gap = w_bound
    h = AxisFunction(A, B, max_evals, AxisKernels((A, B)))
    tau = max(A.max_delay, B.max_delay, 1.0 / max(W, 1.0))
    step = np.pi / (8.0 * tau)
    lipschitz = AxisLipschitz(A, B, h.kernels)
    hi = W * (1.0 + _EXTEND_REL) + _EXTEND_ABS
    lo = 0.0 if (A.is_real and B.is_real) else -hi
    clusters = first_stage(h, lo, hi, lipschitz, step, spare)
    axis_gap = AxisGap(A, B, kernels=h.kernels)
    roots, tangential, slopes = resolve(axis_gap, h, *clusters)
    keep = sorted((w, k) for k, w in enumerate(roots) if abs(w) > ZERO_TOL * max(1.0, W))
    search = CrossingSearch(
        np.array([w for w, _ in keep], dtype=float),
        np.array([tangential[k] for _, k in keep], dtype=bool),
        float(W),
        float(gap),
        h.evals,
        np.array([slopes[k] for _, k in keep], dtype=np.int64),
    )
    return search, axis_gap


def common_axis_zeros(axis_gap: AxisGap, search: CrossingSearch) -> NDArray[np.float64]:
    """Crossing frequencies where ``A`` and ``B`` vanish together (``F(i w; delta) = 0`` for every delta).

    At a common zero ``|A|^2 - |B|^2`` has a double zero, found as a tangency located to
    rounding; there ``|A(i w)|`` is below ``1e-9`` of the sum of the moduli of its terms.
    """
    w = search.omegas
    if not w.size:
        return w
    a = axis_gap.factor_jets(1j * w)[0, 0]
    return w[np.abs(a) <= 1e-9 * axis_gap.scales[0](w)]


def _default_range(base: NDArray[np.float64], period: NDArray[np.float64]) -> float:
    """The default ``delta_max``: one full period past every first delay ``base``, or less.

    A crossing of tiny frequency has a long period, and a loop may have thousands of
    crossings of short period (a strongly coupled output feedback): the range ends where
    the delays ``base_k + j period_k`` up to it, counted by ``sum_k ((t - base_k) / period_k + 1)``
    over ``base_k <= t`` (at least their number), reach ``_MAX_EVENTS`` (each crossing keeps
    its first delay, which the margin needs).
    """
    full = float(np.max(base + period))

    def count(t: float) -> float:
        ahead = base <= t
        return float(np.sum((t - base[ahead]) / period[ahead] + 1.0))

    if count(full) <= _MAX_EVENTS:
        return full
    lo, hi = float(np.min(base)), full  # count(lo) is the number of first delays at lo: below the bound
    for _ in range(64):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if count(mid) <= _MAX_EVENTS else (lo, mid)
    return lo


def axis_crossings(
    A: QuasiPolynomial,
    B: QuasiPolynomial,
    search: CrossingSearch,
    delta_max: float | None,
    axis_gap: AxisGap | None = None,
) -> tuple[tuple[Crossing, ...], float]:
    """Delay sequences and directions at every crossing frequency; returns ``delta_max`` too.

    ``delta_max = None`` selects one full period past the first delay of every crossing,
    ``max_c (delta_{c,0} + 2 pi / |w_c|)`` (``inf`` without crossings), or less where the crossings
    would enumerate more than ``_MAX_EVENTS`` delays together (:func:`_default_range`). The direction is
    ``slope * sign(w)`` with the certified slope of the search (0 at a tangency).
    """
    w = search.omegas
    if not w.size:
        return (), float("inf") if delta_max is None else delta_max
    s = 1j * w
    if axis_gap is None:
        a, b, da, db = A(s), B(s), A.deriv_at(s), B.deriv_at(s)
    else:
        jets = axis_gap.factor_jets(s)
        a, b, da, db = jets[0, 0], jets[1, 0], jets[0, 1], jets[1, 1]
    period = 2.0 * np.pi / np.abs(w)
    base = np.mod(np.angle(-b / a) / w, period)
    base[(base > period * (1 - ZERO_TOL)) | (base < period * ZERO_TOL)] = 0.0
    if delta_max is None:
        delta_max = _default_range(base, period)
    elif not np.isfinite(delta_max):
        raise ParameterError(
            "delta_max", "finite: the loop has crossing frequencies, hence infinitely many crossing delays", delta_max
        )
    e = np.exp(-s * base)
    ds = s * b * e / (da + db * e - base * b * e)
    out = []
    for k in range(w.size):
        count = 1 if delta_max < base[k] else int(np.floor((delta_max - base[k]) / period[k] * (1 + 1e-12))) + 1
        if count > _MAX_EVENTS:
            raise ParameterError(
                "delta_max", f"small enough that at most {_MAX_EVENTS} crossing delays are enumerated", delta_max
            )
        tangential = bool(search.tangential[k])
        direction = 0 if tangential else int(search.slopes[k]) * (1 if w[k] > 0 else -1)
        delays = tuple(float(base[k] + j * period[k]) for j in range(count))
        out.append(Crossing(float(w[k]), delays, direction, complex(ds[k]), tangential))
    # rounding may put the last delay an ulp above delta_max: delta_max covers it
    within = [d for c in out for d in c.delays if d <= delta_max * (1 + 1e-12)]
    delta_max = max([float(delta_max), *within])
    return tuple(sorted(out, key=lambda c: (c.delays[0], c.omega))), float(delta_max)
