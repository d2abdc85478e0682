"""Time-domain simulation of the plant (18)-(20) with a delayed boundary control.

The closed loop simulated is::

    u_t + lam u_x = sigma_pm(x) v,      u(t, 0) = q v(t, 0),
    v_t - mu  v_x = sigma_mp(x) u,      v(t, 1) = rho u(t, 1) + U(t - delta),

with ``U(t) = 0`` for ``t < 0`` and ``U`` given by a state feedback
(:class:`~nrobust.hyperbolic.loops.controllers.FeedbackLaw`): U_BS (eq. (47)),
U_BS2(K) (eq. (53)), their filtered versions (section 2.3.2) or any law of the form
``boundary_gain * u(t, 1) + int_0^1 gain_u u + gain_v v dxi``.

The marching itself (one characteristic lattice for equal speeds, two characteristic grids
otherwise) is in :mod:`.characteristics`; this module sets the grids, the initial state and
the feedback law up, and registers the schemes ``"characteristics"`` (the paper's plant) and
``"normal form"`` (a general plant with a constant ``lam/mu``, through its normal form) of
:func:`~nrobust.hyperbolic.simulate.simulate`. See ``docs/simulation.md``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._json import fields_dict
from ..._validate import nonnegative, positive, positive_int, renamed_keywords
from ...errors import ParameterError
from ..kernels.constant import DEFAULT_KERNEL_GRID, check_kernel_grid, solve_kernels
from ..loops.controllers import Controller, StateFeedback
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from .base import Scheme, SimulationResult, initial_state
from .characteristics import Loop, Recorder, march_lattice, march_two_grids, trapezoid_weights, v_grid

__all__ = [
    "CHARACTERISTICS_SCHEME",
    "DEFAULT_CELLS",
    "MAX_UPDATES",
    "NORMAL_FORM_SCHEME",
    "InitialState",
    "Simulation",
    "simulate_characteristics",
    "simulate_normal_form",
    "simulate_runs",
    "v_nodes",
]

Array = NDArray[np.float64]
InitialState = Callable[[Array], Any] | Array | float

#: Default number of cells of the ``u`` grid (``dt = 1 / (lam cells)``): the grid of the
#: paper's figures, 0.1-0.4 s per run of the paper's example to ``t = 10``
#: (``docs/simulation.md``).
DEFAULT_CELLS = 400
#: Default bound on the number of node updates (nodes times steps).
MAX_UPDATES = 2 * 10**9


@dataclass(frozen=True, repr=False, eq=False)
class Simulation(SimulationResult):
    """Result of :func:`~nrobust.hyperbolic.simulate.simulate` on a 2x2 plant (a :class:`SimulationResult`).

    Attributes
    ----------
    times : ndarray, shape (m + 1,)
        Sampled times ``t_j = j dt``.
    norm : ndarray, shape (m + 1,)
        ``||(u, v)(t_j)||_{L2} = sqrt(int_0^1 u^2 + v^2 dx)`` (trapezoidal rule).
    control : ndarray, shape (m + 1,)
        The controller output ``U(t_j)``; the plant receives ``U(t_j - delta)``.
    x : ndarray, shape (n + 1,)
        Nodes ``k / n`` of ``u``.
    x_v : ndarray
        Nodes of ``v`` (``x`` itself when ``lam == mu``; see :func:`v_nodes`).
    snapshot_times : ndarray, shape (k,)
        Times of the stored states.
    u, v : ndarray, shapes (k, x.size) and (k, x_v.size)
        States at ``snapshot_times``.
    delta : float
        Loop delay.
    dt : float
        Sampling step ``1 / (lam n)`` (the lattice advances in half steps).
    n : int
        Number of cells.
    delay_interpolation : str
        ``"exact shift"`` when ``delta`` is a multiple of ``dt`` (or zero), otherwise
        ``"Lagrange-4"`` (``"linear"`` on the time-of-flight grids).
    scheme : str
        ``"characteristic lattice"`` (``lam == mu``), ``"two characteristic grids"``, or
        ``"time-of-flight grids"`` (a general plant with a varying ``lam/mu``).
    """

    control: Array
    x: Array
    x_v: Array
    snapshot_times: Array
    u: Array
    v: Array
    delta: float
    dt: float
    n: int
    delay_interpolation: str
    scheme: str

    def __repr__(self) -> str:
        return (
            f"Simulation(n={self.n}, dt={self.dt:.3g}, delta={self.delta!r}, "
            f"t_end={self.times[-1]:.6g}, final_norm={self.norm[-1]:.3e}, "
            f"snapshots={self.snapshot_times.size}, delay_interpolation={self.delay_interpolation!r}, "
            f"scheme={self.scheme!r})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (lists of floats; an overflowed state as ``"inf"``/``"nan"``)."""
        return {"type": "Simulation", **fields_dict(self)}


