"""The cases of the floating-point tests of roots, abscissae, crossings and margins, in one place.

Gathered from ``test_roots.py``, ``test_abscissa.py``, ``test_margins.py`` and
``test_crossings.py`` (their closed-form families at the parameters those tests use), so
that ``test_rigorous_corpus.py`` can run every one of them through the floating-point and
the ball-arithmetic paths and compare. Each entry is ``name -> (case, fast)``: ``fast``
cases run in CI, the others only under ``-m long`` (``make fuzz``).
"""

from __future__ import annotations

import numpy as np

from nrobust import DistributedDelay, QuasiPolynomial

QP = QuasiPolynomial
Region = tuple[float, float, float, float]

NEUTRAL = QP([[1.0], [-0.85], [0.1]], [0.0, 2.0, 2.1])


def synthetic_kernel() -> DistributedDelay:
    """A piecewise-linear N~ on [0, 2] with a jump at nu = 1 (``test_margins.synthetic_kernel``)."""
    x1, x2 = np.linspace(0.0, 1.0, 41), np.linspace(1.0, 2.0, 41)
    return DistributedDelay(np.r_[x1, x2], np.r_[0.6 * np.cos(2 * x1) + 0.3, -0.5 + 0.4 * x2])


JUMP = DistributedDelay([0.0, 0.5, 1.0, 1.0, 1.5], [0.3, -0.2, 0.1, -0.4, 0.2])
CUBIC = DistributedDelay(
    np.r_[np.linspace(0.0, 1.0, 21), np.linspace(1.0, 1.5, 6)],
    np.r_[np.cos(3 * np.linspace(0.0, 1.0, 21)), 0.5 * np.sin(np.linspace(1.0, 1.5, 6))],
    interpolation="cubic",
)

# ---------------------------------------------------------------- roots: (F, region)
ROOTS: dict[str, tuple[tuple[QuasiPolynomial, Region], bool]] = {
    "neutral-64": ((NEUTRAL, (-3.0, 1.0, -0.5, 200.0)), False),
    "neutral-50": ((NEUTRAL, (-3.0, 1.0, -0.5, 50.0)), True),
    # 1 - a e^{-tau s} (test_roots: closed-form chains)
    **{
        f"single a={a} tau={tau}": ((QP([[1.0], [-a]], [0.0, tau]), (-3.0, 2.0, -0.5, 40.0)), tau == 1.0)
        for a, tau in [(2.0, 1.0), (0.3, 2.5), (-0.5, 1.0), (-3.0, 0.7)]
    },
    # s + a + b e^{-tau s} (test_roots: Lambert W)
    **{
        f"lambert a={a} b={b} tau={tau}": ((QP([[a, 1.0], [b]], [0.0, tau]), (-6.0, 2.0, -0.5, 30.0)), b == 2.0)
        for a, b, tau in [(1.0, 2.0, 1.0), (-0.5, 0.3, 2.0), (0.2, -1.5, 0.5), (0.0, 1.0, 1.0)]
    },
    # test_roots._CROSS_CASES
    "neutral-degree-1": ((QP([[1.0, 1.0], [0.0, -0.85], [0.3, 0.1]], [0.0, 2.0, 2.1]), (-3.0, 1.0, -0.5, 60.0)), True),
    "incommensurate": ((QP([[1.0], [0.6], [0.3]], [0.0, 1.0, np.sqrt(2.0)]), (-3.0, 1.0, -0.5, 60.0)), False),
    "distributed-jump": ((QP([[1.0], [-0.4]], [0.0, 1.5], [JUMP]), (-3.0, 1.0, -0.5, 60.0)), True),
    "cubic-kernel": ((QP([[1.0, 1.0], [0.3]], [0.0, 1.0], [CUBIC]), (-2.0, 1.0, -0.5, 20.0)), False),
    # two separate roots 1.5e-5 apart (test_roots: contour moments separate them)
    "close pair": ((QP([[1 + 1.5e-5, -(2 + 1.5e-5), 1.0]], [0.0]), (0.0, 2.5, -1.0, 1.0)), True),
}

