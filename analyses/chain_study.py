r"""Efficiency and calibration of chain fits against the full-state bound (issue 32, items 6-7).

For each case (the 2- and 3-dof chains of ``chain_bound.py`` from displacement records,
the 2-dof chain from acceleration records) the study simulates N records (default 10)
of 2000 s at dt = 0.02 with the independent chain simulator (``independent_chain_sim.py``:
a BAOAB splitting, not hosid's Heun method), writes them as ``.npz`` files with their
truths, and fits each with hosid's batch engine (:func:`hosid.batch.run_batch`, the
engine of ``hosid batch fit RECORDS --model SYSTEM.toml``: default components, the eq-65
constraint, emcee until converged) in dask workers.  The batch folders
(``analyses/out/chain_<case>/``) keep every finished fit: an interrupted run resumes,
``--records 20`` adds records 10-19.

Per element coefficient: the bias in bound sds, the efficiency of the posterior mean,
``bound variance / MSE`` (the full-state bound of ``results/chain_bound.csv``: masses and
force levels known, T = 2000 s), and the coverage of the 90 % (q05-q95) and 50 %
(q25-q75) intervals; the masses' and levels' coverage; R-hat and bulk and tail ESS; the
seconds a fit.  Beside them, what the identities can reach at best
(:func:`identity_efficiency`: their efficient GMM with the full state observed and the
masses and levels known, from one 20 000 s simulation).

    python analyses/chain_study.py                       # 10 records a case, 2 workers
    python analyses/chain_study.py --cases chain2 --records 2 --quick   # the tests'
    python analyses/chain_study.py --summary             # tables only
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import independent_chain_sim  # noqa: E402
from chain_bound import SYSTEMS, system  # noqa: E402

from hosid.batch import record_tasks, run_batch  # noqa: E402
from hosid.components.chain_identities import rows  # noqa: E402
from hosid.model.chain import simulate_chain  # noqa: E402
from hosid.model.system import System  # noqa: E402
from hosid.record import write_record  # noqa: E402

RESULTS = HERE / "results"
WORK = HERE / "out"
SEED = 20260321
#: case -> (system, what the records measure)
CASES = {
    "chain2": ("chain2", "displacement"),
    "chain3": ("chain3", "displacement"),
    "chain2-acc": ("chain2", "acceleration"),
}


def identity_efficiency(s: System, q: np.ndarray, v: np.ndarray, duration: float) -> dict:
    r"""What the generator identities (:mod:`hosid.components.chain_identities`) reach with
    the full state observed and the masses and levels known: each identity's block value is
    a martingale increment of :math:`\nabla_vG_a\cdot\sigma dW` (plus boundary terms), so
    their efficient GMM has :math:`\mathrm{avar} = (D^{\mathsf T}S^{-1}D)^{-1}/T` with
    :math:`S_{ab} = E[h_a^{\mathsf T}\Sigma h_b]`, :math:`D_{ac} = -\sum_d\mu_d
    E[\Phi_{dc}h_{ad}]`, :math:`h_a = \nabla_vG_a` and :math:`\Sigma = \mathrm{diag}(2\pi
    S_{0,d}/m_d^2)`; the bound is :math:`(D_*^{\mathsf T}S_*^{-1}D_*)^{-1}/T` of the score.
    Returns the ratio of variances (bound / identities) per coefficient.
    """
    th = s.vector()
    mu = 1.0 / s.mass_vector(th)
    Sig = 2.0 * math.pi * s.levels(th) * mu**2
    Phi = s.features(q, v)  # (N, n, p)
    B = s.incidence
    r, rd = q @ B.T, v @ B.T
    H = []
    for w in rows(s):
        e, t = s.columns[w.col]
        f = t.test(rd[:, e], scale=float(rd[:, e].std())) if w.kind == "v" else t.phi(r[:, e])
        H.append(f[:, None] * np.asarray(w.g)[None, :])
    H = np.stack(H, axis=-1)  # (N, n, A)
    S = np.einsum("nda,d,ndb->ab", H, Sig, H) / len(q)
    D = -np.einsum("d,ndc,nda->ac", mu, Phi, H) / len(q)
    avar = np.linalg.inv(D.T @ np.linalg.solve(S, D)) / duration
    J = -mu[None, :, None] * Phi
    info = duration * np.einsum("ndp,d,ndq->pq", J, 1.0 / Sig, J) / len(q)
    bound = np.linalg.inv(info)
    names = s.param_names[: s.n_drift]
    return dict(zip(names, (np.diag(bound) / np.diag(avar)).tolist(), strict=True))


def toml_text(name: str, measured: str) -> str:
    """The system file of a case (``measured`` declared for accelerations)."""
    head = f'measured = "{measured}"\n' if measured == "acceleration" else ""
    return head + SYSTEMS[name]


def prepare(case: str, n: int, folder: Path, seed: int = SEED) -> list[Path]:
    """The case's system file and records 0 .. n - 1 (simulated where missing)."""
    name, measured = CASES[case]
    folder.mkdir(parents=True, exist_ok=True)
    toml = folder / f"{name}.toml"
    toml.write_text(toml_text(name, measured))
    s = system(name)
    key = list(CASES).index(case)
    paths = []
    for i in range(n):
        path = folder / "records" / f"{case}-{i:03d}.npz"
        paths.append(path)
        if path.exists():
            continue
        path.parent.mkdir(exist_ok=True)
        ss = np.random.SeedSequence(seed).spawn(key + 1)[key].spawn(i + 1)[i]
        rec = independent_chain_sim.simulate(
            s, duration=2000.0, dt=0.02, rng=np.random.default_rng(ss), measured=measured,
            name=path.stem,
        )  # fmt: skip
        tmp = path.with_suffix(".tmp.npz")
        write_record(rec, tmp)
        tmp.replace(path)
        path.with_suffix(".truths.json").write_text(json.dumps(dict(s.values), indent=1))
    return paths


