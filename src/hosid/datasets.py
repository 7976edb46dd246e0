r"""Loaders of public benchmark measurements as hosid records.

:func:`load_silverbox` reads a file of the Silverbox benchmark (nonlinearbenchmark.org;
Wigren & Schoukens, "Three free data sets for development and benchmarking in nonlinear
system identification", ECC 2013): an electronic circuit that behaves as
:math:`m\ddot y + d\dot y + k_1y + k_3y^3 = u`, its input voltage ``V1`` (:math:`u`) and
output voltage ``V2`` (:math:`y`) sampled at :math:`f_s = 10^7/2^{14}` Hz.  The files
hold random-phase odd multisines of period :data:`SILVERBOX_PERIOD` samples (every odd
line of :math:`f_s/8192` up to 200 Hz), each played for a lead-in and then one period,
between sections of zero input.  The loader finds every steady-state period from the
input alone: where :math:`u[n] = u[n + P]` over at least :data:`MIN_LEAD` samples of
active input (the lead-in repeats the end of the period), the period that follows the
lead-in is in steady state; a section whose input repeats after half a period too (the
Schroeder multisine of period 1024) is not one of them.  The output of those periods is
returned as a record in segments (one period a segment) and the input is kept alongside,
for an input-output reference.

Accepted files: the MATLAB file (``V1``, ``V2``, read with :func:`scipy.io.loadmat`) and
the CSV files of the official zip, whose header names the columns ``V1`` and ``V2``
among others (``Schroeder80mV.csv``: ``Ovld2,Ovld1,V1,V2``; ``SNLS80mV.csv``: ``V1,V2``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import HosidInputError
from .record import Record

__all__ = ["MIN_LEAD", "SILVERBOX_FS", "SILVERBOX_PERIOD", "Silverbox", "load_silverbox"]

#: Sampling frequency of the Silverbox files (Hz).
SILVERBOX_FS = 1e7 / 2**14
#: Period of the random-phase odd multisines (samples).
SILVERBOX_PERIOD = 8192
#: Fewest samples of repeated active input that mark a lead-in.
MIN_LEAD = 100


@dataclass(frozen=True)
class Silverbox:
    """Steady-state multisine periods of a Silverbox file.

    Attributes
    ----------
    record : Record
        The output ``V2`` of every period, one segment each (as measured: offset kept).
    inputs : tuple of ndarray
        The input ``V1`` of the same samples, one array a segment.
    starts : tuple of int
        First sample of every period in the file.
    period : int
        Samples a period.
    """

    record: Record
    inputs: tuple[np.ndarray, ...] = field(repr=False)
    starts: tuple[int, ...]
    period: int

    @property
    def fs(self) -> float:
        """Sampling frequency (Hz)."""
        return 1.0 / self.record.dt


def _read(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """``(V1, V2)`` of a Silverbox ``.mat`` or ``.csv`` file."""
    if path.suffix.lower() == ".mat":
        from scipy.io import loadmat

        try:
            data = loadmat(path)
        except (OSError, ValueError, TypeError) as exc:
            raise HosidInputError(f"cannot read {path} as a MATLAB file: {exc}") from None
        if "V1" not in data or "V2" not in data:
            names = sorted(k for k in data if not k.startswith("__"))
            raise HosidInputError(f"{path}: no variables V1 and V2 (found {names})")
        return (np.asarray(data["V1"], dtype=float).ravel(),
                np.asarray(data["V2"], dtype=float).ravel())  # fmt: skip
    if path.suffix.lower() == ".csv":
        lines = path.read_text().splitlines()
        names = [c.strip().strip("\"'") for c in (lines[0].split(",") if lines else [])]
        if "V1" not in names or "V2" not in names:
            raise HosidInputError(f"{path}: the header names no columns V1 and V2")
        i1, i2 = names.index("V1"), names.index("V2")
        rows = [line.split(",") for line in lines[1:] if line.strip()]
        try:
            return (np.array([r[i1] for r in rows], dtype=float),
                    np.array([r[i2] for r in rows], dtype=float))  # fmt: skip
        except (ValueError, IndexError):
            raise HosidInputError(f"{path}: V1 and V2 must be numbers on every row") from None
    raise HosidInputError(f"{path}: a Silverbox file is .mat or .csv")


def _active(u: np.ndarray, width: int = 64) -> np.ndarray:
    """Samples where the input is on: a running rms above a fifth of the median one."""
    kernel = np.ones(width) / width
    rms = np.sqrt(np.convolve((u - np.median(u)) ** 2, kernel, "same"))
    return rms > 0.2 * np.median(rms[rms > 0.5 * rms.max()])


def load_silverbox(path: str | Path, *, period: int = SILVERBOX_PERIOD) -> Silverbox:
    """The steady-state multisine periods of a Silverbox file (module docstring).

    Parameters
    ----------
    path : str or pathlib.Path
        ``Schroeder80mV.mat``, ``SNLS80mV.mat`` or the ``.csv`` of either.
    period : int
        Samples a multisine period.

    Raises
    ------
    HosidInputError
        If the file is missing or unreadable, or holds no steady-state period.
    """
    path = Path(path)
    if not path.is_file():
        raise HosidInputError(f"{path}: no such file")
    u, y = _read(path)
    n = u.size - period
    if n <= MIN_LEAD or y.size != u.size:
        raise HosidInputError(f"{path}: V1 and V2 must be equally long and longer than a period")
    on = _active(u)
    scale = float(np.std(u[on]))
    same = (np.abs(u[:n] - u[period:]) < 0.05 * scale) & on[:n] & on[period:]
    edges = np.flatnonzero(np.diff(np.r_[0, same.astype(np.int8), 0]))
    starts: list[int] = []
    half = period // 2
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        if b - a < MIN_LEAD or b + period > u.size or (starts and b < starts[-1] + period):
            continue
        p = u[b : b + period] - np.mean(u[b : b + period])
        if np.dot(p[:half], p[half : 2 * half]) < 0.9 * np.dot(p, p) / 2:  # not a shorter period
            starts.append(int(b))
    if not starts:
        raise HosidInputError(f"{path}: no steady-state multisine period of {period} samples")
    record = Record.from_segments(
        [y[s : s + period] for s in starts], 1.0 / SILVERBOX_FS, name=path.stem
    )
    inputs = tuple(u[s : s + period].copy() for s in starts)
    return Silverbox(record, inputs, tuple(starts), period)
