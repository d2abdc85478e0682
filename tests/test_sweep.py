"""Sweeps and Monte Carlo studies give the same table on every executor and lose no point."""

from __future__ import annotations

import functools
import json
import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import pytest

import nrobust
from nrobust.errors import ParameterError
from nrobust.hyperbolic import TransportSystem
from nrobust.sweeps import ANALYSES, PointFailure, RobustnessResult, run_sweep_file
from nrobust.sweeps.sweepfile import _Analysis

distributed = pytest.importorskip("distributed")

# The module's in-process Dask cluster keeps threads alive while some tests fork process
# pools. From Python 3.12 on, os.fork() then warns that a lock held by one of those threads
# could be copied into the child; the children here run only the pure functions below and
# never touch Dask, so that one warning is ignored for this module, by its exact text.
pytestmark = pytest.mark.filterwarnings(
    r"ignore:This process \(pid=\d+\) is multi-threaded, use of fork\(\) may lead to deadlocks:DeprecationWarning"
)


# --- functions sent to workers: module level, so that the process pool can pickle them ---


def toy_margin(a: float, b: float) -> float:
    """Delay margin of s + a + b e^{-delta s}: stable for every delay when a > |b|, else
    (b > |a|) arccos(-a/b) / sqrt(b^2 - a^2), the first delay at which a root crosses."""
    if a + b <= 0:
        raise ValueError(f"s + a + b is unstable without delay (a + b = {a + b})")
    if a >= abs(b):
        return math.inf
    return math.acos(-a / b) / math.sqrt(b * b - a * a)


def analyse_point(a: float, b: float, scale: float = 1.0) -> dict:
    """A per-point analysis with a failing region (a + b <= 0) and nested outputs."""
    margin = toy_margin(a, b)
    return {"delta_star": margin * scale, "stable": math.isinf(margin), "root": {"w": complex(0.0, b)}}


@dataclass(frozen=True)
class ToySystem:
    a: float
    b: float

    def to_dict(self) -> dict:
        return {"a": self.a, "b": self.b}


def draw_toy(rng: np.random.Generator) -> ToySystem:
    return ToySystem(a=float(rng.uniform(-0.9, 1.5)), b=1.0)


def toy_analysis(system: ToySystem, controller: float) -> dict:
    return {"delta_star": toy_margin(system.a + controller, system.b), "decay_rate": system.a + system.b + controller}


def draw_transport(rng: np.random.Generator) -> TransportSystem:
    return TransportSystem(lam=1.0, mu=2.0, q=float(rng.uniform(0.8, 1.3)), rho=float(rng.uniform(0.3, 0.9)))


def returns_float(a: float, b: float) -> float:
    return a + b


POINTS = nrobust.grid(a=[-2.5, 0.0, 0.5, 1.2], b=[1.0, 2.0])


@pytest.fixture(scope="module")
def dask_client():
    """A two-worker in-process Dask cluster for this module, started and stopped here."""
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=False, dashboard_address=":0", silence_logs=50
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        yield client


# --- grid ---


def test_grid_is_the_cartesian_product_last_axis_fastest():
    pts = nrobust.grid(K=np.array([0.0, 0.5]), delta=range(3))
    assert pts == [
        {"K": 0.0, "delta": 0},
        {"K": 0.0, "delta": 1},
        {"K": 0.0, "delta": 2},
        {"K": 0.5, "delta": 0},
        {"K": 0.5, "delta": 1},
        {"K": 0.5, "delta": 2},
    ]
    assert type(pts[0]["K"]) is float


@pytest.mark.parametrize("axes, name", [({"K": 0.3}, "K"), ({"K": []}, "K"), ({"K": "abc"}, "K"), ({}, "axes")])
def test_grid_rejects_bad_axes(axes, name):
    with pytest.raises(ParameterError) as info:
        nrobust.grid(**axes)
    assert info.value.name == name


# --- sweep: same table everywhere, failures kept ---


