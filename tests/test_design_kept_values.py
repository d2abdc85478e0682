"""Values kept or summed otherwise behind the one-parameter designs: the same numbers as computed afresh.

A design of the collocated observer's reflection asks for the same nominal loops, far-field bounds, derivatives
and kernel solutions many times. Each is now built once (kept per exact input) or summed in one pass; the check
of each: what is kept equals a cold computation bit for bit (the oracle: the former code, or another route,
written here), and a different input (another parameter, another object equal in value, another plant) is not
answered from what was kept.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from nrobust import Hyperbolic2x2, QuasiPolynomial, ReflectionController
from nrobust.bounds import TailBound, principal_gap
from nrobust.design import gain
from nrobust.distributed_delay import DistributedDelay
from nrobust.hyperbolic.analyses.observer_design import collocated_observer_loop
from nrobust.hyperbolic.kernels import constant
from nrobust.hyperbolic.kernels.constant import solve_kernels
from nrobust.hyperbolic.loops.controllers import CollocatedOutputFeedback
from nrobust.quasipoly import _merge_distributed
from nrobust.roots import abscissa

PAPER = Hyperbolic2x2(1, 1, 1, 1, 1, 0.85)


@pytest.fixture(scope="module")
def loop():
    """The collocated observer's loop affine in its reflection (one kernel of 96 polynomial pieces per factor)."""
    return collocated_observer_loop(PAPER, CollocatedOutputFeedback(ReflectionController(0.1), 0.0))


def _same_term(a: DistributedDelay, b: DistributedDelay) -> bool:
    return (
        a.moment == b.moment
        and a.interpolation == b.interpolation
        and np.array_equal(a.nodes, b.nodes)
        and np.array_equal(a.poly, b.poly)
        and np.array_equal(a.values, b.values)
        and all(np.array_equal(u, v) for u, v in zip(a.pieces, b.pieces, strict=True))
        and a.radius == b.radius
        and a.variation_radius == b.variation_radius
    )


def test_variation_bound_adds_the_jumps_in_order(loop):
    """The jumps' terms ``|[N]| e^{-nu x}`` added one after another, as the sequential sum written here, bit for
    bit: on the loop's kernels (jumps of rounding size between their pieces), splines with one and 59 jumps, scalar
    and array ``x`` (with ``x`` where the exponentials overflow)."""

    def sequential(d: DistributedDelay, x):
        x = np.asarray(x, dtype=float)
        start, h, poly_t = d.pieces
        slope = np.sum(np.abs(poly_t[:, 1:]) * np.arange(1, poly_t.shape[1]), axis=1) / h
        out = np.abs(d.values[0]) * np.exp(-d.a * x) + np.abs(d.values[-1]) * np.exp(-d.b * x)
        for where, size in d._jumps():
            out = out + size * np.exp(-where * x)
        xe = x[..., None]
        seg = np.where(
            np.abs(xe * h) < 1e-8,
            h * np.exp(-start * xe),
            np.exp(-start * xe) * -np.expm1(-h * xe) / np.where(xe == 0, 1.0, xe),
        )
        return out + np.sum(slope * seg, axis=-1) + d._radius_variation(x)

    rng = np.random.default_rng(5)
    # a kernel with a jump at each of 59 interior nodes (a node given twice), as a fitted kernel of many pieces has
    many = np.repeat(np.linspace(0.0, 3.0, 61), 2)[1:-1]
    terms = [
        loop.B0.distributed[0],
        loop.A1.distributed[0],
        DistributedDelay([0.0, 1.0, 1.0, 2.5], [1.0, 2.0, -1.0, 0.5]),
        DistributedDelay(many, rng.normal(0.0, 1.0, many.size)),
    ]
    assert len(terms[0]._jumps()) > 5 and len(terms[-1]._jumps()) > 50
    xs = [0.0, -0.0, 1e-9, -0.14, 3.0, -400.0, *rng.normal(0.0, 2.0, 50)]
    with np.errstate(over="ignore", invalid="ignore"):
        for d in terms:
            for x in xs:
                assert np.array_equal(d.variation_bound(x), sequential(d, x), equal_nan=True)
            grid = rng.normal(0.0, 2.0, (3, 4))
            assert np.array_equal(d.variation_bound(grid), sequential(d, grid))


def test_merge_in_one_pass_is_the_pairwise_scan():
    """Terms merged by a key equal exactly when ``mergeable`` holds: the same sums, in the same order, as the scan
    of every kept term written here, on terms whose nodes differ by the sign of a zero only, whose polynomials are
    real or complex with equal values, and which cancel."""

    def pairwise(terms):
        merged: list[DistributedDelay] = []
        for d in terms:
            for i, m in enumerate(merged):
                if m.mergeable(d):
                    merged[i] = m.plus(d)
                    break
            else:
                merged.append(d)
        return tuple(d for d in merged if not d.is_zero)

    rng = np.random.default_rng(3)
    nodes = [np.array([0.0, 1.0, 2.0]), np.array([-0.0, 1.0, 2.0]), np.array([0.0, 0.5, 2.0]), np.array([1.0, 2.0])]
    polys = [np.array([1.0]), np.array([1.0 + 0.0j]), np.array([1.0, 2.0]), np.array([0.5])]
    merges = 0
    for _ in range(200):
        terms: list[DistributedDelay] = []
        for _ in range(int(rng.integers(1, 12))):
            if terms and rng.random() < 0.2:
                terms.append(terms[int(rng.integers(len(terms)))].times(-1.0))
                continue
            at = nodes[int(rng.integers(len(nodes)))]
            terms.append(
                DistributedDelay(
                    at, rng.normal(size=at.size), poly=polys[int(rng.integers(4))], moment=int(rng.integers(2))
                )
            )
        expected, got = pairwise(terms), _merge_distributed(terms)
        merges += len(terms) - len(expected)
        assert len(got) == len(expected)
        assert all(_same_term(a, b) for a, b in zip(got, expected, strict=True))
    assert merges > 100  # the cases merge (and cancel) often


