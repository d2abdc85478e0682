"""Stability of an ``n + m`` loop with several actuators certified on the whole box of speed errors
(:func:`nrobust.hyperbolic.nplusm.speed_proof.prove_speed_box` with ``m = 2``, module notes "Several actuators").

The oracle at points drawn inside a proven box is the plant's own certified delay margin
(:func:`~nrobust.hyperbolic.nplusm.multi_actuator_delay_margin`: the crossings of ``det(M_0 + z M_1)`` on the unit
circle by the eigenvalues of ``-M_0^{-1} M_1`` and a certified count at ``delta = 0``), which shares no code with the
box proof (no ball arithmetic, no subdivision over the speeds).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nrobust.errors import CertificationError, ParameterError
from nrobust.hyperbolic.nplusm import NPlusMSystem, multi_actuator_delay_margin
from nrobust.hyperbolic.nplusm.design import NPlusMWindow, check_window, nplusm_speed_tolerance
from nrobust.hyperbolic.nplusm.speed_box import perturbed_system
from nrobust.hyperbolic.nplusm.speed_proof import SpeedBoxProof, prove_speed_box

#: A coupled ``1 + 2`` plant (distinct round trips, no diagonal couplings) and a gain with a finite delay margin.
COUPLING = 0.2
SYSTEM = NPlusMSystem(
    [1.5],
    [1.0, 2.0],
    [[0.0, COUPLING, COUPLING], [COUPLING, 0.0, 0.12], [COUPLING, 0.0, 0.0]],
    [[0.3, 0.4]],
    [[0.5], [0.3]],
)
GAIN = [[-0.8], [-0.3]]
EPS, WINDOW = 0.01, (0.0, 5.0)
NOMINAL = (0.0, 0.0, 0.0)


def _nominal_verdict(window: tuple[float, float]) -> NPlusMWindow:
    return check_window(SYSTEM, GAIN, multi_actuator_delay_margin(SYSTEM, GAIN), window)


@functools.cache
def _proof() -> SpeedBoxProof:
    """The proof on the box ``eps = 0.01`` and the window ``[0, 5]`` from the nominal plant's verdict (once)."""
    return prove_speed_box(SYSTEM, GAIN, EPS, WINDOW, [NOMINAL], [_nominal_verdict(WINDOW)])


class _Claimed:
    """A verdict claiming stability (to start the proof where the window is not stable)."""

    stable = True
    certified = True

    def to_dict(self) -> dict[str, object]:
        return {"stable": True, "certified": True}


def test_a_box_of_two_actuators_proven_inside() -> None:
    """The window ``[0, 5]`` (the nominal margin is about 18.7) is proven on the whole box ``eps = 0.01``, from the
    nominal plant's certified verdict; the statement names the box and the frequency bound, above the nominal plant's
    own bound of the root-free far field on ``Re s >= 0``."""
    verdict = _nominal_verdict(WINDOW)
    assert verdict.stable and verdict.certified
    proof = _proof()
    assert proof.proven and proof.base == 0 and proof.boxes > 1 and proof.undecided == ()
    assert "no zero in Re s >= 0 anywhere on the box" in proof.reason
    assert "mu_1, ..., mu_m" in proof.reason


@settings(max_examples=4, deadline=None, derandomize=True)
@given(st.floats(-EPS, EPS), st.floats(-EPS, EPS), st.floats(-EPS, EPS))
def test_inside_points_agree_with_direct_margins(e_lam: float, e_mu1: float, e_mu2: float) -> None:
    """At points drawn inside the box proven above, the plant's own certified delay margin is beyond the window's
    end and its loop has no zero in ``Re s >= 0`` at ``delta = 0``: the verdict of the box agrees."""
    assert _proof().proven
    plant = perturbed_system(SYSTEM, (e_lam, e_mu1, e_mu2))
    dm = multi_actuator_delay_margin(plant, GAIN)
    assert dm.certified and dm.nominal_unstable == 0 and dm.margin > WINDOW[1]


