"""Delay margins of the paper's loops and the gain studies built on them.

:func:`delay_margin` takes a plant and a controller (or the two loop factors ``A, B``)
and returns the margin of ``F(s; delta) = A(s) + B(s) e^{-delta s}``
(:func:`nrobust.margins.delay_margin`). The studies sweep the gain ``K`` of
``U_BS2(K)`` (eq. (53)) or the filter ``(a, b)`` of section 2.3.2: admissible gains
(:func:`k_region`), filters (:func:`ab_region`), the stability chart in ``(K, delta)``
(:func:`stability_chart`) and the decay-rate/margin trade-off (:func:`tradeoff`). Each
takes ``executor=`` and runs its grid through :func:`nrobust.parallel.sweep_map`.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._json import fields_dict, json_safe
from ..._progress import progress_bar
from ..._validate import is_real_number, positive, positive_int, real_array, renamed_keywords
from ...bounds import root_free_region
from ...errors import CertificationError, ParameterError
from ...margins.crossing import Crossing, axis_crossings, common_axis_zeros, crossing_search, frequency_bound
from ...margins.margin import DelayMargin
from ...margins.margin import delay_margin as factor_delay_margin
from ...quasipoly import QuasiPolynomial
from ...roots import count_roots, spectral_abscissa
from ...sweeps.engine import sweep_map
from ..kernels.constant import DEFAULT_KERNEL_GRID
from ..loops.controllers import (
    Controller,
    FilteredController,
    FiniteTimeController,
    ReflectionController,
    StateFeedback,
    characteristic,
    classify,
    loop_factors,
    normalize,
)
from ..plants.general import GeneralHyperbolic2x2, NormalForm
from ..plants.hyperbolic2x2 import Hyperbolic2x2
from .rouche import rouche_delay_bound

__all__ = [
    "DEFAULT_N_GAINS",
    "END_KINDS",
    "ABRegion",
    "GainEnd",
    "KRegion",
    "StabilityChart",
    "Tradeoff",
    "ab_region",
    "delay_margin",
    "k_region",
    "margin_and_decay",
    "stability_chart",
    "tradeoff",
]

#: Default number of gains of the grid of :func:`k_region` (and of
#: :func:`nrobust.certify`'s K-region). For ``U_BS2(K)`` the ends are solved from their
#: equations whatever the grid; its delay margins are reported and must agree with the
#: intervals (a cross-check, about 0.2 s per gain on the paper's plant). For other
#: controller families the grid has to put one gain inside each admissible interval, whose
#: ends are then bisected.
DEFAULT_N_GAINS = 9


@renamed_keywords(n="kernel_grid")
def delay_margin(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2 | QuasiPolynomial,
    controller: Controller | QuasiPolynomial,
    *,
    delta_max: float | None = None,
    verify: bool = True,
    max_evals: int = 2_000_000,
    kernel_grid: int = DEFAULT_KERNEL_GRID,
    rigorous: bool = False,
) -> DelayMargin:
    """Delay margin and stability intervals of a plant with a controller, or of ``(A, B)``.

    Called as ``delay_margin(system, controller)``: the loop factors of
    :func:`nrobust.hyperbolic.loop_factors` (e.g. eq. (60) for
    ``U_BS2(K)``) are passed to :func:`nrobust.margins.delay_margin`; called as
    ``delay_margin(A, B)`` with two :class:`QuasiPolynomial`, it is that function.

    Parameters
    ----------
    system : Hyperbolic2x2, GeneralHyperbolic2x2 or QuasiPolynomial
        The plant (a general plant through its normal form), or the factor ``A`` of
        ``F(s; delta) = A(s) + B(s) e^{-delta s}``.
    controller : Controller or QuasiPolynomial
        The controller of the plant, or the factor ``B`` when ``system`` is ``A``.
    delta_max, verify, max_evals, rigorous
        As in :func:`nrobust.margins.delay_margin` (``rigorous=True``: proven in ball
        arithmetic for the loop as represented, ``N~`` the cubic spline on the kernel grid).
    kernel_grid : int, default :data:`~nrobust.hyperbolic.kernels.DEFAULT_KERNEL_GRID`
        Kernel grid of the delay form when called with a plant (ignored with ``A, B``;
        formerly ``n``, a deprecated alias); the margin converges at about third order
        in ``1/kernel_grid`` (paper's example: grids of 201 and 401 points differ by
        1.3e-10, ``docs/margins.md``).

    Raises
    ------
    ParameterError
        Naming ``system`` or ``controller`` when they are neither a plant and a
        controller nor two quasi-polynomials ``A, B``.

    Returns
    -------
    DelayMargin
    """
    if isinstance(system, (Hyperbolic2x2, GeneralHyperbolic2x2)):
        if not isinstance(controller, Controller):
            raise ParameterError(
                "controller",
                "a controller (OpenLoop, FiniteTimeController, ReflectionController or FilteredController) "
                "when system is a plant",
                type(controller).__name__,
            )
        A, B = loop_factors(system, controller, kernel_grid)
    elif isinstance(system, QuasiPolynomial):
        if not isinstance(controller, QuasiPolynomial):
            raise ParameterError(
                "controller",
                "a QuasiPolynomial when system is one: the factors (A, B) of F(s; delta) = A(s) + B(s) e^{-delta s} "
                "are passed as (system, controller)",
                type(controller).__name__,
            )
        A, B = system, controller
    else:
        raise ParameterError(
            "system",
            "a plant (Hyperbolic2x2 or TransportSystem, with a controller) or a QuasiPolynomial: the factor A of "
            "F(s; delta) = A(s) + B(s) e^{-delta s}, with B as controller",
            type(system).__name__,
        )
    return factor_delay_margin(A, B, delta_max=delta_max, verify=verify, max_evals=max_evals, rigorous=rigorous)


def margin_and_decay(system: Hyperbolic2x2, controller: Controller) -> dict[str, float]:
    """Delay margin and decay rate of one closed loop: the default analysis of
    :func:`nrobust.robustness`.

    Returns
    -------
    dict
        ``delta_star`` (the ``margin`` of :func:`delay_margin`; ``inf`` when every delay
        is tolerated, 0 when an arbitrarily small delay destabilises), ``abscissa``
        (spectral abscissa of the delay-free characteristic function) and
        ``decay_rate = -abscissa``.
    """
    margin = delay_margin(system, controller)
    abscissa = float(spectral_abscissa(characteristic(system, controller, 0.0)).value)
    return {"delta_star": float(margin.margin), "abscissa": abscissa, "decay_rate": -abscissa}


# ============================================================================ gain studies
def _mapper(
    executor: Any, progress: bool | None = None, desc: str = ""
) -> Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]]:
    """A ``map`` in this process (with a progress bar), else the sweep machinery's (``nrobust.sweep``).

    The bar follows :func:`nrobust._progress.show_progress`: drawn when ``progress`` is True,
    or for None when stderr is a terminal or Jupyter.
    """
    if not (isinstance(executor, str) and executor == "serial"):
        return sweep_map(executor, progress=progress)

    def serial(func: Callable[[Any], Any], items: Iterable[Any]) -> Iterator[Any]:
        todo = list(items)
        with progress_bar(len(todo), progress, desc) as bar:
            for item in todo:
                yield func(item)
                bar.update(1)

    return serial


def _reflection(K: float) -> ReflectionController:
    return ReflectionController(K)


def _margin_for(K: float, system: Any, delta_max: float | None, family: Callable[[float], Any]) -> DelayMargin:
    """Delay margin of ``system`` with ``family(K)`` (module level: picklable for pools)."""
    return delay_margin(system, family(float(K)), delta_max=delta_max, verify=False)


def _tolerates(margin: DelayMargin | _Verdict, delta_max: float) -> bool:
    """True if the loop is stable for every delay in ``[0, delta_max]`` (admissible)."""
    return bool(margin.nominally_stable and margin.margin > delta_max)


def _check_system(system: Any) -> None:
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2, TransportSystem or GeneralHyperbolic2x2", system)
    if system.q == 0:
        raise ParameterError("system.q", "non-zero (otherwise the loop does not depend on K)", system.q)


@dataclass(frozen=True)
class _OnNormalForm:
    """Picklable ``K -> family(K)`` acting on the normal form of a general plant.

    A :class:`~nrobust.hyperbolic.controllers.StateFeedback` has its gains mapped from the
    physical coordinates (:meth:`~nrobust.hyperbolic.general.NormalForm.feedback_to_normal`);
    the paper's controllers are defined on the normal form and pass unchanged.
    """

    form: NormalForm
    family: Callable[[float], Any]

    def __call__(self, K: float) -> Any:
        ctrl = self.family(K)
        if isinstance(ctrl, StateFeedback):
            return StateFeedback(*self.form.feedback_to_normal(ctrl.k, ctrl.g_u, ctrl.g_v))
        return ctrl


def _study_plant(
    system: Any, family: Callable[[float], Any] | None, study: str
) -> tuple[Any, Callable[[float], Any] | None]:
    """The plant and gain family a study runs on.

    A general plant with a constant ``lam/mu`` is replaced by its normal form (once: its
    kernels are then shared by every gain) and a custom ``family`` mapped onto it
    (:class:`_OnNormalForm`). With a varying ``lam/mu`` the plant stays as it is (loop
    factors by the characteristic route), which needs a ``family`` other than U_BS2(K),
    a normal-form controller.
    """
    if isinstance(system, GeneralHyperbolic2x2):
        if system.constant_ratio:
            form = system.normal_form()
            if family is None or family is ReflectionController:
                return form.system, None
            return form.system, _OnNormalForm(form, family)
        if family is None or family is ReflectionController:
            raise ParameterError(
                "controller",
                f"a gain family K -> controller (e.g. StateFeedback) for {study} of a plant with a varying lam/mu: "
                "U_BS2(K) is defined on the normal form, which needs a constant lam/mu",
                family,
            )
        return system, family
    _check_system(system)
    return system, family


def _grid(name: str, values: ArrayLike) -> NDArray[np.float64]:
    """A non-empty 1-D grid of finite reals (a number is a grid of one); booleans and strings are refused."""
    return real_array(name, [values] if is_real_number(values) else values)


# ============================================================================ exact ends of the K-region
#: Kinds of the end of an admissible interval of gains (:attr:`GainEnd.kind`).
END_KINDS = ("crossing", "pair_birth", "nominal", "strong_stability", "bisection")
# Scan step on the axis: dw = pi / (_SCAN_STEPS T) rounded down to a power of two, T the
# longest delay of the scanned functions (A e^{i w (tau + delta)} / R has 2 max_delay + delta):
# at least 2 _SCAN_STEPS samples per period of their fastest oscillation.
_SCAN_STEPS = 4
# The bracketed solves stop at this relative width in w (or after _MAX_SOLVE steps).
_W_RTOL = 1e-14
# The same for the roots of the interpolants (their error is about 1e-8: a root to 1e-10 is
# all they can give; those that matter are solved again on the loop).
_MODEL_RTOL = 1e-10
_MAX_SOLVE = 400
# The first scan covers |K| <= (1 - _FIRST_CAP) k, k the paper's bound; without a critical
# gain past a cap, the next cap is k - (k - cap) / _CAP_SHRINK.
_FIRST_CAP = 0.125
_CAP_SHRINK = 4.0
# The interpolated loop's answers are trusted to _MODEL_SAFETY times its error bound; a
# solve on the loop starts from a bracket of half-width _BRACKET_CELLS scan steps about them.
_MODEL_SAFETY = 10.0
_BRACKET_CELLS = 1e-3
_EPS = float(np.finfo(float).eps)
# Order of the kinds when two events fall on the same gain (to rounding).
_KIND_ORDER = {"nominal": 0, "crossing": 1, "pair_birth": 2, "strong_stability": 3}


class GainEnd(NamedTuple):
    """One end of an admissible interval of gains and the event that closes it.

    Attributes
    ----------
    K : float
        The gain at the end (the interval is open: ``K`` itself is not admissible).
    kind : str
        ``"crossing"``: a root reaches the axis at ``i omega`` for ``delta = delta_max``,
        ``A(i w) + B(i w; K) e^{-i w delta_max} = 0`` (a branch of crossing delays passes
        ``delta_max``); ``"pair_birth"``: ``g(w) = |A(i w)|^2 - |B(i w; K)|^2`` has a double
        zero at ``omega`` (``g = dg/dw = 0``), a pair of crossing frequencies is born with
        crossing delay ``delay <= delta_max``; ``"nominal"``: a root on the axis at
        ``delta = 0`` (the nominal loop loses stability; ``omega = 0`` for ``s = 0``);
        ``"strong_stability"``: ``|rho q| + |K q| = 1``, the difference operator stops being
        strongly stable (roots come from ``omega = inf`` at delays down to ``0``);
        ``"bisection"``: located by bisection on delay margins (a ``controller`` family other
        than ``U_BS2(K)``; ``omega`` and ``delay`` are the first crossing of the margin just
        outside, ``inf`` and that margin if it has none).
    omega : float
        Frequency of the root on the axis (``inf`` at the strong-stability limit).
    delay : float
        Delay at which it is there: ``delta_max``, the birth delay, or ``0`` (never ``nan``).
    """

    K: float
    kind: str
    omega: float
    delay: float


@dataclass(frozen=True)
class _Axis:
    """``A``, ``B_0``, ``R`` at ``s = i w`` and (when computed) their derivatives in ``w``."""

    w: NDArray[np.float64]
    a: NDArray[np.complex128]
    b0: NDArray[np.complex128]
    r: NDArray[np.complex128]
    da: NDArray[np.complex128] | None = None
    db0: NDArray[np.complex128] | None = None
    dr: NDArray[np.complex128] | None = None

    def k_at_delay(self, delta: float) -> NDArray[np.complex128]:
        """The complex ``K`` with ``A + (B_0 + K R) e^{-i w delta} = 0``: a crossing where it is real."""
        return -(self.a * np.exp(1j * self.w * delta) + self.b0) / self.r

    def branches(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """``(D, m, sqrt D)``: ``|A|^2 = |B_0 + K R|^2`` at ``K = m +- sqrt D`` (``D >= 0``).

        With ``u = B_0/R``: ``g = |R|^2 (|A|^2/|R|^2 - (K + Re u)^2 - (Im u)^2)``, quadratic in
        ``K``; ``m = -Re u`` and ``D = |A|^2/|R|^2 - (Im u)^2``.
        """
        u = self.b0 / self.r
        D = np.abs(self.a) ** 2 / np.abs(self.r) ** 2 - u.imag**2
        return D, -u.real, np.sqrt(np.maximum(D, 0.0))

    def branch_slopes(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(m', D')``, so that ``dK/dw = m' +- D' / (2 sqrt D)`` on the branches."""
        assert self.da is not None and self.db0 is not None and self.dr is not None
        u = self.b0 / self.r
        du = (self.db0 * self.r - self.b0 * self.dr) / self.r**2
        r2 = np.abs(self.r) ** 2
        da2 = 2.0 * (np.conj(self.a) * self.da).real
        dr2 = 2.0 * (np.conj(self.r) * self.dr).real
        return -du.real, (da2 * r2 - np.abs(self.a) ** 2 * dr2) / r2**2 - 2.0 * u.imag * du.imag

    def delays(self, K: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """Smallest ``delta >= 0`` with ``i w`` a root of the loop with gain ``K`` (where ``|A| = |B|``)."""
        return np.mod(np.angle(-(self.b0 + K * self.r) / self.a), 2.0 * np.pi) / self.w


@dataclass(frozen=True)
class _AffineLoop:
    """``F(s; delta, K) = A(s) + (B_0(s) + K R(s)) e^{-delta s}``: ``U_BS2(K)``'s loop, affine in ``K``.

    From :func:`loop_factors`: ``A = 1 - Phi``, ``B = K q e^{-tau s} - I_N``, so
    ``B_0 = -I_N`` (the factor at ``K = 0``) and ``R = q e^{-tau s}`` (its change per unit gain).
    """

    A: QuasiPolynomial
    B0: QuasiPolynomial
    R: QuasiPolynomial
    #: ``A + B_0``: the distributed parts cancel (``I_N - I_N``), so ``A(i w)`` costs one
    #: evaluation of ``B_0`` (``A = S - B_0``).
    S: QuasiPolynomial = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "S", self.A + self.B0)

    @classmethod
    def of(cls, system: Hyperbolic2x2) -> _AffineLoop:
        """The loop of ``U_BS2(K)`` on ``system`` (``R`` checked to be the gain's factor)."""
        A, B0 = loop_factors(system, ReflectionController(0.0))
        A1, B1 = loop_factors(system, ReflectionController(1.0))
        R = B1 - B0
        if A1 != A or R.distributed or R != QuasiPolynomial([[system.q]], [system.tau]):
            raise CertificationError("k_region: the U_BS2(K) loop is not A + (B_0 + K q e^{-tau s}) e^{-delta s}")
        return cls(A, B0, R)

    def axis(self, w: NDArray[np.float64], slopes: bool = False) -> _Axis:
        s = 1j * np.asarray(w, dtype=float)
        b0 = self.B0(s)
        if not slopes:
            return _Axis(s.imag, self.S(s) - b0, b0, self.R(s))
        db0 = 1j * self.B0.deriv_at(s)
        return _Axis(s.imag, self.S(s) - b0, b0, self.R(s), 1j * self.S.deriv_at(s) - db0, db0, 1j * self.R.deriv_at(s))

    def B(self, K: float) -> QuasiPolynomial:
        return self.B0 + self.R * K

    def loop_at(self, K: float, delta: float) -> QuasiPolynomial:
        """``F(.; delta, K)``."""
        B = self.B(K)
        return self.A + (B.shift(delta) if delta > 0 else B)


