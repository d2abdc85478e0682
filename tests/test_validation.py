"""Bad input gets a ParameterError naming the parameter, and Nyquist counts are certified.

* Every public constructor and function below is fed booleans, NaN, infinities, strings,
  complex numbers where reals are expected, ``None``, ragged or empty sequences and
  out-of-range numbers: each must raise :class:`nrobust.errors.ParameterError` whose
  name or message names the parameter, never numpy's ``TypeError``/``ValueError``, a
  warning (pytest turns warnings into errors) or a silent conversion.
* ``nyquist_response(...).rhp_zeros`` never disagrees with ``count_roots``: loops that are
  stable, unstable, neutral, with zeros beyond the plotted band, and ``None`` with a note
  for advanced loops, ``c_D >= 0``, a principal part that is stable but not strongly
  stable, and zeros on the imaginary axis.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

import nrobust as nr
from nrobust import (
    DifferenceOperator,
    DistributedDelay,
    FilteredController,
    Hyperbolic2x2,
    QuasiPolynomial,
    QuasiTransferFunction,
    ReflectionController,
    TransportSystem,
)
from nrobust.bounds import l1_modulus, root_free_region, total_variation
from nrobust.errors import ParameterError
from nrobust.hyperbolic.kernels.constant import MAX_KERNEL_GRID, RESOLUTION, solve_kernels
from nrobust.lti.transfer import to_frd
from nrobust.plots.nyquist import nyquist_response
from nrobust.roots import count_roots

QP = QuasiPolynomial
NAN, INF = float("nan"), float("inf")
T = TransportSystem(1.0, 2.0, 0.5, 0.8)
PAPER = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
N0 = DistributedDelay([0.0, 0.5, 1.0], [1.0, 0.5, 0.25])
F0 = QP([[1.0, 1.0], [0.5]], [0.0, 1.0])  # s + 1 + 0.5 e^{-s}


def _sin(x: np.ndarray) -> np.ndarray:
    return np.sin(np.pi * x)


# ---------------------------------------------------------------- bad values by kind
#: not a finite real number: booleans, NaN, infinities, strings, complex, None, sequences, objects
NOT_REAL: list[Any] = [True, False, np.bool_(True), NAN, INF, -INF, "1", "abc", 1 + 1j, np.complex128(2.0), None, [1.0]]
NOT_REAL.append(object())
NOT_POSITIVE = [*NOT_REAL, 0.0, -1.0, -INF]
NOT_NONNEGATIVE = [*NOT_REAL, -1.0, -1e-300]
#: not a sequence of finite reals (two entries expected)
NOT_REAL_PAIR: list[Any] = [
    [True, False],
    ["a", "b"],
    "ab",
    None,
    [NAN, 1.0],
    [INF, 1.0],
    [1.0 + 1j, 2.0],
    [[0.0], [1.0, 2.0]],
    [1.0, None],
    [],
]
NOT_INT: list[Any] = [True, 2.5, "20", NAN, None, np.float64(20.0)]


def _cases() -> list[tuple[str, Callable[[Any], Any], str, list[Any]]]:
    """``(label, call with the bad value, name the error must carry, bad values)``."""
    cases: list[tuple[str, Callable[[Any], Any], str, list[Any]]] = []

    def add(label: str, fn: Callable[[Any], Any], name: str, values: list[Any]) -> None:
        cases.append((label, fn, name, values))

    # plants and controllers (Hyperbolic2x2 couplings also take callables)
    add("Hyperbolic2x2", lambda v: Hyperbolic2x2(v, 1.0, 1.0, 1.0, 1.0, 0.5), "lam", NOT_POSITIVE)
    add("Hyperbolic2x2", lambda v: Hyperbolic2x2(1.0, v, 1.0, 1.0, 1.0, 0.5), "mu", NOT_POSITIVE)
    add("Hyperbolic2x2", lambda v: Hyperbolic2x2(1.0, 1.0, v, 1.0, 1.0, 0.5), "sigma_pm", NOT_REAL)
    add("Hyperbolic2x2", lambda v: Hyperbolic2x2(1.0, 1.0, 1.0, v, 1.0, 0.5), "sigma_mp", NOT_REAL)
    add("Hyperbolic2x2", lambda v: Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, v, 0.5), "q", [*NOT_REAL, 0.0])
    add("Hyperbolic2x2", lambda v: Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, v), "rho", NOT_REAL)
    couplings = [lambda x: x > 0.5, lambda x: (1 + 1j) * x, lambda x: np.full_like(x, np.nan), lambda x: "a"]
    add("Hyperbolic2x2", lambda v: Hyperbolic2x2(1.0, 1.0, v, 1.0, 1.0, 0.5), "sigma_pm", couplings)
    add("TransportSystem", lambda v: TransportSystem(v, 1.0, 1.0, 0.5), "lam", NOT_POSITIVE)
    add("TransportSystem", lambda v: TransportSystem(1.0, v, 1.0, 0.5), "mu", NOT_POSITIVE)
    add("TransportSystem", lambda v: TransportSystem(1.0, 1.0, v, 0.5), "q", [*NOT_REAL, 0.0])
    add("TransportSystem", lambda v: TransportSystem(1.0, 1.0, 1.0, v), "rho", NOT_REAL)
    add("ReflectionController", ReflectionController, "K", NOT_REAL)
    add("FilteredController", lambda v: FilteredController(v, 1.0), "a", NOT_REAL)
    add("FilteredController", lambda v: FilteredController(0.5, v), "b", NOT_POSITIVE)
    # quasi-polynomials, distributed delays, difference operators, transfer functions
    add("QuasiPolynomial", lambda v: QP([[1.0], [0.5]], v), "delays", [*NOT_REAL_PAIR, [-1.0, 1.0], [0.0]])
    add("QuasiPolynomial", lambda v: QP([[1.0], v], [0.0, 1.0]), "coefs", [[True], ["a"], [NAN], [INF], [None], []])
    add("QuasiPolynomial", lambda v: QP(v, [0.0]), "coefs", ["abc", None, [], 1.0])
    add("DistributedDelay", lambda v: DistributedDelay(v, [1.0, 2.0]), "nodes", [*NOT_REAL_PAIR, [1.0, 0.0]])
    not_values = [v for v in NOT_REAL_PAIR if v != [1.0 + 1j, 2.0]]  # kernels may be complex
    add("DistributedDelay", lambda v: DistributedDelay([0.0, 1.0], v), "values", [*not_values, [1.0]])
    add("DistributedDelay", lambda v: DistributedDelay([0.0, 1.0], [True, False]), "values", [None])
    add("DifferenceOperator", lambda v: DifferenceOperator(v, [0.0, 1.0]), "coefs", not_values[1:])
    add("DifferenceOperator", lambda v: DifferenceOperator([True, False], [0.0, 1.0]), "coefs", [None])
    add("DifferenceOperator", lambda v: DifferenceOperator([1.0, -0.5], v), "delays", [*NOT_REAL_PAIR, [-1.0, 1.0]])
    add(
        "QuasiTransferFunction",
        lambda v: QuasiTransferFunction(1.0, v),
        "den",
        [True, NAN, "s", 0.0, QP([[0.0]], [0.0])],
    )
    add("QuasiTransferFunction", lambda v: QuasiTransferFunction(v, 1.0), "num", [True, INF, "s", None])
    H = QuasiTransferFunction(1.0, F0)
    add("frequency_response", H.frequency_response, "omega", [["a"], [True], [NAN], [1j], [[1.0], [1.0, 2.0]], None])
    add("to_frd", lambda v: to_frd(F0, v), "omega", ["abc", [True, False], [1.0, NAN], [1.0], [2.0, 1.0], None])
    # bounds
    add("l1_modulus", lambda v: l1_modulus(v, [0.1]), "N", [None, "s", F0, 1.0, [[1.0]]])
    add("l1_modulus", lambda v: l1_modulus(N0, v), "delta", ["abc", [], [True], [NAN], [-1.0], [[1.0], [1.0, 2.0]]])
    add("total_variation", total_variation, "N", [None, F0, 1.0])
    add("root_free_region", lambda v: root_free_region(v, 0.0), "F", [None, "s", 1.0, [[1.0]], object()])
    add("root_free_region", lambda v: root_free_region(F0, v), "x0", NOT_REAL)
    # kernels, Laplace route, simulation
    add("solve_kernels", lambda v: solve_kernels(PAPER, v), "kernel_grid", [*NOT_INT, 2, MAX_KERNEL_GRID + 2])
    add("boundary_function", lambda v: nr.boundary_function(T, v), "s", ["abc", [], [True], [NAN], [[1.0], [1, 2]]])
    add("boundary_function", lambda v: nr.boundary_function(T, v, scaled=True), "s", [[-1e3], [1e300]])
    C = ReflectionController(0.1)
    add("simulate", lambda v: nr.simulate(T, C, v, 1.0, _sin, _sin, 20), "delta", NOT_NONNEGATIVE)
    add("simulate", lambda v: nr.simulate(T, C, 0.1, v, _sin, _sin, 20), "t_end", NOT_POSITIVE)
    # cells=None is the scheme's documented default (simulate: 400 cells of u, n + m: 200)
    not_int = [v for v in NOT_INT if v is not None]
    add("simulate", lambda v: nr.simulate(T, C, 0.1, 1.0, _sin, _sin, v), "cells", [*not_int, 1, 10**9, 10**18])
    states = [None, "x", 1j, NAN, [NAN] * 21, lambda x: (1 + 1j) * x, lambda x: x > 0.5, lambda x: np.nan * x]
    add("simulate", lambda v: nr.simulate(T, C, 0.1, 1.0, v, _sin, 20), "u0", states)
    add("simulate", lambda v: nr.simulate(T, C, 0.1, 1.0, _sin, v, 20), "v0", [np.ones(3) * 1j, "abc"])
    # Nyquist
    A, B = QP([[1.0, 1.0]], [0.0]), QP([[0.5]], [0.0])
    add("nyquist_response", lambda v: nyquist_response(v, B), "A", [True, NAN, "s", None, QP([[0.0]], [0.0])])
    add("nyquist_response", lambda v: nyquist_response(A, v), "B", [False, INF, "0.5", None, -A])
    add("nyquist_response", lambda v: nyquist_response(A, B, v, 10.0, 64), "delta", NOT_NONNEGATIVE)
    add("nyquist_response", lambda v: nyquist_response(A, B, 0.1, v, 64), "omega_max", NOT_POSITIVE)
    add("nyquist_response", lambda v: nyquist_response(A, B, 0.1, 10.0, v), "n_freq", [*NOT_INT, 15, 10**7])
    return cases


_CASES = [(label, fn, name, value) for label, fn, name, values in _cases() for value in values]


@pytest.mark.parametrize(
    ("label", "fn", "name", "value"), _CASES, ids=[f"{c[0]}-{c[2]}-{i}" for i, c in enumerate(_CASES)]
)
def test_bad_input_is_a_named_parameter_error(label: str, fn: Callable[[Any], Any], name: str, value: Any) -> None:
    with pytest.raises(ParameterError) as info:
        fn(value)
    assert name in f"{info.value.name} {info.value}", f"{label}: {info.value}"


# ---------------------------------------------------------------- reproducers of items 5 and 6
def test_slow_plant_names_lam_with_its_admissible_range() -> None:
    """Item 5: ``lam = 1e-4`` made the kernel scheme overflow ("array must not contain infs or NaNs")."""
    system = Hyperbolic2x2(1e-4, 1.0, 1.0, 1.0, 1.0, 0.85)
    bound = 1.0 / (RESOLUTION * (MAX_KERNEL_GRID - 1))  # max|sigma| = 1
    for call in (
        lambda: nr.delay_margin(system, ReflectionController(0.1)),
        lambda: nr.simulate(system, ReflectionController(0.1), 0.1, 1.0, _sin, _sin, 30_000),
        lambda: solve_kernels(system),
    ):
        with pytest.raises(ParameterError) as info:
            call()
        assert info.value.name == "lam" and f"{bound:.6g}" in str(info.value)
    np.testing.assert_allclose(bound, 0.0025, rtol=1e-15)
    # mu is named when it is the slower speed
    with pytest.raises(ParameterError, match=r"^mu must be >= 0\.005"):
        solve_kernels(Hyperbolic2x2(1.0, 1e-4, 2.0, 1.0, 1.0, 0.85))


def test_coarse_kernel_grid_names_the_size_needed() -> None:
    """``lam = 0.005``: 1 / (0.25 * 0.005) = 800 steps, so 801 points; 201 are refused, 801 solve.

    (The default route of ``delay_margin`` needs no grid on this plant: ``N~`` in closed form.)
    """
    system = Hyperbolic2x2(0.005, 1.0, 1.0, 1.0, 1.0, 0.85)
    with pytest.raises(ParameterError, match=r"^kernel_grid must be >= 801 "):
        solve_kernels(system)
    with pytest.raises(ParameterError, match=r"^kernel_grid must be >= 801 "):
        nr.delay_margin(system, ReflectionController(0.1), kernel_grid=201)
    kernels = solve_kernels(system, 801, extrapolate=False)
    assert np.all(np.isfinite(kernels.K)) and np.all(np.isfinite(kernels.L))
    # the paper's plant on a coarse grid stays admissible: h max|sigma| / min(lam, mu) = 0.1 <= 0.25
    assert solve_kernels(PAPER, 11).n == 11


def test_complex_initial_state_is_refused_and_a_real_one_in_complex_dtype_is_not() -> None:
    C = ReflectionController(0.1)
    with pytest.raises(ParameterError, match=r"^u0 must be real-valued"):
        nr.simulate(T, C, 0.1, 1.0, lambda x: (1 + 1j) * np.sin(x), np.sin, 20)
    real = nr.simulate(T, C, 0.1, 1.0, _sin, _sin, 20)
    as_complex = nr.simulate(T, C, 0.1, 1.0, lambda x: _sin(x) + 0j, _sin, 20)
    np.testing.assert_array_equal(as_complex.norm, real.norm)


def test_huge_initial_state_has_a_finite_norm() -> None:
    """The squares of a state of size 1e300 overflow; the norm of the linear evolution does not."""
    C = ReflectionController(0.1)
    big = nr.simulate(T, C, 0.1, 1.0, lambda x: 1e300 * _sin(x), lambda x: 1e300 * _sin(x), 20)
    unit = nr.simulate(T, C, 0.1, 1.0, _sin, _sin, 20)
    assert np.all(np.isfinite(big.norm))
    np.testing.assert_allclose(big.norm, 1e300 * unit.norm, rtol=1e-13, atol=0)


def test_work_bound_of_simulate_comes_before_any_allocation() -> None:
    with pytest.raises(ParameterError, match=r"max_updates") as info:
        nr.simulate(T, ReflectionController(0.1), 0.1, 1.0, _sin, _sin, 10**12)
    assert "cells" in info.value.name


def test_non_numeric_delays_and_nodes_name_the_parameter() -> None:
    with pytest.raises(ParameterError, match=r"^delays must be"):
        QP([[1.0]], ["a"])
    with pytest.raises(ParameterError, match=r"^nodes must be"):
        DistributedDelay(["x", "y"], [1.0, 2.0])


def test_zero_denominator_refused_zero_numerator_accepted() -> None:
    with pytest.raises(ParameterError, match=r"^den must be not identically zero"):
        QuasiTransferFunction(1.0, 0.0)
    H = QuasiTransferFunction(0.0, F0)
    np.testing.assert_array_equal(H(np.array([0.5j, 1.0])), np.zeros(2))


def test_boolean_parameters_refused_where_numbers_are_expected() -> None:
    """Item 6: ``rho=True`` and ``ReflectionController(True)`` were read as 1."""
    with pytest.raises(ParameterError, match=r"^rho must be a finite real number"):
        Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, True)
    with pytest.raises(ParameterError, match=r"^K must be a finite real number"):
        ReflectionController(True)
    with pytest.raises(ParameterError, match=r"^delays must be"):
        QP([[1.0], [0.5]], [True, False])
    # numpy scalars and 0-d arrays are numbers
    assert Hyperbolic2x2(np.float64(1.0), np.int64(1), 1.0, 1.0, np.array(1.0), 0.5).q == 1.0


# ---------------------------------------------------------------- item 4: Nyquist counts are certified
# (A, B, delta, zeros of F = A + B e^{-delta s} in Re s > 0 by an independent argument)
COUNTED = [
    (QP([[1.0, 1.0]], [0.0]), QP([[0.5]], [0.0]), 1.0, 0),  # s + 1 + 0.5 e^{-s}: retarded, stable
    (QP([[-1.0, 1.0]], [0.0]), QP([[0.5]], [0.0]), 0.5, 1),  # s - 1 + 0.5 e^{-s/2}: one real zero in (0, 1)
    (QP([[2.0, 1.0]], [0.0]), QP([[-3.0, 0.4]], [0.0]), 0.7, 1),  # neutral, D = 1 + 0.4 e^{-0.7 s}
    (QP([[1.0, 0.0, 1.0]], [0.0]), QP([[0.0, 1.0]], [0.0]), 3.0, 2),  # s^2 + 1 + s e^{-3 s}: crossing on the bound
    (QP([[1.0, 0.0, 1.0]], [0.0]), QP([[0.0, 1.0]], [0.0]), 0.5, 0),  # the same loop below its margin 0.971
    (QP([[900.0, -0.2, 1.0]], [0.0]), 0.0, 0.0, 2),  # zeros 0.1 +- 30i, far outside the plotted band below
]


@pytest.mark.parametrize(("A", "B", "delta", "expected"), COUNTED)
def test_nyquist_count_is_certified_and_agrees_with_count_roots(A: Any, B: Any, delta: float, expected: int) -> None:
    resp = nyquist_response(A, B, delta, omega_max=5.0, n_freq=64)  # the count does not depend on the band
    assert resp.rhp_zeros == expected, resp.note
    assert resp.note == ""
    F = nr.quasipoly.as_quasipolynomial("A", A) + nr.quasipoly.as_quasipolynomial("B", B).shift(delta)
    assert int(count_roots(F, (0.0, 40.0, -200.0, 200.0))) == expected  # a box far larger than the certified one
    if resp.count_region is not None:
        re_min, re_max, im_min, im_max = resp.count_region
        assert re_min == 0.0
        free = root_free_region(F, 0.0)
        assert re_max > free.half_plane and im_max > free.radius and im_min < -free.radius


def test_nyquist_count_on_the_paper_loop_matches_the_crossing_analysis() -> None:
    A, B = nr.loop_factors(PAPER, ReflectionController(0.1))
    margin = nr.delay_margin(A, B)
    for delta in (0.1, 0.3):
        resp = nyquist_response(A, B, delta, omega_max=60.0, n_freq=2001)
        assert resp.rhp_zeros == int(margin.unstable_count(delta)), resp.note
    assert resp.rhp_zeros == 4


@pytest.mark.parametrize(
    ("A", "B", "delta", "why"),
    [
        (QP([[1.0]], [0.0]), QP([[0.0, 1.0]], [0.0]), 0.5, "advanced type"),  # 1 + s e^{-s/2}
        (QP([[1.0, 1.0]], [0.0]), QP([[0.0, 0.0, 1.0]], [0.0]), 1.0, "advanced type"),  # s + 1 + s^2 e^{-s}
        (QP([[1.0, 1.0]], [0.0]), QP([[0.0, 1.5]], [0.0]), 1.0, "spectral bound"),  # D = 1 + 1.5 e^{-s}: c_D > 0
        # (s + 1)(1 + 0.6 e^{-s} + 0.6 e^{-2s}): c_D = -ln(1/0.6)/2 < 0 <= C_D
        (QP([[1.0, 1.0], [0.6, 0.6]], [0.0, 1.0]), QP([[0.6, 0.6]], [0.0]), 2.0, "not strongly stable"),
        (QP([[1.0, 0.0, 1.0]], [0.0]), 0.0, 0.0, "imaginary axis"),  # s^2 + 1: zeros +- i on the contour
    ],
)
def test_nyquist_gives_no_count_where_none_is_certified(A: Any, B: Any, delta: float, why: str) -> None:
    resp = nyquist_response(A, B, delta, omega_max=20.0, n_freq=256)
    assert resp.rhp_zeros is None and resp.count_region is None
    assert why in resp.note


def test_advanced_loop_really_has_zeros_without_end_in_the_right_half_plane() -> None:
    """The loop the sampled winding called stable (item 4): zeros of ``1 + s e^{-s/2}`` in
    ``Re s > 0`` keep coming as the box grows (about ``|Im s| / (2 pi / 0.5)`` per half box)."""
    F = QP([[1.0]], [0.0]) + QP([[0.0, 1.0]], [0.0]).shift(0.5)
    counts = [int(count_roots(F, (0.0, 40.0, -h, h))) for h in (100.0, 200.0)]
    assert counts[0] > 0 and counts[1] > counts[0]
    assert math.isinf(nyquist_response(QP([[1.0]], [0.0]), QP([[0.0, 1.0]], [0.0]), 0.5).principal_bound)
