"""One-page HTML report of a fit, with its figures and a JSON summary.

:func:`write_report` needs nothing but the fit's ``DataTree`` (as saved in
``posterior.nc``), so a report can be regenerated without the record.
"""

from __future__ import annotations

import base64
import html
import io
import json
import math
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import xarray as xr

from hosid import plots, results
from hosid.errors import HosidInputError

__all__ = ["FIGURES", "SUMMARY_COLUMNS", "write_report"]

#: Columns of the summary table, in order.
SUMMARY_COLUMNS = ("mean", "sd", "q05", "q50", "q95", "r_hat", "ess_bulk", "ess_tail")

#: File stem, drawing function and caption of each figure.
FIGURES: tuple[tuple[str, Callable[[xr.DataTree], Any], str], ...] = (
    (
        "corner",
        plots.corner_plot,
        "Posterior of the sampled parameters; lines mark the 5 %, 50 % and 95 % quantiles "
        "(and the truth when known).",
    ),
    (
        "contour",
        plots.contour_plot,
        "Untempered cost over (a1, n1) with the other parameters at their posterior medians, "
        "posterior draws on top; dashed: a1eq = 0 (eq 65).",
    ),
    (
        "restoring_force",
        plots.restoring_force_plot,
        "Restoring force a2 x + n2 x^3: posterior median and 90 % band.",
    ),
    (
        "trace",
        plots.trace_plot,
        "Traces of a few walkers and of the log pseudo-posterior, to judge mixing.",
    ),
)

_DIAGNOSTICS = ("r_hat", "ess_bulk", "ess_tail")

_CSS = """
body { font-family: sans-serif; max-width: 1100px; margin: 1em auto; padding: 0 1em; }
table { border-collapse: collapse; margin: 0.5em 0 1em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.6em; text-align: right; }
th:first-child, td:first-child, table.kv td { text-align: left; }
tr.fail td { background: #fde0dc; }
.warning { background: #fde0dc; border: 2px solid #c0392b; padding: 0.5em 1em; }
.ok { color: #1e7b34; }
figure { margin: 1em 0; }
figure img { max-width: 100%; }
"""


