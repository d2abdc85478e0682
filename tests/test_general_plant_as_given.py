"""Proofs about a general plant as given: its principal gains carry proven radii, its ``tau`` is mapped exactly.

A :class:`GeneralHyperbolic2x2` with constant coefficients not exact in binary
(``lam = 0.3``, ``mu = 0.7``, ``a = 0.1``, ``d = -0.2``, ``L = 1.3``) has the principal gains
``rho q e^{sigma_0 tau}`` and ``q e^{sigma_0 tau}`` (irrational) and ``tau = L/lam + L/mu`` (not
a double). Oracle, sharing no code with the package: the Laplace-domain solution
``[u; v](L, s) = expm(L M(s)) [q; 1]`` of the PDE with ``M(s) = [[(a - s)/lam, b/lam],
[-c/mu, (s - d)/mu]]`` (``mpmath.expm`` at 40 digits), the loop of ``U(t) = k u(t - delta, L)``
being ``v(L) - rho u(L) - k e^{-delta s} u(L)``; its crossing solved by ``mpmath.findroot``, its
counts by the argument principle at 40 digits.

The old proofs (the gains and ``tau`` as the doubles computed from the coefficients) hold for
the rounded loop: on the uncoupled plant, whose spectral abscissa is ``ln(rho_q') / tau`` in
closed form, their proven bracket misses it by 2e-16 (test below). On the coupled plant their
margin ball still contained the PDE's margin (the rounding moves it by 5e-14, the ball is 2.3e-13
wide): no coupled plant was found on which the old margin ball misses.
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import mpmath as mp
import numpy as np
import pytest
from _oracles import winding_number

import nrobust as nr
from nrobust.balls import ball_eval
from nrobust.hyperbolic import FiniteTimeController, Hyperbolic2x2, ReflectionController, StateFeedback
from nrobust.hyperbolic.analyses.rouche import rouche_delay_bound
from nrobust.hyperbolic.loops.controllers import characteristic, loop_factors, rounded_parts
from nrobust.hyperbolic.loops.given_plant import exact_tau, given_plant_scale
from nrobust.hyperbolic.plants.general import GeneralHyperbolic2x2
from nrobust.quasipoly import QuasiPolynomial

flint = pytest.importorskip("flint")

DPS = 40
COUPLED = dict(lam=0.3, mu=0.7, a=0.1, b=0.4, c=-0.5, d=-0.2, q=0.6, rho=0.7, length=1.3)
UNCOUPLED = {**COUPLED, "b": 0.0, "c": 0.0}
K = -0.4  # U = K u(t - delta, L): nominally stable on the coupled plant, delta* ~ 6.19


def _uv(args, s):
    """``(u(L, s), v(L, s))`` from ``[q; 1]`` at ``x = 0``: the closed-form matrix exponential in mpmath."""
    lam, mu, a, b, c, d, q, L = (mp.mpf(args[k]) for k in ("lam", "mu", "a", "b", "c", "d", "q", "length"))
    M = mp.matrix([[(a - s) / lam, b / lam], [-c / mu, (s - d) / mu]])
    E = mp.expm(L * M)
    return E[0, 0] * q + E[0, 1], E[1, 0] * q + E[1, 1]


def _factors(args, k, s):
    """``(A, B)`` of the PDE's loop ``v(L) - rho u(L) - k e^{-delta s} u(L)`` (the boundary condition)."""
    u, v = _uv(args, s)
    return v - mp.mpf(args["rho"]) * u, -mp.mpf(k) * u


def _pde_margin(args, k, w0):
    """``(w, delta*)``: the crossing near ``w0`` and its first delay, at 40 digits."""
    with mp.workdps(DPS):

        def g(w):
            A, B = _factors(args, k, mp.mpc(0, w))
            return abs(A) ** 2 - abs(B) ** 2

        w = mp.findroot(g, mp.mpf(w0))
        A, B = _factors(args, k, mp.mpc(0, w))
        return w, (-mp.arg(-A / B)) % (2 * mp.pi) / w  # e^{-i w delta} = -A / B


