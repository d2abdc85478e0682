"""sphinx-gallery hooks of the nrobust documentation (named in ``docs/conf.py``).

The examples write their figures into the directory given as their first argument: the
gallery runs each with a directory of its own under ``docs/_build/gallery-output/`` and
shows the PNG files it wrote, in name order.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

OUTPUT = Path(__file__).resolve().parent / "_build" / "gallery-output"


def _output_dir(src_file: str) -> Path:
    return OUTPUT / Path(src_file).stem


def example_argv(gallery_conf: dict[str, Any], script_vars: dict[str, Any]) -> list[str]:
    """The command line of an example: its own, empty, output directory."""
    out = _output_dir(script_vars["src_file"])
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    return [str(out)]


def written_figures(block: Any, block_vars: dict[str, Any], gallery_conf: dict[str, Any]) -> str:
    """Image scraper: the PNG files the example wrote, copied where the gallery wants them."""
    from sphinx_gallery.scrapers import figure_rst

    out = _output_dir(block_vars["src_file"])
    paths = []
    for png, target in zip(sorted(out.glob("*.png")), block_vars["image_path_iterator"]):
        shutil.copyfile(png, target)
        paths.append(target)
    return figure_rst(paths, gallery_conf["src_dir"])
