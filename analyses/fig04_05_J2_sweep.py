"""Figures 4-5: J2's equivalent linear damping and excitation level against S0.

For each excitation level, ``--records`` records of the paper oscillator (the same
records as ``fig01_02_stiffness.py`` with the same seed) are analysed by J2 in two ways:

- ``J2 free``: ``estimate(method="J2")``, all parameters by J2 (the paper's Figures 4-5);
- ``J2, moment stiffness``: the J2 step of hosid's protocol (``method="paper"``: its
  ``a1eq`` and ``S0`` are J2's, with the stiffness from moments);

and the first record of every level by a calibrated J2 fit (median, 90 % interval).
The true equivalent damping is eq (65), a1 + n1 sqrt(8/pi) sigma_v, with sigma_v of
the simulated velocity.  Writes ``fig04_equivalent_damping.png``, ``fig05_S0.png``
and ``fig04_05_J2_sweep.csv``.

    python analyses/fig04_05_J2_sweep.py --records 5
"""

from __future__ import annotations

import argparse

import common
import numpy as np
from matplotlib.ticker import FuncFormatter, LogLocator, NullLocator

from hosid.estimators import estimate

METHODS = {"J2 free": ("^", "C0", 0.9), "J2, moment stiffness": ("o", "C2", 1.0)}
POSTERIOR = "posterior J2"
CSV = "fig04_05_J2_sweep.csv"


def run(levels, s: common.Settings) -> list[dict]:
    rows = []
    root = np.random.SeedSequence(s.seed)
    for level, ss in zip(levels, root.spawn(len(levels)), strict=True):
        sims = common.simulate_records(
            common.truth(level), s.records, duration=s.duration, seed=ss
        )
        for i, sim in enumerate(sims):
            base = {
                "S0_true": level,
                "record": i,
                "a1eq_true": sim.truth["a1eq"],
                "sigma_v": float(np.std(sim.velocity)),
            }
            free = estimate(sim.record, method="J2")["estimates"]
            prot = estimate(sim.record, method="paper")["estimates"]
            for m, e in zip(METHODS, (free, prot), strict=True):
                rows.append({**base, "method": m, "a1eq": e["a1eq"], "S0": e["S0"]})
        tree, summ, secs = common.quiet_fit(
            sims[0].record, cost="J2", seed=sims[0].rng, **s.fit_kwargs()
        )
        rows.append(
            {
                "S0_true": level,
                "record": 0,
                "a1eq_true": sims[0].truth["a1eq"],
                "method": POSTERIOR,
                **common.posterior_row(tree, summ, ("a1eq", "S0")),
                "seconds": secs,
            }
        )
        print(f"S0 = {level:g}: done (fit {secs:.0f} s)", flush=True)
    common.write_csv(rows, s.out / CSV)
    draw(rows, s.out)
    return rows


def draw(rows, out) -> None:
    common.save(plot_damping(rows), out / "fig04_equivalent_damping.png")
    common.save(plot_level(rows), out / "fig05_S0.png")


def _levels(rows):
    return sorted({r["S0_true"] for r in rows})


def _points(ax, rows, name, scale=lambda r: 1.0):
    for m, (marker, colour, off) in METHODS.items():
        sel = [r for r in rows if r["method"] == m]
        x = np.array([r["S0_true"] for r in sel]) * off
        ax.scatter(
            x,
            [r[name] / scale(r) for r in sel],
            marker=marker,
            color=colour,
            s=16,
            alpha=0.5,
            label=f"{m} (single records)",
        )
    post = [r for r in rows if r["method"] == POSTERIOR]
    x = np.array([r["S0_true"] for r in post]) * 1.12
    y = np.array([r[name] / scale(r) for r in post])
    err = np.array([[r[name] - r[f"{name}_q05"], r[f"{name}_q95"] - r[name]] for r in post]).T
    err = err / np.array([scale(r) for r in post])
    ax.errorbar(
        x,
        y,
        yerr=err,
        fmt="s",
        color="C4",
        markersize=4,
        capsize=3,
        label=f"{POSTERIOR}, 90 % interval (1 record)",
    )


def _log_x(ax, levels):
    ax.set_xscale("log")
    ax.set_xticks(levels, labels=[f"{v:g}" for v in levels])
    ax.minorticks_off()
    ax.set_xlabel(r"$S_0$ (true)")


def plot_damping(rows):
    fig, ax = common.figure(size=(7.0, 4.6))
    ax = ax[0, 0]
    levels = _levels(rows)
    _points(ax, rows, "a1eq")
    truth = [
        np.mean([r["a1eq_true"] for r in rows if r["S0_true"] == lv and "sigma_v" in r])
        for lv in levels
    ]
    ax.plot(levels, truth, "k-", label=r"true: $a_1 + n_1\sqrt{8/\pi}\,\sigma_{\dot x}$ (eq 65)")
    _log_x(ax, levels)
    ax.set_ylabel(r"$a_{1\mathrm{eq}}$")
    ax.set_title("Figure 4: equivalent linear damping by J2", fontsize=10)
    ax.legend(fontsize=7, loc="upper left")
    return fig


def plot_level(rows):
    fig, axes = common.figure(1, 2, size=(10.0, 4.4))
    levels = _levels(rows)
    ax = axes[0, 0]
    _points(ax, rows, "S0")
    ax.plot(levels, levels, "k-", label="true")
    _log_x(ax, levels)
    ax.set_yscale("log")
    ax.set_ylabel(r"$S_0$ (estimated)")
    ax.set_title("Figure 5: estimated against true S0", fontsize=10)
    ax.legend(fontsize=7, loc="upper left")
    ax = axes[0, 1]
    _points(ax, rows, "S0", scale=lambda r: r["S0_true"])
    ax.axhline(1.0, color="k")
    _log_x(ax, levels)
    ax.set_yscale("log")
    ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ax.yaxis.set_minor_locator(NullLocator())
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.set_ylabel(r"$\hat S_0 / S_0$")
    ax.set_title("the same as a ratio", fontsize=10)
    return fig


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    common.add_arguments(ap, records=5, seed=101)
    ap.add_argument("--levels", type=float, nargs="+", default=list(common.LEVELS))
    common.add_replot(ap)
    a = ap.parse_args(argv)
    if a.replot:
        draw(common.read_csv(a.out / CSV), a.out)
        return 0
    run(a.levels if not a.quick else a.levels[:2], common.settings(a))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
