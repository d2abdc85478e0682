"""``nrobust analyze`` on an ``n + m`` file: the cancellation study written as a report.

For a one-actuator plant (``[system] type = "NPlusMSystem"``) the file lists partial
cancellations of the top reflection (``[controller] type = "Cancellation"``); each is
analysed by :func:`~nrobust.hyperbolic.nplusm.cancellation_study` (``gamma_0`` of the delayed
principal part in closed form; the abscissa of the delay-free loop and the delay margin checked
in floating point) and the
table is written as ``report.md``, ``report.html`` and ``report.json`` in one committed set
(:class:`~nrobust.reports.outputs.RunOutputs`), with one figure after the answer panel: the
roots of the delay-free loop of the most delay-robust case (``figures/``, embedded in the HTML).
"""

from __future__ import annotations

import base64
import html
import json
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._digits import with_accuracy
from .._json import json_safe
from .._progress import progress_bar
from ..hyperbolic.nplusm import CancellationCase, NPlusMCharacteristic, NPlusMSystem, cancellation_study
from ..plots.base import figure_png, pin_title
from ..plots.rootmap import RootMapData
from ..roots import find_roots
from .outputs import RunOutputs
from .report import ReportFiles

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["run_nplusm_analyze"]

#: Where the report's figure is written, relative to the output directory.
_FIGURE = "figures/roots_delay_free.png"
_HEAD = ("cancelled fractions of R", "gain K", "gamma_0 (delayed)", "abscissa (delta = 0)", "delay margin", "robust")


def _cells(row: CancellationCase) -> tuple[str, ...]:
    return (
        ", ".join(f"{c:g}" for c in row.fractions),
        ", ".join(f"{k:.4g}" for k in row.gain),
        f"{row.gamma_0:.4f}",
        "-infinity (no root)" if row.abscissa == float("-inf") else with_accuracy(row.abscissa, row.abscissa_accuracy),
        _margin_text(row),
        "yes" if row.robust else "no",
    )


def _margin_text(row: CancellationCase) -> str:
    """The delay margin in words when it is infinite or zero, else with its accuracy."""
    margin = row.margin.margin
    if margin == float("inf"):
        return "infinity (stable for every delay)"
    if margin == 0.0:
        return "0" if row.margin.error is not None else "0 (the delay-free loop's zeros not counted)"
    return with_accuracy(margin, row.margin.accuracy)


def _verdict(rows: tuple[CancellationCase, ...]) -> str:
    robust = [row.fractions for row in rows if row.robust]
    if not robust:
        return "no listed cancellation keeps a positive delay margin"
    return "delay-robust cancellations: " + "; ".join("(" + ", ".join(f"{c:g}" for c in f) + ")" for f in robust)


def _best(rows: tuple[CancellationCase, ...]) -> CancellationCase | None:
    """The delay-robust case with the largest delay margin (the first of equal ones); None when none is robust."""
    return max((row for row in rows if row.robust), key=lambda row: row.margin.margin, default=None)


def _fractions(row: CancellationCase) -> str:
    return "(" + ", ".join(f"{c:g}" for c in row.fractions) + ")"


