"""Certificates and reports: every field is consistent with the computation it names."""

from __future__ import annotations

import json

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest

from nrobust.errors import ParameterError
from nrobust.hyperbolic import GeneralHyperbolic2x2, Hyperbolic2x2, StateFeedback, TransportSystem
from nrobust.hyperbolic.loops.controllers import (
    FilteredController,
    FiniteTimeController,
    ReflectionController,
    characteristic,
)
from nrobust.reports.certificate import Certificate, _representation, certify
from nrobust.reports.report import write_report

SYSTEM = TransportSystem(lam=1.0, mu=1.0, q=1.0, rho=0.85)


@pytest.fixture(scope="module")
def filtered() -> Certificate:
    return certify(SYSTEM, FilteredController(0.1, 1.0), delta_max=0.1)


def test_filtered_difference_operator_is_eq_cond_a_b(filtered):
    """Principal part b - (b - a) rho q e^{-tau s} at delta = 0, and
    b - b rho q e^{-tau s} + a rho q e^{-(tau + delta) s} for delta > 0 (eq. (17))."""
    rq = 0.85
    assert filtered.principal_nominal.gamma_0 == pytest.approx(rq * 0.9, rel=1e-13, abs=1e-14)
    assert filtered.principal_delayed.gamma_0 == pytest.approx(rq * 1.1, rel=1e-13, abs=1e-14)
    assert filtered.principal_delayed.delays == pytest.approx((0.0, 2.0, 2.1), rel=1e-13, abs=1e-14)
    assert filtered.principal_delayed.strongly_stable


def test_filtered_margin_is_a_root_on_the_axis(filtered):
    assert filtered.nominally_stable and filtered.delay_robust
    d, w = filtered.delay_margin, filtered.margin.omega
    assert 0.1 < d < np.inf and w > 0
    F = characteristic(SYSTEM, FilteredController(0.1, 1.0), d)
    assert abs(F(np.array([1j * w]))[0]) < 1e-8
    assert filtered.stable_up_to_delta_max
    assert "delay-robust" in filtered.verdict


def test_root_counts_and_abscissa_agree(filtered):
    for roots in (filtered.roots_nominal, filtered.roots_delayed):
        assert roots.certified
        assert int(np.sum(roots.box_counts)) == roots.count == int(np.sum(roots.multiplicities))
        assert np.all(roots.roots.real < 0)
    assert filtered.abscissa.value < 0
    assert filtered.abscissa.value >= np.max(filtered.roots_nominal.roots.real) - 1e-9


def test_json_is_strict_and_complete(filtered):
    data = json.loads(filtered.to_json())
    assert data["delay_margin"] == pytest.approx(filtered.delay_margin, rel=1e-13, abs=1e-14)
    assert data["controller"]["controller"] == "FilteredController"
    assert data["system"]["rho"] == 0.85
    assert set(data["versions"]) == {"nrobust", "numpy", "scipy", "python"}
    assert data["rouche"] is None and data["k_region"] is None
    assert data["roots_nominal"]["count"] == filtered.roots_nominal.count


def test_report_files(filtered, tmp_path):
    files = write_report(filtered, tmp_path)
    md = files.markdown.read_text()
    page = files.html.read_text()
    assert filtered.margin_text in md and filtered.margin_text in page
    assert md.count("![") == len(files.figures) == 2
    assert page.count("data:image/png;base64,") == 2 and "<img" in page
    for fig in files.figures:
        assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads(files.json[0].read_text())["verdict"] == filtered.verdict


def test_bad_arguments():
    with pytest.raises(ParameterError, match="delta_max"):
        certify(SYSTEM, FilteredController(0.1, 1.0), delta_max=0.0)
    with pytest.raises(ParameterError, match="region"):
        certify(SYSTEM, FilteredController(0.1, 1.0), region=(1.0, 0.0, -1.0, 1.0))
    with pytest.raises(ParameterError, match="certificates"):
        write_report([], "unused")


