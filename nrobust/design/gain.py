"""One gain, exactly: the gain of an affine loop that maximises its delay margin or its decay rate.

The loop is an :class:`~nrobust.margins.AffineGainLoop`,
``F(s; delta, K) = A(s) + (B_0(s) + K R(s)) e^{-delta s}`` (``U_BS2(K)``'s, eq. (60), is one).
Its delay margin ``delta*(K)`` is the lower envelope of the *crossing curves*: on
``s = i w`` a root lies on the axis when ``g(w; K) = |A(i w)|^2 - |B(i w; K)|^2 = 0``, which
is quadratic in ``K`` with the explicit roots ``K_pm(w) = m(w) +- sqrt(D(w))``
(:mod:`nrobust.margins.gain`), at the delay ``d(w) = theta(w) / w``,
``theta = arg(-B(i w; K)/A(i w)) in [0, 2 pi)``. Each branch, cut where ``K_pm(w)`` turns
(a *pair birth*: ``g = dg/dw = 0``), where ``D < 0`` or where ``theta`` wraps, is a curve
``w -> (K(w), d(w))`` with ``K`` monotone, and ``delta*(K)`` is the smallest ``d`` over the
curves that reach ``K`` (zero where the nominal loop is unstable). It is neither smooth nor
continuous, and its maximum over ``[K_lo, K_hi]`` is one of:

* a *kink*: two curves meet, ``g(w_1; K) = g(w_2; K) = 0`` and ``d_1 = d_2``: a Newton
  iteration in ``(K, w_1, w_2)`` with the exact Jacobian;
* a *pair birth*: the envelope jumps down where a curve is born (``dK/dw = 0``, solved by
  ``brentq`` in ``w``); the supremum is approached from the side without the pair and not
  attained, so the design is that gain moved ``1e-10`` (relative) to that side;
* an *interior smooth max* of one curve: ``d(d)/dw = 0`` along the branch (``brentq``);
* an *end* of ``[K_lo, K_hi]``.

:func:`best_margin` samples the curves on a uniform frequency grid up to a frequency bound
of the whole gain range (:class:`~nrobust.margins.gain.AxisBound`, else
:func:`~nrobust.margins.frequency_bound`), builds the envelope on a fine gain grid, solves the
equation of the event at each local maximum near the top, and certifies the design: the
delay margin at the gain found (:func:`nrobust.margins.delay_margin`, proven in ball
arithmetic with ``rigorous=True``) must equal the value of the equations, else a
:class:`~nrobust.errors.CertificationError` says that the scan missed a curve.
:func:`best_decay_rate` maximises the decay rate ``-alpha(K)`` (``alpha`` the spectral
abscissa at ``delta = 0``) subject to ``delta*(K) >= d``: the feasible gains are where the
envelope is at least ``d``, ended by a curve crossing the level ``d`` (the *crossing* end of
:func:`~nrobust.margins.locate_gain_ends`) or a pair birth below it.

Features of the curves narrower than the scan step (``pi / (32 T)``, ``T`` the longest delay
of the factors, or ``W / 256``, ``W`` the frequency bound) can be missed (near the
strong-stability bound, crossing pairs are born within tiny gain intervals: on the paper's
plant, gains within about 1 % of it); the returned margin is certified whatever happens between
samples, and a missed curve that would lower it is caught by the certificate
(:class:`~nrobust.errors.CertificationError`, never a wrong margin).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._json import fields_dict
from .._validate import finite_real, positive, positive_int
from ..errors import CertificationError, ParameterError
from ..margins.axis import frequency_bound
from ..margins.gain import AffineGainLoop, AxisBound, GainEnd, nominally_stable
from ..margins.margin import DelayMargin, delay_margin
from ..roots import SpectralAbscissa, spectral_abscissa

__all__ = ["DESIGN_KINDS", "GainDesign", "best_decay_rate", "best_margin"]

#: Kinds of an optimal gain (:attr:`GainDesign.kind`).
DESIGN_KINDS = ("kink", "pair birth", "end", "interior smooth max", "margin constraint", "no crossing")
# Samples of the axis per half period pi / T of the fastest oscillation of the factors.
_STEPS = 32
# Samples of the axis up to the frequency bound, at least.
_MIN_SAMPLES = 256
# Evaluations of the factors per sample of the axis (values and slopes of A, B_0, R).
_EVALS_PER_SAMPLE = 6
# Gains of the envelope grid.
_N_GAINS = 2001
# A gain whose supremum is not attained (a pair birth) is moved this far (relative) to the good side.
_OFFSET = 1e-10
# Local maxima of the sampled envelope within this fraction of the largest are solved.
_NEAR_TOP = 0.05
_NEWTON_STEPS = 30
# Relative Newton step below which steps that stop halving are the rounding floor of g (a loop whose
# distributed terms were computed in floating point, e.g. an output feedback's observer term).
_NOISE_STEP = 1e-12
_TWO_PI = 2.0 * np.pi


@dataclass(frozen=True, eq=False)
class GainDesign:
    """A gain chosen by :func:`best_margin` or :func:`best_decay_rate`, with its certificate.

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    K : float
        The designed gain.
    objective : str
        ``"margin"`` or ``"decay_rate"``.
    value : float
        The objective at ``K``: the certified delay margin, or the decay rate ``-alpha`` of
        the loop at ``delta = 0``.
    margin : float
        The delay margin at ``K`` (``certificate.margin``).
    decay_rate : float
        ``-alpha(K)``, ``alpha`` the spectral abscissa of ``F(.; 0, K)``.
    kind : str
        What decides the optimum (:data:`DESIGN_KINDS`): ``"kink"`` (two crossing curves meet),
        ``"pair birth"`` (the margin jumps down where a crossing pair is born: the supremum is
        not attained, ``K`` is ``1e-10`` (relative) on the good side), ``"interior smooth max"``,
        ``"end"`` (an end of the gain bounds), ``"margin constraint"`` (the decay rate is
        largest where ``delta*(K) = d``: :attr:`end` gives the event), ``"no crossing"``
        (an infinite margin).
    K_bracket : (float, float)
        The optimal gain lies in it (for a pair birth: the birth and ``K``).
    value_bracket : (float, float)
        The optimal value (supremum) lies in it.
    bounds : (float, float)
        The gains searched.
    certificate : DelayMargin
        The delay margin of the designed loop, proven in ball arithmetic when
        ``certified == "proven"``.
    certified : str
        ``"proven"`` (``delay_margin(..., rigorous=True)``) or ``"checked"`` (floating point,
        verified by a certified root count); with the reason when a proof was asked and failed.
    abscissa : SpectralAbscissa
        The spectral abscissa of ``F(.; 0, K)``.
    gains, envelope : ndarray
        The scan: ``delta*(K)`` interpolated on the sampled crossing curves at 2001 gains of
        ``bounds`` (0 where the nominal loop is unstable). What located the optimum, not a
        certificate (to draw ``delta*(K)``).
    end : GainEnd or None
        For ``"margin constraint"``: the end of the feasible gains (``"crossing"``: a crossing
        delay equals ``d``; ``"pair_birth"``: a pair born with delay below ``d``).
    """

    K: float
    objective: str
    value: float
    margin: float
    decay_rate: float
    kind: str
    K_bracket: tuple[float, float]
    value_bracket: tuple[float, float]
    bounds: tuple[float, float]
    certificate: DelayMargin
    certified: str
    abscissa: SpectralAbscissa
    gains: NDArray[np.float64]
    envelope: NDArray[np.float64]
    end: GainEnd | None = None

    @property
    def accuracy(self) -> tuple[float, float]:
        """``(width of K_bracket, width of value_bracket)``: how tightly the optimum is known."""
        (k_lo, k_hi), (v_lo, v_hi) = self.K_bracket, self.value_bracket
        return (k_hi - k_lo, 0.0 if v_hi == v_lo else v_hi - v_lo)

    def __repr__(self) -> str:
        return (
            f"GainDesign(K={self.K:.12g}, objective={self.objective!r}, kind={self.kind!r}, "
            f"margin={self.margin:.12g}, decay_rate={self.decay_rate:.12g}, accuracy=({self.accuracy[0]:.2g}, "
            f"{self.accuracy[1]:.2g}), certified={self.certified!r})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (the certificate and abscissa as their dictionaries)."""
        data = fields_dict(self, exclude=("end",))
        data["end"] = None if self.end is None else self.end._asdict()
        data["accuracy"] = list(self.accuracy)
        return data


