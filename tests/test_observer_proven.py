"""The output feedback's observer term proven on coupled plants with constant couplings: proofs about the PDE.

``OutputFeedback(law)`` measures ``y = v(t, 0)`` and predicts the state over the window ``w = 1/mu``; its loop is
``A - G``, ``B + G`` (no observer delay) with ``G = (1 - Phi) H``, ``H(s) = int_0^w h(nu) e^{-nu s} dnu`` and
``h + N~ * h = m`` on ``[0, w]`` (``m = N~`` for U_BS2(K) and U_BS). The loop's ``G`` now carries a proven error
bound, so the proven delay margin, abscissa and certificate hold for the PDE, and the scope says so.

Oracle, sharing no code with the package, at 40 digits:

* ``1 - Phi = e^{-s/mu} (v(1) - rho u(1))`` from ``[u; v](1) = expm(M(s)) [q; 1]``,
  ``M(s) = [[-s/lam, sigma_pm/lam], [-sigma_mp/mu, s/mu]]`` (the Laplace-domain solution of the PDE; for a
  general plant ``e^{-(s - d) L/mu} (v(L) - rho u(L))`` with ``M = [[(a - s)/lam, b/lam], [-c/mu, (s - d)/mu]]``);
* ``N~`` from its series (``W``, ``h_11``, ``h_22`` summed term by term, times ``e^{sigma nu}`` on a general
  plant), checked in the test against the PDE: ``int_0^tau N~(nu) e^{-nu s} dnu = (1 - Phi) - 1 +
  rho q e^{sigma tau} e^{-tau s}`` by ``mpmath.quad`` at two points;
* ``h`` by Chebyshev collocation of the Volterra equation (36 first-kind points, the integrals by a 40-point
  Gauss-Legendre rule whose nodes are refined by Newton's method at 40 digits), a method unlike the
  package's (a Taylor polynomial from a triangular recursion); ``h`` is entire, so the collocation converges
  geometrically: doubling the points changes ``H`` by less than 1e-30 (checked below);
* crossings ``|A_o(i w)| = |B_o(i w)|`` by ``mpmath.findroot``.

Before the change the observer term was floating point with an estimated error and the scope said "a model of
the PDE": the scope tests fail there; the balls held the PDE's values already (the float term was within 3e-15
of the proven one, the balls 1e-12 to 1e-11 wide), so the containment tests pass on both.
"""

from __future__ import annotations

import functools

import mpmath as mp
import numpy as np
import pytest
from _oracles import assert_balls_contain, barycentric, gauss_legendre, window_collocation

import nrobust as nr
from nrobust.balls import ball_function
from nrobust.hyperbolic import FiniteTimeController, Hyperbolic2x2, ReflectionController, StateFeedback
from nrobust.hyperbolic.loops.controllers import loop_route, loop_scope, observer_of
from nrobust.hyperbolic.loops.observer_proof import proven_observer_failure, proven_observer_term
from nrobust.hyperbolic.loops.output_feedback import observer_term
from nrobust.hyperbolic.plants.general import GeneralHyperbolic2x2
from nrobust.reports.certificate import PROVEN

pytest.importorskip("flint")

