"""Design requirements: a window of delays [d_min, d_max] and a tolerance on the transport speeds.

Oracles: the stability window of the oscillator s^2 - 0.1 s + 1 + K e^{-delta s} in closed form
(its two crossing frequencies from a quadratic in w^2, their first delays theta / w) and the ends
of its gains stable on a window by mpmath at 40 digits; the pair birth that ends the paper's
window design by mpmath at 40 digits on the closed-form boundary function; the decay rate
-ln((rho - K) q) / tau of Lemma 3; brute-force grids of certified delay margins and root counts;
mismatched plants Hyperbolic2x2(lam (1 + e), mu (1 + e')) built here with the nominal law's gains.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import mpmath as mp
import numpy as np
import pytest

from nrobust import Hyperbolic2x2, QuasiPolynomial, ReflectionController, StateFeedback
from nrobust import delay_margin as plant_margin
from nrobust.cli import main
from nrobust.config import load_system_file
from nrobust.design import DESIGN_KINDS, best_decay_rate, best_margin, window_stability
from nrobust.errors import CertificationError, ParameterError
from nrobust.hyperbolic.analyses import design_filtered_exact, design_reflection, speed_tolerance
from nrobust.hyperbolic.analyses.kregion import u_bs2_loop
from nrobust.hyperbolic.kernels.constant import solve_kernels
from nrobust.margins import AffineGainLoop, delay_margin

# the oscillator x'' - 0.1 x' + x + K x(t - delta) = 0: unstable at delta = 0 for every K in (0, 1)
DAMP, STIFF = -0.1, 1.0
OSC_A = QuasiPolynomial([[STIFF, DAMP, 1.0]], [0.0])
OSC = AffineGainLoop(OSC_A, QuasiPolynomial([[0.0]], [0.0]), QuasiPolynomial([[1.0]], [0.0]))
# the paper's example (section 4.2)
RHO, Q, TAU = 0.85, 1.0, 2.0
KB = (1.0 - RHO * Q) / Q  # eq. (54)
BOUNDS = (-0.99 * KB, 0.99 * KB)
PAPER = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, RHO)


def _osc_crossings(K: float) -> list[tuple[float, float, int]]:
    """``(w, first delay, direction)`` of the oscillator's crossings.

    ``|STIFF - w^2 + i DAMP w| = K`` is quadratic in ``u = w^2``.
    """
    p = 2.0 * STIFF - DAMP**2
    root = np.sqrt(p**2 - 4.0 * (STIFF**2 - K**2))
    out = []
    for u, direction in (((p - root) / 2.0, -1), ((p + root) / 2.0, 1)):  # g' < 0 at the smaller root: stabilising
        w = np.sqrt(u)
        theta = np.mod(np.angle(-K / (STIFF - u + 1j * DAMP * w)), 2.0 * np.pi)
        out.append((w, theta / w, direction))
    return out


def test_window_of_the_oscillator_in_closed_form() -> None:
    """Count 2 at delta = 0; the stabilising crossing comes first: stable between the two first delays."""
    (_, t1, s1), (_, t2, s2) = _osc_crossings(0.5)
    assert s1 == -1 and s2 == 1 and t1 < t2  # 4.6212 < 4.9541
    B = QuasiPolynomial([[0.5]], [0.0])
    window = window_stability(OSC_A, B, (4.7, 4.9))
    assert window.stable and window.count == 0 and window.certified == "checked"
    assert window.enclosing is not None
    # 1e-12: the crossings are zeros of a polynomial, solved to rounding (about 1e-15 relative)
    np.testing.assert_allclose(window.enclosing, (t1, t2), rtol=0, atol=1e-12)
    np.testing.assert_allclose(window.clearance, min(4.7 - t1, t2 - 4.9), rtol=0, atol=1e-12)
    proven = window_stability(OSC_A, B, (4.7, 4.9), rigorous=True)
    assert proven.stable and proven.certified == "proven"
    # a crossing delay inside the window, and the nominal loop's two roots in Re s > 0
    assert not window_stability(OSC_A, B, (4.5, 4.7)).stable
    unstable = window_stability(OSC_A, B, (0.0, 1.0))
    assert not unstable.stable and unstable.count == 2
    json.dumps(window.to_dict(), allow_nan=False)


def _osc_end_mp(level: float, which: int, K0: float) -> float:
    """The gain at which the first delay of the crossing ``which`` (0: the smaller w) equals ``level``, 40 digits."""
    mp.mp.dps = 40
    damp, stiff = mp.mpf(DAMP), mp.mpf(STIFF)

    def delay(K: mp.mpf) -> mp.mpf:
        p = 2 * stiff - damp**2
        u = (p + (2 * which - 1) * mp.sqrt(p**2 - 4 * (stiff**2 - K**2))) / 2
        w = mp.sqrt(u)
        theta = mp.arg(-K / (stiff - u + mp.mpc(0, damp * w)))
        return (theta if theta >= 0 else theta + 2 * mp.pi) / w

    return float(mp.findroot(lambda K: delay(K) - level, mp.mpf(K0)))


def test_window_design_on_a_loop_unstable_without_delay() -> None:
    """The gains stable on [4.7, 4.85]: from K_lo = 0.2 to where the stabilising delay reaches 4.7 (mpmath)."""
    design = best_decay_rate(OSC, (0.2, 0.9), delays=(4.7, 4.85))
    assert design.delays == (4.7, 4.85) and design.windows[0].stable
    ((lo, hi),) = design.feasible
    ends = [_osc_end_mp(4.7, 0, 0.52), _osc_end_mp(4.85, 1, 0.45)]
    # the first delay of the stabilising crossing rises with K, the other's falls: the nearer end wins
    assert ends[0] < ends[1]
    # 1e-9: the end is moved 1e-10 * 0.9 inside and solved by brentq in w to 1e-15
    np.testing.assert_allclose(hi, ends[0], rtol=0, atol=1e-9)
    assert lo == 0.2
    assert lo <= design.K <= hi
    # brute force: certified windows on a grid of gains agree with the feasible interval
    for K in np.linspace(0.2, 0.9, 8):
        dm = delay_margin(OSC_A, QuasiPolynomial([[float(K)]], [0.0]), delta_max=6.0)
        counts = dm.unstable_count(np.linspace(4.7, 4.85, 31))
        assert bool(np.all(counts == 0)) == (lo <= K <= hi)
    # the margin objective: 0 everywhere (unstable at delta = 0); any gain of the widest interval
    by_margin = best_margin(OSC, (0.2, 0.9), delays=(4.7, 4.85))
    assert by_margin.kind == "window" and by_margin.value == 0.0 and lo <= by_margin.K <= hi
    assert "window end" in DESIGN_KINDS and "met, checked" in by_margin.requirement


def test_an_unreachable_window_names_the_best_reach() -> None:
    """From d_min = 4.7 the oscillator's stable window reaches farthest at K = 0.2: d_max = 5.5 is refused."""
    reach = _osc_crossings(0.2)[1][1]  # the destabilising crossing's first delay at K = 0.2: 5.28485
    with pytest.raises(ParameterError, match=r"delays must be d_max below about 5\.28") as info:
        best_decay_rate(OSC, (0.2, 0.9), delays=(4.7, 5.5))
    # the reach is interpolated on the scanned curves: 1e-3
    np.testing.assert_allclose(float(str(info.value).split("about ")[1].split(",")[0]), reach, rtol=0, atol=1e-3)


