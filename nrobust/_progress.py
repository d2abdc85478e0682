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

__all__ = ["HiddenBar", "ProgressBar", "progress_bar", "show_progress"]


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


class HiddenBar:
    """The bar that is not shown: it counts the steps and draws nothing.

    tqdm (with ``importlib.metadata`` and ``email``, which it loads) is imported only for a
    bar that is drawn: the workers of ``nrobust paper`` and every computation run without a
    terminal do not load it.
    """

    def __init__(self, total: int) -> None:
        self.total = total
        self.n = 0

    def update(self, n: int = 1) -> None:
        """Count ``n`` more steps."""
        self.n += n

    def close(self) -> None:
        """Nothing to clear."""

    def __enter__(self) -> HiddenBar:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def progress_bar(
    total: int, progress: bool | None, desc: str, unit: str = "it", leave: bool = False
) -> ProgressBar | HiddenBar:
    """A bar of ``total`` steps on stderr, shown by the rule of :func:`show_progress`; else a :class:`HiddenBar`."""
    if not show_progress(progress):
        return HiddenBar(total)
    return _bar_class()(total=total, desc=desc, unit=unit, leave=leave, file=sys.stderr)
