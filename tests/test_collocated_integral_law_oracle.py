"""The collocated observer under U_BS2(K) on coupled plants: the kernel route's loop against the PDE's (40 digits).

Under a law with an integral part the collocated observer's command response ``C_u`` composes the plant's
gains ``K^{v.}(1, .)`` with the dual plant's kernels (module notes of ``collocated``), computed on a kernel grid:
the loop is a model of the PDE, and a rigorous result must say so whenever its ball misses the PDE's value.

Oracle (``_collocated_oracle``), sharing no code with the package, at 40 digits: the kernels as Taylor series of
their Goursat problems, the Laplace-domain profiles as Taylor series in ``x``, crossings by ``mpmath.findroot``.

Measured (the kernel route on its default 201 points, ``rigorous=True``), the paper's plant with
``CollocatedOutputFeedback(ReflectionController(0.1))``: the PDE's margin is 0.16890143103111756993; the ball
was ``[0.1689016192105674, 0.16890161929258768]`` (outside by 1.9e-7, 2300 times its width; the stated model
error 1.1e-6) while the composition ``F = (I - K') f`` took the trapezoidal rule, which left the loop second order
(its error fell by 4.0 per halving of the grid, the observer's gains' by 8); with Gregory's end corrections the
loop is third order and the ball ``[0.1689014326376654, 0.16890143271962718]`` (outside by 1.6e-9, still a
model's: 20 times its width). With ``observer_reflection=-0.3`` the PDE's margin is 0.18222485623151012821, the
ball was ``[0.18222501431991905, 0.18222501439091382]`` (1.6e-7) and is ``[0.18222485756030013,
0.1822248576313101]`` (1.3e-9).
"""

from __future__ import annotations

import math
import re

import mpmath as mp
import numpy as np
import pytest
from _collocated_oracle import DPS, CollocatedPDE, horner

import nrobust as nr
from nrobust.hyperbolic import CollocatedOutputFeedback, Hyperbolic2x2, ReflectionController
from nrobust.hyperbolic.kernels.constant import solve_kernels
from nrobust.hyperbolic.loops.collocated import _gregory_weights, dual_plant, observer_gains
from nrobust.hyperbolic.loops.controllers import collocated_observer_of, loop_route

