"""``best_margin`` where its optimum sits at the end of the nominal loop's stability.

Two kinds of end, each solved here by mpmath from the loop written out by hand (no code of the
package): a crossing curve that ends at ``w = 0`` where ``s = 0`` becomes a root for every delay
(``A(0) + B(0) = 0``, the gain ``K_0``; the curve's frequency falls below any uniform scan's first
sample as ``K -> K_0``, its delay tends to ``B'(0)/B(0) - A'(0)/A(0)``), and a root crossing the axis
at ``delta = 0`` (``A(i w) + B(i w) = 0``): the margin is 0 on one side and jumps to another curve's
delay on the other, a supremum not attained. Both loops were refused ("no crossing curve reaches
K", "the two crossing curves do not change order") before the scan sampled frequencies below its
uniform step and the wraps were solved exactly.
"""

from __future__ import annotations

import itertools

import mpmath as mp
import numpy as np
import pytest

from nrobust import QuasiPolynomial
from nrobust.design import gain
from nrobust.design.gain import AffineLoop, _Curves, _Family, best_margin
from nrobust.errors import CertificationError
from nrobust.margins import delay_margin

mp.mp.dps = 30


def _loop(t1: float, t2: float, t3: float, a0: float, a1: float, b0: float, c: float, a2: float, neutral: bool):
    """``A = (a0 + s) + (a1 + n s) e^{-t1 s} + p a2``, ``B = (b0 + m s) e^{-t2 s} + p c e^{-t3 s}``: the
    loop for the package, and ``A, B`` as mpmath functions of ``(s, p)``."""
    n, m = (0.3, 0.2) if neutral else (0.0, 0.0)
    loop = AffineLoop(
        QuasiPolynomial([[a0, 1.0], [a1, n]], [0.0, t1]),
        QuasiPolynomial([[a2]], [0.0]),
        QuasiPolynomial([[b0, m]], [t2]),
        QuasiPolynomial([[c]], [t3]),
    )

    def A(s, p):
        return (a0 + s) + (a1 + n * s) * mp.exp(-t1 * s) + p * a2

    def B(s, p):
        return (b0 + m * s) * mp.exp(-t2 * s) + p * c * mp.exp(-t3 * s)

    return loop, A, B


def _grid_best(loop: AffineLoop, lo: float, hi: float) -> float:
    return max(delay_margin(loop.A(K), loop.B(K)).margin for K in np.linspace(lo, hi, 21))


def test_optimum_where_s_zero_becomes_a_root() -> None:
    loop, A, B = _loop(0.447, 2.005, 1.237, 0.503, -0.658, 0.536, 0.273, 0.1404, True)
    # K_0: A(0) + B(0) = 0, linear in p
    K0 = -(A(0, 0) + B(0, 0)) / ((A(0, 1) - A(0, 0)) + (B(0, 1) - B(0, 0)))
    limit = mp.diff(lambda s: B(s, K0), 0) / B(0, K0) - mp.diff(lambda s: A(s, K0), 0) / A(0, K0)
    design = best_margin(loop, (-1.0, 1.0))
    assert design.kind == "end"
    # the design sits 1e-10 (relative) off K_0 on the stable side; the delay moves by O(1) per unit of gain
    np.testing.assert_allclose(design.K, float(K0), rtol=0, atol=1e-9)
    np.testing.assert_allclose(design.margin, float(limit), rtol=1e-8)
    assert design.margin >= _grid_best(loop, -1.0, 1.0)