def test_closed_form_toy_margin_is_a_crossing():
    a, b = 0.3, 1.0
    delta, w = toy_margin(a, b), math.sqrt(b * b - a * a)
    assert abs(1j * w + a + b * np.exp(-1j * w * delta)) < 1e-12


def test_failing_point_is_reported_in_place():
    res = nrobust.sweep(analyse_point, POINTS, "serial")
    assert len(res.points) == len(POINTS) and res.n_failed == 2 and res.n_ok == 6
    assert [f.index for f in res.failures] == [0, 1]
    fail = res.failures[0]
    assert isinstance(fail, PointFailure) and fail.type == "ValueError" and "unstable without delay" in fail.message
    assert fail.point == {"a": -2.5, "b": 1.0} and "toy_margin" in fail.traceback
    t = res.table()
    assert list(t["status"]) == ["error"] * 2 + ["ok"] * 6
    assert t["error_type"][0] == "ValueError" and t["error"][2] == ""
    assert np.isnan(t["delta_star"][0]) and t["delta_star"][2] == pytest.approx(
        toy_margin(0.0, 1.0), rel=1e-13, abs=1e-14
    )
    assert np.isinf(t["delta_star"][6])  # a = 1.2 > |b| = 1: every delay tolerated
    assert t.dtype["root.w.imag"].kind == "f" and t.dtype["stable"] is np.dtype(object)  # missing bools stay None
    assert res.columns[:4] == ("index", "a", "b", "status")


def test_serial_processes_threads_and_dask_give_identical_results(dask_client):
    serial = nrobust.sweep(analyse_point, POINTS, "serial")
    runs = [
        nrobust.sweep(analyse_point, POINTS),  # all cores
        nrobust.sweep(analyse_point, POINTS, 2, chunksize=3),
        nrobust.sweep(analyse_point, POINTS, dask_client, chunksize=1),
        nrobust.sweep(analyse_point, POINTS, dask_client.scheduler.address),  # a client per call
    ]
    with ThreadPoolExecutor(2) as pool:
        runs.append(nrobust.sweep(analyse_point, POINTS, pool))
    for run in runs:
        assert run == serial, run.executor
        assert run.table().tobytes() == serial.table().tobytes()
    assert dask_client.status == "running"  # a client passed in is not closed


def test_dask_local_cluster_started_and_closed_by_the_call():
    # No warning filter here: the only warning this used to raise under pyproject's
    # "error" filter was distributed's UserWarning "Port 8787 is already in use" when a
    # second cluster started next to the module's one; sweep() binds the dashboard to a
    # free port (":0"), and the cluster and client are closed through their context
    # managers, so shutdown leaves no unclosed sockets behind (checked under load).
    res = nrobust.sweep(analyse_point, POINTS, "dask")
    assert res.executor.startswith("dask(LocalCluster")
    assert res == nrobust.sweep(analyse_point, POINTS, "serial")


def test_progress_bar_on_request(capsys):
    nrobust.sweep(analyse_point, POINTS, "serial", progress=True)
    assert "8/8" in capsys.readouterr().err
    nrobust.sweep(analyse_point, POINTS, "serial", progress=False)
    assert capsys.readouterr().err == ""


def margin_of(controller, rho: float) -> dict:
    """A point whose parameter is an object: the columns come from its to_dict()."""
    return {"delta_star": toy_margin(1.0 - rho, controller.K + rho)}


def test_object_parameters_are_flattened_into_columns():
    points = [{"controller": nrobust.ReflectionController(K), "rho": 0.3} for K in (0.1, 0.8)]
    t = nrobust.sweep(margin_of, points, 2).table()
    assert t.dtype.names[:5] == ("index", "controller.controller", "controller.K", "rho", "status")
    assert list(t["controller.K"]) == [0.1, 0.8]
    assert np.isinf(t["delta_star"][0]) and np.isfinite(t["delta_star"][1])


