"""State-space time-delay systems: nrobust's certified spectrum vs tdcpy (same process).

tdcpy (the Python port of TDS-CONTROL, Michiels and Appeltans) computes the roots of
``det(s E - sum_k A_k e^{-h_k s} + s sum_k H_k e^{-hH_k s})`` in a rectangle, or right of a
line ``Re s >= r``, by a spectral discretisation of the infinitesimal generator with Newton
corrections (not certified). nrobust takes the same system as a
:class:`~nrobust.lti.statespace.StateSpaceTDS`, never expands the determinant and certifies the
count of the rectangle and a box per root.

Systems (tdcpy's ``NDDE`` writes ``x' + sum H x'(t - hH) = ...``, so ``B = -H``):

* tdcpy's own published examples, matrices exactly as in its repository
  (https://github.com/LockeErasmus/tdcpy) from the TDS-CONTROL manual (Appeltans and
  Michiels, arXiv:2305.00341, 2023): Example 2.1 (Verheyden,
  Luzyanina, Roose 2008, Section 6.1; ``examples/09_tds_control_manual/example_2_01.py``),
  Example 2.6 with ``tau2 = 2, 2.05`` (``example_2_06.py``), the descriptor closed loop of
  Example 2.9 (``examples/example2_9.py``, stated abscissa -0.2845), the Smith predictor
  quasi-polynomial of Example 2.12 at ``tau = 1``, ``delta = 0.5`` (``example_2_12.py``),
  Michiels' (2011) descriptor Example 13 with ``a = 0.75``
  (``examples/03_stabopt/example_strong_sa.py``)
  and manual Example 3.1, a 5-state plant with 6 delays up to 40 closed by the static
  feedback of that example (``examples/example3_1.py``), with tdcpy's ``r = -0.2``;
* three systems written here: a retarded 2x2 system with one delay, the same with a
  neutral term, and a 3x3 retarded system with two incommensurate delays.

Printed per system: roots found by each (nrobust's count is certified; a larger tdcpy
count reports a root twice), the largest distance from a tdcpy root to the nearest nrobust
root, the rightmost real part of each and the published value when one is stated, then the
wall-clock and CPU (``time.process_time``) milliseconds of each (best of 7; 1 for Example 3.1;
nrobust on a fresh copy of the system each time, so that nothing an earlier call kept is reused)
and their ratios nrobust / tdcpy. nrobust limits BLAS to one thread itself; tdcpy is timed
both with its default BLAS threads and with one thread (threadpoolctl), and its better figure
of the two is kept (its best setting: on a shared machine the threads often lose). The load
average (``os.getloadavg``) is printed before and after: CPU time is the steadier figure on a
loaded machine.

Run: ``python benchmarks/statespace.py`` (needs ``pip install tdcpy``, GPL-3.0).
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from nrobust.lti.statespace import StateSpaceTDS

REGION = (-3.0, 1.0, -30.0, 30.0)
A0 = np.array([[-1.0, 0.5], [0.3, -2.0]])
A1 = np.array([[-0.8, 0.2], [0.1, -0.5]])
H = np.array([[0.3, 0.1], [0.0, -0.4]])
C0 = np.array([[-2.0, 0.4, 0.0], [0.1, -1.0, 0.3], [0.0, 0.2, -1.5]])
C1 = np.array([[-0.3, 0.0, 0.2], [0.0, -0.6, 0.0], [0.4, 0.0, -0.2]])
C2 = np.array([[0.0, 0.5, 0.0], [-0.2, 0.0, 0.0], [0.0, 0.0, -0.4]])


@dataclass(frozen=True)
class Case:
    """One comparison: the system, tdcpy's class for it, where to look, the stated abscissa."""

    name: str
    system: StateSpaceTDS
    kind: str  # "RDDE", "NDDE" or "DDAE"
    where: tuple[float, ...] | float  # a rectangle, or tdcpy's r (all roots with Re s >= r)
    published: float | None = None
    repeat: int = 7


def ex29() -> StateSpaceTDS:
    """TDS-CONTROL manual Example 2.9 closed loop, as tdcpy examples/example2_9.py builds it."""
    m0, m1 = np.zeros((6, 6)), np.zeros((6, 6))
    m0[:2, :2], m0[2, :2], m0[2, 2] = [[0.2, 0.1], [-0.5, 1.0]], [1.0, 1.0], -1.0
    m0[3, 2], m0[3, 3] = 3.1, -3.48
    m0[4:, 2], m0[4:, 3], m0[4:, 4:] = [-1.86, -1.4], [1.79, -0.09], -np.eye(2)
    m1[:2, :2], m1[:2, 4:], m1[2, 4:] = [[0.5, 0.3], [0.1, -0.1]], np.eye(2), [0.01, 0.01]
    return StateSpaceTDS([m0, m1], [0.0, 1.0], E=np.diag([1.0, 1.0, 0.0, 1.0, 0.0, 0.0]))


