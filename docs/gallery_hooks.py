"""sphinx-gallery hooks of the nrobust documentation (named in ``docs/conf.py``).

The examples write their figures into the directory given as their first argument: the
gallery runs each with a directory of its own under ``docs/_build/gallery-output/`` and
shows the PNG files it wrote, in name order, each on its own row at the size it was saved
at. The directory is passed relative to the directory the example runs in (sphinx-gallery
runs it in ``examples/``), so that what an example prints about its output names no path
of the machine that built the pages.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

OUTPUT = Path(__file__).resolve().parent / "_build" / "gallery-output"


def _output_dir(src_file: str) -> Path:
    return OUTPUT / Path(src_file).stem


def example_argv(gallery_conf: dict[str, Any], script_vars: dict[str, Any]) -> list[str]:
    """The command line of an example: its own, empty, output directory, as a relative path."""
    out = _output_dir(script_vars["src_file"])
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    return [os.path.relpath(out, Path(script_vars["src_file"]).parent)]


def written_figures(block: Any, block_vars: dict[str, Any], gallery_conf: dict[str, Any]) -> str:
    """Image scraper: the PNG files the example wrote, copied where the gallery wants them.

    Each figure is its own single image (sphinx-gallery sets two or more side by side at 42 %
    of the width, a thumbnail), with its file name as the alternative text.
    """
    from sphinx_gallery.scrapers import figure_rst

    out = _output_dir(block_vars["src_file"])
    rst = []
    for png, target in zip(sorted(out.glob("*.png")), block_vars["image_path_iterator"]):
        shutil.copyfile(png, target)
        rst.append(figure_rst([target], gallery_conf["src_dir"], fig_titles=png.stem.replace("_", " ")))
    return "".join(rst)
