"""Stability of an ``n + 1`` loop certified on the whole box of speed errors (``nplusm_speed_tolerance(...,
inside=True)``, :mod:`nrobust.hyperbolic.nplusm.speed_proof`).

The oracle is written here in mpmath at 40 digits from the PDE of a ``1 + 1`` plant, not from nrobust's builders:
``F(s; delta) = A(s) + B(s) e^{-delta s}``, ``A = e^{-s/mu} (Phi_v - r Phi_u)``, ``B = -k e^{-s/mu} Phi_u``,
``[Phi_u; Phi_v] = exp(M) [q; 1]``, ``M = Lambda^{-1} (Sigma - s I)`` exponentiated in closed form (``e^{tr/2}
(cosh(D) I + sinh(D)/D (M - tr/2 I))``, ``D^2 = (tr/2)^2 - det``); its crossing frequencies are the zeros of
``|A(i w)|^2 - |B(i w)|^2`` (bracketed on a grid, refined by the Illinois method), each with its first crossing
delay ``arg(-B/A) / w`` in ``[0, 2 pi / w)``.
"""

from __future__ import annotations

import math

import mpmath as mp
import numpy as np
import pytest
from _oracles import one_plus_one_factors
from hypothesis import given, settings
from hypothesis import strategies as st

from nrobust._flint import working_precision
from nrobust.errors import CertificationError, ParameterError
from nrobust.hyperbolic.nplusm import NPlusMSystem, nplusm_delay_margin
from nrobust.hyperbolic.nplusm.characteristic import spectral_norm_bound
from nrobust.hyperbolic.nplusm.design import nplusm_speed_tolerance
from nrobust.hyperbolic.nplusm.speed_box import perturbed_system
from nrobust.hyperbolic.nplusm.speed_proof import prove_speed_box

#: The coupled plant of ``tests/test_nplusm_speed_tolerance.py`` (``lam = mu = 1``, ``sigma+- = 1.5``,
#: ``sigma-+ = 0.5``, ``q = 0.8``, ``r = 0.4``) and the gain its tolerance design reaches.
PLANT = (1.0, 1.0, 1.5, 0.5, 0.8, 0.4)
SYSTEM = NPlusMSystem([1.0], [1.0], [[0.0, 1.5], [0.5, 0.0]], [[0.8]], [[0.4]])
GAIN = -0.441025
EPS, WINDOW = 0.05, (0.0, 1.2)


def _factors(s: mp.mpc, plant: tuple[float, ...], k: float) -> tuple[mp.mpc, mp.mpc]:
    """``(A(s), B(s))`` of the ``1 + 1`` loop ``plant = (lam, mu, sigma+-, sigma-+, q, r)`` with gain ``k``."""
    return one_plus_one_factors(s, plant, k)


def _first_delay(plant: tuple[float, ...], k: float, top: float, step: float = 0.02) -> float:
    """The least crossing delay over the crossing frequencies in ``(0, top]`` (``inf``: none there)."""
    with mp.workdps(40):

        def gap(w: mp.mpf) -> mp.mpf:
            A, B = _factors(mp.mpc(0, w), plant, k)
            return abs(A) ** 2 - abs(B) ** 2

        grid = [mp.mpf(step) * j for j in range(1, round(top / step) + 1)]
        values = [gap(w) for w in grid]
        best = math.inf
        for lo, hi, g_lo, g_hi in zip(grid, grid[1:], values, values[1:]):
            if g_lo * g_hi < 0:
                w = mp.findroot(gap, (lo, hi), solver="illinois")
                A, B = _factors(mp.mpc(0, w), plant, k)
                best = min(best, float(mp.fmod(mp.arg(-B / A) + 2 * mp.pi, 2 * mp.pi) / w))
        return best


def _moved(plant: tuple[float, ...], e_lam: float, e_mu: float) -> tuple[float, ...]:
    return (plant[0] * (1.0 + e_lam), plant[1] * (1.0 + e_mu), *plant[2:])


def test_a_box_certified_inside() -> None:
    """On the test plant with ``k = -0.441025`` the window ``[0, 1.2]`` is proven on the whole box ``eps = 0.05``
    (the least margin of the box, about 1.238 at the vertex ``(-0.05, 0.05)``, leaves room): ``inside`` is True and
    the statement says how. The oracle: at the middles of the four edges (points of the grid) and at two points
    inside, off the grid, the first crossing delay of the 40-digit loop is above 1.21 (measured: 1.2474 the least;
    its crossing frequencies are below 1, the search up to 14 covers the box's frequency bound, 13.71). About 6 s of
    CPU time."""
    tol = nplusm_speed_tolerance(SYSTEM, [[GAIN]], EPS, WINDOW, inside=True)
    assert tol.met and tol.certified == "certified at the vertices" and tol.inside
    assert "between the points certified too, on the whole box" in tol.statement
    assert "inside=True" in repr(tol) and tol.to_dict()["inside"] is True
    for e in [(0.0, 0.05), (-0.05, 0.0), (0.02, -0.03), (-0.04, 0.035)]:
        assert _first_delay(_moved(PLANT, *e), GAIN, 14.0) > 1.2 + 0.01


