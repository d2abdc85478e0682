"""The stated accuracies of :mod:`nrobust.volterra` against closed forms, for kernels with few knots.

For a kernel ``N = a + beta H(nu - t0)`` (a jump of ``beta`` at ``t0``; ``beta = 0``: a constant) the resolvent
``r + N * r = N`` has the Laplace transform ``(a + beta E) / (s + a + beta E)``, ``E = e^{-t0 s}``; expanded in
powers of ``beta E / (s + a)`` it is the finite sum, on any window,

    r(nu) = sum_k (-beta)^k / k! [a x_k^k e^{-a x_k} H(x_k) + beta x_{k+1}^k e^{-a x_{k+1}} H(x_{k+1})],

``x_k = nu - k t0`` (for ``beta = 0``: ``a e^{-a nu}``), evaluated here at 40 digits (mpmath). It shares no code
with the collocation. Only ``N`` on the window enters ``r`` there: the kernels below are stored on ``[0, 2]``.
For constant ``N = a`` and a law ``m = c``, ``h = m - m * r = c e^{-a nu}``, and ``A(s) H(s)`` with
``A(s) = 1 - 0.5 e^{-1.3 s} - b int_0^1 e^{-nu s} dnu`` is in closed form with
``H(s) = c (1 - e^{-(a + s) w}) / (a + s)``.
"""

from __future__ import annotations

import mpmath as mp
import numpy as np
import pytest

from nrobust.distributed_delay import DistributedDelay
from nrobust.errors import CertificationError
from nrobust.quasipoly import QuasiPolynomial
from nrobust.volterra import resolvent_product, window_law, window_resolvent

#: The stated accuracy may exceed the error by this factor at most (it is an estimate: the change between
#: the last two collocations, the stored pieces' deviation and a rounding term, all near the error's size).
TIGHT = 1e3


def _resolvent(a: mp.mpf, beta: mp.mpf, t0: mp.mpf, x: mp.mpf) -> mp.mpf:
    """The resolvent of ``a + beta H(nu - t0)`` at ``x >= 0`` (module notes; mpmath numbers)."""
    total, k = mp.mpf(0), 0
    while x - k * t0 >= 0:
        xk, xk1 = x - k * t0, x - (k + 1) * t0
        total += (-beta) ** k / mp.factorial(k) * a * xk**k * mp.exp(-a * xk)
        if xk1 >= 0:
            total += (-beta) ** k / mp.factorial(k) * beta * xk1**k * mp.exp(-a * xk1)
        k += 1
    return total


def closed_form(a: float, beta: float, t0: float, nu: np.ndarray) -> np.ndarray:
    """The resolvent of ``a + beta H(nu - t0)`` at ``nu``, at 40 digits."""
    with mp.workdps(40):
        return np.array([float(_resolvent(mp.mpf(a), mp.mpf(beta), mp.mpf(t0), mp.mpf(float(x)))) for x in nu])


def step_kernel(a: float, beta: float, t0: float) -> DistributedDelay:
    """``a`` on ``[0, t0)``, ``a + beta`` on ``[t0, 2]``: two constant pieces."""
    return DistributedDelay(
        np.array([0.0, t0, 2.0]), None, interpolation="polynomial", coefficients=np.array([[a], [a + beta]])
    )


def _check(kernel: DistributedDelay, a: float, beta: float, t0: float, window: float) -> tuple[float, float]:
    r = window_resolvent(kernel, window)
    nu = np.r_[np.linspace(0.0, window, 161), np.random.default_rng(0).uniform(0.0, window, 40)]
    error = float(np.max(np.abs(r(nu) - closed_form(a, beta, t0, nu))))
    return error, r.accuracy


