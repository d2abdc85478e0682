"""One JSON convention for every result, and an ``==`` that never raises.

Every ``to_dict()`` returns strict-JSON-ready data (``nrobust._json``): infinities and
NaN as the strings ``"inf"``, ``"-inf"``, ``"nan"``, complex numbers as ``[re, im]``,
arrays and tuples as lists. One instance of every result class is built from cheap
inputs and checked; a class with ``to_dict`` that this module does not build fails
:func:`test_every_class_with_to_dict_is_built_here`.
"""

from __future__ import annotations

import copy
import importlib
import inspect
import json
import math
import pkgutil
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest

import nrobust
from nrobust._json import decode_floats, fields_dict, json_safe
from nrobust.bounds import delay_bound_from_kernel, root_free_region
from nrobust.design import optimize_loop, pareto_front, window_stability
from nrobust.difference import DifferenceOperator
from nrobust.errors import ParameterError
from nrobust.hyperbolic import Hyperbolic2x2, TransportSystem
from nrobust.hyperbolic.analyses import (
    ab_region,
    design_filtered,
    design_filtered_exact,
    design_reflection,
    design_state_feedback,
    k_region,
    mismatch_region,
    speed_tolerance,
    stability_chart,
    tradeoff,
)
from nrobust.hyperbolic.kernels.constant import solve_kernels
from nrobust.hyperbolic.kernels.varying import solve_varying_kernels
from nrobust.hyperbolic.loops.controllers import (
    CollocatedOutputFeedback,
    FilteredController,
    OutputFeedback,
    ReflectionController,
    StateFeedback,
    classify,
)
from nrobust.hyperbolic.loops.delay_form import delay_form
from nrobust.hyperbolic.loops.varying_form import varying_delay_form
from nrobust.hyperbolic.nplusm import (
    NPlusMSystem,
    cancellation_study,
    design_nplusm_gains,
    kernel_error_bound,
    nplusm_delay_margin,
    nplusm_speed_tolerance,
)
from nrobust.hyperbolic.nplusm.design import check_window
from nrobust.hyperbolic.nplusm.kernels import NPlusMBackstepping, solve_nplusm_kernels
from nrobust.hyperbolic.plants.frontends import arz, saint_venant
from nrobust.hyperbolic.plants.general import GeneralHyperbolic2x2
from nrobust.hyperbolic.simulate import simulate, simulate_nplusm
from nrobust.hyperbolic.simulate.general import simulate_general
from nrobust.lti.allmargin import allmargin
from nrobust.lti.delay_lti import delay, tf
from nrobust.lti.transfer import QuasiTransferFunction, pade_approximation
from nrobust.margins.count import unstable_count
from nrobust.margins.crossing import crossing_frequencies
from nrobust.margins.margin import delay_margin
from nrobust.margins.proven import proven_crossings
from nrobust.matrix_difference import MatrixDifferenceOperator
from nrobust.plots.bode import bode_response
from nrobust.plots.design import pareto_response
from nrobust.plots.nyquist import nyquist_response
from nrobust.plots.rootlocus import root_locus_response
from nrobust.plots.rootmap import hidden_unstable_roots, root_map_response
from nrobust.qpmatrix import QuasiPolynomialMatrix
from nrobust.quasipoly import DistributedDelay, QuasiPolynomial
from nrobust.reports.certificate import certify
from nrobust.reports.outputs import Manifest
from nrobust.reports.report import ReportFiles
from nrobust.roots import count_roots, find_roots, spectral_abscissa
from nrobust.sweeps.sweepfile import SweepFileResult

F = QuasiPolynomial([[1, 1], [0.5]], [0, 1])  # s + 1 + 0.5 e^{-s}
A, B = QuasiPolynomial([[1, 1]], [0]), QuasiPolynomial([[2]], [0])  # s + 1 + 2 e^{-delta s}
TRANSPORT = TransportSystem(1, 1, 0.5, 0.5)  # |rho q| = 0.25: U_BS2(0.1) tolerates every delay
COUPLED = Hyperbolic2x2(1.0, 1.0, 0.2, 0.1, 0.5, 0.5)
GENERAL = GeneralHyperbolic2x2(lambda x: 1.0 + x, lambda x: 2.0 - x, 0.2, np.cos, 0.5, -0.3, 0.9, 0.6)  # any speeds
ONE_PLUS_ONE = NPlusMSystem([1.0], [1.0], [[0.0, 0.5], [0.4, 0.0]], [[0.8]], [[0.5]])


