"""QuasiPolynomial and DistributedDelay against closed forms and mpmath quadrature."""

from __future__ import annotations

import itertools

import mpmath as mp
import numpy as np
import pytest

from nrobust import DistributedDelay, ParameterError, QuasiPolynomial
from nrobust.distributed_delay import _phi
from nrobust.quasipoly import as_quasipolynomial

RNG = np.random.default_rng(7)
S_SAMPLES = np.array([0.3 + 0.2j, -1.0 + 5.0j, 2.0 - 100.0j, 0.05j, -0.4 + 0.0j, 0.7 + 3000.0j])


def _jump_kernel() -> DistributedDelay:
    """A kernel with a jump at nu = 1, like N~ at nu = 1/mu (paper eq. (40))."""
    left = np.linspace(0.0, 1.0, 11)
    right = np.linspace(1.0, 2.5, 16)
    return DistributedDelay(np.r_[left, right], np.r_[np.sin(left), 2.0 + np.cos(right)])


def _short_jump_kernel() -> DistributedDelay:
    """Short support (cheap mpmath reference at |Im s| = 1e4), jump at nu = 0.1."""
    left = np.linspace(0.0, 0.1, 5)
    right = np.linspace(0.1, 0.25, 7)
    return DistributedDelay(np.r_[left, right], np.r_[np.sin(9 * left), 2.0 + np.cos(9 * right)])


def _mp_integral(d: DistributedDelay, s: complex, weight_power: int = 0) -> complex:
    """int nu^k N(nu) e^{-nu s} dnu for the linear interpolant, by mpmath quadrature.

    Composite 10-point Gauss-Legendre in 20-digit arithmetic on pieces of half a period
    of e^{-i Im(s) nu}: on each piece the integrand is a smooth function with a phase change
    below pi, where the rule is exact to ~1e-18 relative.
    """
    mp.mp.dps = 20
    x, w = np.polynomial.legendre.leggauss(10)
    sm = mp.mpc(s)
    total = mp.mpc(0)
    for a, b, fa, fb in zip(d.nodes[:-1], d.nodes[1:], d.values[:-1], d.values[1:]):
        if b == a:
            continue
        pieces = int(np.ceil((b - a) * max(abs(s.imag), 1.0) / np.pi))
        edges = np.linspace(a, b, pieces + 1)
        for lo, hi in itertools.pairwise(edges):
            half = mp.mpf(hi - lo) / 2
            mid = mp.mpf(hi + lo) / 2
            for xk, wk in zip(x, w):
                nu = mid + half * xk
                n_val = fa + (fb - fa) * (nu - a) / (b - a)
                total += wk * half * n_val * nu**weight_power * mp.exp(-nu * sm)
    return complex(total)


def test_phi_series_and_recursion_agree_across_threshold():
    # Just inside and outside the series radius the two formulas must agree to rounding.
    z_in = np.exp(1j * np.linspace(0, 2 * np.pi, 13)) * (1 - 1e-12)
    z_out = z_in * (1 + 2e-12)
    assert np.max(np.abs(_phi(z_in, 3) - _phi(z_out, 3))) < 1e-11


@pytest.mark.parametrize("near", [0, 1, 10, 24])
def test_phi_against_quadrature_for_high_orders(near):
    """``phi_k(z)``, ``k <= 9`` (the exact kernels' degree-9 pieces), at 24 points, ``near`` of them with
    ``|z| < 3`` (each mix takes another path: recursion only, on all points, on the far ones, series only),
    against 40-digit quadrature. The recursion amplifies rounding by about ``k! / |z|^k`` (18 at ``k = 9``,
    ``|z| = 3``): measured 1.5e-13 relative there, 4e-16 at ``k = 0``."""
    rng = np.random.default_rng(7)
    far = rng.uniform(3.0, 40.0, 24 - near) * np.exp(1j * rng.uniform(-1.6, 1.6, 24 - near))
    close = rng.uniform(0.0, 2.99, near) * np.exp(1j * rng.uniform(-np.pi, np.pi, near))
    z = rng.permutation(np.concatenate([far, close]))
    got = _phi(z, 9)
    for k in (0, 9):
        with mp.workdps(40):
            ref = np.array([complex(mp.quad(lambda t, k=k, v=v: t**k * mp.exp(-mp.mpc(v) * t), [0, 1])) for v in z])
        # order k: 1e-15 growing to 1e-12 at k = 9 (ten times the largest error measured)
        np.testing.assert_allclose(got[k], ref, rtol=1e-15 * 2.2**k, atol=0)


