"""Defects a user meets in the first minutes: orphaned workers, unbounded work, raw errors.

Each test reproduces what a user did and checks what they should have seen.
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from nrobust.cli import main
from nrobust.config import CONTROLLER_TYPES, SYSTEM_TYPES, load_system_file
from nrobust.errors import ParameterError
from nrobust.hyperbolic.analyses import (
    MAX_CHART_POINTS,
    MAX_GAINS,
    ab_region,
    delay_margin,
    k_region,
    stability_chart,
)
from nrobust.hyperbolic.loops.controllers import (
    CollocatedOutputFeedback,
    OpenLoop,
    OutputFeedback,
    characteristic,
    classify,
)
from nrobust.hyperbolic.nplusm import NPlusMSystem
from nrobust.hyperbolic.plants import GeneralHyperbolic2x2, Hyperbolic2x2, TransportSystem
from nrobust.hyperbolic.simulate import simulate
from nrobust.plots.charts import sweep_chart
from nrobust.reports.certificate import certify
from nrobust.sweeps import grid, sweep
from nrobust.sweeps.sweepfile import run_sweep_file

# ---------------------------------------------------------------------------------------
# the workers of a sweep end with the sweep, even killed by SIGKILL
# ---------------------------------------------------------------------------------------

_SWEEP_SCRIPT = """
import time

from nrobust.sweeps import sweep


def slow(x):
    time.sleep(60)
    return {"x": x}


if __name__ == "__main__":
    sweep(slow, [{"x": k} for k in range(4)], executor=2, chunksize=1, timeout=120, progress=False)
"""


def _stat(pid: int) -> list[str] | None:
    """Fields 3.. of /proc/<pid>/stat (state, ppid, ...); None when the process is gone."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return text[text.rindex(")") + 2 :].split()


def _descendants(root: int) -> dict[int, str]:
    """Process id -> start time of every descendant of ``root`` (the pair names a process for good)."""
    parents: dict[int, list[int]] = {}
    starts: dict[int, str] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit() and (fields := _stat(int(entry))) is not None:
            parents.setdefault(int(fields[1]), []).append(int(entry))
            starts[int(entry)] = fields[19]
    found: dict[int, str] = {}
    todo = [root]
    while todo:
        for child in parents.get(todo.pop(), []):
            found[child] = starts[child]
            todo.append(child)
    return found


def _running(pid: int, start: str) -> bool:
    """Whether the process ``pid`` started at ``start`` still runs (a zombie does not: no reaper may be around)."""
    fields = _stat(pid)
    return fields is not None and fields[19] == start and fields[0] not in ("Z", "X")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the process tree in /proc")
@pytest.mark.timeout(60)  # a loaded machine slows the start of the workers, never the check below
def test_sigkill_of_the_sweep_process_ends_its_workers_and_point_processes(tmp_path):
    script = tmp_path / "sweep_script.py"
    script.write_text(textwrap.dedent(_SWEEP_SCRIPT))
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    proc = subprocess.Popen([sys.executable, str(script)], env=env)
    try:
        # two workers, each with the point process it forked for the timeout
        deadline = time.monotonic() + 40
        tree: dict[int, str] = {}
        while time.monotonic() < deadline and proc.poll() is None and len(tree) < 4:
            time.sleep(0.05)
            tree = _descendants(proc.pid)
        assert len(tree) >= 4, f"the sweep did not start its workers and point processes: {tree}"
        time.sleep(0.3)  # let the start of the pool settle (a forkserver start method adds processes)
        tree = _descendants(proc.pid)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        # 5 s: the workers wait on a pidfd of the sweep, so they leave within milliseconds
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and any(_running(p, s) for p, s in tree.items()):
            time.sleep(0.05)
        alive = [pid for pid, start in tree.items() if _running(pid, start)]
        assert alive == [], f"processes of the killed sweep still running: {alive}"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for pid, start in tree.items():
            if _running(pid, start):
                os.kill(pid, signal.SIGKILL)