def _pair_birth_mp(K0: float, w0: float) -> tuple[float, float, float]:
    """The pair birth g = dg/dw = 0 of the paper's loop (eq. (60)) near ``(K0, w0)``, 40 digits: ``(K, w, delay)``.

    A(s) = e^{-s} (v(1) - rho u(1)) from the boundary function of the plant (exp of the 2x2 matrix
    [[-s, 1], [-1, s]] in closed form), B = 1 - rho q e^{-tau s} - A + K q e^{-tau s}.
    """
    mp.mp.dps = 40
    rho, q = mp.mpf(RHO), mp.mpf(Q)

    def g(w: mp.mpf, K: mp.mpf) -> mp.mpf:
        s = mp.mpc(0, w)
        k = mp.sqrt(s * s - 1)
        c, sk = mp.cosh(k), mp.sinh(k) / k
        A = mp.exp(-s) * ((-sk * q + (c + s * sk)) - rho * ((c - s * sk) * q + sk))
        z = mp.exp(-2 * s)
        B = 1 - rho * q * z - A + K * q * z
        return abs(A) ** 2 - abs(B) ** 2

    K, w = mp.findroot(
        lambda K, w: [g(w, K), mp.diff(lambda x: g(x, K), w)], (mp.mpf(K0), mp.mpf(w0)), tol=mp.mpf(10) ** -30
    )
    s = mp.mpc(0, w)
    k = mp.sqrt(s * s - 1)
    c, sk = mp.cosh(k), mp.sinh(k) / k
    A = mp.exp(-s) * ((-sk * q + (c + s * sk)) - rho * ((c - s * sk) * q + sk))
    B = 1 - rho * q * mp.exp(-2 * s) - A + K * q * mp.exp(-2 * s)
    theta = mp.arg(-B / A)
    return float(K), float(w), float((theta if theta >= 0 else theta + 2 * mp.pi) / w)


