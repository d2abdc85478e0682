"""A root on the imaginary axis at the delay margin, with a principal part whose chains lie far left.

The reflection loop of a 2x2 plant with ``rho ~ 1e-80`` has the principal part
``1 + 1e-80 e^{-2.27 s} - 3e-241 e^{-3.15 s}``: its chains sit near ``Re s = -81``, and the
far field of ``Re s >= x`` needs a radius of order ``e^{-3.15 x}`` (``1.7e21`` at ``x = -15``)
because the distributed terms grow like ``e^{-nu Re s}``. At ``delta`` equal to the delay
margin the rightmost root lies on the axis. The oracle is the crossing frequency of the
delay margin, an independent computation (the zeros of ``|A(iw)|^2 - |B(iw)|^2`` on the
axis, :func:`nrobust.delay_margin`): ``w = 5.803997633`` at ``delta = 0.8746852124307``.
"""

from __future__ import annotations

import numpy as np
import pytest
from _guards import hard_deadline

import nrobust as nr
from nrobust.hyperbolic import Hyperbolic2x2, ReflectionController
from nrobust.hyperbolic.loops.controllers import characteristic

pytest.importorskip("flint")

# The crossing frequency at the delay margin (nrobust.delay_margin of the same loop, 10 digits).
ROOT_IMAG = 5.803997633


def _loop() -> nr.QuasiPolynomial:
    plant = Hyperbolic2x2(
        1.5847903837500972,
        0.6095371934591387,
        3.3843289054538754,
        -2.835998001112829,
        0.48248901729792465,
        -2.187405413831829e-80,
    )
    return characteristic(plant, ReflectionController(-6.121196611291071e-241), 0.8746852124306884)


@pytest.mark.parametrize("rigorous", [False, True])
def test_root_on_the_axis_with_chains_far_left_is_found_fast(rigorous: bool) -> None:
    # the far field of x_min = C_D + margin had a radius of 1.7e21: the search of that disc hung
    F = _loop()
    with hard_deadline(40.0):
        res = nr.spectral_abscissa(F, rigorous=rigorous)
    assert res.certified and res.root is not None and not res.approached_at_infinity
    np.testing.assert_allclose(res.root.imag, ROOT_IMAG, atol=1e-8)  # the oracle's 10 digits
    np.testing.assert_allclose(res.value, 0.0, atol=1e-9)
    # a root lies on the axis to rounding: the certificate must not exclude it
    assert res.upper_bound >= 0.0 >= -1e-9
    if rigorous:
        assert res.value_bracket is not None and res.root_box is not None
        lo, hi = res.value_bracket
        assert lo <= res.value <= hi and hi - lo < 1e-9
        x0, x1, y0, y1 = res.root_box
        assert x0 < 0.0 < x1 and y0 - 1e-8 < ROOT_IMAG < y1 + 1e-8  # the box is 1e-10 wide
