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
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from threadpoolctl import threadpool_limits

from .._digits import inner_interval_text, lower_bound_text, upper_bound_text, with_accuracy
from .._json import fields_dict
from ..design.local import delayed_gamma
from ..errors import ParameterError
from ..hyperbolic.loops.controllers import (
    FilteredController,
    FiniteTimeController,
    OpenLoop,
    ReflectionController,
    characteristic,
    loop_factors,
    normalize,
)
from ..hyperbolic.plants.general import GeneralHyperbolic2x2
from ..plots.base import figure_png, pin_title
from ..plots.charts import delay_chart_plot
from ..plots.nyquist import nyquist_response
from ..plots.rootmap import root_map_region, root_map_response
from .certificate import PROVEN, Certificate

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..plots.rootmap import RootMapData
    from ..roots import RootSet

__all__ = [
    "RenderedFigures",
    "ReportFiles",
    "certificate_figures",
    "render_certificate_figures",
    "render_nyquist_figure",
    "write_report",
]


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
    code_column: int | None = None  # a column of function names, set as code
    summary: str = ""  # folded under this line (HTML <details>) when given


@dataclass(frozen=True)
class _Panel:
    """The answer, set apart at the top of a section: a title and a few lines."""

    title: str
    lines: tuple[str, ...]


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
        return "infinity" if x > 0 else "-infinity"
    return f"{x:.{digits}g}"


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_") or "figure"


def _controller_label(controller: Any) -> str:
    params = {k: v for k, v in controller.to_dict().items() if k != "controller"}
    inner = ", ".join(f"{k}={_fmt(v)}" for k, v in params.items())
    return f"{type(controller).__name__}({inner})"


def certificate_figures(cert: Certificate) -> list[tuple[str, Figure]]:
    """The standard figures of a certificate: the stability chart in the delay above the root
    maps at ``0`` and ``delta_max`` (one region for both), then the Nyquist plot.

    The chart draws the certificate's delay margin; the root maps reuse its root sets where
    their region is the certified one; the Nyquist data are computed from the loop factors of
    the certified loop at ``delta_max``.
    """
    return _figures(cert)[0]


@dataclass(frozen=True)
class RenderedFigures:
    """A certificate's standard figures drawn as PNG (:func:`render_certificate_figures`).

    Plain bytes and numbers: a worker process can draw them and send them to the process
    that writes the report (``write_report(..., rendered=...)``), as ``nrobust paper`` does.

    Attributes
    ----------
    pngs : tuple of (str, bytes)
        ``(caption, PNG at 100 dpi)`` of each figure of :func:`certificate_figures`, in order.
    rhp_zeros : int or None
        Closed-loop zeros in ``Re s > 0`` at ``delta_max`` by the Nyquist winding
        (:attr:`NyquistResponse.rhp_zeros <nrobust.plots.nyquist.NyquistResponse>`), which
        the report's table sets beside the count of the crossing analysis.
    """

    pngs: tuple[tuple[str, bytes], ...]
    rhp_zeros: int | None


def render_certificate_figures(cert: Certificate, nyquist: bool = True) -> RenderedFigures:
    """The figures of :func:`certificate_figures` drawn as PNG, with the Nyquist count the report reads.

    With ``nyquist=False``, the first figure only (the Nyquist plot drawn elsewhere by
    :func:`render_nyquist_figure`, its ``rhp_zeros`` None here): the two then make the
    certificate's :class:`RenderedFigures` as ``RenderedFigures(roots.pngs + nyq.pngs, nyq.rhp_zeros)``.
    """
    if nyquist:
        figures, resp = _figures(cert)
    else:
        figures, resp = [_roots_figure(cert)], None
    return RenderedFigures(_pngs(figures), None if resp is None else resp.rhp_zeros)


def render_nyquist_figure(
    system: Any, controller: Any, delta_max: float, kernel_grid: int | None = None
) -> RenderedFigures:
    """The Nyquist figure of the certificate of ``(system, controller, delta_max)``, without the certificate.

    The same figure and count as :func:`render_certificate_figures` draws from
    ``certify(system, controller, delta_max=delta_max, kernel_grid=kernel_grid)`` (whose
    ``kernel_grid`` is the one given, None by default): the principal part's bound is
    computed here as the certificate computes it. ``nrobust paper`` draws it in one worker
    while another certifies the loop.
    """
    Fd = characteristic(system, controller, delta_max, kernel_grid=kernel_grid)
    bound = float(Fd.principal_part().chains().bracket[1])  # Certificate.principal_delayed.spectral_bound
    caption, fig, resp = _nyquist_figure(system, controller, delta_max, kernel_grid, bound)
    return RenderedFigures(_pngs([(caption, fig)]), resp.rhp_zeros)


