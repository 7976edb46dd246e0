"""Beyond the paper: coverage of the credible intervals, nominal against empirical.

``--records`` records of the paper oscillator at S0 = 100 are fitted by calibrated
J2 and J4A pseudo-posteriors (default settings: adaptive chain length, 30 bootstrap
records).  For every parameter and nominal level 10 %, 20 %, ..., 90 %, the
equal-tailed credible interval is checked against the truth (a1eq from the
simulated velocity).  A well-calibrated posterior puts its curve on the diagonal,
within the binomial band.

Writes ``beyond_coverage.png`` and ``beyond_coverage.csv`` (one row per cost,
parameter and level, with the count of records covered).

    python analyses/beyond_coverage.py --records 20
"""

from __future__ import annotations

import argparse

import common
import numpy as np

CSV = "beyond_coverage.csv"
LEVELS = np.round(np.arange(0.1, 0.91, 0.1), 2)


def run(S0: float, costs, s: common.Settings) -> list[dict]:
    sims = common.simulate_records(
        common.truth(S0), s.records, duration=s.duration, seed=np.random.SeedSequence(s.seed)
    )
    hits = {c: {p: np.zeros(LEVELS.size, int) for p in common.PARAMS} for c in costs}
    widths = {c: {p: [] for p in common.PARAMS} for c in costs}
    stats = {c: {"converged": 0, "seconds": []} for c in costs}
    for i, sim in enumerate(sims):
        for cost in costs:
            # a fresh child generator per cost keeps the fits independent of each other
            rng = np.random.default_rng(sim.rng.integers(2**63))
            tree, summ, secs = common.quiet_fit(sim.record, cost=cost, seed=rng, **s.fit_kwargs())
            stats[cost]["converged"] += int(summ["converged"])
            stats[cost]["seconds"].append(secs)
            for p in common.PARAMS:
                d = common.draws(tree, p)
                lo = np.quantile(d, (1 - LEVELS) / 2)
                hi = np.quantile(d, (1 + LEVELS) / 2)
                hits[cost][p] += (lo <= sim.truth[p]) & (sim.truth[p] <= hi)
                widths[cost][p].append(hi[-1] - lo[-1])
        print(f"record {i + 1}/{len(sims)} done", flush=True)
    rows = []
    for cost in costs:
        for p in common.PARAMS:
            for lv, h in zip(LEVELS, hits[cost][p], strict=True):
                rows.append(
                    {
                        "cost": cost,
                        "param": p,
                        "nominal": lv,
                        "covered": int(h),
                        "records": len(sims),
                        "empirical": h / len(sims),
                        "median_width_90": float(np.median(widths[cost][p])),
                        "converged_fits": stats[cost]["converged"],
                        "median_fit_seconds": float(np.median(stats[cost]["seconds"])),
                    }
                )
    common.write_csv(rows, s.out / CSV)
    common.save(plot(rows, costs, S0, s.duration), s.out / "beyond_coverage.png")
    return rows


def plot(rows, costs, S0, duration):
    fig, axes = common.figure(1, len(costs), size=(5.2 * len(costs), 4.8), sharey=True)
    n = int(rows[0]["records"])
    band = 1.96 * np.sqrt(LEVELS * (1 - LEVELS) / n)
    markers = dict(zip(common.PARAMS, "os^vDP", strict=True))
    for ax, cost in zip(axes[0], costs, strict=True):
        ax.fill_between(
            LEVELS,
            np.clip(LEVELS - band, 0, 1),
            np.clip(LEVELS + band, 0, 1),
            color="0.85",
            label=f"binomial 95 % band, {n} records",
        )
        ax.plot([0, 1], [0, 1], "k-", linewidth=0.8)
        for j, p in enumerate(common.PARAMS):
            sel = [r for r in rows if r["cost"] == cost and r["param"] == p]
            ax.plot(
                [r["nominal"] for r in sel],
                [r["empirical"] for r in sel],
                marker=markers[p],
                color=f"C{j}",
                linewidth=1.0,
                markersize=5,
                label=p,
            )
        conv = next(int(r["converged_fits"]) for r in rows if r["cost"] == cost)
        ax.set_title(f"{cost} pseudo-posterior ({conv}/{n} fits pass R-hat/ESS)", fontsize=9)
        ax.set_xlabel("nominal level of the central interval")
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1.02)
        ax.set_aspect("equal")
    axes[0, 0].set_ylabel("fraction of records whose interval holds the truth")
    handles, labels = axes[0, -1].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=8, ncol=7, loc="outside lower center")
    fig.suptitle(f"Coverage, S0 = {S0:g}, records of {duration:g} s", fontsize=10)
    return fig


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    common.add_arguments(ap, records=20, seed=808)
    ap.add_argument("--S0", type=float, default=100.0)
    ap.add_argument("--costs", nargs="+", default=["J2", "J4A"], choices=["J2", "J4A", "J4B"])
    common.add_replot(ap)
    a = ap.parse_args(argv)
    if a.replot:
        rows = common.read_csv(a.out / CSV)
        costs = list(dict.fromkeys(r["cost"] for r in rows))
        common.save(plot(rows, costs, a.S0, a.duration), a.out / "beyond_coverage.png")
        return 0
    run(a.S0, a.costs, common.settings(a))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
