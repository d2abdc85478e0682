"""Every module path of the former flat layout still works: the public names of docs/api.md.

The layout in packages (``docs/architecture.md``) moved modules. A former path is a deprecated
alias (``nrobust/_moved.py``): importing it warns once, naming the new home, and every public
name the module had is the object of its new home. A path that became a package
(``nrobust.margins``, ``nrobust.hyperbolic.kernels``, ...) re-exports its former names without
a warning. The names below are the ``__all__`` of each module before the layout, written out
so that the check cannot drift with the code. The imports run in a child interpreter: an
alias bound to its package would stay there for the other tests of the process.
"""

from __future__ import annotations

import json
import subprocess
import sys

import nrobust._moved

#: ``__all__`` of every module whose path moved, before the layout.
MOVED_MODULES = {
    "nrobust.crossings": [
        "AxisGap",
        "AxisJet",
        "Crossing",
        "CrossingSearch",
        "crossing_frequencies",
        "frequency_bound",
    ],
    "nrobust.proven_crossings": ["ProvenCrossings", "proven_crossings", "proven_gap", "proven_zero_root"],
    "nrobust.matrix_crossings": ["GaugeRemainder", "circle_crossings", "compound_generator", "compound_minors"],
    "nrobust.transfer": ["QuasiTransferFunction", "pade_approximation", "to_frd", "open_loop_tf", "closed_loop_tf"],
    "nrobust.statespace": ["StateSpaceTDS"],
    "nrobust.hyperbolic.system": ["Coupling", "Hyperbolic2x2", "TransportSystem"],
    "nrobust.hyperbolic.general": ["Coefficient", "GeneralHyperbolic2x2", "NormalForm", "as_general"],
    "nrobust.hyperbolic.frontends": ["ARZ", "GRAVITY", "SaintVenant", "arz", "from_riemann", "saint_venant"],
    "nrobust.hyperbolic.varying_kernels": ["VaryingKernels", "solve_varying_kernels"],
    "nrobust.hyperbolic.nplusm_kernels": [
        "MAX_NPLUSM_KERNEL_GRID",
        "NPlusMBackstepping",
        "NPlusMKernels",
        "backstepping_delay_margin",
        "solve_nplusm_kernels",
    ],
    "nrobust.hyperbolic.controllers": [
        "Classification",
        "Controller",
        "FeedbackLaw",
        "FilteredController",
        "FiniteTimeController",
        "OpenLoop",
        "ReflectionController",
        "StateFeedback",
        "characteristic",
        "classify",
        "loop_factors",
        "normalize",
    ],
    "nrobust.hyperbolic.feedback": ["FeedbackLaw", "feedback_factor", "laplace_loop_factors"],
    "nrobust.hyperbolic.delay_form": ["DelayForm", "delay_form"],
    "nrobust.hyperbolic.varying": ["DEFAULT_CHARACTERISTIC_GRID", "VaryingDelayForm", "varying_delay_form"],
    "nrobust.hyperbolic.laplace": ["boundary_function", "general_solution", "magnus_steps"],
    "nrobust.hyperbolic.studies": [
        "DEFAULT_N_GAINS",
        "END_KINDS",
        "ABRegion",
        "GainEnd",
        "KRegion",
        "StabilityChart",
        "Tradeoff",
        "ab_region",
        "delay_margin",
        "k_region",
        "margin_and_decay",
        "stability_chart",
        "tradeoff",
    ],
    "nrobust.hyperbolic.robustness": ["rouche_delay_bound"],
    "nrobust.hyperbolic.simulate_general": ["GeneralSimulation", "simulate_general"],
    "nrobust.parallel": [
        "MAX_POINTS",
        "Grid",
        "PointFailure",
        "SweepInterrupted",
        "SweepMap",
        "SweepResult",
        "grid",
        "sweep",
        "sweep_map",
    ],
    "nrobust.montecarlo": ["RobustnessResult", "robustness"],
    "nrobust.sweepfile": ["ANALYSES", "JOURNAL", "SweepFileResult", "run_sweep_file"],
    "nrobust.sweep": [
        "ANALYSES",
        "Grid",
        "PointFailure",
        "RobustnessResult",
        "SweepFileResult",
        "SweepInterrupted",
        "SweepMap",
        "SweepResult",
        "grid",
        "margin_and_decay",
        "robustness",
        "run_sweep_file",
        "sweep",
        "sweep_map",
    ],
    "nrobust.certificate": ["CHECKED", "PROVEN", "Certificate", "Claim", "ModelError", "PrincipalPart", "certify"],
    "nrobust.report": ["ReportFiles", "write_report", "certificate_figures"],
    "nrobust.outputs": ["MANIFEST", "Manifest", "RunOutputs", "atomic_write", "check_output_dir", "read_manifest"],
    "nrobust.paper": [
        "PAPER_DELAYS_FIG1",
        "PAPER_DELAYS_FIG3",
        "PAPER_K",
        "PAPER_SYSTEM",
        "PAPER_T_END",
        "paper_figure",
        "run_paper",
    ],
    "nrobust.analyze": ["run_analyze"],
    "nrobust.nplusm_report": ["run_nplusm_analyze"],
}

