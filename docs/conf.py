"""Sphinx configuration of the nrobust documentation (``make docs``).

Sphinx, as the scientific Python projects publish theirs: the Markdown pages of ``docs/``
through myst-parser, the API reference generated from the numpydoc docstrings (autosummary
and numpydoc), the scripts of ``examples/`` as a sphinx-gallery with their figures. The
build runs with warnings as errors (``sphinx-build -W``), so a broken reference or a
malformed docstring fails it.
"""

from __future__ import annotations

import sys
from pathlib import Path

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
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "auto_examples/*.ipynb", "auto_examples/*.py", "auto_examples/*.zip", "**.codeobj.json"]
suppress_warnings = ["myst.header"]

# Not nitpicky: the docstrings cite many objects by the name a package re-exports them under
# (``nrobust.roots.find_roots`` for ``nrobust.roots.finder.find_roots``), which Sphinx documents
# once, where defined (93 such references when this was written). That every reference names
# an existing object of the right kind is checked instead by tests/test_docs.py
# (test_docstring_references_resolve), which runs with `make test`.

# Markdown: GitHub-style anchors for the headings the pages link to.
myst_heading_anchors = 3

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

html_theme = "alabaster"
html_static_path: list[str] = []
html_title = f"nrobust {release}"

# ------------------------------------------------------------------ gallery
# The hooks are named by their import path (docs/gallery_hooks.py), so that the
# configuration can be cached. The examples save their figures (``python examples/X.py OUT``
# writes them into OUT): those files are the gallery's images, not the figures left open.
sys.path.insert(0, str(Path(__file__).resolve().parent))

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
}


def _skip_foreign(app: object, what: str, name: str, obj: object, skip: bool, options: object) -> bool | None:
    """Document nrobust's own objects only (not a class a module imports, such as scipy's cKDTree)."""
    module = getattr(obj, "__module__", None)
    if isinstance(module, str) and not module.startswith("nrobust") and what == "module":
        return True
    return None


def setup(app: object) -> None:
    app.connect("autodoc-skip-member", _skip_foreign)  # type: ignore[attr-defined]
