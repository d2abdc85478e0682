"""The collocated observer under ``StateFeedback(k)`` proven on coupled plants with constant couplings.

The collocated observer measures ``y = u(t, 1)``; its error's output ``u~(t, 1)`` per unit command mismatch is
``H_y`` and the law applied to the error is ``C_u``. On a coupled plant the package took both from the dual
plant's kernels on a grid (a model). ``H_y`` is a closed form, the transfer of ``u(t, 1)`` of the delay form,
``H_y = e^{-s/mu} u(1)`` with ``[u; v](1) = expm(M(s)) [q; 1]`` (module notes of ``collocated``, "Closed
forms"), and for ``StateFeedback(k)`` ``C_u = k H_y``: the loop is then made of products of closed forms, now
enclosed in ball arithmetic, and the proofs hold for the PDE.

Oracle, sharing no code with the package, at 40 digits:

* ``H_y`` the closed form above, checked against the package's kernel route (the dual plant's kernels on a
  grid, a computation unlike the closed form): the kernel route converges to it at third order;
* the loop from the PDE's transfer functions: the plant's ``u(1) = P U_p``, ``P = u(1) / (v(1) - rho u(1))``
  from the ``2 x 2`` exponential, the law ``U_c = k (y - u~(1))``, ``u~(1) = H_y W / (1 - kappa H_y)``,
  ``W = (e^{-delta s} - e^{-delta_o s}) U_c``, ``U_p = e^{-delta s} U_c``: ``U_c F = 0`` with
  ``F = 1 - k P e^{-delta s} + k H_y (e^{-delta s} - e^{-delta_o s}) / (1 - kappa H_y)``, multiplied by
  ``(1 - Phi) (1 - kappa H_y)``, ``1 - Phi = e^{-s/mu} (v(1) - rho u(1))``;
* crossings ``|A_o(i w)| = |B_o(i w)|`` and roots by ``mpmath.findroot``.

Before the change the loop route was ``"observer"`` and the scope "a model of the PDE": the route, scope and
certificate tests fail there, and the margin ball of the second case (``kappa = 0.2``) excluded the PDE's margin
(the kernel route's ball was ``[2.09280339707999, 2.09280339708058]``, the PDE's margin 2.0928033966407...).
``DistributedDelay.plus`` of two polynomial terms of different degrees raised a ``ValueError`` (broadcast).
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest

import nrobust as nr
from nrobust.distributed_delay import DistributedDelay
from nrobust.errors import ParameterError
from nrobust.hyperbolic import Hyperbolic2x2, ReflectionController, StateFeedback
from nrobust.hyperbolic.analyses.observer_design import collocated_observer_loop
from nrobust.hyperbolic.loops.collocated import collocated_responses
from nrobust.hyperbolic.loops.controllers import loop_route, loop_scope, observer_reflection_of
from nrobust.hyperbolic.loops.observer_proof import proven_collocated_failure, proven_collocated_products
from nrobust.hyperbolic.plants.general import GeneralHyperbolic2x2
from nrobust.hyperbolic.plants.law import FeedbackLaw
from nrobust.reports.certificate import PROVEN

pytest.importorskip("flint")

DPS = 40
#: Plants whose static feedback ``StateFeedback(k)`` with the collocated observer has a finite delay margin.
FIRST = (1.0, 1.0, 0.7, 0.7, 1.0, 0.3)
SECOND = (1.0, 2.0, 1.0, 1.0, 1.0, 0.2)


def _ends(args, s):
    """``(u(1), v(1))`` of the PDE in the Laplace domain from ``[u; v](0) = [q; 1]``: ``expm(M(s)) [q; 1]``."""
    lam, mu, spm, smp, q, _ = (mp.mpf(v) for v in args)
    E = mp.expm(mp.matrix([[-s / lam, spm / lam], [-smp / mu, s / mu]]))
    return E[0, 0] * q + E[0, 1], E[1, 0] * q + E[1, 1]


def _open_loop_and_hy(args, s):
    """``1 - Phi = e^{-s/mu} (v(1) - rho u(1))`` and ``H_y = e^{-s/mu} u(1)``."""
    u, v = _ends(args, s)
    scale = mp.exp(-s / mp.mpf(args[1]))
    return scale * (v - mp.mpf(args[5]) * u), scale * u


def _factors(args, k, kappa, delta_o, s):
    """``(A_o, B_o)`` of the loop from the PDE's transfer functions (module docstring)."""
    A, H = _open_loop_and_hy(args, s)
    P = H / A  # u(1) per unit U_p
    E = 1 - kappa * H
    # (1 - Phi) E F = A E - k P A E e^{-delta s} + k A H (e^{-delta s} - e^{-delta_o s})
    return A * E - k * A * H * mp.exp(-delta_o * s), -k * P * A * E + k * A * H


