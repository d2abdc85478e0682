"""Padé approximants of a delay and proven bounds of their error on the imaginary axis.

The ``(m, n)`` Padé approximant of ``e^{-z}`` is ``R_{m,n} = P_{m,n} / Q_{m,n}`` with

``P_{m,n}(z) = sum_{j=0}^{m} (m+n-j)! m! / ((m+n)! j! (m-j)!) (-z)^j``,
``Q_{m,n}(z) = sum_{j=0}^{n} (m+n-j)! n! / ((m+n)! j! (n-j)!) z^j``,

and a delay ``e^{-tau s}`` is replaced by ``R_{m,n}(tau s)`` (python-control's ``pade``,
whose ``n`` is our ``n`` and whose ``numdeg`` is our ``m``).

**Remainder.** For all integers ``m, n >= 0`` and every complex ``z``,

``e^{-z} Q_{m,n}(z) - P_{m,n}(z) = (-1)^{m+1} z^{m+n+1} / (m+n)! * int_0^1 t^n (1-t)^m e^{-t z} dt``.

Proof: with ``phi(t) = t^n (1-t)^m`` (degree ``m+n``, leading coefficient ``(-1)^m``),
``m+n+1`` integrations by parts give
``z^{m+n+1} int_0^1 phi(t) e^{-tz} dt = sum_j phi^{(j)}(0) z^{m+n-j} - e^{-z} sum_j phi^{(j)}(1) z^{m+n-j}``;
``phi^{(j)}(0) = 0`` for ``j < n`` and ``phi^{(j)}(1) = 0`` for ``j < m``, so the first sum
is a polynomial of degree ``<= m`` and the second one of degree ``<= n`` whose value at 0 is
``phi^{(m+n)}(1) = (-1)^m (m+n)!``. Divided by ``(-1)^{m+1} (m+n)!`` they are ``P_{m,n}`` and
``Q_{m,n}`` (the remainder is ``O(z^{m+n+1})``, which fixes the Padé approximant uniquely).

**Bound on the axis.** At ``z = i y`` (``y = omega tau`` real), ``|e^{-i t y}| = 1`` and
``int_0^1 t^n (1-t)^m dt = m! n! / (m+n+1)!``, so

``|e^{-i y} - R_{m,n}(i y)| <= |y|^{m+n+1} m! n! / ((m+n)! (m+n+1)! |Q_{m,n}(i y)|)``,

and trivially ``<= 1 + |R_{m,n}(i y)|``. :func:`pade_error_bound` returns the smaller of the
two, evaluated in ball arithmetic (python-flint's Arb, coefficients as exact rationals,
the result rounded up), so every returned number is a proven upper bound; on a band
``[0, omega_max]`` :func:`pade_band_bound` evaluates the same bound on balls covering the
band, a proof for every frequency of the band and not only for samples. The first bound is
sharp as ``y -> 0`` (the integral tends to ``m! n! / (m+n+1)!``); far beyond ``y ~ m + n``
the integral decays like ``1/y`` and the second bound takes over.

**Substituted loops.** :func:`substitution_bound` propagates the bound through a transfer
function ``H = N / D`` of quasi-polynomials with point delays, ``N = sum_j p_j(s) e^{-tau_j s}``
and ``D = s^k D_1`` (``k`` integrators, :func:`split_integrators`), each delay replaced by its
approximant (``N~``, ``D~_1``). From the identity
``N/D_1 - N~/D~_1 = (N/D_1)(D~_1 - D_1)/D~_1 + (N - N~)/D~_1`` (exact, not first order) and
``|N - N~| <= sum_j |p_j| eps_j``, ``eps_j`` the bound above at ``y = omega tau_j``:

``|H - N~/(s^k D~_1)| <= (|N/D_1| sum_l |d_l| eps_l + sum_j |p_j| eps_j) / (|omega|^k |D~_1|)``,

with ``eps_j / |omega|^k`` evaluated as ``|omega|^{m+n+1-k}`` times the rest, so the
integrators cost nothing at ``omega = 0``. A rational model with rounded coefficients adds its
distance to the exact substitution, computed exactly (rational arithmetic on the model's
float coefficients) before it is enclosed.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from fractions import Fraction
from math import factorial
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._flint import precision, require_flint
from .._validate import nonnegative, positive, positive_int, real_array
from ..errors import CertificationError, ParameterError
from ..quasipoly import QuasiPolynomial

__all__ = ["pade", "pade_band_bound", "pade_error_bound", "split_integrators", "substitution_bound"]

# Working precision (bits) of the ball evaluations: rounding far below every bound returned.
_PREC = 106
# Work bound on the cells of a band bound.
_MAX_CELLS = 10**6
# Bisections of a cell of substitution_bound whose ball evaluation overestimates.
_MAX_DEPTH = 8


def _orders(m: Any, n: Any) -> tuple[int, int]:
    """Validated ``(m, n)``; ``n = None`` is ``m`` (the diagonal approximant)."""
    m = positive_int("m", m, minimum=0, maximum=200)
    n = m if n is None else positive_int("n", n, minimum=0, maximum=200)
    return m, n


def _order_pair(name: str, value: Any) -> tuple[int, int]:
    """A validated ``(m, n)`` pair given as one value (an entry of an ``orders`` mapping)."""
    what = "a pair (m, n) of integers in [0, 200]"
    if isinstance(value, (str, bytes)):
        raise ParameterError(name, what, value)
    try:
        m, n = value
    except (TypeError, ValueError):
        raise ParameterError(name, what, value) from None
    for x in (m, n):
        if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, np.integer)) or not 0 <= x <= 200:
            raise ParameterError(name, what, value)
    return int(m), int(n)


def pade_fractions(m: int, n: int) -> tuple[list[Fraction], list[Fraction]]:
    """Exact coefficients of ``P_{m,n}`` and ``Q_{m,n}`` in ascending powers of ``z`` (module notes)."""
    top = factorial(m + n)
    p = [
        Fraction(factorial(m + n - j) * factorial(m) * (-1) ** j, top * factorial(j) * factorial(m - j))
        for j in range(m + 1)
    ]
    q = [Fraction(factorial(m + n - j) * factorial(n), top * factorial(j) * factorial(n - j)) for j in range(n + 1)]
    return p, q


def pade(
    tau: float, m: int, n: int | None = None, normalize: str = "monic"
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Numerator and denominator of the ``(m, n)`` Padé approximant of ``e^{-tau s}``.

    Parameters
    ----------
    tau : float
        The delay, ``>= 0``.
    m : int
        Degree of the numerator, ``0 <= m <= 200``.
    n : int, optional
        Degree of the denominator, ``0 <= n <= 200`` (default ``m``: the diagonal approximant).
    normalize : {"monic", "constant"}
        ``"monic"`` (default): the denominator's leading coefficient is 1, python-control's
        convention, so ``pade(tau, m, n)`` is ``control.pade(tau, n, m)`` (for ``m <= n``,
        python-control's range); ``"constant"``: ``P(0) = Q(0) = 1`` exactly, the form that
        keeps the low-frequency gain of a substituted loop exact.

    Returns
    -------
    num, den : ndarray
        Coefficients in descending powers of ``s`` (python-control's order):
        ``P_{m,n}(tau s)`` and ``Q_{m,n}(tau s)`` of the module notes, scaled. ``tau = 0``
        gives ``[1.0], [1.0]``.

    Examples
    --------
    >>> num, den = pade(1.0, 3)
    >>> num.tolist(), den.tolist()
    ([-1.0, 12.0, -60.0, 120.0], [1.0, 12.0, 60.0, 120.0])
    """
    tau = nonnegative("tau", tau)
    m, n = _orders(m, n)
    if normalize not in ("monic", "constant"):
        raise ParameterError("normalize", '"monic" or "constant"', normalize)
    if tau == 0.0:
        return np.ones(1), np.ones(1)
    p, q = pade_fractions(m, n)
    t = Fraction(tau)
    num = [c * t**j for j, c in enumerate(p)]
    den = [c * t**j for j, c in enumerate(q)]
    scale = den[-1] if normalize == "monic" else Fraction(1)
    largest = max(abs(c) for c in num + den) / scale
    if largest > Fraction(np.finfo(float).max):
        digits = (largest.numerator.bit_length() - largest.denominator.bit_length()) * np.log10(2.0)
        raise ParameterError(
            "tau",
            f"a delay whose ({m}, {n}) Padé coefficients with normalize={normalize!r} are finite in floating "
            f"point (the largest is about 1e{digits:.0f})",
            tau,
        )
    return (
        np.array([float(c / scale) for c in reversed(num)]),
        np.array([float(c / scale) for c in reversed(den)]),
    )


