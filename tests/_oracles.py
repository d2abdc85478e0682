"""Independent oracles for the differential harness (``tests/test_harness.py``).

Nothing here imports nrobust: the answers come from closed forms, exact rational
arithmetic (:mod:`fractions`), ``scipy.special.lambertw``, ``numpy.roots`` and
``mpmath.polyroots`` at high precision, so that a bug in nrobust cannot hide in its own
reference. Each oracle states how far it can be trusted; when it cannot decide (a root
within rounding of a contour, a root on the imaginary axis, a refinement that does not
converge) it returns ``None`` or raises :class:`OracleUnsure`, and the case is skipped,
not counted.

Conventions: polynomial coefficients are in increasing powers of ``s`` (as in
``nrobust.QuasiPolynomial``), a rectangle is ``(re_min, re_max, im_min, im_max)``.

Derivations
-----------
* Lambert W. ``s + a + b e^{-tau s} = 0`` with ``z = tau (s + a)`` reads
  ``z e^z = -b tau e^{a tau}``, so the roots are ``s_k = W_k(-b tau e^{a tau})/tau - a``,
  one per branch ``k`` of Lambert's W (all roots when ``b != 0``). For a real argument the
  principal branch has the largest real part (Shinozaki and Mori, 2006), checked here on
  every call against the neighbouring branches.
* Commensurate delays. ``sum_k c_k e^{-k h s} = D(z)`` with ``z = e^{-h s}``; every root
  ``z_j`` of the polynomial ``D`` gives the vertical chain
  ``s = (-log|z_j| - i arg z_j + 2 pi i m)/h``, ``m`` in ``Z``. ``1 - a e^{-tau s}`` is the
  case ``D(z) = 1 - a z``.
* Products. The roots of ``p(s) D(e^{-h s})`` are those of ``p`` and those of ``D``;
  with dyadic roots and coefficients every product below is exact in binary floating point.
* Distributed delay with a constant kernel: ``alpha + s int_0^h c e^{-nu s} dnu
  = (alpha + c) - c e^{-h s}``: a ``1 - a e^{-h s}`` family with ``a = c/(alpha + c)``.
* Loops ``A + B e^{-delta s}`` (real polynomials). On ``s = i w`` a root needs
  ``|A(i w)| = |B(i w)|``: the zeros ``x_c > 0`` of the real polynomial
  ``P(x) = |A(i w)|^2 - |B(i w)|^2`` in ``x = w^2`` (exact, over the rationals). The
  delays are ``e^{i w delta} = -B/A``: ``delta_{c,k} = (arg(-B/A) mod 2 pi + 2 pi k)/w_c``.
  From ``ds/ddelta = -s B e^{-delta s}/(A' + (B' - delta B) e^{-delta s})`` and
  ``B e^{-delta s} = -A``: ``Re (ds/ddelta)^{-1} = (1/w) d/dw log|A/B|
  = P'(w^2)/|A|^2`` on the axis, so a simple zero crosses in the direction
  ``sign P'(x_c)``; a zero of even multiplicity touches the axis and turns back (no change
  of the count, but a root on the axis at ``delta_{c,k}``). Every crossing moves a
  conjugate pair. With ``N_0`` the unstable roots of the polynomial ``A + B`` (strongly
  stable loops: ``deg B < deg A`` or ``|b_n| < |a_n|``, so no root comes from infinity),
  ``N(delta) = N_0 + 2 sum_c sign P'(x_c) #{k : delta_{c,k} < delta}``; the margin is the
  first ``delta_{c,0}`` (tangencies included: the loop is not exponentially stable there).
* Transport loop ``1 - rho q e^{-tau s} + K q e^{-(tau + delta) s}``: for ``Re s >= 0`` the
  delayed terms have modulus at most ``|rho q| + |K q|``, so ``|rho q| + |K q| < 1`` means
  no root in ``Re s >= 0`` for any delta (margin ``inf``); if ``|rho q| + |K q| > 1`` the
  difference operator is not strongly stable and crossings ``|1 - rho q e^{-i w tau}| = |K q|``
  recur at frequencies ``w -> inf`` with delays ``(theta + 2 pi k)/w -> 0``: margin 0.
  Hence the admissible gains for every ``delta_max > 0`` are the open interval
  ``|K| < (1 - |rho q|)/|q|`` (empty if ``|rho q| >= 1``).
"""

from __future__ import annotations

import functools
import inspect
import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import mpmath as mp
import numpy as np
from scipy.optimize import fsolve
from scipy.special import lambertw

Region = tuple[float, float, float, float]

# Working precision of the mpmath parts (decimal digits).
_DPS = 60


class OracleUnsure(Exception):
    """The oracle cannot decide this case reliably; the harness skips it."""


def winding_number(F: Callable[[mp.mpc], mp.mpc], region: Sequence[float], n: int = 300) -> int:
    """Winding number of ``F`` about the rectangle ``(x0, x1, y0, y1)``, the argument unwrapped on ``4 n`` samples
    at 40 digits (asserted to turn by less than a radian between samples, so that no turn is missed)."""
    with mp.workdps(40):
        x0, x1, y0, y1 = (mp.mpf(v) for v in region)
        corners = [mp.mpc(x0, y0), mp.mpc(x1, y0), mp.mpc(x1, y1), mp.mpc(x0, y1)]
        values = [F(a + (b - a) * mp.mpf(j) / n) for a, b in zip(corners, corners[1:] + corners[:1]) for j in range(n)]
        values.append(values[0])
        steps = [mp.arg(b / a) for a, b in itertools.pairwise(values)]
    assert max(abs(t) for t in steps) < 1.0
    return int(mp.nint(mp.fsum(steps) / (2 * mp.pi)))


def _polyroots(coeffs: list, extraprec: int) -> tuple[list, object]:
    """``mpmath.polyroots`` of increasing-power coefficients (``asc=`` exists from mpmath 1.4 on)."""
    if "asc" in inspect.signature(mp.polyroots).parameters:
        return mp.polyroots(coeffs, maxsteps=400, extraprec=extraprec, error=True, asc=True)
    return mp.polyroots(coeffs[::-1], maxsteps=400, extraprec=extraprec, error=True)


# ============================================================ boxes and known roots
def count_in_box(roots: Sequence[complex], box: Region, guard: float) -> int:
    """Number of ``roots`` strictly inside ``box``.

    Raises :class:`OracleUnsure` when a root lies within ``guard`` of an edge: a root that
    close to the contour may be counted either way by any floating-point method.
    """
    x0, x1, y0, y1 = box
    n = 0
    for z in roots:
        dx = min(abs(z.real - x0), abs(z.real - x1))
        dy = min(abs(z.imag - y0), abs(z.imag - y1))
        inside_x, inside_y = x0 < z.real < x1, y0 < z.imag < y1
        if (dx <= guard and (y0 - guard) <= z.imag <= (y1 + guard)) or (
            dy <= guard and (x0 - guard) <= z.real <= (x1 + guard)
        ):
            raise OracleUnsure(f"root {z} within {guard:.3g} of the edge of {box}")
        n += int(inside_x and inside_y)
    return n


def poly_from_roots(roots: Sequence[complex], lead: float = 1.0) -> list[float]:
    """Real coefficients (increasing powers) of ``lead * prod (s - r)``; complex roots are
    given once per conjugate pair (``Im r > 0``), real roots once each.

    With dyadic roots and a power-of-two ``lead`` (and moderate degree) every coefficient
    is exact in binary floating point; :func:`exact_poly` checks it.
    """
    c = [Fraction(lead)]
    for r in roots:
        if r.imag == 0:
            c = _pmul(c, [Fraction(-r.real), Fraction(1)])
        else:
            re, im = Fraction(r.real), Fraction(r.imag)
            c = _pmul(c, [re * re + im * im, -2 * re, Fraction(1)])
    out = [float(v) for v in c]
    if any(Fraction(f) != v for f, v in zip(out, c)):
        raise OracleUnsure("coefficients not exact in floating point")
    return out


def expand_roots(roots: Sequence[complex]) -> list[complex]:
    """The roots of :func:`poly_from_roots`, each conjugate pair written out."""
    out: list[complex] = []
    for r in roots:
        out.append(complex(r))
        if r.imag != 0:
            out.append(complex(r).conjugate())
    return out


# ============================================================ Lambert W family
def lambert_roots(a: float, b: float, tau: float, im_max: float) -> np.ndarray:
    """All roots of ``s + a + b e^{-tau s}`` with ``|Im s| <= im_max`` (``b != 0``, ``tau > 0``).

    ``s_k = W_k(-b tau e^{a tau})/tau - a``: branch ``k`` has ``Im W_k`` within
    ``(2 pi k - 2 pi, 2 pi k + 2 pi)``, so the branches up to ``im_max tau/(2 pi) + 2``
    cover the band. Reliability: ``scipy.special.lambertw`` is accurate to a few ulps; the
    residual of every root is checked, and a double root (argument ``-1/e``) is refused.
    """
    if b == 0 or tau <= 0:
        raise ValueError("lambert_roots needs b != 0 and tau > 0")
    x = -b * tau * math.exp(a * tau)
    if not math.isfinite(x):
        raise OracleUnsure("argument of W overflows")
    if abs(x + math.exp(-1.0)) < 1e-8:
        raise OracleUnsure("double root (argument of W near -1/e)")
    kmax = int(im_max * tau / (2.0 * math.pi)) + 3
    ks = np.arange(-kmax, kmax + 1)
    s = np.array([complex(lambertw(x, int(k))) / tau - a for k in ks])
    scale = abs(a) + abs(b) + np.abs(s) + 1.0
    res = np.abs(s + a + b * np.exp(-tau * s)) / scale
    if not np.all(np.isfinite(s)) or np.max(res) > 1e-9:
        raise OracleUnsure(f"Lambert W residual {np.max(res):.3g}")
    principal = s[kmax]
    if np.max(s.real) > principal.real + 1e-12 * (1.0 + abs(principal)):
        raise AssertionError("oracle: a non-principal branch lies right of W_0 (contradicts Shinozaki-Mori)")
    return s[np.abs(s.imag) <= im_max]


def lambert_rightmost(a: float, b: float, tau: float) -> complex:
    """Rightmost root of ``s + a + b e^{-tau s}``: the principal branch (see module notes)."""
    x = -b * tau * math.exp(a * tau)
    return complex(lambertw(x, 0)) / tau - a


# ============================================================ commensurate delays
def z_roots(c: Sequence[float]) -> np.ndarray:
    """Roots of ``D(z) = sum_k c_k z^k`` (``c_0 != 0``), by ``mpmath.polyroots`` at 60 digits.

    Refuses (``OracleUnsure``) when the roots cannot be separated at that precision (a
    multiple root of ``D``).
    """
    c = list(c)
    while c and c[-1] == 0:
        c.pop()
    if len(c) < 2 or c[0] == 0:
        raise ValueError("z_roots needs c_0 != 0 and degree >= 1")
    with mp.workdps(_DPS):
        try:
            roots, err = _polyroots([mp.mpf(v) for v in c], extraprec=400)
        except mp.libmp.NoConvergence:
            raise OracleUnsure("polyroots did not converge (multiple root of D)") from None
        if err > mp.mpf(10) ** (-30):
            raise OracleUnsure(f"polyroots error {err}")
        return np.array([complex(r) for r in roots])


def chain_roots(z: Sequence[complex], h: float, box: Region) -> list[complex]:
    """The roots ``s = (-log z_j + 2 pi i m)/h`` of ``D(e^{-h s})`` inside ``box`` (and a
    guard band of one chain spacing around it)."""
    out: list[complex] = []
    x0, x1, y0, y1 = box
    step = 2.0 * math.pi / h
    for zj in z:
        base = -np.log(complex(zj)) / h
        if not (x0 - 1.0 <= base.real <= x1 + 1.0):
            continue
        m_lo = math.floor((y0 - base.imag) / step) - 1
        m_hi = math.ceil((y1 - base.imag) / step) + 1
        out.extend(complex(base.real, base.imag + m * step) for m in range(m_lo, m_hi + 1))
    return out