def margin_at(b: float) -> dict[str, Any]:
    """Swept function: ``s + 1 + b e^{-delta s}`` (``b = 0.5``: infinite margin; ``b < -1``: raises)."""
    if b < -1:
        raise ValueError("unstable without delay")
    return {"delta_star": delay_margin(A, QuasiPolynomial([[b]], [0])).margin}


def margin_result(b: float) -> Any:
    """Swept function returning the DelayMargin itself (flattened through its ``to_dict``)."""
    return delay_margin(A, QuasiPolynomial([[b]], [0]))


def draw_transport(rng: np.random.Generator) -> TransportSystem:
    return TransportSystem(1.0, 1.0, 0.5, float(rng.uniform(0.4, 0.6)))


def root_family(p: float) -> QuasiPolynomial:
    return QuasiPolynomial([[p, 1], [0.5]], [0, 1])


def two_profiles(x: np.ndarray) -> np.ndarray:
    return np.vstack([np.sin(x), np.cos(x)])


def gain_loop(p: np.ndarray) -> tuple[QuasiPolynomial, QuasiPolynomial]:
    """``s + 1 + k e^{-delta s}``: a one-parameter loop family for the design results."""
    return QuasiPolynomial([[1.0, 1.0]], [0.0]), QuasiPolynomial([[float(p[0])]], [0.0])


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """One instance of every result class with ``to_dict``, keyed by a name."""
    tmp = tmp_path_factory.mktemp("json")
    margin = delay_margin(A, B)
    D = DifferenceOperator([1.0, 0.5], [0.0, 1.0])
    N = DistributedDelay([0.0, 0.5, 1.0], [1.0, 2.0 + 1.0j, 0.5])
    sweep = nrobust.sweep(margin_at, [{"b": 0.5}, {"b": 2.0}, {"b": -2.0}], "serial")
    cert = certify(TRANSPORT, ReflectionController(0.1), delta_max=0.1, k_region=False)
    proven = certify(TRANSPORT, ReflectionController(0.1), delta_max=0.1, k_region=False, rigorous=True)
    assert proven.model_error is not None
    MD = MatrixDifferenceOperator([[[0.0, 0.6], [0.0, 0.0]], [[0.0, 0.0], [0.9, 0.0]]], [1.0, 2.0])
    reflection = design_reflection(COUPLED, "margin")
    local = optimize_loop(gain_loop, [(0.0, 5.0)], margin_at_least=0.8, x0=[0.5], max_iter=5)
    mismatch = mismatch_region(TRANSPORT, ReflectionController(0.1), [0.0, 0.2], [0.0], 0.1)
    return {
        "RootFreeRegion": root_free_region(F),
        "RoucheDelayBound": delay_bound_from_kernel(None, 0.5),  # N~ = 0: delta_0 = inf
        "Crossing": margin.crossings[0],
        "Chain": D.chains().chains[0],
        "Chains": DifferenceOperator([1.0], [0.0]).chains(),  # one term: no chain, bracket -inf
        "SpectralBound": DifferenceOperator([1.0], [0.0]).spectral_bound(),
        "DifferenceOperator": D,
        "DelayMargin": margin,
        "DelayMargin(inf)": delay_margin(A, QuasiPolynomial([[0.5]], [0])),
        "UnstableCount": unstable_count(F),
        "DistributedDelay": N,
        "QuasiPolynomial": QuasiPolynomial([[1, 1], [0.5j]], [0, 1], [N]),
        "QuasiTransferFunction": QuasiTransferFunction(B, F),
        "SpectralAbscissa": spectral_abscissa(F),  # retarded: chain value -inf
        "RootSet": find_roots(F, (-3, 1, -10, 10)),
        "RootCount": count_roots(F, (-3, 1, -10, 10)),
        "TransportSystem": TRANSPORT,
        "Hyperbolic2x2": Hyperbolic2x2(1.0, 1.0, np.cos, 0.1, 0.5, 0.5),
        "ReflectionController": ReflectionController(0.1),
        "FilteredController": FilteredController(0.1, 1.0),
        "Classification": classify(TRANSPORT),
        "Kernels": solve_kernels(COUPLED, 11),
        "DelayForm": delay_form(COUPLED, 11),
        "Simulation": simulate(TRANSPORT, ReflectionController(0.1), 0.0, 1.0, np.cos, np.sin, cells=16),
        "KRegion": k_region(TRANSPORT, 0.1, Ks=[-0.1, 0.0, 0.1]),
        "ABRegion": ab_region(TRANSPORT, 0.1, [0.0, 0.1], [1.0]),
        "StabilityChart": stability_chart(TRANSPORT, [0.0, 2.0], [0.0, 0.5]),  # K = 2: not strongly stable
        "Tradeoff": tradeoff(TRANSPORT, [0.0, 0.1]),
        "PointFailure": sweep.failures[0],
        "SweepResult": sweep,
        "RobustnessResult": nrobust.robustness(draw_transport, ReflectionController(0.1), 3, executor="serial"),
        "Certificate": cert,
        "PrincipalPart": cert.principal_delayed,
        "ReportFiles": ReportFiles(tmp / "r.md", tmp / "r.html", (tmp / "c.json",), (tmp / "f.png",)),
        "SweepFileResult": SweepFileResult(
            sweep, tmp / "s.csv", tmp / "s.json", tmp / "s.png", {"delta_star": (math.inf,)}, (0.5,)
        ),
        "NyquistResponse": nyquist_response(A, B, n_freq=101),  # retarded loop: principal bound -inf
        "BodeResponse": bode_response(2.0 * delay(0.1) * tf([1.0], [1.0, 1.0])),
        "RootLocusData": root_locus_response(root_family, [0.5, 1.0], (-3, 1, -10, 10)),
        # the transport line's U = -rho u(t, 1) with delta = 0.01: its unstable chain is above |Im s| = 60
        "HiddenUnstableRoots": hidden_unstable_roots(
            QuasiPolynomial([[1.0], [-0.85], [0.85]], [0.0, 2.0, 2.01]), (-1.5, 0.6, -60.0, 60.0)
        ),
        "RootMapData": root_map_response(
            QuasiPolynomial([[1.0], [-0.85], [0.85]], [0.0, 2.0, 2.01]), (-1.5, 0.6, -60.0, 60.0)
        ),
        "Manifest": Manifest("sweep", "0", "2026-01-01T00:00:00Z", ({"path": "a.csv", "size": 1, "sha256": "0" * 64},)),
        "Claim": proven.claims[0],
        "ModelError": proven.model_error,
        "StateFeedback": StateFeedback(-0.3, np.cos, 0.5),  # a callable gain: its repr
        "OutputFeedback": OutputFeedback(ReflectionController(0.1), observer_delay=0.05),
        "CollocatedOutputFeedback": CollocatedOutputFeedback(ReflectionController(0.1)),
        "SaintVenant": saint_venant(3000.0, 7.0, 1e-4, 14.0, manning=0.02),
        "ARZ": arz(500.0, 40.0, 0.16, 0.5, 60.0, 0.12),
        "GeneralHyperbolic2x2": GENERAL,
        "GeneralSimulation": simulate_general(GENERAL, StateFeedback(-0.3), 0.5, 2.0, 1.0, 0.5, 10),
        "VaryingDelayForm": varying_delay_form(GENERAL, 50),
        "VaryingKernels": solve_varying_kernels(GENERAL, 11),
        "NPlusMSystem": ONE_PLUS_ONE,
        "NPlusMMargin": nplusm_delay_margin(ONE_PLUS_ONE, [[-0.2]]),
        "NPlusMSimulation": simulate_nplusm(ONE_PLUS_ONE, [[-0.2]], 0.5, 2.0, two_profiles, cells=8),
        "CancellationCase": cancellation_study(ONE_PLUS_ONE, [[0.5]], (-2.0, 1.0, -0.25, 6.0))[0],
        "MatrixDifferenceOperator": MD,
        "NPlusMKernels": solve_nplusm_kernels(ONE_PLUS_ONE, 11),
        "KernelErrorBound": kernel_error_bound(solve_nplusm_kernels(ONE_PLUS_ONE, 11)),
        "NPlusMBackstepping": NPlusMBackstepping.for_system(ONE_PLUS_ONE, 11),
        "Gamma0": MD.gamma_0(rtol=1e-3),
        "ProvenCrossings": proven_crossings(A, B),
        "QuasiPolynomialMatrix": QuasiPolynomialMatrix([[F, QuasiPolynomial([[0.0, 0.2]], [0.5])], [0.0, A]]),
        "DelayLTI": delay(0.5) * tf([2.0], [1.0, 1.0]),
        "AllMargins": allmargin(delay(0.5) * tf([2.0], [1.0, 1.0])),
        "PadeModel": pade_approximation(
            QuasiTransferFunction(QuasiPolynomial([[1.0]], [0.5]), QuasiPolynomial([[1.0, 1.0]], [0.0])),
            2,
            [0.1, 1.0],
            return_bound=True,
        ),
        "ReflectionDesign": reflection,
        "GainDesign": reflection.design,
        "LoopDesign": local,
        "LocalRun": local.runs[0],
        "ParetoFront": pareto_front(gain_loop, [(0.0, 5.0)], [0.6], x0=[0.5]),
        "ParetoResponse": pareto_response(gain_loop, [(0.0, 5.0)], [0.6], x0=[0.5]),
        "FilteredDesign": design_filtered(
            TRANSPORT, parameters={"K": (-0.3, 0.3), "a": 0.1, "b": 0.1}, x0=[0.1], starts=1, max_iter=3
        ),
        "ExactFilteredDesign": design_filtered_exact(
            TRANSPORT, "margin", parameters={"b": (0.3, 1.5), "K": 0.1, "a": 0.0}
        ),
        "MismatchRegion": mismatch,
        "DelayWindow": window_stability(A, B, (0.1, 0.2)),
        "SpeedTolerance": speed_tolerance(TRANSPORT, ReflectionController(0.1), 0.1, (0.0, 0.1), grid=2),
        "ObserverDesign": nrobust.design_collocated_observer(
            TransportSystem(1.0, 2.0, 0.9, 0.6), controller=ReflectionController(0.2)
        ),
        "CollocatedDesign": nrobust.design_collocated_output_feedback(
            TransportSystem(1.0, 2.0, 0.9, 0.6), "decay_rate", margin_at_least=0.5, x0=[0.2, 0.1], starts=1, max_iter=3
        ),
        "NPlusMSpeedTolerance": nplusm_speed_tolerance(ONE_PLUS_ONE, [[-0.2]], 0.05, (0.0, 0.1)),
        "NPlusMWindow": check_window(ONE_PLUS_ONE, [[-0.2]], nplusm_delay_margin(ONE_PLUS_ONE, [[-0.2]]), (0.1, 0.2)),
        "NPlusMGainDesign": design_nplusm_gains(
            NPlusMSystem.from_2x2(Hyperbolic2x2(1, 1, 1.5, 0.5, 0.8, 0.4)),
            "margin",
            K_bounds=(-0.8, -0.5),
            x0=[[-0.6]],
            starts=1,
            max_iter=3,
        ),
        "StateFeedbackDesign": design_state_feedback(
            TRANSPORT, "decay_rate", k_bounds=(-0.3, 0.3), kernel_grid=None, starts=1
        ),
    }


