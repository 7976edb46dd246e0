"""Issue 4: coverage of the term-model pseudo-posterior (hosid.modelfit) per parameter.

For each model of the confusion study (the true model of every scenario), records are
simulated and fitted with :func:`hosid.modelfit.fit_model`; the fraction of records
whose 90 % (and 50 %) intervals hold the truth, the bias and the spread of the
posterior mean are written to ``modelfit_coverage.csv`` and ``.md``.

    python analyses/modelfit_coverage.py [--records 40] [--quick]
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

from hosid.modelfit import fit_model
from hosid.simulate import PAPER_PARAMS, simulate
from hosid.terms import Model

PAPER = PAPER_PARAMS
LINEAR = {"a1": 3.0, "a2": 25.0, "S0": 100.0}
CASES = {
    "paper": PAPER,
    "linear": LINEAR,
    "linear,cubic_stiffness": {**LINEAR, "n2": 5.0},
    "paper,quadratic_stiffness": {**PAPER, "b2": 5.0},
    "paper,excitation_mean": {**PAPER, "m": 5.0},
    "paper,coulomb_friction": {**PAPER, "mu": 20.0},
    "paper,measurement_noise": {**PAPER, "noise_sd": 0.01},
    "paper,coloured_excitation": {**PAPER, "wc": 100.0},
    "paper,coloured_excitation ": {**PAPER, "wc": 30.0},  # trailing space: a 2nd strength
}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=40)
    ap.add_argument("--duration", type=float, default=2000.0)
    ap.add_argument("--seed", type=int, default=77)
    ap.add_argument("--quick", action="store_true", help="3 records of 600 s, two models")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "out")
    a = ap.parse_args(argv)
    out = a.out / "modelfit_coverage"
    out.mkdir(parents=True, exist_ok=True)
    cases = dict(list(CASES.items())[:2]) if a.quick else CASES
    n_rec, duration = (3, 600.0) if a.quick else (a.records, a.duration)
    rows = []
    for spec, truth in cases.items():
        model = Model.from_spec(spec.strip())
        t0 = time.perf_counter()
        hits90, hits50, means = [], [], []
        for i in range(n_rec):
            ss = np.random.SeedSequence([a.seed, i, sum(map(ord, spec))])
            s1, s2 = ss.spawn(2)
            rec = simulate(truth, duration=duration, dt=0.02, rng=np.random.default_rng(s1))
            fit = fit_model(rec, model, rng=np.random.default_rng(s2))
            iv90, iv50 = fit.interval(0.9), fit.interval(0.5)
            names = fit.param_names
            hits90.append([iv90[n][0] <= truth.get(n, 0) <= iv90[n][1] for n in names])
            hits50.append([iv50[n][0] <= truth.get(n, 0) <= iv50[n][1] for n in names])
            means.append(fit.draws.mean(axis=0))
        secs = (time.perf_counter() - t0) / n_rec
        h90, h50, mu = np.mean(hits90, 0), np.mean(hits50, 0), np.array(means)
        for j, n in enumerate(names):
            true = truth.get(n, 0.0)
            rows.append(
                {
                    "model": spec.strip(),
                    "truth": ", ".join(f"{k}={v:g}" for k, v in truth.items()),
                    "param": n,
                    "true": true,
                    "cover90": round(float(h90[j]), 3),
                    "cover50": round(float(h50[j]), 3),
                    "mean": round(float(mu[:, j].mean()), 5),
                    "sd_of_means": round(float(mu[:, j].std(ddof=1)), 5),
                    "records": n_rec,
                    "seconds_per_fit": round(secs, 2),
                }
            )
        print(f"{spec}: {secs:.2f} s per fit", flush=True)
    with open(out / "modelfit_coverage.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    lines = [
        "| model | truth | param | true | 90 % coverage | 50 % coverage | mean | sd of means |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['model']} | {r['truth']} | {r['param']} | {r['true']:g} | "
            f"{100 * r['cover90']:.0f} % | {100 * r['cover50']:.0f} % | {r['mean']:.4g} | "
            f"{r['sd_of_means']:.3g} |"
        )
    text = "\n".join(lines) + f"\n\n{n_rec} records of {duration:g} s per model.\n"
    (out / "modelfit_coverage.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
