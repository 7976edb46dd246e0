r"""Blocks of a record and their windowed Fourier transforms (paper eqs 16-17, 46-48).

The record is cut into :math:`B` non-overlapping blocks of :math:`M` samples
(:math:`T = M\Delta t`).  For a signal :math:`y` the windowed finite Fourier transform
of block :math:`r` (eq 46) is

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
]

#: Periods of the natural frequency in a default block (the paper's 20.48 s at 5 rad/s).
PERIODS = 16.0
#: Fewest periods a block may hold.
MIN_PERIODS = 4.0
#: Fewest blocks a fit needs (the covariance of the block statistics).
MIN_BLOCKS = 24


@dataclass(frozen=True)
class BlockLayout:
    """Blocks of ``M`` samples at ``dt``; ``B`` of them fit in the record."""

    M: int
    B: int
    dt: float

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


def choose_layout(
    n: int,
    dt: float,
    omega_n: float,
    *,
    block_seconds: float | None = None,
    min_blocks: int = MIN_BLOCKS,
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

    Raises
    ------
    HosidInputError
        If the record cannot hold ``min_blocks`` blocks of at least
        :data:`MIN_PERIODS` periods (or of the given length).
    """
    period = 2.0 * math.pi / omega_n
    if block_seconds is not None:
        M = round(block_seconds / dt)
        if M < 16:
            raise HosidInputError(
                f"blocks of {block_seconds:g} s hold only {M} samples at dt={dt:g}; "
                "use longer blocks"
            )
        if n // M < min_blocks:
            raise HosidInputError(
                f"record of {n} samples ({n * dt:g} s) is too short for {min_blocks} "
                f"blocks of {M} samples ({block_seconds:g} s)"
            )
        return BlockLayout(M=M, B=n // M, dt=dt)
    M = 2 ** round(math.log2(max(PERIODS * period / dt, 16.0)))
    while n // M < min_blocks and M > 16:
        M //= 2
    if M * dt < MIN_PERIODS * period or n // M < min_blocks:
        m_min = 2 ** math.ceil(math.log2(MIN_PERIODS * period / dt))
        raise HosidInputError(
            f"record of {n * dt:g} s is too short for its {omega_n:.3g} rad/s resonance: "
            f"{min_blocks} blocks of at least {MIN_PERIODS:.0f} periods ({m_min} samples) "
            f"need {min_blocks * m_min * dt:g} s"
        )
    return BlockLayout(M=M, B=n // M, dt=dt)


def block_means(y: np.ndarray, layout: BlockLayout) -> np.ndarray:
    """Block means of the last axis: ``(..., n) -> (..., B)``."""
    y = np.asarray(y, dtype=float)
    blocks = y[..., : layout.n_used].reshape(*y.shape[:-1], layout.B, layout.M)
    return blocks.mean(axis=-1)


def block_fft(
    y: np.ndarray,
    layout: BlockLayout,
    window: str | Window = "hann",
    bins: np.ndarray | None = None,
) -> np.ndarray:
    r"""Windowed block transforms of the last axis, ``(..., n) -> (..., B, K)``.

    ``bins`` selects Fourier bins (default all ``M // 2 + 1``).
    """
    win = get_window(window)
    y = np.asarray(y, dtype=float)
    blocks = y[..., : layout.n_used].reshape(*y.shape[:-1], layout.B, layout.M)
    Y = np.fft.rfft(blocks * win.samples(layout.M), axis=-1) * layout.dt
    return Y if bins is None else Y[..., bins]
