"""Design of the gain matrix of an n + m system (nrobust.hyperbolic.nplusm.design).

Oracles: the exact one-gain engine of the core (``best_decay_rate``, from the equations of its
kind on the scalar loop of the kernel route, not a local search nor the Laplace route) on a
1 + 1 plant; a brute-force grid of certified abscissae on a 2 + 1 plant; central differences
of the certified abscissa and margin for the gradients; closed forms for ``gamma``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from nrobust import StateFeedback, delay_margin
from nrobust.design import TrialPoint, best_decay_rate, best_margin, local_runs
from nrobust.errors import ParameterError
from nrobust.hyperbolic.analyses.state_design import state_feedback_loop
from nrobust.hyperbolic.nplusm import (
    NPlusMCharacteristic,
    NPlusMSystem,
    design_nplusm_gains,
    gain_gradient,
    nplusm_delay_margin,
    principal_gamma,
)
from nrobust.hyperbolic.nplusm.design import K_BOUND_FRACTION, NPlusMGainProblem, default_gain_bounds
from nrobust.hyperbolic.plants.hyperbolic2x2 import Hyperbolic2x2
from nrobust.margins.gain import AffineGainLoop
from nrobust.reports.design import _nplusm_markdown
from nrobust.roots import spectral_abscissa

# a coupled 2 + 1 system (distinct speeds, no diagonal couplings: U_a = V = 1) with one actuator
TWO_ONE = NPlusMSystem(
    [1.0, 0.5], [1.5], [[0.0, 0.0, 0.4], [0.0, 0.0, 0.3], [0.5, -0.4, 0.0]], [[0.6], [0.5]], [[0.5, 0.4]]
)
# a coupled 2x2 plant that the proportional law U = k u(t, 1) stabilises for k in about (-0.84, -0.23)
PLANT = Hyperbolic2x2(1.0, 1.0, 1.5, 0.5, 0.8, 0.4)


def _gamma_two_one(K: np.ndarray) -> float:
    """Hale and Verduyn Lunel's gamma_0 of TWO_ONE's delayed principal part in closed form:
    ``sum |R_a Q_a| + sum |K_a Q_a|`` (no diagonal couplings, so ``U_a = V = 1``)."""
    q = np.array([0.6, 0.5])
    return float(np.sum(np.abs(np.array([0.5, 0.4]) * q)) + np.sum(np.abs(np.ravel(K) * q)))


def test_gamma_and_default_bounds_in_closed_form() -> None:
    """``principal_gamma`` is gamma_0 for one actuator, and each default bound is 0.99 of the entry
    that alone brings it to 1: ``(1 - 0.5) / 0.6`` and ``(1 - 0.5) / 0.5``."""
    for K in ([[0.0, 0.0]], [[-0.3, 0.2]], [[0.7, -0.9]]):
        np.testing.assert_allclose(principal_gamma(TWO_ONE, K), _gamma_two_one(np.array(K)), rtol=1e-14)
    problem_bounds = default_gain_bounds(TWO_ONE)
    expected = K_BOUND_FRACTION * np.array([0.5 / 0.6, 0.5 / 0.5])
    np.testing.assert_allclose(problem_bounds[:, 1], expected, rtol=1e-12)  # bisection to 2^-60 relative
    np.testing.assert_allclose(problem_bounds[:, 0], -expected, rtol=1e-12)


# a fully coupled 2 + 2 system (two actuators: the loop is a 2 x 2 determinant)
TWO_TWO = NPlusMSystem(
    [1.0, 0.5],
    [1.0, 2.0],
    [[0.0, 0.1, 0.5, 0.2], [0.1, 0.0, 0.2, -0.3], [0.4, 0.1, 0.0, 0.1], [0.2, 0.6, 0.1, 0.0]],
    [[0.8, 0.1], [0.2, 0.7]],
    [[0.5, 0.2], [0.1, -0.4]],
)


def _root_near(K: np.ndarray, s0: complex, system: NPlusMSystem = TWO_ONE, delta: float = 0.0) -> complex:
    """The zero of the loop at ``K`` that Newton's method reaches from ``s0`` (to rounding)."""
    F = NPlusMCharacteristic(system, K, delta)
    s = complex(s0)
    for _ in range(30):
        step = complex(F(np.array([s]))[0] / F.deriv_at(np.array([s]))[0])
        s -= step
        if abs(step) < 1e-15 * (1.0 + abs(s)):
            break
    return s


