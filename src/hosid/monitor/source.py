r"""A long or growing record, read by chunks: a file, or a folder of consecutive files.

``hosid monitor`` never holds a long record whole.  A :class:`Source` yields
:class:`Piece`\ s of at most :data:`CHUNK` samples, each with the time of its first
sample and whether a *run* starts there (the record's first sample, a new segment of a
CSV's ``segment`` column, a gap in the time column, or a file of a folder whose first
time does not continue the previous one).  No window spans a run's start.

Formats (as :func:`hosid.record.read_record`):

* ``.csv`` with a header naming ``t`` and ``x`` (and optionally ``segment``), read with
  :func:`numpy.loadtxt` a chunk of lines at a time;
* ``.npz`` holding a 1-D ``x`` and either ``t`` (shaped as ``x``) or a scalar ``dt``;
  the arrays are streamed from the archive's members (:mod:`numpy.lib.format` headers),
  so an uncompressed or compressed archive is never loaded whole;
* a folder of such files, taken in natural order of their names (``part2`` before
  ``part10``); files without a time column continue the previous file's time.

With ``follow`` a CSV source waits at its end for more lines (a last line without its
newline is left for later) until its ``stop`` callback says so: the monitor's
``--follow``.
"""

from __future__ import annotations

import itertools
import math
import re
import time
import zipfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.lib import format as npy_format

from ..errors import HosidInputError
from ..record.core import UNIFORM_RTOL

__all__ = ["CHUNK", "Piece", "Source", "open_source"]

#: Samples read at a time.
CHUNK = 1 << 18
#: A time step larger than this many sampling intervals is a gap (a new run).
GAP_STEPS = 1.5
SUFFIXES = (".csv", ".npz")


@dataclass(frozen=True)
class Piece:
    """Consecutive samples ``x`` from time ``t0`` on; ``new_run``: a run starts here."""

    t0: float
    x: np.ndarray
    new_run: bool


def _natural(path: Path) -> list:
    return [int(s) if s.isdigit() else s.lower() for s in re.split(r"(\d+)", path.name)]


