"""The kernels integrated by parts twice, and the crossing bound of the collocated loop built on it.

``DistributedDelay.second_order_variation`` bounds ``|int N e^{-nu s}|`` by ``V_1 / |s| + V_2 / |s|^2``: the
oracles are the integrals in closed form (a constant kernel, where the bound is attained at ``w = pi``; a
piecewise-linear kernel with a jump, integrated exactly in mpmath at 30 digits) and mpmath quadrature of the
stored pieces of the collocated observer's kernel (the polynomial pieces summed in mpmath, no nrobust
evaluation). The crossing bound of the collocated loop ``(A_0 + K A_1) + (B_0 + K B_1) e^{-delta s}`` over
the default gains is checked by dense sampling of ``|A| - |B|`` at nine gains: the last sign change lies far
below the bound and none lies between it and twice it.
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest

from nrobust import DistributedDelay, Hyperbolic2x2, ParameterError, QuasiPolynomial
from nrobust.bounds import TailBound
from nrobust.design.gain import _circle_crossing_bound, _Family
from nrobust.distributed_delay import _bend
from nrobust.hyperbolic.analyses.design import _OUTPUT_BOUND_FRACTION, _collocated_k_bounds, _collocated_loop

PAPER = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)


def test_constant_kernel_bound_is_attained() -> None:
    """``N = 1`` on ``[0, 1]``: ``|int| = |1 - e^{-i w}| / w <= 2 / w``, equal at ``w = pi``; ``V_2 = 0``."""
    d = DistributedDelay([0.0, 1.0], [1.0, 1.0])
    v1, v2 = d.second_order_variation()
    assert v1 == pytest.approx(2.0, rel=1e-11) and v1 >= 2.0
    assert v2 == 0.0
    for w in (0.5, np.pi, 10.0, 1000.0):
        exact = abs(1 - mp.exp(mp.mpc(0, -w))) / w
        assert v1 / w + v2 / w**2 >= exact
    assert float(abs(1 - mp.exp(mp.mpc(0, -mp.pi))) / mp.pi) == pytest.approx(v1 / np.pi, rel=1e-11)


# N = 1 + 2 nu on [0, 1), 3 - nu on [1, 2]: end values 1 and 1, a jump of -1 at 1 (V_1 = 3), slopes 2 then -1
# (V_2 = 2 + 1 + 3 = 6); N = 1 + 2 nu then -1 on [1, 2]: a jump of -4 (V_1 = 1 + 1 + 4 = 6, V_2 = 2 + 0 + 2 = 4).
_KERNELS = [
    ([0.0, 1.0, 1.0, 2.0], [1.0, 3.0, 2.0, 1.0], lambda nu: 1 + 2 * nu if nu < 1 else 3 - nu, 3.0, 6.0),
    ([0.0, 1.0, 1.0, 2.0], [1.0, 3.0, -1.0, -1.0], lambda nu: 1 + 2 * nu if nu < 1 else -1 + 0 * nu, 6.0, 4.0),
]


def _exact(kernel, nodes: list[float], w: float) -> mp.mpc:
    """``int N e^{-i w nu}`` in closed form per linear piece (``int (c + k nu) e^{-s nu}``), at 30 digits."""
    mp.mp.dps = 30
    s = mp.mpc(0, w)
    total = mp.mpc(0)
    for a, b in zip(nodes[::2], nodes[1::2]):
        mid = (mp.mpf(a) + b) / 2
        k = (kernel(mid + mp.mpf("1e-3")) - kernel(mid - mp.mpf("1e-3"))) / mp.mpf("2e-3")
        c = kernel(mid) - k * mid

        def prim(nu: mp.mpf, c: mp.mpf = c, k: mp.mpf = k) -> mp.mpc:
            # d/dnu of -(c + k nu) e^{-s nu} / s - k e^{-s nu} / s^2 is (c + k nu) e^{-s nu}
            return -(c + k * nu) * mp.exp(-s * nu) / s - k * mp.exp(-s * nu) / s**2

        total += prim(mp.mpf(b)) - prim(mp.mpf(a))
    return total


@pytest.mark.parametrize(("nodes", "values", "kernel", "v1_exact", "v2_exact"), _KERNELS)
def test_linear_kernel_bound_holds(nodes, values, kernel, v1_exact, v2_exact) -> None:
    """The bound is above the exact integral at frequencies from 0.3 to 3000, and is ``V_1, V_2`` of the kernel."""
    d = DistributedDelay(nodes, values)
    v1, v2 = d.second_order_variation()
    # V_1: |N(0)| + |N(2)| + |jump at 1|; V_2: |N'(0)| + |N'(2)| + |jump of N' at 1| (no N'')
    assert v1 == pytest.approx(v1_exact, rel=1e-11) and v1 >= v1_exact
    assert v2 == pytest.approx(v2_exact, rel=1e-11) and v2 >= v2_exact
    for w in np.geomspace(0.3, 3000.0, 40):
        assert v1 / w + v2 / w**2 >= float(abs(_exact(kernel, [0, 1, 1, 2], float(w))))


def _piece_integral(coefficients: list[mp.mpf], z: mp.mpc) -> mp.mpc:
    """``int_0^1 P(t) e^{-z t} dt`` for the polynomial ``P`` (increasing powers), by parts until ``P`` is
    exhausted: ``sum_k (P^(k)(0) - P^(k)(1) e^{-z}) / z^(k+1)``."""
    total, p = mp.mpc(0), list(coefficients)
    power = z
    while p:
        total += (p[0] - mp.fsum(p) * mp.exp(-z)) / power
        p = [j * c for j, c in enumerate(p)][1:]
        power *= z
    return total


def test_collocated_kernel_bound_holds() -> None:
    """The collocated loop's kernels (``A_0``'s: on the proven route ``N~`` on ``[0, 2]`` and ``-G`` on ``[0, 4]``,
    whose sum has a jump of 3.07 at ``nu = 2`` and ends 0 and -2.0): the bounds summed hold at six frequencies
    against the exact integral of their stored pieces in mpmath at 60 digits (each piece integrated by parts to the
    end, :func:`_piece_integral`: no nrobust evaluation). ``V_1`` is below the whole variation that a single
    integration by parts divides by ``|w|``: 1.93 + 7.00 against 3.04 + 12.91 (0.56 of it; the kernel route's one
    kernel had 5.1 against 11.97, as the two kernels' jumps at 2 and their ends at 0 partly cancel in the sum), and
    ``V_2`` is 2.15 + 11.88 (the one kernel's 9.19: ``|N'(0)| + |N'(4)| + [N'](2) + int |N''|``; the moduli of the
    pieces' coefficients in powers of ``t`` would give 102)."""
    kernels = _collocated_loop(PAPER, 0.0).A0.distributed
    assert len(kernels) == 2
    v1 = sum(d.second_order_variation()[0] for d in kernels)
    v2 = sum(d.second_order_variation()[1] for d in kernels)
    assert v1 < 0.6 * sum(float(d.variation_bound(0.0)) for d in kernels)
    assert v2 < 14.5
    mp.mp.dps = 60
    for w in (0.7, 3.0, 17.0, 60.0, 250.0, 700.0):
        s = mp.mpc(0, w)
        total = mp.mpc(0)
        for d in kernels:
            start, h, poly = d.pieces
            for nu0, step, c in zip(start, h, poly):
                coefficients = [mp.mpf(float(x)) for x in c.real]
                total += step * mp.exp(-s * nu0) * _piece_integral(coefficients, s * step)
        assert v1 / w + v2 / w**2 >= float(abs(total))


def test_bend_bounds_the_second_derivative() -> None:
    """``int_0^1 |P''|`` of random polynomials of degree 11 (coefficients of both signs and decreasing sizes, as
    a kernel's pieces) by mpmath quadrature between the real zeros of ``P''`` is at most the bound, which is at
    most ``sum_l l |P_l|`` and, on these, within a factor 5.5 of the integral (the largest ratio seen, 5.18)."""
    rng = np.random.default_rng(7)
    poly = rng.standard_normal((20, 12)) * 0.5 ** np.arange(12)
    bends = _bend(poly)
    mp.mp.dps = 30
    for P, bound in zip(poly, bends):
        second = [mp.mpf(float(c)) * j * (j - 1) for j, c in enumerate(P)][2:]

        def f(t: mp.mpf, second: list = second) -> mp.mpf:
            return abs(mp.fsum(c * t**j for j, c in enumerate(second)))

        zeros = sorted(
            float(r.real) for r in np.roots(np.array([float(c) for c in second])[::-1]) if abs(r.imag) < 1e-9
        )
        cuts = [0.0, *(z for z in zeros if 0.0 < z < 1.0), 1.0]
        exact = mp.quad(f, cuts)
        assert float(exact) <= bound <= 5.5 * float(exact)
        assert bound <= np.sum(np.abs(P[2:]) * np.arange(2, 12)) * (1.0 + 1e-11)


def test_second_order_needs_the_half_plane() -> None:
    P = QuasiPolynomial([[1.0]], [0.0])
    with pytest.raises(ParameterError, match="x0"):
        TailBound(P, 0, -1.0, 0.0, second_order=True)
    with pytest.raises(ParameterError, match="moment"):
        DistributedDelay([0.0, 1.0], [1.0, 1.0], moment=1).second_order_variation()


def test_collocated_crossing_bound_is_sound_and_tight() -> None:
    """Over the default gains of the collocated loop, dense sampling (step ``1/256``, below a hundredth of the
    loop's fastest period ``2 pi / 4``) at nine gains finds the last sign change of ``|A| - |B|`` below 16 and
    none from there to four times the bound; the bound is 38 (on the circle ``z = e^{-2 i w}``:
    :func:`nrobust.design.gain._circle_crossing_bound`), 705 by the triangle inequality with the kernels
    integrated by parts twice, 1654 with them integrated once. On the proven route (two kernels, ``N~`` and ``G``,
    and point coefficients with radii) it is 46.1: ``V_2`` summed over the two kernels, and ``l`` above ``U rho``."""
    k_lo, k_hi = _collocated_k_bounds(PAPER, 0.0)
    lo, hi = _OUTPUT_BOUND_FRACTION * k_lo, _OUTPUT_BOUND_FRACTION * k_hi
    family = _Family(_collocated_loop(PAPER, 0.0))
    W = family.crossing_bound(lo, hi)
    assert 16.0 < W < 50.0
    w = np.arange(1.0 / 256.0, 4.0 * W, 1.0 / 256.0)
    at = family.axis(w)
    for p in np.linspace(lo, hi, 9):
        gap = np.abs(at.a0 + p * at.a1) - np.abs(at.b0 + p * at.b1)
        change = np.flatnonzero(np.sign(gap[:-1]) != np.sign(gap[1:]))
        assert change.size and w[change[-1]] < 16.0
        assert np.all(gap[w > 16.0] > 0.0)
    # delays that are no multiples of one base: the bound on the circle does not apply and leaves W as it is
    A0, A1, B0, B1 = family.affine
    shifted = (A0, A1.shift(0.1), B0, B1.shift(0.1))
    assert _circle_crossing_bound(shifted, lo, hi, 123.0) == 123.0


def test_a_zero_length_interval_of_gains_has_the_bound_of_its_gain() -> None:
    """``crossing_bound(K, K)``: one gain, a piece of zero length (it divided by zero before), a bound no smaller
    than the sampled last crossing of that gain's loop and no larger than that of an interval holding it."""
    family = _Family(_collocated_loop(PAPER, 0.0))
    W = family.crossing_bound(0.1, 0.1)
    assert 0.0 < W <= family.crossing_bound(0.0, 0.2)
    A, B = (family.A(0.1), family.B(0.1))
    w = np.arange(1, int(4 * W * 64)) / 64.0
    gap = np.abs(A(1j * w)) - np.abs(B(1j * w))
    assert not np.any(np.diff(np.sign(gap[w > W])))


def test_pieces_that_overlap_by_an_ulp_count_both_ends() -> None:
    """``N = 1`` on ``[0.1, 1000.3]`` and ``[1000.3, 1001]``: the first piece, ``0.1 + fl(1000.3 - 0.1)``, ends
    ``2.3e-14`` past the second's start, so the stored pieces overlap there and their integral (each constant piece
    exactly, ``(e^{-a s} - e^{-b s}) / s``, 40 digits) has a part that does not decay in ``|s|``: near
    ``w = (2k + 1) pi / 1000.9`` it exceeded the bound taken with the pieces meeting (``V_1 = 2``). Both ends count
    (``V_1 = 4``) and the bound holds there."""
    d = DistributedDelay([0.1, 1000.3, 1001.0], [1.0, 1.0, 1.0])
    start, h, _ = d.pieces
    assert start[0] + h[0] != start[1] or mp.mpf(float(start[0])) + mp.mpf(float(h[0])) != mp.mpf(float(start[1]))
    v1, v2 = d.second_order_variation()
    assert v1 == pytest.approx(4.0, rel=1e-11) and v1 >= 4.0
    with mp.workdps(40):
        pieces = [(mp.mpf(float(a)), mp.mpf(float(a)) + mp.mpf(float(b))) for a, b in zip(start, h)]
        for j in range(-3, 4):
            w = mp.mpf(2 * (10**6 + j) + 1) * mp.pi / mp.mpf("1000.9")
            s = mp.mpc(0, w)
            integral = abs(sum((mp.exp(-a * s) - mp.exp(-b * s)) / s for a, b in pieces))
            assert integral <= v1 / w + v2 / w**2
