r"""J2: the second-order spectrum of the inferred force (paper eqs 21, 47-50).

With :math:`\lambda = (1, \theta_{drift})` and the block transforms :math:`Y_{jr}` of
:math:`\ddot x` and the drift features (:func:`hosid.components.base.feature_ffts`),
the inferred force of block :math:`r` is :math:`X_r(\omega) = \sum_j\lambda_jY_{jr}`
(eq 45) and, on the band's bins :math:`\omega_k`, its standardized periodogram

.. math:: h_{rk}(\theta) = \frac{|X_r(\omega_k)|^2}{2\pi T k_2 S_0 \bar L(\omega_k)} - 1

has expectation 0 under the model (eq 21: :math:`\hat V^a = k_2S_0` for white noise,
:math:`L = 1`) and unit variance.  :math:`\bar L(\omega_k) = \sum_jK_jL(\omega_k +
\delta_j\Delta\omega)` is the force's shape as a block periodogram sees it, smoothed by
the window's spectral kernel (:meth:`hosid.spectra.windows.Window.kernel`): a shaping
filter as narrow as a bin (a ship-roll-like oscillator under a filter at its resonance,
:math:`2\zeta_f\omega_f = \Delta\omega`) left the standardized periodogram at the true
parameters -0.38 at the peak and +0.4 to +0.7 beside it (4 records, 5-9 standard errors)
against the sharp :math:`L`.  The well-scaled J2 of the paper's least squares is
:math:`J_2^W = B\sum_k\bar h_k^2`; its gradient, with the weights
:math:`w_{kj} = \partial\bar h_k/\partial\theta_j` frozen at a pilot
:math:`\tilde\theta`, gives one estimating equation per parameter the spectrum sees
(drift coefficients, :math:`S_0`, :math:`\omega_c`):

.. math:: m_j(\theta) = \frac{1}{K}\sum_k w_{kj}\,\bar h_k(\theta).

Weights and residuals from the same blocks are correlated, which would bias
:math:`m_j` at the truth by about one standard error; the block-diagonal pairs are
therefore removed (a U-statistic over block pairs :math:`r \ne r'`), and its
covariance comes from the delete-one-block jackknife
(:func:`hosid.components.base.u_pseudovalues`).  ``form="printed"`` weights the
ordinates as eq (50) does, :math:`(\hat V^a - k_2S_0)^2`, i.e. by :math:`(S_0L)^2`.

In the default fit (``with_level``), where the force is white and the level above the
band is seen (:class:`hosid.components.level.Level`), J2 keeps only its level equation
(the in-band level, which Hansen's test then holds against the level above the band and
the energy balance): its drift equations repeat the generator identities' information,
and with tens of blocks their estimated weights cost more than they add.  On 40
ship-roll-like records, the default with J2's drift equations and the level gave
:math:`a_{1eq}` an efficiency of 0.59 (biased by +0.55 bound-sd), without them 0.87;
the paper oscillator (S0 = 100) 0.58 and 0.62.  Every shaped force keeps all of J2's
equations (its shape parameters need them).

The default band runs from bin 2 (the Hann window leaks a mean force into bins 0 and 1)
to :math:`\min(6\,\omega_n, \omega_N/2)`, kept below where the record's response
spectrum says the model stops holding (:mod:`hosid.spectra.response`): below 0.9 of the
excitation's edge, and below half the frequency where the response falls into the noise
floor (where the floor's acceleration is a sixteenth of the force level).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.model import Model
from ..state import RecordState
from .base import Moments, feature_ffts, restoration, u_pseudovalues
from .excitation import Excitation

__all__ = ["J2", "default_band", "force_periodogram"]

#: Default upper edge of the J2 band, in units of the natural frequency.
BAND_FACTOR = 6.0


def default_band(state: RecordState) -> tuple[float, float]:
    r"""``(omega_lo, omega_hi)`` of the J2 band (module docstring), rad/s; below the
    Wiener filter (:math:`3\omega_n`) when the record was denoised.
    """
    s, sp = state.scales, state.spectrum
    factor = 3.0 if state.noise is not None else BAND_FACTOR
    hi = min(factor * s.omega_n, 0.5 * s.omega_nyquist, 0.5 * sp.floor_edge)
    if sp.edge is not None:
        hi = min(hi, 0.9 * sp.edge[0])
    return 0.0, hi


@dataclass(frozen=True)
class J2:
    r"""The second-order spectral component (module docstring).

    ``band``: ``(omega_lo, omega_hi)`` in rad/s (default :func:`default_band`);
    ``form``: ``"scaled"`` or ``"printed"``.
    """

    band: tuple[float, float] | None = None
    form: str = "scaled"
    name: str = "J2"
    #: in the default set beside :class:`hosid.components.level.Level`: on the default
    #: band, stand aside where the level's equation holds (module docstring)
    with_level: bool = False

    def prepare(self, state: RecordState, model: Model, pilot: np.ndarray) -> Moments:
        """Per-bin block cross-spectra and frozen weights (module docstring)."""
        level_only = False
        if self.with_level and self.band is None:
            from .level import Level

            level_only = Level().skipped(state, model) is None
        if self.form not in ("scaled", "printed"):
            raise ValueError(f"unknown form {self.form!r}: 'scaled' or 'printed'")
        lo, hi = self.band or default_band(state)
        if hi > state.scales.omega_nyquist:
            raise ValueError(
                f"the J2 band's upper edge {hi:g} rad/s is above the Nyquist frequency "
                f"{state.scales.omega_nyquist:.4g} rad/s"
            )
        L = state.layout
        bins = L.bins(lo, hi, k_min=2)
        if bins.size < 3:
            raise ValueError(f"the J2 band {lo:g}-{hi:g} rad/s holds fewer than 3 bins")
        omega = bins * L.d_omega
        s2, _ = restoration(state, model, pilot)
        Y = feature_ffts(state, model, s2, bins)  # (F, B, K)
        norm = 2 * math.pi * L.T * state.window.k2
        R = np.einsum("ibk,jbk->bkij", Y, Y.conj()).real / norm  # (B, K, F, F)
        B, K = R.shape[:2]
        exc = Excitation(model, pilot, state.scales.sigma_v, state.scales.sigma_x)
        nd = model.n_drift
        th0 = np.asarray(pilot, dtype=float)
        lam0 = np.concatenate([[1.0], th0[:nd]])
        offsets, weights = state.window.kernel(L.M)
        near = np.abs(omega[:, None] + offsets[None, :] * L.d_omega)  # (K, n)

        def seen(theta):  # the shape as the blocks' periodograms see it, (..., K)
            if exc.white:
                return np.ones((*np.shape(theta)[:-1], omega.size))
            return exc.shape(near, theta) @ weights

        level0 = exc.S0(th0) * seen(th0)  # (K,)
        P0 = np.einsum("bkij,i,j->bk", R, lam0, lam0) / level0  # h + 1
        # directions: drift coefficients, S0, and the coefficients c_k (k >= 1) of the
        # shape's 1/L (d h / d c_k = -(h + 1) d log Lbar / d c_k; regular at a white
        # force, where the shape's own parameters give collinear directions)
        n_c = len(exc.spectrum.inverse_poly(th0)) - 1
        Lnear = exc.lowpass(near, th0) if n_c else None
        shape_dirs = [
            -((near ** (2 * k) * Lnear**2) @ weights) / seen(th0) for k in range(1, n_c + 1)
        ]
        names = model.param_names
        labels = [f"J2 d/d{names[i]}" for i in (*range(nd), exc.i_S0)]
        labels += [f"J2 d/dc{k}" for k in range(1, n_c + 1)]
        w = np.empty((B, K, nd + 1 + n_c))
        RL = np.einsum("bkij,j->bki", R, lam0)
        for a in range(nd):
            w[:, :, a] = 2.0 * RL[:, :, a + 1] / level0
        w[:, :, nd] = -P0 / exc.S0(th0)
        for k, d in enumerate(shape_dirs):
            w[:, :, nd + 1 + k] = -P0 * d
        if level_only:  # the in-band level only (module docstring)
            w, labels = w[:, :, nd : nd + 1], labels[nd : nd + 1]
        if self.form == "printed":
            w = w * (level0**2)[None, :, None]
        wbar = w.mean(axis=0)  # (K, J)
        # U-statistic: A_kj = wbar_kj Rbar_k - mean_b(w_bkj R_bk) / B
        Rbar = R.mean(axis=0)
        A = np.einsum("kj,kxy->kjxy", wbar, Rbar) - np.einsum("bkj,bkxy->kjxy", w, R) / B**2
        c = wbar - w.mean(axis=0) / B
        scale = B / ((B - 1) * K)
        c_sum = c.sum(axis=0)
        A_white = A.sum(axis=0)  # a white force: the bins summed once

        def mean(theta):
            th = np.asarray(theta, dtype=float)
            lam = np.concatenate([np.ones((*th.shape[:-1], 1)), th[..., :nd]], axis=-1)
            if exc.white:
                total = np.einsum("...x,jxy,...y->...j", lam, A_white, lam)
            else:
                q = np.einsum("...x,kjxy,...y->...kj", lam, A, lam)
                total = np.einsum("...k,...kj->...j", 1.0 / seen(th), q)
            return scale * (total / exc.S0(th)[..., None] - c_sum)

        # the statistic's projection on the blocks (its other half, w_b times the
        # population residual, vanishes at the solution; the sample residual is noise)
        u = u_pseudovalues(w / K, P0 - 1.0)
        return Moments(
            component=self.name,
            labels=tuple(labels),
            mean=mean,
            influence=u - u.mean(axis=0),
            info={
                "band_rad_s": [float(omega[0]), float(omega[-1])],
                "bins": int(K),
                "form": self.form,
            },
        )


def force_periodogram(
    state: RecordState, model: Model, theta: np.ndarray, bins: np.ndarray
) -> np.ndarray:
    r"""The block-averaged periodogram of the force inferred at ``theta``,
    :math:`\overline{|X(\omega_k)|^2}/2\pi Tk_2` (eq 45; velocity features restored as in
    J2), on ``bins``: what the excitation model's :math:`S_0\bar L` should follow.
    """
    s2, _ = restoration(state, model, theta)
    Y = feature_ffts(state, model, s2, bins)
    lam = np.concatenate([[1.0], np.asarray(theta, dtype=float)[: model.n_drift]])
    X = np.tensordot(lam, Y, axes=1)
    L = state.layout
    return np.mean(X.real**2 + X.imag**2, axis=0) / (2 * math.pi * L.T * state.window.k2)
