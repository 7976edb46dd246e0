"""Issue 13: thresholds of the record checks (hosid.screen), their false alarms and power.

Good records: every regime of ``regimes.py`` from the independent simulator, and
hosid's simulator with each candidate effect that hosid can model (asymmetric stiffness,
friction, a mean force, coloured excitation, measurement noise) at the paper's point.
Bad records: white noise, a pure tone, two tones, a random walk, a constant, and good
records spoiled by clipping, coarse quantisation, a drift and an offset.

The statistics of every check are computed on two seed sets: ``tune`` (what the
thresholds in ``hosid.screen.THRESHOLDS`` were chosen from, with a margin) and ``held``
(never looked at before the thresholds were fixed), and the share of records at
``warn`` and ``fail`` is tabulated per record kind.

    python analyses/record_checks.py                 # 10 records a kind and seed set
    python analyses/record_checks.py --records 2     # a smoke run
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np
from independent_sim import simulate as independent
from regimes import PAPER, REGIMES

from hosid.model import simulate as hosid_simulate
from hosid.record import Record
from hosid.screen import THRESHOLDS, check_record, record_statistics

EFFECTS = {
    "b2 = 5": {"b2": 5.0},
    "mu = 20": {"mu": 20.0},
    "m = 5": {"m": 5.0},
    "wc = 30": {"wc": 30.0},
    "noise_sd = 0.02": {"noise_sd": 0.02},
}
SETS = {"tune": 1301, "held": 2602}


def good(kind: str, rng: np.random.Generator) -> Record:
    """A record hosid can describe."""
    for r in REGIMES:
        if kind == r.name:
            return independent(r.params, duration=r.duration, dt=r.dt, rng=rng)[0]
    params = {**PAPER, "S0": 100.0, **EFFECTS[kind]}
    return hosid_simulate(params, duration=2000.0, dt=0.02, rng=rng)


def bad(kind: str, rng: np.random.Generator) -> Record:
    """A record hosid cannot describe (or a spoiled good one)."""
    n, dt = 100_000, 0.02
    t = dt * np.arange(n)
    if kind == "white noise":
        return Record(rng.standard_normal(n), dt)
    if kind == "tone":
        return Record(np.sin(rng.uniform(1, 20) * t + rng.uniform(0, 6)), dt)
    if kind == "two tones":
        w = rng.uniform(1, 20, 2)
        return Record(np.sin(w[0] * t) + 0.7 * np.sin(w[1] * t + 1.0), dt)
    if kind == "random walk":
        return Record(np.cumsum(rng.standard_normal(n)), dt)
    if kind == "constant":
        return Record(np.full(n, rng.normal()), dt)
    x = good("paper_S100", rng).x
    s = np.std(x)
    if kind == "clipped at 1.5 sd":
        return Record(np.clip(x, -1.5 * s, 1.5 * s), dt)
    if kind == "quantised to sd/10":
        return Record(np.round(x / (s / 10)) * (s / 10), dt)
    if kind == "drift of 5 sd":
        return Record(x + 5 * s * t / t[-1], dt)
    if kind == "offset of 1000 sd":
        return Record(x + 1000 * s, dt)
    raise KeyError(kind)


GOOD = [r.name for r in REGIMES] + list(EFFECTS)
BAD = [
    "white noise",
    "tone",
    "two tones",
    "random walk",
    "constant",
    "clipped at 1.5 sd",
    "quantised to sd/10",
    "drift of 5 sd",
    "offset of 1000 sd",
]
NAMES = ("length", "sampling", "offset", "trend", "clipping", "quantisation", "oscillator")
#: statistic -> (threshold key, True when large values are bad)
STATS = {
    "sampling": ("sampling", True),
    "trend_z": ("trend", True),
    "clipped_share": ("clipping", True),
    "quantisation_share": ("quantisation", True),
    "flatness": ("flatness", True),
    "variation": ("variation", False),
    "line_share": ("line_share", True),
    "wander": ("wander", True),
}


def run(records: int, out: Path, kinds: list[str] | None = None) -> list[dict]:
    rows = []
    for set_name, seed in SETS.items():
        for i, kind in enumerate(GOOD + BAD):
            if kinds and kind not in kinds:
                continue
            for k in range(records):
                rng = np.random.default_rng(np.random.SeedSequence([seed, i, k]))
                rec = good(kind, rng) if kind in GOOD else bad(kind, rng)
                checks = {c.name: c for c in check_record(rec)}
                row = {"set": set_name, "kind": kind, "good": int(kind in GOOD), "record": k}
                for n in NAMES:
                    c = checks.get(n)
                    row[n] = c.status if c else "-"
                st = record_statistics(rec)
                for key in STATS:
                    row[f"v_{key}"] = "" if key not in st else f"{st[key]:.4g}"
                rows.append(row)
            print(f"{set_name} {kind}: done", flush=True)
    with open(out / "record_checks.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return rows


def table(rows: list[dict]) -> str:
    lines = [
        "| set | record kind | n | " + " | ".join(NAMES) + " | rejected (any fail) |",
        "|" + "---|" * (4 + len(NAMES)),
    ]
    for set_name in SETS:
        for kind in GOOD + BAD:
            rs = [r for r in rows if r["set"] == set_name and r["kind"] == kind]
            if not rs:
                continue
            cells = []
            for n in NAMES:
                w = sum(r[n] == "warn" for r in rs)
                f = sum(r[n] == "fail" for r in rs)
                cells.append(f"{w}w {f}f" if w or f else "-")
            rej = sum(any(r[n] == "fail" for n in NAMES) for r in rs)
            lines.append(
                f"| {set_name} | {kind} | {len(rs)} | " + " | ".join(cells) + f" | {rej} |"
            )
    good_rows = [r for r in rows if r["good"] == "1" or r["good"] == 1]
    held = [r for r in good_rows if r["set"] == "held"]
    fa = sum(any(r[n] == "fail" for n in NAMES) for r in held)
    wa = sum(any(r[n] == "warn" for n in NAMES) for r in held)
    lines.append("")
    lines.append(
        f"Held-out good records: {fa} of {len(held)} rejected, {wa} of {len(held)} with a warning."
    )
    # the most extreme value each statistic took on good records, per set, and the
    # thresholds (warn, fail)
    lines.append("")
    lines.append("| statistic | thresholds (warn, fail) | worst on good records: tune | held |")
    lines.append("|---|---|---|---|")
    for key, (th, large_bad) in STATS.items():
        cells = []
        for set_name in SETS:
            v = [
                float(r[f"v_{key}"])
                for r in good_rows
                if r["set"] == set_name and r[f"v_{key}"] != ""
            ]
            cells.append(f"{(max(v) if large_bad else min(v)):.3g}" if v else "-")
        warn, fail = THRESHOLDS[th]
        lines.append(f"| {key} | {warn}, {fail} | {cells[0]} | {cells[1]} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=10)
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "results")
    ap.add_argument("--replot", action="store_true")
    ap.add_argument("--kinds", nargs="*", default=None, help="record kinds (default all)")
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    if a.replot:
        with open(a.out / "record_checks.csv", newline="") as fh:
            rows = list(csv.DictReader(fh))
    else:
        rows = run(a.records, a.out, a.kinds)
    text = "# Record checks: false alarms and detections\n\n" + table(rows)
    (a.out / "record_checks.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
