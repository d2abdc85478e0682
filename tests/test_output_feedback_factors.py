"""How the output feedback's loop stores its kernels: one term per factor, the same function as the separate terms.

``output_feedback_factors`` stores the observer's ``G`` (one term per interval of the
resolvent product) as one term and re-expands the delay form's ``N~`` onto its segments, so that
``A_o = A - G`` and ``B_o = B + G`` hold one kernel each. The oracles are the separate terms
themselves: the state feedback's factors and the pieces of ``G`` as :func:`observer_of` returns
them, summed only on evaluation, and each stored kernel read point by point (``kernel_at``) against
the sum of the kernels it replaces, which must lie within the error bound the refinement adds.
"""

from __future__ import annotations

import numpy as np
import pytest

import nrobust as nr
from nrobust.distributed_delay import DistributedDelay
from nrobust.hyperbolic.loops import output_feedback
from nrobust.hyperbolic.loops.controllers import (
    CollocatedOutputFeedback,
    FilteredController,
    OutputFeedback,
    ReflectionController,
    loop_factors,
    loop_route,
    observer_of,
)
from nrobust.quasipoly import QuasiPolynomial

PAPER = nr.Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
#: Unequal speeds: the window 1/mu = 2, the round trip tau = 2.5.
SLOW_V = nr.Hyperbolic2x2(2.0, 0.5, 0.4, 0.7, 0.8, 0.6)


def _separate(plant, controller: OutputFeedback):
    """``(A - n G e^{-delta_o s}, B + n G)`` as lists of terms, each kept as it was built."""
    inner = controller.controller
    A, B = loop_factors(plant, inner)
    numerator = [1.0, inner.a] if isinstance(inner, FilteredController) else [1.0]
    G = observer_of(plant, controller).product.times_poly(numerator)
    return [A, -G.shift(controller.observer_delay)], [B, G]


@pytest.mark.parametrize(
    "plant, controller",
    [
        (PAPER, OutputFeedback(ReflectionController(0.1))),
        (PAPER, OutputFeedback(ReflectionController(-0.05), 0.3)),
        (PAPER, OutputFeedback(FilteredController(0.3, 0.5, 0.05))),
        (SLOW_V, OutputFeedback(ReflectionController(0.1))),
    ],
)
def test_the_stored_loop_is_the_sum_of_its_terms(plant, controller) -> None:
    A, B = loop_factors(plant, controller)
    parts_A, parts_B = _separate(plant, controller)
    s = np.r_[0.0, 1j * np.geomspace(1e-3, 400.0, 2000), 0.3 + 5.0j, -0.2 + 40.0j]
    for stored, parts in ((A, parts_A), (B, parts_B)):
        value = stored(s)
        reference = sum(P(s) for P in parts)
        # evaluation by a different sum over segments (one kernel instead of several): rounding only,
        # measured 4e-14 at |s| = 400 (8e-13 with the filter's numerator 1 + 0.3 s); a term lost or counted
        # twice would be O(0.1)
        tolerance = 1e-11 * (1.0 + np.abs(s))
        np.testing.assert_array_less(np.abs(value - reference), tolerance)
        np.testing.assert_array_less(np.abs(stored.deriv_at(s) - sum(P.deriv_at(s) for P in parts)), tolerance)


def test_each_factor_holds_one_kernel_and_their_sum_none() -> None:
    A, B = loop_factors(PAPER, OutputFeedback(ReflectionController(0.1)))
    assert len(A.distributed) == len(B.distributed) == 1  # N~ and the three pieces of G were four terms
    assert not (A + B).distributed  # A + B = 1 - (rho - K) q e^{-tau s}: the kernels cancel exactly
    # with a delay the observer assumes, G in A_o is shifted off N~'s segments: A_o keeps two terms, and G's
    # proven kernel moved onto rounded nodes adds a term on one ulp at each of its three true jumps (where the
    # stored kernel is the other side's); the fitted pieces' mismatches at the other nodes join its bounds
    A, B = loop_factors(PAPER, OutputFeedback(ReflectionController(0.1), 0.3))
    wide = [d for d in A.distributed if d.b - d.a > 1e-12]
    assert len(wide) == 2 and len(B.distributed) == 1
    assert len(A.distributed) == 5 and all(np.nextafter(d.a, np.inf) == d.b for d in A.distributed if d not in wide)


