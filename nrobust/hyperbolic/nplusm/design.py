"""Design of the gain matrix ``K`` of ``U(t) = K u(t - delta, 1)`` on an ``n + m`` system: a local optimisation.

The loop of :mod:`~nrobust.hyperbolic.nplusm.system` is a determinant,
``F(s; delta, K) = det M(s; delta, K)``, ``M = E (Phi_v - (R + K e^{-delta s}) Phi_u)``, not
a scalar ``A + B e^{-delta s}`` with quasi-polynomial factors, so the core's loop families do
not describe it; the core's optimiser (:func:`nrobust.design.local_runs`: BFGS with the weak
Wolfe line search of Lewis and Overton, then a pattern search, several starts through any
``map``) runs on :class:`NPlusMGainProblem`, which evaluates the ``m n`` entries of ``K``:

* ``"decay_rate"``: minimise ``alpha(K)``, the spectral abscissa of the delay-free loop
  (:func:`~nrobust.roots.spectral_abscissa` of
  :class:`~nrobust.hyperbolic.nplusm.NPlusMCharacteristic`: certified with its proven far
  field), optionally under a delay margin ``delta*(K) >= d``;
* ``"margin"``: maximise ``delta*(K)``, the certified delay margin
  (:func:`~nrobust.hyperbolic.nplusm.nplusm_delay_margin` for one actuator,
  :func:`~nrobust.hyperbolic.nplusm.multi_actuator_delay_margin` for several).

**Gradients.** Jacobi's formula ``dF = tr(adj(M) dM)`` with
``dM/dK_ij = -e^{-delta s} E e_i e_j^T Phi_u`` gives ``dF/dK = -e^{-delta s} (Phi_u adj(M) E)^T``;
the adjugate (not ``F M^{-1}``) keeps it exact at a root, where ``M`` is singular.

* A simple rightmost root ``s0`` of the delay-free loop moves by ``ds0/dK_ij = -F_K_ij / F_s``
  (implicit function theorem), so ``d alpha/dK = Re(-F_K / F_s)``. Where the abscissa is the
  chain value ``c_D`` of the principal part (approached as ``|Im s| -> infinity``), ``c_D(K)``
  is differentiated by central differences.
* The critical crossing ``(omega*, delta*)`` solves ``F(i omega, delta; K) = 0``, two real
  equations; with ``F_omega = i F_s`` and ``F_delta = tr(adj(M) s e^{-delta s} E K Phi_u)``,
  ``[Re, Im] [F_omega, F_delta] [d omega; d delta] = -[Re, Im] F_K`` gives ``d delta*/dK``.

Both are nonsmooth where two roots (or two crossing branches) are active at once; the
optimiser is built for that (:mod:`nrobust.design.local`).

**Feasibility of every iterate.** A trial point is feasible only inside ``K_bounds``, with the
delayed principal part strongly stable with room, ``gamma <= gamma_max`` (``gamma`` the
Collatz-Wielandt bound ``rho(sum_t |V^{-1} C_t|)`` over the principal terms ``C_t``, those of
``R`` and of ``K`` counted apart: Hale and Verduyn Lunel's ``gamma_0`` for one actuator, an
upper bound of it for several; :meth:`~nrobust.hyperbolic.nplusm.NPlusMSystem.principal_terms`),
and, under a requirement ``d``, with a certified margin ``>= d``; a point whose abscissa or
margin cannot be certified is infeasible too. A trial point is rejected without its
abscissa when a zero right of the line search's line is found first: Newton's method from the
rightmost roots of earlier points, the zero proven by a certified count in a small box.

**Windows of delays.** ``delays`` (one window ``[d_min, d_max]`` or several) requires the loop
exponentially stable for every delay of each window. The loop must be stable at ``delta = 0`` too
(the certified margins list the crossings of a nominally stable loop only). The crossing delays are
``tau_k = tau_0 + 2 pi k / w`` on each crossing frequency ``w`` of the certified margin (every
crossing on ``[0, W]``, none beyond), and each crossing moves ``2`` zeros (a conjugate pair) right or
left as ``Re ds/ddelta = Re(-F_delta / F_s)`` says; the stability windows are the intervals between
crossing delays where no zero is left in ``Re s >= 0``. As in :mod:`nrobust.design.local`, the
requirement's violation measure is the window clearance ``c = min_j max_(l, h) min(d_min,j - l,
h - d_max,j)`` over the windows and the stability windows (``d_min - l`` taken as ``+inf`` for the
window ``[0, h)``; a window from ``d_min = 0`` held only by it), differentiable where one crossing
delay binds (the critical crossing's sensitivity above, on that crossing's branch); a start missing
the requirement first raises the window margin ``d_max,m + c`` to ``d_max,m``, after lowering the
largest spectral abscissa at ``delta = 0`` and at every ``d_min`` below 0 when no window holds. The
design is then checked with certified tools only (:class:`NPlusMWindow`): no crossing delay in the
window, and no zero in ``Re s >= 0`` at ``delta = d_min`` (the nominal count when no crossing delay
lies below ``d_min``, else :func:`~nrobust.roots.count_roots` of ``F(.; d_min)`` on ``[0, W] x
[-W, W]``: ``W`` bounds the zeros in ``Re s >= 0`` for every delay).

**Speed tolerance.** ``speed_tolerance=eps`` holds the windows (a required margin ``d`` is the window
``[0, d]``) with the same ``K`` on the plants at the ``2^(n+m)`` vertices of the box of relative errors of the
speeds (:mod:`~nrobust.hyperbolic.nplusm.speed_box`), the scenarios of :class:`NPlusMGainProblem`: every
iterate meets the windows and ``gamma_max`` on each, and the window clearance and the phase before the first
take the worst of them. The objective is then the worst of the nominal plant and the vertices, the value
guaranteed at every certified point: ``"margin"`` the least certified margin ``min_j delta*_j(K)`` (the
gradient that of the least one's critical crossing), ``"decay_rate"`` the least decay rate, i.e. the largest
certified spectral abscissa ``max_j alpha_j(K)`` of the delay-free loops (the gradient that of the rightmost
root, or chain, of the largest); both nonsmooth where two plants tie. The design is then certified at the
vertices (their margins and abscissae stated one by one) and checked at the other points of a grid of 3
points per speed (:func:`nplusm_speed_tolerance`). The speeds do not enter the loop affinely (they sit in
``E(s)`` and in ``exp(Lambda^{-1} (Sigma - s I))``), so stability at the vertices need not imply it inside
the box, and neither the stability nor the decay rate is certified between the points by the design;
``nplusm_speed_tolerance(system, K, eps, delays, inside=True)`` proves the stability there
(:mod:`~nrobust.hyperbolic.nplusm.speed_proof`; about fifty times the cost of the points' verdicts, so opt-in).

**Local.** The optimum is local: the best of the starts, each ending where neither the line
search nor the pattern search finds a better feasible point, down to steps of ``1e-5`` of the
bounds (:class:`~nrobust.design.LoopDesign` says the same of the scalar designs). For one
entry (``n = m = 1``) the exact scalar engine is the check (:func:`nrobust.design.best_margin`
on the affine loop of ``StateFeedback(k)``, the same law): tests.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._digits import with_accuracy
from ..._json import json_safe
from ..._newton import newton
from ..._threads import one_blas_thread
from ..._validate import finite_real, positive_int
from ...design.gain import check_delays
from ...design.local import (
    ABOVE_LINE,
    BELOW_REQUIREMENT,
    GAMMA_MAX,
    NO_WINDOW,
    LocalRun,
    TrialPoint,
    check_objective,
    check_windows,
    local_runs,
)
from ...errors import CertificationError, ParameterError
from ...roots import SpectralAbscissa, count_roots, spectral_abscissa
from ...sweeps.executors import sweep_map
from .characteristic import EPS, NPlusMCharacteristic
from .margin import NPlusMMargin, multi_actuator_delay_margin, nplusm_delay_margin, smallest_delay_error
from .speed_box import NPlusMSpeedTolerance, check_box_tolerance, perturbed_system, speed_box
from .speed_proof import MAX_BOX_PROOF_BOXES, MAX_PROVEN_ACTUATORS, prove_speed_box
from .system import NPlusMSystem

__all__ = [
    "NPlusMGainDesign",
    "NPlusMWindow",
    "NPlusMGainProblem",
    "default_gain_bounds",
    "design_nplusm_gains",
    "check_window",
    "gain_gradient",
    "nplusm_speed_tolerance",
    "principal_gamma",
    "window_clearance",
]

#: Default bounds of each entry of ``K``: this fraction of the entry that alone (the others 0)
#: brings the delayed principal part's ``gamma`` to 1.
K_BOUND_FRACTION = 0.99
#: Rightmost roots of earlier points kept per process (newest first) as Newton seeds.
WITNESSES = 16
#: Relative step of the central differences of the chain value ``c_D(K)``.
CHAIN_STEP = 1e-6
#: What every design says of its optimality.
LOCAL_STATEMENT = (
    "local: the best of the starts, each ending where neither the BFGS line search nor the pattern search "
    "finds a better feasible point down to steps of 1e-5 of the bounds; not proven locally optimal (the "
    "objective is nonsmooth and nonconvex) and not global"
)


def principal_gamma(system: NPlusMSystem, K: ArrayLike) -> float:
    """``rho(sum_t |V^{-1} C_t|)``: a bound of ``gamma_0`` of the delayed principal part (module notes).

    ``C_t`` are the point terms of :meth:`NPlusMSystem.principal_terms`, those of ``R``
    (delay ``tau_ab``) and of ``K`` (delay ``tau_ab + delta``) counted apart, so the bound holds
    for every loop delay ``delta > 0``; exact for one actuator, where it is
    ``(sum |R_a U_a Q_a| + sum |K_a U_a Q_a|) / |V|``. Below 1: the delayed loop's principal
    part is strongly stable (Hale and Verduyn Lunel).
    """
    v_block, point = system.principal_terms(K)
    v_inv = np.linalg.inv(v_block)
    total = np.zeros((system.m, system.m))
    for _, rq, kq in point:
        total += np.abs(v_inv @ rq) + np.abs(v_inv @ kq)
    return float(np.max(np.abs(np.linalg.eigvals(total))))


def _adjugate(M: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """The adjugate of a square matrix by cofactors (exact at a singular ``M``)."""
    m = M.shape[0]
    if m == 1:
        return np.ones((1, 1), dtype=complex)
    out = np.zeros((m, m), dtype=complex)
    for i in range(m):
        for j in range(m):
            minor = np.delete(np.delete(M, j, axis=0), i, axis=1)
            out[i, j] = (-1) ** (i + j) * np.linalg.det(minor)
    return out


def _jacobi_terms(
    system: NPlusMSystem, K: NDArray[np.float64], s: complex, delta: float
) -> tuple[complex, NDArray[np.complex128], complex]:
    """``(F, dF/dK, dF/ddelta)`` at ``s``: ``F = det M``, Jacobi's formula with the adjugate (module notes)."""
    n, m = system.n, system.m
    phi = system.transition(np.array([s]))[0] @ np.vstack([system.q, np.eye(m)])
    phi_u, phi_v = phi[:n], phi[n:]
    e = np.exp(-s / system.mu)
    z = np.exp(-delta * s)
    M = e[:, None] * (phi_v - (system.r + z * K) @ phi_u)
    adj = _adjugate(M)
    d_k = -z * (phi_u @ adj @ np.diag(e)).T
    d_delta = s * z * np.trace(adj @ np.diag(e) @ K @ phi_u)
    return complex(np.linalg.det(M)), d_k, complex(d_delta)


