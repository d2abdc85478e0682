"""Root finding on 1 - 0.85 e^{-2s} + 0.1 e^{-2.1s} in [-3, 1] x [-0.5, H]: nrobust vs peers.

The quasi-polynomial is the transport loop of the paper (rho q = 0.85, K = 0.1,
delta = 0.1, eq. (13)). Its delays are commensurate with step 0.1, so the
exact roots are ``s = (-ln z + 2 pi i k) / 0.1`` for the 21 roots ``z`` of
``1 - 0.85 z^20 + 0.1 z^21``. Each solver runs in this process on the same region:

* nrobust ``find_roots`` (certified count, chain seeding, certified boxes);
* nrobust ``find_roots(..., rigorous=True)`` ("proven": the same roots, then the count of
  the region and one box per root proven in ball arithmetic with python-flint); its
  ratio to the floating-point run is the price of the proof;
* qpmr (Vyhlidal and Zitek's mapping-based QPmR; not certified);
* cxroots (argument principle by quadrature, count accepted within 0.1 of an integer);
  run for H = 50 and 200 only, skipped at H = 200 with ``--quick``.

Printed per solver: roots found (with multiplicity), exact roots matched by a found root
within 1e-8, exact count, largest distance from an exact root to the nearest found
root, seconds (best of several runs for the fast solvers), and the time ratio of the
peer (or of the proven run) to nrobust's floating-point run.

A second table: the distributed delay ``F(s) = s + 1 - 2 (1 - e^{-s}) / s`` (the constant
kernel 2 on ``[0, 1]``) in ``[-12, 2] x [-0.5, 300]`` (48 roots). nrobust takes ``F`` natively
(a QuasiPolynomial with a DistributedDelay term); the peers, which have point delays only,
take ``s F(s) = s^2 + s - 2 + 2 e^{-s}``, whose roots are those of ``F`` and ``s = 0``
(49 in the region): nrobust on ``s F`` too, qpmr, tdcpy (the retarded system
``x'' + x' - 2 x + 2 x(t - 1) = 0`` in state-space form, its spectral discretisation with
Newton corrections in the rectangle) and cxroots on ``F`` itself (skipped with ``--quick``).
Printed: roots found, the largest distance to nrobust's certified roots of ``F`` (``s = 0`` left
out), seconds and the ratio of each time to nrobust's native one.

Run: ``python benchmarks/roots.py [--quick]``
(``--quick`` skips cxroots at H = 200 and on the distributed delay; it takes minutes)
"""

from __future__ import annotations

import argparse
import logging
import time
import warnings
from collections.abc import Callable

import numpy as np

from nrobust import DistributedDelay, QuasiPolynomial, find_roots

COEFS = [[1.0], [-0.85], [0.1]]
DELAYS = [0.0, 2.0, 2.1]
RE_MIN, RE_MAX, IM_MIN = -3.0, 1.0, -0.5


def exact_roots(H: float) -> np.ndarray:
    """Roots in the region from the degree-21 polynomial in z = e^{-0.1 s}."""
    poly = np.zeros(22)
    poly[0], poly[20], poly[21] = 1.0, -0.85, 0.1
    base = -np.log(np.roots(poly[::-1])) / 0.1
    k = np.arange(-2, int(H * 0.1 / (2 * np.pi)) + 3)
    s = (base[:, None] + 2j * np.pi * k[None, :] / 0.1).ravel()
    return s[(s.real > RE_MIN) & (s.real < RE_MAX) & (s.imag > IM_MIN) & (s.imag < H)]


def max_error(found: np.ndarray, exact: np.ndarray) -> float:
    """Largest distance from an exact root to the nearest found root."""
    if found.size == 0:
        return float("inf")
    return float(np.max(np.min(np.abs(exact[:, None] - found[None, :]), axis=1)))


def matched(found: np.ndarray, exact: np.ndarray, tol: float = 1e-8) -> int:
    """Number of exact roots with a found root within ``tol``."""
    if found.size == 0:
        return 0
    return int(np.sum(np.min(np.abs(exact[:, None] - found[None, :]), axis=1) < tol))


