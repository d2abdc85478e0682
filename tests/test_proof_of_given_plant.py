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

Root counts in a rectangle do not map: they are proven on the plant's own loop
(``given_plant_balls``), and checked here by the argument principle on the exact-tau loop at 40
digits (the argument unwrapped on samples turning by less than a radian each) and by the
40-digit roots in their proven boxes.
"""

from __future__ import annotations

import dataclasses
import itertools
from fractions import Fraction

import mpmath as mp
import numpy as np
import pytest

import nrobust as nr
from nrobust.hyperbolic import FiniteTimeController, Hyperbolic2x2, ReflectionController, StateFeedback
from nrobust.hyperbolic.loops.controllers import loop_factors
from nrobust.hyperbolic.loops.exact_form import exact_ratios
from nrobust.hyperbolic.loops.given_plant import (
    GivenPlantBalls,
    given_plant_balls,
    given_plant_scale,
    rounded_parts,
    to_given_plant,
)
from nrobust.margins import delay_margin as factor_delay_margin
from nrobust.reports.certificate import PROVEN

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
    """``(A, B)`` of the PDE's loop at ``s``: U_BS, U_BS2(K) (Theorem 4), ``U = k u(t, 1)`` (the boundary condition)."""
    rho, q = mp.mpf(args[5]), mp.mpf(args[4])
    zu, zv, tau = _fundamental(args, s)
    A = zv - rho * zu  # e^{-s/mu} (v(1) - rho u(1)) / v(0): the open loop 1 - Phi
    if isinstance(controller, StateFeedback):
        return A, -mp.mpf(controller.k) * zu
    if isinstance(controller, FiniteTimeController):  # U_BS: B = Phi = 1 - A
        return A, 1 - A
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


def test_a_rounded_principal_gain_is_a_ball_about_the_plant():
    """``rho q = 0.3 * 0.1`` is not a double: the loop carries it as a ball, and the margin of the PDE
    (``tau = 4/3`` and ``rho q`` exact, 40 digits) lies in the proven ball."""
    args = (1.0, 3.0, 1.0, 1.0, 0.1, 0.3)
    plant, controller = Hyperbolic2x2(*args), ReflectionController(0.1)
    assert given_plant_scale(plant, controller) is not None
    assert rounded_parts(plant, controller) == ""
    dm = nr.delay_margin(plant, controller, rigorous=True)
    assert "the plant as given" in dm.scope
    if np.isfinite(dm.margin):
        lo, hi = dm.margin_ball
        assert mp.mpf(lo) <= _pde_margin(args, controller, dm.omega)[1] <= mp.mpf(hi)


# ---------------------------------------------------------------------------------------------------- root counts
def _loop(args, controller, delta):
    """The PDE's loop ``s -> A(s) + B(s) e^{-delta s}`` with ``tau`` exact (the oracle of the module notes)."""

    def F(s):
        A, B = _factors(args, controller, s)
        return A + B * mp.exp(-mp.mpf(delta) * s)

    return F


def _winding(F, region, n=300):
    """Winding number of ``F`` about the rectangle's boundary, the argument unwrapped on ``4 n`` samples at 40 digits.

    Independent of the package's counting (no step rule, no balls); asserts that consecutive
    samples turn by less than 1 radian, so that the unwrapping cannot miss a turn.
    """
    x0, x1, y0, y1 = (mp.mpf(v) for v in region)
    corners = [mp.mpc(x0, y0), mp.mpc(x1, y0), mp.mpc(x1, y1), mp.mpc(x0, y1)]
    with mp.workdps(DPS):
        values = [F(a + (b - a) * mp.mpf(k) / n) for a, b in zip(corners, corners[1:] + corners[:1]) for k in range(n)]
        values.append(values[0])
        steps = [mp.arg(b / a) for a, b in itertools.pairwise(values)]
    assert max(abs(t) for t in steps) < 1.0
    return int(mp.nint(mp.fsum(steps) / (2 * mp.pi)))


#: The paper's plant (``tau = 2``, a double) and ``(lam, mu) = (3, 7)`` (``tau = 10/21``, not a double).
COUNT_PLANTS = [(1.0, 1.0, 1.0, 1.0, 1.0, 0.85), PLANTS[1]]