def chain_abscissa(z: Sequence[complex], h: float) -> float:
    """``max_j -log|z_j| / h``: every chain is a vertical line of roots at that real part."""
    return float(max(-math.log(abs(complex(v))) for v in z) / h)


# ============================================================ exact rational polynomials
def _trim(p: list[Fraction]) -> list[Fraction]:
    p = list(p)
    while len(p) > 1 and p[-1] == 0:
        p.pop()
    return p or [Fraction(0)]


def _padd(p: list[Fraction], q: list[Fraction]) -> list[Fraction]:
    n = max(len(p), len(q))
    return _trim([(p[k] if k < len(p) else 0) + (q[k] if k < len(q) else 0) for k in range(n)])


def _pscale(p: list[Fraction], c: Fraction) -> list[Fraction]:
    return _trim([c * v for v in p])


def _pmul(p: list[Fraction], q: list[Fraction]) -> list[Fraction]:
    out = [Fraction(0)] * (len(p) + len(q) - 1)
    for i, u in enumerate(p):
        for j, v in enumerate(q):
            out[i + j] += u * v
    return _trim(out)


def _pder(p: list[Fraction]) -> list[Fraction]:
    return _trim([k * p[k] for k in range(1, len(p))]) if len(p) > 1 else [Fraction(0)]


def _is_zero(p: list[Fraction]) -> bool:
    return len(p) == 1 and p[0] == 0


def _pdivmod(p: list[Fraction], q: list[Fraction]) -> tuple[list[Fraction], list[Fraction]]:
    p, q = _trim(p), _trim(q)
    if _is_zero(q):
        raise ZeroDivisionError("polynomial division by zero")
    if len(p) < len(q):
        return [Fraction(0)], p
    quot = [Fraction(0)] * (len(p) - len(q) + 1)
    r = list(p)
    for k in range(len(p) - len(q), -1, -1):
        c = r[k + len(q) - 1] / q[-1]
        quot[k] = c
        for j, v in enumerate(q):
            r[k + j] -= c * v
    return _trim(quot), _trim(r[: len(q) - 1] or [Fraction(0)])


def _pgcd(p: list[Fraction], q: list[Fraction]) -> list[Fraction]:
    p, q = _trim(p), _trim(q)
    while not _is_zero(q):
        p, q = q, _pdivmod(p, q)[1]
    return _pscale(p, 1 / p[-1])


def squarefree_parts(p: list[Fraction]) -> list[tuple[list[Fraction], int]]:
    """Yun's square-free decomposition over the rationals: ``p = c prod a_i^i``; returns
    the non-constant ``(a_i, i)``. Exact: a multiple root is recognised as such."""
    p = _trim(p)
    if len(p) == 1:
        return []
    dp = _pder(p)
    a0 = _pgcd(p, dp)
    b = _pdivmod(p, a0)[0]
    c = _pdivmod(dp, a0)[0]
    d = _padd(c, _pscale(_pder(b), Fraction(-1)))
    out = []
    i = 1
    while len(b) > 1:
        a = _pgcd(b, d)
        b = _pdivmod(b, a)[0]
        c = _pdivmod(d, a)[0]
        d = _padd(c, _pscale(_pder(b), Fraction(-1)))
        if len(a) > 1:
            out.append((a, i))
        i += 1
    return out


def _mp_roots(p: list[Fraction]) -> list:
    """Roots of a square-free rational polynomial at 60 digits."""
    if len(p) < 2:
        return []
    if len(p) == 2:
        with mp.workdps(_DPS):
            return [mp.mpf(-p[0].numerator * p[1].denominator) / (p[0].denominator * p[1].numerator)]
    with mp.workdps(_DPS):
        coeffs = [mp.mpf(v.numerator) / v.denominator for v in p]
        try:
            roots, err = _polyroots(coeffs, extraprec=600)
        except mp.libmp.NoConvergence:
            raise OracleUnsure("polyroots did not converge") from None
        if err > mp.mpf(10) ** (-40):
            raise OracleUnsure(f"polyroots error {err}")
        return list(roots)


def poly_roots(coefs: Sequence[float]) -> list[complex]:
    """Roots (with multiplicity) of a real polynomial whose float coefficients (increasing
    powers) are taken exactly: square-free parts over the rationals, then 60 digits."""
    out: list[complex] = []
    for part, mult in squarefree_parts(_trim([Fraction(v) for v in coefs])):
        out.extend(complex(r) for r in _mp_roots(part) for _ in range(mult))
    return out


def _mp_eval(p: Sequence[Fraction], s):
    acc = mp.mpf(0)
    for v in reversed(p):
        acc = acc * s + mp.mpf(v.numerator) / v.denominator
    return acc


# ============================================================ loops A + B e^{-delta s}
@dataclass(frozen=True)
class OracleCrossing:
    """A zero ``x_c = w_c^2 > 0`` of ``P`` with its multiplicity and crossing direction.

    ``theta`` is ``arg(-B/A) mod 2 pi`` at ``i w_c``: the delays are ``(theta + 2 pi k)/w_c``.
    ``direction`` is ``sign P'(x_c)`` for a simple zero (odd multiplicity: the sign of
    the first non-vanishing derivative), 0 for an even multiplicity (tangency).
    """

    omega: float
    multiplicity: int
    direction: int
    theta: float

    def delays(self, upto: float) -> list[float]:
        """``delta_{c,k} <= upto`` (at least the first)."""
        period = 2.0 * math.pi / self.omega
        first = self.theta / self.omega
        out = [first]
        while np.isfinite(upto) and out[-1] + period <= upto:
            out.append(out[-1] + period)
        return out


class LoopOracle:
    """The classical crossing analysis of ``F(s; delta) = A(s) + B(s) e^{-delta s}``.

    ``A`` and ``B`` are real polynomials (increasing powers, floats taken exactly). Only
    strongly stable loops are handled (``deg B < deg A`` or ``|b_n| < |a_n|``); others raise
    ``ValueError``. Reliability: ``P`` and ``A + B`` are formed over the rationals, the
    multiplicities of the zeros of ``P`` are exact (square-free decomposition), the zeros
    are located at 60 digits. ``nominal_unstable`` is None (unsure) when ``A + B`` has a
    zero within ``1e-12`` (relative) of the imaginary axis.
    """

    def __init__(self, a: Sequence[float], b: Sequence[float]) -> None:
        A = _trim([Fraction(v) for v in a])
        B = _trim([Fraction(v) for v in b])
        if _is_zero(A) or _is_zero(B):
            raise ValueError("A and B must be non-zero")
        n, m = len(A) - 1, len(B) - 1
        if m > n or (m == n and abs(B[-1]) >= abs(A[-1])):
            raise ValueError("the loop is not strongly stable (deg B > deg A or |b_n| >= |a_n|)")
        self.a, self.b = [float(v) for v in A], [float(v) for v in B]
        self._A, self._B = A, B
        self.zero_root = A[0] + B[0] == 0
        self.P = _padd(_abs2_on_axis(A), _pscale(_abs2_on_axis(B), Fraction(-1)))
        self.nominal_roots, self.nominal_unstable = self._nominal()
        self.crossings = self._crossings()

    # ---------------------------------------------------------------- nominal loop
    def _nominal(self) -> tuple[list[complex], int | None]:
        S = _padd(self._A, self._B)
        roots: list[complex] = []
        with mp.workdps(_DPS):
            for part, mult in squarefree_parts(S):
                for r in _mp_roots(part):
                    roots.extend([complex(r)] * mult)
        if len(roots) != len(S) - 1:
            raise OracleUnsure("lost a root of A + B")
        on_axis = any(abs(r.real) <= 1e-12 * (1.0 + abs(r)) for r in roots)
        return roots, None if on_axis else sum(r.real > 0 for r in roots)

    # ---------------------------------------------------------------- crossings
    def _crossings(self) -> list[OracleCrossing]:
        out: list[OracleCrossing] = []
        with mp.workdps(_DPS):
            for part, mult in squarefree_parts(self.P):
                rest = _pdivmod(self.P, _ppow(part, mult))[0]
                for r in _mp_roots(part):
                    r = mp.mpc(r)
                    if abs(r.imag) > mp.mpf(10) ** (-30) * (1 + abs(r)):
                        if abs(r.imag) < mp.mpf(10) ** (-20) * (1 + abs(r)):
                            raise OracleUnsure("zero of P neither clearly real nor clearly complex")
                        continue
                    x = r.real
                    if x <= 0:
                        if x > -(mp.mpf(10) ** (-30)):
                            raise OracleUnsure("zero of P at w = 0 to working precision")
                        continue
                    w = mp.sqrt(x)
                    if mult % 2 == 0:
                        direction = 0
                    else:
                        sgn = _mp_eval(_pder(part), x) * _mp_eval(rest, x)
                        direction = 1 if sgn > 0 else -1
                    s = mp.mpc(0, w)
                    ratio = -_mp_eval(self._B, s) / _mp_eval(self._A, s)
                    theta = mp.arg(ratio) % (2 * mp.pi)
                    if theta < mp.mpf(10) ** (-25) or 2 * mp.pi - theta < mp.mpf(10) ** (-25):
                        theta = mp.mpf(0)
                    out.append(OracleCrossing(float(w), mult, direction, float(theta)))
        return sorted(out, key=lambda c: c.theta / c.omega)

    # ---------------------------------------------------------------- verdicts
    @property
    def strongly_stable(self) -> bool:
        return True

    @property
    def margin(self) -> float:
        """First delay at which a root is on the axis (0 if the nominal loop is not stable)."""
        if self.zero_root or self.nominal_unstable != 0:
            return 0.0
        firsts = [c.theta / c.omega for c in self.crossings]
        return min(firsts) if firsts else math.inf

    def crossing_delays(self, upto: float) -> list[float]:
        return sorted(d for c in self.crossings for d in c.delays(upto) if d <= upto)

    def unstable_count(self, delta: float, rtol: float = 1e-9) -> int:
        """Number of zeros in ``Re s > 0`` at ``delta`` (the crossing count formula).

        Raises :class:`OracleUnsure` on (or within ``rtol`` of) a crossing delay, at a
        zero root, or when the nominal count is unsure.
        """
        if self.zero_root or self.nominal_unstable is None:
            raise OracleUnsure("root on the axis at delta = 0 or for every delta")
        n = self.nominal_unstable
        for c in self.crossings:
            for d in c.delays(delta * (1 + 2 * rtol) + 1e-300):
                if abs(d - delta) <= rtol * max(abs(delta), 1e-300) + 1e-300:
                    raise OracleUnsure(f"delta = {delta} on a crossing delay")
                if d < delta:
                    n += 2 * c.direction
        if n < 0:
            raise AssertionError("oracle: negative count (crossing analysis inconsistent)")
        return n

    def rhp_radius(self) -> float:
        """``R``: ``|A(s)| > |B(s)| >= |B(s) e^{-delta s}|`` for ``Re s >= 0``, ``|s| >= R``."""
        a, b = np.abs(self.a), np.abs(self.b)
        n = len(a) - 1
        R = 1.0
        for _ in range(200):
            lead = (a[n] - (b[n] if len(b) > n else 0.0)) * R**n
            rest = sum(a[k] * R**k for k in range(n)) + sum(b[k] * R**k for k in range(min(len(b), n)))
            if lead > 2.0 * rest:
                return R
            R *= 2.0
        raise OracleUnsure("no root-free radius")

    def count_by_argument(self, delta: float, max_pieces: int = 400_000) -> int:
        """Independent count of the zeros in ``Re s > 0`` at ``delta``: the argument
        principle on the boundary of the half disc ``{Re s > 0, |s| < R}``.

        Each piece ``[s_1, s_2]`` of the contour (length ``L``) is accepted only if
        ``|F(s_1)| > M L`` with ``M >= max |F'|`` on the piece (``|A'| + |B'| + delta |B|``
        bounded by the absolute coefficients, valid for ``Re s >= 0``): then ``F`` has no
        zero on the piece and its argument changes by less than ``pi/2``, read exactly from
        ``F(s_2)/F(s_1)``. Pieces that fail are halved; beyond ``max_pieces`` (a root on or
        near the axis) the oracle is unsure. Rounding is covered by a ``1e-12`` relative
        allowance on ``|F|``.
        """
        a, b = np.array(self.a), np.array(self.b)
        da, db = np.polynomial.polynomial.polyder(a), np.polynomial.polynomial.polyder(b)
        R = self.rhp_radius()

        def absval(c: np.ndarray, r: np.ndarray) -> np.ndarray:
            return np.polynomial.polynomial.polyval(r, np.abs(c))

        def F(s: np.ndarray) -> np.ndarray:
            pv = np.polynomial.polynomial.polyval
            return pv(s, a) + pv(s, b) * np.exp(-delta * s)

        def bound(r: np.ndarray) -> np.ndarray:
            return absval(da, r) + absval(db, r) + delta * absval(b, r)

        def slack(r: np.ndarray) -> np.ndarray:
            return 1e-12 * (absval(a, r) + absval(b, r))

        # Arc: angle from -pi/2 to pi/2; axis: Im s from R down to -R.
        arc, arc_pieces = _turn_along(
            lambda t: R * np.exp(1j * t),
            R,
            F,
            bound,
            slack,
            (-0.5 * math.pi, 0.5 * math.pi),
            257,
            max_pieces,
            "contour",
        )
        axis, _ = _turn_along(lambda t: 1j * t, 1.0, F, bound, slack, (R, -R), 257, max_pieces - arc_pieces, "contour")
        total = arc + axis
        turns = total / (2.0 * math.pi)
        n = round(turns)
        if abs(turns - n) > 1e-6:
            raise AssertionError(f"oracle: non-integer winding {turns}")
        return int(n)