def gain_gradient(system: NPlusMSystem, K: ArrayLike, s: complex, delta: float = 0.0) -> NDArray[np.complex128]:
    """``ds/dK``: how a simple zero ``s`` of ``F(.; delta, K)`` moves with the entries of ``K``.

    ``ds/dK_ij = -(dF/dK_ij) / F'(s)`` (implicit function theorem) with ``dF/dK`` from Jacobi's
    formula, ``dF/dK = -e^{-delta s} (Phi_u adj(M) E)^T`` (module notes). The real part is the
    gradient of the spectral abscissa where ``s`` is the only rightmost root.

    Parameters
    ----------
    system : NPlusMSystem
    K : array_like, shape (m, n)
    s : complex
        A simple zero of the loop (not checked).
    delta : float
        The loop delay of the loop ``s`` is a zero of.

    Returns
    -------
    ndarray of complex, shape (m, n)
    """
    F = NPlusMCharacteristic(system, K, delta)
    _, d_k, _ = _jacobi_terms(system, F.K, complex(s), F.delta)
    return np.asarray(-d_k / complex(F.deriv_at(np.array([complex(s)]))[0]), dtype=complex)


def _margin_sensitivity(
    system: NPlusMSystem, K: NDArray[np.float64], omega: float, delta: float
) -> tuple[NDArray[np.float64], float]:
    """``(d delta*/dK, estimated error of delta*)`` at the crossing ``F(i omega, delta; K) = 0``.

    The implicit function theorem on the two real equations (module notes); the error is the
    delay part of the Newton step from ``(omega, delta)`` with ``|F|`` raised by its rounding
    scale (a floating-point estimate). A singular system (a tangency) gives a zero gradient and
    an infinite error.
    """
    s = 1j * omega
    value, d_k, d_delta = _jacobi_terms(system, K, s, delta)
    F = NPlusMCharacteristic(system, K, delta)
    d_omega = 1j * complex(F.deriv_at(np.array([s]))[0])
    J = np.array([[d_omega.real, d_delta.real], [d_omega.imag, d_delta.imag]])
    if not np.linalg.cond(J) < 1e12:
        return np.zeros(K.shape), math.inf
    rhs = -np.vstack([d_k.real.ravel(), d_k.imag.ravel()])
    grad = np.linalg.solve(J, rhs)[1].reshape(K.shape)
    slack = abs(value) + EPS * float(F.magnitude(np.array([s]))[0])
    error = slack * float(np.abs(np.linalg.inv(J)[1]).sum())
    return grad, error


def _crossing_delays(
    system: NPlusMSystem, K: NDArray[np.float64], dm: NPlusMMargin, horizon: float
) -> list[tuple[float, float, int]]:
    """Every crossing delay ``tau <= horizon`` of the loop as ``(tau, w, direction)``, ascending.

    ``tau = tau_0 + 2 pi k / w`` on each crossing ``(w, tau_0)`` of ``dm``; ``direction`` is the sign of
    ``Re ds/ddelta = Re(-F_delta / F_s)`` at ``s = i w`` (+1: a pair of zeros enters ``Re s > 0``, -1: it
    leaves, 0: not decided in floating point).
    """
    out = []
    for w, tau0 in dm.crossings:
        tau = tau0
        while tau <= horizon:
            s = 1j * w
            _, _, d_delta = _jacobi_terms(system, K, s, tau)
            d_s = complex(NPlusMCharacteristic(system, K, tau).deriv_at(np.array([s]))[0])
            rate = (-d_delta / d_s).real if d_s != 0 else 0.0
            out.append((float(tau), float(w), int(np.sign(rate))))
            tau += 2.0 * np.pi / w
    return sorted(out)


def _stability_windows(
    crossings: list[tuple[float, float, int]], horizon: float
) -> list[tuple[float, float, float | None, float | None]]:
    """The intervals ``(l, h)`` of delays up to ``horizon`` with no zero in ``Re s >= 0``, each end's crossing
    frequency (None: ``delta = 0`` or the horizon), from the zeros counted at each crossing (none at
    ``delta = 0``: the loop is nominally stable); an undecided direction ends the count."""
    windows: list[tuple[float, float, float | None, float | None]] = []
    count: int | None = 0
    lo, w_lo = 0.0, None
    for tau, w, direction in crossings:
        if count == 0:
            windows.append((lo, tau, w_lo, w))
        if count is None or direction == 0:
            count = None
            continue
        count += 2 * direction
        if count == 0:
            lo, w_lo = tau, w
    if count == 0:
        windows.append((lo, horizon, w_lo, None))
    return windows


def window_clearance(
    system: NPlusMSystem, K: ArrayLike, dm: NPlusMMargin, windows: Iterable[tuple[float, float]]
) -> tuple[float, tuple[float, float, int] | None]:
    """The window clearance of the loop at ``K`` (module notes) and the crossing ``(w, tau, side)`` that binds it.

    ``c = min_j max_(l, h) min(d_min,j - l, h - d_max,j)`` over the windows ``(d_min,j, d_max,j)`` and the
    stability windows ``(l, h)`` up to ``2 d_max,m + 1`` (``d_min - l = +inf`` for ``l = 0``; a window from
    ``d_min = 0`` held by ``[0, h)`` only), in floating point; ``side`` is -1 for a lower end, +1 for an
    upper; None when no crossing binds. ``c = -inf`` when a window has no stability window holding it.

    Parameters
    ----------
    system : NPlusMSystem
    K : array_like, shape (m, n)
    dm : NPlusMMargin
        The certified margin at ``K`` of a nominally stable loop (its crossings).
    windows : iterable of (float, float)

    Returns
    -------
    (float, (float, float, int) or None)
    """
    k = system.gain(K)
    windows = tuple(windows)
    horizon = 2.0 * max(hi for _, hi in windows) + 1.0
    stable = _stability_windows(_crossing_delays(system, k, dm, horizon), horizon)
    worst, binding = math.inf, None
    for d_lo, d_hi in windows:
        best, here = -math.inf, None
        for lo, hi, w_lo, w_hi in stable:
            if d_lo == 0.0 and lo != 0.0:
                continue
            below = math.inf if lo == 0.0 else d_lo - lo
            c = min(below, hi - d_hi)
            if c > best:
                end = (w_lo, lo, -1) if below <= hi - d_hi else (w_hi, hi, 1)
                best, here = c, (None if end[0] is None else (float(end[0]), end[1], end[2]))
        if best < worst:
            worst, binding = best, here
    return worst, (binding if math.isfinite(worst) else None)


