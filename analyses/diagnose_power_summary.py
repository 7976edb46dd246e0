"""The summary of ``diagnose_power.py``: power table, false alarms, confusion, figure.

``summarize(rows, bounds, out)`` writes ``power.md`` and ``power.png`` into ``out``
from the rows of ``power.csv`` (each number with its record count).
"""

from __future__ import annotations

import json
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

COORD = {
    "quadratic_damping": "n1",
    "cubic_stiffness": "n2",
    "quadratic_stiffness": "b2",
    "coulomb_friction": "mu",
    "excitation_mean": "m",
    "coloured_excitation": "1/wc^2",
    "measurement_noise": "noise_sd^2",
}
SHORT = {
    "none": "none",
    "quadratic_damping": "n1",
    "cubic_stiffness": "n2",
    "quadratic_stiffness": "b2",
    "coulomb_friction": "mu",
    "excitation_mean": "m",
    "coloured_excitation": "wc",
    "measurement_noise": "noise",
}


def _ok(rows):
    return [r for r in rows if not r.get("error")]


def power_table(rows: list[dict]) -> tuple[str, dict]:
    """Share of records naming the hidden effect (and exactly it), by effect and strength."""
    single = [r for r in rows if r["hidden"] != "none" and "+" not in r["hidden"]]
    groups = defaultdict(list)
    for r in single:
        groups[(r["regime"], r["system"], r["hidden"], float(r["strength"]))].append(r)
    strengths = sorted({k[3] for k in groups})
    keys = sorted({k[:3] for k in groups})
    lines = [
        "| regime | base | effect | " + " | ".join(f"{s:g} sd" for s in strengths) + " |",
        "|---|---|---|" + "---|" * len(strengths),
    ]
    curves = {}
    for key in keys:
        cells, curve = [], []
        for s in strengths:
            rs = groups.get((*key, s), [])
            ok = _ok(rs)
            if not rs:
                cells.append("")
                continue
            hit = sum(int(r["hit"]) for r in ok)
            exact = sum(int(r["exact"]) for r in ok)
            err = len(rs) - len(ok)
            cells.append(f"{hit}/{len(ok)} ({exact})" + (f" [{err} failed]" if err else ""))
            curve.append((s, hit / max(len(ok), 1)))
        curves[key] = curve
        base = "paper" if key[1] == "paper" else "linear"
        lines.append(
            f"| {key[0]} | {base} | {key[2]} ({COORD[key[2]]}) | " + " | ".join(cells) + " |"
        )
    return "\n".join(lines) + "\n", curves


def reference_power(rows: list[dict]) -> str:
    r"""What a test using all the information could do with the same false-alarm rate.

    A round names an effect when the smallest of the ``m`` candidates' calibrated p-values
    is at most :math:`\alpha` = 5 %; for independent candidates each one's level is then
    :math:`\alpha_m = 1 - (1 - \alpha)^{1/m}` (Sidak).  An efficient statistic for an
    effect at :math:`k` sd is :math:`Z \sim N(k, 1)`, so the power is
    :math:`\Phi(k - z_{\alpha_m/2})` for a two-sided test and :math:`\Phi(k - z_{\alpha_m})`
    at a boundary null (friction, corner, noise).  Correlated candidates make the
    calibrated level a little larger than Sidak's, so this is close to, not above, the
    best attainable.
    """
    from scipy.stats import norm

    from hosid.check.evidence import COORDINATES
    from hosid.model.model import Model

    single = [r for r in rows if r["hidden"] != "none" and "+" not in r["hidden"]]
    strengths = sorted({float(r["strength"]) for r in single})
    keys = sorted({(r["system"], r["hidden"]) for r in single})
    lines = [
        "| base | candidates m | effect | test | "
        + " | ".join(f"{s:g} sd" for s in strengths)
        + " |",
        "|---|---|---|---|" + "---|" * len(strengths),
    ]
    for system, effect in keys:
        m = len(Model.from_spec(system).candidates)
        level = 1.0 - 0.95 ** (1.0 / m)
        boundary = COORDINATES[effect].boundary
        z = norm.isf(level if boundary else level / 2.0)
        power = [norm.sf(z - k) for k in strengths]
        test = f"one-sided, z > {z:.2f}" if boundary else f"two-sided, abs(z) > {z:.2f}"
        lines.append(
            f"| {system} | {m} | {SHORT[effect]} | {test} | "
            + " | ".join(f"{p:.2f}" for p in power)
            + " |"
        )
    return "\n".join(lines) + "\n"


