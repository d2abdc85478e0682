"""Delay margin and stability chart of the paper's example: nrobust vs direct peers.

The plant is the paper's section 5 example (lam = mu = sigma+- = sigma-+ = q = 1,
rho = 0.85) with ``U_BS2(K)`` (eq. (53)), whose loop is eq. (60).
Measured in this process:

* one delay margin (``K = 0.1``) by :func:`nrobust.delay_margin` (certified crossing
  search; without and with the final verification by certified root counts), against a
  *dense scan*: ``|A(i w)| - |B(i w)|`` sampled with step ``1e-3`` on ``[0, W]`` (same
  ``W``), sign changes refined by Brent's method; no completeness guarantee (it misses
  tangential touches and pairs of crossings closer than the step);
* the guaranteed delay ``delta_0`` of Theorem 4's proof (:func:`nrobust.rouche_delay_bound`)
  beside ``delta*``;
* the admissible gains :func:`nrobust.k_region` at ``tol = 1e-9`` for ``delta_max = 0.1`` and
  ``0.2`` (goal: under 1 s on 2 cores): the ends with their kind, the time to
  locate them by their equations (the frequency scan) and the total with their verification
  (a crossing search inside and a root count outside each end, and the 9 grid margins;
  CPU time beside the wall time, which a loaded machine inflates), serially and on 2
  processes; without ``--quick`` also the former route (bisection on delay margins, still
  used for other controller families) for comparison;
* a 50 x 50 chart of the number of unstable roots on ``K in [-0.14, 0.14]``,
  ``delta in [0, 0.5]`` by :func:`nrobust.stability_chart` (one crossing analysis per
  gain), against certified counts (:func:`nrobust.count_roots`) at every grid point,
  timed on a few points and extrapolated to the 2500.

Printed: values, seconds (best of several runs for the single margin and its peer), and
the time ratio peer / nrobust.

Run: ``python benchmarks/margins.py [--quick]`` (``--quick``: a 10 x 10 chart, no bisection route).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.optimize import brentq

from nrobust import (
    Hyperbolic2x2,
    ReflectionController,
    characteristic,
    classify,
    count_roots,
    delay_margin,
    k_region,
    loop_factors,
    rouche_delay_bound,
    stability_chart,
)
from nrobust.hyperbolic.analyses.kregion import u_bs2_loop
from nrobust.margins.gain import locate_gain_ends


def dense_scan_margin(A, B, W: float, step: float = 1e-3) -> tuple[float, int]:
    """The uncertified textbook method: sample, bracket, Brent; return (margin, crossings)."""
    w = np.arange(0.0, W + step, step)
    h = np.abs(A(1j * w)) - np.abs(B(1j * w))
    idx = np.flatnonzero(np.sign(h[1:]) != np.sign(h[:-1]))

    def hs(x: float) -> float:
        s = np.array([1j * x])
        return float(np.abs(A(s))[0] - np.abs(B(s))[0])

    best = np.inf
    for i in idx:
        wc = brentq(hs, w[i], w[i + 1], xtol=1e-12)
        s = np.array([1j * wc])
        d = float(np.mod(np.angle(-B(s)[0] / A(s)[0]) / wc, 2 * np.pi / wc))
        best = min(best, d)
    return best, idx.size


def timed(fn, repeat: int = 1):
    """Best wall time of ``repeat`` calls (as ``timeit``: the least disturbed by other load) and the last result."""
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return float(np.min(times)), out


def bisection_family(K: float) -> ReflectionController:
    """U_BS2(K) as a user family: ``k_region`` then bisects on delay margins (the former route)."""
    return ReflectionController(K)


def k_region_section(system: Hyperbolic2x2, quick: bool) -> None:
    """Time ``k_region`` at ``tol = 1e-9``: locating the ends, verifying them, on 1 and 2 processes."""
    kb = classify(system).k_bound
    loop = u_bs2_loop(system)
    print("\nadmissible gains, tol = 1e-9 (goal: under 1 s on 2 cores)")
    for delta_max in (0.1, 0.2):
        t_loc, _ = timed(lambda d=delta_max: locate_gain_ends(loop, d, kb, 1e-9, 2_000_000), repeat=3)
        cpu = time.process_time()
        t_ser, reg = timed(lambda d=delta_max: k_region(system, d, tol=1e-9))
        cpu = time.process_time() - cpu
        t_par, reg2 = timed(lambda d=delta_max: k_region(system, d, tol=1e-9, executor=2))
        same = reg.intervals == reg2.intervals
        print(f"  delta_max = {delta_max}:")
        for lo, hi in reg.ends:
            for name, end in (("lower", lo), ("upper", hi)):
                print(f"    {name} end K = {end.K:.12f}  {end.kind:<16} w = {end.omega:.8g}  delay {end.delay:.8g}")
        print(
            f"    locate (equations) {t_loc:.3f} s; k_region serial {t_ser:.3f} s ({cpu:.3f} s of CPU: a loaded "
            f"machine shows in the difference), on 2 processes {t_par:.3f} s (same ends: {same})"
        )
        if not quick:
            t_bis, bis = timed(lambda d=delta_max: k_region(system, d, tol=1e-9, controller=bisection_family))
            gap = max(abs(a - b) for iv, jv in zip(bis.intervals, reg.intervals) for a, b in zip(iv, jv))
            print(f"    former route (bisection on margins) {t_bis:.1f} s, ends differ by {gap:.2g}")
    near = Hyperbolic2x2(2.0, 0.5, 0.3, -0.4, 0.7, 0.9)  # ends within 1e-4 of k = 0.528571
    cpu = time.process_time()
    t_near, reg = timed(lambda: k_region(near, 0.2))
    cpu = time.process_time() - cpu
    ends = ", ".join(f"{end.K:.10f} ({end.kind}, w = {end.omega:.6g})" for pair in reg.ends for end in pair)
    print(f"  lam = 2, mu = 0.5, sigma = (0.3, -0.4), q = 0.7, rho = 0.9, delta_max = 0.2: {ends}")
    print(f"    k_region serial {t_near:.3f} s ({cpu:.3f} s of CPU)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10 x 10 chart instead of 50 x 50")
    args = parser.parse_args()
    system = Hyperbolic2x2(1.0, 1.0, 1.0, 1.0, 1.0, 0.85)
    ctrl = ReflectionController(0.1)

    t_setup, (A, B) = timed(lambda: loop_factors(system, ctrl))
    print(f"setup (kernels, delay form, loop factors): {t_setup:.3f} s (cached afterwards)")

    t_dm, dm = timed(lambda: delay_margin(A, B, verify=False), repeat=5)
    t_dmv, dmv = timed(lambda: delay_margin(A, B))
    t_peer, (m_peer, n_peer) = timed(lambda: dense_scan_margin(A, B, dm.frequency_bound), repeat=3)
    print("\none delay margin, K = 0.1")
    print(
        f"  nrobust delay_margin          delta* = {dm.margin:.12f}  w = {dm.omega:.10f}  "
        f"{len(dm.crossings)} crossings in [0, W = {dm.frequency_bound:.4g}], {dm.evaluations} evaluations  "
        f"{t_dm:.4f} s"
    )
    print(f"  nrobust delay_margin, verified delta* = {dmv.margin:.12f}  residual {dmv.residual:.1e}  {t_dmv:.4f} s")
    print(
        f"  dense scan (step 1e-3)        delta* = {m_peer:.12f}  {n_peer} crossings  {t_peer:.4f} s  "
        f"ratio {t_peer / t_dm:.1f}x"
    )
    # the proven margin (ball arithmetic) against the verified floating-point one, best of 3 each
    t_ref, _ = timed(lambda: delay_margin(A, B), repeat=3)
    t_prov, prov = timed(lambda: delay_margin(A, B, rigorous=True), repeat=3)
    lo, hi = prov.margin_ball
    print(
        f"  proven (ball arithmetic)      delta* in [{lo:.15f}, {hi:.15f}]  {prov.evaluations} ball evaluations  "
        f"{t_prov:.3f} s  ratio to the verified margin {t_prov / t_ref:.1f}x (goal: under 20x)"
    )
    t_rb, rb = timed(lambda: rouche_delay_bound(system, ctrl))
    print(
        f"  Rouche bound (Theorem 4)      delta_0 = {rb.delta_0:.6f} <= delta*  ({rb.steps} certified steps)  "
        f"{t_rb:.4f} s"
    )

    k_region_section(system, args.quick)

    n = 10 if args.quick else 50
    Ks = np.linspace(-0.14, 0.14, n)
    deltas = np.linspace(0.0, 0.5, n)
    t_chart, chart = timed(lambda: stability_chart(system, Ks, deltas))
    probe = [(Ks[i], deltas[j]) for i, j in [(n // 4, n // 2), (n // 2, n - 1), (3 * n // 4, n // 3)]]
    W = dm.frequency_bound

    def peer_points() -> list[int]:
        out = []
        for K, d in probe:
            F = characteristic(system, ReflectionController(K), d)
            out.append(int(count_roots(F, (0.0, 1.01 * W, -1.01 * W, 1.01 * W))))
        return out

    t_probe, counts = timed(peer_points)
    per_point = t_probe / len(probe)
    agree = all(
        chart.values[int(np.flatnonzero(Ks == K)[0]), int(np.flatnonzero(deltas == d)[0])] == c
        for (K, d), c in zip(probe, counts)
    )
    stable = int(np.sum(chart.values == 0))
    print(f"\n{n} x {n} stability chart (unstable-root counts), K in [-0.14, 0.14], delta in [0, 0.5]")
    print(
        f"  nrobust stability_chart       {t_chart:.3f} s  ({stable} stable grid points, "
        f"margins {np.nanmin(chart.margins):.4f} .. {np.nanmax(chart.margins):.4f})"
    )
    print(
        f"  certified count per point     {per_point:.3f} s x {n * n} = {per_point * n * n:.1f} s (extrapolated)  "
        f"ratio {per_point * n * n / t_chart:.1f}x  counts agree at {len(probe)} probes: {agree}"
    )
    t_par, chart_par = timed(lambda: stability_chart(system, Ks, deltas, executor=None))
    same = np.array_equal(chart_par.values, chart.values, equal_nan=True)
    print(
        f"  stability_chart, all cores    {t_par:.3f} s  (sweep executor: local processes)  "
        f"speed-up {t_chart / t_par:.2f}x  identical: {same}"
    )


if __name__ == "__main__":
    main()
