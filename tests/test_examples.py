"""Every example runs to completion and writes what it promises."""

from __future__ import annotations

from pathlib import Path

import pytest
from _examples import run_example

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
    stdout = run_example(script, tmp_path)
    for name in CASES[script]:
        assert (tmp_path / name).stat().st_size > 1000, name
    if script == "paper_figures.py":
        assert len(list(tmp_path.glob("*.png"))) == 2
    if script == "transport_loop.py":
        # The certified count of the reference function 1 - 0.85 e^{-2s} + 0.1 e^{-2.1s} on [-3, 1] x [-0.5, 200].
        assert "certified count in (-3.0, 1.0, -0.5, 200.0): 64 (certified: True)" in stdout