def _pde_margin(args, k, kappa, omega0):
    """The PDE's first crossing ``(w, delta*)`` near ``omega0``: ``|A_o(i w)| = |B_o(i w)|``, then the delay."""
    with mp.workdps(DPS):

        def gap(w):
            A, B = _factors(args, k, kappa, 0, 1j * w)
            return abs(A) ** 2 - abs(B) ** 2

        w = mp.findroot(gap, mp.mpf(omega0))
        A, B = _factors(args, k, kappa, 0, 1j * w)
        phase = -mp.arg(-A / B)  # e^{-i w delta} = -A/B
        return w, (phase % (2 * mp.pi)) / w


@pytest.mark.parametrize("args", [FIRST, SECOND])
def test_the_kernel_route_converges_to_the_closed_form_of_h_y(args):
    """The output error per unit mismatch ``H_y`` from the dual plant's kernels on 51, 101, 201 points approaches
    the closed form ``e^{-s/mu} u(1)`` at third order: the error ratios 101 -> 201 measured 7.1 to 8.6 on these
    plants at these points (asserted in (5, 12)), 51 -> 101 measured 6.0 to 10.4 (asserted in (4, 16): the
    coarse grid is not yet asymptotic), and the error on 201 points is below 1e-8 (measured 1.5e-11 to 4.7e-10).
    A route sharing no code with the closed form: the identity ``H_y = u_factor`` the proofs rest on."""
    plant = Hyperbolic2x2(*args)
    unit = FeedbackLaw(1.0, lambda x: np.zeros_like(x), lambda x: np.zeros_like(x))
    for s in (0.3 + 0.7j, -0.5 + 4j):
        with mp.workdps(DPS):
            truth = complex(_open_loop_and_hy(args, mp.mpc(s))[1])
        errors = [abs(complex(collocated_responses(plant, unit, n)[1](s)) - truth) for n in (51, 101, 201)]
        assert errors[2] < 1e-8
        assert 4 < errors[0] / errors[1] < 16 and 5 < errors[1] / errors[2] < 12


@pytest.mark.parametrize("args", [FIRST, SECOND])
def test_the_proven_products_are_the_pde_products(args):
    """``(1 - Phi) u_factor`` and ``u_factor^2`` agree with the 40-digit products of the closed forms to 1e-14 (the
    proven radii are below 1e-15 on these plants; the floating-point evaluation of the stored pieces adds a few
    ulps of the kernel's size, which is below 10), and every stored term carries a proven radius below 1e-14."""
    products = proven_collocated_products(Hyperbolic2x2(*args))
    for term in products.open_loop_product.distributed + products.square.distributed:
        assert 0 < term.radius < 1e-14 and 0 < term.variation_radius < 1e-12
    for s in (0.3 + 0.7j, -0.5 + 4j, 1.2 + 10j):
        with mp.workdps(DPS):
            A, H = _open_loop_and_hy(args, mp.mpc(s))
            first, square = complex(A * H), complex(H * H)
        assert abs(complex(products.open_loop_product(s)) - first) < 1e-14
        assert abs(complex(products.square(s)) - square) < 1e-14


