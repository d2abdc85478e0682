"""Simulation of a general plant with varying speeds, exact transport along characteristics.

Each state lives on a grid uniform in its own time of flight: ``u`` at
``phi(x_i) = i dt`` (``dt = t_u / cells``), ``v`` at ``psi(x_j) = j dt`` plus the node
``psi = t_v`` (a shorter last cell when ``t_v / dt`` is not an integer). In one step each
value moves exactly one node along its characteristic, so the transport is exact (no
numerical dissipation, whatever the speeds); the in-domain terms ``a u + b v`` and
``c u + d v`` are integrated along the characteristic by Heun's method (second order),
the other state being interpolated linearly between the two grids. The characteristic
that reaches the last ``v`` node starts on the boundary ``x = L`` between two time
steps, where the boundary value ``rho u(t, L) + U(t - delta)`` is interpolated linearly in
time; ``U = k u(t, L) + int_0^L g_u u + g_v v dx`` (trapezoidal rule) is delayed by linear
interpolation of its history. Second order overall (``tests/test_general.py`` measures
it); the growth rate of the norm matches the spectral abscissa of the characteristic
route (:mod:`nrobust.hyperbolic.loops.varying_form`). Registered as the scheme ``"time-of-flight grids"`` of
:func:`~nrobust.hyperbolic.simulate.simulate` (:func:`simulate_time_of_flight`, which returns a
:class:`~nrobust.hyperbolic.simulate.Simulation`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._validate import nonnegative, positive, positive_int, renamed_keywords
from ...errors import ParameterError
from ..loops.controllers import FeedbackLaw, OpenLoop, StateFeedback
from ..plants.general import GeneralHyperbolic2x2, Profile
from .base import Scheme, SimulationResult, initial_state
from .characteristics import trapezoid_weights
from .normal_form import DEFAULT_CELLS, MAX_UPDATES, InitialState, Simulation

__all__ = ["TIME_OF_FLIGHT_SCHEME", "GeneralSimulation", "simulate_general", "simulate_time_of_flight"]

Array = NDArray[np.float64]
# Work bound on node updates (nodes times steps), checked before any allocation.
_MAX_UPDATES = 2 * 10**8
# Memory bound on the stored snapshots (values of u and v), checked before any allocation.
_MAX_STORED = 2 * 10**7


@dataclass(frozen=True, eq=False)
class GeneralSimulation(SimulationResult):
    """Result of :func:`simulate_general` (times in the plant's ``time_unit``; a :class:`SimulationResult`).

    Attributes
    ----------
    times, norm, control : ndarray
        Sampled times, ``sqrt(int_0^L u^2 + v^2 dx)`` and the controller output ``U(t)``.
    x_u, x_v : ndarray
        Physical nodes of the two grids.
    u, v : ndarray
        Final states on them.
    dt : float
        Time step ``t_u / cells`` (in ``time_unit``).
    u_end, v_start : ndarray
        The boundary traces ``u(t, L)`` (the measured end) and ``v(t, 0)`` (so
        ``u(t, 0) = q v(t, 0)``) at ``times``.
    snapshot_times : ndarray, shape (k,)
        Times of the stored states (every ``snapshot_every`` steps and the last one).
    u_snapshots, v_snapshots : ndarray, shapes (k, x_u.size) and (k, x_v.size)
        The states at ``snapshot_times``.
    """

    control: Array
    x_u: Array
    x_v: Array
    u: Array
    v: Array
    dt: float
    u_end: Array
    v_start: Array
    snapshot_times: Array
    u_snapshots: Array
    v_snapshots: Array


def _weights(x: Array, nodes: Array) -> tuple[NDArray[np.intp], Array]:
    """Left index and weight of the linear interpolation of ``nodes`` values at ``x``."""
    idx = np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, nodes.size - 2)
    w = (x - nodes[idx]) / (nodes[idx + 1] - nodes[idx])
    return idx, np.clip(w, 0.0, 1.0)


def _state_feedback(controller: StateFeedback | OpenLoop | FeedbackLaw) -> StateFeedback:
    """The controller as a :class:`StateFeedback` (``OpenLoop`` is the zero feedback, a ``FeedbackLaw``
    without filter its gains); anything else raises :class:`~nrobust.errors.ParameterError`."""
    if isinstance(controller, OpenLoop):
        controller = StateFeedback(0.0)
    if isinstance(controller, FeedbackLaw) and controller.filter is None:
        controller = StateFeedback(controller.boundary_gain, controller.gain_u, controller.gain_v)
    if not isinstance(controller, StateFeedback):
        raise ParameterError("controller", "a StateFeedback, OpenLoop or FeedbackLaw without filter", controller)
    return controller


def _snapshot_period(nodes: int, steps: int, cells: int, snapshot_every: int | None) -> int:
    """The steps between stored states, after the work and memory bounds (before any allocation).

    ``nodes`` is the size of the two grids (plus one); the march makes ``nodes * steps``
    node updates, at most ``_MAX_UPDATES`` (else ``cells`` is refused), and stores
    ``nodes`` values per snapshot, at most ``_MAX_STORED`` in all (else ``snapshot_every``
    is refused, with the least period that fits). Without ``snapshot_every`` the period is
    ``steps`` (the final state only).
    """
    if nodes * steps > _MAX_UPDATES:
        raise ParameterError("cells", f"small enough for at most {_MAX_UPDATES:.0e} node updates", cells)
    every = steps if snapshot_every is None else positive_int("snapshot_every", snapshot_every)
    stored = (steps // every + 1) * nodes
    if stored > _MAX_STORED:
        least = int(np.ceil(steps * nodes / (_MAX_STORED - nodes)))
        raise ParameterError("snapshot_every", f">= {least} (at most {_MAX_STORED:.0e} stored values)", every)
    return every


def _time_of_flight_grids(plant: GeneralHyperbolic2x2, n_u: int, m_v: int, dt: float) -> tuple[Array, Array, float]:
    """The physical nodes ``x_u``, ``x_v`` of the two grids and the length ``eps`` of the last ``v`` cell.

    ``u`` at ``phi(x_i) = i dt`` (``i <= n_u``), ``v`` at ``psi(x_j) = j dt`` (``j <= m_v``)
    plus ``psi = t_v`` when ``t_v`` is not on the grid (then ``eps < dt``); ``x(psi)`` is
    the cubic Hermite interpolant of the plant's tables (``psi' = 1/mu``), and the last
    node of each grid is set to ``L`` exactly.
    """
    t_u, t_v = plant.transport_times
    tables = plant.tables
    phi_u = np.arange(n_u + 1) * dt
    x_u = np.asarray(tables.x_of_y(phi_u / t_u))
    x_u[-1] = plant.length
    psi_v = np.arange(m_v + 1) * dt
    if t_v - psi_v[-1] > 1e-9 * dt:
        psi_v = np.append(psi_v, t_v)
    x_nodes = tables.x
    from scipy.interpolate import CubicHermiteSpline  # lazily: scipy.interpolate is slow to import

    x_of_psi = CubicHermiteSpline(tables.psi(x_nodes), x_nodes, plant.coefficient("mu", x_nodes))
    x_v = np.asarray(x_of_psi(psi_v))
    x_v[-1] = plant.length
    return x_u, x_v, float(psi_v[-1] - psi_v[-2])


class _Loop:
    """The closed loop discretized on the two grids: in-domain sources, controller output, norm.

    Holds the coefficients ``a, b`` at the ``u`` nodes and ``c, d`` at the ``v`` nodes, the
    linear interpolation of each state at the other's nodes, the trapezoidal weights of the
    controller's integral and of the norm, and the step ``dt``, the last ``v`` cell ``eps``
    and ``theta = 1 - eps / dt`` (the last interior ``v`` node's characteristic leaves
    ``x = L`` at ``t_{n+1} - eps``).
    """

    def __init__(
        self, plant: GeneralHyperbolic2x2, controller: StateFeedback, x_u: Array, x_v: Array, dt: float, eps: float
    ) -> None:
        self.coef = {k: (plant.coefficient(k, x_u), plant.coefficient(k, x_v)) for k in ("a", "b", "c", "d")}
        self.iv, self.wv = _weights(x_u, x_v)  # v at the u nodes
        self.iu, self.wu = _weights(x_v, x_u)  # u at the v nodes
        gu, gv = Profile("g_u", controller.g_u), Profile("g_v", controller.g_v)
        self.quad_u = trapezoid_weights(x_u) * gu(x_u)
        self.quad_v = trapezoid_weights(x_v) * gv(x_v)
        self.norm_u, self.norm_v = trapezoid_weights(x_u), trapezoid_weights(x_v)
        self.k_gain, self.q, self.rho = controller.k, plant.q, plant.rho
        self.dt, self.eps, self.theta = dt, eps, 1.0 - eps / dt

    def sources(self, u: Array, v: Array) -> tuple[Array, Array]:
        """The in-domain terms ``a u + b v`` at the ``u`` nodes and ``c u + d v`` at the ``v`` nodes."""
        coef, iv, wv, iu, wu = self.coef, self.iv, self.wv, self.iu, self.wu
        v_at_u = v[iv] * (1.0 - wv) + v[iv + 1] * wv
        u_at_v = u[iu] * (1.0 - wu) + u[iu + 1] * wu
        return coef["a"][0] * u + coef["b"][0] * v_at_u, coef["c"][1] * u_at_v + coef["d"][1] * v

    def control(self, u: Array, v: Array) -> float:
        """``U = k u(L) + int_0^L g_u u + g_v v dx`` (trapezoidal rule)."""
        return float(self.k_gain * u[-1] + self.quad_u @ u + self.quad_v @ v)

    def norm(self, u: Array, v: Array) -> float:
        """``sqrt(int_0^L u^2 + v^2 dx)`` (trapezoidal rule)."""
        return float(np.sqrt(self.norm_u @ u**2 + self.norm_v @ v**2))


class _History:
    """What a run keeps: the control, the norm and the boundary traces at every step, the states
    at the snapshot steps; and the delayed control ``U(t_n - delta)`` read from that history."""

    def __init__(self, steps: int, dt: float, delta: float, kept: list[int], sizes: tuple[int, int]) -> None:
        self.dt, self.delta, self.kept = dt, delta, kept
        self.times: Array = np.arange(steps + 1, dtype=np.float64) * dt
        self.control = np.zeros(steps + 1)
        self.norm = np.zeros(steps + 1)
        self.u_end, self.v_start = np.zeros(steps + 1), np.zeros(steps + 1)
        self.u_snap, self.v_snap = np.zeros((len(kept), sizes[0])), np.zeros((len(kept), sizes[1]))
        self.slot = {step: k for k, step in enumerate(kept)}

    def record(self, n: int, u: Array, v: Array) -> None:
        """Store the boundary traces of step ``n`` and, at a snapshot step, the states."""
        self.u_end[n], self.v_start[n] = u[-1], v[0]
        if n in self.slot:
            self.u_snap[self.slot[n]], self.v_snap[self.slot[n]] = u, v

    def delayed(self, n: int, current: float) -> float:
        """``U(t_n - delta)``, linear in the history; ``current`` is ``U(t_n)`` (not yet stored)."""
        s = n - self.delta / self.dt
        if s < 0:
            return 0.0
        i = int(np.floor(s))
        f = s - i
        right = current if i + 1 >= n else self.control[i + 1]
        left = current if i >= n else self.control[i]
        return left if f == 0 else left * (1.0 - f) + right * f


def _heun_step(
    loop: _Loop, history: _History, n: int, u: Array, v: Array, su: Array, sv: Array, boundary_old: float
) -> tuple[Array, Array]:
    """The states at ``t_{n+1}`` from those at ``t_n`` and their sources ``su``, ``sv`` (module notes).

    Each value moves one node along its characteristic: explicit Euler as predictor, then
    Heun's corrector twice (the boundary loop ``v(L) = rho u(L) + U(t - delta)`` substituted
    once more); the characteristic of the last interior ``v`` node starts on ``x = L`` at a
    fraction ``theta`` of the step, where the boundary value and its source are linear in
    time. ``v(L)`` is left to the caller, which sets it from the new control.
    """
    dt, eps, theta, q, rho = loop.dt, loop.eps, loop.theta, loop.q, loop.rho
    # predictor: explicit Euler along the characteristics
    u_new, v_new = np.empty_like(u), np.empty_like(v)
    u_new[1:] = u[:-1] + dt * su[:-1]
    v_new[:-2] = v[1:-1] + dt * sv[1:-1]
    v_new[-2] = boundary_old + eps * sv[-1]
    v_new[-1] = v[-1]
    u_new[0] = q * v_new[0]
    for _ in range(2):  # Heun's corrector, the boundary loop substituted once more
        boundary_new = rho * u_new[-1] + history.delayed(n + 1, loop.control(u_new, v_new))
        v_new[-1] = boundary_new
        su_new, sv_new = loop.sources(u_new, v_new)
        b_mid = boundary_old * (1.0 - theta) + boundary_new * theta
        sv_mid = sv[-1] * (1.0 - theta) + sv_new[-1] * theta
        u_next, v_next = np.empty_like(u), np.empty_like(v)
        u_next[1:] = u[:-1] + 0.5 * dt * (su[:-1] + su_new[1:])
        v_next[:-2] = v[1:-1] + 0.5 * dt * (sv[1:-1] + sv_new[:-2])
        v_next[-2] = b_mid + 0.5 * eps * (sv_mid + sv_new[-2])
        v_next[-1] = boundary_new
        u_next[0] = q * v_next[0]
        u_new, v_new = u_next, v_next
    return u_new, v_new


def _march(loop: _Loop, history: _History, u: Array, v: Array, steps: int) -> tuple[Array, Array]:
    """Run ``steps`` steps from ``(u, v)``, recording each in ``history``; the final states.

    After each step the control ``U(t_{n+1})`` is computed from the new states and the
    boundary value ``v(t_{n+1}, L) = rho u(t_{n+1}, L) + U(t_{n+1} - delta)`` set from it.
    """
    control, norm = history.control, history.norm
    control[0] = loop.control(u, v)
    norm[0] = loop.norm(u, v)
    boundary_old = loop.rho * u[-1] + history.delayed(0, control[0])
    history.record(0, u, v)
    su, sv = loop.sources(u, v)
    for n in range(steps):
        u, v = _heun_step(loop, history, n, u, v, su, sv, boundary_old)
        control[n + 1] = loop.control(u, v)
        v[-1] = loop.rho * u[-1] + history.delayed(n + 1, control[n + 1])
        norm[n + 1] = loop.norm(u, v)
        history.record(n + 1, u, v)
        boundary_old = v[-1]
        su, sv = loop.sources(u, v)
    return u, v


def simulate_general(
    plant: GeneralHyperbolic2x2,
    controller: StateFeedback | OpenLoop | FeedbackLaw,
    delta: float,
    t_end: float,
    u0: Any,
    v0: Any,
    cells: int = 200,
    *,
    snapshot_every: int | None = None,
) -> GeneralSimulation:
    """Simulate ``plant`` under ``U(t - delta)`` (module notes); ``U = 0`` for ``t < 0``.

    Parameters
    ----------
    plant : GeneralHyperbolic2x2
        Any speeds.
    controller : StateFeedback, OpenLoop or FeedbackLaw
        The feedback, gains in the plant's coordinates (a ``FeedbackLaw`` without filter,
        e.g. U_BS of :meth:`~nrobust.hyperbolic.kernels.varying.VaryingKernels.feedback_law`).
    delta : float
        Loop delay ``>= 0``, in the plant's ``time_unit`` (as the delay margins).
    t_end : float
        Final time ``> 0`` in ``time_unit`` (the run ends at the first step at or after it).
    u0, v0 : float or callable
        Initial state: a number (a constant state) or a callable on arrays of ``x`` in ``[0, L]``.
    cells : int, default 200
        Cells of the ``u`` grid; ``v`` has about ``cells t_v / t_u``.
    snapshot_every : int, optional
        Store the state every this many steps (and at the end); default: the final state
        only. The norm, the control and the boundary traces are kept at every step.

    Raises
    ------
    ParameterError
        Bad input, more than 2e8 node updates or more than 2e7 stored snapshot values
        (both checked before allocating).
    """
    if not isinstance(plant, GeneralHyperbolic2x2):
        raise ParameterError("plant", "a GeneralHyperbolic2x2", plant)
    controller = _state_feedback(controller)
    unit = plant.time_unit
    delta, t_end = nonnegative("delta", delta) * unit, positive("t_end", t_end) * unit
    n_u = positive_int("cells", cells, 4)
    t_u, t_v = plant.transport_times
    dt = t_u / n_u
    m_v = int(np.floor(t_v / dt * (1.0 + 1e-12)))
    steps = max(1, int(np.ceil(t_end / dt - 1e-9)))  # the first sampled time >= t_end
    every = _snapshot_period(n_u + m_v + 3, steps, cells, snapshot_every)
    x_u, x_v, eps = _time_of_flight_grids(plant, n_u, m_v, dt)
    loop = _Loop(plant, controller, x_u, x_v, dt, eps)
    u = initial_state("u0", u0, x_u)
    v = initial_state("v0", v0, x_v)
    kept = [steps] if snapshot_every is None else sorted({*range(0, steps + 1, every), steps})
    history = _History(steps, dt, delta, kept, (u.size, v.size))
    u, v = _march(loop, history, u, v, steps)
    return GeneralSimulation(
        history.times / unit,
        history.norm,
        history.control,
        x_u,
        x_v,
        u,
        v,
        dt / unit,
        history.u_end,
        history.v_start,
        history.times[kept] / unit,
        history.u_snap,
        history.v_snap,
    )


@renamed_keywords(n="cells", kernel_n="kernel_grid")
def simulate_time_of_flight(
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
    kernel_grid: int | None = None,
    max_updates: int = MAX_UPDATES,
) -> Simulation:
    """The scheme ``"time-of-flight grids"``: :func:`simulate_general`, its result as a :class:`Simulation`.

    The default scheme of a general plant with a varying ``lam/mu``; with a constant one it
    is chosen by name only. ``kernels``, ``kernel_grid`` and ``max_updates`` are those of
    the other 2x2 schemes and not used here: the controller is a ``StateFeedback``,
    ``OpenLoop`` or ``FeedbackLaw`` with its gains given, and :func:`simulate_general` has
    its own work bounds.
    """
    if not isinstance(controller, (StateFeedback, OpenLoop, FeedbackLaw)):
        raise ParameterError(
            "controller",
            "a StateFeedback, OpenLoop or FeedbackLaw on a plant with a varying lam/mu (the paper's controllers are "
            "built on the kernels of a normal form, which needs a constant lam/mu; U_BS with varying speeds is "
            "solve_varying_kernels(plant).feedback_law())",
            controller,
        )
    n = positive_int("cells", cells, minimum=4)
    run = simulate_general(plant, controller, delta, t_end, u0, v0, n, snapshot_every=snapshot_every)
    return Simulation(
        times=run.times,
        norm=run.norm,
        control=run.control,
        x=run.x_u,
        x_v=run.x_v,
        snapshot_times=run.snapshot_times,
        u=run.u_snapshots,
        v=run.v_snapshots,
        delta=nonnegative("delta", delta),
        dt=run.dt,
        n=n,
        delay_interpolation="linear",
        scheme="time-of-flight grids",
    )


#: A general plant on its time-of-flight grids (any speeds).
TIME_OF_FLIGHT_SCHEME = Scheme(
    "time-of-flight grids",
    (GeneralHyperbolic2x2,),
    simulate_time_of_flight,
    description="a general plant (any speeds) on one time-of-flight grid per state (simulate_general)",
)