def run_nrobust(H: float) -> np.ndarray:
    F = QuasiPolynomial(COEFS, DELAYS)
    res = find_roots(F, (RE_MIN, RE_MAX, IM_MIN, H))
    if not res.certified:
        raise RuntimeError("nrobust did not certify the region")
    return np.repeat(res.roots, res.multiplicities)


def run_proven(H: float) -> np.ndarray:
    F = QuasiPolynomial(COEFS, DELAYS)
    res = find_roots(F, (RE_MIN, RE_MAX, IM_MIN, H), rigorous=True)
    if not (res.certified and res.rigorous):
        raise RuntimeError("nrobust did not prove the region")
    return np.repeat(res.roots, res.multiplicities)


def run_qpmr(H: float) -> np.ndarray:
    import qpmr

    coefs = np.array(COEFS, dtype=float)
    with warnings.catch_warnings():  # qpmr casts complex grid values inside numpy.ma
        warnings.simplefilter("ignore", np.exceptions.ComplexWarning)
        roots, _ = qpmr.qpmr(coefs, np.array(DELAYS), region=(RE_MIN, RE_MAX, IM_MIN, H))
    return np.asarray(roots, dtype=complex)


def run_cxroots(H: float) -> np.ndarray:
    from cxroots import Rectangle

    def f(s: complex) -> complex:
        return 1 - 0.85 * np.exp(-2 * s) + 0.1 * np.exp(-2.1 * s)

    def df(s: complex) -> complex:
        return 1.7 * np.exp(-2 * s) - 0.21 * np.exp(-2.1 * s)

    # scipy.integrate.quad warns on the long edges and cxroots logs its subdivision
    # retries as warnings: keep the table readable
    logging.getLogger("cxroots").setLevel(logging.ERROR)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = Rectangle((RE_MIN, RE_MAX), (IM_MIN, H)).roots(f, df)
    return np.repeat(np.array(result.roots, dtype=complex), result.multiplicities)


def timed(fn: Callable[[float], np.ndarray], H: float, repeat: int) -> tuple[np.ndarray, float]:
    """Best wall-clock time of ``repeat`` runs (a single run for slow peers)."""
    best = float("inf")
    roots = np.zeros(0, dtype=complex)
    for _ in range(repeat):
        t0 = time.perf_counter()
        roots = fn(H)
        best = min(best, time.perf_counter() - t0)
    return roots, best


DD_REGION = (-12.0, 2.0, -0.5, 300.0)


def dd_native() -> np.ndarray:
    """nrobust on F itself: the DistributedDelay term -2 int_0^1 e^{-nu s} dnu."""
    F = QuasiPolynomial([[1.0, 1.0]], [0.0], [DistributedDelay([0.0, 1.0], [-2.0, -2.0])])
    res = find_roots(F, DD_REGION)
    if not res.certified:
        raise RuntimeError("nrobust did not certify the region")
    return np.repeat(res.roots, res.multiplicities)


def dd_times_s() -> np.ndarray:
    """nrobust on s F(s) = s^2 + s - 2 + 2 e^{-s}."""
    res = find_roots(QuasiPolynomial([[-2.0, 1.0, 1.0], [2.0]], [0.0, 1.0]), DD_REGION)
    if not res.certified:
        raise RuntimeError("nrobust did not certify the region")
    return np.repeat(res.roots, res.multiplicities)


def dd_qpmr() -> np.ndarray:
    import qpmr

    with warnings.catch_warnings():  # qpmr casts complex grid values inside numpy.ma
        warnings.simplefilter("ignore", np.exceptions.ComplexWarning)
        roots, _ = qpmr.qpmr(np.array([[-2.0, 1.0, 1.0], [2.0, 0.0, 0.0]]), np.array([0.0, 1.0]), region=DD_REGION)
    return np.asarray(roots, dtype=complex)


def dd_tdcpy() -> np.ndarray:
    import tdcpy

    sys = tdcpy.RDDE(A=[np.array([[0.0, 1.0], [2.0, -1.0]]), np.array([[0.0, 0.0], [-2.0, 0.0]])], hA=[0.0, 1.0])
    roots, _ = tdcpy.roots(sys, r=list(DD_REGION))
    return np.asarray(roots, dtype=complex)


