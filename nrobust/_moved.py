"""Module paths that moved when the package was laid out in layers: deprecated aliases.

``import nrobust.crossings`` (say) still works: a finder at the end of ``sys.meta_path``
answers for the old path with a module that forwards every attribute to the new home and
emits one ``DeprecationWarning`` naming it. ``CHANGELOG.md`` lists the moves;
``docs/api.md`` gives the new paths. New code imports from the new homes.
"""

from __future__ import annotations

import importlib
import importlib.machinery
import sys
import types
import warnings
from collections.abc import Callable, Sequence
from typing import Any, cast

#: Old module path -> the new homes searched for an attribute, in order.
MOVED: dict[str, tuple[str, ...]] = {
    "nrobust.statespace": ("nrobust.lti", "nrobust.lti.statespace"),
    "nrobust.transfer": ("nrobust.lti", "nrobust.lti.transfer", "nrobust.hyperbolic.loops"),
    "nrobust.crossings": ("nrobust.margins", "nrobust.margins.axis", "nrobust.margins.crossing"),
    "nrobust.proven_crossings": ("nrobust.margins", "nrobust.margins.proven"),
    "nrobust.matrix_crossings": ("nrobust.margins", "nrobust.margins.matrix"),
    "nrobust.hyperbolic.system": ("nrobust.hyperbolic.plants", "nrobust.hyperbolic.plants.hyperbolic2x2"),
    "nrobust.hyperbolic.general": ("nrobust.hyperbolic.plants", "nrobust.hyperbolic.plants.general"),
    "nrobust.hyperbolic.frontends": ("nrobust.hyperbolic.plants", "nrobust.hyperbolic.plants.frontends"),
    "nrobust.hyperbolic.varying_kernels": ("nrobust.hyperbolic.kernels", "nrobust.hyperbolic.kernels.varying"),
    "nrobust.hyperbolic.nplusm_kernels": ("nrobust.hyperbolic.nplusm", "nrobust.hyperbolic.nplusm.kernels"),
    "nrobust.hyperbolic.laplace": ("nrobust.hyperbolic.loops", "nrobust.hyperbolic.loops.laplace"),
    "nrobust.hyperbolic.delay_form": ("nrobust.hyperbolic.loops", "nrobust.hyperbolic.loops.delay_form"),
    "nrobust.hyperbolic.varying": ("nrobust.hyperbolic.loops", "nrobust.hyperbolic.loops.varying_form"),
    "nrobust.hyperbolic.controllers": ("nrobust.hyperbolic.loops", "nrobust.hyperbolic.loops.controllers"),
    "nrobust.hyperbolic.feedback": ("nrobust.hyperbolic.loops", "nrobust.hyperbolic.loops.feedback"),
    "nrobust.hyperbolic.robustness": ("nrobust.hyperbolic.analyses", "nrobust.hyperbolic.analyses.rouche"),
    "nrobust.hyperbolic.studies": ("nrobust.hyperbolic.analyses", "nrobust.margins.gain"),
    "nrobust.hyperbolic.simulate_general": ("nrobust.hyperbolic.simulate", "nrobust.hyperbolic.simulate.general"),
    "nrobust.parallel": ("nrobust.sweeps", "nrobust.sweeps.executors", "nrobust.sweeps.engine"),
    "nrobust.montecarlo": ("nrobust.sweeps", "nrobust.sweeps.montecarlo"),
    "nrobust.sweepfile": ("nrobust.sweeps", "nrobust.sweeps.sweepfile"),
    "nrobust.sweep": ("nrobust.sweeps", "nrobust.hyperbolic.analyses"),
    "nrobust.certificate": ("nrobust.reports", "nrobust.reports.certificate"),
    "nrobust.report": ("nrobust.reports", "nrobust.reports.report"),
    "nrobust.outputs": ("nrobust.reports", "nrobust.reports.outputs"),
    "nrobust.paper": ("nrobust.reports", "nrobust.reports.paper"),
    "nrobust.analyze": ("nrobust.reports", "nrobust.reports.analyze"),
    "nrobust.nplusm_report": ("nrobust.reports", "nrobust.reports.nplusm"),
}

