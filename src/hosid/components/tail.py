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

#: The model parameters the tail sees: a low-pass corner, a noise floor.  (Not a shaping
#: filter: under a force that falls as w^-4 the tail is the nonlinear response's harmonics,
#: not the equivalent linear response: its equations sat 5-6 sd off at the truth.)
TAIL_PARAMS = ("wc", "noise_sd")


@dataclass(frozen=True)
class Tail:
    r"""The spectral-tail component (module docstring): one equation for each
    coefficient :math:`c_k` (:math:`k \ge 1`) of the force's :math:`1/L` outside a
    band-limited force's own factor (``wc``: :math:`1/\omega_c^2`; a shaping filter:
    :math:`\omega^2` and :math:`\omega^4`), and one for ``noise_sd``.
    """

    name: str = "tail"

    def prepare(self, state: RecordState, model: Model, pilot: np.ndarray) -> Moments:
        """Block periodograms of the raw record's second difference and the frozen
        efficient-score weights.

        Raises
        ------
        ValueError
            If the model has none of :data:`TAIL_PARAMS`, or the band holds fewer
            than :data:`MIN_BINS` bins.
        """
        if not any(model.has(p) for p in TAIL_PARAMS):
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

        def coef(th):  # the free shape's 1/L coefficients c_1, c_2, ...
            return exc.spectrum.inverse_poly(th, exclude=("band_limited_excitation",))[1:]

        n_c = len(coef(th0))
        i_ns = model.index("noise_sd") if model.has("noise_sd") else None
        floor = dt / (2.0 * math.pi)

        def noise(th):
            if i_ns is None:
                return np.zeros(np.shape(th)[:-1])
            return floor * np.asarray(th, dtype=float)[..., i_ns] ** 2

        c0, N0 = [float(c) for c in coef(th0)], float(noise(th0))
        L0 = 1.0 / (1.0 + sum(c * W2 ** (k + 1) for k, c in enumerate(c0)))
        resp0 = np.sum(L0 * T, axis=1)  # (K,)
        Pbar = P.mean(axis=0)
        lam = max(float(exc.S0(th0)), 1e-300)
        for _ in range(4):  # the level's Whittle score at the pilot, by fixed point
            S_t = lam * resp0 + G * N0
            lam *= np.sum(Pbar * resp0 / S_t**2) / np.sum(lam * resp0**2 / S_t**2)
        S_t = lam * resp0 + G * N0
        dirs = [-lam * np.sum(W2 ** (k + 1) * L0**2 * T, axis=1) for k in range(n_c)]
        labels = ["tail eta"] if n_c == 1 else [f"tail c{k + 1}" for k in range(n_c)]
        if i_ns is not None:
            dirs.append(G)
            labels.append("tail noise")
        E = len(dirs)
        Q = np.stack(level_free(dirs, lam * resp0, S_t))  # (E, K)
        A = (Q[:, :, None] * T[None]).reshape(E, -1)  # the response, per alias
        bvec = Q @ G  # the noise floor
        W2f = W2.ravel()
        const = Q @ Pbar

        def mean(theta):
            th = np.asarray(theta, dtype=float)
            shape = th.shape[:-1]
            cs = [np.asarray(c, dtype=float).reshape(-1) for c in coef(th)]
            n = int(np.prod(shape, dtype=int))
            out = np.empty((n, E))
            for s0 in range(0, n, 256):  # chunks bound the memory
                den = np.ones((min(256, n - s0), W2f.size))
                for k, c in enumerate(cs):
                    den = den + c[s0 : s0 + 256, None] * W2f[None, :] ** (k + 1)
                out[s0 : s0 + 256] = (1.0 / den) @ A.T
            resp = out.reshape(*shape, E)
            return const - lam * resp - noise(th)[..., None] * bvec

        per_block = (P - S_t) @ Q.T  # (B, E)
        return Moments(
            component=self.name,
            labels=tuple(labels),
            mean=mean,
            influence=per_block - per_block.mean(axis=0),
            info={
                "tail_rad_s": [float(omega[0]), float(omega[-1])],
                "bins": int(omega.size),
                "level_ratio": lam / max(float(exc.S0(th0)), 1e-300),
            },
        )


def _band_factor(exc: Excitation, W: np.ndarray, th0: np.ndarray) -> np.ndarray:
    """The band-limited force's in-band shape at the pilot (its roll-off, not the
    corner's), for the frequencies ``W``.
    """
    wb = float(th0[exc.i_wb])
    beta = float(th0[exc.i_rb]) if exc.i_rb is not None else 0.0
    return (np.abs(W) <= wb) / (1.0 + beta * W**2 / wb**2)
