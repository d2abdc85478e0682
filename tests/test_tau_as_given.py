"""Proofs about the plant as given for filtered laws and exact observers: ``tau = 1/lam + 1/mu`` not a double.

The filtered loop ``(1 + b s)(1 - Phi) + (1 + a s) B e^{-delta s}`` is not a function of ``tau s``
alone, but at ``s`` it is the loop built with ``tau_d`` and the filter ``(a / r, b / r)`` at ``r s``
(``r = tau / tau_d``): the loop carries ``a / r``, ``b / r`` as balls and the proofs are mapped by
``r`` as for the unfiltered laws. So are the output feedbacks whose observer is exact on an
uncoupled plant (the collocated observer's term ``(1 - Phi) k q e^{-tau s}``, its coefficients
enclosed from the user's numbers). Loops rebuilt from their point terms keep the radii; proofs
about a general plant's normal form, or not mapped (a design's), say so in their scope.

Oracle, sharing no code with the package: the Laplace-domain solution of the PDE,
``[u; v](1, s) = expm(M(s)) [q; 1]`` with ``M(s) = [[-s/lam, sigma_pm/lam], [-sigma_mp/mu, s/mu]]``
(``mpmath.expm`` at 40 digits, ``tau = 1/lam + 1/mu`` exact), the open loop
``1 - Phi = e^{-s/mu} (v(1) - rho u(1))`` and the filtered law's factors of the module table of
``controllers`` (section 2.3.2 of the paper); on an uncoupled plant, the loop written from the
boundary conditions ``v(1) = rho u(1) + U``, ``U = -(1 + a s)/(1 + b s) K u(1) e^{-delta s}``.
Crossings, roots and windings are solved at 40 digits (``mpmath.findroot``, the argument
principle).

No case was found where the old proofs (the loop with ``tau`` rounded to a double, not mapped)
miss the plant's value: over 21 finite margins on six plants (``lam, mu`` = 3, 7; 0.3, 0.7; 1, 3;
1, 10) and four filters, the PDE's margin lay at least 4e-15 inside the old balls (1e-14 to 2e-12
wide), while ``tau`` moves it by at most 2e-15 (``|r - 1| <= 2^-53`` times the margin); seven of
the eight abscissae attained by a root have brackets 2e-11 to 8e-11 wide (the eighth 0.04), the
plant's root at least 1e-11 inside. The tests below therefore check
the new claims (the plant's value in the mapped ball, the enclosure of the plant's own loop, the
scope) against the oracle; the scope and the enclosure fail before the change.

A state feedback with integral gains ``g_u``, ``g_v`` (section at the end): the oracle is the PDE's state in closed
form (the 2x2 exponential by ``cosh``/``sinh`` of its eigenvalues, the gains' integral by the primitives of
``(alpha + beta x) e^{l x}``), at 40 digits with ``tau`` exact. The old proofs (``t_v`` rounded to a multiple of
``ulp(tau)``, ``tau`` the double) did not miss either: on ``lam, mu = 0.3, 0.7``, ``3, 7`` and a general plant the
PDE's margin lay 5e-14 to 4e-13 inside balls 1e-13 to 8e-13 wide. The new term holding the kernel's jump between
two doubles is checked against the jump written from the PDE (its size, ``0.094`` here, times an ulp, is below
the rounding of the loop: no enclosure shows it).
"""

from __future__ import annotations

import math

import mpmath as mp
import numpy as np
import pytest
from _oracles import winding_number

import nrobust as nr
from nrobust._flint import working_precision
from nrobust.hyperbolic import FilteredController, Hyperbolic2x2
from nrobust.hyperbolic.loops.given_plant import (
    GivenPlantBalls,
    given_plant_balls,
    given_plant_scale,
    rounded_parts,
)
from nrobust.hyperbolic.plants.general import GeneralHyperbolic2x2
from nrobust.reports.certificate import PROVEN

flint = pytest.importorskip("flint")

DPS = 40


def _open_loop(args, s):
    """``(1 - Phi(s), tau)``: ``e^{-s/mu} (v(1) - rho u(1))`` from ``[u; v](0) = [q; 1]`` by ``mpmath.expm``."""
    lam, mu, spm, smp, q, rho = (mp.mpf(v) for v in args)
    E = mp.expm(mp.matrix([[-s / lam, spm / lam], [-smp / mu, s / mu]]))
    u, v = E[0, 0] * q + E[0, 1], E[1, 0] * q + E[1, 1]
    return mp.exp(-s / mu) * (v - rho * u), 1 / lam + 1 / mu


def _factors(args, law, s):
    """``(A, B)`` of the filtered law: ``(1 + b s)(1 - Phi)`` and ``(1 + a s) (K q e^{-tau s} - I_N)``.

    ``I_N = rho q e^{-tau s} - Phi``; U_BS (``K`` None) has ``K = rho``, so ``B = (1 + a s) Phi``.
    """
    q, rho = mp.mpf(args[4]), mp.mpf(args[5])
    one_minus_phi, tau = _open_loop(args, s)
    gain = rho if law.K is None else mp.mpf(law.K)
    unfiltered = (gain - rho) * q * mp.exp(-tau * s) + 1 - one_minus_phi
    return (1 + mp.mpf(law.b) * s) * one_minus_phi, (1 + mp.mpf(law.a) * s) * unfiltered


