"""``nrobust design``: a controller for the plant of a SYSTEM.toml file, designed and certified.

The plant is the ``[system]`` section of the file (the ``[controller]`` and ``[analysis]``
sections may be left out; when given they are checked as for ``nrobust analyze``, and not used:
:func:`~nrobust.config.load_system_file` with ``for_design=True``). The family, the
objective, the requirement and the parameters' bounds come from the file's ``[design]``
section (:func:`nrobust.config.load_system_file`), each overridden by the command line's
options when given:

* ``family = "reflection"``: ``U_BS2(K)`` (eq. (53)), the gain solved from the equation of its
  kind (:func:`nrobust.hyperbolic.analyses.design_reflection`);
* ``family = "output_feedback"``: the same law on the state predicted from the measurement
  ``v(t, 0)`` (:class:`~nrobust.hyperbolic.loops.controllers.OutputFeedback`, with the
  observer's assumed actuation delay ``observer_delay``);
* ``family = "collocated_output_feedback"``: the same law on the estimate of the collocated
  observer from the measurement ``u(t, 1)``
  (:class:`~nrobust.hyperbolic.loops.controllers.CollocatedOutputFeedback`, ``observer_delay``
  likewise; ``design_reflection(..., output_feedback=True, collocated=True)``);
* ``family = "filtered"``: U_BS2(K) through the filter ``(1 + a s)/(1 + b s)``, a local
  optimisation over the free ones of ``K``, ``a``, ``b``
  (:func:`nrobust.hyperbolic.analyses.design_filtered`);
* ``family = "state_feedback"``: ``U = k u(t, L) + int_0^L g_u u + g_v v dx`` with ``g_u``, ``g_v`` on
  the basis ``(x / L)^j`` of the powers ``basis``, a local optimisation over ``k`` and the
  coefficients (:func:`nrobust.hyperbolic.analyses.design_state_feedback`), on the plant as written;
* ``family = "nplusm"`` (an ``NPlusMSystem`` file): the gain matrix ``K`` of ``U = K u(t - delta, 1)``,
  a local optimisation of its entries (:func:`nrobust.hyperbolic.nplusm.design_nplusm_gains`).

Written: ``design.json`` (the design with its certificate), ``design.md`` (the design in words,
each number with the digits its accuracy supports) and ``design.png`` (the delay margin against
``K`` with the requirement and the design marked, the decay rate at ``delta = 0`` against ``K``, and the
trade-off: the best decay rate of the sampled gains against the margin they keep; for the filtered law, with the
designed filter; for the state feedback, the designed integral gains and the margin against ``k``
with them; for ``n + m``, the certified margin along the gains ``t K``), as one set with
``manifest.json``.
"""

from __future__ import annotations

import io
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .._digits import inner_interval_text, with_accuracy
from .._json import json_safe
from ..config import DESIGN_FAMILIES, NPLUSM_TYPE, OBSERVER_FAMILIES, Monomial, load_system_file
from ..design import DelayWindow, GainDesign, best_margin
from ..errors import CertificationError, ParameterError
from ..hyperbolic.analyses.design import DESIGN_OBJECTIVES, ReflectionDesign, design_reflection
from ..hyperbolic.analyses.filter_design import (
    FilteredDesign,
    default_filter_bounds,
    design_filtered,
    filtered_loop,
)
from ..hyperbolic.analyses.margin import delay_margin
from ..hyperbolic.analyses.state_design import (
    StateFeedbackDesign,
    default_state_k_bounds,  # the design's own default bounds of k, for its trade-off figure
    design_state_feedback,
    state_feedback_loop,
)
from ..hyperbolic.loops.controllers import (
    CollocatedOutputFeedback,
    Controller,
    OutputFeedback,
    ReflectionController,
    loop_factors,
)
from ..hyperbolic.nplusm.design import NPlusMGainDesign, design_nplusm_gains, principal_gamma
from ..hyperbolic.nplusm.margin import NPlusMMargin, multi_actuator_delay_margin, nplusm_delay_margin
from ..hyperbolic.nplusm.system import NPlusMSystem
from ..hyperbolic.plants.general import GeneralHyperbolic2x2
from ..margins.gain import AffineGainLoop
from ..roots import spectral_abscissa
from .outputs import RunOutputs, check_output_dir

__all__ = ["design_summary", "run_design"]


def _edge(system: Any, result: ReflectionDesign) -> dict[str, Any] | None:
    """The margins just inside and just past a design on the end of the admissible gains (None elsewhere).

    A best decay rate under a required margin sits on an end of the gains that meet it: the
    margin falls below the requirement past it, by a jump where a crossing pair is born. The
    margins at ``K -+ h`` (``h`` = 1e-6 of the searched interval) show on which side the
    requirement holds and how steep the edge is; ``accuracy_below`` and ``accuracy_above`` bound
    the error of each margin (:attr:`~nrobust.margins.DelayMargin.accuracy`, None when not known).
    """
    d = result.design
    if d.end is None:
        return None
    h = 1e-6 * float(d.bounds[1] - d.bounds[0])
    observer = result.controller if isinstance(result.controller, (OutputFeedback, CollocatedOutputFeedback)) else None
    edge: dict[str, Any] = {"step": h}
    for name, K in (("below", d.K - h), ("above", d.K + h)):
        law: Controller = ReflectionController(K)
        if observer is not None:
            law = type(observer)(law, observer.observer_delay)
        dm = delay_margin(system, law)
        edge[f"margin_{name}"] = float(dm.margin)
        edge[f"accuracy_{name}"] = dm.accuracy
    return edge


def _value_accuracy(d: GainDesign) -> float | None:
    """The accuracy of ``d.value``: the width of its bracket plus the accuracy of its computation at the design
    (the abscissa's for the decay rate, the certified margin's for the margin; None when that is not known).

    A design on a bound of ``K`` has a bracket of width 0, but its value is still a computed abscissa or margin.
    """
    _, v_acc = d.accuracy
    if d.scenario_abscissae:  # the least rate of the loop and the scenarios
        own = d.least_rate_accuracy
    else:
        own = d.abscissa.accuracy if d.objective == "decay_rate" else d.certificate.accuracy
    return None if own is None else v_acc + own


