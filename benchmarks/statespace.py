"""State-space time-delay systems: nrobust's certified spectrum vs tdcpy (same process).

tdcpy (the Python port of TDS-CONTROL, Michiels and Appeltans) computes the roots of
``det(s I - sum_k A_k e^{-h_k s} + s sum_k H_k e^{-hH_k s})`` in a rectangle by a spectral
discretisation of the infinitesimal generator with Newton corrections (not certified).
nrobust takes the same system as a :class:`~nrobust.statespace.StateSpaceTDS`, never
expands the determinant and certifies the count of the rectangle and a box per root.

The wheel of tdcpy 0.0.1 ships no example systems, so the three systems below are
written here: a retarded 2x2 system with one delay, the same with a neutral term
(tdcpy's ``NDDE`` writes ``x' = sum A x(t - h) - sum H x'(t - hH)``, so ``B = -H``), and a
3x3 retarded system with two incommensurate delays.

Printed per system: roots found by each (nrobust's count is certified), the largest
distance from a tdcpy root to the nearest nrobust root, seconds (best of 3), the time
ratio nrobust / tdcpy.

Run: ``python benchmarks/statespace.py`` (needs ``pip install tdcpy``, GPL-3.0).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np

from nrobust.statespace import StateSpaceTDS

REGION = (-3.0, 1.0, -30.0, 30.0)
A0 = np.array([[-1.0, 0.5], [0.3, -2.0]])
A1 = np.array([[-0.8, 0.2], [0.1, -0.5]])
H = np.array([[0.3, 0.1], [0.0, -0.4]])
C0 = np.array([[-2.0, 0.4, 0.0], [0.1, -1.0, 0.3], [0.0, 0.2, -1.5]])
C1 = np.array([[-0.3, 0.0, 0.2], [0.0, -0.6, 0.0], [0.4, 0.0, -0.2]])
C2 = np.array([[0.0, 0.5, 0.0], [-0.2, 0.0, 0.0], [0.0, 0.0, -0.4]])

# (name, A matrices, A delays, H matrices, H delays)
SYSTEMS: list[tuple[str, list[np.ndarray], list[float], list[np.ndarray], list[float]]] = [
    ("retarded 2x2, delay 1", [A0, A1], [0.0, 1.0], [], []),
    ("neutral 2x2, delays 1 and 0.5", [A0, A1], [0.0, 1.0], [H], [0.5]),
    ("retarded 3x3, delays 1 and sqrt 2", [C0, C1, C2], [0.0, 1.0, float(np.sqrt(2.0))], [], []),
]


def best_time(run: Callable[[], Any], repeat: int = 3) -> tuple[Any, float]:
    """Result of ``run`` and the best of ``repeat`` wall-clock times."""
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = run()
        best = min(best, time.perf_counter() - t0)
    return out, best


def tdcpy_system(tdcpy: Any, a: list[np.ndarray], ha: list[float], h: list[np.ndarray], hh: list[float]) -> Any:
    """The system in tdcpy's layout (matrices stacked on the last axis)."""
    A = np.stack(a, axis=-1)
    if not h:
        return tdcpy.RDDE(A=A, hA=np.array(ha))
    return tdcpy.NDDE(A=A, hA=np.array(ha), H=np.stack(h, axis=-1), hH=np.array(hh))


def compare(tdcpy: Any) -> list[tuple[str, int, int, float, float, float]]:
    """One row per system: (name, nrobust roots, tdcpy roots, distance, nrobust s, tdcpy s)."""
    rows = []
    for name, a, ha, h, hh in SYSTEMS:
        sys = StateSpaceTDS(a, ha, B=[-m for m in h], hB=hh)
        tds = tdcpy_system(tdcpy, a, ha, h, hh)
        ours, t_ours = best_time(partial(sys.roots, REGION))
        theirs, t_theirs = best_time(partial(lambda t: tdcpy.roots(t, r=list(REGION))[0], tds))
        z = np.repeat(ours.roots, ours.multiplicities)
        dist = float(np.max(np.min(np.abs(theirs[:, None] - z[None, :]), axis=1))) if theirs.size else 0.0
        assert ours.certified
        rows.append((name, int(z.size), int(theirs.size), dist, t_ours, t_theirs))
    return rows


def main() -> None:
    try:
        import tdcpy
    except ImportError:
        print("tdcpy is not installed (pip install tdcpy): nothing to compare")
        return
    print(f"region {REGION}")
    print(f"{'system':<36} {'nrobust':>8} {'tdcpy':>6} {'max dist':>9} {'nrobust s':>10} {'tdcpy s':>8} {'ratio':>6}")
    for name, n_ours, n_theirs, dist, t_ours, t_theirs in compare(tdcpy):
        print(
            f"{name:<36} {n_ours:>8d} {n_theirs:>6d} {dist:>9.1e} {t_ours:>10.3f} {t_theirs:>8.3f} "
            f"{t_ours / t_theirs:>6.1f}"
        )


if __name__ == "__main__":
    main()
