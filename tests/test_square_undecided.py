"""A square's proof that stops: the boxes it left undecided are checked, and an unstable point in them is found.

The plant and law: ``Hyperbolic2x2(1, 2, 0.4, 0.5, 1, 0.3)`` under ``U = -0.45 u(t, 1) + int 0.8 e^x u -
(1 + x^2) v dx``, speed errors ``|e_lam|, |e_mu| <= 0.15``. The four corners are stable up to delay 0.08449 at
least, but the edge ``e_mu = 0.15`` dips to a margin 0.08246 near ``e_lam = -0.075``: on the window
``[0, 0.083476]`` the proof of the square runs out of boxes, and the corners alone would hide the unstable
mismatches between them.

The oracle shares no code with the package: the Laplace-domain state ``[u; v](x, s) = exp(x M(s)) [q; 1]``
(``M = [[-s/lam, sigma_pm/lam], [-sigma_mp/mu, s/mu]]``) by the closed form ``e^{tr/2} (cosh D I + sinh(D)/D
(M - tr/2 I))`` of a 2x2 exponential, the law's integral by Gauss-Legendre quadrature, the loop ``v(1) - rho
u(1) - e^{-delta s} U = 0`` as ``A + B e^{-delta s}`` with ``A = v(1) - rho u(1)``, ``B = -(k u(1) + int g_u u +
g_v v dx)``, its crossing frequencies (``|A(i w)| = |B(i w)|``) bracketed on a grid and refined by ``brentq``,
and their crossing delays ``(-arg(-A/B) + 2 pi j) / w``. A crossing delay in the window is a zero on the
imaginary axis for a delay of the window: the window is not stable there.

The same on an uncoupled plant (a pocket of the filtered law's margin between stable corners), the loop from the
characteristics written here.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from nrobust import FilteredController, Hyperbolic2x2, TransportSystem
from nrobust.hyperbolic.analyses import speed_tolerance
from nrobust.hyperbolic.loops.controllers import StateFeedback, loop_factors
from nrobust.margins import delay_margin

flint = pytest.importorskip("flint")

PLANT = Hyperbolic2x2(1.0, 2.0, 0.4, 0.5, 1.0, 0.3)
K = -0.45
LAW = StateFeedback(K, g_u=lambda x: 0.8 * np.exp(x), g_v=lambda x: -(1 + x**2))
EPS = 0.15
WINDOW = (0.0, 0.083476)
# Gauss-Legendre nodes on [0, 1]: the integrand turns like e^{-i w x (1/lam + 1/mu)}, under 6 turns for w <= 40;
# the first crossing delay of the refuted point from 24, 48, 96 and 192 nodes agree to 4e-15 (measured), far
# below the 4e-4 between that point's margin and the window's end and the 3e-14 accuracy of the package's margin
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(96)
_X, _W = 0.5 * (_NODES + 1.0), 0.5 * _WEIGHTS


def _state(s: complex, lam: float, mu: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(u(x), v(x))`` of the Laplace-domain PDE with ``v(0) = 1``: ``exp(x M) [q; 1]`` in closed form."""
    m11, m12, m21, m22 = -s / lam, float(PLANT.sigma_pm) / lam, -float(PLANT.sigma_mp) / mu, s / mu
    half = 0.5 * (m11 + m22) * x
    D = np.sqrt((0.5 * (m11 - m22) * x) ** 2 + m12 * m21 * x * x + 0j)
    sinhc = np.sinh(D) / D
    e = np.exp(half)
    e11, e12 = e * (np.cosh(D) + sinhc * (m11 * x - half)), e * sinhc * m12 * x
    e21, e22 = e * sinhc * m21 * x, e * (np.cosh(D) + sinhc * (m22 * x - half))
    return e11 * PLANT.q + e12, e21 * PLANT.q + e22


def _factors(w: float, e_lam: float, e_mu: float) -> tuple[complex, complex]:
    """``(A(i w), B(i w))`` of the PDE's loop at the mismatch ``(e_lam, e_mu)`` (module notes)."""
    lam, mu = PLANT.lam * (1.0 + e_lam), PLANT.mu * (1.0 + e_mu)
    u, v = _state(1j * w, lam, mu, _X)
    integral = np.sum(_W * (0.8 * np.exp(_X) * u - (1.0 + _X**2) * v))
    u1, v1 = (complex(z[0]) for z in _state(1j * w, lam, mu, np.ones(1)))
    return v1 - PLANT.rho * u1, complex(-(K * u1 + integral))


def _crossing_delays(e_lam: float, e_mu: float, d_max: float, w_max: float = 60.0) -> list[float]:
    """Every crossing delay in ``[0, d_max]`` of the mismatched loop, from the oracle."""

    def gap(w: float) -> float:
        A, B = _factors(w, e_lam, e_mu)
        return abs(A) ** 2 - abs(B) ** 2

    grid = np.linspace(1e-3, w_max, 6001)
    values = [gap(w) for w in grid]
    out = []
    for w0, w1, g0, g1 in zip(grid[:-1], grid[1:], values[:-1], values[1:]):
        if g0 * g1 < 0:
            wc = brentq(gap, w0, w1, xtol=1e-15)
            A, B = _factors(wc, e_lam, e_mu)
            phase = -math.atan2((-A / B).imag, (-A / B).real)  # e^{-i w delta} = -A/B
            delay = (phase % (2 * math.pi)) / wc
            while delay <= d_max:
                out.append(delay)
                delay += 2 * math.pi / wc
    return sorted(out)