@dataclass(frozen=True, eq=False)
class _Piece:
    """One crossing curve: samples ``lo..hi`` of the branch ``sigma``, ``K`` monotone, with its joints."""

    sigma: float
    w: NDArray[np.float64]
    K: NDArray[np.float64]
    d: NDArray[np.float64]
    start: str  # how it begins and ends: "birth", "junction", "wrap", "edge"
    stop: str

    def at(self, K: float) -> tuple[float, float] | None:
        """Interpolated ``(w, d)`` where the piece reaches ``K``, or None."""
        order = np.argsort(self.K)
        Ks = self.K[order]
        if self.K.size < 2 or not Ks[0] <= K <= Ks[-1]:
            return None
        return float(np.interp(K, Ks, self.w[order])), float(np.interp(K, Ks, self.d[order]))


class _Curves:
    """The crossing curves of an affine loop for the gains ``[K_lo, K_hi]``, sampled and exact."""

    def __init__(self, loop: AffineGainLoop, K_lo: float, K_hi: float, max_evals: int) -> None:
        self.loop, self.K_lo, self.K_hi = loop, K_lo, K_hi
        W = _crossing_bound(loop, K_lo, K_hi)
        T = max(loop.A.max_delay, loop.B0.max_delay, loop.R.max_delay, 1e-3)
        # a power of two (exact uniform samples), at least _MIN_SAMPLES up to W
        dw = float(2.0 ** np.floor(np.log2(min(np.pi / (_STEPS * T), W / _MIN_SAMPLES))))
        self.W, self.dw = W, dw
        n = max(int(np.ceil(W / dw)), 16)
        if n > max_evals // _EVALS_PER_SAMPLE:
            raise CertificationError(
                f"the crossing curves of the gains [{K_lo:.12g}, {K_hi:.12g}] extend to W = {W:.6g}: sampling them "
                f"needs about {_EVALS_PER_SAMPLE * n:.3g} evaluations, beyond max_evals={max_evals} (gains closer "
                "to the strong-stability bound need more)"
            )
        w = dw * np.arange(1, n + 1, dtype=float)
        D, m, root, dm, dD, at = self._sample(w)
        junctions = self._junctions(w, D)
        self.pieces: list[_Piece] = []
        for sigma in (1.0, -1.0):
            K = m + sigma * root
            slope = dm + sigma * dD / (2.0 * np.maximum(root, 1e-300))
            theta = np.mod(np.angle(-(at.b0 + K * at.r) / at.a), _TWO_PI)
            self._cut(sigma, w, K, slope, theta / w, theta, D, junctions)
        self.gains = np.linspace(K_lo, K_hi, _N_GAINS)
        self.envelope, self.active = self._envelope(self.gains)

    def _sample(self, w: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray, NDArray, NDArray, Any]:
        """``D, m, sqrt D, m', D'`` and the loop on the axis at ``w``."""
        at = self.loop.axis(w, slopes=True)
        D, m, root = at.branches()
        dm, dD = at.branch_slopes()
        return D, m, root, dm, dD, at

    def _junctions(self, w: NDArray[np.float64], D: NDArray[np.float64]) -> dict[int, NDArray[np.float64]]:
        """Points of the branches between each junction (``D = 0``, in ``[w_j, w_{j+1}]``) and the valid sample.

        Near a junction ``K_pm - m ~ sqrt(D)``: the points are spaced quadratically towards
        the junction, located by eight Illinois steps on ``D`` (vectorised over the junctions).
        Keyed by ``j``; each array runs from the junction to the valid sample.
        """
        j = np.flatnonzero((D[:-1] >= 0.0) != (D[1:] >= 0.0))
        if not j.size:
            return {}
        a, b, fa, fb = w[j].copy(), w[j + 1].copy(), D[j].copy(), D[j + 1].copy()
        for _ in range(8):  # Illinois: the end kept twice has its value halved
            x = np.clip(a - fa * (b - a) / (fb - fa), np.minimum(a, b), np.maximum(a, b))
            fx = self._sample(x)[0]
            left = np.sign(fx) == np.sign(fa)
            fb = np.where(left, 0.5 * fb, fb)
            fa = np.where(left, fa, 0.5 * fa)
            a, fa = np.where(left, x, a), np.where(left, fx, fa)
            b, fb = np.where(left, b, x), np.where(left, fb, fx)
        wj = np.where(np.abs(fa) < np.abs(fb), a, b)  # K = m there: sqrt(D) is clipped at 0
        valid_end = np.where(D[j] >= 0.0, w[j], w[j + 1])
        t = np.linspace(0.0, 1.0, 10)[:-1] ** 2
        return {int(k): wj_k + (v - wj_k) * t for k, wj_k, v in zip(j, wj, valid_end)}

    def _cut(
        self,
        sigma: float,
        w: NDArray,
        K: NDArray,
        slope: NDArray,
        d: NDArray,
        theta: NDArray,
        D: NDArray,
        junctions: dict[int, NDArray[np.float64]],
    ) -> None:
        """Cut the branch into monotone pieces at extrema (births), junctions and phase wraps."""
        valid = D >= 0.0
        turn = valid[:-1] & valid[1:] & (np.sign(slope[:-1]) * np.sign(slope[1:]) < 0)
        wrap = valid[:-1] & valid[1:] & (np.abs(np.diff(theta)) > np.pi)
        gap = valid[:-1] != valid[1:]
        cuts = np.flatnonzero(turn | wrap | gap)
        start, how = 0, "edge"
        for c in [*cuts.tolist(), w.size - 1]:
            lo, hi = start, c
            if c == w.size - 1:
                stop = "edge"
            elif turn[c]:
                stop = "birth"
            elif wrap[c]:
                stop = "wrap"
            else:
                stop = "junction"
            if valid[lo] and valid[hi]:
                ws, Ks, ds = w[lo : hi + 1], K[lo : hi + 1], d[lo : hi + 1]
                if how == "birth":  # the extremum between the samples, from the linear slope
                    ws, Ks, ds = self._extremum(w, K, slope, d, lo - 1, ws, Ks, ds, first=True)
                if stop == "birth":
                    ws, Ks, ds = self._extremum(w, K, slope, d, hi, ws, Ks, ds, first=False)
                if how == "junction" and lo - 1 in junctions:
                    wx, Kx, dx = self._on_branch_many(junctions[lo - 1], sigma)
                    ws, Ks, ds = np.r_[wx, ws], np.r_[Kx, Ks], np.r_[dx, ds]
                if stop == "junction" and hi in junctions:
                    wx, Kx, dx = self._on_branch_many(junctions[hi], sigma)
                    ws, Ks, ds = np.r_[ws, wx[::-1]], np.r_[Ks, Kx[::-1]], np.r_[ds, dx[::-1]]
                self.pieces.append(_Piece(sigma, ws, Ks, ds, how, stop))
            start, how = c + 1, stop

    def _on_branch_many(self, w: NDArray[np.float64], sigma: float) -> tuple[NDArray, NDArray, NDArray]:
        """``(w, K, d)`` on the branch ``sigma`` at the points ``w`` from a junction (``w[0]``, where ``K = m``)."""
        _, m, root, _, _, at = self._sample(w)
        root[0] = 0.0  # both branches meet at the same gain
        K = m + sigma * root
        theta = np.mod(np.angle(-(at.b0 + K * at.r) / at.a), _TWO_PI)
        return w, K, theta / w

    @staticmethod
    def _extremum(
        w: NDArray, K: NDArray, slope: NDArray, d: NDArray, j: int, ws: NDArray, Ks: NDArray, ds: NDArray, first: bool
    ) -> tuple[NDArray, NDArray, NDArray]:
        """Add the estimated turning point on ``[w_j, w_{j+1}]`` to a piece."""
        t = slope[j] / (slope[j] - slope[j + 1])
        we = w[j] + t * (w[j + 1] - w[j])
        Ke = K[j] + 0.5 * slope[j] * (we - w[j])
        de = d[j] + t * (d[j + 1] - d[j])
        if first:
            return np.r_[we, ws], np.r_[Ke, Ks], np.r_[de, ds]
        return np.r_[ws, we], np.r_[Ks, Ke], np.r_[ds, de]

    def _envelope(self, gains: NDArray) -> tuple[NDArray, NDArray]:
        """The smallest interpolated delay over the pieces at each gain, and the piece that gives it."""
        env = np.full(gains.size, np.inf)
        active = np.full(gains.size, -1)
        for p, piece in enumerate(self.pieces):
            if piece.K.size < 2:
                continue
            order = np.argsort(piece.K)
            Ks, ds = piece.K[order], piece.d[order]
            inside = (gains >= Ks[0]) & (gains <= Ks[-1])
            val = np.interp(gains[inside], Ks, ds)
            better = val < env[inside]
            idx = np.flatnonzero(inside)[better]
            env[idx], active[idx] = val[better], p
        return env, active

    # ------------------------------------------------------------------ exact evaluations
    def on_branch(self, w: float, sigma: float) -> tuple[float, float, float, float]:
        """Exact ``(K, d, dK/dw, dd/dw)`` on the branch ``sigma`` at ``w``."""
        at = self.loop.axis(np.array([w]), slopes=True)
        _, m, root = at.branches()
        dm, dD = at.branch_slopes()
        K = float(m[0] + sigma * root[0])
        dK = float(dm[0] + sigma * dD[0] / (2.0 * max(float(root[0]), 1e-300)))
        a, da = complex(at.a[0]), complex(at.da[0])  # type: ignore[index]
        b = complex(at.b0[0] + K * at.r[0])
        db = complex(at.db0[0] + K * at.dr[0])  # type: ignore[index]
        theta = float(np.mod(np.angle(-b / a), _TWO_PI))
        d = theta / w
        theta_w = (db / b - da / a).imag
        theta_K = complex(at.r[0] / b).imag
        return K, d, dK, ((theta_w + theta_K * dK) / w - d / w)

    def at_gain(self, K: float, w0: float, theta0: float | None = None) -> tuple[float, float, float, float]:
        """Newton on ``g(w; K) = 0`` from ``w0``: ``(w, d, dd/dK, dg/dw)`` (``d`` near ``theta0 / w``)."""
        w, previous = w0, np.inf
        for _ in range(_NEWTON_STEPS):
            a, b, da, db, r = self._values(np.array([w]), K)
            g = abs(a) ** 2 - abs(b) ** 2
            gw = 2.0 * ((np.conj(a) * da).real - (np.conj(b) * db).real)
            step = float(g / gw)
            w -= step
            # converged, or at the rounding floor of g (steps of 1e-12 relative that stop shrinking)
            if abs(step) <= 4e-16 * w or (abs(step) <= _NOISE_STEP * w and abs(step) > 0.5 * previous):
                break
            previous = abs(step)
        else:
            raise CertificationError(f"best_margin: Newton on |A(i w)| = |B(i w)| did not converge at K = {K:.15g}")
        a, b, da, db, r = self._values(np.array([w]), K)
        theta = float(np.mod(np.angle(-b / a), _TWO_PI))
        if theta0 is not None and abs(theta - theta0) > np.pi:  # the same branch of the phase
            theta += _TWO_PI * np.round((theta0 - theta) / _TWO_PI)
        g_w = 2.0 * ((np.conj(a) * da).real - (np.conj(b) * db).real)
        g_K = -2.0 * (np.conj(b) * r).real
        theta_w = (db / b - da / a).imag
        theta_K = (r / b).imag
        dw_dK = -g_K / g_w
        d = theta / w
        return w, d, (theta_K + theta_w * dw_dK) / w - d * dw_dK / w, g_w

    def _values(self, w: NDArray, K: float) -> tuple[complex, complex, complex, complex, complex]:
        at = self.loop.axis(w, slopes=True)
        return (
            complex(at.a[0]),
            complex(at.b0[0] + K * at.r[0]),
            complex(at.da[0]),  # type: ignore[index]
            complex(at.db0[0] + K * at.dr[0]),  # type: ignore[index]
            complex(at.r[0]),
        )

    def kink(self, starts: list[float], p: _Piece, q: _Piece) -> tuple[float, float, float, float]:
        """Newton in ``(K, w_1, w_2)`` on ``g(w_1; K) = g(w_2; K) = 0``, ``d_1 = d_2``: ``(K, d, w_1, w_2)``.

        Started at the first gain of ``starts`` that both curves reach.
        """
        reached = [K for K in starts if p.at(K) is not None and q.at(K) is not None]
        if not reached:
            raise CertificationError(f"best_margin: the kink near K = {starts[0]:.12g} is not reached by both curves")
        K0 = reached[0]
        s1, s2 = p.at(K0), q.at(K0)
        assert s1 is not None and s2 is not None
        x = np.array([K0, s1[0], s2[0]])
        th = [s1[1] * s1[0], s2[1] * s2[0]]
        scale = max(abs(self.K_lo), abs(self.K_hi), 1e-300)
        for _ in range(_NEWTON_STEPS):
            rows, rhs = [], []
            ds = []
            for k, (wk, t0) in enumerate(zip(x[1:], th)):
                a, b, da, db, r = self._values(np.array([wk]), x[0])
                theta = float(np.mod(np.angle(-b / a), _TWO_PI))
                theta += _TWO_PI * np.round((t0 - theta) / _TWO_PI)
                g_w = 2.0 * ((np.conj(a) * da).real - (np.conj(b) * db).real)
                g_K = -2.0 * (np.conj(b) * r).real
                row = [g_K, 0.0, 0.0]
                row[1 + k] = g_w
                rows.append(row)
                rhs.append(abs(a) ** 2 - abs(b) ** 2)
                ds.append((theta / wk, (r / b).imag / wk, ((db / b - da / a).imag - theta / wk) / wk))
            (d1, d1K, d1w), (d2, d2K, d2w) = ds
            J = np.array([*rows, [d1K - d2K, d1w, -d2w]])
            step = np.linalg.solve(J, np.array([*rhs, d1 - d2]))
            x = x - step
            if abs(step[0]) <= 1e-15 * scale and np.all(np.abs(step[1:]) <= 1e-15 * np.abs(x[1:])):
                break
        else:
            raise CertificationError(f"best_margin: the kink equations near K = {K0:.12g} did not converge")
        if abs(x[1] - x[2]) <= 1e-8 * x[1]:
            raise CertificationError(f"best_margin: the two curves near K = {K0:.12g} meet at one frequency")
        return float(x[0]), 0.5 * (d1 + d2), float(x[1]), float(x[2])

    def value(self, K: float) -> float:
        """The envelope at ``K`` with each curve reaching it solved exactly (inf: none)."""
        best = float("inf")
        for piece in self.pieces:
            s = piece.at(K)
            if s is not None and s[1] < 1.05 * best:  # a curve that may be the lowest (5 %: the scan interpolates it)
                best = min(best, self.at_gain(K, s[0], s[1] * s[0])[1])
        return best


