"""The command line's pieces for systems of several degrees of freedom.

``hosid simulate --system FILE.toml`` (or ``--measured acceleration`` for the single
oscillator as the one-element chain) writes a multi-channel record and its true values;
``hosid fit REC --model FILE.toml`` fits a system (:mod:`hosid.commands` passes the file
to :func:`hosid.fit`); ``hosid diagnose REC --model FILE.toml`` names the missing
(effect, element) pairs (:func:`locate_system`, :mod:`hosid.check.locate`).
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np

from hosid.errors import HosidInputError

__all__ = ["add_system_options", "locate_system", "simulate_system", "system_file"]


def system_file(model: str):
    """``--model``: the :class:`~hosid.model.system.System` of a ``.toml`` file, else the
    model's spec as given.
    """
    if not str(model).lower().endswith(".toml"):
        return model
    from hosid.model.system import System

    return System.from_toml(model)


def add_system_options(sim: argparse.ArgumentParser) -> None:
    """``hosid simulate``'s ``--system`` and ``--measured``."""
    sim.add_argument(
        "--system",
        metavar="TOML",
        help="simulate the system of this file with its [values] (one channel a degree of "
        "freedom) instead of the single oscillator of the options above",
    )
    sim.add_argument(
        "--measured",
        choices=("displacement", "acceleration"),
        help="what every channel holds (the interval-averaged acceleration); default the "
        "system file's, else displacement",
    )


def simulate_system(args, out: Path) -> int:
    """``hosid simulate --system FILE`` (or ``--measured acceleration``): a system's record
    (:func:`hosid.model.chain.simulate_chain`, the values of its file; the single
    oscillator's options as the one-element chain) and its true values.
    """
    from hosid.model.chain import simulate_chain
    from hosid.model.system import System
    from hosid.output.files import write_atomic
    from hosid.record import write_record

    if args.system:
        system = System.from_toml(args.system)
    else:
        terms = ["linear_damping", "quadratic_damping", "linear_stiffness", "cubic_stiffness"]
        values = {k: getattr(args, k) for k in ("a1", "n1", "a2", "n2", "S0")}
        extra = {"b2": "quadratic_stiffness", "mu": "coulomb_friction", "m": "excitation_mean"}
        for k, term in extra.items():
            if getattr(args, k) is not None:
                terms.append(term)
                values[k] = getattr(args, k)
        others = [k for k in ("wc", "wb", "wf", "rate", "noise_sd", "change_at")
                  if getattr(args, k, None) is not None]  # fmt: skip
        if others:
            raise HosidInputError(
                f"--measured acceleration simulates a white force without noise or changes; "
                f"--{others[0].replace('_', '-')} does not apply"
            )
        system = System.single(terms, values)
    record = simulate_chain(system, duration=args.duration, dt=args.dt,
                            rng=np.random.default_rng(args.seed), measured=args.measured,
                            name=out.stem)  # fmt: skip
    tmp = out.with_name(f".{out.stem}.{os.getpid()}.tmp{out.suffix}")
    try:
        write_record(record, tmp)
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    sidecar = out.with_suffix(".truths.json")
    write_atomic(sidecar, json.dumps(dict(system.values), indent=2) + "\n")
    kinds = ", ".join(f"{c} {k}" for c, k in zip(record.channels, record.measured, strict=True))
    print(f"wrote {out}: {record.n} samples, dt={record.dt:g} s, channels {kinds} "
          f"(true parameters: {sidecar})")  # fmt: skip
    return 0


def locate_system(args, record, system, checks, candidates) -> int:
    """``hosid diagnose REC --model SYSTEM.toml``: the missing (effect, element) pairs."""
    from hosid.check.locate import locate
    from hosid.output.files import output_dir
    from hosid.output.locate_report import write_locate
    from hosid.progress import Stages

    stages = Stages("hosid diagnose", enabled=not args.no_progress)
    try:
        with output_dir(args.out, command=args.command_line) as stage:
            loc = locate(record, system, candidates=candidates, alpha=args.alpha,
                         max_effects=args.max_effects, unit=args.unit, force=args.force,
                         checks=checks, progress=stages.stage)  # fmt: skip
            names = [p.name for p in write_locate(loc, stage)]
    finally:
        stages.close()
    for r in loc.rounds:
        print("  " + ", ".join(f"{w.label} z {w.z:+.2f}" for w in r.weighed))
    print(f"named: {', then '.join(loc.named_effects) or 'none'} - {loc.decision}")
    print("wrote " + ", ".join(str(Path(args.out) / n) for n in names))
    return 0
