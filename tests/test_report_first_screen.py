"""What a reader sees first in a report: the answer, one picture, the plant in the user's terms."""

from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest

from nrobust._digits import with_accuracy
from nrobust.config import load_system_file
from nrobust.hyperbolic import (
    FiniteTimeController,
    GeneralHyperbolic2x2,
    ReflectionController,
    StateFeedback,
    TransportSystem,
)
from nrobust.hyperbolic.loops.controllers import FilteredController
from nrobust.reports.certificate import certify
from nrobust.reports.report import certificate_figures, write_report

# rho q = 0.85: U_BS2(0.1) has gamma_0 = 0.95 < 1 and no crossing (infinite margin); the filtered
# U_BS has the finite margin 0.31 (tests/test_certificate.py), below delta_max = 0.5
SYSTEM = TransportSystem(lam=1.0, mu=1.0, q=1.0, rho=0.85)


@pytest.fixture(scope="module")
def filtered():
    return certify(SYSTEM, FilteredController(0.1, 1.0), delta_max=0.5)


@pytest.fixture(scope="module")
def infinite():
    return certify(SYSTEM, ReflectionController(0.1), delta_max=0.1, k_region=False)


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def _prose(md: str) -> str:
    """The Markdown without code spans, image links and HTML tags."""
    md = re.sub(r"`[^`]*`", "", md)
    md = re.sub(r"!\[[^\]]*\]\([^)]*\)", "", md)
    return re.sub(r"<[^>]+>", "", md)


def test_the_answer_comes_before_any_table(filtered, tmp_path):
    """The verdict panel (stability at delta = 0 with the decay rate, the margin with its accuracy,
    what is proven) opens the section, then the picture, then the tables."""
    md = write_report(filtered, tmp_path).markdown.read_text()
    panel = md.index("> **")
    assert panel < md.index("![") < md.index("| quantity |")
    answer = md[panel : md.index("![")]
    assert f"delta* = {filtered.margin_text}" in answer
    assert f"decay rate {with_accuracy(-filtered.abscissa.value, filtered.abscissa.accuracy)}" in answer
    assert "nothing in ball arithmetic" in answer and "argument principle" in answer and "rigorous = true" in answer
    page = (tmp_path / "report.html").read_text()
    assert page.index('class="answer"') < page.index("<table")


def test_first_picture_is_the_delay_chart_above_root_maps_of_one_region(filtered):
    """One picture: zeros in Re s > 0 against delta with delta* marked, and both root maps on the same rectangle."""
    caption, fig = certificate_figures(filtered)[0]
    chart, nominal, delayed = fig.axes
    assert chart.get_xlabel() == "loop delay delta"
    marks = [line for line in chart.get_lines() if line.get_label().startswith("delta* = ")]
    assert len(marks) == 1
    np.testing.assert_allclose(marks[0].get_xdata()[0], filtered.delay_margin, rtol=0, atol=0)
    assert nominal.get_xlim() == delayed.get_xlim() and nominal.get_ylim() == delayed.get_ylim()
    assert caption.startswith("Closed-loop roots in a region holding the rightmost roots")


def test_delayed_root_map_needs_no_second_abscissa_search(filtered, monkeypatch):
    """Every zero in Re s > 0 at delta_max (2, by the crossing analysis) lies in the certified region:
    the map takes its rectangle from the certificate, without a spectral abscissa of the delayed loop."""
    import nrobust.plots.rootmap as rootmap

    def refuse(*args, **kwargs):
        raise AssertionError("spectral_abscissa recomputed for a root map")

    monkeypatch.setattr(rootmap, "spectral_abscissa", refuse)
    assert int(filtered.margin.unstable_count(0.5)) == 2
    (_, fig), _ = certificate_figures(filtered)
    assert fig.axes[1].get_ylim() == fig.axes[2].get_ylim()


def test_float_path_says_what_it_guarantees_and_how_to_prove(infinite):
    cert = infinite
    assert not cert.rigorous
    assert "integers checked in floating point" in cert.scope and "argument principle" in cert.scope
    assert "checked" in cert.scope and "not proven" in cert.scope
    assert "rigorous = true" in cert.scope and "[analysis]" in cert.scope