# ---------------------------------------------------------------------------------------
# bad input: a ParameterError within seconds, before any large allocation
# ---------------------------------------------------------------------------------------


def _plant() -> Hyperbolic2x2:
    return Hyperbolic2x2(1.0, 1.0, 0.5, 0.5, 1.0, 0.5)


def _refused_quickly(call: Callable[[], object], match: str) -> ParameterError:
    """Run ``call``: it must raise a ParameterError matching ``match`` within 2 s having
    allocated less than 64 MB (numpy reports its arrays to tracemalloc)."""
    tracemalloc.start()
    start = time.perf_counter()
    try:
        with pytest.raises(ParameterError, match=match) as info:
            call()
        elapsed = time.perf_counter() - start
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert elapsed < 2.0, f"refused after {elapsed:.2f} s"
    assert peak < 64 * 2**20, f"{peak / 2**20:.0f} MB allocated before the refusal"
    return info.value


def test_k_region_refuses_a_billion_gains_naming_n_gains_and_its_range():
    error = _refused_quickly(lambda: k_region(_plant(), 0.1, n_gains=10**9), r"n_gains must be")
    assert error.name == "n_gains" and f"[3, {MAX_GAINS}]" in str(error)


def test_k_region_refuses_a_gain_grid_longer_than_max_gains():
    error = _refused_quickly(lambda: k_region(_plant(), 0.1, Ks=np.linspace(-0.4, 0.4, MAX_GAINS + 1)), "MAX_GAINS")
    assert error.name == "Ks"


def test_stability_chart_refuses_a_grid_beyond_max_chart_points():
    axis = np.linspace(0.0, 0.4, 10**5)
    error = _refused_quickly(lambda: stability_chart(_plant(), axis, axis), f"MAX_CHART_POINTS = {MAX_CHART_POINTS}")
    assert error.name == "Ks, deltas" and "100000 x 100000" in str(error)


def test_ab_region_refuses_a_grid_beyond_max_chart_points():
    error = _refused_quickly(lambda: ab_region(_plant(), 0.1, np.zeros(2000), np.ones(1000)), "MAX_CHART_POINTS")
    assert error.name == "a, b"


def _divide_by_zero(x: object) -> float:
    return 1 / 0


@pytest.mark.parametrize(
    ("build", "name"),
    [
        (lambda: Hyperbolic2x2(1, 1, _divide_by_zero, 1, 1, 0.5), "sigma_pm"),
        (lambda: Hyperbolic2x2(1, 1, 1, _divide_by_zero, 1, 0.5), "sigma_mp"),
        (lambda: GeneralHyperbolic2x2(1, 1, _divide_by_zero, 0, 0, 0, 1, 0.5), "a"),
        (lambda: GeneralHyperbolic2x2(1, _divide_by_zero, 0, 0, 0, 0, 1, 0.5), "mu"),
    ],
)
def test_a_coefficient_callable_that_raises_is_a_parameter_error_naming_it(build, name):
    with pytest.raises(ParameterError, match=rf"^{name} must be a callable returning real numbers") as info:
        build()
    assert info.value.name == name
    assert "ZeroDivisionError" in str(info.value) and "x = 0" in str(info.value)
    assert isinstance(info.value.__cause__, ZeroDivisionError)


# ---------------------------------------------------------------------------------------
# simulate: numbers as initial states, and an omitted one as in SYSTEM.toml
# ---------------------------------------------------------------------------------------

