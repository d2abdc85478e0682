"""Simulation of ``n + m`` systems along the characteristics (scheme ``"n+m characteristics"``).

Each component lives on its own grid, one cell per time step along its characteristic;
the couplings are integrated by Heun's method, the delayed control interpolated linearly
in its history (:func:`simulate_nplusm`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._validate import finite_real, is_real_number, nonnegative, positive, positive_int
from ...errors import ParameterError
from ..nplusm.system import NPlusMSystem
from .base import Scheme, SimulationResult

__all__ = ["NPLUSM_SCHEME", "NPlusMSimulation", "simulate_nplusm"]


@dataclass(frozen=True)
class _Constant:
    """``x -> `` the constant state ``level`` of every one of ``components`` components (a number as ``w0``)."""

    level: float
    components: int

    def __call__(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.full((self.components, np.size(x)), self.level)


def _coupling_operator(sigma: NDArray[np.float64], xs: list[NDArray[np.float64]], off: NDArray[np.intp]) -> Any:
    """Sparse map of the stacked grid values to ``Sigma w`` on every grid (linear interpolation between grids)."""
    from scipy.sparse import csr_matrix  # lazily: a slow import

    rows, cols, vals = [], [], []
    for i, xi in enumerate(xs):
        for j, xj in enumerate(xs):
            if sigma[i, j] == 0:
                continue
            nj = xj.size - 1
            pos = np.minimum(np.floor(xi * nj).astype(int), nj - 1)
            frac = xi * nj - pos
            node = np.arange(xi.size) + off[i]
            rows += [node, node]
            cols += [pos + off[j], pos + 1 + off[j]]
            vals += [sigma[i, j] * (1 - frac), sigma[i, j] * frac]
    size = int(off[-1])
    if not rows:
        return csr_matrix((size, size))
    return csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(size, size))


@dataclass(frozen=True, eq=False)
class NPlusMSimulation(SimulationResult):
    """Result of :func:`simulate_nplusm` (a :class:`~nrobust.hyperbolic.simulate.base.SimulationResult`).

    Attributes
    ----------
    times : ndarray
        Sampled times ``j dt``.
    norm : ndarray
        ``||w(t)||_{L2}`` (trapezoidal rule on each component's grid).
    dt : float
        Time step (one cell per step for every component).
    cells : tuple of int
        Cells of each component's grid (``round(1 / (c_i dt))`` for speed ``c_i``).
    """

    dt: float
    cells: tuple[int, ...]

    def growth_rate(self, t_start: float | None = None, t_max: float | None = None) -> float:
        """Slope of ``log ||w||`` fitted by least squares on ``[t_start, t_max]`` (default: the second half).

        Unlike :meth:`SimulationResult.growth_rate`, zero norms (a loop that reached zero in
        finite time) are left out of the fit instead of refused.
        """
        t0 = self.times[-1] / 2 if t_start is None else nonnegative("t_start", t_start)
        keep = (self.times >= t0) & (self.norm > 0)
        if t_max is not None:
            keep &= self.times <= nonnegative("t_max", t_max)
        return float(np.polyfit(self.times[keep], np.log(self.norm[keep]), 1)[0])


def simulate_nplusm(
    system: NPlusMSystem,
    K: Any,
    delta: float,
    t_end: float,
    w0: Any,
    cells: int = 200,
    *,
    max_updates: int = 200_000_000,
) -> NPlusMSimulation:
    """Simulate the ``n + m`` system under ``U(t) = K u(t - delta, 1)`` (``U = 0`` for ``t < delta``).

    Each component lives on its own grid of ``N_i = round(1 / (c_i dt))`` cells with
    ``dt = 1 / (cells max c_i)``, so that one time step moves it exactly one cell along
    its characteristic (CFL 1 per speed; the transport times ``1/c_i`` are rounded to
    multiples of ``dt``). The couplings are integrated along the characteristics by
    Heun's method (second order), reading the other components by linear interpolation
    between the grids; the boundary conditions close each step, the delayed output
    control ``U(t - delta)`` is interpolated linearly in the stored history.

    Parameters
    ----------
    system : NPlusMSystem
    K : array_like, None or state feedback
        The gain (``m x n``; None for the open loop), or an object whose
        ``functional(grids)`` returns the control as a row map ``(m, nodes)`` of the
        stacked nodal values on the component grids (as
        :class:`~nrobust.hyperbolic.nplusm.NPlusMBackstepping`): then
        ``v(t, 1) = R u(t, 1) + U(t - delta)`` with ``U(t)`` that map of the state
        (solved with ``v(t, 1)`` when the map reads it).
    delta : float
        Loop delay ``>= 0``.
    t_end : float
        Final time ``> 0``.
    w0 : float or callable
        A number (the same constant state for every component) or a callable: ``w0(x)``
        returns the ``n + m`` initial profiles as an array of shape ``(n + m, x.size)``.
    cells : int, optional
        Cells of the fastest component.
    max_updates : int, optional
        Work bound on node updates, checked before allocating.

    Returns
    -------
    NPlusMSimulation
    """
    functional = getattr(K, "functional", None)
    k = system.gain(None if callable(functional) else K)
    delta = nonnegative("delta", delta)
    t_end = positive("t_end", t_end)
    cells = positive_int("cells", cells, minimum=4)
    max_updates = positive_int("max_updates", max_updates)
    if is_real_number(w0):
        w0 = _Constant(finite_real("w0", w0), system.n + system.m)
    if not callable(w0):
        raise ParameterError("w0", "a number or a callable x -> array of shape (n + m, x.size)", w0)
    speeds = np.abs(system.signed_speeds)
    dt = 1.0 / (cells * float(speeds.max()))
    ncell = [max(1, round(1.0 / (c * dt))) for c in speeds]
    steps = max(1, int(np.ceil(t_end / dt - 1e-9)))  # the first sampled time >= t_end
    if steps * (sum(ncell) + len(ncell)) > max_updates:
        raise ParameterError("max_updates", f">= {steps * (sum(ncell) + len(ncell))} (steps x nodes)", max_updates)
    xs = [np.linspace(0.0, 1.0, nc + 1) for nc in ncell]
    off = np.cumsum([0] + [x.size for x in xs])
    state = np.empty(int(off[-1]))
    for i, x in enumerate(xs):
        try:
            prof = np.asarray(w0(x), dtype=float)
        except Exception as exc:  # the user's callable: its failure is a bad argument, named
            raise ParameterError(
                "w0", "a callable x -> real array", f"{w0!r} raised {type(exc).__name__}: {exc}"
            ) from None
        if prof.shape != (system.n + system.m, x.size) or not np.all(np.isfinite(prof)):
            raise ParameterError("w0", f"finite profiles of shape ({system.n + system.m}, x.size)", prof.shape)
        state[off[i] : off[i + 1]] = prof[i]
    n = system.n
    coupling = _coupling_operator(system.sigma, xs, off)
    # one cell per step along each characteristic: rightward u, leftward v
    dest = np.concatenate(
        [np.arange(off[i] + 1, off[i + 1]) if i < n else np.arange(off[i], off[i + 1] - 1) for i in range(len(xs))]
    )
    src = np.concatenate(
        [np.arange(off[i], off[i + 1] - 1) if i < n else np.arange(off[i] + 1, off[i + 1]) for i in range(len(xs))]
    )
    u_in, u_out = off[:n], off[1 : n + 1] - 1  # u(0), u(1)
    v_in, v_out = off[n + 1 :] - 1, off[n:-1]  # v(1), v(0)
    weights = np.concatenate([np.full(x.size, 1.0 / (x.size - 1)) * np.r_[0.5, np.ones(x.size - 2), 0.5] for x in xs])
    lag = delta / dt
    m = system.m
    if callable(functional):
        gain = np.asarray(functional(xs), dtype=float)
        if gain.shape != (m, state.size) or not np.all(np.isfinite(gain)):
            raise ParameterError("K", f"a functional of shape ({m}, {state.size}) on the grids", gain.shape)
    else:
        gain = np.zeros((m, state.size))
        gain[:, u_out] = k
    implicit = gain[:, v_in]  # weight of v(t, 1) in U(t)
    explicit = gain.copy()
    explicit[:, v_in] = 0.0
    hist = np.zeros((steps + 1, m))  # U(t_j)
    hist[0] = gain @ state

    def delayed(j: int) -> tuple[NDArray[np.float64], float]:
        """``U(t_j - delta)`` (zero before the start), linear in the history: the part known
        before step ``j`` closes, and the weight of ``U(t_j)`` in it."""
        tj = j - lag
        if tj < 0:
            return np.zeros(m), 0.0
        lo = int(np.floor(tj))
        frac = tj - lo
        if lo == j:
            return np.zeros(m), 1.0
        if frac == 0:
            return hist[lo], 0.0
        if lo + 1 == j:
            return (1 - frac) * hist[lo], frac
        return (1 - frac) * hist[lo] + frac * hist[lo + 1], 0.0

    def close(w: NDArray[np.float64], j: int) -> None:
        w[u_in] = system.q @ w[v_out]
        known, c = delayed(j)
        base = system.r @ w[u_out] + known
        hist[j] = np.linalg.solve(np.eye(m) - c * implicit, explicit @ w + implicit @ base)
        w[v_in] = base + c * hist[j]

    norms = np.empty(steps + 1)
    norms[0] = np.sqrt(weights @ state**2)
    # zeros, not empty: close() forms explicit @ w before it sets v(t, 1), and 0 times an
    # uninitialised NaN is NaN
    pred = np.zeros_like(state)
    for j in range(1, steps + 1):
        s_old = coupling @ state
        pred[dest] = state[src] + dt * s_old[src]
        close(pred, j)
        s_new = coupling @ pred
        new = np.zeros_like(state)
        new[dest] = state[src] + 0.5 * dt * (s_old[src] + s_new[dest])
        close(new, j)
        state = new
        norms[j] = np.sqrt(weights @ state**2)
    return NPlusMSimulation(np.arange(steps + 1, dtype=float) * dt, norms, dt, tuple(ncell))


def _run(
    system: NPlusMSystem, K: Any, delta: float, t_end: float, u0: Any, v0: Any, **options: Any
) -> NPlusMSimulation:
    """:func:`simulate_nplusm` as the registry calls it: the state ``w0`` given as ``u0`` or ``w0=``."""
    if v0 is not None:
        raise ParameterError("v0", "not given for an n + m system (its state is one array w0: u0 or w0=)", v0)
    if "w0" in options:
        if u0 is not None:
            raise ParameterError("w0", "given once (as u0 or as w0=, not both)", options["w0"])
        u0 = options.pop("w0")
    return simulate_nplusm(system, K, delta, t_end, u0, **options)


#: The scheme of :func:`simulate_nplusm` in the registry: ``simulate(system, K, delta, t_end, w0, cells)``.
NPLUSM_SCHEME = Scheme(
    "n+m characteristics",
    (NPlusMSystem,),
    _run,
    description="an n + m system on one grid per component, one cell per step (simulate_nplusm)",
)
