r"""The spectral tail of a sampled record, where a coloured force and a noise floor show.

Far above resonance a randomly excited oscillator follows its force,
:math:`\ddot x \approx g`, and the sampled displacement's spectrum is the continuous
tail folded into the band, :math:`S(\omega) = \lambda\sum_jL(\omega_j)T(\omega_j) + N`,
:math:`\omega_j = \omega + 2j\omega_N`, with :math:`T = 1/[(k - \omega^2)^2 +
c^2\omega^2]` of the equivalent linear system, the force's shape :math:`L = 1/(1 +
\eta\omega^2)` (:math:`\eta = 1/\omega_c^2`) and the noise floor :math:`N =
\sigma_\epsilon^2\Delta t/2\pi`.  The log-derivatives of a corner and a floor,
:math:`-\omega^2` and :math:`\propto\omega^4`, put their Whittle information at the top
of the band.

Shared by the likelihood component (:class:`hosid.components.tail.Tail`) and the
predictive measure ``psd_tail`` (:mod:`hosid.check.measures`):

- :func:`difference_periodogram`: each block's second difference :math:`d_n = y_{n+1} -
  2y_n + y_{n-1}` (gain :math:`|D|^2 = (2 - 2\cos\omega\Delta t)^2`) has a nearly flat
  spectrum in the tail, so its plain periodogram (no taper, whose cost would be
  :math:`k_4/k_2^2 = 1.94` for Hann) does not leak the resonance into the tail;
- :func:`folded_tail`: :math:`|D|^2T` at the aliases of the tail's bins (:data:`N_ALIAS`
  on either side);
- :func:`tail_scores`: a record's level-free scores of a corner and a floor against a
  reference tail (weights fixed by it: the same functional on every record);
- :func:`level_free`: the directions of :math:`\eta` and :math:`N` made orthogonal to
  the level's in the Whittle metric :math:`\sum_k ab/S_k^2` and scaled to unit norm: a
  level a little off (the nonlinear tail is not exactly its linear equivalent) does not
  move a score along them to first order.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "LOW",
    "MIN_BINS",
    "N_ALIAS",
    "difference_gain",
    "difference_periodogram",
    "folded_tail",
    "level_free",
    "periodogram_scores",
    "tail_bins",
    "tail_scores",
]

#: The tail starts this many equivalent natural frequencies up.
LOW = 4.0
#: Aliases on either side of the band.
N_ALIAS = 10
#: Fewest bins a tail must hold.
MIN_BINS = 8


def tail_bins(n: int, dt: float, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
    """The bins of a length-``n`` periodogram with ``lo <= omega < hi`` (the Nyquist bin,
    a real ordinate, is never among them): ``(mask over rfft bins, omega)``.
    """
    w = 2.0 * math.pi * np.fft.rfftfreq(n, dt)
    sel = (w >= lo) & (w < min(hi, math.pi / dt) * (1.0 - 1e-9))
    return sel, w[sel]


def difference_gain(omega: np.ndarray, dt: float) -> np.ndarray:
    r"""The second difference's power gain :math:`|D|^2 = (2 - 2\cos\omega\Delta t)^2`
    (also the direction of a white noise floor in its spectrum).
    """
    return (2.0 - 2.0 * np.cos(np.asarray(omega, dtype=float) * dt)) ** 2


def difference_periodogram(blocks: np.ndarray, dt: float, sel: np.ndarray) -> np.ndarray:
    r"""The periodogram :math:`|D_k|^2\Delta t/(2\pi n)` of each block's second
    difference (``blocks`` ``(B, M)``, ``n = M - 2``) at the bins ``sel``
    (:func:`tail_bins` of ``n``): ``(B, K)``, two-sided density.
    """
    d = blocks[:, 2:] - 2.0 * blocks[:, 1:-1] + blocks[:, :-2]
    F = np.fft.rfft(d, axis=1)[:, sel]
    return (F.real**2 + F.imag**2) * dt / (2.0 * math.pi * d.shape[1])


def folded_tail(omega: np.ndarray, dt: float, c: float, k: float) -> tuple[np.ndarray, np.ndarray]:
    r"""The aliases :math:`\omega_j^2` and :math:`|D(\omega)|^2T(\omega_j)` of the bins
    ``omega``, each ``(K, 2 N_ALIAS + 1)``.
    """
    wN = math.pi / dt
    W = omega[:, None] + 2.0 * wN * np.arange(-N_ALIAS, N_ALIAS + 1)
    return W**2, difference_gain(omega, dt)[:, None] / ((k - W**2) ** 2 + (c * W) ** 2)


def level_free(directions: list[np.ndarray], level: np.ndarray, S: np.ndarray) -> list[np.ndarray]:
    r"""The weights :math:`q = w^\perp/S^2` of each direction :math:`w` made orthogonal to
    ``level`` and of unit norm in the Whittle metric (module docstring): a score
    :math:`\sum_kq_k(\bar P_k - S_k)` has unit sd per block at ``S``.
    """
    out = []
    ll = np.sum(level**2 / S**2)
    for w in directions:
        wperp = w - np.sum(w * level / S**2) / ll * level
        out.append(wperp / S**2 / math.sqrt(np.sum(wperp**2 / S**2)))
    return out


def tail_scores(
    blocks: np.ndarray, dt: float, band: tuple[float, float], shape: tuple[float, float]
) -> np.ndarray:
    r"""The level-free scores :math:`t_\psi = \sum_kq_{\psi k}\bar P_k/\hat\lambda` of a
    corner (:math:`\psi = \eta`) and a floor (:math:`N`) of the blocks ``(B, M)`` on the
    bins of ``band``, against the white, noise-free tail of the equivalent linear system
    ``shape = (c, k)``; :math:`\hat\lambda = \overline{\bar P_k/S_k}` is the level, so
    the scores are invariant to a scale of the record.
    """
    sel, omega = tail_bins(blocks.shape[1] - 2, dt, *band)
    return periodogram_scores(
        difference_periodogram(blocks, dt, sel).mean(axis=0), omega, dt, shape
    )


def periodogram_scores(
    Pbar: np.ndarray, omega: np.ndarray, dt: float, shape: tuple[float, float]
) -> np.ndarray:
    """:func:`tail_scores` of a mean periodogram ``Pbar`` of the second difference at
    the bins ``omega``.
    """
    W2, T = folded_tail(omega, dt, *shape)
    S = T.sum(axis=1)
    q = level_free([-np.sum(W2 * T, axis=1), difference_gain(omega, dt)], S, S)
    return np.array([np.sum(qi * Pbar) for qi in q]) / np.mean(Pbar / S)
