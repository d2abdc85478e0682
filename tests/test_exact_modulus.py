"""The exact L1 modulus of continuity of a linear kernel, in integers (``nrobust.bounds``).

``omega(d) = int |N(nu) - N(nu - d)| dnu`` of a linear interpolant (zero outside its nodes) is
what the proven Rouché bound marches on. Its exact value is checked against a closed form and
against a brute-force sum in Python's ``Fraction`` written here: ``|N(nu) - N(nu - d)|`` is
linear between consecutive points of the nodes and the shifted nodes, so its integral on such a
piece is the trapezoid of the two one-sided limits, split at a sign change; the one-sided limits
are read from the nodes by a plain search.
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np
import pytest

from nrobust.bounds import _dyadic, _exact_l1_modulus, delay_bound_from_kernel
from nrobust.quasipoly import DistributedDelay


def _limit(nodes: list[Fraction], values: list[Fraction], x: Fraction, side: int) -> Fraction:
    """``N(x-)`` (``side = -1``) or ``N(x+)`` (``side = +1``) of the linear interpolant, zero outside."""
    if side > 0:  # the last node at x holds the value on the right; beyond the support, zero
        k = max((i for i, v in enumerate(nodes) if v <= x), default=None)
        if k is None or k == len(nodes) - 1:
            return Fraction(0)
    else:  # the first node at x holds the value on the left
        k = min((i for i, v in enumerate(nodes) if v >= x), default=None)
        if k is None or k == 0:
            return Fraction(0)
        k -= 1
    x0, x1 = nodes[k], nodes[k + 1]
    return values[k] + (values[k + 1] - values[k]) * (x - x0) / (x1 - x0)


def _oracle(nodes_f: list[float], values_f: list[float], d_f: float) -> Fraction:
    nodes = [Fraction(x) for x in nodes_f]
    values = [Fraction(v) for v in values_f]
    d = Fraction(d_f)
    points = sorted(set(nodes) | {x + d for x in nodes})
    total = Fraction(0)
    for lo, hi in itertools.pairwise(points):
        a = _limit(nodes, values, lo, +1) - _limit(nodes, values, lo - d, +1)
        b = _limit(nodes, values, hi, -1) - _limit(nodes, values, hi - d, -1)
        if a * b >= 0:
            total += (hi - lo) * (abs(a) + abs(b)) / 2
        else:  # the line crosses zero at lo + (hi - lo) |a| / (|a| + |b|)
            total += (hi - lo) * (a * a + b * b) / (2 * (abs(a) + abs(b)))
    return total


def _modulus(nodes: list[float], values: list[float], d: float) -> Fraction:
    (x, e), (v, f) = _dyadic(nodes), _dyadic(values)
    return _exact_l1_modulus(x, v, e, f, d)


@pytest.mark.parametrize("d", [0.0, 2.0**-20, 0.375, 0.7, 1.0, 1.5])
def test_ramp_has_its_closed_form(d: float) -> None:
    """``N(nu) = nu`` on ``[0, 1]``: ``omega(d) = 2 d - d^2`` for ``d <= 1``, ``1`` beyond (two disjoint ramps)."""
    exact = Fraction(d)
    expected = 2 * exact - exact**2 if exact <= 1 else Fraction(1)
    assert _modulus([0.0, 0.25, 1.0], [0.0, 0.25, 1.0], d) == expected


@pytest.mark.parametrize("d", [0.1, 0.3, 0.3000000000000001, 0.65, 1.7, 2.5])
def test_kernel_with_jumps_matches_the_brute_force_sum(d: float) -> None:
    # jumps at 0.3 and 1.0 (repeated nodes), signs changing, a node at the shift of another (0.3 + 0.4 = 0.7)
    nodes = [0.0, 0.3, 0.3, 0.7, 1.0, 1.0, 1.7]
    values = [0.5, -1.0, 2.0, 0.0, 1.5, -0.25, 0.75]
    assert _modulus(nodes, values, d) == _oracle(nodes, values, d)


def test_random_kernel_matches_the_brute_force_sum() -> None:
    rng = np.random.default_rng(7)
    nodes = np.sort(rng.uniform(0.0, 3.0, 30)).tolist()
    values = rng.normal(size=30).tolist()
    for d in rng.uniform(0.0, 3.5, 5).tolist():
        assert _modulus(nodes, values, d) == _oracle(nodes, values, d)


def test_rouche_march_uses_the_exact_modulus() -> None:
    """The proven march on a constant kernel ``N = c`` on ``[0, 1]`` stops below ``epsilon_0 / (2 c)``
    (``omega(d) = 2 c d``), and the ``omega`` it reports is the exact modulus at ``delta_0``, rounded up."""
    c, eps0 = 0.3, 0.05
    bound = delay_bound_from_kernel(DistributedDelay([0.0, 1.0], [c, c]), eps0, rigorous=True)
    assert bound.rigorous and bound.delta_0 < eps0 / (2 * c)
    exact = 2 * Fraction(c) * Fraction(bound.delta_0)
    assert Fraction(bound.omega_at_delta_0) >= exact
    np.testing.assert_allclose(bound.omega_at_delta_0, float(exact), rtol=2**-52)  # rounded up by one ulp at most
