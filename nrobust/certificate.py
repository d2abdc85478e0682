"""Certificates: every number that decides the delay robustness of one closed loop.

:func:`certify` runs the whole analysis of a plant and a controller and returns a
:class:`Certificate`: the paper's classification by ``|rho q|`` (sections 2 and 3), the
closed-loop difference operator with its ``gamma_0`` and strong stability (Hale and
Verduyn Lunel; eq. (eq_rho_q), eq. (boun_K2)), certified root counts per box at
``delta = 0`` and ``delta = delta_max``, the spectral abscissa, the exact delay margin
with its crossing frequency, the Rouché bound ``delta_0`` from the proof of Theorem 4,
and, for ``U_BS2(K)``, the gains ``K`` that keep the loop stable for every delay in
``[0, delta_max]``. Nothing in a certificate is typed in by hand: each field is the
output of the function named in its docstring, with the parameters and library versions
that produced it.
"""

from __future__ import annotations

import json
import platform
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy

from ._json import fields_dict, json_safe
from ._validate import positive, positive_int, renamed_keywords
from ._validate import region as check_region
from ._version import __version__
from .bounds import RoucheDelayBound
from .errors import CertificationError, ParameterError
from .hyperbolic import studies
from .hyperbolic.controllers import (
    Classification,
    Controller,
    FiniteTimeController,
    ReflectionController,
    characteristic,
    classify,
)
from .hyperbolic.robustness import rouche_delay_bound
from .hyperbolic.studies import DEFAULT_N_GAINS, KRegion, delay_margin
from .hyperbolic.system import Hyperbolic2x2
from .margins import DelayMargin
from .quasipoly import QuasiPolynomial
from .roots import RootSet, SpectralAbscissa, find_roots, spectral_abscissa

__all__ = ["Certificate", "PrincipalPart", "certify"]

#: Default search rectangle for the certified root counts, in units of ``1/tau``.
_DEFAULT_REGION = (-3.0, 1.0, -40.0, 40.0)


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
        ``sum_{k >= 1} |a_k| / |a_0|``; for U_BS this is ``2 |rho q|`` (eq. (eq_rho_q)), for
        U_BS2(K) ``|rho q| + |K q|`` (eq. (boun_K2)).
    strongly_stable : bool
        ``gamma_0 < 1``: the loop's high-frequency chains stay in ``Re s < 0`` for every
        small delay (Hale and Verduyn Lunel).
    strong_spectral_bound : float
        ``C_D``, the supremum of the chains' abscissa over small delay perturbations.
    spectral_bound : float
        ``c_D``, the abscissa of the rightmost chain at this very delay (exact for
        commensurate delays, the certified upper end of its bracket otherwise).
    chains : tuple of float
        Abscissae ``Re s`` of the root chains, rightmost first (commensurate delays only).
    """

    delta: float
    coefs: tuple[float, ...]
    delays: tuple[float, ...]
    gamma_0: float
    strongly_stable: bool
    strong_spectral_bound: float
    spectral_bound: float
    chains: tuple[float, ...]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (infinities as strings)."""
        return fields_dict(self)


