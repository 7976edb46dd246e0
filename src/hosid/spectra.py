r"""Features, block spectra and trispectral domains (paper eqs 16-17, 22, 39, 45-48, 57-58, 64).

The record is cut into :math:`N` non-overlapping blocks of :math:`M` samples
(:math:`T = M\,\Delta t`).  For each block :math:`r` and each feature
:math:`y_0 = \ddot x, y_1 = \dot x, y_2 = \dot x|\dot x|, y_3 = x, y_4 = x^3`
the windowed finite Fourier transform (eq 46)

.. math::

    Y_{jr}(\omega_k) = \int_0^T y_{jr}(t)\,D(t)\,e^{-i\omega_k t}\,dt
    \approx \Delta t\sum_{n=0}^{M-1} y_{jr}(t_n) D_n e^{-2\pi i k n/M}

is taken at the Fourier frequencies :math:`\omega_k = 2\pi k/T`.  The inferred
force of block :math:`r` is :math:`X_r(\omega;\lambda) = \sum_j \lambda_j
Y_{jr}(\omega)` with :math:`\lambda = (1, a_1, n_1, a_2, n_2)` (eq 45).

Velocity and acceleration are reconstructed by spectral differentiation of the
whole record (after removing the straight line through its end points so that
the periodic extension is continuous); see :func:`derivatives`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .errors import HosidInputError
from .records import Record
from .windows import Window, get_window

__all__ = [
    "BlockSpectra",
    "TrispectralDomain",
    "block_spectra",
    "derivatives",
    "features",
    "trispectral_domain",
]

FEATURE_NAMES = ("x''", "x'", "x'|x'|", "x", "x^3")


def derivatives(
    x: np.ndarray, dt: float, method: str = "spectral", detrend: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    r"""Velocity and acceleration of a uniformly sampled record.

    ``"spectral"``: multiply the FFT by :math:`i\omega` (and :math:`-\omega^2`)
    below the Nyquist frequency.  A measured record is not periodic, so by default
    (``detrend=True``) the line through its end points is removed first and its
    slope added back; this keeps the end jump from ringing through the record and
    leaves errors only near the two ends.  With ``detrend=False`` the derivative is
    exact for band-limited periodic signals.  On a simulated
    white-noise-driven oscillator at ``dt = 0.02`` it leaves :math:`E[\dot x^2]`
    within about 3 % (the velocity power above Nyquist is lost).
    ``"central"``: second-order central differences (biased by about -12 % at
    ``dt = 0.02``; kept for comparison with the paper).
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    if method == "central":
        v = np.gradient(x, dt)
        a = np.empty_like(x)
        a[1:-1] = (x[2:] - 2 * x[1:-1] + x[:-2]) / dt**2
        a[0], a[-1] = a[1], a[-2]
        return v, a
    if method != "spectral":
        raise ValueError(f"unknown derivative method {method!r}")
    slope = (x[-1] - x[0]) / ((n - 1) * dt) if detrend else 0.0
    ramp = x[0] + slope * dt * np.arange(n) if detrend else 0.0
    r = x - ramp
    F = np.fft.rfft(r)
    w = 2.0 * np.pi * np.fft.rfftfreq(n, dt)
    if n % 2 == 0:
        F[-1] = 0.0  # Nyquist bin has no well-defined derivative
    v = np.fft.irfft(1j * w * F, n) + slope
    a = np.fft.irfft(-(w**2) * F, n)
    return v, a


def features(record: Record, derivative: str = "spectral") -> np.ndarray:
    """The five features of eq (45), shape ``(5, n)``: x'', x', x'|x'|, x, x^3."""
    x = record.x - 0.0
    v, a = derivatives(x, record.dt, derivative)
    return np.stack([a, v, v * np.abs(v), x, x**3])