# ---------------------------------------------------------------------- ball arithmetic
class _Approximant:
    """``R_{m,n}(tau s)`` in balls: exact coefficients, the constant of the bound."""

    def __init__(self, flint: ModuleType, tau: float, m: int, n: int) -> None:
        self.tau = tau
        self.m, self.n = m, n
        p, q = pade_fractions(m, n)
        t = flint.fmpq(*Fraction(tau).as_integer_ratio())
        self.p = flint.acb_poly(
            [flint.acb(flint.arb(flint.fmpq(c.numerator, c.denominator) * t**j)) for j, c in enumerate(p)]
        )
        self.q = flint.acb_poly(
            [flint.acb(flint.arb(flint.fmpq(c.numerator, c.denominator) * t**j)) for j, c in enumerate(q)]
        )
        const = Fraction(factorial(m) * factorial(n), factorial(m + n) * factorial(m + n + 1)) * Fraction(tau) ** (
            m + n + 1
        )
        self.const = flint.arb(flint.fmpq(const.numerator, const.denominator))
        self.flint = flint

    def remainder(self, w: Any, k: int = 0) -> Any:
        """Upper bound (an ``arb``) of ``|e^{-i w tau} - R(i w tau)| / |w|^k`` on a real ball ``w >= 0``."""
        flint = self.flint
        if self.tau == 0.0:
            return flint.arb(0)
        s = flint.acb(0, w)
        qs = self.q(s)
        q_low = qs.abs_lower()
        inf = flint.arb("inf")
        big = self.m + self.n + 1
        first = self.const * abs(w) ** (big - k) / q_low if q_low > 0 else inf
        if k == 0:
            second = 1 + self.p(s).abs_upper() / q_low if q_low > 0 else inf
        else:
            w_low = abs(w).lower()
            second = (1 + self.p(s).abs_upper() / q_low) / w_low**k if (q_low > 0 and w_low > 0) else inf
        a, b = first.upper(), second.upper()
        if not b.is_finite():
            return a
        if not a.is_finite():
            return b
        return a if a < b else b

    def value(self, s: Any) -> Any:
        """Enclosure of ``R(tau s)`` at a complex ball ``s``."""
        return self.p(s) / self.q(s)


