"""The square of speed errors on a coupled plant under a law with integral gains, against oracles of its own.

The oracle is the loop of the PDE (18)-(20) under ``U(t) = k u(t - delta, 1) + int_0^1 g_u u + g_v v dx``
written from its Laplace transform: ``X' = M(s) X``, ``X = (u, v)``, ``M = [[-s/lam, sigma_pm/lam],
[-sigma_mp/mu, s/mu]]``, ``X(0) = (q, 1) v(0)``, so ``X(x) = e^{x M} (q, 1) v(0)``. Normalised by
``e^{-s/mu}``: ``A = [E (q, 1)]_v - rho [E (q, 1)]_u`` and ``B = -(k [E (q, 1)]_u + int_0^1 g(x) . e^{x M}
(q, 1) e^{-s/mu} dx)`` with ``E = e^{M - s/mu}`` (the 2x2 exponential in closed form): no series, no kernel, no
delay form; in mpmath at 40 digits, or in floating point with a Gauss-Legendre rule for the scans.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from nrobust import Hyperbolic2x2
from nrobust.hyperbolic.analyses import mismatch_loop
from nrobust.hyperbolic.loops.controllers import StateFeedback

flint = pytest.importorskip("flint")
mpmath = pytest.importorskip("mpmath")


def _gains_mp(x: Any) -> tuple[Any, Any]:
    return 0.1 * mpmath.exp(x), -0.2 * (1 + x**2)


LAW = StateFeedback(-0.2, lambda x: 0.1 * np.exp(x), lambda x: -0.2 * (1 + x**2))
PLANT = Hyperbolic2x2(1.0, 2.0, 0.4, 0.5, 1.0, 0.3)


def _exp_mp(x: Any, s: Any, lam: Any, mu: Any, spm: Any, smp: Any) -> tuple[Any, Any, Any, Any]:
    """``e^{x (M - s/mu)}`` in closed form: ``e^{x a/2} (cosh(x r) I + sinh(x r)/r (N - a/2 I))``."""
    a, b, c = -s / lam - s / mu, spm / lam, -smp / mu
    r = mpmath.sqrt(a * a / 4 + b * c)
    e = mpmath.exp(x * a / 2)
    sh = x * mpmath.sinhc(x * r) if False else (mpmath.sinh(x * r) / r if r != 0 else x)
    ch = mpmath.cosh(x * r)
    return e * (ch + sh * a / 2), e * sh * b, e * sh * c, e * (ch - sh * a / 2)


def _loop_mp(s: Any, lam: float, mu: float, spm: float, smp: float, q: float, rho: float) -> tuple[Any, Any]:
    """``(A(s), B(s))`` of the oracle (module notes) at 40 digits, for :data:`LAW`."""
    with mpmath.workdps(40):
        s = mpmath.mpc(s)
        lam, mu, spm, smp, q, rho = (mpmath.mpf(v) for v in (lam, mu, spm, smp, q, rho))
        e11, e12, e21, e22 = _exp_mp(1, s, lam, mu, spm, smp)
        u1, v1 = e11 * q + e12, e21 * q + e22

        def integrand(x: Any) -> Any:
            f11, f12, f21, f22 = _exp_mp(x, s, lam, mu, spm, smp)
            gu, gv = _gains_mp(x)
            # e^{x M} e^{-s/mu} = e^{x (M - s/mu)} e^{-s (1 - x)/mu}
            return (gu * (f11 * q + f12) + gv * (f21 * q + f22)) * mpmath.exp(-s * (1 - x) / mu)

        cuts = mpmath.linspace(0, 1, 2 + int(abs(s) / 2))
        integral = mpmath.quad(integrand, cuts)
        return v1 - rho * u1, -(mpmath.mpf(LAW.k) * u1 + integral)


def test_oracle_is_the_loop_of_the_package() -> None:
    """The oracle and ``mismatch_loop``'s exact route (``gain_kernel``) agree to rounding (1e-12: double sums of
    O(1) terms)."""
    for e_lam, e_mu in [(0.04, -0.03), (-0.05, 0.05)]:
        A, B = mismatch_loop(PLANT, LAW, e_lam, e_mu)
        lam, mu = PLANT.lam * (1 + e_lam), PLANT.mu * (1 + e_mu)
        for w in (0.0, 0.7, 4.0, 15.0):
            a, b = _loop_mp(1j * w, lam, mu, 0.4, 0.5, 1.0, 0.3)
            np.testing.assert_allclose(A(1j * w), complex(a), rtol=0, atol=1e-12)
            np.testing.assert_allclose(B(1j * w), complex(b), rtol=0, atol=1e-12)


def test_box_enclosures_hold_the_loop_of_every_speed_of_the_box() -> None:
    """The balls of a box of ``(tau w, e_lam, e_mu)`` hold the oracle's 40-digit ``A`` and ``B`` at random points of
    the box (``z = tau s`` with the point's own ``tau``)."""
    from nrobust.hyperbolic.analyses.mismatch_coupled import _Box

    rng = np.random.default_rng(5)
    for box, (w0, w1) in (((-0.05, 0.05, -0.05, 0.05), (0.0, 0.5)), ((0.01, 0.02, -0.03, -0.01), (6.0, 6.2))):
        part = _Box(PLANT, LAW, box)
        A, B = part.factors(w0, w1)
        for _ in range(6):
            e_lam, e_mu = rng.uniform(box[0], box[1]), rng.uniform(box[2], box[3])
            lam, mu = PLANT.lam * (1 + e_lam), PLANT.mu * (1 + e_mu)
            z = rng.uniform(w0, w1)
            a, b = _loop_mp(1j * z / (1 / lam + 1 / mu), lam, mu, 0.4, 0.5, 1.0, 0.3)
            for ball, value in ((A, a), (B, b)):
                assert ball.contains(flint.acb(complex(value))), (box, z, ball, value)
