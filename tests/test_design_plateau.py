"""A decay rate flat in the parameter about its optimum: the kind ``"plateau"`` with its interval.

Two loops whose rightmost zero does not move with the parameter over an interval, the rate known in closed form:

* ``F(s; delta, K) = (s + 1)(s + 5) + K (s + 1) e^{-delta s}``: at ``delta = 0`` the zeros are ``-1`` and
  ``-5 - K``, the decay rate ``min(1, 5 + K)``: flat, 1, for ``K >= -4``. For ``|K| < 5`` no zero crosses the
  axis for any delay (``|s + 5| >= 5 > |K|`` on it): the delay margin is infinite.
* ``FilteredController(a, a, K)`` on the uncoupled plant ``Hyperbolic2x2(1, 1, 0, 0, 1, 0.85)`` (``tau = 2``):
  the filter multiplies both factors by ``1 + a s`` (eq. (60) with the filter), so at ``delta = 0`` the loop is
  ``(1 + a s)(1 - (rho - K) q e^{-tau s})`` (the target system, eqs. (56)-(58)): the zero ``-1/a`` and the chain
  ``Re s = ln|(rho - K) q| / tau``. With ``a = 10`` the rate is ``min(0.1, -ln(0.85 - K) / 2)``: flat for
  ``K >= 0.85 - e^{-0.2} = 0.0312692469``.
"""

from __future__ import annotations

import math

import pytest

from nrobust import Hyperbolic2x2, QuasiPolynomial
from nrobust._digits import with_accuracy
from nrobust.design import DESIGN_KINDS, best_decay_rate
from nrobust.hyperbolic.analyses.filter_design import design_filtered_exact
from nrobust.margins import AffineGainLoop

LOOP = AffineGainLoop(
    QuasiPolynomial([[5.0, 6.0, 1.0]], [0.0]), QuasiPolynomial([[0.0]], [0.0]), QuasiPolynomial([[1.0, 1.0]], [0.0])
)
#: Where the bisection of a plateau's end stops: 40 halvings of at most the width of the bounds.
BISECTION = 2.0**-40


@pytest.mark.parametrize(
    ("bounds", "plateau", "margin_at_least"),
    [
        ((-3.0, 3.0), (-3.0, 3.0), None),  # flat everywhere: was the kind "end" at K = -3
        ((-4.5, 4.9), (-4.0, 4.9), None),  # was an "interior smooth max" with K to 1e-9
        ((-4.5, 4.9), (-4.0, 4.9), 1.0),  # the same under a margin requirement (the margin is infinite)
    ],
)
def test_a_flat_rate_is_a_plateau_with_its_interval(
    bounds: tuple[float, float], plateau: tuple[float, float], margin_at_least: float | None
) -> None:
    """The rate ``min(1, 5 + K)`` (closed form): the design is a ``"plateau"``, its value 1 to the abscissa's
    accuracy, its ``K_bracket`` the gains of ``bounds`` with ``5 + K >= 1``: a bound, or ``K = -4`` to the
    bisection's ``2^-40`` of the width (9.4 at most: 9e-12) plus the rates' accuracies over the slope 1 (measured
    3.6e-12; tolerance 2e-11). The repr prints ``K`` to the plateau's width only (``K=0 +- 1e+1`` for the
    gain 0.2 found on ``[-4, 4.9]``; before, ``K=-1.299983403 +- 1e-9``)."""
    assert "plateau" in DESIGN_KINDS
    d = best_decay_rate(LOOP, bounds, margin_at_least=margin_at_least)
    assert d.kind == "plateau" and d.end is None
    assert abs(d.value - 1.0) <= d.abscissa.accuracy
    lo, hi = d.K_bracket
    assert lo <= d.K <= hi
    width = bounds[1] - bounds[0]
    assert abs(lo - plateau[0]) <= 2.0 * BISECTION * width and hi == plateau[1], (d.K_bracket, plateau)
    assert d.accuracy[0] == pytest.approx(hi - lo)
    assert repr(d).startswith(f"GainDesign(K={with_accuracy(d.K, hi - lo)}, ")


def test_a_smooth_maximum_is_not_a_plateau() -> None:
    """``(s + 1)(s + 5) + K`` at ``delta = 0``: zeros ``-3 +- sqrt(4 - K)``, the rate ``3 - sqrt(4 - K)`` for
    ``K <= 4`` and 3 above (a complex pair, ``Re s = -3``): flat for ``K >= 4``, rising before. On ``[0, 3.9]``
    the rate rises to the end (kind ``"end"``, not a plateau: the probe ``1e-3`` of the scale, 0.0039, inside
    is 0.0061 lower); on ``[0, 4.5]`` the plateau is ``[4, 4.5]`` (the end ``K = 4``: the rate ``3 - sqrt(4 - K)``
    is within ``1e-12`` of 3 for ``4 - K <= 1e-24``, the bisection's ``2^-40`` of the width 4.5, 4e-12, decides:
    measured 2.7e-12, tolerance 1e-11)."""
    loop = AffineGainLoop(
        QuasiPolynomial([[5.0, 6.0, 1.0]], [0.0]), QuasiPolynomial([[0.0]], [0.0]), QuasiPolynomial([[1.0]], [0.0])
    )
    rising = best_decay_rate(loop, (0.0, 3.9))
    assert rising.kind == "end" and rising.K == 3.9
    assert abs(rising.value - (3.0 - math.sqrt(0.1))) <= rising.abscissa.accuracy
    flat = best_decay_rate(loop, (0.0, 4.5))
    assert flat.kind == "plateau" and abs(flat.value - 3.0) <= flat.abscissa.accuracy
    assert abs(flat.K_bracket[0] - 4.0) < 1e-11 and flat.K_bracket[1] == 4.5, flat.K_bracket


def test_the_filtered_law_with_its_zero_on_its_pole_has_a_plateau() -> None:
    """``design_filtered_exact`` of ``K`` in ``FilteredController(10, 10, K)`` on the uncoupled plant, the rate
    ``min(0.1, -ln(0.85 - K) / 2)`` (module notes): a ``"plateau"`` of rate 0.1 from ``K = 0.85 - e^{-0.2}`` to the
    bound 0.14. The lower end is where the chain meets the filter's zero ``-0.1``: there the abscissa's accuracy
    grows to 4.7e-8 (the two tie; measured), so gains up to ``4.7e-8 / 0.61`` (the chain's slope in ``K``) below it
    are within the accuracy of 0.1 too (measured: the end 2.6e-8 below); tolerance 1e-7. About 4 s of CPU time."""
    plant = Hyperbolic2x2(1.0, 1.0, 0.0, 0.0, 1.0, 0.85)
    d = design_filtered_exact(
        plant, "decay_rate", parameters={"K": (-0.14, 0.14), "a": 10.0, "b": 10.0}, margin_at_least=0.05
    )
    g = d.design
    assert d.kind == "plateau" and g.kind == "plateau"
    assert abs(g.value - 0.1) <= g.abscissa.accuracy
    lo, hi = g.K_bracket
    assert abs(lo - (0.85 - math.exp(-0.2))) < 1e-7 and hi == 0.14, g.K_bracket
