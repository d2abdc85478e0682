"""The collocated observer's one-parameter designs give the numbers they gave before their evaluations were sped up.

The kernels of their loops are integrated together (:func:`nrobust.distributed_delay.moment_integrals`) and the
observer's products evaluate their pieces one power at a time (the same arithmetic, the same numbers bit for
bit); the command response's not-a-knot splines are solved by numpy instead of scipy's ``CubicSpline`` (the same
splines to rounding: the numbers below moved by at most 7e-14 relative). The values were computed before these
changes, on the paper's plant; the tolerance, ``1e-12`` relative, is the one asked of a faster evaluation (the
designs' stated accuracy is ``1e-10``).
"""

from __future__ import annotations

import pytest

import nrobust as nr
from nrobust import Hyperbolic2x2, ReflectionController

PAPER = Hyperbolic2x2(1, 1, 1, 1, 1, 0.85)
RTOL = 1e-12

# (gain, objective's value, delay margin, decay rate, critical frequency), kind
RECORDED = {
    "observer margin": (
        (-0.7149450549450549, 0.19480276875922264, 0.19480276875922264, 0.14384103622589053, 3.191491014857545),
        "end",
    ),
    "observer rate": (
        (-0.7149450549450549, 0.14384103622589053, 0.19480276875922264, 0.14384103622589053, 3.191491014857545),
        "plateau",  # the rate -ln|(rho - K) q| / tau of the law does not move with kappa (it was labelled "end")
    ),
    "collocated law rate": (
        (0.1928571428571429, 0.20992692278013209, 0.15254352234083313, 0.20992692278013209, 15.69957001902849),
        "end",
    ),
}


def _design(name):
    if name == "observer margin":
        return nr.design_collocated_observer(PAPER, "margin", controller=ReflectionController(0.1))
    if name == "observer rate":
        return nr.design_collocated_observer(
            PAPER, "decay_rate", controller=ReflectionController(0.1), margin_at_least=0.1
        )
    return nr.design_reflection(PAPER, "decay_rate", margin_at_least=0.1, output_feedback=True, collocated=True)


@pytest.mark.parametrize("name", list(RECORDED))
def test_recorded_values(name):
    design = _design(name).design
    numbers, kind = RECORDED[name]
    got = (design.K, design.value, design.margin, design.decay_rate, design.certificate.omega)
    assert design.kind == kind
    for value, recorded in zip(got, numbers, strict=True):
        assert value == pytest.approx(recorded, rel=RTOL, abs=0.0)