def test_human_text_for_infinite_margins_regimes_and_state_feedback(infinite, tmp_path):
    """No internal names, no "[inf", no equation of U_BS / U_BS2 on a state feedback's row."""
    assert infinite.delay_margin == np.inf
    # delta_max = 0.1: the unstable chains' first roots near Im s = 31, a small map
    finite_time = certify(SYSTEM, FiniteTimeController(), delta_max=0.1, k_region=False)
    feedback = certify(SYSTEM, StateFeedback(-0.1), delta_max=0.1, k_region=False)
    md = write_report([infinite, finite_time, feedback], tmp_path).markdown.read_text()
    assert "delta* = infinity (stable for every delay)" in md
    assert "no finite-time controller is delay-robust here" in md
    assert "[inf" not in md and "no_robust_finite_time" not in md and not re.search(r"\binf\b", md)
    prose = _prose(md)
    assert re.findall(r"\b[a-z]+_[a-z]{2,}\w*", prose) == []
    section = md[md.index("## 3. StateFeedback") :]
    gamma_row = next(
        line for line in section.splitlines() if line.startswith("| gamma_0 of the difference operator, delta = 0.1")
    )
    assert "eq." not in gamma_row


GENERAL = """
[system]
type = "GeneralHyperbolic2x2"
lam = 1.0
mu = 2.0
a = 0.3
b = 0.5
c = 0.4
d = -0.2
q = 0.9
rho = 0.6
length = 2.0

[controller]
type = "{kind}"
{gain}

[analysis]
delta_max = 0.5
"""


def _plant_text(tmp_path: Path, kind: str, gain: str) -> tuple[str, dict]:
    from nrobust.reports.report import _plant_blocks  # the plant's paragraphs of a report

    path = tmp_path / f"{kind}.toml"
    path.write_text(GENERAL.format(kind=kind, gain=gain))
    spec = load_system_file(path)
    # the fields of a certificate that the plant's paragraphs read, without the analysis
    cert = SimpleNamespace(
        system=spec["system"],
        controller=spec["controller"],
        given_system=spec["given_system"],
        given_controller=spec["given_controller"],
    )
    return "\n".join(p.text for p in _plant_blocks(cert)), spec


def test_general_plant_is_reported_in_the_users_terms(tmp_path):
    text, spec = _plant_text(tmp_path, "StateFeedback", "k = -0.8")
    assert isinstance(spec["given_system"], GeneralHyperbolic2x2)
    first = text.splitlines()[0]
    assert "lam = 1, mu = 2, a = 0.3, b = 0.5, c = 0.4, d = -0.2, q = 0.9, rho = 0.6, length = 2, time_unit = 1" in (
        first
    )
    assert "StateFeedback(k=-0.8," in first and "normal-form coupling" not in first
    # constant coefficients: analysed as written (the exact route), not through the normal form
    assert "Analysed as written: constant coefficients" in text and "As analysed: its normal form" not in text
    assert spec["system"] is spec["given_system"]


def test_reflection_gain_on_a_general_plant_is_said_to_be_a_normal_form_quantity(tmp_path):
    text, spec = _plant_text(tmp_path, "ReflectionController", "K = 0.05")
    assert "reads K in the normal form's coordinates" in text
    # the physical gain on u(t, L): U = k u(L) maps to k~ = k e^{A(L) + k_b - D(L)} (feedback_to_normal),
    # so U~ = -K u~(1) is the physical gain -K / e^{A(L) + k_b - D(L)}
    scale = spec["given_system"].normal_form().feedback_to_normal(1.0, 0.0, 0.0)[0]
    assert f"is the gain {-0.05 / scale:.6g} on the plant's u(t, L)" in text


def test_a_general_plants_rho_q_is_said_to_be_the_normal_forms(tmp_path):
    # q rho = 0.54 as written; the classification's rho q is the normal form's (weighted by a and d)
    _, spec = _plant_text(tmp_path, "ReflectionController", "K = 0.05")
    cert = certify(spec["system"], spec["controller"], delta_max=0.1, k_region=False)
    rho_q = spec["system"].normal_form().system.rho * spec["system"].normal_form().system.q
    assert abs(cert.classification.rho_q - 0.54) > 1e-3  # the two differ on this plant
    files = write_report(cert, tmp_path / "out")
    text = " ".join(Path(files.markdown).read_text().split())
    assert f"Here rho q = {cert.classification.rho_q:.6g} is the normal form's (the plant's rho q = 0.54" in text
    assert f"{rho_q:.6g}" == f"{cert.classification.rho_q:.6g}"
    assert "K is read in the normal form's coordinates." in text


