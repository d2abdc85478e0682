"""Exact one-parameter designs of the filtered law FilteredController(a, b, K) against oracles.

The loop is eq. (60) with A multiplied by (1 + b s) and B by (1 + a s) (nrobust.design.AffineLoop,
FilteredLoop.affine). Oracles, none of them through the design's scan or its equations:

* the kink of delta*(K) under a filter, solved by mpmath at 40 digits from the two crossing
  equations written here from the loop's definition and the closed-form boundary function of the
  paper's plant (no kernel, no nrobust code path);
* certified delay margins (nrobust.margins.delay_margin) on a grid of the free parameter: the
  design must match or beat every one, and the best of them must come within the grid's reach;
* for the best decay rate under a required margin: the parameter where the certified margin
  reaches the requirement, by bisection on certified margins, and the rightmost root there.
"""

from __future__ import annotations

import json
import time

import mpmath as mp
import numpy as np
import pytest
from _oracles import paper_factors
from scipy.optimize import brentq

from nrobust import Hyperbolic2x2
from nrobust.design import AffineLoop, best_margin
from nrobust.errors import ParameterError
from nrobust.hyperbolic.analyses.filter_design import (
    ExactFilteredDesign,
    design_filtered,
    design_filtered_exact,
    filtered_loop,
)
from nrobust.margins import delay_margin
from nrobust.roots import spectral_abscissa

# the paper's example (section 4.2): lam = mu = sigma_pm = sigma_mp = q = 1, rho = 0.85, tau = 2
RHO, Q = 0.85, 1.0
PLANT = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, RHO)


def _factors_mp(s: mp.mpc, K: mp.mpf, a: mp.mpf, b: mp.mpf) -> tuple[mp.mpc, mp.mpc]:
    """A(s) (1 + b s) and B(s; K) (1 + a s): eq. (60) with the filter, at the working precision (the unfiltered
    factors of the paper's plant in closed form, :func:`_oracles.paper_factors`)."""
    A, B = paper_factors(s, K)
    return A * (1 + b * s), B * (1 + a * s)


def _delay_mp(w: mp.mpf, K: mp.mpf, a: mp.mpf, b: mp.mpf) -> mp.mpf:
    """theta / w, theta = arg(-B/A) in [0, 2 pi): the first delay of the crossing at i w."""
    A, B = _factors_mp(mp.mpc(0, w), K, a, b)
    theta = mp.arg(-B / A)
    return (theta if theta >= 0 else theta + 2 * mp.pi) / w


def _crossings(K: float, a: float, b: float, w_max: float) -> list[tuple[float, float]]:
    """(w, delay) of the crossings of the filtered loop up to w_max, from a grid and mpmath's root finder."""
    mp.mp.dps = 20
    w = np.linspace(0.05, w_max, 1200)
    g = []
    for x in w:
        A, B = _factors_mp(mp.mpc(0, x), mp.mpf(K), mp.mpf(a), mp.mpf(b))
        g.append(float(abs(A) ** 2 - abs(B) ** 2))
    out = []
    for j in np.flatnonzero(np.sign(g[:-1]) != np.sign(g[1:])):

        def gap(x: mp.mpf) -> mp.mpf:
            A, B = _factors_mp(mp.mpc(0, x), mp.mpf(K), mp.mpf(a), mp.mpf(b))
            return abs(A) ** 2 - abs(B) ** 2

        x = mp.findroot(gap, (mp.mpf(w[j]), mp.mpf(w[j + 1])), solver="anderson")
        out.append((float(x), float(_delay_mp(x, mp.mpf(K), mp.mpf(a), mp.mpf(b)))))
    return out


@pytest.fixture(scope="module")
def kink() -> tuple[ExactFilteredDesign, float, float]:
    start_cpu, start = time.process_time(), time.perf_counter()
    design = design_filtered_exact(PLANT, parameters={"K": (0.0, 0.14), "a": 0.0, "b": 0.05})
    return design, time.process_time() - start_cpu, time.perf_counter() - start


