"""Efficiency and calibration of hosid's fits against the information limit (issue 12).

For every regime of ``regimes.py`` and N records (default 10), a record is simulated
with the independent simulator (``independent_sim.py``, not hosid's own), fitted by
``hosid.inference.fit(record, cost=COST, seed=..., progress=False, with_map=False)``
and summarized; one row per record and parameter (a1, n1, a2, n2, S0, a1eq) is
appended to ``results/efficiency_<cost>.csv`` as soon as the fit ends, so a run can be
stopped and resumed (done ``(regime, record, cost)`` are skipped).  The summary step
(``efficiency_summary.py``) then writes ``efficiency_<cost>.md`` and ``.png`` against
the Cramer-Rao bounds of ``results/crb.csv`` (computed by ``crb.py`` when missing).

    python analyses/efficiency_study.py                          # default fit, 10 records
    python analyses/efficiency_study.py --cost J4A --jobs 2      # the paper's J4A
    python analyses/efficiency_study.py --summary                # tables and figure only
    python analyses/efficiency_study.py --regimes short --records 2 --n-steps 200

Seeds: record ``k`` of a regime with key ``r`` uses
``SeedSequence(seed).spawn(r + 1)[r].spawn(k + 1)[k]``, split once more into the
simulation's and the fit's generator; the same records are fitted for every cost.
The truth of a1eq is eq (65) at the simulated velocity's standard deviation.
"""

from __future__ import annotations

import argparse
import csv
import multiprocessing
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from crb import ensure
from efficiency_summary import write_summary
from independent_sim import simulate as independent_simulate
from regimes import Regime, select

from hosid.inference import COSTS, fit
from hosid.model import simulate as hosid_simulate
from hosid.output.results import attr, summarize

RESULTS = Path(__file__).resolve().parent / "results"
SEED = 20250112
PARAMS = ("a1", "n1", "a2", "n2", "S0", "a1eq")
FIELDS = (
    "regime",
    "record",
    "cost",
    "simulator",
    "seed",
    "S0_true",
    "duration",
    "dt",
    "sigma_v",
    "param",
    "truth",
    "mean",
    "sd",
    "q05",
    "q25",
    "q50",
    "q75",
    "q95",
    "draw_min",
    "r_hat",
    "ess_bulk",
    "ess_tail",
    "converged",
    "steps",
    "fit_seconds",
    "warnings",
    "error",
)


@dataclass(frozen=True)
class Task:
    """One record of one regime, to be simulated and fitted."""

    regime: Regime
    record: int
    cost: str
    seed: int
    simulator: str = "independent"
    n_steps: int | None = None


def record_seeds(
    seed: int, regime: Regime, record: int
) -> tuple[np.random.SeedSequence, np.random.SeedSequence]:
    """Seed sequences of the simulation and of the fit of one record."""
    ss = np.random.SeedSequence(seed).spawn(regime.key + 1)[regime.key]
    sim, fitting = ss.spawn(record + 1)[record].spawn(2)
    return sim, fitting


def simulate_record(task: Task):
    """The record of ``task`` and its simulated velocity."""
    sim_ss, _ = record_seeds(task.seed, task.regime, task.record)
    r, rng = task.regime, np.random.default_rng(sim_ss)
    name = f"{r.name}-{task.record}"
    if task.simulator == "independent":
        return independent_simulate(r.params, duration=r.duration, dt=r.dt, rng=rng, name=name)
    if task.simulator == "hosid":
        return hosid_simulate(
            r.params, duration=r.duration, dt=r.dt, rng=rng, name=name, return_velocity=True
        )
    raise ValueError(f"unknown simulator {task.simulator!r}")


def run_one(task: Task) -> list[dict]:
    """Simulate and fit one record; one row per parameter (a failed fit: NaN rows)."""
    record, v = simulate_record(task)
    sigma_v = float(np.std(v))
    truth = {**task.regime.params, "a1eq": task.regime.a1eq(sigma_v)}
    _, fit_ss = record_seeds(task.seed, task.regime, task.record)
    base = {
        "regime": task.regime.name,
        "record": task.record,
        "cost": task.cost,
        "simulator": task.simulator,
        "seed": task.seed,
        "S0_true": task.regime.S0,
        "duration": task.regime.duration,
        "dt": task.regime.dt,
        "sigma_v": sigma_v,
    }
    t0 = time.perf_counter()
    summary, tree, error = None, None, ""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            tree = fit(
                record,
                cost=None if task.cost == "default" else task.cost,
                seed=np.random.default_rng(fit_ss),
                progress=False,
                with_map=False,
                n_steps=task.n_steps,
            )
            summary = summarize(tree, warn=False)
        except Exception as exc:  # a failed fit is a result of the study, not a crash
            error = f"{type(exc).__name__}: {exc}"[:300]
    seconds = time.perf_counter() - t0
    messages = sorted({f"{w.category.__name__}: {w.message}"[:200] for w in caught})
    rows = []
    for p in PARAMS:
        row = {
            **base,
            "param": p,
            "truth": truth[p],
            "fit_seconds": round(seconds, 3),
            "warnings": " | ".join(messages),
            "error": error,
        }
        if summary is not None and tree is not None:
            s = summary["parameters"][p]
            row.update(
                {
                    k: s[k]
                    for k in (
                        "mean",
                        "sd",
                        "q05",
                        "q25",
                        "q50",
                        "q75",
                        "q95",
                        "r_hat",
                        "ess_bulk",
                        "ess_tail",
                    )
                }
            )
            row["draw_min"] = float(tree["posterior"][p].min())
            row["converged"] = int(summary["converged"])
            row["steps"] = attr(tree, "sampler", {}).get("steps", "")
        else:
            row.update({k: float("nan") for k in FIELDS if k not in row and k != "steps"})
            row.update({"converged": 0, "steps": ""})
        rows.append(row)
    return rows


