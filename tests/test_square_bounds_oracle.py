"""The hand-derived bounds of the square's proof under laws with integral gains, against oracles.

- :func:`~nrobust.hyperbolic.analyses.mismatch_gains.gain_term`: the ``L^1`` radius of a box of speeds must hold
  the ``L^1`` distance between the scaled gain kernel ``k`` of each speed of the box and that of the box's
  middle plant (each kernel from ``gain_kernel`` at that speed, checked against the loop's closed form
  ``int_0^1 g(x) . e^{x M(s)} (q, 1) e^{-s/mu} dx`` by Gauss-Legendre quadrature), and ``V_g / |z|`` must
  bound that closed form's modulus at large ``|z|``.
- :func:`~nrobust.hyperbolic.analyses.mismatch_traces.reflection_traces`: ``delta`` must hold the distance
  between the fitted traces and the traces of a fine kernel grid extrapolated (Richardson).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest

from nrobust import Hyperbolic2x2
from nrobust.hyperbolic.loops.controllers import StateFeedback

flint = pytest.importorskip("flint")

PLANT = Hyperbolic2x2(1.0, 2.0, 0.4, 0.5, 1.0, 0.3)
LAW = StateFeedback(-0.2, lambda x: 0.1 * np.exp(x), lambda x: -0.2 * (1 + x**2))
_X, _W = np.polynomial.legendre.leggauss(30)


def _middle_plant(system, box):
    """The plant at the middle of the box of relative speed errors."""
    return dataclasses.replace(
        system, lam=system.lam * (1 + 0.5 * (box[0] + box[1])), mu=system.mu * (1 + 0.5 * (box[2] + box[3]))
    )


def _box_gain_term(flint, system, law, box):
    """``gain_term`` of ``law``'s gains over the box of relative speed errors ``box`` (its ``p``, ``m`` as balls)."""
    from nrobust.hyperbolic.analyses.mismatch_gains import gain_bounds, gain_term

    arb = flint.arb
    lam = arb(system.lam) * (1 + arb(box[0]).union(arb(box[1])))
    mu = arb(system.mu) * (1 + arb(box[2]).union(arb(box[3])))
    P, M = arb(float(system.sigma_pm)) / lam, -arb(float(system.sigma_mp)) / mu
    return gain_term(flint, system, law.g_u, law.g_v, box, P, M, gain_bounds(flint, system, law.g_u, law.g_v))


def _closed_form(system: Hyperbolic2x2, law: StateFeedback, s: complex, n: int) -> complex:
    """``int_0^1 g(x) . e^{x M(s)} (q, 1) e^{-s/mu} dx``, ``M = [[-s/lam, sigma_pm/lam], [-sigma_mp/mu, s/mu]]``
    (eigen-decomposition of ``M``, ``n``-point Gauss-Legendre)."""
    lam, mu = system.lam, system.mu
    m = np.array([[-s / lam, system.sigma_pm / lam], [-system.sigma_mp / mu, s / mu]], dtype=complex)
    ev, vec = np.linalg.eig(m)
    coef = np.linalg.solve(vec, np.array([system.q, 1.0], dtype=complex))
    x, w = np.polynomial.legendre.leggauss(n)
    x, w = 0.5 * (x + 1), 0.5 * w
    state = vec @ (coef[:, None] * np.exp(np.outer(ev, x) - s / mu))  # (2, n): X(x) e^{-s/mu}
    return complex(np.sum(w * (law.g_u(x) * state[0] + law.g_v(x) * state[1])))


def _scaled_kernel(system: Hyperbolic2x2, law: StateFeedback) -> tuple[Any, np.ndarray]:
    """``k(t) = tau K(tau t)`` on ``[0, 1]`` and its breakpoints, ``K`` from ``gain_kernel`` (checked against
    :func:`_closed_form` at two frequencies to 1e-9: double sums of O(1) terms and a 200-point rule)."""
    from nrobust.hyperbolic.loops.exact_gains import gain_kernel

    kernel = gain_kernel(system, law.g_u, law.g_v)
    assert kernel is not None
    for w in (0.5, 7.0):
        np.testing.assert_allclose(kernel(1j * w), _closed_form(system, law, 1j * w, 200), rtol=0, atol=1e-9)
    tau = system.tau
    return (lambda t: tau * np.real(kernel.kernel_at(np.clip(t * tau, 0.0, tau)))), np.asarray(kernel.nodes) / tau