def _uncoupled_factors(args, law, s):
    """``(A, B)`` of an uncoupled plant from its boundary conditions (no backstepping formula).

    ``u(1) = q e^{-s/lam} v(0)``, ``v(1) = e^{s/mu} v(0)``, ``v(1) = rho u(1) + U`` with
    ``U = -(1 + a s)/(1 + b s) K u(1) e^{-delta s}``, times ``(1 + b s) e^{-s/mu} / v(0)``.
    """
    lam, mu, _, _, q, rho = (mp.mpf(v) for v in args)
    gain = rho if law.K is None else mp.mpf(law.K)
    u1, v1 = q * mp.exp(-s / lam), mp.exp(s / mu)
    scale = mp.exp(-s / mu)
    return scale * (1 + mp.mpf(law.b) * s) * (v1 - rho * u1), scale * (1 + mp.mpf(law.a) * s) * gain * u1


def _loop(args, law, delta):
    def F(s):
        A, B = _factors(args, law, s)
        return A + B * mp.exp(-mp.mpf(delta) * s)

    return F


def _pde_margin(factors, w0):
    """``(w, delta*)``: the crossing ``|A(i w)| = |B(i w)|`` near ``w0`` and its first delay, at 40 digits."""
    with mp.workdps(DPS):

        def g(w):
            A, B = factors(mp.mpc(0, w))
            return abs(A) ** 2 - abs(B) ** 2

        w = mp.findroot(g, mp.mpf(w0))
        A, B = factors(mp.mpc(0, w))
        return w, (-mp.arg(-A / B)) % (2 * mp.pi) / w  # e^{-i w delta} = -A / B


def _assert_margin_holds(margin, factors, omega=True):
    """The proven ball of ``margin`` holds the PDE's delay margin (:func:`_pde_margin` from its crossing); with
    ``omega`` its crossing frequency is the PDE's: 1e-12 relative bounds its accuracy here (measured below 1e-15)."""
    w, truth = _pde_margin(factors, margin.omega)
    lo, hi = margin.margin_ball
    assert mp.mpf(lo) <= truth <= mp.mpf(hi)
    if omega:
        np.testing.assert_allclose(margin.omega, float(w), rtol=1e-12)


#: ``tau = 10/21`` and ``p = 1/3``, ``m = -1/7`` (none a double), ``tau = 10/3`` with ``lam, mu = 0.3, 0.7``.
CASES = [
    ((3.0, 7.0, 1.0, 1.0, 1.0, 0.85), FilteredController(0.2, 0.5, 0.1)),
    ((3.0, 7.0, 1.0, 1.0, 1.0, 0.85), FilteredController(0.05, 0.3)),
    ((3.0, 7.0, 2.0, 3.0, 0.9, 0.5), FilteredController(0.3, 0.6, -0.1)),
    ((0.3, 0.7, 0.5, -0.4, 0.8, 0.6), FilteredController(0.05, 0.3)),
]


@pytest.mark.parametrize(("args", "law"), CASES)
def test_the_proven_margin_of_a_filtered_law_holds_for_the_plant_as_given(args, law):
    plant = Hyperbolic2x2(*args)
    assert rounded_parts(plant, law) == "" and given_plant_scale(plant, law) != 1
    dm = nr.delay_margin(plant, law, rigorous=True)
    assert "the plant as given" in dm.scope and "as the double" not in dm.scope
    _assert_margin_holds(dm, lambda s: _factors(args, law, s))


def test_the_proven_margin_of_a_filtered_law_on_an_uncoupled_plant_holds_for_its_boundary_conditions():
    """The loop written from the boundary conditions, not from the backstepping formula of the package."""
    args, law = (3.0, 7.0, 0.0, 0.0, 1.0, 0.85), FilteredController(0.05, 0.3)
    dm = nr.delay_margin(Hyperbolic2x2(*args), law, rigorous=True)
    assert "the plant as given" in dm.scope

    _assert_margin_holds(dm, lambda s: _uncoupled_factors(args, law, s), omega=False)


def test_the_proven_margin_of_a_filtered_law_on_a_general_plant_holds_for_the_plant_as_given():
    """``GeneralHyperbolic2x2`` with ``lam, mu = 0.3, 0.7`` on ``L = 1.3`` (``tau = L/lam + L/mu`` not a double):
    ``1 - Phi = e^{-(s - d) L / mu} (v(L) - rho u(L))`` from ``expm(L M(s))``, U_BS filtered."""
    c = dict(lam=0.3, mu=0.7, a=0.1, b=0.4, c=-0.5, d=-0.2, q=0.6, rho=0.7, length=1.3)
    law = FilteredController(0.05, 0.3)
    plant = GeneralHyperbolic2x2(**c)
    assert rounded_parts(plant, law) == "" and given_plant_scale(plant, law) != 1

    def factors(s):
        lam, mu, a, b, cc, d, q, L, rho = (
            mp.mpf(c[k]) for k in ("lam", "mu", "a", "b", "c", "d", "q", "length", "rho")
        )
        E = mp.expm(L * mp.matrix([[(a - s) / lam, b / lam], [-cc / mu, (s - d) / mu]]))
        u, v = E[0, 0] * q + E[0, 1], E[1, 0] * q + E[1, 1]
        one_minus_phi = mp.exp(-(s - d) * L / mu) * (v - rho * u)
        return (1 + mp.mpf(law.b) * s) * one_minus_phi, (1 + mp.mpf(law.a) * s) * (1 - one_minus_phi)

    dm = nr.delay_margin(plant, law, rigorous=True)
    assert "the plant as given" in dm.scope
    _assert_margin_holds(dm, factors, omega=False)