def _pngs(figures: list[tuple[str, Figure]]) -> tuple[tuple[str, bytes], ...]:
    """``(caption, PNG)`` of each figure, the figures closed."""
    import matplotlib.pyplot as plt

    try:
        return tuple((caption, figure_png(fig)) for caption, fig in figures)
    finally:
        for _, fig in figures:
            plt.close(fig)


def _crossing_count(cert: Certificate) -> int | None:
    """Zeros in ``Re s > 0`` at ``delta_max`` from the crossing analysis (None when not finite or not known)."""
    m = cert.margin
    if not (np.isfinite(m.delta_max) and cert.delta_max <= m.delta_max):
        return None
    n = int(m.unstable_count(cert.delta_max))
    return None if n < 0 else n


def _map_region(cert: Certificate, F0: Any, Fd: Any) -> tuple[float, float, float, float]:
    """One rectangle for both root maps: the certified region, widened only where a root that matters lies outside.

    Without delay, the rightmost root (the certificate's spectral abscissa) unless a root of the
    certified set is as far right (a vertical chain of roots ties). At ``delta_max``, no search
    when the certified set already holds every zero in ``Re s > 0`` counted by the crossing
    analysis, or when a chain of the difference operator lies in ``Re s > 0`` (its roots are
    drawn, or named in a note); otherwise the spectral abscissa of the delayed loop.
    """
    base = (float(cert.region[0]), float(cert.region[1]), float(cert.region[2]), float(cert.region[3]))
    a = cert.abscissa
    drawn0 = np.asarray(cert.roots_nominal.roots, dtype=complex)
    tie = a.root is None or (drawn0.size > 0 and drawn0.real.max() >= a.value - 1e-9 * (1.0 + abs(a.value)))
    box0 = root_map_region(F0, base=base, abscissa=None if tie else a, search=False)
    drawn = np.asarray(cert.roots_delayed.roots, dtype=complex)
    count = _crossing_count(cert)
    known = count is not None and count == int(np.sum(drawn.real > 0.0))
    boxd = root_map_region(Fd, base=base, search=not (known or cert.principal_delayed.spectral_bound > 0.0))
    return (min(box0[0], boxd[0]), max(box0[1], boxd[1]), min(box0[2], boxd[2]), max(box0[3], boxd[3]))


def _rectangle(box: Sequence[float]) -> str:
    """``Re s in [a, b], Im s in [c, d]`` to 4 significant digits."""
    a, b, c, d = (f"{float(v):.4g}" for v in box)
    return f"Re s in [{a}, {b}], Im s in [{c}, {d}]"


def _figures(cert: Certificate) -> tuple[list[tuple[str, Figure]], Any]:
    """The standard figures and the Nyquist data behind the last one."""
    roots = _roots_figure(cert)
    caption, fig, resp = _nyquist_figure(
        cert.system, cert.controller, cert.delta_max, cert.kernel_grid, cert.principal_delayed.spectral_bound
    )
    return [roots, (caption, fig)], resp


def _roots_figure(cert: Certificate) -> tuple[str, Figure]:
    """The stability chart in the delay above the root maps at ``0`` and ``delta_max``, with its caption."""
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(9.0, 7.0))
    grid = fig.add_gridspec(2, 2, height_ratios=(1.0, 1.9))
    chart_ax = fig.add_subplot(grid[0, :])
    delay_chart_plot(cert.margin, ax=chart_ax, margin_text=cert.margin_text)
    chart_ax.set_title("Stability against the loop delay", fontsize="small")
    F0 = characteristic(cert.system, cert.controller, 0.0, kernel_grid=cert.kernel_grid)
    Fd = characteristic(cert.system, cert.controller, cert.delta_max, kernel_grid=cert.kernel_grid)
    box = _map_region(cert, F0, Fd)
    same = box == tuple(float(v) for v in cert.region)
    ax0 = fig.add_subplot(grid[1, 0])
    axes = (ax0, fig.add_subplot(grid[1, 1], sharey=ax0))
    panels = (
        (axes[0], 0.0, F0, cert.roots_nominal, cert.principal_nominal),
        (axes[1], cert.delta_max, Fd, cert.roots_delayed, cert.principal_delayed),
    )
    notes = []
    for ax, delta, F, roots, principal in panels:
        # the certificate's roots where the region is the certified one, else those of the wider box
        data = root_map_response(F, box, roots=roots if same else None, chains=principal.chains)
        drawn = data.plot(ax=ax)
        notes += [f" At delta = {delta:g}: {note.get_text()}".replace("\n", " ") for note in drawn.lines["note"]]
        ax.set_title(f"roots at delta = {delta:g}: {data.count} ({_count_status(data)})", fontsize="small")
    axes[1].set_ylabel("")
    for ax in (chart_ax, *axes):  # their limits final (the maps share their y axis)
        pin_title(ax)
    fig.suptitle(f"Closed loop under {_controller_label(cert.controller)}", fontsize="medium")
    fig.subplots_adjust(left=0.08, right=0.96, bottom=0.07, top=0.92, hspace=0.32, wspace=0.22)
    wider = (
        ""
        if same
        else f" The maps' rectangle, {_rectangle(box)}, is wider than the region of the tables (the certificate's), "
        f"{_rectangle(cert.region)}, so that the rightmost roots and the chains show: its counts are its own."
    )
    return (
        "Closed-loop roots in a region holding the rightmost roots (unstable ones circled in red), "
        "with the chain asymptotes of the difference operator, at delta = 0 and at delta = "
        f"{cert.delta_max:g} in the same region; above them, the stability chart in the loop delay "
        "(zeros in Re s > 0 against delta, the delay margin marked)." + wider + "".join(notes),
        fig,
    )


