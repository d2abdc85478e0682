"""Several parameters: a local nonsmooth optimisation of a loop's decay rate or delay margin.

The loop is a family ``F(s; delta, p) = A(s; p) + B(s; p) e^{-delta s}`` of quasi-polynomials
in the parameters ``p`` (a filter's gain, zero and pole, the gains of a state feedback, ...).
Two objectives:

* ``"decay_rate"``: maximise ``-alpha(p)``, ``alpha`` the spectral abscissa of ``F(.; 0, p)``
  (:func:`nrobust.roots.spectral_abscissa`), optionally subject to a delay margin
  ``delta*(p) >= d`` (:func:`nrobust.margins.delay_margin`): stability for every delay in
  ``[0, d]``;
* ``"margin"``: maximise ``delta*(p)``.

Both functions are nonsmooth: the abscissa where two roots (or a root and a chain of a
neutral loop) share the rightmost real part, the margin where two crossing branches meet
(and it jumps where a crossing pair is born). They are differentiable almost everywhere, with
gradients from the sensitivity of what is active:

* the rightmost root ``s*`` (simple): ``d alpha/dp = Re(-F_p(s*) / F'(s*))``;
* a chain of the difference operator ``D`` of a neutral loop (the abscissa approached as
  ``|Im s| -> infinity``): the derivative of its spectral bound ``c_D(p)`` (the roots of a
  polynomial in ``z = e^{-h s}``), by central differences;
* the critical crossing ``(w*, delta*)`` of the margin: with ``g(w, p) = |A(iw)|^2 - |B(iw)|^2``
  and ``w delta = -arg(-A(iw)/B(iw)) + 2 pi k`` on the branch ``k`` of ``delta*``,
  ``dw/dp = -g_p/g_w`` and ``d delta/dp = -(theta_p + theta_w dw/dp + delta dw/dp)/w``.

The optimiser is BFGS with the weak Wolfe line search of Lewis and Overton ("Nonsmooth
optimization via quasi-Newton methods", Math. Program. 141, 2013), which converges on such
functions in practice; it stops when the smallest convex combination of the gradients
sampled near the last iterate (the gradient-sampling stationarity measure of Burke, Lewis and
Overton, SIAM J. Optim. 15, 2005) is small. Every trial point's feasibility is checked (inside
the bounds, margin ``>= d``): an infeasible point counts as ``+inf`` for the line search, so
every iterate is feasible. Where BFGS stalls (at a kink, or at a corner of the feasible set
where a crossing pair is born), a pattern search over the coordinate axes, their pairwise
diagonals and the descent direction continues with shrinking steps. A start that is not
feasible first maximises the margin until it reaches ``d``. The optimum is local; several
starts (a Halton sequence in the bounds, run through any ``map``, e.g.
:func:`nrobust.sweep_map` for processes or Dask) make a better one likely, not certain. The
design found is then certified: its abscissa (certified count of the roots right of it) and its
delay margin (``rigorous=True``: proven in ball arithmetic).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._json import json_safe
from .._validate import finite_real, nonnegative, positive_int
from ..errors import CertificationError, ParameterError
from ..margins import DelayMargin, delay_margin
from ..quasipoly import QuasiPolynomial
from ..roots import SpectralAbscissa, spectral_abscissa

__all__ = ["GAMMA_MAX", "OBJECTIVES", "LoopDesign", "LocalRun", "ParametricLoop", "delayed_gamma", "optimize_loop"]

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


def _box(bounds: ArrayLike) -> NDArray[np.float64]:
    b = np.asarray(bounds, dtype=float)
    if b.ndim != 2 or b.shape[1] != 2 or b.shape[0] == 0 or not np.all(np.isfinite(b)) or np.any(b[:, 0] >= b[:, 1]):
        raise ParameterError(
            "bounds", "a sequence of finite (low, high) pairs with low < high, one per parameter", bounds
        )
    return b


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
class _Point:
    """One evaluated parameter vector."""

    p: NDArray[np.float64]
    feasible: bool
    value: float  # the function minimised: alpha, or -delta*
    gradient: NDArray[np.float64]
    abscissa: float
    margin: float
    reason: str = ""


@dataclass(frozen=True)
class _Problem:
    """The function minimised, its gradient and its feasibility (picklable)."""

    loop: ParametricLoop
    bounds: NDArray[np.float64]
    objective: str
    margin_at_least: float | None
    gamma_max: float = 1.0

    def _step(self, p: NDArray[np.float64], i: int) -> float:
        return 1e-6 * max(1.0, abs(float(p[i])), float(self.bounds[i, 1] - self.bounds[i, 0]))

    def _pair(self, p: NDArray[np.float64], i: int) -> tuple[NDArray, NDArray, float]:
        """``p - h e_i``, ``p + h e_i`` and their distance (one-sided at a bound)."""
        h = self._step(p, i)
        lo, hi = p.copy(), p.copy()
        lo[i] = max(p[i] - h, self.bounds[i, 0])
        hi[i] = min(p[i] + h, self.bounds[i, 1])
        return lo, hi, float(hi[i] - lo[i])

    def _abscissa_gradient(self, p: NDArray[np.float64], F: QuasiPolynomial, sa: SpectralAbscissa) -> NDArray:
        grad = np.zeros(p.size)
        if sa.root is None or sa.approached_at_infinity:
            for i in range(p.size):  # the chain's abscissa c_D(p)
                lo, hi, h = self._pair(p, i)
                c = [(a + b).principal_part().spectral_bound().value for a, b in (self.loop(lo), self.loop(hi))]
                grad[i] = (c[1] - c[0]) / h
            return grad
        s = np.array([sa.root])
        dF = complex(F.deriv_at(s)[0])
        for i in range(p.size):
            lo, hi, h = self._pair(p, i)
            f = [complex((a + b)(s)[0]) for a, b in (self.loop(lo), self.loop(hi))]
            grad[i] = (-(f[1] - f[0]) / h / dF).real
        return grad

    def _margin_gradient(
        self, p: NDArray[np.float64], A: QuasiPolynomial, B: QuasiPolynomial, dm: DelayMargin
    ) -> NDArray:
        grad = np.zeros(p.size)
        if dm.omega is None or not math.isfinite(dm.margin) or dm.margin <= 0.0:
            return grad
        w = float(dm.omega)
        s = np.array([1j * w])
        a, b = complex(A(s)[0]), complex(B(s)[0])
        da, db = 1j * complex(A.deriv_at(s)[0]), 1j * complex(B.deriv_at(s)[0])  # d/dw of A(iw), B(iw)
        g_w = 2.0 * (a.conjugate() * da).real - 2.0 * (b.conjugate() * db).real
        theta_w = (da / a - db / b).imag  # d/dw of arg(-A/B)
        for i in range(p.size):
            lo, hi, h = self._pair(p, i)
            vals = [(complex(x(s)[0]), complex(y(s)[0])) for x, y in (self.loop(lo), self.loop(hi))]
            g = [abs(x) ** 2 - abs(y) ** 2 for x, y in vals]
            th = [np.angle(-x / y) for x, y in vals]
            g_p = (g[1] - g[0]) / h
            theta_p = float(np.angle(np.exp(1j * (th[1] - th[0])))) / h
            w_p = -g_p / g_w if g_w != 0.0 else 0.0
            grad[i] = -(theta_p + theta_w * w_p + dm.margin * w_p) / w
        return grad

    def __call__(self, p: ArrayLike, want: str | None = None, above: float = math.inf) -> _Point:
        """Evaluate at ``p``; ``want="margin"`` minimises ``-delta*`` whatever the objective.

        With the decay-rate objective, a point whose abscissa exceeds ``above`` (a line
        search's sufficient-decrease line) is returned as it is, its margin not computed: it is
        rejected whether feasible or not.

        A point where the abscissa or the margin cannot be certified within their work bounds
        (e.g. crossings accumulating as the difference operator nears instability) is treated
        as infeasible: the search stays where every iterate is certified.
        """
        p = np.asarray(p, dtype=float)
        if np.any(p < self.bounds[:, 0]) or np.any(p > self.bounds[:, 1]):
            return _Point(p, False, math.inf, np.zeros(p.size), math.nan, math.nan, "outside the bounds")
        try:
            return self._evaluate(p, want or self.objective, above)
        except CertificationError as exc:
            return _Point(p, False, math.inf, np.zeros(p.size), math.nan, math.nan, f"not certified: {exc}")

    def _evaluate(self, p: NDArray[np.float64], objective: str, above: float) -> _Point:
        A, B = self.loop(p)
        gamma = delayed_gamma(A, B)
        if not gamma <= self.gamma_max:
            reason = f"gamma_0 = {gamma:.6g} of the delayed loop's difference operator above gamma_max"
            return _Point(p, False, math.inf, np.zeros(p.size), math.nan, math.nan, reason)
        F = A + B
        sa = spectral_abscissa(F)
        if objective == "decay_rate" and sa.value > above:
            return _Point(p, True, sa.value, np.zeros(p.size), sa.value, math.nan, "above the line search's line")
        need_margin = objective == "margin" or self.margin_at_least is not None
        dm = delay_margin(A, B, verify=False) if need_margin else None
        margin = dm.margin if dm is not None else math.nan
        if objective == "margin":
            assert dm is not None
            if not dm.nominally_stable:
                return _Point(p, False, math.inf, np.zeros(p.size), sa.value, margin, "not stable at delta = 0")
            return _Point(p, True, -margin, -self._margin_gradient(p, A, B, dm), sa.value, margin)
        if self.margin_at_least is not None and not margin >= self.margin_at_least:
            return _Point(p, False, math.inf, np.zeros(p.size), sa.value, margin, "delay margin below the requirement")
        return _Point(p, True, sa.value, self._abscissa_gradient(p, F, sa), sa.value, margin)


def _min_norm_convex(G: NDArray[np.float64]) -> float:
    """``min ||sum_j l_j g_j||`` over ``l >= 0``, ``sum l = 1`` (rows of ``G`` the gradients)."""
    from scipy.optimize import nnls

    k = G.shape[0]
    if k == 1:
        return float(np.linalg.norm(G[0]))
    scale = max(1.0, float(np.abs(G).max())) * 1e3
    M = np.vstack([G.T, scale * np.ones((1, k))])
    rhs = np.concatenate([np.zeros(G.shape[1]), [scale]])
    lam, _ = nnls(M, rhs)
    lam = lam / lam.sum() if lam.sum() > 0 else np.full(k, 1.0 / k)
    return float(np.linalg.norm(lam @ G))


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
        BFGS iterations and evaluations of the loop (line searches and the first phase
        included).
    stationarity : float
        The smallest convex combination of the gradients sampled at the last iterates
        (0 at a smooth stationary point; small at a nonsmooth local optimum).
    reason : str
        Why it stopped.
    """

    start: tuple[float, ...]
    parameters: tuple[float, ...]
    value: float
    feasible: bool
    iterations: int
    evaluations: int
    stationarity: float
    reason: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return json_safe(vars(self))


@dataclass(frozen=True)
class _Local:
    """BFGS with the weak Wolfe line search from one start (picklable, for ``map``)."""

    problem: _Problem
    max_iter: int
    tol: float

    def _line_search(
        self, f: Callable[[NDArray, float], _Point], x: _Point, d: NDArray[np.float64], counter: list[int]
    ) -> _Point | None:
        slope = float(x.gradient @ d)
        lo, hi, t = 0.0, math.inf, 1.0
        for _ in range(LINE_SEARCH_TRIALS):
            y = f(x.p + t * d, x.value + ARMIJO * t * slope)
            counter[0] += 1
            if not y.feasible or y.value > x.value + ARMIJO * t * slope:
                hi = t
            elif float(y.gradient @ d) < WOLFE * slope:
                lo = t
            else:
                return y
            t = 0.5 * (lo + hi) if math.isfinite(hi) else 2.0 * lo
            if math.isfinite(hi) and hi - lo < 1e-14 * max(1.0, hi):
                break
        return None

    def minimise(
        self, f: Callable[[NDArray, float], _Point], x: _Point, counter: list[int], stop_below: float = -math.inf
    ) -> tuple[_Point, int, float, str]:
        """Minimise from the feasible ``x``; stop early once ``value <= stop_below``."""
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
            y = self._line_search(f, x, d, counter)
            if y is None:
                return (
                    x,
                    it,
                    stationarity,
                    "the line search found no better point (a nonsmooth local optimum, or a bound)",
                )
            s, yy = y.p - x.p, y.gradient - x.gradient
            sy = float(s @ yy)
            if sy > 1e-16 * float(np.linalg.norm(s) * np.linalg.norm(yy)):
                rho = 1.0 / sy
                V = np.eye(n) - rho * np.outer(s, yy)
                H = V @ H @ V.T + rho * np.outer(s, s)
            x = y
            samples = [*samples, y][-SAMPLED_GRADIENTS:]
        near = [y for y in samples if np.linalg.norm((y.p - x.p) / width) <= 1e-3]
        return x, self.max_iter, _min_norm_convex(np.array([y.gradient for y in near])), "iteration limit"

    def polish(
        self, f: Callable[[NDArray, float], _Point], x: _Point, counter: list[int], stop_below: float = -math.inf
    ) -> _Point:
        """A pattern search from ``x`` (steps halved to ``POLISH_TOL`` of the bounds' widths).

        Where the line search stalls (at a kink where two roots meet, whose abscissa is not
        even Lipschitz, or at a corner of the feasible set, where a crossing pair is born) BFGS
        has no descent step to take; the pattern search needs none and only accepts feasible,
        better points. Its directions are the coordinate axes, the diagonals of every pair of
        axes (a corner of the feasible set is often crossed along a diagonal only) and the last
        gradient's descent direction, each scaled by the bounds' widths. It stops early once
        ``value <= stop_below``.
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
            for d in directions:
                y = f(x.p + step * d * width, x.value)
                counter[0] += 1
                if y.feasible and y.value < x.value:
                    x = y
                    break
            else:
                step /= 2.0
        return x

    def __call__(self, start: Sequence[float]) -> LocalRun:
        problem = self.problem
        counter = [1]
        x = problem(np.asarray(start, dtype=float))
        iterations = 0
        if not x.feasible and problem.margin_at_least is not None and x.reason == "delay margin below the requirement":
            m = problem(x.p, want="margin")  # first phase: raise the margin to the requirement
            counter[0] += 1
            if m.feasible:

                def margin(q: NDArray, above: float) -> _Point:
                    return problem(q, want="margin")

                target = -problem.margin_at_least
                m, iterations, _, _ = self.minimise(margin, m, counter, stop_below=target)
                m = self.polish(margin, m, counter, stop_below=target)
                x = problem(m.p)
                counter[0] += 1
        if not x.feasible:
            return LocalRun(
                tuple(start), tuple(map(float, x.p)), math.nan, False, iterations, counter[0], math.nan, x.reason
            )
        x, its, stationarity, reason = self.minimise(lambda q, above: problem(q, above=above), x, counter)
        polished = self.polish(lambda q, above: problem(q, above=above), x, counter)
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
        The objective's value at the design (the decay rate ``-alpha``, or ``delta*``).
    decay_rate : float
        ``-alpha`` at ``delta = 0``.
    abscissa : SpectralAbscissa
        Of ``F(.; 0, p)`` at the design (certified; ``rigorous=True`` proves its bracket).
    margin : DelayMargin
        Of the design (verified; ``rigorous=True``: proven, with ``margin_ball``).
    margin_at_least : float or None
        The requirement.
    certified : bool
        True if the abscissa is certified, the margin verified (proven when ``rigorous``) and
        the requirement met by the margin (by the lower end of its ball when ``rigorous``).
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

    @property
    def stationarity(self) -> float:
        """The best run's stationarity measure (see :class:`LocalRun`)."""
        return self.runs[0].stationarity

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (the abscissa and the margin as their own dictionaries)."""
        data = {k: v for k, v in vars(self).items() if k not in ("abscissa", "margin", "runs")}
        data["abscissa"] = {"value": self.abscissa.value, "upper_bound": self.abscissa.upper_bound}
        data["margin"] = self.margin.to_dict()
        data["runs"] = [run.to_dict() for run in self.runs]
        return json_safe(data)


def _starts(bounds: NDArray[np.float64], x0: ArrayLike | None, starts: int) -> list[tuple[float, ...]]:
    from scipy.stats import qmc

    points: list[tuple[float, ...]] = []
    if x0 is not None:
        x = np.asarray(x0, dtype=float)
        if x.shape != (bounds.shape[0],) or not np.all(np.isfinite(x)):
            raise ParameterError("x0", f"{bounds.shape[0]} finite parameters", x0)
        points.append(tuple(map(float, x)))
    k = starts - len(points)
    if k > 0:
        unit = qmc.Halton(d=bounds.shape[0], scramble=False).random(k + 1)[1:]  # skip the corner 0
        points += [tuple(map(float, q)) for q in qmc.scale(unit, bounds[:, 0], bounds[:, 1])]
    return points


def optimize_loop(
    loop: ParametricLoop,
    bounds: ArrayLike,
    *,
    objective: str = "decay_rate",
    margin_at_least: float | None = None,
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
        (e.g. :func:`nrobust.hyperbolic.analyses.filter_design.filtered_loop`); picklable if ``map`` runs processes.
    bounds : sequence of (low, high)
        One interval per parameter; every iterate stays inside.
    objective : {"decay_rate", "margin"}
        Maximise ``-alpha`` (the spectral abscissa at ``delta = 0``) or the delay margin.
    margin_at_least : float, optional
        With ``"decay_rate"``: require ``delta* >= margin_at_least`` (stability for every
        delay in ``[0, margin_at_least]``). A start below it first maximises the margin.
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
        For bad input.
    CertificationError
        If no start reaches a feasible point (the requirement may be out of reach in the
        bounds: widen them or lower ``margin_at_least``).
    """
    box = _box(bounds)
    if objective not in OBJECTIVES:
        raise ParameterError("objective", " or ".join(repr(o) for o in OBJECTIVES), objective)
    if margin_at_least is not None:
        margin_at_least = nonnegative("margin_at_least", margin_at_least)
        if objective == "margin":
            raise ParameterError(
                "margin_at_least", "None with objective='margin' (the margin is maximised)", margin_at_least
            )
    starts = positive_int("starts", starts)
    max_iter = positive_int("max_iter", max_iter)
    tol = finite_real("tol", tol)
    if not callable(loop):
        raise ParameterError("loop", "a callable p -> (A, B)", loop)
    gamma_max = finite_real("gamma_max", gamma_max)
    if not 0.0 <= gamma_max < 1.0:
        raise ParameterError("gamma_max", "in [0, 1) (strong stability of the delayed loop)", gamma_max)
    problem = _Problem(loop, box, objective, margin_at_least, gamma_max)
    runs = sorted(
        map(_Local(problem, max_iter, tol), _starts(box, x0, starts)),
        key=lambda r: (not r.feasible, -r.value if r.feasible else 0.0),
    )
    if not runs or not runs[0].feasible:
        reasons = "; ".join(sorted({r.reason for r in runs}))
        raise CertificationError(
            f"no start reached a feasible design ({reasons}); widen the bounds, give a feasible x0, "
            "add starts or lower margin_at_least"
        )
    return _certify(loop, runs, objective, margin_at_least, rigorous)


def _certify(
    loop: ParametricLoop, runs: list[LocalRun], objective: str, margin_at_least: float | None, rigorous: bool
) -> LoopDesign:
    best = runs[0]
    A, B = loop(np.asarray(best.parameters))
    sa = spectral_abscissa(A + B, rigorous=rigorous)
    dm = delay_margin(A, B, rigorous=rigorous)
    lowest = dm.margin_ball[0] if (rigorous and dm.margin_ball is not None) else dm.margin
    met = margin_at_least is None or lowest >= margin_at_least
    # an infinite margin is decided by the proven frequency bound and the complete crossing
    # search (no crossing at all): there is no crossing delay to check a count at
    decided = dm.verified or (math.isinf(dm.margin) and dm.nominally_stable and dm.strongly_stable)
    certified = bool(sa.certified and decided and met)
    value = -sa.value if objective == "decay_rate" else dm.margin
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
    )