@pytest.mark.parametrize(("args", "k", "kappa"), [(FIRST, -0.3, 0.0), (SECOND, -0.6, 0.2)])
def test_the_proven_margin_of_a_collocated_static_feedback_holds_for_the_pde(args, k, kappa):
    """The proven delay-margin ball holds the PDE's margin (40 digits), the crossing frequency agrees to 1e-10, and
    the scope says the proofs are about the PDE itself."""
    plant = Hyperbolic2x2(*args)
    controller = nr.CollocatedOutputFeedback(StateFeedback(k), observer_reflection=kappa)
    assert loop_route(plant, controller) == "exact"
    margin = nr.delay_margin(plant, controller, rigorous=True)
    assert margin.rigorous and 0 < margin.margin < np.inf
    w, truth = _pde_margin(args, k, kappa, margin.omega)
    lo, hi = margin.margin_ball
    assert mp.mpf(lo) <= truth <= mp.mpf(hi)
    np.testing.assert_allclose(margin.omega, float(w), rtol=1e-10)
    assert margin.scope.startswith("the PDE itself") and "C_u = k u_factor" in margin.scope
    assert ("H_y = u_factor" in margin.scope) == bool(kappa)
    assert "model" not in margin.scope


def test_the_certificate_of_a_collocated_static_feedback_holds_for_the_pde():
    """``certify(..., rigorous=True)`` end to end: margin and abscissa proven, the scope the PDE's, the margin ball
    holds the PDE's margin and the abscissa bracket the PDE's rightmost root at ``delta = 0`` (40 digits, from
    the certificate's root)."""
    plant, k = Hyperbolic2x2(*FIRST), -0.3
    controller = nr.CollocatedOutputFeedback(StateFeedback(k))
    cert = nr.certify(plant, controller, delta_max=3.0, rigorous=True, k_region=False)
    claims = {c.name: c.status for c in cert.claims}
    assert claims["delay margin"] == PROVEN and claims["spectral abscissa"] == PROVEN
    assert "the PDE itself" in cert.scope and "a model of the PDE" not in cert.scope
    _, truth = _pde_margin(FIRST, k, 0.0, cert.margin.omega)
    assert mp.mpf(cert.margin.margin_ball[0]) <= truth <= mp.mpf(cert.margin.margin_ball[1])
    with mp.workdps(DPS):
        root = mp.findroot(lambda s: sum(_factors(FIRST, k, 0.0, 0.0, s)), mp.mpc(cert.abscissa.root))
    lo, hi = cert.abscissa.value_bracket
    assert mp.mpf(lo) <= mp.re(root) <= mp.mpf(hi)


def test_an_observer_delay_keeps_the_proof():
    """With ``observer_delay > 0`` the loop is still proven (``tau`` a double: nothing rounded); the difference
    operator ``1 + |k q| ...`` is not strongly stable here, so the margin is 0, and the scope says the PDE."""
    plant = Hyperbolic2x2(*SECOND)
    controller = nr.CollocatedOutputFeedback(StateFeedback(-0.6), observer_delay=0.1)
    assert loop_route(plant, controller) == "exact"
    A, B = nr.loop_factors(plant, controller)
    scope = loop_scope(plant, controller, None, (A, B))
    assert scope.startswith("the PDE itself") and "floating point" not in scope
    with mp.workdps(DPS):
        for s in (0.3 + 0.7j, -0.2 + 5j):
            A_o, B_o = _factors(SECOND, -0.6, 0.0, mp.mpf(0.1), mp.mpc(s))
            assert abs(complex(A(s)) - complex(A_o)) < 1e-13 and abs(complex(B(s)) - complex(B_o)) < 1e-13


def test_the_design_loop_in_kappa_is_the_proven_loop():
    """``collocated_observer_loop`` (the loop affine in ``kappa`` that ``design_collocated_observer`` searches) is
    built from the same proven terms: at ``kappa = 0.2`` it equals ``loop_factors`` to rounding (1e-14), and the
    reflection's ``H_y`` is the 40-digit closed form to 1e-14."""
    plant = Hyperbolic2x2(*SECOND)
    controller = nr.CollocatedOutputFeedback(StateFeedback(-0.6), observer_reflection=0.2)
    loop = collocated_observer_loop(plant, controller)
    A, B = nr.loop_factors(plant, controller)
    response = observer_reflection_of(plant, controller).response
    for s in (0.3 + 0.7j, -0.2 + 5j):
        assert abs(complex(loop.A0(s) + 0.2 * loop.A1(s)) - complex(A(s))) < 1e-14
        assert abs(complex(loop.B0(s) + 0.2 * loop.B1(s)) - complex(B(s))) < 1e-14
        with mp.workdps(DPS):
            assert abs(complex(response(s)) - complex(_open_loop_and_hy(SECOND, mp.mpc(s))[1])) < 1e-14


