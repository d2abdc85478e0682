"""The collocated observer under U_BS2(K) and U_BS on coupled plants with constant couplings, proven for the PDE.

Oracle (``_collocated_oracle``, no nrobust import, 40 digits): the kernels as Taylor series of their Goursat problems
(degree 50), the Laplace-domain profiles as Taylor series in ``x``, crossings by ``mpmath.findroot``. The inverse
kernels ``L``, which the oracle does not compute, are checked by the resolvent identity ``L = K + K o L`` with the
oracle's ``K`` and mpmath quadrature.

Before ``collocated_proof`` the loop was the kernel route's (a model): on the paper's plant under U_BS2(0.1) the
rigorous ball ``[0.1689014326376654, 0.16890143271962718]`` missed the PDE's margin 0.16890143103111756993 by
1.6e-9 and its scope said "a model of the PDE".
"""

from __future__ import annotations

import math
from fractions import Fraction

import mpmath as mp
import pytest
from _collocated_oracle import DPS, CollocatedPDE, horner, kernel_pair

import nrobust as nr
from nrobust.hyperbolic import CollocatedOutputFeedback, FiniteTimeController, Hyperbolic2x2, ReflectionController
from nrobust.hyperbolic.loops.collocated_proof import (
    _Pair,
    _solve,
    inverse_kernel_enclosure,
    kernel_enclosure,
    response_pieces,
)
from nrobust.hyperbolic.loops.controllers import loop_route, loop_scope
from nrobust.hyperbolic.loops.given_plant import GivenPlantBalls, given_plant_balls
from nrobust.hyperbolic.loops.observer_proof import proven_response_product

flint = pytest.importorskip("flint")

