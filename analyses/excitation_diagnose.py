"""Issue 29: does ``hosid diagnose`` on the white model name a narrow-band or impulsive
force, and does it name nothing on white records?

The records are those of the excitation studies (``excitation_study.py``,
``impulse_study.py``: the independent simulator, the paper oscillator at S0 = 100 over
2000 s and the ship-roll-like one over 4000 s) at the strengths the issue uses: the
filter peaked above the resonance (7 rad/s, zf 0.2), at it (5, 0.2) and at twice it
(13, 0.3) on the paper oscillator, below the ship's resonance (0.45, 0.1) and at it
(0.6, 0.1); Poisson impulses at 0.5, 1
and 2 a second on the paper oscillator; and white records of both systems.  Each is
diagnosed with base ``paper`` (every candidate of the white model, the new
``narrowband_excitation`` and ``impulsive_excitation`` among them) exactly as
``diagnose_power.py`` does (``run_one``: screened posterior, 40 replicates).

    python analyses/excitation_diagnose.py                 # run (resumable) and summarize
    python analyses/excitation_diagnose.py --summary       # the table only
    python analyses/excitation_diagnose.py --records 2     # a first pass

Record ``k`` of a cell is seeded by ``SeedSequence([SEED, crc32(cell), k])``.  The rows
(``results/excitation_diagnose/diagnose.csv``) are ``diagnose_power``'s.  Runs the white
records first, then one record of every cell a pass, so a stopped run has every cell.
"""

from __future__ import annotations

import argparse
import csv
import sys
import zlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from diagnose_power import FIELDS, read_csv, run_rows
from excitation_study import SYSTEMS

from hosid.check.diagnose import DEFAULT_REPLICATES

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "excitation_diagnose"
SEED = 20261127
#: cell: (system, hidden effect or None, its parameters, records)
CELLS = {
    "narrowband_above@paper": ("paper", "narrowband_excitation", {"wf": 7.0, "zf": 0.2}, 10),
    "narrowband_twice@paper": ("paper", "narrowband_excitation", {"wf": 13.0, "zf": 0.3}, 10),
    "narrowband_below@ship": ("ship", "narrowband_excitation", {"wf": 0.45, "zf": 0.1}, 10),
    "narrowband_at@ship": ("ship", "narrowband_excitation", {"wf": 0.6, "zf": 0.1}, 10),
    "narrowband_at@paper": ("paper", "narrowband_excitation", {"wf": 5.0, "zf": 0.2}, 10),
    "impulses_0.5@paper": ("paper", "impulsive_excitation", {"rate": 0.5}, 10),
    "impulses_1@paper": ("paper", "impulsive_excitation", {"rate": 1.0}, 10),
    "impulses_2@paper": ("paper", "impulsive_excitation", {"rate": 2.0}, 10),
    "white@paper": ("paper", None, {}, 10),
    "white@ship": ("ship", None, {}, 10),
}


def rows(records: int | None, replicates: int) -> list[dict]:
    """One ``diagnose_power.run_one`` row per record: the white records first (fast: with
    no candidate near the threshold diagnose stops before its replicates), then one
    record of every other cell a pass."""
    out = []
    for cell, (system, effect, extra, n) in CELLS.items():
        params, duration, dt = SYSTEMS[system]
        for k in range(n if records is None else min(n, records)):
            out.append(
                {"cell": cell, "regime": system, "system": system, "base": "paper",
                 "effects": {effect: 1.0} if effect else {}, "record": k,
                 "truth": {**params, **extra}, "duration": duration, "dt": dt,
                 "replicates": replicates}
            )  # fmt: skip
    return sorted(out, key=lambda r: (bool(r["effects"]), r["record"], r["cell"]))


def summarize(results: list[dict], out: Path) -> Path:
    """``summary.md``: per cell, the records that name the hidden effect (first, and
    exactly), that name anything, and what they named."""
    lines = [
        "# diagnose on the white model: the excitation candidates",
        "",
        "Records from the independent simulator; `diagnose(..., base='paper', "
        "posterior='screen', replicates=40)`. `hit`: the hidden effect named (white "
        "cells: nothing named); `exact`: named it and nothing else.",
        "",
        "| cell | records | hit | exact | named (count) | errors | median s |",
        "|---|---|---|---|---|---|---|",
    ]
    for cell in CELLS:
        rs = [r for r in results if r["cell"] == cell]
        if not rs:
            continue
        ok = [r for r in rs if not r["error"]]
        named: dict[str, int] = {}
        for r in ok:
            named[r["named"]] = named.get(r["named"], 0) + 1
        what = ", ".join(f"{k} ({v})" for k, v in sorted(named.items(), key=lambda t: -t[1]))
        sec = np.median([float(r["seconds"]) for r in rs])
        hit = sum(int(r["hit"]) for r in ok)
        exact = sum(int(r["exact"]) for r in ok)
        lines.append(
            f"| {cell} | {len(rs)} | {hit}/{len(ok)} | {exact}/{len(ok)} | {what} | "
            f"{len(rs) - len(ok)} | {sec:.0f} |"
        )
    path = out / "summary.md"
    path.write_text("\n".join(lines) + "\n")
    return path


PARTS = "diagnose-part-*.csv"


def _merged(out: Path) -> Path:
    """``diagnose.csv``: its rows and every part's (``diagnose-part-*.csv``, written by
    runs of some shards or cells), one a record; the parts are then removed."""
    path = out / "diagnose.csv"
    rows: dict = {}
    for f in [path, *sorted(out.glob(PARTS))]:
        for r in read_csv(f):
            rows[r["cell"], int(r["record"])] = r
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, FIELDS, lineterminator="\n")
        w.writeheader()
        w.writerows(rows.values())
    for f in out.glob(PARTS):
        f.unlink()
    return path


def main(argv: Sequence[str] | None = None) -> int:
    """Run (or resume) the study, then write the summary.  ``--shard K/N`` runs every
    N-th record from the K-th (0-based) and ``--cells`` only some cells, each such run into
    a part file of its own, so that several processes share the work; ``--summary``
    merges the parts."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=None, help="at most this many a cell")
    ap.add_argument("--replicates", type=int, default=DEFAULT_REPLICATES)
    ap.add_argument("--summary", action="store_true", help="merge the parts; the table only")
    ap.add_argument("--shard", default="0/1", help="K/N: this process's share of the records")
    ap.add_argument("--cells", nargs="+", choices=list(CELLS), default=list(CELLS))
    ap.add_argument("--out", type=Path, default=RESULTS)
    a = ap.parse_args(argv)
    k, n = (int(x) for x in a.shard.split("/"))
    a.out.mkdir(parents=True, exist_ok=True)
    if not a.summary:
        whole = n == 1 and set(a.cells) == set(CELLS)
        tag = zlib.crc32(" ".join(sorted(a.cells)).encode())
        path = a.out / ("diagnose.csv" if whole else f"diagnose-part-{k}-of-{n}-{tag:08x}.csv")
        done = {
            (r["cell"], int(r["record"]))
            for f in [a.out / "diagnose.csv", *a.out.glob(PARTS)]
            for r in read_csv(f)
        }
        mine = [r for r in rows(a.records, a.replicates) if r["cell"] in a.cells][k::n]
        todo = [r for r in mine if (r["cell"], r["record"]) not in done]
        new = not path.exists() or path.stat().st_size == 0
        with open(path, "a", newline="") as fh:
            w = csv.DictWriter(fh, FIELDS)
            if new:
                w.writeheader()
            run_rows(todo, w, fh, SEED)
        if not whole:
            return 0
    print(summarize(read_csv(_merged(a.out)), a.out).read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
