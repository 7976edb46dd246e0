"""The figures of ``paper_figures.py``: one PNG per paper figure (7 and 8 side by side)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

MARKERS = {
    "moments": ("D", "k"),
    "J2 free": ("^", "C0"),
    "J2+J4A free": ("o", "C3"),
    "J2": ("v", "C1"),
    "J2 split": ("^", "C0"),
    "J4A line": ("s", "C3"),
    "hosid": ("x", "C2"),
}
LABELS = {
    "moments": "moment method",
    "J2 free": "second order (J2, all free)",
    "J2+J4A free": "fourth order (J2 + J4A, all free)",
    "J2": "second order (J2, moment stiffness)",
    "J2 split": "second order (J2 alone)",
    "J4A line": "fourth order (J4A along eq 65)",
    "hosid": "hosid estimate",
}


def _finish(fig, ax, path, xlabel, ylabel):
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _rows(result, figure, name):
    return [r for r in result["rows"] if r["figure"] == figure and r["estimator"] == name]


def _sweep(result, param, path, truth=None, *, log_y=False, ylim=None):
    """Estimates of ``param`` against S0 (Figures 1, 2, 4, 5)."""
    fig, ax = plt.subplots(figsize=(7.0, 4.6))
    levels = sorted({r["S0_true"] for r in result["rows"] if r["figure"] == "1-2,4-5"})
    names = [n for n in MARKERS if _rows(result, "1-2,4-5", n)]
    for j, name in enumerate(names):
        rows = [r for r in _rows(result, "1-2,4-5", name) if np.isfinite(r[param])]
        if not rows:
            continue
        x = np.array([r["S0_true"] for r in rows]) * (1 + 0.05 * (j - len(names) / 2))
        m, c = MARKERS[name]
        ax.scatter(
            x,
            [r[param] for r in rows],
            marker=m,
            color=c,
            s=22,
            alpha=0.75,
            label=LABELS[name],
            facecolors="none" if m in "^Ds" else None,
        )
    post = [p for p in result["posteriors"] if p["figure"] == "1-2,4-5"]
    ax.errorbar(
        [p["S0_true"] * 0.82 for p in post],
        [p[f"{param}_q50"] for p in post],
        yerr=[
            [p[f"{param}_q50"] - p[f"{param}_q05"] for p in post],
            [p[f"{param}_q95"] - p[f"{param}_q50"] for p in post],
        ],
        fmt="o",
        color="C2",
        ms=3,
        capsize=3,
        label="hosid posterior, 90 %",
    )
    if truth == "level":
        ax.plot(levels, levels, "k-", lw=1, label="true value")
    elif truth == "a1eq":
        true = [
            np.mean(
                [r["a1eq_true"] for r in _rows(result, "1-2,4-5", "moments") if r["S0_true"] == S0]
            )
            for S0 in levels
        ]
        ax.plot(levels, true, "k-", lw=1, label="true value (eq 65)")
    elif truth is not None:
        ax.axhline(truth, color="k", lw=1, label="true value")
    ax.set_xscale("log")
    if log_y:
        ax.set_yscale("log")
    if ylim:
        ax.set_ylim(*ylim)
    _finish(fig, ax, path, "S0", param)


def _force(result, path):
    f = result["force"]
    x = np.linspace(-f["x_max"], f["x_max"], 201)
    fig, ax = plt.subplots(figsize=(7.0, 4.6))
    a2, n2 = f["draws"]
    band = np.quantile(a2[:, None] * x + n2[:, None] * x**3, [0.05, 0.95], axis=0)
    ax.fill_between(x, band[0], band[1], color="C2", alpha=0.3, label="hosid posterior, 90 %")
    styles = iter(["C0--", "C0:", "C3--", "C3:", "k-."])
    for name, val in f.items():
        if name in ("x_max", "draws"):
            continue
        ax.plot(x, val[0] * x + val[1] * x**3, next(styles), lw=1.2, label=name)
    ax.plot(x, 25.0 * x + 5.0 * x**3, "k-", lw=1, label="true a2 x + n2 x^3")
    _finish(fig, ax, path, "x", "restoring force")


def _damping(result, path):
    fig, ax = plt.subplots(figsize=(7.0, 5.0))
    d = result["fig6_draws"]
    ax.scatter(
        d["a1"][::8],
        d["n1"][::8],
        s=2,
        color="C2",
        alpha=0.15,
        label="hosid posterior draws (record 0)",
    )
    for name in ("J2 split", "J4A line", "hosid"):
        rows = _rows(result, "6", name)
        m, c = MARKERS[name]
        ax.scatter(
            [r["a1"] for r in rows],
            [r["n1"] for r in rows],
            marker=m,
            color=c,
            s=24,
            facecolors="none" if m in "^s" else None,
            label=LABELS[name],
        )
    sv = result["sigma_v6"]
    a1 = np.linspace(0.0, result["a1eq6"], 50)
    ax.plot(
        a1,
        (result["a1eq6"] - a1) / (np.sqrt(8 / np.pi) * sv),
        "k:",
        lw=1,
        label="eq (65) at the true a1eq",
    )
    ax.plot(0.5, 0.5, "k*", ms=12, label="true value")
    _finish(fig, ax, path, "a1", "n1")


def _maps(result, path):
    m = result["maps"]
    fig, axes = plt.subplots(1, 2, figsize=(12.0, 4.8))
    sv = result["sigma_v6"]
    for ax, cost, key in zip(axes, ("J2", "J4A"), ("default", "J4A"), strict=True):
        z = np.log10(m[cost] - m[cost].min() + 1e-12 * np.ptp(m[cost]) + 1e-300)
        cs = ax.contourf(m["a1"], m["n1"], z.T, levels=20, cmap="viridis")
        fig.colorbar(cs, ax=ax, label=f"log10({cost} - min)")
        d = result["free"][key]
        ax.scatter(
            d["a1"][::8],
            d["n1"][::8],
            s=2,
            color="w",
            alpha=0.3,
            label=f"unconstrained posterior ({key})",
        )
        ax.plot([0.5, -0.5], [0.5, -0.5], "r*", ms=10, label="truth and its mirror")
        a = np.array([m["a1"][0], m["a1"][-1]])
        ax.plot(a, -a / (np.sqrt(8 / np.pi) * sv), "w--", lw=1, label="a1eq = 0")
        ax.set_xlim(m["a1"][0], m["a1"][-1])
        ax.set_ylim(m["n1"][0], m["n1"][-1])
        ax.set_xlabel("a1")
        ax.set_ylabel("n1")
        ax.set_title(f"Figure {7 if cost == 'J2' else 8}: {cost} as printed, S0 = 100")
        ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def draw_all(result: dict, out: Path) -> None:
    """Every figure into ``out``."""
    _sweep(result, "a2", out / "fig01_a2.png", 25.0, ylim=(0, 60))
    _sweep(result, "n2", out / "fig02_n2.png", 5.0, ylim=(-5, 15))
    _force(result, out / "fig03_restoring_force.png")
    _sweep(result, "a1eq", out / "fig04_a1eq.png", "a1eq")
    _sweep(result, "S0", out / "fig05_S0.png", "level", log_y=True)
    _damping(result, out / "fig06_damping.png")
    _maps(result, out / "fig07_08_maps.png")
