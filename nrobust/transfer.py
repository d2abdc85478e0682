"""Transfer functions with point and distributed delays.

A :class:`QuasiTransferFunction` is a ratio ``H(s) = n(s) / d(s)`` of two
:class:`~nrobust.quasipoly.QuasiPolynomial`, the form of every transfer function of the
paper: the open loop ``H_0(s) = 1 / (1 - rho q e^{-tau s})`` of the transport system
(Laplace transform of eq. (delay_eq_no_couplings)) and
``H_1(s) = 1 / (1 - rho q e^{-tau s} + int_0^tau N~(nu) e^{-nu s} dnu)`` of the coupled
system (Laplace transform of eq. (delay_eq_alpha)). Loops are built the way
python-control users build them (``series``, ``parallel``, ``feedback``, ``delay``),
poles and zeros are certified root sets of the denominator and numerator, and
:func:`to_frd` / :func:`pade_approximation` hand the result to python-control.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._validate import nonnegative, positive_int
from .errors import ParameterError
from .quasipoly import DistributedDelay, QuasiPolynomial

if TYPE_CHECKING:
    import control

    from .roots import RootSet

__all__ = [
    "QuasiTransferFunction",
    "open_loop_tf",
    "closed_loop_tf",
    "output_map",
    "to_frd",
    "pade_approximation",
]


def _as_quasi(name: str, value: Any) -> QuasiPolynomial:
    """Accept a QuasiPolynomial or a number (a constant quasi-polynomial)."""
    if isinstance(value, QuasiPolynomial):
        return value
    if isinstance(value, (int, float, complex, np.number)) and not isinstance(value, bool):
        if not np.isfinite(value):
            raise ParameterError(name, "a finite number or a QuasiPolynomial", value)
        return QuasiPolynomial([[value]], [0.0])
    raise ParameterError(name, "a QuasiPolynomial or a finite number", value)


def _product(name: str, f: QuasiPolynomial, g: QuasiPolynomial) -> QuasiPolynomial:
    """``f * g``, naming the operation when both sides carry distributed terms."""
    if f.distributed and g.distributed:
        raise ParameterError(
            name,
            "a combination in which each product has at most one factor with distributed "
            "delays (write the loop with one distributed factor per product)",
            f"{f!r} * {g!r}",
        )
    return f * g


def _is_one(f: QuasiPolynomial) -> bool:
    """True when ``f`` is the constant 1 (no delay, no distributed term)."""
    return (
        not f.distributed
        and len(f.point_terms) == 1
        and f.point_terms[0][1] == 0.0
        and f.point_terms[0][0].size == 1
        and f.point_terms[0][0][0] == 1
    )


@dataclass(frozen=True, eq=False)
class QuasiTransferFunction:
    """A transfer function ``H(s) = num(s) / den(s)`` with delays.

    Parameters
    ----------
    num, den : QuasiPolynomial or number
        Numerator and denominator; numbers are constant quasi-polynomials.

    Notes
    -----
    No cancellation is attempted: the poles are the zeros of ``den`` and the zeros those
    of ``num``, exactly as written. Products of two factors that both carry distributed
    delays are not formed (the algebra of :class:`QuasiPolynomial` keeps at most one
    distributed factor per product); loops of the paper never need them.

    Examples
    --------
    >>> from nrobust import QuasiPolynomial
    >>> H0 = QuasiTransferFunction(1.0, QuasiPolynomial([[1.0], [-0.85]], [0.0, 2.0]))
    >>> complex(H0(0.0))
    (6.666666666666666+0j)
    """

    num: QuasiPolynomial
    den: QuasiPolynomial

    def __init__(self, num: QuasiPolynomial | complex, den: QuasiPolynomial | complex = 1.0) -> None:
        object.__setattr__(self, "num", _as_quasi("num", num))
        object.__setattr__(self, "den", _as_quasi("den", den))

    # ------------------------------------------------------------------ evaluation
    def __call__(self, s: ArrayLike) -> NDArray[np.complex128]:
        """Evaluate ``H(s)`` on an array of complex ``s`` (``inf`` at poles hit exactly)."""
        s = np.asarray(s, dtype=complex)
        n = self.num(s)
        d = self.den(s)
        with np.errstate(divide="ignore", invalid="ignore"):
            return n / d

    def frequency_response(self, omega: ArrayLike) -> NDArray[np.complex128]:
        """``H(i omega)`` for real angular frequencies ``omega`` (rad per unit time)."""
        w = np.asarray(omega, dtype=float)
        if not np.all(np.isfinite(w)):
            raise ParameterError("omega", "finite real frequencies", omega)
        return self(1j * w)

    def poles(self, region: tuple[float, float, float, float], **kwargs: Any) -> "RootSet":
        """Certified poles in a rectangle: the zeros of ``den`` (see :func:`nrobust.roots.find_roots`)."""
        from .roots import find_roots

        return find_roots(self.den, region, **kwargs)

    def zeros(self, region: tuple[float, float, float, float], **kwargs: Any) -> "RootSet":
        """Certified zeros in a rectangle: the zeros of ``num``."""
        from .roots import find_roots

        return find_roots(self.num, region, **kwargs)

    # ------------------------------------------------------------------ interconnection
    def series(self, other: "QuasiTransferFunction | QuasiPolynomial | complex") -> "QuasiTransferFunction":
        """``self * other``: the two blocks in cascade."""
        other = _as_tf("other", other)
        return QuasiTransferFunction(
            _product("other", self.num, other.num), _product("other", self.den, other.den)
        )

    def parallel(self, other: "QuasiTransferFunction | QuasiPolynomial | complex") -> "QuasiTransferFunction":
        """``self + other``: the two blocks in parallel."""
        other = _as_tf("other", other)
        if _is_one(self.den) and _is_one(other.den):
            return QuasiTransferFunction(self.num + other.num, 1.0)
        num = _product("other", self.num, other.den) + _product("other", other.num, self.den)
        return QuasiTransferFunction(num, _product("other", self.den, other.den))

    def feedback(self, other: "QuasiTransferFunction | QuasiPolynomial | complex" = 1.0, sign: int = -1) -> "QuasiTransferFunction":
        """Close the loop around ``self`` with ``other`` in the return path.

        ``sign = -1`` (negative feedback, python-control's default) gives
        ``H / (1 + H G)``; ``sign = +1`` gives ``H / (1 - H G)``. With
        ``H = n_1/d_1`` and ``G = n_2/d_2`` the result is
        ``n_1 d_2 / (d_1 d_2 - sign n_1 n_2)``: its denominator is the closed-loop
        characteristic function, e.g. ``F(s)`` of the paper's eq. (delay_eq_alpha_ter)
        when ``H = H_1`` and ``G`` is the delayed controller.
        """
        if sign not in (-1, 1):
            raise ParameterError("sign", "-1 (negative feedback) or +1 (positive feedback)", sign)
        other = _as_tf("other", other)
        num = _product("other", self.num, other.den)
        den = _product("other", self.den, other.den) - sign * _product("other", self.num, other.num)
        return QuasiTransferFunction(num, den)

    def delay(self, delta: float) -> "QuasiTransferFunction":
        """Multiply by ``e^{-delta s}``: a delay ``delta >= 0`` in series."""
        delta = nonnegative("delta", delta)
        return QuasiTransferFunction(self.num.shift(delta), self.den)

    def __mul__(self, other: Any) -> "QuasiTransferFunction":
        if not isinstance(other, (QuasiTransferFunction, QuasiPolynomial, int, float, complex, np.number)):
            return NotImplemented
        return self.series(other)

    __rmul__ = __mul__

    def __add__(self, other: Any) -> "QuasiTransferFunction":
        if not isinstance(other, (QuasiTransferFunction, QuasiPolynomial, int, float, complex, np.number)):
            return NotImplemented
        return self.parallel(other)

    __radd__ = __add__

    def __neg__(self) -> "QuasiTransferFunction":
        return QuasiTransferFunction(-self.num, self.den)

    def __sub__(self, other: Any) -> "QuasiTransferFunction":
        return self + (-_as_tf("other", other))

    # ------------------------------------------------------------------ display
    def __repr__(self) -> str:
        return f"QuasiTransferFunction(\n  num={self.num!r},\n  den={self.den!r})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return {"num": self.num.to_dict(), "den": self.den.to_dict()}


def _as_tf(name: str, value: Any) -> QuasiTransferFunction:
    if isinstance(value, QuasiTransferFunction):
        return value
    return QuasiTransferFunction(_as_quasi(name, value), 1.0)


# ---------------------------------------------------------------------- from systems
def open_loop_tf(system: Any, n: int | None = None) -> QuasiTransferFunction:
    """Open-loop transfer function from ``U`` to the boundary output.

    For a :class:`~nrobust.hyperbolic.TransportSystem` (or any uncoupled system) this is
    ``H_0(s) = 1 / (1 - rho q e^{-tau s})`` (from ``U`` to ``v(t, 1)``, Laplace transform
    of eq. (delay_eq_no_couplings)); for a :class:`~nrobust.hyperbolic.Hyperbolic2x2` it is
    ``H_1(s) = 1 / (1 - rho q e^{-tau s} + int_0^tau N~(nu) e^{-nu s} dnu)`` (from ``U_0``
    to ``beta(t, 1)``, Laplace transform of eq. (delay_eq_alpha)), whose denominator is
    ``delay_form(system).characteristic``.

    Parameters
    ----------
    system : TransportSystem or Hyperbolic2x2
    n : int, optional
        Kernel grid passed to :func:`~nrobust.hyperbolic.delay_form` (coupled systems only;
        default: the grid of the closed-loop functions, so that ``H_1`` and
        :func:`closed_loop_tf` share the same ``N~``).
    """
    from .hyperbolic.system import Hyperbolic2x2

    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem", system)
    if system.uncoupled:
        return QuasiTransferFunction(1.0, QuasiPolynomial([[1.0], [-system.rho_q]], [0.0, system.tau]))
    from .hyperbolic.controllers import DEFAULT_N
    from .hyperbolic.delay_form import delay_form
    form = delay_form(system, n=DEFAULT_N if n is None else positive_int("n", n, 2))
    return QuasiTransferFunction(1.0, form.characteristic)


def output_map(system: Any, n: int | None = None) -> QuasiPolynomial:
    """``M(s)`` with ``v(s, 1) = M(s) beta(s, 1)`` for zero initial data.

    The inverse transformation (eq. (back_inv2)) at ``x = 1`` with
    ``alpha(s, xi) = q e^{-(xi/lam + 1/mu) s} beta(s, 1)`` and
    ``beta(s, xi) = e^{-(1 - xi) s / mu} beta(s, 1)`` (eqs. (eq_alpha_1)-(eq_beta_1)) gives
    ``M(s) = 1 + int_0^tau M~(nu) e^{-nu s} dnu`` with
    ``M~(nu) = lam q L^{beta alpha}(1, lam nu - lam/mu) h_[1/mu, tau](nu)
    + mu L^{beta beta}(1, 1 - mu nu) h_[0, 1/mu](nu)``, the same change of variables as
    ``N~`` in eq. (eq_N_tilde). For a transport system ``M = 1``.

    Parameters
    ----------
    system : TransportSystem or Hyperbolic2x2
    n : int, optional
        Kernel grid (default: that of the closed-loop functions); ``M~`` is tabulated on
        ``n + 1`` points of each piece.
    """
    from .hyperbolic.controllers import DEFAULT_N
    from .hyperbolic.kernels import solve_kernels
    from .hyperbolic.system import Hyperbolic2x2

    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or TransportSystem", system)
    if system.uncoupled:
        return QuasiPolynomial([[1.0]], [0.0])
    m = DEFAULT_N if n is None else positive_int("n", n, 2)
    kernels = solve_kernels(system, n=m)
    lam, mu, q = float(system.lam), float(system.mu), float(system.q)
    xi = np.linspace(0.0, 1.0, m + 1)
    ones = np.ones_like(xi)
    # beta part on nu in [0, 1/mu]: xi = 1 - mu nu, decreasing in nu
    nu_b = (1.0 - xi[::-1]) / mu
    val_b = mu * np.asarray(kernels.Lbb(ones, xi[::-1]), dtype=float)
    # alpha part on nu in [1/mu, tau]: xi = lam (nu - 1/mu)
    nu_a = xi / lam + 1.0 / mu
    val_a = lam * q * np.asarray(kernels.Lba(ones, xi), dtype=float)
    nodes = np.concatenate([nu_b, nu_a])
    values = np.concatenate([val_b, val_a])
    if not np.any(values != 0):
        return QuasiPolynomial([[1.0]], [0.0])
    return QuasiPolynomial([[1.0]], [0.0], [DistributedDelay(nodes, values)])


def closed_loop_tf(system: Any, controller: Any, delta: float, output: str = "v") -> QuasiTransferFunction:
    """Closed-loop transfer function from a disturbance at the actuated boundary.

    The disturbance ``d`` enters where the (delayed) control does,
    ``v(t, 1) = rho u(t, 1) + U(t - delta) + d(t)`` (eq. (IC)). With the loop written as
    ``F(s) = A(s) + B(s) e^{-delta s}`` (:func:`~nrobust.hyperbolic.loop_factors`, the
    characteristic function of eq. (delay_eq_alpha_ter) and its variants), ``A = D c_d`` and
    ``B = -c_n`` where ``D`` is the open-loop denominator of ``H_1`` and ``c_n / c_d`` the
    controller's map from ``beta(t, 1)`` to ``U``, the transfer to ``beta(t, 1)`` is
    ``c_d(s) / F(s)``; to ``v(t, 1)`` it is ``M(s) c_d(s) / F(s)`` with ``M`` from
    :func:`output_map`.

    Parameters
    ----------
    system : TransportSystem or Hyperbolic2x2
    controller : a controller of :mod:`nrobust.hyperbolic`
    delta : float
        Loop delay ``>= 0``.
    output : {"v", "beta"}
        ``"v"`` for ``v(t, 1)`` (default), ``"beta"`` for the target-system output.

    Returns
    -------
    QuasiTransferFunction
        Its denominator is the closed-loop characteristic function ``F``.
    """
    from .hyperbolic.controllers import loop_factors

    delta = nonnegative("delta", delta)
    if output not in ("v", "beta"):
        raise ParameterError("output", '"v" or "beta"', output)
    A, B = loop_factors(system, controller)
    F = A + B.shift(delta)
    c_d = _controller_denominator(controller)
    num = c_d if output == "beta" else _product("output", output_map(system), c_d)
    return QuasiTransferFunction(num, F)


def _controller_denominator(controller: Any) -> QuasiPolynomial:
    """``c_d(s)``: ``1 + b s`` for the filtered controller ``(1 + a s)/(1 + b s)``, else 1."""
    from .hyperbolic.controllers import FilteredController

    if isinstance(controller, FilteredController):
        return QuasiPolynomial([[1.0, float(controller.b)]], [0.0])
    return QuasiPolynomial([[1.0]], [0.0])


# ---------------------------------------------------------------------- python-control
def _response(obj: Any, s: NDArray[np.complex128]) -> NDArray[np.complex128]:
    if isinstance(obj, (QuasiTransferFunction, QuasiPolynomial)):
        return np.asarray(obj(s), dtype=complex)
    raise ParameterError("F_or_tf", "a QuasiPolynomial or a QuasiTransferFunction", obj)


def _omega_grid(omega: ArrayLike) -> NDArray[np.float64]:
    w = np.asarray(omega, dtype=float)
    if w.ndim != 1 or w.size < 2 or not np.all(np.isfinite(w)) or np.any(w < 0) or np.any(np.diff(w) <= 0):
        raise ParameterError("omega", "a 1-D increasing array of at least 2 finite frequencies >= 0", omega)
    return w


def to_frd(F_or_tf: QuasiPolynomial | QuasiTransferFunction, omega: ArrayLike) -> "control.FrequencyResponseData":
    """Tabulate ``F(i omega)`` (or ``H(i omega)``) as a python-control FRD.

    The result can be passed to python-control's frequency-domain tools (``bode_plot``,
    ``margin``...). Its Nyquist encirclement count assumes the response decays at high
    frequency, which is false for neutral loops: use :func:`nrobust.plots.nyquist_response`
    for the count.
    """
    import control

    w = _omega_grid(omega)
    return control.FrequencyResponseData(_response(F_or_tf, 1j * w), w)


def _rational(f: QuasiPolynomial, order: int, n_quad: int) -> "control.TransferFunction":
    """A rational approximation of a quasi-polynomial ``f``.

    Every ``e^{-tau s}`` is replaced by ``control.pade(tau, order)``; a distributed term
    ``q(s) int N(nu) e^{-nu s} dnu`` is first discretised by the composite midpoint rule
    with ``n_quad`` nodes on each interval of the support between jumps,
    ``sum_i w_i N(nu_i) e^{-nu_i s}`` (``N(nu_i)`` interpolated linearly between the
    tabulated values), and each point delay of that sum replaced likewise.
    """
    import control

    delays: dict[float, Any] = {}

    def exp_tf(tau: float) -> Any:
        if tau == 0.0:
            return control.TransferFunction([1.0], [1.0])
        if tau not in delays:
            num, den = control.pade(tau, order)
            delays[tau] = control.TransferFunction(num, den)
        return delays[tau]

    def poly_tf(coefs: NDArray) -> Any:
        c = np.real_if_close(np.asarray(coefs))
        if np.iscomplexobj(c):
            raise ParameterError("tf", "real polynomial coefficients for a python-control model", coefs)
        return control.TransferFunction(c[::-1].astype(float), [1.0])

    total: Any = control.TransferFunction([0.0], [1.0])
    for p, t in f.point_terms:
        total = total + poly_tf(p) * exp_tf(t)
    for d in f.distributed:
        if d.moment:
            raise ParameterError("tf", "distributed terms of moment 0 for the Pade approximation", d)
        if np.iscomplexobj(d.values):
            raise ParameterError("tf", "real distributed kernels for a python-control model", d)
        pieces = np.flatnonzero(np.diff(d.nodes) == 0) + 1
        acc: Any = control.TransferFunction([0.0], [1.0])
        for lo, hi in zip(np.r_[0, pieces], np.r_[pieces, d.nodes.size]):
            nodes, vals = d.nodes[lo:hi], d.values[lo:hi]
            if nodes[-1] <= nodes[0]:
                continue
            edges = np.linspace(nodes[0], nodes[-1], n_quad + 1)
            mids = 0.5 * (edges[1:] + edges[:-1])
            weights = np.diff(edges) * np.interp(mids, nodes, vals)
            for nu, wgt in zip(mids, weights):
                acc = acc + float(wgt) * exp_tf(round(float(nu), 15))
        total = total + poly_tf(d.poly) * acc
    return total


def pade_approximation(
    tf: QuasiTransferFunction | QuasiPolynomial,
    order: int,
    omega: ArrayLike,
    n_quad: int = 8,
) -> tuple["control.TransferFunction", NDArray[np.float64]]:
    """A rational python-control model of a transfer function with delays.

    Each point delay ``e^{-tau s}`` is replaced by ``control.pade(tau, order)``. A
    distributed term is replaced by the Pade approximation of its discretisation: the
    composite midpoint rule with ``n_quad`` nodes per smooth piece of the kernel (jumps
    of ``N~`` at ``nu = 1/mu`` are kept as piece boundaries), each node a point delay.
    The model is valid in a band ``|omega| tau_max << order``; the error is returned so
    that the band can be checked, never assumed.

    Parameters
    ----------
    tf : QuasiTransferFunction or QuasiPolynomial
    order : int
        Pade order per delay (``>= 1``).
    omega : array_like
        Increasing frequencies ``>= 0`` on which the error is measured.
    n_quad : int, optional
        Midpoint nodes per smooth piece of each distributed kernel (default 8).

    Returns
    -------
    model : control.TransferFunction
    error : ndarray
        ``|H(i omega) - model(i omega)|`` on ``omega``.
    """
    import control

    order = positive_int("order", order)
    n_quad = positive_int("n_quad", n_quad)
    w = _omega_grid(omega)
    if isinstance(tf, QuasiPolynomial):
        tf = QuasiTransferFunction(tf, 1.0)
    if not isinstance(tf, QuasiTransferFunction):
        raise ParameterError("tf", "a QuasiTransferFunction or a QuasiPolynomial", tf)
    num = _rational(tf.num, order, n_quad)
    den = _rational(tf.den, order, n_quad)
    model = control.TransferFunction(
        np.polymul(num.num[0][0], den.den[0][0]), np.polymul(num.den[0][0], den.num[0][0])
    )
    exact = tf.frequency_response(w)
    approx = np.asarray(model(1j * w), dtype=complex)
    return model, np.abs(exact - approx)