def _jsonable(value: Any) -> Any:
    """Plain Python for JSON: numpy scalars unwrapped, NaN and infinities to ``None``."""
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if hasattr(value, "tolist"):  # numpy scalars and arrays
        return _jsonable(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _fmt(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    try:
        number = float(value)
    except (TypeError, ValueError):
        return str(value)
    return "-" if math.isnan(number) else f"{number:.4g}"


def _failing(row: Mapping[str, float | None]) -> bool:
    """The same test as :func:`hosid.results.summarize` (NaN or ``None`` fails)."""
    r_hat, bulk, tail = (math.nan if row[k] is None else row[k] for k in _DIAGNOSTICS)
    return not (r_hat < results.RHAT_MAX and bulk >= results.ESS_MIN and tail >= results.ESS_MIN)


def _truth_column(summary: Mapping[str, Any]) -> dict[str, float]:
    r"""Known truths, with ``a1eq`` from eq (65) when only ``a1``, ``n1`` are given:
    :math:`a_{1eq} = a_1 + n_1\sqrt{8/\pi}\,\sigma_{\dot x}` with the record's ``sigma_v``.
    """
    known = dict(summary.get("truths") or {})
    sigma_v = summary.get("sigma_v")
    if "a1eq" not in known and {"a1", "n1"} <= known.keys() and sigma_v is not None:
        known["a1eq"] = known["a1"] + known["n1"] * math.sqrt(8 / math.pi) * float(sigma_v)
    return known


def _derived_a1eq_truth(summary: Mapping[str, Any]) -> bool:
    given = summary.get("truths") or {}
    return "a1eq" not in given and "a1eq" in _truth_column(summary)


def _e(value: Any) -> str:
    return html.escape(str(value))


def _summary_table(summary: Mapping[str, Any]) -> str:
    known = _truth_column(summary)
    columns = ["parameter", *SUMMARY_COLUMNS, *(["truth"] if known else [])]
    lines = ["<table>", "<tr>" + "".join(f"<th>{_e(c)}</th>" for c in columns) + "</tr>"]
    for name, row in summary["parameters"].items():
        cells = [name, *(_fmt(row[c]) for c in SUMMARY_COLUMNS)]
        if known:
            cells.append(_fmt(known.get(name)))
        css = ' class="fail"' if _failing(row) else ""
        lines.append(f"<tr{css}>" + "".join(f"<td>{_e(c)}</td>" for c in cells) + "</tr>")
    lines.append("</table>")
    return "\n".join(lines)


def _show(value: Any) -> str:
    """A setting as text, numbers to four significant digits also inside lists and maps."""
    if isinstance(value, Mapping):
        return ", ".join(f"{k}: {_show(v)}" for k, v in value.items())
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_show(v) for v in value) + "]"
    return _fmt(value)


def _key_value_table(data: Mapping[str, Any]) -> str:
    lines = ['<table class="kv">']
    for key, value in data.items():
        lines.append(f"<tr><td>{_e(key)}</td><td>{_e(_show(value))}</td></tr>")
    lines.append("</table>")
    return "\n".join(lines)


def _banner(summary: Mapping[str, Any]) -> str:
    failures = summary.get("diagnostic_failures") or []
    if not failures:
        return (
            f'<p class="ok">Convergence diagnostics passed (R-hat &lt; {results.RHAT_MAX:g}, '
            f"bulk and tail ESS &ge; {results.ESS_MIN:g}).</p>"
        )
    items = "\n".join(f"<li>{_e(f)}</li>" for f in failures)
    return (
        '<div class="warning" role="alert">\n'
        f"<strong>Warning: convergence diagnostics failed</strong> (R-hat &lt; "
        f"{results.RHAT_MAX:g} and bulk and tail ESS &ge; {results.ESS_MIN:g} are required); "
        "do not trust these numbers.\n"
        f"<ul>\n{items}\n</ul>\n</div>"
    )


def _title(summary: Mapping[str, Any]) -> str:
    kind = "constrained" if summary.get("constrained") else "unconstrained"
    record = summary.get("record") or "record"
    return f"{record}: {summary.get('cost') or '?'} cost, {kind}"


def _fit_info(summary: Mapping[str, Any]) -> dict[str, Any]:
    seconds = summary.get("fit_seconds")
    return {
        "record": summary.get("record"),
        "cost": summary.get("cost"),
        "constrained": summary.get("constrained"),
        "temperature": summary.get("temperature"),
        "sigma_v": summary.get("sigma_v"),
        "walkers": summary.get("n_walkers"),
        "draws per walker": summary.get("n_draws"),
        "fit time (s)": seconds,
        "converged": summary.get("converged"),
    }


def _html(summary: Mapping[str, Any], images: Mapping[str, bytes]) -> str:
    title = _title(summary)
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en">',
        "<head>",
        '<meta charset="utf-8">',
        f"<title>hosid fit: {_e(title)}</title>",
        f"<style>{_CSS}</style>",
        "</head>",
        "<body>",
        f"<h1>hosid fit: {_e(title)}</h1>",
        _banner(summary),
        "<h2>Posterior summary</h2>",
        _summary_table(summary),
        *(
            ["<p>The true a1eq is derived from eq (65) with the record's sigma_v.</p>"]
            if _derived_a1eq_truth(summary)
            else []
        ),
        "<h2>Fit</h2>",
        _key_value_table(_fit_info(summary)),
    ]
    if summary.get("settings"):
        parts += ["<h2>Settings</h2>", _key_value_table(summary["settings"])]
    if summary.get("calibration"):
        parts += ["<h2>Calibration</h2>", _key_value_table(summary["calibration"])]
    parts.append("<h2>Figures</h2>")
    for stem, _, caption in FIGURES:
        data = base64.b64encode(images[stem]).decode("ascii")
        parts += [
            "<figure>",
            f'<img src="data:image/png;base64,{data}" alt="{_e(stem)}">',
            f"<figcaption>{_e(caption)}</figcaption>",
            "</figure>",
        ]
    parts += ["</body>", "</html>", ""]
    return "\n".join(parts)


def _write(path: Path, data: bytes | str) -> None:
    try:
        if isinstance(data, bytes):
            path.write_bytes(data)
        else:
            path.write_text(data, encoding="utf-8")
    except OSError as exc:
        raise HosidInputError(f"cannot write {path}: {exc.strerror or exc}") from None


def write_report(tree: xr.DataTree, out_dir: str | Path, *, dpi: int = 100) -> Path:
    """Write the report of a fit into a directory.

    Files: ``corner.png``, ``contour.png``, ``restoring_force.png``, ``trace.png``,
    ``summary.json`` (:func:`hosid.results.summarize` with NaN as ``null``) and
    ``report.html``, a self-contained page (figures embedded as base64 PNG) with
    the summary table, a warning banner when the convergence diagnostics fail,
    the settings, the calibration and the fit time.

    Parameters
    ----------
    tree : xarray.DataTree
        A fit in the layout of :mod:`hosid.results`.
    out_dir : str or pathlib.Path
        Output directory, created if needed; existing report files are replaced.
    dpi : int, optional
        Resolution of the PNG figures.

    Returns
    -------
    pathlib.Path
        The path of ``report.html``.

    Raises
    ------
    HosidInputError
        If the directory or a file cannot be written.
    """
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise HosidInputError(f"cannot create {out}: {exc.strerror or exc}") from None
    summary = _jsonable(results.summarize(tree, warn=False))
    _write(out / "summary.json", json.dumps(summary, indent=2, allow_nan=False) + "\n")
    images: dict[str, bytes] = {}
    for stem, draw, _ in FIGURES:
        buffer = io.BytesIO()
        # the figures are pyplot-free: nothing to close, they go with their last reference
        draw(tree).savefig(buffer, format="png", dpi=dpi)
        images[stem] = buffer.getvalue()
        _write(out / f"{stem}.png", images[stem])
    path = out / "report.html"
    _write(path, _html(summary, images))
    return path