@pytest.mark.parametrize(
    ("params", "start"),
    [
        ((2.271, 0.318, 2.762, 0.649, 1.281, -0.896, -0.496, 0.0, False), (0.6466, 0.9179, 1.1057)),
        ((1.293, 2.434, 1.265, 1.353, 0.45, 1.764, 1.967, 0.2685, False), None),
    ],
)
def test_optimum_where_a_root_crosses_the_axis_without_delay(params: tuple, start: tuple | None) -> None:
    loop, A, B = _loop(*params)
    design = best_margin(loop, (-1.0, 1.0))
    assert design.kind == "end"
    assert design.margin >= _grid_best(loop, -1.0, 1.0)
    # margin 0 just past the end: the nominal loop has a root on the axis there
    K_edge = design.K_bracket[1] if design.K_bracket[1] != design.K else design.K_bracket[0]
    past = 2.0 * K_edge - design.K
    assert delay_margin(loop.A(past), loop.B(past)).margin == 0.0
    if start is None:
        return
    w0, K_start, w1 = start
    # the root on the axis at delta = 0: A(i w) + B(i w) = 0, two real equations in (w, K)
    w_axis, K_w = mp.findroot(
        lambda w, K: [mp.re(A(1j * w, K) + B(1j * w, K)), mp.im(A(1j * w, K) + B(1j * w, K))], (w0, K_start)
    )
    assert abs(w_axis - w0) < 1e-3  # the root found is the one the scan's wrap is at
    np.testing.assert_allclose(design.K, float(K_w), rtol=0, atol=1e-9)
    # the other curve's crossing at K_w: |A(i w)| = |B(i w)|, delay arg(-B/A) / w on [0, 2 pi)
    w_c = mp.findroot(lambda w: abs(A(1j * w, K_w)) ** 2 - abs(B(1j * w, K_w)) ** 2, w1)
    theta = mp.arg(-B(1j * w_c, K_w) / A(1j * w_c, K_w)) % (2 * mp.pi)
    # the design's delay at 1e-10 off K_w: the curve's slope there is about 0.7 per unit of gain
    np.testing.assert_allclose(design.margin, float(theta / w_c), rtol=1e-9)


def test_interior_maximum_far_from_the_largest_sample() -> None:
    """The scan's curve is linear between samples whose gains lie 50 cells apart: its largest value
    (K = 0.777) is far from the exact maximum (K = 0.72), which the design must find, not the end of
    a search window about the sample (it returned 1.77732 at K = 0.769, below 1.77795 at K = 0.7)."""
    loop, A, B = _loop(1.81, 1.45, 2.301, 1.738, 1.658, -1.131, 1.076, -0.519, False)

    def delay(K):
        w = mp.findroot(lambda w: abs(A(1j * w, K)) ** 2 - abs(B(1j * w, K)) ** 2, 1.6028)
        return (mp.arg(-B(1j * w, K) / A(1j * w, K)) % (2 * mp.pi)) / w

    K_star = mp.findroot(lambda K: mp.diff(delay, K), 0.72)
    design = best_margin(loop, (-1.0, 1.0))
    assert design.kind == "interior smooth max"
    # a smooth maximum: the value to rounding, the gain to about sqrt(eps) of the curvature's scale
    np.testing.assert_allclose(design.margin, float(delay(K_star)), rtol=1e-13)
    np.testing.assert_allclose(design.K, float(K_star), rtol=0, atol=1e-7)
    assert design.margin >= _grid_best(loop, -1.0, 1.0)


def test_optimum_where_s_zero_becomes_a_root_at_a_grid_gain() -> None:
    """As above, with ``K_0 = 0.094`` where the curve ends at ``w = 0`` and ``|A|^2 - |B|^2 ~ c w^2`` sinks into
    its rounding at ``w ~ 1e-8``: Newton at ``K_0`` took noise for steps and refused ("did not converge")."""
    loop, A, B = _loop(1.0, 1.0, 2.0, 0.5, -1.5, 0.906, 1.0, 0.0, False)
    K0 = -(A(0, 0) + B(0, 0)) / ((A(0, 1) - A(0, 0)) + (B(0, 1) - B(0, 0)))
    np.testing.assert_allclose(float(K0), 0.094, rtol=1e-12)
    limit = mp.diff(lambda s: B(s, K0), 0) / B(0, K0) - mp.diff(lambda s: A(s, K0), 0) / A(0, K0)
    design = best_margin(loop, (-1.0, 1.0))
    assert design.kind == "end"
    np.testing.assert_allclose(design.K, float(K0), rtol=0, atol=1e-9)
    np.testing.assert_allclose(design.margin, float(limit), rtol=1e-8)
    # the grid gains but K_0 itself, where the oracle cannot decide (a double zero of |A|^2 - |B|^2 at w = 0)
    grid = [K for K in np.linspace(-1.0, 1.0, 21) if abs(K - 0.094) > 1e-6]
    assert design.margin >= max(delay_margin(loop.A(K), loop.B(K)).margin for K in grid)


