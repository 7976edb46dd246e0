"""Coverage of the pseudo-posterior's credible intervals over replicated records.

For ``--records`` independent records of the paper oscillator (a1 = n1 = 0.5,
a2 = 25, n2 = 5, S0 = 100 by default), run :func:`hosid.sampling.fit` with the
default (calibrated) settings and record whether each parameter's 90 % (and 50 %)
equal-tailed credible interval contains the truth, with the fit time and the
convergence diagnostics.  The true equivalent damping uses the simulated velocity.

    python analyses/coverage_study.py --records 40 --cost J4A --out analyses/out

Writes ``coverage_<cost>.csv`` (one row per record and parameter) and
``coverage_<cost>.md`` (the coverage table).
"""

from __future__ import annotations

import argparse
import csv
import math
import time
import warnings
from pathlib import Path

import numpy as np

from hosid import results as R
from hosid.sampling import fit
from hosid.simulate import PAPER_PARAMS, simulate

PARAMS = ("a1", "n1", "a2", "n2", "S0", "a1eq")


def run(
    records: int,
    *,
    cost: str,
    S0: float,
    duration: float,
    seed: int,
    out: Path,
    constrained: bool = True,
    n_steps: int | None = None,
    n_bootstrap: int = 30,
) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    truth = dict(PAPER_PARAMS, S0=float(S0))
    rows = []
    for i, rng in enumerate(np.random.default_rng(seed).spawn(records)):
        rec, v = simulate(truth, duration=duration, rng=rng, return_velocity=True)
        a1eq = truth["a1"] + truth["n1"] * math.sqrt(8 / math.pi) * float(np.std(v))
        tv = dict(truth, a1eq=a1eq)
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            tree = fit(
                rec,
                cost=cost,
                constrained=constrained,
                seed=rng,
                progress=False,
                n_steps=n_steps,
                n_bootstrap=n_bootstrap,
                cost_map=False,
            )
            s = R.summarize(tree, warn=False)
        seconds = time.perf_counter() - t0
        post = tree["posterior"]
        for k in PARAMS:
            d = post[k].values.ravel()
            q = np.quantile(d, [0.05, 0.25, 0.5, 0.75, 0.95])
            rows.append(
                {
                    "record": i,
                    "param": k,
                    "truth": tv[k],
                    "q05": q[0],
                    "q25": q[1],
                    "q50": q[2],
                    "q75": q[3],
                    "q95": q[4],
                    "mean": float(np.mean(d)),
                    "in90": int(q[0] <= tv[k] <= q[4]),
                    "in50": int(q[1] <= tv[k] <= q[3]),
                    "r_hat": s["parameters"][k]["r_hat"],
                    "ess_bulk": s["parameters"][k]["ess_bulk"],
                    "ess_tail": s["parameters"][k]["ess_tail"],
                    "converged": int(s["converged"]),
                    "seconds": seconds,
                }
            )
        print(f"record {i}: {seconds:.1f} s, converged={s['converged']}", flush=True)
        # rewritten after every record, so that an interrupted study keeps its rows
        with (out / f"coverage_{cost}.csv").open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    kind = "constrained" if constrained else "unconstrained"
    lines = [
        f"Coverage of {cost} pseudo-posteriors ({kind}), {records} records of "
        f"{duration:g} s, S0 = {S0:g}",
        "",
        "| param | truth | 90 % coverage | 50 % coverage | mean of posterior means "
        "| median q50 | median 90 % width | max r_hat | min ess_bulk |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for k in PARAMS:
        r = [x for x in rows if x["param"] == k]
        lines.append(
            f"| {k} | {np.median([x['truth'] for x in r]):.3g} "
            f"| {100 * np.mean([x['in90'] for x in r]):.0f} % "
            f"| {100 * np.mean([x['in50'] for x in r]):.0f} % "
            f"| {np.mean([x['mean'] for x in r]):.3g} "
            f"| {np.median([x['q50'] for x in r]):.3g} "
            f"| {np.median([x['q95'] - x['q05'] for x in r]):.3g} "
            f"| {max(x['r_hat'] for x in r):.3f} | {min(x['ess_bulk'] for x in r):.0f} |"
        )
    secs = [x["seconds"] for x in rows if x["param"] == "a1"]
    conv = [x["converged"] for x in rows if x["param"] == "a1"]
    lines += [
        "",
        f"fit time: median {np.median(secs):.1f} s, max {np.max(secs):.1f} s; "
        f"{sum(conv)} of {len(conv)} fits converged (R-hat < 1.01, bulk and tail ESS >= 400)",
    ]
    md = out / f"coverage_{cost}.md"
    md.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return md


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=40)
    ap.add_argument("--cost", default="J4A", choices=("J2", "J4A", "J4B"))
    ap.add_argument("--S0", type=float, default=100.0)
    ap.add_argument("--duration", type=float, default=2000.0)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--steps", type=int, default=None)
    ap.add_argument("--bootstrap", type=int, default=30)
    ap.add_argument("--unconstrained", action="store_true")
    ap.add_argument("--out", type=Path, default=Path("analyses/out"))
    a = ap.parse_args(argv)
    run(
        a.records,
        cost=a.cost,
        S0=a.S0,
        duration=a.duration,
        seed=a.seed,
        out=a.out,
        constrained=not a.unconstrained,
        n_steps=a.steps,
        n_bootstrap=a.bootstrap,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
