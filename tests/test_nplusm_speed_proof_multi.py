"""Stability of an ``n + m`` loop with several actuators certified on the whole box of speed errors
(:func:`nrobust.hyperbolic.nplusm.speed_proof.prove_speed_box` with ``m = 2``, module notes "Several actuators").

The oracle at points drawn inside a proven box is the plant's own certified delay margin
(:func:`~nrobust.hyperbolic.nplusm.multi_actuator_delay_margin`: the crossings of ``det(M_0 + z M_1)`` on the unit
circle by the eigenvalues of ``-M_0^{-1} M_1`` and a certified count at ``delta = 0``), which shares no code with the
box proof (no ball arithmetic, no subdivision over the speeds).
"""

from __future__ import annotations

import functools
import itertools

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
    the plant is not proven: it halves down to its least width about that frequency and names it (1,880 boxes
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


#: A coupled ``1 + 3`` plant and a gain with the certified margin 5.62 (``multi_actuator_delay_margin``).
THREE_COUPLING = 0.2
THREE = NPlusMSystem(
    [1.5],
    [1.0, 2.0, 1.5],
    [
        [0, THREE_COUPLING, THREE_COUPLING, THREE_COUPLING],
        [THREE_COUPLING, 0, 0, 0],
        [THREE_COUPLING, 0, 0, 0],
        [THREE_COUPLING, 0, THREE_COUPLING, 0],
    ],
    [[0.3, 0.4, 0.2]],
    [[0.5], [0.3], [0.2]],
)
THREE_GAIN = [[-0.7], [-0.3], [-0.2]]
THREE_EPS, THREE_WINDOW = 1e-4, (0.0, 2.0)


@functools.cache
def _three_proof() -> SpeedBoxProof:
    """The proof for three actuators on the box ``eps = 1e-4`` and the window ``[0, 2]`` (once)."""
    dm = multi_actuator_delay_margin(THREE, THREE_GAIN)
    verdict = check_window(THREE, THREE_GAIN, dm, THREE_WINDOW)
    return prove_speed_box(THREE, THREE_GAIN, THREE_EPS, THREE_WINDOW, [(0.0,) * 4], [verdict], max_boxes=10_000)


def test_three_actuators_proven_inside() -> None:
    """Three actuators (``F`` a cubic in ``z``, cleared by a dominant coefficient or ``z`` as a ball over the window):
    the window ``[0, 2]`` proven on the box ``eps = 1e-4`` within 10,000 boxes (2,403 measured, about 1.2 s of CPU
    time; ``W`` about 122)."""
    proof = _three_proof()
    assert proof.proven and proof.base == 0 and 100.0 < proof.frequency_bound < 150.0


@settings(max_examples=3, deadline=None, derandomize=True)
@given(st.lists(st.floats(-THREE_EPS, THREE_EPS), min_size=4, max_size=4))
def test_three_actuator_points_agree_with_direct_margins(errors: list[float]) -> None:
    """At points drawn inside the box proven above the plant's own certified margin is beyond the window's end, with
    no zero in ``Re s >= 0`` at ``delta = 0``."""
    assert _three_proof().proven
    dm = multi_actuator_delay_margin(perturbed_system(THREE, tuple(errors)), THREE_GAIN)
    assert dm.certified and dm.nominal_unstable == 0 and dm.margin > THREE_WINDOW[1]


def test_four_actuators_are_refused_before_work() -> None:
    """Four actuators: the proof is a ``ParameterError`` naming ``system`` before any work (at most
    ``MAX_PROVEN_ACTUATORS = 3``), and the tolerance one naming ``eps`` (the box of a ``1 + 4`` plant has 32 vertices,
    above ``MAX_SPEED_CORNERS``)."""
    c = 0.1
    four = NPlusMSystem(
        [1.5],
        [1.0, 2.0, 1.5, 1.2],
        [[0, c, c, 0, 0], [c, 0, 0, 0, 0], [c, 0, 0, 0, 0], [0, 0, c, 0, 0], [c, 0, 0, 0, 0]],
        [[0.3, 0.4, 0.2, 0.1]],
        [[0.5], [0.3], [0.2], [0.1]],
    )
    gain = [[-0.4], [-0.2], [-0.1], [-0.1]]
    with pytest.raises(ParameterError) as info:
        prove_speed_box(four, gain, 0.002, (0.0, 0.5), [], [])
    assert info.value.name == "system" and "at most 3 actuators" in str(info.value)
    with pytest.raises(ParameterError) as info:
        nplusm_speed_tolerance(four, gain, 0.002, (0.0, 0.5), inside=True)
    assert info.value.name == "eps"


#: The fully coupled ``2 + 2`` plant of ``tests/test_nplusm_design.py`` (couplings up to 0.6) and a gain with the
#: certified margin 4.6096 (``multi_actuator_delay_margin``).
TWO_TWO = NPlusMSystem(
    [1.0, 0.5],
    [1.0, 2.0],
    [[0.0, 0.1, 0.5, 0.2], [0.1, 0.0, 0.2, -0.3], [0.4, 0.1, 0.0, 0.1], [0.2, 0.6, 0.1, 0.0]],
    [[0.8, 0.1], [0.2, 0.7]],
    [[0.5, 0.2], [0.1, -0.4]],
)
TWO_GAIN = np.array([[-0.3, 0.0], [0.0, 0.2]])


def _inverse_box(system: NPlusMSystem, eps: float) -> list[tuple[float, float]]:
    """Float intervals of the inverse speeds holding ``1 / (c (1 + e))`` for ``|e| <= eps`` (one ulp outwards)."""
    speeds = np.concatenate([system.lam, system.mu])
    return [
        (float(np.nextafter(1.0 / (c * (1.0 + eps)), 0.0)), float(np.nextafter(1.0 / (c * (1.0 - eps)), 2.0)))
        for c in speeds
    ]


def _direct_coefficients(plant: NPlusMSystem, gain: np.ndarray, w: float) -> np.ndarray:
    """``c_0, ..., c_m`` of ``F(i w) = sum_d c_d z^d`` from the plant's own floating-point characteristic function
    (``NPlusMCharacteristic``: scipy's ``expm`` and numpy's determinant, no ball arithmetic) at the ``m + 1`` delays
    putting ``z = e^{-i w delta}`` on the roots of unity of order ``m + 1`` (a well-conditioned Vandermonde system)."""
    from nrobust.hyperbolic.nplusm import NPlusMCharacteristic

    k = plant.m + 1
    delays = 2.0 * np.pi * np.arange(k) / (k * w)
    z = np.exp(-1j * w * delays)
    f = [complex(NPlusMCharacteristic(plant, gain, d)(np.array([1j * w]))[0]) for d in delays]
    return np.asarray(np.linalg.solve(np.vander(z, increasing=True), f))


@pytest.mark.parametrize(
    ("system", "gain", "w0", "hw", "eps"),
    [
        (SYSTEM, np.array(GAIN), 11.0, 0.05, 1e-3),
        (TWO_TWO, TWO_GAIN, 5.0, 0.05, 1e-3),
        (TWO_TWO, TWO_GAIN, 150.0, 0.01, 1e-5),
        (TWO_TWO, TWO_GAIN, 150.0, 1e-6, 1e-8),
        (SYSTEM, np.array(GAIN), 11.0, 1e-6, 1e-8),
    ],
)
def test_the_centred_enclosure_holds_direct_evaluations(
    system: NPlusMSystem, gain: np.ndarray, w0: float, hw: float, eps: float
) -> None:
    """The centred enclosures of ``c_0, ..., c_m`` on a box of ``(w, inverse speeds)`` hold the coefficients of the
    plants at the box's corners (where the first-order term is largest) and at random points, from the plant's own
    floating-point characteristic function (rounding below 1e-13 for coefficients about 1, so the slack 1e-12). On the
    tiny boxes the first-order term decides the radius and the corners reach 0.4 to 0.7 of it (measured): the
    derivatives are those of the plant, not merely bounds."""
    from nrobust._flint import working_precision
    from nrobust.hyperbolic.nplusm.speed_proof import _Loop

    rng = np.random.default_rng(7)
    box = [(w0, w0 + hw), *_inverse_box(system, eps)]
    speeds = np.concatenate([system.lam, system.mu])
    with working_precision(53) as flint:
        balls = [flint.arb(lo).union(flint.arb(hi)) for lo, hi in box]
        loop = _Loop(flint, system, gain, balls[1:])
        coefficients, shares = loop.centred([box])[0]
    assert len(coefficients) == system.m + 1 and np.all(shares >= 0.0)
    mids = np.array([complex(c.mid()) for c in coefficients])
    radii = np.array([float(c.rad()) for c in coefficients])  # acb: the rectangle holds the disc of this radius
    corners = list(itertools.product((-1.0, 1.0), repeat=speeds.size + 1))
    inside = [tuple(rng.uniform(-1.0, 1.0, speeds.size + 1)) for _ in range(10)]
    reach = np.zeros(system.m + 1)
    for point in corners + inside:
        plant_speeds = speeds * (1.0 + eps * np.array(point[1:]))
        plant = NPlusMSystem(plant_speeds[: system.n], plant_speeds[system.n :], system.sigma, system.q, system.r)
        direct = _direct_coefficients(plant, gain, w0 + hw * (1.0 + point[0]) / 2.0)
        assert np.all(np.abs(direct - mids) <= radii + 1e-12)
        reach = np.maximum(reach, np.abs(direct - mids) / radii)
    if hw < 1e-3:
        assert max(reach) > 0.4


WIDE_EPS = 0.02


@functools.cache
def _wide_proof() -> SpeedBoxProof:
    """The proof on the box ``eps = 0.02`` and the window ``[0, 5]`` from the nominal plant's verdict (once)."""
    return prove_speed_box(SYSTEM, GAIN, WIDE_EPS, WINDOW, [NOMINAL], [_nominal_verdict(WINDOW)], max_boxes=15_000)


@pytest.mark.long
def test_a_wider_box_proven_with_the_centred_form() -> None:
    """``eps = 0.02`` is proven within 15,000 boxes (7,037 measured, about 1.3 s of CPU time; the ball exponentials
    needed 48,589 boxes and 18 s, so the work bound would have stopped them): the centred form clears the boxes where
    the ball exponentials wrap."""
    proof = _wide_proof()
    assert proof.proven and proof.base == 0 and proof.undecided == ()
    assert proof.boxes < 15_000


@pytest.mark.long
@settings(max_examples=4, deadline=None, derandomize=True)
@given(st.floats(-WIDE_EPS, WIDE_EPS), st.floats(-WIDE_EPS, WIDE_EPS), st.floats(-WIDE_EPS, WIDE_EPS))
def test_wide_box_points_agree_with_direct_margins(e_lam: float, e_mu1: float, e_mu2: float) -> None:
    """At points drawn inside the box ``eps = 0.02`` proven above, the plant's own certified delay margin is beyond the
    window's end and its loop has no zero in ``Re s >= 0`` at ``delta = 0``."""
    assert _wide_proof().proven
    plant = perturbed_system(SYSTEM, (e_lam, e_mu1, e_mu2))
    dm = multi_actuator_delay_margin(plant, GAIN)
    assert dm.certified and dm.nominal_unstable == 0 and dm.margin > WINDOW[1]


def test_a_box_holding_an_unstable_plant_is_refused() -> None:
    """On the box ``eps = 0.001`` the certified margins at the vertices range from 18.51 (all speeds low) to 18.98 (all
    high): the window ``[0, 18.75]`` holds the crossing delay of the low vertex, so that plant is unstable there,
    while the high vertex is certified stable on it. From the high vertex's verdict the proof is refused: not proven,
    or stopped at the work bound (2,000 boxes; it halves towards the crossing at w = 0.147)."""
    eps, window = 1e-3, (0.0, 18.75)
    low, high = (-eps, -eps, -eps), (eps, eps, eps)
    dm_low = multi_actuator_delay_margin(perturbed_system(SYSTEM, low), GAIN)
    dm_high = multi_actuator_delay_margin(perturbed_system(SYSTEM, high), GAIN)
    assert dm_low.certified and dm_low.margin < window[1] < dm_high.margin
    verdict = check_window(perturbed_system(SYSTEM, high), GAIN, dm_high, window)
    assert verdict.stable and verdict.certified
    try:
        proof = prove_speed_box(SYSTEM, GAIN, eps, window, [high], [verdict], max_boxes=2_000)
    except CertificationError as error:
        assert "max_boxes = 2000" in str(error)
    else:
        assert not proof.proven
