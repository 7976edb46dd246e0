"""Accuracy table of every estimator and window over replicated simulations.

For each excitation level S0, each window and each method, simulate ``n``
independent records of the paper oscillator (a1 = n1 = 0.5, a2 = 25, n2 = 5) and
report the bias (median and mean error) and the spread (sd) of every estimate.
The true equivalent damping is a1 + n1 sqrt(8/pi) sigma_v with sigma_v from the
simulated velocity.

    python analyses/accuracy_table.py --records 10 --out analyses/out

Writes ``accuracy.csv`` (one row per record, method and window) and
``accuracy.md`` (the summary table).
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from pathlib import Path

import numpy as np

from hosid.estimators import estimate
from hosid.simulate import PAPER_PARAMS, simulate

PARAMS = ("a1", "n1", "a2", "n2", "S0", "a1eq")


def run(records: int, levels, windows, methods, duration: float, seed: int, out: Path) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    root = np.random.default_rng(seed)
    for S0 in levels:
        truth = dict(PAPER_PARAMS, S0=float(S0))
        for i, rng in enumerate(root.spawn(records)):
            rec, v = simulate(truth, duration=duration, rng=rng, return_velocity=True)
            a1eq = truth["a1"] + truth["n1"] * math.sqrt(8 / math.pi) * float(np.std(v))
            tv = dict(truth, a1eq=a1eq)
            for window in windows:
                for method in methods:
                    t0 = time.perf_counter()
                    est = estimate(rec, method=method, window=window)["estimates"]
                    row = {
                        "S0_true": S0,
                        "record": i,
                        "window": window,
                        "method": method,
                        "seconds": time.perf_counter() - t0,
                    }
                    for p in PARAMS:
                        row[p] = est[p]
                        row[p + "_true"] = tv[p]
                    rows.append(row)
            print(f"S0={S0} record {i + 1}/{records} done", flush=True)
    with open(out / "accuracy.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    (out / "accuracy.md").write_text(summarize(rows))
    return out / "accuracy.md"


def summarize(rows) -> str:
    lines = [
        "| S0 | window | method | param | truth | median est | mean err | sd | "
        "median abs rel err | s/fit |",
        "|" + "---|" * 10,
    ]
    keys = sorted(
        {(r["S0_true"], r["window"], r["method"]) for r in rows},
        key=lambda k: (k[0], k[1], ["moments", "J2", "paper", "J4A", "J4B"].index(k[2])),
    )
    for S0, window, method in keys:
        sel = [r for r in rows if (r["S0_true"], r["window"], r["method"]) == (S0, window, method)]
        secs = np.mean([r["seconds"] for r in sel])
        for p in PARAMS:
            est = np.array([r[p] for r in sel], dtype=float)
            if np.all(np.isnan(est)):
                continue
            tru = np.array([r[p + "_true"] for r in sel], dtype=float)
            err = est - tru
            lines.append(
                f"| {S0:g} | {window} | {method} | {p} | {np.mean(tru):.3g} | "
                f"{np.median(est):.3g} | {np.mean(err):+.3g} | {np.std(err, ddof=1):.3g} | "
                f"{np.median(np.abs(err / tru)) * 100:.1f} % | {secs:.1f} |"
            )
    return "\n".join(lines) + "\n"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=10)
    ap.add_argument("--levels", type=float, nargs="+", default=[25.0, 100.0, 400.0])
    ap.add_argument("--windows", nargs="+", default=["hann", "boxcar"])
    ap.add_argument("--methods", nargs="+", default=["moments", "J2", "paper", "J4A", "J4B"])
    ap.add_argument("--duration", type=float, default=2000.0)
    ap.add_argument("--seed", type=int, default=20261121)
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "out")
    a = ap.parse_args(argv)
    path = run(a.records, a.levels, a.windows, a.methods, a.duration, a.seed, a.out)
    print(path.read_text())


if __name__ == "__main__":
    main()
