"""``nrobust design`` reads the plant and ``[design]`` only: ``[controller]`` and ``[analysis]`` may be left out.

Oracle: the same command on the same plant with the sections present (the design cannot depend on
sections it does not read), and the decay rate of U_BS2(K) at ``delta = 0``, ``-ln|(rho - K) q| / tau``
(Lemma 3), on the designed gain.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from nrobust.cli import main
from nrobust.config import load_system_file
from nrobust.errors import ParameterError

PLANT = """
[system]
type = "Hyperbolic2x2"
lam = 1.0
mu = 1.0
sigma_pm = 1.0
sigma_mp = 1.0
q = 1.0
rho = 0.85
"""
DESIGN = """
[design]
objective = "decay_rate"
margin_at_least = 0.15
"""
SECTIONS = """
[controller]
type = "ReflectionController"
K = 0.1

[analysis]
delta_max = 0.1
"""
NPLUSM = """
[system]
type = "NPlusMSystem"
lam = [1.0]
mu = [1.0]
sigma = [[0.0, 1.5], [0.5, 0.0]]
q = [[0.8]]
r = [[0.4]]

[design]
objective = "margin"
delays = [0.5, 1.2]
"""


def _design(tmp_path: Path, name: str, text: str) -> dict:
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    assert main(["design", str(path), "-o", str(tmp_path / name)]) == 0
    data = json.loads((tmp_path / name / "design.json").read_text())
    data.pop("file")
    return data


def test_a_plant_and_a_design_table_suffice(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The file without [controller] and [analysis] designs what the file with them designs; analyze refuses it."""
    bare = _design(tmp_path, "bare", PLANT + DESIGN)
    full = _design(tmp_path, "full", PLANT + SECTIONS + DESIGN)
    assert bare == full
    K = bare["design"]["K"]
    assert bare["design"]["margin"] >= 0.15
    # Lemma 3 at the designed gain: tau = 1/lam + 1/mu = 2; the design's rate to 1e-9 (its bracket is ~1e-11)
    assert abs(bare["design"]["decay_rate"] + math.log((0.85 - K) * 1.0) / 2.0) < 1e-9
    path = tmp_path / "bare.toml"
    assert main(["analyze", str(path), "-o", str(tmp_path / "analyzed")]) == 2
    assert "controller must be a [controller] table" in capsys.readouterr().err


def test_the_design_reader_defaults_and_checks(tmp_path: Path) -> None:
    """Left out: controller None, delta_max None, the analysis defaults; given: checked as for analyze."""
    path = tmp_path / "s.toml"
    path.write_text(PLANT + DESIGN)
    spec = load_system_file(path, for_design=True)
    assert spec["controller"] is None and spec["given_controller"] is None and spec["delta_max"] is None
    assert (spec["region"], spec["k_region"], spec["rigorous"], spec["accuracy"]) == (None, True, False, None)
    path.write_text(PLANT + SECTIONS.split("[analysis]")[0] + DESIGN)
    with pytest.raises(ParameterError, match=r"analysis must be a \[analysis\] table"):
        load_system_file(path)  # nrobust analyze needs it
    assert load_system_file(path, for_design=True)["controller"].K == 0.1
    path.write_text(PLANT + DESIGN + "\n[analysis]\nk_region = true\n")  # delta_max: not read by the design
    assert load_system_file(path, for_design=True)["delta_max"] is None
    path.write_text(PLANT + DESIGN + "\n[analysis]\ndelta_max = -0.1\n")
    with pytest.raises(ParameterError, match=r"analysis\.delta_max must be > 0"):
        load_system_file(path, for_design=True)
    path.write_text(PLANT + DESIGN + '\n[controller]\ntype = "ReflectionController"\n')
    with pytest.raises(ParameterError, match=r"controller\.K"):
        load_system_file(path, for_design=True)


def test_an_nplusm_design_file_without_controller_and_analysis(tmp_path: Path) -> None:
    path = tmp_path / "n.toml"
    path.write_text(NPLUSM)
    spec = load_system_file(path, for_design=True)
    assert spec["cancellations"] is None and spec["region"] is None and spec["design"]["delays"] is not None
    with pytest.raises(ParameterError, match="controller"):
        load_system_file(path)