@dataclass(frozen=True)
class _AxisBound:
    """Second-order bound of the crossing frequencies of ``U_BS2(K)``'s loop (none above :meth:`W`).

    For ``S = 1 - rho q z``, ``R = q z`` (``z = e^{-tau s}``) and ``B_0 = J = int_0^tau n(nu)
    e^{-nu s} dnu`` with ``n`` continuous and ``n'`` of bounded variation (the paper's plants),
    ``A = S - J`` and ``B = K R + J``, so that on ``s = i w`` (``|J|^2`` cancels)

        g = |A|^2 - |B|^2 = |S|^2 - K^2 q^2 - 2 Re(conj(T) J),   T = S + K R = 1 - c z,  c = (rho - K) q.

    Integration by parts twice gives ``J = (n(0) - n(tau) z)/(i w) + E`` with
    ``|E| <= V_2 / w^2``, ``V_2 = |n'(0)| + |n'(tau)| + TV(n')``. With ``z = e^{-i theta}``,
    ``Re(conj(T) (n(0) - n(tau) z)/(i w)) = (n(tau) - c n(0)) sin(theta) / w``, and with
    ``p = |rho q|``, ``phi = theta`` (``rho q > 0``) or ``theta - pi``, ``x = |sin(phi/2)|``:
    ``|S|^2 = (1 - p)^2 + 4 p x^2`` and ``|sin theta| <= 2 x``. Hence, minimising
    ``4 p x^2 - 4 beta x / w`` over ``x``,

        g >= (1 - p)^2 - K^2 q^2 - C_2 / w^2,   C_2 = beta^2 / p + 2 (1 + |c|) V_2,  beta = |n(tau) - c n(0)|,

    and there is no crossing above ``W_2 = sqrt(C_2 / (q^2 (k^2 - K^2)))``, ``k = (1 - p)/|q|``.
    The first-order bound (:func:`nrobust.crossings.frequency_bound`) grows like
    ``1/(k - |K|)``; this one like ``1/sqrt(k - |K|)`` (``lam = 2, mu = 0.5, sigma = (0.3, -0.4),
    q = 0.7, rho = 0.9`` at ``k - |K| = 1.7e-5``: ``W_2 = 190`` instead of ``7.3e4``).
    """

    rho_q: float
    q: float
    n0: float
    n_tau: float
    v2: float

    @classmethod
    def of(cls, loop: _AffineLoop) -> _AxisBound | None:
        """The bound of ``loop``, or None if it is not of the form above."""
        S, B0, R = loop.S, loop.B0, loop.R
        if len(R.point_terms) != 1 or R.distributed or not R.is_real:
            return None
        (r, tau), terms = R.point_terms[0], dict((t, p) for p, t in S.point_terms)
        if r.size != 1 or set(terms) != {0.0, tau} or S.distributed or not S.is_real:
            return None
        if terms[0.0].size != 1 or terms[0.0][0] != 1.0 or terms[tau].size != 1 or terms[tau][0] == 0.0:
            return None
        if B0.point_terms or len(B0.distributed) != 1:
            return None
        d = B0.distributed[0]
        if d.a != 0.0 or d.b != tau or d.moment != 0 or d.poly.size != 1 or np.iscomplexobj(d.values):
            return None
        start, h, poly = d._pieces
        n = float(d.poly[0]) * np.asarray(poly, dtype=float)
        j = np.arange(n.shape[1])
        value_end, slope_start, slope_end = n.sum(axis=1), n[:, 1] / h, (n * j).sum(axis=1) / h
        scale = float(np.max(np.abs(n[:, 0]))) + 1e-300
        contiguous = np.abs(start[1:] - (start[:-1] + h[:-1])) <= 1e-12 * tau
        if not np.all(contiguous) or np.any(np.abs(n[1:, 0] - value_end[:-1]) > 1e-12 * scale):
            return None  # a gap or a jump of n: the first-order bound applies
        # TV of n' on each segment: int |n''| = (1/h) int_0^1 |2 P_2 + 6 P_3 t| dt (cubic; 0 when linear)
        a2 = 2.0 * n[:, 2] if n.shape[1] > 2 else np.zeros(h.size)
        a3 = 6.0 * n[:, 3] if n.shape[1] > 3 else np.zeros(h.size)
        lo, hi = a2, a2 + a3
        crossing = lo * hi < 0
        inside = np.where(crossing, (lo**2 + hi**2) / (2.0 * np.abs(np.where(crossing, a3, 1.0))), np.abs(lo + hi) / 2)
        v2 = (
            abs(slope_start[0])
            + abs(slope_end[-1])
            + float(np.sum(inside / h))
            + float(np.sum(np.abs(slope_start[1:] - slope_end[:-1])))
        )
        # the bound carries its own rounding: V_2 a little larger (its sums err by ~ n_segments eps)
        v2 = v2 * (1.0 + 1e-9) + 1e-300
        return cls(-float(terms[tau][0]), float(r[0]), float(n[0, 0]), float(value_end[-1]), v2)

    def W(self, K_lo: float, K_hi: float) -> float:
        """A frequency above every crossing of every gain in ``[K_lo, K_hi]`` (``inf`` if one has ``|K| >= k``).

        ``C_2`` is convex in ``K`` and ``1/(k^2 - K^2)`` too: both are largest at an end.
        """
        p, q = abs(self.rho_q), abs(self.q)
        if p == 0.0:
            return float("inf")
        c2 = 0.0
        room = float("inf")
        for K in (K_lo, K_hi):
            c = self.rho_q - K * self.q
            beta = abs(self.n_tau - c * self.n0)
            c2 = max(c2, beta**2 / p + 2.0 * (1.0 + abs(c)) * self.v2)
            # q^2 (k^2 - K^2) = ((1 - p) - |K q|)((1 - p) + |K q|), the first factor less its rounding
            gap = (1.0 - p) - abs(K) * q - 8.0 * _EPS * (1.0 + p + abs(K) * q)
            room = min(room, gap * ((1.0 - p) + abs(K) * q))
        if room <= 0.0:
            return float("inf")
        return float(np.sqrt(c2 * (1.0 + 1e-9) / room) * (1.0 + 1e-9))


