"""Delay form (39) against the kernel-free boundary function.

Two independent routes to the open-loop characteristic function: the kernels give
``1 - rho q e^{-tau s} + int N~ e^{-nu s}``; the Laplace-transformed PDE gives
``e^{-s/mu} (v(1, s) - rho u(1, s))`` with ``[u; v](0) = [q; 1]``, without any kernel.
"""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest

from nrobust import (
    DelayForm,
    DistributedDelay,
    Hyperbolic2x2,
    ParameterError,
    QuasiPolynomial,
    TransportSystem,
    boundary_function,
    delay_form,
    find_roots,
    solve_kernels,
)
from nrobust.hyperbolic.loops.laplace import magnus_steps

PAPER = Hyperbolic2x2(lam=1.0, mu=1.0, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)
VARYING = Hyperbolic2x2(1.0, 2.5, lambda x: 1.0 + 0.5 * np.sin(3.0 * x), lambda x: 2.0 * np.exp(-x), 0.7, 0.85)

# Frequencies of the identity check: |Im s| up to 200, on both sides of the axis.
S_GRID = (np.linspace(-2.0, 3.0, 6)[:, None] + 1j * np.linspace(-200.0, 200.0, 33)[None, :]).ravel()


# --------------------------------------------------------------------------- transport
def test_transport_delay_form_is_the_difference_equation():
    system = TransportSystem(lam=1.0, mu=2.0, q=1.5, rho=0.9)
    form = delay_form(system)
    assert form.tau == pytest.approx(1.5, rel=1e-13, abs=1e-14) and form.rho_q == pytest.approx(
        1.35, rel=1e-13, abs=1e-14
    )
    assert not np.any(form.N_tilde.values) and form.characteristic.distributed == ()
    s = S_GRID[:20]
    np.testing.assert_allclose(form.characteristic(s), 1.0 - 1.35 * np.exp(-1.5 * s), rtol=0, atol=1e-14)
    np.testing.assert_allclose(boundary_function(system, s, scaled=True), form.characteristic(s), rtol=0, atol=1e-12)


def test_transport_roots_lie_on_ln_rho_q_over_tau():
    """The chain of 1 - rho q e^{-tau s} has real part ln(rho q)/tau (not ln(rho q)/(2 tau))."""
    system = TransportSystem(lam=1.0, mu=2.0, q=1.5, rho=0.9)
    roots = find_roots(delay_form(system).characteristic, (-1.0, 1.0, -30.0, 30.0))
    assert roots.certified and roots.count == 15  # Im = 2 pi k / 1.5, |k| <= 7
    # Newton-polished simple roots, |s| <= 30: rounding only (measured: exact, 2.7e-15 on spacings)
    np.testing.assert_allclose(roots.roots.real, np.log(1.35) / 1.5, rtol=0, atol=1e-13)
    np.testing.assert_allclose(np.diff(np.sort(roots.roots.imag)), 2 * np.pi / 1.5, rtol=0, atol=1e-13)


# --------------------------------------------------------------------------- structure
def test_structure_of_n_tilde():
    form = delay_form(VARYING, kernel_grid=51)
    nodes = form.N_tilde.nodes
    assert nodes[0] == 0.0 and nodes[-1] == pytest.approx(VARYING.tau, abs=1e-15)
    jump = np.flatnonzero(np.diff(nodes) == 0)
    np.testing.assert_array_equal(nodes[jump], [1.0 / VARYING.mu])  # one jump, on a node
    # the two branches of (40), the N^alpha branch carrying the factor q
    assert form.N_tilde.values[jump[0]] == pytest.approx(VARYING.mu * form.N_beta[0], rel=1e-13, abs=1e-14)
    assert form.N_tilde.values[jump[0] + 1] == pytest.approx(
        VARYING.lam * VARYING.q * form.N_alpha[0], rel=1e-13, abs=1e-14
    )
    nu = np.array([0.0, 0.1, 1.0 / VARYING.mu, 0.9, VARYING.tau])
    np.testing.assert_allclose(
        form.N_tilde_at(nu),
        np.interp(nu, nodes[jump[0] + 1 :], form.N_tilde.values[jump[0] + 1 :]) * (nu >= 0.4)
        + np.interp(nu, nodes[: jump[0] + 1], form.N_tilde.values[: jump[0] + 1]) * (nu < 0.4),
        rtol=1e-14,
        atol=0,
    )
    assert isinstance(form.characteristic, QuasiPolynomial) and isinstance(form.N_tilde, DistributedDelay)


