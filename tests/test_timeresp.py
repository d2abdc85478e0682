"""Time responses of delay systems in LFT form against closed forms and python-control.

Oracles share no code with :mod:`nrobust.lti.timeresp`: piecewise closed forms derived by the
method of steps (by hand, or as polynomial recursions evaluated with mpmath at 30-40 digits
in this file), python-control on delay-free systems, and the time invariance of the loop.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import control
import mpmath as mp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nrobust.errors import ConvergenceError, ParameterError
from nrobust.lti import LFTSystem, forced_response, impulse_response, initial_response, step_response


def _m(x: object) -> np.ndarray:
    return np.atleast_2d(np.asarray(x, dtype=float))


@dataclass
class Loop:
    """An LFT delay system: the attributes :class:`nrobust.lti.LFTSystem` asks for."""

    A: np.ndarray
    B1: np.ndarray
    B2: np.ndarray
    C1: np.ndarray
    C2: np.ndarray
    D11: np.ndarray
    D12: np.ndarray
    D21: np.ndarray
    D22: np.ndarray
    tau: np.ndarray = field(default_factory=lambda: np.ones(1))


def fopdt_loop(a: float, k: float, tau: float, d22: float = 0.0) -> Loop:
    """Unity feedback around ``k e^{-tau s} / (s + a)``: ``x' = -a x + k w``, ``z = r - x + d22 w``."""
    return Loop(_m(-a), _m(0.0), _m(k), _m(1.0), _m(-1.0), _m(0.0), _m(0.0), _m(1.0), _m(d22), np.array([tau]))


def test_protocol_is_satisfied_by_a_dataclass() -> None:
    loop: LFTSystem = fopdt_loop(1.0, 1.0, 1.0)
    assert step_response(loop, [0.0, 1.0]).outputs.shape == (2,)


def test_controlsystems_jl_delayed_integrator() -> None:
    # ControlSystems.jl's test suite, test_delayed_systems.jl ("Test with known solution";
    # lib/ControlSystemsBase/test/ today, test/ in older releases):
    # step(feedback(delay(1) * 2/s, 1), 3) is 0 (t < 1), 2(t - 1) (1 <= t < 2),
    # 2(t - 1) - 2(t - 2)^2 (2 <= t <= 3). LFT form: x' = 2 w, w(t) = z(t - 1), z = r - x.
    loop = Loop(_m(0.0), _m(0.0), _m(2.0), _m(1.0), _m(-1.0), _m(0.0), _m(0.0), _m(1.0), _m(0.0))
    t = np.linspace(0.0, 3.0, 301)
    exact = np.where(t < 1, 0.0, np.where(t < 2, 2 * (t - 1), 2 * (t - 1) - 2 * (t - 2) ** 2))
    np.testing.assert_allclose(step_response(loop, t).outputs, exact, rtol=0, atol=1e-12)
    # The impulse response is the derivative: the Dirac enters the delay line (D21 = 1) and
    # makes x jump by B2 = 2 at t = 1.
    derivative = np.where(t < 1, 0.0, np.where(t < 2, 2.0, 2.0 - 4 * (t - 2)))
    np.testing.assert_allclose(impulse_response(loop, t).outputs, derivative, rtol=0, atol=1e-12)
    # Same file: step(delay(1) * delay(1) * 1/s) on 0:0.01:4 is [zeros(200); 0:0.01:2]. Two
    # channels in a chain, z_2 = w_1 (D22 = [[0, 0], [1, 0]]), then x' = w_2.
    chain = Loop(
        _m(0.0), _m(0.0), _m([[0.0, 1.0]]), _m(1.0), np.zeros((2, 1)), _m(0.0), np.zeros((1, 2)),
        _m([[1.0], [0.0]]), _m([[0.0, 0.0], [1.0, 0.0]]), np.array([1.0, 1.0]),
    )  # fmt: skip
    t = np.linspace(0.0, 4.0, 401)
    np.testing.assert_allclose(step_response(chain, t).outputs, np.maximum(t - 2.0, 0.0), rtol=0, atol=1e-13)


def horner(coefs: list[mp.mpf], s: mp.mpf) -> mp.mpf:
    """``sum_i coefs[i] s^i`` (ascending coefficients)."""
    out = mp.mpf(0)
    for c in reversed(coefs):
        out = out * s + c
    return out


