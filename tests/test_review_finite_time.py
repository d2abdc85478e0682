"""The finite-time gain of :func:`nrobust.design.best_decay_rate` at the edges of its detection.

A loop whose nominal part ``F(.; 0, K)`` is one constant (no zero: the decay rate is ``inf``) at one gain, with
a distributed kernel ``I(s) = n (1 - e^{-s}) / s`` (``n = -1`` on ``[0, 1]``) that cancels at ``delta = 0`` and
gives the loop finite delay margins otherwise:

``F(s; delta, K) = 1 - 0.3 e^{-2s} + I(s) + (-I(s) + K e^{-2s}) e^{-delta s}``, so ``F(.; 0, K) = 1 + (K - 0.3)
e^{-2s}``, whose roots all have the real part ``ln|K - 0.3| / 2``: the decay rate ``-ln|K - 0.3| / 2``, ``inf`` at
``K = 0.3``.

Oracles, independent of :mod:`nrobust.design`: that closed form, and the delay margin at 40 digits in mpmath
(:func:`mp_margin`): the crossing frequencies ``|A(iw)| = |B(iw)|`` bracketed on a grid and solved, each giving the
smallest delay ``(-arg(-A/B) mod 2 pi) / w``; the margin is the least of them (the nominal loop is stable).
"""

from __future__ import annotations

import mpmath
import numpy as np
import pytest

from nrobust.design import AffineLoop, best_decay_rate, best_margin
from nrobust.distributed_delay import DistributedDelay
from nrobust.errors import CertificationError, ParameterError
from nrobust.margins import AffineGainLoop
from nrobust.quasipoly import QuasiPolynomial

RHO = 0.3
N = -1.0
KERNEL = DistributedDelay(np.array([0.0, 1.0]), np.array([N, N]))
LOOP = AffineGainLoop(
    QuasiPolynomial([[1.0], [-RHO]], [0.0, 2.0], [KERNEL]),
    QuasiPolynomial([[0.0]], [0.0], [KERNEL.scale(-1.0)]),
    QuasiPolynomial([[1.0]], [2.0]),
)
BOUNDS = (-0.3, 0.3)
S = np.array([0.0, 0.3 + 1.0j, 2.0j, 1.5 - 7.0j, 0.1 + 40.0j])


def rate(K: float) -> float:
    """``-ln|K - 0.3| / 2``, the decay rate of ``1 + (K - 0.3) e^{-2s}``."""
    return float(-np.log(abs(K - RHO)) / 2.0)


def mp_margin(K: float) -> float:
    """The delay margin of ``A + B e^{-delta s}`` at ``K`` (``|K| <= 0.3``), at 40 digits.

    ``|A| >= 0.7 - 2/w`` and ``|B| <= 0.3 + 2/w`` on the axis: no crossing above ``w = 10``; the grid of
    ``g = |A|^2 - |B|^2`` on ``(0, 12]`` (step 0.0025) brackets each crossing, ``findroot`` solves it.
    """

    def g_float(w: np.ndarray) -> np.ndarray:
        s = 1j * w
        i_s = N * (1.0 - np.exp(-s)) / s
        return np.abs(1.0 - RHO * np.exp(-2.0 * s) + i_s) ** 2 - np.abs(-i_s + K * np.exp(-2.0 * s)) ** 2

    ws = np.linspace(1e-3, 12.0, 4801)
    gs = g_float(ws)
    with mpmath.workdps(40):
        n, k, rho = mpmath.mpf(N), mpmath.mpf(K), mpmath.mpf(RHO)

        def A(s: mpmath.mpc) -> mpmath.mpc:
            return 1 - rho * mpmath.exp(-2 * s) + n * (1 - mpmath.exp(-s)) / s

        def B(s: mpmath.mpc) -> mpmath.mpc:
            return -n * (1 - mpmath.exp(-s)) / s + k * mpmath.exp(-2 * s)

        def g(w: mpmath.mpf) -> mpmath.mpf:
            s = mpmath.mpc(0, w)
            return abs(A(s)) ** 2 - abs(B(s)) ** 2

        delays = []
        for i in np.flatnonzero(gs[:-1] * gs[1:] < 0):
            w = mpmath.findroot(g, (mpmath.mpf(ws[i]), mpmath.mpf(ws[i + 1])), solver="anderson")
            s = mpmath.mpc(0, w)
            delays.append((-mpmath.arg(-A(s) / B(s))) % (2 * mpmath.pi) / w)
        return float(min(delays))


def test_loop_at_rho_is_one() -> None:
    """The kernels cancel exactly (one stored kernel and its negation): ``F(.; 0, 0.3) = 1``, no zero."""
    np.testing.assert_array_equal((LOOP.A + LOOP.B(RHO))(S), np.ones(S.size))


@pytest.mark.parametrize("how", ["margin", "window"])
def test_finite_time_gain_just_inside_the_margin_end(how: str) -> None:
    """``d`` 1e-11 below the margin at 0.3: the feasible gains end ``1e-11 / |d delta*/dK|`` (``|d delta*/dK|``
    about 0.9: 1.1e-11) past 0.3, closer than the ``1e-10 * 0.3`` the end is moved inside; 0.3 is feasible and is
    the design."""
    m_rho = mp_margin(RHO)
    d = m_rho - 1e-11
    if how == "margin":
        design = best_decay_rate(LOOP, BOUNDS, margin_at_least=d)
    else:
        design = best_decay_rate(LOOP, BOUNDS, delays=(0.0, d))
    assert design.kind == "finite time" and design.K == RHO and design.value == np.inf
    assert design.value_bracket == (np.inf, np.inf)
    # the certified margin at the design is the oracle's, to the rounding of the loop's evaluation (1e-15)
    np.testing.assert_allclose(design.margin, m_rho, rtol=1e-12)
    assert design.margin >= d