def _crossing_bound(loop: AffineGainLoop, K_lo: float, K_hi: float) -> float:
    """A frequency above every crossing of every gain in ``[K_lo, K_hi]`` (the bounds are convex in ``K``)."""
    second = AxisBound.of(loop)
    if second is not None:
        W = second.W(K_lo, K_hi)
        if np.isfinite(W):
            return W
    out = 0.0
    for K in (K_lo, K_hi):
        b = frequency_bound(loop.A, loop.B(K))
        if b is None:
            raise ParameterError(
                "bounds",
                f"gains where the loop's difference operator is strongly stable (no frequency bound at K = {K:.12g})",
                (K_lo, K_hi),
            )
        out = max(out, float(b[0]))
    return out


def _checked_loop(loop: Any, bounds: Any) -> tuple[float, float]:
    if not isinstance(loop, AffineGainLoop):
        raise ParameterError("loop", "an AffineGainLoop A + (B_0 + K R) e^{-delta s}", type(loop).__name__)
    if not (loop.A.is_real and loop.B0.is_real and loop.R.is_real):
        raise ParameterError("loop", "real coefficients (crossings in conjugate pairs)", loop)
    try:
        lo, hi = (finite_real("bounds", b) for b in bounds)
    except TypeError:
        raise ParameterError("bounds", "a pair (K_lo, K_hi) of finite numbers with K_lo < K_hi", bounds) from None
    if not lo < hi:
        raise ParameterError("bounds", "a pair (K_lo, K_hi) of finite numbers with K_lo < K_hi", bounds)
    return lo, hi


