"""``nrobust design`` with ``family = "collocated_output_feedback"``: U_BS2(K) on the collocated observer's estimate.

The plant is the transport plant ``TransportSystem(1, 1, 1, 0.85)`` (no coupling: the observer is exact and
the loop is in closed form). With ``observer_delay = 0`` the loop at ``delta = 0`` is ``1 - (rho - K) q
e^{-tau s}``, ``tau = 1/lam + 1/mu = 2`` (``A = 1 - rho q E + K q E - K rho q^2 E^2``, ``B = K rho q^2 E^2``,
``E = e^{-tau s}``): its decay rate is ``-ln|(rho - K) q| / tau`` in closed form, largest at the upper end of
the gains, and the default bounds are 0.9 times the ends of the strong-stability interval ``|rho - K| |q| +
2 |K rho| q^2 < 1``: ``(-0.15/2.7, 0.15/0.7)`` (with ``observer_delay > 0``: ``|rho q| + |K q| + 2 |K rho|
q^2 < 1``, ``+-0.15/2.7``). On this plant ``|A| > |B|`` on the axis wherever the difference operator is
strongly stable, so every gain has an infinite margin and the window ``[0, 0.5]`` holds. Each design of the
command is also compared with the direct call of ``design_reflection(..., output_feedback=True,
collocated=True)``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import nrobust as nr
from nrobust.cli import main
from nrobust.config import load_system_file
from nrobust.errors import ParameterError
from nrobust.hyperbolic.analyses.design import design_reflection
from nrobust.hyperbolic.loops.controllers import CollocatedOutputFeedback

RHO = 0.85
PLANT = nr.TransportSystem(1.0, 1.0, 1.0, RHO)
SYSTEM_TOML = f"""
[system]
type = "TransportSystem"
lam = 1.0
mu = 1.0
q = 1.0
rho = {RHO}

[controller]
type = "ReflectionController"
K = 0.1

[analysis]
delta_max = 0.5

