"""The command line against the library call: ``hosid fit`` as a user runs it beside
``hosid.fit()`` on the same record in a warm process, as ratios measured in one run.

Simulates a 100 000-sample record of the paper oscillator (2000 s at dt = 0.02 s, with
its ``.truths.json``), warms this process up with one ``hosid.fit()`` call, then runs
``REPEAT`` rounds, each of them, interleaved:

- ``hosid --help`` and ``python -c "import hosid.cli"`` (subprocesses);
- ``hosid fit REC --out DIR --no-progress`` (a subprocess, the console script of this
  environment, into a fresh folder), end to end, as a user runs it: the figures are
  drawn in two processes forked beside the fit when the load average leaves a core free
  (:mod:`hosid.output.render`), after the fit otherwise; its ``summary.json`` gives the
  time of the fit inside it (``fit_seconds``) and the steps;
- the same command with ``HOSID_FIGURE_PROCESSES=1`` (always beside the fit) and ``=0``
  (always after it, in the command's own process), in turns;
- what the command does before it writes anything (:data:`FLOOR`: import, read and
  check the record, fit it with the chain in a file), in a subprocess: the least the
  command can take whatever its output costs;
- ``hosid.fit(hosid.read_record(REC), seed=0, truths=...)`` in this (warm) process: the
  same seed and settings as the command's defaults, hence the same chain.

and prints the medians and the ratios (each command's end-to-end time over the warm
``fit()`` call, and over the fit inside it), of the wall times and of the CPU times
(the command's user + system time, with its figure processes, against this process's
for the ``fit()`` call: on a machine that other jobs share, CPU time tracks the work
better than wall time, but the figure processes trade CPU time for wall time); the
load average is read before and after the rounds.  ``--write`` adds the table to
``benchmarks/results.md`` (replacing an earlier one of this script).

    python benchmarks/cli_overhead.py                  # 5 rounds
    python benchmarks/cli_overhead.py --repeat 3 --write

On a machine other sessions keep busy, the figure processes have no free core to run on;
as root, ``echo -19 > /proc/self/autogroup`` before the run measures as on an idle
machine (the table says so).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import hosid
from hosid.output import render

HERE = Path(__file__).resolve().parent
HOSID = Path(sys.executable).with_name("hosid")
HEADING = "## `hosid fit` against `hosid.fit()` (`benchmarks/cli_overhead.py`)"


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _run(args: list[str], **env: str) -> tuple[float, float]:
    """Wall and CPU time (s) of one subprocess; fails loudly when it fails."""
    env = {**os.environ, "PYTHONWARNINGS": "ignore", **env}
    c0, t0 = _children_cpu(), time.perf_counter()
    done = subprocess.run(args, capture_output=True, text=True, env=env)
    sec, cpu = time.perf_counter() - t0, _children_cpu() - c0
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(args)} failed ({done.returncode}): {done.stderr}")
    return sec, cpu


def _fit(path: Path, truths: dict) -> tuple[float, float, int]:
    """Wall and CPU time and steps of the library call the command makes (the same
    settings).
    """
    c0, t0 = time.process_time(), time.perf_counter()
    tree = hosid.fit(hosid.read_record(path), seed=0, progress=False, truths=truths)
    sec, cpu = time.perf_counter() - t0, time.process_time() - c0
    return sec, cpu, json.loads(tree.attrs["sampler_json"])["steps"]


#: The command up to its output: the same imports, record checks and fit (``--out``'s
#: chain file included), nothing written.
FLOOR = """
import sys, tempfile
from pathlib import Path
import hosid.cli
from hosid.record import read_record, read_truths
from hosid.screen import check_record
from hosid.inference import fit
path = Path(sys.argv[1])
record = read_record(path)
checks = check_record(record)
with tempfile.TemporaryDirectory() as tmp:
    fit(record, seed=0, progress=False, truths=read_truths(path, None), checks=checks,
        backend=Path(tmp) / "chain.h5")
