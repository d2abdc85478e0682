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


def test_predicted_convergence_saves_the_confirming_step_only():
    """``predict=True`` ends a point whose next step is predicted below the step test: one step
    fewer from a seed within 1e-6 of the root (the second step, 1e-13, ends it; without the
    prediction a third step of rounding size confirms it), the same root to rounding."""
    fdf = _poly([-2.0, 0.0, 1.0])  # s^2 - 2
    for seed in (1.414213, 1.4142135 + 1e-7j):
        plain: list[int] = []
        fast: list[int] = []
        s0 = newton(fdf, [seed], max_step=1.0, on_step=plain.append)
        s1 = newton(fdf, [seed], max_step=1.0, on_step=fast.append, predict=True)
        # the step test of both is 4 eps (1 + |s|): the roots agree to that, and to sqrt(2)
        np.testing.assert_allclose(s1, s0, rtol=0, atol=4 * np.finfo(float).eps * 3)
        np.testing.assert_allclose(s1, [np.sqrt(2.0)], rtol=0, atol=4 * np.finfo(float).eps * 3)
        assert len(fast) == len(plain) - 1


def test_prediction_waits_for_a_superlinear_contraction():
    """At a double root (steps halving, linear convergence) nothing is predicted while the steps
    halve: the point reaches the root as far as without the prediction (a double root of a
    rounded function is resolved to about sqrt(eps), 1.5e-8)."""
    fdf = _poly([1.0, -2.0, 1.0])  # (s - 1)^2
    kept = dict(accept_stalled=lambda x: np.abs(x - 1.0) < 1e-6)
    plain = newton(fdf, [3.0 + 1.0j], max_step=1.0, iters=40, **kept)
    fast = newton(fdf, [3.0 + 1.0j], max_step=1.0, iters=40, predict=True, **kept)
    np.testing.assert_allclose(fast, plain, rtol=0, atol=1.5e-8)
    np.testing.assert_allclose(fast, [1.0], rtol=0, atol=1.5e-8)
    # a first step cut to max_step predicts nothing: from 10 the steps are 0.5, ... as without it
    fdf = _poly([-1.0, 0.0, 1.0])
    counts: list[int] = []
    assert np.isnan(newton(fdf, [10.0], max_step=0.5, iters=3, on_step=counts.append, predict=True)[0])
    assert counts == [1, 1, 1]
