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
too. Printed: the abscissa each method claims, the certified abscissa of each design, seconds
(one run each) and the ratio.
"""

from __future__ import annotations

import contextlib
import io
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
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):  # tdcpy prints its own progress
        sol = minimize_spectral_abscissa(ddae, order=0, method="L-BFGS-B", options={"disp": False}, type="barrier")
    return np.ravel(sol.x), float(sol.fun), time.perf_counter() - start


def main() -> None:
    print(__doc__.split("\n\n")[0])
    start = time.perf_counter()
    design = optimize_loop(loop, [(-40.0, 40.0), (-40.0, 40.0)], x0=(0.0, 0.0))
    t_nr = time.perf_counter() - start
    print(f"{'method':32s} {'K':>28s} {'claimed':>11s} {'certified':>11s} {'seconds':>8s} {'ratio':>6s}")
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


if __name__ == "__main__":
    main()
