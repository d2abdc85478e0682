"""Padé approximants of delays: coefficients, the remainder and its proven bound, PI loops.

Oracles: python-control's ``pade`` (its own implementation, Golub and Van Loan's recurrence),
the factorial formula and the Taylor series of ``e^{-z}`` in exact rational arithmetic, and
mpmath at 40 significant digits (the error of the approximant, the remainder integral).
"""

from __future__ import annotations

import functools
import json
from fractions import Fraction
from math import factorial

import control
import mpmath as mp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nrobust.errors import CertificationError, ParameterError
from nrobust.lti import PadeModel, QuasiTransferFunction, delay, pade_approximation
from nrobust.lti.pade import pade, pade_band_bound, pade_error_bound, split_integrators, substitution_bound
from nrobust.quasipoly import DistributedDelay, QuasiPolynomial


@functools.cache
def _closed_form(m: int, n: int) -> tuple[list[Fraction], list[Fraction]]:
    """P and Q of the (m, n) approximant of e^{-z}, ascending powers (Baker and Graves-Morris, sec. 1.2)."""
    p = [Fraction(factorial(m + n - j) * factorial(m), factorial(m + n) * factorial(j) * factorial(m - j)) * (-1) ** j
         for j in range(m + 1)]  # fmt: skip
    q = [Fraction(factorial(m + n - j) * factorial(n), factorial(m + n) * factorial(j) * factorial(n - j))
         for j in range(n + 1)]  # fmt: skip
    return p, q


def _ascending(coefs: list[Fraction], z: mp.mpc) -> mp.mpc:
    """``sum_j coefs[j] z^j`` in mpmath (exact rational coefficients rounded at the working precision)."""
    return mp.polyval([mp.mpf(c.numerator) / c.denominator for c in coefs], z, asc=True)


def _descending(coefs: np.ndarray, z: mp.mpc) -> mp.mpc:
    """A float polynomial in python-control's order, its coefficients taken as exact."""
    return mp.polyval([mp.mpf(float(c)) for c in coefs[::-1]], z, asc=True)


def _true_error(tau: float, m: int, n: int, w: float, digits: int = 40) -> mp.mpf:
    """``|e^{-i w tau} - P(i w tau)/Q(i w tau)|`` with ``digits`` significant digits of the difference."""
    p, q = _closed_form(m, n)
    with mp.workdps(digits + 10 + (m + n + 1) * max(0, int(np.ceil(-np.log10(w * tau))))):
        z = 1j * mp.mpf(w) * mp.mpf(tau)
        approx = _ascending(p, z) / _ascending(q, z)
        return abs(mp.exp(-z) - approx)


# ---------------------------------------------------------------------- coefficients
@pytest.mark.parametrize("tau", [0.0, 0.3, 1.0, 2.5])
@pytest.mark.parametrize("n", [1, 2, 3, 5, 8])
def test_coefficients_match_python_control(tau, n):
    """pade(tau, m, n) is control.pade(tau, n, numdeg=m) for every 0 <= m <= n (python-control's range).
    Both round each coefficient after at most 2n operations: agreement to 32 eps (measured 2.2e-16 relative)."""
    for m in range(n + 1):
        num, den = pade(tau, m, n)
        c_num, c_den = control.pade(tau, n, m)
        np.testing.assert_allclose(num, c_num, rtol=32 * np.finfo(float).eps, atol=0)
        np.testing.assert_allclose(den, c_den, rtol=32 * np.finfo(float).eps, atol=0)
    assert [a.tolist() for a in pade(tau, n)] == [a.tolist() for a in pade(tau, n, n)]


@pytest.mark.parametrize("m,n", [(0, 1), (1, 1), (2, 3), (3, 3), (5, 2), (6, 6)])
def test_coefficients_are_the_closed_form_and_match_the_taylor_series(m, n):
    """normalize="constant" gives P(tau s), Q(tau s) of the factorial formula (one rounding each);
    and Q e^{-z} - P = O(z^{m+n+1}) exactly (rational arithmetic on the Taylor series of e^{-z})."""
    p, q = _closed_form(m, n)
    tau = 0.75
    num, den = pade(tau, m, n, normalize="constant")
    np.testing.assert_allclose(num[::-1], [float(c) * tau**j for j, c in enumerate(p)], rtol=4e-16, atol=0)
    np.testing.assert_allclose(den[::-1], [float(c) * tau**j for j, c in enumerate(q)], rtol=4e-16, atol=0)
    assert num[-1] == 1.0 and den[-1] == 1.0
    exp = [Fraction((-1) ** j, factorial(j)) for j in range(m + n + 2)]
    prod = [sum(q[i] * exp[j - i] for i in range(len(q)) if i <= j) for j in range(m + n + 2)]
    residual = [prod[j] - (p[j] if j < len(p) else 0) for j in range(m + n + 2)]
    assert all(r == 0 for r in residual[: m + n + 1]) and residual[m + n + 1] != 0


