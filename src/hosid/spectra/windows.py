r"""Data windows and their constants (paper eqs 20, 25-31, A6, App. B).

A window is a function :math:`D(t)` on a block :math:`0 \le t < T`.  The block spectra
use its periodic ("DFT-even") samples :math:`D_n = D(n\,\Delta t)`, taken from
:func:`scipy.signal.get_window`, so that the constants below are exact for the block
FFTs at the Fourier frequencies :math:`\omega_k = 2\pi k/T`:

.. math::

    k_2 = \frac{1}{T}\int_0^T D^2\,dt \quad (20), \qquad
    k_4 = \frac{1}{T}\int_0^T D^4\,dt \quad (A6),

.. math::

    \Delta_T(\omega) = \frac{1}{2\pi T}\left|\int_0^T D^2(t)\,e^{-i\omega t}\,dt\right|^2
    \quad (25), \qquad \int_{-\infty}^{\infty}\Delta_T(\omega)\,d\omega = k_4 \quad (31).

Boxcar: :math:`k_2 = k_4 = 1`, :math:`\Delta_T = \frac{T}{2\pi}\frac{\sin^2\pi\Omega}
{(\pi\Omega)^2}`, :math:`\Omega = \omega T/2\pi` (26-27).  Hann,
:math:`D = \tfrac12(1-\cos 2\pi t/T)` (28): :math:`k_2 = 3/8`, :math:`k_4 = 35/128`,
:math:`\Delta_T = \frac{T}{128\pi^3}(X^2+Y^2)` (29) with :math:`X, Y` of Appendix B.

On the Fourier bins the block statistics see the *discrete* window; its bin
correlation

.. math:: \rho(k) = \frac{1}{M k_2}\sum_{n=0}^{M-1} D_n^2\,e^{-2\pi i k n/M}

is real and even for a symmetric window, and :math:`\Delta_T(2\pi k/T) =
\frac{T}{2\pi}k_2^2\rho(k)^2` exactly (:meth:`Window.delta_bins`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import signal

__all__ = ["WINDOWS", "Window", "get_window", "hann_delta_xy"]

#: Window names accepted by :func:`get_window`.
WINDOWS = ("hann", "boxcar")


def _sinc_term(s: np.ndarray) -> np.ndarray:
    """sin(2 pi s)/s with its limit 2 pi at s = 0."""
    s = np.asarray(s, dtype=float)
    out = np.full_like(s, 2.0 * np.pi)
    nz = np.abs(s) > 1e-12
    out[nz] = np.sin(2.0 * np.pi * s[nz]) / s[nz]
    return out


def _cosc_term(s: np.ndarray) -> np.ndarray:
    """(1 - cos 2 pi s)/s with its limit 0 at s = 0."""
    s = np.asarray(s, dtype=float)
    out = np.zeros_like(s)
    nz = np.abs(s) > 1e-12
    out[nz] = (1.0 - np.cos(2.0 * np.pi * s[nz])) / s[nz]
    return out


def hann_delta_xy(Omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r"""Appendix B: :math:`X = \int_0^{2\pi}(1-\cos u)^2\cos\Omega u\,du` and its sine
    analogue :math:`Y` (eqs B1-B3; the exponent of A3/A4 misses its :math:`i`).
    """
    W = np.asarray(Omega, dtype=float)
    X = 1.5 * _sinc_term(W) - _sinc_term(W + 1) - _sinc_term(W - 1)
    X = X + 0.25 * (_sinc_term(W + 2) + _sinc_term(W - 2))
    Y = 1.5 * _cosc_term(W) - _cosc_term(W + 1) - _cosc_term(W - 1)
    Y = Y + 0.25 * (_cosc_term(W + 2) + _cosc_term(W - 2))
    return X, Y


@lru_cache(maxsize=32)
def _samples(name: str, m: int) -> np.ndarray:
    w = signal.get_window(name, m, fftbins=True)
    w.setflags(write=False)
    return w


@lru_cache(maxsize=32)
def _rho(name: str, m: int) -> np.ndarray:
    d2 = _samples(name, m) ** 2
    F = np.fft.fft(d2).real / (m * np.mean(d2))
    F.setflags(write=False)
    return F


@lru_cache(maxsize=32)
def _kernel(name: str, m: int, oversample: int, reach: int) -> tuple[np.ndarray, np.ndarray]:
    D = _samples(name, m)
    power = np.abs(np.fft.fft(D, m * oversample)) ** 2
    j = np.arange(-reach * oversample, reach * oversample + 1)
    weights = power[j % power.size]
    return j / oversample, weights / weights.sum()


@dataclass(frozen=True)
class Window:
    """A named data window (``"hann"`` or ``"boxcar"``)."""

    name: str

    def samples(self, m: int) -> np.ndarray:
        """The periodic window on ``m`` samples (:func:`scipy.signal.get_window`)."""
        return _samples(self.name, int(m))

    @property
    def k2(self) -> float:
        """Eq (20): mean of ``D^2`` (exact on any periodic grid of >= 5 samples)."""
        return float(np.mean(self.samples(64) ** 2))

    @property
    def k4(self) -> float:
        """Eq (A6): mean of ``D^4``."""
        return float(np.mean(self.samples(64) ** 4))

    def rho(self, k, m: int) -> np.ndarray:
        r"""Bin correlation :math:`\rho(k)` of the discrete window on ``m`` samples."""
        return _rho(self.name, int(m))[np.asarray(k) % m]

    def delta_bins(self, k, m: int, T: float) -> np.ndarray:
        r""":math:`\Delta_T` at integer bin offsets ``k`` as the block FFTs see it,
        :math:`\frac{T}{2\pi}k_2^2\rho(k)^2`.
        """
        return T / (2.0 * np.pi) * self.k2**2 * self.rho(k, m) ** 2

    def kernel(self, m: int, oversample: int = 8, reach: int = 8) -> tuple[np.ndarray, ...]:
        r"""The spectral window of a block periodogram: bin offsets :math:`\delta_j`
        (``reach`` bins either side, ``oversample`` points a bin) and weights
        :math:`K_j \propto |\sum_nD_ne^{-2\pi i\delta_jn/m}|^2` summing to 1, so that a
        process of spectrum :math:`S` has :math:`E[P_k] \approx \sum_jK_jS(\omega_k +
        \delta_j\Delta\omega)` (beyond 8 bins the Hann window leaves :math:`10^{-5}` of
        its power, the boxcar 2.5 %).
        """
        return _kernel(self.name, int(m), int(oversample), int(reach))

    def delta_T(self, omega: np.ndarray, T: float) -> np.ndarray:
        r"""Eq (25) for the continuous window: analytic for the boxcar (eq 26) and
        Hann (eq 29, App. B) windows.
        """
        Omega = np.asarray(omega, dtype=float) * T / (2.0 * np.pi)  # eq (27)
        if self.name == "boxcar":
            return T / (2.0 * np.pi) * np.sinc(Omega) ** 2  # eq (26)
        X, Y = hann_delta_xy(Omega)
        return T / (128.0 * np.pi**3) * (X**2 + Y**2)  # eq (29)


def get_window(window: str | Window) -> Window:
    """A :class:`Window` from its name (``"hann"`` or ``"boxcar"``) or itself.

    Raises
    ------
    ValueError
        For any other name.
    """
    if isinstance(window, Window):
        return window
    key = str(window).lower()
    if key in ("hann", "hanning"):
        return Window("hann")
    if key in ("boxcar", "rect", "rectangular"):
        return Window("boxcar")
    raise ValueError(f"unknown window {window!r}: use 'hann' or 'boxcar'")
