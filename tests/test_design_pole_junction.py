"""Poles of the crossing curves between two samples of the scan (:meth:`_Curves._split_poles`), and the scan next
to them.

On the collocated observer's loop of U_BS2(0.1) on the plant ``(1, 1, 1, 1, 1, 0.8)`` the
curvature ``c_2`` of ``g(w; kappa)`` changes sign near ``w = 3.180`` and the discriminant ``D``
vanishes near ``w = 3.185``, both between the samples ``3.171875`` and ``3.1875`` (step
``1/64``). The piece of curve between them reaches every ``kappa`` below about ``-0.51`` with
the smallest crossing delay there (about ``0.232`` at ``w ~ 3.1847``); a scan that misses it
put a kink at ``kappa = -0.5442`` with the delay ``0.4345`` and refused the design when its
certificate found ``0.2320``.

On the plant ``(1, 1, 1, 1, 1, 0.9)``: a branch leaves through ``kappa = -inf`` at the pole
``w = 15.7159``, and between the sample ``15.703125`` (``kappa = -0.224``) and the pole it
reaches every ``kappa`` below, with the smallest crossing delay there (``0.1262`` at ``-0.35``);
a birth at ``kappa = -2.406`` between two poles, estimated at ``0.863``, made a curve seem to
reach ``kappa = -0.202``, where Newton found no root and the design refused; and the refinement's
5 % window about an envelope that interpolation had put 10 % low left out the lowest curve.

Oracles: the certified delay margins of loops built at each ``kappa`` by
:func:`~nrobust.hyperbolic.loops.controllers.loop_factors` (no code shared with the affine
family's scan), a brute-force grid of them, and the recorded ``rho = 0.85`` design
(``tests/test_collocated_design_values.py``).
"""

from __future__ import annotations

import numpy as np
import pytest

import nrobust as nr
from nrobust.design.gain import _Curves, _Family
from nrobust.hyperbolic.analyses.observer_design import collocated_observer_loop
from nrobust.hyperbolic.loops.controllers import CollocatedOutputFeedback, ReflectionController

PLANT = nr.Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.8)
PLANT_09 = nr.Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.9)
INNER = ReflectionController(0.1)


def _margin(kappa: float, plant: nr.Hyperbolic2x2 = PLANT) -> nr.DelayMargin:
    return nr.delay_margin(plant, CollocatedOutputFeedback(INNER, 0.0, float(kappa)))


@pytest.mark.parametrize("kappa", [-0.65, -0.6, -0.5442, -0.52])
def test_scan_has_the_curve_between_pole_and_junction(kappa):
    """The scan's exact envelope equals the certified margin where the curve at ``w ~ 3.1847`` is the lowest.

    The two routes agreed to 2e-15 relative in a study at these ``kappa``; ``1e-10`` leaves room
    for rounding and is far below the gap to the next curve (0.4345 against 0.2320 at -0.5442).
    """
    loop = collocated_observer_loop(PLANT, CollocatedOutputFeedback(INNER, 0.0))
    curves = _Curves(_Family(loop), -0.7118266253869969, 0.07777089783281727, 2_000_000)
    margin = _margin(kappa)
    assert abs(margin.omega - 3.1847) < 1e-3  # the curve that passes between the pole and the junction
    assert curves.value(kappa) == pytest.approx(margin.margin, rel=1e-10, abs=0.0)


def test_rho_08_design_matches_its_certificate_and_beats_the_grid():
    """The design at ``rho = 0.8``: a kink whose margin the designed loop's certified margin confirms, no smaller
    than the certified margin anywhere on a grid of ``kappa`` (uniform, and about the kink and the false one).

    Both margins are certified to their stated accuracies (about 1.2e-6 each, the model's); the design
    must match or beat each grid value to their sum.
    """
    design = nr.design_collocated_observer(PLANT, "margin", controller=INNER)
    assert design.design.kind == "kink"
    checked = nr.delay_margin(PLANT, design.controller)
    tol = design.design.certificate.accuracy + checked.accuracy
    assert abs(checked.margin - design.value) <= tol
    lo, hi = design.bounds
    kappas = np.concatenate([np.linspace(lo, hi, 9), design.kappa + np.array([-1e-3, -1e-4, 1e-4, 1e-3]), [-0.5442]])
    for kappa in kappas[(kappas >= lo) & (kappas <= hi)]:
        grid = _margin(kappa)
        assert design.value >= grid.margin - (design.design.certificate.accuracy + grid.accuracy), kappa


@pytest.mark.parametrize(
    ("kappa", "omega"),
    [pytest.param(-0.35, 15.7047, marks=pytest.mark.long), (-0.3, 15.7041), (-0.202066666666667, 15.7027)],  # 7 s
)
def test_scan_follows_a_curve_to_its_pole(kappa, omega):
    """The exact envelope of the ``rho = 0.9`` scan equals the certified margin where the curve that leaves through
    ``kappa = -inf`` at ``w = 15.7159`` is the lowest (agreement 2e-15 relative in a study, as above)."""
    loop = collocated_observer_loop(PLANT_09, CollocatedOutputFeedback(INNER, 0.0))
    curves = _Curves(_Family(loop), -0.7178888888888889, 0.01899999999999999, 2_000_000)
    margin = _margin(kappa, PLANT_09)
    assert abs(margin.omega - omega) < 1e-3
    assert curves.value(kappa) == pytest.approx(margin.margin, rel=1e-10, abs=0.0)


def test_rho_09_design_matches_its_certificate_and_beats_the_grid():
    """The design at ``rho = 0.9``: the upper end of the bounds (the margin grows with ``kappa`` over them: 0.1184
    at the lower end, 0.1262 at -0.35, 0.1306 at the upper), confirmed by the designed loop's certified margin and
    no smaller than a grid of certified margins to the sum of their accuracies (about 6e-7 each)."""
    design = nr.design_collocated_observer(PLANT_09, "margin", controller=INNER)
    lo, hi = design.bounds
    assert design.design.kind == "end"
    assert design.kappa == hi
    checked = nr.delay_margin(PLANT_09, design.controller)
    assert abs(checked.margin - design.value) <= design.design.certificate.accuracy + checked.accuracy
    for kappa in [*np.linspace(lo, hi, 7), -0.35, hi - 1e-3]:
        grid = _margin(kappa, PLANT_09)
        assert design.value >= grid.margin - (design.design.certificate.accuracy + grid.accuracy), kappa
