"""The crossing bound of the filter's pole ``b`` (nrobust.design.gain) against the closed-form loop.

With ``a = 0`` the filtered loop is ``A_0 (1 + b s) + B e^{-delta s}``: ``|A|^2 = |A_0|^2 (1 + b^2 w^2)``
grows with ``b``, so a frequency above which ``|A_0| > |B|`` (the bound at ``b = 0``) bounds the
crossings of every pole; the bound at a small pole grows like ``1/b``. The oracle is the
paper's plant in closed form at 20 digits (``tests/test_filter_cutoff.py``'s boundary function, no
kernel, no nrobust code path): no crossing above the bound for poles across the interval.
"""

from __future__ import annotations

import mpmath as mp
import numpy as np

from nrobust import Hyperbolic2x2
from nrobust.design.gain import _Family
from nrobust.hyperbolic.analyses.filter_design import design_filtered_exact, filtered_loop

RHO, Q, K = 0.85, 1.0, 0.1
PLANT = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, RHO)


def _gap(w: float, b: float) -> float:
    """``|A(i w)|^2 - |B(i w)|^2`` of ``FilteredController(0, b, K)`` (eq. (60) with the filter), at 20 digits."""
    mp.mp.dps = 20
    s = mp.mpc(0, w)
    k = mp.sqrt(s * s - 1)
    c, sk = mp.cosh(k), mp.sinh(k) / k
    u1, v1 = (c - s * sk) * Q + sk, -sk * Q + (c + s * sk)
    A = mp.exp(-s) * (v1 - RHO * u1)  # 1 - Phi: the open loop's characteristic function
    z = mp.exp(-2 * s)
    B = 1 - RHO * Q * z - A + K * Q * z
    return float(abs(A * (1 + b * s)) ** 2 - abs(B) ** 2)


def test_the_bound_of_the_pole_holds_for_every_pole_and_does_not_grow_like_one_over_b() -> None:
    lo, hi = 0.002, 2.0  # design_filtered_exact's default bounds of b (a = 0: no strong-stability limit)
    W = _Family(filtered_loop(PLANT, {"K": K, "a": 0.0, "b": None}).affine()).crossing_bound(lo, hi)
    # the bound at b = 0 (78.1, the kernels integrated by parts twice; 121.6 once); at b = 0.002 alone it is 6515
    assert W < 80.0
    for b in (lo, 0.01, 0.1, 0.6298503342, hi):
        gaps = [_gap(w, b) for w in np.geomspace(W, 50.0 * W, 300)]
        assert min(gaps) > 0.0, (b, min(gaps))


def test_the_design_with_default_bounds_is_the_one_on_a_narrower_interval() -> None:
    # the optimum (a pair birth at b* = 0.62985033418..., docs/design.md) from the default interval
    # [0.002, 2] and from [0.3, 1.5]: each sits 1e-10 (relative to its bounds) on the side without the pair
    wide = design_filtered_exact(PLANT, parameters={"K": K, "a": 0.0, "b": None})
    narrow = design_filtered_exact(PLANT, parameters={"K": K, "a": 0.0, "b": (0.3, 1.5)})
    assert wide.kind == narrow.kind == "pair birth"
    np.testing.assert_allclose(wide.optimum, narrow.optimum, rtol=0, atol=3e-10)
    np.testing.assert_allclose(wide.value, narrow.value, rtol=0, atol=1e-9)  # the margin's slope in b is O(1)