def _nyquist_figure(
    system: Any, controller: Any, delta_max: float, kernel_grid: int | None, principal_bound: float
) -> tuple[str, Figure, Any]:
    """The Nyquist plot of the loop at ``delta_max``, its caption and its data."""
    import matplotlib.pyplot as plt

    A, B = loop_factors(system, controller, kernel_grid)
    # 20 periods of the principal part (a varying lam/mu plant: tau in its time unit)
    w_max = 20.0 * 2 * np.pi * getattr(system, "time_unit", 1.0) / float(system.tau)
    fig, ax = plt.subplots(figsize=(5.0, 5.0))
    resp = nyquist_response(A, B, delta_max, omega_max=w_max, n_freq=2001, principal_bound=principal_bound)
    resp.plot(ax=ax)
    pin_title(ax)
    fig.subplots_adjust(left=0.14, right=0.97, bottom=0.1, top=0.92)
    return f"Nyquist plot of the loop B/A e^(-i w delta) at delta = {delta_max:g}", fig, resp


#: The paper's regimes of ``|rho q|`` (:class:`~nrobust.hyperbolic.loops.controllers.Classification`) in words.
_REGIMES = {
    "not_stabilizable": "no controller is delay-robust here (|rho q| > 1, Theorem 2)",
    "critical_one": "critical case |rho q| = 1 (the open-loop chain on the imaginary axis)",
    "no_robust_finite_time": "no finite-time controller is delay-robust here (1/2 < |rho q| < 1, Theorem 3)",
    "critical_half": "critical case |rho q| = 1/2 (finite-time U_BS not strongly stable)",
    "robust_finite_time": "finite-time control can be delay-robust (|rho q| < 1/2)",
}


def _panel(cert: Certificate) -> _Panel:
    """The answer first: stability without delay, the delay margin, the range, what is proven."""
    m = cert.margin
    lines = []
    if cert.nominally_stable and np.isneginf(cert.abscissa.value):
        lines.append("**Without delay (delta = 0):** stable, no closed-loop root at all (finite-time convergence).")
    elif cert.nominally_stable:
        lines.append(
            f"**Without delay (delta = 0):** stable; decay rate "
            f"{with_accuracy(-cert.abscissa.value, cert.abscissa.accuracy)}{_rate_unit(cert)} "
            + (
                "(the abscissa of the rightmost chain of roots, approached as Im s grows)."
                if cert.abscissa.approached_at_infinity
                else "(the rightmost closed-loop root)."
            )
        )
    else:
        n = "some" if m.nominal_unstable is None else str(m.nominal_unstable)
        lines.append(f"**Without delay (delta = 0):** unstable, {n} closed-loop zero(s) in Re s >= 0.")
    if not cert.nominally_stable:
        lines.append("**Delay margin:** none (the loop is unstable without delay).")
    elif np.isposinf(cert.delay_margin):
        lines.append("**Delay margin:** delta* = infinity (stable for every delay).")
    elif cert.delay_margin == 0.0:
        lines.append("**Delay margin:** delta* = 0: the smallest loop delay destabilises the loop (not delay-robust).")
    else:
        where = (
            ""
            if m.omega is None
            else f", a root crossing the imaginary axis at w = {with_accuracy(m.omega, m.omega_accuracy)}"
        )
        lines.append(f"**Delay margin:** delta* = {cert.margin_text}{_unit(cert)}{where}.")
    dmax = f"{cert.delta_max:g}"
    count = _crossing_count(cert)
    if cert.stable_up_to_delta_max:
        lines.append(f"**Delays 0 to {dmax}:** stable for every one of them.")
    elif cert.delay_robust:
        zeros = "" if count is None else f"; {count} zero(s) in Re s > 0 at delta = {dmax}"
        lines.append(f"**Delays 0 to {dmax}:** stable below delta*, not beyond{zeros}.")
    elif cert.nominally_stable:
        lines.append(f"**Delays 0 to {dmax}:** unstable for every delay in (0, {dmax}].")
    if cert.rigorous:
        proven = sum(c.status == PROVEN for c in cert.claims)
        checked = [c.name for c in cert.claims if c.status != PROVEN]
        rest = f"; checked in floating point: {', '.join(checked)}" if checked else ""
        lines.append(f"**Proven:** {proven} of {len(cert.claims)} claims in ball arithmetic{rest} (details below).")
    else:
        lines.append(
            "**Proven:** nothing in ball arithmetic; every claim is checked in floating point (the root counts are "
            "integers from the argument principle with a step control). For proofs: `rigorous = true` in [analysis] "
            "of SYSTEM.toml, or `certify(..., rigorous=True)`."
        )
    return _Panel(cert.verdict, tuple(lines))


