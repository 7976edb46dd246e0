"""One-page HTML report of a fit, its figures as PNG and a JSON summary.

:func:`write_report` needs nothing but the fit's ``DataTree`` (as saved in
``posterior.nc``), so a report can be regenerated without the record.  The page is
rendered from the jinja2 template ``templates/report.html.j2`` with the figures
embedded as base64 PNG; every file is written atomically (a temporary name in the
output directory, then :func:`os.replace`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import xarray as xr

from .files import b64, make_dir, png, render, write_atomic
from .labels import fit_title, known_truths, length_unit, unit
from .results import ESS_MIN, RHAT_MAX, attr, jsonable, stored_model, summarize

if TYPE_CHECKING:  # pragma: no cover - matplotlib loads with the first figure
    from matplotlib.figure import Figure

__all__ = ["CAPTIONS", "COLUMNS", "STEMS", "draw", "figures", "write_report"]

#: Columns of the posterior table, in order (``summarize`` keys).
COLUMNS = ("mean", "sd", "q05", "q50", "q95", "r_hat", "ess_bulk")

_HEADERS = {"q05": "5 %", "q50": "50 %", "q95": "95 %"}
_PROVENANCE = (
    "record",
    "record_hash",
    "created_at",
    "hosid_version",
    "inference_library",
    "inference_library_version",
)

#: The report's figures by file stem, in the page's order.
STEMS = (
    "corner",
    "likelihood_map",
    "restoring_force",
    "trace",
    "spectrum",
    "force_spectrum",
    "mode_shapes",
)


def _plots() -> dict[str, Callable[[xr.DataTree], Figure | None]]:
    """The plotting function of each stem (imported here: the page needs no matplotlib)."""
    from . import plots, spectrum_plots

    return {
        "corner": plots.corner_plot,
        "likelihood_map": plots.likelihood_map_plot,
        "restoring_force": plots.restoring_force_plot,
        "trace": plots.trace_plot,
        "spectrum": spectrum_plots.spectrum_plot,
        "force_spectrum": spectrum_plots.force_spectrum_plot,
        "mode_shapes": plots.mode_shapes_plot,
    }


#: Caption of each figure, by file stem.
CAPTIONS = {
    "corner": "Posterior of the parameters and of the equivalent damping a1eq (eq 65); "
    "dashed lines at the 5, 50 and 95 % quantiles, blue lines at the truth when known.",
    "likelihood_map": "Quasi-log-likelihood over (a1, n1), the other parameters at the "
    "estimate, with posterior draws; dashed: a1eq = 0 (eq 65), shaded where the "
    "constraint rules the plane out.",
    "restoring_force": "Restoring force over four displacement standard deviations: "
    "posterior median and 5-95 % band.",
    "trace": "Traces of a few walkers and of the log quasi-posterior, to judge mixing.",
    "spectrum": "The record's displacement spectrum and the linear-equivalent oscillator "
    "at the posterior median (a2eq = sigma_v^2 / sigma_x^2).",
    "force_spectrum": "The force inferred from the record at the estimate (eq 45) against "
    "the excitation model S0 L(omega): posterior median and 5-95 % band.  Where they part, "
    "the excitation model does not describe the record.",
    "mode_shapes": "Mode shapes along the chain (posterior mean), of the system linearised "
    "at the record's response level (solid) and of its linear terms alone (dashed).",
}

# the drift terms as they read in the equation of motion
_TERM_TEXT = {
    "linear_damping": "a1 ẋ",
    "quadratic_damping": "n1 ẋ|ẋ|",
    "coulomb_friction": "mu sign(ẋ)",
    "linear_stiffness": "a2 x",
    "quadratic_stiffness": "b2 x²",
    "cubic_stiffness": "n2 x³",
    "excitation_mean": "(-m)",
}


def figures(tree: xr.DataTree) -> dict[str, Figure]:
    """Every figure of the report, by file stem; figures that do not apply are left out.

    Parameters
    ----------
    tree : xarray.DataTree
        A fit (:mod:`hosid.output.results`).

    Returns
    -------
    dict of str to matplotlib.figure.Figure
        ``corner``, ``likelihood_map`` (when the fit has the group), ``restoring_force``
        (when the model has stiffness), ``trace`` and ``spectrum``, in that order.
    """
    out = {}
    for stem, plot in _plots().items():
        fig = plot(tree)
        if fig is not None:
            out[stem] = fig
    return out


def draw(tree: xr.DataTree, stems: Iterable[str] = STEMS, *, dpi: int = 100) -> dict[str, bytes]:
    """The PNG bytes of the figures ``stems`` of :func:`figures` that apply, by stem.

    Each figure is drawn and encoded before the next is made (what
    :mod:`hosid.output.render` runs in the processes that draw beside a fit).
    """
    plots = _plots()
    out = {}
    for stem in stems:
        fig = plots[stem](tree)
        if fig is not None:
            out[stem] = png(fig, dpi)
    return out


def _num(value: Any, digits: int = 4) -> str:
    """A number to ``digits`` significant digits; ``-`` for missing or NaN."""
    if value is None or value == "":
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    try:
        number = float(value)
    except (TypeError, ValueError):
        return str(value)
    return "-" if math.isnan(number) else f"{number:.{digits}g}"


def _show(value: Any) -> str:
    """Any attribute value as short text, numbers to four digits inside lists and maps."""
    if isinstance(value, Mapping):
        return ", ".join(f"{k}: {_show(v)}" for k, v in value.items())
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_show(v) for v in value) + "]"
    return _num(value)


def _pairs(data: Mapping[str, Any] | None) -> list[tuple[str, str]]:
    return [(str(k), _show(v)) for k, v in (data or {}).items()]


def _summary(tree: xr.DataTree) -> dict[str, Any]:
    """:func:`~hosid.output.results.summarize` with the fit's remaining attributes."""
    length = length_unit(tree)
    out = summarize(tree, warn=False)
    calibration = out.get("calibration") or {}
    out.update(
        {
            "units": {k: unit(k, length) for k in out["parameters"]},
            "length_unit": length,
            "hansen": calibration.get("hansen"),
            "sigma_v": attr(tree, "sigma_v"),
            **{k: attr(tree, k) for k in ("state", "components_info", "priors", "estimate")},
            **{k: attr(tree, k) for k in ("sampler", "timings", "duration", "dt")},
            "created_at": attr(tree, "created_at"),
            "hosid_version": attr(tree, "hosid_version"),
            "inference_library": attr(tree, "inference_library"),
            "inference_library_version": attr(tree, "inference_library_version"),
        }
    )
    return jsonable(out)


