r"""``peers.csv``, ``peers.md`` and ``peers.png`` of ``peers.py``: bias, efficiency and
coverage of every method against the Cramer-Rao bound of ``results/crb.csv``.

Per regime, method and parameter over the ``n`` records: the bias ``mean(est - truth)``
in bound-sd and in standard errors (``sd / sqrt(n)``), within the issue's tolerance when
``|bias| <= 0.3 bound-sd + 3 se``; the efficiency ``bound^2 / MSE``; the coverage of the
90 % and 50 % intervals where the method gives intervals.  ``S0`` has no bound here (the
full path would give it exactly): its efficiency is against the reference
:math:`S_0\sqrt{2/N}`, the bound of a white sequence's level from the record's ``N``
samples, and the tables give its bias and sd relative to the truth.  ``peers.csv``: one
row per method, regime and parameter (the oracle ``kramersmoyal_true_v``, which no
output-only user can run, only in ``peers.md``).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from crb import load
from regimes import BY_NAME

RESULTS = Path(__file__).resolve().parent / "results"
PARAMS = ("a1", "n1", "a2", "n2", "a1eq", "S0")
METHODS = (
    "hosid",
    "paper_J2",
    "paper_J4A",
    "kramersmoyal",
    "kramersmoyal_true_v",
    "iv_regression",
    "oma",
)
ORACLES = ("kramersmoyal_true_v",)
FIELDS = (
    "method", "regime", "parameter", "truth", "bias", "efficiency", "coverage90", "coverage50",
    "bias_bound_sd", "bias_se", "sd", "rmse", "bound", "n",
)  # fmt: skip
LIMIT = 30.0  # the figure's range: bound-sd, or % for S0
TICKS = (-30, -10, -3, -1, 0, 1, 3, 10, 30)
COLOURS = dict(zip(METHODS, ("C2", "C0", "C3", "C1", "C5", "C4", "C7"), strict=True))


def stats(rows: Sequence[Mapping], p: str, bound: float | None) -> dict | None:
    """The numbers of one (regime, method, parameter) cell (module docstring)."""
    est = np.array([r[p] for r in rows], dtype=float)
    true = np.array([r[f"{p}_true"] for r in rows], dtype=float)
    ok = np.isfinite(est)
    if not ok.any():
        return None
    err = est[ok] - true[ok]
    n = int(ok.sum())
    sd = float(np.std(err, ddof=1)) if n > 1 else math.nan
    se = sd / math.sqrt(n)
    out = {"n": n, "bias": float(np.mean(err)), "sd": sd, "se": se, "truth": float(np.mean(true))}
    out["mse"] = float(np.mean(err**2))
    if bound:
        out["bound"] = bound
        out["bias_bound"] = out["bias"] / bound
        out["eff"] = bound**2 / out["mse"]
        out["ok"] = abs(out["bias"]) <= 0.3 * bound + 3 * se
    for level, lo, hi in ((90, "q05", "q95"), (50, "q25", "q75")):
        key_lo, key_hi = f"{p}_{lo}", f"{p}_{hi}"
        if key_lo in rows[0]:
            a = np.array([r[key_lo] for r in rows], dtype=float)[ok]
            b = np.array([r[key_hi] for r in rows], dtype=float)[ok]
            if np.all(np.isfinite(a)):
                out[f"cov{level}"] = float(np.mean((a <= true[ok]) & (true[ok] <= b)))
    return out


def summarize(rows: Sequence[Mapping], regimes: Sequence[str]) -> dict:
    """``{regime: {method: {param: stats}}}``."""
    bounds = load(RESULTS / "crb.csv")
    out = {}
    for g in regimes:
        b = dict(bounds.get(g, {}))
        r = BY_NAME[g]
        b["sd_S0"] = r.S0 * math.sqrt(2.0 / round(r.duration / r.dt))  # module docstring
        out[g] = {}
        for m in METHODS:
            sub = [r for r in rows if r["regime"] == g and r["method"] == m]
            if sub:
                out[g][m] = {
                    p: stats(sub, p, _num(b.get(f"sd_{p}"))) for p in PARAMS if p in sub[0]
                }
    return out


def table(summary: dict, path: Path) -> None:
    """``peers.csv`` (module docstring)."""
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=FIELDS)
        w.writeheader()
        for g, methods in summary.items():
            for m, cells in methods.items():
                if m in ORACLES:
                    continue
                for p, s in cells.items():
                    if s is None:
                        continue
                    w.writerow(
                        {
                            "method": m,
                            "regime": g,
                            "parameter": p,
                            "truth": f"{s['truth']:.6g}",
                            "bias": f"{s['bias']:.6g}",
                            "efficiency": f"{s['eff']:.4g}",
                            "coverage90": f"{s['cov90']:.3g}" if "cov90" in s else "",
                            "coverage50": f"{s['cov50']:.3g}" if "cov50" in s else "",
                            "bias_bound_sd": f"{s['bias_bound']:.4g}",
                            "bias_se": f"{s['bias'] / s['se']:.4g}" if s["se"] > 0 else "",
                            "sd": f"{s['sd']:.6g}",
                            "rmse": f"{math.sqrt(s['mse']):.6g}",
                            "bound": f"{s['bound']:.6g}",
                            "n": s["n"],
                        }
                    )


def _num(x) -> float | None:
    try:
        return float(x)
    except (TypeError, ValueError):
        return None


def _cell(s: dict | None, p: str) -> str:
    if s is None:
        return "-"
    if p == "S0":
        rel = f"{100 * s['bias'] / s['truth']:+.1f} % ({100 * s['sd'] / s['truth']:.1f} %)"
        txt = f"{s['eff']:.2f}; {rel}"
    else:
        z = s["bias"] / s["se"] if s["se"] > 0 else math.copysign(math.inf, s["bias"])
        txt = f"{s['eff']:.2f}; {s['bias_bound']:+.2f} ({z:+.1f} se){'' if s['ok'] else ' **x**'}"
    if "cov90" in s:
        txt += f"; {100 * s['cov90']:.0f}/{100 * s['cov50']:.0f} %"
    return txt


def markdown(summary: dict, rows: Sequence[Mapping]) -> str:
    """The tables (module docstring)."""
    lines = [
        "# hosid beside its peers, on the same records",
        "",
        "Made by `python analyses/peers.py` (its docstring names the methods and the "
        "records). A cell reads *efficiency* (Cramer-Rao variance / MSE); *bias* in bound-sd "
        "(in standard errors of the mean), **x** where it exceeds 0.3 bound-sd + 3 se; and "
        "the 90 % / 50 % interval coverage where the method gives intervals. S0 has no "
        "bound: its efficiency is against S0 sqrt(2/N) (a white sequence's level from N "
        "samples) and its bias is relative (its relative sd in brackets). "
        "`kramersmoyal_true_v` is given the simulator's velocity: an oracle.",
        "",
    ]
    for g, methods in summary.items():
        n = max((s["n"] for m in methods.values() for s in m.values() if s), default=0)
        lines += [
            f"## {g} ({n} records)",
            "",
            "| method | " + " | ".join(PARAMS) + " | median s |",
            "|---|" + "---|" * (len(PARAMS) + 1),
        ]
        for m, cells in methods.items():
            secs = np.median([r["seconds"] for r in rows if r["regime"] == g and r["method"] == m])
            row = [_cell(cells.get(p), p) for p in PARAMS]
            lines.append(f"| {m} | " + " | ".join(row) + f" | {secs:.2f} |")
        lines.append("")
    lines.append("The paper's two estimators share one timing (J4A along the line needs J2's).")
    lines += ["", *against_best(summary)]
    return "\n".join(lines) + "\n"


def against_best(summary: dict) -> list[str]:
    """hosid's efficiency over the best peer's, among the peers (not the oracle) whose
    bias is within 10 % of the truth: one table, a ratio per regime and parameter.
    """
    lines = [
        "## hosid against the best peer",
        "",
        "hosid's efficiency over that of the most efficient peer whose mean error is within "
        "10 % of the truth (which peer in brackets; the oracle is left out).",
        "",
        "| regime | " + " | ".join(PARAMS) + " |",
        "|---|" + "---|" * len(PARAMS),
    ]
    for g, methods in summary.items():
        cells = []
        for p in PARAMS:
            own = methods.get("hosid", {}).get(p)
            peers = [
                (s["eff"], m)
                for m, c in methods.items()
                if m not in ("hosid", *ORACLES)
                and (s := c.get(p)) is not None
                and abs(s["bias"]) <= 0.1 * abs(s["truth"])
            ]
            if own is None or not peers:
                cells.append("-")
                continue
            eff, best = max(peers)
            cells.append(f"{own['eff'] / eff:.2f} ({best})")
        lines.append(f"| {g} | " + " | ".join(cells) + " |")
    return [*lines, ""]


def figure(summary: dict, rows: Sequence[Mapping], path: Path) -> None:
    """Errors in bound-sd (S0: relative, in %) per regime, parameter and method."""
    regimes = list(summary)
    fig, axes = plt.subplots(
        len(regimes), len(PARAMS), figsize=(3.0 * len(PARAMS), 3.4 * len(regimes)), squeeze=False
    )
    for i, g in enumerate(regimes):
        for j, p in enumerate(PARAMS):
            ax = axes[i, j]
            for k, m in enumerate(METHODS):
                s = summary[g].get(m, {}).get(p)
                if s is None:
                    continue
                sub = [r for r in rows if r["regime"] == g and r["method"] == m]
                e = np.array([r[p] - r[f"{p}_true"] for r in sub], dtype=float)
                e = e / s["bound"] if p != "S0" else 100 * e / s["truth"]
                e = np.clip(e, -LIMIT, LIMIT)  # drawn at the edge beyond it
                x = k + np.linspace(-0.25, 0.25, e.size)
                ax.scatter(x, e, s=8, color=COLOURS[m], alpha=0.7)
                ax.plot([k - 0.3, k + 0.3], [np.nanmean(e)] * 2, color="k", lw=1.5)
            ax.axhline(0, color="0.5", lw=0.8)
            if p != "S0":
                ax.axhspan(-1, 1, color="0.9", zorder=0)
            ax.set_yscale("symlog", linthresh=1)
            ax.set_ylim(-1.2 * LIMIT, 1.2 * LIMIT)
            ax.set_yticks(TICKS, [f"{t:g}" for t in TICKS])
            ax.set_xticks(range(len(METHODS)), METHODS, rotation=60, fontsize=7)
            ax.set_title(f"{g}: {p}", fontsize=9)
            if j == 0:
                ax.set_ylabel("error / bound sd  (S0: %)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write(rows: Sequence[Mapping], out: Path, regimes: Sequence[str]) -> dict:
    """``peers.csv``, ``peers.md`` and ``peers.png`` into ``out``."""
    summary = summarize(rows, [g for g in regimes if any(r["regime"] == g for r in rows)])
    table(summary, out / "peers.csv")
    (out / "peers.md").write_text(markdown(summary, rows))
    figure(summary, rows, out / "peers.png")
    return summary