def test_the_proof_reports_its_bound_and_its_start() -> None:
    """``prove_speed_box`` on the window with the vertices' verdicts: proven from the first stable vertex, the
    frequency bound above every vertex's own proven bound (the box's holds for each of its plants), and the work
    bound refusing with a CertificationError naming ``max_boxes``."""
    tol = nplusm_speed_tolerance(SYSTEM, [[GAIN]], EPS, WINDOW)
    vertices = tol.points[: tol.vertices]
    verdicts = [row[0] for row in tol.windows[: tol.vertices]]
    proof = prove_speed_box(SYSTEM, [[GAIN]], EPS, WINDOW, vertices, verdicts)
    assert proof.proven and proof.base == 0 and proof.boxes > 1 and proof.undecided == ()
    from nrobust.hyperbolic.nplusm import NPlusMCharacteristic

    for e in vertices:
        assert NPlusMCharacteristic(perturbed_system(SYSTEM, e), [[GAIN]]).frequency_bound() < proof.frequency_bound
    with pytest.raises(CertificationError, match="max_boxes = 20"):
        prove_speed_box(SYSTEM, [[GAIN]], EPS, WINDOW, vertices, verdicts, max_boxes=20)


@settings(max_examples=4, deadline=None, derandomize=True)
@given(st.floats(-EPS, EPS), st.floats(-EPS, EPS))
def test_inside_points_agree_with_direct_margins(e_lam: float, e_mu: float) -> None:
    """At points drawn inside the box proven above, the plant's own certified delay margin is above the window's end
    and its loop stable at ``delta = 0``, and the 40-digit oracle's first crossing delay agrees with that margin to
    ``1e-8`` (the margin's stated accuracy is about 4e-12; measured 7e-16 at 6 random points)."""
    plant = perturbed_system(SYSTEM, (e_lam, e_mu))
    dm = nplusm_delay_margin(plant, [[GAIN]])
    assert dm.certified and dm.nominal_unstable == 0 and dm.margin > WINDOW[1]
    truth = _first_delay((float(plant.lam[0]), float(plant.mu[0]), *PLANT[2:]), GAIN, 14.0)
    assert abs(dm.margin - truth) < 1e-8, (dm.margin, truth)


#: A 2 + 1 plant with distinct speeds, and a gain that keeps it stable for every delay (its delay margin is infinite).
THREE = NPlusMSystem([1.0, 0.5], [1.5], [[0, 0, 0.4], [0, 0, 0.3], [0.5, -0.4, 0]], [[0.6], [0.5]], [[0.3, 0.2]])
THREE_GAIN = (-0.2, 0.1)


def _three_gap(w: float, errors: tuple[float, ...]) -> mp.mpf:
    """``|A(i w)|^2 - |B(i w)|^2`` of ``THREE`` with the speed errors ``errors``, at 40 digits (mpmath's ``expm``)."""
    sigma, q, r = ((0, 0, 0.4), (0, 0, 0.3), (0.5, -0.4, 0)), (0.6, 0.5), (0.3, 0.2)
    with mp.workdps(40):
        s = mp.mpc(0, w)
        speeds = [mp.mpf(1.0) * (1 + mp.mpf(errors[0])), mp.mpf(0.5) * (1 + mp.mpf(errors[1]))]
        mu = mp.mpf(1.5) * (1 + mp.mpf(errors[2]))
        signed = [*speeds, -mu]
        M = mp.matrix(3, 3)
        for i in range(3):
            for k in range(3):
                M[i, k] = mp.mpf(sigma[i][k]) / signed[i] - (s / signed[i] if i == k else 0)
        G = mp.expm(M)
        col = [G[i, 0] * q[0] + G[i, 1] * q[1] + G[i, 2] for i in range(3)]
        scale = mp.exp(-s / mu)
        A = scale * (col[2] - r[0] * col[0] - r[1] * col[1])
        B = -scale * (THREE_GAIN[0] * col[0] + THREE_GAIN[1] * col[1])
        return abs(A) ** 2 - abs(B) ** 2