def _calibration(summary: Mapping[str, Any]) -> dict[str, Any]:
    """Method, dispersion, Hansen's test and the note for the banner."""
    cal = dict(summary.get("calibration") or {})
    hansen = cal.pop("hansen", None)
    return {
        "method": cal.pop("method", "?"),
        "dispersion": _num(cal.pop("dispersion", None)),
        "note": cal.pop("note", None),
        "hansen": hansen and {k: _num(hansen.get(k)) for k in ("J", "df", "p_value")},
        "details": _pairs(cal),
    }


def _table(summary: Mapping[str, Any], truths: Mapping[str, float]) -> list[dict]:
    rows = []
    for name, row in summary["parameters"].items():
        cells = [_num(row[c]) for c in COLUMNS[:-2]]
        cells.append("-" if row["r_hat"] is None else f"{row['r_hat']:.3f}")
        cells.append("-" if row["ess_bulk"] is None else str(round(row["ess_bulk"])))
        failed = any(f.startswith(f"{name}:") for f in summary["diagnostic_failures"])
        rows.append(
            {
                "name": name,
                "unit": summary["units"].get(name, ""),
                "cells": cells,
                "truth": _num(truths.get(name)),
                "fail": failed,
            }
        )
    return rows


def _model(tree: xr.DataTree) -> dict[str, Any]:
    model = stored_model(tree)
    if model is None and attr(tree, "system"):  # a system's equations, one a dof
        from .system_text import system_model

        return system_model(attr(tree, "system"))
    terms = model.terms if model is not None else ()
    drift = [_TERM_TEXT.get(t.name, t.latex) for t in terms if t.kind == "drift"]
    return {
        "equation": "ẍ + " + " + ".join(drift) + " = f(t)" if drift else "",
        "terms": [(t.name, t.kind, ", ".join(t.params)) for t in terms],
    }


def _state(summary: Mapping[str, Any]) -> list[tuple[str, str]]:
    state = summary.get("state") or {}
    band = ((summary.get("components_info") or {}).get("J2") or {}).get("band_rad_s")
    rows = {
        "block length (s)": state.get("block_seconds"),
        "blocks": state.get("blocks"),
        "samples per block": state.get("block_samples"),
        "window": state.get("window"),
        "omega_n = sigma_v / sigma_x (rad/s)": state.get("omega_n"),
        "J2 band (rad/s)": band,
        f"sigma_x ({summary['length_unit']})": state.get("sigma_x"),
        f"sigma_v, restored ({summary['length_unit']}/s)": summary.get("sigma_v"),
        "record duration (s)": summary.get("duration"),
        "dt (s)": summary.get("dt"),
    }
    return _pairs({k: v for k, v in rows.items() if v is not None})


