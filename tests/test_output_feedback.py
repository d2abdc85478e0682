"""Output feedback from ``v(t, 0)``: the exact predictor's loop and its parts, against independent routes.

The oracle (:func:`literal_predictor`) does what the controller does, literally: for exponential
signals it predicts the output of the delay form on the window by solving the window's
convolution equation with a fine trapezoidal rule (Richardson-extrapolated over two grids), and
applies the law to the measured past and the prediction. It shares the delay form's kernel
``N~`` and the law's loop factor with the code under test, not the resolvent, the window law or
the products (:mod:`nrobust.volterra`). Its measured error: differences of 1e-11 to 6.3e-9 against
the loop at the points below (the largest with unequal speeds, whose window of 2 gets the same 150
and 300 steps), so the tolerance is 2e-8.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from _predictor import kernel_sum as _kernel
from _predictor import literal_predictor

import nrobust as nr
from nrobust.cli import main
from nrobust.config import load_system_file
from nrobust.distributed_delay import DistributedDelay
from nrobust.errors import ParameterError
from nrobust.hyperbolic.analyses.design import design_reflection
from nrobust.hyperbolic.analyses.mismatch import mismatch_loop
from nrobust.hyperbolic.loops.controllers import (
    FilteredController,
    FiniteTimeController,
    OpenLoop,
    OutputFeedback,
    ReflectionController,
    StateFeedback,
    loop_factors,
    loop_route,
    loop_scope,
    observer_of,
)
from nrobust.hyperbolic.loops.output_feedback import observer_term
from nrobust.quasipoly import QuasiPolynomial
from nrobust.volterra import resolvent_product, window_law, window_resolvent

PAPER = nr.Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
#: Unequal speeds: the window 1/mu = 2 is not half the round trip tau = 2.5.
SLOW_V = nr.Hyperbolic2x2(2.0, 0.5, 0.4, 0.7, 0.8, 0.6)
POINTS = (0.3 + 2.0j, -0.1 + 6.2j, 0.05 + 0.7j)


def oracle(plant, controller: OutputFeedback, s, deltas):
    """``A_o + B_o e^{-delta s}`` at each delay from the literal predictor, Richardson over ``M = 150, 300``."""
    inner = controller.controller
    if isinstance(inner, FilteredController):
        unfiltered = FiniteTimeController() if inner.K is None else ReflectionController(inner.K)
        numerator = 1 + inner.a * s
    else:
        unfiltered, numerator = inner, 1.0
    grid = None if loop_route(plant, inner) == "exact" else 201  # the state feedback's route
    open_loop = loop_factors(plant, OpenLoop(), grid)[0]
    law = loop_factors(plant, unfiltered, grid)[1]
    A = loop_factors(plant, inner, grid)[0]
    w = 1.0 / plant.mu
    coarse = literal_predictor(open_loop, law, w, s, 150, controller.observer_delay)
    fine = literal_predictor(open_loop, law, w, s, 300, controller.observer_delay)
    c_z, c_u = ((4 * b - a) / 3 for a, b in zip(coarse, fine))
    return [A(s) - numerator * (open_loop(s) * c_u + c_z * np.exp(-delta * s)) for delta in deltas]


CASES = [
    ("U_BS2(0.1)", PAPER, OutputFeedback(ReflectionController(0.1))),
    ("U_BS", SLOW_V, OutputFeedback(FiniteTimeController())),
    ("filtered U_BS2", PAPER, OutputFeedback(FilteredController(0.02, 0.05, K=0.1))),
    ("observer delay", PAPER, OutputFeedback(ReflectionController(0.1), observer_delay=0.1)),
    ("integral gains", SLOW_V, OutputFeedback(StateFeedback(-0.2, g_u=0.3, g_v=lambda x: 0.2 * x))),
]


@pytest.mark.parametrize(("name", "plant", "controller"), CASES, ids=[c[0] for c in CASES])
def test_loop_is_the_literal_predictor(name, plant, controller):
    A, B = loop_factors(plant, controller)
    for s in POINTS:
        mine = [A(s) + B(s) * np.exp(-delta * s) for delta in (0.0, 0.25)]
        np.testing.assert_allclose(mine, oracle(plant, controller, s, (0.0, 0.25)), rtol=0, atol=2e-8)


def test_exact_at_the_assumed_delay_and_the_target_without_delay():
    s = np.array(POINTS)
    for observer_delay in (0.0, 0.1):
        A, B = loop_factors(PAPER, OutputFeedback(ReflectionController(0.1), observer_delay))
        A0, B0 = loop_factors(PAPER, ReflectionController(0.1))
        np.testing.assert_allclose(
            (A + B.shift(observer_delay))(s), (A0 + B0.shift(observer_delay))(s), rtol=1e-13, atol=1e-14
        )
    # delta = delta_o = 0: the target system of U_BS2(K), 1 - (rho - K) q e^{-tau s} (eq. (55))
    A, B = loop_factors(PAPER, OutputFeedback(ReflectionController(0.1)))
    np.testing.assert_allclose((A + B)(s), 1 - 0.75 * np.exp(-2.0 * s), rtol=1e-13, atol=1e-14)


@pytest.mark.parametrize(("name", "plant", "controller"), [CASES[0], CASES[4]], ids=["U_BS2", "gains"])
def test_the_controller_uses_the_measurement_only(name, plant, controller):
    """``B_o`` multiplies ``y = z(t - w)``: its kernel vanishes below the window, to the stated accuracy."""
    _, B = loop_factors(plant, controller)
    w = 1.0 / plant.mu
    assert all(d >= w for _, d in B.point_terms)
    nu = np.linspace(0.0, w, 101)[:-1]
    grid = None if loop_route(plant, controller.controller) == "exact" else 201
    law = loop_factors(plant, controller.controller, grid)[1]
    accuracy = observer_term(loop_factors(plant, OpenLoop(), grid)[0], law, w).accuracy
    assert accuracy < 1e-8
    np.testing.assert_allclose(_kernel(B, nu), 0.0, atol=accuracy)


def test_no_observer_needed():
    A0, B0 = loop_factors(PAPER, OpenLoop())
    assert loop_factors(PAPER, OutputFeedback(OpenLoop())) == (A0, B0)
    uncoupled = nr.Hyperbolic2x2(1.0, 2.0, 0.0, 0.0, 0.9, 0.7)
    controller = OutputFeedback(ReflectionController(0.05))
    assert loop_factors(uncoupled, controller) == loop_factors(uncoupled, ReflectionController(0.05))
    assert loop_route(uncoupled, controller) == "exact"
    assert "the observer is exact" in loop_scope(uncoupled, controller, None, loop_factors(uncoupled, controller))


def test_scope_says_the_loop_is_the_pdes():
    """The observer's term is proven on the paper's plant (constant couplings): the loop is the PDE's."""
    controller = OutputFeedback(ReflectionController(0.1))
    assert loop_route(PAPER, controller) == "exact"
    scope = loop_scope(PAPER, controller, None, loop_factors(PAPER, controller))
    assert scope.startswith("the PDE itself") and "enclosed in ball arithmetic" in scope
    margin = nr.delay_margin(PAPER, controller)
    assert not margin.of_model and margin.scope == scope


