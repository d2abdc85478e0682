"""Decay-rate designs that reach a gain where the nominal loop converges in finite time.

For ``U_BS2(K)`` (eq. (53)) the loop at ``delta = 0`` is the target system ``1 - (rho - K) q e^{-tau s}``
(eqs. (56)-(58)) under the state feedback and under either observer replaying the commands undelayed,
so its decay rate is ``-ln|(rho - K) q| / tau``: it grows without bound as ``K -> rho`` and is infinite at
``K = rho`` (``U_BS``, eq. (47): ``F = 1``, no root at all). A design of the largest decay rate under a
delay-margin requirement that ``K = rho`` meets must return that gain, with the kind ``"finite time"``,
not a point a rounding-sized step away called a smooth maximum (the collocated design on
``Hyperbolic2x2(1, 1, 1, 1, 1, 0.3)`` once gave 12.145 there).

Oracles, independent of :mod:`nrobust.design.gain`:

* the closed form of the target system's roots, ``s = (ln|c| + i (arg c + 2 pi k)) / tau`` for
  ``1 - c e^{-tau s}``, and the loops built directly at each gain (:func:`nrobust.characteristic`);
* mpmath at 40 digits: the characteristic function written out here, its root by ``findroot``;
* simulation of the PDE under ``U_BS2(K)`` (characteristics scheme): at ``K = rho`` what is left after
  ``tau`` is the scheme's error (second order in the cell size: finite-time convergence), at
  ``K = rho + 10^-3`` the norm decays at ``-ln(10^-3) / tau``;
* core loops with point delays only, whose decay rates are closed forms.
"""

from __future__ import annotations

import mpmath
import numpy as np
import pytest

import nrobust as nr
from nrobust.design import AffineLoop, best_decay_rate
from nrobust.errors import CertificationError
from nrobust.hyperbolic.analyses.design import ReflectionDesign
from nrobust.hyperbolic.loops.controllers import (
    CollocatedOutputFeedback,
    ReflectionController,
    gain_slope_factors,
    loop_route,
)
from nrobust.margins import AffineGainLoop
from nrobust.quasipoly import QuasiPolynomial

RHO = 0.3
WEAK = nr.Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, RHO)  # q = 1, tau = 2, rho q = 0.3 < 1/2
TAU = 2.0
ZERO = QuasiPolynomial([[0.0]], [0.0])
# points of the right half-plane and of the axis at which the loops are compared with their closed forms
S = np.array([0.0, 0.3 + 1.0j, 2.0j, 1.5 - 7.0j, 0.1 + 40.0j])


def target_rate(K: float) -> float:
    """``-ln|(rho - K) q| / tau``: the decay rate of ``1 - (rho - K) q e^{-tau s}`` (every root has that real part)."""
    return float(-np.log(abs(RHO - K)) / TAU)


def mp_root(c: float, start: complex) -> mpmath.mpc:
    """A root of ``1 - c e^{-tau s}`` near ``start``, at 40 digits."""
    with mpmath.workdps(40):
        return mpmath.findroot(lambda s: 1 - mpmath.mpf(c) * mpmath.exp(-TAU * s), mpmath.mpc(start))


# ------------------------------------------------------------------ a core loop with point delays
def test_core_loop_designs_the_finite_time_gain() -> None:
    """``F = 1 - 0.3 e^{-2s} + K e^{-(2 + delta) s}``: ``|A| >= 0.7 > |K|`` on the axis, so every gain of the
    bounds has an infinite margin, and at ``delta = 0`` the decay rate is ``-ln|K - 0.3| / 2``."""
    loop = AffineGainLoop(QuasiPolynomial([[1.0], [-RHO]], [0.0, TAU]), ZERO, QuasiPolynomial([[1.0]], [TAU]))
    for design in (
        best_decay_rate(loop, (-0.5, 0.6), margin_at_least=1.0),
        best_decay_rate(loop, (-0.5, 0.6), delays=(0.0, 1.0)),
    ):
        assert design.kind == "finite time" and design.K == RHO
        assert design.value == np.inf and design.decay_rate == np.inf and design.value_bracket == (np.inf, np.inf)
        assert design.abscissa.value == -np.inf and design.abscissa.root is None
        assert design.margin == np.inf
        # the loop at the design: the constant 1 (no zero), exactly
        F = loop.A + loop.B(design.K)
        np.testing.assert_array_equal(F(S), np.ones(S.size))
    # about the design the rate is finite and unbounded: the closed form at K = 0.3 +- h
    for h in (1e-3, -1e-3, 1e-6, -1e-6):
        rate = -nr.spectral_abscissa(loop.A + loop.B(RHO + h)).value
        # the loop's coefficient RHO + h - RHO is h to rounding of 0.3 (1e-16), relative 1e-10 at h = 1e-6
        np.testing.assert_allclose(rate, target_rate(RHO + h), rtol=1e-9)