def test_gradients_match_central_differences() -> None:
    """At ``K = [[-0.5, 0.1]]`` (a simple real rightmost root, certified; one crossing) the
    gradients from Jacobi's formula agree with central differences: of the rightmost root, continued
    by Newton's method to ``K +- h e_ij`` (the abscissa is its real part near ``K``), and of the
    certified margin. With ``h = 1e-5`` the truncation error is ``O(h^2)`` (about 1e-10 here) and
    the values' rounding (below 1e-12) divided by ``2 h`` is below 1e-7: ``rtol = 1e-6`` (measured
    agreement 1e-9)."""
    K = np.array([[-0.5, 0.1]])
    problem = NPlusMGainProblem(TWO_ONE, np.array([(-0.8, 0.8), (-0.9, 0.9)]), "decay_rate", None)
    sa = problem.abscissa(K)
    assert sa.certified and sa.root is not None and not sa.approached_at_infinity
    grad = gain_gradient(TWO_ONE, K, sa.root)
    h = 1e-5
    fd = np.zeros(2, dtype=complex)
    for i in range(2):
        step = np.zeros((1, 2))
        step[0, i] = h
        hi, lo = (_root_near(K + sgn * step, sa.root) for sgn in (1.0, -1.0))
        fd[i] = (hi - lo) / (2 * h)
    np.testing.assert_allclose(grad.ravel(), fd, rtol=1e-6)
    point = problem(K.ravel())  # the abscissa remembered, its gradient from Jacobi's formula
    assert point.feasible and point.value == sa.value
    np.testing.assert_allclose(point.gradient, fd.real, rtol=1e-6)

    problem = NPlusMGainProblem(TWO_ONE, np.array([(-0.8, 0.8), (-0.9, 0.9)]), "margin", None)
    point = problem(K.ravel())
    dm = nplusm_delay_margin(TWO_ONE, K)
    assert point.feasible and dm.certified
    np.testing.assert_allclose(-point.value, dm.margin, rtol=0)
    fd = np.zeros(2)
    for i in range(2):
        step = np.zeros((1, 2))
        step[0, i] = h
        hi, lo = (nplusm_delay_margin(TWO_ONE, K + sgn * step).margin for sgn in (1.0, -1.0))
        fd[i] = (hi - lo) / (2 * h)
    np.testing.assert_allclose(-point.gradient, fd, rtol=1e-6)


@pytest.mark.parametrize(("delta", "seed"), [(0.0, -0.77 + 1.16j), (0.5, -0.71 + 1.23j)])
def test_two_actuator_root_gradient_matches_central_differences(delta: float, seed: complex) -> None:
    """Two actuators: ``ds/dK`` from Jacobi's formula with the 2 x 2 adjugate (and the factor
    ``e^{-delta s}`` of a delayed loop) against central differences of a zero continued by Newton's
    method (a simple zero near ``seed``, located by ``find_roots`` beforehand). Tolerance as for one
    actuator: ``rtol = 1e-6``."""
    K = np.array([[-0.2, 0.1], [0.05, 0.1]])
    s0 = _root_near(K, seed, TWO_TWO, delta)
    F = NPlusMCharacteristic(TWO_TWO, K, delta)
    assert abs(F(np.array([s0]))[0]) < 1e-12 and abs(F.deriv_at(np.array([s0]))[0]) > 1e-3
    grad = gain_gradient(TWO_TWO, K, s0, delta)
    h = 1e-5
    fd = np.zeros((2, 2), dtype=complex)
    for i in range(2):
        for j in range(2):
            step = np.zeros((2, 2))
            step[i, j] = h
            hi, lo = (_root_near(K + sgn * step, s0, TWO_TWO, delta) for sgn in (1.0, -1.0))
            fd[i, j] = (hi - lo) / (2 * h)
    np.testing.assert_allclose(grad, fd, rtol=1e-6)


