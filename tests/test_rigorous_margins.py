"""Delay margins proven in ball arithmetic (``delay_margin(..., rigorous=True)``).

Oracles independent of both the floating-point search and the proof: closed forms
(``arccos(-a/b) / sqrt(b^2 - a^2)``, the golden-ratio crossings of ``s^2 + 1`` against
``s``, the double zero of ``(w^2 - 8)^2``), high-precision evaluation (mpmath, 50 digits)
of the closed-form crossings of a loop built to fool the floating-point allowance, and
the floating-point margins themselves, which must lie in the proven balls wherever the
floating-point search is within its allowance.
"""

from __future__ import annotations

import json
import math
import sys
from decimal import Decimal
from pathlib import Path
from typing import Any

import mpmath
import numpy as np
import pytest

from nrobust import (
    CertificationError,
    FiniteTimeController,
    Hyperbolic2x2,
    OpenLoop,
    ParameterError,
    QuasiPolynomial,
    ReflectionController,
    TransportSystem,
    certify,
    loop_factors,
    rouche_delay_bound,
)
from nrobust import delay_margin as plant_margin
from nrobust.bounds import delay_bound_from_kernel
from nrobust.cli import main
from nrobust.config import load_system_file
from nrobust.margins.margin import delay_margin
from nrobust.margins.proven import proven_crossings, proven_gap, proven_zero_root
from nrobust.quasipoly import DistributedDelay
from nrobust.reports.certificate import CHECKED, PROVEN, _outward
from nrobust.reports.paper import PAPER_K, PAPER_SYSTEM

pytest.importorskip("flint")

QP = QuasiPolynomial
PHI = (1.0 + np.sqrt(5.0)) / 2.0
TANGENT_A = QP([[10.0, 2.0, 1.0]], [0.0])  # s^2 + 2 s + 10: |A|^2 - 36 = (w^2 - 8)^2


def inside(ball: tuple[float, float] | None, value: float, ulps: float = 0.0) -> bool:
    """``value`` in the ball, widened by ``ulps`` units of ``value`` (for floating-point results)."""
    assert ball is not None
    tol = ulps * float(np.finfo(float).eps) * abs(value)
    return bool(ball[0] - tol <= value <= ball[1] + tol)


def width(ball: tuple[float, float] | None) -> float:
    assert ball is not None
    return ball[1] - ball[0]


# The floating-point margin is an angle over a frequency computed in doubles, accurate
# to a few ulps; the proven balls are a few ulps wide: compared up to 8 ulps.
ULPS = 8.0