#: ``__all__`` of every module whose path is now a package of the same name.
PACKAGES = {
    "nrobust.margins": ["DelayMargin", "delay_margin"],
    "nrobust.hyperbolic.kernels": ["DEFAULT_KERNEL_GRID", "MAX_KERNEL_GRID", "Kernels", "solve_kernels"],
    "nrobust.hyperbolic.loops": ["closed_loop_tf", "open_loop_tf", "output_map"],
    "nrobust.hyperbolic.nplusm": [
        "CancellationCase",
        "NPlusMCharacteristic",
        "NPlusMMargin",
        "NPlusMSystem",
        "cancellation_study",
        "compound_characteristic",
        "multi_actuator_delay_margin",
        "multi_actuator_margin",
        "nplusm_delay_margin",
    ],
    "nrobust.hyperbolic.simulate": ["DEFAULT_CELLS", "Simulation", "simulate", "v_nodes"],
    "nrobust.plots": [
        "NrobustPlot",
        "NyquistResponse",
        "nyquist_response",
        "nyquist_plot",
        "root_map_region",
        "root_map_plot",
        "HiddenUnstableRoots",
        "hidden_unstable_roots",
        "RootLocusData",
        "root_locus_response",
        "root_locus_plot",
        "residual_floor",
        "simulation_plot",
        "stability_chart_plot",
        "tradeoff_plot",
        "sweep_chart",
        "simulation_figure",
    ],
}

_CHILD = """
import importlib, json, sys, warnings
moved, packages = json.loads(sys.argv[1]), json.loads(sys.argv[2])
from nrobust._moved import MOVED
out = {}
for old, names in moved.items():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        module = importlib.import_module(old)
    homes = [importlib.import_module(h) for h in MOVED[old]]
    same = [n for n in names if any(getattr(h, n, None) is getattr(module, n) for h in homes)]
    warned = [str(w.message) for w in caught if issubclass(w.category, DeprecationWarning)]
    out[old] = {"missing": sorted(set(names) - set(same)), "warned": warned}
for package, names in packages.items():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        module = importlib.import_module(package)
        out[package] = {"missing": [n for n in names if not hasattr(module, n)], "warned": []}
import nrobust
out["nrobust.sweep callable"] = {"missing": [] if callable(nrobust.sweep) else ["sweep"], "warned": []}
print(json.dumps(out))
"""


def _in_child() -> dict[str, dict[str, list[str]]]:
    run = subprocess.run(
        [sys.executable, "-c", _CHILD, json.dumps(MOVED_MODULES), json.dumps(PACKAGES)],
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    return json.loads(run.stdout)


def test_former_module_paths_are_deprecated_aliases_of_their_new_homes() -> None:
    assert set(MOVED_MODULES) == set(nrobust._moved.MOVED)
    found = _in_child()
    for old in MOVED_MODULES:
        assert found[old]["missing"] == [], (old, found[old])
        assert len(found[old]["warned"]) == 1 and "deprecated alias" in found[old]["warned"][0], (old, found[old])
        assert nrobust._moved.MOVED[old][0] in found[old]["warned"][0]
    for package in PACKAGES:
        assert found[package]["missing"] == [], (package, found[package])
    # importing the former namespace module nrobust.sweep leaves nrobust.sweep the function
    assert found["nrobust.sweep callable"]["missing"] == []