def fopdt_step_exact(a: float, k: float, tau: float, times: np.ndarray) -> np.ndarray:
    """Step response of the FOPDT loop by the method of steps, as a recursion in mpmath.

    On ``[j tau, (j + 1) tau]`` with ``s = t - j tau``, ``x = alpha_j + e^{-a s} P_j(s)``:
    ``x' = -a x + k (1 - x(t - tau))`` gives ``alpha_j = k (1 - alpha_{j-1}) / a``,
    ``P_j' = -k P_{j-1}`` and ``P_j(0) = x(j tau) - alpha_j`` (continuity); ``x = 0`` on ``[0, tau)``.
    """
    mp.mp.dps = 30
    A, K, TAU = mp.mpf(a), mp.mpf(k), mp.mpf(tau)
    alphas, polys = [mp.mpf(0)], [[mp.mpf(0)]]
    for _ in range(int(max(times) / tau) + 1):
        q = polys[-1]
        alpha = K * (1 - alphas[-1]) / A
        p = [mp.mpf(0)] + [-K * q[i] / (i + 1) for i in range(len(q))]
        p[0] = alphas[-1] + mp.exp(-A * TAU) * horner(q, TAU) - alpha
        alphas.append(alpha)
        polys.append(p)
    out = []
    for t in times:
        j = int(mp.floor(mp.mpf(t) / TAU))
        s = mp.mpf(t) - j * TAU
        out.append(float(alphas[j] + mp.exp(-A * s) * horner(polys[j], s)))
    return np.array(out)


def test_fopdt_closed_loop_by_hand() -> None:
    a, k = 1.0, 1.5
    t = np.linspace(0.0, 3.0, 151)
    # By hand: x = 0 on [0, 1); x' = -a x + k on [1, 2): x = (k/a)(1 - e^{-a(t-1)});
    # on [2, 3): x' = -a x + k - k x(t - 1) = -a x + k (1 - k/a) + (k^2/a) e^{-a(t-2)}, so
    # x = x(2) e^{-a s} + (k (1 - k/a)/a)(1 - e^{-a s}) + (k^2/a) s e^{-a s}, s = t - 2.
    s = t - 2
    x2 = k / a * (1 - np.exp(-a))
    third = x2 * np.exp(-a * s) + k * (1 - k / a) / a * (1 - np.exp(-a * s)) + k**2 / a * s * np.exp(-a * s)
    exact = np.where(t < 1, 0.0, np.where(t < 2, k / a * (1 - np.exp(-a * (t - 1))), third))
    response = step_response(fopdt_loop(a, k, 1.0), t)
    np.testing.assert_allclose(response.outputs, exact, rtol=0, atol=1e-12)
    # The recursion reproduces the hand-derived pieces, then checks 40 delay intervals.
    np.testing.assert_allclose(fopdt_step_exact(a, k, 1.0, t), exact, rtol=0, atol=1e-14)
    long = np.linspace(0.0, 40.0, 801)
    np.testing.assert_allclose(
        step_response(fopdt_loop(a, k, 1.0), long).outputs, fopdt_step_exact(a, k, 1.0, long), rtol=0, atol=1e-11
    )


def neutral_exact(a: float, c: float, times: np.ndarray) -> np.ndarray:
    """``x`` and ``x'`` of ``x'(t) + c x'(t - 1) = -a x(t)``, ``x = 1`` on ``(-oo, 0]`` (mpmath).

    Method of steps: on ``[j, j + 1]``, ``x = e^{-a s} P_j(s)`` (``s = t - j``) with ``P_0 = 1``,
    ``P_j' = -c (P_{j-1}' - a P_{j-1})`` and ``P_j(0) = e^{-a} P_{j-1}(1)``: ``x`` is continuous
    and ``x'`` jumps by ``-a (-c)^j`` at ``t = j``.
    """
    mp.mp.dps = 40
    A, C = mp.mpf(a), mp.mpf(c)
    polys = [[mp.mpf(1)]]
    for _ in range(int(max(times)) + 1):
        q = polys[-1]
        dq = [i * q[i] for i in range(1, len(q))] + [mp.mpf(0)]
        p = [mp.mpf(0)] + [-C * (dq[i] - A * q[i]) / (i + 1) for i in range(len(q))]
        p[0] = mp.exp(-A) * sum(q)
        polys.append(p)
    out = np.empty((2, len(times)))
    for n, t in enumerate(times):
        j = int(mp.floor(mp.mpf(t)))
        s = mp.mpf(t) - j
        q = polys[j]
        val = horner(q, s)
        der = horner([i * q[i] for i in range(1, len(q))], s)
        out[:, n] = float(mp.exp(-A * s) * val), float(mp.exp(-A * s) * (der - A * val))
    return out