def _assert_encloses(balls, F, points, delta) -> None:
    """``balls(s, k)`` holds the ``k``-th derivative of the 40-digit ``F`` at each point, ``k = 0, 1, 2``."""
    for s in points:
        for k in range(3):
            value = balls(s, k)
            with mp.workdps(DPS):
                truth = mp.diff(F, mp.mpc(s), k)
            with working_precision(200) as fl:  # the 40-digit value, far narrower than the enclosure
                assert value.contains(fl.acb(truth)), (delta, s, k, value, truth)


def test_the_plant_balls_enclose_the_filtered_loop_with_tau_exact():
    """``given_plant_balls`` of a filtered law encloses ``F``, ``F'``, ``F''`` of the exact-tau loop (40 digits);
    before, the filtered law had no enclosure of the plant's own loop (None)."""
    args, law = CASES[0]
    for delta in (0.0, 0.3):
        balls = given_plant_balls(Hyperbolic2x2(*args), law, delta)
        assert isinstance(balls, GivenPlantBalls)
        F = _loop(args, law, delta)
        _assert_encloses(balls, F, (complex(-1.0, 30.0), complex(0.5, -7.0), complex(-4.0, 150.0)), delta)


def test_the_chain_abscissa_of_a_filtered_law_is_in_the_proven_bracket():
    """Uncoupled plant: the roots approach ``Re s = ln(|b rho - a K| q / b) / tau`` (the difference operator
    ``b (1 - rho q e^{-tau s}) + a K q e^{-tau s}`` at ``delta = 0``), in closed form with ``tau`` exact."""
    args, law = (3.0, 7.0, 0.0, 0.0, 1.0, 0.85), FilteredController(0.2, 0.5, 0.1)
    plant = Hyperbolic2x2(*args)
    cert = nr.certify(plant, law, delta_max=0.3, rigorous=True, k_region=False)
    ab = cert.abscissa
    assert ab.rigorous and ab.approached_at_infinity
    with mp.workdps(DPS):
        lam, mu, _, _, q, rho = (mp.mpf(v) for v in args)
        chain = mp.log(abs(mp.mpf(law.b) * rho - mp.mpf(law.a) * mp.mpf(law.K)) * q / mp.mpf(law.b)) / (
            1 / lam + 1 / mu
        )
    assert mp.mpf(ab.value_bracket[0]) <= chain <= mp.mpf(ab.value_bracket[1])
    assert "the plant as given" in cert.scope


def test_the_certificate_of_a_filtered_law_holds_for_the_plant_as_given():
    """``certify(plant, FilteredController(...), rigorous=True)`` end to end: the scope, the abscissa attained by a
    root (in its proven bracket), the margin ball, and the proven root counts (argument principle at 40 digits)."""
    args, law = CASES[2]
    plant, delta_max = Hyperbolic2x2(*args), 0.3
    cert = nr.certify(plant, law, delta_max=delta_max, rigorous=True, k_region=False)
    assert "the plant as given" in cert.scope and "root counts marked proven" in cert.scope
    assert "as the double" not in cert.scope.split("they are proven")[0]
    claims = {c.name: c.status for c in cert.claims}
    assert claims["spectral abscissa"] == PROVEN and claims["delay margin"] == PROVEN
    ab = cert.abscissa
    assert not ab.approached_at_infinity
    with mp.workdps(DPS):
        root = mp.findroot(_loop(args, law, 0.0), mp.mpc(ab.root))
    assert mp.mpf(ab.value_bracket[0]) <= root.real <= mp.mpf(ab.value_bracket[1])
    _assert_margin_holds(cert.margin, lambda s: _factors(args, law, s), omega=False)
    for roots, delta, name in (
        (cert.roots_nominal, 0.0, "roots at delta = 0"),
        (cert.roots_delayed, delta_max, "roots at delta_max"),
    ):
        assert claims[name] == PROVEN and roots.rigorous
        assert roots.count == winding_number(_loop(args, law, delta), roots.region)


def test_a_designs_scope_says_tau_is_rounded_when_its_proofs_are_not_mapped():
    """A filtered design's certificate is proven on the loop as built (the family with ``tau_d``): its scope
    says so where ``tau`` is not a double, and says the plant as given where it is (``lam = mu = 1``)."""
    from nrobust.hyperbolic.analyses.filter_design import design_filtered_exact

    parameters = {"K": 0.1, "b": 0.5, "a": (0.0, 0.3)}
    rounded = design_filtered_exact(Hyperbolic2x2(*CASES[0][0]), "margin", parameters=parameters, rigorous=True)
    assert "the plant as given" not in rounded.scope
    assert "as the double 0.47619047619047616" in rounded.scope and "not mapped" in rounded.scope
    exact = design_filtered_exact(Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85), "margin", parameters=parameters)
    assert "the plant as given" in exact.scope