def _junction(at: _Axis) -> NDArray[np.float64]:
    """``D``: zero where the two branches ``K_pm`` meet."""
    return at.branches()[0]


def _branch_slope(at: _Axis, sign: float) -> NDArray[np.float64]:
    """``dK/dw`` on the branch ``K = m + sign sqrt(D)`` (zero at a pair birth)."""
    mx, Dx = at.branch_slopes()
    return mx + sign * Dx / (2.0 * np.maximum(at.branches()[2], 1e-300))


def _solve(
    f: Callable[[NDArray[np.float64], NDArray[np.intp]], NDArray[np.float64]],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    flo: NDArray[np.float64],
    fhi: NDArray[np.float64],
    rtol: float = _W_RTOL,
) -> NDArray[np.float64]:
    """Zeros of ``f`` in the brackets ``[lo, hi]`` (``f(lo) f(hi) <= 0``), all brackets at once.

    ``f(x, k)`` evaluates at the points ``x`` of the brackets ``k``. Illinois steps (regula
    falsi halving the value kept twice), a bisection every fourth step; each bracket stops
    at the relative width ``rtol``.
    """
    lo, hi, flo, fhi = (np.array(v, dtype=float) for v in (lo, hi, flo, fhi))
    out = np.where(flo == 0, lo, np.where(fhi == 0, hi, np.nan))
    side = np.zeros(lo.size, dtype=int)
    for it in range(_MAX_SOLVE):
        active = np.flatnonzero(np.isnan(out) & (hi - lo > rtol * np.maximum(np.abs(lo), np.abs(hi))))
        if not active.size:
            break
        a, b, fa, fb = lo[active], hi[active], flo[active], fhi[active]
        with np.errstate(divide="ignore", invalid="ignore"):
            x = (a * fb - b * fa) / (fb - fa)
        bisect = ~np.isfinite(x) | (x <= a) | (x >= b) | (it % 4 == 3)
        x[bisect] = 0.5 * (a + b)[bisect]
        fx = f(x, active)
        out[active[fx == 0]] = x[fx == 0]
        left = fx * fa < 0
        right = ~left & (fx != 0)
        i, j = active[left], active[right]
        hi[i], fhi[i] = x[left], fx[left]
        flo[i] = np.where(side[i] == 1, 0.5 * flo[i], flo[i])
        side[i] = 1
        lo[j], flo[j] = x[right], fx[right]
        fhi[j] = np.where(side[j] == -1, 0.5 * fhi[j], fhi[j])
        side[j] = -1
    return np.where(np.isnan(out), 0.5 * (lo + hi), out)


def _sign_changes(f: NDArray[np.float64], valid: NDArray[np.bool_] | None = None) -> NDArray[np.intp]:
    """Indices ``j`` where ``f`` changes sign on ``[j, j + 1]`` (both samples valid)."""
    change = (np.sign(f[:-1]) * np.sign(f[1:]) < 0) | ((f[:-1] == 0) & (f[1:] != 0))
    if valid is not None:
        change &= valid[:-1] & valid[1:]
    return np.flatnonzero(change)


def _sixth_derivative_bound(P: QuasiPolynomial) -> float:
    """Bound of ``|d^6 P(i w) / dw^6|`` over real ``w`` (``inf`` if a term has a polynomial factor)."""
    if any(p.size > 1 for p, _ in P.point_terms) or any(d.poly.size > 1 for d in P.distributed):
        return float("inf")
    total = sum(float(np.abs(p[0])) * t**6 for p, t in P.point_terms)
    return total + sum(float(np.abs(d.poly[0]) * d.abs_moment(0.0, 6)) for d in P.distributed)


class _AxisGrid:
    """``S = A + B_0``, ``B_0``, ``R`` and two ``w``-derivatives at ``w_k = k dw``, with interpolants.

    Off a uniform grid each evaluation of the kernel ``I_N`` costs ``O(nodes)``; on it one
    chirp-z transform gives every sample. Between samples, quintic Hermite interpolants
    (:meth:`model`) stand for the loop, with an error below :attr:`error` (``dw^6 / 46080``
    times the sixth derivatives); they locate every root of the scan, and only those that
    decide the region are solved again on the loop itself (:meth:`_Scan._exact`). The grid
    grows with :meth:`extend` and keeps its samples.
    """

    def __init__(self, loop: _AffineLoop, dw: float) -> None:
        self.loop, self.dw = loop, dw
        self.w = np.zeros(0)
        self.parts: tuple[NDArray[np.complex128], ...] = tuple(np.zeros(0, dtype=complex) for _ in range(9))
        self._first = tuple(P.derivative() for P in (loop.S, loop.B0, loop.R))
        self.roots: dict[tuple, NDArray[np.float64]] = {}  # the scans' roots of the interpolants
        sixth = sum(_sixth_derivative_bound(P) for P in (loop.S, loop.B0, loop.B0, loop.R))
        #: Bound of the interpolation error of ``|A| + |B_0| + |R|`` between samples.
        self.error = float(sixth * dw**6 / 46080.0)

    def extend(self, W: float) -> None:
        """Samples up to ``W`` (at least 16)."""
        n = max(int(np.ceil(W / self.dw)), 16)
        if n <= self.w.size:
            return
        s = 1j * self.dw * np.arange(self.w.size + 1, n + 1)
        new = []
        for P, P1 in zip((self.loop.S, self.loop.B0, self.loop.R), self._first):
            new += [P(s), 1j * P1(s), -P1.deriv_at(s)]  # P(i w) and its first two w-derivatives
        self.parts = tuple(np.concatenate([old, part]) for old, part in zip(self.parts, new))
        self.w = np.concatenate([self.w, s.imag])

    def samples(self, n: int) -> _Axis:
        """The loop at the first ``n`` samples, with slopes."""
        S, dS, _, B0, dB0, _, R, dR, _ = (p[:n] for p in self.parts)
        return _Axis(self.w[:n], S - B0, B0, R, dS - dB0, dB0, dR)

    def model(self, j: NDArray[np.intp], x: NDArray[np.float64], slopes: bool = False) -> _Axis:
        """The interpolated loop at ``x`` in ``[w_j, w_{j+1}]``."""
        h, t = self.dw, (x - self.w[j]) / self.dw
        t2, t3, t4, t5 = t**2, t**3, t**4, t**5
        basis = (
            1 - 10 * t3 + 15 * t4 - 6 * t5,
            (t - 6 * t3 + 8 * t4 - 3 * t5) * h,
            (t2 - 3 * t3 + 3 * t4 - t5) * h**2 / 2,
            10 * t3 - 15 * t4 + 6 * t5,
            (-4 * t3 + 7 * t4 - 3 * t5) * h,
            (t3 - 2 * t4 + t5) * h**2 / 2,
        )

        def interp(f: NDArray, df: NDArray, ddf: NDArray, b: tuple) -> NDArray[np.complex128]:
            return b[0] * f[j] + b[1] * df[j] + b[2] * ddf[j] + b[3] * f[j + 1] + b[4] * df[j + 1] + b[5] * ddf[j + 1]

        S, dS, ddS, B0, dB0, ddB0, R, dR, ddR = self.parts
        s, b0, r = interp(S, dS, ddS, basis), interp(B0, dB0, ddB0, basis), interp(R, dR, ddR, basis)
        if not slopes:
            return _Axis(x, s - b0, b0, r)
        slope = (
            (-30 * t2 + 60 * t3 - 30 * t4) / h,
            1 - 18 * t2 + 32 * t3 - 15 * t4,
            (2 * t - 9 * t2 + 12 * t3 - 5 * t4) * h / 2,
            (30 * t2 - 60 * t3 + 30 * t4) / h,
            -12 * t2 + 28 * t3 - 15 * t4,
            (3 * t2 - 8 * t3 + 5 * t4) * h / 2,
        )
        ds, db0 = interp(S, dS, ddS, slope), interp(B0, dB0, ddB0, slope)
        return _Axis(x, s - b0, b0, r, ds - db0, db0, interp(R, dR, ddR, slope))