def synthetic_loop(rho_q: float, kq: float) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``A = 1 - rho q e^{-2 s} + I_N``, ``B = K q e^{-2 s} - I_N`` with a linear kernel with a jump."""
    x1, x2 = np.linspace(0.0, 1.0, 41), np.linspace(1.0, 2.0, 41)
    i_n = QP([], [], [DistributedDelay(np.r_[x1, x2], np.r_[0.6 * np.cos(2 * x1) + 0.3, -0.5 + 0.4 * x2])])
    return 1.0 - (QP([[rho_q]], [2.0]) - i_n), QP([[kq]], [2.0]) - i_n


# ============================================================ closed forms, exact polynomial route
@pytest.mark.parametrize("a, b", [(1.0, 2.0), (0.5, 3.0), (-0.2, 1.0), (0.0, 1.5), (3.0, 3.5)])
def test_first_order_closed_form_in_the_ball(a: float, b: float) -> None:
    A, B = QP([[a, 1.0]], [0.0]), QP([[b]], [0.0])
    dm = delay_margin(A, B, rigorous=True)
    exact = float(mpmath.acos(mpmath.mpf(-a) / b) / mpmath.sqrt(mpmath.mpf(b) ** 2 - mpmath.mpf(a) ** 2))
    assert dm.rigorous and dm.method == "ball arithmetic" and dm.nominally_stable
    assert inside(dm.margin_ball, exact) and inside(dm.margin_ball, delay_margin(A, B).margin, ULPS)
    assert width(dm.margin_ball) <= 1e-14 * max(1.0, exact)  # a few ulps: the zeros are isolated exactly
    assert [c.direction for c in dm.crossings] == [1]


def test_undamped_oscillator_crossing_on_the_frequency_bound() -> None:
    """``s^2 + 1`` against ``s``: crossings at ``1/phi`` and at ``phi = W``, margin ``pi / (2 phi)``."""
    A, B = QP([[1.0, 0.0, 1.0]], [0.0]), QP([[0.0, 1.0]], [0.0])
    proof = proven_crossings(A, B)
    assert proof.method == "exact polynomial" and proof.multiplicities == (1, 1) and proof.slopes == (-1, 1)
    assert inside(proof.omegas[0], 1.0 / PHI) and inside(proof.omegas[1], PHI)
    assert proof.frequency_bound >= PHI
    json.dumps(proof.to_dict(), allow_nan=False)  # strict JSON
    dm = delay_margin(A, B, rigorous=True)
    assert inside(dm.margin_ball, np.pi / 2.0 / PHI)
    assert inside(dm.margin_ball, delay_margin(A, B).margin, ULPS)


def test_exact_tangency_is_a_proven_double_zero() -> None:
    B = QP([[6.0]], [0.0])
    proof = proven_crossings(TANGENT_A, B)
    assert proof.multiplicities == (2,) and proof.slopes == (0,) and inside(proof.omegas[0], 2.0 * np.sqrt(2.0))
    dm = delay_margin(TANGENT_A, B, rigorous=True)
    w = mpmath.sqrt(8)
    u = -6 / (10 - w**2 + 2j * w)  # -B/A at s = i w
    exact = float(mpmath.arg(u) % (2 * mpmath.pi) / w)
    assert dm.crossings[0].tangential and inside(dm.margin_ball, exact)
    assert inside(dm.margin_ball, delay_margin(TANGENT_A, B).margin, ULPS)


def test_complex_coefficients_scan_both_signs() -> None:
    A, B = QP([[1.0, 1.0]], [0.0]), QP([[2.0j]], [0.0])
    dm, fl = delay_margin(A, B, rigorous=True), delay_margin(A, B)
    assert dm.omega is not None and dm.omega < 0 and inside(dm.margin_ball, fl.margin, ULPS)
    assert [c.direction for c in dm.crossings] == [c.direction for c in fl.crossings]


def test_second_order_windows_agree_with_the_closed_form() -> None:
    """``s^2 + 0.1 s + 1 + 0.5 e^{-delta s}``: ``w^4 + (a^2 - 2 b) w^2 + b^2 - c^2 = 0`` gives both crossings."""
    a, b, c = 0.1, 1.0, 0.5
    A, B = QP([[b, a, 1.0]], [0.0]), QP([[c]], [0.0])
    p = 2 * b - a * a
    w2 = (p + np.sqrt(p * p - 4 * (b * b - c * c))) / 2
    wp = np.sqrt(w2)
    exact = float(np.mod(np.angle(-c / (b - w2 + 1j * a * wp)), 2 * np.pi) / wp)
    dm, fl = delay_margin(A, B, delta_max=12.0, rigorous=True), delay_margin(A, B, delta_max=12.0)
    assert abs(dm.margin - exact) <= 1e-12 * exact and inside(dm.margin_ball, fl.margin, ULPS)
    assert [n for _, _, n in dm.counts] == [n for _, _, n in fl.counts] == [0, 2, 0, 2, 4]
    np.testing.assert_allclose([hi for _, hi, _ in dm.counts], [hi for _, hi, _ in fl.counts], rtol=1e-12)


@pytest.mark.parametrize("a, b", [(0.0, 1.0), (0.1, 1.0), (0.15, 2.0)])
def test_filtered_transport_loop_by_the_ball_route(a: float, b: float) -> None:
    """``(1 + b s)(1 - 0.85 e^{-2s})`` against ``(1 + a s) 0.85 e^{-2s}``: two delays in ``A``, so ``g`` is
    transcendental and the crossings are isolated by bisection in balls."""
    A = QP([[1.0, b], [-0.85, -0.85 * b]], [0.0, 2.0])
    B = QP([[0.85, 0.85 * a]], [2.0])
    proof = proven_crossings(A, B)
    fl = delay_margin(A, B)
    assert proof.method == "ball bisection" and not proof.unresolved
    assert sorted(c.direction for c in fl.crossings) == sorted(
        s * (1 if lo > 0 else -1) for (lo, _), s in zip(proof.omegas, proof.slopes)
    )
    for (lo, hi), c in zip(proof.omegas, sorted(fl.crossings, key=lambda c: c.omega)):
        assert lo - 1e-12 * hi <= c.omega <= hi + 1e-12 * hi
    dm = delay_margin(A, B, rigorous=True)
    assert inside(dm.margin_ball, fl.margin, ULPS) and width(dm.margin_ball) < 1e-12


# ============================================================ a loop built to fool the allowance
@pytest.mark.parametrize("rel", [1e-14, 1e-15])
def test_near_tangency_below_the_allowance_is_proven_away(rel: float) -> None:
    """``min (|A|^2 - |B|^2) = 36 (2 rel - rel^2) > 0``: no crossing, margin inf.

    The floating-point search sees ``g`` and ``g'`` vanish to its rounding allowance and
    reports a tangency, hence a finite margin that does not exist.
    """
    B = QP([[6.0 * (1.0 - rel)]], [0.0])
    fl = delay_margin(TANGENT_A, B)
    assert fl.crossings and fl.crossings[0].tangential and np.isfinite(fl.margin)  # fooled
    dm = delay_margin(TANGENT_A, B, rigorous=True)
    assert dm.margin == np.inf and dm.margin_ball == (np.inf, np.inf) and not dm.crossings
    assert dm.intervals == ((0.0, np.inf),)


@pytest.mark.parametrize("rel", [1e-14, 1e-15])
def test_pair_born_below_the_allowance_is_two_proven_crossings(rel: float) -> None:
    """``c = 6 (1 + rel)``: two simple crossings at ``w^2 = 8 -+ sqrt(c^2 - 36)``, to 50 digits."""
    c = 6.0 * (1.0 + rel)
    B = QP([[c]], [0.0])
    mpmath.mp.dps = 50
    try:
        cc = mpmath.mpf(c)
        root = mpmath.sqrt(cc**2 - 36)
        delays = []
        for w in (mpmath.sqrt(8 - root), mpmath.sqrt(8 + root)):
            u = -cc / (10 - w**2 + 2j * w)
            delays.append(mpmath.arg(u) % (2 * mpmath.pi) / w)
        exact = float(min(delays))
    finally:
        mpmath.mp.dps = 15
    dm = delay_margin(TANGENT_A, B, rigorous=True)
    assert [c.direction for c in dm.crossings] == [1, -1] or sorted(c.direction for c in dm.crossings) == [-1, 1]
    assert inside(dm.margin_ball, exact)
    fl = delay_margin(TANGENT_A, B)
    assert fl.crossings[0].tangential  # the floating-point path sees one tangency instead
    assert not inside(dm.margin_ball, fl.margin, 1e3)  # and its margin is off by more than it claims


@pytest.mark.parametrize("rel", [1e-14, 2e-15, -1e-14, -2e-15])
def test_transcendental_near_tangency_decided_in_balls(rel: float) -> None:
    """``s + 2 + 0.5 e^{-s}`` against ``c``: ``|A(i w)|^2`` has a minimum ``m`` at ``w* ~ 1.53``; with
    ``c = sqrt(m) (1 - rel)`` the gap ``m - c^2`` is ``~ 2 rel m``, below the floating-point allowance.

    Oracle: ``w*``, ``m``, the two crossings and their delays at 40 digits (mpmath). The
    floating-point search reports one tangency in every case; the ball route proves no
    crossing (``rel > 0``) or two simple ones (``rel < 0``) and encloses the true margin.
    """
    A = QP([[2.0, 1.0], [0.5]], [0.0, 1.0])
    mpmath.mp.dps = 40
    try:

        def g(w: Any) -> Any:
            return abs(1j * w + 2 + 0.5 * mpmath.exp(-1j * w)) ** 2 - cc**2

        cc = mpmath.mpf(0)
        wstar = mpmath.findroot(lambda w: mpmath.diff(g, w), 1.53)
        m = g(wstar)
        c = float(mpmath.sqrt(m) * (1 - rel))
        cc = mpmath.mpf(c)
        gap = g(wstar)
        delays = []
        if gap < 0:
            half = mpmath.sqrt(-2 * gap / mpmath.diff(g, wstar, 2))
            for w0 in (wstar - half, wstar + half):
                w = mpmath.findroot(g, w0)
                u = -cc / (1j * w + 2 + 0.5 * mpmath.exp(-1j * w))
                delays.append(mpmath.arg(u) % (2 * mpmath.pi) / w)
        exact = float(min(delays)) if delays else np.inf
    finally:
        mpmath.mp.dps = 15
    B = QP([[c]], [0.0])
    fl = delay_margin(A, B)
    assert [x.tangential for x in fl.crossings] == [True]  # the floating-point path sees a tangency
    dm = delay_margin(A, B, rigorous=True)
    assert proven_crossings(A, B).method == "ball bisection"
    if rel > 0:
        assert gap > 0 and dm.margin == np.inf and not dm.crossings
    else:
        assert gap < 0 and len(dm.crossings) == 2 and inside(dm.margin_ball, exact)
        assert not inside(dm.margin_ball, fl.margin, 1e3)


def test_cancelling_pair_of_delayed_terms_is_refused_within_the_work_bound() -> None:
    """``s + 1 + 1e8 (e^{-s} - e^{-(1 + 1e-9) s})`` against ``2``: terms 1e8 apart cancel to ~0.1.

    The proven frequency bound is ``W ~ 2e8`` (the moduli of the pair enter the tail), so
    a complete search is out of reach: both paths refuse before allocating their grids.
    """
    A = QP([[1.0, 1.0], [1e8], [-1e8]], [0.0, 1.0, 1.0 + 1e-9])
    B = QP([[2.0]], [0.0])
    with pytest.raises(CertificationError, match="max_evals"):
        delay_margin(A, B, rigorous=True)
    with pytest.raises(CertificationError, match="max_evals"):
        delay_margin(A, B)


# ============================================================ zero and infinite margins
@pytest.mark.parametrize(
    "rho_q, kq, expected", [(0.85, 0.1, np.inf), (-0.6, 0.3, np.inf), (0.85, 0.2, 0.0), (0.3, -0.8, 0.0)]
)
def test_transport_reflection_controller(rho_q: float, kq: float, expected: float) -> None:
    """Margin inf iff ``|rho q| + |K q| < 1`` (eq. (13)), 0 when it exceeds 1 (Theorem 3)."""
    A, B = QP([[1.0], [-rho_q]], [0.0, 2.0]), QP([[kq]], [2.0])
    dm = delay_margin(A, B, rigorous=True)
    assert dm.margin == expected and dm.margin_ball == (expected, expected)
    assert (proven_gap(A, B)[0] > 0.0) == (expected > 0.0)


def test_unstable_nominal_and_zero_root() -> None:
    dm = delay_margin(QP([[-1.0, 1.0]], [0.0]), QP([[0.5]], [0.0]), rigorous=True)  # s - 0.5 at delta = 0
    assert dm.margin == 0.0 and dm.margin_ball == (0.0, 0.0) and dm.nominal_unstable == 1
    A, B = QP([[-1.0, 1.0]], [0.0]), QP([[1.0]], [0.0])
    assert proven_zero_root(A, B)
    dm = delay_margin(A, B, rigorous=True)
    assert dm.zero_root and dm.margin_ball == (0.0, 0.0)
    # s + 1 - 0.5 e^{-s} against -0.5: F(0) = 0 exactly; g has a double zero at w = 0, where the
    # floating-point search gives up, while the exact zero decides the margin in balls
    A, B = QP([[1.0, 1.0], [-0.5]], [0.0, 1.0]), QP([[-0.5]], [0.0])
    with pytest.raises(CertificationError):
        delay_margin(A, B)
    dm = delay_margin(A, B, rigorous=True)
    assert dm.zero_root and dm.margin == 0.0 and dm.margin_ball == (0.0, 0.0)


# ============================================================ distributed delays: the ball route
def test_distributed_loop_float_margin_inside_the_ball() -> None:
    A, B = synthetic_loop(0.85, 0.1)
    fl = delay_margin(A, B)
    dm = delay_margin(A, B, rigorous=True)
    proof = proven_crossings(A, B)
    assert proof.method == "ball bisection" and not proof.unresolved
    assert len(proof.omegas) == len(fl.crossings)
    for (lo, hi), c in zip(proof.omegas, sorted(fl.crossings, key=lambda c: c.omega)):
        assert lo <= c.omega <= hi
    assert inside(dm.margin_ball, fl.margin, ULPS)
    assert width(dm.margin_ball) < 1e-10
    assert sorted(c.direction for c in dm.crossings) == sorted(c.direction for c in fl.crossings)


@pytest.mark.slow
def test_paper_example_margin_proven() -> None:
    """``U_BS2(K = 0.1)`` on the paper's plant: the crossing at ``w ~ 6.281`` fixes ``delta* ~ 0.2295``."""
    plant = Hyperbolic2x2(**PAPER_SYSTEM)
    ctrl = ReflectionController(PAPER_K)
    fl = plant_margin(plant, ctrl)
    dm = plant_margin(plant, ctrl, rigorous=True)
    assert dm.rigorous and dm.nominally_stable and inside(dm.margin_ball, fl.margin, ULPS)
    assert width(dm.margin_ball) < 1e-11
    assert dm.omega is not None and abs(dm.omega - 6.28096) < 1e-4
    proof = proven_crossings(*loop_factors(plant, ctrl))
    assert len(proof.omegas) == 5 and not proof.unresolved


