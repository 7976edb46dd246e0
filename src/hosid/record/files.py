"""Record files: CSV with a header naming columns ``t`` and ``x`` and optionally an
integer ``segment`` column (any order, extra columns ignored; the time may jump between
segments), or ``.npz`` archives holding ``x`` (1-D, or 2-D with one segment a row),
either ``t`` (shaped as ``x``) or ``dt``, and optionally ``segment`` (one integer label
a sample, as the CSV column).
"""

from __future__ import annotations

import json
import math
import zipfile
from pathlib import Path

import numpy as np

from hosid.errors import HosidInputError

from .core import UNIFORM_RTOL, Record

__all__ = ["read_record", "read_truths", "write_record"]


def _runs(labels: np.ndarray, source: str, where) -> tuple[int, ...]:
    """Segment starts of integer labels whose segments are contiguous, or raise;
    ``where(i)`` names sample ``i`` in the file.
    """
    if labels.dtype.kind == "f":
        bad = np.flatnonzero(~np.isfinite(labels) | (labels != np.round(labels)))
        if bad.size:
            raise HosidInputError(
                f"{source}: {where(bad[0])}, column 'segment': "
                f"{float(labels[bad[0]])!r} is not an integer"
            )
    starts = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]])
    seen = labels[starts]
    _, first = np.unique(seen, return_index=True)
    if first.size != seen.size:
        k = np.setdiff1d(np.arange(seen.size), first)[0]
        raise HosidInputError(
            f"{source}: segment {int(seen[k])} is not contiguous: it starts again at "
            f"{where(starts[k])}"
        )
    return tuple(int(v) for v in starts)


