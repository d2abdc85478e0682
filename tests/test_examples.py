"""Every example runs to completion and writes what it promises."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

# script -> files it must write into the output directory given as its argument
CASES = {
    "filtered_controller.py": ["filtered_ab_region.png", "filtered_simulation.png"],
    "ode_pde.py": ["ode_pde.png"],
    "paper_figures.py": [],
    "transport_tutorial.py": ["transport_root_maps.png", "transport_nyquist.png", "transport_locus_delta.png"],
    "varying_couplings.py": ["varying_chart.png"],
    "transport_loop.py": [],
    "drift_flux.py": [],
}


@pytest.mark.slow
@pytest.mark.parametrize("script", sorted(CASES))
def test_example_runs(script: str, tmp_path: Path) -> None:
    env = {**os.environ, "MPLBACKEND": "Agg", "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / script), str(tmp_path)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    for name in CASES[script]:
        assert (tmp_path / name).stat().st_size > 1000, name
    if script == "paper_figures.py":
        assert len(list(tmp_path.glob("*.png"))) == 2
    if script == "transport_loop.py":
        # The certified count of the reference function 1 - 0.85 e^{-2s} + 0.1 e^{-2.1s} on [-3, 1] x [-0.5, 200].
        assert "certified count in (-3.0, 1.0, -0.5, 200.0): 64 (certified: True)" in done.stdout
