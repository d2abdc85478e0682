"""Certificates: every number that decides the delay robustness of one closed loop.

:func:`certify` runs the whole analysis of a plant and a controller and returns a
:class:`Certificate`: the paper's classification by ``|rho q|`` (sections 2 and 3), the
closed-loop difference operator with its ``gamma_0`` and strong stability (Hale and
Verduyn Lunel; eq. (11), eq. (54)), certified root counts per box at
``delta = 0`` and ``delta = delta_max``, the spectral abscissa, the exact delay margin
with its crossing frequency, the Rouché bound ``delta_0`` from the proof of Theorem 4,
and, for ``U_BS2(K)``, the gains ``K`` that keep the loop stable for every delay in
``[0, delta_max]``. Nothing in a certificate is typed in by hand: each field is the
output of the function named in its docstring, with the parameters and library versions
that produced it.
"""

from __future__ import annotations

import dataclasses
import json
import platform
from collections.abc import Callable
from dataclasses import dataclass
from decimal import ROUND_CEILING, ROUND_FLOOR, Decimal
from typing import Any, TypeVar

import numpy as np
import scipy
from threadpoolctl import threadpool_limits

from .._digits import lower_bound_text, with_accuracy
from .._json import fields_dict, json_safe
from .._validate import positive, positive_int, renamed_keywords
from .._validate import region as check_region
from .._version import __version__
from ..bounds import RoucheDelayBound
from ..errors import CertificationError, ParameterError
from ..hyperbolic import analyses
from ..hyperbolic.analyses import DEFAULT_N_GAINS, KRegion
from ..hyperbolic.analyses.grid_study import MAX_ACCURACY_GRID, GridStudy, grid_study, study_scope
from ..hyperbolic.analyses.margin import studied_delay_margin
from ..hyperbolic.analyses.rouche import rouche_delay_bound
from ..hyperbolic.kernels.constant import DEFAULT_KERNEL_GRID, MIN_KERNEL_GRID, check_kernel_grid
from ..hyperbolic.loops.controllers import (
    Classification,
    Controller,
    FiniteTimeController,
    ReflectionController,
    StateFeedback,
    characteristic,
    classify,
    loop_factors,
    loop_route,
    loop_scope,
    normalize,
)
from ..hyperbolic.loops.exact_form import closed_form_parameters
from ..hyperbolic.loops.given_plant import GivenPlantBalls, given_plant_balls, given_plant_scale, to_given_plant
from ..hyperbolic.plants.general import GeneralHyperbolic2x2
from ..hyperbolic.plants.hyperbolic2x2 import Hyperbolic2x2
from ..margins.margin import DelayMargin
from ..quasipoly import QuasiPolynomial
from ..roots import RootSet, SpectralAbscissa, count_roots, find_roots, spectral_abscissa

__all__ = ["CHECKED", "FLOAT_SCOPE", "PROVEN", "Certificate", "Claim", "ModelError", "PrincipalPart", "certify"]

#: Default search rectangle for the certified root counts, in units of ``1/tau``.
_DEFAULT_REGION = (-3.0, 1.0, -40.0, 40.0)
# Natural logarithm of the largest double: e^x overflows beyond.
_LOG_MAX = float(np.log(np.finfo(float).max))
# Bits of a node spacing kept when the nodes are shifted by delta_max (rounding 2^-52 relative).
_NODE_BITS = 48


