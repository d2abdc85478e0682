"""The gains of ``U_BS2(K)`` on a plant with constant couplings, enclosed: :func:`reflection_traces`.

``U_BS2(K)`` (eq. (53)) is ``U = -K u(t, 1) + int_0^1 g_u u + g_v v dx`` with the kernel traces
``g_u = K^{vu}(1, .) - (rho - K) K^{uu}(1, .)`` and ``g_v = K^{vv}(1, .) - (rho - K) K^{uv}(1, .)``, known on a
kernel grid only. They are enclosed here without solving the kernel equations in ball arithmetic, from the
loop of the nominal plant, which is exact (:mod:`~nrobust.hyperbolic.loops.exact_form`): on the plant they
are designed for, ``B = K q e^{-tau s} - int N~ e^{-nu s}`` must equal ``-(k u_factor + I_g)`` with
``k = -K`` (:mod:`~nrobust.hyperbolic.loops.exact_gains`), so the kernel of ``I_g`` is

    ``K[g](theta) = K U~(theta) + N~(theta)``,  ``theta`` in ``[0, tau]``,

and ``g -> K[g]`` is a Volterra operator of the second kind (the module notes of ``exact_gains``): for
``y`` in ``[0, 1]``, ``K[g](t_v (1 - y)) = g_v(y) / t_v + int_y^1 (g_u U + g_v V)(xi, t_v (1 - y)) dxi`` and
``K[g](t_v + t_u y) = q g_u(y) / t_u + int_y^1 (g_u U + g_v V)(xi, t_v + t_u y) dxi``.

The traces on the kernel grid are fitted by Chebyshev polynomials ``h`` (:class:`ChebyshevGain`, evaluable in
ball arithmetic), and the residual ``R = K[h] - K U~ - N~`` is bounded in ball arithmetic
(:func:`_residual`: the three kernels' pieces on a common partition, their proven radii added). The error
``e = h - g`` solves ``K[e] = R``; with ``E(y) = max(|e_u(y)|, |e_v(y)|)``,
``c_1 = max(t_v, t_u / |q|)`` and ``c_2 = (sup |U| + sup |V|)``,
``E(y) <= c_1 sup |R| + c_1 c_2 int_y^1 E``, and Gronwall's lemma gives
``sup |e| <= c_1 sup |R| e^{c_1 c_2}``: the law's gains are ``h`` within that bound.

The Volterra identity is that of the plant the exact forms describe, whose round trip is the double ``tau`` and
``t_v`` on the grid of ``ulp(tau)``: the enclosure is refused (:class:`~nrobust.errors.CertificationError`)
unless both are the plant's own (e.g. ``lam = mu = 1``).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache
from typing import Any

import numpy as np

from ..._flint import precision, require_flint
from ...errors import CertificationError
from ...quasipoly import DistributedDelay
from ..kernels.constant import solve_kernels
from ..loops.controllers import ReflectionController, StateFeedback
from ..loops.exact_form import PRECISION, exact_form, has_exact_form
from ..loops.exact_gains import gain_kernel
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from .mismatch_gains import section_bounds
from .mismatch_proof import ball_upper

__all__ = ["CHEBYSHEV_DEGREE", "ChebyshevGain", "reflection_traces"]

#: Degree of the Chebyshev fits of the traces.
CHEBYSHEV_DEGREE = 24


@dataclass(frozen=True)
class ChebyshevGain:
    """``x -> sum_j c_j T_j(2 x - 1)`` on ``[0, 1]`` (Clenshaw's recurrence: arithmetic only, so it evaluates on
    arrays and on python-flint series alike)."""

    coefficients: tuple[float, ...]

    def __call__(self, x: Any) -> Any:
        y = 2 * x - 1
        b1: Any = 0.0
        b2: Any = 0.0
        for c in reversed(self.coefficients[1:]):
            b1, b2 = 2 * y * b1 - b2 + c, b1
        return y * b1 - b2 + self.coefficients[0]


def _fit(gain: Any) -> ChebyshevGain:
    """The Chebyshev interpolant of ``gain`` at ``CHEBYSHEV_DEGREE + 1`` Chebyshev points of ``[0, 1]``."""
    nodes = 0.5 * (1.0 + np.cos(np.pi * (np.arange(CHEBYSHEV_DEGREE + 1) + 0.5) / (CHEBYSHEV_DEGREE + 1)))
    coefs = np.polynomial.chebyshev.chebfit(2 * nodes - 1, np.asarray(gain(nodes), dtype=float), CHEBYSHEV_DEGREE)
    return ChebyshevGain(tuple(float(c) for c in coefs))


def _pieces(kernel: DistributedDelay) -> list[tuple[float, float, float, Any]]:
    """``(start, end, length, coefficients)`` of each piece of a polynomial kernel: ``N(start + length t) =
    sum_l c_l t^l`` on ``[start, end]`` (the nodes as stored, the length as the ball evaluation takes it)."""
    if kernel.moment != 0 or not np.array_equal(np.asarray(kernel.poly), [1.0]):
        raise CertificationError("a kernel with a polynomial factor or moment: not a kernel of the exact forms")
    start, h, coefs = kernel.pieces
    nodes = np.asarray(kernel.nodes, dtype=float)
    return [(float(a), float(b), float(w), c) for a, b, w, c in zip(start, nodes[1:], h, coefs)]


def _on(flint: Any, pieces: list[tuple[float, float, float, Any]], lo: float, hi: float, factor: float) -> Any:
    """``factor`` times the piece covering ``[lo, hi]`` as an ``arb_poly`` in ``t``, ``theta = lo + (hi - lo) t``."""
    arb, arb_poly = flint.arb, flint.arb_poly
    for a, b, h, c in pieces:
        if a <= lo and hi <= b:
            local = arb_poly([(arb(lo) - arb(a)) / arb(h), (arb(hi) - arb(lo)) / arb(h)])
            return arb_poly([arb(float(v)) * factor for v in c])(local)
    raise CertificationError("the kernels' pieces do not cover [0, tau]")


def _residual(flint: Any, fitted: DistributedDelay, K: float, u_tilde: DistributedDelay, n_tilde: Any) -> Any:
    """A bound of ``sup |K[h] - K U~ - N~|`` on ``[0, tau]`` (the module notes), the stored radii included."""
    arb = flint.arb
    parts = [(_pieces(fitted), 1.0), (_pieces(u_tilde), -K)]
    radius = arb(fitted.radius) + abs(arb(K)) * arb(u_tilde.radius)
    if n_tilde is not None:
        parts.append((_pieces(n_tilde), -1.0))
        radius += arb(n_tilde.radius)
    cuts = sorted({x for pieces, _ in parts for a, b, _, _ in pieces for x in (a, b)})
    sup = arb(0)
    for lo, hi in itertools.pairwise(cuts):
        diff = sum((_on(flint, pieces, lo, hi, f) for pieces, f in parts), flint.arb_poly(0))
        sup = arb.max(sup, sum((abs(c) for c in diff.coeffs()), arb(0)))  # |sum c_l t^l| <= sum |c_l| on [0, 1]
    return sup + radius


@lru_cache(maxsize=8)
def reflection_traces(system: Hyperbolic2x2, K: float, kernel_grid: int = 201) -> tuple[StateFeedback, float]:
    """``U_BS2(K)``'s law on ``system`` as a :class:`StateFeedback` with polynomial gains and the bound of their
    distance to the true gains (module notes).

    Parameters
    ----------
    system : Hyperbolic2x2
        The plant the law is designed for, with constant couplings (``has_exact_form``), ``q != 0``.
    K : float
        The reflection gain of eq. (53).
    kernel_grid : int, default 201
        Kernel grid of the traces that are fitted (the bound does not rest on it).

    Returns
    -------
    (StateFeedback, float)
        ``StateFeedback(-K, h_u, h_v)`` with :class:`ChebyshevGain` gains, and ``delta`` with
        ``|h_u - g_u|, |h_v - g_v| <= delta`` on ``[0, 1]``.

    Raises
    ------
    CertificationError
        A plant outside the closed form, ``q = 0``, a round trip or ``t_v`` that are not the plant's own
        doubles, or gains that cannot be enclosed.
    """
    if not has_exact_form(system) or system.uncoupled:
        raise CertificationError("the traces are enclosed on a coupled plant with the closed form only")
    if system.q == 0.0:
        raise CertificationError("q = 0: the Volterra equation of the traces is of the first kind")
    tau = system.tau
    ulp = math.ulp(tau)
    t_v = round((1.0 / system.mu) / ulp) * ulp
    exact_tau = 1 / Fraction(system.lam) + 1 / Fraction(system.mu)
    if Fraction(tau) != exact_tau or Fraction(t_v) != 1 / Fraction(system.mu):
        raise CertificationError(
            "the round trip 1/lam + 1/mu or the time of flight 1/mu of this plant is not a double: the Volterra "
            "identity of the exact forms holds for the rounded plant only"
        )
    law = ReflectionController(K).feedback_law(system, solve_kernels(system, kernel_grid))
    fitted_law = StateFeedback(-K, _fit(law.gain_u), _fit(law.gain_v))
    fitted = gain_kernel(system, fitted_law.g_u, fitted_law.g_v)
    form = exact_form(system)
    u_tilde = form.u_factor.distributed[0] if form.u_factor.distributed else None
    if fitted is None or u_tilde is None:
        raise CertificationError("the traces or U~ vanish: nothing to enclose")
    flint = require_flint()
    with precision(flint, PRECISION):
        arb = flint.arb
        residual = _residual(flint, fitted, K, u_tilde, form.N_tilde)
        P = arb(float(system.sigma_pm)) / arb(system.lam)  # type: ignore[arg-type]
        M = -arb(float(system.sigma_mp)) / arb(system.mu)  # type: ignore[arg-type]
        sec = section_bounds(flint, P, M, system.q)
        T, Tv = arb(tau), arb(t_v)
        c1 = arb.max(Tv, (T - Tv) / abs(arb(system.q)))
        c2 = (sec["U"][0] + sec["V"][0]) / T  # the sections U, V of exact_gains are the scaled ones over tau
        delta = c1 * residual * (c1 * c2).exp()
        return fitted_law, ball_upper(delta)
