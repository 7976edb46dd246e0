r"""Blocks of a record and their windowed Fourier transforms (paper eqs 16-17, 46-48).

The record is cut into :math:`B` non-overlapping blocks of :math:`M` samples
(:math:`T = M\Delta t`), each inside one segment of the record (no block spans a gap;
the samples a segment holds beyond its last whole block are not used).  For a signal
:math:`y` the windowed finite Fourier transform of block :math:`r` (eq 46) is

.. math:: Y_r(\omega_k) = \Delta t\sum_{n=0}^{M-1} y_{rM+n}\,D_n\,e^{-2\pi i k n/M},
   \qquad \omega_k = 2\pi k/T,

and :math:`|Y_r|^2/(2\pi T k_2)` is a block periodogram whose mean over blocks
estimates the two-sided spectral density.

:func:`choose_layout` derives the block length from the record's response spectrum
(:mod:`hosid.spectra.response`): at least 16 periods of the equivalent natural frequency
:math:`\omega_n = \sigma_{\dot x}/\sigma_x` (the paper's 20.48 s for its oscillator)
and at least :data:`BINS_PER_BANDWIDTH` Fourier bins across the resonance's equivalent
bandwidth :math:`\Delta\omega` (:math:`T \ge 4\cdot2\pi/\Delta\omega`: a lightly
damped resonance needs blocks several decay times long), rounded to a power of two,
shortened to keep at least :data:`MIN_BLOCKS` blocks (or the ``target_blocks`` a
caller asks for: a system's many equations, :mod:`hosid.inference.system_estimate`) but
never below :data:`MIN_PERIODS` periods.

A segment that repeats itself (the steady-state response to a periodic input holding
more than one period, or one period of an *odd* multisine, :math:`u(t + P/2) = -u(t)`,
whose response to a symmetric system is antiperiodic) would give blocks that are copies
of each other, and the block statistics would count the same information twice:
:func:`distinct_bounds` finds the lag :math:`\tau` at which a segment's normalized
autocorrelation reaches :data:`REPEAT_CORRELATION` in absolute value (lags from an eighth
to seven eighths of the segment) and keeps blocks in its first :math:`\tau` samples.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import HosidInputError
from .windows import Window, get_window

__all__ = [
    "BINS_PER_BANDWIDTH",
    "MIN_BLOCKS",
    "MIN_PERIODS",
    "PERIODS",
    "REPEAT_CORRELATION",
    "BlockLayout",
    "block_fft",
    "block_means",
    "blocks_in",
    "choose_layout",
    "distinct_bounds",
    "inner_bounds",
    "repeat_lag",
    "windowed_fft",
]

#: Periods of the natural frequency in a default block (the paper's 20.48 s at 5 rad/s).
PERIODS = 16.0
#: Fewest periods a block may hold.
MIN_PERIODS = 4.0
#: Fewest blocks a fit needs (the covariance of the block statistics).
MIN_BLOCKS = 24
#: Fourier bins of a default block across the resonance's equivalent bandwidth.
BINS_PER_BANDWIDTH = 4.0
#: Absolute autocorrelation at which a segment is taken to repeat itself.
REPEAT_CORRELATION = 0.9


@dataclass(frozen=True)
class BlockLayout:
    """Blocks of ``M`` samples at ``dt``; ``B`` of them fit in the record.

    ``starts`` holds the first sample of every block when the blocks are not the
    first ``B * M`` samples one after the other (a record in segments).
    """

    M: int
    B: int
    dt: float
    starts: tuple[int, ...] | None = None

    @property
    def offsets(self) -> np.ndarray:
        """First sample of every block, ``(B,)``."""
        if self.starts is None:
            return np.arange(self.B) * self.M
        return np.asarray(self.starts, dtype=np.int64)

    def take(self, y: np.ndarray) -> np.ndarray:
        """The blocks of the last axis of ``y``: ``(..., n) -> (..., B, M)``."""
        y = np.asarray(y)
        if self.starts is None:
            return y[..., : self.n_used].reshape(*y.shape[:-1], self.B, self.M)
        return y[..., self.offsets[:, None] + np.arange(self.M)]

    @property
    def T(self) -> float:
        """Block length (s)."""
        return self.M * self.dt

    @property
    def d_omega(self) -> float:
        r"""Bin spacing :math:`2\pi/T` (rad/s)."""
        return 2.0 * math.pi / self.T

    @property
    def n_used(self) -> int:
        """Samples covered by the blocks."""
        return self.M * self.B

    def bins(self, omega_lo: float, omega_hi: float, k_min: int = 1) -> np.ndarray:
        """Fourier bins ``k >= k_min`` with ``omega_lo <= omega_k <= omega_hi``."""
        k = np.arange(k_min, self.M // 2)
        w = k * self.d_omega
        return k[(w >= omega_lo - 1e-12) & (w <= omega_hi + 1e-12)]

    def as_dict(self) -> dict:
        """Layout as plain numbers (for attrs and reports)."""
        return {"block_samples": self.M, "blocks": self.B, "block_seconds": self.T}


def blocks_in(bounds, M: int, dt: float) -> BlockLayout:
    """Blocks of ``M`` samples from the start of every segment ``(start, stop)``."""
    starts = [a + k * M for a, b in bounds for k in range((b - a) // M)]
    if len(bounds) == 1 and bounds[0][0] == 0:
        return BlockLayout(M=M, B=len(starts), dt=dt)
    return BlockLayout(M=M, B=len(starts), dt=dt, starts=tuple(starts))


def choose_layout(
    n: int,
    dt: float,
    omega_n: float,
    *,
    block_seconds: float | None = None,
    min_blocks: int = MIN_BLOCKS,
    bounds: Sequence[tuple[int, int]] | None = None,
    bandwidth: float | None = None,
    target_blocks: int | None = None,
) -> BlockLayout:
    """The block layout of a record of ``n`` samples (module docstring).

    Parameters
    ----------
    n, dt : int, float
        Samples and sampling interval.
    omega_n : float
        Equivalent natural frequency (rad/s).
    block_seconds : float, optional
        Use this block length instead.
    bounds : sequence of (start, stop), optional
        The record's segments (:attr:`hosid.record.Record.bounds`); default one.
    bandwidth : float, optional
        The resonance's equivalent bandwidth (rad/s), if known.
    target_blocks : int, optional
        Shorten the default blocks (by halves, never below :data:`MIN_PERIODS` periods)
        until the record holds this many.

    Raises
    ------
    HosidInputError
        If the record cannot hold ``min_blocks`` blocks of at least
        :data:`MIN_PERIODS` periods (or of the given length).
    """
    period = 2.0 * math.pi / omega_n
    bounds = [(0, n)] if bounds is None else [(int(a), int(b)) for a, b in bounds]
    where = "" if len(bounds) == 1 else f" in {len(bounds)} segments"
    if block_seconds is not None:
        M = round(block_seconds / dt)
        if M < 16:
            raise HosidInputError(
                f"blocks of {block_seconds:g} s hold only {M} samples at dt={dt:g}; "
                "use longer blocks"
            )
        layout = blocks_in(bounds, M, dt)
        if layout.B < min_blocks:
            raise HosidInputError(
                f"record of {n} samples ({n * dt:g} s{where}) is too short for {min_blocks} "
                f"blocks of {M} samples ({block_seconds:g} s)"
            )
        return layout
    target = PERIODS * period
    if bandwidth is not None and bandwidth > 0:
        target = max(target, BINS_PER_BANDWIDTH * 2.0 * math.pi / bandwidth)
    M = 2 ** round(math.log2(max(target / dt, 16.0)))
    while blocks_in(bounds, M, dt).B < min_blocks and M > 16:
        M //= 2
    while (
        target_blocks is not None
        and blocks_in(bounds, M, dt).B < target_blocks
        and M // 2 * dt >= MIN_PERIODS * period
    ):
        M //= 2
    layout = blocks_in(bounds, M, dt)
    if M * dt < MIN_PERIODS * period or layout.B < min_blocks:
        m_min = 2 ** math.ceil(math.log2(MIN_PERIODS * period / dt))
        raise HosidInputError(
            f"record of {n * dt:g} s{where} is too short for its {omega_n:.3g} rad/s "
            f"resonance: {min_blocks} blocks of at least {MIN_PERIODS:.0f} periods "
            f"({m_min} samples) need {min_blocks * m_min * dt:g} s"
        )
    return layout


def repeat_lag(y: np.ndarray, *, edge: float = 0.125) -> tuple[int, float]:
    r"""The first lag :math:`\tau` (samples, from ``edge`` to ``1 - edge`` of the length)
    at which the absolute normalized autocorrelation of ``y`` peaks above
    :data:`REPEAT_CORRELATION` (else the lag of its largest value), and its value,
    :math:`r(\tau) = \sum_iy_iy_{i+\tau}/(\sum_iy_i^2\sum_iy_{i+\tau}^2)^{1/2}` over the
    overlap (``y`` centred first).
    """
    y = np.asarray(y, dtype=float) - np.mean(y)
    n = y.size
    lags = np.arange(math.ceil(edge * n), math.floor((1.0 - edge) * n) + 1)
    if lags.size == 0 or n < 16:
        return 0, 0.0
    F = np.fft.rfft(y, 2 * n)
    c = np.fft.irfft(F.real**2 + F.imag**2, 2 * n)[lags]
    e = np.concatenate([[0.0], np.cumsum(y**2)])
    with np.errstate(invalid="ignore", divide="ignore"):
        r = c / np.sqrt(e[n - lags] * (e[n] - e[lags]))
    a = np.abs(np.nan_to_num(r))
    peaks = np.flatnonzero(
        (a >= REPEAT_CORRELATION) & (a >= np.r_[0.0, a[:-1]]) & (a >= np.r_[a[1:], 0.0])
    )
    k = int(peaks[0]) if peaks.size else int(np.argmax(a))  # the first copy, if any
    return int(lags[k]), float(r[k])


def distinct_bounds(
    x: np.ndarray, bounds: Sequence[tuple[int, int]], *, threshold: float = REPEAT_CORRELATION
) -> tuple[list[tuple[int, int]], list[tuple[int, float] | None]]:
    """Per segment, the samples that are not a copy of earlier ones (module docstring):
    ``(start, start + tau)`` where the segment repeats with lag ``tau``, else the segment,
    and the ``(tau, r)`` found (``None`` where it does not repeat).
    """
    out, found = [], []
    for a, b in bounds:
        lag, r = repeat_lag(x[a:b])
        if abs(r) >= threshold:
            out.append((a, a + lag))
            found.append((lag, r))
        else:
            out.append((a, b))
            found.append(None)
    return out, found


def inner_bounds(bounds: Sequence[tuple[int, int]], margin: int) -> list[tuple[int, int]]:
    """The segments ``bounds`` less ``margin`` samples at each end; a segment no longer
    than the two margins is left out (the caller decides what an empty list means).
    """
    return [(a + margin, b - margin) for a, b in bounds if b - a > 2 * margin]


def block_means(y: np.ndarray, layout: BlockLayout) -> np.ndarray:
    """Block means of the last axis: ``(..., n) -> (..., B)``."""
    return layout.take(np.asarray(y, dtype=float)).mean(axis=-1)


def block_fft(
    y: np.ndarray,
    layout: BlockLayout,
    window: str | Window = "hann",
    bins: np.ndarray | None = None,
) -> np.ndarray:
    r"""Windowed block transforms of the last axis, ``(..., n) -> (..., B, K)``.

    ``bins`` selects Fourier bins (default all ``M // 2 + 1``).
    """
    return windowed_fft(layout.take(np.asarray(y, dtype=float)), layout.dt, window, bins)


def windowed_fft(
    blocks: np.ndarray, dt: float, window: str | Window = "hann", bins: np.ndarray | None = None
) -> np.ndarray:
    """Eq (46) on blocks already cut, ``(..., B, M) -> (..., B, K)``."""
    win = get_window(window)
    Y = np.fft.rfft(blocks * win.samples(blocks.shape[-1]), axis=-1) * dt
    return Y if bins is None else Y[..., bins]
