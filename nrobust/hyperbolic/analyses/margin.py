"""Delay margins of a plant with a controller: the plant-level entry of the core's margin.

:func:`delay_margin` takes a plant and a controller (or the two loop factors ``A, B``),
builds the loop factors (:func:`nrobust.hyperbolic.loop_factors`, eq. (60) for
``U_BS2(K)``) and returns the margin of ``F(s; delta) = A(s) + B(s) e^{-delta s}`` computed
by :func:`nrobust.margins.delay_margin`; :func:`margin_and_decay` adds the nominal decay rate
(the default analysis of :func:`nrobust.robustness`). On the kernel route the margin and its
crossing frequency carry the model errors a convergence study in the kernel grid estimates
(:func:`~nrobust.hyperbolic.analyses.grid_study.grid_study`); :func:`studied_delay_margin`
returns the study too, or skips it (the study's own margins, sweeps over gains).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..._validate import renamed_keywords
from ...errors import ParameterError
from ...lti.allmargin import loop_delay_margin
from ...lti.delay_lti import DelayLTI
from ...lti.transfer import QuasiTransferFunction
from ...margins.margin import DelayMargin
from ...margins.margin import delay_margin as factor_delay_margin
from ...quasipoly import QuasiPolynomial
from ...roots import spectral_abscissa
from ..kernels.constant import DEFAULT_KERNEL_GRID
from ..loops.controllers import (
    CollocatedOutputFeedback,
    Controller,
    OutputFeedback,
    characteristic,
    loop_factors,
    loop_route,
    loop_scope,
    normalize,
)
from ..loops.given_plant import built_delay, to_given_plant
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from .grid_study import GridStudy, grid_study, study_scope
from .observer_accuracy import observer_model_error

__all__ = ["delay_margin", "margin_and_decay"]


def _kinds(*bases: type) -> str:
    """The public classes ``isinstance`` accepts for ``bases`` (their subclasses too), by name, for a message."""
    seen: dict[str, None] = {}
    todo = list(bases)
    while todo:
        cls = todo.pop(0)
        if not getattr(cls, "__abstractmethods__", None) and not cls.__name__.startswith("_"):
            seen[cls.__name__] = None
        todo += cls.__subclasses__()
    return ", ".join(seen)


@renamed_keywords(n="kernel_grid")
def delay_margin(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2 | QuasiPolynomial | QuasiTransferFunction | DelayLTI,
    controller: Controller | QuasiPolynomial | None = None,
    *,
    delta_max: float | None = None,
    verify: bool = True,
    max_evals: int = 2_000_000,
    kernel_grid: int | None = None,
    rigorous: bool = False,
) -> DelayMargin:
    """Delay margin and stability intervals of a plant with a controller, or of ``(A, B)``.

    Called as ``delay_margin(system, controller)``: the loop factors of
    :func:`nrobust.hyperbolic.loop_factors` (e.g. eq. (60) for
    ``U_BS2(K)``) are passed to :func:`nrobust.margins.delay_margin`; called as
    ``delay_margin(A, B)`` with two :class:`QuasiPolynomial`, it is that function; called as
    ``delay_margin(L)`` with one SISO loop transfer function (a ``QuasiTransferFunction``,
    a ``DelayLTI`` or a python-control ``TransferFunction`` or ``StateSpace``, ``L = N / D``
    under negative unit feedback), it is
    :func:`nrobust.lti.allmargin.loop_delay_margin` (``A = D``, ``B = N``).

    Parameters
    ----------
    system : Hyperbolic2x2, GeneralHyperbolic2x2, QuasiPolynomial, QuasiTransferFunction, DelayLTI or control.LTI
        The plant (a general plant through its normal form), the factor ``A`` of
        ``F(s; delta) = A(s) + B(s) e^{-delta s}``, or a SISO loop ``L`` (alone).
    controller : Controller or QuasiPolynomial, optional
        The controller of the plant, or the factor ``B`` when ``system`` is ``A``; omitted
        when ``system`` is a loop transfer function.
    delta_max, verify, max_evals, rigorous
        As in :func:`nrobust.margins.delay_margin`. ``rigorous=True`` proves the margin in
        ball arithmetic for the loop as built: for a plant with constant coefficients (and no
        ``kernel_grid``) that is the PDE itself (``N~`` in closed form with a proven error
        bound, :func:`~nrobust.hyperbolic.loops.controllers.loop_route`), as given for the
        paper's laws, filtered or not, and a proportional feedback (the ball mapped from the
        loop with ``tau`` rounded to a double,
        :func:`~nrobust.hyperbolic.loops.given_plant.to_given_plant`);
        otherwise the model, ``N~`` the cubic spline on the kernel grid (``DelayMargin.scope``
        says which).
    kernel_grid : int, optional
        Kernel grid of the delay form when called with a plant (ignored with ``A, B``;
        formerly ``n``, a deprecated alias). Default: the exact route where it applies, else
        :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID` points. On the kernel
        route the margin converges at an observed order between 1.8 and 3 in
        ``1/kernel_grid`` (``docs/margins.md``), and the margin's and the crossing frequency's
        distances to the PDE's are estimated by a convergence study on ``(kernel_grid + 3) / 4``
        and ``(kernel_grid + 1) / 2`` points (and ``2 kernel_grid - 1`` when not yet monotone):
        :attr:`~nrobust.margins.DelayMargin.model_error` and
        :attr:`~nrobust.margins.DelayMargin.omega_model_error`, floating point, not proven
        (:func:`~nrobust.hyperbolic.analyses.grid_study.grid_study`; the scope says so).

    Raises
    ------
    ParameterError
        Naming ``system`` or ``controller`` when they are neither a plant and a
        controller nor two quasi-polynomials ``A, B``.

    Returns
    -------
    DelayMargin
    """
    if controller is None and (isinstance(system, QuasiTransferFunction) or hasattr(system, "ninputs")):
        # a loop transfer function: a QuasiTransferFunction, a DelayLTI or a python-control system
        return loop_delay_margin(system, delta_max=delta_max, verify=verify, max_evals=max_evals, rigorous=rigorous)
    return studied_delay_margin(
        system,
        controller,
        delta_max=delta_max,
        verify=verify,
        max_evals=max_evals,
        kernel_grid=kernel_grid,
        rigorous=rigorous,
    )[0]


def studied_delay_margin(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2 | QuasiPolynomial | QuasiTransferFunction | DelayLTI,
    controller: Controller | QuasiPolynomial | None,
    *,
    delta_max: float | None = None,
    verify: bool = True,
    max_evals: int = 2_000_000,
    kernel_grid: int | None = None,
    rigorous: bool = False,
    study: bool = True,
) -> tuple[DelayMargin, GridStudy | None]:
    """:func:`delay_margin` of a plant and a controller (or of ``A, B``), and its convergence study.

    The study (:func:`~nrobust.hyperbolic.analyses.grid_study.grid_study`) is made on the kernel
    route only, with ``study`` (the study's own margins are computed without one); its estimates
    are the margin's ``model_error`` and ``omega_model_error``. Parameters as :func:`delay_margin`.

    Returns
    -------
    (DelayMargin, GridStudy or None)
        The margin, and the study (None when not made or when the grid is too coarse to halve).
    """
    normalized = False  # the proofs are about the normal form of a general plant
    if isinstance(system, (Hyperbolic2x2, GeneralHyperbolic2x2)):
        if not isinstance(controller, Controller):
            raise ParameterError(
                "controller",
                f"a controller ({_kinds(Controller)}) when system is a plant",
                type(controller).__name__,
            )
        if isinstance(controller, CollocatedOutputFeedback) and isinstance(system, GeneralHyperbolic2x2):
            if not system.constant_ratio:  # the collocated observer is built on the normal form
                raise ParameterError(
                    "system",
                    "a plant with a constant lam/mu for a CollocatedOutputFeedback (through its normal form)",
                    system,
                )
            normal: tuple[Hyperbolic2x2, Controller] = normalize(system, controller)
            system, controller = normal
            normalized = True
        A, B = loop_factors(system, controller, kernel_grid)
        scope = loop_scope(system, controller, kernel_grid, (A, B), normal_form=normalized)
    elif isinstance(system, QuasiPolynomial):
        if not isinstance(controller, QuasiPolynomial):
            raise ParameterError(
                "controller",
                "a QuasiPolynomial when system is one: the factors (A, B) of F(s; delta) = A(s) + B(s) e^{-delta s} "
                "are passed as (system, controller)",
                type(controller).__name__,
            )
        A, B = system, controller
        scope = ""
    else:
        raise ParameterError(
            "system",
            f"a plant ({_kinds(Hyperbolic2x2, GeneralHyperbolic2x2)}, with a controller), a QuasiPolynomial: "
            "the factor A of F(s; delta) = A(s) + B(s) e^{-delta s}, with B as controller, or a SISO loop "
            "transfer function alone (QuasiTransferFunction, DelayLTI, python-control system)",
            type(system).__name__,
        )
    plant = isinstance(system, (Hyperbolic2x2, GeneralHyperbolic2x2))
    # a proof about the plant as given: the loop as built analysed over the delays that map onto [0, delta_max]
    built = built_delay(delta_max, system, controller, kernel_grid) if plant and rigorous is True else delta_max
    result = factor_delay_margin(A, B, delta_max=built, verify=verify, max_evals=max_evals, rigorous=rigorous)
    if plant:
        result = to_given_plant(result, system, controller, kernel_grid, delta_max if built != delta_max else None)
    of_model = isinstance(system, (Hyperbolic2x2, GeneralHyperbolic2x2)) and (
        loop_route(system, controller, kernel_grid) != "exact" and not getattr(system, "uncoupled", False)
    )
    model_error = omega_model_error = None
    studied = None
    if (
        of_model
        and isinstance(system, (Hyperbolic2x2, GeneralHyperbolic2x2))
        and isinstance(controller, (OutputFeedback, CollocatedOutputFeedback))
        and loop_route(system, controller, kernel_grid) == "observer"
    ):
        model_error, omega_model_error = observer_model_error(system, controller, result, (A, B))
    if study and of_model and loop_route(system, controller, kernel_grid) == "kernels":
        given = (system, controller)

        def margin_on(grid: int) -> DelayMargin:
            return studied_delay_margin(
                *given, delta_max=delta_max, verify=verify, max_evals=max_evals, kernel_grid=grid, study=False
            )[0]

        grid = DEFAULT_KERNEL_GRID if kernel_grid is None else kernel_grid
        studied = grid_study(margin_on, grid, result)
        if studied is not None and np.isfinite(studied.estimate):
            model_error, omega_model_error = studied.estimate, studied.omega_estimate
            scope += study_scope(studied)
    if of_model:  # a ball about the loop as represented, not the PDE's: the reason says so (the scope says why)
        result = dataclasses.replace(result, reason=result.reason.replace(_PROVEN, _PROVEN + " for the model"))
    studied_margin = dataclasses.replace(
        result, scope=scope, of_model=of_model, model_error=model_error, omega_model_error=omega_model_error
    )
    return studied_margin, studied


# The words of a proven margin's reason (nrobust.margins.margin), completed on a model's loop.
_PROVEN = "(proven in ball arithmetic"


def margin_and_decay(system: Hyperbolic2x2, controller: Controller) -> dict[str, float]:
    """Delay margin and decay rate of one closed loop: the default analysis of
    :func:`nrobust.robustness`.

    Returns
    -------
    dict
        ``delta_star`` (the ``margin`` of :func:`delay_margin`; ``inf`` when every delay
        is tolerated, 0 when an arbitrarily small delay destabilises), ``abscissa``
        (spectral abscissa of the delay-free characteristic function),
        ``decay_rate = -abscissa`` and ``decay_rate_accuracy``, a bound of the error of both:
        the abscissa's :attr:`~nrobust.roots.SpectralAbscissa.accuracy` (``nan`` when not known).
    """
    margin = studied_delay_margin(system, controller, study=False)[0]  # the margin's value only
    result = spectral_abscissa(characteristic(system, controller, 0.0))
    abscissa, accuracy = float(result.value), result.accuracy
    return {
        "delta_star": float(margin.margin),
        "abscissa": abscissa,
        "decay_rate": -abscissa,
        "decay_rate_accuracy": float("nan") if accuracy is None else float(accuracy),
    }