def efficiency(rows: list[dict]) -> str:
    r"""How much of the information the first round's ratio uses: for an effect at
    :math:`k` sd and an estimator of efficiency :math:`e`, :math:`E[D] \approx e k^2 + 1`,
    so :math:`\hat e = (\bar D - 1)/k^2` (for :math:`k \ge 3`; a boundary null gives a
    little less than 1 for the ``+ 1``).
    """
    groups = defaultdict(list)
    for r in _ok(rows):
        if r["hidden"] != "none" and "+" not in r["hidden"] and float(r["strength"]) >= 3:
            D = json.loads(r["evidence"])[r["hidden"]][1]
            groups[(r["regime"], r["system"], r["hidden"])].append((float(r["strength"]), D))
    lines = ["| regime | base | effect | strengths | records | efficiency (D - 1)/k^2 |",
             "|---|---|---|---|---|---|"]  # fmt: skip
    for key, vals in sorted(groups.items()):
        k, D = np.array(vals).T
        e = (D - 1.0) / k**2
        ks = ", ".join(f"{x:g}" for x in sorted(set(k)))
        lines.append(
            f"| {key[0]} | {key[1]} | {SHORT[key[2]]} | {ks} | {len(D)} | "
            f"{np.mean(e):.2f} +- {np.std(e, ddof=1) / np.sqrt(len(e)) if len(e) > 1 else 0:.2f} |"
        )
    return "\n".join(lines) + "\n"


def false_alarms(rows: list[dict]) -> str:
    """Clean records with any effect named, per regime and base."""
    lines = ["| regime | base | records | named any | which |", "|---|---|---|---|---|"]
    clean = defaultdict(list)
    for r in rows:
        if r["hidden"] == "none":
            clean[(r["regime"], r["system"])].append(r)
    for (regime, system), rs in sorted(clean.items()):
        ok = _ok(rs)
        fa = [r for r in ok if r["named"] != "none"]
        which = Counter(r["named"] for r in fa)
        share = 100 * len(fa) / max(len(ok), 1)
        named = ", ".join(f"{k} x{v}" for k, v in which.items()) or "-"
        lines.append(f"| {regime} | {system} | {len(ok)} | {len(fa)} ({share:.0f} %) | {named} |")
    return "\n".join(lines) + "\n"


def confusion(rows: list[dict], min_strength: float = 3.0) -> str:
    """Hidden effect (rows) against the first named effect (columns), single effects at
    ``min_strength`` sd or more and clean records.
    """
    use = [
        r
        for r in _ok(rows)
        if "+" not in r["hidden"]
        and (r["hidden"] == "none" or float(r["strength"]) >= min_strength)
    ]
    hidden = sorted({r["hidden"] for r in use}, key=lambda h: (h != "none", h))
    named = sorted({r["first"] for r in use} | {"none"}, key=lambda h: (h != "none", h))
    lines = [
        "| hidden \\ first named | " + " | ".join(SHORT.get(n, n) for n in named) + " | records |",
        "|---|" + "---|" * (len(named) + 1),
    ]
    for h in hidden:
        rs = [r for r in use if r["hidden"] == h]
        c = Counter(r["first"] for r in rs)
        lines.append(
            f"| {SHORT.get(h, h)} | "
            + " | ".join(str(c.get(n, 0)) for n in named)
            + f" | {len(rs)} |"
        )
    return "\n".join(lines) + "\n"


def two_effects(rows: list[dict]) -> str:
    """Records with two hidden effects: both named, the order, the gaps after each step."""
    head = (
        "| regime | hidden | records | both named | exactly | gap fell each step "
        "(finite gaps) | named |"
    )
    lines = [head, "|---|---|---|---|---|---|---|"]
    groups = defaultdict(list)
    for r in _ok(rows):
        if "+" in r["hidden"]:
            groups[(r["regime"], r["hidden"], r["strength"])].append(r)
    for (regime, hidden, s), rs in sorted(groups.items()):
        named = Counter(r["named"] for r in rs)
        shrank = [r for r in rs if r["shrank"] != "" and not any(np.isinf(_gaps(r)[1:]))]
        hit, exact = sum(int(r["hit"]) for r in rs), sum(int(r["exact"]) for r in rs)
        fell = sum(int(r["shrank"]) for r in shrank)
        which = ", ".join(f"{k} x{v}" for k, v in named.items())
        lines.append(
            f"| {regime} | {hidden} at {float(s):g} sd | {len(rs)} | {hit} | {exact} | "
            f"{fell}/{len(shrank)} | {which} |"
        )
    return "\n".join(lines) + "\n"


def _gaps(row: dict) -> list[float]:
    return [float(g) for g in row["gaps"].split(";")]


def gap_shrink(rows: list[dict]) -> str:
    """How often the gap fell at every step, among records that named something; steps
    whose models' simulations all diverge (an infinite gap before and after) apart.
    """
    named = [r for r in _ok(rows) if r["named"] != "none"]
    diverged = [r for r in named if any(np.isinf(_gaps(r)[1:]))]
    finite = [r for r in named if r not in diverged]
    right = [r for r in finite if int(r["exact"])]
    fell = sum(int(r["shrank"]) for r in finite)
    return (
        f"Of {len(named)} records that named something, {len(diverged)} named an effect whose "
        "model's posterior-predictive simulations diverged as the model before it did (an "
        "infinite gap before and after: the gap cannot judge, the evidence decided). In the "
        f"other {len(finite)} the gap fell at every step in {fell} "
        f"({sum(int(r['shrank']) for r in right)} of the {len(right)} that named exactly the "
        "hidden effects).\n"
    )