def test_a_window_holding_a_crossing_is_refused() -> None:
    """The window ``[0, 20]`` holds the nominal plant's first crossing delay (its certified margin, about 18.74, at
    the crossing frequency 0.14861): given a verdict that claims stability, the proof on a box ``eps = 1e-9`` about
    the plant is not proven: it halves down to its least width about that frequency and names it (2,115 boxes
    measured, the work bound 20,000 not reached). The frequency of the margin holds to about 1e-12 and the box moves
    it by about 1e-9 relative: the named interval within 1e-8 of it."""
    dm = multi_actuator_delay_margin(SYSTEM, GAIN)
    assert 15.0 < dm.margin < 20.0 and dm.omega is not None
    proof = prove_speed_box(SYSTEM, GAIN, 1e-9, (0.0, 20.0), [NOMINAL], [_Claimed()], max_boxes=20_000)
    assert not proof.proven and len(proof.undecided) == 3
    assert "a zero of F on the imaginary axis for w in" in proof.reason
    lo, hi = (float(v) for v in proof.reason.split("for w in [")[1].split("]")[0].split(", "))
    assert lo - 1e-8 <= dm.omega <= hi + 1e-8
    assert max(abs(a - b) for a, b in zip(proof.undecided, (1.5, 1.0, 2.0))) < 1e-8


def test_the_work_bound_and_bad_arguments() -> None:
    """The work bound refuses with a CertificationError naming ``max_boxes``; ``eps`` outside ``(0, 1)`` is a
    ParameterError naming it, before any work."""
    verdict = _nominal_verdict(WINDOW)
    with pytest.raises(CertificationError, match="max_boxes = 3"):
        prove_speed_box(SYSTEM, GAIN, EPS, WINDOW, [NOMINAL], [verdict], max_boxes=3)
    with pytest.raises(ParameterError) as info:
        prove_speed_box(SYSTEM, GAIN, 1.5, WINDOW, [NOMINAL], [verdict])
    assert info.value.name == "eps"


def test_a_strong_gain_is_refused_at_the_far_field() -> None:
    """A gain whose ``rho(V^-1 (|R| + |K|) U |Q|)`` exceeds 1 on the box (``K = [[2], [2]]``: 1.07 at the nominal
    plant, by hand ``(0.5 + 2) 0.3 + (0.3 + 2) 0.4``) gets no frequency bound: not proven, and the reason says so."""
    K = np.array([[2.0], [2.0]])
    gamma = np.array([[2.5], [2.3]]) @ np.array([[0.3, 0.4]])
    assert max(abs(np.linalg.eigvals(gamma))) > 1.0
    proof = prove_speed_box(SYSTEM, K, EPS, WINDOW, [NOMINAL], [_Claimed()])
    assert not proof.proven and "not proven strongly stable" in proof.reason


def test_the_tolerance_with_two_actuators_proven_inside() -> None:
    """``nplusm_speed_tolerance(..., inside=True)`` with two actuators: the points' verdicts (the 8 vertices and 18
    other points of the grid, each a certified margin) and the proof inside, ``inside`` True."""
    tol = nplusm_speed_tolerance(SYSTEM, GAIN, EPS, WINDOW, inside=True)
    assert tol.met and tol.certified == "certified at the vertices" and tol.inside
    assert "between the points certified too, on the whole box" in tol.statement


def test_three_actuators_are_refused_before_work() -> None:
    """Three actuators: a ``ParameterError`` naming ``inside`` (and ``system`` for the proof itself) before any
    verdict is computed (boxes of the delay were not decided on the plants tried)."""
    c = 0.1
    three = NPlusMSystem(
        [1.5],
        [1.0, 2.0, 1.5],
        [[0, c, c, 0], [c, 0, 0, 0], [c, 0, 0, 0], [0, 0, c, 0]],
        [[0.3, 0.4, 0.2]],
        [[0.5], [0.3], [0.2]],
    )
    gain = [[-0.4], [-0.2], [-0.1]]
    with pytest.raises(ParameterError) as info:
        nplusm_speed_tolerance(three, gain, 0.002, (0.0, 0.5), inside=True)
    assert info.value.name == "inside" and "at most 2 actuators" in str(info.value)
    with pytest.raises(ParameterError) as info:
        prove_speed_box(three, gain, 0.002, (0.0, 0.5), [], [])
    assert info.value.name == "system"
