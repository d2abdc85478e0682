"""Property-based tests of :func:`~nrobust.design.gain.best_margin` on random affine loops.

``F(s; delta, p) = (A_0 + p A_1)(s) + (B_0 + p B_1)(s) e^{-delta s}`` with a retarded or neutral
``A_0``, point delays in ``[0.2, 3]`` and ``p`` in ``[-1, 1]``. The claim checked: the design's delay
margin is the certified margin at its gain, and no gain of a 21-point grid has a larger one (each
from :func:`nrobust.margins.delay_margin`, which does not use the design's crossing-curve scan; a
grid gain where that search cannot decide is left out). A design may be refused only when no gain
is stable without delay (``ParameterError`` naming ``bounds``). Budget as in
``tests/test_fuzz_lti.py``: a few derandomised examples in CI,
``NROBUST_FUZZ_EXAMPLES=N`` random ones under ``make fuzz``.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from _budget import FUZZ, budget
from hypothesis import example, given
from hypothesis import strategies as st

from nrobust import QuasiPolynomial
from nrobust.design.gain import AffineLoop, best_margin
from nrobust.errors import CertificationError, ParameterError
from nrobust.margins import delay_margin

pytestmark = pytest.mark.timeout(0 if FUZZ else 300)

DELAY = st.floats(0.2, 3.0).map(lambda x: round(x, 3))
COEF = st.floats(-2.0, 2.0).map(lambda x: round(x, 3))


@st.composite
def loops(draw: st.DrawFn) -> AffineLoop:
    """``A_0 = (a_0 + s) + (a_1 + n s) e^{-t_1 s}``, ``A_1 = a_2``, ``B_0 = (b_0 + m s) e^{-t_2 s}``,
    ``B_1 = c e^{-t_3 s}`` (``n = 0.3, m = 0.2`` when neutral: ``|n| + |m| < 1``, strongly stable)."""
    t1, t2, t3 = draw(DELAY), draw(DELAY), draw(DELAY)
    a0, a1, b0, a2 = (draw(COEF) for _ in range(4))
    c = draw(COEF.filter(lambda x: x != 0.0))  # the delay enters the loop
    n, m = (0.3, 0.2) if draw(st.booleans()) else (0.0, 0.0)
    a2 = 0.3 * a2 if draw(st.booleans()) else 0.0
    return AffineLoop(
        QuasiPolynomial([[abs(a0) + 0.5, 1.0], [a1, n]], [0.0, t1]),
        QuasiPolynomial([[a2]], [0.0]),
        QuasiPolynomial([[b0, m]], [t2]),
        QuasiPolynomial([[c]], [t3]),
    )


#: Found by this test: the margin rises toward the gain where the loop without delay loses stability
#: (``K = -0.72346``, margin 0.073368), past a minimum of the curve at ``K = -0.92`` that the design took for its
#: smooth maximum (it returned the bound ``K = -1``, margin 0.071796, below the grid's 0.072207 at ``K = -0.8``).
_EDGE_ABOVE_A_MINIMUM = AffineLoop(
    QuasiPolynomial([[1.454, 1.0], [-1.751]], [0.0, 1.928]),
    QuasiPolynomial([[-0.6]], [0.0]),
    QuasiPolynomial([[-1.584]], [1.529]),
    QuasiPolynomial([[-2.0]], [0.333]),
)


@budget(3, 0.2)
@given(loops())
@example(loop=_EDGE_ABOVE_A_MINIMUM)
def test_best_margin_beats_a_grid_of_certified_margins(loop: AffineLoop) -> None:
    try:
        design = best_margin(loop, (-1.0, 1.0))
    except ParameterError as exc:
        assert exc.name == "bounds"
        assert all(_margin_or_none(loop, K) in (0.0, None) for K in np.linspace(-1.0, 1.0, 21))
        return
    except CertificationError as exc:
        if "cannot decide" in str(exc):  # an honest refusal: |A|^2 - |B|^2 flat within rounding (a multiple zero)
            return
        # otherwise a refusal only where the margin has no largest value: it grows without bound toward the gain
        found = re.search(r"grows without bound toward K = (\S+),", str(exc))
        assert found is not None, str(exc)
        K0 = float(found.group(1))
        grid = [m for m in (_margin_or_none(loop, K) for K in np.linspace(-1.0, 1.0, 21)) if m is not None]
        near = [m for m in (_margin_or_none(loop, K0 + h) for h in (-1e-6, 1e-6)) if m is not None]
        assert max(near) > 10.0 * max(grid)
        return
    check = delay_margin(loop.A(design.K), loop.B(design.K))
    # the design's value comes from its crossing equations, solved to rounding; the certified margin too
    np.testing.assert_allclose(design.margin, check.margin, rtol=1e-9)
    grid = [_margin_or_none(loop, K) for K in np.linspace(-1.0, 1.0, 21)]
    assert sum(m is None for m in grid) <= 2  # honest refusals of the oracle (|A(0)| = |B(0)| on a grid gain)
    assert design.margin >= max(m for m in grid if m is not None) * (1.0 - 1e-9)


def _margin_or_none(loop: AffineLoop, K: float) -> float | None:
    """The delay margin at ``K``, or None where its search cannot decide (a zero of high order of
    ``|A|^2 - |B|^2``, e.g. at ``w = 0`` where ``A(0) = B(0)``)."""
    try:
        return float(delay_margin(loop.A(K), loop.B(K)).margin)
    except CertificationError:
        return None
