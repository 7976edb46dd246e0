"""``hosid batch``: its argument parser and its command.

::

    hosid batch fit|estimate|diagnose RECORD... --out DIR [options]
    hosid batch simulate-study DESIGN --out DIR [--analysis fit|estimate|diagnose] [options]

RECORD is a file, a glob pattern or a manifest (``.txt``, one path a line).  The
analysis options are those of the single commands; the batch options choose the
cluster (``--workers N`` local processes, default one per core, or ``--scheduler
ADDRESS``), the root ``--seed`` and what is kept (``--save-posterior``,
``--write-records``).  Rerunning the same command skips the finished tasks.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .. import arguments
from ..check.diagnose import DEFAULT_REPLICATES
from ..errors import HosidInputError
from .tasks import ANALYSES

__all__ = ["add_batch_parser", "cluster_options", "cmd_batch"]

_ALL = ANALYSES
_SPECTRAL = ("fit", "estimate")


def _flags() -> tuple[tuple[str, str, tuple[str, ...], dict], ...]:
    """Analysis options: flag, option name, the analyses it applies to, argparse kwargs."""
    n = arguments.integer
    return (
        (
            "--model",
            "model",
            _ALL,
            {
                "metavar": "MODEL",
                "help": "linear, paper (default) or term names; diagnose: the base model",
            },
        ),
        (
            "--excitation-shape",
            "excitation_shape",
            _ALL,
            {"metavar": "CSV", "help": "the force spectrum's known shape (omega, level)"},
        ),
        (
            "--measured",
            "measured",
            _SPECTRAL,
            {
                "choices": ("displacement", "acceleration"),
                "help": "what every channel holds; default what the file or system says",
            },
        ),
        (
            "--cost",
            "cost",
            _SPECTRAL,
            {
                "choices": ("J2", "J4A", "J4B"),
                "help": "the paper's components instead of the default",
            },
        ),
        (
            "--unconstrained",
            "constrained",
            ("fit",),
            {"action": "store_false", "help": "drop eq 65's a1eq > 0"},
        ),
        ("--walkers", "n_walkers", ("fit",), {"type": n(2), "metavar": "N", "help": "default 32"}),
        (
            "--steps",
            "n_steps",
            ("fit",),
            {"type": n(1), "metavar": "N", "help": "per walker; default: until converged"},
        ),
        (
            "--block-seconds",
            "block_seconds",
            _SPECTRAL,
            {"type": arguments.positive, "metavar": "S"},
        ),
        ("--omega-max", "omega_max", _SPECTRAL, {"type": arguments.positive, "metavar": "W"}),
        ("--form", "form", _SPECTRAL, {"choices": ("scaled", "printed")}),
        ("--domain", "domain", _SPECTRAL, {"choices": ("principal", "reduced", "full")}),
        (
            "--candidates",
            "candidates",
            ("diagnose",),
            {"type": _names, "metavar": "LIST", "help": "effects to try; default all"},
        ),
        (
            "--replicates",
            "replicates",
            ("diagnose",),
            {"type": n(4), "metavar": "N", "help": f"default {DEFAULT_REPLICATES}"},
        ),
        (
            "--threshold",
            "threshold",
            ("diagnose",),
            {
                "type": arguments.positive,
                "metavar": "Z",
                "help": "base gap significance, default 3",
            },
        ),
        (
            "--alpha",
            "alpha",
            ("diagnose",),
            {
                "type": arguments.positive,
                "metavar": "P",
                "help": "false alarms a round, default 0.05",
            },
        ),
        (
            "--max-effects",
            "max_effects",
            ("diagnose",),
            {"type": n(0), "metavar": "N", "help": "default: as many as supported"},
        ),
        (
            "--posterior",
            "posterior",
            ("diagnose",),
            {"choices": ("emcee", "screen"), "help": "how models are fitted; default emcee"},
        ),
        (
            "--no-candidate-gaps",
            "candidate_gaps",
            ("diagnose",),
            {"action": "store_false", "help": "no predictive gap for every candidate"},
        ),
    )


def _names(text: str) -> list[str]:
    return [c.strip() for c in text.split(",") if c.strip()]


def cluster_options(p: argparse.ArgumentParser) -> None:
    """``--workers`` or ``--scheduler``, ``--seed`` and ``--no-progress``: the options of
    every command that runs on dask (``hosid batch``, ``hosid monitor``).
    """
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--workers", type=arguments.integer(1), help="local worker processes; default one per core"
    )
    where.add_argument("--scheduler", metavar="ADDRESS", help="an existing dask scheduler")
    p.add_argument("--seed", type=arguments.integer(0), default=0, help="root seed, default 0")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def _batch_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, metavar="DIR", help="the batch's folder")
    cluster_options(p)
    p.add_argument("--save-posterior", action="store_true", help="keep each posterior.nc")
    p.add_argument("--retry-errors", action="store_true", help="rerun tasks that failed")


def add_batch_parser(sub) -> None:
    """Add ``hosid batch`` and its four sub-commands to the sub-parsers ``sub``."""
    batch = sub.add_parser(
        "batch",
        allow_abbrev=False,
        help="many records, or a simulation design, on dask (resumable)",
        description=(
            "Run fit, estimate or diagnose over many records, or simulate and analyse a "
            "design table, on a local dask cluster or an existing one; every finished task "
            "is kept in --out and a rerun of the same command skips it."
        ),
    )
    commands = batch.add_subparsers(dest="batch_command", metavar="ANALYSIS")
    flags = _flags()
    for name in (*ANALYSES, "simulate-study"):
        study = name == "simulate-study"
        p = commands.add_parser(
            name,
            allow_abbrev=False,
            help="simulate and analyse a design table" if study else f"{name} every record",
        )
        if study:
            p.add_argument("design", metavar="DESIGN", help="design table, .csv or .json")
            p.add_argument("--analysis", choices=ANALYSES, default="fit", help="default fit")
            p.add_argument("--write-records", action="store_true", help="keep the records")
        else:
            p.add_argument("records", nargs="+", metavar="RECORD", help="files, globs, lists")
        for flag, dest, where, kwargs in flags:
            if study or name in where:
                p.add_argument(flag, dest=dest, default=argparse.SUPPRESS, **kwargs)
        _batch_options(p)
    batch.set_defaults(func=cmd_batch)


def _options(args: argparse.Namespace, analysis: str) -> dict:
    from .tasks import options_for

    given = {}
    for flag, dest, where, _ in _flags():
        if dest in vars(args):
            if analysis not in where:
                raise HosidInputError(f"{flag} does not apply to --analysis {analysis}")
            given[dest] = getattr(args, dest)
    if given.get("excitation_shape") is not None:  # read once here: a bad table stops at once
        from ..model.measured import read_shape

        path = Path(given["excitation_shape"]).resolve()
        read_shape(path)
        given["excitation_shape"] = str(path)
    return options_for(analysis, given)


def cmd_batch(args: argparse.Namespace) -> int:
    """``hosid batch``: run the tasks; print what happened; write ``DIR/results.csv``."""
    from .design import design_tasks, read_design
    from .runner import run_batch
    from .tasks import expand_inputs, record_tasks

    command = getattr(args, "batch_command", None)
    if command is None:
        raise HosidInputError("hosid batch needs fit, estimate, diagnose or simulate-study")
    study = command == "simulate-study"
    analysis = args.analysis if study else command
    options = _options(args, analysis)
    if study:
        rows = read_design(args.design)
        tasks = design_tasks(
            rows,
            analysis=analysis,
            options=options,
            seed=args.seed,
            folder=Path(args.design).parent,
        )
    else:
        paths = expand_inputs(args.records)
        tasks = record_tasks(paths, analysis=analysis, options=options, seed=args.seed)
    res = run_batch(  # Ctrl-C: hosid.cli names the command that finishes the others
        tasks,
        args.out,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=not args.no_progress,
        save_posterior=args.save_posterior,
        write_records=getattr(args, "write_records", False),
        retry_errors=args.retry_errors,
        label=f"hosid batch {command}",
    )
    c = res.counts
    print(
        f"{len(res.rows)} records: {c['ok']} ok, {c['rejected']} rejected, {c['error']} errors "
        f"({res.skipped} done before, {res.ran} run now, {res.seconds:.1f} s)"
    )
    print("wrote " + ", ".join(str(p) for p in res.tables))
    if c["error"]:
        print(
            f"hosid: warning: {c['error']} task(s) failed; their message is in {res.tables[0]}",
            file=sys.stderr,
        )
    return 0