def test_a_box_of_three_speeds_certified_inside() -> None:
    """``n + m = 3``: on ``THREE`` with ``eps = 0.05`` the window ``[0, 3]`` is proven on the whole box (a frequency
    bound of about 3.28 over the box, then 91 boxes). The oracle, at three points drawn inside: ``|A(i w)|^2 -
    |B(i w)|^2`` of the 40-digit loop stays above 0.1 on a grid of step 0.02 of ``[0, 3.3]`` (measured: 0.174 the
    least), so no crossing frequency there, as the proof says. About 3 s of CPU time."""
    tol = nplusm_speed_tolerance(THREE, [THREE_GAIN], 0.05, (0.0, 3.0), inside=True)
    assert tol.met and tol.inside and len(tol.points) == 26
    assert "none with Re s >= 0 and |s| >= 3.28" in tol.statement
    rng = np.random.default_rng(0)
    for _ in range(3):
        errors = tuple(float(e) for e in rng.uniform(-0.05, 0.05, 3))
        assert min(_three_gap(float(w), errors) for w in np.arange(0.0, 3.3, 0.02)) > 0.1


#: A 1 + 1 plant whose delay margin under ``k = 0.54`` is not monotone in ``lam``: on the box ``eps = 0.2`` its least
#: value, about 2.688, sits near ``(e_lam, e_mu) = (-0.1, 0.2)``, away from every point of the grid of 3 per speed
#: (the least of those, 2.7315, at the vertex ``(-0.2, 0.2)``).
DIP = (0.744, 1.286, 0.98, 0.72, 0.73, -0.59)
DIP_SYSTEM = NPlusMSystem([0.744], [1.286], [[0.0, 0.98], [0.72, 0.0]], [[0.73]], [[-0.59]])
DIP_GAIN, DIP_EPS, DIP_WINDOW = 0.54, 0.2, (0.0, 2.725)


def test_a_box_unstable_between_the_grid_points_is_refused() -> None:
    """The window ``[0, 2.725]`` on the box ``eps = 0.2`` of the plant ``DIP``: every vertex and every other point of
    the grid is certified stable on it (``met``, ``"certified at the vertices"``), but the plant at ``(e_lam, e_mu) =
    (-0.1, 0.17)``, inside the box and on no grid line of ``lam``, has a crossing delay below 2.725 (the oracle's
    first crossing delay there, about 2.70: a zero on the imaginary axis for a delay of the window), so the box is not
    stable on the window. The oracle agrees at the grid: the first crossing delay of each of its 9 plants is above
    2.725 + 0.005 (crossing frequencies searched up to 25). ``inside=True`` does not certify it: the subdivision
    cannot clear the boxes around that plant's crossing, and stops at its work bound with a CertificationError naming
    ``max_boxes`` (it would stop the same way on a stable box this wide: on this plant even ``eps = 0.05`` takes more
    than 20,000 boxes; the test checks that no proof is claimed). About 10 s of CPU time."""
    tol = nplusm_speed_tolerance(DIP_SYSTEM, [[DIP_GAIN]], DIP_EPS, DIP_WINDOW)
    assert tol.met and tol.certified == "certified at the vertices" and not tol.inside
    for e in [(0.0, 0.0), *tol.points]:
        assert _first_delay(_moved(DIP, *e), DIP_GAIN, 25.0) > DIP_WINDOW[1] + 0.005, e
    assert _first_delay(_moved(DIP, -0.1, 0.17), DIP_GAIN, 25.0) < DIP_WINDOW[1] - 0.01
    with pytest.raises(CertificationError, match="max_boxes = 3000"):
        nplusm_speed_tolerance(DIP_SYSTEM, [[DIP_GAIN]], DIP_EPS, DIP_WINDOW, inside=True, max_boxes=3000)


def test_a_box_whose_rates_meet_is_not_certified_inside() -> None:
    """A 2 + 1 plant with ``lam = (1, 1.05)``: on the box ``eps = 0.1`` the round-trip rates of ``u_1`` and ``u_2`` can
    be equal, and the far-field bound needs them apart, so the inside is not certified (``inside`` False, the
    statement saying why) while the points' verdicts stand."""
    plant = NPlusMSystem([1.0, 1.05], [1.0], [[0, 0, 0.3], [0, 0, 0.2], [0.3, 0.1, 0]], [[0.3], [0.2]], [[0.2, 0.1]])
    tol = nplusm_speed_tolerance(plant, [[0.1, 0.1]], 0.1, (0.0, 1.0), inside=True)
    assert tol.met and tol.certified == "certified at the vertices" and not tol.inside
    assert "between the points not certified: the round-trip rates of u_1 and u_2 meet" in tol.statement


def test_bad_arguments_are_refused_before_work() -> None:
    """A non-boolean ``inside``, a bad ``max_boxes``: ParameterErrors naming them (several actuators are taken:
    ``tests/test_nplusm_speed_proof_multi.py``)."""
    with pytest.raises(ParameterError) as info:
        nplusm_speed_tolerance(SYSTEM, [[GAIN]], 0.1, (0.0, 1.0), inside="yes")  # type: ignore[arg-type]
    assert info.value.name == "inside"
    with pytest.raises(ParameterError) as info:
        nplusm_speed_tolerance(SYSTEM, [[GAIN]], 0.1, (0.0, 1.0), inside=True, max_boxes=0)
    assert info.value.name == "max_boxes"


