"""The record: uniformly sampled channels ``x(t)`` in one or more segments.

A record is the only input of the identification: ``x_k = x(k dt)`` for
``k = 0, ..., n - 1``, cut into *segments*, each contiguous and sampled at the same
``dt``, with a gap of unknown length (or another realization) between them: no
statistic of hosid spans a gap.  A record of one segment is the common case.
(Its files: :mod:`hosid.record.files`.)

**Channels.**  A record holds one channel per measured degree of freedom, each named
(:attr:`Record.channels`, a system file's ``dofs``) and each a ``"displacement"`` or an
``"acceleration"`` (:attr:`Record.measured`).  The single oscillator's record is the
case of one displacement channel named ``x``: its samples ``x`` are 1-D, and its hash,
files and messages are those of hosid before channels existed.  Several channels are
held as one array ``x`` of shape ``(n_samples, n_channels)``, one column a channel (the
layout of a CSV file); :attr:`Record.samples` is that 2-D view for any number of
channels, :meth:`Record.channel` one channel as a single-channel record (for the
per-channel checks and spectra), and :meth:`Record.select` picks and orders the
channels a system names.  A single channel is always stored 1-D: there is one layout
per number of channels.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from hosid.errors import HosidInputError

__all__ = ["MEASURED", "MIN_SAMPLES", "RESERVED_NAMES", "UNIFORM_RTOL", "Record"]

#: Fewest samples a record (and each of its segments) may have.
MIN_SAMPLES = 16
#: Largest relative deviation of a time step from the median step.
UNIFORM_RTOL = 1e-6
#: What a channel may hold (:data:`hosid.model.system_file.MEASURED_KINDS` is the same).
MEASURED = ("displacement", "acceleration")
#: Names a channel may not take: the other arrays and columns of a record file.
RESERVED_NAMES = ("t", "dt", "segment", "dofs", "measured")


@dataclass(frozen=True, eq=False)
class Record:
    """A uniformly sampled response record: one or more channels, one or more segments.

    Parameters
    ----------
    x : numpy.ndarray
        The samples, real and finite (segments one after the other): 1-D for one
        channel, ``(n_samples, n_channels)`` for several (then ``channels`` names the
        columns; a single column is stored 1-D).  Stored as a read-only ``float64`` copy.
    dt : float
        Sampling interval in seconds, finite and positive (the same in every segment).
    name : str, optional
        Label used in reports (``read_record`` sets the file's stem).
    segments : sequence of int, optional
        Start index of each segment in ``x``: ``0`` first, strictly increasing.
        Default: one segment.  Stored as a tuple.
    channels : sequence of str, optional
        The channels' names (distinct, non-empty, without commas, none of
        :data:`RESERVED_NAMES`), one a column of ``x``.  Default ``("x",)`` for 1-D
        samples.
    measured : str, sequence of str or mapping, optional
        What each channel holds, ``"displacement"`` or ``"acceleration"``: one for all,
        one a channel, or by channel name (the others displacements).  Default:
        displacement.

    Raises
    ------
    HosidInputError
        If ``x`` is not real, not 1-D without ``channels`` or not 2-D with one column a
        channel, has fewer than 16 samples or a non-finite one (the message names the
        first), if ``dt`` is not finite and positive, if the segment starts are not
        integers from 0, increasing, with 16 samples a segment or more, or if a channel
        name or kind is bad.

    Examples
    --------
    >>> rec = Record.from_segments([np.zeros(20), np.ones(30)], 0.1)
    >>> rec.segments, rec.bounds
    ((0, 20), ((0, 20), (20, 50)))
    >>> two = Record(np.zeros((20, 2)), 0.1, channels=("x1", "x2"), measured="acceleration")
    >>> two.n_channels, two.channel("x2").measured
    (2, ('acceleration',))
    """

    x: np.ndarray
    dt: float
    name: str = ""
    segments: tuple[int, ...] | None = None
    channels: tuple[str, ...] | None = None
    measured: str | tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        x = np.asarray(self.x)
        if x.dtype.kind not in "fiu":
            raise HosidInputError(f"record samples must be real numbers, got dtype {x.dtype}")
        channels = _names(self.channels, x)
        if x.ndim == 2:
            x = x[:, 0] if len(channels) == 1 else x
        n = x.shape[0] if x.ndim else 0
        if n < MIN_SAMPLES:
            raise HosidInputError(f"record has {n} samples; at least {MIN_SAMPLES} are needed")
        x = np.array(x, dtype=np.float64)
        bad = np.argwhere(~np.isfinite(x))
        if bad.size:
            i = tuple(int(v) for v in bad[0])
            where = "" if x.ndim == 1 else f" of channel {channels[i[1]]!r}"
            raise HosidInputError(
                f"record sample {i[0]}{where} is {float(x[i])!r} "
                f"({len(bad)} non-finite samples in all)"
            )
        x.setflags(write=False)
        try:
            dt = float(self.dt)
        except (TypeError, ValueError):
            raise HosidInputError(f"dt must be a number, got {self.dt!r}") from None
        if not (math.isfinite(dt) and dt > 0):
            raise HosidInputError(f"dt must be finite and positive, got {dt!r}")
        set_ = object.__setattr__
        set_(self, "x", x)
        set_(self, "dt", dt)
        set_(self, "name", str(self.name))
        set_(self, "segments", _starts(self.segments, n))
        set_(self, "channels", channels)
        set_(self, "measured", _kinds(self.measured, channels))

    @classmethod
    def from_segments(
        cls,
        pieces: Sequence[np.ndarray],
        dt: float,
        name: str = "",
        *,
        channels: Sequence[str] | None = None,
        measured=None,
    ) -> Record:
        """A record of the arrays ``pieces``, one segment each: 1-D, or all
        ``(n_i, n_channels)`` with ``channels`` (and ``measured``) as for :class:`Record`.
        """
        pieces = [np.asarray(p) for p in pieces]
        ndim = 1 if channels is None else 2
        if not pieces or any(p.ndim != ndim for p in pieces):
            what = "1-D arrays" if ndim == 1 else "2-D arrays (samples, channels)"
            raise HosidInputError(f"segments must be a non-empty list of {what}")
        starts = np.concatenate([[0], np.cumsum([p.shape[0] for p in pieces])[:-1]])
        starts = tuple(int(s) for s in starts)
        return cls(np.concatenate(pieces), dt, name, starts, channels=channels, measured=measured)

    # ------------------------------------------------------------------ channels
    @property
    def n_channels(self) -> int:
        """Number of channels."""
        return len(self.channels)

    @property
    def samples(self) -> np.ndarray:
        """The samples as ``(n_samples, n_channels)`` (a read-only view), whatever the
        number of channels.
        """
        return self.x[:, None] if self.x.ndim == 1 else self.x

    def channel(self, name: str) -> Record:
        """Channel ``name`` as a single-channel record (same ``dt``, segments, name)."""
        return self.select((name,))

    def select(self, channels: Sequence[str], *, measured=None) -> Record:
        """The record of ``channels`` in that order (a system's ``dofs``).

        Parameters
        ----------
        channels : sequence of str
            Names of channels of this record (one name gives a single-channel record).
        measured : str or mapping or sequence, optional
            What the channels hold, as declared by the caller (a system file, a
            command-line option): one kind for all, a mapping by channel, or one a
            channel.  Default: what the record says.

        Raises
        ------
        HosidInputError
            If a channel is missing (naming it and the record's channels), named twice,
            or declared a displacement when the record says it is an acceleration.
        """
        if isinstance(channels, str):
            channels = (channels,)
        names = tuple(channels)
        if not names:
            raise HosidInputError("select needs at least one channel name")
        for c in names:
            if c not in self.channels:
                raise HosidInputError(
                    f"record {self.name!r} has no channel {c!r}; its channels: "
                    f"{', '.join(self.channels)}"
                )
        cols = [self.channels.index(c) for c in names]
        kinds = tuple(self.measured[k] for k in cols)
        if measured is not None:
            if isinstance(measured, Mapping):  # the channels it does not name keep their kind
                given = {c: k for c, k in measured.items() if c in names}
                measured = {**dict(zip(names, kinds, strict=True)), **given}
            declared = _kinds(measured, names)
            for c, have, want in zip(names, kinds, declared, strict=True):
                if have == "acceleration" and want != "acceleration":
                    raise HosidInputError(
                        f"channel {c!r} of record {self.name!r} is an acceleration (its file "
                        f"says so) but was declared a {want}"
                    )
            kinds = declared
        x = self.samples[:, cols]
        return Record(x, self.dt, self.name, self.segments, channels=names, measured=kinds)

    # ------------------------------------------------------------------ segments
    @property
    def n(self) -> int:
        """Number of samples (all segments)."""
        return int(self.x.shape[0])

    @property
    def n_segments(self) -> int:
        """Number of segments."""
        return len(self.segments)

    @property
    def bounds(self) -> tuple[tuple[int, int], ...]:
        """``(start, stop)`` of every segment in ``x``."""
        stops = (*self.segments[1:], self.n)
        return tuple(zip(self.segments, stops, strict=True))

    def split(self, y: np.ndarray, axis: int = -1) -> list[np.ndarray]:
        """An array aligned with the samples along ``axis`` (default the last, as a
        channel's samples; ``axis=0`` for :attr:`samples`) cut into its segments (views).
        """
        return np.split(np.asarray(y), self.segments[1:], axis=axis)

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
        16 digits): what a chain backend checks before it resumes.  The channels' names
        enter for several channels, what they measure when one is an acceleration: one
        displacement channel hashes as before channels existed, whatever its name.
        """
        h = hashlib.sha256(self.x.tobytes())
        h.update(np.float64(self.dt).tobytes())
        if self.n_segments > 1:  # a one-segment record hashes as before segments existed
            h.update(np.asarray(self.segments, dtype=np.int64).tobytes())
        if self.n_channels > 1:
            h.update(",".join(self.channels).encode())
        if "acceleration" in self.measured:
            h.update(",".join(self.measured).encode())
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
        state.setdefault("channels", ("x",))  # pickled before channels existed
        state.setdefault("measured", ("displacement",))
        self.__dict__.update(state)

    def __repr__(self) -> str:
        seg = f", segments={self.n_segments}" if self.n_segments > 1 else ""
        ch = f", channels={self.channels!r}" if self.channels != ("x",) else ""
        kinds = f", measured={self.measured!r}" if "acceleration" in self.measured else ""
        return f"Record(n={self.n}, dt={self.dt!r}, name={self.name!r}{seg}{ch}{kinds})"


def _names(channels, x: np.ndarray) -> tuple[str, ...]:
    """Validated channel names for samples ``x`` (see :class:`Record`)."""
    if channels is None:
        if x.ndim != 1:
            raise HosidInputError(
                f"record samples must be 1-D, got shape {x.shape} (several channels need "
                "their names: channels=...)"
            )
        return ("x",)
    names = (channels,) if isinstance(channels, str) else tuple(channels)
    one = x.ndim == 1 and len(names) == 1  # a single channel given 1-D
    if not one and (x.ndim != 2 or x.shape[1] != len(names) or not names):
        raise HosidInputError(
            f"record samples of {len(names)} channels must be (n_samples, {len(names)}), "
            f"got shape {x.shape}"
        )
    for c in names:
        if not _good_name(c):
            raise HosidInputError(
                f"bad channel name {c!r}: a non-empty name without commas, quotes or "
                f"surrounding spaces, none of {', '.join(RESERVED_NAMES)}"
            )
    dup = [c for k, c in enumerate(names) if c in names[:k]]
    if dup:
        raise HosidInputError(f"channel {dup[0]!r} given twice")
    return names


def _good_name(c) -> bool:
    """A channel name: a non-empty string without commas, quotes, line breaks or
    surrounding spaces (a CSV header holds it), not reserved.
    """
    return (
        isinstance(c, str)
        and bool(c)
        and c == c.strip()
        and c not in RESERVED_NAMES
        and not any(s in c for s in ",\"'\n\r")
    )


def _kinds(measured, channels: tuple[str, ...]) -> tuple[str, ...]:
    """What each channel holds (see :class:`Record`)."""
    if measured is None:
        measured = "displacement"
    if isinstance(measured, Mapping):
        extra = [c for c in measured if c not in channels]
        if extra:
            raise HosidInputError(
                f"measured names channel {extra[0]!r}, not one of {', '.join(channels)}"
            )
        measured = [measured.get(c, "displacement") for c in channels]
    kinds = (measured,) * len(channels) if isinstance(measured, str) else tuple(measured)
    if len(kinds) != len(channels):
        raise HosidInputError(
            f"measured names {len(kinds)} kinds for {len(channels)} channels "
            f"({', '.join(channels)})"
        )
    for c, k in zip(channels, kinds, strict=True):
        if k not in MEASURED:
            raise HosidInputError(
                f"channel {c!r}: measured must be one of {', '.join(MEASURED)}, got {k!r}"
            )
    return kinds


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