def _feedback_law(system: Hyperbolic2x2, controller: Any, kernels: Any, kernel_grid: int) -> Any:
    """The :class:`~nrobust.hyperbolic.plants.FeedbackLaw` of ``controller`` (itself if it already is one)."""
    if hasattr(controller, "boundary_gain") and hasattr(controller, "gain_u"):
        return controller
    if not callable(getattr(controller, "feedback_law", None)):
        raise ParameterError(
            "controller",
            "a controller (OpenLoop, FiniteTimeController, ReflectionController, FilteredController, StateFeedback, "
            "OutputFeedback, CollocatedOutputFeedback), a FeedbackLaw, or an object with feedback_law(system, kernels)",
            controller,
        )
    if kernels is None and not system.uncoupled:
        kernels = solve_kernels(system, kernel_grid)
    return controller.feedback_law(system, kernels)


def _gain_values(name: str, gain: Callable[[Array], Any], x: Array) -> Array:
    out = np.asarray(gain(x), dtype=float)
    if out.shape == ():
        out = np.full(x.shape, float(out))
    if out.shape != x.shape or not np.all(np.isfinite(out)):
        raise ParameterError(name, "a callable returning finite values on arrays of xi in [0, 1]", gain)
    return out


@renamed_keywords(n="cells", kernel_n="kernel_grid")
def simulate_characteristics(
    system: Hyperbolic2x2,
    controller: Any,
    delta: float,
    t_end: float,
    u0: InitialState,
    v0: InitialState,
    cells: int = DEFAULT_CELLS,
    *,
    snapshot_every: int | None = None,
    kernels: Any = None,
    kernel_grid: int = DEFAULT_KERNEL_GRID,
    max_updates: int = MAX_UPDATES,
) -> Simulation:
    """The scheme ``"characteristics"``: the paper's plant (18)-(20) along its characteristics.

    ``lam == mu``: the characteristic lattice; otherwise two characteristic grids
    (:mod:`.characteristics`). The parameters are those of
    :func:`~nrobust.hyperbolic.simulate.simulate`; ``kernel_grid`` (default
    :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID`, as every analysis) is the grid
    of the kernels solved for ``controller`` when ``kernels`` is not given.
    """
    return _simulate(system, controller, delta, t_end, u0, v0, cells, snapshot_every, kernels, kernel_grid, max_updates)


def _simulate(
    system: Hyperbolic2x2,
    controller: Any,
    delta: float,
    t_end: float,
    u0: InitialState,
    v0: InitialState,
    cells: int,
    snapshot_every: int | None,
    kernels: Any,
    kernel_grid: int,
    max_updates: int,
    norm_weights: tuple[Callable[[Array], Array], Callable[[Array], Array]] | None = None,
) -> Simulation:
    """The paper's plant along its characteristics; ``norm_weights`` (of the nodes) weight ``u^2``, ``v^2``."""
    return _simulate_runs(
        system,
        [(controller, delta)],
        t_end,
        u0,
        v0,
        cells,
        snapshot_every,
        kernels,
        kernel_grid,
        max_updates,
        norm_weights,
    )[0]