def test_scope_says_the_loop_is_a_model_where_the_observer_term_is_not_proven():
    """An integral gain with a pole near ``[0, 1]`` (not one Taylor model on the window): the observer's term is not
    proven, floating point, and a model (``kappa = 36`` under U_BS2(0.1), where the proof refused before, is proven
    now: ``tests/test_observer_proven.py``)."""
    strong = nr.Hyperbolic2x2(1.0, 1.0, 6.0, 6.0, 0.5, 0.5)
    controller = OutputFeedback(StateFeedback(-0.2, g_v=lambda x: 0.1 / (1.05 - x)))
    assert loop_route(strong, controller) == "observer"
    scope = loop_scope(strong, controller, None, loop_factors(strong, controller))
    assert scope.startswith("a model of the PDE") and "not part of the proof" in scope


@pytest.mark.long
def test_rigorous_margin_is_about_the_pde():
    """In ball arithmetic the margin is proven for the PDE, and the float margin lies in its ball."""
    controller = OutputFeedback(ReflectionController(0.1))
    proven = nr.delay_margin(PAPER, controller, rigorous=True)
    checked = nr.delay_margin(PAPER, controller)
    assert not proven.of_model and proven.scope.startswith("the PDE itself")
    lo, hi = proven.margin_ball
    assert lo <= checked.margin <= hi


