"""Record files, CSV or ``.npz``; one channel or several.

**CSV.**  A header naming the columns, in any order: ``t`` (the sample times), the
channels, and optionally an integer ``segment`` column (the time may jump between
segments).  A file with a column ``x`` is the single oscillator's record: ``x`` is read
and other columns are ignored (as before channels existed).  A file without ``x`` is a
record of every other column when it has two or more (any names: ``t,x1,x2``, as
:func:`hosid.model.chain.write_chain_record` writes).  ``channels=`` (a system's
``dofs``) picks and orders the columns instead.  A CSV file does not say what a channel
measures (displacement unless the caller declares otherwise, :meth:`Record.select`).

**.npz.**  Either the single oscillator's ``x`` (1-D, or 2-D with one segment a row),
or channels named by a 1-D string array ``dofs``: their samples are a 2-D array ``q``
of shape ``(n_samples, n_channels)``, one column a name of ``dofs``, or else one 1-D
array a channel, named as in ``dofs`` (what :func:`~hosid.model.chain.write_chain_record`
writes).  Beside them: ``t`` (one time a sample) or a scalar ``dt``; optionally
``segment`` (one integer label a sample, as the CSV column) and, with ``dofs``,
``measured`` (``"displacement"`` or ``"acceleration"``, one for all or one a channel).

:func:`write_record` writes the single displacement channel ``x`` as before (``t,x``;
``x``, ``dt``), and any other record as ``t,<channels>`` or the ``dofs`` form with one
array a channel; reading the file back gives the same record (from a CSV file, up to
the 10 digits written and what the channels measure).
"""

from __future__ import annotations

import zipfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from hosid.errors import HosidInputError

from .core import MEASURED, UNIFORM_RTOL, Record
from .truths import read_truths

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


def _read_csv(path: Path, channels: tuple[str, ...] | None = None) -> Record:
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
    if "t" not in names:
        raise HosidInputError(f"{path}: no column 't' in header {lines[0].strip()!r}")
    wanted = _csv_channels(path, names, lines[0].strip(), channels)
    numbers = [k + 1 for k, line in enumerate(lines) if k and line.strip()]
    if not numbers:
        raise HosidInputError(f"{path}: no data rows after the header")
    rows = [lines[k - 1].split(",") for k in numbers]
    t = _column(path, rows, numbers, "t", names.index("t"))
    cols = [_column(path, rows, numbers, c, names.index(c)) for c in wanted]
    starts: tuple[int, ...] = (0,)
    if "segment" in names:
        labels = _column(path, rows, numbers, "segment", names.index("segment"))
        starts = _runs(labels, str(path), lambda i: f"line {numbers[i]}")
    dt = _dt_from_times(t, str(path), starts)
    if wanted == ("x",):  # the single oscillator's record, its messages as ever
        return Record(cols[0], dt, name=path.stem, segments=starts)
    x = cols[0] if len(cols) == 1 else np.column_stack(cols)
    try:
        return Record(x, dt, name=path.stem, segments=starts, channels=wanted)
    except HosidInputError as exc:
        raise HosidInputError(f"{path}: {exc}") from None


def _csv_channels(path: Path, names: list[str], header: str, channels) -> tuple[str, ...]:
    """The channel columns of a CSV header (module docstring)."""
    if channels is not None:
        _need(path, channels, names, "column")
        return tuple(channels)
    if "x" in names:
        return ("x",)
    data = tuple(c for c in names if c and c not in ("t", "segment"))
    if len(data) < 2:
        raise HosidInputError(
            f"{path}: no column 'x' in header {header!r} (one channel is the column x; "
            "a system file's dofs name other columns)"
        )
    return data


def _need(path: Path, channels, present, what: str) -> None:
    """Raise naming the first of ``channels`` not ``present`` (and those present)."""
    for c in channels:
        if c not in present:
            raise HosidInputError(
                f"{path}: no {what} {c!r} (asked for {', '.join(channels)}; the file has "
                f"{', '.join(p for p in present if p)})"
            )


