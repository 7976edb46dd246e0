"""The excitation as the paper states it (issue 29): bias and coverage of the default fit
under a narrow-band force, with the matching excitation term and with the white model,
on the same records, and what the new terms cost on white records.

Records come from the independent simulator (``independent_sim.py``: the force through
the second-order shaping filter, discretized exactly), ``--records`` (default 10) per
case: the paper oscillator (S0 = 100, 2000 s at 0.02 s) and the ship-roll-like one
(4000 s at 0.1 s) under a filter peaked below, at and above the resonance, and both
under white noise.  Every record is fitted twice through ``hosid batch simulate-study``
(the workers simulate, fit and write one row each; a killed run resumes): with
``--model paper,narrowband_excitation`` and with ``--model paper``.

The summary (``results/excitation/summary.md``, ``.csv``) gives per case and model the
mean of the posterior means, their bias in standard errors and in units of the
information limit (``shaped_bound.py``: the augmented state's bound with all seven
parameters unknown; the white bound of ``crb.md``'s regimes for the white records), the
90 % and 50 % coverage of the drift coefficients pooled, the records whose 90 % interval
holds each excitation parameter, and the efficiency (bound variance over mean squared
error).  White records: the efficiency of the narrow-band fit over the white fit's.

    python analyses/excitation_study.py                       # run and summarize
    python analyses/excitation_study.py --summary             # summary only
    python analyses/excitation_study.py --cases paper_above --records 2 --n-steps 200
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from hosid.batch import design_tasks, read_design, run_batch

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "excitation"
WORK = HERE / "out" / "excitation"
SEED = 20261125
PAPER = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0}
SHIP = {"a1": 0.03, "n1": 0.15, "a2": 0.35, "n2": 0.2, "S0": 2.6e-4}
SYSTEMS = {"paper": (PAPER, 2000.0, 0.02), "ship": (SHIP, 4000.0, 0.1)}
#: name: (system, key, wf, zf); wf None = white noise
CASES = {
    "paper_below": ("paper", 1, 4.0, 0.2),
    "paper_above": ("paper", 2, 7.0, 0.2),
    "paper_at": ("paper", 8, 5.0, 0.2),
    "paper_twice": ("paper", 3, 13.0, 0.3),
    "ship_below": ("ship", 4, 0.45, 0.1),
    "ship_at": ("ship", 5, 0.6, 0.1),
    "ship_at_broad": ("ship", 7, 0.6, 0.25),
    "ship_above": ("ship", 6, 0.9, 0.15),
    "paper_white": ("paper", 11, None, None),
    "ship_white": ("ship", 12, None, None),
}
MODELS = {"narrowband": "paper,narrowband_excitation", "white": "paper"}
DRIFT = ("a1", "n1", "a2", "n2")
#: the information limit of the white regimes (crb.md)
WHITE_BOUND = {
    "paper": {"a1": 0.221, "n1": 0.0192, "a2": 0.90, "n2": 0.236},
    "ship": {"a1": 0.0149, "n1": 0.0768, "a2": 0.00569, "n2": 0.0466},
}


def write_design(cases: Sequence[str], path: Path, records: int) -> Path:
    """One design row per case, ``records`` seeds each."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fields = ["name", "key", "seeds", "duration", "dt", "simulator", *PAPER, "wf", "zf"]
    sim = HERE / "independent_sim.py"
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields, lineterminator="\n")
        w.writeheader()
        for name in cases:
            system, key, wf, zf = CASES[name]
            params, T, dt = SYSTEMS[system]
            row = {"name": name, "key": key, "seeds": records, "duration": T, "dt": dt}
            row["simulator"] = f"{sim}:simulate"
            row.update(params)
            row.update({"wf": "" if wf is None else wf, "zf": "" if zf is None else zf})
            w.writerow(row)
    return path


def run(cases, *, records, work, workers, n_steps, progress, models=MODELS) -> dict[str, Path]:
    """Fit every record with each of ``models`` (both by default); their tables."""
    design = write_design(cases, work / "design.csv", records)
    out = {}
    for label in models:
        spec = MODELS[label]
        tasks = design_tasks(
            read_design(design),
            analysis="fit",
            options={"model": spec, "n_steps": n_steps},
            seed=SEED,
            folder=design.parent,
        )
        res = run_batch(
            tasks, work / label, workers=workers, progress=progress, label=f"excitation {label}"
        )
        out[label] = res.tables[0]
    return out