class Source:
    """A record file or a folder of them (module docstring).

    Parameters
    ----------
    path : str or pathlib.Path
        A ``.csv`` or ``.npz`` record, or a folder of them.

    Raises
    ------
    HosidInputError
        If the path is missing, of another type, an empty folder, or its first file has
        no readable header or sampling interval.
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if self.path.is_dir():
            files = sorted(
                (p for p in self.path.iterdir() if p.suffix.lower() in SUFFIXES and p.is_file()),
                key=_natural,
            )
            if not files:
                raise HosidInputError(f"{self.path}: a folder without .csv or .npz records")
        elif not self.path.exists():
            raise HosidInputError(f"{self.path}: no such file or folder")
        elif self.path.suffix.lower() not in SUFFIXES:
            raise HosidInputError(
                f"{self.path}: unknown file type {self.path.suffix or '(none)'!r}; "
                "use .csv, .npz or a folder of them"
            )
        else:
            files = [self.path]
        self.files = files
        self.dt = _first_dt(files[0])
        self.name = self.path.stem if self.path.is_file() else self.path.name

    def samples(self) -> int:
        """The number of samples now in the source (a pass over CSV files' lines)."""
        total = 0
        for f in self.files:
            if f.suffix.lower() == ".npz":
                with zipfile.ZipFile(f) as z, z.open("x.npy") as fh:
                    total += int(np.prod(_header(fh, f, "x")[0]))
            else:
                with f.open("rb") as fh:
                    total += max(sum(1 for line in fh if line.strip()) - 1, 0)
        return total

    def pieces(
        self, *, follow: bool = False, poll: float = 1.0, stop: Callable[[], bool] | None = None
    ) -> Iterator[Piece | None]:
        """The samples, a chunk at a time (module docstring); with ``follow`` the last
        CSV file is watched for appended lines until ``stop()`` is true, and ``None`` is
        yielded after each look that found nothing new.
        """
        t_next = None
        for i, f in enumerate(self.files):
            last = follow and i == len(self.files) - 1
            dt_f = _first_dt(f) if i else self.dt
            if abs(dt_f - self.dt) > 1e-6 * self.dt:
                first = self.files[0].name
                raise HosidInputError(f"{f}: dt = {dt_f:g} s, not {self.dt:g} s as in {first}")
            if f.suffix.lower() == ".npz":
                if last:
                    raise HosidInputError(f"{f}: --follow needs a growing .csv file")
                chunks = _npz_chunks(f, self.dt, t_next)
            else:
                chunks = _csv_chunks(f, self.dt, t_next, follow=last, poll=poll, stop=stop)
            for piece in chunks:
                yield piece
                if piece is None:
                    continue
                t_next = piece.t0 + piece.x.size * self.dt


def open_source(path: str | Path) -> Source:
    """:class:`Source` of ``path``."""
    return Source(path)


# --- CSV ------------------------------------------------------------------------------


def _csv_columns(path: Path, header: str) -> tuple[int, int, int | None]:
    names = [c.strip().strip("\"'").strip() for c in header.split(",")]
    for col in ("t", "x"):
        if col not in names:
            raise HosidInputError(f"{path}: no column {col!r} in header {header.strip()!r}")
    seg = names.index("segment") if "segment" in names else None
    return names.index("t"), names.index("x"), seg


def _parse(path: Path, lines: list[str], cols, first_line: int) -> np.ndarray:
    use = [c for c in cols if c is not None]
    try:
        return np.loadtxt(lines, delimiter=",", usecols=use, ndmin=2, dtype=float)
    except ValueError as exc:
        raise HosidInputError(
            f"{path}: a line from line {first_line} on is not numbers in columns "
            f"t, x ({' '.join(str(exc).split())[:120]})"
        ) from None


def _read_lines(fh, n: int, follow: bool) -> list[str]:
    """Up to ``n`` complete lines; a partial last line is pushed back when following."""
    lines = []
    for _ in range(n):
        pos = fh.tell()
        line = fh.readline()
        if not line:
            break
        if not line.endswith("\n") and follow:
            fh.seek(pos)
            break
        if line.strip():
            lines.append(line)
    return lines


def _csv_chunks(path, dt, t_next, *, follow, poll, stop) -> Iterator[Piece | None]:
    try:
        fh = path.open(newline="")
    except OSError as exc:
        raise HosidInputError(f"cannot read {path}: {exc.strerror or exc}") from None
    with fh:
        header = fh.readline()
        if not header.strip():
            raise HosidInputError(f"{path}: empty file, expected a header naming t and x")
        cols = _csv_columns(path, header)
        line_no, prev_t, prev_seg = 2, t_next, None
        while True:
            lines = _read_lines(fh, CHUNK, follow)
            if not lines:
                if not follow or (stop is not None and stop()):
                    return
                time.sleep(poll)
                yield None  # a tick: nothing new yet
                continue
            a = _parse(path, lines, cols, line_no)
            line_no += len(lines)
            t, x = a[:, 0], a[:, 1]
            seg = a[:, 2] if cols[2] is not None else None
            yield from _split_runs(path, t, x, seg, dt, prev_t, prev_seg)
            prev_t = float(t[-1]) + dt
            prev_seg = None if seg is None else float(seg[-1])


def _split_runs(path, t, x, seg, dt, prev_t, prev_seg) -> Iterator[Piece]:
    """Cut a chunk where its times jump (or its segment label changes)."""
    if not np.all(np.isfinite(x)):
        i = int(np.flatnonzero(~np.isfinite(x))[0])
        raise HosidInputError(f"{path}: x is not finite at t = {t[i]:g}")
    steps = np.diff(t, prepend=t[0] - dt if prev_t is None else prev_t - dt)
    if np.any(steps <= 0):
        i = int(np.flatnonzero(steps <= 0)[0])
        raise HosidInputError(f"{path}: the time column does not increase at t = {t[i]:g}")
    breaks = steps > GAP_STEPS * dt
    bad = ~breaks & (np.abs(steps - dt) > max(UNIFORM_RTOL * 1e3, 1e-6) * dt)
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise HosidInputError(
            f"{path}: the sampling is not uniform at t = {t[i]:g} "
            f"(step {steps[i]:g} s against dt = {dt:g} s)"
        )
    if seg is not None:
        before = np.concatenate([[seg[0] if prev_seg is None else prev_seg], seg[:-1]])
        breaks |= seg != before
    if prev_t is None:
        breaks[0] = True
    starts = [*np.flatnonzero(breaks), t.size] if breaks.any() else [0, t.size]
    if starts[0] != 0:
        starts = [0, *starts]
    for a, b in itertools.pairwise(starts):
        if b > a:
            yield Piece(float(t[a]), np.ascontiguousarray(x[a:b]), bool(breaks[a]))


def _first_dt(path: Path) -> float:
    if path.suffix.lower() == ".npz":
        return _npz_dt(path)
    try:
        with path.open(newline="") as fh:
            header = fh.readline()
            if not header.strip():
                raise HosidInputError(f"{path}: empty file, expected a header naming t and x")
            cols = _csv_columns(path, header)
            lines = _read_lines(fh, 1024, follow=False)
    except OSError as exc:
        raise HosidInputError(f"cannot read {path}: {exc.strerror or exc}") from None
    if len(lines) < 2:
        raise HosidInputError(f"{path}: fewer than 2 samples; the sampling interval is unknown")
    t = _parse(path, lines, cols, 2)[:, 0]
    dt = _rounded(float(np.median(np.diff(t))))
    if not (math.isfinite(dt) and dt > 0):
        raise HosidInputError(f"{path}: the time column does not increase")
    return dt


# --- npz ------------------------------------------------------------------------------


def _header(fh, path: Path, name: str) -> tuple[tuple[int, ...], bool, np.dtype]:
    try:
        version = npy_format.read_magic(fh)
        if version == (1, 0):
            return npy_format.read_array_header_1_0(fh)
        return npy_format.read_array_header_2_0(fh)
    except ValueError as exc:
        raise HosidInputError(f"{path}: array {name!r} is not a numpy array ({exc})") from None


def _npz_members(path: Path) -> dict[str, str]:
    if not zipfile.is_zipfile(path):
        raise HosidInputError(f"cannot read {path}: not an .npz archive (not a zip file)")
    with zipfile.ZipFile(path) as z:
        return {n.removesuffix(".npy"): n for n in z.namelist()}


def _npz_dt(path: Path) -> float:
    members = _npz_members(path)
    if "x" not in members:
        raise HosidInputError(f"{path}: no array 'x' (found {sorted(members)})")
    with np.load(path, allow_pickle=False) as archive:
        if "dt" in members:
            dt = np.asarray(archive["dt"])
            if dt.size != 1:
                raise HosidInputError(f"{path}: dt must be a single number")
            return float(dt.reshape(()))
        if "t" not in members:
            raise HosidInputError(f"{path}: needs an array 't' or 'dt' besides 'x'")
    with zipfile.ZipFile(path) as z, z.open(members["t"]) as fh:
        shape, _, dtype = _header(fh, path, "t")
        t = np.frombuffer(fh.read(dtype.itemsize * min(1024, int(np.prod(shape)))), dtype)
    if t.size < 2:
        raise HosidInputError(f"{path}: fewer than 2 samples; the sampling interval is unknown")
    return _rounded(float(np.median(np.diff(t))))


def _rounded(dt: float) -> float:
    """The median step to 12 significant digits (times printed with rounding)."""
    return float(f"{dt:.12g}") if math.isfinite(dt) else dt


def _stream(z: zipfile.ZipFile, member: str, path: Path, name: str) -> Iterator[np.ndarray]:
    with z.open(member) as fh:
        shape, _, dtype = _header(fh, path, name)
        if len(shape) != 1:
            raise HosidInputError(f"{path}: {name} must be 1-D for monitoring, got {shape}")
        left = int(shape[0])
        while left:
            k = min(CHUNK, left)
            buf = fh.read(k * dtype.itemsize)
            if len(buf) < k * dtype.itemsize:
                raise HosidInputError(f"{path}: array {name!r} is truncated")
            yield np.frombuffer(buf, dtype).astype(float)
            left -= k


def _npz_chunks(path: Path, dt: float, t_next: float | None) -> Iterator[Piece]:
    members = _npz_members(path)
    with zipfile.ZipFile(path) as z:
        xs = _stream(z, members["x"], path, "x")
        if "t" in members and "dt" not in members:
            ts = _stream(z, members["t"], path, "t")
            prev = t_next
            for x, t in zip(xs, ts, strict=True):
                yield from _split_runs(path, t, x, None, dt, prev, None)
                prev = float(t[-1]) + dt
            return
        t0, first = (0.0 if t_next is None else t_next), t_next is None
        for x in xs:
            if not np.all(np.isfinite(x)):
                raise HosidInputError(f"{path}: x is not finite near t = {t0:g}")
            yield Piece(t0, x, first)
            t0, first = t0 + x.size * dt, False
