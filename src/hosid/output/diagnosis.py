r"""The report of :func:`hosid.check.diagnose.diagnose`: figures, ``report.json``, HTML.

:func:`write_diagnosis` writes into a directory

- ``report.json``: :meth:`hosid.check.diagnosis_result.Diagnosis.report` (infinite gaps as
  ``null``);
- ``evidence.png`` (:func:`evidence_figure`): every round's evidence for every
  candidate, the Wald :math:`z` and the quasi-likelihood ratio's calibrated p-value,
  with the thresholds of the decision;
- ``posterior.png`` (:func:`posterior_figure`, when an effect is named): the posterior
  of every named effect's parameter, its null marked;
- ``gaps.png`` (:func:`gap_figure`): the total gap of the base model, of every
  screened first-round candidate and of each model along the named steps, with the
  base model's null band and the base gap (a named step must fall below the gap before
  it);
- ``measure_gaps.png`` (:func:`measure_gap_figure`): the gap :math:`G_m` of every
  measure for every model, so that one sees which measure each effect closes;
- ``measures.png`` (:func:`measures_figure`): the record's standardized distance
  :math:`z_j` from the replicates, component by component, for the measures that
  moved most, before (base) and after (final model);
- ``report.html``: a self-contained page (figures embedded) from the jinja2 template
  ``output/templates/diagnosis.html.j2``.

Figures are :class:`matplotlib.figure.Figure` objects (no pyplot state).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.figure import Figure

from ..check.evidence import critical_z
from ..check.measures import component_labels
from .files import b64, make_dir, png, render, write_atomic
from .results import jsonable

if TYPE_CHECKING:  # pragma: no cover
    from ..check.diagnose import Diagnosis

__all__ = [
    "evidence_figure",
    "gap_figure",
    "measure_gap_figure",
    "measures_figure",
    "moved_measures",
    "posterior_figure",
    "render_html",
    "write_diagnosis",
]

_NAMED, _BASE, _OTHER = "tab:green", "0.45", "tab:blue"


def _models(diag: Diagnosis) -> list[tuple[str, Any]]:
    """``(label, check)`` of the base, every screened candidate and each named step."""
    fit = diag.base.method
    rows = [(f"base ({fit})", diag.base)]
    rows += [(f"+ {c} (screen)", chk) for c, chk in diag.candidates.items()]
    names: list[str] = []
    for st in diag.steps:
        names.append(st.effect)
        rows.append((f"step {len(names)}: + {' + '.join(names)} ({st.check.method})", st.check))
    return rows


def gap_figure(diag: Diagnosis) -> Figure:
    """Horizontal bars of the total gap of every model (module docstring)."""
    rows = _models(diag)
    labels = [r[0] for r in rows]
    values = np.array([r[1].total for r in rows], dtype=float)
    finite = values[np.isfinite(values)]
    cap = 1.2 * float(finite.max()) if finite.size else 1.0
    diverged = ~np.isfinite(values)
    values = np.where(diverged, cap, values)
    colors = [
        _BASE if i == 0 else (_NAMED if lab.startswith("step") else _OTHER)
        for i, lab in enumerate(labels)
    ]
    fig = Figure(figsize=(7.5, 0.45 * len(rows) + 1.4), layout="constrained")
    ax = fig.subplots()
    y = np.arange(len(rows))[::-1]
    bars = ax.barh(y, values, color=colors)
    ax.set_yticks(y, labels)
    for bar, div in zip(bars, diverged, strict=True):
        if div:
            bar.set_hatch("//")
            ax.text(cap, bar.get_y() + bar.get_height() / 2, " diverges", va="center", fontsize=8)
    null = np.asarray(diag.base.gap["null"], dtype=float)
    null = null[np.isfinite(null)]
    if null.size:
        ax.axvspan(
            float(null.min()), float(null.max()), color="0.88", zorder=0, label="base null range"
        )
    if math.isfinite(diag.base.total):
        ax.axvline(diag.base.total, color="tab:red", ls="--", label="base gap")
    ax.axvline(1.0, color="k", lw=0.6)
    ax.set_xlabel("total gap G (replicate standard deviations)")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="lower right", fontsize=8)
    return fig


def measure_gap_figure(diag: Diagnosis) -> Figure:
    r"""The gap :math:`G_m` of every measure (columns) for every model (rows)."""
    rows = _models(diag)
    names = list(diag.base.gap["measures"])
    G = np.array([[chk.gap["measures"].get(m, np.nan) for m in names] for _, chk in rows])
    shown = np.where(np.isfinite(G), G, np.nan)
    fig = Figure(figsize=(0.62 * len(names) + 3.2, 0.42 * len(rows) + 1.9), layout="constrained")
    ax = fig.subplots()
    top = max(3.0, float(np.nanmax(shown)) if np.isfinite(shown).any() else 3.0)
    im = ax.imshow(np.log10(np.maximum(shown, 0.1)), cmap="Reds", vmin=-0.3, vmax=np.log10(top))
    for i in range(G.shape[0]):
        for j in range(G.shape[1]):
            text = "inf" if not np.isfinite(G[i, j]) else f"{G[i, j]:.1f}"
            dark = np.isfinite(G[i, j]) and G[i, j] > math.sqrt(top)
            ax.text(j, i, text, ha="center", va="center", fontsize=7, color="w" if dark else "k")
    ax.set_xticks(range(len(names)), names, rotation=40, ha="right", fontsize=8)
    ax.set_yticks(range(len(rows)), [r[0] for r in rows], fontsize=8)
    fig.colorbar(im, ax=ax, shrink=0.8, label="log10 G_m")
    return fig


def moved_measures(diag: Diagnosis, most: int = 4) -> list[str]:
    """The measures whose gap changed most from the base to the final model."""
    before = diag.base.gap["measures"]
    after = diag.final.gap["measures"]
    if diag.base.diverged:  # no finite "before": show where the final model is worst
        return sorted(after, key=lambda k: -after[k])[:most]
    return sorted(before, key=lambda k: -abs(before[k] - after[k]))[:most]


def measures_figure(diag: Diagnosis, names: Sequence[str] | None = None) -> Figure:
    r"""For each measure, the record's standardized distance :math:`z_j` from the
    replicates of the base model and of the final model, component by component.
    """
    names = list(moved_measures(diag) if names is None else names)
    n = max(1, len(names))
    ncol = 2 if n > 1 else 1
    nrow = math.ceil(n / ncol)
    fig = Figure(figsize=(4.6 * ncol, 2.6 * nrow), layout="constrained")
    axes = np.atleast_1d(fig.subplots(nrow, ncol, squeeze=False)).ravel()
    named = " + ".join(diag.named_effects)
    after_label = f"after: + {named}" if named else "after: base"
    for ax, name in zip(axes, names, strict=False):
        zb = np.asarray(diag.base.gap["z"][name], dtype=float)
        za = np.asarray(diag.final.gap["z"][name], dtype=float)
        zb, za = (np.where(np.isfinite(z), z, np.nan) for z in (zb, za))
        idx = np.arange(zb.size)
        ax.bar(idx - 0.2, zb, width=0.4, color=_BASE, label="before: base")
        ax.bar(idx + 0.2, za, width=0.4, color=_NAMED, label=after_label)
        ax.axhspan(-2, 2, color="tab:blue", alpha=0.08, zorder=0)
        ax.axhline(0, color="k", lw=0.6)
        gb, ga = diag.base.gap["measures"][name], diag.final.gap["measures"][name]
        ax.set_title(f"{name}: G {gb:.2f} -> {ga:.2f}", fontsize=9)
        ax.set_xticks(idx, component_labels(name, zb.size), fontsize=7)
        ax.set_ylabel("z (replicate sd)", fontsize=8)
    for ax in axes[n:]:
        ax.set_visible(False)
    axes[0].legend(fontsize=7)
    return fig


def evidence_figure(diag: Diagnosis) -> Figure:
    r"""Every round's evidence: the Wald :math:`|z|` and :math:`-\log_{10}` of the
    calibrated and asymptotic p-values of each candidate, the decision's thresholds
    (the Wald threshold of the round's level, alpha) dashed.
    """
    rounds = diag.rounds or []
    n = max(1, len(rounds))
    fig = Figure(figsize=(9.0, 2.3 * n + 0.6), layout="constrained")
    axes = np.atleast_2d(fig.subplots(n, 2, squeeze=False))
    for k, rnd in enumerate(rounds):
        names = sorted(rnd.evidence, key=lambda c: rnd.evidence[c].log_p)
        y = np.arange(len(names))[::-1]
        chosen = diag.steps[k].effect if k < len(diag.steps) else None
        colors = [_NAMED if c == chosen else _OTHER for c in names]
        z = [abs(rnd.evidence[c].z) for c in names]
        lp = [-math.log10(max(rnd.adjusted(c), 1e-300)) for c in names]
        lp_raw = [-rnd.evidence[c].log_p / math.log(10) for c in names]
        ax_z, ax_p = axes[k]
        ax_z.barh(y, z, color=colors)
        for c, yy in zip(names, y, strict=True):
            zc = critical_z(rnd.wald_level, rnd.evidence[c].coordinate.boundary)
            ax_z.plot([zc, zc], [yy - 0.4, yy + 0.4], color="tab:red", ls="--", lw=1)
        ax_z.set_yticks(y, names, fontsize=8)
        ax_z.set_xlabel("|Wald z| of the effect's coordinate", fontsize=8)
        ax_p.barh(y, lp, color=colors, label="calibrated")
        ax_p.plot(lp_raw, y, "k|", ms=10, label="asymptotic")
        ax_p.axvline(
            -math.log10(rnd.alpha), color="tab:red", ls="--", label=f"alpha {rnd.alpha:g}"
        )
        ax_p.set_yticks(y, [""] * len(names))
        top = max([*lp, *lp_raw, -math.log10(rnd.alpha)])
        if top > 5:
            ax_p.set_xscale("symlog", linthresh=2.0)
        ax_p.set_xlim(0.0, 1.15 * top)
        ax_p.set_xlabel("-log10 p of the quasi-likelihood ratio", fontsize=8)
        ax_p.legend(fontsize=7, loc="lower right")
        ax_z.set_title(
            f"round {k + 1}: {len(names)} candidates against {len(rnd.model.names) - 1} terms",
            fontsize=9,
        )
    if not rounds:
        axes[0, 0].set_visible(False)
        axes[0, 1].set_visible(False)
    return fig


def posterior_figure(diag: Diagnosis) -> Figure:
    """Histograms of every named effect's parameter (the step's posterior draws)."""
    n = max(1, len(diag.steps))
    fig = Figure(figsize=(4.2 * n, 2.8), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, n, squeeze=False)).ravel()
    for ax, st in zip(axes, diag.steps, strict=False):
        post = st.posterior()
        draws = st.check.sample[:, st.check.model.index(post["param"])]
        ax.hist(draws, bins=40, color=_NAMED, alpha=0.8)
        null = 0.0 if post["param"] not in ("wc", "wf", "rate") else None
        if null is not None:
            ax.axvline(null, color="k", lw=1.0, label="null")
            ax.legend(fontsize=7)
        ax.set_xlabel(post["param"])
        ax.set_title(
            f"{st.effect}: {post['mean']:.4g} +- {post['sd']:.2g} ({st.check.method})", fontsize=9
        )
    if not diag.steps:
        axes[0].set_visible(False)
    return fig


def _num(value: Any, digits: int = 2, none: str = "diverged") -> str:
    """A number for the page; ``None`` (an infinite gap in JSON) reads ``none``."""
    if value is None:
        return none
    if isinstance(value, float) and not math.isfinite(value):
        return "diverged" if value > 0 else "-"
    if isinstance(value, int | float):
        return f"{value:.{digits}f}"
    return str(value)


def _sig(value: Any) -> str:
    return "-" if value is None else f"{value:.4g}"


def render_html(report: dict[str, Any], images: dict[str, bytes]) -> str:
    """The HTML page of a (JSON-ready) report and its PNG figures by name."""
    filters = {
        "num": _num,
        "sig": _sig,
        "worst": lambda m: max(m, key=lambda k: -1 if m[k] is None else m[k]),
    }
    return render(
        "diagnosis.html.j2",
        filters,
        rep=report,
        images={k: b64(v) for k, v in images.items()},
        settings_json=json.dumps(report["settings"], indent=1),
    )


def write_diagnosis(diag: Diagnosis, out_dir: str | Path) -> list[Path]:
    """Write the report files of the module docstring into ``out_dir`` (created).

    Returns
    -------
    list of Path
        ``report.json``, ``report.html``, ``evidence.png``, ``gaps.png``,
        ``measure_gaps.png``, ``measures.png`` and (when an effect is named)
        ``posterior.png``.

    Raises
    ------
    HosidInputError
        If the directory or a file cannot be written.
    """
    out = make_dir(out_dir)
    rep = jsonable(diag.report())
    images = {
        "evidence": png(evidence_figure(diag)),
        "gaps": png(gap_figure(diag)),
        "measure_gaps": png(measure_gap_figure(diag)),
        "measures": png(measures_figure(diag)),
    }
    if diag.steps:
        images["posterior"] = png(posterior_figure(diag))
    paths = [
        write_atomic(out / "report.json", json.dumps(rep, indent=1)),
        write_atomic(out / "report.html", render_html(rep, images)),
    ]
    paths += [write_atomic(out / f"{k}.png", v) for k, v in images.items()]
    return paths