def _certify(loop: AffineGainLoop, K: float, rigorous: bool, max_evals: int) -> tuple[DelayMargin, str]:
    """The delay margin at ``K``: proven when asked and possible, else checked."""
    A, B = loop.A, loop.B(K)
    if rigorous:
        try:
            return delay_margin(A, B, max_evals=max_evals, rigorous=True), "proven"
        except CertificationError as exc:
            return delay_margin(A, B, max_evals=max_evals), f"checked (the proof failed: {exc})"
    return delay_margin(A, B, max_evals=max_evals), "checked"


def _nominal_mask(curves: _Curves, loop: AffineGainLoop) -> NDArray[np.bool_]:
    """Nominal stability of ``F(.; 0, K)`` on the envelope grid: it changes only where a curve's delay wraps
    through 0 (a root on the axis at ``delta = 0``) or at ``s = 0``; decided once between two such gains."""
    cuts = [float(p.K[-1]) for p in curves.pieces if p.stop == "wrap"]
    s0 = np.array([0j])
    r0 = complex(loop.R(s0)[0])
    if r0 != 0.0:  # s = 0 is a root at K0 = -S(0)/R(0), for every delay
        K0 = -complex(loop.S(s0)[0]) / r0
        if abs(K0.imag) <= 1e-12 * max(abs(K0), 1.0):
            cuts.append(K0.real)
    edges = sorted(c for c in cuts if curves.K_lo < c < curves.K_hi)
    bounds = [curves.K_lo, *edges, curves.K_hi]
    mask = np.zeros(curves.gains.size, dtype=bool)
    for lo, hi in itertools.pairwise(bounds):
        inside = (curves.gains > lo) & (curves.gains < hi) if hi > lo else np.zeros_like(mask)
        if inside.any() and nominally_stable(loop, 0.5 * (lo + hi)):
            mask |= inside
    mask[0] = mask[0] or (curves.gains.size > 1 and mask[1] and nominally_stable(loop, curves.K_lo))
    mask[-1] = mask[-1] or (curves.gains.size > 1 and mask[-2] and nominally_stable(loop, curves.K_hi))
    return mask