def _modes(summary: Mapping[str, Any], key: str) -> list[dict[str, str]]:
    """A system's modes (``summary[key]``) as table rows: frequency and damping ratio,
    mean (sd) and 90 % interval, and the shape.
    """

    def cell(d):
        return f"{_num(d['mean'])} ({_num(d['sd'])}) [{_num(d['q05'])}, {_num(d['q95'])}]"

    return [
        {"frequency": cell(m["frequency_hz"]), "damping": cell(m["damping_ratio"]),
         "shape": ", ".join(f"{v:+.3f}" for v in m["shape"])}
        for m in summary.get(key) or []
    ]  # fmt: skip


def _versions(summary: Mapping[str, Any]) -> list[tuple[str, str]]:
    """The provenance row of the libraries' versions, as text (``3.10`` is no number)."""
    known = {k: v for k, v in (summary.get("versions") or {}).items() if v}
    return [("versions", ", ".join(f"{k} {v}" for k, v in known.items()))] if known else []


def _context(
    tree: xr.DataTree, summary: Mapping[str, Any], images: Mapping[str, bytes]
) -> dict[str, Any]:
    """Everything the template shows, formatted."""
    truths = known_truths(tree)
    timings = dict(summary.get("timings") or {})
    timings["total"] = summary.get("fit_seconds")
    return {
        "title": fit_title(tree),
        "summary": summary,
        "rhat_max": RHAT_MAX,
        "ess_min": ESS_MIN,
        "calibration": _calibration(summary),
        "checks": [{**c, "value": _num(c.get("value"))} for c in summary.get("checks") or []],
        "verdict_class": {"pass": "ok", "warn": "warn", "fail": "fail"}[summary["verdict"]],
        "columns": [_HEADERS.get(c, c) for c in COLUMNS],
        "rows": _table(summary, truths),
        "has_truth": bool(truths),
        "derived_a1eq": "a1eq" in truths and "a1eq" not in (summary.get("truths") or {}),
        "model": _model(tree),
        "modes": _modes(summary, "modes"),
        "modes_small": _modes(summary, "modes_small_amplitude"),
        "dofs": (attr(tree, "system") or {}).get("dofs", []),
        "components": [
            (c, _show((summary.get("components_info") or {}).get(c, {})))
            for c in summary.get("components") or []
        ],
        "state": _state(summary),
        "sampler": _pairs(summary.get("sampler")),
        "timings": _pairs({f"{k} (s)": v for k, v in timings.items()}),
        "priors": _pairs(summary.get("priors")),
        "settings": _pairs(summary.get("settings")),
        "provenance": _pairs({k: summary.get(k) for k in _PROVENANCE}) + _versions(summary),
        "figures": [
            {"stem": k, "caption": CAPTIONS.get(k, k), "data": b64(v)} for k, v in images.items()
        ],
    }


def write_report(
    tree: xr.DataTree,
    out_dir: str | Path,
    *,
    dpi: int = 100,
    images: Callable[[], Mapping[str, bytes]] | None = None,
) -> list[Path]:
    """Write the report of a fit into ``out_dir`` (created when missing).

    Files: ``report.html`` (self-contained: convergence and calibration banner,
    posterior table with units and truths, model, components, state, sampler, timings,
    priors, settings and the figures), ``summary.json``
    (:func:`~hosid.output.results.summarize` plus calibration, Hansen's test, state,
    timings ...; NaN as ``null``) and one PNG per figure of :func:`figures`.

    Parameters
    ----------
    tree : xarray.DataTree
        A fit (:mod:`hosid.output.results`).
    out_dir : str or Path
        Output directory; existing files of the same names are replaced.
    dpi : int
        Resolution of the PNG figures.
    images : callable, optional
        Called once the summary is made, returns the figures' PNG bytes by stem (those
        of :func:`draw`, drawn meanwhile by
        :class:`~hosid.output.render.FigureProcesses`); default: :func:`draw` here.

    Returns
    -------
    list of Path
        The files written, ``report.html`` first, then ``summary.json`` and the PNGs.

    Raises
    ------
    HosidInputError
        If the directory or a file cannot be written.
    """
    out_dir = make_dir(out_dir)
    summary = _summary(tree)
    given = draw(tree, dpi=dpi) if images is None else images()
    pngs = {stem: given[stem] for stem in STEMS if stem in given}
    html = render("report.html.j2", **_context(tree, summary, pngs))
    files = {
        "report.html": html.encode("utf-8"),
        "summary.json": json.dumps(summary, indent=2, allow_nan=False).encode("utf-8"),
        **{f"{stem}.png": data for stem, data in pngs.items()},
    }
    return [write_atomic(out_dir / name, data) for name, data in files.items()]
