"""The delay margin of ``F(s; delta) = A(s) + B(s) e^{-delta s}`` and its stability windows.

The number of unstable roots is piecewise constant in ``delta`` and changes only at the
crossing delays of :mod:`nrobust.margins.crossing`, so a certified count at ``delta = 0`` and the
signed crossings give it for every ``delta``: stability windows included. The crossing
search is complete and classifies every crossing (simple, with a certified direction, or
a tangency), so this count is right by construction, with or without ``verify``; the
verification is an independent check by the argument principle, and a count that the
crossings would make negative is reported as an error, never returned. The loops of the
paper's plants (:func:`nrobust.hyperbolic.loop_factors`: for ``U_BS2(K)``,
eq. (60), ``A = 1 - Phi`` and ``B = K q e^{-tau s} - I_N``) are studied
with :mod:`nrobust.hyperbolic.analyses`.

Tangencies: a tangency at ``(w, delta_c)`` (a double zero in ``w`` of
``|A(i w)|^2 - |B(i w)|^2``) puts a root on the axis at ``delta_c`` that returns to the
left half-plane: the count does not change, but the loop is not exponentially stable at
that single delay. The margin is therefore the first delay at which a root lies on the
axis, tangencies included, and the stability windows (open intervals) exclude every
tangency delay: a window ends at it and the next one starts there.
"""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._digits import with_accuracy
from .._json import fields_dict
from .._validate import positive_int
from ..bounds import joint_degree, principal_gap, root_free_region
from ..errors import CertificationError, ParameterError
from ..quasipoly import QuasiPolynomial, as_quasipolynomial
from .axis import AxisGap, frequency_bound, is_zero
from .count import unstable_count
from .crossing import ZERO_TOL, Crossing, CrossingSearch, axis_crossings, common_axis_zeros, crossing_search
from .proven import ProvenCrossings, proven_crossings, proven_gap, proven_zero_radius, proven_zero_root

__all__ = ["DelayMargin", "delay_margin"]