def _candidates(env: NDArray) -> list[int]:
    """Grid indices of the local maxima of the sampled envelope near its top."""
    top = float(np.max(env))
    n = env.size
    out = []
    for i in range(n):
        left = env[i - 1] if i > 0 else -np.inf
        right = env[i + 1] if i < n - 1 else -np.inf
        if env[i] >= left and env[i] >= right and env[i] >= (1.0 - _NEAR_TOP) * top:
            out.append(i)
    return out


def _solve_candidate(curves: _Curves, i: int) -> tuple[float, float, str, tuple, tuple]:
    """The exact optimum near the grid index ``i``: ``(K_design, value, kind, K_bracket, value_bracket)``."""
    gains, active = curves.gains, curves.active
    n = gains.size
    scale = max(abs(curves.K_lo), abs(curves.K_hi))
    for j in (i - 1, i + 1):
        if not 0 <= j < n or active[j] == active[i] or active[j] < 0 or active[i] < 0:
            continue
        p, q = curves.pieces[active[i]], curves.pieces[active[j]]
        lo, hi = sorted((gains[i], gains[j]))
        birth = _birth_in(curves, q, lo, hi) if "birth" in (q.start, q.stop) else None
        if birth is not None:
            Kb, _ = birth
            side = 1.0 if gains[i] > Kb else -1.0
            K = Kb + side * _OFFSET * max(scale, 1e-300)
            v = curves.value(K)
            # the supremum lies between v and the envelope at Kb from the good side
            w_p = p.at(Kb)
            sup = curves.at_gain(Kb, w_p[0], w_p[1] * w_p[0])[1] if w_p is not None else v
            return K, v, "pair birth", tuple(sorted((Kb, K))), (min(v, sup), max(v, sup))
        if p.start == "junction" or p.stop == "junction" or q.start == "junction" or q.stop == "junction":
            if p.sigma != q.sigma and abs(p.w[-1] - q.w[-1]) + abs(p.w[0] - q.w[0]) < 4 * curves.dw:
                continue  # the same curve through a junction: smooth
        try:
            K, d, _, _ = curves.kink([0.5 * (lo + hi), float(gains[i]), float(gains[j])], p, q)
        except CertificationError:  # near a birth w(K) turns: d_1(K) - d_2(K) = 0 bracketed in K instead
            K, d = _bracketed_kink(curves, p, q, float(lo), float(hi))
        h = 1e-12 * max(scale, 1e-300)
        vals = [min(curves.at_gain(Kx, *_start(r, Kx))[1] for r in (p, q)) for Kx in (K - h, K + h)]
        return K, d, "kink", (K - h, K + h), (min(*vals, d), d)
    if i in (0, n - 1):
        K = float(gains[i])
        v = curves.value(K)
        return K, v, "end", (K, K), (v, v)
    return _smooth_max(curves, i)