def _time_unit(cert: Certificate) -> float:
    """The seconds of the time unit the plant's delays are in (1 when not said)."""
    given = cert.system if cert.given_system is None else cert.given_system
    return float(getattr(given, "time_unit", 1.0))


def _rate_unit(cert: Certificate) -> str:
    """`` per time unit (T s)`` for a plant whose delays are in a unit of ``T`` seconds, else empty."""
    unit = _time_unit(cert)
    return "" if unit == 1.0 else f" per time unit ({unit:g} s)"


def _unit(cert: Certificate) -> str:
    """`` (time unit: T s)`` for a plant whose delays are in a unit of ``T`` seconds, else empty."""
    unit = _time_unit(cert)
    return "" if unit == 1.0 else f" (time unit: {unit:g} s)"


def _number(value: Any) -> str:
    """A coefficient as the user wrote it: a number in full (10 digits), else its description."""
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        return f"{float(value):.10g}"
    return str(value)


def _profile_text(plant: GeneralHyperbolic2x2, name: str) -> str:
    """A coefficient of a general plant: its number, or the range of its values on ``[0, L]`` (6 digits).

    A function: the range of 101 values on ``[0, L]``. Samples: the range of the samples the
    user gave, and, when the cubic spline through them (the model analysed) leaves that range
    between samples, the spline's range too (its extremes exactly: the zeros of its derivative),
    so that an undershoot is not read as data.
    """
    profile = plant.profiles[name]
    if profile.constant:
        return _number(profile.describe())
    if not isinstance(profile.value, tuple):
        values = np.asarray(profile(np.linspace(0.0, plant.length, 101)), dtype=float)
        low, high = _fmt(values.min()), _fmt(values.max())
        return low if low == high else f"varying in [{low}, {high}]"
    from scipy.interpolate import PPoly  # lazily, as the plant's own spline

    # the spline's extremes: at the ends and where its derivative vanishes (exactly, piece by piece)
    stationary = PPoly.from_spline(profile.spline.derivative()).roots(extrapolate=False)
    values = profile(np.concatenate([[0.0, plant.length], stationary[np.isfinite(stationary)]]))
    low, high = _fmt(values.min()), _fmt(values.max())
    samples = np.asarray(profile.value[1], dtype=float)
    s_low, s_high = _fmt(samples.min()), _fmt(samples.max())
    text = f"{samples.size} samples in [{s_low}, {s_high}]"
    if (low, high) != (s_low, s_high) and (values.min() < samples.min() or values.max() > samples.max()):
        text += f" (the cubic spline through them, the model analysed, ranges over [{low}, {high}])"
    return text


def _plant_blocks(cert: Certificate, with_controller: bool = True) -> list[_Paragraph]:
    """The plant in the user's own terms; a general plant's normal form as a secondary "as analysed" line."""
    given = cert.system if cert.given_system is None else cert.given_system
    controller = cert.controller if cert.given_controller is None else cert.given_controller
    tau = _fmt(cert.system.tau / getattr(cert.system, "time_unit", 1.0))
    law = f"; controller `{_controller_label(controller)}`" if with_controller else ""
    if not isinstance(given, GeneralHyperbolic2x2):
        return [_Paragraph(f"**Plant.** `{given!r}`{law}; round trip tau = {tau}.")]
    terms = ", ".join(f"{k} = {_profile_text(given, k)}" for k in ("lam", "mu", "a", "b", "c", "d"))
    terms += ", " + ", ".join(f"{k} = {_number(getattr(given, k))}" for k in ("q", "rho", "length", "time_unit"))
    out = [_Paragraph(f"**Plant.** GeneralHyperbolic2x2 with {terms}{law}; round trip tau = {tau} (in time units).")]
    if not given.constant_ratio:
        return out
    form = given.normal_form()
    if isinstance(cert.system, GeneralHyperbolic2x2):  # constant coefficients: the loop in closed form
        out.append(_Paragraph("Analysed as written: constant coefficients, the loop in closed form (no kernel grid)."))
    else:
        analysed = cert.controller if cert.given_controller is not None else normalize(given, controller)[1]
        out.append(
            _Paragraph(
                "As analysed: its normal form, the paper's plant (18)-(20) on [0, 1] with time in units of time_unit: "
                + _normal_form_text(form.system)
                + (f", under `{_controller_label(analysed)}`." if with_controller else ".")
            )
        )
    gain = getattr(controller, "K", None)
    if isinstance(controller, (ReflectionController, FilteredController)) and gain is not None:
        factor = form.control_gain * float(np.exp(-float(given.A(given.length)) - form.balance))
        out.append(
            _Paragraph(
                f"{type(controller).__name__} reads K in the normal form's coordinates, not in the plant's: "
                f"K = {_number(gain)} is the gain {_fmt(-float(gain) * factor + 0.0)} on the plant's u(t, L) "
                "(with the kernel terms of eq. (53))."
            )
        )
    return out