__import__("gc").freeze()  # as the command ends (hosid.cli.main)
"""
#: The ways of running the command: as a user does, figures beside the fit, after it.
COMMANDS = {
    "command": {},
    "forked": {"HOSID_FIGURE_PROCESSES": "1"},
    "serial": {"HOSID_FIGURE_PROCESSES": "0"},
}


def measure(repeat: int, folder: Path) -> dict[str, list[float]]:
    """``repeat`` interleaved rounds (module docstring); the times of every round."""
    rec = hosid.simulate(
        hosid.PAPER_PARAMS, duration=2000.0, dt=0.02, rng=__import__("numpy").random.default_rng(7)
    )
    path = folder / "rec.npz"
    hosid.write_record(rec, path)
    truths = dict(hosid.PAPER_PARAMS)
    path.with_suffix(".truths.json").write_text(json.dumps(truths))
    _fit(path, truths)  # warm: imports, numba, first calls
    times: dict[str, list[float]] = {}

    def add(key: str, wall_cpu: tuple[float, float]) -> None:
        times.setdefault(key, []).append(wall_cpu[0])
        times.setdefault(f"{key}_cpu", []).append(wall_cpu[1])

    for i in range(repeat):
        add("help", _run([str(HOSID), "--help"]))
        add("import", _run([sys.executable, "-c", "import hosid.cli"]))
        order = list(COMMANDS)[i % 3 :] + list(COMMANDS)[: i % 3]
        for key in order:
            out = folder / f"{key}{i}"
            cmd = [str(HOSID), "fit", str(path), "--out", str(out), "--no-progress"]
            if key == "command":  # what the command will decide (the same rule, now)
                times.setdefault("command_forked", []).append(float(render.enabled()))
            add(key, _run(cmd, **COMMANDS[key]))
            summary = json.loads((out / "summary.json").read_text())
            times.setdefault(f"{key}_inside", []).append(summary["fit_seconds"])
            times.setdefault(f"{key}_steps", []).append(summary["sampler"]["steps"])
            shutil.rmtree(out)
        add("floor", _run([sys.executable, "-c", FLOOR, str(path)]))
        sec, cpu, steps = _fit(path, truths)
        add("fit", (sec, cpu))
        times.setdefault("fit_steps", []).append(steps)
    return times


def _priority() -> str:
    """How this run was scheduled beside other jobs, when not as usual: Linux shares the
    cores between sessions (autogroups), and ``echo -19 > /proc/self/autogroup`` (root)
    gives this session the machine as if the others were idle.
    """
    try:
        nice = int(Path("/proc/self/autogroup").read_text().split("nice")[1])
    except (OSError, IndexError, ValueError):
        return ""
    if nice == 0:
        return ""
    return (
        f" This session's scheduling group ran at nice {nice} (`/proc/self/autogroup`): "
        "the other jobs yielded the cores, as on an idle machine."
    )


def table(times: dict[str, list[float]], load: tuple[float, float]) -> str:
    """The results as markdown."""
    med = {k: statistics.median(v) for k, v in times.items()}

    def ratio(a: str, b: str) -> float:
        return statistics.median(x / y for x, y in zip(times[a], times[b], strict=True))

    n = len(times["fit"])

    def wrap(text: str) -> str:
        return textwrap.fill(text, 88, break_on_hyphens=False)

    def row(text: str, key: str) -> str:
        return f"| {text} | {med[key]:.2f} | {med[key + '_cpu']:.2f} |"

    return "\n".join(
        [
            HEADING,
            "",
            wrap(
                f"{platform.machine()}, {os.cpu_count()} cores, "
                f"Python {platform.python_version()}, "
                f"hosid {hosid.__version__}; a 100 000-sample record of the paper oscillator "
                f"(2000 s at dt = 0.02 s), seed 0; median of {n} interleaved rounds; load "
                f"average {load[0]:.2f} before the run, {load[1]:.2f} after it.{_priority()}"
            ),
            "",
            "| what | wall time (s) | CPU time (s) |",
            "|---|---|---|",
            row("`hosid --help`", "help"),
            row('`python -c "import hosid.cli"`', "import"),
            row(
                "`hosid fit REC --out DIR --no-progress`, end to end (figures beside the fit "
                f"in {sum(times['command_forked']):.0f} of {n} rounds, by the load average)",
                "command",
            ),
            f"| the fit inside it (`fit_seconds` of its summary) | {med['command_inside']:.2f} "
            "| |",
            row("the same, `HOSID_FIGURE_PROCESSES=1` (figures beside the fit)", "forked"),
            f"| the fit inside it | {med['forked_inside']:.2f} | |",
            row("the same, `HOSID_FIGURE_PROCESSES=0` (figures after the fit)", "serial"),
            f"| the fit inside it | {med['serial_inside']:.2f} | |",
            row("the command up to its output (imports, checks, fit; nothing written)", "floor"),
            row("`hosid.fit()` of the same record, warm process", "fit"),
            "",
            wrap(
                "Ratio of the command to the warm `fit()` call (median of the rounds' ratios): "
                f"**{ratio('command', 'fit'):.2f}** in wall time, "
                f"**{ratio('command_cpu', 'fit_cpu'):.2f}** in CPU time; "
                f"to the fit inside it (wall): {ratio('command', 'command_inside'):.2f}.  "
                + "; ".join(
                    f"{what}: {ratio(k, 'fit'):.2f} wall, {ratio(k + '_cpu', 'fit_cpu'):.2f} "
                    f"CPU, {ratio(k, k + '_inside'):.2f} to the fit inside it"
                    for k, what in (("forked", "Figures beside the fit"), ("serial", "after it"))
                )
                + f".  The command up to its output: {ratio('floor', 'fit'):.2f} wall, "
                f"{ratio('floor_cpu', 'fit_cpu'):.2f} CPU."
                + f"  Steps per walker: command {sorted(set(times['command_steps']))}, "
                f"`fit()` {sorted(set(times['fit_steps']))}."
            ),
            "",
        ]
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="rounds, default 5")
    ap.add_argument("--write", action="store_true", help="add the table to results.md")
    args = ap.parse_args()
    before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        times = measure(args.repeat, Path(tmp))
    print(json.dumps({k: [round(x, 3) for x in v] for k, v in times.items()}))
    text = table(times, (before, os.getloadavg()[0]))
    print(text)
    if args.write:
        results = HERE / "results.md"
        old = results.read_text()
        start = old.find(HEADING)
        if start < 0:  # a new section at the end
            results.write_text(old.rstrip("\n") + "\n\n" + text)
        else:  # the earlier one replaced where it stands
            end = old.find("\n## ", start + len(HEADING))
            rest = old[end + 1 :] if end >= 0 else ""
            results.write_text(old[:start] + text + ("\n" + rest if rest else ""))


if __name__ == "__main__":
    main()
