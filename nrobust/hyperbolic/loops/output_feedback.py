"""Output feedback from the unactuated boundary: a state feedback fed by an exact predictor of the state.

The measurement is ``y(t) = v(t, 0)``. The backstepping transformation (30)-(31) is a Volterra
transformation from ``x = 0``, so ``v(t, 0) = beta(t, 0)``, and along the characteristics
(eq. (37)) ``beta(t, 0) = beta(t - 1/mu, 1)``: with ``z(t) = beta(t, 1)`` the output of the
delay form (39), the measurement is ``z`` delayed by the window ``w = 1/mu``,
``y(t) = z(t - w)``. A state feedback of the package is a functional of the past of ``z`` on
``[t - tau, t]``: ``U = -(n/d) B~ z`` with the loop ``A = d (1 - Phi)``, ``B = n B~`` of
:mod:`~nrobust.hyperbolic.loops.controllers` (``n/d = (1 + a s)/(1 + b s)`` for a filtered
law, else 1). Only ``z`` on the last window ``(t - w, t]`` is not measured yet; ``B~`` reads it
through its kernel ``m`` there (``N~`` for U_BS and U_BS2(K)).

The observer predicts it: on the window the plant obeys the delay form ``z = Phi z + U``
(eq. (39), ``Phi = rho q e^{-tau s} - I_N``), whose terms reaching before ``t - w`` are
measured, so the prediction solves the convolution equation of the second kind
``x + N~_w * x = g`` on the window (``N~_w`` the first ``w`` units of ``N~``, eq. (40)),
driven by the commands the controller sent. Through the resolvent ``r`` of ``N~`` on the window
(:func:`~nrobust.volterra.window_resolvent`), the law's window term applied to the prediction is
``H g`` with ``H(s) = int_0^w h(nu) e^{-nu s} dnu``, ``h = m - m * r``
(:func:`~nrobust.volterra.window_law`; ``h = r`` for U_BS2), and the controller's output is

    U_c = (n/d) (-B~ z_m + H (U_c - (1 - Phi) z_m)),     z_m = e^{s w} y,

which uses ``y`` only up to time ``t`` (the terms of ``B~ + (1 - Phi) H`` below the delay ``w``
cancel). The observer is exact: without a delay, the estimated state is the state after one
window and the loop is the state feedback's.

With a delay ``delta_a`` on the actuation and ``delta_m`` on the measurement, the plant gets
``e^{-delta_a s} U_c`` and the controller ``e^{-delta_m s} y``, and the closed loop is
``F = A_o + B_o e^{-delta s}`` with ``delta = delta_a + delta_m`` (only the sum matters) and

    A_o = A - n G e^{-delta_o s},      B_o = B + n G,      G = (1 - Phi) H,

where ``delta_o`` is the actuation delay the observer assumes (the delay of the commands it
replays; 0 by default). At ``delta = delta_o`` the loop is the state feedback's with that delay,
``A + B e^{-delta_o s}``; at ``delta = delta_o = 0`` it is the target system (for U_BS2(K),
``1 - (rho - K) q e^{-tau s}``). ``G`` is a distributed delay on ``[0, tau + w]``, so the
difference operator, hence strong stability, is the state feedback's: the observer keeps the
delay robustness of the law (Theorem 4) and changes the margin's value.

The observer has no reflection of its own to keep: its error enters only through the window,
where the boundary ``x = 0`` reflects the measured ``y`` (``u(t, 0) = q y(t)``). The parameters
left to design are the law's (``K`` of U_BS2) and ``delta_o``.

:func:`observer_term` computes ``G`` (:func:`~nrobust.volterra.resolvent_product`) in floating
point, with an estimate of its error: a proof about the loop is a proof about this model. On a
plant with constant coefficients :func:`~nrobust.hyperbolic.loops.observer_proof.proven_observer_term`
encloses ``G`` with a proven error instead (the loop of
:func:`~nrobust.hyperbolic.loops.controllers.loop_factors` on the exact route), and a proof is about
the PDE.
"""

