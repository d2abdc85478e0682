"""The bounds that settle trial points of nrobust.design.local without a full evaluation.

Oracles, sharing no code with the bounds: the margin ``arccos(-1/k)/sqrt(k^2 - 1)`` of
``s + 1 + k e^{-delta s}`` (crossing ``w = sqrt(k^2 - 1)``), the crossings ``w^2 = c -+ b`` of
``s^2 + c + b e^{-delta s}`` (delay ``pi / sqrt(c - b)``), the zeros ``W_k(-b e^a) - a`` of
``s + a + b e^{-s}`` (SciPy's Lambert W), and the zeros ``ln(r)/tau + i (2 m + 1) pi / tau`` of
``1 + r e^{-tau s}``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import lambertw

import nrobust as nr
from nrobust.design.local import _crossing_near, _Local, _Problem
from nrobust.roots import spectral_abscissa

ONE = nr.QuasiPolynomial([[1.0, 1.0]], [0.0])  # s + 1


def _first_order(p: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
    return ONE, nr.QuasiPolynomial([[p[0]]], [0.0])


def _margin(k: float) -> float:
    return math.acos(-1.0 / k) / math.sqrt(k * k - 1.0)


def test_a_witness_crossing_bounds_the_margin() -> None:
    k = 3.0
    A, B = _first_order(np.array([k]))
    w, margin = math.sqrt(k * k - 1.0), _margin(k)
    # the crossing is refined to 1e-8 w: its delay to |d delta/dw| 1e-8 w ~ 1e-8
    np.testing.assert_allclose(_crossing_near(A, B, [1.01 * w], 1.0), margin, rtol=1e-7)
    assert _crossing_near(A, B, [1.01 * w], margin * (1 - 1e-6)) == math.inf  # not below the level
    assert _crossing_near(A, B, [2.0 * w], 1.0) == math.inf  # no crossing in the window
    assert _crossing_near(A, B, [], 1.0) == math.inf


def test_a_pair_between_two_samples_is_found() -> None:
    """``s^2 + 9 + 0.001 e^{-delta s}``: ``g = (9 - w^2)^2 - 1e-6`` is negative on a band of
    ``3.3e-4`` only, between two samples of the window about ``w0 = 3.0015`` (spacing 3e-3)."""
    c, b = 9.0, 1e-3
    A, B = nr.QuasiPolynomial([[c, 0.0, 1.0]], [0.0]), nr.QuasiPolynomial([[b]], [0.0])
    grid = 3.0015 * (1.0 + np.linspace(-0.02, 0.02, 41))
    g = (c - grid**2) ** 2 - b**2
    assert np.all(g > 0.0)  # the samples alone see no sign change
    # at w^2 = c - b, A(i w) = b = B and e^{-i w delta} = -1: delta = pi / w (at w^2 = c + b the phase is 0)
    np.testing.assert_allclose(_crossing_near(A, B, [3.0015], 2.0), math.pi / math.sqrt(c - b), rtol=1e-7)


@pytest.mark.parametrize("two_stages", [False, True])
def test_the_margin_test_matches_the_closed_form(two_stages: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """In two stages: ``|w| <= 0.1 pi / d`` (below every crossing ``sqrt(k^2 - 1) >= 1.1`` here), then the rest."""
    if two_stages:
        monkeypatch.setattr("nrobust.design.local.LOW_BAND", 0.05)
        monkeypatch.setattr("nrobust.design.local.LOW_BAND_FROM", 0.0)
    problem = _Problem(_first_order, np.array([(0.0, 5.0)]), "decay_rate", 0.5, 0.999)
    for k in (1.5, 3.0, 4.0):
        A, B = _first_order(np.array([k]))
        sa = spectral_abscissa(A + B)
        for d in (0.3, 0.5, 0.8):
            ok, margin = problem._meets(A, B, sa, d)
            assert ok == (_margin(k) >= d)
            if ok:  # the certified crossing, to rounding
                np.testing.assert_allclose(margin, _margin(k), rtol=1e-12)
            else:  # a crossing delay below d: an upper bound of the margin
                assert _margin(k) - 1e-12 <= margin < d


def test_witness_roots_bound_the_abscissa_from_below() -> None:
    """``s + a + b e^{-s}``: the rightmost zeros are ``W_0(-b e^a) - a`` (a complex pair here)."""

    def loop(p: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
        return nr.QuasiPolynomial([[p[0], 1.0], [p[1]]], [0.0, 1.0]), nr.QuasiPolynomial([[0.0]], [0.0])

    problem = _Problem(loop, np.array([(0.0, 3.0), (0.0, 3.0)]), "decay_rate", None, 0.999)
    start = problem(np.array([0.5, 1.5]))  # records its rightmost root as a witness
    assert start.feasible and problem.memo.roots
    a, b = 0.45, 1.55
    exact = complex(lambertw(-b * math.exp(a), 0)) - a  # (s + a) e^{s + a} = -b e^a
    F = sum(loop(np.array([a, b])), nr.QuasiPolynomial([[0.0]], [0.0]))
    floor, why = problem._abscissa_floor(F, exact.real - 1e-3)
    # the left edge of a box of half-width 1e-6 (1 + |s|) about the zero, proven to hold it
    assert floor <= exact.real and "zero" in why
    np.testing.assert_allclose(floor, exact.real, atol=2e-6 * (1.0 + abs(exact)))
    assert problem._abscissa_floor(F, exact.real + 1e-3)[0] == -math.inf  # nothing right of the line


def test_a_screened_point_is_never_feasible_and_is_remembered() -> None:
    """A neutral loop ``1 + r e^{-2 s}`` (zeros on ``Re s = ln(r)/2``): the chains reject a point
    whose ``r`` puts them right of the line, before any spectral abscissa."""

    def loop(p: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
        return nr.QuasiPolynomial([[1.0], [p[0]]], [0.0, 2.0]), nr.QuasiPolynomial([[0.0]], [0.0])

    problem = _Problem(loop, np.array([(0.1, 0.9)]), "decay_rate", None, 0.999)
    x = problem(np.array([0.5]))
    np.testing.assert_allclose(x.value, math.log(0.5) / 2.0, rtol=1e-12)
    full = problem.memo.full
    y = problem(np.array([0.6]), above=x.value)
    assert y.screened and not y.feasible and problem.memo.full == full
    np.testing.assert_allclose(y.value, math.log(0.6) / 2.0, rtol=1e-12)  # the chain value: a lower bound
    assert problem(np.array([0.6]), above=x.value).reason == "above the line (remembered bound)"
    z = problem(np.array([0.6]))  # without a line: evaluated in full, the same value
    assert z.feasible and not z.screened
    np.testing.assert_allclose(z.value, math.log(0.6) / 2.0, rtol=1e-12)


@pytest.mark.parametrize("objective", ["decay_rate", "margin"])
def test_screening_keeps_the_trajectory_to_the_optimum(objective: str) -> None:
    """The same run with an empty memo at every evaluation (no witness, no remembered value) ends
    at the same design, after as many evaluations: the bounds only skip work on points the search
    rejects anyway. On ``s + 1 + k e^{-delta s}``, ``k`` in ``[1.2, 5]``: the decay rate (root
    ``-1 - k``) under ``delta* >= 0.8`` is best where the margin is 0.8, and the margin (decreasing
    in ``k``) at ``k = 1.2``."""

    class Forgetful(_Problem):
        def __call__(self, p, want=None, above=math.inf):
            object.__setattr__(self, "memo", type(self.memo)())
            return super().__call__(p, want, above)

    required = 0.8 if objective == "decay_rate" else None
    bounds = np.array([(1.2, 5.0)])
    runs = [
        _Local(cls(_first_order, bounds, objective, required, 0.999), 20, 1e-6)((2.0,)) for cls in (_Problem, Forgetful)
    ]
    np.testing.assert_allclose(runs[0].parameters, runs[1].parameters, rtol=0, atol=0)
    assert runs[0].evaluations == runs[1].evaluations and runs[0].screened > runs[1].screened == 0
    best = brentq(lambda k: _margin(k) - 0.8, 1.0 + 1e-9, 5.0, xtol=1e-14) if required else 1.2
    # the last step the pattern search tries is at most 2 POLISH_TOL of the width (halved from
    # POLISH_START = 1e-2 until it is below POLISH_TOL = 1e-5): 7.6e-5 here
    np.testing.assert_allclose(runs[0].parameters[0], best, atol=2e-5 * 3.8)
