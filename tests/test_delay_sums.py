"""Loop delays added to point delays: ``t + delta`` is seldom a double, and proofs must not round it.

``characteristic(system, controller, delta)`` holds ``B e^{-delta s}`` with its point delays moved to the
doubles nearest ``t + delta`` (``2 + 0.1`` is ``2.1000000000000000888`` where the exact sum is
``2.1000000000000000056``). At ``|s| ~ 1e7`` that moves ``F`` by ``K q |s| 8e-17 ~ 8e-12``, far beyond the ball
of the rounded loop: a root count or a Krawczyk test proven with that ball was a theorem about the rounded
delays. ``given_plant_balls`` now encloses ``A + B e^{-delta s}`` with ``delta`` exact when a sum rounds (the
rigorous certificate's roots at ``delta_max`` are proven with it), and the proven collocated observer's scope
names the delays ``tau + delta_o`` it holds rounded.

Oracle, sharing no code with the package: the uncoupled plant's loop under U_BS2(K) written from its boundary
conditions (``v(1) = rho u(1) + U`` with ``U = -K u(1)`` applied ``delta`` late, eqs. (47)-(52) of the paper
with no coupling): ``F = 1 - rho q e^{-tau s} + K q e^{-(tau + delta) s}`` up to the factor of the round trip,
evaluated by mpmath at 90 digits with every delay the exact sum of the user's doubles; exactness of a sum decided
by mpmath's exact addition (``fadd(..., exact=True)``).
"""

from __future__ import annotations

import mpmath as mp
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nrobust._flint import working_precision
from nrobust.balls import DelayedSumBalls, ball_function
from nrobust.hyperbolic import CollocatedOutputFeedback, Hyperbolic2x2, ReflectionController, StateFeedback
from nrobust.hyperbolic.loops.controllers import characteristic, loop_factors, loop_scope
from nrobust.hyperbolic.loops.given_plant import GivenPlantBalls, given_plant_balls
from nrobust.margins.count import unstable_count
from nrobust.quasipoly import DistributedDelay, QuasiPolynomial

flint = pytest.importorskip("flint")

PLANT = (1.0, 1.0, 0.0, 0.0, 1.0, 0.85)  # tau = 2, a double: the loop as built is the plant's
K, DELTA = 0.1, 0.1
POINTS = (complex(0.0, 1.0e7), complex(-0.3, 3.3e6), complex(0.2, -9.1e6))


def _uncoupled_loop(s: mp.mpc) -> mp.mpc:
    lam, mu, _, _, q, rho = (mp.mpf(v) for v in PLANT)
    tau = 1 / lam + 1 / mu
    return 1 - rho * q * mp.exp(-tau * s) + mp.mpf(K) * q * mp.exp(-(tau + mp.mpf(DELTA)) * s)


def _contains(ball: object, value: mp.mpc) -> bool:
    with working_precision(400) as fl:
        return bool(ball.contains(fl.acb(value)))  # type: ignore[attr-defined]


def test_the_rounded_sum_is_what_the_loop_holds():
    """The premise: ``2 + 0.1`` is not a double, and the loop as built holds the rounded sum."""
    F = characteristic(Hyperbolic2x2(*PLANT), ReflectionController(K), DELTA)
    assert 2.1 in [t for _, t in F.point_terms]
    assert mp.fadd(2.0, DELTA, exact=True) != mp.mpf(2.0 + DELTA)
    assert not loop_factors(Hyperbolic2x2(*PLANT), ReflectionController(K))[1].shift_is_exact(DELTA)


def test_the_plant_balls_hold_the_exact_delay_where_the_rounded_loop_does_not():
    """``given_plant_balls`` (prec 200) contains the loop with the exact sum at ``|s| ~ 1e7``; the ball of the
    loop as built (rounded sum) excludes it there (before: ``given_plant_balls`` returned None and the proofs
    used that ball)."""
    plant, law = Hyperbolic2x2(*PLANT), ReflectionController(K)
    balls = given_plant_balls(plant, law, DELTA, prec=200)
    assert isinstance(balls, GivenPlantBalls)
    rounded = ball_function(characteristic(plant, law, DELTA), 200)
    with mp.workdps(90):  # 200-bit balls (60 digits) at |s| ~ 1e7: the oracle far narrower
        for s in POINTS:
            truth = _uncoupled_loop(mp.mpc(s))
            assert _contains(balls(s), truth), s
            assert not _contains(rounded(s), truth), s


