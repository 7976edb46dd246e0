"""``hosid simulate``'s options: the paper's parameters, the effects, a change of the
parameters during the record, and the record's length, step and seed (the command is
:func:`hosid.commands.cmd_simulate`).
"""

from __future__ import annotations

import argparse

from hosid import commands
from hosid.arguments import integer, nonnegative, number, positive
from hosid.system_commands import add_system_options

__all__ = ["add_simulate_parser"]


def add_simulate_parser(sim: argparse.ArgumentParser) -> None:
    """Add ``hosid simulate``'s options to its parser ``sim``."""
    for name, kind, default in (
        ("a1", nonnegative, 0.5),
        ("n1", nonnegative, 0.5),
        ("a2", number, 25.0),
        ("n2", nonnegative, 5.0),
        ("S0", positive, 100.0),
    ):
        sim.add_argument(f"--{name}", type=kind, default=default, help=f"default {default:g}")
    for name, kind, text in (
        ("b2", number, "quadratic stiffness b2 x^2"),
        ("mu", nonnegative, "Coulomb friction mu sign(x')"),
        ("m", number, "mean force m"),
        ("wc", positive, "corner (rad/s) of a low-pass on the force"),
        ("wb", positive, "edge (rad/s) above which the force has no power"),
        ("rolloff", nonnegative, "roll-off beta of the band-limited force within its band"),
        ("wf", positive, "frequency (rad/s) of a second-order shaping filter on the force"),
        ("zf", positive, "damping ratio of that filter (with --wf)"),
        ("noise_sd", positive, "sd of white measurement noise on x"),
    ):
        sim.add_argument(
            f"--{name.replace('_', '-')}", dest=name, type=kind, help=f"{text}; default none"
        )
    sim.add_argument(
        "--impulse-rate",
        dest="rate",
        type=positive,
        help="Poisson impulses a second with Gaussian areas in place of the white force "
        "(the same level S0, not Gaussian); default none",
    )
    sim.add_argument(
        "--change-at",
        type=positive,
        metavar="T",
        help="seconds from the first sample at which the parameters change to the --*-after "
        "values; default no change",
    )
    sim.add_argument(
        "--ramp",
        type=nonnegative,
        metavar="R",
        help="seconds over which they move linearly to those values; default 0 (a step)",
    )
    for name, kind in (
        ("a1", nonnegative),
        ("n1", nonnegative),
        ("a2", number),
        ("n2", nonnegative),
        ("S0", positive),
    ):
        sim.add_argument(
            f"--{name}-after",
            dest=f"{name}_after",
            type=kind,
            metavar="V",
            help=f"{name} after the change (with --change-at); default unchanged",
        )
    add_system_options(sim)
    sim.add_argument("--duration", type=positive, default=2000.0, help="seconds, default 2000")
    sim.add_argument("--dt", type=positive, default=0.02, help="seconds, default 0.02")
    sim.add_argument("--seed", type=integer(0), default=0, help="default 0")
    sim.add_argument("--out", required=True, help="output file, .csv or .npz")
    sim.set_defaults(func=commands.cmd_simulate)