def test_an_unstable_point_between_stable_corners_is_found() -> None:
    """The proof runs out of boxes; a point of its undecided boxes is refuted, named, and unstable (oracle)."""
    # the case as described: no crossing delay in the window at the corners, one on the edge e_mu = eps
    assert all(_crossing_delays(a, b, WINDOW[1]) == [] for a in (-EPS, EPS) for b in (-EPS, EPS))
    assert _crossing_delays(-0.075, EPS, WINDOW[1])
    result = speed_tolerance(PLANT, LAW, EPS, WINDOW, grid=2, rigorous=True)
    assert not result.met and result.certified == "not met"
    assert all(w.stable and w.certified == "proven" for w in result.windows[:4])
    (e_lam, e_mu), window = result.points[-1], result.windows[-1]
    assert len(result.points) == 5 and not window.stable
    assert abs(e_lam) <= EPS and abs(e_mu) <= EPS
    assert f"({e_lam!r}, {e_mu!r})" in result.statement
    assert "left undecided" in result.statement and "delay margin 0.0824639" in result.statement
    assert result.statement.endswith("(proven)")
    # the oracle: a crossing delay of the PDE's loop at that mismatch lies in the window
    delays = _crossing_delays(e_lam, e_mu, WINDOW[1])
    assert delays and delays[0] < WINDOW[1] - 1e-4
    # the verdict's margin, proven in ball arithmetic, is the first of them (to the accuracies above)
    margin = window.margin
    assert margin.verified and margin.margin < WINDOW[1]
    assert abs(margin.margin - delays[0]) < 1e-12
    # and the package's own delay margin of the plant with the perturbed speeds, built here
    plant = Hyperbolic2x2(PLANT.lam * (1.0 + e_lam), PLANT.mu * (1.0 + e_mu), 0.4, 0.5, 1.0, 0.3)
    assert delay_margin(*loop_factors(plant, LAW), rigorous=True).margin < WINDOW[1]


def test_checked_undecided_boxes_keep_the_corners_certificate() -> None:
    """A proof stopped by its work bound on a stable square: the undecided boxes are checked, and said so."""
    result = speed_tolerance(PLANT, StateFeedback(-0.2), 0.2, (0.0, 1.0), grid=2, rigorous=True, max_boxes=3)
    assert result.met and result.certified == "proven at the corners"
    assert "boxes of mismatches it left undecided checked in floating point" in result.statement
    assert len(result.points) == 4


# an uncoupled plant: the filtered law U = -0.7 u(t, 1) / (1 + 0.2 s) on rho q = 0.5; its loop from the
# characteristics is (1 + 0.2 s)(1 - 0.5 e^{-tau s}) + 0.7 e^{-(tau + delta) s}, tau = 1/lam' + 1/mu', whose
# first crossing delay dips below 0.45 for round trips inside the square's (a pocket between stable corners)
POCKET = TransportSystem(10.0, 0.37, 1.0, 0.5)
FILTERED = FilteredController(0.0, 0.2, 0.7)


def _pocket_crossings(e_lam: float, e_mu: float, d_max: float) -> list[float]:
    """Every crossing delay in ``[0, d_max]`` of the pocket's loop at the mismatch (``|A(i w)| = |B(i w)|``)."""
    tau = 1.0 / (POCKET.lam * (1.0 + e_lam)) + 1.0 / (POCKET.mu * (1.0 + e_mu))

    def gap(w: float) -> float:
        return abs(1 + 0.2j * w) ** 2 * abs(1 - 0.5 * np.exp(-1j * w * tau)) ** 2 - 0.49

    # |A| >= sqrt(1 + 0.04 w^2) (1 - 0.5) > 0.7 = |B| for w > 9.8: every crossing frequency is below 12
    grid = np.linspace(1e-9, 12.0, 6001)
    out = []
    for w0, w1 in itertools.pairwise(grid):
        if gap(w0) * gap(w1) < 0:
            wc = brentq(gap, w0, w1, xtol=1e-14)
            ratio = -(1 + 0.2j * wc) * (1 - 0.5 * np.exp(-1j * wc * tau)) / (0.7 * np.exp(-1j * wc * tau))
            delay = (-math.atan2(ratio.imag, ratio.real)) % (2 * math.pi) / wc
            while delay <= d_max:
                out.append(delay)
                delay += 2 * math.pi / wc
    return sorted(out)


@pytest.mark.parametrize("max_boxes", [5, 50, 100])
def test_a_transport_square_out_of_boxes_finds_the_pocket(max_boxes: int) -> None:
    """Out of boxes before the pocket is decided (the box stopped at is stable there): a point of the undecided
    ranges of the round trip is refuted, and the oracle has a crossing delay in the window there."""
    window = (0.0, 0.45)
    assert all(_pocket_crossings(a, b, window[1]) == [] for a in (-0.1, 0.1) for b in (-0.1, 0.1))
    result = speed_tolerance(POCKET, FILTERED, 0.1, window, grid=2, rigorous=True, max_boxes=max_boxes)
    assert not result.met and result.certified == "not met"
    assert all(w.stable and w.certified == "proven" for w in result.windows[:4])
    (e_lam, e_mu), verdict = result.points[-1], result.windows[-1]
    assert len(result.points) == 5 and not verdict.stable and abs(e_lam) <= 0.1 and abs(e_mu) <= 0.1
    delays = _pocket_crossings(e_lam, e_mu, window[1])
    # the package's margin and the oracle's delay solve one crossing equation (brentq to 1e-14 in w): 1e-9 is loose
    assert delays and abs(verdict.margin.margin - delays[0]) < 1e-9
