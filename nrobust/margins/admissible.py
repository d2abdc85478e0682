"""Is a gain admissible: the delay margin at one gain of an affine family, and the check of an end.

For ``F(s; delta, K) = A(s) + (B_0(s) + K R(s)) e^{-delta s}`` (:class:`~nrobust.margins.gain.AffineGainLoop`),
:func:`gain_verdict` decides one gain with the steps of :func:`nrobust.margins.delay_margin` and a
tighter frequency bound, :func:`tolerates` reads a verdict against a required margin, and
:func:`check_gain_end` confirms an end located by :func:`~nrobust.margins.gain.locate_gain_ends`
on both sides (a certified zero in ``Re s > 0`` just outside).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..errors import CertificationError
from ..roots import count_roots
from .axis import frequency_bound
from .crossing import Crossing, axis_crossings, common_axis_zeros, crossing_search
from .gain import AffineGainLoop, AxisBound, GainEnd, nominally_stable
from .margin import DelayMargin
from .search import SPARE_SEGMENTS

__all__ = ["GainVerdict", "check_gain_end", "gain_verdict", "tolerates"]


class GainVerdict(NamedTuple):
    """What :func:`gain_verdict` proves of one gain: the fields of
    :class:`~nrobust.margins.DelayMargin` that an admissibility test reads (:func:`tolerates`)."""

    margin: float
    nominally_stable: bool
    strongly_stable: bool
    crossings: tuple[Crossing, ...]


def gain_verdict(loop: AffineGainLoop, K: float, delta_max: float, max_evals: int) -> GainVerdict:
    """Delay margin of ``A + (B_0 + K R) e^{-delta s}`` at one gain, for an admissibility test.

    The steps of :func:`nrobust.margins.delay_margin` (the certified crossing search of
    :mod:`nrobust.margins.crossing`, the crossing delays up to ``delta_max``, the nominal
    verdict), with two differences that make the gains next to the strong-stability limit
    affordable: the search stops at the smaller of the first-order frequency bound and
    :class:`AxisBound`'s (``1/sqrt(k - |K|)`` instead of ``1/(k - |K|)``: on the plant
    ``lam = 2, mu = 0.5, sigma = (0.3, -0.4), q = 0.7, rho = 0.9`` with ``delta_max = 0.1`` the
    gain ``K = -0.5285666771`` takes 1.2 s here, while ``delay_margin(A, B)`` exceeds its work
    bound), and nominal stability is decided in closed form when ``F(.; 0, K)`` is
    ``c_0 + c_1 e^{-t s}`` (:func:`~nrobust.margins.gain.nominally_stable`). Neither the residual at the margin nor
    a verification count is computed. Roots reach ``Re s > 0`` only through the axis (the
    difference operator is strongly stable), so the nominal verdict and the crossings decide
    every delay. ``delta_max`` (``> 0``, finite) and ``max_evals`` are trusted.

    Parameters
    ----------
    loop : AffineGainLoop
    K : float
        The gain.
    delta_max : float
        Crossing delays are listed up to ``delta_max``.
    max_evals : int
        Work bound of the crossing search.

    Returns
    -------
    GainVerdict
        ``margin`` 0 when the difference operator is not strongly stable, ``A`` and ``B`` vanish
        together on the axis, or the nominal loop is unstable; else the first crossing delay
        (``inf`` without crossings).
    """
    A, B = loop.A, loop.B(K)
    first = frequency_bound(A, B)
    if first is None:
        return GainVerdict(0.0, False, False, ())
    bound = AxisBound.of(loop)
    W = first[0] if bound is None else min(first[0], bound.W(K, K))
    search, axis_gap = crossing_search(A, B, (W, first[1]), max_evals, SPARE_SEGMENTS)
    if common_axis_zeros(axis_gap, search).size:  # a root on the axis for every delay
        return GainVerdict(0.0, False, True, ())
    crossings, _ = axis_crossings(A, B, search, delta_max, axis_gap)
    if not nominally_stable(loop, K):
        return GainVerdict(0.0, False, True, crossings)
    return GainVerdict(crossings[0].delays[0] if crossings else float("inf"), True, True, crossings)


def _unstable_root_near(loop: AffineGainLoop, K: float, delta: float, omega: float) -> str | None:
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


def check_gain_end(
    end: GainEnd, inner: GainVerdict | str, K_out: float, loop: AffineGainLoop, delta_max: float
) -> str | None:
    """None if ``end`` is confirmed on both sides, else why not.

    Inside, the verdict (:func:`gain_verdict`) must be admissible. Outside, a certified count
    proves a zero in ``Re s > 0`` at some delay in ``[0, delta_max]`` (:func:`_unstable_root_near`):
    at ``delta = 0`` next to a nominal end, at ``delta_max`` next to a crossing, at the birth delay
    next to a pair birth (between the delays of the newborn pair, ``O(sqrt(tol))`` apart);
    beyond the strong-stability limit the difference operator is not strongly stable (margin 0).

    Parameters
    ----------
    end : GainEnd
        The end, as :func:`~nrobust.margins.gain.locate_gain_ends` gives it.
    inner : GainVerdict or str
        The verdict just inside the interval (``end.K +- tol``), or the message of its
        :class:`~nrobust.errors.CertificationError`.
    K_out : float
        The gain just outside (``end.K -+ tol``).
    loop : AffineGainLoop
    delta_max : float

    Returns
    -------
    str or None
    """
    if isinstance(inner, str):
        return f"the delay margin inside failed ({inner})"
    if not tolerates(inner, delta_max):
        return f"inside, the margin is {inner.margin:.12g} (nominally stable: {inner.nominally_stable})"
    if end.kind == "strong_stability":
        strong = frequency_bound(loop.A, loop.B(K_out)) is not None
        return "outside, the difference operator is still strongly stable" if strong else None
    delay = {"nominal": 0.0, "crossing": delta_max, "pair_birth": end.delay}[end.kind]
    return _unstable_root_near(loop, K_out, delay, end.omega)


def tolerates(margin: DelayMargin | GainVerdict, delta_max: float) -> bool:
    """True if the loop is stable for every delay in ``[0, delta_max]`` (admissible).

    That is: nominally stable and ``margin > delta_max`` (the margin is the first delay with a
    root on the axis, so the whole of ``[0, delta_max]`` is covered). A margin proven in ball
    arithmetic must exceed ``delta_max`` with its whole ball (a loop whose kernels are known within
    proven radii can have a ball wider than the digits of ``margin``).
    """
    ball = getattr(margin, "margin_ball", None)
    lowest = margin.margin if ball is None else min(margin.margin, ball[0])
    return bool(margin.nominally_stable and lowest > delta_max)
