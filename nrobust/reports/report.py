"""Reports: certificates written as Markdown, self-contained HTML and JSON.

:func:`write_report` turns one or several :class:`~nrobust.reports.certificate.Certificate` into

* ``report.md`` with the figures as PNG files next to it (``figures/``),
* ``report.html``, a single file with the same content and the figures embedded as
  base64 PNG (it can be mailed or attached as is),
* ``certificate.json`` (one certificate) or ``certificate_<k>.json`` (several).

Every number in a report is read from a certificate (or from the figures passed in),
never typed in: the report is a view of computations, not a second source of results.
"""

from __future__ import annotations

import base64
import html
import io
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._json import fields_dict
from ..errors import ParameterError
from ..hyperbolic.loops.controllers import (
    FilteredController,
    FiniteTimeController,
    OpenLoop,
    ReflectionController,
    characteristic,
    loop_factors,
)
from ..plots.nyquist import nyquist_response
from ..plots.rootmap import root_map_region, root_map_response
from .certificate import Certificate

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["ReportFiles", "write_report", "certificate_figures"]


@dataclass(frozen=True)
class ReportFiles:
    """Paths written by :func:`write_report`."""

    markdown: Path
    html: Path
    json: tuple[Path, ...]
    figures: tuple[Path, ...]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (paths as strings)."""
        return fields_dict(self)


# ---------------------------------------------------------------------- document model
@dataclass(frozen=True)
class _Heading:
    level: int
    text: str


@dataclass(frozen=True)
class _Paragraph:
    text: str


@dataclass(frozen=True)
class _Table:
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]


@dataclass(frozen=True)
class _Figure:
    name: str
    caption: str
    png: bytes


def _fmt(x: Any, digits: int = 6) -> str:
    if x is None:
        return "-"
    if isinstance(x, (bool, np.bool_)):
        return "yes" if x else "no"
    if isinstance(x, str):
        return x
    x = float(x)
    if np.isinf(x):
        return "inf" if x > 0 else "-inf"
    return f"{x:.{digits}g}"


def _png(fig: Figure) -> bytes:
    buf = io.BytesIO()
    if fig.get_layout_engine() is None:
        fig.set_layout_engine("tight")
    fig.savefig(buf, format="png", dpi=100)
    return buf.getvalue()


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_") or "figure"


def _controller_label(controller: Any) -> str:
    params = {k: v for k, v in controller.to_dict().items() if k != "controller"}
    inner = ", ".join(f"{k}={_fmt(v)}" for k, v in params.items())
    return f"{type(controller).__name__}({inner})"


def certificate_figures(cert: Certificate) -> list[tuple[str, Figure]]:
    """The standard figures of a certificate: root maps at ``0`` and ``delta_max``, Nyquist.

    Root maps reuse the certificate's root sets; the Nyquist data are computed from the
    loop factors of the certified loop at ``delta_max``.
    """
    return _figures(cert)[0]


def _figures(cert: Certificate) -> tuple[list[tuple[str, Figure]], Any]:
    """The standard figures and the Nyquist data behind the last one."""
    import matplotlib.pyplot as plt

    out: list[tuple[str, Figure]] = []
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 4.2))
    panels = (
        (axes[0], 0.0, cert.roots_nominal, cert.principal_nominal, cert.abscissa),
        (axes[1], cert.delta_max, cert.roots_delayed, cert.principal_delayed, None),
    )
    notes = []
    for ax, delta, roots, principal, abscissa in panels:
        F = characteristic(cert.system, cert.controller, delta)
        # the certified region, widened to hold the rightmost roots (an unstable root must show)
        box = root_map_region(F, base=cert.region, abscissa=abscissa)
        # the certificate's roots where the region is the certified one, else those of the wider box
        data = root_map_response(F, box, roots=roots if box == tuple(cert.region) else None, chains=principal.chains)
        drawn = data.plot(ax=ax)
        notes += [f" At delta = {delta:g}: {note.get_text()}".replace("\n", " ") for note in drawn.lines["note"]]
        ax.set_title(f"delta = {delta:g}: {data.count} roots (certified: {_fmt(data.certified)})", fontsize="small")
    fig.suptitle(f"Closed-loop roots, {_controller_label(cert.controller)}", fontsize="medium")
    out.append(
        (
            "Closed-loop roots in a region holding the rightmost roots (unstable ones circled in red), "
            "with the chain asymptotes of the difference operator" + ("." + "".join(notes) if notes else ""),
            fig,
        )
    )

    A, B = loop_factors(cert.system, cert.controller)
    # 20 periods of the principal part (a varying lam/mu plant: tau in its time unit)
    w_max = 20.0 * 2 * np.pi * getattr(cert.system, "time_unit", 1.0) / float(cert.system.tau)
    fig, ax = plt.subplots(figsize=(5.0, 5.0))
    resp = nyquist_response(
        A, B, cert.delta_max, omega_max=w_max, n_freq=2001, principal_bound=cert.principal_delayed.spectral_bound
    )
    resp.plot(ax=ax)
    out.append((f"Nyquist plot of the loop B/A e^(-i w delta) at delta = {cert.delta_max:g}", fig))
    return out, resp


def _certificate_blocks(cert: Certificate, index: int | None) -> tuple[list[Any], list[tuple[str, Figure]]]:
    label = _controller_label(cert.controller)
    head = f"{label}" if index is None else f"{index + 1}. {label}"
    cls = cert.classification
    m = cert.margin
    blocks: list[Any] = [_Heading(2, head), _Paragraph(f"**Verdict.** {cert.verdict}"), _Paragraph(_opening(cert))]
    rows = [
        ("open-loop gain rho q", _fmt(cls.rho_q), "classify (section 2)"),
        ("regime", cls.regime, "classify"),
        ("gamma_0 of the difference operator, delta = 0", _fmt(cert.principal_nominal.gamma_0), "principal_part"),
        (
            f"gamma_0 of the difference operator, delta = {cert.delta_max:g}",
            _fmt(cert.principal_delayed.gamma_0),
            "principal_part (< 1: eq. (11) for U_BS, eq. (54) for U_BS2)",
        ),
        ("strongly stable for small delays", _fmt(m.strongly_stable), "delay_margin"),
        ("spectral abscissa, delta = 0", _fmt(cert.abscissa.value), "spectral_abscissa"),
        ("nominally stable", _fmt(cert.nominally_stable), "delay_margin"),
        ("delay margin delta*", cert.margin_text, "delay_margin"),
        ("accuracy of the delay margin", cert.accuracy_statement.split(": ", 1)[1], "certify"),
        ("crossing frequency at delta*", _fmt(m.omega), "delay_margin"),
        (
            "margin verified (residual and count)",
            "not needed: infinite, no crossing frequency" if np.isposinf(m.margin) else _fmt(m.verified),
            "delay_margin",
        ),
        ("how the margin was decided", m.reason, "delay_margin"),
        (
            "stable delay intervals in [0, delta_max]",
            ", ".join(f"({_fmt(lo)}, {_fmt(hi)})" for lo, hi in m.intervals) or "none",
            "delay_margin",
        ),
        (
            "Rouché guaranteed range delta_0",
            "-" if cert.rouche is None else _fmt(cert.rouche.delta_0),
            "rouche_delay_bound (Theorem 4)",
        ),
        (
            "roots in the region, delta = 0",
            f"{cert.roots_nominal.count} (certified: {_fmt(cert.roots_nominal.certified)})",
            "find_roots",
        ),
        (
            f"roots in the region, delta = {cert.delta_max:g}",
            f"{cert.roots_delayed.count} (certified: {_fmt(cert.roots_delayed.certified)})",
            "find_roots",
        ),
        ("region (Re min, Re max, Im min, Im max)", ", ".join(_fmt(v, 4) for v in cert.region), "certify"),
    ]
    figures, nyquist = _figures(cert)
    # the same number by two routes: crossing analysis and winding along the axis
    crossing_count = (
        int(m.unstable_count(cert.delta_max)) if np.isfinite(m.delta_max) and cert.delta_max <= m.delta_max else None
    )
    rows.append(
        (
            f"closed-loop zeros in Re s > 0 at delta = {cert.delta_max:g}",
            f"{'-' if crossing_count is None or crossing_count < 0 else crossing_count} (crossings); "
            f"{'no finite count' if nyquist.rhp_zeros is None else nyquist.rhp_zeros} (Nyquist winding)",
            "delay_margin; nyquist_response",
        )
    )
    if cert.k_region is not None:
        rows.append(("admissible gains K on [0, delta_max]", _k_region_text(cert.k_region), "k_region"))
    elif cert.k_region_error:
        rows.append(("admissible gains K on [0, delta_max]", f"not certified: {cert.k_region_error}", "k_region"))
    blocks.append(_Table(("quantity", "value", "computed by"), tuple(rows)))
    box_rows = tuple(
        (f"delta = {_fmt(d)}", _box_text(box), str(int(c)))
        for d, rs in ((0.0, cert.roots_nominal), (cert.delta_max, cert.roots_delayed))
        for box, c in zip(np.asarray(rs.boxes).reshape(-1, 4), rs.box_counts)
    )
    if box_rows:
        blocks.append(_Paragraph("Certified root counts per box (argument principle with a certified step):"))
        blocks.append(_Table(("loop", "box", "roots"), box_rows))
    if cert.claims:
        blocks.append(_Paragraph(f"**What is proven.** {cert.scope}"))
        blocks.append(
            _Table(
                ("claim", "statement", "status", "computed by"),
                tuple((c.name, c.statement, c.status, c.source) for c in cert.claims),
            )
        )
        for note in cert.unproven:
            blocks.append(_Paragraph(f"Not proven: {note}"))
    return blocks, figures


def _opening(cert: Certificate) -> str:
    """The sentence under the verdict: what the paper says of this controller on this plant."""
    cls, controller = cert.classification, cert.controller
    if isinstance(controller, (FiniteTimeController, ReflectionController)):
        return cls.statement  # the regimes of |rho q| for U_BS and U_BS2 (Theorems 2 to 4)
    if isinstance(controller, FilteredController):
        a, b = float(controller.a), float(controller.b)
        gamma = abs(cls.rho_q) * (1.0 + abs(a) / b)
        return (
            f"Filtered U_BS with a = {_fmt(a)}, b = {_fmt(b)} (section 2.3.2): its delayed loop's difference operator "
            f"1 - rho q e^(-tau s) + (a/b) rho q e^(-(tau + delta) s) has gamma_0 = |rho q| (1 + |a|/b) = "
            f"{_fmt(gamma)}, {'below' if gamma < 1.0 else 'not below'} 1, the condition for a positive delay margin "
            "(the paper's eq. (17) states it without the absolute value of a)."
        )
    if isinstance(controller, OpenLoop):
        return (
            f"Open loop (U = 0), open-loop gain rho q = {_fmt(cls.rho_q)}. For the paper's controllers: {cls.statement}"
        )
    return f"Open-loop gain rho q = {_fmt(cls.rho_q)}. For the paper's controllers: {cls.statement}"


def _interval(lo: float, hi: float) -> str:
    """``[lo, hi]`` with the digits needed to tell the ends apart (a point when they are equal)."""
    if lo == hi:
        return _fmt(lo, 10)
    digits = 4
    while digits < 15 and _fmt(lo, digits) == _fmt(hi, digits):
        digits += 1
    return f"[{_fmt(lo, digits)}, {_fmt(hi, digits)}]"


def _box_text(box: Any) -> str:
    """A root box as ``Re [a, b] x Im [c, d]`` (a side of zero width as a single number)."""
    re_lo, re_hi, im_lo, im_hi = (float(v) for v in box)
    return f"Re {_interval(re_lo, re_hi)} x Im {_interval(im_lo, im_hi)}"


def _end_text(end: Any) -> str:
    """What closes an interval at a :class:`~nrobust.hyperbolic.analyses.GainEnd`, in words."""
    if end.kind == "crossing":
        return f"crossing (a root at i {_fmt(end.omega, 8)} for delta = delta_max)"
    if end.kind == "pair_birth":
        return f"pair birth (|A| = |B| touches at w = {_fmt(end.omega, 8)}, crossing delay {_fmt(end.delay, 8)})"
    if end.kind == "nominal":
        return f"nominal loop unstable (a root at i {_fmt(end.omega, 8)} for delta = 0)"
    if end.kind == "strong_stability":
        return "strong-stability limit |rho q| + |K q| = 1"
    return "bisection on delay margins"


def _k_region_text(kreg: Any) -> str:
    """The admissible intervals of a :class:`~nrobust.hyperbolic.analyses.KRegion`, the kind of each end
    and their accuracy."""
    if not kreg.intervals:
        return "none"
    parts = [
        f"({_fmt(lo.K, 10)}, {_fmt(hi.K, 10)}): lower end {_end_text(lo)}, upper end {_end_text(hi)}"
        for lo, hi in kreg.ends
    ] or [f"({_fmt(lo, 10)}, {_fmt(hi, 10)})" for lo, hi in kreg.intervals]
    return f"{'; '.join(parts)}; each end verified to {_fmt(kreg.tol, 3)} (paper bound |K| < {_fmt(kreg.paper_bound)})"


# ---------------------------------------------------------------------- renderers
def _markdown(blocks: Sequence[Any], fig_paths: Mapping[str, str]) -> str:
    out: list[str] = []
    for b in blocks:
        if isinstance(b, _Heading):
            out.append("#" * b.level + " " + b.text)
        elif isinstance(b, _Paragraph):
            out.append(b.text)
        elif isinstance(b, _Table):
            out.append("| " + " | ".join(b.header) + " |")
            out.append("|" + "|".join("---" for _ in b.header) + "|")
            out += ["| " + " | ".join(c.replace("|", "\\|") for c in row) + " |" for row in b.rows]
        elif isinstance(b, _Figure):
            out.append(f"![{b.caption}]({fig_paths[b.name]})\n\n*{b.caption}*")
        out.append("")
    return "\n".join(out)


def _inline(text: str) -> str:
    """Escape, then render ``**bold**`` and ``code`` spans."""
    t = html.escape(text)
    t = re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", t)
    return re.sub(r"`(.+?)`", r"<code>\1</code>", t)


_CSS = (
    "body{font-family:sans-serif;max-width:60em;margin:2em auto;padding:0 1em;color:#222}"
    "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:.25em .6em;"
    "text-align:left;vertical-align:top}th{background:#eee}figure{margin:1.5em 0}"
    "img{max-width:100%}figcaption{font-style:italic;font-size:.9em}"
)


def _html(title: str, blocks: Sequence[Any]) -> str:
    out = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
    ]
    for b in blocks:
        if isinstance(b, _Heading):
            out.append(f"<h{b.level}>{_inline(b.text)}</h{b.level}>")
        elif isinstance(b, _Paragraph):
            out.append(f"<p>{_inline(b.text)}</p>")
        elif isinstance(b, _Table):
            out.append("<table><tr>" + "".join(f"<th>{_inline(h)}</th>" for h in b.header) + "</tr>")
            out += ["<tr>" + "".join(f"<td>{_inline(c)}</td>" for c in row) + "</tr>" for row in b.rows]
            out.append("</table>")
        elif isinstance(b, _Figure):
            data = base64.b64encode(b.png).decode("ascii")
            out.append(
                f'<figure><img alt="{html.escape(b.caption)}" src="data:image/png;base64,{data}">'
                f"<figcaption>{html.escape(b.caption)}</figcaption></figure>"
            )
    out.append("</body></html>")
    return "\n".join(out)


# ---------------------------------------------------------------------- entry point
def write_report(
    certificates: Certificate | Sequence[Certificate],
    out_dir: str | Path,
    figures: Sequence[tuple[str, Figure]] = (),
    title: str = "nrobust delay-robustness report",
    intro: Sequence[str] = (),
) -> ReportFiles:
    """Write a Markdown report, a self-contained HTML report and the certificates' JSON.

    Parameters
    ----------
    certificates : Certificate or sequence of Certificate
        From :func:`nrobust.certify`; one section each, with its standard figures
        (:func:`certificate_figures`).
    out_dir : path-like
        Output directory (created if needed).
    figures : sequence of (caption, matplotlib Figure), optional
        Further figures (simulations, stability charts...), appended in order.
    title : str
        Report title.
    intro : sequence of str
        Paragraphs placed after the title.

    Returns
    -------
    ReportFiles
    """
    import matplotlib.pyplot as plt

    certs = [certificates] if isinstance(certificates, Certificate) else list(certificates)
    if not certs or not all(isinstance(c, Certificate) for c in certs):
        raise ParameterError("certificates", "a Certificate or a non-empty sequence of Certificate", certificates)
    for k, item in enumerate(figures):
        if not (
            isinstance(item, tuple) and len(item) == 2 and isinstance(item[0], str) and hasattr(item[1], "savefig")
        ):
            raise ParameterError(f"figures[{k}]", "a (caption, matplotlib Figure) pair", item)
    out = Path(out_dir)
    fig_dir = out / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)

    system = certs[0].system
    blocks: list[Any] = [_Heading(1, title)]
    blocks += [_Paragraph(p) for p in intro]
    blocks.append(
        _Paragraph(f"**System.** `{system!r}`, tau = {_fmt(system.tau / getattr(system, 'time_unit', 1.0))}.")
    )
    all_figs: list[tuple[str, Figure]] = []
    for k, cert in enumerate(certs):
        section, figs = _certificate_blocks(cert, None if len(certs) == 1 else k)
        blocks += section
        for caption, fig in figs:
            blocks.append(_Figure(f"{k + 1}_{_slug(caption)[:40]}", caption, _png(fig)))
            all_figs.append((caption, fig))
    if figures:
        blocks.append(_Heading(2, "Further figures"))
        for j, (caption, fig) in enumerate(figures):
            blocks.append(_Figure(f"extra_{j + 1}_{_slug(caption)[:40]}", caption, _png(fig)))
    v = certs[0].versions
    blocks.append(_Paragraph("Computed with " + ", ".join(f"{k} {val}" for k, val in v.items()) + "."))

    fig_paths: dict[str, str] = {}
    written: list[Path] = []
    for b in blocks:
        if isinstance(b, _Figure):
            path = fig_dir / f"{b.name}.png"
            path.write_bytes(b.png)
            fig_paths[b.name] = f"figures/{path.name}"
            written.append(path)
    md = out / "report.md"
    md.write_text(_markdown(blocks, fig_paths), encoding="utf-8")
    page = out / "report.html"
    page.write_text(_html(title, blocks), encoding="utf-8")
    jsons: list[Path] = []
    for k, cert in enumerate(certs):
        path = out / ("certificate.json" if len(certs) == 1 else f"certificate_{k + 1}.json")
        path.write_text(cert.to_json(), encoding="utf-8")
        jsons.append(path)
    for _, fig in all_figs:
        plt.close(fig)
    return ReportFiles(md, page, tuple(jsons), tuple(written))