# The open transport loop u_t + u_x = 0, v_t - v_x = 0, u(t, 0) = q v(t, 0),
# v(t, 1) = rho u(t, 1), from u = v = 1: at t = 1/2 < 1 (one transport time) u = q on
# [0, t] and 1 beyond, v = 1 on [0, 1 - t] and rho beyond, so
# ||(u, v)||^2 = (1 - t) + q^2 t + (1 - t) + rho^2 t.
_Q, _RHO, _T = 1.0, 0.5, 0.5
_EXACT_NORM = math.sqrt((1 - _T) + _Q**2 * _T + (1 - _T) + _RHO**2 * _T)
# The trapezoidal norm on 200 cells straddles the jump of v^2 (1 - rho^2 = 0.75) with one
# cell: at most 0.75 / 200 / 2 in the square, 0.75 / 400 / (2 ||.||) = 7.4e-4 in the norm.
_NORM_ATOL = 1e-3


def test_simulate_takes_numbers_and_says_what_to_give_for_a_state_left_out():
    plant = TransportSystem(1.0, 1.0, _Q, _RHO)
    run = simulate(plant, OpenLoop(), 0.0, _T, 1.0, 1.0, 200)
    np.testing.assert_allclose(run.times[-1], _T, rtol=1e-12)
    np.testing.assert_allclose(run.norm[-1], _EXACT_NORM, atol=_NORM_ATOL)
    with pytest.raises(ParameterError, match=r"^v0 must be given: a number \(a constant state") as info:
        simulate(plant, OpenLoop(), 0.0, _T, u0=1.0, cells=200)
    assert info.value.name == "v0"


def test_simulate_takes_a_number_as_the_state_of_an_n_plus_m_system():
    system = NPlusMSystem([1.0], [1.0], np.zeros((2, 2)), [[_Q]], [[_RHO]])
    run = simulate(system, None, 0.0, _T, u0=1.0, cells=200)
    np.testing.assert_allclose(run.norm[-1], _EXACT_NORM, atol=_NORM_ATOL)
    with pytest.raises(ParameterError, match="w0 must be a number or a callable"):
        simulate(system, None, 0.0, _T, u0=True)


# ---------------------------------------------------------------------------------------
# TOML: suggestions for unknown keys; type lists from the registries
# ---------------------------------------------------------------------------------------

_SYSTEM_TOML = """
[system]
type = "Hyperbolic2x2"
lam = 1.0
mu = 1.0
sigma_pm = 0.5
sigma_mp = 0.5
q = 1.0
rho = 0.5

[controller]
type = "FiniteTimeController"

[analysis]
delta_max = 0.1
"""


@pytest.mark.parametrize(
    ("old", "new", "key", "suggestion"),
    [
        ("lam = 1.0", "lamda = 1.0", "system.lamda", "lam"),
        ('type = "Hyperbolic2x2"', 'type = "Hyperbolic2X2"', "system.type", "Hyperbolic2x2"),
        ("[analysis]\ndelta_max", "[analysis]\ndelta_mx", "analysis.delta_mx", "delta_max"),
        ("[analysis]", "[simulaton]\nt_end = 1.0\n[analysis]", "simulaton", "simulation"),
        ("sigma_pm = 0.5", "sigma_pm = {x = [0.0, 1.0], value = [1.0, 1.0]}", "system.sigma_pm", "values"),
        ('type = "Hyperbolic2x2"', 'type = "NPlusMSytem"', "system.type", "NPlusMSystem"),
    ],
)
def test_an_unknown_key_of_system_toml_suggests_the_close_ones(tmp_path, old, new, key, suggestion):
    path = tmp_path / "SYSTEM.toml"
    assert old in _SYSTEM_TOML
    path.write_text(_SYSTEM_TOML.replace(old, new, 1))
    with pytest.raises(ParameterError, match=f"did you mean '{suggestion}'") as info:
        load_system_file(path)
    assert info.value.name == key