def bounds(cases: Sequence[str], path: Path, seed: int = SEED) -> dict[str, dict]:
    """The information limit of each case (computed once, kept in ``path``)."""
    from shaped_bound import run_case

    known = json.loads(path.read_text()) if path.is_file() else {}
    for name in cases:
        system, _, wf, zf = CASES[name]
        if name in known:
            continue
        if wf is None:
            known[name] = WHITE_BOUND[system]
            continue
        case = run_case(system, wf, zf, rng=np.random.default_rng([seed, CASES[name][1]]))
        known[name] = dict(case["full"].sd)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(known, indent=1))
    return known


def _rows(table: Path) -> dict[str, list[dict]]:
    with table.open(newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r["status"] == "ok"]
    out: dict[str, list[dict]] = {}
    for r in rows:
        out.setdefault(r["record"].rsplit("-", 1)[0], []).append(r)
    return out


def _col(rows, key) -> np.ndarray:
    return np.array([float(r[key]) if r.get(key) not in (None, "") else math.nan for r in rows])


def _held(rows, truth, p, lo, hi) -> float:
    """The share of records whose interval ``[lo, hi]`` of ``p`` holds the truth."""
    return float(np.mean((truth >= _col(rows, f"{p}_{lo}")) & (truth <= _col(rows, f"{p}_{hi}"))))


def summarize(tables: dict[str, Path], bound: dict[str, dict]) -> list[dict]:
    """One row per case, model and parameter (module docstring)."""
    out = []
    for model, table in tables.items():
        for name, rows in _rows(table).items():
            for p in (*DRIFT, "S0", "wf", "zf", "rate"):
                if f"{p}_mean" not in rows[0] or f"true_{p}" not in rows[0]:
                    continue
                truth, mean = _col(rows, f"true_{p}"), _col(rows, f"{p}_mean")
                if np.all(np.isnan(truth)):
                    continue
                # a record whose fit dropped the term (the white force kept:
                # hosid.inference.settle) has no value of its parameter: its interval
                # holds nothing, and the mean is over the records that kept it
                kept = np.isfinite(mean)
                n = int(kept.sum())
                if n < 2:
                    continue
                se = np.std(mean[kept], ddof=1) / math.sqrt(n)
                bsd = bound.get(name, {}).get(p, math.nan)
                err = mean[kept] - truth[kept]
                out.append(
                    {
                        "case": name, "model": model, "param": p, "records": n,
                        "truth": float(truth[0]), "mean": float(np.mean(mean[kept])),
                        "bias_se": float(np.mean(err) / se) if se > 0 else math.nan,
                        "bias_bound_sd": float(np.mean(err) / bsd),
                        "tolerance_bound_sd": float(0.3 + 3 * se / bsd),
                        "cover90": _held(rows, truth, p, "q05", "q95"),
                        "cover50": _held(rows, truth, p, "q25", "q75"),
                        "efficiency": float(bsd**2 / np.mean(err**2)),
                    }
                )  # fmt: skip
    return out


