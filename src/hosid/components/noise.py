r"""The noise floor of the measured displacement (``measurement_noise``).

With :math:`y_n = x_n + \epsilon_n`, the spectrum of the record far above resonance is
the response's tail plus the flat floor of the noise,

.. math:: S_y(\omega) = S_0\sum_jL(\omega_j)|H(\omega_j)|^2
    + \frac{\sigma_\epsilon^2\Delta t}{2\pi}, \qquad \omega_j = \omega + 2j\omega_N,

(the sum folds the response's tail into the band; :math:`H` is the equivalent linear
system at the pilot).  On the tail bins :math:`\omega_k \in [4\omega_n, 0.9\,\omega_N]`
of the *raw* record the standardized block periodogram :math:`h_{rk} = P_{rk}/S_y(\omega_k)
- 1` gives one estimating equation for :math:`\sigma_\epsilon`, built as J2's
(:mod:`hosid.components.spectral`): frozen weights
:math:`w = \partial h/\partial\sigma_\epsilon`, block-diagonal pairs removed.  The rest of
the fit sees the Wiener-filtered record (:func:`hosid.state.noise_floor`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.model import Model
from ..state import RecordState
from .base import Moments
from .excitation import Excitation

__all__ = ["NoiseFloor"]


@dataclass(frozen=True)
class NoiseFloor:
    """The noise-floor component (module docstring)."""

    name: str = "noise"

    def prepare(self, state: RecordState, model: Model, pilot: np.ndarray) -> Moments:
        """Tail periodograms of the raw record and frozen weights."""
        i = model.index("noise_sd")
        L, s = state.layout, state.scales
        bins = L.bins(4.0 * s.omega_n, 0.9 * s.omega_nyquist, k_min=2)
        if bins.size < 3:
            raise ValueError("measurement_noise needs a spectral tail: the sampling is too coarse")
        omega = bins * L.d_omega
        raw = state.record.x - state.offset
        Y = state.block_fft(("raw x",), lambda b: L.take(raw), bins)
        P = (Y.real**2 + Y.imag**2) / (2 * math.pi * L.T * state.window.k2)  # (B, K)
        exc = Excitation(model, pilot, s.sigma_v, s.sigma_x)
        c, k = exc.linear
        wN = s.omega_nyquist
        alias = omega[:, None] + 2.0 * wN * np.arange(-20, 21)  # (K, J)
        H2 = 1.0 / ((k - alias**2) ** 2 + (c * alias) ** 2)
        floor = state.dt / (2 * math.pi)
        th0 = np.asarray(pilot, dtype=float)
        sd0 = max(float(th0[i]), 0.05 * (state.noise or {}).get("sd", 0.0), 1e-6 * s.sigma_x)

        def level(th):
            th = np.asarray(th, dtype=float)
            resp = exc.S0(th)[..., None] * np.sum(exc.shape(alias, th) * H2, axis=-1)
            return resp + floor * th[..., i, None] ** 2

        th_w = th0.copy()
        th_w[i] = sd0
        M0 = level(th_w)
        w = -P / M0**2 * 2.0 * sd0 * floor  # d h / d sd at the pilot, (B, K)
        B, K = P.shape
        wbar, Pbar = w.mean(axis=0), P.mean(axis=0)
        num = wbar * Pbar - (w * P).mean(axis=0) / B
        cst = np.sum(wbar - w.mean(axis=0) / B)
        scale = B / ((B - 1) * K)

        def mean(theta):
            return scale * (np.sum(num / level(theta), axis=-1) - cst)[..., None]

        h0 = P / level(th0) - 1.0
        u = h0 @ wbar / K
        return Moments(
            component=self.name,
            labels=("noise d/dnoise_sd",),
            mean=mean,
            influence=(u - u.mean())[:, None],
            info={"tail_rad_s": [float(omega[0]), float(omega[-1])], "bins": int(K)},
        )
