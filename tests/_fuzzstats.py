"""Counters of the differential harness (``tests/test_harness.py``), printed by ``tests/conftest.py``.

A *case* is one generated input; a *claim* is one certified statement of nrobust checked
against an oracle (a root count, a certified abscissa, a margin, a crossing direction, a
named ``ParameterError`` for a bad input, ...); a *contradiction* is a claim the oracle
refutes, a wrong exception type, a NaN result or a hang; a *refusal* is an honest
``CertificationError`` (or ``ConvergenceError``) on valid input; *unsure* counts the
cases an oracle could not decide (skipped, not counted as claims).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any


@dataclass
class FuzzStats:
    """Running totals over a pytest session."""

    counts: Counter = field(default_factory=Counter)
    refusals_by_test: Counter = field(default_factory=Counter)
    contradictions: list[dict[str, Any]] = field(default_factory=list)

    def case(self) -> None:
        self.counts["cases"] += 1

    def claim(self, ok: bool, test: str, what: str, case: Any) -> bool:
        """Count a checked claim; record a contradiction if ``ok`` is False."""
        self.counts["claims"] += 1
        if not ok:
            self.contradiction(test, what, case)
        return ok

    def contradiction(self, test: str, what: str, case: Any) -> None:
        self.counts["contradictions"] += 1
        self.contradictions.append({"test": test, "what": what, "case": repr(case)[:600]})

    def refusal(self, test: str) -> None:
        self.counts["refusals"] += 1
        self.refusals_by_test[test] += 1

    def unsure(self) -> None:
        self.counts["unsure"] += 1

    def summary(self) -> list[str]:
        c = self.counts
        lines = [
            f"cases tried: {c['cases']}",
            f"certified claims checked: {c['claims']}",
            f"contradictions: {c['contradictions']}",
            f"honest refusals: {c['refusals']}",
            f"oracle unsure (skipped): {c['unsure']}",
        ]
        if self.refusals_by_test:
            lines.append("refusals by test: " + ", ".join(f"{k} {v}" for k, v in sorted(self.refusals_by_test.items())))
        kinds = Counter((d["test"], d["what"].split(":")[0]) for d in self.contradictions)
        for (test, what), n in sorted(kinds.items()):
            lines.append(f"  {n:5d} x {test}: {what}")
        return lines


STATS = FuzzStats()