@dataclass(frozen=True)
class NPlusMWindow:
    """The verdict on one window of delays of a designed ``K``, from certified tools only.

    Attributes
    ----------
    window : (float, float)
        ``(d_min, d_max)``.
    stable : bool
        True: no crossing delay in the window and no zero in ``Re s >= 0`` at ``delta = d_min``, so the
        loop is exponentially stable for every delay of the window.
    certified : bool
        True when ``stable`` rests on the certified margin (complete crossing search) and a certified
        count; False when a count could not be decided or the margin is not certified.
    crossing : float or None
        A crossing delay inside the window (why it is missed), or None.
    count : int or None
        The zeros in ``Re s >= 0`` at ``delta = d_min`` (None: not decided).
    how : str
        How the count was obtained.
    """

    window: tuple[float, float]
    stable: bool
    certified: bool
    crossing: float | None
    count: int | None
    how: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return json_safe(dict(vars(self)))


def check_window(system: NPlusMSystem, K: ArrayLike, dm: NPlusMMargin, window: tuple[float, float]) -> NPlusMWindow:
    """Whether the loop at ``K`` is exponentially stable for every delay of ``window``, with certified tools.

    No crossing delay ``tau_0 + 2 pi k / w`` of ``dm`` (every crossing, :func:`nplusm_delay_margin` or
    :func:`multi_actuator_delay_margin`) lies in ``[d_min, d_max]``, and no zero lies in ``Re s >= 0`` at
    ``delta = d_min``: the nominal count when no crossing delay is below ``d_min``, else
    :func:`~nrobust.roots.count_roots` of ``F(.; d_min)`` on ``[0, W] x [-W, W]`` (``W`` of ``dm``: no zero in
    ``Re s >= 0`` beyond it, for any delay).

    Parameters
    ----------
    system : NPlusMSystem
    K : array_like, shape (m, n)
    dm : NPlusMMargin
        The certified margin at ``K``.
    window : (float, float)

    Returns
    -------
    NPlusMWindow
    """
    k = system.gain(K)
    lo, hi = (float(v) for v in window)
    if dm.nominal_unstable != 0:
        why = (
            f"the loop has {dm.nominal_unstable} zero(s) in Re s >= 0 at delta = 0"
            if dm.nominal_unstable
            else "the delayed loop is not strongly stable (gamma_0 >= 1), or its zeros at delta = 0 are not counted"
        )
        return NPlusMWindow((lo, hi), False, dm.certified, None, dm.nominal_unstable, why)
    taus = [tau for tau, _, _ in _crossing_delays(system, k, dm, hi)]
    inside = [tau for tau in taus if tau >= lo]
    if inside:
        return NPlusMWindow((lo, hi), False, dm.certified, inside[0], None, "a crossing delay in the window")
    if not any(tau < lo for tau in taus):
        how = "no crossing delay below d_min: the certified count at delta = 0"
        return NPlusMWindow((lo, hi), True, dm.certified, None, 0, how)
    radius = max(dm.frequency_bound, 1.0)
    try:
        count = count_roots(NPlusMCharacteristic(system, k, lo), (0.0, radius, -radius, radius))
    except CertificationError as exc:
        return NPlusMWindow((lo, hi), False, False, None, None, f"the count at d_min not decided: {exc}")
    if count.region[0] < 0.0:
        return NPlusMWindow((lo, hi), False, False, None, None, "the count at d_min not decided (a zero near the axis)")
    n = int(count)
    how = f"certified count of the zeros of F(.; d_min) on [0, {radius:.6g}] x [-{radius:.6g}, {radius:.6g}]"
    return NPlusMWindow((lo, hi), n == 0, dm.certified, None, n, how)


def nplusm_speed_tolerance(
    system: NPlusMSystem,
    K: ArrayLike,
    eps: float,
    delays: Any,
    *,
    inside: bool = False,
    max_boxes: int = MAX_BOX_PROOF_BOXES,
) -> NPlusMSpeedTolerance:
    """Stability of ``U = K u(t - delta, 1)`` on windows of delays under relative speed errors ``|e_i| <= eps``.

    At each vertex of the box of ``n + m`` speed errors (:func:`~.speed_box.speed_box`) and at the other
    points of its grid of 3 points per speed, the plant with the perturbed speeds
    (:func:`~.speed_box.perturbed_system`) gets its certified delay margin (:func:`nplusm_delay_margin`,
    :func:`multi_actuator_delay_margin` for several actuators) and a verdict on each window
    (:func:`check_window`: no crossing delay in it, a certified count at its start). Certified at those
    points; the box between them is not (:mod:`~.speed_box`: the speeds do not enter the loop affinely),
    unless ``inside=True``: when every point is stable and every vertex certified, each
    window is then proven on the whole box by subdivision in ball arithmetic
    (:func:`~.speed_proof.prove_speed_box`, starting from a vertex's verdict), and
    :attr:`NPlusMSpeedTolerance.inside` says whether it was. Opt-in: it costs about fifty times the points'
    verdicts on the ``1 + 1`` plant of the tests (``eps = 0.05``: 3.5 to 3.9 s against 0.07 to 0.08 s of CPU time),
    more for wider boxes, more speeds and higher frequency bounds; on the ``1 + 2`` plant of the tests (``eps =
    0.01``) 1.0 to 1.05 s against 6.0 to 6.3 s for its 26 points, 18 s at ``eps = 0.02``.

    Parameters
    ----------
    system : NPlusMSystem
    K : array_like, shape (m, n)
    eps : float
        The tolerance, in ``(0, 1)``, with at most :data:`~.speed_box.MAX_SPEED_CORNERS` vertices.
    delays : (float, float) or sequence of them
        The windows ``[d_min, d_max]`` (a required margin ``d`` is ``(0, d)``).
    inside : bool, optional
        Prove the windows on the whole box too.
    max_boxes : int, optional
        Work bound of each window's proof inside the box (:func:`~.speed_proof.prove_speed_box`).

    Returns
    -------
    NPlusMSpeedTolerance

    Raises
    ------
    ParameterError
        A bad argument, before any work.
    CertificationError
        A delay margin failed at a point, or a proof inside the box reached ``max_boxes``.
    """
    if not isinstance(system, NPlusMSystem):
        raise ParameterError("system", "an NPlusMSystem", type(system).__name__)
    k = system.gain(K)
    eps = check_box_tolerance(eps, system, "eps")
    windows = _merged(check_windows(delays))
    if not windows:
        raise ParameterError("delays", "a window (d_min, d_max) or a sequence of them", delays)
    if not isinstance(inside, bool) or (inside and system.m > MAX_PROVEN_ACTUATORS):
        raise ParameterError("inside", f"True or False; True with at most {MAX_PROVEN_ACTUATORS} actuators", inside)
    max_boxes = positive_int("max_boxes", max_boxes)
    return _box_tolerance(system, k, eps, windows, inside, max_boxes, stopped_raises=True)


