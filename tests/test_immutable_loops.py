"""The loop data classes keep read-only copies of their arrays: results kept for an object stay its own.

:class:`~nrobust.quasipoly.QuasiPolynomial`, :class:`~nrobust.distributed_delay.DistributedDelay`,
:class:`~nrobust.qpmatrix.QuasiPolynomialMatrix` (and its :class:`~nrobust.qpmatrix.ExpandedDeterminant`),
:class:`~nrobust.difference.DifferenceOperator` and
:class:`~nrobust.matrix_difference.MatrixDifferenceOperator` keep results per object (a derivative, a
tensor of coefficients, segment groups, the gaps and tails of the spectral abscissa keyed by the object's
identity, the last batch of values). An in-place write into an array they keep raises numpy's
``ValueError``; the caller's arrays are copied, stay writable, and writing them changes nothing.

Oracles: closed forms evaluated with ``cmath``, the 40-digit closed form of
``int_0^1 nu e^{-nu s} dnu`` and the Lambert W function of mpmath for the rightmost root of
``s + c e^{-s}`` (``s e^s = -c``: ``s = W_0(-c)``), none sharing code with nrobust. Tolerance: the
evaluations are sums of a few terms, each a few roundings; their errors, measured on every check
here, are at most ``7.1e-17`` of the sum of the moduli of the terms (0 for most), so ``1e-14`` of it
holds with a margin above 100, while the writes tried change a coefficient by more than a tenth.
"""

from __future__ import annotations

import cmath
import dataclasses
from typing import Any

import mpmath as mp
import numpy as np
import pytest

from nrobust import DistributedDelay, QuasiPolynomial, QuasiPolynomialMatrix
from nrobust.difference import DifferenceOperator
from nrobust.matrix_difference import MatrixDifferenceOperator
from nrobust.roots import spectral_abscissa

S = np.array([0.3 + 2.0j, 1.0 - 5.0j, 4.0j, -0.7 + 0.1j])
RTOL = 1e-14
READ_ONLY = "read-only"


def _close(got: Any, want: list[complex], scale: list[float]) -> None:
    """``|got - want| <= RTOL scale`` entrywise (``scale``: the sum of the moduli of the terms)."""
    got = np.asarray(got, dtype=complex)
    assert got.shape == (len(want),)
    for g, w, m in zip(got.tolist(), want, scale):
        assert abs(g - w) <= RTOL * m, (g, w)


def _arrays(obj: Any, seen: set[int] | None = None) -> list[np.ndarray]:
    """Every ndarray an object keeps: its attributes (cached ones included), walked through tuples,
    lists, dicts, dataclasses and nrobust objects."""
    seen = set() if seen is None else seen
    if id(obj) in seen:
        return []
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        return [obj]
    if isinstance(obj, (tuple, list)):
        return [a for x in obj for a in _arrays(x, seen)]
    if isinstance(obj, dict):
        return [a for x in obj.values() for a in _arrays(x, seen)]
    if type(obj).__module__.startswith("nrobust") and hasattr(obj, "__dict__"):
        return [a for x in vars(obj).values() for a in _arrays(x, seen)]
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return [a for f in dataclasses.fields(obj) for a in _arrays(getattr(obj, f.name), seen)]
    return []


def _all_read_only(obj: Any) -> int:
    """The number of arrays ``obj`` keeps, after asserting each is read-only."""
    arrays = _arrays(obj)
    for a in arrays:
        assert not a.flags.writeable, a
    return len(arrays)


# ---------------------------------------------------------------------- QuasiPolynomial
def _qp_oracle(c: float) -> tuple[list[complex], list[float]]:
    """``s + c e^{-s}`` at S, and the sums of the moduli of its terms."""
    return [s + c * cmath.exp(-s) for s in S.tolist()], [abs(s) + abs(c * cmath.exp(-s)) for s in S.tolist()]