def _simulate_runs(
    system: Hyperbolic2x2,
    runs: Sequence[tuple[Any, float]],
    t_end: float,
    u0: InitialState,
    v0: InitialState,
    cells: int,
    snapshot_every: int | None,
    kernels: Any,
    kernel_grid: int,
    max_updates: int,
    norm_weights: tuple[Callable[[Array], Array], Callable[[Array], Array]] | None = None,
) -> list[Simulation]:
    """:func:`_simulate` for each ``(controller, delta)`` of ``runs``; on a lattice the runs march together."""
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem", system)
    deltas = [nonnegative("delta", delta) for _, delta in runs]
    t_end = positive("t_end", t_end)
    n = positive_int("cells", cells, minimum=2)
    kernel_grid = check_kernel_grid(kernel_grid)
    if snapshot_every is not None:
        snapshot_every = positive_int("snapshot_every", snapshot_every)
    max_updates = positive_int("max_updates", max_updates)

    lattice = abs(system.mu - system.lam) <= 1e-12 * system.lam
    dt = 1.0 / (system.lam * n)
    if not math.isfinite(t_end / dt):
        raise ParameterError("(cells, t_end)", f"at most max_updates = {max_updates} node updates", "inf")
    steps = max(1, math.ceil(t_end / dt - 1e-9))
    # the work bound before any grid is allocated (a lower bound of the node count below:
    # at least floor(1/(mu dt)) + 1 nodes of v, see v_grid)
    nodes_min = 2 * n if lattice else n + 2 + math.floor(1.0 / (system.mu * dt) + 1e-9)
    if steps * nodes_min > max_updates:
        raise ParameterError("(cells, t_end)", f"at most max_updates = {max_updates} node updates", steps * nodes_min)
    x = np.linspace(0.0, 1.0, n + 1)
    xv = x if lattice else v_nodes(system, n)
    if xv.size < 4:
        raise ParameterError("cells", f">= {math.ceil(3 * system.mu / system.lam)} (three cells of v at least)", n)
    updates = steps * (2 * n if lattice else x.size + xv.size)
    if updates > max_updates:
        raise ParameterError("(cells, t_end)", f"at most max_updates = {max_updates} node updates", updates)

    u = initial_state("u0", u0, x)
    v = initial_state("v0", v0, xv)
    laws = sum(not (hasattr(c, "boundary_gain") and hasattr(c, "gain_u")) for c, _ in runs)
    if kernels is None and laws > 1 and not system.uncoupled:
        kernels = solve_kernels(system, kernel_grid)  # the plant's kernels, once for every controller
    w_x, w_v = trapezoid_weights(x), trapezoid_weights(xv)
    if norm_weights is not None:
        n_x, n_v = w_x * norm_weights[0](x), w_v * norm_weights[1](xv)
    else:
        n_x, n_v = w_x, w_v
    us, vs = np.tile(u, (len(runs), 1)), np.tile(v, (len(runs), 1))  # one row per run
    loops, records = [], []
    for (controller, _), delta, ur, vr in zip(runs, deltas, us, vs):
        law = _feedback_law(system, controller, kernels, kernel_grid)
        loop = Loop(
            law,
            w_x * _gain_values("gain_u", law.gain_u, x),
            w_v * _gain_values("gain_v", law.gain_v, xv),
            system.rho,
            delta,
            dt,
            steps,
        )
        record = Recorder(steps, snapshot_every, n_x, n_v)
        loop.start(ur, vr)
        record(0, ur, vr)
        loops.append(loop)
        records.append(record)
    if lattice:
        march_lattice(system, x, us, vs, dt, steps, loops, records)
    else:
        for loop, record, ur, vr in zip(loops, records, us, vs):
            march_two_grids(system, x, xv, ur, vr, dt, steps, loop, record)

    times = (dt * np.arange(steps + 1)).astype(np.float64)
    return [
        Simulation(
            times=times,
            norm=record.norm,
            control=loop.control,
            x=x,
            x_v=xv,
            snapshot_times=times[record.index],
            u=np.asarray(record.u),
            v=np.asarray(record.v),
            delta=delta,
            dt=dt,
            n=n,
            delay_interpolation="exact shift" if loop.exact else "Lagrange-4",
            scheme="characteristic lattice" if lattice else "two characteristic grids",
        )
        for loop, record, delta in zip(loops, records, deltas)
    ]


@renamed_keywords(n="cells", kernel_n="kernel_grid")
def simulate_runs(
    system: Hyperbolic2x2,
    runs: Sequence[tuple[Any, float]],
    t_end: float,
    u0: InitialState,
    v0: InitialState,
    cells: int = DEFAULT_CELLS,
    *,
    snapshot_every: int | None = None,
    kernels: Any = None,
    kernel_grid: int = DEFAULT_KERNEL_GRID,
    max_updates: int = MAX_UPDATES,
) -> list[Simulation]:
    """Several loops of one plant from one initial state: one :class:`Simulation` per ``(controller, delta)``.

    Each result is the one :func:`simulate_characteristics` (the scheme ``"characteristics"``
    of :func:`~nrobust.hyperbolic.simulate.simulate`) returns for that controller and delay
    with the same arguments, to the last bit. With equal speeds the runs march together on
    the characteristic lattice (the elementwise updates of all runs in one array operation:
    the five runs of the paper's figures 1 and 3 in about 0.6 of the time they take one by
    one), and the plant's kernels are solved once when ``kernels`` is not given
    (``max_updates`` bounds each run).

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant.
    runs : sequence of (controller, float)
        The loops: a controller (as for :func:`simulate_characteristics`) and a delay ``>= 0``.
    t_end, u0, v0, cells, snapshot_every, kernels, kernel_grid, max_updates
        As for :func:`simulate_characteristics`.
    """
    runs = list(runs)
    if not runs or not all(isinstance(r, tuple) and len(r) == 2 for r in runs):
        raise ParameterError("runs", "a non-empty sequence of (controller, delta) pairs", runs)
    return _simulate_runs(system, runs, t_end, u0, v0, cells, snapshot_every, kernels, kernel_grid, max_updates)