# a = 3, window 0.7 and a = 6, window 0.7 stated 1.3e-14 and 4.3e-13 against errors of 1.2e-9 and 1.6e-6 while
# the quadrature had a fixed number of points on the one sub-interval of a constant kernel.
@pytest.mark.parametrize("a", [1.0, 3.0, 6.0])
@pytest.mark.parametrize("window", [0.3, 0.7, 1.1, 1.5])
def test_constant_kernel_resolvent_is_within_its_stated_accuracy(a, window):
    error, accuracy = _check(DistributedDelay([0.0, 2.0], [a, a]), a, 0.0, 1.0, window)
    assert error <= accuracy
    # near rounding both are about 1e-14 (a e^{-a nu} is at most 6): the floor keeps the ratio meaningful
    assert accuracy <= TIGHT * max(error, 1e-15 * a)
    assert accuracy < 1e-12  # an analytic correction: the collocation reaches rounding


@pytest.mark.parametrize(("a", "beta", "t0", "window"), [(3.0, -2.0, 0.4, 0.3), (6.0, 1.0, 1.6, 1.5)])
def test_kernel_with_a_jump_beyond_the_window(a, beta, t0, window):
    """Two pieces, the jump after the window: one sub-interval per row, as for a constant (old error 4e-10)."""
    error, accuracy = _check(step_kernel(a, beta, t0), a, beta, t0, window)
    assert error <= accuracy <= TIGHT * max(error, 1e-15 * a)


@pytest.mark.parametrize(("a", "beta", "t0", "window"), [(1.0, 2.0, 0.25, 0.7), (2.0, -3.0, 0.5, 1.5)])
def test_kernel_with_a_jump_inside_the_window_is_refused(a, beta, t0, window):
    """The correction has a kink at the jump: global collocation does not settle, and says why."""
    with pytest.raises(CertificationError, match="jumps inside the window"):
        window_resolvent(step_kernel(a, beta, t0), window)


def test_closed_form_of_a_step_kernel_solves_the_equation():
    """The oracle itself: ``r(nu) + int_0^nu N(nu - x) r(x) dx - N(nu)`` at 40 digits (mpmath quadrature on the
    pieces between the jumps and kinks of both factors) vanishes to the working precision."""
    with mp.workdps(40):
        a, beta, t0 = mp.mpf(2), mp.mpf(-3), mp.mpf("0.5")
        for nu in (mp.mpf("0.3"), mp.mpf("0.8"), mp.mpf("1.3"), mp.mpf("1.5")):
            cuts = sorted(c for c in {mp.mpf(0), nu, nu - t0, t0, 2 * t0} if 0 <= c <= nu)
            integral = mp.quad(lambda x, nu=nu: (a + beta * (nu - x >= t0)) * _resolvent(a, beta, t0, x), cuts)
            residual = _resolvent(a, beta, t0, nu) + integral - (a + beta * (nu >= t0))
            assert abs(residual) < mp.mpf(10) ** -30  # quadrature of analytic pieces at 40 digits


# With the law's and the product's rules fixed (not split at the correction's pieces): for a = 6 on a window
# of 0.7, h stated 3e-13 against an error of 2.3e-7, and A H 9.7e-13 (times the support) against 1.4e-8.
@pytest.mark.parametrize("a", [1.0, 3.0, 6.0])
@pytest.mark.parametrize("window", [0.3, 0.7, 1.5])
def test_window_law_and_product_of_constant_kernels_are_within_their_stated_accuracy(a, window):
    c, b = -0.6, 0.9
    h = window_law(
        (DistributedDelay([0.0, 2.0], [c, c]),), window_resolvent(DistributedDelay([0.0, 2.0], [a, a]), window)
    )
    nu = np.linspace(0.0, window, 401)
    error = np.max(np.abs(h(nu) - c * np.exp(-a * nu)))
    assert error <= h.accuracy <= TIGHT * max(error, 1e-15)
    factor = QuasiPolynomial([[1.0], [-0.5]], [0.0, 1.3], [DistributedDelay([0.0, 1.0], [-b, -b])])
    product = resolvent_product(factor, h)
    s = np.array([0.5, 1j, 3j, 10j, 0.3 + 30j])
    exact = (1 - 0.5 * np.exp(-1.3 * s) - b * (1 - np.exp(-s)) / s) * c * (1 - np.exp(-(a + s) * window)) / (a + s)
    # on Re s >= 0 the transform's error is at most the kernel's sup-norm error times its support's length
    assert np.max(np.abs(product.product(s) - exact)) <= product.accuracy * (1.3 + window)
