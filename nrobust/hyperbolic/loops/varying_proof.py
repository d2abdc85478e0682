"""``N~`` of eq. (40) with a proven error bound for coefficients that vary with ``x``.

For the paper's plant (18)-(20) with constant ``lam, mu, q, rho`` and couplings
``sigma_pm(x)``, ``sigma_mp(x)`` given as functions, the characteristic route of
:mod:`~nrobust.hyperbolic.loops.varying_form` (``docs/theory.md``, "Varying speed ratio") has
``T(x) = tau x``, so ``x`` itself is the characteristic time in units of ``tau``. In the
coordinates ``A = (theta - nu) / tau``, ``V = nu / tau`` of the triangle
``A, V >= 0``, ``A + V <= 1`` (``A + V = x``), with ``k_r = sigma_pm / lam``,
``k_w = -sigma_mp / mu`` (the ``p, m`` of :mod:`~nrobust.hyperbolic.loops.exact_form`) and the
scaled unknowns ``F = tau f``, ``G = tau g``, the Goursat system is the Volterra system::

    F(A, V) = k_r(A)   + int_0^V k_r(A + S) G(A, S) dS,
    G(A, V) = q k_w(V) + int_0^A k_w(A' + V) F(A', V) dA',

and ``N~(nu) = (G - rho F)(1 - V, V) / tau`` at ``V = nu / tau`` (for constant couplings it is
the closed form of :mod:`~nrobust.hyperbolic.loops.exact_form`).

**The bound (a posteriori).** The couplings are Taylor models on ``[0, 1]``: a polynomial
``P_r`` (ball coefficients) with ``|k_r - P_r| <= eps_r`` and ``|k_r' - P_r'| <= eps_r'``,
from one call of ``sigma`` on a python-flint ``arb_series`` at ``x = 1/2`` (``x = 1/2 + t/2``,
the Taylor polynomial of order :data:`ORDER` - 1 in ``t``) and calls on 64 balls covering
``[0, 1]``, whose coefficients of ``t^ORDER`` bound the Lagrange remainder (and, times
``2 ORDER``, that of the derivative). Ball arithmetic overestimates that coefficient on a wide ball,
above all through ``x(y)`` of varying speeds (10^20 times its value on balls of width 1/64): each
ball's bound is the least of its ball value and of the coefficient's Taylor expansion about the ball's
centre to :data:`_SHIFT` terms (the coefficients at the exact centre are tight, the ball's enters as
the last term, times ``(2 r)^16``); a ball whose bound is still above ``2^-44`` of the sum of the
model's ``|coefficients|`` is halved, largest bound first, up to :data:`_TOP_DEPTH` times, while its
halves bound it at least twice tighter. The model must agree with the
coupling evaluated on arrays at 17 points of ``[0, 1]`` (a function that acts differently on balls is
refused). A Picard iteration in floating point gives polynomials ``F^, G^`` of total degree ``n`` (the first of
:data:`DEGREES` whose bound is small enough; for varying speeds a screening pass with the models' remainders
taken as 0 finds that degree, or the refusal, before the remainders are bounded). The integrals raise the total
degree by one, so the iteration is done once, degree by degree, in the basis ``b_ij = C(i + j, i) A^i V^j`` (at
most 1 on the triangle), where multiplying by ``A + V`` makes convex combinations of coefficients and integrating
divides them by ``i + j + 1``: each rounding is relative to the coefficients it combines (the monomial coefficients
of a function of size 1 on the triangle reach ``C(n, n/2)``, ``10^37`` at ``n = 128``, and products by FFT, whose
error is relative to the largest coefficient, swamped the small ones). Their residual
``R = T(F^, G^) - (F^, G^)`` (``T`` the right-hand sides with the true couplings) is the
polynomial ``T_P(F^, G^) - (F^, G^)`` computed exactly in ball arithmetic, plus the models'
remainders, ``|R_F| <= eps_r (1 + sup |G^|)`` and
``|R_G| <= eps_w (|q| + sup |F^|)``. The error ``E = (F, G) - (F^, G^)`` solves ``E = R + L E``,
``L`` the linear part of ``T``; the integrals of ``L`` at a point with ``A + V = x`` run once
over points with ``A + V`` from ``0`` to ``x``, so with ``m(x)`` the largest ``|E|`` on
``A + V <= x`` and ``C = max(sup |k_r|, sup |k_w|)``, ``m(x) <= sup |R| + C int_0^x m``, and by
Gronwall's lemma::

    |E| <= M = sup |R| e^C.

Differentiating the Volterra system gives the derivatives of ``E``:
``|d_V E_F| <= sup |d_V R_F| + C M``, ``|d_A E_G| <= sup |d_A R_G| + C M``,
``|d_A E_F| <= sup |d_A R_F| + C' M + C (sup |d_A R_G| + C M)`` and the same with ``F, G``,
``A, V`` exchanged, ``C' = max(sup |k_r'|, sup |k_w'|)``. Along ``A = 1 - V``,
``|N~ - N^| <= (1 + |rho|) M / tau`` and the total variation of ``N~ - N^`` on ``[0, tau]`` is at
most ``sup |(d_V - d_A)(E_G - rho E_F)| / tau``. The sups of polynomials on the triangle are
bounded by ``sum |c_ij| i^i j^j / (i + j)^(i + j)`` (the largest ``A^i V^j`` there), those of
univariate polynomials on ``[0, 1]`` (the couplings, the kernels along ``A = 1 - V``, whose monomial coefficients
reach ``10^10`` for a kernel of size 1) on 64 balls, each after an exact Taylor shift to its centre.
``N^`` is then stored as polynomial pieces by
:func:`~nrobust.hyperbolic.loops.exact_form.expand_piece` (the rounding of each piece added to
the bounds): a ball enclosure built on it holds for the PDE itself.

**General plants.** A :class:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2` with
constant ``lam, mu`` (numbers) and ``a, b, c, d`` numbers or functions is proven through its
normal form (:mod:`~nrobust.hyperbolic.plants.general`) enclosed rigorously instead of
tabulated: with ``x = L y`` (the space change is linear for constant speeds),
``alpha = L a / lam`` and ``delta = -L d / mu`` are Taylor models as above, and
``A(L y) = int_0^y alpha``, ``D(L y) = int_0^y delta`` their exact integrals within
``e_E = eps_alpha + eps_delta`` (the derivative of the error of ``E = D - A`` within ``e_E``
too). The balance ``k`` is read as ``log(q / q~)``, ``q~`` the normal form's double, so ``q~``
and ``e^{-k} = q~ / q`` are exact. Then ``k_r = (L / lam) b e^{E} e^{-k}`` and
``k_w = -(L / mu) c e^{-E} e^{k}`` are Taylor models of the function with ``E`` replaced by its
polynomial, evaluated on ``arb_series`` and checked against the normal form's tabulated
couplings, their remainders grown by ``sup |P| (e^{e_E} - 1)`` (and
``sup |P'| (e^{e_E} - 1) + sup |P| e_E e^{e_E}`` for the derivative);
``rho~ = rho e^{-E(L)} e^{k}`` is a ball whose radius enters the residual and the pieces of
``N~``. ``U~`` is returned in the plant's coordinates, times the ball ``e^{A(L) + k - D(L)}``, so a
feedback ``U = k u(t, L)`` closes the loop with ``B = -k u_factor``. What stays a double: ``tau``,
the double ``(L / lam + L / mu) / time_unit`` computed in floating point, and the principal gains
``q e^{A(L) - D(L)}`` and ``rho q e^{A(L) - D(L)}`` (rounded to nearest from their enclosures,
so the proof is of the plant with these values, relative changes of ``2^-53``). Coefficients
given as samples (the cubic spline is the model the user gave) are refused with a reason
(:func:`varying_failure`): the kernel route, a model.

**Varying speeds.** Speeds ``lam(x)``, ``mu(x)`` given as functions (any ratio) are made constant
along the characteristics by ``y = T(x) / T(L)``, ``T = int_0^x 1/lam + 1/mu`` the round-trip
time: in ``theta = T(x)`` the characteristic system of
:mod:`~nrobust.hyperbolic.loops.varying_form` (``f`` along diagonals, ``g`` along rows, diagonal
terms ``p = dA/dtheta``, ``e = dD/dtheta``) becomes, with ``f = e^{A} f~``, ``g = e^{D} g~`` (the
diagonal terms removed by the same exponents as the normal form's), the Volterra system above
with ``A = (theta - nu) / T(L)``, ``V = nu / T(L)`` and, at ``x(y)``::

    alpha = s_u a,   delta = -s_v d,   k_r = s_u b e^{E} e^{-k},   k_w = -s_v c e^{-E} e^{k},
    s_u = T(L) mu / (lam + mu),   s_v = T(L) lam / (lam + mu)

(for constant speeds ``s_u = L / lam``, ``s_v = L / mu``; for a constant ratio this is the normal
form's ``y = phi(x) / phi(L)``), and ``N~``, ``U~`` as above: the proof applies unchanged. What is
new is ``x(y)`` in ball arithmetic. The slowness ``L (1/lam + 1/mu)(L xi)`` is a Taylor model on
each of ``m`` equal pieces of ``[0, 1]`` (as the couplings above, remainder ``eps_j``; ``m`` doubles
from 1 up to 16 until ``T(L)`` is far below double precision), so on the piece ``[a_j, a_j + h]``
``T(L (a_j + h u)) = C_j + Phi_j(u) + e_j(u)``, ``Phi_j`` the model's exact integral, ``|e_j(u)| <= eps_j u``
and ``C_j`` the ball of ``T(L a_j)`` (from the pieces before), and ``T(L)`` is a ball. A ball ``y`` maps
to the ball ``x(y)`` between two points at which ``C_j + Phi_j(u) -+ eps_j u`` is proven below or above
``T(L) y`` (``T`` increases), found by Newton's method on ``Phi_j``. The Taylor coefficients of
``x(Y(t))`` for an arb_series ``Y`` follow from ``dx/dy = T(L) / (1/lam + 1/mu)(x)`` by Picard
passes on series (the ``k``-th fixes the coefficient of ``t^k``; ball arithmetic encloses them for
every ``y`` of ``Y``'s constant ball). A coefficient at ``x(y)`` times its weight is then a
function of ``y`` evaluated on an arb_series and modelled as above. The balance ``k`` is the
normal form's for a constant ratio, else the mid-range of ``D - A`` likewise (read as
``log(q / q~)``, ``q~`` a double). ``tau`` is the double nearest the ball ``T(L) / time_unit``:
the plant proven has both speeds times ``T(L) / (tau time_unit)``, a factor within about
``2^-53`` of 1 that :attr:`VaryingProof.assumption` bounds and the proof's scope quotes. On a
varying ratio the loop route serves the laws the characteristic route serves (not U_BS2(K),
defined on the normal form). A speed without ball evaluation, or whose ``1/lam + 1/mu`` or
``x(y)`` is not analytic on a disc about ``[0, 1]`` wide enough for one model of order
:data:`ORDER`, has no proof.

A coupling that fails on ``arb_series`` (comparisons, conversions to float, ...), is not
analytic on a disc about ``[0, 1]`` large enough for one model of order :data:`ORDER` to reach
double precision, or a coupling too strong for :data:`DEGREES` has no proof:
:func:`varying_failure` says why and the kernel route (a model of the PDE) is used.
"""

