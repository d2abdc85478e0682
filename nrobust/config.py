"""The TOML input schema: systems, controllers, profiles and the SYSTEM.toml file.

One place knows how a file names a plant or a controller (:data:`SYSTEM_TYPES`,
:data:`CONTROLLER_TYPES`), reads TOML on every supported Python (``tomllib`` from 3.11,
``tomli`` before) and turns a coupling table ``{x = [...], values = [...]}`` into a
profile (:class:`PiecewiseLinear`). ``nrobust analyze`` reads SYSTEM.toml with
:func:`load_system_file`; ``nrobust sweep`` reads SWEEP.toml with
:mod:`nrobust.sweeps.sweepfile`. Schemas: ``docs/getting_started.md`` and ``docs/sweeps.md``.
"""

from __future__ import annotations

import difflib
import functools
import itertools
import math
import sys
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .design.gain import check_delays
from .errors import ParameterError
from .hyperbolic.loops.controllers import (
    Controller,
    FilteredController,
    FiniteTimeController,
    OpenLoop,
    ReflectionController,
    StateFeedback,
    loop_route,
    normalize,
)
from .hyperbolic.nplusm.speed_box import check_box_tolerance
from .hyperbolic.nplusm.system import NPlusMSystem
from .hyperbolic.plants.frontends import arz, saint_venant
from .hyperbolic.plants.general import GeneralHyperbolic2x2
from .hyperbolic.plants.hyperbolic2x2 import Hyperbolic2x2, TransportSystem
from .hyperbolic.simulate.normal_form import DEFAULT_CELLS

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised by the Python 3.10 run of CI
    import tomli as tomllib

__all__ = [
    "CONTROLLER_TYPES",
    "DESIGN_FAMILIES",
    "OBSERVER_FAMILIES",
    "PLANT_FAMILIES",
    "Monomial",
    "SYSTEM_TYPES",
    "PiecewiseLinear",
    "build_in_section",
    "load_system_file",
    "load_toml",
    "unknown_key",
]


def unknown_key(name: str, requirement: str, given: Any, allowed: Iterable[str], value: Any = None) -> ParameterError:
    """The error of a key (or a type name) that a file may not use, with the closest allowed ones.

    Parameters
    ----------
    name : str
        The key as the file spells it, with its section (``"system.lamda"``).
    requirement : str
        What is admissible (``"a key of Hyperbolic2x2: one of [...]"``).
    given : object
        The unknown key or type name itself, compared with ``allowed``.
    allowed : iterable of str
        The admissible keys or names.
    value : object, optional
        The value the file gave the key, echoed in the message.

    Returns
    -------
    ParameterError
        Its requirement ends with ``did you mean 'lam'?`` when some allowed names are close
        to ``given`` (:func:`difflib.get_close_matches`, default cutoff 0.6).
    """
    close = difflib.get_close_matches(given, list(allowed), n=3) if isinstance(given, str) else []
    if close:
        requirement += "; did you mean " + " or ".join(repr(c) for c in close) + "?"
    return ParameterError(name, requirement, value)


def _plant_of(build: Callable[..., Any], name: str) -> Callable[..., GeneralHyperbolic2x2]:
    """A front end returning its plant (``.system``), named ``name`` in the registry.

    The signature is kept (``functools.wraps``) so that sweep files read the parameters
    from it.
    """

    @functools.wraps(build)
    def make(*args: Any, **kwargs: Any) -> GeneralHyperbolic2x2:
        plant: GeneralHyperbolic2x2 = build(*args, **kwargs).system
        return plant

    make.__name__ = make.__qualname__ = name
    return make


