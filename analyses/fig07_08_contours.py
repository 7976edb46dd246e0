"""Figures 7-8: contour maps of J2 and J4 over (a1, n1), with the posterior on top.

One record at S0 = 100.  As in the paper, each cost is a function of the two damping
parameters with the others (a2, n2, S0) at their true values; the grid spans positive
and negative damping, so that both J2's valley (constant a1eq, eq 65) and the twin
minimum at the mirrored damping show.  Top row: the costs as printed (eqs 50, 59);
bottom row: the well-scaled costs hosid uses (J2W, J4AW), with the draws of
*unconstrained* calibrated J2 and J4A fits of the same record on top.  Contours are
of log10(cost - min) on geometric levels.  The grid minimum in each half-plane
(a1eq > 0 and a1eq < 0) is marked.

Writes ``fig07_08_contours.png`` and ``fig07_08_contours.csv`` (the grids).

    python analyses/fig07_08_contours.py
"""

from __future__ import annotations

import argparse

import common
import numpy as np

from hosid import costs as C
from hosid.estimators import SQRT_8_PI
from hosid.spectra import block_spectra

CSV = "fig07_08_contours.csv"
N_DRAWS = 3000
PANELS = [
    ("J2", "J2", "as printed"),
    ("J4A", "J4A", "as printed"),
    ("J2W", "J2", "well-scaled"),
    ("J4AW", "J4A", "well-scaled"),
]


def cost_map(data, name, a1, n1, fixed, chunk=256):
    A, N = np.meshgrid(a1, n1, indexing="ij")
    th = np.empty((A.size, 5))
    th[:, 0], th[:, 1] = A.ravel(), N.ravel()
    th[:, 2:] = fixed
    out = np.concatenate(
        [C.evaluate_cost(name, th[i : i + chunk], data) for i in range(0, th.shape[0], chunk)]
    )
    return out.reshape(A.shape)


def half_minima(J, a1, n1, sigma_v):
    """Grid minimum where a1eq > 0 and where a1eq < 0."""
    A, N = np.meshgrid(a1, n1, indexing="ij")
    eq = A + SQRT_8_PI * sigma_v * N
    out = {}
    for side, mask in (("pos", eq > 0), ("neg", eq < 0)):
        Jm = np.where(mask, J, np.inf)
        i, j = np.unravel_index(np.argmin(Jm), J.shape)
        out[side] = (float(a1[i]), float(n1[j]), float(J[i, j]))
    return out


def run(S0: float, n_grid: int, s: common.Settings, a1_max: float, n1_max: float):
    truth = common.truth(S0)
    sim = common.simulate_records(
        truth, 1, duration=s.duration, seed=np.random.SeedSequence(s.seed)
    )[0]
    rec = sim.record
    sigma_v = float(np.std(sim.velocity))
    data = C.prepare(block_spectra(rec))
    a1 = np.linspace(-a1_max, a1_max, n_grid)
    n1 = np.linspace(-n1_max, n1_max, n_grid)
    fixed = [truth["a2"], truth["n2"], truth["S0"]]
    maps = {name: cost_map(data, name, a1, n1, fixed) for name, _, _ in PANELS}
    draws, fits = {}, []
    for cost in ("J2", "J4A"):
        tree, summ, secs = common.quiet_fit(
            rec, cost=cost, constrained=False, seed=sim.rng, **s.fit_kwargs()
        )
        d_a1, d_n1 = common.draws(tree, "a1"), common.draws(tree, "n1")
        idx = np.linspace(0, d_a1.size - 1, min(d_a1.size, N_DRAWS)).round().astype(int)
        draws[cost] = (d_a1[idx], d_n1[idx])
        neg = float(np.mean(d_a1 + SQRT_8_PI * sigma_v * d_n1 < 0))
        fits.append(
            {
                "cost": cost,
                "fraction_negative_a1eq": neg,
                "seconds": secs,
                **common.posterior_row(tree, summ, ("a1", "n1", "a1eq")),
            }
        )
        print(
            f"unconstrained {cost} fit: {100 * neg:.0f} % of draws at a1eq < 0 ({secs:.0f} s)",
            flush=True,
        )
    minima = {name: half_minima(J, a1, n1, sigma_v) for name, J in maps.items()}
    rows = []
    A, N = np.meshgrid(a1, n1, indexing="ij")
    for name, J in maps.items():
        for aa, nn, jj in zip(A.ravel(), N.ravel(), J.ravel(), strict=True):
            rows.append({"kind": "grid", "cost": name, "a1": aa, "n1": nn, "value": jj})
        for side, (ma, mn, mj) in minima[name].items():
            rows.append({"kind": f"min_{side}", "cost": name, "a1": ma, "n1": mn, "value": mj})
    rows += [{"kind": "fit", **f} for f in fits]
    for cost, (d_a1, d_n1) in draws.items():
        rows += [
            {"kind": "draw", "cost": cost, "a1": a, "n1": n}
            for a, n in zip(d_a1, d_n1, strict=True)
        ]
    rows.append(
        {
            "kind": "truth",
            "a1": truth["a1"],
            "n1": truth["n1"],
            "a1eq": sim.truth["a1eq"],
            "sigma_v": sigma_v,
        }
    )
    common.write_csv(rows, s.out / CSV)
    common.save(plot(*unpack(rows), S0), s.out / "fig07_08_contours.png")
    return minima, fits


