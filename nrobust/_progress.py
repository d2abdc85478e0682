"""Progress bars: one rule for the Python API and the command line.

A bar is drawn on stderr when ``progress`` is True; when it is None (the default of
every long computation: sweeps, the paper run, ``k_region``, ``stability_chart``,
``tradeoff``), only when stderr is a terminal or the code runs in Jupyter, so that logs,
pipes and CI output carry no bars. ``nrobust --progress`` forces them, ``--no-progress``
turns them off.
"""

from __future__ import annotations

import functools
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from tqdm import tqdm as ProgressBar

__all__ = ["ProgressBar", "progress_bar", "show_progress"]


@functools.cache
def _bar_class() -> type[ProgressBar]:
    """tqdm without its monitor thread, so that no helper thread is alive (and copied
    half-way through a lock) when a fork-based pool forks its workers.

    tqdm is imported on the first bar, not with nrobust: the command line checks its
    input and output directory before it loads anything it does not need.
    """
    from tqdm import tqdm

    class _Bar(tqdm):
        monitor_interval = 0

    return _Bar


def show_progress(progress: bool | None) -> bool:
    """Whether to draw a bar: ``progress`` itself, or for None whether stderr is a terminal or Jupyter."""
    if progress is None:
        isatty = getattr(sys.stderr, "isatty", None)
        return bool(isatty is not None and isatty()) or "ipykernel" in sys.modules
    return bool(progress)


def progress_bar(total: int, progress: bool | None, desc: str, unit: str = "it", leave: bool = False) -> ProgressBar:
    """A bar of ``total`` steps on stderr, shown by the rule of :func:`show_progress` (disabled otherwise)."""
    show = show_progress(progress)
    return _bar_class()(total=total, disable=not show, desc=desc, unit=unit, leave=leave, file=sys.stderr)