def _normal_form_text(system: Any) -> str:
    """The paper's plant ``(lam, mu, sigma_pm, sigma_mp, q, rho)`` with 6 significant digits."""
    parts = []
    for name in ("lam", "mu", "sigma_pm", "sigma_mp", "q", "rho"):
        value = getattr(system, name)
        parts.append(f"{name} = {_fmt(value) if isinstance(value, (int, float)) else 'varying'}")
    return ", ".join(parts)


def _certificate_blocks(
    cert: Certificate, index: int | None, rendered: RenderedFigures | None = None
) -> tuple[list[Any], RenderedFigures]:
    """The section of one certificate (the answer panel, its figures, the details) and its figures as drawn.

    ``rendered``: its standard figures if already drawn (:func:`render_certificate_figures`).
    """
    if rendered is None:
        rendered = render_certificate_figures(cert)
    label = _controller_label(cert.controller if cert.given_controller is None else cert.given_controller)
    head = f"{label}" if index is None else f"{index + 1}. {label}"
    cls = cert.classification
    m = cert.margin
    number = 1 if index is None else index + 1
    pictures = [_Figure(f"{number}_{_slug(caption)[:40]}", caption, png) for caption, png in rendered.pngs]
    blocks: list[Any] = [_Heading(2, head), _panel(cert), pictures[0]]
    if index is None:
        blocks += _plant_blocks(cert)
    blocks += [_Heading(3, "Details"), _Paragraph(f"**Verdict.** {cert.verdict}"), _Paragraph(_opening(cert))]
    if isinstance(cert.controller, FiniteTimeController):
        gamma_source = "principal_part (eq. (11): strongly stable when < 1)"
    elif isinstance(cert.controller, ReflectionController):
        gamma_source = "principal_part (eq. (54): strongly stable when < 1)"
    else:
        gamma_source = "principal_part (strongly stable when < 1)"
    rows = [
        ("open-loop gain rho q", _fmt(cls.rho_q), "classify (section 2)"),
        ("regime", _REGIMES.get(cls.regime, cls.regime), "classify"),
        ("gamma_0 of the difference operator, delta = 0", cert.principal_nominal.gamma_0_text, "principal_part"),
        (
            f"gamma_0 of the difference operator, delta = {cert.delta_max:g}",
            cert.principal_delayed.gamma_0_text,
            gamma_source,
        ),
        ("strongly stable for small delays", _fmt(m.strongly_stable), "delay_margin"),
        (
            "spectral abscissa, delta = 0",
            _fmt(cert.abscissa.value)
            if np.isinf(cert.abscissa.value)
            else with_accuracy(cert.abscissa.value, cert.abscissa.accuracy),
            "spectral_abscissa",
        ),
        ("nominally stable", _fmt(cert.nominally_stable), "delay_margin"),
        (
            "delay margin delta*",
            "infinity (stable for every delay)" if np.isposinf(cert.delay_margin) else cert.margin_text,
            "delay_margin",
        ),
        ("accuracy of the delay margin", _accuracy_text(cert), "certify"),
        (
            "crossing frequency at delta*",
            "none" if m.omega is None else with_accuracy(m.omega, m.omega_accuracy),
            "delay_margin",
        ),
        (
            "margin verified (residual and count)",
            _verified_text(m),
            "delay_margin",
        ),
        ("how the margin was decided", m.reason, "delay_margin"),
        (
            f"stable delay intervals in [0, {cert.delta_max:g}]",
            ", ".join(
                inner_interval_text(lo, hi, 6, accuracies=(m.end_accuracy(lo), m.end_accuracy(hi)))
                for lo, hi in m.intervals
            )
            or "none",
            "delay_margin",
        ),
        (
            "Rouché guaranteed range delta_0",
            _rouche_text(cert),
            "rouche_delay_bound (Theorem 4)" if cert.rouche is not None else "-",
        ),
        (
            "roots in the region, delta = 0",
            f"{cert.roots_nominal.count} ({_count_status(cert.roots_nominal)})",
            "find_roots",
        ),
        (
            f"roots in the region, delta = {cert.delta_max:g}",
            f"{cert.roots_delayed.count} ({_count_status(cert.roots_delayed)})",
            "find_roots",
        ),
        ("region (Re min, Re max, Im min, Im max)", ", ".join(_fmt(v, 4) for v in cert.region), "certify"),
    ]
    # the same number by two routes: crossing analysis and winding along the axis
    crossing_count = _crossing_count(cert)
    rows.append(
        (
            f"closed-loop zeros in Re s > 0 at delta = {cert.delta_max:g}",
            f"{'-' if crossing_count is None else crossing_count} (crossings); "
            f"{'no finite count' if rendered.rhp_zeros is None else rendered.rhp_zeros} (Nyquist winding)",
            "delay_margin; nyquist_response",
        )
    )
    if cert.k_region is not None:
        rows.append((f"admissible gains K on [0, {cert.delta_max:g}]", _k_region_text(cert.k_region), "k_region"))
    elif cert.k_region_error:
        rows.append(
            (f"admissible gains K on [0, {cert.delta_max:g}]", f"not certified: {cert.k_region_error}", "k_region")
        )
    blocks.append(_Table(("quantity", "value", "computed by"), tuple(rows), code_column=2))
    blocks.append(_Paragraph(f"**What is proven.** {cert.scope}"))
    if cert.claims:
        blocks.append(
            _Table(
                ("claim", "statement", "status", "computed by"),
                tuple((_at_delta_max(c.name, cert), c.statement, c.status, c.source) for c in cert.claims),
                code_column=3,
            )
        )
        for note in cert.unproven:
            blocks.append(_Paragraph(f"Not proven: {note}"))
    box_rows = tuple(
        (f"delta = {_fmt(d)}", _box_text(box), str(int(c)))
        for d, rs in ((0.0, cert.roots_nominal), (cert.delta_max, cert.roots_delayed))
        for box, c in zip(np.asarray(rs.boxes).reshape(-1, 4), rs.box_counts)
    )
    if box_rows:
        how = (
            "proven in ball arithmetic"
            if cert.roots_nominal.rigorous and cert.roots_delayed.rigorous
            else "checked in floating point"
        )
        blocks.append(_Paragraph(f"Root counts per box (argument principle with a step control, {how}):"))
        blocks.append(_Table(("loop", "box", "roots"), box_rows, summary=f"{len(box_rows)} boxes, one root count each"))
    blocks += pictures[1:]
    return blocks, rendered