def test_the_scope_is_the_plant_as_given():
    plant = GeneralHyperbolic2x2(**COUPLED)
    for controller in (StateFeedback(K), FiniteTimeController(), ReflectionController(0.1)):
        assert rounded_parts(plant, controller) == ""
        assert given_plant_scale(plant, controller) == exact_tau(plant) / Fraction(
            loop_factors(plant, controller)[0].delays[-1]
        )
    assert exact_tau(plant) == Fraction(1.3) / Fraction(0.3) + Fraction(1.3) / Fraction(0.7)
    A, B = loop_factors(plant, StateFeedback(K))
    # the principal gains are not exact: their balls have positive radii, of the order of their rounding
    assert A.point_radii[1][0] > 0.0 and B.point_radii[0][0] > 0.0
    assert max(A.point_radii[1][0], B.point_radii[0][0]) < 1e-15


def test_the_proven_margin_holds_for_the_pde():
    """delta* of the PDE (40 digits) lies in the proven ball; the crossing frequency within its proven accuracy."""
    plant = GeneralHyperbolic2x2(**COUPLED)
    dm = nr.delay_margin(plant, StateFeedback(K), rigorous=True)
    assert dm.rigorous and "the plant as given" in dm.scope
    w, delta = _pde_margin(COUPLED, K, dm.omega)
    lo, hi = dm.margin_ball
    assert mp.mpf(lo) <= delta <= mp.mpf(hi)
    assert abs(mp.mpf(dm.omega) - w) <= mp.mpf(dm.omega_accuracy)
    # the ball is tight: 1e-13 relative (the kernel's proven radius, 5e-16, and the gains' balls)
    assert hi - lo <= 1e-13 * delta
    np.testing.assert_allclose(dm.margin, float(delta), rtol=1e-13)  # inside a ball 1e-13 wide


@pytest.mark.parametrize("delta, expected", [(0.0, 0), (10.0, 2)])
def test_the_proven_counts_agree_with_the_argument_principle(delta, expected):
    """The counts between crossing delays: 0 before delta* ~ 6.19, 2 after, by the 40-digit argument principle.

    The proven frequency bound ``W`` holds every zero with ``Re s >= 0`` for every delay in
    ``|s| < W``: the rectangle ``[0, W] x [-W, W]`` holds them all.
    """
    plant = GeneralHyperbolic2x2(**COUPLED)
    dm = nr.delay_margin(plant, StateFeedback(K), rigorous=True)
    (count,) = [n for a, b, n in dm.counts if a <= delta < b]
    assert count == expected

    def F(s):
        A, B = _factors(COUPLED, K, s)
        return A + B * mp.exp(-mp.mpf(delta) * s)

    W = dm.frequency_bound
    assert winding_number(F, (0.0, W, -W, W), 400) == count


def test_the_certificate_holds_for_the_pde():
    """The certificate's proven abscissa bracket and root boxes hold the 40-digit roots of the PDE's loop."""
    plant = GeneralHyperbolic2x2(**COUPLED)
    cert = nr.certify(plant, StateFeedback(K), delta_max=1.0, rigorous=True, k_region=False)
    assert "the plant as given" in cert.scope and "L/lam + L/mu" in cert.scope

    def F(s):
        return sum(_factors(COUPLED, K, s))

    with mp.workdps(DPS):
        ab = cert.abscissa
        root = mp.findroot(F, mp.mpc(ab.root))
        assert mp.mpf(ab.value_bracket[0]) <= root.real <= mp.mpf(ab.value_bracket[1])
        roots = cert.roots_nominal
        assert roots.rigorous and roots.count == len(roots.boxes) > 0
        for z, box in zip(roots.roots, roots.boxes):
            r = mp.findroot(F, mp.mpc(z))
            assert mp.mpf(box[0]) <= r.real <= mp.mpf(box[1]) and mp.mpf(box[2]) <= r.imag <= mp.mpf(box[3])