NAMES = [
    "RootFreeRegion",
    "RoucheDelayBound",
    "Crossing",
    "Chain",
    "Chains",
    "SpectralBound",
    "DifferenceOperator",
    "DelayMargin",
    "DelayMargin(inf)",
    "UnstableCount",
    "DistributedDelay",
    "QuasiPolynomial",
    "QuasiTransferFunction",
    "SpectralAbscissa",
    "RootSet",
    "RootCount",
    "TransportSystem",
    "Hyperbolic2x2",
    "ReflectionController",
    "FilteredController",
    "Classification",
    "Kernels",
    "DelayForm",
    "Simulation",
    "KRegion",
    "ABRegion",
    "StabilityChart",
    "Tradeoff",
    "PointFailure",
    "SweepResult",
    "RobustnessResult",
    "Certificate",
    "PrincipalPart",
    "ReportFiles",
    "SweepFileResult",
    "NyquistResponse",
    "BodeResponse",
    "ParetoResponse",
    "RootLocusData",
    "HiddenUnstableRoots",
    "RootMapData",
    "Manifest",
    "Claim",
    "ModelError",
    "StateFeedback",
    "OutputFeedback",
    "CollocatedOutputFeedback",
    "SaintVenant",
    "ARZ",
    "GeneralHyperbolic2x2",
    "GeneralSimulation",
    "VaryingDelayForm",
    "VaryingKernels",
    "NPlusMSystem",
    "NPlusMMargin",
    "NPlusMSimulation",
    "CancellationCase",
    "MatrixDifferenceOperator",
    "NPlusMKernels",
    "NPlusMBackstepping",
    "KernelErrorBound",
    "Gamma0",
    "ProvenCrossings",
    "QuasiPolynomialMatrix",
    "DelayLTI",
    "AllMargins",
    "PadeModel",
    "ReflectionDesign",
    "GainDesign",
    "LoopDesign",
    "LocalRun",
    "ParetoFront",
    "FilteredDesign",
    "ExactFilteredDesign",
    "MismatchRegion",
    "DelayWindow",
    "SpeedTolerance",
    "ObserverDesign",
    "CollocatedDesign",
    "NPlusMWindow",
    "NPlusMSpeedTolerance",
    "NPlusMGainDesign",
    "StateFeedbackDesign",
]