#: The plants a file can name in ``[system] type = ...``: the paper's plants, the general
#: plant and the physical front ends. The readers pass a general plant and its controller
#: through :func:`~nrobust.hyperbolic.loops.controllers.normalize` (the normal form, and the
#: gains of a ``StateFeedback`` mapped from the physical coordinates).
SYSTEM_TYPES: dict[str, Callable[..., Hyperbolic2x2 | GeneralHyperbolic2x2]] = {
    "Hyperbolic2x2": Hyperbolic2x2,
    "TransportSystem": TransportSystem,
    "GeneralHyperbolic2x2": GeneralHyperbolic2x2,
    "SaintVenant": _plant_of(saint_venant, "SaintVenant"),
    "ARZ": _plant_of(arz, "ARZ"),
}
#: The physical front ends among :data:`SYSTEM_TYPES`: a file's parameters of one are echoed by the report.
FRONT_ENDS = ("SaintVenant", "ARZ")
#: The ``n + m`` plant (``[system] type = "NPlusMSystem"``) has its own reader, :func:`_load_nplusm`:
#: its analysis is a study of static feedbacks, not a 2x2 certificate, and sweeps do not take it.
NPLUSM_TYPE = "NPlusMSystem"
#: The controllers a file can name in ``[controller] type = ...``.
CONTROLLER_TYPES: dict[str, type[Controller]] = {
    "OpenLoop": OpenLoop,
    "FiniteTimeController": FiniteTimeController,
    "ReflectionController": ReflectionController,
    "FilteredController": FilteredController,
    "StateFeedback": StateFeedback,
}
_SYSTEM_KEYS = {
    "Hyperbolic2x2": ("lam", "mu", "sigma_pm", "sigma_mp", "q", "rho"),
    "TransportSystem": ("lam", "mu", "q", "rho"),
    "GeneralHyperbolic2x2": ("lam", "mu", "a", "b", "c", "d", "q", "rho"),
    "SaintVenant": ("length", "width", "slope", "discharge"),
    "ARZ": ("length", "v_max", "rho_max", "gamma", "relaxation", "rho_star"),
}
#: Keys a file may leave out (the builder's default applies).
_SYSTEM_OPTIONAL: dict[str, tuple[str, ...]] = {
    "GeneralHyperbolic2x2": ("length", "time_unit"),
    "SaintVenant": (
        "side_slope",
        "manning",
        "chezy",
        "downstream",
        "downstream_depth",
        "weir_height",
        "weir_coefficient",
        "time_unit",
    ),
    "ARZ": ("time_unit",),
}
#: Coefficients of the general plant: numbers or samples ``{x = [...], values = [...]}`` on [0, L].
_GENERAL_PROFILES = ("lam", "mu", "a", "b", "c", "d")
_CONTROLLER_KEYS = {
    "OpenLoop": (),
    "FiniteTimeController": (),
    "ReflectionController": ("K",),
    "FilteredController": ("a", "b"),
    "StateFeedback": ("k",),
}
_CONTROLLER_OPTIONAL: dict[str, tuple[str, ...]] = {"StateFeedback": ("g_u", "g_v"), "FilteredController": ("K",)}
_ANALYSIS_KEYS = {"delta_max": None, "region": None, "k_region": True, "rigorous": False, "accuracy": None}
_SIMULATION_KEYS = {"delays": None, "t_end": 10.0, "cells": DEFAULT_CELLS, "u0": 1.0, "v0": 1.0}
#: Deprecated keys of ``[simulation]``, read as their new names with a DeprecationWarning.
_SIMULATION_RENAMED = {"n": "cells"}
_TOP_KEYS = ("system", "controller", "analysis", "simulation", "design")
#: Keys of ``[design]`` (``nrobust design``) and their defaults; ``K``, ``a``, ``b``: a number (fixed)
#: or ``[low, high]`` bounds (None: the default bounds of the family); ``delays = [d_min, d_max]``: the
#: window of delays to be stable on; ``speed_tolerance``: the relative error of ``lam`` and ``mu`` in (0, 1).
#: ``k_bounds``, ``basis``, ``coefficient_bounds``, ``kernel_grid``: family ``"state_feedback"``
#: (:func:`~nrobust.hyperbolic.analyses.design_state_feedback`'s parameters; ``basis``: powers ``j`` of
#: the functions ``(x / L)^j``; ``kernel_grid`` left out: the exact route without a basis, else 201
#: points). An ``NPlusMSystem`` file's ``[design]`` has :data:`_NPLUSM_DESIGN_KEYS`.
_DESIGN_KEYS: dict[str, Any] = {
    "family": "reflection",
    "objective": "margin",
    "margin_at_least": None,
    "K": None,
    "a": None,
    "b": None,
    "starts": 4,
    "rigorous": False,
    "observer_delay": 0.0,
    "delays": None,
    "speed_tolerance": None,
    "k_bounds": None,
    "basis": [],
    "coefficient_bounds": [-1.0, 1.0],
    "kernel_grid": None,
}
#: The keys only family ``"state_feedback"`` takes, and those it does not.
_STATE_FEEDBACK_KEYS = ("k_bounds", "basis", "coefficient_bounds", "kernel_grid")
_GAIN_KEYS = ("K", "a", "b", "observer_delay")
#: Keys of ``[design]`` in an ``NPlusMSystem`` file (family ``"nplusm"``,
#: :func:`~nrobust.hyperbolic.nplusm.design_nplusm_gains`'s parameters) and their defaults;
#: ``speed_tolerance``: the relative error of every speed in (0, 1), with a delay requirement.
_NPLUSM_DESIGN_KEYS: dict[str, Any] = {
    "family": "nplusm",
    "objective": "decay_rate",
    "margin_at_least": None,
    "delays": None,
    "speed_tolerance": None,
    "K_bounds": None,
    "x0": None,
    "starts": 4,
    "max_iter": 60,
    "rigorous": False,
}
#: The controller families ``nrobust design`` can design: U_BS2(K), U_BS2(K) on the state predicted
#: from ``v(t, 0)`` (output feedback), U_BS2(K) on the collocated observer's estimate from ``u(t, 1)``
#: (collocated output feedback), the filtered U_BS2(K), the general state feedback
#: ``U = k u(t, L) + int g_u u + g_v v`` and, for an ``NPlusMSystem``, the gain matrix of
#: ``U = K u(t - delta, 1)``.
DESIGN_FAMILIES = (
    "reflection",
    "output_feedback",
    "collocated_output_feedback",
    "filtered",
    "state_feedback",
    "nplusm",
)
#: The families whose gain K is designed on an observer's estimate (they take ``observer_delay``).
OBSERVER_FAMILIES = ("output_feedback", "collocated_output_feedback")
#: The families of a 2x2 plant (``"nplusm"`` takes an ``NPlusMSystem``).
PLANT_FAMILIES = DESIGN_FAMILIES[:-1]


