"""The power study of ``diagnose`` run through ``hosid batch simulate-study``.

``python analyses/diagnose_power.py --batch [--workers N]`` writes one design table a
base model (``DIR/batch/design_<base>.json``: a row a cell, its records as seeds, its
true parameters, the independent simulator, and the cell's own random streams as the
row's ``entropy``) and runs

    hosid batch simulate-study DIR/batch/design_<base>.json --analysis diagnose
        --model <base> --posterior screen --no-candidate-gaps --replicates R
        --seed SEED --out DIR/batch/<base>

Record ``k`` of a cell then has the stream ``SeedSequence([SEED, crc32(cell), k])``, as
in the single-process loop: both ways simulate the same records and diagnose them with
the same random numbers.  The batch keeps every finished task (a rerun skips it) and its
table ``results.csv``; :func:`collect` turns its rows into the study's rows
(:func:`diagnose_power.result_row`).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import zlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np

SIMULATOR = Path(__file__).resolve().parent / "independent_sim.py"


def cell_entropy(cell: str) -> list[int]:
    """The cell's random streams: the words after the root seed."""
    return [zlib.crc32(cell.encode())]


def designs(rows: Sequence[dict], folder: Path) -> dict[str, list[dict]]:
    """``base -> design rows`` for the study's rows (one design row a cell, its records
    ``0 .. n - 1`` as seed numbers), to be written in ``folder`` (the simulator's path is
    relative to it: a task's id does not depend on where the project lies).
    """
    simulator = os.path.relpath(SIMULATOR, folder)
    out: dict[str, list[dict]] = {}
    seen: dict[str, dict] = {}
    for row in rows:
        cell = seen.get(row["cell"])
        if cell is None:
            cell = seen[row["cell"]] = {
                "name": row["cell"],
                "key": len(seen),
                "seeds": 0,
                "duration": row["duration"],
                "dt": row["dt"],
                "simulator": f"{simulator}:simulate",
                "entropy": cell_entropy(row["cell"]),
                **row["truth"],
            }
            out.setdefault(row["base"], []).append(cell)
        cell["seeds"] = max(cell["seeds"], int(row["record"]) + 1)
    return out


def run(
    rows: Sequence[dict], out: Path, *, replicates: int, seed: int, workers: int | None
) -> None:
    """Run every base's design through ``hosid batch simulate-study`` (module docstring).

    Raises
    ------
    RuntimeError
        If a batch command fails (its own one-line message is on stderr).
    """
    folder = out / "batch"
    folder.mkdir(parents=True, exist_ok=True)
    for base, design in designs(rows, folder).items():
        path = folder / f"design_{base}.json"
        path.write_text(json.dumps(design, indent=1) + "\n")
        cmd = [
            sys.executable, "-m", "hosid", "batch", "simulate-study", str(path),
            "--analysis", "diagnose", "--model", base, "--posterior", "screen",
            "--no-candidate-gaps", "--replicates", str(replicates), "--seed", str(seed),
            "--out", str(folder / base),
        ]  # fmt: skip
        if workers is not None:
            cmd += ["--workers", str(workers)]
        print(" ".join(cmd[1:]), flush=True)
        if subprocess.run(cmd).returncode != 0:
            raise RuntimeError(f"hosid batch failed on {path}")


def collect(rows: Sequence[dict], out: Path) -> list[dict]:
    """The study's rows of the records the batches finished (``rows``: the design rows
    of :func:`diagnose_power.rows_of` they ran).
    """
    from diagnose_power import result_row

    from hosid.batch.table import read_results

    want = {(r["cell"], int(r["record"])): r for r in rows}
    found = []
    for base in sorted({r["base"] for r in rows}):
        table = out / "batch" / base / "results.csv"
        if not table.exists():
            continue
        for b in read_results(table):
            row = want.get((b.get("design"), int(b.get("seed_index", -1))))
            if row is None:
                continue
            seconds = float(b.get("task_seconds") or np.nan)
            if b["status"] != "ok":
                found.append(result_row(row, seconds=seconds, error=str(b.get("message"))))
                continue
            named = str(b.get("named_effect") or "")
            found.append(
                result_row(
                    row,
                    named=[e for e in named.split("+") if e],
                    gaps=[float(g) for g in str(b["gaps"]).split(";")],
                    evidence=json.loads(b["evidence"]),
                    estimates=json.loads(b["estimates"]),
                    rounds_calibrated=int(b["rounds_calibrated"]),
                    seconds=seconds,
                )
            )
    return found