# ---------------------------------------------------------------------- remainder and bound
@pytest.mark.parametrize("m,n", [(0, 0), (1, 2), (3, 3), (4, 1)])
@pytest.mark.parametrize("z", [0.7 + 0.2j, 3.0j, -1.5 + 4.0j])
def test_remainder_identity_against_mpmath(m, n, z):
    """e^{-z} Q - P = (-1)^{m+1} z^{m+n+1}/(m+n)! int_0^1 t^n (1-t)^m e^{-tz} dt (the formula the bound
    rests on), both sides by mpmath at 40 digits: agreement to 1e-30 relative."""
    p, q = _closed_form(m, n)
    with mp.workdps(40):
        zz = mp.mpc(z.real, z.imag)
        lhs = mp.exp(-zz) * _ascending(q, zz) - _ascending(p, zz)
        integral = mp.quad(lambda t: t**n * (1 - t) ** m * mp.exp(-t * zz), [0, 1])
        rhs = (-1) ** (m + 1) * zz ** (m + n + 1) / mp.factorial(m + n) * integral
        assert abs(lhs - rhs) <= 1e-30 * abs(rhs)


@pytest.mark.parametrize("m,n", [(1, 1), (2, 2), (2, 3), (4, 4), (6, 6)])
def test_bound_holds_and_is_tight_on_a_dense_grid(m, n):
    """On 600 frequencies of y = w tau in (0, 2(m+n)], the proven bound is above the error computed by
    mpmath, and tight where the integral of the remainder has not yet oscillated: within 3 % for
    y <= 1 (measured 1.026 (1,1) down to 1.008 (6,6)), within 40 % for y <= (m+n)/2 (measured
    1.025 (1,1) up to 1.357 (6,6)); the band bound on [0, (m+n)/2] within 40 % of the sampled
    maximum (measured 1.03..1.38). Beyond, the true error oscillates (near-zeros: ratio up to 176
    at (6,6)) and the bound follows its envelope."""
    tau = 1.3
    y = np.linspace(0.0, 2.0 * (m + n), 601)[1:]
    w = y / tau
    bound = pade_error_bound(tau, m, n, w)
    true = np.array([float(_true_error(tau, m, n, x)) for x in w])
    assert np.all(bound >= true)
    ratio = bound / true
    assert np.max(ratio[y <= 1.0]) <= 1.03
    assert np.max(ratio[y <= (m + n) / 2]) <= 1.4
    # a band bound holds on the whole band, so above every sample, and is not loose on it
    band = pade_band_bound(tau, m, n, (m + n) / (2 * tau), cells=200)
    on_band = true[y <= (m + n) / 2]
    assert on_band.max() <= band <= 1.4 * on_band.max()


@settings(max_examples=50, deadline=None, derandomize=True)
@given(
    tau=st.floats(1e-3, 10.0),
    m=st.integers(0, 10),
    n=st.integers(0, 10),
    w=st.lists(st.floats(1e-4, 100.0), min_size=10, max_size=10),
)
def test_bound_is_never_violated(tau, m, n, w):
    """50 draws of (tau, m, n) with 10 frequencies each: 500 (w, tau, m, n), the error by mpmath
    with 40 significant digits (precision raised for tiny errors): never above the bound."""
    bound = pade_error_bound(tau, m, n, w)
    for x, b in zip(w, bound):
        assert _true_error(tau, m, n, x) <= b


def test_zero_delay_and_bad_input():
    np.testing.assert_array_equal(pade_error_bound(0.0, 3, 3, [0.0, 5.0]), [0.0, 0.0])
    assert [a.tolist() for a in pade(0.0, 2, 3)] == [[1.0], [1.0]]
    with pytest.raises(ParameterError, match="tau"):
        pade(-1.0, 2)
    with pytest.raises(ParameterError, match="normalize"):
        pade(1.0, 2, normalize="unit")
    with pytest.raises(ParameterError, match="omega"):
        pade_error_bound(1.0, 2, 2, [-1.0])
    with pytest.raises(ParameterError, match="cells"):
        pade_band_bound(1.0, 2, 2, 1.0, cells=0)


# ---------------------------------------------------------------------- PI loop with a delay
K, T = 0.5, 2.0