def _window_text(window: DelayWindow) -> str:
    """The verdict of ``window`` in words, each end of the stability window holding it named for what it is.

    :attr:`DelayWindow.reason` calls both ends crossing delays; an end is also ``delta = 0`` (the loop stable
    without delay) or the end ``2 d_max + 1`` of the delays searched (no crossing delay up to it).
    """
    if not window.stable or window.enclosing is None:
        return f"{window.reason}, {window.certified}"
    lo, hi = window.enclosing
    dm = window.margin
    crossing = {t for c in dm.crossings for t in c.delays}
    low = "delta = 0 (stable without delay)" if lo == 0.0 else "a crossing delay"
    if hi in crossing:
        high = "a crossing delay"
    elif hi == dm.delta_max:
        high = "the end 2 d_max + 1 of the delays searched (no crossing delay up to it)"
    else:
        high = "the end of the stability window"
    window_text = inner_interval_text(lo, hi, accuracies=(dm.end_accuracy(lo), dm.end_accuracy(hi)))
    return f"stable on the window {window_text}, from {low} to {high}, {window.certified}"


def _edge_margin_text(edge: dict[str, Any], side: str) -> str:
    """The margin on ``side`` (``"below"`` or ``"above"``) of an :func:`_edge`, with its accuracy."""
    margin = float(edge[f"margin_{side}"])
    return "infinity" if np.isposinf(margin) else with_accuracy(margin, edge[f"accuracy_{side}"])


def _feasible_text(d: GainDesign) -> str:
    """The intervals of gains meeting the requirement, each end said to be a bound of ``K`` or solved."""
    spans = []
    for a, b in d.feasible:
        bound = (a == d.bounds[0], b == d.bounds[1])
        how = {
            (True, True): "both ends the bounds of K",
            (True, False): "the lower end the bound of K, the upper solved from its equation",
            (False, True): "the lower end solved from its equation, the upper the bound of K",
            (False, False): "both ends solved from their equations",
        }[bound]
        spans.append(f"{inner_interval_text(a, b)} ({how})")
    return ", ".join(spans)


def _reflection_markdown(
    path: Path,
    result: ReflectionDesign,
    margin_at_least: float | None = None,
    edge: dict[str, Any] | None = None,
) -> list[str]:
    d, cert = result.design, result.design.certificate
    what = "delay margin" if d.objective == "margin" else "decay rate at delta = 0"
    if result.corner_abscissae:
        what = f"least decay rate at delta = 0 of the nominal plant and the {len(result.corner_abscissae)} corners"
    need = "" if margin_at_least is None else f" with a delay margin of at least {margin_at_least:g}"
    k_acc, _ = d.accuracy
    law = "U_BS2(K)"
    if isinstance(result.controller, (OutputFeedback, CollocatedOutputFeedback)):
        if isinstance(result.controller, OutputFeedback):
            law += " on the state predicted from v(t, 0)"
        else:
            law += " on the collocated observer's estimate from u(t, 1)"
        if result.controller.observer_delay:
            law += f" (the observer assumes an actuation delay {result.controller.observer_delay:g})"
    lines = [
        f"# Design of {law} for {path.name}",
        "",
        f"- objective: the largest {what}{need}, K in [{float(d.bounds[0])!r}, {float(d.bounds[1])!r}]",
        f"- designed gain: K = {with_accuracy(d.K, k_acc)} ({d.kind})",
        f"- {what}: {with_accuracy(d.value, _value_accuracy(d))}",
        f"- delay margin of the designed loop: {with_accuracy(cert.margin, cert.accuracy)}, {d.certified} "
        f"({cert.method}); about {cert.scope}",
    ]
    if d.objective == "margin" or result.corner_abscissae:
        nominal = " of the nominal plant" if result.corner_abscissae else ""
        lines.append(f"- decay rate at delta = 0{nominal}: {with_accuracy(d.decay_rate, d.abscissa.accuracy)}")
    if d.end is not None:
        end_accuracy = d.end.accuracy if d.end.accuracy is not None or d.end.K != d.K else k_acc
        which = "meeting the requirement" if d.delays is not None else "with a large enough margin"
        lines.append(
            f"- the end of the gains {which}: K = {with_accuracy(d.end.K, end_accuracy)}, "
            f"{d.end.kind.replace('_', ' ')} at w = {with_accuracy(d.end.omega, d.end.omega_accuracy)}, "
            f"delay {with_accuracy(d.end.delay, d.end.delay_accuracy)}"
        )
    if d.delays is not None:
        d_lo, d_hi = d.delays
        met = all(w.stable for w in d.windows)
        proven = met and all(w.certified == "proven" for w in d.windows)
        lines.append(
            f"- requirement: exponentially stable for every delay in [{float(d_lo)!r}, {float(d_hi)!r}]: "
            + ("met, proven in ball arithmetic" if proven else "met, checked in floating point" if met else "not met")
        )
        for n, w in enumerate(d.windows):
            which = "the designed loop" if n == 0 else f"the plant with speed errors {_corner(result, n - 1)}"
            lines.append(f"  - {which}: {_window_text(w)}")
        if d.feasible:
            lines.append(f"- gains meeting the requirement: {_feasible_text(d)}")
    if result.tolerance is not None:
        t = result.tolerance
        verdict = "met" if t.met else "not met"
        lines.append(f"- speed tolerance {float(t.eps)!r} on lam and mu: {verdict}, {t.certified}")
        lines.append(f"  - {t.statement}; about {t.scope}")
    lines += _corner_rate_lines(result)
    if edge is not None:
        lines.append(
            f"- on the edge: the margin is {_edge_margin_text(edge, 'below')} at K - {edge['step']:.1g} and "
            f"{_edge_margin_text(edge, 'above')} at K + {edge['step']:.1g}; the requirement holds on one side only, so "
            "a gain implemented with an error must be chosen inside, away from this end"
        )
    lines += [
        "",
        "![delay margin and decay rate at delta = 0 against K, and the best sampled decay rate against the delay "
        "margin, the design marked](design.png)",
    ]
    return lines