# ---------------------------------------------------------------- abscissae: F
ABSCISSAE: dict[str, tuple[QuasiPolynomial, bool]] = {
    "neutral": (NEUTRAL, True),
    **{
        f"lambert a={a} b={b} tau={tau}": (QP([[a, 1.0], [b]], [0.0, tau]), tau == 1.0)
        for a, b, tau in [(1.0, 2.0, 1.0), (0.5, 0.5, 14.0), (0.3, -1.0, 1.0)]
    },
    "kernel": (QP([[1.0, 1.0], [0.3]], [0.0, 1.0], [CUBIC]), False),
    # test_abscissa._POLYNOMIALS (exact route through FLINT)
    "s + 3000": (QP([[3000.0, 1.0]], [0.0]), True),
    "mixed scales": (
        QP([list(np.polynomial.polynomial.polyfromroots([-5.0, -2e-3, 0.5 + 3j, 0.5 - 3j, 40.0]).real)], [0.0]),
        False,
    ),
}

# ---------------------------------------------------------------- margins: (A, B, delta_max)
MARGINS: dict[str, tuple[tuple[QuasiPolynomial, QuasiPolynomial, float | None], bool]] = {
    # s + a + b e^{-delta s}: arccos(-a/b) / sqrt(b^2 - a^2)
    **{
        f"first-order a={a} b={b}": ((QP([[a, 1.0]], [0.0]), QP([[b]], [0.0]), None), a == 1.0)
        for a, b in [(1.0, 2.0), (0.5, 3.0), (-0.2, 1.0), (0.0, 1.5), (3.0, 3.5), (1.0, 0.5), (2.0, -1.9)]
    },
    # s^2 + a s + b + c e^{-delta s}: stability windows
    "second-order": ((QP([[1.0, 0.1, 1.0]], [0.0]), QP([[0.5]], [0.0]), 12.0), True),
    # transport loop of eq. (13): 1 - rho q e^{-2 s} + K q e^{-(2 + delta) s}
    **{
        f"transport rho_q={r} kq={k}": ((QP([[1.0], [-r]], [0.0, 2.0]), QP([[k]], [2.0]), None), (r, k) == (0.85, 0.1))
        for r, k in [(0.85, 0.1), (0.85, -0.14), (-0.6, 0.3), (0.85, 0.2)]
    },
    # a distributed kernel in both factors
    "distributed": (
        (
            1.0 - (QP([[0.85]], [2.0]) - QP([], [], [synthetic_kernel()])),
            QP([[0.1]], [2.0]) - QP([], [], [synthetic_kernel()]),
            None,
        ),
        False,
    ),
}

# ---------------------------------------------------------------- crossings: (A, B) (test_crossings)
TANGENT_A = QP([[10.0, 2.0, 1.0]], [0.0])  # |A|^2 - 36 = (w^2 - 8)^2: a double zero at 2 sqrt 2 for c = 6
CROSSINGS: dict[str, tuple[tuple[QuasiPolynomial, QuasiPolynomial], bool]] = {
    "golden ratio": ((QP([[1.0, 0.0, 1.0]], [0.0]), QP([[0.0, 1.0]], [0.0])), True),
    "tangency c=6": ((TANGENT_A, QP([[6.0]], [0.0])), True),
    "near tangency 1e-6 below": ((TANGENT_A, QP([[6.0 * (1 - 1e-6)]], [0.0])), True),
    "pair born 1e-6 above": ((TANGENT_A, QP([[6.0 * (1 + 1e-6)]], [0.0])), True),
    "second-order": ((QP([[1.0, 0.1, 1.0]], [0.0]), QP([[0.5]], [0.0])), True),
    "transport": ((QP([[1.0], [-0.85]], [0.0, 2.0]), QP([[-0.14]], [2.0])), True),
    "distributed": (
        (
            1.0 - (QP([[0.85]], [2.0]) - QP([], [], [synthetic_kernel()])),
            QP([[0.1]], [2.0]) - QP([], [], [synthetic_kernel()]),
        ),
        False,
    ),
}


def cases(table: dict, long: bool) -> list[str]:
    """The names of ``table`` to run: all of them with ``long``, else the fast ones."""
    return sorted(name for name, (_, fast) in table.items() if long or fast)