def _panel(system: NPlusMSystem, rows: tuple[CancellationCase, ...]) -> tuple[str, list[str]]:
    """The answer first: which cancellations are delay-robust, the plant, the best margin, what is proven."""
    verdict = _verdict(rows)
    best = _best(rows)
    lines = [
        f"**Plant:** speeds lam = {system.lam.tolist()}, mu = {system.mu.tolist()}; Q = {system.q.tolist()}, "
        f"R = {system.r.tolist()}; {len(rows)} cancellation(s) of R studied."
    ]
    if best is not None:
        fractions = ", ".join(f"{c:g}" for c in best.fractions)
        lines.append(
            f"**Largest delay margin:** cancelled fractions ({fractions}): delta* = {_margin_text(best)}, decay "
            f"rate without delay {with_accuracy(-best.abscissa, best.abscissa_accuracy)}."
        )
    if rows and rows[0].rigorous:
        lines.append(
            "**Proven:** in ball arithmetic for the PDE itself (its exact Laplace-domain loop): the abscissae and the "
            "delay margins of the cases with gamma_0 < 1, each printed to its proven accuracy; gamma_0 in closed form "
            "and the margin 0 of gamma_0 > 1 in floating point."
        )
        return verdict[:1].upper() + verdict[1:], lines
    lines.append(
        "**Proven:** nothing in ball arithmetic; gamma_0 in closed form, the abscissae and the delay margins are "
        "checked in floating point (root counts by the argument principle with a step control; a proven frequency "
        "bound and a complete crossing search). For proofs: "
        "`spectral_abscissa(NPlusMCharacteristic(system, K), rigorous=True)`, and "
        "`backstepping_delay_margin(..., rigorous=True)` for the full-state law."
    )
    return verdict[:1].upper() + verdict[1:], lines


def _details(region: tuple[float, ...]) -> str:
    return (
        f"Abscissae in the region {list(region)}; a loop is delay-robust when gamma_0 of its delayed principal part is "
        "below 1 and it is stable without delay."
    )


def _root_figure(
    system: NPlusMSystem, region: tuple[float, ...], rows: tuple[CancellationCase, ...]
) -> tuple[str, Figure, RootMapData]:
    """The report's figure: the roots of the delay-free loop of the most delay-robust case in the study's region.

    The case drawn is the delay-robust one with the largest delay margin (else the first
    listed); its roots are those of :func:`~nrobust.roots.find_roots` on
    ``NPlusMCharacteristic(system, K, 0.0)`` in ``region`` (argument principle with a step
    control, in floating point), drawn by :meth:`~nrobust.plots.rootmap.RootMapData.plot` with
    the chain asymptotes of the difference operator that meet the region.

    Returns
    -------
    (str, matplotlib Figure, RootMapData)
        The caption, the figure and the data drawn.
    """
    import matplotlib.pyplot as plt

    best = _best(rows)
    case = rows[0] if best is None else best
    box = (float(region[0]), float(region[1]), float(region[2]), float(region[3]))
    F = NPlusMCharacteristic(system, [list(case.gain)], 0.0)
    found = find_roots(F, box)
    values = np.asarray(found.roots, dtype=complex).ravel()
    reals = sorted((c.real for c in F.principal_part().chains().chains if box[0] <= c.real <= box[1]), reverse=True)
    data = RootMapData(
        box, values, int(found.count), bool(found.certified), int(np.sum(values.real > 0.0)), np.array(reals), None
    )
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    data.plot(ax=ax)
    status = "all found" if data.certified else "not all found"
    ax.set_title(f"cancelled fractions {_fractions(case)}, delta = 0: {data.count} roots ({status})", fontsize="small")
    pin_title(ax)
    fig.subplots_adjust(left=0.11, right=0.97, bottom=0.11, top=0.92)
    which = "the delay-robust case with the largest delay margin" if best is not None else "the first case listed"
    a, b, c, d = (f"{v:.4g}" for v in box)
    caption = (
        f"Roots of the delay-free loop (delta = 0) for cancelled fractions {_fractions(case)}, {which}, "
        f"delta* = {_margin_text(case)}, in the study's region Re s in [{a}, {b}], Im s in [{c}, {d}] "
        "(unstable ones circled in red), with the chain asymptotes of the difference operator that meet it; the "
        f"table's abscissa is the rightmost of these roots and chains. The count, {data.count}, is checked in "
        "floating point (argument principle with a step control), not proven."
    )
    return caption, fig, data


def _figure_png(
    system: NPlusMSystem, region: tuple[float, ...], rows: tuple[CancellationCase, ...]
) -> tuple[str, bytes, RootMapData]:
    """:func:`_root_figure` as ``(caption, PNG, data drawn)``, the figure closed."""
    import matplotlib.pyplot as plt

    caption, fig, data = _root_figure(system, region, rows)
    try:
        return caption, figure_png(fig), data
    finally:
        plt.close(fig)


