"""Plots: each artist holds what it claims (rendered with the Agg backend)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest

from nrobust import plots
from nrobust.errors import ParameterError
from nrobust.hyperbolic import Hyperbolic2x2
from nrobust.hyperbolic.loops.controllers import ReflectionController
from nrobust.hyperbolic.simulate import simulate
from nrobust.margins import delay_margin
from nrobust.quasipoly import QuasiPolynomial as Q
from nrobust.roots import count_roots, find_roots


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


A_TRANSPORT = Q([[1.0], [-0.85]], [0.0, 2.0])  # 1 - rho q e^{-tau s}, paper's example


def test_nyquist_reflection_controller_is_stable_without_crossings():
    """U_BS2 on the transport system: |K q| < 1 - |rho q|, |L| < 1 everywhere (eq. (54))."""
    B = Q([[0.1]], [2.0])
    resp = plots.nyquist_response(A_TRANSPORT, B, delta=0.1, omega_max=60.0, n_freq=2001)
    assert resp.rhp_zeros == 0 and resp.note == ""
    assert resp.crossings.size == 0
    w = resp.omega
    expected = B(1j * w) / A_TRANSPORT(1j * w) * np.exp(-0.1j * w)
    np.testing.assert_allclose(resp.loop, expected, rtol=1e-12, atol=0)
    fig, ax = plt.subplots()
    out = resp.plot(ax=ax)
    assert out.axes is ax and out.figure is fig
    np.testing.assert_allclose(out.lines["loop"][0].get_xdata(), expected.real, rtol=1e-15, atol=0)
    np.testing.assert_allclose(out.lines["loop"][0].get_ydata(), expected.imag, rtol=1e-15, atol=0)
    circle = out.lines["unit_circle"][0]
    np.testing.assert_allclose(np.hypot(circle.get_xdata(), circle.get_ydata()), 1.0, rtol=1e-15, atol=0)
    assert out.lines["crossings"] == []
    assert list(out.lines["critical"][0].get_xdata()) == [-1.0]


def test_nyquist_finite_time_controller_has_no_finite_count():
    """U_BS with |rho q| > 1/2: the difference operator is not stable (Theorem 3)."""
    B = Q([[0.85]], [2.0])
    resp = plots.nyquist_response(A_TRANSPORT, B, delta=0.1, omega_max=20.0, n_freq=2001)
    assert resp.rhp_zeros is None and resp.principal_bound > 0
    assert "spectral bound" in resp.note
    # |1 - 0.85 e^{-2 i w}| = 0.85 at cos 2w = 1/1.7: the certified search (nrobust.margins) locates
    # them to its tolerance 1e-12 max(1, w) (measured 8.3e-13 relative), on the band 0 < w <= 20
    exact = np.sort([(sign * np.arccos(1 / 1.7) + 2 * np.pi * k) / 2 for k in range(8) for sign in (1, -1)])
    exact = exact[(exact > 0) & (exact <= 20.0)]
    assert resp.crossings.size == exact.size == 13 and resp.crossing_note == ""
    np.testing.assert_allclose(resp.crossings, exact, rtol=1e-12, atol=1e-12)
    out = resp.plot()
    pts = resp.crossing_values
    np.testing.assert_allclose(out.lines["crossings"][0].get_xdata(), pts.real, rtol=1e-15, atol=0)
    # |L| - 1 ~ |d|L|/dw| * (error in w), measured 3.1e-11
    np.testing.assert_allclose(np.abs(pts), 1.0, rtol=0, atol=1e-10)


@pytest.mark.parametrize(
    "A,B,delta",
    [
        (Q([[-1.0, 1.0]], [0.0]), Q([[0.0]], [0.0]), 0.0),  # s - 1
        (Q([[-1.0, 1.0]], [0.0]), Q([[0.0, 0.5]], [1.0]), 0.0),  # neutral, one real root > 0
        (Q([[2.0, 1.0]], [0.0]), Q([[-3.0, 0.4]], [0.5]), 0.7),  # neutral with a delay
    ],
)
def test_nyquist_count_matches_certified_root_count(A, B, delta):
    resp = plots.nyquist_response(A, B, delta=delta, omega_max=400.0)
    F = A + B.shift(delta)
    assert resp.rhp_zeros is not None, resp.note
    assert resp.rhp_zeros == int(count_roots(F, (0.0, 20.0, -400.0, 400.0)))


def test_root_map_markers_are_the_roots_and_chains_are_drawn():
    F = Q([[1.0], [-0.85], [0.1]], [0.0, 2.0, 2.1])
    box = (-1.0, 1.0, -15.0, 15.0)
    roots = find_roots(F, box)
    out = plots.root_map_plot(F, box, roots=roots)
    marker = out.lines["roots"][0]
    np.testing.assert_allclose(marker.get_xdata(), roots.roots.real, rtol=1e-15, atol=0)
    np.testing.assert_allclose(marker.get_ydata(), roots.roots.imag, rtol=1e-15, atol=0)
    reals = sorted(line.get_xdata()[0] for line in out.lines["chains"])
    expected = sorted(c.real for c in F.principal_part().chains().chains if -1.0 <= c.real <= 1.0)
    assert len(expected) == 20
    np.testing.assert_allclose(reals, expected[-12:], rtol=1e-15, atol=0)  # the 12 rightmost by default
    out_all = plots.root_map_plot(F, box, roots=roots, max_chains=50)
    np.testing.assert_allclose(
        sorted(line.get_xdata()[0] for line in out_all.lines["chains"]), expected, rtol=1e-15, atol=0
    )
    assert out.lines["axis"][0].get_xdata()[0] == 0.0
    assert out.axes.get_xlim() == (-1.0, 1.0)
    data = plots.root_map_response(F, box, roots=roots)
    assert data.count == roots.count and data.unstable == int(np.sum(roots.roots.real > 0))
    np.testing.assert_array_equal(data.chains, sorted(expected, reverse=True))
    assert data.hidden is None and data.to_dict()["count"] == roots.count


def test_nyquist_crossings_are_those_of_the_certified_search():
    """The crossings on a Nyquist plot are those of the delay margin (one search, nrobust.margins)."""
    A, B = Q([[1.0, 1.0]], [0.0]), Q([[2.0]], [0.0])  # s + 1 + 2 e^{-delta s}: |A| = |B| at w = sqrt(3)
    resp = plots.nyquist_response(A, B, delta=0.2, omega_max=20.0)
    margin = delay_margin(A, B)
    np.testing.assert_array_equal(resp.crossings, [c.omega for c in margin.crossings])
    # s^2 + 1 with B = 0: A and B vanish together at w = 1 (a tangency the sign changes missed)
    resp = plots.nyquist_response(Q([[1.0, 0.0, 1.0]], [0.0]), Q([[0.0]], [0.0]), omega_max=20.0, n_freq=256)
    np.testing.assert_allclose(resp.crossings, [1.0], rtol=1e-12, atol=0)
    resp.plot()  # L = 0/0 there: the point is not labelled


def test_root_locus_in_a_gain_matches_closed_form():
    """F_K(s) = 1 - K e^{-s}: roots ln K + 2 pi i k."""
    Ks = np.array([0.5, 0.7, 0.9])
    data = plots.root_locus_response(lambda K: Q([[1.0], [-K]], [0.0, 1.0]), Ks, (-1.0, 0.5, -10.0, 10.0), name="K")
    for K, r in zip(Ks, data.roots):
        expected = np.log(K) + 2j * np.pi * np.arange(-1, 2)
        # Newton-polished simple roots of 1 - K e^{-s}: rounding only (measured 7e-17)
        np.testing.assert_allclose(np.sort_complex(r), np.sort_complex(expected), rtol=1e-13, atol=1e-13)
    out = data.plot()
    scatter = out.lines["roots"][0]
    offsets = scatter.get_offsets()
    assert offsets.shape == (9, 2)
    np.testing.assert_allclose(np.sort(scatter.get_array()), np.repeat(Ks, 3), rtol=1e-15, atol=0)
    assert data.to_dict()["name"] == "K"


def test_simulation_plot_log_scale_one_line_per_run():
    system = Hyperbolic2x2(lam=1.0, mu=1.0, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)
    runs = [
        simulate(
            system, ReflectionController(0.1), d, 4.0, lambda x: np.sin(np.pi * x), lambda x: 1.0 + 0 * x, cells=40
        )
        for d in (0.0, 0.1)
    ]
    out = plots.simulation_plot(runs, labels=["delta=0", "delta=0.1"])
    assert out.axes.get_yscale() == "log"
    assert len(out.lines["norms"]) == 2
    np.testing.assert_allclose(out.lines["norms"][1].get_ydata(), runs[1].norm, rtol=1e-15, atol=0)
    with pytest.raises(ParameterError, match="labels"):
        plots.simulation_plot(runs, labels=["one"])


def test_plot_arguments_are_checked():
    with pytest.raises(ParameterError, match=r"^A must be"):
        plots.nyquist_response(True, A_TRANSPORT)
    with pytest.raises(ParameterError, match=r"^B must be"):
        plots.nyquist_response(A_TRANSPORT, "0.85")
    # a number is a constant factor, as in delay_margin(A, B): 1 + 0.5 e^{-0.3 s} has no root in Re s >= 0
    assert plots.nyquist_response(1.0, 0.5, delta=0.3).rhp_zeros == 0
    with pytest.raises(ParameterError, match="omega_max"):
        plots.nyquist_response(A_TRANSPORT, A_TRANSPORT, omega_max=-1.0)
    with pytest.raises(ParameterError, match="region"):
        plots.root_map_plot(A_TRANSPORT, (1.0, 0.0, -1.0, 1.0), roots=[])


def test_stability_chart_and_tradeoff_plots_draw_their_data():
    from nrobust.hyperbolic.analyses import StabilityChart, Tradeoff

    Ks = np.array([-0.1, 0.0, 0.1])
    deltas = np.array([0.0, 0.1, 0.2])
    values = np.array([[0, 0, 1], [0, 0, 0], [0, 1, 1]], dtype=float)
    margins = np.array([0.15, np.inf, 0.05])
    boundaries = (np.array([[0.15, 3.0, 1.0]]), np.zeros((0, 3)), np.array([[0.05, 2.0, 1.0], [0.3, 2.0, 1.0]]))
    chart = StabilityChart(Ks, deltas, values, "count", margins, boundaries)
    out = plots.stability_chart_plot(chart, k_bound=0.15, rouche=(Ks, np.array([0.01, 0.02, 0.0])))
    assert len(out.lines["stable"][0].get_xdata()) == 6 and len(out.lines["unstable"][0].get_xdata()) == 3
    np.testing.assert_allclose(
        out.lines["margin"][0].get_ydata(), [0.15, 0.2, 0.05], rtol=1e-15, atol=0
    )  # infinite margin drawn at the top
    np.testing.assert_allclose(out.lines["crossings"][0].get_ydata(), [0.15, 0.05, 0.3], rtol=1e-15, atol=0)
    assert [line.get_xdata()[0] for line in out.lines["paper_bound"]] == [-0.15, 0.15]
    np.testing.assert_allclose(out.lines["rouche"][0].get_ydata(), [0.01, 0.02, 0.0], rtol=1e-15, atol=0)
    trade = Tradeoff(Ks, np.array([0.1, 0.2, 0.3]), margins, np.zeros(3))
    out = plots.tradeoff_plot(trade)
    np.testing.assert_allclose(out.lines["curve"][0].get_xdata(), [0.15, 0.05], rtol=1e-15, atol=0)
    np.testing.assert_allclose(out.lines["curve"][0].get_ydata(), [0.1, 0.3], rtol=1e-15, atol=0)


def test_root_locus_in_delta_and_the_one_call_wrappers():
    """Locus in the loop delay of U = -rho u(t, 1) on the transport line: every plotted
    point is a zero of 1 - rho q e^{-tau s} + rho q e^{-(tau + delta) s}."""

    def family(d):
        return A_TRANSPORT + Q([[0.85]], [2.0]).shift(d)

    deltas = [0.25, 0.5]
    out = plots.root_locus_plot(family, deltas, (-1.0, 0.5, 0.0, 12.0), name="delta")
    pts = out.lines["roots"][0].get_offsets()
    z = pts[:, 0] + 1j * pts[:, 1]
    colours = out.lines["roots"][0].get_array()
    assert z.size > 0 and set(np.unique(colours)) == set(deltas)
    for d in deltas:
        assert np.max(np.abs(family(d)(z[colours == d]))) < 1e-8
    nyq = plots.nyquist_plot(A_TRANSPORT, Q([[0.1]], [2.0]), delta=0.1, omega_max=10.0)
    assert "0 closed-loop zeros" in nyq.axes.get_title()


def _paper_loop(controller, delta):
    from nrobust.hyperbolic.loops.controllers import characteristic

    return characteristic(Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85), controller, delta)


def test_root_map_shows_the_unstable_open_loop_root():
    """Open loop of the paper's plant: one unstable real root, 0.923 (outside the old fixed box [-3, 1]/tau).

    The value is the PDE's: the root of ``v(1, s) - rho u(1, s)`` by mpmath at 30 digits,
    0.922962801169938538577592942167 (the cubic spline of N~ on 201 points had 0.922962801372)."""
    from nrobust.hyperbolic.loops.controllers import OpenLoop
    from nrobust.roots import spectral_abscissa

    F = _paper_loop(OpenLoop(), 0.0)
    rightmost = spectral_abscissa(F).root
    np.testing.assert_allclose(rightmost, 0.922962801169938538577592942167, rtol=0, atol=1e-13)
    box = plots.root_map_region(F)
    assert box[0] <= -1.5 and box[1] >= rightmost.real + 0.25 and box[2] <= -20.0 <= 20.0 <= box[3]
    out = plots.root_map_plot(F)
    unstable = out.lines["unstable"][0]
    np.testing.assert_allclose(unstable.get_xdata(), [rightmost.real], rtol=1e-9, atol=0)
    assert out.axes.get_xlim()[1] > rightmost.real
    assert any("1 unstable" in t.get_text() for t in out.axes.get_legend().get_texts())


@pytest.mark.slow
def test_root_map_shows_the_unstable_roots_of_u_bs_at_a_small_delay():
    """U_BS with delta = 0.01: the unstable roots sit near Im s = +-311 on the chains at Re s = 0.2647."""
    from nrobust.hyperbolic.loops.controllers import FiniteTimeController
    from nrobust.roots import spectral_abscissa

    F = _paper_loop(FiniteTimeController(), 0.01)
    abscissa = spectral_abscissa(F)
    rightmost = abscissa.root
    assert rightmost.real > 0.26 and 300.0 < rightmost.imag < 320.0
    box = plots.root_map_region(F, abscissa=abscissa)
    assert box[0] < rightmost.real < box[1] and box[2] < -rightmost.imag and rightmost.imag < box[3]
    out = plots.root_map_plot(F, box)
    unstable = out.lines["unstable"][0]
    z = unstable.get_xdata() + 1j * unstable.get_ydata()
    assert z.size > 0 and np.all(z.real > 0)
    assert np.min(np.abs(z - rightmost)) < 1e-8
    # the certified count of the map's unstable roots agrees with the markers
    assert int(count_roots(F, (0.0, box[1], box[2], box[3]))) == z.size


def test_figure_1_cuts_its_axis_at_the_residual_and_shows_the_growth():
    """Under U_BS without delay the norm reaches the scheme's residual after t = tau (down to
    1e-40 and below); the axis stops at h^2 max ||.|| so that the delta = 0.01 growth shows."""
    from nrobust.hyperbolic.loops.controllers import FiniteTimeController
    from nrobust.reports.paper import PAPER_DELAYS_FIG1, PAPER_SYSTEM, _paper_u0, _paper_v0, paper_figure

    system = Hyperbolic2x2(**PAPER_SYSTEM)
    runs = [
        simulate(system, FiniteTimeController(), d, 8.0, _paper_u0, _paper_v0, cells=100) for d in PAPER_DELAYS_FIG1
    ]
    assert runs[0].norm[-1] < 1e-15  # finite-time convergence, then the residual decays further
    floor = plots.residual_floor(runs)
    np.testing.assert_allclose(floor, max(r.norm.max() for r in runs) / 100**2, rtol=1e-15, atol=0)
    ax = paper_figure(1, runs).axes[0]
    bottom, top = ax.get_ylim()
    assert bottom == floor and top > runs[1].norm.max()
    # the delayed loop grows over the visible range: from t = 3 to t = 8 by a factor 1.75 (100 cells)
    grown = runs[1].norm[-1] / runs[1].norm[np.searchsorted(runs[1].times, 3.0)]
    assert grown > 1.5 and runs[1].norm.min() > bottom
    assert "O(h^2) residual" in " ".join(t.get_text() for t in ax.texts)
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["delta = 0", "delta = 0.01"]
    # a stable loop stays above the residual: the axis hugs the data, no note
    out = plots.simulation_plot(runs[1:])
    assert out.lines["floor"] == [] and out.axes.get_ylim()[0] > floor
    with pytest.raises(ParameterError, match="number"):
        paper_figure(2)


def test_rouche_curve_is_drawn_for_negative_gains_too():
    """delta_0(K) of Theorem 4 depends on |K| only; a curve computed for K >= 0 is mirrored,
    and the mirrored values are the bound computed at -K."""
    from nrobust.hyperbolic.analyses import StabilityChart
    from nrobust.hyperbolic.analyses.rouche import rouche_delay_bound

    system = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
    Ks = np.array([0.0, 0.05, 0.1])
    d0 = np.array([rouche_delay_bound(system, ReflectionController(K)).delta_0 for K in Ks])
    chart = StabilityChart(
        np.array([-0.1, 0.1]),
        np.array([0.0, 1.0]),
        np.zeros((2, 2)),
        "count",
        np.full(2, np.inf),
        (np.zeros((0, 3)),) * 2,
    )
    line = plots.stability_chart_plot(chart, rouche=(Ks, d0)).lines["rouche"][0]
    np.testing.assert_array_equal(line.get_xdata(), [-0.1, -0.05, 0.0, 0.05, 0.1])
    mirrored = [rouche_delay_bound(system, ReflectionController(K)).delta_0 for K in (-0.1, -0.05)]
    np.testing.assert_allclose(line.get_ydata()[:2], mirrored, rtol=1e-12, atol=0)
    np.testing.assert_allclose(line.get_ydata()[2:], d0, rtol=1e-15, atol=0)


def test_nyquist_labels_are_spread_and_the_mirror_is_in_the_legend():
    """U_BS on the transport line at delta = 0.01: dozens of crossings in clusters; at most six
    labels, no two closer than 12 % of the plot's width."""
    B = Q([[0.85]], [2.0])
    resp = plots.nyquist_response(A_TRANSPORT, B, delta=0.01, omega_max=60.0, n_freq=2001)
    assert resp.crossings.size > 20
    out = resp.plot()
    labels = out.lines["labels"]
    assert 1 <= len(labels) <= 6
    at = np.array([complex(*a.xy) for a in labels])
    span = max(np.ptp(resp.loop.real), 2.0)
    gaps = np.abs(at[:, None] - at[None, :])[np.triu_indices(at.size, 1)]
    assert np.all(gaps > 0.12 * span)
    assert labels[0].get_text() == f"{resp.crossings[0]:.3g}"  # the lowest crossing is labelled
    legend = [t.get_text() for t in out.axes.get_legend().get_texts()]
    assert "L(-iw), mirror image" in legend and any(t.startswith(f"{resp.crossings.size} crossings") for t in legend)


