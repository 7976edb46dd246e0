"""Command line: argument parsing and error mapping only.

``hosid simulate | estimate | fit | diagnose | report | demo | batch | monitor``.  Every
failure ends with one line on stderr and no traceback:

- bad input of any kind: ``hosid: error: <message>``, exit code 2;
- a record that hosid's model class cannot describe (:mod:`hosid.screen`):
  ``hosid: rejected: <why>``, exit code 3 (``--force`` fits it anyway);
- Ctrl-C: ``hosid: interrupted; ...`` naming the command that resumes, exit code 130;
- a process drawing the figures failed: ``hosid: error: ...``, exit code 1.
"""

from __future__ import annotations

import argparse
import gc
import shlex
import sys
from collections.abc import Callable, Sequence
from typing import NoReturn

from hosid import __version__, commands
from hosid.arguments import integer, positive, probability
from hosid.errors import (
    EXIT_INPUT,
    EXIT_INTERRUPTED,
    EXIT_REJECTED,
    HosidInputError,
    RecordRejected,
)
from hosid.output.render import FigureError

__all__ = ["COMMANDS", "build_parser", "main"]

EXIT_USAGE = EXIT_INPUT
#: A process drawing the report's figures failed (:mod:`hosid.output.render`).
EXIT_FIGURES = 1
#: The commands and their help in ``hosid --help``, in order (batch's and monitor's own
#: parsers repeat theirs).
COMMANDS = {
    "simulate": "simulate a response record",
    "estimate": "estimate the parameters (mode and sd, no sampling)",
    "fit": "sample the posterior (emcee)",
    "diagnose": "find the gap between model and record; name the missing effect",
    "report": "rewrite a fit's report from DIR/posterior.nc",
    "demo": "simulate the paper oscillator and fit it",
    "batch": "many records, or a simulation design, on dask (resumable)",
    "monitor": "track the parameters over a long or growing record; name changes",
}


