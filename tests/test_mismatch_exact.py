"""Mismatched loops of ``U_BS2(K)`` on a coupled plant proven about the PDE under the true law.

Oracle, written here and sharing no code with the exact route: the Laplace-domain solution of the perturbed
plant ``u_t + lam' u_x = sigma_pm v``, ``v_t - mu' v_x = sigma_mp u``, ``u(t, 0) = q v(t, 0)``,
``v(t, 1) = rho u(t, 1) + U(t - delta)`` with ``U = -K u(t, 1) + int_0^1 g_u u + g_v v dx``: with
``v(0) = 1`` the state is ``e^{x M(s)} (q, 1)``, ``M = [[-s/lam', b], [c, s/mu']]`` (``b = sigma_pm/lam'``,
``c = -sigma_mp/mu'``), in the closed form ``e^{x M} = e^{x a/2} (cosh(x r) I + sinh(x r)/r [[-h, b], [c, h]])``
(``a = tr M``, ``h = (s/lam' + s/mu')/2``, ``r^2 = h^2 + b c``), and the loop is
``A_o + B_o e^{-delta s}`` with ``A_o = v(1) - rho u(1)`` and ``B_o = K u(1) - int g . w dx`` (40 digits,
mpmath quadrature). The crossing frequencies solve ``|A_o(i w)| = |B_o(i w)|`` (a scan, then ``findroot``) and
the margin is the least ``arg(-B_o/A_o) / w`` over them (mod ``2 pi``).

The gains ``g`` are the true traces of eq. (53) on the NOMINAL plant: the kernel route's traces on 801 and
1601 points extrapolated at the nodes the grids share (observed order 2.00 on both plants: the differences
801/1601 are 4.00 times those 401/801), fitted by a Chebyshev polynomial of degree 40 (least squares on the
801 nodes). Their accuracy is checked against the nominal loop identity
``e^{-s/mu} (A_o + B_o) = 1 - (rho - K) q e^{-tau s}`` (the target system of ``U_BS2(K)``, no kernel): it holds
to 1e-12 (paper's plant) and 1e-13 (second plant). The oracle margins, 0.2261608516101 (paper's plant) and
4.891588641083 (second plant) at ``(e_lam, e_mu) = (0.03, -0.02)``, move by 2e-12 and 1.3e-11 when the traces
are extrapolated from 401 and 801 points instead, and by 1e-12 and 3e-12 with the traces of 1601 points alone:
the tests take twice the latter as the oracle's error (the extrapolated traces, of fourth order, are better than
those of 1601 points by far more than that), below the proven balls' distances to the oracle (widths 6.1e-10 and
4.0e-11: the traces, solved by collocation, are enclosed within 4.1e-12 and 1.1e-13; fitted to the kernel
route's traces on 201 points they were enclosed within 2.9e-5 and 9.7e-8, and the balls were 4e-3 and 3.5e-5
wide). The kernel route's balls (widths 1e-13) miss the oracle by 8e-11 and 2.2e-9.
"""

from __future__ import annotations

import dataclasses
from functools import lru_cache
from typing import Any

import mpmath as mp
import numpy as np
import pytest

from nrobust import Hyperbolic2x2
from nrobust.hyperbolic.analyses import mismatch_loop, mismatch_region
from nrobust.hyperbolic.analyses.mismatch_traces import gain_error_terms, trace_enclosure
from nrobust.hyperbolic.kernels.constant import solve_kernels
from nrobust.hyperbolic.loops.controllers import ReflectionController
from nrobust.margins import delay_margin

pytest.importorskip("flint")

PAPER = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
SECOND = Hyperbolic2x2(1.0, 2.0, 0.4, 0.5, 1.0, 0.3)
K = 0.1
E_LAM, E_MU = 0.03, -0.02
DEGREE = 40


def _perturbed(system: Hyperbolic2x2) -> Hyperbolic2x2:
    return dataclasses.replace(system, lam=system.lam * (1.0 + E_LAM), mu=system.mu * (1.0 + E_MU))