def _l1(f: Any, g: Any, cuts: np.ndarray) -> float:
    """``int_0^1 |f - g|`` by 30-point Gauss-Legendre between the kernels' breakpoints and a 400-cell grid."""
    cuts = np.unique(np.clip(np.concatenate([cuts, np.linspace(0.0, 1.0, 401)]), 0.0, 1.0))
    a, b = cuts[:-1], cuts[1:]
    t = 0.5 * (a + b)[:, None] + 0.5 * (b - a)[:, None] * _X[None, :]
    diff = np.abs(f(t.ravel()) - g(t.ravel())).reshape(t.shape)
    return float(np.sum(0.5 * (b - a) * (diff @ _W)))


@pytest.mark.parametrize(
    ("case", "box"),
    [
        ("exp_gains", (-0.05, 0.05, -0.05, 0.05)),
        pytest.param("paper_traces", (-0.05, 0.05, -0.05, 0.05), marks=pytest.mark.long),  # 6 s
        ("paper_traces", (-0.0025, 0.0, 0.0, 0.0025)),
        pytest.param("exp_gains", (0.09, 0.1, -0.1, -0.09), marks=pytest.mark.long),
    ],
)
def test_gain_radius_and_variation_hold_the_kernels_of_the_box(
    case: str, box: tuple[float, float, float, float]
) -> None:
    """The box's ``L^1`` radius is at least the ``L^1`` distance of each sampled speed's kernel to the middle
    plant's (the radius is a proof: no tolerance; the quadrature of the distance is exact to ~1e-12 on
    polynomial pieces), and ``V_g / |z| >= |I_g(z)|`` at ``|z|`` from 20 to 500. The speeds: the four corners
    and two random points of the box. Observed radius / largest distance: 2.6 to 3.0 for the gains ``e^x``,
    ``1 + x^2``, 6.2 to 7.1 for ``U_BS2(0.1)``'s traces on the paper's plant (its kernels' jump at ``r``
    nearly cancels, and the moving jump is bounded by the jump itself)."""
    from nrobust._flint import precision
    from nrobust.hyperbolic.loops.exact_form import PRECISION

    system, law = (PLANT, LAW) if case == "exp_gains" else _paper_law()
    with precision(flint, PRECISION):
        term = _box_gain_term(flint, system, law, box)
    assert term is not None
    radius, v_g = term.kernel.radius + term.spread, term.variation
    middle = _middle_plant(system, box)
    k0, c0 = _scaled_kernel(middle, law)
    rng = np.random.default_rng(3)
    speeds = [(a, b) for a in box[:2] for b in box[2:]]
    speeds += [tuple(rng.uniform([box[0], box[2]], [box[1], box[3]])) for _ in range(2)]
    distances = []
    for e_lam, e_mu in speeds:
        plant = dataclasses.replace(system, lam=system.lam * (1 + e_lam), mu=system.mu * (1 + e_mu))
        k, c = _scaled_kernel(plant, law)
        distances.append(_l1(k, k0, np.concatenate([c, c0])))
        for z in (20.0, 100.0, 500.0):
            assert v_g / z >= abs(_closed_form(plant, law, 1j * z / plant.tau, 4 * int(z) + 200))
    assert radius >= max(distances) > 0.0