@pytest.mark.parametrize("args", COUNT_PLANTS)
def test_the_certificate_counts_the_roots_of_the_plant_as_given(args):
    """The proven counts at ``delta = 0`` and ``delta_max``, and each proven box, hold for the exact-tau loop."""
    plant, controller, delta_max = Hyperbolic2x2(*args), ReflectionController(0.1), 0.1
    cert = nr.certify(plant, controller, delta_max=delta_max, rigorous=True, k_region=False)
    assert "the plant as given" in cert.scope
    assert "proven for the loop with tau the double" not in cert.scope  # the counts are no longer an exception
    if given_plant_scale(plant, controller) != 1:
        assert "root counts marked proven" in cert.scope and "plant's own loop" in cert.scope
    claims = {c.name: c for c in cert.claims}
    for roots, delta, name in (
        (cert.roots_nominal, 0.0, "roots at delta = 0"),
        (cert.roots_delayed, delta_max, "roots at delta_max"),
    ):
        assert claims[name].status == PROVEN and roots.rigorous and roots.certified
        F = _loop(args, controller, delta)
        # the count: the argument principle at 40 digits on the region proven (exact integers)
        assert roots.count == _winding(F, roots.region) > 0
        # each entry: the root of the exact-tau loop, refined at 40 digits, lies in its proven box
        for z, box in zip(roots.roots, roots.boxes):
            with mp.workdps(DPS):
                root = mp.findroot(F, mp.mpc(z))
            assert box[0] <= root.real <= box[1] and box[2] <= root.imag <= box[3]


@pytest.mark.parametrize("delta", [0.0, 0.3])
def test_the_plant_balls_enclose_the_loop_with_tau_exact(delta):
    """``given_plant_balls`` encloses ``F``, ``F'`` and ``F''`` of the exact-tau loop (mpmath, 40 digits)."""
    from nrobust._flint import working_precision

    args, controller = PLANTS[1], ReflectionController(0.1)
    balls = given_plant_balls(Hyperbolic2x2(*args), controller, delta)
    assert isinstance(balls, GivenPlantBalls)
    F = _loop(args, controller, delta)
    for s in (complex(-1.0, 30.0), complex(0.5, -7.0), complex(-4.0, 150.0)):
        for k in range(3):
            value = balls(s, k)
            with mp.workdps(DPS):
                truth = mp.diff(F, mp.mpc(s), k)
            with working_precision(200) as flint:  # the 40-digit value as a ball far narrower than the enclosure
                assert value.contains(flint.acb(truth)), (s, k, value, truth)
    # tau a double: no map, the loop's own enclosure applies at delta = 0; at 0.3 the loop's point delays
    # tau + 0.3 are not doubles, so the enclosure is of A + B e^{-delta s} with delta exact (r = 1)
    own = given_plant_balls(Hyperbolic2x2(*COUNT_PLANTS[0]), controller, delta)
    assert own is None if delta == 0.0 else isinstance(own, GivenPlantBalls)
    # a rounded principal gain (rho q = 0.3 * 0.1): its ball is part of the plant's enclosure
    args = (1.0, 3.0, 1.0, 1.0, 0.1, 0.3)
    balls = given_plant_balls(Hyperbolic2x2(*args), controller, delta)
    assert isinstance(balls, GivenPlantBalls)
    F = _loop(args, controller, delta)
    for s in (complex(-1.0, 30.0), complex(0.5, -7.0)):
        with mp.workdps(DPS):
            truth = F(mp.mpc(s))
        with working_precision(200) as flint:
            assert balls(s, 0).contains(flint.acb(truth))


