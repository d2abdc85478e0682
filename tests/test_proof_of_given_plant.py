"""Proofs about the plant as given: ``tau = 1/lam + 1/mu`` and ``p = sigma_pm / lam`` not doubles.

Oracle, sharing no code with the package: the Laplace-domain solution ``e^{-s/mu} [u; v](1, s)``
from ``[q; 1]`` by the closed-form 2x2 matrix exponential written here, in mpmath at 40 digits,
with ``tau = mpf(1)/lam + mpf(1)/mu`` and ``p = mpf(sigma_pm)/lam`` exact; the crossing
equations ``|A(i w)| = |B(i w)|``, ``e^{-i w delta} = -A/B`` and the rightmost root solved by
``mpmath.findroot``.

No plant was found whose old ball (the loop with ``tau`` rounded) misses the PDE's margin:
the margin moves by ``|tau_d / tau - 1| <= 2^-53`` relative, 1e-3 of the proven balls'
widths (1e-14 to 1e-12 relative), and the PDE's margin sits near their middle. The map itself
is therefore tested directly: each mapped end contains the exact scaled value.
"""

from __future__ import annotations

import dataclasses
from fractions import Fraction

import mpmath as mp
import numpy as np
import pytest

import nrobust as nr
from nrobust.hyperbolic import Hyperbolic2x2, ReflectionController, StateFeedback
from nrobust.hyperbolic.loops.controllers import loop_factors
from nrobust.hyperbolic.loops.exact_form import exact_ratios
from nrobust.hyperbolic.loops.given_plant import given_plant_scale, rounded_parts, to_given_plant
from nrobust.margins import delay_margin as factor_delay_margin

pytest.importorskip("flint")

DPS = 40
#: ``tau = 4/3`` (not a double); ``tau = 10/21``, ``p = 1/3``, ``m = -1/7`` (none a double); the
#: paper's third plant of the issue table (every number a double).
PLANTS = [(1.0, 3.0, 1.0, 1.0, 1.0, 0.85), (3.0, 7.0, 1.0, 1.0, 1.0, 0.85), (1.0, 1.0, 4.0, 4.0, 0.5, 0.5)]


def _fundamental(args, s):
    """``(z_u, z_v) = expm([[-s tau, p], [m, 0]]) [q; 1]``, ``expm M = e^{a/2} (cosh D I + sinh D / D (M - a/2 I))``."""
    lam, mu, spm, smp, q, _ = (mp.mpf(v) for v in args)
    tau = 1 / lam + 1 / mu
    a, p, m = -mp.mpc(s) * tau, spm / lam, -smp / mu
    half = a / 2
    d = mp.sqrt(half * half + p * m)
    sinhc, e = mp.sinh(d) / d, mp.exp(half)
    zu = e * ((mp.cosh(d) + sinhc * half) * q + sinhc * p)
    zv = e * (sinhc * m * q + (mp.cosh(d) - sinhc * half))
    return zu, zv, tau


def _factors(args, controller, s):
    """``(A, B)`` of the PDE's loop at ``s``: U_BS2(K) by Theorem 4, ``U = k u(t, 1)`` by the boundary condition."""
    rho, q = mp.mpf(args[5]), mp.mpf(args[4])
    zu, zv, tau = _fundamental(args, s)
    A = zv - rho * zu  # e^{-s/mu} (v(1) - rho u(1)) / v(0): the open loop 1 - Phi
    if isinstance(controller, StateFeedback):
        return A, -mp.mpf(controller.k) * zu
    round_trip = q * mp.exp(-s * tau)
    return A, mp.mpf(controller.K) * round_trip - (A - 1 + rho * round_trip)  # K q e^{-tau s} - I_N


def _pde_margin(args, controller, w0):
    """``(w, delta*)`` of the crossing near ``w0``, at 40 digits."""
    with mp.workdps(DPS):
        w = mp.findroot(
            lambda v: abs(_factors(args, controller, 1j * v)[0]) - abs(_factors(args, controller, 1j * v)[1]),
            mp.mpf(w0),
        )
        A, B = _factors(args, controller, 1j * w)
        return w, (-mp.arg(-A / B)) % (2 * mp.pi) / w


CASES = [(args, ReflectionController(0.1)) for args in PLANTS] + [((3.0, 7.0, 2.0, 3.0, 1.0, 0.5), StateFeedback(-0.3))]