def _principal(F: QuasiPolynomial, delta: float) -> PrincipalPart:
    D = F.principal_part()
    chains = D.chains()
    bound = chains.bracket[1]  # c_D when commensurate, else the certified upper end
    return PrincipalPart(
        float(delta),
        tuple(float(np.real(a)) for a in D.coefs),
        tuple(float(t) for t in D.delays),
        float(D.gamma_0),
        bool(D.is_strongly_stable()),
        float(D.strong_spectral_bound()),
        float(bound),
        tuple(float(c.real) for c in chains.chains),
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
        :func:`nrobust.hyperbolic.robustness.rouche_delay_bound` (U_BS and U_BS2 only).
    k_region : object or None
        :func:`nrobust.hyperbolic.studies.k_region` for ``U_BS2(K)``: the gains ``K`` keeping every
        delay in ``[0, delta_max]`` stable, each end solved from its own equations and verified
        (``KRegion.ends`` gives its kind: crossing, pair birth, nominal, strong-stability limit).
    region : tuple of float
        The rectangle of the root counts.
    versions : dict
        nrobust, numpy, scipy and python versions.
    k_region_error : str
        Why the admissible gains could not be certified (the
        :class:`~nrobust.errors.CertificationError` of ``k_region``, which is then None);
        empty otherwise.
    """

    system: Hyperbolic2x2
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
        if self.stable_up_to_delta_max:
            return (
                f"{name}: delay-robust, stable for every delay in [0, {self.delta_max:g}] "
                f"(delay margin {self.delay_margin:.6g})."
            )
        return f"{name}: delay-robust with margin {self.delay_margin:.6g} < delta_max = {self.delta_max:g}."

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
            "stable_up_to_delta_max": self.stable_up_to_delta_max,
        }
        fields = {("spectral_abscissa" if k == "abscissa" else k): v for k, v in fields_dict(self).items()}
        return {**json_safe(verdicts), **fields}

    def to_json(self, indent: int | None = 2) -> str:
        """The certificate as JSON text (strict: no NaN or infinity literals)."""
        return json.dumps(self.to_dict(), indent=indent, allow_nan=False)

    def __repr__(self) -> str:
        return (
            f"Certificate({type(self.controller).__name__}, delta_max={self.delta_max:g}, "
            f"margin={self.delay_margin:.6g}, nominally_stable={self.nominally_stable}, "
            f"delay_robust={self.delay_robust})"
        )


@renamed_keywords(k_grid="n_gains")
def certify(
    system: Hyperbolic2x2,
    controller: Controller,
    delta_max: float = 0.1,
    region: tuple[float, float, float, float] | None = None,
    k_region: bool = True,
    n_gains: int = DEFAULT_N_GAINS,
) -> Certificate:
    """Certify the delay robustness of a plant and a controller on ``[0, delta_max]``.

    Parameters
    ----------
    system : Hyperbolic2x2 or TransportSystem
        The plant, eqs. (u_pde)-(IC).
    controller : OpenLoop, FiniteTimeController, ReflectionController or FilteredController
        The control law (U_BS eq. (control), U_BS2(K) eq. (control3), ...).
    delta_max : float
        Largest loop delay of interest (``> 0``).
    region : tuple, optional
        ``(re_min, re_max, im_min, im_max)`` for the certified root counts; default
        ``(-3, 1, -40, 40) / tau``: about 13 periods ``2 pi / tau`` of the root chains.
    k_region : bool
        For ``ReflectionController``, also compute the admissible gains on
        ``[0, delta_max]`` (:func:`nrobust.hyperbolic.studies.k_region`).
    n_gains : int, default :data:`~nrobust.hyperbolic.studies.DEFAULT_N_GAINS`
        Number of gains, evenly spread in ``|K| < (1 - |rho q|)/|q|``, at which that
        computation also reports (and cross-checks) delay margins (formerly ``k_grid``, a
        deprecated alias). The interval ends do not depend on it: each is solved from the
        equations of its kind and verified to ``KRegion.tol`` (``1e-10`` times the paper's
        bound). When they cannot be verified (e.g. an end so close to the strong-stability
        limit that the crossing search exceeds its work bound), ``k_region`` is None and
        ``k_region_error`` says why.

    Returns
    -------
    Certificate
    """
    delta_max = positive("delta_max", delta_max)
    if not np.isfinite(delta_max):
        raise ParameterError("delta_max", "finite", delta_max)
    classification = classify(system)  # also checks the system
    if region is None:
        tau = float(system.tau)
        box = (_DEFAULT_REGION[0] / tau, _DEFAULT_REGION[1] / tau, _DEFAULT_REGION[2] / tau, _DEFAULT_REGION[3] / tau)
    else:
        box = check_region(region)
    # the algebra of QuasiPolynomial merges kernels on equal nodes: the I_N - I_N of the
    # nominal U_BS and U_BS2 loops cancels exactly
    F0 = characteristic(system, controller, 0.0)
    Fd = characteristic(system, controller, delta_max)
    roots0 = find_roots(F0, box)
    rootsd = find_roots(Fd, box)
    abscissa = spectral_abscissa(F0)
    margin = delay_margin(system, controller, delta_max=delta_max)
    rouche = (
        rouche_delay_bound(system, controller)
        if isinstance(controller, (ReflectionController, FiniteTimeController))
        else None
    )
    kreg, k_region_error = None, ""
    if k_region and isinstance(controller, ReflectionController) and classification.k_bound > 0:
        n_gains = positive_int("n_gains", n_gains, 3)
        try:
            kreg = studies.k_region(system, delta_max, n_gains=n_gains)
        except CertificationError as exc:
            k_region_error = str(exc)
    return Certificate(
        system=system,
        controller=controller,
        delta_max=delta_max,
        classification=classification,
        principal_nominal=_principal(F0, 0.0),
        principal_delayed=_principal(Fd, delta_max),
        roots_nominal=roots0,
        roots_delayed=rootsd,
        abscissa=abscissa,
        margin=margin,
        rouche=rouche,
        k_region=kreg,
        region=tuple(float(v) for v in box),  # type: ignore[arg-type]
        versions=_versions(),
        k_region_error=k_region_error,
    )
