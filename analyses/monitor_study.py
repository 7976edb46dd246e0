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
defaults: a calibrated emcee fit per window, alpha = ``ALPHA``, 95 % intervals) on one local
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
from hosid.monitor.changes import ALPHA  # noqa: E402
from hosid.monitor.run import monitor  # noqa: E402
from hosid.monitor.tracks import CORRELATION  # noqa: E402
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
#: the change time is drawn uniformly between these (s); --change-between overrides
CHANGE_BETWEEN = (20000.0, 36000.0)
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
    cases: Sequence[str], records: int, sizes: Sequence[float], system: str = "ship", first=0
) -> list[dict]:
    """One dict per record: case, index (from ``first``: other seeds), system, parameters
    and change."""
    out = []
    for name in cases:
        sys_, key, p, factor, mult = CASES[name]
        out += [dict(case=name, i=i, system=sys_, key=key, p=p, factor=factor)
                for i in range(first, first + records * mult)]  # fmt: skip
    for k in sizes:
        bound, T = A2_BOUND[system]
        step = k * bound * math.sqrt(T / WINDOW[system])
        factor = 1.0 - step / SYSTEMS[system][0]["a2"]
        out += [dict(case=f"{system}_a2_{k:g}sd", i=i, system=system, key=100 + round(10 * k),
                     p="a2", factor=factor) for i in range(first, first + 5)]  # fmt: skip
    return out


def simulate(row: dict, path: Path, between=CHANGE_BETWEEN) -> tuple[float | None, float | None]:
    params, dt = SYSTEMS[row["system"]]
    ss = np.random.SeedSequence(SEED, spawn_key=(row["key"], row["i"]))
    rng = np.random.default_rng(ss)
    flat = dict(params)
    at = size = None
    if row["p"] is not None:
        at = float(rng.uniform(*between))
        after = params[row["p"]] * row["factor"]
        size = after - params[row["p"]]
        flat.update(change_at=at, **{f"{row['p']}_after": after})
    rec, _ = independent_sim.simulate(flat, duration=DURATION, dt=dt, rng=rng)
    write_record(rec, path)
    return at, size


def score(case, i, p, at, size, tracks, changes, seconds) -> dict:
    """One results row: what the monitor named against the truth."""
    mine = [c for c in changes if c.parameter == p]
    kinds = tracks.kinds
    wrong = [c for c in changes if c.parameter != p and kinds.get(c.parameter) == "drift"]
    c = mine[0] if mine else None
    return {
        "case": case, "record": i, "parameter": p or "",
        "truth_time": at, "truth_size": size, "windows": int(tracks.start.size),
        "failed": len(tracks.failed), "named": " ".join(x.parameter for x in changes),
        "kinds": " ".join(kinds.get(x.parameter, "") for x in changes),
        "hit": int(c is not None), "alone": int(c is not None and len(changes) == 1),
        "time_in": int(c is not None and c.time_lo <= at <= c.time_hi),
        "size_in": int(c is not None and c.size_lo <= size <= c.size_hi),
        "wrong_drift": len(wrong),
        "changes": json.dumps([tracks.change_row(x) for x in changes]),
        "seconds": seconds,
    }  # fmt: skip


def run_one(row: dict, scheduler: str, work: Path = WORK, between=CHANGE_BETWEEN) -> dict:
    """Simulate, monitor into ``work/runs/<case>-<i>`` (kept: its ``tracks.nc`` holds what
    the change test needs, :func:`retest`), remove the record, score."""
    work.mkdir(parents=True, exist_ok=True)
    label = f"{row['case']}-{row['i']}"
    path = work / f"{label}.npz"
    t0 = time.perf_counter()
    at, size = simulate(row, path, between)
    res = monitor(path, work / "runs" / label, scheduler=scheduler, progress=False,
                  echo=lambda s: None, seed=row["i"])  # fmt: skip
    path.unlink()
    seconds = time.perf_counter() - t0
    return score(row["case"], row["i"], row["p"], at, size, res.tracks, res.changes, seconds)


def retest(work: Path, **options) -> list[dict]:
    """The change test run again on every kept monitor of ``work`` (no refit): the rows
    of ``work/results.csv`` scored anew with ``options`` of
    :meth:`hosid.monitor.tracks.Tracks.changes` (``alpha``, ``level``; seed: the record's).
    """
    from hosid.monitor.tracks import Tracks

    out = []
    for (case, i), r in sorted(_done(work / "results.csv").items()):
        folder = work / "runs" / f"{case}-{i}"
        if not (folder / "tracks.nc").is_file():
            continue
        tracks = Tracks.read(folder)
        opts = {"alpha": ALPHA, "level": 0.95, "seed": i, **options}
        changes = tracks.changes(**opts)
        at, size = (float(r[k]) if r[k] else None for k in ("truth_time", "truth_size"))
        out.append(score(case, i, r["parameter"] or None, at, size, tracks, changes, 0.0))
    return out


def _done(path: Path) -> dict[tuple[str, int], dict]:
    if not path.is_file():
        return {}
    with path.open(newline="") as fh:
        return {(r["case"], int(r["record"])): r for r in csv.DictReader(fh)}


