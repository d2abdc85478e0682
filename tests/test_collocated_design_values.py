"""The collocated observer's one-parameter designs: their gains, and margins and crossing frequencies as the PDE's.

The gains are ends of the design bounds and the decay rates the state feedback's closed form ``-ln|(rho - K) q| /
tau`` (the observer's term cancels at ``delta = 0``): they are pinned at ``1e-12`` relative (recorded before the
designs' evaluations were sped up, which moved them by at most ``7e-14`` relative). The margins and crossing
frequencies are proven of the PDE (the observer's ``G`` from the kernels' Taylor enclosures, the reflection's terms
in closed form, in ball arithmetic): they are pinned at the PDE's values, 40-digit ``_collocated_oracle`` (the
kernels as Taylor series), and asserted within the accuracies the designs state (3e-13 for the observer's designs,
1.2e-11 for the law's; the values are 2e-16 and 2.5e-14 from the PDE's). While the observer's terms were a model's
(kernels on 201 points) the stated accuracies were at most 5e-9 (a convergence study in the observer's grid), and
before the composition ``F = (I - K') f`` took Gregory's end corrections the model margins were 1.3e-7
(0.19480276875922264) and 1.6e-7 (0.15254352234083313) from the PDE's.
"""

from __future__ import annotations

import math

import pytest
from _collocated_oracle import CollocatedPDE

import nrobust as nr
from nrobust import Hyperbolic2x2, ReflectionController

ARGS = (1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
PAPER = Hyperbolic2x2(*ARGS)
RTOL = 1e-12
#: The PDE's delay margins and crossing frequencies (``_collocated_oracle``, 40 digits; 20 quoted).
PDE_OBSERVER = (0.19480264109353176829, 3.1914911452878906585)  # U_BS2(0.1), kappa = -0.7149450549450549
PDE_LAW = (0.15254335603258105131, 15.699570179571697416)  # U_BS2(0.1928571428571429), kappa = 0

# (gain, objective's value or None for the margin, decay rate), the PDE's (margin, omega), kind
RECORDED = {
    "observer margin": ((-0.7149450549450549, None, 0.14384103622589053), PDE_OBSERVER, "end"),
    "observer rate": (
        (-0.7149450549450549, 0.14384103622589053, 0.14384103622589053),
        PDE_OBSERVER,
        "plateau",  # the rate -ln|(rho - K) q| / tau of the law does not move with kappa (it was labelled "end")
    ),
    "collocated law rate": ((0.1928571428571429, 0.20992692278013209, 0.20992692278013209), PDE_LAW, "end"),
}


def _design(name):
    if name == "observer margin":
        return nr.design_collocated_observer(PAPER, "margin", controller=ReflectionController(0.1))
    if name == "observer rate":
        return nr.design_collocated_observer(
            PAPER, "decay_rate", controller=ReflectionController(0.1), margin_at_least=0.1
        )
    return nr.design_reflection(PAPER, "decay_rate", margin_at_least=0.1, output_feedback=True, collocated=True)


def test_the_rates_are_the_closed_form():
    """The recorded decay rates are ``-ln|(rho - K) q| / tau`` of U_BS2(0.1) and U_BS2(0.1928571428571429)."""
    for K, name in ((0.1, "observer rate"), (0.1928571428571429, "collocated law rate")):
        rate = RECORDED[name][0][2]
        assert rate == pytest.approx(-math.log(abs(PAPER.rho - K) * PAPER.q) / PAPER.tau, rel=RTOL, abs=0.0)


@pytest.mark.parametrize("name", list(RECORDED))
def test_recorded_values(name):
    design = _design(name).design
    (gain, value, rate), (pde_margin, pde_omega), kind = RECORDED[name]
    assert design.kind == kind
    if kind == "plateau":
        # every gain of the plateau is optimal and the sampled rates tie there to rounding: the design's is one of
        # them (-0.7149 and 0.0475 seen as the loops' rounding changed), the recorded one inside the bracket
        lo, hi = design.K_bracket
        assert lo <= design.K <= hi and lo <= gain <= hi
        pde_omega, pde_margin = (
            float(x) for x in CollocatedPDE(ARGS, 0.1, design.K).crossing(design.certificate.omega)
        )
    else:
        assert design.K == pytest.approx(gain, rel=RTOL, abs=0.0)
    assert design.decay_rate == pytest.approx(rate, rel=RTOL, abs=0.0)
    assert design.value == pytest.approx(design.margin if value is None else value, rel=RTOL, abs=0.0)
    certificate = design.certificate
    assert not certificate.of_model and certificate.scope.startswith("the PDE itself")
    assert certificate.accuracy <= 5e-11 and certificate.omega_accuracy <= 5e-11
    assert abs(design.margin - pde_margin) <= certificate.accuracy
    assert abs(certificate.omega - pde_omega) <= certificate.omega_accuracy


def test_the_plateau_ends_where_the_observers_chain_overtakes_the_laws():
    """On ``Hyperbolic2x2(1, 1, 1, 1, 1, 0.8)`` under U_BS2(0.1) the rate design is a plateau at the law's
    ``-ln|(rho - K) q| / tau = -ln 0.7 / 2`` that ends where the observer's chain ``-ln|kappa| / tau`` (the reflection
    of its target system; ``lam q / mu = 1`` here) falls below it: ``kappa = -(rho - K) q = -0.7``. The end is solved
    on the chain's rate (measured 6.2e-14 from -0.7; the 40 bisections of the abscissa it replaced stopped 1.6e-12
    away): tolerance 1e-12."""
    rho, K = 0.8, 0.1
    plant = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, rho)
    design = nr.design_collocated_observer(
        plant, "decay_rate", controller=ReflectionController(K), margin_at_least=0.1
    ).design
    assert design.kind == "plateau"
    assert design.decay_rate == pytest.approx(-math.log(rho - K) / 2.0, rel=RTOL, abs=0.0)
    assert design.K_bracket[0] == pytest.approx(-(rho - K), rel=0.0, abs=1e-12)