def unpack(rows):
    """Maps, minima, draws, grid axes and sigma_v from the CSV rows."""
    grid = [r for r in rows if r["kind"] == "grid"]
    a1 = np.unique([r["a1"] for r in grid])
    n1 = np.unique([r["n1"] for r in grid])
    maps, minima, draws = {}, {}, {}
    for name, _, _ in PANELS:
        g = sorted((r for r in grid if r["cost"] == name), key=lambda r: (r["a1"], r["n1"]))
        maps[name] = np.array([r["value"] for r in g]).reshape(a1.size, n1.size)
        minima[name] = {
            side: next(
                (r["a1"], r["n1"], r["value"])
                for r in rows
                if r["kind"] == f"min_{side}" and r["cost"] == name
            )
            for side in ("pos", "neg")
        }
    for cost in ("J2", "J4A"):
        d = [r for r in rows if r["kind"] == "draw" and r["cost"] == cost]
        draws[cost] = (np.array([r["a1"] for r in d]), np.array([r["n1"] for r in d]))
    (t,) = [r for r in rows if r["kind"] == "truth"]
    return maps, minima, draws, a1, n1, float(t["sigma_v"])


def plot(maps, minima, draws, a1, n1, sigma_v, S0):
    fig, axes = common.figure(2, 2, size=(11.0, 8.6), sharex=True, sharey=True)
    slope = SQRT_8_PI * sigma_v
    a1eq = 0.5 + 0.5 * slope
    nn = np.array([n1[0], n1[-1]])
    for ax, (name, cost, form) in zip(axes.ravel(), PANELS, strict=True):
        J = maps[name]
        delta = J - np.min(J)
        pos = delta[delta > 0]
        lo = max(float(np.min(pos)), float(np.max(pos)) * 1e-8)
        levels = np.geomspace(lo, float(np.max(pos)), 16)
        surf = np.log10(np.maximum(delta, lo / 2))
        cs = ax.contour(a1, n1, surf.T, levels=np.log10(levels), cmap="viridis", linewidths=0.8)
        fig.colorbar(cs, ax=ax, label=r"$\log_{10}$(cost $-$ min)", shrink=0.85)
        if form == "well-scaled" and cost in draws:
            d_a1, d_n1 = draws[cost]
            idx = np.linspace(0, d_a1.size - 1, min(d_a1.size, 3000)).round().astype(int)
            ax.scatter(
                d_a1[idx],
                d_n1[idx],
                s=2,
                alpha=0.3,
                color="C3",
                zorder=2,
                label="posterior draws (unconstrained fit)",
            )
        ax.plot(
            a1eq - slope * nn,
            nn,
            color="0.3",
            linestyle=":",
            linewidth=1.0,
            label=r"$a_{1eq}$ = true (eq 65)",
        )
        ax.plot(-a1eq - slope * nn, nn, color="0.3", linestyle=":", linewidth=1.0)
        ax.plot(-slope * nn, nn, "k--", linewidth=0.8, label=r"$a_{1eq} = 0$")
        ax.plot(0.5, 0.5, "kx", markersize=11, markeredgewidth=2.2, label="true value", zorder=4)
        ax.plot(
            -0.5,
            -0.5,
            "x",
            color="0.5",
            markersize=9,
            markeredgewidth=2,
            zorder=4,
            label="mirrored truth",
        )
        mp, mn = minima[name]["pos"], minima[name]["neg"]
        ax.plot(
            mp[0],
            mp[1],
            "o",
            mfc="none",
            mec="C1",
            markersize=10,
            mew=2,
            zorder=5,
            label="grid minimum, each half",
        )
        ax.plot(mn[0], mn[1], "o", mfc="none", mec="C1", markersize=10, mew=2, zorder=5)
        ax.set_ylim(n1[0], n1[-1])
        ax.set_xlim(a1[0], a1[-1])
        ax.set_title(
            f"Figure {7 if cost == 'J2' else 8}: {name} ({form}); minima at "
            f"({mp[0]:.2f}, {mp[1]:.2f}) and ({mn[0]:.2f}, {mn[1]:.2f})",
            fontsize=8,
        )
    handles, labels = axes[1, 1].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=8, ncol=4, loc="outside lower center")
    for ax in axes[-1]:
        ax.set_xlabel(r"$a_1$")
    for ax in axes[:, 0]:
        ax.set_ylabel(r"$n_1$")
    fig.suptitle(
        f"Cost over (a1, n1), a2, n2, S0 at the truth; S0 = {S0:g}, one record", fontsize=10
    )
    return fig


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    common.add_arguments(ap, records=1, seed=707)
    ap.add_argument("--S0", type=float, default=100.0)
    ap.add_argument("--grid", type=int, default=101, help="grid points per axis")
    ap.add_argument("--a1-max", type=float, default=8.0)
    ap.add_argument("--n1-max", type=float, default=1.0)
    common.add_replot(ap)
    a = ap.parse_args(argv)
    s = common.settings(a)
    if a.replot:
        rows = common.read_csv(s.out / CSV)
        common.save(plot(*unpack(rows), a.S0), s.out / "fig07_08_contours.png")
        return 0
    run(a.S0, a.grid if not a.quick else min(a.grid, 21), s, a.a1_max, a.n1_max)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