@pytest.mark.parametrize("s", [0.5 + 1e4j, -0.3 + 1234.5j, 2.0 - 7777.0j])
def test_distributed_exact_at_high_frequency(s):
    """Filon-type evaluation is exact for the interpolant: no error growth with |Im s|."""
    d = _short_jump_kernel()
    ref = _mp_integral(d, s)
    assert abs(d(s) - ref) <= 1e-13 * max(1.0, abs(ref)) + 1e-15


def test_moment_terms_against_mpmath():
    d = _jump_kernel()
    d2 = DistributedDelay(d.nodes, d.values, moment=2)
    for s in (0.2 + 3.0j, -0.5 + 250.0j):
        assert abs(d2(s) - _mp_integral(d, s, 2)) < 1e-12


def test_closed_form_distributed_delay():
    """s + k (1 - e^{-sT})/(sT) = s + (k/T) int_0^T e^{-nu s} dnu."""
    k, T = 2.0, 1.5
    F = QuasiPolynomial([[0, 1]], [0], [DistributedDelay([0, T], [k / T, k / T])])
    s = S_SAMPLES
    exact = s + k * (1 - np.exp(-s * T)) / (s * T)
    assert np.max(np.abs(F(s) - exact)) < 1e-13
    # At s -> 0 the closed form loses digits; the Filon series does not.
    assert abs(F(1e-12) - (1e-12 + k * (1 - 1e-12 * T / 2))) < 1e-15


def test_qpmr_convention():
    F = QuasiPolynomial([[0, 1], [1]], [0, 1])  # s + e^{-s}
    s = S_SAMPLES
    np.testing.assert_allclose(F(s), s + np.exp(-s), rtol=1e-15, atol=0)


def test_derivative_matches_evaluation_and_finite_differences():
    d = _jump_kernel()
    F = QuasiPolynomial([[1, 0.5, 2.0], [-0.85, 0.1]], [0, 2], [d.times_poly([0.3, 1.0])])
    s = S_SAMPLES[:5]
    dF = F.derivative()
    assert np.max(np.abs(dF(s) - F.deriv_at(s))) < 1e-12 * np.max(np.abs(F.deriv_at(s)))
    h = 1e-5
    fd = (F(s + h) - F(s - h)) / (2 * h)
    assert np.max(np.abs(fd - F.deriv_at(s)) / np.abs(F.deriv_at(s))) < 1e-8


def test_algebra_shift_sum_product():
    d = _jump_kernel()
    F = QuasiPolynomial([[0, 1]], [0], [d])
    G = QuasiPolynomial([[1], [-0.85], [0.1]], [0, 2, 2.1])
    z = np.array([0.2 + 3j, -0.7 + 40j])
    np.testing.assert_allclose((F * G)(z), F(z) * G(z), rtol=1e-13, atol=0)
    np.testing.assert_allclose((F + G)(z), F(z) + G(z), rtol=1e-13, atol=0)
    np.testing.assert_allclose((F - 2.5 * G)(z), F(z) - 2.5 * G(z), rtol=1e-13, atol=0)
    np.testing.assert_allclose(F.shift(0.3)(z), F(z) * np.exp(-0.3 * z), rtol=1e-13, atol=0)
    np.testing.assert_allclose(F.derivative().shift(0.7)(z), F.deriv_at(z) * np.exp(-0.7 * z), rtol=1e-12, atol=0)
    np.testing.assert_allclose(G.times_poly([1, 2])(z), G(z) * (1 + 2 * z), rtol=1e-13, atol=0)
    np.testing.assert_allclose((1.0 - G)(z), 1.0 - G(z), rtol=1e-13, atol=0)


