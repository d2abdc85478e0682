"""Unit-circle crossings of ``det(M_0(i w) + z M_1(i w))``: the delay margin of a matrix loop.

A loop with one delay ``delta`` on every input has the characteristic function
``F(s; delta) = det(M_0(s) + e^{-delta s} M_1(s))``. A root sits at ``s = i w`` for some
delay iff ``f(w, z) = det(M_0(i w) + z M_1(i w))`` vanishes for some ``|z| = 1``
(``z = e^{-i w delta}``): an eigenvalue of ``-M_0^{-1} M_1`` of modulus one. This module
holds the generic, plant-free pieces of the certified search.

**Compound form.** When ``M(s; z) = L(z) G(s) W`` with ``G(s) = exp(C - s P)`` (``P``
real diagonal), ``L(z)`` an ``m x N`` matrix affine in ``z`` and ``W`` an ``N x m``
matrix, the Cauchy-Binet formula gives ``det M = a(z)^T (wedge^m G(s)) b`` with ``a(z)`` the
``m x m`` minors of ``L(z)`` (a polynomial of degree ``<= m`` in ``z``), ``b`` the minors
of ``W``, and ``wedge^m exp(A) = exp(D_m(A))`` with ``D_m(A)`` the derivation of ``A``
on the ``m``-th exterior power (:func:`compound_generator`). So ``f(w, e^{i phi}) =
sum_d c_d(w) e^{i d phi}``, ``c_d(w) = a_d^T exp(D_m(C) - i w D_m(P)) b``, and every
``w``-derivative obeys ``|c_d^{(k)}| <= ||a_d|| ||b|| ||D_m(P)||^k e^{beta}``,
``beta = lambda_max(Herm D_m(C))`` (Dyson's expansion; ``Herm(-i w P) = 0`` on the axis).

**Far field.** :class:`GaugeRemainder` bounds ``||exp(C - s P) - exp(C_d - s P)||`` by a
non-increasing ``r(|s|) = O(1/|s|)`` (``C_d`` the entries of ``C`` between indices of
equal ``p_i``): on the axis for any real ``P``, on ``Re s >= 0`` for ``P >= 0``. It is
the bound of :meth:`nrobust.hyperbolic.nplusm.NPlusMCharacteristic.coupling_remainder`
for a general pair ``(C, P)``; ``docs/theory.md``, "Beyond 2x2", has the derivation.

**Search** (:func:`circle_crossings`). The rectangle ``[0, W] x [0, 2 pi)`` of
``(w, phi)`` is covered by cells. A cell with centre ``x_0`` and half-widths
``(h_w, h_phi)`` holds no zero of ``f`` when ``|f(x_0)| - err > L_w h_w + L_phi h_phi``
(``L_w = sum_d sup |c_d'|``, ``L_phi = sum_d d sup |c_d|``), or, to second order, when
``(sigma_min(J_0) - e_J) dist(d*, cell) > err + e_J |d| + S |d|^2 / 2`` with ``d*`` the
Newton step from the centre (near a zero the first-order test leaves a ring of cells of
radius ``~ (L / sigma_min) h``; this one leaves ``O(S h^2 / sigma_min)``). A zero is proven, and
proven unique in a disc ``B(x*, r)``, by the Newton-Kantorovich contraction of the real
``2 x 2`` map ``(w, phi) -> f``: with ``J_0`` its Jacobian at ``x*``,
``kappa = ||J_0^{-1}|| (r S + e_J) < 1/2`` and ``||J_0^{-1}|| (|f(x*)| + err) <= (1 - kappa) r``,
``S`` bounding the second derivatives. Cells inside a proven disc are dropped, the others
are quartered, down to a width of ``1e-11 max(1, W)``; a zero that stays undecided there,
or more than 2000 open cells narrower than ``1e-5 max(1, W)`` (a tangency, two crossings
at one point), raises :class:`~nrobust.errors.CertificationError`.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import positive_int
from ..errors import CertificationError, ParameterError

__all__ = ["GaugeRemainder", "circle_crossings", "compound_generator", "compound_generator_of", "compound_minors"]

# Initial cells of the circle of phases.
_PHASE_CELLS = 64
# Smallest half-width of a cell, relative to max(1, W), before the search refuses.
_MIN_WIDTH = 1e-11
# Proofs attempted per round of the search (on the open cells of smallest |f|, apart).
_ATTEMPTS = 32
# Largest number of open cells narrower than _FINE max(1, W) in a round before the search refuses
# (a simple zero leaves a few dozen: its disc is proven long before; a tangency leaves ~ h^{-1/2}).
_MAX_OPEN = 2000
_FINE = 1e-5
# Newton steps that refine a zero before its disc is proven.
_NEWTON_STEPS = 6


def _subsets(size: int, m: int) -> list[tuple[int, ...]]:
    return list(itertools.combinations(range(size), m))


def compound_generator(A: ArrayLike, m: int) -> NDArray[np.complex128]:
    """``D_m(A)``: the derivation of ``A`` on the ``m``-th exterior power, ``exp(D_m(A)) = wedge^m exp(A)``.

    The basis is ``e_S = e_{S_1} ^ ... ^ e_{S_m}`` over the increasing ``m``-subsets ``S``
    in lexicographic order (:func:`itertools.combinations`), so that
    ``(wedge^m X)_{S, T} = det X[S, T]``.

    Parameters
    ----------
    A : array_like, shape (N, N)
    m : int
        ``1 <= m <= N``.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.linalg import expm
    >>> A = np.array([[0.1, 0.2, 0.0], [0.3, -0.1, 0.5], [0.0, 0.4, 0.2]])
    >>> G = expm(A)
    >>> minor = np.linalg.det(G[np.ix_([0, 2], [1, 2])])
    >>> bool(np.isclose(expm(compound_generator(A, 2))[1, 2], minor))
    True
    """
    a = np.asarray(A, dtype=complex)
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise ParameterError("A", "a square matrix", a.shape)
    size = a.shape[0]
    m = positive_int("m", m)
    if m > size:
        raise ParameterError("m", f"an integer in [1, {size}]", m)
    subsets = _subsets(size, m)
    index = {S: i for i, S in enumerate(subsets)}
    out = np.zeros((len(subsets), len(subsets)), dtype=complex)
    for col, S in enumerate(subsets):
        for pos, i in enumerate(S):
            for k in range(size):
                if a[k, i] == 0 or (k != i and k in S):
                    continue
                T = list(S)
                T[pos] = k
                # sorting T moves k past the entries of S strictly between i and k
                sign = -1.0 if sum(min(i, k) < j < max(i, k) for j in S) % 2 else 1.0
                out[index[tuple(sorted(T))], col] += sign * a[k, i]
    return out


def compound_generator_of(entries: Sequence[Sequence[Any]], nonzero: ArrayLike, m: int, zero: Any) -> list[list[Any]]:
    """:func:`compound_generator` of a matrix whose entries are numbers of another kind (balls, rationals).

    ``D_m`` is linear in the matrix and its entries for a unit matrix are small integers, so the generator is the sum
    over the entries ``entries[k][i]`` where ``nonzero[k, i]`` of that pattern times the entry, each sum starting at
    ``zero`` (exact arithmetic on the integers: a ball sum encloses the generator of every matrix of the balls).

    Parameters
    ----------
    entries : sequence of sequence
        The ``N x N`` entries, of any type with ``+`` and multiplication by ``int``.
    nonzero : array_like of bool, shape (N, N)
        Where an entry can be nonzero (the others are skipped).
    m : int
        ``1 <= m <= N``.
    zero : object
        The zero of the entries' type.
    """
    mask = np.asarray(nonzero, dtype=bool)
    size = mask.shape[0]
    count = len(_subsets(size, m))
    out = [[zero for _ in range(count)] for _ in range(count)]
    for i, k in itertools.product(range(size), repeat=2):
        if not mask[k, i]:
            continue
        unit = np.zeros((size, size))
        unit[k, i] = 1.0
        pattern = compound_generator(unit, m).real  # small integers, exact
        for a, b in zip(*np.nonzero(pattern)):
            out[a][b] += int(pattern[a, b]) * entries[k][i]
    return out


def compound_minors(X: ArrayLike, axis: int) -> NDArray[np.complex128]:
    """The ``m x m`` minors of an ``m x N`` (``axis=1``) or ``N x m`` (``axis=0``) matrix, in the basis order
    of :func:`compound_generator`: ``det X[:, S]`` or ``det X[S, :]``."""
    x = np.asarray(X, dtype=complex)
    if x.ndim != 2 or axis not in (0, 1):
        raise ParameterError("X", "a matrix and axis 0 or 1", x.shape)
    m, size = (x.shape[0], x.shape[1]) if axis == 1 else (x.shape[1], x.shape[0])
    rows = [x[:, S] if axis == 1 else x[S, :] for S in _subsets(size, m)]
    return np.asarray(np.linalg.det(np.array(rows)), dtype=complex)


@dataclass(frozen=True, eq=False)
class GaugeRemainder:
    """``r(|s|)`` with ``||exp(C - s P) - exp(C_d - s P)||_2 <= r(|s|)``.

    ``C_d`` keeps the entries of ``C`` between indices of equal ``p_i``. With ``N`` solving
    ``[P, N] = C_o = C - C_d`` and ``H = C N - N C_d``, the gauge ``Y = (I + N/s) Z`` turns
    ``Y' = (C - s P) Y`` into ``Z' = (C_d - s P + E/s) Z`` with
    ``||E|| <= e = ||H|| / (1 - ||N||/|s|)``, and Gronwall's lemma with the logarithmic norm
    ``beta_d = lambda_max(Herm C_d)`` gives, for ``|s| > ||N||`` and ``t = 1 / (1 - ||N||/|s|)``, ::

        r = ((1 + ||N||/|s|) t e e^{beta_d + e/|s|} + 2 ||N|| t e^{beta_d}) / |s|,

    non-increasing in ``|s|`` (``inf`` for ``|s| <= ||N||``; ``1e-9`` relative slack). The
    bound holds on the imaginary axis for any real diagonal ``P`` and on ``Re s >= 0`` when
    ``P >= 0`` (then ``Herm(C_d - s P) <= Herm C_d``).

    Parameters
    ----------
    C : array_like, shape (N, N)
    p : array_like, shape (N,)
        The diagonal of ``P``.
    """

    floor: float
    h_norm: float
    beta_d: float
    c_d: NDArray[np.complex128]

    def __init__(self, C: ArrayLike, p: ArrayLike) -> None:
        c = np.asarray(C, dtype=complex)
        pv = np.asarray(p, dtype=float)
        if c.ndim != 2 or c.shape != (pv.size, pv.size) or not np.all(np.isfinite(c)) or not np.all(np.isfinite(pv)):
            raise ParameterError("C", f"a finite square matrix matching p ({pv.size})", c.shape)
        same = pv[:, None] == pv[None, :]
        c_d = np.where(same, c, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            N = np.where(same, 0.0, c / (pv[:, None] - pv[None, :]))
        H = c @ N - N @ c_d
        slack = 1e-12 * (1.0 + float(np.abs(c).sum()))
        object.__setattr__(self, "floor", float(np.linalg.norm(N, 2)))
        object.__setattr__(self, "h_norm", float(np.linalg.norm(H, 2)))
        object.__setattr__(self, "beta_d", float(np.linalg.eigvalsh(0.5 * (c_d + c_d.conj().T))[-1]) + slack)
        object.__setattr__(self, "c_d", c_d)

    def __call__(self, radius: ArrayLike) -> NDArray[np.float64]:
        x: NDArray[np.float64] = np.abs(np.asarray(radius, dtype=np.float64))
        nN, beta_d = self.floor, self.beta_d
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            t = 1.0 / (1.0 - nN / x)
            e = t * self.h_norm
            r = ((1.0 + nN / x) * t * e * np.exp(beta_d + e / x) + 2.0 * nN * t * np.exp(beta_d)) / x
        return np.asarray(np.where(x > nN, r * (1.0 + 1e-9), np.inf), dtype=np.float64)

    def radius(self, scale: float, level: float) -> float:
        """A radius ``R > floor`` with ``scale r(R) < level`` within ``1e-7`` (relative) of the smallest.

        Raises
        ------
        CertificationError
            ``level <= 0``, or the bound stays above ``level`` up to ``2^200``.
        """
        if not level > 0.0:
            raise CertificationError(f"frequency bound: no room below the principal part's gap ({level:.3g})")
        if self.floor == 0.0 and self.h_norm == 0.0:
            return 0.0
        hi = max(2.0 * self.floor, 1.0)
        while not scale * float(self(hi)) < level:
            hi *= 2.0
            if hi > 2.0**200:
                raise CertificationError(f"frequency bound: the coupling remainder stays above the gap {level:.3g}")
        lo = self.floor
        while hi - lo > 1e-7 * hi:
            mid = 0.5 * (lo + hi)
            if scale * float(self(mid)) < level:
                hi = mid
            else:
                lo = mid
        return hi


def _wrap(d: NDArray[np.float64]) -> NDArray[np.float64]:
    """Phase differences in ``[-pi, pi)``."""
    return np.asarray(np.mod(d + np.pi, 2 * np.pi) - np.pi, dtype=np.float64)


class _Evaluator:
    """The function ``f(w, e^{i phi})`` of one search, its derivative bounds and its work counter.

    Built from the caller's ``coefs``, ``jet``, ``level`` and ``bounds``: ``lip_w``,
    ``lip_phi`` are the Lipschitz constants of ``f`` in ``w`` and ``phi``, ``second`` bounds
    the norm of its second derivatives (the ``S`` of the module notes, ``1e-12`` relative
    slack), ``dscale`` the rounding of a ``w``-derivative relative to that of ``f``. Every
    evaluation of the coefficients is charged against ``max_points`` before it is made
    (:meth:`charge`).
    """

    def __init__(
        self,
        coefs: Callable[[NDArray[np.float64]], NDArray[np.complex128]],
        jet: Callable[[NDArray[np.float64]], tuple[NDArray[np.complex128], NDArray[np.complex128]]],
        level: Callable[[NDArray[np.float64]], NDArray[np.float64]],
        bounds: ArrayLike,
        max_points: int,
    ) -> None:
        self.coefs, self.jet, self.level, self.max_points = coefs, jet, level, max_points
        b = np.asarray(bounds, dtype=float)
        deg = np.arange(b.shape[1], dtype=float)
        self.deg = deg
        self.lip_w, self.lip_phi = float(b[1].sum()), float((deg * b[0]).sum())
        s_ww, s_wp, s_pp = float(b[2].sum()), float((deg * b[1]).sum()), float((deg**2 * b[0]).sum())
        self.second = float(np.sqrt(s_ww**2 + 2.0 * s_wp**2 + s_pp**2)) * (1.0 + 1e-12)
        self.dscale = 1.0 + self.lip_w / max(float(b[0].sum()), 1e-300)
        self.spent = 0

    def charge(self, count: int) -> None:
        """Count ``count`` more evaluations; raise once the total would pass ``max_points``."""
        if self.spent + count > self.max_points:
            raise CertificationError(
                f"circle crossings: {count} more evaluations after {self.spent} exceed max_points={self.max_points} "
                "(raise max_points)"
            )
        self.spent += count

    def values(self, w: NDArray[np.float64], phi: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """``f`` at the points and its rounding bound (the coefficients evaluated once per distinct ``w``)."""
        deg = self.deg
        uw, inv = np.unique(w, return_inverse=True)
        self.charge(uw.size)
        c = self.coefs(uw)[inv]
        z = np.exp(1j * phi[:, None] * deg[None, :])
        err = self.level(uw)[inv] * deg.size + 4e-16 * np.abs(c).sum(axis=1)
        return np.sum(c * z, axis=1), err

    def gradients(self, w: NDArray[np.float64], phi: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """``df/dw`` and ``df/dphi`` at the points (the jet evaluated once per distinct ``w``)."""
        deg = self.deg
        uw, inv = np.unique(w, return_inverse=True)
        self.charge(uw.size)
        c, dc = self.jet(uw)
        z = np.exp(1j * phi[:, None] * deg[None, :])
        return np.sum(dc[inv] * z, axis=1), np.sum(1j * deg * c[inv] * z, axis=1)

    def newton(self, x: NDArray[np.float64]) -> tuple[NDArray[np.float64], complex, NDArray[np.float64], float]:
        """Newton steps on the real 2 x 2 map: the last point evaluated, with ``f``, ``J`` and the rounding
        of ``f`` there (the Newton correction ``J^{-1} f`` is then small)."""
        deg = self.deg
        for it in range(_NEWTON_STEPS + 1):
            self.charge(1)
            c, dc = self.jet(np.array([x[0]]))
            z = np.exp(1j * x[1] * deg)
            f = complex(np.sum(c[0] * z))
            fw, fp = complex(np.sum(dc[0] * z)), complex(np.sum(1j * deg * c[0] * z))
            J = np.array([[fw.real, fp.real], [fw.imag, fp.imag]])
            try:
                dx = np.linalg.solve(J, [f.real, f.imag])
            except np.linalg.LinAlgError:
                break
            if it == _NEWTON_STEPS or not np.all(np.isfinite(dx)) or np.hypot(*dx) < 1e-13 * max(1.0, abs(x[0])):
                break
            x = x - dx
        err = float(self.level(np.array([x[0]]))[0]) * deg.size + 4e-16 * float(np.abs(c).sum())
        return x, f, J, err

    def probe(self, x: NDArray[np.float64]) -> float:
        """Length of the Newton correction at ``x`` (one evaluation): how far a zero is predicted."""
        deg = self.deg
        self.charge(1)
        c, dc = self.jet(np.array([x[0]]))
        z = np.exp(1j * x[1] * deg)
        f, fw, fp = complex(np.sum(c[0] * z)), complex(np.sum(dc[0] * z)), complex(np.sum(1j * deg * c[0] * z))
        det = fw.real * fp.imag - fp.real * fw.imag
        return float(abs(f) * np.hypot(abs(fw), abs(fp)) / abs(det)) if det != 0 else np.inf


# Cells of the (w, phi) rectangle: centres cw, cp and half-widths hw, hp (four arrays of one size).
_Cells = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]
# A zero x* = (w, phi) and the radius of the disc in which it is proven unique.
_Zero = tuple[NDArray[np.float64], float]


def _select(cells: _Cells, mask: NDArray) -> _Cells:
    """The cells picked by a boolean mask (or index array)."""
    cw, cp, hw, hp = cells
    return cw[mask], cp[mask], hw[mask], hp[mask]


def _first_grid(W: float, step: float, max_points: int) -> _Cells:
    """The initial cells: ``ceil(W / step)`` columns in ``w`` times ``_PHASE_CELLS`` in ``phi``.

    One column when ``W = 0``. Refuses a ``max_points`` below the number of columns (each
    costs one evaluation of the coefficients), before evaluating anything.
    """
    nw = max(1, int(np.ceil(W / step))) if W > 0 else 1
    if nw > max_points:
        raise ParameterError("max_points", f">= {nw} (the first grid up to W = {W:.6g})", max_points)
    hw0 = 0.5 * W / nw if W > 0 else 0.0
    wc = (np.arange(nw) + 0.5) * (2 * hw0)
    pc = (np.arange(_PHASE_CELLS) + 0.5) * (2 * np.pi / _PHASE_CELLS)
    cw, cp = (g.ravel() for g in np.meshgrid(wc, pc, indexing="ij"))
    return cw, cp, np.full(cw.size, hw0), np.full(cw.size, np.pi / _PHASE_CELLS)


def _outside_discs(cells: _Cells, zeros: list[_Zero]) -> _Cells:
    """The cells not wholly inside a proven disc (those inside are settled: their only zero is listed).

    The farthest corner of a cell from ``x*`` is measured with the phase difference wrapped.
    """
    cw, cp, hw, hp = cells
    keep = np.ones(cw.size, dtype=bool)
    for x, r in zeros:
        far_w = np.abs(cw - x[0]) + hw
        far_p = np.abs(_wrap(cp - x[1])) + hp
        keep &= np.hypot(far_w, far_p) > r
    return _select(cells, keep)


def _lipschitz_open(cells: _Cells, ev: _Evaluator) -> tuple[_Cells, NDArray, NDArray]:
    """The cells the first-order test leaves open, with ``f`` and its rounding bound at their centres.

    A cell is excluded (holds no zero) when ``|f(x_0)| - err > L_w h_w + L_phi h_phi``.
    """
    cw, cp, hw, hp = cells
    f, err = ev.values(cw, cp)
    open_ = np.abs(f) - err <= ev.lip_w * hw + ev.lip_phi * hp
    return _select(cells, open_), f[open_], err[open_]


def _newton_open(cells: _Cells, f: NDArray, err: NDArray, ev: _Evaluator) -> tuple[_Cells, NDArray]:
    """The cells the second-order test leaves open, with ``f`` at their centres.

    With ``d* = -J_0^{-1} f(x_0)`` the Newton step from the centre,
    ``|f(x_0 + d)| >= sigma_min(J_0) dist(d*, cell) - e_J |d| - S |d|^2 / 2``, ``e_J`` the
    rounding of ``J_0`` (and of ``sigma_min``). The test can only decide a cell with
    ``|f(x_0)| > S |d|^2 / 2``, and ``|f(x_0)| <= L |d|`` on a cell the first-order test
    left open: it is tried on the cells small enough for that (one evaluation of the jet
    per distinct ``w``), and excludes those with a positive margin.
    """
    cw, cp, hw, hp = cells
    second = ev.second
    near = np.flatnonzero(np.hypot(hw, hp) * second < 2.0 * (ev.lip_w + ev.lip_phi))
    if not near.size:
        return cells, f
    nhw, nhp, nf, nerr = hw[near], hp[near], f[near], err[near]
    fw, fp = ev.gradients(cw[near], cp[near])
    J = np.stack([np.stack([fw.real, fp.real], -1), np.stack([fw.imag, fp.imag], -1)], -2)
    sig = np.linalg.svd(J, compute_uv=False)[:, -1]
    det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        dw = -(J[:, 1, 1] * nf.real - J[:, 0, 1] * nf.imag) / det
        dp = -(-J[:, 1, 0] * nf.real + J[:, 0, 0] * nf.imag) / det
    dist = np.hypot(np.maximum(np.abs(dw) - nhw, 0.0), np.maximum(np.abs(dp) - nhp, 0.0))
    reach = np.hypot(nhw, nhp)
    e_j = 1e-12 * np.hypot(np.abs(fw), np.abs(fp)) + nerr * ev.dscale
    dist = np.where(np.isfinite(dist), dist, 0.0)
    margin = (sig - e_j) * dist - nerr - e_j * reach - 0.5 * second * reach**2
    keep = np.ones(cw.size, dtype=bool)
    keep[near[margin > 0]] = False
    return _select(cells, keep), f[keep]


def _prove_discs(cells: _Cells, f: NDArray, zeros: list[_Zero], ev: _Evaluator, W: float) -> None:
    """Try Newton-Kantorovich discs from the open cells of smallest ``|f|``; add the proven ones to ``zeros``.

    At most ``_ATTEMPTS`` proofs per round, from centres apart from each other (an attempt
    blocks a disc of 8 times its cell's half-diagonal) and outside the proven discs. A disc
    whose zero is the mirror at ``-w`` or lies beyond ``W`` is dropped; a zero within its
    radius of ``w = 0`` (a root at ``s = 0`` for some delay) raises
    :class:`~nrobust.errors.CertificationError`.
    """
    cw, cp, hw, hp = cells
    tried: list[_Zero] = []
    sizes = np.hypot(hw, hp)
    for i in np.argsort(np.abs(f)):
        if len(tried) >= _ATTEMPTS:
            break
        size = float(sizes[i])
        if _near(zeros + tried, cw[i], cp[i], 0.0):
            continue  # settled, or tried nearby
        tried.append((np.array([cw[i], cp[i]]), 8.0 * size))
        proven = _prove_zero(ev.newton, np.array([cw[i], cp[i]]), size, ev.second, ev.probe, ev.dscale)
        if proven is None or proven[0][0] < -proven[1] or proven[0][0] - proven[1] > W:
            continue  # no proof, or the mirror zero at -w, or one beyond the caller's bound
        if proven[0][0] <= proven[1]:
            raise CertificationError(
                f"circle crossings: a zero within {proven[1]:.3g} of w = 0 (a root at s = 0 for some delay)"
            )
        if not _near(zeros, proven[0][0], proven[0][1], proven[1]):
            zeros.append(proven)


def _refuse_undecided(cells: _Cells, zeros: list[_Zero], width: float, W: float) -> None:
    """Raise :class:`~nrobust.errors.CertificationError` on a tangency or a multiple crossing.

    Either an open cell narrowed to ``width`` in both directions outside every proven disc,
    or more than ``_MAX_OPEN`` open cells narrower than ``_FINE max(1, W)`` in ``w`` (a
    simple zero leaves a few dozen; a tangency leaves ``~ h^{-1/2}``).
    """
    cw, cp, hw, hp = cells
    if np.any((hw <= width) & (hp <= width)):
        j = int(np.argmax((hw <= width) & (hp <= width)))
        if not _near(zeros, cw[j], cp[j], 0.0):
            raise CertificationError(
                f"circle crossings: cannot decide a zero near w = {cw[j]:.17g}, phi = {cp[j]:.17g} (a tangency "
                "or a multiple crossing to rounding); a slight change of the gain would decide it"
            )
    fine = hw <= _FINE * max(1.0, W)
    if np.count_nonzero(fine) > _MAX_OPEN:
        raise CertificationError(
            f"circle crossings: {np.count_nonzero(fine)} cells narrower than {_FINE:g} max(1, W) near w in "
            f"[{cw[fine].min():.6g}, {cw[fine].max():.6g}] stay undecided (a "
            "tangency or a near-double zero); a slight change of the gain would decide it"
        )


def _quarter(cells: _Cells, W: float) -> _Cells:
    """Each open cell split in four; the quarters starting at or beyond ``W`` are dropped (the caller's bound)."""
    cw, cp, hw, hp = cells
    ow, op = np.array([-0.5, 0.5, -0.5, 0.5]), np.array([-0.5, -0.5, 0.5, 0.5])
    cw = (cw[:, None] + ow[None] * hw[:, None]).ravel()
    cp = (cp[:, None] + op[None] * hp[:, None]).ravel()
    hw, hp = np.repeat(hw / 2, 4), np.repeat(hp / 2, 4)
    inside = cw - hw < W
    return cw[inside], cp[inside], hw[inside], hp[inside]


def circle_crossings(
    coefs: Callable[[NDArray[np.float64]], NDArray[np.complex128]],
    jet: Callable[[NDArray[np.float64]], tuple[NDArray[np.complex128], NDArray[np.complex128]]],
    W: float,
    bounds: ArrayLike,
    level: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    *,
    step: float,
    max_points: int = 2_000_000,
) -> tuple[tuple[float, float], ...]:
    """Every zero ``(w, phi)`` of ``f(w, e^{i phi}) = sum_d c_d(w) e^{i d phi}`` with ``0 < w <= W``, certified.

    Parameters
    ----------
    coefs : callable
        ``coefs(w)`` returns ``c_d(w)``, shape ``(w.size, D + 1)``.
    jet : callable
        ``jet(w)`` returns ``c_d(w)`` and ``c_d'(w)`` (derivative in ``w``).
    W : float
        Upper end ``>= 0`` of the frequencies (no zero beyond it, proven by the caller).
    bounds : array_like, shape (3, D + 1)
        ``sup |c_d|``, ``sup |c_d'|``, ``sup |c_d''|`` over ``[0, W]``.
    level : callable
        ``level(w)``: bound of the rounding error of each computed ``c_d(w)``, shape ``(w.size,)``.
    step : float
        Width ``> 0`` of the initial cells in ``w``.
    max_points : int, optional
        Work bound on evaluations of the coefficients, checked before each batch.

    Returns
    -------
    tuple of (float, float)
        The zeros ``(w, phi)``, ``phi`` in ``[0, 2 pi)``, sorted by ``w``; each is proven
        unique in a disc of the ``(w, phi)`` plane, and ``f`` proven nonzero elsewhere.

    Raises
    ------
    CertificationError
        The work bound was hit, a zero lies within rounding of ``w = 0``, or a cell
        narrowed to rounding without a decision (a tangency or a multiple zero).
    """
    W = float(W)
    if not (np.isfinite(W) and W >= 0.0):
        raise ParameterError("W", "a finite frequency >= 0", W)
    if not (np.isfinite(step) and step > 0.0):
        raise ParameterError("step", "a width > 0", step)
    max_points = positive_int("max_points", max_points)
    ev = _Evaluator(coefs, jet, level, bounds, max_points)
    width = max(1.0, W) * _MIN_WIDTH
    cells = _first_grid(W, step, max_points)
    zeros: list[_Zero] = []
    while cells[0].size:
        cells = _outside_discs(cells, zeros)
        if not cells[0].size:
            break
        cells, f, err = _lipschitz_open(cells, ev)
        cells, f = _newton_open(cells, f, err, ev)
        _prove_discs(cells, f, zeros, ev, W)
        _refuse_undecided(cells, zeros, width, W)
        cells = _quarter(cells, W)
    out = sorted((float(x[0]), float(np.mod(x[1], 2 * np.pi))) for x, _ in zeros)
    return tuple(out)


def _near(zeros: list[tuple[NDArray[np.float64], float]], w: float, phi: float, extra: float) -> bool:
    """True if ``(w, phi)`` lies within ``max(r, extra)`` of a listed point (phases wrapped)."""
    if not zeros:
        return False
    pts = np.array([x for x, _ in zeros])
    r = np.maximum([r for _, r in zeros], extra)
    d = np.mod(phi - pts[:, 1] + np.pi, 2 * np.pi) - np.pi
    return bool(np.any(np.hypot(w - pts[:, 0], d) < r))


def _prove_zero(
    newton: Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], complex, NDArray[np.float64], float]],
    x0: NDArray[np.float64],
    size: float,
    second: float,
    probe: Callable[[NDArray[np.float64]], float],
    dscale: float,
) -> tuple[NDArray[np.float64], float] | None:
    """A disc ``B(x*, r)`` holding exactly one zero (Newton-Kantorovich contraction), or None.

    Tried only when the Newton correction at the cell's centre is below ``4 size`` (a zero
    predicted nearby). ``r`` is the largest radius with ``kappa = ||J^{-1}|| (r S + e_J) <= 1/2``
    (less 1 %: the larger the disc, the more cells it settles), and the proof needs
    ``||J^{-1}|| (|f| + err) <= (1 - kappa) r``.
    """
    if probe(x0) > 4.0 * size:
        return None  # no zero predicted near this cell: not worth the Newton steps
    x, f, J, err = newton(x0)
    if not np.all(np.isfinite(x)):
        return None
    try:
        jinv = float(np.linalg.norm(np.linalg.inv(J), 2))
    except np.linalg.LinAlgError:
        return None
    if not np.isfinite(jinv):
        return None
    e_j = 1e-12 * float(np.linalg.norm(J, 2)) + err * dscale
    step = jinv * (abs(f) + err)
    r = 0.99 * (0.5 / jinv - e_j) / second if second > 0 else 4.0 * size
    kappa = jinv * (r * second + e_j)
    if r > 0.0 and kappa < 0.5 and step <= (1.0 - kappa) * r:
        return x, r
    return None