@lru_cache(maxsize=4)
def _traces(system: Hyperbolic2x2, extrapolated: bool) -> tuple[tuple[Any, ...], tuple[Any, ...]]:
    """Chebyshev coefficients (mpf) of ``g_u``, ``g_v`` on ``[0, 1]``: the traces of 1601 points, or those of 801
    and 1601 extrapolated to second order, at the nodes the two grids share (no interpolation error), fitted by
    least squares on those 801 points."""
    nodes = np.linspace(0.0, 1.0, 801)
    coarse, fine = (ReflectionController(K).feedback_law(system, solve_kernels(system, n)) for n in (801, 1601))
    out = []
    for name in ("gain_u", "gain_v"):
        g1, g2 = (np.asarray(getattr(law, name)(nodes), dtype=float) for law in (coarse, fine))
        values = g2 + (g2 - g1) / 3.0 if extrapolated else g2
        coefs = np.polynomial.chebyshev.chebfit(2 * nodes - 1, values, DEGREE)
        out.append(tuple(mp.mpf(float(c)) for c in coefs))
    return out[0], out[1]


def _cheb(coefs: tuple[Any, ...], x: Any) -> Any:
    y = 2 * x - 1
    b1 = b2 = mp.mpf(0)
    for c in reversed(coefs[1:]):
        b1, b2 = 2 * y * b1 - b2 + c, b1
    return y * b1 - b2 + coefs[0]


def _state(plant: Hyperbolic2x2, s: Any, x: Any) -> tuple[Any, Any]:
    """``(u, v)(x, s)`` with ``v(0) = 1`` (module notes)."""
    lam, mu, q = mp.mpf(plant.lam), mp.mpf(plant.mu), mp.mpf(plant.q)
    b, c = mp.mpf(plant.sigma_pm) / lam, -mp.mpf(plant.sigma_mp) / mu
    a, h = s / mu - s / lam, (s / lam + s / mu) / 2
    r = mp.sqrt(h * h + b * c)
    grow, ch = mp.exp(x * a / 2), mp.cosh(x * r)
    sh = mp.sinh(x * r) / r if r != 0 else x
    return grow * (ch * q + sh * (-h * q + b)), grow * (ch + sh * (c * q + h))


def _factors(plant: Hyperbolic2x2, gains: tuple[tuple[Any, ...], tuple[Any, ...]], s: Any) -> tuple[Any, Any]:
    """``(A_o, B_o)`` of the law ``U = -K u(t, 1) + int g . w`` on ``plant`` at ``s``."""
    u1, v1 = _state(plant, s, mp.mpf(1))

    def integrand(x: Any) -> Any:
        u, v = _state(plant, s, x)
        return _cheb(gains[0], x) * u + _cheb(gains[1], x) * v

    integral = mp.quad(integrand, [0, 0.25, 0.5, 0.75, 1])
    return v1 - mp.mpf(plant.rho) * u1, mp.mpf(K) * u1 - integral


def _float_factors(plant: Hyperbolic2x2, gains: tuple[tuple[Any, ...], tuple[Any, ...]], w: np.ndarray) -> Any:
    """``(A_o, B_o)`` at ``s = i w`` in floating point (the same formulas, 200-point Gauss-Legendre): the scan."""
    lam, mu, q = plant.lam, plant.mu, plant.q
    b, c = plant.sigma_pm / lam, -plant.sigma_mp / mu
    x, weights = np.polynomial.legendre.leggauss(200)
    x, weights = 0.5 * (x + 1.0), 0.5 * weights
    s = 1j * np.asarray(w, dtype=float)[:, None]
    a, h = s / mu - s / lam, (s / lam + s / mu) / 2
    r = np.sqrt(h * h + b * c)

    def state(x: Any) -> tuple[Any, Any]:
        grow, ch, sh = np.exp(x * a / 2), np.cosh(x * r), np.sinh(x * r) / r
        return grow * (ch * q + sh * (-h * q + b)), grow * (ch + sh * (c * q + h))

    u1, v1 = state(np.ones(1))
    u, v = state(x[None, :])
    g_u, g_v = (np.polynomial.chebyshev.chebval(2 * x - 1, [float(c) for c in g]) for g in gains)
    integral = (g_u * u + g_v * v) @ weights
    return (v1 - plant.rho * u1)[:, 0], (K * u1)[:, 0] - integral


