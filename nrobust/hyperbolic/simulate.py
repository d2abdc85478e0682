"""Time-domain simulation of the plant (u_pde)-(IC) with a delayed boundary control.

The closed loop simulated is::

    u_t + lam u_x = sigma_pm(x) v,      u(t, 0) = q v(t, 0),
    v_t - mu  v_x = sigma_mp(x) u,      v(t, 1) = rho u(t, 1) + U(t - delta),

with ``U(t) = 0`` for ``t < 0`` and ``U`` given by a state feedback
(:class:`~nrobust.hyperbolic.controllers.FeedbackLaw`): U_BS (eq. (control)),
U_BS2(K) (eq. (control3)), their filtered versions (section 2.3.2) or any law of the form
``boundary_gain * u(t, 1) + int_0^1 gain_u u + gain_v v dxi``.

Scheme: a single characteristic lattice
---------------------------------------
With equal speeds ``lam = mu = c`` every point of the lattice below is the crossing of
one u-characteristic and one v-characteristic. With ``n`` cells and ``dt = 1 / (c n)``:

* at the sampled times ``t_j = j dt`` both ``u`` and ``v`` live on the nodes
  ``x_k = k / n`` (``k = 0 .. n``), at the half times ``t_j + dt / 2`` on the midpoints
  ``(k + 1/2) / n``;
* a half step moves ``u`` half a cell to the right and ``v`` half a cell to the left:
  transport is an exact index shift, nothing is interpolated in space;
* the couplings are integrated along each characteristic by the trapezoidal rule between
  consecutive crossings, where both unknowns are known at the same point; the two
  trapezoidal relations at a new crossing form a 2x2 linear system solved in closed form
  (implicit, second order, no numerical dissipation);
* the boundary relations hold exactly at ``x = 0`` and ``x = 1`` at every ``t_j``
  (implicitly with the control when ``delta`` is shorter than ``dt``);
* ``U(t_j)`` is computed from the state at ``t_j`` by the trapezoidal rule on the nodes,
  the filter ``(1 + a s)/(1 + b s) = a/b + (1 - a/b)/(1 + b s)`` by the exact exponential
  integrator of ``b w' + w = (1 - a/b) V`` for an input linear between samples;
* the delayed control ``U(t_j - delta)`` is read from the stored history exactly when
  ``delta`` is a multiple of ``dt``, otherwise by 4-point Lagrange interpolation of the
  history (fourth order; one-sided at ``t = 0``, where the zero prehistory meets ``U(0)``).

Because each lattice point is one crossing, the lattice does not split into
decoupled odd and even sub-lattices, as it does when ``u`` and ``v`` are stored on the
same nodes at every step of size ``1 / (c n)`` (there, the two halves are tied only by
the control integral, and their difference evolves without the integral part of the
feedback). The pure transport loop is reproduced to rounding; with couplings the
scheme is second-order convergent. See ``docs/simulation.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Union

import numpy as np
from numpy.typing import NDArray

from .._validate import finite_real, nonnegative, positive, positive_int
from ..errors import ParameterError
from .system import Hyperbolic2x2

__all__ = ["Simulation", "simulate"]

Array = NDArray[np.float64]
InitialState = Union[Callable[[Array], Any], Array]

#: Relative tolerance under which ``delta / dt`` counts as an integer.
_INTEGER_TOL = 1e-9
#: Default bound on the number of cell updates (``n`` times the number of steps).
MAX_UPDATES = 2 * 10**9


@dataclass(frozen=True, repr=False, eq=False)
class Simulation:
    """Result of :func:`simulate`.

    Attributes
    ----------
    times : ndarray, shape (m + 1,)
        Sampled times ``t_j = j dt``.
    norm : ndarray, shape (m + 1,)
        ``||(u, v)(t_j)||_{L2} = sqrt(int_0^1 u^2 + v^2 dx)`` (trapezoidal rule).
    control : ndarray, shape (m + 1,)
        The controller output ``U(t_j)``; the plant receives ``U(t_j - delta)``.
    x : ndarray, shape (n + 1,)
        Nodes ``k / n``.
    snapshot_times : ndarray, shape (k,)
        Times of the stored states.
    u, v : ndarray, shape (k, n + 1)
        States at ``snapshot_times`` on the nodes ``x``.
    delta : float
        Loop delay.
    dt : float
        Sampling step ``1 / (lam n)`` (the lattice advances in half steps).
    n : int
        Number of cells.
    delay_interpolation : str
        ``"exact shift"`` when ``delta`` is a multiple of ``dt`` (or zero), otherwise
        ``"Lagrange-4"``.
    """

    times: Array
    norm: Array
    control: Array
    x: Array
    snapshot_times: Array
    u: Array
    v: Array
    delta: float
    dt: float
    n: int
    delay_interpolation: str
    scheme: str = field(default="characteristic lattice, trapezoidal couplings")

    def growth_rate(self, t_min: float, t_max: float | None = None) -> float:
        """Least-squares slope of ``log ||(u, v)(t)||`` on ``[t_min, t_max]``.

        Parameters
        ----------
        t_min, t_max : float
            Fit window; ``t_max`` defaults to the last time.

        Raises
        ------
        ParameterError
            If the window holds fewer than two samples or a norm in it is zero.
        """
        t_max = float(self.times[-1]) if t_max is None else finite_real("t_max", t_max)
        mask = (self.times >= finite_real("t_min", t_min)) & (self.times <= t_max)
        if np.count_nonzero(mask) < 2:
            raise ParameterError("(t_min, t_max)", "a window holding at least two sampled times", (t_min, t_max))
        values = self.norm[mask]
        if np.any(values <= 0.0):
            raise ParameterError("(t_min, t_max)", "a window where the norm is positive", (t_min, t_max))
        slope, _ = np.polyfit(self.times[mask], np.log(values), 1)
        return float(slope)

    def __repr__(self) -> str:
        return (
            f"Simulation(n={self.n}, dt={self.dt:.3g}, delta={self.delta!r}, "
            f"t_end={self.times[-1]:.6g}, final_norm={self.norm[-1]:.3e}, "
            f"snapshots={self.snapshot_times.size}, delay_interpolation={self.delay_interpolation!r})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (lists of floats)."""
        return {
            "type": "Simulation",
            "scheme": self.scheme,
            "n": self.n,
            "dt": self.dt,
            "delta": self.delta,
            "delay_interpolation": self.delay_interpolation,
            "times": self.times.tolist(),
            "norm": self.norm.tolist(),
            "control": self.control.tolist(),
            "x": self.x.tolist(),
            "snapshot_times": self.snapshot_times.tolist(),
            "u": self.u.tolist(),
            "v": self.v.tolist(),
        }


