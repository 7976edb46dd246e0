"""Figure 6: (a1, n1) estimates over many records at S0 = 100, J2 vs J4, beside the posteriors.

Every record is analysed by

- ``J2``: the J2 step of the protocol (:func:`hosid.estimators.fit_J2` with the moment
  stiffness), whose (a1, n1) is wherever the polish stops in J2's valley;
- ``J4A line``: the paper's J4 step, J4A along the line of constant a1eq (eq 65)
  (``estimate(method="paper")``);
- ``J4B line``: the same with J4B (``method="J4B"``);
- ``J4A joint``: J4A + J2 over (a1, n1, S0) (``method="J4A"``, eq 15);

and the first ``--fits`` records by calibrated J2 and J4A fits (posterior draws in
the right-hand panels, posterior medians of all fitted records marked).  Writes
``fig06_damping_scatter.png`` and ``fig06_damping_scatter.csv``.

    python analyses/fig06_damping_scatter.py --records 30 --fits 1
"""

from __future__ import annotations

import argparse

import common
import numpy as np

from hosid import costs as C
from hosid import estimators as E
from hosid.spectra import block_spectra

CSV = "fig06_damping_scatter.csv"
N_DRAWS = 2000
METHODS = {  # label: (marker, colour)
    "J2": ("^", "C0"),
    "J4A line": ("s", "C3"),
    "J4B line": ("D", "C1"),
    "J4A joint": ("o", "C2"),
}


def analyse(sim: common.Sim, i: int, methods) -> list[dict]:
    rec = sim.record
    mom = E.moments(rec)
    data = C.prepare(block_spectra(rec))
    out = {}
    if "J2" in methods:
        out["J2"] = E.fit_J2(data, sigma_v=mom["sigma_v"], stiffness=(mom["a2"], mom["n2"]))
    names = {"J4A line": "paper", "J4B line": "J4B", "J4A joint": "J4A"}
    for m, method in names.items():
        if m in methods:
            out[m] = E.estimate(rec, method=method)["estimates"]
    return [
        {
            "record": i,
            "method": m,
            "a1": e["a1"],
            "n1": e["n1"],
            "a1eq": e["a1eq"],
            "a1_true": 0.5,
            "n1_true": 0.5,
            "a1eq_true": sim.truth["a1eq"],
        }
        for m, e in out.items()
    ]


def run(S0: float, fits: int, s: common.Settings, methods=tuple(METHODS)) -> list[dict]:
    sims = common.simulate_records(
        common.truth(S0), s.records, duration=s.duration, seed=np.random.SeedSequence(s.seed)
    )
    rows = []
    for i, sim in enumerate(sims):
        rows += analyse(sim, i, methods)
        if i < fits:
            for cost in ("J2", "J4A"):
                tree, summ, secs = common.quiet_fit(
                    sim.record, cost=cost, seed=sim.rng, **s.fit_kwargs()
                )
                row = common.posterior_row(tree, summ, ("a1", "n1", "a1eq"))
                rows.append({"record": i, "method": f"posterior {cost}", **row, "seconds": secs})
                if i == 0:  # a thinned set of draws, for the figure
                    a1, n1 = common.draws(tree, "a1"), common.draws(tree, "n1")
                    idx = np.linspace(0, a1.size - 1, min(a1.size, N_DRAWS)).round().astype(int)
                    rows += [
                        {"record": 0, "method": f"draws {cost}", "a1": a, "n1": n}
                        for a, n in zip(a1[idx], n1[idx], strict=True)
                    ]
        print(f"record {i + 1}/{len(sims)} done", flush=True)
    common.write_csv(rows, s.out / CSV)
    common.save(plot(rows, S0), s.out / "fig06_damping_scatter.png")
    return rows


def _at_zero(sel) -> str:
    """How many estimates sit on either boundary of the eq-65 segment."""
    a1_0 = sum(r["a1"] < 0.02 * r["a1eq"] for r in sel)
    n1_0 = sum(r["n1"] < 0.01 for r in sel)
    return f"{a1_0} at a1 = 0, {n1_0} at n1 = 0"


def plot(rows, S0):
    fig, axes = common.figure(1, 3, size=(13.0, 4.6), sharex=True, sharey=True)
    a1eq = np.median([r["a1eq_true"] for r in rows if "a1eq_true" in r])
    sv = (a1eq - 0.5) / (0.5 * E.SQRT_8_PI)
    n_line = np.linspace(0, a1eq / (E.SQRT_8_PI * sv), 2)
    ax = axes[0, 0]
    for m, (marker, colour) in METHODS.items():
        sel = [r for r in rows if r["method"] == m]
        if sel:
            ax.scatter(
                [r["a1"] for r in sel],
                [r["n1"] for r in sel],
                marker=marker,
                color=colour,
                s=22,
                alpha=0.6,
                label=f"{m}: {len(sel)} records, {_at_zero(sel)}",
            )
    n_rec = len({r["record"] for r in rows if r["method"] in METHODS})
    ax.set_title(f"Figure 6: point estimates, S0 = {S0:g}, {n_rec} records", fontsize=9)
    for ax, cost in zip(axes[0, 1:], ("J2", "J4A"), strict=True):
        d = [r for r in rows if r["method"] == f"draws {cost}"]
        ax.scatter(
            [r["a1"] for r in d],
            [r["n1"] for r in d],
            s=2,
            alpha=0.25,
            color="C4",
            label="posterior draws, record 0",
        )
        post = [r for r in rows if r["method"] == f"posterior {cost}"]
        ax.scatter(
            [r["a1"] for r in post],
            [r["n1"] for r in post],
            marker="P",
            color="k",
            s=40,
            label=f"posterior medians, {len(post)} fitted record(s)",
            zorder=3,
        )
        ax.set_title(f"calibrated {cost} fit", fontsize=9)
    for ax in axes[0]:
        ax.plot(
            a1eq - E.SQRT_8_PI * sv * n_line,
            n_line,
            color="0.5",
            linewidth=0.8,
            linestyle="--",
            label="eq (65) line, true a1eq",
        )
        ax.plot(0.5, 0.5, "kx", markersize=12, markeredgewidth=2.5, label="true value", zorder=4)
        ax.set_xlabel(r"$a_1$")
        ax.legend(fontsize=7, loc="upper right")
    axes[0, 0].set_ylabel(r"$n_1$")
    return fig


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    common.add_arguments(ap, records=30, seed=606)
    ap.add_argument("--S0", type=float, default=100.0)
    ap.add_argument("--fits", type=int, default=4, help="records also fitted (J2 and J4A)")
    ap.add_argument("--methods", nargs="+", default=list(METHODS), choices=list(METHODS))
    common.add_replot(ap)
    a = ap.parse_args(argv)
    s = common.settings(a)
    if a.replot:
        rows = common.read_csv(s.out / CSV)
        common.save(plot(rows, a.S0), s.out / "fig06_damping_scatter.png")
        return 0
    run(a.S0, min(a.fits, s.records), s, tuple(a.methods))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