def test_margin_is_a_crossing_of_the_literal_loop():
    controller = OutputFeedback(ReflectionController(0.1))
    margin = nr.delay_margin(PAPER, controller)
    assert margin.nominally_stable and margin.strongly_stable
    assert 0.16 < margin.margin < nr.delay_margin(PAPER, ReflectionController(0.1)).margin
    # the observer term is proven: no model error to add
    assert margin.model_error is None and margin.accuracy is not None and margin.accuracy < 1e-10
    (value,) = oracle(PAPER, controller, 1j * margin.omega, (margin.margin,))
    np.testing.assert_allclose(abs(value), 0.0, atol=2e-8)


@pytest.mark.long
def test_design_matches_certified_neighbours():
    design = design_reflection(PAPER, "margin", output_feedback=True)
    assert isinstance(design.controller, OutputFeedback) and design.kind == "kink"
    assert not design.design.certificate.of_model
    best = design.value
    for K in (design.K - 0.02, design.K - 1e-3, design.K + 1e-3, design.K + 0.02):
        assert nr.delay_margin(PAPER, OutputFeedback(ReflectionController(K))).margin < best
    check = nr.delay_margin(PAPER, design.controller)
    np.testing.assert_allclose(check.margin, best, rtol=1e-9)


def test_resolvent_and_window_law_closed_forms():
    """N = a on the window: r = a e^{-a nu}; m = c: h = c e^{-a nu}; (1 - p e^{-tau s}) H in closed form."""
    a, c, w = 0.8, -0.6, 0.7
    N = DistributedDelay([0.0, 2.0], [a, a])
    r = window_resolvent(N, w)
    nu = np.linspace(0.0, w, 41)
    np.testing.assert_allclose(r(nu), a * np.exp(-a * nu), rtol=0, atol=1e-13)
    h = window_law((DistributedDelay([0.0, 1.5], [c, c]),), r)
    np.testing.assert_allclose(h(nu), c * np.exp(-a * nu), rtol=0, atol=1e-13)
    factor = QuasiPolynomial([[1.0], [-0.5]], [0.0, 1.3])
    product = resolvent_product(factor, h)
    s = np.array([0.2 + 1j, -0.3 + 8j, 2.0])
    H = c * (1 - np.exp(-(a + s) * w)) / (a + s)
    np.testing.assert_allclose(product.product(s), (1 - 0.5 * np.exp(-1.3 * s)) * H, rtol=0, atol=1e-13)
    assert product.accuracy < 1e-12


def test_product_segments_and_their_refinement():
    """``A H`` on one segment per interval: doubled to a tolerance, or left with its stated accuracy.

    The oracle is ``A(s)`` times ``H(s)`` of the stored window kernel integrated directly (20 Gauss points
    on each of its 32 polynomial pieces: exact to rounding for |s| <= 30 on pieces of length 0.022).
    """
    a, c, w = 6.0, -0.6, 0.7
    h = window_law((DistributedDelay([0.0, 1.5], [c, c]),), window_resolvent(DistributedDelay([0.0, 2.0], [a, a]), w))
    factor = QuasiPolynomial([[1.0], [-0.5]], [0.0, 1.3])
    s = np.array([0.2 + 1j, -0.3 + 8j, 2.0, 30j])
    x, g = np.polynomial.legendre.leggauss(20)
    edges = np.linspace(0.0, w, h.coefficients.shape[0] + 1)
    nu = (0.5 * (edges[:-1, None] + edges[1:, None]) + 0.5 * np.diff(edges)[:, None] * x).ravel()
    weights = (0.5 * np.diff(edges)[:, None] * g).ravel()
    exact = (1 - 0.5 * np.exp(-1.3 * s)) * (np.exp(-np.outer(s, nu)) @ (h(nu) * weights))
    coarse = resolvent_product(factor, h, segments=1)
    refined = resolvent_product(factor, h, segments=1, tolerance=1e-13)
    pieces = [sum(d.pieces[0].size for d in p.product.distributed) for p in (coarse, refined)]
    assert pieces[1] > pieces[0]  # e^{-6 nu} on 0.7: degree 11 misses 1e-13, two halvings reach it
    # a sup-norm error times the support's length (1.3 + w) bounds the transform's on Re s >= 0
    assert np.all(np.abs(coarse.product(s) - exact)[[0, 2, 3]] <= coarse.accuracy * (1.3 + w))
    np.testing.assert_allclose(refined.product(s), exact, rtol=0, atol=1e-14)  # measured 4e-17
    with pytest.raises(ParameterError, match="segments"):
        resolvent_product(factor, h, segments=0)
    with pytest.raises(ParameterError, match="tolerance"):
        resolvent_product(factor, h, tolerance=-1.0)