def test_the_norm_bound_of_a_ball_matrix_holding_zero_is_finite() -> None:
    """``spectral_norm_bound`` of a ball matrix whose entries straddle 0 (the gauge's ``H`` over a box of speeds of
    an uncoupled diagonal): a finite bound, at or above the norm 0.642 of a matrix it holds
    (``diag(0.642, -0.642)``); a power ``x ** 2`` of such a ball is nan in arb, which made it nan."""
    with working_precision(53) as flint:
        arb = flint.arb
        x = flint.arb_mat([[arb(0, 0.642), arb(0)], [arb(0), arb(0, 0.642)]])
        bound = spectral_norm_bound(flint, x)
        assert math.isfinite(float(bound.upper())) and float(bound.upper()) >= 0.642


DESIGN_WITH_ROOM = {"margin_at_least": 0.5, "K_bounds": (-0.8, -0.3), "x0": [[-0.5]], "starts": 1}


@pytest.mark.long
def test_a_design_proven_on_the_whole_box() -> None:
    """``design_nplusm_gains(..., speed_tolerance=0.05, inside=True)`` with a margin of at least 0.5 (the rate binds,
    not the window): the designed gain's window ``[0, 0.5]`` is proven on the whole box (about 28,000 boxes, 30 s of
    CPU), and the oracle finds no crossing delay below 0.5 at interior plants off the grid."""
    from nrobust.hyperbolic.nplusm.design import design_nplusm_gains

    design = design_nplusm_gains(SYSTEM, "decay_rate", speed_tolerance=EPS, inside=True, **DESIGN_WITH_ROOM)
    assert design.tolerance is not None and design.tolerance.inside
    assert "between the points certified too, on the whole box" in design.tolerance.statement
    k = design.K[0][0]
    for e_lam, e_mu in ((0.013, -0.037), (-0.041, 0.022), (0.049, 0.049)):
        assert _first_delay(_moved(PLANT, e_lam, e_mu), k, 20.0) > 0.5


def test_a_design_whose_proof_inside_stops_keeps_its_points(monkeypatch: pytest.MonkeyPatch) -> None:
    """A proof inside the box that stops at its work bound (here made to stop at once) leaves the design and its
    verdicts at the points, ``inside`` False and the reason in the statement; ``inside`` is refused without a
    tolerance, before any work."""
    import nrobust.hyperbolic.nplusm.design as design_module

    def stops(*args: object, **kwargs: object) -> None:
        raise CertificationError("prove_speed_box: the work bound max_boxes = 1 was reached")

    monkeypatch.setattr(design_module, "prove_speed_box", stops)
    # the final check of the design (its optimisation, about 20 s, is the long test's above)
    tolerance = design_module._box_tolerance(
        SYSTEM, np.array([[GAIN]]), EPS, (WINDOW,), True, 50_000, stopped_raises=False
    )
    assert not tolerance.inside and tolerance.certified == "certified at the vertices"
    assert "the proof inside the box stopped: prove_speed_box: the work bound" in tolerance.statement
    with pytest.raises(ParameterError) as info:
        design_module.design_nplusm_gains(SYSTEM, "decay_rate", inside=True, **DESIGN_WITH_ROOM)
    assert info.value.name == "inside"


class _Claimed:
    """A verdict claiming stability (to start the proof where the window is not stable)."""

    stable = True
    certified = True

    def to_dict(self) -> dict[str, object]:
        return {"stable": True, "certified": True}


def test_a_crossing_inside_the_window_ends_the_proof_at_its_least_box() -> None:
    """The window ``[0, 1.5]`` holds the first crossing delay of every plant of a box ``eps = 1e-9`` about the test
    plant (1.2384 at ``k = -0.441025``, the oracle): given a verdict that claims stability at a vertex, the proof
    finds no box free of crossings about that frequency, halves down to its least width and refuses there, naming
    the frequency (not the work bound)."""
    first = _first_delay(PLANT, GAIN, 10.0)
    assert 1.0 < first < 1.5
    vertices = [(-1e-9, -1e-9), (-1e-9, 1e-9), (1e-9, -1e-9), (1e-9, 1e-9)]
    proof = prove_speed_box(SYSTEM, [[GAIN]], 1e-9, (0.0, 1.5), vertices, [_Claimed()] * 4)
    assert not proof.proven and proof.undecided
    assert "a zero of F on the imaginary axis for w in" in proof.reason
