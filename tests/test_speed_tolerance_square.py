"""Speed tolerance proven on the whole square of mismatches (uncoupled plants), not only at its corners.

Oracles independent of the code under test. On a transport plant the law ``U = -K u(t, 1)``
(filtered by ``1/(1 + b s)``) holds no speed and the mismatched loop is, from the
characteristics, ``F(s) = (1 + b s)(1 - rho q e^{-tau s}) + K q e^{-(tau + delta) s}`` with
``tau = 1/(lam (1 + e_lam)) + 1/(mu (1 + e_mu))``, written here:

- ``|rho q| + |K q| < 1`` unfiltered: ``|F| >= 1 - |rho q| - |K q| > 0`` on ``Re s >= 0`` for
  every ``tau`` and delay (closed form);
- the filtered loop ``rho q = 0.5``, ``K q = 0.7``, ``b = 0.2`` is stable at ``delta = 0`` for
  every ``tau`` (``|0.5 - 0.7/(1 + 0.2 s)| < 1`` on ``Re s >= 0``, maximum modulus), so its
  delay margin is its first crossing delay, solved here from ``|A(i w)| = |B(i w)|`` on a
  brute-force grid of ``tau``; a pair of crossings born inside the square makes the margin dip
  to 0.44598 between corners whose margins are 0.458 to 0.644 (a pocket), and mpmath at 40
  digits finds a zero with ``Re s > 0`` at the nominal speeds and ``delta = 0.45``.
"""

from __future__ import annotations

import math
from typing import Any

import mpmath as mp
import numpy as np
import pytest
from scipy.optimize import brentq

from nrobust import FilteredController, Hyperbolic2x2, ParameterError, ReflectionController, TransportSystem
from nrobust.hyperbolic import OutputFeedback
from nrobust.hyperbolic.analyses import prove_transport_square, speed_tolerance

# the pocket: rho q = 0.5, K q = 0.7, filter 1/(1 + 0.2 s); lam = 10 makes the mixed corners'
# round trips close to the ends of [T_lo, T_hi] = [2.548, 3.114] and outside the dip
POCKET = TransportSystem(10.0, 0.37, 1.0, 0.5)
FILTERED = FilteredController(0.0, 0.2, 0.7)
EPS = 0.1
R, C, BF = 0.5, 0.7, 0.2


def _round_trip(e_lam: float, e_mu: float) -> float:
    return 1.0 / (POCKET.lam * (1.0 + e_lam)) + 1.0 / (POCKET.mu * (1.0 + e_mu))


def _margin(tau: float) -> float:
    """First crossing delay of the filtered loop at round trip ``tau`` (written here from the crossing equation)."""

    def gap(w: Any) -> Any:
        return np.abs(1 + 1j * BF * w) ** 2 * np.abs(1 - R * np.exp(-1j * w * tau)) ** 2 - C**2

    # |A| >= sqrt(1 + 0.04 w^2) (1 - 0.5) > 0.7 = |B| for w > 9.8: every crossing frequency is below 12
    w = np.linspace(1e-9, 12.0, 6001)
    g = gap(w)
    delays = []
    for i in np.nonzero(np.sign(g[:-1]) != np.sign(g[1:]))[0]:
        wc = brentq(gap, w[i], w[i + 1], xtol=1e-14)
        A = (1 + 1j * BF * wc) * (1 - R * np.exp(-1j * wc * tau))
        B = C * np.exp(-1j * wc * tau)
        delays.append((-np.angle(-A / B)) % (2 * np.pi) / wc)
    return min(delays)


def test_closed_form_square_is_proven() -> None:
    """|rho q| + |K q| = 0.7 < 1: no zero in Re s >= 0 for any speed and delay; proven without subdivision."""
    plant = TransportSystem(1.0, 2.0, 1.0, 0.5)
    result = speed_tolerance(plant, ReflectionController(0.2), 0.3, (0.0, 2.0), grid=2, rigorous=True)
    assert result.met and result.certified == "proven on the square" and result.route == "exact"
    assert "[-0.3, 0.3]^2" in result.statement and "[0.0, 2.0]" in result.statement
    assert "c_D <= 0.700001 < 1" in result.statement  # |rho q| + |K q| = 0.7, printed rounded up
    # |rho q| + |K q| = 1.1 >= 1: the difference operator is not strongly stable, refuted at the corners
    refuted = speed_tolerance(plant, ReflectionController(0.6), 0.3, (0.0, 2.0), grid=2, rigorous=True)
    assert not refuted.met and refuted.certified == "not met"