def _count_status(roots: RootSet | RootMapData) -> str:
    """How a root count is known, in the words of the claims: proven, checked, or not settled.

    A root map's own count (its wider rectangle) is always a floating-point one.
    """
    if not roots.certified:
        return "not every root accounted for"
    return "proven in ball arithmetic" if getattr(roots, "rigorous", False) else "checked in floating point"


def _at_delta_max(text: str, cert: Certificate) -> str:
    """``text`` with the parameter name ``delta_max`` replaced by its value (``delta = 0.1``)."""
    return text.replace("delta_max", f"delta = {cert.delta_max:g}")


def _accuracy_text(cert: Certificate) -> str:
    """The accuracy part of :attr:`Certificate.accuracy_statement` (exact for an infinite margin)."""
    if np.isposinf(cert.delay_margin):
        return "exact: no crossing, hence no delay to estimate"
    if cert.margin_accuracy == 0.0:
        return "exact"
    text = cert.accuracy_statement.split(": ", 1)[1]
    return text.removeprefix("accuracy ")  # the row's label says it


def _opening(cert: Certificate) -> str:
    """The sentence under the verdict: what the paper says of this controller on this plant."""
    cls, controller = cert.classification, cert.controller
    given = cert.system if cert.given_system is None else cert.given_system
    normal = ""
    if isinstance(given, GeneralHyperbolic2x2):  # rho q below is the normal form's, not the plant's rho times q
        own = float(given.rho * given.q)
        if not np.isclose(cls.rho_q, own, rtol=1e-12, atol=0.0):
            normal = (
                f" Here rho q = {_fmt(cls.rho_q)} is the normal form's (the plant's rho q = {_fmt(own)} weighted by "
                "its diagonal terms a and d)."
            )
        normal += " K is read in the normal form's coordinates."
    if isinstance(controller, (FiniteTimeController, ReflectionController)):
        return cls.statement + normal  # the regimes of |rho q| for U_BS and U_BS2 (Theorems 2 to 4)
    if isinstance(controller, FilteredController) and controller.K is not None:
        a, b, K = float(controller.a), float(controller.b), float(controller.K)
        gamma = delayed_gamma(*loop_factors(cert.system, controller))
        return (
            f"Filtered U_BS2(K) with K = {_fmt(K)}, a = {_fmt(a)}, b = {_fmt(b)} (section 2.3.2): its delayed loop's "
            f"difference operator 1 - rho q e^(-tau s) + (a/b) K q e^(-(tau + delta) s) has gamma_0 = |rho q| + "
            f"|a/b| |K q| = {_fmt(gamma)}, {'below' if gamma < 1.0 else 'not below'} 1, the condition for a positive "
            "delay margin."
        )
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
            f"Open loop (U = 0), open-loop gain rho q = {_fmt(cls.rho_q)}. For the paper's controllers: "
            f"{cls.statement}{normal}"
        )
    return f"Open-loop gain rho q = {_fmt(cls.rho_q)}. For the paper's controllers: {cls.statement}{normal}"


