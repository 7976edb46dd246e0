r"""Data windows and their constants (paper eqs 20, 25-31, A6, App. B).

A window is a function :math:`D(t)` on a block :math:`0 \le t < T`.  The block
spectra use the discrete, periodic ("DFT-even") form
:math:`D_n = D(n\,\Delta t)`, :math:`n = 0, \dots, M-1`, so that the window
constants below are exact for the block FFTs at the Fourier frequencies
:math:`\omega_k = 2\pi k / T`:

.. math::

    k_2 = \frac{1}{T}\int_0^T D^2\,dt \quad (20), \qquad
    k_4 = \frac{1}{T}\int_0^T D^4\,dt \quad (A6),

.. math::

    \Delta_T(\omega) = \frac{1}{2\pi T}\left|\int_0^T D^2(t)\,e^{-i\omega t}\,dt\right|^2
    \quad (25), \qquad \int_{-\infty}^{\infty}\Delta_T(\omega)\,d\omega = k_4 \quad (31).

Boxcar: :math:`k_2 = k_4 = 1`, :math:`\Delta_T = \frac{T}{2\pi}
\frac{\sin^2 \pi\Omega}{(\pi\Omega)^2}` with :math:`\Omega = \omega T/2\pi` (26-27).
Hann, :math:`D = \tfrac12(1-\cos 2\pi t/T)` (28): :math:`k_2 = 3/8`,
:math:`k_4 = 35/128`, :math:`\Delta_T = \frac{T}{128\pi^3}(X^2+Y^2)` (29) with
:math:`X, Y` of Appendix B.  Any other callable ``D(u)`` on :math:`u = t/T \in
[0, 1)` is integrated numerically.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["Window", "get_window", "hann_delta_xy"]


def _sinc_term(omega_shift: np.ndarray) -> np.ndarray:
    """sin(2 pi s)/s with its limit 2 pi at s = 0."""
    s = np.asarray(omega_shift, dtype=float)
    out = np.full_like(s, 2.0 * np.pi)
    nz = np.abs(s) > 1e-12
    out[nz] = np.sin(2.0 * np.pi * s[nz]) / s[nz]
    return out


def _cosc_term(omega_shift: np.ndarray) -> np.ndarray:
    """(1 - cos 2 pi s)/s with its limit 0 at s = 0."""
    s = np.asarray(omega_shift, dtype=float)
    out = np.zeros_like(s)
    nz = np.abs(s) > 1e-12
    out[nz] = (1.0 - np.cos(2.0 * np.pi * s[nz])) / s[nz]
    return out


def hann_delta_xy(Omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r"""Appendix B: :math:`X = \int_0^{2\pi}(1-\cos u)^2\cos\Omega u\,du` and the sine
    analogue :math:`Y` (eq B1-B3).
    """
    W = np.asarray(Omega, dtype=float)
    X = 1.5 * _sinc_term(W) - _sinc_term(W + 1) - _sinc_term(W - 1)
    X = X + 0.25 * (_sinc_term(W + 2) + _sinc_term(W - 2))
    Y = 1.5 * _cosc_term(W) - _cosc_term(W + 1) - _cosc_term(W - 1)
    Y = Y + 0.25 * (_cosc_term(W + 2) + _cosc_term(W - 2))
    return X, Y


@dataclass(frozen=True)
class Window:
    """A data window ``D(u)``, ``u = t / T`` in ``[0, 1)``.

    Attributes
    ----------
    name : str
        ``"boxcar"``, ``"hann"`` or a user label.
    func : callable
        Vectorized ``D(u)``.
    """

    name: str
    func: Callable[[np.ndarray], np.ndarray]

    def samples(self, m: int) -> np.ndarray:
        """The periodic window on ``m`` samples, ``D(n/m)``."""
        return np.asarray(self.func(np.arange(m) / m), dtype=float)

    @property
    def k2(self) -> float:
        """Eq (20): mean of ``D^2``."""
        if self.func is _boxcar:
            return 1.0
        if self.func is _hann:
            return 3.0 / 8.0
        return float(np.mean(self.samples(1 << 16) ** 2))

    @property
    def k4(self) -> float:
        """Eq (A6): mean of ``D^4``."""
        if self.func is _boxcar:
            return 1.0
        if self.func is _hann:
            return 35.0 / 128.0
        return float(np.mean(self.samples(1 << 16) ** 4))

    def delta_T(self, omega: np.ndarray, T: float) -> np.ndarray:
        r"""Eq (25): :math:`\Delta_T(\omega)` for block length ``T`` (seconds).

        Analytic for the boxcar (eq 26) and Hann (eq 29, App. B) windows;
        otherwise the integral is done by the trapezoidal rule on 4096 points.
        """
        omega = np.asarray(omega, dtype=float)
        Omega = omega * T / (2.0 * np.pi)  # eq (27)
        if self.func is _boxcar:
            return T / (2.0 * np.pi) * np.sinc(Omega) ** 2  # eq (26); np.sinc(x)=sin(pi x)/(pi x)
        if self.func is _hann:
            X, Y = hann_delta_xy(Omega)
            return T / (128.0 * np.pi**3) * (X**2 + Y**2)  # eq (29)
        u = np.linspace(0.0, 1.0, 4097)
        d2 = self.func(u) ** 2
        phase = np.exp(-2j * np.pi * np.multiply.outer(Omega, u))
        integral = T * np.trapezoid(d2 * phase, u, axis=-1)
        return np.abs(integral) ** 2 / (2.0 * np.pi * T)

    def delta_T_bins(self, k: np.ndarray, m: int, T: float) -> np.ndarray:
        r""":math:`\Delta_T` at integer bin offsets ``k`` (``omega = 2 pi k / T``),
        from the discrete window on ``m`` samples, exactly as the block FFTs see it:
        :math:`\frac{T}{2\pi}|\frac{1}{m}\sum_n D_n^2 e^{-2\pi i k n/m}|^2`.
        """
        d2 = self.samples(m) ** 2
        F = np.fft.fft(d2) / m
        return T / (2.0 * np.pi) * np.abs(F[np.asarray(k) % m]) ** 2


def _boxcar(u):
    return np.ones_like(np.asarray(u, dtype=float))


def _hann(u):
    return 0.5 * (1.0 - np.cos(2.0 * np.pi * np.asarray(u, dtype=float)))


def get_window(window: str | Window | Callable) -> Window:
    """Return a :class:`Window` from a name (``"boxcar"``, ``"hann"``), a
    :class:`Window` or a callable ``D(u)`` on ``u in [0, 1)``.
    """
    if isinstance(window, Window):
        return window
    if isinstance(window, str):
        key = window.lower()
        if key in ("boxcar", "rect", "rectangular"):
            return Window("boxcar", _boxcar)
        if key in ("hann", "hanning"):
            return Window("hann", _hann)
        raise ValueError(f"unknown window {window!r}: use 'hann', 'boxcar' or a callable")
    if callable(window):
        return Window(getattr(window, "__name__", "custom"), window)
    raise ValueError(f"unknown window {window!r}: use 'hann', 'boxcar' or a callable")