def test_neutral_scalar_equation_keeps_its_jumps() -> None:
    # x'(t) + c x'(t - 1) = -a x(t) in LFT form: z = x' = -a x - c w, w(t) = z(t - 1),
    # x' = z; outputs y = (x, x'). Zero history of z is x' = 0 before 0 (x = 1 there).
    a, c = 1.0, 0.8
    loop = Loop(
        _m(-a),
        np.zeros((1, 0)),
        _m(-c),
        _m([[1.0], [-a]]),
        _m(-a),
        np.zeros((2, 0)),
        _m([[0.0], [-c]]),
        np.zeros((1, 0)),
        _m(-c),
    )
    jumps = np.arange(1, 16)
    t = np.sort(np.concatenate((np.linspace(0.0, 15.0, 301), jumps - 1e-9)))
    response = initial_response(loop, t, X0=1.0)
    exact = neutral_exact(a, c, t)
    np.testing.assert_allclose(response.outputs, exact, rtol=0, atol=1e-11)
    # The jumps of x' at t = j travel undamped: -a (-c)^j (0.035 at j = 15), to 1e-8
    # (the left value is taken 1e-9 early, where x'' is O(1)).
    after = response.outputs[1, np.searchsorted(t, jumps)]
    before = response.outputs[1, np.searchsorted(t, jumps - 1e-9)]
    np.testing.assert_allclose(after - before, -a * (-c) ** jumps, rtol=0, atol=1e-8)


def delay_free_pair() -> tuple[object, Loop]:
    A = np.array([[-1.0, 2.0, 0.0], [-2.0, -1.0, 0.5], [0.3, 0.0, -3.0]])
    B = np.array([[1.0, 0.0], [0.0, 1.0], [0.5, -1.0]])
    C = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
    D = np.array([[0.0, 0.1], [0.2, 0.0]])
    # A delay channel that exists (a neutral chain z = ... + 0.5 w) but does not act on x or y.
    loop = Loop(
        A, B, np.zeros((3, 1)), C, np.ones((1, 3)), D, np.zeros((2, 1)), np.ones((1, 2)), _m(0.5), np.array([0.7])
    )
    return control.ss(A, B, C, D), loop


def test_delay_free_limit_agrees_with_python_control() -> None:
    ss, loop = delay_free_pair()
    t = np.linspace(0.0, 10.0, 201)
    x0 = [1.0, 0.0, -1.0]
    ours, theirs = step_response(loop, t), control.step_response(ss, t)
    assert ours.outputs.shape == theirs.outputs.shape == (2, 2, 201)
    assert ours.states.shape == theirs.states.shape
    np.testing.assert_allclose(ours.outputs, theirs.outputs, rtol=0, atol=1e-8)
    U = np.vstack((np.sin(t), np.cos(3 * t)))
    ours, theirs = forced_response(loop, t, U, x0), control.forced_response(ss, t, U, x0)
    assert ours.outputs.shape == theirs.outputs.shape == (2, 201)
    np.testing.assert_allclose(ours.outputs, theirs.outputs, rtol=0, atol=1e-8)
    np.testing.assert_allclose(ours.states, theirs.states, rtol=0, atol=1e-8)
    ours, theirs = initial_response(loop, t, x0), control.initial_response(ss, t, x0)
    np.testing.assert_allclose(ours.outputs, theirs.outputs, rtol=0, atol=1e-8)
    with pytest.warns(UserWarning, match="feedthrough"):
        theirs = control.impulse_response(ss, t)
    np.testing.assert_allclose(impulse_response(loop, t).outputs, theirs.outputs, rtol=0, atol=1e-8)