def _margin(plant: Hyperbolic2x2, gains: tuple[tuple[Any, ...], tuple[Any, ...]]) -> float:
    """The least delay with a root on the axis: the crossings of ``|A_o| = |B_o|`` located by a scan of ``w`` in
    ``(0, 80]`` in floating point (beyond, ``|B_o / A_o|`` stays below 0.8: checked on ``[80, 400]``), the one of
    least delay (and any within 1e-3 of it) refined at 40 digits."""
    ws = np.linspace(1e-3, 80.0, 16001)
    A, B = _float_factors(plant, gains, ws)
    far_A, far_B = _float_factors(plant, gains, np.linspace(80.0, 400.0, 3201))
    assert np.max(np.abs(far_B / far_A)) < 0.8
    gap = np.abs(A) ** 2 - np.abs(B) ** 2
    cut = np.flatnonzero(gap[:-1] * gap[1:] < 0)
    assert cut.size
    rough = np.mod(np.angle(-B[cut] / A[cut]), 2 * np.pi) / ws[cut]
    with mp.workdps(40):

        def gap40(w: Any) -> Any:
            A, B = _factors(plant, gains, mp.mpc(0, w))
            return abs(A) ** 2 - abs(B) ** 2

        delays = []
        for i in cut[rough < rough.min() + 1e-3]:
            w = mp.findroot(gap40, (mp.mpf(ws[i]), mp.mpf(ws[i + 1])), solver="anderson")
            A, B = _factors(plant, gains, mp.mpc(0, w))
            delays.append(mp.fmod(mp.arg(-B / A) + 2 * mp.pi, 2 * mp.pi) / w)
        return float(min(delays))


# the oracle's self-check: once in the quick suite, the paper plant's (11 s) under make fuzz
@pytest.mark.parametrize("system", [pytest.param(PAPER, marks=pytest.mark.long), SECOND], ids=["paper", "second"])
def test_oracle_traces_satisfy_the_nominal_loop_identity(system: Hyperbolic2x2) -> None:
    """The oracle's traces close the nominal loop on the target system: ``e^{-s/mu} (A_o + B_o) = 1 - (rho - K)
    q e^{-tau s}`` to within 1e-10 at ``s = 0, 2i, 7i, 1 + 3i`` (measured at most 1e-12); the other plant's traces
    miss it by 0.66 and 1.3."""
    gains = _traces(system, True)
    with mp.workdps(20):
        for s in (mp.mpc(0, 0), mp.mpc(0, 2), mp.mpc(0, 7), mp.mpc(1, 3)):
            A, B = _factors(system, gains, s)
            target = 1 - (system.rho - K) * system.q * mp.exp(-s * (1 / mp.mpf(system.lam) + 1 / mp.mpf(system.mu)))
            assert abs(mp.exp(-s / system.mu) * (A + B) - target) < 1e-10
        other = _traces(SECOND if system is PAPER else PAPER, True)
        A, B = _factors(system, other, mp.mpc(0, 2))
        target = 1 - (system.rho - K) * system.q * mp.exp(-2j * (1 / mp.mpf(system.lam) + 1 / mp.mpf(system.mu)))
        assert abs(mp.exp(-2j / system.mu) * (A + B) - target) > 1e-3