def load_toml(path: str | Path, what: str = "TOML file") -> dict[str, Any]:
    """Parse a TOML file; a missing or malformed file is a :class:`ParameterError` on ``path``."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ParameterError("path", f"an existing {what}", str(path)) from None
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError("path", f"a valid TOML file ({exc})", str(path)) from None
    except UnicodeDecodeError as exc:
        raise ParameterError(
            "path",
            f"a UTF-8 encoded TOML file (byte {exc.object[exc.start]:#04x} at offset {exc.start} is not UTF-8)",
            str(path),
        ) from None
    except IsADirectoryError:
        raise ParameterError("path", f"an existing {what}, not a directory", str(path)) from None


@dataclass(frozen=True)
class PiecewiseLinear:
    """A coupling given in a file as ``{x = [...], values = [...]}``, linear between nodes.

    Parameters
    ----------
    x : tuple of float
        Increasing nodes covering ``[0, 1]``.
    values : tuple of float
        Values at the nodes.
    """

    x: tuple[float, ...]
    values: tuple[float, ...]

    def __call__(self, x: Any) -> np.ndarray:
        return np.interp(np.asarray(x, dtype=float), self.x, self.values)

    @property
    def __name__(self) -> str:  # used by the systems' repr
        return "piecewise_linear"


@dataclass(frozen=True)
class Monomial:
    """``x -> (x / length)^power``: a function of a state feedback's basis, named in a file by its power.

    Parameters
    ----------
    power : int
        ``>= 0``.
    length : float
        The plant's length ``L`` (``> 0``).
    """

    power: int
    length: float = 1.0

    def __call__(self, x: Any) -> np.ndarray:
        return np.asarray(np.asarray(x, dtype=float) / self.length, dtype=float) ** self.power

    @property
    def __name__(self) -> str:  # used by BasisGain's repr
        return f"(x/{self.length:g})^{self.power}" if self.length != 1.0 else f"x^{self.power}"


def _number(key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise ParameterError(key, "a finite number", value)
    return float(value)


def _profile(key: str, value: Any) -> float | PiecewiseLinear:
    """A number or a piecewise-linear table ``{x = [...], values = [...]}`` on [0, 1]."""
    table = _samples(key, value)
    if not isinstance(table, tuple):
        return table
    xs, vs = table
    if len(xs) != len(vs) or len(xs) < 2:
        raise ParameterError(f"{key}.x", "a list of at least 2 nodes, as long as values", list(xs))
    if xs[0] != 0.0 or xs[-1] != 1.0 or any(b <= a for a, b in itertools.pairwise(xs)):
        raise ParameterError(f"{key}.x", "increasing from 0 to 1", list(xs))
    return PiecewiseLinear(xs, vs)


def _samples(key: str, value: Any) -> float | tuple[tuple[float, ...], tuple[float, ...]]:
    """A number or samples ``{x = [...], values = [...]}`` (the plant checks they span [0, L])."""
    if not isinstance(value, dict):
        return _number(key, value)
    if set(value) != {"x", "values"}:
        stray = sorted(set(value) - {"x", "values"})
        raise unknown_key(
            key,
            "a number or a table with exactly the keys x and values",
            stray[0] if stray else None,
            ("x", "values"),
            value,
        )
    x, v = value["x"], value["values"]
    if not isinstance(x, list) or not isinstance(v, list):
        raise ParameterError(key, "lists x and values", value)
    return tuple(_number(f"{key}.x", t) for t in x), tuple(_number(f"{key}.values", t) for t in v)


def _system_value(kind: str, key: str, value: Any) -> Any:
    """One value of ``[system]``: a coupling profile, a coefficient, a word, or a number."""
    name = f"system.{key}"
    if key.startswith("sigma"):
        return _profile(name, value)
    if kind == "GeneralHyperbolic2x2" and key in _GENERAL_PROFILES:
        return _samples(name, value)
    if key == "downstream":
        if value not in ("gate", "weir"):
            raise ParameterError(name, "'gate' or 'weir'", value)
        return value
    return _number(name, value)


def _table(spec: dict[str, Any], name: str, required: bool) -> dict[str, Any]:
    table = spec.get(name)
    if table is None and not required:
        return {}
    if not isinstance(table, dict):
        raise ParameterError(name, f"a [{name}] table", table)
    return table


def _typed(
    table: dict[str, Any],
    section: str,
    keys: dict[str, tuple[str, ...]],
    optional: dict[str, tuple[str, ...]] | None = None,
    others: tuple[str, ...] = (),
) -> tuple[str, dict[str, Any]]:
    """The type of ``table`` and its other keys, checked against ``keys`` (``others``: types read elsewhere)."""
    kind = table.get("type")
    if kind not in keys:
        types = [*keys, *others]
        raise unknown_key(f"{section}.type", f"one of {types}", kind, types, kind)
    params = {k: v for k, v in table.items() if k != "type"}
    allowed = keys[kind] + (optional or {}).get(kind, ())
    for key in params:
        if key not in allowed:
            raise unknown_key(f"{section}.{key}", f"a key of {kind}: one of {list(allowed)}", key, allowed, params[key])
    for key in keys[kind]:
        if key not in params:
            raise ParameterError(f"{section}.{key}", f"given for {kind}", None)
    return kind, params


def _options(table: dict[str, Any], section: str, defaults: dict[str, Any]) -> dict[str, Any]:
    for key in table:
        if key not in defaults:
            raise unknown_key(
                f"{section}.{key}", f"a key of [{section}]: one of {list(defaults)}", key, defaults, table[key]
            )
    return {**defaults, **table}


def build_in_section(key: str, build: Callable[[], Any]) -> Any:
    """``build()``, a ParameterError of it renamed ``key.<name>`` (the file's section first).

    Parameters
    ----------
    key : str
        The section of the file the object is built from (``"system"``, ``"controller"``).
    build : callable
        Builds the object from the section's values.

    Returns
    -------
    object
        What ``build`` returns.
    """
    try:
        return build()
    except ParameterError as exc:
        raise ParameterError(f"{key}.{exc.name}", exc.requirement, exc.value) from None


def _load_nplusm(spec: dict[str, Any], for_design: bool = False) -> dict[str, Any]:
    """An ``n + m`` file: ``[system] type = "NPlusMSystem"`` (``lam``, ``mu``, ``sigma``, ``q``, ``r``),
    ``[controller] type = "Cancellation"`` with ``fractions`` (rows of cancelled fractions of
    ``R``), ``[analysis] region``, optionally ``[design]`` (family ``"nplusm"``, read by ``nrobust
    design``). Returns ``kind = "NPlusMSystem"``, ``system``, ``cancellations``, ``region`` and
    ``design`` (None without the section). ``for_design``: ``[controller]`` and ``[analysis]`` may be
    left out (``cancellations`` and ``region`` then None), as ``nrobust design`` reads neither."""
    sections = ("system", "controller", "analysis", "design")
    for key in spec:
        if key not in sections:
            raise unknown_key(
                key,
                "a section of an NPlusMSystem file: system, controller, analysis, design",
                key,
                sections,
                spec[key],
            )
    table = {k: v for k, v in spec["system"].items() if k != "type"}
    keys = ("lam", "mu", "sigma", "q", "r")
    for key in table:
        if key not in keys:
            raise unknown_key(f"system.{key}", f"a key of NPlusMSystem: one of {list(keys)}", key, keys, table[key])
    for key in keys:
        if key not in table:
            raise ParameterError(f"system.{key}", "given for NPlusMSystem", None)
    system = build_in_section("system", lambda: NPlusMSystem(**table))
    rows = None if for_design and "controller" not in spec else _cancellations(spec, system)
    box = None if for_design and "analysis" not in spec else _nplusm_region(spec)
    design = _nplusm_design(spec["design"], system) if "design" in spec else None
    return {"kind": NPLUSM_TYPE, "system": system, "cancellations": rows, "region": box, "design": design}


def _cancellations(spec: dict[str, Any], system: NPlusMSystem) -> list[list[float]]:
    """The ``[controller]`` of an ``n + m`` file: ``type = "Cancellation"``, one row of fractions per input."""
    controller = _table(spec, "controller", True)
    if controller.get("type") != "Cancellation" or set(controller) != {"type", "fractions"}:
        raise ParameterError("controller", 'type = "Cancellation" and fractions = [[c_1, ..., c_n], ...]', controller)
    fractions = controller["fractions"]
    if not isinstance(fractions, list) or not fractions:
        raise ParameterError("controller.fractions", "a non-empty list of rows of fractions", fractions)
    rows = [[_number("controller.fractions", c) for c in row] if isinstance(row, list) else None for row in fractions]
    if any(row is None or len(row) != system.n for row in rows):
        raise ParameterError("controller.fractions", f"rows of {system.n} numbers (one per u component)", fractions)
    return [row for row in rows if row is not None]


def _nplusm_region(spec: dict[str, Any]) -> tuple[float, ...]:
    """The ``[analysis] region`` of an ``n + m`` file: ``[re_min, re_max, im_min, im_max]``."""
    analysis = _options(_table(spec, "analysis", True), "analysis", {"region": None})
    region = analysis["region"]
    if not isinstance(region, list) or len(region) != 4:
        raise ParameterError("analysis.region", "a list [re_min, re_max, im_min, im_max]", region)
    box = tuple(_number("analysis.region", v) for v in region)
    if not (box[0] < box[1] and box[2] < box[3]):
        raise ParameterError("analysis.region", "a non-empty rectangle: re_min < re_max, im_min < im_max", region)
    return box


def _bounds(key: str, value: Any) -> tuple[float, float]:
    """``[low, high]`` with ``low < high``, finite."""
    if not isinstance(value, list) or len(value) != 2:
        raise ParameterError(key, "[low, high] bounds of finite numbers with low < high", value)
    lo, hi = (_number(key, v) for v in value)
    if not lo < hi:
        raise ParameterError(key, "[low, high] with low < high", value)
    return lo, hi


def _state_feedback_keys(d: dict[str, Any]) -> None:
    """``k_bounds``, ``basis``, ``coefficient_bounds``, ``kernel_grid`` of family ``"state_feedback"``, checked."""
    if d["k_bounds"] is not None:
        d["k_bounds"] = _bounds("design.k_bounds", d["k_bounds"])
    d["coefficient_bounds"] = _bounds("design.coefficient_bounds", d["coefficient_bounds"])
    basis = d["basis"]
    powers = "a list of distinct integer powers j >= 0 of the basis functions (x / L)^j, e.g. [0, 1]"
    if not isinstance(basis, list) or any(isinstance(j, bool) or not isinstance(j, int) or j < 0 for j in basis):
        raise ParameterError("design.basis", powers, basis)
    if len(set(basis)) != len(basis):
        raise ParameterError("design.basis", powers, basis)
    grid = d["kernel_grid"]
    if grid is not None and (isinstance(grid, bool) or not isinstance(grid, int)):
        raise ParameterError(
            "design.kernel_grid",
            "an integer number of kernel grid points (e.g. 201); left out: the exact route without a basis, "
            "else 201 points",
            grid,
        )


def _nplusm_design(table: Any, system: NPlusMSystem) -> dict[str, Any]:
    """The ``[design]`` section of an ``NPlusMSystem`` file (family ``"nplusm"``), checked."""
    if not isinstance(table, dict):
        raise ParameterError("design", "a [design] table", table)
    d = _options(table, "design", _NPLUSM_DESIGN_KEYS)
    if d["family"] != "nplusm":
        raise unknown_key(
            "design.family",
            'family = "nplusm" for an NPlusMSystem (the gain matrix K of U = K u(t - delta, 1))',
            str(d["family"]),
            ("nplusm",),
            d["family"],
        )
    if d["objective"] not in ("margin", "decay_rate"):
        raise ParameterError("design.objective", '"margin" or "decay_rate"', d["objective"])
    if d["margin_at_least"] is not None:
        d["margin_at_least"] = _number("design.margin_at_least", d["margin_at_least"])
    if d["delays"] is not None:
        d["delays"] = _windows(d["delays"])
        if d["margin_at_least"] is not None:
            raise ParameterError(
                "design.margin_at_least", "left out with design.delays (the window [0, d] is a margin > d)"
            )
    m, n = system.m, system.n
    if d["K_bounds"] is not None:
        what = f"[low, high] for every entry of K, or {m} rows of {n} pairs [low, high]"
        value = d["K_bounds"]
        if isinstance(value, list) and len(value) == 2 and all(not isinstance(v, list) for v in value):
            d["K_bounds"] = _bounds("design.K_bounds", value)
        elif isinstance(value, list) and len(value) == m and all(isinstance(r, list) and len(r) == n for r in value):
            d["K_bounds"] = [[_bounds("design.K_bounds", pair) for pair in row] for row in value]
        else:
            raise ParameterError("design.K_bounds", what, value)
    if d["x0"] is not None:
        value = d["x0"]
        if not (
            isinstance(value, list) and len(value) == m and all(isinstance(r, list) and len(r) == n for r in value)
        ):
            raise ParameterError("design.x0", f"the first start: {m} rows of {n} numbers (a gain K)", value)
        d["x0"] = [[_number("design.x0", v) for v in row] for row in value]
    for key, low in (("starts", 1), ("max_iter", 1)):
        v = d[key]
        if isinstance(v, bool) or not isinstance(v, int) or not low <= v <= 1000:
            raise ParameterError(f"design.{key}", "an integer in [1, 1000]", v)
    if not isinstance(d["rigorous"], bool):
        raise ParameterError("design.rigorous", "true or false", d["rigorous"])
    if d["speed_tolerance"] is not None:
        # (0, 1) and at most MAX_SPEED_CORNERS vertices of the box of the n + m speeds' errors
        d["speed_tolerance"] = check_box_tolerance(
            _number("design.speed_tolerance", d["speed_tolerance"]), system, "design.speed_tolerance"
        )
        if d["delays"] is None and d["margin_at_least"] is None:
            raise ParameterError(
                "design.speed_tolerance",
                "given with a delay requirement (design.delays or design.margin_at_least) that the speeds must keep",
                d["speed_tolerance"],
            )
    return d


def _windows(value: Any) -> tuple[tuple[float, float], ...]:
    """``design.delays``: ``[d_min, d_max]`` or a list of such windows."""
    what = "a window [d_min, d_max] with 0 <= d_min <= d_max, d_max > 0, or a list of such windows"
    if not isinstance(value, list) or not value:
        raise ParameterError("design.delays", what, value)
    items = value if all(isinstance(w, list) for w in value) else [value]
    out = []
    for j, w in enumerate(items):
        name = "design.delays" if items is not value else f"design.delays[{j}]"
        if not isinstance(w, list) or any(isinstance(v, bool) for v in w):
            raise ParameterError(name, what, w)
        out.append(check_delays(w, name))
    return tuple(out)


def _design(table: dict[str, Any]) -> dict[str, Any]:
    """The ``[design]`` section: the family, the objective, the requirement, the parameters' bounds."""
    d = _options(table, "design", _DESIGN_KEYS)
    if d["family"] == "nplusm":
        raise ParameterError(
            "design.family", f'one of {list(PLANT_FAMILIES)} ("nplusm" takes [system] type = "NPlusMSystem")', "nplusm"
        )
    if d["family"] not in PLANT_FAMILIES:
        raise unknown_key(
            "design.family", f"one of {list(PLANT_FAMILIES)}", str(d["family"]), PLANT_FAMILIES, d["family"]
        )
    family = d["family"]
    own = _STATE_FEEDBACK_KEYS if family != "state_feedback" else _GAIN_KEYS
    for key in own:
        if key in table:
            takes = 'family = "state_feedback"' if family != "state_feedback" else "the families of U_BS2(K)"
            raise ParameterError(f"design.{key}", f'left out for family = "{family}" ({takes} takes it)', table[key])
    if family == "state_feedback":
        _state_feedback_keys(d)
    if d["objective"] not in ("margin", "decay_rate"):
        raise ParameterError("design.objective", '"margin" or "decay_rate"', d["objective"])
    if d["margin_at_least"] is not None:
        d["margin_at_least"] = _number("design.margin_at_least", d["margin_at_least"])
        if d["margin_at_least"] < 0.0:
            raise ParameterError("design.margin_at_least", ">= 0 (a delay)", d["margin_at_least"])
    for name in ("K", "a", "b"):
        value = d[name]
        if value is None or family == "state_feedback":
            continue
        if isinstance(value, list):
            if len(value) != 2:
                raise ParameterError(f"design.{name}", "[low, high] bounds or a number (fixed)", value)
            lo, hi = (_number(f"design.{name}", v) for v in value)
            if not lo < hi:
                raise ParameterError(f"design.{name}", "[low, high] with low < high", value)
            d[name] = (lo, hi)
        else:
            d[name] = _number(f"design.{name}", value)
    if d["family"] in ("reflection", *OBSERVER_FAMILIES):
        family = d["family"]
        for name in ("a", "b"):
            if d[name] is not None:
                raise ParameterError(f"design.{name}", f'left out for family = "{family}" (U_BS2(K) has no filter)')
        if isinstance(d["K"], float):
            raise ParameterError("design.K", f'bounds [low, high] for family = "{family}" (K is designed)', d["K"])
    d["observer_delay"] = _number("design.observer_delay", d["observer_delay"])
    if d["observer_delay"] < 0.0:
        raise ParameterError("design.observer_delay", ">= 0 (a delay)", d["observer_delay"])
    if d["observer_delay"] != 0.0 and d["family"] not in OBSERVER_FAMILIES:
        raise ParameterError(
            "design.observer_delay",
            'left out unless family = "output_feedback" or "collocated_output_feedback" (an observer\'s)',
            d["observer_delay"],
        )
    if d["delays"] is not None:
        if not isinstance(d["delays"], list) or any(isinstance(v, bool) for v in d["delays"]):
            raise ParameterError(
                "design.delays",
                "a pair [d_min, d_max] of finite delays with 0 <= d_min <= d_max and d_max > 0",
                d["delays"],
            )
        d["delays"] = check_delays(d["delays"], "design.delays")
        if d["margin_at_least"] is not None:
            raise ParameterError(
                "design.margin_at_least", "left out with design.delays (the window [0, d] is a margin > d)"
            )
    if d["speed_tolerance"] is not None:
        eps = _number("design.speed_tolerance", d["speed_tolerance"])
        if not 0.0 < eps < 1.0:
            raise ParameterError(
                "design.speed_tolerance", "a relative error of the speeds lam and mu in (0, 1)", d["speed_tolerance"]
            )
        d["speed_tolerance"] = eps
        if d["family"] in OBSERVER_FAMILIES:
            raise ParameterError(
                "design.speed_tolerance",
                f'left out for family = "{d["family"]}" (family "reflection", "filtered" or "state_feedback" takes it)',
                d["speed_tolerance"],
            )
        if d["delays"] is None and d["margin_at_least"] is None:
            raise ParameterError(
                "design.speed_tolerance",
                "given with a delay requirement (design.delays or design.margin_at_least) that the speeds must keep",
                d["speed_tolerance"],
            )
    starts = d["starts"]
    if isinstance(starts, bool) or not isinstance(starts, int) or not 1 <= starts <= 64:
        raise ParameterError("design.starts", "an integer in [1, 64]", starts)
    if not isinstance(d["rigorous"], bool):
        raise ParameterError("design.rigorous", "true or false", d["rigorous"])
    return d


def load_system_file(path: str | Path, *, for_design: bool = False) -> dict[str, Any]:
    """Read a SYSTEM.toml file (schema in ``docs/getting_started.md``).

    ``for_design=True`` reads the file of ``nrobust design``, which designs the controller: the
    ``[controller]`` and ``[analysis]`` sections may then be left out (``controller`` and
    ``given_controller`` None, ``delta_max`` None, the other analysis keys their defaults; an
    ``NPlusMSystem`` file's ``cancellations`` and ``region`` None); when given they are checked as
    for ``nrobust analyze``, except that ``delta_max`` may be left out.

    Returns
    -------
    dict
        ``system``, ``controller``, ``delta_max``, ``region``, ``k_region``, ``rigorous``
        (``[analysis] rigorous = true``: prove the certificate in ball arithmetic), ``accuracy``
        (``[analysis] accuracy = 1e-9``: the delay margin's target accuracy, see
        :func:`~nrobust.reports.certificate.certify`) and
        ``simulation`` (None or a dict of ``delays``, ``t_end``, ``cells``, ``u0``, ``v0``);
        ``given_system`` and ``given_controller``: the plant and controller as written, before
        ``system`` and ``controller`` became their normal form; ``design``: None or the
        ``[design]`` section (``family``, ``objective``, ``margin_at_least``, ``K``, ``a``, ``b``,
        ``starts``, ``rigorous``) that ``nrobust design`` reads.
        The deprecated key ``[simulation] n`` is read as ``cells`` with a
        :class:`DeprecationWarning`.

    Raises
    ------
    ParameterError
        Naming the bad key (``system.rho``, ``controller.type``, ``analysis.delta_max``...).
    """
    spec = load_toml(path, "TOML file")
    if isinstance(spec.get("system"), dict) and spec["system"].get("type") == NPLUSM_TYPE:
        return _load_nplusm(spec, for_design)
    for key in spec:
        if key not in _TOP_KEYS:
            raise unknown_key(key, f"a section of the file: one of {list(_TOP_KEYS)}", key, _TOP_KEYS, spec[key])

    kind, params = _typed(_table(spec, "system", True), "system", _SYSTEM_KEYS, _SYSTEM_OPTIONAL, (NPLUSM_TYPE,))
    values: dict[str, Any] = {k: _system_value(kind, k, v) for k, v in params.items()}
    cls = SYSTEM_TYPES[kind]
    system = build_in_section("system", lambda: cls(**values))
    # a physical front end: its parameters as written, for the report (the plant is its general 2x2 form)
    physical = (kind, dict(params)) if kind in FRONT_ENDS else None

    controller: Controller | None = None  # nrobust design without [controller]: the controller is designed
    if not (for_design and "controller" not in spec):
        kind, params = _typed(_table(spec, "controller", True), "controller", _CONTROLLER_KEYS, _CONTROLLER_OPTIONAL)
        values = {k: _number(f"controller.{k}", v) for k, v in params.items()}
        controller = build_in_section("controller", lambda: CONTROLLER_TYPES[kind](**values))
    given_system, given_controller = system, controller  # as written, for the report
    # the plant as for a paper's controller when none is given (the route is the same for all of them)
    if loop_route(system, OpenLoop() if controller is None else controller) != "exact":
        # constant coefficients: analysed as written, exactly; a varying lam/mu: unchanged (characteristic route)
        system, controller = normalize(system, controller)

    analysis = _options(_table(spec, "analysis", not for_design), "analysis", _ANALYSIS_KEYS)
    delta_max = None
    if analysis["delta_max"] is None and not for_design:
        raise ParameterError("analysis.delta_max", "given (the largest loop delay of interest, > 0)")
    if analysis["delta_max"] is not None:
        delta_max = _number("analysis.delta_max", analysis["delta_max"])
        if delta_max <= 0:
            raise ParameterError("analysis.delta_max", "> 0", analysis["delta_max"])
    region = analysis["region"]
    if region is not None:
        if not isinstance(region, list) or len(region) != 4:
            raise ParameterError("analysis.region", "a list [re_min, re_max, im_min, im_max]", region)
        region = tuple(_number("analysis.region", v) for v in region)
        if not (region[0] < region[1] and region[2] < region[3]):
            raise ParameterError(
                "analysis.region", "a non-empty rectangle: re_min < re_max, im_min < im_max", list(region)
            )
    if not isinstance(analysis["k_region"], bool):
        raise ParameterError("analysis.k_region", "true or false", analysis["k_region"])
    if not isinstance(analysis["rigorous"], bool):
        raise ParameterError("analysis.rigorous", "true or false", analysis["rigorous"])
    accuracy = analysis["accuracy"]
    if accuracy is not None:
        accuracy = _number("analysis.accuracy", accuracy)
        if not 0.0 < accuracy < math.inf:
            raise ParameterError(
                "analysis.accuracy", "a positive number (the delay margin's target accuracy)", accuracy
            )

    design = _design(_table(spec, "design", True)) if "design" in spec else None

    simulation = None
    if "simulation" in spec:
        table = dict(_table(spec, "simulation", True))
        for old, new in _SIMULATION_RENAMED.items():
            if old not in table:
                continue
            if new in table:
                raise ParameterError(
                    f"simulation.{old}", f"left out when simulation.{new} is given (it is the deprecated name of {new})"
                )
            warnings.warn(
                f"{path}: the key simulation.{old} is deprecated, use simulation.{new}",
                DeprecationWarning,
                stacklevel=2,
            )
            table[new] = table.pop(old)
        sim = _options(table, "simulation", _SIMULATION_KEYS)
        delays = sim["delays"]
        if not isinstance(delays, list) or not delays:
            raise ParameterError("simulation.delays", "a non-empty list of loop delays >= 0", delays)
        delays = [_number("simulation.delays", d) for d in delays]
        if any(d < 0 for d in delays):
            raise ParameterError("simulation.delays", "delays >= 0", delays)
        t_end = _number("simulation.t_end", sim["t_end"])
        if t_end <= 0:
            raise ParameterError("simulation.t_end", "> 0", sim["t_end"])
        cells = sim["cells"]
        if isinstance(cells, bool) or not isinstance(cells, int) or cells < 4:
            raise ParameterError("simulation.cells", "an integer >= 4", cells)
        simulation = {
            "delays": delays,
            "t_end": t_end,
            "cells": cells,
            "u0": _profile("simulation.u0", sim["u0"]),
            "v0": _profile("simulation.v0", sim["v0"]),
        }
    return {
        "system": system,
        "controller": controller,
        "delta_max": delta_max,
        "region": region,
        "k_region": analysis["k_region"],
        "rigorous": analysis["rigorous"],
        "accuracy": accuracy,
        "simulation": simulation,
        "given_system": given_system,
        "given_controller": given_controller,
        "physical": physical,
        "design": design,
    }