def _box_tolerance(
    system: NPlusMSystem,
    k: NDArray[np.float64],
    eps: float,
    windows: tuple[tuple[float, float], ...],
    inside: bool,
    max_boxes: int,
    *,
    stopped_raises: bool,
) -> NPlusMSpeedTolerance:
    """:func:`nplusm_speed_tolerance` of checked arguments; a proof inside the box that reaches ``max_boxes``
    raises its :class:`~nrobust.errors.CertificationError` (``stopped_raises``) or leaves its reason in the
    statement (a design's final check: the design is not lost, its verdicts at the points are not recomputed)."""
    vertices, others = speed_box(system.n + system.m, eps)
    points = (*vertices, *others)
    verdicts = []
    for errors in points:
        plant = perturbed_system(system, errors)
        dm = _margin(plant, k)
        verdicts.append(tuple(check_window(plant, k, dm, w) for w in windows))
    proofs: list[tuple[bool, str]] = []
    stable = all(v.stable for row in verdicts for v in row)
    if inside and stable and all(v.certified for row in verdicts[: len(vertices)] for v in row):
        for j, w in enumerate(windows):
            at = [row[j] for row in verdicts[: len(vertices)]]
            try:
                proof = prove_speed_box(system, k, eps, w, vertices, at, max_boxes=max_boxes)
            except CertificationError as exc:
                if stopped_raises:
                    raise
                proofs.append((False, f"the proof inside the box stopped: {exc}"))
                break
            proofs.append((proof.proven, proof.reason))
    elif inside and stable:
        proofs.append((False, "a vertex's verdict is not certified, so no point to start the proof from"))
    return NPlusMSpeedTolerance.from_verdicts(eps, windows, points, len(vertices), tuple(verdicts), proofs)


def _margin(system: NPlusMSystem, K: NDArray[np.float64]) -> NPlusMMargin:
    """The certified delay margin: :func:`nplusm_delay_margin` for one actuator, else the compound form."""
    if system.m == 1:
        return nplusm_delay_margin(system, K)
    return multi_actuator_delay_margin(system, K)


@dataclass(eq=False)
class _Memo:
    """What one process learned: complete evaluations by ``(K, objective)``, lower bounds of rejected points,
    abscissae and margins by ``K``, the rightmost roots of earlier points, the evaluations settled by a bound, and
    the plant with the largest abscissa at the last ``K`` (:meth:`NPlusMGainProblem.worst_abscissa`)."""

    points: dict[tuple[bytes, str], TrialPoint] = field(default_factory=dict)
    floors: dict[tuple[bytes, str], float] = field(default_factory=dict)
    abscissae: dict[bytes, SpectralAbscissa] = field(default_factory=dict)
    margins: dict[bytes, NPlusMMargin] = field(default_factory=dict)
    roots: list[complex] = field(default_factory=list)
    screened: int = 0
    worst_plant: int = 0

    def add_root(self, s: complex | None) -> None:
        if s is None or not np.isfinite(s):
            return
        s = complex(s.real, abs(s.imag))
        self.roots = [s, *(r for r in self.roots if abs(s - r) > 1e-3 * (1.0 + abs(s)))][:WITNESSES]