@dataclass(frozen=True)
class PrincipalPart:
    """The closed-loop difference operator ``D(s) = sum_k a_k e^{-tau_k s}`` at one delay.

    Attributes
    ----------
    delta : float
        The loop delay at which ``F(s; delta)`` was formed.
    coefs, delays : tuple of float
        ``a_k`` (real parts; the loops of the paper are real) and ``tau_k``.
    gamma_0 : float
        ``sum_{k >= 1} |a_k| / |a_0|``; for U_BS this is ``2 |rho q|`` (eq. (11)), for
        U_BS2(K) ``|rho q| + |K q|`` at a delay ``delta > 0`` (eq. (54) is ``gamma_0 < 1``).
        Within :attr:`gamma_0_ball` when that is given.
    strongly_stable : bool
        ``gamma_0 < 1``: the loop's high-frequency chains stay in ``Re s < 0`` for every
        small delay (Hale and Verduyn Lunel). With :attr:`gamma_0_ball`, True only when
        proven (its upper end below 1).
    strong_spectral_bound : float
        ``C_D``, the supremum of the chains' abscissa over small delay perturbations.
    spectral_bound : float
        ``c_D``, the abscissa of the rightmost chain at this very delay (exact for
        commensurate delays, the certified upper end of its bracket otherwise).
    chains : tuple of float
        Abscissae ``Re s`` of the root chains, rightmost first (commensurate delays only).
    gamma_0_ball : tuple of float or None
        With ``certify(..., rigorous=True)``: ``(lo, hi)`` proven in ball arithmetic to hold
        ``gamma_0`` of every difference operator whose coefficients lie in the proven balls
        of the loop's principal coefficients (``QuasiPolynomial(..., radii=...)``: the
        plant's own gains, irrational ones included; the stored coefficients, taken as
        exact, when the loop carries no radii), ends rounded outwards
        (:meth:`~nrobust.difference.DifferenceOperator.proven_gamma_0`). None without
        proofs, or when a ball is centred on a stored zero coefficient.
    """

    delta: float
    coefs: tuple[float, ...]
    delays: tuple[float, ...]
    gamma_0: float
    strongly_stable: bool
    strong_spectral_bound: float
    spectral_bound: float
    chains: tuple[float, ...]
    gamma_0_ball: tuple[float, float] | None = None

    @property
    def gamma_0_accuracy(self) -> float | None:
        """A proven bound of ``|gamma_0 - gamma_0 of the loop|``: the distance to the far end of
        :attr:`gamma_0_ball`, rounded up; None without it."""
        if self.gamma_0_ball is None:
            return None
        lo, hi = self.gamma_0_ball
        return float(np.nextafter(max(hi - self.gamma_0, self.gamma_0 - lo), np.inf))

    @property
    def gamma_0_text(self) -> str:
        """``gamma_0`` with the digits its proven accuracy supports (6 significant digits without proofs)."""
        if self.gamma_0_ball is None:
            return f"{self.gamma_0:.6g}"
        return with_accuracy(self.gamma_0, self.gamma_0_accuracy) + " (proven)"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (infinities as strings)."""
        return fields_dict(self)


def _principal(F: QuasiPolynomial, delta: float, rigorous: bool = False) -> PrincipalPart:
    """The :class:`PrincipalPart` of ``F``; with ``rigorous``, its ``gamma_0`` proven with the radii of ``F``."""
    D = F.principal_part()
    chains = D.chains()
    bound = chains.bracket[1]  # c_D when commensurate, else the certified upper end
    gamma, stable, ball = float(D.gamma_0), bool(D.is_strongly_stable()), None
    radii = F.principal_radii() if rigorous else None
    if radii is not None:
        ball = D.proven_gamma_0(radii=radii)
        gamma = min(max(gamma, ball[0]), ball[1])
        stable = ball[1] < 1.0
    return PrincipalPart(
        float(delta),
        tuple(float(np.real(a)) for a in D.coefs),
        tuple(float(t) for t in D.delays),
        gamma,
        stable,
        float(D.strong_spectral_bound()),
        float(bound),
        tuple(float(c.real) for c in chains.chains),
        ball,
    )


#: Status of a claim proven in ball arithmetic (python-flint): a theorem about ``F`` as represented.
PROVEN = "proven (ball arithmetic)"
#: Status of a claim computed in floating point with a rounding allowance.
CHECKED = "checked (floating point)"
#: What a certificate computed without ``rigorous`` guarantees, and how to get proofs.
FLOAT_SCOPE = (
    "Without proofs, the root counts are integers checked in floating point: the argument principle with a "
    "step control that bounds the change of argument between samples. The other values (the delay margin, "
    "the crossing frequencies, the spectral abscissa, the Rouché range) are checked with a rounding "
    "allowance, not proven. To prove them in ball arithmetic (python-flint, pip install nrobust[rigorous]): "
    "rigorous = true in the [analysis] table of SYSTEM.toml, or certify(..., rigorous=True)."
)


@dataclass(frozen=True)
class Claim:
    """One statement of a certificate and how far it is established.

    Attributes
    ----------
    name : str
        What the claim is about (``"delay margin"``, ``"nominal stability"``, ...).
    statement : str
        The claim, with its numbers.
    status : str
        :data:`PROVEN` (ball arithmetic, about ``F`` as represented) or :data:`CHECKED`
        (floating point with a rounding allowance).
    source : str
        The function whose result the claim states.
    """

    name: str
    statement: str
    status: str
    source: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        return fields_dict(self)


@dataclass(frozen=True)
class ModelError:
    """How far the loop of the certificate is from the PDE.

    On the exact route (constant coefficients, :func:`~nrobust.hyperbolic.loops.controllers.loop_route`)
    there is no model: ``N~`` is in closed form and its proven error bound is inside every
    enclosure (``difference = 0``). On the kernel route the proofs concern ``F`` as
    represented (``N~`` the cubic spline on ``kernel_grid`` points), and this is the separate,
    floating-point evidence on its distance to the PDE: a convergence study of the delay
    margin on the grid, one half as fine and one a quarter as fine.

    Attributes
    ----------
    kernel_grid, coarse_grid : int
        The grid of the certificate and the grid half as fine (equal when no study was made).
    margin, coarse_margin : float
        The delay margins on both grids.
    difference : float
        ``|margin - coarse_margin|``.
    order : float or None
        The observed order ``log2`` of the ratio of two successive differences (None when not
        measured or when the convergence is not monotone).
    statement : str
        The evidence in words.
    estimate : float or None
        The estimate of the margin's model error (the convergence study: the last
        difference when the margins converge monotonically at an observed order of at least 1,
        else from a grid twice as fine); None means ``difference`` (0 or ``nan``).
    """

    kernel_grid: int
    coarse_grid: int
    margin: float
    coarse_margin: float
    difference: float
    statement: str
    order: float | None = None
    estimate: float | None = None

    @property
    def error(self) -> float:
        """The estimated model error of the margin (``estimate``, else ``difference``)."""
        return self.difference if self.estimate is None else self.estimate

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (infinities as strings)."""
        return fields_dict(self)


def _model_error(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    controller: Controller,
    margin: DelayMargin,
    grid: int | None,
    study: GridStudy | None,
) -> ModelError:
    """No model on the exact route; on the kernel route, the convergence study of the margin (``study``, made
    here when ``delay_margin`` did not: an uncoupled plant with integral gains)."""
    gains = isinstance(controller, StateFeedback) and any(
        callable(g) or g != 0.0 for g in (controller.g_u, controller.g_v)
    )
    if getattr(system, "uncoupled", False) and not gains:  # integral gains: Simpson's rule on the grid
        return ModelError(
            0, 0, margin.margin, margin.margin, 0.0, "no kernel (uncoupled plant, N~ = 0): the loop is exact"
        )
    if loop_route(system, controller, grid) == "exact":
        return ModelError(
            0,
            0,
            margin.margin,
            margin.margin,
            0.0,
            "no model: N~ (and a state feedback's gain kernels) in closed form, its proven error bound in every proof",
        )
    grid = DEFAULT_KERNEL_GRID if grid is None else grid
    if study is None:
        study = grid_study(
            lambda n: studied_delay_margin(system, controller, kernel_grid=n, study=False)[0], grid, margin
        )
    spline = _spline(system, grid)
    if study is None:  # too few points to halve: no comparison to make
        return ModelError(
            grid,
            grid,
            margin.margin,
            margin.margin,
            float("nan"),
            f"{spline}, too few to compare with a grid half as fine "
            f"(at least {2 * MIN_KERNEL_GRID - 1} points): the model error is not estimated",
        )
    diff = _difference(margin.margin, study.coarse_margin)
    statement = f"{spline}; {study.statement}"
    estimate = None if study.estimate == 0.0 and diff == 0.0 else study.estimate
    return ModelError(
        grid, study.coarse_grid, float(margin.margin), study.coarse_margin, diff, statement, study.order, estimate
    )