def test_quasipolynomial_arrays_are_read_only_copies() -> None:
    p0, p1 = np.array([0.0, 1.0]), np.array([0.5])
    F = QuasiPolynomial([p0, p1], [0.0, 1.0])
    F(S), F.deriv_at(S), F.abs_bound(S, S + 0.1), F.deriv_bound(S, S + 0.1), F.magnitude(S), F.derivative()
    with pytest.raises(ValueError, match=READ_ONLY):
        F.coefs[1][0] = 2.0
    with pytest.raises(ValueError, match=READ_ONLY):
        F.point_terms[0][0][1] = 3.0
    with pytest.raises(ValueError, match=READ_ONLY):
        F.derivative().coefs[0][0] = 3.0
    assert _all_read_only(F) >= 2 + 3  # the coefficients and the cached tensor (delays, Taylor rows, moduli)
    # the caller's arrays are not the object's: writable, and writing them changes nothing
    assert p0.flags.writeable and p1.flags.writeable
    p1[0], p0[1] = 2.0, 7.0
    _close(F(S), *_qp_oracle(0.5))
    assert F.coefs[1].tolist() == [0.5] and F.coefs[0].tolist() == [0.0, 1.0]


def test_quasipolynomial_radii_and_coefficient_array() -> None:
    r0, r1 = np.array([0.0, 1e-10]), np.array([2e-10])
    F = QuasiPolynomial([[0.0, 1.0], [0.5]], [0.0, 1.0], radii=[r0, r1])
    with pytest.raises(ValueError, match=READ_ONLY):
        F.point_radii[1][0] = 0.0
    assert r1.flags.writeable
    r1[0] = 1.0
    assert F.point_radii[1].tolist() == [2e-10]
    # from_coefficient_array: the entries' coefficients are copies of the array, read-only
    coefs = np.array([[[[0.0, 1.0], [0.5, 0.0]]]])  # one entry: s + 0.5 e^{-s}
    (entry,) = QuasiPolynomial.from_coefficient_array(coefs, [0.0, 1.0])[0]
    with pytest.raises(ValueError, match=READ_ONLY):
        entry.coefs[1][0] = 2.0
    coefs[0, 0, 1, 0] = 2.0
    _close(entry(S), *_qp_oracle(0.5))


def _rightmost_real_part(c: float) -> float:
    """``Re W_0(-c)``: the rightmost root of ``s + c e^{-s}`` (``s e^s = -c``), to 40 digits."""
    with mp.workdps(40):
        return float(mp.re(mp.lambertw(-mp.mpf(c))))


def test_cached_abscissa_stays_the_objects_own() -> None:
    """The reproducer: the in-place write used to succeed, leaving ``F.coefs`` at the new numbers while the
    evaluations (the cached tensor) and the abscissa stayed those of the old ones."""
    F = QuasiPolynomial([np.array([0.0, 1.0]), np.array([0.5])], [0.0, 1.0])
    before = spectral_abscissa(F)
    assert abs(before.value - _rightmost_real_part(0.5)) <= before.accuracy
    with pytest.raises(ValueError, match=READ_ONLY):
        F.coefs[1][0] = 2.0
    after = spectral_abscissa(F)
    assert after.value == before.value
    assert F.coefs[1].tolist() == [0.5]
    _close(F(S), *_qp_oracle(0.5))
    # the modified numbers are another object, with its own abscissa
    G = QuasiPolynomial([[0.0, 1.0], [2.0]], [0.0, 1.0])
    other = spectral_abscissa(G)
    assert abs(other.value - _rightmost_real_part(2.0)) <= other.accuracy
    assert other.value - before.value > 0.9  # 0.1728 against -0.7940
    _close(G(S), *_qp_oracle(2.0))


# ---------------------------------------------------------------------- DistributedDelay
def _ramp_oracle() -> tuple[list[complex], list[float]]:
    """``int_0^1 nu e^{-nu s} dnu = (1 - (1 + s) e^{-s}) / s^2`` at S (40 digits), and the bound
    ``int_0^1 nu |e^{-nu s}| dnu`` of the moduli."""
    out, scale = [], []
    with mp.workdps(40):
        for s in S.tolist():
            z = mp.mpc(s.real, s.imag)
            out.append(complex((1 - (1 + z) * mp.exp(-z)) / z**2))
            x = z.real  # int_0^1 nu e^{-nu x} dnu: the same closed form at real x (1/2 at 0)
            scale.append(float((1 - (1 + x) * mp.exp(-x)) / x**2) if x else 0.5)
    return out, scale