PAPER = (1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
SECOND = (1.0, 2.0, 0.4, 0.5, 1.0, 0.3)
THIRD = (2.0, 1.0, 1.2, 0.7, 1.0, 0.8)
#: The PDE's margin of the paper's plant under the collocated U_BS2(0.1) (the oracle, 20 digits).
PAPER_MARGIN = "0.16890143103111756993"
POINTS = (0.3 + 0.7j, -0.2 + 5j, 2j)


@pytest.fixture(autouse=True)
def _bits():
    """Ball arithmetic at 256 bits in the tests' own evaluations (the enclosures keep their own precision)."""
    old = flint.ctx.prec
    flint.ctx.prec = 256
    yield
    flint.ctx.prec = old


def _mid(ball):
    return mp.mpf(ball.mid().str(60, radius=False))


def _oracle_kernels(args):
    """The oracle's ``K`` of a plant: ``{name: {(i, j): c}}`` (its ``traces`` with the 2-D coefficients)."""
    lam, mu, spm, smp, q = (mp.mpf(v) for v in args[:5])
    vv, vu = kernel_pair(spm / mu, smp / mu, lam / mu, -smp / (lam + mu), lam * q / mu)
    uu, uv = kernel_pair(-smp / lam, -spm / lam, mu / lam, spm / (lam + mu), mu / (lam * q))
    return {"uu": uu, "uv": uv, "vu": vu, "vv": vv}


def _at(table, x, xi):
    return mp.fsum(c * x**i * xi**j for (i, j), c in table.items())


@pytest.mark.parametrize("args", [PAPER, SECOND, THIRD])
def test_the_kernel_enclosures_hold_the_series(args):
    """``K`` within its proven bound of the oracle's 40-digit kernels on the triangle, the bound below 1e-40
    (measured 1e-58, 1e-76, 2e-62); the oracle's own truncation is below 1e-50."""
    with mp.workdps(DPS):
        truth = _oracle_kernels(args)
        enclosure = kernel_enclosure(flint, Hyperbolic2x2(*args))
        assert enclosure.error < 1e-40
        for x, xi in ((1, 0), (1, 0.3), (1, 1), (0.7, 0.2), (0.5, 0.5)):
            for name in ("uu", "uv", "vu", "vv"):
                value = enclosure.at(flint, name, x, xi)
                gap = abs(_mid(value) - _at(truth[name], mp.mpf(x), mp.mpf(xi)))
                assert gap <= 1e-38 + float((enclosure.error + value.rad()).upper())


@pytest.mark.parametrize(("args", "K"), [(PAPER, 0.1), (SECOND, 0.1)])
def test_the_traces_on_which_the_law_and_observer_rest_are_the_oracles(args, K):
    """The law's gains (eq. (53)) and the observer's gains ``p = -lam K'^{v.}(1, .)`` of the dual plant read from
    the enclosures are the oracle's at 40 digits (the oracle checks that its gains give the target loop and a
    nilpotent error)."""
    pde = CollocatedPDE(args, K)
    plant = Hyperbolic2x2(*args)
    enclosure = kernel_enclosure(flint, plant)
    dual = kernel_enclosure(flint, Hyperbolic2x2(args[1], args[0], args[2], args[3], args[0] * args[4] / args[1], 0.0))
    r = flint.arb(args[5]) - flint.arb(K)
    g_u = enclosure.trace(flint, "vu") - r * enclosure.trace(flint, "uu")
    p_v = -flint.arb(args[0]) * dual.trace(flint, "vu")
    with mp.workdps(DPS):
        for xi in (0.0, 0.4, 1.0):
            assert abs(_mid(g_u(flint.arb(xi))) - horner(pde.g_u, mp.mpf(xi))) < 1e-38
            assert abs(_mid(p_v(flint.arb(xi))) - horner(pde.p_v, mp.mpf(xi))) < 1e-38


def test_a_low_degree_enclosure_holds_the_kernel_and_its_slope():
    """At degree 10 the remainder bound is far from 0 (1.9e-6 on the paper's plant) and must hold the distance to
    the degree-50 series (measured 3.1e-9, so the bound is 600 times it) and the slope bound that of the
    derivatives (both partials): a wrong Gronwall constant or source fails here, where the test of degree 50 could
    not see it."""
    lam = mu = spm = smp = q = flint.arb(1)
    pairs = (
        _Pair(-smp / lam, -spm / lam, mu / lam, spm / (lam + mu), mu / (lam * q), 0),
        _Pair(spm / mu, smp / mu, lam / mu, -smp / (lam + mu), lam * q / mu, 1),
    )
    A, B, error, slope = _solve(flint, pairs, 10)
    assert 1e-7 < error < 1e-5 and slope > error
    truth = _oracle_kernels(PAPER)
    with mp.workdps(DPS):
        worst, worst_slope = mp.mpf(0), mp.mpf(0)
        for name, table in (("uu", A[0]), ("uv", B[0]), ("vv", A[1]), ("vu", B[1])):
            poly = {k: _mid(v) for k, v in table.items()}
            for x, xi in ((1, 0), (1, 0.5), (1, 1), (0.8, 0.1), (0.6, 0.6)):
                x, xi = mp.mpf(x), mp.mpf(xi)
                worst = max(worst, abs(_at(poly, x, xi) - _at(truth[name], x, xi)))
                for dx, dxi in ((1, 0), (0, 1)):

                    def d(t, dx=dx, dxi=dxi):
                        return {(i - dx, j - dxi): c * (i if dx else j) for (i, j), c in t.items() if (i if dx else j)}

                    worst_slope = max(worst_slope, abs(_at(d(poly), x, xi) - _at(d(truth[name]), x, xi)))
    assert 1e-10 < worst <= float(error.upper())
    assert worst_slope <= float(slope.upper())


def _in_second(table, x):
    """``s -> table(x, s)`` as increasing coefficients."""
    out = [mp.mpf(0)] * (1 + max(j for _, j in table))
    for (i, j), c in table.items():
        out[j] += c * x**i
    return out


def _in_first(table, xi):
    """``s -> table(s, xi)`` as increasing coefficients."""
    out = [mp.mpf(0)] * (1 + max(i for i, _ in table))
    for (i, j), c in table.items():
        out[i] += c * xi**j
    return out


def _times(a, b):
    out = [mp.mpf(0)] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] += x * y
    return out


