"""A one-parameter design in a fresh interpreter imports neither ``scipy.optimize`` nor ``scipy.linalg``.

Their imports took 0.4 s of CPU, more than the rest of the equation solving of a design such as the one
below: the ends of a feasible interval (:func:`nrobust.design.best_decay_rate`, a curve crossing the required
margin) and the pair births near them are solved by the package's own bracketed iteration, and the design's
block of one BLAS thread (:func:`nrobust._threads.one_blas_thread`) does not import ``scipy.linalg``.

Oracle: ``sys.modules`` of the fresh interpreter after the design. The design (U_BS2(K) on the paper's plant,
the best decay rate with a delay margin of at least 0.1) solves three level crossings and six pair births on
its way; its gain must still be the one where the margin is 0.1, which the certified margin of the returned
design shows (``margin`` within its own accuracy of 0.1, bounded below by the requirement).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

_SCRIPT = textwrap.dedent(
    """
    import json, sys
    import nrobust as nr

    design = nr.design_reflection(nr.Hyperbolic2x2(1, 1, 1, 1, 1, 0.85), "decay_rate", margin_at_least=0.1)
    margin = design.design.certificate
    print(json.dumps({
        "kind": design.design.kind,
        "margin": margin.margin,
        "accuracy": margin.accuracy,
        "scipy": sorted(m for m in ("scipy.optimize", "scipy.linalg") if m in sys.modules),
    }))
    """
)


def test_decay_rate_design_without_scipy_imports():
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    run = subprocess.run([sys.executable, "-c", _SCRIPT], capture_output=True, text=True, env=env, check=True)
    out = json.loads(run.stdout)
    assert out["scipy"] == []
    assert out["kind"] == "margin constraint"
    assert 0.1 <= out["margin"] <= 0.1 + max(out["accuracy"], 1e-9)
