"""Session hooks: the figures of the differential harness (``tests/test_harness.py``)."""

from __future__ import annotations

from typing import Any

from _fuzzstats import STATS


def pytest_terminal_summary(terminalreporter: Any) -> None:
    """Print cases, claims, contradictions and refusals when the harness ran."""
    if STATS.counts["cases"]:
        terminalreporter.section("nrobust differential harness")
        for line in STATS.summary():
            terminalreporter.write_line(line)
