"""The algebra of distributed terms carries the rounding of the kernels it stores (radius, variation_radius).

Oracle: the exact result of each operation on the operands' stored pieces, in rational arithmetic
(``Fraction``), evaluated on a grid of each segment; the stored result must lie within the error bounds the
operation added, in sup norm and in total variation (the variation on a grid is at most the total variation).
Before the bounds carried the rounding, every inexact case below added nothing and failed.
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np
import pytest

from nrobust.distributed_delay import DistributedDelay

GRID = 40  # points per segment: the variation on the grid is a lower bound of the true variation


def _kernel(d: DistributedDelay, nu: Fraction, scale: complex = 1) -> tuple[Fraction, Fraction]:
    """``scale N(nu)`` of the stored kernel of ``d`` (its segment by the right-continuous rule), exactly."""
    start, h, poly = d.pieces
    i = int(np.clip(np.searchsorted(start, float(nu), side="right") - 1, 0, start.size - 1))
    while i > 0 and Fraction(float(start[i])) > nu:
        i -= 1
    while i + 1 < start.size and Fraction(float(start[i + 1])) <= nu:
        i += 1
    if nu < Fraction(d.a) or nu > Fraction(d.b):
        return Fraction(0), Fraction(0)
    t = (nu - Fraction(float(start[i]))) / Fraction(float(h[i]))
    re = sum((Fraction(float(np.real(c))) * t**k for k, c in enumerate(poly[i])), Fraction(0))
    im = sum((Fraction(float(np.imag(c))) * t**k for k, c in enumerate(poly[i])), Fraction(0))
    sr, si = Fraction(float(np.real(scale))), Fraction(float(np.imag(scale)))
    return sr * re - si * im, sr * im + si * re


def _points(nodes: np.ndarray, offset: Fraction = Fraction(0)) -> list[Fraction]:
    """A grid of each segment, its ends and the rationals just beside them."""
    out: list[Fraction] = []
    x = [Fraction(float(v)) + offset for v in np.unique(nodes)]
    for lo, hi in itertools.pairwise(x):
        out += [lo + (hi - lo) * Fraction(j, GRID) for j in range(GRID)]
    out.append(x[-1])
    tiny = Fraction(1, 2**80)
    return sorted(set(out + [v + s * tiny for v in x for s in (-1, 1)]))


def _gaps(exact, stored, points: list[Fraction]) -> tuple[float, float]:
    """sup |exact - stored| and the variation of ``exact - stored`` on ``points`` (moduli by |re| + |im|)."""
    diffs = []
    for nu in points:
        (er, ei), (sr, si) = exact(nu), stored(nu)
        diffs.append((er - sr, ei - si))
    sup = max(abs(r) + abs(i) for r, i in diffs)
    tv = sum(abs(b[0] - a[0]) + abs(b[1] - a[1]) for a, b in itertools.pairwise(diffs))
    return float(sup), float(tv)


def _term(seed: int, complex_: bool = False, pieces: int = 4, degree: int = 5, radius: float = 1e-12):
    rng = np.random.default_rng(seed)
    nodes = np.cumsum(np.r_[0.3, rng.uniform(0.1, 0.7, pieces)])
    coefs = rng.normal(size=(pieces, degree + 1)) * 10.0 ** rng.integers(-3, 3, size=(pieces, degree + 1))
    if complex_:
        coefs = coefs + 1j * rng.normal(size=coefs.shape)
    return DistributedDelay(
        nodes, None, interpolation="polynomial", coefficients=coefs, radius=radius, variation_radius=3 * radius
    )


def _dyadic_term() -> DistributedDelay:
    """Two pieces on dyadic nodes with dyadic coefficients: sums, doublings and unit shifts of it are exact."""
    return DistributedDelay(
        [0.0, 0.5, 1.0],
        None,
        interpolation="polynomial",
        coefficients=[[1.0, 0.5, 0.25], [0.75, 2.0, -1.0]],
        radius=1e-12,
        variation_radius=1e-12,
    )


def _added(new: DistributedDelay, old_radius: float, old_variation: float) -> tuple[Fraction, Fraction]:
    return Fraction(new.radius) - Fraction(old_radius), Fraction(new.variation_radius) - Fraction(old_variation)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("c", [0.1, -1.0 / 3.0, 0.3 + 0.7j, 1e-5])
def test_times_carries_the_rounding(seed: int, c: complex) -> None:
    d = _term(seed, complex_=seed % 2 == 1)
    out = d.times(c)
    sup, tv = _gaps(lambda nu: _kernel(d, nu, c), lambda nu: _kernel(out, nu), _points(d.nodes))
    assert sup > 0  # the products round
    # |c| radius is what the bound held before; the rounding comes on top (rounded up by the module's _up)
    r_old, v_old = abs(c) * d.radius, abs(c) * d.variation_radius
    dr, dv = _added(out, r_old * (1 + 2**-50), v_old * (1 + 2**-50))
    assert Fraction(sup) <= dr
    assert Fraction(tv) <= dv
    assert out.radius < r_old + 1e-13 * float(np.max(np.sum(np.abs(d.pieces[2]), axis=1)))  # not grossly large


@pytest.mark.parametrize("c", [2.0, -1.0, 0.5, 1j, -1j, 0.25j])
def test_exact_scalings_add_nothing(c: complex) -> None:
    d = _term(3, complex_=True)
    out = d.times(c)
    assert out.radius == (d.radius if abs(c) == 1 else float(np.nextafter(np.nextafter(d.radius * abs(c), 1), 1)))
    assert out.variation_radius == (
        d.variation_radius if abs(c) == 1 else float(np.nextafter(np.nextafter(d.variation_radius * abs(c), 1), 1))
    )


@pytest.mark.parametrize("seed", range(4))
def test_plus_carries_the_rounding(seed: int) -> None:
    d = _term(seed, complex_=seed == 3)
    e = d.replace(
        coefficients=np.random.default_rng(seed + 10).normal(size=d.pieces[2].shape) / 3.0,
        radius=0.0,
        variation_radius=0.0,
    )
    out = d.plus(e)

    def exact(nu):
        (a, b), (x, y) = _kernel(d, nu), _kernel(e, nu)
        return a + x, b + y

    sup, tv = _gaps(exact, lambda nu: _kernel(out, nu), _points(d.nodes))
    assert sup > 0
    dr, dv = _added(out, d.radius * (1 + 2**-50), d.variation_radius * (1 + 2**-50))
    assert Fraction(sup) <= dr
    assert Fraction(tv) <= dv


def test_exact_sums_add_nothing() -> None:
    d = _dyadic_term()
    out = d.plus(d.times(2.0))
    assert np.array_equal(out.pieces[2], 3.0 * d.pieces[2])
    # the bounds are exactly those of the summands added (each rounded up), no rounding of the kernel
    twice = d.times(2.0)
    assert out.radius == float(np.nextafter(np.nextafter(d.radius + twice.radius, 1), 1))
    assert out.variation_radius == float(np.nextafter(np.nextafter(d.variation_radius + twice.variation_radius, 1), 1))


def test_linear_values_times() -> None:
    nodes = np.linspace(0.0, 1.0, 7)
    d = DistributedDelay(nodes, np.sin(3 * nodes), radius=1e-10, variation_radius=1e-10)
    out = d.times(0.1)
    sup, tv = _gaps(lambda nu: _kernel(d, nu, 0.1), lambda nu: _kernel(out, nu), _points(nodes))
    assert sup > 0
    dr, dv = _added(out, 0.1 * d.radius * (1 + 2**-50), 0.1 * d.variation_radius * (1 + 2**-50))
    assert Fraction(sup) <= dr and Fraction(tv) <= dv


@pytest.mark.parametrize("seed", range(4))
def test_restricted_carries_the_rounding(seed: int) -> None:
    d = _term(seed, complex_=seed == 1)
    lo = float(0.37 * d.a + 0.63 * float(d.nodes[1]))
    out = d.restricted(lo)
    points = [nu for nu in _points(out.nodes) if Fraction(lo) <= nu <= Fraction(d.b)]
    sup, tv = _gaps(lambda nu: _kernel(d, nu), lambda nu: _kernel(out, nu), points)
    assert sup > 0
    dr, dv = _added(out, d.radius, d.variation_radius)
    assert Fraction(sup) <= dr and Fraction(tv) <= dv
    assert d.restricted(float(d.nodes[1])).radius == d.radius  # a cut at a node is exact


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("delta", [0.1, 1.0 / 3.0, 2.7])
def test_shift_carries_the_rounding(seed: int, delta: float) -> None:
    d = _term(seed, complex_=seed == 2)
    moved = d.shift(delta)
    offset = Fraction(delta)

    def exact(nu):
        return _kernel(d, nu - offset)

    def stored(nu):
        parts = [_kernel(m, nu) for m in moved]
        return sum((p[0] for p in parts), Fraction(0)), sum((p[1] for p in parts), Fraction(0))

    points = _points(d.nodes, offset) + _points(moved[0].nodes)
    points = sorted(set(points))
    # near each node: the true end and the stored one, both sides
    for nu in points:
        (er, ei), (sr, si) = exact(nu), stored(nu)
        gap2 = (er - sr) ** 2 + (ei - si) ** 2  # the modulus, squared
        covering = [m for m in moved if Fraction(m.a) <= nu <= Fraction(m.b)]
        allowed = sum((Fraction(m.radius) for m in covering), Fraction(0)) - (Fraction(d.radius) if covering else 0)
        assert gap2 == 0 or (allowed > 0 and gap2 <= allowed**2), (float(nu), float(gap2) ** 0.5, float(allowed))


def test_exact_shift_adds_nothing() -> None:
    d = _dyadic_term()
    (out,) = d.shift(1.0)
    assert out.radius == d.radius and out.variation_radius == d.variation_radius
    assert np.array_equal(out.nodes, d.nodes + 1.0) and np.array_equal(out.pieces[2], d.pieces[2])


def test_unbounded_terms_unchanged() -> None:
    """A term without error bounds stores the same numbers as before: no bound is invented."""
    d = _term(0, radius=0.0)
    assert d.times(0.1).radius == 0.0
    assert d.plus(d.times(0.1)).radius == 0.0
    assert d.restricted(0.5 * (d.a + float(d.nodes[1]))).radius == 0.0
    assert [m.radius for m in d.shift(0.1)] == [0.0]


@pytest.mark.parametrize("delta", [0.1, 2.7])
def test_shift_of_a_moment_carries_its_weights_rounding(delta: float) -> None:
    """``int nu^2 N(nu) e^{-nu s}`` times ``e^{-delta s}``: the weights ``C(2, j) (-delta)^(2 - j)`` of
    ``(mu - delta)^2`` round; the terms' sum is within their radii of the exact moved kernel."""
    d = _term(1).replace(moment=2)
    moved = d.shift(delta)
    offset = Fraction(delta)
    for nu in _points(d.nodes, offset):
        base = _kernel(d, nu - offset)
        exact = ((nu - offset) ** 2 * base[0], (nu - offset) ** 2 * base[1])
        parts = [(nu**m.moment * _kernel(m, nu)[0], nu**m.moment * _kernel(m, nu)[1]) for m in moved]
        stored = (sum((p[0] for p in parts), Fraction(0)), sum((p[1] for p in parts), Fraction(0)))
        gap2 = (exact[0] - stored[0]) ** 2 + (exact[1] - stored[1]) ** 2
        covering = [m for m in moved if Fraction(m.a) <= nu <= Fraction(m.b)]
        old = (nu - offset) ** 2 * Fraction(d.radius) if Fraction(d.a) <= nu - offset <= Fraction(d.b) else 0
        allowed = sum((nu**m.moment * Fraction(m.radius) for m in covering), Fraction(0)) - old
        assert gap2 == 0 or (allowed > 0 and gap2 <= allowed**2), (float(nu), float(gap2) ** 0.5, float(allowed))


