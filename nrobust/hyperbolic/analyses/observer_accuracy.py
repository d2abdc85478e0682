"""How far an output feedback's delay margin is from the PDE's: the observer term's share of the model error.

On the ``"observer"`` route (:func:`~nrobust.hyperbolic.loops.controllers.loop_route`: a law with
integral gains, couplings too strong for the observer's proven enclosure, or a collocated observer on a
coupled plant) the state feedback is in closed form and only the observer's term is computed in
floating point, so the loop is a model of the PDE. :func:`observer_model_error` estimates the
distances of its margin and its crossing frequency to the PDE's, which
:attr:`nrobust.margins.DelayMargin.model_error` and
:attr:`~nrobust.margins.DelayMargin.omega_model_error` add to their accuracies:

* :class:`~nrobust.hyperbolic.loops.controllers.OutputFeedback`: its term ``G`` is computed to
  a stated accuracy ``e`` (the sup-norm error of its kernel on a support of length ``T``), so
  ``A_o = A - n G e^{-delta_o s}`` and ``B_o = B + n G`` err by ``e T |n(i w)|`` each on the
  axis, ``F(i w; delta)`` by twice that, and the crossing delay by that over
  ``|dF/d delta| = w |B_o(i w)|``: first order, times :data:`OBSERVER_SAFETY`; the crossing
  frequency by the largest ``|dw|`` over the phases of ``dF`` (``i F_s dw + F_delta d delta = -dF``).
* :class:`~nrobust.hyperbolic.loops.controllers.CollocatedOutputFeedback`: its terms come from
  the kernels of the dual plant on a grid of ``n`` points (201 by default), whose sup-norm
  change between grids overstates the margin's by orders of magnitude (on the paper's plant
  ``1.7e-6`` under U_BS2(0.1) against a margin error of ``1.6e-9``). The estimate is a convergence study in the
  observer's grid alone, the state feedback kept on its route: the margin with the observer's
  responses ``C_u, H_y`` on ``n``, ``(n + 1) / 2`` and ``(n + 3) / 4`` points, each crossing
  near the margin (within 1% of it) moved to first order and studied on its own, the margin's
  error taken as the largest of theirs (the loop is affine in the responses, so the change of
  ``F`` at the crossing is exact; the crossings move by ``1e-6`` at most, the second-order
  terms are below ``1e-11``), as :func:`nrobust.certify` studies the kernel route. The loop
  converges at third order in the observer's grid (the dual plant's kernels, their composition
  ``F = (I - K') f`` with the law's gains by the trapezoidal rule with Gregory's end corrections,
  the splines). When the two differences have one sign and the second is at most half the first
  (observed ratio ``r = d_2 / d_1 <= 1/2``), the remaining error is the geometric tail
  ``|d_2| r / (1 - r)`` at the observed ratio, never taken below the third order's (``r >= 1/8``:
  ``|d_2| / 7``), and the estimate is :data:`STUDY_SAFETY` times it; otherwise twice
  :data:`STUDY_SAFETY` times the largest difference, a
  rough estimate. Floating point, not proven.
"""

from __future__ import annotations

import numpy as np

from ...margins.margin import DelayMargin
from ...quasipoly import QuasiPolynomial
from ...roots import SpectralAbscissa
from ..kernels.constant import DEFAULT_KERNEL_GRID, MIN_KERNEL_GRID
from ..loops.controllers import (
    CollocatedOutputFeedback,
    FilteredController,
    OpenLoop,
    OutputFeedback,
    collocated_responses_of,
    loop_factors,
    loop_route,
    observer_of,
    unfiltered,
)
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2

__all__ = ["OBSERVER_SAFETY", "STUDY_SAFETY", "crossing_delay", "observer_model_error", "observer_rate_error"]

#: Safety factor of the first-order estimate of an :class:`OutputFeedback`'s margin error (its observer
#: term's stated accuracy is itself an estimate, and the second-order terms are left out).
OBSERVER_SAFETY = 10.0
#: Safety factor of the convergence study of a collocated observer (also used by :mod:`.mismatch`). Against the
#: PDE's loops (40 digits, ``tests/test_collocated_integral_law_oracle.py``) under U_BS2(K) on five plants (``K``
#: from 0.05 to 0.2, ``kappa`` from -0.71 to 0; nine margins) the grids 51, 101, 201 show ratios 6.5 to 8.8 and the
#: errors of the 201-point margins and crossing frequencies are 0.74 to 1.0 times the tail taken by the study (at
#: most 1.08 times the tail at the observed ratio); 2 also covers a ratio falling to 4.5 (order 2.2) beyond them.
STUDY_SAFETY = 2.0
#: The order of the collocated observer's loop in its grid: the study assumes no faster convergence.
_ORDER = 3
#: Newton steps of :func:`crossing_delay`.
_NEWTON_STEPS = 30
#: Crossings of the design whose first delay is within this fraction of the margin are continued to the
#: other grids (the margin is the smallest of them there: the grids move a crossing far less than this).
_NEAR_MARGIN = 0.01


