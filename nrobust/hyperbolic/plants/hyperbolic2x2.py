"""Boundary-controlled 2x2 heterodirectional hyperbolic systems.

The plant of the reference paper, eqs. (18)-(20)::

    u_t + lam u_x = sigma_pm(x) v,      u(t, 0) = q v(t, 0),
    v_t - mu  v_x = sigma_mp(x) u,      v(t, 1) = rho u(t, 1) + U(t),

on ``x in [0, 1]`` with ``lam, mu > 0`` and ``q != 0``. The in-domain couplings are
numbers or callables on ``[0, 1]``; :class:`TransportSystem` is the uncoupled case of
Section 2 (eqs. (1)-(3)).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, is_dataclass
from typing import Any

import numpy as np

from ..._json import json_safe
from ..._validate import finite_real, is_real_number, positive
from ...errors import ParameterError

__all__ = ["Coupling", "Hyperbolic2x2", "TransportSystem"]

Coupling = float | Callable[[np.ndarray], Any]

# Grid on which callable couplings are probed at construction.
_PROBE = np.linspace(0.0, 1.0, 17)
# Points at which callable couplings are tabulated by ``to_dict``.
_SAMPLES = np.linspace(0.0, 1.0, 11)


def _coupling_name(value: Coupling) -> str:
    """Readable name of a coupling for ``repr``: the number, a callable dataclass's own ``repr``
    (its definition, e.g. ``PiecewiseLinear(x=..., values=...)``), or a function's name."""
    if callable(value):
        if is_dataclass(value):
            return repr(value)
        return f"<function {getattr(value, '__qualname__', type(value).__name__)}>"
    return repr(value)


def _call_vectorised(name: str, fun: Callable[..., Any], x: np.ndarray) -> np.ndarray | None:
    """Evaluate ``fun`` on the array ``x``; ``None`` if it does not act elementwise."""
    try:
        with np.errstate(all="ignore"):
            out = np.asarray(fun(x))
    except Exception:  # a scalar-only callable may raise anything on an array
        return None
    if out.shape != x.shape or out.dtype.kind == "O":
        return None
    if out.dtype.kind not in "iufc":  # booleans, strings: not converted silently
        raise ParameterError(name, "real-valued on [0, 1] (numbers, not booleans or strings)", f"dtype {out.dtype}")
    if np.iscomplexobj(out):
        if np.any(out.imag != 0):
            raise ParameterError(name, "real-valued on [0, 1]", "complex values")
        out = out.real
    return out.astype(float)


def _pointwise(name: str, fun: Callable[..., Any], x: np.ndarray) -> np.ndarray:
    """Evaluate a scalar-only callable point by point; each value must be a real number.

    An exception of the callable becomes a ParameterError naming the coupling and the
    point, with the original exception as its cause.
    """
    flat = []
    for xi in np.ravel(x):
        try:
            value = np.real_if_close(fun(float(xi)))
        except Exception as exc:
            raise ParameterError(
                name, f"a callable returning real numbers on [0, 1]; at x = {xi:g} it raised {exc!r}"
            ) from exc
        if not is_real_number(value):
            raise ParameterError(name, "a callable returning real numbers on [0, 1]", fun)
        flat.append(float(value))
    return np.asarray(flat, dtype=float).reshape(np.shape(x))


@dataclass(frozen=True)
class _Evaluator:
    """Vectorised evaluation of one coupling; picklable whenever the coupling is.

    A number is broadcast; a callable is called on the whole array when it acts
    elementwise (``vectorised``), point by point otherwise.
    """

    name: str
    value: Coupling
    vectorised: bool

    def __call__(self, x: np.ndarray) -> np.ndarray:
        if not callable(self.value):
            return np.full(np.shape(x), self.value)
        arr = np.asarray(x, dtype=float)
        out = _call_vectorised(self.name, self.value, arr) if self.vectorised else None
        return _pointwise(self.name, self.value, arr) if out is None else out


def _make_evaluator(name: str, value: Any) -> tuple[Coupling, _Evaluator]:
    """Check a coupling and return it with a vectorised evaluator on arrays of ``x``.

    Numbers are returned as floats. A callable that does not act elementwise on arrays
    is evaluated point by point. The evaluator is probed on a 17-point grid of ``[0, 1]``
    and must return finite reals there.
    """
    if not callable(value):
        if isinstance(value, (bool, np.bool_)) or not np.isscalar(value):
            raise ParameterError(name, "a finite real number or a callable on [0, 1]", value)
        number = finite_real(name, value)
        return number, _Evaluator(name, number, True)
    probe = _call_vectorised(name, value, _PROBE)
    evaluator = _Evaluator(name, value, probe is not None)
    if probe is None:
        probe = _pointwise(name, value, _PROBE)
    if not np.all(np.isfinite(probe)):
        raise ParameterError(name, "finite on [0, 1] (checked on a 17-point grid)", value)
    return value, evaluator


