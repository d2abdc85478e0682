"""Robustness to a mismatch of the transport speeds: :func:`mismatch_loop`, :func:`mismatch_region`.

A controller is designed for the plant ``system`` (its gains are those of
``controller.feedback_law(system, kernels of system)``: ``U = k u(t, 1) + int_0^1 g_u u + g_v v
dx``, for ``U_BS2(K)`` the kernel traces of eq. (53)), but the plant it acts on transports at
``lam (1 + e_lam)`` and ``mu (1 + e_mu)``. The law is a fixed functional of the state, so the
mismatched loop is that of :class:`~nrobust.hyperbolic.loops.controllers.StateFeedback` with the
nominal gains on the perturbed plant: ``A = 1 - Phi`` and ``B = -P`` of the perturbed plant
(:func:`~nrobust.hyperbolic.loops.feedback.feedback_factor`, its inverse kernels and ``N~`` on
the kernel grid), times ``1 + b s`` and ``1 + a s`` for a filtered controller (section 2.3.2).

On an uncoupled plant the paper's laws are ``U = k u(t, 1)`` (no kernel), the route is exact
and a certificate is about the PDE itself; so is a ``StateFeedback`` whose gains evaluate in ball
arithmetic on a plant with constant couplings. With ``rigorous=True`` (:func:`mismatch_region`, the
corners of :func:`speed_tolerance`), ``U_BS2(K)`` and ``U_BS`` unfiltered on a coupled plant with
constant couplings take the exact route as well: the gains are Chebyshev polynomials ``h`` solving the
traces' Volterra identity, within a proven ``delta`` of the true ones
(:func:`~nrobust.hyperbolic.analyses.mismatch_traces.trace_enclosure`), and since the kernel of the
law's term is linear in the gains, the loop's ``B`` carries zero kernels whose radii hold that of
``h - g`` on the perturbed plant (:func:`~nrobust.hyperbolic.analyses.mismatch_traces.gain_error_terms`):
a proven margin holds for the PDE under the true law, mapped to the exact round trip of the perturbed
plant (its speeds the doubles ``lam (1 + e_lam)``, ``mu (1 + e_mu)``). Otherwise (a filtered law,
varying couplings, traces that cannot be enclosed, or in floating point, where it is about 3 times
cheaper) the route is the kernel route of :func:`~nrobust.hyperbolic.loops.controllers.loop_factors`:
a certificate is then about a model of the PDE, the nominal gains and the perturbed plant's ``N~`` and
``M`` being cubic splines of kernels on ``kernel_grid`` points
(:func:`~nrobust.hyperbolic.loops.controllers.loop_scope`).

An :class:`~nrobust.hyperbolic.loops.controllers.OutputFeedback` is an input-output map from the
measurement ``v(t, 0)`` and its own commands, designed on the nominal plant: its observer
predicts with the nominal delay form and window ``1/mu`` while the plant transports at the
perturbed speeds (:func:`mismatch_loop`; the nominal observer's term of
:mod:`~nrobust.hyperbolic.loops.output_feedback` replayed through the perturbed plant's delay form in
floating point: a model of the PDE, as :func:`mismatch_region`'s scope says).

The delay margin is not a continuous function of the mismatch: where ``|A(i w)|^2 - |B(i w)|^2``
gains a double zero a pair of crossing frequencies is born and the margin jumps down to its
first crossing delay. :func:`mismatch_region` therefore brackets each end of the admissible
set along an axis between two certified evaluations and says whether the margin jumps there.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._digits import with_accuracy
from ..._json import fields_dict, json_safe
from ..._validate import finite_real, positive, positive_int
from ...design.gain import DelayWindow, check_delays, window_stability
from ...design.local import check_objective
from ...errors import CertificationError, ParameterError
from ...margins.admissible import tolerates
from ...margins.gain import AffineGainLoop
from ...margins.margin import DelayMargin
from ...margins.margin import delay_margin as factor_delay_margin
from ...quasipoly import QuasiPolynomial
from ...roots import SpectralAbscissa, spectral_abscissa
from ...volterra import resolvent_product
from ..kernels.constant import DEFAULT_KERNEL_GRID, MAX_KERNEL_GRID, Kernels, check_kernel_grid, solve_kernels
from ..loops.controllers import (
    Controller,
    FilteredController,
    FiniteTimeController,
    OpenLoop,
    OutputFeedback,
    ReflectionController,
    StateFeedback,
    loop_factors,
    loop_route,
    loop_scope,
    unfiltered,
)
from ..loops.exact_form import has_exact_form
from ..loops.exact_gains import gain_failure
from ..loops.given_plant import to_given_plant
from ..loops.output_feedback import observer_term
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from ._common import mapper, real_grid
from .mismatch_coupled import MAX_COUPLED_BOXES, MAX_GAIN_BOXES, prove_coupled_square
from .mismatch_proof import MAX_SQUARE_BOXES, SquareProof, prove_transport_square
from .mismatch_traces import TraceEnclosure, gain_error_terms, reflection_traces, trace_enclosure
from .observer_accuracy import STUDY_SAFETY

__all__ = [
    "JUMP_FRACTION",
    "MAX_MISMATCH_POINTS",
    "MAX_UNDECIDED_PROBES",
    "MismatchEnd",
    "MismatchRegion",
    "SpeedTolerance",
    "USABLE_TRACE_BOUND",
    "check_local_requirements",
    "check_speed_tolerance",
    "mismatch_abscissa",
    "mismatch_gain_loop",
    "mismatch_loop",
    "mismatch_region",
    "speed_tolerance",
]

#: Most certified evaluations :func:`mismatch_region` plans: the grid ``len(e_lam) * len(e_mu)``
#: plus the points of the two axes. One evaluation solves the kernels of the perturbed plant
#: and a verified delay margin (1 to 5 s on the paper's plant at 201 kernel points on a shared
#: core), so this bound is a few hours of work; a larger grid is refused before any work.
MAX_MISMATCH_POINTS = 4096

#: Most mismatches :func:`speed_tolerance` checks in the boxes the square's proof left undecided (the corners
#: and middle of each, in the proof's order): each a delay margin and a count in floating point (0.05 to 0.3 s
#: on a shared core), so this bound is about a minute at most.
MAX_UNDECIDED_PROBES = 256

#: A change of the margin across an end's final bracket larger than this fraction of
#: ``delta_max`` is reported as a jump (kind ``"jump"``) rather than a continuous crossing of
#: ``delta_max``; either way the end lies between the two certified points.
JUMP_FRACTION = 1e-3


@lru_cache(maxsize=8)
def _nominal_kernels(system: Hyperbolic2x2, kernel_grid: int) -> Kernels:
    """The kernels the controller is designed on (cached: every grid point shares them)."""
    return solve_kernels(system, kernel_grid)


def _check_error(name: str, value: Any) -> float:
    """A relative speed error: finite and ``> -1`` (the perturbed speed stays positive)."""
    out = finite_real(name, value)
    if out <= -1.0:
        raise ParameterError(name, "> -1 (the perturbed speed must stay positive)", value)
    return out


def _check_pair(system: Any, controller: Any) -> None:
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem (constant speeds lam, mu)", system)
    if not isinstance(controller, Controller):
        raise ParameterError(
            "controller",
            "OpenLoop, FiniteTimeController, ReflectionController, FilteredController or StateFeedback",
            controller,
        )


class _Mismatched(NamedTuple):
    """The perturbed plant, the nominal law as a state feedback on it, the law's filter, and the enclosure of
    ``U_BS2(K)``'s traces when its gains are their Chebyshev fits (the exact route)."""

    plant: Hyperbolic2x2
    feedback: StateFeedback
    filt: tuple[float, float] | None
    enclosure: TraceEnclosure | None