def test_interior_instability_is_not_proven() -> None:
    """Every corner stable on [0, 0.45], the nominal speeds not: 'not met', the square never 'proven'."""
    corner_margins = [_margin(_round_trip(a, b)) for a in (-EPS, EPS) for b in (-EPS, EPS)]
    assert min(corner_margins) > 0.455  # 0.4580, 0.4593, 0.4785, 0.6444
    tau0 = _round_trip(0.0, 0.0)
    assert _margin(tau0) < 0.4461  # 0.446021
    with mp.workdps(40):
        tau, b, r, c, delta = (mp.mpf(x) for x in (tau0, BF, R, C, 0.45))
        root = mp.findroot(lambda s: (1 + b * s) * (1 - r * mp.exp(-tau * s)) + c * mp.exp(-(tau + delta) * s), 4.55j)
        F_root = (1 + b * root) * (1 - r * mp.exp(-tau * root)) + c * mp.exp(-(tau + delta) * root)
        assert abs(F_root) < mp.mpf(10) ** -30 and root.real > 1e-4  # 0.000538 + 4.5484 i
    result = speed_tolerance(POCKET, FILTERED, EPS, (0.0, 0.45), grid=2, rigorous=True)
    assert all(w.stable and w.certified == "proven" for w in result.windows[:4])
    assert not result.met and result.certified == "not met"
    # the mismatch where the proof stopped, checked and refuted: its round trip lies in the dip
    (e_lam, e_mu), window = result.points[4], result.windows[4]
    assert not window.stable and abs(e_lam) <= EPS and abs(e_mu) <= EPS
    assert _margin(_round_trip(e_lam, e_mu)) < 0.45
    # without ball arithmetic the corners alone are all there is: met at them, never proven between
    checked = speed_tolerance(POCKET, FILTERED, EPS, (0.0, 0.45), grid=2)
    assert checked.met and checked.certified == "checked at the corners" and "not certified" in checked.statement


def test_shrunk_window_is_proven_on_the_square() -> None:
    """The same loop on [0, 0.44]: below the dip's 0.44598, proven on the square by subdivision."""
    taus = np.linspace(_round_trip(EPS, EPS), _round_trip(-EPS, -EPS), 101)
    dip = min(_margin(t) for t in taus)
    np.testing.assert_allclose(dip, 0.44598, rtol=0, atol=2e-5)  # a grid of 101 round trips: 0.445977 to 0.44599
    result = speed_tolerance(POCKET, FILTERED, EPS, (0.0, 0.44), grid=2, rigorous=True)
    assert result.met and result.certified == "proven on the square"
    assert "boxes in ball arithmetic" in result.statement and "c_D <= 0.5" in result.statement
    # a work bound too small to decide: the corners' certificate stands, the statement says why
    bounded = speed_tolerance(
        POCKET, FILTERED, EPS, (0.0, 0.44), grid=2, rigorous=True, max_boxes=20, corner_windows=result.windows[:4]
    )
    assert bounded.met and bounded.certified == "proven at the corners" and "max_boxes = 20" in bounded.statement
    assert len(bounded.points) == 4  # the box's mismatch is stable: nothing added


def test_square_needs_a_strongly_stable_difference_operator() -> None:
    """Filtered with |rho q| + |K q a / b| >= 1: zeros come from infinity; the proof refuses, saying why."""
    result = prove_transport_square(POCKET, -0.7, (0.2, 0.2), EPS, (0.0, 0.1), [])
    assert not result.proven and "not proven strongly stable" in result.reason
    assert math.isnan(result.frequency_bound)


def test_coupled_plant_proves_the_square_of_reflection() -> None:
    """U_BS2's kernel gains on a coupled plant: the corners' loops are exact loops of the traces' fits with their
    proven error (``rigorous=True``), the square is proven on the PDE with the traces enclosed
    (``reflection_traces``; the traces fitted from 21 kernel points, their bound proven whatever the grid)."""
    coupled = Hyperbolic2x2(1.0, 1.0, 0.2, 0.2, 0.5, 0.5)
    result = speed_tolerance(
        coupled, ReflectionController(0.1), 0.05, (0.0, 0.5), grid=2, kernel_grid=21, rigorous=True
    )
    assert result.met and result.certified == "proven on the square" and result.route == "exact"
    # the scope is the proof's (the PDE's loop, the traces within their bound), not the corners' route
    assert "kernel traces" in result.statement
    assert "no kernel grid" in result.scope and "proven bound" in result.scope
    with pytest.raises(ParameterError, match="system"):
        prove_transport_square(coupled, 0.1, None, 0.05, (0.0, 0.5), [])


def test_bad_arguments() -> None:
    """Each bad argument named, with its admissible range, before any work."""
    with pytest.raises(ParameterError, match="max_boxes"):
        speed_tolerance(POCKET, FILTERED, EPS, (0.0, 0.44), max_boxes=0)
    with pytest.raises(ParameterError, match=r"eps must be in \(0, 1\)"):
        prove_transport_square(POCKET, -0.7, (0.0, 0.2), 1.0, (0.0, 0.44), [])
    with pytest.raises(ParameterError, match="b must be > 0"):
        prove_transport_square(POCKET, -0.7, (0.0, -0.2), EPS, (0.0, 0.44), [])


def test_an_output_feedback_keeps_the_corners_certificate() -> None:
    # the square proof needs the law on the state; an output feedback raised a ParameterError from it
    result = speed_tolerance(
        TransportSystem(1, 1, 1, 0.5), OutputFeedback(ReflectionController(0.2)), 0.1, (0.0, 0.1), rigorous=True
    )
    assert result.met and result.certified == "proven at the corners"
    assert "an output feedback" in result.statement
    assert all(w.stable for w in result.windows)
    assert result.scope.endswith("acting on the mismatched one")
