"""Time-domain simulation of the plant (18)-(20) with a delayed boundary control.

The closed loop simulated is::

    u_t + lam u_x = sigma_pm(x) v,      u(t, 0) = q v(t, 0),
    v_t - mu  v_x = sigma_mp(x) u,      v(t, 1) = rho u(t, 1) + U(t - delta),

with ``U(t) = 0`` for ``t < 0`` and ``U`` given by a state feedback
(:class:`~nrobust.hyperbolic.controllers.FeedbackLaw`): U_BS (eq. (47)),
U_BS2(K) (eq. (53)), their filtered versions (section 2.3.2) or any law of the form
``boundary_gain * u(t, 1) + int_0^1 gain_u u + gain_v v dxi``.

Equal speeds: a single characteristic lattice
---------------------------------------------
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
scheme is second-order convergent.

Unequal speeds: two characteristic grids
----------------------------------------
With ``lam != mu`` and ``dt = 1 / (lam n)``, ``u`` lives on ``k / n`` and ``v`` on
``1 - k mu dt`` at the sampled times, both shifted by half a cell at the half steps, so
that characteristics crossing between two sampled times are also coupled half-way (with
``lam = mu`` they meet exactly there: the lattice above), and no family of crossings is
skipped. Each half step is an exact index shift on both
grids; the couplings are integrated along the characteristics by Heun's method (Euler
predictor, trapezoidal corrector), the other unknown being read by 4-point Lagrange
interpolation across the grids (exactly where a characteristic sits). When ``1/(mu dt)``
is not an integer the ``v`` grid ends with a partial cell and ``v(t, 0)`` is the value,
interpolated, of the characteristic that was at ``x = mu dt / 2`` half a step earlier.
Transport stays exact when ``1/(mu dt)`` is an integer; the scheme is second order.
See ``docs/simulation.md``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..._json import fields_dict
from ..._validate import finite_real, nonnegative, positive, positive_int, renamed_keywords
from ...errors import ParameterError
from ..kernels.constant import solve_kernels
from ..loops.controllers import Controller, FeedbackLaw, OpenLoop, StateFeedback
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from .general import simulate_general

if TYPE_CHECKING:
    from scipy import sparse

__all__ = ["DEFAULT_CELLS", "Simulation", "simulate", "v_nodes"]

Array = NDArray[np.float64]
InitialState = Callable[[Array], Any] | Array

#: Relative tolerance under which ``delta / dt`` counts as an integer.
_INTEGER_TOL = 1e-9
#: Default number of cells of the ``u`` grid (``dt = 1 / (lam cells)``): the grid of the
#: paper's figures, 0.1-0.4 s per run of the paper's example to ``t = 10``
#: (``docs/simulation.md``). It also caps the default kernel grid of :func:`simulate`,
#: ``min(cells, DEFAULT_CELLS) + 1`` (kernel nodes on the ``u`` nodes).
DEFAULT_CELLS = 400
#: Default bound on the number of node updates (nodes times steps).
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

    times: Array
    norm: Array
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
            f"snapshots={self.snapshot_times.size}, delay_interpolation={self.delay_interpolation!r}, "
            f"scheme={self.scheme!r})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (lists of floats; an overflowed state as ``"inf"``/``"nan"``)."""
        return {"type": "Simulation", **fields_dict(self)}


def _real_state(name: str, raw: Any, expected: str) -> Array:
    """``raw`` as a float array; complex values with a nonzero imaginary part, booleans,
    strings and ragged sequences are refused (the simulated state is real)."""
    try:
        arr = np.asarray(raw)
    except (TypeError, ValueError):  # ragged nesting
        raise ParameterError(name, expected, raw) from None
    if arr.dtype.kind == "c":
        if np.any(arr.imag != 0):
            raise ParameterError(name, "real-valued (simulate evolves real states)", "complex values")
        arr = arr.real
    if arr.dtype.kind not in "iuf":
        raise ParameterError(name, expected, raw)
    return arr.astype(float)