@pytest.mark.parametrize("system", [PAPER, SECOND], ids=["paper", "second"])
def test_error_terms_hold_the_fits_distance_to_the_traces(system: Hyperbolic2x2) -> None:
    """On the perturbed plant, ``|I_h(i w) - I_g(i w)|`` (the law's term with the Chebyshev fits ``h`` and with the
    oracle's traces ``g``, both by the oracle's quadrature) is at most the two error terms' radii times their
    lengths, the bound of their integrals on ``Re s = 0``; the bound is not loose by more than a factor 1e3
    (measured 28 on the paper's plant, 4 on the second: ``9.9e-13`` and ``9.5e-14`` against ``2.8e-11`` and
    ``4.0e-13``, the distance measured through the oracle's traces, themselves within about ``1e-12``)."""
    enclosure = trace_enclosure(system, K)
    plant = _perturbed(system)
    terms = gain_error_terms(enclosure, plant)
    bound = sum(d.radius * (d.b - d.a) for d in terms)
    h = tuple(tuple(mp.mpf(float(c)) for c in gain.coefficients) for gain in (enclosure.law.g_u, enclosure.law.g_v))
    g = _traces(system, True)
    worst = 0.0
    with mp.workdps(20):
        for w in (0.0, 1.0, 5.0, 20.0):
            s = mp.mpc(0, w)
            worst = max(worst, float(abs(_factors(plant, h, s)[1] - _factors(plant, g, s)[1])))
    assert worst <= bound < 1e3 * worst


@pytest.mark.slow
@pytest.mark.parametrize("system", [PAPER, pytest.param(SECOND, marks=pytest.mark.long)], ids=["paper", "second"])
def test_proven_margin_holds_the_pde_margin(system: Hyperbolic2x2) -> None:
    """The margin of ``mismatch_loop(..., rigorous=True)`` proven in ball arithmetic contains the PDE's margin under
    the true law (the oracle), with the oracle's error (the change between two trace sets, times 2) to spare,
    and is narrower than ``2e-9`` (paper, measured ``6.1e-10``) and ``2e-10`` (second, ``4.0e-11``): before the
    traces were solved by collocation, ``4e-3`` and ``3.5e-5``."""
    plant = _perturbed(system)
    oracle = _margin(plant, _traces(system, True))
    spread = 2.0 * abs(_margin(plant, _traces(system, False)) - oracle) + 1e-13
    A, B = mismatch_loop(system, ReflectionController(K), E_LAM, E_MU, rigorous=True)
    dm = delay_margin(A, B, rigorous=True)
    lo, hi = dm.margin_ball
    # the loop as built has tau rounded: the plant's margin is r times it, |r - 1| < 1e-15 (far inside)
    assert lo * (1 + 1e-15) < oracle - spread and oracle + spread < hi * (1 - 1e-15)
    assert hi - lo < {"paper": 2e-9, "second": 2e-10}["paper" if system is PAPER else "second"]


@pytest.mark.slow
def test_region_is_proven_about_the_pde() -> None:
    """``mismatch_region(..., rigorous=True)`` of ``U_BS2(0.1)`` on the second plant: the exact route, its scope
    says the PDE itself with the traces' bound, and the margin at ``(0.03, -0.02)`` is the oracle's within the
    proven ball's width."""
    region = mismatch_region(SECOND, ReflectionController(K), [E_LAM], [E_MU], 0.05, rigorous=True)
    assert region.route == "exact"
    assert region.scope.startswith("the PDE itself")
    assert "Chebyshev polynomials (trace_enclosure" in region.scope
    assert "as computed in floating point" in region.scope
    assert f"{trace_enclosure(SECOND, K).error:.1e}" in region.scope
    oracle = _margin(_perturbed(SECOND), _traces(SECOND, True))
    assert abs(region.margins[0, 0] - oracle) < 1e-4
    floating = mismatch_region(SECOND, ReflectionController(K), [E_LAM], [E_MU], 0.05)
    assert floating.route == "kernels" and "rigorous=True takes the exact route" in floating.scope