def test_paper_window_design_against_a_grid_and_mpmath() -> None:
    """Decay rate under [0.05, 0.2] on the paper's plant: beats a grid of certified windows; its end is a pair birth."""
    design = design_reflection(PAPER, "decay_rate", delays=(0.05, 0.2))
    d = design.design
    assert d.kind == "window end" and d.end is not None and d.end.kind == "pair_birth"
    K, w, delay = _pair_birth_mp(d.end.K, d.end.omega)
    # the birth is solved by brentq on dK/dw to 1e-15 in w; 1e-9 covers the loop's rounding
    np.testing.assert_allclose((d.end.K, d.end.omega), (K, w), rtol=1e-9)
    assert 0.05 <= delay <= 0.2  # the pair is born inside the window
    # Lemma 3: the nominal decay rate in closed form
    np.testing.assert_allclose(d.decay_rate, -np.log((RHO - d.K) * Q) / TAU, rtol=1e-9)
    loop = u_bs2_loop(PAPER)
    best_on_grid = -np.inf
    for Kg in np.linspace(-0.1, 0.14, 7):  # the gains nearer the bound of eq. (54) have margins below 0.06
        dm = delay_margin(loop.A, loop.B(float(Kg)), delta_max=0.25)
        if np.all(dm.unstable_count(np.linspace(0.05, 0.2, 31)) == 0):
            best_on_grid = max(best_on_grid, -np.log((RHO - Kg) * Q) / TAU)
    assert d.value >= best_on_grid - 1e-12
    assert d.windows[0].stable and "met, checked" in design.requirement


def test_a_window_from_zero_is_the_margin_requirement() -> None:
    """[0, d] is delta* > d: the same end as margin_at_least = d; beyond the best margin a ParameterError names it."""
    loop = u_bs2_loop(PAPER)
    by_window = best_decay_rate(loop, BOUNDS, delays=(0.0, 0.2))
    by_margin = best_decay_rate(loop, BOUNDS, margin_at_least=0.2)
    np.testing.assert_allclose(by_window.K, by_margin.K, rtol=0, atol=1e-15)
    assert by_window.kind == "window end" and by_margin.kind == "margin constraint"
    with pytest.raises(ParameterError, match=r"d_max below 0\.232292"):
        best_decay_rate(loop, BOUNDS, delays=(0.0, 0.3))


