"""``nrobust design`` with ``family = "state_feedback"`` and, for an ``NPlusMSystem`` file, ``family = "nplusm"``.

The plant is the coupled 2x2 plant ``Hyperbolic2x2(1, 1, 1.5, 0.5, 0.8, 0.4)`` (as an ``NPlusMSystem``
for ``"nplusm"``: ``K = [[k]]`` is ``StateFeedback(k)``). The proportional law ``U = k u(t, 1)`` has a
loop affine in ``k``, so the core's exact one-gain engine (``best_decay_rate`` / ``best_margin`` on the
scalar loop of the kernel route, from the equations of its kind) is the oracle of both commands.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from nrobust.cli import main
from nrobust.config import Monomial, load_system_file
from nrobust.design import best_decay_rate, best_margin
from nrobust.errors import ParameterError
from nrobust.hyperbolic.analyses.margin import delay_margin
from nrobust.hyperbolic.analyses.state_design import BasisGain, state_feedback_loop
from nrobust.hyperbolic.loops.controllers import StateFeedback
from nrobust.hyperbolic.plants.hyperbolic2x2 import Hyperbolic2x2
from nrobust.margins.gain import AffineGainLoop

PLANT = Hyperbolic2x2(1.0, 1.0, 1.5, 0.5, 0.8, 0.4)
STATE_TOML = """
[system]
type = "Hyperbolic2x2"
lam = 1.0
mu = 1.0
sigma_pm = 1.5
sigma_mp = 0.5
q = 0.8
rho = 0.4

[controller]
type = "StateFeedback"
k = -0.5

[analysis]
delta_max = 2.0

[design]
family = "state_feedback"
objective = "decay_rate"
margin_at_least = 1.0
k_bounds = [-0.8, -0.3]
starts = 1
"""
NPLUSM_TOML = """
[system]
type = "NPlusMSystem"
lam = [1.0]
mu = [1.0]
sigma = [[0.0, 1.5], [0.5, 0.0]]
q = [[0.8]]
r = [[0.4]]

[controller]
type = "Cancellation"
fractions = [[0.0]]

[analysis]
region = [-3.0, 1.0, 0.0, 40.0]