from __future__ import annotations

import heapq
import itertools
import math
from fractions import Fraction
from functools import lru_cache
from typing import Any, NamedTuple

import numpy as np

from ..._digits import upper_bound_text
from ..._flint import ball_upper, precision, require_flint
from ...errors import CertificationError, ParameterError
from ...quasipoly import DistributedDelay, QuasiPolynomial
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from .exact_form import MAX_PIECES, TARGET, ball_radius, expand_piece

__all__ = ["DEGREES", "ORDER", "VaryingProof", "has_varying_proof", "varying_failure", "varying_proof"]

#: Order of the Taylor model of each coupling on ``[0, 1]``.
ORDER = 40
#: Total degrees of the polynomials ``F^, G^`` of the Picard iteration, tried in turn.
DEGREES = (56, 96, 128)
# Working precision (bits) of the residual (the monomial coefficients of F^, G^ reach C(128, 64) < 2^124).
_PRECISION = 192
# Relative agreement asked of the ball model with the coupling evaluated on arrays at _CHECK_POINTS.
_AGREEMENT = 1e-8
# Largest residual accepted, relative to the size of N~ (beyond it the proof would say little); at the
# last degree also an absolute one (the loop's constant term is 1: a tiny kernel's rounding floor).
_RESIDUAL = 2.0**-27
# Balls covering [0, 1] on which the coefficient of order ORDER of a coupling's model is bounded.
_TOP_BALLS = 64
# Most halvings of a top ball whose bound is far above the model's size.
_TOP_DEPTH = 5
# Terms of the Taylor expansion about a top ball's centre of the coefficient bounding the remainder.
_SHIFT = 16
# Points at which a coupling's model must agree with its values on arrays (and which key the cache).
_CHECK_POINTS = np.linspace(0.0, 1.0, 17)
# Most pieces of [0, L] on which 1/lam + 1/mu is modelled for the map y = T(x)/T(L) (a power of 2).
_MAP_PIECES = 16
# Balls covering [0, 1] in the bounds of univariate polynomials.
_SUP_BALLS = 64
# The in-domain coefficients of a general plant.
_GENERAL = ("a", "b", "c", "d")


