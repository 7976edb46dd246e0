r"""The spectral tail: what a coloured force and measurement noise leave in the record.

Far above resonance the response follows its force, :math:`\ddot x \approx g`, and the
sampled spectrum of the measured displacement :math:`y_n = x(n\Delta t) + \epsilon_n` is

.. math:: S_y(\omega) = \lambda\sum_j L(\omega_j)\,T(\omega_j)
    + N, \qquad \omega_j = \omega + 2j\omega_N, \qquad
    N = \frac{\sigma_\epsilon^2\Delta t}{2\pi},

the response's tail folded into the band by the sampling (:math:`|j| \le` 10), with
:math:`T = 1/[(k - \omega^2)^2 + c^2\omega^2]` of the equivalent linear system at the
pilot (:class:`hosid.components.excitation.Excitation`), the force's shape
:math:`L = 1/(1 + \eta\omega^2)`, :math:`\eta = 1/\omega_c^2` (``coloured_excitation``;
1 for white noise) and the noise floor :math:`N` (``measurement_noise``).  Both
effects are regular at their null in :math:`\eta` and :math:`N` and both show at the
top of the band: the log-derivatives are :math:`-\omega^2` and :math:`N/S_y \propto
\omega^4`, so their Whittle information (:func:`hosid.model.information.spectral_bound`)
lies mostly above :math:`\omega_N/2`.

**Data.**  The block periodograms :math:`P_{bk}` of the raw record's second difference
(:mod:`hosid.spectra.tail`: flat in the tail, no taper) on the bins
:math:`4\omega_n \le \omega_k < \omega_N` (below :math:`0.9\,\omega_b` for a
band-limited force).

**Equations** (the Whittle scores of :math:`\eta` and :math:`N` with the level
:math:`\lambda` profiled out).  With :math:`\tilde S_k` the spectrum at the pilot, the
level :math:`\lambda` fitted there by its own Whittle score, and :math:`w_\psi =
\partial S_d/\partial\psi` for :math:`\psi \in \{\eta, N\}`, the direction
:math:`w^\perp_\psi = w_\psi - \beta_\psi w_\lambda` is orthogonal to the level's
(:math:`\langle w^\perp_\psi, w_\lambda\rangle = \sum_kw^\perp w_\lambda/\tilde S_k^2 =
0`), and

.. math:: \bar m_\psi(\theta) = \sum_k\frac{w^\perp_{\psi,k}}{\tilde S_k^2}
    \big(\bar P_k - S_{d,k}(\theta)\big)

is the efficient score of :math:`\psi` given the level: a level the fit gets slightly
wrong (the tail of a nonlinear oscillator is not exactly its equivalent linear one) does
not move it to first order.  Per block the same sum over :math:`P_{bk}` gives the
influence.  The equations depend on :math:`\theta` through :math:`\omega_c` and
:math:`\sigma_\epsilon` only.  The equivalent linear tail shape leaves a bias in the
score on strongly nonlinear records (0.1-0.8 sd on simulated regimes at
:math:`4\omega_n`); ``hosid diagnose`` compares the record with replicates of the same
model, which share it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.model import Model
from ..spectra.tail import (
    LOW,
    MIN_BINS,
    difference_gain,
    difference_periodogram,
    folded_tail,
    level_free,
    tail_bins,
)
from ..state import RecordState
from .base import Moments
from .excitation import Excitation

__all__ = ["LOW", "TAIL_PARAMS", "Tail"]

#: The model parameters the tail sees, with the label of their equation.
TAIL_PARAMS = {"wc": "tail eta", "noise_sd": "tail noise"}


@dataclass(frozen=True)
class Tail:
    """The spectral-tail component (module docstring): one equation for each of
    ``wc`` and ``noise_sd`` the model has.
    """

    name: str = "tail"

    def prepare(self, state: RecordState, model: Model, pilot: np.ndarray) -> Moments:
        """Block periodograms of the raw record's second difference and the frozen
        efficient-score weights.

        Raises
        ------
        ValueError
            If the model has neither ``wc`` nor ``noise_sd``, or the band holds fewer
            than :data:`MIN_BINS` bins.
        """
        params = [p for p in TAIL_PARAMS if model.has(p)]
        if not params:
            raise ValueError("the tail component needs wc or noise_sd in the model")
        th0 = np.asarray(pilot, dtype=float)
        s, dt = state.scales, state.dt
        exc = Excitation(model, th0, s.sigma_v, s.sigma_x)
        hi = math.pi / dt
        if model.has("wb"):
            hi = min(hi, 0.9 * float(th0[model.index("wb")]))
        sel, omega = tail_bins(state.layout.M - 2, dt, LOW * s.omega_n, hi)
        if omega.size < MIN_BINS:
            raise ValueError(
                f"the spectral tail [{LOW:g} w_n, {hi:.3g} rad/s] holds fewer than "
                f"{MIN_BINS} bins: the sampling is too coarse for the tail"
            )
        P = difference_periodogram(state.layout.take(state.record.x - state.offset), dt, sel)
        W2, T = folded_tail(omega, dt, *exc.linear)
        if model.has("wb"):  # the band's roll-off at the pilot, held
            T = T * _band_factor(exc, np.sqrt(W2), th0)
        G = difference_gain(omega, dt)  # the floor's direction

        i_wc = model.index("wc") if model.has("wc") else None
        i_ns = model.index("noise_sd") if model.has("noise_sd") else None
        floor = dt / (2.0 * math.pi)

        def eta(th):
            if i_wc is None:
                return np.zeros(np.shape(th)[:-1])
            return np.asarray(th, dtype=float)[..., i_wc] ** -2.0

        def noise(th):
            if i_ns is None:
                return np.zeros(np.shape(th)[:-1])
            return floor * np.asarray(th, dtype=float)[..., i_ns] ** 2

        e0, N0 = float(eta(th0)), float(noise(th0))
        L0 = 1.0 / (1.0 + e0 * W2)
        resp0 = np.sum(L0 * T, axis=1)  # (K,)
        Pbar = P.mean(axis=0)
        lam = max(float(exc.S0(th0)), 1e-300)
        for _ in range(4):  # the level's Whittle score at the pilot, by fixed point
            S_t = lam * resp0 + G * N0
            lam *= np.sum(Pbar * resp0 / S_t**2) / np.sum(lam * resp0**2 / S_t**2)
        S_t = lam * resp0 + G * N0
        dirs = {"wc": -lam * np.sum(W2 * L0**2 * T, axis=1), "noise_sd": G}
        Q = np.stack(level_free([dirs[p] for p in params], lam * resp0, S_t))  # (E, K)
        A = (Q[:, :, None] * T[None]).reshape(len(params), -1)  # the response, per alias
        bvec = Q @ G  # the noise floor
        W2f = W2.ravel()
        const = Q @ Pbar

        def mean(theta):
            th = np.asarray(theta, dtype=float)
            et = eta(th)
            flat = et.reshape(-1)
            out = np.empty((flat.size, len(params)))
            for s0 in range(0, flat.size, 256):  # chunks bound the memory
                Lc = 1.0 / (1.0 + flat[s0 : s0 + 256, None] * W2f[None, :])
                out[s0 : s0 + 256] = Lc @ A.T
            resp = out.reshape(*et.shape, len(params))
            return const - lam * resp - noise(th)[..., None] * bvec

        per_block = (P - S_t) @ Q.T  # (B, E)
        return Moments(
            component=self.name,
            labels=tuple(TAIL_PARAMS[p] for p in params),
            mean=mean,
            influence=per_block - per_block.mean(axis=0),
            info={
                "tail_rad_s": [float(omega[0]), float(omega[-1])],
                "bins": int(omega.size),
                "level_ratio": lam / max(float(exc.S0(th0)), 1e-300),
            },
        )


def _band_factor(exc: Excitation, W: np.ndarray, th0: np.ndarray) -> np.ndarray:
    """The band-limited force's in-band shape at the pilot (its low-pass factors but
    the corner's), for the frequencies ``W``.
    """
    out = np.ones_like(W)
    for i, a in exc.inverse_factors():
        if i != exc.i_wc:
            out = out / (1.0 + W**2 * float(a(th0)))
    return out * (np.abs(W) <= float(th0[exc.i_wb]))