def _rouche_text(cert: Certificate) -> str:
    """The Rouché range ``delta_0`` rounded down (a printed lower bound stays one)."""
    if cert.rouche is None:
        return "not applicable (U_BS and U_BS2 only)"
    delta_0 = float(cert.rouche.delta_0)
    return "infinity" if np.isposinf(delta_0) else lower_bound_text(delta_0)


def _verified_text(m: Any) -> str:
    """Whether the margin was checked independently, or why there was nothing to check."""
    if not m.without_crossing:
        return _fmt(m.verified)
    if np.isposinf(m.margin):
        return "not needed: infinite, no crossing frequency"
    return "not needed: zero, decided without a crossing frequency"


def _interval(lo: float, hi: float) -> str:
    """``[lo, hi]`` printed around itself, with the digits needed to tell the ends apart.

    ``lo`` is rounded down and ``hi`` up, so the printed interval contains the proven one (to
    the nearest, ``[0.123456789, 0.123457999]`` would print as ``[0.123457, 0.123458]``, which
    leaves ``lo`` out). A side of zero width is printed as its number in full.
    """
    if lo == hi:
        return repr(float(lo))
    digits = 4
    while digits < 17 and _fmt(lo, digits) == _fmt(hi, digits):
        digits += 1
    return f"[{_trimmed(lower_bound_text(lo, digits))}, {_trimmed(upper_bound_text(hi, digits))}]"


def _trimmed(text: str) -> str:
    """A decimal numeral without the trailing zeros of its fraction (``-1.000`` -> ``-1``)."""
    mantissa, _, exponent = text.partition("e")
    if "." in mantissa:
        mantissa = mantissa.rstrip("0").rstrip(".")
    return mantissa + ("e" + exponent if exponent else "")


def _box_text(box: Any) -> str:
    """A root box as ``Re [a, b] x Im [c, d]`` (a side of zero width as a single number)."""
    re_lo, re_hi, im_lo, im_hi = (float(v) for v in box)
    return f"Re {_interval(re_lo, re_hi)} x Im {_interval(im_lo, im_hi)}"


def _end_text(end: Any) -> str:
    """What closes an interval at a :class:`~nrobust.hyperbolic.analyses.GainEnd`, in words."""
    omega = with_accuracy(end.omega, end.omega_accuracy)
    if end.kind == "crossing":
        return f"crossing (a root at i ({omega}) for delta = delta_max)"
    if end.kind == "pair_birth":
        delay = with_accuracy(end.delay, end.delay_accuracy)
        return f"pair birth (|A| = |B| touches at w = {omega}, crossing delay {delay})"
    if end.kind == "nominal":
        return f"nominal loop unstable (a root at i ({omega}) for delta = 0)"
    if end.kind == "strong_stability":
        return "strong-stability limit |rho q| + |K q| = 1"
    return "bisection on delay margins"


def _k_region_text(kreg: Any) -> str:
    """The admissible intervals of a :class:`~nrobust.hyperbolic.analyses.KRegion`, the kind of each end
    and their accuracy."""
    if not kreg.intervals:
        return "none"
    parts = [
        f"({with_accuracy(lo.K, lo.accuracy)}, {with_accuracy(hi.K, hi.accuracy)}): lower end {_end_text(lo)}, "
        f"upper end {_end_text(hi)}"
        for lo, hi in kreg.ends
    ] or [
        f"({with_accuracy(lo, lo_acc)}, {with_accuracy(hi, hi_acc)})"
        for (lo, hi), (lo_acc, hi_acc) in zip(kreg.intervals, kreg.end_accuracies)
    ]
    how = "proven for the PDE" if kreg.ends_proven else "verified"
    return f"{'; '.join(parts)}; each end {how} to {_fmt(kreg.tol, 3)} (paper bound |K| < {_fmt(kreg.paper_bound)})"


# ---------------------------------------------------------------------- renderers
def _markdown(blocks: Sequence[Any], fig_paths: Mapping[str, str]) -> str:
    out: list[str] = []
    for b in blocks:
        if isinstance(b, _Heading):
            out.append("#" * b.level + " " + b.text)
        elif isinstance(b, _Paragraph):
            out.append(b.text)
        elif isinstance(b, _Panel):
            out.append(f"> **{b.title}**")
            for line in b.lines:
                out += [">", f"> {line}"]
        elif isinstance(b, _Table):
            if b.summary:
                out.append(f"<details><summary>{html.escape(b.summary)}</summary>\n")
            out.append("| " + " | ".join(b.header) + " |")
            out.append("|" + "|".join("---" for _ in b.header) + "|")
            out += ["| " + " | ".join(c.replace("|", "\\|") for c in _cells(b, row)) + " |" for row in b.rows]
            if b.summary:
                out.append("\n</details>")
        elif isinstance(b, _Figure):
            out.append(f"![{b.caption}]({fig_paths[b.name]})\n\n*{b.caption}*")
        out.append("")
    return "\n".join(out)


