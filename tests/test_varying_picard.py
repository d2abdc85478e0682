"""Plants whose kernels need the high degrees of the floating-point Picard iteration (96 and 128).

Each was refused before the iteration was done degree by degree in the basis ``C(i + j, i) A^i V^j``: FFT products
of monomial coefficients up to ``C(96, 48)`` swamped the small ones. Oracles share no code with
:mod:`nrobust.hyperbolic.loops.varying_proof`: the plant's Laplace-domain ODE in ``x`` solved by mpmath's Taylor
integrator (the helpers of ``tests/test_varying_speed_proof.py``, 20 digits) and the crossing equations
``|A(i w)| = |B(i w)|`` solved on it by ``mpmath.findroot``.
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest
from test_varying_speed_proof import _holds_the_ode, _ode_couplings

import nrobust as nr
from nrobust.hyperbolic import GeneralHyperbolic2x2, Hyperbolic2x2, ReflectionController
from nrobust.hyperbolic.loops.varying_proof import varying_failure

pytest.importorskip("flint")

Q, RHO, K = 0.9, 0.6, 0.1


def _one(x):
    return mp.mpf(1)


def _half(x):
    return mp.mpf(0.5)


def _fast(frequency, amplitude=2.0):
    """``Hyperbolic2x2(1, 1, amplitude sin(frequency x), 0.5, Q, RHO)`` and its mpmath coefficients."""
    plant = Hyperbolic2x2(1.0, 1.0, lambda x: amplitude * np.sin(frequency * x), 0.5, Q, RHO)
    mp_plant = (_one, _one, lambda x: mp.mpf(amplitude) * mp.sin(frequency * x), _half, Q, RHO, 1.0)
    return plant, mp_plant


@pytest.mark.parametrize("s", [0.5j, pytest.param(-0.3 + 6.0j, marks=pytest.mark.long)])
def test_fast_coupling_proven_at_degree_96(s):
    """``sigma_pm = 2 sin 5x``: proven at degree 96 (refused before: "proven error of the kernel (1.4e+00)"); the open
    loop and ``u_factor`` in ball arithmetic hold the ODE's."""
    _holds_the_ode(*_fast(5.0), s)


@pytest.mark.parametrize("s", [0.5j, pytest.param(1.0 + 4.0j, marks=pytest.mark.long)])
def test_faster_coupling_proven_at_degree_128(s):
    """``sigma_pm = 2 sin 6x``: proven at degree 128 (refused before: "proven error of the kernel (1.3e+65)"; the
    exact iteration leaves 1e-7 at degree 96), and it holds the ODE's."""
    _holds_the_ode(*_fast(6.0), s)


@pytest.mark.long  # about 4 s: findroot on the ODE
def test_faster_coupling_margin_holds_the_pdes_crossing():
    """The proven margin of U_BS2(0.1) on the ``2 sin 6x`` plant holds the PDE's: the crossing equations on the ODE's
    solution (20 digits) solved by findroot from the proof's crossing frequency."""
    plant, mp_plant = _fast(6.0)
    dm = nr.delay_margin(plant, ReflectionController(K), delta_max=20.0, rigorous=True)
    lo, hi = dm.margin_ball
    assert dm.scope.startswith("the PDE itself") and hi - lo < 1e-8

    def factors(w):
        A, _ = _ode_couplings(*mp_plant, 1j * w)
        return A, 1 - A + (mp.mpf(K) - mp.mpf(RHO)) * mp.mpf(Q) * mp.exp(-2j * w)  # tau = 1/lam + 1/mu = 2

    def gap(w):
        A, B = factors(w)
        return abs(A) ** 2 - abs(B) ** 2

    with mp.workdps(20):
        w = mp.findroot(gap, mp.mpf(0.4216), tol=mp.mpf(10) ** -16)
        A, B = factors(w)
        margin = ((-mp.arg(-A / B)) % (2 * mp.pi)) / w
    # the gap's root to 1e-16 (its slope in w is of order 1) moves the margin (slope about 10 in w) by 1e-15, far below
    # the proven ball's width (4e-10)
    assert lo <= float(margin) <= hi


@pytest.mark.parametrize("s", [0.5j, pytest.param(-0.2 + 5.0j, marks=pytest.mark.long)])
def test_varying_speed_on_l_2_proven_at_degree_96(s):
    """``lam = 2 + 0.5 sin x``, ``mu = 1`` on ``L = 2``: proven at degree 96 (refused before: "proven error of the
    kernel (5.6e-02)"; the univariate sup of the kernel's line, whose monomial coefficients reach 4e10, is now
    bounded on balls about their centres), and it holds the ODE's."""
    plant = GeneralHyperbolic2x2(
        lambda x: 2 + 0.5 * np.sin(x), lambda x: 1.0 + 0 * x, 0.0, 0.5, 0.3, 0.0, 0.7, -0.4, length=2.0
    )
    mp_plant = (lambda x: 2 + mp.mpf(0.5) * mp.sin(x), _one, _half, lambda x: mp.mpf(0.3), 0.7, -0.4, 2.0)
    _holds_the_ode(plant, mp_plant, s)


def test_overflow_is_refused_with_its_reason():
    """Couplings of ``10^100``: the parts of degree ``k`` of the kernels are of order ``10^(100 k) / k!`` (the Volterra
    series), beyond double precision from degree 4, and the reason says the iteration overflows."""
    reason = varying_failure(Hyperbolic2x2(1.0, 1.0, lambda x: 1e100 * (1 + x), 1e100, Q, RHO))
    assert reason is not None and "Picard iteration overflows at degree 128" in reason