def test_sweep_chart_leaves_gaps_at_infinite_margins():
    """A curve must not join the finite margins on either side of an infinite stretch."""
    import nrobust

    def margin(K: float) -> dict:
        return {"delta_star": np.inf if abs(K) < 0.45 else 0.0}

    result = nrobust.sweep(margin, [{"K": K} for K in np.linspace(-0.9, 0.9, 19)], "serial")
    fig = plots.sweep_chart(result, ["K"], {}, sampling=False)
    curve, infinite = fig.axes[0].get_lines()[:2]
    y = np.asarray(curve.get_ydata(), dtype=float)
    np.testing.assert_array_equal(np.isnan(y), np.abs(curve.get_xdata()) < 0.45)
    assert len(infinite.get_xdata()) == 9


def test_root_map_names_an_unstable_chain_above_its_height():
    """U = -rho u(t, 1) on the transport line with delta = 0.01, the map capped below the chain's
    roots: the chain at Re s = c, its zero nearest the axis at Im s = pi / 0.01 (z = e^{-0.01 s}
    = -r with r^200 (1 + r) = 1 / 0.85, so c = -100 ln r), is written on the figure."""
    from scipy.optimize import brentq

    F = Q([[1.0], [-0.85], [0.85]], [0.0, 2.0, 2.01])
    r = brentq(lambda x: 200 * np.log(x) + np.log1p(x) + np.log(0.85), 0.5, 1.0, xtol=1e-15)
    box = (-1.5, 0.6, -60.0, 60.0)
    hidden = plots.hidden_unstable_roots(F, box)
    np.testing.assert_allclose(hidden.real, -100.0 * np.log(r), rtol=0, atol=1e-10)
    np.testing.assert_allclose(hidden.first, np.pi / 0.01, rtol=1e-12, atol=0)
    assert hidden.height == 60.0 and hidden.chains > 1
    out = plots.root_map_plot(F, box)
    assert out.lines["unstable"][0].get_xdata().size == 0  # no unstable root in the map
    (note,) = out.lines["note"]
    text = note.get_text().replace("\n", " ")
    assert text.startswith("Unstable roots not drawn: the chain at Re s = 0.2647") and "+-314.16" in text
    assert any(line.get_xdata()[0] == hidden.real and line.get_color() == "tab:red" for line in out.lines["chains"])
    # the same map tall enough to hold the chain's first roots: no note
    assert plots.hidden_unstable_roots(F, (-1.5, 0.6, -330.0, 330.0)) is None
    assert plots.root_map_plot(A_TRANSPORT, (-1.0, 0.5, -10.0, 10.0), roots=[]).lines["note"] == []
    with pytest.raises(ParameterError, match="roots must be an array of finite numbers"):
        plots.hidden_unstable_roots(F, box, [np.nan])