class VaryingProof:
    """``N~`` and ``U~`` of a plant with varying couplings, with proven error bounds (module notes).

    Attributes
    ----------
    tau, q, rho_q : float
        The round trip ``1/lam + 1/mu`` (for a general plant with constant speeds the double nearest
        ``(L/lam + L/mu) / time_unit``; with varying speeds the double nearest the ball
        ``int_0^L (1/lam + 1/mu) / time_unit``, the speeds of the plant proven scaled to make it exact:
        ``assumption``), ``q`` of the normal form and the principal gain ``rho q`` (``rho q e^{A(L) - D(L)}``
        rounded to a double for a general plant).
    rho_q_radius, u_radius : float
        Proven bounds of ``|rho_q - rho q e^{A(L) - D(L)}|`` and of the distance of ``u_factor``'s point
        coefficient to ``q e^{A(L) - D(L)}`` (``e^{A(L) - D(L)} = 1`` for a :class:`Hyperbolic2x2`): the
        radii of the point coefficients of ``characteristic`` and ``u_factor``.
    N_tilde, U_tilde : DistributedDelay or None
        Polynomial pieces (None: zero); ``radius`` and ``variation_radius`` bound the distance
        to the PDE's kernels (sup and total variation). ``U~ = f(tau, .)``: the
        ``u`` row of the fundamental matrix applied to ``[q; 1]``, as for the closed form (in
        the plant's own coordinates for a general plant).
    characteristic : QuasiPolynomial
        ``1 - rho q e^{-tau s} + int_0^tau N~(nu) e^{-nu s} dnu``, the open loop.
    assumption : str
        For varying speeds, what the plant proven takes that the plant given may not be exactly (the
        speeds' factor making ``tau`` a double, module notes "Varying speeds"); ``""`` otherwise.
    u_factor : QuasiPolynomial
        ``e^{-s t_v} u(1, s)`` normalised as the characteristic function:
        ``q e^{-tau s} + int_0^tau U~(nu) e^{-nu s} dnu`` (``q e^{A(L) - D(L)}`` rounded to a
        double for a general plant: a proportional feedback ``U = k u(t, L)`` closes the loop
        with ``B = -k u_factor``).
    """

    __slots__ = (
        "N_tilde",
        "U_tilde",
        "assumption",
        "characteristic",
        "q",
        "rho_q",
        "rho_q_radius",
        "tau",
        "u_factor",
        "u_radius",
    )

    def __init__(
        self,
        tau: float,
        q: float,
        rho_q: float,
        N_tilde: DistributedDelay | None,
        U_tilde: DistributedDelay | None,
        u_point: float | None = None,
        assumption: str = "",
        radii: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        self.tau, self.q, self.rho_q, self.N_tilde, self.U_tilde = tau, q, rho_q, N_tilde, U_tilde
        self.assumption = assumption
        self.rho_q_radius, self.u_radius = radii
        self.characteristic = QuasiPolynomial(
            [[1.0], [-rho_q]],
            [0.0, tau],
            [N_tilde] if N_tilde is not None else [],
            radii=[[0.0], [self.rho_q_radius]] if self.rho_q_radius else None,
        )
        point = q if u_point is None else u_point
        self.u_factor = QuasiPolynomial(
            [[point]],
            [tau],
            [U_tilde] if U_tilde is not None else [],
            radii=[[self.u_radius]] if self.u_radius else None,
        )


def has_varying_proof(system: object) -> bool:
    """True for a plant with coefficients given as functions whose ``N~`` is proven.

    A :class:`Hyperbolic2x2` with a coupling given as a function, or a
    :class:`~nrobust.hyperbolic.plants.general.GeneralHyperbolic2x2` with one of ``a, b, c, d`` a
    function (module notes, "General plants") or speeds given as functions (module notes,
    "Varying speeds").
    """
    if isinstance(system, Hyperbolic2x2) and system.constant_couplings:
        return False
    if isinstance(system, GeneralHyperbolic2x2) and all(system.is_constant(k) for k in ("lam", "mu", *_GENERAL)):
        return False
    return isinstance(system, (Hyperbolic2x2, GeneralHyperbolic2x2)) and varying_failure(system) is None


def varying_failure(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> str | None:
    """Why :func:`varying_proof` cannot prove ``N~`` of this plant (None when it can)."""
    out = _attempt(system)
    return out if isinstance(out, str) else None


def varying_proof(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> VaryingProof:
    """``N~`` of a plant with couplings that vary with ``x``, with a proven error (module notes).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The paper's plant, constant speeds, ``sigma_pm`` and ``sigma_mp`` numbers or functions
        of ``x`` on ``[0, 1]`` that python-flint's ``arb_series`` can evaluate; or a general
        plant with ``a, b, c, d``, ``lam, mu`` numbers or such functions on ``[0, L]``.

    Returns
    -------
    VaryingProof

    Raises
    ------
    ParameterError
        Not a :class:`Hyperbolic2x2` or :class:`GeneralHyperbolic2x2`.
    CertificationError
        A coefficient that cannot be enclosed (samples, no ball arithmetic),
        or a residual too large to be useful (:func:`varying_failure` gives the reason).
    """
    out = _attempt(system)
    if isinstance(out, str):
        raise CertificationError(out)
    return out


def _attempt(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> VaryingProof | str:
    """The proof, or why there is none (cached for hashable plants: routes ask several times)."""
    if isinstance(system, GeneralHyperbolic2x2):
        reason = _general_failure(system)
        if reason is not None:
            return reason
        # the coefficients' values at the check points key the cache, as the couplings' below
        points = system.length * _CHECK_POINTS
        key = tuple(float(v) for name in ("lam", "mu", *_GENERAL) for v in system.coefficient(name, points))
        return _attempt_cached(system, key)
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 (constant speeds) or GeneralHyperbolic2x2", system)
    try:
        hash(system)
    except TypeError:
        return _attempt_uncached(system)
    # the couplings' values at the check points join the key: a function that reads a
    # variable the user changed since is a new plant (equal plants share function objects)
    values = (system.sigma_pm_at(_CHECK_POINTS), system.sigma_mp_at(_CHECK_POINTS))
    key = tuple(float(v) for array in values for v in np.broadcast_to(array, _CHECK_POINTS.shape))
    return _attempt_cached(system, key)


def _general_failure(system: GeneralHyperbolic2x2) -> str | None:
    """Why a general plant is outside the proof before any enclosure is tried (None: it is not)."""
    for name in ("lam", "mu", *_GENERAL):
        if isinstance(getattr(system, name), tuple):
            kind = "speed" if name in ("lam", "mu") else "coefficient"
            return (
                f"the {kind} {name} is given as samples: its cubic spline is the model of the plant, which "
                "the kernel route (kernel_grid=...) takes"
            )
    return None


@lru_cache(maxsize=16)
def _attempt_cached(system: Hyperbolic2x2 | GeneralHyperbolic2x2, values: tuple[float, ...]) -> VaryingProof | str:
    return _attempt_uncached(system)


def _attempt_uncached(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> VaryingProof | str:
    try:
        return _proof(system)
    except CertificationError as exc:
        return str(exc)


# --------------------------------------------------------------------------- coupling models


def _on_series(flint: Any, value: Any, series: Any, name: str) -> Any:
    """``value`` (a number or a user's callable on arrays) at one arb_series, as an arb_series of its length."""
    arb, arb_series = flint.arb, flint.arb_series
    what = f"the speed {name}" if name in ("lam", "mu") else f"the coupling {name}"
    if not callable(value):
        return arb_series([arb(float(value))], prec=series.prec)
    holder = np.empty(1, dtype=object)
    holder[0] = series
    cap = flint.ctx.cap
    flint.ctx.cap = series.prec  # series functions truncate at the global cap
    try:
        out = value(holder)
    except Exception as exc:  # a user's callable may raise anything on an object array: no model
        raise CertificationError(
            f"{what} cannot be evaluated in ball arithmetic (on a python-flint arb_series: {exc})"
        ) from None
    finally:
        flint.ctx.cap = cap
    if isinstance(out, np.ndarray) and out.size == 1:
        out = out.reshape(-1)[0]
    if isinstance(out, (int, float)) and not isinstance(out, bool):
        out = arb(float(out))
    if isinstance(out, arb):  # constant in x
        out = arb_series([out], prec=series.prec)
    if not isinstance(out, arb_series):
        raise CertificationError(f"{what} cannot be evaluated in ball arithmetic (it gave {type(out).__name__})")
    if out.prec < series.prec:
        raise CertificationError(f"{what} gave a series truncated before the order {series.prec - 1}")
    return out


def _model(flint: Any, value: Any, at: Any, scale: Any, name: str, remainder: bool = True) -> tuple[Any, Any, Any]:
    """``(P, eps, eps')`` of ``scale * value`` on ``[0, 1]`` (``scale`` a ball), ``P`` an arb_poly in ``x``.

    ``remainder=False``: ``eps = eps' = 0``, the screening pass of :func:`_proof` (the bound of the remainder,
    on balls halved where ball arithmetic overestimates it, is most of a varying-speed proof's time).
    """
    arb, arb_poly, arb_series = flint.arb, flint.arb_poly, flint.arb_series
    if not callable(value):
        return arb_poly([arb(float(value)) * scale]), arb(0), arb(0)

    def call(centre: Any, length: int = ORDER + 1) -> list[Any]:
        out = _on_series(flint, value, arb_series([centre, arb(0.5)], prec=length), name)
        coefs = list(out.coeffs())[:length]
        coefs += [arb(0)] * (length - len(coefs))
        return coefs

    head = call(arb(0.5))[:ORDER]
    # the remainder's coefficient is worth bounding more tightly (smaller balls) down to this size
    goal = sum((abs(c) for c in head), arb(0)) * 2.0**-44 + 2.0**-64

    def own(centre: float, radius: float) -> Any:
        """An exact upper bound of ``|c_ORDER(xi)|`` (the coefficient of ``t^ORDER`` at the centre ``xi``,
        ``x = xi + t/2``) for every ``xi`` of the ball: the least of its ball value and of its Taylor expansion
        about the centre, ``sum_{m < S} C(ORDER + m, m) |c_(ORDER + m)(centre)| (2 r)^m`` plus the same term at
        ``m = S`` on the ball (``S`` :data:`_SHIFT`; two calls): the coefficients at the exact centre are tight
        where ball arithmetic's overestimation on a wide ball (varying speeds' ``x(y)``) reaches 10^20 times
        the true coefficient, and the ball's enters only times ``(2 r)^S``."""
        wide = radius + 2.0**-30 * radius
        ball = call(arb(centre, wide), ORDER + _SHIFT + 1)
        if bool(abs(ball[ORDER]) < goal):  # tight enough: the expansion is not needed
            return abs(ball[ORDER]).upper()
        point = call(arb(centre), ORDER + _SHIFT + 1)
        step = 2 * arb(wide)
        shifted = arb(math.comb(ORDER + _SHIFT, _SHIFT)) * abs(ball[ORDER + _SHIFT]) * step**_SHIFT
        for m in range(_SHIFT):
            shifted += arb(math.comb(ORDER + m, m)) * abs(point[ORDER + m]) * step**m
        return arb.min(abs(ball[ORDER]), shifted).upper()

    # sup of the coefficient of t^ORDER over [0, 1], from balls covering it (less overestimation than one ball),
    # best first: the ball of the largest bound is halved (up to _TOP_DEPTH times) while that at least halves
    # its bound (ball arithmetic's overestimation: a wide ball of x(y) for varying speeds, module notes) and the
    # bound is above the goal; the sup is the largest bound once that ball cannot be refined.
    order = itertools.count()
    cover: list[tuple[float, int, Any, float, float, int, bool]] = []

    def push(out: Any, centre: float, radius: float, depth: int, final: bool) -> None:
        key = float(out.upper()) if out.is_finite() else math.inf
        heapq.heappush(cover, (-key, next(order), out, centre, radius, depth, final))

    for k in range(_TOP_BALLS if remainder else 0):
        centre, radius = (2 * k + 1) / (2 * _TOP_BALLS), 1 / (2 * _TOP_BALLS)
        push(own(centre, radius), centre, radius, 0, False)
    while cover:
        _, _, out, centre, radius, depth, final = cover[0]
        if final or depth == _TOP_DEPTH or not out.is_finite() or bool(out < goal):
            break
        heapq.heappop(cover)
        halves = [(centre + side * radius / 2, radius / 2) for side in (-1, 1)]
        bounds = [own(c, r) for c, r in halves]
        largest = arb.max(*bounds)
        if not bool(2 * largest < out):  # halving does not tighten it: not ball arithmetic's overestimation
            push(largest if bool(largest < out) else out, centre, radius, depth, True)
        else:
            for (c, r), b in zip(halves, bounds):
                push(b, c, r, depth + 1, False)
    top = arb(0)
    for entry in cover:
        top = arb.max(top, entry[2])
    if not (all(c.is_finite() for c in head) and top.is_finite()):
        raise CertificationError(f"the coupling {name} is not enclosed by finite balls on [0, 1] (not analytic there)")
    # x = 1/2 + t/2: the model in t, then in x (t = 2 x - 1); the remainder is |top| |t|^ORDER.
    model = arb_poly(head)(arb_poly([-1, 2]))
    floating = np.asarray(at(_CHECK_POINTS), dtype=float)
    for x, f in zip(_CHECK_POINTS, floating):
        ball = model(arb(float(x)))
        slack = _AGREEMENT * (1.0 + abs(f)) + float(ball.rad()) + float(abs(top).upper())
        if not abs(f - float(ball.mid())) <= slack:
            raise CertificationError(
                f"the coupling {name} gives {float(ball.mid())!r} on balls and {float(f)!r} on arrays at x = {x:g}"
            )
    poly = model * scale
    eps = abs(top) * abs(scale)
    return poly, eps, 2 * ORDER * eps


# --------------------------------------------------------------------------- bivariate polynomials


def _raise(u: np.ndarray) -> np.ndarray:
    """``(A + V) u`` for the coefficients ``u[i]`` of a homogeneous part of degree ``m = len(u) - 1`` in the basis
    ``b_ij = C(i + j, i) A^i V^j``: ``(A + V) b_ij = ((i + 1) b_(i+1,j) + (j + 1) b_(i,j+1)) / (m + 1)``, each new
    coefficient a convex combination of two old ones."""
    m = len(u) - 1
    weight = np.arange(m + 2) / (m + 1)
    out = np.zeros(m + 2)
    out[1:] = u * weight[1:]
    out[:-1] += u * weight[::-1][:-1]
    return out


def _times(p: np.ndarray, parts: list[np.ndarray], k: int) -> np.ndarray:
    """The part of degree ``k`` of ``P(A + V) H`` (``p`` the coefficients of ``P(x)``, ``parts[m]`` those of ``H``'s
    part of degree ``m`` in the basis of :func:`_raise`), by Horner's rule:
    ``sum_l p_l (A + V)^l H_(k - l)``."""
    low = max(0, k - len(p) + 1)
    out = p[k - low] * parts[low]
    for m in range(low + 1, k + 1):
        out = _raise(out) + p[k - m] * parts[m]
    return out


def _picard(kr: np.ndarray, kw: np.ndarray, q: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``F^, G^`` of total degree ``n``: the Volterra system's Picard iteration in floating point (module notes).

    The integrals raise the total degree by one, so the part of degree ``k`` of ``F, G`` is fixed by the parts
    below it: the iteration is done once, degree by degree. The parts are held in the basis
    ``b_ij = C(i + j, i) A^i V^j`` (at most 1 on the triangle; the monomial coefficients of an ``O(1)`` function
    there are up to ``C(n, n/2)`` times larger), in which ``(A + V) b_ij`` is a convex combination
    (:func:`_raise`) and ``int_0^V b_ij dS = b_(i,j+1) / (i + j + 1)``, ``int_0^A b_ij dA' = b_(i+1,j) / (i + j + 1)``:
    each rounding is relative to the coefficients it combines, not to the largest one.
    Returns the monomial coefficients ``c[i, j]`` of ``A^i V^j``.
    """
    f: list[np.ndarray] = []
    g: list[np.ndarray] = []
    with np.errstate(all="ignore"):  # an overflow is caught below
        for k in range(n + 1):
            f_k, g_k = np.zeros(k + 1), np.zeros(k + 1)
            f_k[k] = kr[k] if k < len(kr) else 0.0  # k_r(A)
            g_k[0] = q * kw[k] if k < len(kw) else 0.0  # q k_w(V)
            if k:
                f_k[:-1] += _times(kr, g, k - 1) / k  # int_0^V k_r(A + S) G(A, S) dS
                g_k[1:] += _times(kw, f, k - 1) / k  # int_0^A k_w(A' + V) F(A', V) dA'
            f.append(f_k)
            g.append(g_k)
    F, G = np.zeros((n + 1, n + 1)), np.zeros((n + 1, n + 1))
    for k in range(n + 1):
        i = np.arange(k + 1)
        binomial = np.array([float(math.comb(k, int(j))) for j in i])
        F[i, k - i], G[i, k - i] = f[k] * binomial, g[k] * binomial
    if not (np.all(np.isfinite(F)) and np.all(np.isfinite(G))):
        raise CertificationError(
            f"the kernel equations' Picard iteration overflows at degree {n} (couplings too strong, or models with "
            "huge monomial coefficients on [0, 1]); the kernel route (kernel_grid=...) gives a model of the PDE"
        )
    return F, G


class _Bi:
    """Bivariate polynomials in ball arithmetic: ``A^i V^j`` at ``y^(i + K j)`` of an arb_poly (Kronecker)."""

    def __init__(self, flint: Any, n: int) -> None:
        self.flint = flint
        self.K = n + ORDER + 2  # above the degree in A of every product formed (total degree n)

    def from_array(self, c: np.ndarray) -> Any:
        coefs = [0.0] * (self.K * c.shape[1])
        for i, j in zip(*np.nonzero(c)):
            coefs[i + self.K * j] = float(c[i, j])
        return self.flint.arb_poly(coefs)

    def shifted(self, p: Any) -> Any:
        """``P(A + V)`` from the arb_poly ``P(x)``."""
        y = [0] * (self.K + 1)
        y[1] = y[self.K] = 1
        return p(self.flint.arb_poly(y))

    def terms(self, p: Any) -> dict[tuple[int, int], Any]:
        out = {}
        for n, c in enumerate(p.coeffs()):
            if not c.is_zero():
                out[(n % self.K, n // self.K)] = c
        return out

    def from_terms(self, terms: dict[tuple[int, int], Any]) -> Any:
        arb = self.flint.arb
        size = 1 + max((i + self.K * j for i, j in terms), default=0)
        coefs = [arb(0)] * size
        for (i, j), c in terms.items():
            coefs[i + self.K * j] = c
        return self.flint.arb_poly(coefs)

    def integrate(self, p: Any, axis: int) -> Any:
        arb = self.flint.arb
        return self.from_terms(
            {(i + 1 - axis, j + axis): c / arb(j + 1 if axis else i + 1) for (i, j), c in self.terms(p).items()}
        )

    def derivative(self, p: Any, axis: int) -> Any:
        return self.from_terms(
            {
                (i - 1 + axis, j - axis): c * (j if axis else i)
                for (i, j), c in self.terms(p).items()
                if (j if axis else i)
            }
        )

    def sup(self, p: Any) -> Any:
        """A bound of ``|P|`` on the triangle ``A, V >= 0, A + V <= 1``."""
        arb = self.flint.arb
        total = arb(0)
        for (i, j), c in self.terms(p).items():
            n = i + j
            peak = arb(1) if 0 in (i, j) else (arb(i) ** i * arb(j) ** j) / arb(n) ** n
            total += abs(c) * peak
        return total


# --------------------------------------------------------------------------- varying speeds


class _SpeedMap:
    """``x(y)`` of a general plant whose speeds vary with ``x`` (module notes, "Varying speeds").

    ``y = T(x) / T(L)``, ``T = int_0^x 1/lam + 1/mu``, on ``m`` equal pieces ``[a_j, b_j]`` of
    ``[0, 1]`` in ``xi = x / L``: ``T(L (a_j + h u)) = C_j + Phi_j(u) + e_j(u)``, ``Phi_j`` the exact
    integral of the Taylor model of the slowness ``L h (1/lam + 1/mu)`` on the piece, ``|e_j(u)| <= eps_j u``
    and ``C_j`` the ball of ``T(L a_j)``; ``m`` doubles (up to :data:`_MAP_PIECES`) until the map's
    enclosure is far below double precision (its width is the width of every Taylor coefficient's ball).
    ``total`` is the ball ``T(L)``. :meth:`x_of` gives the Taylor coefficients of ``x(Y(t))`` for an
    arb_series ``Y`` (all ``y`` in its constant ball at once) from ``dx/dy = T(L) / (1/lam + 1/mu)(x)``.
    """

    def __init__(self, flint: Any, g: GeneralHyperbolic2x2) -> None:
        arb = flint.arb
        self.flint, self.g, self.L = flint, g, arb(g.length)
        pieces = 1
        while True:
            self.pieces: list[tuple[Any, Any, Any, Any]] = []
            for j in range(pieces):  # each piece starts at the ball T(L a_j) of those before it
                self.pieces.append(self._piece(j, pieces))
            if bool(self.total.rad() < 2.0**-150 * self.total.mid()) or 2 * pieces > _MAP_PIECES:
                break
            pieces *= 2
        if not bool(self.total.rad() < _RESIDUAL * 2.0**-26 * self.total.mid()):
            raise CertificationError(
                f"the speeds' 1/lam + 1/mu is not within double precision of Taylor models of order {ORDER} on "
                f"{pieces} pieces of [0, L] (T(L) within {float(self.total.rad()):.1e}): the kernel route "
                "(kernel_grid=...) gives a model of the PDE"
            )
        self.cache: dict[tuple[tuple[float, ...], int], Any] = {}

    @property
    def total(self) -> Any:
        """The ball ``T(L)``."""
        start, _, Phi, eps = self.pieces[-1]
        return start + Phi(self.flint.arb(1)) + self.flint.arb(0, ball_upper(eps))

    def _piece(self, j: int, pieces: int) -> tuple[Any, Any, Any, Any]:
        """``(C_j, P_j, Phi_j, eps_j)`` of the piece ``j`` of ``pieces`` (``C_j`` from the pieces before)."""
        flint, g, L = self.flint, self.g, self.L
        arb, length = flint.arb, g.length
        h, a = arb(1) / pieces, arb(j) / pieces  # exact: pieces is a power of 2

        def slowness(u: Any) -> Any:
            return self.slowness((a + h * u.reshape(-1)[0]) * L) * L * h

        def slowness_at(u: Any) -> Any:
            x = length * (j + np.asarray(u)) / pieces
            return length / pieces * (1.0 / g.coefficient("lam", x) + 1.0 / g.coefficient("mu", x))

        P, eps, _ = _model(flint, slowness, slowness_at, arb(1), "lam, mu")
        start = arb(0) if j == 0 else self.total  # self.pieces holds the pieces before j
        return start, P, P.integral(), eps

    def slowness(self, X: Any) -> Any:
        """``1/lam + 1/mu`` at the arb_series ``X`` (of ``x``)."""
        flint, g = self.flint, self.g
        return 1 / _on_series(flint, g.lam, X, "lam") + 1 / _on_series(flint, g.mu, X, "mu")

    def _at(self, xi: Any) -> tuple[Any, Any]:
        """The ball ``T(L xi)`` and ``dT/dxi`` (centre) at an exact ``xi`` of ``[0, 1]``."""
        arb = self.flint.arb
        m = len(self.pieces)
        j = min(m - 1, int(float((xi * m).floor())))  # exact: m is a power of 2, so u = m xi - j lies in [0, 1]
        start, P, Phi, eps = self.pieces[j]
        u = xi * m - j
        return start + Phi(u) + arb(0, ball_upper(eps * abs(u))), (P(u) * m).mid()

    def _inverse(self, y: Any, side: int) -> Any:
        """``xi`` with ``T(L xi)`` proven below (``side = -1``) or above (``+1``) ``T(L) y`` (``y`` exact)."""
        arb = self.flint.arb
        if (side < 0 and y <= 0) or (side > 0 and y >= 1):
            return arb(0 if side < 0 else 1)
        target = self.total * y
        xi = y
        for _ in range(60):  # Newton at the working precision on the centres
            value, slope = self._at(xi)
            step = ((value.mid() - target.mid()) / slope).mid()
            xi = arb.max(arb(0), arb.min(arb(1), (xi - step).mid()))
            if abs(float(step)) < 2.0**-170:
                break
        gap = 2.0**-170
        while gap < 2.0**-8:
            point = arb.max(arb(0), arb.min(arb(1), xi + side * gap))
            value, _ = self._at(point)
            if bool(value > target) if side > 0 else bool(value < target):
                return point
            gap *= 256.0
        raise CertificationError("the map y = T(x)/T(L) of the speeds could not be inverted in ball arithmetic")

    def x_ball(self, y: Any) -> Any:
        """A ball holding ``x(y')`` for every ``y'`` of the ball ``y`` within ``[0, 1]``."""
        low, high = self._inverse(y.lower(), -1), self._inverse(y.upper(), 1)
        return self.L * low.union(high)

    def x_of(self, Y: Any) -> Any:
        """``x(Y(t))`` as an arb_series of the length of ``Y`` (Picard: the ``k``-th pass fixes ``t^k``)."""
        flint = self.flint
        coefs = Y.coeffs()
        key = tuple(float(v) for c in coefs for v in (c.mid(), c.rad()))
        exact = all(c.mid() == flint.arb(float(c.mid())) for c in coefs)
        if exact and (key, Y.prec) in self.cache:
            return self.cache[(key, Y.prec)]
        x0 = self.x_ball(coefs[0])
        cap = flint.ctx.cap
        try:
            flint.ctx.cap = Y.prec  # series arithmetic truncates at the global cap
            slope = list((Y.derivative() * self.total).coeffs())
            X = flint.arb_series([x0], prec=1)
            for length in range(2, Y.prec + 1):  # X right to t^(length - 2): the pass makes it right to t^(length - 1)
                flint.ctx.cap = length
                X = flint.arb_series(list(X.coeffs()), prec=length)
                X = x0 + (flint.arb_series(slope[:length], prec=length) / self.slowness(X)).integral()
        finally:
            flint.ctx.cap = cap
        if exact:
            self.cache[(key, Y.prec)] = X
        return X


# --------------------------------------------------------------------------- the proof


class _Setup(NamedTuple):
    """What the proof needs of a plant: the models of ``k_r, k_w`` and the boundary gains as balls."""

    model_r: tuple[Any, Any, Any]
    model_w: tuple[Any, Any, Any]
    Q: Any  # q (of the normal form) as a ball
    R: Any  # rho (of the normal form) as a ball
    tau: float  # the principal delay (a double)
    q: float  # the double of the point delay of the round trip q e^{-tau s}
    rho_q: float  # the double of the open loop's principal gain
    u_point: float  # the double of the point delay of u_factor
    u_weight: Any  # the ball by which U~ of the normal form is multiplied in u_factor
    assumption: str = ""  # what the plant proven takes that the plant given may not be exactly
    radii: tuple[float, float] = (0.0, 0.0)  # bounds of the distance of rho_q and u_point to the exact values


def _proof(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> VaryingProof:
    flint = require_flint()
    arb = flint.arb
    with precision(flint, _PRECISION):
        if isinstance(system, GeneralHyperbolic2x2):
            geo = _geometry(flint, system)
            first = _screen(flint, system, geo)
            setup = _general_setup(flint, system, geo)
        else:
            first, setup = 0, _setup(flint, system)
        for (P, eps, _), name in ((setup.model_r, "k_r"), (setup.model_w, "k_w")):
            if not bool(eps < _RESIDUAL * _poly_sup(flint, P) + arb(2.0**-60)):
                raise CertificationError(
                    f"the coupling {name} is not within double precision of one Taylor model of order {ORDER} on "
                    f"[0, 1] (remainder {upper_bound_text(ball_upper(eps), 2)}): a singularity near [0, 1], a "
                    "coupling that varies too fast for that order, or (varying speeds, long L) ball arithmetic "
                    "overestimating the "
                    f"remainder's coefficient on the {_TOP_BALLS} balls covering [0, 1], even halved {_TOP_DEPTH} "
                    "times; the kernel route (kernel_grid=...) gives a model of the PDE"
                )
        for n in DEGREES[first:]:
            try:
                n_tilde, u_tilde = _kernels(flint, setup, n, n == DEGREES[-1])
                break
            except CertificationError:
                if n == DEGREES[-1]:
                    raise
    return VaryingProof(setup.tau, setup.q, setup.rho_q, n_tilde, u_tilde, setup.u_point, setup.assumption, setup.radii)


def _screen(flint: Any, system: GeneralHyperbolic2x2, geo: _Geometry) -> int:
    """The index in :data:`DEGREES` of the first degree worth proving at.

    For varying speeds the kernels' error bound is first found with the models' remainders taken as 0,
    which only lowers it (but for the rounding of the models' centres), so a plant refused there would be
    refused by the proof too (possibly for another reason found first: a remainder too large), in a
    fraction of its time (bounding the remainders is most of it); 0 for constant speeds. The reason says
    which bound it is.
    """
    if geo.scales is not None:
        return 0
    setup = _general_setup(flint, system, geo, remainder=False)
    for index, n in enumerate(DEGREES[:-1]):
        try:
            _kernels(flint, setup, n, False, screen=True)
            return index
        except CertificationError:
            pass
    _kernels(flint, setup, DEGREES[-1], True, screen=True)  # raises for a plant the proof would refuse
    return len(DEGREES) - 1


def _setup(flint: Any, system: Hyperbolic2x2) -> _Setup:
    """The paper's plant: ``k_r = sigma_pm / lam``, ``k_w = -sigma_mp / mu``, ``q, rho`` exact."""
    arb = flint.arb
    model_r = _model(flint, system.sigma_pm, system.sigma_pm_at, 1 / arb(system.lam), "sigma_pm")
    model_w = _model(flint, system.sigma_mp, system.sigma_mp_at, -1 / arb(system.mu), "sigma_mp")
    q, rho = system.q, system.rho
    radii = (ball_radius(flint, rho * q, arb(rho) * arb(q)), 0.0)
    return _Setup(model_r, model_w, arb(q), arb(rho), system.tau, q, rho * q, q, arb(1), "", radii)


class _Geometry(NamedTuple):
    """The change of variable ``y = T(x) / T(L)`` of a general plant, enclosed (``x = L y`` for constant speeds)."""

    tau: float  # T(L) / time_unit of the plant proven, a double
    x_series: Any  # arb_series in y -> arb_series in x of x(y)
    x_arrays: Any  # x(y) on arrays (the plant's tables), for the models' check
    weight: Any  # (arb_series of x, "u" or "v") -> the weight s_u or s_v there; None for constant speeds
    weight_at: Any  # the same on arrays of x
    scales: tuple[Any, Any] | None  # constant speeds: the balls L / lam, L / mu (the weights); else None
    assumption: str  # what the plant proven takes that the plant given may not be exactly ("": nothing)
    change: float = 0.0  # a bound of |factor - 1|, the factor of the speeds in the assumption


def _geometry(flint: Any, g: GeneralHyperbolic2x2) -> _Geometry:
    """``x(y)``, the weights ``s_u, s_v`` and ``tau`` (module notes, "General plants" and "Varying speeds")."""
    arb = flint.arb
    length, L = g.length, arb(g.length)
    if g.is_constant("lam") and g.is_constant("mu"):  # x = L y
        lam, mu = float(g.lam), float(g.mu)  # type: ignore[arg-type]
        tau = float((Fraction(length) / Fraction(lam) + Fraction(length) / Fraction(mu)) / Fraction(g.time_unit))
        scales = (L / arb(lam), L / arb(mu))
        return _Geometry(tau, lambda Y: Y * L, lambda y: length * np.asarray(y), None, None, scales, "")
    from scipy.interpolate import CubicHermiteSpline  # lazily: a slow import

    speed = _SpeedMap(flint, g)
    # tau the double nearest T(L) / time_unit: the plant proven has both speeds times T(L) / (tau time_unit)
    tau = float((speed.total / arb(g.time_unit)).mid())
    total = arb(tau) * arb(g.time_unit)
    gap = abs(speed.total / total - 1)
    change = 0.0 if gap.is_zero() else ball_upper(gap)  # exactly 1 when T(L) is the double (no 5e-324 printed)
    factor = "as given" if change == 0.0 else f"times a factor within {upper_bound_text(change, 2)} of 1"
    assumption = f"both speeds {factor} (tau the double {tau!r})"

    def weight(X: Any, side: str) -> Any:
        inv_lam, inv_mu = 1 / _on_series(flint, g.lam, X, "lam"), 1 / _on_series(flint, g.mu, X, "mu")
        return total * (inv_lam if side == "u" else inv_mu) / (inv_lam + inv_mu)

    def weight_at(x: Any, side: str) -> Any:
        inv_lam, inv_mu = 1.0 / g.coefficient("lam", x), 1.0 / g.coefficient("mu", x)
        return g.tau * (inv_lam if side == "u" else inv_mu) / (inv_lam + inv_mu)

    nodes = g.tables.x
    rate = 1.0 / g.coefficient("lam", nodes) + 1.0 / g.coefficient("mu", nodes)
    x_of_y = CubicHermiteSpline((g.phi(nodes) + g.psi(nodes)) / g.tau, nodes, g.tau / rate)

    def x_arrays(y: Any) -> Any:
        return np.asarray(x_of_y(np.clip(np.asarray(y, dtype=float), 0.0, 1.0)))

    return _Geometry(tau, speed.x_of, x_arrays, weight, weight_at, None, assumption, change)


def _general_setup(flint: Any, g: GeneralHyperbolic2x2, geo: _Geometry, remainder: bool = True) -> _Setup:
    """The normal form of a general plant, enclosed (module notes, "General plants" and "Varying speeds"),
    ``geo`` its change of variable; ``remainder=False``: the models' remainders taken as 0 (:func:`_screen`)."""
    arb = flint.arb
    length, L = g.length, arb(g.length)

    def physical(name: str, side: str) -> tuple[Any, Any, Any]:
        """The coefficient ``name`` times the weight of ``side`` as a function of ``y`` (at ``x(y)``): on balls,
        on arrays, and the constant scale of the model (the weight itself for constant speeds)."""
        value = getattr(g, name)
        if geo.scales is not None:  # constant speeds
            scale = geo.scales[0 if side == "u" else 1]
            if not callable(value):
                return float(value), None, scale
            return (lambda y: value(y * L)), (lambda y: g.coefficient(name, length * np.asarray(y))), scale

        def on_balls(y: Any) -> Any:
            X = geo.x_series(y.reshape(-1)[0])
            return _on_series(flint, value, X, name) * geo.weight(X, side)

        def on_arrays(y: Any) -> Any:
            x = geo.x_arrays(y)
            return g.coefficient(name, x) * geo.weight_at(x, side)

        return on_balls, on_arrays, arb(1)

    # A(x(y)) = int_0^y alpha, D(x(y)) = int_0^y delta: alpha = s_u a, delta = -s_v d at x(y)
    a_value, a_at, a_scale = physical("a", "u")
    d_value, d_at, d_scale = physical("d", "v")
    P_a, e_a, _ = _model(flint, a_value, a_at, a_scale, "a", remainder)
    P_d, e_d, _ = _model(flint, d_value, d_at, -d_scale, "d", remainder)
    E = P_d.integral() - P_a.integral()  # D - A at x(y), within e_E (and its derivative too)
    e_E = e_a + e_d
    # q~ = q e^{-k}: k is read as log(q / q~), q~ exact; k the normal form's balance (the mid-range of D - A)
    if g.constant_ratio:
        q_n = g.normal_form().system.q
    else:
        exponent = g.D(g.tables.x) - g.A(g.tables.x)
        q_n = g.q * float(np.exp(-0.5 * (np.max(exponent) + np.min(exponent))))
    ek = arb(q_n) / arb(g.q)  # e^{-k}
    E_end = E(arb(1)) + arb(0, ball_upper(e_E))
    # the given plant's A(L) - D(L) is the factor of the assumption times the proven plant's: the ball holds both
    E_end += arb(0, ball_upper(abs(E_end) * geo.change))
    weight = (-E_end).exp() / ek  # e^{A(L) + k - D(L)} = rho~ / rho

    def coupling(name: str, sign: int) -> tuple[Any, Any, Any]:
        value, at, scale = physical(name, "u" if sign > 0 else "v")
        factor = ek if sign > 0 else 1 / ek

        def on_balls(y: Any) -> Any:
            exponent = _poly_on_series(flint, E, y.reshape(-1)[0])
            own = value(y) if callable(value) else value
            if isinstance(own, np.ndarray):
                own = own.reshape(-1)[0]
            return own * (sign * exponent).exp() * factor

        def on_arrays(y: Any) -> Any:
            y = np.asarray(y, dtype=float)
            own = at(y) if at is not None else np.full(y.shape, value)
            x = geo.x_arrays(y)
            exponent = sign * (g.D(x) - g.A(x))
            return own * np.exp(exponent) * (q_n / g.q) ** sign

        P, eps, eps1 = _model(flint, on_balls, on_arrays, sign * scale, name, remainder)
        # the true coupling is the model's times e^{sign r}, |r| <= e_E, |r'| <= e_E
        grow = e_E.exp() - 1
        size, slope = _poly_sup(flint, P) + eps, _poly_sup(flint, P.derivative()) + eps1
        return P, eps + size * grow, eps1 + slope * grow + size * e_E * e_E.exp()

    model_r = coupling("b", 1)
    model_w = coupling("c", -1)
    rho = g.rho
    u_ball = arb(g.q) * (-E_end).exp()  # q e^{A(L) - D(L)}
    u_point = float(u_ball.mid())
    radii = (ball_radius(flint, rho * u_point, arb(rho) * u_ball), ball_radius(flint, u_point, u_ball))
    return _Setup(
        model_r,
        model_w,
        arb(q_n),
        arb(rho) * weight,
        geo.tau,
        q_n,
        rho * u_point,
        u_point,
        weight,
        geo.assumption,
        radii,
    )


def _kernels(
    flint: Any, setup: _Setup, n: int, last: bool, screen: bool = False
) -> tuple[DistributedDelay | None, DistributedDelay | None]:
    """``N~`` and ``U~`` from ``F^, G^`` of total degree ``n`` and the bound of their error (module notes);
    ``screen``: the bound's check only (:func:`_screen`), ``(None, None)`` when it passes.

    ``last``: the last degree tried, where an error below :data:`_RESIDUAL` of the loop's scale (its
    constant term 1) is accepted even when it is not below that fraction of a small kernel.
    """
    arb, arb_poly = flint.arb, flint.arb_poly
    (Pr, er, er1), (Pw, ew, ew1) = setup.model_r, setup.model_w
    Q, R = setup.Q, setup.R
    kr = np.array([float(c.mid()) for c in Pr.coeffs()] or [0.0])
    kw = np.array([float(c.mid()) for c in Pw.coeffs()] or [0.0])
    F_hat, G_hat = _picard(kr, kw, float(Q.mid()), n)
    bi = _Bi(flint, n)
    F, G = bi.from_array(F_hat), bi.from_array(G_hat)
    # residual polynomials T_P(F^, G^) - (F^, G^), exact in ball arithmetic (q a ball: its radius counts)
    RF = Pr - F  # k_r(A): P_r in the variable A = y
    RF += bi.integrate(bi.shifted(Pr) * G, 1)
    RG = Pw(arb_poly([0] * bi.K + [1])) * Q - G  # q k_w(V): V = y^K
    RG += bi.integrate(bi.shifted(Pw) * F, 0)
    sup_F, sup_G = bi.sup(F), bi.sup(G)
    sF_V, sG_A = bi.sup(bi.derivative(F, 1)), bi.sup(bi.derivative(G, 0))
    res = arb.max(bi.sup(RF) + er * (1 + sup_G), bi.sup(RG) + ew * (abs(Q) + sup_F))
    rF_V = bi.sup(bi.derivative(RF, 1)) + er * sup_G
    rF_A = bi.sup(bi.derivative(RF, 0)) + er1 * (1 + sup_G) + er * sG_A
    rG_A = bi.sup(bi.derivative(RG, 0)) + ew * sup_F
    rG_V = bi.sup(bi.derivative(RG, 1)) + ew1 * (abs(Q) + sup_F) + ew * sF_V
    C = arb.max(_poly_sup(flint, Pr) + er, _poly_sup(flint, Pw) + ew)
    C1 = arb.max(_poly_sup(flint, Pr.derivative()) + er1, _poly_sup(flint, Pw.derivative()) + ew1)
    M = res * C.exp()
    eF_V, eG_A = rF_V + C * M, rG_A + C * M
    eF_A = rF_A + C1 * M + C * eG_A
    eG_V = rG_V + C1 * M + C * eF_V
    T, W = arb(setup.tau), abs(setup.u_weight)
    # N^ = (G^ - rho F^)(1 - V, V) / tau and U^ = F^(1 - V, V) / tau, V = nu / tau in [0, 1] (T is tau)
    F_line, G_line = _along(flint, F_hat), _along(flint, G_hat)
    # The balls rho and u_weight enter as their centres times F^, their radii times the bounds of |F^| and of
    # its variation along the line (on the triangle, whose side A + V = 1 it is): the line's monomial
    # coefficients can be 10^12 times |F^| (alternating), too large for the radii to multiply them.
    F_size, F_var = sup_F, sF_V + bi.sup(bi.derivative(F, 0))
    R_mid, R_rad = arb(R.mid()), arb(R.rad())
    u_mid, u_rad = arb(setup.u_weight.mid()), arb(setup.u_weight.rad())
    floor = arb(_RESIDUAL if last else 2.0**-60)
    n_err = ((1 + abs(R)) * M + R_rad * F_size) / T
    n_var = (eG_V + eG_A + abs(R) * (eF_V + eF_A) + R_rad * F_var) / T
    n_tilde = _store(flint, G_line - F_line * R_mid, T, n_err, n_var, floor, screen)
    u_err, u_var = (W * M + u_rad * F_size) / T, (W * (eF_V + eF_A) + u_rad * F_var) / T
    u_tilde = _store(flint, F_line * u_mid, T, u_err, u_var, floor, screen)
    return n_tilde, u_tilde


def _along(flint: Any, c: np.ndarray) -> Any:
    """``P(1 - V, V)`` as an arb_poly in ``V``, exactly, for the coefficients ``c[i, j]`` of ``A^i V^j``."""
    arb_poly = flint.arb_poly
    one_minus = arb_poly([1, -1])
    out = arb_poly(0)
    for i in range(c.shape[0] - 1, -1, -1):
        out = out * one_minus + arb_poly([float(v) for v in c[i]])
    return out


def _store(
    flint: Any, line: Any, T: Any, sup_err: Any, var_err: Any, floor: Any, screen: bool = False
) -> DistributedDelay | None:
    """``line(nu / T) / T`` on ``[0, tau]`` as pieces, the proven bounds ``sup_err, var_err`` added to their own;
    ``sup_err`` must be below :data:`_RESIDUAL` of the kernel's size or below ``floor`` (``screen``: that check
    only, None when it passes).

    The pieces expand the midpoint polynomial of ``line``: its distance ``sum_k delta_k V^k / T`` to ``line``'s
    (``|delta_k|`` at most the radius of the coefficient ``k``, ``0 <= V = nu / T <= r = max(1, tau / T)``) is at
    most ``sum_k |delta_k| r^k / T`` in sup and in total variation (each ``V^k`` increases), added to both bounds:
    the radii of ``R``, ``u_weight`` and the models cannot then keep the pieces from double precision.
    """
    arb, arb_poly = flint.arb, flint.arb_poly
    tau = float(T.mid())
    coeffs = line.coeffs()
    reach = arb.max(arb(1), arb(tau) / T)
    spread = sum((arb(c.rad()) * reach**k for k, c in enumerate(coeffs)), arb(0)) / T
    sup_err, var_err = sup_err + spread, var_err + spread
    series = arb_poly([arb(c.mid()) for c in coeffs])(arb_poly([0, 1 / T])) * (1 / T)
    size = _poly_sup(flint, series(arb_poly([0, T])))
    if not size.is_finite():
        raise CertificationError(
            "the kernel's size bound is not finite (its polynomial's coefficients overflow): the kernel route "
            "(kernel_grid=...) gives a model of the PDE"
        )
    if not (sup_err.is_finite() and bool(sup_err < _RESIDUAL * size + floor)):
        what = "proven error of the kernel"
        if screen:
            what = "error bound of the kernel without the couplings' Taylor remainders"
        raise CertificationError(
            f"the {what} ({upper_bound_text(ball_upper(sup_err), 2)}) is too large: couplings not analytic on "
            f"a disc about [0, 1] wide enough for a Taylor model of order {ORDER}, or too strong for degree "
            f"{DEGREES[-1]}; the kernel route (kernel_grid=...) gives a model of the PDE"
        )
    if screen:  # the error bound is all the screening pass asks
        return None
    pieces = 8
    while True:
        mant, expo = math.frexp(tau / pieces)
        h = math.ldexp(math.floor(mant * 2**40) / 2**40, expo)  # i h exact: nodes and widths are exact
        nodes = [i * h for i in range(pieces)] + [tau]
        done = [expand_piece(flint, series, arb(0), lo, hi - lo) for lo, hi in itertools.pairwise(nodes)]
        scale = arb(0)
        for _, _, size_j in done:
            scale = arb.max(scale, size_j)
        if all(bool(err < TARGET * scale + arb(2.0**-60)) for _, err, _ in done):
            break
        pieces *= 2
        if pieces > MAX_PIECES:
            raise CertificationError(f"the kernel needs more than {MAX_PIECES} pieces to reach double precision")
    coefs = [c for c, _, _ in done]
    if not np.any(np.asarray(coefs)):
        return None
    piece_sup, piece_var = arb(0), arb(0)
    for _, err, _ in done:
        piece_sup, piece_var = arb.max(piece_sup, err), piece_var + err
    for left, right in itertools.pairwise(coefs):  # the jumps of the stored pieces at the nodes
        piece_var += abs(sum((arb(v) for v in left), arb(0)) - arb(right[0]))
    return DistributedDelay(
        np.asarray(nodes),
        None,
        interpolation="polynomial",
        coefficients=np.asarray(coefs),
        radius=ball_upper(piece_sup + sup_err),
        variation_radius=ball_upper(piece_var + var_err),
    )


def _poly_on_series(flint: Any, p: Any, Y: Any) -> Any:
    """``p(Y)`` for an arb_poly ``p`` and an arb_series ``Y``, Taylor-shifted first to the centre ``m`` of ``Y``'s
    constant ball: Horner's rule in ``Y - m`` (a constant ball about 0) encloses ``p``'s Taylor coefficients at
    every point of the ball far more tightly than Horner's rule in ``Y`` (monomials about 0 on a wide ball)."""
    m = Y.coeffs()[0].mid()
    shifted = p(flint.arb_poly([m, 1]))
    step = Y - m
    out = flint.arb(0)
    for c in reversed(shifted.coeffs()):
        out = out * step + c
    return out


def _poly_sup(flint: Any, p: Any) -> Any:
    """A bound of ``|p(x)|`` on ``[0, 1]`` (``p`` an arb_poly), from 64 balls covering it: on each, ``p`` is
    Taylor-shifted to the ball's centre (exactly) and evaluated on the ball about 0 (Horner's rule on the monomials
    about 0 multiplies their moduli by the ball's radius: ``10^10`` times too large for alternating coefficients of
    ``10^10`` and a function of size 1)."""
    arb, arb_poly = flint.arb, flint.arb_poly
    out = arb(0)
    step = arb(0, 1 / (2 * _SUP_BALLS))
    for k in range(_SUP_BALLS):
        local = p(arb_poly([arb((2 * k + 1) / (2 * _SUP_BALLS)), 1]))
        out = arb.max(out, abs(local(step)))
    return out
