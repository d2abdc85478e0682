"""Three exact shortcuts of the root search, each against an oracle that shares no code with it.

* ``QuasiPolynomial.from_coefficient_array`` (one validation for a whole matrix) against the
  entry-by-entry constructor;
* the exact expansion of ``det M`` in scaled integers (``QuasiPolynomialMatrix.exact_expansion``)
  against a Leibniz sum over permutations in Python's ``Fraction`` written here, rounded once;
* counts of a real ``F`` that compute only the upper half of a contour (``F(conj s) = conj F(s)``)
  against roots placed by construction: ``prod (s - r_i) (s - conj r_i)`` times ``1 + 0.2 e^{-s}``
  (whose roots are ``-ln 5 + (2k + 1) pi i``), so that the count of a box is the number of known
  roots inside it.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nrobust import QuasiPolynomial, count_roots
from nrobust.errors import ParameterError
from nrobust.lti.statespace import StateSpaceTDS
from nrobust.qpmatrix import QuasiPolynomialMatrix
from nrobust.roots._common import Budget
from nrobust.roots.winding import Counter

_VALUES = st.sampled_from([0.0, 0.0, 1.0, -2.5, 0.1, 1 / 3, -0.7, 1e-3, 3.0])
_DELAYS = st.sampled_from([0.0, 0.5, 1.0, 0.1, 1 / 3, 2.0])


@settings(max_examples=60, deadline=None)
@given(
    st.integers(1, 3),
    st.integers(1, 3),
    st.integers(1, 3),
    st.data(),
)
def test_coefficient_array_entries_equal_the_constructor(n: int, K: int, P: int, data: st.DataObject) -> None:
    """Every entry equals ``QuasiPolynomial(coefs[i, j], delays)`` (equal delays summed, zeros dropped)."""
    coefs = np.array(data.draw(st.lists(_VALUES, min_size=n * n * K * P, max_size=n * n * K * P))).reshape(n, n, K, P)
    delays = data.draw(st.lists(_DELAYS, min_size=K, max_size=K))
    rows = QuasiPolynomial.from_coefficient_array(coefs, delays)
    for i, j in itertools.product(range(n), range(n)):
        expected = QuasiPolynomial(list(coefs[i, j]), delays)
        assert rows[i][j] == expected
        assert [t for _, t in rows[i][j].point_terms] == [t for _, t in expected.point_terms]


@pytest.mark.parametrize(
    ("coefs", "delays", "name"),
    [
        (np.ones((2, 2, 2, 1)), [0.0], "coefs"),  # two coefficient rows, one delay
        (np.ones((2, 2)), [0.0, 1.0], "coefs"),  # no leading axis of entries
        (np.full((1, 1, 1), np.nan), [0.0], "coefs"),
        (np.ones((1, 1, 1)), [-1.0], "delays"),
        (np.ones((1, 1, 1)), [np.inf], "delays"),
    ],
)
def test_coefficient_array_refuses_bad_input(coefs: np.ndarray, delays: list[float], name: str) -> None:
    with pytest.raises(ParameterError, match=name):
        QuasiPolynomial.from_coefficient_array(coefs, delays)


def _leibniz_fraction(entries: Sequence[Sequence[QuasiPolynomial]]) -> dict[tuple[Fraction, int], Fraction]:
    """``det`` of the entries (their doubles as exact rationals) as ``(delay, power) -> coefficient``."""
    n = len(entries)
    entry = [
        [{(Fraction(t), k): Fraction(c) for p, t in q.point_terms for k, c in enumerate(p.tolist()) if c} for q in row]
        for row in entries
    ]
    total: dict[tuple[Fraction, int], Fraction] = {}
    for perm in itertools.permutations(range(n)):
        sign = (-1) ** sum(perm[i] > perm[j] for i in range(n) for j in range(i + 1, n))
        prod: dict[tuple[Fraction, int], Fraction] = {(Fraction(0), 0): Fraction(sign)}
        for i in range(n):
            nxt: dict[tuple[Fraction, int], Fraction] = {}
            for (t, k), c in prod.items():
                for (u, m), d in entry[i][perm[i]].items():
                    nxt[(t + u, k + m)] = nxt.get((t + u, k + m), Fraction(0)) + c * d
            prod = nxt
        for key, c in prod.items():
            total[key] = total.get(key, Fraction(0)) + c
    return {key: c for key, c in total.items() if c}


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 4), st.data())
def test_exact_expansion_is_the_rational_leibniz_sum_rounded_once(n: int, data: st.DataObject) -> None:
    """Each coefficient of the expansion is the exact Leibniz coefficient rounded to the nearest double
    (monomials whose delays round to the same double summed first), descriptor ``E`` included."""
    mats = [np.array(data.draw(st.lists(_VALUES, min_size=n * n, max_size=n * n))).reshape(n, n) for _ in range(3)]
    E = np.diag(data.draw(st.lists(st.sampled_from([0.0, 1.0, 0.5, 3.0]), min_size=n, max_size=n)))
    delays = [0.0, *data.draw(st.lists(_DELAYS.filter(bool), min_size=2, max_size=2))]
    sys = StateSpaceTDS(mats, delays, E=E)
    entries = sys.characteristic_matrix().entries
    Q = QuasiPolynomialMatrix(entries).exact_expansion()
    assert Q is not None
    exact = _leibniz_fraction(entries)
    grouped: dict[tuple[float, int], Fraction] = {}
    for (t, k), c in exact.items():
        grouped[(float(t), k)] = grouped.get((float(t), k), Fraction(0)) + c
    got = {(t, k): c for p, t in Q.poly.point_terms for k, c in enumerate(p.tolist()) if c != 0}
    assert got == {key: float(c) for key, c in grouped.items() if float(c) != 0}


def _placed(roots: list[complex]) -> tuple[QuasiPolynomial, np.ndarray]:
    """``p(s) (1 + 0.2 e^{-s})`` with ``p = prod (s - r) (s - conj r)`` (real), and all its roots with
    ``|Im s| < 20``."""
    poly = np.poly(np.concatenate([roots, np.conj(roots)]))[::-1].real
    chain = -np.log(5.0) + 1j * np.pi * (2 * np.arange(-4, 4) + 1)
    return QuasiPolynomial([list(poly), list(0.2 * poly)], [0.0, 1.0]), np.concatenate([roots, np.conj(roots), chain])


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(-8, 8), st.integers(1, 8)).map(lambda xy: complex(xy[0] + 0.25, xy[1] + 0.25) / 4),
        min_size=1,
        max_size=4,
        unique=True,
    ),
    st.tuples(st.integers(-6, 0), st.integers(1, 6), st.integers(-6, 5), st.integers(1, 6)),
)
def test_mirrored_counts_are_the_roots_placed_in_the_box(roots: list[complex], box: tuple[int, int, int, int]) -> None:
    """Boxes on both sides of the real axis, across it and symmetric about it; edges on a grid of
    quarters, roots off it by 1/16: each count is the number of placed roots inside, and the
    symmetric box computes only the upper half of its contour."""
    x0, w, y0, h = box
    region = (x0 / 2, (x0 + w) / 2, y0 / 2, (y0 + h) / 2)
    F, every = _placed(roots)
    inside = int(
        np.sum(
            (every.real > region[0]) & (every.real < region[1]) & (every.imag > region[2]) & (every.imag < region[3])
        )
    )
    assert int(count_roots(F, region)) == inside
    sym = (region[0], region[1], -abs(region[3]), abs(region[3]))
    counter = Counter(F, Budget(10**6))
    counts, blocked = counter.count([sym])
    assert not blocked.any()
    assert int(counts[0]) == int(np.sum((every.real > sym[0]) & (every.real < sym[1]) & (np.abs(every.imag) < sym[3])))
    assert all(min(p.imag, q.imag) >= 0.0 for p, q in counter.cache)  # upper half only


def test_a_complex_function_is_counted_on_the_whole_contour() -> None:
    """``F(s) = s - (0.3 + 0.5i)`` is not real: its count must not use the mirror (which would give the
    count of the conjugate root's box)."""
    F = QuasiPolynomial([[-(0.3 + 0.5j), 1.0]], [0.0])
    assert int(count_roots(F, (0.0, 1.0, 0.2, 1.0))) == 1
    assert int(count_roots(F, (0.0, 1.0, -1.0, -0.2))) == 0


def test_prefetched_boxes_are_computed_with_the_next_count() -> None:
    """``Counter.prefetch``: the boxes' edges are computed in the batch of the next count, which
    returns the counts of its own boxes only; counting them next costs no evaluation."""
    F, every = _placed([complex(0.3, 1.2), complex(-0.4, 2.3)])
    region = (-1.0, 1.0, -3.0, 3.0)
    boxes = [(0.2, 0.4, 1.1, 1.3), (-0.5, -0.3, 2.2, 2.4), (-0.5, -0.3, -2.4, -2.2)]
    budget = Budget(10**6)
    counter = Counter(F, budget)
    counter.prefetch = list(boxes)
    counts, _ = counter.count([region])
    inside = (every.real > -1) & (every.real < 1) & (np.abs(every.imag) < 3)
    assert counts.tolist() == [int(np.sum(inside))] and counter.prefetch == []
    used = budget.used
    counts, blocked = counter.count(boxes)
    assert counts.tolist() == [1, 1, 1] and not blocked.any()
    assert budget.used == used  # every edge was computed with the region's


def test_a_box_thin_about_the_real_axis_gets_a_row_of_seeds() -> None:
    """``[-0.895, 2.96] x [-4.2e-12, 4.2e-12]``: the grid of about ``n`` square cells had 4.4 million
    points (sorted, then refused by the work bound); now a row of at most ``n``, and the real root
    is found, at mpmath's value (40 digits) of ``0.0722 + 0.498 s + 0.0205 s^2 + s^3 - 0.0693 e^{-1.77 s}``."""
    import mpmath

    from nrobust import find_roots
    from nrobust.roots.search import Finder

    F = QuasiPolynomial([[0.0722, 0.498, 0.0205, 1.0], [-0.0693]], [0.0, 1.77])
    box = (-0.895, 2.96, -4.2e-12, 4.2e-12)
    assert Finder(F, box, 1e-6, Budget(10**6)).grid_seeds(box, 20).size <= 20
    found = find_roots(F, box, max_evals=100_000)
    with mpmath.workdps(40):
        f = lambda s: (  # noqa: E731
            mpmath.mpf(0.0722)
            + mpmath.mpf(0.498) * s
            + mpmath.mpf(0.0205) * s**2
            + s**3
            - mpmath.mpf(0.0693) * mpmath.exp(-mpmath.mpf(1.77) * s)
        )
        root = float(mpmath.findroot(f, -0.0047))
    assert found.count == 1
    np.testing.assert_allclose(found.roots.real, [root], rtol=1e-10)


def test_a_determinant_beyond_the_doubles_is_a_parameter_error() -> None:
    """Entries ``1e300 + s + 0.5 e^{-s}``: the exact expansion's coefficients round beyond the
    doubles; the point determinant falls back to the floating-point expansion and its check
    (a ParameterError naming the coefficients), not a bare OverflowError."""

    def entry(c: float) -> QuasiPolynomial:
        return QuasiPolynomial([[c, 1.0], [0.5]], [0.0, 1.0])

    M = QuasiPolynomialMatrix([[entry(1e300), entry(2.0)], [entry(3.0), entry(1e300)]])
    assert M.exact_expansion() is None
    with pytest.raises(ParameterError, match="coefs"):
        M.point_determinant()