def test_wrong_return_type_is_a_recorded_failure():
    res = nrobust.sweep(returns_float, POINTS[:2], "serial")
    assert res.n_failed == 2 and res.failures[0].type == "TypeError"
    assert "dict of scalars" in res.failures[0].message


@pytest.mark.parametrize("executor", ["threads", 0, -2, True, 1.5, object()])
def test_bad_executor_names_executor(executor):
    with pytest.raises(ParameterError) as info:
        nrobust.sweep(analyse_point, POINTS, executor)
    assert info.value.name == "executor"


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"func": 3}, "func"),
        ({"points": {"a": 1}}, "points"),
        ({"points": []}, "points"),
        ({"points": [{"a": 1}, 2]}, "points[1]"),
        ({"chunksize": 0}, "chunksize"),
    ],
)
def test_bad_arguments_are_named(kwargs, name):
    args = {"func": analyse_point, "points": POINTS, "executor": "serial", **kwargs}
    with pytest.raises(ParameterError) as info:
        nrobust.sweep(**args)
    assert info.value.name == name


def test_lambda_is_rejected_by_the_process_pool_with_a_clear_error(dask_client):
    func = lambda a, b: {"s": a + b}  # noqa: E731
    with pytest.raises(ParameterError) as info:
        nrobust.sweep(func, POINTS, 2)
    assert info.value.name == "func" and "lambda" in str(info.value)
    # in-process and Dask executors take it (Dask pickles functions by value)
    assert nrobust.sweep(func, POINTS, "serial") == nrobust.sweep(func, POINTS, dask_client)
    # a functools.partial of a module-level function goes to processes
    part = nrobust.sweep(functools.partial(analyse_point, scale=2.0), POINTS, 2)
    assert part.table()["delta_star"][2] == pytest.approx(2 * toy_margin(0.0, 1.0), rel=1e-13, abs=1e-14)


def test_csv_and_json_outputs(tmp_path):
    res = nrobust.sweep(analyse_point, POINTS, "serial")
    csv_text = res.to_csv(tmp_path / "t.csv").read_text().splitlines()
    assert csv_text[0].split(",")[:4] == ["index", "a", "b", "status"]
    assert len(csv_text) == 1 + len(POINTS) and "inf" in csv_text[7]
    data = json.loads((tmp_path / "t.json").write_text("") or res.to_json(tmp_path / "t.json").read_text())
    assert data["n_failed"] == 2 and data["rows"][6]["delta_star"] == "inf"
    assert data["failures"][0]["type"] == "ValueError"
    assert res.to_dict()["rows"][6]["delta_star"] == "inf"  # to_dict is strict-JSON-ready
    assert res.records()[6]["delta_star"] == math.inf  # the table keeps the float
    assert "2 failed" in repr(res)


# --- Monte Carlo ---


def test_robustness_quantiles_and_reproducibility():
    res = nrobust.robustness(
        draw_toy, 0.0, 40, seed=3, executor="serial", analysis=toy_analysis, levels=(0.1, 0.5, 0.9)
    )
    assert isinstance(res, RobustnessResult) and res.n_samples == 40 and res.n_failed == 0
    t = res.sweep.table()
    margins = np.array([toy_margin(a, 1.0) for a in t["system.a"]])
    np.testing.assert_array_equal(t["delta_star"], margins)
    expected = np.quantile(margins, [0.1, 0.5, 0.9], method="inverted_cdf")
    np.testing.assert_array_equal(res.quantiles["delta_star"], expected)
    assert res.quantile("delta_star", 0.9) == math.inf  # a > 1 in about a fifth of the samples
    assert res.quantile("decay_rate", 0.5) > 0
    # the first samples of a larger study are the samples of a smaller one
    small = nrobust.robustness(draw_toy, 0.0, 10, seed=3, executor="serial", analysis=toy_analysis)
    np.testing.assert_array_equal(small.sweep.table()["system.a"], t["system.a"][:10])
    assert "delta_star" in repr(res)
    summary = {k: v for k, v in res.to_dict().items() if k != "sweep"}
    quantiles = {c: list(v) for c, v in res.quantiles.items()}
    assert quantiles["delta_star"] == expected.tolist()
    strict = {c: ["inf" if math.isinf(x) else x for x in v] for c, v in quantiles.items()}
    want = {"levels": [0.1, 0.5, 0.9], "quantiles": strict, "n_samples": 40, "n_failed": 0, "seed": 3}
    assert summary == want and json.loads(json.dumps(summary, allow_nan=False)) == want