[design]
family = "collocated_output_feedback"
objective = "decay_rate"
delays = [0.0, 0.5]
"""


def _run(tmp_path: Path, toml: str, *options: str) -> tuple[str, dict]:
    tmp_path.mkdir(exist_ok=True)
    system = tmp_path / "SYSTEM.toml"
    system.write_text(toml)
    out = tmp_path / "out"
    assert main(["design", str(system), "-o", str(out), *options]) == 0
    return (out / "design.md").read_text(), json.loads((out / "design.json").read_text())


def test_design_command_for_the_collocated_output_feedback(tmp_path: Path) -> None:
    """The gain at the upper end of the default bounds, the decay rate in closed form, as the direct call."""
    text, data = _run(tmp_path, SYSTEM_TOML)
    assert text.startswith("# Design of U_BS2(K) on the collocated observer's estimate from u(t, 1)")
    assert "requirement: exponentially stable for every delay in [0.0, 0.5]: met" in text
    assert data["family"] == "collocated_output_feedback" and data["delays"] == [0.0, 0.5]
    controller = data["controller"]
    assert controller["controller"] == "CollocatedOutputFeedback" and controller["observer_delay"] == 0.0
    K = controller["state_feedback"]["K"]
    # 0.9 times the closed-form end 0.15/0.7 (the bounds are that product, to rounding)
    np.testing.assert_allclose(K, 0.9 * 0.15 / 0.7, rtol=1e-14)
    # the decay rate -ln((rho - K) q)/tau, tau = 2: the abscissa of a difference equation in closed form,
    # computed to about 1e-15 relative (the certified abscissa's accuracy)
    np.testing.assert_allclose(data["design"]["value"], -math.log(RHO - K) / 2.0, rtol=1e-12)
    direct = design_reflection(PLANT, "decay_rate", delays=(0.0, 0.5), output_feedback=True, collocated=True)
    assert isinstance(direct.controller, CollocatedOutputFeedback)
    assert direct.K == K and direct.value == data["design"]["value"]


def test_design_command_passes_the_bounds_objective_and_observer_delay(tmp_path: Path) -> None:
    """``--k-bounds`` overrides the file; ``margin_at_least`` and ``observer_delay`` reach the design."""
    _, data = _run(tmp_path, SYSTEM_TOML, "--k-bounds", "-0.05", "0.1")
    K = data["controller"]["state_feedback"]["K"]
    assert K == 0.1  # the upper bound given
    np.testing.assert_allclose(data["design"]["value"], -math.log(RHO - 0.1) / 2.0, rtol=1e-12)
    delayed = SYSTEM_TOML.replace("delays = [0.0, 0.5]\n", "margin_at_least = 0.5\nobserver_delay = 0.1\n")
    _, data = _run(tmp_path / "observer", delayed)
    assert data["margin_at_least"] == 0.5 and data["delays"] is None
    controller = data["controller"]
    assert controller["controller"] == "CollocatedOutputFeedback" and controller["observer_delay"] == 0.1
    direct = design_reflection(
        PLANT, "decay_rate", margin_at_least=0.5, output_feedback=True, collocated=True, observer_delay=0.1
    )
    assert isinstance(direct.controller, CollocatedOutputFeedback) and direct.controller.observer_delay == 0.1
    assert controller["state_feedback"]["K"] == direct.K and data["design"]["value"] == direct.value
    # the default bounds with an observer delay: 0.9 times +-0.15/2.7, in closed form
    np.testing.assert_allclose(data["design"]["bounds"], [-0.9 * 0.15 / 2.7, 0.9 * 0.15 / 2.7], rtol=1e-14)


@pytest.mark.parametrize(
    ("extra", "name"),
    [
        ("speed_tolerance = 0.1", "design.speed_tolerance"),  # as for "output_feedback"
        ("a = 0.1", "design.a"),  # U_BS2(K) has no filter
        ("K = 0.1", "design.K"),  # K is designed: bounds
        ("observer_delay = -0.1", "design.observer_delay"),
    ],
)
def test_design_section_checks_the_collocated_family(tmp_path: Path, extra: str, name: str) -> None:
    system = tmp_path / "SYSTEM.toml"
    system.write_text(SYSTEM_TOML + extra + "\n")
    with pytest.raises(ParameterError, match=name):
        load_system_file(system)


def test_the_family_is_read_with_its_observer_delay(tmp_path: Path) -> None:
    system = tmp_path / "SYSTEM.toml"
    system.write_text(SYSTEM_TOML + "observer_delay = 0.1\nK = [-0.05, 0.1]\n")
    design = load_system_file(system)["design"]
    assert design["family"] == "collocated_output_feedback" and design["observer_delay"] == 0.1
    assert design["K"] == (-0.05, 0.1) and design["delays"] == (0.0, 0.5)


def test_design_report_prints_true_digits_and_names_the_ends(tmp_path: Path) -> None:
    """The headline numbers of ``design.md`` carry their accuracy, and the window's and the gains' ends are named
    for what they are: ``delta = 0`` and the end ``2 d_max + 1 = 2`` of the delays searched (the margin is
    infinite: no crossing delay), and the bounds of ``K`` (every gain of the bounds meets the window)."""
    text, data = _run(tmp_path, SYSTEM_TOML)
    K = data["controller"]["state_feedback"]["K"]
    line = next(x for x in text.splitlines() if x.startswith("- decay rate at delta = 0: "))
    value, accuracy = (float(v) for v in line.split(": ")[1].split(" +- "))
    # the closed form -ln(rho - K)/2 lies within the printed accuracy (1e-16 for its own rounding), which
    # is not below the double's resolution (no digit beyond what the abscissa's computation supports)
    assert 1e-16 < accuracy < 1e-9
    np.testing.assert_allclose(value, -math.log(RHO - K) / 2.0, rtol=0.0, atol=accuracy + 1e-16)
    assert (
        "the designed loop: stable on the window (0, 2.000000000), from delta = 0 (stable without delay) to the "
        "end 2 d_max + 1 of the delays searched (no crossing delay up to it), checked"
    ) in text
    assert "of the crossing delays" not in text
    assert "- gains meeting the requirement: (-0.05000000000, 0.1928571428) (both ends the bounds of K)" in text
    bounds = data["design"]["bounds"]
    assert f"K in [{bounds[0]!r}, {bounds[1]!r}]" in text


@pytest.mark.parametrize("family", ["collocated_output_feedback", "output_feedback"])
def test_speed_tolerance_option_is_refused_for_the_observer_families(
    tmp_path: Path, family: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--speed-tolerance`` with an observer's family: an error naming the ``[design]`` key, the option and the
    family (as the file's key is refused), not the Python argument, and nothing written."""
    system = tmp_path / "SYSTEM.toml"
    system.write_text(SYSTEM_TOML)
    out = tmp_path / "out"
    assert main(["design", str(system), "-o", str(out), "--family", family, "--speed-tolerance", "0.1"]) == 2
    err = capsys.readouterr().err
    assert f'design.speed_tolerance (--speed-tolerance) must be left out for family = "{family}"' in err
    assert "output_feedback=True" not in err and not (out / "design.md").exists()
