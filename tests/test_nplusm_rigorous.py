"""Root counts of the n + m closed loop proven in ball arithmetic (``BallNPlusM``).

Oracles: mpmath's matrix exponential at 40 digits (written here), the closed-form roots of
an uncoupled loop, and the 2x2 exact route (closed-form kernels, no matrix exponential).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from nrobust import characteristic, count_roots, find_roots, spectral_abscissa
from nrobust.balls import acb_to_disc, ball_function
from nrobust.errors import CertificationError
from nrobust.hyperbolic.loops.controllers import StateFeedback
from nrobust.hyperbolic.nplusm import BallNPlusM, NPlusMCharacteristic, NPlusMSystem
from nrobust.hyperbolic.plants.hyperbolic2x2 import Hyperbolic2x2

flint = pytest.importorskip("flint")
mpmath = pytest.importorskip("mpmath")

PLANT = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
GAIN, DELAY = -0.3, 0.5
# Uncoupled 2 + 1 (Sigma = 0), round trips 1/lam_i + 1/mu = 1.5 and 2.5 (exact in binary) and
# delta = 2.5: F = 1 - a e^{-1.5 s} - b e^{-2.5 s} + ab e^{-4 s} = (1 - a e^{-1.5 s})(1 - b e^{-2.5 s}).
A_, B_ = 0.5, 0.36
UNCOUPLED = NPlusMSystem([1.0, 0.5], [2.0], np.zeros((3, 3)), [[1.0], [1.0]], [[A_, B_]])
K_UNCOUPLED, D_UNCOUPLED = [[-A_ * B_, 0.0]], 2.5
# a coupled 2 + 1 with a non-commuting C and P_j, and a 1 + 2 (two actuators)
TWO_ONE = NPlusMSystem(
    [1.0, 0.4], [2.0], [[0.0, 0.3, -0.5], [0.2, 0.1, 0.4], [0.6, -0.3, 0.0]], [[0.7], [-0.5]], [[0.3, 0.6]]
)
ONE_TWO = NPlusMSystem(
    [1.0], [1.0, 2.0], [[0.0, 0.3, 0.2], [0.1, 0.0, 0.4], [0.5, 0.2, 0.0]], [[0.5, 0.2]], [[0.3], [0.1]]
)


def closed_form_roots(im_max: float) -> list[complex]:
    """Roots of (1 - a e^{-1.5 s})(1 - b e^{-2.5 s}) with 0 <= Im s <= im_max (and conjugates), 40 digits."""
    mpmath.mp.dps = 40
    out = []
    for c, tau in ((A_, 1.5), (B_, 2.5)):
        x = mpmath.log(mpmath.mpf(c)) / tau
        n = 0
        while 2 * math.pi * n / tau <= im_max:
            y = 2 * mpmath.pi * n / tau
            out += [complex(x, y)] + ([complex(x, -y)] if n else [])
            n += 1
    return out


def mp_value(F: NPlusMCharacteristic, s: complex, h: complex = 0) -> Any:
    """F(s + h): det of rows l_j^T exp(C - (s + h) P_j) [Q; I] by mpmath.expm (at mpmath's precision)."""
    sys = F.system
    n, m = sys.n, sys.m
    z = mpmath.mpc(s) + h
    inv = [1 / mpmath.mpf(v) for v in sys.lam] + [-1 / mpmath.mpf(v) for v in sys.mu]
    C = mpmath.matrix([[inv[i] * mpmath.mpf(sys.sigma[i, k]) for k in range(n + m)] for i in range(n + m)])
    W = mpmath.matrix(np.vstack([sys.q, np.eye(m)]).tolist())
    rows = mpmath.matrix(m, m)
    for j in range(m):
        P = mpmath.diag([inv[i] + 1 / mpmath.mpf(sys.mu[j]) for i in range(n + m)])
        ell = mpmath.matrix(1, n + m)
        for i in range(n):
            ell[0, i] = -(mpmath.mpf(sys.r[j, i]) + mpmath.mpf(F.K[j, i]) * mpmath.exp(-mpmath.mpf(F.delta) * z))
        ell[0, n + j] = 1
        row = ell * mpmath.expm(C - z * P) * W
        for k in range(m):
            rows[j, k] = row[0, k]
    return mpmath.det(rows)


@pytest.mark.parametrize(
    "F",
    [
        NPlusMCharacteristic(NPlusMSystem.from_2x2(PLANT), [[GAIN]], DELAY),
        NPlusMCharacteristic(TWO_ONE, [[-0.2, 0.1]], 0.3),
        NPlusMCharacteristic(ONE_TWO, [[0.1], [-0.2]], 0.4),
    ],
)
def test_enclosures_hold_mpmath_values(F: NPlusMCharacteristic) -> None:
    """F and F' at random points, and F on a small box, lie in the ball enclosures; the radii
    at points stay near rounding (below 1e-12 for |Im s| <= 20; measured at most 3.2e-14)."""
    balls = ball_function(F)
    assert isinstance(balls, BallNPlusM)
    rng = np.random.default_rng(7)
    pts = rng.uniform(-1.5, 1.5, 3) + 1j * rng.uniform(-20, 20, 3)
    mpmath.mp.dps = 40
    for s in pts:
        exact = complex(mp_value(F, s))
        mid, rad = acb_to_disc(balls(complex(s)))
        assert abs(mid - exact) <= rad + 1e-30 * abs(exact) and rad < 1e-12
        # over a box: two opposite corners and the centre lie in the enclosure
        box = (s.real - 1e-3, s.real + 1e-3, s.imag - 1e-3, s.imag + 1e-3)
        mid, rad = acb_to_disc(balls.on_box(box))
        for p in (complex(box[0], box[2]), complex(box[1], box[3])):
            assert abs(complex(mp_value(F, p)) - mid) <= rad
        assert abs(exact - mid) <= rad
    # F' by mpmath's 40-digit numerical derivative (its error, ~1e-30, far below the ball radius)
    s = complex(pts[0])
    d1 = complex(mpmath.diff(lambda h: mp_value(F, s, h), 0))
    mid, rad = acb_to_disc(balls(s, 1))
    assert abs(mid - d1) <= rad + 1e-25 * (1 + abs(d1))
    # the floating-point F agrees with the enclosure's midpoint to rounding
    mids, rads = balls.values(pts)
    np.testing.assert_allclose(mids, F(pts), rtol=1e-12, atol=rads.max())


def test_one_plus_one_matches_the_two_by_two_exact_route() -> None:
    """U = k u(t - delta, 1) on the coupled 2x2 plant: the n + m matrix exponential loop and
    the 2x2 exact route (closed-form kernels with proven bounds) are the same function; their
    proven counts agree with each other and with the floating-point count (7 and 2 roots: measured)."""
    F = NPlusMCharacteristic(NPlusMSystem.from_2x2(PLANT), [[GAIN]], DELAY)
    Q = characteristic(PLANT, StateFeedback(GAIN), DELAY)
    box = (-1.0, 1.0, -0.5, 20.0)
    proven = count_roots(F, box, rigorous=True)
    assert proven.rigorous and not proven.shifted
    assert int(proven) == int(count_roots(Q, box, rigorous=True)) == 7
    small = (-1.0, 1.0, -0.5, 4.0)
    assert int(count_roots(F, small, rigorous=True)) == int(count_roots(F, small)) == 2


def test_uncoupled_counts_are_the_closed_form() -> None:
    """Sigma = 0: the proven count and the proven root boxes match the closed-form roots."""
    F = NPlusMCharacteristic(UNCOUPLED, K_UNCOUPLED, D_UNCOUPLED)
    s = np.array([0.3 + 2.0j, -0.7 + 13.0j])
    np.testing.assert_allclose(F(s), (1 - A_ * np.exp(-1.5 * s)) * (1 - B_ * np.exp(-2.5 * s)), rtol=1e-13)
    roots = closed_form_roots(25.0)
    box = (-1.0, 0.0, -0.1, 20.0)
    expected = sum(box[0] < z.real < box[1] and box[2] < z.imag < box[3] for z in roots)
    assert expected == 13 and int(count_roots(F, box, rigorous=True)) == expected
    found = find_roots(F, (-1.0, 0.5, -0.1, 1.0), rigorous=True)
    inside = [z for z in roots if -0.1 < z.imag < 1.0]
    assert found.rigorous and len(found) == len(inside) == 2
    for z in inside:  # every closed-form root lies in exactly one proven box
        hits = [b for b in found.boxes if b[0] <= z.real <= b[1] and b[2] <= z.imag <= b[3]]
        assert len(hits) == 1


@pytest.mark.parametrize("offset", [1e-9, -1e-9, 0.0, 5e-9])
@pytest.mark.parametrize("side", ["right", "top"])
def test_edge_near_a_root_is_never_miscounted(offset: float, side: str) -> None:
    """An edge within 1e-8 of a root: the proven count is the closed-form count of the region
    actually counted (40-digit roots); 1e-9 away the balls decide it in place, an edge through
    the root (to rounding) is refused without shifts and moved outwards with them."""
    F = NPlusMCharacteristic(UNCOUPLED, K_UNCOUPLED, D_UNCOUPLED)
    z = complex(math.log(A_) / 1.5, 4 * math.pi / 1.5)
    box = (-0.6, z.real + offset, 3.0, 5.0) if side == "right" else (-0.5, -0.3, 3.0, z.imag + offset)
    roots = closed_form_roots(10.0)
    if offset == 0.0:  # the edge within rounding of the root (1e-17): refused in place, counted when moved
        with pytest.raises(CertificationError, match="cannot prove the winding number"):
            count_roots(F, box, rigorous=True, max_shifts=0)
    for shifts in (0, 4) if offset else (4,):
        res = count_roots(F, box, rigorous=True, max_shifts=shifts)
        assert res.shifted == (offset == 0.0)
        x0, x1, y0, y1 = res.region
        assert int(res) == sum(x0 < w.real < x1 and y0 < w.imag < y1 for w in roots)


def test_spectral_abscissa_on_the_chains_needs_a_region() -> None:
    """Every root of this uncoupled loop lies on its chains (abscissa ln(b) / 2.5 = c_D): the far
    field cannot be proven right of them, and rigorous=True says so and asks for a region (a
    loop whose rightmost root lies right of the chains needs none: tests/test_nplusm_proven.py);
    with one, the proven root box holds the closed-form abscissa."""
    F = NPlusMCharacteristic(UNCOUPLED, K_UNCOUPLED, D_UNCOUPLED)
    with pytest.raises(CertificationError, match="give a region"):
        spectral_abscissa(F, rigorous=True)
    res = spectral_abscissa(F, (-0.45, 0.5, -0.1, 1.0), rigorous=True)
    assert res.rigorous and res.root_box is not None and res.chain_bracket is None
    assert res.root_box[0] <= math.log(B_) / 2.5 <= res.root_box[1]
