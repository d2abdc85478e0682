"""The command line: end to end on small files, and errors that name the key."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from nrobust.cli import PiecewiseLinear, load_system_file, main
from nrobust.errors import ParameterError

SMALL = """
[system]
type = "TransportSystem"
lam = 1.0
mu = 1.0
q = 1.0
rho = 0.85

[controller]
type = "FilteredController"
a = 0.1
b = 1.0

[analysis]
delta_max = 0.1

[simulation]
delays = [0.0, 0.1]
t_end = 3.0
cells = 20
"""


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "SYSTEM.toml"
    path.write_text(text)
    return path


def test_analyze_writes_report_and_valid_json(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["analyze", str(_write(tmp_path, SMALL)), "-o", str(out), "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "report.md" in printed and "FilteredController: delay-robust" in printed
    data = json.loads((out / "certificate.json").read_text())
    assert data["controller"] == {"controller": "FilteredController", "a": 0.1, "b": 1.0}
    assert data["delay_robust"] is True and data["delay_margin"] > 0.1
    md = (out / "report.md").read_text()
    assert "L2 norm of the simulated closed loop" in md
    assert len(list((out / "figures").glob("*.png"))) == 3
    assert "data:image/png;base64," in (out / "report.html").read_text()


@pytest.mark.parametrize(
    "edit,key",
    [
        (("rho = 0.85", "rhoo = 0.85"), "system.rhoo"),
        (("rho = 0.85", 'rho = "high"'), "system.rho"),
        (('type = "FilteredController"', 'type = "Magic"'), "controller.type"),
        (("a = 0.1\n", ""), "controller.a"),
        (("b = 1.0", "b = -1.0"), "controller.b"),
        (("delta_max = 0.1", "delta_max = -0.1"), "analysis.delta_max"),
        (("delta_max = 0.1", "delta_max = 0.1\nregion = [1, 0, -1, 1]"), "analysis.region"),
        (("cells = 20", "cells = 2.5"), "simulation.cells"),
        (("[simulation]", "[simulations]"), "simulations"),
        (("q = 1.0", "q = 0.0"), "system.q"),
    ],
)
def test_bad_file_names_the_key(tmp_path, capsys, edit, key):
    path = _write(tmp_path, SMALL.replace(*edit))
    assert main(["analyze", str(path), "-o", str(tmp_path / "out"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"nrobust: error: {key} ") and "\n" not in err
    assert "Traceback" not in err


def test_invalid_toml_and_missing_file(tmp_path, capsys):
    path = _write(tmp_path, "[system\n")
    assert main(["analyze", str(path), "-o", str(tmp_path / "o")]) == 2
    assert "valid TOML" in capsys.readouterr().err
    assert main(["analyze", str(tmp_path / "nope.toml"), "-o", str(tmp_path / "o")]) == 2
    assert "existing TOML file" in capsys.readouterr().err


def test_varying_coupling_table(tmp_path):
    text = SMALL.replace('type = "TransportSystem"', 'type = "Hyperbolic2x2"').replace(
        "q = 1.0", "q = 1.0\nsigma_pm = {x = [0.0, 0.5, 1.0], values = [1.0, 2.0, 1.0]}\nsigma_mp = 0.5"
    )
    spec = load_system_file(_write(tmp_path, text))
    sys_ = spec["system"]
    assert isinstance(sys_.sigma_pm, PiecewiseLinear)
    np.testing.assert_allclose(sys_.sigma_pm_at([0.0, 0.25, 0.5]), [1.0, 1.5, 2.0], rtol=1e-15, atol=0)
    bad = text.replace("x = [0.0, 0.5, 1.0]", "x = [0.0, 0.7, 0.5]")
    with pytest.raises(ParameterError, match=r"system\.sigma_pm\.x"):
        load_system_file(_write(tmp_path, bad))


def test_sweep_subcommand_calls_the_file_runner(tmp_path, capsys):
    (tmp_path / "SWEEP.toml").write_text(
        'analysis = "delay_margin"\nexecutor = "serial"\n[system]\ntype = "TransportSystem"\nlam = 1.0\nmu = 1.0\n'
        'q = 1.0\n[controller]\ntype = "ReflectionController"\n[grid]\nK = [0.1, 0.8]\nrho = [0.5]\n'
    )
    out = tmp_path / "out"
    assert main(["sweep", str(tmp_path / "SWEEP.toml"), "-o", str(out), "--no-progress"]) == 0
    assert "2 points, 0 failed" in capsys.readouterr().out
    assert json.loads((out / "sweep.json").read_text())["n_points"] == 2
    rows = (out / "sweep.csv").read_text().splitlines()
    header = rows[0].split(",")
    margins = [row.split(",")[header.index("delta_star")] for row in rows[1:]]
    # |K q| < 1 - |rho q|: every delay is tolerated (eq. (boun_K2)); |rho q| + |K q| > 1:
    # the difference operator is not strongly stable, zero margin
    assert margins[0] == "inf" and float(margins[1]) == 0.0
    bad = tmp_path / "BAD.toml"
    bad.write_text((tmp_path / "SWEEP.toml").read_text().replace("[grid]", "[grid]\nspeed = [1]"))
    assert main(["sweep", str(bad), "-o", str(out), "--no-progress"]) == 2
    assert "grid.speed" in capsys.readouterr().err


def test_python_dash_m(tmp_path):
    path = _write(tmp_path, SMALL.replace("rho = 0.85", "rho = 0.85\nspeed = 2"))
    env = {**os.environ, "MPLBACKEND": "Agg"}
    run = subprocess.run(
        [sys.executable, "-m", "nrobust", "analyze", str(path), "-o", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert run.returncode == 2
    assert run.stderr.strip().splitlines()[-1].startswith("nrobust: error: system.speed ")
    help_run = subprocess.run(
        [sys.executable, "-m", "nrobust", "--help"], capture_output=True, text=True, env=env, timeout=120
    )
    assert help_run.returncode == 0 and "analyze" in help_run.stdout and "paper" in help_run.stdout


def test_paper_end_to_end_small(tmp_path):
    """The paper's pipeline on a coarse chart and short simulations, on two workers."""
    from nrobust.cli import run_paper

    summary = run_paper(tmp_path, progress=False, workers=2, t_end=2.0, cells=20, n_K=5, n_delta=4)
    data = json.loads((tmp_path / "summary.json").read_text())
    assert data["classification"]["regime"] == "no_robust_finite_time"
    assert data["U_BS"]["delay_margin"] == 0.0 and data["U_BS"]["gamma_0_delayed"] == pytest.approx(
        1.7, rel=1e-13, abs=1e-14
    )
    bs2 = data["U_BS2(K=0.1)"]
    assert 0.2 < bs2["delay_margin"] < 0.25 and bs2["spectral_abscissa"] < 0
    assert summary["files"]["html"].endswith("report.html")
    page = (tmp_path / "report.html").read_text()
    assert page.count("data:image/png;base64,") == 9  # 2 x (root maps, Nyquist) + 5 further figures
    assert len(list((tmp_path / "figures").glob("*.png"))) == 9
