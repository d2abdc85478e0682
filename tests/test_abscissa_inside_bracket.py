"""A spectral abscissa never lies outside its own proven bracket (issue reproducer: with ``rigorous=True`` the
value of ``1 + 0.5 e^{-s} + 0.5 e^{-(1 + 1e-12) s}``'s loop lay outside its ``value_bracket``).

The helper that enforces it is private; its test is kept apart from the public behaviour's
(``tests/test_close_delays_clusters.py``), whose module imports public names only.
"""

from __future__ import annotations

import pytest

from nrobust import CertificationError
from nrobust.roots.abscissa import SpectralAbscissa, _inside_bracket


def test_a_value_off_its_proven_bracket_is_refused() -> None:
    sa = SpectralAbscissa(-5.2e-5, complex(-5.2e-5, 97.4), False, -0.69, 0.01, True, (0, 1, 0, 1))
    with pytest.raises(CertificationError, match="outside its proven bracket"):
        _inside_bracket(sa, (1e-6, 0.01))
    # off by rounding only: moved onto the bracket
    near = _inside_bracket(sa, (-5.2e-5 + 1e-15, 0.01))
    assert near.value == -5.2e-5 + 1e-15