#: Single names that left a module which stays: module -> {name: its new home}. The module
#: installs :func:`moved_attribute` as its ``__getattr__`` (PEP 562).
MOVED_NAMES: dict[str, dict[str, str]] = {
    "nrobust.hyperbolic.nplusm": {
        "simulate_nplusm": "nrobust.hyperbolic.simulate",
        "NPlusMSimulation": "nrobust.hyperbolic.simulate",
    },
}


class MovedModule(types.ModuleType):
    """An old module path: every attribute is looked up in the new homes.

    Importing ``a.b`` binds the module to the attribute ``b`` of ``a``. Where ``a.b`` was also
    a function of ``a`` (``nrobust.sweep``, ``nrobust.hyperbolic.delay_form``), the alias is
    callable as that function, so the import of the old path does not break a call of it.
    """

    def __init__(self, name: str, homes: Sequence[str], function: Any = None) -> None:
        super().__init__(name, f"Deprecated alias of {', '.join(homes)}.")
        self.__homes = tuple(homes)
        self.__function = function

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        if self.__function is None:
            raise TypeError(f"module {self.__name__!r} is not callable")
        return self.__function(*args, **kwargs)

    def __getattr__(self, attr: str) -> Any:
        if attr == "__all__":  # ``from old import *``: the public names of the new homes
            return sorted({n for home in self.__homes for n in getattr(importlib.import_module(home), "__all__", ())})
        if attr.startswith("__"):
            raise AttributeError(attr)
        for home in self.__homes:
            module = importlib.import_module(home)
            if hasattr(module, attr):
                return getattr(module, attr)
        raise AttributeError(f"module {self.__name__!r} (now {', '.join(self.__homes)}) has no attribute {attr!r}")

    def __dir__(self) -> list[str]:
        return sorted({n for home in self.__homes for n in dir(importlib.import_module(home))})


def moved_attribute(module: str) -> Callable[[str], Any]:
    """The PEP 562 ``__getattr__`` of ``module`` for its names in :data:`MOVED_NAMES`.

    Each access finds the name in its new home and emits a ``DeprecationWarning`` naming it
    (the home is imported on first access, so the old module need not import it: no cycle).
    """
    names = MOVED_NAMES.get(module, {})

    def __getattr__(attr: str) -> Any:
        home = names.get(attr)
        if home is None:
            raise AttributeError(f"module {module!r} has no attribute {attr!r}")
        warnings.warn(
            f"{module}.{attr} moved to {home}.{attr}; import it from there (the old name is a deprecated alias)",
            DeprecationWarning,
            stacklevel=2,
        )
        return getattr(importlib.import_module(home), attr)

    return __getattr__


class MovedFinder:
    """Finder and loader (``importlib.abc`` protocols) of the old paths of :data:`MOVED`, last on ``sys.meta_path``."""

    def find_spec(self, fullname: str, path: Any, target: Any = None) -> importlib.machinery.ModuleSpec | None:
        if fullname not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, cast(Any, self))  # a Loader by protocol

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType:
        homes = MOVED[spec.name]
        warnings.warn(
            f"{spec.name} moved to {homes[0]}; import from there ({spec.name} is a deprecated alias)",
            DeprecationWarning,
            stacklevel=2,  # the warnings module skips the import machinery's frames: the importer's line
        )
        parent, _, child = spec.name.rpartition(".")
        shadowed = getattr(sys.modules[parent], child, None) if parent in sys.modules else None
        return MovedModule(spec.name, homes, shadowed if callable(shadowed) else None)

    def exec_module(self, module: types.ModuleType) -> None:
        """Nothing to run: attributes are forwarded on access."""


def install() -> None:
    """Put :class:`MovedFinder` last on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, MovedFinder) for f in sys.meta_path):
        sys.meta_path.append(MovedFinder())