def _corner_rate_lines(result: ReflectionDesign | FilteredDesign | StateFeedbackDesign) -> list[str]:
    """The least decay rate of the nominal plant and the corners of the speed tolerance, and each corner's."""
    if not result.corner_abscissae:
        return []
    least = with_accuracy(result.worst_decay_rate, result.worst_decay_rate_accuracy)
    lines = [
        f"- least decay rate at delta = 0 of the nominal plant and the {len(result.corner_abscissae)} corners: "
        f"{least} (the design maximises it; between the corners not certified)"
    ]
    for n, sa in enumerate(result.corner_abscissae):
        lines.append(f"  - the plant with speed errors {_corner(result, n)}: {with_accuracy(-sa.value, sa.accuracy)}")
    return lines


def _corner(result: ReflectionDesign | FilteredDesign | StateFeedbackDesign, n: int) -> str:
    """The ``n``-th corner of the speed tolerance's square as ``(e_lam, e_mu)``."""
    if result.tolerance is None:
        return f"of scenario {n}"
    a, b = result.tolerance.points[n]
    return f"(e_lam, e_mu) = ({a:+.6g}, {b:+.6g})"


def _filtered_markdown(path: Path, result: FilteredDesign) -> list[str]:
    d = result.design
    c = result.controller
    what = "delay margin" if d.objective == "margin" else "decay rate at delta = 0"
    need = "" if d.margin_at_least is None else f", with a delay margin of at least {d.margin_at_least:g}"
    lines = [
        f"# Design of the filtered U_BS2(K) for {path.name}",
        "",
        f"- objective: the largest {what}{need} (a local optimum: the best of {len(d.runs)} start(s))",
        f"- designed controller: K = {c.K:.6g}, a = {c.a:.6g}, b = {c.b:.6g} (the filter (1 + a s)/(1 + b s))",
    ]
    return lines + _local_design_lines(result)


#: Gains of the scan at which the report computes the decay rate at ``delta = 0`` (about 0.1 s in all on the
#: paper's plant, 1 s under the collocated observer): the rate curve and the trade-off are drawn from them.
_RATE_SAMPLES = 41


def _rate_samples(system: Any, result: ReflectionDesign) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(K, delta*(K), decay rate at delta = 0)`` at :data:`_RATE_SAMPLES` gains of the design's scan.

    The margins are the scan's (:attr:`~nrobust.design.GainDesign.envelope`, 0 where the loop is unstable
    without delay); each rate is ``-alpha`` of the designed law's loop with that gain at ``delta = 0``
    (:func:`~nrobust.roots.spectral_abscissa`, floating point), of the nominal plant.
    """
    d = result.design
    gains, envelope = np.asarray(d.gains, dtype=float), np.asarray(d.envelope, dtype=float)
    picked = np.unique(np.linspace(0, gains.size - 1, min(_RATE_SAMPLES, gains.size)).round().astype(int))
    observer = result.controller if isinstance(result.controller, (OutputFeedback, CollocatedOutputFeedback)) else None
    rates = []
    for K in gains[picked]:
        law: Controller = ReflectionController(float(K))
        if observer is not None:
            law = type(observer)(law, observer.observer_delay)
        A, B = loop_factors(system, law)
        rates.append(-float(spectral_abscissa(A + B).value))
    return gains[picked], envelope[picked], np.asarray(rates)


def _best_sampled_rates(margins: np.ndarray, rates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The trade-off of samples: for each finite margin ``m`` of ``margins``, the best of ``rates`` among the
    samples whose margin is at least ``m`` (ascending ``m``; a staircase that does not rise)."""
    finite = np.isfinite(margins)
    levels = np.unique(margins[finite])
    best = np.array([np.max(rates[margins >= m]) for m in levels])
    return levels, best


def _tradeoff_figure(
    result: ReflectionDesign, margin_at_least: float | None, samples: tuple[np.ndarray, np.ndarray, np.ndarray]
) -> Any:
    """Three panels: the delay margin against ``K`` (the scanned envelope, the requirement and the design
    marked), the decay rate at ``delta = 0`` against ``K`` (:func:`_rate_samples`), and the best sampled rate
    against the margin it keeps (:func:`_best_sampled_rates`), the design marked."""
    import matplotlib.pyplot as plt

    d = result.design
    fig, (ax, ax_rate, ax_trade) = plt.subplots(1, 3, figsize=(15.0, 4.4))
    ax.plot(d.gains, d.envelope, label="delay margin delta*(K) (the scan behind the design)")
    if d.objective == "decay_rate" and margin_at_least is not None:
        ax.axhline(margin_at_least, color="0.5", lw=0.8, ls="--", label=f"required margin {margin_at_least:g}")
    if d.delays is not None:
        ax.axhspan(d.delays[0], d.delays[1], color="0.85", label=f"required window [{d.delays[0]:g}, {d.delays[1]:g}]")
    design_label = f"design: K = {d.K:.6g} ({d.kind}), decay rate {d.decay_rate:.4g}"
    ax.plot([d.K], [d.margin], "o", color="C3", label=design_label)
    ax.set_xlabel("K")
    ax.set_ylabel("delay")
    finite = np.asarray(d.envelope)[np.isfinite(d.envelope)]
    if finite.size:
        ax.set_ylim(0.0, 1.45 * float(np.max(finite)))  # room for the legend
    ax.legend(fontsize="x-small", loc="upper left")

    gains, margins, rates = samples
    ax_rate.plot(gains, rates, ".-", color="C2", label=f"decay rate at delta = 0 ({gains.size} gains of the scan)")
    ax_rate.plot([d.K], [d.decay_rate], "o", color="C3", label="design")
    ax_rate.set_xlabel("K")
    ax_rate.set_ylabel("decay rate (nominal plant)")
    ax_rate.legend(fontsize="small")

    levels, best = _best_sampled_rates(margins, rates)
    ax_trade.step(levels, best, where="post", color="C1", label="best sampled rate with a margin >= delta")
    ax_trade.plot(margins, rates, ".", color="0.6", label="the sampled gains")
    ax_trade.plot([d.margin], [d.decay_rate], "o", color="C3", label="design")
    if d.objective == "decay_rate" and margin_at_least is not None:
        ax_trade.axvline(margin_at_least, color="0.5", lw=0.8, ls="--", label=f"required margin {margin_at_least:g}")
    ax_trade.set_xlabel("delay margin delta")
    ax_trade.set_ylabel("decay rate at delta = 0")
    ax_trade.set_title("trade-off (samples, floating point)", fontsize="small")
    ax_trade.legend(fontsize="x-small")
    return fig