@pytest.mark.parametrize("interpolation", ["linear", "cubic", "polynomial"])
def test_distributed_delay_arrays_are_read_only_copies(interpolation: str) -> None:
    """``N(nu) = nu`` on ``[0, 1]``: each interpolation holds it exactly."""
    nodes = np.linspace(0.0, 1.0, 5)
    values = nodes.copy()
    coefficients = np.stack([nodes[:-1], np.diff(nodes)], axis=1)  # nu = nu_i + h t on segment i
    given = {"coefficients": coefficients} if interpolation == "polynomial" else {"values": values}
    d = DistributedDelay(nodes, given.get("values"), [1.0], 0, interpolation, coefficients=given.get("coefficients"))
    want, scale = _ramp_oracle()
    _close(d(S), want, scale)
    moment = d.abs_moment(np.array([0.0, 0.5]))  # kept per real part
    assert moment[0] >= 0.5 * (1.0 - 1e-15)  # an upper bound of int_0^1 nu dnu
    d.deriv_at(S), d.decay_bound(0.0, 3.0), d.variation_bound(0.0)
    d.second_order_variation(), d.asymptotic_terms(), QuasiPolynomial([[1.0]], [0.0], [d]).deriv_bound(S, S + 0.1)
    for name in ("nodes", "values", "poly"):
        with pytest.raises(ValueError, match=READ_ONLY):
            getattr(d, name)[0] = 5.0
    with pytest.raises(ValueError, match=READ_ONLY):
        d.pieces[2][0, 0] = 5.0
    assert _all_read_only(d) >= 6 + 2  # the fields, the pieces and the cached groups and end terms
    for a in (nodes, values, coefficients):
        assert a.flags.writeable
        a[...] = 7.0
    _close(d(S), want, scale)
    assert d.abs_moment(np.array([0.0, 0.5])).tolist() == moment.tolist()
    assert d.nodes.tolist() == np.linspace(0.0, 1.0, 5).tolist()


def test_distributed_algebra_keeps_read_only_arrays() -> None:
    d = DistributedDelay(np.linspace(0.0, 1.0, 5), np.linspace(0.0, 1.0, 5), radius=1e-12)
    for term in (d.times(3.0), d.plus(d), d.shift(0.25)[0], d.restricted(0.3), d.replace(moment=1)):
        assert term is not None
        assert _all_read_only(term) >= 6


# ---------------------------------------------------------------------- matrices
def test_matrix_and_expanded_determinant_results_are_not_their_caches() -> None:
    """A returned value is the caller's: writing it leaves the batch the matrix keeps (before, the 1 x 1
    determinant and the expanded determinant's values were views of it, and the next call returned the
    written numbers)."""
    s = QuasiPolynomial([[0.0, 1.0]], [0.0])
    M = QuasiPolynomialMatrix([[s + QuasiPolynomial([[0.5]], [1.0])]])
    want, scale = _qp_oracle(0.5)
    first = M(S)
    first[:] = 0.0
    _close(M(S), want, scale)
    with pytest.raises(ValueError, match=READ_ONLY):
        M.entries[0][0].coefs[1][0] = 2.0
    M.deriv_at(S), M.deriv_bound(S, S + 0.1), M.magnitude(S), M.principal_part()
    assert _all_read_only(M) >= 5

    # det [[s + 1, e^{-s}], [0.5 e^{-s/2}, s + 2]] = (s + 1)(s + 2) - 0.5 e^{-1.5 s}
    M2 = QuasiPolynomialMatrix([[s + 1.0, QuasiPolynomial([[1.0]], [1.0])], [QuasiPolynomial([[0.5]], [0.5]), s + 2.0]])
    Q = M2.exact_expansion()
    assert Q is not None
    pts = S.tolist()
    det = [(z + 1) * (z + 2) - 0.5 * cmath.exp(-1.5 * z) for z in pts]
    det_scale = [abs(z * z) + 3 * abs(z) + 2 + abs(0.5 * cmath.exp(-1.5 * z)) for z in pts]
    slope = [2 * z + 3 + 0.75 * cmath.exp(-1.5 * z) for z in pts]
    slope_scale = [2 * abs(z) + 3 + abs(0.75 * cmath.exp(-1.5 * z)) for z in pts]
    for f, w, m in ((Q, det, det_scale), (Q.deriv_at, slope, slope_scale), (M2, det, det_scale)):
        values = f(S)
        values[:] = 0.0
        _close(f(S), w, m)
    Q.deriv_bound(S, S + 0.1), Q.magnitude(S), Q.poly, Q.principal_part()
    assert _all_read_only(Q) >= 8
    assert _all_read_only(M2) >= 5


