"""Messages and results at the edges of double precision: each names what is wrong and what is admissible."""

from __future__ import annotations

import sys
import time

import mpmath
import numpy as np
import pytest
from test_general import RHO, general_plant

import nrobust as nr
from nrobust import (
    CertificationError,
    Hyperbolic2x2,
    ParameterError,
    QuasiPolynomial,
    ReflectionController,
    StateFeedback,
    TransportSystem,
    certify,
    spectral_abscissa,
)
from nrobust.hyperbolic.loops.controllers import loop_factors, normalize
from nrobust.hyperbolic.nplusm import NPlusMCharacteristic, NPlusMSystem
from nrobust.margins import delay_margin

PLANT = Hyperbolic2x2(lam=1.0, mu=1.0, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)


def test_certify_refuses_an_unrepresentable_delta_max_by_name() -> None:
    """delta_max = 1e308: a ParameterError naming delta_max and its range, in well under a minute."""
    start = time.perf_counter()
    with pytest.raises(ParameterError) as err:
        certify(PLANT, ReflectionController(0.1), delta_max=1e308)
    assert err.value.name == "delta_max"
    assert "in (0, 471.188]" in str(err.value)  # log(max double) / 1.5 - tau, the default region Re s >= -3/tau
    with pytest.raises(ParameterError) as err:
        certify(PLANT, ReflectionController(0.1), delta_max=1e308, region=(0.0, 1.0, -1.0, 1.0))
    assert err.value.name == "delta_max" and "nodes merge" in str(err.value)
    assert time.perf_counter() - start < 20.0


def test_delay_margin_refuses_a_delay_whose_powers_overflow_without_region_advice() -> None:
    """A delay of 1e300: ParameterError naming the delays and their range, no advice about a region."""
    A, B = QuasiPolynomial([[1.0, 1.0]], [0.0]), QuasiPolynomial([[0.5]], [1e300])
    with pytest.raises(ParameterError) as err:
        delay_margin(A, B)
    assert err.value.name == "delays"
    assert "at most 2.82e+102" in str(err.value) and "region" not in str(err.value)


def test_spectral_abscissa_names_the_overflow_of_huge_coefficients() -> None:
    """``1e308 + s + 1e308 e^{-s}`` is retarded: the refusal names the scale, not the type."""
    with pytest.raises(ParameterError) as err:
        spectral_abscissa(QuasiPolynomial([[1e308, 1.0], [1e308]], [0.0, 1.0]))
    assert err.value.name == "F" and "2^200" in str(err.value)
    assert "overflow" in str(err.value) and "retarded or neutral" not in str(err.value)


def test_spectral_abscissa_refuses_a_delay_whose_square_overflows_without_region_advice() -> None:
    """A delay of 1e300 and no region: ParameterError naming the delays and their range, not a
    region the search built itself; with a region the search is the user's and runs."""
    F = QuasiPolynomial([[1.0, 1.0], [0.5]], [0.0, 1e300])
    with pytest.raises(ParameterError) as err:
        spectral_abscissa(F)
    assert err.value.name == "delays"
    assert "at most 1.34e+154" in str(err.value) and "region" not in str(err.value)
    at_limit = QuasiPolynomial([[1.0, 1.0], [0.5]], [0.0, 1e154])
    with pytest.raises(CertificationError) as cert:  # admitted: too many roots to find, not an overflow
        spectral_abscissa(at_limit, max_evals=20_000)
    assert "overflows" not in str(cert.value)


def _oracle_margin() -> tuple[mpmath.mpf, mpmath.mpf]:
    """``(w, delta*)`` of ``A = s + 1``, ``B = (1 - 2^-52) s + 2`` at 40 digits: ``|A(i w)| = |B(i w)|``
    gives ``w^2 (1 - c^2) = 3``; ``e^{-i w delta} = -A/B`` the first delay."""
    with mpmath.workdps(40):
        c = 1 - mpmath.mpf(2) ** -52
        w = mpmath.sqrt(3 / (1 - c**2))
        u = -(1 + 1j * w) / (2 + c * 1j * w)
        assert abs(abs(u) - 1) < mpmath.mpf(10) ** -30
        return w, ((-mpmath.arg(u)) % (2 * mpmath.pi)) / w