def test_n_alpha_n_beta_from_inverse_kernels():
    kernels = solve_kernels(PAPER, kernel_grid=101)
    form = delay_form(PAPER, kernels=kernels)
    np.testing.assert_allclose(
        form.N_alpha, kernels.Lba(1.0, kernels.grid) - 0.85 * kernels.Laa(1.0, kernels.grid), rtol=1e-14, atol=0
    )
    np.testing.assert_allclose(
        form.N_beta, kernels.Lbb(1.0, kernels.grid) - 0.85 * kernels.Lab(1.0, kernels.grid), rtol=1e-14, atol=0
    )
    np.testing.assert_allclose(form.N_alpha_at([0.0, 1.0]), form.N_alpha[[0, -1]], rtol=1e-14, atol=0)
    np.testing.assert_allclose(form.N_beta_at(0.5), form.N_beta[50], rtol=1e-14, atol=0)


def test_closed_form_n_tilde_when_sigma_mp_vanishes():
    """sigma_mp = 0: L^{aa}, L^{ab} constant, so N~ = -rho mu sigma_pm / (lam + mu) on [0, tau]."""
    system = Hyperbolic2x2(1.0, 2.5, 1.3, 0.0, 0.7, 0.85)
    form = delay_form(system, kernel_grid=201)
    # kernel grid n = 201 (discretisation, not rounding): measured 6.9e-7
    np.testing.assert_allclose(form.N_tilde.values, -0.85 * 2.5 * 1.3 / 3.5, rtol=0, atol=1e-6)


def test_repr_to_dict_and_validation():
    form = delay_form(PAPER, kernel_grid=21)
    assert isinstance(form, DelayForm) and repr(form).startswith("DelayForm(system=Hyperbolic2x2(")
    data = json.loads(json.dumps(form.to_dict()))
    assert data["tau"] == 2.0 and len(data["N_alpha"]) == 21
    with pytest.raises(ParameterError):
        form.N_tilde_at(2.5)
    with pytest.raises(ParameterError):
        form.N_alpha_at(-0.1)
    with pytest.raises(ParameterError):
        delay_form(PAPER, kernels=solve_kernels(VARYING, kernel_grid=11))
    with pytest.raises(ParameterError):
        boundary_function(PAPER, np.nan)


# --------------------------------------------------------------------------- boundary function
def test_boundary_function_transport_closed_form():
    system = TransportSystem(lam=2.0, mu=0.5, q=-0.7, rho=1.2)
    s = S_GRID[::7] / 10
    expected = np.exp(s / 0.5) - 1.2 * (-0.7) * np.exp(-s / 2.0)
    np.testing.assert_allclose(boundary_function(system, s), expected, rtol=1e-12)


def test_magnus_route_fourth_order_and_default_accuracy():
    s = S_GRID
    values = [boundary_function(VARYING, s, scaled=True, steps=m) for m in (200, 400, 800, 1600)]
    diffs = [np.abs(a - b).max() for a, b in itertools.pairwise(values)]
    assert np.all(np.log2(np.array(diffs[:-1]) / np.array(diffs[1:])) >= 3.5), diffs
    default = boundary_function(VARYING, s, scaled=True)
    assert magnus_steps(VARYING, s) >= 1400
    assert np.abs(default - values[-1]).max() < 5e-9