def crossing_delay(A: QuasiPolynomial, B: QuasiPolynomial, w0: float) -> tuple[float, float] | None:
    """``(w, tau)``: a zero ``w > 0`` of ``g(w) = |A(i w)|^2 - |B(i w)|^2`` that Newton's method reaches from ``w0``,
    and the smallest delay ``tau >= 0`` with ``A(i w) + B(i w) e^{-i w tau} = 0``; None when it does not converge.

    ``tau = theta / w``, ``theta = arg(-B(i w) / A(i w))`` in ``[0, 2 pi)``: the loop has the zero ``i w`` at
    that delay, so its delay margin is at most ``tau`` (to the rounding of ``w``, at the level of ``1e-14``).
    """
    w = w0
    for _ in range(_NEWTON_STEPS):
        s = np.array([1j * w])
        a, b = complex(A(s)[0]), complex(B(s)[0])
        da, db = 1j * complex(A.deriv_at(s)[0]), 1j * complex(B.deriv_at(s)[0])  # d/dw of A(i w), B(i w)
        g_w = 2.0 * ((a.conjugate() * da).real - (b.conjugate() * db).real)
        if g_w == 0.0 or a == 0.0:
            return None
        step = (abs(a) ** 2 - abs(b) ** 2) / g_w
        w -= step
        if not w > 0.0:
            return None
        if abs(step) <= 1e-14 * w:
            break
    else:
        return None
    s = np.array([1j * w])
    a, b = complex(A(s)[0]), complex(B(s)[0])
    if not abs(abs(a) - abs(b)) <= 1e-12 * (abs(a) + abs(b)):
        return None
    return w, float(np.mod(np.angle(-b / a), 2.0 * np.pi)) / w


def observer_model_error(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    controller: OutputFeedback | CollocatedOutputFeedback,
    margin: DelayMargin,
    factors: tuple[QuasiPolynomial, QuasiPolynomial],
) -> tuple[float | None, float | None]:
    """The estimated distances of ``margin`` and of its crossing frequency (of ``controller``'s loop ``A_o, B_o``
    on the ``"observer"`` route) to the PDE's (module notes); None where not estimated.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant (a general plant with a constant ``lam/mu``: a collocated observer needs its normal form).
    controller : OutputFeedback or CollocatedOutputFeedback
        The output feedback whose loop ``margin`` is about.
    margin : DelayMargin
        Its delay margin (floating point or proven).
    factors : (QuasiPolynomial, QuasiPolynomial)
        The loop's factors ``(A_o, B_o)``.

    Returns
    -------
    (float or None, float or None)
        For the margin and for ``margin.omega``: 0 and None for a margin of 0 or ``inf`` (decided by
        the structure of the loop); None off the ``"observer"`` route, without a crossing frequency, at a
        tangency, or when the observer term states no accuracy.
    """
    if not np.isfinite(margin.margin) or margin.margin == 0.0:
        return 0.0, None
    if loop_route(system, controller) != "observer" or margin.omega is None or margin.omega <= 0.0:
        return None, None
    if isinstance(controller, CollocatedOutputFeedback):
        return _collocated_error(system, controller, margin, factors)
    term = observer_of(system, controller)
    if term is None:
        return None, None
    inner = controller.controller
    w = float(margin.omega)
    numerator = abs(1.0 + inner.a * 1j * w) if isinstance(inner, FilteredController) else 1.0
    total = sum(d.b - d.a for d in term.product.distributed)
    change = 2.0 * term.accuracy * total * numerator  # a bound of |dF(i w)| from the term's stated accuracy
    slope = w * abs(complex(factors[1](np.array([1j * w]))[0]))
    inverse = _crossing_inverse(factors, w, float(margin.margin))
    if slope <= 0.0 or inverse is None:
        return None, None
    # the delay as before (dF against d F / d delta); the frequency: the largest dw over the phases of dF
    return OBSERVER_SAFETY * change / slope, OBSERVER_SAFETY * change * float(np.hypot(*inverse[0]))