# ============================================================ refusals and validation
def test_delay_independent_loop_is_refused() -> None:
    with pytest.raises(CertificationError, match="count_roots"):
        delay_margin(QP([[1.0, 1.0]], [0.0]), QP([[0.0]], [0.0]), rigorous=True)


def test_rigorous_switch_is_validated() -> None:
    with pytest.raises(ParameterError, match="rigorous"):
        delay_margin(QP([[1.0, 1.0]], [0.0]), QP([[2.0]], [0.0]), rigorous="yes")  # type: ignore[arg-type]


def test_without_flint_the_error_says_how_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "flint", None)
    with pytest.raises(ImportError, match=r"nrobust\[rigorous\]"):
        delay_margin(QP([[1.0, 1.0]], [0.0]), QP([[2.0]], [0.0]), rigorous=True)


# ============================================================ the Rouché range in exact arithmetic
def test_rouche_bound_exact_for_a_constant_kernel() -> None:
    """``N = c`` on ``[0, 1]``: ``omega(d) = 2 c d`` for ``d <= 1``, so ``delta_0 -> epsilon_0 / (2 c)``."""
    c, eps0 = 0.3, 0.05
    N = DistributedDelay([0.0, 1.0], [c, c])
    bound = delay_bound_from_kernel(N, eps0, rigorous=True)
    assert bound.rigorous and bound.steps > 1
    assert (1.0 - 1e-5) * eps0 / (2 * c) < bound.delta_0 < eps0 / (2 * c)


