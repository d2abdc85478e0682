"""Sphinx configuration of the nrobust documentation (``make docs``).

Sphinx, as the scientific Python projects publish theirs: the Markdown pages of ``docs/``
through myst-parser, the API reference generated from the numpydoc docstrings (autosummary
and numpydoc), the scripts of ``examples/`` as a sphinx-gallery with their figures. The
build runs with warnings as errors (``sphinx-build -W``), so a broken reference or a
malformed docstring fails it.
"""

from __future__ import annotations

import inspect
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import nrobust  # noqa: E402

project = "nrobust"
author = "the nrobust authors"
copyright = "2026, the nrobust authors"
release = nrobust.__version__
version = release

extensions = [
    "myst_parser",
    "numpydoc",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    # MathJax served from the site itself (_static/mathjax), not from a CDN: the pages render
    # their equations offline and from a local build
    "sphinx-mathjax-offline",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "auto_examples/*.ipynb", "auto_examples/*.py", "auto_examples/*.zip", "**.codeobj.json"]
suppress_warnings = ["myst.header"]

# Nitpicky: every reference must resolve. The docstrings cite objects by the name a package
# re-exports them under (``nrobust.roots.find_roots`` for ``nrobust.roots.finder.find_roots``)
# or by the short name their module imports (``QuasiPolynomial``); Sphinx documents each
# object once, where it is defined, and _resolve_by_import (below) sends such a reference
# there. A reference to an object that exists but has no page by design (a private helper,
# a standard-library function: the build is offline, without intersphinx) is set as code,
# unlinked; a name that does not exist stays an error.
nitpicky = True

# Markdown: GitHub-style anchors for the headings the pages link to; ``$...$`` and ``$$...$$``
# for mathematics (rendered by MathJax) and bare ``\begin{align}`` environments. Displayed
# equations carry the published paper's numbers by ``\tag{53}``, not Sphinx's own numbering.
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath", "amsmath"]
# The local MathJax is version 3, which keeps inline formulas on one line (the narrow columns
# of the tables of docs/theory.md would otherwise cut them mid-term).

# API reference: one page per module, generated from the docstrings.
autosummary_generate = True
autosummary_imported_members = False
# members defined in each module only: the re-exports of nrobust and nrobust.hyperbolic are
# documented where they are defined
autodoc_default_options = {"members": True, "ignore-module-all": True}
autodoc_typehints = "none"  # numpydoc's Parameters sections carry the types
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks: set[str] = set()

# The theme of NumPy, SciPy and pandas: a top bar for the chapters, the page's sections on
# the right, and room for the wide tables of the API pages (docs/_static/nrobust.css).
html_theme = "pydata_sphinx_theme"
html_static_path = ["_static"]
templates_path = ["_templates"]
html_css_files = ["nrobust.css"]
html_title = f"nrobust {release}"
html_theme_options = {
    "navbar_align": "left",
    "header_links_before_dropdown": 3,
    "show_toc_level": 2,
    "navigation_with_keys": False,
    "show_prev_next": True,
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version", "theme-version"],
    # the API contract and the generated reference: the whole width for their tables
    "secondary_sidebar_items": {"**": ["page-toc"], "api": [], "reference": []},
}
html_sidebars = {"index": [], "five_minutes": [], "api": [], "reference": []}
html_context = {"default_mode": "light"}

# ------------------------------------------------------------------ gallery
# The hooks are named by their import path (docs/gallery_hooks.py), so that the
# configuration can be cached. The examples save their figures (``python examples/X.py OUT``
# writes them into OUT): those files are the gallery's images, not the figures left open.
sys.path.insert(0, str(Path(__file__).resolve().parent))
import gallery_hooks  # noqa: E402  (the directory above, on sys.path)

sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": "auto_examples",
    # every example runs (10-40 s each on two cores); their figures are the gallery's
    "filename_pattern": r".*\.py$",
    "reset_argv": "gallery_hooks.example_argv",
    "image_scrapers": ("gallery_hooks.written_figures",),
    "download_all_examples": False,
    "abort_on_example_error": True,
    "write_computation_times": False,
    # the examples' own figures are shown one per row at the width they were saved at
    # (gallery_hooks.written_figures), the first one as the thumbnail of the index
    "thumbnail_size": (400, 280),
    "remove_config_comments": True,
    "show_signature": False,
}


def _skip_foreign(app: object, what: str, name: str, obj: object, skip: bool, options: object) -> bool | None:
    """Document nrobust's own classes and functions only (not a class a module imports, such as
    scipy's cKDTree); module data with a ``#:`` comment, such as a type alias, is documented."""
    module = getattr(obj, "__module__", None)
    foreign = isinstance(module, str) and not module.startswith("nrobust")
    if foreign and what == "module" and (inspect.isclass(obj) or inspect.isroutine(obj)):
        return True
    return None