def test_a_root_within_rounding_of_the_contour_is_not_counted_on_it():
    """A root of the plant's loop 4e-19 (relative) from an edge: refused on that edge, counted right once moved.

    Nominal loop of ``(3, 7)`` under U_BS2(0.1): ``F = 1 - 0.75 e^{-tau s}`` (``N~`` cancels), zeros
    ``s_k = (-ln(4/3) + 2 pi i k) / tau`` with ``tau = 10/21`` exactly; the right edge of the box is the
    double nearest ``Re s_10`` (at most 5.6e-17 away, ``|s_10| = 132``).
    """
    args, controller = PLANTS[1], ReflectionController(0.1)
    plant = Hyperbolic2x2(*args)
    with mp.workdps(DPS):
        tau = 1 / mp.mpf(args[0]) + 1 / mp.mpf(args[1])
        zeros = [(-mp.log(mp.mpf(4) / 3) + 2j * mp.pi * k) / tau for k in range(-300, 301)]
    edge = float(zeros[310].real)
    assert abs(edge - zeros[310].real) <= 1e-17 * abs(zeros[310])
    box = (edge - 1.0, edge, float(zeros[310].imag) - 1.0, float(zeros[310].imag) + 1.0)
    F0, balls = nr.characteristic(plant, controller, 0.0), given_plant_balls(plant, controller, 0.0)
    with pytest.raises(nr.CertificationError):
        nr.count_roots(F0, box, rigorous=True, balls=balls, max_shifts=0)

    def inside(region):
        return sum(region[0] < z.real < region[1] and region[2] < z.imag < region[3] for z in zeros)

    moved = nr.count_roots(F0, box, rigorous=True, balls=balls)
    with pytest.raises(nr.ParameterError, match="balls"):
        nr.count_roots(F0, box, rigorous=True, balls=F0)
    assert moved.shifted and moved.region[1] > edge and int(moved) == inside(moved.region) == 1
    cert = nr.certify(plant, controller, delta_max=0.1, region=box, rigorous=True, k_region=False)
    status = {c.name: c.status for c in cert.claims}["roots at delta = 0"]
    if status == PROVEN:  # proven only about a region whose edges miss the root
        assert cert.roots_nominal.shifted and cert.roots_nominal.count == inside(cert.roots_nominal.region) == 1
    else:
        assert any(u.startswith("roots at delta = 0") for u in cert.unproven)


def test_the_instability_witness_holds_for_the_plant_as_given():
    """U_BS on ``(3, 7)``: ``2 |rho q| > 1``, so zeros in ``Re s > 0`` at ``delta_max``; the witness box
    proven on the plant's own loop holds as many zeros of the exact-tau loop (argument principle at 40 digits)."""
    from nrobust.reports.certificate import _unstable_witness

    args, controller, delta_max = PLANTS[1], FiniteTimeController(), 0.1
    plant = Hyperbolic2x2(*args)
    cert = nr.certify(plant, controller, delta_max=delta_max, rigorous=True, k_region=False)
    assert {c.name: c.status for c in cert.claims}["instability at delta_max"] == PROVEN
    Fd = nr.characteristic(plant, controller, delta_max)
    box, n = _unstable_witness(Fd, True, given_plant_balls(plant, controller, delta_max))
    assert box[0] > 0.0 and n == _winding(_loop(args, controller, delta_max), box) >= 1


def test_the_analysis_as_built_covers_the_plants_delay_range(monkeypatch: pytest.MonkeyPatch) -> None:
    """``r = tau / tau_d < 1`` (lam, mu = 1, 10): the plant's delays up to ``delta_max`` are those of the loop as
    built up to ``delta_max / r > delta_max``; the loop as built is analysed that far (:func:`built_delay`) and the
    mapped result is cut at the plant's ``delta_max`` (analysing only to ``delta_max`` left the plant's delays in
    ``(r delta_max, delta_max]`` unexamined)."""
    import nrobust.hyperbolic.analyses.margin as analysis

    plant, law = Hyperbolic2x2(1.0, 10.0, 1.0, 1.0, 1.0, 0.85), ReflectionController(0.1)
    r = given_plant_scale(plant, law)
    assert r is not None and r < 1
    asked: list[float] = []
    core = analysis.factor_delay_margin

    def spy(A, B, **kwargs):
        asked.append(kwargs["delta_max"])
        return core(A, B, **kwargs)

    monkeypatch.setattr(analysis, "factor_delay_margin", spy)
    m = nr.delay_margin(plant, law, delta_max=0.5, rigorous=True)
    assert Fraction(asked[0]) * r >= Fraction(0.5)  # the analysis reaches the plant's 0.5
    assert m.delta_max == 0.5 and m.intervals[-1][1] == 0.5 and m.counts[-1][1] == 0.5
    assert all(d <= 0.5 for c in m.crossings for d in c.delays)