def test_finite_time_gain_below_the_margin_is_not_the_design() -> None:
    """``d = 1`` > the margin at 0.3 (0.948): the largest rate is at the end of the feasible gains below 0.3,
    a margin constraint where the margin is ``d``, its rate the closed form there."""
    d = 1.0
    assert mp_margin(RHO) < d
    design = best_decay_rate(LOOP, BOUNDS, margin_at_least=d)
    assert design.kind == "margin constraint" and design.K < RHO
    np.testing.assert_allclose(design.value, rate(design.K), rtol=1e-12)  # roots of 1 + c e^{-2s}: 1e-15
    # the end is moved 1e-10 (relative, 0.3) inside the event where the margin is d: slope ~ 1 per unit K
    m_K = mp_margin(design.K)
    assert d <= m_K <= d + 1e-9
    np.testing.assert_allclose(design.margin, m_K, rtol=1e-12)


def test_window_from_d_min() -> None:
    """``delays = (0.5, 0.9)``: 0.3 is stable on the window (its margin is 0.948), so it is the design."""
    design = best_decay_rate(LOOP, BOUNDS, delays=(0.5, 0.9))
    assert design.kind == "finite time" and design.K == RHO and design.value == np.inf
    assert mp_margin(RHO) > 0.9 and all(w.stable for w in design.windows)


def test_kernels_cancelling_to_rounding_only_are_refused() -> None:
    """The kernel of ``A`` is ``0.3 v`` computed as ``3 v / 10`` (1e-17 off ``0.3 v`` at two nodes): at ``K = 0.3``
    the nominal loop is ``1`` plus a residue kernel, one term up to rounding only; the rate about 0.3 is the
    closed form of ``1 + (K - 0.3) e^{-2s}``, unbounded, so no sampled maximum is the design."""
    nodes = np.array([0.0, 0.5, 1.0, 1.5, 2.0])
    v = np.array([0.1, 0.07, 0.13, 0.11, 0.05])
    m = v * 3.0 / 10.0
    assert np.any(m != RHO * v) and np.all(np.abs(m - RHO * v) <= 1e-16)
    A = QuasiPolynomial([[1.0], [-RHO]], [0.0, 2.0], [DistributedDelay(nodes, m)])
    R = QuasiPolynomial([[1.0]], [2.0], [DistributedDelay(nodes, -v)])
    loop = AffineGainLoop(A, QuasiPolynomial([[0.0]], [0.0]), R)
    with pytest.raises(CertificationError, match=r"grows without bound toward K = 0\.3"):
        best_decay_rate(loop, BOUNDS, margin_at_least=1.0)


def test_gain_whose_coefficient_is_outweighed() -> None:
    """``1 + (-300 + 0.001 K) e^{-2s}``: the coefficient of ``K`` is 3e5 times smaller than the constant part, and
    ``0.001 * 300000.0`` rounds to 300 exactly: the loop is the constant 1 at ``K = 300000``, the design."""
    loop = AffineGainLoop(
        QuasiPolynomial([[1.0]], [0.0]), QuasiPolynomial([[-300.0]], [2.0]), QuasiPolynomial([[0.001]], [2.0])
    )
    design = best_decay_rate(loop, (299999.5, 300000.5), margin_at_least=1.0)
    assert design.kind == "finite time" and design.K == 300000.0 and design.value == np.inf
    np.testing.assert_array_equal((loop.A + loop.B(design.K))(S), np.ones(S.size))


def test_margin_objective_against_the_oracle() -> None:
    """``objective="margin"`` does not go through the decay-rate search: its optimum is the oracle's margin there,
    and no larger than the oracle's at gains ``10^-3`` on either side."""
    design = best_margin(LOOP, BOUNDS)
    m_K = mp_margin(design.K)
    np.testing.assert_allclose(design.value, m_K, rtol=1e-12)  # the margin to the rounding of the loop (1e-15)
    assert m_K >= max(mp_margin(design.K - 1e-3), mp_margin(design.K + 1e-3))


def test_search_ending_below_its_sample_is_refused() -> None:
    """``F(.; 0, p) = (1 - p) + 0.1 p e^{-2s} + 0.01 e^{-3s}``: at ``p = 1`` the leading coefficient vanishes and the
    rate is ``ln 10 = 2.302585`` (``e^{-2s} (0.1 + 0.01 e^{-s})``), about it the loop is unstable (roots with
    ``|e^{-2s}| = |1 - p| / (0.1 p)`` small): its difference operator is not strongly stable for
    ``0.9 <= p <= 1.01 / 0.9``, and the bounds ``(0.25, 1.75)`` are refused before any sample is taken."""
    loop = AffineLoop(
        QuasiPolynomial([[1.0]], [0.0]),
        QuasiPolynomial([[-1.0], [0.1]], [0.0, 2.0]),
        QuasiPolynomial([[0.01]], [3.0]),
        QuasiPolynomial([[0.0]], [0.0]),
    )
    with pytest.raises(ParameterError, match=r"bounds.*not on \[0\.9, 1\.12222222222\]"):
        best_decay_rate(loop, (0.25, 1.75), margin_at_least=0.1)