def _markdown(system: NPlusMSystem, region: tuple[float, ...], rows: tuple[CancellationCase, ...], caption: str) -> str:
    """The report: the answer first (a panel and the figure), then the study's table."""
    head, panel = _panel(system, rows)
    lines = [f"# n + m loop: {system.n} + {system.m}, static feedback U = K u(t - delta, 1)", "", f"> **{head}**"]
    for line in panel:
        lines += [">", f"> {line}"]
    lines += ["", f"![{caption}]({_FIGURE})", "", f"*{caption}*"]
    lines += ["", _details(region), "", "| " + " | ".join(_HEAD) + " |", "|" + "---|" * len(_HEAD)]
    lines += ["| " + " | ".join(_cells(row)) + " |" for row in rows]
    lines += [""]
    return "\n".join(lines)


def _html(
    markdown_title: str,
    system: NPlusMSystem,
    region: tuple[float, ...],
    rows: tuple[CancellationCase, ...],
    figure: tuple[str, bytes, RootMapData],
) -> str:
    head, panel = _panel(system, rows)
    quote = "".join(f"<p>{_inline_html(line)}</p>" for line in panel)
    cols = "".join(f"<th>{html.escape(h)}</th>" for h in _HEAD)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in _cells(r)) + "</tr>" for r in rows)
    title = html.escape(markdown_title)
    caption = html.escape(figure[0])
    data = base64.b64encode(figure[1]).decode("ascii")
    picture = (
        f'<figure><img alt="{caption}" style="max-width:100%" src="data:image/png;base64,{data}">'
        f"<figcaption><i>{caption}</i></figcaption></figure>"
    )
    return (
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{title}</title></head><body>"
        f"<h1>{title}</h1><blockquote><p><b>{html.escape(head)}</b></p>{quote}</blockquote>{picture}"
        f"<p>{html.escape(_details(region))}</p><table><tr>{cols}</tr>{body}</table></body></html>"
    )


def _inline_html(text: str) -> str:
    """``**bold**`` and ```code``` of a panel line as HTML, the rest escaped."""
    out = html.escape(text)
    out = re.sub(r"\*\*(.+?)\*\*", r"<b>\1</b>", out)
    return re.sub(r"`(.+?)`", r"<code>\1</code>", out)


def run_nplusm_analyze(
    spec: dict[str, Any], out_dir: str | Path, progress: bool | None = None, *, rigorous: bool = False
) -> tuple[ReportFiles, str]:
    """Run the cancellation study of an ``n + m`` file (:func:`~nrobust.config.load_system_file`); write the report.

    ``rigorous``: the study's abscissae and margins proven in ball arithmetic (:func:`cancellation_study`)."""
    system: NPlusMSystem = spec["system"]
    outputs = RunOutputs(out_dir, "analyze")
    with outputs, progress_bar(len(spec["cancellations"]) + 1, progress, "analyze") as bar:
        rows = cancellation_study(system, spec["cancellations"], spec["region"], rigorous=rigorous)
        bar.update(len(rows))
        figure = _figure_png(system, spec["region"], rows)
        md = _markdown(system, spec["region"], rows, figure[0])
        paths = tuple(outputs.path(name) for name in ("report.md", "report.html", "report.json", _FIGURE))
        paths[0].write_text(md, encoding="utf-8")
        paths[1].write_text(_html(md.splitlines()[0][2:], system, spec["region"], rows, figure), encoding="utf-8")
        paths[3].write_bytes(figure[1])
        data = {
            "system": system.to_dict(),
            "region": spec["region"],
            "cases": [r.to_dict() for r in rows],
            "figure": {"path": _FIGURE, "caption": figure[0], **figure[2].to_dict()},
        }
        paths[2].write_text(json.dumps(json_safe(data), indent=2, allow_nan=False), encoding="utf-8")
        files = outputs.final(ReportFiles(paths[0], paths[1], (paths[2],), (paths[3],)))
        outputs.commit()
        bar.update(1)
    return files, _verdict(rows)
