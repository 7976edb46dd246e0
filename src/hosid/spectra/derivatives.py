r"""Derivatives of a sampled record and what sampling takes from them.

:func:`derivatives` (the velocity and acceleration of :class:`hosid.state.RecordState`),
:func:`smooth_derivatives` (up to the jerk, for the smooth response to a coloured force),
and the variance the sampled derivatives lack above the Nyquist frequency:
:func:`velocity_deficit` (module docstring of :mod:`hosid.state`) and its generalization
to the whole jet, :func:`jet_deficit`.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "C_ALIAS",
    "derivatives",
    "jet_deficit",
    "smooth_derivatives",
    "velocity_deficit",
]


def derivatives(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    r"""Spectral velocity and acceleration of a record.

    The record less the line through its end samples, :math:`r`, vanishes at both ends
    and is extended by its point reflection about the last sample (period
    :math:`2n - 2`: a sine series), whose periodic extension is continuous with its
    slope; the derivatives of that series, with the line's slope, are the record's.

    The plain periodic extension of :math:`r` keeps its value but not its slope: the
    velocity jumps at the wrap, and the acceleration gets the jump's band-limited delta,
    :math:`\Delta v/(\pi\Delta t(k + \tfrac12))` at :math:`k` samples from the wrap.
    On a 2000 s record of the two-dof chain of ``analyses/oma_comparison.py`` its first
    sample was 17.8 sd of the acceleration, and it alone made the inferred force's
    excess kurtosis 1.4 (the data's: 0.02), so that the force-kurtosis equation's block
    influences were a single block's spike.  With the reflection the acceleration is
    continuous at the wrap and only its curvature jumps: the error is of the order of
    the end samples' own acceleration, and decays from the ends as :math:`1/k`.
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    slope = (x[-1] - x[0]) / ((n - 1) * dt)
    r = x - (x[0] + slope * dt * np.arange(n))
    ext = np.concatenate([r, -r[-2:0:-1]])  # odd about the last sample: period 2n - 2
    m = ext.size
    F = np.fft.rfft(ext)
    w = 2.0 * np.pi * np.fft.rfftfreq(m, dt)
    F[-1] = 0.0  # the Nyquist bin has no derivative (m is even)
    v = np.fft.irfft(1j * w * F, m)[:n] + slope
    a = np.fft.irfft(-(w**2) * F, m)[:n]
    return v, a


def smooth_derivatives(x: np.ndarray, dt: float, n_fit: int) -> tuple[np.ndarray, ...]:
    r"""Spectral velocity, acceleration and jerk of a smooth record (a coloured force).

    The periodic extension of a record breaks its derivatives at the wrap, and the
    third derivative rings for hundreds of samples (its squares, summed, exceeded the
    record's own by 1-2 % after 200 samples were trimmed).  Here the record is extended
    by a gap of :math:`4n` samples bridged by the quintic Hermite interpolant of the
    displacement, velocity and acceleration at both ends (local least-squares
    polynomials of degree 5 on :math:`n` = ``n_fit`` samples), so the periodic extension
    is :math:`C^2`; the gap is dropped after differentiation.
    """
    from scipy.interpolate import BPoly

    x = np.asarray(x, dtype=float)
    n = x.size
    n_fit = int(min(max(n_fit, 8), n // 4))
    u = np.arange(n_fit) / n_fit  # normalized time of the fits
    V = np.polynomial.polynomial.polyvander(u, 5)
    ends = []
    for seg, sign in ((x[:n_fit], 1.0), (x[::-1][:n_fit], -1.0)):
        coef = np.linalg.lstsq(V, seg, rcond=None)[0]
        tau = n_fit * dt
        ends.append([coef[0], sign * coef[1] / tau, 2.0 * coef[2] / tau**2])
    gap = 4 * n_fit
    bridge = BPoly.from_derivatives([0.0, (gap + 1) * dt], [ends[1], ends[0]])
    ext = np.concatenate([x, bridge(np.arange(1, gap + 1) * dt)])
    F = np.fft.rfft(ext)
    w = 2.0 * np.pi * np.fft.rfftfreq(ext.size, dt)
    if ext.size % 2 == 0:
        F[-1] = 0.0
    return tuple(np.fft.irfft((1j * w) ** k * F, ext.size)[:n] for k in (1, 2, 3))


def jet_deficit(S0: float, dt: float, shape, order: int, n_alias: int = 60) -> np.ndarray:
    r"""The covariance of what the sampled jet :math:`(x, \dot x, \ddot x, \dddot x)`
    (orders 0..``order``) lacks, for an excitation :math:`S_0L(\omega)`.

    With the response :math:`S_0L(\omega)/\omega^4` far above resonance, the spectral
    derivatives of the sampled record hold, of each alias :math:`\omega_j = \omega +
    2j\omega_N`, the power at :math:`\omega` instead of at :math:`\omega_j`:

    .. math:: \Sigma_{rs} = S_0\sum_{j\ne0}\int_{-\omega_N}^{\omega_N}
        \mathrm{Re}\big[(i\omega_j)^r(-i\omega_j)^s - (i\omega)^r(-i\omega)^s\big]
        \frac{L(\omega_j)}{\omega_j^4}\,d\omega,

    zero for :math:`r + s` odd; :math:`\Sigma_{11}` is :func:`velocity_deficit`.  A
    statistic :math:`F` of the jet is restored as :math:`F + \tfrac12\sum_{rs}\Sigma_{rs}
    \partial_r\partial_sF` (:mod:`hosid.components.jets`).
    """
    wN = math.pi / dt
    u = np.linspace(-1.0, 1.0, 1001)[:, None]
    j = np.array([k for k in range(-n_alias, n_alias + 1) if k])[None, :]
    W = (u + 2.0 * j) * wN
    nu = u * wN
    L = np.asarray(shape(W)) / W**4
    out = np.zeros((order + 1, order + 1))
    for r in range(order + 1):
        for s in range(r, order + 1):
            if (r + s) % 2:
                continue
            f = np.real((1j * W) ** r * (-1j * W) ** s - (1j * nu) ** r * (-1j * nu) ** s)
            out[r, s] = out[s, r] = S0 * np.trapezoid((f * L).sum(axis=1), u[:, 0] * wN)
    return out


#: The alias constant c of the module docstring (white excitation): 2 - pi^2/6.
C_ALIAS = 2.0 - math.pi**2 / 6.0


def velocity_deficit(S0, dt: float, shape=None, n_alias: int = 60) -> np.ndarray:
    r"""The velocity variance :math:`s^2` a sampled record lacks (module docstring).

    ``shape`` is the excitation's spectral shape :math:`L(\omega)` (a callable on an
    array of frequencies), ``None`` for white noise.
    """
    wN = math.pi / dt
    if shape is None:
        return np.asarray(S0) * (2.0 - C_ALIAS) / wN
    u = np.linspace(-1.0, 1.0, 1001)[:, None]
    j = np.array([k for k in range(-n_alias, n_alias + 1) if k])[None, :]
    W = (u + 2.0 * j) * wN
    integrand = 1.0 / W**2 - (u * wN) ** 2 / W**4
    val = np.trapezoid((integrand * np.asarray(shape(W))).sum(axis=1), u[:, 0] * wN)
    return np.asarray(S0) * val
