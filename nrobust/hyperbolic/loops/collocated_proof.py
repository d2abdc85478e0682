"""Proven enclosures of the backstepping kernels of a plant with constant couplings.

The collocated observer's command response ``C_u`` under a law with integral gains composes the
plant's kernels at ``x = 1`` with the dual plant's kernels ``K'`` and ``L'``
(:mod:`~nrobust.hyperbolic.loops.collocated`, "The command response"). Here those kernels are
bivariate polynomials with ball coefficients and a proven bound of their distance to the kernels of
the PDE on the triangle ``T = {0 <= xi <= x <= 1}``.

**The Goursat systems.** With constant couplings both the kernels ``K`` of eqs. (24)-(29) and the
inverse kernels ``L`` of (30)-(31) are made of two pairs ``(A_p, B_p)``: ``A_p`` transported along
``(1, 1)``, ``B_p`` along ``(1, -kappa_p)``,

    A_{p,x} + A_{p,xi} = a_p B_p,    B_{p,x} - kappa_p B_{p,xi} = b_p A_p,
    B_p(x, x) = g_p,                  A_p(x, 0) = r_p B_{pi(p)}(x, 0),

with ``pi`` the identity for ``K`` (``(K^{uu}, K^{uv})``, ``(K^{vv}, K^{vu})``) and the swap for
``L`` (``(L^{uu}, L^{vu})``, ``(L^{vv}, L^{uv})``: the inverse transformation reads the target
system's boundary ``alpha(0) = q beta(0)``, so ``lam q L^{uu}(x, 0) = mu L^{uv}(x, 0)`` and
``lam q L^{vu}(x, 0) = mu L^{vv}(x, 0)``; inserting the inverse map into the plant (18)-(19) gives
``lam (L^{uu}_x + L^{uu}_xi) = sigma^{+-} L^{vu}``, ``mu L^{vu}_x - lam L^{vu}_xi = -sigma^{-+} L^{uu}``,
``L^{vu}(x, x) = -sigma^{-+} / (lam + mu)`` and their mirror images).

**Taylor coefficients.** With ``A = sum A_ij x^i xi^j`` the equations read, at each monomial of
degree ``n``, ``(i + 1) A_{i+1, j} + (j + 1) A_{i, j+1} = a B_ij`` and ``(i + 1) B_{i+1, j} -
kappa (j + 1) B_{i, j+1} = b A_ij``; the diagonal condition is ``sum_{i+j=n} B_ij = g [n = 0]`` and the
reflection ``A_{n,0} = r B'_{n,0}``. Degree ``n + 1`` follows from degree ``n``: the ``B`` of degree
``n + 1`` are affine in ``B_{0,n+1}`` (the sweep in ``i``), fixed by the diagonal (the slopes sum to
``(1 + kappa)^{n+1} > 0``); then ``A_{n+1,0}`` by the reflection and the others by the sweep down in
``i``. All of it in ball arithmetic.

**The remainder.** The truncation ``P`` of degree ``N`` (with the exact coefficients, which lie in
the balls) satisfies the boundary conditions exactly and the transport equations up to the sources
``-a_p B_p^{(N)}``, ``-b_p A_p^{(N)}`` (``^{(N)}``: the homogeneous part of degree ``N``). The error
``E = kernel - P`` then solves the Goursat system with zero data and the sources ``S_A = a_p
B_p^{(N)}``, ``S_B = b_p A_p^{(N)}``. Along the characteristics (``B_p`` from the diagonal, ``A_p``
from ``xi = 0``, where it is ``r_p`` times ``B_{pi(p)}``, itself an integral from the diagonal over
the ``x``-range ``[0, x - xi]`` disjoint from ``A_p``'s own ``[x - xi, x]``), the largest error
``m(x)`` over ``T`` with abscissae up to ``x`` obeys ``m(x) <= int_0^x (C m + S)`` with
``C = max_p (|a_p|, |b_p|, |r_p b_{pi(p)}|)`` and ``S = max_p (sup |S_{A,p}|, sup |S_{B,p}|,
|r_p| sup |S_{B,pi(p)}|)``, so (Gronwall) ``|E| <= S (e^C - 1) / C`` on ``T``. The sup of a homogeneous
part on ``T`` is at most the sum of its coefficients' moduli.

**The derivatives.** With constant couplings ``E_x`` solves the same system with the sources
differentiated in ``x``; on the diagonal ``E_B(x, x) = 0`` and the transport equation give
``E_{B,x} = (b E_A + S_B) / (1 + kappa)`` (bounded by the above), and the reflection holds for ``E_x``.
The same characteristics give ``m_1(x) <= D + int_0^x (C m_1 + S_1)``, ``D`` the largest diagonal datum
(times ``|r_p|`` for the reflected), ``S_1`` the sources' ``x``-derivatives (sums of ``i |c_ij|``), so
``|E_x| <= (D + S_1) e^C``; then ``E_{A,xi} = a E_B + S_A - E_{A,x}`` and ``E_{B,xi} = (E_{B,x} - b E_A -
S_B) / kappa`` from the transport equations.

**The command response.** :func:`response_pieces` evaluates the formula of ``c`` (module notes of
:mod:`~nrobust.hyperbolic.loops.collocated`) on each piece between ``0, 1/lam, 1/mu, tau`` (exact rationals of the
user's doubles, compared exactly: the pieces are those of the PDE whether or not the ends are doubles) with the
polynomials: ``F = (I - K') f`` by exact integration of monomials, each integral over ``xi`` with
limits linear in ``t`` by :func:`polynomial_integral`; the error of ``c`` and of its derivative follow from
the remainders, the derivative bounds and the sums of the polynomials' coefficients (sup bounds on
``[0, 1]``), every integral over an interval of length at most 1. A plant with ``q = 0`` is refused (the
reflection ``K^{uu}(x, 0) = mu / (lam q) K^{uv}(x, 0)`` divides by ``q``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

from ..._flint import precision
from ...errors import CertificationError
from ..plants.hyperbolic2x2 import Hyperbolic2x2

__all__ = [
    "KernelEnclosure",
    "ResponsePieces",
    "dual_enclosures",
    "inverse_kernel_enclosure",
    "kernel_enclosure",
    "polynomial_integral",
    "response_pieces",
]

#: Degrees tried for the kernels' Taylor polynomials, and working precisions (bits) tried at each: the
#: recursion cancels (alternating sweeps), so the balls need far more bits than the result keeps. Measured at
#: degree 50: 256 bits suffice on the paper's plant (remainder 1e-58), ``(1, 2, 0.4, 0.5, 1, 0.3)`` needs 2048
#: (the bound is 6e266 at 256 bits, 4e35 at 1024, 1e-76 at 2048); ``(1, 1, 4, 4, 0.5, 0.5)`` stops at 4e-16
#: at degree 50 whatever the precision (Gronwall's factor ``e^8``) and needs a higher degree.
DEGREES, PRECISIONS = (50, 80, 120), (1024, 2048, 4096, 8192)
#: The remainder bound to reach (far below double precision: the loops built on the kernels keep 53 bits).
TARGET = 2.0**-80
# Working precision (bits) of the algebra on the kernels' polynomials in :func:`response_pieces`: the kernels'
# recursion needs up to 8192 bits, the polynomial algebra on its results does not cancel as much (the pieces' balls
# are 1e-75 to 1e-62 wide at 256 bits on the plants of the module's tests, far below TARGET) and runs twice as fast
# as at the kernels' precision.
_ALGEBRA_BITS = 256

#: Names of the four kernels, in the order of their storage.
NAMES = ("uu", "uv", "vu", "vv")


@dataclass(frozen=True)
class KernelEnclosure:
    """Four kernels on ``T`` as bivariate polynomials in ball arithmetic, within ``error`` of the PDE's.

    Attributes
    ----------
    coefficients : dict
        ``name -> {(i, j): c}``: the coefficient of ``x^i xi^j`` (an ``arb`` ball), for the names
        ``"uu", "uv", "vu", "vv"``.
    error : Any
        An ``arb`` upper bound of the largest distance on ``T`` between a kernel and its polynomial
        (any polynomial with coefficients in the balls).
    slope : Any
        An ``arb`` upper bound of the partial derivatives of that distance on ``T``.
    degree : int
        The polynomials' degree.
    bits : int
        The working precision the coefficients were computed at (the precision for further algebra on them).
    """

    coefficients: dict[str, dict[tuple[int, int], Any]]
    error: Any
    slope: Any
    degree: int
    bits: int

    def trace(self, flint: Any, name: str) -> Any:
        """The polynomial ``xi -> kernel(1, xi)`` (an ``arb_poly``; add :attr:`error` for the kernel's)."""
        out = [flint.arb(0)] * (self.degree + 1)
        for (_, j), c in self.coefficients[name].items():
            out[j] += c
        return flint.arb_poly(out)

    def at(self, flint: Any, name: str, x: Any, xi: Any) -> Any:
        """The polynomial's ball at ``(x, xi)`` (add :attr:`error` for the kernel's)."""
        x, xi = flint.arb(x), flint.arb(xi)
        return sum((c * x**i * xi**j for (i, j), c in self.coefficients[name].items()), flint.arb(0))


@dataclass(frozen=True)
class _Pair:
    """One pair ``(A, B)`` of a Goursat system (module notes) and the pair whose ``B`` its reflection reads."""

    a: Any
    b: Any
    kappa: Any
    g: Any
    r: Any
    partner: int


def _solve(flint: Any, pairs: tuple[_Pair, _Pair], degree: int) -> tuple[list[dict], list[dict], Any, Any]:
    """The Taylor coefficients of the ``A_p`` and ``B_p`` up to ``degree``, the bound of the remainder and of its
    first partial derivatives."""
    arb = flint.arb
    A: list[dict[tuple[int, int], Any]] = [{}, {}]
    B: list[dict[tuple[int, int], Any]] = [{}, {}]
    for p, pair in enumerate(pairs):
        B[p][(0, 0)] = pair.g
    for p, pair in enumerate(pairs):
        A[p][(0, 0)] = pair.r * B[pair.partner][(0, 0)]
    for n in range(degree):
        m = n + 1
        for p, pair in enumerate(pairs):
            free, slope = [arb(0)], [arb(1)]  # B_{i, m-i} = free_i + slope_i B_{0, m}
            for i in range(m):
                j = n - i
                free.append((pair.kappa * (j + 1) * free[i] + pair.b * A[p][(i, j)]) / (i + 1))
                slope.append(pair.kappa * (j + 1) * slope[i] / (i + 1))
            top = -sum(free, arb(0)) / sum(slope, arb(0))
            for i in range(m + 1):
                B[p][(i, m - i)] = free[i] + slope[i] * top
        for p, pair in enumerate(pairs):
            A[p][(m, 0)] = pair.r * B[pair.partner][(m, 0)]
            for i in range(n, -1, -1):
                j = n - i
                A[p][(i, j + 1)] = (pair.a * B[p][(i, j)] - (i + 1) * A[p][(i + 1, j)]) / (j + 1)

    def top_sum(table: dict[tuple[int, int], Any]) -> Any:
        return sum((abs(table[(i, degree - i)]) for i in range(degree + 1)), arb(0))

    source_a = [abs(pair.a) * top_sum(B[p]) for p, pair in enumerate(pairs)]
    source_b = [abs(pair.b) * top_sum(A[p]) for p, pair in enumerate(pairs)]
    rate, source = arb(0), arb(0)
    for p, pair in enumerate(pairs):
        rate = arb.max(rate, arb.max(abs(pair.a), arb.max(abs(pair.b), abs(pair.r * pairs[pair.partner].b))))
        source = arb.max(source, arb.max(source_a[p], arb.max(source_b[p], abs(pair.r) * source_b[pair.partner])))
    growth = arb(1) if rate == 0 else (rate.exp() - 1) / rate
    error = arb((source * growth).upper())

    # the x-derivatives of the error: the same system, sources differentiated, diagonal data
    # E_{B,x}(x, x) = (b E_A + S_B) / (1 + kappa) (module notes, "The derivatives")
    def top_slope(table: dict[tuple[int, int], Any]) -> Any:
        return sum((i * abs(table[(i, degree - i)]) for i in range(degree + 1)), arb(0))

    diagonal = [(abs(pair.b) * error + source_b[p]) / (1 + pair.kappa) for p, pair in enumerate(pairs)]
    slope_a = [abs(pair.a) * top_slope(B[p]) for p, pair in enumerate(pairs)]
    slope_b = [abs(pair.b) * top_slope(A[p]) for p, pair in enumerate(pairs)]
    start, slope_source = arb(0), arb(0)
    for p, pair in enumerate(pairs):
        start = arb.max(start, arb.max(diagonal[p], abs(pair.r) * diagonal[pair.partner]))
        slope_source = arb.max(
            slope_source, arb.max(slope_a[p], arb.max(slope_b[p], abs(pair.r) * slope_b[pair.partner]))
        )
    along_x = (start + slope_source) * rate.exp()
    slope = along_x
    for p, pair in enumerate(pairs):
        slope = arb.max(slope, along_x + abs(pair.a) * error + source_a[p])
        slope = arb.max(slope, (along_x + abs(pair.b) * error + source_b[p]) / pair.kappa)
    return A, B, error, arb(slope.upper())


def _enclosed(
    flint: Any, pairs_of: Callable[[], tuple[_Pair, _Pair]]
) -> tuple[list[dict], list[dict], Any, Any, int, int]:
    """:func:`_solve` of the pairs ``pairs_of()`` (built at the working precision) at the first degree of
    :data:`DEGREES` and precision of :data:`PRECISIONS` whose remainder bound and slope bound are below
    :data:`TARGET` (a higher precision is tried while it lowers the bound by 4 at least); a
    :class:`CertificationError` when none is."""
    best = None
    for degree in DEGREES:
        previous = None
        for bits in PRECISIONS:
            with precision(flint, bits):
                A, B, error, slope = _solve(flint, pairs_of(), degree)
            if error < TARGET and slope < TARGET:
                return A, B, error, slope, degree, bits
            if best is None or error < best:
                best = error
            if previous is not None and not error < previous / 4:
                break
            previous = error
    raise CertificationError(
        f"the kernels' remainder bound is {best.str(2) if best is not None else 'unknown'} at degree {DEGREES[-1]}: "
        "couplings this strong need a higher degree"
    )


def _constants(flint: Any, system: Hyperbolic2x2) -> tuple[Any, ...]:
    """The plant's constants as balls; a :class:`CertificationError` unless its couplings are constant, ``q != 0``."""
    if not isinstance(system, Hyperbolic2x2) or callable(system.sigma_pm) or callable(system.sigma_mp):
        raise CertificationError("the kernels are enclosed for a Hyperbolic2x2 with constant couplings only")
    if system.q == 0.0:
        raise CertificationError("the kernels' reflection at xi = 0 divides by q: no enclosure for q = 0")
    arb = flint.arb
    return tuple(arb(float(v)) for v in (system.lam, system.mu, system.sigma_pm, system.sigma_mp, system.q))


def kernel_enclosure(flint: Any, system: Hyperbolic2x2) -> KernelEnclosure:
    """The kernels ``K`` of eqs. (24)-(29) of ``system`` as proven polynomial enclosures (module notes).

    Pairs ``(K^{uu}, K^{uv})``: ``a = -sigma^{-+}/lam``, ``b = -sigma^{+-}/lam``, ``kappa = mu/lam``,
    ``g = sigma^{+-}/(lam + mu)``, ``r = mu/(lam q)``; ``(K^{vv}, K^{vu})``: ``a = sigma^{+-}/mu``,
    ``b = sigma^{-+}/mu``, ``kappa = lam/mu``, ``g = -sigma^{-+}/(lam + mu)``, ``r = lam q/mu``.
    """
    _constants(flint, system)

    def pairs() -> tuple[_Pair, _Pair]:
        lam, mu, spm, smp, q = _constants(flint, system)
        return (
            _Pair(-smp / lam, -spm / lam, mu / lam, spm / (lam + mu), mu / (lam * q), 0),
            _Pair(spm / mu, smp / mu, lam / mu, -smp / (lam + mu), lam * q / mu, 1),
        )

    A, B, error, slope, degree, bits = _enclosed(flint, pairs)
    return KernelEnclosure({"uu": A[0], "uv": B[0], "vu": B[1], "vv": A[1]}, error, slope, degree, bits)


def inverse_kernel_enclosure(flint: Any, system: Hyperbolic2x2) -> KernelEnclosure:
    """The inverse kernels ``L`` of eqs. (30)-(31) of ``system`` as proven polynomial enclosures (module notes).

    Pairs ``(L^{uu}, L^{vu})``: ``a = sigma^{+-}/lam``, ``b = -sigma^{-+}/mu``, ``kappa = lam/mu``,
    ``g = -sigma^{-+}/(lam + mu)``, ``L^{uu}(x, 0) = mu/(lam q) L^{uv}(x, 0)``; ``(L^{vv}, L^{uv})``:
    ``a = -sigma^{-+}/mu``, ``b = sigma^{+-}/lam``, ``kappa = mu/lam``, ``g = sigma^{+-}/(lam + mu)``,
    ``L^{vv}(x, 0) = lam q/mu L^{vu}(x, 0)``.
    """
    _constants(flint, system)

    def pairs() -> tuple[_Pair, _Pair]:
        lam, mu, spm, smp, q = _constants(flint, system)
        return (
            _Pair(spm / lam, -smp / mu, lam / mu, -smp / (lam + mu), mu / (lam * q), 1),
            _Pair(-smp / mu, spm / lam, mu / lam, spm / (lam + mu), lam * q / mu, 0),
        )

    A, B, error, slope, degree, bits = _enclosed(flint, pairs)
    return KernelEnclosure({"uu": A[0], "vu": B[0], "uv": B[1], "vv": A[1]}, error, slope, degree, bits)


def _sum_abs(flint: Any, values: Any) -> Any:
    """``sum |c|`` of balls: an upper bound of a polynomial's sup on ``[0, 1]`` (of a bivariate one on ``T``)."""
    return flint.arb(sum((abs(c) for c in values), flint.arb(0)).upper())


@dataclass(frozen=True)
class ResponsePieces:
    """``c`` of ``C_u(s) = k q e^{-tau s} + int_0^tau c(nu) e^{-nu s} dnu`` on its smooth pieces, proven.

    Attributes
    ----------
    breaks : tuple
        ``0 < ... < tau``: the ends of the pieces (``0, 1/lam, 1/mu, tau``, the equal ones merged), as balls.
    pieces : tuple
        On ``[t_j, t_{j+1}]`` an ``arb_poly`` in ``nu - t_j``.
    error : Any
        An ``arb`` bound of ``|c - piece|`` on every piece.
    slope : Any
        An ``arb`` bound of the derivative of ``c - piece`` on every piece.
    times : tuple of Fraction
        The same ends as exact rationals of the user's doubles.
    """

    breaks: tuple[Any, ...]
    pieces: tuple[Any, ...]
    error: Any
    slope: Any
    times: tuple[Fraction, ...]


def polynomial_integral(flint: Any, P: Any, Q: Any, alpha: Any, w: Any, lo: Any, hi: Any) -> Any:
    """``u -> int_{lo(u)}^{hi(u)} P(xi) Q(alpha xi + w(u)) dxi`` (``lo``, ``hi``, ``w``: polynomials in ``u``).

    ``Q(alpha xi + w) = sum_k (alpha xi)^k Q^(k)(w) / k!`` and ``int xi^k P`` exact: one term per degree of ``Q``.
    When ``Q`` has the higher degree and ``alpha`` is an exact non-zero ball, the substitution ``eta = alpha xi + w``
    exchanges the roles (``(1 / alpha) int_{alpha lo + w}^{alpha hi + w} Q(eta) P((eta - w) / alpha) deta``): one term
    per degree of ``P``, the integral of a kernel of degree 27 against a response of degree 150 five times faster.
    """
    if Q.degree() > P.degree() and alpha.is_exact() and not alpha.is_zero():
        inverse = 1 / alpha
        return _integral_by_terms(flint, Q, P, inverse, -w * inverse, alpha * lo + w, alpha * hi + w) * inverse
    return _integral_by_terms(flint, P, Q, alpha, w, lo, hi)


def _integral_by_terms(flint: Any, P: Any, Q: Any, alpha: Any, w: Any, lo: Any, hi: Any) -> Any:
    """:func:`polynomial_integral` by the expansion of ``Q`` about ``w`` (one term per degree of ``Q``)."""
    arb, arb_poly = flint.arb, flint.arb_poly
    xi = arb_poly([0, 1])
    total, power, monomial = arb_poly([0]), arb(1), arb_poly([1])
    derivative, factorial = Q, arb(1)
    for k in range(Q.degree() + 1):
        H = (P * monomial).integral()
        total += power * (H(hi) - H(lo)) * (derivative(w) * (1 / factorial))
        power *= alpha
        monomial *= xi
        derivative = derivative.derivative()
        factorial *= k + 1
    return total


def _composed(flint: Any, kernel: dict[tuple[int, int], Any], f: Any) -> Any:
    """``xi -> int_0^xi kernel(xi, eta) f(eta) deta`` (exact polynomial algebra)."""
    arb_poly = flint.arb_poly
    degree = max(i for i, _ in kernel)
    xi = arb_poly([0, 1])
    total, monomial = arb_poly([0]), arb_poly([1])
    for j in range(degree + 1):
        row = arb_poly([kernel.get((i, j), flint.arb(0)) for i in range(degree + 1)])
        total += row * (f * monomial).integral()
        monomial *= xi
    return total


def response_pieces(flint: Any, system: Hyperbolic2x2, K: float) -> ResponsePieces:
    """``c`` of the collocated observer's command response under U_BS2(K) (eq. (53); ``K = rho``: U_BS), proven.

    The formula of :mod:`~nrobust.hyperbolic.loops.collocated` ("The command response ``C_u``"): the law
    ``k = -K``, ``g_u = K^{vu}(1, .) - (rho - K) K^{uu}(1, .)``, ``g_v = K^{vv}(1, .) - (rho - K) K^{uv}(1, .)``;
    ``F = (I - K') (-g_v, -g_u)`` and ``L'(1, .)`` of the dual plant; every term a polynomial on each piece,
    its error bounded from the kernels' remainders (sup norms on ``[0, 1]`` by coefficient sums).
    """
    plant, dual = kernel_enclosure(flint, system), dual_enclosures(flint, system)
    K_dual, L_dual = dual
    arb, arb_poly = flint.arb, flint.arb_poly
    with precision(flint, _ALGEBRA_BITS):
        lam, mu, _, _, q = _constants(flint, system)
        reflected = arb(float(system.rho)) - arb(float(K))
        k = -arb(float(K))
        q_dual = lam * q / mu
        f_a = -(plant.trace(flint, "vv") - reflected * plant.trace(flint, "uv"))
        f_b = -(plant.trace(flint, "vu") - reflected * plant.trace(flint, "uu"))
        F_a = f_a - _composed(flint, K_dual.coefficients["uu"], f_a) - _composed(flint, K_dual.coefficients["uv"], f_b)
        F_b = f_b - _composed(flint, K_dual.coefficients["vu"], f_a) - _composed(flint, K_dual.coefficients["vv"], f_b)
        L_aa, L_ab = L_dual.trace(flint, "uu"), L_dual.trace(flint, "uv")
        # error bounds (module notes of this function)
        e_f = plant.error * (1 + abs(reflected))
        size_f = arb.max(_sum_abs(flint, f_a.coeffs()), _sum_abs(flint, f_b.coeffs()))
        size_K = arb(0)
        for name in NAMES:
            size_K = arb.max(size_K, _sum_abs(flint, K_dual.coefficients[name].values()))
        e_F = e_f + 2 * (size_K * e_f + K_dual.error * (size_f + e_f))
        size_F = arb.max(_sum_abs(flint, F_a.coeffs()), _sum_abs(flint, F_b.coeffs()))
        size_L = arb.max(_sum_abs(flint, L_aa.coeffs()), _sum_abs(flint, L_ab.coeffs()))
        e_L = L_dual.error
        e_integral = size_L * e_F + e_L * (size_F + e_F)
        error = mu * (
            arb.max(arb(1), abs(q_dual)) * e_F + (2 + abs(q_dual)) * e_integral + abs(k) * arb.max(arb(1), abs(q)) * e_L
        )
        # the derivatives' errors: F' = f' - K'(xi, xi) f - int K'_x f, and d/dt of each term of c (module notes)
        e_df = plant.slope * (1 + abs(reflected))
        e_dF = e_df + 4 * (size_K * e_f + K_dual.error * (size_f + e_f) + K_dual.slope * (size_f + e_f))
        e_dF += (
            2 * _sum_abs(flint, (i * abs(c) for name in NAMES for (i, _), c in K_dual.coefficients[name].items())) * e_f
        )
        size_dF = arb.max(_sum_abs(flint, F_a.derivative().coeffs()), _sum_abs(flint, F_b.derivative().coeffs()))
        size_dL = arb.max(_sum_abs(flint, L_aa.derivative().coeffs()), _sum_abs(flint, L_ab.derivative().coeffs()))
        e_dL = L_dual.slope
        e_d_integral = arb.max(e_dL * (size_F + e_F) + size_dL * e_F, e_L * (size_dF + e_dF) + size_L * e_dF)
        speed = arb.max(lam, mu)
        slope = (
            mu
            * speed
            * (
                (1 + abs(q_dual)) * e_dF
                + (3 + 2 * abs(q_dual)) * e_integral
                + (2 + abs(q_dual)) * e_d_integral
                + abs(k) * (1 + abs(q)) * e_dL
            )
        )
        t_u, t_v = 1 / lam, 1 / mu
        tau = t_u + t_v
        # the ends as exact rationals (equal ones merged, the pieces chosen by exact comparisons) and as balls
        exact_u, exact_v = 1 / Fraction(system.lam), 1 / Fraction(system.mu)
        balls = {Fraction(0): arb(0), exact_u: t_u, exact_v: t_v, exact_u + exact_v: tau}
        times = sorted(balls)
        pieces = []
        zero, one = arb_poly([0]), arb_poly([1])
        for j in range(len(times) - 1):
            start, middle = balls[times[j]], (times[j] + times[j + 1]) / 2
            t = arb_poly([start, 1])  # nu = start + u
            if middle < exact_v:
                total = F_a(1 - mu * t)
                total += polynomial_integral(flint, L_aa, F_a, arb(1), -mu * t, mu * t, one)
                upper = mu * t
            else:
                total = q_dual * F_b(lam * (t - t_v))
                upper = one
            lower = mu * (t - t_u) if middle > exact_u else zero
            total += q_dual * polynomial_integral(flint, L_aa, F_b, -lam / mu, lam * t, lower, upper)
            if middle < exact_u:
                total += polynomial_integral(flint, L_ab, F_b, arb(1), lam * t, zero, 1 - lam * t)
                total -= k * L_ab(1 - lam * t)
            else:
                total -= q * k * L_aa(mu * (t - t_u))
            pieces.append(-mu * total)
    breaks = tuple(balls[t] for t in times)
    return ResponsePieces(breaks, tuple(pieces), arb(error.upper()), arb(slope.upper()), tuple(times))


def dual_enclosures(flint: Any, system: Hyperbolic2x2) -> tuple[KernelEnclosure, KernelEnclosure]:
    """``K'`` and ``L'`` of the dual plant ``Hyperbolic2x2(mu, lam, sigma^{+-}, sigma^{-+}, lam q / mu, 0)``."""
    dual = Hyperbolic2x2(
        system.mu, system.lam, system.sigma_pm, system.sigma_mp, system.lam * system.q / system.mu, 0.0
    )
    return kernel_enclosure(flint, dual), inverse_kernel_enclosure(flint, dual)
