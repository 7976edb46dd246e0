"""Summary of an efficiency study: Markdown tables and a figure from its results.csv.

Per regime and parameter, over the records whose fit succeeded:

* bias = mean(posterior mean - truth), also in CRB standard deviations and as t =
  bias / its standard error (10 records see a bias when abs(t) > 2);
* sd = standard deviation of the error over records; post sd = rms posterior sd;
* efficiency = CRB variance / MSE of the posterior mean (a1, n1, a2, n2, a1eq; the
  bound of S0 under continuous observation is 0, so S0 has none);
* coverage of the central 50 % (q25-q75) and 90 % (q05-q95) intervals, k / n;
* relative bias in % (reported for S0 and a1eq).

Then averages over regimes, coverage pooled over regimes (per parameter, and over
a1, n1, a2, n2, S0 together), and everything that looks wrong: failed fits, R-hat
>= 1.01 or ESS_bulk < 400, biases beyond 0.3 CRB sd that the records can see,
draws with a1eq <= 0, warnings.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from regimes import select

from hosid.batch import read_results

PARAMS = ("a1", "n1", "a2", "n2", "S0", "a1eq")
CRB_PARAMS = ("a1", "n1", "a2", "n2", "a1eq")
POOLED = ("a1", "n1", "a2", "n2", "S0")
RHAT_MAX, ESS_MIN = 1.01, 400.0
#: Long-row fields and the results.csv column of each (``{p}`` is the parameter).
FIELDS = {
    "truth": "true_{p}",
    "mean": "{p}_mean",
    "sd": "{p}_sd",
    "q05": "{p}_q05",
    "q25": "{p}_q25",
    "q50": "{p}_q50",
    "q75": "{p}_q75",
    "q95": "{p}_q95",
    "draw_min": "{p}_min",
    "r_hat": "{p}_r_hat",
    "ess_bulk": "{p}_ess_bulk",
    "ess_tail": "{p}_ess_tail",
}


def read_rows(path: Path) -> list[dict]:
    """One row per record and parameter from a ``hosid batch`` results.csv (numbers as
    floats, NaN when missing; ``error`` holds the message of a failed record).
    """
    rows = []
    for r in read_results(path):
        failed = r["status"] != "ok"
        for p in PARAMS:
            row = {
                "regime": r["design"],
                "record": float(r["seed_index"]),
                "param": p,
                "fit_seconds": _num(r.get("fit_seconds")),
                "warnings": r.get("warnings") or "",
                "error": (r.get("message") or r["status"]) if failed else "",
            }
            for k, col in FIELDS.items():
                row[k] = _num(r.get(col.format(p=p)))
            rows.append(row)
    return rows


def _num(value) -> float:
    return math.nan if value is None else float(value)


def group_stats(rows: Sequence[Mapping], crb_sd: float | None) -> dict:
    """Statistics of one regime and parameter (module docstring)."""
    ok = [r for r in rows if not r["error"]]
    n = len(ok)
    out: dict = {"n": n, "failed": len(rows) - n}
    if n == 0:
        return out
    m = np.array([r["mean"] for r in ok])
    t = np.array([r["truth"] for r in ok])
    e = m - t
    sd = float(np.std(e, ddof=1)) if n > 1 else math.nan
    bias = float(np.mean(e))
    mse = float(np.mean(e**2))
    out.update(
        truth=float(np.mean(t)),
        bias=bias,
        t=bias / (sd / math.sqrt(n)) if n > 1 and sd > 0 else math.nan,
        sd=sd,
        post_sd=float(np.sqrt(np.mean([r["sd"] ** 2 for r in ok]))),
        rel_bias=float(100.0 * np.mean(m / t - 1.0)),
        c50=sum(r["q25"] <= r["truth"] <= r["q75"] for r in ok),
        c90=sum(r["q05"] <= r["truth"] <= r["q95"] for r in ok),
        r_hat=float(max(r["r_hat"] for r in ok)),
        ess=float(min(r["ess_bulk"] for r in ok)),
    )
    if crb_sd:
        out.update(crb_sd=crb_sd, bias_crb=bias / crb_sd, eff=crb_sd**2 / mse)
    return out


def summarize_rows(rows: Sequence[Mapping], bounds: Mapping[str, Mapping]) -> dict:
    """Per-regime statistics, averages, pooled coverage and flags."""
    order = [r.name for r in select(None)]
    names = sorted(
        {r["regime"] for r in rows}, key=lambda n: order.index(n) if n in order else len(order)
    )
    per: dict[str, dict[str, dict]] = {}
    for name in names:
        b = bounds.get(name, {})
        per[name] = {
            p: group_stats(
                [r for r in rows if r["regime"] == name and r["param"] == p],
                b.get(f"sd_{p}") if p in CRB_PARAMS else None,
            )
            for p in PARAMS
        }
    averages = {}
    for p in PARAMS:
        st = [per[n][p] for n in names if per[n][p]["n"]]
        effs = [(s["eff"], n) for s, n in zip(st, names, strict=False) if "eff" in s]
        n_all = sum(s["n"] for s in st)
        averages[p] = {
            "n": n_all,
            "eff_mean": float(np.mean([e for e, _ in effs])) if effs else math.nan,
            "eff_min": min(effs) if effs else (math.nan, ""),
            "c50": sum(s["c50"] for s in st) / n_all if n_all else math.nan,
            "c90": sum(s["c90"] for s in st) / n_all if n_all else math.nan,
            "rel_bias": float(np.mean([s["rel_bias"] for s in st])) if st else math.nan,
            "abs_rel_bias": float(np.mean([abs(s["rel_bias"]) for s in st])) if st else math.nan,
        }
    pooled_n = sum(per[n][p]["n"] for n in names for p in POOLED)
    pooled = {
        "n": pooled_n,
        "c50": sum(per[n][p].get("c50", 0) for n in names for p in POOLED) / max(pooled_n, 1),
        "c90": sum(per[n][p].get("c90", 0) for n in names for p in POOLED) / max(pooled_n, 1),
    }
    return {"regimes": per, "averages": averages, "pooled": pooled, "flags": flags(rows, per)}


def flags(rows: Sequence[Mapping], per: Mapping[str, Mapping]) -> list[str]:
    """Everything that looks wrong, one line each."""
    out = []
    for r in rows:
        tag = f"{r['regime']} record {int(r['record'])}"
        if r["param"] == "a1" and r["error"]:
            out.append(f"failed fit: {tag}: {r['error']}")
        if r["param"] == "a1" and r["warnings"]:
            out.append(f"warnings: {tag}: {r['warnings']}")
        if r["error"]:
            continue
        if r["param"] == "a1":
            mine = [
                q
                for q in rows
                if q["regime"] == r["regime"]
                and q["record"] == r["record"]
                and q["param"] in POOLED
            ]
            worst_r = max(mine, key=lambda q: q["r_hat"])
            worst_e = min(mine, key=lambda q: q["ess_bulk"])
            if not (worst_r["r_hat"] < RHAT_MAX and worst_e["ess_bulk"] >= ESS_MIN):
                out.append(
                    f"convergence: {tag}: max R-hat {worst_r['r_hat']:.4f} "
                    f"({worst_r['param']}), min ESS_bulk {worst_e['ess_bulk']:.0f} "
                    f"({worst_e['param']})"
                )
        if r["param"] == "a1eq" and not r["draw_min"] > 0:
            out.append(f"a1eq <= 0 in a draw: {tag}: min {r['draw_min']:.3g}")
    for name, st in per.items():
        for p, s in st.items():
            if "bias_crb" in s and abs(s["bias_crb"]) > 0.3 and abs(s["t"]) > 2:
                out.append(
                    f"bias: {name} {p}: {s['bias']:+.4g} = {s['bias_crb']:+.2f} CRB sd, "
                    f"t = {s['t']:+.1f} over {s['n']} records"
                )
    return out


def _f(x: float, spec: str = ".3g") -> str:
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def markdown(summary: Mapping, cost: str, path: Path, seconds: Sequence[float]) -> str:
    """The Markdown report."""
    per, av, pooled = summary["regimes"], summary["averages"], summary["pooled"]
    names = list(per)
    lines = [
        f"# Efficiency and calibration: cost {cost}",
        "",
        f"From `{path.name}`: {len(names)} regimes; fit time median "
        f"{_f(float(np.median(seconds)), '.1f')} s, max {_f(max(seconds), '.1f')} s, "
        f"total {_f(sum(seconds) / 60, '.1f')} min.",
        "",
        "## Efficiency (CRB variance / MSE of the posterior mean)",
        "",
        "| regime | n | " + " | ".join(CRB_PARAMS) + " | S0 bias % | a1eq bias % |",
        "|---|---|" + "---|" * (len(CRB_PARAMS) + 2),
    ]
    for n in names:
        st = per[n]
        lines.append(
            f"| {n} | {st['a1']['n']} | "
            + " | ".join(_f(st[p].get("eff", math.nan), ".2f") for p in CRB_PARAMS)
            + f" | {_f(st['S0'].get('rel_bias', math.nan), '+.2f')}"
            f" | {_f(st['a1eq'].get('rel_bias', math.nan), '+.2f')} |"
        )
    lines.append(
        "| **mean** | | "
        + " | ".join(_f(av[p]["eff_mean"], ".2f") for p in CRB_PARAMS)
        + f" | {_f(av['S0']['rel_bias'], '+.2f')} | {_f(av['a1eq']['rel_bias'], '+.2f')} |"
    )
    lines.append(
        "| **min** | | "
        + " | ".join(
            f"{_f(av[p]['eff_min'][0], '.2f')} ({av[p]['eff_min'][1]})" for p in CRB_PARAMS
        )
        + " | | |"
    )
    lines += [
        "",
        "## Coverage pooled over regimes",
        "",
        "| | " + " | ".join(PARAMS) + " | pooled a1, n1, a2, n2, S0 |",
        "|---|" + "---|" * (len(PARAMS) + 1),
        "| 50 % | "
        + " | ".join(_f(av[p]["c50"], ".2f") for p in PARAMS)
        + f" | {_f(pooled['c50'], '.3f')} |",
        "| 90 % | "
        + " | ".join(_f(av[p]["c90"], ".2f") for p in PARAMS)
        + f" | {_f(pooled['c90'], '.3f')} |",
        "| n | " + " | ".join(str(av[p]["n"]) for p in PARAMS) + f" | {pooled['n']} |",
        "",
        "Mean abs relative bias over regimes: "
        f"S0 {_f(av['S0']['abs_rel_bias'], '.2f')} %, "
        f"a1eq {_f(av['a1eq']['abs_rel_bias'], '.2f')} %.",
        "",
        "## Per regime and parameter",
        "",
        "| regime | param | truth | bias | bias/CRB sd | t | sd | post sd | CRB sd "
        "| efficiency | bias % | cov 50 | cov 90 | max R-hat | min ESS |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for n in names:
        for p in PARAMS:
            s = per[n][p]
            if not s["n"]:
                lines.append(f"| {n} | {p} | no successful fit ({s['failed']} failed) |")
                continue
            lines.append(
                f"| {n} | {p} | {s['truth']:.4g} | {s['bias']:+.3g} | "
                f"{_f(s.get('bias_crb', math.nan), '+.2f')} | {_f(s['t'], '+.1f')} | "
                f"{_f(s['sd'])} | {s['post_sd']:.3g} | {_f(s.get('crb_sd', math.nan))} | "
                f"{_f(s.get('eff', math.nan), '.2f')} | {s['rel_bias']:+.2f} | "
                f"{s['c50']}/{s['n']} | {s['c90']}/{s['n']} | {s['r_hat']:.4f} | {s['ess']:.0f} |"
            )
    lines += ["", "## Flags", ""]
    lines += [f"- {f}" for f in summary["flags"]] or ["- none"]
    return "\n".join(lines) + "\n"


def figure(summary: Mapping, cost: str, path: Path) -> None:
    """Efficiency per parameter and regime; coverage per parameter with nominal lines."""
    per, av = summary["regimes"], summary["averages"]
    names = list(per)
    fig = Figure(figsize=(12, 4.8), layout="constrained")
    ax, bx = fig.subplots(1, 2, width_ratios=(1.3, 1))
    width = 0.8 / max(len(names), 1)
    for i, n in enumerate(names):
        eff = [per[n][p].get("eff", math.nan) for p in CRB_PARAMS]
        ax.bar(
            np.arange(len(CRB_PARAMS)) + (i - (len(names) - 1) / 2) * width, eff, width, label=n
        )
    ax.plot(
        np.arange(len(CRB_PARAMS)),
        [av[p]["eff_mean"] for p in CRB_PARAMS],
        "k_",
        ms=30,
        mew=2,
        label="mean",
    )
    for y, ls in ((1.0, "-"), (0.5, "--"), (0.3, ":")):
        ax.axhline(y, color="0.4", ls=ls, lw=0.8)
    ax.set_xticks(range(len(CRB_PARAMS)), CRB_PARAMS)
    ax.set_ylabel("efficiency = CRB variance / MSE")
    ax.set_title(f"efficiency ({cost})")
    ax.legend(fontsize=7, ncol=4, loc="upper center", bbox_to_anchor=(0.5, -0.07))
    x = np.arange(len(PARAMS))
    for level, key, colour, band in (
        (0.5, "c50", "C0", (0.35, 0.65)),
        (0.9, "c90", "C3", (0.80, 0.97)),
    ):
        bx.axhspan(*band, color=colour, alpha=0.08)
        bx.axhline(level, color=colour, lw=0.8)
        for n in names:
            cov = [
                per[n][p]["c50" if key == "c50" else "c90"] / per[n][p]["n"]
                if per[n][p]["n"]
                else math.nan
                for p in PARAMS
            ]
            bx.plot(x, cov, ".", color=colour, alpha=0.35, ms=5)
        bx.plot(
            x,
            [av[p][key] for p in PARAMS],
            "o",
            color=colour,
            ms=8,
            label=f"{int(100 * level)} % pooled",
        )
    bx.set_xticks(x, PARAMS)
    bx.set_ylim(-0.02, 1.02)
    bx.set_ylabel("coverage (dots: per regime)")
    bx.set_title("interval coverage, nominal lines and accepted bands")
    bx.legend(fontsize=8, loc="lower left")
    fig.savefig(path, dpi=120)


def write_summary(csv_file: Path, bounds: Mapping[str, Mapping], out: Path, cost: str) -> dict:
    """Write ``efficiency_<cost>.md`` and ``.png``; return the summary (and their paths)."""
    rows = read_rows(csv_file)
    summary = summarize_rows(rows, bounds)
    seconds = [r["fit_seconds"] for r in rows if r["param"] == "a1"]
    md = out / f"efficiency_{cost}.md"
    png = out / f"efficiency_{cost}.png"
    md.write_text(markdown(summary, cost, csv_file, seconds))
    figure(summary, cost, png)
    return {**summary, "markdown": md, "figure": png}
