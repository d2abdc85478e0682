"""The registry of simulation schemes and :func:`simulate`, which picks one by the plant or by name."""

from __future__ import annotations

from typing import Any, overload

from ...errors import ParameterError
from ..nplusm.system import NPlusMSystem
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from .base import Scheme, SimulationResult
from .general import TIME_OF_FLIGHT_SCHEME
from .normal_form import CHARACTERISTICS_SCHEME, NORMAL_FORM_SCHEME, Simulation
from .nplusm import NPLUSM_SCHEME, NPlusMSimulation

__all__ = ["SCHEMES", "simulate"]

#: Scheme name -> :class:`~nrobust.hyperbolic.simulate.base.Scheme`, in the order
#: :func:`simulate` tries them on a plant (the first that accepts it runs).
SCHEMES: dict[str, Scheme] = {
    s.name: s for s in (CHARACTERISTICS_SCHEME, NORMAL_FORM_SCHEME, TIME_OF_FLIGHT_SCHEME, NPLUSM_SCHEME)
}


@overload
def simulate(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    controller: Any,
    delta: float,
    t_end: float,
    u0: Any = None,
    v0: Any = None,
    cells: int | None = None,
    *,
    scheme: str | None = None,
    **options: Any,
) -> Simulation: ...


@overload
def simulate(
    system: NPlusMSystem,
    controller: Any,
    delta: float,
    t_end: float,
    u0: Any = None,
    v0: Any = None,
    cells: int | None = None,
    *,
    scheme: str | None = None,
    **options: Any,
) -> NPlusMSimulation: ...


def simulate(
    system: Any,
    controller: Any,
    delta: float,
    t_end: float,
    u0: Any = None,
    v0: Any = None,
    cells: int | None = None,
    *,
    scheme: str | None = None,
    **options: Any,
) -> SimulationResult:
    """Simulate ``system`` under the delayed boundary feedback ``U(t - delta)`` (``U = 0`` for ``t < 0``).

    The scheme is the first of :data:`SCHEMES` that accepts the plant, or the one named by
    ``scheme``; the initial state, ``cells`` and the keyword options go to it. For the 2x2
    plants (``"characteristics"``, ``"normal form"``, ``"time-of-flight grids"``) the options
    are ``snapshot_every=None, kernels=None, kernel_grid=DEFAULT_KERNEL_GRID,
    max_updates=MAX_UPDATES`` and the result is a
    :class:`~nrobust.hyperbolic.simulate.Simulation`; for an ``n + m`` system
    (``"n+m characteristics"``) the state is one array ``w0`` (given as ``u0`` or ``w0=``),
    the option ``max_updates``, and the result an
    :class:`~nrobust.hyperbolic.simulate.NPlusMSimulation`.

    Parameters
    ----------
    system : Hyperbolic2x2, GeneralHyperbolic2x2 or NPlusMSystem
        The plant, eqs. (18)-(20) (or (1)-(3) for a ``TransportSystem``), a general 2x2
        plant in its physical coordinates, or an ``n + m`` system.
    controller : Controller, FeedbackLaw, gain or state feedback
        2x2 plants: an object with ``feedback_law(system, kernels)`` (``OpenLoop``,
        ``FiniteTimeController`` = U_BS eq. (47), ``ReflectionController(K)`` = U_BS2
        eq. (53), ``FilteredController(a, b)``) or a ``FeedbackLaw`` (a general plant with a
        varying ``lam/mu``: ``StateFeedback``, ``OpenLoop`` or a ``FeedbackLaw`` in its
        coordinates). ``n + m``: the gain ``K`` or an ``NPlusMBackstepping``.
    delta : float
        Loop delay ``>= 0``.
    t_end : float
        Final time ``> 0``; the run ends at the first sampled time ``>= t_end``.
    u0, v0 : float, callable or array_like
        The initial state of a 2x2 plant, both required: numbers (a constant state),
        callables on arrays of ``x``, or values on the nodes (``cells + 1`` for ``u``, for
        ``v`` as many as :func:`~nrobust.hyperbolic.simulate.v_nodes` returns). For an
        ``n + m`` system, ``u0`` is its state ``w0`` (a number or a callable) and ``v0`` is
        not given.
    cells : int, optional
        Cells of the grid of the fastest (2x2: the ``u``) component, ``dt = 1 / (lam cells)``
        (formerly ``n``); None: the scheme's default (2x2: ``DEFAULT_CELLS``; ``n + m``: 200).
    **options
        The scheme's own options: for the 2x2 plants ``snapshot_every`` (store the
        state every this many steps and at the end; default the final state only),
        ``kernels`` (backstepping kernels of the controller, else solved on
        ``kernel_grid`` points, formerly ``kernel_n``: the grid of every analysis, so
        that the simulated loop is the analysed one) and ``max_updates`` (bound on node
        updates). The schemes keep the deprecated keywords ``n`` (``cells``) and
        ``kernel_n`` (``kernel_grid``).
    scheme : str, optional
        A key of :data:`SCHEMES`; default: picked by the plant.

    Returns
    -------
    SimulationResult
        ``times``, ``norm`` and the scheme's own fields.

    Raises
    ------
    ParameterError
        An unknown scheme, a plant no scheme (or not the named one) takes, or the scheme's
        own errors (bad input, a work bound exceeded, an ill-posed boundary loop).

    Notes
    -----
    ``lam == mu``: characteristic lattice, exact transport, trapezoidal couplings at the
    crossings. ``lam != mu``: one grid per direction (steps ``lam dt`` and ``mu dt``),
    advanced in half steps by exact index shifts, Heun couplings with cubic cross-grid
    interpolation, and a partial last cell at ``x = 0`` for ``v`` when ``1/(mu dt)`` is
    not an integer. A general plant with a constant ``lam/mu`` runs through its normal
    form, with a varying one on its time-of-flight grids. See ``docs/simulation.md``.

    Examples
    --------
    >>> sorted(SCHEMES)
    ['characteristics', 'n+m characteristics', 'normal form', 'time-of-flight grids']
    """
    if scheme is None:
        chosen = next((s for s in SCHEMES.values() if s.accepts(system)), None)
        if chosen is None:
            takes = "; ".join(f"{s.name}: {', '.join(p.__name__ for p in s.plants)}" for s in SCHEMES.values())
            raise ParameterError("system", f"a plant one of the schemes takes ({takes})", system)
    else:
        if scheme not in SCHEMES:
            raise ParameterError("scheme", f"one of {sorted(SCHEMES)}", scheme)
        chosen = SCHEMES[scheme]
        if not chosen.accepts(system):
            raise ParameterError("system", f"a plant the scheme {scheme!r} takes ({chosen.description})", system)
    if cells is not None:
        options["cells"] = cells
    return chosen.run(system, controller, delta, t_end, u0, v0, **options)