def _spline(system: Hyperbolic2x2 | GeneralHyperbolic2x2, grid: int) -> str:
    """What ``N~`` is on the kernel route, in words."""
    if isinstance(system, GeneralHyperbolic2x2):  # a varying lam/mu: no kernels, the characteristic route
        return (
            f"N~ is the cubic spline of the characteristic route (varying lam/mu) on {grid} nodes, "
            f"Richardson-extrapolated from {2 * (grid - 1)} steps"
        )
    if getattr(system, "uncoupled", False):
        return f"N~ = 0 (uncoupled plant); the integral gains are integrated by Simpson's rule on {grid} points"
    return f"N~ is the cubic spline of the kernels on {grid} points"


def _difference(a: float, b: float) -> float:
    """``|a - b|``, 0 when equal (infinities included), ``inf`` when one is infinite."""
    if a == b:
        return 0.0
    return float(abs(a - b)) if np.isfinite(a) and np.isfinite(b) else float("inf")


def _representation(system: Hyperbolic2x2 | GeneralHyperbolic2x2, controller: Controller, grid: int) -> str:
    """How ``N~`` (and a state feedback's kernel) is represented in the certified ``F``, per kind of plant."""
    if isinstance(system, GeneralHyperbolic2x2):  # normalize() leaves only a varying lam/mu general
        text = (
            f"N~ the cubic spline of the characteristic route (varying lam/mu) on {grid} "
            f"nodes, Richardson-extrapolated from {2 * (grid - 1)} steps"
        )
        gains = (getattr(controller, "g_u", 0.0), getattr(controller, "g_v", 0.0))
        if isinstance(controller, StateFeedback) and any(callable(g) or g != 0.0 for g in gains):
            text += (
                f", and the feedback's kernel M the cubic spline of the kernels with varying speeds on {grid} points"
            )
        return text
    if getattr(system, "uncoupled", False):
        return "N~ = 0 exactly (uncoupled plant: no kernel)"
    return f"N~ the cubic spline of the kernels on the kernel grid ({grid} points)"


def _unstable_witness(
    Fd: QuasiPolynomial, rigorous: bool, balls: GivenPlantBalls | None = None
) -> tuple[tuple[float, float, float, float], int] | None:
    """A box in ``Re s > 0`` holding zeros of ``F(s; delta_max)`` (count and box), or None.

    The roots of a neutral loop approach the chains of its difference operator (each chain
    ``Re s = c``, ``Im s = offset + k spacing``): a box of half-width ``min(c/2, 0.1)`` and
    half-height 1 about a chain point with ``c > 0`` is counted (in ball arithmetic with
    ``rigorous``: on the plant's own loop when ``balls``, :func:`given_plant_balls`, is
    given); a positive count proves the loop unstable.
    """
    try:
        chains = Fd.principal_part().chains().chains
    except (ParameterError, CertificationError):
        return None
    for chain in [c for c in chains if c.real > 0][:3]:
        im = chain.offset % chain.spacing if np.isfinite(chain.spacing) and chain.spacing > 0 else chain.offset
        im = im or chain.spacing
        r = min(0.5 * chain.real, 0.1)
        box = (chain.real - r, chain.real + r, im - 1.0, im + 1.0)
        try:
            n = count_roots(Fd, box, rigorous=rigorous, balls=balls)
        except CertificationError:
            continue
        if int(n) > 0 and n.region[0] > 0.0:
            return tuple(float(v) for v in n.region), int(n)  # type: ignore[return-value]
    return None


def _outward(x: float | None, digits: int, up: bool) -> str:
    """``x`` to ``digits`` significant digits, rounded up (``up``) or down: a displayed bound stays a bound."""
    if x is None or not np.isfinite(x):
        return "-" if x is None else {np.inf: "infinity", -np.inf: "-infinity"}.get(float(x), "nan")
    if x == 0.0:
        return "0"
    exact = Decimal(float(x))
    quantum = Decimal(1).scaleb(exact.adjusted() - digits + 1)
    return f"{exact.quantize(quantum, rounding=ROUND_CEILING if up else ROUND_FLOOR).normalize():g}"