def _tradeoff_png(
    result: ReflectionDesign, margin_at_least: float | None, samples: tuple[np.ndarray, np.ndarray, np.ndarray]
) -> bytes:
    """:func:`_tradeoff_figure` as PNG bytes."""
    fig = _tradeoff_figure(result, margin_at_least, samples)
    fig.subplots_adjust(left=0.05, right=0.99, bottom=0.12, top=0.93, wspace=0.25)
    return _save_png(fig)


def _png(fig: Any, ax: Any) -> bytes:
    """The trade-off figure ``fig`` (its legend on ``ax``) as PNG bytes, then closed."""

    ax.legend(fontsize="small")
    fig.subplots_adjust(left=0.12, right=0.97, bottom=0.12, top=0.95)
    return _save_png(fig)


def _save_png(fig: Any) -> bytes:
    """``fig`` as PNG bytes, then closed."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


def _filtered_slice(system: Any, result: FilteredDesign, bounds: Any) -> GainDesign | str:
    """``delta*(K)`` with the design's filter ``(a, b)`` on the gains' bounds, or why it could not be computed."""
    c = result.controller
    if bounds is None:
        bounds = default_filter_bounds(system)["K"]  # those of the design
    loop = filtered_loop(system, {"K": None, "a": c.a, "b": c.b}).affine()
    try:
        return best_margin(loop, (float(bounds[0]), float(bounds[1])))
    except (CertificationError, ParameterError) as exc:
        return str(exc)


def _filtered_png(result: FilteredDesign, scan: GainDesign) -> bytes:
    """The delay margin against ``K`` with the design's filter, the design marked: its trade-off in ``K``."""
    import matplotlib.pyplot as plt

    c, d = result.controller, result.design
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.plot(scan.gains, scan.envelope, label=f"delay margin delta*(K), filter a = {c.a:.4g}, b = {c.b:.4g}")
    if d.margin_at_least is not None:
        ax.axhline(d.margin_at_least, color="0.5", lw=0.8, ls="--", label=f"required margin {d.margin_at_least:g}")
    K = float(c.K if c.K is not None else np.nan)  # a designed law has its gain
    margin = float(d.margin.margin)
    ax.plot(
        [K],
        [margin if np.isfinite(margin) else np.nan],
        "o",
        color="C3",
        label=f"design: K = {K:.6g}, decay rate {d.decay_rate:.4g}",
    )
    ax.set_xlabel("K")
    ax.set_ylabel("delay")
    envelope = np.asarray(scan.envelope, dtype=float)
    finite = envelope[np.isfinite(envelope)]
    # the design and its requirement in view (a margin that grows without bound near a gain would flatten them)
    levels = [v for v in (margin, d.margin_at_least) if v is not None and np.isfinite(v) and v > 0.0]
    top = 1.2 * float(np.max(finite)) if finite.size else 1.0
    if levels:
        top = min(top, 4.0 * max(levels)) if finite.size else 4.0 * max(levels)
    ax.set_ylim(0.0, top)
    if not np.all(np.isfinite(envelope)):
        ax.fill_between(
            scan.gains,
            0.0,
            top,
            where=~np.isfinite(envelope),
            color="C0",
            alpha=0.12,
            lw=0,
            label="no crossing: delta* infinite",
        )
    return _png(fig, ax)


def _state_feedback_markdown(path: Path, result: StateFeedbackDesign, powers: list[int]) -> list[str]:
    d, c = result.design, result.controller
    what = "delay margin" if d.objective == "margin" else "decay rate at delta = 0"
    need = "" if d.margin_at_least is None else f", with a delay margin of at least {d.margin_at_least:g}"
    n = len(powers)
    p = result.parameters
    basis = ", ".join(f"(x/L)^{j}" for j in powers) or "none (the proportional law)"
    lines = [
        f"# Design of the state feedback U = k u(t, L) + int g_u u + g_v v dx for {path.name}",
        "",
        f"- objective: the largest {what}{need} (a local optimum: the best of {len(d.runs)} start(s))",
        f"- basis of g_u and g_v: {basis}",
        f"- designed gain: k = {p[0]!r}",
        f"- g_u coefficients: {[float(v) for v in p[1 : 1 + n]]}",
        f"- g_v coefficients: {[float(v) for v in p[1 + n :]]}",
        f"- controller: {c!r}",
    ]
    return lines + _local_design_lines(result)


def _state_feedback_slice(
    system: Any, result: StateFeedbackDesign, powers: list[int], k_bounds: Any, kernel_grid: int | None
) -> GainDesign | str:
    """``delta*(k)`` with the designed integral gains fixed, on the bounds of ``k``, or why it was not computed."""
    length = float(system.length) if isinstance(system, GeneralHyperbolic2x2) else 1.0
    basis = [Monomial(j, length) for j in powers]
    try:
        loop = state_feedback_loop(system, basis, kernel_grid)  # the design's own loop
        bounds = tuple(k_bounds) if k_bounds is not None else default_state_k_bounds(loop)
        p = np.array(result.parameters, dtype=float)
        fixed = loop.B(np.concatenate([[0.0], p[1:]]))
        return best_margin(AffineGainLoop(loop.A, fixed, loop.units[0]), (float(bounds[0]), float(bounds[1])))
    except (CertificationError, ParameterError) as exc:
        return str(exc)