def test_the_observer_term_on_fewer_segments_is_the_default_one():
    """G on 8 segments per window (the observer's) and on the default 24: two fits of one product, each
    within its stated accuracy of it, so within the sum of both of each other; and the proven term (a Taylor
    polynomial of h, exact convolutions in ball arithmetic) within its proven radius plus that of both."""
    open_loop = loop_factors(PAPER, OpenLoop())[0]
    term = observer_term(open_loop, loop_factors(PAPER, ReflectionController(0.1))[1], 1.0)
    default = resolvent_product(open_loop, term.kernel)
    sizes = [sum(d.pieces[0].size for d in p.product.distributed) for p in (term, default)]
    assert sizes == [24, 72]
    length = max(d.b for d in default.product.distributed)
    s = np.r_[0.0, 1j * np.geomspace(1e-2, 300.0, 400), 0.5 + 7j]
    difference = np.abs(term.product(s) - default.product(s))
    # sup-norm errors times the support's length bound the transforms' difference on Re s >= 0
    assert np.max(difference) <= (term.accuracy + default.accuracy) * length
    assert term.accuracy < 2e-13  # measured 8.5e-14 (9.1e-14 on 24 segments)
    proven = observer_of(PAPER, OutputFeedback(ReflectionController(0.1)))
    assert np.max(np.abs(term.product(s) - proven.product(s))) <= (term.accuracy + proven.accuracy) * length


def test_exponential_kernel_resolvent():
    """N = e^{b nu} (degree-12 Taylor pieces): r = e^{(b - 1) nu} (Laplace: N^/(1 + N^) = 1/(s - b + 1))."""
    b, w = -1.5, 1.0
    edges = np.linspace(0.0, w, 9)
    k = np.arange(13)
    factorial = np.cumprod(np.r_[1.0, np.arange(1, 13)])
    coefs = np.array([np.exp(b * x0) * (b * (edges[1] - edges[0])) ** k / factorial for x0 in edges[:-1]])
    N = DistributedDelay(edges, None, interpolation="polynomial", coefficients=coefs)
    nu = np.linspace(0.0, w, 33)
    np.testing.assert_allclose(window_resolvent(N, w)(nu), np.exp((b - 1) * nu), rtol=0, atol=1e-13)


def test_bad_input():
    with pytest.raises(ParameterError, match="controller"):
        OutputFeedback(OutputFeedback(ReflectionController(0.1)))
    with pytest.raises(ParameterError, match="controller"):
        OutputFeedback("U_BS2")
    with pytest.raises(ParameterError, match="observer_delay"):
        OutputFeedback(ReflectionController(0.1), observer_delay=-1.0)
    with pytest.raises(ParameterError, match="state feedback"):
        OutputFeedback(ReflectionController(0.1)).feedback_law(PAPER)
    varying = nr.GeneralHyperbolic2x2(lam=lambda x: 1 + 0.2 * x, mu=1.0, a=0.0, b=0.5, c=0.5, d=0.0, q=0.5, rho=0.5)
    with pytest.raises(ParameterError, match="constant lam/mu"):
        loop_factors(varying, OutputFeedback(ReflectionController(0.1)))
    with pytest.raises(ParameterError, match="observer_delay"):
        design_reflection(PAPER, "margin", observer_delay=0.1)
    with pytest.raises(ParameterError, match="window"):
        window_resolvent(DistributedDelay([0.0, 0.5], [1.0, 1.0]), 1.0)