def test_a_margin_without_bound_at_a_common_zero_of_a_and_b_is_refused() -> None:
    """``A = 0.5 + s - 0.5 e^{-s}`` (``A(0) = 0``), ``B = (0.25 + 0.375 K) e^{-s}``: at ``K_0 = -2/3``
    ``s = 0`` is a zero of both. At ``K = K_0 + h`` the crossing is where ``|A(i w)| ~ 1.5 w`` meets
    ``|B| = 0.375 h``, ``w = h/4``, with the phase ``arg(-B/A) ~ pi/2``: ``delta* ~ (pi/2)/w = 2 pi/h``, without
    bound. best_margin returned margin 0 at ``K_0`` (its limit formula gave inf, the certificate 0, and
    ``|0 - inf| <= inf`` passed its check)."""
    loop, _, _ = _loop(1.0, 1.0, 1.0, 0.5, -0.5, 0.25, 0.375, 0.0, False)
    with pytest.raises(CertificationError, match=r"grows without bound toward K = -0\.66666666"):
        best_margin(loop, (-1.0, 1.0))
    # the oracle: the margin just above K_0 against 2 pi / h, growing past any grid value
    for h in (1e-2, 1e-3):
        m = delay_margin(loop.A(-2.0 / 3.0 + h), loop.B(-2.0 / 3.0 + h)).margin
        np.testing.assert_allclose(m, 2.0 * np.pi / h, rtol=0.01)  # first order in h: 1.3e-3 measured at 1e-2
    assert best_margin(loop, (-0.6, 1.0)).margin > 90.0  # bounds that leave K_0 out: a design (93.4 at -0.6)


