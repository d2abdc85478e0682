"""What the gain studies share: the executor's ``map``, the plant and gain family a study
runs on, the grids, and the picklable delay margin of one gain.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._digits import with_accuracy
from ..._progress import progress_bar
from ..._validate import is_real_number, real_array
from ...errors import CertificationError, ParameterError
from ...margins.margin import DelayMargin
from ...roots import SpectralAbscissa
from ...sweeps.executors import sweep_map
from ..loops.controllers import ReflectionController, StateFeedback, loop_route
from ..nplusm.margin import smallest_delay_error
from ..plants.general import GeneralHyperbolic2x2, NormalForm
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from .margin import studied_delay_margin

__all__ = [
    "CornerRates",
    "GainMargin",
    "OnNormalForm",
    "check_system",
    "exact_loop_plant",
    "mapper",
    "real_grid",
    "reflection",
    "study_plant",
]


class CornerRates:
    """The decay rates a 2x2 design under a speed tolerance guarantees (a mixin of the design results).

    The class sets ``corner_abscissae`` (the abscissae at ``delta = 0`` at the corners of the square of speed
    errors, in the order of ``tolerance.points[:4]``; empty without them) and ``design.abscissa`` (the nominal
    plant's).
    """

    corner_abscissae: tuple[SpectralAbscissa, ...]
    design: Any

    @property
    def corner_decay_rates(self) -> tuple[float, ...]:
        """The decay rate ``-alpha`` at ``delta = 0`` at each corner of the speed tolerance (empty without them)."""
        return tuple(float(-a.value) for a in self.corner_abscissae)

    @property
    def worst_decay_rate(self) -> float:
        """The least decay rate at ``delta = 0`` of the nominal plant and the corners of the speed tolerance
        (the nominal ``design.abscissa``'s without them)."""
        return float(min(-a.value for a in (self.design.abscissa, *self.corner_abscissae)))

    @property
    def worst_decay_rate_accuracy(self) -> float | None:
        """A bound of the error of :attr:`worst_decay_rate`: the abscissae's accuracies combined by
        :func:`~nrobust.hyperbolic.nplusm.margin.smallest_delay_error` (None when one is not estimated)."""
        abscissae = (self.design.abscissa, *self.corner_abscissae)
        return smallest_delay_error([-a.value for a in abscissae], [a.accuracy for a in abscissae])

    def worst_text(self) -> str:
        """``", worst_decay_rate=... (nominal and 4 corners)"`` to its accuracy for a repr; empty without
        corners."""
        if not self.corner_abscissae:
            return ""
        text = with_accuracy(self.worst_decay_rate, self.worst_decay_rate_accuracy)
        return f", worst_decay_rate={text} (nominal and {len(self.corner_abscissae)} corners)"

    def corner_dict(self) -> dict[str, Any]:
        """The corners' rates, the least and its accuracy for ``to_dict()`` (empty without corners)."""
        if not self.corner_abscissae:
            return {}
        return {
            "corner_decay_rates": list(self.corner_decay_rates),
            "worst_decay_rate": self.worst_decay_rate,
            "worst_decay_rate_accuracy": self.worst_decay_rate_accuracy,
        }


def mapper(
    executor: Any, progress: bool | None = None, desc: str = ""
) -> Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]]:
    """A ``map`` in this process (with a progress bar), else the executors' (:func:`~nrobust.sweep_map`).

    The bar follows :func:`nrobust._progress.show_progress`: drawn when ``progress`` is True,
    or for None when stderr is a terminal or Jupyter.
    """
    if not (isinstance(executor, str) and executor == "serial"):
        return sweep_map(executor, progress=progress)

    def serial(func: Callable[[Any], Any], items: Iterable[Any]) -> Iterator[Any]:
        todo = list(items)
        with progress_bar(len(todo), progress, desc) as bar:
            for item in todo:
                yield func(item)
                bar.update(1)

    return serial


def reflection(K: float) -> ReflectionController:
    """``U_BS2(K)``: the default gain family of the studies (module level: picklable)."""
    return ReflectionController(K)