class _UsageError(Exception):
    """Raised by the parser instead of printing usage and exiting."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        raise _UsageError(message)


# --- parser ---------------------------------------------------------------------------
def _shape_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--excitation-shape",
        metavar="CSV",
        default=None,
        help="the force spectrum's known shape (columns omega in rad/s, level): "
        "S(omega) = S0 level(omega), S0 estimated",
    )


def _analysis_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--model",
        default="paper",
        metavar="MODEL",
        help="linear, paper, comma-separated term names, or a system file (.toml: several "
        "degrees of freedom, the record's channels); default paper",
    )
    _shape_option(p)
    p.add_argument(
        "--block-seconds",
        type=positive,
        default=None,
        help="block length in seconds; default about 16 periods of the resonance",
    )
    p.add_argument(
        "--omega-max",
        type=positive,
        default=None,
        help="upper edge of the J2 band, rad/s; default 6 x the resonance",
    )
    p.add_argument(
        "--form",
        choices=("scaled", "printed"),
        default="scaled",
        help="weighting of the spectral components; default scaled",
    )
    p.add_argument(
        "--domain",
        choices=("principal", "reduced", "full"),
        default="principal",
        help="trispectral domain of J4: eq (39), eq (64) or all; default principal",
    )
    _record_options(p)


def _record_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--unit", default="m", metavar="UNIT", help="unit of the record's x; default m")
    p.add_argument(
        "--measured",
        choices=("displacement", "acceleration"),
        default=None,
        help="what every channel of the record holds; default what its file (an .npz "
        "written by hosid) or the system file says, else displacement",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="analyse a record that fails the record checks anyway (exit 3 otherwise)",
    )


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``hosid`` argument parser (its ``error`` raises instead of exiting).

    Parameters
    ----------
    command : str, optional
        Build this command's options alone: the others are listed with their help and
        take none, so that parsing imports no more than the command needs (what
        :func:`main` does).  Default: every command's options.
    """
    parser = _Parser(
        prog="hosid",
        allow_abbrev=False,
        description=(
            "Output-only identification of x'' + a1 x' + n1 x'|x'| + a2 x + n2 x^3 = f(t)."
        ),
    )
    parser.add_argument("--version", action="version", version=f"hosid {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, text in COMMANDS.items():
        if command in (None, name):
            _ADD[name](sub)
        else:
            sub.add_parser(name, help=text, allow_abbrev=False)
    return parser


def _add(sub, name: str) -> argparse.ArgumentParser:
    return sub.add_parser(name, help=COMMANDS[name], allow_abbrev=False)


def _add_simulate(sub) -> None:
    from hosid.cli_simulate import add_simulate_parser

    add_simulate_parser(sub.add_parser("simulate", help=COMMANDS["simulate"], allow_abbrev=False))


def _add_estimate(sub) -> None:
    est = _add(sub, "estimate")
    est.add_argument("record", help="record file, .csv (columns t,x) or .npz")
    est.add_argument(
        "--cost",
        choices=("J2", "J4A", "J4B"),
        default=None,
        help="the paper's components instead of the default ones",
    )
    methods = tuple(commands.METHODS)
    est.add_argument("--method", choices=methods, default=None, help=argparse.SUPPRESS)
    _analysis_options(est)
    est.add_argument("--json", metavar="FILE", help="also write the result as JSON")
    est.set_defaults(func=commands.cmd_estimate)


def _add_fit(sub) -> None:
    fit = _add(sub, "fit")
    fit.add_argument("record", help="record file, .csv (columns t,x) or .npz")
    fit.add_argument(
        "--cost",
        choices=("J2", "J4A", "J4B"),
        default=None,
        help="the paper's posterior instead of the default, most efficient one",
    )
    _analysis_options(fit)
    fit.add_argument(
        "--unconstrained",
        action="store_true",
        help="drop the eq-65 constraint a1eq > 0 (shows the twin modes)",
    )
    fit.add_argument("--walkers", type=integer(2), default=None,
                     help="default 32, or 2 x parameters + 2 when more")  # fmt: skip
    fit.add_argument(
        "--steps",
        type=integer(1),
        default=None,
        help="steps per walker; default: until the diagnostics pass",
    )
    fit.add_argument("--seed", type=integer(0), default=0, help="default 0")
    fit.add_argument("--backend", metavar="FILE.h5", help="store (or resume) the chain")
    fit.add_argument("--no-progress", action="store_true", help="no progress bar")
    fit.add_argument(
        "--truths",
        metavar="FILE.json",
        help="true values (default REC.truths.json next to the record)",
    )
    fit.add_argument("--out", required=True, metavar="DIR", help="output directory")
    fit.set_defaults(func=commands.cmd_fit)


def _add_diagnose(sub) -> None:
    from hosid.check.diagnose import DEFAULT_REPLICATES

    dia = _add(sub, "diagnose")
    dia.add_argument("record", help="record file, .csv (columns t,x) or .npz")
    dia.add_argument(
        "--model",
        default="paper",
        metavar="BASE",
        help="base model: linear, paper, or term names; or a system file (.toml): then "
        "each candidate effect is tried in each element and the pair is named "
        "(hosid.check.locate; --alpha, --candidates and --max-effects apply); default paper",
    )
    _shape_option(dia)
    dia.add_argument(
        "--candidates",
        metavar="LIST",
        help="comma-separated effects to try; default all not in BASE",
    )
    dia.add_argument(
        "--replicates",
        type=integer(4),
        default=DEFAULT_REPLICATES,
        help=f"default {DEFAULT_REPLICATES}",
    )
    dia.add_argument(
        "--alpha",
        type=probability,
        default=0.05,
        help="false-alarm rate of each round (any candidate); default 0.05",
    )
    dia.add_argument(
        "--threshold",
        type=positive,
        default=3.0,
        help="robust z of the base gap for significance (reported); default 3",
    )
    dia.add_argument(
        "--max-effects",
        type=integer(0),
        default=None,
        help="name at most this many effects",
    )
    dia.add_argument(
        "--posterior",
        choices=("emcee", "screen"),
        default="emcee",
        help="how the base and named models are fitted for their gaps; default emcee",
    )
    dia.add_argument("--seed", type=integer(0), default=0, help="default 0")
    _record_options(dia)
    dia.add_argument("--no-progress", action="store_true", help="no progress bar")
    dia.add_argument("--out", required=True, metavar="DIR", help="output directory")
    dia.set_defaults(func=commands.cmd_diagnose)


def _add_report(sub) -> None:
    rep = _add(sub, "report")
    rep.add_argument("dir", metavar="DIR", help="directory of a fit (holding posterior.nc)")
    rep.set_defaults(func=commands.cmd_report)


def _add_demo(sub) -> None:
    demo = _add(sub, "demo")
    demo.add_argument("--out", default="demo-out", help="output directory, default demo-out")
    demo.add_argument("--seed", type=integer(0), default=2026, help="default 2026")
    demo.add_argument("--no-progress", action="store_true", help="no progress bar")
    demo.set_defaults(func=commands.cmd_demo)


def _add_batch(sub) -> None:
    from hosid.batch.cli import add_batch_parser

    add_batch_parser(sub)


def _add_monitor(sub) -> None:
    from hosid.monitor.cli import add_monitor_parser

    add_monitor_parser(sub)


_ADD: dict[str, Callable[[argparse._SubParsersAction], None]] = {
    "simulate": _add_simulate,
    "estimate": _add_estimate,
    "fit": _add_fit,
    "diagnose": _add_diagnose,
    "report": _add_report,
    "demo": _add_demo,
    "batch": _add_batch,
    "monitor": _add_monitor,
}


def _command(argv: Sequence[str]) -> str:
    """The command of ``argv``: its first word that is not an option (``hosid`` itself
    takes no option with a value), ``""`` when it has none or an unknown one.
    """
    first = next((a for a in argv if not a.startswith("-")), "")
    return first if first in COMMANDS else ""


def _resume_hint(args: argparse.Namespace) -> str:
    if args.command in ("fit", "demo"):
        return f"the chain so far is kept; resume with: {args.command_line}"
    if args.command in ("batch", "monitor"):
        return f"the finished tasks are kept; finish the others with: {args.command_line}"
    return f"nothing was written; rerun: {args.command_line}"


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code (0; 1 a figure process failed; 2 bad
    input; 3 rejected record; 130 interrupted).

    Without ``argv`` (the console script, ``python -m hosid``) it runs the process's own
    command line, which ends when it returns: the objects made so far are frozen
    (:func:`gc.freeze`), so that the interpreter's exit does not collect them once more
    (a third of a second after a fit).
    """
    code = _run(list(sys.argv[1:] if argv is None else argv))
    if argv is None:
        gc.freeze()
    return code


def _run(argv: list[str]) -> int:
    args = None
    try:
        parser = build_parser(_command(argv))
        args = parser.parse_args(argv)
        if args.command is None:
            parser.error(
                "a command is required: simulate, estimate, fit, diagnose, report, demo, "
                "batch or monitor"
            )
        args.command_line = shlex.join(["hosid", *argv])
        return args.func(args)
    except (_UsageError, HosidInputError) as exc:
        print(f"hosid: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return EXIT_USAGE
    except RecordRejected as exc:
        print(f"hosid: rejected: {' '.join(str(exc).split())}", file=sys.stderr)
        return EXIT_REJECTED
    except FigureError as exc:
        print(f"hosid: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return EXIT_FIGURES
    except KeyboardInterrupt:
        hint = _resume_hint(args) if args is not None and hasattr(args, "command_line") else ""
        print(f"hosid: interrupted; {hint}".rstrip("; "), file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