def test_the_abscissa_bracket_holds_for_the_uncoupled_plant():
    """``F(s; 0) = 1 - (rho + k) q e^{sigma_0 tau} e^{-tau s}``: every root has ``Re s = ln((rho + k) q w) / tau``.

    The old bracket, proven for the doubles ``tau_d`` and ``(rho + k) q w`` rounded, missed it by 2e-16.
    """
    plant = GeneralHyperbolic2x2(**UNCOUPLED)
    cert = nr.certify(plant, StateFeedback(K), delta_max=0.5, rigorous=True, region=(-1.0, 1.0, -60.0, 60.0))
    assert "the plant as given" in cert.scope
    ab = cert.abscissa
    with mp.workdps(DPS):
        lam, mu, a, d, q, rho, L = (mp.mpf(UNCOUPLED[k]) for k in ("lam", "mu", "a", "d", "q", "rho", "length"))
        tau = L / lam + L / mu
        gain = (rho + mp.mpf(K)) * q * mp.exp(L * (a / lam + d / mu))
        value = mp.log(gain) / tau
        assert ab.rigorous and ab.value_bracket is not None
        assert mp.mpf(ab.value_bracket[0]) <= value <= mp.mpf(ab.value_bracket[1])
        # each proven box of the nominal roots holds a root (ln(gain) + 2 pi i j) / tau of the PDE
        for z, box in zip(cert.roots_nominal.roots, cert.roots_nominal.boxes):
            j = mp.nint(mp.mpf(z.imag) * tau / (2 * mp.pi))
            root = (mp.log(gain) + 2j * mp.pi * j) / tau
            assert mp.mpf(box[0]) <= root.real <= mp.mpf(box[1]) and mp.mpf(box[2]) <= root.imag <= mp.mpf(box[3])
    # 1e-9: the proven boxes of the root search, the value's float within its bracket
    np.testing.assert_allclose(ab.value, float(value), rtol=0, atol=1e-9)


def test_the_rouche_range_uses_the_gains_of_the_plant():
    """epsilon_0 of U_BS on the plant: at most ``1 - 2 |rho q e^{sigma_0 tau}|`` (40 digits), within 1e-15 of it."""
    plant = GeneralHyperbolic2x2(**COUPLED)
    bound = rouche_delay_bound(plant, FiniteTimeController(), rigorous=True)
    with mp.workdps(DPS):
        lam, mu, a, d, q, rho, L = (mp.mpf(COUPLED[k]) for k in ("lam", "mu", "a", "d", "q", "rho", "length"))
        exact = 1 - 2 * rho * q * mp.exp(L * (a / lam + d / mu))
    assert bound.rigorous and mp.mpf(bound.epsilon_0) <= exact
    np.testing.assert_allclose(bound.epsilon_0, float(exact), rtol=0, atol=1e-15)  # the gains' radii, a few ulps


def test_a_cancellation_of_the_gains_is_exact():
    """U_BS at delta = 0: ``A + B = 1 + (I_N - I_N)``, its gains cancel exactly (not a ball about 0)."""
    plant = GeneralHyperbolic2x2(**COUPLED)
    F = characteristic(plant, FiniteTimeController(), 0.0)
    assert [t for _, t in F.point_terms] == [0.0] and F.exact_points
    # and the natural gain StateFeedback(-rho) (issue 21, point 7)
    F = characteristic(plant, StateFeedback(-COUPLED["rho"]), 0.0)
    assert [t for _, t in F.point_terms] == [0.0]


def test_a_rounded_product_of_a_hyperbolic2x2_is_a_ball():
    """``rho q = 0.3 * 0.1`` is not a double: its ball holds it, the margin is of the plant as given."""
    plant, controller = Hyperbolic2x2(1.0, 3.0, 1.0, 1.0, 0.1, 0.3), ReflectionController(0.1)
    A, _ = loop_factors(plant, controller)
    exact = Fraction(0.3) * Fraction(0.1)
    stored, radius = Fraction(float(A.point_terms[1][0][0])), Fraction(float(A.point_radii[1][0]))
    assert stored != -exact and abs(stored + exact) <= radius
    assert rounded_parts(plant, controller) == "" and given_plant_scale(plant, controller) is not None


