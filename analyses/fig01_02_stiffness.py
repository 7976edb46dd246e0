"""Figures 1-2: estimates of a2 and n2 against S0 by moments, J2 and J4, with credible intervals.

For each excitation level, ``--records`` records of the paper oscillator are analysed by

- ``moments``: the stationary moment identities (damping terms dropped);
- ``J2 free``: :func:`hosid.estimators.estimate` ``method="J2"``, all parameters by the
  well-scaled J2 (the paper's second-order method: stiffness not taken from moments);
- ``J2 literal``: the same with the cost as printed (eq 50);
- ``J2+J4A free``: all five parameters by the well-scaled J2 + J4A jointly, from the
  protocol estimate (the paper's fourth-order method; :func:`common.spectral_stiffness`);
- ``protocol``: the stiffness hosid's J4 estimators use (moments with the damping
  terms kept, ``method="paper"``);

and the first record of every level by a calibrated J4A fit (posterior median and 90 %
interval).  Writes ``fig01_a2.png``, ``fig02_n2.png`` and ``fig01_02_stiffness.csv``.

    python analyses/fig01_02_stiffness.py --records 5
"""

from __future__ import annotations

import argparse

import common
import numpy as np

from hosid.estimators import estimate

METHODS = {  # label: (marker, colour, x offset factor)
    "moments": ("D", "k", 0.84),
    "protocol": ("s", "C2", 0.92),
    "J2 free": ("^", "C0", 1.0),
    "J2 literal": ("^", "C9", 1.08),
    "J2+J4A free": ("o", "C3", 1.17),
}
POSTERIOR = "posterior J4A"
CSV = "fig01_02_stiffness.csv"
LABELS = {"protocol": "moments + damping terms (protocol)"}
LIMITS = {"a2": (0.0, 60.0), "n2": (-5.0, 15.0)}


def analyse(sim: common.Sim, level: float, i: int) -> list[dict]:
    rec = sim.record
    mom = estimate(rec, method="moments")["estimates"]
    j2 = estimate(rec, method="J2")["estimates"]
    j2l = estimate(rec, method="J2", form="literal")["estimates"]
    prot = estimate(rec, method="paper")["estimates"]
    j4 = common.spectral_stiffness(rec, prot)
    rows = []
    for m, e in zip(METHODS, (mom, prot, j2, j2l, j4), strict=True):
        rows.append({"S0_true": level, "record": i, "method": m, "a2": e["a2"], "n2": e["n2"]})
    return rows


def run(levels, s: common.Settings) -> list[dict]:
    rows = []
    root = np.random.SeedSequence(s.seed)
    for level, ss in zip(levels, root.spawn(len(levels)), strict=True):
        sims = common.simulate_records(
            common.truth(level), s.records, duration=s.duration, seed=ss
        )
        for i, sim in enumerate(sims):
            rows += analyse(sim, level, i)
        tree, summ, secs = common.quiet_fit(
            sims[0].record, cost="J4A", seed=sims[0].rng, **s.fit_kwargs()
        )
        row = common.posterior_row(tree, summ, ("a2", "n2"))
        rows.append({"S0_true": level, "record": 0, "method": POSTERIOR, **row, "seconds": secs})
        print(f"S0 = {level:g}: done (fit {secs:.0f} s)", flush=True)
    common.write_csv(rows, s.out / CSV)
    draw(rows, s.out)
    return rows


def draw(rows, out) -> None:
    for name, fname, true in (("a2", "fig01_a2.png", 25.0), ("n2", "fig02_n2.png", 5.0)):
        common.save(plot(rows, name, true), out / fname)


def plot(rows, name: str, true: float):
    fig, ax = common.figure(size=(7.5, 4.8))
    ax = ax[0, 0]
    lo, hi = LIMITS[name]
    clipped_total = {}
    for m, (marker, colour, off) in METHODS.items():
        sel = [r for r in rows if r["method"] == m]
        x = np.array([r["S0_true"] for r in sel]) * off
        y = np.array([r[name] for r in sel])
        n = common.clipped(
            ax, x, y, lo, hi, marker=marker, color=colour, s=14, alpha=0.45, label=None
        )
        clipped_total[m] = n
        levels = sorted({r["S0_true"] for r in sel})
        med = [np.median([r[name] for r in sel if r["S0_true"] == lv]) for lv in levels]
        ax.plot(
            np.array(levels) * off,
            np.clip(med, lo, hi),
            marker=marker,
            color=colour,
            linestyle="none",
            markersize=8,
            markeredgecolor="k",
            label=f"{LABELS.get(m, m)} (median)",
        )
    post = [r for r in rows if r["method"] == POSTERIOR]
    x = np.array([r["S0_true"] for r in post]) * 1.27
    y = np.array([r[name] for r in post])
    err = np.array([[r[name] - r[f"{name}_q05"], r[f"{name}_q95"] - r[name]] for r in post]).T
    ax.errorbar(
        x,
        y,
        yerr=err,
        fmt="o",
        color="C4",
        markersize=4,
        capsize=3,
        label=f"{POSTERIOR}, 90 % interval (1 record)",
    )
    ax.axhline(true, color="k", linewidth=1.0, label="true value")
    ax.set_xscale("log")
    levels = sorted({r["S0_true"] for r in rows})
    ax.set_xticks(levels, labels=[f"{v:g}" for v in levels])
    ax.minorticks_off()
    ax.set_ylim(lo - 0.02 * (hi - lo), hi + 0.02 * (hi - lo))
    ax.set_xlabel(r"$S_0$")
    ax.set_ylabel({"a2": r"$a_2$", "n2": r"$n_2$"}[name])
    out = ", ".join(f"{m} {n}" for m, n in clipped_total.items() if n)
    n_rec = len({(r["S0_true"], r["record"]) for r in rows if r["method"] == "moments"})
    ax.set_title(
        f"Figure {1 if name == 'a2' else 2}: estimates of {name} "
        f"({n_rec} records; small marks = single records)"
        + (f"\noutside the axis (triangles at the edge): {out}" if out else ""),
        fontsize=9,
    )
    fig.legend(fontsize=7, ncol=3, loc="outside lower center")
    return fig


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    common.add_arguments(ap, records=5, seed=101)
    ap.add_argument("--levels", type=float, nargs="+", default=list(common.LEVELS))
    common.add_replot(ap)
    a = ap.parse_args(argv)
    s = common.settings(a)
    if a.replot:
        draw(common.read_csv(s.out / CSV), s.out)
        return 0
    run(a.levels if not a.quick else a.levels[:2], s)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
