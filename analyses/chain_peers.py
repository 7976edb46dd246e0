r"""The Kramers-Moyal route beside hosid on a 2-degree-of-freedom chain (issue 33, item 2).

The records are those of ``chain_study.py``'s ``chain2`` case (the nonlinear chain of
``chain_bound.py``, the independent BAOAB simulator, 2000 s at dt = 0.02, displacements;
the same seeds), simulated again here with their true velocities.  On each:

- **hosid**: the default fit of the system file from the displacements alone
  (:func:`hosid.fit`), posterior mean and its 90 % interval;
- **KM, true state**: :func:`peer_methods.km_chain_drift` (``kramersmoyal.km`` on the
  4-dimensional grid of :math:`(q, \dot q)`, the system's equations fitted to the drift
  and diffusion) given the simulator's own velocities: what the method needs and an
  output-only user does not have;
- **KM, hosid's state**: the same given hosid's reconstructed velocities
  (:class:`hosid.chain_state.ChainState`: the channels' spectral derivatives).

Per coefficient: the mean over the records, the RMSE, the efficiency against the
full-state bound (``results/chain_bound.csv``, masses and levels known) and, for hosid,
the coverage of its 90 % intervals.  ``results/chain_peers.md`` and ``.csv``.

    python analyses/chain_peers.py              # 10 records (about 4 minutes)
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import independent_chain_sim  # noqa: E402
import peer_methods  # noqa: E402
from chain_bound import system  # noqa: E402
from chain_study import CASES, SEED  # noqa: E402

import hosid  # noqa: E402
from hosid.inference.system_estimate import system_state  # noqa: E402
from hosid.output.results import summarize  # noqa: E402

RESULTS = HERE / "results"
METHODS = ("hosid", "KM, true state", "KM, hosid's state")


def one(i: int) -> list[dict]:
    """Record ``i`` of chain_study's chain2 case: every method's estimates, one row each."""
    s = system("chain2")
    key = list(CASES).index("chain2")
    seed = np.random.SeedSequence(SEED).spawn(key + 1)[key].spawn(i + 1)[i]
    rec, q, v = independent_chain_sim.simulate(s, duration=2000.0, dt=0.02, name=f"chain2-{i}",
                                               rng=np.random.default_rng(seed),
                                               return_state=True)  # fmt: skip
    rows = []
    t0 = time.perf_counter()
    summ = summarize(hosid.fit(rec, s, seed=i, progress=False), warn=False)["parameters"]
    row = {"record": i, "method": METHODS[0], "seconds": time.perf_counter() - t0}
    for p in s.param_names:
        row[p] = summ[p]["mean"]
        row[f"{p}_in90"] = int(summ[p]["q05"] <= dict(s.values)[p] <= summ[p]["q95"])
    rows.append(row)
    st = system_state(rec, s)
    for method, (qq, vv) in zip(METHODS[1:], ((q, v), (st.q.T, st.v.T)), strict=True):
        t0 = time.perf_counter()
        est = peer_methods.km_chain_drift(s, qq - qq.mean(axis=0), vv, rec.dt)
        rows.append({"record": i, "method": method, "seconds": time.perf_counter() - t0, **est})
    return rows


def write(rows: list[dict], n: int) -> str:
    """``results/chain_peers.csv`` and ``.md``."""
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with open(RESULTS / "chain_peers.csv", "w", newline="") as f:
        w = csv.DictWriter(f, keys, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
    s = system("chain2")
    truth = dict(s.values)
    with open(RESULTS / "chain_bound.csv") as f:
        bound = {r["coefficient"]: float(r["sd"]) for r in csv.DictReader(f)
                 if r["system"] == "chain2"}  # fmt: skip
    head = "| coefficient | truth | bound sd | " + " | ".join(
        f"{m}: mean | RMSE | eff" for m in METHODS) + " | hosid 90 % |"  # fmt: skip
    lines = [
        "# Kramers-Moyal beside hosid on a 2-dof chain (issue 33, item 2)",
        "",
        f"`python analyses/chain_peers.py --records {n}`: chain_study's chain2 records "
        "(independent simulator, 2000 s at dt = 0.02, displacement channels). hosid: the "
        "default fit, posterior mean; KM: `kramersmoyal.km` on the 4-d grid of the state "
        "(14 bins a dimension, bandwidth 0.5 sd), the system's equations fitted to its "
        "drift and diffusion, given the simulator's velocities (true state) or hosid's "
        "reconstructed ones. eff: bound variance / MSE (full-state bound, masses and "
        "levels known; `chain_bound.md`).",
        "",
        head,
        "|---|---|---|" + "---|---|---|" * len(METHODS) + "---|",
    ]
    for p in s.param_names:
        cells = [p, f"{truth[p]:.4g}", f"{bound[p]:.3g}" if p in bound else "-"]
        for m in METHODS:
            x = np.array([float(r[p]) for r in rows if r["method"] == m])
            rmse = float(np.sqrt(np.mean((x - truth[p]) ** 2)))
            eff = bound[p] ** 2 / rmse**2 if p in bound else float("nan")
            cells += [f"{x.mean():.4g}", f"{rmse:.3g}", "-" if p not in bound else f"{eff:.3g}"]
        held = [int(r[f"{p}_in90"]) for r in rows if r["method"] == METHODS[0]]
        cells.append(f"{sum(held)}/{len(held)}")
        lines.append("| " + " | ".join(cells) + " |")
    secs = {m: np.mean([float(r["seconds"]) for r in rows if r["method"] == m]) for m in METHODS}
    lines += ["", "Seconds a record: " + ", ".join(f"{m} {v:.1f}" for m, v in secs.items()) + "."]
    text = "\n".join(lines) + "\n"
    (RESULTS / "chain_peers.md").write_text(text)
    return text


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=10)
    args = ap.parse_args(argv)
    rows = [r for i in range(args.records) for r in one(i)]
    print(write(rows, args.records))


if __name__ == "__main__":
    main()