def test_rigorous_margin_with_a_gap_below_float_rounding() -> None:
    """``|b_n / a_n| = 1 - 2^-52 < 1`` exactly: strongly stable, the margin 3.82e-8 is proven."""
    pytest.importorskip("flint")
    A, B = QuasiPolynomial([[1.0, 1.0]], [0.0]), QuasiPolynomial([[2.0, 1.0 - 2.0**-52]], [0.0])
    dm = delay_margin(A, B, rigorous=True)
    w, delta = _oracle_margin()
    assert dm.strongly_stable and dm.nominally_stable and dm.margin_ball is not None
    assert dm.margin_ball[0] <= float(delta) <= dm.margin_ball[1]
    np.testing.assert_allclose(dm.margin, float(delta), rtol=1e-12)
    assert dm.omega is not None
    np.testing.assert_allclose(dm.omega, float(w), rtol=1e-9)


def test_float_margin_with_a_gap_below_rounding_is_not_called_zero() -> None:
    """The floating-point gap of these loops is ``0 +- r``: a zero margin was returned (unverified) where the
    transport plant with ``|q K| = 1 - 2^-53`` is stable for every delay (``1 - q K e^{-tau s}`` has a positive gap;
    found by the property-based harness). The ball gap decides: positive, the proof is tried within a small work
    bound (the transport loop: ``inf``; ``A = s + 1``, ``B = (1 - 2^-52) s + 2``: ``3.82e-8``, both proven; where it
    cannot decide, the zero margin's reason says the coefficients as given are not decided). An exactly zero gap
    keeps its zero margin, proven too."""
    pytest.importorskip("flint")
    plant, controller = TransportSystem(1.625, 2.125, -1.0, 0.0), ReflectionController(-0.9999999999999999)
    margin = nr.delay_margin(plant, controller)
    assert margin.margin == np.inf and margin.strongly_stable and margin.rigorous
    A, B = QuasiPolynomial([[1.0, 1.0]], [0.0]), QuasiPolynomial([[2.0, 1.0 - 2.0**-52]], [0.0])
    near = delay_margin(A, B)  # decided within the small work bound: the margin 3.82e-8 of the test above
    _, delta = _oracle_margin()
    assert near.rigorous and near.margin_ball is not None
    assert near.margin_ball[0] <= float(delta) <= near.margin_ball[1]
    # the paper's plant at the end of k_region: 1 - 0.85 - 0.15 = 2.8e-17 in doubles, a frequency bound near 3e17
    edge = nr.delay_margin(Hyperbolic2x2(1, 1, 1, 1, 1, 0.85), ReflectionController(0.15))
    assert edge.margin == 0.0 and not edge.verified and not edge.rigorous
    assert "> 0: strongly stable for the coefficients as given" in edge.reason
    assert "not decided for them as given" in edge.reason
    boundary = QuasiPolynomial([[2.0, 1.0]], [0.0])  # |b_1| = |a_1| exactly
    for rigorous in (False, True):
        at_boundary = delay_margin(A, boundary, rigorous=rigorous)
        assert at_boundary.margin == 0.0 and not at_boundary.strongly_stable