def timing(rows: list[dict]) -> str:
    sec = np.array([float(r["seconds"]) for r in rows if r.get("seconds")])
    if sec.size == 0:
        return ""
    return (
        f"{len(sec)} records, {sec.sum() / 3600:.2f} h in all; per record median "
        f"{np.median(sec):.1f} s, 90 % {np.quantile(sec, 0.9):.1f} s, max {sec.max():.1f} s "
        "(wall time of each record as run: the machine's load is not recorded).\n"
    )


def bounds_table(bounds: dict) -> str:
    lines = ["| regime | base | effect | coordinate | CRB sd |", "|---|---|---|---|---|"]
    for (regime, system, effect), sd in sorted(bounds.items()):
        coord = COORD[effect.split(" given ")[0]]  # also "e given o=k": e's bound given o
        lines.append(f"| {regime} | {system} | {effect} | {coord} | {sd:.4g} |")
    return "\n".join(lines) + "\n"


def figure(curves: dict, path: Path) -> None:
    """One panel a regime: the share of records naming each effect against its strength
    (solid: the paper base, dashed: the linear base), over the band of
    :func:`reference_power`'s efficient test with the paper base's 5 candidates (lower
    edge two-sided, upper edge one-sided).
    """
    from matplotlib.figure import Figure
    from scipy.stats import norm

    regimes = sorted({key[0] for key, c in curves.items() if c})
    if not regimes:
        return
    fig = Figure(figsize=(4.2 * len(regimes), 4.2), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(regimes), sharey=True))
    colors = {e: f"C{i}" for i, e in enumerate(COORD)}  # one colour an effect
    level = 1.0 - 0.95 ** (1.0 / 5)
    for ax, regime in zip(axes, regimes, strict=True):
        keys = [k for k in sorted(curves) if k[0] == regime and curves[k]]
        s_all = [s for k in keys for s, _ in curves[k]]
        k = np.geomspace(min(s_all), max(s_all), 100)
        ax.fill_between(k, norm.sf(norm.isf(level / 2) - k), norm.sf(norm.isf(level) - k),
                        color="0.85", label="efficient test, 5 candidates")  # fmt: skip
        for key in keys:
            s, p = zip(*curves[key], strict=True)
            ls = "-" if key[1] == "paper" else "--"
            ax.plot(s, p, ls, color=colors[key[2]], marker="o",
                    label=f"{SHORT[key[2]]} ({key[1]} base)")  # fmt: skip
        ax.set_xscale("log")
        ticks = sorted(set(s_all))
        ax.set_xticks(ticks, [f"{t:g}" for t in ticks])
        ax.set_xticks([], minor=True)
        ax.set_title(regime, fontsize=10)
        ax.set_xlabel("strength (Cramer-Rao sd)")
        ax.axhline(0.9, color="0.6", lw=0.6)
        ax.axhline(0.5, color="0.6", lw=0.6)
        ax.set_ylim(-0.03, 1.03)
        ax.legend(fontsize=7)
    axes[0].set_ylabel("share of records naming the effect")
    fig.savefig(path, dpi=110)


def summarize(rows: list[dict], bounds: dict, out: Path) -> str:
    """Write ``power.md`` and ``power.png``; return the markdown."""
    table, curves = power_table(rows)
    reps = sorted({int(r.get("replicates") or 20) for r in rows})  # older rows: 20
    commit = (out / "COMMIT").read_text().strip() if (out / "COMMIT").exists() else ""
    parts = [
        "# diagnose: power against the information limit\n",
        "Records from the independent simulator; `diagnose(..., posterior='screen', "
        f"candidate_gaps=False, replicates={'/'.join(map(str, reps))})`, alpha = 5 % a round. "
        "Cells: named the hidden effect / records (in brackets: named exactly the hidden "
        "effect and nothing else)." + (f" Code: commit {commit}." if commit else "") + "\n",
        "## Power\n",
        table,
        "## What an efficient test could do at the same false-alarm rate\n",
        reference_power(rows),
        "## False alarms on clean records\n",
        false_alarms(rows),
        "## How much of the information the test uses\n",
        efficiency(rows),
        "## Confusion (first named effect; single effects at >= 3 sd, and clean records)\n",
        confusion(rows),
        "## Two hidden effects\n",
        two_effects(rows),
        "## The gap\n",
        gap_shrink(rows),
        "## Bounds (sd of each effect's coordinate at its null)\n",
        bounds_table(bounds),
        "## Time\n",
        timing(rows),
    ]
    text = "\n".join(parts)
    out.mkdir(parents=True, exist_ok=True)
    (out / "power.md").write_text(text)
    if curves:
        figure(curves, out / "power.png")
    failed = [r for r in rows if r.get("error")]
    if failed:
        text += f"\n{len(failed)} failed records: " + json.dumps(
            Counter(r["error"][:80] for r in failed)
        )
    return text