DPS = 40
PAPER = (1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
SECOND = (1.0, 2.0, 0.4, 0.5, 1.0, 0.3)
#: Strong couplings ``kappa = p m = -25``, ``-36``: Gronwall's ``e^{K w}`` (1e12, 1e20) made the proof fail at ``-36``;
#: the resolvent's bound (module notes of ``observer_proof``) proves both.
STRONG25 = (1.0, 1.0, 5.0, 5.0, 0.5, 0.5)
STRONG36 = (1.0, 1.0, 6.0, 6.0, 0.5, 0.5)
#: A general plant with constant coefficients (lam, mu, a, b, c, d, q, rho, L): its weight e^{sigma nu} is not 1.
GENERAL = ("general", 0.3, 0.7, 0.1, 0.2, 0.3, -0.2, 0.6, 0.7, 1.3)


def _plant(args):
    """The plant of ``args`` (:func:`_coefficients`)."""
    if args[0] == "general":
        lam, mu, a, b, c, d, q, rho, L = args[1:]
        return GeneralHyperbolic2x2(lam=lam, mu=mu, a=a, b=b, c=c, d=d, q=q, rho=rho, length=L)
    return Hyperbolic2x2(*args)


def _coefficients(args):
    """``(lam, mu, a, b, c, d, q, rho, L)`` of the paper's plant ``args = (lam, mu, sigma_pm, sigma_mp, q, rho)``
    (``a = d = 0``, ``L = 1``) or of a general plant ``args = ("general", lam, mu, a, b, c, d, q, rho, L)``."""
    if args[0] == "general":
        return tuple(mp.mpf(v) for v in args[1:])  # exact: doubles
    lam, mu, spm, smp, q, rho = (mp.mpf(v) for v in args)
    return lam, mu, mp.mpf(0), spm, smp, mp.mpf(0), q, rho, mp.mpf(1)


def _params(args):
    """``(tau, w, p, m, sigma, q, rho)``: the round trip, the window ``L/mu``, ``p = b L/lam``, ``m = -c L/mu``, the
    weight ``sigma = (a L/lam + d L/mu)/tau`` of ``N~ = e^{sigma nu} N~_0`` (module notes of ``exact_form``)."""
    lam, mu, a, b, c, d, q, rho, L = _coefficients(args)
    with mp.workdps(DPS + 10):
        tau = L / lam + L / mu
        return tau, L / mu, b * L / lam, -c * L / mu, (a * L / lam + d * L / mu) / tau, q, rho


def _open_loop(args, s):
    """``1 - Phi(s)`` from the PDE's Laplace-domain solution: ``e^{-(s - d) L/mu} (v(L) - rho u(L))``,
    ``[u; v](L) = expm(L M(s)) [q; 1]``, ``M = [[(a - s)/lam, b/lam], [-c/mu, (s - d)/mu]]``."""
    lam, mu, a, b, c, d, q, rho, L = _coefficients(args)
    E = mp.expm(L * mp.matrix([[(a - s) / lam, b / lam], [-c / mu, (s - d) / mu]]))
    u, v = E[0, 0] * q + E[0, 1], E[1, 0] * q + E[1, 1]
    return mp.exp(-(s - d) * L / mu) * (v - rho * u)


def _kernel(args):
    """``N~(nu)`` on ``[0, tau]``: ``e^{sigma nu}`` times its series ``h_22 - rho q h_11 + (m q - rho p) W / tau``."""
    tau, _, p, m, sigma, q, rho = _params(args)
    with mp.workdps(DPS + 10):
        a = p * m / tau**2

    def N(nu):
        x = a * nu * (tau - nu)
        W = I1 = mp.mpf(0)
        term, k = mp.mpf(1), 0
        while True:  # term = x^k / (k!)^2
            W += term
            I1 += term / (k + 1)  # x^k / (k! (k + 1)!)
            k += 1
            term *= x / (k * k)
            if abs(term) < mp.mpf(10) ** (-DPS - 10) and k > 3:
                break
        h22, h11 = a * (tau - nu) * I1, a * nu * I1
        return mp.exp(sigma * nu) * (h22 - rho * q * h11 + (m * q - rho * p) / tau * W)

    return N


@functools.cache
def _window_kernel(args, n=36):
    """``h`` at ``n`` Chebyshev points of ``[0, w]`` and the barycentric weights: ``(I + M) h = N~`` (collocation)."""
    N = _kernel(args)
    return window_collocation(N, N, _params(args)[1], n, DPS)


def _h(args, y, n=36):
    x, bary, h = _window_kernel(args, n)
    return mp.fdot(barycentric(x, bary, y), h)


def _H(args, s, n=36):
    """``int_0^w h(nu) e^{-nu s} dnu`` (Gauss-Legendre, 40 points; ``h`` a polynomial of degree ``n - 1``)."""
    w = _params(args)[1]
    gx, gw = gauss_legendre(40, DPS)
    return w * mp.fsum(wt * _h(args, w * y, n) * mp.exp(-w * y * s) for y, wt in zip(gx, gw))


def _H_pieces(args, s, pieces):
    """:func:`_H` with the 40-point rule on each of ``pieces`` equal parts of the window (``e^{-nu s}`` resolved at
    high frequency)."""
    w = _params(args)[1]
    gx, gw = gauss_legendre(40, DPS)
    step = w / pieces
    return step * mp.fsum(
        wt * _h(args, step * (k + y)) * mp.exp(-step * (k + y) * s) for k in range(pieces) for y, wt in zip(gx, gw)
    )


def _factors(args, law, s, H=_H):
    """``(A_o, B_o) = (A - G, B + G)``, ``G = (1 - Phi) H``, ``B = K q e^{sigma tau/2} e^{-tau s} - I_N`` with
    ``I_N = (1 - Phi) - 1 + rho q e^{sigma tau} e^{-tau s}`` (U_BS: ``rho q e^{sigma tau}`` for the first gain)."""
    tau, _, _, _, sigma, q, rho = _params(args)
    A = _open_loop(args, s)
    principal = rho * q * mp.exp(sigma * tau)
    gain = principal if isinstance(law, FiniteTimeController) else mp.mpf(law.K) * q * mp.exp(sigma * tau / 2)
    B = (gain - principal) * mp.exp(-tau * s) + 1 - A
    G = A * H(args, s)
    return A - G, B + G


def _pde_margin(args, law, w0, H=_H):
    """``(w, delta*)``: the crossing near ``w0`` and its first delay, at 40 digits (``H`` the window's transform)."""
    with mp.workdps(DPS):

        def g(w):
            A, B = _factors(args, law, mp.mpc(0, w), H)
            return abs(A) ** 2 - abs(B) ** 2

        w = mp.findroot(g, mp.mpf(w0))
        A, B = _factors(args, law, mp.mpc(0, w), H)
        return w, (-mp.arg(-A / B)) % (2 * mp.pi) / w


# ------------------------------------------------------------------------------------------- the oracle itself
@pytest.mark.long  # 15 s: the oracle's own convergence, at 40 digits
def test_the_oracles_kernel_is_the_pdes_and_its_collocation_has_converged():
    """``N~``'s series is the PDE's (its transform is ``(1 - Phi) - 1 + rho q e^{-tau s}``), and the collocation
    of ``h`` with 36 points agrees with 48 to 1e-30 in ``H`` (on the strong couplings ``H`` is about 1e3 and the
    difference 1e-33; 48 and 60 points differ by 1e-38)."""
    for args in (PAPER, SECOND, GENERAL, STRONG25, STRONG36):
        tau, _, _, _, sigma, q, rho = _params(args)
        N = _kernel(args)
        with mp.workdps(DPS):
            principal = rho * q * mp.exp(sigma * tau)
            for s in (mp.mpc(0.7, 1.3), mp.mpc(-0.2, 4.0)):
                transform = mp.quad(lambda nu, s=s, N=N: N(nu) * mp.exp(-nu * s), [0, tau / 2, tau])
                assert abs(transform - (_open_loop(args, s) - 1 + principal * mp.exp(-tau * s))) < mp.mpf(10) ** -30
                assert abs(_H(args, s) - _H(args, s, 48)) < mp.mpf(10) ** -30


# ----------------------------------------------------------------------------------------- the enclosure of G
@pytest.mark.parametrize(("args", "bound"), [(PAPER, 1e-15), (SECOND, 1e-15), (STRONG25, 1e-12), (STRONG36, 5e-12)])
def test_the_stored_observer_term_is_within_its_proven_radius_of_the_pdes(args, bound):
    """At points of each interval the stored kernel of ``G`` is within its term's ``radius`` of the oracle's
    ``g = h 1_[0, w] - rho q h(. - tau) + N~ * h`` (by ``mpmath.quad``), and the radius is at most ``bound``: 1e-15 on
    the paper's plants; on the strong couplings the kernel is about 1e3 and 1e4 and its double-precision pieces
    carry 2^-50 of that (measured radii 2.9e-13 and 1.2e-12)."""
    law = ReflectionController(0.1)
    G = observer_of(Hyperbolic2x2(*args), nr.OutputFeedback(law))
    assert G.accuracy <= bound
    lam, mu, _, _, q, rho = (mp.mpf(v) for v in args)
    with mp.workdps(DPS):
        tau, w = 1 / lam + 1 / mu, 1 / mu
    N = _kernel(args)

    def g(nu):
        lo, hi = max(mp.mpf(0), nu - tau), min(w, nu)
        conv = mp.quad(lambda x: N(nu - x) * _h(args, x), [lo, hi]) if hi > lo else 0
        own = _h(args, nu) if nu <= w else 0
        late = -rho * q * _h(args, nu - tau) if nu >= tau else 0
        return own + late + conv

    with mp.workdps(DPS):
        for term in G.product.distributed[:3]:
            for t in (0.03, 0.41, 0.97):
                nu = term.a + t * (term.b - term.a)
                start, h, coefs = term.pieces
                i = int(np.searchsorted(start, nu, side="right") - 1)
                t_local = mp.mpf(nu - start[i]) / mp.mpf(h[i])  # the piece in exact arithmetic: no rounding here
                stored = mp.fsum(mp.mpf(c) * t_local**k for k, c in enumerate(coefs[i]))
                assert abs(stored - g(mp.mpf(nu))) <= term.radius


@pytest.mark.parametrize(
    ("args", "law"),
    [(PAPER, ReflectionController(0.1)), (STRONG36, ReflectionController(0.1)), (STRONG36, FiniteTimeController())],
)
def test_the_loops_balls_enclose_the_pdes_loop(args, law):
    """The ball enclosure of the loop ``A_o + B_o e^{-delta s}`` (the one every proof evaluates) holds the PDE's loop
    and its first derivative at 40 digits, at ``delta = 0.3`` (where ``G`` does not cancel); on ``kappa = -36`` too,
    where the loop was a model with a floating-point ``G`` (its error 1e-8, no part of the balls)."""
    delta = 0.3
    plant, controller = Hyperbolic2x2(*args), nr.OutputFeedback(law)
    assert loop_route(plant, controller) == "exact"
    balls = ball_function(nr.characteristic(plant, controller, delta), 53)  # tau = 2 exact: the loop as built

    def F(s):
        A, B = _factors(args, law, s)
        return A + B * mp.exp(-mp.mpf(delta) * s)

    assert_balls_contain(balls, F, (complex(-0.5, 6.3), complex(0.3, -17.0), complex(-2.0, 90.0)), (0, 1), DPS)


@pytest.mark.parametrize(
    "args",
    [
        (0.1, 0.1, 0.05, 0.05, 1.0, 0.5),
        (10.0, 10.0, 5.0, 5.0, 0.5, 0.5),
        (5.0, 0.2, 1.0, -2.0, 1.0, 0.3),
        (1.0, 1.0, -1.0, 3.0, 0.7, -0.6),
        (1.0, 1.0, 4.0, 4.0, 0.5, 0.5),
    ],
)
def test_the_proven_term_agrees_with_the_floating_point_route(args):
    """Against the floating-point route (collocation of the resolvent, quadrature, a fit: another method), on plants
    with windows from 0.5 to 10 and ``kappa`` from -3 to 16: the transforms of ``G`` differ by at most the sum of the
    two accuracies times the support's length (measured: 1e-16 to 5e-13 against bounds 1e-14 to 2e-10)."""
    plant = Hyperbolic2x2(*args)
    open_loop = nr.loop_factors(plant, nr.OpenLoop())[0]
    s = np.r_[0.0, 1j * np.geomspace(1e-2, 300.0, 200), 0.5 + 7j]
    length = plant.tau + 1.0 / plant.mu
    for law in (ReflectionController(0.1), StateFeedback(-0.4)):
        proven = observer_of(plant, nr.OutputFeedback(law))
        floating = observer_term(open_loop, nr.loop_factors(plant, law)[1], 1.0 / plant.mu)
        assert proven.accuracy <= 1e-12
        difference = np.max(np.abs(proven.product(s) - floating.product(s)))
        assert difference <= (proven.accuracy + floating.accuracy) * length


# --------------------------------------------------------------------------------------------- the loop's claims
@pytest.mark.parametrize(
    ("args", "law"),
    [
        (PAPER, ReflectionController(0.1)),
        (SECOND, ReflectionController(0.1)),
        (SECOND, FiniteTimeController()),
        (GENERAL, ReflectionController(0.1)),
    ],
)
def test_the_proven_margin_of_an_output_feedback_holds_for_the_pde(args, law):
    """The proven delay-margin ball holds the PDE's margin (40 digits), the crossing frequency agrees to 1e-12, and
    the scope says the proofs are about the PDE itself (a general plant with constant coefficients too)."""
    plant, controller = _plant(args), nr.OutputFeedback(law)
    assert loop_route(plant, controller) == "exact"
    margin = nr.delay_margin(plant, controller, rigorous=True)
    assert margin.rigorous and 0 < margin.margin < np.inf
    w, truth = _pde_margin(args, law, margin.omega)
    lo, hi = margin.margin_ball
    assert mp.mpf(lo) <= truth <= mp.mpf(hi)
    np.testing.assert_allclose(margin.omega, float(w), rtol=1e-12)
    assert margin.scope.startswith("the PDE itself") and "observer's term (1 - Phi) H enclosed" in margin.scope
    assert not margin.of_model and "model" not in margin.scope


def test_the_certificate_of_an_output_feedback_holds_for_the_pde():
    """``certify(plant, OutputFeedback(U_BS2(0.1)), rigorous=True)`` on the paper's plant: the claims proven, the
    scope the PDE's, the margin ball holds the PDE's margin, and the abscissa bracket the closed form
    ``ln((rho - K) q) / tau`` of the target system (the loop at ``delta = 0``, where ``G`` cancels)."""
    plant, controller = Hyperbolic2x2(*PAPER), nr.OutputFeedback(ReflectionController(0.1))
    cert = nr.certify(plant, controller, delta_max=0.1, rigorous=True, k_region=False)
    claims = {c.name: c.status for c in cert.claims}
    assert claims["delay margin"] == PROVEN and claims["spectral abscissa"] == PROVEN
    assert "the PDE itself" in cert.scope and "a model of the PDE" not in cert.scope
    _, truth = _pde_margin(PAPER, controller.controller, cert.margin.omega)
    assert mp.mpf(cert.margin.margin_ball[0]) <= truth <= mp.mpf(cert.margin.margin_ball[1])
    with mp.workdps(DPS):
        chain = mp.log((mp.mpf(0.85) - mp.mpf(0.1)) * 1) / 2
    lo, hi = cert.abscissa.value_bracket
    assert mp.mpf(lo) <= chain <= mp.mpf(hi)


def test_a_plant_whose_end_of_support_is_not_a_double_keeps_the_term_past_it():
    """``tau + 1/mu`` not a double (``lam, mu = 1, 3``): the last interval ends at the double below it and a term on
    the next ulp holds the rest of ``g``; the margin ball still holds the PDE's, the scope names the rounded
    ``tau`` and window."""
    args, law = (1.0, 3.0, 1.0, 1.0, 1.0, 0.85), ReflectionController(0.1)
    plant, controller = Hyperbolic2x2(*args), nr.OutputFeedback(law)
    terms = observer_of(plant, controller).product.distributed
    assert len(terms) == 4 and terms[3].b - terms[3].a == np.spacing(terms[3].a)
    margin = nr.delay_margin(plant, controller, rigorous=True)
    _, truth = _pde_margin(args, law, margin.omega)
    assert mp.mpf(margin.margin_ball[0]) <= truth <= mp.mpf(margin.margin_ball[1])
    assert margin.scope.startswith("the PDE itself") and "the window 1/mu as the double" in margin.scope


def test_a_state_feedback_and_strong_couplings():
    """A state feedback ``U = k u(t, 1)`` reads ``k U~`` on the window: proven too. Couplings ``kappa = -25``, ``-36``
    are proven under U_BS2(0.1) and U_BS (the scope the PDE's); ``kappa = -625``, where ``h`` reaches 7e18 on the
    window, is refused and the reason names what would help (more terms of ``N~``'s series), and a coupling beyond
    the closed form's work bound ``|kappa| <= 2500`` is refused before the work, saying so."""
    plant = Hyperbolic2x2(*SECOND)
    assert loop_route(plant, nr.OutputFeedback(StateFeedback(-0.3))) == "exact"
    for args in (STRONG25, STRONG36):
        strong = Hyperbolic2x2(*args)
        assert proven_observer_failure(strong, ("N", 1.0)) is None
        assert proven_observer_failure(strong, ("U", -0.3)) is None
        for law in (ReflectionController(0.1), FiniteTimeController()):
            controller = nr.OutputFeedback(law)
            assert loop_route(strong, controller) == "exact"
            scope = loop_scope(strong, controller, None, nr.loop_factors(strong, controller))
            assert scope.startswith("the PDE itself") and "observer's term (1 - Phi) H enclosed" in scope
    too_strong = Hyperbolic2x2(1.0, 1.0, 25.0, 25.0, 0.5, 0.5)
    reason = proven_observer_failure(too_strong, ("N", 1.0))
    assert "coupling too strong" in reason and "more terms of N~'s series would help" in reason
    assert loop_route(too_strong, nr.OutputFeedback(ReflectionController(0.1))) == "observer"
    beyond = Hyperbolic2x2(1.0, 1.0, 51.0, 51.0, 0.5, 0.5)
    assert "beyond the closed form's work bound 2500" in proven_observer_failure(beyond, ("N", 1.0))
    with pytest.raises(nr.ParameterError, match=r"system must be .*\|kappa\| = \|p m\| <= 2500 .*weaker coupling"):
        proven_observer_term(beyond, ("N", 1.0))


@pytest.mark.long
@pytest.mark.timeout(1200)  # about 120 s of CPU (a loaded machine triples it): make fuzz runs it, not make test
def test_the_proven_margin_of_a_strong_coupling_holds_for_the_pde():
    """``kappa = -25`` (``(1, 1, 5, 5, 0.5, 0.5)``, U_BS2(0.1)): the proven delay-margin ball (about 2e-11 wide) holds
    the PDE's margin at 40 digits, the crossing frequency agrees to 1e-11 (1886 crossings below it: minutes of CPU)."""
    law = ReflectionController(0.1)
    plant, controller = Hyperbolic2x2(*STRONG25), nr.OutputFeedback(law)
    margin = nr.delay_margin(plant, controller, rigorous=True)
    w, truth = _pde_margin(STRONG25, law, margin.omega)
    lo, hi = margin.margin_ball
    assert mp.mpf(lo) <= truth <= mp.mpf(hi)
    np.testing.assert_allclose(margin.omega, float(w), rtol=1e-11)
    assert margin.scope.startswith("the PDE itself")


@pytest.mark.long
@pytest.mark.timeout(2400)  # about 300 s of CPU (a loaded machine triples it): make fuzz runs it, not make test
def test_the_proven_margin_of_kappa_36_holds_for_the_pde():
    """``kappa = -36`` (``(1, 1, 6, 6, 0.5, 0.5)``, U_BS2(0.1)): the proven delay-margin ball holds the PDE's margin at
    40 digits and the crossing frequency agrees to 1e-10. The search covers ``[0, W]``, ``W = 6.8e4`` (the kernels'
    jumps, about 1e4, against the principal gap 0.7); it refused at ``w = 0.7243`` (the balls of ``g'`` on a cluster,
    :func:`test_a_crossing_of_kappa_36_is_isolated_where_the_balls_of_g_prime_cancel`) and then ran out of memory
    enumerating the delays of its crossings up to the default range (``_default_range``). The oracle's window
    transform takes the 40-point rule on pieces of the window, checked against twice as many pieces at the crossing."""
    law = ReflectionController(0.1)
    plant, controller = Hyperbolic2x2(*STRONG36), nr.OutputFeedback(law)
    margin = nr.delay_margin(plant, controller, rigorous=True)
    pieces = max(2, int(margin.omega / 4) + 1)
    with mp.workdps(DPS):
        s = mp.mpc(0, margin.omega)
        assert abs(_H_pieces(STRONG36, s, pieces) - _H_pieces(STRONG36, s, 2 * pieces)) < mp.mpf(10) ** -30
    w, truth = _pde_margin(STRONG36, law, margin.omega, functools.partial(_H_pieces, pieces=pieces))
    lo, hi = margin.margin_ball
    assert mp.mpf(lo) <= truth <= mp.mpf(hi)
    np.testing.assert_allclose(margin.omega, float(w), rtol=1e-10)
    assert margin.scope.startswith("the PDE itself")


def test_a_crossing_of_kappa_36_is_isolated_where_the_balls_of_g_prime_cancel():
    """``kappa = -36`` under U_BS2(0.1): near ``w = 0.7243`` the ball of ``g' = -2 Im(conj(A) A') + 2 Im(conj(B) B')``
    on an interval loses the cancellation of its two terms (each about ``|A| |A'| = 1.7e7`` against
    ``g' = -1.1e4``): on ``[0.7242, 0.7244]`` it is ``+-5.6e4``, ``g''`` ``+-1e5``, and the search refused there
    ("cannot decide") once the bisection reached ``1e-9 W`` (``W = 6.8e4``). The centred form
    ``g'(c) + g''(I) (I - c)`` (``+-10`` there) proves one simple zero, decreasing, whose enclosure holds the PDE's
    crossing (40 digits, :func:`_pde_margin`'s equation)."""
    from nrobust.margins.proven import _Axis, _decide

    law = ReflectionController(0.1)
    A, B = nr.loop_factors(Hyperbolic2x2(*STRONG36), nr.OutputFeedback(law))
    axis = _Axis(A, B, 1000)
    zeros, unresolved = [], []
    work = [(0.7242, 0.7244, 0, 0)]
    for _ in range(40):  # the old bisection reached its floor in 2 rounds, then refused
        work = [part for cluster in work for part in _decide(axis, *cluster, 67787.0, zeros, unresolved)]
    assert not work and not unresolved and len(zeros) == 1
    ((w, slope),) = zeros
    with mp.workdps(DPS):

        def g(x):
            a, b = _factors(STRONG36, law, mp.mpc(0, x))
            return abs(a) ** 2 - abs(b) ** 2

        truth = mp.findroot(g, mp.mpf("0.7243"))
    assert slope == -1 and mp.mpf(w.lower()) <= truth <= mp.mpf(w.upper())
    assert w.rad() < 1e-9  # the balls of g (radius 5e-7 against g' = -1.1e4) fix w to 5e-11
    assert axis.evals < 100  # measured 26


def test_bad_input_is_refused_before_work():
    """``law`` must be ``("N" | "U", c)``, ``c`` finite, and the plant a ``Hyperbolic2x2`` with constant couplings."""
    plant = Hyperbolic2x2(*PAPER)
    for law in (("X", 1.0), ("N", float("nan")), ("N",), "N"):
        with pytest.raises(nr.ParameterError, match="law"):
            proven_observer_term(plant, law)
    with pytest.raises(nr.ParameterError, match="system"):
        proven_observer_term(Hyperbolic2x2(1.0, 1.0, lambda x: 1.0 + x, 1.0, 1.0, 0.85), ("N", 1.0))


def test_the_scope_says_what_is_rounded_and_where_the_accuracy_holds() -> None:
    """On ``(1, 3, ...)`` ``tau + w = 4/3`` is not a double: the printed accuracy of ``G`` holds but on the ulp past
    it (a term holding the kernel's value there, radius about 1.75); the window ``1/3`` is a rounded double, its
    relative distance to ``1/3`` (exact fractions: at most 2^-54 / (1/3)) printed as for ``tau``."""
    from fractions import Fraction

    plant = Hyperbolic2x2(1.0, 3.0, 1.0, 1.0, 1.0, 0.85)
    controller = nr.OutputFeedback(ReflectionController(0.1))
    term = observer_of(plant, controller)
    assert len(term.product.distributed) == 4 and term.product.distributed[3].radius > 1.0
    scope = loop_scope(plant, controller, None, nr.loop_factors(plant, controller))
    assert "but the ulp past its double" in scope
    gap = abs(Fraction(1.0 / 3.0) * 3 - 1)
    assert 0 < gap <= Fraction(1, 2**53)
    assert "the window 1/mu as the double 0.3333333333333333 (a relative 5.6e-17 from the exact window)" in scope