@pytest.mark.parametrize("args", [PAPER, SECOND])
def test_the_inverse_kernels_solve_the_resolvent_identity(args):
    """``L(x, xi) = K(x, xi) + int_xi^x K(x, s) L(s, xi) ds`` with the oracle's ``K`` (the polynomials' product
    integrated exactly in mpmath) to 1e-35 (measured 1e-41); the bound of ``L``'s remainder below 1e-40."""
    enclosure = inverse_kernel_enclosure(flint, Hyperbolic2x2(*args))
    assert enclosure.error < 1e-40
    with mp.workdps(DPS):
        truth = _oracle_kernels(args)
        L = {n: {k: _mid(v) for k, v in enclosure.coefficients[n].items()} for n in enclosure.coefficients}
        for x, xi in ((1, 0.3), (1, 0), (0.7, 0.2)):
            x, xi = mp.mpf(x), mp.mpf(xi)
            for r in "uv":
                for c in "uv":
                    integral = mp.mpf(0)
                    for m in "uv":
                        product = _times(_in_second(truth[r + m], x), _in_first(L[m + c], xi))
                        integral += mp.fsum(a * (x ** (n + 1) - xi ** (n + 1)) / (n + 1) for n, a in enumerate(product))
                    rhs = _at(truth[r + c], x, xi) + integral
                    assert abs(_at(L[r + c], x, xi) - rhs) < 1e-35


@pytest.mark.parametrize(("args", "K"), [(PAPER, 0.1), (SECOND, 0.1), (SECOND, 0.3)])
def test_the_command_response_is_the_pdes(args, K):
    """``C_u(s) = -K q e^{-tau s} + int c e^{-nu s}`` from the proven pieces of ``c`` equals the oracle's ``C_u``
    (the Laplace-domain profiles, no kernel composition) at 40 digits (measured 2e-42 to 2e-41)."""
    response = response_pieces(flint, Hyperbolic2x2(*args), K)
    assert response.error < 1e-40 and response.slope < 1e-40
    pde = CollocatedPDE(args, K)
    lam, mu, q = (mp.mpf(args[i]) for i in (0, 1, 4))
    with mp.workdps(DPS):
        for s in POINTS:
            s = mp.mpc(s)
            total = -K * q * mp.exp(-(1 / lam + 1 / mu) * s)
            for j, piece in enumerate(response.pieces):
                a, b = _mid(response.breaks[j]), _mid(response.breaks[j + 1])
                c = [_mid(x) for x in piece.coeffs()]
                total += mp.quad(lambda u, a=a, c=c, s=s: horner(c, u) * mp.exp(-(a + u) * s), [0, b - a])
            assert abs(total - pde.responses(s)[0]) < 1e-38


@pytest.mark.parametrize(("args", "kappa"), [(PAPER, 0.0), (SECOND, 0.0), (PAPER, -0.3)])
def test_the_loop_holds_the_pdes(args, kappa):
    """``(A_o, B_o)`` of the proven loop within the proven radii of their terms of the PDE's (the oracle's
    ``(1 - Phi) E (1 - C_u, C_u - T)``) at three points (measured 1e-16 to 6e-16; the radii's sum bounds
    ``|int e(nu) e^{-nu s}|`` by ``sup |e| 2 tau`` for ``Re s >= 0`` and by ``sup |e| 2 tau e^{2 tau |Re s|}``
    to the left), plus rounding of the evaluation (1e-14)."""
    plant = Hyperbolic2x2(*args)
    controller = CollocatedOutputFeedback(ReflectionController(0.1), observer_reflection=kappa)
    assert loop_route(plant, controller) == "exact"
    A, B = nr.loop_factors(plant, controller)
    pde = CollocatedPDE(args, 0.1, kappa)
    for s in POINTS:
        truth = pde.factors(s)
        for F, exact in zip((A, B), truth, strict=True):
            weight = 2.0 * plant.tau * max(1.0, float(mp.exp(2 * plant.tau * max(0.0, -s.real))))
            radius = sum(d.radius for d in F.distributed) * weight + sum(
                max(r, default=0.0) for r in (F.point_radii or [])
            )
            assert abs(complex(F(s)) - complex(exact)) <= radius + 1e-14