def test_kink_of_the_gain_under_a_low_pass_matches_mpmath(
    kink: tuple[ExactFilteredDesign, float, float],
) -> None:
    design, cpu, _ = kink
    assert design.parameter == "K" and design.kind == "kink"
    # the two crossings with the smallest delays at the design: the branches that meet at the kink
    (w1, d1), (w2, d2) = sorted(_crossings(design.optimum, 0.0, 0.05, 14.0), key=lambda c: c[1])[:2]
    assert abs(d1 - d2) < 1e-6  # they meet there (to the grid search's accuracy)
    mp.mp.dps = 40
    a, b = mp.mpf(0), mp.mpf("0.05")

    def equations(K: mp.mpf, x1: mp.mpf, x2: mp.mpf) -> list[mp.mpf]:
        A1, B1 = _factors_mp(mp.mpc(0, x1), K, a, b)
        A2, B2 = _factors_mp(mp.mpc(0, x2), K, a, b)
        return [
            abs(A1) ** 2 - abs(B1) ** 2,
            abs(A2) ** 2 - abs(B2) ** 2,
            _delay_mp(x1, K, a, b) - _delay_mp(x2, K, a, b),
        ]

    # started 1e-3 away from the design: the root is mpmath's, not the design's
    K, x1, _ = mp.findroot(equations, (mp.mpf(round(design.optimum, 3)), mp.mpf(w1), mp.mpf(w2)))
    margin = _delay_mp(x1, K, a, b)
    # 1e-10: the design's Newton solves to ~1e-15; the loop factors carry ~1e-15 of rounding and quadrature
    np.testing.assert_allclose(design.optimum, float(K), rtol=0, atol=1e-10)
    np.testing.assert_allclose(design.value, float(margin), rtol=0, atol=1e-10)
    assert design.design.accuracy[0] < 1e-10 and design.design.accuracy[1] < 1e-10
    assert design.controller.K == design.optimum and design.controller.b == 0.05
    json.dumps([design.controller.to_dict(), design.design.to_dict()], allow_nan=False)
    assert cpu < 10.0


@pytest.fixture(scope="module")
def cutoff() -> ExactFilteredDesign:
    return design_filtered_exact(PLANT, parameters={"K": -0.0832482936, "a": 0.341, "b": (0.8, 1.2)})


def test_pair_birth_of_the_cutoff_matches_mpmath(cutoff: ExactFilteredDesign) -> None:
    design = cutoff
    assert design.parameter == "b" and design.kind == "pair birth"
    K, a = mp.mpf("-0.0832482936"), mp.mpf("0.341")
    # the birth is the end of the bracket away from the design (the design sits on the side without the pair)
    lo, hi = design.design.K_bracket
    birth = lo if hi == design.optimum else hi
    side = 1.0 if design.optimum > birth else -1.0
    # on the other side the pair exists: its two crossings are the closest pair of frequencies
    ws = sorted(w for w, _ in _crossings(float(K), float(a), birth - 0.02 * side, 14.0))
    j = int(np.argmin(np.diff(ws)))
    mp.mp.dps = 40

    def g(w: mp.mpf, b: mp.mpf) -> mp.mpf:
        A, B = _factors_mp(mp.mpc(0, w), K, a, b)
        return abs(A) ** 2 - abs(B) ** 2

    def equations(b: mp.mpf, w: mp.mpf) -> list[mp.mpf]:  # g = dg/dw = 0: a double crossing
        return [g(w, b), mp.diff(lambda x: g(x, b), w)]

    b_star, w_star = mp.findroot(equations, (mp.mpf(round(birth, 3)), mp.mpf(0.5 * (ws[j] + ws[j + 1]))))
    # the birth to 1e-10 (the design's brentq on dK/dw solves it to ~1e-15, the factors carry ~1e-15)
    np.testing.assert_allclose(birth, float(b_star), rtol=0, atol=1e-10)
    assert design.optimum - float(b_star) == pytest.approx(side * 1e-10 * 1.2, abs=1e-15)
    # the margin there is the delay of the lowest other crossing, at least that of the pair (born below it)
    assert _delay_mp(w_star, K, a, b_star) < design.value
    assert design.certified == "checked" and design.design.certificate.margin == design.value


def _grid_margins(name: str, base: dict[str, float], values: np.ndarray) -> np.ndarray:
    family = filtered_loop(PLANT, {**base, name: None})
    return np.array([delay_margin(*family(np.array([p]))).margin for p in values])


def _check_against_grid(design: ExactFilteredDesign, base: dict[str, float], n: int) -> None:
    lo, hi = design.design.bounds
    values = np.linspace(lo, hi, n)
    margins = _grid_margins(design.parameter, base, values)
    # the design matches or beats every certified margin of the grid (1e-12: their accuracy)
    assert margins.max() <= design.value + 1e-12
    # and the grid's best comes within its reach: the largest change between neighbours, the most the
    # envelope can rise within one cell towards the design
    reach = float(np.max(np.abs(np.diff(margins))))
    assert margins.max() >= design.value - reach


# (parameter, fixed values, bounds): each parameter free alone about the three-parameter margin optimum of
# docs/design.md (K = -0.0832482936, a = 0.341, b = 1.0087292910: margin 0.6273230551)
CASES = [
    ("K", {"a": 0.341, "b": 1.008729291}, (-0.1, 0.1)),
    ("a", {"K": -0.0832482936, "b": 1.008729291}, (0.0, 1.0)),
    ("b", {"K": -0.0832482936, "a": 0.341}, (0.8, 1.2)),
]
# under 1 s of CPU each (benchmarks/design_onepar.py): the cut-off in the fast suite, the gain and the zero with the
# long tests
FAST_CASES = [pytest.param(*case, marks=[] if case[0] == "b" else [pytest.mark.long]) for case in CASES]