def check_system(system: Any) -> None:
    """Raise :class:`~nrobust.errors.ParameterError` unless ``system`` is a 2x2 plant whose loop depends on ``K``."""
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2, TransportSystem or GeneralHyperbolic2x2", system)
    if system.q == 0:
        raise ParameterError("system.q", "non-zero (otherwise the loop does not depend on K)", system.q)


@dataclass(frozen=True)
class OnNormalForm:
    """Picklable ``K -> family(K)`` acting on the normal form of a general plant.

    A :class:`~nrobust.hyperbolic.loops.StateFeedback` has its gains mapped from the
    physical coordinates (:meth:`~nrobust.hyperbolic.plants.NormalForm.feedback_to_normal`);
    the paper's controllers are defined on the normal form and pass unchanged.
    """

    form: NormalForm
    family: Callable[[float], Any]

    def __call__(self, K: float) -> Any:
        ctrl = self.family(K)
        if isinstance(ctrl, StateFeedback):
            return StateFeedback(*self.form.feedback_to_normal(ctrl.k, ctrl.g_u, ctrl.g_v))
        return ctrl


def study_plant(
    system: Any, family: Callable[[float], Any] | None, study: str
) -> tuple[Any, Callable[[float], Any] | None]:
    """The plant and gain family a study runs on.

    A general plant with a constant ``lam/mu`` is replaced by its normal form (once: its
    kernels are then shared by every gain) and a custom ``family`` mapped onto it
    (:class:`OnNormalForm`). With a varying ``lam/mu`` the plant stays as it is (loop
    factors by the characteristic route), which needs a ``family`` other than U_BS2(K),
    a normal-form controller.
    """
    if isinstance(system, GeneralHyperbolic2x2):
        if system.constant_ratio:
            form = system.normal_form()
            if family is None or family is ReflectionController:
                return form.system, None
            return form.system, OnNormalForm(form, family)
        if family is None or family is ReflectionController:
            raise ParameterError(
                "controller",
                f"a gain family K -> controller (e.g. StateFeedback) for {study} of a plant with a varying lam/mu: "
                "U_BS2(K) is defined on the normal form, which needs a constant lam/mu",
                family,
            )
        return system, family
    check_system(system)
    return system, family


def exact_loop_plant(system: Any, plant: Any) -> Any:
    """The plant whose U_BS2(K) loops a study builds: ``system`` itself where it is a general plant whose own loop is
    exact (coefficients given as functions: the varying-coefficient proof of
    :mod:`~nrobust.hyperbolic.loops.varying_proof`) while that of ``plant``, its normal form with tabulated couplings,
    is a model; else ``plant``. The gains and their accuracies are then those of the plant as given, not of the
    model's kernels (on ``lam = mu = 1`` given as functions the model's kink missed the plant's by 9.5e-12 while
    printing ``+- 3e-13``)."""
    if (
        isinstance(system, GeneralHyperbolic2x2)
        and plant is not system
        and loop_route(plant, ReflectionController(0.0), None) != "exact"
        and loop_route(system, ReflectionController(0.0), None) == "exact"
    ):
        return system
    return plant


def real_grid(name: str, values: ArrayLike) -> NDArray[np.float64]:
    """A non-empty 1-D grid of finite reals (a number is a grid of one); booleans and strings are refused."""
    return real_array(name, [values] if is_real_number(values) else values)


@dataclass(frozen=True)
class GainMargin:
    """Picklable ``K -> delay_margin(system, family(K), delta_max=delta_max, verify=False)``.

    The one delay margin of a gain that the studies map over their grids (:meth:`checked`
    returns the message of a :class:`~nrobust.errors.CertificationError` instead of raising).
    """

    system: Any
    family: Callable[[float], Any]
    delta_max: float | None
    max_evals: int = 2_000_000

    def __call__(self, K: float) -> DelayMargin:
        return studied_delay_margin(  # a sweep: no convergence study per gain
            self.system,
            self.family(float(K)),
            delta_max=self.delta_max,
            verify=False,
            max_evals=self.max_evals,
            study=False,
        )[0]

    def checked(self, K: float) -> DelayMargin | str:
        """The margin at ``K``, or the message of its CertificationError."""
        try:
            return self(K)
        except CertificationError as exc:
            return str(exc)
