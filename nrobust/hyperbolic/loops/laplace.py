"""Kernel-free route to the open-loop spectrum: the Laplace-domain boundary function.

With zero initial data, the Laplace transform of eqs. (18)-(19) in ``t`` is the
linear ODE in ``x``::

    d/dx [u; v] = A(x, s) [u; v],   A(x, s) = [[-s/lam, sigma_pm(x)/lam],
                                               [-sigma_mp(x)/mu, s/mu]],

(the ``(2, 1)`` entry is ``-sigma_mp/mu`` because ``s v - mu v_x = sigma_mp u``),
started from ``[u; v](0) = [q; 1]`` so that ``u(0) = q v(0)`` holds. The boundary
function ``v(1, s) - rho u(1, s)`` is the control ``U(s)`` that produces this solution;
its zeros are the open-loop eigenvalues, and ``e^{-s/mu} (v(1, s) - rho u(1, s))`` equals
the characteristic function ``1 - rho q e^{-tau s} + int_0^tau N~(nu) e^{-nu s} dnu`` of
the delay form (39) exactly, with no kernels involved.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..._validate import number_array, positive_int
from ...errors import ParameterError
from ..plants.general import GeneralHyperbolic2x2
from ..plants.hyperbolic2x2 import Hyperbolic2x2

__all__ = ["boundary_function", "general_solution", "magnus_steps"]

# Default Magnus steps (varying couplings): at least _MIN_STEPS, and _STEPS_PER_PHASE
# per unit of |s| tau. Measured: absolute error about 1e-9 for |s| <= 200 (the method is
# fourth order; halving the step divides the error by 16).
_MIN_STEPS = 200
_STEPS_PER_PHASE = 5.0
# Below this |Delta| the function sinh(Delta)/Delta is evaluated by its Taylor series.
_SERIES_RADIUS = 1e-2
# Work bound on the Magnus steps (varying couplings), checked before integrating.
_MAX_STEPS = 10**6


def _as_complex(s: Any) -> np.ndarray:
    """``s`` as a complex array of finite numbers, at least one (strings, booleans, ragged refused)."""
    return number_array("s", s, ndim=None).astype(complex)


def _constant_scaled(system: Hyperbolic2x2, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``e^{-s/mu} [u(1, s); v(1, s)]`` for constant couplings, by the closed-form 2x2 exponential.

    ``exp(A) = e^m (cosh(D) I + sinh(D)/D (A - m I))`` with ``m = tr(A)/2`` and
    ``D^2 = ((a - d)/2)^2 + b c``; the factors ``e^{m - s/mu +- D}`` are formed directly so
    that no overflowing exponential is cancelled.
    """
    lam, mu, q = system.lam, system.mu, system.q
    a, d = -s / lam, s / mu
    # constant couplings (the caller checks system.constant_couplings): numbers, not callables
    b, c = float(system.sigma_pm) / lam, -float(system.sigma_mp) / mu  # type: ignore[arg-type]
    # e^{-s/mu} exp(A) = exp(A - (s/mu) I): the scaling that keeps |v(1)| from overflowing.
    e11, e12, e21, e22 = _expm2(a - s / mu, b, c, d - s / mu)
    return e11 * q + e12, e21 * q + e22


def _expm2(
    a: np.ndarray | float, b: np.ndarray | float, c: np.ndarray | float, d: np.ndarray | float
) -> tuple[np.ndarray, ...]:
    """Entries of ``exp([[a, b], [c, d]])`` (elementwise arrays), in closed form."""
    m = 0.5 * (a + d)
    delta = np.sqrt((0.5 * (a - d)) ** 2 + b * c)
    e_plus, e_minus = np.exp(m + delta), np.exp(m - delta)
    cosh = 0.5 * (e_plus + e_minus)
    small = np.abs(delta) < _SERIES_RADIUS
    safe = np.where(small, 1.0, delta)
    d2 = delta * delta
    series = np.exp(m) * (1.0 + d2 / 6.0 * (1.0 + d2 / 20.0 * (1.0 + d2 / 42.0 * (1.0 + d2 / 72.0))))
    sinhc = np.where(small, series, (e_plus - e_minus) / (2.0 * safe))
    return cosh + sinhc * (a - m), sinhc * b, sinhc * c, cosh + sinhc * (d - m)