def test_nominal_loop_kept_per_parameter(loop):
    """``F(.; 0, p)`` built once per ``p``: the kept loop is the one built afresh (its terms bit for bit), another
    ``p`` and ``-0.0`` against ``0.0`` are built anew."""
    family = gain._Family(loop)
    p = -0.4290109890109890
    F = family.nominal(p)
    assert family.nominal(p) is F
    cold = gain._merged(family.A(p) + family.B(p))
    assert len(F.distributed) == len(cold.distributed)
    assert all(_same_term(a, b) for a, b in zip(F.distributed, cold.distributed, strict=True))
    assert all(np.array_equal(a, b) and s == t for (a, s), (b, t) in zip(F.point_terms, cold.point_terms, strict=True))
    assert family.nominal(np.nextafter(p, 0.0)) is not F
    assert family.nominal(-0.0) is not family.nominal(0.0)


def test_far_field_bounds_kept_per_function(loop):
    """The principal gap and tail bound at a real part, kept for the function: equal to a cold computation; not
    given to another function equal in value, nor at another real part."""
    F = gain._Family(loop).nominal(-0.6)
    n, x = 0, -0.05
    g, tail = abscissa._gap_and_tail(F, n, x)
    assert abscissa._gap_and_tail(F, n, x)[1] is tail
    cold_gap = principal_gap({"F": (F, 0)}, n, x)
    cold_tail = TailBound(F, n, x, cold_gap.t0)
    assert g == cold_gap and cold_gap.gap > 0.0
    radii = np.geomspace(1.0, 1e6, 25)
    assert np.array_equal(tail(radii), cold_tail(radii))
    twin = QuasiPolynomial.from_parts(F.point_terms, F.distributed, F.radii_of())
    assert twin == F and abscissa._gap_and_tail(twin, n, x)[1] is not tail
    assert abscissa._gap_and_tail(F, n, np.nextafter(x, 0.0))[1] is not tail
    for R in (2.0, 50.0, 1e4):
        assert abscissa._far_field_holds(F, n, x, R) == bool(cold_tail(R) < cold_gap.gap)


def test_derivative_built_once(loop):
    """``F.derivative()`` is built once per function; its values are those of ``F.deriv_at`` (another route: the
    terms' own derivatives), and another function gets its own."""
    F = gain._Family(loop).nominal(-0.2)
    dF = F.derivative()
    assert F.derivative() is dF
    s = np.array([0.1 + 1.0j, -0.3 + 20.0j, 0.5 + 97.0j, 2.0 - 3.0j])
    # measured: equal to the last bit (the same moment integrals); a few ulps of the terms' magnitude allowed
    assert np.all(np.abs(dF(s) - F.deriv_at(s)) <= 8 * np.finfo(float).eps * F.magnitude(s) * (1 + np.abs(s)))
    assert gain._Family(loop).nominal(-0.2).derivative() is not dF


def test_moved_kernel_is_its_own_unit_multiple(loop):
    """A kernel moved by a delay keeps its terms (moment 0: the weight 1): the same terms as scaled by 1.0 (the
    former route: a copy, with a zero rounding), bound for bound."""
    d = loop.B0.distributed[0]
    assert d.radius > 0.0 and d.moment == 0
    moved = d.moved(0.1948)
    shifted = d.shift(0.1948)
    assert len(shifted) == len(moved)
    for m, s in zip(moved, shifted, strict=True):
        assert s is m or _same_term(s, m)
        assert _same_term(s, m.times(1.0, moment=0))
        assert m._times_exact(Fraction(1), 0) is m


def test_kernels_shared_by_plants_differing_in_rho_only():
    """Eqs. (24)-(29) do not hold ``rho``: plants that differ only in it share one kept solution, equal to the cold
    solve of each; a plant with another ``q`` is solved anew."""
    plant = Hyperbolic2x2(1.0, 1.5, 1.0, 0.7, 0.9, 0.4)
    others = (Hyperbolic2x2(1.0, 1.5, 1.0, 0.7, 0.9, 0.0), Hyperbolic2x2(1.0, 1.5, 1.0, 0.7, 0.9, -2.0))
    cold = {}
    for system in (plant, *others):
        constant._kept_grid.cache_clear()
        cold[system] = solve_kernels(system, 101)
    constant._kept_grid.cache_clear()
    solve_kernels(plant, 101)
    misses = constant._kept_grid.cache_info().misses
    for system in others:
        got = solve_kernels(system, 101)
        assert got.system is system
        assert np.array_equal(got.K, cold[system].K) and np.array_equal(got.L, cold[system].L)
    assert constant._kept_grid.cache_info().misses == misses  # read, not solved
    solve_kernels(Hyperbolic2x2(1.0, 1.5, 1.0, 0.7, 0.8, 0.4), 101)
    assert constant._kept_grid.cache_info().misses > misses