def _find(dotted: str) -> tuple[bool, object]:
    """``(True, obj)`` for the object named ``dotted`` (a module, then attributes), else ``(False, None)``.

    A dataclass field without a default (``Certificate.claims``) is found as its class.
    """
    import dataclasses
    import importlib

    if not dotted:  # the parent of a top-level name (``cmath``)
        return False, None
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj: object = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for k, name in enumerate(parts[cut:]):
            if hasattr(obj, name):
                obj = getattr(obj, name)
            elif dataclasses.is_dataclass(obj) and k == len(parts) - cut - 1 and name in obj.__dataclass_fields__:
                return True, obj
            else:
                return False, None
        return True, obj
    return False, None


def _canonical(obj: object) -> str | None:
    """``module.qualname`` where Sphinx documents a class or function, or None (data)."""
    module, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
    if isinstance(module, str) and isinstance(qualname, str) and "<" not in qualname:
        return f"{module}.{qualname}"
    return None


def _resolve_by_import(app: Any, env: Any, node: Any, contnode: Any) -> Any:
    """Resolve a Python reference by importing what it names (``missing-reference``).

    The name is looked up as Python would see it from the docstring (the class and the
    module the reference is written in), then as written, then in every nrobust module
    (a function documented under the name of its package); the reference goes to the
    object's defining module. An object that exists but has no page of its own (private,
    or outside nrobust) is set as code without a link; a name that does not exist is left
    unresolved, so that nitpicky reports it.
    """
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"].lstrip("~.")
    module, cls = node.get("py:module"), node.get("py:class")
    tries = ([f"{module}.{cls}.{target}"] if module and cls else []) + ([f"{module}.{target}"] if module else [])
    tries.append(target)
    tries += [f"{name}.{target}" for name in sorted(sys.modules) if name.startswith("nrobust")]
    domain = env.get_domain("py")
    for dotted in tries:
        exists, obj = _find(dotted)
        if not exists:
            continue
        names = [n for n in (_canonical(obj), dotted) if n is not None]
        parent_found, parent = _find(dotted.rpartition(".")[0])
        if parent_found and inspect.isclass(parent) and _canonical(parent):
            names.append(str(_canonical(parent)))  # an attribute without a page of its own: its class
        for name in dict.fromkeys(names):
            ref = domain.resolve_xref(env, node["refdoc"], app.builder, "obj", name, node, contnode)
            if ref is not None:
                return ref
        canonical = _canonical(obj) or dotted
        if not canonical.startswith("nrobust.") or any(part.startswith("_") for part in canonical.split(".")):
            return contnode
    return None


def _write_shadowed_modules(app: Any, config: Any = None) -> None:
    """Write ``generated/shadowed_modules.rst``: the members of the modules named like a function.

    ``nrobust.hyperbolic.delay_form`` is a module and, as an attribute of its package, the
    function ``delay_form``; autosummary's walk of the package documents the function under
    that name and never enters the module. This page documents the module's own classes and
    functions (found by walking the package, so that it cannot drift), written before
    Sphinx lists the sources, so that autosummary generates the pages it lists.
    """
    import importlib
    import pkgutil

    lines = ["Modules named like a function", "=============================", ""]
    lines += [
        "Each of these modules bears the name of the function its package re-exports, which the",
        "reference documents under that name; the module's own classes and functions are these.",
        "",
    ]
    for info in pkgutil.walk_packages(nrobust.__path__, "nrobust."):
        module = importlib.import_module(info.name)
        package, _, last = info.name.rpartition(".")
        if getattr(importlib.import_module(package), last, None) is module:
            continue
        own = [
            name
            for name, obj in vars(module).items()
            if not name.startswith("_")
            and (inspect.isclass(obj) or inspect.isfunction(obj))
            and obj.__module__ == info.name
        ]
        if own:
            title = f"``{info.name}``"
            lines += [title, "-" * len(title), "", f".. currentmodule:: {info.name}", "", ".. autosummary::"]
            lines += ["   :toctree: .", "", *(f"   {name}" for name in own), ""]
    page = Path(app.srcdir) / "generated" / "shadowed_modules.rst"
    page.parent.mkdir(exist_ok=True)
    text = "\n".join(lines)
    if not page.exists() or page.read_text() != text:
        page.write_text(text)


def setup(app: Any) -> None:
    app.connect("config-inited", _write_shadowed_modules)  # before the sources are listed
    app.connect("build-finished", gallery_hooks.remove_output)  # examples/out lives during the build only
    app.connect("autodoc-skip-member", _skip_foreign)
    app.connect("missing-reference", _resolve_by_import)
