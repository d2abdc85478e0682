"""``nrobust design``: the gain ``K`` of ``U_BS2(K)`` for the plant of a SYSTEM.toml file.

The plant is the ``[system]`` section of the file (the ``[controller]`` and ``[analysis]``
sections are read and checked as for ``nrobust analyze``, and not used); the design is
:func:`nrobust.hyperbolic.analyses.design_reflection`. Written: ``design.json`` (the
:class:`~nrobust.hyperbolic.analyses.design.ReflectionDesign`, with its certificate) and
``design.md`` (the design in words), as one set with ``manifest.json``.
"""

from __future__ import annotations

import json
from pathlib import Path

from .._json import json_safe
from ..config import NPLUSM_TYPE, load_system_file
from ..errors import ParameterError
from ..hyperbolic.analyses.design import DESIGN_OBJECTIVES, ReflectionDesign, design_reflection
from .outputs import RunOutputs, check_output_dir

__all__ = ["run_design"]


def _markdown(path: Path, result: ReflectionDesign) -> str:
    d, cert = result.design, result.design.certificate
    what = "delay margin" if d.objective == "margin" else "decay rate at delta = 0"
    lines = [
        f"# Design of U_BS2(K) for {path.name}",
        "",
        f"- objective: the largest {what}, K in [{d.bounds[0]:.12g}, {d.bounds[1]:.12g}]",
        f"- designed gain: K = {d.K:.15g} ({d.kind}); the optimum lies in [{d.K_bracket[0]:.15g}, "
        f"{d.K_bracket[1]:.15g}]",
        f"- {what}: {d.value:.15g} (optimum in [{d.value_bracket[0]:.15g}, {d.value_bracket[1]:.15g}])",
        f"- delay margin of the designed loop: {d.margin:.15g}, {d.certified} ({cert.method}); about {cert.scope}",
    ]
    if d.objective == "margin":
        lines.append(f"- decay rate at delta = 0: {d.decay_rate:.15g}")
    if d.end is not None:
        lines.append(
            f"- the end of the gains with a large enough margin: K = {d.end.K:.15g}, {d.end.kind} at "
            f"w = {d.end.omega:.12g}, delay {d.end.delay:.12g}"
        )
    return "\n".join(lines) + "\n"


def run_design(
    path: str | Path,
    out_dir: str | Path,
    objective: str = "margin",
    margin_at_least: float | None = None,
    K_bounds: tuple[float, float] | None = None,
    rigorous: bool = False,
) -> tuple[tuple[Path, ...], ReflectionDesign]:
    """``nrobust design``: design ``U_BS2(K)`` for the plant of a SYSTEM.toml file and write the result.

    The file and ``out_dir`` are checked before any computation; the files are written as one
    set (:class:`~nrobust.reports.outputs.RunOutputs`). Returns the written paths and the design.

    Raises
    ------
    ParameterError
        A bad file, an ``n + m`` plant (``U_BS2(K)`` is a 2x2 law), or the arguments of
        :func:`~nrobust.hyperbolic.analyses.design_reflection`.
    """
    check_output_dir(out_dir)
    if objective not in DESIGN_OBJECTIVES:
        raise ParameterError("objective", f"one of {DESIGN_OBJECTIVES}", objective)
    spec = load_system_file(path)
    if spec.get("kind") == NPLUSM_TYPE:
        raise ParameterError("system.type", "a 2x2 plant (U_BS2(K) is designed for 2x2 plants)", NPLUSM_TYPE)
    outputs = RunOutputs(out_dir, "design")
    with outputs:
        result = design_reflection(
            spec["system"], objective, margin_at_least=margin_at_least, K_bounds=K_bounds, rigorous=rigorous
        )
        data = {"file": str(path), "plant": repr(spec["given_system"]), **result.to_dict()}
        written = (
            outputs.write_text("design.json", json.dumps(json_safe(data), indent=2, allow_nan=False)),
            outputs.write_text("design.md", _markdown(Path(path), result)),
        )
    return written, result