def run(rows: list[dict], workers: int | None, work: Path = WORK, between=CHANGE_BETWEEN) -> Path:
    path = work / "results.csv"
    done = _done(path)
    todo = [r for r in rows if (r["case"], r["i"]) not in done]
    work.mkdir(parents=True, exist_ok=True)
    new = not path.is_file()
    with dask_client(workers=workers) as client, path.open("a", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=FIELDS, lineterminator="\n")
        if new:
            w.writeheader()
        for k, row in enumerate(todo):
            out = run_one(row, client.scheduler.address, work, between)
            w.writerow(out)
            fh.flush()
            print(f"[{k + 1}/{len(todo)}] {out['case']}-{out['record']}: named "
                  f"{out['named'] or 'nothing'} ({out['seconds']:.0f} s)", flush=True)  # fmt: skip
    return path


def summarize(path: Path, out: Path, alpha: float = ALPHA) -> Path:
    """The tables of ``path``'s rows (changes named at ``alpha``) in ``out``."""
    rows = list(_done(path).values())
    cases = sorted({r["case"] for r in rows}, key=lambda c: (c.split("_")[0], c))
    table = []
    for case in cases:
        rs = [r for r in rows if r["case"] == case]
        n = len(rs)
        s = {k: sum(int(r[k]) for r in rs) for k in ("hit", "alone", "time_in", "size_in")}
        named = [json.loads(r["changes"] or "[]") for r in rs]
        primary = [[c["parameter"] for c in cs if c.get("role") != "alternative"] for cs in named]
        kinds = [[c.get("kind") for c in cs if c.get("role") != "alternative"] for cs in named]
        table.append({
            "case": case, "records": n, "parameter": rs[0]["parameter"] or "-",
            **s, "any_named": sum(1 for r in rs if r["named"]),
            "hit_primary": sum(r["parameter"] in p for r, p in zip(rs, primary, strict=True)),
            "wrong_drift_primary": sum(
                any(k == "drift" and q != r["parameter"] for q, k in zip(p, ks, strict=True))
                for r, p, ks in zip(rs, primary, kinds, strict=True)
            ),
            "with_alternative": sum(
                len(p) < len(cs) for p, cs in zip(primary, named, strict=True)
            ),
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
        f"(emcee fit per window, alpha {alpha:g}, 95 % intervals). Counts of records. `named it`: "
        "in changes.csv (as an alternative too); `first`: by the test or as a companion, not "
        "as an alternative; `wrong drift`: another structural parameter named (`first`: not "
        "as an alternative); `alt.`: records with an alternative named.", "",
        "| case | changed | records | windows | named it | first | named it alone | time "
        "interval holds | size interval holds | named any change | wrong drift | wrong drift, "
        "first | alt. | min/record |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]  # fmt: skip
    for t in table:
        lines.append(
            f"| {t['case']} | {t['parameter']} | {t['records']} | {t['windows']} | {t['hit']} | "
            f"{t['hit_primary']} | {t['alone']} | {t['time_in']} | {t['size_in']} | "
            f"{t['any_named']} | {t['wrong_drift']} | {t['wrong_drift_primary']} | "
            f"{t['with_alternative']} | {t['minutes_per_record']:.1f} |"
        )
    path_md = out / "summary.md"
    path_md.write_text("\n".join(lines) + "\n")
    return path_md


def main(argv: Sequence[str] | None = None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--records", type=int, default=10)
    ap.add_argument("--first", type=int, default=0, help="records numbered from (other seeds)")
    ap.add_argument("--change-between", type=float, nargs=2, default=CHANGE_BETWEEN,
                    metavar=("LO", "HI"), help="the change time's range (s)")  # fmt: skip
    ap.add_argument("--tag", default="", help="a run of its own: out/monitor/TAG, no results/")
    ap.add_argument("--sizes", type=float, nargs="*", default=[], help="a2 steps in bound-sd")
    ap.add_argument("--size-system", choices=list(SYSTEMS), default="ship")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--summary", action="store_true")
    ap.add_argument("--retest", action="store_true", help="test the kept tracks again (no refit)")
    ap.add_argument("--alpha", type=float, default=ALPHA, help="of --retest")
    ap.add_argument("--correlation", choices=("own", "pooled"), default=CORRELATION,
                    help="of --retest: each window's correlation, or their mean")  # fmt: skip
    args = ap.parse_args(argv)
    work = WORK / args.tag if args.tag else WORK
    path = work / "results.csv"
    if args.retest:
        rows = retest(work, alpha=args.alpha, correlation=args.correlation)
        name = f"retest-alpha{args.alpha:g}" + (
            "" if args.correlation == CORRELATION else f"-{args.correlation}"
        )
        path = work / f"{name}.csv"
        with path.open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=FIELDS, lineterminator="\n")
            w.writeheader()
            w.writerows(rows)
        md = summarize(path, work / name, args.alpha)
        print(md.read_text())
        return md
    if not args.summary:
        rows = design(args.cases, args.records, args.sizes, args.size_system, args.first)
        run(rows, args.workers, work, tuple(args.change_between))
    md = summarize(path, work if args.tag else RESULTS)
    if not args.tag:
        (RESULTS / "results.csv").write_text(path.read_text())
    print(f"wrote {md}")
    return md


if __name__ == "__main__":
    main()
