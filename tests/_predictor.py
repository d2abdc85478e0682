"""The literal predictor of an output feedback from ``v(t, 0)``: an oracle that shares no code with
:mod:`nrobust.volterra` and :mod:`nrobust.hyperbolic.loops.output_feedback`.

For exponential signals (``z_m = e^{s theta}`` measured, commands ``e^{s theta}``) it predicts the
output of the delay form on the window ``(-w, 0]`` by solving the window's convolution equation
with the trapezoidal rule on ``M`` steps (second order: Richardson over two grids gives about
1e-10), and applies the law ``-law`` to the measured past and the prediction.
"""

from __future__ import annotations

import numpy as np

from nrobust.quasipoly import QuasiPolynomial


def gauss(lo: float, hi: float, pieces: int = 16, points: int = 30) -> tuple[np.ndarray, np.ndarray]:
    """Composite Gauss-Legendre points and weights on ``[lo, hi]``."""
    x, g = np.polynomial.legendre.leggauss(points)
    edges = np.linspace(lo, hi, pieces + 1)
    h = np.diff(edges)[:, None]
    return (edges[:-1, None] + h * (x + 1) / 2).ravel(), (h * g / 2).ravel()


def kernel_sum(q: QuasiPolynomial, nu: np.ndarray) -> np.ndarray:
    """The sum of the distributed kernels of ``q`` at ``nu`` (zero outside their supports)."""
    out = np.zeros(nu.shape)
    for d in q.distributed:
        inside = (nu >= d.a) & (nu <= d.b)
        if np.any(inside):
            out[inside] += d.kernel_at(nu[inside])
    return out


def literal_predictor(open_loop, law, window, s, M, observer_delay=0.0):
    """``(C_z, C_u)``: the law ``-law`` on the state predicted for ``z_m = e^{s theta}``, ``U_c = e^{s theta}``.

    ``open_loop = 1 - Phi = 1 - rho_q e^{-tau s} + int N e^{-nu s}``; the window is ``(-w, 0]``.
    """
    reflected = [(-c[0], d) for c, d in open_loop.point_terms if d > 0.0]
    tau = max(d.b for d in open_loop.distributed)  # the support of N~ (with rho q = 0 no point term at tau)
    rho_q_coef = reflected[0][0] if reflected else 0.0
    w = window
    h = w / M
    theta = -w + h * np.arange(M + 1)

    # the measured part: int over nu in [t + w, tau] of N(nu) e^{s (t - nu)}, every t of the window at once
    x, g = np.polynomial.legendre.leggauss(30)
    edges = theta[:, None] + w + (tau - theta[:, None] - w) * np.linspace(0.0, 1.0, 17)[None, :]
    width = np.diff(edges, axis=1)[:, :, None]
    nodes = edges[:, :-1, None] + width * (x + 1) / 2
    known = np.sum(
        width * g / 2 * kernel_sum(open_loop, nodes) * np.exp(s * (theta[:, None, None] - nodes)), axis=(1, 2)
    )
    f_z = rho_q_coef * np.exp(s * (theta - tau)) - known
    f_v = np.exp(s * (theta - observer_delay))
    lags = h * np.arange(M + 1)
    lags[-1] = np.nextafter(w, 0.0)  # the window's kernels: their left values at w
    n_lag = kernel_sum(open_loop, lags)
    i, j = np.tril_indices(M + 1)
    weights = np.where((j == 0) | (j == i), 0.5, 1.0) * h
    weights[i == 0] = 0.0
    T = np.eye(M + 1)
    T[i, j] += weights * n_lag[i - j]
    # the law -law = sum_point c e^{-d s} + int m e^{-nu s}: measured part and window part
    points = [(-c[0], d) for c, d in law.point_terms]
    x, g = gauss(w, max(d.b for d in law.distributed))
    measured = sum(c * np.exp(-s * d) for c, d in points) - np.sum(g * kernel_sum(law, x) * np.exp(-s * x))
    m_window = -kernel_sum(law, lags)
    trap = np.r_[0.5, np.ones(M - 1), 0.5] * h
    out = []
    for f, z in ((f_z, 1.0), (f_v, 0.0)):
        xs = np.linalg.solve(T, f)  # x at theta_0 = -w (its right limit) .. theta_M = 0
        out.append(z * measured + np.sum(trap * m_window * xs[::-1]))
    return out