@pytest.mark.long
def test_trace_bound_holds_a_fine_grid() -> None:
    """``h`` of ``reflection_traces`` agrees with ``g``, the traces of grids 401 and 801 extrapolated to second
    order, within ``delta`` plus the oracle's own error, taken as four times the extrapolation's change (the
    observed order is 2.3: the change overstates the extrapolated traces' error). Since the traces are solved by
    collocation ``delta`` (7.5e-14) is far below the oracle's accuracy (``sup |h - g|`` measured 7.8e-10, the
    extrapolation's change about 2e-9); fitted to the kernel route's traces they were within ``delta`` ~1e-7 of
    it, ``sup |h - g|`` ~4e-8."""
    from nrobust.hyperbolic.analyses.mismatch_traces import reflection_traces
    from nrobust.hyperbolic.kernels.constant import solve_kernels
    from nrobust.hyperbolic.loops.controllers import ReflectionController

    K = 0.15
    law, delta = reflection_traces(PLANT, K)
    x = np.linspace(0.0, 1.0, 1001)
    coarse, fine = (ReflectionController(K).feedback_law(PLANT, solve_kernels(PLANT, n)) for n in (401, 801))
    for h, name in ((law.g_u, "gain_u"), (law.g_v, "gain_v")):
        g1, g2 = (np.asarray(getattr(f, name)(x), dtype=float) for f in (coarse, fine))
        truth = g2 + (g2 - g1) / 3.0
        oracle_error = 4.0 * float(np.max(np.abs(g2 - g1))) / 3.0
        assert np.max(np.abs(np.asarray(h(x), dtype=float) - truth)) <= delta + oracle_error


def _integral_terms(system: Hyperbolic2x2, law: StateFeedback, s: np.ndarray, n: int) -> np.ndarray:
    """:func:`_closed_form` at many ``s`` at once, by the closed form of the 2x2 exponential instead of an
    eigen-decomposition: ``e^{x N} = e^{x a / 2} (cosh(x r) I + sinh(x r) / r (N - a/2 I))`` for
    ``N = M - s/mu I`` (``a = tr N``, ``r^2 = a^2 / 4 - det N``), and ``e^{x M} e^{-s/mu} = e^{x N}
    e^{-s (1 - x)/mu}``; ``n``-point Gauss-Legendre."""
    lam, mu, q = system.lam, system.mu, system.q
    b, c = system.sigma_pm / lam, -system.sigma_mp / mu
    x, w = np.polynomial.legendre.leggauss(n)
    x, w = 0.5 * (x + 1), 0.5 * w
    s = np.asarray(s, dtype=complex)[:, None]
    a = -s / lam - s / mu
    r = np.sqrt(a * a / 4 + b * c)
    e, ch, sh = np.exp(x * a / 2 - s * (1 - x) / mu), np.cosh(x * r), np.sinh(x * r) / r
    u = e * ((ch + sh * a / 2) * q + sh * b)  # e^{x N} (q, 1), N - a/2 I = [[a/2, b], [c, -a/2]]
    v = e * (sh * c * q + ch - sh * a / 2)
    return np.asarray((law.g_u(x) * u + law.g_v(x) * v) @ w)


def _two_term_bounds(
    system: Hyperbolic2x2, law: StateFeedback, box: tuple[float, float, float, float]
) -> tuple[float, float, float]:
    """``(V_g, V_{g,1}, V_{g,2})`` of ``gain_variations`` on a box of speed errors."""
    from nrobust._flint import precision
    from nrobust.hyperbolic.analyses.mismatch_gains import gain_bounds, gain_variations, time_ratio
    from nrobust.hyperbolic.loops.exact_form import PRECISION

    arb = flint.arb
    with precision(flint, PRECISION):
        lam = arb(system.lam) * (1 + arb(box[0]).union(arb(box[1])))
        mu = arb(system.mu) * (1 + arb(box[2]).union(arb(box[3])))
        P, M = arb(float(system.sigma_pm)) / lam, -arb(float(system.sigma_mp)) / mu
        bounds = gain_bounds(flint, system, law.g_u, law.g_v)
        out = gain_variations(flint, P, M, time_ratio(flint, system, box), system.q, bounds)
    return tuple(float(v.upper()) for v in out)  # type: ignore[return-value]


def _paper_law() -> tuple[Hyperbolic2x2, StateFeedback]:
    from nrobust.hyperbolic.analyses.mismatch_traces import reflection_traces

    plant = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
    return plant, reflection_traces(plant, 0.1)[0]