@pytest.mark.slow
def test_rouche_bound_of_the_paper_example_proven_and_below_the_margin() -> None:
    plant = Hyperbolic2x2(**PAPER_SYSTEM)
    ctrl = ReflectionController(PAPER_K)
    fl = rouche_delay_bound(plant, ctrl)
    ex = rouche_delay_bound(plant, ctrl, rigorous=True)
    assert ex.rigorous and not fl.rigorous
    # both marches stop when the step falls below rtol = 1e-6 of the delay; their steps differ (the float
    # march's slope bound is the total variation of the linearised closed form with its error bound,
    # the exact march's that of the linear interpolant): measured 1.6e-6 apart
    np.testing.assert_allclose(ex.delta_0, fl.delta_0, rtol=1e-5)
    # independent check: the L1 modulus of the PDE's N~ at delta_0 stays below epsilon_0. N~ of the
    # paper's plant (kappa = -1, a = -1/4) by SciPy's Bessel functions: with r = sqrt(nu (2 - nu)) / 2,
    # W = J_0(2r), h_22 = -(2 - nu) J_1(2r) / (4 r), h_11 = -nu J_1(2r) / (4 r), N~ = h_22 - 0.85 h_11 - 0.925 W
    from scipy.special import j0, j1

    def n_tilde(nu):
        nu = np.asarray(nu, dtype=float)
        inside = (nu >= 0.0) & (nu <= 2.0)
        r = np.sqrt(np.clip(nu * (2.0 - nu), 0.0, None)) / 2.0
        g = np.where(r > 0, j1(2.0 * r) / np.where(r > 0, r, 1.0), 1.0)  # J_1(2r) / r -> 1 as r -> 0
        value = -(2.0 - nu) * g / 4.0 + 0.85 * nu * g / 4.0 - 0.925 * j0(2.0 * r)
        return np.where(inside, value, 0.0)

    d = ex.delta_0
    nu = np.linspace(0.0, 2.0 + d, 400_001)
    omega = np.trapezoid(np.abs(n_tilde(nu) - n_tilde(nu - d)), nu)  # error ~ h (jumps of N~ at 0 and 2)
    assert omega < ex.epsilon_0 and ex.epsilon_0 - omega < 1e-3
    assert ex.delta_0 < plant_margin(plant, ctrl).margin