def _upper(x: Any) -> float:
    """A float ``>=`` every point of the ball ``x`` (``inf`` when ``x`` is not finite)."""
    if not x.is_finite():
        return float("inf")
    if x == 0:  # exact zero (a zero delay, or the bound at omega = 0)
        return 0.0
    return float(np.nextafter(float(x.upper()), np.inf))


def _frequencies(omega: ArrayLike) -> NDArray[np.float64]:
    w = real_array("omega", omega, ndim=None, min_size=1).ravel()
    if np.any(w < 0):
        raise ParameterError("omega", "frequencies >= 0", omega)
    return w


def pade_error_bound(tau: float, m: int, n: int | None, omega: ArrayLike) -> NDArray[np.float64]:
    """Proven upper bounds of ``|e^{-i omega tau} - R_{m,n}(i omega tau)|`` at each frequency.

    The bound proven in the module notes,
    ``min(|y|^{m+n+1} m! n! / ((m+n)! (m+n+1)! |Q_{m,n}(i y)|), 1 + |R_{m,n}(i y)|)`` at
    ``y = omega tau``, evaluated in ball arithmetic and rounded up.

    Parameters
    ----------
    tau : float
        The delay, ``>= 0``.
    m, n : int
        Degrees of the numerator and the denominator (``n = None``: ``m``).
    omega : array_like
        Frequencies ``>= 0``.

    Returns
    -------
    ndarray
        One bound per frequency.

    Examples
    --------
    >>> float(pade_error_bound(1.0, 1, 1, [0.1])[0]) < 1e-3 / 12 * 1.01
    True
    """
    tau = nonnegative("tau", tau)
    m, n = _orders(m, n)
    w = _frequencies(omega)
    flint = require_flint()
    with precision(flint, _PREC):
        approx = _Approximant(flint, tau, m, n)
        return np.array([_upper(approx.remainder(flint.arb(float(x)))) for x in w])


