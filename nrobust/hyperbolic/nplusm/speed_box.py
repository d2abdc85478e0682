"""The box of relative errors of the transport speeds of an ``n + m`` plant, and a gain's verdicts on it.

Each speed has its own error: the plant transports ``u_i`` at ``lam_i (1 + e_i)`` and ``v_j`` at
``mu_j (1 + e_{n+j})``, ``|e_i| <= eps``, the couplings, the reflections and the gain unchanged
(:func:`perturbed_system`). The errors form a box of dimension ``n + m`` with ``2^(n+m)`` vertices
(:func:`speed_box`).

**Vertices do not decide the inside.** The speeds enter the loop
``det(E(s) (Phi_v - (R + K e^{-delta s}) Phi_u))`` through ``E(s) = diag(e^{-s/mu_j})`` and
``Phi(s) = exp(Lambda^{-1} (Sigma - s I))``: not affinely (not even on an uncoupled plant, where
they move the round trips ``1/lam_i + 1/mu_j`` inside exponentials of ``s``), and the stability
windows of a delay loop are not continuous in its data (a pair of crossing frequencies is born where
``|A(i w)| = |B(i w)|`` gains a double zero). So stability at the vertices need not imply it inside
the box: the verdicts at the vertices are certified, those at the other points of the grid are
computed by the same certified tools at those points only, and the box between the points is not
certified (:class:`NPlusMSpeedTolerance` says so in its statement), unless it is proven:
``nplusm_speed_tolerance(..., inside=True)`` proves the windows on the whole box by subdivision
in ball arithmetic (:mod:`~nrobust.hyperbolic.nplusm.speed_proof`, the argument of the square of the 2x2
plant, :func:`~nrobust.hyperbolic.analyses.speed_tolerance` with ``rigorous=True``), and
:attr:`NPlusMSpeedTolerance.inside` says whether it was.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from ..._json import json_safe
from ..._validate import finite_real
from ...errors import ParameterError
from .system import NPlusMSystem

__all__ = [
    "MAX_SPEED_CORNERS",
    "NPlusMSpeedTolerance",
    "WindowVerdict",
    "check_box_tolerance",
    "perturbed_system",
    "speed_box",
]

#: Most vertices of the box of speed errors a design or a check takes: ``2^(n+m) <= 16``, so ``n + m <= 4``.
#: Each vertex adds a certified delay margin to every evaluation of the design, and the grid of 3 points per
#: speed adds ``3^(n+m) - 2^(n+m) - 1`` more to its certificate (65 at ``n + m = 4``).
MAX_SPEED_CORNERS = 16


class WindowVerdict(Protocol):
    """A verdict on a window of delays at one point of the box (:class:`~nrobust.hyperbolic.nplusm.NPlusMWindow`)."""

    @property
    def stable(self) -> bool:
        """Exponentially stable for every delay of the window."""

    @property
    def certified(self) -> bool:
        """The verdict rests on certified tools."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""


def check_box_tolerance(value: Any, system: NPlusMSystem, name: str = "speed_tolerance") -> float:
    """``eps`` in ``(0, 1)`` with at most :data:`MAX_SPEED_CORNERS` vertices; a :class:`ParameterError` naming ``name``.

    Parameters
    ----------
    value : float
        The relative tolerance of every speed.
    system : NPlusMSystem
        The plant (its ``n + m`` speeds give the box its dimension).
    name : str
        The parameter named in the error.

    Returns
    -------
    float
    """
    what = "a relative error of every speed in (0, 1) (the perturbed speeds stay positive)"
    try:
        eps = finite_real(name, value)
    except ParameterError:
        raise ParameterError(name, what, value) from None
    if not 0.0 < eps < 1.0:
        raise ParameterError(name, what, value)
    dimension = system.n + system.m
    if 2**dimension > MAX_SPEED_CORNERS:
        raise ParameterError(
            name,
            f"None for {system.n} + {system.m} speeds: the box has 2^{dimension} = {2**dimension} vertices, at most "
            f"MAX_SPEED_CORNERS = {MAX_SPEED_CORNERS} are taken (n + m <= 4)",
            value,
        )
    return eps


def speed_box(dimension: int, eps: float) -> tuple[tuple[tuple[float, ...], ...], tuple[tuple[float, ...], ...]]:
    """``(vertices, others)``: the error vectors of the box ``[-eps, eps]^dimension``.

    The vertices in lexicographic order of the signs (``-eps`` first), then the other points of the
    grid of 3 points per speed (``-eps, 0, eps``) but its centre (the nominal plant), lexicographic.
    """
    vertices = tuple(itertools.product((-eps, eps), repeat=dimension))
    others = tuple(
        p
        for p in itertools.product((-eps, 0.0, eps), repeat=dimension)
        if p not in vertices and any(e != 0.0 for e in p)
    )
    return vertices, others


def perturbed_system(system: NPlusMSystem, errors: tuple[float, ...]) -> NPlusMSystem:
    """``system`` with ``lam_i (1 + e_i)`` and ``mu_j (1 + e_{n+j})``, everything else unchanged.

    Parameters
    ----------
    system : NPlusMSystem
    errors : tuple of float
        ``n + m`` relative errors, each ``> -1``.

    Returns
    -------
    NPlusMSystem
    """
    n, m = system.n, system.m
    if len(errors) != n + m or not all(finite_real("errors", e) > -1.0 for e in errors):
        raise ParameterError("errors", f"{n + m} relative speed errors, each > -1", errors)
    e = np.asarray(errors, dtype=float)
    return NPlusMSystem(system.lam * (1.0 + e[:n]), system.mu * (1.0 + e[n:]), system.sigma, system.q, system.r)