def ex31() -> StateSpaceTDS:
    """TDS-CONTROL manual Example 3.1 with its static feedback, as tdcpy examples/example3_1.py writes it."""
    Th, Ta, Td, Tc = 14.0, 3.0, 3.0, 25.0
    Kb, Ka, Kd, Kc, Ku = 0.24, 1.0, 0.94, 0.81, 0.39
    a = np.zeros((8, 5, 5))
    a[0][1, 0], a[0][1, 1], a[0][2, 2], a[0][4, 3] = Ka / Ta, (-Ka - 1) / Ta, -1 / Td, -1.0
    a[1][0, 0], a[2][0, 1], a[3][1, 3] = -1 / Th, Kb / Th, 1 / Ta
    a[4][2, 1], a[5][3, 2], a[6][3, 3] = Kd / Td, Kc / Tc, -1 / Tc
    a[7][0] = Ku / Th * np.array([-0.1659, -0.2968, -0.3612, -0.3629, 0.0168])  # u(t - 13.2) = K x(t - 13.2)
    return StateSpaceTDS(a, [0.0, 6.5, 40.0, 13.0, 18.0, 2.8, 9.2, 13.2])


def ex13() -> StateSpaceTDS:
    """Michiels (2011) Example 13, a = 0.75, as tdcpy examples/03_stabopt/example_strong_sa.py writes it."""
    a = [[[0.0, -0.125], [-1.0, 1.0]], [[0.0, 0.0], [0.0, -0.75]], [[0.0, 0.0], [0.0, 0.5]]]
    return StateSpaceTDS(a, [0.0, 1.0, 2.0], E=[[1.0, 0.0], [0.0, 0.0]])


EX21 = [
    np.array([[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, -10, -4], [0, 0, 4, -10]], dtype=float),
    np.array([[3, 3, 3, 3], [0, -1.5, 0, 0], [0, 0, 3, -5], [0, 5, 5, 5]], dtype=float),
]


def ex26(tau2: float) -> StateSpaceTDS:
    """TDS-CONTROL manual Example 2.6: x' = x/4 - x(t-1)/3 + 3/4 x'(t-1) - 1/2 x'(t-tau2)."""
    return StateSpaceTDS([[[0.25]], [[-1.0 / 3.0]]], [0.0, 1.0], B=[[[0.75]], [[-0.5]]], hB=[1.0, tau2])


CASES = [
    # rightmost root as stated in tdcpy tests/stability/test_rightmost_root.py
    Case("manual 2.1 (4x4, r = -2.5)", StateSpaceTDS(EX21, [0.0, 1.0]), "RDDE", -2.5, 0.6176424667764324),
    Case("manual 2.6, tau2 = 2", ex26(2.0), "NDDE", (-0.9, 0.2, -60.0, 60.0)),
    Case("manual 2.6, tau2 = 2.05", ex26(2.05), "NDDE", (-0.9, 0.2, -60.0, 60.0)),
    Case("manual 2.9 (descriptor, n = 6)", ex29(), "DDAE", (-1.0, 0.5, -10.0, 10.0), -0.2845),
    # manual 2.12: D_cl(s) = 3/2 s + 3 + (s/2 + 2) e^{-s} - (s/2 + 2) e^{-1.5 s}, divided by 3/2
    Case(
        "manual 2.12 (Smith predictor)",
        StateSpaceTDS([[[-2.0]], [[-4 / 3]], [[4 / 3]]], [0.0, 1.0, 1.5], B=[[[-1 / 3]], [[1 / 3]]], hB=[1.0, 1.5]),
        "NDDE",
        (-3.0, 1.0, -60.0, 60.0),
    ),
    Case("Michiels 2011 ex. 13, a = 0.75", ex13(), "DDAE", (-1.0, 0.5, -30.0, 30.0)),
    Case("manual 3.1 closed loop (r = -0.2)", ex31(), "RDDE", -0.2, None, 1),
    Case("retarded 2x2, delay 1", StateSpaceTDS([A0, A1], [0.0, 1.0]), "RDDE", REGION),
    Case("neutral 2x2, delays 1 and 0.5", StateSpaceTDS([A0, A1], [0.0, 1.0], B=[-H], hB=[0.5]), "NDDE", REGION),
    Case(
        "retarded 3x3, delays 1, sqrt 2", StateSpaceTDS([C0, C1, C2], [0.0, 1.0, float(np.sqrt(2.0))]), "RDDE", REGION
    ),
]