@pytest.mark.parametrize(("args", "K", "kappa"), [(PAPER, 0.1, 0.0), (PAPER, 0.1, -0.3), (SECOND, 0.8, 0.0)])
def test_the_proven_margin_holds_the_pdes(args, K, kappa):
    """The rigorous margin's ball contains the PDE's (oracle, 40 digits): the paper's plant under the collocated
    U_BS2(0.1) (0.16890143103111756993, ball measured [0.16890143103028402, 0.16890143103195202]; with the
    observer's reflection ``kappa = -0.3`` 0.18222485623151012821, the kernel route's ball missed it by 1.3e-9) and
    ``(1, 2, 0.4, 0.5, 1, 0.3)`` under U_BS2(0.8) (8.99436528018..., measured; U_BS2(0.1) and (0.3) have no
    crossing there); the scope says the PDE itself."""
    plant = Hyperbolic2x2(*args)
    controller = CollocatedOutputFeedback(ReflectionController(K), observer_reflection=kappa)
    proven = nr.delay_margin(plant, controller, rigorous=True)
    _, truth = CollocatedPDE(args, K, kappa).crossing(proven.omega)
    lo, hi = proven.margin_ball
    with mp.workdps(DPS):
        if args == PAPER and kappa == 0.0:
            assert abs(truth - mp.mpf(PAPER_MARGIN)) < 1e-19
        assert mp.mpf(lo) <= truth <= mp.mpf(hi)
    assert not proven.of_model
    assert proven.scope.startswith("the PDE itself")


def test_u_bs_and_a_model_with_an_observer_delay():
    """U_BS (``FiniteTimeController``) takes the proven loop too, and so does a plant whose ``1/mu`` is not a double
    (``mu = 1.5``; it kept the kernel route's model before the ends of ``c``'s pieces were placed on doubles with
    the ulps around them held by proven terms); an observer delay keeps the kernel route's model, said so by its
    route and scope."""
    plant = Hyperbolic2x2(*PAPER)
    assert loop_route(plant, CollocatedOutputFeedback(FiniteTimeController())) == "exact"
    other = Hyperbolic2x2(1.0, 1.5, 0.8, 1.0, 1.0, 0.6)
    assert loop_route(other, CollocatedOutputFeedback(ReflectionController(0.1))) == "exact"
    controller = CollocatedOutputFeedback(ReflectionController(0.1), observer_delay=0.2)
    assert loop_route(other, controller) == "observer"
    assert loop_scope(other, controller, None, nr.loop_factors(other, controller)).startswith("a model of the PDE")


#: Plants whose ends ``1/lam``, ``1/mu`` and ``tau`` are not all doubles (``tau`` neither), with the PDE's margin
#: under the collocated U_BS2(0.1) (oracle, measured) and the proven ball (measured).
OFF_THE_DOUBLES = (
    # 0.4984519912862440..., ball [0.49845199128597434, 0.4984519912865134]; the kernel route's model had
    # [0.49845199847310367, 0.49845199847377036], 7.2e-9 away
    (1.0, 3.0, 1.0, 1.0, 1.0, 0.85),
    # 0.965748634102588..., ball [0.9657486341024308, 0.9657486341027454]
    (1.1, 0.7, 0.8, 0.6, 0.9, 0.5),
)