@pytest.mark.slow
def test_root_map_of_u_bs_at_delta_0001_says_where_the_unstable_roots_are():
    """U_BS at delta = 0.001 on the paper's plant: the chains (delays 2 and 2.001, not resolved
    within the degree bound) reach Re s = 0.26525 near Im s = pi / 0.001, far above the map.
    The figure says so; three of those roots are found there independently."""
    from nrobust.hyperbolic.loops.controllers import FiniteTimeController

    F = _paper_loop(FiniteTimeController(), 0.001)
    box = plots.root_map_region(F)
    out = plots.root_map_plot(F, box)
    # the map reaches the rightmost roots below its height bound, all stable; none is circled
    drawn = out.lines["roots"][0].get_xdata()
    assert drawn.size > 0 and drawn.max() < 0.0 and out.lines["unstable"][0].get_xdata().size == 0
    assert int(count_roots(F, (0.0, *box[1:]))) == 0
    hidden = plots.hidden_unstable_roots(F, box, [])
    assert hidden.first is None and 0.265 < hidden.lower <= hidden.real < 0.2653
    assert box[0] < hidden.real < box[1]
    (note,) = out.lines["note"]
    assert "Unstable roots not drawn" in note.get_text() and f"{box[3]:.4g}" in note.get_text()
    assert any(line.get_xdata()[0] == hidden.real and line.get_color() == "tab:red" for line in out.lines["chains"])
    above = find_roots(F, (0.2, 0.4, 3136.0, 3146.0))
    assert above.count == 3 and above.certified
    np.testing.assert_allclose(above.roots.real, hidden.real, rtol=0, atol=1e-5)