# ---------------------------------------------------------------------------------------------- output feedbacks
def _collocated_factors(args, law, s):
    """``(A, B)`` of the collocated output feedback on an uncoupled plant, from the PDE and the observer.

    Plant: ``u(1) = q e^{-s/lam}``, ``v(1) = e^{s/mu}`` (``v(0) = 1``), ``v(1) = rho u(1) + e^{-delta s} U``.
    Observer (no coupling, no injection): ``v^(1) = rho y + U``, ``y = u(1)`` measured, ``u^(1) = q e^{-tau s}
    v^(1)``; the law on the estimate ``U = -(n/d) K u^(1)`` (``n/d = (1 + a s)/(1 + b s)``). Solving for ``U``:
    ``(v(1) - rho u(1))(d + n K q e^{-tau s}) + e^{-delta s} n K rho q u(1) e^{-tau s} = 0``, times ``e^{-s/mu}``.
    """
    lam, mu, _, _, q, rho = (mp.mpf(v) for v in args)
    gain = rho if law.K is None else mp.mpf(law.K)
    n, d = 1 + mp.mpf(law.a) * s, 1 + mp.mpf(law.b) * s
    u1, v1, round_trip = q * mp.exp(-s / lam), mp.exp(s / mu), mp.exp(-s * (1 / lam + 1 / mu))
    scale = mp.exp(-s / mu)
    return scale * (v1 - rho * u1) * (d + n * gain * q * round_trip), scale * n * gain * rho * q * u1 * round_trip


#: Uncoupled plants (``tau = 10/21``, ``10/3``): the observers' terms are exact, the loops functions of ``tau s``.
OBSERVED = [
    ((3.0, 7.0, 0.0, 0.0, 1.0, 0.85), nr.CollocatedOutputFeedback(FilteredController(0.02, 0.3)), _collocated_factors),
    ((0.3, 0.7, 0.0, 0.0, 0.9, 0.6), nr.OutputFeedback(FilteredController(0.05, 0.3)), _uncoupled_factors),
]


@pytest.mark.parametrize(("args", "controller", "oracle"), OBSERVED)
def test_the_proven_margin_of_an_exact_observer_holds_for_the_plant_as_given(args, controller, oracle):
    plant = Hyperbolic2x2(*args)
    assert rounded_parts(plant, controller) == "" and given_plant_scale(plant, controller) != 1
    dm = nr.delay_margin(plant, controller, rigorous=True)
    assert "the plant as given" in dm.scope and "observer is exact" in dm.scope
    _assert_margin_holds(dm, lambda s: oracle(args, controller.controller, s))


def test_the_collocated_loop_encloses_the_observers_gains():
    """``k q`` and ``k rho q^2`` of ``G`` are not doubles (``0.85 * 0.7``): the loop's balls enclose the loop of the
    PDE and the observer with ``tau`` exact (``given_plant_balls`` at 40 digits), the certificate is about the plant
    as given, and its proven counts are the exact loop's windings."""
    args = (3.0, 7.0, 0.0, 0.0, 0.7, 0.85)
    controller = nr.CollocatedOutputFeedback(FilteredController(0.02, 0.3))
    plant = Hyperbolic2x2(*args)

    def loop(delta):
        def F(s):
            A, B = _collocated_factors(args, controller.controller, s)
            return A + B * mp.exp(-mp.mpf(delta) * s)

        return F

    for delta in (0.0, 0.2):
        balls = given_plant_balls(plant, controller, delta)
        assert isinstance(balls, GivenPlantBalls)
        for s in (complex(-1.0, 30.0), complex(0.5, -7.0)):
            for k in range(2):
                with mp.workdps(DPS):
                    truth = mp.diff(loop(delta), mp.mpc(s), k)
                with working_precision(200) as fl:
                    assert balls(s, k).contains(fl.acb(truth)), (delta, s, k)
    cert = nr.certify(plant, controller, delta_max=0.2, rigorous=True, k_region=False)
    assert "the plant as given" in cert.scope and "root counts marked proven" in cert.scope
    claims = {c.name: c.status for c in cert.claims}
    for roots, delta, name in (
        (cert.roots_nominal, 0.0, "roots at delta = 0"),
        (cert.roots_delayed, 0.2, "roots at delta_max"),
    ):
        assert claims[name] == PROVEN and roots.count == winding_number(loop(delta), roots.region)