[design]
family = "nplusm"
objective = "margin"
delays = [0.5, 1.2]
K_bounds = [-0.8, -0.3]
x0 = [[-0.4]]
starts = 1
max_iter = 10
"""


def _affine() -> AffineGainLoop:
    loop = state_feedback_loop(PLANT)
    return AffineGainLoop(loop.A, loop.units[0] * 0.0, loop.units[0])


def _run(tmp_path: Path, toml: str, *options: str) -> tuple[Path, str, dict]:
    tmp_path.mkdir(exist_ok=True)
    system = tmp_path / "SYSTEM.toml"
    system.write_text(toml)
    out = tmp_path / "out"
    assert main(["design", str(system), "-o", str(out), *options]) == 0
    return out, (out / "design.md").read_text(), json.loads((out / "design.json").read_text())


def test_state_feedback_command_agrees_with_the_exact_scalar_design(tmp_path: Path) -> None:
    """The proportional state feedback (no basis) with the best decay rate under ``delta* >= 1``.

    The decay rate rises with ``k`` from the end ``k = -0.5489`` where the margin is 1 to a peak at
    ``k = -0.51077`` (margin 1.087) and falls after it; the one-gain engine finds that peak from 9 samples
    of the rate per feasible interval (with its default 5 it keeps the end, rate 1.0621 against 1.2060).
    The local search stops with pattern steps of ``1e-5`` of the width 0.5, so ``k`` agrees to ``1e-5``
    (measured 3e-6) and the rate, with slopes about 4 on either side of the peak, to ``5e-5`` (measured
    1.3e-5). The report names ``k``, ``g_u``, ``g_v``, the certificate and the figure. About 20 s of CPU
    time."""
    out, text, data = _run(tmp_path, STATE_TOML)
    exact = best_decay_rate(_affine(), (-0.8, -0.3), margin_at_least=1.0, n_rates=9)
    assert data["family"] == "state_feedback" and data["margin_at_least"] == 1.0
    k = data["controller"]["k"]
    np.testing.assert_allclose(k, exact.K, atol=1e-5)
    np.testing.assert_allclose(data["design"]["decay_rate"], exact.decay_rate, atol=5e-5)
    assert data["design"]["decay_rate"] <= exact.decay_rate + 1e-9  # feasible: never above the optimum
    assert data["design"]["certified"] and data["design"]["margin"]["margin"] >= 1.0
    assert text.startswith("# Design of the state feedback U = k u(t, L) + int g_u u + g_v v dx for SYSTEM.toml")
    assert f"- designed gain: k = {k!r}" in text
    assert "- g_u coefficients: []" in text and "- g_v coefficients: []" in text and "- certified: yes" in text
    assert (out / "design.png").stat().st_size > 0 and "](design.png)" in text


@pytest.mark.long  # about a minute of CPU: make fuzz runs it
@pytest.mark.slow
def test_state_feedback_command_with_a_basis(tmp_path: Path) -> None:
    """With ``basis = [0]`` (constant ``g_u``, ``g_v``) on 51 kernel points: the first start is the exact
    proportional optimum (decay rate 1.2060), so the design is at least that good to the local search's
    last step (measured 1.8187, margin 1.0000004); the designed controller, rebuilt from ``design.json``
    and analysed by ``delay_margin(plant, controller, kernel_grid=51)`` (the loop of the law itself, not
    the sum of unit gains the design uses), has the margin the report states, to the crossing search's
    accuracy (``1e-9``, measured 1e-12). About 60 s of CPU time."""
    toml = STATE_TOML.replace(
        "starts = 1", "starts = 1\nbasis = [0]\ncoefficient_bounds = [-0.5, 0.5]\nkernel_grid = 51"
    )
    out, text, data = _run(tmp_path, toml)
    design = data["design"]
    assert design["certified"] and design["margin"]["margin"] >= 1.0
    assert design["decay_rate"] >= 1.2060 - 1e-4
    k, c, d = data["parameters"]
    assert f"- g_u coefficients: [{c!r}]" in text and f"- g_v coefficients: [{d!r}]" in text
    assert "basis of g_u and g_v: (x/L)^0" in text and (out / "design.png").stat().st_size > 0
    controller = StateFeedback(k, BasisGain((c,), (Monomial(0),)), BasisGain((d,), (Monomial(0),)))
    check = delay_margin(PLANT, controller, kernel_grid=51)
    np.testing.assert_allclose(check.margin, design["margin"]["margin"], atol=1e-9)


def test_nplusm_command_with_a_window(tmp_path: Path) -> None:
    """The largest margin of ``U = K u(t - delta, 1)`` stable on ``[0.5, 1.2]``, ``K`` in ``[-0.8, -0.3]``:
    the margin rises with ``k`` to the upper bound (the exact engine: ``k = -0.3``, margin 1.860594), where
    the window holds. The local design reaches the bound to its last pattern step, ``1e-5`` of the width
    (the margin's slope about 4 there: ``5e-5``). About 6 s of CPU time."""
    out, text, data = _run(tmp_path, NPLUSM_TOML)
    exact = best_margin(_affine(), (-0.8, -0.3))
    assert data["family"] == "nplusm" and data["delays"] == [[0.5, 1.2]] and data["certified"]
    np.testing.assert_allclose(data["K"][0][0], exact.K, atol=1e-5)
    np.testing.assert_allclose(data["value"], exact.margin, atol=5e-5)
    assert data["windows"][0]["stable"] and data["windows"][0]["certified"]
    assert text.startswith("# Design of the gain matrix K of U = K u(t - delta, 1) for SYSTEM.toml")
    assert "- designed gain: K = [[" in text and "window [0.5, 1.2]: stable, certified" in text
    assert "- certified: yes" in text and (out / "design.png").stat().st_size > 0


def test_the_command_line_overrides_the_nplusm_file(tmp_path: Path) -> None:
    """``--k-bounds`` and ``--family nplusm`` reach the design (the bounds pin the gain: one point wide
    around the bound of the file), a ``--speed-tolerance`` outside ``(0, 1)`` is refused (exit code 2)."""
    system = tmp_path / "SYSTEM.toml"
    system.write_text(NPLUSM_TOML.replace("x0 = [[-0.4]]\n", ""))
    assert main(["design", str(system), "-o", str(tmp_path / "bad"), "--speed-tolerance", "1.5"]) == 2
    assert main(["design", str(system), "-o", str(tmp_path / "sf"), "--family", "state_feedback"]) == 2
    state = tmp_path / "STATE.toml"
    state.write_text(STATE_TOML)
    assert main(["design", str(state), "-o", str(tmp_path / "nm"), "--family", "nplusm"]) == 2
    assert not (tmp_path / "bad").exists() or not any((tmp_path / "bad").iterdir())


@pytest.mark.parametrize(
    ("old", "new", "name", "message"),
    [
        ("k_bounds = [-0.8, -0.3]", "k_bound = [-0.8, -0.3]", "design.k_bound", "did you mean 'k_bounds'"),
        ("k_bounds = [-0.8, -0.3]", "k_bounds = [-0.3, -0.8]", "design.k_bounds", "low < high"),
        ("starts = 1", "basis = [0, 0]", "design.basis", "distinct integer powers"),
        ("starts = 1", "basis = [0.5]", "design.basis", "distinct integer powers"),
        ("starts = 1", "coefficient_bounds = [1.0]", "design.coefficient_bounds", "low, high"),
        ("starts = 1", "kernel_grid = 20.5", "design.kernel_grid", "integer"),
        ("starts = 1", "K = [-0.1, 0.1]", "design.K", 'family = "state_feedback"'),
        # k_bounds, read first, is the first key the family does not take
        ('family = "state_feedback"', 'family = "reflection"\nbasis = [0]', "design.k_bounds", "state_feedback"),
        ('family = "state_feedback"', 'family = "nplusm"', "design.family", "NPlusMSystem"),
        ('family = "state_feedback"', 'family = "state_feedbak"', "design.family", "did you mean 'state_feedback'"),
    ],
)
def test_state_feedback_section_errors(tmp_path: Path, old: str, new: str, name: str, message: str) -> None:
    system = tmp_path / "SYSTEM.toml"
    assert old in STATE_TOML
    system.write_text(STATE_TOML.replace(old, new))
    with pytest.raises(ParameterError, match=message) as info:
        load_system_file(system)
    assert info.value.name == name


@pytest.mark.parametrize(
    ("old", "new", "name", "message"),
    [
        ("starts = 1", "start = 1", "design.start", "did you mean 'starts'"),
        ('family = "nplusm"', 'family = "reflection"', "design.family", '"nplusm" for an NPlusMSystem'),
        ("K_bounds = [-0.8, -0.3]", "K_bounds = [[-0.8, -0.3, 0.0]]", "design.K_bounds", "1 rows of 1 pairs"),
        ("x0 = [[-0.4]]", "x0 = [-0.4]", "design.x0", "1 rows of 1 numbers"),
        ("delays = [0.5, 1.2]", "delays = [1.2, 0.5]", "design.delays", "d_min <= d_max"),
        ("delays = [0.5, 1.2]", "delays = [[0.0, 0.2], [0.5]]", "design.delays[1]", "d_min"),
        ('objective = "margin"', 'objective = "decay"', "design.objective", "decay_rate"),
        ("starts = 1", "starts = 0", "design.starts", "integer in"),
    ],
)
def test_nplusm_section_errors(tmp_path: Path, old: str, new: str, name: str, message: str) -> None:
    system = tmp_path / "SYSTEM.toml"
    assert old in NPLUSM_TOML
    system.write_text(NPLUSM_TOML.replace(old, new))
    with pytest.raises(ParameterError, match=message) as info:
        load_system_file(system)
    assert info.value.name == name


def test_the_sections_are_read() -> None:
    """The basis powers become functions ``(x / L)^j`` of the plant's length."""
    phi = Monomial(2, 2.0)
    np.testing.assert_array_equal(phi(np.array([0.0, 1.0, 2.0])), [0.0, 0.25, 1.0])
    assert phi.__name__ == "(x/2)^2" and Monomial(1).__name__ == "x^1"


def test_nplusm_file_design_section_is_read(tmp_path: Path) -> None:
    system = tmp_path / "SYSTEM.toml"
    system.write_text(NPLUSM_TOML.replace("K_bounds = [-0.8, -0.3]", "K_bounds = [[[-0.8, -0.3]]]"))
    design = load_system_file(system)["design"]
    assert design["family"] == "nplusm" and design["delays"] == ((0.5, 1.2),)
    assert design["K_bounds"] == [[(-0.8, -0.3)]] and design["x0"] == [[-0.4]] and design["starts"] == 1