def test_a_constant_factor_of_the_constructor_carries_its_rounding() -> None:
    """``poly=[c]`` moves ``c`` into the pieces: their rounding joins the bounds given."""
    d = _term(0)
    scaled = DistributedDelay(
        d.nodes,
        None,
        poly=[0.1],
        interpolation="polynomial",
        coefficients=d.pieces[2],
        radius=d.radius,
        variation_radius=d.variation_radius,
    )
    sup, tv = _gaps(lambda nu: _kernel(d, nu, 0.1), lambda nu: _kernel(scaled, nu), _points(d.nodes))
    assert sup > 0
    dr, dv = _added(scaled, 0.1 * d.radius * (1 + 2**-50), 0.1 * d.variation_radius * (1 + 2**-50))
    assert Fraction(sup) <= dr and Fraction(tv) <= dv


@pytest.mark.parametrize("delta", [-0.0128331688, -0.25, 0.1])
def test_moved_either_way_carries_the_rounding(delta: float) -> None:
    """``moved(delta)``: the stored kernels' sum within the terms' radii of ``N(nu - delta)``, exactly."""
    d = _term(2)
    moved = d.moved(delta)
    offset = Fraction(delta)
    for nu in sorted(set(_points(d.nodes, offset) + _points(moved[0].nodes))):
        (er, ei) = _kernel(d, nu - offset)
        parts = [_kernel(m, nu) for m in moved]
        sr, si = sum((p[0] for p in parts), Fraction(0)), sum((p[1] for p in parts), Fraction(0))
        gap2 = (er - sr) ** 2 + (ei - si) ** 2
        covering = [m for m in moved if Fraction(m.a) <= nu <= Fraction(m.b)]
        allowed = sum((Fraction(m.radius) for m in covering), Fraction(0)) - (Fraction(d.radius) if covering else 0)
        assert gap2 == 0 or (allowed > 0 and gap2 <= allowed**2), (float(nu), float(gap2) ** 0.5, float(allowed))