def test_robustness_identical_on_processes_and_failures_excluded():
    # controller = -0.5 makes the samples with a < -0.5 unstable without delay: recorded failures
    serial = nrobust.robustness(draw_toy, -0.5, 24, seed=11, executor="serial", analysis=toy_analysis)
    procs = nrobust.robustness(draw_toy, -0.5, 24, seed=11, executor=2, analysis=toy_analysis)
    assert serial == procs and serial.n_failed > 0
    ok = serial.sweep.table()
    ok = ok[ok["status"] == "ok"]
    assert serial.quantile("delta_star", 0.5) == np.quantile(ok["delta_star"], 0.5, method="inverted_cdf")


def test_robustness_names_the_unpicklable_argument():
    with pytest.raises(ParameterError) as info:
        nrobust.robustness(lambda rng: ToySystem(0.1, 1.0), 0.0, 4, executor=2, analysis=toy_analysis)
    assert info.value.name == "sample_system"
    with pytest.raises(ParameterError) as info:
        nrobust.robustness(draw_toy, 0.0, 0, analysis=toy_analysis)
    assert info.value.name == "n_samples"


# --- SWEEP.toml ---


def toy_file_margin(system, controller, scale: float = 1.0):
    """Stands in for nrobust.delay_margin in the file runner: closed-form margin of
    s + a + b e^{-delta s} with a = 1 - |rho q| and b = |K q| + |rho q|."""

    @dataclass(frozen=True)
    class Margin:
        delta_star: float

    rq, kq = abs(system.rho * system.q), abs(controller.K * system.q)
    return Margin(scale * toy_margin(1.0 - rq, kq + rq))


def _toy_columns(result):
    return {"delta_star": result.delta_star}


@pytest.fixture
def toy_registry(monkeypatch):
    """Register a closed-form analysis in the file runner's registry, so that its
    machinery is tested apart from the margin search."""
    monkeypatch.setitem(ANALYSES, "toy", _Analysis(toy_file_margin, 2, (), _toy_columns))


GRID_TOML = """
analysis = "toy"
executor = "serial"
[system]
type = "TransportSystem"
lam = 1.0
mu = 2.0
q = 0.8
[controller]
type = "ReflectionController"
[options.toy]
scale = 2.0
[grid]
K = {start = 0.0, stop = 1.0, num = 5}
rho = [0.2, 0.6]
"""


def test_sweep_file_grid_writes_table_and_chart(tmp_path, toy_registry):
    (tmp_path / "SWEEP.toml").write_text(GRID_TOML)
    out = run_sweep_file(tmp_path / "SWEEP.toml", tmp_path / "out")
    t = out.sweep.table()
    assert len(t) == 10 and list(t.dtype.names[1:3]) == ["K", "rho"]
    for row in t:
        expected = 2.0 * toy_margin(1.0 - 0.8 * row["rho"], 0.8 * row["K"] + 0.8 * row["rho"])
        assert row["delta_star"] == expected
    assert out.csv.read_text().startswith("index,K,rho,status")
    assert json.loads(out.json.read_text())["n_points"] == 10
    assert out.png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_sweep_file_sampling_gives_quantiles(tmp_path, toy_registry):
    text = (
        GRID_TOML.split("[grid]")[0]
        + """
[sampling]
n_samples = 30
seed = 4
levels = [0.5]
[sampling.distributions]
rho = {uniform = [0.1, 0.5]}
K = {choice = [0.0, 0.5]}
"""
    )
    (tmp_path / "SWEEP.toml").write_text(text)
    out = run_sweep_file(tmp_path / "SWEEP.toml", tmp_path / "out")
    assert out.levels == (0.5,) and set(out.quantiles) == {"delta_star"}
    margins = out.sweep.table()["delta_star"]
    assert out.quantiles["delta_star"][0] == np.quantile(margins, 0.5, method="inverted_cdf")
    written = json.loads(out.json.read_text())["quantiles"]["delta_star"]  # strict JSON: inf as "inf"
    assert [float(v) for v in written] == list(out.quantiles["delta_star"])
    assert out.png.stat().st_size > 0