def test_an_observer_delay_keeps_tau_rounded_and_says_by_how_much():
    """An observer delay (``delta_o / r`` is not a double): the scope names the rounding and its size,
    ``|tau_d - tau| / tau`` with ``tau = 10/21`` (rounded up to two digits: at least the exact value, and within 10%
    of it); before, the size was not said."""
    import re
    from fractions import Fraction

    plant = Hyperbolic2x2(3.0, 7.0, 0.0, 0.0, 1.0, 0.85)
    gap = abs(Fraction(0.47619047619047616) / Fraction(10, 21) - 1)
    controller = nr.CollocatedOutputFeedback(FilteredController(0.02, 0.3), observer_delay=0.01)
    assert given_plant_scale(plant, controller) is None
    dm = nr.delay_margin(plant, controller, rigorous=True)
    assert "the plant as given" not in dm.scope and "as the double 0.47619047619047616" in dm.scope
    said = re.search(r"as the double 0\.47619047619047616 \(a relative (\S+) from the exact tau\)", dm.scope)
    assert said and gap <= Fraction(said.group(1)) <= gap * Fraction(11, 10)


def _reflected_factors(args, law, kappa, s):
    """``(A, B)`` of the collocated output feedback whose observer keeps the reflection ``kappa``, from the PDE.

    As :func:`_collocated_factors` with ``v^(1) = (rho - kappa) y + kappa u^(1) + U``: ``u^(1) = q e^{-tau s} v^(1)``
    gives ``u^(1) (1 - kappa q E) = q E ((rho - kappa) y + U)`` (``E = e^{-tau s}``), the law ``U = -(n/d) K u^(1)``
    ``U = -n K q E (rho - kappa) y / (d (1 - kappa q E) + n K q E)``, and ``v(1) - rho u(1) = e^{-delta s} U``.
    """
    lam, mu, _, _, q, rho = (mp.mpf(v) for v in args)
    gain, kap = (rho if law.K is None else mp.mpf(law.K)), mp.mpf(kappa)
    n, d = 1 + mp.mpf(law.a) * s, 1 + mp.mpf(law.b) * s
    u1, v1, E = q * mp.exp(-s / lam), mp.exp(s / mu), mp.exp(-s * (1 / lam + 1 / mu))
    scale = mp.exp(-s / mu)
    return scale * (v1 - rho * u1) * (d * (1 - kap * q * E) + n * gain * q * E), scale * n * gain * q * E * (
        rho - kap
    ) * u1


@pytest.mark.parametrize("kappa", [0.1, -0.3])
def test_an_observer_reflection_holds_for_the_plant_as_given(kappa):
    """The observer's own reflection on an uncoupled plant multiplies the loop by ``1 - kappa q e^{-tau s}``, a
    function of ``tau s``: the proofs map to the plant as given (before, the scope said ``tau`` rounded). The margin
    ball holds the PDE's, and the plant's balls its loop at 40 digits (``rho q`` and ``kappa q rho q`` not doubles)."""
    args, law = (3.0, 7.0, 0.0, 0.0, 1.0, 0.85), FilteredController(0.02, 0.3)
    plant = Hyperbolic2x2(*args)
    controller = nr.CollocatedOutputFeedback(law, observer_reflection=kappa)
    assert rounded_parts(plant, controller) == "" and given_plant_scale(plant, controller) != 1
    dm = nr.delay_margin(plant, controller, rigorous=True)
    assert "the plant as given" in dm.scope and "as the double" not in dm.scope
    _assert_margin_holds(dm, lambda s: _reflected_factors(args, law, kappa, s))
    plant = Hyperbolic2x2(3.0, 7.0, 0.0, 0.0, 0.7, 0.85)
    for delta in (0.0, 0.2):
        balls = given_plant_balls(plant, controller, delta)
        assert isinstance(balls, GivenPlantBalls)

        def F(s, delta=delta):
            A, B = _reflected_factors((3.0, 7.0, 0.0, 0.0, 0.7, 0.85), law, kappa, s)
            return A + B * mp.exp(-mp.mpf(delta) * s)

        for s in (complex(-1.0, 30.0), complex(0.5, -7.0)):
            for k in range(2):
                with mp.workdps(DPS):
                    value = mp.diff(F, mp.mpc(s), k)
                with working_precision(200) as fl:
                    assert balls(s, k).contains(fl.acb(value)), (delta, s, k)


