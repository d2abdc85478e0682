"""The trade-off of decay rate against delay margin as a front of certified designs.

For required margins ``d_1 < d_2 < ...``, the best decay rate of a loop family subject to
``delta* >= d_j`` (:func:`~nrobust.design.local.optimize_loop`, each design warm-started from
the previous one), so the front is the paper's trade-off (its conclusion: robustness to delays
is bought with decay rate) computed over every parameter of the family at once. Each point is
certified; each is a local optimum.

Further requirements hold at every point: windows of delays ``[d_min, d_max]`` on which the loop
must be exponentially stable too (``delays``), and further loops of the same parameters
(``scenarios``: e.g. the loop on plants with mismatched speeds) held to every requirement of the
loop: stable for every delay in ``[0, d_j]`` and in each window. The requirement of a point is then
stability on a union of closed intervals of delays (``[0, d_j]`` merged with the windows), which
:func:`~nrobust.design.local.optimize_loop` takes as it is (``margin_at_least = d_j`` with the
windows and the scenarios) and certifies requirement by requirement
(:attr:`~nrobust.design.local.LoopDesign.windows`, :func:`~nrobust.design.window_stability`).
With ``worst_case`` each point maximises the least decay rate of the loop and the scenarios instead of the
loop's own (``optimize_loop(..., worst_case=True)``), and the front is that least rate against the margin.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._digits import with_accuracy
from .._json import json_safe
from .._validate import callables, real_array
from ..errors import CertificationError, ParameterError
from ..roots import SpectralAbscissa
from .gain import DelayWindow
from .local import LoopDesign, ParametricLoop, check_windows, optimize_loop

__all__ = ["ParetoFront", "pareto_front"]

_Windows = tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class ParetoFront:
    """Decay rate against required delay margin, one certified local design per requirement.

    Drawn by :func:`nrobust.plots.pareto_plot`; as data with ``.plot()``,
    :class:`nrobust.plots.ParetoResponse` wraps it (``ParetoResponse(front).plot()``): the core computes
    and draws nothing, so the front itself has no ``plot`` method.

    Attributes
    ----------
    required : ndarray
        The required margins ``d_j`` (ascending) that a design was found for.
    decay_rates : ndarray
        The best decay rate found under each requirement (``-alpha`` at ``delta = 0``; negative
        when ``d_j = 0`` and a window ``d_min > 0`` lets the loop be unstable without delay). With
        :attr:`worst_case`, the least decay rate at ``delta = 0`` of the loop and the scenarios (each
        design's ``value``, or with :attr:`scenario_abscissae` the least of ``design.abscissa``'s and
        theirs; ``design.decay_rate`` is the loop's own); :attr:`objective_text` says which.
    margins : ndarray
        The delay margin of each design (at least its requirement).
    designs : tuple of LoopDesign
        The designs (parameters, certificates, runs).
    infeasible : tuple of float
        Requirements no start could meet, or whose design could not be certified (left out of
        the front).
    delays : tuple of (float, float)
        The windows ``[d_min, d_max]`` of delays on which every design is stable too (empty: none).
    scenarios : tuple of str
        The names of the further loops held to every requirement of each point (empty: none).
    windows : tuple
        For each design, for the loop and then each scenario, the certificates
        (:class:`~nrobust.design.DelayWindow`, :func:`~nrobust.design.window_stability`) of its
        requirement: a scenario's ``[0, d_j]`` first (when ``d_j > 0``; the loop's margin is
        its design's, checked against ``d_j``), then each window of :attr:`delays`. Empty tuples without
        ``delays`` and ``scenarios``.
    worst_case : bool
        True if each point maximises the least decay rate of the loop and the scenarios
        (:func:`pareto_front`'s ``worst_case``), False if the loop's own.
    scenario_abscissae : tuple of tuple of SpectralAbscissa
        With :attr:`worst_case`, for each design the scenarios' abscissae at ``delta = 0`` restated by a caller
        that knows what the scenarios' loops model (with their ``model_error``), in the order of the scenarios;
        :attr:`decay_rates` and the certificates use them instead of ``design.scenario_abscissae``. Empty: the
        designs' own.
    """

    required: NDArray[np.float64]
    decay_rates: NDArray[np.float64]
    margins: NDArray[np.float64]
    designs: tuple[LoopDesign, ...]
    infeasible: tuple[float, ...] = ()
    delays: _Windows = ()
    scenarios: tuple[str, ...] = ()
    windows: tuple[tuple[tuple[DelayWindow, ...], ...], ...] = field(default=(), repr=False)
    worst_case: bool = False
    scenario_abscissae: tuple[tuple[SpectralAbscissa, ...], ...] = field(default=(), repr=False)

    def _others(self, n: int) -> tuple[SpectralAbscissa, ...]:
        """The scenarios' abscissae of design ``n`` that its rate is the least with (empty without worst_case)."""
        if self.scenario_abscissae:
            return self.scenario_abscissae[n]
        return self.designs[n].scenario_abscissae

    @property
    def objective_text(self) -> str:
        """What :attr:`decay_rates` are, in words."""
        if not self.worst_case:
            return "the loop's decay rate at delta = 0"
        n = len(self.scenarios)
        return f"the least decay rate at delta = 0 of the loop and the {n} scenario{'s' if n > 1 else ''}"

    @property
    def decay_rate_accuracies(self) -> tuple[float | None, ...]:
        """For each point, a bound of the error of its entry of :attr:`decay_rates`: its abscissa's accuracy (with
        :attr:`worst_case`, the largest of the loop's and the scenarios': the least of values each within ``a_j``
        of its true one is within ``max_j a_j`` of the true least); None when one is not estimated."""
        out: list[float | None] = []
        for n, design in enumerate(self.designs):
            accuracies = [a.accuracy for a in (design.abscissa, *self._others(n))]
            known = [float(a) for a in accuracies if a is not None]
            out.append(max(known) if len(known) == len(accuracies) else None)
        return tuple(out)

    @property
    def points_certified(self) -> tuple[bool, ...]:
        """For each design: certified (:attr:`LoopDesign.certified`) and every window of :attr:`windows`
        certified stable (proven in ball arithmetic when the design is ``rigorous``)."""
        out = []
        for n, design in enumerate(self.designs):
            certs = [w for loop in (self.windows[n] if self.windows else ()) for w in loop]
            proven = not design.rigorous or all(w.certified == "proven" for w in certs)
            rates = all(a.certified for a in self._others(n)) if self.worst_case else True
            out.append(bool(design.certified and proven and rates and all(w.stable for w in certs)))
        return tuple(out)

    @property
    def certified(self) -> bool:
        """True if every design of the front is certified, with every requirement (and with :attr:`worst_case`
        every scenario's abscissa its rate is the least with)."""
        return all(self.points_certified)

    @property
    def requirement(self) -> str:
        """The requirements of each point in words (``d`` its required margin)."""
        parts = ["the loop's delay margin >= d"]
        if self.scenarios:
            n = len(self.scenarios)
            parts.append(
                f"{n} scenario{'s' if n > 1 else ''} ({', '.join(self.scenarios)}) stable for every delay in [0, d] "
                "when d > 0"
            )
        if self.delays:
            who = "the loop and the scenarios" if self.scenarios else "the loop"
            parts.append(f"{who} stable for every delay in " + " and ".join(f"[{a!r}, {b!r}]" for a, b in self.delays))
        return "; ".join(parts)

    def __repr__(self) -> str:
        rates = ", ".join(with_accuracy(float(r), a) for r, a in zip(self.decay_rates, self.decay_rate_accuracies))
        n = len(self.scenarios)
        least = f" (least of the loop and {n} scenario{'s' if n > 1 else ''})" if self.worst_case else ""
        parts = [
            f"required={[float(d) for d in self.required]}",
            f"decay_rates=[{rates}]{least}",
            f"infeasible={list(self.infeasible)}",
        ]
        if self.delays:
            parts.append(f"delays={[list(w) for w in self.delays]}")
        if self.scenarios:
            parts.append(f"scenarios={list(self.scenarios)}")
        parts.append(f"certified={self.certified}")
        return f"ParetoFront({', '.join(parts)})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (each window certificate as its dictionary)."""
        return json_safe(
            {
                "required": self.required,
                "decay_rates": self.decay_rates,
                "decay_rate_accuracies": self.decay_rate_accuracies,
                "worst_case": self.worst_case,
                "objective": self.objective_text,
                "nominal_decay_rates": [d.decay_rate for d in self.designs],
                "margins": self.margins,
                "parameters": [d.parameters for d in self.designs],
                "certified": list(self.points_certified),
                "infeasible": self.infeasible,
                "delays": self.delays,
                "scenarios": self.scenarios,
                "windows": [[[w.to_dict() for w in loop] for loop in point] for point in self.windows],
                "requirement": self.requirement,
            }
        )


def pareto_front(
    loop: ParametricLoop,
    bounds: ArrayLike,
    required: ArrayLike,
    *,
    delays: tuple[float, float] | Sequence[tuple[float, float]] | None = None,
    scenarios: Sequence[ParametricLoop] | Mapping[str, ParametricLoop] = (),
    worst_case: bool = False,
    x0: ArrayLike | None = None,
    starts: int = 1,
    max_iter: int = 60,
    rigorous: bool = False,
    map: Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]] = map,
) -> ParetoFront:
    """The best certified decay rate of ``loop`` under each required delay margin.

    Without ``delays`` and ``scenarios`` each point is :func:`~nrobust.design.local.optimize_loop`
    under ``margin_at_least = d_j``. With them, each point requires exponential stability of the
    loop for every delay in ``[0, d_j]`` (``delta* > d_j``) and in each window of ``delays``, and of
    every scenario likewise (:func:`~nrobust.design.local.optimize_loop` with ``margin_at_least =
    d_j``, the windows and the scenarios); each design found is certified requirement by requirement
    (:attr:`ParetoFront.windows`). A point whose requirements no start meets, or whose design is not
    certified, is left in :attr:`ParetoFront.infeasible`. With ``worst_case`` each point maximises the least
    decay rate at ``delta = 0`` of the loop and the scenarios (``optimize_loop(..., worst_case=True)``), and
    :attr:`ParetoFront.decay_rates` are those least rates (each design's ``value``), certified with every
    scenario's abscissa (``design.scenario_abscissae``).

    Parameters
    ----------
    loop, bounds, x0, starts, max_iter, rigorous, map
        As in :func:`~nrobust.design.local.optimize_loop`; the design of each requirement starts
        from the previous design (and ``starts - 1`` Halton points).
    required : sequence of float
        Required delay margins, at least 0 (sorted here); each ``> 0`` with ``scenarios`` unless
        ``delays`` is given.
    delays : (float, float) or sequence of (float, float), optional
        Windows ``[d_min, d_max]`` (``0 <= d_min <= d_max``, ``d_max > 0``; ``d_min = d_max``: one
        delay) on which every design must be exponentially stable too (``d_min > 0``: not
        necessarily in between).
    scenarios : sequence or mapping of callable, optional
        Further loop families ``p -> (A, B)`` of the same parameters held to every requirement of
        the loop (a mapping gives them names; else ``"scenario 0"``, ...), each a pair of
        :class:`~nrobust.quasipoly.QuasiPolynomial`.
    worst_case : bool
        Maximise at each point the least decay rate of the loop and the ``scenarios`` (as
        :func:`~nrobust.design.local.optimize_loop`'s ``worst_case``) instead of the loop's own; only with
        ``scenarios``.

    Returns
    -------
    ParetoFront

    Raises
    ------
    ParameterError
        For bad input: ``required`` negative (or 0 with ``scenarios`` and no ``delays``), ``delays``
        not windows (:func:`~nrobust.design.local.check_windows`), a scenario not callable, ``worst_case``
        True without ``scenarios`` or not a bool; as
        :func:`~nrobust.design.local.optimize_loop` for the rest.
    """
    d = np.sort(real_array("required", required, ndim=1, min_size=1))
    if np.any(d < 0.0):
        raise ParameterError("required", "delay margins >= 0", required)
    windows = check_windows(delays)
    named = dict(scenarios) if isinstance(scenarios, Mapping) else None
    others = callables(
        "scenarios",
        scenarios if named is None else list(named.values()),
        "a sequence or mapping of callables p -> (A, B)",
        "a callable p -> (A, B)",
    )
    names = tuple(str(k) for k in named) if named is not None else tuple(f"scenario {n}" for n in range(len(others)))
    if not isinstance(worst_case, (bool, np.bool_)):
        raise ParameterError("worst_case", "True or False", worst_case)
    if worst_case and not others:
        raise ParameterError("worst_case", "False without scenarios (the least rate is over the loop and them)", True)
    if others and not windows and np.any(d == 0.0):
        raise ParameterError(
            "required",
            "delay margins > 0 with scenarios and no delays (each scenario is held to stability on [0, d])",
            required,
        )
    designs: list[LoopDesign] = []
    certs: list[tuple[tuple[DelayWindow, ...], ...]] = []
    missed: list[float] = []
    start = x0
    for req in (float(x) for x in d):
        try:
            design = optimize_loop(
                loop,
                bounds,
                margin_at_least=req if req > 0.0 or not windows else None,
                delays=windows or None,
                scenarios=others,
                worst_case=bool(worst_case),
                x0=start,
                starts=starts,
                max_iter=max_iter,
                rigorous=rigorous,
                map=map,
            )
        except CertificationError:
            missed.append(req)
            continue
        dm = design.margin
        if not (dm.margin_ball[0] if (rigorous and dm.margin_ball is not None) else dm.margin) >= req:
            missed.append(req)  # the certified margin below the requirement: no point of the front
            continue
        designs.append(design)
        if windows or others:
            certs.append(design.loop_windows)
        start = design.parameters
    done = [float(x) for x in d if float(x) not in missed]
    return ParetoFront(
        np.array(done),
        np.array([x.value for x in designs]),
        np.array([x.margin.margin for x in designs]),
        tuple(designs),
        tuple(missed),
        windows,
        names,
        tuple(certs),
        bool(worst_case),
    )