from __future__ import annotations

import itertools
import math
from functools import lru_cache

import numpy as np

from ...distributed_delay import DistributedDelay
from ...errors import ParameterError
from ...quasipoly import QuasiPolynomial
from ...volterra import (
    C_DEGREE,
    C_PIECES,
    ResolventProduct,
    WindowKernel,
    resolvent_product,
    window_law,
    window_resolvent,
)

__all__ = ["observer_term", "output_feedback_factors"]

# Segments per window of the stored G, doubled on an interval (nrobust.volterra.resolvent_product) while its fit
# deviates by more than OBSERVER_RTOL relative: on the paper's plants 8 reach 1e-14 (the resolvent's own error is
# larger), and G then has a third of the 24 segments of the default, each evaluation of the loop a third of the work.
OBSERVER_SEGMENTS, OBSERVER_RTOL = 8, 1e-13
# Segments joined only when their starts are uniformly spaced to this many ulps: the exponential sums over
# uniform starts are chirp-z transforms (nrobust.distributed_delay), else one exponential per segment and frequency.
_UNIFORM_ULPS = 8.0
# Rounding of the refinement (_refined_term): a multiple of eps large enough for the composition P(alpha + beta t)
# of degree d (Horner in polynomial arithmetic, gamma_{2d+1} sum |P_k|) and the rounding of alpha, beta (<= 3 eps
# each, times |P'| <= sum k |P_k|): 8 (d + 2) eps sum (k + 1) |P_k| bounds their sum; d + 2 times it bounds the
# variation of the error on a segment (6 eps sum k (k - 1) |P_k| from |P''|, d gamma_{2d+1} from the coefficients)
# and its jumps at the segment's ends.
_REFINE_ULPS = 8.0
_EPS = float(np.finfo(float).eps)


def observer_term(open_loop: QuasiPolynomial, law: QuasiPolynomial, window: float) -> ResolventProduct | None:
    """``G = (1 - Phi) H`` of the open loop, the law and the measurement's window (module notes).

    Parameters
    ----------
    open_loop : QuasiPolynomial
        ``1 - Phi = 1 - rho q e^{-tau s} + int_0^tau N~(nu) e^{-nu s} dnu`` (eq. (39)).
    law : QuasiPolynomial
        ``B~``: the unfiltered law is ``U = -B~ beta(., 1)`` (the loop factor ``B`` of the
        state feedback without its filter's numerator); its kernel on the window is ``m``.
    window : float
        ``w``: the transport time of ``v`` (``1/mu``, in the loop's time unit).

    Returns
    -------
    ResolventProduct or None
        None when the law uses no value of the window (``m = 0``: e.g. the open loop, or
        U_BS2 on an uncoupled plant), where ``G = 0``.

    Raises
    ------
    ParameterError
        A law with a point delay shorter than the window (a value the measurement has not
        reached and the predictor's formula does not cover).
    """
    if any(delay < window and np.any(coefs != 0) for coefs, delay in law.point_terms):
        raise ParameterError("controller", "a law whose point delays are at least the window 1/mu", law)
    m = tuple(d.scale(-1.0) for d in law.distributed if d.a < window and not d.is_zero)
    if not m:
        return None
    return _observer_term(open_loop, m, window)


@lru_cache(maxsize=16)
def _observer_term(open_loop: QuasiPolynomial, m: tuple[DistributedDelay, ...], window: float) -> ResolventProduct:
    """:func:`observer_term` from the law's kernel ``m`` on the window (cached: the law's terms that the window
    does not reach, such as U_BS2's ``K q e^{-tau s}``, do not change it)."""
    kernels = [d for d in open_loop.distributed if not d.is_zero]
    if len(kernels) > 1:
        raise ParameterError("open_loop", "a delay form with one distributed term N~ (eq. (39))", open_loop)
    if kernels:
        h = window_law(m, window_resolvent(kernels[0], window))
    else:  # N~ = 0: the window's equation is x = f, h = m
        h = WindowKernel(m, window, np.zeros((C_PIECES, C_DEGREE + 1)), 0.0)
    return resolvent_product(open_loop, h, OBSERVER_SEGMENTS, OBSERVER_RTOL)