@pytest.mark.parametrize(
    "edit, name",
    [
        (("[grid]", "[grid]\nfoo = [1]"), "grid.foo"),
        (('type = "TransportSystem"', 'type = "Pipe"'), "system.type"),
        (("mu = 2.0", "mu = 2.0\nnu = 1.0"), "system.nu"),
        (("q = 0.8", ""), "system.q"),
        (("scale = 2.0", "scal = 2.0"), "options.toy.scal"),
        (('analysis = "toy"', 'analysis = "nyquist"'), "analysis"),
        (("num = 5", "num = 0"), "grid.K.num"),
        (('executor = "serial"', 'executor = "threads"'), "executor"),
        (("[grid]", "[sampling]\nn_samples = 3\n[grid]"), "grid"),
        (('executor = "serial"', 'executor = "serial"\nmode = 1'), "mode"),
    ],
)
def test_sweep_file_errors_name_the_bad_key(tmp_path, toy_registry, edit, name):
    (tmp_path / "SWEEP.toml").write_text(GRID_TOML.replace(*edit))
    with pytest.raises(ParameterError) as info:
        run_sweep_file(tmp_path / "SWEEP.toml", tmp_path / "out")
    assert info.value.name == name


def test_sweep_file_bad_distribution_is_named(tmp_path, toy_registry):
    text = (
        GRID_TOML.split("[grid]")[0]
        + "[sampling]\nn_samples = 3\n[sampling.distributions]\nrho = {uniform = [0.5, 0.1]}\n"
    )
    (tmp_path / "SWEEP.toml").write_text(text)
    with pytest.raises(ParameterError) as info:
        run_sweep_file(tmp_path / "SWEEP.toml", tmp_path / "out")
    assert info.value.name == "sampling.distributions.rho.uniform"


# --- on the plant: transport equations with the reflection-preserving controller ---


def test_robustness_on_transport_system_matches_the_paper():
    """Margin inf iff |rho q| + |K q| < 1 (else 0); decay rate -ln|(rho - K) q| / tau."""
    K = 0.2
    res = nrobust.robustness(draw_transport, nrobust.ReflectionController(K), 16, seed=5, executor=2)
    assert res.n_failed == 0
    t = res.sweep.table()
    rq, kq = np.abs(t["system.rho"] * t["system.q"]), np.abs(K * t["system.q"])
    robust = rq + kq < 1
    assert robust.any() and (~robust).any()
    np.testing.assert_array_equal(np.isinf(t["delta_star"]), robust)
    assert np.all(t["delta_star"][~robust] == 0.0)
    tau = 1.0 / 1.0 + 1.0 / 2.0
    expected = -np.log(np.abs((t["system.rho"] - K) * t["system.q"])) / tau
    # abscissa = chain value ln|c|/tau of the difference operator: rounding (measured 5e-16 relative)
    np.testing.assert_allclose(t["decay_rate"], expected, rtol=1e-13, atol=1e-14)
    assert res == nrobust.robustness(draw_transport, nrobust.ReflectionController(K), 16, seed=5, executor="serial")