def test_error_decreases_with_the_tolerance() -> None:
    # A stiff-ish loop (a tau = 16) whose pieces the tolerance decides.
    a, k, tau = 8.0, 4.0, 2.0
    t = np.linspace(0.0, 20.0, 401)
    exact = fopdt_step_exact(a, k, tau, t)
    errors, estimates, pieces = [], [], []
    for rtol in (1e-3, 1e-7, 1e-11):
        response = step_response(fopdt_loop(a, k, tau), t, rtol=rtol, atol=0.0)
        errors.append(float(np.abs(response.outputs - exact).max()))
        estimates.append(response.error_estimate)
        pieces.append(response.n_pieces)
        assert errors[-1] <= rtol  # the scale (largest |x|, |z|) is 1 here
    assert errors[0] > 1e2 * errors[1] > 1e4 * errors[2]  # measured: 6e-6, 8e-9, 1e-13
    assert pieces[0] < pieces[1] < pieces[2]
    assert all(e <= est for e, est in zip(errors, estimates, strict=True))


def test_pure_delay_and_neutral_chain() -> None:
    # No state: y = w = z(t - 1), z = u + d22 w: a delayed step, and for d22 = 1/2 the
    # geometric staircase 1, 1.5, 1.75 (each jump half the previous one).
    empty = np.zeros((0, 1))
    loop = Loop(np.zeros((0, 0)), empty, empty, empty.T, empty.T, _m(0.0), _m(1.0), _m(1.0), _m(0.0))
    t = np.array([0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0])
    np.testing.assert_allclose(step_response(loop, t).outputs, [0, 0, 1, 1, 1, 1, 1], atol=1e-15)
    loop.D22 = _m(0.5)
    np.testing.assert_allclose(step_response(loop, t).outputs, [0, 0, 1, 1, 1.5, 1.5, 1.75], atol=1e-15)
    # A history of the delay line comes out first: y(t) = sin(t - 1) on [0, 1).
    free = initial_response(loop, t[:2], history=lambda s: [np.sin(s)])
    np.testing.assert_allclose(free.outputs, np.sin(t[:2] - 1.0), atol=1e-15)


def test_mimo_shapes_and_incommensurate_delays() -> None:
    loop = Loop(
        _m([[-1.0, 0.2], [0.0, -2.0]]),
        _m([[1.0, 0.0], [0.0, 1.0]]),
        _m([[0.5, 0.0], [0.0, 0.3]]),
        _m([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]),
        _m([[-1.0, 0.0], [0.0, -1.0]]),
        np.zeros((3, 2)),
        np.zeros((3, 2)),
        _m([[1.0, 0.0], [0.0, 1.0]]),
        np.zeros((2, 2)),
        np.array([1.0, np.sqrt(2.0)]),
    )
    t = np.linspace(0.0, 8.0, 81)
    response = step_response(loop, t)
    assert response.outputs.shape == (3, 2, 81) and response.states.shape == (2, 2, 81)
    assert response.inputs.shape == (2, 2, 81)
    # Superposition: the step of both inputs together is the sum of the columns.
    both = forced_response(loop, t, np.ones((2, 81)))
    np.testing.assert_allclose(both.outputs, response.outputs.sum(axis=1), rtol=0, atol=1e-11)
    # Until the first delay the loop is open: x' = A x + B1 e_j, decoupled from w.
    first = t < 1.0
    open_loop = control.step_response(control.ss(loop.A, loop.B1, loop.C1, np.zeros((3, 2))), t[first])
    np.testing.assert_allclose(response.outputs[:, :, first], open_loop.outputs, rtol=0, atol=1e-10)


@settings(max_examples=5, deadline=None)
@given(
    a=st.floats(0.2, 3.0),
    k=st.floats(-1.0, 1.0),
    tau=st.floats(0.3, 2.0),
    d22=st.floats(-0.6, 0.6),
    shift=st.floats(0.05, 2.0),
)
def test_time_invariance(a: float, k: float, tau: float, d22: float, shift: float) -> None:
    # The response to a step applied at `shift` is the step response delayed by `shift`.
    loop = fopdt_loop(a, k, tau, d22)
    grid = np.linspace(0.0, 6.0, 61)
    t = np.concatenate((np.linspace(0.0, shift, 4, endpoint=False), shift + grid))
    step = step_response(loop, grid).outputs
    late = forced_response(loop, t, lambda s: 1.0 if s >= shift else 0.0, breaks=[shift]).outputs
    np.testing.assert_allclose(late[:4], 0.0, atol=0)
    np.testing.assert_allclose(late[4:], step, rtol=0, atol=1e-9)