def pade_band_bound(tau: float, m: int, n: int | None, omega_max: float, cells: int = 256) -> float:
    """Proven ``sup`` of ``|e^{-i omega tau} - R_{m,n}(i omega tau)|`` over ``0 <= omega <= omega_max``.

    The band is covered by ``cells`` equal intervals, and the bound of
    :func:`pade_error_bound` is evaluated on each as a ball (so it holds at every frequency of
    the band); more cells give a tighter bound.

    Parameters
    ----------
    tau : float
        The delay, ``>= 0``.
    m, n : int
        Degrees (``n = None``: ``m``).
    omega_max : float
        End of the band, ``> 0``.
    cells : int, optional
        Number of intervals, ``1 <= cells <= 10**6`` (default 256).
    """
    tau = nonnegative("tau", tau)
    m, n = _orders(m, n)
    top = positive("omega_max", omega_max)
    cells = positive_int("cells", cells, maximum=_MAX_CELLS)
    edges = np.linspace(0.0, top, cells + 1)
    flint = require_flint()
    with precision(flint, _PREC):
        approx = _Approximant(flint, tau, m, n)
        return max(_upper(approx.remainder(flint.arb(a).union(flint.arb(b)))) for a, b in itertools.pairwise(edges))


def split_integrators(F: QuasiPolynomial) -> tuple[int, QuasiPolynomial]:
    """``(k, F_1)`` with ``F = s^k F_1`` exactly: the largest power of ``s`` dividing every term.

    Only point terms can carry the factor (a distributed term gives ``k = 0``); the
    coefficients of ``F_1`` are those of ``F`` shifted down by ``k``, no arithmetic.
    """
    if F.distributed or not F.point_terms:
        return 0, F
    k = min(int(np.flatnonzero(p)[0]) if np.any(p) else p.size for p, _ in F.point_terms)
    if k == 0:
        return 0, F
    return k, QuasiPolynomial([p[k:] for p, _ in F.point_terms], [t for _, t in F.point_terms])


def _real_terms(name: str, F: QuasiPolynomial) -> list[tuple[list[Fraction], float]]:
    """The point terms of ``F`` as exact rational coefficient lists (ascending) and delays."""
    if F.distributed:
        raise CertificationError(
            f"the band bound covers point delays only: {name} has distributed delays, whose discretisation "
            "error is not bounded here (write the kernel as point delays, or use the returned sampled error)"
        )
    out = []
    for p, t in F.point_terms:
        c = np.real_if_close(p)
        if np.iscomplexobj(c):
            raise ParameterError(name, "real polynomial coefficients", p)
        out.append(([Fraction(float(x)) for x in c], float(t)))
    return out


def _fmpq_poly(flint: ModuleType, coefs: Sequence[Fraction]) -> Any:
    return flint.fmpq_poly([flint.fmpq(c.numerator, c.denominator) for c in coefs])


def _substituted(
    flint: ModuleType, terms: list[tuple[list[Fraction], float]], orders: Mapping[float, tuple[int, int]]
) -> tuple[Any, Any]:
    """``(A, B)`` exact polynomials with ``sum_j p_j R_j(tau_j s) = A / B`` (``B`` the product of the ``Q_j``)."""
    num = flint.fmpq_poly([0])
    den = flint.fmpq_poly([1])
    for p, t in terms:
        if t == 0.0:
            a, b = _fmpq_poly(flint, p), flint.fmpq_poly([1])
        else:
            m, n = orders[t]
            pc, qc = pade_fractions(m, n)
            tt = Fraction(t)
            a = _fmpq_poly(flint, p) * _fmpq_poly(flint, [c * tt**j for j, c in enumerate(pc)])
            b = _fmpq_poly(flint, [c * tt**j for j, c in enumerate(qc)])
        num, den = num * b + a * den, den * b
    return num, den