def _crossing_inverse(factors: tuple[QuasiPolynomial, QuasiPolynomial], w: float, tau: float) -> np.ndarray | None:
    """The inverse of the real ``2 x 2`` matrix taking ``(dw, dtau)`` to the change ``(Re, Im)`` of ``F(i w; tau)``.

    ``F = A_o + B_o e^{-tau s}``: ``dF = i F_s dw + F_tau dtau`` with ``F_tau = -s B_o e^{-tau s}``, so a change
    ``dF`` of the loop moves the crossing by ``-M^{-1} (Re dF, Im dF)``. None when ``M`` is singular (a tangency).
    """
    A, B = factors
    s = np.array([1j * w])
    e = np.exp(-tau * s[0])
    b = complex(B(s)[0])
    f_s = complex(A.deriv_at(s)[0]) + (complex(B.deriv_at(s)[0]) - tau * b) * e
    f_tau = -s[0] * b * e
    matrix = np.array([[(1j * f_s).real, f_tau.real], [(1j * f_s).imag, f_tau.imag]])
    if not abs(np.linalg.det(matrix)) > 1e-14 * float(np.max(np.abs(matrix))) ** 2:
        return None
    return np.linalg.inv(matrix)


def _study(d1: float, d2: float) -> float:
    """The error of the finest value from its changes ``d1`` then ``d2`` as the grid halves (module notes)."""
    if d1 * d2 > 0.0 and abs(d2) <= 0.5 * abs(d1):
        ratio = max(d2 / d1, 2.0**-_ORDER)
        return STUDY_SAFETY * abs(d2) * ratio / (1.0 - ratio)
    return 2.0 * STUDY_SAFETY * max(abs(d1), abs(d2))


def _collocated_error(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    controller: CollocatedOutputFeedback,
    margin: DelayMargin,
    factors: tuple[QuasiPolynomial, QuasiPolynomial],
) -> tuple[float | None, float | None]:
    """The convergence study in the collocated observer's grid (module notes), for the margin and its frequency."""
    if not isinstance(system, Hyperbolic2x2) or margin.omega is None:
        return None, None
    near = margin.margin * (1.0 + _NEAR_MARGIN)
    crossings = [(c.omega, c.delays[0]) for c in margin.crossings if c.omega > 0.0 and c.delays and c.delays[0] <= near]
    if not crossings:
        return None, None
    critical = int(np.argmin([abs(w - margin.omega) for w, _ in crossings]))
    grid = DEFAULT_KERNEL_GRID
    coarse, coarsest = (grid + 1) // 2, (grid + 3) // 4
    if coarsest < MIN_KERNEL_GRID:
        return None, None
    fine = collocated_responses_of(system, controller, grid)
    rows = []
    for n in (coarse, coarsest):
        other = collocated_responses_of(system, controller, n)
        row = [_crossing_change(system, controller, factors, fine, other, w, tau) for w, tau in crossings]
        if any(change is None for change in row):
            return None, None
        rows.append(row)
    # the margin is the least of the crossings' delays, so its error is at most the largest of theirs: each
    # crossing studied on its own (the least of the delays on the coarser grids can be another crossing's)
    margin_error = max(
        _study(coarse_change[1] - coarsest_change[1], -coarse_change[1])  # type: ignore[index]
        for coarse_change, coarsest_change in zip(rows[0], rows[1], strict=True)
    )
    w2 = crossings[critical][0]
    w1, w0 = (w2 + row[critical][0] for row in rows)  # type: ignore[index]
    return margin_error, _study(w1 - w0, w2 - w1)


def _crossing_change(
    system: Hyperbolic2x2,
    controller: CollocatedOutputFeedback,
    factors: tuple[QuasiPolynomial, QuasiPolynomial],
    fine: tuple[QuasiPolynomial, QuasiPolynomial],
    other: tuple[QuasiPolynomial, QuasiPolynomial],
    w: float,
    tau: float,
) -> tuple[float, float] | None:
    """The first-order change ``(dw, dtau)`` of the crossing ``(w, tau)`` when the observer's responses are ``other``:
    ``-M^{-1} (Re dF, Im dF)`` (:func:`_crossing_inverse`, :func:`_loop_change`). None at a tangency."""
    inverse = _crossing_inverse(factors, w, tau)
    if inverse is None:
        return None
    d_f = _loop_change(system, controller, fine, other, 1j * w, tau)
    dw, dtau = -inverse @ np.array([d_f.real, d_f.imag])
    return float(dw), float(dtau)