class _Scan:
    """The loop on ``0 < w <= W``: its critical gains and crossing curves ``K_pm(w)``.

    The verdict "stable for every delay in ``[0, delta_max]``" can change with ``K`` only
    at a *critical gain*: a root on the axis at ``delta = delta_max`` (``Im K_delta(w) = 0``),
    at ``delta = 0`` (the same with ``delta = 0``; ``w = 0`` included), or a pair birth with
    delay ``<= delta_max`` (an extremum in ``w`` of a root ``K_pm(w)`` of ``g``). Gains whose
    crossing frequencies all lie in ``(0, W]`` (every ``|K|`` whose frequency bound is ``<= W``)
    have all their critical gains found, up to the sampling step ``dw``. Every root is first
    located on the interpolants of :class:`_AxisGrid`; critical gains in ``window`` are then
    solved on the loop to ``_W_RTOL`` in ``w``, the others only keep an estimate
    (:attr:`beyond`), to choose the next window.
    """

    def __init__(self, grid: _AxisGrid, delta_max: float, kb: float, W: float, window: tuple[float, float]) -> None:
        loop = grid.loop
        self.loop, self.grid, self.delta_max = loop, grid, delta_max
        lo_w, hi_w = window
        grid.extend(W)
        n = max(int(np.ceil(W / grid.dw)), 16)
        ax = grid.samples(n)
        w = ax.w
        # what the interpolants may be off by: in K (|R| = |q| for U_BS2) and in the phase of B/A
        r_min = float(np.min(np.abs(ax.r)))
        self.margin = margin = _MODEL_SAFETY * grid.error / r_min + 1e-12 * kb
        self.phase_margin = _MODEL_SAFETY * grid.error / max(float(np.min(np.abs(ax.a))), 1e-300)
        crit: list[GainEnd] = []
        self.beyond: list[float] = []  # estimates of the critical gains outside the window

        def keep(K: float, kind: str, x: float, delta: float) -> None:
            if lo_w <= K <= hi_w:
                crit.append(GainEnd(float(K), kind, float(x), float(delta)))
            elif -kb < K < kb:
                self.beyond.append(float(K))

        def sort_out(K_model: NDArray[np.float64]) -> NDArray[np.bool_]:
            """Mask of the model's critical gains to solve on the loop; the rest go to ``beyond``."""
            near = (K_model >= lo_w - margin) & (K_model <= hi_w + margin)
            self.beyond.extend(K_model[~near & (np.abs(K_model) < kb)].tolist())
            return near

        # (a) and (c): a root on the axis at delta = delta_max or 0, Im K_delta(w) = 0
        for delta, event in ((delta_max, "crossing"), (0.0, "nominal")):

            def imag_k(at: _Axis, delta: float = delta) -> NDArray[np.float64]:
                return at.k_at_delay(delta).imag

            j = _sign_changes(ax.k_at_delay(delta).imag)
            xm = self._model_roots(imag_k, j, ("delay", delta))
            near = sort_out(grid.model(j, xm).k_at_delay(delta).real)
            xs = self._exact(imag_k, j[near], xm[near])
            for K, x in zip(loop.axis(xs).k_at_delay(delta).real, xs):
                keep(K, event, x, delta)
        s0 = np.array([0j])
        K0 = -complex(loop.S(s0)[0]) / complex(loop.R(s0)[0])  # s = 0 is a root for every delay
        if abs(K0.imag) <= 1e-12 * max(abs(K0), 1.0):
            keep(K0.real, "nominal", 0.0, 0.0)
        # (b): the branches K_pm(w) of |A| = |B|, their extrema (pair births) and junctions (D = 0)
        D, m, root = ax.branches()
        dm, dD = ax.branch_slopes()
        valid = D > 0
        jj = _sign_changes(D)
        xj = self._model_roots(_junction, jj, ("junction",))
        Kj = grid.model(jj, xj).branches()[1]
        self.nodes: list[tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.intp], NDArray[np.int_]]] = []
        for sign in (1.0, -1.0):
            Kb = np.where(valid, m + sign * root, np.nan)
            slope = np.where(valid, dm + sign * dD / (2.0 * np.where(valid, root, 1.0)), 0.0)
            je = _sign_changes(slope, valid)

            def dK(at: _Axis, sign: float = sign) -> NDArray[np.float64]:
                return _branch_slope(at, sign)

            xe = self._model_roots(dK, je, ("extremum", sign), slopes=True)
            at = grid.model(je, xe)
            Ke = at.branches()[1] + sign * at.branches()[2]
            births = at.delays(Ke) <= delta_max + self.phase_margin / np.maximum(xe, 1e-300)
            near = births & sort_out(np.where(births, Ke, np.inf))
            xs = self._exact(dK, je[near], xe[near], slopes=True)
            at = loop.axis(xs)
            _, mx, rx = at.branches()
            for K, x, d in zip(mx + sign * rx, xs, at.delays(mx + sign * rx)):
                if d <= delta_max:
                    keep(K, "pair_birth", x, d)
            # nodes of the branch: samples (exact), extrema and junctions (interpolated), with their cells
            nw = np.concatenate([w, xe, xj])
            order = np.argsort(nw, kind="stable")
            cell = np.concatenate([np.arange(n), je, jj])
            kind = np.concatenate([np.zeros(n, dtype=int), np.ones(xe.size, dtype=int), np.full(xj.size, 2)])
            self.nodes.append((nw[order], np.concatenate([Kb, Ke, Kj])[order], cell[order], kind[order]))
        self.critical = sorted(crit, key=lambda e: (e.K, _KIND_ORDER[e.kind]))

    def _model_roots(
        self, f: Callable[[_Axis], NDArray[np.float64]], j: NDArray[np.intp], key: tuple, slopes: bool = False
    ) -> NDArray[np.float64]:
        """Zeros of ``f`` of the interpolated loop in the cells ``[w_j, w_{j+1}]`` (a sign change each).

        Kept by the grid under ``key`` and the cells: a later window on the same grid reuses them.
        """
        memo = (key, j.tobytes())
        if memo not in self.grid.roots:
            w, model = self.grid.w, self.grid.model
            f_lo, f_hi = f(model(j, w[j], slopes)), f(model(j, w[j + 1], slopes))
            self.grid.roots[memo] = _solve(
                lambda x, k: f(model(j[k], x, slopes)), w[j], w[j + 1], f_lo, f_hi, _MODEL_RTOL
            )
        return self.grid.roots[memo]

    def _exact(
        self,
        f: Callable[[_Axis], NDArray[np.float64]],
        j: NDArray[np.intp],
        x0: NDArray[np.float64],
        slopes: bool = False,
    ) -> NDArray[np.float64]:
        """Zeros of ``f`` of the loop itself near the model's ``x0`` (in the cells ``j``)."""
        if not j.size:
            return x0
        loop, w = self.loop, self.grid.w
        half = _BRACKET_CELLS * self.grid.dw
        lo, hi = np.maximum(x0 - half, w[j]), np.minimum(x0 + half, w[j + 1])
        f_lo, f_hi = f(loop.axis(lo, slopes)), f(loop.axis(hi, slopes))
        wide = np.sign(f_lo) * np.sign(f_hi) > 0  # the model's root is too far off: the whole cell
        if wide.any():
            lo[wide], hi[wide] = w[j[wide]], w[j[wide] + 1]
            f_lo[wide], f_hi[wide] = f(loop.axis(lo[wide], slopes)), f(loop.axis(hi[wide], slopes))
        return _solve(lambda x, k: f(loop.axis(x, slopes)), lo, hi, f_lo, f_hi)

    def crossings(self, K: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Crossing frequencies of the loop with gain ``K`` in ``(0, W]`` and their smallest delays.

        From the interpolated loop, except where its error matters: an extremum or junction
        of a branch within :attr:`margin` of ``K`` is solved again on the loop, and so are the
        crossings next to it, and every crossing whose delay is closer to ``delta_max`` than
        the interpolants' error allows.
        """
        loop, model = self.loop, self.grid.model
        ws, ds = [], []
        for sign, (nw, nK, cell, kind) in zip((1.0, -1.0), self.nodes):
            doubt = (kind > 0) & (np.abs(nK - K) <= self.margin)
            if doubt.any():

                def slope_of(at: _Axis, sign: float = sign) -> NDArray[np.float64]:
                    return _branch_slope(at, sign)

                nw, nK = nw.copy(), nK.copy()
                ext, jun = np.flatnonzero(doubt & (kind == 1)), np.flatnonzero(doubt & (kind == 2))
                nw[ext] = self._exact(slope_of, cell[ext], nw[ext], slopes=True)
                nw[jun] = self._exact(_junction, cell[jun], nw[jun])
                _, mx, rx = loop.axis(nw[doubt]).branches()
                nK[doubt] = mx + np.where(kind[doubt] == 1, sign * rx, 0.0)
            f = nK - K
            i = _sign_changes(f, np.isfinite(f))
            j = cell[i]

            def on_branch(at: _Axis, sign: float = sign) -> NDArray[np.float64]:
                _, mx, rx = at.branches()
                return mx + sign * rx - K

            def interpolated(x: NDArray[np.float64], k: NDArray[np.intp], j: NDArray[np.intp] = j) -> NDArray:
                return on_branch(model(j[k], x))

            x = _solve(interpolated, nw[i], nw[i + 1], f[i], f[i + 1], _MODEL_RTOL)
            exact = doubt[i] | doubt[i + 1]
            if exact.any():
                e = np.flatnonzero(exact)
                x[e] = _solve(lambda x, k: on_branch(loop.axis(x)), nw[i[e]], nw[i[e] + 1], f[i[e]], f[i[e] + 1])
            d = np.where(exact, 0.0, model(j, x).delays(K))
            close = exact | (np.abs(d - self.delta_max) * x <= self.phase_margin)
            if close.any():
                x[close & ~exact] = self._exact(on_branch, j[close & ~exact], x[close & ~exact])
                d[close] = loop.axis(x[close]).delays(K)
            ws.append(x)
            ds.append(d)
        return np.concatenate(ws), np.concatenate(ds)


def _nominally_stable(loop: _AffineLoop, K: float) -> bool:
    """Certified: ``F(.; 0, K)`` has no zero with ``Re s >= 0``.

    For ``U_BS2(K)`` the kernels cancel at ``delta = 0``: ``F = 1 - (rho - K) q e^{-tau s}``, whose
    zeros lie on ``Re s = ln|(rho - K) q| / tau`` (closed form, eq. (60) with
    ``delta = 0``). Otherwise a certified count in the root-free radius, its left edge on the axis
    or to its left.
    """
    F = loop.S + loop.R * K  # = A + B_0 + K R = F(.; 0, K)
    terms = F.point_terms
    if not F.distributed and len(terms) <= 2 and terms[0][1] == 0.0 and all(p.size == 1 for p, _ in terms):
        return len(terms) == 1 or abs(terms[1][0][0]) < abs(terms[0][0][0])  # c_0 + c_1 e^{-t s}
    r = 1.01 * root_free_region(F).radius + 1e-9
    count = count_roots(F, (0.0, r, -r, r))
    return int(count) == 0 and count.region[0] <= 0.0


def _scan_step(loop: _AffineLoop, delta_max: float) -> float:
    """``pi / (_SCAN_STEPS T)`` rounded down to a power of two.

    A power of two makes every sample ``k dw`` exact, so that each extension of the grid
    is recognised as a uniform line (chirp-z) by :meth:`QuasiPolynomial.__call__`.
    """
    T = 2.0 * max(loop.A.max_delay, loop.B0.max_delay, loop.R.max_delay) + delta_max
    return float(2.0 ** np.floor(np.log2(np.pi / (_SCAN_STEPS * max(T, 1e-3)))))


def _locate_ends(loop: _AffineLoop, delta_max: float, kb: float, tol: float, max_evals: int) -> list[tuple]:
    """The admissible intervals of ``(-kb, kb)`` as pairs of :class:`GainEnd`, located by their equations.

    A scan of the axis up to the frequency bound of the largest gain considered (the
    *cap*) finds the critical gains; the verdict is constant between two of them and is
    taken at their midpoint (crossings of :meth:`_Scan.crossings` with a delay
    ``<= delta_max``; nominal stability counted once between two nominal critical gains).
    While an admissible interval reaches a cap, the cap moves towards ``kb``; an interval
    still admissible within ``tol`` of ``kb`` ends at the strong-stability limit.
    """
    dw = _scan_step(loop, delta_max)
    grid = _AxisGrid(loop, dw)
    second = _AxisBound.of(loop)

    def crossing_bound(lo: float, hi: float) -> float:
        """Above every crossing frequency of the gains in ``[lo, hi]`` (``lo <= 0 <= hi``; 0: none):
        :class:`_AxisBound`'s, else the first-order bound of the largest ``|K|``."""
        if second is not None:
            return second.W(lo, hi)
        first = [frequency_bound(loop.A, loop.B(c)) for c in (lo, hi)]
        return max(0.0 if b is None else b[0] for b in first)

    caps = [-kb * (1.0 - _FIRST_CAP), kb * (1.0 - _FIRST_CAP)]
    open_end = [False, False]
    nominal: dict[tuple[float | None, float | None], bool] = {}
    # verdicts between two critical gains (not caps): a later, wider scan finds the same crossings there
    between: dict[tuple[float, float], bool] = {}
    while True:
        Ws = [crossing_bound(min(c, 0.0), max(c, 0.0)) for c in caps]
        W = max(Ws)
        if W / dw > max_evals / 6:
            far = " and ".join(f"K = {c:.10g}" for c, Wc in zip(caps, Ws) if Wc / dw > max_evals / 6)
            raise CertificationError(
                f"k_region: an admissible interval reaches {far}, {kb - max(abs(c) for c in caps):.3g} from the "
                f"strong-stability limit {kb:.10g}, where crossing frequencies extend to W = {W:.6g}: locating "
                f"its end needs about {6 * W / dw:.3g} evaluations, beyond the work bound max_evals={max_evals}"
            )
        scan = _Scan(grid, delta_max, kb, W, (caps[0], caps[1]))
        inside = [c for c in scan.critical if caps[0] < c.K < caps[1]]
        cuts = [caps[0], *[c.K for c in inside], caps[1]]
        nominal_cuts = [c.K for c in inside if c.kind == "nominal"]
        ok = []
        for lo, hi in itertools.pairwise(cuts):
            mid = 0.5 * (lo + hi)
            g = sum(1 for x in nominal_cuts if x < mid)
            key = (nominal_cuts[g - 1] if g else None, nominal_cuts[g] if g < len(nominal_cuts) else None)
            if key not in nominal:
                nominal[key] = _nominally_stable(loop, mid)
            if not nominal[key]:
                ok.append(False)
                continue
            if (lo, hi) not in between:
                free = not np.any(scan.crossings(mid)[1] <= delta_max)
                if lo not in caps and hi not in caps:
                    between[(lo, hi)] = free
                ok.append(free)
                continue
            ok.append(between[(lo, hi)])
        moved = False
        for side, sgn in ((1, 1.0), (0, -1.0)):
            if open_end[side] or not ok[-1 if side else 0]:
                continue
            # past the first critical gain seen beyond the cap, but at most _CAP_SHRINK times closer
            # to kb (gains past the cap have crossings above W, not scanned yet); within tol of kb
            # the interval ends at the strong-stability limit
            cap = abs(caps[side])
            past = [sgn * K for K in scan.beyond if cap < sgn * K < kb - tol]
            new = kb - (kb - cap) / _CAP_SHRINK
            if past:
                new = min(new, min(past) + (kb - min(past)) / _CAP_SHRINK)
            new = min(max(new, cap + 0.5 * tol), kb - tol)
            if not past and crossing_bound(min(0.0, sgn * (kb - tol)), max(0.0, sgn * (kb - tol))) <= W:
                # the scan covers every gain up to kb - tol
                new = kb - tol
            if new <= cap:
                open_end[side] = True
                continue
            caps[side] = sgn * new
            moved = True
        if not moved:
            break
    lower = GainEnd(-kb, "strong_stability", float("inf"), 0.0)
    upper = GainEnd(kb, "strong_stability", float("inf"), 0.0)
    ends = [lower, *inside, upper]
    return [(ends[k], ends[k + 1]) for k in range(len(ok)) if ok[k]]


@dataclass(frozen=True, eq=False)
class KRegion:
    """Gains ``K`` for which ``U_BS2(K)`` is exponentially stable for every delay in ``[0, delta_max]``.

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    intervals : tuple of (float, float)
        The admissible gains, as open intervals (``ends`` gives the event at each end).
    delta_max : float
        The delay range that must be tolerated.
    paper_bound : float
        ``(1 - |rho q|)/|q|`` of eq. (54). It is also necessary for a positive margin:
        ``|rho q| + |K q| < 1`` is the strong stability of the loop's difference operator.
    Ks : ndarray
        Gain grid on which the margins were computed.
    margins : ndarray
        ``delta*(K)`` on the grid.
    admissible : ndarray of bool
        ``delta*(K) > delta_max`` and the nominal loop stable, on the grid.
    tol : float
        Accuracy of the interval ends: each end was checked ``tol`` inside (admissible: the
        certified crossing search of :func:`delay_margin`) and ``tol`` outside (not
        admissible: a certified count of a zero in ``Re s > 0``).
    ends : tuple of (GainEnd, GainEnd)
        For each interval, its lower and upper end with their kind (:class:`GainEnd`:
        ``"crossing"``, ``"pair_birth"``, ``"nominal"``, ``"strong_stability"``, or
        ``"bisection"`` for a ``controller`` family other than ``U_BS2(K)``).
    method : str
        ``"equations"`` (ends solved from the equations of their kind) or ``"bisection"``.
    """

    intervals: tuple[tuple[float, float], ...]
    delta_max: float
    paper_bound: float
    Ks: NDArray[np.float64]
    margins: NDArray[np.float64]
    admissible: NDArray[np.bool_]
    tol: float
    ends: tuple[tuple[GainEnd, GainEnd], ...] = ()
    method: str = "bisection"

    def __repr__(self) -> str:
        ivs = ", ".join(f"({lo:.6g}, {hi:.6g})" for lo, hi in self.intervals) or "empty"
        return f"KRegion(delta_max={self.delta_max:.6g}, K in {ivs}, paper bound |K| < {self.paper_bound:.6g})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description; each end as ``{"K", "kind", "omega", "delay"}``."""
        data = fields_dict(self, exclude=("ends",))
        data["ends"] = json_safe([[end._asdict() for end in pair] for pair in self.ends])
        return data


@dataclass(frozen=True)
class _CheckedMargin:
    """Picklable ``K -> delay_margin(system, family(K))``, or the message of its CertificationError."""

    system: Any
    delta_max: float
    family: Callable[[float], Any]
    max_evals: int

    def __call__(self, K: float) -> DelayMargin | str:
        try:
            return delay_margin(
                self.system, self.family(float(K)), delta_max=self.delta_max, verify=False, max_evals=self.max_evals
            )
        except CertificationError as exc:
            return str(exc)


class _Verdict(NamedTuple):
    """What :func:`_loop_verdict` proves of one gain: the fields of :class:`DelayMargin` that
    :func:`k_region` reads."""

    margin: float
    nominally_stable: bool
    strongly_stable: bool
    crossings: tuple[Crossing, ...]


def _loop_verdict(loop: _AffineLoop, K: float, delta_max: float, max_evals: int) -> _Verdict:
    """Delay margin of ``A + (B_0 + K R) e^{-delta s}`` by the certified crossing search of
    :func:`nrobust.delay_margin` on ``[0, W]``, ``W`` the smaller of the first-order frequency
    bound and :class:`_AxisBound`'s (the margin of :func:`delay_margin`, whose search runs up to
    the first-order bound: ``1/(k - |K|)`` instead of ``1/sqrt(k - |K|)`` near the paper's bound).

    Roots reach ``Re s > 0`` only through the axis (the difference operator is strongly stable),
    so the nominal verdict and the crossings decide every delay.
    """
    A, B = loop.A, loop.B(K)
    first = frequency_bound(A, B)
    if first is None:
        return _Verdict(0.0, False, False, ())
    bound = _AxisBound.of(loop)
    W = first[0] if bound is None else min(first[0], bound.W(K, K))
    search, axis_gap = crossing_search(A, B, (W, first[1]), max_evals)
    if common_axis_zeros(axis_gap, search).size:  # a root on the axis for every delay
        return _Verdict(0.0, False, True, ())
    crossings, _ = axis_crossings(A, B, search, delta_max, axis_gap)
    if not _nominally_stable(loop, K):
        return _Verdict(0.0, False, True, crossings)
    return _Verdict(crossings[0].delays[0] if crossings else float("inf"), True, True, crossings)


@dataclass(frozen=True)
class _LoopMargin:
    """Picklable ``K -> _loop_verdict(loop, K)``, or the message of its CertificationError.

    A worker process receives the loop's factors instead of solving the kernels again.
    """

    loop: _AffineLoop
    delta_max: float
    max_evals: int

    def __call__(self, K: float) -> _Verdict | str:
        try:
            return _loop_verdict(self.loop, float(K), self.delta_max, self.max_evals)
        except CertificationError as exc:
            return str(exc)


def _unstable_root_near(loop: _AffineLoop, K: float, delta: float, omega: float) -> str | None:
    """None if a certified count finds a zero of ``F(.; delta, K)`` with ``Re s > 0`` near ``i omega``.

    Newton from ``i omega`` gives the zero ``s*``; :func:`nrobust.roots.count_roots` on the
    square of half-side ``Re s* / 2`` about it must count at least one zero (the square lies
    in ``Re s > 0``). Otherwise the reason, in words.
    """
    F = loop.loop_at(K, delta)
    s = complex(0.0, omega)
    for _ in range(60):
        step = complex(F(np.array([s]))[0] / F.deriv_at(np.array([s]))[0])
        s -= step
        if not np.isfinite(s) or abs(step) <= 4e-16 * max(1.0, abs(s)):
            break
    if not (np.isfinite(s) and s.real > 0):
        return f"no zero in Re s > 0 near i {omega:.10g} at delta = {delta:.10g} (Newton: {s:.6g})"
    h = 0.5 * s.real
    try:
        count = count_roots(F, (s.real - h, s.real + h, s.imag - h, s.imag + h))
    except CertificationError as exc:
        return f"the count about {s:.12g} failed ({exc})"
    if int(count) < 1 or count.region[0] <= 0.0:
        return f"count_roots finds {int(count)} zeros in {count.region} about {s:.12g}"
    return None


def _check_end(end: GainEnd, inner: _Verdict | str, K_out: float, loop: _AffineLoop, delta_max: float) -> str | None:
    """None if ``end`` is confirmed on both sides, else why not.

    Inside, the verdict (:func:`_loop_verdict`) must be admissible. Outside, a certified count
    proves a zero in ``Re s > 0`` at some delay in ``[0, delta_max]`` (:func:`_unstable_root_near`):
    at ``delta = 0`` next to a nominal end, at ``delta_max`` next to a crossing, at the birth delay
    next to a pair birth (between the delays of the newborn pair, ``O(sqrt(tol))`` apart);
    beyond the strong-stability limit the difference operator is not strongly stable (margin 0).
    """
    if isinstance(inner, str):
        return f"the delay margin inside failed ({inner})"
    if not _tolerates(inner, delta_max):
        return f"inside, the margin is {inner.margin:.12g} (nominally stable: {inner.nominally_stable})"
    if end.kind == "strong_stability":
        strong = frequency_bound(loop.A, loop.B(K_out)) is not None
        return "outside, the difference operator is still strongly stable" if strong else None
    delay = {"nominal": 0.0, "crossing": delta_max, "pair_birth": end.delay}[end.kind]
    return _unstable_root_near(loop, K_out, delay, end.omega)


def _grid_verdicts(
    delta_max: float, grid: NDArray, margins: list[DelayMargin | str] | list[_Verdict | str]
) -> tuple[NDArray, NDArray]:
    """Margins and verdicts of the grid gains (a failed margin raises, naming the gain)."""
    for K, dm in zip(grid, margins):
        if isinstance(dm, str):
            raise CertificationError(f"k_region: the delay margin at the grid gain K = {K:.12g} failed: {dm}")
    checked = [dm for dm in margins if not isinstance(dm, str)]
    return np.array([dm.margin for dm in checked]), np.array([_tolerates(dm, delta_max) for dm in checked])


def _exact_region(
    system: Hyperbolic2x2,
    delta_max: float,
    kb: float,
    grid: NDArray,
    tol: float,
    executor: Any,
    max_evals: int,
    progress: bool | None,
) -> KRegion:
    """:func:`k_region` of ``U_BS2(K)``: ends from their equations, each checked."""
    loop = _AffineLoop.of(system)
    pairs = _locate_ends(loop, delta_max, kb, tol, max_evals) if kb > 0 else []
    probes: list[float] = []
    for lo, hi in pairs:
        probes += [lo.K + tol, hi.K - tol]
    run = _mapper(executor, progress, "k_region: delay margins")
    results = list(run(_LoopMargin(loop, delta_max, max_evals), [*grid, *probes]))
    margins, ok = _grid_verdicts(delta_max, grid, results[: grid.size])
    checks = iter(results[grid.size :])
    for lo, hi in pairs:
        for end, sign in ((lo, 1.0), (hi, -1.0)):
            why = _check_end(end, next(checks), end.K - sign * tol, loop, delta_max)
            if why is not None:
                raise CertificationError(
                    f"k_region: the end K = {end.K:.15g} ({end.kind}, w = {end.omega:.10g}) of the admissible "
                    f"interval ({lo.K:.12g}, {hi.K:.12g}) could not be verified on the bracket "
                    f"[{min(end.K - tol, end.K + tol):.15g}, {max(end.K - tol, end.K + tol):.15g}]: {why}"
                )
    intervals = tuple((float(lo.K), float(hi.K)) for lo, hi in pairs)
    for K, good in zip(grid, ok):
        near_end = any(min(abs(K - lo), abs(K - hi)) <= 2.0 * tol for lo, hi in intervals)
        inside = any(lo < K < hi for lo, hi in intervals)
        if not near_end and inside != bool(good):
            raise CertificationError(
                f"k_region: at the grid gain K = {K:.12g} the delay margin says {'' if good else 'not '}admissible, "
                f"the located intervals {intervals} say the opposite"
            )
    return KRegion(intervals, delta_max, kb, grid, margins, ok, tol, tuple(pairs), "equations")


def _bisection_region(
    system: Any,
    delta_max: float,
    kb: float,
    grid: NDArray,
    tol: float,
    family: Callable[[float], Any],
    executor: Any,
    max_evals: int,
    progress: bool | None,
) -> KRegion:
    """:func:`k_region` of another ``controller`` family: the grid's changes of verdict bisected to ``tol``."""
    margin_at = _CheckedMargin(system, delta_max, family, max_evals)
    at_grid = list(_mapper(executor, progress, "k_region: grid margins")(margin_at, grid))
    margins, ok = _grid_verdicts(delta_max, grid, at_grid)

    def checked(K: float) -> DelayMargin:
        dm = margin_at(K)
        if isinstance(dm, str):
            raise CertificationError(f"k_region: the delay margin at K = {K:.12g} failed while bisecting: {dm}")
        return dm

    def edge(good: float, bad: float, outer: DelayMargin | str | None) -> GainEnd:
        while abs(good - bad) > tol:
            mid = 0.5 * (good + bad)
            dm = checked(mid)
            if _tolerates(dm, delta_max):
                good = mid
            else:
                bad, outer = mid, dm
        outer = checked(bad) if not isinstance(outer, DelayMargin) else outer
        first = outer.crossings[0] if outer.crossings else None
        omega = float("inf") if first is None else abs(first.omega)
        delay = float(outer.margin) if first is None else float(first.delays[0])
        return GainEnd(float(good), "bisection", omega, delay)

    ends: list[tuple[GainEnd, GainEnd]] = []
    k = 0
    while k < grid.size:
        if not ok[k]:
            k += 1
            continue
        j = k
        while j + 1 < grid.size and ok[j + 1]:
            j += 1
        lo_bad, lo_outer = (grid[k - 1], at_grid[k - 1]) if k > 0 else (-kb, None)
        hi_bad, hi_outer = (grid[j + 1], at_grid[j + 1]) if j + 1 < grid.size else (kb, None)
        lo = (
            edge(grid[k], lo_bad, lo_outer)
            if lo_bad < grid[k]
            else GainEnd(float(grid[k]), "bisection", float("inf"), 0.0)
        )
        hi = (
            edge(grid[j], hi_bad, hi_outer)
            if hi_bad > grid[j]
            else GainEnd(float(grid[j]), "bisection", float("inf"), 0.0)
        )
        ends.append((lo, hi))
        k = j + 1
    intervals = tuple((lo.K, hi.K) for lo, hi in ends)
    return KRegion(intervals, delta_max, kb, grid, margins, ok, tol, tuple(ends), "bisection")


@renamed_keywords(n="n_gains")
def k_region(
    system: Any,
    delta_max: float,
    *,
    Ks: ArrayLike | None = None,
    n_gains: int = DEFAULT_N_GAINS,
    tol: float | None = None,
    controller: Callable[[float], Any] | None = None,
    executor: Any = "serial",
    max_evals: int = 2_000_000,
    progress: bool | None = None,
) -> KRegion:
    """Gains keeping the loop stable for every delay in ``[0, delta_max]``, with exact ends.

    ``U_BS2(K)`` (eq. (53)) is admissible when the nominal loop is stable and its
    delay margin exceeds ``delta_max`` (the margin is the *first* delay at which a root
    reaches the axis, so the whole of ``[0, delta_max]`` is checked). Its loop
    ``A(s) + (B_0(s) + K q e^{-tau s}) e^{-delta s}`` (eq. (60)) is affine in
    ``K``, and an end of an admissible interval is one of:

    * a *crossing*: ``A(i w) + B(i w; K) e^{-i w delta_max} = 0``, i.e. ``K(w) = -(A(i w)
      e^{i w delta_max} + B_0(i w)) / (q e^{-i w tau})`` with ``Im K(w) = 0``, solved in ``w``;
    * a *pair birth*: ``g(w; K) = |A(i w)|^2 - |B(i w; K)|^2`` has a double zero in ``w``
      (``g = dg/dw = 0``) with crossing delay ``<= delta_max``; ``g`` is quadratic in ``K``,
      its roots ``K_pm(w)`` are explicit, and the birth is an extremum of ``K_pm(w)``;
    * *nominal*: the crossing equation with ``delta = 0`` (the nominal loop loses stability);
    * the *strong-stability* limit ``|rho q| + |K q| = 1`` (the paper's bound, eq. (54)).

    A scan of the imaginary axis up to the frequency bound finds these critical gains
    (between two of them the verdict is constant), each is solved from its own equation to
    ``1e-14`` in ``w``, and each end is then verified independently: ``tol`` inside, the
    certified crossing search of :func:`delay_margin` finds the loop admissible; ``tol``
    outside, a certified root count (:func:`nrobust.count_roots`) finds a zero in ``Re s > 0``
    about the root of the end's event, at a delay in ``[0, delta_max]``. An end that cannot be
    verified raises :class:`~nrobust.errors.CertificationError`. The grid ``Ks`` is checked the
    same way: its certified verdicts must agree with the intervals. The crossing searches of
    the scan and of the checks stop at a second-order frequency bound (the kernels' boundary
    terms, integrated by parts twice): near the paper's bound ``k`` it grows like
    ``1/sqrt(k - |K|)`` where :func:`nrobust.crossings.frequency_bound` grows like
    ``1/(k - |K|)``.
    Features narrower than the scan step ``pi / (4 (2 tau + delta_max))`` in frequency can
    be missed; a verified end is exact whatever happens between ends.

    For any other ``controller`` family the grid's changes of verdict are bisected to
    ``tol`` on delay margins instead (kind ``"bisection"``).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant; a general plant through its normal form (a ``controller`` family then acts
        in its physical coordinates), with a varying ``lam/mu`` only with a ``controller``
        family other than U_BS2(K) (e.g. ``StateFeedback``: its loop by the characteristic
        route; the default grid then spans the strong-stability bound of ``|k|`` of
        ``U = k u(t, L)``, :func:`~nrobust.hyperbolic.classify`).
    delta_max : float
        Delay range to tolerate (``> 0``, finite).
    Ks : array_like, optional
        Gain grid on which margins are reported (and, for other families, bisected); default
        ``n_gains`` points spanning ``(-k, k)``, ``k`` the paper's bound (gains outside it
        have zero margin: the difference operator ``1 - rho q e^{-tau s} + K q
        e^{-(tau+delta) s}`` is not strongly stable).
    n_gains : int, default :data:`DEFAULT_N_GAINS`
        Size of the default grid, ``>= 3`` (formerly ``n``, a deprecated alias).
    tol : float, optional
        Accuracy of the interval ends (the offset of their verification); default
        ``1e-10`` times the paper's bound (``1e-4`` times it when bisecting).
    controller : callable, optional
        ``K -> controller``; default (or ``ReflectionController``) ``U_BS2(K)``, whose ends
        are solved from their equations.
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the delay margins run (:func:`nrobust.sweep`'s executors); default in this
        process. Results are the same whatever the executor.
    max_evals : int, optional
        Work bound of each delay margin (:func:`nrobust.margins.delay_margin`) and of the
        scan of the axis.
    progress : bool, optional
        A progress bar over the delay margins on stderr; by default only when stderr is a
        terminal or Jupyter.

    Returns
    -------
    KRegion

    Raises
    ------
    CertificationError
        An end could not be verified (the message names its bracket), a delay margin
        failed, or the scan would exceed ``max_evals``.
    """
    system, controller = _study_plant(system, controller, "k_region")
    delta_max = positive("delta_max", delta_max)
    max_evals = positive_int("max_evals", max_evals)
    exact = controller is None or controller is ReflectionController
    kb = classify(system).k_bound
    scale = kb if kb > 0 else 1.0
    tol = positive("tol", tol) if tol is not None else (1e-10 if exact else 1e-4) * scale
    if Ks is None:
        n_gains = positive_int("n_gains", n_gains, 3)
        if kb == 0.0:
            raise ParameterError("system", "with |rho q| < 1 for the default gain grid (pass Ks)", system)
        Ks = kb * np.linspace(-1.0, 1.0, n_gains + 2)[1:-1]
    grid = np.sort(_grid("Ks", Ks))
    if controller is None or controller is ReflectionController:
        return _exact_region(system, delta_max, kb, grid, tol, executor, max_evals, progress)
    return _bisection_region(system, delta_max, kb, grid, tol, controller, executor, max_evals, progress)


@dataclass(frozen=True)
class _PartialMargin:
    """Picklable ``K -> delay_margin(system, family(K))`` for ``map`` hooks."""

    system: Any
    delta_max: float | None
    family: Callable[[float], Any]

    def __call__(self, K: float) -> DelayMargin:
        return _margin_for(K, self.system, self.delta_max, self.family)


#: Largest filter coefficient ``max(|a|, b)`` that :func:`ab_region` uses as it is (:class:`_PartialFilter`).
_FILTER_SCALE = 2.0**32


@dataclass(frozen=True)
class _PartialFilter:
    """Picklable ``(a, b) -> delay_margin(system, FilteredController(a, b))``.

    Filter coefficients beyond ``_FILTER_SCALE`` make ``|A(i w)|^2`` overflow: the loop
    ``(1 + b s)(1 - Phi) + (1 + a s) Phi e^{-delta s}`` is then divided by the power of two
    ``c`` just above ``max(|a|, b)`` (exact in floating point; the zeros, hence the margin,
    do not change), i.e. ``(1 - Phi)`` and ``Phi`` multiply ``(c + c b s)`` and ``(c + c a s)``.
    """

    system: Any
    delta_max: float

    def __call__(self, ab: tuple[float, float]) -> DelayMargin:
        a, b = ab
        big = max(abs(a), b)
        if big <= _FILTER_SCALE:
            return delay_margin(self.system, FilteredController(a, b), delta_max=self.delta_max, verify=False)
        FilteredController(a, b)  # the same validation of (a, b)
        c = float(2.0 ** -np.ceil(np.log2(big)))
        A, B = loop_factors(self.system, FiniteTimeController())  # (1 - Phi, Phi)
        A, B = A.times_poly([c, c * b]), B.times_poly([c, c * a])
        return factor_delay_margin(A, B, delta_max=self.delta_max, verify=False)


@dataclass(frozen=True, eq=False)
class ABRegion:
    """Filter coefficients ``(a, b)`` keeping the filtered ``U_BS`` stable on ``[0, delta_max]``.

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    a, b : ndarray
        The grid axes.
    admissible : ndarray of bool, shape ``(len(a), len(b))``
        Nominal loop stable and delay margin above ``delta_max``.
    margins : ndarray, shape ``(len(a), len(b))``
        ``delta*(a, b)``.
    strongly_stable : ndarray of bool
        ``|rho q| (1 + |a|/b) < 1``: the difference operator
        ``1 - rho q e^{-tau s} + (a/b) rho q e^{-(tau+delta) s}`` is strongly stable
        (necessary for a positive margin).
    paper_conditions : ndarray of bool
        The paper's eq. (17): ``a/b < (1 - |rho q|)/|rho q|`` and
        ``a < (1 - |rho q|)/|rho q|``.
    delta_max : float
    """

    a: NDArray[np.float64]
    b: NDArray[np.float64]
    admissible: NDArray[np.bool_]
    margins: NDArray[np.float64]
    strongly_stable: NDArray[np.bool_]
    paper_conditions: NDArray[np.bool_]
    delta_max: float

    def __repr__(self) -> str:
        return (
            f"ABRegion(delta_max={self.delta_max:.6g}, {int(self.admissible.sum())}/{self.admissible.size} admissible, "
            f"{int((self.paper_conditions & ~self.admissible).sum())} meet eq. (17) but are not)"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


def ab_region(system: Any, delta_max: float, a: ArrayLike, b: ArrayLike, *, executor: Any = "serial") -> ABRegion:
    """Admissible filter coefficients of the filtered finite-time controller (section 2.3.2).

    With ``U_1(s) = -(1 + a s)/(1 + b s) U_BS``, the loop is
    ``(1 + b s)(1 - Phi) + (1 + a s) Phi e^{-delta s}`` (eq. (16) for a
    transport system). Its difference operator (the ``s`` terms divided by ``b``) is
    ``1 - rho q e^{-tau s} + (a/b) rho q e^{-(tau + delta) s}``, strongly stable iff
    ``|rho q| (1 + |a|/b) < 1``; this, not the one-sided ``a/b < (1 - |rho q|)/|rho q|``
    of eq. (17), is necessary for a positive margin. Each grid point is decided by
    :func:`delay_margin` (nominal stability and ``delta* > delta_max``).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant; a general plant through its normal form, or with a varying ``lam/mu`` by
        its characteristic route (U_BS is defined on both, :mod:`~nrobust.hyperbolic.controllers`).
    delta_max : float
        Delay range to tolerate.
    a, b : array_like
        Grid axes (``b > 0``).
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the grid points run (:func:`nrobust.sweep`'s executors); default in this
        process. Results are the same whatever the executor.

    Returns
    -------
    ABRegion
    """
    if isinstance(system, GeneralHyperbolic2x2):  # U_BS: the normal form, or the characteristic route
        system = normalize(system, None)[0]
    else:
        _check_system(system)
    delta_max = positive("delta_max", delta_max)
    av, bv = _grid("a", a), _grid("b", b)
    if np.any(bv <= 0):
        raise ParameterError("b", "> 0", b)
    pairs = [(float(x), float(y)) for x in av for y in bv]
    results = list(_mapper(executor)(_PartialFilter(system, delta_max), pairs))
    shape = (av.size, bv.size)
    margins = np.array([r.margin for r in results]).reshape(shape)
    ok = np.array([_tolerates(r, delta_max) for r in results]).reshape(shape)
    g = abs(system.rho_q)
    A_, B_ = np.meshgrid(av, bv, indexing="ij")
    strong = g * (1.0 + np.abs(A_) / B_) < 1.0
    bound = (1.0 - g) / g if g > 0 else np.inf
    paper = (A_ / B_ < bound) & (A_ < bound)
    return ABRegion(av, bv, ok, margins, strong, paper, delta_max)


@dataclass(frozen=True, eq=False)
class StabilityChart:
    """Number of unstable roots (or spectral abscissa) on a ``(K, delta)`` grid, with boundaries.

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    Ks, deltas : ndarray
        Grid axes.
    values : ndarray, shape ``(len(Ks), len(deltas))``
        ``quantity`` at each grid point: the number of zeros with ``Re s > 0``
        (``inf`` when the difference operator is not strongly stable and ``delta > 0``;
        ``nan`` at ``delta = 0`` when the nominal count cannot be certified, e.g. a chain of
        zeros in ``Re s > 0``; ``-1`` exactly on a crossing delay), or the spectral abscissa.
    quantity : str
        ``"count"`` or ``"abscissa"``.
    margins : ndarray
        Delay margin ``delta*(K)``: the lower boundary of the stable region.
    boundaries : tuple of ndarray
        Per gain, the array of rows ``(delta, omega, direction)`` of every crossing
        delay up to ``max(deltas)``: the exact boundary curves of the chart.
    """

    Ks: NDArray[np.float64]
    deltas: NDArray[np.float64]
    values: NDArray[np.float64]
    quantity: str
    margins: NDArray[np.float64]
    boundaries: tuple[NDArray[np.float64], ...]

    def __repr__(self) -> str:
        return (
            f"StabilityChart({self.Ks.size} x {self.deltas.size} grid of {self.quantity}, "
            f"K in [{self.Ks[0]:.6g}, {self.Ks[-1]:.6g}], delta in [{self.deltas[0]:.6g}, {self.deltas[-1]:.6g}])"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


@dataclass(frozen=True)
class _PartialAbscissa:
    """Picklable ``(K, delta) -> spectral abscissa`` of the loop with ``family(K)``."""

    system: Any
    family: Callable[[float], Any]

    def __call__(self, point: tuple[float, float]) -> float:

        A, B = loop_factors(self.system, self.family(point[0]))
        F = A + B if point[1] == 0 else A + B.shift(point[1])
        return float(spectral_abscissa(F).value)


def stability_chart(
    system: Any,
    Ks: ArrayLike,
    deltas: ArrayLike,
    *,
    quantity: str = "count",
    controller: Callable[[float], Any] | None = None,
    executor: Any = "serial",
    progress: bool | None = None,
) -> StabilityChart:
    """Stability chart of ``U_BS2(K)`` in the ``(K, delta)`` plane (section 4.2.1).

    For each gain one :func:`delay_margin` analysis gives the number of unstable zeros for
    every delay at once (certified count at ``delta = 0`` plus signed crossings) and the
    exact boundary curves ``delta_{c,k}(K)``. With ``quantity="abscissa"`` the spectral
    abscissa is computed at every grid point (:func:`nrobust.roots.spectral_abscissa`;
    much slower).

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant; a general plant through its normal form (a ``controller`` family then acts
        in its physical coordinates), with a varying ``lam/mu`` only with a ``controller``
        family other than U_BS2(K) (its loops by the characteristic route).
    Ks, deltas : array_like
        Grid axes (``deltas >= 0``).
    quantity : {"count", "abscissa"}
        What to tabulate.
    controller : callable, optional
        ``K -> controller``; default ``ReflectionController``.
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the grid points run (:func:`nrobust.sweep`'s executors); default in this
        process. Results are the same whatever the executor.
    progress : bool, optional
        A progress bar over the gains (and grid points for ``"abscissa"``) on stderr; by
        default only when stderr is a terminal or Jupyter.

    Returns
    -------
    StabilityChart
    """
    system, controller = _study_plant(system, controller, "stability_chart")
    kv, dv = _grid("Ks", Ks), _grid("deltas", deltas)
    if np.any(dv < 0):
        raise ParameterError("deltas", ">= 0", deltas)
    if quantity not in ("count", "abscissa"):
        raise ParameterError("quantity", "'count' or 'abscissa'", quantity)
    family = _reflection if controller is None else controller
    dmax = float(np.max(dv)) if np.max(dv) > 0 else None
    results = list(_mapper(executor, progress, "stability chart: gains")(_PartialMargin(system, dmax, family), kv))
    margins = np.array([r.margin for r in results])
    boundaries = tuple(
        np.array([(d, c.omega, c.direction) for c in r.crossings for d in c.delays if d <= np.max(dv)]).reshape(-1, 3)
        for r in results
    )
    if quantity == "abscissa":
        pts = [(float(K), float(d)) for K in kv for d in dv]
        run = _mapper(executor, progress, "stability chart: abscissae")
        values = np.array(list(run(_PartialAbscissa(system, family), pts))).reshape(kv.size, dv.size)
    else:
        values = np.empty((kv.size, dv.size))
        for i, r in enumerate(results):
            if r.strongly_stable:
                inside = dv <= r.delta_max  # delta_max is max(deltas), or inf without crossings
                values[i, inside] = r.unstable_count(dv[inside])
                values[i, ~inside] = r.counts[-1][2] if r.counts else np.nan
            else:
                values[i] = np.inf
                nominal = r.nominal_unstable
                values[i, dv == 0] = np.nan if nominal is None else nominal
    return StabilityChart(kv, dv, values, quantity, margins, boundaries)


@dataclass(frozen=True, eq=False)
class Tradeoff:
    """Nominal decay rate against delay margin over the gain ``K`` (section 4.2.1).

    Compared by identity (``==`` is ``is``): it holds numpy arrays.

    Attributes
    ----------
    Ks : ndarray
        Gains.
    decay_rates : ndarray
        ``-`` spectral abscissa of the nominal loop (``delta = 0``).
    margins : ndarray
        Exact delay margins ``delta*(K)``.
    rouche_bounds : ndarray
        Guaranteed ``delta_0(K)`` of Theorem 4's proof (:func:`rouche_delay_bound`),
        ``nan`` when the controller is not ``U_BS2``.
    """

    Ks: NDArray[np.float64]
    decay_rates: NDArray[np.float64]
    margins: NDArray[np.float64]
    rouche_bounds: NDArray[np.float64]

    def __repr__(self) -> str:
        return f"Tradeoff({self.Ks.size} gains in [{self.Ks.min():.6g}, {self.Ks.max():.6g}])"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


@dataclass(frozen=True)
class _PartialTradeoff:
    """Picklable ``K -> (decay rate, margin, delta_0)``."""

    system: Any
    family: Callable[[float], Any]

    def __call__(self, K: float) -> tuple[float, float, float]:

        ctrl = self.family(float(K))
        A, B = loop_factors(self.system, ctrl)
        rate = -float(spectral_abscissa(A + B).value)
        margin = delay_margin(A, B, verify=False).margin
        d0 = rouche_delay_bound(self.system, ctrl).delta_0 if isinstance(ctrl, ReflectionController) else np.nan
        return rate, float(margin), float(d0)


def tradeoff(
    system: Any,
    Ks: ArrayLike,
    *,
    controller: Callable[[float], Any] | None = None,
    executor: Any = "serial",
    progress: bool | None = None,
) -> Tradeoff:
    """Decay rate of the nominal loop against the delay margin, over ``K``.

    The paper's remark after Lemma 3: ``K`` trades the convergence rate of the target
    system (reflection ``rho - K``: decay rate ``-ln|(rho - K) q| / tau`` on a transport
    system) for robustness to delays.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant; a general plant as for :func:`stability_chart`.
    Ks : array_like
        Gains.
    controller : callable, optional
        ``K -> controller``; default ``ReflectionController``.
    executor : "serial", None, int, Executor, "dask", address or dask Client, optional
        Where the grid points run (:func:`nrobust.sweep`'s executors); default in this
        process. Results are the same whatever the executor.
    progress : bool, optional
        A progress bar over the gains on stderr; by default only when stderr is a terminal
        or Jupyter.

    Returns
    -------
    Tradeoff
    """
    system, controller = _study_plant(system, controller, "tradeoff")
    kv = _grid("Ks", Ks)
    family = _reflection if controller is None else controller
    run = _mapper(executor, progress, "tradeoff: gains")
    rows = np.array(list(run(_PartialTradeoff(system, family), kv)), dtype=float).reshape(kv.size, 3)
    return Tradeoff(kv, rows[:, 0], rows[:, 1], rows[:, 2])
