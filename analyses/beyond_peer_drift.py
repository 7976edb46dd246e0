"""Beyond the paper: hosid against a peer method, drift regression, on the same records.

The peer is the standard data-driven route to a stochastic oscillator: reconstruct the
velocity from the displacement (hosid's spectral derivative), estimate the
Kramers-Moyal drift and diffusion of the state (x, v) on a grid with the
``kramersmoyal`` package (kernel estimator, Lamouroux & Lehnertz 2009), and fit the
model's drift -(a1 v + n1 v|v| + a2 x + n2 x^3) to it by weighted least squares; the
diffusion D^2/2 = pi S0 gives the excitation level.  It is run twice: on the
reconstructed velocity (what an output-only user has) and on the simulator's true
velocity (an oracle nobody has), which separates the velocity-reconstruction error
from the method's own bias (one-step increments at dt = 0.02).

hosid's estimators on the same records: moments, the protocol (J4A along the eq-65
line), J4B, and J4A joint.  Writes ``beyond_peer_drift.png`` and
``beyond_peer_drift.csv``.

    python analyses/beyond_peer_drift.py --records 20
"""

from __future__ import annotations

import argparse
import math

import common
import kramersmoyal
import numpy as np

from hosid.estimators import estimate
from hosid.spectra import derivatives

HOSID = {
    "moments": "moments",
    "hosid protocol (J4A line)": "paper",
    "hosid J4B": "J4B",
    "hosid J4A joint": "J4A",
}
CSV = "beyond_peer_drift.csv"
PEER = ("KM drift, reconstructed v", "KM drift, true v (oracle)")
COLOURS = dict(zip((*HOSID, *PEER), ("k", "C3", "C1", "C2", "C0", "C9"), strict=True))


def km_drift(
    x: np.ndarray, v: np.ndarray, dt: float, *, bins: int = 41, bw: float = 0.15
) -> dict[str, float]:
    """Kramers-Moyal drift/diffusion of (x, v) by ``kramersmoyal.km``, then the model's
    coefficients by least squares weighted with the kernel density.

    The state is standardized (one kernel bandwidth ``bw`` for both axes, in units of
    the standard deviations); the grid spans +-4 standard deviations.
    """
    sx, sv = float(np.std(x)), float(np.std(v))
    z = np.column_stack([x / sx, v / sv])
    edges = [np.linspace(-4.0, 4.0, bins + 1)] * 2
    powers = np.array([[0, 0], [0, 1], [0, 2]])
    kmc, centres = kramersmoyal.km(z, bins=edges, powers=powers, bw=bw)
    X, V = np.meshgrid(centres[0] * sx, centres[1] * sv, indexing="ij")
    w = kmc[0]
    ok = w > 1e-3 * w.max()
    drift = kmc[1][ok] * sv / dt  # E[dv | x, v] / dt
    diffusion = kmc[2][ok] * sv**2 / dt  # E[dv^2 | x, v] / (2 dt) = D^2 / 2 = pi S0
    Xo, Vo = X[ok], V[ok]
    phi = np.column_stack([Vo, Vo * np.abs(Vo), Xo, Xo**3])
    sw = np.sqrt(w[ok])
    coef, *_ = np.linalg.lstsq(phi * sw[:, None], -drift * sw, rcond=None)
    a1, n1, a2, n2 = map(float, coef)
    S0 = float(np.sum(w[ok] * diffusion) / np.sum(w[ok]) / math.pi)
    a1eq = a1 + n1 * math.sqrt(8 / math.pi) * sv
    return {"a1": a1, "n1": n1, "a2": a2, "n2": n2, "S0": S0, "a1eq": a1eq}


def run(S0: float, methods, s: common.Settings) -> list[dict]:
    sims = common.simulate_records(
        common.truth(S0), s.records, duration=s.duration, seed=np.random.SeedSequence(s.seed)
    )
    rows = []
    for i, sim in enumerate(sims):
        rec = sim.record
        truth = {f"{p}_true": sim.truth[p] for p in common.PARAMS}
        out = {
            m: estimate(rec, method=meth)["estimates"] for m, meth in HOSID.items() if m in methods
        }
        x = rec.x - np.mean(rec.x)
        v_rec = derivatives(x, rec.dt)[0]
        out[PEER[0]] = km_drift(x, v_rec, rec.dt)
        out[PEER[1]] = km_drift(x, sim.velocity, rec.dt)
        for m, e in out.items():
            rows.append({"record": i, "method": m, **{p: e[p] for p in common.PARAMS}, **truth})
        print(f"record {i + 1}/{len(sims)} done", flush=True)
    common.write_csv(rows, s.out / CSV)
    common.save(plot(rows, S0), s.out / "beyond_peer_drift.png")
    return rows


def plot(rows, S0):
    fig, axes = common.figure(2, 3, size=(13.0, 7.6))
    methods = list(dict.fromkeys(r["method"] for r in rows))
    for ax, p in zip(axes.ravel(), common.PARAMS, strict=True):
        true = np.median([r[f"{p}_true"] for r in rows])
        for j, m in enumerate(methods):
            vals = np.array([r[p] for r in rows if r["method"] == m], dtype=float)
            vals = vals[np.isfinite(vals)]
            if vals.size == 0:
                continue
            jitter = (np.arange(vals.size) / max(vals.size - 1, 1) - 0.5) * 0.4
            ax.scatter(j + jitter, vals, s=12, alpha=0.6, color=COLOURS.get(m, "0.5"))
            ax.plot([j - 0.3, j + 0.3], [np.median(vals)] * 2, color="k", linewidth=2)
            err = common.median_abs_rel(vals, np.full(vals.size, true))
            ax.annotate(
                f"{100 * err:.0f} %",
                (j, 1.0),
                xycoords=("data", "axes fraction"),
                ha="center",
                va="bottom",
                fontsize=7,
            )
        ax.axhline(true, color="k", linestyle="--", linewidth=0.8)
        ax.set_xticks(
            range(len(methods)),
            labels=[m.replace(", ", ",\n").replace(" (", "\n(") for m in methods],
            fontsize=6,
            rotation=90,
        )
        ax.set_ylabel(p)
    n = len({r["record"] for r in rows})
    fig.suptitle(
        f"hosid against Kramers-Moyal drift regression on the same {n} records, "
        f"S0 = {S0:g} (bars: medians; numbers: median |relative error|; "
        "dashed: truth)",
        fontsize=9,
    )
    return fig


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    common.add_arguments(ap, records=20, seed=1010)
    ap.add_argument("--S0", type=float, default=100.0)
    ap.add_argument(
        "--methods",
        nargs="+",
        default=list(HOSID),
        choices=list(HOSID),
        help="hosid estimators to run (the drift regression always runs)",
    )
    common.add_replot(ap)
    a = ap.parse_args(argv)
    if a.replot:
        common.save(plot(common.read_csv(a.out / CSV), a.S0), a.out / "beyond_peer_drift.png")
        return 0
    run(a.S0, a.methods, common.settings(a))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