@pytest.mark.parametrize(
    ("args", "kappa"), [(OFF_THE_DOUBLES[0], 0.0), (OFF_THE_DOUBLES[1], 0.0), (OFF_THE_DOUBLES[0], -0.3)]
)
def test_the_proven_margin_holds_the_pdes_where_the_ends_are_not_doubles(args, kappa):
    """The rigorous margin's ball contains the PDE's (oracle, 40 digits) and the scope says the PDE itself, mapped
    to the exact ``tau`` (before: "a model of the PDE", ``G`` from kernels on 201 points, and on ``(1, 3, 1, 1, 1,
    0.85)`` a ball 7.2e-9 from the PDE's margin); with the observer's reflection ``kappa = -0.3`` the PDE's
    0.581547317037402 in the ball ``[0.5815473170371488, 0.581547317037656]`` (measured)."""
    plant = Hyperbolic2x2(*args)
    controller = CollocatedOutputFeedback(ReflectionController(0.1), observer_reflection=kappa)
    assert loop_route(plant, controller) == "exact"
    proven = nr.delay_margin(plant, controller, rigorous=True)
    _, truth = CollocatedPDE(args, 0.1, kappa).crossing(proven.omega)
    lo, hi = proven.margin_ball
    with mp.workdps(DPS):
        assert mp.mpf(lo) <= truth <= mp.mpf(hi)
    assert not proven.of_model
    assert proven.scope.startswith("the PDE itself")
    assert "tau mapped to its exact value" in proven.scope


@pytest.mark.parametrize("args", OFF_THE_DOUBLES)
@pytest.mark.parametrize("delta", [0.0, 0.3])
def test_the_plants_balls_hold_the_pdes_loop_where_the_ends_are_not_doubles(args, delta):
    """``given_plant_balls`` (the loop as built at ``r s``, ``r = tau / tau_d`` a ball) contains the PDE's
    ``A_o + B_o e^{-delta s}`` (oracle, 40 digits) at four points, to the left of the axis too (radii measured
    4e-16 to 4e-12)."""
    from nrobust._flint import working_precision

    plant = Hyperbolic2x2(*args)
    controller = CollocatedOutputFeedback(ReflectionController(0.1))
    balls = given_plant_balls(plant, controller, delta)
    assert isinstance(balls, GivenPlantBalls)
    pde = CollocatedPDE(args, 0.1)
    for s in (*POINTS, -1.0 + 30.0j):
        A, B = pde.factors(mp.mpc(s))
        with mp.workdps(DPS):
            truth = A + B * mp.exp(-delta * mp.mpc(s))
        value = balls(s, 0)
        with working_precision(200) as flint:
            assert value.contains(flint.acb(truth)), (s, value, truth)


def test_the_nodes_stand_for_the_ends_within_an_ulp():
    """``G``'s kernel on ``(1, 3, 1, 1, 1, 0.85)``: ``t_v / r = 3 tau_d / 4`` and the ends plus ``tau`` are not
    doubles; each is held by a term on one ``ulp(2 tau_d)`` next to the node standing for it, zero within a proven
    radius, whose ends bracket the true end (exact rationals)."""
    plant = Hyperbolic2x2(1.0, 3.0, 1.0, 1.0, 1.0, 0.85)
    kernel, *moved = proven_response_product(plant, 0.1).distributed
    tau = Fraction(plant.tau)
    ends = {3 * tau / 4, tau + tau / 4, tau + 3 * tau / 4}
    assert len(moved) == len(ends)
    unit = math.ulp(2.0 * plant.tau)
    for term in moved:
        lo, hi = (Fraction(x) for x in term.nodes)
        assert hi - lo == Fraction(unit) and not term.pieces[2].any()
        assert sum(lo < end < hi for end in ends) == 1
        assert 0.0 < term.radius < 1e-14
    assert all(Fraction(x) not in ends for x in kernel.nodes)