def test_bad_requirements_are_parameter_errors(tmp_path: Path) -> None:
    bad: list[Any] = [(0.2, 0.1), (-0.1, 0.2), (0.0, 0.0), (0.1, float("inf")), (0.1,)]
    for delays in bad:
        with pytest.raises(ParameterError, match="delays must be a pair"):
            design_reflection(PAPER, "decay_rate", delays=delays)
    for eps in (1.0, 1.5, 0.0, -0.1):
        with pytest.raises(ParameterError, match=r"speed_tolerance must be .*\(0, 1\)"):
            design_reflection(PAPER, "decay_rate", margin_at_least=0.1, speed_tolerance=eps)
    with pytest.raises(ParameterError, match="margin_at_least"):
        design_reflection(PAPER, "decay_rate", margin_at_least=0.1, delays=(0.0, 0.1))
    with pytest.raises(ParameterError, match="speed_tolerance"):
        design_reflection(PAPER, "margin", speed_tolerance=0.1)
    head = (
        '[system]\ntype = "Hyperbolic2x2"\nlam = 1.0\nmu = 1.0\nsigma_pm = 1.0\nsigma_mp = 1.0\nq = 1.0\n'
        'rho = 0.85\n\n[controller]\ntype = "ReflectionController"\nK = 0.1\n\n[analysis]\ndelta_max = 0.1\n\n'
        "[design]\n"
    )
    for body, key in (
        ("delays = [0.3, 0.1]\n", "design.delays"),
        ("delays = [-1.0, 0.1]\n", "design.delays"),
        ("delays = 0.1\n", "design.delays"),
        ("speed_tolerance = 1.0\n", "design.speed_tolerance"),
        ('family = "filtered"\nspeed_tolerance = 0.1\n', "design.speed_tolerance"),
        ("speed_tolerance = 0.1\n", "design.speed_tolerance"),  # no delay requirement for the speeds to keep
        ("delays = [true, 0.2]\n", "design.delays"),
    ):
        path = tmp_path / "bad.toml"
        path.write_text(head + body)
        with pytest.raises(ParameterError, match=rf"{key} must be"):
            load_system_file(path)
    path = tmp_path / "good.toml"
    path.write_text(head + "delays = [0.05, 0.2]\nspeed_tolerance = 0.01\n")
    assert load_system_file(path)["design"]["delays"] == (0.05, 0.2)


def test_design_command_states_the_window(tmp_path: Path) -> None:
    system = tmp_path / "paper.toml"
    system.write_text(
        '[system]\ntype = "Hyperbolic2x2"\nlam = 1.0\nmu = 1.0\nsigma_pm = 1.0\nsigma_mp = 1.0\nq = 1.0\n'
        'rho = 0.85\n\n[controller]\ntype = "ReflectionController"\nK = 0.1\n\n[analysis]\ndelta_max = 0.1\n\n'
        '[design]\nobjective = "decay_rate"\ndelays = [0.05, 0.2]\n'
    )
    out = tmp_path / "out"
    assert main(["design", str(system), "-o", str(out), "--k-bounds", "0.1", "0.145"]) == 0
    text = (out / "design.md").read_text()
    assert "requirement: exponentially stable for every delay in [0.05, 0.2]: met, checked" in text
    data = json.loads((out / "design.json").read_text())
    assert data["delays"] == [0.05, 0.2] and data["design"]["windows"][0]["stable"] is True


def _mismatched_margin(K: float, e_lam: float, e_mu: float, kernel_grid: int) -> float:
    """The certified margin of U_BS2(K)'s law (gains on the nominal kernels) on the plant with scaled speeds."""
    law = ReflectionController(K).feedback_law(PAPER, solve_kernels(PAPER, kernel_grid))
    plant = Hyperbolic2x2(PAPER.lam * (1 + e_lam), PAPER.mu * (1 + e_mu), 1.0, 1.0, 1.0, RHO)
    controller = StateFeedback(law.boundary_gain, law.gain_u, law.gain_v)
    dm = plant_margin(plant, controller, kernel_grid=kernel_grid)
    return float(dm.margin) if dm.nominally_stable else 0.0


@pytest.mark.long
def test_speed_tolerance_design_against_mismatched_plants() -> None:
    """Decay rate with delta* > 0.15 under 2 % speed errors: certified at the corners, checked on a 3 x 3 grid."""
    design = design_reflection(PAPER, "decay_rate", margin_at_least=0.15, speed_tolerance=0.02, kernel_grid=51)
    tol = design.tolerance
    assert tol is not None and tol.met and tol.certified == "checked at the corners"
    assert "not certified" in tol.statement and len(tol.points) == 9
    for a, b in tol.points[:4]:
        assert _mismatched_margin(design.K, a, b, 51) > 0.15
    # the corners constrain the design: past the solved end of the feasible gains a corner fails
    nominal = design_reflection(PAPER, "decay_rate", margin_at_least=0.15)
    assert design.design.value <= nominal.design.value + 1e-12
    K_out = design.design.feasible[-1][1] + 1e-3
    assert min(_mismatched_margin(K_out, a, b, 51) for a, b in tol.points[:4]) < 0.15 or K_out > BOUNDS[1]