def test_equal_delays_merge_and_zero_terms_drop():
    F = QuasiPolynomial([[1], [0.5], [-0.5]], [0, 1, 1])
    assert F.delays.tolist() == [0.0]
    zero = QuasiPolynomial([[0, 1]], [0], [_jump_kernel()]) * 0.0
    assert zero.point_terms == () and zero.distributed == ()


def test_classification_of_principal_part():
    assert QuasiPolynomial([[1], [-0.85], [0.1]], [0, 2, 2.1]).kind == "neutral"
    assert QuasiPolynomial([[1, 1], [0.5]], [0, 1]).kind == "retarded"
    assert QuasiPolynomial([[1], [0, 1]], [0, 1]).kind == "advanced"
    dist_high = QuasiPolynomial([[1]], [0], [DistributedDelay([0, 1], [1, 1], poly=[0, 1])])
    with pytest.raises(ParameterError, match="distributed"):
        _ = dist_high.kind


def test_deriv_bound_is_an_upper_bound():
    d = _jump_kernel()
    F = QuasiPolynomial([[1, 0.5, 2.0], [-0.85, 0.1]], [0, 2], [d.times_poly([0.3, 1.0])])
    a = RNG.uniform(-2, 2, 200) + 1j * RNG.uniform(-50, 50, 200)
    b = a + RNG.uniform(-0.3, 0.3, 200) + 1j * RNG.uniform(-0.3, 0.3, 200)
    bound = F.deriv_bound(a, b)
    t = np.linspace(0, 1, 41)[:, None]
    actual = np.max(np.abs(F.deriv_at(a + t * (b - a))), axis=0)
    assert np.all(actual <= bound)
    assert np.median(bound / actual) < 5  # the bound is usable for step control


def test_variation_bound_controls_decay():
    d = _jump_kernel()
    w = np.array([5.0, 50.0, 500.0, 5000.0])
    for x in (0.0, 0.4):
        s = x + 1j * w
        assert np.all(np.abs(d(s)) <= d.variation_bound(x) / np.abs(s))


def test_variation_bound_closed_form_at_every_call():
    """``N = 1 + nu`` on ``[0, 1]`` with a jump of ``-1.5`` at ``0.5`` (linear, exact):
    ``V(x) = 1 + 0.5 e^{-x} + 1.5 e^{-x/2} + (1 - e^{-x}) / x``; the slopes and jumps formed at the first call
    serve the later ones (the values in any order, against the closed form, to 1e-14)."""
    d = DistributedDelay([0.0, 0.5, 0.5, 1.0], [1.0, 1.5, 0.0, 0.5])
    xs = np.array([2.0, -1.0, 0.0, 0.3])

    def closed(x: float) -> float:
        inner = 1.0 if x == 0.0 else -np.expm1(-x) / x
        return 1.0 + 0.5 * np.exp(-x) + 1.5 * np.exp(-0.5 * x) + inner

    for x in (*xs, *xs[::-1]):
        np.testing.assert_allclose(d.variation_bound(float(x)), closed(float(x)), rtol=1e-14)
    np.testing.assert_allclose(d.variation_bound(xs), [closed(float(x)) for x in xs], rtol=1e-14)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        (dict(nodes=[0.0], values=[1.0]), "nodes"),
        (dict(nodes=[0.0, 1.0, 0.5], values=[1, 1, 1]), "nodes"),
        (dict(nodes=[0.0, 1.0, 1.0, 1.0, 2.0], values=[1] * 5), "nodes"),
        (dict(nodes=[-0.1, 1.0], values=[1, 1]), "nodes"),
        (dict(nodes=[0.0, np.nan], values=[1, 1]), "nodes"),
        (dict(nodes=[0.0, 1.0], values=[1, np.inf]), "values"),
        (dict(nodes=[0.0, 1.0], values=[1, 2, 3]), "values"),
        (dict(nodes=[0.0, 1.0], values=[1, 2], poly=[]), "poly"),
    ],
)
def test_distributed_bad_input(kwargs, name):
    with pytest.raises(ParameterError, match=name):
        DistributedDelay(**kwargs)


