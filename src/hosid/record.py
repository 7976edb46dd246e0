"""Measured records: a uniformly sampled displacement ``x(t)`` in one or more segments,
its I/O and validation.

A record is the only input of the identification: ``x_k = x(k dt)`` for
``k = 0, ..., n - 1``, cut into *segments*, each contiguous and sampled at the same
``dt``, with a gap of unknown length (or another realization) between them: no
statistic of hosid spans a gap.  A record of one segment is the common case.

Files are CSV with a header naming columns ``t`` and ``x`` and optionally an integer
``segment`` column (any order, extra columns ignored; the time may jump between
segments), or ``.npz`` archives holding ``x`` (1-D, or 2-D with one segment a row),
either ``t`` (shaped as ``x``) or ``dt``, and optionally ``segment`` (one integer label
a sample, as the CSV column).
"""

from __future__ import annotations

import hashlib
import math
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from hosid.errors import HosidInputError

__all__ = ["MIN_SAMPLES", "Record", "read_record", "write_record"]

#: Fewest samples a record (and each of its segments) may have.
MIN_SAMPLES = 16
#: Largest relative deviation of a time step from the median step.
UNIFORM_RTOL = 1e-6


@dataclass(frozen=True, eq=False)
class Record:
    """A uniformly sampled response record, in one or more segments.

    Parameters
    ----------
    x : numpy.ndarray
        Displacement samples, 1-D, real and finite (segments one after the other).
        Stored as a read-only ``float64`` copy.
    dt : float
        Sampling interval in seconds, finite and positive (the same in every segment).
    name : str, optional
        Label used in reports (``read_record`` sets the file's stem).
    segments : sequence of int, optional
        Start index of each segment in ``x``: ``0`` first, strictly increasing.
        Default: one segment.  Stored as a tuple.

    Raises
    ------
    HosidInputError
        If ``x`` is not 1-D and real, has fewer than 16 samples or a non-finite one (the
        message names the first), if ``dt`` is not finite and positive, or if the segment
        starts are not integers from 0, increasing, with 16 samples a segment or more.

    Examples
    --------
    >>> rec = Record.from_segments([np.zeros(20), np.ones(30)], 0.1)
    >>> rec.segments, rec.bounds
    ((0, 20), ((0, 20), (20, 50)))
    """

    x: np.ndarray
    dt: float
    name: str = ""
    segments: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        x = np.asarray(self.x)
        if x.dtype.kind not in "fiu":
            raise HosidInputError(f"record samples must be real numbers, got dtype {x.dtype}")
        if x.ndim != 1:
            raise HosidInputError(f"record samples must be 1-D, got shape {x.shape}")
        if x.size < MIN_SAMPLES:
            raise HosidInputError(
                f"record has {x.size} samples; at least {MIN_SAMPLES} are needed"
            )
        x = np.array(x, dtype=np.float64)
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            i = int(bad[0])
            raise HosidInputError(
                f"record sample {i} is {float(x[i])!r} ({bad.size} non-finite samples in all)"
            )
        x.setflags(write=False)
        try:
            dt = float(self.dt)
        except (TypeError, ValueError):
            raise HosidInputError(f"dt must be a number, got {self.dt!r}") from None
        if not (math.isfinite(dt) and dt > 0):
            raise HosidInputError(f"dt must be finite and positive, got {dt!r}")
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "name", str(self.name))
        object.__setattr__(self, "segments", _starts(self.segments, x.size))

    @classmethod
    def from_segments(cls, pieces: Sequence[np.ndarray], dt: float, name: str = "") -> Record:
        """A record of the 1-D arrays ``pieces``, one segment each."""
        pieces = [np.asarray(p) for p in pieces]
        if not pieces or any(p.ndim != 1 for p in pieces):
            raise HosidInputError("segments must be a non-empty list of 1-D arrays")
        starts = np.concatenate([[0], np.cumsum([p.size for p in pieces])[:-1]])
        return cls(np.concatenate(pieces), dt, name, tuple(int(s) for s in starts))

    @property
    def n(self) -> int:
        """Number of samples (all segments)."""
        return int(self.x.size)

    @property
    def n_segments(self) -> int:
        """Number of segments."""
        return len(self.segments)

    @property
    def bounds(self) -> tuple[tuple[int, int], ...]:
        """``(start, stop)`` of every segment in ``x``."""
        stops = (*self.segments[1:], self.n)
        return tuple(zip(self.segments, stops, strict=True))

    def split(self, y: np.ndarray) -> list[np.ndarray]:
        """An array aligned with ``x`` (last axis) cut into its segments (views)."""
        return [np.asarray(y)[..., a:b] for a, b in self.bounds]

    @property
    def labels(self) -> np.ndarray:
        """The segment of every sample (0, 1, ...)."""
        return np.repeat(np.arange(self.n_segments), [b - a for a, b in self.bounds])

    @property
    def t(self) -> np.ndarray:
        """Sample times ``k dt``, ``k = 0, ..., n - 1``, in seconds (gaps not kept)."""
        return self.dt * np.arange(self.n)

    @property
    def duration(self) -> float:
        """Sampled time ``n dt`` in seconds (all segments)."""
        return self.n * self.dt

    @cached_property
    def hash(self) -> str:
        """SHA-256 of the samples, the sampling interval and the segment starts (hex,
        16 digits): what a chain backend checks before it resumes.
        """
        h = hashlib.sha256(self.x.tobytes())
        h.update(np.float64(self.dt).tobytes())
        if self.n_segments > 1:  # a one-segment record hashes as before segments existed
            h.update(np.asarray(self.segments, dtype=np.int64).tobytes())
        return h.hexdigest()[:16]

    def __setstate__(self, state: dict) -> None:
        """Unpickle with a fresh, aligned copy of the samples: what arrives through dask
        is a view at any byte offset of a message, and numpy sums unaligned data in
        another order (the last digits of a fit would depend on how the record
        travelled).
        """
        state = dict(state)
        x = np.array(state["x"], dtype=np.float64)
        x.setflags(write=False)
        state["x"] = x
        self.__dict__.update(state)

    def __repr__(self) -> str:
        seg = f", segments={self.n_segments}" if self.n_segments > 1 else ""
        return f"Record(n={self.n}, dt={self.dt!r}, name={self.name!r}{seg})"