@pytest.mark.parametrize("errors", [(0.05, 0.0), (-0.03, 0.04)])
def test_speed_mismatch_is_the_literal_predictor_on_the_perturbed_plant(errors):
    """The controller (nominal model, nominal window) on a plant with speeds lam (1 + e_lam), mu (1 + e_mu)."""
    e_lam, e_mu = errors
    controller = OutputFeedback(ReflectionController(0.1))
    A, B = mismatch_loop(PAPER, controller, e_lam, e_mu)
    perturbed = nr.Hyperbolic2x2(1.0 + e_lam, 1.0 + e_mu, 1.0, 1.0, 1.0, 0.85)
    open_loop, law = loop_factors(PAPER, OpenLoop())[0], loop_factors(PAPER, ReflectionController(0.1))[1]
    plant_loop = loop_factors(perturbed, OpenLoop())[0]
    w, w_plant = 1.0, 1.0 / (1.0 + e_mu)
    for s in POINTS:
        coarse = literal_predictor(open_loop, law, w, s, 150)
        fine = literal_predictor(open_loop, law, w, s, 300)
        c_z, c_u = ((4 * b - a) / 3 for a, b in zip(coarse, fine))
        for delta in (0.0, 0.2):
            expected = plant_loop(s) * (1 - c_u) - c_z * np.exp(s * (w - w_plant) - delta * s)
            np.testing.assert_allclose(A(s) + B(s) * np.exp(-delta * s), expected, rtol=0, atol=2e-8)
    A0, B0 = mismatch_loop(PAPER, controller, 0.0, 0.0)
    A1, B1 = loop_factors(PAPER, controller)
    s = np.array(POINTS)
    np.testing.assert_allclose((A0 + B0.shift(0.2))(s), (A1 + B1.shift(0.2))(s), rtol=0, atol=1e-12)


def test_output_feedback_is_fragile_to_the_speed_of_u():
    """5 % on lam: the output feedback loses stability without any delay; the state feedback keeps a margin."""
    observed = nr.delay_margin(*mismatch_loop(PAPER, OutputFeedback(ReflectionController(0.1)), 0.05, 0.0))
    state = nr.delay_margin(*mismatch_loop(PAPER, ReflectionController(0.1), 0.05, 0.0))
    assert not observed.nominally_stable and observed.margin == 0.0
    assert state.nominally_stable and state.margin > 0.2


SYSTEM_TOML = """
[system]
type = "Hyperbolic2x2"
lam = 1.0
mu = 1.0
sigma_pm = 1.0
sigma_mp = 1.0
q = 1.0
rho = 0.85

[controller]
type = "ReflectionController"
K = 0.1

[analysis]
delta_max = 0.5

[design]
family = "output_feedback"
K = [0.1, 0.13]
"""


def test_design_command_for_output_feedback(tmp_path):
    system = tmp_path / "SYSTEM.toml"
    system.write_text(SYSTEM_TOML)
    out = tmp_path / "out"
    assert main(["design", str(system), "-o", str(out)]) == 0
    text = (out / "design.md").read_text()
    assert text.startswith("# Design of U_BS2(K) on the state predicted from v(t, 0)")
    assert re.search(r"K = 0\.117757776215\d* \+- \de-1[23] \(kink\)", text) and "the PDE itself" in text
    data = json.loads((out / "design.json").read_text())
    assert data["family"] == "output_feedback" and data["controller"]["controller"] == "OutputFeedback"


@pytest.mark.parametrize(
    ("extra", "family", "name"),
    [
        ("observer_delay = -0.1", "output_feedback", "design.observer_delay"),
        ("observer_delay = 0.1", "reflection", "design.observer_delay"),
        ("a = 0.1", "output_feedback", "design.a"),
    ],
)
def test_design_section_checks_the_observer_keys(tmp_path, extra, family, name):
    system = tmp_path / "SYSTEM.toml"
    system.write_text(SYSTEM_TOML.replace('family = "output_feedback"', f'family = "{family}"\n{extra}'))
    with pytest.raises(ParameterError, match=name):
        load_system_file(system)