def _dt_from_times(t: np.ndarray, source: str, starts: tuple[int, ...] = (0,)) -> float:
    """Return the common time step of the uniformly spaced times of every segment."""
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1:
        raise HosidInputError(f"{source}: t must be 1-D, got shape {t.shape}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise HosidInputError(f"{source}: time {int(bad[0])} is {float(t[bad[0]])!r}")
    if t.size < 2:
        raise HosidInputError(f"{source}: at least 2 time values are needed")
    pieces = np.split(t, starts[1:])
    steps = np.concatenate([np.diff(p) for p in pieces])
    median = float(np.median(steps)) if steps.size else float("nan")
    if not median > 0:
        raise HosidInputError(f"{source}: times must increase, median step is {median!r}")
    for k, p in enumerate(pieces):
        dev = np.abs(np.diff(p) - median) / median
        if dev.size == 0:
            continue
        worst = int(np.argmax(dev))
        if dev[worst] > UNIFORM_RTOL:
            where = f" in segment {k}" if len(pieces) > 1 else ""
            raise HosidInputError(
                f"non-uniform sampling{where}: {source}: step {worst} "
                f"(t={float(p[worst])!r} -> {float(p[worst + 1])!r}) "
                f"differs from the median step {median!r} by a relative {dev[worst]:.3g} "
                f"(tolerance {UNIFORM_RTOL:g})"
            )
    span = sum(float(p[-1] - p[0]) for p in pieces)
    return span / sum(p.size - 1 for p in pieces)


def _column(path: Path, rows: list[list[str]], lines: list[int], name: str, i: int):
    """One CSV column as floats; a bad cell is named by column and line."""
    try:
        cells = [r[i] for r in rows]
    except IndexError:
        k = next(j for j, r in enumerate(rows) if len(r) <= i)
        raise HosidInputError(
            f"{path}: line {lines[k]} has {len(rows[k])} fields; column {name!r} is field {i + 1}"
        ) from None
    try:
        return np.array(cells, dtype=np.float64)
    except ValueError:
        for j, c in enumerate(cells):
            try:
                float(c)
            except ValueError:
                raise HosidInputError(
                    f"{path}: line {lines[j]}, column {name!r}: {c.strip()!r} is not a number"
                ) from None
        raise  # pragma: no cover - every cell converts on its own


def _read_csv(path: Path) -> Record:
    try:
        text = path.read_text(encoding="utf-8-sig")  # a spreadsheet's byte-order mark skipped
    except UnicodeDecodeError as exc:
        raise HosidInputError(
            f"{path}: not a text file (byte {exc.object[exc.start]:#04x} at offset {exc.start} "
            "is not UTF-8); a .csv record is text with a header naming t and x"
        ) from None
    except OSError as exc:
        raise HosidInputError(f"cannot read {path}: {exc.strerror or exc}") from None
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise HosidInputError(f"{path}: empty file, expected a header line naming t and x")
    names = [c.strip().strip("\"'").strip() for c in lines[0].split(",")]
    for col in ("t", "x"):
        if col not in names:
            raise HosidInputError(f"{path}: no column {col!r} in header {lines[0].strip()!r}")
    numbers = [k + 1 for k, line in enumerate(lines) if k and line.strip()]
    if not numbers:
        raise HosidInputError(f"{path}: no data rows after the header")
    rows = [lines[k - 1].split(",") for k in numbers]
    t = _column(path, rows, numbers, "t", names.index("t"))
    x = _column(path, rows, numbers, "x", names.index("x"))
    starts: tuple[int, ...] = (0,)
    if "segment" in names:
        labels = _column(path, rows, numbers, "segment", names.index("segment"))
        starts = _runs(labels, str(path), lambda i: f"line {numbers[i]}")
    dt = _dt_from_times(t, str(path), starts)
    return Record(x, dt, name=path.stem, segments=starts)


def _read_npz(path: Path) -> Record:
    if not zipfile.is_zipfile(path):
        raise HosidInputError(f"cannot read {path}: not an .npz archive (not a zip file)")
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {k: archive[k] for k in archive.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise HosidInputError(
            f"cannot read {path}: not a valid .npz archive of numeric arrays ({exc})"
        ) from None
    if "x" not in arrays:
        raise HosidInputError(f"{path}: no array 'x' (found {sorted(arrays)})")
    x, t = arrays["x"], arrays.get("t")
    if t is not None and np.shape(t) != np.shape(x):
        raise HosidInputError(f"{path}: t has shape {np.shape(t)} but x has {np.shape(x)}")
    starts: tuple[int, ...] = (0,)
    if np.ndim(x) == 2:  # one segment a row
        if "segment" in arrays:
            raise HosidInputError(f"{path}: a 2-D x holds its segments as rows; drop 'segment'")
        starts = tuple(range(0, x.size, max(x.shape[1], 1)))
        x = x.reshape(-1)
        t = None if t is None else np.asarray(t).reshape(-1)
    elif "segment" in arrays:
        labels = np.asarray(arrays["segment"])
        if labels.shape != np.shape(x) or labels.dtype.kind not in "iuf":
            raise HosidInputError(
                f"{path}: 'segment' must be one integer label a sample, shaped as x "
                f"{np.shape(x)}, got {labels.dtype} of shape {labels.shape}"
            )
        starts = _runs(labels, str(path), lambda i: f"index {int(i)}")
    if t is not None:
        dt = _dt_from_times(t, str(path), starts)
    elif "dt" in arrays:
        if np.size(arrays["dt"]) != 1 or np.asarray(arrays["dt"]).dtype.kind not in "fiu":
            raise HosidInputError(f"{path}: dt must be a single number")
        dt = float(np.asarray(arrays["dt"]).reshape(()))
    else:
        raise HosidInputError(f"{path}: needs an array 't' or 'dt' besides 'x'")
    return Record(x, dt, name=path.stem, segments=starts)


_READERS = {".csv": _read_csv, ".npz": _read_npz}


def read_record(path: str | Path) -> Record:
    """Read a record from a CSV or ``.npz`` file (module docstring).

    Parameters
    ----------
    path : str or pathlib.Path
        A ``.csv`` file whose header names columns ``t``, ``x`` and optionally
        ``segment`` (in any order, other columns ignored), or an ``.npz`` archive
        holding ``x``, either ``t`` or a scalar ``dt``, and optionally ``segment``.

    Returns
    -------
    Record
        Named after the file's stem; ``dt`` is the mean step of ``t`` in the segments.

    Raises
    ------
    HosidInputError
        If the file is missing, a folder, not a regular file, unreadable, of unknown
        type, empty or (a CSV) not UTF-8 text, if a column is missing or a cell is not a
        number (named by column and line), if a segment label is not an integer or a
        segment not contiguous, if the times of a segment are not uniform (a step off the
        median by more than 1e-6 relative), or if the samples fail the checks of `Record`.
    """
    path = Path(path)
    if path.is_dir():
        raise HosidInputError(
            f"{path}: is a folder, not a record file (a .csv or .npz; hosid batch and hosid "
            "monitor take folders)"
        )
    reader = _READERS.get(path.suffix.lower())
    if reader is None:
        raise HosidInputError(
            f"{path}: unknown file type {path.suffix or '(none)'!r}; use .csv or .npz"
        )
    if not path.exists():
        raise HosidInputError(f"{path}: no such file")
    if not path.is_file():
        raise HosidInputError(f"{path}: not a regular file (a .csv or .npz record is read whole)")
    return reader(path)


def write_record(record: Record, path: str | Path) -> Path:
    """Write a record to a CSV or ``.npz`` file, chosen by the suffix.

    CSV files get a header ``t,x`` (``t,x,segment`` for several segments); times are
    written with 15 significant digits (so that they read back uniformly spaced),
    samples with 10.  ``.npz`` archives hold ``x`` and ``dt`` exactly (and the labels
    ``segment``).  Reading the file back gives the same samples, ``dt`` and segments.

    Returns the path written; raises `HosidInputError` if the suffix (``.csv`` or
    ``.npz``) is unknown or the file cannot be written.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in _READERS:
        raise HosidInputError(
            f"{path}: unknown file type {path.suffix or '(none)'!r}; use .csv or .npz"
        )
    several = record.n_segments > 1
    try:
        if suffix == ".csv":
            cols, fmt, header = [record.t, record.x], ["%.15g", "%.10g"], "t,x"
            if several:
                cols, fmt, header = [*cols, record.labels], [*fmt, "%d"], "t,x,segment"
            np.savetxt(
                path, np.column_stack(cols), fmt=fmt, delimiter=",", header=header, comments=""
            )
        else:
            extra = {"segment": record.labels} if several else {}
            with path.open("wb") as fh:
                np.savez(fh, x=record.x, dt=np.float64(record.dt), **extra)
    except OSError as exc:
        raise HosidInputError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path


def read_truths(record_path: str | Path, path: str | Path | None = None) -> dict | None:
    """The true parameters of a simulated record: ``path`` (a JSON object of finite
    numbers), or else the sidecar ``REC.truths.json`` (or ``REC.csv.truths.json``) that
    ``hosid simulate`` writes; ``None`` when there is none.

    Raises
    ------
    HosidInputError
        If the file is missing (when given), unreadable or not such an object.
    """
    record_path = Path(record_path)
    path = Path(path) if path else None
    if path is None:
        for cand in (
            record_path.with_suffix(".truths.json"),
            record_path.with_name(record_path.name + ".truths.json"),
        ):
            if cand.is_file():
                path = cand
                break
    if path is None:
        return None
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise HosidInputError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise HosidInputError(f"{path}: not valid JSON ({exc})") from None
    ok = (
        isinstance(data, dict)
        and data
        and all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            for v in data.values()
        )
    )
    if not ok:
        raise HosidInputError(f"{path}: truths must be a JSON object of finite numbers")
    return {k: float(v) for k, v in data.items()}
