"""The record: a uniformly sampled displacement ``x(t)`` in one or more segments.

A record is the only input of the identification: ``x_k = x(k dt)`` for
``k = 0, ..., n - 1``, cut into *segments*, each contiguous and sampled at the same
``dt``, with a gap of unknown length (or another realization) between them: no
statistic of hosid spans a gap.  A record of one segment is the common case.
(Its files: :mod:`hosid.record.files`.)
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from hosid.errors import HosidInputError

__all__ = ["MIN_SAMPLES", "UNIFORM_RTOL", "Record"]

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