def test_laws_with_an_integral_part_stay_a_model():
    """U_BS2(K) and a state feedback with integral gains read the dual plant's kernels composed with the plant's:
    the state feedback's collocated loop, and U_BS2(K)'s with an observer delay, stay the kernel route's, and the
    scope says it is a model (U_BS2(K) without it is proven: ``test_collocated_proof.py``)."""
    plant = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
    for controller in (
        nr.CollocatedOutputFeedback(ReflectionController(0.1), observer_delay=0.05),
        nr.CollocatedOutputFeedback(StateFeedback(-0.3, g_u=0.1)),
    ):
        assert loop_route(plant, controller) == "observer"
        A, B = nr.loop_factors(plant, controller)
        assert loop_scope(plant, controller, None, (A, B)).startswith("a model of the PDE")


def test_bad_input_is_refused():
    """A plant other than a ``Hyperbolic2x2`` with constant couplings is refused before work."""
    general = GeneralHyperbolic2x2(lam=1.0, mu=2.0, a=0.1, b=0.2, c=0.3, d=-0.2, q=0.6, rho=0.7)
    with pytest.raises(ParameterError, match="system"):
        proven_collocated_products(general)
    assert "Hyperbolic2x2" in proven_collocated_failure(general)
    assert proven_collocated_failure(Hyperbolic2x2(*FIRST)) is None


def test_polynomial_terms_of_two_degrees_add():
    """Two polynomial-piece terms on the same nodes with pieces of degrees 1 and 3 add to the term whose value is
    the sum of theirs (exactly: the coefficients are small integers), and their error bounds add (rounded up)."""
    nodes = np.array([0.0, 0.5, 1.0])
    low = DistributedDelay(nodes, None, interpolation="polynomial", coefficients=np.array([[1.0, 2.0], [3.0, -1.0]]))
    high = DistributedDelay(
        nodes,
        None,
        interpolation="polynomial",
        coefficients=np.array([[0.0, 1.0, 0.0, 2.0], [1.0, 0.0, -1.0, 1.0]]),
        radius=0.25,
        variation_radius=0.5,
    )
    total = low.plus(high)
    nu = np.linspace(0.0, 1.0, 9)
    np.testing.assert_array_equal(total.kernel_at(nu), low.kernel_at(nu) + high.kernel_at(nu))
    assert 0.25 <= total.radius <= 0.25 * (1 + 1e-12) and 0.5 <= total.variation_radius <= 0.5 * (1 + 1e-12)
    for s in (0.5 + 1j, -1 + 3j):
        assert abs(total(s) - (low(s) + high(s))) < 1e-14


def test_an_undecided_loop_without_delay_is_not_called_unstable():
    """``kappa = rho = 0.2`` and ``observer_delay = 0.05`` on ``(1, 2, 1, 1, 1, 0.2)``: the input delay's principal
    term vanishes and ``A``'s own principal part, stable at ``observer_delay / tau = 1/30`` as given (its roots at
    ``Re s <= -0.145``), is not strongly stable in its two delays. The margin is 0 (Theorem 3: small changes of those
    delays destabilise) and the count without delay is not decided: the reason says that ``nominally_stable`` False
    means not certified (it read as unstable before)."""
    plant = Hyperbolic2x2(*SECOND)
    controller = nr.CollocatedOutputFeedback(StateFeedback(-0.6), observer_reflection=0.2, observer_delay=0.05)
    margin = nr.delay_margin(plant, controller, rigorous=True)
    assert margin.margin == 0.0 and margin.nominal_unstable is None
    assert "not certified, not unstable" in margin.reason
