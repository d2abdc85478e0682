"""The decay-rate/delay-margin trade-off over the gain ``K`` (section 4.2.1): :func:`tradeoff`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._json import fields_dict
from ...errors import ParameterError
from ...roots import spectral_abscissa
from ..loops.controllers import ReflectionController, loop_factors
from ._common import mapper, real_grid, reflection, study_plant
from .margin import delay_margin
from .rouche import rouche_delay_bound

__all__ = ["Tradeoff", "tradeoff"]


@dataclass(frozen=True, eq=False)
class Tradeoff:
    """Nominal decay rate against delay margin over the gain ``K`` (section 4.2.1).

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    Ks : ndarray
        Gains.
    decay_rates : ndarray
        ``-`` spectral abscissa of the nominal loop (``delta = 0``).
    margins : ndarray
        Exact delay margins ``delta*(K)``.
    rouche_bounds : ndarray
        Guaranteed ``delta_0(K)`` of Theorem 4's proof (:func:`rouche_delay_bound`),
        ``nan`` when the controller is not ``U_BS2``.
    decay_rate_accuracies : ndarray or None
        A bound of the error of each decay rate: the :attr:`~nrobust.roots.SpectralAbscissa.accuracy`
        of its spectral abscissa (a floating-point estimate; ``nan`` where it is not known);
        None when not computed.
    """

    Ks: NDArray[np.float64]
    decay_rates: NDArray[np.float64]
    margins: NDArray[np.float64]
    rouche_bounds: NDArray[np.float64]
    decay_rate_accuracies: NDArray[np.float64] | None = None

    def __repr__(self) -> str:
        return f"Tradeoff({self.Ks.size} gains in [{self.Ks.min():.6g}, {self.Ks.max():.6g}])"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


@dataclass(frozen=True)
class _PartialTradeoff:
    """Picklable ``(K, known margin or nan) -> (decay rate, margin, delta_0, accuracy of the decay rate)``."""

    system: Any
    family: Callable[[float], Any]

    def __call__(self, point: tuple[float, float]) -> tuple[float, float, float, float]:
        K, known = point
        ctrl = self.family(float(K))
        A, B = loop_factors(self.system, ctrl)
        abscissa = spectral_abscissa(A + B)
        rate, accuracy = -float(abscissa.value), abscissa.accuracy
        margin = known if not np.isnan(known) else delay_margin(A, B, verify=False).margin
        d0 = rouche_delay_bound(self.system, ctrl).delta_0 if isinstance(ctrl, ReflectionController) else np.nan
        return rate, float(margin), float(d0), np.nan if accuracy is None else float(accuracy)


def _known_margins(margins: ArrayLike, size: int) -> NDArray[np.float64]:
    """``margins`` as ``size`` floats ``>= 0`` (``inf`` allowed, ``nan``: not known), or raise ParameterError."""
    admissible = f"{size} delay margins >= 0 (inf allowed, nan where not known), one per gain"
    try:
        raw = np.asarray(margins)
    except (TypeError, ValueError):
        raise ParameterError("margins", admissible, margins) from None
    known = raw.astype(float) if raw.dtype.kind in "iuf" else np.full(size, -1.0)  # no booleans, strings or None
    if known.shape != (size,) or np.any(known < 0):
        raise ParameterError("margins", admissible, margins)
    return known


def tradeoff(
    system: Any,
    Ks: ArrayLike,
    *,
    controller: Callable[[float], Any] | None = None,
    margins: ArrayLike | None = None,
    executor: Any = "serial",
    progress: bool | None = None,
) -> Tradeoff:
    """Decay rate of the nominal loop against the delay margin, over ``K``.

    The paper's remark after Lemma 3: ``K`` trades the convergence rate of the target
    system (reflection ``rho - K``: decay rate ``-ln|(rho - K) q| / tau`` on a transport
    system) for robustness to delays.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant; a general plant as for :func:`~nrobust.hyperbolic.analyses.stability_chart`.
    Ks : array_like
        Gains.
    controller : callable, optional
        ``K -> controller``; default ``ReflectionController``.
    margins : array_like, optional
        Delay margins ``delta*(K)`` already known at ``Ks`` (``nan`` where not known), e.g.
        the :attr:`StabilityChart.margins` of the same plant and family at these gains where they
        are at most the chart's largest delay; the others are computed.
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the grid points run (:func:`nrobust.sweeps.sweep`'s executors); default in this
        process. Results are the same whatever the executor.
    progress : bool, optional
        A progress bar over the gains on stderr; by default only when stderr is a terminal
        or Jupyter.

    Returns
    -------
    Tradeoff
    """
    system, controller = study_plant(system, controller, "tradeoff")
    kv = real_grid("Ks", Ks)
    family = reflection if controller is None else controller
    known = np.full(kv.size, np.nan) if margins is None else _known_margins(margins, kv.size)
    run = mapper(executor, progress, "tradeoff: gains")
    points = list(zip(kv.tolist(), known.tolist()))
    rows = np.array(list(run(_PartialTradeoff(system, family), points)), dtype=float).reshape(kv.size, 4)
    return Tradeoff(kv, rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3])