def _turn_along(
    point: Callable[[np.ndarray], np.ndarray],
    speed: float,
    F: Callable[[np.ndarray], np.ndarray],
    bound: Callable[[np.ndarray], np.ndarray],
    slack: Callable[[np.ndarray], np.ndarray],
    span: tuple[float, float],
    samples: int,
    max_pieces: int,
    where: str,
) -> tuple[float, int]:
    """The turn of ``arg F`` along ``point(t)``, ``t`` over ``span`` (``|ds/dt| = speed``), and the pieces used.

    A piece of length ``L`` is accepted when ``|F(s_1)| > bound(r) L + slack(r)`` (``bound`` a bound of
    ``|F'|`` within radius ``r``): ``F`` has no zero on it and turns by less than ``pi/2``; otherwise it
    is halved. OracleUnsure beyond ``max_pieces`` (a zero near the path).
    """
    t = np.linspace(span[0], span[1], samples)
    starts, ends = t[:-1], t[1:]
    total, pieces = 0.0, starts.size
    with np.errstate(all="ignore"):
        while starts.size:
            s1, s2 = point(starts), point(ends)
            r = np.maximum(np.abs(s1), np.abs(s2))
            f1, f2 = F(s1), F(s2)
            length = speed * np.abs(ends - starts)
            ok = np.isfinite(f1) & np.isfinite(f2) & (np.abs(f1) > bound(r) * length + slack(r))
            total += float(np.sum(np.angle(f2[ok] / f1[ok])))
            mid = 0.5 * (starts[~ok] + ends[~ok])
            starts = np.concatenate([starts[~ok], mid])
            ends = np.concatenate([mid, ends[~ok]])
            pieces += mid.size
            if pieces > max_pieces:
                raise OracleUnsure(f"argument principle: more than {max_pieces} pieces (a zero near the {where})")
    return total, pieces


