"""Many seeds on few roots: Newton's repeated limit points do not blow up the merge of candidates."""

import numpy as np

from nrobust import QuasiPolynomial, find_roots


def test_hundred_thousand_seeds_on_two_roots() -> None:
    # (s - 1)(s + 1/2): 100,001 seeds converge to two roots; the pair search of the merge
    # asked for 29 GiB before repeats were dropped (a MemoryError).
    F = QuasiPolynomial([[-0.5, -0.5, 1.0]], [0.0])
    res = find_roots(F, (-2.0, 2.0, -1.0, 1.0), seeds=np.linspace(-1.5, 1.5, 100_001))
    assert res.certified
    np.testing.assert_allclose(np.sort(res.roots.real), [-0.5, 1.0], rtol=0, atol=1e-14)  # closed form
    np.testing.assert_allclose(res.roots.imag, 0.0, atol=1e-14)
