"""One BLAS thread inside a block (:func:`nrobust._threads.one_blas_thread`), and ``scipy.linalg`` imported only
for a block that calls it.

Oracle: threadpoolctl's own report of every loaded BLAS library's thread count (``threadpool_info``), read in a
fresh interpreter (``sys.modules`` there starts without scipy) whose BLAS libraries are first set to two threads.
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
    import numpy  # noqa: F401  (its BLAS loaded)
    from threadpoolctl import threadpool_info, threadpool_limits
    from nrobust._threads import one_blas_thread

    def blas():
        return sorted((p["filepath"], p["num_threads"]) for p in threadpool_info() if p["user_api"] == "blas")

    threadpool_limits(2, user_api="blas")
    out = {"before": blas()}
    with one_blas_thread():
        out["plain"] = blas()
        out["plain_scipy"] = "scipy.linalg" in sys.modules
    out["after_plain"] = blas()
    with one_blas_thread(scipy_linalg=True):
        out["scipy"] = blas()
    threadpool_limits(2, user_api="blas")
    out["loaded"] = blas()
    with one_blas_thread():
        out["plain_loaded"] = blas()
    out["after"] = blas()
    print(json.dumps(out))
    """
)


def test_blas_limited_and_scipy_imported_on_request():
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    run = subprocess.run([sys.executable, "-c", _SCRIPT], capture_output=True, text=True, env=env, check=True)
    out = json.loads(run.stdout)
    assert out["before"] and all(n == 2 for _, n in out["before"])
    # a plain block: numpy's BLAS on one thread, scipy.linalg not imported, the limit restored after
    assert not out["plain_scipy"]
    assert [p for p, _ in out["plain"]] == [p for p, _ in out["before"]]
    assert all(n == 1 for _, n in out["plain"])
    assert out["after_plain"] == out["before"]
    # scipy_linalg=True: scipy's own BLAS loaded (none more where numpy and scipy share one), every BLAS on one
    # thread inside
    assert len(out["before"]) <= len(out["scipy"]) <= len(out["before"]) + 1
    assert all(n == 1 for _, n in out["scipy"])
    # once scipy.linalg is loaded a plain block limits its BLAS too
    assert len(out["loaded"]) == len(out["scipy"]) and all(n == 2 for _, n in out["loaded"])
    assert all(n == 1 for _, n in out["plain_loaded"])
    assert out["after"] == out["loaded"]
