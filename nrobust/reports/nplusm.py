"""``nrobust analyze`` on an ``n + m`` file: the cancellation study written as a report.

For a one-actuator plant (``[system] type = "NPlusMSystem"``) the file lists partial
cancellations of the top reflection (``[controller] type = "Cancellation"``); each is
analysed by :func:`~nrobust.hyperbolic.nplusm.cancellation_study` (exact ``gamma_0`` of the
delayed principal part, certified abscissa of the delay-free loop, delay margin) and the
table is written as ``report.md``, ``report.html`` and ``report.json`` in one committed set
(:class:`~nrobust.reports.outputs.RunOutputs`).
"""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

from .._digits import with_accuracy
from .._json import json_safe
from .._progress import progress_bar
from ..hyperbolic.nplusm import CancellationCase, NPlusMSystem, cancellation_study
from .outputs import RunOutputs
from .report import ReportFiles

__all__ = ["run_nplusm_analyze"]

_HEAD = ("cancelled fractions of R", "gain K", "gamma_0 (delayed)", "abscissa (delta = 0)", "delay margin", "robust")


def _cells(row: CancellationCase) -> tuple[str, ...]:
    return (
        ", ".join(f"{c:g}" for c in row.fractions),
        ", ".join(f"{k:.4g}" for k in row.gain),
        f"{row.gamma_0:.4f}",
        with_accuracy(row.abscissa, row.abscissa_accuracy),
        with_accuracy(row.margin.margin, row.margin.accuracy),
        "yes" if row.robust else "no",
    )


def _verdict(rows: tuple[CancellationCase, ...]) -> str:
    robust = [row.fractions for row in rows if row.robust]
    if not robust:
        return "no listed cancellation keeps a positive delay margin"
    return "delay-robust cancellations: " + "; ".join("(" + ", ".join(f"{c:g}" for c in f) + ")" for f in robust)


def _markdown(system: NPlusMSystem, region: tuple[float, ...], rows: tuple[CancellationCase, ...]) -> str:
    lines = [
        f"# n + m loop: {system.n} + {system.m}, static feedback U = K u(t - delta, 1)",
        "",
        f"Speeds lam = {system.lam.tolist()}, mu = {system.mu.tolist()}; Q = {system.q.tolist()}, "
        f"R = {system.r.tolist()}. Abscissae certified in the region {list(region)}; the delay margins are certified "
        "(proven frequency bound, complete crossing search, counted delay-free loop), gamma_0 is exact.",
        "",
        "| " + " | ".join(_HEAD) + " |",
        "|" + "---|" * len(_HEAD),
    ]
    lines += ["| " + " | ".join(_cells(row)) + " |" for row in rows]
    lines += ["", f"**{_verdict(rows)}**", ""]
    return "\n".join(lines)


def _html(markdown_title: str, rows: tuple[CancellationCase, ...]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in _HEAD)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in _cells(r)) + "</tr>" for r in rows)
    title = html.escape(markdown_title)
    return (
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{title}</title></head><body>"
        f"<h1>{title}</h1><table><tr>{head}</tr>{body}</table><p><b>{html.escape(_verdict(rows))}</b></p></body></html>"
    )


def run_nplusm_analyze(
    spec: dict[str, Any], out_dir: str | Path, progress: bool | None = None
) -> tuple[ReportFiles, str]:
    """Run the cancellation study of an ``n + m`` file (:func:`~nrobust.config.load_system_file`); write the report."""
    system: NPlusMSystem = spec["system"]
    outputs = RunOutputs(out_dir, "analyze")
    with outputs, progress_bar(len(spec["cancellations"]) + 1, progress, "analyze") as bar:
        rows = cancellation_study(system, spec["cancellations"], spec["region"])
        bar.update(len(rows))
        md = _markdown(system, spec["region"], rows)
        paths = (outputs.path("report.md"), outputs.path("report.html"), outputs.path("report.json"))
        paths[0].write_text(md, encoding="utf-8")
        paths[1].write_text(_html(md.splitlines()[0][2:], rows), encoding="utf-8")
        data = {"system": system.to_dict(), "region": spec["region"], "cases": [r.to_dict() for r in rows]}
        paths[2].write_text(json.dumps(json_safe(data), indent=2, allow_nan=False), encoding="utf-8")
        files = outputs.final(ReportFiles(paths[0], paths[1], (paths[2],), ()))
        outputs.commit()
        bar.update(1)
    return files, _verdict(rows)