def test_core_loop_one_term_up_to_rounding_is_refused() -> None:
    """``F(.; 0, K) = 1 + (K - a) e^{-2s} + (K - a') e^{-3s}`` with ``a' = a`` + 8 units of rounding: the
    rate grows to about ``-ln(1e-16) / 3`` near ``a`` but no float makes both terms vanish, so no design."""
    a = 0.1
    a_next = a
    for _ in range(8):
        a_next = float(np.nextafter(a_next, 1.0))
    A = QuasiPolynomial([[1.0], [-a], [-a_next]], [0.0, 2.0, 3.0])
    loop = AffineGainLoop(A, ZERO, QuasiPolynomial([[1.0], [1.0]], [2.0, 3.0]))
    with pytest.raises(CertificationError, match=r"grows without bound toward K = 0\.1"):
        best_decay_rate(loop, (0.0, 0.3), margin_at_least=1.0)


# ------------------------------------------------------------------ U_BS2(K) on a coupled plant
@pytest.fixture(scope="module")
def collocated() -> ReflectionDesign:  # 3 s of CPU
    # bounds about rho (default: 0.9 x (-0.4375, 0.8125) from |rho - K| + 2 |K rho| < 1, test_collocated_design)
    return nr.design_reflection(
        WEAK, "decay_rate", margin_at_least=0.05, output_feedback=True, collocated=True, K_bounds=(0.2, 0.4)
    )


def test_collocated_loop_at_rho_has_no_root() -> None:
    """The loop built directly at ``K = rho`` (not the affine model of the design): the target system, 1."""
    F = nr.characteristic(WEAK, CollocatedOutputFeedback(ReflectionController(RHO)), 0.0)
    np.testing.assert_allclose(F(S), 1.0, rtol=0, atol=1e-12)
    assert nr.spectral_abscissa(F).value == -np.inf


@pytest.mark.long
def test_collocated_design_is_u_bs(collocated: ReflectionDesign) -> None:
    assert collocated.K == RHO and collocated.kind == "finite time" and collocated.value == np.inf
    assert isinstance(collocated.controller, CollocatedOutputFeedback)
    assert collocated.design.certificate.margin >= 0.05 and collocated.design.certificate.nominally_stable


def test_the_affine_collocated_loop_is_the_target_system_at_rho() -> None:
    """The design's loop affine in ``K`` (``gain_slope_factors``: the collocated loop is proven here, its point
    coefficients balls): at ``K = rho`` its nominal loop is the target system ``1 - (rho - K) q e^{-tau s}`` (eqs.
    (56)-(58)), the constant 1 with no radius, and one floating-point step away the single term ``(rho - K) q`` at
    ``tau`` is that double exactly. Before the slopes' radii came from exact differences they were the two loops'
    radii added, and ``1 + (0 +- 3.3e-17) e^{-2 s} + (0 +- 3.3e-18) e^{-4 s}`` was no single term."""
    at_zero, at_one = (CollocatedOutputFeedback(ReflectionController(K)) for K in (0.0, 1.0))
    assert loop_route(WEAK, at_one) == "exact"
    loop = AffineLoop(*gain_slope_factors(WEAK, at_zero, at_one))
    F = loop.nominal(RHO)
    assert not F.distributed and [(list(p), t) for p, t in F.point_terms] == [([1.0], 0.0)]
    assert not any(r.any() for r in F.point_radii)
    for K in (np.nextafter(RHO, 1.0), np.nextafter(RHO, 0.0)):
        F = loop.nominal(float(K))
        assert not F.distributed and [(list(p), t) for p, t in F.point_terms] == [([1.0], 0.0), ([K - RHO], TAU)]
        np.testing.assert_allclose(F(S), 1.0 - (RHO - K) * np.exp(-TAU * S), rtol=0, atol=1e-15)