@dataclass(frozen=True)
class BlockSpectra:
    r"""Block Fourier transforms of the features.

    Attributes
    ----------
    Y : ndarray, complex, shape (5, N, K)
        :math:`Y_{jr}(\omega_k)` for ``k = 0 .. K-1``.
    T, dt : float
        Block length and sampling interval (s).
    M : int
        Samples per block.
    window : Window
    k_max : int
        Highest bin used by the costs (:math:`\omega_{k_{max}} \le \omega_{max}`).
    k_min : int
        Lowest bin used (default 1: the zero frequency is left out).
    """

    Y: np.ndarray
    T: float
    dt: float
    M: int
    window: Window
    k_max: int
    k_min: int = 1

    @property
    def n_blocks(self) -> int:
        """Number of blocks N."""
        return self.Y.shape[1]

    @property
    def d_omega(self) -> float:
        """Bin spacing 2 pi / T (rad/s)."""
        return 2.0 * np.pi / self.T

    @property
    def band(self) -> np.ndarray:
        """Bins ``k_min .. k_max`` used by the second-order costs."""
        return np.arange(self.k_min, self.k_max + 1)

    @property
    def omega(self) -> np.ndarray:
        """Frequencies (rad/s) of the band."""
        return self.band * self.d_omega

    @cached_property
    def cross_spectra(self) -> np.ndarray:
        r"""Eq (48)/(52): :math:`\hat U_{jk}(\omega) = \overline{Y_j Y_k^*}/(2\pi T)`,
        shape ``(5, 5, K_band)``; estimates :math:`k_2 S_{jk}(\omega)`.
        """
        Yb = self.Y[:, :, self.band]
        return np.einsum("irk,jrk->ijk", Yb, Yb.conj()) / (self.n_blocks * 2 * np.pi * self.T)


