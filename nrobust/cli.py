"""The ``nrobust`` command line.

``nrobust analyze SYSTEM.toml -o OUT/``
    Certify one plant and controller (schema in ``docs/getting_started.md``) and write
    ``report.md``, ``report.html``, ``certificate.json`` and the figures.
``nrobust paper -o OUT/``
    The reference paper's example end to end: classification, figures 1 and 3 by
    simulation of the PDE, delay margins of U_BS and U_BS2(K = 0.1), the ``(K, delta)``
    stability chart with the sufficient bound, the decay/margin trade-off and the report.
``nrobust sweep SWEEP.toml -o OUT/ [--dask ADDRESS]``
    A parameter sweep or Monte Carlo study (:func:`nrobust.sweep.run_sweep_file`).

Input errors end the program with exit code 2 and a one-line message naming the bad key
(no traceback); a certified computation that reaches its work bound ends it with exit
code 1 and the message of the :class:`~nrobust.errors.CertificationError`.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

import matplotlib

from .analyze import run_analyze
from .config import PiecewiseLinear, load_system_file
from .errors import NrobustError, ParameterError
from .paper import PAPER_SYSTEM, run_paper
from .sweepfile import run_sweep_file

__all__ = ["PAPER_SYSTEM", "PiecewiseLinear", "load_system_file", "main", "run_analyze", "run_paper"]


# ---------------------------------------------------------------------- main
def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="nrobust", description="Delay-robustness analysis of boundary-controlled 2x2 hyperbolic PDEs."
    )
    sub = p.add_subparsers(dest="command", required=True)
    a = sub.add_parser("analyze", help="certify the loop described by a SYSTEM.toml file and write a report")
    a.add_argument("file", help="SYSTEM.toml (schema: docs/getting_started.md)")
    a.add_argument("-o", "--out", required=True, help="output directory")
    a.add_argument("--no-progress", action="store_true", help="no progress bar")
    pp = sub.add_parser("paper", help="the reference paper's example end to end")
    pp.add_argument("-o", "--out", required=True, help="output directory")
    pp.add_argument("--no-progress", action="store_true", help="no progress bar")
    s = sub.add_parser("sweep", help="run a SWEEP.toml parameter sweep or Monte Carlo study")
    s.add_argument("file", help="SWEEP.toml (schema: docs/sweeps.md)")
    s.add_argument("-o", "--out", required=True, help="output directory")
    s.add_argument("--dask", metavar="ADDRESS", default=None, help="Dask scheduler address, e.g. tcp://host:8786")
    s.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``nrobust`` command; returns the exit code."""
    matplotlib.use("Agg")
    args = _parser().parse_args(argv)
    progress = not args.no_progress
    try:
        if args.command == "analyze":
            files, verdict = run_analyze(args.file, args.out, progress=progress)
            print(verdict)
            print(f"wrote {files.markdown}, {files.html}, {', '.join(str(p) for p in files.json)}")
        elif args.command == "paper":
            summary = run_paper(args.out, progress=progress)
            print(
                f"wrote {summary['files']['markdown']} and {summary['files']['html']} "
                f"in {summary['elapsed_seconds']:.1f} s"
            )
        else:
            result = run_sweep_file(args.file, args.out, dask_address=args.dask, progress=progress)
            print(
                f"wrote {result.csv}, {result.json}, {result.png} "
                f"({len(result.sweep.points)} points, {result.sweep.n_failed} failed)"
            )
    except (ParameterError, OSError) as exc:
        print(f"nrobust: error: {exc}", file=sys.stderr)
        return 2
    except NrobustError as exc:  # a certified computation hit its work bound
        print(f"nrobust: computation failed: {exc}", file=sys.stderr)
        return 1
    return 0