@pytest.mark.parametrize(
    "args, name",
    [
        (([], []), "coefs"),
        (([[1], [2]], [0.0]), "delays"),
        (([[1]], [-1.0]), "delays"),
        (([[1]], [np.inf]), "delays"),
        (([[np.nan]], [0.0]), "coefs"),
        (([[]], [0.0]), "coefs"),
    ],
)
def test_quasipolynomial_bad_input(args, name):
    with pytest.raises(ParameterError, match=name):
        QuasiPolynomial(*args)


def test_repr_and_to_dict_roundtrip():
    F = QuasiPolynomial([[1], [-0.85]], [0, 2], [_jump_kernel()])
    text = repr(F)
    assert "e^(-2 s)" in text and "DistributedDelay" in text
    d = F.to_dict()
    G = QuasiPolynomial(
        d["coefs"],
        d["delays"],
        [DistributedDelay(x["nodes"], x["values"], x["poly"], x["moment"]) for x in d["distributed"]],
    )
    z = np.array([0.1 + 2j, 1 - 30j])
    np.testing.assert_allclose(F(z), G(z), rtol=1e-15, atol=0)


def test_chirp_z_path_on_vertical_lines_matches_direct(monkeypatch):
    """Uniform frequency sweeps use chirp-z transforms; they agree with the direct sum."""
    import nrobust.distributed_delay as dd

    n = 201
    nodes = np.r_[np.linspace(0, 1, n), np.linspace(1, 2, n)]
    d = DistributedDelay(nodes, np.r_[np.sin(3 * nodes[:n]), np.cos(nodes[n:])], moment=1)
    for x in (0.0, 0.5, -0.7):
        s = x + 1j * np.linspace(-30.0, 3000.0, 5000)
        fast = d(s)
        monkeypatch.setattr(dd, "_CZT_MIN_S", 10**9)
        direct = d(s)
        monkeypatch.undo()
        # Block length 1024 bounds the chirp phase error; measured ~1e-13 relative.
        assert np.max(np.abs(fast - direct)) < 1e-12 * np.max(np.abs(direct))


def test_chirp_z_sums_agree_with_direct_sums_to_a_few_ulps(monkeypatch):
    """Bluestein's sums with phases from ``d dw`` itself agree with the direct sums within
    1e-13 relative (measured 3e-14 to 4.3e-14 on these lines; scipy.signal.czt's chirps,
    powers of a rounded ``e^{-i d dw}``, gave 1.6e-13 to 2.7e-13)."""
    import nrobust.distributed_delay as dd

    n = 201
    nodes = np.r_[np.linspace(0, 1, n), np.linspace(1, 2, n)]
    d = DistributedDelay(nodes, np.r_[np.sin(3 * nodes[:n]), np.cos(nodes[n:])], moment=1)
    for x in (0.0, 0.5, -0.7):
        s = x + 1j * np.linspace(-30.0, 3000.0, 5000)
        fast = d(s)
        monkeypatch.setattr(dd, "_CZT_MIN_S", 10**9)
        direct = d(s)
        monkeypatch.undo()
        assert np.max(np.abs(fast - direct)) < 1e-13 * np.max(np.abs(direct))


def test_identical_distributed_terms_merge_and_cancel_exactly():
    d = _jump_kernel()
    A = QuasiPolynomial([[1], [-0.85]], [0, 2], [d])
    B = QuasiPolynomial([[0.1]], [2], [d.scale(-1.0)])
    F = A + B.shift(0.0)
    assert F.distributed == ()
    np.testing.assert_allclose(F(S_SAMPLES), 1 - 0.75 * np.exp(-2 * S_SAMPLES), rtol=1e-15, atol=0)
    G = A + A
    assert len(G.distributed) == 1
    np.testing.assert_allclose(G(S_SAMPLES), 2 * A(S_SAMPLES), rtol=1e-14, atol=0)