# ============================================================ what the certificate says
RIGOROUS_TOML = """
[system]
type = "TransportSystem"
lam = 1.0
mu = 1.0
q = 1.0
rho = 0.85

[controller]
type = "ReflectionController"
K = 0.1

[analysis]
delta_max = 0.1
region = [-1.0, 0.5, -6.0, 6.0]
k_region = false
rigorous = true
"""


def test_analyze_with_the_toml_switch_marks_every_claim(tmp_path: Path) -> None:
    path = tmp_path / "SYSTEM.toml"
    path.write_text(RIGOROUS_TOML)
    out = tmp_path / "out"
    assert main(["analyze", str(path), "-o", str(out), "--no-progress"]) == 0
    data = json.loads((out / "certificate.json").read_text())
    assert data["rigorous"] is True and "ball arithmetic" in data["scope"]
    statuses = {c["name"]: c["status"] for c in data["claims"]}
    for name in ("nominal stability", "delay margin", "stability up to delta_max", "roots at delta = 0"):
        assert statuses[name] == PROVEN, (name, statuses)
    assert data["model_error"]["statement"].startswith("no kernel")
    md = (out / "report.md").read_text()
    assert "**What is proven.**" in md and PROVEN in md


def test_toml_switch_is_validated(tmp_path: Path) -> None:
    path = tmp_path / "SYSTEM.toml"
    path.write_text(RIGOROUS_TOML.replace("rigorous = true", 'rigorous = "yes"'))
    with pytest.raises(ParameterError, match=r"analysis\.rigorous"):
        load_system_file(path)


