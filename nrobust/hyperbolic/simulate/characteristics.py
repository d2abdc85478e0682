"""The marching schemes of the paper's plant (18)-(20) along its characteristics.

The closed loop marched is::

    u_t + lam u_x = sigma_pm(x) v,      u(t, 0) = q v(t, 0),
    v_t - mu  v_x = sigma_mp(x) u,      v(t, 1) = rho u(t, 1) + U(t - delta),

with ``U`` a :class:`~nrobust.hyperbolic.loops.FeedbackLaw` (:class:`Loop`: the actuated
boundary, the filter and the delayed control history; :class:`Recorder`: the norm and the
snapshots). :mod:`.normal_form` sets the grids up and calls :func:`march_lattice` or
:func:`march_two_grids`.

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

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..._validate import finite_real, positive
from ...errors import ParameterError
from ..plants.hyperbolic2x2 import Hyperbolic2x2

if TYPE_CHECKING:
    from scipy import sparse

__all__ = ["Loop", "Recorder", "march_lattice", "march_two_grids", "trapezoid_weights", "v_grid"]

Array = NDArray[np.float64]

#: Relative tolerance under which ``delta / dt`` counts as an integer.
_INTEGER_TOL = 1e-9


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


def trapezoid_weights(nodes: Array) -> Array:
    """Trapezoidal-rule weights on sorted, possibly non-uniform nodes."""
    gaps = np.diff(nodes)
    w = np.zeros(nodes.size)
    w[:-1] += gaps / 2.0
    w[1:] += gaps / 2.0
    return w


class Loop:
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
        self.advance(j, float(self.wu @ u + self.wv @ v) + self.bg * u[-1])

    def advance(self, j: int, v_now: float) -> None:
        """Store ``U(t_j)`` from ``V(t_j) = v_now`` and advance the filter (:meth:`commit`'s second half)."""
        base = self.decay * self.w_state + self.phi1 * self.v_prev
        self.control[j] = base + self.gain * v_now
        self.w_state = self.control[j] - self.ratio * v_now
        self.v_prev = v_now


def _row_dots(A: Array, W: Array) -> Array:
    """``sum_k A[r, k] W[r, k]`` for every row ``r``, each row summed alone (as many rows or one)."""
    return np.einsum("ij,ij->i", A, W)


def l2_norms(wu: Array, wv: Array, U: Array, V: Array) -> Array:
    """Discrete ``L^2`` norms of the states ``(U[r], V[r])`` (rows) with the quadrature weights ``wu, wv``.

    A state whose squares overflow (``|state|`` above about ``1e154``) is scaled first, so that
    its norm is still computed when it is finite; an overflowed state has norm ``inf``.
    """
    WU = wu if wu.shape == U.shape else np.broadcast_to(wu, U.shape)
    WV = wv if wv.shape == V.shape else np.broadcast_to(wv, V.shape)
    with np.errstate(over="ignore"):
        square = _row_dots(U * U, WU) + _row_dots(V * V, WV)
    norms = np.sqrt(square)
    for r in np.flatnonzero(np.isinf(square)):
        scale = float(max(np.max(np.abs(U[r])), np.max(np.abs(V[r]))))
        if math.isfinite(scale):
            norms[r] = scale * math.sqrt(
                float(
                    _row_dots((U[r : r + 1] / scale) ** 2, WU[r : r + 1])[0]
                    + _row_dots((V[r : r + 1] / scale) ** 2, WV[r : r + 1])[0]
                )
            )
        else:
            norms[r] = scale  # an overflowed state
    return norms


class Recorder:
    """L2 norm at every step and states every ``every`` steps (and at the end)."""

    def __init__(self, steps: int, every: int | None, wu: Array, wv: Array) -> None:
        self.steps, self.every, self.wu, self.wv = steps, every, wu, wv
        self.norm = np.empty(steps + 1)
        self.index: list[int] = []
        self.u: list[Array] = []
        self.v: list[Array] = []

    def __call__(self, j: int, u: Array, v: Array) -> None:
        self.store(j, float(l2_norms(self.wu, self.wv, u[None, :], v[None, :])[0]), u, v)

    def store(self, j: int, norm: float, u: Array, v: Array) -> None:
        """Record the norm ``norm`` of the state ``(u, v)`` at step ``j`` (:meth:`__call__`'s second half)."""
        self.norm[j] = norm
        if (self.every is not None and j % self.every == 0) or j == self.steps:
            self.index.append(j)
            self.u.append(u.copy())
            self.v.append(v.copy())


class _LatticeStep:
    """The lattice's step of the interior and of ``x = 0``, elementwise on rows ``(U, V)`` of states.

    ``U`` and ``V`` at ``t_j`` from those at ``t_{j-1}``, nodes ``0 .. n-1`` (``x = 1`` is the
    loop's); returns ``ru`` at ``x = 1``, the value of ``u`` arriving there before the coupling
    with the boundary (:meth:`Loop.solve`).
    """

    def __init__(self, system: Hyperbolic2x2, x: Array, dt: float) -> None:
        n = x.size - 1
        xm = (np.arange(n) + 0.5) / n
        h4 = dt / 4.0  # trapezoidal factor on a half step
        spm, smp = h4 * system.sigma_pm_at(x), h4 * system.sigma_mp_at(x)
        self.spm_m, self.smp_m = h4 * system.sigma_pm_at(xm), h4 * system.sigma_mp_at(xm)
        det_m = 1.0 - self.spm_m * self.smp_m
        det_i = 1.0 - spm[1:-1] * smp[1:-1]
        det_0 = 1.0 - smp[0] * system.q
        if np.any(np.abs(det_m) < 1e-12) or np.any(np.abs(det_i) < 1e-12) or abs(det_0) < 1e-12:
            raise ParameterError("cells", "large enough for the trapezoidal coupling step to be solvable", n)
        self.inv_m, self.inv_i, self.inv_0 = 1.0 / det_m, 1.0 / det_i, 1.0 / det_0
        self.spm_l, self.spm_i, self.smp_r, self.smp_i = spm[:-1], spm[1:-1], smp[1:], smp[1:-1]
        self.spm_last, self.q = float(spm[-1]), float(system.q)

    def __call__(self, U: Array, V: Array) -> Array:
        # Half step: nodes -> midpoints (u from the left node, v from the right node).
        ru = U[:, :-1] + self.spm_l * V[:, :-1]
        rv = V[:, 1:] + self.smp_r * U[:, 1:]
        um = (ru + self.spm_m * rv) * self.inv_m
        vm = (rv + self.smp_m * ru) * self.inv_m
        # Half step: midpoints -> nodes.
        ru = um + self.spm_m * vm  # arrives at nodes 1..n
        rv = vm + self.smp_m * um  # arrives at nodes 0..n-1
        U[:, 1:-1] = (ru[:, :-1] + self.spm_i * rv[:, 1:]) * self.inv_i
        V[:, 1:-1] = (rv[:, 1:] + self.smp_i * ru[:, :-1]) * self.inv_i
        V[:, 0] = rv[:, 0] * self.inv_0
        U[:, 0] = self.q * V[:, 0]
        return np.asarray(ru[:, -1])

    def matrix(self, n: int) -> sparse.csr_matrix:
        """The step as a sparse matrix ``T`` on columns ``X = [U; V]`` (``2 (n + 1)`` rows, one column a run).

        ``T X`` holds the new ``U`` and ``V`` at nodes ``0 .. n-1`` and, in the row of ``u(1)``,
        ``ru`` at ``x = 1`` (the row of ``v(1)`` is zero): the loop then sets both. The new value
        at a node depends on the old ones at that node and its two neighbours, so the columns are
        read from the step of 16 probe states (the unit states of every eighth node of ``u`` or of
        ``v``: no two of a probe reach one node), each entry the step of one unit state, computed
        by the elementwise formulas above. The matrix is checked against the elementwise step on
        one state of random values.
        """
        from scipy import sparse  # lazily: scipy.sparse is slow to import

        size, period = n + 1, 8
        probes = np.zeros((2 * period, 2 * size))
        for f in range(2):
            for c in range(period):
                probes[f * period + c, f * size + c : (f + 1) * size : period] = 1.0
        U, V = probes[:, :size].copy(), probes[:, size:].copy()
        ru = self(U, V)
        U[:, -1], V[:, -1] = ru, 0.0
        out = np.hstack([U, V])  # (probe, output)
        node = np.tile(np.arange(size), 2)  # node of each output
        rows, cols, vals = [], [], []
        for f in range(2):
            for c in range(period):
                k = node + ((c - node + period // 2) % period) - period // 2  # the probe's node nearest each output
                hit = (k >= 0) & (k < size) & (out[f * period + c] != 0.0)
                rows.append(np.flatnonzero(hit))
                cols.append(f * size + k[hit])
                vals.append(out[f * period + c][hit])
        T = sparse.csr_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(2 * size, 2 * size)
        )
        state = np.random.default_rng(0).uniform(-1.0, 1.0, (1, 2 * size))
        U, V = state[:, :size].copy(), state[:, size:].copy()
        U[:, -1], V[:, -1] = self(U, V), 0.0
        if not np.allclose(T @ state[0], np.hstack([U, V])[0], rtol=1e-12, atol=1e-12):
            raise AssertionError("the lattice step's matrix differs from the elementwise step")
        return T


def march_lattice(
    system: Hyperbolic2x2,
    x: Array,
    u: Array,
    v: Array,
    dt: float,
    steps: int,
    loop: Loop | Sequence[Loop],
    record: Recorder | Sequence[Recorder],
) -> None:
    """Equal speeds: the characteristic lattice (nodes at ``t_j``, midpoints at ``t_j + dt/2``).

    Several runs of one plant on one grid (other loops, other delays) march together: ``u``
    and ``v`` then hold one row per run, and ``loop`` and ``record`` are one per run. The
    interior of the lattice is advanced for all runs at once by one sparse product
    (:meth:`_LatticeStep.matrix`: the step is linear and the same for every run), the
    boundary ``x = 1`` by each run's loop, so that each run's values are those it has alone.
    """
    loops = [loop] if isinstance(loop, Loop) else list(loop)
    records = [record] if isinstance(record, Recorder) else list(record)
    U0, V0 = np.atleast_2d(u), np.atleast_2d(v)  # views: the rows of u and v hold the final states
    if not (U0.shape == V0.shape and U0.shape[0] == len(loops) == len(records)):
        raise ParameterError("(u, v)", "one row of u and of v per loop and recorder", (U0.shape, V0.shape))
    n = x.size - 1
    step = _LatticeStep(system, x, dt)
    T = step.matrix(n)
    last_u, last_v = n, 2 * n + 1  # the entries of u(1) and v(1) in a run's state [U, V]
    # the weights of every run stacked: the sums over the nodes are taken for all runs at once, each
    # run's on its own contiguous row (as many runs or one: the same sums)
    BG = np.array([lp.bg for lp in loops])
    W_in = np.hstack([np.stack([lp.wu for lp in loops]), np.stack([lp.wv for lp in loops])])
    W_last = W_in[:, [last_u, last_v]].T.copy()
    W_last[0] += BG  # V(t_j) = inner + the terms of x = 1 (bg: the u(1) feedthrough)
    W_in[:, [last_u, last_v]] = 0.0
    NW = np.hstack([np.stack([rec.wu for rec in records]), np.stack([rec.wv for rec in records])])
    X = np.hstack([U0, V0])  # one row per run
    runs = range(len(loops))
    for j in range(1, steps + 1):
        X = np.ascontiguousarray((T @ X.T).T)
        ru = X[:, last_u].tolist()
        inner = np.einsum("ij,ij->i", X, W_in)
        for r, v_inner in zip(runs, inner.tolist()):
            X[r, last_u], X[r, last_v] = loops[r].solve(j, ru[r], step.spm_last, v_inner)
        v_now = inner + W_last[0] * X[:, last_u] + W_last[1] * X[:, last_v]
        # einsum sums the squares without floating-point checks: an overflow shows as inf, rescaled by l2_norms
        norms = np.sqrt(np.einsum("ij,ij,ij->i", X, X, NW))
        U, V = X[:, : n + 1], X[:, n + 1 :]
        if not np.isfinite(norms).all():
            norms = l2_norms(NW[:, : n + 1], NW[:, n + 1 :], U, V)
        for r, v_r, norm in zip(runs, v_now.tolist(), norms.tolist()):
            loops[r].advance(j, v_r)
            records[r].store(j, norm, U[r], V[r])
    U0[:], V0[:] = X[:, : n + 1], X[:, n + 1 :]


def v_grid(mu: float, dt: float, offset: float = 0.0) -> Array:
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


def march_two_grids(
    system: Hyperbolic2x2,
    x: Array,
    xv: Array,
    u: Array,
    v: Array,
    dt: float,
    steps: int,
    loop: Loop,
    record: Recorder,
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
    phase1 = _Phase.build(system, np.concatenate([[0.0], (np.arange(n) + 0.5) * hu]), v_grid(system.mu, dt, 0.5))
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
