r"""Blocks of a record and their windowed Fourier transforms (paper eqs 16-17, 46-48).

The record is cut into :math:`B` non-overlapping blocks of :math:`M` samples
(:math:`T = M\Delta t`), each inside one segment of the record (no block spans a gap;
the samples a segment holds beyond its last whole block are not used).  For a signal
:math:`y` the windowed finite Fourier transform of block :math:`r` (eq 46) is

.. math:: Y_r(\omega_k) = \Delta t\sum_{n=0}^{M-1} y_{rM+n}\,D_n\,e^{-2\pi i k n/M},
   \qquad \omega_k = 2\pi k/T,

and :math:`|Y_r|^2/(2\pi T k_2)` is a block periodogram whose mean over blocks
estimates the two-sided spectral density.

:func:`choose_layout` derives the block length from the record (the paper's 20.48 s
is 16 periods of its oscillator): about 16 periods of the equivalent natural frequency
:math:`\omega_n = \sigma_{\dot x}/\sigma_x`, rounded to a power of two, shortened to
keep at least :data:`MIN_BLOCKS` blocks but never below :data:`MIN_PERIODS` periods.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import HosidInputError
from .windows import Window, get_window

__all__ = [
    "MIN_BLOCKS",
    "MIN_PERIODS",
    "PERIODS",
    "BlockLayout",
    "block_fft",
    "block_means",
    "choose_layout",
    "windowed_fft",
]

#: Periods of the natural frequency in a default block (the paper's 20.48 s at 5 rad/s).
PERIODS = 16.0
#: Fewest periods a block may hold.
MIN_PERIODS = 4.0
#: Fewest blocks a fit needs (the covariance of the block statistics).
MIN_BLOCKS = 24


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


def _fit(bounds, M: int, dt: float) -> BlockLayout:
    """Blocks of ``M`` samples from the start of every segment ``(start, stop)``."""
    starts = [a + k * M for a, b in bounds for k in range((b - a) // M)]
    if len(bounds) == 1:
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
        layout = _fit(bounds, M, dt)
        if layout.B < min_blocks:
            raise HosidInputError(
                f"record of {n} samples ({n * dt:g} s{where}) is too short for {min_blocks} "
                f"blocks of {M} samples ({block_seconds:g} s)"
            )
        return layout
    M = 2 ** round(math.log2(max(PERIODS * period / dt, 16.0)))
    while _fit(bounds, M, dt).B < min_blocks and M > 16:
        M //= 2
    layout = _fit(bounds, M, dt)
    if M * dt < MIN_PERIODS * period or layout.B < min_blocks:
        m_min = 2 ** math.ceil(math.log2(MIN_PERIODS * period / dt))
        raise HosidInputError(
            f"record of {n * dt:g} s{where} is too short for its {omega_n:.3g} rad/s "
            f"resonance: {min_blocks} blocks of at least {MIN_PERIODS:.0f} periods "
            f"({m_min} samples) need {min_blocks * m_min * dt:g} s"
        )
    return layout


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