def best_time(run: Callable[[], Any], repeat: int = 7) -> tuple[Any, float, float]:
    """Result of ``run`` and the best of ``repeat`` wall-clock and CPU times (seconds)."""
    wall, cpu, out = np.inf, np.inf, None
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = run()
        wall, cpu = min(wall, time.perf_counter() - t0), min(cpu, time.process_time() - c0)
    return out, wall, cpu


def _on_fresh_copies(system: StateSpaceTDS, method: str, where: Any, n: int) -> Callable[[], Any]:
    """``method(where)`` of a new copy of ``system`` at each of ``n`` calls (the copies made beforehand):
    nothing that an earlier call kept on the object is reused."""
    copies = iter([dataclasses.replace(system) for _ in range(n)])
    return lambda: getattr(next(copies), method)(where)


def peer_time(run: Callable[[], Any], repeat: int) -> tuple[Any, float, float]:
    """:func:`best_time` of a peer with its default BLAS threads and with one, the better of each figure."""
    from threadpoolctl import threadpool_limits

    out, wall, cpu = best_time(run, repeat)
    with threadpool_limits(limits=1, user_api="blas"):
        _, wall1, cpu1 = best_time(run, repeat)
    return out, min(wall, wall1), min(cpu, cpu1)


def tdcpy_system(tdcpy: Any, sys: StateSpaceTDS, kind: str) -> Any:
    """The system in tdcpy's classes (``H = -B``)."""
    if kind == "RDDE":
        return tdcpy.RDDE(A=list(sys.A), hA=sys.hA)
    if kind == "NDDE":
        return tdcpy.NDDE(A=list(sys.A), hA=sys.hA, H=[-b for b in sys.B], hH=sys.hB)
    return tdcpy.DDAE(E=sys.E, A=list(sys.A), hA=sys.hA)


Row = tuple[Case, int, int, float, float, float, tuple[float, float], tuple[float, float]]


def compare(tdcpy: Any) -> list[Row]:
    """Per case: (case, nrobust roots, tdcpy roots, distance, nrobust max Re, tdcpy max Re,
    nrobust (wall s, CPU s), tdcpy (wall s, CPU s))."""
    rows = []
    for case in CASES:
        tds = tdcpy_system(tdcpy, case.system, case.kind)
        if isinstance(case.where, float):
            ours, wall, cpu = best_time(
                _on_fresh_copies(case.system, "roots_right_of", case.where, case.repeat), case.repeat
            )
            r: Any = case.where
        else:
            ours, wall, cpu = best_time(_on_fresh_copies(case.system, "roots", case.where, case.repeat), case.repeat)
            r = list(case.where)
        out, wall_t, cpu_t = peer_time(partial(tdcpy.roots, tds, r=r, max_size_evp=1500), case.repeat)
        theirs = out[0]
        assert ours.certified
        z = np.repeat(ours.roots, ours.multiplicities)
        dist = float(np.max(np.min(np.abs(theirs[:, None] - z[None, :]), axis=1))) if theirs.size else 0.0
        top = float(np.max(theirs.real)) if theirs.size else -np.inf
        rows.append(
            (case, int(z.size), int(theirs.size), dist, float(np.max(z.real)), top, (wall, cpu), (wall_t, cpu_t))
        )
    return rows


def main() -> None:
    try:
        import tdcpy
    except ImportError:
        print("tdcpy is not installed (pip install tdcpy): nothing to compare")
        return
    print("load average (1, 5, 15 min) before: {:.2f} {:.2f} {:.2f}".format(*os.getloadavg()))
    print(
        f"{'system':<36} {'nrobust':>7} {'tdcpy':>5} {'max dist':>8} {'max Re nrobust':>15} {'max Re tdcpy':>15} "
        f"{'stated':>8} {'wall ms':>15} {'ratio':>5} {'CPU ms':>15} {'ratio':>5}"
    )
    for case, n_ours, n_theirs, dist, re_ours, re_theirs, t_ours, t_theirs in compare(tdcpy):
        stated = "" if case.published is None else f"{case.published:.6g}"
        times = "".join(
            f" {1e3 * t_ours[k]:>7.1f} {1e3 * t_theirs[k]:>7.1f} {t_ours[k] / t_theirs[k]:>5.2f}" for k in (0, 1)
        )
        print(
            f"{case.name:<36} {n_ours:>7d} {n_theirs:>5d} {dist:>8.1e} {re_ours:>15.10f} {re_theirs:>15.10f} "
            f"{stated:>8}{times}"
        )
    print("load average (1, 5, 15 min) after: {:.2f} {:.2f} {:.2f}".format(*os.getloadavg()))


if __name__ == "__main__":
    main()
