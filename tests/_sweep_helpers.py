"""A slow, observable analysis for the journal tests of ``nrobust sweep``.

Each point sleeps ``pause`` seconds, then, as its last act before returning, leaves a
marker file named after its parameters in the directory ``$NROBUST_TEST_MARKERS`` (when
set): the markers on disk are the points that finished, whatever happened next.
"""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

from nrobust.sweeps.sweepfile import ANALYSES, _Analysis

MARKERS_ENV = "NROBUST_TEST_MARKERS"


def marker_name(K: float, rho: float) -> str:
    return f"{K!r}_{rho!r}"


def slow_product(system: Any, controller: Any, pause: float = 0.05) -> dict[str, float]:
    """``rho * K`` after a pause."""
    time.sleep(pause)
    value = system.rho * controller.K
    markers = os.environ.get(MARKERS_ENV)
    if markers:
        Path(markers, marker_name(controller.K, system.rho)).touch()
    return {"y": value}


def _columns(result: dict[str, float]) -> dict[str, float]:
    return result


SLOW = _Analysis(slow_product, 2, (), _columns, ("y",))


def register() -> None:
    """Make the analysis available to SWEEP.toml as ``analysis = "slow"``."""
    ANALYSES["slow"] = SLOW