@dataclass(frozen=True)
class NPlusMGainProblem:
    """The gain design of an ``n + m`` system as a :class:`~nrobust.design.LocalProblem` (picklable).

    The parameters are the entries of ``K`` row by row (``p = K.ravel()``). Called at ``p``, it
    returns a :class:`~nrobust.design.TrialPoint`: the function minimised (``alpha``, or
    ``-delta*``), its gradient (module notes), and whether ``p`` is feasible.

    Attributes
    ----------
    system : NPlusMSystem
    bounds : ndarray, shape (m n, 2)
    objective : {"decay_rate", "margin"}
    margin_at_least : float or None
        The required margin; with ``windows``, the end of the last window (the level to which the
        first phase raises the window margin, :class:`~nrobust.design.LocalProblem`).
    gamma_max : float
        Feasible only with :func:`principal_gamma` ``<= gamma_max``.
    windows : tuple of (float, float)
        Windows of delays (ascending, disjoint) on which a feasible ``K`` is stable (module notes);
        ``want="margin"`` is then minus the window margin, ``want="abscissa"`` the largest spectral
        abscissa at ``delta = 0`` and at each ``d_min``.
    scenarios : tuple of NPlusMSystem
        Further plants (the vertices of a box of speed errors, :func:`~.speed_box.perturbed_system`)
        held with the same ``K`` to the windows and to ``gamma_max``: a feasible ``K`` meets them on every
        one, the window margin, the phase before the first and the objective (``"margin"``: the least margin;
        ``"decay_rate"``: the largest abscissa, :meth:`worst_abscissa`) take the worst of the plant and these.
        Only with ``windows``.
    """

    system: NPlusMSystem
    bounds: NDArray[np.float64]
    objective: str
    margin_at_least: float | None
    gamma_max: float = GAMMA_MAX
    windows: tuple[tuple[float, float], ...] = ()
    scenarios: tuple[NPlusMSystem, ...] = ()
    memo: _Memo = field(default_factory=_Memo, compare=False, repr=False)

    def plant(self, j: int) -> NPlusMSystem:
        """The plant ``j``: ``0`` the nominal one, ``1, 2, ...`` the scenarios."""
        return self.system if j == 0 else self.scenarios[j - 1]

    @property
    def screened(self) -> int:
        """Evaluations settled by a bound so far (in this process)."""
        return self.memo.screened

    def gain(self, p: ArrayLike) -> NDArray[np.float64]:
        """``K`` of the parameters ``p``."""
        return np.asarray(p, dtype=float).reshape(self.system.m, self.system.n)

    def margin(self, K: NDArray[np.float64], j: int = 0) -> NPlusMMargin:
        """The certified delay margin at ``K`` of the plant ``j`` (:meth:`plant`; remembered in this process)."""
        key = K.tobytes() + bytes([j])
        if key not in self.memo.margins:
            self.memo.margins[key] = _margin(self.plant(j), K)
        return self.memo.margins[key]

    def abscissa(self, K: NDArray[np.float64], j: int = 0) -> SpectralAbscissa:
        """The certified spectral abscissa of the delay-free loop at ``K`` of the plant ``j`` (:meth:`plant`;
        remembered in this process)."""
        key = K.tobytes() + bytes([j])
        if key not in self.memo.abscissae:
            self.memo.abscissae[key] = spectral_abscissa(NPlusMCharacteristic(self.plant(j), K, 0.0))
        return self.memo.abscissae[key]

    def worst_abscissa(self, K: NDArray[np.float64], above: float = math.inf) -> tuple[int, SpectralAbscissa]:
        """``(j, alpha_j)``: the largest certified spectral abscissa of the delay-free loops at ``K`` of the plant
        and the scenarios, and the plant ``j`` that has it (the first of those that tie); or, once one is found
        above ``above``, that one (a lower bound of the largest). The plant first, then the one that had the
        largest at the last ``K``, then the others."""
        last = self.memo.worst_plant
        order = [0, *([last] if last else []), *(i for i in range(1, 1 + len(self.scenarios)) if i != last)]
        worst = (0, self.abscissa(K))
        for j in order[1:]:
            if worst[1].value > above:
                break
            sa = self.abscissa(K, j)
            if sa.value > worst[1].value or (sa.value == worst[1].value and j < worst[0]):
                worst = (j, sa)
        self.memo.worst_plant = worst[0]
        return worst

    def __call__(self, p: ArrayLike, want: str | None = None, above: float = math.inf) -> TrialPoint:
        p = np.asarray(p, dtype=float)
        none = np.zeros(p.size)
        if np.any(p < self.bounds[:, 0]) or np.any(p > self.bounds[:, 1]):
            return TrialPoint(p, False, math.inf, none, math.nan, math.nan, "outside the bounds")
        objective = want or self.objective
        if self.windows and want == "margin":
            objective = "window"
        key = (p.tobytes(), objective)
        memo = self.memo
        if key in memo.points:
            return memo.points[key]
        floor = memo.floors.get(key, -math.inf)
        if floor > above:
            memo.screened += 1
            return TrialPoint(p, False, floor, none, floor, math.nan, "above the line (remembered bound)", True)
        K = self.gain(p)
        gammas = [principal_gamma(plant, K) for plant in (self.system, *self.scenarios)]
        j = int(np.argmax(gammas))
        if not gammas[j] <= self.gamma_max:
            memo.screened += 1
            which = "" if j == 0 else f" of scenario {j - 1}"
            reason = f"gamma = {gammas[j]:.6g} of the delayed principal part{which} above gamma_max"
            return TrialPoint(p, False, math.inf, none, math.nan, math.nan, reason)
        try:
            if objective == "window":
                point = self._window_point(p, K)
            elif objective == "abscissa":
                point = self._delayed_abscissa_point(p, K)
            elif objective == "margin":
                point = self._margin_point(p, K)
            else:
                point = self._abscissa_point(p, K, above)
        except CertificationError as exc:
            point = TrialPoint(p, False, math.inf, none, math.nan, math.nan, f"not certified: {exc}")
        if point.screened or point.reason == ABOVE_LINE:
            memo.floors[key] = max(floor, point.value)
        else:
            memo.points[key] = point
        return point

    def _abscissa_point(self, p: NDArray[np.float64], K: NDArray[np.float64], above: float) -> TrialPoint:
        memo = self.memo
        none = np.zeros(p.size)
        F = NPlusMCharacteristic(self.system, K, 0.0)
        sa = memo.abscissae.get(K.tobytes() + bytes([0]))
        if sa is None:  # the cheap rejections first, a zero right of the line (the nominal abscissa is at most
            # the worst), then the margin
            floor, why = self._floor(F, above)
            if floor > above:
                memo.screened += 1
                return TrialPoint(p, False, floor, none, floor, math.nan, f"above the line ({why})", True)
        margin = math.nan
        d = self.margin_at_least
        if self.windows:  # before the abscissa, which costs several margins
            missed, margin = self._windows_missed(K)
            if missed:
                return TrialPoint(p, False, math.inf, none, math.nan, margin, f"{BELOW_REQUIREMENT}: {missed}")
        elif d:  # before the abscissa, which costs several margins
            dm = self.margin(K)
            margin = dm.margin
            if not dm.certified:
                return TrialPoint(p, False, math.inf, none, math.nan, margin, "margin not certified")
            if not margin >= d:
                return TrialPoint(p, False, math.inf, none, math.nan, margin, BELOW_REQUIREMENT)
        if sa is None:
            sa = self.abscissa(K)
            memo.add_root(sa.root)
        j, worst = self.worst_abscissa(K, above)
        if worst.value > above:
            return TrialPoint(p, True, worst.value, none, worst.value, margin, ABOVE_LINE)
        if j:
            F = NPlusMCharacteristic(self.plant(j), K, 0.0)
        return TrialPoint(p, True, worst.value, self._abscissa_gradient(p, F, worst), worst.value, margin)

    def _floor(self, F: NPlusMCharacteristic, above: float) -> tuple[float, str]:
        """A lower bound of the abscissa of ``F`` above ``above``, or ``-inf``: the chains of the
        principal part, or a zero Newton's method reaches from the witnesses, proven by a
        certified count in a small box right of ``above``."""
        if not math.isfinite(above):
            return -math.inf, ""
        chain = F.principal_part().spectral_bound().lower
        if chain > above:
            return float(chain), f"chains at {chain:.6g}"
        if not self.memo.roots:
            return -math.inf, ""

        def fdf(x: NDArray[np.complex128]) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
            return F(x), F.deriv_at(x)

        roots = newton(fdf, np.array(self.memo.roots, dtype=complex), max_step=0.25, iters=30)
        roots = roots[np.isfinite(roots) & (roots.real > above)]
        for s in roots[np.argsort(-roots.real)][:2]:
            h = min(1e-6 * (1.0 + abs(s)), 0.5 * (s.real - above))
            try:
                count = count_roots(F, (s.real - h, s.real + h, s.imag - h, s.imag + h))
            except (CertificationError, ParameterError):
                continue
            if int(count) >= 1 and count.region[0] > above:
                self.memo.add_root(complex(s))
                return float(count.region[0]), f"a zero at {complex(s):.6g}"
        return -math.inf, ""

    def _abscissa_gradient(
        self, p: NDArray[np.float64], F: NPlusMCharacteristic, sa: SpectralAbscissa
    ) -> NDArray[np.float64]:
        if sa.root is not None and not sa.approached_at_infinity:
            return np.asarray(gain_gradient(F.system, F.K, complex(sa.root), F.delta).real.ravel(), dtype=float)
        grad = np.zeros(p.size)
        for i in range(p.size):  # the chain value c_D(K), by central differences
            h = CHAIN_STEP * max(1.0, abs(float(p[i])), float(self.bounds[i, 1] - self.bounds[i, 0]))
            lo, hi = p.copy(), p.copy()
            lo[i], hi[i] = max(p[i] - h, self.bounds[i, 0]), min(p[i] + h, self.bounds[i, 1])
            c = [
                NPlusMCharacteristic(F.system, self.gain(x), F.delta).principal_part().spectral_bound().value
                for x in (lo, hi)
            ]
            grad[i] = (c[1] - c[0]) / (hi[i] - lo[i])
        return grad

    def _windows_missed(self, K: NDArray[np.float64]) -> tuple[str, float]:
        """Why ``K`` misses the windows on the plant or a scenario (empty if it meets them, in floating point),
        and the plant's delay margin."""
        margin = self.margin(K).margin
        for j in range(1 + len(self.scenarios)):
            which = "the loop" if j == 0 else f"scenario {j - 1}"
            dm = self.margin(K, j)
            if dm.nominal_unstable != 0 or not dm.certified:
                return f"{which} is not stable at delta = 0 (or its margin is not certified)", margin
            c, _ = window_clearance(self.plant(j), K, dm, self.windows)
            if not c > 0.0:
                return f"{which} is not stable on the windows (clearance {c:.6g})", margin
        return "", margin

    def _window_point(self, p: NDArray[np.float64], K: NDArray[np.float64]) -> TrialPoint:
        """Minus the window margin ``d_max,m + c`` with its gradient (module notes), ``c`` the least clearance
        over the plant and the scenarios; :data:`NO_WINDOW` when one is unstable at ``delta = 0`` or has no
        stability window holding a window."""
        none = np.zeros(p.size)
        margin = self.margin(K).margin
        worst: tuple[float, tuple[float, float, int] | None, int] = (math.inf, None, 0)
        for j in range(1 + len(self.scenarios)):
            which = "the loop" if j == 0 else f"scenario {j - 1}"
            dm = self.margin(K, j)
            if dm.nominal_unstable != 0 or not dm.certified:
                reason = f"{NO_WINDOW} [0, h): {which} is not stable at delta = 0 (or its margin is not certified)"
                return TrialPoint(p, False, math.inf, none, math.nan, margin, reason)
            c, end = window_clearance(self.plant(j), K, dm, self.windows)
            if not math.isfinite(c):
                reason = f"{NO_WINDOW} holding each of {[list(w) for w in self.windows]} for {which}"
                return TrialPoint(p, False, math.inf, none, math.nan, margin, reason)
            if c < worst[0]:
                worst = (c, end, j)
        c, end, j = worst
        grad = np.zeros(p.size)
        if end is not None:
            w, tau, side = end
            g, _ = _margin_sensitivity(self.plant(j), K, w, tau)
            grad = side * g.ravel()
        value = self.windows[-1][1] + c
        return TrialPoint(p, True, -value, -grad, math.nan, value)

    def _delayed_abscissa_point(self, p: NDArray[np.float64], K: NDArray[np.float64]) -> TrialPoint:
        """The phase before the first: the largest spectral abscissa of ``F(.; delta, K)`` over ``delta = 0`` and
        the windows' ``d_min``, of the plant and the scenarios, with the gradient of the rightmost root (or
        chain) of the largest."""
        worst: tuple[float, float, int, SpectralAbscissa | None] = (-math.inf, 0.0, 0, None)
        for j in range(1 + len(self.scenarios)):
            for delta in sorted({0.0, *(lo for lo, _ in self.windows)}):
                if delta == 0.0:
                    sa = self.abscissa(K, j)
                else:
                    sa = spectral_abscissa(NPlusMCharacteristic(self.plant(j), K, delta))
                if sa.value > worst[0]:
                    worst = (sa.value, delta, j, sa)
        value, delta, j, rightmost = worst
        assert rightmost is not None
        F = NPlusMCharacteristic(self.plant(j), K, delta)
        return TrialPoint(p, True, value, self._abscissa_gradient(p, F, rightmost), value, math.nan)

    def _margin_point(self, p: NDArray[np.float64], K: NDArray[np.float64]) -> TrialPoint:
        none = np.zeros(p.size)
        dm = self.margin(K)
        if dm.nominal_unstable != 0:
            # under windows the first phase (after the phase before it) makes the loop stable at delta = 0
            prefix = f"{BELOW_REQUIREMENT}: " if self.windows else ""
            return TrialPoint(p, False, math.inf, none, math.nan, dm.margin, f"{prefix}not stable at delta = 0")
        if not dm.certified:
            return TrialPoint(p, False, math.inf, none, math.nan, dm.margin, "margin not certified")
        if self.windows:
            missed, _ = self._windows_missed(K)
            if missed:
                return TrialPoint(p, False, math.inf, none, math.nan, dm.margin, f"{BELOW_REQUIREMENT}: {missed}")
        j = min(range(1 + len(self.scenarios)), key=lambda i: self.margin(K, i).margin)
        worst = self.margin(K, j)  # the least margin of the plant and the scenarios (all certified: windows held)
        if worst.omega is None or not math.isfinite(worst.margin):
            return TrialPoint(p, True, -worst.margin, none, math.nan, dm.margin)
        grad, _ = _margin_sensitivity(self.plant(j), K, float(worst.omega), worst.margin)
        return TrialPoint(p, True, -worst.margin, -grad.ravel(), math.nan, dm.margin)