@pytest.mark.parametrize(
    ("args", "controller"),
    [
        ((3.0, 7.0, 1.0, 1.0, 0.7, 0.85), FilteredController(0.2, 0.5, 0.1)),
        ((3.0, 7.0, 1.0, 1.0, 0.7, 0.85), FilteredController(0.05, 0.3)),
        ((3.0, 7.0, 0.0, 0.0, 0.7, 0.85), nr.CollocatedOutputFeedback(FilteredController(0.02, 0.3))),
        ((3.0, 7.0, 0.0, 0.0, 0.7, 0.85), nr.CollocatedOutputFeedback(FilteredController(0.02, 0.3, -0.1))),
        (
            (3.0, 7.0, 0.0, 0.0, 0.7, 0.85),
            nr.CollocatedOutputFeedback(FilteredController(0.02, 0.3, -0.1), observer_reflection=0.3),
        ),
    ],
)
def test_the_point_coefficients_are_balls_about_the_scaled_loop(args, controller):
    """Each stored point coefficient is within its radius of the exact one of the loop at ``x = r s``: the filter
    ``(a / r, b / r)``, ``E = e^{-tau_d x}``, written here in rationals from the module table of ``controllers``
    and the collocated loop above (the stored ``a``, ``b`` themselves are not in these balls' centres)."""
    from fractions import Fraction

    plant = Hyperbolic2x2(*args)
    lam, mu, q, rho = (Fraction(args[k]) for k in (0, 1, 4, 5))
    r = (1 / lam + 1 / mu) / Fraction(plant.tau)
    law = controller.controller if isinstance(controller, nr.CollocatedOutputFeedback) else controller
    a, b = Fraction(law.a) / r, Fraction(law.b) / r
    K = rho if law.K is None else Fraction(law.K)
    if isinstance(controller, nr.CollocatedOutputFeedback):  # (1 - rho q E)((1 + b x)(1 - k q E) + (1 + a x) K q E)
        k = Fraction(controller.observer_reflection) * q  # the observer's reflection kappa, times q
        A = {
            0: [1, b],
            1: [K * q - rho * q - k, K * q * a - rho * q * b - k * b],
            2: [rho * q * k - rho * q * K * q, rho * q * k * b - rho * q * K * q * a],
        }
        B = {2: [K * (rho * q - k) * q, K * (rho * q - k) * q * a]}  # n K q^2 (rho - kappa) E^2
    else:  # (1 + b x)(1 - rho q E), (1 + a x) K q E
        A = {0: [1, b], 1: [-rho * q, -rho * q * b]}
        B = {1: [K * q, K * q * a]}
    A_built, B_built = nr.loop_factors(plant, controller)
    moved = 0
    for built, exact in ((A_built, A), (B_built, B)):
        assert {t for _, t in built.point_terms} == {j * plant.tau for j in exact}
        for (coefs, t), radii in zip(built.point_terms, built.radii_of()):
            truth = exact[round(t / plant.tau)]
            for c, rad, x in zip(coefs, radii, truth):
                assert abs(Fraction(float(c)) - x) <= Fraction(float(rad))
                moved += Fraction(float(c)) != x
    assert moved > 0  # the radii are needed: a stored coefficient differs from its exact value


# ------------------------------------------------------------------------- loops rebuilt from their point terms
def test_loops_rebuilt_from_their_point_terms_keep_the_radii():
    """The design's merged nominal loop and truncated factors, and an output feedback's loop refined onto its observer
    term, keep the radii of the point coefficients (``rho q = 0.85 * 0.7`` is not a double): each stored coefficient
    stays within its radius of the exact rational, as in the loop they were built from."""
    from fractions import Fraction

    from nrobust.design.gain import _merged, _truncated

    plant = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 0.7, 0.85)
    rho_q = Fraction(0.85) * Fraction(0.7)

    def holds(P, j, exact):  # the coefficient of s^j e^{-tau s} within its radius of ``exact``
        c, rad = next((p, r) for (p, t), r in zip(P.point_terms, P.radii_of()) if t == plant.tau)
        return abs(Fraction(float(c[j])) - exact) <= Fraction(float(rad[j]))

    law = FilteredController(0.05, 0.3)
    A, B = nr.loop_factors(plant, law)
    F = A + B  # (1 + b s)(1 - Phi) + (1 + a s) Phi: rho q (a - b) s e^{-tau s}
    merged = _merged(F)
    assert len(merged.distributed) < len(F.distributed)  # the kernels N and -N written once: rebuilt
    assert holds(A, 0, -rho_q) and holds(merged, 1, rho_q * (Fraction(law.a) - Fraction(law.b)))
    truncated = _truncated(A, 1)
    assert all(p.size == 1 for p, _ in truncated.point_terms) and holds(truncated, 0, -rho_q)
    observed, _ = nr.loop_factors(plant, nr.OutputFeedback(nr.ReflectionController(0.1)))
    assert holds(observed, 0, -rho_q)


def test_proofs_about_a_general_plants_normal_form_say_so():
    """A collocated output feedback on a general plant is analysed on its normal form, whose ``lam, mu, q, rho``
    are doubles computed from the coefficients: its proofs, mapped to that normal form's exact ``tau``, are not
    about the plant as given, and the scopes of the margin, the certificate and a design say so."""
    general = GeneralHyperbolic2x2(lam=0.3, mu=0.7, a=0.1, b=0.0, c=0.0, d=-0.2, q=0.6, rho=0.7, length=1.3)
    controller = nr.CollocatedOutputFeedback(FilteredController(0.02, 0.3))
    dm = nr.delay_margin(general, controller, rigorous=True)
    cert = nr.certify(general, controller, delta_max=0.1, rigorous=True, k_region=False)
    design = nr.design_reflection(general, "margin").design.certificate
    for scope in (dm.scope, cert.scope, cert.margin.scope, design.scope):
        assert "the plant's normal form as computed in floating point" in scope
        assert "the plant as given" not in scope