def _mismatched(
    system: Hyperbolic2x2, controller: Controller, e_lam: float, e_mu: float, kernel_grid: int, exact: bool = False
) -> _Mismatched:
    """The perturbed plant and the nominal law on it (:class:`_Mismatched`).

    With ``exact``, ``U_BS2(K)`` and ``U_BS`` on a coupled plant with constant couplings take their traces
    enclosed (:func:`~nrobust.hyperbolic.analyses.mismatch_traces.trace_enclosure`) where that succeeds;
    otherwise (and a filtered law, varying couplings) the kernel traces on ``kernel_grid`` points.
    """
    plant = dataclasses.replace(system, lam=system.lam * (1.0 + e_lam), mu=system.mu * (1.0 + e_mu))
    if isinstance(controller, StateFeedback):
        return _Mismatched(plant, controller, None, None)
    enclosure = _enclosure(system, controller, kernel_grid) if exact else None
    if isinstance(enclosure, TraceEnclosure):
        return _Mismatched(plant, enclosure.law, None, enclosure)
    kernels = None if system.uncoupled else _nominal_kernels(system, kernel_grid)
    law = controller.feedback_law(system, kernels)
    if system.uncoupled:  # the paper's laws without kernels: U = k u(t, 1), no integral term
        return _Mismatched(plant, StateFeedback(law.boundary_gain), law.filter, None)
    return _Mismatched(plant, StateFeedback(law.boundary_gain, law.gain_u, law.gain_v), law.filter, None)


#: Largest proven bound of the enclosed traces, relative to their size, with which the exact route is taken.
USABLE_TRACE_BOUND = 1e-2


def _enclosure(system: Hyperbolic2x2, controller: Controller, kernel_grid: int) -> TraceEnclosure | str | None:
    """The enclosed traces of an unfiltered ``U_BS2(K)``/``U_BS`` on a coupled plant with constant couplings, the
    reason they are not enclosed (a string), or None (another law, an uncoupled plant, varying couplings).

    A bound above :data:`USABLE_TRACE_BOUND` times the traces' size (their largest modulus at 201 points) is a
    reason too: the loop's error terms would outweigh its kernels, and their radii overflow its frequency bounds
    (``3.6e72`` on ``Hyperbolic2x2(1, 1, 4, 4, 0.5, 0.5)``, where Gronwall's factor of the traces is ``e^{166}``).
    """
    K = _reflection_gain(controller, system)
    if K is None or system.uncoupled or not has_exact_form(system):
        return None
    try:
        enclosure = trace_enclosure(system, K)
    except CertificationError as exc:
        return str(exc)
    x = np.linspace(0.0, 1.0, 201)
    size = max(float(np.max(np.abs(enclosure.law.g_u(x)))), float(np.max(np.abs(enclosure.law.g_v(x)))))
    if not enclosure.error <= USABLE_TRACE_BOUND * size:
        return (
            f"the traces' proven bound {enclosure.error:.1e} exceeds {USABLE_TRACE_BOUND:g} times their size "
            f"{size:.1e} (Gronwall's factor of a strong coupling)"
        )
    return enclosure


def _loop(
    plant: Hyperbolic2x2,
    feedback: StateFeedback,
    filt: tuple[float, float] | None,
    kernel_grid: int,
    enclosure: TraceEnclosure | None = None,
) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``(A, B)`` of the state feedback on ``plant``, through the law's filter ``(1 + a s)/(1 + b s)``; with
    ``enclosure``, ``B`` holds the terms of the gains' error (:func:`gain_error_terms`): the loop of the true law."""
    grid = kernel_grid if loop_route(plant, feedback) == "kernels" else None
    A, B = loop_factors(plant, feedback, grid)
    if enclosure is not None:
        B = B - QuasiPolynomial([], [], list(gain_error_terms(enclosure, plant)))
    if filt is None:
        return A, B
    a, b = filt
    return A.times_poly([1.0, b]), B.times_poly([1.0, a])


def _measured(B: QuasiPolynomial, window: float, move: float) -> QuasiPolynomial:
    """``B`` on delays ``>= window`` (its part below is zero: it multiplies the measurement), moved by ``move``."""
    terms = [d.restricted(window) for d in B.distributed]
    return QuasiPolynomial.from_parts(
        [(p, t + move) for p, t in B.point_terms],
        [e for d in terms if d is not None for e in d.moved(move)],
        B.point_radii or None,
    )