def test_expanded_determinant_from_coefficients_copies() -> None:
    from nrobust.qpmatrix import ExpandedDeterminant

    coefs = np.zeros((1, 1, 2, 2))
    coefs[0, 0, 0] = [0.0, 1.0]
    coefs[0, 0, 1] = [0.5, 0.0]  # s + 0.5 e^{-s}
    Q = ExpandedDeterminant.from_coefficients(coefs, [0.0, 1.0])
    assert Q is not None
    coefs[0, 0, 1, 0] = 2.0
    _close(Q(S), *_qp_oracle(0.5))
    _close(Q.matrix(S), *_qp_oracle(0.5))
    assert Q.max_delay == 1.0
    assert _all_read_only(Q) >= 7


# ---------------------------------------------------------------------- difference operators
def test_difference_operator_arrays_are_read_only_copies() -> None:
    a, t = np.array([1.0, -0.5, 0.25]), np.array([0.0, 1.0, 2.0])
    D = DifferenceOperator(a, t)
    want = [1 - 0.5 * cmath.exp(-z) + 0.25 * cmath.exp(-2 * z) for z in S.tolist()]
    scale = [1 + abs(0.5 * cmath.exp(-z)) + abs(0.25 * cmath.exp(-2 * z)) for z in S.tolist()]
    for name in ("coefs", "delays"):
        with pytest.raises(ValueError, match=READ_ONLY):
            getattr(D, name)[0] = 5.0
    assert a.flags.writeable and t.flags.writeable
    a[:], t[:] = 9.0, [0.0, 3.0, 4.0]
    _close(D(S), want, scale)
    assert D.gamma_0 == 0.75  # (0.5 + 0.25) / 1, exact in binary
    assert len(D.chains()) == 2  # 1 - 0.5 z + 0.25 z^2: two roots


def test_matrix_difference_operator_arrays_are_read_only_copies() -> None:
    A, t = np.array([[[0.0, 0.5], [0.25, 0.0]]]), np.array([1.0])
    D = MatrixDifferenceOperator(A, t)
    want = [1 - 0.125 * cmath.exp(-2 * z) for z in S.tolist()]  # det(I - A e^{-s})
    scale = [1 + abs(0.125 * cmath.exp(-2 * z)) for z in S.tolist()]
    with pytest.raises(ValueError, match=READ_ONLY):
        D.coefs[0, 0, 1] = 5.0
    with pytest.raises(ValueError, match=READ_ONLY):
        D.delays[0] = 5.0
    assert A.flags.writeable and t.flags.writeable
    A[:], t[:] = 3.0, 2.0
    _close(D(S), want, scale)
    assert D.delays.tolist() == [1.0]


# ---------------------------------------------------------------------- copies
def _loop_objects() -> list[Any]:
    """One of each class, with its caches built."""
    s = QuasiPolynomial([[0.0, 1.0]], [0.0])
    kernel = DistributedDelay(np.linspace(0.0, 1.0, 5), np.linspace(0.0, 1.0, 5))
    F = QuasiPolynomial([[0.0, 1.0], [0.5]], [0.0, 1.0], [kernel])
    M = QuasiPolynomialMatrix([[s + 1.0, QuasiPolynomial([[1.0]], [1.0])], [QuasiPolynomial([[0.5]], [0.5]), s + 2.0]])
    Q = M.exact_expansion()
    D, MD = DifferenceOperator([1.0, -0.5], [0.0, 1.0]), MatrixDifferenceOperator([[[0.0, 0.5], [0.25, 0.0]]], [1.0])
    for f in (F, M, Q, D, MD, kernel):
        f(S)
    F.deriv_bound(S, S + 0.1), F.derivative(), M.deriv_bound(S, S + 0.1), Q.deriv_bound(S, S + 0.1)
    return [F, kernel, M, Q, D, MD]


@pytest.mark.parametrize("how", ["pickle", "deepcopy", "copy"])
def test_copies_keep_read_only_arrays(how: str) -> None:
    """numpy's pickles drop the read-only flag: an unpickled or copied object marks its arrays again."""
    import copy
    import pickle

    duplicate = {"pickle": lambda x: pickle.loads(pickle.dumps(x)), "deepcopy": copy.deepcopy, "copy": copy.copy}[how]
    for obj in _loop_objects():
        twin = duplicate(obj)
        assert _all_read_only(twin) >= 2
        _close(twin(S), obj(S).tolist(), np.abs(obj(S)).tolist())