def test_bad_input_names_the_parameter() -> None:
    loop = fopdt_loop(1.0, 1.0, 1.0)
    with pytest.raises(ParameterError, match=r"^T must be a strictly increasing"):
        step_response(loop, [0.0, 2.0, 1.0])
    with pytest.raises(ParameterError, match=r"^U must be"):
        forced_response(loop, [0.0, 1.0, 2.0], np.ones((2, 3)))
    with pytest.raises(ParameterError, match=r"^sys\.tau must be"):
        step_response(fopdt_loop(1.0, 1.0, 0.0), 1.0)
    with pytest.raises(ParameterError, match=r"^sys\.B2 must be"):
        step_response(Loop(_m(0.0), _m(0.0), np.ones((1, 2)), _m(1.0), _m(1.0), _m(0.0), _m(0.0), _m(1.0), _m(0.0)))
    with pytest.raises(ParameterError, match=r"^sys must be"):
        step_response(object())
    with pytest.raises(ParameterError, match=r"^X0 must be"):
        initial_response(loop, 1.0, [1.0, 2.0])
    with pytest.raises(ParameterError, match=r"^rtol must be"):
        step_response(loop, 1.0, rtol=0.0)
    # Two incommensurate delays of 1e-3 over 1000 time units: about 3e11 breakpoints,
    # refused from their count before any array of them exists.
    many = Loop(
        _m(-1.0),
        _m(0.0),
        _m([[1.0, 1.0]]),
        _m(1.0),
        _m([[1.0], [1.0]]),
        _m(0.0),
        _m([[0.0, 0.0]]),
        _m([[1.0], [1.0]]),
        np.zeros((2, 2)),
        np.array([1e-3, 1e-3 * np.sqrt(2.0)]),
    )
    with pytest.raises(ParameterError, match=r"^max_nodes must be"):
        step_response(many, [0.0, 1000.0])


def test_work_bound_on_pieces() -> None:
    # Three breakpoints (0, 2, 4) fit in max_nodes = 3, but a tau = 16 needs more pieces at 1e-12.
    with pytest.raises(ConvergenceError, match="max_nodes = 3"):
        step_response(fopdt_loop(8.0, 4.0, 2.0), [0.0, 4.0], rtol=1e-12, max_nodes=3)
    assert step_response(fopdt_loop(8.0, 4.0, 2.0), [0.0, 4.0], rtol=1e-12).n_pieces > 3


def test_impulse_jump_at_the_final_breakpoint_is_kept() -> None:
    # x' = -x + z, z = u + c z(t - 1), y = x (B1 = D21 = 1, B2 = D22 = c): the impulse gives
    # x(t) = sum_{k <= t} c^k e^{-(t - k)} (right-continuous: the Dirac arriving at t = k is
    # counted at k), including at t = T[-1] = 3, a breakpoint.
    c = 0.5
    loop = Loop(_m(-1.0), _m(1.0), _m(c), _m(1.0), _m(0.0), _m(0.0), _m(0.0), _m(1.0), _m(c))
    for T in (np.linspace(0.0, 3.0, 8), np.linspace(0.0, 2.0, 5)):
        exact = [sum(c**k * np.exp(-(t - k)) for k in range(4) if k <= t) for t in T]
        # the step solution is exact to rounding (piecewise exponentials, rtol 1e-10 met)
        np.testing.assert_allclose(impulse_response(loop, T).outputs, exact, rtol=1e-10, atol=1e-14)


def test_user_callables_with_non_finite_values_are_refused() -> None:
    loop = fopdt_loop(1.0, 1.0, 1.0)
    T = np.linspace(0.0, 2.0, 5)
    with pytest.raises(ParameterError, match=r"^U must be a callable returning 1 finite"):
        forced_response(loop, T, U=lambda t: np.nan)
    with pytest.raises(ParameterError, match=r"^U must be a callable returning 1 finite"):
        forced_response(loop, T, U=lambda t: 1.0 if t < 1.0 else np.inf)
    with pytest.raises(ParameterError, match=r"^history must be a callable returning") as info:
        initial_response(loop, 2.0, history=lambda t: [np.nan])
    with pytest.raises(ParameterError, match=r"^U must be a callable returning .* raised") as info:
        forced_response(loop, T, U=lambda t: 1.0 / 0.0)
    assert isinstance(info.value.__cause__, ZeroDivisionError)
    with pytest.raises(ParameterError, match=r"^history must be a callable returning .* raised") as info:
        initial_response(loop, 2.0, history=lambda t: [{"z": 0.0}[str(t)]])
    assert isinstance(info.value.__cause__, KeyError)