def _claims(
    margin: DelayMargin,
    roots0: RootSet,
    rootsd: RootSet,
    abscissa: SpectralAbscissa,
    rouche: RoucheDelayBound | None,
    kreg: KRegion | None,
    delta_max: float,
    witness: tuple[tuple[float, float, float, float], int] | None = None,
) -> tuple[Claim, ...]:
    """Every claim of a certificate with its status (proven in balls or checked in floating point)."""

    def status(proven: bool) -> str:
        return PROVEN if proven else CHECKED

    main = margin.rigorous and margin.strongly_stable  # the crossing analysis ran in balls
    out = [
        Claim(
            "strong stability",
            "the difference operator of F(s; delta) is "
            + ("" if margin.strongly_stable else "not ")
            + f"strongly stable for small delta > 0 (principal gap {with_accuracy(margin.gap, margin.gap_accuracy)})",
            status(margin.rigorous),
            "delay_margin",
        ),
        Claim(
            "nominal stability",
            "F(s; 0) has "
            + (
                "no zero in Re s >= 0"
                if margin.nominally_stable
                else ("an unknown number of zeros" if margin.nominal_unstable is None else f"{margin.nominal_unstable}")
                + " zeros in Re s > 0 (or one on the axis)"
            ),
            status(
                main
                or (margin.rigorous and margin.zero_root)
                or (margin.nominally_stable and abscissa.rigorous and abscissa.certified and abscissa.upper_bound < 0)
            ),
            "delay_margin (count_roots), spectral_abscissa",
        ),
    ]
    if np.isposinf(margin.margin):
        text = "delta* = infinity (stable for every delay)"
    elif margin.margin_ball is not None and margin.rigorous:
        lo, hi = margin.margin_ball
        text = f"delta* in [{_outward(lo, 16, False)}, {_outward(hi, 16, True)}]"
        if margin.of_model:  # the ball is about the model; the plant's margin to its estimated accuracy
            text = f"{text} for the model, {with_accuracy(margin.margin, margin.accuracy)} for the plant"
    else:
        text = f"delta* = {with_accuracy(margin.margin, margin.accuracy)}"
    reason = margin.reason.split(" (proven in ball arithmetic")[0]
    if "stable for every delay" in reason:  # said once
        text = text.replace(" (stable for every delay)", "")
    out.append(Claim("delay margin", f"{text}: {reason}", status(margin.rigorous), "delay_margin"))
    if margin.margin_ball is not None and margin.margin_ball[0] > delta_max:
        out.append(
            Claim(
                "stability up to delta_max",
                f"F(s; delta) has no zero in Re s >= 0 for every delta in [0, {delta_max:g}] (delta* > delta_max)",
                status(margin.rigorous),
                "delay_margin",
            )
        )
    if witness is not None:
        box, n = witness
        out.append(
            Claim(
                "instability at delta_max",
                f"F(s; {delta_max:g}) has at least {n} zero(s) in the box Re s in "
                f"[{_outward(box[0], 6, False)}, {_outward(box[1], 6, True)}], "
                f"Im s in [{_outward(box[2], 6, False)}, {_outward(box[3], 6, True)}] "
                "(inside Re s > 0: a chain of the difference operator)",
                status(margin.rigorous),
                "count_roots",
            )
        )
    if margin.omega is not None and np.isfinite(margin.margin) and margin.margin > 0:
        first = next((c for c in margin.crossings if c.omega == margin.omega), None)
        kind = "a tangency" if first is not None and first.tangential else "a destabilising crossing"
        out.append(
            Claim(
                "crossing that fixes delta*",
                f"{kind} at w = {with_accuracy(margin.omega, margin.omega_accuracy)}, first of every zero of "
                f"|A(i w)|^2 - |B(i w)|^2 on "
                f"[0, W], W = {_outward(margin.frequency_bound, 6, True)}",
                status(main),
                "delay_margin (crossings)",
            )
        )
    for name, roots, delta in (("roots at delta = 0", roots0, 0.0), ("roots at delta_max", rootsd, delta_max)):
        right = int(np.sum(roots.box_counts[roots.boxes[:, 0] > 0.0])) if roots.boxes.size else 0
        extra = f", {right} of them in boxes inside Re s > 0" if right else ""
        out.append(
            Claim(
                name,
                f"F(s; {delta:g}) has {roots.count} zero{'' if roots.count == 1 else 's'} in the region, each entry in "
                f"its counted box{extra}",
                status(roots.rigorous and roots.certified),
                "find_roots",
            )
        )
    out.append(
        Claim(
            "spectral abscissa",
            "F(s; 0) has no zero at all" if np.isneginf(abscissa.value) else _abscissa_statement(abscissa),
            status(abscissa.rigorous and abscissa.certified),
            "spectral_abscissa",
        )
    )
    if rouche is not None:
        out.append(
            Claim(
                "Rouché delay range",
                (
                    "every delay"
                    if np.isposinf(rouche.delta_0)
                    else f"every delay in [0, {_outward(rouche.delta_0, 6, False)}]"
                )
                + " keeps F zero-free on Re s >= 0",
                status(bool(getattr(rouche, "rigorous", False))),
                "rouche_delay_bound",
            )
        )
    if kreg is not None:
        out.append(
            Claim(
                "admissible gains",
                f"the gains K stable for every delay in [0, {delta_max:g}] (admissible gains, above)",
                CHECKED,
                "k_region",
            )
        )
        if kreg.rigorous and kreg.intervals:
            out.append(_gain_ends_claim(kreg))
    return tuple(out)


def _gain_ends_claim(kreg: KRegion) -> Claim:
    """The claim on the ends of the admissible gains of ``k_region(..., rigorous=True)``: proven when every end is
    (:attr:`~nrobust.hyperbolic.analyses.KRegion.proven`), else checked, with the reasons."""
    ends = ", ".join(
        f"{with_accuracy(end.K, end.accuracy)} ({end.kind.replace('_', ' ')})" for pair in kreg.ends for end in pair
    )
    how = (
        f"each end of the admissible gains ({ends}) lies, within its accuracy, between a gain stable for every "
        f"delay in [0, {kreg.delta_max:g}] (a proven delay margin above it, the nominal loop proven stable) and "
        "one that is not (a proven crossing delay below it, a proven unstable nominal loop, or a difference "
        "operator proven not strongly stable), on the exact loop "
        "of the PDE; that no other end lies between two ends rests on the floating-point scan"
    )
    if kreg.ends_proven:
        return Claim("admissible gain ends", how, PROVEN, "k_region (rigorous)")
    why = "; ".join(kreg.unproven) or "no proof decided"
    return Claim("admissible gain ends", f"not all proven ({why}); checked in floating point", CHECKED, "k_region")