def fit_case(case: str, paths: Sequence[Path], folder: Path, workers: int, steps=None,
             seed: int = SEED):  # fmt: skip
    """Fit the records through the batch engine (resumable)."""
    name, _ = CASES[case]
    options = {"model": str(folder / f"{name}.toml")}
    if steps:
        options["n_steps"] = steps
    tasks = record_tasks([str(p) for p in paths], analysis="fit", options=options, seed=seed)
    return run_batch(tasks, folder / "batch", workers=workers, progress=False,
                     label=f"chain study {case}")  # fmt: skip


def _bounds() -> dict:
    out = {}
    with (RESULTS / "chain_bound.csv").open() as fh:
        for row in csv.DictReader(fh):
            out.setdefault(row["system"], {})[row["coefficient"]] = float(row["sd"])
    return out


def _value(row, key):
    v = row.get(key)
    return float(v) if v not in (None, "") else math.nan


def summarize(case: str, folder: Path) -> dict:
    """Per-parameter statistics of a case's fits (module docstring)."""
    name, _ = CASES[case]
    s = system(name)
    sd_bound = _bounds()[name]
    with (folder / "batch" / "results.csv").open() as fh:
        table = [r for r in csv.DictReader(fh) if r.get("status") == "ok"]
    truth = dict(s.values)
    per = {}
    for p in s.param_names:
        mean = np.array([_value(r, f"{p}_mean") for r in table])
        t = truth[p]
        inside90 = [_value(r, f"{p}_q05") <= t <= _value(r, f"{p}_q95") for r in table]
        inside50 = [_value(r, f"{p}_q25") <= t <= _value(r, f"{p}_q75") for r in table]
        err = mean - t
        row = {
            "n": len(table),
            "truth": t,
            "mean": float(np.mean(mean)),
            "bias": float(np.mean(err)),
            "rmse": float(np.sqrt(np.mean(err**2))),
            "post_sd": float(np.sqrt(np.mean([_value(r, f"{p}_sd") ** 2 for r in table]))),
            "cover90": int(sum(inside90)),
            "cover50": int(sum(inside50)),
            "rhat": max(_value(r, f"{p}_r_hat") for r in table),
            "ess": min(min(_value(r, f"{p}_ess_bulk"), _value(r, f"{p}_ess_tail")) for r in table),
        }
        if p in sd_bound:
            row["bound_sd"] = sd_bound[p]
            row["efficiency"] = sd_bound[p] ** 2 / float(np.mean(err**2))
            row["bias_bound_sd"] = row["bias"] / sd_bound[p]
        per[p] = row
    seconds = [_value(r, "fit_seconds") for r in table]
    return {"case": case, "params": per, "seconds": seconds, "converged":
            sum(int(_value(r, "converged")) for r in table), "n": len(table)}  # fmt: skip