def _abs2_on_axis(p: list[Fraction]) -> list[Fraction]:
    """``|p(i w)|^2`` as a polynomial in ``x = w^2``: ``E(x)^2 + x O(x)^2`` with
    ``p(i w) = E(w^2) + i w O(w^2)``, ``E = p_0 - p_2 x + p_4 x^2 ...``, ``O = p_1 - p_3 x + ...``."""
    even = _trim([p[k] * (-1) ** (k // 2) for k in range(0, len(p), 2)] or [Fraction(0)])
    odd = _trim([p[k] * (-1) ** (k // 2) for k in range(1, len(p), 2)] or [Fraction(0)])
    return _padd(_pmul(even, even), _pmul([Fraction(0), Fraction(1)], _pmul(odd, odd)))


def _ppow(p: list[Fraction], k: int) -> list[Fraction]:
    out = [Fraction(1)]
    for _ in range(k):
        out = _pmul(out, p)
    return out


# ============================================================ transport plant
def transport_k_interval(q: float, rho: float) -> tuple[float, float] | None:
    """Admissible gains of ``U_BS2(K)`` on the uncoupled transport plant, any ``delta_max > 0``:
    ``(-k, k)`` with ``k = (1 - |rho q|)/|q|``, or None if ``|rho q| >= 1`` (module notes)."""
    rq = abs(Fraction(rho) * Fraction(q))
    if rq >= 1:
        return None
    k = float((1 - rq) / abs(Fraction(q)))
    return (-k, k)


def transport_margin(q: float, rho: float, K: float) -> float | None:
    """Delay margin of ``1 - rho q e^{-tau s} + K q e^{-(tau+delta) s}``: ``inf`` if
    ``|rho q| + |K q| < 1``; 0 if the nominal loop ``1 - (rho - K) q e^{-tau s}`` is unstable or
    ``|rho q| + |K q| > 1``; None (unsure) on the boundary."""
    Q, R, Kf = Fraction(q), Fraction(rho), Fraction(K)
    total = abs(R * Q) + abs(Kf * Q)
    nominal = abs((R - Kf) * Q)
    if nominal >= 1:
        return 0.0
    if total < 1:
        return math.inf
    if total > 1:
        return 0.0
    return None


def pair_birth(A, B0, q: float, tau: float, K0: float, w0: float) -> tuple[float, float, float]:
    """``(K_b, w_b, delay)``: where ``g(K, w) = |A(i w)|^2 - |B_K(i w)|^2`` with
    ``B_K = K q e^{-tau s} + B0`` has a double zero in ``w`` (``g = dg/dw = 0``), solved by
    scipy's ``fsolve`` from ``(K0, w0)`` on the values of ``A``, ``B0`` and their
    derivatives (callables ``P(s)`` and ``P.deriv_at(s)``), and the crossing delay born there."""

    def g(x: np.ndarray) -> list[float]:
        K, w = x
        s = np.array([1j * w])
        a, da, b0, db0 = A(s)[0], 1j * A.deriv_at(s)[0], B0(s)[0], 1j * B0.deriv_at(s)[0]
        e = np.exp(-1j * w * tau)
        b, db = K * q * e + b0, -1j * tau * K * q * e + db0
        return [abs(a) ** 2 - abs(b) ** 2, 2 * (np.conj(a) * da).real - 2 * (np.conj(b) * db).real]

    (K, w), info, ok, _ = fsolve(g, [K0, w0], xtol=1e-14, full_output=True)
    assert ok == 1 and max(abs(v) for v in info["fvec"]) < 1e-12
    s = np.array([1j * w])
    b = K * q * np.exp(-1j * w * tau) + B0(s)[0]
    return float(K), float(w), float(np.mod(np.angle(-b / A(s)[0]), 2 * np.pi) / w)


# ============================================================ 2x2 plants with constant coefficients
#: Controllers of :class:`PDELoop`: ``("open",)``, ``("finite",)`` (U_BS), ``("reflection", K)``
#: (U_BS2(K)) and ``("filtered", a, b)`` (U_BS through ``(1 + a s)/(1 + b s)``).
ControllerSpec = tuple


class PDELoop:
    """``F(s; delta) = A(s) + B(s) e^{-delta s}`` of the plant
    ``u_t + lam u_x = sigma_pm v``, ``v_t - mu v_x = sigma_mp u``, ``u(t, 0) = q v(t, 0)``,
    ``v(t, 1) = rho u(t, 1) + U(t)`` with a boundary controller, from the Laplace-domain solution.

    Derivation: along ``x`` the Laplace transforms satisfy ``d/dx [u; v] = M(s) [u; v]``; with
    ``[u; v](0) = [q; 1]`` and the factor ``e^{-s/mu}`` taken out, ``z = expm(B) [q; 1]`` with
    ``B = [[-s tau, sigma_pm/lam], [-sigma_mp/mu, 0]]`` and ``tau`` the double nearest
    ``1/lam + 1/mu`` (the plant nrobust's proofs are about). The open loop is
    ``A_ol = z_v - rho z_u = 1 - rho q e^{-tau s} + I_N(s)``; ``I_N = A_ol - 1 + rho q e^{-tau s}``,
    and the controllers close the loop as (``Phi = 1 - A_ol``): open ``(A_ol, 0)``, U_BS
    ``(A_ol, 1 - A_ol)``, U_BS2(K) ``(A_ol, K q e^{-tau s} - I_N)``, filtered
    ``((1 + b s) A_ol, (1 + a s)(1 - A_ol))``.

    Values at 30 digits come from ``mpmath.expm``; scans and contour integrals use the same
    exponential in closed form in double precision (``e^{t/2} (cosh d I + sinh(d)/d (B - t/2 I))``,
    ``t = -s tau``, ``d^2 = t^2/4 + det``), checked against ``mpmath.expm`` on every refined point.
    Bounds (far field, derivatives) use ``I_N(s) = int_0^tau N~(nu) e^{-nu s} dnu`` with the kernel
    ``N~ = h22 - rho q h11 + (m q - rho p)/tau W`` in hypergeometric functions (``p = sigma_pm/lam``,
    ``m = -sigma_mp/mu``, ``a = p m/tau^2``, ``x = a nu (tau - nu)``, ``W = 0F1(;1;x)``,
    ``h22 = a (tau - nu) 0F1(;2;x)``, ``h11 = a nu 0F1(;2;x)``), checked once against the
    ``expm`` route by quadrature: ``|I_N(s)| <= L1 e^{tau max(0, -Re s)}`` and, integrating by parts,
    ``|I_N(s)| <= V e^{tau max(0, -Re s)}/|s|`` with ``V = |N~(0)| + |N~(tau)| + TV(N~)``.
    """

    DPS = 30

    def __init__(
        self, lam: float, mu: float, spm: float, smp: float, q: float, rho: float, controller: ControllerSpec
    ) -> None:
        self.args = (lam, mu, spm, smp, q, rho)
        self.controller = controller
        self.tau = float(1.0 / lam + 1.0 / mu)
        self.q, self.rho = q, rho
        self.p = Fraction(spm) / Fraction(lam)
        self.m = -Fraction(smp) / Fraction(mu)
        self._kernel_bounds()

    # ---------------------------------------------------------------- values
    #: Extra digits of the current evaluation (set by :meth:`F_mp` for points far left, where terms of
    #: size ``e^{-Re s (tau + delta)}`` cancel and ``expm`` errs relative to its largest entry).
    _boost = 0

    def _mp_open(self, s):
        """``(A_ol, e^{-tau s})`` at ``s`` by ``mpmath.expm``."""
        with mp.workdps(self.DPS + 10 + self._boost):
            s = mp.mpc(s)
            tau = mp.mpf(self.tau)
            p = mp.mpf(self.p.numerator) / self.p.denominator
            m = mp.mpf(self.m.numerator) / self.m.denominator
            z = mp.expm(mp.matrix([[-s * tau, p], [m, 0]])) * mp.matrix([mp.mpf(self.q), 1])
            return z[1] - mp.mpf(self.rho) * z[0], mp.exp(-s * tau)

    def factors_mp(self, s):
        """``(A(s), B(s))`` at ``DPS`` digits."""
        aol, e = self._mp_open(s)
        with mp.workdps(self.DPS + 10 + self._boost):
            s = mp.mpc(s)
            kind = self.controller[0]
            if kind == "open":
                return aol, mp.mpc(0)
            if kind == "finite":
                return aol, 1 - aol
            if kind == "reflection":
                i_n = aol - 1 + mp.mpf(self.rho) * mp.mpf(self.q) * e
                return aol, mp.mpf(self.controller[1]) * mp.mpf(self.q) * e - i_n
            a, b = (mp.mpf(v) for v in self.controller[1:])
            return (1 + b * s) * aol, (1 + a * s) * (1 - aol)

    def _F_at(self, s, delta: float, boost: int):
        self._boost = boost
        try:
            A, B = self.factors_mp(s)
            with mp.workdps(self.DPS + 10 + boost):
                return A + B * mp.exp(-mp.mpc(s) * mp.mpf(delta))
        finally:
            self._boost = 0

    def F_mp(self, s, delta: float):
        """``F(s; delta)`` to ``DPS`` digits: the working precision grows with the size of the terms that
        cancel (``e^{-Re s (2 tau + delta)}``, a tiny ``rho q``), and two precisions 30 digits apart must
        agree, else OracleUnsure."""
        x = float(mp.re(mp.mpc(s)))
        rq = abs(self.rho * self.q)
        extra = max(0.0, -x) * (2.0 * self.tau + float(delta)) / math.log(10.0)
        extra += max(0.0, -math.log10(rq)) if rq > 0.0 else 0.0
        if not extra <= 2000.0:  # also infinite (a point at Re s = -inf) or nan
            raise OracleUnsure(f"terms at s = {s} need more than 2000 extra digits")
        boost = math.ceil(extra) + 5
        if boost > 2000:
            raise OracleUnsure(f"terms at s = {s} need more than 2000 extra digits")
        f1 = self._F_at(s, delta, boost)
        f2 = self._F_at(s, delta, boost + 30)
        with mp.workdps(self.DPS + 10):
            if abs(f1 - f2) > mp.mpf(10) ** (-self.DPS + 5) * (1 + abs(f2)):
                raise OracleUnsure(f"F at s = {s} is not settled at {self.DPS + 10 + boost} digits")
            return +f2

    def factors_np(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(A, B)`` in double precision (closed-form 2x2 exponential), vectorised."""
        s = np.asarray(s, dtype=complex)
        p, m, q, rho = float(self.p), float(self.m), self.q, self.rho
        t = -s * self.tau
        d = np.sqrt(t * t / 4 + p * m + 0j)
        small = np.abs(d) < 1e-4
        shd = np.where(small, 1 + d * d / 6, np.sinh(d) / np.where(small, 1.0, d))
        ch, g = np.cosh(d), np.exp(t / 2)
        zu = g * (ch * q + shd * (t / 2 * q + p))
        zv = g * (ch + shd * (m * q - t / 2))
        aol = zv - rho * zu
        e = np.exp(-s * self.tau)
        kind = self.controller[0]
        if kind == "open":
            return aol, np.zeros_like(aol)
        if kind == "finite":
            return aol, 1 - aol
        if kind == "reflection":
            return aol, self.controller[1] * q * e - (aol - 1 + rho * q * e)
        a, b = self.controller[1:]
        return (1 + b * s) * aol, (1 + a * s) * (1 - aol)

    def F_np(self, s: np.ndarray, delta: float) -> np.ndarray:
        A, B = self.factors_np(s)
        return A + B * np.exp(-delta * np.asarray(s, dtype=complex))

    def _check_np(self, s: complex, delta: float) -> None:
        """The double-precision closed form against ``mpmath.expm`` (oracle self-consistency)."""
        with np.errstate(all="ignore"):
            A, B = self.factors_np(np.array([s]))
        Am, Bm = self.factors_mp(s)
        scale = 1.0 + abs(complex(Am)) + abs(complex(Bm))
        err = abs(complex(A[0]) - complex(Am)) + abs(complex(B[0]) - complex(Bm))
        if not err <= 1e-9 * scale * (1.0 + abs(s) * self.tau):
            # terms of size e^{-Re s tau} cancel, each with a rounding error of a few eps of its size: beyond
            # e^{-Re s tau} 16 eps = 1e-9 (-Re s tau > 12.6) doubles cannot meet the tolerance above
            if math.exp(min(-s.real * self.tau, 700.0)) * 16.0 * np.finfo(float).eps > 1e-9:
                raise OracleUnsure(
                    f"the double-precision closed form cancels e^{{{-s.real * self.tau:.0f}}} at s = {s}"
                )
            raise AssertionError(f"oracle: closed-form exponential off by {err:.3g} at s = {s} (expm {complex(Am)})")

    # ---------------------------------------------------------------- kernel bounds
    def _kernel(self, nu: np.ndarray) -> np.ndarray:
        from scipy.special import hyp0f1

        p, m, tau, rq = float(self.p), float(self.m), self.tau, self.rho * self.q
        a = p * m / tau**2
        x = a * nu * (tau - nu)
        f2 = hyp0f1(2, x)
        return a * (tau - nu) * f2 - rq * a * nu * f2 + (m * self.q - self.rho * p) / tau * hyp0f1(1, x)

    def _kernel_bounds(self) -> None:
        """``L1 >= int |N~|`` and ``V >= |N~(0)| + |N~(tau)| + TV(N~)`` (fine grid, 2% allowance),
        and the kernel checked against the ``expm`` route by quadrature at one point."""
        n = 4001
        nu = np.linspace(0.0, self.tau, n)
        k = self._kernel(nu)
        top = float(np.max(np.abs(k)))
        h = self.tau / (n - 1)
        self.L1 = 1.02 * float(np.sum(np.abs(k)) * h) + top * h
        self.V = 1.02 * (abs(k[0]) + abs(k[-1]) + float(np.sum(np.abs(np.diff(k))))) + 1e-12
        s0 = mp.mpc("0.37", "1.9")
        aol, e = self._mp_open(s0)
        with mp.workdps(20):
            i_n = aol - 1 + mp.mpf(self.rho) * mp.mpf(self.q) * e
            p, m, tau, rq = (mp.mpf(float(self.p)), mp.mpf(float(self.m)), mp.mpf(self.tau), self.rho * self.q)
            a = p * m / tau**2

            def kern(v):
                x = a * v * (tau - v)
                f2 = mp.hyp0f1(2, x)
                return a * (tau - v) * f2 - rq * a * v * f2 + (m * self.q - self.rho * p) / tau * mp.hyp0f1(1, x)

            quad = mp.quad(lambda v: kern(v) * mp.exp(-s0 * v), mp.linspace(0, tau, 5))
            if abs(quad - i_n) > 1e-12 * (1 + abs(i_n) + self.L1):
                raise AssertionError(f"oracle: kernel quadrature {quad} against expm route {i_n}")

    # ---------------------------------------------------------------- bounds on Re s >= x0
    def _consts(self, x0: float, delta: float) -> tuple[float, float, float, float]:
        try:
            return (
                math.exp(-self.tau * x0),
                math.exp(-delta * x0),
                math.exp(self.tau * max(0.0, -x0)),
                abs(self.rho * self.q),
            )
        except OverflowError:
            raise OracleUnsure(f"bounds at Re s >= {x0:.4g} overflow double precision") from None

    def principal_gap(self, x0: float, delta: float) -> float:
        """Lower bound of ``|principal part|/|s|^n`` on ``Re s >= x0`` (``> 0``: strongly dominated)."""
        et, ed, _, rq = self._consts(x0, delta)
        kind = self.controller[0]
        if kind == "open":
            return 1 - rq * et
        if kind == "finite":
            return 1 - rq * et - rq * et * ed
        if kind == "reflection":
            return 1 - rq * et - abs(self.controller[1] * self.q) * et * ed
        a, b = self.controller[1:]
        return b * (1 - rq * et) - abs(a) * rq * et * ed

    def _lower(self, x0: float, delta: float, R: float) -> float:
        """Lower bound of ``|F(s)|/|s|^n`` on ``{Re s >= x0, |s| >= R}``."""
        et, ed, ei, rq = self._consts(x0, delta)
        g0, V = self.principal_gap(x0, delta), self.V * ei
        kind = self.controller[0]
        if kind == "open":
            return g0 - V / R
        if kind in ("finite", "reflection"):
            return g0 - V * (1 + ed) / R
        a, b = self.controller[1:]
        return g0 - (1 - rq * et) / R - rq * et * ed / R - V * (1 / R + b) / R - V * (1 / R + abs(a)) * ed / R

    def far_field(self, x0: float, delta: float, cap: float = 2e4) -> float:
        """``R``: no zero of ``F(.; delta)`` in ``{Re s >= x0, |s| >= R}``; OracleUnsure beyond ``cap``."""
        if self.principal_gap(x0, delta) <= 1e-9:
            raise OracleUnsure(f"principal part not dominant on Re s >= {x0}")
        R = 1.0
        try:
            with np.errstate(over="raise", invalid="raise"):  # far left (rho q = 1e-226) the bounds leave doubles
                while self._lower(x0, delta, R) <= 0.0:
                    R *= 1.25
                    if R > cap:
                        raise OracleUnsure(f"far-field radius above {cap}")
        except FloatingPointError:
            raise OracleUnsure(f"bounds at Re s >= {x0:.4g} overflow double precision") from None
        return R

    def _derivative_bound(self, x0: float, delta: float, r: np.ndarray) -> np.ndarray:
        """Bound of ``|F'|`` on ``{Re s >= x0, |s| <= r}``."""
        et, ed, ei, rq = self._consts(x0, delta)
        tau, L = self.tau, self.L1 * ei
        Ab = 1 + rq * et + L
        dAb = tau * (rq * et + L)
        kind = self.controller[0]
        if kind == "open":
            return np.full_like(r, dAb)
        if kind == "finite":
            return dAb + (dAb + delta * (1 + Ab)) * ed + 0 * r
        if kind == "reflection":
            kq = abs(self.controller[1] * self.q)
            Bb, dBb = kq * et + L, tau * (kq * et + L)
            return dAb + (dBb + delta * Bb) * ed + 0 * r
        a, b = self.controller[1:]
        dA = b * Ab + (1 + b * r) * dAb
        Bb = (1 + abs(a) * r) * (1 + Ab)
        dB = abs(a) * (1 + Ab) + (1 + abs(a) * r) * dAb
        return dA + (dB + delta * Bb) * ed

    def _size_bound(self, x0: float, delta: float, r: np.ndarray) -> np.ndarray:
        """Bound of ``|A| + |B|`` on ``{Re s >= x0, |s| <= r}`` (the rounding allowance)."""
        et, ed, ei, rq = self._consts(x0, delta)
        Ab = 1 + rq * et + self.L1 * ei
        if self.controller[0] == "filtered":
            a, b = self.controller[1:]
            return (1 + b * r) * Ab + (1 + abs(a) * r) * (1 + Ab) * ed
        return Ab + (1 + Ab) * ed + 0 * r

    # ---------------------------------------------------------------- counts and roots
    def count_in_box(self, box: Region, delta: float, max_pieces: int = 400_000) -> int:
        """Zeros of ``F(.; delta)`` inside ``box`` by the argument principle (as
        :meth:`LoopOracle.count_by_argument`: a piece of length ``L`` is accepted when
        ``|F(s_1)| > M L + rounding`` with ``M`` a bound of ``|F'|``, so that ``F`` has no zero on it
        and turns by less than ``pi/2``); OracleUnsure beyond ``max_pieces`` (a zero near the edge)."""
        x0, x1, y0, y1 = box
        corners = [complex(x0, y0), complex(x1, y0), complex(x1, y1), complex(x0, y1), complex(x0, y0)]
        total, pieces = 0.0, 0
        with np.errstate(all="ignore"):
            for c1, c2 in itertools.pairwise(corners):
                turn, used = _turn_along(
                    lambda t, c1=c1, c2=c2: c1 + (c2 - c1) * t,
                    abs(c2 - c1),
                    lambda z: self.F_np(z, delta),
                    lambda r: self._derivative_bound(x0, delta, r),
                    lambda r: 1e-11 * self._size_bound(x0, delta, r) * (1 + r * self.tau),
                    (0.0, 1.0),
                    513,
                    max_pieces - pieces,
                    str(box),
                )
                total, pieces = total + turn, pieces + used
        turns = total / (2.0 * math.pi)
        n = round(turns)
        if abs(turns - n) > 1e-6:
            raise AssertionError(f"oracle: non-integer winding {turns}")
        return int(n)

    def polish(self, s0: complex, delta: float, steps: int = 60):
        """A zero of ``F(.; delta)`` by the secant method at ``DPS`` digits from ``s0``; OracleUnsure
        if it does not converge (``|step| < 1e-25 (1 + |s|)``)."""
        with mp.workdps(self.DPS + 10):
            x0 = mp.mpc(s0)
            x1 = x0 + mp.mpf(10) ** -7 * (1 + abs(x0))
            f0, f1 = self.F_mp(x0, delta), self.F_mp(x1, delta)
            for _ in range(steps):
                if f1 == f0:
                    break
                x2 = x1 - f1 * (x1 - x0) / (f1 - f0)
                if abs(x2 - x1) < mp.mpf(10) ** -25 * (1 + abs(x2)):
                    return x2
                x0, f0, x1, f1 = x1, f1, x2, self.F_mp(x2, delta)
            raise OracleUnsure(f"secant iteration from {s0} did not converge")

    def is_zero(self, s: complex, delta: float) -> bool:
        """True if the double ``s`` is a zero of ``F(.; delta)`` to its rounding: ``|F(s)|`` within
        ``1000 |F'(s)| eps (1 + |s|)`` (a zero rounded to a double moves ``F`` by ``|F'| eps |s|``).

        A secant iteration (:meth:`polish`) can stall far left, where ``F`` is the small difference of
        terms of size ``e^{-Re s tau}`` and flat at the working precision, at a point that is no zero
        (``|F| = 1`` was seen there, with ``|F'| = 1e-3``).
        """
        value = self.F_mp(s, delta)
        with mp.workdps(self.DPS + 10):
            h = mp.mpf(10) ** -12 * (1 + abs(mp.mpc(s)))
            slope = abs(self.F_mp(mp.mpc(s) + h, delta) - self.F_mp(mp.mpc(s) - h, delta)) / (2 * h)
            return bool(abs(value) <= 1000 * slope * mp.mpf(2.0**-52) * (1 + abs(mp.mpc(s))))

    def roots_near(self, box: Region, delta: float, n_re: int = 12, n_im: int = 60) -> list[complex]:
        """Zeros of ``F(.; delta)`` reached by Newton's method in double precision from a grid of
        seeds in ``box`` (``Im >= 0`` half: ``F`` is real), then polished at ``DPS`` digits; not
        a complete search (the counts are :meth:`count_in_box`)."""
        x0, x1, y0, y1 = box
        s = newton_from_grid(lambda z: self.F_np(z, delta), box, n_re, n_im, steps=40, max_step=1.0)
        width = max(x1 - x0, y1 - y0)
        top = max(abs(y0), abs(y1)) + width
        keep = np.isfinite(s) & (s.real > x0 - width) & (s.real < x1 + width) & (np.abs(s.imag) < top)
        with np.errstate(all="ignore"):
            res = np.abs(self.F_np(s, delta)) / (1 + self._size_bound(min(x0, 0.0), delta, np.abs(s)))

        def polished(z: complex) -> complex:
            r = complex(self.polish(z, delta))
            self._check_np(r, delta)
            return r

        return distinct_polished(s[keep & (res < 1e-6)], polished)

    # ---------------------------------------------------------------- delay margin
    def nominal_unstable(self) -> int:
        """Zeros of ``F(.; 0)`` with ``Re s > 0`` (argument principle on ``[0, R] x [-R, R]``)."""
        R = self.far_field(0.0, 0.0)
        return self.count_in_box((0.0, R, -R, R), 0.0)

    def crossings(self, max_crossings: int = 60) -> list[tuple[float, float]]:
        """``(w, delta_0)`` of every ``w > 0`` with ``|A(i w)| = |B(i w)|`` (below the far field at
        ``Re s >= 0``): sign changes of ``g = |A| - |B|`` on a grid of step ``2 pi/(256 tau)``, refined by
        ``mpmath.findroot`` at ``DPS`` digits; OracleUnsure at a local minimum of ``|g|`` that may touch
        zero between grid points (tangency), at ``g(0) ~ 0``, or above ``max_crossings``."""
        if self.controller[0] == "open":
            return []
        W = self.far_field(0.0, 0.0)
        step = 2 * math.pi / (256 * self.tau)
        if self.controller[0] == "filtered":
            step = min(step, 0.02 * min(self.controller[2], 1.0 / max(abs(self.controller[1]), 1e-9)))
        w = np.linspace(0.0, W, int(W / step) + 2)
        with np.errstate(all="ignore"):
            A, B = self.factors_np(1j * w)
        g = np.abs(A) - np.abs(B)
        size = np.abs(A) + np.abs(B)
        if not np.all(np.isfinite(g)):
            raise OracleUnsure("non-finite values on the imaginary axis")
        if abs(g[0]) <= 1e-9 * size[0]:
            raise OracleUnsure("|A(0)| = |B(0)| to rounding")
        if g[-1] <= 0:
            raise AssertionError("oracle: |A| <= |B| at the far-field bound")
        # touching zero between grid points: at a discrete local minimum of |g|, the drop of the
        # parabola through three points plus twice the second difference (the grid resolves the
        # fastest oscillation, period 2 pi/tau, by 256 points) reaches |g|
        inner = np.arange(1, g.size - 1)
        local_min = (np.abs(g[inner]) <= np.abs(g[inner - 1])) & (np.abs(g[inner]) <= np.abs(g[inner + 1]))
        same = np.sign(g[inner - 1]) == np.sign(g[inner + 1])
        d1 = g[inner + 1] - g[inner - 1]
        d2 = np.abs(g[inner + 1] - 2 * g[inner] + g[inner - 1])
        drop = d1 * d1 / (8 * d2 + 1e-300)
        near = np.abs(g[inner]) <= drop + 2 * d2 + 1e-9 * size[inner]
        if np.any(local_min & same & near):
            raise OracleUnsure(f"|A| - |B| touches zero near w = {w[inner[local_min & same & near]][:3]}")
        idx = np.flatnonzero(np.sign(g[:-1]) != np.sign(g[1:]))
        if idx.size > max_crossings:
            raise OracleUnsure(f"{idx.size} crossings")
        out = []
        for i in idx:

            def gm(v):
                Av, Bv = self.factors_mp(mp.mpc(0, v))
                return abs(Av) - abs(Bv)

            with mp.workdps(self.DPS + 10):
                try:
                    wc = mp.findroot(gm, (mp.mpf(w[i]), mp.mpf(w[i + 1])), solver="anderson")
                except (ValueError, ZeroDivisionError):
                    raise OracleUnsure(f"findroot failed in [{w[i]}, {w[i + 1]}]") from None
                if not (w[i] - step <= wc <= w[i + 1] + step):
                    raise OracleUnsure(f"findroot left the bracket [{w[i]}, {w[i + 1]}]")
                Av, Bv = self.factors_mp(mp.mpc(0, wc))
                phase = (-mp.arg(-Av / Bv)) % (2 * mp.pi)
                if phase < mp.mpf(10) ** -20 or 2 * mp.pi - phase < mp.mpf(10) ** -20:
                    raise OracleUnsure(f"a zero on the axis at delta = 0 (w = {wc})")
                self._check_np(complex(0, float(wc)), 0.0)
                out.append((float(wc), float(phase / wc)))
        return out

    def margin(self) -> float:
        """The delay margin: 0 when the principal part is not dominated on ``Re s >= 0`` or the
        nominal loop has a zero in ``Re s > 0``; else the smallest crossing delay (``inf`` if none)."""
        g0 = self.principal_gap(0.0, 0.0)
        if abs(g0) <= 1e-12:
            raise OracleUnsure("principal part on the strong-stability boundary")
        if g0 < 0:
            return 0.0
        if self.nominal_unstable() > 0:
            return 0.0
        cross = self.crossings()
        return min((d for _, d in cross), default=math.inf)


@dataclass(frozen=True)
class Profile:
    """A coefficient ``c0 + c1 sin(w x + phi)`` (``kind == "sin"``) or ``c0 e^{w x}`` (``"exp"``):
    the same formula as a numpy/ball callable for nrobust and in mpmath for the oracle."""

    kind: str
    c0: float
    c1: float = 0.0
    w: float = 0.0
    phi: float = 0.0

    def numpy(self) -> Callable[[np.ndarray], np.ndarray]:
        c0, c1, w, phi = self.c0, self.c1, self.w, self.phi
        if self.kind == "exp":
            return lambda x: c0 * np.exp(w * x)
        return lambda x: c0 + c1 * np.sin(w * x + phi)

    def mp(self, x):
        c0, c1, w, phi = (mp.mpf(v) for v in (self.c0, self.c1, self.w, self.phi))
        return c0 * mp.exp(w * x) if self.kind == "exp" else c0 + c1 * mp.sin(w * x + phi)


class VaryingPDELoop:
    """``F(s; delta) = A(s) + B(s) e^{-delta s}`` of the plant with varying coefficients
    ``u_t + lam u_x = a(x) u + b(x) v``, ``v_t - mu v_x = c(x) u + d(x) v`` on ``[0, L]``,
    ``u(t, 0) = q v(t, 0)``, ``v(t, L) = rho u(t, L) + U(t)``, from the Laplace-domain ODE.

    Derivation: the Laplace transforms satisfy ``u_x = ((a - s) u + b v)/lam``,
    ``v_x = ((s - d) v - c u)/mu``; from ``[u; v](0) = [q; 1]`` (the solution is determined up to
    the value ``v(0)``) the boundary condition at ``L`` gives the characteristic function
    ``A = w (v(L) - rho u(L))``, normalised by ``w = e^{-s L/mu - D(L)}``, ``D(L) = -int_0^L d/mu``
    (so that its principal part is ``1 - rho q e^{A(L) - D(L)} e^{-tau s}``, ``A(L) = int_0^L
    a/lam``, ``tau = L/lam + L/mu``). A law ``U = k u(t, L)`` closes the loop with
    ``B = -k w u(L)``; the backstepping laws of the paper (its normal form, eqs. (10)-(16)):
    U_BS ``B = 1 - A``, U_BS2(K) ``B = 1 - A + (K q~ - rho q e^{A(L) - D(L)}) e^{-tau s}`` with
    ``q~`` the normal form's ``q`` (``K`` is read in its coordinates).

    Values at ``DPS`` digits come from ``mpmath.odefun`` (a Taylor integrator), ``A(L)`` and
    ``D(L)`` from ``mpmath.quad``; scans use scipy's DOP853 at ``rtol = 1e-12``. Frequency scans
    cover a band, not the whole axis: a crossing above it is not looked for.
    """

    DPS = 20
    #: ``crossing_near`` stops at a secant step below ``10^-STEP_DIGITS``.
    STEP_DIGITS = 2 * DPS - 8

    def __init__(
        self,
        lam: float,
        mu: float,
        length: float,
        coefs: dict[str, Profile],
        q: float,
        rho: float,
        controller: tuple,
        q_normal: float | None = None,
    ) -> None:
        self.lam, self.mu, self.L, self.coefs, self.q, self.rho = lam, mu, length, coefs, q, rho
        self.controller, self.q_normal = controller, q if q_normal is None else q_normal
        self.tau = length / lam + length / mu
        with mp.workdps(self.DPS + 10):
            L = mp.mpf(length)
            self.A_L = mp.quad(lambda x: coefs["a"].mp(x), [0, L]) / lam
            self.D_L = -mp.quad(lambda x: coefs["d"].mp(x), [0, L]) / mu
            self.principal = mp.mpf(rho) * mp.mpf(q) * mp.exp(self.A_L - self.D_L)

    def _end(self, s):
        """``(w u(L), w v(L))`` at ``DPS`` digits."""
        lam, mu, co = mp.mpf(self.lam), mp.mpf(self.mu), self.coefs
        with mp.workdps(self.DPS + 5):
            s = mp.mpc(s)

            def rhs(x, y):
                return [
                    ((co["a"].mp(x) - s) * y[0] + co["b"].mp(x) * y[1]) / lam,
                    ((s - co["d"].mp(x)) * y[1] - co["c"].mp(x) * y[0]) / mu,
                ]

            u, v = mp.odefun(rhs, 0, [mp.mpf(self.q), mp.mpf(1)])(mp.mpf(self.L))
            w = mp.exp(-s * mp.mpf(self.L) / mu - self.D_L)
            return w * u, w * v

    def factors_mp(self, s):
        """``(A(s), B(s), w u(L, s))``."""
        u, v = self._end(s)
        with mp.workdps(self.DPS + 5):
            s = mp.mpc(s)
            A = v - mp.mpf(self.rho) * u
            kind = self.controller[0]
            if kind == "open":
                B = mp.mpc(0)
            elif kind == "finite":
                B = 1 - A
            elif kind == "reflection":
                gain = mp.mpf(self.controller[1]) * mp.mpf(self.q_normal) - self.principal
                B = 1 - A + gain * mp.exp(-s * mp.mpf(self.tau))
            else:  # ("state", k): U = k u(t, L)
                B = -mp.mpf(self.controller[1]) * u
            return A, B, u

    def gap_np(self, w: np.ndarray) -> np.ndarray:
        """``|A(i w)| - |B(i w)|`` in double precision (DOP853), one ODE per frequency."""
        from scipy.integrate import solve_ivp

        co = {k: p.numpy() for k, p in self.coefs.items()}
        out = np.empty(len(w))
        D_L, prin = float(self.D_L), float(self.principal)
        for i, wi in enumerate(w):
            s = 1j * wi

            def rhs(x: float, y: np.ndarray, s: complex = s) -> np.ndarray:
                return np.array(
                    [
                        ((co["a"](x) - s) * y[0] + co["b"](x) * y[1]) / self.lam,
                        ((s - co["d"](x)) * y[1] - co["c"](x) * y[0]) / self.mu,
                    ]
                )

            sol = solve_ivp(
                rhs, (0.0, self.L), np.array([self.q, 1.0], dtype=complex), "DOP853", rtol=1e-12, atol=1e-14
            )
            u, v = sol.y[:, -1] * np.exp(-s * self.L / self.mu - D_L)
            A = v - self.rho * u
            kind = self.controller[0]
            if kind == "open":
                B = 0.0
            elif kind == "finite":
                B = 1 - A
            elif kind == "reflection":
                B = 1 - A + (self.controller[1] * self.q_normal - prin) * np.exp(-s * self.tau)
            else:
                B = -self.controller[1] * u
            out[i] = abs(A) - abs(B)
        return out

    def crossing_near(self, w0: float) -> tuple[float, float]:
        """``(w, delta)`` of the crossing ``|A(i w)| = |B(i w)|`` nearest ``w0`` (mpmath.findroot, secant),
        ``delta`` the smallest delay of that crossing; OracleUnsure if it does not settle."""

        def g(w):
            A, B, _ = self.factors_mp(mp.mpc(0, w))
            return abs(A) ** 2 - abs(B) ** 2

        with mp.workdps(self.DPS):
            try:
                # the secant's second point near w0 (mpmath's default, w0 + 1/4, costs several more solves)
                start = (mp.mpf(w0), mp.mpf(w0) * (1 + mp.mpf(10) ** -8) + mp.mpf(10) ** -8)
                w = mp.findroot(g, start, tol=mp.mpf(10) ** -self.STEP_DIGITS)
            except (ValueError, ZeroDivisionError):
                raise OracleUnsure(f"findroot did not settle near w = {w0}") from None
            if abs(w - w0) > 1e-6 * (1 + abs(w0)):
                raise OracleUnsure(f"findroot went from {w0} to {w}")
            A, B, _ = self.factors_mp(mp.mpc(0, w))
            return float(w), float(((-mp.arg(-A / B)) % (2 * mp.pi)) / w)

    def crossings_in_band(self, w_max: float) -> list[tuple[float, float]]:
        """``(w, delta)`` of the sign changes of ``|A| - |B|`` on ``(0, w_max]`` (step ``2 pi/(64 tau)``,
        refined by bisection in double precision); a local minimum of ``||A| - |B||`` below ``1e-6``
        between grid points raises OracleUnsure (a tangency the grid cannot resolve)."""
        from scipy.optimize import brentq

        if self.controller[0] == "open":
            return []
        n = int(w_max / (2 * math.pi / (64 * self.tau))) + 2
        w = np.linspace(1e-3, w_max, n)
        g = self.gap_np(w)
        inner = np.arange(1, n - 1)
        low = (np.abs(g[inner]) <= np.abs(g[inner - 1])) & (np.abs(g[inner]) <= np.abs(g[inner + 1]))
        if np.any(low & (np.abs(g[inner]) < 1e-6) & (np.sign(g[inner - 1]) == np.sign(g[inner + 1]))):
            raise OracleUnsure("|A| - |B| nearly touches zero between grid points")
        out = []
        for i in np.flatnonzero(np.sign(g[:-1]) != np.sign(g[1:])):
            wc = brentq(lambda x: float(self.gap_np(np.array([x]))[0]), w[i], w[i + 1], xtol=1e-13)
            A, B, _ = self.factors_mp(mp.mpc(0, wc))
            with mp.workdps(self.DPS):
                out.append((wc, float(((-mp.arg(-A / B)) % (2 * mp.pi)) / wc)))
        return out


@dataclass(frozen=True)
class Speed:
    """A speed on ``[0, L]``: ``c0 (1 + e1 x + e2 x^2)`` (``kind == "poly"``) or ``c0 e^{e1 x}``
    (``"exp"``), or another speed divided by ``ratio`` (``of`` that speed: a constant ratio). The same
    formula as a callable for nrobust (numpy arrays and python-flint ``arb_series`` alike: only
    arithmetic and ``np.exp``) and in mpmath for the oracle."""

    kind: str
    c0: float
    e1: float = 0.0
    e2: float = 0.0
    of: Speed | None = None

    def numpy(self) -> Callable[[Any], Any]:
        c0, e1, e2 = self.c0, self.e1, self.e2
        if self.of is not None:
            base = self.of.numpy()
            return lambda x: base(x) / c0
        if self.kind == "exp":
            return lambda x: c0 * np.exp(e1 * x)
        return lambda x: c0 * (1.0 + e1 * x + e2 * x * x)

    def mp(self, x):
        c0, e1, e2 = (mp.mpf(v) for v in (self.c0, self.e1, self.e2))
        if self.of is not None:
            return self.of.mp(x) / c0
        return c0 * mp.exp(e1 * x) if self.kind == "exp" else c0 * (1 + e1 * x + e2 * x * x)


class VaryingSpeedPDELoop(VaryingPDELoop):
    """:class:`VaryingPDELoop` with speeds ``lam(x)``, ``mu(x)`` that vary and a time unit.

    The Laplace-domain equations of the plant as given, in its own ``x`` (no change of variable):
    ``u_x = ((a - z) u + b v)/lam(x)``, ``v_x = ((z - d) v - c u)/mu(x)`` with ``z = s / time_unit``
    (``s`` the Laplace variable in the plant's time unit, as nrobust's delays and frequencies), from
    ``[u; v](0) = [q; 1]``; the normalisation ``w = e^{-z t_v - D(L)}`` with ``t_v = int_0^L 1/mu``,
    ``D(L) = -int_0^L d/mu``, ``A(L) = int_0^L a/lam`` (``mpmath.quad``), so the principal part of
    the open loop is ``1 - rho q e^{A(L) - D(L)} e^{-tau s}`` with
    ``tau = (int_0^L 1/lam + 1/mu) / time_unit``: a characteristic leaves ``x = 0`` and returns after
    ``t_u + t_v``, and ``u``, ``v`` gain ``e^{A}``, ``e^{-D}`` on the way. The loops closed by
    ``B`` are those of :class:`VaryingPDELoop`. Values at ``DPS`` digits (``mpmath.odefun``).
    """

    DPS = 25
    #: Steps of about the values' 25 digits (the crossing's delay to 1e-20 or better): each step is an ODE
    #: solve of about a second, and smaller steps only chase the rounding.
    STEP_DIGITS = DPS - 3

    def __init__(
        self,
        lam: Speed,
        mu: Speed,
        length: float,
        coefs: dict[str, Profile],
        q: float,
        rho: float,
        controller: tuple,
        q_normal: float | None = None,
        time_unit: float = 1.0,
    ) -> None:
        self.lam_of, self.mu_of, self.time_unit = lam, mu, time_unit
        self.L, self.coefs, self.q, self.rho = length, coefs, q, rho
        self.controller, self.q_normal = controller, q if q_normal is None else q_normal
        with mp.workdps(self.DPS + 10):
            L = mp.mpf(length)
            self.t_u = mp.quad(lambda x: 1 / lam.mp(x), [0, L])
            self.t_v = mp.quad(lambda x: 1 / mu.mp(x), [0, L])
            self.tau = float((self.t_u + self.t_v) / mp.mpf(time_unit))
            self.A_L = mp.quad(lambda x: coefs["a"].mp(x) / lam.mp(x), [0, L])
            self.D_L = -mp.quad(lambda x: coefs["d"].mp(x) / mu.mp(x), [0, L])
            self.principal = mp.mpf(rho) * mp.mpf(q) * mp.exp(self.A_L - self.D_L)

    def _end(self, s):
        """``(w u(L), w v(L))`` at ``DPS`` digits, ``s`` in the plant's time unit."""
        lam, mu, co = self.lam_of.mp, self.mu_of.mp, self.coefs
        with mp.workdps(self.DPS + 5):
            z = mp.mpc(s) / mp.mpf(self.time_unit)

            def rhs(x, y):
                return [
                    ((co["a"].mp(x) - z) * y[0] + co["b"].mp(x) * y[1]) / lam(x),
                    ((z - co["d"].mp(x)) * y[1] - co["c"].mp(x) * y[0]) / mu(x),
                ]

            u, v = mp.odefun(rhs, 0, [mp.mpf(self.q), mp.mpf(1)])(mp.mpf(self.L))
            w = mp.exp(-z * self.t_v - self.D_L)
            return w * u, w * v

    def gap_np(self, w: np.ndarray) -> np.ndarray:
        """``|A(i w)| - |B(i w)|`` in double precision (DOP853), one ODE per frequency."""
        from scipy.integrate import solve_ivp

        co = {k: p.numpy() for k, p in self.coefs.items()}
        lam, mu = self.lam_of.numpy(), self.mu_of.numpy()
        t_v, D_L, prin = float(self.t_v), float(self.D_L), float(self.principal)
        out = np.empty(len(w))
        for i, wi in enumerate(w):
            s = 1j * wi
            z = s / self.time_unit

            def rhs(x: float, y: np.ndarray, z: complex = z) -> np.ndarray:
                return np.array(
                    [
                        ((co["a"](x) - z) * y[0] + co["b"](x) * y[1]) / lam(x),
                        ((z - co["d"](x)) * y[1] - co["c"](x) * y[0]) / mu(x),
                    ]
                )

            sol = solve_ivp(
                rhs, (0.0, self.L), np.array([self.q, 1.0], dtype=complex), "DOP853", rtol=1e-12, atol=1e-14
            )
            u, v = sol.y[:, -1] * np.exp(-z * t_v - D_L)
            A = v - self.rho * u
            kind = self.controller[0]
            if kind == "reflection":
                B = 1 - A + (self.controller[1] * self.q_normal - prin) * np.exp(-s * self.tau)
            else:  # ("state", k): U = k u(t, L)
                B = -self.controller[1] * u
            out[i] = abs(A) - abs(B)
        return out


@functools.cache
def gauss_legendre(n: int, dps: int) -> tuple[list, list]:
    """Gauss-Legendre nodes and weights on ``[0, 1]`` at ``dps`` digits (numpy's nodes refined by Newton)."""
    with mp.workdps(dps + 10):
        nodes, weights = [], []
        for x0 in np.polynomial.legendre.leggauss(n)[0]:
            x = mp.findroot(lambda t: mp.legendre(n, t), mp.mpf(x0))
            dp = n * (x * mp.legendre(n, x) - mp.legendre(n - 1, x)) / (x * x - 1)
            nodes.append((x + 1) / 2)
            weights.append(1 / ((1 - x * x) * dp * dp))
        return nodes, weights


def one_plus_one_factors(s: mp.mpc, plant: Sequence[float], k: float) -> tuple[mp.mpc, mp.mpc]:
    """``(A(s), B(s))`` of the ``1 + 1`` loop of ``plant = (lam, mu, sigma+-, sigma-+, q, r)`` under
    ``U = k u(t - delta, 1)``: the closed form of the 2x2 exponential (``cosh``/``sinh`` of its eigenvalues), at the
    working precision."""
    lam, mu, s_pm, s_mp, q, r = (mp.mpf(v) for v in plant)
    a, b = -s / lam, s_pm / lam
    c, d = -s_mp / mu, s / mu
    half = (a + d) / 2
    root = mp.sqrt(half**2 - (a * d - b * c))
    ch = mp.cosh(root)
    sh = mp.sinh(root) / root if root != 0 else mp.mpf(1)
    e = mp.exp(half)
    phi_u = e * (ch + sh * (a - half)) * q + e * sh * b
    phi_v = e * sh * c * q + e * (ch + sh * (d - half))
    scale = mp.exp(-s / mu)
    return scale * (phi_v - r * phi_u), -mp.mpf(k) * scale * phi_u


def barycentric(x: Sequence, bary: Sequence, y: object) -> list:
    """The weights of the values at the nodes ``x`` (barycentric weights ``bary``) that interpolate at ``y``."""
    terms = []
    for xj, bj in zip(x, bary):
        if y == xj:
            return [mp.mpf(1) if v == xj else mp.mpf(0) for v in x]
        terms.append(bj / (y - xj))
    total = mp.fsum(terms)
    return [t / total for t in terms]


def window_collocation(
    kernel: Callable[[object], object], rhs: Callable[[object], object], w: object, n: int, dps: int
) -> tuple[list, list, list]:
    """``h`` with ``h + kernel * h = rhs`` on ``[0, w]`` (a convolution equation of the second kind) at ``n``
    Chebyshev points, the convolution by Gauss-Legendre with 40 points on ``[0, nu]``: ``(x, bary, h)``."""
    with mp.workdps(dps + 10):
        theta = [(2 * j + 1) * mp.pi / (2 * n) for j in range(n)]
        x = [w / 2 * (1 - mp.cos(t)) for t in theta]
        bary = [(-1) ** j * mp.sin(t) for j, t in enumerate(theta)]
        gx, gw = gauss_legendre(40, dps)
        M = mp.matrix(n, n)
        for i in range(n):
            for y, wt in zip(gx, gw):
                row = barycentric(x, bary, x[i] * y)
                weight = wt * x[i] * kernel(x[i] - x[i] * y)
                for j in range(n):
                    M[i, j] += weight * row[j]
            M[i, i] += 1
        h = mp.lu_solve(M, mp.matrix([rhs(v) for v in x]))
        return x, bary, [h[j] for j in range(n)]


def assert_balls_contain(
    balls: Callable[..., object],
    F: Callable[[mp.mpc], mp.mpc],
    points: Sequence[complex],
    orders: Sequence[int],
    dps: int,
) -> None:
    """Each enclosure ``balls(s, k)`` holds ``F^{(k)}(s)`` computed by mpmath at ``dps`` digits (as a 200-bit ball)."""
    from nrobust._flint import working_precision

    for s in points:
        for k in orders:
            value = balls(s, k)
            with mp.workdps(dps):
                truth = mp.diff(F, mp.mpc(s), k)
            with working_precision(200) as fl:
                assert value.contains(fl.acb(truth)), (s, k, value, truth)  # type: ignore[attr-defined]


# ============================================================================ zeros by Newton's method from a grid
def newton_from_grid(
    F: Callable[[np.ndarray], np.ndarray], box: Region, n_re: int, n_im: int, steps: int, max_step: float
) -> np.ndarray:
    """Where Newton's method on ``F`` (a vectorised double-precision function; derivative by central differences)
    takes ``steps`` steps, each at most ``max_step`` long, from an ``n_re x n_im`` grid of seeds over the ``Im >= 0``
    half of ``box`` (the functions are real)."""
    x0, x1, y0, y1 = box
    xs, ys = np.linspace(x0, x1, n_re), np.linspace(max(0.0, y0), max(y1, 0.0), n_im)
    s = (xs[:, None] + 1j * ys[None, :]).ravel()
    with np.errstate(all="ignore"):
        for _ in range(steps):
            h = 1e-6 * (1 + np.abs(s))
            step = F(s) / ((F(s + h) - F(s - h)) / (2 * h))
            step = np.where(np.isfinite(step), step, 0.0)
            s = s - np.clip(np.abs(step), 0, max_step) * np.exp(1j * np.angle(step))
    return s


def distinct_polished(candidates: np.ndarray, polish: Callable[[complex], complex]) -> list[complex]:
    """The distinct zeros ``polish`` reaches from ``candidates`` (a candidate within ``1e-6`` of one taken is skipped;
    an :class:`OracleUnsure` polish is left out; two polished zeros within ``1e-12`` are one)."""
    out: list[complex] = []
    for z in candidates:
        if any(abs(z - w) < 1e-6 * (1 + abs(w)) for w in out):
            continue
        try:
            r = polish(complex(z))
        except OracleUnsure:
            continue
        if not any(abs(r - w) < 1e-12 * (1 + abs(w)) for w in out):
            out.append(r)
    return out


# ============================================================================ the paper's plant in closed form
#: ``delta*`` of U_BS2(0.1) on the paper's plant ``Hyperbolic2x2(1, 1, 1, 1, 1, 0.85)``: its crossing equations
#: (:func:`paper_factors`) solved at 40 digits.
PAPER_MARGIN = 0.2295391302761485093812871100572
#: ``delta*`` of U_BS2(0.1) on ``Hyperbolic2x2(1, 1, 4, 4, 0.5, 0.5)``, the same equations (14 digits; the exact route
#: gives 0.08708699915035, ``docs/margins.md``).
PDE_MARGIN_STRONG = 0.08708699915035


def paper_factors(s: Any, K: Any, rho: str = "0.85", q: str = "1") -> tuple[Any, Any]:
    """``A(s)`` and ``B(s; K)`` of U_BS2(K) (eq. (60)) on the paper's plant, at mpmath's working precision.

    The Laplace transform of the plant is ``[u; v]' = [[-s, 1], [-1, s]] [u; v]`` with ``[u; v](0) = [q; 1]``;
    ``M^2 = (s^2 - 1) I`` gives ``exp(M) = cosh(k) I + sinh(k)/k M``, ``k^2 = s^2 - 1``. ``A = e^{-s} (v(1) - rho
    u(1))`` is the open loop's characteristic function, and at ``delta = 0`` the loop is ``1 - (rho - K) q e^{-2 s}``
    (the kernels cancel), so ``B = 1 - rho q e^{-2 s} - A + K q e^{-2 s}``.
    """
    rho_, q_ = mp.mpf(rho), mp.mpf(q)
    k = mp.sqrt(s * s - 1)
    c, sk = mp.cosh(k), mp.sinh(k) / k
    u1 = (c - s * sk) * q_ + sk
    v1 = -sk * q_ + (c + s * sk)
    A = mp.exp(-s) * (v1 - rho_ * u1)
    z = mp.exp(-2 * s)
    return A, 1 - rho_ * q_ * z - A + K * q_ * z


# ============================================================ n + m plants (constant coefficients)
class NPlusMLoop:
    """``F(s; delta) = det(M_0(s) + e^{-delta s} M_1(s))`` of the ``n + m`` plant
    ``u_t + diag(lam) u_x = S_uu u + S_uv v``, ``v_t - diag(mu) v_x = S_vu u + S_vv v`` on ``[0, 1]``,
    ``u(t, 0) = Q v(t, 0)``, ``v(t, 1) = R u(t, 1) + U(t)``, ``U(t) = K u(t - delta, 1)``.

    Derivation: with zero initial data the Laplace transforms ``w = (u, v)`` satisfy
    ``s u + diag(lam) u_x = S_u w`` and ``s v - diag(mu) v_x = S_v w``, i.e.
    ``w_x = diag(lam, -mu)^{-1} (Sigma - s I) w``; so ``w(1) = expm(diag(lam, -mu)^{-1} (Sigma - s I)) w(0)``
    with ``w(0) = [Q; I] v(0)`` (the distal condition), and ``[Phi_u; Phi_v]`` the two row blocks of
    that product. The proximal condition with the delayed feedback is ``(Phi_v - (R + K e^{-delta s})
    Phi_u) v(0) = 0``: a nonzero solution iff its determinant vanishes. Row ``j`` is scaled by
    ``e^{-s/mu_j}`` (the normalisation nrobust documents, ``det(E(s) (...))``, ``E = diag(e^{-s/mu_j})``),
    so ``M_0 = E (Phi_v - R Phi_u)`` and ``M_1 = -E K Phi_u``. With ``Sigma = 0`` and ``m = 1``:
    ``F = 1 - sum_i (R_i + K_i e^{-delta s}) Q_i e^{-(1/lam_i + 1/mu) s}``.

    On ``s = i w`` a root needs ``z = e^{-i w delta}`` on the unit circle with ``det(M_0 + z M_1) = 0``,
    a polynomial of degree ``m <= 2`` in ``z`` (written out below); a root ``z`` with ``|z| = 1`` gives the
    delays ``(-arg z mod 2 pi + 2 pi k) / w``. Values at ``DPS`` digits come from ``mpmath.expm`` (two
    precisions that must agree), scans from ``scipy.linalg.expm`` in double precision.
    """

    DPS = 30

    def __init__(self, lam: Sequence[float], mu: Sequence[float], sigma, q, r, K) -> None:
        self.lam, self.mu = [float(v) for v in lam], [float(v) for v in mu]
        self.n, self.m = len(self.lam), len(self.mu)
        if self.m not in (1, 2):
            raise ValueError("the oracle is written for m = 1 or 2")
        self.sigma = np.asarray(sigma, dtype=float)
        self.q, self.r, self.K = (
            np.asarray(a, dtype=float).reshape(shape)
            for a, shape in ((q, (self.n, self.m)), (r, (self.m, self.n)), (K, (self.m, self.n)))
        )
        self.speeds = np.array(self.lam + [-v for v in self.mu])
        #: The longest round trip ``max_ij 1/lam_i + 1/mu_j``: the fastest oscillation of ``F`` on the axis.
        self.tau = max(1.0 / a + 1.0 / b for a in self.lam for b in self.mu)

    # ---------------------------------------------------------------- values
    def matrices_mp(self, s, dps: int):
        """``(M_0(s), M_1(s))`` at ``dps`` digits."""
        N, n = self.n + self.m, self.n
        with mp.workdps(dps):
            s = mp.mpc(s)
            gen = mp.matrix(N, N)
            for i in range(N):
                for j in range(N):
                    gen[i, j] = (mp.mpf(self.sigma[i, j]) - (s if i == j else 0)) / mp.mpf(self.speeds[i])
            phi = mp.expm(gen)
            w0 = mp.matrix(N, self.m)
            for j in range(self.m):
                w0[n + j, j] = 1
                for i in range(n):
                    w0[i, j] = mp.mpf(self.q[i, j])
            col = phi * w0
            M0, M1 = mp.matrix(self.m, self.m), mp.matrix(self.m, self.m)
            for j in range(self.m):
                e = mp.exp(-s / mp.mpf(self.mu[j]))
                for k in range(self.m):
                    pu = [col[i, k] for i in range(n)]
                    M0[j, k] = e * (col[n + j, k] - mp.fsum(mp.mpf(self.r[j, i]) * pu[i] for i in range(n)))
                    M1[j, k] = -e * mp.fsum(mp.mpf(self.K[j, i]) * pu[i] for i in range(n))
            return M0, M1

    def _F_at(self, s, delta, dps: int):
        M0, M1 = self.matrices_mp(s, dps)
        with mp.workdps(dps):
            return mp.det(M0 + mp.exp(-mp.mpc(s) * mp.mpf(delta)) * M1)

    def F_mp(self, s, delta) -> Any:
        """``F(s; delta)`` to ``DPS`` digits; the precision grows with the terms that cancel left of the
        axis (``e^{-Re s (tau + delta)}``), and two precisions 30 digits apart must agree."""
        x = float(mp.re(mp.mpc(s)))
        extra = max(0.0, -x) * (2.0 * self.tau + float(delta)) / math.log(10.0)
        if not extra <= 500.0:
            raise OracleUnsure(f"terms at s = {s} need more than 500 extra digits")
        dps = self.DPS + 10 + math.ceil(extra)
        f1, f2 = self._F_at(s, delta, dps), self._F_at(s, delta, dps + 30)
        with mp.workdps(self.DPS + 10):
            if abs(f1 - f2) > mp.mpf(10) ** (-self.DPS + 5) * (1 + abs(f2)):
                raise OracleUnsure(f"F at s = {s} is not settled at {dps} digits")
            return +f2

    def matrices_np(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(M_0, M_1)`` in double precision, shape ``s.shape + (m, m)``."""
        from scipy.linalg import expm

        s = np.asarray(s, dtype=complex).reshape(-1)
        N, n = self.n + self.m, self.n
        gen = (self.sigma[None] - s[:, None, None] * np.eye(N)[None]) / self.speeds[None, :, None]
        col = expm(gen) @ np.vstack([self.q, np.eye(self.m)])
        pu, pv = col[:, :n, :], col[:, n:, :]
        e = np.exp(-s[:, None] / np.array(self.mu)[None, :])[:, :, None]
        return e * (pv - self.r[None] @ pu), -e * (self.K[None] @ pu)

    def F_np(self, s: np.ndarray, delta: float) -> np.ndarray:
        s = np.asarray(s, dtype=complex)
        M0, M1 = self.matrices_np(s)
        return np.linalg.det(M0 + np.exp(-delta * s.reshape(-1))[:, None, None] * M1).reshape(s.shape)

    # ---------------------------------------------------------------- the axis
    def z_polynomial(self, a: Callable[[int, int], Any], b: Callable[[int, int], Any]) -> list:
        """Coefficients ``[c_0, .., c_m]`` of ``det(M_0 + z M_1)``, the entries given as ``a(i, j)``, ``b(i, j)``
        (``m = 1``: ``a + z b``; ``m = 2``: ``det M_0 + z (a_00 b_11 + b_00 a_11 - a_01 b_10 - b_01 a_10)
        + z^2 det M_1``)."""
        if self.m == 1:
            return [a(0, 0), b(0, 0)]
        c0 = a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0)
        c1 = a(0, 0) * b(1, 1) + b(0, 0) * a(1, 1) - a(0, 1) * b(1, 0) - b(0, 1) * a(1, 0)
        c2 = b(0, 0) * b(1, 1) - b(0, 1) * b(1, 0)
        return [c0, c1, c2]

    def log_moduli(self, w: np.ndarray) -> np.ndarray:
        """``log|z_k(i w)|`` of the roots of ``det(M_0 + z M_1)`` in ``z``, sorted, shape ``(w.size, m)``
        (``+inf`` for a root at infinity, ``M_1`` singular: that branch does not reach ``|z| = 1``)."""
        M0, M1 = self.matrices_np(1j * np.asarray(w, dtype=float))
        c = self.z_polynomial(lambda i, j: M0[:, i, j], lambda i, j: M1[:, i, j])
        with np.errstate(all="ignore"):
            if self.m == 1:
                z = (-c[0] / c[1])[:, None]
            else:
                disc = np.sqrt(c[1] * c[1] - 4 * c[0] * c[2])
                big = np.where(np.abs(-c[1] + disc) >= np.abs(-c[1] - disc), -c[1] + disc, -c[1] - disc)
                z1 = big / (2 * c[2])  # the larger root, and the smaller one by Vieta (no cancellation)
                z2 = 2 * c[0] / big
                z = np.stack([z1, z2], axis=1)
            out = np.sort(np.log(np.abs(z)), axis=1)
        return np.where(np.isnan(out), np.inf, out)

    def first_delay(self, w) -> list[tuple[float, float]]:
        """``(|z|, delta)`` of each root ``z`` of ``det(M_0 + z M_1)`` at ``s = i w`` (``DPS`` digits),
        ``delta = (-arg z mod 2 pi) / w``."""
        with mp.workdps(self.DPS + 10):
            w = mp.mpf(w)
            M0, M1 = self.matrices_mp(mp.mpc(0, w), self.DPS + 10)
            c = self.z_polynomial(lambda i, j: M0[i, j], lambda i, j: M1[i, j])
            if self.m == 1:
                zs = [-c[0] / c[1]]
            else:  # the root of larger modulus from the formula without cancellation, the other by Vieta
                disc = mp.sqrt(c[1] * c[1] - 4 * c[0] * c[2])
                big = max(-c[1] + disc, -c[1] - disc, key=abs)
                if big == 0:
                    raise OracleUnsure(f"det(M_0 + z M_1) = c_0 at w = {w}")
                zs = [2 * c[0] / big] + ([big / (2 * c[2])] if c[2] != 0 else [])  # c_2 = 0: a root at infinity
            return [(float(abs(z)), float(((-mp.arg(z)) % (2 * mp.pi)) / w)) for z in zs]

    def crossing_near(self, w0: float, d0: float) -> tuple[float, float]:
        """``(w, delta)`` with ``F(i w; delta) = 0`` from ``(w0, d0)`` (``mpmath.findroot``, two real unknowns),
        ``delta`` reduced to the first delay of that crossing; OracleUnsure if it does not settle nearby."""

        def eqs(w, d):
            f = self.F_mp(mp.mpc(0, w), d)
            return mp.re(f), mp.im(f)

        with mp.workdps(self.DPS):
            try:
                w, d = mp.findroot(eqs, (mp.mpf(w0), mp.mpf(d0)), tol=mp.mpf(10) ** (-2 * self.DPS + 12))
            except (ValueError, ZeroDivisionError):
                raise OracleUnsure(f"findroot did not settle from (w, delta) = ({w0}, {d0})") from None
            if abs(w - w0) > 1e-6 * (1 + abs(w0)) or w <= 0:
                raise OracleUnsure(f"findroot went from w = {w0} to {w}")
            period = 2 * mp.pi / w
            return float(w), float(d - mp.floor(d / period) * period)

    def crossings_in_band(self, w_max: float) -> list[tuple[float, float]]:
        """``(w, delta)`` of the sign changes of each sorted ``log|z_k(i w)|`` on ``(0, w_max]`` (step
        ``2 pi / (64 tau)``, refined by ``brentq`` in double precision), ``delta`` the first delay; a local
        minimum of ``|log|z_k||`` below ``1e-6`` without a sign change raises OracleUnsure (a tangency)."""
        from scipy.optimize import brentq

        n = int(w_max / (2 * math.pi / (64 * self.tau))) + 2
        w = np.linspace(1e-6, w_max, n)
        g = self.log_moduli(w)
        out = []
        for k in range(self.m):
            gk = g[:, k]
            inner = np.arange(1, n - 1)
            low = (np.abs(gk[inner]) <= np.abs(gk[inner - 1])) & (np.abs(gk[inner]) <= np.abs(gk[inner + 1]))
            if np.any(low & (np.abs(gk[inner]) < 1e-6) & (np.sign(gk[inner - 1]) == np.sign(gk[inner + 1]))):
                raise OracleUnsure("|z| - 1 nearly touches zero between grid points")
            for i in np.flatnonzero(np.sign(gk[:-1]) != np.sign(gk[1:])):
                wc = brentq(lambda x, k=k: float(self.log_moduli(np.array([x]))[0, k]), w[i], w[i + 1], xtol=1e-14)
                # the root z on the unit circle (of the two, the one whose modulus is nearest 1)
                _, delay = min(self.first_delay(wc), key=lambda t: abs(math.log(t[0])))
                out.append((wc, delay))
        return out

    # ---------------------------------------------------------------- roots
    def polish(self, s0: complex, delta: float) -> Any:
        """A zero of ``F(.; delta)`` by the secant method (``mpmath.findroot``) from ``s0``; OracleUnsure if it
        does not settle within ``1e-6 (1 + |s0|)`` of ``s0``."""
        with mp.workdps(self.DPS):
            try:
                r = mp.findroot(lambda s: self.F_mp(s, delta), mp.mpc(s0), tol=mp.mpf(10) ** (-2 * self.DPS + 12))
            except (ValueError, ZeroDivisionError):
                raise OracleUnsure(f"secant iteration from {s0} did not converge") from None
            if abs(r - s0) > 1e-6 * (1 + abs(s0)):
                raise OracleUnsure(f"secant iteration went from {s0} to {r}")
            return r

    def roots_near(
        self, box: Region, delta: float, n_re: int = 8, n_im: int = 40, right_of: float = -math.inf
    ) -> list[complex]:
        """Zeros of ``F(.; delta)`` reached by Newton's method in double precision from a grid of seeds in
        ``box`` (``Im >= 0``: ``F`` is real), those with ``Re s > right_of - 1e-6`` polished at ``DPS``
        digits; not a complete search."""
        x0, x1, _, y1 = box
        s = newton_from_grid(lambda z: self.F_np(z, delta), box, n_re, n_im, steps=30, max_step=0.5)
        with np.errstate(all="ignore"):
            res = np.abs(self.F_np(s, delta))
        keep = np.isfinite(s) & (s.real > x0 - 1.0) & (s.real < x1 + 1.0) & (np.abs(s.imag) < y1 + 1.0) & (res < 1e-8)
        keep &= s.real > right_of - 1e-6
        return distinct_polished(s[keep], lambda z: complex(self.polish(z, delta)))
