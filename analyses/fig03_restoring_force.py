"""Figure 3: restoring force, true against estimated, S0 = 2500, J2 and J4 at w_max 8 and 12 rad/s.

One record at S0 = 2500.  Each panel (cost x w_max) shows the true restoring force
a2 x + n2 x^3 over the record's displacement range, the spectral point estimate of the
paper (all parameters by the cost: ``J2 free`` is ``estimate(method="J2")``,
``J2+J4A free`` is :func:`common.spectral_stiffness`), the moment estimate, and the
posterior median and 90 % band of a calibrated fit with that cost and w_max (whose
stiffness is informed by the moment criterion: the spectral costs are cut from it).

Writes ``fig03_restoring_force.png`` and ``fig03_restoring_force.csv``.

    python analyses/fig03_restoring_force.py
"""

from __future__ import annotations

import argparse

import common
import numpy as np

from hosid.estimators import estimate

PANELS = [("J2", 8.0), ("J2", 12.0), ("J4A", 8.0), ("J4A", 12.0)]
N_X = 81
CSV = "fig03_restoring_force.csv"


def run(S0: float, s: common.Settings, panels=PANELS) -> list[dict]:
    sim = common.simulate_records(
        common.truth(S0), 1, duration=s.duration, seed=np.random.SeedSequence(s.seed)
    )[0]
    rec = sim.record
    x_max = float(np.max(np.abs(rec.x - np.mean(rec.x))))
    x = np.linspace(-x_max, x_max, N_X)
    true = 25.0 * x + 5.0 * x**3
    mom = estimate(rec, method="moments")["estimates"]
    rows = []
    for cost, om in panels:
        if cost == "J2":
            point = estimate(rec, method="J2", omega_max=om)["estimates"]
        else:
            prot = estimate(rec, method="paper", omega_max=om)["estimates"]
            point = common.spectral_stiffness(rec, prot, omega_max=om)
        tree, _, secs = common.quiet_fit(
            rec, cost=cost, omega_max=om, seed=sim.rng, **s.fit_kwargs()
        )
        a2, n2 = common.draws(tree, "a2"), common.draws(tree, "n2")
        idx = np.linspace(0, a2.size - 1, min(a2.size, 2000)).round().astype(int)
        band = np.quantile(a2[idx, None] * x + n2[idx, None] * x**3, [0.05, 0.5, 0.95], axis=0)
        f_point = point["a2"] * x + point["n2"] * x**3
        f_mom = mom["a2"] * x + mom["n2"] * x**3
        scale = np.max(np.abs(true))
        for j in range(N_X):
            rows.append(
                {
                    "cost": cost,
                    "omega_max": om,
                    "x": x[j],
                    "true": true[j],
                    "point": f_point[j],
                    "moments": f_mom[j],
                    "post_q05": band[0, j],
                    "post_q50": band[1, j],
                    "post_q95": band[2, j],
                    "a2_point": point["a2"],
                    "n2_point": point["n2"],
                    "a2_post": float(np.median(a2)),
                    "n2_post": float(np.median(n2)),
                    "max_err_point": np.max(np.abs(f_point - true)) / scale,
                    "max_err_post": np.max(np.abs(band[1] - true)) / scale,
                    "max_err_moments": np.max(np.abs(f_mom - true)) / scale,
                    "band_half_width": np.max(band[2] - band[0]) / 2 / scale,
                    "fit_seconds": secs,
                }
            )
        print(
            f"{cost} w_max {om:g}: a2 {point['a2']:.2f}, n2 {point['n2']:.3f} (fit {secs:.0f} s)",
            flush=True,
        )
    common.write_csv(rows, s.out / CSV)
    common.save(plot(rows, S0), s.out / "fig03_restoring_force.png")
    return rows


def plot(rows, S0):
    panels = list(dict.fromkeys((r["cost"], r["omega_max"]) for r in rows))
    ncols = 2
    nrows = (len(panels) + 1) // 2
    fig, axes = common.figure(
        nrows, ncols, size=(9.5, 3.6 * nrows + 0.4), sharex=True, sharey=True
    )
    for ax, (cost, om) in zip(axes.ravel(), panels, strict=False):
        sel = [r for r in rows if (r["cost"], r["omega_max"]) == (cost, om)]
        x = np.array([r["x"] for r in sel])

        def col(k, sel=sel):
            return np.array([r[k] for r in sel])

        name = "J2 free" if cost == "J2" else "J2+J4A free"
        ax.fill_between(
            x,
            col("post_q05"),
            col("post_q95"),
            color="C0",
            alpha=0.3,
            label=f"{cost} posterior, 90 % band",
        )
        ax.plot(x, col("post_q50"), color="C0", linewidth=1.2, label=f"{cost} posterior median")
        ax.plot(
            x,
            col("point"),
            color="C3",
            linestyle="-.",
            linewidth=1.4,
            label=f"{name} point estimate",
        )
        ax.plot(x, col("moments"), color="0.4", linestyle=":", linewidth=1.2, label="moments")
        ax.plot(x, col("true"), "k--", linewidth=1.0, label="true")
        r0 = sel[0]
        ax.set_title(
            rf"{cost}, $\omega_{{max}}$ = {om:g} rad/s: point a2 = {r0['a2_point']:.1f}, "
            f"n2 = {r0['n2_point']:.2f}\nmax |error| / max |f|: point "
            f"{100 * r0['max_err_point']:.0f} %, posterior {100 * r0['max_err_post']:.1f} %",
            fontsize=8,
        )
        ax.axhline(0, color="0.8", linewidth=0.5)
        top = 1.6 * np.max(np.abs(col("true")))
        ax.set_ylim(-top, top)
        ax.legend(fontsize=7, loc="upper left")
    for ax in axes[-1]:
        ax.set_xlabel(r"$x$")
    for ax in axes[:, 0]:
        ax.set_ylabel(r"$f_R = a_2 x + n_2 x^3$")
    fig.suptitle(f"Figure 3: restoring force, S0 = {S0:g} (one record)", fontsize=10)
    return fig


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    common.add_arguments(ap, records=1, seed=303)
    ap.add_argument("--S0", type=float, default=2500.0)
    ap.add_argument(
        "--panels",
        nargs="+",
        default=[f"{c}:{o:g}" for c, o in PANELS],
        help="cost:omega_max pairs",
    )
    common.add_replot(ap)
    a = ap.parse_args(argv)
    if a.replot:
        rows = common.read_csv(a.out / CSV)
        common.save(plot(rows, a.S0), a.out / "fig03_restoring_force.png")
        return 0
    panels = [(p.split(":")[0], float(p.split(":")[1])) for p in a.panels]
    run(a.S0, common.settings(a), panels)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