def magnus_steps(system: Hyperbolic2x2, s: np.ndarray) -> int:
    """Default number of Magnus steps on ``[0, 1]`` for the frequencies ``s``."""
    top = float(np.max(np.abs(s))) if s.size else 0.0
    return max(_MIN_STEPS, int(np.ceil(_STEPS_PER_PHASE * top * system.tau)))


def _magnus_scaled(system: Hyperbolic2x2, s: np.ndarray, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """``e^{-s/mu} [u(1, s); v(1, s)]`` by the fourth-order Magnus integrator, fixed steps.

    Integrates ``z = e^{-s x / mu} [u; v]``, ``z' = B(x) z`` with
    ``B = [[-s tau, sigma_pm/lam], [-sigma_mp/mu, 0]]``, vectorised over ``s``: on each
    step ``z <- exp(Omega) z``, ``Omega = h/2 (B_1 + B_2) + sqrt(3)/12 h^2 [B_2, B_1]``
    with ``B_1, B_2`` at the two Gauss points and ``exp`` in closed form. The large
    term ``-s tau`` is constant, so it enters the commutator only linearly and the
    method keeps its fourth order at high frequency.
    """
    flat = s.ravel()
    h = 1.0 / steps
    g = np.sqrt(3.0) / 6.0
    x1 = (np.arange(steps) + 0.5 - g) * h
    x2 = (np.arange(steps) + 0.5 + g) * h
    p1, p2 = system.sigma_pm_at(x1) / system.lam, system.sigma_pm_at(x2) / system.lam
    m1, m2 = -system.sigma_mp_at(x1) / system.mu, -system.sigma_mp_at(x2) / system.mu
    diag = -flat * system.tau
    f = np.sqrt(3.0) / 12.0 * h * h
    u = np.full(flat.shape, system.q, dtype=complex)
    v = np.ones(flat.shape, dtype=complex)
    for k in range(steps):
        # [B_2, B_1] for B_i = [[diag, p_i], [m_i, 0]].
        e00, e01, e10, e11 = _expm2(
            h * diag + f * (p2[k] * m1[k] - p1[k] * m2[k]),
            0.5 * h * (p1[k] + p2[k]) + f * diag * (p1[k] - p2[k]),
            0.5 * h * (m1[k] + m2[k]) + f * diag * (m2[k] - m1[k]),
            np.full(flat.shape, f * (m2[k] * p1[k] - m1[k] * p2[k]), dtype=complex),
        )
        u, v = e00 * u + e01 * v, e10 * u + e11 * v
    return u.reshape(s.shape), v.reshape(s.shape)


def _general_steps(system: GeneralHyperbolic2x2, s: np.ndarray, steps: int | None) -> int:
    """Magnus steps on ``[0, L]``: the default of :func:`magnus_steps`, work-bounded."""
    if steps is not None:
        return positive_int("steps", steps, maximum=_MAX_STEPS)
    top = float(np.max(np.abs(s))) if s.size else 0.0
    tau = system.tau / system.time_unit
    n_steps = max(_MIN_STEPS, int(np.ceil(_STEPS_PER_PHASE * top * tau)))
    if n_steps > _MAX_STEPS:
        raise ParameterError(
            "s",
            f"of modulus at most {_MAX_STEPS / (_STEPS_PER_PHASE * tau):.6g} "
            f"(the default Magnus steps, {_STEPS_PER_PHASE:g} |s| tau, are at most {_MAX_STEPS})",
            f"max |s| = {top:.6g}",
        )
    return n_steps


def general_solution(
    system: GeneralHyperbolic2x2, s: Any, steps: int | None = None, *, nodes: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scaled Laplace-domain solution of a general plant, ``e^{-s psi(x)} [u; v](x, s)``.

    The transformed plant is the ODE ``d/dx [u; v] = [[(a - s)/lam, b/lam],
    [-c/mu, (s - d)/mu]] [u; v]`` from ``[u; v](0) = [q; 1]``; ``z = e^{-s psi(x)} [u; v]``
    (``psi = int_0^x 1/mu``) solves ``z' = [[(a - s)/lam - s/mu, b/lam], [-c/mu, -d/mu]] z``
    (``s`` in units of ``1/time_unit``, converted to the equations' time),
    integrated by the fourth-order Magnus method on a uniform grid of ``[0, L]``, vectorised
    over ``s``, every coefficient evaluated at the two Gauss points of each step (no kernel,
    no change of variables: the independent route for any speeds).

    Parameters
    ----------
    system : GeneralHyperbolic2x2
    s : complex or array_like
    steps : int, optional
        Magnus steps (default ``max(200, 5 |s| tau)``, at most 10**6).
    nodes : bool, default False
        Return the solution at every grid node (shape ``(steps + 1,) + s.shape``) instead of
        at ``x = L`` only; the number of values is bounded by 10**8.

    Returns
    -------
    x, zu, zv : ndarray
        The grid (or ``[L]``) and the two components there.
    """
    if not isinstance(system, GeneralHyperbolic2x2):
        raise ParameterError("system", "a GeneralHyperbolic2x2", system)
    s_arr = _as_complex(s)
    n_steps = _general_steps(system, s_arr, steps)
    if nodes and (n_steps + 1) * s_arr.size > 10**8:
        raise ParameterError("s", "at most 10**8 values (steps + 1) * size(s) when nodes=True", s_arr.size)
    flat = s_arr.ravel() / system.time_unit  # the equations' time
    h = system.length / n_steps
    g = np.sqrt(3.0) / 6.0
    grid = np.linspace(0.0, system.length, n_steps + 1)
    gauss = [(np.arange(n_steps) + 0.5 + sign * g) * h for sign in (-1.0, 1.0)]
    coef = [{k: system.coefficient(k, xg) for k in ("lam", "mu", "a", "b", "c", "d")} for xg in gauss]
    # B = [[p - s r, b/lam], [-c/mu, -d/mu]] with p = a/lam, r = 1/lam + 1/mu at each Gauss point.
    parts = [
        (c["a"] / c["lam"], 1.0 / c["lam"] + 1.0 / c["mu"], c["b"] / c["lam"], -c["c"] / c["mu"], -c["d"] / c["mu"])
        for c in coef
    ]
    f = np.sqrt(3.0) / 12.0 * h * h
    u = np.full(flat.shape, system.q, dtype=complex)
    v = np.ones(flat.shape, dtype=complex)
    out_u = [u] if nodes else []
    out_v = [v] if nodes else []
    with np.errstate(all="ignore"):
        for k in range(n_steps):
            (p1, r1, b1, c1, d1), (p2, r2, b2, c2, d2) = ((q[k] for q in part) for part in parts)
            x11, y11 = p2 - flat * r2, p1 - flat * r1
            # [B_2, B_1] with B_i = [[x_ii, b_i], [c_i, d_i]].
            k11 = b2 * c1 - b1 * c2
            k12 = x11 * b1 + b2 * d1 - y11 * b2 - b1 * d2
            k21 = c2 * y11 + d2 * c1 - c1 * x11 - d1 * c2
            e00, e01, e10, e11 = _expm2(
                0.5 * h * (x11 + y11) + f * k11,
                0.5 * h * (b1 + b2) + f * k12,
                0.5 * h * (c1 + c2) + f * k21,
                np.full(flat.shape, 0.5 * h * (d1 + d2) - f * k11, dtype=complex),
            )
            u, v = e00 * u + e01 * v, e10 * u + e11 * v
            if nodes:
                out_u.append(u)
                out_v.append(v)
    if nodes:
        shape = (n_steps + 1, *s_arr.shape)
        return grid, np.asarray(out_u).reshape(shape), np.asarray(out_v).reshape(shape)
    return grid[-1:], u.reshape(s_arr.shape), v.reshape(s_arr.shape)


def boundary_function(
    system: Hyperbolic2x2 | GeneralHyperbolic2x2, s: Any, scaled: bool = False, steps: int | None = None
) -> np.ndarray:
    """Boundary function ``v(1, s) - rho u(1, s)`` of the Laplace-transformed plant.

    Parameters
    ----------
    system : Hyperbolic2x2 or GeneralHyperbolic2x2
        The plant, eqs. (18)-(20), or a general plant on ``[0, L]``: then the function
        is ``v(L, s) - rho u(L, s)`` (``e^{-s t_v}`` times it when scaled, ``t_v = int 1/mu``),
        by :func:`general_solution`; scaled, it is ``e^{D(L)}`` times the characteristic
        function of the normal form (``docs/theory.md``).
    s : complex or array_like
        Laplace variable(s); the result has the same shape.
    scaled : bool, default False
        If True, return ``e^{-s/mu} (v(1, s) - rho u(1, s))``, which equals the
        characteristic function of the delay form, ``1 - rho q e^{-tau s}
        + int_0^tau N~(nu) e^{-nu s} dnu`` (eq. (39)), and stays bounded for
        large ``Re s``.
    steps : int, optional
        Magnus steps on ``[0, 1]`` for varying couplings (default
        :func:`magnus_steps`); ignored for constant couplings.

    Returns
    -------
    ndarray of complex
        The boundary function at ``s``, for the solution with ``[u; v](0) = [q; 1]``.

    Raises
    ------
    ParameterError
        Bad input; an ``s`` at which the function overflows (e.g. ``Re s tau`` below about
        ``-700``, or ``Re s / mu`` above about 700 unscaled); for varying couplings an ``s``
        so large that the default Magnus steps exceed 10**6.

    Notes
    -----
    Constant couplings: closed-form 2x2 matrix exponential, exact to rounding.
    Varying couplings: the ODE ``d/dx [u; v] = A(x, s) [u; v]`` is integrated by the
    fourth-order Magnus method with fixed steps, vectorised over ``s``; with the default
    steps the absolute error of the scaled function is about ``1e-9`` for
    ``|s| <= 200`` (measured against an adaptive DOP853 solve at ``rtol = 1e-12``).
    Its zeros are the open-loop eigenvalues, computed without any backstepping kernel.
    """
    if isinstance(system, GeneralHyperbolic2x2):
        s_arr = _as_complex(s)
        _, zu, zv = general_solution(system, s_arr, steps)
        with np.errstate(all="ignore"):
            out = zv - system.rho * zu
            if not scaled:
                out = out * np.exp(s_arr * (system.transport_times[1] / system.time_unit))
        return _finite(out, s_arr)
    if not isinstance(system, Hyperbolic2x2):
        raise ParameterError("system", "a Hyperbolic2x2 or GeneralHyperbolic2x2", system)
    s_arr = _as_complex(s)
    with np.errstate(all="ignore"):  # overflow is checked on the result
        if system.constant_couplings:
            u1, v1 = _constant_scaled(system, s_arr)
        else:
            if steps is None:
                n_steps = magnus_steps(system, s_arr)
                if n_steps > _MAX_STEPS:
                    raise ParameterError(
                        "s",
                        f"of modulus at most {_MAX_STEPS / (_STEPS_PER_PHASE * system.tau):.6g} for varying couplings "
                        f"(the default Magnus steps, {_STEPS_PER_PHASE:g} |s| tau, are at most {_MAX_STEPS})",
                        f"max |s| = {np.max(np.abs(s_arr)):.6g}",
                    )
            else:
                n_steps = positive_int("steps", steps, maximum=_MAX_STEPS)
            u1, v1 = _magnus_scaled(system, s_arr, n_steps)
        out = v1 - system.rho * u1
        if not scaled:
            out = out * np.exp(s_arr / system.mu)
    return _finite(out, s_arr)


def _finite(out: np.ndarray, s_arr: np.ndarray) -> np.ndarray:
    """``out``, or a ParameterError naming the first ``s`` where it overflowed."""
    bad = ~np.isfinite(out)
    if np.any(bad):
        raise ParameterError(
            "s",
            "where the boundary function is representable in double precision (it overflows there)",
            complex(s_arr[bad].flat[0]),
        )
    return out