# ------------------------------------------------------------------------------------ integral gains
def _gains_factors(c, law, s):
    """``(A, B)`` of ``StateFeedback(k, a_u + b_u x, a_v + b_v x)`` on the PDE at ``s``, in closed form at 40 digits.

    ``d/dx [u; v] = M [u; v]``, ``M = [[(a - s)/lam, b/lam], [-c/mu, (s - d)/mu]]``, ``[u; v](0) = [q; 1]``;
    ``e^{x M} = e^{h x} (cosh(D x) I + sinh(D x)/D N)`` (``h`` half the trace, ``N = M - h I``, ``D^2 = -det N``),
    so ``int_0^L (alpha + beta x) [u; v] dx`` needs ``P(l) = int_0^L (alpha + beta x) e^{l x} dx`` at ``l = h +- D``.
    ``A = e^{-(s - d) L/mu} (v(L) - rho u(L))``, ``B = -e^{-(s - d) L/mu} (k u(L) + int_0^L g_u u + g_v v dx)``
    (the boundary condition ``v(L) = rho u(L) + U e^{-delta s}``), ``tau = L/lam + L/mu`` exact.
    """
    lam, mu, a, b, cc, d, q, rho, L = (mp.mpf(c[k]) for k in ("lam", "mu", "a", "b", "c", "d", "q", "rho", "length"))
    k, (au, bu), (av, bv) = mp.mpf(law[0]), (mp.mpf(x) for x in law[1]), (mp.mpf(x) for x in law[2])
    m00, m01, m10, m11 = (a - s) / lam, b / lam, -cc / mu, (s - d) / mu
    h = (m00 + m11) / 2
    D = mp.sqrt(((m00 - m11) / 2) ** 2 + m01 * m10)
    w = (q, mp.mpf(1))
    nw = ((m00 - h) * q + m01, m10 * q + (m11 - h))
    state = [mp.exp(h * L) * (mp.cosh(D * L) * w[i] + mp.sinh(D * L) / D * nw[i]) for i in range(2)]

    def P(lmb, alpha, beta):
        e = mp.exp(lmb * L)
        return alpha * (e - 1) / lmb + beta * (e * (lmb * L - 1) + 1) / lmb**2

    def integral(i, alpha, beta):
        plus, minus = P(h + D, alpha, beta), P(h - D, alpha, beta)
        return (plus + minus) / 2 * w[i] + (plus - minus) / (2 * D) * nw[i]

    norm = mp.exp(-(s - d) * L / mu)
    total = integral(0, au, bu) + integral(1, av, bv)
    return norm * (state[1] - rho * state[0]), -norm * (k * state[0] + total)


def _paper(lam, mu, spm, smp, q, rho):
    return dict(lam=lam, mu=mu, a=0.0, b=spm, c=smp, d=0.0, q=q, rho=rho, length=1.0)


#: ``(coefficients, (k, (a_u, b_u), (a_v, b_v)))``: ``lam, mu = 0.3, 0.7`` (``t_v = tau_d lam / (lam + mu)`` between two
#: multiples of ``ulp(tau_d)``), ``3, 7`` (``tau = 10/21`` not a double, ``t_v`` on the grid), a general plant.
GAINS = [
    (_paper(0.3, 0.7, 0.5, -0.4, 0.8, 0.6), (-0.6, (0.1, 0.2), (-0.1, 0.0))),
    (_paper(3.0, 7.0, 2.0, 3.0, 0.9, 0.5), (-0.3, (0.1, 0.2), (-0.3, 0.0))),
    (
        dict(lam=0.3, mu=0.7, a=0.1, b=0.4, c=-0.5, d=-0.2, q=0.6, rho=0.7, length=1.3),
        (-0.6, (0.1, 0.2), (-0.1, 0.0)),
    ),
]


def _gains_case(c, law):
    """The package's plant and ``StateFeedback`` of a case of :data:`GAINS`."""
    if c["a"] or c["d"] or c["length"] != 1.0:
        plant = GeneralHyperbolic2x2(**c)
    else:
        plant = Hyperbolic2x2(c["lam"], c["mu"], c["b"], c["c"], c["q"], c["rho"])
    (au, bu), (av, bv) = law[1], law[2]
    return plant, nr.StateFeedback(law[0], lambda x: au + bu * x, lambda x: av + bv * x)


@pytest.mark.parametrize(("c", "law"), GAINS)
def test_the_proven_margin_of_a_state_feedback_with_integral_gains_holds_for_the_plant_as_given(c, law):
    """Before, the proofs took ``t_v`` rounded to a multiple of ``ulp(tau)`` and ``tau`` as the double: the scope said
    so and the margin was not mapped. The old balls held the PDE's margin too (5e-14 to 4e-13 inside), the rounding
    moving it by about 1e-16; the old crossing frequency of the general plant was 1.0e-14 from the PDE's, within
    its stated 1.1e-14."""
    plant, controller = _gains_case(c, law)
    assert rounded_parts(plant, controller) == "" and given_plant_scale(plant, controller) != 1
    dm = nr.delay_margin(plant, controller, rigorous=True)
    assert "the plant as given" in dm.scope and "as the double" not in dm.scope
    _assert_margin_holds(dm, lambda s: _gains_factors(c, law, s))