def _state_feedback_png(system: Any, result: StateFeedbackDesign, scan: GainDesign | str) -> bytes:
    """The designed integral gains on ``[0, L]`` and, when scanned, the delay margin against ``k`` with them."""
    import matplotlib.pyplot as plt

    c, d = result.controller, result.design
    if callable(c.g_u) or callable(c.g_v):  # with a basis: the integral gains on the left
        fig, (ax_g, ax) = plt.subplots(1, 2, figsize=(10.0, 4.0))
        length = float(system.length) if isinstance(system, GeneralHyperbolic2x2) else 1.0
        x = np.linspace(0.0, length, 201)
        for name, g in (("g_u", c.g_u), ("g_v", c.g_v)):
            y = np.asarray(g(x), dtype=float) if callable(g) else np.full_like(x, float(g))
            ax_g.plot(x, y, label=name)
        ax_g.set_xlabel("x")
        ax_g.set_title(f"designed integral gains, k = {c.k:.6g}", fontsize="small")
        ax_g.legend(fontsize="small")
    else:
        fig, ax = plt.subplots(figsize=(6.4, 4.0))
    margin = float(d.margin.margin)
    if isinstance(scan, str):
        ax.text(0.5, 0.5, "delay margin against k not scanned", ha="center", va="center", transform=ax.transAxes)
    else:
        envelope = np.asarray(scan.envelope, dtype=float)
        ax.plot(scan.gains, envelope, label="delay margin delta*(k), integral gains fixed")
        finite = envelope[np.isfinite(envelope)]
        levels = [v for v in (margin, d.margin_at_least) if v is not None and np.isfinite(v) and v > 0.0]
        top = 1.2 * float(np.max(finite)) if finite.size else 1.0
        if levels:
            top = min(top, 4.0 * max(levels)) if finite.size else 4.0 * max(levels)
        ax.set_ylim(0.0, top)
    if d.margin_at_least is not None:
        ax.axhline(d.margin_at_least, color="0.5", lw=0.8, ls="--", label=f"required margin {d.margin_at_least:g}")
    for j, (lo, hi) in enumerate(d.required_windows):
        ax.axhspan(lo, hi, color="0.85", label="required window" if j == 0 else None)
    ax.plot(
        [c.k],
        [margin if np.isfinite(margin) else np.nan],
        "o",
        color="C3",
        label=f"design: k = {c.k:.6g}, decay rate {d.decay_rate:.4g}",
    )
    ax.set_xlabel("k")
    ax.set_ylabel("delay")
    return _png(fig, ax)


def _nplusm_markdown(path: Path, result: NPlusMGainDesign) -> list[str]:
    what = "delay margin" if result.objective == "margin" else "decay rate at delta = 0"
    if result.objective == "margin" and result.vertex_margins:
        what = f"least delay margin of the nominal plant and the {len(result.vertex_margins)} vertices"
    if result.objective == "decay_rate" and result.vertex_abscissae:
        what = f"least decay rate at delta = 0 of the nominal plant and the {len(result.vertex_abscissae)} vertices"
    worst_value = [f"- {what}: {with_accuracy(result.value, result.accuracy)}"]
    need = "" if result.margin_at_least is None else f", with a delay margin of at least {result.margin_at_least:g}"
    if result.delays:
        need += ", stable for every delay in " + ", ".join(f"[{lo!r}, {hi!r}]" for lo, hi in result.delays)
    dm = result.margin
    lines = [
        f"# Design of the gain matrix K of U = K u(t - delta, 1) for {path.name}",
        "",
        f"- objective: the largest {what}{need} (a local optimum: the best of {result.starts} start(s))",
        f"- designed gain: K = {[list(row) for row in result.K]}",
        *(worst_value if result.objective == "margin" or result.vertex_abscissae else []),
        f"- decay rate at delta = 0: {with_accuracy(result.decay_rate, result.abscissa.accuracy)} "
        f"({'certified' if result.abscissa.certified else 'not certified'}"
        f"{', proven in ball arithmetic' if result.rigorous else ''})",
        f"- gamma of the delayed principal part: {result.gamma:.6g} (below 1: strongly stable for every delay)",
    ]
    if dm is not None:
        lines.append(
            f"- delay margin: {with_accuracy(dm.margin, dm.accuracy)} "
            f"({'certified' if dm.certified else 'not certified'}); about {dm.scope}"
        )
    for w in result.windows:
        verdict = "stable" if w.stable else "not stable"
        proof = "certified" if w.certified else "not certified"
        extra = "" if w.crossing is None else f", crossing delay {_window_crossing_text(w.crossing, dm)} inside"
        lines.append(f"  - window [{w.window[0]!r}, {w.window[1]!r}]: {verdict}, {proof} ({w.how}{extra})")
    t = result.tolerance
    if t is not None:
        lines.append(
            f"- speed tolerance {float(t.eps)!r} on every speed: {'met' if t.met else 'not met'} at the "
            f"{len(t.points)} points examined, {t.certified}"
        )
        lines.append(f"  - {t.statement}")
        for e, vm in zip(t.points, result.vertex_margins):
            where = ", ".join(f"{float(x)!r}" for x in e)
            lines.append(f"  - delay margin at the vertex ({where}): {with_accuracy(vm.margin, vm.accuracy)}")
        if result.vertex_margins and result.worst_margin is not None:
            worst = with_accuracy(result.worst_margin, result.worst_margin_accuracy)
            lines.append(f"  - least delay margin of the nominal plant and the vertices: {worst}")
        for e, sa in zip(t.points, result.vertex_abscissae):
            where = ", ".join(f"{float(x)!r}" for x in e)
            proof = ("certified" if sa.certified else "not certified") + (
                ", proven in ball arithmetic" if result.rigorous else ""
            )
            rate = with_accuracy(-sa.value, sa.accuracy)
            lines.append(f"  - decay rate at delta = 0 at the vertex ({where}): {rate} ({proof})")
        if result.vertex_abscissae:
            worst = with_accuracy(result.worst_decay_rate, result.worst_decay_rate_accuracy)
            lines.append(
                f"  - least decay rate at delta = 0 of the nominal plant and the vertices: {worst} (between the "
                "vertices not certified)"
            )
    lines.append(f"- certified: {'yes' if result.certified else 'no'}")
    lines.append(f"- optimality: {result.optimality}")
    return lines + _start_lines(result.runs)