# ============================================================================ delay margin
@dataclass(frozen=True)
class DelayMargin:
    """Delay margin of ``F(s; delta) = A(s) + B(s) e^{-delta s}`` and its stability intervals.

    Attributes
    ----------
    margin : float
        ``delta*``: the loop is exponentially stable for every ``delta`` in
        ``[0, delta*)`` and not at ``delta*``, where a root lies on the imaginary axis
        (the first destabilising crossing, or an earlier tangency). 0 when the nominal
        loop is not stable or the difference operator is not strongly stable for small
        ``delta > 0`` (the paper's zero margin, Theorem 3); ``inf`` when no crossing
        exists, or when ``A`` or ``B`` is identically zero and the other is stable (the
        loop does not depend on the delay).
    omega : float or None
        Crossing frequency at which the margin is reached.
    crossings : tuple of Crossing
        Every crossing frequency with its delays up to ``delta_max``.
    nominally_stable : bool
        The loop with ``delta = 0`` is exponentially stable.
    nominal_unstable : int or None
        Certified number of zeros of ``F(.; 0)`` with ``Re s > 0`` (None when a zero
        lies on the imaginary axis or no count was possible).
    strongly_stable : bool
        The difference operator of ``F(.; delta)`` is strongly stable for small delays.
    zero_root : bool
        ``A(0) + B(0) = 0``: ``s = 0`` is a root for every delta.
    intervals : tuple of (float, float)
        Maximal open delay intervals in ``[0, delta_max]`` on which the loop is
        exponentially stable (``[0, hi)`` when it includes the nominal loop). Crossing
        delays, tangencies included, are never inside a window.
    counts : tuple of (float, float, int)
        Number of zeros with ``Re s > 0`` on each interval between crossing delays.
    delta_max : float
        Range of delays covered by ``intervals``.
    frequency_bound : float or None
        ``W``: no crossing (and no zero in ``Re s >= 0``) for ``|s| > W``, every delta.
    gap : float
        ``|a_0| - sum |others|`` of the principal terms (``> 0`` iff strongly stable).
        :attr:`gap_accuracy` bounds its error.
    verified : bool
        The margin was checked independently: a certified count by the argument
        principle (on the boundary of the half disc of radius ``1.01 W``, the imaginary
        axis sampled on chirp-z grids; :func:`nrobust.count_roots` where that does not
        apply) finds no zero in ``Re s > 0`` at ``delta* (1 - 1e-3)``. The residual below
        is checked with or without verification.
    residual : float or None
        ``|F(i w; delta*)| / (|A| + |B|)`` at the margin (at rounding level, else a
        :class:`CertificationError` is raised).
    reason : str
        How the margin was decided, in words.
    evaluations : int
        Evaluations of ``A`` and ``B`` spent by the crossing search.
    rigorous : bool
        True when the margin is proven in ball arithmetic (``delay_margin(..., rigorous=True)``):
        the nominal count by :func:`nrobust.count_roots` with ``rigorous=True``, the crossing
        set by :func:`nrobust.margins.proven.proven_crossings` and ``delta*`` enclosed in
        ``margin_ball``; a theorem about ``A`` and ``B`` as represented.
    margin_ball : (float, float) or None
        With ``rigorous``: ``(lo, hi)`` with ``lo <= delta* <= hi`` proven (``margin`` lies
        inside); None otherwise.
    scope : str
        What the margin is about when it came from a plant (set by the plant-level
        ``delay_margin``: the PDE itself, or a model of it); empty for ``A, B`` given
        directly, where it is about ``A`` and ``B`` as represented.
    of_model : bool
        True when ``A`` and ``B`` are a model of the plant (kernels on a grid): the margin's
        distance to the plant's is then not known here (:attr:`accuracy` is None), unless
        :attr:`model_error` estimates it.
    omega_error : float or None
        A bound of ``|omega - w|``, ``w`` the exact crossing frequency of ``A`` and ``B`` as
        represented (:attr:`omega_accuracy` is the one to print): with ``rigorous`` the
        distance from ``omega`` to the far end of its proven enclosure
        (:attr:`~nrobust.margins.proven.ProvenCrossings.omegas`); in floating point the estimate
        ``16 (|g| + eps (M_A^2 + M_B^2)) / |g'| + eps |omega|`` from the residual of
        ``g(w) = |A(i w)|^2 - |B(i w)|^2`` (``M`` the sums of the moduli of the monomials,
        :meth:`~nrobust.quasipoly.QuasiPolynomial.magnitude`; the factor 16 is 20 times the
        largest ratio, 0.76, of the true error, closed form or mpmath at 40 digits, to the
        unscaled estimate, measured on ``s + a + b e^{-delta s}`` and the paper's plant).
        0 for ``omega = 0`` at ``s = 0``; None without ``omega`` or at a tangency (``g' = 0``:
        a double zero).
    model_error : float or None
        For a model (:attr:`of_model`): an estimate of the margin's change from the model's
        error, set by the plant-level ``delay_margin`` when the model states its own accuracy
        (an output feedback's observer term) or from a convergence study in the kernel grid (the
        kernel route: floating point, not proven); it is added to :attr:`accuracy`. None: not
        estimated here.
    omega_model_error : float or None
        For a model: an estimate of the crossing frequency's change from the model's error, set
        with :attr:`model_error`; it is added to :attr:`omega_accuracy`. None: not estimated here.
    gap_accuracy : float or None
        A bound of ``|gap - g|``, ``g`` the principal gap of ``A`` and ``B`` as represented: with
        ``rigorous`` the distance from ``gap`` to the far end of its enclosure in ball arithmetic
        (:func:`~nrobust.margins.proven.proven_gap`, proven), else the rounding bound of its
        floating-point sum (:attr:`nrobust.bounds.PrincipalGap.error`); 0 for an advanced-type
        loop (``gap = -inf``). A gap within it of 0 is zero to rounding. None: not known.
    """

    margin: float
    omega: float | None
    crossings: tuple[Crossing, ...]
    nominally_stable: bool
    nominal_unstable: int | None
    strongly_stable: bool
    zero_root: bool
    intervals: tuple[tuple[float, float], ...]
    counts: tuple[tuple[float, float, int], ...]
    delta_max: float
    frequency_bound: float | None
    gap: float
    verified: bool
    residual: float | None
    reason: str
    evaluations: int = field(default=0)
    rigorous: bool = False
    margin_ball: tuple[float, float] | None = None
    scope: str = ""
    of_model: bool = False
    omega_error: float | None = None
    model_error: float | None = None
    omega_model_error: float | None = None
    gap_accuracy: float | None = None

    def __post_init__(self) -> None:
        # the crossings carry the accuracies this margin states: the margin's crossing its
        # omega_accuracy and accuracy, the others theirs about A and B, withdrawn for a model
        own = [c.omega == self.omega and bool(c.delays) and c.delays[0] == self.margin for c in self.crossings]
        if any(own) or self.of_model:
            crossings = tuple(self._stated(c, mine) for c, mine in zip(self.crossings, own))
            object.__setattr__(self, "crossings", crossings)

    def _stated(self, crossing: Crossing, own: bool) -> Crossing:
        """``crossing`` with the accuracies this margin states: the margin's on its own first delay; none
        on a model's other crossings and delays (their distance to the plant's is not estimated)."""
        if not own and not self.of_model:
            return crossing
        model = (None,) * len(crossing.delays) if self.of_model else crossing.delay_accuracies
        if not own:
            return replace(crossing, omega_accuracy=None, delay_accuracy=None, delay_accuracies=model)
        rest = tuple(model[1:]) if len(model) == len(crossing.delays) else (None,) * (len(crossing.delays) - 1)
        return replace(
            crossing,
            omega_accuracy=self.omega_accuracy,
            delay_accuracy=self.accuracy,
            delay_accuracies=(self.accuracy, *rest),
        )

    @property
    def omega_accuracy(self) -> float | None:
        """A bound of ``|omega - w|`` (proven with ``rigorous``, else an estimate: :attr:`omega_error`);
        for a model of the plant (:attr:`of_model`) :attr:`omega_model_error` is added, None when it is
        not known (its distance to the plant's crossing is not estimated here)."""
        if not self.of_model:
            return self.omega_error
        if self.omega_error is None or self.omega_model_error is None:
            return None
        return self.omega_error + self.omega_model_error

    @property
    def accuracy(self) -> float | None:
        """A bound of ``|margin - delta*|``: proven, or a conservative estimate; None if unknown.

        With ``rigorous``: the distance from ``margin`` to the far end of ``margin_ball``
        (proven). A margin of 0 or ``inf`` decided by the structure of the loop: 0. Otherwise
        the floating-point estimate ``max(1e-12 |margin|, 20 residual / omega)``: the
        crossing's residual turned into a delay through ``|dF/d delta| = omega |B|`` (``|A| =
        |B|`` there), with a floor 1000 times the largest distance to the proven ball measured
        on the test plants (3e-16 relative), plus the crossing frequency's error carried by the
        slope of the crossing delay in the frequency (``_from_omega``: just past a pair birth,
        where that slope is steep, the residual alone understated the error). For a model of
        the plant (:attr:`of_model`, the kernel route:
        ``nrobust.hyperbolic.loops.controllers.loop_route(...) == "kernels"``)
        :attr:`model_error`, its estimated distance to the plant's margin, is added; None when
        it is not known, with ``rigorous`` too (the ball is proven about the model, not the
        plant): the plant-level ``delay_margin`` estimates it by a convergence study in the kernel grid.
        """
        if self.of_model and self.model_error is None:
            return None  # a ball proven about a model says nothing of the plant's margin
        model = self.model_error if self.of_model and self.model_error is not None else 0.0
        if self.margin_ball is not None:
            lo, hi = self.margin_ball
            radius = max(hi - self.margin, self.margin - lo)
            return (float(np.nextafter(radius, np.inf)) if radius > 0.0 else 0.0) + model
        if not np.isfinite(self.margin) or self.margin == 0.0:
            return 0.0
        if self.omega is None or self.residual is None:
            return None
        from_residual = max(1e-12 * abs(self.margin), 20.0 * float(self.residual) / max(float(self.omega), 1e-300))
        return from_residual + self._from_omega() + model

    def _from_omega(self) -> float:
        """The margin's error carried by the crossing frequency's: ``|d delta/d omega| omega_error``.

        ``delta(omega) = (arg(-B/A)(i omega) + 2 pi k) / omega`` on the crossing's phase; at the
        crossing, with ``d = ds/d delta`` the root's sensitivity, ``d delta/d omega =
        Im(d) / |d|^2`` (``F_delta = i omega A``, ``F_s = A (A'/A - B'/B + delta)``). The residual
        alone misses it: a frequency off the curve ``|A| = |B|`` by ``e`` leaves a residual of
        order ``e |g'|`` whatever the slope of the phase.
        """
        crossing = next((c for c in self.crossings if c.omega == self.omega), None)
        if crossing is None or self.omega_error is None:
            return 0.0
        d = complex(crossing.ds_ddelta)
        if d == 0.0:
            return float("inf")
        return float(self.omega_error) * abs(d.imag) / abs(d) ** 2

    def end_accuracy(self, delay: float) -> float | None:
        """A bound of the error of ``delay``, an end of :attr:`intervals`; None when not estimated.

        0 for ``delay = 0`` and for :attr:`delta_max` when it is not a crossing delay (given, not
        computed); :attr:`accuracy` for the margin; for a crossing delay its
        :attr:`~nrobust.margins.crossing.Crossing.delay_accuracies` entry.
        """
        crossings = [c for c in self.crossings if delay in c.delays]
        if delay == 0.0 or (delay == self.delta_max and not crossings):
            return 0.0
        if delay == self.margin:
            return self.accuracy
        for c in crossings:
            k = c.delays.index(delay)
            if k < len(c.delay_accuracies):
                return c.delay_accuracies[k]
        return None

    @property
    def without_crossing(self) -> bool:
        """True for a margin decided with no crossing to verify: ``inf``, or 0 with no crossing frequency.

        ``verified`` (a crossing's residual and count checked) is then not needed: the reports'
        verified row and a sweep's ``verified`` column say so.
        """
        return bool(np.isposinf(self.margin) or (self.margin == 0.0 and self.omega is None))

    @property
    def method(self) -> str:
        """``"ball arithmetic"`` (``rigorous=True``: proven) or ``"floating point"`` (checked)."""
        return "ball arithmetic" if self.rigorous else "floating point"

    @property
    def nominal_stable(self) -> bool:
        """Deprecated alias of :attr:`nominally_stable` (the name :class:`nrobust.Certificate` uses)."""
        warnings.warn(
            "DelayMargin.nominal_stable is deprecated, use DelayMargin.nominally_stable",
            DeprecationWarning,
            stacklevel=2,
        )
        return self.nominally_stable

    def is_stable(self, delta: ArrayLike) -> NDArray[np.bool_]:
        """Exponential stability at each ``delta`` in ``[0, delta_max]`` (from the intervals)."""
        d = np.asarray(delta, dtype=float)
        if np.any(d < 0) or np.any(d > self.delta_max):
            raise ParameterError("delta", f"in [0, delta_max = {self.delta_max:.6g}]", delta)
        out = np.zeros(d.shape, dtype=bool)
        for lo, hi in self.intervals:
            closed = hi == self.delta_max and not any(hi in c.delays for c in self.crossings)
            out |= ((d > lo) | ((lo == 0.0) & (d == 0.0) & self.nominally_stable)) & ((d < hi) | (closed & (d == hi)))
        return out

    def unstable_count(self, delta: ArrayLike) -> NDArray[np.int64]:
        """Number of zeros with ``Re s > 0`` at each ``delta`` (-1 on a crossing delay)."""
        d = np.asarray(delta, dtype=float)
        if np.any(d < 0) or np.any(d > self.delta_max):
            raise ParameterError("delta", f"in [0, delta_max = {self.delta_max:.6g}]", delta)
        out = np.full(d.shape, -1, dtype=np.int64)
        for lo, hi, n in self.counts:
            closed = hi == self.delta_max and not any(hi in c.delays for c in self.crossings)
            out[(d > lo) & ((d < hi) | (closed & (d == hi)))] = n
        if self.nominal_unstable is not None:
            out[d == 0.0] = self.nominal_unstable
        return out

    def __repr__(self) -> str:
        w = "None" if self.omega is None else with_accuracy(self.omega, self.omega_accuracy)
        return (
            f"DelayMargin(margin={with_accuracy(self.margin, self.accuracy)}, omega={w}, "
            f"crossings={len(self.crossings)}, "
            f"nominally_stable={self.nominally_stable}, strongly_stable={self.strongly_stable}, "
            f"windows={len(self.intervals)}, verified={self.verified}, reason={self.reason!r})"
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (infinities as strings)."""
        return fields_dict(self)


def _margin_ball(proof: ProvenCrossings, zero_root: bool, nominal: int | None) -> tuple[float, float]:
    """Enclosure of ``delta*`` from the proven crossings and the proven nominal count; raises what is not proven."""
    if zero_root:
        return (0.0, 0.0)
    if nominal is None:
        raise CertificationError(
            "delay_margin(rigorous=True): the number of zeros of A + B in Re s >= 0 is not proven (a zero on or "
            "within the ball radii of the imaginary axis at delta = 0)"
        )
    if nominal > 0:
        return (0.0, 0.0)
    ball = proof.margin_ball()
    first = min((lo for lo, _ in proof.unresolved_delays), default=float("inf"))
    if ball is None:
        if proof.unresolved:
            raise CertificationError(
                f"delay_margin(rigorous=True): no proven crossing, but tangencies to rounding at w in "
                f"{list(proof.unresolved)}: whether a root touches the axis there is not decided in ball arithmetic"
            )
        return (float("inf"), float("inf"))
    if first <= ball[1]:
        raise CertificationError(
            f"delay_margin(rigorous=True): a tangency to rounding (w in {list(proof.unresolved)}, delays from "
            f"{first:.12g}) may come before the first proven crossing (delay <= {ball[1]:.12g}); ball arithmetic "
            "cannot tell a double zero from two close zeros or none"
        )
    return ball


def _delay_max(value: Any) -> float | None:
    """``delta_max`` as None, ``inf`` or a positive float; NaN, ``-inf`` and non-positive values raise."""
    if value is None:
        return None
    expected = "a positive number or inf (None: one period past every crossing delay)"
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ParameterError("delta_max", expected, value)
    if not float(value) > 0.0:  # NaN, -inf, 0 and negative numbers
        raise ParameterError("delta_max", expected, value)
    return float(value)


def _delay_free(P: QuasiPolynomial, which: str, zero_root: bool, delta_max: float | None) -> DelayMargin:
    """The loop ``F = P`` (``which`` factor identically zero): no delay enters, one certified count decides.

    A zero of ``P`` on (or within rounding of) the imaginary axis makes the count move its
    left edge: the loop is then not exponentially stable and ``nominal_unstable`` is None.
    """
    principal = principal_gap({"P": (P, 0)}, joint_degree(P), 0.0)
    gap = float("-inf") if principal is None else principal.gap
    gap_accuracy = 0.0 if principal is None else principal.error
    nominal: int | None = None
    radius: float | None = None
    if principal is not None and gap > 0.0 and not zero_root:
        try:
            radius = root_free_region(P).radius
            nominal = unstable_count(P, radius).count
        except (ParameterError, CertificationError):
            nominal = None
    stable = nominal == 0
    d_max = float("inf") if delta_max is None else delta_max
    other = "A" if which == "B" else "B e^{-delta s}"
    return DelayMargin(
        margin=float("inf") if stable else 0.0,
        omega=None,
        crossings=(),
        nominally_stable=stable,
        nominal_unstable=nominal,
        strongly_stable=gap > 0.0,
        zero_root=zero_root,
        intervals=((0.0, d_max),) if stable else (),
        counts=((0.0, d_max, nominal),) if nominal is not None else (),
        delta_max=d_max,
        frequency_bound=radius,
        gap=gap,
        gap_accuracy=gap_accuracy,
        verified=False,
        residual=None,
        reason=(
            f"{which} is identically zero: the loop {other} does not depend on the delay and is "
            + ("exponentially stable" if stable else "not exponentially stable")
        ),
    )


# Longest delay of A and B: the term scales of the crossing search hold 8 tau^3 (margins/axis.py).
_MAX_DELAY = float((np.finfo(float).max / 8.0) ** (1.0 / 3.0))


def _validated(
    A: Any, B: Any, delta_max: Any, max_evals: Any, rigorous: Any
) -> tuple[QuasiPolynomial, QuasiPolynomial, float | None, int]:
    """Step 1, validation: the factors as quasi-polynomials (not both zero), ``delta_max`` and ``max_evals``."""
    A, B = as_quasipolynomial("A", A), as_quasipolynomial("B", B)
    max_evals = positive_int("max_evals", max_evals)
    delta_max = _delay_max(delta_max)
    if not isinstance(rigorous, (bool, np.bool_)):
        raise ParameterError("rigorous", "True or False", rigorous)
    if is_zero(A) and is_zero(B):
        raise ParameterError("A, B", "not both identically zero (F(s; delta) would vanish for every s)", (A, B))
    longest = max(A.max_delay, B.max_delay)
    if longest > _MAX_DELAY:
        raise ParameterError(
            "delays",
            f"at most {_MAX_DELAY:.3g} (the longest delay of A and B: the bounds of the crossing search hold "
            "tau^3, which overflows double precision beyond)",
            longest,
        )
    return A, B, delta_max, max_evals


def _zero_root(A: QuasiPolynomial, B: QuasiPolynomial, rigorous: bool) -> bool:
    """``A(0) + B(0) = 0`` (``s = 0`` a root for every delay): to ``ZERO_TOL``, or proven with ``rigorous``.

    With ``rigorous`` a factor identically zero raises: the loop does not depend on the
    delay, and its stability is a count (``count_roots(..., rigorous=True)``).
    """
    a0, b0 = complex(A(np.array([0j]))[0]), complex(B(np.array([0j]))[0])
    zero_root = abs(a0 + b0) <= ZERO_TOL * max(abs(a0) + abs(b0), 1e-300)
    if rigorous:
        zero_root = proven_zero_root(A, B)
        if is_zero(B) or is_zero(A):
            raise CertificationError(
                "delay_margin(rigorous=True): A or B is identically zero, the loop does not depend on the delay; "
                "prove its stability with count_roots(..., rigorous=True)"
            )
    return zero_root


def _principal_gap(A: QuasiPolynomial, B: QuasiPolynomial, rigorous: bool) -> tuple[float, float]:
    """The principal gap ``|a_0| - sum |others|`` of the loop (``-inf`` for an advanced-type loop) and a
    bound of its error (:attr:`DelayMargin.gap_accuracy`: proven with ``rigorous``)."""
    principal = principal_gap({"A": (A, 0), "B": (B, 1)}, joint_degree(A, B), 0.0)
    if principal is None:
        return float("-inf"), 0.0
    return principal.gap, _gap_accuracy(A, B, principal.gap, principal.error, rigorous)


def _gap_accuracy(A: QuasiPolynomial, B: QuasiPolynomial, gap: float, rounding: float, rigorous: bool) -> float:
    """A bound of the error of ``gap``: the distance to the far end of :func:`proven_gap` with ``rigorous``
    (proven), else ``rounding`` (:attr:`~nrobust.bounds.PrincipalGap.error`); 0 for ``gap = -inf``."""
    if not np.isfinite(gap):
        return 0.0
    return _far_end(gap, proven_gap(A, B)) if rigorous else rounding


def _far_end(x: float, ball: tuple[float, float]) -> float:
    """The distance from ``x`` to the far end of ``ball``, rounded up."""
    return float(np.nextafter(max(ball[1] - x, x - ball[0], 0.0), np.inf))


def _proven_zero_root(A: QuasiPolynomial, B: QuasiPolynomial, delta_max: float | None) -> DelayMargin:
    """The rigorous route when ``A(0) + B(0) = 0`` is proven: margin 0 whatever the crossings."""
    gap, gap_accuracy = _principal_gap(A, B, True)
    return DelayMargin(
        margin=0.0,
        omega=0.0,
        crossings=(),
        nominally_stable=False,
        nominal_unstable=None,
        strongly_stable=gap > 0.0,
        zero_root=True,
        intervals=(),
        counts=(),
        delta_max=float("inf") if delta_max is None else delta_max,
        frequency_bound=None,
        gap=gap,
        gap_accuracy=gap_accuracy,
        verified=False,
        residual=None,
        reason="s = 0 is a root for every delay (A(0) + B(0) = 0 exactly, in ball arithmetic)",
        rigorous=True,
        margin_ball=(0.0, 0.0),
        omega_error=0.0,
    )


#: Work bound of the proof tried where the floating-point gap is zero to its accuracy and the ball gap positive: a
#: loop with no crossing (every delay stable) is proven at once; a frequency bound near ``1/gap`` is beyond it.
ZERO_GAP_EVALS = 20_000


def _zero_gap_decided(
    A: QuasiPolynomial, B: QuasiPolynomial, gap: float, gap_accuracy: float, delta_max: float | None
) -> DelayMargin | str:
    """A gap zero to its floating-point accuracy, decided in ball arithmetic where it can be.

    The floating-point gap ``0 +- r`` does not say whether the difference operator is strongly stable; the gap in
    ball arithmetic (:func:`~nrobust.margins.proven.proven_gap`) does when it is negative or exactly zero (the
    margin is 0: returns ``""``). A positive one means a strongly stable loop: its proven margin when the search in
    ball arithmetic decides within :data:`ZERO_GAP_EVALS` (a loop with no crossing, say), else the words the zero
    margin's reason adds (it is 0 after changes of the coefficients of the gap's size, not decided for them as given).
    """
    try:
        lo, hi = proven_gap(A, B)
    except ImportError:  # python-flint is an extra: without it the zero margin stands as the float gap has it
        return "; ball arithmetic (pip install nrobust[rigorous]) would decide the gap's sign"
    if hi < 0.0 or lo == hi == 0.0:
        return ""
    if lo > 0.0:
        try:
            return delay_margin(A, B, delta_max=delta_max, max_evals=ZERO_GAP_EVALS, rigorous=True)
        except CertificationError:
            pass
        return (
            f"; in ball arithmetic the gap is [{lo:.3g}, {hi:.3g}] > 0: strongly stable for the coefficients as "
            "given, with a frequency bound beyond reach: the margin is 0 after changes of the coefficients of the "
            "gap's size, and not decided for them as given (delay_margin(..., rigorous=True) with a larger "
            "max_evals)"
        )
    return (
        f"; in ball arithmetic the gap is [{lo:.3g}, {hi:.3g}]: the zero margin is not decided for the coefficients "
        "as given"
    )


def _not_strongly_stable(
    A: QuasiPolynomial, B: QuasiPolynomial, zero_root: bool, delta_max: float | None, rigorous: bool
) -> DelayMargin:
    """The principal part: no frequency bound, so the difference operator is not strongly stable
    for small ``delta > 0`` (or the loop is of advanced type) and the margin is 0 (Theorem 3)."""
    gap, rounding = _principal_gap(A, B, False)
    proven = proven_gap(A, B) if rigorous and np.isfinite(gap) else (-np.inf, -np.inf)
    if not (proven[1] < 0.0 or proven == (0.0, 0.0)):  # an exactly zero gap: root chains tend to the axis
        raise CertificationError(
            f"delay_margin(rigorous=True): the principal gap {gap:.3g} is not proven negative (the loop is at "
            "the boundary of strong stability to rounding): zero margin not proven"
        )
    gap_accuracy = _gap_accuracy(A, B, gap, rounding, rigorous)
    note = ""
    if not rigorous and np.isfinite(gap) and gap + gap_accuracy >= 0.0:
        decided = _zero_gap_decided(A, B, gap, gap_accuracy, delta_max)
        if isinstance(decided, DelayMargin):
            return decided
        note = decided
    nominal = unstable_count(A + B).count
    reason = (
        "advanced-type loop: chains of roots in Re s > 0 for every delta > 0"
        if not np.isfinite(gap)
        else f"difference operator not strongly stable for small delta > 0 (gap {with_accuracy(gap, gap_accuracy)}"
        + (" < 0" if gap + gap_accuracy < 0 else ", zero to its accuracy")
        + "): zero margin"
        + note
    )
    if nominal is None:  # e.g. A's own principal part not strongly stable: stable only at its delays' exact ratio
        reason += (
            "; the loop without delay is not decided (its count is not certified: the principal part of A + B "
            "may be stable at its delays as given and not under small changes of them), so nominally_stable "
            "False means not certified, not unstable"
        )
    return DelayMargin(
        margin=0.0,
        omega=None,
        crossings=(),
        nominally_stable=nominal == 0 and not zero_root,
        nominal_unstable=nominal,
        strongly_stable=False,
        zero_root=zero_root,
        intervals=(),
        counts=(),
        delta_max=0.0 if delta_max is None else delta_max,
        frequency_bound=None,
        gap=gap,
        gap_accuracy=gap_accuracy,
        verified=False,
        residual=None,
        reason=reason,
        rigorous=rigorous,
        margin_ball=(0.0, 0.0) if rigorous else None,
    )


def _search(
    A: QuasiPolynomial, B: QuasiPolynomial, w_bound: tuple[float, float] | None, max_evals: int, rigorous: bool
) -> tuple[ProvenCrossings | None, CrossingSearch, AxisGap]:
    """The crossing search: certified in floating point, or proven in ball arithmetic (``rigorous``,
    which proves its own frequency bound: ``w_bound`` is None when only the balls prove the gap)."""
    if rigorous:
        proof = proven_crossings(A, B, max_evals=max_evals)
        return proof, proof.search(), AxisGap(A, B)
    assert w_bound is not None
    search, axis_gap = _float_search(A, B, w_bound, max_evals)
    return None, search, axis_gap


@functools.lru_cache(maxsize=64)
def _float_search(
    A: QuasiPolynomial, B: QuasiPolynomial, w_bound: tuple[float, float], max_evals: int
) -> tuple[CrossingSearch, AxisGap]:
    """:func:`~nrobust.margins.crossing.crossing_search`, remembered for equal loops.

    The search does not depend on ``delta_max``: studies that ask for the margin of one loop
    with different delay ranges (a stability chart and a trade-off on the same gains) search
    once. The result is read, never changed, by :func:`delay_margin`.
    """
    return crossing_search(A, B, w_bound, max_evals)


def _common_zero(
    search: CrossingSearch, common: NDArray, zero_root: bool, delta_max: float | None, gap_accuracy: float
) -> DelayMargin:
    """``A`` and ``B`` vanish together at ``i w`` (``common[0] = w``): a root on the axis for every delay."""
    return DelayMargin(
        margin=0.0,
        omega=float(common[0]),
        crossings=(),
        nominally_stable=False,
        nominal_unstable=None,
        strongly_stable=True,
        zero_root=zero_root,
        intervals=(),
        counts=(),
        delta_max=float("inf") if delta_max is None else delta_max,
        frequency_bound=search.frequency_bound,
        gap=search.gap,
        gap_accuracy=gap_accuracy,
        verified=False,
        residual=None,
        reason=f"A and B vanish together at s = i w, w = {common[0]:.10g}: a root on the axis for every delay",
        evaluations=search.evaluations,
    )


def _events(crossings: tuple[Crossing, ...], delta_max: float, real: bool) -> dict[float, int]:
    """Change of the number of unstable zeros at each crossing delay up to ``delta_max``
    (conjugate pairs count twice for real coefficients; tangencies change nothing)."""
    mult = 2 if real else 1
    events: dict[float, int] = {}
    for c in crossings:
        for d in c.delays:
            if d <= delta_max:
                events[d] = events.get(d, 0) + mult * c.direction
    return events


def _windows(
    first: int | None, events: dict[float, int], delta_max: float, crossings: tuple[Crossing, ...]
) -> tuple[list[tuple[float, float, int]], list[tuple[float, float]]]:
    """The counts between crossing delays from the count ``first`` on the first interval, and the
    stability windows (intervals with no unstable zero).

    A count made negative by the crossing directions contradicts the certificates and raises.
    """
    counts: list[tuple[float, float, int]] = []
    if first is None:
        return counts, []
    marks = sorted(d for d in events if d > 0.0)
    bounds = [0.0, *marks, delta_max]
    cur = first
    for k in range(len(bounds) - 1):
        if k > 0:
            cur += events[bounds[k]]
            if cur < 0:
                raise CertificationError(
                    f"delay_margin: the crossing directions make the number of unstable roots negative "
                    f"({cur}) after delta = {bounds[k]:.12g}: certified count {first} on (0, {bounds[1]:.12g}), "
                    f"changes {[(d, events[d]) for d in marks[:k]]}, crossings {list(crossings)}; "
                    "this contradicts the certificates (please report it)"
                )
        if bounds[k + 1] > bounds[k]:
            counts.append((bounds[k], bounds[k + 1], cur))
    # consecutive intervals are separated by a delay with a zero on the axis: never merged
    return counts, [(lo, hi) for lo, hi, m in counts if m == 0]


def _first_axis_root(
    crossings: tuple[Crossing, ...], zero_root: bool, stable_at_zero: bool
) -> tuple[float, float | None, str]:
    """The margin: ``(delta*, w, reason)``, the first delay with a root on the axis."""
    if zero_root:
        return 0.0, 0.0, "s = 0 is a root for every delay (A(0) + B(0) = 0)"
    if not stable_at_zero:
        return 0.0, None, "the nominal loop (delta = 0) is not exponentially stable"
    if not crossings:
        return float("inf"), None, "no crossing frequency: stable for every delay"
    first_crossing = crossings[0]
    kind = "tangency (a double root touches the axis and returns)" if first_crossing.tangential else "crossing"
    # the frequency is the margin's omega, printed there to its accuracy (a model's can be known to 1e-7 only)
    return first_crossing.delays[0], first_crossing.omega, f"first {kind} (at omega)"


def _stored_radius(F: QuasiPolynomial, omega: float) -> float:
    """A bound of ``|F_true(i w) - F(i w)|`` from the proven radii of ``F``'s kernels: ``radius (b - a) b^m |q(i w)|``
    each (a kernel within ``radius`` of its stored pieces, weight ``nu^m``, polynomial factor ``q``); 0 for a
    loop stored exactly. A margin proven for ``F_true`` has its crossing within that of a zero of ``F``."""
    out = 0.0
    for d in F.distributed:
        if d.radius:
            q = abs(np.polynomial.polynomial.polyval(1j * omega, np.asarray(d.poly, dtype=complex)))
            out += d.radius * (d.b - d.a) * d.b**d.moment * float(q)
    return out


def _checked(
    A: QuasiPolynomial,
    B: QuasiPolynomial,
    margin: float,
    omega: float,
    W: float,
    axis_gap: AxisGap,
    max_evals: int,
    verify: bool,
) -> tuple[bool, float]:
    """``(verified, residual)``: the residual of ``F(i w; delta*)`` (raises unless at rounding level plus the
    kernels' proven radii, :func:`_stored_radius`: a margin proven for the true kernels need not be a zero of
    the stored ones)
    and, with ``verify``, no unstable zero at ``delta* (1 - 1e-3)`` (raises otherwise)."""
    s = np.array([1j * omega])
    Fm = A(s) + B(s) * np.exp(-s * margin)
    size = abs(A(s)[0]) + abs(B(s)[0])
    residual = float(abs(Fm[0]) / size)
    if residual > 1e-8 + (_stored_radius(A, omega) + _stored_radius(B, omega)) / size:
        raise CertificationError(
            f"delay_margin: F(i w; delta*) does not vanish at delta* = {margin:.12g}, w = {omega:.12g} "
            f"(relative residual {residual:.3g})"
        )
    if not verify:
        return False, residual
    probe = margin * (1 - 1e-3)
    below = unstable_count(
        A + B.shift(probe), W, loop=(A, B, probe), kernels=axis_gap.kernels, max_evals=max_evals
    ).count
    if below != 0:
        raise CertificationError(
            f"delay_margin: verification failed at delta* = {margin:.12g}: {below} unstable roots at "
            f"delta* (1 - 1e-3), where the crossing analysis finds none"
        )
    return True, residual


def delay_margin(
    A: QuasiPolynomial,
    B: QuasiPolynomial,
    *,
    delta_max: float | None = None,
    verify: bool = True,
    max_evals: int = 2_000_000,
    rigorous: bool = False,
) -> DelayMargin:
    r"""Delay margin and stability intervals of ``F(s; delta) = A(s) + B(s) e^{-delta s}``.

    For a plant and a controller, :func:`nrobust.delay_margin` builds ``A`` and ``B`` with
    :func:`nrobust.hyperbolic.loop_factors` (e.g. eq. (60) for
    ``U_BS2(K)``) and calls this function.

    Parameters
    ----------
    A, B : QuasiPolynomial
        The loop factors (numbers are taken as constants).
    delta_max : float, optional
        Range of delays for the stability intervals; default
        ``max_c (delta_{c,0} + 2 pi / |w_c|)``, one period of every crossing (``inf``
        without crossings).
    verify : bool, optional
        Check the margin by the residual at ``i w`` and a certified count at
        ``delta* (1 - 1e-3)`` (the count is left out when only ball arithmetic proves the
        principal gap positive: its floating-point frequency bound does not exist).
    max_evals : int, optional
        Work bound of the crossing search.
    rigorous : bool, optional
        Prove the margin in ball arithmetic (python-flint, ``pip install nrobust[rigorous]``):
        the frequency bound, every zero of ``|A(i w)|^2 - |B(i w)|^2`` with the direction of its
        crossing and its first delay (:func:`nrobust.margins.proven.proven_crossings`),
        and the nominal count (:func:`nrobust.count_roots` with ``rigorous=True``); the
        result has ``rigorous=True`` and ``margin_ball = (lo, hi)`` enclosing ``delta*``.
        What cannot be proven raises :class:`CertificationError` (e.g. a tangency to
        rounding that could come first, a loop in which ``A`` or ``B`` is identically zero).

    Returns
    -------
    DelayMargin

    Raises
    ------
    ParameterError
        ``A`` and ``B`` both identically zero, ``delta_max`` not positive (NaN, ``-inf``),
        or ``max_evals`` not a positive integer.
    CertificationError
        A work bound was hit (``max_evals`` is checked before any grid is allocated), a
        crossing cluster could not be decided, or a check failed: the residual at the
        margin, a count made negative by the crossing directions, or the verification;
        with ``rigorous=True``, whatever could not be proven.
    ImportError
        ``rigorous=True`` without python-flint.

    Notes
    -----
    A zero of

    .. math::

        F(s; \delta) = A(s) + B(s)\, e^{-\delta s}

    reaches the imaginary axis at :math:`s = i\omega` only where
    :math:`|A(i\omega)| = |B(i\omega)|`, and then at the delays

    .. math::

        \delta_{k}(\omega) = \frac{\arg\left(-B(i\omega)/A(i\omega)\right) + 2\pi k}{\omega}, \qquad k \in \mathbb{Z};

    the margin :math:`\delta^*` is the smallest delay at which a crossing is destabilising,
    searched on :math:`[0, W]` with :math:`W` a proven bound beyond which
    :math:`|A(i\omega)| > |B(i\omega)|` (it exists when the principal parts leave a positive
    gap: strong stability of the loop's difference operator).

    When ``B`` (or ``A``) is identically zero the loop does not depend on the delay: the
    margin is ``inf`` if the other factor is exponentially stable (certified count, no
    zero on the axis), else 0. When ``A`` and ``B`` vanish together at some ``i w`` the
    loop has that root for every delay: margin 0, like ``A(0) + B(0) = 0``.

    Examples
    --------
    >>> from nrobust import QuasiPolynomial
    >>> A = QuasiPolynomial([[1.0, 1.0]], [0.0])      # s + 1
    >>> B = QuasiPolynomial([[2.0]], [0.0])           # 2 e^{-delta s}
    >>> dm = delay_margin(A, B)
    >>> bool(abs(dm.margin - np.arccos(-0.5) / np.sqrt(3.0)) < 1e-12)
    True
    """
    A, B, delta_max, max_evals = _validated(A, B, delta_max, max_evals, rigorous)
    zero_root = _zero_root(A, B, rigorous)
    if rigorous and zero_root:
        return _proven_zero_root(A, B, delta_max)
    if is_zero(B) or is_zero(A):
        return _delay_free(B if is_zero(A) else A, "A" if is_zero(A) else "B", zero_root, delta_max)
    w_bound = frequency_bound(A, B)
    # a gap below the rounding of its floating-point sum may still be proven positive in balls
    if w_bound is None and not (rigorous and proven_gap(A, B)[0] > 0.0):
        return _not_strongly_stable(A, B, zero_root, delta_max, rigorous)
    proof, search, axis_gap = _search(A, B, w_bound, max_evals, rigorous)
    W = search.frequency_bound
    gap_accuracy = _principal_gap(A, B, False)[1] if proof is None else _far_end(search.gap, proof.gap)
    common = common_axis_zeros(axis_gap, search)
    if common.size:
        return _common_zero(search, common, zero_root, delta_max, gap_accuracy)
    crossings, delta_max = axis_crossings(A, B, search, delta_max, axis_gap)
    events = _events(crossings, delta_max, A.is_real and B.is_real)
    # The nominal count, and the count on the first interval (0, first positive crossing delay).
    nominal_loop = A + B if proof is None else _proven_sum(A, B)
    radius = W if proof is None else min(W, proven_zero_radius(nominal_loop) or W)  # W: a bound for every delay
    nominal = None if zero_root or 0.0 in events else unstable_count(nominal_loop, radius, rigorous=rigorous).count
    first = nominal
    if nominal is None and not zero_root:
        marks = sorted(d for d in events if d > 0.0)
        probe = 0.5 * marks[0] if marks else (1.0 if not np.isfinite(delta_max) else 0.5 * delta_max)
        loop = A + B.shift(probe) if proof is None else _proven_sum(A, B.shift(probe))
        first = unstable_count(loop, W, rigorous=rigorous).count
    counts, intervals = _windows(first, events, delta_max, crossings)
    stable_at_zero = nominal == 0
    margin, omega, reason = _first_axis_root(crossings, zero_root, stable_at_zero)
    verified, residual = False, None
    if stable_at_zero and np.isfinite(margin) and margin > 0 and omega is not None:
        verified, residual = _checked(A, B, margin, omega, W, axis_gap, max_evals, verify and w_bound is not None)
    omega_error, *errors = _omega_errors(A, B, [omega, *(c.omega for c in crossings)], crossings, proof, zero_root)
    crossings = _with_delay_accuracies(
        A, B, tuple(replace(c, omega_accuracy=e) for c, e in zip(crossings, errors)), proof
    )
    ball = None
    if proof is not None:
        ball = _margin_ball(proof, zero_root, nominal)
        if not ball[0] <= margin <= ball[1]:
            margin = 0.5 * (ball[0] + ball[1])
        reason += (
            " (proven in ball arithmetic)"
            if np.isposinf(ball[0])
            else f" (proven in ball arithmetic: delta* in [{ball[0]:.17g}, {ball[1]:.17g}])"
        )
    return DelayMargin(
        margin=float(margin),
        omega=None if omega is None else float(omega),
        crossings=crossings,
        nominally_stable=bool(stable_at_zero and not zero_root),
        nominal_unstable=nominal,
        strongly_stable=True,
        zero_root=zero_root,
        intervals=tuple(intervals),
        counts=tuple(counts),
        delta_max=float(delta_max),
        frequency_bound=W,
        gap=search.gap,
        gap_accuracy=gap_accuracy,
        verified=verified,
        residual=residual,
        reason=reason,
        evaluations=search.evaluations,
        rigorous=rigorous,
        margin_ball=ball,
        omega_error=omega_error,
    )


def _proven_sum(A: QuasiPolynomial, B: QuasiPolynomial) -> QuasiPolynomial:
    """``A + B`` whose point coefficients hold the exact sums: the rounding of a coefficient summed in
    floating point (equal delays) becomes its radius (:class:`~nrobust.quasipoly.QuasiPolynomial`'s ``radii``)."""
    return QuasiPolynomial.from_parts(A.point_terms, A.distributed, A.radii_of()) + B


# Safety factor of the floating-point estimate of omega's error (see DelayMargin.omega_accuracy).
_OMEGA_SAFETY = 16.0


def _with_delay_accuracies(
    A: QuasiPolynomial, B: QuasiPolynomial, crossings: tuple[Crossing, ...], proof: ProvenCrossings | None
) -> tuple[Crossing, ...]:
    """Each crossing with :attr:`~nrobust.margins.crossing.Crossing.delay_accuracies` (and ``delay_accuracy``,
    its first): proven from ``proof``'s enclosures, else estimated as :attr:`DelayMargin.accuracy` is."""
    if proof is not None:
        return tuple(_with_accuracies(c, _proven_delay_accuracies(c, proof)) for c in crossings)
    if not crossings:
        return crossings
    s = 1j * np.array([c.omega for c in crossings], dtype=float)  # A and B at every crossing frequency at once
    return tuple(_with_accuracies(c, _delay_estimates(c, a, b)) for c, a, b in zip(crossings, A(s), B(s)))


def _with_accuracies(c: Crossing, accuracies: tuple[float | None, ...]) -> Crossing:
    """``c`` with ``accuracies`` as its :attr:`~nrobust.margins.crossing.Crossing.delay_accuracies` (the first
    its ``delay_accuracy``)."""
    return replace(c, delay_accuracy=accuracies[0] if accuracies else None, delay_accuracies=accuracies)


def _delay_estimates(c: Crossing, a: complex, b: complex) -> tuple[float | None, ...]:
    """The floating-point estimate of :attr:`DelayMargin.accuracy` at each delay ``tau_k`` of ``c`` (``a, b``:
    ``A`` and ``B`` at ``i w``): ``max(1e-12 tau_k, 20 residual_k / |w|)`` plus ``omega_accuracy |Im(1/d_k)|``,
    with ``1/d_k = 1/d_0 - i (tau_k - tau_0) / w`` (``d = ds/d delta``: ``1/d = (A'/A - B'/B + delta) / s`` on
    the axis)."""
    if c.omega_accuracy is None or c.tangential or c.omega == 0.0:
        return (None,) * len(c.delays)
    taus = np.asarray(c.delays, dtype=float)
    residual = np.abs(a + b * np.exp(-1j * c.omega * taus)) / (abs(a) + abs(b))
    from_residual = np.maximum(1e-12 * taus, 20.0 * residual / abs(c.omega))
    d0 = complex(c.ds_ddelta)
    if d0 == 0.0:
        return (float("inf"),) * len(c.delays)
    slope = np.abs((1.0 / d0).imag - (taus - taus[0]) / c.omega)
    return tuple(float(v) for v in from_residual + c.omega_accuracy * slope)


def _proven_delay_accuracies(c: Crossing, proof: ProvenCrossings) -> tuple[float | None, ...]:
    """The distance from each delay ``tau_k`` of ``c`` to the far end of its enclosure
    ``[d_lo + 2 pi k / |w|_hi, d_hi + 2 pi k / |w|_lo]`` (``proof``'s enclosures of the first delay and of
    ``w``; each end moved outward by ``4 eps`` of its modulus, above the rounding of its three operations
    and of ``pi``); None when no proven enclosure holds ``c.omega`` (a tangency to rounding)."""
    ball = next(((w, d) for w, d in zip(proof.omegas, proof.delays) if w[0] <= c.omega <= w[1]), None)
    if ball is None or ball[0][0] <= 0.0 <= ball[0][1]:
        return (None,) * len(c.delays)
    (w_lo, w_hi), (d_lo, d_hi) = ball
    slow, fast = min(abs(w_lo), abs(w_hi)), max(abs(w_lo), abs(w_hi))
    wide = 4.0 * float(np.finfo(float).eps)
    out: list[float | None] = []
    for k, tau in enumerate(c.delays):
        lo, hi = d_lo + 2.0 * np.pi * k / fast, d_hi + 2.0 * np.pi * k / slow
        lo, hi = lo - wide * abs(lo), hi + wide * abs(hi)
        out.append(float(np.nextafter(max(hi - tau, tau - lo, 0.0), np.inf)))
    return tuple(out)


def _omega_errors(
    A: QuasiPolynomial,
    B: QuasiPolynomial,
    omegas: list[float | None],
    crossings: tuple[Crossing, ...],
    proof: ProvenCrossings | None,
    zero_root: bool,
) -> list[float | None]:
    """:attr:`DelayMargin.omega_error` of each frequency of ``omegas`` (one evaluation of ``A`` and ``B``
    for all): from the proven enclosure of ``omega`` (``proof``), or the residual of
    ``g(w) = |A(i w)|^2 - |B(i w)|^2`` over ``|g'(w)|``."""
    out: list[float | None] = [None] * len(omegas)
    todo = []
    for k, omega in enumerate(omegas):
        if omega is None:
            continue
        if zero_root and omega == 0.0:
            out[k] = 0.0
        elif proof is not None:
            balls = [*proof.omegas, *proof.unresolved]
            if balls:
                lo, hi = min(balls, key=lambda b: max(b[0] - omega, omega - b[1], 0.0))
                out[k] = float(np.nextafter(max(hi - omega, omega - lo, 0.0), np.inf))
        elif not any(c.tangential for c in crossings if c.omega == omega):
            todo.append(k)
    if not todo:
        return out
    w = np.array([omegas[k] for k in todo], dtype=float)
    s = 1j * w
    a, b = A(s), B(s)
    da, db = 1j * A.deriv_at(s), 1j * B.deriv_at(s)  # d/dw of A(i w), B(i w)
    slope = np.abs(2.0 * ((a.conj() * da).real - (b.conj() * db).real))
    eps = float(np.finfo(float).eps)
    noise = np.abs(np.abs(a) ** 2 - np.abs(b) ** 2) + eps * (A.magnitude(s) ** 2 + B.magnitude(s) ** 2)
    for k, sl, no, x in zip(todo, slope, noise, w):
        out[k] = float(_OMEGA_SAFETY * no / sl + eps * abs(x)) if sl > 0.0 else None
    return out