def test_an_unknown_key_of_sweep_toml_suggests_the_close_ones(tmp_path):
    path = tmp_path / "SWEEP.toml"
    path.write_text(_SWEEP_TOML.replace("[grid]", "[grid]\nrh = [0.5]").replace("rho = [0.5]\n", ""))
    with pytest.raises(ParameterError, match="did you mean 'rho'") as info:
        run_sweep_file(path, tmp_path / "out")
    assert info.value.name == "grid.rh"
    path.write_text(_SWEEP_TOML.replace('executor = "serial"', 'executer = "serial"'))
    with pytest.raises(ParameterError, match="did you mean 'executor'"):
        run_sweep_file(path, tmp_path / "out")


def test_the_types_a_plant_and_a_controller_may_be_are_all_listed():
    with pytest.raises(ParameterError) as info:
        delay_margin(_plant(), 3)
    for cls in CONTROLLER_TYPES.values():
        assert cls.__name__ in str(info.value)
    with pytest.raises(ParameterError) as info:
        delay_margin(3, 3)
    for build in SYSTEM_TYPES.values():
        if isinstance(build, type):  # the front ends are functions returning a GeneralHyperbolic2x2
            assert build.__name__ in str(info.value)


# every entry point that takes a plant and a controller (the observer-based laws included)
_ENTRY_POINTS = {"delay_margin": delay_margin, "characteristic": characteristic, "certify": certify}


@pytest.mark.parametrize("name", sorted(_ENTRY_POINTS))
def test_a_refused_controller_is_told_every_public_controller_and_no_private_name(name):
    with pytest.raises(ParameterError) as info:
        _ENTRY_POINTS[name](_plant(), 3)
    message = str(info.value)
    for cls in (*CONTROLLER_TYPES.values(), OutputFeedback, CollocatedOutputFeedback):
        assert cls.__name__ in message
    assert not re.search(r"\b_[A-Za-z]", message), message


@pytest.mark.parametrize("call", [classify, lambda system: certify(system, OpenLoop())])
def test_a_refused_plant_is_told_the_general_plant_too(call):
    """classify and certify take a GeneralHyperbolic2x2 (through its normal form): their refusal says so."""
    with pytest.raises(ParameterError, match="GeneralHyperbolic2x2") as info:
        call(3)
    assert info.value.name == "system"


# ---------------------------------------------------------------------------------------
# sweeps: the verified column, infinite margins on the chart, the resume message
# ---------------------------------------------------------------------------------------

# |K q| < 1 - |rho q| (K = 0.1): every delay is tolerated (eq. (54)), an infinite margin
# with no crossing to check; |rho q| + |K q| > 1 (K = 0.8): the difference operator is not
# strongly stable, a zero margin decided without a crossing: nothing to verify either
_SWEEP_TOML = """analysis = "delay_margin"
executor = "serial"
[system]
type = "TransportSystem"
lam = 1.0
mu = 1.0
q = 1.0
[controller]
type = "ReflectionController"
[grid]
K = [0.1, 0.8]
rho = [0.5]
"""


def test_the_verified_column_says_not_needed_for_an_infinite_margin_and_a_rerun_says_it_resumed(tmp_path, capsys):
    (tmp_path / "SWEEP.toml").write_text(_SWEEP_TOML)
    out = tmp_path / "out"
    args = ["sweep", str(tmp_path / "SWEEP.toml"), "-o", str(out), "--no-progress"]
    assert main(args) == 0
    assert "resumed" not in capsys.readouterr().out
    rows = json.loads((out / "sweep.json").read_text())["rows"]
    assert [row["delta_star"] for row in rows] == ["inf", 0.0]
    # analyze's words ("not needed: infinite, no crossing frequency"; "not needed: zero, decided without a
    # crossing frequency"), not False
    assert [row["verified"] for row in rows] == ["not needed", "not needed"]
    csv_rows = [line.split(",") for line in (out / "sweep.csv").read_text().splitlines()]
    column = csv_rows[0].index("verified")
    assert [row[column] for row in csv_rows[1:]] == ["not needed", "not needed"]
    assert main(args) == 0
    assert f"resumed: kept 2 of 2 points from {out / 'sweep.jsonl'}" in capsys.readouterr().out


