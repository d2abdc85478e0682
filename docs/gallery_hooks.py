"""sphinx-gallery hooks of the nrobust documentation (named in ``docs/conf.py``).

The examples write their figures into the directory given as their first argument
(``python examples/X.py OUT``; default ``out/``). The gallery runs each example in
``examples/`` (sphinx-gallery's working directory) with the argument ``out``, as a user
would type it, so that what an example prints about its output (``figures in out/``) names
no path of the machine that built the pages; it shows the PNG files the example wrote, in
name order, each on its own row at the size it was saved at. ``examples/out`` exists only
during the build: :func:`claim_output` creates it (and refuses to touch a directory of that
name that the build did not create) and :func:`remove_output` deletes it when the build ends.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

#: The examples' output directory during the build, as the examples see it (``out``).
OUTPUT = Path(__file__).resolve().parent.parent / "examples" / "out"
#: The file that marks :data:`OUTPUT` as the build's own.
MARKER = OUTPUT / ".written-by-the-docs-build"


def claim_output(app: Any = None) -> None:
    """Create :data:`OUTPUT` for the build; an ``examples/out`` the build did not create is an error."""
    if OUTPUT.exists() and not MARKER.exists():
        raise RuntimeError(f"{OUTPUT} exists and was not written by the documentation build: move it away first")
    shutil.rmtree(OUTPUT, ignore_errors=True)
    OUTPUT.mkdir(parents=True)
    MARKER.touch()


def remove_output(app: Any = None, exception: BaseException | None = None) -> None:
    """Delete :data:`OUTPUT` when the build ends (if it is the build's own)."""
    if MARKER.exists():
        shutil.rmtree(OUTPUT)


def example_argv(gallery_conf: dict[str, Any], script_vars: dict[str, Any]) -> list[str]:
    """The command line of an example: ``out``, emptied of the previous example's files."""
    claim_output()
    return [OUTPUT.name]


def written_figures(block: Any, block_vars: dict[str, Any], gallery_conf: dict[str, Any]) -> str:
    """Image scraper: the PNG files the example wrote, copied where the gallery wants them.

    Each figure is its own single image (sphinx-gallery sets two or more side by side at 42 %
    of the width, a thumbnail), with its file name as the alternative text.
    """
    from sphinx_gallery.scrapers import figure_rst

    rst = []
    for png, target in zip(sorted(OUTPUT.glob("*.png")), block_vars["image_path_iterator"]):
        shutil.copyfile(png, target)
        rst.append(figure_rst([target], gallery_conf["src_dir"], fig_titles=png.stem.replace("_", " ")))
    return "".join(rst)
