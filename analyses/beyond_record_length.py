"""Beyond the paper: accuracy against record length.

For each record length, ``--records`` records of the paper oscillator at S0 = 100 are
analysed by moments, hosid's protocol (``method="paper"``: J2 for a1eq and S0, J4A
along the eq-65 line for the a1-n1 split) and the protocol with J4B; the first
``--fits`` records of each length are also fitted by a calibrated J4A pseudo-posterior.
The figure shows the median absolute relative error of each parameter against the
record length, the posterior's median 90 % half-width, and a T^(-1/2) guide.

Writes ``beyond_record_length.png`` and ``beyond_record_length.csv``.

    python analyses/beyond_record_length.py --records 8
"""

from __future__ import annotations

import argparse

import common
import numpy as np
from matplotlib.ticker import FuncFormatter, LogLocator, NullLocator

from hosid.estimators import estimate

CSV = "beyond_record_length.csv"
LABELS = {"paper": "protocol (J4A on the eq-65 line)", "J4B": "protocol with J4B"}
DURATIONS = (250.0, 500.0, 1000.0, 2000.0, 4000.0)
METHODS = {
    "moments": ("D", "k"),
    "paper": ("s", "C3"),
    "J4B": ("o", "C1"),
    "posterior J4A median": ("P", "C4"),
}


def run(durations, fits: int, S0: float, s: common.Settings) -> list[dict]:
    rows = []
    root = np.random.SeedSequence(s.seed)
    for T, ss in zip(durations, root.spawn(len(durations)), strict=True):
        sims = common.simulate_records(common.truth(S0), s.records, duration=T, seed=ss)
        for i, sim in enumerate(sims):
            base = {"duration": T, "record": i}
            truth = {f"{p}_true": sim.truth[p] for p in common.PARAMS}
            for m in ("moments", "paper", "J4B"):
                e = estimate(sim.record, method=m)["estimates"]
                rows.append({**base, "method": m, **{p: e[p] for p in common.PARAMS}, **truth})
            if i < fits:
                tree, summ, secs = common.quiet_fit(
                    sim.record, cost="J4A", seed=sim.rng, **s.fit_kwargs()
                )
                rows.append(
                    {
                        **base,
                        "method": "posterior J4A median",
                        **common.posterior_row(tree, summ),
                        **truth,
                        "seconds": secs,
                    }
                )
        print(f"T = {T:g} s: done", flush=True)
    common.write_csv(rows, s.out / CSV)
    common.save(plot(rows, S0), s.out / "beyond_record_length.png")
    return rows


def plot(rows, S0):
    fig, axes = common.figure(2, 3, size=(12.0, 7.2), sharex=True)
    durations = sorted({r["duration"] for r in rows})
    for ax, p in zip(axes.ravel(), common.PARAMS, strict=True):
        for m, (marker, colour) in METHODS.items():
            err = []
            for T in durations:
                sel = [r for r in rows if r["method"] == m and r["duration"] == T]
                vals = [r[p] for r in sel if np.isfinite(r[p])]
                err.append(
                    common.median_abs_rel(vals, [sel[0][f"{p}_true"]] * len(vals))
                    if vals
                    else np.nan
                )
            if np.isfinite(err).any():
                ax.plot(durations, err, marker=marker, color=colour, label=LABELS.get(m, m))
        half = []
        for T in durations:
            sel = [r for r in rows if r["method"] == "posterior J4A median" and r["duration"] == T]
            half.append(
                np.median([(r[f"{p}_q95"] - r[f"{p}_q05"]) / 2 / r[f"{p}_true"] for r in sel])
                if sel
                else np.nan
            )
        ax.plot(durations, half, color="C4", linestyle="--", label="posterior J4A 90 % half-width")
        ref = np.nanmax(half) if np.isfinite(half).any() else 1.0
        ax.plot(
            durations,
            ref * np.sqrt(durations[0] / np.array(durations)),
            color="0.6",
            linestyle=":",
            label=r"$\propto T^{-1/2}$",
        )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xticks(durations, labels=[f"{T:g}" for T in durations])
        ax.minorticks_off()
        ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.yaxis.set_minor_locator(NullLocator())
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{100 * v:.3g} %"))
        ax.set_title(p, fontsize=10)
    for ax in axes[-1]:
        ax.set_xlabel("record length (s)")
    for ax in axes[:, 0]:
        ax.set_ylabel("median |relative error|")
    handles, labels = axes[0, 2].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=8, ncol=6, loc="outside lower center")
    n = len({(r["duration"], r["record"]) for r in rows if r["method"] == "moments"})
    fig.suptitle(f"Accuracy against record length, S0 = {S0:g} ({n} records in all)", fontsize=10)
    return fig


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    common.add_arguments(ap, records=8, seed=909)
    ap.add_argument("--S0", type=float, default=100.0)
    ap.add_argument("--durations", type=float, nargs="+", default=list(DURATIONS))
    ap.add_argument("--fits", type=int, default=2, help="records per length also fitted")
    common.add_replot(ap)
    a = ap.parse_args(argv)
    s = common.settings(a)
    if a.replot:
        common.save(plot(common.read_csv(s.out / CSV), a.S0), s.out / "beyond_record_length.png")
        return 0
    durations = a.durations if not a.quick else [300.0, 400.0]
    run(durations, min(a.fits, s.records), a.S0, s)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