def dd_cxroots() -> np.ndarray:
    from cxroots import Rectangle

    def f(s: complex) -> complex:
        return s + 1 - 2 * (1 - np.exp(-s)) / s

    def df(s: complex) -> complex:
        return 1 + 2 * (1 - np.exp(-s)) / s**2 - 2 * np.exp(-s) / s

    logging.getLogger("cxroots").setLevel(logging.ERROR)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = Rectangle(DD_REGION[:2], DD_REGION[2:]).roots(f, df)
    return np.repeat(np.array(result.roots, dtype=complex), result.multiplicities)


def best_of(fn: Callable[[], np.ndarray], repeat: int) -> tuple[np.ndarray, float]:
    """The roots and the best wall-clock time of ``repeat`` runs."""
    best, roots = float("inf"), np.zeros(0, dtype=complex)
    for _ in range(repeat):
        t0 = time.perf_counter()
        roots = fn()
        best = min(best, time.perf_counter() - t0)
    return roots, best


def distributed_table(quick: bool) -> None:
    """The distributed-delay problem: nrobust natively against the peers on s F."""
    header = f"{'solver':>22} {'found':>6} {'max dist':>10} {'seconds':>9} {'time / nrobust native':>22}"
    print("\nF(s) = s + 1 - 2 (1 - e^{-s}) / s in [-12, 2] x [-0.5, 300]")
    print(header)
    print("-" * len(header))
    runs: list[tuple[str, Callable[[], np.ndarray], int]] = [
        ("nrobust native F", dd_native, 5),
        ("nrobust on s F", dd_times_s, 5),
        ("qpmr on s F", dd_qpmr, 3),
        ("tdcpy on s F", dd_tdcpy, 3),
    ]
    if not quick:
        runs.append(("cxroots on F", dd_cxroots, 1))
    base, reference = float("nan"), np.zeros(0, dtype=complex)
    for name, fn, repeat in runs:
        try:
            roots, seconds = best_of(fn, repeat)
        except ImportError as exc:
            print(f"{name:>22}  skipped: {exc}")
            continue
        if name == "nrobust native F":
            base, reference = seconds, roots
        nonzero = roots[np.abs(roots) > 1e-8]
        dist = max_error(reference, nonzero) if nonzero.size else float("inf")
        print(f"{name:>22} {roots.size:6d} {dist:10.2e} {seconds:9.4f} {seconds / base:22.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="skip cxroots at H = 200 (it takes minutes)")
    args = parser.parse_args()
    header = (
        f"{'H':>6} {'solver':>8} {'found':>6} {'matched':>8} {'exact':>6} {'max error':>10} "
        f"{'seconds':>9} {'peer/nrobust':>13}"
    )
    print(header)
    print("-" * len(header))
    goal = float("nan")
    for H in (50.0, 200.0, 1000.0):
        exact = exact_roots(H)
        runs: list[tuple[str, Callable[[float], np.ndarray], int]] = [
            ("nrobust", run_nrobust, 5),
            ("proven", run_proven, 3),
            ("qpmr", run_qpmr, 3),
        ]
        if H == 50.0 or (H == 200.0 and not args.quick):
            runs.append(("cxroots", run_cxroots, 1))
        base = None
        for name, fn, repeat in runs:
            try:
                roots, seconds = timed(fn, H, repeat)
            except ImportError as exc:  # a peer (or python-flint for "proven") is not installed
                print(f"{H:6.0f} {name:>8}  skipped: {exc}")
                continue
            base = seconds if base is None else base
            if name == "proven" and H == 200.0:
                goal = seconds / base
            ratio = "" if name == "nrobust" else f"{seconds / base:13.1f}"
            print(
                f"{H:6.0f} {name:>8} {roots.size:6d} {matched(roots, exact):8d} {exact.size:6d} "
                f"{max_error(roots, exact):10.2e} "
                f"{seconds:9.4f} {ratio:>13}"
            )

    print(f"\nproven / floating-point find_roots, 64 roots (H = 200): {goal:.1f}x (goal: under 20x)")
    distributed_table(args.quick)


if __name__ == "__main__":
    main()