def _initial(name: str, value: InitialState, x: Array) -> Array:
    """Sample an initial condition (callable or node values) on the nodes ``x``."""
    if callable(value):
        try:
            out = np.asarray(value(x), dtype=float)
        except (TypeError, ValueError):
            raise ParameterError(name, "a callable returning real numbers on arrays of x", value) from None
        if out.shape == ():
            out = np.full(x.shape, float(out))
    else:
        try:
            out = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ParameterError(name, f"a callable or an array of {x.size} node values", value) from None
    if out.shape != x.shape:
        raise ParameterError(name, f"{x.size} values, one per node k/n", f"shape {out.shape}")
    if not np.all(np.isfinite(out)):
        raise ParameterError(name, "finite on [0, 1]", "non-finite values")
    return out.copy()


def _feedback_law(system: Hyperbolic2x2, controller: Any, kernels: Any, kernel_n: int) -> Any:
    """The :class:`FeedbackLaw` of ``controller`` (itself if it already is one)."""
    if hasattr(controller, "boundary_gain") and hasattr(controller, "gain_u"):
        return controller
    if not callable(getattr(controller, "feedback_law", None)):
        raise ParameterError("controller", "a FeedbackLaw or an object with feedback_law(system, kernels)", controller)
    if kernels is None and not system.uncoupled:
        from .kernels import solve_kernels

        kernels = solve_kernels(system, n=kernel_n)
    return controller.feedback_law(system, kernels)


def _gain_values(name: str, gain: Callable[[Array], Any], x: Array) -> Array:
    out = np.asarray(gain(x), dtype=float)
    if out.shape == ():
        out = np.full(x.shape, float(out))
    if out.shape != x.shape or not np.all(np.isfinite(out)):
        raise ParameterError(name, "a callable returning finite values on arrays of xi in [0, 1]", gain)
    return out


def _filter_coefficients(law_filter: Any, dt: float) -> tuple[float, float, float, float]:
    """``(a/b, e^{-dt/b}, phi_1, phi_2)`` of the exact filter step; identity if no filter.

    The filter ``(1 + a s)/(1 + b s)`` is ``a/b + (1 - a/b)/(1 + b s)``; its state obeys
    ``b w' + w = (1 - a/b) V`` and ``U = (a/b) V + w``. For ``V`` linear on a step,
    ``w_{j+1} = e^{-dt/b} w_j + (1 - a/b)(phi_1 V_j + phi_2 V_{j+1})``.
    """
    if law_filter is None:
        return 1.0, 0.0, 0.0, 0.0
    try:
        a, b = (float(c) for c in law_filter)
    except (TypeError, ValueError):
        raise ParameterError("filter", "None or a pair (a, b) of finite reals with b > 0", law_filter) from None
    a = finite_real("filter a", a)
    b = positive("filter b", b)
    r = dt / b
    one_minus_e = -math.expm1(-r)
    phi2 = 1.0 - one_minus_e / r
    phi1 = one_minus_e / r - math.exp(-r)
    return a / b, math.exp(-r), phi1, phi2