def _abscissa_statement(abscissa: SpectralAbscissa) -> str:
    """The abscissa claim: the bound it proves, and how that bound stands to the value the tables give.

    The claim is the upper end (``F`` has no zero right of it), rounded up to 10 digits; with a
    proven ``value_bracket`` its lower end too, so that a reader sees why the bound is looser
    than the estimated value beside it (the value is inside the bracket, the bound its right end).
    """
    hi = _outward(abscissa.upper_bound, 10, True)
    if abscissa.rigorous and abscissa.value_bracket is not None:
        lo = _outward(abscissa.value_bracket[0], 10, False)
        return f"sup Re s over the zeros of F(s; 0) lies in [{lo}, {hi}]: no zero with Re s > {hi}"
    return (
        f"no zero of F(s; 0) with Re s > {hi} (a bound above the spectral abscissa; the value in the "
        "quantities table is the rightmost root found)"
    )


def _versions() -> dict[str, str]:
    return {
        "nrobust": __version__,
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "python": platform.python_version(),
    }


@dataclass(frozen=True, eq=False)
class Certificate:
    """The delay-robustness certificate of one closed loop (see :func:`certify`).

    Attributes
    ----------
    system, controller : objects
        The plant and controller analysed (kept to redraw figures; serialised through
        their ``to_dict``).
    delta_max : float
        The range ``[0, delta_max]`` of loop delays covered.
    classification : Classification
        :func:`nrobust.hyperbolic.classify`: the regime of ``|rho q|``.
    principal_nominal, principal_delayed : PrincipalPart
        The difference operator of ``F(s; 0)`` and of ``F(s; delta_max)``.
    roots_nominal, roots_delayed : RootSet
        :func:`nrobust.roots.find_roots` of ``F(s; 0)`` and ``F(s; delta_max)`` in
        ``region``, with per-box certified counts.
    abscissa : SpectralAbscissa
        :func:`nrobust.roots.spectral_abscissa` of ``F(s; 0)`` (the decay rate is its
        opposite).
    margin : DelayMargin
        :func:`nrobust.margins.delay_margin` with the crossing frequency and the stability
        intervals up to ``delta_max``.
    rouche : RoucheDelayBound or None
        :func:`nrobust.hyperbolic.analyses.rouche.rouche_delay_bound` (U_BS and U_BS2 only).
    k_region : object or None
        :func:`nrobust.hyperbolic.analyses.k_region` for ``U_BS2(K)``: the gains ``K`` keeping every
        delay in ``[0, delta_max]`` stable, each end solved from its own equations and verified
        (``KRegion.ends`` gives its kind: crossing, pair birth, nominal, strong-stability limit);
        with ``rigorous`` each end proven for the PDE where the proofs decide (``KRegion.proven``).
    region : tuple of float
        The rectangle of the root counts.
    versions : dict
        nrobust, numpy, scipy and python versions.
    k_region_error : str
        Why the admissible gains could not be certified (the
        :class:`~nrobust.errors.CertificationError` of ``k_region``, which is then None);
        empty otherwise.
    rigorous : bool
        ``certify(..., rigorous=True)``: the claims were proven in ball arithmetic where possible.
    claims : tuple of Claim
        Every claim with its status, :data:`PROVEN` or :data:`CHECKED` (see :attr:`scope`).
    model_error : ModelError or None
        With ``rigorous``: the floating-point evidence on the distance of ``N~`` to the kernel.
    accuracy_target : float or None
        The target of ``certify(..., accuracy=...)`` (:attr:`accuracy_statement`).
    unproven : tuple of str
        With ``rigorous``: the parts whose proof was refused (then checked in floating point), and why.
    kernel_grid : int or None
        Points per direction of the kernel grid of the certificate's loops; None on the exact
        route (no grid: ``N~`` in closed form). The K-region of
        :func:`~nrobust.hyperbolic.analyses.k_region` is computed on its default route.
    given_system, given_controller : objects or None
        The plant and controller as passed to :func:`certify` when ``system`` and
        ``controller`` are their normal form (a :class:`GeneralHyperbolic2x2` with a constant
        ``lam/mu`` analysed on the kernel route); None when they were analysed as given.
    """

    system: Hyperbolic2x2 | GeneralHyperbolic2x2
    controller: Controller
    delta_max: float
    classification: Classification
    principal_nominal: PrincipalPart
    principal_delayed: PrincipalPart
    roots_nominal: RootSet
    roots_delayed: RootSet
    abscissa: SpectralAbscissa
    margin: DelayMargin
    rouche: RoucheDelayBound | None
    k_region: KRegion | None
    region: tuple[float, float, float, float]
    versions: dict[str, str]
    k_region_error: str = ""
    rigorous: bool = False
    claims: tuple[Claim, ...] = ()
    model_error: ModelError | None = None
    unproven: tuple[str, ...] = ()
    kernel_grid: int | None = None
    accuracy_target: float | None = None
    given_system: Any = None
    given_controller: Any = None

    @property
    def accuracy_statement(self) -> str:
        """The delay margin's accuracy against the target of ``certify(..., accuracy=...)``, in words."""
        achieved = self.margin_accuracy
        text = "not estimated" if achieved is None else f"{achieved:.1e}"
        if self.accuracy_target is None:
            return f"delay margin {self.margin_text}: accuracy {text}"
        met = achieved is not None and achieved <= self.accuracy_target
        return (
            f"delay margin {self.margin_text}: accuracy {text}, target {self.accuracy_target:.1e} "
            + ("met" if met else "not met")
            + ("" if met or self.route == "exact" else f" (kernel grid {self.kernel_grid}, the finest tried)")
        )

    @property
    def route(self) -> str:
        """``"exact"`` (the PDE's own loop) or ``"kernels"`` (a model).

        See :func:`~nrobust.hyperbolic.loops.controllers.loop_route`.
        """
        return loop_route(self.system, self.controller, self.kernel_grid)

    @property
    def scope(self) -> str:
        """What the certificate's proofs are about, in words."""
        if not self.rigorous:
            return FLOAT_SCOPE
        if self.route in ("exact", "observer"):  # loop_scope says what the observer's term is (a model)
            return (
                "Claims marked proven hold for "
                + loop_scope(
                    self.system,
                    self.controller,
                    self.kernel_grid,
                    loop_factors(self.system, self.controller),
                    normal_form=self.given_system is not None,
                )
                + "; they are proven in ball arithmetic (python-flint)."
                + self._counts_scope
            )
        return (
            "Claims marked proven hold for F as represented: the stored floating-point numbers taken as exact, "
            + _representation(self.system, self.controller, self.kernel_grid or DEFAULT_KERNEL_GRID)
            + "; they are proven in ball arithmetic (python-flint). The distance of N~ to the exact one (the model "
            "error) is not part of the proofs: "
            + (self.model_error.statement if self.model_error is not None else "not estimated")
            + "."
        )

    @property
    def _counts_scope(self) -> str:
        """How the proofs reach the plant as given when ``tau`` is not a double (:func:`given_plant_scale`)."""
        r = given_plant_scale(self.system, self.controller, self.kernel_grid)
        if r is None or r == 1:
            return ""
        exact = "L/lam + L/mu" if isinstance(self.system, GeneralHyperbolic2x2) else "1/lam + 1/mu"
        return (
            f" The loop is built with tau the double {closed_form_parameters(self.system)[0]!r} (relative change "
            f"{float(abs(r - 1)):.1e} from tau = {exact}): the delay margin, its crossing, the spectral abscissa and "
            "the Rouché range are mapped from it to tau exactly, and the root counts marked proven (roots at "
            "delta = 0 and at delta_max, instability at delta_max) are proven on the plant's own loop "
            "A(r s) + B(r s) e^{-delta s}, "
            "r = tau / tau_d in a ball: both hold for "
            + ("its normal form as computed." if self.given_system is not None else "the plant as given.")
        )

    # ------------------------------------------------------------------ verdicts
    @property
    def nominally_stable(self) -> bool:
        """The loop without delay is exponentially stable (from the delay margin's count)."""
        return bool(self.margin.nominally_stable)

    @property
    def delay_margin(self) -> float:
        """``delta*`` (``inf`` when no crossing exists)."""
        return float(self.margin.margin)

    @property
    def margin_accuracy(self) -> float | None:
        """A bound of the margin's distance to the plant's: proven, or estimated; None if unknown.

        On the exact route, that of :attr:`DelayMargin.accuracy <nrobust.margins.margin.DelayMargin.accuracy>`
        (the ball's radius when proven). On the kernel route, the model error of
        :attr:`model_error` (estimated by a convergence study) plus the margin's own accuracy on
        the model, when both are known.
        """
        if self.route == "exact" or not self.margin.of_model:
            return self.margin.accuracy
        if self.model_error is None or not np.isfinite(self.model_error.error):
            return None
        if self.margin.model_error == self.model_error.error:  # the margin carries the study's error: one sum
            return self.margin.accuracy
        on_model = self.margin.margin_ball
        own = 0.0 if on_model is None else max(on_model[1] - self.delay_margin, self.delay_margin - on_model[0])
        own = max(own, 1e-12 * abs(self.delay_margin)) if np.isfinite(self.delay_margin) else 0.0
        return self.model_error.error + own

    @property
    def margin_text(self) -> str:
        """The margin with the digits its accuracy supports (:attr:`margin_accuracy`); ``"infinity"``
        when no delay destabilises the loop."""
        if np.isposinf(self.delay_margin):
            return "infinity"
        return with_accuracy(self.delay_margin, self.margin_accuracy)

    @property
    def delay_robust(self) -> bool:
        """Stable for ``delta = 0`` and for every small ``delta > 0`` (Definition 1)."""
        return self.nominally_stable and self.delay_margin > 0.0

    @property
    def stable_up_to_delta_max(self) -> bool:
        """Stable for every delay in ``[0, delta_max]``."""
        return self.delay_robust and self.delay_margin > self.delta_max

    @property
    def verdict(self) -> str:
        """The conclusion in one sentence."""
        name = type(self.controller).__name__
        if not self.nominally_stable:
            return f"{name}: the loop is not stable even without delay."
        if not self.delay_robust:
            return f"{name}: stable without delay but with zero delay margin: not delay-robust."
        if np.isposinf(self.delay_margin):
            return f"{name}: delay-robust, stable for every delay (delay margin infinity)."
        if self.stable_up_to_delta_max:
            return (
                f"{name}: delay-robust, stable for every delay in [0, {self.delta_max:g}] "
                f"(delay margin {self.margin_text})."
            )
        return (
            f"{name}: delay-robust with margin {self.margin_text}, below the largest delay examined, "
            f"{self.delta_max:g}."
        )

    # ------------------------------------------------------------------ output
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description of every field, the verdicts first (infinities as strings).

        ``abscissa`` is written as ``"spectral_abscissa"``.
        """
        verdicts = {
            "verdict": self.verdict,
            "nominally_stable": self.nominally_stable,
            "delay_robust": self.delay_robust,
            "delay_margin": self.delay_margin,
            "delay_margin_accuracy": self.margin_accuracy,
            "stable_up_to_delta_max": self.stable_up_to_delta_max,
            "scope": self.scope,
        }
        fields = {("spectral_abscissa" if k == "abscissa" else k): v for k, v in fields_dict(self).items()}
        return {**json_safe(verdicts), **fields}

    def to_json(self, indent: int | None = 2) -> str:
        """The certificate as JSON text (strict: no NaN or infinity literals)."""
        return json.dumps(self.to_dict(), indent=indent, allow_nan=False)

    def __repr__(self) -> str:
        return (
            f"Certificate({type(self.controller).__name__}, delta_max={self.delta_max:g}, "
            f"margin={self.margin_text}, nominally_stable={self.nominally_stable}, "
            f"delay_robust={self.delay_robust})"
        )


@renamed_keywords(k_grid="n_gains")
def certify(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    controller: Controller,
    delta_max: float = 0.1,
    region: tuple[float, float, float, float] | None = None,
    k_region: bool = True,
    n_gains: int = DEFAULT_N_GAINS,
    rigorous: bool = False,
    kernel_grid: int | None = None,
    accuracy: float | None = None,
) -> Certificate:
    """Certify the delay robustness of a plant and a controller on ``[0, delta_max]``.

    Parameters
    ----------
    system : Hyperbolic2x2, TransportSystem or GeneralHyperbolic2x2
        The plant, eqs. (18)-(20); a general plant through its normal form, or, with a
        varying ``lam/mu``, as it is (every analysis by its characteristic route,
        :func:`~nrobust.hyperbolic.loops.varying_form.varying_delay_form`).
    controller : OpenLoop, FiniteTimeController, ReflectionController or FilteredController
        The control law (U_BS eq. (47), U_BS2(K) eq. (53), ...).
    delta_max : float
        Largest loop delay of interest (``> 0``).
    region : tuple, optional
        ``(re_min, re_max, im_min, im_max)`` for the certified root counts; default
        ``(-3, 1, -40, 40) / tau``: about 13 periods ``2 pi / tau`` of the root chains.
    k_region : bool
        For ``ReflectionController``, also compute the admissible gains on
        ``[0, delta_max]`` (:func:`nrobust.hyperbolic.analyses.k_region`).
    n_gains : int, default :data:`~nrobust.hyperbolic.analyses.kregion.DEFAULT_N_GAINS`
        Number of gains, evenly spread in ``|K| < (1 - |rho q|)/|q|``, at which that
        computation also reports (and cross-checks) delay margins (formerly ``k_grid``, a
        deprecated alias). The interval ends do not depend on it: each is solved from the
        equations of its kind and verified to ``KRegion.tol`` (``1e-10`` times the paper's
        bound). When they cannot be verified (e.g. an end so close to the strong-stability
        limit that the crossing search exceeds its work bound), ``k_region`` is None and
        ``k_region_error`` says why.

    rigorous : bool
        Prove the root counts, the spectral abscissa, the delay margin (with its crossing)
        and the Rouché range in ball arithmetic (python-flint, ``pip install
        nrobust[rigorous]``), prove the ends of the admissible gains (``k_region(...,
        rigorous=True)``: the claim "admissible gain ends"), and estimate the model error of
        ``N~`` (:class:`ModelError`).
        Every claim of the certificate (:attr:`Certificate.claims`) says whether it is
        :data:`PROVEN` or :data:`CHECKED`.
    kernel_grid : int, optional
        Default: the exact route where it applies (constant coefficients: ``N~`` in closed
        form, every proven claim a claim about the PDE, :attr:`Certificate.scope`), else
        :data:`~nrobust.hyperbolic.kernels.constant.DEFAULT_KERNEL_GRID` points. Given: the
        kernel grid of every kernel solved here (the characteristic functions, the delay margin
        and the Rouché range; validated by the first of them,
        :func:`~nrobust.hyperbolic.kernels.check_kernel_grid`), a model of the PDE whose
        distance to it :class:`ModelError` estimates.
    accuracy : float, optional
        Target accuracy of the delay margin. On the exact route it is met by the proof or
        the floating-point estimate (:attr:`Certificate.margin_accuracy`); on the kernel
        route the grid is refined (each grid ``2 n - 1`` points, up to
        ``MAX_ACCURACY_GRID``) until the margin moves by less than ``accuracy`` from
        the grid half as fine. :attr:`Certificate.accuracy_statement` says what was
        achieved.

    Returns
    -------
    Certificate
    """
    delta_max = positive("delta_max", delta_max)
    if kernel_grid is not None:
        kernel_grid = check_kernel_grid(kernel_grid)
    if accuracy is not None:
        accuracy = positive("accuracy", accuracy)
        if loop_route(system, controller, kernel_grid) != "exact":
            kernel_grid = _grid_for(system, controller, kernel_grid or DEFAULT_KERNEL_GRID, accuracy)
    given_system, given_controller = system, controller
    if loop_route(system, controller, kernel_grid) != "exact":
        system, controller = normalize(system, controller)  # a general plant: its normal form
    if not np.isfinite(delta_max):
        raise ParameterError("delta_max", "finite", delta_max)
    classification = classify(system)  # also checks the system
    if region is None:
        tau = float(system.tau) / getattr(system, "time_unit", 1.0)  # a varying lam/mu: in its time unit
        box = (_DEFAULT_REGION[0] / tau, _DEFAULT_REGION[1] / tau, _DEFAULT_REGION[2] / tau, _DEFAULT_REGION[3] / tau)
    else:
        box = check_region(region)
    # the algebra of QuasiPolynomial merges kernels on equal nodes: the I_N - I_N of the
    # nominal U_BS and U_BS2 loops cancels exactly
    F0 = characteristic(system, controller, 0.0, kernel_grid=kernel_grid)
    _check_delta_max(delta_max, loop_factors(system, controller, kernel_grid), box, region is None)
    Fd = characteristic(system, controller, delta_max, kernel_grid=kernel_grid)
    if not isinstance(rigorous, (bool, np.bool_)):
        raise ParameterError("rigorous", "True or False", rigorous)
    rigorous = bool(rigorous)
    # one BLAS thread: the small eigenvalue problems (the chains of a difference operator) run
    # slower, and cost more CPU time, when BLAS threads compete for the cores
    with threadpool_limits(1):
        unproven: list[str] = []
        # tau not a double: the counts are proven on the plant's own loop (given_plant_balls), else on F0, Fd
        balls0 = given_plant_balls(system, controller, 0.0, kernel_grid) if rigorous else None
        ballsd = given_plant_balls(system, controller, delta_max, kernel_grid) if rigorous else None
        roots0 = _prove(
            "roots at delta = 0", rigorous, unproven, lambda r: find_roots(F0, box, rigorous=r, balls=balls0)
        )
        rootsd = _prove(
            "roots at delta_max", rigorous, unproven, lambda r: find_roots(Fd, box, rigorous=r, balls=ballsd)
        )
        abscissa = _prove(
            "spectral abscissa",
            rigorous,
            unproven,
            lambda r: to_given_plant(spectral_abscissa(F0, rigorous=r), system, controller, kernel_grid),
        )
        margin, study = _prove(
            "delay margin",
            rigorous,
            unproven,
            lambda r: studied_delay_margin(
                system, controller, delta_max=delta_max, rigorous=r, kernel_grid=kernel_grid
            ),
        )
        if given_system is not system:  # the proofs are about the normal form computed in floating point
            margin = dataclasses.replace(
                margin,
                scope=loop_scope(
                    system, controller, kernel_grid, loop_factors(system, controller, kernel_grid), normal_form=True
                )
                + (study_scope(study) if margin.model_error is not None and study is not None else ""),
            )
        rouche = (
            _prove(
                "Rouché delay range",
                rigorous,
                unproven,
                lambda r: to_given_plant(
                    rouche_delay_bound(system, controller, rigorous=r, kernel_grid=kernel_grid),
                    system,
                    controller,
                    kernel_grid,
                ),
            )
            if isinstance(controller, (ReflectionController, FiniteTimeController))
            else None
        )
        kreg, k_region_error = None, ""
        if k_region and isinstance(controller, ReflectionController) and classification.k_bound > 0:
            n_gains = positive_int("n_gains", n_gains, 3)
            try:
                kreg = analyses.k_region(system, delta_max, n_gains=n_gains, rigorous=rigorous)
            except CertificationError as exc:
                k_region_error = str(exc)
    model_error = _model_error(system, controller, margin, kernel_grid, study)
    if margin.of_model and margin.model_error is None and np.isfinite(model_error.error):
        margin = dataclasses.replace(margin, model_error=model_error.error)  # its repr then carries the accuracy
    return Certificate(
        system=system,
        controller=controller,
        delta_max=delta_max,
        classification=classification,
        principal_nominal=_principal(F0, 0.0, rigorous),
        principal_delayed=_principal(Fd, delta_max, rigorous),
        roots_nominal=roots0,
        roots_delayed=rootsd,
        abscissa=abscissa,
        margin=margin,
        rouche=rouche,
        k_region=kreg,
        region=tuple(float(v) for v in box),  # type: ignore[arg-type]
        versions=_versions(),
        k_region_error=k_region_error,
        rigorous=rigorous,
        claims=_claims(
            margin,
            roots0,
            rootsd,
            abscissa,
            rouche,
            kreg,
            delta_max,
            _unstable_witness(Fd, rigorous, ballsd) if margin.margin <= delta_max else None,
        ),
        model_error=model_error,
        unproven=tuple(unproven),
        kernel_grid=kernel_grid,
        accuracy_target=accuracy,
        given_system=None if given_system is system else given_system,
        given_controller=None if given_system is system else given_controller,
    )


def _grid_for(system: Any, controller: Controller, grid: int, accuracy: float) -> int:
    """The first grid ``n, 2 n - 1, ...`` on which the margin moves by less than ``accuracy`` from ``(n + 1) / 2``."""
    while (grid - 1) // 2 + 1 < MIN_KERNEL_GRID:
        grid = 2 * grid - 1
    coarse = studied_delay_margin(system, controller, kernel_grid=(grid - 1) // 2 + 1, verify=False, study=False)[
        0
    ].margin
    while True:
        fine = studied_delay_margin(system, controller, kernel_grid=grid, verify=False, study=False)[0].margin
        if _difference(fine, coarse) <= accuracy or 2 * grid - 1 > MAX_ACCURACY_GRID:
            return grid
        grid, coarse = 2 * grid - 1, fine  # the fine margin is the next grid's coarse one


def _check_delta_max(
    delta_max: float, factors: tuple[QuasiPolynomial, QuasiPolynomial], box: tuple[float, ...], default_region: bool
) -> None:
    """Refuse a ``delta_max`` whose loop ``A + B e^{-delta_max s}`` double precision cannot represent on ``box``.

    Two limits: ``e^{-(tau + delta_max) s}`` must stay finite on the left edge of ``box``
    (``tau`` the longest delay of ``B``), and the nodes of the kernels of ``B``, shifted by
    ``delta_max``, must stay apart (their spacing above the rounding of ``delta_max``). A term
    whose stored kernel is zero (zero within its radius) moves onto the doubles enclosing its
    shifted support however short it is (:meth:`~nrobust.quasipoly.DistributedDelay.shift`).
    """
    B = factors[1]
    limits = []
    if box[0] < 0.0:
        limits.append(_LOG_MAX / -box[0] - B.max_delay)
    spacings = [
        np.min(np.diff(d.nodes)[np.diff(d.nodes) > 0.0], initial=np.inf) for d in B.distributed if np.any(d.pieces[2])
    ]
    limits.append(min(spacings, default=np.inf) * 2.0**_NODE_BITS)
    limit = min(limits)
    if delta_max > limit:
        where = "the default region" if default_region else "the region"
        raise ParameterError(
            "delta_max",
            f"in (0, {lower_bound_text(limit)}] for this loop and {where} (Re s >= {box[0]:.6g}): beyond, the "
            "delayed loop e^{-(tau + delta_max) s} overflows double precision there, or its kernel nodes merge",
            delta_max,
        )


_T = TypeVar("_T")


def _prove(name: str, rigorous: bool, unproven: list[str], compute: Callable[[bool], _T]) -> _T:
    """``compute(rigorous)``; when the proof is refused, the floating-point result, and why in ``unproven``."""
    if not rigorous:
        return compute(False)
    try:
        return compute(True)
    except CertificationError as exc:
        unproven.append(f"{name}: not proven in ball arithmetic ({exc}); checked in floating point")
        return compute(False)
