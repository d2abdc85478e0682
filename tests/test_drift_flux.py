"""The drift-flux example (2 + 1) from its TOML file through `nrobust analyze`: which cancellation is robust."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from nrobust import ParameterError, spectral_abscissa
from nrobust.config import load_system_file
from nrobust.hyperbolic.nplusm import NPlusMCharacteristic, nplusm_delay_margin
from nrobust.reports.analyze import run_analyze
from nrobust.roots import count_roots

TOML = Path(__file__).resolve().parents[1] / "examples" / "drift_flux.toml"


def test_file_reads_the_plant() -> None:
    spec = load_system_file(TOML)
    assert spec["kind"] == "NPlusMSystem" and spec["system"].n == 2 and spec["system"].m == 1
    assert len(spec["cancellations"]) == 5


@pytest.mark.slow
def test_analyze_full_cancellation_is_not_delay_robust(tmp_path: Path) -> None:
    files, verdict = run_analyze(TOML, tmp_path, progress=False)
    cases = {tuple(c["fractions"]): c for c in json.loads(files.json[0].read_text())["cases"]}
    none, full = cases[(0.0, 0.0)], cases[(1.0, 1.0)]
    # full cancellation doubles gamma_0 of the delayed principal part (paper, Section 5)
    np.testing.assert_allclose(full["gamma_0"], 2 * none["gamma_0"], rtol=1e-12)
    assert full["gamma_0"] > 1 and full["margin"]["margin"] == 0 and not full["robust"]
    # cancelling the pressure wave's reflection alone is not robust either; the void wave's is
    assert not cases[(1.0, 0.0)]["robust"] and cases[(0.0, 1.0)]["robust"]
    assert "(0, 1)" in verdict and "(1, 1)" not in verdict
    assert files.markdown.read_text().count("|") > 30 and files.html.exists()
    # the answer first: a panel under the title (the verdict, the plant, the largest margin with its
    # accuracy, what is proven), in the words of the 2 x 2 reports: nothing "certified" on the float path
    md = files.markdown.read_text().splitlines()
    assert md[2] == "> **Delay-robust cancellations: (0, 0); (0, 1); (0.5, 0.5)**"
    panel = "\n".join(md[2 : next(k for k in range(2, len(md)) if not md[k].startswith(">"))])
    assert "**Largest delay margin:** cancelled fractions (0, 0): delta* = infinity (stable for every delay)" in panel
    assert "**Proven:** nothing in ball arithmetic" in panel and "checked in floating point" in panel
    assert "certified" not in files.markdown.read_text() and "<blockquote>" in files.html.read_text()


@pytest.mark.slow
def test_analyze_figure_after_the_panel(tmp_path: Path) -> None:
    """One picture after the panel: the delay-free roots of the case with the largest margin, checked in balls."""
    files, _ = run_analyze(TOML, tmp_path, progress=False)
    (png,) = files.figures
    assert png == tmp_path / "figures" / "roots_delay_free.png" and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = files.markdown.read_text().splitlines()
    end = next(k for k in range(2, len(md)) if not md[k].startswith(">"))  # the panel's end
    assert md[end] == "" and md[end + 1].startswith("![") and md[end + 1].endswith("](figures/roots_delay_free.png)")
    assert md[end + 3].startswith("*Roots of the delay-free loop (delta = 0) for cancelled fractions (0, 0)")
    assert "checked in floating point" in md[end + 3] and "certified" not in md[end + 3]
    page = files.html.read_text()
    assert page.index("</blockquote><figure>") < page.index("<table>") and "data:image/png;base64," in page
    figure = json.loads(files.json[0].read_text())["figure"]
    roots = np.array([complex(re, im) for re, im in figure["roots"]])
    # independent oracle: the count and the abscissa proven in ball arithmetic (FLINT), no float root search;
    # the proven root box has radius 2e-11 and the float abscissa an accuracy of 1e-13: 1e-9 is room for both
    F = NPlusMCharacteristic(load_system_file(TOML)["system"], [[0.0, 0.0]], 0.0)
    region = tuple(figure["region"])
    assert figure["count"] == roots.size == int(count_roots(F, region, rigorous=True)) == 2
    proven = spectral_abscissa(F, region, rigorous=True)
    assert proven.rigorous and np.all(roots.real <= proven.value + 1e-9)
    assert abs(roots.real.max() - proven.value) <= 1e-9 and figure["unstable"] == 0


@pytest.mark.slow
def test_analyze_figure_without_a_robust_case(tmp_path: Path) -> None:
    """No delay-robust case: the first listed is drawn (full cancellation: no root, finite-time convergence)."""
    toml = tmp_path / "full.toml"
    listed = "[[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0], [0.5, 0.5]]"
    toml.write_text(TOML.read_text().replace(listed, "[[1.0, 1.0]]"))
    files, verdict = run_analyze(toml, tmp_path / "out", progress=False)
    assert verdict == "no listed cancellation keeps a positive delay margin" and files.figures[0].exists()
    figure = json.loads(files.json[0].read_text())["figure"]
    assert "for cancelled fractions (1, 1), the first case listed, delta* = 0" in figure["caption"]
    F = NPlusMCharacteristic(load_system_file(toml)["system"], [[-0.6, -0.4]], 0.0)
    assert figure["count"] == len(figure["roots"]) == int(count_roots(F, tuple(figure["region"]), rigorous=True)) == 0


@pytest.mark.slow
def test_margin_of_the_void_wave_cancellation() -> None:
    """Certified abscissae on both sides of the margin (independent of the frequency search)."""
    system = load_system_file(TOML)["system"]
    K = [[0.0, -0.4]]
    m = nplusm_delay_margin(system, K)
    band = (-0.5, 0.5, -0.25, 3.0)
    below = spectral_abscissa(NPlusMCharacteristic(system, K, 0.95 * m.margin), band)
    above = spectral_abscissa(NPlusMCharacteristic(system, K, 1.05 * m.margin), band)
    assert below.certified and above.certified and below.value < 0 < above.value


@pytest.mark.parametrize("fractions", [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)])
def test_gamma_0_closed_form(fractions: tuple[float, float]) -> None:
    """gamma_0 = sum_a (1 + c_a) |R_a U_a Q_a| / |V| (scalar groups) inside the certified torus bracket.

    The criterion behind the example's conclusion, valid for any parameters: cancelling
    reflection a alone is strongly stable iff gamma_0(open loop) + g_a < 1.
    """
    system = load_system_file(TOML)["system"]
    sig, lam, mu = system.sigma, system.lam, system.mu
    g = np.array([abs(system.r[0, a] * np.exp(sig[a, a] / lam[a]) * system.q[a, 0]) for a in range(2)])
    g /= np.exp(-sig[2, 2] / mu[0])
    closed = float(np.sum((1.0 + np.array(fractions)) * g))
    K = [[-c * r for c, r in zip(fractions, system.r[0])]]
    bracket = system.principal_operator(K, delta=0.01).gamma_0()
    assert bracket.lower - 1e-12 <= closed <= bracket.upper
    assert (closed < 1.0) == (fractions != (1.0, 0.0))  # g = (0.489, 0.110): the void wave's is the one to cancel


def test_bad_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(TOML.read_text().replace("[[0.0, 0.0], [1.0, 1.0]", "[[0.0], [1.0, 1.0]"))
    with pytest.raises(ParameterError, match=r"controller\.fractions"):
        load_system_file(bad)
    bad.write_text(TOML.read_text().replace("mu = [1.0]", "mu = [-1.0]"))
    with pytest.raises(ParameterError, match=r"system\.mu"):
        load_system_file(bad)
