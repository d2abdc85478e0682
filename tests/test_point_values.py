"""``QuasiPolynomialsAtPoint`` and ``TermsAtPoint``: several functions at one point, against 40-digit mpmath.

The oracle is each function written out in the test and integrated by ``mpmath.quad`` at 40 digits (the
kernels are a cubic, a piecewise line with a jump and a two-segment line, which the cubic spline and the
linear interpolant reproduce exactly, so the stored kernels are the ones written here), and its derivative
in ``s`` by the same formula with the moment raised by one. Tolerance ``1e-13`` of the scale
``1 + sum of |term|``: measured errors are at most ``3e-16`` of it at the points below, ``5e-15`` at
``|s| = 400`` (the rounding of the stored spline's segment integrals, the same in ``F(s)``); ``s = 0`` and
small ``|s h|`` on the series of ``phi_l``, ``|s h| = 10`` on its recursion.
"""

from __future__ import annotations

import mpmath
import numpy as np
import pytest

from nrobust.distributed_delay import TermsAtPoint
from nrobust.errors import ParameterError
from nrobust.quasipoly import DistributedDelay, QuasiPolynomial, QuasiPolynomialsAtPoint

mpmath.mp.dps = 40

CUBIC_NODES = np.linspace(0.2, 1.2, 41)  # 40 segments: the shared-segment path


def cubic(nu):
    return 1 - nu + nu**3 / 2


def broken(nu):
    """``nu`` on ``[0, 0.5)``, ``2 - nu`` on ``[0.5, 1]``: a jump of 1 at 0.5."""
    return nu if nu < 0.5 else 2 - nu


BROKEN_NODES = np.r_[np.linspace(0.0, 0.5, 21), np.linspace(0.5, 1.0, 21)]
BROKEN_VALUES = np.r_[np.linspace(0.0, 0.5, 21), 2.0 - np.linspace(0.5, 1.0, 21)]


def functions() -> tuple[QuasiPolynomial, QuasiPolynomial, QuasiPolynomial]:
    """``F1 = 1 - 0.3 e^{-2 s} + (0.2 + 0.1 i) s e^{-s/2} + (1 + s/2) int nu N_c e^{-nu s}``,
    ``F2 = 0.7 s^2 + e^{-s} - 2 int N_b e^{-nu s} + int_0^{0.3} (1 + 2 nu) e^{-nu s}`` (two segments: the
    closed form), ``F3 = F1'``."""
    F1 = QuasiPolynomial(
        [[1.0], [-0.3], [0.0, 0.2 + 0.1j]],
        [0.0, 2.0, 0.5],
        [DistributedDelay(CUBIC_NODES, cubic(CUBIC_NODES), [1.0, 0.5], moment=1, interpolation="cubic")],
    )
    F2 = QuasiPolynomial(
        [[0.0, 0.0, 0.7], [1.0]],
        [0.0, 1.0],
        [
            DistributedDelay(BROKEN_NODES, -2.0 * BROKEN_VALUES),
            DistributedDelay([0.0, 0.15, 0.3], [1.0, 1.3, 1.6]),
        ],
    )
    return F1, F2, F1.derivative()


def integral(f, m: int, s, a: float, b: float, breaks=()) -> mpmath.mpc:
    points = [mpmath.mpf(a), *map(mpmath.mpf, breaks), mpmath.mpf(b)]
    return mpmath.quad(lambda nu: nu**m * f(nu) * mpmath.exp(-nu * s), points)


def oracle(s: complex) -> tuple[list[mpmath.mpc], list[mpmath.mpf]]:
    """The three values in 40 digits, and the sum of the moduli of their terms (the rounding scale)."""
    s = mpmath.mpc(s)
    c = mpmath.mpc(0.2, 0.1)
    q, dq = 1 + s / 2, mpmath.mpf(1) / 2
    j1, j2 = integral(cubic, 1, s, 0.2, 1.2), integral(cubic, 2, s, 0.2, 1.2)
    f1 = [1, -0.3 * mpmath.exp(-2 * s), c * s * mpmath.exp(-s / 2), q * j1]
    f2 = [
        0.7 * s**2,
        mpmath.exp(-s),
        -2 * integral(broken, 0, s, 0.0, 1.0, breaks=(0.5,)),
        integral(lambda nu: 1 + 2 * nu, 0, s, 0.0, 0.3),
    ]
    # F1' = 0.6 e^{-2 s} + c (1 - s/2) e^{-s/2} + q' J_1 - q J_2
    f3 = [0.6 * mpmath.exp(-2 * s), c * (1 - s / 2) * mpmath.exp(-s / 2), dq * j1, -q * j2]
    return [mpmath.fsum(t) for t in (f1, f2, f3)], [1 + mpmath.fsum(abs(x) for x in t) for t in (f1, f2, f3)]


POINTS = [0.0, 0.3 + 0.2j, -1.5 + 7.0j, 2.0 - 30.0j, -0.5 + 400.0j]


@pytest.mark.parametrize("s", POINTS)
def test_values_against_mpmath(s: complex) -> None:
    at = QuasiPolynomialsAtPoint(functions())
    values = at(s)
    exact, scale = oracle(s)
    assert len(values) == 3 and all(isinstance(v, complex) for v in values)
    for v, e, sc in zip(values, exact, scale, strict=True):
        assert abs(mpmath.mpc(v) - e) <= 1e-13 * sc


@pytest.mark.parametrize("s", POINTS)
def test_same_as_each_function_to_rounding(s: complex) -> None:
    """The contract: ``F(s)`` of each function, to rounding (a few ulps of the scale)."""
    Fs = functions()
    values = QuasiPolynomialsAtPoint(Fs)(s)
    _, scale = oracle(s)
    for F, v, sc in zip(Fs, values, scale, strict=True):
        assert abs(v - complex(F(np.array([s]))[0])) <= 1e-14 * float(sc)
    terms = [d for F in Fs for d in F.distributed]
    for d, v in zip(terms, TermsAtPoint(terms)(s), strict=True):
        assert abs(v - complex(d(np.array([s]))[0])) <= 1e-14 * (1.0 + float(np.max(np.abs(d(np.array([s]))))))


def test_point_terms_only_and_overflow() -> None:
    """Without distributed terms; far left, where ``e^{-tau s}`` overflows, an infinite value, not an error."""
    F = QuasiPolynomial([[0.0, 1.0], [1.0]], [0.0, 1.0])  # s + e^{-s}
    at = QuasiPolynomialsAtPoint([F, F.derivative()])
    assert at(0.0) == (1.0 + 0j, 0j)
    value = at(-1000.0)[0]
    assert np.isinf(value.real)


def test_bad_input() -> None:
    with pytest.raises(ParameterError, match="functions"):
        QuasiPolynomialsAtPoint([1.0])  # type: ignore[list-item]
    with pytest.raises(ParameterError, match="terms"):
        TermsAtPoint([QuasiPolynomial([[1.0]], [0.0])])  # type: ignore[list-item]
