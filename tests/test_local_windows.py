"""Several windows of delays, and a margin with windows, in one local design (``optimize_loop``).

Oracles, sharing no code with the optimiser:

* the first-order loop ``s + 1 + k e^{-delta s}``: for ``k > 1`` its delay margin is
  ``arccos(-1/k) / sqrt(k^2 - 1)`` in closed form, and it is stable exactly for the delays below it
  (one crossing frequency ``w^2 = k^2 - 1``, a simple root of ``P(u) = u - (k^2 - 1)`` with ``P' > 0``:
  every crossing is to the right, Cooke and van den Driessche, Funkcial. Ekvac. 29, 1986). So stability
  on ``[0, d]`` and on windows ``[a_j, b_j]`` is ``margin(k) > max(d, b_j)``, the margin decreases in
  ``k``, and the best decay rate ``1 + k`` under them is ``1 + k*(D)``, ``k*(D)`` the root of
  ``margin(k) = D`` (scipy's brentq);
* the delayed oscillator ``s^2 + c s + 1 + K (1 + BETA s) e^{-delta s}``: its crossing delays in closed
  form (``|A(i w)| = |B(i w)|`` is a quadratic in ``w^2``), its count of zeros in ``Re s > 0`` at any delay
  from the count at ``delta = 0`` and the crossing directions (the sign of ``P'`` at the root), and its
  decay rate ``(c + BETA K)/2`` (complex roots on the bounds).

The optimiser stops when the pattern search's step is ``POLISH_TOL = 1e-5`` of the bounds' width: on
``k in [0, 5]`` a design is within about ``5e-5`` of the optimum in ``k``, so ``1 + k`` is compared to
``1e-4``.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest
from _design_loops import BETA, K_BOUNDS, OSC_BOUNDS, RATE_TOL, best_k, first_order, late, margin, oscillator

from nrobust.design import optimize_loop
from nrobust.design.local import check_windows
from nrobust.errors import ParameterError


def _branches(c: float, K: float) -> list[tuple[float, float, int]]:
    """``(w, theta, direction)`` of each crossing frequency of the oscillator.

    ``|1 - w^2 + i c w|^2 = K^2 |1 + i BETA w|^2`` is ``P(u) = u^2 + (c^2 - 2 - K^2 BETA^2) u + 1 - K^2 = 0``
    in ``u = w^2``; at a positive root ``e^{-i w delta} = -A/B``, the delays ``(theta + 2 pi k)/w`` with
    ``theta = arg(-B/A) mod 2 pi``; a pair crosses to the right where ``P'(u) > 0``, to the left otherwise.
    """
    out = []
    for u in np.roots([1.0, c * c - 2.0 - K * K * BETA * BETA, 1.0 - K * K]):
        if abs(u.imag) > 1e-12 or u.real <= 0.0:
            continue
        w = math.sqrt(u.real)
        theta = float(np.mod(np.angle(-K * (1 + 1j * BETA * w) / (1 - w * w + 1j * c * w)), 2 * np.pi))
        out.append((w, theta, 1 if 2.0 * u.real + c * c - 2.0 - K * K * BETA * BETA > 0.0 else -1))
    return out


def crossing_delays(c: float, K: float, up_to: float) -> list[float]:
    """Every delay up to ``up_to`` at which the oscillator has a zero ``i w``."""
    delays = [
        (theta + 2 * np.pi * k) / w for w, theta, _ in _branches(c, K) for k in range(int(up_to * w / (2 * np.pi)) + 2)
    ]
    return sorted(d for d in delays if d <= up_to)


def unstable_count(c: float, K: float, delta: float) -> int:
    """Zeros of the oscillator in ``Re s > 0`` at ``delta`` (not a crossing delay): 0 or 2 at ``delta = 0`` by
    the sign of ``c + BETA K``, then 2 more (or fewer) at each crossing delay below ``delta``."""
    count = 0 if c + BETA * K > 0.0 else 2
    for w, theta, direction in _branches(c, K):
        passed = sum(1 for k in range(int(delta * w / (2 * np.pi)) + 2) if (theta + 2 * np.pi * k) / w < delta)
        count += 2 * direction * passed
    return count


def stable_on(c: float, K: float, window: tuple[float, float]) -> bool:
    """Stable for every delay of the closed window: no zero right at its start, no crossing delay in it."""
    lo, hi = window
    return unstable_count(c, K, lo) == 0 and not any(lo <= d <= hi for d in crossing_delays(c, K, hi + 1.0))


@pytest.mark.parametrize(
    ("margin_at_least", "delays", "scenarios", "need"),
    [
        (0.5, None, (), 0.5),  # a margin alone, as before
        (1.2, (0.5, 0.7), (), 1.2),  # a margin and a window: the margin binds
        (None, [(0.2, 0.3), (0.9, 0.9)], (), 0.9),  # two windows, one a single delay
        (0.3, (0.5, 0.7), (late,), 0.8),  # the window binds, on a scenario 0.1 later held to both: 0.8
    ],
)
def test_every_requirement_at_once_on_the_first_order_loop(
    margin_at_least: float | None, delays: Any, scenarios: tuple, need: float
) -> None:
    """The best decay rate is ``1 + k*(D)`` with ``D`` the largest delay required of the loop (closed form)."""
    design = optimize_loop(
        first_order, K_BOUNDS, margin_at_least=margin_at_least, delays=delays, scenarios=scenarios, x0=[0.5]
    )
    assert design.certified
    np.testing.assert_allclose(design.value, 1.0 + best_k(need), atol=RATE_TOL)
    (k,) = design.parameters
    assert margin(k) > need  # the closed form: every requirement met
    windows = check_windows(delays)
    assert design.required_windows == windows
    assert design.delays == (windows[0] if len(windows) == 1 else windows or None)
    # the record: the loop's window certificates, then each scenario's [0, d] and windows
    loop, *others = design.loop_windows
    assert [w.delays for w in loop] == list(windows) and all(w.stable for w in loop)
    for certs in others:
        assert [w.delays for w in certs] == [(0.0, margin_at_least), *windows] and all(w.stable for w in certs)
        assert margin_at_least is not None and certs[0].margin.margin > margin_at_least and certs[0].margin.verified
    if scenarios:
        assert margin(k) - 0.1 > 0.7  # the scenario is the loop 0.1 later: its margin is margin(k) - 0.1
    text = design.requirement
    if margin_at_least is not None:
        who = "the loop" if not scenarios else "the loop and its 1 scenarios"
        assert f"delay margin >= {margin_at_least!r} ({who}): met, checked" in text
    for lo, hi in windows:
        assert f"stable for every delay in [{lo!r}, {hi!r}]" in text
    assert "not met" not in text
    json.dumps(design.to_dict(), allow_nan=False)


def test_two_windows_from_a_start_unstable_for_every_delay() -> None:
    """The oscillator on ``[0.5, 0.65]`` and ``[4.7, 4.85]``, from ``(-0.2, 0.05)``, unstable for every delay.

    The phase before the first lowers the abscissae at both windows' starts; the design is then stable on
    both and unstable between them (closed-form count). The first window binds: a crossing delay within
    1e-3 of its end (a pattern step of 9e-6 in K moves it by about 1e-4), and the rate is below the best of
    the second window alone on a grid of the closed form (0.1825 at c = 0.2, K = 0.55).
    """
    windows = [(0.5, 0.65), (4.7, 4.85)]
    c0, K0 = -0.2, 0.05
    assert unstable_count(c0, K0, 0.5) == 2 and not crossing_delays(c0, K0, 11.0)
    design = optimize_loop(oscillator, OSC_BOUNDS, delays=windows, x0=[c0, K0])
    assert design.certified and len(design.windows) == 2 and all(w.stable for w in design.windows)
    c, K = design.parameters
    assert all(stable_on(c, K, w) for w in windows)
    delays = crossing_delays(c, K, 11.0)
    between = [d for d in delays if 0.65 < d < 4.7]
    assert between and unstable_count(c, K, between[0] + 1e-3) > 0  # unstable between the windows
    assert min(abs(d - 0.65) for d in delays) < 1e-3
    np.testing.assert_allclose(design.decay_rate, (c + BETA * K) / 2.0, rtol=1e-9)
    # no grid point stable on both windows beats the design (to the pattern search's last step, 1e-5 of rate)
    grid = [(cg, Kg) for cg in np.linspace(-0.2, 0.2, 9) for Kg in np.linspace(0.05, 0.9, 35)]
    both = max((cg + BETA * Kg) / 2.0 for cg, Kg in grid if all(stable_on(cg, Kg, w) for w in windows))
    second = max((cg + BETA * Kg) / 2.0 for cg, Kg in grid if stable_on(cg, Kg, windows[1]))
    assert design.value >= both - 1e-5 and design.value < second - 1e-3
    assert "[0.5, 0.65] (the loop): met" in design.requirement
    assert "[4.7, 4.85] (the loop): met" in design.requirement


def test_bad_requirements_are_named() -> None:
    with pytest.raises(ParameterError, match="delays"):
        optimize_loop(first_order, K_BOUNDS, scenarios=[late])  # a scenario needs a requirement
    with pytest.raises(ParameterError, match="delays"):
        optimize_loop(first_order, K_BOUNDS, margin_at_least=0.0, scenarios=[late])
    with pytest.raises(ParameterError, match=r"delays\[1\]"):
        optimize_loop(first_order, K_BOUNDS, delays=[(0.5, 0.7), (0.9, 0.8)])
    with pytest.raises(ParameterError, match="delays"):
        optimize_loop(first_order, K_BOUNDS, delays=[])
    with pytest.raises(ParameterError, match="margin_at_least"):
        optimize_loop(first_order, K_BOUNDS, margin_at_least=0.3, delays=(0.5, 0.7), objective="margin")
    assert check_windows(None) == () and check_windows((0.5, 0.7)) == ((0.5, 0.7),)
    assert check_windows([(0.5, 0.7), (0.9, 0.9)]) == ((0.5, 0.7), (0.9, 0.9))