def _read_npz(path: Path, channels: tuple[str, ...] | None = None) -> Record:
    if not zipfile.is_zipfile(path):
        raise HosidInputError(f"cannot read {path}: not an .npz archive (not a zip file)")
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {k: archive[k] for k in archive.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise HosidInputError(
            f"cannot read {path}: not a valid .npz archive of numeric arrays ({exc})"
        ) from None
    record = _npz_channels(path, arrays) if "dofs" in arrays else _npz_x(path, arrays)
    if channels is not None:
        _need(path, channels, record.channels, "channel")
        record = record.select(channels)
    return record


def _npz_x(path: Path, arrays: dict) -> Record:
    """The single-channel record of an archive with ``x`` (module docstring)."""
    if "x" not in arrays:
        if "q" in arrays:
            raise HosidInputError(
                f"{path}: a 2-D 'q' needs 'dofs', the names of its columns (one a channel)"
            )
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
        starts = _npz_segments(path, arrays, np.shape(x), "x")
    return Record(x, _npz_dt(path, arrays, t, starts, "'x'"), name=path.stem, segments=starts)


def _npz_channels(path: Path, arrays: dict) -> Record:
    """The record of an archive with ``dofs`` (module docstring)."""
    dofs = np.asarray(arrays["dofs"])
    if dofs.ndim != 1 or dofs.size == 0 or dofs.dtype.kind not in "US":
        raise HosidInputError(f"{path}: 'dofs' must be a 1-D array of channel names")
    names = tuple(str(d) for d in dofs)
    if "q" in arrays:
        q = np.asarray(arrays["q"])
        if q.ndim != 2 or q.shape[1] != len(names):
            raise HosidInputError(
                f"{path}: 'q' must be (n_samples, {len(names)}), one column a name of dofs "
                f"({', '.join(names)}); got shape {q.shape}"
            )
    else:
        _need(path, names, tuple(arrays), "array")
        shapes = {np.shape(arrays[d]) for d in names}
        if len(shapes) != 1 or len(next(iter(shapes))) != 1:
            raise HosidInputError(
                f"{path}: the channels {', '.join(names)} must be 1-D arrays of one length, "
                f"got shapes {', '.join(str(np.shape(arrays[d])) for d in names)}"
            )
        q = np.column_stack([arrays[d] for d in names])
    measured = None
    if "measured" in arrays:
        kinds = np.asarray(arrays["measured"])
        if kinds.dtype.kind not in "US" or kinds.ndim > 1:
            raise HosidInputError(
                f"{path}: 'measured' must hold {' or '.join(MEASURED)}, one for all or one "
                "a channel"
            )
        measured = str(kinds) if kinds.ndim == 0 else tuple(str(k) for k in kinds)
    starts: tuple[int, ...] = (0,)
    if "segment" in arrays:
        starts = _npz_segments(path, arrays, (q.shape[0],), "one channel")
    t = arrays.get("t")
    if t is not None and np.shape(t) != (q.shape[0],):
        raise HosidInputError(
            f"{path}: t has shape {np.shape(t)} but the channels have {q.shape[0]} samples"
        )
    dt = _npz_dt(path, arrays, t, starts, "the channels")
    try:
        return Record(q, dt, path.stem, starts, channels=names, measured=measured)
    except HosidInputError as exc:
        raise HosidInputError(f"{path}: {exc}") from None


def _npz_segments(path: Path, arrays: dict, shape: tuple, what: str) -> tuple[int, ...]:
    """Segment starts of an archive's ``segment`` labels, shaped as ``what``."""
    labels = np.asarray(arrays["segment"])
    if labels.shape != shape or labels.dtype.kind not in "iuf":
        raise HosidInputError(
            f"{path}: 'segment' must be one integer label a sample, shaped as {what} "
            f"{shape}, got {labels.dtype} of shape {labels.shape}"
        )
    return _runs(labels, str(path), lambda i: f"index {int(i)}")


def _npz_dt(path: Path, arrays: dict, t, starts: tuple[int, ...], what: str) -> float:
    """The step of an archive's ``t`` or its ``dt``."""
    if t is not None:
        return _dt_from_times(t, str(path), starts)
    if "dt" in arrays:
        if np.size(arrays["dt"]) != 1 or np.asarray(arrays["dt"]).dtype.kind not in "fiu":
            raise HosidInputError(f"{path}: dt must be a single number")
        return float(np.asarray(arrays["dt"]).reshape(()))
    raise HosidInputError(f"{path}: needs an array 't' or 'dt' besides {what}")


_READERS = {".csv": _read_csv, ".npz": _read_npz}


def read_record(path: str | Path, *, channels: Sequence[str] | None = None) -> Record:
    """Read a record from a CSV or ``.npz`` file (module docstring).

    Parameters
    ----------
    path : str or pathlib.Path
        A ``.csv`` file whose header names columns ``t``, ``x`` and optionally
        ``segment`` (in any order, other columns ignored), or ``t`` and two or more
        channels; or an ``.npz`` archive holding ``x``, or ``dofs`` and their samples
        (``q`` or one array a channel), either ``t`` or a scalar ``dt``, and optionally
        ``segment`` and ``measured``.
    channels : sequence of str, optional
        The channels to read, in this order (a system's ``dofs``); one name gives a
        single-channel record.  Default: as the module docstring says.

    Returns
    -------
    Record
        Named after the file's stem; ``dt`` is the mean step of ``t`` in the segments.

    Raises
    ------
    HosidInputError
        If the file is missing, a folder, not a regular file, unreadable, of unknown
        type, empty or (a CSV) not UTF-8 text, if a column or channel is missing (named,
        with those the file has) or a cell is not a number (named by column and line), if
        a segment label is not an integer or a segment not contiguous, if the times of a
        segment are not uniform (a step off the median by more than 1e-6 relative), or if
        the samples fail the checks of `Record`.
    """
    path = Path(path)
    if not path.exists():
        raise HosidInputError(f"{path}: no such file")
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
    if not path.is_file():
        raise HosidInputError(f"{path}: not a regular file (a .csv or .npz record is read whole)")
    if channels is not None:
        channels = (channels,) if isinstance(channels, str) else tuple(channels)
        if not channels:
            raise HosidInputError(f"{path}: channels must name at least one channel")
    return reader(path, channels)


def write_record(record: Record, path: str | Path) -> Path:
    """Write a record to a CSV or ``.npz`` file, chosen by the suffix.

    CSV files get a header ``t,x`` (``t,x,segment`` for several segments), or
    ``t,<channels>`` for any other record; times are written with 15 significant digits
    (so that they read back uniformly spaced), samples with 10.  ``.npz`` archives hold
    ``x`` and ``dt`` exactly (and the labels ``segment``), or for any other record one
    array a channel, ``dofs`` and ``measured``.  Reading the file back gives the same
    samples, ``dt``, segments and channels (and, from ``.npz``, what they measure; a CSV
    file of one channel not named ``x`` is read with ``channels=``).

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
    plain = record.channels == ("x",) and record.measured == ("displacement",)
    try:
        if suffix == ".csv":
            cols = [record.t, *record.samples.T]
            fmt = ["%.15g", *(["%.10g"] * record.n_channels)]
            header = ",".join(("t", *record.channels))
            if several:
                cols, fmt, header = [*cols, record.labels], [*fmt, "%d"], header + ",segment"
            np.savetxt(
                path, np.column_stack(cols), fmt=fmt, delimiter=",", header=header, comments=""
            )
        else:
            arrays = {"segment": record.labels} if several else {}
            if plain:
                arrays["x"] = record.x
            else:
                arrays.update(zip(record.channels, record.samples.T, strict=True))
                arrays.update(dofs=np.array(record.channels), measured=np.array(record.measured))
            with path.open("wb") as fh:
                np.savez(fh, dt=np.float64(record.dt), **arrays)
    except OSError as exc:
        raise HosidInputError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path
