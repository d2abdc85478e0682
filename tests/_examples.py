"""Running the scripts of ``examples/`` as a user would: a fresh interpreter, an output directory."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run_example(script: str, out: Path) -> str:
    """Run ``examples/<script> <out>`` in ``out`` (Agg backend, one BLAS thread); its standard output.

    Fails the calling test on a non-zero exit, with the end of the standard error.
    """
    env = {**os.environ, "MPLBACKEND": "Agg", "OPENBLAS_NUM_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / script), str(out)],
        cwd=out,
        env=env,
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout
