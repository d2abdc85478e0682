"""A command-line process imports matplotlib without composing its artists' ``set`` docstrings.

Matplotlib writes, for each of its hundred ``Artist`` subclasses, the docstring of its ``set``
method: the list of the class's properties, each read from its setter's docstring
(:func:`matplotlib.artist.kwdoc`). That is about a quarter of the time ``import matplotlib.pyplot``
takes (0.2 s of CPU), spent on text that only ``help()`` shows. The ``nrobust`` command never
shows it, so its process has :func:`matplotlib.artist.kwdoc` return an empty list instead; what
matplotlib draws does not depend on it. A library user's process is left as it is.
"""

from __future__ import annotations

import importlib.machinery
import sys
from collections.abc import Sequence
from types import ModuleType
from typing import Any

__all__ = ["skip_artist_property_docs"]


class _ArtistDocsFinder:
    """Finds ``matplotlib.artist`` as the standard finder does, and has it load without property lists.

    A meta path finder (:class:`importlib.abc.MetaPathFinder`'s protocol, without importing
    :mod:`importlib.abc`, whose import costs a command 0.02 s).
    """

    def find_spec(self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None) -> Any:
        if fullname != "matplotlib.artist":
            return None
        sys.meta_path.remove(self)  # once: the module is found below
        spec = importlib.machinery.PathFinder.find_spec(fullname, path)
        loader = None if spec is None else spec.loader
        if loader is None or not hasattr(loader, "exec_module"):
            return spec
        execute = loader.exec_module

        def exec_module(module: ModuleType) -> None:
            execute(module)  # Artist's own docstring is written here; its subclasses come later
            if callable(getattr(module, "kwdoc", None)):
                module.kwdoc = _no_property_list  # type: ignore[attr-defined]

        loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


def _no_property_list(artist: Any) -> str:
    """What :func:`matplotlib.artist.kwdoc` returns in the command's process: no property list."""
    return ""


def skip_artist_property_docs() -> None:
    """Have a later ``import matplotlib`` in this process skip the artists' property lists.

    Nothing is imported here (a command that stops at an input error never loads matplotlib);
    nothing changes when matplotlib is already loaded.
    """
    if "matplotlib.artist" not in sys.modules and not any(isinstance(f, _ArtistDocsFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, _ArtistDocsFinder())