def test_moved_checks_its_argument() -> None:
    d = _term(0)
    with pytest.raises(ValueError, match="delta"):
        d.moved(-1.0)  # a = 0.3: the support would start below 0
    with pytest.raises(ValueError, match="delta"):
        d.moved(float("nan"))
    assert d.moved(0.0) == (d,)


@pytest.mark.parametrize("delta", [0.1, 1.0 / 3.0])
def test_a_fitted_kernels_small_jumps_fold_into_its_bounds(delta: float) -> None:
    """Pieces that meet to ``1e-15`` (a fitted kernel's mismatch, above its ``radius`` of ``1e-17`` and below
    ``2^-40`` of its size) moved onto rounded nodes: one term, its radius raised to hold the other piece's values on
    the ulp between each rounded node and the true one (exact rational oracle at the nodes and beside them)."""
    first, second = [1.0, 0.5, -0.25], [1.25 + 1e-15, -0.2, 0.1]
    d = DistributedDelay(
        [0.3, 0.7, 1.1, 1.5],
        None,
        interpolation="polynomial",
        coefficients=[first, second, [sum(second) + 1e-15, 0.3, 0.0]],
        radius=1e-17,
        variation_radius=1e-17,
    )
    main, *ends = d.shift(delta)
    assert main.radius >= 1e-15  # the inner nodes' mismatches folded in
    # a term on an ulp only where the kernel truly jumps: at the ends of its support (to 0 outside)
    assert len(ends) <= 2 and all(min(abs(e.a - main.a), abs(e.b - main.b)) <= 1e-15 for e in ends)
    offset = Fraction(delta)
    inner = [Fraction(float(v)) + offset for v in d.nodes[1:-1]] + [Fraction(float(v)) for v in main.nodes[1:-1]]
    points = [
        p
        for p in sorted(set(_points(d.nodes, offset) + _points(main.nodes)))
        if min(abs(p - q) for q in inner) < Fraction(1, 10)
    ]
    sup, _ = _gaps(lambda nu: _kernel(d, nu - offset), lambda nu: _kernel(main, nu), points)
    assert sup <= main.radius - d.radius
