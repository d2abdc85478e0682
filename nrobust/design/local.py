"""Several parameters: a local nonsmooth optimisation of a loop's decay rate or delay margin.

The loop is a family ``F(s; delta, p) = A(s; p) + B(s; p) e^{-delta s}`` of quasi-polynomials
in the parameters ``p`` (a filter's gain, zero and pole, the gains of a state feedback, ...).
Two objectives:

* ``"decay_rate"``: maximise ``-alpha(p)``, ``alpha`` the spectral abscissa of ``F(.; 0, p)``
  (:func:`nrobust.roots.spectral_abscissa`), optionally subject to a delay margin
  ``delta*(p) >= d`` (:func:`nrobust.margins.delay_margin`): stability for every delay in
  ``[0, d]``;
* ``"margin"``: maximise ``delta*(p)``.

Windows of delays ``[d_min, d_max]`` may be required too (``delays``: one window or several,
stable for every delay of each, :func:`nrobust.design.window_stability`; ``d_min > 0`` allows a
loop unstable at ``delta = 0``), with or without a margin, of the loop and of further loops of the
same parameters (``scenarios``: the loop on plants with mismatched data, held to every requirement
of the loop). The requirement is then stability on a union of closed intervals of delays: the
windows and the margin's ``[0, d]``, merged where they meet, ``[l_1, h_1] < ... < [l_m, h_m]``.
The zeros in ``Re s > 0`` change in number only at the crossing delays ``tau_k(w) = (theta(w) + 2 pi
k)/w``, so an interval is met iff it lies inside one of the loop's stability windows ``(l, h)``
(:attr:`DelayMargin.intervals`: no crossing delay in ``[l_j, h_j]``, no zero in ``Re s > 0``
between). Its violation measure is the *window clearance* ``c_j(p) = max_(l, h) min(l_j - l, h -
h_j)`` over the stability windows (``l_j - l`` taken as ``+inf`` for a window ``[0, h)`` holding the
nominal loop, or ``(0, h)`` when ``l_j > 0``; with ``l_j = 0`` only the window ``[0, h)`` of a stable
nominal loop counts), minimised over the intervals and the loops: the requirement is ``c(p) > 0``,
and ``h_m + c(p)`` (the *window margin*) is ``delta*(p)`` for the one interval ``[0, h_1]``, so the
margin requirement ``delta* > d`` is the window ``[0, d]``. ``c`` is differentiable where one end
``tau`` binds, with the gradient of that crossing delay (below), and a start that misses the
requirement first maximises ``c`` up to 0, as a start below a required margin maximises the margin.
``c = -inf`` where a loop has no stability window up to ``2 h_m + 1`` that can hold an interval
(with ``l_1 = 0``: no window ``[0, h)``, the loop unstable at ``delta = 0``): from such a start a
phase before the first minimises the largest spectral abscissa of the loops at the starts ``l_j``
of the intervals (``A + B e^{-l_j s}``; ``A + B`` at ``l_1 = 0``) until it is negative: every
feasible point is stable there. The margin objective also requires the loop stable at ``delta =
0`` (the margin is the end of its window ``[0, h)``): with ``l_1 > 0`` a start unstable there goes
through the same phase with the loop's ``A + B`` among the abscissae lowered, and the first phase
keeps it stable at ``delta = 0``. Each loop is then stable at each ``l_j``, which a stability window
holds (``gamma_0 <= gamma_max < 1`` keeps the difference operator strongly stable, so for a neutral
loop too a negative abscissa at one delay opens a window of delays), and the first phase continues
from there.

With ``worst_case`` the decay rate is the least of the loop's and the scenarios' (the largest of
their abscissae at ``delta = 0`` is minimised, e.g. the guaranteed rate under a tolerance on the
plant's data), nonsmooth where two are equal: the gradient is the largest one's, and at a near-tie
the pattern search also tries minus the least-norm point of the convex hull of the gradients of
every abscissa within :data:`NEAR_TIE` of the largest, the steepest descent of the maximum along the
tie's ridge.

Both functions are nonsmooth: the abscissa where two roots (or a root and a chain of a
neutral loop) share the rightmost real part, the margin where two crossing branches meet
(and it jumps where a crossing pair is born). They are differentiable almost everywhere, with
gradients from the sensitivity of what is active:

* the rightmost root ``s*`` (simple): ``d alpha/dp = Re(-F_p(s*) / F'(s*))``;
* a chain of the difference operator ``D`` of a neutral loop (the abscissa approached as
  ``|Im s| -> infinity``): the derivative of its spectral bound ``c_D(p)`` (the roots of a
  polynomial in ``z = e^{-h s}``), by central differences;
* the critical crossing ``(w*, delta*)`` of the margin (any crossing delay ``tau`` of a window
  end alike, on its own branch): with ``g(w, p) = |A(iw)|^2 - |B(iw)|^2``
  and ``w delta = -arg(-A(iw)/B(iw)) + 2 pi k`` on the branch ``k`` of ``delta*``,
  ``dw/dp = -g_p/g_w`` and ``d delta/dp = -(theta_p + theta_w dw/dp + delta dw/dp)/w``.

The optimiser is BFGS with the weak Wolfe line search of Lewis and Overton ("Nonsmooth
optimization via quasi-Newton methods", Math. Program. 141, 2013), which converges on such
functions in practice; it stops when the smallest convex combination of the gradients
sampled near the last iterate (the gradient-sampling stationarity measure of Burke, Lewis and
Overton, SIAM J. Optim. 15, 2005) is small. Every trial point's feasibility is checked (inside
the bounds, margin ``>= d``): an infeasible point counts as ``+inf`` for the line search, so
every iterate is feasible. Most trial points are rejected, and a bound settles most of those
before any spectral abscissa or crossing search (:class:`_Problem`): ``gamma_0`` in closed
form, the chains of the principal part (the abscissa is at least their ``c_D``), a zero
continued by Newton's method from the rightmost roots of earlier points and proven by a
certified count, a crossing continued from the crossing frequencies of earlier points (its
delay bounds the margin from above). Where BFGS stalls (at a kink, or at a corner of the feasible set
where a crossing pair is born), a pattern search over the coordinate axes, their pairwise
diagonals and the descent direction continues with shrinking steps (and growing ones along a
direction that keeps improving). A start that is not
feasible first maximises the margin until it reaches ``d`` (under windows, the window margin
until it reaches ``h_m``, after the phase that makes a window exist when it has none). The optimum is local; several
starts (a Halton sequence in the bounds, run through any ``map``, e.g.
:func:`nrobust.sweep_map` for processes or Dask) make a better one likely, not certain. The
design found is then certified: its abscissa (certified count of the roots right of it), its
delay margin (``rigorous=True``: proven in ball arithmetic) and, with windows, each window of
each loop, and each scenario's ``[0, d]`` under a margin (:func:`nrobust.design.window_stability`,
whose delay margin is verified, or proven).

The optimiser itself (:func:`local_runs`) takes any :class:`LocalProblem`: a function of the
parameters returning :class:`TrialPoint` s (value, gradient, feasibility), so a loop that is not
``A + B e^{-delta s}`` (the determinant of an ``n + m`` system with ``m`` actuators,
:mod:`nrobust.hyperbolic.nplusm.design`) is optimised by the same searches.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._digits import with_accuracy
from .._json import json_safe
from .._newton import newton
from .._threads import one_blas_thread
from .._validate import callables, finite_real, is_real_number, nonnegative, positive_int
from ..errors import CertificationError, ParameterError
from ..margins import Crossing, DelayMargin, delay_margin, frequency_bound
from ..margins.crossing import axis_crossings, common_axis_zeros, crossing_search
from ..quasipoly import QuasiPolynomial
from ..roots import SpectralAbscissa, count_roots, spectral_abscissa
from .gain import DelayWindow, check_delays, window_requirement, window_stability

__all__ = [
    "GAMMA_MAX",
    "OBJECTIVES",
    "LocalProblem",
    "LoopDesign",
    "LocalRun",
    "ParametricLoop",
    "TrialPoint",
    "check_objective",
    "check_windows",
    "delayed_gamma",
    "local_runs",
    "optimize_loop",
]

#: A family of loops: parameters ``p`` (a 1-D array) to the factors ``(A, B)``.
ParametricLoop = Callable[[NDArray[np.float64]], tuple[QuasiPolynomial, QuasiPolynomial]]

#: The objectives: the decay rate ``-alpha`` at ``delta = 0``, or the delay margin.
OBJECTIVES = ("decay_rate", "margin")

#: Wolfe constants of the line search (Lewis and Overton, 2013).
ARMIJO = 1e-4
WOLFE = 0.5
#: Default bound on ``gamma_0`` of the delayed loop's difference operator (:func:`delayed_gamma`): every gain
#: of U_BS2(K) within 0.99 of the bound of eq. (54) meets it on the paper's plant.
GAMMA_MAX = 0.999
#: First and last steps of the pattern search that polishes each start, relative to the bounds.
POLISH_START = 1e-2
POLISH_TOL = 1e-5
#: Trial points of one line search: the step shrinks to about 2^-15 of the first before the search gives up
#: (near a loop whose difference operator approaches instability each trial can take seconds).
LINE_SEARCH_TRIALS = 16
#: Gradients kept for the stationarity measure.
SAMPLED_GRADIENTS = 8
#: Witnesses kept by each process, the newest: rightmost roots of earlier trial points (continued by
#: Newton's method to a new point, a located root bounds its abscissa from below) and crossing
#: frequencies with short delays (a crossing found near one bounds the new point's margin from above).
WITNESSES = 32
#: A crossing near a witness frequency ``w0`` is sought on ``w0 (1 +- WITNESS_WINDOW)``, sampled at
#: ``WITNESS_SAMPLES`` points (a sign change of ``|A|^2 - |B|^2`` above its rounding level).
WITNESS_WINDOW = 0.02
WITNESS_SAMPLES = 41
#: Newton seeds on the rightmost chain of the principal part: its zeros with ``0 <= Im s <= CHAIN_SEEDS``
#: spacings (the low-frequency zeros of a neutral loop leave their chain first).
CHAIN_SEEDS = 24
#: A test of ``delta* >= d`` first searches the crossings of ``|w| <= LOW_BAND 2 pi / d`` (every crossing
#: above ``2 pi / d`` has a delay below ``d``, so most violations are found there), then up to the
#: frequency bound ``W``; the first stage only when ``W`` exceeds ``LOW_BAND_FROM`` times its band (near
#: ``gamma_0 = 1``, where ``W`` grows like ``1/(1 - gamma_0)``: on the paper's plant with ``d = 0.2`` the
#: low band takes 0.3 s and the whole search 0.4 s at ``W = 609``, 5.3 s at ``W = 9139``).
LOW_BAND = 2.0
LOW_BAND_FROM = 16.0
#: Work bound of each crossing search (that of :func:`nrobust.margins.delay_margin`).
MAX_EVALS = 2_000_000
#: The reason of a trial point whose margin is below the requirement (it starts the first phase).
BELOW_REQUIREMENT = "delay margin below the requirement"
#: The reason of a trial point whose abscissa, computed, is above the line that rejects it.
ABOVE_LINE = "above the line search's line"
#: The reason of a first-phase point without a stability window that can hold the required window (it starts
#: the phase before: the largest abscissa at the windows' ``delta = d_min`` lowered below 0).
NO_WINDOW = "no stability window"
#: Functions of a maximum (the worst-case abscissa) within this much of it, relative to ``1 + |max|``, are active
#: together: their gradients' convex hull gives the pattern search a descent direction along a tie's ridge.
NEAR_TIE = 1e-3
#: The phase before the first stops once the largest abscissa at the ``d_min`` is below ``-STABLE_BY`` times its
#: value at the start (any negative value makes a stability window exist; a little more keeps it from the edge).
STABLE_BY = 1e-2


def _box(bounds: ArrayLike) -> NDArray[np.float64]:
    b = np.asarray(bounds, dtype=float)
    if b.ndim != 2 or b.shape[1] != 2 or b.shape[0] == 0 or not np.all(np.isfinite(b)) or np.any(b[:, 0] >= b[:, 1]):
        raise ParameterError(
            "bounds", "a sequence of finite (low, high) pairs with low < high, one per parameter", bounds
        )
    return b


#: Windows of delays ``((d_min, d_max), ...)``.
_Windows = tuple[tuple[float, float], ...]


def check_windows(delays: Any, name: str = "delays") -> _Windows:
    """``delays`` (None, one window ``(d_min, d_max)`` or a sequence of them) as a tuple of checked windows.

    Each window as :func:`nrobust.design.check_delays` checks it (``0 <= d_min <= d_max``,
    ``d_max > 0``; ``d_min = d_max``: one delay); the empty tuple for None. A
    :class:`ParameterError` naming ``name`` (or ``name[j]`` for the ``j``-th window) otherwise.
    """
    if delays is None:
        return ()
    what = "a window (d_min, d_max) with 0 <= d_min <= d_max, d_max > 0, or a sequence of such windows"
    if isinstance(delays, (str, bytes)):
        raise ParameterError(name, what, delays)
    try:
        items = list(delays)
    except TypeError:
        raise ParameterError(name, what, delays) from None
    if not items:
        raise ParameterError(name, what, delays)
    if all(is_real_number(x) for x in items):
        return (check_delays(items, name),)
    return tuple(check_delays(w, f"{name}[{n}]") for n, w in enumerate(items))


def _merged(windows: _Windows, margin_at_least: float | None = None) -> _Windows:
    """The windows and ``[0, margin_at_least]`` (when given and ``> 0``) merged into disjoint closed intervals.

    Stability on every window is stability on their union; intervals that meet (an end of one in
    the other) are one interval. Ascending.
    """
    pieces = sorted([*windows, *([(0.0, margin_at_least)] if margin_at_least else [])])
    merged: list[tuple[float, float]] = []
    for lo, hi in pieces:
        if merged and lo <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], hi))
        else:
            merged.append((lo, hi))
    return tuple(merged)


@dataclass(frozen=True)
class _Checked:
    """A loop family ``p -> (A, B)`` whose every value is checked to be a pair of QuasiPolynomials
    (a ``ParameterError`` naming ``name`` at the first call that returns anything else; picklable)."""

    family: ParametricLoop
    name: str

    def __post_init__(self) -> None:
        """A ``ParameterError`` naming ``name`` when the family cannot be called with one argument ``p``."""
        try:
            signature = inspect.signature(self.family)
        except (TypeError, ValueError):  # no signature to read (some builtins): the first call decides
            return
        try:
            signature.bind(np.zeros(1))
        except TypeError:
            raise ParameterError(
                self.name,
                "a callable p -> (A, B) of one argument (the parameters); its signature is "
                f"({', '.join(signature.parameters)})",
            ) from None

    def __call__(self, p: NDArray[np.float64]) -> tuple[QuasiPolynomial, QuasiPolynomial]:
        value = self.family(p)
        pair = isinstance(value, (tuple, list)) and len(value) == 2
        if not (pair and all(isinstance(f, QuasiPolynomial) for f in value)):
            got = type(value).__name__
            if isinstance(value, (tuple, list)):
                got += " of " + (", ".join(type(f).__name__ for f in value) or "nothing")
            raise ParameterError(
                self.name, f"a callable p -> (A, B) returning a pair of QuasiPolynomials; it returned a {got}"
            )
        return value[0], value[1]


def delayed_gamma(A: QuasiPolynomial, B: QuasiPolynomial) -> float:
    """``gamma_0`` of the difference operator of ``A + B e^{-delta s}`` for a generic ``delta > 0``.

    ``(sum_{k>=1} |a_k| + sum_k |b_k|) / |a_0|`` over the coefficients of the highest power of
    ``s`` (``a_0`` that of delay 0): the delayed loop is strongly stable (robust to small
    changes of its delays, Hale and Verduyn Lunel) for every such ``delta`` iff this is below
    1. ``inf`` for an advanced loop (``B`` of higher degree, or ``A`` without an undelayed
    leading term); 0 for a retarded loop.
    """
    n = A.degree
    if B.degree > n:
        return math.inf
    a = A.leading_terms(n)
    b = B.leading_terms(n) if B.degree == n else []
    a0 = sum(abs(c) for c, t in a if t == 0.0)
    rest = sum(abs(c) for c, t in a if t != 0.0) + sum(abs(c) for c, _ in b)
    if a0 == 0.0:
        return math.inf
    return float(rest / a0)


@dataclass(frozen=True)
class TrialPoint:
    """One evaluated parameter vector: what a :class:`LocalProblem` returns to the optimiser.

    ``value`` is the function minimised (``alpha``, or ``-delta*``), ``gradient`` its gradient
    (zeros where none is needed: an infeasible or rejected point), ``abscissa`` and ``margin``
    what was computed of them (``nan`` otherwise), ``reason`` why a point is infeasible or
    rejected. ``screened`` points were rejected by a bound without their value: ``value`` is
    then a lower bound of the function minimised (above the line that rejected them), and they
    are never feasible, so they can never become an iterate. ``active`` (a point of a maximum of
    several functions, e.g. the worst-case abscissa) holds the gradients of every function within
    :data:`NEAR_TIE` of the maximum when there are two or more (the pattern search then tries the
    steepest descent of their convex hull, which a tie's ridge needs); None otherwise.
    """

    p: NDArray[np.float64]
    feasible: bool
    value: float  # the function minimised: alpha, or -delta*
    gradient: NDArray[np.float64]
    abscissa: float
    margin: float
    reason: str = ""
    screened: bool = False
    active: NDArray[np.float64] | None = None


class LocalProblem(Protocol):
    """What :func:`local_runs` optimises: a function of the parameters with its feasibility.

    ``problem(p)`` evaluates the objective at ``p`` (``want="margin"``: ``-delta*`` whatever the
    objective, for the first phase of a start below the required margin; under windows of
    delays, minus the window margin, which the first phase raises to ``h_m``, the end of the last; a
    problem whose ``want="margin"`` point can be infeasible with a reason starting with :data:`NO_WINDOW`
    takes ``want="abscissa"`` too: the largest spectral abscissa of its loops at the delays a feasible
    point must be stable at, the start of each window (and, for :func:`optimize_loop`'s margin
    objective, the loop's at ``delta = 0``), which the phase before the first lowers below 0); ``above`` is the line
    a trial point must stay under (the line search's sufficient decrease, or the incumbent of the
    pattern search), so a point found above it may be returned early, without its gradient. A
    point outside ``bounds``, below ``margin_at_least`` (its ``reason`` starting with
    :data:`BELOW_REQUIREMENT`) or not certified must be returned infeasible: the optimiser
    never moves to an infeasible point. ``screened`` counts the evaluations settled by a bound
    so far (reported per start by :class:`LocalRun`). The loop families ``p -> (A, B)`` of
    :func:`optimize_loop` are one such problem; a PDE whose loop is not ``A + B e^{-delta s}``
    (:mod:`nrobust.hyperbolic.nplusm.design`) brings its own. Picklable if ``map`` runs processes.
    """

    @property
    def bounds(self) -> NDArray[np.float64]:
        """One ``(low, high)`` row per parameter."""

    @property
    def margin_at_least(self) -> float | None:
        """The level the first phase raises ``problem(p, want="margin")`` to: the required delay margin
        (under windows of delays the end of the last), or None."""

    @property
    def screened(self) -> int:
        """Evaluations settled by a bound so far (in this process)."""

    def __call__(self, p: ArrayLike, want: str | None = None, above: float = math.inf) -> TrialPoint:
        """The evaluation at ``p``."""


@dataclass(eq=False)
class _Memo:
    """What one process learned about the loop family (each process of ``map`` keeps its own).

    ``points`` maps ``(p, objective)`` to complete evaluations, ``floors`` to lower bounds of
    the function minimised at points rejected early, ``abscissae`` ``p`` to its spectral
    abscissa; ``roots`` and ``omegas`` are the witnesses (:data:`WITNESSES`, the crossings of the
    scenarios' loops among them); ``screened`` counts the evaluations settled by a bound (the
    gamma of the delayed loop, the chains, a witness) and ``full`` those that ran a spectral
    abscissa or a crossing search; ``binding`` is the scenario that last missed the windows
    (checked first); ``worst`` the scenario with the largest abscissa at the last point of a worst-case
    decay rate (computed first).
    """

    points: dict[tuple[bytes, str], TrialPoint] = field(default_factory=dict)
    floors: dict[tuple[bytes, str], float] = field(default_factory=dict)
    abscissae: dict[bytes, SpectralAbscissa] = field(default_factory=dict)
    roots: list[complex] = field(default_factory=list)
    omegas: list[float] = field(default_factory=list)
    screened: int = 0
    full: int = 0
    binding: int = 0
    worst: int = 0

    def add_root(self, s: complex | None) -> None:
        """Keep ``s`` (a rightmost root) as the newest witness, in place of those within ``1e-3 (1 + |s|)``."""
        if s is None or not np.isfinite(s):
            return
        s = complex(s.real, abs(s.imag))
        self.roots = [s, *(r for r in self.roots if abs(s - r) > 1e-3 * (1.0 + abs(s)))][:WITNESSES]

    def add_crossings(self, crossings: Sequence[Crossing], below: float) -> None:
        """Keep the frequencies of the crossings whose first delay is below ``below`` as the newest
        witnesses, each in place of those within a quarter of the window (:data:`WITNESS_WINDOW`)."""
        for c in crossings:
            w = abs(float(c.omega))
            if c.delays[0] < below:
                near = 0.25 * WITNESS_WINDOW * w
                self.omegas = [w, *(v for v in self.omegas if abs(w - v) > near)][:WITNESSES]


def _newton_roots(F: QuasiPolynomial, seeds: NDArray[np.complex128], max_step: float) -> NDArray[np.complex128]:
    """The zeros of ``F`` Newton's method reaches from ``seeds`` (nan where it does not converge)."""

    def fdf(x: NDArray[np.complex128]) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        return F(x), F.deriv_at(x)

    return newton(fdf, seeds, max_step=max_step, iters=30)


def _proven_root_right_of(F: QuasiPolynomial, s: complex, level: float) -> float | None:
    """The left edge of a box right of ``level`` that a certified count proves holds a zero of ``F``
    (about ``s``, a zero located in floating point), or None."""
    h = min(1e-6 * (1.0 + abs(s)), 0.5 * (s.real - level))
    if not h > 0.0:
        return None
    try:
        count = count_roots(F, (s.real - h, s.real + h, s.imag - h, s.imag + h))
    except (CertificationError, ParameterError):
        return None
    return count.region[0] if int(count) >= 1 and count.region[0] > level else None


def _window_grid(omegas: NDArray[np.float64]) -> NDArray[np.float64]:
    """Samples of the windows ``w0 (1 +- WITNESS_WINDOW)`` about the witnesses, overlapping windows merged."""
    if not omegas.size:
        return omegas
    lo, hi = np.sort(omegas) * (1.0 - WITNESS_WINDOW), np.sort(omegas) * (1.0 + WITNESS_WINDOW)
    pieces = []
    start, end = lo[0], hi[0]
    for a, b in zip(lo[1:], hi[1:]):
        if a > end:
            pieces.append((start, end))
            start = a
        end = max(end, b)
    pieces.append((start, end))
    spacing = 2.0 * WITNESS_WINDOW / (WITNESS_SAMPLES - 1)
    return np.concatenate([np.linspace(a, b, 1 + math.ceil((b - a) / (spacing * a))) for a, b in pieces])


def _crossing_near(A: QuasiPolynomial, B: QuasiPolynomial, omegas: Sequence[float], level: float) -> float:
    """A delay below ``level`` at which ``A + B e^{-delta s}`` has a zero ``i w`` with ``w`` near a
    witness frequency, or ``inf``.

    ``g(w) = |A(i w)|^2 - |B(i w)|^2`` is sampled on ``w0 (1 +- WITNESS_WINDOW)`` about each witness
    ``w0`` (and at the vertex of the parabola through each local minimum of the samples, where a
    pair of zeros may lie between two of them); a sign change with ``|g|`` above ``1e-9`` of its
    rounding scale at both ends brackets a
    zero ``w*`` of ``g``: ``|A| = |B|`` there, and ``e^{-i w* delta} = -A/B`` at ``delta(w*) =
    (arg(-B/A) mod 2 pi) / w*``, a delay at which the loop has a zero on the imaginary axis (its
    margin is at most that delay). The brackets whose ends give delays near or below ``level``
    are narrowed together (false position with the Illinois modification, every third step a
    bisection) to ``1e-8 w``; a delay is returned when it is below ``level`` by ``1e-9`` relative
    at both ends of its bracket (the phase kept ``1e-6`` from the branch cut of ``mod 2 pi``): on
    so short a bracket the delay ``delta(w)`` departs from the chord through its ends by
    ``|delta''| h^2 / 8``, about ``1e-14`` for the loops met here.
    """
    if not omegas or not level > 0.0:
        return math.inf
    w0 = np.abs(np.asarray(omegas, dtype=float))
    grid = _window_grid(w0[w0 > 0.0])
    if not grid.size:
        return math.inf

    def gap(w: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        s = 1j * w
        a, b = A(s), B(s)
        with np.errstate(divide="ignore", invalid="ignore"):
            delay = np.mod(np.angle(-b / a), 2.0 * np.pi)
        delay = np.where((delay > 1e-6) & (delay < 2.0 * np.pi - 1e-6), delay / w, np.inf)
        return np.abs(a) ** 2 - np.abs(b) ** 2, delay

    g, delay = gap(grid)
    # a pair of zeros about to be born (or just born) lies between two samples: the vertex of the
    # parabola through a local minimum and its neighbours is sampled too
    i = 1 + np.flatnonzero((g[1:-1] <= g[:-2]) & (g[1:-1] <= g[2:]))
    if i.size:
        x0, x1, x2, y0, y1, y2 = grid[i - 1], grid[i], grid[i + 1], g[i - 1], g[i], g[i + 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            num = (x1 - x0) ** 2 * (y1 - y2) - (x1 - x2) ** 2 * (y1 - y0)
            den = (x1 - x0) * (y1 - y2) - (x1 - x2) * (y1 - y0)
            vertex = x1 - 0.5 * num / den
        vertex = vertex[np.isfinite(vertex) & (vertex > x0) & (vertex < x2)]
        if vertex.size:
            g_v, delay_v = gap(vertex)
            order = np.argsort(np.concatenate([grid, vertex]))
            grid = np.concatenate([grid, vertex])[order]
            g, delay = np.concatenate([g, g_v])[order], np.concatenate([delay, delay_v])[order]
    s = 1j * grid
    noise = 1e-9 * (A.magnitude(s) ** 2 + B.magnitude(s) ** 2)
    sign = np.where(g > noise, 1, np.where(g < -noise, -1, 0))
    k = np.flatnonzero((sign[:-1] * sign[1:] < 0) & (np.minimum(delay[:-1], delay[1:]) < 1.05 * level))
    if not k.size:
        return math.inf
    lo, hi, g_lo, g_hi = grid[k], grid[k + 1], g[k], g[k + 1]
    for step in range(60):
        if np.all(hi - lo <= 1e-8 * hi):
            break
        w = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
        w = np.where((step % 3 == 2) | ~(w > lo) | ~(w < hi), 0.5 * (lo + hi), w)
        g_w, _ = gap(w)
        left = np.sign(g_w) == np.sign(g_lo)  # the zero lies right of w
        g_hi = np.where(left, 0.5 * g_hi, g_w)  # Illinois: halve the end that stays
        g_lo = np.where(left, g_w, 0.5 * g_lo)
        lo, hi = np.where(left, w, lo), np.where(left, hi, w)
    _, d_lo = gap(lo)
    _, d_hi = gap(hi)
    ok = (hi - lo <= 1e-8 * hi) & (np.maximum(d_lo, d_hi) < level * (1.0 - 1e-9))
    return float(np.min(np.maximum(d_lo, d_hi)[ok])) if np.any(ok) else math.inf


@dataclass(frozen=True)
class _Problem:
    """The function minimised, its gradient and its feasibility (picklable).

    The work of a trial point is ordered from cheap to costly, and stops as soon as the point
    is settled: the bounds and ``gamma_0`` (closed form), the memo, then bounds that reject it
    (a witness crossing below the required margin, the chains of the principal part or a
    witness root right of the line), then the spectral abscissa, then the margin. A rejection
    never needs a proof to keep the search sound (it only loses a candidate), but each is one
    all the same: a certified root count about the located root, a sign change of ``|A|^2 -
    |B|^2`` above its rounding level. An accepted point is certified as before: its abscissa
    by :func:`~nrobust.roots.spectral_abscissa`, its margin by the complete certified
    crossing search (:meth:`_meets`).

    ``margin_at_least`` is the required margin, or with ``windows`` the end ``h_m`` of the last (the
    level the first phase raises the window margin to); ``windows`` the required intervals of
    delays (disjoint, ascending: the windows and the margin's ``[0, d]`` merged, module notes), which
    every loop of ``scenarios`` must meet too (:meth:`_window_clearance`). ``worst_case``: the decay-rate
    objective minimises the largest abscissa at ``delta = 0`` of the loop and the scenarios
    (:meth:`_worst_abscissa`).
    """

    loop: ParametricLoop
    bounds: NDArray[np.float64]
    objective: str
    margin_at_least: float | None
    gamma_max: float = 1.0
    windows: _Windows = ()
    scenarios: tuple[ParametricLoop, ...] = ()
    worst_case: bool = False
    memo: _Memo = field(default_factory=_Memo, compare=False, repr=False)

    @property
    def screened(self) -> int:
        """Evaluations settled by a bound so far (:class:`LocalProblem`)."""
        return self.memo.screened

    def _step(self, p: NDArray[np.float64], i: int) -> float:
        return 1e-6 * max(1.0, abs(float(p[i])), float(self.bounds[i, 1] - self.bounds[i, 0]))

    def _pair(self, p: NDArray[np.float64], i: int) -> tuple[NDArray, NDArray, float]:
        """``p - h e_i``, ``p + h e_i`` and their distance (one-sided at a bound)."""
        h = self._step(p, i)
        lo, hi = p.copy(), p.copy()
        lo[i] = max(p[i] - h, self.bounds[i, 0])
        hi[i] = min(p[i] + h, self.bounds[i, 1])
        return lo, hi, float(hi[i] - lo[i])

    def _abscissa_gradient(
        self,
        p: NDArray[np.float64],
        F: QuasiPolynomial,
        sa: SpectralAbscissa,
        loop: ParametricLoop | None = None,
        delay: float = 0.0,
    ) -> NDArray:
        """The gradient of the abscissa ``sa`` of ``F = A + B e^{-delay s}``, ``(A, B) = loop(p)``."""
        family = self.loop if loop is None else loop

        def at(q: NDArray[np.float64]) -> QuasiPolynomial:
            a, b = family(q)
            return a + (b.shift(delay) if delay else b)

        grad = np.zeros(p.size)
        if sa.root is None or sa.approached_at_infinity:
            for i in range(p.size):  # the chain's abscissa c_D(p)
                lo, hi, h = self._pair(p, i)
                c = [at(q).principal_part().spectral_bound().value for q in (lo, hi)]
                grad[i] = (c[1] - c[0]) / h
            return grad
        s = np.array([sa.root])
        dF = complex(F.deriv_at(s)[0])
        for i in range(p.size):
            lo, hi, h = self._pair(p, i)
            if dF == 0.0:  # a multiple root (roots meeting): no sensitivity, a difference of the abscissae
                grad[i] = (spectral_abscissa(at(hi)).value - spectral_abscissa(at(lo)).value) / h
                continue
            f = [complex(at(q)(s)[0]) for q in (lo, hi)]
            grad[i] = (-(f[1] - f[0]) / h / dF).real
        return grad

    def _margin_gradient(
        self, p: NDArray[np.float64], A: QuasiPolynomial, B: QuasiPolynomial, dm: DelayMargin
    ) -> NDArray:
        if dm.omega is None or not math.isfinite(dm.margin) or dm.margin <= 0.0:
            return np.zeros(p.size)
        return self._delay_gradient(p, self.loop, A, B, float(dm.omega), dm.margin)

    def _delay_gradient(
        self, p: NDArray[np.float64], loop: ParametricLoop, A: QuasiPolynomial, B: QuasiPolynomial, w: float, tau: float
    ) -> NDArray:
        """The gradient of the crossing delay ``tau`` of the loop ``(A, B) = loop(p)`` at the frequency ``w``."""
        grad = np.zeros(p.size)
        s = np.array([1j * w])
        a, b = complex(A(s)[0]), complex(B(s)[0])
        da, db = 1j * complex(A.deriv_at(s)[0]), 1j * complex(B.deriv_at(s)[0])  # d/dw of A(iw), B(iw)
        g_w = 2.0 * (a.conjugate() * da).real - 2.0 * (b.conjugate() * db).real
        theta_w = (da / a - db / b).imag  # d/dw of arg(-A/B)
        for i in range(p.size):
            lo, hi, h = self._pair(p, i)
            vals = [(complex(x(s)[0]), complex(y(s)[0])) for x, y in (loop(lo), loop(hi))]
            g = [abs(x) ** 2 - abs(y) ** 2 for x, y in vals]
            th = [np.angle(-x / y) for x, y in vals]
            g_p = (g[1] - g[0]) / h
            theta_p = float(np.angle(np.exp(1j * (th[1] - th[0])))) / h
            w_p = -g_p / g_w if g_w != 0.0 else 0.0
            grad[i] = -(theta_p + theta_w * w_p + tau * w_p) / w
        return grad

    def __call__(self, p: ArrayLike, want: str | None = None, above: float = math.inf) -> TrialPoint:
        """Evaluate at ``p``; ``want="margin"`` minimises ``-delta*`` whatever the objective.

        A point whose value exceeds ``above`` (a line search's sufficient-decrease line, or the
        incumbent of the pattern search) is rejected whether feasible or not: it is returned as
        soon as that is known, with the abscissa (decay-rate objective) or a lower bound of the
        value (a screened point, never feasible), its margin not computed.

        A point where the abscissa or the margin cannot be certified within their work bounds
        (e.g. crossings accumulating as the difference operator nears instability) is treated
        as infeasible: the search stays where every iterate is certified.
        """
        p = np.asarray(p, dtype=float)
        if np.any(p < self.bounds[:, 0]) or np.any(p > self.bounds[:, 1]):
            return TrialPoint(p, False, math.inf, np.zeros(p.size), math.nan, math.nan, "outside the bounds")
        objective = "window" if want == "margin" and self.windows else want or self.objective
        key = (p.tobytes(), objective)
        memo = self.memo
        if key in memo.points:
            return memo.points[key]
        floor = memo.floors.get(key, -math.inf)
        if floor > above:
            memo.screened += 1
            return self._screened(p, floor, objective, "above the line (remembered bound)")
        try:
            point = self._evaluate(p, objective, above)
        except CertificationError as exc:
            point = TrialPoint(p, False, math.inf, np.zeros(p.size), math.nan, math.nan, f"not certified: {exc}")
        if point.screened or point.reason == ABOVE_LINE:
            memo.floors[key] = max(floor, point.value)
        else:
            memo.points[key] = point
        return point

    def _screened(self, p: NDArray[np.float64], floor: float, objective: str, why: str) -> TrialPoint:
        abscissa = floor if objective == "decay_rate" else math.nan
        margin = -floor if objective == "margin" else math.nan
        return TrialPoint(p, False, floor, np.zeros(p.size), abscissa, margin, why, screened=True)

    def _evaluate(self, p: NDArray[np.float64], objective: str, above: float) -> TrialPoint:
        A, B = self.loop(p)
        gammas = [delayed_gamma(A, B), *(delayed_gamma(*loop(p)) for loop in self.scenarios)]
        n = int(np.argmax(gammas))
        gamma = gammas[n]
        memo = self.memo
        if not gamma <= self.gamma_max:
            memo.screened += 1
            which = "the loop" if n == 0 else f"scenario {n - 1}"
            reason = f"gamma_0 = {gamma:.6g} of the delayed loop's difference operator above gamma_max for {which}"
            if math.isinf(gamma):
                reason += " (advanced: B of higher degree than A, or A without an undelayed leading term)"
            return TrialPoint(p, False, math.inf, np.zeros(p.size), math.nan, math.nan, reason)
        if objective == "window":
            return self._window_point(p, A, B)
        if objective == "abscissa":
            return self._abscissa_point(p, A, B, above)
        if objective == "margin":
            return self._margin_point(p, A, B, above)
        F = A + B
        pkey = p.tobytes()
        sa = memo.abscissae.get(pkey)
        if sa is None and math.isfinite(above):
            lower = F.principal_part().spectral_bound().lower  # the chains: alpha >= c_D
            if lower > above:
                memo.screened += 1
                return self._screened(p, float(lower), objective, f"above the line (chains at {lower:.6g})")
        d = self._from_zero  # a crossing delay below l_1 > 0 may leave the windows stable: no screening by witnesses
        delay = _crossing_near(A, B, memo.omegas, d) if d else math.inf
        if d and delay < d:
            memo.screened += 1
            reason = f"{BELOW_REQUIREMENT} (a crossing at delay {delay:.6g})"
            return TrialPoint(p, False, math.inf, np.zeros(p.size), math.nan, delay, reason, screened=True)
        if sa is None:
            floor, why = self._abscissa_floor(F, above)
            if floor > above:
                memo.screened += 1
                return self._screened(p, floor, objective, f"above the line ({why})")
            memo.full += 1
            sa = memo.abscissae[pkey] = spectral_abscissa(F)
            memo.add_root(sa.root)
        if sa.value > above:
            return TrialPoint(p, True, sa.value, np.zeros(p.size), sa.value, math.nan, ABOVE_LINE)
        worst: tuple[SpectralAbscissa, QuasiPolynomial, ParametricLoop | None] = (sa, F, None)
        if self.worst_case:  # before the requirement, which costs a crossing search of every loop
            found = self._worst_abscissa(p, above)
            if isinstance(found, TrialPoint):
                return found
            if found is not None and found[0].value > sa.value:
                worst = found
        margin = math.nan
        if self.windows:
            why = self._window_missed(p, A, B, sa)
            if why:
                return TrialPoint(p, False, math.inf, np.zeros(p.size), sa.value, margin, f"{BELOW_REQUIREMENT}: {why}")
        elif d:
            ok, margin = self._meets(A, B, sa, d)
            if not ok:
                return TrialPoint(p, False, math.inf, np.zeros(p.size), sa.value, margin, BELOW_REQUIREMENT)
        top, F_top, family = worst
        gradient = self._abscissa_gradient(p, F_top, top, family)
        active = None
        if self.worst_case:  # the loops near the largest abscissa: a tie's ridge needs all their gradients
            near = NEAR_TIE * (1.0 + abs(top.value))
            pieces = [(sa, F, None), *self._scenario_abscissae(p)]
            rows = [
                self._abscissa_gradient(p, F_j, sa_j, f_j) if F_j is not F_top else gradient
                for sa_j, F_j, f_j in pieces
                if sa_j.value >= top.value - near
            ]
            active = np.array(rows) if len(rows) > 1 else None
        return TrialPoint(p, True, top.value, gradient, top.value, margin, active=active)

    def _scenario_abscissae(
        self, p: NDArray[np.float64]
    ) -> list[tuple[SpectralAbscissa, QuasiPolynomial, ParametricLoop]]:
        """The scenarios' abscissae at ``delta = 0`` remembered at ``p`` (by :meth:`_worst_abscissa`), with
        their loops and families."""
        out = []
        for n, family in enumerate(self.scenarios):
            sa_n = self.memo.abscissae.get(self._scenario_key(p, n))
            if sa_n is not None:
                A_n, B_n = family(p)
                out.append((sa_n, A_n + B_n, family))
        return out

    @staticmethod
    def _scenario_key(p: NDArray[np.float64], n: int) -> bytes:
        return p.tobytes() + b"scenario" + n.to_bytes(4, "little")

    def _worst_abscissa(
        self, p: NDArray[np.float64], above: float
    ) -> TrialPoint | tuple[SpectralAbscissa, QuasiPolynomial, ParametricLoop] | None:
        """The largest spectral abscissa at ``delta = 0`` of the scenarios' loops ``A_j + B_j`` at ``p``, with
        that loop and its family (None without scenarios); or, as soon as one is found above ``above``, the
        point rejected there (screened by a bound of :meth:`_abscissa_floor`, or above the line: a lower bound
        of the largest). The scenario that was largest at the last point first (the worst-case objective,
        ``max(alpha_0, alpha_1, ...)``: its value is that of the largest, its gradient that one's; where two
        tie it is not differentiable, and the stationarity measure samples both gradients nearby).
        """
        memo = self.memo
        order = sorted(range(len(self.scenarios)), key=lambda n: n != memo.worst)
        worst: tuple[SpectralAbscissa, QuasiPolynomial, ParametricLoop] | None = None
        for n in order:
            family = self.scenarios[n]
            A_n, B_n = family(p)
            F_n = A_n + B_n
            key = self._scenario_key(p, n)
            sa_n = memo.abscissae.get(key)
            if sa_n is None:
                lower = F_n.principal_part().spectral_bound().lower
                if lower > above:
                    memo.screened += 1
                    return self._screened(p, float(lower), "decay_rate", f"above the line (scenario {n}'s chains)")
                floor, why = self._abscissa_floor(F_n, above)
                if floor > above:
                    memo.screened += 1
                    return self._screened(p, floor, "decay_rate", f"above the line (scenario {n}: {why})")
                memo.full += 1
                sa_n = memo.abscissae[key] = spectral_abscissa(F_n)
                memo.add_root(sa_n.root)
            if sa_n.value > above:
                memo.worst = n
                return TrialPoint(p, True, sa_n.value, np.zeros(p.size), sa_n.value, math.nan, ABOVE_LINE)
            if worst is None or sa_n.value > worst[0].value:
                worst = (sa_n, F_n, family)
                memo.worst = n
        return worst

    @property
    def _from_zero(self) -> float | None:
        """The delay up to which every loop must be stable from ``delta = 0``: the required margin, or with
        ``windows`` the end of the first interval when it starts at 0 (else None)."""
        if not self.windows:
            return self.margin_at_least
        lo, hi = self.windows[0]
        return hi if lo == 0.0 else None

    def _window_clearance(
        self, A: QuasiPolynomial, B: QuasiPolynomial, skip_first: bool = False
    ) -> tuple[float, tuple[float, float, int] | None, DelayMargin]:
        """``(c, end, dm)``: the window clearance of the loop (module notes) and the delay that binds it.

        ``c`` is the least clearance ``c_j`` over the intervals (over all but the first with
        ``skip_first``); ``dm`` is the delay margin with its stability windows up to ``2 h_m + 1`` (as
        :func:`nrobust.design.window_stability` takes them for the last interval), not verified; ``end``
        is ``(w, tau, side)`` for the crossing delay ``tau`` at the frequency ``w`` that binds (``side``
        -1 for a lower end, ``c = l_j - tau``; +1 for an upper, ``c = tau - h_j``), None when no crossing
        binds (an end at the horizon); ``c = -inf`` when an interval has no stability window that can hold
        it (or without strong stability, or with ``s = 0`` a root for every delay); for ``l_j = 0`` only
        the window ``[0, h)`` of a stable nominal loop counts (no other can ever hold the interval: no path
        of windows ``(l, h)``, ``l > 0``, leads to it but through a jump).
        """
        assert self.windows
        dm = delay_margin(A, B, delta_max=2.0 * self.windows[-1][1] + 1.0, verify=False)
        if not dm.strongly_stable or dm.zero_root:
            return -math.inf, None, dm
        worst, binding = math.inf, (0.0, 0)
        for d_lo, d_hi in self.windows[1:] if skip_first else self.windows:
            best, here = -math.inf, (0.0, 0)
            for lo, hi in dm.intervals:
                if d_lo == 0.0 and not (lo == 0.0 and dm.nominally_stable):
                    continue
                below = math.inf if lo == 0.0 else d_lo - lo
                c = min(below, hi - d_hi)
                if c > best:
                    best, here = c, ((lo, -1) if below <= hi - d_hi else (hi, 1))
            if best < worst:
                worst, binding = best, here
        if not math.isfinite(worst):
            return worst, None, dm
        tau, side = binding
        w = next((float(x.omega) for x in dm.crossings if tau in x.delays and x.omega), None)
        return worst, (None if w is None else (w, tau, side)), dm

    def _window_missed(
        self, p: NDArray[np.float64], A: QuasiPolynomial, B: QuasiPolynomial, sa: SpectralAbscissa
    ) -> str:
        """Why the loop (abscissa ``sa`` at ``delta = 0``) or a scenario is not stable on the intervals, or "".

        The loop on a first interval ``[0, h_1]`` by :meth:`_meets` (``delta* > h_1``), on the others by
        its window clearance; each scenario by its window clearance. In floating point: the design is
        certified afterwards (:func:`nrobust.design.window_stability`).
        """
        assert self.windows
        first = self._from_zero
        memo = self.memo
        if first is not None:
            ok, margin = self._meets(A, B, sa, first)
            if not (ok and margin > first):
                return f"the loop's delay margin {margin:.6g} is not above {first!r}"
        if (first is None or len(self.windows) > 1) and not self._window_clearance(A, B, first is not None)[0] > 0.0:
            return "the loop is not stable on the windows"
        for n in sorted(range(len(self.scenarios)), key=lambda n: n != memo.binding):
            A_n, B_n = self.scenarios[n](p)
            # a crossing delay below h_1 near a witness frequency settles it
            delay = _crossing_near(A_n, B_n, memo.omegas, first) if first is not None else math.inf
            if first is not None and delay < first:
                memo.screened += 1
                memo.binding = n
                return f"scenario {n} has a crossing at delay {delay:.6g}"
            c, _, dm = self._window_clearance(A_n, B_n)
            memo.add_crossings(dm.crossings, 1.5 * self.windows[-1][1])
            if not c > 0.0:
                memo.binding = n
                return f"scenario {n} is not stable on the windows"
        return ""

    def _window_point(self, p: NDArray[np.float64], A: QuasiPolynomial, B: QuasiPolynomial) -> TrialPoint:
        """Minus the window margin ``h_m + c(p)`` (the least clearance over the intervals, the loop and the
        scenarios), with its gradient.

        Feasible (for the first phase) where every loop has, for each interval, a stability window that
        can hold it (:meth:`_window_clearance`) and, under the margin objective, the loop is stable at
        ``delta = 0`` (its window ``[0, h)`` exists: the design must have it); infeasible with the reason
        :data:`NO_WINDOW` otherwise, which starts the phase before (:meth:`_abscissa_point`). The
        requirement is met where the value is below ``-h_m``.
        """
        assert self.windows
        self.memo.full += 1
        worst: tuple[float, tuple[float, float, int] | None, ParametricLoop, QuasiPolynomial, QuasiPolynomial] = (
            math.inf,
            None,
            self.loop,
            A,
            B,
        )
        which = ""
        for n, loop in enumerate((self.loop, *self.scenarios)):
            A_j, B_j = (A, B) if loop is self.loop else loop(p)
            c, end, dm = self._window_clearance(A_j, B_j)
            if n == 0 and self._nominal and not dm.nominally_stable:
                reason = f"{NO_WINDOW} [0, h) for the loop: not stable at delta = 0, as the margin objective requires"
                return TrialPoint(p, False, math.inf, np.zeros(p.size), math.nan, math.nan, reason)
            if c < worst[0]:
                worst = (c, end, loop, A_j, B_j)
                which = "the loop" if n == 0 else f"scenario {n - 1}"
        c, end, loop, A_j, B_j = worst
        if not math.isfinite(c):
            horizon = f"up to {2.0 * self.windows[-1][1] + 1.0:.6g}"
            if len(self.windows) > 1:
                held = f"{horizon} for each interval of {[list(w) for w in self.windows]}"
            else:
                held = "[0, h) of a stable nominal loop" if self.windows[0][0] == 0.0 else horizon
            reason = f"{NO_WINDOW} {held} for {which}"
            return TrialPoint(p, False, math.inf, np.zeros(p.size), math.nan, math.nan, reason)
        grad = np.zeros(p.size)
        if end is not None:
            w, tau, side = end
            grad = side * self._delay_gradient(p, loop, A_j, B_j, w, tau)
        value = self.windows[-1][1] + c
        return TrialPoint(p, True, -value, -grad, math.nan, value)

    @property
    def _nominal(self) -> bool:
        """True when the loop must be stable at ``delta = 0`` beyond the intervals: the margin objective with
        ``l_1 > 0`` (with ``l_1 = 0`` the first interval requires it anyway)."""
        return self.objective == "margin" and bool(self.windows) and self.windows[0][0] > 0.0

    def _abscissa_point(
        self, p: NDArray[np.float64], A: QuasiPolynomial, B: QuasiPolynomial, above: float
    ) -> TrialPoint:
        """The phase before the first: the largest spectral abscissa of ``A_j + B_j e^{-l_k s}`` over the
        loop and the scenarios and the starts ``l_k`` of the intervals, and under the margin objective with
        ``l_1 > 0`` of the loop's ``A + B`` too (at ``delta = 0``), with its gradient (the rightmost root's or
        chain's, module notes).

        Below 0 every loop is exponentially stable at each ``delta = l_k`` (at ``delta = 0`` when ``l_1 =
        0``): ``l_k`` lies in a stability window of each, whose ends the first phase then moves past the
        interval; under the margin objective the loop is stable at ``delta = 0`` as well (its window ``[0,
        h)`` exists), as every design of that objective must be. Each is a necessary condition of a feasible
        point. That window is not lost to the difference operator: ``gamma_0 <= gamma_max < 1``
        (checked before) makes it strongly stable, so no delay near ``l_k`` brings zeros from
        infinity. A point whose chains (a lower bound, :meth:`QuasiPolynomial.principal_part`) or
        abscissa lie above ``above`` is rejected as soon as that is known.
        """
        assert self.windows
        memo = self.memo
        worst: tuple[SpectralAbscissa, ParametricLoop, QuasiPolynomial, float] | None = None
        starts = [lo for lo, _ in self.windows]
        for loop in (self.loop, *self.scenarios):
            A_j, B_j = (A, B) if loop is self.loop else loop(p)
            for d in [0.0, *starts] if self._nominal and loop is self.loop else starts:
                F = A_j + (B_j.shift(d) if d else B_j)
                lower = F.principal_part().spectral_bound().lower
                if lower > above:
                    memo.screened += 1
                    return self._screened(p, float(lower), "abscissa", f"above the line (chains at {lower:.6g})")
                memo.full += 1
                sa = spectral_abscissa(F)
                if sa.value > above:
                    return TrialPoint(p, True, sa.value, np.zeros(p.size), sa.value, math.nan, ABOVE_LINE)
                if worst is None or sa.value > worst[0].value:
                    worst = (sa, loop, F, d)
        assert worst is not None
        sa, loop, F, d = worst
        return TrialPoint(p, True, sa.value, self._abscissa_gradient(p, F, sa, loop, d), sa.value, math.nan)

    def _abscissa_floor(self, F: QuasiPolynomial, above: float) -> tuple[float, str]:
        """A lower bound of the spectral abscissa of ``F`` above ``above``, or ``-inf``.

        The zeros Newton's method reaches from the witness roots and from the lowest zeros of
        the rightmost chain of the principal part, the rightmost of them proven by a certified
        count in a small box right of ``above`` (:func:`_proven_root_right_of`).
        """
        if not math.isfinite(above):
            return -math.inf, ""
        chains = F.principal_part().chains().chains
        spacing = chains[0].spacing if chains else 1.0
        seeds = [*self.memo.roots]
        if chains:
            seeds += list(chains[0].points(0.0, CHAIN_SEEDS * spacing))
            if not F.is_real:
                seeds += list(chains[0].points(-CHAIN_SEEDS * spacing, 0.0))
        if not seeds:
            return -math.inf, ""
        roots = _newton_roots(F, np.array(seeds, dtype=complex), 0.25 * spacing)
        roots = roots[np.isfinite(roots) & (roots.real > above)]
        for s in roots[np.argsort(-roots.real)][:2]:
            edge = _proven_root_right_of(F, complex(s), above)
            if edge is not None:
                self.memo.add_root(complex(s))
                return edge, f"a zero at {complex(s):.6g}"
        return -math.inf, ""

    def _meets(self, A: QuasiPolynomial, B: QuasiPolynomial, sa: SpectralAbscissa, d: float) -> tuple[bool, float]:
        """``(delta* >= d, delta*)`` for the loop whose abscissa at ``delta = 0`` is ``sa``.

        Stability for every delay in ``[0, d]``: the loop is stable at ``delta = 0`` (``sa``'s
        certified upper bound is negative), its delayed difference operator is strongly stable
        (a frequency bound exists: no zero of ``Re s >= 0`` comes from infinity) and no crossing
        has a delay below ``d`` (so no zero reaches the axis on ``[0, d)``: the steps of
        :func:`nrobust.margins.delay_margin` without its nominal count). The crossings are
        searched on ``|w| <= LOW_BAND 2 pi / d`` first, where most violations lie, then up to the
        frequency bound (the first stage only for a bound above ``LOW_BAND_FROM`` times that band,
        where it is cheap beside the whole search); the margin returned is exact when the requirement is met (the first
        crossing delay), an upper bound of it otherwise. Without a negative upper bound the
        exact margin decides (:func:`nrobust.margins.delay_margin`).
        """
        memo = self.memo
        memo.full += 1
        if not sa.upper_bound < 0.0:
            dm = delay_margin(A, B, verify=False)
            memo.add_crossings(dm.crossings, 1.5 * d)
            return dm.margin >= d, dm.margin
        w_bound = frequency_bound(A, B)
        if w_bound is None:
            return False, 0.0
        W, gap = w_bound
        low = LOW_BAND * 2.0 * math.pi / d
        first = math.inf
        for top in (min(low, W), W) if W > LOW_BAND_FROM * low else (W,):
            try:
                search, axis_gap = crossing_search(A, B, (top, gap), MAX_EVALS)
            except CertificationError:
                if top < W:
                    continue  # the full search decides
                raise
            if common_axis_zeros(axis_gap, search).size:
                return False, 0.0
            crossings, _ = axis_crossings(A, B, search, d, axis_gap)
            memo.add_crossings(crossings, 1.5 * d)
            first = min((c.delays[0] for c in crossings), default=math.inf)
            if first < d:
                return False, first
        return True, first

    def _margin_point(self, p: NDArray[np.float64], A: QuasiPolynomial, B: QuasiPolynomial, above: float) -> TrialPoint:
        """The margin objective: ``-delta*`` and its gradient, or a rejection below the line.

        Below a finite line (``delta* < -above`` rejects), a witness crossing and then the
        crossings of ``|w| <= LOW_BAND 2 pi / level`` may show a delay with a zero on the axis
        below the line (an upper bound of the margin) before the complete computation.
        """
        memo = self.memo
        level = -above
        if math.isfinite(level) and level > 0.0:
            delay = _crossing_near(A, B, memo.omegas, level)
            if delay < level:
                memo.screened += 1
                return self._screened(p, -delay, "margin", f"below the line (a crossing at delay {delay:.6g})")
            w_bound = frequency_bound(A, B)
            low = LOW_BAND * 2.0 * math.pi / level
            if w_bound is not None and w_bound[0] > LOW_BAND_FROM * low:
                memo.full += 1
                try:
                    search, axis_gap = crossing_search(A, B, (low, w_bound[1]), MAX_EVALS)
                    crossings, _ = axis_crossings(A, B, search, level, axis_gap)
                except CertificationError:
                    crossings = ()
                memo.add_crossings(crossings, 1.5 * level)
                first = min((c.delays[0] for c in crossings), default=math.inf)
                if first < level:
                    return self._screened(p, -first, "margin", f"below the line (a crossing at delay {first:.6g})")
        memo.full += 1
        c = math.inf
        if self.windows:
            c, _, dm = self._window_clearance(A, B)
        else:
            dm = delay_margin(A, B, verify=False)
        margin = dm.margin
        memo.add_crossings(dm.crossings, 1.5 * margin if math.isfinite(margin) else math.inf)
        if not dm.nominally_stable:
            # the margin objective requires it (and with l_1 = 0 the intervals too): under windows the phases
            # before the first make it so (:meth:`_window_point`, :meth:`_abscissa_point`)
            reason = "not stable at delta = 0"
            if self.windows:
                reason = f"{BELOW_REQUIREMENT}: {reason}"
            else:
                reason += " (give an x0 stable at delta = 0, or a window of delays: its phases stabilise a start)"
            return TrialPoint(p, False, math.inf, np.zeros(p.size), math.nan, margin, reason)
        if self.windows:
            bad = "" if c > 0.0 else "the loop"
            for n, loop in enumerate(self.scenarios):
                if not bad and not self._window_clearance(*loop(p))[0] > 0.0:
                    bad = f"scenario {n}"
            if bad:
                reason = f"{BELOW_REQUIREMENT}: {bad} is not stable on the windows"
                return TrialPoint(p, False, math.inf, np.zeros(p.size), math.nan, margin, reason)
        return TrialPoint(p, True, -margin, -self._margin_gradient(p, A, B, dm), math.nan, margin)


def _min_norm_convex(G: NDArray[np.float64]) -> float:
    """``min ||sum_j l_j g_j||`` over ``l >= 0``, ``sum l = 1`` (rows of ``G`` the gradients)."""
    return float(np.linalg.norm(_min_norm_point(G)))


def _min_norm_point(G: NDArray[np.float64]) -> NDArray[np.float64]:
    """The point ``sum_j l_j g_j`` of least norm of the convex hull of the rows of ``G`` (``l >= 0``, ``sum l =
    1``): minus it is the steepest descent direction of the maximum of functions with these gradients."""
    from scipy.optimize import nnls

    k = G.shape[0]
    if k == 1:
        return np.asarray(G[0], dtype=float)
    scale = max(1.0, float(np.abs(G).max())) * 1e3
    M = np.vstack([G.T, scale * np.ones((1, k))])
    rhs = np.concatenate([np.zeros(G.shape[1]), [scale]])
    lam, _ = nnls(M, rhs)
    lam = lam / lam.sum() if lam.sum() > 0 else np.full(k, 1.0 / k)
    return np.asarray(lam @ G, dtype=float)


@dataclass(frozen=True)
class LocalRun:
    """One start of the local optimisation.

    Attributes
    ----------
    start : tuple of float
        The starting parameters.
    parameters : tuple of float
        The last iterate (feasible), or the start when no feasible point was reached.
    value : float
        The objective there (decay rate or delay margin); ``nan`` when not feasible.
    feasible : bool
        True if ``parameters`` meets the bounds and the margin requirement.
    iterations, evaluations : int
        BFGS iterations and evaluations of the loop (line searches and the first phases
        included).
    stationarity : float
        The smallest convex combination of the gradients sampled at the last iterates
        (0 at a smooth stationary point; small at a nonsmooth local optimum).
    reason : str
        Why it stopped.
    screened : int
        Evaluations settled by a bound, without a spectral abscissa or a crossing search: the
        ``gamma_0`` of the delayed loop, the chains of the principal part, a root or a crossing
        continued from a witness of an earlier evaluation, a value remembered at the same point.
    path : tuple of tuple of float
        The iterates of the main phase, each feasible when accepted: the first feasible point, every
        step the line search accepted and every step of the pattern search that improved (empty when
        no feasible point was reached).
    """

    start: tuple[float, ...]
    parameters: tuple[float, ...]
    value: float
    feasible: bool
    iterations: int
    evaluations: int
    stationarity: float
    reason: str
    screened: int = 0
    path: tuple[tuple[float, ...], ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return json_safe(vars(self))


# A gradient whose change over the bounds' width exceeds this many times 1 + |value| marks a steep fall.
_STEEP = 1e6


def _stalled_search(
    x: TrialPoint,
    d: NDArray[np.float64],
    slope: float,
    lo: float,
    hi: float,
    steep: TrialPoint | None,
    last: str,
    width: float,
) -> str:
    """What stopped a line search from ``x`` along ``d`` (initial slope ``slope``) with no Wolfe step.

    ``lo`` is the longest step below Armijo's line (``steep`` its point, whose slope was still too steep),
    ``hi`` the shortest step too long (``last`` why: infeasible, or above Armijo's line), ``width`` the size of
    the bounds: a gradient whose change over it exceeds ``_STEEP`` times ``1 + |value|`` is a steep fall, not
    a kink.
    """
    singular = (
        "e.g. where the loop at delta = 0 tends to one term c e^{-h s}, which has no zero: finite-time "
        "convergence, an infinite decay rate"
    )
    if steep is not None:
        ratio = float(steep.gradient @ d) / slope
        at = f"p = {_vector_text(steep.p)} (the value {steep.value:.6g} against {x.value:.6g})"
        if ratio > 1.0:
            falls = (
                f"the objective falls ever more steeply along the search direction (its slope {ratio:.3g} times the "
                f"iterate's at {at})"
            )
        else:
            falls = f"the objective still falls at {at}, its slope {ratio:.3g} times the iterate's"
        if not math.isfinite(hi):
            return f"{falls}, over steps up to {lo:.3g} times the first: it may be unbounded that way"
        beyond = f"p = {_vector_text(x.p + hi * d)}"
        if last.startswith("infeasible"):
            past = f"may be unbounded past that edge ({singular})" if ratio > 1.0 else "is best at that edge"
            return (
                f"{falls}, and the longer step to {beyond} is {last}: along the search direction the objective "
                f"{past} (a bound or a requirement)"
            )
        if ratio > 1.0:
            return (
                f"{falls}, and the longer step to {beyond} rises above Armijo's line: no step between meets the "
                f"Wolfe conditions, the objective is unbounded or not Lipschitz between them ({singular})"
            )
        return (
            f"{falls}, and the longer step to {beyond} rises above Armijo's line: no step between meets the Wolfe "
            "conditions, a kink between them (the objective not smooth there)"
        )
    if last.startswith("infeasible"):
        return (
            f"every step down to {hi:.3g} times the first was too long, the shortest {last}: the iterate is at the "
            "edge of the feasible set along the search direction (a bound or a requirement)"
        )
    rises = f"every step down to {hi:.3g} times the first rose above Armijo's line"
    change = float(np.linalg.norm(x.gradient)) * width
    if change > _STEEP * (1.0 + abs(x.value)):
        return (
            f"{rises}, the gradient at the iterate {change / (1.0 + abs(x.value)):.3g} times (1 + |value|) per width "
            f"of the bounds: the objective falls steeply toward a point where it is unbounded or not Lipschitz, "
            f"and the steps overshoot it ({singular})"
        )
    return (
        f"{rises}: the objective is not smooth at the iterate (a kink: a nonsmooth local optimum, or where two "
        "rightmost roots meet)"
    )


def _vector_text(p: NDArray[np.float64]) -> str:
    return "[" + ", ".join(f"{float(v):.12g}" for v in np.ravel(p)) + "]"


@dataclass(frozen=True)
class _Local:
    """BFGS with the weak Wolfe line search from one start (picklable, for ``map``)."""

    problem: LocalProblem
    max_iter: int
    tol: float

    def _line_search(
        self, f: Callable[[NDArray, float], TrialPoint], x: TrialPoint, d: NDArray[np.float64], counter: list[int]
    ) -> tuple[TrialPoint | None, str]:
        """A step along ``d`` meeting the weak Wolfe conditions, or None and what stopped the search."""
        slope = float(x.gradient @ d)
        lo, hi, t = 0.0, math.inf, 1.0
        steep: TrialPoint | None = None  # the last step below Armijo's line, its slope too steep for Wolfe's
        last = ""  # why the last step too long was
        for _ in range(LINE_SEARCH_TRIALS):
            y = f(x.p + t * d, x.value + ARMIJO * t * slope)
            counter[0] += 1
            if not y.feasible or y.value > x.value + ARMIJO * t * slope:
                hi = t
                # a screened point lies above the line by a bound, without its value
                last = f"infeasible: {y.reason}" if not (y.feasible or y.screened) else "above Armijo's line"
            elif float(y.gradient @ d) < WOLFE * slope:
                lo, steep = t, y
            else:
                return y, ""
            t = 0.5 * (lo + hi) if math.isfinite(hi) else 2.0 * lo
            if math.isfinite(hi) and hi - lo < 1e-14 * max(1.0, hi):
                break
        width = self.problem.bounds[:, 1] - self.problem.bounds[:, 0]
        return None, _stalled_search(x, d, slope, lo, hi, steep, last, float(np.linalg.norm(width)))

    def minimise(
        self,
        f: Callable[[NDArray, float], TrialPoint],
        x: TrialPoint,
        counter: list[int],
        stop_below: float = -math.inf,
        path: list[tuple[float, ...]] | None = None,
    ) -> tuple[TrialPoint, int, float, str]:
        """Minimise from the feasible ``x``; stop early once ``value <= stop_below``; each accepted iterate appended
        to ``path``."""
        width = self.problem.bounds[:, 1] - self.problem.bounds[:, 0]
        scale = 0.05 * float(np.linalg.norm(width))
        n = x.p.size
        g_norm = float(np.linalg.norm(x.gradient))
        H = np.eye(n) * (scale / g_norm if g_norm > 0 else 1.0)
        samples = [x]
        for it in range(self.max_iter):
            if x.value <= stop_below:
                return x, it, math.nan, "target reached"
            near = [y for y in samples if np.linalg.norm((y.p - x.p) / width) <= 1e-3]
            stationarity = _min_norm_convex(np.array([y.gradient for y in near]))
            if stationarity <= self.tol:
                return (
                    x,
                    it,
                    stationarity,
                    "stationary: the smallest convex combination of nearby gradients is below tol",
                )
            d = -H @ x.gradient
            if float(x.gradient @ d) >= 0.0:
                H = np.eye(n) * (scale / max(float(np.linalg.norm(x.gradient)), 1e-300))
                d = -H @ x.gradient
            y, why = self._line_search(f, x, d, counter)
            if y is None:
                return x, it, stationarity, f"the line search stopped: {why}"
            s, yy = y.p - x.p, y.gradient - x.gradient
            sy = float(s @ yy)
            if sy > 1e-16 * float(np.linalg.norm(s) * np.linalg.norm(yy)):
                rho = 1.0 / sy
                V = np.eye(n) - rho * np.outer(s, yy)
                H = V @ H @ V.T + rho * np.outer(s, s)
            x = y
            if path is not None:
                path.append(tuple(map(float, x.p)))
            samples = [*samples, y][-SAMPLED_GRADIENTS:]
        near = [y for y in samples if np.linalg.norm((y.p - x.p) / width) <= 1e-3]
        return x, self.max_iter, _min_norm_convex(np.array([y.gradient for y in near])), "iteration limit"

    def polish(
        self,
        f: Callable[[NDArray, float], TrialPoint],
        x: TrialPoint,
        counter: list[int],
        stop_below: float = -math.inf,
        path: list[tuple[float, ...]] | None = None,
    ) -> TrialPoint:
        """A pattern search from ``x`` (steps halved to ``POLISH_TOL`` of the bounds' widths; each accepted point
        appended to ``path``).

        Where the line search stalls (at a kink where two roots meet, whose abscissa is not
        even Lipschitz, or at a corner of the feasible set, where a crossing pair is born) BFGS
        has no descent step to take; the pattern search needs none and only accepts feasible,
        better points. Its directions are the coordinate axes, the diagonals of every pair of
        axes (a corner of the feasible set is often crossed along a diagonal only), the last
        gradient's descent direction and, at a tie of a maximum (:attr:`TrialPoint.active`), minus the
        least-norm point of the convex hull of the active gradients (the steepest descent of the
        maximum: a tie's ridge is rarely along an axis or a diagonal), each scaled by the bounds' widths.
        A step that improves is followed by steps twice as long in its direction while they improve (a
        long valley is crossed in a few evaluations, each accepted one costing a complete
        certification). It
        stops early once ``value <= stop_below``.
        """
        width = self.problem.bounds[:, 1] - self.problem.bounds[:, 0]
        n = x.p.size
        axes = list(np.eye(n))
        axes += [(e1 + sign * e2) / 2.0 for i, e1 in enumerate(axes[:n]) for e2 in axes[i + 1 : n] for sign in (1, -1)]
        step = POLISH_START
        while step > POLISH_TOL and x.value > stop_below:
            directions = [sign * a for a in axes for sign in (1.0, -1.0)]
            g = x.gradient * width
            if np.any(g != 0.0):
                directions.insert(0, -g / np.max(np.abs(g)))
            if x.active is not None:  # a tie: the steepest descent of the active gradients' hull (bounds' units)
                v = _min_norm_point(x.active * width)
                if np.any(v != 0.0):
                    directions.insert(0, -v / np.max(np.abs(v)))
            for d in directions:
                # a step past a bound stops on it: an optimum on the boundary is reached, not only approached
                trial = np.clip(x.p + step * d * width, self.problem.bounds[:, 0], self.problem.bounds[:, 1])
                if np.array_equal(trial, x.p):
                    continue
                y = f(trial, x.value)
                counter[0] += 1
                if y.feasible and y.value < x.value:
                    x = self._extrapolate(f, self.problem.bounds, y, step * d * width, counter, stop_below, path)
                    break
            else:
                step /= 2.0
        return x

    @staticmethod
    def _extrapolate(
        f: Callable[[NDArray, float], TrialPoint],
        bounds: NDArray[np.float64],
        x: TrialPoint,
        move: NDArray[np.float64],
        counter: list[int],
        stop_below: float,
        path: list[tuple[float, ...]] | None = None,
    ) -> TrialPoint:
        """From ``x``, reached by ``move``: steps of 2, 4, ... ``move`` (clipped to ``bounds``) while they improve
        (``x`` and each accepted step appended to ``path``)."""
        if path is not None:
            path.append(tuple(map(float, x.p)))
        while x.value > stop_below:
            move = 2.0 * move
            trial = np.clip(x.p + move, bounds[:, 0], bounds[:, 1])
            if np.array_equal(trial, x.p):
                break
            y = f(trial, x.value)
            counter[0] += 1
            if not (y.feasible and y.value < x.value):
                break
            x = y
            if path is not None:
                path.append(tuple(map(float, x.p)))
        return x

    def stabilise(self, m: TrialPoint, counter: list[int]) -> tuple[TrialPoint, int]:
        """The phase before the first, from ``m`` (a first-phase point without a stability window, :data:`NO_WINDOW`).

        Minimises the largest spectral abscissa of the loops at each window's ``delta = d_min`` (``want="abscissa"``;
        with :func:`optimize_loop`'s margin objective and every ``d_min > 0``, the loop's at ``delta = 0`` among
        them) by BFGS and the pattern search until it is below ``-STABLE_BY`` times its value at ``m`` (or
        to a local minimum), and returns the first phase's point there with the BFGS iterations: a
        stability window holds each ``d_min`` once that abscissa is negative. Not negative: the first-phase
        point, infeasible, says how far the abscissa came down.
        """
        problem = self.problem

        def abscissa(q: NDArray, above: float) -> TrialPoint:
            return problem(q, want="abscissa", above=above)

        a = abscissa(m.p, math.inf)
        counter[0] += 1
        if not a.feasible:
            return replace(m, reason=f"{m.reason}; the abscissa of the phase before not lowered: {a.reason}"), 0
        target = -STABLE_BY * abs(a.value) if a.value != 0.0 else -STABLE_BY
        a, iterations, _, _ = self.minimise(abscissa, a, counter, stop_below=target)
        a = self.polish(abscissa, a, counter, stop_below=target)
        m = problem(a.p, want="margin")
        counter[0] += 1
        if not m.feasible and a.value >= 0.0:
            m = replace(
                m,
                reason=f"{m.reason}; the phase before lowered the largest abscissa (at d_min, and at delta = 0 "
                f"under the margin objective) to {a.value:.6g} only, a local minimum: a start nearer stability "
                "would help",
            )
        return m, iterations

    @one_blas_thread(scipy_linalg=True)  # in whichever process runs the start (nnls: scipy)
    def __call__(self, start: Sequence[float]) -> LocalRun:
        problem = self.problem
        counter = [1]
        screened = problem.screened
        x = problem(np.asarray(start, dtype=float))
        iterations = 0
        if not x.feasible and problem.margin_at_least is not None and x.reason.startswith(BELOW_REQUIREMENT):
            m = problem(x.p, want="margin")  # first phase: raise the margin to the requirement
            counter[0] += 1
            if not m.feasible and m.reason.startswith(NO_WINDOW):
                m, iterations = self.stabilise(m, counter)
            if m.feasible:

                def margin(q: NDArray, above: float) -> TrialPoint:
                    return problem(q, want="margin", above=above)

                target = -problem.margin_at_least
                m, its, _, _ = self.minimise(margin, m, counter, stop_below=target)
                iterations += its
                m = self.polish(margin, m, counter, stop_below=target)
                x = problem(m.p)
                counter[0] += 1
                if not x.feasible and m.value > target:
                    reached = (
                        f"; the first phase raised the margin (with windows: the last d_max plus the clearance) to "
                        f"{-m.value:.6g}, {problem.margin_at_least:.6g} required"
                    )
                    x = replace(x, reason=x.reason + reached)
        if not x.feasible:
            return LocalRun(
                tuple(map(float, start)),
                tuple(map(float, x.p)),
                math.nan,
                False,
                iterations,
                counter[0],
                math.nan,
                x.reason,
                problem.screened - screened,
            )
        path = [tuple(map(float, x.p))]
        x, its, stationarity, reason = self.minimise(lambda q, above: problem(q, above=above), x, counter, path=path)
        polished = self.polish(lambda q, above: problem(q, above=above), x, counter, path=path)
        if polished.value < x.value:
            x, reason = polished, reason + "; then improved by a pattern search"
        return LocalRun(
            tuple(map(float, start)),
            tuple(map(float, x.p)),
            float(-x.value),
            True,
            iterations + its,
            counter[0],
            float(stationarity),
            reason,
            problem.screened - screened,
            tuple(path),
        )


@dataclass(frozen=True)
class LoopDesign:
    """A locally optimal member of a loop family, certified.

    Attributes
    ----------
    parameters : tuple of float
        The design.
    objective : str
        ``"decay_rate"`` or ``"margin"``.
    value : float
        The objective's value at the design (the decay rate ``-alpha``, or ``delta*``; with
        ``worst_case`` the least decay rate of the loop and the scenarios).
    decay_rate : float
        ``-alpha`` at ``delta = 0`` (of the loop, not the scenarios).
    abscissa : SpectralAbscissa
        Of ``F(.; 0, p)`` at the design (certified; ``rigorous=True`` proves its bracket).
    margin : DelayMargin
        Of the design (verified; ``rigorous=True``: proven, with ``margin_ball``).
    margin_at_least : float or None
        The required margin.
    certified : bool
        True if the abscissa is certified, the margin verified (proven when ``rigorous``) and
        the required margin met by it (by the lower end of its ball when ``rigorous``); with
        ``delays`` or ``scenarios``, every window of :attr:`windows` certified stable (proven when
        ``rigorous``); with the margin objective, the loop stable at ``delta = 0`` (its certified count).
    rigorous : bool
        True if the certificate is in ball arithmetic.
    local : bool
        Always True: the design is the best of ``runs``, each a point where neither the line
        search nor the pattern search (:meth:`_Local.polish`) finds a better feasible point, down
        to a step of ``POLISH_TOL`` of the bounds. That is not a proof of local optimality: the
        functions are nonconvex and nonsmooth, and the feasible set has corners (where crossing
        pairs are born) that no finite set of directions is sure to enter.
    runs : tuple of LocalRun
        Every start, the best first.
    delays : (float, float) or tuple of (float, float) or None
        The window ``[d_min, d_max]`` required (:func:`optimize_loop`'s ``delays``), or the windows
        when several (:attr:`required_windows`: always a tuple of windows).
    windows : tuple of DelayWindow
        The certificates of the requirements at the design (:func:`nrobust.design.window_stability`,
        each with its delay margin, verified or proven), for the loop and then for each scenario
        (:attr:`loop_windows` groups them): the loop's, one per window of :attr:`required_windows`
        (its margin is :attr:`margin`); each scenario's, with a required margin ``d > 0`` first its
        ``[0, d]`` (``delta* > d``), then one per window. Empty without ``delays`` and ``scenarios``.
    scenario_abscissae : tuple of SpectralAbscissa
        With ``worst_case`` (:func:`optimize_loop`): the certified spectral abscissa at ``delta = 0`` of
        each scenario's loop at the design (proven when ``rigorous``), in the order of the scenarios;
        :attr:`value` is the least decay rate of :attr:`abscissa` and these. Empty otherwise.
    """

    parameters: tuple[float, ...]
    objective: str
    value: float
    decay_rate: float
    abscissa: SpectralAbscissa
    margin: DelayMargin
    margin_at_least: float | None
    certified: bool
    rigorous: bool
    runs: tuple[LocalRun, ...] = field(repr=False)
    local: bool = True
    delays: tuple[float, float] | _Windows | None = None
    windows: tuple[DelayWindow, ...] = field(default=(), repr=False)
    scenario_abscissae: tuple[SpectralAbscissa, ...] = field(default=(), repr=False)

    @property
    def value_accuracy(self) -> float | None:
        """A bound of the error of :attr:`value`: the margin's accuracy, or the abscissa's (with
        :attr:`scenario_abscissae`, the largest of theirs and the loop's: the least of values each within
        ``a_j`` of its true one is within ``max_j a_j`` of the true least); None when one is not estimated."""
        if self.objective == "margin":
            return self.margin.accuracy
        accuracies = [a.accuracy for a in (self.abscissa, *self.scenario_abscissae)]
        return None if any(a is None for a in accuracies) else float(max(a for a in accuracies if a is not None))

    @property
    def value_text(self) -> str:
        """:attr:`value` printed to its accuracy (:attr:`value_accuracy`), ``+-`` it."""
        return with_accuracy(self.value, self.value_accuracy)

    def __repr__(self) -> str:
        # the designed parameters are the controller's own numbers (in full); the objective's value and the
        # decay rate are estimates, printed to their accuracy
        rate = with_accuracy(self.decay_rate, self.abscissa.accuracy)
        return (
            f"LoopDesign(parameters={self.parameters!r}, objective={self.objective!r}, value={self.value_text}, "
            f"decay_rate={rate}, abscissa={self.abscissa!r}, margin={self.margin!r}, "
            f"margin_at_least={self.margin_at_least!r}, certified={self.certified}, rigorous={self.rigorous}, "
            f"local={self.local}, delays={self.delays!r})"
        )

    @property
    def required_windows(self) -> _Windows:
        """The windows of delays required, one ``(d_min, d_max)`` each (empty without ``delays``)."""
        if self.delays is None:
            return ()
        first = self.delays[0]
        if isinstance(first, tuple):
            return tuple((float(lo), float(hi)) for lo, hi in self.delays)  # type: ignore[misc]
        return ((float(first), float(self.delays[1])),)  # type: ignore[arg-type]

    @property
    def loop_windows(self) -> tuple[tuple[DelayWindow, ...], ...]:
        """:attr:`windows` grouped by loop: the loop's, then each scenario's (its ``[0, d]`` first under a
        required margin ``d > 0``, then one per window)."""
        m = len(self.required_windows)
        size = m + (1 if self.margin_at_least else 0)
        rest = self.windows[m:] if size else ()
        return (self.windows[:m], *(rest[k : k + size] for k in range(0, len(rest), max(size, 1))))

    @property
    def requirement(self) -> str:
        """Each requirement and its verdict in words (met and proven, met and checked, or not met): the
        required margin (of the loop and the scenarios), then each window; ``"none"`` without one."""
        groups = self.loop_windows
        parts = []
        d = self.margin_at_least
        if d:
            dm = self.margin
            ball = dm.margin_ball if self.rigorous else None
            others = [g[0] for g in groups[1:]]
            met = (ball[0] if ball is not None else dm.margin) >= d and all(w.stable for w in others)
            proven = met and ball is not None and all(w.certified == "proven" for w in others)
            loops = "the loop" if not others else f"the loop and its {len(others)} scenarios"
            verdict = "met, proven" if proven else "met, checked" if met else "not met"
            parts.append(f"delay margin >= {float(d)!r} ({loops}): {verdict}")
        skip = 1 if d else 0
        for j, window in enumerate(self.required_windows):
            parts.append(window_requirement(window, [groups[0][j], *(g[skip + j] for g in groups[1:])]))
        return "; ".join(parts) or "none"

    @property
    def stationarity(self) -> float:
        """The best run's stationarity measure (see :class:`LocalRun`)."""
        return self.runs[0].stationarity

    @property
    def optimality(self) -> str:
        """What is known of the optimality of :attr:`parameters`, in words (as the ``n + m`` designs state it)."""
        starts = len(self.runs)
        return (
            f"local: the best of {starts} start{'s' if starts != 1 else ''}, each ending where neither the line search "
            f"nor the pattern search finds a better feasible point down to steps of {POLISH_TOL:g} of the bounds "
            f"(stationarity measure {self.stationarity:.1e}); not proven locally optimal (the objective is nonsmooth "
            "and nonconvex) and not global"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (the abscissa and the margin as their own dictionaries)."""
        skip = ("abscissa", "margin", "runs", "windows", "scenario_abscissae")
        data = {k: v for k, v in vars(self).items() if k not in skip}
        data["abscissa"] = {"value": self.abscissa.value, "upper_bound": self.abscissa.upper_bound}
        if self.scenario_abscissae:
            data["scenario_abscissae"] = [
                {"value": a.value, "upper_bound": a.upper_bound} for a in self.scenario_abscissae
            ]
        data["margin"] = self.margin.to_dict()
        data["runs"] = [run.to_dict() for run in self.runs]
        data["windows"] = [w.to_dict() for w in self.windows]
        data["requirement"] = self.requirement
        data["optimality"] = self.optimality
        return json_safe(data)


def _starts(bounds: NDArray[np.float64], x0: ArrayLike | None, starts: int) -> list[tuple[float, ...]]:
    points: list[tuple[float, ...]] = []
    if x0 is not None:
        x = np.asarray(x0, dtype=float)
        if x.shape != (bounds.shape[0],) or not np.all(np.isfinite(x)):
            raise ParameterError("x0", f"{bounds.shape[0]} finite parameters", x0)
        points.append(tuple(map(float, x)))
    k = starts - len(points)
    if k > 0:
        from scipy.stats import qmc  # 0.8 s to import: only when a Halton start is wanted

        unit = qmc.Halton(d=bounds.shape[0], scramble=False).random(k + 1)[1:]  # skip the corner 0
        points += [tuple(map(float, q)) for q in qmc.scale(unit, bounds[:, 0], bounds[:, 1])]
    return points


def check_objective(objective: str, margin_at_least: float | None) -> float | None:
    """The checked ``margin_at_least`` of an ``objective`` of :data:`OBJECTIVES` (a ``ParameterError`` otherwise).

    ``"margin"`` takes no requirement (the margin is maximised); ``"decay_rate"`` takes None or a
    delay ``>= 0``.
    """
    if objective not in OBJECTIVES:
        raise ParameterError("objective", " or ".join(repr(o) for o in OBJECTIVES), objective)
    if margin_at_least is None:
        return None
    margin_at_least = nonnegative("margin_at_least", margin_at_least)
    if objective == "margin":
        raise ParameterError(
            "margin_at_least", "None with objective='margin' (the margin is maximised)", margin_at_least
        )
    return margin_at_least


def local_runs(
    problem: LocalProblem,
    *,
    x0: ArrayLike | None = None,
    starts: int = 1,
    max_iter: int = 60,
    tol: float = 1e-6,
    map: Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]] = map,
) -> list[LocalRun]:
    """The local optimisation of :func:`optimize_loop` on any :class:`LocalProblem`, one run per start.

    From each start (``x0`` first, then a Halton sequence in ``problem.bounds``): a start below
    the required margin first maximises the margin up to it (from a first-phase point without a
    stability window, :data:`NO_WINDOW`, after a phase that lowers ``want="abscissa"`` below 0),
    then BFGS with the weak Wolfe line
    search, then the pattern search (module notes). Nothing is certified here: the caller
    certifies the best run's parameters.

    Parameters
    ----------
    problem : LocalProblem
    x0 : sequence of float, optional
        The first start.
    starts : int
        Number of starts (``>= 1``).
    max_iter : int
        BFGS iterations per start (``>= 1``).
    tol : float
        Stationarity at which a start stops (see :class:`LocalRun`).
    map : callable
        ``map(func, starts)``; :func:`nrobust.sweep_map` runs the starts on processes or Dask.

    Returns
    -------
    list of LocalRun
        Every start's run, the feasible ones first, best value first.
    """
    box = _box(problem.bounds)
    starts = positive_int("starts", starts)
    max_iter = positive_int("max_iter", max_iter)
    tol = finite_real("tol", tol)
    return sorted(
        map(_Local(problem, max_iter, tol), _starts(box, x0, starts)),
        key=lambda r: (not r.feasible, -r.value if r.feasible else 0.0),
    )


@one_blas_thread(scipy_linalg=True)  # many small products: competing BLAS threads only cost time
def optimize_loop(
    loop: ParametricLoop,
    bounds: ArrayLike,
    *,
    objective: str = "decay_rate",
    margin_at_least: float | None = None,
    delays: tuple[float, float] | Sequence[tuple[float, float]] | None = None,
    scenarios: Sequence[ParametricLoop] = (),
    worst_case: bool = False,
    gamma_max: float = GAMMA_MAX,
    x0: ArrayLike | None = None,
    starts: int = 1,
    max_iter: int = 60,
    tol: float = 1e-6,
    rigorous: bool = False,
    map: Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]] = map,
) -> LoopDesign:
    """The parameters of a loop family with the best decay rate or delay margin, certified.

    Parameters
    ----------
    loop : callable
        ``p -> (A, B)``: ``F(s; delta) = A(s) + B(s) e^{-delta s}`` at the parameters ``p``
        (e.g. :func:`nrobust.hyperbolic.analyses.filter_design.filtered_loop`), a pair of
        :class:`~nrobust.quasipoly.QuasiPolynomial`; picklable if ``map`` runs processes.
    bounds : sequence of (low, high)
        One interval per parameter; every iterate stays inside.
    objective : {"decay_rate", "margin"}
        Maximise ``-alpha`` (the spectral abscissa at ``delta = 0``) or the delay margin.
    margin_at_least : float, optional
        With ``"decay_rate"``: require ``delta* >= margin_at_least`` (stability for every
        delay in ``[0, margin_at_least]``). A start below it first maximises the margin. With
        ``delays`` or ``scenarios`` it is the window ``[0, margin_at_least]`` (``delta* > d``) merged
        with the windows, held by every loop.
    delays : (float, float) or sequence of (float, float), optional
        A window ``[d_min, d_max]`` (``0 <= d_min <= d_max``, ``d_max > 0``; ``d_min = d_max``: one
        delay) or several: require exponential stability for every delay of each window, of every
        iterate (its window clearance positive, module notes; ``d_min > 0`` allows a loop unstable at
        ``delta = 0``, the decay rate then that of the loop without delay, negative); with either
        objective, and with ``margin_at_least``. A start that misses them first maximises its
        window clearance; when the start or a scenario at it has no stability window up to
        ``2 h + 1`` (``h`` the largest ``d_max`` or margin) that can hold each window (with ``d_min =
        0``, or the margin objective: is unstable at ``delta = 0``), a phase before lowers the largest
        spectral abscissa at the windows' ``d_min`` (and with the margin objective the loop's at ``delta
        = 0``) below 0 (module notes); a start is refused when that phase stops at a local minimum
        above 0 (another ``x0`` or more ``starts`` help), and without ``delays`` a margin-objective start
        unstable at ``delta = 0``. The design's windows are certified by
        :func:`nrobust.design.window_stability` (:attr:`LoopDesign.windows`), each window as given.
    scenarios : sequence of callable, optional
        Further loop families ``p -> (A, B)`` of the same parameters held to every requirement of the
        loop (with ``delays`` or ``margin_at_least > 0``): stable on each window and for every delay in
        ``[0, margin_at_least]``; e.g. the loop on plants with mismatched speeds. Each is held to
        ``gamma_max`` as well, and certified at the design (:attr:`LoopDesign.windows`). Each must return
        a pair ``(A, B)`` of :class:`~nrobust.quasipoly.QuasiPolynomial` (a ``ParameterError``
        naming it at the first call that returns anything else, as for ``loop``).
    worst_case : bool
        With ``"decay_rate"`` and ``scenarios``: maximise the least decay rate at ``delta = 0`` of the loop
        and the scenarios, ``min_j -alpha_j(p)`` (the largest abscissa minimised: nonsmooth where two are
        equal, the gradient that of the largest; the stationarity measure samples the gradients of both
        sides of such a tie), instead of the loop's own. :attr:`LoopDesign.value` is then that least rate,
        :attr:`LoopDesign.decay_rate` the loop's, and :attr:`LoopDesign.scenario_abscissae` the scenarios'
        certified abscissae at the design.
    gamma_max : float
        Require ``gamma_0 <= gamma_max`` for the delayed loop's difference operator
        (:func:`delayed_gamma`; below 1: strongly stable). As ``gamma_0 -> 1`` the chains of
        the delayed loop approach the imaginary axis and its crossings accumulate, so the
        margin's supremum is often approached there, where any change of the loop's
        delays destroys it: a design keeps away from it.
    x0 : sequence of float, optional
        A start (the first); the others follow a Halton sequence in ``bounds``.
    starts : int
        Number of starts.
    max_iter : int
        BFGS iterations per start.
    tol : float
        Stationarity at which a start stops (see :class:`LocalRun`).
    rigorous : bool
        Certify the design in ball arithmetic (python-flint): the abscissa's bracket and the
        margin's ball; otherwise the floating-point certification (certified counts).
    map : callable
        ``map(func, starts)``; :func:`nrobust.sweep_map` runs the starts on processes or Dask.

    Returns
    -------
    LoopDesign

    Raises
    ------
    ParameterError
        For bad input (``loop`` or a scenario that cannot be called with one argument ``p``, before
        any evaluation, or returning anything but a pair of QuasiPolynomials, at its first such call).
    CertificationError
        If no start reaches a feasible point (the requirement may be out of reach in the
        bounds: widen them or lower ``margin_at_least``, narrow the windows), or the design is
        not certified stable on a window (:func:`nrobust.design.window_stability`, for the
        loop or a scenario; a scenario's ``[0, margin_at_least]`` too).
    """
    box = _box(bounds)
    margin_at_least = check_objective(objective, margin_at_least)
    windows = check_windows(delays)
    scenarios = callables(
        "scenarios", scenarios, "a sequence of callables p -> (A, B) (a tuple, even of one)", "a callable p -> (A, B)"
    )
    if scenarios and not windows and not margin_at_least:
        raise ParameterError("delays", "a window [d_min, d_max], or margin_at_least > 0, with scenarios", None)
    if not isinstance(worst_case, (bool, np.bool_)):
        raise ParameterError("worst_case", "True or False", worst_case)
    if worst_case and not (objective == "decay_rate" and scenarios):
        raise ParameterError(
            "worst_case", "False unless objective='decay_rate' with scenarios (the least rate is over them)", True
        )
    starts = positive_int("starts", starts)
    max_iter = positive_int("max_iter", max_iter)
    tol = finite_real("tol", tol)
    if not callable(loop):
        raise ParameterError("loop", "a callable p -> (A, B)", loop)
    gamma_max = finite_real("gamma_max", gamma_max)
    if not 0.0 <= gamma_max < 1.0:
        raise ParameterError("gamma_max", "in [0, 1) (strong stability of the delayed loop)", gamma_max)
    # the windows, and the margin's [0, d] with them, as disjoint intervals (a margin alone keeps delta* >= d)
    intervals = _merged(windows, margin_at_least) if windows or scenarios else ()
    level = intervals[-1][1] if intervals else margin_at_least
    loop = _Checked(loop, "loop")
    scenarios = tuple(_Checked(scenario, f"scenarios[{n}]") for n, scenario in enumerate(scenarios))
    problem = _Problem(loop, box, objective, level, gamma_max, intervals, scenarios, bool(worst_case))
    runs = local_runs(problem, x0=x0, starts=starts, max_iter=max_iter, tol=tol, map=map)
    if not runs or not runs[0].feasible:
        reasons = "; ".join(sorted({r.reason for r in runs}))
        remedies = ["lower margin_at_least"] if margin_at_least or not windows else []
        remedies += ["narrow the window" + ("s" if len(windows) > 1 else "")] if windows else []
        raise CertificationError(
            f"no start reached a feasible design ({reasons}); widen the bounds, give a feasible x0, "
            "add starts or " + " or ".join(remedies)
        )
    required = windows[0] if len(windows) == 1 else windows or None
    return _certify(loop, runs, objective, margin_at_least, rigorous, required, scenarios, bool(worst_case))


def _certify(
    loop: ParametricLoop,
    runs: list[LocalRun],
    objective: str,
    margin_at_least: float | None,
    rigorous: bool,
    delays: tuple[float, float] | _Windows | None = None,
    scenarios: tuple[ParametricLoop, ...] = (),
    worst_case: bool = False,
) -> LoopDesign:
    """The best run's design with its certificates (:class:`LoopDesign`); ``delays`` as the record keeps it.

    With ``worst_case`` each scenario's abscissa at ``delta = 0`` is certified too, and the value is the least
    decay rate of the loop and the scenarios."""
    best = runs[0]
    p = np.asarray(best.parameters)
    A, B = loop(p)
    windows = check_windows(delays)
    certificates: list[DelayWindow] = []
    for n, (A_n, B_n) in enumerate(((A, B), *(s(p) for s in scenarios))):
        # a scenario's margin is certified as the window [0, d]: its delay margin verified (or proven) above d
        need = [*([(0.0, margin_at_least)] if n and margin_at_least else []), *windows]
        for window in need:
            w = window_stability(A_n, B_n, window, rigorous=rigorous)
            if not w.stable:
                which = "the loop" if n == 0 else f"scenario {n - 1}"
                raise CertificationError(
                    f"optimize_loop: the design {best.parameters} is not certified stable on the window "
                    f"[{window[0]!r}, {window[1]!r}] for {which} ({w.reason}), though its floating-point check "
                    "passed: a window end at a crossing delay; narrow the window or add starts"
                )
            certificates.append(w)
    sa = spectral_abscissa(A + B, rigorous=rigorous)
    dm = delay_margin(A, B, rigorous=rigorous)
    lowest = dm.margin_ball[0] if (rigorous and dm.margin_ball is not None) else dm.margin
    met = margin_at_least is None or lowest >= margin_at_least
    # an infinite margin is decided by the proven frequency bound and the complete crossing
    # search (no crossing at all): there is no crossing delay to check a count at
    decided = dm.verified or (math.isinf(dm.margin) and dm.nominally_stable and dm.strongly_stable)
    if objective == "margin":
        # the margin is that of a loop stable at delta = 0: an unstable one is no design of this objective
        decided = decided and dm.nominally_stable
    elif windows and not margin_at_least and min(lo for lo, _ in windows) > 0.0 and not dm.nominally_stable:
        # unstable at delta = 0 (a certified count of its zeros in Re s > 0): the margin is 0, the windows certify
        decided = bool(dm.strongly_stable and dm.nominal_unstable)
    proven = not rigorous or all(w.certified == "proven" for w in certificates)
    scenario_loops = (s(p) for s in scenarios) if worst_case else ()
    others = tuple(spectral_abscissa(A_n + B_n, rigorous=rigorous) for A_n, B_n in scenario_loops)
    certified = bool(sa.certified and decided and met and proven and all(o.certified for o in others))
    value = -max(a.value for a in (sa, *others)) if objective == "decay_rate" else dm.margin
    return LoopDesign(
        best.parameters,
        objective,
        float(value),
        float(-sa.value),
        sa,
        dm,
        margin_at_least,
        certified,
        rigorous,
        tuple(runs),
        delays=delays,
        windows=tuple(certificates),
        scenario_abscissae=others,
    )
