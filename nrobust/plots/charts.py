"""Charts of the parameter studies: the stability chart, the trade-off, the chart of a sweep."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ParameterError
from .base import NrobustPlot, get_axes

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from ..sweeps.result import SweepResult

__all__ = ["delay_chart_plot", "stability_chart_plot", "sweep_chart", "tradeoff_plot"]


def stability_chart_plot(
    chart: Any,
    ax: Axes | None = None,
    k_bound: float | None = None,
    rouche: tuple[ArrayLike, ArrayLike] | None = None,
) -> NrobustPlot:
    """Stability chart in ``(K, delta)``: the grid, the exact boundary, the paper's bound.

    Parameters
    ----------
    chart : StabilityChart
        From :func:`nrobust.hyperbolic.analyses.stability_chart` (``quantity="count"``).
    ax : matplotlib Axes, optional
    k_bound : float, optional
        The sufficient bound ``|K| < (1 - |rho q|)/|q|`` of eq. (54)
        (``classify(system).k_bound``), drawn as two vertical lines.
    rouche : (Ks, delta_0) pair, optional
        The guaranteed delays ``delta_0(K)`` of Theorem 4's proof
        (:func:`nrobust.hyperbolic.analyses.tradeoff` gives them as ``rouche_bounds``).
        ``delta_0`` depends on ``K`` through ``|K|`` only (``epsilon_0 = 1 - |q rho| - |K q|``),
        so a curve given for ``K >= 0`` only is drawn for ``-K`` too.

    Returns
    -------
    NrobustPlot
        ``lines["stable"]`` (grid points with no unstable zero), ``lines["unstable"]``,
        ``lines["margin"]`` (the exact boundary ``delta*(K)``), ``lines["crossings"]`` (every
        crossing delay up to ``max(deltas)``), ``lines["paper_bound"]``, ``lines["rouche"]``.
    """
    if getattr(chart, "quantity", None) != "count":
        raise ParameterError("chart", 'a StabilityChart with quantity "count"', chart)
    ax = get_axes(ax)
    Ks, deltas, values = chart.Ks, chart.deltas, chart.values
    KK, DD = np.meshgrid(Ks, deltas, indexing="ij")
    stable = values == 0
    lines: dict[str, list[Any]] = {}
    lines["stable"] = ax.plot(KK[stable], DD[stable], "s", color="tab:green", ms=3, alpha=0.6, label="stable")
    lines["unstable"] = ax.plot(KK[~stable], DD[~stable], "s", color="tab:red", ms=3, alpha=0.35, label="unstable")
    top = float(deltas.max())
    shown = np.where(np.isfinite(chart.margins), np.minimum(chart.margins, top), top)
    lines["margin"] = ax.plot(Ks, shown, "-", color="k", lw=1.5, label="delay margin delta*(K)")
    kc, dc = [], []
    for K, rows in zip(Ks, chart.boundaries):
        rows = np.asarray(rows).reshape(-1, 3)
        kc += [K] * rows.shape[0]
        dc += list(rows[:, 0])
    lines["crossings"] = ax.plot(kc, dc, ".", color="0.3", ms=3, label="crossing delays") if kc else []
    lines["paper_bound"] = []
    if k_bound is not None:
        kb = float(k_bound)
        for k, x in enumerate((-kb, kb)):
            lines["paper_bound"].append(
                ax.axvline(
                    x, color="C0", ls="--", lw=1.0, label="|K| = (1 - |rho q|)/|q|, eq. (54)" if k == 0 else None
                )
            )
    lines["rouche"] = []
    if rouche is not None:
        rk, rd = (np.asarray(v, dtype=float).ravel() for v in rouche)
        if rk.shape != rd.shape:
            raise ParameterError("rouche", "a pair (Ks, delta_0) of equal lengths", rouche)
        if rk.size and np.all(rk >= 0.0):  # delta_0 depends on |K| only: mirror the curve to K < 0
            keep = rk > 0.0
            rk, rd = np.concatenate([-rk[keep][::-1], rk]), np.concatenate([rd[keep][::-1], rd])
        order = np.argsort(rk, kind="stable")
        lines["rouche"] = ax.plot(
            rk[order], np.minimum(rd[order], top), "-.", color="C1", label="Rouche delta_0(K), Theorem 4"
        )
    ax.set_xlabel("K")
    ax.set_ylabel("delta")
    ax.set_ylim(0.0, top * 1.02)
    ax.set_title("Stability chart of U_BS2(K)", fontsize="small")
    ax.legend(fontsize="x-small", loc="upper right")
    return NrobustPlot(lines, ax, ax.figure)


def delay_chart_plot(margin: Any, ax: Axes | None = None, margin_text: str | None = None) -> NrobustPlot:
    """Stability chart in the loop delay: zeros in ``Re s > 0`` against ``delta``, the margin marked.

    Draws what :func:`nrobust.margins.delay_margin` computed: the number of closed-loop zeros
    in ``Re s > 0`` on each delay window of ``[0, delta_max]`` (:attr:`DelayMargin.counts
    <nrobust.margins.margin.DelayMargin>`), the stable windows shaded green and the unstable
    ones red, and the delay margin ``delta*`` as a vertical line. A loop whose difference
    operator is not strongly stable (no windows: infinitely many zeros in ``Re s > 0`` for
    every small delay) is shaded red from ``0`` on; an infinite margin is written as such.

    Parameters
    ----------
    margin : DelayMargin
        From :func:`nrobust.margins.delay_margin` or :func:`nrobust.delay_margin` with a
        finite ``delta_max``.
    ax : matplotlib Axes, optional
    margin_text : str, optional
        The margin as the legend writes it (e.g. ``Certificate.margin_text``, with the digits
        its accuracy supports); default 6 significant digits.

    Returns
    -------
    NrobustPlot
        ``lines["count"]`` (the step curve of the count; no data without windows),
        ``lines["stable"]`` and ``lines["unstable"]`` (the shaded windows), ``lines["margin"]``
        (the line at ``delta*``; empty when ``delta*`` is not in ``(0, delta_max]``),
        ``lines["note"]`` (the text of an infinite margin, a margin beyond the chart or of a
        loop destabilised by every delay; empty otherwise).
    """
    top = float(getattr(margin, "delta_max", np.nan))
    if not (np.isfinite(top) and top > 0.0 and hasattr(margin, "counts")):
        raise ParameterError("margin", "a DelayMargin computed with a finite delta_max > 0", margin)
    ax = get_axes(ax)
    value = float(margin.margin)
    text = margin_text or ("infinity" if np.isposinf(value) else f"{value:.6g}")
    lines: dict[str, list[Any]] = {"stable": [], "unstable": [], "margin": [], "note": []}
    xs: list[float] = []
    ys: list[float] = []
    for lo, hi, n in margin.counts:
        xs += [lo, hi]
        ys += [n, n]
        key, color = ("stable", "tab:green") if n == 0 else ("unstable", "tab:red")
        label = None if lines[key] else ("stable" if n == 0 else "unstable")
        lines[key].append(ax.axvspan(lo, hi, color=color, alpha=0.18, lw=0, label=label))
    lines["count"] = ax.plot(xs, ys, "-", color="k", lw=1.2, label="zeros in Re s > 0")
    note = ""
    if not margin.counts:
        unstable = not margin.nominally_stable or (value == 0.0 and not margin.strongly_stable)
        key, color = ("unstable", "tab:red") if unstable else ("stable", "tab:green")
        lines[key].append(ax.axvspan(0.0, top, color=color, alpha=0.18, lw=0, label=key))
        if value == 0.0 and not margin.strongly_stable:
            note = "infinitely many zeros in Re s > 0 for every delay > 0 (root chains): delta* = 0"
    if np.isposinf(value):
        note = "delta* = infinity: stable for every delay"
    elif 0.0 < value <= top:
        lines["margin"].append(ax.axvline(value, color="tab:red", lw=1.5, label=f"delta* = {text}"))
    elif value > top:
        note = f"delta* = {text}, beyond this chart (stable on all of it)"
    if note:
        lines["note"].append(
            ax.text(0.5, 0.5, note, transform=ax.transAxes, ha="center", va="center", fontsize="small")
        )
    ax.set_xlim(0.0, top)
    ax.set_ylim(-0.2, max([1.0, *ys]) * 1.15)
    ax.set_xlabel("loop delay delta")
    ax.set_ylabel("zeros in Re s > 0")
    ax.legend(fontsize="x-small", loc="upper left")
    return NrobustPlot(lines, ax, ax.figure)


def tradeoff_plot(tradeoff: Any, ax: Axes | None = None, annotate: bool = True) -> NrobustPlot:
    """Decay rate against delay margin as the gain ``K`` varies (the paper's trade-off).

    Parameters
    ----------
    tradeoff : Tradeoff
        From :func:`nrobust.hyperbolic.analyses.tradeoff`.
    ax : matplotlib Axes, optional
    annotate : bool
        Write ``K`` next to the points.

    Returns
    -------
    NrobustPlot
        ``lines["curve"]`` with x = delay margins (finite ones) and y = decay rates.
    """
    ax = get_axes(ax)
    Ks = np.asarray(tradeoff.Ks, dtype=float)
    m = np.asarray(tradeoff.margins, dtype=float)
    r = np.asarray(tradeoff.decay_rates, dtype=float)
    ok = np.isfinite(m) & np.isfinite(r)
    lines: dict[str, list[Any]] = {}
    lines["curve"] = ax.plot(m[ok], r[ok], "o-", color="C0", ms=4, label="U_BS2(K)")
    if annotate:
        for K, x, y in zip(Ks[ok], m[ok], r[ok]):
            ax.annotate(f"{K:.3g}", (x, y), textcoords="offset points", xytext=(3, 3), fontsize=6)
    ax.set_xlabel("delay margin delta*")
    ax.set_ylabel("decay rate (- spectral abscissa)")
    ax.set_title("Decay rate against delay margin", fontsize="small")
    hidden = int(np.sum(~ok))
    if hidden:
        ax.text(0.02, 0.02, f"{hidden} gain(s) with infinite margin not shown", transform=ax.transAxes, fontsize=7)
    return NrobustPlot(lines, ax, ax.figure)


def sweep_chart(result: SweepResult, swept: Sequence[str], plot: Mapping[str, str], sampling: bool) -> Figure:
    """The chart of a sweep: a curve for one swept name, a map for two, histograms for samples.

    Parameters
    ----------
    result : SweepResult
        The table.
    swept : sequence of str
        The names varied by the sweep.
    plot : mapping
        Optional ``x`` (a swept parameter) and ``y`` (a numeric result column).
    sampling : bool
        True for a Monte Carlo study: histograms of the result columns.

    Returns
    -------
    matplotlib.figure.Figure
        A figure on an Agg canvas (no display needed).
    """
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    table = result.table()
    numeric = [c for c in result.result_columns if table.dtype[c].kind == "f"]
    y = plot.get("y", numeric[0] if numeric else None)
    if y is not None and y not in numeric:
        raise ParameterError("plot.y", f"a numeric result column: one of {numeric}", y)
    varying = [k for k in swept if len({repr(p.get(k)) for p in result.points}) > 1]
    x = plot.get("x", varying[0] if varying else (swept[0] if swept else None))
    if x is not None and x not in result.parameter_columns:
        raise ParameterError("plot.x", f"a swept parameter: one of {list(result.parameter_columns)}", x)

    ok = table["status"] == "ok"
    title = f"{result.n_ok} ok, {result.n_failed} failed"
    if sampling and y is not None:
        shown = [y, *[c for c in numeric if c != y]][:3]
        fig = Figure(figsize=(4.0 * len(shown), 3.6), layout="constrained")
        FigureCanvasAgg(fig)
        for i, col in enumerate(shown):
            ax = fig.add_subplot(1, len(shown), i + 1)
            vals = table[col][ok]
            finite = vals[np.isfinite(vals)]
            n_inf = int(np.sum(np.isposinf(vals)))
            if finite.size:
                ax.hist(finite, bins=max(5, min(50, 2 * int(np.sqrt(finite.size)))), color="C0")
            else:
                ax.text(0.5, 0.5, f"no finite {col}", ha="center", va="center", transform=ax.transAxes)
            ax.set_xlabel(col)
            ax.set_ylabel("samples")
            ax.set_title(f"{n_inf} infinite" if n_inf else "", fontsize="small")
        fig.suptitle(title, fontsize="medium")
        return fig
    fig = Figure(figsize=(6.4, 4.4), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    if y is None:
        ax.text(0.5, 0.5, "no numeric result", ha="center", va="center", transform=ax.transAxes)
    elif x is not None and table.dtype[x].kind in "fiu" and len(varying) == 2 and table.dtype[varying[1]].kind in "fiu":
        x2 = varying[1] if x == varying[0] else varying[0]
        xs, ys = np.unique(table[x]), np.unique(table[x2])
        grid_vals = np.full((ys.size, xs.size), np.nan)
        for row in table[ok]:
            grid_vals[np.searchsorted(ys, row[x2]), np.searchsorted(xs, row[x])] = row[y]
        finite = grid_vals[np.isfinite(grid_vals)]
        infinite = np.isposinf(grid_vals)
        low, high = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
        if high == low:  # one finite value: a scale above it (matplotlib's would straddle it, e.g. negative margins)
            high = low + max(abs(low), 1.0)
        # the finite values on the colour scale; an infinite value is no colour of the scale
        # (its top would read as the largest finite value): white, hatched, in the legend
        # cells bounded half-way between samples (geometrically on a log-spaced axis, which is
        # then drawn in log scale), and a dot at each sample: the values are the samples'
        (x_edges, x_log), (y_edges, y_log) = _cell_edges(xs), _cell_edges(ys)
        mesh = ax.pcolormesh(
            x_edges,
            y_edges,
            np.ma.masked_invalid(grid_vals),
            shading="flat",
            cmap=matplotlib.colormaps["viridis"].with_extremes(bad="lightgray"),
            vmin=low,
            vmax=high,
        )
        fig.colorbar(mesh, ax=ax, label=f"{y} (finite)")
        handles: list[Any] = []
        if infinite.any():
            ax.pcolor(
                x_edges,
                y_edges,
                np.ma.masked_where(~infinite, np.ones_like(grid_vals)),
                shading="flat",
                cmap=ListedColormap(["white"]),
                hatch="///",
                edgecolor="0.25",
                linewidth=0.0,
            )
            handles.append(Patch(facecolor="white", edgecolor="0.25", hatch="///", label=f"{y} = inf"))
        if (~ok).any() or np.isnan(grid_vals).any():
            handles.append(Patch(facecolor="lightgray", label="failed or missing"))
        gx, gy = np.meshgrid(xs, ys)
        ax.plot(gx.ravel(), gy.ravel(), ".", color="0.15", ms=2.0)
        handles.append(Line2D([], [], ls="", marker=".", color="0.15", ms=4.0, label="sample (cells half-way between)"))
        if x_log:
            ax.set_xscale("log")
        if y_log:
            ax.set_yscale("log")
        if handles:
            ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.0, -0.12), ncol=2, fontsize="small")
        ax.set_xlabel(x)
        ax.set_ylabel(x2)
    elif x is not None and table.dtype[x].kind in "fiu":
        xv, yv = table[x][ok].astype(float), table[y][ok]
        fin = np.isfinite(yv)
        # every point in x order, NaN where the value is infinite or failed: the line has a gap
        # there instead of joining the finite points on either side
        x_all = table[x].astype(float)
        y_all = np.where(ok & np.isfinite(table[y]), table[y], np.nan)
        order = np.argsort(x_all, kind="stable")
        ax.plot(x_all[order], y_all[order], "o-", ms=3, label=y)
        edge = ax.get_xaxis_transform()  # x in data, y in axes units: markers on the frame
        if (~fin).any():
            ax.plot(xv[~fin], np.full((~fin).sum(), 0.97), "^", color="C1", transform=edge, label=f"{y} = inf")
        if (~ok).any():
            ax.plot(
                table[x][~ok].astype(float), np.full((~ok).sum(), 0.03), "x", color="C3", transform=edge, label="failed"
            )
        ax.set_xlabel(x)
        ax.set_ylabel(y)
        ax.legend(loc="best", fontsize="small")
    else:
        yv = table[y]
        ax.plot(np.arange(len(yv))[ok], yv[ok], "o", ms=3)
        ax.set_xlabel("point index")
        ax.set_ylabel(y)
    ax.set_title(title, fontsize="medium")
    return fig


def _cell_edges(values: np.ndarray) -> tuple[np.ndarray, bool]:
    """The edges of the cells around sorted samples, and whether the axis is log-spaced.

    A positive axis whose ratios are more even than its differences (a geometric sweep, say
    ``K = 1e-3 ... 1e-1``) is log-spaced: its cells end at the geometric means of neighbours
    and it is drawn in log scale, so each cell is centred on its sample as the eye reads it.
    Otherwise the cells end at the arithmetic midpoints. A single sample gets a cell of width
    1 (or of ``|value|``) around it.
    """
    v = np.asarray(values, dtype=float)
    if v.size == 1:
        half = 0.5 * (abs(v[0]) or 1.0)
        return np.array([v[0] - half, v[0] + half]), False
    steps = np.diff(v)
    log = bool(v[0] > 0 and v.size > 2)
    if log:
        ratios = np.diff(np.log(v))
        log = bool(np.ptp(ratios) / np.mean(ratios) < np.ptp(steps) / np.mean(steps))
    w = np.log(v) if log else v
    inner = 0.5 * (w[1:] + w[:-1])
    edges = np.concatenate([[w[0] - (inner[0] - w[0])], inner, [w[-1] + (w[-1] - inner[-1])]])
    return (np.exp(edges) if log else edges), log