def _pi_loop() -> QuasiTransferFunction:
    """L = K (1 + 1/(T s)) e^{-s}/(s + 1) = K (T s + 1) e^{-s} / (T s (s + 1))."""
    return QuasiTransferFunction(QuasiPolynomial([[K, K * T]], [1.0]), QuasiPolynomial([[0.0, T, T]], [0.0]))


def _model_error(model: control.TransferFunction, w: np.ndarray) -> np.ndarray:
    """|L(i w) - model(i w)| by mpmath at 40 digits (the model's float coefficients taken as exact)."""
    out = []
    with mp.workdps(40):
        for x in w:
            s = 1j * mp.mpf(x)
            exact = K * (T * s + 1) * mp.exp(-s) / (T * s * (s + 1))
            approx = _descending(model.num[0][0], s) / _descending(model.den[0][0], s)
            out.append(float(abs(exact - approx)))
    return np.array(out)


def test_pi_loop_model_converges_and_keeps_its_integrator():
    """The PI loop has a pole at 0, which used to be refused. The model keeps it exactly; its error
    on [0.001, 2] falls with the order n of the (n, n) approximant (measured 9.8e-2, 7.9e-3, 2.5e-4,
    4.1e-6, 4.3e-8 for n = 1..5: ratios 12, 32, 60, 97, i.e. factorially, as (n!)^2/((2n)!(2n+1)!)),
    and in frequency it is O(w^{2n}) at low frequency (the remainder O(w^{2n+1}) over the
    integrator; observed slopes 2.005, 4.006, 6.006 on [0.01, 0.05] for n = 1, 2, 3); the proven bound is above the
    mpmath error on the whole band and within 15 % of its maximum."""
    L = _pi_loop()
    w = np.linspace(1e-3, 2.0, 300)
    errors = []
    for n in range(1, 6):
        fit = pade_approximation(L, n, w, return_bound=True)
        assert isinstance(fit, PadeModel) and fit.integrators == 1
        den = fit.model.den[0][0]
        assert den[-1] == 0.0 and den[-2] != 0.0  # one exact integrator
        assert np.min(np.abs(fit.model.poles())) <= 1e-14
        # residue at 0: K / T exactly as in L (num(0) / den_1(0))
        np.testing.assert_allclose(fit.model.num[0][0][-1] / den[-2], K / T, rtol=2e-16, atol=0)
        true = _model_error(fit.model, w)
        cells = np.maximum(true[:-1], true[1:])
        assert np.all(fit.bound >= cells)
        assert fit.band_bound <= 1.15 * true.max()
        errors.append(true.max())
        if n <= 3:  # beyond, the rounding of the model's coefficients (1e-24..1e-21 here) hides the order
            low = np.geomspace(1e-2, 5e-2, 5)
            slope = np.polyfit(np.log(low), np.log(_model_error(fit.model, low)), 1)[0]
            np.testing.assert_allclose(slope, 2 * n, atol=0.05)  # measured |slope - 2n| < 0.012
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all(ratios > 10.0) and np.all(np.diff(ratios) > 0)


def test_mixed_orders_and_a_delayed_denominator():
    """(m, n) per delay; the denominator 1 - 0.85 e^{-2 s} is approximated too: the bound of the
    ratio (the |N/D| |D - D~| / |D~| term) is above the mpmath error on every cell."""
    H = QuasiTransferFunction(QuasiPolynomial([[1.0, 0.5]], [0.5]), QuasiPolynomial([[1.0], [-0.85]], [0.0, 2.0]))
    w = np.linspace(0.0, 1.5, 120)
    fit = pade_approximation(H, (3, 4), w, orders={0.5: (1, 2)}, return_bound=True)
    assert fit.orders == ((0.5, 1, 2), (2.0, 3, 4))
    with mp.workdps(40):
        true = []
        for x in w:
            s = 1j * mp.mpf(x)
            exact = (1 + s / 2) * mp.exp(-s / 2) / (1 - mp.mpf(0.85) * mp.exp(-2 * s))
            approx = _descending(fit.model.num[0][0], s) / _descending(fit.model.den[0][0], s)
            true.append(float(abs(exact - approx)))
    true = np.array(true)
    assert np.all(fit.bound >= np.maximum(true[:-1], true[1:]))
    assert fit.band_bound <= 3.0 * true.max()  # measured 1.2
    np.testing.assert_allclose(fit.error, true, rtol=0, atol=1e-12)  # float sampling, |H| <= 6.7
    json.dumps(fit.to_dict(), allow_nan=False)
    assert "PadeModel(degree=" in repr(fit)