@renamed_keywords(n="cells", kernel_n="kernel_grid")
def simulate_normal_form(
    plant: GeneralHyperbolic2x2,
    controller: Any,
    delta: float,
    t_end: float,
    u0: InitialState,
    v0: InitialState,
    cells: int = DEFAULT_CELLS,
    *,
    snapshot_every: int | None = None,
    kernels: Any = None,
    kernel_grid: int = DEFAULT_KERNEL_GRID,
    max_updates: int = MAX_UPDATES,
) -> Simulation:
    """The scheme ``"normal form"``: a general plant with a constant ``lam/mu``, simulated as its normal form.

    The initial state is carried to the normal form, the paper's plant simulated as by
    :func:`simulate_characteristics` under the controller (a ``StateFeedback``'s gains
    mapped from the physical coordinates), and the states, the control
    ``U = e^{D(L)} U~`` and the norm ``sqrt(int_0^L u^2 + v^2 dx)`` are those of the
    physical plant (``x``, ``x_v``: the physical nodes; times in ``time_unit``).

    ``u = e^{A + k} u~``, ``v = e^{D} v~`` at ``y(x)`` (:class:`~nrobust.hyperbolic.plants.general.NormalForm`);
    with ``dx = t_u lam(x(y)) dy`` the physical norm is the normal form's with the weights
    ``e^{2(A + k)} t_u lam`` and ``e^{2D} t_u lam`` on the squares.
    """
    if not isinstance(controller, Controller):
        raise ParameterError(
            "controller",
            "a Controller for a general plant (a FeedbackLaw's gains would be in the normal form's coordinates: "
            "simulate plant.normal_form().system with it)",
            controller,
        )
    form = plant.normal_form()
    system = form.system
    if isinstance(controller, StateFeedback):
        controller = StateFeedback(*form.feedback_to_normal(controller.k, controller.g_u, controller.g_v))
    t_u = plant.transport_times[0]

    def physical(nodes: Array) -> Array:
        at = form.x_of_y(nodes)
        at[0], at[-1] = 0.0, plant.length
        return at

    # The initial state is sampled on the nodes by _simulate, after its work bound is checked.
    def un(nodes: Array) -> Array:
        at = physical(nodes)
        return np.asarray(form.to_normal(at, initial_state("u0", u0, at), 0.0)[1])

    def vn(nodes: Array) -> Array:
        at = physical(nodes)
        return np.asarray(form.to_normal(at, 0.0, initial_state("v0", v0, at))[2])

    def weight_u(nodes: Array) -> Array:
        at = form.x_of_y(nodes)
        return np.exp(2.0 * (plant.A(at) + form.balance)) * t_u * plant.coefficient("lam", at)

    def weight_v(nodes: Array) -> Array:
        at = form.x_of_y(nodes)
        return np.exp(2.0 * plant.D(at)) * t_u * plant.coefficient("lam", at)

    run = _simulate(
        system,
        controller,
        delta,
        t_end,
        un,
        vn,
        cells,
        snapshot_every,
        kernels,
        kernel_grid,
        max_updates,
        (weight_u, weight_v),
    )
    _, u, _ = form.from_normal(run.x, run.u, 0.0)
    _, _, v = form.from_normal(run.x_v, 0.0, run.v)
    x, xv = physical(run.x), physical(run.x_v)
    return dataclasses.replace(run, x=x, x_v=xv, u=u, v=v, control=run.control * form.control_gain)


@renamed_keywords(n="cells")
def v_nodes(system: Hyperbolic2x2, cells: int) -> Array:
    """Nodes (ascending) on which :func:`~nrobust.hyperbolic.simulate.simulate` stores ``v`` (``cells`` cells of ``u``).

    Equal speeds: the ``u`` nodes ``k / cells``. Otherwise ``1 - k mu dt``
    (``dt = 1/(lam cells)``) down to the last one in ``[0, 1]``, and ``x = 0`` when that
    one is not 0. (``cells`` was formerly ``n``, a deprecated alias.)
    """
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem", system)
    n = positive_int("cells", cells, minimum=2)
    if abs(system.mu - system.lam) <= 1e-12 * system.lam:
        return np.linspace(0.0, 1.0, n + 1)
    return v_grid(system.mu, 1.0 / (system.lam * n))


#: The paper's plant (and ``TransportSystem``) along its characteristics.
CHARACTERISTICS_SCHEME = Scheme(
    "characteristics",
    (Hyperbolic2x2,),
    simulate_characteristics,
    description="the paper's plant along its characteristics (lattice for lam == mu, else two grids)",
)
#: A general plant with a constant ``lam/mu``, through its normal form.
NORMAL_FORM_SCHEME = Scheme(
    "normal form",
    (GeneralHyperbolic2x2,),
    simulate_normal_form,
    condition=lambda plant: bool(plant.constant_ratio),
    description="a general plant with a constant lam/mu, simulated as its normal form and mapped back",
)