def _window_crossing_text(delay: float, dm: NPlusMMargin | None) -> str:
    """A crossing delay inside a window of an n + m design: with the margin's accuracy when it is the
    margin, else marked as not estimated (the other crossing delays carry none)."""
    return with_accuracy(delay, dm.accuracy if dm is not None and delay == dm.margin else None)


def _start_lines(runs: Sequence[Any]) -> list[str]:
    """One line per local start: where it began, where it ended, why it stopped."""
    return [
        f"- start {i + 1}: {tuple(round(v, 6) for v in run.start)} -> {tuple(round(v, 6) for v in run.parameters)}"
        f", {run.reason}"
        for i, run in enumerate(runs)
    ]


#: Gains ``t K`` of the n + m figure.
NPLUSM_SECTION = np.linspace(0.0, 1.2, 13)


def _nplusm_png(system: NPlusMSystem, result: NPlusMGainDesign) -> bytes:
    """The certified delay margin along the gains ``t K`` (the design at ``t = 1``), the windows shaded; the
    gains unstable at ``delta = 0`` (or with ``gamma >= 1``) marked on the axis, those not certified left out."""
    import matplotlib.pyplot as plt

    K = result.gain
    margins, unstable = [], []
    for t in NPLUSM_SECTION:
        margin = np.nan
        try:
            if principal_gamma(system, t * K) < 1.0:
                dm = nplusm_delay_margin(system, t * K) if system.m == 1 else multi_actuator_delay_margin(system, t * K)
                if dm.certified and dm.nominal_unstable == 0:
                    margin = dm.margin
                elif dm.certified:
                    unstable.append(t)
            else:
                unstable.append(t)
        except CertificationError:
            pass
        margins.append(margin)
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.plot(NPLUSM_SECTION, margins, ".-", label="certified delay margin at t K")
    if unstable:
        ax.plot(unstable, np.zeros(len(unstable)), "x", color="0.4", label="unstable at delta = 0, or gamma >= 1")
    for j, (lo, hi) in enumerate(result.delays):
        ax.axhspan(lo, hi, color="0.85", label="required window" if j == 0 else None)
    if result.margin_at_least is not None:
        ax.axhline(result.margin_at_least, color="0.5", lw=0.8, ls="--", label="required margin")
    own = result.margin.margin if result.margin is not None else np.nan
    ax.plot([1.0], [own], "o", color="C3", label=f"design (t = 1), decay rate {result.decay_rate:.4g}")
    ax.set_xlabel("t (gain t K)")
    ax.set_ylabel("delay")
    values = np.asarray(margins, dtype=float)
    finite = values[np.isfinite(values)]
    if finite.size:
        ax.set_ylim(0.0, 1.2 * float(np.max(finite)) + 1e-9)
    return _png(fig, ax)


def design_summary(result: ReflectionDesign | FilteredDesign | StateFeedbackDesign | NPlusMGainDesign) -> str:
    """One line: the designed controller and its objective, with the digits their accuracy supports."""
    if isinstance(result, ReflectionDesign):
        d = result.design
        k_acc, _ = d.accuracy
        if result.corner_abscissae:  # the design maximises the least rate of the nominal plant and the corners
            text = with_accuracy(result.worst_decay_rate, result.worst_decay_rate_accuracy)
            nominal = with_accuracy(d.decay_rate, d.abscissa.accuracy)
            return (
                f"K = {with_accuracy(d.K, k_acc)} ({d.kind}), least decay rate of the nominal plant and the corners "
                f"{text}; nominal {nominal}"
            )
        return (
            f"K = {with_accuracy(d.K, k_acc)} ({d.kind}), {d.objective} = {with_accuracy(d.value, _value_accuracy(d))}"
        )
    if isinstance(result, NPlusMGainDesign):
        t = result.tolerance
        tolerance = "" if t is None else f"; speed tolerance {float(t.eps)!r}: {t.certified}"
        least = (
            " (least of the nominal plant and the vertices)" if result.vertex_margins or result.vertex_abscissae else ""
        )
        return (
            f"K = {[list(row) for row in result.K]}: {result.objective}{least} = "
            f"{with_accuracy(result.value, result.accuracy)} (a local optimum; certified: "
            f"{'yes' if result.certified else 'no'}{tolerance})"
        )
    least = ""
    if result.corner_abscissae:  # the design maximises the least rate of the nominal plant and the corners
        text = with_accuracy(result.worst_decay_rate, result.worst_decay_rate_accuracy)
        least = f"least decay rate of the nominal plant and the corners {text}; nominal "
    if isinstance(result, StateFeedbackDesign):
        sf = result.design
        return (
            f"StateFeedback parameters {tuple(round(v, 6) for v in result.parameters)}: {least}decay rate "
            f"{with_accuracy(sf.decay_rate, sf.abscissa.accuracy)}, delay margin "
            f"{with_accuracy(sf.margin.margin, sf.margin.accuracy)} (a local optimum; certified: "
            f"{'yes' if sf.certified else 'no'})"
        )
    c, local = result.controller, result.design
    margin = with_accuracy(local.margin.margin, local.margin.accuracy)
    return (
        f"FilteredController(a={c.a:.6g}, b={c.b:.6g}, K={c.K:.6g}): {least}decay rate "
        f"{with_accuracy(local.decay_rate, local.abscissa.accuracy)}, delay "
        f"margin {margin} (a local optimum; certified: {'yes' if local.certified else 'no'})"
    )


