"""A batch's results under its folder: one row file per task, and one table.

::

    DIR/tasks/<task id>.json              one row per finished task (written when it ends)
    DIR/posteriors/<name>-<task id>.nc    its posterior (``--save-posterior``)
    DIR/records/<record>.npz              the simulated record (``--write-records``)
    DIR/results.csv                       one row per record of the batch
    DIR/results.parquet                   the same, when pyarrow is installed

Every file is written atomically (:func:`hosid.output.files.write_atomic`).  The table's
columns: the record and its outcome (``status`` ok | rejected | error, ``verdict`` pass |
warn | fail, ``message``), the analysis and its settings, then for every parameter
``<name>_<stat>`` for the statistics of :data:`STATS`, then the true values
``true_<name>``, then the versions of hosid, its libraries and Python the task ran with,
``version_<name>`` (:func:`hosid.output.results.versions`, as in a fit's
``summary.json``).  Numbers are written with all their digits.
"""

from __future__ import annotations

import csv
import functools
import importlib.util
import io
import json
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from ..errors import HosidInputError
from ..output.files import make_dir, write_atomic
from ..output.results import LIBRARIES, jsonable, versions

__all__ = [
    "LEAD",
    "STATS",
    "TABLE",
    "TIMES",
    "VERSION",
    "columns",
    "read_results",
    "read_rows",
    "stored",
    "write_row",
    "write_table",
]

#: The table's file name.
TABLE = "results.csv"
#: Per-task columns, in this order (those that no row has are left out).
LEAD = (
    "record",
    "status",
    "verdict",
    "message",
    "checks",
    "analysis",
    "design",
    "seed_index",
    "simulator",
    "model",
    "cost",
    "seed",
    "record_hash",
    "n",
    "dt",
    "converged",
    "steps",
    "named_effect",
    "decision",
    "final_model",
    "gap_before",
    "gap_after",
    "hansen_J",
    "hansen_df",
    "hansen_p",
    "sigma_v",
    "fit_seconds",
    "task_seconds",
    "warnings",
    "posterior",
    "task",
)
#: Per-parameter statistics, columns ``<name>_<stat>``.
STATS = (
    "mean",
    "sd",
    "q05",
    "q25",
    "q50",
    "q75",
    "q95",
    "min",
    "max",
    "r_hat",
    "ess_bulk",
    "ess_tail",
)
#: Columns that measure time (they differ between runs of the same task).
TIMES = ("fit_seconds", "task_seconds")
#: Prefix of the columns of the versions, ``version_numpy`` ...
VERSION = "version_"
_VERSIONS = tuple(f"{VERSION}{k}" for k in (*LIBRARIES, "python"))


def _params(rows: Iterable[Mapping[str, Any]]) -> list[str]:
    names: list[str] = []
    for row in rows:
        for key in row:
            if key.endswith("_mean"):
                name = key[: -len("_mean")]
                if name not in names:
                    names.append(name)
    return names


def columns(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """The table's columns for ``rows`` (module docstring)."""
    present = {k for row in rows for k in row}
    params = _params(rows)
    cols = [c for c in LEAD if c in present]
    for name in params:
        cols += [f"{name}_{s}" for s in STATS if f"{name}_{s}" in present]
    truths = sorted(k for k in present if k.startswith("true_"))
    order = {f"true_{p}": i for i, p in enumerate(params)}
    cols += sorted(truths, key=lambda k: (order.get(k, len(order)), k))
    rest = sorted(present - set(cols) - set(_VERSIONS))
    cols += [k for k in rest if not k.startswith(VERSION)]
    cols += [k for k in _VERSIONS if k in present] + [k for k in rest if k.startswith(VERSION)]
    return cols


def stored(row: Mapping[str, Any]) -> dict[str, Any]:
    """A row as its file holds it (plain JSON types, NaN as missing)."""
    return jsonable(dict(row))


@functools.cache
def _versions() -> dict[str, str | None]:
    return {f"{VERSION}{k}": v for k, v in versions().items()}


def write_row(out: Path, row: dict[str, Any]) -> Path:
    """Write a task's row to ``out/tasks/<task id>.json``; a row without the versions
    (``version_<name>``) gets this process's first, in place: the table shows what the
    file holds.
    """
    if not any(k.startswith(VERSION) for k in row):
        row.update(_versions())
    folder = make_dir(Path(out) / "tasks")
    return write_atomic(folder / f"{row['task']}.json", json.dumps(stored(row), indent=1) + "\n")


def read_rows(out: Path) -> dict[str, dict[str, Any]]:
    """The rows of the finished tasks under ``out``, by task id (unreadable files are
    skipped: their tasks run again).
    """
    rows = {}
    folder = Path(out) / "tasks"
    if not folder.is_dir():
        return rows
    for path in sorted(folder.glob("*.json")):
        try:
            row = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):
            continue
        if isinstance(row, dict) and row.get("task") == path.stem:
            rows[path.stem] = row
    return rows


def _cell(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, bool):
        return int(value)
    return value


def write_table(out: Path, rows: Sequence[Mapping[str, Any]]) -> list[Path]:
    """Write ``out/results.csv`` (and ``.parquet`` when pyarrow is importable)."""
    rows = [stored(r) for r in rows]
    cols = columns(rows)
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=cols, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({c: _cell(row.get(c)) for c in cols})
    paths = [write_atomic(Path(out) / TABLE, buffer.getvalue())]
    if importlib.util.find_spec("pyarrow") is not None:
        import pandas as pd

        frame = pd.DataFrame([{c: row.get(c) for c in cols} for row in rows], columns=cols)
        data = io.BytesIO()
        frame.to_parquet(data, index=False)
        paths.append(write_atomic(Path(out) / "results.parquet", data.getvalue()))
    return paths


def _value(text: str) -> Any:
    if text == "":
        return None
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def read_results(path: str | Path) -> list[dict[str, Any]]:
    """The rows of a ``results.csv`` (numbers as numbers, versions as text, empty cells
    as ``None``).

    Raises
    ------
    HosidInputError
        If the file cannot be read.
    """
    path = Path(path)
    try:
        with path.open(newline="") as fh:
            return [
                {k: v or None if k.startswith(VERSION) else _value(v) for k, v in row.items()}
                for row in csv.DictReader(fh)
            ]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise HosidInputError(f"cannot read {path}: {exc}") from None