@dataclass(frozen=True)
class NPlusMGainDesign:
    """A gain matrix ``K`` of ``U(t) = K u(t - delta, 1)`` designed on an ``n + m`` system, certified.

    Attributes
    ----------
    K : tuple of tuple of float
        The design, ``m`` rows of ``n`` entries (:attr:`gain` as an array).
    objective : str
        ``"decay_rate"`` or ``"margin"``.
    value : float
        The objective at ``K``: the decay rate :attr:`worst_decay_rate` (``-alpha`` of the delay-free loop of
        the nominal plant; with ``speed_tolerance`` the least of it and the vertices' decay rates,
        :attr:`vertex_abscissae`), or the delay margin :attr:`worst_margin` (``delta*`` of the nominal plant;
        with ``speed_tolerance`` the least of it and the vertices' :attr:`vertex_margins`).
    accuracy : float
        A bound of the error of ``value``: for the decay rate the abscissae's
        (:attr:`~nrobust.roots.SpectralAbscissa.accuracy`: proven with ``rigorous``, else their
        floating-point estimates), for the margin the margins' :attr:`NPlusMMargin.accuracy`, each
        combined over the nominal plant and the vertices by
        :func:`~nrobust.hyperbolic.nplusm.margin.smallest_delay_error` (``inf`` when one is not
        estimated).
    abscissa : SpectralAbscissa
        Of the delay-free loop at ``K``: certified (no root right of ``upper_bound``), proven in
        ball arithmetic with ``rigorous`` (:meth:`NPlusMCharacteristic.proven_abscissa`).
    margin : NPlusMMargin or None
        The certified delay margin at ``K`` when the objective is the margin or one is required.
    margin_at_least : float or None
        The requirement.
    K_bounds : tuple of (float, float)
        The bounds of the entries of ``K``, row by row (given, or :func:`default_gain_bounds`).
    gamma : float
        :func:`principal_gamma` at ``K`` (below 1: the delayed principal part is strongly stable).
    certified : bool
        True if the abscissa is certified (with ``speed_tolerance``: each of :attr:`vertex_abscissae` too), and
        the margin (when computed) is certified, of a loop
        stable at ``delta = 0``, and meets the requirement (with ``speed_tolerance``: at every point of
        :attr:`tolerance`, certified at its vertices). It certifies the values at ``K``, not that ``K``
        is optimal.
    rigorous : bool
        True if the abscissa is proven in ball arithmetic, and with one actuator the margins too
        (:func:`nplusm_delay_margin` with ``rigorous=True``: :attr:`NPlusMMargin.rigorous`); with
        several actuators the margins are the floating-point certificate of
        :func:`multi_actuator_delay_margin`.
    starts, evaluations : int
        Starts run, and evaluations of the objective over all of them.
    runs : tuple of LocalRun
        Every start, the best first (parameters are ``K`` row by row).
    local : bool
        Always True: the optimum is local (:attr:`optimality`).
    optimality : str
        What is known of the optimality of ``K``.
    delays : tuple of (float, float)
        The required windows of delays (merged, ascending; empty without ``delays``).
    windows : tuple of NPlusMWindow
        The verdict on each window (:func:`check_window`); ``certified`` requires each stable and
        certified.
    tolerance : NPlusMSpeedTolerance or None
        With ``speed_tolerance``: the verdicts on the box of speed errors (:func:`nplusm_speed_tolerance`),
        certified at its vertices and checked at the other points of a grid; ``certified`` requires every
        point stable and every vertex's verdict certified. The box between the points is not certified
        (:attr:`NPlusMSpeedTolerance.statement`).
    vertex_margins : tuple of NPlusMMargin
        With ``speed_tolerance`` and a margin: the certified delay margin at each vertex of the box, in the
        order of ``tolerance.points``; empty otherwise. :attr:`worst_margin` is the least of them and
        :attr:`margin`.
    vertex_abscissae : tuple of SpectralAbscissa
        With ``speed_tolerance``: the certified spectral abscissa of the delay-free loop at each vertex of the
        box (proven in ball arithmetic with ``rigorous``), in the order of ``tolerance.points``; empty
        otherwise. :attr:`worst_decay_rate` is the least decay rate of them and :attr:`abscissa`. Between the
        vertices it is not certified (the speeds do not enter the loop affinely).
    """

    K: tuple[tuple[float, ...], ...]
    objective: str
    value: float
    accuracy: float
    abscissa: SpectralAbscissa
    margin: NPlusMMargin | None
    margin_at_least: float | None
    K_bounds: tuple[tuple[float, float], ...]
    gamma: float
    certified: bool
    rigorous: bool
    starts: int
    evaluations: int
    runs: tuple[LocalRun, ...] = field(repr=False)
    local: bool = True
    optimality: str = LOCAL_STATEMENT
    delays: tuple[tuple[float, float], ...] = ()
    windows: tuple[NPlusMWindow, ...] = ()
    tolerance: NPlusMSpeedTolerance | None = None
    vertex_margins: tuple[NPlusMMargin, ...] = ()
    vertex_abscissae: tuple[SpectralAbscissa, ...] = ()

    @property
    def gain(self) -> NDArray[np.float64]:
        """``K`` as an ``(m, n)`` array."""
        return np.array(self.K, dtype=float)

    @property
    def worst_margin(self) -> float | None:
        """The least certified delay margin of the nominal plant and the vertices of the box of speed errors
        (:attr:`vertex_margins`; the nominal margin without ``speed_tolerance``), None without a margin."""
        if self.margin is None:
            return None
        return min(m.margin for m in (self.margin, *self.vertex_margins))

    @property
    def worst_margin_accuracy(self) -> float | None:
        """A bound of the error of :attr:`worst_margin`: the margins' accuracies combined by
        :func:`~nrobust.hyperbolic.nplusm.margin.smallest_delay_error` (None when one is not estimated)."""
        if self.margin is None:
            return None
        margins = (self.margin, *self.vertex_margins)
        return smallest_delay_error([m.margin for m in margins], [m.accuracy for m in margins])

    @property
    def worst_decay_rate(self) -> float:
        """The least decay rate ``-alpha`` of the delay-free loops of the nominal plant and the vertices of the box
        of speed errors (:attr:`vertex_abscissae`; the nominal :attr:`decay_rate` without ``speed_tolerance``)."""
        return float(min(-a.value for a in (self.abscissa, *self.vertex_abscissae)))

    @property
    def worst_decay_rate_accuracy(self) -> float | None:
        """A bound of the error of :attr:`worst_decay_rate`: the abscissae's accuracies combined by
        :func:`~nrobust.hyperbolic.nplusm.margin.smallest_delay_error` (None when one is not estimated)."""
        return _least_rate_error((self.abscissa, *self.vertex_abscissae))

    def __repr__(self) -> str:
        worst = ""
        if self.vertex_abscissae:
            text = with_accuracy(self.worst_decay_rate, self.worst_decay_rate_accuracy)
            worst += f", worst_decay_rate={text}"
        if self.vertex_margins and self.worst_margin is not None:
            text = with_accuracy(self.worst_margin, self.worst_margin_accuracy)
            worst += f", worst_margin={text}"
        if worst:
            worst += f" (nominal and {len(self.vertex_abscissae) or len(self.vertex_margins)} vertices)"
        return (
            f"NPlusMGainDesign(K={[list(row) for row in self.K]}, objective={self.objective!r}, "
            f"value={with_accuracy(self.value, self.accuracy)}, margin={self.margin!r}{worst}, "
            f"certified={self.certified}, rigorous={self.rigorous}, local={self.local}, tolerance={self.tolerance!r})"
        )

    @property
    def decay_rate(self) -> float:
        """``-alpha`` of the delay-free loop at ``K``."""
        return float(-self.abscissa.value)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (the abscissa and the margin as their own dictionaries)."""
        skip = ("abscissa", "margin", "runs", "windows", "tolerance", "vertex_margins", "vertex_abscissae")
        data = {k: v for k, v in vars(self).items() if k not in skip}
        data["tolerance"] = None if self.tolerance is None else self.tolerance.to_dict()
        data["delays"] = [list(w) for w in self.delays]
        data["windows"] = [w.to_dict() for w in self.windows]
        data["K"] = [list(row) for row in self.K]
        data["abscissa"] = _abscissa_dict(self.abscissa)
        data["vertex_abscissae"] = [_abscissa_dict(a) for a in self.vertex_abscissae]
        data["worst_decay_rate"] = self.worst_decay_rate
        data["margin"] = None if self.margin is None else self.margin.to_dict()
        data["vertex_margins"] = [m.to_dict() for m in self.vertex_margins]
        data["worst_margin"] = self.worst_margin
        data["runs"] = [run.to_dict() for run in self.runs]
        return json_safe(data)


def _abscissa_dict(sa: SpectralAbscissa) -> dict[str, Any]:
    return {
        "value": sa.value,
        "upper_bound": sa.upper_bound,
        "certified": sa.certified,
        "value_bracket": sa.value_bracket,
    }


def _least_rate_error(abscissae: Iterable[SpectralAbscissa]) -> float | None:
    """A bound of the error of the least decay rate ``min_j (-alpha_j)`` from the abscissae's accuracies
    (:func:`~nrobust.hyperbolic.nplusm.margin.smallest_delay_error`: a rate within its error of the least may be
    the true least); None when one is not estimated."""
    abscissae = tuple(abscissae)
    return smallest_delay_error([-a.value for a in abscissae], [a.accuracy for a in abscissae])


def default_gain_bounds(system: NPlusMSystem) -> NDArray[np.float64]:
    """The default ``K_bounds`` of :func:`design_nplusm_gains`: one ``(low, high)`` row per entry of ``K``.

    Entry ``(i, j)`` within :data:`K_BOUND_FRACTION` ``= 0.99`` of the value ``t`` at which
    ``K = t e_i e_j^T`` alone brings :func:`principal_gamma` to 1 (bisected to ``2^-60``
    relative; ``gamma`` is nondecreasing in ``|t|``), on each side: for one actuator
    ``t = |V| (1 - gamma_R) / |U_a Q|`` (``gamma_R`` the reflection's part).

    Raises
    ------
    ParameterError
        ``R`` alone has ``gamma >= 1`` (no gain makes the delayed loop robust), or an entry of
        ``K`` does not reach the principal part (then give ``K_bounds``).
    """
    if not isinstance(system, NPlusMSystem):
        raise ParameterError("system", "an NPlusMSystem", type(system).__name__)
    m, n = system.m, system.n
    base = principal_gamma(system, np.zeros((m, n)))
    if not base < 1.0:
        raise ParameterError("system", "R alone with gamma < 1 (no gain makes the delayed loop robust)", base)
    rows = []
    for i in range(m * n):
        unit = np.zeros((m, n))
        unit[divmod(i, n)] = 1.0
        hi = 1.0
        while principal_gamma(system, hi * unit) < 1.0:
            hi *= 2.0
            if hi > 1e12:
                raise ParameterError(
                    "K_bounds", f"explicit bounds: entry {divmod(i, n)} of K leaves the principal part unchanged", None
                )
        lo = 0.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if principal_gamma(system, mid * unit) < 1.0 else (lo, mid)
        rows.append((-K_BOUND_FRACTION * lo, K_BOUND_FRACTION * lo))
    return np.array(rows)


def _gain_bounds(system: NPlusMSystem, K_bounds: Any) -> NDArray[np.float64]:
    """``K_bounds`` as ``(m n, 2)`` rows, checked (None: :func:`default_gain_bounds`)."""
    m, n = system.m, system.n
    what = f"None, a pair (low, high) for every entry, or ({m}, {n}, 2) pairs; finite, low < high"
    if K_bounds is None:
        return default_gain_bounds(system)
    try:
        b = np.asarray(K_bounds, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError("K_bounds", what, K_bounds) from None
    if b.shape == (2,):
        b = np.tile(b, (m * n, 1))
    elif b.shape in ((m, n, 2), (m * n, 2)):
        b = b.reshape(m * n, 2)
    else:
        raise ParameterError("K_bounds", what, K_bounds)
    if not np.all(np.isfinite(b)) or np.any(b[:, 0] >= b[:, 1]):
        raise ParameterError("K_bounds", what, K_bounds)
    return b


def _x0(x0: Any, system: NPlusMSystem, bounds: NDArray[np.float64]) -> NDArray[np.float64] | None:
    if x0 is None:
        return None
    try:
        k = np.asarray(x0, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError("x0", f"a real gain of shape ({system.m}, {system.n}) inside K_bounds", x0) from None
    if k.size != system.m * system.n or not np.all(np.isfinite(k)):
        raise ParameterError("x0", f"a real gain of shape ({system.m}, {system.n}) inside K_bounds", x0)
    p = k.reshape(-1)
    if np.any(p < bounds[:, 0]) or np.any(p > bounds[:, 1]):
        raise ParameterError("x0", f"a real gain of shape ({system.m}, {system.n}) inside K_bounds", x0)
    return p


@one_blas_thread(scipy_linalg=True)  # many exponentials of small matrices: competing BLAS threads only cost time
def design_nplusm_gains(
    system: NPlusMSystem,
    objective: str = "decay_rate",
    *,
    margin_at_least: float | None = None,
    delays: Any = None,
    K_bounds: Any = None,
    x0: ArrayLike | None = None,
    starts: int = 4,
    gamma_max: float = GAMMA_MAX,
    max_iter: int = 60,
    tol: float = 1e-6,
    rigorous: bool = False,
    executor: Any = "serial",
    speed_tolerance: float | None = None,
    inside: bool = False,
) -> NPlusMGainDesign:
    """The gain matrix ``K`` of ``U(t) = K u(t - delta, 1)`` with the best decay rate or delay margin, certified.

    A local nonsmooth optimisation (module notes) of the ``m n`` entries of ``K``: the core's
    BFGS with weak Wolfe line search and pattern search (:func:`nrobust.design.local_runs`)
    on :class:`NPlusMGainProblem`, gradients from the rightmost root's or the critical
    crossing's sensitivity (Jacobi's formula on ``det M``), every iterate feasible; the best
    start's ``K`` is then certified.

    Parameters
    ----------
    system : NPlusMSystem
    objective : {"decay_rate", "margin"}
        Maximise ``-alpha`` (the spectral abscissa of the delay-free loop; with ``speed_tolerance`` the
        least decay rate of the nominal plant and the vertices of the box,
        :attr:`NPlusMGainDesign.worst_decay_rate`) or the delay margin (the same delay on every actuator;
        with ``speed_tolerance`` the least margin of the nominal plant and the vertices,
        :attr:`NPlusMGainDesign.worst_margin`).
    margin_at_least : float, optional
        With ``"decay_rate"``: require ``delta* >= margin_at_least``. A start below it first
        maximises the margin.
    delays : (float, float) or sequence of them, optional
        Windows ``[d_min, d_max]`` (``0 <= d_min <= d_max``, ``d_max > 0``) on which the loop must
        be exponentially stable for every delay, at every iterate (module notes), with either
        objective, not with ``margin_at_least``; the loop must be stable at ``delta = 0`` too. The
        design is checked on each window with certified tools (:attr:`NPlusMGainDesign.windows`).
    K_bounds : pair, or array of shape (m, n, 2) or (m n, 2), optional
        ``(low, high)`` for every entry, or one pair per entry (row by row). Default
        (:func:`default_gain_bounds`): each entry within ``0.99`` of the value that alone (the
        others 0) brings :func:`principal_gamma` to 1.
    x0 : array_like, shape (m, n), optional
        The first start (inside ``K_bounds``); the others follow a Halton sequence in the bounds.
    starts : int
        Number of starts (``>= 1``).
    gamma_max : float
        Require :func:`principal_gamma` ``<= gamma_max < 1`` (strong stability of the delayed
        loop's principal part, with room) at every iterate.
    max_iter : int
        BFGS iterations per start.
    tol : float
        Stationarity at which a start stops (:class:`~nrobust.design.LocalRun`).
    rigorous : bool
        Prove the design's abscissa in ball arithmetic (python-flint), and with one actuator its
        delay margins (:func:`nplusm_delay_margin` with ``rigorous=True``).
    executor : "serial", None, str, int, Executor or dask.distributed.Client
        Where the starts run (``"serial"``: in this process; otherwise :func:`nrobust.sweep_map`).
    speed_tolerance : float, optional
        ``eps`` in ``(0, 1)``: the delay requirement (the windows of ``delays``, or ``margin_at_least``
        ``d`` as the window ``[0, d]``; one of them is needed) must hold too, with the same ``K``, on the
        plants whose speeds are ``lam_i (1 + e_i)``, ``mu_j (1 + e_{n+j})`` at the ``2^(n+m)`` vertices
        ``|e_i| = eps`` of the box of speed errors (:func:`~.speed_box.perturbed_system`; at most
        :data:`~.speed_box.MAX_SPEED_CORNERS` vertices), and each vertex's ``gamma`` within
        ``gamma_max``: at every iterate, each vertex one more certified margin per evaluation. The objective
        is then the worst of the nominal plant and the vertices (the guaranteed one): with ``"margin"`` the
        least margin (:attr:`NPlusMGainDesign.vertex_margins` and :attr:`~NPlusMGainDesign.margin` state
        each), with ``"decay_rate"`` the least decay rate, each vertex one more certified abscissa per
        evaluation (:attr:`NPlusMGainDesign.vertex_abscissae` and :attr:`~NPlusMGainDesign.abscissa` state
        each). The
        design's verdicts are then certified at the vertices and checked at the other points of the grid of 3 points
        per speed (:attr:`NPlusMGainDesign.tolerance`, :func:`nplusm_speed_tolerance`); the box between
        the points is not certified (the speeds do not enter the loop affinely, :mod:`~.speed_box`) unless
        ``inside``.
    inside : bool, optional
        With ``speed_tolerance``: prove the designed ``K``'s windows on the whole box of speed
        errors (``nplusm_speed_tolerance(..., inside=True)``, about fifty times the points' verdicts, once, after
        the optimisation); :attr:`NPlusMSpeedTolerance.inside` of :attr:`NPlusMGainDesign.tolerance` says
        whether it was, and its statement why not (a proof stopped at its work bound included).

    Returns
    -------
    NPlusMGainDesign

    Raises
    ------
    ParameterError
        For bad input, before any work; ``speed_tolerance`` outside ``(0, 1)``, without a delay
        requirement, or with more than :data:`~.speed_box.MAX_SPEED_CORNERS` vertices.
    CertificationError
        No start reached a feasible ``K`` (widen ``K_bounds``, give a feasible ``x0``, add starts
        or lower ``margin_at_least``, or ``speed_tolerance``), or the design's abscissa cannot be
        proven (``rigorous``).

    Examples
    --------
    >>> sys = NPlusMSystem([1.0], [1.0], [[0.0, 0.5], [0.4, 0.0]], [[0.8]], [[0.5]])
    >>> d = design_nplusm_gains(sys, "margin", K_bounds=(-0.6, -0.2), starts=1)  # doctest: +SKIP
    """
    if not isinstance(system, NPlusMSystem):
        raise ParameterError("system", "an NPlusMSystem", type(system).__name__)
    margin_at_least = check_objective(objective, margin_at_least)
    windows = _merged(check_windows(delays))
    if windows and margin_at_least is not None:
        raise ParameterError(
            "margin_at_least", "left out with delays (the window [0, d] is a margin above d)", margin_at_least
        )
    gamma_max = finite_real("gamma_max", gamma_max)
    if not 0.0 <= gamma_max < 1.0:
        raise ParameterError("gamma_max", "in [0, 1) (strong stability of the delayed loop)", gamma_max)
    starts = positive_int("starts", starts)
    max_iter = positive_int("max_iter", max_iter)
    tol = finite_real("tol", tol)
    if not tol > 0.0:
        raise ParameterError("tol", "> 0", tol)
    if not isinstance(rigorous, bool):
        raise ParameterError("rigorous", "True or False", rigorous)
    eps = None if speed_tolerance is None else check_box_tolerance(speed_tolerance, system)
    if not isinstance(inside, bool) or (inside and (eps is None or system.m > MAX_PROVEN_ACTUATORS)):
        raise ParameterError(
            "inside", f"True or False; True with speed_tolerance and at most {MAX_PROVEN_ACTUATORS} actuators", inside
        )
    if eps is not None and not windows:
        if not margin_at_least:
            raise ParameterError(
                "speed_tolerance",
                "given with a delay requirement (delays, or margin_at_least > 0) that the speeds must keep",
                speed_tolerance,
            )
        windows, margin_at_least = (check_delays((0.0, margin_at_least), "margin_at_least"),), None
    bounds = _gain_bounds(system, K_bounds)
    start = _x0(x0, system, bounds)
    map_: Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]] = (
        map if isinstance(executor, str) and executor == "serial" else sweep_map(executor, progress=False)
    )
    level = windows[-1][1] if windows else margin_at_least
    vertices = () if eps is None else speed_box(system.n + system.m, eps)[0]
    scenarios = tuple(perturbed_system(system, e) for e in vertices)
    problem = NPlusMGainProblem(system, bounds, objective, level, gamma_max, windows, scenarios)
    runs = local_runs(problem, x0=start, starts=starts, max_iter=max_iter, tol=tol, map=map_)
    if not runs or not runs[0].feasible:
        reasons = "; ".join(sorted({r.reason for r in runs}))
        raise CertificationError(
            f"design_nplusm_gains: no start reached a feasible gain ({reasons}); widen K_bounds, give a feasible x0, "
            "add starts or lower margin_at_least (or narrow delays"
            + (", or lower speed_tolerance: scenario j is the vertex j of the box of speed errors" if eps else "")
            + ")"
        )
    return _certify(system, problem, runs, rigorous, eps, inside)


def _merged(windows: tuple[tuple[float, float], ...]) -> tuple[tuple[float, float], ...]:
    """The windows as disjoint closed intervals, ascending (windows that meet are one)."""
    merged: list[tuple[float, float]] = []
    for lo, hi in sorted(windows):
        if merged and lo <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], hi))
        else:
            merged.append((lo, hi))
    return tuple(merged)


def _certificate_margin(problem: NPlusMGainProblem, K: NDArray[np.float64], j: int, rigorous: bool) -> NPlusMMargin:
    """The margin the certificate reports for plant ``j``: with ``rigorous`` and one actuator proven in ball
    arithmetic (:func:`nplusm_delay_margin`), else the problem's certified one."""
    plant = problem.plant(j)
    if rigorous and plant.m == 1:
        return nplusm_delay_margin(plant, K, rigorous=True)
    return problem.margin(K, j)


def _certify(
    system: NPlusMSystem,
    problem: NPlusMGainProblem,
    runs: list[LocalRun],
    rigorous: bool,
    eps: float | None,
    inside: bool = False,
) -> NPlusMGainDesign:
    K = problem.gain(runs[0].parameters)
    F = NPlusMCharacteristic(system, K, 0.0)
    sa = F.proven_abscissa() if rigorous else problem.abscissa(K)
    d = None if problem.windows else problem.margin_at_least
    need_margin = problem.objective == "margin" or problem.margin_at_least is not None
    dm = _certificate_margin(problem, K, 0, rigorous) if need_margin else None
    met = dm is None or (dm.certified and dm.nominal_unstable == 0 and (d is None or dm.margin >= d))
    verdicts = tuple(check_window(system, K, dm, w) for w in problem.windows) if dm is not None else ()
    met = met and all(v.stable and v.certified for v in verdicts)
    tolerance = None
    if eps is not None:
        tolerance = _box_tolerance(system, K, eps, problem.windows, inside, MAX_BOX_PROOF_BOXES, stopped_raises=False)
        met = met and tolerance.certified == "certified at the vertices"
    vertex_margins = (
        ()
        if eps is None or dm is None
        else tuple(_certificate_margin(problem, K, j, rigorous) for j in range(1, 1 + len(problem.scenarios)))
    )
    vertex_abscissae: tuple[SpectralAbscissa, ...] = ()
    if eps is not None:
        vertex_abscissae = tuple(
            NPlusMCharacteristic(problem.plant(j), K, 0.0).proven_abscissa() if rigorous else problem.abscissa(K, j)
            for j in range(1, 1 + len(problem.scenarios))
        )
        met = met and all(a.certified for a in vertex_abscissae)
    if problem.objective == "decay_rate":
        abscissae = (sa, *vertex_abscissae)
        value = min(-a.value for a in abscissae)
        error = _least_rate_error(abscissae)
        accuracy = math.inf if error is None else error
    else:
        assert dm is not None
        margins = (dm, *vertex_margins)
        value = min(m.margin for m in margins)
        error = smallest_delay_error([m.margin for m in margins], [m.accuracy for m in margins])
        accuracy = math.inf if error is None else error
    return NPlusMGainDesign(
        tuple(tuple(map(float, row)) for row in K),
        problem.objective,
        float(value),
        float(accuracy),
        sa,
        dm,
        d,
        tuple((float(lo), float(hi)) for lo, hi in problem.bounds),
        principal_gamma(system, K),
        bool(sa.certified and met),
        rigorous,
        len(runs),
        sum(r.evaluations for r in runs),
        tuple(runs),
        delays=problem.windows,
        windows=verdicts,
        tolerance=tolerance,
        vertex_margins=vertex_margins,
        vertex_abscissae=vertex_abscissae,
    )
