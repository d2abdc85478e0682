"""``nrobust analyze``: certify the loop of a SYSTEM.toml file and write its report."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
from tqdm import tqdm

from .certificate import certify
from .config import PiecewiseLinear, _wrap, load_system_file
from .hyperbolic.simulate import Simulation, simulate
from .plots import simulation_figure
from .report import ReportFiles, write_report

__all__ = ["run_analyze"]


def _initial(value: float | PiecewiseLinear) -> Callable[[np.ndarray], np.ndarray]:
    if isinstance(value, PiecewiseLinear):
        return value
    c = float(value)
    return lambda x: np.full(np.shape(x), c)


def _progress(total: int, enabled: bool, desc: str) -> tqdm:
    return tqdm(total=total, desc=desc, disable=not enabled, leave=False, file=sys.stderr)


def run_analyze(path: str | Path, out_dir: str | Path, progress: bool = True) -> tuple[ReportFiles, str]:
    """``nrobust analyze``: certify the loop of a SYSTEM.toml file and write its report.

    Returns the :class:`~nrobust.report.ReportFiles` and the certificate's verdict.
    """
    spec = load_system_file(path)
    sim = spec["simulation"]
    with _progress(2 + (0 if sim is None else len(sim["delays"])), progress, "analyze") as bar:
        cert = certify(spec["system"], spec["controller"], spec["delta_max"], spec["region"], spec["k_region"])
        bar.update(1)
        figures = []
        if sim is not None:
            runs: list[Simulation] = []
            for d in sim["delays"]:

                def run(delta: float = d) -> Simulation:
                    u0, v0 = _initial(sim["u0"]), _initial(sim["v0"])
                    return simulate(spec["system"], spec["controller"], delta, sim["t_end"], u0, v0, sim["cells"])

                runs.append(_wrap("simulation", run))
                bar.update(1)
            figures.append(
                (
                    "L2 norm of the simulated closed loop",
                    simulation_figure(runs, [f"delta = {d:g}" for d in sim["delays"]], "Simulation of the PDE"),
                )
            )
        files = write_report(cert, out_dir, figures=figures)
        bar.update(1)
    return files, cert.verdict