def run_design(
    path: str | Path,
    out_dir: str | Path,
    objective: str | None = None,
    margin_at_least: float | None = None,
    K_bounds: tuple[float, float] | None = None,
    rigorous: bool | None = None,
    family: str | None = None,
    delays: tuple[float, float] | None = None,
    speed_tolerance: float | None = None,
) -> tuple[tuple[Path, ...], ReflectionDesign | FilteredDesign | StateFeedbackDesign | NPlusMGainDesign]:
    """``nrobust design``: design a controller for the plant of a SYSTEM.toml file and write the result.

    Each argument left None takes the file's ``[design]`` value (or its default: U_BS2(K),
    the largest margin; ``delays = (d_min, d_max)``: the window of delays to be stable on,
    ``speed_tolerance``: the relative error of the speeds it must hold under, both with
    ``family = "reflection"`` or ``"filtered"``, ``delays`` with ``"output_feedback"`` and
    ``"collocated_output_feedback"`` too; ``"state_feedback"`` takes both, and ``K_bounds`` are its
    ``k_bounds``; an ``NPlusMSystem`` file's family is ``"nplusm"``, ``K_bounds`` a pair for every
    entry of ``K``, ``delays`` its windows, ``speed_tolerance`` the relative error of every speed).
    The report states each
    requirement and whether it is met and proven. The file and ``out_dir`` are checked before any computation; the
    files are written as one set (:class:`~nrobust.reports.outputs.RunOutputs`). Returns the
    written paths and the design.

    Raises
    ------
    ParameterError
        A bad file, a family that does not take the file's plant (``"nplusm"`` an ``NPlusMSystem``,
        the others a 2x2 plant), or the arguments of the design function of the family.
    """
    check_output_dir(out_dir)
    if objective is not None and objective not in DESIGN_OBJECTIVES:
        raise ParameterError("objective", f"one of {DESIGN_OBJECTIVES}", objective)
    if family is not None and family not in DESIGN_FAMILIES:
        raise ParameterError("family", f"one of {DESIGN_FAMILIES}", family)
    spec = load_system_file(path, for_design=True)
    if spec.get("kind") == NPLUSM_TYPE:
        return _run_nplusm(
            Path(path), spec, out_dir, objective, margin_at_least, K_bounds, rigorous, family, delays, speed_tolerance
        )
    if family == "nplusm":
        raise ParameterError(
            "family (--family)", 'a family of a 2x2 plant ("nplusm" takes an NPlusMSystem file)', family
        )
    given: dict[str, Any] = spec["design"] or {}
    family = family or given.get("family", "reflection")
    objective = objective or given.get("objective", "margin")
    margin_at_least = margin_at_least if margin_at_least is not None else given.get("margin_at_least")
    rigorous = rigorous if rigorous is not None else bool(given.get("rigorous", False))
    bounds = K_bounds if K_bounds is not None else given.get("K")
    delays = delays if delays is not None else given.get("delays")
    speed_tolerance = speed_tolerance if speed_tolerance is not None else given.get("speed_tolerance")
    if delays is not None and margin_at_least is not None:
        raise ParameterError("margin_at_least", "left out with delays (the window [0, d] is a margin > d)")
    if speed_tolerance is not None and family in OBSERVER_FAMILIES:
        # as the file's [design] section is checked (the observer's laws take no speed tolerance)
        raise ParameterError(
            "design.speed_tolerance (--speed-tolerance)",
            f'left out for family = "{family}" (family "reflection" or "filtered" takes it)',
            speed_tolerance,
        )
    outputs = RunOutputs(out_dir, "design")
    edge: dict[str, Any] | None = None
    scan: GainDesign | str = "not a filtered design"
    with outputs:
        result: ReflectionDesign | FilteredDesign | StateFeedbackDesign
        if family == "state_feedback":
            powers = list(given.get("basis", []))
            plant = spec["given_system"]  # the gains act on the state as written
            length = float(plant.length) if isinstance(plant, GeneralHyperbolic2x2) else 1.0
            grid = given.get("kernel_grid")  # None: the exact route without a basis, else 201 points
            k_bounds = bounds if bounds is not None else given.get("k_bounds")
            result = design_state_feedback(
                plant,
                objective,
                margin_at_least=margin_at_least,
                delays=delays,
                speed_tolerance=speed_tolerance,
                k_bounds=k_bounds,
                basis=[Monomial(j, length) for j in powers],
                coefficient_bounds=tuple(given.get("coefficient_bounds", (-1.0, 1.0))),
                starts=int(given.get("starts", 4)),
                rigorous=rigorous,
                kernel_grid=grid,
            )
            lines = _state_feedback_markdown(Path(path), result, powers)
            scan = _state_feedback_slice(plant, result, powers, k_bounds, grid)
            if isinstance(scan, str):
                lines += ["", f"The delay margin against k with the designed g_u, g_v was not scanned ({scan})."]
            lines += ["", "![the designed gains, and the delay margin against k with them](design.png)"]
        elif family in ("reflection", *OBSERVER_FAMILIES):
            result = design_reflection(
                spec["system"],
                objective,
                margin_at_least=margin_at_least,
                K_bounds=bounds,
                rigorous=rigorous,
                output_feedback=family in OBSERVER_FAMILIES,
                collocated=family == "collocated_output_feedback",
                observer_delay=float(given.get("observer_delay", 0.0)),
                delays=delays,
                speed_tolerance=speed_tolerance,
            )
            edge = _edge(spec["system"], result) if objective == "decay_rate" else None
            lines = _reflection_markdown(Path(path), result, margin_at_least, edge)
        else:
            result = design_filtered(
                spec["system"],
                objective=objective,
                margin_at_least=margin_at_least,
                delays=delays,
                speed_tolerance=speed_tolerance,
                parameters={"K": bounds, "a": given.get("a"), "b": given.get("b")},
                starts=int(given.get("starts", 4)),
                rigorous=rigorous,
            )
            lines = _filtered_markdown(Path(path), result)
            scan = _filtered_slice(spec["system"], result, bounds)
            if isinstance(scan, str):
                lines += ["", f"No trade-off figure: the delay margin in K with this filter was not scanned ({scan})."]
            else:
                k_acc, v_acc = scan.accuracy
                m_acc = None if scan.certificate.accuracy is None else scan.certificate.accuracy + v_acc
                best = (
                    f"is {with_accuracy(scan.margin, m_acc)} at K = {with_accuracy(scan.K, k_acc)} ({scan.kind})"
                    if np.isfinite(scan.margin)
                    else f"is infinite (no crossing) on part of them, e.g. at K = {scan.K:.6g}"
                )
                lines += [
                    "",
                    f"The trade-off in K with the designed filter (a, b): the largest delay margin on the gains' "
                    f"bounds {best}.",
                    "",
                    "![delay margin against K with the designed filter, the design marked](design.png)",
                ]
        data = {
            "file": str(path),
            "plant": repr(spec["given_system"]),
            "family": family,
            "margin_at_least": margin_at_least,
            "delays": delays,
            "speed_tolerance": speed_tolerance,
            **result.to_dict(),
        }
        if edge is not None:
            data["edge"] = edge
        written = [
            outputs.write_text("design.json", json.dumps(json_safe(data), indent=2, allow_nan=False)),
            outputs.write_text("design.md", "\n".join(lines) + "\n"),
        ]
        if isinstance(result, ReflectionDesign):
            samples = _rate_samples(spec["system"], result)
            written.append(outputs.write_bytes("design.png", _tradeoff_png(result, margin_at_least, samples)))
        elif isinstance(result, StateFeedbackDesign):
            written.append(outputs.write_bytes("design.png", _state_feedback_png(spec["given_system"], result, scan)))
        elif not isinstance(scan, str):
            written.append(outputs.write_bytes("design.png", _filtered_png(result, scan)))
    return tuple(written), result