def _acb_poly(flint: ModuleType, f: Any) -> Any:
    return flint.acb_poly([flint.acb(flint.arb(c)) for c in f.coeffs()])


def _exact_poly(flint: ModuleType, coefs: ArrayLike) -> Any:
    """An exact ``fmpq_poly`` from float coefficients in descending powers (python-control's order)."""
    c = np.asarray(coefs, dtype=float)
    return _fmpq_poly(flint, [Fraction(float(x)) for x in c[::-1]])


def substitution_bound(
    num: QuasiPolynomial,
    den: QuasiPolynomial,
    omega: ArrayLike,
    orders: Mapping[float, tuple[int, int]],
    model: tuple[ArrayLike, ArrayLike] | None = None,
) -> NDArray[np.float64]:
    """Proven bounds of ``|H(i w) - M(i w)|`` on the cells ``[omega_j, omega_{j+1}]``.

    ``H = num / den`` with point delays only; ``M`` is ``H`` with every delay ``tau``
    replaced by its ``orders[tau]`` Padé approximant (the exact substitution), or the given
    rational ``model``, whose distance to the exact substitution is added (module notes).

    Parameters
    ----------
    num, den : QuasiPolynomial
        Real coefficients, point delays only. ``den = s^k D_1`` (:func:`split_integrators`).
    omega : array_like
        Increasing frequencies ``>= 0``, at least two: the cells.
    orders : mapping of float to (int, int)
        ``(m, n)`` of every nonzero delay of ``num`` and ``den``, ``m + n + 1 >= k``.
    model : (array_like, array_like), optional
        Numerator and denominator of a rational model in descending powers of ``s``; its
        denominator must keep the ``k`` integrators exactly (``k`` trailing zeros).

    Returns
    -------
    ndarray
        ``len(omega) - 1`` bounds, each valid at every frequency of its cell (a cell whose
        ball evaluation exceeds 1.5 times the bound at its ends is bisected, up to 8 times;
        ``inf`` where
        nothing finite is proven: a zero of ``D~_1`` or ``D_1`` on the cell, or a model whose
        low-frequency gain differs from the substitution's while ``k > 0``, for the cell at 0).

    Raises
    ------
    CertificationError
        ``num`` or ``den`` has distributed delays.
    """
    w = _frequencies(omega)
    if w.size < 2 or np.any(np.diff(w) <= 0):
        raise ParameterError("omega", "an increasing array of at least 2 frequencies >= 0", omega)
    k, den1 = split_integrators(den)
    n_terms, d_terms = _real_terms("num", num), _real_terms("den", den1)
    if not isinstance(orders, Mapping):
        raise ParameterError("orders", "a mapping {tau: (m, n)}", orders)
    checked: dict[float, tuple[int, int]] = {}
    for _, t in n_terms + d_terms:
        if t != 0.0:
            if t not in orders:
                raise ParameterError("orders", f"an order (m, n) for every delay (missing {t!r})", dict(orders))
            checked[t] = _order_pair(f"orders[{t!r}]", orders[t])
            if sum(checked[t]) + 1 < k:
                raise ParameterError("orders", f"m + n + 1 >= {k} (the number of integrators)", orders[t])
    orders = checked
    flint = require_flint()
    with precision(flint, _PREC):
        approx = {t: _Approximant(flint, t, *orders[t]) for _, t in n_terms + d_terms if t != 0.0}
        a_n, b_n = _substituted(flint, n_terms, orders)
        a_d, b_d = _substituted(flint, d_terms, orders)
        # N~/D~_1 = (a_n b_d) / (b_n a_d)
        top, bottom = a_n * b_d, b_n * a_d
        polys_n = [(_acb_poly(flint, _fmpq_poly(flint, p)), t) for p, t in n_terms]
        polys_d = [(_acb_poly(flint, _fmpq_poly(flint, p)), t) for p, t in d_terms]
        exact_n = _num_poly(flint, n_terms)
        exact_d = _num_poly(flint, d_terms)
        gap = None
        if model is not None:
            mn, md = _exact_poly(flint, model[0]), _exact_poly(flint, model[1])
            md_c = md.coeffs()
            if len(md_c) <= k or any(c != 0 for c in md_c[:k]):
                raise ParameterError("model", f"a denominator with the {k} integrator(s) of den kept exactly", model[1])
            md1 = flint.fmpq_poly(md_c[k:])
            # N~/D~_1 - M_n/M_d1 = (top md1 - mn bottom) / (bottom md1), divided by s^k
            diff = top * md1 - mn * bottom
            gap = (_acb_poly(flint, diff), _acb_poly(flint, bottom * md1), diff.coeffs()[:k])

        def cell(lo: float, hi: float, depth: int) -> float:
            # the bound on [lo, hi]; bisected (up to _MAX_DEPTH times) while it exceeds 1.5 times the
            # bound at its ends, the overestimation of a wide ball: the sup over a union is the max
            wb = flint.arb(lo).union(flint.arb(hi))
            b = _cell_bound(flint, flint.acb(0, wb), wb, k, approx, polys_n, polys_d, exact_n, exact_d, gap)
            if depth >= _MAX_DEPTH:
                return b
            if np.isfinite(b):
                ends = [flint.arb(lo), flint.arb(hi)]
                ref = max(
                    _cell_bound(flint, flint.acb(0, e), e, k, approx, polys_n, polys_d, exact_n, exact_d, gap)
                    for e in ends
                )
                if b <= 1.5 * ref or b == 0.0:
                    return b
            mid = 0.5 * (lo + hi)
            return max(cell(lo, mid, depth + 1), cell(mid, hi, depth + 1))

        out = np.array([cell(float(lo), float(hi), 0) for lo, hi in itertools.pairwise(w)])
    return out