def test_magnus_route_matches_closed_form_on_constant_couplings():
    """A callable constant coupling takes the Magnus route; it must agree with the exponential."""
    as_callables = Hyperbolic2x2(1.0, 2.5, lambda x: 1.3 + 0 * x, lambda x: 0.6 + 0 * x, 0.7, 0.85)
    constant = Hyperbolic2x2(1.0, 2.5, 1.3, 0.6, 0.7, 0.85)
    s = S_GRID[::3]
    np.testing.assert_allclose(
        boundary_function(as_callables, s, scaled=True, steps=200),
        boundary_function(constant, s, scaled=True),
        rtol=0,
        atol=1e-11,  # rounding over 200 Magnus steps, values up to 11: measured 4.6e-13
    )


# --------------------------------------------------------------------------- identity
@pytest.mark.parametrize("system", [PAPER, VARYING], ids=["paper", "varying"])
def test_laplace_identity_converges(system):
    """int N~ e^{-nu s} = e^{-s/mu} (v(1,s) - rho u(1,s)) - 1 + rho q e^{-tau s}, |Im s| <= 200.

    With the cubic-spline N~ the kernels set the error, at third order: measured with
    n = 51, 101, 201, 401: 1.3e-6, 1.6e-7, 1.9e-8, 2.3e-9 (paper) and 1.2e-4, 1.5e-5,
    1.9e-6, 2.4e-7 (varying); the bound 8e-6 at n = 201 leaves ~4x.
    """
    exact = boundary_function(system, S_GRID, scaled=True) - 1.0 + system.rho_q * np.exp(-system.tau * S_GRID)
    errors = [np.abs(delay_form(system, kernel_grid=n).N_tilde(S_GRID) - exact).max() for n in (51, 101, 201)]
    assert errors[-1] < 8e-6, errors
    assert np.all(np.log2(np.array(errors[:-1]) / np.array(errors[1:])) >= 1.8), errors


# --------------------------------------------------------------------------- spectrum
def newton(f, z: np.ndarray, steps: int = 12, h: float = 1e-6) -> np.ndarray:
    for _ in range(steps):
        z = z - f(z) / ((f(z + h) - f(z - h)) / (2 * h))
    return z


def winding_number(f, box, step: float = 0.02) -> int:
    """Zeros of ``f`` in the rectangle by the argument principle on dense samples."""
    re_min, re_max, im_min, im_max = box
    corners = [complex(re_min, im_min), complex(re_max, im_min), complex(re_max, im_max), complex(re_min, im_max)]
    path = []
    for a, b in zip(corners, corners[1:] + corners[:1]):
        m = int(np.ceil(abs(b - a) / step))
        path.append(a + (b - a) * np.arange(m) / m)
    values = f(np.append(np.concatenate(path), corners[0]))
    turns = np.angle(values[1:] / values[:-1])
    assert np.abs(turns).max() < np.pi / 4  # the samples resolve the argument
    return round(turns.sum() / (2 * np.pi))


@pytest.mark.parametrize(
    "system, box, count",
    [(PAPER, (-1.0, 2.0, -40.0, 40.0), 25), (VARYING, (-1.5, 2.0, -60.0, 60.0), 27)],
    ids=["paper", "varying"],
)
def test_open_loop_spectrum_two_routes(system, box, count):
    """Certified roots of the delay form = zeros of the kernel-free boundary function.

    Roots of the delay form converge to those of the boundary function at third order
    (cubic N~, extrapolated kernels): with n = 101, 201, 401 the measured gaps are
    2.0e-9, 2.5e-10, 3.1e-11 (paper) and 2.7e-6, 3.4e-7, 4.2e-8 (varying); the
    tolerance 2e-6 at n = 201 leaves a margin of about 6.
    """
    form = delay_form(system, kernel_grid=201)
    found = find_roots(form.characteristic, box)
    assert found.certified and found.count == count and np.all(found.multiplicities == 1)
    assert found.roots.real.max() > 0.5  # the paper's open loop is unstable
    G = lambda s: boundary_function(system, s, scaled=True)  # noqa: E731
    refined = newton(G, found.roots)
    assert np.abs(refined - found.roots).max() < 2e-6
    assert np.abs(G(refined)).max() < 1e-9
    # Completeness on the boundary-function side: the winding number of G along the
    # searched rectangle (dense samples, each step turning by less than pi/4) equals the
    # certified count of the delay form.
    assert winding_number(G, found.region) == found.count