@pytest.mark.parametrize("case", ["exp_gains", "paper_traces"])
def test_two_term_gain_bound_holds_the_closed_form(case: str) -> None:
    """``V_{g,1} / |z| + V_{g,2} / |z|^2 >= |I_g(z)|`` (``z = tau s``, the speed's own ``tau``) at the corners, the
    centre and random speeds of the square ``[-0.05, 0.05]^2``, on the imaginary axis (``|z|`` from 10 to 320) and
    at ``Re z = 0.5, 3``; ``I_g`` by the closed form of the 2x2 exponential (:func:`_integral_terms`, checked
    against :func:`_closed_form`'s eigen-decomposition to 1e-10), no kernel, no series.

    The ``1 / |z|`` coefficient is the sharp one: ``max |z I_g(z)|`` over ``y = Im z`` in ``[300, 340]`` (dense,
    the end terms' phases ``y`` and ``r y`` sweep) must lie within ``V_{g,1} + V_{g,2} / 300`` and above
    ``V_{g,1} / 3`` (observed at eps = 0.05: ``V_{g,1}`` is 1.02 to 1.2 times the peak, ``V_g`` 2.4 to 12.7
    times); on the paper's plant the bound of one integration by parts, ``V_g``, is more than 10 times
    ``V_{g,1}``."""
    system, law = (PLANT, LAW) if case == "exp_gains" else _paper_law()
    box = (-0.05, 0.05, -0.05, 0.05)
    v_g, v1, v2 = _two_term_bounds(system, law, box)
    rng = np.random.default_rng(7)
    speeds = [(a, b) for a in (-0.05, 0.05) for b in (-0.05, 0.05)] + [(0.0, 0.0)]
    speeds += [tuple(rng.uniform(-0.05, 0.05, 2)) for _ in range(3)]
    zs = np.array([10j, 40j, 160j, 320j, 0.5 + 20j, 3.0 + 80j, 0.5 + 320j])
    ys = np.linspace(300.0, 340.0, 801)
    for e_lam, e_mu in speeds:
        plant = dataclasses.replace(system, lam=system.lam * (1 + e_lam), mu=system.mu * (1 + e_mu))
        tau = plant.tau
        true = np.abs(_integral_terms(plant, law, zs / tau, 1000))
        np.testing.assert_allclose(
            true[[0, 4]], [abs(_closed_form(plant, law, z / tau, 1000)) for z in zs[[0, 4]]], rtol=0, atol=1e-10
        )
        assert np.all(v1 / np.abs(zs) + v2 / np.abs(zs) ** 2 >= true)
        peak = float(np.max(ys * np.abs(_integral_terms(plant, law, 1j * ys / tau, 1000))))
        assert v1 + v2 / 300.0 >= peak >= v1 / 3.0
    assert case == "exp_gains" or v_g > 10.0 * v1


def _ball(re: tuple[float, float], im: tuple[float, float]) -> Any:
    """The complex ball of the rectangle ``re x im`` (an enclosure of every point of it)."""
    arb = flint.arb
    return flint.acb(arb(re[0]).union(arb(re[1])), arb(im[0]).union(arb(im[1])))


def test_crossing_free_clears_low_frequencies_by_the_loop_itself() -> None:
    """``crossing_free`` on a box with ``w`` in ``[0, 0.5]`` and the delays ``[0, 0.2]``: the factors' moduli overlap
    and ``-A/B`` is about a positive real (its argument's ball holds 0, so no crossing delay is resolved near
    ``w = 0``), yet ``F = A + B e^{-i w delta}`` has no zero: ``Re F <= 1.05 - 1.19 cos(0.1) < 0`` for ``A`` in
    ``[0.95, 1.05] + i [-0.7, 0.7]``, ``B`` in ``[-1.21, -1.19]`` (the oracle, a closed form; checked on a dense
    sample of the box too). Cleared now, undecided before. With ``B = -1`` and ``A = 1`` the box holds the zero
    ``w = 0`` of every delay, and with ``A = e^{0.05 i}`` the zero ``w delta = 0.05``: not cleared."""
    from nrobust.hyperbolic.analyses.mismatch_proof import crossing_free

    arb = flint.arb
    A, B = _ball((0.95, 1.05), (-0.7, 0.7)), _ball((-1.21, -1.19), (0.0, 0.0))
    w = arb(0).union(arb(0.5))
    gap = abs(A) ** 2 - abs(B) ** 2
    assert not (gap > 0 or gap < 0)  # the moduli overlap: the first test does not decide
    assert 1.05 - 1.19 * math.cos(0.1) < 0.0
    grid = np.linspace(0.0, 1.0, 9)
    a = (0.95 + 0.1 * grid)[:, None] + 1j * (-0.7 + 1.4 * grid)[None, :]
    turns = np.exp(-1j * np.linspace(0.0, 0.1, 21))  # w delta in [0, 0.5 x 0.2]
    values = a[:, :, None, None] + np.array([-1.21, -1.2, -1.19])[None, None, :, None] * turns[None, None, None, :]
    assert np.max(values.real) < 0.0
    assert crossing_free(flint, A, B, w, 0.0, 0.2)
    assert not crossing_free(flint, _ball((1.0, 1.0), (0.0, 0.0)), _ball((-1.0, -1.0), (0.0, 0.0)), w, 0.0, 0.2)
    shifted = flint.acb(arb(math.cos(0.05)), arb(math.sin(0.05)))  # F = e^{0.05 i} - e^{-i w delta}
    assert not crossing_free(flint, shifted, _ball((-1.0, -1.0), (0.0, 0.0)), w, 0.0, 0.2)