def test_local_runs_on_a_problem_of_its_own() -> None:
    """The core's optimiser on a problem that is no loop: ``|p_0 - 0.3| + 2 |p_1 + 0.1| + p_1^2``
    with ``p_0 + p_1 <= 0.15`` (an infeasible point is never an iterate). The minimum on the feasible
    set is at ``(0.25, -0.1)``, on the constraint (slope 1 of ``p_0`` beats slope 2 of ``p_1``); the
    pattern search stops with steps of 1e-5 of the widths, so within 2e-5 of it."""

    class Kinked:
        bounds = np.array([(-1.0, 1.0), (-1.0, 1.0)])
        margin_at_least = None
        screened = 0

        def __call__(self, p, want=None, above=math.inf):
            p = np.asarray(p, dtype=float)
            if np.any(np.abs(p) > 1.0) or p[0] + p[1] > 0.15:
                return TrialPoint(p, False, math.inf, np.zeros(2), math.nan, math.nan, "infeasible")
            value = abs(p[0] - 0.3) + 2.0 * abs(p[1] + 0.1) + p[1] ** 2
            grad = np.array([np.sign(p[0] - 0.3), 2.0 * np.sign(p[1] + 0.1) + 2.0 * p[1]])
            return TrialPoint(p, True, value, grad, value, math.nan)

    runs = local_runs(Kinked(), x0=(-0.5, 0.5))
    assert runs[0].feasible and all(r.parameters[0] + r.parameters[1] <= 0.15 for r in runs if r.feasible)
    np.testing.assert_allclose(runs[0].parameters, (0.25, -0.1), atol=2e-5 * 2.0)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"K_bounds": (0.5, -0.5)}, "K_bounds"),
        ({"K_bounds": [(-1.0, 1.0)] * 3}, "K_bounds"),
        ({"K_bounds": (-math.inf, 1.0)}, "K_bounds"),
        ({"K_bounds": "wide"}, "K_bounds"),
        ({"objective": "speed"}, "objective"),
        ({"objective": "margin", "margin_at_least": 0.5}, "margin_at_least"),
        ({"margin_at_least": -1.0}, "margin_at_least"),
        ({"x0": [[0.1, 0.2, 0.3]]}, "x0"),
        ({"x0": [[5.0, 0.0]]}, "x0"),
        ({"starts": 0}, "starts"),
        ({"gamma_max": 1.0}, "gamma_max"),
        ({"tol": 0.0}, "tol"),
        ({"rigorous": "yes"}, "rigorous"),
    ],
)
def test_bad_input_is_refused_before_any_work(kwargs: dict, name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each bad argument is a ParameterError naming it, raised before the first evaluation."""
    import nrobust.hyperbolic.nplusm.design as design

    def no_work(*args: object, **kw: object) -> None:
        raise AssertionError("evaluated before the arguments were checked")

    monkeypatch.setattr(design, "local_runs", no_work)
    with pytest.raises(ParameterError) as info:
        design_nplusm_gains(TWO_ONE, **kwargs)
    assert info.value.name == name
    with pytest.raises(ParameterError) as info:
        design_nplusm_gains(PLANT)  # type: ignore[arg-type]
    assert info.value.name == "system"


def test_one_plus_one_margin_agrees_with_the_exact_scalar_design() -> None:
    """The margin objective on the 1 + 1 plant below (``K = [[k]]`` is ``StateFeedback(k)``), ``k`` in
    ``[-0.8, -0.5]``: the margin rises with ``k`` (towards the edge of nominal stability near
    ``k = -0.23``), and the exact engine puts the optimum at the end ``k = -0.5`` (margin 1.114009).
    The local design stops with pattern steps of ``1e-5`` of the width 0.3, so ``k`` agrees to
    ``1e-5`` (measured 2e-6) and the margin, whose slope in ``k`` is about 2.6, to ``5e-5``
    (measured 5e-6). About 2 s of CPU time: 28 certified margins of the 1 + 1 loop (most of each in
    ``scipy.linalg.expm`` of 2 x 2 matrices), with BLAS on one thread (competing BLAS threads made it 15 to 20
    times slower on a loaded machine), and 0.8 s the exact engine."""
    loop = state_feedback_loop(PLANT)
    exact = best_margin(AffineGainLoop(loop.A, loop.units[0] * 0.0, loop.units[0]), (-0.8, -0.5))
    design = design_nplusm_gains(NPlusMSystem.from_2x2(PLANT), "margin", K_bounds=(-0.8, -0.5), x0=[[-0.7]], starts=1)
    assert design.certified and design.margin is not None and design.margin.certified
    np.testing.assert_allclose(design.K[0][0], exact.K, atol=1e-5)
    np.testing.assert_allclose(design.value, exact.margin, atol=5e-5)
    assert design.value <= exact.margin + 1e-9 and design.accuracy < 1e-9
    # the report prints the designed loop's margin to its accuracy: against the scalar route's margin at that k
    (line,) = [
        x for x in _nplusm_markdown(Path("plant.toml"), design) if x.startswith("- delay margin: ") and "about" in x
    ]
    printed, bound = line.removeprefix("- delay margin: ").split(" (")[0].split(" +- ")
    scalar = delay_margin(PLANT, StateFeedback(float(design.K[0][0])))
    assert abs(float(printed) - scalar.margin) <= 1.5 * float(bound) + scalar.accuracy, (line, scalar)


@pytest.mark.long
def test_one_plus_one_agrees_with_the_exact_scalar_design() -> None:
    """On a coupled 1 + 1 plant, ``U = k u(t - delta, 1)`` is ``StateFeedback(k)`` of the 2x2 plant
    (``from_2x2`` keeps ``v(t, 1) = rho u(t, 1) + U``: ``K = [[k]]``, same sign). The best decay rate
    under ``delta* >= 1.2`` for ``k`` in ``[-0.8, -0.3]`` is where the margin equals 1.2 (the decay
    rate falls and the margin rises with ``k``); the exact engine solves that end from its
    equation. The local design stops with pattern steps of ``1e-5`` of the width 0.5, so ``k``
    agrees to ``1e-5`` (measured 4.5e-6) and the decay rate, whose slope in ``k`` is about 6.3
    there, to ``1e-4`` (measured 2.9e-5); the local design is feasible, so never better than
    the optimum by more than the oracle's accuracy. The design's abscissa is proven in ball
    arithmetic. About 7 s of CPU time."""
    loop = state_feedback_loop(PLANT)
    exact = best_decay_rate(
        AffineGainLoop(loop.A, loop.units[0] * 0.0, loop.units[0]), (-0.8, -0.3), margin_at_least=1.2
    )
    design = design_nplusm_gains(
        NPlusMSystem.from_2x2(PLANT),
        "decay_rate",
        margin_at_least=1.2,
        K_bounds=(-0.8, -0.3),
        x0=[[-0.5]],
        starts=1,
        rigorous=True,
    )
    assert design.certified and design.local and design.margin is not None
    assert design.rigorous and design.abscissa.value_bracket is not None and design.accuracy < 1e-9
    assert design.margin.margin >= 1.2
    assert design.margin.rigorous and design.margin.margin_bracket is not None  # proven for the PDE too
    np.testing.assert_allclose(design.K[0][0], exact.K, atol=1e-5)
    np.testing.assert_allclose(design.value, exact.decay_rate, atol=1e-4)
    assert design.value <= exact.decay_rate + 1e-9


@pytest.mark.long
@pytest.mark.timeout(1800)  # about 90 s of CPU time: on a loaded machine the wall time is several times that
def test_two_plus_one_beats_a_grid_of_gains() -> None:
    """On a coupled 2 + 1 plant the designed ``K`` (decay rate, default bounds) has an abscissa no
    larger than that of any point of a 5 x 5 grid of the bounds whose delayed loop is robust
    (closed-form ``gamma_0 <= 0.999``), each certified; the design's own abscissa is certified.
    About 90 s of CPU time."""
    design = design_nplusm_gains(TWO_ONE, "decay_rate", starts=1)
    assert design.certified and design.abscissa.certified and design.gamma <= 0.999
    np.testing.assert_allclose(design.gamma, _gamma_two_one(design.gain), rtol=1e-12)
    bounds = default_gain_bounds(TWO_ONE)
    grid = []
    for k1 in np.linspace(bounds[0, 0], bounds[0, 1], 5):
        for k2 in np.linspace(bounds[1, 0], bounds[1, 1], 5):
            K = np.array([[k1, k2]])
            if _gamma_two_one(K) <= 0.999:
                sa = spectral_abscissa(NPlusMCharacteristic(TWO_ONE, K))
                assert sa.certified
                grid.append(sa.value)
    assert len(grid) == 13  # 0.6 |k_1| + 0.5 |k_2| <= 0.499 on the grid
    assert design.abscissa.value <= min(grid)
