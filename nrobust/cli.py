"""The ``nrobust`` command line.

``nrobust analyze SYSTEM.toml -o OUT/``
    Certify one plant and controller (schema in ``docs/getting_started.md``) and write
    ``report.md``, ``report.html``, ``certificate.json`` and the figures.
``nrobust paper -o OUT/``
    The reference paper's example end to end: classification, figures 1 and 3 by
    simulation of the PDE, delay margins of U_BS and U_BS2(K = 0.1), the ``(K, delta)``
    stability chart with the sufficient bound, the decay/margin trade-off and the report.
``nrobust design SYSTEM.toml -o OUT/ [--family F] [--objective OBJ] [--margin-at-least D] [--k-bounds L H]``
    ``[--delays D_MIN D_MAX] [--speed-tolerance EPS] [--rigorous]``:
    a controller for the file's plant (:func:`nrobust.reports.design.run_design`): ``F =
    reflection`` (the gain ``K`` of ``U_BS2(K)``, solved exactly; ``output_feedback``: on the state
    predicted from ``v(t, 0)``, ``collocated_output_feedback``: on the collocated observer's estimate
    from ``u(t, 1)``), ``filtered`` (``K`` and the filter's ``a``, ``b``, a certified local
    optimum), ``state_feedback`` (``k`` and the integral gains on a basis, a certified local
    optimum) or, for an ``NPlusMSystem`` file, ``nplusm`` (the gain matrix ``K``), with the largest
    delay margin
    (``OBJ = margin``) or the largest decay rate (``decay_rate``) with a margin of at least
    ``D``, or stable for every delay in ``[D_MIN, D_MAX]`` (and under a relative error ``EPS``
    of both speeds); each option defaults to the file's ``[design]`` section. Writes ``design.json``,
    ``design.md`` and ``design.png`` (the delay margin against the gain, the design marked; for
    ``U_BS2(K)`` also its decay rate against ``K`` and the trade-off of rate against margin).
``nrobust sweep SWEEP.toml -o OUT/ [--dask ADDRESS] [--restart]``
    A parameter sweep or Monte Carlo study (:func:`nrobust.sweeps.run_sweep_file`); run
    again on the same ``OUT/``, it resumes where it stopped (``--restart``: from scratch).

Each command validates its whole input and checks that ``OUT/`` can be created and
written before it computes anything. Input errors (a bad key, an unwritable ``OUT/``, a
file that is not UTF-8 TOML) end the program with exit code 2 and a one-line message
naming the bad key (no traceback); a certified computation that reaches its work bound
ends it with exit code 1 and the message of the
:class:`~nrobust.errors.CertificationError`; Ctrl-C ends it with exit code 130 and a
one-line summary (for a sweep: the points done and where they are kept).
"""

from __future__ import annotations

import argparse
import gc
import os
import sys
from collections.abc import Sequence
from typing import NoReturn

from ._version import __version__
from .config import DESIGN_FAMILIES, PiecewiseLinear, load_system_file
from .errors import NrobustError, ParameterError
from .plots.base import skip_artist_property_docs
from .reports.analyze import run_analyze
from .reports.design import design_summary, run_design
from .reports.paper import PAPER_SYSTEM, run_paper
from .sweeps.engine import SweepInterrupted
from .sweeps.sweepfile import run_sweep_file

__all__ = ["PAPER_SYSTEM", "PiecewiseLinear", "load_system_file", "main", "run", "run_analyze", "run_paper"]