def _bracketed_kink(curves: _Curves, p: _Piece, q: _Piece, lo: float, hi: float) -> tuple[float, float]:
    """The kink of ``p`` and ``q`` in ``[lo, hi]`` by ``brentq`` on ``d_p(K) - d_q(K)``: ``(K, d)``.

    Each delay is solved at fixed ``K`` by Newton in ``w`` (:meth:`_Curves.at_gain`); the two
    grid gains where the lower interpolated curve changes, widened until the exact delays change
    order, bracket it.
    """
    from scipy.optimize import brentq  # loaded on first use (the start-up of the commands)

    def gap(K: float) -> float:
        return curves.at_gain(K, *_start(p, K))[1] - curves.at_gain(K, *_start(q, K))[1]

    cell = float(curves.gains[1] - curves.gains[0])
    for cells in (0, 2, 8, 32):  # the interpolated curves may cross a few cells away from the exact ones
        a, b = lo - cells * cell, hi + cells * cell
        if any(r.at(x) is None for r in (p, q) for x in (a, b)):
            break
        if gap(a) * gap(b) <= 0:
            K = brentq(gap, a, b, xtol=1e-15 * max(abs(a), abs(b), 1e-300), rtol=1e-15)
            return K, curves.at_gain(K, *_start(p, K))[1]
    raise CertificationError(
        f"best_margin: the two crossing curves do not change order near [{lo:.15g}, {hi:.15g}]: the scan's "
        "interpolated curves are off there (features narrower than its step, as near the strong-stability bound, "
        "where crossing pairs near w = k pi / tau are born within tiny gain intervals); narrower bounds away from "
        "that limit would help"
    )


def _start(piece: _Piece, K: float) -> tuple[float, float]:
    s = piece.at(K)
    assert s is not None
    return s[0], s[1] * s[0]


def _birth_in(curves: _Curves, piece: _Piece, lo: float, hi: float) -> tuple[float, float] | None:
    """The birth that starts or ends ``piece`` with its gain in ``[lo, hi]`` (widened by a few cells): ``(K, w)``."""
    from scipy.optimize import brentq  # scipy.optimize loads on first use (the start-up of the commands)

    width = 4.0 * (curves.gains[1] - curves.gains[0])
    for at_start in (True, False):
        if (piece.start if at_start else piece.stop) != "birth":
            continue
        we = piece.w[0] if at_start else piece.w[-1]
        if not lo - width <= (piece.K[0] if at_start else piece.K[-1]) <= hi + width:
            continue  # the estimated birth (the interpolated turning point) is elsewhere
        a, b = we - curves.dw, we + curves.dw
        slope = lambda x: curves.on_branch(x, piece.sigma)[2]  # noqa: E731
        fa, fb = slope(a), slope(b)
        if fa * fb > 0:
            continue
        wb = brentq(slope, a, b, xtol=1e-15 * we, rtol=1e-15)
        Kb = curves.on_branch(wb, piece.sigma)[0]
        if lo - width <= Kb <= hi + width:
            return Kb, wb
    return None


def _smooth_max(curves: _Curves, i: int) -> tuple[float, float, str, tuple, tuple]:
    """An interior maximum of one curve: ``d(d)/dw = 0`` along its branch (``brentq`` between samples)."""
    from scipy.optimize import (
        brentq,
        minimize_scalar,
    )  # scipy.optimize loads on first use (the start-up of the commands)

    piece = curves.pieces[curves.active[i]]
    K0 = float(curves.gains[i])
    dg = curves.gains[1] - curves.gains[0]

    def slope(x: float) -> float:
        return curves.on_branch(x, piece.sigma)[3]

    for cells in (2, 8, 32):  # the sampled curve's maximum is off by its interpolation error
        s_lo, s_hi = piece.at(K0 - cells * dg), piece.at(K0 + cells * dg)
        if s_lo is None or s_hi is None:
            break
        a, b = sorted((s_lo[0], s_hi[0]))
        if slope(a) * slope(b) < 0:
            w = brentq(slope, a, b, xtol=1e-15 * b, rtol=1e-15)
            K, d, dK, _ = curves.on_branch(w, piece.sigma)
            half = abs(dK) * 4e-15 * w  # the bracket of w mapped to K; the value is flat there
            return K, d, "interior smooth max", (K - half, K + half), (d, d)
    # across a junction: Brent's bounded search on the exact envelope
    res = minimize_scalar(
        lambda K: -curves.value(K), bounds=(K0 - 8 * dg, K0 + 8 * dg), method="bounded", options={"xatol": 1e-12}
    )
    K, v = float(res.x), float(-res.fun)
    # Brent's search locates a smooth maximum to about sqrt(eps): the value may be higher by f''/2 width^2
    width = float(np.sqrt(2.2e-16) * max(abs(K), 1.0)) + 1e-12
    h = 1e-4 * max(_scale(curves), 1e-300)
    second = abs(curves.value(K + h) - 2.0 * v + curves.value(K - h)) / h**2
    return K, v, "interior smooth max", (K - width, K + width), (v, v + second * width**2)