def _run_nplusm(
    path: Path,
    spec: dict[str, Any],
    out_dir: str | Path,
    objective: str | None,
    margin_at_least: float | None,
    K_bounds: tuple[float, float] | None,
    rigorous: bool | None,
    family: str | None,
    delays: tuple[float, float] | None,
    speed_tolerance: float | None,
) -> tuple[tuple[Path, ...], NPlusMGainDesign]:
    """``nrobust design`` on an ``NPlusMSystem`` file: the gain matrix ``K`` (family ``"nplusm"``)."""
    if family is not None and family != "nplusm":
        raise ParameterError("family (--family)", '"nplusm" for an NPlusMSystem file', family)
    given: dict[str, Any] = spec.get("design") or {}
    speed_tolerance = speed_tolerance if speed_tolerance is not None else given.get("speed_tolerance")
    objective = objective or given.get("objective", "decay_rate")
    margin_at_least = margin_at_least if margin_at_least is not None else given.get("margin_at_least")
    windows: Any = delays if delays is not None else given.get("delays")
    if delays is not None and margin_at_least is not None:
        raise ParameterError("margin_at_least", "left out with delays (the window [0, d] is a margin > d)")
    rigorous = rigorous if rigorous is not None else bool(given.get("rigorous", False))
    system = spec["system"]
    outputs = RunOutputs(out_dir, "design")
    with outputs:
        result = design_nplusm_gains(
            system,
            objective,
            margin_at_least=margin_at_least,
            delays=windows,
            K_bounds=K_bounds if K_bounds is not None else given.get("K_bounds"),
            x0=given.get("x0"),
            starts=int(given.get("starts", 4)),
            max_iter=int(given.get("max_iter", 60)),
            rigorous=rigorous,
            speed_tolerance=speed_tolerance,
        )
        lines = _nplusm_markdown(path, result)
        lines += ["", "![the certified delay margin along the gains t K, the design at t = 1](design.png)"]
        data = {
            "file": str(path),
            "plant": repr(system),
            "family": "nplusm",
            "margin_at_least": margin_at_least,
            "delays": windows,
            "speed_tolerance": speed_tolerance,
            **result.to_dict(),
        }
        written = [
            outputs.write_text("design.json", json.dumps(json_safe(data), indent=2, allow_nan=False)),
            outputs.write_text("design.md", "\n".join(lines) + "\n"),
            outputs.write_bytes("design.png", _nplusm_png(system, result)),
        ]
    return tuple(written), result


def _local_design_lines(result: FilteredDesign | StateFeedbackDesign) -> list[str]:
    """The lines every local design's report shares: rate, margin, certificate, requirements, starts."""
    d = result.design
    lines = [
        f"- decay rate at delta = 0: {with_accuracy(d.decay_rate, d.abscissa.accuracy)} "
        f"({'no root right of it: certified count' if d.abscissa.certified else 'not certified'})",
        f"- delay margin: {with_accuracy(d.margin.margin, d.margin.accuracy)} ({d.margin.method}); "
        f"about {result.scope}",
        f"- certified: {'yes' if d.certified else 'no'}",
    ]
    if d.delays is not None:
        lines.append(f"- requirement: {d.requirement}")
        for n, w in enumerate(d.windows):
            which = "the designed loop" if n == 0 else f"the plant with speed errors {_corner(result, n - 1)}"
            lines.append(f"  - {which}: {_window_text(w)}")
    if result.tolerance is not None:
        t = result.tolerance
        lines.append(
            f"- speed tolerance {float(t.eps)!r} on lam and mu: {'met' if t.met else 'not met'}, {t.certified}"
        )
        lines.append(f"  - {t.statement}; about {t.scope}")
    return lines + _corner_rate_lines(result) + _start_lines(d.runs)
