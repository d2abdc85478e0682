"""Nothing lost: sweeps sized before they run, hung points timed out, finished points kept
on disk through Ctrl-C and kill -9 and resumed to the table of an uninterrupted run, and
output directories replaced as a whole set."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from _sweep_helpers import MARKERS_ENV, SLOW, marker_name

import nrobust
from nrobust.errors import ParameterError
from nrobust.reports.outputs import MANIFEST, RunOutputs, atomic_write, check_output_dir, read_manifest
from nrobust.sweeps import ANALYSES, run_sweep_file
from nrobust.sweeps.engine import SweepInterrupted
from nrobust.sweeps.sweepfile import JOURNAL

TESTS = Path(__file__).resolve().parent

# --- functions sent to workers: module level, so that the process pool can pickle them ---


def square_sum(a: float, b: float) -> dict[str, float | str]:
    return {"s": a * a + b, "inf": math.inf, "text": "inf"}


def hang_at_two(a: int) -> dict[str, int]:
    """Hangs (sleeps far past any timeout of these tests) at a == 2."""
    if a == 2:
        time.sleep(600)
    return {"a2": a * a}


def exit_at_one(a: int) -> dict[str, int]:
    if a == 1:
        os._exit(3)
    return {"a2": a * a}


class Counter:
    """Counts its calls in a directory (one file per call), so that resumed points can be told from re-run ones."""

    def __init__(self, directory: Path, stop_at: int | None = None) -> None:
        self.directory, self.stop_at = directory, stop_at

    def __call__(self, a: int, b: int) -> dict[str, int]:
        if self.stop_at is not None and a * 3 + b == self.stop_at:
            raise KeyboardInterrupt  # what Ctrl-C does in the middle of a point
        (self.directory / f"{a}_{b}_{time.monotonic_ns()}").touch()
        return {"ab": a * 10 + b}


# --- sized before anything runs ---


def test_oversized_grid_is_refused_in_well_under_a_second():
    start = time.perf_counter()
    g = nrobust.grid(a=range(10**4), b=range(10**4))
    with pytest.raises(ParameterError) as info:
        nrobust.sweep(square_sum, g, "serial")
    elapsed = time.perf_counter() - start
    assert elapsed < 1.0, elapsed  # measured ~1e-4 s: nothing of the product is built
    message = str(info.value)
    assert info.value.name == "points"
    assert "10000 x 10000 = 100000000 points over a, b" in message and "max_points = 1000000" in message
    assert "GiB" in message
    with pytest.raises(ParameterError, match="max_points = 5"):
        nrobust.sweep(square_sum, nrobust.grid(a=[1, 2, 3], b=[1, 2]), "serial", max_points=5)
    assert nrobust.sweep(square_sum, nrobust.grid(a=[1, 2, 3], b=[1, 2]), "serial", max_points=6).n_ok == 6


def test_grid_is_lazy_and_indexable():
    g = nrobust.grid(a=range(10**4), b=[0.5, 1.5], c=("x", "y", "z"))
    assert len(g) == 60_000 and g[0] == {"a": 0, "b": 0.5, "c": "x"}
    assert g[-1] == {"a": 9999, "b": 1.5, "c": "z"} and g[7] == {"a": 1, "b": 0.5, "c": "y"}
    small = nrobust.grid(a=[1, 2], b=[3, 4, 5])
    assert list(small) == [small[i] for i in range(6)] == small[:] and small == list(small)
    with pytest.raises(IndexError):
        small[6]


SWEEP_HEAD = """
analysis = "spectral_abscissa"
executor = "serial"
[system]
type = "TransportSystem"
lam = 1.0
mu = 1.0
q = 1.0
[controller]
type = "ReflectionController"
"""


@pytest.mark.parametrize(
    "grid_table, name",
    [
        ("K = {start = 0.0, stop = 0.3, num = 1000000000}\nrho = [0.5]", "grid"),
        ("K = [0.0, 0.1]\nrho = {start = 0.1, stop = 0.9, num = 1000001}", "grid"),
        ("K = {start = nan, stop = 0.3, num = 3}\nrho = [0.5]", "grid.K.start"),
        ("K = {start = 0.0, stop = inf, num = 3}\nrho = [0.5]", "grid.K.stop"),
        ("K = [0.0, nan]\nrho = [0.5]", "grid.K"),
    ],
)
def test_sweep_file_refuses_oversized_and_non_finite_grids_before_running(tmp_path, grid_table, name):
    (tmp_path / "SWEEP.toml").write_text(SWEEP_HEAD + "[grid]\n" + grid_table + "\n")
    start = time.perf_counter()
    with pytest.raises(ParameterError) as info:
        run_sweep_file(tmp_path / "SWEEP.toml", tmp_path / "out")
    assert time.perf_counter() - start < 1.0
    assert info.value.name == name
    if name == "grid":
        assert "max_points = 1000000" in str(info.value)
    assert not (tmp_path / "out").exists()  # refused before the output directory is touched


def test_sweep_file_max_points_and_timeout_keys(tmp_path):
    (tmp_path / "SWEEP.toml").write_text("max_points = 3\n" + SWEEP_HEAD + "[grid]\nK = [0.0, 0.1]\nrho = [0.5, 0.6]\n")
    with pytest.raises(ParameterError, match=r"2 x 2 = 4 points over K, rho") as info:
        run_sweep_file(tmp_path / "SWEEP.toml", tmp_path / "out")
    assert info.value.name == "grid"
    (tmp_path / "SWEEP.toml").write_text("timeout = -1\n" + SWEEP_HEAD + "[grid]\nK = [0.0]\nrho = [0.5]\n")
    with pytest.raises(ParameterError) as info:
        run_sweep_file(tmp_path / "SWEEP.toml", tmp_path / "out")
    assert info.value.name == "timeout"


@pytest.mark.parametrize(("plot", "name"), [('y = "delta_star"', "plot.y"), ('x = "q"', "plot.x")])
def test_bad_plot_is_found_before_the_sweep_runs(tmp_path, plot, name):
    (tmp_path / "SWEEP.toml").write_text(SWEEP_HEAD + f"[grid]\nK = [0.0, 0.1]\nrho = [0.5]\n[plot]\n{plot}\n")
    with pytest.raises(ParameterError) as info:
        run_sweep_file(tmp_path / "SWEEP.toml", tmp_path / "out")
    assert info.value.name == name
    assert not (tmp_path / "out" / JOURNAL).exists()


@pytest.mark.parametrize("timeout", [0, -1.0, math.nan, math.inf, "1"])
def test_bad_timeout_is_named(timeout):
    with pytest.raises(ParameterError) as info:
        nrobust.sweep(square_sum, nrobust.grid(a=[1], b=[2]), "serial", timeout=timeout)
    assert info.value.name == "timeout"


# --- timeouts ---


@pytest.mark.parametrize("executor", ["serial", 2])
def test_hanging_point_times_out_while_the_rest_complete(executor):
    start = time.perf_counter()
    res = nrobust.sweep(hang_at_two, nrobust.grid(a=range(5)), executor, timeout=0.5)
    elapsed = time.perf_counter() - start
    assert elapsed < 8.0, elapsed  # one timeout of 0.5 s plus process start-up, not 600 s
    assert [f.index for f in res.failures] == [2] and res.failures[0].type == "Timeout"
    assert "timeout = 0.5 s" in res.failures[0].message
    t = res.table()
    assert list(t["status"]) == ["ok", "ok", "error", "ok", "ok"]
    np.testing.assert_array_equal(t["a2"][[0, 1, 3, 4]], [0, 1, 9, 16])


def test_a_dying_point_is_recorded_and_the_rest_complete():
    res = nrobust.sweep(exit_at_one, nrobust.grid(a=range(3)), "serial", timeout=30)
    assert [(f.index, f.type) for f in res.failures] == [(1, "WorkerDied")]
    assert "exited with code 3" in res.failures[0].message and res.n_ok == 2


def test_timeout_gives_the_same_table_as_no_timeout():
    points = nrobust.grid(a=[0.5, 1.0, 2.0], b=[1.0, -1.0])
    assert nrobust.sweep(square_sum, points, "serial", timeout=10) == nrobust.sweep(square_sum, points, "serial")


# --- the journal: resume, restart, changed definitions ---


def test_interrupted_sweep_resumes_without_rerunning_finished_points(tmp_path):
    calls = tmp_path / "calls"
    calls.mkdir()
    points = nrobust.grid(a=range(4), b=range(3))
    journal = tmp_path / "run.jsonl"
    with pytest.raises(SweepInterrupted) as info:
        nrobust.sweep(Counter(calls, stop_at=7), points, "serial", results=journal)
    assert (info.value.done, info.value.total, info.value.results) == (7, 12, journal)
    assert str(info.value) == f"interrupted: 7 of 12 points done, results in {journal}, rerun to resume"
    assert len(list(calls.iterdir())) == 7 and len(journal.read_text().splitlines()) == 1 + 7

    resumed = nrobust.sweep(Counter(calls), points, "serial", results=journal)
    assert len(list(calls.iterdir())) == 12  # the 7 finished points were read back, not run again
    assert resumed == nrobust.sweep(Counter(tmp_path), points, "serial")
    lines = [json.loads(x) for x in journal.read_text().splitlines()]
    assert sorted(x["index"] for x in lines[1:]) == list(range(12))


def test_journal_keeps_values_exactly_and_survives_a_cut_line(tmp_path):
    points = nrobust.grid(a=[0.1, 1e-300, 3.0], b=[1.0])
    journal = tmp_path / "run.jsonl"
    first = nrobust.sweep(square_sum, points, "serial", results=journal)
    text = journal.read_text()
    journal.write_text(text[: len(text) - 10])  # kill -9 in the middle of the last line
    resumed = nrobust.sweep(square_sum, points, "serial", results=journal)
    assert resumed == first
    assert resumed.results[1] is not None and resumed.results[1]["inf"] == math.inf
    assert resumed.results[1]["text"] == "inf"  # a string stays a string
    assert journal.read_text() == text  # the cut line dropped, the point appended again


def test_changed_definition_is_refused_unless_restart(tmp_path):
    journal = tmp_path / "run.jsonl"
    nrobust.sweep(square_sum, nrobust.grid(a=[1, 2], b=[1]), "serial", results=journal)
    with pytest.raises(ParameterError) as info:
        nrobust.sweep(square_sum, nrobust.grid(a=[1, 3], b=[1]), "serial", results=journal)
    old = json.loads(journal.read_text().splitlines()[0])["hash"]
    assert info.value.name == "results" and old[:12] in str(info.value) and "changed: points.grid.a" in str(info.value)
    with pytest.raises(ParameterError, match="changed: func"):
        nrobust.sweep(hang_at_two, nrobust.grid(a=[1, 2], b=[1]), "serial", results=journal)
    res = nrobust.sweep(square_sum, nrobust.grid(a=[1, 3], b=[1]), "serial", results=journal, restart=True)
    assert res.n_ok == 2 and len(journal.read_text().splitlines()) == 3
    for bad in (tmp_path, tmp_path / "missing" / "run.jsonl"):
        with pytest.raises(ParameterError, match="existing directory"):
            nrobust.sweep(square_sum, nrobust.grid(a=[1], b=[1]), "serial", results=bad)
    journal.write_text("not a journal\n")
    with pytest.raises(ParameterError, match="journal header"):
        nrobust.sweep(square_sum, nrobust.grid(a=[1, 3], b=[1]), "serial", results=journal)


def test_timed_out_points_are_retried_on_resume(tmp_path):
    journal = tmp_path / "run.jsonl"
    first = nrobust.sweep(hang_at_two, nrobust.grid(a=range(3)), "serial", timeout=0.3, results=journal)
    assert first.failures[0].type == "Timeout"
    again = nrobust.sweep(hang_at_two, nrobust.grid(a=range(3)), "serial", timeout=0.3, results=journal)
    assert again == first and len(journal.read_text().splitlines()) == 1 + 3 + 1  # only the timed-out point re-ran


def draw_rho(rng: np.random.Generator) -> nrobust.hyperbolic.TransportSystem:
    return nrobust.hyperbolic.TransportSystem(lam=1.0, mu=1.0, q=1.0, rho=float(rng.uniform(0.3, 0.9)))


def test_robustness_resumes_from_its_journal(tmp_path):
    journal = tmp_path / "mc.jsonl"
    ctl = nrobust.ReflectionController(0.1)
    first = nrobust.robustness(draw_rho, ctl, 6, seed=3, executor="serial", results=journal)
    lines = journal.read_text()
    again = nrobust.robustness(draw_rho, ctl, 6, seed=3, executor="serial", results=journal)
    assert again == first and journal.read_text() == lines  # nothing recomputed
    with pytest.raises(ParameterError) as info:
        nrobust.robustness(draw_rho, ctl, 6, seed=None, executor="serial", results=journal)
    assert info.value.name == "seed"
    with pytest.raises(ParameterError, match="changed"):
        nrobust.robustness(draw_rho, ctl, 6, seed=4, executor="serial", results=journal)


# --- the command line killed part-way (SIGINT, SIGKILL) and resumed ---

SLOW_TOML = """
analysis = "slow"
executor = "serial"
[system]
type = "TransportSystem"
lam = 1.0
mu = 1.0
q = 1.0
[controller]
type = "ReflectionController"
[grid]
K = {start = 0.0, stop = 0.9, num = 10}
rho = [0.5, 0.6, 0.7]
"""
# Ctrl-C's handler installed explicitly: a test runner's worker may have started us with SIGINT ignored
RUN_CLI = (
    "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
    f"sys.path.insert(0, {str(TESTS)!r}); import _sweep_helpers; _sweep_helpers.register(); "
    "from nrobust.cli import main; sys.exit(main(sys.argv[1:]))"
)


@pytest.fixture
def slow_registry(monkeypatch):
    monkeypatch.setitem(ANALYSES, "slow", SLOW)


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    """The table of the slow sweep run without interruption (in this process)."""
    ANALYSES["slow"] = SLOW
    try:
        d = tmp_path_factory.mktemp("ref")
        (d / "SWEEP.toml").write_text(SLOW_TOML)
        return run_sweep_file(d / "SWEEP.toml", d / "out")
    finally:
        del ANALYSES["slow"]


def _journal_indices(out: Path) -> list[int]:
    lines = (out / JOURNAL).read_bytes().split(b"\n")
    return [json.loads(line)["index"] for line in lines[1:-1]]  # complete lines only


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGKILL], ids=["SIGINT", "SIGKILL"])
def test_killed_cli_sweep_keeps_finished_points_and_resumes(tmp_path, slow_registry, uninterrupted, sig):
    (tmp_path / "SWEEP.toml").write_text(SLOW_TOML)
    out, markers = tmp_path / "out", tmp_path / "markers"
    markers.mkdir()
    env = {**os.environ, MARKERS_ENV: str(markers)}
    cmd = [sys.executable, "-c", RUN_CLI, "sweep", str(tmp_path / "SWEEP.toml"), "-o", str(out), "--no-progress"]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not ((out / JOURNAL).exists() and len(_journal_indices(out)) >= 5):
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.01)
    proc.send_signal(sig)
    _, stderr = proc.communicate(timeout=30)

    indices = _journal_indices(out)
    assert 5 <= len(indices) < 30 and len(set(indices)) == len(indices)
    points = uninterrupted.sweep.points
    finished = {marker_name(p["K"], p["rho"]) for p in (points[i] for i in indices)}
    markers_on_disk = {m.name for m in markers.iterdir()}
    # every point that finished is in the journal, but for the one whose outcome was on its
    # way to the file at the instant of the signal (a window of microseconds in 50 ms)
    assert finished <= markers_on_disk and len(markers_on_disk - finished) <= 1
    if sig == signal.SIGINT:
        assert proc.returncode == 130, stderr
        assert stderr == (
            f"nrobust: interrupted: {len(indices)} of 30 points done, results in {out / JOURNAL}, rerun to resume\n"
        )
    else:
        assert proc.returncode == -signal.SIGKILL
    assert not (out / "sweep.csv").exists() and not (out / MANIFEST).exists()

    resumed = run_sweep_file(tmp_path / "SWEEP.toml", out)
    assert resumed.sweep == uninterrupted.sweep
    assert resumed.csv.read_text() == uninterrupted.csv.read_text()
    assert sorted(_journal_indices(out)) == list(range(30))  # each point computed once
    manifest = read_manifest(out)
    assert manifest is not None and set(manifest.paths) == {"sweep.csv", "sweep.json", "sweep.png", JOURNAL}


def test_cli_restart_and_changed_definition(tmp_path, slow_registry, capsys):
    from nrobust.cli import main

    toml = tmp_path / "SWEEP.toml"
    toml.write_text(SLOW_TOML.replace("num = 10", "num = 2").replace("[0.5, 0.6, 0.7]", "[0.5]"))
    out = tmp_path / "out"
    assert main(["sweep", str(toml), "-o", str(out), "--no-progress"]) == 0
    toml.write_text(SLOW_TOML.replace("num = 10", "num = 3").replace("[0.5, 0.6, 0.7]", "[0.5]"))
    assert main(["sweep", str(toml), "-o", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("nrobust: error: results must be the journal of this sweep") and "--restart" in err
    assert "points.grid.K" in err and err.count("\n") == 1
    assert main(["sweep", str(toml), "-o", str(out), "--no-progress", "--restart"]) == 0
    assert "3 points, 0 failed" in capsys.readouterr().out


# --- outputs: checked first, atomic, replaced as a set ---


def test_output_dir_checks(tmp_path):
    (tmp_path / "file").write_text("x")
    for bad in (tmp_path / "file", tmp_path / "file" / "sub", Path("/proc/nrobust-out")):
        with pytest.raises(ParameterError) as info:
            check_output_dir(bad)
        assert info.value.name == "out"
    assert check_output_dir(tmp_path / "a" / "b").is_dir() and list((tmp_path / "a" / "b").iterdir()) == []


def test_atomic_write_leaves_the_old_file_on_failure(tmp_path):
    target = tmp_path / "t.json"
    target.write_text("old")
    with pytest.raises(RuntimeError), atomic_write(target) as fh:
        fh.write("half of the new")
        raise RuntimeError("disk full")
    assert target.read_text() == "old" and os.listdir(tmp_path) == ["t.json"]
    with atomic_write(target, "wb") as fh:
        fh.write(b"new")
    assert target.read_bytes() == b"new" and oct(target.stat().st_mode & 0o777) != "0o600"


def test_rerun_replaces_the_whole_set(tmp_path):
    out = tmp_path / "out"
    with RunOutputs(out, "test") as first:
        first.write_text("report.md", "one")
        first.write_bytes("figures/a.png", b"a")
        first.write_bytes("figures/b.png", b"b")
    (out / "mine.txt").write_text("not the run's")
    manifest = json.loads((out / MANIFEST).read_text())
    assert [f["path"] for f in manifest["files"]] == ["figures/a.png", "figures/b.png", "report.md"]
    assert manifest["command"] == "test" and manifest["version"] == nrobust.__version__

    with pytest.raises(RuntimeError), RunOutputs(out, "test") as failed:
        failed.write_text("report.md", "half")
        raise RuntimeError("writing certificate.json failed")
    assert (out / "report.md").read_text() == "one" and (out / "figures" / "b.png").exists()
    assert sorted(p.name for p in out.iterdir()) == ["figures", "manifest.json", "mine.txt", "report.md"]

    (out / ".nrobust-staging-killed").mkdir()  # left by a run killed with SIGKILL
    (out / ".nrobust-staging-killed" / "report.md").write_text("never committed")
    with RunOutputs(out, "test") as second:
        second.write_text("report.md", "two")
        second.write_bytes("figures/a.png", b"A")
    assert (out / "report.md").read_text() == "two" and (out / "figures" / "a.png").read_bytes() == b"A"
    assert not (out / "figures" / "b.png").exists()  # listed by the previous run, not produced again
    assert (out / "mine.txt").exists()  # never listed: left alone
    assert sorted(p.name for p in out.iterdir()) == ["figures", "manifest.json", "mine.txt", "report.md"]
    sizes = {f["path"]: f["size"] for f in json.loads((out / MANIFEST).read_text())["files"]}
    assert sizes == {"figures/a.png": 1, "report.md": 3}


def test_sweep_file_timeout_records_the_hanging_point(tmp_path, slow_registry):
    text = SLOW_TOML.replace('executor = "serial"', 'executor = "serial"\ntimeout = 0.5').split("[grid]")[0]
    (tmp_path / "SWEEP.toml").write_text(text + "[grid]\nK = [0.5]\nrho = [0.5]\npause = [0.0, 60.0, 0.0]\n")
    start = time.perf_counter()
    res = run_sweep_file(tmp_path / "SWEEP.toml", tmp_path / "out")
    assert time.perf_counter() - start < 8.0  # not 60 s
    assert [(f.index, f.type) for f in res.sweep.failures] == [(1, "Timeout")]
    rows = res.csv.read_text().splitlines()
    assert rows[2].split(",")[4:6] == ["error", "Timeout"] and rows[1].endswith(",0.25")


def test_sweep_file_sampling_resumes_and_refuses_another_seed(tmp_path, slow_registry):
    text = (
        SLOW_TOML.split("[grid]")[0]
        + "[options.slow]\npause = 0.0\n"
        + (
            "[sampling]\nn_samples = 6\nseed = 2\n[sampling.distributions]\nrho = {uniform = [0.1, 0.5]}\n"
            "K = {choice = [0.2, 0.4]}\n"
        )
    )
    (tmp_path / "SWEEP.toml").write_text(text)
    first = run_sweep_file(tmp_path / "SWEEP.toml", tmp_path / "out")
    again = run_sweep_file(tmp_path / "SWEEP.toml", tmp_path / "out")
    assert again.sweep == first.sweep and again.sweep.executor == "resumed: nothing to run"
    assert again.quantiles == first.quantiles and len((tmp_path / "out" / JOURNAL).read_text().splitlines()) == 7
    (tmp_path / "SWEEP.toml").write_text(text.replace("seed = 2", "seed = 3"))
    with pytest.raises(ParameterError, match=r"changed: points\.sha256"):
        run_sweep_file(tmp_path / "SWEEP.toml", tmp_path / "out")


HANG_SCRIPT = """
import time, nrobust
def hang(a):
    time.sleep(600)
if __name__ == "__main__":
    nrobust.sweep(hang, nrobust.grid(a=[1]), "serial", timeout=500)
"""


def _children(pid: int) -> list[int]:
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return "gone"


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl(PR_SET_PDEATHSIG) is Linux's")
def test_a_hung_point_process_dies_with_a_killed_sweep(tmp_path):
    (tmp_path / "hang.py").write_text(HANG_SCRIPT)
    proc = subprocess.Popen([sys.executable, str(tmp_path / "hang.py")])
    try:
        deadline = time.monotonic() + 60
        while not (kids := _children(proc.pid)):
            assert proc.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
    finally:
        proc.kill()
        proc.wait()
    deadline = time.monotonic() + 5
    while any(_state(k) not in ("Z", "X", "gone") for k in kids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert all(_state(k) in ("Z", "X", "gone") for k in kids)  # dead (a zombie waits for its new parent)
