"""``nrobust paper``: the reference paper's example (section 5) end to end."""

from __future__ import annotations

import gc
import importlib.util
import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from threadpoolctl import threadpool_limits

from .._digits import with_accuracy
from .._json import json_float, json_safe
from .._validate import positive, renamed_keywords
from ..errors import ParameterError
from ..hyperbolic.analyses import StabilityChart, Tradeoff, stability_chart, tradeoff
from ..hyperbolic.loops.controllers import (
    Classification,
    FiniteTimeController,
    ReflectionController,
    characteristic,
    classify,
)
from ..hyperbolic.plants.hyperbolic2x2 import Hyperbolic2x2
from ..hyperbolic.simulate import DEFAULT_CELLS, Simulation, simulate_runs
from ..plots.base import figure_png, pin_title
from ..plots.charts import stability_chart_plot, tradeoff_plot
from ..plots.rootlocus import RootLocusData, root_locus_response
from ..plots.simulation import residual_floor, simulation_figure
from ..sweeps.executors import sweep_map
from .certificate import PROVEN, Certificate, certify
from .outputs import RunOutputs
from .report import RenderedFigures, render_certificate_figures, render_nyquist_figure, write_report

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "PAPER_DELAYS_FIG1",
    "PAPER_DELAYS_FIG3",
    "PAPER_K",
    "PAPER_SYSTEM",
    "PAPER_T_END",
    "paper_figure",
    "run_paper",
]

#: The paper's numerical example (section 5): lam = mu = sigma+- = sigma-+ = q = 1, rho = 0.85.
PAPER_SYSTEM = {"lam": 1.0, "mu": 1.0, "sigma_pm": 1.0, "sigma_mp": 1.0, "q": 1.0, "rho": 0.85}
#: The tuning gain of figure 3 (U_BS2(K), eq. (53)).
PAPER_K = 0.1
#: The loop delays of figure 1 (U_BS).
PAPER_DELAYS_FIG1 = (0.0, 0.01)
#: The loop delays of figure 3 (U_BS2(K)).
PAPER_DELAYS_FIG3 = (0.0, 0.01, 0.1)
#: Horizon of the simulations of figures 1 and 3.
PAPER_T_END = 15.0
#: The accuracy of a simulated growth rate is this many times its change from the run on the grid half as
#: fine. The slopes converge at first order (their changes halve with the grid); on the four runs of
#: figures 1 and 3 that do not converge in finite time, with 100 to 800 cells, the largest ratio of the true
#: error (extrapolated from 1600 and 3200 cells) to that change was 2.78 (100 cells), 1.11 at the default
#: 400 cells.
_GROWTH_SAFETY = 8.0


#: The certificates are proven in ball arithmetic when python-flint (``nrobust[rigorous]``) is installed.
_RIGOROUS = importlib.util.find_spec("flint") is not None
#: The paper's central claims, whose status the report states first.
_CENTRAL_CLAIMS = (
    "nominal stability",
    "stability up to delta_max",
    "crossing that fixes delta*",
    "delay margin",
    "instability at delta_max",
)


def _paper_u0(x: np.ndarray) -> np.ndarray:
    """Initial ``u``: constant 1 (any L2 datum with energy on both chains would do)."""
    return np.ones_like(np.asarray(x, dtype=float))


def _paper_v0(x: np.ndarray) -> np.ndarray:
    """Initial ``v``: ``1 + sin(pi x)``."""
    return 1.0 + np.sin(np.pi * np.asarray(x, dtype=float))


