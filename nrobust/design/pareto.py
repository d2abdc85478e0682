"""The trade-off of decay rate against delay margin as a front of certified designs.

For required margins ``d_1 < d_2 < ...``, the best decay rate of a loop family subject to
``delta* >= d_j`` (:func:`~nrobust.design.local.optimize_loop`, each design warm-started from
the previous one), so the front is the paper's trade-off (its conclusion: robustness to delays
is bought with decay rate) computed over every parameter of the family at once. Each point is
certified; each is a local optimum.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._json import json_safe
from .._validate import real_array
from ..errors import CertificationError, ParameterError
from .local import LoopDesign, ParametricLoop, optimize_loop

__all__ = ["ParetoFront", "pareto_front"]


@dataclass(frozen=True)
class ParetoFront:
    """Decay rate against required delay margin, one certified local design per requirement.

    Attributes
    ----------
    required : ndarray
        The required margins ``d_j`` (ascending) that a design was found for.
    decay_rates : ndarray
        The best decay rate found under each requirement (``-alpha`` at ``delta = 0``).
    margins : ndarray
        The delay margin of each design (at least its requirement).
    designs : tuple of LoopDesign
        The designs (parameters, certificates, runs).
    infeasible : tuple of float
        Requirements no start could meet (left out of the front).
    """

    required: NDArray[np.float64]
    decay_rates: NDArray[np.float64]
    margins: NDArray[np.float64]
    designs: tuple[LoopDesign, ...]
    infeasible: tuple[float, ...] = ()

    @property
    def certified(self) -> bool:
        """True if every design of the front is certified."""
        return all(d.certified for d in self.designs)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return json_safe(
            {
                "required": self.required,
                "decay_rates": self.decay_rates,
                "margins": self.margins,
                "parameters": [d.parameters for d in self.designs],
                "certified": [d.certified for d in self.designs],
                "infeasible": self.infeasible,
            }
        )


def pareto_front(
    loop: ParametricLoop,
    bounds: ArrayLike,
    required: ArrayLike,
    *,
    x0: ArrayLike | None = None,
    starts: int = 1,
    max_iter: int = 60,
    rigorous: bool = False,
    map: Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]] = map,
) -> ParetoFront:
    """The best certified decay rate of ``loop`` under each required delay margin.

    Parameters
    ----------
    loop, bounds, x0, starts, max_iter, rigorous, map
        As in :func:`~nrobust.design.local.optimize_loop`; the design of each requirement starts
        from the previous design (and ``starts - 1`` Halton points).
    required : sequence of float
        Required delay margins, at least 0 (sorted here).

    Returns
    -------
    ParetoFront
    """
    d = np.sort(real_array("required", required, ndim=1, min_size=1))
    if np.any(d < 0.0):
        raise ParameterError("required", "delay margins >= 0", required)
    designs: list[LoopDesign] = []
    missed: list[float] = []
    start = x0
    for req in d:
        try:
            design = optimize_loop(
                loop,
                bounds,
                margin_at_least=float(req),
                x0=start,
                starts=starts,
                max_iter=max_iter,
                rigorous=rigorous,
                map=map,
            )
        except CertificationError:
            missed.append(float(req))
            continue
        designs.append(design)
        start = design.parameters
    done = [float(x) for x in d if float(x) not in missed]
    return ParetoFront(
        np.array(done),
        np.array([x.decay_rate for x in designs]),
        np.array([x.margin.margin for x in designs]),
        tuple(designs),
        tuple(missed),
    )