def test_a_proven_margin_tolerates_by_its_ball() -> None:
    """``tolerates`` reads a proven margin by its ball's lower end: a ball reaching below ``delta_max`` is not
    admissible, whatever its midpoint (the margin of ``s + 1 + 2 e^{-delta s}`` is ``arccos(-1/2) / sqrt(3)``)."""
    import dataclasses as dc
    import math

    from nrobust import QuasiPolynomial
    from nrobust.margins.admissible import tolerates

    dm = delay_margin(QuasiPolynomial([[1.0, 1.0]], [0.0]), QuasiPolynomial([[2.0]], [0.0]), rigorous=True)
    exact = math.acos(-0.5) / math.sqrt(3.0)
    assert dm.margin_ball[0] <= exact <= dm.margin_ball[1]
    assert tolerates(dm, exact - 1e-9)
    wide = dc.replace(dm, margin_ball=(exact - 1e-3, exact + 1e-3))
    assert not tolerates(wide, exact - 1e-4) and tolerates(wide, exact - 2e-3)


def test_speed_tolerance_corners_are_proven_about_the_pde() -> None:
    """The corners of ``speed_tolerance(..., rigorous=True)`` under ``U_BS2(K)`` on a coupled plant are proven on the
    exact loops of the true law (the square's proof cut to one box: the corners' certificate); the scope says that
    the other points are the kernel route's and that the corners' proofs hold with ``tau`` rounded."""
    from nrobust.hyperbolic.analyses import speed_tolerance

    result = speed_tolerance(SECOND, ReflectionController(K), 0.03, (0.0, 1.0), grid=2, rigorous=True, max_boxes=1)
    assert result.met and result.certified == "proven at the corners" and result.route == "exact"
    assert all(w.certified == "proven" for w in result.windows[:4])
    assert result.scope.startswith("the corners: the PDE itself")
    assert "not mapped to the exact tau" in result.scope and "the kernel route" in result.scope


def test_state_feedback_with_ball_gains_is_mapped_to_each_perturbed_plant() -> None:
    """A ``StateFeedback`` whose gains evaluate in ball arithmetic takes the exact route at every mismatch, and each
    proven margin is mapped to the exact round trip of its perturbed plant: the region's margin is ``r`` times the
    margin of the loop as built (``r = tau / tau_d`` of ``lam' = 1.03``, ``mu' = 1.96``, not 1)."""
    from fractions import Fraction

    from nrobust.hyperbolic.loops.controllers import StateFeedback, loop_factors
    from nrobust.hyperbolic.loops.exact_form import tau_ratio

    law = StateFeedback(-0.4, lambda x: 0.3 * np.exp(x), lambda x: -0.3 * (1 + x**2))  # margin 0.368 there
    region = mismatch_region(SECOND, law, [E_LAM], [E_MU], 0.05, rigorous=True)
    assert region.route == "exact" and "Taylor models" in region.scope and "given_plant_scale" in region.scope
    plant = _perturbed(SECOND)
    r = tau_ratio(plant)
    assert r != 1
    built = delay_margin(*loop_factors(plant, law), rigorous=True)
    assert region.margins[0, 0] == pytest.approx(float(Fraction(built.margin) * r), rel=0, abs=1e-15)


def test_the_kernel_grid_of_the_traces_is_deprecated() -> None:
    """``trace_enclosure(..., kernel_grid)`` and ``reflection_traces(..., kernel_grid)`` still run, warn, and give the
    traces solved by collocation (the grid is not used)."""
    from nrobust.hyperbolic.analyses.mismatch_traces import reflection_traces

    with pytest.warns(DeprecationWarning, match="kernel_grid is deprecated"):
        old = trace_enclosure(SECOND, K, 201)
    assert old == trace_enclosure(SECOND, K)
    with pytest.warns(DeprecationWarning, match="kernel_grid is deprecated"):
        law, bound = reflection_traces(SECOND, K, 401)
    assert (law, bound) == (old.law, old.error)