def test_float_margin_at_a_zero_gap_without_flint(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without python-flint (an extra) the floating-point margin at a gap zero to its accuracy keeps its zero margin
    and says that ball arithmetic would decide (no ImportError on the floating-point path)."""
    monkeypatch.setitem(sys.modules, "flint", None)
    edge = nr.delay_margin(Hyperbolic2x2(1, 1, 1, 1, 1, 0.85), ReflectionController(0.15))
    assert edge.margin == 0.0 and "pip install nrobust[rigorous]" in edge.reason


def test_natural_gain_cancels_the_reflection_of_a_general_plant_exactly() -> None:
    """``StateFeedback(-rho)`` on a general plant: ``k~ = -rho~`` to the bit, the certificate goes through."""
    plant = general_plant()
    system, controller = normalize(plant, StateFeedback(-RHO))
    assert controller.k == -system.rho
    A, B = loop_factors(plant, StateFeedback(-RHO))
    # rho q e^{-tau s} and k q e^{-tau s} cancel exactly in value; the proven radii of the principal gains
    # (VaryingProof.rho_q_radius, u_radius) stay as a ball about 0, far below the principal gap
    F = A + B
    assert all(not np.any(p) for p, _ in F.point_terms[1:])
    assert all(np.all(r < 1e-12) for r in F.radii_of()[1:])
    cert = certify(plant, StateFeedback(-RHO), delta_max=0.1, k_region=False)
    assert cert.nominally_stable and cert.delay_robust


# ---------------------------------------------------------------- n + m loops without a region
# the coupled 2 + 1 system of tests/test_nplusm.py, and two actuators on a coupled 2 + 2 system
TWO_ONE = NPlusMSystem(
    [1.0, 0.5], [1.5], [[0.0, 0.0, 0.4], [0.0, 0.0, 0.3], [0.5, -0.4, 0.0]], [[0.6], [0.5]], [[0.5, 0.4]]
)
TWO_TWO = NPlusMSystem(
    [1.0, 0.5],
    [1.0, 2.0],
    [[0.0, 0.1, 0.5, 0.2], [0.1, 0.0, 0.2, -0.3], [0.4, 0.1, 0.0, 0.1], [0.2, 0.6, 0.1, 0.0]],
    [[0.8, 0.1], [0.2, 0.7]],
    [[0.5, 0.2], [0.1, -0.4]],
)


def _loop_det(system: NPlusMSystem, K: list[list[float]], delta: float, s: complex) -> mpmath.mpc:
    """``det(E(s) (Phi_v - (R + K e^{-delta s}) Phi_u))`` at 40 digits, from the system's matrices:
    ``Phi(s) = exp(Lambda^{-1} (Sigma - s I))``, ``[Phi_u; Phi_v] = Phi [Q; I]``, ``E = diag(e^{-s/mu_j})``."""
    n, m = system.n, system.m
    with mpmath.workdps(40):
        s = mpmath.mpmathify(s)
        inv = [1 / mpmath.mpf(float(v)) for v in system.lam] + [-1 / mpmath.mpf(float(v)) for v in system.mu]
        a = mpmath.matrix(n + m, n + m)
        for i in range(n + m):
            for j in range(n + m):
                a[i, j] = inv[i] * (mpmath.mpf(float(system.sigma[i, j])) - (s if i == j else 0))
        phi = mpmath.expm(a)
        w = mpmath.matrix(n + m, m)
        for i in range(n):
            for j in range(m):
                w[i, j] = mpmath.mpf(float(system.q[i, j]))
        for j in range(m):
            w[n + j, j] = 1
        col = phi * w
        z = mpmath.exp(-delta * s)
        loop = mpmath.matrix(m, m)
        for j in range(m):
            for k in range(m):
                feedback = sum(
                    (mpmath.mpf(float(system.r[j, i])) + mpmath.mpf(float(K[j][i])) * z) * col[i, k] for i in range(n)
                )
                loop[j, k] = mpmath.exp(-s / mpmath.mpf(float(system.mu[j]))) * (col[n + j, k] - feedback)
        return mpmath.det(loop)


def _winding(system: NPlusMSystem, K: list[list[float]], delta: float, box: tuple[float, ...]) -> int:
    """Zeros of the loop determinant in ``box`` by the argument principle on a fine grid (double
    precision, the test's own formula with SciPy's ``expm``; each step's change of argument
    below ``pi / 4``, so the grid resolves the winding)."""
    from scipy.linalg import expm

    n, m = system.n, system.m
    x0, x1, y0, y1 = box
    edges = [
        np.linspace(complex(x0, y0), complex(x1, y0), 1001),
        np.linspace(complex(x1, y0), complex(x1, y1), 6001),
        np.linspace(complex(x1, y1), complex(x0, y1), 1001),
        np.linspace(complex(x0, y1), complex(x0, y0), 6001),
    ]
    s = np.concatenate([e[:-1] for e in edges] + [edges[0][:1]])
    inv = np.concatenate([1.0 / system.lam, -1.0 / system.mu])
    a = inv[None, :, None] * (system.sigma[None] - s[:, None, None] * np.eye(n + m)[None])
    col = expm(a) @ np.vstack([system.q, np.eye(m)])
    gain = system.r[None] + np.asarray(K)[None] * np.exp(-delta * s)[:, None, None]
    loop = np.exp(-s[:, None, None] / system.mu[None, :, None]) * (col[:, n:, :] - gain @ col[:, :n, :])
    f = np.linalg.det(loop)
    steps = np.angle(f[1:] / f[:-1])
    assert np.max(np.abs(steps)) < np.pi / 4
    return round(float(np.sum(steps)) / (2 * np.pi))


@pytest.mark.parametrize(
    ("system", "K", "delta"),
    [(TWO_ONE, [[-0.5, 0.0]], 0.0), (TWO_ONE, [[-0.5, 0.0]], 0.3), (TWO_TWO, [[-0.2, 0.0], [0.0, 0.1]], 0.5)],
)
def test_nplusm_abscissa_needs_no_region(system: NPlusMSystem, K: list[list[float]], delta: float) -> None:
    """The abscissa of an n + m loop without a region, from the proven far field of the loop.

    Oracles written here: Newton's method on the loop determinant at 40 digits from the
    reported root (a simple root: ``F`` is evaluated to about ``1e-14`` relative by SciPy's
    ``expm`` inside nrobust, so the root moves by ``1e-14 |F| / |F'|``, below ``1e-10``), and
    no zero right of it: the argument principle on a fine grid over ``[value + 0.01, 5] x
    [-30, 30]`` counts none (right of ``Re s = 5`` the far field holds for ``|s| >= 5``).
    """
    F = NPlusMCharacteristic(system, K, delta)
    ab = spectral_abscissa(F)
    assert ab.certified and ab.root is not None and not ab.approached_at_infinity
    assert ab.value <= ab.upper_bound and ab.strong_bound < ab.upper_bound
    with mpmath.workdps(40):
        root = complex(mpmath.findroot(lambda z: _loop_det(system, K, delta, z), mpmath.mpc(ab.root), tol=1e-30))
    np.testing.assert_allclose(ab.root.real, root.real, atol=1e-10)
    np.testing.assert_allclose(ab.root.imag, root.imag, atol=1e-10)
    x = ab.value + 0.01
    assert _winding(system, K, delta, (x, 5.0, -30.0, 30.0)) == 0
    radius = F.far_field_radius(5.0)  # and nothing right of Re s = 5: the far field holds there for |s| >= 5
    assert radius is not None and radius < 5.0
    # the far field of the first x (of a few) where it exists: the determinant is sampled nonzero there
    xf = next(v for v in (x, 0.0, 0.5, 1.0) if F.far_field_radius(v) is not None)
    R = F.far_field_radius(xf)
    assert R is not None
    far = xf + np.linspace(0.0, 2.0, 5)[:, None] + 1j * np.linspace(R, 8.0 * R, 200)[None, :]
    assert np.all(np.abs(F(far)) > 0.0)


def test_nplusm_far_field_is_the_principal_part_and_its_gap() -> None:
    """The far field of an n + m loop exists right of the first-term abscissa of its principal
    part, on both sides of 0, and not left of the chains: ``1 - 0.3 e^{-5/3 x} - 0.2 e^{-8/3 x}``
    (TWO_ONE, K = 0) vanishes at ``x_0``, by Brent's method below."""
    from scipy.optimize import brentq

    F = NPlusMCharacteristic(TWO_ONE)
    D = F.principal_part()
    np.testing.assert_allclose(sorted(np.abs(D.coefs)), [0.2, 0.3, 1.0], rtol=1e-12)
    x0 = brentq(lambda x: 1.0 - 0.3 * np.exp(-5.0 / 3.0 * x) - 0.2 * np.exp(-8.0 / 3.0 * x), -2.0, 2.0, xtol=1e-14)
    assert F.far_field_radius(x0 - 1e-6) is None
    for x in (x0 + 0.05, 0.0, 1.0):
        R = F.far_field_radius(x)
        assert R is not None and F.far_field_holds(x, R) and not F.far_field_holds(x, 0.5 * R)
    radii = np.array([F.far_field_radius(x) for x in (x0 + 0.05, 0.0, 1.0)], dtype=float)
    assert np.all(np.diff(radii) < 0.0)  # the far field widens to the right