def test_the_design_of_the_observer_is_certified_of_the_pde():
    """``design_collocated_observer`` on ``(1, 3, 1, 1, 1, 0.85)`` under U_BS2(0.1): its certificate is about the PDE
    (before: ``of_model`` True, a model); its margin is the PDE's at the designed ``kappa`` within the certificate's
    accuracy (oracle; the design is proven for the loop as built, ``tau`` a relative 5.6e-17 from the exact, which
    moves the margin by about 3e-17, far below that accuracy, measured 6.7e-13)."""
    args = (1.0, 3.0, 1.0, 1.0, 1.0, 0.85)
    result = nr.design_collocated_observer(Hyperbolic2x2(*args), "margin", controller=ReflectionController(0.1))
    certificate = result.design.certificate
    assert not certificate.of_model and certificate.scope.startswith("the PDE itself")
    _, truth = CollocatedPDE(args, 0.1, result.design.K).crossing(certificate.omega)
    with mp.workdps(DPS):
        assert abs(mp.mpf(result.design.margin) - truth) <= certificate.accuracy


def test_certify_end_to_end_on_the_pde():
    """``certify(..., rigorous=True)`` of the paper's plant under the collocated U_BS2(0.1) proves the margin whose
    ball holds the PDE's, its scope the PDE itself."""
    plant = Hyperbolic2x2(*PAPER)
    certificate = nr.certify(plant, CollocatedOutputFeedback(ReflectionController(0.1)), delta_max=0.1, rigorous=True)
    assert "the PDE itself" in certificate.scope
    lo, hi = certificate.margin.margin_ball
    with mp.workdps(DPS):
        assert mp.mpf(lo) <= mp.mpf(PAPER_MARGIN) <= mp.mpf(hi)


@pytest.mark.parametrize(("p_degree", "q_degree", "alpha"), [(3, 9, -1), (9, 3, -1), (4, 12, 1), (5, 11, 0.5)])
def test_polynomial_integral_holds_the_quadrature(p_degree, q_degree, alpha):
    """``int_{lo(u)}^{hi(u)} P(xi) Q(alpha xi + w(u)) dxi`` for polynomials with random coefficients and linear
    ``lo, hi, w``, against mpmath's Gauss-Legendre quadrature at 40 digits at three ``u`` (exact for polynomials;
    its error is rounding: 1e-35 allowed). Both expansions are exercised: in ``Q`` (of the lower degree) and in ``P``
    after ``eta = alpha xi + w`` (``Q`` of the higher degree, ``alpha = -1, 1, 0.5``). The balls must hold the
    quadrature and be narrower than ``1e-60``."""
    import random

    from nrobust.hyperbolic.loops.collocated_proof import polynomial_integral

    rng = random.Random(p_degree * 100 + q_degree)
    p = [rng.uniform(-1, 1) for _ in range(p_degree + 1)]
    q = [rng.uniform(-1, 1) for _ in range(q_degree + 1)]
    lo, hi, w = (rng.uniform(-1, 1), rng.uniform(-1, 1)), (rng.uniform(-1, 1), rng.uniform(-1, 1)), (0.3, -0.7)
    poly = flint.arb_poly
    value = polynomial_integral(
        flint, poly(p), poly(q), flint.arb(alpha), poly(list(w)), poly(list(lo)), poly(list(hi))
    )
    with mp.workdps(DPS):
        for u in (mp.mpf(-0.5), mp.mpf(0), mp.mpf("0.75")):

            def f(x, u=u):
                z = alpha * x + w[0] + w[1] * u
                return sum(c * x**k for k, c in enumerate(p)) * sum(c * z**k for k, c in enumerate(q))

            expected = mp.quad(f, [lo[0] + lo[1] * u, hi[0] + hi[1] * u])
            ball = value(flint.arb(str(u)))
            assert ball.rad() < 1e-60
            assert abs(_mid(ball) - expected) <= mp.mpf(ball.rad().str(5, radius=False)) + mp.mpf(10) ** -35
