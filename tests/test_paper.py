"""The paper's statements, as computations on its example (section 5).

lam = mu = sigma_pm = sigma_mp = q = 1, rho = 0.85: the open loop is unstable, the
finite-time controller U_BS loses stability with any loop delay (Theorem 3), and the
reflection-preserving U_BS2 with K = 0.1 keeps it (Theorem 4). Each verdict is reached by
two routes: certified root counts of the characteristic quasi-polynomial, and an
independent one (the kernel-free boundary function, the difference operator, or the
complete crossing search of the delay margin).
"""

from __future__ import annotations

import numpy as np
import pytest

import nrobust as nr

PAPER = nr.Hyperbolic2x2(lam=1.0, mu=1.0, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)


def test_open_loop_is_unstable_by_two_routes():
    F = nr.characteristic(PAPER, nr.OpenLoop())
    sa = nr.spectral_abscissa(F)
    assert sa.certified and sa.value > 0.9  # a real unstable root near 0.923
    root = sa.root
    assert abs(root.imag) < 1e-12
    # Kernel-free route: the same root zeroes v(1, s) - rho u(1, s) of the Laplace-transformed PDE.
    assert abs(nr.boundary_function(PAPER, np.array([root]))[0]) < 1e-7
    assert nr.count_roots(F, (0.5, 1.5, -1.0, 1.0)) == 1


def test_finite_time_controller_without_delay_has_no_root_at_all():
    """U_BS with delta = 0: the characteristic function is the constant 1 (finite time)."""
    F = nr.characteristic(PAPER, nr.FiniteTimeController(), 0.0)
    assert F.distributed == () and [(p.tolist(), t) for p, t in F.point_terms] == [([1.0], 0.0)]
    assert nr.count_roots(F, (-5.0, 5.0, -500.0, 500.0)) == 0


@pytest.mark.parametrize(
    "delta, box",
    [
        (0.01, (0.05, 0.6, 280.0, 340.0)),  # the chain peaks near Im s = pi / delta ~ 314
        (0.003, (0.05, 0.6, 1000.0, 1100.0)),  # ~ pi / 0.003 ~ 1047
    ],
)
def test_finite_time_controller_with_a_delay_is_unstable(delta, box):
    """Theorem 3: roots with positive real part for every delta > 0 when |rho q| > 1/2."""
    F = nr.characteristic(PAPER, nr.FiniteTimeController(), delta)
    found = nr.find_roots(F, box)
    assert found.certified and found.count > 0
    assert np.all(found.roots.real > 0.2)
    # Second route: the difference operator is not strongly stable (gamma_0 = 2 |rho q|)
    # and its chains reach Re s = C_D > 0; the roots of F lie within O(1/|s|) of them
    # (the distributed term decays like 1/|s|), so their peak approaches C_D.
    D = F.principal_part()
    assert D.gamma_0 == pytest.approx(1.7, rel=1e-13, abs=1e-14) and not D.is_strongly_stable()
    assert abs(found.roots.real.max() - D.strong_spectral_bound()) < 1e-3


@pytest.mark.parametrize("delta", [0.0, 0.01, 0.1])
def test_reflection_controller_is_stable_for_the_paper_delays(delta):
    """Theorem 4 with K = 0.1: no root in the closed right half-plane."""
    F = nr.characteristic(PAPER, nr.ReflectionController(0.1), delta)
    assert F.principal_part().is_strongly_stable()
    sa = nr.spectral_abscissa(F)
    assert sa.certified and sa.value < -0.02
    assert nr.count_roots(F, (0.0, 2.0, -sa.region[3], sa.region[3])) == 0


def test_reflection_controller_stable_on_the_whole_delay_interval():
    """The complete crossing search: stable for every delta in [0, 0.2], first crossing at 0.2295."""
    dm = nr.delay_margin(PAPER, nr.ReflectionController(0.1), delta_max=0.2)
    assert dm.verified and dm.nominally_stable and dm.strongly_stable
    assert dm.intervals == ((0.0, 0.2),)
    assert dm.margin == pytest.approx(0.2295391304, abs=1e-9)  # n = 201 vs 401: 1.3e-10
    # The margin is a root on the imaginary axis.
    A, B = nr.loop_factors(PAPER, nr.ReflectionController(0.1))
    s = np.array([1j * dm.omega])
    assert abs((A(s) + B(s) * np.exp(-s * dm.margin))[0]) < 1e-9