def _unit_margin(a: float, b: float) -> dict[str, float]:
    return {"margin": math.inf if a + b > 1.5 else a + b}


def test_the_sweep_chart_draws_an_infinite_margin_apart_from_the_scale_with_a_legend_entry():
    result = sweep(_unit_margin, grid(a=[0.0, 0.5, 1.0], b=[0.0, 0.5, 1.0]), executor="serial", progress=False)
    fig = sweep_chart(result, ["a", "b"], {}, False)
    ax = fig.axes[0]
    legend = ax.get_legend()
    assert legend is not None and "margin = inf" in [t.get_text() for t in legend.get_texts()]
    # the colour-mapped cells: the infinite ones (a + b = 2) are masked off the scale,
    # whose top is the largest finite value
    scaled = ax.collections[0]
    values = np.ma.getmaskarray(scaled.get_array()).reshape(3, 3)
    np.testing.assert_array_equal(values, [[False, False, False], [False, False, False], [False, False, True]])
    np.testing.assert_allclose(scaled.norm.vmax, 1.5, rtol=0, atol=0)


def _zero_margin(a: float, b: float) -> dict[str, float]:
    return {"margin": math.inf if a > 0.5 else 0.0}


def test_a_sweep_chart_with_one_finite_value_has_a_scale_above_it():
    # every finite margin is 0: matplotlib's own scale would run from -0.1 to 0.1 (negative margins)
    result = sweep(_zero_margin, grid(a=[0.0, 1.0], b=[0.0, 1.0]), executor="serial", progress=False)
    scaled = sweep_chart(result, ["a", "b"], {}, False).axes[0].collections[0]
    assert (scaled.norm.vmin, scaled.norm.vmax) == (0.0, 1.0)


def test_a_geometric_sweep_axis_is_drawn_in_log_scale_with_cells_centred_on_their_samples():
    """K = 1e-3, 1e-2, 1e-1 (a geometric sweep): cells end at the geometric means (10^-2.5,
    10^-1.5), not at the arithmetic midpoints (0.0055, 0.055) that would give the first sample a
    sliver and the last a wide cell; the even axis b keeps linear cells; the samples are marked."""
    result = sweep(_unit_margin, grid(a=[1e-3, 1e-2, 1e-1], b=[0.0, 0.5, 1.0]), executor="serial", progress=False)
    ax = sweep_chart(result, ["a", "b"], {}, False).axes[0]
    assert ax.get_xscale() == "log" and ax.get_yscale() == "linear"
    corners = ax.collections[0].get_coordinates()  # (rows + 1, columns + 1, 2): the cells' corners
    np.testing.assert_allclose(corners[0, :, 0], [10**-3.5, 10**-2.5, 10**-1.5, 10**-0.5], rtol=1e-12)
    np.testing.assert_allclose(corners[:, 0, 1], [-0.25, 0.25, 0.75, 1.25], rtol=0, atol=1e-15)
    dots = [line for line in ax.get_lines() if line.get_marker() == "."]
    assert len(dots) == 1 and len(dots[0].get_xdata()) == 9


def test_a_resumed_sweep_says_how_many_points_it_kept_from_which_journal(tmp_path, caplog):
    journal = tmp_path / "sweep.jsonl"
    points = grid(a=[0.0, 0.5], b=[0.0, 0.5, 1.0])
    first = sweep(_unit_margin, points, executor="serial", progress=False, results=journal)
    assert first.resumed == ""
    with caplog.at_level(logging.INFO, logger="nrobust.sweeps.engine"):
        again = sweep(_unit_margin, points, executor="serial", progress=False, results=journal)
    message = f"resumed: kept 6 of 6 points from {journal}"
    assert again.resumed == message and message in caplog.messages
    assert again == first
    fresh = sweep(_unit_margin, points, executor="serial", progress=False, results=journal, restart=True)
    assert fresh.resumed == ""