def test_the_paper_plant_has_no_radii():
    """Every number of the paper's plant is exact: its loop carries no radius (the proofs cost nothing more)."""
    A, B = loop_factors(Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85), ReflectionController(0.1))
    assert A.point_radii == () and B.point_radii == ()


# ---------------------------------------------------------------------------------------------------- the algebra
def test_balls_enclose_every_function_in_the_radii():
    """The ball of ``1 + (c +- r) e^{-s}`` at a point holds the function with the coefficient at either end."""
    c, r = -0.3, 1e-6
    F = QuasiPolynomial([[1.0], [c]], [0.0, 1.0], radii=[[0.0], [r]])
    for s in (0.5 + 2j, -1.0 + 0.0j):
        value = ball_eval(F, s)
        for coef in (c - r, c + r):
            assert value.contains(flint.acb(1 + coef * complex(np.exp(-s))))


def test_the_algebra_carries_the_radii():
    """Sums, scalings, products and derivatives of balls hold every function of the operands' balls."""
    F = QuasiPolynomial([[1.0], [0.3]], [0.0, 1.0], radii=[[0.0], [1e-10]])
    G = QuasiPolynomial([[0.7, 2.0]], [1.0], radii=[[1e-10, 0.0]])
    s = 0.2 + 3j

    def ends(sign_f, sign_g):
        f = QuasiPolynomial([[1.0], [0.3 + sign_f * 1e-10]], [0.0, 1.0])
        g = QuasiPolynomial([[0.7 + sign_g * 1e-10, 2.0]], [1.0])
        return f, g

    for expr in (lambda f, g: f + g, lambda f, g: f * 3.1, lambda f, g: f * g, lambda f, g: (f + g).derivative()):
        ball = ball_eval(expr(F, G), s)
        for sf, sg in itertools.product((-1, 1), repeat=2):
            f, g = ends(sf, sg)
            assert ball.contains(flint.acb(complex(expr(f, g)(np.array([s]))[0])))
    # equality and hashing see the radii
    assert F != QuasiPolynomial([[1.0], [0.3]], [0.0, 1.0]) and F == QuasiPolynomial(
        [[1.0], [0.3]], [0.0, 1.0], radii=[[0.0], [1e-10]]
    )
    # a kernel times a ball is refused (its error is not a point radius)
    kernel = nr.DistributedDelay([0.0, 1.0], [1.0, 2.0])
    with pytest.raises(nr.ParameterError):
        _ = G * QuasiPolynomial([], [], [kernel])


def test_coefficients_given_as_samples_are_the_plants_model_in_the_scope() -> None:
    """A coefficient given as samples: the cubic spline through them is the user's model of the plant, and the
    kernel route a model of that; the scope says both and the proven ball's reason says "for the model" (before:
    "proven in ball arithmetic: delta* in [3.1115744173041091, 3.1115744173043924]", the spline plant's own margin
    3.11157441799810 lying 7e-10 outside)."""
    xs = np.linspace(0.0, 1.0, 21)
    plant = nr.GeneralHyperbolic2x2(1.2, 0.8, (xs, 0.1 + 0.1 * xs), 0.3, 0.3, -0.1, 0.6, 0.4)
    dm = nr.delay_margin(plant, nr.StateFeedback(-0.9), rigorous=True)
    assert dm.of_model and dm.scope.startswith("a model of the PDE")
    assert "; a given as samples: the cubic spline through them is the plant's model; " in dm.scope
    assert dm.scope.endswith(
        "a convergence study in the kernel grid estimates the margin's distance to the PDE's at "
        f"{dm.model_error:.2g} (floating point, not proven)"
    )
    assert "(proven in ball arithmetic for the model: delta* in [" in dm.reason