@pytest.mark.long  # 1.5 s of CPU each (the observer's kernels)
@pytest.mark.parametrize("h", [1e-3, -1e-3, 1e-6, -1e-6])
def test_collocated_rate_about_rho_is_the_target_systems(h) -> None:
    """Continuous and unbounded: ``-ln|h| / 2`` at ``K = rho + h`` (6.91 at ``|h| = 10^-6``, 3.45 at ``10^-3``)."""
    K = RHO + h
    F = nr.characteristic(WEAK, CollocatedOutputFeedback(ReflectionController(K)), 0.0)
    c = RHO - K  # q = 1
    # the observer's and the kernels' terms cancel at delta = delta_o = 0: the target system to rounding
    np.testing.assert_allclose(F(S), 1.0 - c * np.exp(-TAU * S), rtol=0, atol=1e-12)
    sa = nr.spectral_abscissa(F)
    np.testing.assert_allclose(-sa.value, target_rate(K), rtol=1e-9)  # c is h to rounding of 0.3: 1e-10 relative
    assert sa.root is not None
    root = mp_root(c, sa.root)
    np.testing.assert_allclose(sa.root, complex(root), rtol=1e-12)


def test_the_old_value_was_the_rate_a_rounding_step_from_rho() -> None:
    """12.14515816371311 was reported at K = 0.300000000028239: the rate there, 2.8e-11 from K = rho."""
    K = 0.300000000028239
    c = RHO - K
    root = mp_root(c, complex(np.log(abs(c)) / TAU, np.pi / TAU))
    # rho - K loses 12 of 16 digits to cancellation: 1e-5 relative in c, 1e-6 in the rate
    np.testing.assert_allclose(-float(root.real), 12.14515816371311, rtol=1e-6)
    np.testing.assert_allclose(target_rate(K), 12.14515816371311, rtol=1e-6)


def test_simulation_converges_in_finite_time_at_rho() -> None:
    """The PDE under ``U_BS2(K)`` (state feedback, ``delta = 0``): at ``K = rho`` the norm after ``tau`` is the
    scheme's error, which falls about 4 times when the cells double; at ``rho + 10^-3`` it decays at
    ``-ln(10^-3) / 2 = 3.4539`` whatever the cells."""

    def norms(K: float, cells: int) -> dict[float, float]:
        sim = nr.simulate(
            WEAK,
            ReflectionController(K),
            0.0,
            5.0,
            lambda x: np.sin(np.pi * x) + 1.0,
            lambda x: x,
            cells,
            snapshot_every=1,
        )
        t, n = np.asarray(sim.times), np.asarray(sim.norm)
        return {T: float(n[np.argmin(np.abs(t - T))]) for T in (0.0, 2.5, 3.0, 5.0)}

    coarse, fine = norms(RHO, 100), norms(RHO, 200)
    assert fine[2.5] < 1e-5 * fine[0.0]
    assert 3.0 < coarse[2.5] / fine[2.5] < 5.0  # second order: the limit of the scheme is 0 after tau
    off = norms(RHO + 1e-3, 200)
    # the measured rate to the scheme's error (1.5e-3 at 200 cells, from the run at 100: 3.4601)
    np.testing.assert_allclose(-np.log(off[5.0] / off[3.0]) / TAU, target_rate(RHO + 1e-3), rtol=2e-3)


@pytest.mark.parametrize("output_feedback", [False, pytest.param(True, marks=pytest.mark.long)])  # 0.2 s, 2 s
def test_state_and_output_feedback_designs_are_u_bs(output_feedback) -> None:
    """The same design without an observer and with the observer from ``v(t, 0)``: ``K = rho`` is inside the
    default bounds (0.99 and 0.9 of ``(1 - |rho q|)/|q| = 0.7``, eq. (54)) and meets the margin."""
    result = nr.design_reflection(WEAK, "decay_rate", margin_at_least=0.05, output_feedback=output_feedback)
    bound = (0.9 if output_feedback else 0.99) * 0.7
    np.testing.assert_allclose(result.design.bounds, (-bound, bound), rtol=1e-14)
    assert result.K == RHO and result.kind == "finite time" and result.value == np.inf
    assert result.design.certificate.margin >= 0.05


@pytest.mark.long
def test_collocated_default_bounds() -> None:
    """The observed case: the default bounds (0.9 of the strong-stability interval, 10 s of CPU)."""
    result = nr.design_reflection(WEAK, "decay_rate", margin_at_least=0.05, output_feedback=True, collocated=True)
    np.testing.assert_allclose(result.design.bounds, (-0.9 * 0.4375, 0.9 * 0.8125), rtol=1e-14)
    assert result.K == RHO and result.kind == "finite time" and result.value == np.inf
