"""Benchmark of the simulator against two peers measured in the same run.

Plant of the paper's simulation section (``lam = mu = sigma = q = 1``, ``rho = 0.85``).
Peers, both vectorised numpy on the same nodes ``k/n``:

* ``co-located``: u and v on the same nodes, shifted one cell per step ``dt = 1/(lam n)``
  with the same trapezoidal couplings. Its lattice splits into two sub-lattices tied
  only by the control integral (the trap described in ``docs/simulation.md``).
* ``upwind``: first-order upwind finite volumes at CFL 0.5 (explicit Euler in time).

Printed: node updates per second (and their ratio to this simulator's), the time of the paper's run to ``t = 10`` at the
figure's grid (n = 400), and what each scheme says about the closed loops of
Figures 1 and 3. Run: ``python benchmarks/simulate.py``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from nrobust import FiniteTimeController, ReflectionController, characteristic, simulate, spectral_abscissa
from nrobust.hyperbolic.kernels.constant import solve_kernels
from nrobust.hyperbolic.plants.hyperbolic2x2 import Hyperbolic2x2

SYSTEM = Hyperbolic2x2(lam=1.0, mu=1.0, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)
N, T_END = 400, 10.0


def u0(x: np.ndarray) -> np.ndarray:
    return np.sin(np.pi * x) + x


def v0(x: np.ndarray) -> np.ndarray:
    return 1.0 - x**2


def peer(law, delta: float, n: int, scheme: str) -> tuple[np.ndarray, np.ndarray]:
    """Times and L2 norm of the closed loop by a peer scheme (``co-located`` or ``upwind``)."""
    x = np.linspace(0.0, 1.0, n + 1)
    h = 1.0 / n
    dt = h if scheme == "co-located" else 0.5 * h
    steps = round(T_END / dt)
    w = np.full(n + 1, h)
    w[[0, -1]] /= 2
    wu, wv = w * law.gain_u(x), w * law.gain_v(x)
    lag = round(delta / dt)
    u, v = u0(x), v0(x)
    hist = np.zeros(steps + 1)
    norm = np.empty(steps + 1)
    q, rho, bg = SYSTEM.q, SYSTEM.rho, law.boundary_gain
    a = dt / 2  # trapezoidal factor, sigma = 1
    inv = 1.0 / (1.0 - a * a)
    for j in range(steps + 1):
        hist[j] = bg * u[-1] + wu @ u + wv @ v
        norm[j] = math.sqrt(w @ (u * u + v * v))
        if j == steps:
            break
        delayed = hist[j + 1 - lag] if 0 < lag <= j + 1 else 0.0
        if scheme == "co-located":
            ru = u[:-1] + a * v[:-1]
            rv = v[1:] + a * u[1:]
            un, vn = np.empty_like(u), np.empty_like(v)
            un[1:-1] = (ru[:-1] + a * rv[1:]) * inv
            vn[1:-1] = (rv[1:] + a * ru[:-1]) * inv
            vn[0] = rv[0] / (1.0 - a * q)
            un[0] = q * vn[0]
            un[-1] = ru[-1] + a * v[-1]  # explicit at x = 1; then the boundary law
            if lag == 0:
                # U(t_{j+1}) depends on v(t_{j+1}, 1): solve the scalar loop equation.
                rest = wu @ un + wv[:-1] @ vn[:-1] + bg * un[-1]
                vn[-1] = (rho * un[-1] + rest) / (1.0 - wv[-1])
            else:
                vn[-1] = rho * un[-1] + delayed
            u, v = un, vn
        else:
            c = dt / h
            un = u.copy()
            vn = v.copy()
            un[1:] = u[1:] - c * (u[1:] - u[:-1]) + dt * v[1:]
            vn[:-1] = v[:-1] + c * (v[1:] - v[:-1]) + dt * u[:-1]
            if lag == 0:
                rest = wu[:-1] @ un[:-1] + wv[:-1] @ vn[:-1] + (bg + wu[-1]) * un[-1]
                vn[-1] = (rho * un[-1] + rest) / (1.0 - wv[-1])
            else:
                vn[-1] = rho * un[-1] + delayed
            un[0] = q * vn[0]
            u, v = un, vn
    return dt * np.arange(steps + 1), norm


def slope(times: np.ndarray, norm: np.ndarray, t_min: float = 5.0) -> float:
    mask = (times >= t_min) & (norm > 0)
    return float(np.polyfit(times[mask], np.log(norm[mask]), 1)[0])


def timed(fun: Callable[[], object]) -> tuple[object, float]:
    start = time.perf_counter()
    out = fun()
    return out, time.perf_counter() - start


def main() -> None:
    kernels, t_kernels = timed(lambda: solve_kernels(SYSTEM, N + 1))
    print(f"kernels (n = {N + 1}): {t_kernels:.2f} s")
    runs = {
        "U_BS, delta = 0": (FiniteTimeController(), 0.0),
        "U_BS, delta = 0.01": (FiniteTimeController(), 0.01),
        "U_BS2, delta = 0.1": (ReflectionController(0.1), 0.1),
    }
    print(f"\npaper example to t = {T_END:g}, n = {N} cells")
    print(
        f"{'run':<22}{'scheme':<14}{'time [s]':>10}{'updates/s':>12}{'vs lattice':>12}{'slope [5,10]':>14}"
        f"{'final norm':>12}"
    )
    for name, (controller, delta) in runs.items():
        law = controller.feedback_law(SYSTEM, kernels)
        sim, t_sim = timed(lambda law=law, delta=delta: simulate(SYSTEM, law, delta, T_END, u0, v0, cells=N))
        rows = [("lattice", sim.times, sim.norm, t_sim, 2 * N * (sim.times.size - 1))]
        for scheme in ("co-located", "upwind"):
            (times, norm), t_peer = timed(lambda law=law, delta=delta, scheme=scheme: peer(law, delta, N, scheme))
            rows.append((scheme, times, norm, t_peer, (N + 1) * (times.size - 1)))
        reference = rows[0][4] / rows[0][3]
        for scheme, times, norm, seconds, updates in rows:
            print(
                f"{name:<22}{scheme:<14}{seconds:>10.3f}{updates / seconds:>12.3g}"
                f"{updates / seconds / reference:>12.2f}{slope(times, norm):>+14.4f}{norm[-1]:>12.3e}"
            )
        if delta > 0:
            spectrum, t_roots = timed(lambda c=controller, d=delta: spectral_abscissa(characteristic(SYSTEM, c, d)))
            print(f"{'':<22}spectral abscissa {spectrum.value:+.4f} (certified: {spectrum.certified}, {t_roots:.1f} s)")
    unequal = Hyperbolic2x2(lam=1.0, mu=2.0, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)
    law = ReflectionController(0.1).feedback_law(unequal, solve_kernels(unequal, N + 1))
    sim, t_sim = timed(lambda: simulate(unequal, law, 0.1, T_END, u0, v0, cells=N))
    nodes = (sim.x.size + sim.x_v.size) * (sim.times.size - 1)
    print(
        f"\nunequal speeds (lam, mu) = (1, 2), two grids, U_BS2, delta = 0.1: {t_sim:.3f} s, "
        f"{nodes / t_sim:.3g} node updates/s"
    )
    print("\nlattice updates count both half steps (2 n nodes per sampling step). The initial state is")
    print("generic, so the fitted slope approaches the abscissa slowly (docs/simulation.md); the sign is")
    print("the verdict.")


if __name__ == "__main__":
    main()
