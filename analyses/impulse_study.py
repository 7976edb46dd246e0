"""Poisson impulses (issue 29): bias and coverage of the default fit with
``--model paper,impulsive_excitation`` and with the white model ``--model paper`` on the
same records of the independent simulator.

Records: ``independent_sim.py`` with ``rate`` (impulses at the times of a Poisson
process, Gaussian areas of variance ``2 pi S0 / rate``: the white spectrum ``S0``),
``--records`` (default 10) per case, the paper oscillator at 0.5, 1 and 2 impulses a
second (S0 = 100, 2000 s at 0.02 s) and the ship-roll-like one at 0.5 a second, and
white records of both (what the impulsive term costs where there are no impulses: the
efficiency of its fit beside the white model's).  Fitted
through ``hosid batch`` (resumable).  The summary (``results/impulses/summary.md``,
``.csv``; the tables of ``excitation_study.py``) sets bias and coverage beside the white
force's information limit (``crb.md``): a Gaussian force's bound, a reference only (a
non-Gaussian force can carry more information).

    python analyses/impulse_study.py                 # run and summarize
    python analyses/impulse_study.py --summary       # summary only
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

from excitation_study import (
    PAPER,
    SYSTEMS,
    WHITE_BOUND,
    arguments,
    keep_tables,
    summarize,
    write,
)

from hosid.batch import design_tasks, read_design, run_batch

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results" / "impulses"
WORK = HERE / "out" / "impulses"
SEED = 20261126
#: name: (system, key, impulses a second)
CASES = {
    "paper_kicks_0.5": ("paper", 21, 0.5),
    "paper_kicks_1": ("paper", 22, 1.0),
    "paper_kicks_2": ("paper", 23, 2.0),
    "ship_kicks_0.5": ("ship", 24, 0.5),
    "paper_white": ("paper", 25, None),  # what the impulsive term costs on white records
    "ship_white": ("ship", 26, None),
}
MODELS = {"impulsive": "paper,impulsive_excitation", "white": "paper"}


def write_design(cases: Sequence[str], path: Path, records: int) -> Path:
    """One design row per case, ``records`` seeds each."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fields = ["name", "key", "seeds", "duration", "dt", "simulator", *PAPER, "rate"]
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields, lineterminator="\n")
        w.writeheader()
        for name in cases:
            system, key, rate = CASES[name]
            params, T, dt = SYSTEMS[system]
            w.writerow(
                {"name": name, "key": key, "seeds": records, "duration": T, "dt": dt,
                 "simulator": f"{HERE / 'independent_sim.py'}:simulate", **params,
                 "rate": "" if rate is None else rate}
            )  # fmt: skip
    return path


def main(argv: Sequence[str] | None = None) -> Path:
    """Run the study (unless ``--summary``) and write its summary."""
    args = arguments(argv, __doc__, CASES, WORK, RESULTS, models=MODELS)
    # the impulsive model's fits before the sampling-bias correction (commit 7f97d23),
    # kept beside the corrected ones; not re-run
    tables = {m: args.work / m / "results.csv" for m in (*MODELS, "impulsive_uncorrected")}
    if not args.summary:
        design = write_design(args.cases, args.work / "design.csv", args.records)
        for label in args.models:
            spec = MODELS[label]
            tasks = design_tasks(
                read_design(design), analysis="fit", seed=SEED, folder=design.parent,
                options={"model": spec, "n_steps": args.n_steps},
            )  # fmt: skip
            res = run_batch(
                tasks, args.work / label, workers=args.workers,
                progress=not args.no_progress, label=f"impulses {label}",
            )  # fmt: skip
            tables[label] = res.tables[0]
    tables = keep_tables(tables, args.work, args.out)
    for m in (*MODELS, "impulsive_uncorrected"):  # a model not rerun keeps its kept rows
        if m not in tables and (args.out / f"{m}.csv").is_file():
            tables[m] = args.out / f"{m}.csv"
    tables = {m: tables[m] for m in (*MODELS, "impulsive_uncorrected") if m in tables}
    bound = {name: WHITE_BOUND[CASES[name][0]] for name in CASES}
    title = (
        "# Poisson impulses: bias and coverage (issue 29)\n\n"
        "`python analyses/impulse_study.py`: independent simulator, the default fit with "
        "`--model paper,impulsive_excitation` and with `--model paper` on the same records. "
        "bias: mean error over its standard error (se) and in units of the white Gaussian "
        "force's bound (a reference); tolerance: 0.3 bound sd + 3 se; cover: share of "
        "records whose interval holds the truth; eff: bound variance / mean squared error; "
        "n: the records whose fit kept the parameter (a fit that keeps the white force has "
        "no rate: its interval holds nothing)."
    )
    kicked = [c for c in CASES if CASES[c][2] is not None]
    path = write(summarize(tables, bound), args.out, title=title, shaped=kicked.__contains__)
    print(f"wrote {path}")
    return path


if __name__ == "__main__":
    main()