PAPER = (1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
SECOND = (1.0, 2.0, 0.4, 0.5, 1.0, 0.3)
POINTS = (0.3 + 0.7j, -0.2 + 5j, 2j)


@pytest.mark.parametrize("args", [PAPER, SECOND])
def test_the_series_gains_give_the_target_loop_and_a_nilpotent_error(args):
    """The oracle's gains do what they must: U_BS2(0.1) closes the plant's loop on its target
    ``1 - (rho - K) q e^{-tau s}`` and the observer's error has the characteristic function ``e^{s/mu}``
    (``e^{-s/mu} Delta = 1``: nilpotent), to 1e-35 (measured 1e-49 at 50 digits; the series' last degree is below
    1e-55). The second checks the package's claim that the observer's gains are the dual plant's U_BS' gains."""
    pde = CollocatedPDE(args, 0.1)
    assert pde.last < 1e-50
    tau = 1 / pde.lam + 1 / pde.mu
    for s in (*POINTS, -1 + 3j):
        _, _, error, _, target = pde.responses(s)
        with mp.workdps(DPS):
            assert abs(error - 1) < 1e-35
            assert abs(target - (1 - (pde.rho - pde.K) * pde.q * mp.exp(-tau * mp.mpc(s)))) < 1e-35


@pytest.mark.parametrize(("args", "error_201"), [(PAPER, 1e-8), (SECOND, 1e-9)])
def test_the_kernel_route_gains_converge_to_the_series(args, error_201):
    """The package's observer gains (the dual plant's kernels on 51, 101, 201 points) approach the series at third
    order: the error ratios measured 7.8 to 8.1 (asserted in (6, 10)); on 201 points 1.1e-9 to 3.4e-9 (paper's
    plant) and 1.5e-10 (second), asserted below ``error_201``."""
    plant = Hyperbolic2x2(*args)
    pde = CollocatedPDE(args, 0.1)
    errors = []
    for n in (51, 101, 201):
        x, p_u, p_v = observer_gains(solve_kernels(dual_plant(plant), n), plant.lam)
        with mp.workdps(DPS):
            exact_u = np.array([float(horner(pde.p_u, mp.mpf(v))) for v in x])
            exact_v = np.array([float(horner(pde.p_v, mp.mpf(v))) for v in x])
        errors.append(max(np.max(np.abs(p_u - exact_u)), np.max(np.abs(p_v - exact_v))))
    assert errors[2] < error_201
    assert 6 < errors[0] / errors[1] < 10 and 6 < errors[1] / errors[2] < 10


def test_the_composition_weights_are_third_order_on_every_row():
    """``F = (I - K') f`` integrates on ``[0, x_i]`` for every node ``i`` of the uniform grid: the trapezoidal rule
    with Gregory's end corrections ``h/12 (-f_0 + f_1 + f_{i-1} - f_i)`` is exact on linear functions (the
    corrections cancel) and third order on every row from the smallest kernel grid (5 points) on: on
    ``e^x cos(3 x)`` the largest error over the rows falls by 8.2 to 9.0 per halving (measured 3.1e-2 on 5 points,
    6.5e-7 on 129)."""
    errors = []
    for n in (5, 9, 17, 33, 65, 129):
        x = np.linspace(0.0, 1.0, n)
        w = _gregory_weights(n)
        assert w.shape == (n, n) and np.all(w[np.triu_indices(n, 1)] == 0.0)
        np.testing.assert_allclose(w @ (2.0 - 3.0 * x), 2.0 * x - 1.5 * x**2, rtol=0.0, atol=1e-15)
        exact = (np.exp(x) * (np.cos(3.0 * x) + 3.0 * np.sin(3.0 * x)) - 1.0) / 10.0
        errors.append(np.max(np.abs(w @ (np.exp(x) * np.cos(3.0 * x)) - exact)))
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all((7.0 < ratios) & (ratios < 9.5))


@pytest.mark.parametrize(("args", "kappa", "error_201"), [(PAPER, 0.0, 2e-7), (PAPER, -0.3, 2e-7), (SECOND, 0.0, 1e-9)])
def test_the_collocated_loop_of_u_bs2_converges_to_the_pde_loop(args, kappa, error_201):
    """``loop_factors`` on 51, 101, 201 points approaches the PDE's ``(A_o, B_o)`` at third order (ratios
    measured 7.5 to 8.4, asserted in (6, 10); 3.9 to 4.0 with the plain trapezoidal composition); on the default
    grid the error is below ``error_201`` (measured 6e-9 to 2.5e-8 on the paper's plant, 3e-11 to 1.1e-10 on the
    second; 9e-7 to 3.4e-6 and 4e-9 to 1.6e-8 before) and within the observer's stated accuracy times the length
    ``2 tau`` of ``G``'s kernel (``|int e(nu) e^{-nu s}| <= sup |e| 2 tau`` for ``Re s >= 0``; 6.8e-6 and 2.7e-8)."""
    plant = Hyperbolic2x2(*args)
    controller = CollocatedOutputFeedback(ReflectionController(0.1), observer_reflection=kappa)
    # without a grid the loop is the proven one (test_collocated_proof.py)
    assert loop_route(plant, controller) == "exact"
    pde = CollocatedPDE(args, 0.1, kappa)
    truth = {s: tuple(complex(v) for v in pde.factors(s)) for s in POINTS}
    errors = []
    for n in (51, 101, 201):
        A, B = nr.loop_factors(plant, controller, kernel_grid=n)
        errors.append([max(abs(complex(A(s)) - truth[s][0]), abs(complex(B(s)) - truth[s][1])) for s in POINTS])
    errors = np.array(errors)
    assert np.all((6 < errors[0] / errors[1]) & (errors[0] / errors[1] < 10))
    assert np.all((6 < errors[1] / errors[2]) & (errors[1] / errors[2] < 10))
    assert np.all(errors[2] < error_201)
    bound = collocated_observer_of(plant, controller).accuracy * 2.0 * plant.tau
    on_axis = [i for i, s in enumerate(POINTS) if s.real >= 0]
    assert np.all(errors[2, on_axis] < bound)


@pytest.mark.parametrize("kappa", [0.0, -0.3])
def test_the_margin_of_u_bs2_with_the_collocated_observer_on_the_kernel_grid_claims_no_pde_certificate(kappa):
    """On a kernel grid (the default's 201 points, given) the float margin is within 1e-8 of the PDE's (40 digits;
    measured 1.7e-9 and 1.4e-9; 1.9e-7 and 1.6e-7 with the plain trapezoidal composition), and the rigorous ball,
    which misses the PDE's margin (module docstring), is said to be a model's: ``of_model`` and the scope "a model
    of the PDE". Without a grid the loop is proven and its ball holds the PDE's margin
    (``test_collocated_proof.py``)."""
    plant = Hyperbolic2x2(*PAPER)
    controller = CollocatedOutputFeedback(ReflectionController(0.1), observer_reflection=kappa)
    pde = CollocatedPDE(PAPER, 0.1, kappa)
    margin = nr.delay_margin(plant, controller, kernel_grid=201)
    _, truth = pde.crossing(margin.omega)
    assert abs(margin.margin - float(truth)) <= 1e-8
    proven = nr.delay_margin(plant, controller, rigorous=True, kernel_grid=201)
    lo, hi = proven.margin_ball
    if not mp.mpf(lo) <= truth <= mp.mpf(hi):
        assert proven.of_model and proven.scope.startswith("a model of the PDE")


def test_no_crossing_of_the_second_plant_on_samples():
    """``Hyperbolic2x2(1, 2, 0.4, 0.5, 1, 0.3)`` under the collocated U_BS2(0.1) has no crossing (the package's
    margin is infinite, below its frequency bound 8.96): the PDE's ``|1 - C_u(i w)| - |C_u(i w) - T(i w)|`` on
    ``w = 0, 0.25, ..., 9`` stays above 0.4 (measured minimum 0.449 at ``w = 0`` on a 0.01 grid), far above the
    loop's error (4e-8 on 201 points)."""
    plant = Hyperbolic2x2(*SECOND)
    margin = nr.delay_margin(plant, CollocatedOutputFeedback(ReflectionController(0.1)))
    assert margin.margin == np.inf and margin.frequency_bound < 9.0
    pde = CollocatedPDE(SECOND, 0.1)
    for w in np.arange(0.0, 9.01, 0.25):
        response, plant_response, *_ = pde.responses(1j * w)
        assert abs(1 - response) - abs(response - plant_response) > 0.4


NUMBER = r"(-?[0-9.]+(?:e[-+]?[0-9]+)?) \+- ([0-9]e[-+]?[0-9]+)"


def _printed(text, name):
    """``name=VALUE +- ACC`` in a repr: the value's text, the value and the accuracy (else the test fails)."""
    match = re.search(rf"{name}={NUMBER}", text)
    assert match is not None, f"{name} printed without an accuracy: {text}"
    return match.group(1), float(match.group(1)), float(match.group(2))


@pytest.mark.parametrize(
    ("args", "K", "kappa"),
    [
        (PAPER, 0.1, 0.0),
        (PAPER, 0.1, -0.3),
        (PAPER, 0.1, -0.7149450549450549),
        ((1.0, 1.5, 0.8, 1.0, 1.0, 0.6), 0.1, 0.0),
        ((2.0, 1.0, 1.2, 0.7, 1.0, 0.8), 0.1, 0.0),
    ],
)
def test_every_printed_digit_of_the_collocated_margin_is_the_pdes(args, K, kappa):
    """The float margin and crossing frequency (default 201 points) with their stated accuracies contain the
    PDE's, the accuracies are at most 5e-9 and at most 5 times the true errors, and the repr prints exactly the
    digits they support, each of them the PDE's: ``|printed - PDE| <= printed accuracy``.

    Measured: the errors 3.6e-11 to 1.8e-9, the stated model errors 2.0 to 2.7 times them (the grid study's tail
    at third order times ``STUDY_SAFETY``); the repr of the paper's loop ``margin=0.168901433 +- 4e-9`` against the
    PDE's 0.16890143103 (it printed ``0.168902 +- 2e-6`` with the plain trapezoidal composition, whose loop was
    second order, and the accuracies below fail there). Where the ends ``1/lam``, ``1/mu``, ``tau`` are doubles the
    loop is the proven one (``loop_route`` "exact", no model error): its printed digits are the PDE's (measured
    errors 1e-16 to 6e-16 against printed accuracies 4e-13 to 6e-13)."""
    plant = Hyperbolic2x2(*args)
    controller = CollocatedOutputFeedback(ReflectionController(K), observer_reflection=kappa)
    margin = nr.delay_margin(plant, controller)
    w, truth = CollocatedPDE(args, K, kappa).crossing(margin.omega)
    text = repr(margin)
    for name, value, exact, model_error in (
        ("margin", margin.margin, truth, margin.model_error),
        ("omega", margin.omega, w, margin.omega_model_error),
    ):
        digits, printed_value, accuracy = _printed(text, name)
        assert abs(printed_value - float(exact)) <= accuracy <= 5e-9
        assert len(digits.split(".")[1]) == -math.floor(math.log10(accuracy))
        if model_error is None:  # the proven loop (the pieces' ends doubles): no model error
            assert loop_route(plant, controller) == "exact"
            continue
        error = abs(value - float(exact))
        assert error <= model_error <= 5e-9
        assert model_error <= 5.0 * error or model_error <= 1e-10