@dataclass(frozen=True, repr=False)
class Hyperbolic2x2:
    """Two heterodirectional transport equations coupled in the domain, eqs. (18)-(20).

    Parameters
    ----------
    lam, mu : float
        Transport speeds, ``lam > 0`` rightwards for ``u``, ``mu > 0`` leftwards for ``v``.
    sigma_pm, sigma_mp : float or callable
        In-domain couplings ``sigma^{+-}(x)`` (source of ``u``) and ``sigma^{-+}(x)``
        (source of ``v``): numbers or callables on ``[0, 1]`` returning finite reals.
    q : float
        Distal reflection (at the unactuated end) ``u(t, 0) = q v(t, 0)``, ``q != 0``.
    rho : float
        Proximal reflection (at the actuated end) ``v(t, 1) = rho u(t, 1) + U(t)``.

    Raises
    ------
    ParameterError
        If a speed is not positive, ``q`` is zero, a number is not finite, or a coupling
        is neither a number nor a callable with finite real values on a probe grid.
    """

    lam: float
    mu: float
    sigma_pm: Coupling
    sigma_mp: Coupling
    q: float
    rho: float
    _eval_pm: _Evaluator = field(init=False, repr=False, compare=False)
    _eval_mp: _Evaluator = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "lam", positive("lam", self.lam))
        object.__setattr__(self, "mu", positive("mu", self.mu))
        q = finite_real("q", self.q)
        if q == 0.0:
            raise ParameterError("q", "nonzero (the kernel boundary condition divides by q)", self.q)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "rho", finite_real("rho", self.rho))
        for attr, evaluator in (("sigma_pm", "_eval_pm"), ("sigma_mp", "_eval_mp")):
            value, fun = _make_evaluator(attr, getattr(self, attr))
            object.__setattr__(self, attr, value)
            object.__setattr__(self, evaluator, fun)

    @property
    def tau(self) -> float:
        """Round-trip transport time ``1/lam + 1/mu``, eq. (5)."""
        return 1.0 / self.lam + 1.0 / self.mu

    @property
    def rho_q(self) -> float:
        """Open-loop gain ``rho * q`` of the principal (difference) part."""
        return self.rho * self.q

    @property
    def constant_couplings(self) -> bool:
        """True when both couplings are numbers (closed forms apply)."""
        return not (callable(self.sigma_pm) or callable(self.sigma_mp))

    @property
    def uncoupled(self) -> bool:
        """True when both couplings are the number zero."""
        return self.constant_couplings and self.sigma_pm == 0.0 and self.sigma_mp == 0.0

    def sigma_pm_at(self, x: Any) -> np.ndarray:
        """``sigma^{+-}(x)`` on an array of ``x``, same shape."""
        return self._eval_pm(np.asarray(x, dtype=float))

    def sigma_mp_at(self, x: Any) -> np.ndarray:
        """``sigma^{-+}(x)`` on an array of ``x``, same shape."""
        return self._eval_mp(np.asarray(x, dtype=float))

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(lam={self.lam!r}, mu={self.mu!r}, "
            f"sigma_pm={_coupling_name(self.sigma_pm)}, sigma_mp={_coupling_name(self.sigma_mp)}, "
            f"q={self.q!r}, rho={self.rho!r})"
        )

    def _coupling_dict(self, attr: str) -> float | dict[str, Any]:
        value = getattr(self, attr)
        if not callable(value):
            return float(value)
        at = self.sigma_pm_at if attr == "sigma_pm" else self.sigma_mp_at
        return {
            "callable": _coupling_name(value),
            "x": _SAMPLES,
            "values": at(_SAMPLES),
        }

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description; callable couplings are tabulated on 11 points."""
        return json_safe(
            {
                "type": type(self).__name__,
                "lam": self.lam,
                "mu": self.mu,
                "sigma_pm": self._coupling_dict("sigma_pm"),
                "sigma_mp": self._coupling_dict("sigma_mp"),
                "q": self.q,
                "rho": self.rho,
                "tau": self.tau,
                "rho_q": self.rho_q,
            }
        )


@dataclass(frozen=True, repr=False)
class TransportSystem(Hyperbolic2x2):
    """Uncoupled transport equations, eqs. (1)-(3).

    A :class:`Hyperbolic2x2` with ``sigma_pm = sigma_mp = 0``; its kernels vanish and
    its delay form is ``1 - rho q e^{-tau s}`` (eq. (6)).

    Parameters
    ----------
    lam, mu : float
        Transport speeds, both ``> 0``.
    q : float
        Distal reflection, ``q != 0``.
    rho : float
        Proximal reflection.
    """

    lam: float
    mu: float
    q: float
    rho: float
    sigma_pm: Coupling = field(default=0.0, init=False)
    sigma_mp: Coupling = field(default=0.0, init=False)

    def __repr__(self) -> str:
        return f"TransportSystem(lam={self.lam!r}, mu={self.mu!r}, q={self.q!r}, rho={self.rho!r})"