#: Function names of a "computed by" column (``delay_margin``, ``classify``...), set as code.
_FUNCTION = re.compile(r"\b([a-z][a-z0-9]*(?:_[a-z0-9]+)+|classify|certify)\b")


def _cells(table: _Table, row: Sequence[str]) -> list[str]:
    """A row's cells, the function names of the table's code column as code spans."""
    return [_FUNCTION.sub(r"`\1`", c) if k == table.code_column else c for k, c in enumerate(row)]


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
    ".answer{border-left:.4em solid #2a6fb0;background:#f2f6fb;padding:.4em 1em;margin:1em 0}"
    ".answer p{margin:.4em 0}summary{cursor:pointer;margin:.5em 0}"
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
        elif isinstance(b, _Panel):
            out.append(f'<div class="answer"><p><strong>{_inline(b.title)}</strong></p>')
            out += [f"<p>{_inline(line)}</p>" for line in b.lines]
            out.append("</div>")
        elif isinstance(b, _Table):
            if b.summary:
                out.append(f"<details><summary>{html.escape(b.summary)}</summary>")
            out.append("<table><tr>" + "".join(f"<th>{_inline(h)}</th>" for h in b.header) + "</tr>")
            out += ["<tr>" + "".join(f"<td>{_inline(c)}</td>" for c in _cells(b, row)) + "</tr>" for row in b.rows]
            out.append("</table>")
            if b.summary:
                out.append("</details>")
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
    figures: Sequence[tuple[str, Figure | bytes]] = (),
    title: str = "nrobust delay-robustness report",
    intro: Sequence[str] = (),
    rendered: Sequence[RenderedFigures] | None = None,
    answer: tuple[str, Sequence[str]] | None = None,
) -> ReportFiles:
    """Write a Markdown report, a self-contained HTML report and the certificates' JSON.

    Parameters
    ----------
    certificates : Certificate or sequence of Certificate
        From :func:`nrobust.certify`; one section each, with its standard figures
        (:func:`certificate_figures`).
    out_dir : path-like
        Output directory (created if needed).
    figures : sequence of (caption, matplotlib Figure or PNG bytes), optional
        Further figures (simulations, stability charts...), appended in order; a figure
        given as PNG bytes (:func:`nrobust.plots.base.figure_png`) is embedded as is.
    title : str
        Report title.
    intro : sequence of str
        Paragraphs placed after the title.
    rendered : sequence of RenderedFigures, optional
        The standard figures of each certificate, already drawn
        (:func:`render_certificate_figures`, e.g. in the worker that certified it); by
        default they are drawn here.
    answer : (str, sequence of str), optional
        The answer of a report with several certificates, set apart right after the title and
        before ``intro``: a headline and a few lines (each section keeps its own panel).

    Returns
    -------
    ReportFiles
    """
    certs = [certificates] if isinstance(certificates, Certificate) else list(certificates)
    if not certs or not all(isinstance(c, Certificate) for c in certs):
        raise ParameterError("certificates", "a Certificate or a non-empty sequence of Certificate", certificates)
    for k, item in enumerate(figures):
        if not (
            isinstance(item, tuple)
            and len(item) == 2
            and isinstance(item[0], str)
            and (isinstance(item[1], bytes) or hasattr(item[1], "savefig"))
        ):
            raise ParameterError(f"figures[{k}]", "a (caption, matplotlib Figure or PNG bytes) pair", item)
    if rendered is not None and (
        len(rendered) != len(certs) or not all(isinstance(r, RenderedFigures) for r in rendered)
    ):
        raise ParameterError("rendered", f"one RenderedFigures per certificate ({len(certs)})", rendered)
    out = Path(out_dir)
    fig_dir = out / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)

    blocks: list[Any] = [_Heading(1, title)]
    if answer is not None:
        blocks.append(_Panel(answer[0], tuple(answer[1])))
    blocks += [_Paragraph(p) for p in intro]
    if len(certs) > 1:  # one plant, several controllers: the plant once, each controller in its section
        blocks += _plant_blocks(certs[0], with_controller=False)
    with threadpool_limits(1):  # the chains' small eigenvalue problems: competing BLAS threads slow them tenfold
        for k, cert in enumerate(certs):
            section, _ = _certificate_blocks(
                cert, None if len(certs) == 1 else k, None if rendered is None else rendered[k]
            )
            blocks += section
    if figures:
        blocks.append(_Heading(2, "Further figures"))
        for j, (caption, fig) in enumerate(figures):
            png = fig if isinstance(fig, bytes) else figure_png(fig)
            blocks.append(_Figure(f"extra_{j + 1}_{_slug(caption)[:40]}", caption, png))
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
    return ReportFiles(md, page, tuple(jsons), tuple(written))