def test_cubic_interpolation_is_fourth_order_at_all_frequencies():
    """A smooth N with a jump: the cubic-spline Filon integral converges at fourth order."""
    from scipy.integrate import quad

    f1, f2 = (lambda x: np.sin(3 * x) + x**2), (lambda x: 2 + np.cos(2 * x))

    def exact(s: complex) -> complex:
        def part(f, a, b, c):
            return quad(lambda x: c(f(x) * np.exp(-x * s)), a, b, limit=400, epsabs=1e-15)[0]

        return sum(part(f, a, b, np.real) + 1j * part(f, a, b, np.imag) for f, a, b in ((f1, 0, 1), (f2, 1, 2.5)))

    for s in (0.3 + 2j, 0.1 + 60j):
        ref = exact(s)
        errors = []
        for n in (21, 41, 81):
            left, right = np.linspace(0, 1, n), np.linspace(1, 2.5, n)
            d = DistributedDelay(np.r_[left, right], np.r_[f1(left), f2(right)], interpolation="cubic")
            errors.append(abs(d(s) - ref))
        orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
        assert np.all(orders > 3.5), orders  # measured 3.9-5.9


def test_cubic_pieces_bounds_and_algebra():
    d = DistributedDelay([0.0, 0.0, 1.0, 1.0, 2.0], [1.0, 2.0, 3.0, 4.0, 5.0], interpolation="cubic")
    assert d.interpolation == "cubic" and d.shift(0.5)[0].interpolation == "cubic"
    w = np.array([3.0, 30.0, 300.0])
    assert np.all(np.abs(d(1j * w)) <= d.variation_bound(0.0) / w)
    x = np.linspace(0, 2, 2001)
    assert d.abs_moment(0.0, 0) >= np.trapezoid(np.abs(np.interp(x, [0, 1, 1 + 1e-12, 2], [2, 3, 4, 5])), x) - 1e-9
    with pytest.raises(ParameterError, match="interpolation"):
        DistributedDelay([0, 1], [1, 1], interpolation="spline")
    # A constant polynomial factor is folded into the values (canonical form).
    e = DistributedDelay([0, 1], [1, 2], poly=[3.0])
    assert e.poly.tolist() == [1.0] and e.values.tolist() == [3.0, 6.0]


def test_a_zero_term_shifted_keeps_its_support_inside_its_nodes():
    """A term zero within its radius, one ulp long: shifted by delays whose ulp is wider, its nodes are the doubles
    enclosing ``[a + delta, b + delta]`` (exact rationals), its variation gains ``2 radius`` where an end moved; and
    a moment expands as for any term. Before, ``nodes + delta`` rounded both ends onto one double (a ParameterError).
    """
    from fractions import Fraction

    a = 1.4285714285714284
    nodes = [a, a + np.spacing(4.0)]
    d = DistributedDelay(nodes, None, interpolation="polynomial", coefficients=[[0.0]], radius=0.1, variation_radius=1)
    for delta in (7.1, 10.42, 1e6):
        (moved,) = d.shift(delta)
        lo, hi = Fraction(d.a) + Fraction(delta), Fraction(d.b) + Fraction(delta)
        assert Fraction(moved.a) <= lo < hi <= Fraction(moved.b) and moved.nodes.size == 2
        assert moved.radius == d.radius and moved.variation_radius >= d.variation_radius + 2 * d.radius
        assert not np.any(moved.pieces[2])
    exact = d.shift(2.0**-40)[0]  # a + delta, b + delta exact: nothing moves outward
    assert exact.b - exact.a == d.b - d.a and exact.variation_radius == d.variation_radius
    first = d.replace(moment=1).shift(7.1)
    assert [t.moment for t in first] == [0, 1] and first[0].radius >= 7.1 * d.radius


def test_terms_that_are_only_their_error_bound_never_cancel():
    """Two zero kernels with equal radii are two unknown kernels each within the radius (e.g. ``|N| <= 0.1`` and
    ``|M| <= 0.1``): their sum is within ``0.2``, not zero; opposite nonzero kernels with equal bounds still
    cancel (one kernel and its negation)."""
    nodes = [0.5, 1.5]
    z = DistributedDelay(nodes, None, interpolation="polynomial", coefficients=[[0.0]], radius=0.1, variation_radius=1)
    total = z.plus(z.times(-1.0))
    assert total.radius >= 0.2 and total.variation_radius >= 2  # the kernel 0.2 = 0.1 + 0.1 lies within it
    k = DistributedDelay(nodes, None, interpolation="polynomial", coefficients=[[0.7]], radius=0.1)
    assert k.plus(k.times(-1.0)).radius == 0.0