@pytest.mark.parametrize(("args", "controller"), CASES)
def test_the_proven_margin_holds_for_the_plant_as_given(args, controller):
    plant = Hyperbolic2x2(*args)
    dm = nr.delay_margin(plant, controller, rigorous=True)
    w, truth = _pde_margin(args, controller, dm.omega)
    lo, hi = dm.margin_ball
    assert mp.mpf(lo) <= truth <= mp.mpf(hi)
    assert "the plant as given" in dm.scope
    # the crossing frequency is the PDE's: 1e-12 relative bounds its proven accuracy here
    np.testing.assert_allclose(dm.omega, float(w), rtol=1e-12)
    # no large widening: the ball of the loop as built, before the map, is as wide to 10 %
    # (the map adds 2 ulps; measured ratios 1.00)
    built = factor_delay_margin(*loop_factors(plant, controller), rigorous=True).margin_ball
    assert hi - lo <= 1.1 * (built[1] - built[0]) + 4 * np.spacing(hi)


@pytest.mark.parametrize("args", PLANTS[:2])
def test_the_map_contains_the_exact_scaled_values(args):
    """Delays times ``r = tau / tau_d``, frequencies over it, each end outward (exact rationals)."""
    plant, controller = Hyperbolic2x2(*args), ReflectionController(0.1)
    r = given_plant_scale(plant, controller)
    assert r == (Fraction(1) / Fraction(args[0]) + Fraction(1) / Fraction(args[1])) / Fraction(plant.tau) != 1
    built = factor_delay_margin(*loop_factors(plant, controller), rigorous=True)
    given = to_given_plant(built, plant, controller)
    assert Fraction(given.margin_ball[0]) <= r * Fraction(built.margin_ball[0])
    assert Fraction(given.margin_ball[1]) >= r * Fraction(built.margin_ball[1])
    assert given.margin_ball[0] <= given.margin <= given.margin_ball[1]
    assert Fraction(given.frequency_bound) >= Fraction(built.frequency_bound) / r
    np.testing.assert_allclose(given.omega, built.omega * float(1 / r), rtol=2**-52)
    # a map that moved nothing would still pass the checks above when r rounds to 1: it does not
    assert given.margin_ball != built.margin_ball
    # an abscissa: real parts divided by r, the bracket outward
    F0 = nr.characteristic(plant, controller, 0.0)
    ab = nr.spectral_abscissa(F0, rigorous=True)
    mapped = to_given_plant(ab, plant, controller)
    assert Fraction(mapped.value_bracket[0]) <= Fraction(ab.value_bracket[0]) / r
    assert Fraction(mapped.value_bracket[1]) >= Fraction(ab.value_bracket[1]) / r
    assert Fraction(mapped.upper_bound) >= Fraction(ab.upper_bound) / r
    # a float result is not a proof: it passes unchanged
    assert to_given_plant(dataclasses.replace(built, rigorous=False), plant, controller).margin == built.margin


def test_the_certificate_proves_the_abscissa_of_the_plant_as_given():
    """The rightmost root of the PDE's nominal loop (tau = 4/3) lies in the proven bracket."""
    args, controller = PLANTS[0], ReflectionController(0.1)
    cert = nr.certify(Hyperbolic2x2(*args), controller, delta_max=0.5, rigorous=True, k_region=False)
    ab = cert.abscissa
    assert not ab.approached_at_infinity and ab.rigorous
    with mp.workdps(DPS):
        root = mp.findroot(lambda s: sum(_factors(args, controller, s)), mp.mpc(ab.root))
    assert mp.mpf(ab.value_bracket[0]) <= root.real <= mp.mpf(ab.value_bracket[1])
    # 1e-12: the floating-point root the bracket is built about, relative to |root| ~ 1
    np.testing.assert_allclose(ab.value, float(root.real), rtol=0, atol=1e-12)
    assert "the plant as given" in cert.scope and "root counts" in cert.scope
    lo, hi = cert.margin.margin_ball
    assert mp.mpf(lo) <= _pde_margin(args, controller, cert.margin.omega)[1] <= mp.mpf(hi)


def test_the_ratios_are_exact_rationals():
    p, m, shift = exact_ratios(Hyperbolic2x2(3.0, 7.0, 1.0, 2.0, 1.0, 0.85))
    assert (p, m, shift) == (Fraction(1, 3), Fraction(-2, 7), 0)


def test_a_rounded_principal_gain_keeps_the_scope():
    """``rho q = 0.3 * 0.1`` is not a double: the proof is about the rounded product, and says so."""
    plant, controller = Hyperbolic2x2(1.0, 3.0, 1.0, 1.0, 0.1, 0.3), ReflectionController(0.1)
    assert given_plant_scale(plant, controller) is None
    assert "rho q" in rounded_parts(plant, controller)
    assert "rho q" in nr.delay_margin(plant, controller, rigorous=True).scope
