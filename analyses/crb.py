r"""The information limit of every regime: Cramer-Rao bound of (a1, n1, a2, n2).

With the whole state observed continuously for T seconds, the Girsanov likelihood of
the drift has the Fisher matrix I = T / (2 pi S0) E[phi phi^T], phi = (v, v|v|, x,
x^3) (NOTES.md, last section).  :func:`hosid.model.information.cramer_rao` estimates
E[phi phi^T] from one long simulation with the full state (hosid's simulator; 40 000 s
or 20 T, whichever is longer) and returns I^-1 for a record of T seconds.

    python analyses/crb.py                         # all regimes -> results/crb.csv, crb.md
    python analyses/crb.py --regimes paper_S100    # one regime (rows are merged)

Writes ``crb.csv`` (one row per regime: sd of a1, n1, a2, n2, a1eq and corr(a1, n1))
and ``crb.md`` (the table, and the paper point against NOTES.md).
"""

from __future__ import annotations

import argparse
import csv
import time
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np
from regimes import Regime, select

from hosid.model.information import cramer_rao

RESULTS = Path(__file__).resolve().parent / "results"
DRIFT = ("a1", "n1", "a2", "n2")
FIELDS = (
    "regime",
    "a1",
    "n1",
    "a2",
    "n2",
    "S0",
    "duration",
    "dt",
    "sim_duration",
    "seed",
    "sigma_v",
    "sd_a1",
    "sd_n1",
    "sd_a2",
    "sd_n2",
    "sd_a1eq",
    "corr_a1_n1",
    "seconds",
)
#: NOTES.md, last section: (sd a1, sd n1, sd a2, sd n2) of the paper oscillator, T = 2000 s.
NOTES = {
    "paper_S25": (0.177, 0.0247, 0.64, 0.338),
    "paper_S100": (0.221, 0.0192, 0.90, 0.236),
    "paper_S400": (0.277, 0.0150, 1.31, 0.186),
}


def sim_length(regime: Regime) -> float:
    """Length of the long simulation: 40 000 s or 20 record lengths."""
    return max(40000.0, 20.0 * regime.duration)


def compute(regime: Regime, *, seed: int, sim_duration: float | None = None) -> dict:
    """The bound of one regime as a ``crb.csv`` row.

    Parameters
    ----------
    regime : Regime
    seed : int
        Root seed; the regime's simulation uses ``SeedSequence(seed).spawn`` at its key.
    sim_duration : float, optional
        Length of the long simulation (default :func:`sim_length`).
    """
    t0 = time.perf_counter()
    length = sim_length(regime) if sim_duration is None else float(sim_duration)
    ss = np.random.SeedSequence(seed).spawn(regime.key + 1)[regime.key]
    bound = cramer_rao(
        "paper",
        regime.params,
        duration=regime.duration,
        rng=np.random.default_rng(ss),
        dt=regime.dt,
        sim_duration=length,
    )
    sd = bound.sd
    return {
        "regime": regime.name,
        **{k: regime.params[k] for k in (*DRIFT, "S0")},
        "duration": regime.duration,
        "dt": regime.dt,
        "sim_duration": length,
        "seed": seed,
        "sigma_v": bound.sigma_v,
        **{f"sd_{k}": sd[k] for k in (*DRIFT, "a1eq")},
        "corr_a1_n1": bound.corr("a1", "n1"),
        "seconds": round(time.perf_counter() - t0, 2),
    }


def load(path: Path) -> dict[str, dict]:
    """Rows of a ``crb.csv`` by regime name (numbers as floats); empty if absent."""
    if not path.is_file():
        return {}
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    conv = {"regime": str, "seed": int}
    return {r["regime"]: {k: conv.get(k, float)(v) for k, v in r.items()} for r in rows}


