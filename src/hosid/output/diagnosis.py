r"""The report of :func:`hosid.check.diagnose.diagnose`: figures, ``report.json``, HTML.

:func:`write_diagnosis` writes into a directory

- ``report.json``: :meth:`hosid.check.diagnose.Diagnosis.report` (infinite gaps as
  ``null``);
- ``gaps.png`` (:func:`gap_figure`): the total gap of the base model, of every
  screened candidate and of the fitted final model, with the base model's null band
  and the shrink threshold;
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

from ..check.measures import component_labels
from .files import b64, make_dir, png, render, write_atomic
from .results import jsonable

if TYPE_CHECKING:  # pragma: no cover
    from ..check.diagnose import Diagnosis

__all__ = [
    "gap_figure",
    "measure_gap_figure",
    "measures_figure",
    "moved_measures",
    "render_html",
    "write_diagnosis",
]

_NAMED, _BASE, _OTHER = "tab:green", "0.45", "tab:blue"


def _models(diag: Diagnosis) -> list[tuple[str, Any]]:
    """``(label, check)`` of the base, every candidate and the fitted final model."""
    rows = [("base (fit)", diag.base)]
    rows += [(f"+ {c}", chk) for c, chk in diag.candidates.items()]
    if diag.named_effect:
        rows.append((f"+ {diag.named_effect} (fit)", diag.final))
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
    named = diag.named_effect
    colors = [
        _BASE if i == 0 else (_NAMED if named and lab.startswith(f"+ {named}") else _OTHER)
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
        s = diag.settings.get("shrink", 0.75)
        ax.axvline(s * diag.base.total, color="tab:red", ls="--", label=f"x{s:g} of the base gap")
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
    after_label = f"after: + {diag.named_effect}" if diag.named_effect else "after: base"
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
        ``report.json``, ``report.html``, ``gaps.png``, ``measure_gaps.png`` and
        ``measures.png``.

    Raises
    ------
    HosidInputError
        If the directory or a file cannot be written.
    """
    out = make_dir(out_dir)
    rep = jsonable(diag.report())
    images = {
        "gaps": png(gap_figure(diag)),
        "measure_gaps": png(measure_gap_figure(diag)),
        "measures": png(measures_figure(diag)),
    }
    paths = [
        write_atomic(out / "report.json", json.dumps(rep, indent=1)),
        write_atomic(out / "report.html", render_html(rep, images)),
    ]
    paths += [write_atomic(out / f"{k}.png", v) for k, v in images.items()]
    return paths