@pytest.mark.parametrize("name, fixed, bounds", FAST_CASES)
def test_each_parameter_alone_beats_the_local_optimum(
    name: str, fixed: dict[str, float], bounds: tuple, cutoff: ExactFilteredDesign
) -> None:
    design = cutoff if name == "b" else design_filtered_exact(PLANT, parameters={**fixed, name: bounds})
    # the local optimiser's point is feasible for each one-parameter problem: the exact optimum is no worse
    assert design.value >= 0.6273230551 - 1e-9
    assert design.kind == "pair birth"  # a crossing pair is born just past the optimum
    lo, hi = design.design.K_bracket
    # the supremum is approached from the side without the pair: certified margins on that side
    assert lo <= design.optimum <= hi and hi - lo < 1e-9
    _check_against_grid(design, fixed, 9)


@pytest.mark.long
@pytest.mark.parametrize("name, fixed, bounds", CASES)
def test_each_parameter_against_40_certified_margins(name: str, fixed: dict[str, float], bounds: tuple) -> None:
    design = design_filtered_exact(PLANT, parameters={**fixed, name: bounds})
    _check_against_grid(design, fixed, 40)


def test_decay_rate_under_a_margin_at_the_requirement() -> None:
    d = 0.4
    fixed = {"K": 0.0, "a": 0.0}
    design = design_filtered_exact(PLANT, "decay_rate", parameters={**fixed, "b": (0.05, 1.0)}, margin_at_least=d)
    assert design.parameter == "b" and design.kind == "margin constraint"
    assert design.design.end is not None and design.design.end.kind == "crossing"
    assert design.design.margin >= d
    family = filtered_loop(PLANT, {**fixed, "b": None})

    def excess(b: float) -> float:
        return delay_margin(*family(np.array([b]))).margin - d

    # the end of {b : delta*(b) >= d} next to the design, by Brent's method on certified margins
    side = 1.0 if design.design.end.K > design.optimum else -1.0
    step = 1e-3 * side
    assert excess(design.optimum) >= 0.0 > excess(design.optimum + step)
    b_end = brentq(excess, *sorted((design.optimum, design.optimum + step)), xtol=1e-14, rtol=1e-14)
    # 2e-10: the design sits 1e-10 (relative to the bounds) inside the end
    np.testing.assert_allclose(design.optimum, b_end, rtol=0, atol=2e-10)
    A, B = family(np.array([b_end]))
    rate = -spectral_abscissa(A + B).value
    # the decay rate at the end (its slope in b is O(0.1): 2e-10 in b moves it by far less than 1e-9)
    np.testing.assert_allclose(design.value, rate, rtol=0, atol=1e-9)


def test_affine_loop_of_a_gain_loop_gives_the_same_kink() -> None:
    family = filtered_loop(PLANT, {"K": None, "a": 0.0, "b": 0.0})
    as_affine = family.affine()
    assert isinstance(as_affine, AffineLoop)
    design = best_margin(as_affine, (0.0, 0.12))
    # the unfiltered optimum of docs/design.md (design_reflection), from U_BS2's own loop
    np.testing.assert_allclose(design.K, 0.07855293005948, rtol=0, atol=1e-12)
    np.testing.assert_allclose(design.margin, 0.23229251319035, rtol=0, atol=1e-12)


def test_refuses_bad_arguments() -> None:
    with pytest.raises(ParameterError, match="parameters"):
        design_filtered_exact(PLANT, parameters={"K": None, "a": None, "b": 0.1})
    with pytest.raises(ParameterError, match="parameters"):
        design_filtered_exact(PLANT, parameters={"K": 0.1, "a": 0.0, "b": 0.1})
    with pytest.raises(ParameterError, match="objective"):
        design_filtered_exact(PLANT, "speed", parameters={"K": None, "a": 0.0, "b": 0.1})
    with pytest.raises(ParameterError, match="margin_at_least"):
        design_filtered_exact(PLANT, "decay_rate", parameters={"K": None, "a": 0.0, "b": 0.1})
    with pytest.raises(ParameterError, match="parameters\\['b'\\]"):
        design_filtered_exact(PLANT, parameters={"K": 0.1, "a": 0.0, "b": (0.0, 1.0)})
    with pytest.raises(ParameterError, match=r"^parameters\['a'\] must be"):  # past |a K| = b k: no frequency bound
        design_filtered_exact(PLANT, parameters={"K": 0.1, "a": (0.0, 0.5), "b": 0.1})
    # bounds that are not a pair low < high are named by their parameter
    for bad in ((0.1, 0.0), (0.1,), (0.0, 0.1, 0.2), "K", (0.0, np.inf)):
        with pytest.raises(ParameterError, match=r"^parameters\['K'\] must be"):
            design_filtered_exact(PLANT, parameters={"K": bad, "a": 0.0, "b": 0.05})
        with pytest.raises(ParameterError, match=r"^parameters\['K'\] must be"):
            design_filtered(PLANT, parameters={"K": bad, "a": 0.0, "b": 0.05})
    with pytest.raises(ParameterError, match="free"):
        filtered_loop(PLANT, {"K": None, "a": None, "b": 0.1}).affine()