@pytest.mark.parametrize("box", [(-0.0075, -0.005, -0.005, -0.0025), (0.0175, 0.02, -0.02, -0.0175)])
def test_centred_gain_term_holds_the_closed_form(box: tuple[float, float, float, float]) -> None:
    """The slopes' term of the gains (``mismatch_slopes.GainSlopes``) bounds ``|I_g(z; e) - I_g(z; e_0)|`` on the
    paper's plant under ``U_BS2(0.1)``'s traces, ``I_g`` by the closed form of the 2x2 exponential
    (:func:`_integral_terms`, 1000 nodes: ~1e-13), ``e`` the box's corners and random speeds, ``e_0`` its middle
    (whose kernel's point ``r_0`` is on the grid of ``ulp(tau)``: 1e-16 away, within the 1e-12 allowed), at
    ``tau w`` from 0.5 to 150. It is first order and near sharp where the proof needs it: at 0.5 and 6.4 (the
    crossing) at most 3 times the largest sampled difference (observed 1.9 to 2.1); at 50 and 150 the cells'
    variation dominates (observed 10 to 61 times), still below the ``L^1`` bound of ``gain_term`` (the proof's
    bound before the centred form), which is 4.9 to 5.2 times the centred bound at 6.4."""
    from nrobust._flint import precision
    from nrobust.hyperbolic.analyses.mismatch_slopes import T_CELLS, GainSlopes, cell_integrals, gain_pieces
    from nrobust.hyperbolic.loops.exact_form import PRECISION

    system, law = _paper_law()
    arb = flint.arb
    with precision(flint, PRECISION):
        term = _box_gain_term(flint, system, law, box)
        assert term is not None
        slopes = GainSlopes(flint, gain_pieces(flint, system, law.g_u, law.g_v), system.q, *term.balls, term.offsets)
        zs = (0.5, 6.4, 50.0, 150.0)
        bounds = [float(slopes.spread(arb(z), cell_integrals(flint, arb(z), T_CELLS)).upper()) for z in zs]
    rng = np.random.default_rng(4)
    speeds = [(a, b) for a in box[:2] for b in box[2:]] + [tuple(rng.uniform(box[::2], box[1::2])) for _ in range(3)]
    middle = _middle_plant(system, box)
    centre = _integral_terms(middle, law, 1j * np.array(zs) / middle.tau, 1000)
    worst = np.zeros(len(zs))
    for e_lam, e_mu in speeds:
        plant = dataclasses.replace(system, lam=system.lam * (1 + e_lam), mu=system.mu * (1 + e_mu))
        worst = np.maximum(worst, np.abs(_integral_terms(plant, law, 1j * np.array(zs) / plant.tau, 1000) - centre))
    assert np.all(np.array(bounds) >= worst - 1e-12), (bounds, worst)
    assert bounds[0] <= 3.0 * worst[0] and bounds[1] <= 3.0 * worst[1], (bounds, worst)
    assert max(bounds) < term.spread, (bounds, term.spread)
