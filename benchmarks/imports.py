"""Start-up cost: the time and the modules of ``import nrobust`` and of the core's entry points.

Each statement runs in a fresh interpreter (``python -X importtime``-free timing: wall time
of the import statement alone, measured inside the child), ``--repeat`` times; the minimum
is printed with the number of nrobust modules and of all modules it loaded, and whether it
loaded matplotlib. The peers, measured in the same run, are python-control (``import
control``) and scipy's signal processing (``import scipy.signal``), the imports a control
engineer pays for today.

``tests/test_layering.py`` asserts which modules the core's imports load (a deterministic
stand-in for their time); this script measures the time itself, outside CI.

Run: ``python benchmarks/imports.py [--repeat 5]``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

STATEMENTS = (
    "import nrobust",
    "import nrobust.quasipoly",
    "import nrobust.roots",
    "import nrobust.margins",
    "import nrobust.hyperbolic",
    "from nrobust import delay_margin; delay_margin",
    "import nrobust.cli",
)
PEERS = ("import control", "import scipy.signal")

_CHILD = """
import sys, time
t = time.perf_counter()
exec({statement!r})
dt = time.perf_counter() - t
import json
mods = list(sys.modules)
print(json.dumps([dt, sum(m.startswith("nrobust") for m in mods), len(mods), "matplotlib" in sys.modules]))
"""


def measure(statement: str, repeat: int) -> tuple[float, int, int, bool]:
    """Minimum wall time of ``statement`` over ``repeat`` fresh interpreters, and what it loaded."""
    runs = []
    for _ in range(repeat):
        out = subprocess.run(
            [sys.executable, "-c", _CHILD.format(statement=statement)], capture_output=True, text=True, check=True
        )
        runs.append(json.loads(out.stdout))
    best = min(runs, key=lambda r: r[0])
    return best[0], best[1], best[2], best[3]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    print(f"{'statement':52s} {'min s':>7s} {'nrobust':>8s} {'modules':>8s}  matplotlib")
    for statement in (*STATEMENTS, *PEERS):
        dt, ours, total, mpl = measure(statement, args.repeat)
        print(f"{statement:52s} {dt:7.3f} {ours:8d} {total:8d}  {'yes' if mpl else 'no'}")


if __name__ == "__main__":
    main()