@pytest.mark.parametrize(("c", "law"), [GAINS[0], GAINS[2]])
def test_the_plant_balls_enclose_the_loop_with_integral_gains_and_tau_exact(c, law):
    """``given_plant_balls`` of a state feedback with integral gains encloses ``F``, ``F'``, ``F''`` of the PDE's loop
    with ``tau`` exact (40 digits); before, there was no enclosure of the plant's own loop (None)."""
    plant, controller = _gains_case(c, law)
    for delta in (0.0, 0.7):
        balls = given_plant_balls(plant, controller, delta)
        assert isinstance(balls, GivenPlantBalls)

        def F(s, delta=delta):
            A, B = _gains_factors(c, law, s)
            return A + B * mp.exp(-mp.mpf(delta) * s)

        _assert_encloses(balls, F, (complex(-1.0, 30.0), complex(0.5, -7.0), complex(-0.2, 150.0)), delta)


def test_the_jump_of_the_gains_kernel_between_two_doubles_is_held_by_a_proven_term():
    """``lam, mu = 0.3, 0.7``: the loop as built (``tau_d``) has ``t_v = tau_d lam / (lam + mu)``, not a multiple of
    ``ulp(tau_d)``. Its kernel ``r K(r theta)`` jumps there by ``r (q g_u(0) lam - g_v(0) mu)`` (the point delays of
    ``e^{-s t_v} [u; v](x, s)``: ``q e^{-s (t_v + x/lam)}`` and ``e^{-s (1 - x)/mu}``, weighted by the gains); the
    stored kernel jumps by as much at the nearest multiple, and the second term, on the ulp holding ``t_v``, has
    that jump as its radius (1e-12 above it at most). Shifted by a loop delay whose ulp is wider than its own, the
    term keeps its support inside its nodes (before, the rounded sum made it empty: a ParameterError)."""
    from fractions import Fraction

    from nrobust.hyperbolic.loops.exact_gains import gain_terms

    c, law = GAINS[0]
    plant, controller = _gains_case(c, law)
    lam, mu, q = Fraction(c["lam"]), Fraction(c["mu"]), Fraction(c["q"])
    tau_d = Fraction(plant.tau)
    r = (1 / lam + 1 / mu) / tau_d
    t_v = tau_d * lam / (lam + mu)
    kernel, term = gain_terms(plant, controller.g_u, controller.g_v)
    jump = r * (q * Fraction(law[1][0]) * lam - Fraction(law[2][0]) * mu)
    assert term.nodes.size == 2 and term.b - term.a == math.ulp(plant.tau)
    assert Fraction(term.a) < t_v < Fraction(term.b) and not np.any(term.pieces[2])
    ulp = Fraction(math.ulp(plant.tau))
    node = float(round(t_v / ulp) * ulp)  # the multiple of ulp(tau_d) nearest t_v: an end of the term
    assert node in (term.a, term.b)
    assert abs(float(jump)) <= term.radius <= abs(float(jump)) + 1e-12
    start, _, coefs = kernel.pieces
    i = int(np.flatnonzero(start == node)[0])
    stored = complex(coefs[i, 0] - coefs[i - 1].sum()).real
    assert abs(stored - float(jump)) < 1e-12 and abs(stored) > 1e6 * kernel.radius
    delta = 7.1  # ulp(t_v + delta) = 4 ulp(tau_d): t_v + delta rounds onto a node of the shifted grid
    (moved,) = term.shift(delta)
    assert Fraction(moved.a) <= Fraction(term.a) + Fraction(delta) <= Fraction(term.b) + Fraction(delta)
    assert Fraction(term.b) + Fraction(delta) <= Fraction(moved.b)
    assert moved.radius == term.radius and moved.variation_radius >= term.variation_radius + 2 * term.radius


def test_the_certificate_of_a_state_feedback_with_integral_gains_holds_for_the_plant_as_given():
    """``certify(plant, StateFeedback(k, g_u, g_v), rigorous=True)`` end to end on ``lam, mu = 0.3, 0.7``: the scope,
    the abscissa (its root re-solved at 40 digits in its proven bracket), the margin ball, and the proven root
    counts (the argument principle at 40 digits)."""
    c, law = GAINS[0]
    plant, controller = _gains_case(c, law)
    delta_max = 0.5
    cert = nr.certify(plant, controller, delta_max=delta_max, rigorous=True, k_region=False)
    assert "the plant as given" in cert.scope and "root counts marked proven" in cert.scope
    assert "as the double" not in cert.scope.split("they are proven")[0]
    claims = {x.name: x.status for x in cert.claims}
    assert claims["spectral abscissa"] == PROVEN and claims["delay margin"] == PROVEN

    def loop(delta):
        def F(s):
            A, B = _gains_factors(c, law, s)
            return A + B * mp.exp(-mp.mpf(delta) * s)

        return F

    ab = cert.abscissa
    assert ab.rigorous and ab.root is not None
    with mp.workdps(DPS):
        root = mp.findroot(loop(0.0), mp.mpc(ab.root))
    assert mp.mpf(ab.value_bracket[0]) <= root.real <= mp.mpf(ab.value_bracket[1])
    _assert_margin_holds(cert.margin, lambda s: _gains_factors(c, law, s), omega=False)
    for roots, delta, name in (
        (cert.roots_nominal, 0.0, "roots at delta = 0"),
        (cert.roots_delayed, delta_max, "roots at delta_max"),
    ):
        assert claims[name] == PROVEN and roots.rigorous
        assert roots.count == winding_number(loop(delta), roots.region)