@pytest.mark.slow  # a certificate and its figures: ~4 s
def test_report_caption_names_the_unstable_roots_above_the_root_map():
    """The report repeats the figure's note: U_BS on the transport line at delta_max = 0.001."""
    from nrobust import TransportSystem
    from nrobust.hyperbolic.loops.controllers import FiniteTimeController
    from nrobust.reports.certificate import certify
    from nrobust.reports.report import certificate_figures

    cert = certify(TransportSystem(1.0, 1.0, 1.0, 0.85), FiniteTimeController(), delta_max=0.001)
    caption = certificate_figures(cert)[0][0]
    assert caption.startswith("Closed-loop roots in a region holding the rightmost roots")
    assert "At delta = 0.001: Unstable roots not drawn: chains with Re s -> c_D in [0.2652, 0.2652]" in caption
    assert "At delta = 0:" not in caption  # U_BS without delay: F = 1, no root at all


def test_root_map_region_work_bound_keeps_the_base():
    """U = -rho u(t, 1) on the transport line with delta = 0.01: the rightmost chain (Re s = 0.265)
    first meets the roots near Im s = 311; a small work bound stops the widening, never the base."""
    F = Q([[1.0], [-0.85], [0.85]], [0.0, 2.0, 2.01])
    from nrobust.roots import spectral_abscissa

    top = max(F.principal_part().chains().chains, key=lambda c: c.real)
    sa = spectral_abscissa(F)
    box = plots.root_map_region(F, abscissa=sa)
    assert box[1] > top.real and box[3] > 300.0 and box[2] == -box[3]
    capped = plots.root_map_region(F, abscissa=sa, max_roots=100)
    np.testing.assert_allclose(capped[3], 100 * np.pi / (2.01 * (capped[1] - capped[0])), rtol=1e-12, atol=0)
    assert capped[3] < 300.0
    wide = plots.root_map_region(F, base=(-1.0, 0.5, -200.0, 200.0), abscissa=sa, max_roots=100)
    assert wide[2] == -200.0 and wide[3] == 200.0