def _initial(name: str, value: InitialState, x: Array) -> Array:
    """Sample an initial condition (callable or node values) on the nodes ``x``."""
    if callable(value):
        expected = "a callable returning real numbers on arrays of x"
        try:
            raw = value(x)
        except (TypeError, ValueError):
            raise ParameterError(name, expected, value) from None
        out = _real_state(name, raw, expected)
        if out.shape == ():
            out = np.full(x.shape, float(out))
    else:
        out = _real_state(name, value, f"a callable or an array of {x.size} node values")
    if out.shape != x.shape:
        raise ParameterError(name, f"{x.size} values, one per node", f"shape {out.shape}")
    if not np.all(np.isfinite(out)):
        raise ParameterError(name, "finite on [0, 1]", "non-finite values")
    return out.copy()


def _feedback_law(system: Hyperbolic2x2, controller: Any, kernels: Any, kernel_grid: int) -> Any:
    """The :class:`~nrobust.hyperbolic.controllers.FeedbackLaw` of ``controller`` (itself if it already is one)."""
    if hasattr(controller, "boundary_gain") and hasattr(controller, "gain_u"):
        return controller
    if not callable(getattr(controller, "feedback_law", None)):
        raise ParameterError("controller", "a FeedbackLaw or an object with feedback_law(system, kernels)", controller)
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
    i0 = math.floor(s)
    lo = max(0, min(i0 - 1, current - 3))
    hi = min(lo + 3, current)
    idx = np.arange(lo, hi + 1)
    return idx, _lagrange(idx.astype(float), s)


def _lagrange(nodes: Array, s: float) -> Array:
    """Weights of the Lagrange interpolant on ``nodes`` evaluated at ``s``."""
    w = np.ones(nodes.size)
    for m, node in enumerate(nodes):
        for other in nodes[np.arange(nodes.size) != m]:
            w[m] *= (s - other) / (node - other)
    return w


