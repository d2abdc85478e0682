"""Time responses of delay LTI systems in LFT form, computed by the method of steps.

A delay system in linear fractional form (ControlSystems.jl's ``DelayLtiSystem``) is::

    x'(t) = A x(t) + B1 u(t) + B2 w(t)
    y(t)  = C1 x(t) + D11 u(t) + D12 w(t)
    z(t)  = C2 x(t) + D21 u(t) + D22 w(t)
    w_i(t) = z_i(t - tau_i),   tau_i > 0 (one delay per channel).

Any object with the attributes ``A, B1, B2, C1, C2, D11, D12, D21, D22`` (2-D arrays) and
``tau`` (1-D array) is accepted (:class:`LFTSystem`), and so are python-control's
``TransferFunction`` and ``StateSpace`` and a SISO
:class:`~nrobust.lti.transfer.QuasiTransferFunction` with point delays (realised by
:func:`~nrobust.lti.delay_lti.as_delay_lti`). The functions have python-control's
names, arguments and result (:class:`control.TimeResponseData`, MIMO shapes included), so
plotting code written for python-control keeps working.

Method (Bellen and Zennaro, *Numerical Methods for Delay Differential Equations*, Oxford
2003, Ch. 3 and 5, for the method of steps and its breakpoints):

* **Breakpoints.** With zero history (or a smooth history on ``[-max tau, 0)``) the solution
  can lose smoothness only at the points ``d + k_1 tau_1 + ... + k_m tau_m`` (``k_i >= 0``)
  where ``d`` is ``0`` or a discontinuity of the input (each sample of a sampled input, where
  linear interpolation has a kink; the ``breaks`` of a callable one). All of them up to the
  final time are computed first (their number is checked against ``max_nodes`` before
  anything is allocated) and every one is a node of the integration: between two
  consecutive breakpoints everything is analytic, and a shifted interval
  ``[a - tau_i, b - tau_i]`` never contains a breakpoint in its interior.
* **Integration.** The multiples of the smallest delay are breakpoints, so an interval
  between breakpoints is no longer than it, and on the interval ``w(t) = z(t - tau)`` is
  already known; the interval is cut into pieces as the tolerance asks. On a piece the
  solution is the degree-``DEGREE`` polynomial at the Chebyshev-Lobatto points that solves
  the integrated equation ``x(t) = x(a) + int_a^t (A x + B1 u + B2 w)`` exactly for the
  interpolant of the integrand (spectral integration, Greengard, SIAM J. Numer. Anal. 28(4),
  1991): spectral accuracy on analytic pieces, and the derivative discontinuities, all at
  piece ends, cost no accuracy.
* **Error control.** A piece is accepted when the last two Chebyshev coefficients of its
  ``x`` and ``z`` are below ``atol + rtol * scale`` (``scale`` the largest ``|x|``, ``|z|``
  seen so far): the usual tail estimate of a Chebyshev interpolant (Trefethen,
  *Approximation Theory and Approximation Practice*, SIAM 2013, Ch. 8); otherwise it is
  halved. The next piece length follows the estimate as in an adaptive Runge-Kutta code.
  The returned ``error_estimate`` is the sum of the accepted local estimates: an estimate of
  the global error of ``x`` and ``z`` for loops that do not amplify errors, not a bound.
* **Neutral loops** (``D22 != 0``). ``z`` jumps at breakpoints and the jumps travel along
  ``z(t) = ... + D22 z(t - tau)`` undamped. ``z`` is stored on each piece with its one-sided
  values at both ends, and the recurrence is evaluated at the nodes of each new piece from
  the stored values of the piece ``tau`` earlier (copied when the pieces line up, otherwise
  interpolated inside the one analytic interval they belong to): no jump is ever smoothed.
* **Impulses.** ``impulse_response`` sends a Dirac ``delta(t) e_j``: ``x(0+) = B1 e_j`` and
  ``D21 e_j delta(t)`` travels along the delay lines as a train of Diracs at breakpoints
  (weights from the same recurrence ``zeta(t) = D22 zeta(t - tau)``), each making ``x`` jump
  by ``B2 w``. The Dirac parts of ``y`` (``D11 delta``, ``D12`` times the train) are left out
  of the returned output, as python-control leaves out ``D delta``.

Outputs are right-continuous: at a breakpoint ``t``, ``w(t) = z(t - tau)`` is the value just
after it, and at the final time too ``x`` includes the jump of a Dirac of the impulse train
arriving there.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.polynomial import chebyshev as cheb
from numpy.typing import ArrayLike, NDArray

from .._validate import is_real_number, nonnegative, positive, positive_int
from ..errors import ConvergenceError, NrobustError, ParameterError
from .delay_lti import DelayLTI, as_delay_lti

if TYPE_CHECKING:
    from typing import TypeAlias

    import control

    from .transfer import QuasiTransferFunction

    #: What the responses accept: an LFT system, or a system :func:`as_delay_lti` converts.
    System: TypeAlias = "LFTSystem | control.StateSpace | control.TransferFunction | QuasiTransferFunction"

__all__ = [
    "DEGREE",
    "MAX_NODES",
    "LFTSystem",
    "default_horizon",
    "forced_response",
    "impulse_response",
    "initial_response",
    "step_response",
]

#: Degree of the Chebyshev polynomial on each piece (``DEGREE + 1`` Lobatto points).
DEGREE = 14
#: Default work bound: the largest number of pieces (integration intervals) of one response.
MAX_NODES = 100_000
#: Number of points of the time grid when ``T`` is ``None`` or a final time.
DEFAULT_POINTS = 1000
#: Time constants ``1 / |alpha|`` of the slowest mode that the default horizon covers: ``ln 1000``,
#: the slowest mode decayed to 0.1 % (python-control 0.10's default final time of a delay-free system).
SETTLING_CONSTANTS = math.log(1000.0)
#: Longest default horizon, in units of ``max(tau)`` (of 0.5 for a system without delay).
MAX_HORIZON = 1000.0

Array = NDArray[np.float64]
History = Callable[[float], ArrayLike]
InputFunction = Callable[[float], ArrayLike]


class LFTSystem(Protocol):
    """A delay system in LFT form: the attributes read by the responses of this module.

    ``A (n, n)``, ``B1 (n, nu)``, ``B2 (n, nw)``, ``C1 (ny, n)``, ``C2 (nw, n)``,
    ``D11 (ny, nu)``, ``D12 (ny, nw)``, ``D21 (nw, nu)``, ``D22 (nw, nw)`` and the delays
    ``tau (nw,)``, all ``> 0``.
    """

    @property
    def A(self) -> ArrayLike: ...
    @property
    def B1(self) -> ArrayLike: ...
    @property
    def B2(self) -> ArrayLike: ...
    @property
    def C1(self) -> ArrayLike: ...
    @property
    def C2(self) -> ArrayLike: ...
    @property
    def D11(self) -> ArrayLike: ...
    @property
    def D12(self) -> ArrayLike: ...
    @property
    def D21(self) -> ArrayLike: ...
    @property
    def D22(self) -> ArrayLike: ...
    @property
    def tau(self) -> ArrayLike: ...


@dataclass(frozen=True, eq=False)
class _Mats:
    """The checked matrices of an :class:`LFTSystem`."""

    A: Array
    B1: Array
    B2: Array
    C1: Array
    C2: Array
    D11: Array
    D12: Array
    D21: Array
    D22: Array
    tau: Array

    @property
    def n(self) -> int:
        return self.A.shape[0]

    @property
    def nu(self) -> int:
        return self.B1.shape[1]

    @property
    def ny(self) -> int:
        return self.C1.shape[0]

    @property
    def nw(self) -> int:
        return self.tau.size


_FIELDS = ("A", "B1", "B2", "C1", "C2", "D11", "D12", "D21", "D22", "tau")


def _matrix(name: str, value: Any, shape: tuple[int | None, int | None]) -> Array:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(name, "a real 2-D array", value) from exc
    if a.size == 0 and all(s is not None for s in shape) and 0 in shape:
        return np.zeros(shape)  # type: ignore[arg-type]
    if a.ndim != 2 or any(s is not None and s != t for s, t in zip(shape, a.shape, strict=True)):
        want = " x ".join("k" if s is None else str(s) for s in shape)
        raise ParameterError(name, f"a real {want} array", a.shape)
    if not np.all(np.isfinite(a)):
        raise ParameterError(name, "finite", value)
    return a


def _as_lft(system: System) -> LFTSystem:
    """``system`` itself if it has the LFT attributes, else converted by :func:`as_delay_lti`."""
    missing = [f for f in _FIELDS if not hasattr(system, f)]
    if not missing:
        return system  # type: ignore[return-value]
    try:  # python-control's systems, QuasiTransferFunction, StateSpaceTDS
        return as_delay_lti(system)
    except ParameterError as exc:
        raise ParameterError(
            "sys",
            "a DelayLTI, a python-control system, a QuasiTransferFunction or an object with attributes "
            f"{', '.join(_FIELDS)} (missing {missing})",
            type(system).__name__,
        ) from exc


def _check_system(system: System) -> _Mats:
    sys = _as_lft(system)
    try:
        tau = np.asarray(sys.tau, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ParameterError("sys.tau", "a 1-D array of delays > 0", sys.tau) from exc
    if np.ndim(sys.tau) > 1 or not np.all(np.isfinite(tau)) or np.any(tau <= 0.0):
        raise ParameterError("sys.tau", "a 1-D array of finite delays > 0", sys.tau)
    A = _matrix("sys.A", sys.A, (None, None))
    n = A.shape[0]
    if A.shape[1] != n:
        raise ParameterError("sys.A", "a square matrix", A.shape)
    nw = tau.size
    B1 = _matrix("sys.B1", sys.B1, (n, None))
    C1 = _matrix("sys.C1", sys.C1, (None, n))
    nu, ny = B1.shape[1], C1.shape[0]
    return _Mats(
        A=A,
        B1=B1,
        B2=_matrix("sys.B2", sys.B2, (n, nw)),
        C1=C1,
        C2=_matrix("sys.C2", sys.C2, (nw, n)),
        D11=_matrix("sys.D11", sys.D11, (ny, nu)),
        D12=_matrix("sys.D12", sys.D12, (ny, nw)),
        D21=_matrix("sys.D21", sys.D21, (nw, nu)),
        D22=_matrix("sys.D22", sys.D22, (nw, nw)),
        tau=tau,
    )


def _abscissa(m: _Mats) -> float:
    """The spectral abscissa ``alpha`` of the system (nan when it cannot be computed)."""
    if not m.nw:
        return float(np.max(np.linalg.eigvals(m.A).real)) if m.n else -np.inf
    try:
        sys = DelayLTI(m.A, m.B1, m.B2, m.C1, m.C2, m.D11, m.D12, m.D21, m.D22, m.tau)
        return float(sys.spectral_abscissa().value)
    except NrobustError:  # no abscissa within its work bound (or too many channels): no horizon from it
        return float("nan")


def default_horizon(sys: System, max_nodes: int = MAX_NODES) -> float:
    """The final time of the responses when ``T`` is None.

    With ``h = max(tau)`` (``0.5`` without delay) and ``alpha`` the spectral abscissa
    (:meth:`~nrobust.lti.delay_lti.DelayLTI.spectral_abscissa`; the eigenvalues of ``A`` without
    delay): ``max(20 h, ln(1000) / |alpha|)`` when ``alpha < 0`` (:data:`SETTLING_CONSTANTS` time
    constants of the slowest mode, which has then decayed to 0.1 %: python-control's default final
    time for a delay-free system), else ``20 h`` (also when ``alpha`` cannot be computed); at most
    :data:`MAX_HORIZON` ``h``, and halved (not below ``20 h``) while the delay breakpoints up to it
    exceed ``max_nodes / 10`` (the work bound).

    Examples
    --------
    >>> from nrobust.lti import delay, tf
    >>> T = (0.5 * delay(0.5) * tf([1.0], [1.0, 1.0, 0.0])).feedback(1)   # alpha = -0.353
    >>> round(default_horizon(T), 2)   # ln(1000) / 0.353, beyond 20 tau = 10
    19.57
    """
    m = _check_system(sys)
    max_nodes = positive_int("max_nodes", max_nodes)
    h = float(m.tau.max()) if m.nw else 0.5
    short = 20.0 * h
    alpha = _abscissa(m)
    if not alpha < 0.0:  # unstable, on the axis, or unknown: no settling to cover
        return short
    t_end = min(max(short, SETTLING_CONSTANTS / -alpha), MAX_HORIZON * h)
    while m.nw and t_end > short:
        try:
            _breakpoints(np.zeros(1), m.tau, t_end, max(max_nodes // 10, 1), 1e-12 * t_end)
            break
        except ParameterError:
            t_end = max(0.5 * t_end, short)
    return t_end


def _time_grid(T: ArrayLike | None, m: _Mats, max_nodes: int = MAX_NODES) -> Array:
    if T is None:
        return np.linspace(0.0, default_horizon(m, max_nodes), DEFAULT_POINTS)
    if is_real_number(T):
        return np.linspace(0.0, positive("T", T), DEFAULT_POINTS)
    try:
        t = np.asarray(T, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError("T", "a final time > 0 or a strictly increasing 1-D array of times", T) from exc
    if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
        raise ParameterError("T", "a strictly increasing 1-D array of at least 2 finite times", T)
    return t


@lru_cache(maxsize=4)
def _chebyshev(p: int) -> tuple[Array, Array, Array, Array]:
    """Lobatto nodes on ``[-1, 1]``, barycentric weights, integration matrix, values-to-coefficients."""
    nodes: Array = -np.cos(np.pi * np.arange(p + 1) / p)
    weights: Array = np.where(np.arange(p + 1) % 2 == 0, 1.0, -1.0)
    weights[0] *= 0.5
    weights[-1] *= 0.5
    to_coef: Array = np.asarray(np.linalg.inv(cheb.chebvander(nodes, p)), dtype=float)
    integrated = np.column_stack([cheb.chebval(nodes, cheb.chebint(np.eye(p + 1)[k], lbnd=-1.0)) for k in range(p + 1)])
    integration: Array = np.asarray(integrated @ to_coef, dtype=float)
    return nodes, weights, integration, to_coef


def _barycentric(values: Array, xi: Array, nodes: Array, weights: Array) -> Array:
    """Evaluate polynomials given at the Lobatto nodes: ``values (m, p+1, c)`` at ``xi (m,)``."""
    diff = xi[:, None] - nodes[None, :]
    hit = np.abs(diff) < 1e-15
    diff[hit] = 1.0
    ratio = weights[None, :] / diff
    out = np.einsum("mj,mjc->mc", ratio, values) / ratio.sum(axis=1)[:, None]
    rows, cols = np.nonzero(hit)
    out[rows] = values[rows, cols]
    return out


def _dedupe(points: Array, tol: float) -> Array:
    points = np.sort(points)
    if points.size < 2:
        return points
    keep = np.concatenate(([True], np.diff(points) > tol))
    return points[keep]


def _nearest(points: Array, at: Array) -> Array:
    """The nearest of the sorted ``points`` to each of ``at``."""
    j = np.searchsorted(points, at)
    lo = points[np.clip(j - 1, 0, points.size - 1)]
    hi = points[np.clip(j, 0, points.size - 1)]
    return np.where(np.abs(lo - at) <= np.abs(hi - at), lo, hi)


def _breakpoints(starts: Array, tau: Array, t_end: float, max_nodes: int, tol: float) -> Array:
    """Every ``d + sum k_i tau_i <= t_end`` (``d`` in ``starts``), counted before it is built."""
    combos = np.zeros(1)
    for ti in np.unique(tau):
        counts = np.floor((t_end - combos) / ti + 1e-9).astype(np.int64) + 1
        total = int(counts.sum())
        if total > max_nodes:
            raise ParameterError(
                "max_nodes", f">= the number of delay breakpoints up to T (more than {total})", max_nodes
            )
        offsets = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
        combos = _dedupe(np.repeat(combos, counts) + ti * offsets, tol)
    counts = np.searchsorted(combos, t_end - starts + tol, side="right")
    total = int(counts.sum())
    if total > max_nodes:
        raise ParameterError("max_nodes", f">= the number of delay breakpoints up to T ({total})", max_nodes)
    offsets = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
    points = np.repeat(starts, counts) + combos[offsets]
    points = _dedupe(points[points < t_end - tol], tol)
    return np.concatenate((points, [t_end]))


@dataclass
class _Input:
    """An input signal on internal time ``s >= 0``: values (right limits) and discontinuities."""

    values: Callable[[Array, bool], Array]
    breaks: Array
    impulse: Array | None = None


def _user_values(name: str, f: Callable[[float], Any], t: float, size: int, what: str) -> Array:
    """``f(t)`` as a finite vector of ``size`` numbers, or a ParameterError naming ``name``."""
    try:
        value = np.asarray(f(t), dtype=float).reshape(-1)
    except Exception as exc:
        raise ParameterError(name, f"a callable returning {what} (calling it at t = {t!r} raised)", f) from exc
    if value.size != size or not np.all(np.isfinite(value)):
        raise ParameterError(name, f"a callable returning {what}", f"{value!r} at t = {t!r}")
    return value


def _constant_input(u: Array) -> _Input:
    piece = np.tile(u, (DEGREE + 1, 1))
    return _Input(lambda t, left_end: piece if t.size == DEGREE + 1 else np.tile(u, (t.size, 1)), np.zeros(1))


class _Solution:
    """Pieces of ``x`` and ``z`` on ``[0, t_end]``, built by :func:`_integrate`."""

    def __init__(self, m: _Mats, bps: Array, p: int, tol: float, history: History | None) -> None:
        self.m, self.bps, self.p, self.tol, self.history = m, bps, p, tol, history
        cap = bps.size + 16
        self.count = 0
        self.starts = np.empty(cap)
        self.ends = np.empty(cap)
        self.region = np.empty(cap, dtype=np.int64)
        self.X = np.empty((cap, p + 1, m.n))
        self.Z = np.empty((cap, p + 1, m.nw))
        self.region_first: list[int] = []
        self.region_last: list[int] = []
        self.error_estimate = 0.0
        # The jump of x at t_end itself (an impulse train reaching the last breakpoint): right limit there.
        self.end_jump = np.zeros(m.n)

    def append(self, a: float, b: float, r: int, X: Array, Z: Array) -> None:
        k = self.count
        if k == self.starts.size:
            cap = 2 * k
            self.starts = np.resize(self.starts, cap)
            self.ends = np.resize(self.ends, cap)
            self.region = np.resize(self.region, cap)
            self.X = np.concatenate((self.X, np.empty_like(self.X)))
            self.Z = np.concatenate((self.Z, np.empty_like(self.Z)))
        self.starts[k], self.ends[k], self.region[k] = a, b, r
        self.X[k], self.Z[k] = X, Z
        self.count = k + 1

    def history_values(self, s: Array, i: int) -> Array:
        if self.history is None:
            return np.zeros(s.size)
        out = np.empty(s.size)
        what = f"{self.m.nw} finite value(s)"
        for j, sj in enumerate(s):
            out[j] = _user_values("history", self.history, float(sj), self.m.nw, what)[i]
        return out

    def delayed(self, a: float, b: float, t: Array, i: int) -> Array:
        """``z_i(t - tau_i)`` at the nodes ``t`` of a piece ``[a, b]`` between two breakpoints."""
        ti, tol = self.m.tau[i], self.tol
        if b - ti <= tol:
            return self.history_values(t - ti, i)
        starts = self.starts[: self.count]
        sa, sb = a - ti, b - ti
        k = int(np.searchsorted(starts, sa + tol, side="right")) - 1
        if abs(starts[k] - sa) <= tol and abs(self.ends[k] - sb) <= tol:
            return self.Z[k, :, i]
        km = int(np.searchsorted(starts, 0.5 * (sa + sb), side="right")) - 1
        r = int(self.region[km])
        idx = np.clip(np.searchsorted(starts, t - ti, side="right") - 1, self.region_first[r], self.region_last[r])
        return self._eval(self.Z[:, :, i : i + 1], idx, t - ti)[:, 0]

    def _eval(self, V: Array, idx: Array, s: Array) -> Array:
        nodes, weights, _, _ = _chebyshev(self.p)
        a, b = self.starts[idx], self.ends[idx]
        return _barycentric(V[idx], 2.0 * (s - a) / (b - a) - 1.0, nodes, weights)

    def snap(self, s: Array) -> Array:
        """``s`` moved onto a breakpoint closer than the tolerance (so that sides are right)."""
        near = _nearest(self.bps, s)
        return np.where(np.abs(near - s) <= self.tol, near, s)

    def _pieces(self, s: Array) -> Array:
        return np.clip(np.searchsorted(self.starts[: self.count], s, side="right") - 1, 0, self.count - 1)

    def state(self, s: Array) -> Array:
        """``x(s)``, shape ``(len(s), n)``."""
        s = self.snap(s)
        X = self._eval(self.X, self._pieces(s), s)
        X[s >= self.bps[-1]] += self.end_jump
        return X

    def delayed_at(self, s: Array) -> Array:
        """``w(s) = z(s - tau)`` (right limits), shape ``(len(s), nw)``."""
        out = np.empty((s.size, self.m.nw))
        for i, ti in enumerate(self.m.tau):
            q = self.snap(s - ti)
            past = q < 0.0
            out[past, i] = self.history_values(q[past], i)
            if np.any(~past):
                out[~past, i] = self._eval(self.Z[:, :, i : i + 1], self._pieces(q[~past]), q[~past])[:, 0]
        return out


def _piece_operator(A: Array, h: float, p: int) -> tuple[Array, Array]:
    """``P, Q`` with ``vec(X) = P x(a) + Q vec(F)`` on a piece of length ``h`` (node-major order).

    ``X`` holds ``x`` at the Lobatto nodes and solves ``X = x(a) + (h/2) S (A X + F)``, ``S`` the
    spectral integration matrix: ``(I - (h/2) S (x) A) vec(X) = 1 (x) x(a) + (h/2) (S (x) I) vec(F)``.
    """
    n = A.shape[0]
    _, _, S, _ = _chebyshev(p)
    K = np.eye((p + 1) * n) - 0.5 * h * np.kron(S, A)
    G = np.linalg.inv(K)
    P = G @ np.kron(np.ones((p + 1, 1)), np.eye(n))
    Q = 0.5 * h * G @ np.kron(S, np.eye(n))
    return P, Q


def _integrate(
    m: _Mats,
    t_end: float,
    u: _Input,
    x0: Array,
    history: History | None,
    rtol: float,
    atol: float,
    max_nodes: int,
) -> _Solution:
    """March the method of steps over ``[0, t_end]``."""
    p = DEGREE
    nodes, _, _, to_coef = _chebyshev(p)
    tol = 1e-12 * max(t_end, 1.0)
    bps = _breakpoints(_dedupe(u.breaks, tol), m.tau, t_end, max_nodes, tol)
    sol = _Solution(m, bps, p, tol, history)
    # The operators of the piece lengths met so far, within a memory budget of about 32 MB.
    operators: dict[float, tuple[Array, Array]] = {}
    budget = max(8, 2_000_000 // max(((p + 1) * m.n) ** 2, 1))
    norm_a = float(np.abs(m.A).sum(axis=1).max()) if m.n else 0.0
    h = t_end if norm_a == 0.0 else min(t_end, 4.0 / norm_a)
    x = x0.astype(float).copy()
    zimp = np.zeros((bps.size, m.nw)) if u.impulse is not None else None
    if u.impulse is not None:
        x = x + m.B1 @ u.impulse
    scale = float(np.abs(x).max()) if x.size else 0.0
    h_min = 1e-10 * max(t_end, 1.0)
    B1T, B2T, C2T, D21T, D22T = m.B1.T.copy(), m.B2.T.copy(), m.C2.T.copy(), m.D21.T.copy(), m.D22.T.copy()
    for r in range(bps.size):
        a = float(bps[r])
        if zimp is not None:
            w_imp = np.zeros(m.nw)
            for i, ti in enumerate(m.tau):
                j = int(np.searchsorted(bps, a - ti - tol))
                if j < bps.size and abs(bps[j] - (a - ti)) <= tol:
                    w_imp[i] = zimp[j, i]
            zimp[r] = m.D22 @ w_imp + (m.D21 @ u.impulse if r == 0 else 0.0)  # type: ignore[operator]
            x = x + m.B2 @ w_imp
        if r == bps.size - 1:
            sol.end_jump = x - sol.X[sol.count - 1, -1] if sol.count else np.zeros(m.n)
            break
        b = float(bps[r + 1])
        pieces = max(1, math.ceil((b - a) / h - 1e-9))
        todo = [(a + (b - a) * (j + 1) / pieces, a + (b - a) * j / pieces) for j in range(pieces)][::-1]
        sol.region_first.append(sol.count)
        while todo:
            end, start = todo.pop()
            length = end - start
            t = start + 0.5 * length * (nodes + 1.0)
            t[0], t[-1] = start, end
            U = u.values(t, True)
            W = np.empty((p + 1, m.nw))
            for i in range(m.nw):
                W[:, i] = sol.delayed(start, end, t, i)
            F = U @ B1T + W @ B2T
            key = round(length / tol, 2)  # lengths equal but for rounding share one operator
            if key not in operators:
                if len(operators) >= budget:
                    operators.clear()
                operators[key] = _piece_operator(m.A, length, p)
            P, Q = operators[key]
            X = (P @ x + Q @ F.ravel()).reshape(p + 1, m.n)
            Z = X @ C2T + U @ D21T + W @ D22T
            both = np.hstack((X, Z))
            tail = np.abs(to_coef[-2:] @ both).sum(axis=0).max() if both.size else 0.0
            scale = max(scale, float(np.abs(both).max()) if both.size else 0.0)
            threshold = atol + rtol * scale
            if tail > threshold:
                if length < h_min:
                    raise ConvergenceError(
                        f"the local error estimate {tail:.3g} stays above atol + rtol * scale = {threshold:.3g} "
                        f"on a piece of length {length:.3g} at t = {start:.6g}; loosen rtol/atol"
                    )
                mid = 0.5 * (start + end)
                todo += [(end, mid), (mid, start)]
                h = 0.5 * length
                continue
            if sol.count >= max_nodes:
                raise ConvergenceError(
                    f"more than max_nodes = {max_nodes} pieces needed to reach the tolerance "
                    f"(stopped at t = {start:.6g} of {t_end:.6g}); raise max_nodes or loosen rtol/atol"
                )
            sol.append(start, end, r, X, Z)
            sol.error_estimate += float(tail)
            x = X[-1]
            growth = 0.8 * (threshold / max(tail, 1e-300)) ** (1.0 / p)
            h = length * min(4.0, max(0.2, growth))
        sol.region_last.append(sol.count - 1)
    return sol


def _options(rtol: float, atol: float, max_nodes: int) -> tuple[float, float, int]:
    return positive("rtol", rtol), nonnegative("atol", atol), positive_int("max_nodes", max_nodes)


def _state(name: str, X0: ArrayLike, n: int) -> Array:
    x0 = np.asarray(X0, dtype=float)
    if x0.ndim == 0:
        x0 = np.full(n, float(x0))
    x0 = x0.reshape(-1)
    if x0.shape != (n,) or not np.all(np.isfinite(x0)):
        raise ParameterError(name, f"a finite number or a vector of {n} finite numbers", X0)
    return x0


def _check_history(history: History | None, m: _Mats) -> History | None:
    if history is None:
        return None
    if not callable(history):
        raise ParameterError("history", "a callable t -> z(t) for t < 0 (a vector of length nw), or None", history)
    _user_values(
        "history", history, -float(m.tau.max()) if m.nw else -1.0, m.nw, f"vectors of nw = {m.nw} finite values"
    )
    return history


def _respond(
    m: _Mats, t: Array, u: _Input, x0: Array, history: History | None, opts: tuple[float, float, int]
) -> tuple[Array, Array, Array, _Solution]:
    """``y (ny, nt)``, ``x (n, nt)``, ``u (nu, nt)`` at the times ``t`` (starting at ``t[0]``)."""
    s = t - t[0]
    sol = _integrate(m, float(s[-1]), u, x0, history, *opts)
    X = sol.state(s)
    W = sol.delayed_at(s)
    U = np.asarray(u.values(sol.snap(s), False), dtype=float)
    Y = X @ m.C1.T + U @ m.D11.T + W @ m.D12.T
    return Y.T, X.T, U.T, sol


def _labels(prefix: str, k: int) -> list[str]:
    return [f"{prefix}[{i}]" for i in range(k)]


def _per_input(
    sys: System,
    T: ArrayLike | None,
    X0: ArrayLike,
    impulse: bool,
    rtol: float,
    atol: float,
    max_nodes: int,
    **kwargs: Any,
) -> control.TimeResponseData:
    import control

    m = _check_system(sys)
    t = _time_grid(T, m, max_nodes)
    x0 = _state("X0", X0, m.n)
    opts = _options(rtol, atol, max_nodes)
    yout = np.empty((m.ny, m.nu, t.size))
    xout = np.empty((m.n, m.nu, t.size))
    uout = np.zeros((m.nu, m.nu, t.size))
    error, pieces = 0.0, 0
    for j in range(m.nu):
        e = np.zeros(m.nu)
        e[j] = 1.0
        u = _constant_input(np.zeros(m.nu)) if impulse else _constant_input(e)
        if impulse:
            u.impulse = e
        y, x, uu, sol = _respond(m, t, u, x0, None, opts)
        yout[:, j], xout[:, j], uout[:, j] = y, x, uu
        error, pieces = max(error, sol.error_estimate), pieces + sol.count
    kind = "impulse" if impulse else "step"
    resp = control.TimeResponseData(
        t,
        yout,
        xout,
        uout,
        issiso=m.ny == 1 and m.nu == 1,
        output_labels=_labels("y", m.ny),
        input_labels=_labels("u", m.nu),
        state_labels=_labels("x", m.n),
        title=f"{kind.capitalize()} response of a delay system",
        trace_labels=[f"From u[{j}]" for j in range(m.nu)],
        trace_types=[kind] * m.nu,
        plot_inputs=False,
        **kwargs,
    )
    resp.error_estimate, resp.n_pieces = error, pieces
    return resp


def step_response(
    sys: System,
    T: ArrayLike | None = None,
    X0: ArrayLike = 0.0,
    *,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_nodes: int = MAX_NODES,
    transpose: bool = False,
    return_x: bool = False,
    squeeze: bool | None = None,
) -> control.TimeResponseData:
    """Step response of a delay system in LFT form (python-control's ``step_response``).

    For each input ``j``, ``u = e_j`` for ``t >= T[0]``, zero history and ``x(T[0]) = X0``.

    Parameters
    ----------
    sys : LFTSystem, python-control system or QuasiTransferFunction
        Any object with ``A, B1, B2, C1, C2, D11, D12, D21, D22, tau`` (e.g.
        ``nrobust.lti.delay_lti.DelayLTI``), or a system
        :func:`~nrobust.lti.delay_lti.as_delay_lti` converts.
    T : array_like or float, optional
        Strictly increasing output times, or a final time (1000 points from 0); by default
        1000 points on ``[0, default_horizon(sys)]``: ``max(20 max(tau), ln(1000) / |alpha|)`` for a
        spectral abscissa ``alpha < 0``, within a work bound (:func:`default_horizon`).
    X0 : array_like, optional
        Initial state ``x(T[0])``.
    rtol, atol : float, optional
        Local tolerance of each piece: its Chebyshev tail must be ``<= atol + rtol * scale``
        (module docstring).
    max_nodes : int, optional
        Work bound: the largest number of breakpoints (checked before any allocation,
        :class:`~nrobust.errors.ParameterError`) and of pieces
        (:class:`~nrobust.errors.ConvergenceError`), per input.
    transpose, return_x, squeeze : optional
        As in python-control.

    Returns
    -------
    control.TimeResponseData
        ``outputs`` of shape ``(ny, nu, len(T))`` (squeezed for SISO), ``states``
        ``(n, nu, len(T))``; the attributes ``error_estimate`` (largest over inputs of the sum
        of accepted local error estimates) and ``n_pieces`` (pieces integrated, all inputs).

    Examples
    --------
    ControlSystems.jl's ``feedback(delay(1) * 2/s, 1)``: ``y = 2 (t - 1)`` on ``[1, 2]``.

    >>> from types import SimpleNamespace
    >>> loop = SimpleNamespace(A=[[0.0]], B1=[[0.0]], B2=[[2.0]], C1=[[1.0]], C2=[[-1.0]],
    ...                        D11=[[0.0]], D12=[[0.0]], D21=[[1.0]], D22=[[0.0]], tau=[1.0])
    >>> float(step_response(loop, [0.0, 1.5, 3.0]).outputs[1])
    1.0
    """
    return _per_input(sys, T, X0, False, rtol, atol, max_nodes, transpose=transpose, return_x=return_x, squeeze=squeeze)


def impulse_response(
    sys: System,
    T: ArrayLike | None = None,
    X0: ArrayLike = 0.0,
    *,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_nodes: int = MAX_NODES,
    transpose: bool = False,
    return_x: bool = False,
    squeeze: bool | None = None,
) -> control.TimeResponseData:
    """Impulse response of a delay system in LFT form (python-control's ``impulse_response``).

    For each input ``j``, ``u = delta(t - T[0]) e_j``: ``x`` starts at ``X0 + B1 e_j`` and the
    Diracs ``D21 e_j delta`` that enter the delay lines travel along them (through ``D22``)
    and make ``x`` jump by ``B2 w`` where they come out. The Dirac parts of the output
    (``D11 delta``, ``D12`` times the delayed Diracs) are not included, as python-control
    leaves out ``D delta``. Parameters and result as :func:`step_response`.

    Parameters
    ----------
    sys : LFTSystem
        The delay system.
    T : array_like or float, optional
        Output times or final time (:func:`step_response`).
    X0 : array_like, optional
        Initial state before the impulse.
    rtol, atol, max_nodes, transpose, return_x, squeeze : optional
        As in :func:`step_response`.

    Returns
    -------
    control.TimeResponseData
        As :func:`step_response`.
    """
    return _per_input(sys, T, X0, True, rtol, atol, max_nodes, transpose=transpose, return_x=return_x, squeeze=squeeze)


def initial_response(
    sys: System,
    T: ArrayLike | None = None,
    X0: ArrayLike = 0.0,
    *,
    history: History | None = None,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_nodes: int = MAX_NODES,
    transpose: bool = False,
    return_x: bool = False,
    squeeze: bool | None = None,
) -> control.TimeResponseData:
    """Free response from ``x(T[0]) = X0`` and a history of the delay lines (zero by default).

    Parameters
    ----------
    sys : LFTSystem
        The delay system.
    T : array_like or float, optional
        Output times or final time (:func:`step_response`).
    X0 : array_like, optional
        Initial state.
    history : callable, optional
        ``history(t)`` for ``-max(tau) <= t <= 0`` (time relative to ``T[0]``; the value at 0
        is the left limit) returns ``z(t)``, a vector of length ``nw``: the content of the
        delay lines, which with ``x(0)`` is the state of an LFT delay system. It should be
        smooth there (its own kinks are not breakpoints); ``None`` is zero history.
    rtol, atol, max_nodes, transpose, return_x, squeeze : optional
        As in :func:`step_response`.

    Returns
    -------
    control.TimeResponseData
        ``outputs (ny, len(T))``, ``states (n, len(T))``, no inputs; ``error_estimate`` and
        ``n_pieces`` as in :func:`step_response`.
    """
    import control

    m = _check_system(sys)
    t = _time_grid(T, m, max_nodes)
    x0 = _state("X0", X0, m.n)
    hist = _check_history(history, m)
    opts = _options(rtol, atol, max_nodes)
    y, x, _, sol = _respond(m, t, _constant_input(np.zeros(m.nu)), x0, hist, opts)
    resp = control.TimeResponseData(
        t,
        y,
        x,
        None,
        issiso=m.ny == 1 and m.nu == 1,
        output_labels=_labels("y", m.ny),
        state_labels=_labels("x", m.n),
        title="Initial response of a delay system",
        trace_types=["initial"],
        transpose=transpose,
        return_x=return_x,
        squeeze=squeeze,
    )
    resp.error_estimate, resp.n_pieces = sol.error_estimate, sol.count
    return resp


def _sampled_input(U: Any, t: Array, nu: int) -> _Input:
    s = t - t[0]
    u = np.asarray(U, dtype=float)
    if u.ndim == 0:
        u = np.full((nu, s.size), float(u))
    elif u.ndim == 1 and nu == 1 and u.size == s.size:
        u = u[None, :]
    if u.shape != (nu, s.size) or not np.all(np.isfinite(u)):
        raise ParameterError("U", f"a number, or finite samples of shape ({nu}, {s.size}) (inputs x times)", u.shape)
    slopes = np.diff(u, axis=1) / np.diff(s)
    bend = np.abs(np.diff(slopes, axis=1)).max(axis=0) if nu else np.zeros(s.size - 2)
    size = max(float(np.abs(slopes).max()) if slopes.size else 0.0, 1.0)
    kinks = s[1:-1][bend > 1e-13 * size]
    rows = u.copy()

    def values(times: Array, left_end: bool) -> Array:
        return np.column_stack([np.interp(times, s, row) for row in rows]) if nu else np.zeros((times.size, 0))

    return _Input(values, np.concatenate(([0.0], kinks)))


def _callable_input(U: InputFunction, t: Array, nu: int, breaks: ArrayLike | None) -> _Input:
    """``U(t)`` called at absolute times; at a listed break, the node before it takes the left limit."""
    t0 = float(t[0])
    b = np.zeros(0) if breaks is None else np.asarray(breaks, dtype=float).reshape(-1)
    if not np.all(np.isfinite(b)):
        raise ParameterError("breaks", "finite times", breaks)
    b = np.sort(b[(b > t0) & (b < t[-1])])
    tol = 1e-12 * max(float(t[-1] - t0), 1.0)
    what = f"{nu} finite input value(s)"
    _user_values("U", U, t0, nu, what)

    def values(times: Array, left_end: bool) -> Array:
        at = times + t0
        if b.size:
            near = _nearest(b, at)
            on = np.abs(near - at) <= tol
            at = np.where(on, near, at)
            if left_end and on[-1]:
                at[-1] = np.nextafter(at[-1], -np.inf)
        out = np.empty((times.size, nu))
        for k, tk in enumerate(at):
            out[k] = _user_values("U", U, float(tk), nu, what)
        return out

    return _Input(values, np.concatenate(([0.0], b - t0)))


def forced_response(
    sys: System,
    T: ArrayLike,
    U: ArrayLike | InputFunction = 0.0,
    X0: ArrayLike = 0.0,
    *,
    history: History | None = None,
    breaks: Sequence[float] | None = None,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_nodes: int = MAX_NODES,
    transpose: bool = False,
    return_x: bool = False,
    squeeze: bool | None = None,
) -> control.TimeResponseData:
    """Response to an input (python-control's ``forced_response``, lsim).

    Parameters
    ----------
    sys : LFTSystem
        The delay system.
    T : array_like
        Strictly increasing times; the response starts at ``T[0]``.
    U : array_like or callable, optional
        Samples of shape ``(nu, len(T))`` (a 1-D array for one input, a number for a
        constant), linearly interpolated between samples as lsim does (each sample where the
        slope changes is a breakpoint, so the response to the interpolant is exact to the
        tolerance); or a callable ``U(t)`` returning the ``nu`` inputs at time ``t``.
    X0 : array_like, optional
        Initial state ``x(T[0])``.
    history : callable, optional
        Content of the delay lines before ``T[0]`` (:func:`initial_response`).
    breaks : sequence of float, optional
        Times where a callable ``U`` is discontinuous or not smooth (absolute times).
    rtol, atol, max_nodes, transpose, return_x, squeeze : optional
        As in :func:`step_response`.

    Returns
    -------
    control.TimeResponseData
        ``outputs (ny, len(T))``, ``states (n, len(T))``, ``inputs (nu, len(T))``;
        ``error_estimate`` and ``n_pieces`` as in :func:`step_response`.
    """
    import control

    m = _check_system(sys)
    if T is None:
        raise ParameterError("T", "a strictly increasing 1-D array of times (the input's sample times)", T)
    t = _time_grid(T, m, max_nodes)
    x0 = _state("X0", X0, m.n)
    hist = _check_history(history, m)
    opts = _options(rtol, atol, max_nodes)
    u = _callable_input(U, t, m.nu, breaks) if callable(U) else _sampled_input(U, t, m.nu)
    y, x, uu, sol = _respond(m, t, u, x0, hist, opts)
    resp = control.TimeResponseData(
        t,
        y,
        x,
        uu,
        issiso=m.ny == 1 and m.nu == 1,
        output_labels=_labels("y", m.ny),
        input_labels=_labels("u", m.nu),
        state_labels=_labels("x", m.n),
        title="Forced response of a delay system",
        trace_types=["forced"],
        plot_inputs=True,
        transpose=transpose,
        return_x=return_x,
        squeeze=squeeze,
    )
    resp.error_estimate, resp.n_pieces = sol.error_estimate, sol.count
    return resp