def _history_weights(s: float, current: int) -> tuple[NDArray[np.intp], Array]:
    """Lagrange weights reading ``U`` at fractional index ``s`` from samples ``0 .. current``.

    Four points ``floor(s) - 1 .. floor(s) + 2`` moved inside ``[0, current]`` (fewer near
    the start), so that no point lies before ``t = 0``.
    """
    i0 = int(math.floor(s))
    lo = max(0, min(i0 - 1, current - 3))
    hi = min(lo + 3, current)
    idx = np.arange(lo, hi + 1)
    w = np.ones(idx.size)
    for m, node in enumerate(idx):
        for other in idx:
            if other != node:
                w[m] *= (s - other) / (node - other)
    return idx, w


def simulate(
    system: Hyperbolic2x2,
    controller: Any,
    delta: float,
    t_end: float,
    u0: InitialState,
    v0: InitialState,
    n: int = 400,
    *,
    snapshot_every: int | None = None,
    kernels: Any = None,
    kernel_n: int | None = None,
    max_updates: int = MAX_UPDATES,
) -> Simulation:
    """Simulate the plant (u_pde)-(IC) under the feedback ``U(t - delta)``.

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant; the characteristic lattice needs equal speeds ``lam == mu``.
    controller : Controller or FeedbackLaw
        An object with ``feedback_law(system, kernels)`` (``OpenLoop``,
        ``FiniteTimeController`` = U_BS eq. (control), ``ReflectionController(K)`` = U_BS2
        eq. (control3), ``FilteredController(a, b)``) or a ``FeedbackLaw``.
    delta : float
        Loop delay ``>= 0``; the plant receives ``U(t - delta)``, with ``U = 0`` for
        ``t < 0``.
    t_end : float
        Final time ``> 0``; the run ends at the first sampled time ``>= t_end``.
    u0, v0 : callable or array
        Initial state: callables on arrays of ``x`` or values on the ``n + 1`` nodes.
    n : int, default 400
        Cells on ``[0, 1]``; the sampling step is ``dt = 1 / (lam n)``.
    snapshot_every : int, optional
        Store the state every this many steps (and at the end); default: final state only.
    kernels : Kernels, optional
        Backstepping kernels for the controller; solved with ``kernel_n`` points otherwise
        (not needed for an uncoupled system or a ``FeedbackLaw``).
    kernel_n : int, optional
        Kernel grid points, default ``n + 1`` (kernel nodes on the simulation nodes).
    max_updates : int
        Bound on ``n`` times the number of steps.

    Returns
    -------
    Simulation
        Times, L2 norm, control history and snapshots.

    Raises
    ------
    ParameterError
        On bad input, unequal speeds, a work bound exceeded, or an ill-posed boundary loop.
    """
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem", system)
    c = system.lam
    if abs(system.mu - c) > 1e-12 * c:
        raise ParameterError(
            "system",
            "equal speeds lam == mu (the characteristic lattice is built on one crossing grid)",
            (system.lam, system.mu),
        )
    delta = nonnegative("delta", delta)
    t_end = positive("t_end", t_end)
    n = positive_int("n", n, minimum=2)
    kernel_n = n + 1 if kernel_n is None else positive_int("kernel_n", kernel_n, minimum=3)
    if snapshot_every is not None:
        snapshot_every = positive_int("snapshot_every", snapshot_every)
    max_updates = positive_int("max_updates", max_updates)

    dt = 1.0 / (c * n)
    steps = max(1, int(math.ceil(t_end / dt - 1e-9)))
    if steps * n > max_updates:
        raise ParameterError("(n, t_end)", f"at most max_updates = {max_updates} cell updates", steps * n)

    x = np.linspace(0.0, 1.0, n + 1)
    xm = (np.arange(n) + 0.5) / n
    u = _initial("u0", u0, x)
    v = _initial("v0", v0, x)

    law = _feedback_law(system, controller, kernels, kernel_n)
    bg = finite_real("boundary_gain", law.boundary_gain)
    weights = np.full(n + 1, 1.0 / n)
    weights[[0, -1]] = 0.5 / n
    wu = weights * _gain_values("gain_u", law.gain_u, x)
    wv = weights * _gain_values("gain_v", law.gain_v, x)
    alpha = bg + wu[-1]  # weight of u(t, 1) in V
    beta = wv[-1]  # weight of v(t, 1) in V
    wu_in, wv_in = wu[:-1], wv[:-1]
    ratio, decay, phi1, phi2 = _filter_coefficients(law.filter, dt)
    gain_now = ratio + (1.0 - ratio) * phi2

    # Trapezoidal factor on a half step (length dt / 2) and the couplings at the nodes.
    h4 = dt / 4.0
    spm, smp = h4 * system.sigma_pm_at(x), h4 * system.sigma_mp_at(x)
    spm_m, smp_m = h4 * system.sigma_pm_at(xm), h4 * system.sigma_mp_at(xm)
    det_m = 1.0 - spm_m * smp_m
    det_i = 1.0 - spm[1:-1] * smp[1:-1]
    det_0 = 1.0 - smp[0] * system.q
    if np.any(np.abs(det_m) < 1e-12) or np.any(np.abs(det_i) < 1e-12) or abs(det_0) < 1e-12:
        raise ParameterError("n", "large enough for the trapezoidal coupling step to be solvable", n)
    inv_m, inv_i, inv_0 = 1.0 / det_m, 1.0 / det_i, 1.0 / det_0
    spm_n, rho, q = spm[-1], system.rho, system.q

    shift = delta / dt
    exact = abs(shift - round(shift)) <= _INTEGER_TOL * max(1.0, shift)
    lag = int(round(shift)) if exact else -1

    times = dt * np.arange(steps + 1)
    norm = np.empty(steps + 1)
    control = np.empty(steps + 1)
    snap_t: list[float] = []
    snap_u: list[Array] = []
    snap_v: list[Array] = []

    def record(j: int) -> None:
        norm[j] = math.sqrt(float(weights @ (u * u + v * v)))
        if (snapshot_every is not None and j % snapshot_every == 0) or j == steps:
            snap_t.append(times[j])
            snap_u.append(u.copy())
            snap_v.append(v.copy())

    v_prev = float(wu @ u + wv @ v) + bg * u[-1]
    control[0] = ratio * v_prev
    w_state = control[0] - ratio * v_prev
    record(0)

    for j in range(1, steps + 1):
        # Half step: nodes -> midpoints (u from the left node, v from the right node).
        ru = u[:-1] + spm[:-1] * v[:-1]
        rv = v[1:] + smp[1:] * u[1:]
        um = (ru + spm_m * rv) * inv_m
        vm = (rv + smp_m * ru) * inv_m
        # Half step: midpoints -> nodes.
        ru = um + spm_m * vm  # arrives at nodes 1..n
        rv = vm + smp_m * um  # arrives at nodes 0..n-1
        u[1:-1] = (ru[:-1] + spm[1:-1] * rv[1:]) * inv_i
        v[1:-1] = (rv[1:] + smp[1:-1] * ru[:-1]) * inv_i
        v[0] = rv[0] * inv_0
        u[0] = q * v[0]
        # Boundary x = 1: u' = ru_n + spm_n v', v' = rho u' + U(t_j - delta), U = C + g V.
        s = j - shift
        if exact:
            theta = 1.0 if lag == 0 else 0.0
            hist = control[j - lag] if 0 < lag <= j else 0.0
        elif s < 0.0:
            theta, hist = 0.0, 0.0
        else:
            idx, wts = _history_weights(s, j)
            theta = float(wts[-1]) if idx[-1] == j else 0.0
            past = idx < j
            hist = float(wts[past] @ control[idx[past]])
        base = decay * w_state + (1.0 - ratio) * phi1 * v_prev
        C = base + gain_now * float(wu_in @ u[:-1] + wv_in @ v[:-1])
        P = rho + theta * gain_now * alpha
        R = hist + theta * C
        Q = 1.0 - theta * gain_now * beta
        den = Q - spm_n * P
        if abs(den) < 1e-12 or abs(Q) < 1e-12:
            raise ParameterError("controller", "a boundary loop with a solvable implicit step", (theta, gain_now))
        u[-1] = (ru[-1] * Q + spm_n * R) / den
        v[-1] = (P * u[-1] + R) / Q
        v_now = float(wu @ u + wv @ v) + bg * u[-1]
        control[j] = base + gain_now * v_now
        w_state = control[j] - ratio * v_now
        v_prev = v_now
        record(j)

    return Simulation(
        times=times,
        norm=norm,
        control=control,
        x=x,
        snapshot_times=np.asarray(snap_t),
        u=np.asarray(snap_u),
        v=np.asarray(snap_v),
        delta=delta,
        dt=dt,
        n=n,
        delay_interpolation="exact shift" if exact else "Lagrange-4",
    )