@dataclass(frozen=True, eq=False)
class NPlusMSpeedTolerance:
    """What is known of a gain ``K`` on the box of speed errors ``|e_i| <= eps`` with the required delays.

    Compared by identity (``==`` is ``is``).

    Attributes
    ----------
    eps : float
        The tolerance: every speed ``c_i (1 + e_i)`` with ``|e_i| <= eps``.
    delays : tuple of (float, float)
        The windows ``[d_min, d_max]`` required at every point (a required margin ``d`` is ``[0, d]``).
    points : tuple of tuple of float
        The error vectors examined (``lam_1, ..., lam_n, mu_1, ..., mu_m``): the ``2^(n+m)`` vertices
        first, then the other points of the grid of 3 points per speed (:func:`speed_box`).
    vertices : int
        How many of ``points`` are vertices.
    windows : tuple of tuple of WindowVerdict
        The verdicts at each point, one per window (:func:`~nrobust.hyperbolic.nplusm.check_window`:
        the certified delay margin of the perturbed loop and a certified count).
    met : bool
        Stable on every window at every point examined.
    certified : str
        ``"certified at the vertices"`` (every vertex's verdict stable and certified; the other points
        stable), ``"not certified at the vertices"`` (stable, but a vertex's verdict could not be
        certified), or ``"not met"`` (a point is not stable on a window).
    statement : str
        The tolerance in words: what is certified, what is only checked, and whether the box between the
        points is certified (with the proof's reason, or why not).
    inside : bool
        True when stability on every window is certified on the whole box, not only at the points
        (:func:`~nrobust.hyperbolic.nplusm.speed_proof.prove_speed_box`, asked by
        ``nplusm_speed_tolerance(..., inside=True)``); False when not asked or not proven.
    """

    eps: float
    delays: tuple[tuple[float, float], ...]
    points: tuple[tuple[float, ...], ...]
    vertices: int
    windows: tuple[tuple[WindowVerdict, ...], ...]
    met: bool
    certified: str
    statement: str
    inside: bool = False

    def __repr__(self) -> str:
        return (
            f"NPlusMSpeedTolerance(eps={float(self.eps)!r}, met={self.met}, certified={self.certified!r}, "
            f"points={len(self.points)}, inside={self.inside})"
        )

    @classmethod
    def from_verdicts(
        cls,
        eps: float,
        delays: tuple[tuple[float, float], ...],
        points: tuple[tuple[float, ...], ...],
        vertices: int,
        windows: tuple[tuple[WindowVerdict, ...], ...],
        proofs: Sequence[tuple[bool, str]] = (),
    ) -> NPlusMSpeedTolerance:
        """The tolerance from the verdicts at ``points`` (the first ``vertices`` of them the vertices), in words.

        ``proofs``: one ``(proven, reason)`` per window of ``delays`` when the inside of the box was examined
        (:func:`~nrobust.hyperbolic.nplusm.speed_proof.prove_speed_box`), else empty.
        """
        met = all(w.stable for verdicts in windows for w in verdicts)
        at_vertices = all(w.certified for verdicts in windows[:vertices] for w in verdicts)
        dimension = len(points[0])
        span = ", ".join(f"[{float(lo)!r}, {float(hi)!r}]" for lo, hi in delays)
        if not met:
            bad = [p for p, verdicts in zip(points, windows) if not all(w.stable for w in verdicts)]
            certified = "not met"
            statement = f"not shown stable for every delay in {span} at the speed errors " + ", ".join(
                "(" + ", ".join(f"{float(e)!r}" for e in p) + ")" for p in bad
            )
        else:
            certified = "certified at the vertices" if at_vertices else "not certified at the vertices"
            how = (
                "certified: each perturbed loop's certified delay margin and a certified count"
                if at_vertices
                else "not all certified: a margin or a count was not decided"
            )
            statement = (
                f"stable for every delay in {span} at the {vertices} vertices of the box |e_i| <= {float(eps)!r} of "
                f"the {dimension} relative speed errors ({how}), and at the {len(points) - vertices} other points of "
                "the grid of 3 points per speed (by the same tools, at those points only); "
            )
            failed = [reason for proven, reason in proofs if not proven]
            if proofs and not failed:
                statement += "between the points certified too, on the whole box: " + "; ".join(r for _, r in proofs)
            elif proofs:
                statement += "between the points not certified: " + failed[0]
            else:
                statement += (
                    "between the points not certified: the speeds enter the loop through exp(Lambda^-1 (Sigma - s I)) "
                    "and E(s), not affinely, and the stability windows are not continuous in them, so stability at the "
                    "vertices need not imply it inside the box"
                )
        inside = met and bool(proofs) and all(proven for proven, _ in proofs)
        return cls(eps, delays, points, vertices, windows, met, certified, statement, inside)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (each verdict as its dictionary)."""
        return json_safe(
            {
                "eps": self.eps,
                "delays": [list(w) for w in self.delays],
                "points": [list(p) for p in self.points],
                "vertices": self.vertices,
                "windows": [[w.to_dict() for w in verdicts] for verdicts in self.windows],
                "met": self.met,
                "certified": self.certified,
                "statement": self.statement,
                "inside": self.inside,
            }
        )
