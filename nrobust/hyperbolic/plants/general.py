"""General linear 2x2 heterodirectional systems and their normal form.

The plant as it comes out of a linearised physical model, on ``x in [0, L]``::

    u_t + lam(x) u_x = a(x) u + b(x) v,      u(t, 0) = q v(t, 0),
    v_t - mu(x)  v_x = c(x) u + d(x) v,      v(t, L) = rho u(t, L) + U(t),

with ``lam, mu > 0``. :meth:`GeneralHyperbolic2x2.normal_form` brings it to the paper's
plant (18)-(20) (:class:`~nrobust.hyperbolic.plants.hyperbolic2x2.Hyperbolic2x2`) in three steps
(derived in ``docs/theory.md``, section "General plants and their normal form"):

1. the diagonal terms are removed by the exponential scaling ``u = e^{A(x) + k} u~``,
   ``v = e^{D(x)} v~`` with ``A = int_0^x a/lam``, ``D = -int_0^x d/mu`` and the constant
   ``k`` that centres the range of ``D - A`` (so the two couplings are balanced: the
   kernels' grid needs ``max |sigma| / min(lam, mu)`` small);
2. space is measured by the transport time of ``u``, ``y = phi(x)/phi(L)`` with
   ``phi = int_0^x 1/lam``, so that ``lam~ = 1/phi(L)``; ``mu~ = 1/psi(L)`` with
   ``psi = int_0^x 1/mu`` is then constant exactly when ``lam/mu`` is, and the round
   trip is ``tau = int_0^L 1/lam + int_0^L 1/mu`` (time is measured in ``time_unit``:
   the speeds and couplings of the normal form are multiplied by it);
3. the boundary gains and the actuation follow: ``q~ = q e^{-k}``,
   ``rho~ = rho e^{A(L) + k - D(L)}``, ``U~ = e^{-D(L)} U``, and the couplings are
   ``sigma_pm(y) = b e^{D - A - k}``, ``sigma_mp(y) = c e^{A + k - D}`` at ``x(y)``.

The transformation is an exact change of variables (no approximation beyond the
quadrature of ``phi, psi, A, D`` and the cubic-spline tabulation of the couplings on 2049
nodes, both at rounding level for smooth coefficients: 8e-15 relative measured), so the
two plants have the same spectrum, delay margins and closed-loop behaviour. Proofs do not
rest on these tables: with every coefficient a number or a function,
:mod:`~nrobust.hyperbolic.loops.varying_proof` encloses ``x(y)``, ``A, D`` and the couplings in
ball arithmetic (a varying ``lam/mu`` too, through its characteristic system); coefficients given
as samples are the user's model (their cubic spline).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..._json import json_safe
from ..._validate import finite_real, is_real_number, positive, real_array
from ...errors import ParameterError
from .hyperbolic2x2 import Hyperbolic2x2

if TYPE_CHECKING:
    from scipy.interpolate import CubicHermiteSpline

__all__ = ["Coefficient", "GeneralHyperbolic2x2", "NormalForm", "as_general"]

Array = NDArray[np.float64]
#: A coefficient of the general plant: a number, a callable on ``[0, L]`` or samples ``(x, values)``.
Coefficient = float | Callable[[Array], Any] | tuple[Any, Any]

# Panels of the composite Gauss rule that tabulates phi, psi, A, D (5 points each):
# the integrals are exact to rounding for smooth coefficients.
_PANELS = 1024
_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(5)
# Nodes on which the couplings of the normal form are tabulated (cubic spline between).
_COUPLING_NODES = 2049
# Relative variation of lam/mu below which the speed ratio counts as constant.
_RATIO_RTOL = 1e-10


@dataclass(frozen=True)
class Profile:
    """One coefficient on ``[0, L]``: a number, a callable, or a spline through samples.

    Picklable whenever the user's callable is. ``value`` is what the user gave (a float,
    the callable, or the samples as a tuple of two tuples).
    """

    name: str
    value: Any
    spline: Any = None

    @property
    def constant(self) -> bool:
        return not callable(self.value) and not isinstance(self.value, tuple)

    def __call__(self, x: Any) -> Array:
        arr = np.asarray(x, dtype=float)
        if self.constant:
            return np.full(arr.shape, float(self.value))
        if self.spline is not None:
            return np.asarray(self.spline(arr), dtype=float)
        with np.errstate(all="ignore"):
            try:
                out = np.asarray(self.value(arr))
            except Exception:  # a scalar-only callable may raise anything on an array
                out = None
        if out is None or out.shape != arr.shape or out.dtype.kind not in "iuf":
            flat = []
            for t in arr.ravel():
                try:
                    val = self.value(float(t))
                except Exception as exc:
                    raise ParameterError(
                        self.name, f"a callable returning real numbers on [0, L]; at x = {t:g} it raised {exc!r}"
                    ) from exc
                if not is_real_number(val):
                    raise ParameterError(self.name, "a callable returning real numbers on [0, L]", val)
                flat.append(float(val))
            out = np.asarray(flat).reshape(arr.shape)
        return out.astype(float)

    def describe(self) -> Any:
        if self.constant:
            return float(self.value)
        if isinstance(self.value, tuple):
            return {"x": self.value[0], "values": self.value[1]}
        return f"<function {getattr(self.value, '__qualname__', type(self.value).__name__)}>"


def coefficient_profile(name: str, value: Any, length: float) -> Profile:
    """Check one coefficient and return its evaluator (samples must span ``[0, L]``)."""
    from scipy.interpolate import make_interp_spline  # lazily: scipy.interpolate is slow to import

    if callable(value):
        return Profile(name, value)
    if isinstance(value, (tuple, list)) and len(value) == 2 and not is_real_number(value):
        x = real_array(f"{name}[0]", value[0], min_size=2)
        v = real_array(f"{name}[1]", value[1], min_size=2)
        if x.shape != v.shape:
            raise ParameterError(name, "samples (x, values) of equal lengths", (x.size, v.size))
        if np.any(np.diff(x) <= 0) or abs(x[0]) > 1e-12 * length or abs(x[-1] - length) > 1e-12 * length:
            raise ParameterError(f"{name}[0]", f"increasing nodes from 0 to L = {length:g}", value[0])
        spline = make_interp_spline(x, v, k=min(3, x.size - 1))
        return Profile(name, (tuple(x.tolist()), tuple(v.tolist())), spline)
    if isinstance(value, (bool, np.bool_)) or not is_real_number(value):
        raise ParameterError(name, "a finite real number, a callable on [0, L] or samples (x, values)", value)
    return Profile(name, finite_real(name, value))


@dataclass(frozen=True, eq=False)
class _Tables:
    """``phi, psi, A, D`` on the panel nodes, with cubic Hermite interpolants (exact slopes)."""

    x: Array
    phi: CubicHermiteSpline
    psi: CubicHermiteSpline
    A: CubicHermiteSpline
    D: CubicHermiteSpline
    x_of_y: CubicHermiteSpline
    t_u: float
    t_v: float


def _cumulative(f: Callable[[Array], Array], length: float) -> tuple[Array, Array]:
    """Nodes of ``[0, L]`` and ``int_0^x f`` there (composite 5-point Gauss rule)."""
    nodes = np.linspace(0.0, length, _PANELS + 1)
    h = length / _PANELS
    pts = nodes[:-1, None] + 0.5 * h * (1.0 + _GAUSS_X[None, :])
    panel = 0.5 * h * (f(pts) @ _GAUSS_W)
    return nodes, np.concatenate([[0.0], np.cumsum(panel)])


@dataclass(frozen=True, repr=False, eq=False)
class GeneralHyperbolic2x2:
    """A linear 2x2 heterodirectional system with varying speeds and diagonal terms.

    ``u_t + lam(x) u_x = a(x) u + b(x) v``, ``v_t - mu(x) v_x = c(x) u + d(x) v`` on
    ``[0, L]``, ``u(t, 0) = q v(t, 0)``, ``v(t, L) = rho u(t, L) + U(t)``.

    Parameters
    ----------
    lam, mu : float, callable or (x, values)
        Speeds, positive on ``[0, L]``: a number, a callable on arrays of ``x`` in
        ``[0, L]``, or samples (increasing nodes from 0 to ``L`` and values; cubic spline).
    a, b, c, d : float, callable or (x, values)
        In-domain coefficients, same forms.
    q : float
        Distal reflection ``u(t, 0) = q v(t, 0)``, nonzero.
    rho : float
        Proximal reflection ``v(t, L) = rho u(t, L) + U(t)``.
    length : float, default 1
        ``L > 0``.
    time_unit : float, default 1
        The unit, in the time of the equations, in which every analysis of the plant
        speaks: the normal form's time is ``t / time_unit``, so delays, margins and
        frequencies of :func:`~nrobust.delay_margin` or the Laplace variable of
        :func:`~nrobust.hyperbolic.boundary_function` are in that unit (e.g. 60 for
        minutes when the coefficients are in seconds). The root counts and crossing
        searches are fastest when the round trip is of order 1 in that unit.

    Raises
    ------
    ParameterError
        Naming the bad coefficient: a speed not positive, a value not finite on the
        1025-node probe grid of ``[0, L]``, samples not spanning ``[0, L]``, ``q = 0``.
    """

    lam: Coefficient
    mu: Coefficient
    a: Coefficient
    b: Coefficient
    c: Coefficient
    d: Coefficient
    q: float
    rho: float
    length: float = 1.0
    time_unit: float = 1.0
    profiles: dict[str, Profile] = field(init=False, repr=False)
    tables: _Tables = field(init=False, repr=False)

    def __post_init__(self) -> None:
        length = positive("length", self.length)
        object.__setattr__(self, "time_unit", positive("time_unit", self.time_unit))
        object.__setattr__(self, "length", length)
        q = finite_real("q", self.q)
        if q == 0.0:
            raise ParameterError("q", "nonzero (the normal form's kernels divide by q)", self.q)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "rho", finite_real("rho", self.rho))
        probe = np.linspace(0.0, length, _PANELS + 1)
        profiles = {}
        for name in ("lam", "mu", "a", "b", "c", "d"):
            prof = coefficient_profile(name, getattr(self, name), length)
            values = prof(probe)
            if not np.all(np.isfinite(values)):
                raise ParameterError(
                    name, f"finite on [0, L] = [0, {length:g}] (checked on {probe.size} nodes)", prof.describe()
                )
            if name in ("lam", "mu") and np.min(values) <= 0.0:
                raise ParameterError(name, "positive on [0, L]", f"min {np.min(values):.6g}")
            object.__setattr__(self, name, prof.value)
            profiles[name] = prof
        object.__setattr__(self, "profiles", profiles)
        object.__setattr__(self, "tables", self._tabulate())

    def _tabulate(self) -> _Tables:
        from scipy.interpolate import CubicHermiteSpline  # lazily: scipy.interpolate is slow to import

        p = self.profiles
        lam, mu, a, d = p["lam"], p["mu"], p["a"], p["d"]
        x, phi = _cumulative(lambda t: 1.0 / lam(t), self.length)
        _, psi = _cumulative(lambda t: 1.0 / mu(t), self.length)
        _, A = _cumulative(lambda t: a(t) / lam(t), self.length)
        _, D = _cumulative(lambda t: -d(t) / mu(t), self.length)
        lx, mx = lam(x), mu(x)
        t_u, t_v = float(phi[-1]), float(psi[-1])
        return _Tables(
            x=x,
            phi=CubicHermiteSpline(x, phi, 1.0 / lx),
            psi=CubicHermiteSpline(x, psi, 1.0 / mx),
            A=CubicHermiteSpline(x, A, a(x) / lx),
            D=CubicHermiteSpline(x, D, -d(x) / mx),
            x_of_y=CubicHermiteSpline(phi / t_u, x, t_u * lx),
            t_u=t_u,
            t_v=t_v,
        )

    # ------------------------------------------------------------------ coefficients
    def coefficient(self, name: str, x: Any) -> Array:
        """The coefficient ``name`` (``"lam"``, ``"mu"``, ``"a"``, ``"b"``, ``"c"``, ``"d"``) at ``x``."""
        if name not in self.profiles:
            raise ParameterError("name", f"one of {list(self.profiles)}", name)
        return self.profiles[name](x)

    def is_constant(self, name: str) -> bool:
        """True when the coefficient ``name`` was given as a number."""
        return self.profiles[name].constant

    @property
    def transport_times(self) -> tuple[float, float]:
        """``(int_0^L 1/lam, int_0^L 1/mu)``: the times of flight of ``u`` and ``v``."""
        return self.tables.t_u, self.tables.t_v

    @property
    def tau(self) -> float:
        """Round-trip time ``int_0^L 1/lam + int_0^L 1/mu``."""
        return self.tables.t_u + self.tables.t_v

    @property
    def rho_q(self) -> float:
        """Open-loop gain of the principal part, ``rho q e^{A(L) - D(L)}`` (the normal form's ``rho~ q``)."""
        return self.rho * self.q * float(np.exp(self.tables.A(self.length) - self.tables.D(self.length)))

    def phi(self, x: Any) -> Array:
        """``int_0^x 1/lam``."""
        return np.asarray(self.tables.phi(np.asarray(x, dtype=float)))

    def psi(self, x: Any) -> Array:
        """``int_0^x 1/mu``."""
        return np.asarray(self.tables.psi(np.asarray(x, dtype=float)))

    def A(self, x: Any) -> Array:
        """``int_0^x a/lam``, the exponent of the scaling of ``u``."""
        return np.asarray(self.tables.A(np.asarray(x, dtype=float)))

    def D(self, x: Any) -> Array:
        """``-int_0^x d/mu``, the exponent of the scaling of ``v``."""
        return np.asarray(self.tables.D(np.asarray(x, dtype=float)))

    @property
    def constant_ratio(self) -> bool:
        """True when ``lam(x)/mu(x)`` is constant (relative variation below 1e-10)."""
        r = self.coefficient("lam", self.tables.x) / self.coefficient("mu", self.tables.x)
        return bool(np.ptp(r) <= _RATIO_RTOL * np.max(np.abs(r)))

    def normal_form(self) -> NormalForm:
        """The paper's plant on ``[0, 1]`` equivalent to this one, and the maps between them.

        Returns
        -------
        NormalForm

        Raises
        ------
        ParameterError
            On ``mu`` when ``lam/mu`` varies: one change of the space variable scales both
            speeds by the same factor, so constant speeds need a constant ratio
            (``docs/theory.md``); the characteristic route
            (:func:`~nrobust.hyperbolic.loops.varying_form.varying_delay_form`) and the kernel-free route
            (:func:`~nrobust.hyperbolic.boundary_function`) still apply.
        """
        if not self.constant_ratio:
            raise ParameterError(
                "mu",
                "proportional to lam on [0, L] for normal_form() (constant lam/mu: one change of space variable "
                "cannot make both speeds constant otherwise); for any speeds loop_factors and delay_margin use "
                "varying_delay_form, and boundary_function the Laplace route",
                self.profiles["mu"].describe(),
            )
        return NormalForm(self)

    def __repr__(self) -> str:
        parts = ", ".join(f"{k}={self.profiles[k].describe()!r}" for k in ("lam", "mu", "a", "b", "c", "d"))
        return (
            f"GeneralHyperbolic2x2({parts}, q={self.q!r}, rho={self.rho!r}, length={self.length!r}, "
            f"time_unit={self.time_unit!r})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description; samples listed, callables named and tabulated on 11 points of ``[0, L]``."""
        out: dict[str, Any] = {"type": "GeneralHyperbolic2x2"}
        x = np.linspace(0.0, self.length, 11)
        for name, prof in self.profiles.items():
            plain = prof.constant or isinstance(prof.value, tuple)
            out[name] = prof.describe() if plain else {"callable": prof.describe(), "x": x, "values": prof(x)}
        out.update({"q": self.q, "rho": self.rho, "length": self.length, "time_unit": self.time_unit})
        out.update({"tau": self.tau, "rho_q": self.rho_q})
        return json_safe(out)


@dataclass(frozen=True, repr=False)
class _Scaled:
    """``y -> coef(x(y)) e^{sign (D - A - k)(x(y))}`` (a normal-form coupling), picklable.

    Evaluated once on :data:`_COUPLING_NODES` uniform nodes of ``[0, 1]`` and then by the
    not-a-knot cubic spline through them (the kernel solver calls a coupling thousands of
    times; a physical coefficient may cost a profile evaluation each time). The spline's
    error is ``O(h^4)``: below 1e-12 relative on the tests' plants (``exact`` is the
    direct evaluation).
    """

    general: GeneralHyperbolic2x2
    coef: str
    sign: float
    offset: float
    spline: Any = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        from scipy.interpolate import make_interp_spline  # lazily: scipy.interpolate is slow to import

        nodes = np.linspace(0.0, 1.0, _COUPLING_NODES)
        object.__setattr__(self, "spline", make_interp_spline(nodes, self.exact(nodes), k=3))

    def exact(self, y: Any) -> Array:
        """The coupling evaluated through the coefficient itself."""
        g = self.general
        x = np.asarray(g.tables.x_of_y(np.clip(np.asarray(y, dtype=float), 0.0, 1.0)))
        exponent = self.sign * (g.D(x) - g.A(x) - self.offset)
        return g.time_unit * g.coefficient(self.coef, x) * np.exp(exponent)

    def __call__(self, y: Any) -> Array:
        return np.asarray(self.spline(np.clip(np.asarray(y, dtype=float), 0.0, 1.0)), dtype=float)

    def __repr__(self) -> str:
        sign = "" if self.sign > 0 else "-"
        offset = f"- {self.offset:.6g}" if self.offset >= 0 else f"+ {-self.offset:.6g}"
        return f"<normal-form coupling T {self.coef} e^({sign}(D - A {offset}))>"


@dataclass(frozen=True)
class _MappedGain:
    """``y -> scale g(x(y)) e^{W(x(y))} t_u lam(x(y))``, a feedback gain in normal coordinates."""

    general: GeneralHyperbolic2x2
    gain: Any
    weight: str
    scale: float
    offset: float

    def __call__(self, y: Any) -> Array:
        g = self.general
        x = np.asarray(g.tables.x_of_y(np.clip(np.asarray(y, dtype=float), 0.0, 1.0)))
        w = g.A(x) + self.offset if self.weight == "u" else g.D(x)
        t_u = g.transport_times[0]
        return self.scale * Profile("gain", self.gain)(x) * np.exp(w) * t_u * g.coefficient("lam", x)


@dataclass(frozen=True, repr=False, eq=False)
class NormalForm:
    """The normal form of a :class:`GeneralHyperbolic2x2` and the maps back.

    ``u(t, x) = e^{A(x) + k} u~(t, y(x))``, ``v(t, x) = e^{D(x)} v~(t, y(x))``,
    ``y(x) = phi(x)/phi(L)``, ``U = e^{D(L)} U~``.

    Attributes
    ----------
    general : GeneralHyperbolic2x2
        The plant in its own coordinates.
    system : Hyperbolic2x2
        The paper's plant (18)-(20) on ``[0, 1]``, time in ``T = time_unit``:
        ``lam~ = T/phi(L)``, ``mu~ = T/psi(L)``, ``sigma_pm = T b e^{D - A - k}``,
        ``sigma_mp = T c e^{A + k - D}`` at ``x(y)``, ``q~ = q e^{-k}``,
        ``rho~ = rho e^{A(L) + k - D(L)}``.
    balance : float
        ``k``, the mid-range of ``D - A`` on ``[0, L]`` (0 when ``D - A`` is constant).
    control_gain : float
        ``e^{D(L)}``: the physical control is ``U = control_gain * U~``.
    """

    general: GeneralHyperbolic2x2
    system: Hyperbolic2x2 = field(init=False)
    control_gain: float = field(init=False)
    balance: float = field(init=False)

    def __post_init__(self) -> None:
        g = self.general
        t_u, t_v = g.transport_times
        end = g.length
        exponent = g.D(g.tables.x) - g.A(g.tables.x)
        balance = 0.5 * float(np.max(exponent) + np.min(exponent))
        couplings = []
        for coef, sign in (("b", 1.0), ("c", -1.0)):
            flat = g.is_constant("a") and g.is_constant("d") and g.is_constant("lam") and g.is_constant("mu")
            no_scaling = flat and float(g.a) / float(g.lam) + float(g.d) / float(g.mu) == 0.0  # type: ignore[arg-type]
            value = g.coefficient(coef, np.zeros(1))[0]
            if g.is_constant(coef) and (value == 0.0 or no_scaling):
                couplings.append(float(value) * g.time_unit)
            else:
                couplings.append(_Scaled(g, coef, sign, balance))  # type: ignore[arg-type]
        rho = g.rho * float(np.exp(g.A(end) + balance - g.D(end)))
        q = g.q * float(np.exp(-balance))
        unit = g.time_unit
        system = Hyperbolic2x2(unit / t_u, unit / t_v, couplings[0], couplings[1], q, rho)
        object.__setattr__(self, "system", system)
        object.__setattr__(self, "balance", balance)
        object.__setattr__(self, "control_gain", float(np.exp(g.D(end))))

    def y_of_x(self, x: Any) -> Array:
        """Normal-form coordinate ``y = phi(x)/phi(L)`` of the points ``x`` of ``[0, L]``."""
        return self.general.phi(x) / self.general.transport_times[0]

    def x_of_y(self, y: Any) -> Array:
        """Physical coordinate of the points ``y`` of ``[0, 1]``."""
        return np.asarray(self.general.tables.x_of_y(np.asarray(y, dtype=float)))

    def to_normal(self, x: Any, u: Any, v: Any) -> tuple[Array, Array, Array]:
        """``(y, u~, v~)`` from a state ``u, v`` sampled at ``x``."""
        g = self.general
        x = np.asarray(x, dtype=float)
        return self.y_of_x(x), np.asarray(u) * np.exp(-g.A(x) - self.balance), np.asarray(v) * np.exp(-g.D(x))

    def from_normal(self, y: Any, u: Any, v: Any) -> tuple[Array, Array, Array]:
        """``(x, u, v)`` from a normal-form state ``u~, v~`` sampled at ``y``."""
        g = self.general
        x = self.x_of_y(y)
        return x, np.asarray(u) * np.exp(g.A(x) + self.balance), np.asarray(v) * np.exp(g.D(x))

    def feedback_to_normal(self, k: float, g_u: Any, g_v: Any) -> tuple[float, Any, Any]:
        """The feedback ``U = k u(L) + int_0^L g_u u + g_v v dx`` in normal coordinates.

        Returns ``(k~, g~_u, g~_v)`` with ``U~ = k~ u~(1) + int_0^1 g~_u u~ + g~_v v~ dy``:
        ``k~ = k e^{A(L) + k_b - D(L)}`` (``k_b`` the balance),
        ``g~_u(y) = e^{-D(L)} g_u e^{A + k_b} t_u lam`` and
        ``g~_v(y) = e^{-D(L)} g_v e^{D} t_u lam`` at ``x(y)`` (``dx = t_u lam dy``).
        Numbers stay numbers when the map leaves them constant.
        """
        g = self.general
        end = g.length
        scale = float(np.exp(-g.D(end)))
        # the factor of rho~, to the bit: k = -rho cancels the reflection exactly, as it does physically
        k_n = finite_real("k", k) * float(np.exp(g.A(end) + self.balance - g.D(end)))
        gains: list[Any] = []
        for gain, weight in ((g_u, "u"), (g_v, "v")):
            if not callable(gain) and finite_real(f"g_{weight}", gain) == 0.0:
                gains.append(0.0)
            else:
                gains.append(_MappedGain(g, gain, weight, scale, self.balance if weight == "u" else 0.0))
        return k_n, gains[0], gains[1]

    def __repr__(self) -> str:
        return f"NormalForm(system={self.system!r}, control_gain={self.control_gain:.6g})"


def as_general(system: Hyperbolic2x2 | GeneralHyperbolic2x2) -> GeneralHyperbolic2x2:
    """A plant as a :class:`GeneralHyperbolic2x2` (the paper's plant: ``a = d = 0``, ``L = 1``)."""
    if isinstance(system, GeneralHyperbolic2x2):
        return system
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or GeneralHyperbolic2x2", system)
    return GeneralHyperbolic2x2(system.lam, system.mu, 0.0, system.sigma_pm, system.sigma_mp, 0.0, system.q, system.rho)