def test_a_root_map_wider_than_the_certified_region_says_its_rectangle():
    """Delayed chains in Re s > 0 (c_D > 0 at delta_max) widen the maps beyond the certified region of the
    tables, whose counts then differ from the maps' own: the caption gives both rectangles."""
    plant = GeneralHyperbolic2x2(lam=1.0, mu=2.0, a=0.3, b=0.5, c=0.4, d=-0.2, q=0.9, rho=0.6, length=2.0)
    cert = certify(plant, StateFeedback(-0.8), delta_max=0.5, k_region=False)
    assert cert.principal_delayed.spectral_bound > 0.0
    caption, fig = certificate_figures(cert)[0]
    _, nominal, _ = fig.axes
    re_lo, re_hi = nominal.get_xlim()
    im_lo, im_hi = nominal.get_ylim()
    assert im_hi > 2.0 * cert.region[3]  # wider than the certified region
    said = re.search(r"The maps' rectangle, Re s in \[(\S+), (\S+)\], Im s in \[(\S+), (\S+)\], is wider", caption)
    assert said is not None, caption
    # 4 significant digits of the rectangle drawn (the map's limits are the rectangle's)
    np.testing.assert_allclose([float(v) for v in said.groups()], [re_lo, re_hi, im_lo, im_hi], rtol=5e-4)
    region = re.search(
        r"region of the tables \(the certificate's\), Re s in \[(\S+), (\S+)\], Im s in \[(\S+), (\S+)\]", caption
    )
    assert region is not None
    np.testing.assert_allclose([float(v.rstrip(",")) for v in region.groups()], cert.region, rtol=5e-4)


def test_root_counts_are_named_as_the_claims_name_them(filtered, tmp_path):
    """A float certificate's root counts are "checked in floating point" everywhere (the quantities
    table, the root maps' titles, the per-box table), as its claims are: never "certified" beside a
    claim marked checked."""
    md = write_report(filtered, tmp_path).markdown.read_text()
    for delta in ("0", "0.5"):
        row = next(line for line in md.splitlines() if line.startswith(f"| roots in the region, delta = {delta} |"))
        assert "(checked in floating point)" in row, row
    assert "certified: yes" not in md and "Certified root counts" not in md
    assert "Root counts per box (argument principle with a step control, checked in floating point):" in md


def test_proven_abscissa_claim_states_its_bracket(tmp_path):
    """The proven abscissa claim gives the bracket that holds the value (ln(rho q - K q)/tau for
    U_BS2(K) at delta = 0, closed form), so that its bound, the bracket's right end, is seen to be
    looser than the value beside it for a reason."""
    import mpmath

    cert = certify(SYSTEM, ReflectionController(0.1), delta_max=0.1, k_region=False, rigorous=True)
    claim = next(c for c in cert.claims if c.name == "spectral abscissa")
    match = re.search(r"lies in \[(\S+), (\S+)\]: no zero with Re s > (\S+)$", claim.statement)
    assert match, claim.statement
    lo, hi, bound = (float(g) for g in match.groups())
    exact = float(mpmath.log(mpmath.mpf("0.85") - mpmath.mpf("0.1")) / 2)
    assert lo <= exact <= hi and hi == bound and hi - lo < 1e-6
    md = write_report(cert, tmp_path).markdown.read_text()
    assert claim.statement in md


def test_a_sampled_coefficient_is_reported_by_its_samples_and_the_splines_undershoot_apart():
    """Samples 1, 1, 0.1, 0.1, 1 of ``a``: the plant line gives the samples' range [0.1, 1]; the
    cubic spline through them dips below 0 between the two low samples (not-a-knot, checked here
    with scipy's own spline), which the line names as the model's range, not as data."""
    from scipy.interpolate import make_interp_spline

    from nrobust.reports.report import _plant_blocks

    x, v = [0.0, 0.25, 0.5, 0.75, 1.0], [1.0, 1.0, 0.1, 0.1, 1.0]
    spline_min = float(make_interp_spline(x, v, k=3)(np.linspace(0, 1, 100001)).min())
    assert spline_min < -0.04
    plant = GeneralHyperbolic2x2(lam=1.0, mu=1.0, a=(x, v), b=0.0, c=0.0, d=0.0, q=1.0, rho=0.5)
    cert = SimpleNamespace(system=plant, given_system=None, controller=StateFeedback(-0.5), given_controller=None)
    line = _plant_blocks(cert)[0].text
    match = re.search(
        r"a = 5 samples in \[0\.1, 1\] \(the cubic spline through them, the model analysed, ranges over "
        r"\[(\S+), (\S+)\]\)",
        line,
    )
    assert match, line
    # six digits, each true: the dense grid's minimum (step 1e-5) is within 1e-9 of the spline's
    spline_max = float(make_interp_spline(x, v, k=3)(np.linspace(0, 1, 100001)).max())
    assert match.groups() == (f"{spline_min:.6g}", f"{spline_max:.6g}")