def _paper_job(task: tuple[Any, ...]) -> Any:
    """One independent computation ``(job, *args)`` of :func:`run_paper`, run in a worker process.

    The plant is rebuilt from :data:`PAPER_SYSTEM` in the worker, so a job is sent as its
    name and a few numbers. A job draws its figures, as PNG bytes, when it has all they
    show: the figures are drawn in parallel and the report only embeds them.
    """
    job, *args = task
    system = Hyperbolic2x2(**PAPER_SYSTEM)
    if job == "simulate":  # the runs of figures 1 and 3, marched together, the two figures, the growth rates
        t_end, cells = args
        loops = [(controller, d) for controller, deltas in map(_figure_loop, (1, 3)) for d in deltas]
        runs = simulate_runs(system, loops, t_end, _paper_u0, _paper_v0, cells)
        try:  # the same runs on the grid half as fine: the growth rates' accuracy
            coarse: list[Simulation | None] = list(
                simulate_runs(system, loops, t_end, _paper_u0, _paper_v0, cells // 2)
            )
        except ParameterError:  # too few cells to halve
            coarse = [None] * len(runs)
        growth = [_growth(run, other) for run, other in zip(runs, coarse)]
        fig1, fig3 = runs[: len(PAPER_DELAYS_FIG1)], runs[len(PAPER_DELAYS_FIG1) :]
        return _png(paper_figure(1, fig1)), _png(paper_figure(3, fig3)), growth
    if job == "certify":  # the loops one after the other: the second reuses what the first left in memory
        loops, rigorous, accuracy = args
        certs = [
            (certify(system, c, delta_max=d, k_region=False, rigorous=rigorous, accuracy=accuracy), nyquist)
            for c, d, nyquist in loops
        ]
        return [(cert, render_certificate_figures(cert, nyquist)) for cert, nyquist in certs]
    if job == "nyquist":  # a loop's Nyquist figure, drawn while another worker certifies the loop
        controller, delta_max = args
        return render_nyquist_figure(system, controller, delta_max)
    if job == "charts":  # the chart draws the trade-off's Rouché bounds: one job, two figures
        Ks, deltas, k_max = args
        chart = stability_chart(system, Ks, deltas, progress=False)
        # the chart's margins up to its largest delay are the trade-off's: only the others are computed
        margins = np.where(chart.margins <= deltas.max(), chart.margins, np.nan)[Ks >= 0]
        trade = tradeoff(system, Ks[Ks >= 0], margins=margins, progress=False)
        return chart, trade, _png(_chart_figure(chart, trade, k_max)), _png(_tradeoff_figure(trade))
    if job == "locus":  # the root locus of U_BS2 in K and its figure
        Ks, delta, region = args
        locus = root_locus_response(
            lambda K: characteristic(system, ReflectionController(K), delta), Ks, region, name="K"
        )
        return _png(_locus_figure(locus))
    raise ParameterError("job", "one of simulate, certify, charts, locus", job)


def _png(fig: Figure) -> bytes:
    """``fig`` as PNG (:func:`nrobust.plots.base.figure_png`), then closed."""
    import matplotlib.pyplot as plt

    try:
        return figure_png(fig)
    finally:
        plt.close(fig)


@renamed_keywords(n="cells")
def run_paper(
    out_dir: str | Path,
    progress: bool | None = None,
    workers: int = 2,
    t_end: float = PAPER_T_END,
    cells: int = DEFAULT_CELLS,
    n_K: int = 25,
    n_delta: int = 26,
    accuracy: float | None = None,
) -> dict[str, Any]:
    """``nrobust paper``: the reference paper's example end to end; returns the summary.

    Simulates the PDE for figures 1 (U_BS, eq. (47), ``delta = 0, 0.01``) and 3
    (U_BS2 with ``K = 0.1``, eq. (53), ``delta = 0, 0.01, 0.1``), certifies both
    loops (classification, difference operator, certified roots, spectral abscissa,
    delay margin, Rouché bound), computes the ``(K, delta)`` stability chart and the
    decay/margin trade-off and the root locus in ``K`` of U_BS2, writes the report and
    ``summary.json`` with the headline numbers, each read from a computation.

    Parameters
    ----------
    out_dir : path-like
        Output directory, checked (created, writable) before anything is computed; the
        report, its figures and ``summary.json`` are written there as one set with
        ``manifest.json`` (:class:`~nrobust.reports.outputs.RunOutputs`), so a failed or
        interrupted run leaves it as it was.
    progress : bool, optional
        Show a progress bar on stderr; by default only when stderr is a terminal or Jupyter.
    workers : int
        Worker processes for the independent computations (0: all in this process).
    t_end : float
        Simulation horizon.
    cells : int, default :data:`~nrobust.hyperbolic.simulate.normal_form.DEFAULT_CELLS`
        Cells of the simulations' grid (formerly ``n``, a deprecated alias).
    n_K, n_delta : int
        Size of the stability chart's grid.
    accuracy : float, optional
        Target accuracy of the certificates' delay margins (``nrobust paper --accuracy A``,
        :func:`~nrobust.reports.certificate.certify`): the paper's plant takes the exact route,
        whose margins are known to about ``1e-13``; the report says what was achieved.
    """
    start = time.perf_counter()
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 0:
        raise ParameterError("workers", "an integer >= 0", workers)
    if accuracy is not None:
        accuracy = positive("accuracy", accuracy)
    # one BLAS thread, as in the workers: the small eigenvalue problems of the report (the chains of a
    # difference operator) run tens of times slower when BLAS threads compete for the cores
    with threadpool_limits(1), RunOutputs(out_dir, "paper") as outputs:  # checked before anything is computed
        summary = _run_paper(outputs, start, progress, workers, t_end, cells, n_K, n_delta, accuracy)
    return summary


def _run_paper(
    outputs: RunOutputs,
    start: float,
    progress: bool | None,
    workers: int,
    t_end: float,
    cells: int,
    n_K: int,
    n_delta: int,
    accuracy: float | None = None,
) -> dict[str, Any]:
    """The body of :func:`run_paper`, writing into the staged ``outputs``."""
    system = Hyperbolic2x2(**PAPER_SYSTEM)
    classification = classify(system)
    tasks = _paper_tasks(classification.k_bound, t_end, cells, n_K, n_delta, accuracy)
    collecting = gc.isenabled()
    if workers:
        # loaded once, here, rather than by each worker forked from here (0.2 s of CPU each): matplotlib
        # and the image writers Pillow loads on its first save (every job draws), numpy.fft (the chirp-z
        # sums of certificates and charts), FLINT (the certificates' proofs, with nrobust[rigorous])
        import matplotlib.backends.backend_agg
        import matplotlib.pyplot  # noqa: F401
        import numpy.fft  # noqa: F401
        from PIL import Image

        Image.preinit()
        if _RIGOROUS:
            import flint  # noqa: F401

        # the objects of the imports left out of garbage collection in the workers forked from here: a
        # full collection there (one per job) otherwise walks all of them (about 0.05 s of CPU each)
        gc.freeze()
        # and no collection at all in the workers, which live for these few jobs: their cyclic garbage
        # (closed figures) adds about 2 MB to the largest, the collections cost 0.05 s of CPU per worker
        gc.disable()
    # one task per chunk: the jobs are few and long, and the longest go first
    run = sweep_map(workers or "serial", chunksize=1, progress=progress)
    try:
        res = dict(zip(tasks, run(_paper_job, tasks.values())))
    finally:
        if collecting:
            gc.enable()
        gc.unfreeze()  # this process collects them again (no-ops without workers)
    fig1_png, fig3_png, growth = res["simulate"]
    (cert_bs, drawn_bs), (cert_bs2, drawn_bs2) = res["certify"]
    if cert_bs.kernel_grid is None:  # the grid the Nyquist job took: the figures of U_BS's certificate
        drawn_bs = RenderedFigures(drawn_bs.pngs + res["nyquist"].pngs, res["nyquist"].rhp_zeros)
    else:  # a kernel grid chosen for the accuracy asked (a plant off the exact route): drawn here
        drawn_bs = render_certificate_figures(cert_bs)
    chart, trade, chart_png, trade_png = res["charts"]
    figures = [
        (_FIGURE_CAPTIONS[1], fig1_png),
        (_FIGURE_CAPTIONS[3], fig3_png),
        (_CHART_CAPTION, chart_png),
        (_TRADEOFF_CAPTION, trade_png),
        (_LOCUS_CAPTION, res["locus"]),
    ]
    admissible = _stable_gains(chart)
    summary = _paper_summary(system, classification, cert_bs, cert_bs2, chart, trade, growth, admissible)
    intro = _paper_intro(cert_bs, cert_bs2, summary, admissible)
    files = write_report(
        [cert_bs, cert_bs2],
        outputs.staging,
        figures=figures,
        title="nrobust: the paper's example, end to end",
        intro=intro,
        rendered=[drawn_bs, drawn_bs2],
        answer=_paper_answer(classification, cert_bs, cert_bs2),
    )
    summary["elapsed_seconds"] = time.perf_counter() - start
    summary["workers"] = workers
    summary["files"] = outputs.final(files).to_dict()
    outputs.write_text("summary.json", json.dumps(json_safe(summary), indent=2, allow_nan=False))
    outputs.commit()
    return summary


def _paper_tasks(
    k_max: float, t_end: float, cells: int, n_K: int, n_delta: int, accuracy: float | None = None
) -> dict[str, tuple[Any, ...]]:
    """The independent computations of section 5 as :func:`_paper_job` tasks, by name.

    The certificates of U_BS and U_BS2 (one job: after the first, in the same process, the
    second costs a good part less than alone), the ``(K, delta)`` chart of U_BS2 on
    ``n_K x n_delta`` gains in ``[-1.2, 1.2] k_max`` and delays in ``[0, 0.5]`` with the
    trade-off on its gains ``K >= 0``, the simulations of figures 1 and 3, the root locus of
    U_BS2 in ``K`` (seven gains in ``[0, 0.9 k_max]``), the Nyquist figure of U_BS (its
    certificate's, drawn apart so that the two workers end together).
    """
    u_bs, u_bs2 = FiniteTimeController(), ReflectionController(PAPER_K)
    Ks = np.linspace(-1.2 * k_max, 1.2 * k_max, n_K)
    deltas = np.linspace(0.0, 0.5, n_delta)
    # longest first, so that the workers finish together: the certificates (without U_BS's Nyquist
    # figure) on one, the chart and the simulations on the other, then the root locus on the first
    # free and U_BS's Nyquist figure on the other
    return {
        "certify": (
            "certify",
            ((u_bs, max(PAPER_DELAYS_FIG1), False), (u_bs2, max(PAPER_DELAYS_FIG3), True)),
            _RIGOROUS,
            accuracy,
        ),
        "charts": ("charts", Ks, deltas, k_max),
        "simulate": ("simulate", t_end, cells),
        "locus": ("locus", np.linspace(0.0, 0.9 * k_max, 7), max(PAPER_DELAYS_FIG3), (-1.0, 0.4, 0.0, 20.0)),
        "nyquist": ("nyquist", u_bs, max(PAPER_DELAYS_FIG1)),
    }


#: Captions of the report's further figures.
_FIGURE_CAPTIONS = {
    1: "Figure 1 of the paper: L2 norm under U_BS (finite-time backstepping)",
    3: f"Figure 3 of the paper: L2 norm under U_BS2 with K = {PAPER_K:g}",
}
_CHART_CAPTION = (
    "Stability chart of U_BS2(K) in (K, delta): grid verdicts, the exact boundary delta*(K), "
    "the sufficient bound |K| < (1 - |rho q|)/|q| and the Rouche delay range"
)
_TRADEOFF_CAPTION = "Trade-off between decay rate and delay margin as K varies (labels: K)"
_LOCUS_CAPTION = (
    f"Root locus of U_BS2 in K at delta = {max(PAPER_DELAYS_FIG3):g} (upper half-plane; "
    "the roots of a real loop are symmetric)"
)


def _chart_figure(chart: StabilityChart, trade: Tradeoff, k_max: float) -> Figure:
    """The ``(K, delta)`` stability chart with the bound (54) and the trade-off's Rouché range."""
    import matplotlib.pyplot as plt  # lazily: the command line checks its input before drawing anything

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    stability_chart_plot(chart, ax=ax, k_bound=k_max, rouche=(trade.Ks, trade.rouche_bounds))
    pin_title(ax)
    fig.subplots_adjust(left=0.12, right=0.97, bottom=0.12, top=0.92)  # by hand: one draw, no tight layout
    return fig


def _tradeoff_figure(trade: Tradeoff) -> Figure:
    """Decay rate against delay margin, labelled by ``K``."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    tradeoff_plot(trade, ax=ax)
    pin_title(ax)
    fig.subplots_adjust(left=0.12, right=0.97, bottom=0.12, top=0.92)  # by hand: one draw, no tight layout
    return fig


def _locus_figure(locus: RootLocusData) -> Figure:
    """The root locus of U_BS2 in ``K``."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    locus.plot(ax=ax)
    pin_title(ax)
    fig.subplots_adjust(left=0.12, right=0.97, bottom=0.12, top=0.92)  # by hand: one draw, no tight layout
    return fig


def _figure_loop(number: int) -> tuple[FiniteTimeController | ReflectionController, tuple[float, ...]]:
    """The controller and the loop delays of figure 1 or 3."""
    if number == 1:
        return FiniteTimeController(), PAPER_DELAYS_FIG1
    return ReflectionController(PAPER_K), PAPER_DELAYS_FIG3


def _growth(run: Simulation, coarse: Simulation | None) -> tuple[float | None, float | None]:
    """The least-squares slope of ``log ||(u, v)||`` over the second half of ``run`` and its accuracy.

    The accuracy is an estimate of the slope's discretisation error: :data:`_GROWTH_SAFETY` times its
    change from ``coarse``, the run on the grid half as fine (None without it). ``(None, None)`` when the
    norm falls to the scheme's residual in that half (:func:`~nrobust.plots.residual_floor`): a loop that
    converges in finite time, whose slope there is the scheme's, not the plant's.
    """
    half = np.asarray(run.times) >= 0.5 * float(run.times[-1])
    if float(np.min(np.asarray(run.norm)[half])) <= residual_floor([run]):
        return None, None
    rate = run.growth_rate()
    if coarse is None or coarse.n == run.n:
        return rate, None
    return rate, _GROWTH_SAFETY * abs(rate - coarse.growth_rate())


def _growth_text(rate: float | None, accuracy: float | None) -> str:
    """A simulated growth rate with its estimated accuracy, or why it has none."""
    return (
        "none (the norm falls to the scheme's residual: finite-time convergence)"
        if rate is None
        else with_accuracy(rate, accuracy)
    )


def _stable_gains(chart: StabilityChart) -> list[float]:
    """The chart's gains nominally stable with a delay margin above the largest delay of figure 3."""
    return [
        float(K)
        for K, m, v in zip(chart.Ks, chart.margins, chart.values[:, 0])
        if v == 0 and m > max(PAPER_DELAYS_FIG3)
    ]


def _paper_summary(
    system: Hyperbolic2x2,
    classification: Classification,
    cert_bs: Certificate,
    cert_bs2: Certificate,
    chart: StabilityChart,
    trade: Tradeoff,
    growth: list[tuple[float | None, float | None]],
    admissible: list[float],
) -> dict[str, Any]:
    """The headline numbers of ``summary.json``, each read from a computation (``growth``: :func:`_growth` of
    the runs of figures 1 and 3)."""
    fig1, fig3 = growth[: len(PAPER_DELAYS_FIG1)], growth[len(PAPER_DELAYS_FIG1) :]
    return {
        "system": system.to_dict(),
        "classification": classification.to_dict(),
        "U_BS": {
            "delay_margin": cert_bs.to_dict()["delay_margin"],
            "margin_reason": cert_bs.margin.reason,
            "gamma_0_delayed": cert_bs.principal_delayed.gamma_0,
            "chain_abscissa_delayed": cert_bs.principal_delayed.spectral_bound,
            "simulated_growth_rate": {f"{d:g}": g for d, (g, _) in zip(PAPER_DELAYS_FIG1, fig1)},
            "simulated_growth_rate_accuracy": {f"{d:g}": a for d, (_, a) in zip(PAPER_DELAYS_FIG1, fig1)},
        },
        f"U_BS2(K={PAPER_K:g})": {
            "delay_margin": cert_bs2.to_dict()["delay_margin"],
            "crossing_frequency": cert_bs2.margin.omega,
            "gamma_0_delayed": cert_bs2.principal_delayed.gamma_0,
            "spectral_abscissa": cert_bs2.abscissa.value,
            "rouche_delta_0": None if cert_bs2.rouche is None else cert_bs2.rouche.to_dict()["delta_0"],
            "simulated_growth_rate": {f"{d:g}": g for d, (g, _) in zip(PAPER_DELAYS_FIG3, fig3)},
            "simulated_growth_rate_accuracy": {f"{d:g}": a for d, (_, a) in zip(PAPER_DELAYS_FIG3, fig3)},
        },
        "chart": {
            "Ks": chart.Ks.tolist(),
            "margins": [json_float(m) for m in chart.margins],
            f"K_stable_up_to_{max(PAPER_DELAYS_FIG3):g}_on_grid": admissible,
        },
        "tradeoff": trade.to_dict(),
    }


def _paper_answer(classification: Classification, cert_bs: Certificate, cert_bs2: Certificate) -> tuple[str, list[str]]:
    """The report's first lines: which law survives a delay, each verdict, and how much is proven."""
    bs2 = f"U_BS2(K = {PAPER_K:g})"
    robust = [name for name, c in (("U_BS", cert_bs), (bs2, cert_bs2)) if c.delay_robust]
    fragile = [name for name, c in (("U_BS", cert_bs), (bs2, cert_bs2)) if not c.delay_robust]
    headline = "The paper's example (section 5): " + "; ".join(
        part
        for part in (
            f"{' and '.join(robust)} {'is' if len(robust) == 1 else 'are'} delay-robust" if robust else "",
            f"{' and '.join(fragile)} {'is' if len(fragile) == 1 else 'are'} not" if fragile else "",
        )
        if part
    )
    claims = [c for cert in (cert_bs, cert_bs2) for c in cert.claims]
    proven = sum(c.status == PROVEN for c in claims)
    return headline, [
        "**Plant:** " + ", ".join(f"{k} = {v:g}" for k, v in PAPER_SYSTEM.items()) + ".",
        f"**Classification:** {classification.statement}",
        f"**U_BS:** {cert_bs.verdict}",
        f"**{bs2}:** {cert_bs2.verdict}",
        f"**Proven:** {proven} of {len(claims)} claims of the two certificates in ball arithmetic"
        + ("." if proven == len(claims) else " (the rest checked in floating point; each section says which)."),
    ]


def _paper_intro(
    cert_bs: Certificate,
    cert_bs2: Certificate,
    summary: dict[str, Any],
    admissible: list[float],
) -> list[str]:
    """The details under the answer panel: the two loops, the growth rates, the gains, what is proven."""
    bs2 = summary[f"U_BS2(K={PAPER_K:g})"]
    reason = cert_bs.margin.reason
    return [
        "The example of section 5 of Auriol, Aarsnes, Martin and Di Meglio, in detail.",
        f"**U_BS.** {reason[:1].upper() + reason[1:]}; rightmost chain of the delayed difference operator at Re s = "
        f"{cert_bs.principal_delayed.spectral_bound:.4g}.",
        f"**U_BS2(K = {PAPER_K:g}).** Crossing frequency "
        f"{with_accuracy(cert_bs2.margin.omega, cert_bs2.margin.omega_accuracy) if cert_bs2.margin.omega else '-'}, "
        f"nominal decay rate {with_accuracy(-cert_bs2.abscissa.value, cert_bs2.abscissa.accuracy)}, Rouché "
        f"guaranteed range delta_0 = {cert_bs2.rouche.text if cert_bs2.rouche is not None else '-'}.",
        "Simulated growth rates (slope of log ||(u, v)|| over the second half of each run; the accuracy "
        f"estimated as {_GROWTH_SAFETY:g} times its change from the run on the grid half as fine): "
        + "; ".join(
            f"{name} delta = {d}: {_growth_text(g, part['simulated_growth_rate_accuracy'][d])}"
            for name, part in (("U_BS", summary["U_BS"]), ("U_BS2", bs2))
            for d, g in part["simulated_growth_rate"].items()
        )
        + ".",
        f"Gains of the chart's grid stable for every delay in [0, {max(PAPER_DELAYS_FIG3):g}]: "
        + (", ".join(f"{k:.3g}" for k in admissible) or "none")
        + ".",
        "**What is proven.** "
        + "; ".join(
            f"{name}: {claim.name.replace('delta_max', f'delta = {cert.delta_max:g}')} {claim.status}"
            for name, cert in (("U_BS", cert_bs), (f"U_BS2(K = {PAPER_K:g})", cert_bs2))
            for claim in cert.claims
            if claim.name in _CENTRAL_CLAIMS
        )
        + ". "
        + cert_bs2.scope,
    ]


def _fmt_num(x: Any) -> str:
    """``x`` with 6 significant digits, or ``-`` for None."""
    return "-" if x is None else f"{float(x):.6g}"


def paper_figure(number: int, runs: Sequence[Simulation] | None = None, cells: int = DEFAULT_CELLS) -> Figure:
    """Figure 1 or 3 of the paper: the ``L^2`` norm of the simulated closed loop.

    Figure 1: U_BS (eq. (47)) with ``delta = 0`` and ``0.01`` (:data:`PAPER_DELAYS_FIG1`):
    finite-time convergence without delay, growth with the smallest delay (Theorem 3,
    ``rho q = 0.85 > 1/2``). Figure 3: U_BS2 (eq. (53)) with ``K = 0.1`` and ``delta = 0,
    0.01, 0.1`` (:data:`PAPER_DELAYS_FIG3`): stable for every delay. The plant is
    :data:`PAPER_SYSTEM` from the initial state ``u = 1``, ``v = 1 + sin(pi x)``, up to
    :data:`PAPER_T_END`; the log axis is cut at the scheme's ``O(h^2)`` residual
    (:func:`nrobust.plots.residual_floor`). ``nrobust paper`` and
    ``examples/paper_figures.py`` (the figures of the documentation) both draw them here.

    Parameters
    ----------
    number : {1, 3}
        Which figure.
    runs : sequence of Simulation, optional
        The simulations, one per delay of the figure, if already computed (``run_paper``
        computes them in parallel); by default they are computed here with ``cells``.
    cells : int, default :data:`~nrobust.hyperbolic.simulate.normal_form.DEFAULT_CELLS`
        Grid cells of the simulations computed here.

    Returns
    -------
    matplotlib.figure.Figure
    """
    if number not in (1, 3):
        raise ParameterError("number", "1 or 3 (the paper's simulation figures)", number)
    controller, deltas = _figure_loop(number)
    law = "U_BS, eq. (47)" if number == 1 else f"U_BS2(K={PAPER_K:g}), eq. (53)"
    if runs is None:  # the runs of simulate(), marched together (the kernels solved once)
        runs = simulate_runs(
            Hyperbolic2x2(**PAPER_SYSTEM), [(controller, d) for d in deltas], PAPER_T_END, _paper_u0, _paper_v0, cells
        )
    elif len(runs) != len(deltas):
        raise ParameterError("runs", f"one simulation per delay {deltas}", runs)
    return simulation_figure(runs, [f"delta = {d:g}" for d in deltas], f"Figure {number} of the paper: {law}")
