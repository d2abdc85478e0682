"""Property-based tests of output feedback from ``v(t, 0)`` on random plants with constant coefficients.

For random speeds, couplings and boundary gains with ``|rho q| < 1`` and a gain ``K`` of U_BS2(K)
inside the strong-stability bound of eq. (54), three claims of
:mod:`nrobust.hyperbolic.loops.output_feedback` are checked against oracles written here:

1. without a delay the loop is the target system ``1 - (rho - K) q e^{-tau s}`` (the observer is
   exact), at random points of the plane;
2. the factor ``B_o`` multiplies the measurement only: its kernel vanishes below the window
   ``1/mu`` to the accuracy the observer term states;
3. the loop with a random delay equals the literal predictor (:mod:`_predictor`: the window's
   convolution equation by the trapezoidal rule, Richardson over two grids, its error estimated
   from a third).

Budget as in ``tests/test_fuzz_lti.py``: a few derandomised examples in CI,
``NROBUST_FUZZ_EXAMPLES=N`` random ones under ``make fuzz``.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from _budget import FUZZ, budget
from _predictor import kernel_sum, literal_predictor
from hypothesis import example, given
from hypothesis import strategies as st

import nrobust as nr
from nrobust.hyperbolic.loops.controllers import OpenLoop, OutputFeedback, ReflectionController, loop_factors
from nrobust.hyperbolic.loops.output_feedback import observer_term

pytestmark = pytest.mark.timeout(0 if FUZZ else 300)


@st.composite
def plants(draw: st.DrawFn) -> tuple[nr.Hyperbolic2x2, float]:
    """A coupled plant with ``|rho q| <= 0.9`` and a gain K within 0.9 of the bound of eq. (54)."""
    lam = draw(st.floats(0.5, 3.0))
    mu = draw(st.floats(0.5, 3.0))
    sigma_pm = draw(st.floats(-2.0, 2.0).filter(lambda x: abs(x) > 0.05))
    sigma_mp = draw(st.floats(-2.0, 2.0).filter(lambda x: abs(x) > 0.05))
    q = draw(st.floats(0.2, 1.5))
    rho = draw(st.floats(-0.9, 0.9)) / q
    bound = (1.0 - abs(rho * q)) / q
    K = draw(st.floats(-0.9, 0.9)) * bound
    return nr.Hyperbolic2x2(lam, mu, sigma_pm, sigma_mp, q, rho), K


POINT = st.tuples(st.floats(-0.5, 1.0), st.floats(-12.0, 12.0)).map(lambda p: complex(*p))


@budget(4, 0.5)
@given(plants(), st.lists(POINT, min_size=3, max_size=3))
def test_without_delay_the_loop_is_the_target(case, points):
    plant, K = case
    A, B = loop_factors(plant, OutputFeedback(ReflectionController(K)))
    s = np.array(points)
    target = 1.0 - (plant.rho - K) * plant.q * np.exp(-plant.tau * s)
    scale = 1.0 + np.abs(np.exp(-plant.tau * s))
    np.testing.assert_allclose((A + B)(s) / scale, target / scale, rtol=0, atol=1e-11)


@budget(4, 0.5)
@given(plants())
def test_the_controller_reads_the_measurement_only(case):
    plant, K = case
    controller = OutputFeedback(ReflectionController(K))
    _, B = loop_factors(plant, controller)
    w = 1.0 / plant.mu
    term = observer_term(loop_factors(plant, OpenLoop())[0], loop_factors(plant, ReflectionController(K))[1], w)
    assert term is not None
    nu = np.linspace(0.0, w, 65)[:-1]
    np.testing.assert_allclose(kernel_sum(B, nu), 0.0, atol=10.0 * term.accuracy + 1e-12)


@budget(2, 0.2)
@given(plants(), POINT, st.floats(0.0, 0.5))
@example(case=(nr.Hyperbolic2x2(1.0, 0.5, -2.0, -2.0, 0.25, -3.0), 0.0), s=4.5j, delta=0.0)  # found by make fuzz
def test_the_loop_is_the_literal_predictor(case, s, delta):
    plant, K = case
    A, B = loop_factors(plant, OutputFeedback(ReflectionController(K)))
    open_loop = loop_factors(plant, OpenLoop())[0]
    law = loop_factors(plant, ReflectionController(K))[1]
    w = 1.0 / plant.mu
    grids = [literal_predictor(open_loop, law, w, s, n) for n in (150, 300, 600)]
    # Richardson on 150/300 and on 300/600 points; their difference (the error of the first, 16 times that
    # of the second at the observed fourth order) joins the tolerance: strong couplings on a long window
    # (sigma = -2, 1/mu = 2) left 2.6e-5 on 150/300 points where 600/1200 agree with the loop to 1e-7
    (cz_1, cu_1), (c_z, c_u) = (((4 * b - a) / 3 for a, b in zip(lo, hi)) for lo, hi in itertools.pairwise(grids))
    expected = open_loop(s) * (1 - c_u) - c_z * np.exp(-delta * s)
    spread = abs(open_loop(s) * (cu_1 - c_u)) + abs(cz_1 - c_z)
    mine = A(s) + B(s) * np.exp(-delta * s)
    scale = 1.0 + abs(np.exp(-plant.tau * s)) * (1.0 + abs(c_z))
    np.testing.assert_allclose(mine / scale, expected / scale, rtol=0, atol=5e-7 + spread / scale)
