"""Several-parameter design: nrobust's optimize_loop vs tdcpy's minimize_spectral_abscissa (same process).

The loop is tdcpy's own example of ``minimize_spectral_abscissa`` (its docstring,
``tdcpy/stabopt/controller_bfgs.py``): ``x' = A0 x + A1 x(t - 1) + B u(t - 0.5)``, ``y = x``, with
``A0 = diag(-1, -2)``, ``A1 = I``, ``B = (-0.1, -0.2)^T`` and a static output feedback
``u = K y``, ``K = (k1, k2)``. Its characteristic function, ``det(s I - A0 - A1 e^{-s} - B K
e^{-s/2})``, is written here by hand (the ``B K`` term has rank one):
``(s + 1 - e^{-s})(s + 2 - e^{-s}) - e^{-s/2} (b1 k1 (s + 2 - e^{-s}) + b2 k2 (s + 1 - e^{-s}))``.

tdcpy minimises the spectral abscissa of a spectral discretisation with L-BFGS-B from
``K = 0`` (no bounds, no certificate). nrobust minimises the certified spectral abscissa
(:func:`nrobust.design.optimize_loop`, bounds ``|k_i| <= 40``, one start at ``K = 0``) and
certifies its design; tdcpy's design is certified here by :func:`nrobust.spectral_abscissa`
too. Printed: the abscissa each method claims, the certified abscissa of each design, CPU seconds
(one run each) and the ratio.

``--case filtered``: the three-parameter design of ``FilteredController(a, b, K)`` on the paper's plant
(``Hyperbolic2x2(1, 1, 1, 1, 1, 0.85)``, default bounds ``|K| <= 0.99 k_bound``, ``|a| <= tau``,
``tau/1000 <= b <= tau``) by :func:`nrobust.design_filtered`, warm-started from the exact U_BS2(K)
design: the best decay rate under ``delta* >= 0.2``, then the largest margin. Printed: the design,
its certificate, wall and CPU seconds (this process and its workers), the evaluations of the loop
and how many of them a bound settled (``LocalRun.screened``). Before the bounds and the pattern
search's extrapolation, with one start (``--starts 1``) on the same shared two-core machine: the
decay rate took 167 s of wall time (104 s of CPU, 207 evaluations), the margin 692 s (422 s of CPU,
434 evaluations, margin 0.549060).

Run: ``python benchmarks/design_local.py [--case all|tdcpy|filtered] [--starts 4] [--executor serial|2]
[--rigorous]``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import resource
import time

import numpy as np

import nrobust as nr
from nrobust.design import optimize_loop
from nrobust.roots import spectral_abscissa

B1, B2 = -0.1, -0.2
OPEN = nr.QuasiPolynomial([[2.0, 3.0, 1.0], [-3.0, -2.0], [1.0]], [0.0, 1.0, 2.0])  # (s+1-e^-s)(s+2-e^-s)
ZERO = nr.QuasiPolynomial([[0.0]], [0.0])


def loop(k: np.ndarray) -> tuple[nr.QuasiPolynomial, nr.QuasiPolynomial]:
    """``p = (k1, k2) -> (F, 0)``: no loop delay to vary, the decay rate alone is optimised."""
    c = B1 * k[0] + B2 * k[1]
    feedback = nr.QuasiPolynomial([[-(2.0 * B1 * k[0] + B2 * k[1]), -c], [c]], [0.5, 1.5])
    return OPEN + feedback, ZERO


def tdcpy_design() -> tuple[np.ndarray, float, float]:
    from tdcpy.ddae import DDAE
    from tdcpy.stabopt.controller_bfgs import minimize_spectral_abscissa

    A = np.stack([np.diag([-1.0, -2.0]), np.eye(2)], axis=2)
    B = np.stack([np.array([[B1], [B2]])], axis=2)
    C = np.stack([np.eye(2)], axis=2)
    ddae = DDAE(
        A=A,
        hA=np.array([0.0, 1.0]),
        B=B,
        hB=np.array([0.5]),
        C=C,
        hC=np.array([0.0]),
        D=np.zeros((2, 1, 1)),
        hD=np.array([0.0]),
    )
    cpu = time.process_time()
    with contextlib.redirect_stdout(io.StringIO()):  # tdcpy prints its own progress
        sol = minimize_spectral_abscissa(ddae, order=0, method="L-BFGS-B", options={"disp": False}, type="barrier")
    return np.ravel(sol.x), float(sol.fun), time.process_time() - cpu


def _cpu() -> float:
    """CPU seconds of this process and of its finished workers."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def filtered(starts: int, executor: str | int, rigorous: bool) -> None:
    """The three-parameter filtered design on the paper's plant, both objectives."""
    plant = nr.Hyperbolic2x2(lam=1.0, mu=1.0, sigma_pm=1.0, sigma_mp=1.0, q=1.0, rho=0.85)
    cases = (("decay rate, margin >= 0.2", {"margin_at_least": 0.2}), ("delay margin", {"objective": "margin"}))
    for name, options in cases:
        wall, cpu = time.perf_counter(), _cpu()
        best = nr.design_filtered(plant, starts=starts, executor=executor, rigorous=rigorous, **options)
        wall, cpu = time.perf_counter() - wall, _cpu() - cpu
        c, d = best.controller, best.design
        runs = d.runs
        print(f"filtered design, {name}: K = {c.K:.10f}, a = {c.a:.10f}, b = {c.b:.10f}")
        print(
            f"    decay rate {d.decay_rate:.12g} (abscissa {d.abscissa.value:.12g}, certified "
            f"{d.abscissa.certified}), {d.margin!r}"
        )
        print(
            f"    certified {best.certified} (rigorous {d.rigorous}), starts {starts} ({executor}), "
            f"evaluations {sum(r.evaluations for r in runs)} of which screened {sum(r.screened for r in runs)}, "
            f"wall {wall:.1f} s, CPU {cpu:.1f} s"
        )