def table(rows: Iterable[Mapping]) -> str:
    """The Markdown table of ``crb.md``."""
    lines = [
        "| regime | S0 | T (s) | sd a1 | sd n1 | sd a2 | sd n2 | sd a1eq | corr(a1, n1) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['regime']} | {r['S0']:g} | {r['duration']:g} | {r['sd_a1']:.3g} | "
            f"{r['sd_n1']:.3g} | {r['sd_a2']:.3g} | {r['sd_n2']:.3g} | {r['sd_a1eq']:.3g} | "
            f"{r['corr_a1_n1']:.2f} |"
        )
    return "\n".join(lines)


def check(rows: Mapping[str, Mapping]) -> str:
    """The regimes NOTES.md lists, against its numbers (ratio computed / NOTES)."""
    lines = ["| regime | | sd a1 | sd n1 | sd a2 | sd n2 |", "|---|---|---|---|---|---|"]
    for name, ref in NOTES.items():
        if name not in rows:
            continue
        got = [rows[name][f"sd_{k}"] for k in DRIFT]
        lines.append(f"| {name} | NOTES.md | " + " | ".join(f"{v:.3g}" for v in ref) + " |")
        lines.append("| | computed | " + " | ".join(f"{v:.3g}" for v in got) + " |")
        lines.append(
            "| | ratio | "
            + " | ".join(f"{g / r:.3f}" for g, r in zip(got, ref, strict=True))
            + " |"
        )
    return "\n".join(lines)


def write(rows: Mapping[str, Mapping], out: Path) -> None:
    """Write ``crb.csv`` and ``crb.md`` (regimes in table order)."""
    out.mkdir(parents=True, exist_ok=True)
    order = [r.name for r in select(None)]
    ordered = sorted(
        rows.values(),
        key=lambda r: order.index(r["regime"]) if r["regime"] in order else len(order),
    )
    with (out / "crb.csv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=FIELDS)
        w.writeheader()
        for r in ordered:
            w.writerow({k: r[k] for k in FIELDS})
    length = ", ".join(f"{r['regime']} {r['sim_duration']:g} s" for r in ordered)
    text = [
        "# Cramer-Rao bound per regime",
        "",
        "Full state observed continuously for T s; I = T / (2 pi S0) E[phi phi^T], "
        "phi = (v, v|v|, x, x^3), E from one long simulation with hosid's simulator "
        f"({length}; seed {int(ordered[0]['seed']) if ordered else ''}). "
        "sd = sqrt(diag I^-1); a1eq = a1 + n1 sqrt(8/pi) sigma_v at the simulated sigma_v.",
        "",
        table(ordered),
        "",
        "## Check against NOTES.md (paper oscillator, T = 2000 s)",
        "",
        check(rows),
        "",
    ]
    (out / "crb.md").write_text("\n".join(text))


def ensure(
    regimes: Iterable[Regime], out: Path, *, seed: int, sim_duration: float | None = None
) -> dict[str, dict]:
    """The bounds of ``regimes`` from ``out/crb.csv``, computing (and adding) missing ones."""
    rows = load(out / "crb.csv")
    missing = [r for r in regimes if r.name not in rows]
    for r in missing:
        rows[r.name] = compute(r, seed=seed, sim_duration=sim_duration)
    if missing:
        write(rows, out)
    return rows


def main(argv: Sequence[str] | None = None) -> dict[str, dict]:
    """Compute the bounds of the chosen regimes and merge them into ``crb.csv``."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--regimes", nargs="+", default=None, help="default: all")
    ap.add_argument("--seed", type=int, default=20250112)
    ap.add_argument("--sim-duration", type=float, default=None, help="default max(40000, 20 T)")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    rows = load(args.out / "crb.csv")
    for r in select(args.regimes):
        rows[r.name] = compute(r, seed=args.seed, sim_duration=args.sim_duration)
        row = rows[r.name]
        print(
            f"{r.name}: sd "
            + ", ".join(f"{k} {row[f'sd_{k}']:.4g}" for k in (*DRIFT, "a1eq"))
            + f"; corr(a1, n1) {row['corr_a1_n1']:.3f} ({row['seconds']:.1f} s)",
            flush=True,
        )
    write(rows, args.out)
    return rows


if __name__ == "__main__":
    main()
