"""Efficiency and calibration of hosid's fits against the information limit (issue 12),
run through ``hosid batch simulate-study`` (issue 14).

For every regime of ``regimes.py`` and N records (default 10), the study writes a
design table (one row per regime: its parameters, record length, ``seeds = N`` and the
regime's fixed seed key) and runs it with ``hosid batch``: each record is simulated in a
dask worker with the independent simulator (``independent_sim.py``, not hosid's own),
fitted by ``hosid.fit(record, cost=COST, ...)`` and summarized into one row of the
batch's ``results.csv`` as soon as it ends.  The batch folder (default
``analyses/out/efficiency_<cost>/``) keeps every finished record: an interrupted run
resumes, and ``--records 20`` fits only records 10-19.  The same study by hand::

    hosid batch simulate-study analyses/out/efficiency_default/design.csv \\
        --out analyses/out/efficiency_default --seed 20250112 --workers 2

The table is copied to ``results/efficiency_<cost>.csv`` and the summary step
(``efficiency_summary.py``) writes ``efficiency_<cost>.md`` and ``.png`` from it against
the Cramer-Rao bounds of ``results/crb.csv`` (computed by ``crb.py`` when missing).

    python analyses/efficiency_study.py                          # default fit, 10 records
    python analyses/efficiency_study.py --cost J4A --workers 2   # the paper's J4A
    python analyses/efficiency_study.py --summary                # tables and figure only
    python analyses/efficiency_study.py --regimes short --records 2 --n-steps 200

Seeds: record ``k`` of the regime with key ``r`` is the batch task ``(r, k)``:
``SeedSequence(seed).spawn(r + 1)[r].spawn(k + 1)[k]``, whose two children drive the
simulation and the fit (the same records as before the port); every cost sees the same
records.  The truth of a1eq is eq (65) at the simulated velocity's standard deviation.
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
from collections.abc import Sequence
from pathlib import Path

from crb import ensure
from efficiency_summary import write_summary
from regimes import Regime, select

from hosid.batch import design_tasks, read_design, run_batch
from hosid.inference import COSTS

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
WORK = HERE / "out"
SEED = 20250112
SIMULATORS = {"independent": HERE / "independent_sim.py", "hosid": None}
DESIGN_FIELDS = (
    "name",
    "key",
    "seeds",
    "duration",
    "dt",
    "simulator",
    "a1",
    "n1",
    "a2",
    "n2",
    "S0",
)


def write_design(
    regimes: Sequence[Regime], path: Path, *, records: int, simulator: str = "independent"
) -> Path:
    """The study's design table: one row per regime, ``records`` seeds each."""
    sim = SIMULATORS[simulator]
    ref = "hosid" if sim is None else f"{os.path.relpath(sim, path.parent)}:simulate"
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=DESIGN_FIELDS, lineterminator="\n")
        w.writeheader()
        for r in regimes:
            w.writerow(
                {
                    "name": r.name,
                    "key": r.key,
                    "seeds": records,
                    "duration": r.duration,
                    "dt": r.dt,
                    "simulator": ref,
                    **r.params,
                }
            )
    return path


def run_study(
    regimes: Sequence[Regime],
    *,
    records: int,
    cost: str,
    work: Path,
    seed: int = SEED,
    workers: int | None = None,
    scheduler: str | None = None,
    simulator: str = "independent",
    n_steps: int | None = None,
    progress: bool = True,
) -> Path:
    """Fit every missing record of ``regimes`` with ``hosid batch``; return its table.

    Parameters
    ----------
    regimes : sequence of Regime
    records : int
        Records per regime.
    cost : {"default", "J2", "J4A", "J4B"}
    work : Path
        The batch's folder (its design, finished records and ``results.csv``).
    seed : int
        Root seed (module docstring).
    workers, scheduler
        A local cluster of ``workers`` processes (default one per core), or an existing
        dask scheduler.
    simulator : {"independent", "hosid"}
    n_steps : int, optional
        Fixed emcee steps per fit (default: fit's stopping rule).
    progress : bool
        The batch's progress bar.
    """
    if cost not in ("default", *COSTS):
        raise ValueError(f"unknown cost {cost!r}; choose from default, {', '.join(COSTS)}")
    design = write_design(regimes, work / "design.csv", records=records, simulator=simulator)
    options = {"cost": None if cost == "default" else cost, "n_steps": n_steps}
    tasks = design_tasks(
        read_design(design), analysis="fit", options=options, seed=seed, folder=design.parent
    )
    res = run_batch(
        tasks,
        work,
        workers=workers,
        scheduler=scheduler,
        progress=progress,
        label=f"efficiency {cost}",
    )
    print(
        f"{res.ran} fits run, {res.skipped} done before ({res.counts['ok']} ok, "
        f"{res.counts['error'] + res.counts['rejected']} failed) in {res.seconds:.0f} s",
        flush=True,
    )
    return res.tables[0]


def csv_path(out: Path, cost: str) -> Path:
    """``efficiency_<cost>.csv`` in ``out``: the batch's ``results.csv``, copied."""
    return out / f"efficiency_{cost}.csv"


def main(argv: Sequence[str] | None = None) -> dict:
    """Run the study for one cost, then write its summary; returns the summary."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--cost",
        default="default",
        choices=("default", *COSTS),
        help="default: fit's default components (cost=None)",
    )
    ap.add_argument("--regimes", nargs="+", default=None, help="default: all")
    ap.add_argument("--records", type=int, default=10, help="records per regime")
    ap.add_argument("--seed", type=int, default=SEED)
    ap.add_argument("--workers", type=int, default=None, help="default: one per core")
    ap.add_argument("--scheduler", default=None, help="an existing dask scheduler")
    ap.add_argument("--simulator", default="independent", choices=tuple(SIMULATORS))
    ap.add_argument("--n-steps", type=int, default=None, help="fixed emcee steps per fit")
    ap.add_argument("--no-progress", action="store_true")
    ap.add_argument("--summary", action="store_true", help="only write the summary")
    ap.add_argument("--crb-seed", type=int, default=20250112)
    ap.add_argument(
        "--crb-sim-duration",
        type=float,
        default=None,
        help="long-simulation length for missing bounds (default crb.py's)",
    )
    ap.add_argument("--out", type=Path, default=RESULTS, help="tables and figures")
    ap.add_argument("--work", type=Path, default=None, help="default out/efficiency_<cost>")
    args = ap.parse_args(argv)
    path = csv_path(args.out, args.cost)
    if not args.summary:
        work = args.work or WORK / f"efficiency_{args.cost}"
        table = run_study(
            select(args.regimes),
            records=args.records,
            cost=args.cost,
            work=work,
            seed=args.seed,
            workers=args.workers,
            scheduler=args.scheduler,
            simulator=args.simulator,
            n_steps=args.n_steps,
            progress=not args.no_progress,
        )
        args.out.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(table, path)
    if not path.is_file():
        raise SystemExit(f"{path}: no results yet; run the study first")
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    if rows and "design" not in rows[0]:
        raise SystemExit(f"{path} predates hosid batch (one row per parameter); rerun the study")
    names = {r["design"] for r in rows}
    bounds = ensure(
        [r for r in select(None) if r.name in names],
        args.out,
        seed=args.crb_seed,
        sim_duration=args.crb_sim_duration,
    )
    summary = write_summary(path, bounds, args.out, args.cost)
    print(f"wrote {summary['markdown']} and {summary['figure']}")
    return summary


if __name__ == "__main__":
    main()