def test_transport_reflection_controller_matches_eq_boun_K2():
    """U_BS2 on the transport system: |K q| < 1 - |rho q| gives an infinite margin, the
    Rouche range is unbounded and the admissible gains are |K| < (1 - |rho q|)/|q|."""
    cert = certify(SYSTEM, ReflectionController(0.1), delta_max=0.1)
    assert cert.delay_margin == np.inf and cert.stable_up_to_delta_max
    assert cert.principal_delayed.gamma_0 == pytest.approx(0.95, rel=1e-13, abs=1e-14)
    assert cert.rouche.delta_0 == np.inf
    ((lo, hi),) = cert.k_region.intervals
    # the exact ends: the strong-stability limit |rho q| + |K q| = 1, verified 1e-10 k inside and outside
    assert cert.k_region.tol == pytest.approx(1e-10 * 0.15, rel=1e-12)
    np.testing.assert_allclose([lo, hi], [-0.15, 0.15], rtol=0, atol=1e-15)
    assert [end.kind for end in cert.k_region.ends[0]] == ["strong_stability", "strong_stability"]
    assert cert.k_region_error == ""
    data = json.loads(cert.to_json())
    assert data["delay_margin"] == "inf" and data["k_region"]["paper_bound"] == pytest.approx(
        0.15, rel=1e-13, abs=1e-14
    )


def test_transport_finite_time_controller_has_zero_margin():
    """Theorem 3 / eq. (11): gamma_0 = 2 |rho q| = 1.7 > 1, margin 0."""
    cert = certify(SYSTEM, FiniteTimeController(), delta_max=0.05)
    assert cert.nominally_stable and not cert.delay_robust and cert.delay_margin == 0.0
    assert cert.principal_delayed.gamma_0 == pytest.approx(1.7, rel=1e-13, abs=1e-14)
    assert not cert.principal_delayed.strongly_stable
    assert cert.principal_delayed.spectral_bound > 0 and cert.principal_delayed.chains[0] == pytest.approx(
        cert.principal_delayed.spectral_bound, rel=1e-13, abs=1e-14
    )
    assert "zero delay margin" in cert.verdict


def test_report_counts_unstable_zeros_by_two_routes(tmp_path):
    """Beyond its margin (0.31) the filtered loop has zeros in Re s > 0: the crossing
    analysis and the Nyquist winding of F/((s+1) D) must give the same number."""
    cert = certify(SYSTEM, FilteredController(0.1, 1.0), delta_max=0.5)
    assert not cert.stable_up_to_delta_max
    expected = int(cert.margin.unstable_count(0.5))
    assert expected > 0
    md = write_report(cert, tmp_path).markdown.read_text()
    assert f"| {expected} (crossings); {expected} (Nyquist winding) |" in md


@pytest.mark.slow
def test_scope_says_how_each_plant_kind_represents_n_tilde():
    """The rigorous scope names the representation of N~ actually certified: kernels, none, or the
    characteristic route of a varying lam/mu (whose N~ has no kernel)."""
    # varying speeds on a plant the proof refuses (its kernels' error at the last degree is too large at L = 3)
    refused = GeneralHyperbolic2x2(
        lambda x: 1.2 * np.exp(0.3 * x), lambda x: 0.7 + 0.1 * x**2, 0.0, 0.5, 0.3, 0.0, 0.7, -0.4, length=3.0
    )
    scope = certify(refused, StateFeedback(-0.3), delta_max=0.5, k_region=False, rigorous=True).scope
    assert "characteristic route" in scope and "spline of the kernels" not in scope
    varying = GeneralHyperbolic2x2(lambda x: 1.0 + x, lambda x: 2.0 - x, 0.2, np.cos, 0.5, -0.3, 0.9, 0.6)
    scope = certify(varying, StateFeedback(-0.3), delta_max=0.5, k_region=False, rigorous=True).scope
    assert "the PDE itself" in scope and "speeds times a factor within" in scope
    scope = certify(SYSTEM, ReflectionController(0.1), delta_max=0.1, k_region=False, rigorous=True).scope
    assert "N~ = 0 exactly" in scope and "kernels on the kernel grid" not in scope
    coupled = Hyperbolic2x2(1.0, 1.0, 0.5, 0.5, 0.9, 0.6)
    assert "kernels on the kernel grid (201 points)" in _representation(coupled, StateFeedback(-0.3, 0.1), 201)
    assert "varying speeds" in _representation(varying, StateFeedback(-0.3, np.cos), 201)
    assert "varying speeds" not in _representation(varying, StateFeedback(-0.3), 201)
    assert not certify(SYSTEM, ReflectionController(0.1), delta_max=0.1, k_region=False).rigorous