def tdcpy_case() -> None:
    """nrobust's optimize_loop against tdcpy on tdcpy's example."""
    print(__doc__.split("\n\n")[0])
    cpu = time.process_time()
    design = optimize_loop(loop, [(-40.0, 40.0), (-40.0, 40.0)], x0=(0.0, 0.0))
    t_nr = time.process_time() - cpu
    print(f"{'method':32s} {'K':>28s} {'claimed':>11s} {'certified':>11s} {'CPU s':>8s} {'ratio':>6s}")
    k = design.parameters
    print(
        f"{'nrobust optimize_loop':32s} ({k[0]:12.6f}, {k[1]:12.6f}) {-design.value:11.6f} "
        f"{design.abscissa.value:11.6f} {t_nr:8.2f} {1.0:6.2f}"
    )
    try:
        x, claimed, t_td = tdcpy_design()
    except ImportError:
        print("tdcpy is not installed (pip install tdcpy)")
        return
    certified = spectral_abscissa(loop(x)[0]).value
    print(
        f"{'tdcpy minimize_spectral_abscissa':32s} ({x[0]:12.6f}, {x[1]:12.6f}) {claimed:11.6f} "
        f"{certified:11.6f} {t_td:8.2f} {t_td / t_nr:6.2f}"
    )
    print("claimed: the method's own value; certified: nrobust.spectral_abscissa of the design (certified count)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", choices=("all", "tdcpy", "filtered"), default="all")
    parser.add_argument("--starts", type=int, default=4)
    parser.add_argument("--executor", default="serial", help="'serial' or a number of worker processes")
    parser.add_argument("--rigorous", action="store_true", help="certify the filtered designs in ball arithmetic")
    args = parser.parse_args()
    executor: str | int = int(args.executor) if args.executor.isdigit() else args.executor
    if args.case in ("all", "tdcpy"):
        tdcpy_case()
    if args.case in ("all", "filtered"):
        filtered(args.starts, executor, args.rigorous)


if __name__ == "__main__":
    main()
