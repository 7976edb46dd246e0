"""``hosid monitor``: its argument parser and its command.

::

    hosid monitor RECORD --out DIR [--window S] [--step S] [--alpha P] [--follow] [options]

RECORD is a ``.csv`` or ``.npz`` record, or a folder of consecutive ones.  The analysis
options are those of ``hosid batch fit`` (``--analysis estimate`` for the faster
Laplace posterior); the cluster options are the batch's.  Rerunning the same command
resumes: only the windows not finished are fitted.
"""

from __future__ import annotations

import argparse
import signal
from pathlib import Path

from .. import arguments
from ..errors import HosidInputError
from .changes import ALPHA

__all__ = ["add_monitor_parser", "cmd_monitor"]

_SKIP = ("--block-seconds", "--excitation-shape")


def add_monitor_parser(sub) -> None:
    """Add ``hosid monitor`` to the sub-parsers ``sub``."""
    from ..batch.cli import _flags, cluster_options

    p = sub.add_parser(
        "monitor",
        allow_abbrev=False,
        help="track the parameters over a long or growing record; name changes",
        description=(
            "Fit a long record window by window on dask (one calibrated posterior per "
            "window), write every parameter's track and name the changes of the structure "
            "or the excitation with their time and size.  A rerun resumes."
        ),
    )
    p.add_argument("record", metavar="RECORD", help=".csv or .npz record, or a folder of them")
    p.add_argument("--out", required=True, metavar="DIR", help="the monitor's folder")
    p.add_argument("--window", type=arguments.positive, metavar="S", help="window length (s)")
    p.add_argument("--step", type=arguments.positive, metavar="S", help="default: the window")
    p.add_argument(
        "--block-seconds", type=arguments.positive, metavar="S", help="default: from the record"
    )
    p.add_argument(
        "--analysis", choices=("fit", "estimate"), default="fit", help="per window; default fit"
    )
    for flag, dest, where, kwargs in _flags():
        if "fit" in where and flag not in _SKIP:
            if flag == "--model":  # the batch's help names diagnose's base model too
                kwargs = {**kwargs, "help": "linear, paper (default) or term names"}
            p.add_argument(flag, dest=dest, default=argparse.SUPPRESS, **kwargs)
    p.add_argument(
        "--alpha",
        type=arguments.probability,
        default=ALPHA,
        help=f"chance of naming a change in a stationary record; default {ALPHA:g}",
    )
    p.add_argument(
        "--level", type=arguments.probability, default=0.95, help="of the intervals; default 0.95"
    )
    ref = p.add_mutually_exclusive_group()
    ref.add_argument("--baseline", metavar="SUMMARY.json", help="a reference fit's summary")
    ref.add_argument(
        "--baseline-windows",
        type=arguments.integer(1),
        default=0,
        metavar="K",
        help="the first K windows are the reference",
    )
    p.add_argument("--follow", action="store_true", help="keep reading a growing .csv file")
    p.add_argument("--poll", type=arguments.positive, default=2.0, metavar="S", help="default 2 s")
    cluster_options(p)
    p.set_defaults(func=cmd_monitor)


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def cmd_monitor(args: argparse.Namespace) -> int:
    """``hosid monitor``: run it, print the changes, name the files."""
    from .run import monitor

    options = {}
    for key in ("model", "cost", "constrained", "n_walkers", "n_steps", "omega_max", "form"):
        if key in vars(args):
            options[key] = getattr(args, key)
    if args.analysis == "estimate":
        for key in ("constrained", "n_walkers", "n_steps"):
            if key in options:
                raise HosidInputError(f"--{key.replace('_', '-')} applies to --analysis fit only")
    if "domain" in vars(args):
        options["domain"] = args.domain
    if Path(args.out).resolve() == Path(args.record).resolve():
        raise HosidInputError("--out must not be the record itself")
    if args.follow:  # a service manager's stop is a Ctrl-C: finish the tables and exit 0
        signal.signal(signal.SIGTERM, _interrupt)
    res = monitor(
        args.record,
        args.out,
        window=args.window,
        step=args.step,
        block_seconds=args.block_seconds,
        analysis=args.analysis,
        options=options,
        alpha=args.alpha,
        level=args.level,
        baseline=args.baseline,
        baseline_windows=args.baseline_windows,
        seed=args.seed,
        workers=args.workers,
        scheduler=args.scheduler,
        follow=args.follow,
        poll=args.poll,
        progress=not args.no_progress,
    )
    failed = len(res.tracks.failed)
    print(
        f"{res.tracks.start.size} windows ({failed} without a posterior), "
        f"{len(res.changes)} change(s) named, {res.seconds:.1f} s"
    )
    for c in res.changes:
        kind = res.tracks.kinds.get(c.parameter, "")
        kind += ", or the others: the records do not tell" if c.role == "alternative" else ""
        print(
            f"  {c.parameter} ({kind}) at {c.time:.6g} s [{c.time_lo:.6g}, {c.time_hi:.6g}]: "
            f"{c.size:+.4g} [{c.size_lo:+.4g}, {c.size_hi:+.4g}]"
        )
    print("wrote " + ", ".join(str(p) for p in res.files))
    return 0
