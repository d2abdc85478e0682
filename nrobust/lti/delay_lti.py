"""MIMO delay systems in LFT form with internal delays: :class:`DelayLTI`.

A :class:`DelayLTI` is the continuous-time system (the form of MATLAB's ``DelayLTI`` and of
ControlSystems.jl's ``DelayLtiSystem``)::

    x'(t) = A x(t) + B1 u(t) + B2 w(t)
    y(t)  = C1 x(t) + D11 u(t) + D12 w(t)
    z(t)  = C2 x(t) + D21 u(t) + D22 w(t)
    w(t)  = z(t - tau),   tau = (tau_1, ..., tau_k),  tau_i > 0, one delay per channel.

Input, output and internal delays are all channels of ``w``; the delay-free part is an
ordinary state-space system ``P`` with inputs ``(u, w)`` and outputs ``(y, z)``, so the
transfer function is the lower LFT ::

    H(s) = P11(s) + P12(s) Delta(s) (I - P22(s) Delta(s))^{-1} P21(s),
    Delta(s) = diag(e^{-tau_1 s}, ..., e^{-tau_k s}),

with ``P_ij(s) = C_i (sI - A)^{-1} B_j + D_ij``. A ``D22 != 0`` makes the system neutral
(a delayed loop without dynamics): the difference operator ``I - D22 Delta(s)`` must be
strongly stable (Hale and Verduyn Lunel, ``gamma_0 < 1``,
:class:`~nrobust.matrix_difference.MatrixDifferenceOperator`) for stability to survive
small changes of the delays.

Series, parallel and feedback connections keep this form: the states and the delay
channels of the two operands stack (the formulas are in :meth:`DelayLTI.feedback`).
The poles are the zeros of ::

    det M(s),   M(s) = [[sI - A, -B2 Delta(s)], [-C2, I - D22 Delta(s)]],

a :class:`~nrobust.qpmatrix.QuasiPolynomialMatrix` (``M [x; z] = [B1; D21] u`` in the
Laplace domain). Channels whose row or column of ``D22`` is zero are eliminated exactly
(a row or column operation against the unit pivot of ``I``), and the remaining
determinant is expanded into one :class:`~nrobust.quasipoly.QuasiPolynomial`, on which
:mod:`nrobust.roots` certifies the poles and the spectral abscissa. For a SISO system the
bordered determinant ``det [[M, b], [-c, d]] = det M (d + c M^{-1} b)`` (Schur) gives the
numerator: :meth:`DelayLTI.to_quasi_transfer` returns ``H = N / D`` as a
:class:`~nrobust.lti.transfer.QuasiTransferFunction`.

Coefficient orders: :func:`tf` takes polynomial coefficients in *descending* powers of
``s`` (python-control, ``numpy.poly1d``, MATLAB: ``tf([1, 2], [1, 3])`` is
``(s + 2)/(s + 3)``); :class:`~nrobust.quasipoly.QuasiPolynomial` and
:class:`~nrobust.lti.transfer.QuasiTransferFunction` take *ascending* powers (qpmr's
convention: ``QuasiPolynomial([[2, 1]], [0])`` is ``2 + s``).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._json import fields_dict
from .._validate import finite_real, is_real_number, nonnegative, number_array, real_array
from ..bounds import root_free_region
from ..errors import CertificationError, ParameterError
from ..matrix_difference import MatrixDifferenceOperator
from ..qpmatrix import QuasiPolynomialMatrix
from ..quasipoly import QuasiPolynomial
from ..roots import SpectralAbscissa, find_roots, spectral_abscissa
from .statespace import StateSpaceTDS
from .transfer import PoleSet, QuasiTransferFunction

if TYPE_CHECKING:
    import control

__all__ = ["DelayLTI", "as_delay_lti", "delay", "tf"]

_FIELDS = ("A", "B1", "B2", "C1", "C2", "D11", "D12", "D21", "D22")
# Largest matrix whose determinant is expanded (Leibniz: n! products), as QuasiPolynomialMatrix.
_MAX_EXPANDED = 8


def _is_control(obj: Any) -> bool:
    """True for a python-control LTI object (checked by module, without importing python-control)."""
    return type(obj).__module__.split(".")[0] == "control" and hasattr(obj, "ninputs")


def _frozen(a: NDArray[np.float64]) -> NDArray[np.float64]:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def _matrix(name: str, value: Any, shape: tuple[int, int]) -> NDArray[np.float64]:
    """``value`` as a real matrix of ``shape``; an empty value gives zeros when a dimension is 0."""
    if np.size(value) == 0 and 0 in shape:
        return np.zeros(shape)
    a = real_array(name, value, ndim=2, min_size=0)
    if a.shape != shape:
        raise ParameterError(name, f"a real {shape[0]} x {shape[1]} matrix", a.shape)
    return a


# Largest strongly connected block of D22 with several delays whose determinant is expanded exactly.
_EXPANSION_CHANNELS = 12


def _cyclic_components(D22: NDArray[np.float64]) -> list[NDArray[np.intp]]:
    """The strongly connected components of the graph of ``D22`` that contain a cycle."""
    k = D22.shape[0]
    reach = D22 != 0  # paths of length >= 1, closed transitively by squaring
    for _ in range(max(1, int(np.ceil(np.log2(max(k, 2)))) + 1)):
        reach = reach | ((reach.astype(np.int64) @ reach.astype(np.int64)) > 0)
    seen = np.zeros(k, dtype=bool)
    out = []
    for i in range(k):
        if reach[i, i] and not seen[i]:
            comp = np.flatnonzero(reach[i] & reach[:, i])
            seen[comp] = True
            out.append(comp)
    return out


def _det(rows: list[list[Fraction]]) -> Fraction:
    """Exact determinant by Gaussian elimination."""
    a = [r[:] for r in rows]
    n, det = len(a), Fraction(1)
    for j in range(n):
        p = next((i for i in range(j, n) if a[i][j] != 0), None)
        if p is None:
            return Fraction(0)
        if p != j:
            a[j], a[p] = a[p], a[j]
            det = -det
        det *= a[j][j]
        for i in range(j + 1, n):
            f = a[i][j] / a[j][j]
            if f:
                a[i] = [x - f * y for x, y in zip(a[i], a[j])]
    return det


def _unit_determinant(M: NDArray[np.float64], tau: NDArray[np.float64]) -> bool:
    """Whether ``det(I - M diag(e^{-tau_i s})) = 1`` identically (exact; :attr:`DelayLTI.is_neutral`)."""
    k = M.shape[0]
    F = [[Fraction(float(x)) for x in row] for row in M]
    if np.all(tau == tau[0]):  # det(I - z M) = 1 for all z iff M is nilpotent: M^k = 0
        P = F
        for _ in range(k - 1):
            P = [[sum((P[i][t] * F[t][j] for t in range(k)), Fraction(0)) for j in range(k)] for i in range(k)]
        return all(x == 0 for row in P for x in row)
    if k > _EXPANSION_CHANNELS:
        return False
    terms: dict[Fraction, Fraction] = {}
    delays = [Fraction(float(t)) for t in tau]
    for size in range(1, k + 1):
        for S in itertools.combinations(range(k), size):
            d = _det([[F[i][j] for j in S] for i in S])
            if d:
                total = sum((delays[i] for i in S), Fraction(0))
                terms[total] = terms.get(total, Fraction(0)) + (-1) ** size * d
    return all(c == 0 for c in terms.values())


@dataclass(frozen=True, eq=False)
class DelayLTI:
    """A MIMO continuous-time system with internal delays, in LFT form (module notes).

    Parameters
    ----------
    A : array_like, shape (n, n)
        State matrix (``n = 0`` allowed: a static system with delays).
    B1, B2 : array_like, shapes (n, m), (n, k)
        Input matrices of ``u`` and of the delayed channels ``w``.
    C1, C2 : array_like, shapes (p, n), (k, n)
        Output matrices of ``y`` and of the channels ``z`` fed into the delays.
    D11, D12, D21, D22 : array_like, shapes (p, m), (p, k), (k, m), (k, k)
        Feedthrough matrices.
    tau : array_like, shape (k,)
        One delay ``> 0`` per channel: ``w_i(t) = z_i(t - tau_i)``.

    Notes
    -----
    The attributes are read-only float arrays with exactly these names; the object is
    immutable, and every operation returns a new system. ``D22 != 0`` gives a neutral
    system. Build systems with :func:`delay`, :func:`tf`, :meth:`from_control`,
    :meth:`from_quasi_transfer`, :meth:`from_statespace_tds` and the algebra (``*``
    is a series connection, ``G2 * G1`` applies ``G1`` first; ``+``, ``-``,
    :meth:`feedback`, :meth:`append`, ``G[i, j]``). python-control's ``TransferFunction``
    and ``StateSpace`` combine with it on either side (``control.tf(1, [1, 1]) * delay(1)``):
    python-control 0.10 returns ``NotImplemented`` for operands it does not know, so Python
    calls :meth:`__rmul__` / :meth:`__radd__` here, and ``__array_ufunc__ = None`` makes numpy
    arrays defer likewise (``K * sys`` with a gain matrix ``K``).

    Examples
    --------
    >>> import numpy as np
    >>> G = (delay(1.0) * tf([2.0], [1.0, 0.0])).feedback(1)
    >>> w = 0.7
    >>> exact = 2 * np.exp(-1j * w) / (1j * w + 2 * np.exp(-1j * w))
    >>> bool(abs(G(1j * w) - exact) < 1e-13)
    True
    """

    A: NDArray[np.float64]
    B1: NDArray[np.float64]
    B2: NDArray[np.float64]
    C1: NDArray[np.float64]
    C2: NDArray[np.float64]
    D11: NDArray[np.float64]
    D12: NDArray[np.float64]
    D21: NDArray[np.float64]
    D22: NDArray[np.float64]
    tau: NDArray[np.float64]

    # numpy defers to __rmul__/__radd__ (``K @ sys``-like products with arrays), and so does
    # python-control (its TransferFunction and StateSpace return NotImplemented on unknown types)
    __array_ufunc__ = None
    __array_priority__ = 100

    def __init__(
        self,
        A: ArrayLike,
        B1: ArrayLike,
        B2: ArrayLike,
        C1: ArrayLike,
        C2: ArrayLike,
        D11: ArrayLike,
        D12: ArrayLike,
        D21: ArrayLike,
        D22: ArrayLike,
        tau: ArrayLike,
    ) -> None:
        t = real_array("tau", tau, ndim=1, min_size=0)
        if np.any(t <= 0):
            raise ParameterError("tau", "delays > 0, one per internal channel", tau)
        k = t.size
        a = real_array("A", A, ndim=2, min_size=0) if np.size(A) else np.zeros((0, 0))
        n = a.shape[0]
        if a.shape != (n, n):
            raise ParameterError("A", "a square real matrix", a.shape)
        d11 = real_array("D11", D11, ndim=2, min_size=0)
        p, m = d11.shape
        mats = {
            "A": a,
            "B1": _matrix("B1", B1, (n, m)),
            "B2": _matrix("B2", B2, (n, k)),
            "C1": _matrix("C1", C1, (p, n)),
            "C2": _matrix("C2", C2, (k, n)),
            "D11": d11,
            "D12": _matrix("D12", D12, (p, k)),
            "D21": _matrix("D21", D21, (k, m)),
            "D22": _matrix("D22", D22, (k, k)),
        }
        for name in _FIELDS:
            object.__setattr__(self, name, _frozen(mats[name]))
        object.__setattr__(self, "tau", _frozen(t))

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_ss(cls, A: ArrayLike, B: ArrayLike, C: ArrayLike, D: ArrayLike) -> DelayLTI:
        """A delay-free state-space system ``(A, B, C, D)``."""
        d = real_array("D", np.atleast_2d(D), ndim=2, min_size=0)
        p, m = d.shape
        a = real_array("A", A, ndim=2, min_size=0) if np.size(A) else np.zeros((0, 0))
        n = a.shape[0]
        b, c = _matrix("B", B, (n, m)), _matrix("C", C, (p, n))
        return cls(a, b, np.zeros((n, 0)), c, np.zeros((0, n)), d, np.zeros((p, 0)), np.zeros((0, m)), [], [])

    @classmethod
    def gain(cls, K: ArrayLike) -> DelayLTI:
        """The static gain ``y = K u`` (a number is a 1 x 1 gain)."""
        k = real_array("K", np.atleast_2d(K), ndim=2, min_size=0)
        return cls.from_ss(np.zeros((0, 0)), np.zeros((0, k.shape[1])), np.zeros((k.shape[0], 0)), k)

    @classmethod
    def from_control(cls, sys: control.StateSpace | control.TransferFunction) -> DelayLTI:
        """A python-control ``StateSpace`` or ``TransferFunction`` (continuous time, MIMO too).

        A ``TransferFunction`` is realised entry by entry (observable canonical form of each
        SISO entry, which must be proper), so no SLICOT is needed; ``StateSpace`` matrices
        are taken as they are.

        Raises
        ------
        ParameterError
            Not a python-control system, discrete time, or an improper entry (the message
            shows how to group ``delay(h) * (s / (s + 1))``).
        """
        import control

        if not isinstance(sys, (control.StateSpace, control.TransferFunction)):
            raise ParameterError("sys", "a python-control StateSpace or TransferFunction", type(sys).__name__)
        if sys.dt not in (0, None):
            raise ParameterError("sys", "a continuous-time system (dt = 0)", sys.dt)
        if isinstance(sys, control.StateSpace):
            return cls.from_ss(sys.A, sys.B, sys.C, sys.D)
        p, m = sys.noutputs, sys.ninputs
        total: DelayLTI | None = None
        for i in range(p):
            for j in range(m):
                num = np.asarray(sys.num_array[i, j], dtype=float)
                den = np.asarray(sys.den_array[i, j], dtype=float)
                if not np.any(num):
                    continue
                if np.trim_zeros(num, "f").size > np.trim_zeros(den, "f").size:
                    raise ParameterError(
                        "sys",
                        f"a proper transfer function (entry [{i}, {j}] has a numerator of higher degree than its "
                        "denominator); with s = tf('s'), Python reads delay(h) * s / (s + 1) as "
                        "(delay(h) * s) / (s + 1): write delay(h) * (s / (s + 1))",
                        sys,
                    )
                entry = _rational([(num[::-1], 0.0)], den[::-1], [])
                term = cls.gain(np.eye(p)[:, [i]]) * entry * cls.gain(np.eye(m)[[j], :])
                total = term if total is None else total + term
        return total if total is not None else cls.gain(np.zeros((p, m)))

    @classmethod
    def from_quasi_transfer(cls, H: QuasiTransferFunction) -> DelayLTI:
        """A SISO :class:`~nrobust.lti.transfer.QuasiTransferFunction` with point delays.

        With ``den = sum_k d_k(s) e^{-h_k s}`` (``h_0`` the smallest delay) and
        ``num = sum_j n_j(s) e^{-t_j s}``, ``H = (num / d_0) / (1 + sum_{k>0} (d_k / d_0) e^{-(h_k - h_0) s})``
        after both are shifted by ``h_0``: one observable canonical realisation of the row
        ``[n_j / d_0, -d_k / d_0]`` (``deg d_0`` states) whose inputs are ``u`` delayed by
        ``t_j - h_0`` and ``y`` delayed by ``h_k - h_0``, each delay an internal channel
        (``d_k`` of the degree of ``d_0``: a neutral channel, ``D22 != 0``).

        Raises
        ------
        ParameterError
            Distributed delays, complex coefficients, a numerator delay below ``h_0`` (an
            advance: not causal), ``deg n_j > deg d_0`` (improper) or ``deg d_k > deg d_0``
            (advanced type): such a quotient has no realisation in this form.
        """
        if not isinstance(H, QuasiTransferFunction):
            raise ParameterError("H", "a QuasiTransferFunction", type(H).__name__)
        num, den = H.num, H.den
        if num.distributed or den.distributed:
            raise ParameterError(
                "H", "point delays only (distributed delays have no finite LFT realisation; use to_frd)", H
            )
        if not (num.is_real and den.is_real):
            raise ParameterError("H", "real coefficients", H)
        h0 = den.point_terms[0][1]
        d0 = np.real(den.point_terms[0][0]).astype(float)
        num_terms = [(np.real(p).astype(float), t - h0) for p, t in num.point_terms]
        if any(t < 0 for _, t in num_terms):
            raise ParameterError(
                "H",
                "a numerator delay >= the smallest denominator delay (else H contains an advance: not causal, "
                "no realisation in LFT form)",
                H,
            )
        den_terms = [(np.real(p).astype(float), t - h0) for p, t in den.point_terms[1:]]
        return _rational(num_terms, d0, den_terms)

    @classmethod
    def from_statespace_tds(
        cls,
        sys: StateSpaceTDS,
        B: ArrayLike | None = None,
        C: ArrayLike | None = None,
        D: ArrayLike | None = None,
    ) -> DelayLTI:
        """A :class:`~nrobust.lti.statespace.StateSpaceTDS` ``x' = sum A_k x(t - hA_k) + sum B_k x'(t - hB_k)``.

        With inputs and outputs ``E x' = ... + B u``, ``y = C x + D u`` (default ``B = I``,
        ``C = I``, ``D = 0``: the resolvent ``M(s)^{-1}``). The state is
        ``xi = x - sum_k B_k x(t - hB_k)``, so ``xi' = A_0 x + sum_k A_k x(t - hA_k) + B u`` and
        ``x = xi + sum_k B_k x(t - hB_k)``; each distinct delay is one group of channels
        carrying the components of ``x`` that its matrices use. An invertible ``E`` is
        multiplied out (``E^{-1}``). A singular ``E`` (a descriptor system of index one, without
        neutral terms) is reduced by :meth:`_from_descriptor`; distributed terms are refused.
        """
        if not isinstance(sys, StateSpaceTDS):
            raise ParameterError("sys", "a StateSpaceTDS", type(sys).__name__)
        if sys.distributed:
            raise ParameterError("sys", "no distributed delay (no finite LFT realisation)", sys.distributed)
        n = sys.n
        b = np.eye(n) if B is None else real_array("B", np.atleast_2d(B), ndim=2)
        if b.shape[0] != n:
            raise ParameterError("B", f"a real matrix with {n} rows", b.shape)
        m = b.shape[1]
        c = np.eye(n) if C is None else real_array("C", np.atleast_2d(C), ndim=2)
        if c.shape[1] != n:
            raise ParameterError("C", f"a real matrix with {n} columns", c.shape)
        d = np.zeros((c.shape[0], m)) if D is None else _matrix("D", np.atleast_2d(D), (c.shape[0], m))
        if np.linalg.matrix_rank(sys.E) < n:
            return cls._from_descriptor(sys, b, c, d)
        einv = np.linalg.inv(sys.E)
        b = einv @ b
        a0 = sum((einv @ a for a, h in zip(sys.A, sys.hA) if h == 0), np.zeros((n, n)))
        retarded: dict[float, NDArray[np.float64]] = {}
        neutral: dict[float, NDArray[np.float64]] = {}
        for mats, delays, store in ((sys.A, sys.hA, retarded), (sys.B, sys.hB, neutral)):
            for a, h in zip(mats, delays):
                if h > 0:
                    store[float(h)] = store.get(float(h), np.zeros((n, n))) + einv @ a
        cols_r, cols_n, taus, sel = [], [], [], []
        for h in sorted(set(retarded) | set(neutral)):
            ar, an = retarded.get(h, np.zeros((n, n))), neutral.get(h, np.zeros((n, n)))
            used = np.flatnonzero(np.any(ar != 0, axis=0) | np.any(an != 0, axis=0))
            for j in used:
                cols_r.append(ar[:, j])
                cols_n.append(an[:, j])
                taus.append(h)
                sel.append(j)
        k = len(taus)
        Ar = np.array(cols_r).T.reshape(n, k)  # x' gets sum A_k x(t - h) = Ar w
        An = np.array(cols_n).T.reshape(n, k)  # x = xi + An w
        S = np.eye(n)[sel].reshape(k, n)  # z = S x
        return cls(a0, b, a0 @ An + Ar, c, S, d, c @ An, np.zeros((k, m)), S @ An, taus)

    @classmethod
    def _from_descriptor(
        cls, sys: StateSpaceTDS, b: NDArray[np.float64], c: NDArray[np.float64], d: NDArray[np.float64]
    ) -> DelayLTI:
        """:meth:`from_statespace_tds` of a singular ``E``: the algebraic part solved for, index one.

        With ``E = U diag(Sigma, 0) V^T`` (SVD, ``Sigma`` of size ``r``) and ``x = V (x_1, x_2)``, the
        rows ``U^T`` of the equations split into ``Sigma x_1' = A_11 x_1 + A_12 x_2 + G_1 w + B_1 u``
        and ``0 = A_21 x_1 + A_22 x_2 + G_2 w + B_2 u`` (``w`` the delayed components of ``x``, the
        channels of :meth:`from_statespace_tds`, ``G = U^T`` their matrices). ``A_22`` invertible
        (index one): ``x_2 = P_1 x_1 + P_w w + P_u u`` with ``P = -A_22^{-1} (A_21, G_2, B_2)``, so ``x``,
        ``y`` and the channels ``z = S x`` are affine in ``(x_1, u, w)``: a realisation with ``r``
        states whose ``D_22 = S V_2 P_w`` makes the loop neutral when an algebraic variable feeds its
        own delays. Neutral terms ``B_k x'(t - h)`` (the derivative of an algebraic variable) are refused.
        ``b``, ``c``, ``d``: the input and output matrices, checked.
        """
        n = sys.n
        if np.any(sys.B != 0):
            raise ParameterError(
                "sys",
                "an invertible E, or a singular E without neutral terms (x'(t - h) of an algebraic variable)",
                sys.E,
            )
        u_, sv, vt = np.linalg.svd(sys.E)
        r = int(np.sum(sv > n * np.finfo(float).eps * max(float(sv[0]), 1.0)))
        V = vt.T
        a0 = sum((a for a, h in zip(sys.A, sys.hA) if h == 0), np.zeros((n, n)))
        delayed: dict[float, NDArray[np.float64]] = {}
        for a, h in zip(sys.A, sys.hA):
            if h > 0:
                delayed[float(h)] = delayed.get(float(h), np.zeros((n, n))) + a
        cols, taus, sel = [], [], []
        for h in sorted(delayed):
            for j in np.flatnonzero(np.any(delayed[h] != 0, axis=0)):
                cols.append(delayed[h][:, j])
                taus.append(h)
                sel.append(j)
        k = len(taus)
        G = u_.T @ np.array(cols).T.reshape(n, k)
        At, Bt = u_.T @ a0 @ V, u_.T @ b
        A22 = At[r:, r:]
        if np.linalg.cond(A22) > 1e12:
            raise ParameterError("sys", "a descriptor system of index one (the algebraic block A_22 invertible)", A22)
        P1, Pw, Pu = (-np.linalg.solve(A22, M) for M in (At[r:, :r], G[r:], Bt[r:]))
        sigma_inv = 1.0 / sv[:r]
        V1, V2 = V[:, :r], V[:, r:]
        X1, Xw, Xu = V1 + V2 @ P1, V2 @ Pw, V2 @ Pu  # x = X1 x_1 + Xw w + Xu u
        S = np.eye(n)[sel].reshape(k, n)  # z = S x
        return cls(
            sigma_inv[:, None] * (At[:r, :r] + At[:r, r:] @ P1),
            sigma_inv[:, None] * (Bt[:r] + At[:r, r:] @ Pu),
            sigma_inv[:, None] * (G[:r] + At[:r, r:] @ Pw),
            c @ X1,
            S @ X1,
            d + c @ Xu,
            c @ Xw,
            S @ Xu,
            S @ Xw,
            taus,
        )

    # ------------------------------------------------------------------ structure
    @property
    def nstates(self) -> int:
        """``n``, the number of states."""
        return int(self.A.shape[0])

    @property
    def ninputs(self) -> int:
        """``m``, the number of inputs ``u``."""
        return int(self.D11.shape[1])

    @property
    def noutputs(self) -> int:
        """``p``, the number of outputs ``y``."""
        return int(self.D11.shape[0])

    @property
    def ndelays(self) -> int:
        """``k``, the number of internal delay channels."""
        return int(self.tau.size)

    def issiso(self) -> bool:
        """True for one input and one output."""
        return self.ninputs == 1 and self.noutputs == 1

    @property
    def is_neutral(self) -> bool:
        """True if the difference operator ``det(I - D22 Delta(s))`` has a term with a delay.

        Decided exactly (rational arithmetic on the binary values of ``D22`` and ``tau``).
        The determinant is the product of those of the strongly connected components of the
        graph of ``D22``; a component without a cycle gives 1. A component whose channels
        share one delay ``h`` gives ``det(I - e^{-h s} D22_C)``, which is 1 exactly when
        ``D22_C`` is nilpotent. Otherwise the principal minor expansion
        ``det(I - D22_C Delta) = sum_S (-1)^|S| det(D22_SS) e^{-s sum_{i in S} tau_i}`` is
        collected by total delay, for a component of at most :data:`_EXPANSION_CHANNELS`
        channels; a larger one with several delays is taken as neutral (the conservative
        side: the neutral checks then run on an operator that may be trivial).
        So ``D22 = [[1, 1], [-1, -1]]`` with equal delays (nilpotent) is retarded.
        """
        return any(not _unit_determinant(self.D22[np.ix_(c, c)], self.tau[c]) for c in _cyclic_components(self.D22))

    def difference_operator(self) -> MatrixDifferenceOperator | None:
        """``I - D22 Delta(s) = I - sum_h D22[:, tau == h] e^{-h s}`` (None for a retarded system)."""
        if not self.is_neutral:
            return None
        hs = np.unique(self.tau)
        coefs = np.array([np.where(self.tau[None, :] == h, self.D22, 0.0) for h in hs])
        return MatrixDifferenceOperator(coefs, hs)

    def is_strongly_stable(self) -> bool:
        """``gamma_0 < 1`` for :meth:`difference_operator` (True for a retarded system)."""
        op = self.difference_operator()
        return True if op is None else op.is_strongly_stable()

    # ------------------------------------------------------------------ frequency domain
    def __call__(self, s: ArrayLike, squeeze: bool | None = None) -> NDArray[np.complex128]:
        """``H(s)``, shape ``(p, m) + s.shape`` (``s.shape`` for a SISO system unless ``squeeze=False``).

        Vectorised over ``s``: one batched solve with ``sI - A`` and one with
        ``I - P22 Delta``; ``nan`` where either is singular (a pole hit exactly).
        """
        z = number_array("s", s, ndim=None, min_size=0).astype(complex)
        flat = z.reshape(-1)
        out = self._response(flat)
        out = np.moveaxis(out, 0, -1).reshape((self.noutputs, self.ninputs, *z.shape))
        if squeeze is None:
            squeeze = self.issiso()
        return out[0, 0] if squeeze and self.issiso() else out

    def _response(self, s: NDArray[np.complex128]) -> NDArray[np.complex128]:
        """``H(s)`` on a flat array: shape ``(len(s), p, m)``."""
        n, m, k = self.nstates, self.ninputs, self.ndelays
        N = s.size
        C = np.vstack([self.C1, self.C2])
        D = np.block([[self.D11, self.D12], [self.D21, self.D22]])
        P = np.broadcast_to(D, (N, *D.shape)).astype(complex)
        if n:
            M = s[:, None, None] * np.eye(n) - self.A
            rhs = np.broadcast_to(np.hstack([self.B1, self.B2]), (N, n, m + k))
            P = P + C @ _solve(M, rhs)
        if not k:
            return P[:, : self.noutputs, :m]
        p = self.noutputs
        delta = np.exp(-s[:, None] * self.tau)  # (N, k)
        P11, P12, P21, P22 = P[:, :p, :m], P[:, :p, m:], P[:, p:, :m], P[:, p:, m:]
        loop = np.eye(k) - P22 * delta[:, None, :]
        return P11 + (P12 * delta[:, None, :]) @ _solve(loop, P21)

    def frequency_response(self, omega: ArrayLike, squeeze: bool | None = None) -> NDArray[np.complex128]:
        """``H(i omega)`` for real angular frequencies ``omega`` (shapes as :meth:`__call__`)."""
        w = real_array("omega", omega, ndim=None, min_size=0)
        return self(1j * w, squeeze=squeeze)

    def to_frd(self, omega: ArrayLike, name: str = "G") -> control.FrequencyResponseData:
        """``H(i omega)`` tabulated as a python-control ``FrequencyResponseData`` (exact values).

        The way to hand a delay system to python-control's frequency-domain functions
        (``bode_plot``, ``nyquist_plot``, ``stability_margins``, ...), which do not accept a
        ``DelayLTI`` itself. The data is named ``name`` (python-control 0.10's ``bode_plot`` titles
        its figure with the names and fails on an unnamed ``FrequencyResponseData``). Margins read
        off the grid are only as fine as ``omega``: :func:`nrobust.lti.allmargin` locates every
        crossing exactly.

        Examples
        --------
        >>> import numpy as np
        >>> import control
        >>> L = 0.5 * delay(0.5) * tf([1.0], [1.0, 1.0, 0.0])
        >>> F = L.to_frd(np.logspace(-2, 2, 200), name="L")
        >>> gm, pm, wpc, wgc = control.margin(F)   # interpolated on the grid
        >>> bool(abs(pm - 52.4928) < 0.1)
        True
        """
        import control

        w = real_array("omega", omega, min_size=1)
        if np.any(w < 0) or np.any(np.diff(w) <= 0):
            raise ParameterError("omega", "an increasing array of frequencies >= 0", omega)
        return control.FrequencyResponseData(self.frequency_response(w, squeeze=False), w, name=name)

    def to_control(self) -> control.StateSpace:
        """The python-control ``StateSpace(A, B1, C1, D11)`` of a system without delay channels.

        Raises
        ------
        ParameterError
            The system has delay channels: python-control has no exact delay. Use
            :meth:`to_frd` (exact on a frequency grid) or a rational Padé model
            (:func:`nrobust.lti.pade_approximation` of :meth:`to_quasi_transfer`).
        """
        import control

        if self.ndelays:
            raise ParameterError(
                "system",
                "free of delays for a python-control StateSpace (it has "
                f"{self.ndelays} delay channel(s)): use to_frd(omega) for exact frequency data, or a Pade model "
                "(nrobust.lti.pade_approximation(sys.to_quasi_transfer(), order, omega)) for a rational one",
                self.tau.tolist(),
            )
        return control.StateSpace(self.A, self.B1, self.C1, self.D11)

    # ------------------------------------------------------------------ characteristic function
    def characteristic_matrix(self) -> QuasiPolynomialMatrix:
        """``M(s) = [[sI - A, -B2 Delta], [-C2, I - D22 Delta]]`` after the exact channel eliminations.

        ``det M`` is the characteristic function (module notes); a system with no state
        and no remaining channel gives the 1 x 1 matrix ``[1]``.

        Raises
        ------
        ParameterError
            More than 8 rows remain (the expansion of the determinant is ``n!`` products).
        """
        rows = _eliminate(self._entries(border=False), set(range(self.nstates, self.nstates + self.ndelays)))
        if not rows:
            return QuasiPolynomialMatrix([[1.0]])
        if len(rows) > _MAX_EXPANDED:
            raise ParameterError(
                "system",
                f"at most {_MAX_EXPANDED} states plus neutral channels for a certified characteristic function",
                len(rows),
            )
        return QuasiPolynomialMatrix(rows)

    def characteristic_function(self) -> QuasiPolynomial:
        """``det M(s)`` expanded as one quasi-polynomial: its zeros are the poles."""
        M = self.characteristic_matrix()
        return M.entries[0][0] if M.size == 1 else M.expand()

    def to_quasi_transfer(self) -> QuasiTransferFunction:
        """``H = N / D`` of a SISO system: ``D = det M``, ``N = det [[M, b], [-c, d]]`` (module notes).

        No cancellation: the zeros of ``D`` are the poles of the realisation.
        """
        if not self.issiso():
            raise ParameterError("system", "SISO for a scalar transfer function (index it: sys[i, j])", self)
        den = self.characteristic_function()
        rows = _eliminate(self._entries(border=True), set(range(self.nstates, self.nstates + self.ndelays)))
        if len(rows) > _MAX_EXPANDED:
            raise ParameterError("system", f"at most {_MAX_EXPANDED - 1} states plus neutral channels", len(rows))
        num = rows[0][0] if len(rows) == 1 else QuasiPolynomialMatrix(rows).expand()
        return QuasiTransferFunction(num, den)

    def _entries(self, border: bool) -> list[list[QuasiPolynomial]]:
        """The entries of ``M`` (bordered by ``b = [B1; D21]``, ``[-c, d] = [-C1, -D12 Delta, D11]``)."""
        n, k = self.nstates, self.ndelays

        def const(c: float) -> QuasiPolynomial:
            return QuasiPolynomial([[float(c)]], [0.0])

        def delayed(c: float, h: float) -> QuasiPolynomial:
            return QuasiPolynomial([[float(c)]], [float(h)])

        rows: list[list[QuasiPolynomial]] = []
        for i in range(n):
            row = [QuasiPolynomial([[-self.A[i, j], 1.0 if i == j else 0.0]], [0.0]) for j in range(n)]
            row += [delayed(-self.B2[i, j], self.tau[j]) for j in range(k)]
            rows.append(row + ([const(self.B1[i, 0])] if border else []))
        for i in range(k):
            row = [const(-self.C2[i, j]) for j in range(n)]
            row += [
                QuasiPolynomial([[1.0 if i == j else 0.0], [-self.D22[i, j]]], [0.0, self.tau[j]]) for j in range(k)
            ]
            rows.append(row + ([const(self.D21[i, 0])] if border else []))
        if border:
            last = [const(-self.C1[0, j]) for j in range(n)]
            last += [delayed(-self.D12[0, j], self.tau[j]) for j in range(k)]
            rows.append([*last, const(self.D11[0, 0])])
        return rows

    def poles(self, region: ArrayLike | None = None, *, re_min: float = -1.0, **options: Any) -> PoleSet:
        """Certified poles: the zeros of :meth:`characteristic_function`, as a
        :class:`~nrobust.lti.transfer.PoleSet` (printed with the floating-point estimate of each pole
        and, apart, the certified radius about it).

        Parameters
        ----------
        region : (re_min, re_max, im_min, im_max), optional
            A rectangle. By default every pole with ``Re s >= re_min``: the rectangle of
            :func:`nrobust.bounds.root_free_region` (a neutral system needs ``re_min``
            right of the chains, ``C_D``).
        re_min : float, optional
            Left edge of the default region (``-1``).
        **options
            Passed to :func:`nrobust.roots.find_roots` (``rigorous=True`` proves them in
            ball arithmetic).

        Raises
        ------
        ParameterError
            A neutral system and ``re_min`` at or left of ``C_D``, the strong spectral bound of
            its difference operator (the message gives ``C_D``): infinitely many poles there.

        Examples
        --------
        >>> sys = (delay(1.0) * tf([1.0], [1.0, 0.0])).feedback(1)  # s + e^{-s} = 0
        >>> roots = sys.poles(re_min=-0.5).roots
        >>> [complex(round(r.real, 6), round(r.imag, 6)) for r in roots]
        [(-0.318132-1.337236j), (-0.318132+1.337236j)]
        """
        P = self.characteristic_function()
        if region is None:
            x = finite_real("re_min", re_min)
            if P.degree == 0 and len(P.point_terms) == 1:  # c e^{-h s}: no pole at all
                return PoleSet.of(P, find_roots(P, (x, x + 1.0, -1.0, 1.0), **options))
            try:
                free = root_free_region(P, x)
            except ParameterError as exc:
                c_d = P.principal_part().strong_spectral_bound()
                raise ParameterError(
                    "re_min",
                    f"> {c_d:.6g}, right of the chains of the neutral part (C_D = {c_d:.6g}: infinitely many poles "
                    "accumulate at Re s = C_D or left of it) for a bounded set of poles",
                    re_min,
                ) from exc
            R = free.radius * (1.0 + 1e-9) + 1e-9
            region = (x, max(min(free.half_plane, R), x) + 1e-6 * (1.0 + R), -R, R)
        return PoleSet.of(P, find_roots(P, region, **options))

    def spectral_abscissa(self, **options: Any) -> SpectralAbscissa:
        """Certified spectral abscissa of :meth:`characteristic_function` (:func:`nrobust.roots.spectral_abscissa`)."""
        return spectral_abscissa(self.characteristic_function(), **options)

    def is_stable(self, **options: Any) -> bool:
        """Exponential stability, robust to small changes of the delays, certified.

        True iff the difference operator ``I - D22 Delta`` is strongly stable
        (``gamma_0 < 1``) and the certified spectral abscissa is negative. A system
        without state or delay channel is stable.

        Raises
        ------
        CertificationError
            The spectral abscissa could not be certified (``options`` go to
            :meth:`spectral_abscissa`; more ``max_evals`` may help).
        """
        if not self.is_strongly_stable():
            return False
        P = self.characteristic_function()
        if P.degree == 0 and len(P.point_terms) <= 1:
            return True
        sa = self.spectral_abscissa(**options)
        if sa.upper_bound < 0.0:
            return True
        if not sa.certified:
            raise CertificationError(
                f"is_stable: the spectral abscissa {sa.value:.6g} is not certified (upper bound {sa.upper_bound:.6g})"
            )
        return bool(sa.value < 0.0)

    # ------------------------------------------------------------------ interconnection
    def series(self, other: Any) -> DelayLTI:
        """``self`` followed by ``other`` (``other * self``, python-control's ``series(self, other)``)."""
        return _as_system("other", other, self.noutputs) * self

    def parallel(self, other: Any) -> DelayLTI:
        """``self + other``: the same input, the outputs summed."""
        return self + other

    def append(self, *others: Any) -> DelayLTI:
        """Block-diagonal combination: the inputs and outputs of ``others`` follow those of ``self``."""
        out = self
        for j, o in enumerate(others):
            out = _append(out, _as_system(f"others[{j}]", o, 1))
        return out

    def feedback(self, other: Any = 1, sign: int = -1) -> DelayLTI:
        """Close the loop: ``u = r + sign * other(y)``, output ``y``.

        With ``self = (A1, B11, B12, C11, ...)`` and ``other = (A2, ...)``, the output solves
        ``(I - sign D11_1 D11_2) y = C11 x1 + sign D11_1 (C12 x2 + D12_2 w2) + D11_1 r + D12_1 w1``;
        the states and delay channels stack (``tau = (tau_1, tau_2)``). ``other`` is a
        ``DelayLTI``, a python-control system, or a gain (a number is ``c I``).

        Raises
        ------
        ParameterError
            ``I - sign D11_1 D11_2`` is singular (an algebraic loop), or sizes disagree.
        """
        if sign not in (-1, 1):
            raise ParameterError("sign", "-1 (negative feedback) or +1 (positive feedback)", sign)
        g1 = self
        g2 = _as_system("other", other, self.noutputs)
        if (g2.ninputs, g2.noutputs) != (g1.noutputs, g1.ninputs):
            raise ParameterError(
                "other", f"{g1.noutputs} input(s) and {g1.ninputs} output(s)", (g2.ninputs, g2.noutputs)
            )
        n1, n2, k1, k2 = g1.nstates, g2.nstates, g1.ndelays, g2.ndelays
        n, k, m, p = n1 + n2, k1 + k2, g1.ninputs, g1.noutputs
        E1, E2 = np.eye(n)[:n1], np.eye(n)[n1:]
        F1, F2 = np.eye(k)[:k1], np.eye(k)[k1:]
        loop = np.eye(p) - sign * g1.D11 @ g2.D11
        if np.linalg.matrix_rank(loop) < p:
            raise ParameterError("other", "I - sign D11 D11_other invertible (else an algebraic loop)", loop)
        Q = np.linalg.inv(loop)
        Cy = Q @ (g1.C1 @ E1 + sign * g1.D11 @ g2.C1 @ E2)
        Dyu = Q @ g1.D11
        Dyw = Q @ (g1.D12 @ F1 + sign * g1.D11 @ g2.D12 @ F2)
        Ce = sign * (g2.C1 @ E2 + g2.D11 @ Cy)
        Deu = np.eye(m) + sign * g2.D11 @ Dyu
        Dew = sign * (g2.D12 @ F2 + g2.D11 @ Dyw)
        r1 = _rows(g1, E1, F1, Ce, Deu, Dew)
        r2 = _rows(g2, E2, F2, Cy, Dyu, Dyw)
        return _assemble(r1, r2, (Cy, Dyu, Dyw), np.concatenate([g1.tau, g2.tau]))

    def __getitem__(self, key: Any) -> DelayLTI:
        """``sys[outputs, inputs]``: integers, slices or index lists select outputs and inputs."""
        if not (isinstance(key, tuple) and len(key) == 2):
            raise ParameterError("key", "a pair (outputs, inputs) of indices or slices", key)
        picked = []
        for i, (k, size) in enumerate(zip(key, (self.noutputs, self.ninputs))):
            try:
                picked.append(np.atleast_1d(np.arange(size)[k]))
            except (IndexError, TypeError, ValueError):
                raise ParameterError(
                    f"key[{i}] ({('output', 'input')[i]} index)",
                    f"an integer in [{-size}, {size - 1}], a slice or a list of them",
                    k,
                ) from None
        rows, cols = picked
        return DelayLTI(
            self.A,
            self.B1[:, cols],
            self.B2,
            self.C1[rows],
            self.C2,
            self.D11[np.ix_(rows, cols)],
            self.D12[rows],
            self.D21[:, cols],
            self.D22,
            self.tau,
        )

    def __mul__(self, other: Any) -> DelayLTI:
        """``self * other``: ``other`` first, then ``self`` (a number or matrix scales the inputs)."""
        if _is_gain(other):
            return self * DelayLTI.gain(np.eye(self.ninputs) * other if is_real_number(other) else other)
        if not (isinstance(other, DelayLTI) or _is_control(other)):
            return NotImplemented
        return _series(_as_system("other", other, 1), self)

    def __rmul__(self, other: Any) -> DelayLTI:
        """``other * self``: ``self`` first (a number or matrix scales the outputs)."""
        if _is_gain(other):
            return DelayLTI.gain(np.eye(self.noutputs) * other if is_real_number(other) else other) * self
        if not _is_control(other):
            return NotImplemented
        return _series(self, _as_system("other", other, 1))

    def __truediv__(self, other: Any) -> DelayLTI:
        """``self / other`` for a number or a SISO python-control system (``self * (1 / other)``)."""
        if is_real_number(other):
            if float(other) == 0.0:
                raise ParameterError("other", "a nonzero divisor", other)
            return self * (1.0 / float(other))
        if _is_control(other):
            return self * (1 / other)
        return NotImplemented

    def __add__(self, other: Any) -> DelayLTI:
        """Parallel connection; a number is added to every entry (python-control's rule)."""
        if _is_gain(other):
            other = DelayLTI.gain(np.full((self.noutputs, self.ninputs), other) if is_real_number(other) else other)
        elif not (isinstance(other, DelayLTI) or _is_control(other)):
            return NotImplemented
        return _parallel(self, _as_system("other", other, 1))

    __radd__ = __add__

    def __neg__(self) -> DelayLTI:
        return DelayLTI(self.A, self.B1, self.B2, -self.C1, self.C2, -self.D11, -self.D12, self.D21, self.D22, self.tau)

    def __sub__(self, other: Any) -> DelayLTI:
        if _is_gain(other):
            return self + (-np.asarray(other, dtype=float))
        if not (isinstance(other, DelayLTI) or _is_control(other)):
            return NotImplemented
        return self + (-_as_system("other", other, 1))

    def __rsub__(self, other: Any) -> DelayLTI:
        return (-self) + other

    # ------------------------------------------------------------------ display
    def __repr__(self) -> str:
        kind = "neutral" if self.is_neutral else "retarded"
        taus = np.array2string(self.tau, precision=6, separator=", ")
        return (
            f"DelayLTI(states={self.nstates}, inputs={self.ninputs}, outputs={self.noutputs}, "
            f"delays={self.ndelays}, tau={taus}, {kind})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description: the ten matrices and arrays as nested lists."""
        return fields_dict(self)


# ---------------------------------------------------------------------- algebra helpers
def _solve(M: NDArray[Any], rhs: NDArray[Any]) -> NDArray[np.complex128]:
    """Batched ``M^{-1} rhs``; ``nan`` for the singular matrices of the batch."""
    try:
        return np.asarray(np.linalg.solve(M, rhs), dtype=complex)
    except np.linalg.LinAlgError:
        out = np.full(rhs.shape, np.nan, dtype=complex)
        for i in range(M.shape[0]):
            try:
                out[i] = np.linalg.solve(M[i], rhs[i])
            except np.linalg.LinAlgError:
                continue
        return out


def _is_gain(value: Any) -> bool:
    if is_real_number(value):
        return True
    return isinstance(value, (np.ndarray, list)) and np.asarray(value).dtype.kind in "iuf"


def _as_system(name: str, value: Any, size: int) -> DelayLTI:
    """``value`` as a DelayLTI: itself, a python-control system, a gain matrix or a number (``c I_size``)."""
    if isinstance(value, DelayLTI):
        return value
    if _is_control(value):
        return DelayLTI.from_control(value)
    if isinstance(value, QuasiTransferFunction):
        return DelayLTI.from_quasi_transfer(value)
    if is_real_number(value):
        return DelayLTI.gain(float(value) * np.eye(size))
    if _is_gain(value):
        return DelayLTI.gain(value)
    raise ParameterError(
        name, "a DelayLTI, a python-control system, a QuasiTransferFunction or a real gain", type(value).__name__
    )


def _promote(siso: DelayLTI, copies: int) -> DelayLTI:
    return siso.append(*([siso] * (copies - 1))) if copies > 1 else siso


def _rows(
    g: DelayLTI, Ex: NDArray, Fw: NDArray, cin: NDArray, duin: NDArray, dwin: NDArray
) -> tuple[tuple[NDArray, ...], tuple[NDArray, ...], tuple[NDArray, ...]]:
    """Rows of ``g`` in a composite whose input to ``g`` is ``cin x + duin u + dwin w``.

    ``Ex``, ``Fw`` select ``g``'s states and channels from the composite's. Returns the rows
    of ``x'`` (A, B1, B2), of ``g``'s output (C, D_u, D_w) and of its channels (C2, D21, D22).
    """
    state = (g.A @ Ex + g.B1 @ cin, g.B1 @ duin, g.B1 @ dwin + g.B2 @ Fw)
    out = (g.C1 @ Ex + g.D11 @ cin, g.D11 @ duin, g.D11 @ dwin + g.D12 @ Fw)
    chan = (g.C2 @ Ex + g.D21 @ cin, g.D21 @ duin, g.D21 @ dwin + g.D22 @ Fw)
    return state, out, chan


def _assemble(r1: Any, r2: Any, out: tuple[NDArray, ...], tau: NDArray) -> DelayLTI:
    (s1, _, c1), (s2, _, c2) = r1, r2
    A, B1, B2 = (np.vstack([a, b]) for a, b in zip(s1, s2))
    C2, D21, D22 = (np.vstack([a, b]) for a, b in zip(c1, c2))
    return DelayLTI(A, B1, B2, out[0], C2, out[1], out[2], D21, D22, tau)


def _frame(g1: DelayLTI, g2: DelayLTI) -> tuple[NDArray, ...]:
    n1, k1 = g1.nstates, g1.ndelays
    n, k = n1 + g2.nstates, k1 + g2.ndelays
    return np.eye(n)[:n1], np.eye(n)[n1:], np.eye(k)[:k1], np.eye(k)[k1:]


def _series(g1: DelayLTI, g2: DelayLTI) -> DelayLTI:
    """``g2 * g1``: ``u -> g1 -> g2 -> y`` (a SISO operand is repeated to fit, as python-control does)."""
    if g1.issiso() and not g2.issiso():
        g1 = _promote(g1, g2.ninputs)
    elif g2.issiso() and not g1.issiso():
        g2 = _promote(g2, g1.noutputs)
    if g2.ninputs != g1.noutputs:
        raise ParameterError("other", f"{g1.noutputs} input(s) to follow a system with as many outputs", g2.ninputs)
    E1, E2, F1, F2 = _frame(g1, g2)
    m = g1.ninputs
    r1 = _rows(g1, E1, F1, np.zeros((m, E1.shape[1])), np.eye(m), np.zeros((m, F1.shape[1])))
    r2 = _rows(g2, E2, F2, *r1[1])
    return _assemble(r1, r2, r2[1], np.concatenate([g1.tau, g2.tau]))


def _parallel(g1: DelayLTI, g2: DelayLTI) -> DelayLTI:
    if g1.issiso() and not g2.issiso():
        g1 = DelayLTI.gain(np.ones((g2.noutputs, 1))) * g1 * DelayLTI.gain(np.ones((1, g2.ninputs)))
    elif g2.issiso() and not g1.issiso():
        g2 = DelayLTI.gain(np.ones((g1.noutputs, 1))) * g2 * DelayLTI.gain(np.ones((1, g1.ninputs)))
    if (g1.noutputs, g1.ninputs) != (g2.noutputs, g2.ninputs):
        raise ParameterError("other", f"{g1.noutputs} output(s) and {g1.ninputs} input(s)", (g2.noutputs, g2.ninputs))
    E1, E2, F1, F2 = _frame(g1, g2)
    m = g1.ninputs
    zero_x, zero_w = np.zeros((m, E1.shape[1])), np.zeros((m, F1.shape[1]))
    r1 = _rows(g1, E1, F1, zero_x, np.eye(m), zero_w)
    r2 = _rows(g2, E2, F2, zero_x, np.eye(m), zero_w)
    out = tuple(a + b for a, b in zip(r1[1], r2[1]))
    return _assemble(r1, r2, out, np.concatenate([g1.tau, g2.tau]))


def _append(g1: DelayLTI, g2: DelayLTI) -> DelayLTI:
    E1, E2, F1, F2 = _frame(g1, g2)
    m1, m = g1.ninputs, g1.ninputs + g2.ninputs
    U1, U2 = np.eye(m)[:m1], np.eye(m)[m1:]
    r1 = _rows(g1, E1, F1, np.zeros((m1, E1.shape[1])), U1, np.zeros((m1, F1.shape[1])))
    r2 = _rows(g2, E2, F2, np.zeros((g2.ninputs, E1.shape[1])), U2, np.zeros((g2.ninputs, F1.shape[1])))
    out = tuple(np.vstack([a, b]) for a, b in zip(r1[1], r2[1]))
    return _assemble(r1, r2, out, np.concatenate([g1.tau, g2.tau]))


def _rational(
    num_terms: Sequence[tuple[NDArray[np.float64], float]],
    den0: NDArray[np.float64],
    den_terms: Sequence[tuple[NDArray[np.float64], float]],
) -> DelayLTI:
    """``y = (sum_j n_j u(t - t_j) - sum_k d_k y(t - h_k)) / d_0``: one observable canonical form.

    ``den0 = d_0``, ``n_j``, ``d_k`` in ascending powers of ``s``; delays ``t_j >= 0``, ``h_k > 0``.
    """
    d = np.trim_zeros(np.asarray(den0, dtype=float), "b")
    if d.size == 0:
        raise ParameterError("den", "not identically zero", den0)
    deg = d.size - 1
    for name, terms in (("numerator", num_terms), ("denominator", den_terms)):
        for c, _ in terms:
            if np.trim_zeros(np.asarray(c, dtype=float), "b").size - 1 > deg:
                kind = "improper" if name == "numerator" else "of advanced type"
                raise ParameterError(
                    name, f"polynomial degrees <= {deg}, that of the leading denominator term (else {kind})", c
                )
    monic = d / d[-1]
    # columns of the row [n_j / d0, -d_k / d0]: direct term and strictly proper remainder
    cols = [np.asarray(c, dtype=float) / d[-1] for c, _ in num_terms] + [
        -np.asarray(c, dtype=float) / d[-1] for c, _ in den_terms
    ]
    feed, Bcols = [], []
    for c in cols:
        c = np.pad(c, (0, deg + 1 - c.size))
        direct = c[deg] if deg >= 0 else 0.0
        rem = c - direct * monic
        feed.append(direct)
        Bcols.append(rem[:deg][::-1])  # highest power first
    A = np.zeros((deg, deg))
    if deg:
        A[:, 0] = -monic[:deg][::-1]
        A[: deg - 1, 1:] = np.eye(deg - 1)
    C = np.eye(1, deg)
    Bm = np.array(Bcols).T.reshape(deg, len(cols))
    Dm = np.array(feed).reshape(1, len(cols))
    # inputs of the row: u at delay 0 (if present), u delayed, y delayed
    nu = [(j, t) for j, (_, t) in enumerate(num_terms)]
    direct_u = [j for j, t in nu if t == 0]
    delayed_u = [(j, t) for j, t in nu if t > 0]
    ny = len(num_terms)
    chans = [j for j, _ in delayed_u] + [ny + i for i in range(len(den_terms))]
    taus = [t for _, t in delayed_u] + [h for _, h in den_terms]
    k = len(chans)
    B1 = Bm[:, direct_u].sum(axis=1, keepdims=True)
    D11 = Dm[:, direct_u].sum(axis=1, keepdims=True)
    B2, D12 = Bm[:, chans], Dm[:, chans]
    nd = len(delayed_u)
    # channels: z = u for delayed inputs, z = y for delayed outputs
    C2 = np.vstack([np.zeros((nd, deg)), np.repeat(C, len(den_terms), axis=0)])
    D21 = np.vstack([np.ones((nd, 1)), np.repeat(D11, len(den_terms), axis=0)])
    D22 = np.vstack([np.zeros((nd, k)), np.repeat(D12, len(den_terms), axis=0)])
    return DelayLTI(A, B1, B2, C, C2.reshape(k, deg), D11, D12, D21, D22.reshape(k, k), taus)


def _is_zero(q: QuasiPolynomial) -> bool:
    return not q.point_terms and not q.distributed


def _is_unit(q: QuasiPolynomial) -> bool:
    return (
        not q.distributed
        and len(q.point_terms) == 1
        and q.point_terms[0][1] == 0.0
        and q.point_terms[0][0].size == 1
        and q.point_terms[0][0][0] == 1
    )


def _eliminate(rows: list[list[QuasiPolynomial]], channels: set[int]) -> list[list[QuasiPolynomial]]:
    """Remove, without changing the determinant, each channel ``j`` whose pivot is 1 and whose row
    (or column) is zero in the other channel columns (rows): a row (column) operation clears its
    column (row), and the expansion along it drops both. Returns the reduced matrix."""
    rows = [list(r) for r in rows]
    idx = list(range(len(rows)))  # original index of each current row/column
    changed = True
    while changed:
        changed = False
        for pos, j in enumerate(idx):
            if j not in channels or not _is_unit(rows[pos][pos]):
                continue
            others = [q for q, c in enumerate(idx) if c in channels and c != j]
            if all(_is_zero(rows[pos][q]) for q in others):
                for r in range(len(rows)):
                    if r != pos and not _is_zero(rows[r][pos]):
                        f = rows[r][pos]
                        rows[r] = [rows[r][c] - f * rows[pos][c] if c != pos else rows[r][c] for c in range(len(rows))]
            elif all(_is_zero(rows[q][pos]) for q in others):
                for c in range(len(rows)):
                    if c != pos and not _is_zero(rows[pos][c]):
                        f = rows[pos][c]
                        for r in range(len(rows)):
                            if r != pos:
                                rows[r][c] = rows[r][c] - f * rows[r][pos]
            else:
                continue
            del rows[pos]
            for line in rows:
                del line[pos]
            del idx[pos]
            changed = True
            break
    return rows


# ---------------------------------------------------------------------- public builders
def delay(tau: float) -> DelayLTI:
    """The pure delay ``e^{-tau s}`` (1 x 1): one channel, ``D12 = D21 = 1``; ``tau = 0`` is the gain 1.

    Examples
    --------
    >>> import numpy as np
    >>> bool(abs(delay(2.0)(1j) - np.exp(-2j)) < 1e-15)
    True
    """
    t = nonnegative("tau", tau)
    if t == 0.0:
        return DelayLTI.gain(1.0)
    none, row, col = np.zeros((0, 0)), np.zeros((1, 0)), np.zeros((0, 1))
    return DelayLTI(none, col, col, row, row, [[0.0]], [[1.0]], [[1.0]], [[0.0]], [t])


def tf(num: ArrayLike | str, den: ArrayLike | None = None) -> DelayLTI | control.TransferFunction:
    """A rational SISO transfer function, coefficients in DESCENDING powers of ``s`` (python-control's order).

    ``tf([1, 2], [1, 3])`` is ``(s + 2)/(s + 3)`` as a :class:`DelayLTI` (it must be proper).
    ``tf('s')`` returns python-control's ``TransferFunction`` ``s`` (improper, so not a
    ``DelayLTI``): rational expressions in it are python-control objects that combine with
    delay systems, ``delay(1.0) * 2 / s`` or ``tf('s')`` ``+ 1`` alike. The ascending-order
    constructors are :class:`~nrobust.quasipoly.QuasiPolynomial` and
    :class:`~nrobust.lti.transfer.QuasiTransferFunction` (qpmr's convention).

    Examples
    --------
    >>> G = tf([1.0, 2.0], [1.0, 3.0])
    >>> round(complex(G(0.0)).real, 12)
    0.666666666667
    """
    if isinstance(num, str):
        if num != "s" or den is not None:
            raise ParameterError("num", "'s' (the Laplace variable) or coefficients in descending powers", num)
        import control

        return control.tf("s")
    n = real_array("num", np.atleast_1d(num), ndim=1)
    d = real_array("den", np.atleast_1d(1.0 if den is None else den), ndim=1)
    d = np.trim_zeros(d, "f")
    if d.size == 0:
        raise ParameterError("den", "not identically zero", den)
    return _rational([(n[::-1], 0.0)], d[::-1], [])


def as_delay_lti(sys: Any) -> DelayLTI:
    """``sys`` as a :class:`DelayLTI`: itself, a python-control system, a SISO
    :class:`~nrobust.lti.transfer.QuasiTransferFunction`, a :class:`~nrobust.lti.statespace.StateSpaceTDS`
    (its resolvent) or a real gain."""
    if isinstance(sys, StateSpaceTDS):
        return DelayLTI.from_statespace_tds(sys)
    return _as_system("sys", sys, 1)