def test_the_legend_keeps_off_a_note_in_the_corner_it_would_take():
    """Lines in three corners, the lower left empty: the legend goes there, unless a note placed
    in axes fractions (the simulation plot's "axis cut at ...") stands there."""
    from nrobust.plots.base import legend_corner

    fig, ax = plt.subplots()
    for x, y in ((0.9, 0.9), (0.1, 0.9), (0.9, 0.1)):
        ax.plot([x - 0.05, x + 0.05], [y, y], "k-")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1)
    assert legend_corner(ax) == "lower left"
    ax.text(0.01, 0.02, "axis cut at 1e-04", transform=ax.transAxes)
    assert legend_corner(ax) != "lower left"
    plt.close(fig)


def test_the_paper_figure_1_legend_does_not_hide_its_axis_cut_note():
    """Figure 1 of ``nrobust paper``: the legend's box and the note's box do not overlap when drawn."""
    from nrobust.reports.paper import paper_figure

    fig = paper_figure(1)
    ax = fig.axes[0]
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    notes = [t for t in ax.texts if t.get_text().startswith("axis cut")]
    assert notes
    legend = ax.get_legend().get_window_extent(renderer)
    assert not any(legend.overlaps(t.get_window_extent(renderer)) for t in notes)
    plt.close(fig)
