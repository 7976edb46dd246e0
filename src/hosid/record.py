"""Measured records: a uniformly sampled displacement ``x(t)``, its I/O and validation.

A record is the only input of the identification: ``x_k = x(k dt)`` for
``k = 0, ..., n - 1``. Files are CSV with a header naming columns ``t`` and
``x`` (any order, extra columns ignored) or ``.npz`` archives holding ``x``
and either ``t`` or ``dt``.
"""

from __future__ import annotations

import hashlib
import io
import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from hosid.errors import HosidInputError

__all__ = ["MIN_SAMPLES", "Record", "read_record", "write_record"]

#: Fewest samples a record may have.
MIN_SAMPLES = 16
#: Largest relative deviation of a time step from the median step.
UNIFORM_RTOL = 1e-6


@dataclass(frozen=True, eq=False)
class Record:
    """A uniformly sampled response record.

    Parameters
    ----------
    x : numpy.ndarray
        Displacement samples, 1-D, real and finite. Stored as a read-only
        ``float64`` copy.
    dt : float
        Sampling interval in seconds, finite and positive.
    name : str, optional
        Label used in reports (``read_record`` sets the file's stem).

    Raises
    ------
    HosidInputError
        If ``x`` is not 1-D, not real, has fewer than 16 samples or holds a
        NaN or an infinity (the message names the first bad index), or if
        ``dt`` is not finite and positive.
    """

    x: np.ndarray
    dt: float
    name: str = ""

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

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.x.size)

    @property
    def t(self) -> np.ndarray:
        """Sample times ``k dt``, ``k = 0, ..., n - 1``, in seconds."""
        return self.dt * np.arange(self.n)

    @property
    def duration(self) -> float:
        """Record length ``n dt`` in seconds."""
        return self.n * self.dt

    @cached_property
    def hash(self) -> str:
        """SHA-256 of the samples and the sampling interval (hex, 16 digits): what a
        chain backend checks before it resumes.
        """
        h = hashlib.sha256(self.x.tobytes())
        h.update(np.float64(self.dt).tobytes())
        return h.hexdigest()[:16]

    def __repr__(self) -> str:
        return f"Record(n={self.n}, dt={self.dt!r}, name={self.name!r})"


def _dt_from_times(t: np.ndarray, source: str) -> float:
    """Return the time step of uniformly spaced times ``t`` or raise."""
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1:
        raise HosidInputError(f"{source}: t must be 1-D, got shape {t.shape}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise HosidInputError(f"{source}: time {int(bad[0])} is {float(t[bad[0]])!r}")
    if t.size < 2:
        raise HosidInputError(f"{source}: at least 2 time values are needed")
    steps = np.diff(t)
    median = float(np.median(steps))
    if not median > 0:
        raise HosidInputError(f"{source}: times must increase, median step is {median!r}")
    dev = np.abs(steps - median) / median
    worst = int(np.argmax(dev))
    if dev[worst] > UNIFORM_RTOL:
        raise HosidInputError(
            f"non-uniform sampling: {source}: step {worst} "
            f"(t={float(t[worst])!r} -> {float(t[worst + 1])!r}) "
            f"differs from the median step {median!r} by a relative {dev[worst]:.3g} "
            f"(tolerance {UNIFORM_RTOL:g})"
        )
    return float((t[-1] - t[0]) / (t.size - 1))


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
    it, ix = names.index("t"), names.index("x")
    if not any(line.strip() for line in lines[1:]):
        raise HosidInputError(f"{path}: no data rows after the header")
    try:
        data = np.loadtxt(
            io.StringIO(text),
            delimiter=",",
            skiprows=1,
            usecols=(it, ix),
            ndmin=2,
            dtype=np.float64,
        )
    except ValueError as exc:
        raise HosidInputError(f"{path}: {exc}") from None
    dt = _dt_from_times(data[:, 0], str(path))
    return Record(data[:, 1], dt, name=path.stem)


def _read_npz(path: Path) -> Record:
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {k: archive[k] for k in archive.files}
    except (OSError, ValueError, EOFError) as exc:
        raise HosidInputError(f"cannot read {path}: {exc}") from None
    if "x" not in arrays:
        raise HosidInputError(f"{path}: no array 'x' (found {sorted(arrays)})")
    if "t" in arrays:
        dt = _dt_from_times(arrays["t"], str(path))
        if np.shape(arrays["t"]) != np.shape(arrays["x"]):
            raise HosidInputError(
                f"{path}: t has shape {np.shape(arrays['t'])} but x has {np.shape(arrays['x'])}"
            )
    elif "dt" in arrays:
        if np.size(arrays["dt"]) != 1 or np.asarray(arrays["dt"]).dtype.kind not in "fiu":
            raise HosidInputError(f"{path}: dt must be a single number")
        dt = float(np.asarray(arrays["dt"]).reshape(()))
    else:
        raise HosidInputError(f"{path}: needs an array 't' or 'dt' besides 'x'")
    return Record(arrays["x"], dt, name=path.stem)


_READERS = {".csv": _read_csv, ".npz": _read_npz}


def read_record(path: str | Path) -> Record:
    """Read a record from a CSV or ``.npz`` file.

    Parameters
    ----------
    path : str or pathlib.Path
        A ``.csv`` file whose header names columns ``t`` and ``x`` (in any
        order, other columns ignored), or an ``.npz`` archive holding ``x``
        and either ``t`` or a scalar ``dt``.

    Returns
    -------
    Record
        The record, named after the file's stem; ``dt`` is the mean step of ``t``.

    Raises
    ------
    HosidInputError
        If the file is missing, unreadable, empty or of unknown type, if a
        column is missing, if the times are not uniformly spaced (relative
        deviation of a step from the median step above 1e-6), or if the
        samples fail the checks of `Record`.
    """
    path = Path(path)
    reader = _READERS.get(path.suffix.lower())
    if reader is None:
        raise HosidInputError(
            f"{path}: unknown file type {path.suffix or '(none)'!r}; use .csv or .npz"
        )
    if not path.is_file():
        raise HosidInputError(f"{path}: no such file")
    return reader(path)


def write_record(record: Record, path: str | Path) -> Path:
    """Write a record to a CSV or ``.npz`` file, chosen by the suffix.

    CSV files get a header ``t,x``; times are written with 15 significant
    digits (so that they read back uniformly spaced), samples with 10.
    ``.npz`` archives hold ``x`` and ``dt`` exactly.

    Parameters
    ----------
    record : Record
        The record to write.
    path : str or pathlib.Path
        Destination ending in ``.csv`` or ``.npz``.

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    HosidInputError
        If the suffix is unknown or the file cannot be written.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in _READERS:
        raise HosidInputError(
            f"{path}: unknown file type {path.suffix or '(none)'!r}; use .csv or .npz"
        )
    try:
        if suffix == ".csv":
            data = np.column_stack([record.t, record.x])
            np.savetxt(
                path, data, fmt=["%.15g", "%.10g"], delimiter=",", header="t,x", comments=""
            )
        else:
            with path.open("wb") as fh:
                np.savez(fh, x=record.x, dt=np.float64(record.dt))
    except OSError as exc:
        raise HosidInputError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path