def test_sweep_file_on_transport_system(tmp_path):
    (tmp_path / "SWEEP.toml").write_text("""
analysis = ["delay_margin", "spectral_abscissa"]
executor = 2
[system]
type = "TransportSystem"
lam = 1.0
mu = 1.0
q = 1.0
[controller]
type = "ReflectionController"
[grid]
K = [0.0, 0.1, 0.3]
rho = [0.5, 0.85]
""")
    out = run_sweep_file(tmp_path / "SWEEP.toml", tmp_path / "out")
    t = out.sweep.table()
    assert out.sweep.n_failed == 0 and len(t) == 6
    np.testing.assert_array_equal(np.isinf(t["delta_star"]), t["rho"] + t["K"] < 1)
    np.testing.assert_allclose(t["decay_rate"], -np.log(np.abs(t["rho"] - t["K"])) / 2.0, rtol=1e-13, atol=1e-14)
    assert out.png.stat().st_size > 0


def test_sweep_file_bad_dask_address_is_named(tmp_path, toy_registry):
    (tmp_path / "SWEEP.toml").write_text(GRID_TOML)
    with pytest.raises(ParameterError) as info:
        run_sweep_file(tmp_path / "SWEEP.toml", tmp_path / "out", dask_address="scheduler")
    assert info.value.name == "dask_address"


def _square_or_fail(x: float) -> float:
    if x == 3:
        raise ValueError("three is not allowed")
    return x * x


def _blas_threads(_: int) -> int:
    from threadpoolctl import threadpool_info

    return max((pool["num_threads"] for pool in threadpool_info()), default=1)


def test_process_pool_workers_have_one_blas_thread():
    """Workers of the local pool run their BLAS on one thread, whatever the parent uses."""
    from threadpoolctl import threadpool_limits

    from nrobust.sweeps import sweep_map

    with threadpool_limits(2):
        assert sweep_map(2, chunksize=1)(_blas_threads, [0, 1]) == [1, 1]


def test_sweep_map_keeps_order_and_names_a_failing_item():
    from nrobust.errors import SweepError
    from nrobust.sweeps import sweep_map

    items = [5, 1, 4, 2]
    assert sweep_map("serial")(_square_or_fail, items) == [25, 1, 16, 4]
    assert sweep_map(2, chunksize=1)(_square_or_fail, items) == [25, 1, 16, 4]
    with pytest.raises(SweepError, match=r"item 3 raised ValueError: three is not allowed"):
        sweep_map("serial")(_square_or_fail, [1, 3])
    with pytest.raises(ParameterError, match="executor"):
        sweep_map("threads")


def _hang_at_two(a: int) -> dict:
    if a == 2:
        time.sleep(600)
    return {"a2": a * a}


def test_timeout_on_dask_and_thread_pools(dask_client):
    """The worker forks the point's process and kills it at the timeout; the worker lives on."""
    with ThreadPoolExecutor(2) as threads:
        for executor in (dask_client, threads):
            res = nrobust.sweep(_hang_at_two, nrobust.grid(a=range(4)), executor, timeout=0.5, chunksize=2)
            assert [(f.index, f.type) for f in res.failures] == [(2, "Timeout")]
            np.testing.assert_array_equal(res.table()["a2"][[0, 1, 3]], [0, 1, 9])
    assert nrobust.sweep(_hang_at_two, nrobust.grid(a=[0, 1]), dask_client, timeout=0.5).n_ok == 2


def test_one_blas_thread_limits_and_restores():
    """Every BLAS library runs one thread inside the block; the limits from before are restored after."""
    from threadpoolctl import threadpool_info, threadpool_limits

    from nrobust._threads import one_blas_thread

    def blas() -> list[int]:
        return [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]

    import scipy.linalg  # noqa: F401  (its BLAS too, which one_blas_thread loads)

    with threadpool_limits(2, user_api="blas"):
        before = blas()
        with one_blas_thread():
            assert blas() == [1] * len(before)
        assert blas() == before