def test_an_exact_sum_keeps_the_loops_own_balls():
    """``delta = 0.5``: ``2 + 0.5`` is a double, the loop as built is the plant's (None: its own balls)."""
    assert given_plant_balls(Hyperbolic2x2(*PLANT), ReflectionController(K), 0.5) is None


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(0.0, 50.0, allow_subnormal=False), min_size=1, max_size=4),
    st.floats(0.0, 10.0, allow_subnormal=False),
)
def test_shift_is_exact_agrees_with_the_sums_at_200_bits(delays: list[float], delta: float):
    """``shift_is_exact`` is True exactly when every ``t + delta`` (mpmath, exactly) is a double."""
    F = QuasiPolynomial([[1.0]] * len(delays), delays)
    exact = all(mp.fadd(t, delta, exact=True) == mp.mpf(t + delta) for _, t in F.point_terms)
    assert F.shift_is_exact(delta) == exact


def test_the_collocated_scope_names_the_observer_delays_it_rounds():
    """The proven collocated observer with ``delta_o = 0.05`` holds ``1.5 + 0.05`` and ``3.0 + 0.05`` rounded: the
    scope says so (before: "the plant as given"); ``delta_o = 0.5`` (exact sums) keeps "the plant as given"."""
    plant = Hyperbolic2x2(1, 2, 0.4, 0.5, 1, 0.3)
    assert mp.fadd(1.5, 0.05, exact=True) != mp.mpf(1.5 + 0.05)
    rounded = CollocatedOutputFeedback(StateFeedback(-0.2), 0.05)
    scope = loop_scope(plant, rounded, None, loop_factors(plant, rounded))
    assert "1.5 + delta_o and 3.0 + delta_o as the nearest doubles" in scope
    assert "the plant as given" not in scope
    exact = CollocatedOutputFeedback(StateFeedback(-0.2), 0.5)
    assert "the plant as given" in loop_scope(plant, exact, None, loop_factors(plant, exact))


def test_the_delayed_sum_encloses_the_loop_with_the_delay_exact():
    """``DelayedSumBalls(A, B, delta)`` (core) contains ``A + B e^{-delta s}`` with ``1 + 0.1`` and the kernel's
    nodes moved exactly (mpmath, kernel integrated by ``mpmath.quad``), ``F``, ``F'`` and ``F''``."""
    A = QuasiPolynomial([[-1.0, 1.0]], [0.0])  # s - 1
    B = QuasiPolynomial([[0.5]], [1.0], [DistributedDelay([0.0, 0.25, 0.75], [1.0, -2.0, 0.5], poly=[0.25])])
    delta = 0.1
    balls = DelayedSumBalls(A, B, delta, prec=100)  # 30 digits: the 40-digit oracle is far narrower

    def F(s: mp.mpc) -> mp.mpc:
        d = mp.mpf(delta)
        kernel = mp.quad(lambda nu: _hat(nu) * mp.exp(-nu * s), [0, mp.mpf(0.25), mp.mpf(0.75)])
        return s - 1 + (mp.mpf(0.5) * mp.exp(-s) + mp.mpf(0.25) * kernel) * mp.exp(-d * s)

    with mp.workdps(40):
        for s in (complex(0.3, 2.0), complex(-0.5, 17.0)):
            for k in range(3):
                assert _contains(balls(s, k), mp.diff(F, mp.mpc(s), k)), (s, k)


def _hat(nu: mp.mpf) -> mp.mpf:
    """The linear interpolant of the values ``1, -2, 0.5`` at ``0, 0.25, 0.75`` (its slopes -12 and 5 exact)."""
    a, b = mp.mpf(0.25), mp.mpf(0.75)
    if nu <= a:
        return 1 + (-2 - 1) * nu / a
    return -2 + (mp.mpf(0.5) + 2) * (nu - a) / (b - a)


def test_a_count_proven_with_the_delayed_sum(monkeypatch: pytest.MonkeyPatch):
    """``unstable_count(..., balls=DelayedSumBalls(...))``: ``s - 1 + e^{-(1 + 0.1) s} / 2`` has one zero in
    ``Re s > 0`` (real: ``s - 1 + e^{-1.1 s}/2`` is -0.5 at 0 and grows to +inf), ``s + 2 - e^{-(1 + 0.1) s}``
    none (``|s + 2| >= 2 > 1`` there); the count is proven with the enclosure given (``count_roots`` receives it)."""
    import nrobust.margins.count as count_module

    given_balls = []
    count_roots = count_module.count_roots

    def recording(*args: object, **kwargs: object) -> object:
        given_balls.append(kwargs.get("balls"))
        return count_roots(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(count_module, "count_roots", recording)
    for poly, expected in (([-1.0, 1.0], 1), ([2.0, 1.0], 0)):
        A = QuasiPolynomial([poly], [0.0])
        B = QuasiPolynomial([[0.5 if expected else -1.0]], [1.0])
        assert not B.shift_is_exact(0.1)
        balls = DelayedSumBalls(A, B, 0.1)
        given_balls.clear()
        count = unstable_count(A + B.shift(0.1), 4.0, rigorous=True, balls=balls)
        assert count.count == expected
        assert given_balls and all(b is balls for b in given_balls)