def test_spline_total_variation_and_linear_deviation_are_upper_bounds():
    x = np.r_[np.linspace(0, 1, 9), np.linspace(1, 2, 9)]
    v = np.r_[np.sin(4 * x[:9]), 1 + np.cos(3 * x[9:])]
    lin, cub = DistributedDelay(x, v), DistributedDelay(x, v, interpolation="cubic")
    assert lin.linear_deviation() == 0.0
    assert lin.total_variation() == pytest.approx(
        abs(v[0]) + abs(v[-1]) + np.sum(np.abs(np.diff(v))), rel=1e-13, abs=1e-14
    )
    # Dense samples of the spline: its variation and its distance to the linear interpolant.
    _start, h, P = cub.pieces
    t = np.linspace(0, 1, 2001)
    seg = np.array([np.polyval(p[::-1], t) for p in P])  # spline values, one row per segment
    tv = abs(v[0]) + abs(v[-1]) + abs(v[9] - v[8]) + np.sum(np.abs(np.diff(seg, axis=1)))
    line = P[:, :1] + (np.sum(P, axis=1, keepdims=True) - P[:, :1]) * t
    dev = np.sum(h * np.trapezoid(np.abs(seg - line), t, axis=1))
    assert tv <= cub.total_variation() + 1e-12 and dev <= cub.linear_deviation() + 1e-12
    assert cub.linear_deviation() < 1.5 * dev + 1e-9  # and tight


@pytest.mark.parametrize("value", [2, -0.5, 1 + 2j, np.float32(0.25), np.int64(3)])
def test_as_quasipolynomial_takes_finite_numbers_as_constants(value):
    F = as_quasipolynomial("B", value)
    np.testing.assert_allclose(F(S_SAMPLES), np.full(S_SAMPLES.shape, complex(value)), rtol=1e-7, atol=0)
    G = QuasiPolynomial([[0, 1], [1]], [0, 1])
    assert as_quasipolynomial("B", G) is G


@pytest.mark.parametrize("value", [True, np.bool_(False), np.inf, complex(np.nan, 0), "s + 1", [1.0], None])
def test_as_quasipolynomial_rejects_booleans_non_finite_and_other_types(value):
    with pytest.raises(ParameterError, match=r"^A must be a QuasiPolynomial or a finite number"):
        as_quasipolynomial("A", value)


# --- structural equality ---


def _kernels() -> tuple[DistributedDelay, DistributedDelay]:
    return DistributedDelay([0.0, 0.5, 1.0], [1.0, 2.0, 0.5]), DistributedDelay([0.2, 1.0], [1.0, -1.0], moment=1)


def test_same_function_in_another_order_is_equal_with_equal_hash():
    d1, d2 = _kernels()
    F = QuasiPolynomial([[1, 1], [0.5], [0.25, 0, 0]], [0, 1, 2], [d1, d2])
    G = QuasiPolynomial([[0.25], [0.5], [1, 1]], [2, 1, 0], [d2, d1])  # trailing zeros trimmed
    H = QuasiPolynomial([[1, 0.5], [0.5], [0, 0.5], [0.25]], [0, 1, 0, 2], [d1, d2])  # merged by delay
    assert F == G == H and hash(F) == hash(G) == hash(H)
    assert {F: "F"}[G] == "F" and len({F, G, H}) == 1
    np.testing.assert_allclose(F(S_SAMPLES), G(S_SAMPLES), rtol=1e-14, atol=0)


