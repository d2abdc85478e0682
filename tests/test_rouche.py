"""Rouché certificates: L1 modulus of continuity, Theorem 4's delay bound, root-free regions."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from nrobust import ParameterError, QuasiPolynomial, delay_margin
from nrobust.bounds import (
    delay_bound_from_kernel,
    l1_modulus,
    root_free_region,
    total_variation,
)
from nrobust.quasipoly import DistributedDelay
from nrobust.roots import count_roots


def kernel() -> DistributedDelay:
    """Piecewise linear with a jump at nu = 1 and non-zero end values (jumps to zero)."""
    return DistributedDelay([0.0, 0.5, 1.0, 1.0, 2.0], [1.0, -0.5, 0.3, 0.8, 0.2])


def smooth_kernel() -> DistributedDelay:
    x1, x2 = np.linspace(0.0, 1.0, 41), np.linspace(1.0, 2.0, 41)
    return DistributedDelay(np.r_[x1, x2], np.r_[0.6 * np.cos(2 * x1) + 0.3, -0.5 + 0.4 * x2])


def _n(d: DistributedDelay, x: float) -> float:
    """Right-continuous evaluation of the interpolant extended by zero (reference)."""
    nodes, vals = d.nodes, d.values
    if x < nodes[0] or x >= nodes[-1]:
        return 0.0
    i = int(np.searchsorted(nodes, x, side="right"))
    x0, x1 = nodes[i - 1], nodes[i]
    return float(vals[i - 1] + (x - x0) / (x1 - x0) * (vals[i] - vals[i - 1]))


@pytest.mark.parametrize("delta", [1e-3, 0.3, 0.5, 1.0, 1.7, 2.5])
def test_l1_modulus_matches_quadrature(delta: float) -> None:
    d = kernel()
    pts = sorted(set(np.r_[d.nodes, d.nodes + delta]))
    ref = quad(lambda x: abs(_n(d, x) - _n(d, x - delta)), -0.5, 5.0, points=pts, limit=400, epsabs=1e-13)[0]
    assert float(l1_modulus(d, delta)) == pytest.approx(ref, rel=1e-9, abs=1e-12)


def test_l1_modulus_properties() -> None:
    d = kernel()
    tv = total_variation(d)
    assert tv == pytest.approx(1.0 + 0.2 + 1.5 + 0.8 + 0.5 + 0.6, rel=1e-13, abs=1e-14)
    deltas = np.linspace(0.0, 3.0, 301)
    om = l1_modulus(d, deltas)
    assert om[0] == 0.0 and np.all(om >= 0)
    assert np.all(om <= deltas * tv + 1e-13)  # omega(delta) <= delta TV
    assert float(l1_modulus(d, 1e-7)) / 1e-7 == pytest.approx(tv, rel=1e-5)  # slope TV at 0
    l1 = quad(lambda x: abs(_n(d, x)), 0.0, 2.0, points=[0.5, 1.0], limit=200)[0]
    assert om[-1] == pytest.approx(2 * l1, rel=1e-10)  # disjoint supports
    for i, j in [(10, 20), (55, 70), (100, 150)]:  # subadditivity
        k = i + j
        assert om[k] <= om[i] + om[j] + 1e-13
    with pytest.raises(ParameterError):
        l1_modulus(d, -0.1)


def test_delay_bound_is_certified_on_the_whole_interval() -> None:
    d = smooth_kernel()
    for eps0 in (0.05, 0.2, 0.6):
        res = delay_bound_from_kernel(d, eps0)
        assert 0 < res.delta_0 < np.inf and res.omega_at_delta_0 < eps0
        dense = l1_modulus(d, np.linspace(0.0, res.delta_0, 2001))
        assert np.max(dense) < eps0
        assert res.delta_0 >= eps0 / total_variation(d)  # at least the Lipschitz bound
    assert delay_bound_from_kernel(None, 0.1).delta_0 == np.inf
    assert delay_bound_from_kernel(d, -0.1).delta_0 == 0.0
    assert "delta_0=" in repr(res) and res.to_dict()["steps"] == res.steps


@pytest.mark.parametrize("rho_q, kq", [(0.85, 0.1), (0.85, 0.05), (0.5, 0.3), (0.3, -0.2)])
def test_rouche_bound_below_exact_margin(rho_q: float, kq: float) -> None:
    """delta_0 of Theorem 4's proof never exceeds the exact delay margin."""
    d = smooth_kernel()
    i_n = QuasiPolynomial([], [], [d])
    A = 1.0 - (QuasiPolynomial([[rho_q]], [2.0]) - i_n)
    B = QuasiPolynomial([[kq]], [2.0]) - i_n
    dm = delay_margin(A, B, verify=False)
    bound = delay_bound_from_kernel(d, 1.0 - abs(rho_q) - abs(kq), kq)
    assert 0 < bound.delta_0 <= dm.margin
    assert dm.is_stable(min(bound.delta_0, dm.delta_max))


def test_root_free_region_retarded() -> None:
    F = QuasiPolynomial([[1.0, 1.0], [0.5]], [0.0, 1.0])  # s + 1 + 0.5 e^{-s}
    cert = root_free_region(F)
    assert cert.degree == 1 and cert.gap == 1.0
    c, R = cert.half_plane, cert.radius
    assert int(count_roots(F, (c, c + 20.0, -20.0, 20.0))) == 0
    assert int(count_roots(F, (0.0, R + 1.0, R, R + 40.0))) == 0
    assert cert.contains(np.array([c + 1e-3, 0.0 + 1j * (R + 1)])).all()
    assert not cert.contains(np.array([0.0 + 0.0j]))[0]
    assert cert.to_dict()["radius"] == R


def test_root_free_region_neutral_with_distributed_term() -> None:
    d = smooth_kernel()
    F = QuasiPolynomial([[1.0], [-0.5]], [0.0, 1.0], [d])
    cert = root_free_region(F, x0=-0.3)
    # the chains of 1 - 0.5 e^{-s} sit at Re s = ln(0.5) = -0.69 < -0.3
    assert cert.gap == pytest.approx(1.0 - 0.5 * np.exp(0.3), rel=1e-13, abs=1e-14)
    R = cert.radius
    assert int(count_roots(F, (-0.3, 2.0, R, R + 60.0))) == 0
    assert int(count_roots(F, (cert.half_plane, cert.half_plane + 10.0, -R - 10, R + 10))) == 0
    with pytest.raises(ParameterError):
        root_free_region(F, x0=-1.0)  # left of the chains: no dominance
    with pytest.raises(ParameterError):
        root_free_region(QuasiPolynomial([[1.0], [0.0, 1.0]], [0.0, 1.0]))  # advanced: s e^{-s} + 1


def test_delay_bound_near_the_paper_bound_and_below_the_spline_correction() -> None:
    """epsilon_0 -> 0 (|K| -> (1 - |rho q|)/|q|): delta_0 -> 0, never an error."""
    from nrobust import Hyperbolic2x2, ReflectionController, rouche_delay_bound

    plant = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
    for K in (0.15 - 1e-15, 0.15 - 1e-9, 0.1499):
        bound = rouche_delay_bound(plant, ReflectionController(K))
        assert 0.0 <= bound.delta_0 < 1e-3
        assert bound.omega_at_delta_0 <= bound.epsilon_0 or bound.delta_0 == 0.0