def test_target_system_of_the_reflection_controller():
    """Lemma 3: without delay, U_BS2 leaves 1 - (rho - K) q e^{-tau s}: chain at ln(0.75)/2."""
    F = nr.characteristic(PAPER, nr.ReflectionController(0.1), 0.0)
    assert F.distributed == ()
    roots = nr.find_roots(F, (-1.0, 1.0, -10.0, 10.0))
    assert roots.certified
    np.testing.assert_allclose(roots.roots.real, np.log(0.75) / 2, rtol=0, atol=1e-12)


def test_theorem_2_open_loop_gain_above_one():
    """|rho q| > 1: infinitely many unstable open-loop poles, near Re s = ln(rho q) / tau."""
    plant = nr.Hyperbolic2x2(lam=1.0, mu=1.0, sigma_pm=0.3, sigma_mp=0.2, q=1.0, rho=1.4)
    assert nr.classify(plant).regime == "not_stabilizable"
    F = nr.characteristic(plant, nr.OpenLoop())
    chain = np.log(1.4) / 2
    for im0 in (100.0, 1000.0):
        found = nr.find_roots(F, (chain - 0.1, chain + 0.1, im0, im0 + 20.0))
        assert found.certified and found.count >= 5
        assert np.all(found.roots.real > 0)


@pytest.mark.slow
def test_the_paper_job_at_full_size(tmp_path):
    """`nrobust paper` (the README's main job) with its default sizes, numbers included."""
    import gc
    import json

    from nrobust.cli import run_paper

    run_paper(tmp_path, progress=False)
    assert gc.get_freeze_count() == 0  # the objects frozen for the workers are collected again here
    assert gc.isenabled()  # collections are off in the workers only
    data = json.loads((tmp_path / "summary.json").read_text())
    bs, bs2 = data["U_BS"], data["U_BS2(K=0.1)"]
    assert bs["delay_margin"] == 0.0 and bs["gamma_0_delayed"] == pytest.approx(1.7, rel=1e-13, abs=1e-14)
    assert bs["chain_abscissa_delayed"] == pytest.approx(0.26465293, abs=1e-7)
    assert bs2["delay_margin"] == pytest.approx(0.2295391304, abs=2e-10)
    assert bs2["crossing_frequency"] == pytest.approx(6.2809603591, abs=1e-8)
    assert bs2["spectral_abscissa"] == pytest.approx(np.log(0.75) / 2, abs=1e-10)
    assert 0.0 < bs2["rouche_delta_0"] <= bs2["delay_margin"]
    stable = data["chart"]["K_stable_up_to_0.1_on_grid"]
    assert min(stable) > -0.15 and max(stable) < 0.15  # inside the paper's bound (54)
    assert (tmp_path / "report.html").stat().st_size > 100_000
    # the answer first: right under the title, a panel saying which law survives a delay, each verdict
    # (the margin with its accuracy) and how much is proven; the details come after it
    md = (tmp_path / "report.md").read_text().splitlines()
    assert md[2] == "> **The paper's example (section 5): U_BS2(K = 0.1) is delay-robust; U_BS is not**"
    end = next(k for k in range(2, len(md)) if not md[k].startswith(">"))
    text = "\n".join(md[2:end])
    assert "**U_BS:** FiniteTimeController: stable without delay but with zero delay margin" in text
    assert "**U_BS2(K = 0.1):** ReflectionController: delay-robust" in text and "0.22953913027" in text
    assert "**Proven:** 17 of 17 claims" in text


def test_a_hidden_progress_bar_does_not_load_tqdm():
    """The paper's jobs and every computation off a terminal run without tqdm (and the
    ``importlib.metadata`` and ``email`` it loads): a hidden bar only counts."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "from nrobust._progress import progress_bar\n"
        "from nrobust.hyperbolic import TransportSystem\n"
        "from nrobust.hyperbolic.analyses import stability_chart\n"
        "with progress_bar(3, False, 'x') as bar:\n"
        "    bar.update(2)\n"
        "stability_chart(TransportSystem(1.0, 1.0, 1.0, 0.5), [0.1, 0.3], [0.0, 0.1], progress=False)\n"
        "assert 'tqdm' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
