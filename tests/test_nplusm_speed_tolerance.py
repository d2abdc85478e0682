"""A tolerance on the transport speeds in the gain design of an n + m system (``speed_tolerance=``).

The plant is the coupled 2x2 plant of ``tests/test_nplusm_design.py`` as a 1 + 1 system (``lam = mu = 1``,
``sigma+- = 1.5``, ``sigma-+ = 0.5``, ``q = 0.8``, ``r = 0.4``). The oracle is written here in mpmath at 40
digits, from the PDE and not from nrobust's builders: the loop ``F(s; delta) = A(s) + B(s) e^{-delta s}``
with ``A = e^{-s/mu} (Phi_v - r Phi_u)``, ``B = -k e^{-s/mu} Phi_u``, ``[Phi_u; Phi_v] = exp(M) [q; 1]``,
``M = Lambda^{-1} (Sigma - s I)`` exponentiated in closed form (a 2 x 2 matrix:
``e^{tr/2} (cosh(D) I + sinh(D)/D (M - tr/2 I))``, ``D^2 = (tr/2)^2 - det``). For each plant with perturbed
speeds it finds every crossing frequency (the zeros of ``|A(i w)|^2 - |B(i w)|^2``, bracketed on a grid and
refined by the Illinois method) with its first crossing delay, and counts the zeros of ``F(.; 0)`` in
``[0, 4] x [-40, 40]`` by the argument principle (the winding of ``F`` along the rectangle).
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Callable
from pathlib import Path

import mpmath as mp
import numpy as np
import pytest
from _oracles import one_plus_one_factors, winding_number

from nrobust._digits import with_accuracy
from nrobust.cli import main
from nrobust.config import load_system_file
from nrobust.errors import CertificationError, ParameterError
from nrobust.hyperbolic.nplusm import NPlusMSystem, design_nplusm_gains, nplusm_delay_margin
from nrobust.hyperbolic.nplusm.characteristic import NPlusMCharacteristic
from nrobust.hyperbolic.nplusm.design import NPlusMGainProblem, nplusm_speed_tolerance
from nrobust.hyperbolic.nplusm.speed_box import MAX_SPEED_CORNERS, perturbed_system, speed_box
from nrobust.reports.design import _nplusm_markdown, design_summary
from nrobust.roots import spectral_abscissa

SIGMA_PM, SIGMA_MP, Q, R = 1.5, 0.5, 0.8, 0.4
SYSTEM = NPlusMSystem([1.0], [1.0], [[0.0, SIGMA_PM], [SIGMA_MP, 0.0]], [[Q]], [[R]])
#: The design of the tests: the best decay rate with a delay margin of at least 1.2, k in [-0.8, -0.3].
DESIGN = {"margin_at_least": 1.2, "K_bounds": (-0.8, -0.3), "x0": [[-0.5]], "starts": 1}


def _factors(s: mp.mpc, lam: float, mu: float, k: float) -> tuple[mp.mpc, mp.mpc]:
    """``(A(s), B(s))`` of the 1 + 1 loop with speeds ``lam``, ``mu`` and gain ``k``, at 40 digits."""
    with mp.workdps(40):
        return one_plus_one_factors(mp.mpc(s), (lam, mu, SIGMA_PM, SIGMA_MP, Q, R), k)


def _gap(w: mp.mpf, lam: float, mu: float, k: float) -> mp.mpf:
    A, B = _factors(mp.mpc(0, w), lam, mu, k)
    return abs(A) ** 2 - abs(B) ** 2


def _crossings(lam: float, mu: float, k: float, top: float = 40.0, step: float = 0.02) -> list[tuple[float, float]]:
    """Every crossing ``(w, first delay)`` with ``0 < w <= top``: ``|A(i w)| = |B(i w)|`` and ``e^{-i w delta} =
    -A/B``. Beyond ``top`` the principal parts keep ``|A| >= 1 - |r q| - O(1/w)`` above ``|B| <= |k q| + O(1/w)``
    (checked on samples up to 200: at least half the principal parts' gap ``(1 - |r q|)^2 - (k q)^2 > 0``)."""
    with mp.workdps(40):
        for w in range(int(top), 201, 4):
            assert _gap(mp.mpf(w), lam, mu, k) > 0.5 * ((1.0 - abs(R * Q)) ** 2 - (k * Q) ** 2) > 0.0
        n = round(top / step)
        grid = [mp.mpf(step) * j for j in range(1, n + 1)]
        values = [_gap(w, lam, mu, k) for w in grid]
        out = []
        for lo, hi, g_lo, g_hi in zip(grid, grid[1:], values, values[1:]):
            if g_lo * g_hi < 0:
                w = mp.findroot(lambda x: _gap(x, lam, mu, k), (lo, hi), solver="illinois")
                A, B = _factors(mp.mpc(0, w), lam, mu, k)
                out.append((float(w), float(mp.fmod(mp.arg(-B / A) + 2 * mp.pi, 2 * mp.pi) / w)))
        return out


def _zeros_in_box(lam: float, mu: float, k: float, x: float = 4.0, y: float = 40.0) -> int:
    """The zeros of ``F(.; 0) = A + B`` in ``[0, x] x [-y, y]``: the winding number of ``F`` along its boundary,
    steps halved until the argument turns by less than 0.3 between samples. Outside it, in ``Re s >= 0``, ``|F|
    >= 1 - |(r + k) q| - O(1/|s|)`` (the principal part ``1 - (r + k) q e^{-2 s}``): no zero there."""
    corners = [mp.mpc(0, -y), mp.mpc(x, -y), mp.mpc(x, y), mp.mpc(0, y), mp.mpc(0, -y)]

    def F(s: mp.mpc) -> mp.mpc:
        A, B = _factors(s, lam, mu, k)
        return A + B

    turn = mp.mpf(0)
    with mp.workdps(40):
        for z0, z1 in itertools.pairwise(corners):
            t, h, f0 = mp.mpf(0), mp.mpf("0.05") / abs(z1 - z0), F(z0)
            while t < 1:
                step = min(h, 1 - t)
                f1 = F(z0 + (t + step) * (z1 - z0))
                change = mp.arg(f1 / f0)
                if abs(change) > 0.3 and step > 1e-9:
                    h = step / 2
                    continue
                turn += change
                t, f0, h = t + step, f1, min(2 * step, mp.mpf("0.05") / abs(z1 - z0))
        return int(mp.nint(turn / (2 * mp.pi)))


def _first_delay(lam: float, mu: float, k: float) -> float:
    return min((delay for _, delay in _crossings(lam, mu, k)), default=math.inf)


def test_the_box_of_speed_errors_and_its_plants() -> None:
    """The vertices and the other points of the 3-point grid (centre left out) of a 2 + 1 plant; the perturbed
    plant scales each speed by its own factor and keeps the rest."""
    vertices, others = speed_box(3, 0.2)
    assert len(vertices) == 8 and len(others) == 27 - 8 - 1 and (0.0, 0.0, 0.0) not in others
    assert vertices[0] == (-0.2, -0.2, -0.2) and vertices[-1] == (0.2, 0.2, 0.2)
    plant = NPlusMSystem([1.0, 0.5], [1.5], [[0, 0, 0.4], [0, 0, 0.3], [0.5, -0.4, 0]], [[0.6], [0.5]], [[0.5, 0.4]])
    moved = perturbed_system(plant, (0.1, -0.2, 0.3))
    assert list(moved.lam) == [1.1, 0.4] and list(moved.mu) == [1.5 * 1.3]
    assert (moved.sigma == plant.sigma).all() and (moved.q == plant.q).all() and (moved.r == plant.r).all()
    with pytest.raises(ParameterError) as info:
        perturbed_system(plant, (0.1, -1.0, 0.0))
    assert info.value.name == "errors"


def test_the_design_under_a_speed_tolerance_is_stable_at_every_vertex() -> None:
    """The best decay rate with a margin of at least 1.2 sits where the margin is 1.2 (``k = -0.467578``): the
    nominal design is on a speed-sensitive edge, and at the vertex ``(e_lam, e_mu) = (-0.1, 0.1)`` its loop has a
    crossing delay 1.1268 (the oracle), inside ``[0, 1.2]``. With ``speed_tolerance=0.1`` the design moves to
    ``k = -0.441025``: at each of the 4 vertices the oracle finds no zero of ``F(.; 0)`` in ``Re s >= 0`` and no
    crossing delay up to 1.2, so the loop is stable for every delay in ``[0, 1.2]``; the first crossing delay of
    the worst vertex is 1.2000118 (the requirement binds: the local search stops with pattern steps of ``1e-5``
    of the width 0.5, ``5e-6`` in ``k``, and that delay's slope in ``k`` is about 2.9, so within ``1e-4`` of 1.2;
    measured 1.2e-5), and a gain ``1e-3`` lower misses it there (1.19713). The decay rate paid for it: 0.7007
    nominally; under the tolerance 0.5563 on the nominal plant and 0.3487 guaranteed, the least of the nominal
    plant and the vertices (the value; the oracle's rightmost zeros of ``F(.; 0)`` at the 4 vertices and the
    nominal plant agree with the certified abscissae stated one by one to ``1e-10``, measured 1e-15). nrobust's
    certified margin at that vertex agrees with the oracle's crossing delay to ``1e-8`` (measured 2e-16). About
    20 s of CPU time (the designs 1.3 s and 5 s, the oracle's windings the rest)."""
    nominal = design_nplusm_gains(SYSTEM, "decay_rate", **DESIGN)
    assert nominal.certified and nominal.tolerance is None
    assert _first_delay(0.9, 1.1, nominal.K[0][0]) < 1.2 - 0.05
    design = design_nplusm_gains(SYSTEM, "decay_rate", speed_tolerance=0.1, **DESIGN)
    t = design.tolerance
    assert t is not None and design.certified and t.met and t.certified == "certified at the vertices"
    assert design.delays == ((0.0, 1.2),) and design.margin_at_least is None
    assert t.vertices == 4 and t.points[:4] == ((-0.1, -0.1), (-0.1, 0.1), (0.1, -0.1), (0.1, 0.1))
    assert all(w.stable and w.certified for verdicts in t.windows for w in verdicts)
    assert "need not imply it inside the box" in t.statement and "certified" in repr(design)
    k = design.K[0][0]
    first = {}
    for e_lam, e_mu in t.points[:4]:
        assert _zeros_in_box(1.0 + e_lam, 1.0 + e_mu, k) == 0
        first[(e_lam, e_mu)] = _first_delay(1.0 + e_lam, 1.0 + e_mu, k)
    worst = min(first, key=lambda p: first[p])
    assert 1.2 <= first[worst] < 1.2 + 1e-4
    assert _first_delay(1.0 + worst[0], 1.0 + worst[1], k - 1e-3) < 1.2
    dm = nplusm_delay_margin(perturbed_system(SYSTEM, worst), design.K)
    assert dm.certified and abs(dm.margin - first[worst]) < 1e-8
    assert design.value < design.decay_rate < nominal.value
    rates = []
    for (e_lam, e_mu), sa in zip([(0.0, 0.0), *t.points[:4]], (design.abscissa, *design.vertex_abscissae)):
        assert sa.certified and sa.root is not None
        s = _rightmost(1.0 + e_lam, 1.0 + e_mu, k, sa.root)
        assert abs(sa.value - float(s.real)) < 1e-10, (e_lam, e_mu, sa.value, s)
        rates.append(-float(s.real))
    assert design.value == design.worst_decay_rate and abs(design.value - min(rates)) <= design.accuracy + 1e-10
    assert design.accuracy < 1e-9 and min(rates) < design.decay_rate - 0.1
    assert "decay_rate (least of the nominal plant and the vertices)" in design_summary(design)
    lines = _nplusm_markdown(Path("plant.toml"), design)
    for (a, b), rate in zip(t.points[:4], rates[1:]):
        (line,) = [x for x in lines if x.startswith(f"  - decay rate at delta = 0 at the vertex ({a!r}, {b!r}): ")]
        printed, bound = line.split(": ")[1].split(" (")[0].split(" +- ")
        assert abs(float(printed) - rate) <= 1.5 * float(bound), (line, rate)
    data = design.to_dict()
    assert data["worst_decay_rate"] == design.value and len(data["vertex_abscissae"]) == 4
    json.dumps(data, allow_nan=False)


def test_an_infeasible_tolerance_is_a_certification_error_with_advice() -> None:
    """With ``speed_tolerance=0.3`` the design finds no gain of ``[-0.8, -0.3]`` keeping the margin 1.2 at every
    vertex (its first phase raises the worst window margin to 1.025 only) and says what would help. The oracle:
    at 6 gains spread over the bounds a vertex misses the requirement, by a crossing delay below 1.2 (every
    ``k <= -0.4``: at ``(-0.3, 0.3)`` from 0.38 to 1.178) or by a zero in ``Re s > 0`` at ``delta = 0`` (``k =
    -0.3``, at ``(-0.3, -0.3)``; its vertex ``(-0.3, 0.3)`` has its first crossing delay at 1.548). About 7 s of
    CPU time (the design 1.8 s)."""
    with pytest.raises(CertificationError, match="lower speed_tolerance"):
        design_nplusm_gains(SYSTEM, "decay_rate", speed_tolerance=0.3, **DESIGN)
    vertices = speed_box(2, 0.3)[0]
    for j in range(6):
        k = -0.8 + 0.1 * j
        plants = [(1.0 + a, 1.0 + b) for a, b in vertices]
        assert any(_first_delay(lam, mu, k) < 1.2 for lam, mu in plants) or any(
            _zeros_in_box(lam, mu, k) > 0 for lam, mu in plants
        )
    assert _zeros_in_box(0.7, 0.7, -0.3) == 1 and _first_delay(0.7, 1.3, -0.3) > 1.2


def test_a_gain_checked_on_the_box() -> None:
    """``nplusm_speed_tolerance`` on the nominal design's gain: not met, the vertex ``(-0.1, 0.1)`` among the
    points refuted (its crossing delay 1.1268, the oracle of the test above)."""
    tol = nplusm_speed_tolerance(SYSTEM, [[-0.467578125]], 0.1, (0.0, 1.2))
    assert not tol.met and tol.certified == "not met" and len(tol.points) == 8
    assert "(-0.1, 0.1)" in tol.statement and "not met" in repr(tol)


class _NoWork(Exception):
    pass


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"speed_tolerance": -0.1, "margin_at_least": 1.0}, "speed_tolerance"),
        ({"speed_tolerance": 0.0, "margin_at_least": 1.0}, "speed_tolerance"),
        ({"speed_tolerance": 1.0, "margin_at_least": 1.0}, "speed_tolerance"),
        ({"speed_tolerance": math.nan, "margin_at_least": 1.0}, "speed_tolerance"),
        ({"speed_tolerance": "0.1", "margin_at_least": 1.0}, "speed_tolerance"),
        ({"speed_tolerance": 0.1}, "speed_tolerance"),  # no delay requirement
    ],
)
def test_bad_tolerance_is_refused_before_any_work(kwargs: dict, name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    import nrobust.hyperbolic.nplusm.design as design

    def no_work(*args: object, **kw: object) -> None:
        raise _NoWork

    monkeypatch.setattr(design, "local_runs", no_work)
    with pytest.raises(ParameterError) as info:
        design_nplusm_gains(SYSTEM, **kwargs)
    assert info.value.name == name


def test_too_many_vertices_are_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    """A 3 + 2 plant has 32 vertices, above ``MAX_SPEED_CORNERS = 16``: refused naming ``speed_tolerance``."""
    import nrobust.hyperbolic.nplusm.design as design

    monkeypatch.setattr(design, "local_runs", lambda *a, **k: (_ for _ in ()).throw(_NoWork()))
    big = NPlusMSystem([1.0, 2.0, 3.0], [1.0, 2.0], [[0.0] * 5] * 5, [[0.5, 0.0]] * 3, [[0.1, 0.0, 0.0]] * 2)
    assert 2**5 > MAX_SPEED_CORNERS
    with pytest.raises(ParameterError, match="MAX_SPEED_CORNERS") as info:
        design_nplusm_gains(big, margin_at_least=1.0, speed_tolerance=0.1, K_bounds=(-0.1, 0.1))
    assert info.value.name == "speed_tolerance"
    with pytest.raises(ParameterError) as info:
        nplusm_speed_tolerance(SYSTEM, [[-0.4]], 1.5, (0.0, 1.0))
    assert info.value.name == "eps"
    with pytest.raises(ParameterError) as info:
        nplusm_speed_tolerance(SYSTEM, [[-0.4]], 0.1, None)
    assert info.value.name == "delays"


TOML = """
[system]
type = "NPlusMSystem"
lam = [1.0]
mu = [1.0]
sigma = [[0.0, 1.5], [0.5, 0.0]]
q = [[0.8]]
r = [[0.4]]

[controller]
type = "Cancellation"
fractions = [[0.0]]

[analysis]
region = [-3.0, 1.0, 0.0, 40.0]

[design]
family = "nplusm"
objective = "decay_rate"
margin_at_least = 1.2
speed_tolerance = 0.1
K_bounds = [-0.8, -0.3]
x0 = [[-0.5]]
starts = 1
"""


def test_the_command_takes_the_tolerance(tmp_path: Path) -> None:
    """``nrobust design`` on an ``NPlusMSystem`` file with ``speed_tolerance``: the design of the test above
    (the same gain), the report stating what is certified and what only checked. About 3 s of CPU time."""
    system = tmp_path / "SYSTEM.toml"
    system.write_text(TOML)
    out = tmp_path / "out"
    assert main(["design", str(system), "-o", str(out)]) == 0
    data = json.loads((out / "design.json").read_text())
    text = (out / "design.md").read_text()
    assert data["speed_tolerance"] == 0.1 and data["certified"]
    assert data["tolerance"]["certified"] == "certified at the vertices" and data["tolerance"]["vertices"] == 4
    assert abs(data["K"][0][0] - (-0.441025)) < 1e-5
    assert "- speed tolerance 0.1 on every speed: met at the 8 points examined, certified at the vertices" in text
    assert "between the points not certified" in text


#: A 3 + 2 plant: its box of speed errors has 32 vertices.
BIG = """
[system]
type = "NPlusMSystem"
lam = [1.0, 2.0, 3.0]
mu = [1.0, 2.0]
sigma = [[0.0, 0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0, 0.0],
         [0.0, 0.0, 0.0, 0.0, 0.0]]
q = [[0.5, 0.0], [0.5, 0.0], [0.5, 0.0]]
r = [[0.1, 0.0, 0.0], [0.1, 0.0, 0.0]]

[controller]
type = "Cancellation"
fractions = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]

[analysis]
region = [-3.0, 1.0, 0.0, 40.0]

[design]
family = "nplusm"
margin_at_least = 1.2
speed_tolerance = 0.1
"""


@pytest.mark.parametrize(
    ("toml", "message"),
    [
        (TOML.replace("speed_tolerance = 0.1", "speed_tolerance = 1.5"), "in \\(0, 1\\)"),
        (TOML.replace("margin_at_least = 1.2\n", ""), "delay requirement"),
        (BIG, "MAX_SPEED_CORNERS"),
    ],
)
def test_the_file_tolerance_is_checked(tmp_path: Path, toml: str, message: str) -> None:
    """``[design] speed_tolerance`` outside ``(0, 1)``, without a delay requirement, or with more vertices than
    ``MAX_SPEED_CORNERS``: a ParameterError naming it when the file is read."""
    system = tmp_path / "SYSTEM.toml"
    system.write_text(toml)
    with pytest.raises(ParameterError, match=message) as info:
        load_system_file(system)
    assert info.value.name == "design.speed_tolerance"


def _margins(k: float, eps: float) -> list[float]:
    """The first crossing delays of the nominal plant and of the vertices of the box (the oracle), in that order."""
    return [_first_delay(1.0 + a, 1.0 + b, k) for a, b in [(0.0, 0.0), *speed_box(2, eps)[0]]]


def test_the_margin_objective_under_a_tolerance_is_the_least_of_nominal_and_vertices() -> None:
    """What the optimiser sees: at ``k = -0.5`` the problem's margin objective is minus the least first crossing delay
    of the nominal plant and the 4 vertices (the oracle: 1.0460 at the vertex ``(-0.1, 0.1)``, the nominal 1.1140;
    the certified margins agree to ``1e-10``), feasible on the window ``[0, 1.0]``, and its gradient is the slope of
    that least delay in ``k`` (the oracle's central difference with ``h = 1e-4``: error ``O(h^2)``, about ``1e-8``
    times the second derivative, measured 6e-8 on a slope of 2.36; tolerance 1e-5). About 5 s of CPU time."""
    vertices = speed_box(2, 0.1)[0]
    problem = NPlusMGainProblem(
        SYSTEM,
        np.array([[-0.8, -0.3]]),
        "margin",
        1.0,
        windows=((0.0, 1.0),),
        scenarios=tuple(perturbed_system(SYSTEM, e) for e in vertices),
    )
    point = problem(np.array([-0.5]))
    truth = _margins(-0.5, 0.1)
    assert point.feasible and min(truth) < truth[0] - 0.05
    assert abs(-point.value - min(truth)) < 1e-10
    h = 1e-4
    slope = (min(_margins(-0.5 + h, 0.1)) - min(_margins(-0.5 - h, 0.1))) / (2 * h)
    assert abs(-float(point.gradient[0]) - slope) < 1e-5, (point.gradient, slope)


def test_the_most_robust_gain_under_a_tolerance_beats_a_grid_of_gains() -> None:
    """``design_nplusm_gains(..., "margin", speed_tolerance=0.1)`` on ``k`` in ``[-0.8, -0.3]`` with the window
    ``[0, 1.2]``: its value is the least certified margin of the nominal plant and the 4 vertices (the oracle's
    least first crossing delay within the design's accuracy; the nominal margin, larger, stated in ``margin``), and
    it matches or beats the best worst-vertex margin over 11 gains of the bounds (certified margins, each gain
    meeting the window at every vertex; the worst-vertex margin rises with ``k`` to 1.74888 at ``k = -0.3``, the
    bound, where the design ends). About 6 s of CPU time."""
    design = design_nplusm_gains(
        SYSTEM, "margin", delays=(0.0, 1.2), speed_tolerance=0.1, K_bounds=(-0.8, -0.3), x0=[[-0.5]], starts=1
    )
    assert design.certified and design.margin is not None and len(design.vertex_margins) == 4
    k = design.K[0][0]
    truth = _margins(k, 0.1)
    assert design.value == design.worst_margin and abs(design.value - min(truth)) <= design.accuracy < 1e-9
    assert abs(design.margin.margin - truth[0]) <= design.margin.accuracy and design.margin.margin > design.value + 0.05
    for vm, t in zip(design.vertex_margins, truth[1:]):
        assert vm.certified and abs(vm.margin - t) <= vm.accuracy
    plants = [SYSTEM, *(perturbed_system(SYSTEM, e) for e in speed_box(2, 0.1)[0])]
    best = -math.inf
    for g in np.linspace(-0.8, -0.3, 11):
        margins = [nplusm_delay_margin(p, [[g]]) for p in plants]
        assert all(m.certified and m.nominal_unstable == 0 for m in margins)
        worst = min(m.margin for m in margins)
        if worst >= 1.2:
            best = max(best, worst)
    assert best > 1.2 and design.value >= best - design.accuracy, (design.value, best)
    assert "least of the nominal plant and the vertices" in design_summary(design)
    assert f"value={with_accuracy(design.value, design.accuracy)}" in repr(design)
    lines = _nplusm_markdown(Path("plant.toml"), design)
    assert design.tolerance is not None
    for (a, b), t in zip(design.tolerance.points, truth[1:]):
        (line,) = [x for x in lines if x.startswith(f"  - delay margin at the vertex ({a!r}, {b!r}): ")]
        printed, bound = line.split(": ")[1].split(" +- ")
        assert abs(float(printed) - t) <= 1.5 * float(bound), (line, t)


def _rate_loop(lam: float, mu: float, k: float) -> Callable[[mp.mpc], mp.mpc]:
    """The delay-free loop ``F(s; 0) = A(s) + B(s)`` of the oracle, at 40 digits."""

    def F(s: mp.mpc) -> mp.mpc:
        A, B = _factors(s, lam, mu, k)
        return A + B

    return F


def _rightmost(lam: float, mu: float, k: float, seed: complex) -> mp.mpc:
    """The rightmost zero of ``F(.; 0)`` (the oracle at 40 digits): Newton's method (mpmath's ``findroot``) from
    ``seed``, then the winding number of ``F`` about ``[Re s - 0.15, 4] x [-60, 60]`` is 1 for a real zero, 2 for
    a complex one (with its conjugate): no other zero there. Outside the box, in ``Re s >= Re s - 0.15``, the
    principal part ``1 - (r + k) q e^{-tau s}`` (``tau = 1/lam + 1/mu``) keeps ``|F|`` above half its gap (checked
    on samples up to 400)."""
    F = _rate_loop(lam, mu, k)
    with mp.workdps(40):
        s = mp.findroot(F, mp.mpc(seed))
        x0 = float(s.real) - 0.15
        _far_field(F, lam, mu, k, x0)
        real = abs(s.imag) < mp.mpf("1e-30")  # a real zero (Newton's rounding left on its imaginary part)
        assert winding_number(F, (x0, 4.0, -60.0, 60.0), n=1200) == (1 if real else 2)
        return s


def _far_field(F: Callable[[mp.mpc], mp.mpc], lam: float, mu: float, k: float, x0: float) -> None:
    """``|F| > (1 - |(r + k) q| e^{-tau x0}) / 2 > 0`` on samples of ``Re s in [x0, 4]``, ``60 <= Im s <= 400``."""
    gap = 1.0 - abs((R + k) * Q) * math.exp(-(1.0 / lam + 1.0 / mu) * x0)
    assert gap > 0.0
    with mp.workdps(40):
        for y in range(60, 401, 5):
            for x in np.linspace(x0, 4.0, 6):
                assert abs(F(mp.mpc(x, y))) > 0.5 * gap, (x, y)


def _none_right_of(lam: float, mu: float, k: float, x0: float) -> None:
    """No zero of ``F(.; 0)`` in ``Re s >= x0`` (the oracle: the winding number about ``[x0, 4] x [-60, 60]`` is 0,
    the far field as in :func:`_rightmost`)."""
    F = _rate_loop(lam, mu, k)
    _far_field(F, lam, mu, k, x0)
    assert winding_number(F, (x0, 4.0, -60.0, 60.0), n=1200) == 0


#: The rate designs below: a delay margin of at least 0.9 at every vertex of the box of speed errors 0.1.
RATE_EPS, RATE_MARGIN = 0.1, 0.9


def test_the_decay_rate_objective_under_a_tolerance_is_the_least_of_nominal_and_vertices() -> None:
    """What the optimiser sees: at ``k = -0.52`` the problem's decay-rate objective is the largest spectral abscissa of
    the delay-free loops of the nominal plant and the 4 vertices, that of the vertex ``(-0.1, -0.1)`` (the oracle's
    rightmost zero ``-0.7924 + i y``; the nominal plant's rate is 1.168, larger by 0.38, and no zero of the other
    plants lies right of ``Re s = -0.7924 + 0.05``), feasible on the window ``[0, 0.9]``, and its gradient is the
    slope of that zero's real part in ``k`` (the oracle: ``ds/dk = -F_k / F_s`` at 40 digits, ``F_k = B / k``,
    ``F_s`` by a central difference of step ``1e-15``, error ``O(1e-30)``). The value and the gradient come from
    floating point (the rightmost root, Jacobi's formula): measured errors 1e-15 and 2e-14 on a slope of 11.4;
    tolerances 1e-10 and 1e-7. About 9 s of CPU time, most of it the oracle's windings."""
    k = -0.52
    vertices = speed_box(2, RATE_EPS)[0]
    problem = NPlusMGainProblem(
        SYSTEM,
        np.array([[-0.8, -0.3]]),
        "decay_rate",
        RATE_MARGIN,
        windows=((0.0, RATE_MARGIN),),
        scenarios=tuple(perturbed_system(SYSTEM, e) for e in vertices),
    )
    point = problem(np.array([k]))
    assert point.feasible
    j, worst = problem.worst_abscissa(np.array([[k]]))
    assert j == 1 and worst.root is not None
    lam, mu = 1.0 + vertices[0][0], 1.0 + vertices[0][1]
    s = _rightmost(lam, mu, k, worst.root)
    assert abs(point.value - float(s.real)) < 1e-10, (point.value, s)
    nominal = problem.abscissa(np.array([[k]]))
    assert nominal.value < point.value - 0.3
    for a, b in [(0.0, 0.0), *vertices[1:]]:
        _none_right_of(1.0 + a, 1.0 + b, k, float(s.real) + 0.05)
    F = _rate_loop(lam, mu, k)
    with mp.workdps(40):
        h = mp.mpf("1e-15")
        slope = -(_factors(s, lam, mu, k)[1] / k) / ((F(s + h) - F(s - h)) / (2 * h))
    assert abs(float(point.gradient[0]) - float(slope.real)) < 1e-7, (point.gradient, slope)


@pytest.mark.long  # about a minute: five certified abscissae per evaluation, at a kink of the least rate (make fuzz)
def test_the_best_guaranteed_decay_rate_under_a_tolerance_beats_a_grid_of_gains() -> None:
    """``design_nplusm_gains(..., "decay_rate", margin_at_least=0.9, speed_tolerance=0.1)`` on ``k`` in ``[-0.56,
    -0.5]``: its value is the least decay rate of the nominal plant and the 4 vertices (the certified abscissae of
    the plants built here with the perturbed speeds, within the design's accuracy), and it matches or beats the best
    least rate over 13 gains of the bounds (certified abscissae and margins, each gain with a margin of at least 0.9
    at every vertex). The least rate peaks at a kink, ``k = -0.53248``, where two zeros of the vertex ``(-0.1,
    -0.1)`` tie: 1.00415 there, against 0.9960 at the best gain of the grid, ``-0.535``; the nominal rate's
    maximiser, ``k = -0.5108`` (rate 1.206), guarantees only about 0.70. About 65 s of CPU time."""
    design = design_nplusm_gains(
        SYSTEM,
        "decay_rate",
        margin_at_least=RATE_MARGIN,
        speed_tolerance=RATE_EPS,
        K_bounds=(-0.56, -0.5),
        x0=[[-0.54]],
        starts=1,
    )
    assert design.certified and len(design.vertex_abscissae) == 4
    sigma = [[0.0, SIGMA_PM], [SIGMA_MP, 0.0]]
    corners = [(0.0, 0.0), *speed_box(2, RATE_EPS)[0]]
    plants = [NPlusMSystem([1.0 + a], [1.0 + b], sigma, [[Q]], [[R]]) for a, b in corners]
    k = design.K[0][0]
    rates = [-spectral_abscissa(NPlusMCharacteristic(p, [[k]], 0.0)).value for p in plants]
    assert abs(design.value - min(rates)) <= design.accuracy < 1e-9, (design.value, rates)
    assert min(rates) < design.decay_rate - 0.1
    best = -math.inf
    for g in np.linspace(-0.56, -0.5, 13):
        margins = [nplusm_delay_margin(p, [[g]]) for p in plants]
        assert all(m.certified and m.nominal_unstable == 0 for m in margins)
        if min(m.margin for m in margins) >= RATE_MARGIN:
            abscissae = [spectral_abscissa(NPlusMCharacteristic(p, [[g]], 0.0)) for p in plants]
            assert all(a.certified for a in abscissae)
            best = max(best, min(-a.value for a in abscissae))
    assert best > 0.9 and design.value >= best - design.accuracy, (design.value, best)