def test_speed_tolerance_on_an_uncoupled_plant() -> None:
    """|rho q| + |K q| < 1 on a transport plant: stable for every delay and every speed; exact route."""
    plant = Hyperbolic2x2(1.0, 2.0, 0.0, 0.0, 1.0, 0.5)
    result = speed_tolerance(plant, ReflectionController(0.2), 0.3, (0.5, 2.0), grid=2)
    assert result.met and len(result.points) == 4 and result.route == "exact"
    for (a, b), window in zip(result.points, result.windows):
        oracle = Hyperbolic2x2(1.0 + a, 2.0 * (1.0 + b), 0.0, 0.0, 1.0, 0.5)
        assert np.isinf(plant_margin(oracle, StateFeedback(-0.2)).margin) and window.stable
    json.dumps(result.to_dict(), allow_nan=False)


def test_filtered_window_design_ends_at_the_pair_birth() -> None:
    """b of FilteredController(0, b, 0.1) stable on [0.1, 0.4]: from the pair birth b = 0.6298503342.

    The birth is the one tests/test_filter_cutoff.py solves by mpmath at 40 digits (to 1e-10): a
    crossing pair born there with a delay inside the window.
    """
    result = design_filtered_exact(PAPER, "margin", parameters={"b": (0.3, 1.5), "K": 0.1, "a": 0.0}, delays=(0.1, 0.4))
    d = result.design
    assert d.kind == "window end" and d.end is not None and d.end.kind == "pair_birth"
    assert 0.1 <= d.end.delay <= 0.4
    np.testing.assert_allclose(d.end.K, 0.6298503342, rtol=0, atol=1e-9)  # the mpmath value to 10 digits
    assert d.accuracy[0] < 1e-9 and d.windows[0].stable


# s - 1 + 2 e^{-delta s}: |i w - 1| = 2 at w = sqrt(3), where e^{-i w delta} = (1 - i sqrt 3) / 2 = e^{-i pi / 3}:
# delta* = pi / (3 sqrt 3); stable on [0, delta*), a zero on the axis at delta*, unstable just past it.
EDGE_A, EDGE_B = QuasiPolynomial([[-1.0, 1.0]], [0.0]), QuasiPolynomial([[2.0]], [0.0])


def _edge_delay() -> mp.mpf:
    with mp.workdps(40):
        return mp.pi / (3 * mp.sqrt(3))


def test_a_window_ending_at_the_crossing_delay_is_not_refuted() -> None:
    """A window whose end is the crossing delay to rounding: undecided (CertificationError), never 'refuted'."""
    d_star = float(_edge_delay())
    assert abs(d_star - _edge_delay()) < 1e-16  # the float is the crossing to rounding
    for rigorous in (False, True):
        try:
            w = window_stability(EDGE_A, EDGE_B, (0.0, d_star), rigorous=rigorous)
        except CertificationError as exc:
            assert "end of the window" in str(exc) or "could not be counted" in str(exc)
        else:  # the float may lie below the true crossing: stable is then right, refuted never is
            assert w.stable and w.certified != "refuted"
    with pytest.raises(CertificationError, match=r"could not be counted|end of the window"):
        window_stability(EDGE_A, EDGE_B, (d_star, d_star))
    w = window_stability(EDGE_A, EDGE_B, (0.0, 0.7), rigorous=True)
    assert not w.stable and w.certified == "refuted"  # a crossing well inside


def test_the_printed_stability_window_lies_inside_the_true_one() -> None:
    """The reason prints the enclosing window rounded inwards: its upper end is below the crossing delay."""
    w = window_stability(EDGE_A, EDGE_B, (0.0, 0.5), rigorous=True)
    assert w.stable and w.certified == "proven"
    printed_hi = mp.mpf(w.reason.split("(")[1].split(")")[0].split(",")[1])
    assert printed_hi <= _edge_delay()
    assert _edge_delay() - printed_hi < 1e-9  # ten digits


def test_requirements_print_the_window_exactly() -> None:
    """A window of many digits is printed as given, not rounded outwards (0.12345678 is not 0.123457)."""
    A, B = QuasiPolynomial([[1.0, 1.0]], [0.0]), QuasiPolynomial([[0.5]], [0.0])  # s + 1 + 0.5 e^{-delta s}
    loop = AffineGainLoop(A, QuasiPolynomial([[0.0]], [0.0]), B)
    design = best_margin(loop, (0.5, 0.9), delays=(0.0, 0.12345678))
    assert "[0.0, 0.12345678]" in design.requirement