def test_refused_proof_is_checked_and_says_why() -> None:
    """The open loop does not depend on the delay (``B = 0``): its margin is refused in balls, checked in floats."""
    plant = TransportSystem(1.0, 1.0, 1.0, 0.85)
    cert = certify(plant, OpenLoop(), 0.1, region=(-1.0, 0.5, -6.0, 6.0), k_region=False, rigorous=True)
    claims = {c.name: c.status for c in cert.claims}
    assert claims["delay margin"] == CHECKED and claims["roots at delta = 0"] == PROVEN
    assert any(note.startswith("delay margin: not proven") for note in cert.unproven)
    assert cert.delay_margin == np.inf


def test_float_certificate_marks_every_claim_checked() -> None:
    plant = TransportSystem(1.0, 1.0, 1.0, 0.85)
    cert = certify(plant, ReflectionController(0.1), 0.1, region=(-1.0, 0.5, -6.0, 6.0), k_region=False)
    assert not cert.rigorous and cert.claims
    assert cert.model_error is not None and cert.model_error.error == 0.0  # uncoupled: no kernel, no model
    assert {c.status for c in cert.claims} == {CHECKED}


@pytest.mark.slow
def test_paper_certificates_prove_the_central_claims() -> None:
    """U_BS2(0.1): stable at delta = 0 and on [0, 0.1], the crossing fixing delta*; U_BS: a zero in Re s > 0."""
    plant = Hyperbolic2x2(**PAPER_SYSTEM)
    bs2 = certify(plant, ReflectionController(PAPER_K), 0.1, k_region=False, rigorous=True)
    claims = {c.name: c for c in bs2.claims}
    for name in ("nominal stability", "stability up to delta_max", "crossing that fixes delta*", "delay margin"):
        assert claims[name].status == PROVEN, name
    # the exact route: no model between the proofs and the PDE
    assert bs2.route == "exact" and bs2.model_error is not None and bs2.model_error.difference == 0.0
    assert bs2.scope.startswith("Claims marked proven hold for the PDE itself")
    lo, hi = bs2.margin.margin_ball
    assert lo <= 0.2295391302761485093812871100572 <= hi  # the crossing equations at 40 digits (test_exact_form)
    # the abscissa claim states the proven bound, not the estimate: the nominal loop is the target system
    # 1 - (rho - K) q e^{-2 s}, its chain at ln(0.75) / 2 = -0.1438410362258904 (closed form); the proven upper
    # end (Krawczyk boxes about the roots) is near -0.14384103524, which the statement may not undercut
    stated = Decimal(claims["spectral abscissa"].statement.rsplit("> ", 1)[1])
    assert claims["spectral abscissa"].status == PROVEN
    assert stated >= Decimal(bs2.abscissa.upper_bound) and stated >= Decimal(math.log(0.75) / 2)
    bs = certify(plant, FiniteTimeController(), 0.01, region=(-1.5, 0.5, -2.0, 2.0), k_region=False, rigorous=True)
    claims = {c.name: c for c in bs.claims}
    assert claims["instability at delta_max"].status == PROVEN
    assert claims["delay margin"].status == PROVEN and bs.delay_margin == 0.0


def test_displayed_bounds_round_outwards() -> None:
    """A bound written in a claim stays a bound: lower ends rounded down, upper ends up."""
    rng = np.random.default_rng(7)
    for x in np.r_[rng.normal(size=50) * 10.0 ** rng.integers(-8, 8, size=50), 0.22953913042698212]:
        for digits in (3, 6, 16):
            assert (
                Decimal(_outward(float(x), digits, False))
                <= Decimal(float(x))
                <= Decimal(_outward(float(x), digits, True))
            )