def test_a_tiny_change_makes_quasipolynomials_unequal():
    d1, d2 = _kernels()
    F = QuasiPolynomial([[1, 1], [0.5]], [0, 1], [d1])
    assert F != QuasiPolynomial([[1, 1 + 1e-15], [0.5]], [0, 1], [d1])
    assert F != QuasiPolynomial([[1, 1], [0.5]], [0, 1 + 1e-15], [d1])
    assert F != QuasiPolynomial([[1, 1], [0.5]], [0, 1], [d1.scale(1 + 1e-15)])
    assert F != QuasiPolynomial([[1, 1], [0.5]], [0, 1], [d1, d2])
    assert F != QuasiPolynomial([[1, 1], [0.5]], [0, 1])
    assert len({F, QuasiPolynomial([[1, 1], [0.5 + 1e-15]], [0, 1], [d1])}) == 2


def test_equality_follows_the_canonical_form():
    d1, _ = _kernels()
    # real and complex coefficients with the same values, like 1.0 == 1 + 0j; -0.0 == 0.0
    assert QuasiPolynomial([[1.0, -0.0, 2.0]], [0]) == QuasiPolynomial([[1 + 0j, 0.0, 2.0]], [0])
    assert hash(QuasiPolynomial([[1.0, -0.0, 2.0]], [0])) == hash(QuasiPolynomial([[1 + 0j, 0.0, 2.0]], [0]))
    # a constant factor of a distributed term lives in its values
    assert DistributedDelay(d1.nodes, d1.values, poly=[2.0]) == d1.scale(2.0)
    assert hash(DistributedDelay(d1.nodes, d1.values, poly=[2.0])) == hash(d1.scale(2.0))
    # two terms on the same support are merged
    half = d1.scale(0.5)
    assert QuasiPolynomial([[1]], [0], [half, half]) == QuasiPolynomial([[1]], [0], [d1])
    # the sum of a function and its negative is the zero function, whatever it was
    F = QuasiPolynomial([[1, 1], [0.5]], [0, 1], [d1])
    assert F - F == QuasiPolynomial([[0.0]], [0.0]) == QuasiPolynomial([[0.0]], [3.0])


def test_distributed_delays_differ_by_any_attribute():
    d1, _ = _kernels()
    assert d1 == DistributedDelay([0.0, 0.5, 1.0], [1.0, 2.0, 0.5])
    assert d1 != DistributedDelay([0.0, 0.5, 1.0], [1.0, 2.0, 0.5], interpolation="cubic")
    assert d1 != DistributedDelay([0.0, 0.5, 1.0], [1.0, 2.0, 0.5], moment=1)
    assert d1 != DistributedDelay([0.0, 0.5, 1.0], [1.0, 2.0, 0.5], poly=[1.0, 1.0])
    assert d1 != DistributedDelay([0.0, 0.5, 1.1], [1.0, 2.0, 0.5])
    assert d1 != DistributedDelay([0.0, 1.0], [1.0, 0.5])


@pytest.mark.parametrize("other", [1, 1.0, "F", None, (1, 1)])
def test_comparison_with_other_types_is_not_implemented(other):
    d1, _ = _kernels()
    F = QuasiPolynomial([[1]], [0])
    assert F.__eq__(other) is NotImplemented and d1.__eq__(other) is NotImplemented
    assert F != other and d1 != other and F != d1


def test_decay_bound_at_distinct_real_parts_is_the_same_bound() -> None:
    """``decay_bound(xs, d, k, where=idx)`` (the contour's distinct real parts given) equals
    ``decay_bound(xs[idx], d, k)`` bit for bit, zero moduli (infinite bounds) included."""
    N = DistributedDelay(np.linspace(0.0, 2.0, 9), np.cos(np.linspace(0.0, 3.0, 9)), moment=1)
    rng = np.random.default_rng(3)
    xs = np.unique(np.round(rng.uniform(-3.0, 1.0, 30) * 64.0) / 64.0)
    idx = rng.integers(0, xs.size, size=(5, 7))
    d = rng.uniform(0.0, 40.0, size=(5, 7))
    d[0, 0] = 0.0
    for k in (0, 1, 2):
        expected = N.decay_bound(xs[idx], d, k)
        assert np.isinf(expected[0, 0])
        np.testing.assert_array_equal(N.decay_bound(xs, d, k, where=idx), expected)