def markdown(summaries: Sequence[dict], ideff: dict, argv: str, seed: int = SEED) -> str:
    """The study's tables."""
    lines = [
        "# Chain fits: efficiency against the full-state bound, and calibration",
        "",
        f"`python analyses/chain_study.py{argv}` (seed {seed}). Records of 2000 s at dt = "
        "0.02 from the independent chain simulator (`independent_chain_sim.py`), fitted by "
        "hosid's batch engine with the system file (default components, eq-65 constraint "
        "per element, emcee to convergence). Efficiency = bound variance / MSE of the "
        "posterior mean; the bound: the whole state observed, masses and force levels known "
        "(`chain_bound.md`). Its standard error over n records is about eff sqrt(2/n). "
        "`ident.` is what the identities reach with the full state (masses and levels "
        "known): the loss of their test functions alone.",
        "",
    ]
    for sm in summaries:
        case, per = sm["case"], sm["params"]
        coef = [p for p, r in per.items() if "efficiency" in r]
        effs = [per[p]["efficiency"] for p in coef]
        n = sm["n"]
        c90 = sum(per[p]["cover90"] for p in coef) / (n * len(coef))
        c50 = sum(per[p]["cover50"] for p in coef) / (n * len(coef))
        a90 = sum(r["cover90"] for r in per.values()) / (n * len(per))
        a50 = sum(r["cover50"] for r in per.values()) / (n * len(per))
        lines += [
            f"## {case}: {n} records",
            "",
            f"Efficiency over the element coefficients: mean {np.mean(effs):.2f}, min "
            f"{np.min(effs):.2f}. Coverage pooled over coefficients and records: 90 % "
            f"{c90:.2f}, 50 % {c50:.2f} (all parameters: {a90:.2f}, {a50:.2f}). Converged "
            f"(R-hat < 1.01, ESS >= 400): {sm['converged']}/{n}. Seconds a fit: mean "
            f"{np.mean(sm['seconds']):.0f} (the batch engine on 2 cores, shared with other work).",
            "",
            "| parameter | truth | mean | bias / bound sd | rmse | post sd | bound sd | "
            "efficiency | ident. | 90 % | 50 % | max R-hat | min ESS |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        name = CASES[case][0]
        for p, r in per.items():
            eff = f"{r['efficiency']:.2f}" if "efficiency" in r else "-"
            bsd = f"{r['bound_sd']:.3g}" if "bound_sd" in r else "-"
            bb = f"{r['bias_bound_sd']:+.2f}" if "bias_bound_sd" in r else "-"
            ie = f"{ideff[name][p]:.3f}" if p in ideff.get(name, {}) else "-"
            lines.append(
                f"| {p} | {r['truth']:g} | {r['mean']:.4g} | {bb} | {r['rmse']:.3g} | "
                f"{r['post_sd']:.3g} | {bsd} | {eff} | {ie} | {r['cover90']}/{n} | "
                f"{r['cover50']}/{n} | {r['rhat']:.4f} | {r['ess']:.0f} |"
            )
        lines.append("")
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> list[dict]:
    """Simulate, fit and summarize (module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--records", type=int, default=10)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--summary", action="store_true", help="tables from the fits made")
    ap.add_argument("--quick", action="store_true", help="200 steps a fit (the tests')")
    ap.add_argument("--out", type=Path, default=WORK)
    ap.add_argument("--seed", type=int, default=SEED,
                    help=f"another set of records (default {SEED}): its own work folders and "
                    "results/chain_study_seed<SEED>.md, .csv")  # fmt: skip
    args = ap.parse_args(argv)
    tag = "" if args.seed == SEED else f"_seed{args.seed}"
    summaries, ideff = [], {}
    for case in args.cases:
        folder = args.out / f"chain_{case}{tag}"
        if not args.summary:
            paths = prepare(case, args.records, folder, args.seed)
            fit_case(case, paths, folder, args.workers, steps=200 if args.quick else None,
                     seed=args.seed)  # fmt: skip
        summaries.append(summarize(case, folder))
    for name in sorted({CASES[c][0] for c in args.cases}):
        s = system(name)
        sim = 2000.0 if args.quick else 20000.0
        _, q, v = simulate_chain(s, duration=sim, dt=0.02, rng=np.random.default_rng(SEED),
                                 return_state=True)  # fmt: skip
        ideff[name] = identity_efficiency(s, q[::2], v[::2], 2000.0)
    shown = "" if list(args.cases) == list(CASES) else " --cases " + " ".join(args.cases)
    shown += "" if args.records == 10 else f" --records {args.records}"
    shown += f" --seed {args.seed}" if tag else ""
    text = markdown(summaries, ideff, shown + (" --quick" if args.quick else ""), args.seed)
    print(text)
    if not args.quick:
        (RESULTS / f"chain_study{tag}.md").write_text(text)
        fields = [
            "case",
            "parameter",
            "n",
            "truth",
            "mean",
            "bias",
            "rmse",
            "post_sd",
            "bound_sd",
            "bias_bound_sd",
            "efficiency",
            "cover90",
            "cover50",
            "rhat",
            "ess",
        ]
        with (RESULTS / f"chain_study{tag}.csv").open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=fields, restval="")
            w.writeheader()
            for sm in summaries:
                for p, r in sm["params"].items():
                    w.writerow({"case": sm["case"], "parameter": p, **r})
    return summaries


if __name__ == "__main__":
    main()