def csv_path(out: Path, cost: str) -> Path:
    """``efficiency_<cost>.csv`` in ``out``."""
    return out / f"efficiency_{cost}.csv"


def done_keys(path: Path) -> set[tuple[str, int, str]]:
    """``(regime, record, cost)`` already in the CSV."""
    if not path.is_file():
        return set()
    with path.open(newline="") as fh:
        return {(r["regime"], int(r["record"]), r["cost"]) for r in csv.DictReader(fh)}


def append(path: Path, rows: Sequence[dict]) -> None:
    """Append rows (writing the header to a new file) and flush them to disk."""
    new = not path.is_file() or path.stat().st_size == 0
    with path.open("a", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=FIELDS)
        if new:
            w.writeheader()
        for row in rows:
            w.writerow({k: row.get(k, "") for k in FIELDS})
        fh.flush()


def _report(rows: Sequence[dict], done: int, total: int, t0: float) -> None:
    r = {row["param"]: row for row in rows}
    a1, n1 = r["a1"], r["n1"]
    status = a1["error"] or (
        f"a1 {a1['mean']:.3g} (truth {a1['truth']:.3g}), n1 {n1['mean']:.3g} "
        f"(truth {n1['truth']:.3g}), S0 {r['S0']['mean']:.4g}, "
        f"{'converged' if a1['converged'] else 'NOT converged'}, {a1['fit_seconds']:.1f} s"
    )
    print(
        f"[{done}/{total}, {time.perf_counter() - t0:.0f} s] {a1['regime']} "
        f"record {a1['record']}: {status}",
        flush=True,
    )


def run_study(
    regimes: Sequence[Regime],
    *,
    records: int,
    cost: str,
    out: Path,
    seed: int = SEED,
    jobs: int = 1,
    simulator: str = "independent",
    n_steps: int | None = None,
    verbose: bool = True,
) -> Path:
    """Fit every missing record of ``regimes`` and append its rows to the CSV.

    Parameters
    ----------
    regimes : sequence of Regime
    records : int
        Records per regime.
    cost : {"default", "J2", "J4A", "J4B"}
    out : Path
        Directory of ``efficiency_<cost>.csv``.
    seed : int
        Root seed (module docstring).
    jobs : int
        Worker processes (spawn context); 1 runs in this process.
    simulator : {"independent", "hosid"}
    n_steps : int, optional
        Fixed emcee steps per fit (default: fit's stopping rule).
    verbose : bool
        One line per finished record.

    Returns
    -------
    Path
        The CSV.
    """
    if cost not in ("default", *COSTS):
        raise ValueError(f"unknown cost {cost!r}; choose from default, {', '.join(COSTS)}")
    out.mkdir(parents=True, exist_ok=True)
    path = csv_path(out, cost)
    done = done_keys(path)
    tasks = [
        Task(r, k, cost, seed, simulator, n_steps)
        for r in regimes
        for k in range(records)
        if (r.name, k, cost) not in done
    ]
    if verbose:
        print(f"{len(tasks)} fits to run ({len(done)} records already in {path.name})", flush=True)
    t0 = time.perf_counter()
    if jobs <= 1:
        for i, task in enumerate(tasks, 1):
            rows = run_one(task)
            append(path, rows)
            if verbose:
                _report(rows, i, len(tasks), t0)
    elif tasks:
        with multiprocessing.get_context("spawn").Pool(jobs) as pool:
            for i, rows in enumerate(pool.imap_unordered(run_one, tasks), 1):
                append(path, rows)
                if verbose:
                    _report(rows, i, len(tasks), t0)
    return path


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
    ap.add_argument("--jobs", type=int, default=1, help="worker processes")
    ap.add_argument("--simulator", default="independent", choices=("independent", "hosid"))
    ap.add_argument("--n-steps", type=int, default=None, help="fixed emcee steps per fit")
    ap.add_argument("--summary", action="store_true", help="only write the summary")
    ap.add_argument("--crb-seed", type=int, default=20250112)
    ap.add_argument(
        "--crb-sim-duration",
        type=float,
        default=None,
        help="long-simulation length for missing bounds (default crb.py's)",
    )
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    regimes = select(args.regimes)
    if not args.summary:
        run_study(
            regimes,
            records=args.records,
            cost=args.cost,
            out=args.out,
            seed=args.seed,
            jobs=args.jobs,
            simulator=args.simulator,
            n_steps=args.n_steps,
        )
    path = csv_path(args.out, args.cost)
    if not path.is_file():
        raise SystemExit(f"{path}: no results yet; run the study first")
    with path.open(newline="") as fh:
        names = {r["regime"] for r in csv.DictReader(fh)}
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