def test_an_edge_next_to_a_junction_of_the_crossing_curves() -> None:
    """``A = 0.625 + s + e^{-2.625 s}``, ``B = -0.5 e^{-0.375 s} + p e^{-0.5 s}``: stable without delay for
    ``p > p_0 ~ 0.4978``, where a root crosses the axis at ``w_0 = 0.8454``, 2.2e-6 above the frequency where the
    two branches of the crossing curves meet (``D = 0``). The junction was located 3e-6 off, on the side with
    crossings, and both branches put at ``K = m`` there: the branch's gain jumped over the wrap of its phase at
    ``w_0``, the edge was missed and best_margin refused ("stable at p = 0.5"). The edge against mpmath's root of
    ``F(i w; p) = 0`` (``F`` written by hand), the design against certified margins on a grid of ``p``."""
    loop = AffineLoop(
        QuasiPolynomial([[0.625, 1.0], [1.0]], [0.0, 2.625]),
        QuasiPolynomial([[0.0]], [0.0]),
        QuasiPolynomial([[-0.5]], [0.375]),
        QuasiPolynomial([[1.0]], [0.5]),
    )

    def F(w, p):
        s = 1j * w
        return 0.625 + s + mp.exp(-2.625 * s) - 0.5 * mp.exp(-0.375 * s) + p * mp.exp(-0.5 * s)

    w0, p0 = mp.findroot(lambda w, p: [mp.re(F(w, p)), mp.im(F(w, p))], (0.85, 0.5))
    np.testing.assert_allclose(float(w0), 0.8453997621808740, rtol=1e-15)
    # the wrap is solved to rounding on the phase; p_0 moves by dp/dw ~ 0.3 per unit of w there
    assert _Curves(_Family(loop), -1.0, 1.0, 2_000_000).edges == pytest.approx([float(p0)], rel=0, abs=1e-13)
    design = best_margin(loop, (-1.0, 1.0))
    assert design.kind == "end"
    assert design.K == 1.0
    # the scan's envelope: margin 0 exactly on the unstable side of p_0, positive on the other
    assert np.all(design.envelope[design.gains < float(p0)] == 0.0)
    assert np.all(design.envelope[design.gains > float(p0) + 1e-3] > 0.0)
    grid = [delay_margin(loop.A(K), loop.B(K)).margin for K in np.linspace(-1.0, 1.0, 41)]
    assert max(grid[:29]) == 0.0  # p <= 0.4: unstable without delay
    # the design is certified at K = 1 (a grid gain): the same margin, to the certificate's rounding
    np.testing.assert_allclose(design.margin, max(grid), rtol=1e-12)

    # and by mpmath at p = 1: the least crossing delay arg(-B/A) / w over the zeros of |A|^2 - |B|^2 in (0, 3.2]
    # (3.2 is above the scan's crossing bound W = 3.125), each bracketed on 640 cells and refined
    def A(w):
        return 0.625 + 1j * w + mp.exp(-2.625j * w)

    def B(w):
        return -0.5 * mp.exp(-0.375j * w) + mp.exp(-0.5j * w)

    def g(w):
        return abs(A(w)) ** 2 - abs(B(w)) ** 2

    cells = np.linspace(1e-3, 3.2, 641)
    zeros = [mp.findroot(g, (a, b), solver="anderson") for a, b in itertools.pairwise(cells) if g(a) * g(b) < 0]
    delays = [(mp.arg(-B(w) / A(w)) % (2 * mp.pi)) / w for w in zeros]
    np.testing.assert_allclose(design.margin, float(min(delays)), rtol=1e-12)


def test_an_edge_the_scan_misses_is_found_by_certified_verdicts(monkeypatch: pytest.MonkeyPatch) -> None:
    """The loop above with the junction put 3e-6 off, on the side with crossings (the scan misses the edge, as
    it did when the junction was an estimate of a few Illinois steps). The certified nominal verdicts at
    17 gains differ about ``p_0``: bisected, then ``F(i w; p) = 0`` solved by Newton; the design is the same."""
    loop = AffineLoop(
        QuasiPolynomial([[0.625, 1.0], [1.0]], [0.0, 2.625]),
        QuasiPolynomial([[0.0]], [0.0]),
        QuasiPolynomial([[-0.5]], [0.375]),
        QuasiPolynomial([[1.0]], [0.5]),
    )

    def F(w, p):
        s = 1j * w
        return 0.625 + s + mp.exp(-2.625 * s) - 0.5 * mp.exp(-0.375 * s) + p * mp.exp(-0.5 * s)

    w0, p0 = mp.findroot(lambda w, p: [mp.re(F(w, p)), mp.im(F(w, p))], (0.85, 0.5))
    # the junction put 3e-6 on the side with crossings (``-toward``): the scan then misses the edge
    monkeypatch.setattr(gain, "_side_without_crossings", lambda disc, x, a, b, toward: x - 3e-6 * toward)
    curves = _Curves(_Family(loop), -1.0, 1.0, 2_000_000)
    assert curves.edges == []  # missed by the scan
    # Newton on F(i w; p) = 0 converges to rounding: p_0 to a few ulps of its scale
    ((w_e, p_e),) = gain._missed_edges(curves)
    np.testing.assert_allclose([w_e, p_e], [float(w0), float(p0)], rtol=0, atol=1e-13)
    design = best_margin(loop, (-1.0, 1.0))
    assert design.K == 1.0 and design.kind == "end"
    np.testing.assert_allclose(design.margin, delay_margin(loop.A(1.0), loop.B(1.0)).margin, rtol=1e-12)
