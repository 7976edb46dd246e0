"""Condition monitoring (issue 31): power, false alarms and interval coverage of
``hosid monitor`` with its defaults on long records with a step change.

Records come from the independent simulator (``independent_sim.py``, its flat change
keys), 40 000 s each: the paper oscillator (S0 = 100, dt = 0.02 s) and the ship-roll-like
one (dt = 0.1 s).  Per system, ``--records`` (default 10) records with a 5 % loss of the
linear stiffness a2, 10 with a 30 % rise of the excitation level S0 alone, and twice as
many stationary ones; the change time is drawn uniformly in [20 000, 36 000] s (the
second half, at least two windows before the end) from the record's own stream
(``SeedSequence(SEED, spawn_key=(case key, record))``).  ``--sizes K ...`` adds a power
curve: a2 steps of K bound-sd of one window (``crb.md``'s a2 bound scaled to the
window) on the ship-roll-like oscillator (``--size-system paper`` for the other), 5
records each.

Each record is simulated, written as ``.npz``, monitored (``hosid.monitor.monitor``,
defaults: a calibrated emcee fit per window, alpha = 0.05, 95 % intervals) on one local
dask cluster shared by the records, and removed; one row per record goes to
``out/monitor/results.csv`` (a rerun skips the records done).  The summary
(``results/monitor/summary.md``, ``.csv``) gives per case the records that named the
changed parameter, named it alone, whose time and size intervals hold the truth, and
that named a structural (drift) parameter wrongly.

    python analyses/monitor_study.py                        # run and summarize
    python analyses/monitor_study.py --summary
    python analyses/monitor_study.py --cases ship_a2 --records 2
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import independent_sim  # noqa: E402

from hosid.batch import dask_client  # noqa: E402
from hosid.monitor.run import monitor  # noqa: E402
from hosid.record import write_record  # noqa: E402

WORK = HERE / "out" / "monitor"
RESULTS = HERE / "results" / "monitor"
SEED = 20261126
DURATION = 40000.0
PAPER = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0}
SHIP = {"a1": 0.03, "n1": 0.15, "a2": 0.35, "n2": 0.2, "S0": 2.6e-4}
SYSTEMS = {"paper": (PAPER, 0.02), "ship": (SHIP, 0.1)}
#: a2's information limit per 2000 s (paper) and 4000 s (ship) record (crb.md)
A2_BOUND = {"paper": (0.90, 2000.0), "ship": (0.00569, 4000.0)}
#: the monitor's default window on these records (s)
WINDOW = {"paper": 1986.56, "ship": 4096.0}
#: name: (system, key, changed parameter or None, factor after, records per --records)
CASES = {
    "paper_a2": ("paper", 1, "a2", 0.95, 1),
    "paper_S0": ("paper", 2, "S0", 1.30, 1),
    "paper_none": ("paper", 3, None, 1.0, 2),
    "ship_a2": ("ship", 4, "a2", 0.95, 1),
    "ship_S0": ("ship", 5, "S0", 1.30, 1),
    "ship_none": ("ship", 6, None, 1.0, 2),
}
FIELDS = ["case", "record", "parameter", "truth_time", "truth_size", "windows", "failed",
          "named", "kinds", "hit", "alone", "time_in", "size_in", "wrong_drift", "changes",
          "seconds"]  # fmt: skip


def design(
    cases: Sequence[str], records: int, sizes: Sequence[float], system: str = "ship"
) -> list[dict]:
    """One dict per record: case, index, system, parameters and change."""
    out = []
    for name in cases:
        system, key, p, factor, mult = CASES[name]
        out += [dict(case=name, i=i, system=system, key=key, p=p, factor=factor)
                for i in range(records * mult)]  # fmt: skip
    for k in sizes:
        bound, T = A2_BOUND[system]
        step = k * bound * math.sqrt(T / WINDOW[system])
        factor = 1.0 - step / SYSTEMS[system][0]["a2"]
        out += [dict(case=f"{system}_a2_{k:g}sd", i=i, system=system, key=100 + round(10 * k),
                     p="a2", factor=factor) for i in range(5)]  # fmt: skip
    return out


def simulate(row: dict, path: Path) -> tuple[float | None, float | None]:
    params, dt = SYSTEMS[row["system"]]
    ss = np.random.SeedSequence(SEED, spawn_key=(row["key"], row["i"]))
    rng = np.random.default_rng(ss)
    flat = dict(params)
    at = size = None
    if row["p"] is not None:
        at = float(rng.uniform(20000.0, 36000.0))
        after = params[row["p"]] * row["factor"]
        size = after - params[row["p"]]
        flat.update(change_at=at, **{f"{row['p']}_after": after})
    rec, _ = independent_sim.simulate(flat, duration=DURATION, dt=dt, rng=rng)
    write_record(rec, path)
    return at, size


def run_one(row: dict, scheduler: str) -> dict:
    WORK.mkdir(parents=True, exist_ok=True)
    label = f"{row['case']}-{row['i']}"
    path = WORK / f"{label}.npz"
    t0 = time.perf_counter()
    at, size = simulate(row, path)
    res = monitor(path, WORK / "runs" / label, scheduler=scheduler, progress=False,
                  echo=lambda s: None, seed=row["i"])  # fmt: skip
    path.unlink()
    changes = res.changes
    mine = [c for c in changes if c.parameter == row["p"]]
    kinds = res.tracks.kinds
    wrong = [c for c in changes if c.parameter != row["p"] and kinds.get(c.parameter) == "drift"]
    c = mine[0] if mine else None
    return {
        "case": row["case"], "record": row["i"], "parameter": row["p"] or "",
        "truth_time": at, "truth_size": size, "windows": int(res.tracks.start.size),
        "failed": len(res.tracks.failed), "named": " ".join(x.parameter for x in changes),
        "kinds": " ".join(kinds.get(x.parameter, "") for x in changes),
        "hit": int(c is not None), "alone": int(c is not None and len(changes) == 1),
        "time_in": int(c is not None and c.time_lo <= at <= c.time_hi),
        "size_in": int(c is not None and c.size_lo <= size <= c.size_hi),
        "wrong_drift": len(wrong),
        "changes": json.dumps([res.tracks.change_row(x) for x in changes]),
        "seconds": time.perf_counter() - t0,
    }  # fmt: skip


def _done(path: Path) -> dict[tuple[str, int], dict]:
    if not path.is_file():
        return {}
    with path.open(newline="") as fh:
        return {(r["case"], int(r["record"])): r for r in csv.DictReader(fh)}


def run(rows: list[dict], workers: int | None) -> Path:
    path = WORK / "results.csv"
    done = _done(path)
    todo = [r for r in rows if (r["case"], r["i"]) not in done]
    WORK.mkdir(parents=True, exist_ok=True)
    new = not path.is_file()
    with dask_client(workers=workers) as client, path.open("a", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=FIELDS, lineterminator="\n")
        if new:
            w.writeheader()
        for k, row in enumerate(todo):
            out = run_one(row, client.scheduler.address)
            w.writerow(out)
            fh.flush()
            print(f"[{k + 1}/{len(todo)}] {out['case']}-{out['record']}: named "
                  f"{out['named'] or 'nothing'} ({out['seconds']:.0f} s)", flush=True)  # fmt: skip
    return path


def summarize(path: Path, out: Path) -> Path:
    rows = list(_done(path).values())
    cases = sorted({r["case"] for r in rows}, key=lambda c: (c.split("_")[0], c))
    table = []
    for case in cases:
        rs = [r for r in rows if r["case"] == case]
        n = len(rs)
        s = {k: sum(int(r[k]) for r in rs) for k in ("hit", "alone", "time_in", "size_in")}
        table.append({
            "case": case, "records": n, "parameter": rs[0]["parameter"] or "-",
            **s, "any_named": sum(1 for r in rs if r["named"]),
            "wrong_drift": sum(1 for r in rs if int(r["wrong_drift"])),
            "windows": rs[0]["windows"], "failed_windows": sum(int(r["failed"]) for r in rs),
            "minutes_per_record": np.mean([float(r["seconds"]) for r in rs]) / 60,
        })  # fmt: skip
    out.mkdir(parents=True, exist_ok=True)
    with (out / "summary.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(table[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(table)
    lines = [
        "# Condition monitoring: power, false alarms and interval coverage (issue 31)", "",
        "`python analyses/monitor_study.py`: independent simulator, 40 000 s records, a step "
        "at a uniform time in [20 000, 36 000] s; `hosid monitor` with its defaults "
        "(emcee fit per window, alpha 0.05, 95 % intervals). Counts of records.", "",
        "| case | changed | records | windows | named it | named it alone | time interval "
        "holds | size interval holds | named any change | named a wrong drift parameter "
        "| min/record |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]  # fmt: skip
    for t in table:
        lines.append(
            f"| {t['case']} | {t['parameter']} | {t['records']} | {t['windows']} | {t['hit']} | "
            f"{t['alone']} | {t['time_in']} | {t['size_in']} | {t['any_named']} | "
            f"{t['wrong_drift']} | {t['minutes_per_record']:.1f} |"
        )
    path_md = out / "summary.md"
    path_md.write_text("\n".join(lines) + "\n")
    return path_md


def main(argv: Sequence[str] | None = None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--records", type=int, default=10)
    ap.add_argument("--sizes", type=float, nargs="*", default=[], help="a2 steps in bound-sd")
    ap.add_argument("--size-system", choices=list(SYSTEMS), default="ship")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--summary", action="store_true")
    args = ap.parse_args(argv)
    path = WORK / "results.csv"
    if not args.summary:
        run(design(args.cases, args.records, args.sizes, args.size_system), args.workers)
    md = summarize(path, RESULTS)
    (RESULTS / "results.csv").write_text(path.read_text())
    print(f"wrote {md}")
    return md


if __name__ == "__main__":
    main()