def _reject_constant(name: str) -> None:
    raise AssertionError(f"non-strict JSON constant {name}")


def _leaves(value: Any) -> list[Any]:
    if isinstance(value, dict):
        return [x for v in value.values() for x in _leaves(v)]
    if isinstance(value, list):
        return [x for v in value for x in _leaves(v)]
    return [value]


def test_names_cover_the_fixture(results):
    assert sorted(NAMES) == sorted(results)


def test_every_class_with_to_dict_is_built_here(results):
    """A new result class with ``to_dict`` must be added to :func:`results`."""
    defining = set()
    for info in pkgutil.walk_packages(nrobust.__path__, "nrobust."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for _, cls in inspect.getmembers(module, inspect.isclass):
            # a Protocol that names to_dict (a type of the results, not one) has no instances
            if cls.__module__ == module.__name__ and "to_dict" in vars(cls) and not getattr(cls, "_is_protocol", False):
                defining.add(cls)
    missing = {c.__qualname__ for c in defining if not any(isinstance(obj, c) for obj in results.values())}
    assert not missing


@pytest.mark.parametrize("name", NAMES)
def test_to_dict_is_strict_json(results, name):
    data = results[name].to_dict()
    text = json.dumps(data, allow_nan=False)
    assert json.loads(text, parse_constant=_reject_constant) == data  # lists, str keys, plain numbers
    for leaf in _leaves(data):
        assert leaf is None or type(leaf) in (bool, int, float, str), (name, type(leaf))
        assert not isinstance(leaf, float) or math.isfinite(leaf)


@pytest.mark.parametrize(
    ("name", "path", "expected"),
    [
        ("RoucheDelayBound", ("delta_0",), "inf"),
        ("Chains", ("bracket",), ["-inf", "-inf"]),
        ("SpectralBound", ("lower",), "-inf"),
        ("DelayMargin(inf)", ("margin",), "inf"),
        ("SpectralAbscissa", ("chain_value",), "-inf"),
        ("SpectralAbscissa", ("strong_bound",), "-inf"),
        ("KRegion", ("margins",), ["inf", "inf", "inf"]),
        ("ABRegion", ("margins",), [["inf"], ["inf"]]),
        ("StabilityChart", ("values",), [[0.0, 0.0], [0.0, "inf"]]),
        ("StabilityChart", ("margins",), ["inf", 0.0]),
        ("Tradeoff", ("rouche_bounds",), ["inf", "inf"]),
        ("SweepResult", ("rows", 0, "delta_star"), "inf"),
        ("RobustnessResult", ("quantiles", "delta_star"), ["inf"] * 5),
        ("Certificate", ("delay_margin",), "inf"),
        ("Certificate", ("margin", "margin"), "inf"),
        ("Certificate", ("rouche", "delta_0"), "inf"),
        ("SweepFileResult", ("quantiles", "delta_star"), ["inf"]),
        ("NyquistResponse", ("principal_bound",), "-inf"),
    ],
)
def test_infinities_are_strings(results, name, path, expected):
    value = results[name].to_dict()
    for key in path:
        value = value[key]
    assert value == expected


def test_complex_numbers_and_arrays_become_lists(results):
    cross = results["Crossing"]
    np.testing.assert_allclose(cross.to_dict()["ds_ddelta"], [cross.ds_ddelta.real, cross.ds_ddelta.imag], rtol=0)
    assert results["DistributedDelay"].to_dict()["values"] == [[1.0, 0.0], [2.0, 1.0], [0.5, 0.0]]
    roots = results["RootSet"]
    data = roots.to_dict()
    np.testing.assert_allclose([complex(*z) for z in data["roots"]], roots.roots, rtol=0, atol=0)
    assert data["boxes"] == roots.boxes.tolist() and data["region"] == list(roots.region)
    assert results["ReportFiles"].to_dict()["json"] == [str(results["ReportFiles"].json[0])]


def test_existing_keys_are_kept(results):
    assert list(results["DelayMargin"].to_dict())[:3] == ["margin", "omega", "crossings"]
    assert "characteristic" not in results["DelayForm"].to_dict()
    assert results["DelayForm"].to_dict()["type"] == "DelayForm"
    assert results["Certificate"].to_dict()["spectral_abscissa"] == results["Certificate"].abscissa.to_dict()
    assert results["ReflectionController"].to_dict() == {"controller": "ReflectionController", "K": 0.1}
    qp = results["QuasiPolynomial"].to_dict()
    assert qp["coefs"] == [[1.0, 1.0], [[0.0, 0.5]]] and qp["delays"] == [0.0, 1.0] and len(qp["distributed"]) == 1


def test_writers_are_strict(results, tmp_path):
    json.loads(results["Certificate"].to_json(), parse_constant=_reject_constant)
    path = results["SweepResult"].to_json(tmp_path / "s.json", extra={"x": [math.inf, math.nan]})
    data = json.loads(path.read_text(), parse_constant=_reject_constant)
    assert data["x"] == ["inf", "nan"] and data["rows"][0]["delta_star"] == "inf"


def test_sweep_table_keeps_floats_from_to_dict():
    """A swept function returning a result: its ``"inf"`` strings become numeric columns again."""
    res = nrobust.sweep(margin_result, [{"b": 0.5}, {"b": 2.0}], "serial")
    margins = res.table()["margin"]
    assert margins.dtype == np.float64 and margins[0] == math.inf
    np.testing.assert_allclose(margins[1], delay_margin(A, B).margin, rtol=1e-14)


def test_json_safe_convention():
    value = {
        "a": np.array([1.0, np.inf, -np.inf, np.nan]),
        1: (np.int64(3), np.bool_(True), 1 + 2j, np.complex128(-1j)),
        "m": np.eye(2, dtype=int),
        "p": Path("x") / "y.json",
        "o": None,
    }
    want = {
        "a": [1.0, "inf", "-inf", "nan"],
        "1": [3, True, [1.0, 2.0], [-0.0, -1.0]],
        "m": [[1, 0], [0, 1]],
        "p": str(Path("x") / "y.json"),
        "o": None,
    }
    out = json_safe(value)
    assert out == want and json_safe(out) == out  # idempotent
    assert type(out["1"][0]) is int and type(out["1"][1]) is bool
    decoded = decode_floats(out)
    assert decoded["a"][:3] == [1.0, math.inf, -math.inf] and math.isnan(decoded["a"][3])
    assert decoded["p"] == want["p"]


def test_fields_dict_names_bad_arguments(results):
    with pytest.raises(ParameterError) as info:
        fields_dict(results["DelayMargin"], exclude=("no_such_field",))
    assert info.value.name == "exclude"
    with pytest.raises(ParameterError) as info:
        fields_dict({"a": 1})
    assert info.value.name == "obj"


# --- equality: never raises; identity for results holding arrays ---

IDENTITY = [
    "KRegion",
    "ABRegion",
    "StabilityChart",
    "Tradeoff",
    "RootSet",
    "DelayForm",
    "Kernels",
    "Simulation",
    "NyquistResponse",
    "RootLocusData",
    "RootMapData",
    "DifferenceOperator",
    "SaintVenant",
    "GeneralHyperbolic2x2",
    "GeneralSimulation",
    "VaryingDelayForm",
    "VaryingKernels",
    "NPlusMSystem",
    "NPlusMSimulation",
    "MatrixDifferenceOperator",
]


@pytest.mark.parametrize("name", NAMES)
def test_equality_never_raises(results, name):
    obj = results[name]
    assert obj == obj
    assert isinstance(obj == copy.copy(obj), bool) and isinstance(obj != copy.copy(obj), bool)


@pytest.mark.parametrize("name", IDENTITY)
def test_results_holding_arrays_compare_by_identity(results, name):
    obj = results[name]
    assert obj == obj and obj != copy.copy(obj)
    assert {obj: 1}[obj] == 1


def test_crossing_search_compares_by_identity():
    search = crossing_frequencies(A, B)
    assert search == search and search != copy.copy(search)
    assert search != crossing_frequencies(A, B)
