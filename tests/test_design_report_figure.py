"""The figure of ``nrobust design``'s report (family ``"reflection"``): delta*(K), the decay rate at ``delta = 0``
against ``K``, and the trade-off of the best decay rate against the delay margin.

Oracles: Lemma 3, the decay rate ``-ln|(rho - K) q| / tau`` of U_BS2(K) at ``delta = 0`` (paper's plant,
``tau = 2``), at every drawn gain; the trade-off staircase recomputed here from the drawn samples by a plain
loop; the design's own scan for the margin curve.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nrobust import Hyperbolic2x2
from nrobust.reports.design import _rate_samples, _tradeoff_figure, run_design

PAPER = """
[system]
type = "Hyperbolic2x2"
lam = 1.0
mu = 1.0
sigma_pm = 1.0
sigma_mp = 1.0
q = 1.0
rho = 0.85

[design]
objective = "decay_rate"
margin_at_least = 0.15
"""


def test_the_report_draws_the_rate_and_the_tradeoff(tmp_path: Path) -> None:
    path = tmp_path / "SYSTEM.toml"
    path.write_text(PAPER)
    written, result = run_design(path, tmp_path / "out")
    png = tmp_path / "out" / "design.png"
    assert png in written and png.read_bytes().startswith(b"\x89PNG")
    report = (tmp_path / "out" / "design.md").read_text()
    assert "decay rate at delta = 0 against K, and the best sampled decay rate against the delay margin" in report
    assert "](design.png)" in report

    samples = _rate_samples(Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85), result)
    fig = _tradeoff_figure(result, 0.15, samples)
    margin_ax, rate_ax, trade_ax = fig.axes
    d = result.design
    (envelope,) = [ln for ln in margin_ax.get_lines() if ln.get_label().startswith("delay margin delta*(K)")]
    np.testing.assert_array_equal(envelope.get_xdata(), d.gains)

    (rate,) = [ln for ln in rate_ax.get_lines() if ln.get_label().startswith("decay rate at delta = 0")]
    K, r = np.asarray(rate.get_xdata()), np.asarray(rate.get_ydata())
    assert K.size >= 30 and K.min() == d.gains[0] and K.max() == d.gains[-1]
    # the spectral abscissa is accurate to ~1e-15 here (one chain of roots, closed form); 1e-9 leaves room
    np.testing.assert_allclose(r, -np.log(np.abs((0.85 - K) * 1.0)) / 2.0, rtol=0, atol=1e-9)

    (step,) = [ln for ln in trade_ax.get_lines() if ln.get_label().startswith("best sampled rate")]
    (dots,) = [ln for ln in trade_ax.get_lines() if ln.get_label() == "the sampled gains"]
    m, rs = np.asarray(dots.get_xdata()), np.asarray(dots.get_ydata())
    np.testing.assert_array_equal(rs, r)
    expected = {}
    for level in m[np.isfinite(m)]:
        expected[float(level)] = max(float(y) for x, y in zip(m, rs) if x >= level)
    levels = sorted(expected)
    np.testing.assert_array_equal(step.get_xdata(), levels)
    np.testing.assert_array_equal(step.get_ydata(), [expected[v] for v in levels])
    # the design is at least as good as every sampled gain that keeps the required margin
    assert d.decay_rate >= max(y for x, y in zip(m, rs) if x >= 0.15) - 1e-12