def _num_poly(flint: ModuleType, terms: list[tuple[list[Fraction], float]]) -> list[tuple[Any, Any]]:
    """``(p_j as acb_poly, tau_j)`` for the ball evaluation of ``sum p_j e^{-tau_j s}``."""
    return [
        (_acb_poly(flint, _fmpq_poly(flint, p)), flint.arb(flint.fmpq(*Fraction(t).as_integer_ratio())))
        for p, t in terms
    ]


def _cell_bound(
    flint: ModuleType,
    s: Any,
    wb: Any,
    k: int,
    approx: Mapping[float, _Approximant],
    polys_n: list[tuple[Any, float]],
    polys_d: list[tuple[Any, float]],
    exact_n: list[tuple[Any, Any]],
    exact_d: list[tuple[Any, Any]],
    gap: tuple[Any, Any, list[Any]] | None,
) -> float:
    """The bound of :func:`substitution_bound` on one cell (``s = i wb``, ``wb`` a real ball)."""
    inf = float("inf")
    n_val = sum((p(s) * (-s * t).exp() for p, t in exact_n), flint.acb(0))
    d_val = sum((p(s) * (-s * t).exp() for p, t in exact_d), flint.acb(0))
    d_low = d_val.abs_lower()
    dt_val = sum((p(s) * (approx[t].value(s) if t != 0.0 else 1) for p, t in polys_d), flint.acb(0))
    dt_low = dt_val.abs_lower()
    if not (d_low > 0 and dt_low > 0):
        return inf
    b_n = sum((p(s).abs_upper() * approx[t].remainder(wb, k) for p, t in polys_n if t != 0.0), flint.arb(0))
    b_d = sum((p(s).abs_upper() * approx[t].remainder(wb, k) for p, t in polys_d if t != 0.0), flint.arb(0))
    bound = (n_val.abs_upper() / d_low * b_d + b_n) / dt_low
    if gap is not None:
        diff, base, low = gap
        base_low = base(s).abs_lower()
        if not base_low > 0:
            return inf
        if all(c == 0 for c in low):
            # the first k coefficients vanish exactly: divide by s^k term by term
            shifted = flint.acb_poly(diff.coeffs()[k:])
            extra = shifted(s).abs_upper() / base_low
        else:
            w_low = abs(wb).lower()
            if not w_low > 0:
                return inf
            extra = diff(s).abs_upper() / base_low / w_low**k
        bound = bound + extra
    return _upper(bound)