def _starts(segments, n: int) -> tuple[int, ...]:
    """Validated segment starts (see :class:`Record`)."""
    if segments is None:
        return (0,)
    s = np.asarray(segments)
    if s.ndim != 1 or s.size == 0 or s.dtype.kind not in "iu":
        raise HosidInputError(f"segments must be a 1-D list of start indices, got {segments!r}")
    if s[0] != 0:
        raise HosidInputError(f"the first segment must start at sample 0, not {int(s[0])}")
    lengths = np.diff(np.append(s, n))
    if np.any(lengths < MIN_SAMPLES):
        k = int(np.flatnonzero(lengths < MIN_SAMPLES)[0])
        raise HosidInputError(
            f"segment {k} (from sample {int(s[k])}) has {int(lengths[k])} samples; "
            f"each segment needs at least {MIN_SAMPLES}, in increasing order"
        )
    return tuple(int(v) for v in s)


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
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise HosidInputError(f"cannot read {path}: {exc}") from None
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
        If the file is missing, a directory, unreadable, empty or of unknown type, if a
        column is missing or a cell is not a number (named by column and line), if a
        segment label is not an integer or a segment not contiguous, if the times of a
        segment are not uniform (a step off the median by more than 1e-6 relative), or
        if the samples fail the checks of `Record`.
    """
    path = Path(path)
    reader = _READERS.get(path.suffix.lower())
    if reader is None:
        raise HosidInputError(
            f"{path}: unknown file type {path.suffix or '(none)'!r}; use .csv or .npz"
        )
    if path.is_dir():
        raise HosidInputError(f"{path}: is a directory, not a record file")
    if not path.is_file():
        raise HosidInputError(f"{path}: no such file")
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
