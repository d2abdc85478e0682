"""The contract of the simulators: the result every scheme returns and the scheme interface.

:func:`~nrobust.hyperbolic.simulate.simulate` runs a :class:`Scheme` of the registry
:data:`~nrobust.hyperbolic.simulate.registry.SCHEMES` (name -> scheme), picked by the plant or by
name, as :func:`scipy.integrate.solve_ivp` picks a method of ``METHODS``. Every scheme
returns a :class:`SimulationResult`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._json import fields_dict
from ..._validate import finite_real
from ...errors import ParameterError

__all__ = ["Scheme", "SimulationResult", "initial_state"]


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """What every simulation returns: the sampled times and the norm of the state.

    The result classes of the schemes subclass it, adding their fields after these two
    (so their positional order starts with them): :class:`~nrobust.hyperbolic.simulate.Simulation`
    (2x2 plants: also ``control``, the node grids ``x``, ``x_v``, the snapshots
    ``snapshot_times``, ``u``, ``v``, ``dt``), :class:`~nrobust.hyperbolic.simulate.GeneralSimulation`
    (the same on time-of-flight grids, and the boundary traces) and
    :class:`~nrobust.hyperbolic.simulate.NPlusMSimulation` (``n + m`` systems: ``dt`` and
    the cells of each component). Every one also has ``dt``, its time step.

    Attributes
    ----------
    times : ndarray
        Sampled times ``j dt``, from 0 to the first sampled time at or after ``t_end``.
    norm : ndarray
        The L2 norm of the state at ``times`` (trapezoidal rule on the scheme's grids).
    """

    times: NDArray[np.float64]
    norm: NDArray[np.float64]

    def growth_rate(self, t_min: float | None = None, t_max: float | None = None) -> float:
        """Least-squares slope of ``log ||state(t)||`` on ``[t_min, t_max]``.

        Parameters
        ----------
        t_min, t_max : float, optional
            Fit window; ``t_min`` defaults to half the last time, ``t_max`` to the last time.

        Raises
        ------
        ParameterError
            If the window holds fewer than two samples or a norm in it is zero.
        """
        t_max = float(self.times[-1]) if t_max is None else finite_real("t_max", t_max)
        t_min = float(self.times[-1]) / 2 if t_min is None else finite_real("t_min", t_min)
        mask = (self.times >= t_min) & (self.times <= t_max)
        if np.count_nonzero(mask) < 2:
            raise ParameterError("(t_min, t_max)", "a window holding at least two sampled times", (t_min, t_max))
        values = self.norm[mask]
        if np.any(values <= 0.0):
            raise ParameterError("(t_min, t_max)", "a window where the norm is positive", (t_min, t_max))
        slope, _ = np.polyfit(self.times[mask], np.log(values), 1)
        return float(slope)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (every field)."""
        return fields_dict(self)


def _real_state(name: str, raw: Any, expected: str) -> NDArray[np.float64]:
    """``raw`` as a float array; complex values with a nonzero imaginary part, booleans,
    strings and ragged sequences are refused (the simulated state is real)."""
    try:
        arr = np.asarray(raw)
    except (TypeError, ValueError):  # ragged nesting
        raise ParameterError(name, expected, raw) from None
    if arr.dtype.kind == "c":
        if np.any(arr.imag != 0):
            raise ParameterError(name, "real-valued (simulate evolves real states)", "complex values")
        arr = arr.real
    if arr.dtype.kind not in "iuf":
        raise ParameterError(name, expected, raw)
    return arr.astype(float)


def initial_state(name: str, value: Any, x: NDArray[np.float64]) -> NDArray[np.float64]:
    """An initial condition sampled on the nodes ``x``: the one check of every scheme.

    ``value`` is a real number (a constant state), a callable on arrays of ``x`` (an error it
    raises is reported as a :class:`~nrobust.errors.ParameterError` on ``name``, not passed
    through), or the values on the nodes (one per node). The result is finite and real.
    None (a state left out) is refused, saying what to give.
    """
    if value is None:
        raise ParameterError(
            name,
            f"given: a number (a constant state, e.g. {name}=1.0, the default of SYSTEM.toml), a callable on "
            f"arrays of x or {x.size} node values",
        )
    if callable(value):
        expected = "a callable returning real numbers on arrays of x"
        try:
            raw = value(x)
        except Exception as exc:  # the user's callable: its failure is a bad argument, named
            raise ParameterError(name, expected, f"{value!r} raised {type(exc).__name__}: {exc}") from None
        out = _real_state(name, raw, expected)
    else:
        out = _real_state(name, value, f"a number, a callable or an array of {x.size} node values")
    if out.shape == ():
        out = np.full(x.shape, float(out))
    if out.shape != x.shape:
        raise ParameterError(name, f"{x.size} values, one per node", f"shape {out.shape}")
    if not np.all(np.isfinite(out)):
        raise ParameterError(name, "finite on the domain", "non-finite values")
    return out.copy()


@dataclass(frozen=True, eq=False)
class Scheme:
    """A simulation scheme of the registry: which plants it takes and how it runs.

    Attributes
    ----------
    name : str
        Its key in :data:`~nrobust.hyperbolic.simulate.registry.SCHEMES` (``scheme=`` of ``simulate``).
    plants : tuple of type
        The plant classes it takes.
    run : callable
        ``run(system, controller, delta, t_end, u0, v0, **options)`` -> :class:`SimulationResult`:
        the scheme's own simulator; ``simulate`` passes the initial state ``u0, v0`` as given
        (None where the caller gave none: the scheme says which it needs) and ``cells`` and
        the options by keyword.
    condition : callable, optional
        A further test on a plant of ``plants`` (say, a constant ``lam/mu``); None: every one.
    description : str
        One line for the documentation and the error messages.
    """

    name: str
    plants: tuple[type, ...]
    run: Callable[..., SimulationResult]
    condition: Callable[[Any], bool] | None = None
    description: str = ""

    def accepts(self, system: Any) -> bool:
        """True if the scheme simulates ``system``."""
        return isinstance(system, self.plants) and (self.condition is None or bool(self.condition(system)))
