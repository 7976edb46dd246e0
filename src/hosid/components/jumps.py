r"""What Poisson impulses change in the estimating equations (``impulsive_excitation``).

**Generator identities.**  Under impulses of rate :math:`r` with areas
:math:`A \sim N(0, \sigma_A^2)`, :math:`\sigma_A^2 = 2\pi S_0/r`
(:class:`hosid.model.excitation.ImpulsiveExcitation`), the velocity jumps and Itô's
formula for jump processes replaces the white force's term :math:`\pi S_0\,\overline{
\psi'(\dot x)}` of a velocity identity (:mod:`hosid.components.identities`, with
:math:`G = \int\psi`) by the generator of the jumps,

.. math:: r\,\overline{E_A[G(\dot x + A)] - G(\dot x)} = \pi S_0\,\overline{\psi'}
    + \frac{(\pi S_0)^2}{2r}\,\overline{\psi'''} + \dots,

exactly (the series in the cumulants of :math:`A` ends for a polynomial :math:`G`, not
for :math:`\dot x|\dot x|`); :math:`r \to \infty` is the Gaussian identity.  With the
velocity restored for what the sampled record lacks (a Gaussian :math:`z`, variance
:math:`s^2`), the mean over a block is :math:`\pi S_0\,e(\sigma_A^2)` with

.. math:: e(\sigma^2) = \frac{2}{\sigma^2}\big[h(s^2 + \sigma^2) - h(s^2)\big], \qquad
    h(\sigma^2) = \overline{E\,G(\dot x + \sigma\xi)},\ \xi \sim N(0, 1),

tabulated on a grid of :math:`\sigma^2` (:func:`jump_table`: :math:`G` smoothed by the
Gaussian on a fine grid of velocities, then interpolated at the record's) and read
off by interpolation in :math:`\log\sigma^2`.  A displacement identity does not change:
an impulse moves the velocity only.

**The inferred force's kurtosis.**  The force inferred from a sampled record,
:math:`\ddot x + g(x, \dot x)` with spectral derivatives (:mod:`hosid.state`), sees one
impulse as the spectral second derivative of a sampled kink, :math:`A\,k(t - t_i)`, so
its fourth cumulant at a sample is :math:`3r\sigma_A^4\int k^4 = 3(2\pi S_0)^2c_4/(r\,
\Delta t^3)` with :math:`c_4 = \Delta t^3\int k^4\,dt` (:func:`kink_constants`: 1.25,
where the ideal low-pass of the force would give 2/3, since the kink's aliases add to
it); :class:`hosid.components.cumulant.ForceKurtosis` subtracts it.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
from scipy.signal import fftconvolve

from ..spectra.derivatives import derivatives

__all__ = ["GRID", "jump_table", "kink_constants", "read_table"]

#: The tabulated area variances, in units of the velocity's variance.
GRID = np.geomspace(1e-4, 1e4, 65)


@cache
def kink_constants() -> tuple[float, float]:
    r"""``(c2, c4)``: :math:`\Delta t\int k^2` and :math:`\Delta t^3\int k^4` of the
    spectral second derivative :math:`k` of a unit kink sampled at phase :math:`u`
    (:func:`hosid.state.derivatives`), averaged over :math:`u` uniform in a sample
    (module docstring).  Dimensionless: the same for every sampling interval.
    """
    n, dt = 4096, 1.0
    t = np.arange(n) * dt
    c2 = c4 = 0.0
    phases = np.linspace(0.0, 1.0, 64, endpoint=False)
    for u in phases:
        _, a = derivatives(np.maximum(t - (n // 2 + u) * dt, 0.0), dt)
        mid = a[n // 4 : 3 * n // 4]
        c2 += float(np.sum(mid**2)) * dt * dt
        c4 += float(np.sum(mid**4)) * dt * dt**3
    return c2 / phases.size, c4 / phases.size


def jump_table(G, v: np.ndarray, s2: float, sigma_v: float) -> np.ndarray:
    r""":math:`e(\sigma^2)` (module docstring) per block for the boundary function ``G``
    (vectorized) on the velocity blocks ``v`` ``(B, M)``: an array ``(B, len(GRID))``
    at :math:`\sigma^2 = ` ``GRID`` :math:`\sigma_v^2`.
    """
    s2 = max(float(s2), 0.0)
    var = GRID * sigma_v**2
    top = math.sqrt(var[-1] + s2)
    du = 0.02 * sigma_v
    half = float(np.max(np.abs(v))) + 8.0 * top
    u = np.arange(-half, half + du, du)
    Gu = G(u)

    def smoothed(f, sd):  # f smoothed by N(0, sd^2) on the grid
        z = np.arange(-math.ceil(8 * sd / du), math.ceil(8 * sd / du) + 1) * du
        kern = np.exp(-0.5 * (z / sd) ** 2)
        return fftconvolve(f, kern / kern.sum(), mode="same")

    def second(f):
        return np.gradient(np.gradient(f, du), du)

    # G smoothed by the restoration, then the difference the areas make, taken on the grid
    # before it is read at the velocities (the difference is small where sigma is)
    base = smoothed(Gu, math.sqrt(s2)) if s2 > (4 * du) ** 2 else Gu + 0.5 * s2 * second(Gu)
    b2 = second(base)
    b4 = second(b2)
    # the block means of a linear interpolation at v are linear in the grid's values: one
    # weight per block and grid point, on the few points the velocities reach
    lo, W = _interpolation_weights(v, u[0], du)
    diffs = []
    for s in var:
        if s > (4 * du) ** 2:
            diff = smoothed(base, math.sqrt(s)) - base
        else:  # below the grid's resolution: the expansion in the Gaussian's cumulants
            diff = 0.5 * s * b2 + s * s / 8.0 * b4
        diffs.append(2.0 / s * diff[lo : lo + W.shape[-1]])
    return W @ np.stack(diffs, axis=-1)


def _interpolation_weights(v: np.ndarray, u0: float, du: float) -> tuple[int, np.ndarray]:
    r"""``(lo, W)`` with ``W @ f[lo:lo + W.shape[-1]]`` the block means of the linear
    interpolation of ``f`` (on the grid :math:`u_k = u_0 + k\,\Delta u`) at the velocities
    ``v`` ``(B, M)``: each sample adds :math:`1 - w` to its grid point below and
    :math:`w` to the one above, over :math:`M`.
    """
    pos = (np.asarray(v, dtype=float) - u0) / du
    i = np.floor(pos).astype(np.int64)
    w = pos - i
    lo = int(i.min())
    width = int(i.max()) - lo + 2
    B, M = pos.shape
    rows = np.repeat(np.arange(B) * width, M).reshape(B, M)
    idx = rows + (i - lo)
    W = np.bincount(idx.ravel(), (1.0 - w).ravel(), minlength=B * width)
    W += np.bincount((idx + 1).ravel(), w.ravel(), minlength=B * width)
    return lo, W.reshape(B, width) / M


def read_table(table: np.ndarray, sigma2, sigma_v: float) -> np.ndarray:
    r"""The table ``(..., len(GRID))`` at area variances ``sigma2`` (any shape ``S``),
    linear in :math:`\log\sigma^2` and held at the grid's ends: shape ``S + (...)``.
    """
    x = np.log(np.asarray(sigma2, dtype=float) / sigma_v**2)
    grid = np.log(GRID)
    pos = np.clip(np.interp(x, grid, np.arange(grid.size)), 0.0, grid.size - 1.0)
    i = np.minimum(np.floor(pos).astype(int), grid.size - 2)
    w = (pos - i)[..., None]
    flat = table.reshape(-1, grid.size)
    out = flat[:, i] * (1.0 - w[..., 0]) + flat[:, i + 1] * w[..., 0]  # (rows, *S)
    return np.moveaxis(out, 0, -1).reshape(*np.shape(x), *table.shape[:-1])