def _scale(curves: _Curves) -> float:
    """The scale of the gains: the largest ``|K|`` of the bounds."""
    return max(abs(curves.K_lo), abs(curves.K_hi))


def _abscissa(loop: AffineGainLoop, K: float) -> SpectralAbscissa:
    return spectral_abscissa(loop.loop_at(K, 0.0))


def best_margin(
    loop: AffineGainLoop,
    bounds: tuple[float, float],
    *,
    rigorous: bool = False,
    max_evals: int = 2_000_000,
) -> GainDesign:
    """The gain in ``[K_lo, K_hi]`` with the largest delay margin, from the equations of its kind.

    ``delta*(K)`` is the lower envelope of the crossing curves (module docstring); its
    maximum is a kink (two curves meet: ``delta_1(K) = delta_2(K)``), a pair birth (a jump
    down: the supremum, approached from the side without the pair), an interior smooth
    maximum or an end. The curves are sampled once on a uniform frequency grid, the local
    maxima of the envelope within 5 % of the largest are solved from their equations
    (Newton with the exact Jacobian for a kink, ``brentq`` otherwise) and the best is
    certified.

    Parameters
    ----------
    loop : AffineGainLoop
        ``A + (B_0 + K R) e^{-delta s}`` with real coefficients (``U_BS2(K)``'s, eq. (60):
        :func:`nrobust.hyperbolic.analyses.kregion.u_bs2_loop`).
    bounds : (float, float)
        ``K_lo < K_hi``, where the difference operator is strongly stable (for ``U_BS2(K)``:
        ``|K| < (1 - |rho q|)/|q|``, eq. (54)).
    rigorous : bool, optional
        Prove the margin at the design in ball arithmetic (``certified == "proven"``); when
        the proof fails the margin is checked in floating point and ``certified`` says why.
    max_evals : int, optional
        Work bound of the sampling of the crossing curves (six evaluations per sample) and of
        the certifying delay margin.

    Returns
    -------
    GainDesign

    Raises
    ------
    ParameterError
        ``loop`` not an ``AffineGainLoop`` with real coefficients, ``bounds`` not increasing or
        reaching gains without a frequency bound.
    CertificationError
        The sampling would exceed ``max_evals``, an equation did not converge, or the certified
        margin at the design disagrees with the equations (a crossing curve missed by the scan).
    """
    lo, hi = _checked_loop(loop, bounds)
    max_evals = positive_int("max_evals", max_evals)
    curves = _Curves(loop, lo, hi, max_evals)
    env = np.where(_nominal_mask(curves, loop), curves.envelope, 0.0)
    scan = (curves.gains, env)
    if np.any(np.isinf(env)):  # gains that no crossing curve reaches, nominally stable: delta* = inf
        idx = np.flatnonzero(np.isinf(env))
        run = max(np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1), key=len)
        K = float(curves.gains[run[run.size // 2]])  # the middle of the longest run
        cert, how = _certify(loop, K, rigorous, max_evals)
        if not np.isinf(cert.margin):
            raise CertificationError(
                f"best_margin: no crossing curve reaches K = {K:.12g}, but its delay margin is {cert.margin}"
            )
        inf = float("inf")
        sa = _abscissa(loop, K)
        return GainDesign(
            K, "margin", inf, inf, -sa.value, "no crossing", (K, K), (inf, inf), (lo, hi), cert, how, sa, *scan
        )
    finite = env
    solved = [_solve_candidate(curves, i) for i in _candidates(finite)]
    K, value, kind, K_br, v_br = max(solved, key=lambda c: c[1])
    cert, how = _certify(loop, K, rigorous, max_evals)
    tol = 1e-9 * max(value, 1e-300) + (cert.accuracy or 0.0)
    if abs(cert.margin - value) > tol:
        raise CertificationError(
            f"best_margin: the {kind} at K = {K:.15g} gives delta* = {value:.15g} by its equations, the certified "
            f"delay margin there is {cert.margin:.15g}: a crossing curve was missed by the scan"
        )
    sa = _abscissa(loop, K)
    return GainDesign(
        K, "margin", cert.margin, cert.margin, -sa.value, kind, K_br, v_br, (lo, hi), cert, how, sa, *scan
    )


def _level_end(curves: _Curves, i: int, j: int, level: float) -> GainEnd:
    """The event between the feasible grid gain ``i`` and the infeasible ``j``: a curve crossing ``level``
    (``"crossing"``) or a pair born below it (``"pair_birth"``); the one nearest the feasible side."""
    from scipy.optimize import brentq  # scipy.optimize loads on first use (the start-up of the commands)

    lo, hi = sorted((curves.gains[i], curves.gains[j]))
    events: list[GainEnd] = []
    for piece in curves.pieces:
        for at_start in (True, False):
            if (piece.start if at_start else piece.stop) == "birth":
                found = _birth_in(curves, piece, lo, hi)
                if found is not None:
                    Kb, wb = found
                    db = curves.on_branch(wb, piece.sigma)[1]
                    if db < level and lo - (hi - lo) <= Kb <= hi + (hi - lo):
                        events.append(GainEnd(float(Kb), "pair_birth", float(wb), float(db)))
        d = piece.d - level
        change = np.flatnonzero(np.sign(d[:-1]) * np.sign(d[1:]) < 0)
        for c in change:
            Ka, Kc = sorted((piece.K[c], piece.K[c + 1]))
            if Kc < lo - (hi - lo) or Ka > hi + (hi - lo):
                continue

            def f(x: float, sigma: float = piece.sigma) -> float:
                return curves.on_branch(x, sigma)[1] - level

            wa, wc = piece.w[c], piece.w[c + 1]
            if f(wa) * f(wc) > 0:
                continue
            wx = brentq(f, wa, wc, xtol=1e-15 * wc, rtol=1e-15)
            events.append(GainEnd(curves.on_branch(wx, piece.sigma)[0], "crossing", float(wx), level))
    if not events:
        raise CertificationError(
            f"best_decay_rate: no equation found for the end of the feasible gains in [{lo:.12g}, {hi:.12g}]"
        )
    feasible = curves.gains[i]
    return min(events, key=lambda e: abs(e.K - feasible))


def best_decay_rate(
    loop: AffineGainLoop,
    bounds: tuple[float, float],
    *,
    margin_at_least: float,
    rigorous: bool = False,
    n_rates: int = 5,
    max_evals: int = 2_000_000,
) -> GainDesign:
    """The gain in ``[K_lo, K_hi]`` with the largest decay rate among those with ``delta*(K) >= d``.

    The decay rate is ``-alpha(K)``, ``alpha`` the spectral abscissa of the loop at
    ``delta = 0``, ``F(.; 0, K) = A + B_0 + K R``: the paper's trade-off (the remark after
    Lemma 3, section 4.2.1) sets the nominal convergence rate against the delay margin, and
    the constraint ``delta*(K) >= d`` already guarantees exponential stability for every delay
    in ``[0, d)``; the rate at a delay in ``(0, d]`` is another function of ``K``, not the one
    the target system fixes. The feasible gains are where the envelope of the crossing
    curves is at least ``d``; each of their ends is solved from its equation (a curve
    crossing ``d``: :func:`~nrobust.margins.locate_gain_ends`' ``"crossing"``; a pair born with
    delay below ``d``: ``"pair_birth"``) and moved ``1e-10`` (relative) inside. The rate is
    sampled at ``n_rates`` gains of each feasible interval, ends included; when the largest
    sample is an end, that end is the design (``kind`` ``"margin constraint"`` or ``"end"``),
    otherwise Brent's bounded search refines the interior maximum.

    Parameters
    ----------
    loop, bounds, rigorous, max_evals
        As in :func:`best_margin`.
    margin_at_least : float
        ``d > 0``: the delay margin required.
    n_rates : int, optional
        Gains at which the decay rate is sampled in each feasible interval (``>= 2``).

    Returns
    -------
    GainDesign
        ``value`` is the decay rate; ``end`` the event at a ``"margin constraint"`` optimum.

    Raises
    ------
    ParameterError
        As :func:`best_margin`; ``margin_at_least`` not positive.
    CertificationError
        No gain in the bounds has ``delta*(K) >= d``, an end could not be solved, or the
        certified margin at the design is below ``d``.
    """
    from scipy.optimize import minimize_scalar  # scipy.optimize loads on first use (the start-up of the commands)

    lo, hi = _checked_loop(loop, bounds)
    d = positive("margin_at_least", margin_at_least)
    n_rates = positive_int("n_rates", n_rates, 2)
    max_evals = positive_int("max_evals", max_evals)
    curves = _Curves(loop, lo, hi, max_evals)
    env = np.where(_nominal_mask(curves, loop), curves.envelope, 0.0)
    scan = (curves.gains, env)
    ok = env >= d
    if not ok.any():
        raise CertificationError(
            f"best_decay_rate: no gain in [{lo:.12g}, {hi:.12g}] has a delay margin >= {d:.12g} "
            f"(largest on the scan: {float(np.max(env)):.12g})"
        )
    scale = max(abs(lo), abs(hi))
    best: tuple[float, float, str, GainEnd | None, SpectralAbscissa] | None = None
    idx = np.flatnonzero(ok)
    runs = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)
    for run in runs:
        ends: list[tuple[float, GainEnd | None]] = []
        for k, side in ((run[0], -1), (run[-1], 1)):
            if k + side < 0 or k + side >= curves.gains.size:
                ends.append((float(curves.gains[k]), None))
                continue
            event = _level_end(curves, k, k + side, d)
            ends.append((event.K - side * _OFFSET * scale, event))
        (K_a, _), (K_b, _) = ends
        Ks = np.linspace(K_a, K_b, n_rates)
        sas = [_abscissa(loop, float(K)) for K in Ks]
        rates = np.array([-sa.value for sa in sas])
        k = int(np.argmax(rates))
        if k in (0, n_rates - 1):
            K_end, event_end = ends[0 if k == 0 else 1]
            cand: tuple[float, float, str, GainEnd | None, SpectralAbscissa] = (
                K_end,
                float(rates[k]),
                "end" if event_end is None else "margin constraint",
                event_end,
                sas[k],
            )
        else:
            res = minimize_scalar(
                lambda K: _abscissa(loop, K).value,
                bounds=(float(Ks[k - 1]), float(Ks[k + 1])),
                method="bounded",
                options={"xatol": 1e-10 * max(scale, 1e-300)},
            )
            sa = _abscissa(loop, float(res.x))
            cand = (float(res.x), -sa.value, "interior smooth max", None, sa)
        if best is None or cand[1] > best[1]:
            best = cand
    assert best is not None
    K, rate, kind, end, sa = best
    cert, how = _certify(loop, K, rigorous, max_evals)
    if not cert.margin >= d:
        raise CertificationError(
            f"best_decay_rate: the certified delay margin at the design K = {K:.15g} is {cert.margin:.15g} < {d:.15g}"
        )
    K_br, v_br = (K, K), (rate, rate)
    if end is not None:  # the supremum: the rate at the end itself (not feasible at a pair birth)
        K_br = (min(K, end.K), max(K, end.K))
        at_end = -_abscissa(loop, end.K).value
        v_br = (min(rate, at_end), max(rate, at_end))
    elif kind == "interior smooth max":
        K_br = (K - 1e-10 * max(scale, 1e-300), K + 1e-10 * max(scale, 1e-300))
    return GainDesign(K, "decay_rate", rate, cert.margin, rate, kind, K_br, v_br, (lo, hi), cert, how, sa, *scan, end)
