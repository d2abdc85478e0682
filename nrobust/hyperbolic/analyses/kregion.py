"""Admissible gains of a plant with ``U_BS2(K)`` or another gain family: :func:`k_region`.

For ``U_BS2(K)`` (eq. (53)) the loop is affine in ``K`` (eq. (60)) and the ends of the
admissible intervals are solved from their equations by :mod:`nrobust.margins.gain`, then each
is verified; for any other family the grid's changes of verdict are bisected on delay margins.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._digits import with_accuracy
from ..._json import fields_dict, json_safe
from ..._progress import show_progress
from ..._validate import positive, positive_int, renamed_keywords
from ...errors import CertificationError, ParameterError
from ...margins.admissible import GainVerdict, check_gain_end, gain_verdict, tolerates
from ...margins.gain import END_KINDS, AffineGainLoop, GainEnd, locate_gain_ends
from ...margins.margin import DelayMargin
from ...quasipoly import QuasiPolynomial
from ..loops.controllers import ReflectionController, classify, loop_factors
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from ._common import GainMargin, exact_loop_plant, mapper, real_grid, study_plant
from .margin import studied_delay_margin

# END_KINDS and GainEnd, the kinds and ends of a KRegion's intervals, are also exported by nrobust.hyperbolic.analyses
__all__ = ["DEFAULT_N_GAINS", "END_KINDS", "MAX_GAINS", "GainEnd", "KRegion", "k_region", "u_bs2_loop"]

#: Default number of gains of the grid of :func:`k_region` (and of
#: :func:`nrobust.certify`'s K-region). For ``U_BS2(K)`` the ends are solved from their
#: equations whatever the grid; its delay margins are reported and must agree with the
#: intervals (a cross-check, a few hundredths of a second per gain on the paper's plant). For other
#: controller families the grid has to put one gain inside each admissible interval, whose
#: ends are then bisected.
DEFAULT_N_GAINS = 9

#: Most gains :func:`k_region` takes (``n_gains`` or the size of ``Ks``): each is a delay
#: margin (a few hundredths of a second on the paper's plant, more near the strong-stability
#: limit), so this bound is minutes of work on one core; a larger grid is refused before
#: anything is allocated or computed.
MAX_GAINS = 20_000


@dataclass(frozen=True, eq=False)
class KRegion:
    """Gains ``K`` for which ``U_BS2(K)`` is exponentially stable for every delay in ``[0, delta_max]``.

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    intervals : tuple of (float, float)
        The admissible gains, as open intervals (``ends`` gives the event at each end).
    delta_max : float
        The delay range that must be tolerated.
    paper_bound : float
        ``(1 - |rho q|)/|q|`` of eq. (54). It is also necessary for a positive margin:
        ``|rho q| + |K q| < 1`` is the strong stability of the loop's difference operator.
    Ks : ndarray
        Gain grid on which the margins were computed.
    margins : ndarray
        ``delta*(K)`` on the grid.
    admissible : ndarray of bool
        ``delta*(K) > delta_max`` and the nominal loop stable, on the grid.
    tol : float
        Accuracy of the interval ends: each end was checked ``tol`` inside (admissible: the
        certified crossing search of :func:`~nrobust.hyperbolic.analyses.delay_margin`) and ``tol`` outside (not
        admissible: a certified count of a zero in ``Re s > 0``).
    ends : tuple of (GainEnd, GainEnd)
        For each interval, its lower and upper end with their kind (:class:`GainEnd`:
        ``"crossing"``, ``"pair_birth"``, ``"nominal"``, ``"strong_stability"``, or
        ``"bisection"`` for a ``controller`` family other than ``U_BS2(K)``).
    method : str
        ``"equations"`` (ends solved from the equations of their kind) or ``"bisection"``.
    rigorous : bool
        ``k_region(..., rigorous=True)``: each end was put to a proof for the PDE (:attr:`proven`).
    proven : tuple of (bool, bool)
        With :attr:`rigorous`, for each interval, whether its lower and upper end are proven for the
        PDE: at the two gains that bracket the end (``end.K -+ tol``), proven delay margins of the
        exact loop (:func:`~nrobust.hyperbolic.analyses.delay_margin` with ``rigorous=True``) find the
        inner gain admissible (the nominal loop proven stable, the margin's ball above ``delta_max``)
        and the outer gain not (a crossing delay's ball below ``delta_max``, the nominal loop proven
        unstable, or the difference operator proven not strongly stable). The admissible set then has
        a boundary point within :attr:`GainEnd.accuracy` of ``end.K``. That no other end lies between
        two ends rests on the floating-point scan. Empty without :attr:`rigorous`.
    unproven : tuple of str
        With :attr:`rigorous`, why each end that is not proven could not be (it is then checked in
        floating point only).
    """

    intervals: tuple[tuple[float, float], ...]
    delta_max: float
    paper_bound: float
    Ks: NDArray[np.float64]
    margins: NDArray[np.float64]
    admissible: NDArray[np.bool_]
    tol: float
    ends: tuple[tuple[GainEnd, GainEnd], ...] = ()
    method: str = "bisection"
    rigorous: bool = False
    proven: tuple[tuple[bool, bool], ...] = ()
    unproven: tuple[str, ...] = ()

    @property
    def ends_proven(self) -> bool:
        """True when every end of every interval is proven for the PDE (:attr:`proven`; False
        without :attr:`rigorous` or without an interval)."""
        return self.rigorous and bool(self.proven) and all(lo and hi for lo, hi in self.proven)

    @property
    def end_accuracies(self) -> tuple[tuple[float | None, float | None], ...]:
        """A bound of the error of each end of each interval
        (:attr:`nrobust.margins.gain.GainEnd.accuracy`: ``tol`` for a verified end, the last
        bisection step when bisected; None for an end at a gain of the grid, not bisected)."""
        if len(self.ends) != len(self.intervals):
            return tuple((None, None) for _ in self.intervals)
        return tuple((lo.accuracy, hi.accuracy) for lo, hi in self.ends)

    def __repr__(self) -> str:
        ivs = (
            ", ".join(
                f"({with_accuracy(lo, a_lo)}, {with_accuracy(hi, a_hi)})"
                for (lo, hi), (a_lo, a_hi) in zip(self.intervals, self.end_accuracies)
            )
            or "empty"
        )
        proofs = ""
        if self.rigorous and self.intervals:
            proofs = ", ends proven for the PDE" if self.ends_proven else ", ends not all proven (see unproven)"
        return f"KRegion(delta_max={self.delta_max:.6g}, K in {ivs}, paper bound |K| < {self.paper_bound:.6g}{proofs})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description; each end as ``{"K", "kind", "omega", "delay", "accuracy"}``."""
        data = fields_dict(self, exclude=("ends",))
        data["ends"] = json_safe([[end._asdict() for end in pair] for pair in self.ends])
        return data


def u_bs2_loop(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> AffineGainLoop:
    """The loop of ``U_BS2(K)`` on ``system``: ``A + (B_0 + K q e^{-tau s}) e^{-delta s}`` (eq. (60)).

    A general plant with a constant ``lam / mu`` (its own loop, where that is exact while its normal form's
    tabulated couplings are a model: :func:`~nrobust.hyperbolic.analyses._common.exact_loop_plant`) has the
    principal gain of its normal form in place of ``q``.

    Raises
    ------
    CertificationError
        The loop factors are not affine in ``K`` with ``R`` one point term (``q e^{-tau s}`` on the paper's plant).
    """
    A, B0 = loop_factors(system, ReflectionController(0.0))
    A1, B1 = loop_factors(system, ReflectionController(1.0))
    R = B1 - B0
    if isinstance(system, Hyperbolic2x2):
        affine = R == QuasiPolynomial([[system.q]], [system.tau])
    else:
        affine = not R.distributed and len(R.point_terms) == 1 and R.point_terms[0][0].size == 1
    if A1 != A or R.distributed or not affine:
        raise CertificationError("k_region: the U_BS2(K) loop is not A + (B_0 + K q e^{-tau s}) e^{-delta s}")
    return AffineGainLoop(A, B0, R)


@dataclass(frozen=True)
class _LoopMargin:
    """Picklable ``K -> gain_verdict(loop, K)``, or the message of its CertificationError.

    A worker process receives the loop's factors instead of solving the kernels again.
    """

    loop: AffineGainLoop
    delta_max: float
    max_evals: int

    def __call__(self, K: float) -> GainVerdict | str:
        try:
            return gain_verdict(self.loop, float(K), self.delta_max, self.max_evals)
        except CertificationError as exc:
            return str(exc)


def _grid_verdicts(
    delta_max: float, grid: NDArray, margins: list[DelayMargin | str] | list[GainVerdict | str]
) -> tuple[NDArray, NDArray]:
    """Margins and verdicts of the grid gains (a failed margin raises, naming the gain)."""
    for K, dm in zip(grid, margins):
        if isinstance(dm, str):
            raise CertificationError(f"k_region: the delay margin at the grid gain K = {K:.12g} failed: {dm}")
    checked = [dm for dm in margins if not isinstance(dm, str)]
    return np.array([dm.margin for dm in checked]), np.array([tolerates(dm, delta_max) for dm in checked])


def _proven_margin(plant: Hyperbolic2x2 | GeneralHyperbolic2x2, K: float, delta_max: float) -> DelayMargin | str:
    """The delay margin of ``U_BS2(K)`` on ``plant`` proven for the PDE, or why there is none."""
    try:
        dm = studied_delay_margin(  # a model's margin is refused below: no convergence study
            plant, ReflectionController(K), delta_max=delta_max, verify=False, rigorous=True, study=False
        )[0]
    except CertificationError as exc:
        return f"the proof of the delay margin at K = {K:.15g} failed ({exc})"
    if not dm.rigorous or dm.of_model:
        return f"the delay margin at K = {K:.15g} is proven for a model of the plant only ({dm.scope})"
    return dm


def _proven_side(dm: DelayMargin, delta_max: float, inside: bool) -> str | None:
    """None if the proven margin ``dm`` shows its gain admissible (``inside``) or not, else why not.

    Admissible: strongly stable, the nominal loop proven stable and the margin's ball above
    ``delta_max`` (an infinite margin: no crossing). Not admissible: the difference operator not
    strongly stable, zeros of the nominal loop counted in ``Re s > 0``, or a crossing delay whose
    ball lies below ``delta_max``.
    """
    ball = dm.margin_ball
    if inside:
        above = np.isposinf(dm.margin) or (ball is not None and ball[0] > delta_max)
        if dm.strongly_stable and dm.nominally_stable and above:
            return None
        return f"inside, the proven margin {ball} does not exceed {delta_max:g} with a stable nominal loop"
    below = dm.nominally_stable and ball is not None and ball[1] < delta_max
    if not dm.strongly_stable or bool(dm.nominal_unstable) or below:
        return None
    return f"outside, the proven margin {ball} does not lie below {delta_max:g}"


def _prove_end(
    plant: Hyperbolic2x2 | GeneralHyperbolic2x2, end: GainEnd, K_in: float, K_out: float, delta_max: float
) -> str | None:
    """None if ``end`` is proven for the PDE between the gains ``K_in`` (admissible) and ``K_out`` (not), else why not
    (:attr:`KRegion.proven`)."""
    for K, inside in ((K_in, True), (K_out, False)):
        dm = _proven_margin(plant, K, delta_max)
        why = dm if isinstance(dm, str) else _proven_side(dm, delta_max, inside)
        if why is not None:
            return f"the {end.kind} end K = {end.K:.15g}: {why}"
    return None


def _exact_region(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    delta_max: float,
    kb: float,
    grid: NDArray,
    tol: float,
    executor: Any,
    max_evals: int,
    progress: bool | None,
    rigorous: bool = False,
    given: Any = None,
) -> KRegion:
    """:func:`k_region` of ``U_BS2(K)``: ends from their equations, each checked (``system``: the plant whose loops
    are built, :func:`~nrobust.hyperbolic.analyses._common.exact_loop_plant`), and with ``rigorous`` proven for the
    plant as given (``given``) where the proofs decide."""
    loop = u_bs2_loop(system)
    pairs = locate_gain_ends(loop, delta_max, kb, tol, max_evals) if kb > 0 else []
    probes: list[float] = []
    for lo, hi in pairs:
        probes += [lo.K + tol, hi.K - tol]
    verdict = _LoopMargin(loop, delta_max, max_evals)
    if isinstance(executor, str) and executor == "serial" and not show_progress(progress):
        results = [verdict(K) for K in [*grid, *probes]]  # no bar to draw: tqdm is not even imported
    else:
        results = list(mapper(executor, progress, "k_region: delay margins")(verdict, [*grid, *probes]))
    margins, ok = _grid_verdicts(delta_max, grid, results[: grid.size])
    checks = iter(results[grid.size :])
    proven: list[tuple[bool, bool]] = []
    unproven: list[str] = []
    verified: list[tuple[GainEnd, GainEnd]] = []
    for lo, hi in pairs:
        pair: list[GainEnd] = []
        flags: list[bool] = []
        for end, sign in ((lo, 1.0), (hi, -1.0)):
            K_in, K_out = end.K + sign * tol, end.K - sign * tol
            why = check_gain_end(end, next(checks), K_out, loop, delta_max)
            proof = None
            if rigorous:  # a proof also settles an end that floating point cannot (a bracket too tight for it)
                mapped = (
                    f"the {end.kind} end K = {end.K:.15g}: its loops are the normal form's, computed in floating point"
                )
                proof = _prove_end(system, end, K_in, K_out, delta_max) if system is given else mapped
            if why is not None and (not rigorous or proof is not None):
                raise CertificationError(
                    f"k_region: the end K = {end.K:.15g} ({end.kind}, w = {end.omega:.10g}) of the admissible "
                    f"interval ({lo.K:.12g}, {hi.K:.12g}) could not be verified on the bracket "
                    f"[{min(K_in, K_out):.15g}, {max(K_in, K_out):.15g}]: {why}"
                    + (f"; nor proven: {proof}" if proof else "")
                )
            # verified on K +- tol; where only the proof settled it (floating point could not), the gain alone is
            # known: omega and the delay keep the accuracies they had (not those of a verified end)
            end = loop.verified_end(end, tol) if why is None else end
            if rigorous and proof is None:  # the bracket holds both probes as they were rounded
                end = end._replace(accuracy=float(np.nextafter(max(abs(K_in - end.K), abs(K_out - end.K)), np.inf)))
            elif proof is not None:
                unproven.append(proof)
            pair.append(end)
            flags.append(rigorous and proof is None)
        verified.append((pair[0], pair[1]))
        if rigorous:
            proven.append((flags[0], flags[1]))
    pairs = verified
    intervals = tuple((float(lo.K), float(hi.K)) for lo, hi in pairs)
    for K, good in zip(grid, ok):
        near_end = any(min(abs(K - lo), abs(K - hi)) <= 2.0 * tol for lo, hi in intervals)
        inside = any(lo < K < hi for lo, hi in intervals)
        if not near_end and inside != bool(good):
            raise CertificationError(
                f"k_region: at the grid gain K = {K:.12g} the delay margin says {'' if good else 'not '}admissible, "
                f"the located intervals {intervals} say the opposite"
            )
    return KRegion(
        intervals,
        delta_max,
        kb,
        grid,
        margins,
        ok,
        tol,
        tuple(pairs),
        "equations",
        rigorous,
        tuple(proven),
        tuple(unproven),
    )


def _bisection_region(
    system: Any,
    delta_max: float,
    kb: float,
    grid: NDArray,
    tol: float,
    family: Callable[[float], Any],
    executor: Any,
    max_evals: int,
    progress: bool | None,
) -> KRegion:
    """:func:`k_region` of another ``controller`` family: the grid's changes of verdict bisected to ``tol``."""
    margin_at = GainMargin(system, family, delta_max, max_evals)
    at_grid = list(mapper(executor, progress, "k_region: grid margins")(margin_at.checked, grid))
    margins, ok = _grid_verdicts(delta_max, grid, at_grid)

    def checked(K: float) -> DelayMargin:
        dm = margin_at.checked(K)
        if isinstance(dm, str):
            raise CertificationError(f"k_region: the delay margin at K = {K:.12g} failed while bisecting: {dm}")
        return dm

    def edge(good: float, bad: float, outer: DelayMargin | str | None) -> GainEnd:
        while abs(good - bad) > tol:
            mid = 0.5 * (good + bad)
            dm = checked(mid)
            if tolerates(dm, delta_max):
                good = mid
            else:
                bad, outer = mid, dm
        outer = checked(bad) if not isinstance(outer, DelayMargin) else outer
        first = outer.crossings[0] if outer.crossings else None
        omega = float("inf") if first is None else abs(first.omega)
        delay = float(outer.margin) if first is None else float(first.delays[0])
        # the first crossing is the margin's (its omega and delta*), printed to the margin's accuracies
        margins_own = first is None or (outer.omega is not None and abs(outer.omega) == omega)
        omega_accuracy = (0.0 if first is None else outer.omega_accuracy) if margins_own else None
        delay_accuracy = outer.accuracy if delay == outer.margin else None
        return GainEnd(float(good), "bisection", omega, delay, abs(good - bad), omega_accuracy, delay_accuracy)

    ends: list[tuple[GainEnd, GainEnd]] = []
    k = 0
    while k < grid.size:
        if not ok[k]:
            k += 1
            continue
        j = k
        while j + 1 < grid.size and ok[j + 1]:
            j += 1
        lo_bad, lo_outer = (grid[k - 1], at_grid[k - 1]) if k > 0 else (-kb, None)
        hi_bad, hi_outer = (grid[j + 1], at_grid[j + 1]) if j + 1 < grid.size else (kb, None)
        lo = (
            edge(grid[k], lo_bad, lo_outer)
            if lo_bad < grid[k]
            else GainEnd(float(grid[k]), "bisection", float("inf"), 0.0, None, 0.0, 0.0)
        )
        hi = (
            edge(grid[j], hi_bad, hi_outer)
            if hi_bad > grid[j]
            else GainEnd(float(grid[j]), "bisection", float("inf"), 0.0, None, 0.0, 0.0)
        )
        ends.append((lo, hi))
        k = j + 1
    intervals = tuple((lo.K, hi.K) for lo, hi in ends)
    return KRegion(intervals, delta_max, kb, grid, margins, ok, tol, tuple(ends), "bisection")


@renamed_keywords(n="n_gains")
def k_region(
    system: Any,
    delta_max: float,
    *,
    Ks: ArrayLike | None = None,
    n_gains: int = DEFAULT_N_GAINS,
    tol: float | None = None,
    controller: Callable[[float], Any] | None = None,
    executor: Any = "serial",
    max_evals: int = 2_000_000,
    progress: bool | None = None,
    rigorous: bool = False,
) -> KRegion:
    """Gains keeping the loop stable for every delay in ``[0, delta_max]``, with exact ends.

    ``U_BS2(K)`` (eq. (53)) is admissible when the nominal loop is stable and its
    delay margin exceeds ``delta_max`` (the margin is the *first* delay at which a root
    reaches the axis, so the whole of ``[0, delta_max]`` is checked). Its loop
    ``A(s) + (B_0(s) + K q e^{-tau s}) e^{-delta s}`` (eq. (60)) is affine in
    ``K``, and an end of an admissible interval is one of:

    * a *crossing*: ``A(i w) + B(i w; K) e^{-i w delta_max} = 0``, i.e. ``K(w) = -(A(i w)
      e^{i w delta_max} + B_0(i w)) / (q e^{-i w tau})`` with ``Im K(w) = 0``, solved in ``w``;
    * a *pair birth*: ``g(w; K) = |A(i w)|^2 - |B(i w; K)|^2`` has a double zero in ``w``
      (``g = dg/dw = 0``) with crossing delay ``<= delta_max``; ``g`` is quadratic in ``K``,
      its roots ``K_pm(w)`` are explicit, and the birth is an extremum of ``K_pm(w)``;
    * *nominal*: the crossing equation with ``delta = 0`` (the nominal loop loses stability);
    * the *strong-stability* limit ``|rho q| + |K q| = 1`` (the paper's bound, eq. (54)).

    A scan of the imaginary axis up to the frequency bound finds these critical gains
    (between two of them the verdict is constant), each is solved from its own equation to
    ``1e-14`` in ``w``, and each end is then verified independently: ``tol`` inside, the
    certified crossing search of :func:`~nrobust.hyperbolic.analyses.delay_margin` finds the loop admissible; ``tol``
    outside, a certified root count (:func:`nrobust.count_roots`) finds a zero in ``Re s > 0``
    about the root of the end's event, at a delay in ``[0, delta_max]``. An end that cannot be
    verified raises :class:`~nrobust.errors.CertificationError`. The grid ``Ks`` is checked the
    same way: its certified verdicts must agree with the intervals. The crossing searches of
    the scan and of the checks stop at a second-order frequency bound (the kernels' boundary
    terms, integrated by parts twice): near the paper's bound ``k`` it grows like
    ``1/sqrt(k - |K|)`` where :func:`nrobust.margins.frequency_bound` grows like
    ``1/(k - |K|)``.
    Features narrower than the scan step ``pi / (4 (2 tau + delta_max))`` in frequency can
    be missed; a verified end is exact whatever happens between ends.

    With ``rigorous=True`` each end of ``U_BS2(K)`` is also proven for the PDE: at its two
    probe gains ``end.K -+ tol`` the delay margins of the exact loop, proven in ball arithmetic
    (:func:`~nrobust.hyperbolic.analyses.delay_margin` with ``rigorous=True``), find the inner
    gain admissible and the outer one not, so that an end of the admissible set lies between
    them as a theorem (:attr:`KRegion.proven`; the end's :attr:`GainEnd.accuracy` is then the
    distance to the farther probe). An end the proofs cannot decide (a margin's ball that
    straddles ``delta_max``, a loop that is a model of the plant) stays checked in floating
    point, and :attr:`KRegion.unproven` says why. That no other end lies between two ends rests
    on the floating-point scan.

    For any other ``controller`` family the grid's changes of verdict are bisected to
    ``tol`` on delay margins instead (kind ``"bisection"``; with ``rigorous`` its ends are
    not proven, and :attr:`KRegion.unproven` says so).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant; a general plant through its normal form (a ``controller`` family then acts
        in its physical coordinates), with a varying ``lam/mu`` only with a ``controller``
        family other than U_BS2(K) (e.g. ``StateFeedback``: its loop by the characteristic
        route; the default grid then spans the strong-stability bound of ``|k|`` of
        ``U = k u(t, L)``, :func:`~nrobust.hyperbolic.classify`).
    delta_max : float
        Delay range to tolerate (``> 0``, finite).
    Ks : array_like, optional
        Gain grid on which margins are reported (and, for other families, bisected); default
        ``n_gains`` points spanning ``(-k, k)``, ``k`` the paper's bound (gains outside it
        have zero margin: the difference operator ``1 - rho q e^{-tau s} + K q
        e^{-(tau+delta) s}`` is not strongly stable).
    n_gains : int, default :data:`DEFAULT_N_GAINS`
        Size of the default grid, in ``[3, MAX_GAINS]`` (:data:`MAX_GAINS`; formerly ``n``,
        a deprecated alias). ``Ks`` may hold at most :data:`MAX_GAINS` gains too.
    tol : float, optional
        Accuracy of the interval ends (the offset of their verification); default
        ``1e-10`` times the paper's bound (``1e-4`` times it when bisecting).
    controller : callable, optional
        ``K -> controller``; default (or ``ReflectionController``) ``U_BS2(K)``, whose ends
        are solved from their equations.
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the delay margins run (:func:`nrobust.sweeps.sweep`'s executors); default in this
        process. Results are the same whatever the executor.
    max_evals : int, optional
        Work bound of each delay margin (:func:`nrobust.margins.delay_margin`) and of the
        scan of the axis.
    progress : bool, optional
        A progress bar over the delay margins on stderr; by default only when stderr is a
        terminal or Jupyter.
    rigorous : bool, default False
        Prove each end for the PDE as above (python-flint, ``pip install nrobust[rigorous]``;
        four proven delay margins per interval). Without it the ends are checked in floating
        point only, at no extra cost.

    Returns
    -------
    KRegion

    Raises
    ------
    ParameterError
        A bad argument, e.g. ``n_gains`` outside ``[3, MAX_GAINS]`` or more than
        :data:`MAX_GAINS` gains in ``Ks`` (checked before any work).
    CertificationError
        An end could not be verified (the message names its bracket), a delay margin
        failed, or the scan would exceed ``max_evals``.
    """
    if Ks is None:
        n_gains = positive_int("n_gains", n_gains, 3, MAX_GAINS)
    if not isinstance(rigorous, (bool, np.bool_)):
        raise ParameterError("rigorous", "True or False", rigorous)
    rigorous = bool(rigorous)
    given = system
    system, controller = study_plant(system, controller, "k_region")
    delta_max = positive("delta_max", delta_max)
    max_evals = positive_int("max_evals", max_evals)
    exact = controller is None or controller is ReflectionController
    kb = classify(system).k_bound
    scale = kb if kb > 0 else 1.0
    tol = positive("tol", tol) if tol is not None else (1e-10 if exact else 1e-4) * scale
    if Ks is None:
        if kb == 0.0:
            raise ParameterError("system", "with |rho q| < 1 for the default gain grid (pass Ks)", system)
        Ks = kb * np.linspace(-1.0, 1.0, n_gains + 2)[1:-1]
    grid = np.sort(real_grid("Ks", Ks))
    if grid.size > MAX_GAINS:
        raise ParameterError("Ks", f"at most MAX_GAINS = {MAX_GAINS} gains long", grid.size)
    if controller is None or controller is ReflectionController:
        plant = exact_loop_plant(given, system)
        return _exact_region(plant, delta_max, kb, grid, tol, executor, max_evals, progress, rigorous, given)
    region = _bisection_region(system, delta_max, kb, grid, tol, controller, executor, max_evals, progress)
    if not rigorous:
        return region
    why = "the ends of a controller family other than U_BS2(K) are bisected on floating-point delay margins"
    return dataclasses.replace(
        region, rigorous=True, proven=tuple((False, False) for _ in region.ends), unproven=(why,) if region.ends else ()
    )