def _loop_change(
    system: Hyperbolic2x2,
    controller: CollocatedOutputFeedback,
    fine: tuple[QuasiPolynomial, QuasiPolynomial],
    other: tuple[QuasiPolynomial, QuasiPolynomial],
    s: complex,
    delay: float,
) -> complex:
    """The change of ``F(s; delay) = A_o(s) + B_o(s) e^{-delay s}`` when the observer's responses are ``other``.

    The loop is ``A_o = d (1 - Phi)(1 - kappa H_y) - n (1 - Phi) C_u e^{-delta_o s}``, ``B_o = n B~ (1 - kappa
    H_y) + n (1 - Phi) C_u`` (:mod:`~nrobust.hyperbolic.loops.collocated`), affine in ``(C_u, H_y)``: the change
    is exact from the responses' values at ``s``.
    """
    at = np.array([s])
    inner = controller.controller
    num = 1.0 + inner.a * s if isinstance(inner, FilteredController) else 1.0
    den = 1.0 + inner.b * s if isinstance(inner, FilteredController) else 1.0
    kappa, delta_o = controller.observer_reflection, controller.observer_delay
    open_loop = complex(loop_factors(system, OpenLoop())[0](at)[0])
    law = complex(loop_factors(system, unfiltered(inner))[1](at)[0])
    d_c = complex(other[0](at)[0]) - complex(fine[0](at)[0])
    d_h = complex(other[1](at)[0]) - complex(fine[1](at)[0])
    d_a = -kappa * den * open_loop * d_h - num * open_loop * d_c * np.exp(-delta_o * s)
    d_b = -kappa * num * law * d_h + num * open_loop * d_c
    return complex(d_a + d_b * np.exp(-delay * s))


def observer_rate_error(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2,
    controller: OutputFeedback | CollocatedOutputFeedback,
    abscissa: SpectralAbscissa,
    factors: tuple[QuasiPolynomial, QuasiPolynomial],
) -> float | None:
    """The estimated distance of the rightmost root of ``controller``'s loop at ``delta = 0`` (``abscissa``, of
    ``A_o + B_o``) to the PDE's, in each of its parts; None where not estimated.

    At ``delta = delta_o`` the loop is ``E`` times the state feedback's, whose factors are in
    closed form: with ``E = 1`` (an :class:`OutputFeedback`, or a collocated observer with
    ``kappa = 0``) and ``delta_o = 0`` the observer's terms cancel and the error is 0. A collocated
    observer with ``kappa != 0`` (the zeros of ``E = 1 - kappa H_y``, from the dual plant's
    kernels, are modes of the loop) or ``delta_o > 0``: the convergence study in the observer's
    grid (module notes), the root moved to first order ``ds = -dF / F'``, the larger of the
    studies of its real and imaginary parts. None for an :class:`OutputFeedback` with
    ``delta_o > 0``, a chain value (the rightmost roots approached at infinity), or no root.
    """
    if loop_route(system, controller) != "observer":
        return None
    kappa = getattr(controller, "observer_reflection", 0.0)
    if kappa == 0.0 and controller.observer_delay == 0.0:
        return 0.0
    root = abscissa.root
    if not isinstance(controller, CollocatedOutputFeedback) or not isinstance(system, Hyperbolic2x2):
        return None
    if root is None or abscissa.approached_at_infinity:
        return None
    A, B = factors
    at = np.array([complex(root)])
    slope = complex(A.deriv_at(at)[0]) + complex(B.deriv_at(at)[0])
    if slope == 0.0:
        return None
    grid = DEFAULT_KERNEL_GRID
    fine = collocated_responses_of(system, controller, grid)
    moves = [
        -_loop_change(system, controller, fine, collocated_responses_of(system, controller, n), complex(root), 0.0)
        / slope
        for n in ((grid + 1) // 2, (grid + 3) // 4)
    ]
    # the finest root minus the coarser ones' (moves[0]: 101 points, moves[1]: 51)
    d2, d1 = -moves[0], moves[0] - moves[1]
    return max(_study(d1.real, d2.real), _study(d1.imag, d2.imag))