def _stencil(nodes: Array, targets: Array) -> sparse.csr_matrix:
    """Four-point Lagrange interpolation from sorted ``nodes`` to ``targets``, as a matrix.

    A target on a node (a characteristic) is read exactly. A node closer than a quarter of
    the typical spacing to the previous one (the end of a short partial cell) is left out
    of the stencils, which keeps the weights bounded.
    """
    gaps = np.diff(nodes)
    keep = np.concatenate([[True], gaps >= 0.25 * float(np.median(gaps))])
    usable = np.flatnonzero(keep)
    size = min(4, usable.size)
    right = np.searchsorted(nodes[usable], targets, side="right")
    lo = np.clip(right - size // 2, 0, usable.size - size)
    index = usable[lo[:, None] + np.arange(size)[None, :]]
    weight = np.empty(index.shape)
    tol = 1e-9 * float(gaps.min())
    for row, target in enumerate(targets):
        hit = np.flatnonzero(np.abs(nodes - target) <= tol)
        if hit.size:
            index[row], weight[row] = hit[0], np.eye(size)[0]
        else:
            weight[row] = _lagrange(nodes[index[row]], float(target))
    rows = np.repeat(np.arange(targets.size), size)
    from scipy import sparse  # lazily: scipy.sparse is slow to import

    return sparse.csr_matrix((weight.ravel(), (rows, index.ravel())), shape=(targets.size, nodes.size))


def _trapezoid_weights(nodes: Array) -> Array:
    """Trapezoidal-rule weights on sorted, possibly non-uniform nodes."""
    gaps = np.diff(nodes)
    w = np.zeros(nodes.size)
    w[:-1] += gaps / 2.0
    w[1:] += gaps / 2.0
    return w


class _Loop:
    """The actuated boundary ``v(t, 1) = rho u(t, 1) + U(t - delta)`` and the control history.

    ``V(t) = boundary_gain u(t, 1) + int gain_u u + gain_v v`` (trapezoidal rule);
    ``U = (a/b) V + w`` with ``b w' + w = (1 - a/b) V`` (``U = V`` without filter), so
    ``U_j = base_j + g V_j`` with ``base_j`` known from step ``j - 1``.
    """

    def __init__(self, law: Any, wu: Array, wv: Array, rho: float, delta: float, dt: float, steps: int) -> None:
        self.bg = finite_real("boundary_gain", law.boundary_gain)
        self.wu, self.wv, self.rho = wu, wv, rho
        self.alpha = self.bg + wu[-1]  # weight of u(t, 1) in V (node x = 1 last on both grids)
        self.beta = wv[-1]  # weight of v(t, 1) in V
        self.ratio, self.decay, phi1, phi2 = _filter_coefficients(law.filter, dt)
        self.phi1 = (1.0 - self.ratio) * phi1
        self.gain = self.ratio + (1.0 - self.ratio) * phi2
        self.shift = delta / dt
        self.exact = abs(self.shift - round(self.shift)) <= _INTEGER_TOL * max(1.0, self.shift)
        self.lag = round(self.shift) if self.exact else -1
        self.control = np.empty(steps + 1)
        self.v_prev = 0.0
        self.w_state = 0.0

    def start(self, u: Array, v: Array) -> None:
        """``U(0) = (a/b) V(0)``: the filter starts at rest."""
        self.v_prev = float(self.wu @ u + self.wv @ v) + self.bg * u[-1]
        self.control[0] = self.ratio * self.v_prev
        self.w_state = 0.0

    def delayed(self, j: int) -> tuple[float, float]:
        """``U(t_j - delta) = hist + theta U(t_j)`` from the stored samples ``U(t_i)``, ``i < j``."""
        if self.exact:
            if self.lag == 0:
                return 1.0, 0.0
            return 0.0, (self.control[j - self.lag] if self.lag <= j else 0.0)
        s = j - self.shift
        if s < 0.0:
            return 0.0, 0.0
        idx, wts = _history_weights(s, j)
        theta = float(wts[-1]) if idx[-1] == j else 0.0
        past = idx < j
        return theta, float(wts[past] @ self.control[idx[past]])

    def solve(self, j: int, ru: float, a: float, v_inner: float) -> tuple[float, float]:
        """Boundary values ``(u, v)`` at ``x = 1`` and time ``t_j``.

        Solves ``u = ru + a v``, ``v = rho u + hist + theta U``,
        ``U = base + g (v_inner + alpha u + beta v)``, where ``v_inner`` is the part of
        ``V`` from the other nodes.
        """
        theta, hist = self.delayed(j)
        c = self.decay * self.w_state + self.phi1 * self.v_prev + self.gain * v_inner
        p = self.rho + theta * self.gain * self.alpha
        r = hist + theta * c
        q = 1.0 - theta * self.gain * self.beta
        den = q - a * p
        if abs(den) < 1e-12 or abs(q) < 1e-12:
            raise ParameterError("controller", "a boundary loop with a solvable implicit step", (theta, self.gain))
        u1 = (ru * q + a * r) / den
        return u1, (p * u1 + r) / q

    def commit(self, j: int, u: Array, v: Array) -> None:
        """Store ``U(t_j)`` from the final state at ``t_j`` and advance the filter."""
        v_now = float(self.wu @ u + self.wv @ v) + self.bg * u[-1]
        base = self.decay * self.w_state + self.phi1 * self.v_prev
        self.control[j] = base + self.gain * v_now
        self.w_state = self.control[j] - self.ratio * v_now
        self.v_prev = v_now


class _Recorder:
    """L2 norm at every step and states every ``every`` steps (and at the end)."""

    def __init__(self, steps: int, every: int | None, wu: Array, wv: Array) -> None:
        self.steps, self.every, self.wu, self.wv = steps, every, wu, wv
        self.norm = np.empty(steps + 1)
        self.index: list[int] = []
        self.u: list[Array] = []
        self.v: list[Array] = []

    def __call__(self, j: int, u: Array, v: Array) -> None:
        with np.errstate(over="ignore"):
            square = float(self.wu @ (u * u) + self.wv @ (v * v))
        if math.isinf(square):  # |state| above ~1e154: the squares overflow, the norm may not
            scale = float(max(np.max(np.abs(u)), np.max(np.abs(v))))
            if math.isfinite(scale):
                self.norm[j] = scale * math.sqrt(float(self.wu @ (u / scale) ** 2 + self.wv @ (v / scale) ** 2))
            else:
                self.norm[j] = scale  # an overflowed state
        else:
            self.norm[j] = math.sqrt(square)
        if (self.every is not None and j % self.every == 0) or j == self.steps:
            self.index.append(j)
            self.u.append(u.copy())
            self.v.append(v.copy())


def _march_lattice(
    system: Hyperbolic2x2, x: Array, u: Array, v: Array, dt: float, steps: int, loop: _Loop, record: _Recorder
) -> None:
    """Equal speeds: the characteristic lattice (nodes at ``t_j``, midpoints at ``t_j + dt/2``)."""
    n = x.size - 1
    xm = (np.arange(n) + 0.5) / n
    h4 = dt / 4.0  # trapezoidal factor on a half step
    spm, smp = h4 * system.sigma_pm_at(x), h4 * system.sigma_mp_at(x)
    spm_m, smp_m = h4 * system.sigma_pm_at(xm), h4 * system.sigma_mp_at(xm)
    det_m = 1.0 - spm_m * smp_m
    det_i = 1.0 - spm[1:-1] * smp[1:-1]
    det_0 = 1.0 - smp[0] * system.q
    if np.any(np.abs(det_m) < 1e-12) or np.any(np.abs(det_i) < 1e-12) or abs(det_0) < 1e-12:
        raise ParameterError("cells", "large enough for the trapezoidal coupling step to be solvable", n)
    inv_m, inv_i, inv_0 = 1.0 / det_m, 1.0 / det_i, 1.0 / det_0
    wu_in, wv_in = loop.wu[:-1], loop.wv[:-1]
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
        u[0] = system.q * v[0]
        u[-1], v[-1] = loop.solve(j, ru[-1], spm[-1], float(wu_in @ u[:-1] + wv_in @ v[:-1]))
        loop.commit(j, u, v)
        record(j, u, v)


def _v_grid(mu: float, dt: float, offset: float = 0.0) -> Array:
    """Positions of ``v`` (ascending): ``1 - (k + offset) mu dt`` in ``[0, 1]``, and ``x = 0``.

    ``offset = 0`` at the sampled times, ``1/2`` at the half steps. When no characteristic
    sits at 0, the point ``x = 0`` is added: the boundary of a partial cell.
    """
    hv = mu * dt
    count = math.floor(1.0 / hv - offset + 1e-9)
    nodes = 1.0 - hv * (np.arange(count, -1, -1) + offset)
    if nodes[0] <= 1e-9 * hv:
        nodes[0] = 0.0
        return nodes.astype(np.float64)
    return np.concatenate([[0.0], nodes]).astype(np.float64)


@dataclass(frozen=True, eq=False)
class _Phase:
    """Positions of ``u`` and ``v`` at the sampled times (phase 0) or the half steps (phase 1).

    Entry 0 of both arrays is ``x = 0``; in phase 0 the last entries are ``x = 1``.
    """

    xu: Array
    xv: Array
    pm_u: Array  # sigma_pm at xu
    mp_v: Array  # sigma_mp at xv
    v_at_u: sparse.csr_matrix  # v on xv -> values at xu
    u_at_v: sparse.csr_matrix  # u on xu -> values at xv

    @classmethod
    def build(cls, system: Hyperbolic2x2, xu: Array, xv: Array) -> _Phase:
        return cls(xu, xv, system.sigma_pm_at(xu), system.sigma_mp_at(xv), _stencil(xv, xu), _stencil(xu, xv))


@dataclass(frozen=True, eq=False)
class _HalfStep:
    """From phase ``a`` to phase ``b`` in ``dt / 2``: where each new value comes from.

    ``u`` entries ``1..`` of ``b`` come from ``u`` entries ``u_src`` of ``a`` (exact shift);
    the first ``m`` ``v`` entries of ``b`` (all but ``x = 1``) from the points ``mu dt / 2``
    upstream, read from ``a`` by ``v_up`` (a pick on characteristics, an interpolation for
    ``x = 0``), where ``u`` is read by ``u_up``.
    """

    a: _Phase
    b: _Phase
    u_src: NDArray[np.intp]
    m: int
    v_up: sparse.csr_matrix
    u_up: sparse.csr_matrix
    mp_up: Array

    @classmethod
    def build(cls, system: Hyperbolic2x2, a: _Phase, b: _Phase, u_src: NDArray[np.intp], dt: float) -> _HalfStep:
        m = b.xv.size - 1 if b.xv[-1] == 1.0 else b.xv.size
        up = np.minimum(b.xv[:m] + system.mu * dt / 2.0, 1.0)
        return cls(a, b, u_src, m, _stencil(a.xv, up), _stencil(a.xu, up), system.sigma_mp_at(up))


def _march_two_grids(
    system: Hyperbolic2x2,
    x: Array,
    xv: Array,
    u: Array,
    v: Array,
    dt: float,
    steps: int,
    loop: _Loop,
    record: _Recorder,
) -> None:
    """Unequal speeds: ``u`` on steps of ``lam dt``, ``v`` on steps of ``mu dt``, in half steps.

    At the sampled times ``u`` sits on ``x`` and ``v`` on ``xv``; at the half steps both are
    shifted by half a cell, so that characteristics crossing between two sampled times are
    also coupled half-way (on the lattice of equal speeds they meet exactly there) and no
    family of crossings is skipped. Transport is an exact index shift. The couplings are integrated over each
    half step by Heun's method (trapezoidal corrector), the other unknown being read by
    4-point Lagrange interpolation across the grids. ``v(t, 0)`` is the value of the
    characteristic that was at ``x = mu dt / 2`` half a step earlier (interpolated when no
    characteristic sits there), with the trapezoidal coupling to ``u(t, 0) = q v(t, 0)``.
    """
    n = x.size - 1
    hu = 1.0 / n
    phase0 = _Phase.build(system, x, xv)
    phase1 = _Phase.build(system, np.concatenate([[0.0], (np.arange(n) + 0.5) * hu]), _v_grid(system.mu, dt, 0.5))
    shift = np.arange(n)
    steps_ab = (
        _HalfStep.build(system, phase0, phase1, shift, dt),  # u entry k + 1 <- entry k
        _HalfStep.build(system, phase1, phase0, shift + 1, dt),  # u entry k + 1 <- entry k + 1
    )
    h = dt / 2.0
    h2 = dt / 4.0
    inv_0 = 1.0 / (1.0 - h2 * system.sigma_mp_at(np.zeros(1))[0] * system.q)
    wu_in, wv_in = loop.wu[:-1], loop.wv[:-1]
    u1, v1 = np.empty(phase1.xu.size), np.empty(phase1.xv.size)  # state at the half step
    ut, vt = np.empty_like(u), np.empty_like(v)  # state at the next sampled time

    def half(step: _HalfStep, uo: Array, vo: Array, un: Array, vn: Array, j: int | None) -> None:
        m, src = step.m, step.u_src
        fu_old = (step.a.pm_u * (step.a.v_at_u @ vo))[src]
        v_up = step.v_up @ vo
        fv_up = step.mp_up * (step.u_up @ uo)

        def close() -> None:
            vn[0] = (v_up[0] + h2 * fv_up[0]) * inv_0
            un[0] = system.q * vn[0]
            if j is not None:
                un[-1], vn[-1] = loop.solve(j, un[-1], 0.0, float(wu_in @ un[:-1] + wv_in @ vn[:-1]))

        un[1:] = uo[src] + h * fu_old
        vn[:m] = v_up + h * fv_up
        close()
        fu_new = step.b.pm_u * (step.b.v_at_u @ vn)
        fv_new = step.b.mp_v * (step.b.u_at_v @ un)
        un[1:] = uo[src] + h2 * (fu_old + fu_new[1:])
        vn[:m] = v_up + h2 * (fv_up + fv_new[:m])
        close()

    for j in range(1, steps + 1):
        half(steps_ab[0], u, v, u1, v1, None)
        half(steps_ab[1], u1, v1, ut, vt, j)
        u[:], v[:] = ut, vt
        loop.commit(j, u, v)
        record(j, u, v)


@renamed_keywords(n="cells", kernel_n="kernel_grid")
def simulate(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
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
    """Simulate the plant (18)-(20) under the feedback ``U(t - delta)``.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant, eqs. (18)-(20) (or (1)-(3) for a
        ``TransportSystem``), or a general plant (see the end of this docstring).
    controller : Controller or FeedbackLaw
        An object with ``feedback_law(system, kernels)`` (``OpenLoop``,
        ``FiniteTimeController`` = U_BS eq. (47), ``ReflectionController(K)`` = U_BS2
        eq. (53), ``FilteredController(a, b)``) or a ``FeedbackLaw``.
    delta : float
        Loop delay ``>= 0``; the plant receives ``U(t - delta)``, with ``U = 0`` for
        ``t < 0``.
    t_end : float
        Final time ``> 0``; the run ends at the first sampled time ``>= t_end``.
    u0, v0 : callable or array
        Initial state: callables on arrays of ``x``, or values on the nodes (``cells + 1``
        for ``u``; for ``v`` as many as :func:`v_nodes` returns).
    cells : int, default :data:`DEFAULT_CELLS`
        Cells of the ``u`` grid; the sampling step is ``dt = 1 / (lam cells)`` (formerly
        ``n``, a deprecated alias).
    snapshot_every : int, optional
        Store the state every this many steps (and at the end); default: final state only.
    kernels : Kernels, optional
        Backstepping kernels for the controller; solved on ``kernel_grid`` points otherwise
        (not needed for an uncoupled system or a ``FeedbackLaw``).
    kernel_grid : int, optional
        Kernel grid points (formerly ``kernel_n``, a deprecated alias); default
        ``min(cells, DEFAULT_CELLS) + 1``: the kernels are evaluated on the ``u`` nodes by
        linear interpolation, so their nodes are put there, up to :data:`DEFAULT_CELLS`
        cells (the kernel solver's cost grows like the cube of its grid).
    max_updates : int
        Bound on the number of node updates (nodes times steps).

    Returns
    -------
    Simulation
        Times, L2 norm, control history and snapshots.

    Raises
    ------
    ParameterError
        On bad input, a work bound exceeded, or an ill-posed boundary loop.

    Notes
    -----
    ``lam == mu``: characteristic lattice, exact transport, trapezoidal couplings at the
    crossings. ``lam != mu``: one grid per direction (steps ``lam dt`` and ``mu dt``),
    advanced in half steps by exact index shifts, Heun couplings with cubic cross-grid
    interpolation, and a partial last cell at ``x = 0`` for ``v`` when ``1/(mu dt)`` is
    not an integer.
    See ``docs/simulation.md``.

    A :class:`~nrobust.hyperbolic.general.GeneralHyperbolic2x2` with a constant ``lam/mu`` is
    simulated through its normal form (:func:`_simulate_normal_form`): the initial state is
    carried to it, the paper's plant simulated as above under the controller (a
    ``StateFeedback``'s gains mapped from the physical coordinates), and the states, the
    control ``U = e^{D(L)} U~`` and the norm ``sqrt(int_0^L u^2 + v^2 dx)`` are those of the
    physical plant (``x``, ``x_v``: the physical nodes; times in ``time_unit``). With a
    varying ``lam/mu`` it is simulated on its own time-of-flight grids
    (:func:`~nrobust.hyperbolic.simulate_general.simulate_general`: ``StateFeedback``,
    ``OpenLoop`` or a ``FeedbackLaw`` in the physical coordinates, such as U_BS of
    :meth:`~nrobust.hyperbolic.varying_kernels.VaryingKernels.feedback_law`; snapshots as
    above, ``scheme = "time-of-flight grids"``).
    """
    if isinstance(system, GeneralHyperbolic2x2):
        if not system.constant_ratio:
            return _simulate_varying(system, controller, delta, t_end, u0, v0, cells, snapshot_every)
        return _simulate_normal_form(
            system, controller, delta, t_end, u0, v0, cells, snapshot_every, kernels, kernel_grid, max_updates
        )
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
    kernel_grid: int | None,
    max_updates: int,
    norm_weights: tuple[Callable[[Array], Array], Callable[[Array], Array]] | None = None,
) -> Simulation:
    """:func:`simulate` on the paper's plant; ``norm_weights`` (functions of the nodes) weight ``u^2``, ``v^2``."""
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2, TransportSystem or GeneralHyperbolic2x2", system)
    delta = nonnegative("delta", delta)
    t_end = positive("t_end", t_end)
    n = positive_int("cells", cells, minimum=2)
    if kernel_grid is None:
        kernel_grid = min(n, DEFAULT_CELLS) + 1
    kernel_grid = positive_int("kernel_grid", kernel_grid, minimum=3)
    if snapshot_every is not None:
        snapshot_every = positive_int("snapshot_every", snapshot_every)
    max_updates = positive_int("max_updates", max_updates)

    lattice = abs(system.mu - system.lam) <= 1e-12 * system.lam
    dt = 1.0 / (system.lam * n)
    if not math.isfinite(t_end / dt):
        raise ParameterError("(cells, t_end)", f"at most max_updates = {max_updates} node updates", "inf")
    steps = max(1, math.ceil(t_end / dt - 1e-9))
    # the work bound before any grid is allocated (a lower bound of the node count below:
    # at least floor(1/(mu dt)) + 1 nodes of v, see _v_grid)
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

    u = _initial("u0", u0, x)
    v = _initial("v0", v0, xv)
    law = _feedback_law(system, controller, kernels, kernel_grid)
    w_x, w_v = _trapezoid_weights(x), _trapezoid_weights(xv)
    loop = _Loop(
        law,
        w_x * _gain_values("gain_u", law.gain_u, x),
        w_v * _gain_values("gain_v", law.gain_v, xv),
        system.rho,
        delta,
        dt,
        steps,
    )
    if norm_weights is not None:
        w_x, w_v = w_x * norm_weights[0](x), w_v * norm_weights[1](xv)
    record = _Recorder(steps, snapshot_every, w_x, w_v)
    loop.start(u, v)
    record(0, u, v)
    if lattice:
        _march_lattice(system, x, u, v, dt, steps, loop, record)
    else:
        _march_two_grids(system, x, xv, u, v, dt, steps, loop, record)

    times = (dt * np.arange(steps + 1)).astype(np.float64)
    return Simulation(
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


def _simulate_normal_form(
    plant: GeneralHyperbolic2x2,
    controller: Any,
    delta: float,
    t_end: float,
    u0: InitialState,
    v0: InitialState,
    cells: int,
    snapshot_every: int | None,
    kernels: Any,
    kernel_grid: int | None,
    max_updates: int,
) -> Simulation:
    """A general plant with a constant ``lam/mu``, simulated as its normal form and mapped back.

    ``u = e^{A + k} u~``, ``v = e^{D} v~`` at ``y(x)`` (:class:`~nrobust.hyperbolic.general.NormalForm`);
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
        return np.asarray(form.to_normal(at, _initial("u0", u0, at), 0.0)[1])

    def vn(nodes: Array) -> Array:
        at = physical(nodes)
        return np.asarray(form.to_normal(at, 0.0, _initial("v0", v0, at))[2])

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


def _simulate_varying(
    plant: GeneralHyperbolic2x2,
    controller: Any,
    delta: float,
    t_end: float,
    u0: InitialState,
    v0: InitialState,
    cells: int,
    snapshot_every: int | None,
) -> Simulation:
    """A general plant with a varying ``lam/mu``: :func:`~nrobust.hyperbolic.simulate_general.simulate_general`."""
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


@renamed_keywords(n="cells")
def v_nodes(system: Hyperbolic2x2, cells: int) -> Array:
    """Nodes (ascending) on which :func:`simulate` stores ``v`` for ``cells`` cells of ``u``.

    Equal speeds: the ``u`` nodes ``k / cells``. Otherwise ``1 - k mu dt``
    (``dt = 1/(lam cells)``) down to the last one in ``[0, 1]``, and ``x = 0`` when that
    one is not 0. (``cells`` was formerly ``n``, a deprecated alias.)
    """
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem", system)
    n = positive_int("cells", cells, minimum=2)
    if abs(system.mu - system.lam) <= 1e-12 * system.lam:
        return np.linspace(0.0, 1.0, n + 1)
    return _v_grid(system.mu, 1.0 / (system.lam * n))
