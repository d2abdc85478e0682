"""Several distributed terms integrated together (:func:`nrobust.distributed_delay.moment_integrals`).

Oracle: ``int nu^e N(nu) e^{-nu s} dnu`` of polynomial pieces by 40-digit quadrature (mpmath) on each
segment, written here. The batched values must also be the numbers of each term's own evaluation
(``F(s)``, ``-F.deriv_at(s)``), which the designs rely on to give the same results.

Tolerance: the Filon sums are exact for the interpolant up to rounding, about ``eps`` times the sum of the
moduli of their ``segments x degree`` terms; measured at most 6e-16 of ``S = int nu^e |N| e^{-nu Re s}``
here, so ``1e-13 S`` is loose for rounding and far below a misplaced column of coefficients (order ``S``).
"""

from __future__ import annotations

import mpmath
import numpy as np
import pytest

from nrobust.distributed_delay import DistributedDelay, moment_integrals

mpmath.mp.dps = 40
RTOL = 1e-13


def _kernels() -> list[DistributedDelay]:
    """Three kernels of degree 3 on one grid of 12 segments (the batched path), one of 4 segments (apart)."""
    rng = np.random.default_rng(7)
    nodes = np.linspace(0.0, 1.5, 13)
    shared = [
        DistributedDelay(nodes, None, interpolation="polynomial", coefficients=rng.uniform(-1.0, 1.0, (12, 4)))
        for _ in range(3)
    ]
    few = DistributedDelay(
        np.linspace(0.5, 2.0, 5), None, interpolation="polynomial", coefficients=rng.uniform(-1.0, 1.0, (4, 3))
    )
    return [*shared, few]


def _oracle(term: DistributedDelay, s: complex, extra: int) -> tuple[complex, float]:
    """The integral by mpmath (Gauss-Legendre on each segment, exact for a polynomial times a smooth
    function to 40 digits), and ``int nu^e |N| e^{-nu Re s}`` (the scale, in floating point)."""
    start, h, poly_t = term.pieces
    z = mpmath.mpc(s)

    def integrand(nu):
        i = min(int(np.searchsorted(start, float(nu), side="right")) - 1, start.size - 1)
        t = (nu - mpmath.mpf(float(start[i]))) / mpmath.mpf(float(h[i]))
        return sum(mpmath.mpf(float(c)) * t**j for j, c in enumerate(poly_t[i])) * nu**extra * mpmath.exp(-nu * z)

    edges = [mpmath.mpf(float(a)) for a in start] + [mpmath.mpf(float(start[-1] + h[-1]))]
    total = mpmath.quad(integrand, edges, method="gauss-legendre")
    nu = np.linspace(term.a, term.b, 4001)
    scale = float(np.trapezoid(np.abs(term.kernel_at(nu)) * nu**extra * np.exp(-nu * s.real), nu))
    return complex(total), scale


@pytest.mark.parametrize(
    "s",
    [
        np.array([0.0, 0.3 + 2.0j, -0.2 + 7.5j, 1j * 40.0, 0.1 - 13.0j]),  # direct sums
        0.05 + 1j * (3.0 + 0.25 * np.arange(80)),  # a uniform line: chirp-z transforms
    ],
    ids=["points", "line"],
)
def test_against_quadrature(s):
    terms = _kernels()
    out = moment_integrals(terms, s, (0, 1))
    check = (0, 2, 4) if s.size < 10 else (0, 79)
    for i, term in enumerate(terms):
        for j, extra in enumerate((0, 1)):
            assert out[i][j].shape == s.shape
            for k in check:
                value, scale = _oracle(term, complex(s[k]), extra)
                assert abs(out[i][j][k] - value) <= RTOL * scale, (i, extra, s[k])


def test_same_numbers_as_each_term():
    """Bit for bit the values of each term's own evaluation, for every path (batched, chirp-z, closed form)."""
    terms = _kernels()
    rng = np.random.default_rng(3)
    for s in (rng.uniform(-1, 1, 300) + 1j * rng.uniform(-60, 60, 300), 1j * (0.5 + np.arange(100) * 0.5)):
        out = moment_integrals(terms, s, (1, 0))
        for i, term in enumerate(terms):
            unit = term.replace(poly=[1.0])
            assert np.array_equal(out[i][1], unit(s))
            assert np.array_equal(out[i][0], -unit.deriv_at(s))


def test_empty():
    assert moment_integrals([], np.array([1j])) == []
    (row,) = moment_integrals(_kernels()[:1], np.zeros(0, dtype=complex), (0,))
    assert row[0].shape == (0,)


def test_long_line_in_rounds():
    """A chirp-z line of 5000 frequencies (several rounds of blocks) against the direct sums of the same terms
    (chunks of 50 points: an exponential matrix each). Measured 1.6e-14 of the largest value (the chirp's phase
    rounding on blocks of 1024 frequencies); ``1e-12`` is loose for it and far below a misplaced block."""
    rng = np.random.default_rng(5)
    nodes = np.linspace(0.0, 4.0, 97)
    terms = [
        DistributedDelay(nodes, None, interpolation="polynomial", coefficients=rng.uniform(-1.0, 1.0, (96, 12)))
        for _ in range(2)
    ]
    s = 1j * 2.0**-6 * np.arange(1, 5001)
    out = moment_integrals(terms, s, (0, 1))
    for i, term in enumerate(terms):
        for j, extra in enumerate((0, 1)):
            chunks = [moment_integrals([term], s[k : k + 50], (extra,))[0][0] for k in range(0, s.size, 50)]
            direct = np.concatenate(chunks)
            assert np.max(np.abs(out[i][j] - direct)) <= 1e-12 * np.max(np.abs(direct))


def test_shared_line_same_numbers_as_each_term():
    """Kernels on one uniform grid share ``phi`` on a chirp-z line (one per segment length and order): still bit
    for bit each term's own evaluation, on a line of several blocks (3000 frequencies: three blocks of 1024) and
    for both moments, whose ``phi`` of different orders are not shared."""
    rng = np.random.default_rng(11)
    nodes = np.linspace(0.0, 2.0, 49)
    terms = [
        DistributedDelay(nodes, None, interpolation="polynomial", coefficients=rng.uniform(-1.0, 1.0, (48, 12)))
        for _ in range(3)
    ]
    s = 0.01 + 1j * 2.0**-5 * np.arange(1, 3001)
    out = moment_integrals(terms, s, (0, 1))
    for i, term in enumerate(terms):
        unit = term.replace(poly=[1.0])
        assert np.array_equal(out[i][0], unit(s))
        assert np.array_equal(out[i][1], -unit.deriv_at(s))