# ---------------------------------------------------------------------- main
def _progress_options(parser: argparse.ArgumentParser) -> None:
    """``--progress`` / ``--no-progress``; neither: bars only when stderr is a terminal or Jupyter."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument(
        "--progress",
        dest="progress",
        action="store_const",
        const=True,
        default=None,
        help="progress bars on stderr even when it is not a terminal (default: only in a terminal or Jupyter)",
    )
    group.add_argument("--no-progress", dest="progress", action="store_const", const=False, help="no progress bar")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="nrobust", description="Delay-robustness analysis of boundary-controlled 2x2 hyperbolic PDEs."
    )
    p.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    a = sub.add_parser("analyze", help="certify the loop described by a SYSTEM.toml file and write a report")
    a.add_argument("file", help="SYSTEM.toml (schema: docs/getting_started.md)")
    a.add_argument("-o", "--out", required=True, help="output directory")
    a.add_argument(
        "--accuracy",
        type=float,
        default=None,
        help="target accuracy of the delay margin (overrides [analysis] accuracy; the kernel grid is refined to it)",
    )
    a.add_argument(
        "--rigorous",
        action="store_true",
        default=None,
        help="prove the certificate's claims in ball arithmetic (overrides [analysis] rigorous)",
    )
    _progress_options(a)
    pp = sub.add_parser("paper", help="the reference paper's example end to end")
    pp.add_argument("-o", "--out", required=True, help="output directory")
    pp.add_argument("--accuracy", type=float, default=None, help="target accuracy of the certificates' delay margins")
    _progress_options(pp)
    d = sub.add_parser("design", help="a controller for the plant of a SYSTEM.toml file, designed and certified")
    d.add_argument("file", help="SYSTEM.toml (schema: docs/getting_started.md); its [system] is the plant")
    d.add_argument("-o", "--out", required=True, help="output directory")
    d.add_argument(
        "--family",
        choices=DESIGN_FAMILIES,
        default=None,
        help="U_BS2(K), U_BS2(K) on the state predicted from v(t, 0), U_BS2(K) on the collocated observer's "
        "estimate from u(t, 1), the filtered U_BS2(K), the state feedback k u(t, L) + int g_u u + g_v v, "
        "or the gain matrix K of an NPlusMSystem",
    )
    d.add_argument("--objective", choices=("margin", "decay_rate"), default=None, help="what to maximise")
    d.add_argument("--margin-at-least", type=float, default=None, help="the delay margin required (decay_rate)")
    d.add_argument(
        "--k-bounds",
        type=float,
        nargs=2,
        default=None,
        metavar=("LO", "HI"),
        help="the gains searched (K; k of state_feedback; every entry of K for nplusm)",
    )
    d.add_argument(
        "--delays",
        type=float,
        nargs=2,
        default=None,
        metavar=("D_MIN", "D_MAX"),
        help="the window of delays on which the design must be stable",
    )
    d.add_argument(
        "--speed-tolerance", type=float, default=None, metavar="EPS", help="relative error of lam and mu, in (0, 1)"
    )
    d.add_argument(
        "--rigorous", action="store_true", default=None, help="prove the designed loop's margin in ball arithmetic"
    )
    d.set_defaults(progress=None)  # no progress bar: one design takes about a second
    s = sub.add_parser("sweep", help="run a SWEEP.toml parameter sweep or Monte Carlo study")
    s.add_argument("file", help="SWEEP.toml (schema: docs/sweeps.md)")
    s.add_argument("-o", "--out", required=True, help="output directory")
    s.add_argument("--dask", metavar="ADDRESS", default=None, help="Dask scheduler address, e.g. tcp://host:8786")
    s.add_argument(
        "--restart",
        action="store_true",
        help="discard the results of an earlier run in OUT and run every point (default: resume)",
    )
    _progress_options(s)
    return p


def _draw_off_screen() -> None:
    """Select matplotlib's Agg backend without importing matplotlib before a figure is drawn.

    Importing matplotlib takes a good part of a second; an input error must be reported
    before that.
    """
    if "matplotlib" in sys.modules:
        sys.modules["matplotlib"].use("Agg")
    else:
        os.environ["MPLBACKEND"] = "Agg"


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``nrobust`` command; returns the exit code."""
    _draw_off_screen()
    args = _parser().parse_args(argv)
    progress = args.progress
    try:
        if args.command == "analyze":
            files, verdict = run_analyze(
                args.file, args.out, progress=progress, accuracy=args.accuracy, rigorous=args.rigorous
            )
            print(verdict)
            print(f"wrote {files.markdown}, {files.html}, {', '.join(str(p) for p in files.json)}")
        elif args.command == "design":
            written, designed = run_design(
                args.file,
                args.out,
                args.objective,
                args.margin_at_least,
                None if args.k_bounds is None else tuple(args.k_bounds),
                args.rigorous,
                args.family,
                None if args.delays is None else tuple(args.delays),
                args.speed_tolerance,
            )
            print(design_summary(designed))
            print(f"wrote {', '.join(str(p) for p in written)}")
        elif args.command == "paper":
            summary = run_paper(args.out, progress=progress, accuracy=args.accuracy)
            print(
                f"wrote {summary['files']['markdown']} and {summary['files']['html']} "
                f"in {summary['elapsed_seconds']:.1f} s"
            )
        else:
            result = run_sweep_file(
                args.file, args.out, dask_address=args.dask, progress=progress, restart=args.restart
            )
            if result.sweep.resumed:
                print(result.sweep.resumed)
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
    except SweepInterrupted as exc:  # Ctrl-C: the finished points are in the journal
        print(f"nrobust: {exc}", file=sys.stderr)
        return 130
    except KeyboardInterrupt:
        print(f"nrobust: interrupted: nothing written, {args.out} holds what it held before", file=sys.stderr)
        return 130
    return 0


def run() -> NoReturn:
    """The ``nrobust`` command (and ``python -m nrobust``): :func:`main`, then exit with its code.

    Once :func:`main` has returned, every output is written and committed and the worker
    processes are gone; what is left is the interpreter's teardown, whose garbage collections
    walk every object of numpy, scipy, matplotlib and FLINT: 0.25-0.45 s of wall time after
    ``nrobust paper``, about a tenth of its run. Those objects are frozen first
    (:func:`gc.freeze`: the collections skip them), so the process exits in about 0.05 s, its
    exit handlers run and its streams flushed as usual.
    """
    skip_artist_property_docs()  # the property lists of help(): a quarter of matplotlib's import
    code = main()
    gc.freeze()
    sys.exit(code)
