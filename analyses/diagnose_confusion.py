"""Issue 4: the confusion table of the discrepancy workflow (hidden vs named effect).

For every scenario (one hidden effect that the base model lacks, or none) records are
simulated, ``hosid.check.diagnose.diagnose`` is run with its defaults, and the named
effects (joined by ``+``), the gaps before and after, and whether the final model's 90 %
intervals cover the true parameters are written to ``confusion.csv`` (one row per
record, appended as soon as it is done) and summarized in ``confusion.md``.  (Issue 15's
power study, ``diagnose_power.py``, measures the same against the information limit on
the independent simulator's records.)

    python analyses/diagnose_confusion.py                      # 5 records per scenario
    python analyses/diagnose_confusion.py --records 2 --quick  # a smoke run
    python analyses/diagnose_confusion.py --replot             # table from the CSV

Scenarios: the paper oscillator (a1 = n1 = 0.5, a2 = 25, n2 = 5, S0 = 100) with
``paper`` as base and one of quadratic_stiffness (b2), excitation_mean (m),
coulomb_friction (mu), measurement_noise (noise_sd), coloured_excitation (wc); a
linear oscillator (a1 = 3, a2 = 25, S0 = 100) with ``linear`` as base and hidden
quadratic_damping (the paper oscillator without n2) or cubic_stiffness (n2); and
both bases with nothing hidden.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import multiprocessing
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from hosid.model import PAPER_PARAMS

#: workers are spawned: a forked child of a process that ran OpenMP kernels aborts
SPAWN = multiprocessing.get_context("spawn")

PAPER = PAPER_PARAMS
LINEAR = {"a1": 3.0, "a2": 25.0, "S0": 100.0}

#: name -> (base, true simulator parameters, hidden effect or None, strength label)
SCENARIOS: dict[str, tuple[str, dict, str | None, str]] = {
    "none (paper)": ("paper", PAPER, None, ""),
    "quadratic_stiffness": ("paper", {**PAPER, "b2": 5.0}, "quadratic_stiffness", "b2 = 5"),
    "excitation_mean": ("paper", {**PAPER, "m": 5.0}, "excitation_mean", "m = 5"),
    "coulomb_friction": ("paper", {**PAPER, "mu": 20.0}, "coulomb_friction", "mu = 20"),
    "measurement_noise": (
        "paper",
        {**PAPER, "noise_sd": 0.01},
        "measurement_noise",
        "noise_sd = 0.01 (0.9 % of sigma_x)",
    ),
    "coloured_excitation": (
        "paper",
        {**PAPER, "wc": 100.0},
        "coloured_excitation",
        "wc = 100 rad/s (19 w_n)",
    ),
    "coulomb_friction, stronger": (
        "paper",
        {**PAPER, "mu": 40.0},
        "coulomb_friction",
        "mu = 40",
    ),
    "measurement_noise, stronger": (
        "paper",
        {**PAPER, "noise_sd": 0.02},
        "measurement_noise",
        "noise_sd = 0.02",
    ),
    "coloured_excitation, stronger": (
        "paper",
        {**PAPER, "wc": 30.0},
        "coloured_excitation",
        "wc = 30 rad/s (6 w_n)",
    ),
    "none (linear)": ("linear", LINEAR, None, ""),
    "quadratic_damping": (
        "linear",
        {"a1": 0.5, "n1": 0.5, "a2": 25.0, "S0": 100.0},
        "quadratic_damping",
        "n1 = 0.5 (a1 = 0.5)",
    ),
    "cubic_stiffness": ("linear", {**LINEAR, "n2": 5.0}, "cubic_stiffness", "n2 = 5"),
}

#: Weaker strengths, near the detection limit (run with --weak): how the workflow
#: fails when an effect is too small to see.
WEAK: dict[str, tuple[str, dict, str | None, str]] = {
    "quadratic_stiffness, weaker": (
        "paper",
        {**PAPER, "b2": 2.0},
        "quadratic_stiffness",
        "b2 = 2",
    ),
    "excitation_mean, weaker": ("paper", {**PAPER, "m": 2.0}, "excitation_mean", "m = 2"),
    "coulomb_friction, weaker": ("paper", {**PAPER, "mu": 10.0}, "coulomb_friction", "mu = 10"),
    "measurement_noise, weaker": (
        "paper",
        {**PAPER, "noise_sd": 0.005},
        "measurement_noise",
        "noise_sd = 0.005",
    ),
    "coloured_excitation, weaker": (
        "paper",
        {**PAPER, "wc": 200.0},
        "coloured_excitation",
        "wc = 200 rad/s (38 w_n)",
    ),
}
DEFAULT = tuple(SCENARIOS)
SCENARIOS.update(WEAK)

FIELDS = (
    "scenario",
    "record",
    "base",
    "hidden",
    "named",
    "correct",
    "gap_before",
    "z_before",
    "p_before",
    "gap_after",
    "ratio",
    "best_other",
    "covered",
    "n_params",
    "seconds",
    "estimate",
    "candidate_gaps",
    "null_gaps",
)


def run_one(args: tuple[str, int, int, float, int]) -> dict:
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    from hosid.check.diagnose import diagnose
    from hosid.model import simulate

    name, index, seed, duration, replicates = args
    base, truth, hidden, _ = SCENARIOS[name]
    ss = np.random.SeedSequence([seed, index, sum(map(ord, name))])
    sim_seed, diag_seed = ss.spawn(2)
    record = simulate(truth, duration=duration, dt=0.02, rng=np.random.default_rng(sim_seed))
    t0 = time.perf_counter()
    d = diagnose(record, base, rng=np.random.default_rng(diag_seed), replicates=replicates)
    rep = d.report()
    final = rep["final_fit"]
    covered = []
    for p, (lo, hi) in final["interval90"].items():
        true = truth.get(p, 0.0)
        covered.append(int(lo <= true <= hi))
    ok = [c for c in rep["candidates"] if c.get("gap") is not None and "error" not in c]
    others = [c for c in ok if c["effect"] not in rep["named_effects"]]
    return {
        "scenario": name,
        "record": index,
        "base": base,
        "hidden": hidden or "none",
        "named": "+".join(rep["named_effects"]) or "none",
        "correct": int(rep["named_effects"] == ([hidden] if hidden else [])),
        "gap_before": round(rep["gap_before"], 3),  # inf if the base diverges
        "z_before": round(rep["z_before"], 2),
        "p_before": round(rep["p_before"], 3),
        "gap_after": round(rep["gap_after"], 3),
        "ratio": round(rep["gap_after"] / rep["gap_before"], 3),
        "best_other": f"{others[0]['effect']}={others[0]['gap']:.2f}" if others else "",
        "covered": sum(covered),
        "n_params": len(covered),
        "seconds": round(time.perf_counter() - t0, 1),
        "estimate": json.dumps({k: round(v, 5) for k, v in final["estimate"].items()}),
        "candidate_gaps": json.dumps({c["effect"]: round(c["gap"], 3) for c in ok}),
        "null_gaps": json.dumps([round(g, 3) for g in rep["base_fit"]["null_gaps"]]),
    }


def table(rows: list[dict]) -> str:
    named_cols = sorted({r["named"] for r in rows} | {"none"}, key=lambda n: (n != "none", n))
    lines = [
        "| scenario | strength | records | correct | "
        + " | ".join(f"named {c}" for c in named_cols)
        + " | gap before (median, range) | z before (min-max) | gap after (median, range) "
        "| after/before (max) | final 90 % intervals covering the truth |",
        "|" + "---|" * (9 + len(named_cols)),
    ]
    for s in SCENARIOS:
        rs = [r for r in rows if r["scenario"] == s]
        if not rs:
            continue
        counts = {c: sum(r["named"] == c for r in rs) for c in named_cols}
        gb = np.array([float(r["gap_before"]) for r in rs])
        ga = np.array([float(r["gap_after"]) for r in rs])
        zb = np.array([float(r["z_before"]) for r in rs])
        ratio = np.array([float(r["ratio"]) for r in rs])
        cov = sum(int(r["covered"]) for r in rs)
        npar = sum(int(r["n_params"]) for r in rs)
        lines.append(
            f"| {s} | {SCENARIOS[s][3]} | {len(rs)} | {sum(int(r['correct']) for r in rs)} | "
            + " | ".join(str(counts[c]) for c in named_cols)
            + f" | {np.median(gb):.2f} ({gb.min():.2f}-{gb.max():.2f})"
            f" | {zb.min():.1f}-{zb.max():.1f}"
            f" | {np.median(ga):.2f} ({ga.min():.2f}-{ga.max():.2f})"
            f" | {ratio.max():.2f} | {cov}/{npar} ({100 * cov / max(npar, 1):.0f} %) |"
        )
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=5, help="records per scenario")
    ap.add_argument("--duration", type=float, default=2000.0)
    ap.add_argument("--seed", type=int, default=4)
    ap.add_argument("--replicates", type=int, default=20)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", nargs="*", default=None, help="scenario names")
    ap.add_argument("--weak", action="store_true", help="also the weaker strengths (WEAK)")
    ap.add_argument("--quick", action="store_true", help="600 s records, 19 replicates")
    ap.add_argument("--replot", action="store_true", help="rewrite the table from the CSV")
    ap.add_argument("--append", action="store_true", help="add rows to an existing CSV")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "out")
    a = ap.parse_args(argv)
    out = a.out / "diagnose_confusion"
    out.mkdir(parents=True, exist_ok=True)
    path = out / "confusion.csv"
    if not a.replot:
        duration, reps = (600.0, 19) if a.quick else (a.duration, a.replicates)
        names = a.only or list(DEFAULT) + (list(WEAK) if a.weak else [])
        unknown = [n for n in names if n not in SCENARIOS]
        if unknown:
            print(f"unknown scenario(s): {unknown}; known: {list(SCENARIOS)}", file=sys.stderr)
            return 2
        jobs = [(n, i, a.seed, duration, reps) for i in range(a.records) for n in names]
        append = a.append and path.exists()
        with open(path, "a" if append else "w", newline="") as fh:
            w = csv.DictWriter(fh, FIELDS)
            if not append:
                w.writeheader()
            if a.jobs > 1:
                ex = ProcessPoolExecutor(max_workers=a.jobs, mp_context=SPAWN)
                results = ex.map(run_one, jobs)
            else:  # in this process (also when the module is loaded by a test)
                ex, results = None, map(run_one, jobs)
            try:
                for row in results:
                    w.writerow(row)
                    fh.flush()
                    print(
                        f"{row['scenario']:20s} #{row['record']} named {row['named']:20s} "
                        f"G {row['gap_before']:.2f} (z {row['z_before']:.1f}) -> "
                        f"{row['gap_after']:.2f} ({row['seconds']:.0f} s)",
                        flush=True,
                    )
            finally:
                if ex is not None:
                    ex.shutdown()
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    md = out / "confusion.md"
    md.write_text(table(rows))
    print(md.read_text())
    if not rows or any(math.isnan(float(r["gap_before"])) for r in rows):
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
