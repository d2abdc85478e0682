"""``nrobust analyze``: certify the loop of a SYSTEM.toml file and write its report."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from .._progress import progress_bar
from .._validate import positive
from ..config import NPLUSM_TYPE, PiecewiseLinear, build_in_section, load_system_file
from ..errors import ParameterError
from ..hyperbolic.simulate import Simulation, simulate
from ..plots.simulation import simulation_figure
from .certificate import certify
from .nplusm import run_nplusm_analyze
from .outputs import RunOutputs, check_output_dir
from .report import ReportFiles, write_report

__all__ = ["run_analyze"]


def _initial(value: float | PiecewiseLinear) -> Callable[[np.ndarray], np.ndarray]:
    if isinstance(value, PiecewiseLinear):
        return value
    c = float(value)
    return lambda x: np.full(np.shape(x), c)


def run_analyze(
    path: str | Path,
    out_dir: str | Path,
    progress: bool | None = None,
    *,
    accuracy: float | None = None,
    rigorous: bool | None = None,
) -> tuple[ReportFiles, str]:
    """``nrobust analyze``: certify the loop of a SYSTEM.toml file and write its report.

    ``accuracy`` and ``rigorous`` (``--accuracy A``, ``--rigorous`` on the command line)
    override ``[analysis] accuracy`` and ``rigorous`` of the file: the delay margin's target
    accuracy (:func:`~nrobust.reports.certificate.certify` refines the kernel grid until it is
    met and the report says what was achieved) and proofs in ball arithmetic.

    The input file is validated and ``out_dir`` checked (created, writable) before any
    computation; the report's files are written as one set with ``manifest.json``
    (:class:`~nrobust.reports.outputs.RunOutputs`): a failed or interrupted run leaves ``out_dir``
    as it was. Returns the :class:`~nrobust.reports.report.ReportFiles` and the certificate's verdict. A progress
    bar is drawn on stderr when ``progress`` is True, or for None when stderr is a terminal
    or Jupyter.
    """
    if accuracy is not None:
        accuracy = positive("accuracy", accuracy)
    check_output_dir(out_dir)  # before the plant is built (a steady profile, a front end's ODE)
    spec = load_system_file(path)
    if spec.get("kind") == NPLUSM_TYPE:  # an n + m plant: the cancellation study
        if accuracy is not None:
            raise ParameterError("accuracy", "left out for an n + m plant (its cancellation study has none)", accuracy)
        return run_nplusm_analyze(spec, out_dir, progress, rigorous=bool(rigorous))
    sim = spec["simulation"]
    outputs = RunOutputs(out_dir, "analyze")  # checked before anything is computed
    # one BLAS thread: the small eigenvalue problems (the chains of a difference operator) run tens of
    # times slower when BLAS threads compete for the cores
    bar = progress_bar(2 + (0 if sim is None else len(sim["delays"])), progress, "analyze")
    with threadpool_limits(1), outputs, bar:
        cert = certify(
            spec["system"],
            spec["controller"],
            spec["delta_max"],
            spec["region"],
            spec["k_region"],
            rigorous=spec["rigorous"] if rigorous is None else rigorous,
            accuracy=spec.get("accuracy") if accuracy is None else accuracy,
        )
        if spec["given_system"] is not spec["system"]:  # the report speaks of the plant as written
            cert = dataclasses.replace(
                cert, given_system=spec["given_system"], given_controller=spec["given_controller"]
            )
        bar.update(1)
        figures = []
        if sim is not None:
            runs: list[Simulation] = []
            for d in sim["delays"]:

                def run(delta: float = d) -> Simulation:
                    u0, v0 = _initial(sim["u0"]), _initial(sim["v0"])
                    return simulate(spec["system"], spec["controller"], delta, sim["t_end"], u0, v0, sim["cells"])

                runs.append(build_in_section("simulation", run))
                bar.update(1)
            figures.append(
                (
                    "L2 norm of the simulated closed loop",
                    simulation_figure(runs, [f"delta = {d:g}" for d in sim["delays"]], "Simulation of the PDE"),
                )
            )
        files = outputs.final(write_report(cert, outputs.staging, figures=figures, intro=_physical(spec)))
        outputs.commit()
        bar.update(1)
    return files, cert.verdict


def _physical(spec: dict[str, Any]) -> list[str]:
    """The report's opening line for a physical front end: its parameters as the file gives them."""
    if spec.get("physical") is None:
        return []
    kind, params = spec["physical"]
    given = ", ".join(f"{k} = {v:g}" if isinstance(v, float) else f"{k} = {v}" for k, v in params.items())
    return [
        f"**Given as** {kind} with {given} (the file's [system] table); analysed as the general 2x2 plant "
        "below, its linearisation about the steady state, in characteristic coordinates."
    ]
