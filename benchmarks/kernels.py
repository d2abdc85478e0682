"""Backstepping kernels: error and time per grid, plain second-order scheme vs extrapolated.

Two plants:

* the paper's example, ``lam = mu = sigma_pm = sigma_mp = q = 1``, ``rho = 0.85``;
* ``lam = 1``, ``mu = 2.5``, ``sigma_pm = 1 + 0.5 sin(3x)``, ``sigma_mp = 2 e^{-x}``,
  ``q = 0.7``, ``rho = 0.85`` (non-aligned cross characteristics, varying couplings).

For ``n = 51 ... 801`` the script prints the largest error of ``K`` and of ``L`` on the
grid against a fine reference (Richardson-extrapolated solution with ``n_ref`` points,
``K`` from 3201 points, ``L`` from 1601 points by default), and the seconds per solve,
for the plain scheme (``extrapolate=False``, the peer measured in the same run) and the
default extrapolated one, with the ratios. For comparison, a published first-order
solver is reported to need about 8.6 s at ``n = 401`` for an error of 1.7e-4 on the
paper's example (a number quoted, not measured here).

Run: ``python benchmarks/kernels.py [--quick]`` (``--quick``: n up to 401, coarser references).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from nrobust import Hyperbolic2x2, solve_kernels
from nrobust.hyperbolic.kernels.constant import _richardson, _solve_K

PLANTS = {
    "paper (lam = mu = 1)": Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85),
    "lam = 1, mu = 2.5, varying": Hyperbolic2x2(
        1.0, 2.5, lambda x: 1.0 + 0.5 * np.sin(3.0 * x), lambda x: 2.0 * np.exp(-x), 0.7, 0.85
    ),
}


def reference(system: Hyperbolic2x2, n_K: int, n_L: int) -> tuple[np.ndarray, np.ndarray]:
    """Fine-grid references: extrapolated ``K`` on ``n_K`` points, extrapolated ``L`` on ``n_L``."""
    K_ref = _richardson(_solve_K(system, n_K), _solve_K(system, (n_K + 1) // 2))
    L_ref = solve_kernels(system, kernel_grid=n_L).L
    return K_ref, L_ref


def timed(system: Hyperbolic2x2, n: int, extrapolate: bool, repeat: int) -> tuple[float, object]:
    best, result = np.inf, None
    for _ in range(repeat):
        start = time.perf_counter()
        result = solve_kernels(system, kernel_grid=n, extrapolate=extrapolate)
        best = min(best, time.perf_counter() - start)
    return best, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="n up to 401 and coarser references")
    args = parser.parse_args()
    grids = (51, 101, 201, 401) if args.quick else (51, 101, 201, 401, 801)
    n_K, n_L = (1601, 801) if args.quick else (3201, 1601)
    for name, system in PLANTS.items():
        K_ref, L_ref = reference(system, n_K, n_L)
        print(f"\n{name}   (reference: K from n = {n_K}, L from n = {n_L}, both extrapolated)")
        print(
            f"{'n':>5} | {'plain: err K':>12} {'err L':>9} {'s':>7} | {'extrap: err K':>13} {'err L':>9} {'s':>7} | "
            f"{'err ratio K':>11} {'time ratio':>10}"
        )
        for n in grids:
            row = []
            for extrapolate in (False, True):
                seconds, k = timed(system, n, extrapolate, repeat=3 if n <= 401 else 1)
                err_K = np.abs(k.K - K_ref[:, :, :: (n_K - 1) // (n - 1), :: (n_K - 1) // (n - 1)]).max()
                if n <= n_L:
                    stride = (n_L - 1) // (n - 1)
                    err_L = np.abs(k.L - L_ref[:, :, ::stride, ::stride]).max()
                else:
                    err_L = np.nan
                row.append((err_K, err_L, seconds))
            (pK, pL, pt), (eK, eL, et) = row
            print(
                f"{n:>5} | {pK:>12.2e} {pL:>9.2e} {pt:>7.3f} | {eK:>13.2e} {eL:>9.2e} {et:>7.3f} | "
                f"{pK / eK:>11.1f} {et / pt:>10.2f}"
            )


if __name__ == "__main__":
    main()
