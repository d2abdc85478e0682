"""The one Newton iteration of nrobust (nrobust._newton), shared by the root finder and
the spectral bound of difference operators."""

from __future__ import annotations

import numpy as np

from nrobust._newton import newton


def _poly(coefs):
    p = np.polynomial.Polynomial(coefs)
    dp = p.deriv()
    return lambda x: (p(x), dp(x))


def test_converges_to_simple_roots_from_every_seed():
    fdf = _poly([-1.0, 0.0, 1.0])  # s^2 - 1
    s = newton(fdf, [0.7 + 0.1j, -1.6 - 0.2j, 3.0], max_step=10.0)
    np.testing.assert_allclose(s, [1.0, -1.0, 1.0], rtol=0, atol=1e-14)


def test_step_limit_and_work_accounting():
    fdf = _poly([-1.0, 0.0, 1.0])
    counts: list[int] = []
    # from 10 + 0j the first Newton step is 4.95 long: cut to 0.5, iterations continue
    s = newton(fdf, [10.0], max_step=0.5, iters=3, on_step=counts.append)
    assert np.isnan(s[0])  # three short steps do not reach the root
    assert counts == [1, 1, 1]
    s = newton(fdf, [10.0], max_step=0.5, iters=60)
    np.testing.assert_allclose(s, [1.0], rtol=0, atol=1e-14)


def test_stalled_points_kept_only_when_accepted():
    fdf = _poly([0.0, 0.0, 0.0, 1.0])  # s^3: a triple root converges linearly
    seeds = [0.5 + 0.5j]
    assert np.isnan(newton(fdf, seeds, max_step=1.0, iters=20)[0])
    kept = newton(fdf, seeds, max_step=1.0, iters=20, accept_stalled=lambda x: np.abs(x) < 1e-3)
    np.testing.assert_allclose(kept, [(0.5 + 0.5j) * (2 / 3) ** 20], rtol=1e-12)


def test_non_finite_step_gives_nan():
    fdf = _poly([1.0, 0.0, 1.0])  # s^2 + 1: f'(0) = 0
    s = newton(fdf, [0.0, 0.1 + 0.9j], max_step=1.0)
    assert np.isnan(s[0])
    np.testing.assert_allclose(s[1], 1j, rtol=0, atol=1e-14)