def _observed(
    system: Hyperbolic2x2, controller: OutputFeedback, e_lam: float, e_mu: float, kernel_grid: int
) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``(A, B)`` of an output feedback designed for ``system`` on the plant with mismatched speeds.

    The controller is an input-output map designed on the nominal plant: from the measurement
    ``y = v(t, 0)`` through ``B_o`` (its part on the delays ``>= w = 1/mu``, read as ``z`` delayed
    by the nominal window) and from its commands through the nominal window kernel ``h``. The
    plant has ``y = e^{-s w'} z'`` with ``(1 - Phi') z' = U`` for its own window ``w' = 1/mu'``
    and delay form, so ``A = d (1 - Phi') - n (1 - Phi') H e^{-delta_o s}`` and
    ``B = B_o e^{-(w' - w) s}``.
    """
    inner = controller.controller
    grid = None if loop_route(system, inner) == "exact" else kernel_grid
    plant = dataclasses.replace(system, lam=system.lam * (1.0 + e_lam), mu=system.mu * (1.0 + e_mu))
    _, B_o = loop_factors(system, controller, grid)
    term = observer_term(
        loop_factors(system, OpenLoop(), grid)[0], loop_factors(system, unfiltered(inner), grid)[1], 1.0 / system.mu
    )
    open_loop = loop_factors(plant, OpenLoop(), None if grid is None or plant.uncoupled else grid)[0]
    d, n = ((1.0, inner.b), (1.0, inner.a)) if isinstance(inner, FilteredController) else ((1.0,), (1.0,))
    A = open_loop.times_poly(list(d))
    if term is not None:
        A = A - resolvent_product(open_loop, term.kernel).product.times_poly(list(n)).shift(controller.observer_delay)
    return A, _measured(B_o, 1.0 / system.mu, 1.0 / plant.mu - 1.0 / system.mu)


def mismatch_loop(
    system: Hyperbolic2x2,
    controller: Controller,
    e_lam: float,
    e_mu: float,
    *,
    kernel_grid: int = DEFAULT_KERNEL_GRID,
    rigorous: bool = False,
) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """Loop factors of ``controller`` designed for ``system``, acting on the plant with mismatched speeds.

    The law is ``controller.feedback_law(system, solve_kernels(system, kernel_grid))``, a
    :class:`~nrobust.hyperbolic.loops.controllers.StateFeedback` ``U = k u(t, 1) + int g_u u +
    g_v v dx`` with the nominal gains (for ``U_BS2(K)`` the kernel traces of eq. (53)); the plant
    is ``system`` with ``lam (1 + e_lam)`` and ``mu (1 + e_mu)``. Its loop is ``A = 1 - Phi`` and
    ``B = -P`` of the perturbed plant (:func:`~nrobust.hyperbolic.loops.feedback.feedback_factor`),
    with ``A`` times ``1 + b s`` and ``B`` times ``1 + a s`` for a
    :class:`~nrobust.hyperbolic.loops.controllers.FilteredController`. A ``StateFeedback``
    controller keeps its own gains.

    Route: on an uncoupled plant (or a proportional ``StateFeedback``) the paper's laws are
    ``U = k u(t, 1)`` and the route is exact: the PDE itself; so is a ``StateFeedback`` whose gains
    evaluate in ball arithmetic on a plant with constant couplings
    (:func:`~nrobust.hyperbolic.loops.controllers.loop_route`). With ``rigorous=True``, ``U_BS2(K)`` and
    ``U_BS`` (unfiltered) on a coupled plant with constant couplings take the exact route too: the law
    with its traces' Chebyshev polynomials ``h`` (:func:`~nrobust.hyperbolic.analyses.mismatch_traces.trace_enclosure`),
    ``N~``, ``U~`` and the term of ``h`` in closed form, and ``B`` holds two zero kernels whose proven radii hold
    the kernel of ``h``'s error (:func:`~nrobust.hyperbolic.analyses.mismatch_traces.gain_error_terms`), so
    a proof in ball arithmetic about ``F = A + B e^{-delta s}`` holds for the PDE under the true law (the
    plant with the speeds as computed in floating point, its loop built with ``tau`` rounded: a proof maps to
    the exact ``tau`` by :func:`~nrobust.hyperbolic.loops.given_plant.to_given_plant`). Otherwise (and where
    the traces are not enclosed, a filtered law, varying couplings) the kernel route: the nominal gains, the
    perturbed ``N~`` and the feedback kernel ``M`` are cubic splines of kernels on ``kernel_grid`` points, so
    ``F`` is a model of the PDE and a certificate about it is about that model (about 3 times cheaper to
    build than the exact loop of ``h``). With ``e_lam = e_mu = 0`` the kernel route's factors are those of
    ``loop_factors(system, controller)`` to about ``1e-9`` on the paper's plant at 201 points (the errors of
    the nominal kernels cancel there; its traces are within about ``2e-6`` of the true ones).

    Parameters
    ----------
    system : Hyperbolic2x2 or TransportSystem
        The plant the controller is designed for (nominal speeds ``lam``, ``mu``).
    controller : Controller
        One of the paper's controllers or a ``StateFeedback``.
    e_lam, e_mu : float
        Relative errors of the speeds, each ``> -1``.
    kernel_grid : int, default :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID`
        Kernel grid of the nominal gains and of the perturbed plant's loop (not used by the exact route of
        ``rigorous=True``).
    rigorous : bool, default False
        Build the loop of the true law for proofs in ball arithmetic (the exact route above).

    Returns
    -------
    tuple of QuasiPolynomial
        ``A`` and ``B`` with ``F(s; delta) = A(s) + B(s) e^{-delta s}``.
    """
    _check_pair(system, controller)
    e_lam, e_mu = _check_error("e_lam", e_lam), _check_error("e_mu", e_mu)
    kernel_grid = check_kernel_grid(kernel_grid)
    if isinstance(controller, OutputFeedback):
        return _observed(system, controller, e_lam, e_mu, kernel_grid)
    plant, feedback, filt, enclosure = _mismatched(system, controller, e_lam, e_mu, kernel_grid, rigorous)
    return _loop(plant, feedback, filt, kernel_grid, enclosure)


def mismatch_abscissa(
    system: Hyperbolic2x2,
    controller: Controller,
    e_lam: float,
    e_mu: float,
    *,
    kernel_grid: int = DEFAULT_KERNEL_GRID,
    rigorous: bool = False,
) -> SpectralAbscissa:
    """The spectral abscissa at ``delta = 0`` of ``controller`` designed for ``system``, on the plant with speeds
    ``lam (1 + e_lam)``, ``mu (1 + e_mu)``: its decay rate there is ``-value``.

    The loop is :func:`mismatch_loop`'s (with ``rigorous``; the abscissa proven in ball arithmetic then). On its
    exact route (the PDE itself: an uncoupled plant, or with ``rigorous=True`` the enclosed traces of ``U_BS2(K)``
    and ``U_BS`` on constant couplings, or a ``StateFeedback`` whose gains evaluate in balls) ``model_error`` is
    0. On the kernel route the loop is a model on ``kernel_grid = n`` points, and ``model_error`` a convergence
    study in the kernel grid: the rightmost root moved to first order, ``ds = -dF / F'``, by the loops built on
    ``2n - 1`` and ``4n - 3`` points (changes ``d_1`` then ``d_2`` as the spacing halves, in each part). When
    they have one sign and ``|d_2| <= |d_1| / 2`` the root's error on ``n`` points is at most ``|d_1| + 2 |d_2|``
    (a geometric tail of ratio ``<= 1/2``) and the estimate is :data:`STUDY_SAFETY` times that; otherwise
    ``2 STUDY_SAFETY (|d_1| + |d_2|)``. Floating point, not proven. On the paper's plant under ``U_BS2(0.1414)``,
    ``(e_lam, e_mu) = (-0.05, -0.05)``, 31 points: the rate ``0.10684494`` moves by ``1.2e-7`` to 61 points and
    ``4.6e-9`` more to 121; the estimate is ``2.5e-7``. None (not estimated): an output feedback, a chain value,
    or ``4n - 3`` above ``MAX_KERNEL_GRID``.

    With ``rigorous=True`` a proof the ball arithmetic cannot complete (radii of the enclosed traces that make the
    roots' boxes overlap) gives the floating-point result instead: ``rigorous`` of the result says which. On the
    paper's plant the traces' bound (``4.1e-12``) lets the proof complete.

    Parameters
    ----------
    system, controller, e_lam, e_mu, kernel_grid, rigorous
        As in :func:`mismatch_loop`.

    Returns
    -------
    SpectralAbscissa
    """
    A, B = mismatch_loop(system, controller, e_lam, e_mu, kernel_grid=kernel_grid, rigorous=rigorous)
    F = A + B  # the loop at delta = 0
    try:
        sa = spectral_abscissa(F, rigorous=rigorous)
    except CertificationError:
        if not rigorous:
            raise
        # the balls are too wide to separate the roots (the enclosed traces' radii): floating point, studied
        return mismatch_abscissa(system, controller, e_lam, e_mu, kernel_grid=kernel_grid)
    if isinstance(controller, OutputFeedback):
        return sa
    plant, feedback, _, _ = _mismatched(system, controller, e_lam, e_mu, kernel_grid, rigorous)
    if loop_route(plant, feedback) == "exact":
        return dataclasses.replace(sa, model_error=0.0)
    kernel_grid = check_kernel_grid(kernel_grid)
    finest = 4 * kernel_grid - 3
    if sa.root is None or sa.approached_at_infinity or finest > MAX_KERNEL_GRID:
        return sa
    at = np.array([complex(sa.root)])
    slope = complex(F.deriv_at(at)[0])
    if slope == 0.0:
        return sa
    moves = []  # the root on the finer grid minus ours
    for n in (2 * kernel_grid - 1, finest):
        A_n, B_n = mismatch_loop(system, controller, e_lam, e_mu, kernel_grid=n)
        moves.append(-(complex((A_n + B_n)(at)[0]) - complex(F(at)[0])) / slope)
    d1, d2 = moves[0], moves[1] - moves[0]
    bounds = []
    for a, b in ((d1.real, d2.real), (d1.imag, d2.imag)):
        if a * b > 0.0 and abs(b) <= 0.5 * abs(a):
            bounds.append(STUDY_SAFETY * (abs(a) + 2.0 * abs(b)))
        else:
            bounds.append(2.0 * STUDY_SAFETY * (abs(a) + abs(b)))
    return dataclasses.replace(sa, model_error=max(bounds))


@dataclass(frozen=True)
class _MismatchMargin:
    """Picklable ``(e_lam, e_mu) -> certified delay margin of the mismatched loop``, or the message
    of its :class:`~nrobust.errors.CertificationError`."""

    system: Hyperbolic2x2
    controller: Controller
    kernel_grid: int
    rigorous: bool
    max_evals: int

    def __call__(self, point: tuple[float, float]) -> DelayMargin | str:
        try:
            if isinstance(self.controller, OutputFeedback):
                A, B = _observed(self.system, self.controller, point[0], point[1], self.kernel_grid)
            else:
                plant, feedback, filt, enclosure = _mismatched(
                    self.system, self.controller, point[0], point[1], self.kernel_grid, self.rigorous
                )
                A, B = _loop(plant, feedback, filt, self.kernel_grid, enclosure)
                if filt is None and loop_route(plant, feedback) == "exact":  # the loop as built is in tau s
                    dm = factor_delay_margin(A, B, verify=True, max_evals=self.max_evals, rigorous=self.rigorous)
                    return to_given_plant(dm, plant, feedback)
            return factor_delay_margin(A, B, verify=True, max_evals=self.max_evals, rigorous=self.rigorous)
        except CertificationError as exc:
            return str(exc)


class MismatchEnd(NamedTuple):
    """One end of the admissible mismatch along an axis, bracketed by certified evaluations.

    Attributes
    ----------
    e : float
        The end's estimate: the root of ``margin(e) - delta_max`` by ``brentq`` (kind
        ``"crossing"``), or the inner, certified admissible point of its bracket (``"jump"``);
        the last axis point
        (``"grid_end"``); ``0`` (``"nominal"``: the undisturbed loop is not admissible).
    inside, outside : float
        The final bracket: admissible at ``inside`` (certified margin ``> delta_max``, nominal
        loop stable), not at ``outside``; ``outside`` is ``nan`` for ``"grid_end"``.
    margin_inside, margin_outside : float
        The certified margins there (``nan`` where not evaluated).
    kind : str
        ``"crossing"`` (the margin passes through ``delta_max`` within the bracket: it changes by
        at most ``JUMP_FRACTION * delta_max`` across it), ``"jump"`` (the margin jumps within the
        bracket, e.g. a pair of crossing frequencies is born or the nominal loop loses
        stability: the end is between the two certified points, no closer), ``"grid_end"``
        (admissible at every axis point checked) or ``"nominal"``.
    """

    e: float
    inside: float
    outside: float
    margin_inside: float
    margin_outside: float
    kind: str


@dataclass(frozen=True, eq=False)
class MismatchRegion:
    """Speed mismatches under which a controller stays stable for every delay in ``[0, delta_max]``.

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    e_lam, e_mu : ndarray
        The grid of relative speed errors.
    margins : ndarray, shape ``(len(e_lam), len(e_mu))``
        Certified delay margin of the mismatched loop (0 when its nominal loop is unstable).
    nominally_stable : ndarray of bool
        The mismatched loop without delay is exponentially stable.
    admissible : ndarray of bool
        Nominally stable and ``margin > delta_max``: stable for every delay in ``[0, delta_max]``.
    delta_max : float
        The delay range that must be tolerated.
    extent : dict
        ``{"e_lam": (lower, upper), "e_mu": (lower, upper)}``: the ends (:class:`MismatchEnd`) of
        the admissible set along each axis from ``e = 0`` (the other error zero). Each was
        bracketed by the axis points and refined to ``tol``; an axis point's verdict and the
        end's bracket are certified, what happens between two axis points before the first
        change of verdict is not examined.
    tol : float
        Width of the final bracket of each end.
    route, scope : str
        The route of the mismatched loops (``"kernels"`` or ``"exact"``) and what a certificate
        is about (:func:`~nrobust.hyperbolic.loops.controllers.loop_scope`).
    rigorous : bool
        The margins were proven in ball arithmetic, not only verified.
    evaluations : int
        Certified delay margins computed (grid, axes and brackets).
    """

    e_lam: NDArray[np.float64]
    e_mu: NDArray[np.float64]
    margins: NDArray[np.float64]
    nominally_stable: NDArray[np.bool_]
    admissible: NDArray[np.bool_]
    delta_max: float
    extent: dict[str, tuple[MismatchEnd, MismatchEnd]]
    tol: float
    route: str
    scope: str
    rigorous: bool
    evaluations: int

    def __repr__(self) -> str:
        def axis(name: str) -> str:
            lo, hi = self.extent[name]
            return f"{name} in ({lo.e:.6g}, {hi.e:.6g}) [{lo.kind}, {hi.kind}]"

        return (
            f"MismatchRegion(delta_max={self.delta_max:.6g}, {int(self.admissible.sum())}/{self.admissible.size} "
            f"grid points admissible, {axis('e_lam')}, {axis('e_mu')})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description; each end of ``extent`` as a dict of the :class:`MismatchEnd` fields."""
        data = fields_dict(self, exclude=("extent",))
        data["extent"] = json_safe({k: [end._asdict() for end in pair] for k, pair in self.extent.items()})
        return data


class _Evaluator:
    """Certified margins at mismatch points, cached, counted; a failed margin raises naming its point."""

    def __init__(self, margin_at: _MismatchMargin) -> None:
        self.margin_at = margin_at
        self.known: dict[tuple[float, float], DelayMargin] = {}

    def store(self, point: tuple[float, float], result: DelayMargin | str) -> DelayMargin:
        if isinstance(result, str):
            raise CertificationError(
                f"mismatch_region: the delay margin at (e_lam, e_mu) = ({point[0]:.12g}, {point[1]:.12g}) failed: "
                f"{result}"
            )
        self.known[point] = result
        return result

    def __call__(self, point: tuple[float, float]) -> DelayMargin:
        if point not in self.known:
            self.store(point, self.margin_at(point))
        return self.known[point]


def _axis_end(
    evaluate: _Evaluator, axis: int, points: NDArray[np.float64], delta_max: float, tol: float
) -> MismatchEnd:
    """The end of the admissible set along one half-axis from 0 through ``points`` (``|e|`` increasing)."""
    from scipy.optimize import brentq  # lazily: scipy.optimize is slow to import

    def at(e: float) -> tuple[float, float]:
        return (e, 0.0) if axis == 0 else (0.0, e)

    def signed(e: float) -> float:
        """``margin - delta_max``, clipped to ``(0, delta_max]`` where admissible, ``<= 0`` where not."""
        dm = evaluate(at(e))
        if tolerates(dm, delta_max):
            return min(float(dm.margin), 2.0 * delta_max) - delta_max
        return min(float(dm.margin), delta_max) - delta_max

    good = 0.0
    if signed(good) <= 0.0:
        margin = float(evaluate(at(good)).margin)
        return MismatchEnd(0.0, math.nan, 0.0, math.nan, margin, "nominal")
    for e in points:
        if signed(float(e)) > 0.0:
            good = float(e)
            continue
        root = float(brentq(signed, good, float(e), xtol=tol, rtol=4.0 * np.finfo(float).eps))
        values = sorted(
            {p[axis] for p in evaluate.known if p[1 - axis] == 0.0 and min(good, e) <= p[axis] <= max(good, e)}
        )
        brackets = [(x, y) for x, y in itertools.pairwise(values) if (signed(x) > 0.0) != (signed(y) > 0.0)]
        lo, hi = min(brackets, key=lambda pair: pair[1] - pair[0])
        inside, outside = (lo, hi) if signed(lo) > 0.0 else (hi, lo)
        m_in, m_out = float(evaluate(at(inside)).margin), float(evaluate(at(outside)).margin)
        if signed(outside) == 0.0:
            return MismatchEnd(outside, inside, outside, m_in, m_out, "crossing")
        jump = abs(m_in - m_out) > JUMP_FRACTION * delta_max
        return MismatchEnd(inside if jump else root, inside, outside, m_in, m_out, "jump" if jump else "crossing")
    m_in = float(evaluate(at(good)).margin)
    return MismatchEnd(good, good, math.nan, m_in, math.nan, "grid_end")


def mismatch_region(
    system: Hyperbolic2x2,
    controller: Controller,
    e_lam: ArrayLike,
    e_mu: ArrayLike,
    delta_max: float,
    *,
    tol: float = 1e-6,
    kernel_grid: int = DEFAULT_KERNEL_GRID,
    rigorous: bool = False,
    max_evals: int = 2_000_000,
    executor: Any = "serial",
    progress: bool | None = None,
) -> MismatchRegion:
    """Speed mismatches under which ``controller``, designed for ``system``, tolerates ``[0, delta_max]``.

    At every point of the grid ``e_lam x e_mu`` the mismatched loop (:func:`mismatch_loop`) gets
    a certified delay margin (:func:`nrobust.margins.delay_margin`, verified by an independent
    root count, or proven in ball arithmetic with ``rigorous=True``); a point is admissible when
    the loop without delay is stable and the margin exceeds ``delta_max``. Along each axis (the
    other error zero) the end of the admissible set reached from ``e = 0`` is located: the axis
    points (the grid values of that axis) bracket the first change of verdict, ``brentq`` on
    ``margin(e) - delta_max`` (every evaluation certified) narrows the bracket to ``tol``, and
    the end is reported with its final bracket and whether the margin jumps across it
    (:class:`MismatchEnd`): the margin is not continuous where a pair of crossing frequencies is
    born or the nominal loop loses stability, and there the end is only known to lie between
    the two certified points. A change of verdict and back between two axis points is not seen.

    What a certificate is about: :attr:`MismatchRegion.scope` (on an uncoupled plant the PDE itself; on
    a coupled plant with constant couplings with ``rigorous=True`` under ``U_BS2(K)``, ``U_BS`` or a
    ``StateFeedback`` whose gains evaluate in ball arithmetic, the PDE itself under the true law,
    each margin ball holding the fitted traces' proven error: wider than a model's; otherwise a model
    of the PDE with the kernels on ``kernel_grid`` points).

    Parameters
    ----------
    system : Hyperbolic2x2 or TransportSystem
        The plant the controller is designed for.
    controller : Controller
        The controller, designed on ``system`` (its ``feedback_law``).
    e_lam, e_mu : array_like
        Relative speed errors (each ``> -1``); the plant transports at ``lam (1 + e_lam)`` and
        ``mu (1 + e_mu)``.
    delta_max : float
        The delay range to tolerate (``> 0``).
    tol : float, default 1e-6
        Width of the final bracket of each end of :attr:`MismatchRegion.extent`.
    kernel_grid : int, default :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID`
        Kernel grid of the nominal gains and of every perturbed loop.
    rigorous : bool, default False
        Prove every margin in ball arithmetic (python-flint) instead of verifying it.
    max_evals : int, optional
        Work bound of each delay margin.
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the grid points run (:func:`nrobust.sweeps.sweep`'s executors); default in this
        process. The brackets of the ends are refined in this process.
    progress : bool, optional
        A progress bar over the grid points on stderr; by default only when stderr is a
        terminal or Jupyter.

    Returns
    -------
    MismatchRegion

    Raises
    ------
    ParameterError
        A bad argument, e.g. an error ``<= -1`` or more than :data:`MAX_MISMATCH_POINTS`
        evaluations planned (checked before any work).
    CertificationError
        A delay margin failed (the message names its point).
    """
    _check_pair(system, controller)
    lam_axis, mu_axis = real_grid("e_lam", e_lam), real_grid("e_mu", e_mu)
    planned = lam_axis.size * mu_axis.size + lam_axis.size + mu_axis.size + 1
    if planned > MAX_MISMATCH_POINTS:
        raise ParameterError(
            "e_lam, e_mu",
            f"grids with len(e_lam) * len(e_mu) + len(e_lam) + len(e_mu) + 1 <= MAX_MISMATCH_POINTS = "
            f"{MAX_MISMATCH_POINTS}",
            f"{lam_axis.size} x {mu_axis.size}",
        )
    for name, errors in (("e_lam", lam_axis), ("e_mu", mu_axis)):
        for value in errors:
            _check_error(name, value)
    delta_max = positive("delta_max", delta_max)
    tol = positive("tol", tol)
    kernel_grid = check_kernel_grid(kernel_grid)
    max_evals = positive_int("max_evals", max_evals)
    evaluate = _Evaluator(_MismatchMargin(system, controller, kernel_grid, bool(rigorous), max_evals))
    points = [(float(a), float(b)) for a in lam_axis for b in mu_axis]
    axes = [(0.0, 0.0)] + [(float(a), 0.0) for a in lam_axis] + [(0.0, float(b)) for b in mu_axis]
    todo = list(dict.fromkeys(points + axes))
    run = mapper(executor, progress, "mismatch_region: delay margins")
    for point, result in zip(todo, run(evaluate.margin_at, todo)):
        evaluate.store(point, result)
    grid = [evaluate(p) for p in points]
    shape = (lam_axis.size, mu_axis.size)
    margins = np.array([dm.margin for dm in grid], dtype=float).reshape(shape)
    stable = np.array([dm.nominally_stable for dm in grid], dtype=bool).reshape(shape)
    admissible = np.array([tolerates(dm, delta_max) for dm in grid], dtype=bool).reshape(shape)
    extent: dict[str, tuple[MismatchEnd, MismatchEnd]] = {}
    for axis, (name, values) in enumerate((("e_lam", lam_axis), ("e_mu", mu_axis))):
        below, above = np.sort(values[values < 0.0])[::-1], np.sort(values[values > 0.0])
        extent[name] = (
            _axis_end(evaluate, axis, below, delta_max, tol),
            _axis_end(evaluate, axis, above, delta_max, tol),
        )
    route, scope = _route_scope(system, controller, kernel_grid, bool(rigorous))
    return MismatchRegion(
        lam_axis,
        mu_axis,
        margins,
        stable,
        admissible,
        delta_max,
        extent,
        tol,
        route,
        scope,
        bool(rigorous),
        len(evaluate.known),
    )


def check_speed_tolerance(value: Any, name: str = "speed_tolerance", plant: Any = None) -> float:
    """A relative speed tolerance ``eps`` in ``(0, 1)``; a :class:`ParameterError` naming ``name`` otherwise.

    With ``plant``: also refused unless it is a ``Hyperbolic2x2`` or ``TransportSystem`` (constant
    speeds, whose mismatched plants are built here).
    """
    what = "a relative error of the speeds lam and mu in (0, 1) (the perturbed speeds stay positive)"
    try:
        eps = finite_real(name, value)
    except ParameterError:
        raise ParameterError(name, what, value) from None
    if not 0.0 < eps < 1.0:
        raise ParameterError(name, what, value)
    if plant is not None and not isinstance(plant, Hyperbolic2x2):
        raise ParameterError(
            name,
            "None for a GeneralHyperbolic2x2: the mismatched plants are built for a Hyperbolic2x2 or "
            "TransportSystem (constant speeds lam, mu)",
            value,
        )
    return eps


def check_local_requirements(
    plant: Any, objective: str, margin_at_least: Any, delays: Any, speed_tolerance: Any
) -> tuple[float | None, tuple[float, float] | None, float | None]:
    """``(margin_at_least, window, eps)`` of a local design's requirements, checked.

    For :func:`~nrobust.hyperbolic.analyses.design_filtered` and
    :func:`~nrobust.hyperbolic.analyses.design_state_feedback`: a window of delays or a margin,
    not both; a speed tolerance needs a ``Hyperbolic2x2`` (constant speeds) and a delay
    requirement, and turns a required margin ``d`` into the window ``[0, d]``.
    """
    margin_at_least = check_objective(objective, margin_at_least)
    window = None if delays is None else check_delays(delays)
    if window is not None and margin_at_least is not None:
        raise ParameterError("margin_at_least", "None with delays (the window [0, d] is delta* > d)", margin_at_least)
    eps = None if speed_tolerance is None else check_speed_tolerance(speed_tolerance, plant=plant)
    if eps is not None:
        if window is None:
            if margin_at_least is None:
                raise ParameterError(
                    "speed_tolerance", "given with a delay requirement (delays, or margin_at_least)", speed_tolerance
                )
            window, margin_at_least = check_delays((0.0, margin_at_least), "margin_at_least"), None
    return margin_at_least, window, eps


def mismatch_gain_loop(
    system: Hyperbolic2x2, e_lam: float, e_mu: float, *, kernel_grid: int = DEFAULT_KERNEL_GRID
) -> AffineGainLoop:
    """``U_BS2(K)`` (eq. (53)) designed for ``system`` on the plant with mismatched speeds, affine in ``K``.

    The law of ``ReflectionController(K)`` is affine in ``K`` (boundary gain ``-K``, integral
    gains ``K^{vu} - (rho - K) K^{uu}`` and ``K^{vv} - (rho - K) K^{uv}`` on the nominal
    kernels) and the mismatched loop's ``B`` is linear in the law's gains, so
    ``B(K) = B_0 + K R`` with ``B_0`` the loop of :func:`mismatch_loop` at ``K = 0`` and ``R``
    the difference of those at ``K = 1`` and ``K = 0`` (``A`` does not depend on the law).

    Parameters
    ----------
    system : Hyperbolic2x2 or TransportSystem
        The plant the law is designed for.
    e_lam, e_mu : float
        Relative errors of the speeds, each ``> -1``.
    kernel_grid : int, default :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID`
        As in :func:`mismatch_loop`.

    Returns
    -------
    AffineGainLoop
    """
    A, B0 = mismatch_loop(system, ReflectionController(0.0), e_lam, e_mu, kernel_grid=kernel_grid)
    _, B1 = mismatch_loop(system, ReflectionController(1.0), e_lam, e_mu, kernel_grid=kernel_grid)
    return AffineGainLoop(A, B0, B1 - B0)


@dataclass(frozen=True, eq=False)
class SpeedTolerance:
    """What is known of a controller on the square of speed mismatches ``[-eps, eps]^2`` with a delay window.

    Compared by identity (``==`` is ``is``).

    Attributes
    ----------
    eps : float
        The tolerance: ``lam (1 + e_lam)``, ``mu (1 + e_mu)`` with ``|e_lam|, |e_mu| <= eps``.
    delays : (float, float)
        The window ``[d_min, d_max]`` of delays required at every mismatch.
    points : tuple of (float, float)
        The mismatches examined: the ``grid x grid`` points of the square, corners first, then,
        when the square's proof stopped, the first mismatch of the boxes it left undecided whose
        verdict is refuted.
    windows : tuple of DelayWindow
        The verdict at each point (:func:`nrobust.design.window_stability`): at the four corners
        with the rigour asked (proven in ball arithmetic with ``rigorous=True``), elsewhere in
        floating point.
    met : bool
        Stable on the window at every point examined (and on the whole square when
        ``certified`` is ``"proven on the square"``).
    certified : str
        What is certified: ``"proven on the square"`` (every mismatch of the square and every
        delay of the window, in ball arithmetic, with ``rigorous=True``:
        :func:`~nrobust.hyperbolic.analyses.mismatch_proof.prove_transport_square` on an uncoupled
        plant, :func:`~nrobust.hyperbolic.analyses.mismatch_coupled.prove_coupled_square` on a coupled
        one with constant couplings),
        ``"proven at the corners"`` or ``"checked at the corners"`` (the other points checked,
        the square between the points not certified), or ``"not met"``.
    statement : str
        The tolerance in words: what is proven, what is only checked, and why the square is not
        proven when it is not.
    route, scope : str
        The route of the mismatched loops and what a certificate is about
        (:func:`~nrobust.hyperbolic.loops.controllers.loop_scope`: on a coupled plant a model
        with the kernels on a grid).
    """

    eps: float
    delays: tuple[float, float]
    points: tuple[tuple[float, float], ...]
    windows: tuple[DelayWindow, ...]
    met: bool
    certified: str
    statement: str
    route: str
    scope: str

    def __repr__(self) -> str:
        return f"SpeedTolerance(eps={float(self.eps)!r}, met={self.met}, certified={self.certified!r})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (each window as its dictionary)."""
        return fields_dict(self)


def _square_scope(
    system: Hyperbolic2x2,
    controller: Controller,
    feedback: StateFeedback,
    filt: tuple[float, float] | None,
    rigorous: bool,
) -> str | None:
    """Why the square is not proven for this loop (None: :func:`prove_transport_square` or
    :func:`prove_coupled_square` applies)."""
    if _integral_gains(feedback) and not _enclosed_gains(system, controller, filt):
        where = "the mismatched loops of a coupled plant hold" if not system.uncoupled else "the law has"
        return (
            f"{where} the law's integral gains, which have no proven enclosure here: only the corners are certified "
            "(on a coupled plant with constant couplings a proportional law U = k u(t, 1), U_BS2(K), U_BS, or a "
            "StateFeedback whose gains evaluate in ball arithmetic is proven on the square)"
        )
    if not system.uncoupled and not has_exact_form(system):
        return (
            "the mismatched loops of a plant with varying couplings (or |kappa| > KAPPA_MAX) are kernel-route models: "
            "only the corners are certified"
        )
    if not system.uncoupled and filt is not None:
        return (
            "a filtered law on a coupled plant has no proven enclosure over the square here: only the corners are "
            "certified"
        )
    if not rigorous:
        return "rigorous=True proves it (in ball arithmetic, on the loop of the PDE itself)"
    return None


def _coupled_proof(
    system: Hyperbolic2x2,
    controller: Controller,
    feedback: StateFeedback,
    eps: float,
    delays: tuple[float, float],
    corner_loops: list[tuple[QuasiPolynomial, QuasiPolynomial, DelayWindow]],
    max_boxes: int,
    kernel_grid: int,
    max_evals: int,
) -> tuple[SquareProof, float | None]:
    """:func:`prove_coupled_square` for the law of ``controller``, and the bound of its gains' error (None: exact).

    ``U_BS2(K)`` (``U_BS``: ``K = rho``) takes the Chebyshev polynomials of its traces within their proven bound
    (:func:`~nrobust.hyperbolic.analyses.mismatch_traces.reflection_traces`); the corners' loops of that fitted law
    (exact route) are proven on the window in turn until one is stable, the point the argument starts from.
    """
    K = _reflection_gain(controller, system)
    if K is None:
        return prove_coupled_square(system, feedback, eps, delays, corner_loops, max_boxes=max_boxes), None
    nan = math.nan
    try:
        law, error = reflection_traces(system, K)
    except CertificationError as exc:
        return SquareProof(
            False, f"the law's kernel traces are not enclosed: {exc}", (nan, nan), nan, nan, 0, nan
        ), None
    fitted = []
    for a, b in [(a, b) for a in (-eps, eps) for b in (-eps, eps)]:
        A, B = mismatch_loop(system, law, a, b)
        try:
            window = window_stability(A, B, delays, rigorous=True, max_evals=max_evals)
        except CertificationError:
            continue
        fitted.append((A, B, window))
        if window.stable and window.certified == "proven":
            break
    proof = prove_coupled_square(system, law, eps, delays, fitted, max_boxes=max_boxes, gain_error=error)
    return proof, error


def _coupled_text(system: Hyperbolic2x2, controller: Controller, feedback: StateFeedback, traces: float | None) -> str:
    """The loop a coupled plant's square is proven on, in words."""
    if traces is not None:
        return (
            f"of the coupled plant (N~, U~ and the gains' term in closed form) under {type(controller).__name__}'s "
            f"law U = {float(feedback.k)!r} u(t, 1) + int g_u u + g_v v dx, its kernel traces g_u, g_v enclosed "
            f"within {traces:.3g} of Chebyshev polynomials (reflection_traces; the square's proof does not rest on "
            f"the kernel grid)"
        )
    if _integral_gains(feedback):
        return (
            f"of the coupled plant (N~, U~ and the gains' term in closed form) under U = k u(t, 1) + int g_u u + "
            f"g_v v dx, k = {float(feedback.k)!r}"
        )
    return f"of the coupled plant (N~ and U~ in closed form) under U = k u(t, 1), k = {float(feedback.k)!r}"


def _route_scope(
    system: Hyperbolic2x2, controller: Controller, kernel_grid: int, rigorous: bool, mapped: bool = True
) -> tuple[str, str]:
    """The route and the scope of the mismatched loops.

    The exact route (an uncoupled plant; a coupled one with constant couplings under ``U_BS2(K)``/``U_BS``
    unfiltered, their traces enclosed, or a ``StateFeedback`` whose gains evaluate in ball arithmetic): the PDE
    itself, each mismatched plant being ``lam (1 + e_lam)``, ``mu (1 + e_mu)`` as computed in floating point;
    with ``mapped`` its margin is mapped to its exact ``tau`` unless the law is filtered (otherwise the proofs
    are about its loop built with ``tau`` rounded). Otherwise :func:`loop_scope` of the kernel route, with why
    the exact route was not taken.
    """
    if isinstance(controller, OutputFeedback):
        route = loop_route(system, controller)
        route_grid = kernel_grid if route == "kernels" else None
        scope = loop_scope(system, controller, route_grid, loop_factors(system, controller, route_grid))
        return route, scope + "; the observer and the law designed on the nominal plant, acting on the mismatched one"
    plant, feedback, filt, enclosure = _mismatched(system, controller, 0.0, 0.0, kernel_grid, rigorous)
    route = loop_route(plant, feedback)
    if route == "exact":
        return route, _exact_scope(system, filt, enclosure, mapped and filt is None)
    scope = loop_scope(plant, feedback, kernel_grid, _loop(plant, feedback, None, kernel_grid))
    if not isinstance(controller, StateFeedback):
        scope += f"; the gains: kernel traces of the nominal plant on {kernel_grid} points"
        refused = _enclosure(system, controller, kernel_grid)
        if isinstance(refused, TraceEnclosure):
            scope += " (rigorous=True takes the exact route: the PDE itself, the traces enclosed)"
        elif isinstance(refused, str):
            scope += f" (their enclosure, the exact route, is refused: {refused})"
        elif filt is not None and not system.uncoupled and has_exact_form(system):
            scope += " (a filtered law keeps the kernel route)"
    return route, scope


def _exact_scope(
    system: Hyperbolic2x2, filt: tuple[float, float] | None, enclosure: TraceEnclosure | None, mapped: bool
) -> str:
    """The scope of mismatched loops on the exact route (:func:`_route_scope`)."""
    plants = "each mismatched plant is lam (1 + e_lam), mu (1 + e_mu) as computed in floating point, its numbers exact"
    if mapped:
        plants += ", tau mapped to its exact value 1/lam' + 1/mu' (given_plant_scale)"
    else:
        why = "a filtered law's loop is" if filt is not None else "the proofs are"
        plants += f", tau the double nearest 1/lam' + 1/mu' ({why} not mapped to the exact tau)"
    plants += " and the principal gains enclosed with the proven radii of their rounding"
    if system.uncoupled:
        return f"the PDE itself (uncoupled: N~ = 0, the law U = k u(t, 1); {plants})"
    radius = max((d.radius for d in loop_factors(system, OpenLoop())[0].distributed), default=0.0)
    kernel = f"N~ and U~ in closed form, stored within a proven {radius:.1e} that every enclosure includes"
    if enclosure is None:
        gains = "the integral gains as Taylor models in ball arithmetic"
    else:
        gains = (
            f"the law's gains enclosed within {enclosure.error:.1e} of Chebyshev polynomials (trace_enclosure: "
            f"the traces of eq. (53) on the nominal plant solved by collocation, their errors' total variations within "
            f"{max(enclosure.variation_u, enclosure.variation_v):.1e}; every enclosure holds the true law)"
        )
    return f"the PDE itself ({kernel}; {gains}; {plants})"


def _reflection_gain(controller: Controller, system: Hyperbolic2x2) -> float | None:
    """``K`` of ``U_BS2(K)`` (``rho`` for ``U_BS``), None for other controllers."""
    if isinstance(controller, ReflectionController):
        return controller.K
    if isinstance(controller, FiniteTimeController):
        return system.rho
    return None


def _enclosed_gains(system: Hyperbolic2x2, controller: Controller, filt: tuple[float, float] | None) -> bool:
    """True when the mismatched loops' integral gains are enclosed on the square: a coupled plant with the closed
    form, unfiltered, and ``U_BS2(K)``/``U_BS`` (:func:`reflection_traces`) or a ``StateFeedback`` whose gains
    evaluate in ball arithmetic."""
    if system.uncoupled or filt is not None or not has_exact_form(system):
        return False
    if _reflection_gain(controller, system) is not None:
        return True
    return isinstance(controller, StateFeedback) and gain_failure(system, controller.g_u, controller.g_v) is None


def _integral_gains(feedback: StateFeedback) -> bool:
    """True when a state feedback has an integral term (a callable or a nonzero gain)."""
    return any(callable(g) or g != 0.0 for g in (feedback.g_u, feedback.g_v))


class _Probes(NamedTuple):
    """What the checks of the undecided boxes found: the first mismatch refuted (with its verdict) or None, and
    in words that mismatch or what was checked."""

    refuted: tuple[tuple[float, float], DelayWindow] | None
    text: str


def _probe_undecided(
    system: Hyperbolic2x2,
    controller: Controller,
    eps: float,
    delays: tuple[float, float],
    undecided: tuple[tuple[float, float, float, float], ...],
    examined: list[tuple[float, float]],
    kernel_grid: int,
    max_evals: int,
) -> _Probes:
    """Check the middle and corners of the boxes of mismatches a square's proof left undecided, in its order.

    Each mismatch (clipped to the square, those in ``examined`` skipped) gets the window's verdict in floating
    point, up to :data:`MAX_UNDECIDED_PROBES` of them; the first refuted is checked again with the delay margin
    proven in ball arithmetic (:func:`nrobust.design.window_stability` with ``rigorous=True`` on
    :func:`mismatch_loop` with ``rigorous=True``), whose verdict stands when it is made.
    """
    seen = set(examined)
    probes: list[tuple[float, float]] = []
    boxes = 0
    for a0, a1, b0, b1 in undecided:
        if len(probes) >= MAX_UNDECIDED_PROBES:
            break
        boxes += 1
        for a, b in ((0.5 * (a0 + a1), 0.5 * (b0 + b1)), (a0, b0), (a0, b1), (a1, b0), (a1, b1)):
            point = (min(max(a, -eps), eps), min(max(b, -eps), eps))
            if point not in seen and len(probes) < MAX_UNDECIDED_PROBES:
                seen.add(point)
                probes.append(point)
    undecided_points = 0
    for point in probes:
        A, B = mismatch_loop(system, controller, point[0], point[1], kernel_grid=kernel_grid)
        try:
            window = window_stability(A, B, delays, max_evals=max_evals)
            if not window.stable:
                try:
                    A, B = mismatch_loop(system, controller, point[0], point[1], kernel_grid=kernel_grid, rigorous=True)
                    window = window_stability(A, B, delays, rigorous=True, max_evals=max_evals)
                except CertificationError:
                    pass  # the verdict in floating point stands
        except CertificationError:
            undecided_points += 1
            continue
        if not window.stable:
            dm = window.margin
            margin = with_accuracy(dm.margin, dm.accuracy) + (" (proven)" if dm.rigorous else "")
            text = (
                f"({point[0]!r}, {point[1]!r}) lies in a box of mismatches the square's proof left undecided: "
                f"{window.reason}, delay margin {margin}"
            )
            return _Probes((point, window), text)
    decided = len(probes) - undecided_points
    text = (
        f"the middle and corners of {boxes} of the {len(undecided)} boxes of mismatches it left undecided checked in "
        f"floating point: {decided} points stable"
    )
    if undecided_points:
        text += f", {undecided_points} not decided"
    return _Probes(None, text)


def speed_tolerance(
    system: Hyperbolic2x2,
    controller: Controller,
    eps: float,
    delays: tuple[float, float],
    *,
    grid: int = 3,
    kernel_grid: int = DEFAULT_KERNEL_GRID,
    rigorous: bool = False,
    max_evals: int = 2_000_000,
    corner_windows: tuple[DelayWindow, ...] | None = None,
    max_boxes: int | None = None,
) -> SpeedTolerance:
    """Stability on a delay window of ``controller`` under speed mismatches ``(e_lam, e_mu)`` in ``[-eps, eps]^2``.

    At the four corners ``(+-eps, +-eps)`` the mismatched loop (:func:`mismatch_loop`) gets a
    window certificate (:func:`nrobust.design.window_stability`: no crossing delay in
    ``[d_min, d_max]`` and no zero in ``Re s > 0`` at its middle; proven in ball arithmetic with
    ``rigorous=True``); at the other points of a ``grid x grid`` grid of the square the same
    verdict in floating point.

    Between the points: the delay margin, and the stability windows, are not continuous in the
    mismatch (a pair of crossing frequencies is born where ``|A(i w)|^2 - |B(i w)|^2`` gains a
    double zero, :func:`mismatch_region`), so the points alone certify nothing in between. On an
    uncoupled plant (the loop is the PDE itself, eqs. (10), (13), (16): ``U = k u(t, 1)``, filtered
    or not) with ``rigorous=True`` the whole square is proven
    (:func:`~nrobust.hyperbolic.analyses.mismatch_proof.prove_transport_square`: the mismatch
    moves only the round trip ``tau``; a strongly stable difference operator keeps the zeros off
    infinity, no zero crosses the imaginary axis for any ``tau`` of the square and delay of the
    window, proven on boxes in ball arithmetic, and a corner is proven stable), ``certified ==
    "proven on the square"``. When that proof stops (out of boxes, or at a box it cannot decide),
    the middle and corners of the boxes of mismatches it left undecided
    (:attr:`~nrobust.hyperbolic.analyses.mismatch_proof.SquareProof.undecided`: the box it stopped
    at, then the pending ones, smallest first; at most :data:`MAX_UNDECIDED_PROBES` mismatches) are
    checked in floating point, a refuted one again with its delay margin proven in ball
    arithmetic: the first refuted joins :attr:`SpeedTolerance.points` and the tolerance is
    ``"not met"``; otherwise the corners' certificate stands and :attr:`SpeedTolerance.statement`
    says why the square is not proven and how many points of the undecided boxes were checked. On a coupled plant with
    constant couplings and ``rigorous=True`` the square is proven the same way for ``U = k u(t, 1)``,
    ``U_BS2(K)``, ``U_BS`` and a ``StateFeedback`` whose gains evaluate in ball arithmetic
    (:func:`~nrobust.hyperbolic.analyses.mismatch_coupled.prove_coupled_square`; ``U_BS2(K)``'s kernel
    traces enclosed by :func:`~nrobust.hyperbolic.analyses.mismatch_traces.reflection_traces`, the
    corners of the square then proven again on the exact loop of the enclosed law); a filtered law
    or varying couplings keep the corners' certificate only.

    Parameters
    ----------
    system : Hyperbolic2x2 or TransportSystem
        The plant the controller is designed for.
    controller : Controller
        The controller (its ``feedback_law`` on ``system``).
    eps : float
        The tolerance, in ``(0, 1)``.
    delays : (float, float)
        The window ``[d_min, d_max]`` (``0 <= d_min <= d_max``, ``d_max > 0``).
    grid : int, default 3
        Points per side of the checked grid (``>= 2``; 3 adds the edge midpoints and ``e = 0``).
    kernel_grid : int, default :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID`
        As in :func:`mismatch_loop`.
    rigorous : bool, default False
        Prove the corners' verdicts in ball arithmetic, and on an uncoupled plant the square.
    max_evals : int, optional
        Work bound of each delay margin.
    corner_windows : tuple of DelayWindow, optional
        The corners' verdicts when already certified (by a design under this tolerance), in
        the order ``(-eps, -eps), (-eps, eps), (eps, -eps), (eps, eps)``: four verdicts of the
        corners' loops on windows containing ``delays``.
    max_boxes : int, optional
        Work bound of the square's proof: boxes of ``(w, tau)`` on an uncoupled plant
        (default :data:`~nrobust.hyperbolic.analyses.mismatch_proof.MAX_SQUARE_BOXES`), of
        ``(tau w, e_lam, e_mu)`` on a coupled one (default
        :data:`~nrobust.hyperbolic.analyses.mismatch_coupled.MAX_COUPLED_BOXES`, each box far dearer;
        :data:`~nrobust.hyperbolic.analyses.mismatch_coupled.MAX_GAIN_BOXES` for ``U_BS2(K)``, ``U_BS`` and a
        ``StateFeedback`` with integral gains, dearer again).

    Returns
    -------
    SpeedTolerance

    Raises
    ------
    ParameterError
        A bad argument (``eps`` outside ``(0, 1)``, ``delays`` not a window, ``grid < 2``,
        ``max_boxes < 1``, ``corner_windows`` not four verdicts on windows containing ``delays``).
    CertificationError
        A delay margin or count failed.

    Examples
    --------
    >>> from nrobust import TransportSystem
    >>> plant = TransportSystem(1.0, 2.0, 1.0, 0.5)     # |rho q| + |K q| = 0.7 < 1
    >>> speed_tolerance(plant, ReflectionController(0.2), 0.3, (0.0, 2.0), grid=2, rigorous=True).certified
    'proven on the square'
    """
    _check_pair(system, controller)
    eps = check_speed_tolerance(eps, "eps")
    d_lo, d_hi = check_delays(delays)
    grid = positive_int("grid", grid, 2, 33)
    kernel_grid = check_kernel_grid(kernel_grid)
    max_evals = positive_int("max_evals", max_evals)
    if max_boxes is None:
        if system.uncoupled:
            max_boxes = MAX_SQUARE_BOXES
        elif isinstance(controller, (ReflectionController, FiniteTimeController)) or (
            isinstance(controller, StateFeedback) and _integral_gains(controller)
        ):
            max_boxes = MAX_GAIN_BOXES
        else:
            max_boxes = MAX_COUPLED_BOXES
    max_boxes = positive_int("max_boxes", max_boxes)
    if corner_windows is not None and (
        len(corner_windows) != 4
        or not all(isinstance(w, DelayWindow) and w.delays[0] <= d_lo and d_hi <= w.delays[1] for w in corner_windows)
    ):
        raise ParameterError(
            "corner_windows", f"four DelayWindow verdicts on windows containing [{d_lo!r}, {d_hi!r}]", corner_windows
        )
    corners = [(a, b) for a in (-eps, eps) for b in (-eps, eps)]
    axis = np.linspace(-eps, eps, grid)
    inner = [(float(a), float(b)) for a in axis for b in axis if (float(a), float(b)) not in corners]
    windows: list[DelayWindow] = []
    for n, point in enumerate([*corners, *inner]):
        if n < 4 and corner_windows is not None:
            windows.append(corner_windows[n])
            continue
        corner = rigorous and n < 4
        A, B = mismatch_loop(system, controller, point[0], point[1], kernel_grid=kernel_grid, rigorous=corner)
        windows.append(window_stability(A, B, (d_lo, d_hi), rigorous=corner, max_evals=max_evals))
    points = [*corners, *inner]
    met = all(w.stable for w in windows)
    proven = all(w.certified == "proven" for w in windows[:4])
    proof = None
    why_not: str | None
    found = ""
    if isinstance(controller, OutputFeedback):
        # the observer designed on the nominal plant is in every mismatched loop (a model in floating point)
        why_not = (
            "an output feedback's mismatched loops hold its observer, designed on the nominal plant and computed in "
            "floating point (a model): only the corners are certified"
        )
    else:
        _, feedback, filt, _ = _mismatched(system, controller, 0.0, 0.0, kernel_grid)
        why_not = _square_scope(system, controller, feedback, filt, rigorous)
    traces: float | None = None
    if met and why_not is None:
        loops = [
            mismatch_loop(system, controller, a, b, kernel_grid=kernel_grid, rigorous=rigorous) for a, b in corners
        ]
        corner_loops = [(A, B, w) for (A, B), w in zip(loops, windows[:4])]
        if system.uncoupled:
            proof = prove_transport_square(
                system, feedback.k, filt, eps, (d_lo, d_hi), corner_loops, max_boxes=max_boxes
            )
        else:  # not filtered, gains enclosed (_square_scope): the corners' loops take the exact route
            proof, traces = _coupled_proof(
                system, controller, feedback, eps, (d_lo, d_hi), corner_loops, max_boxes, kernel_grid, max_evals
            )
        why_not = None if proof.proven else proof.reason
        if proof.undecided:
            probes = _probe_undecided(
                system, controller, eps, (d_lo, d_hi), proof.undecided, points, kernel_grid, max_evals
            )
            if probes.refuted is not None:
                points.append(probes.refuted[0])
                windows.append(probes.refuted[1])
                met = False
                found = f"; {probes.text}"
            else:
                why_not = f"{why_not}; {probes.text}"
    if not met:
        certified = "not met"
        bad = [p for p, w in zip(points, windows) if not w.stable]
        statement = (
            f"not stable on [{float(d_lo)!r}, {float(d_hi)!r}] at (e_lam, e_mu) = "
            + ", ".join(f"({float(a)!r}, {float(b)!r})" for a, b in bad)
            + found
        )
    elif proof is not None and proof.proven:
        certified = "proven on the square"
        loop_text = (
            f"d(s) (1 - rho q e^{{-tau s}}) - k q n(s) e^{{-(tau + delta) s}} with k = {float(feedback.k)!r}, "
            f"d = {'1 + ' + repr(float(filt[1])) + ' s' if filt else '1'}, "
            f"n = {'1 + ' + repr(float(filt[0])) + ' s' if filt else '1'}"
            if system.uncoupled
            else _coupled_text(system, controller, feedback, traces)
        )
        statement = (
            f"exponentially stable for every (e_lam, e_mu) in [-{float(eps)!r}, {float(eps)!r}]^2 and every delay in "
            f"[{float(d_lo)!r}, {float(d_hi)!r}], proven in ball arithmetic on the loop of the PDE {loop_text}: "
            f"{proof.reason}"
        )
        if proof.base >= 0:
            a, b = points[proof.base]
            statement += f" (corners[{proof.base}]: (e_lam, e_mu) = ({float(a)!r}, {float(b)!r}))"
    else:
        certified = "proven at the corners" if proven else "checked at the corners"
        statement = (
            f"stable for every delay in [{float(d_lo)!r}, {float(d_hi)!r}] at the 4 corners (e_lam, e_mu) = "
            f"(+-{float(eps)!r}, +-{float(eps)!r}) "
            f"({'proven in ball arithmetic' if proven else 'checked in floating point'}) and at the "
            f"{len(points) - 4} other points of a {grid} x {grid} grid of the square (checked in floating point); "
            f"between the points not certified (the stability windows are not continuous in the mismatch; the square "
            f"is not proven: {why_not})"
        )
    route, scope = _route_scope(system, controller, kernel_grid, rigorous, mapped=False)
    if rigorous and not isinstance(controller, OutputFeedback):
        if _mismatched(system, controller, 0.0, 0.0, kernel_grid, True).enclosure is not None:
            scope = (
                f"the corners: {scope}; the other points (floating point): the kernel route with the traces on "
                f"{kernel_grid} points"
            )
    if certified == "proven on the square":  # the statement's loop of the PDE, not the corners' route
        scope = "the PDE's loop with the speeds in the square, exact in tau s (no kernel grid)" + (
            f"; the law's gain kernels Chebyshev polynomials of their traces, within their proven bound {traces:.1e}"
            if traces
            else ""
        )
    return SpeedTolerance(eps, (d_lo, d_hi), tuple(points), tuple(windows), met, certified, statement, route, scope)