def test_the_refined_kernel_is_within_its_bound_of_the_kernels_it_replaces() -> None:
    controller = OutputFeedback(ReflectionController(0.1))
    (stored,) = loop_factors(PAPER, controller)[1].distributed
    _, parts = _separate(PAPER, controller)
    terms = [d for P in parts for d in P.distributed]
    rng = np.random.default_rng(7)
    nu = np.sort(rng.uniform(stored.a, stored.b, 4000))
    reference = np.zeros(nu.size)
    for d in terms:
        inside = (nu > d.a) & (nu < d.b)
        reference[inside] += d.kernel_at(nu[inside])
    error = np.max(np.abs(stored.kernel_at(nu) - reference))
    # the bound of the re-expansion of N~ (its own radius excluded, as N~ is the reference here)
    added = stored.radius - max(d.radius for d in terms)
    assert 0.0 < added < 1e-12
    assert error <= added, (error, added)


def test_the_observer_term_is_shared_by_every_gain() -> None:
    # U_BS2(K)'s window kernel does not depend on K: one observer term for every gain (the design reuses it)
    one = observer_of(PAPER, OutputFeedback(ReflectionController(0.1)))
    other = observer_of(PAPER, OutputFeedback(ReflectionController(0.117757776)))
    assert one is other


def test_the_collocated_factors_hold_one_kernel_each_within_its_bound_of_their_terms(monkeypatch) -> None:
    """A model collocated loop's kernels (``G`` given as a quasi-polynomial, from kernels on a grid: the filtered
    law's) summed into one in ``B_o`` on the union of their nodes (steps of 1/24 and 1/8); ``A_o``'s are left apart
    (the reflection's terms there carry the filter's denominator ``1 + b s``: another kind). The oracle is the same
    loop with its terms kept apart. (Under U_BS2(K) the loop is proven and keeps its terms: the test below.)"""
    controller = CollocatedOutputFeedback(FilteredController(0.3, 0.5, 0.05), 0.0, 0.3)
    assert loop_route(PAPER, controller) == "observer"
    B = loop_factors(PAPER, controller)[1]
    monkeypatch.setattr(output_feedback, "consolidated", lambda P: P)
    parts = loop_factors(PAPER, controller)
    assert len(B.distributed) == 1 and all(len(P.distributed) > 4 for P in parts)
    s = np.r_[0.0, 1j * np.geomspace(1e-3, 400.0, 1000), 0.3 + 5.0j, -0.2 + 40.0j]
    rng = np.random.default_rng(3)
    separate = parts[1]
    # one sum over the segments instead of several: rounding only (measured 3e-15 relative)
    np.testing.assert_allclose(B(s), separate(s), rtol=1e-12, atol=1e-13)
    (kernel,) = B.distributed
    nu = np.sort(rng.uniform(kernel.a, kernel.b, 4000))
    reference = np.zeros(nu.size)
    for d in separate.distributed:
        inside = (nu > d.a) & (nu < d.b)
        reference[inside] += d.kernel_at(nu[inside])
    # within the re-expansions' bound (the separate terms' own radii excluded: they are the reference)
    added = kernel.radius - sum(d.radius for d in separate.distributed)
    assert 0.0 < added < 1e-12
    assert np.max(np.abs(kernel.kernel_at(nu) - reference)) <= added


def test_the_proven_collocated_factors_keep_their_bounds() -> None:
    """Under U_BS2(K) the collocated loop is proven (every kernel with its ball-arithmetic bound, at most 9e-16): its
    factors keep their terms. Where their nodes' union is uniform (``B_o``'s kernels on ``[0, 2]``: ``N~`` and the
    reflection's product, steps 1/8 and 1/4) summing them into one would bound the sum by the re-expansion's
    rounding, far above their bounds (with ``G`` in pieces of uniform union ``B_o`` was summed so: 3.4e-13, and the
    proven margin's ball at ``kappa = -0.715`` was 45 times wider). The oracle of the rule is the same kernels
    without bounds (a model's): those are summed into one, with the same values."""
    controller = CollocatedOutputFeedback(ReflectionController(0.1), 0.0, 0.3)
    assert loop_route(PAPER, controller) == "exact"
    A, B = loop_factors(PAPER, controller)
    for P in (A, B):
        assert len(P.distributed) > 2 and all(0.0 < d.radius < 1e-15 for d in P.distributed)
        assert output_feedback.consolidated(P) is P
    first = QuasiPolynomial.from_parts((), [d for d in B.distributed if d.a == 0.0 and d.b == 2.0])
    assert len(first.distributed) == 2 and output_feedback.consolidated(first) is first
    unbounded = [
        DistributedDelay(d.nodes, None, d.poly, d.moment, "polynomial", coefficients=d.pieces[2])
        for d in first.distributed
    ]
    bare = QuasiPolynomial.from_parts((), unbounded)
    (summed,) = output_feedback.consolidated(bare).distributed
    assert summed.radius > 2.0 * sum(d.radius for d in first.distributed)
    s = np.r_[0.0, 1j * np.geomspace(1e-3, 400.0, 200), 0.3 + 5.0j]
    np.testing.assert_allclose(output_feedback.consolidated(bare)(s), first(s), rtol=1e-12, atol=1e-13)
