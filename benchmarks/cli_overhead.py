"""The command line against the library call: ``hosid fit`` as a user runs it beside
``hosid.fit()`` on the same record in a warm process, as ratios measured in one run.

Simulates a 100 000-sample record of the paper oscillator (2000 s at dt = 0.02 s, with
its ``.truths.json``), warms this process up with one ``hosid.fit()`` call, then runs
``REPEAT`` rounds, each of them, interleaved:

- ``hosid --help`` and ``python -c "import hosid.cli"`` (subprocesses);
- ``hosid fit REC --out DIR --no-progress`` (a subprocess, the console script of this
  environment, into a fresh folder), end to end; its ``summary.json`` gives the time of
  the fit inside it (``fit_seconds``) and the steps it ran;
- ``hosid.fit(hosid.read_record(REC), seed=0, truths=...)`` in this (warm) process: the
  same seed and settings as the command's defaults, hence the same chain.

and prints the medians and the ratios (the command's end-to-end time over the warm
``fit()`` call, and over the fit inside the command), of the wall times and of the CPU
times (the subprocess's user + system time against this process's for the ``fit()``
call: on a machine that other jobs share, CPU time tracks the work better than wall
time); ``--write`` adds the table to ``benchmarks/results.md`` (replacing an earlier one
of this script).

    python benchmarks/cli_overhead.py                  # 5 rounds
    python benchmarks/cli_overhead.py --repeat 3 --write
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

HERE = Path(__file__).resolve().parent
HOSID = Path(sys.executable).with_name("hosid")
HEADING = "## `hosid fit` against `hosid.fit()` (`benchmarks/cli_overhead.py`)"


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _run(args: list[str]) -> tuple[float, float]:
    """Wall and CPU time (s) of one subprocess; fails loudly when it fails."""
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
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
    keys = ("help", "import", "command", "inside", "fit")
    times: dict[str, list[float]] = {
        k: [] for k in (*keys, *(f"{k}_cpu" for k in keys if k != "inside"), "steps_cmd",
                        "steps_fit")
    }  # fmt: skip

    def add(key: str, wall_cpu: tuple[float, float]) -> None:
        times[key].append(wall_cpu[0])
        times[f"{key}_cpu"].append(wall_cpu[1])

    for i in range(repeat):
        add("help", _run([str(HOSID), "--help"]))
        add("import", _run([sys.executable, "-c", "import hosid.cli"]))
        out = folder / f"out{i}"
        add("command", _run([str(HOSID), "fit", str(path), "--out", str(out), "--no-progress"]))
        summary = json.loads((out / "summary.json").read_text())
        times["inside"].append(summary["fit_seconds"])
        times["steps_cmd"].append(summary["sampler"]["steps"])
        sec, cpu, steps = _fit(path, truths)
        add("fit", (sec, cpu))
        times["steps_fit"].append(steps)
        shutil.rmtree(out)
    return times


def table(times: dict[str, list[float]], load: float) -> str:
    """The results as markdown."""
    med = {k: statistics.median(v) for k, v in times.items()}

    def ratio(a: str, b: str) -> float:
        return statistics.median(x / y for x, y in zip(times[a], times[b], strict=True))

    n = len(times["fit"])

    def wrap(text: str) -> str:
        return textwrap.fill(text, 88, break_on_hyphens=False)

    return "\n".join(
        [
            HEADING,
            "",
            wrap(
                f"{platform.machine()}, {os.cpu_count()} cores, "
                f"Python {platform.python_version()}, "
                f"hosid {hosid.__version__}; a 100 000-sample record of the paper oscillator "
                f"(2000 s at dt = 0.02 s), seed 0; median of {n} interleaved rounds; load "
                f"average {load:.2f} before the run."
            ),
            "",
            "| what | wall time (s) | CPU time (s) |",
            "|---|---|---|",
            f"| `hosid --help` | {med['help']:.2f} | {med['help_cpu']:.2f} |",
            f'| `python -c "import hosid.cli"` | {med["import"]:.2f} | {med["import_cpu"]:.2f} |',
            f"| `hosid fit REC --out DIR --no-progress`, end to end | {med['command']:.2f} | "
            f"{med['command_cpu']:.2f} |",
            f"| the fit inside the command (`fit_seconds` of its summary) | {med['inside']:.2f} "
            "| |",
            f"| `hosid.fit()` of the same record, warm process | {med['fit']:.2f} | "
            f"{med['fit_cpu']:.2f} |",
            "",
            wrap(
                "Ratio of the command to the warm `fit()` call (median of the rounds' ratios): "
                f"**{ratio('command', 'fit'):.2f}** in wall time, "
                f"**{ratio('command_cpu', 'fit_cpu'):.2f}** in CPU time; "
                "to the fit inside it (wall): "
                f"{ratio('command', 'inside'):.2f}.  "
                f"Steps per walker: command {sorted(set(times['steps_cmd']))}, `fit()` "
                f"{sorted(set(times['steps_fit']))}."
            ),
            "",
        ]
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="rounds, default 5")
    ap.add_argument("--write", action="store_true", help="add the table to results.md")
    args = ap.parse_args()
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        times = measure(args.repeat, Path(tmp))
    print(json.dumps({k: [round(x, 3) for x in v] for k, v in times.items()}))
    text = table(times, load)
    print(text)
    if args.write:
        results = HERE / "results.md"
        old = results.read_text()
        start = old.find(HEADING)
        if start >= 0:
            end = old.find("\n## ", start + len(HEADING))
            old = old[:start] + (old[end + 1 :] if end >= 0 else "")
        results.write_text(old.rstrip("\n") + "\n\n" + text)


if __name__ == "__main__":
    main()