def output_feedback_factors(
    A: QuasiPolynomial,
    B: QuasiPolynomial,
    term: ResolventProduct | QuasiPolynomial | None,
    numerator: tuple[float, ...] = (1.0,),
    observer_delay: float = 0.0,
) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``(A_o, B_o)`` of the output feedback from the state feedback's ``(A, B)`` (module notes).

    The collocated observer's loop has the same form
    (:mod:`~nrobust.hyperbolic.loops.collocated`), its ``G`` given as a quasi-polynomial; the
    distributed terms of each of its factors are then summed into one kernel on the union of their
    nodes when that union is uniform (:func:`consolidated`).
    The observer's ``G`` (a :class:`~nrobust.volterra.ResolventProduct`) is stored as one term
    (:func:`_joined`), and the kernels of ``A`` and ``B`` that its segments refine are stored on
    them (:func:`_refined_onto`, its rounding added to their error bounds), so that each factor
    holds one kernel where it held several: the loop's values agree with the sum of the separate
    terms to rounding, and each evaluation integrates one kernel instead of four.

    Parameters
    ----------
    A, B : QuasiPolynomial
        The state feedback's loop, ``A = d (1 - Phi)``, ``B = n B~``.
    term : ResolventProduct, QuasiPolynomial or None
        ``G`` from :func:`observer_term`, or ``G`` itself (None: ``G = 0``).
    numerator : tuple of float
        ``n``, increasing powers (``(1, a)`` for a law filtered by ``(1 + a s)/(1 + b s)``).
    observer_delay : float
        ``delta_o``.
    """
    if term is None:
        return A, B
    if isinstance(term, QuasiPolynomial):
        ng = term.times_poly(list(numerator))
        return consolidated(A - ng.shift(observer_delay)), consolidated(B + ng)
    ng = _joined(term.product).times_poly(list(numerator))
    shifted = ng.shift(observer_delay)
    A, B = _refined_onto(A, shifted), _refined_onto(B, ng)
    return A - shifted, B + ng


def _joined(G: QuasiPolynomial) -> QuasiPolynomial:
    """``G`` of :func:`observer_term` with its kernels on consecutive intervals stored as one term.

    The product holds one term of polynomial pieces per interval between breakpoints
    (:func:`~nrobust.volterra.resolvent_product`), all of one segment length on the paper's plants.
    As one term of the same pieces (the same stored kernel, coefficients zero-padded to one degree),
    the loop integrates them as one exponential sum over all the segments instead of one per interval
    (the values agree to rounding). The joined term's error bounds are the largest of the terms' ``radius``
    and the sum of their ``variation_radius`` and of the jumps of the error where they meet (the two
    radii at each inner end). Terms that are not plain polynomial pieces on consecutive
    intervals, or whose segments together are not uniform (several lengths), are left as they are.
    """
    terms = G.distributed
    plain = all(
        d.interpolation == "polynomial" and d.moment == 0 and d.poly.size == 1 and d.poly[0] == 1.0 for d in terms
    )
    if len(terms) < 2 or G.point_terms or not plain:
        return G
    if any(u.b != v.a for u, v in itertools.pairwise(terms)):
        return G
    nodes = np.concatenate([terms[0].nodes[:1], *(d.nodes[1:] for d in terms)])
    if not _uniform(nodes[:-1]):
        return G  # segments of several lengths: one sum per length either way, and each interval's is uniform
    degree = max(d.pieces[2].shape[1] for d in terms)
    coefficients = np.concatenate([np.pad(d.pieces[2], ((0, 0), (0, degree - d.pieces[2].shape[1]))) for d in terms])
    # the error of the joined kernel: the largest of the terms', its variation theirs and its jumps where they meet
    variation = math.fsum(
        [d.variation_radius for d in terms] + [u.radius + v.radius for u, v in itertools.pairwise(terms)]
    )
    joined = DistributedDelay(
        nodes,
        None,
        interpolation="polynomial",
        coefficients=coefficients,
        radius=max(d.radius for d in terms),
        variation_radius=_up(variation) if variation else 0.0,
    )
    return QuasiPolynomial([], [], [joined])


def consolidated(P: QuasiPolynomial) -> QuasiPolynomial:
    """``P`` with its distributed terms summed into one term on the union of their nodes, when that is uniform.

    The terms (polynomial pieces, one ``q(s)`` and moment, real) are re-expanded on the union's segments
    (:func:`_refined_term`, zero outside each one's support, its rounding added to the error bounds)
    and added (:meth:`~nrobust.distributed_delay.DistributedDelay.plus`, the bounds add). On the paper's
    plant the collocated loop's six kernels (on ``[0, 2]``, ``[2, 4]`` and the four unit intervals,
    all in steps of ``1/8``) become one, integrated once per evaluation of the loop instead of six times.
    ``P`` is returned as it is when the terms are fewer than two, of another kind, or their nodes
    together are not uniformly spaced; and when every term carries a proven error bound and the sum's
    would be more than twice theirs (the re-expansion's rounding bound, from the pieces' monomial
    coefficients, is far above the bounds of ball arithmetic: on the paper's plant under U_BS2(0.1) with
    ``kappa = -0.715`` it was ``3.4e-13`` against ``1e-15``, and the proven margin's ball 45 times wider).
    """
    terms = P.distributed
    if len(terms) < 2:
        return P
    first = terms[0]
    if any(
        d.interpolation != "polynomial" or d.moment != first.moment or not np.array_equal(d.poly, first.poly)
        for d in terms
    ):
        return P
    nodes = np.unique(np.concatenate([d.nodes for d in terms]))
    if nodes.size < 2 or not _uniform(nodes[:-1]):
        return P
    degree = max(d.pieces[2].shape[1] for d in terms)
    target = DistributedDelay(
        nodes, None, first.poly, first.moment, "polynomial", coefficients=np.zeros((nodes.size - 1, degree))
    )
    refined = [_refined_term(d, target) for d in terms]
    if any(r is None for r in refined):
        return P
    total = refined[0]
    for r in refined[1:]:
        assert total is not None and r is not None
        total = total.plus(r)
    assert total is not None
    bound = math.fsum(d.radius for d in terms)
    if all(d.radius > 0.0 for d in terms) and total.radius > 2.0 * bound:
        return P  # proven terms: their bounds kept rather than one integration per evaluation
    return QuasiPolynomial.from_parts(P.point_terms, [total], P.point_radii or None)


def _uniform(starts: np.ndarray) -> bool:
    """The segment starts are uniformly spaced to :data:`_UNIFORM_ULPS` ulps."""
    ideal = starts[0] + (starts[-1] - starts[0]) / max(starts.size - 1, 1) * np.arange(starts.size)
    return bool(np.max(np.abs(starts - ideal)) <= _UNIFORM_ULPS * _EPS * max(float(np.max(np.abs(starts))), 1.0))


def _refined_onto(P: QuasiPolynomial, G: QuasiPolynomial) -> QuasiPolynomial:
    """``P`` with each distributed term that ``G``'s one term refines stored on ``G``'s segments.

    A term of ``P`` (polynomial pieces, the same ``q(s)`` and moment as ``G``'s term, degree at most
    its degree) whose nodes are nodes of ``G``'s term, inside its support, is re-expanded on the finer
    segments (zero beyond its support) so that the sum with ``G`` is one term of ``G``'s segments
    (:meth:`~nrobust.distributed_delay.DistributedDelay.plus`): on the paper's plant ``N~`` of the
    delay form (16 pieces on ``[0, tau]``) and ``G`` (24 pieces on ``[0, tau + 1/mu]``) become one
    kernel, integrated once per evaluation of the loop instead of twice. The re-expansion
    ``P_i(alpha + beta t)`` is computed in floating point; its error is added to the term's bounds:
    ``radius`` grows by ``8 (d + 2) eps sum_k (k + 1) |P_ik|`` on each fine segment (the composition and
    the rounding of ``alpha``, ``beta``; ``|P_i'| <= sum_k k |P_ik|`` on ``[0, 1]``; also where a fine
    segment is the piece itself, where it covers the rounding of the coefficients' sum with the target's),
    and ``variation_radius`` by ``d + 2`` times the sum of that growth over the fine segments (the
    variation of the error on each, ``d`` times its coefficients' sum, and its jumps between them) and by
    the term's ``radius`` at each end of its support inside the target's (where its error jumps to zero).
    Other terms are kept.
    """
    if len(G.distributed) != 1 or not P.distributed:
        return P
    (target,) = G.distributed
    if target.interpolation != "polynomial":
        return P
    terms = [_refined_term(d, target) for d in P.distributed]
    if all(t is None for t in terms):
        return P
    kept = [d if t is None else t for d, t in zip(P.distributed, terms)]
    return QuasiPolynomial.from_parts(P.point_terms, kept, P.point_radii or None)


def _refined_term(d: DistributedDelay, target: DistributedDelay) -> DistributedDelay | None:
    """``d`` on the segments of ``target`` (see :func:`_refined_onto`), or None when they do not refine it."""
    if d.interpolation != "polynomial" or d.moment != target.moment or not np.array_equal(d.poly, target.poly):
        return None
    start, h, coefs = d.pieces
    fine = target.nodes
    degree = target.pieces[2].shape[1] - 1
    if coefs.shape[1] - 1 > degree or np.iscomplexobj(coefs) or d.a < fine[0] or d.b > fine[-1]:
        return None
    at = np.searchsorted(fine, d.nodes)
    if np.any(at >= fine.size) or not np.array_equal(fine[np.minimum(at, fine.size - 1)], d.nodes):
        return None  # a node of d that is not a node of the target
    d_deg = coefs.shape[1] - 1
    # the fine segments of each piece i, and t = (nu - start_i) / h_i = alpha + beta t' on each
    piece = np.repeat(np.arange(start.size), np.diff(at))
    k = np.arange(int(at[0]), int(at[-1]))
    alpha, beta = (fine[k] - start[piece]) / h[piece], (fine[k + 1] - fine[k]) / h[piece]
    P = coefs[piece]
    local = np.zeros((k.size, d_deg + 1))  # P_i(alpha + beta t') by Horner's rule in polynomial arithmetic
    local[:, 0] = P[:, d_deg]
    for j in range(d_deg - 1, -1, -1):
        local[:, 1:] = alpha[:, None] * local[:, 1:] + beta[:, None] * local[:, :-1]
        local[:, 0] = alpha * local[:, 0] + P[:, j]
    out = np.zeros((fine.size - 1, degree + 1))
    out[k, : d_deg + 1] = local
    weight = _REFINE_ULPS * (d_deg + 2) * _EPS * np.sum(np.abs(coefs) * (np.arange(d_deg + 1) + 1.0), axis=1)
    error = np.zeros(fine.size - 1)
    error[k] = weight[piece]
    # where d's support ends inside the target's, its error (at most d.radius) jumps to 0
    ends = d.radius * ((d.a > fine[0]) + (d.b < fine[-1]))
    return DistributedDelay(
        fine,
        None,
        d.poly,
        d.moment,
        "polynomial",
        coefficients=out,
        radius=_up(d.radius + float(np.max(error))),
        variation_radius=_up(d.variation_radius + ends + (d_deg + 2) * float(np.sum(error))),
    )


def _up(x: float) -> float:
    """``x`` rounded up by two ulps (a sum of error bounds stays an upper bound)."""
    return float(np.nextafter(np.nextafter(x, np.inf), np.inf))
