"""The example budget of the property-based tests (``tests/test_harness.py``, ``tests/test_fuzz_*.py``).

CI runs ``ci`` derandomised examples per test; ``NROBUST_FUZZ_EXAMPLES=N`` (``make fuzz``) runs
``N * weight`` random ones.
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, Phase, settings

FUZZ = int(os.environ.get("NROBUST_FUZZ_EXAMPLES", "0") or 0)


def budget(ci: int, weight: float = 1.0, *, shrink: bool = True) -> settings:
    """Hypothesis settings for ``ci`` examples in CI, ``FUZZ * weight`` under ``make fuzz``.

    ``shrink=True``: a failure is reported as its minimal example; ``False``: no shrinking (the
    harness collects contradictions instead of raising them).
    """
    return settings(
        max_examples=max(1, int(FUZZ * weight)) if FUZZ else ci,
        derandomize=not FUZZ,
        database=None,
        deadline=None,
        suppress_health_check=list(HealthCheck),
        print_blob=False,
        **({} if shrink else {"phases": (Phase.explicit, Phase.generate)}),
    )