def write(rows: list[dict], out: Path, title: str | None = None, shaped=None) -> Path:
    """``summary.csv`` and ``summary.md`` (``title`` and the cases ``shaped`` pooled for
    another study's records).
    """
    shaped = shaped or (lambda case: CASES[case][2] is not None)
    out.mkdir(parents=True, exist_ok=True)
    with (out / "summary.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]), lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    lines = [
        title
        or "# Narrow-band excitation: bias and coverage (issue 29)\n\n"
        "`python analyses/excitation_study.py`: independent simulator, the default fit with "
        "`--model paper,narrowband_excitation` and with `--model paper` on the same records. "
        "bias: mean error over its standard error (se) and in bound sd; tolerance: "
        "0.3 bound sd + 3 se; cover: share of records whose interval holds the truth; "
        "eff: bound variance / mean squared error; n: the records whose fit kept the "
        "parameter (a fit that keeps the white force has no wf, zf or rate: its interval "
        "holds nothing).",
        "",
        "| case | model | param | n | truth | mean | bias/se | bias/bound sd | tolerance "
        "| 90 % | 50 % | eff |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['case']} | {r['model']} | {r['param']} | {r['records']} | {r['truth']:.4g} "
            f"| {r['mean']:.4g} | {r['bias_se']:+.1f} | {r['bias_bound_sd']:+.2f} "
            f"| {r['tolerance_bound_sd']:.2f} | {r['cover90']:.2f} | {r['cover50']:.2f} "
            f"| {r['efficiency']:.2f} |"
        )
    pooled = {}
    for r in rows:
        if r["param"] in DRIFT and shaped(r["case"]):
            pooled.setdefault(r["model"], []).append(r)
    lines += ["", "Pooled over the drift coefficients of the non-white cases:", ""]
    for model, rs in pooled.items():
        w90 = sum(r["cover90"] * r["records"] for r in rs) / sum(r["records"] for r in rs)
        w50 = sum(r["cover50"] * r["records"] for r in rs) / sum(r["records"] for r in rs)
        lines.append(f"- {model}: 90 % intervals {w90:.3f}, 50 % intervals {w50:.3f}")
    path = out / "summary.md"
    path.write_text("\n".join(lines) + "\n")
    return path


def arguments(
    argv, doc: str, cases, work: Path, results: Path, models=MODELS
) -> argparse.Namespace:
    """The command line of a study of the excitation (this one's and ``impulse_study``'s)."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=list(cases), choices=list(cases))
    ap.add_argument("--records", type=int, default=10)
    ap.add_argument("--models", nargs="+", default=list(models), choices=list(models))
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--n-steps", type=int, default=None, help="fixed emcee steps per fit")
    ap.add_argument("--summary", action="store_true", help="only write the summary")
    ap.add_argument("--no-progress", action="store_true")
    ap.add_argument("--work", type=Path, default=work)
    ap.add_argument("--out", type=Path, default=results)
    return ap.parse_args(argv)


def keep_tables(tables: dict[str, Path], work: Path, out: Path) -> dict[str, Path]:
    """The result tables that exist (a model not run yet is left out), merged into
    ``out``: a run of some cases replaces their rows where they stand and keeps the other
    cases' rows.
    """
    tables = {m: t for m, t in tables.items() if t.is_file()}
    if not tables:
        raise SystemExit(f"{work}: no results yet; run the study first")
    out.mkdir(parents=True, exist_ok=True)
    kept = {}
    for m, t in tables.items():
        with t.open(newline="") as fh:
            new = list(csv.DictReader(fh))
        dest = out / f"{m}.csv"
        old = []
        if dest.is_file():
            with dest.open(newline="") as fh:
                old = list(csv.DictReader(fh))
        fresh = {r["record"]: r for r in new}  # in place: the tables keep their order
        rows = [fresh.pop(r["record"], r) for r in old] + list(fresh.values())
        fields = list(dict.fromkeys([*(new[0] if new else []), *(old[0] if old else [])]))
        with dest.open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=fields, lineterminator="\n", extrasaction="ignore")
            w.writeheader()
            w.writerows(rows)
        kept[m] = dest
    return kept


def main(argv: Sequence[str] | None = None) -> Path:
    """Run the study (unless ``--summary``) and write its summary."""
    args = arguments(argv, __doc__, CASES, WORK, RESULTS)
    tables = {m: args.work / m / "results.csv" for m in MODELS}
    if not args.summary:
        tables = run(
            args.cases, records=args.records, work=args.work, workers=args.workers,
            n_steps=args.n_steps, progress=not args.no_progress, models=args.models,
        )  # fmt: skip
    tables = keep_tables(tables, args.work, args.out)
    for m in MODELS:  # a model not rerun keeps its kept rows
        if m not in tables and (args.out / f"{m}.csv").is_file():
            tables[m] = args.out / f"{m}.csv"
    tables = {m: tables[m] for m in MODELS if m in tables}
    path = write(summarize(tables, bounds(args.cases, args.out / "bounds.json")), args.out)
    print(f"wrote {path}")
    return path


if __name__ == "__main__":
    main()