def test_split_integrators_and_substitution_bound_from_zero():
    """s^2 (s + 3) factors exactly; the exact substitution of the PI loop has a finite bound down to w = 0."""
    k, rest = split_integrators(QuasiPolynomial([[0.0, 0.0, 3.0, 1.0], [0.0, 0.0, 2.0]], [0.0, 1.0]))
    assert k == 2 and [p.tolist() for p, _ in rest.point_terms] == [[3.0, 1.0], [2.0]]
    L = _pi_loop()
    bound = substitution_bound(L.num, L.den, np.linspace(0.0, 1.0, 50), {1.0: (3, 3)})
    assert np.all(np.isfinite(bound)) and bound[0] < 1e-15


def test_refusals():
    L = _pi_loop()
    with pytest.raises(ParameterError, match="omega"):
        pade_approximation(L, 2, [0.0, 1.0])
    with pytest.raises(ParameterError, match="order"):
        pade_approximation(L, (3, 2), [0.1, 1.0])
    with pytest.raises(ParameterError, match="orders"):
        pade_approximation(L, 2, [0.1, 1.0], orders={0.7: 2})
    dist = DistributedDelay([0.0, 1.0], [1.0, 1.0])
    H = QuasiTransferFunction(1.0, QuasiPolynomial([[1.0]], [0.0], distributed=[dist]))
    with pytest.raises(CertificationError, match="distributed"):
        pade_approximation(H, 2, [0.0, 1.0], return_bound=True)


def test_an_order_beyond_double_precision_is_refused_by_name() -> None:
    """Order 100 of a two-delay loop: coefficients spanning beyond the double range, refused clearly."""
    import warnings

    from nrobust.errors import CertificationError
    from nrobust.lti.transfer import QuasiTransferFunction, pade_approximation
    from nrobust.quasipoly import QuasiPolynomial

    H = QuasiTransferFunction(
        QuasiPolynomial([[1.0, 1.0]], [0.3]), QuasiPolynomial([[1.0, 2.0, 1.0], [0.5]], [0.0, 0.7])
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # numpy's overflow on the way
        with pytest.raises(CertificationError, match="lower the order"):
            pade_approximation(H, 100, [0.0, 1.0, 2.0])


@pytest.mark.parametrize("order", [(-1, 2), (2.5, 2), (1000, 2), (2,), "ab", 3, (True, 2)])
def test_substitution_orders_are_validated_by_name(order) -> None:
    num, den = QuasiPolynomial([[1.0]], [0.7]), QuasiPolynomial([[1.0, 1.0]], [0.0])
    with pytest.raises(ParameterError, match=r"^orders\[0\.7\] must be a pair \(m, n\) of integers in \[0, 200\]"):
        substitution_bound(num, den, [0.0, 1.0], {0.7: order})
    assert np.all(np.isfinite(substitution_bound(num, den, [0.0, 1.0], {0.7: (2, 2)})))


def test_coefficients_beyond_double_range_are_refused() -> None:
    # tau = 1e-320 (subnormal): the monic denominator's constant 120 / tau^3 is about 1e962
    with pytest.raises(ParameterError, match=r"^tau must be a delay whose \(3, 3\) Padé coefficients"):
        pade(1e-320, 3)
    with pytest.raises(ParameterError, match=r"^tau must be"):
        pade(1e200, 3, normalize="constant")  # tau^3 / 120 overflows
    # in range: the closed form 120 / tau^3 of the monic denominator's constant term, to rounding
    np.testing.assert_allclose(pade(1e-100, 3)[1][-1], 120.0 / 1e-300, rtol=4e-16)


def test_a_delay_lti_pi_loop_built_from_python_control_is_taken_as_is():
    """The PI loop as a python-control user writes it, K (1 + 1/(T s)) / (s + 1) * delay(1): the same
    model class, integrator and proven bound as its quasi-polynomial form, and the bound above the
    mpmath error of the model against the closed form of _pi_loop."""
    L = control.tf([K * T, K], [T, 0.0]) * control.tf([1.0], [1.0, 1.0]) * delay(1.0)
    w = np.linspace(1e-3, 2.0, 60)
    fit = pade_approximation(L, 3, w, return_bound=True)
    assert isinstance(fit, PadeModel) and fit.integrators == 1
    true = _model_error(fit.model, w)
    assert np.all(fit.bound >= np.maximum(true[:-1], true[1:]))
    reference = pade_approximation(_pi_loop(), 3, w, return_bound=True)
    # the DelayLTI's quotient is _pi_loop's factors up to a constant: the same model to rounding
    np.testing.assert_allclose(fit.band_bound, reference.band_bound, rtol=1e-9)
    np.testing.assert_allclose(fit.error, reference.error, rtol=0, atol=1e-12)