def block_spectra(
    record: Record,
    *,
    window: str | Window = "hann",
    block_seconds: float = 20.48,
    omega_max: float = 8.0,
    omega_min: float | None = None,
    derivative: str = "spectral",
    k_store: int | None = None,
    min_blocks: int = 8,
) -> BlockSpectra:
    r"""Cut the record into blocks and take the windowed FFT of every feature.

    Bins up to ``3 * k_max`` are stored so that :math:`\\omega_1+\\omega_2+\\omega_3`
    is available on any trispectral domain.
    """
    win = get_window(window)
    M, T, k_min, k_max = block_layout(
        record.n,
        record.dt,
        block_seconds=block_seconds,
        omega_max=omega_max,
        omega_min=omega_min,
        min_blocks=min_blocks,
    )
    F = features(record, derivative)
    K = min(M // 2 + 1, k_store or 3 * k_max + 1)
    Y = block_fft(F, M, record.dt, win, K)
    return BlockSpectra(Y=Y, T=T, dt=record.dt, M=M, window=win, k_max=k_max, k_min=k_min)


def block_fft(
    F: np.ndarray, M: int, dt: float, window: str | Window = "hann", K: int | None = None
) -> np.ndarray:
    r"""Windowed block transforms :math:`Y_r(\omega_k) = \Delta t\sum_n D_n F_{rn}
    e^{-2\pi i kn/M}` of the last axis: ``(..., n) -> (..., n // M, K)``.

    ``K`` bins are kept (default ``M // 2 + 1``); samples past the last whole block
    are dropped.
    """
    win = get_window(window)
    F = np.asarray(F, dtype=float)
    N = F.shape[-1] // M
    blocks = F[..., : N * M].reshape(*F.shape[:-1], N, M) * win.samples(M)
    Y = np.fft.rfft(blocks, axis=-1) * dt
    return Y if K is None else Y[..., :K]


def block_periodogram(y: np.ndarray, M: int, dt: float, window: str | Window = "hann"):
    r"""Per-block two-sided periodogram :math:`|Y_r(\omega_k)|^2/(2\pi T k_2)`,
    shape ``(n // M, M // 2 + 1)``; its block mean estimates the two-sided spectrum.
    """
    win = get_window(window)
    Y = block_fft(y, M, dt, win)
    return (Y.real**2 + Y.imag**2) / (2.0 * np.pi * M * dt * win.k2)


def block_layout(
    n: int,
    dt: float,
    *,
    block_seconds: float,
    omega_max: float,
    omega_min: float | None = None,
    min_blocks: int = 8,
) -> tuple[int, float, int, int]:
    """Block size and band for ``n`` samples at ``dt``: ``(M, T, k_min, k_max)``.

    Raises
    ------
    HosidInputError
        If a block holds fewer than 16 samples, the record fewer than ``min_blocks``
        blocks, the band fewer than 3 bins, or ``omega_max`` is at or above the Nyquist
        frequency or below ``omega_min``.
    """
    M = round(block_seconds / dt)
    if M < 16:
        raise HosidInputError(
            f"blocks of {block_seconds} s hold only {M} samples; use longer blocks"
        )
    N = n // M
    if N < min_blocks:
        raise HosidInputError(
            f"record of {n} samples ({n * dt:g} s) is too short for "
            f"{min_blocks} blocks of {M} samples ({block_seconds:g} s)"
        )
    T = M * dt
    k_max = int(np.floor(omega_max * T / (2 * np.pi) + 1e-9))
    if k_max < 3:
        raise HosidInputError(f"omega_max = {omega_max} rad/s leaves fewer than 3 frequency bins")
    if k_max >= M // 2:
        raise HosidInputError(f"omega_max = {omega_max} rad/s is above the Nyquist frequency")
    k_min = 1 if omega_min is None else max(1, int(np.ceil(omega_min * T / (2 * np.pi) - 1e-9)))
    if k_min > k_max:
        raise HosidInputError(
            f"omega_min = {omega_min} rad/s is above omega_max = {omega_max} rad/s"
        )
    return M, T, k_min, k_max


@dataclass(frozen=True)
class TrispectralDomain:
    r"""Integer bin triples :math:`(k_1, k_2, k_3)` and :math:`k_4 = k_1+k_2+k_3`.

    ``gauss`` holds :math:`\Delta_T(\omega_1+\omega_2) + \Delta_T(\omega_1+\omega_3)
    + \Delta_T(\omega_2+\omega_3)` (the window factor of eq 59) and ``pairs`` the
    three pair sums, for the Gaussian terms of eqs 59 and 63.
    """

    k: np.ndarray  # (n, 4) ints, k4 = k1 + k2 + k3
    kind: str
    delta: np.ndarray  # (n, 3): Delta_T(w1+w2), Delta_T(w1+w3), Delta_T(w2+w3)

    @property
    def size(self) -> int:
        """Number of triples."""
        return self.k.shape[0]

    @property
    def gauss(self) -> np.ndarray:
        """Sum of the three Delta_T factors (eq 59)."""
        return self.delta.sum(axis=1)


def trispectral_domain(spectra: BlockSpectra, kind: str = "principal") -> TrispectralDomain:
    r"""Frequency triples for the fourth-order costs.

    ``"principal"``: eq (39) — :math:`\\omega_1\\ge\\omega_2\\ge\\omega_3`,
    :math:`\\omega_1+\\omega_2+\\omega_3\\ge 0`, :math:`\\omega_1+\\omega_2+2\\omega_3\\ge 0`,
    exactly one negative frequency.
    ``"reduced"``: the principal domain intersected with eq (64), read as the
    union :math:`|\\omega_i+\\omega_j| \\le \\Delta\\omega` for some pair.
    ``"full"``: every triple with all four :math:`|\\omega| \\le \\omega_{max}`.
    All four frequencies lie in ``k_min .. k_max`` in absolute value.
    """
    lo, hi = spectra.k_min, spectra.k_max
    r = np.arange(-hi, hi + 1)
    r = r[np.abs(r) >= lo]
    k1, k2, k3 = (a.ravel() for a in np.meshgrid(r, r, r, indexing="ij"))
    k4 = k1 + k2 + k3
    ok = (np.abs(k4) >= lo) & (np.abs(k4) <= hi)
    if kind in ("principal", "reduced"):
        neg = (k1 < 0).astype(int) + (k2 < 0) + (k3 < 0)
        ok &= (k1 >= k2) & (k2 >= k3) & (k4 >= 0) & (k1 + k2 + 2 * k3 >= 0) & (neg == 1)
        if kind == "reduced":
            near = (np.abs(k1 + k2) <= 1) | (np.abs(k1 + k3) <= 1) | (np.abs(k2 + k3) <= 1)
            ok &= near
    elif kind != "full":
        raise ValueError(f"unknown trispectral domain {kind!r}: principal, reduced or full")
    k = np.stack([k1[ok], k2[ok], k3[ok], k4[ok]], axis=1)
    sums = np.stack([k[:, 0] + k[:, 1], k[:, 0] + k[:, 2], k[:, 1] + k[:, 2]], axis=1)
    delta = spectra.window.delta_T(sums * spectra.d_omega, spectra.T)
    return TrispectralDomain(k=k, kind=kind, delta=delta)
