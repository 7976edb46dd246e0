r"""Second, third and fourth order spectral costs for an arbitrary set of features.

:mod:`hosid.costs` infers the force from exactly five features.  Here the force
is built from any number :math:`p` of feature rows (paper eq 45 generalized),

.. math::

    f(t) = \ddot x + \sum_{k\ge 1}\theta_k\,\phi_k(x, \dot x), \qquad
    X_r(\omega;\lambda) = \sum_{j=0}^{p-1}\lambda_j Y_{jr}(\omega),

where row 0 is normally :math:`\ddot x` (:math:`\lambda_0 = 1`) and the rows
:math:`\phi_k` may be :math:`\dot x, \dot x|\dot x|, x, x^3, x^2,
\operatorname{sign}\dot x, 1, \dots`.  :math:`Y_{jr}` is the windowed block FFT
(times :math:`\Delta t`) of row :math:`j` in block :math:`r`, exactly as in
:func:`hosid.spectra.block_spectra`.

The excitation may be coloured: :math:`S_f(\omega) = S_0 L(\omega)` with a known
shape :math:`L \ge 0` (``shape``; ``None`` is white, :math:`L = 1`).  Every
ordinate is normalized by its own model level :math:`s(\omega) = k_2 S_0
L(\omega)`,

.. math::

    z_r(\omega) = \frac{X_r(\omega)}{\sqrt{2\pi T s(\omega)}},

so that for a Gaussian force of that spectrum
:math:`E[z_r(\omega_a) z_r^*(\omega_b)] \approx \rho(a-b)` with the window bin
correlation :math:`\rho(k) = \frac{1}{M k_2}\sum_n D_n^2 e^{-2\pi i k n/M}`
(exact for a white force).  With the unbiased (U-statistic) estimate of a
squared mean over the :math:`N` independent blocks,
:math:`\widehat{|E h|^2} = (N|\bar h|^2 - \overline{|h|^2})/(N-1)`, the
well-scaled centred costs are

.. math::

    J_2^W = N\sum_{k_{min}\le k\le k_{max}} \widehat{|E h_k|^2}, \quad
        h = |z(\omega_k)|^2 - 1,

.. math::

    J_3^W = N\sum_{\mathcal B}\frac{\widehat{|E h_b|^2}}{v_b}, \quad
        h = z(\omega_{k_1}) z(\omega_{k_2}) z^*(\omega_{k_1+k_2}),

.. math::

    J_4^W = N\sum_{\mathcal T}\frac{\widehat{|E h_t|^2}}{v_t}, \quad
        h = z_1 z_2 z_3 z_4^* - g_t,

(:math:`J_2^W` and :math:`J_4^W` are :func:`hosid.costs.J2W` and
:func:`hosid.costs.J4AW` when :math:`L = 1`; :math:`\mathcal T` is the principal
trispectral domain, eq 39, with the Gaussian mean :math:`g_t` and per-block
variance :math:`v_t` of :class:`hosid.costs.CostData`).  The bispectral cost is
defined by analogy (paper section 6) on the principal domain

.. math::

    \mathcal B = \{(k_1, k_2):\ k_{lo} \le k_2 \le k_1,\ k_1 + k_2 \le k_{max}\},
    \qquad k_{lo} = \max(k_{min}, 2).

With the Hann window the DFT of a constant is non-zero only on bins
:math:`0, \pm 1`, so with :math:`k_{lo} \ge 2` a non-zero mean of the force
reaches no ordinate of :math:`J_3^W` (the mean shows only as zero-frequency
spikes, paper section 6).  For a Gaussian force :math:`E h = 0` (an odd moment)
and, by Isserlis' theorem over the 15 pairings of
:math:`(z_1, z_2, z_3^*, z_1^*, z_2^*, z_3)` (signed bins
:math:`s = (k_1, k_2, -k_3, -k_1, -k_2, k_3)`, :math:`k_3 = k_1 + k_2`,
:math:`E[z(a)z(b)] = \rho(a+b)` on signed bins),

.. math::

    v_b = E|h|^2 = \sum_{\text{pairings } \pi}\ \prod_{(a,b)\in\pi}\rho(s_a+s_b)
        = \sum_{\sigma\in S_3}\prod_i \rho(k_i - k_{\sigma(i)}) + \dots,

where the first sum pairs every :math:`z_i` with a :math:`z_j^*` and the dots
are the pairings of two unconjugated (or two conjugated) ordinates, with factors
:math:`\rho(k_i + k_j)`; on :math:`\mathcal B` these offsets are at least
:math:`2k_{lo} \ge 4`, beyond the reach of the Hann (:math:`|k| \le 2`) and
boxcar (:math:`k = 0`) correlations, so for those windows :math:`v_b` is the
six-permutation sum (1 to 2.11 for Hann).  For a non-Gaussian white
force with per-sample third cumulant :math:`\kappa_3` the block products have
the flat mean :math:`E h = \kappa_3 \Delta t^3 \sum_n D_n^3 / (2\pi T k_2
S_0)^{3/2}`.

All costs are centred: their expectation for a force of the model spectrum is 0
(:math:`J_3^W`: for any Gaussian force), their spread of order the square root
of the number of ordinates (larger by the correlation of neighbouring ordinates
through :math:`\rho(\pm 1)`), and they grow like :math:`N` times the squared
standardized bias away from it.  The eq-15 combination is
:math:`J = \sum_k w_k J_k^W` (:func:`combined`).

Every cost takes ``lam`` of shape ``(..., p)`` and ``S0`` broadcastable with
``lam.shape[:-1]`` and returns an array of the broadcast batch shape.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from . import costs as _costs
from .errors import HosidInputError
from .spectra import BlockSpectra, block_fft, block_layout
from .windows import Window, get_window

__all__ = [
    "FeatureSpectra",
    "bispectral_domain",
    "combined",
    "feature_spectra",
    "inferred_force",
    "j2w",
    "j3w",
    "j4w",
    "normalized_bispectrum",
    "trispectral_domain_k",
]

#: Soft cap on the number of complex elements of one batch chunk's work arrays.
_CHUNK_ELEMENTS = 1 << 22

_M6 = np.array(list(_costs._matchings(tuple(range(6)))))  # (15, 3, 2)


@dataclass(frozen=True)
class FeatureSpectra(BlockSpectra):
    r"""Block Fourier transforms of :math:`p` feature rows (any number).

    A :class:`hosid.spectra.BlockSpectra` whose ``Y`` holds arbitrary feature rows
    (row 0 is :math:`\ddot x`), shape ``(p, N, K)``: windowed block FFTs times
    ``dt`` on bins ``0 .. K-1`` (``K = min(M//2 + 1, 3 k_max + 1)``); the costs use
    the band ``k_min .. k_max``.
    """

    @property
    def n_features(self) -> int:
        """Number of feature rows p."""
        return self.Y.shape[0]

    @cached_property
    def rho(self) -> np.ndarray:
        r"""Window bin correlation :math:`\rho(k)` on ``k = 0 .. M-1`` (index ``k % M``)."""
        d2 = self.window.samples(self.M) ** 2
        return np.fft.fft(d2).real / (self.M * self.window.k2)

    @cached_property
    def _tri(self) -> _costs.CostData:
        """The principal trispectral domain with its Isserlis constants."""
        return _costs.prepare(self, "principal")

    @cached_property
    def _bi(self) -> tuple[np.ndarray, np.ndarray]:
        """The bispectral domain and its Gaussian per-block variance v."""
        k = bispectral_domain(self)
        s = np.stack([k[:, 0], k[:, 1], -k[:, 2], -k[:, 0], -k[:, 1], k[:, 2]], axis=1)
        v = np.zeros(k.shape[0])
        for m in _M6:
            term = np.ones(k.shape[0])
            for a, b in m:
                term = term * self.rho[(s[:, a] + s[:, b]) % self.M]
            v += term
        return k, np.maximum(v, 1e-12)


def feature_spectra(
    F: np.ndarray,
    dt: float,
    *,
    block_seconds: float = 20.48,
    omega_max: float,
    omega_min: float | None = None,
    window: str | Window = "hann",
    min_blocks: int = 8,
) -> FeatureSpectra:
    r"""Cut the feature rows ``F`` (shape ``(p, n)``; a 1-d array is one row) into
    :math:`N = \lfloor n/M \rfloor` blocks of :math:`M = \mathrm{round}(T/\Delta t)`
    samples and take the windowed FFT of every row (as
    :func:`hosid.spectra.block_spectra`, with the same checks and messages).
    Row 0 is normally :math:`\ddot x`.  Bins up to ``3 * k_max`` are stored.
    """
    F = np.asarray(F, dtype=float)
    if F.ndim == 1:
        F = F[None, :]
    if F.ndim != 2 or F.shape[0] < 1:
        raise HosidInputError(f"features must have shape (p, n); got {F.shape}")
    if not np.all(np.isfinite(F)):
        bad = np.argwhere(~np.isfinite(F))[0]
        raise HosidInputError(f"feature row {bad[0]} has a non-finite value at sample {bad[1]}")
    if not (np.isfinite(dt) and dt > 0):
        raise HosidInputError(f"dt must be positive and finite; got {dt}")
    win = get_window(window)
    M, T, k_min, k_max = block_layout(
        F.shape[1],
        dt,
        block_seconds=block_seconds,
        omega_max=omega_max,
        omega_min=omega_min,
        min_blocks=min_blocks,
    )
    Y = block_fft(F, M, dt, win, min(M // 2 + 1, 3 * k_max + 1))
    return FeatureSpectra(Y=Y, T=T, dt=dt, M=M, window=win, k_min=k_min, k_max=k_max)


def bispectral_domain(fs: FeatureSpectra) -> np.ndarray:
    r"""``(n, 3)`` bins :math:`(k_1, k_2, k_1+k_2)` with :math:`\max(k_{min}, 2) \le
    k_2 \le k_1` and :math:`k_1 + k_2 \le k_{max}` (may be empty).
    """
    lo, hi = max(fs.k_min, 2), fs.k_max
    rows = [(k1, k2, k1 + k2) for k2 in range(lo, hi + 1) for k1 in range(k2, hi - k2 + 1)]
    return np.array(rows, dtype=np.int64).reshape(-1, 3)


def trispectral_domain_k(fs: FeatureSpectra) -> np.ndarray:
    """``(n, 4)`` bins ``(k1, k2, k3, k4 = k1 + k2 + k3)`` of the principal
    trispectral domain (eq 39; :func:`hosid.spectra.trispectral_domain`).
    """
    return fs._tri.domain.k


def inferred_force(fs: FeatureSpectra, lam) -> np.ndarray:
    r"""Eq (45): :math:`X_r(\omega_k) = \sum_j \lambda_j Y_{jr}(\omega_k)`.

    ``lam`` of shape ``(..., p)`` gives ``(..., N, K)`` (all stored bins).
    """
    lam = _lam(fs, lam)
    return np.tensordot(lam, fs.Y, axes=([-1], [0]))


# ---------------------------------------------------------------------- internals
def _lam(fs: FeatureSpectra, lam) -> np.ndarray:
    lam = np.asarray(lam, dtype=float)
    if lam.ndim == 0 or lam.shape[-1] != fs.n_features:
        raise ValueError(
            f"lam must have shape (..., {fs.n_features}) for {fs.n_features} features; "
            f"got {lam.shape}"
        )
    return lam


def _shape_factor(fs: FeatureSpectra, shape: Callable | None) -> np.ndarray:
    """1/sqrt(L(omega_k)) on bins 0..k_max (1 outside the band, where it is unused)."""
    f = np.ones(fs.k_max + 1)
    if shape is None:
        return f
    L = np.broadcast_to(np.asarray(shape(fs.omega), dtype=float), fs.band.shape)
    if not np.all(np.isfinite(L) & (L > 0)):
        raise HosidInputError(
            "the spectral shape L(omega) must be positive and finite on the band"
        )
    f[fs.band] = 1.0 / np.sqrt(L)
    return f


def _map_z(fs: FeatureSpectra, lam, S0, shape, fn: Callable, n_out: int = 1) -> np.ndarray:
    r"""Evaluate ``fn(z)`` on chunks of the flattened batch.

    ``z`` has shape ``(B, N, k_max + 1)``: the normalized force
    :math:`X/\sqrt{2\pi T k_2 S_0 L}` on bins ``0 .. k_max``; ``fn`` returns
    ``(n_out, B)`` (or ``(B,)`` when ``n_out == 1``).
    """
    lam = _lam(fs, lam)
    S0 = np.asarray(S0, dtype=float)
    batch = np.broadcast_shapes(lam.shape[:-1], S0.shape)
    p = fs.n_features
    lam_f = np.broadcast_to(lam, (*batch, p)).reshape(-1, p)
    S0_f = np.broadcast_to(S0, batch).reshape(-1)
    Y = fs.Y[:, :, : fs.k_max + 1]
    norm = _shape_factor(fs, shape) / np.sqrt(2 * np.pi * fs.T * fs.window.k2)
    B = lam_f.shape[0]
    per = fs.n_blocks * max(fs.k_max + 1, bispectral_domain(fs).shape[0], 2 * fs.k_max + 1)
    step = max(1, _CHUNK_ELEMENTS // per)
    out = np.empty((n_out, B))
    for i in range(0, B, step):
        lam_c, S0_c = lam_f[i : i + step], S0_f[i : i + step]
        X = np.tensordot(lam_c, Y, axes=([-1], [0]))
        z = X * (norm / np.sqrt(S0_c)[:, None, None])
        out[:, i : i + step] = np.reshape(fn(z), (n_out, -1))
    return out.reshape(batch) if n_out == 1 else out.reshape((n_out, *batch))


def _unbiased(mean_abs2: np.ndarray, mean_sq: np.ndarray, N: int) -> np.ndarray:
    return (N * mean_abs2 - mean_sq) / (N - 1)


def _j2_z(fs: FeatureSpectra, z: np.ndarray) -> np.ndarray:
    zb = z[:, :, fs.band]
    h = zb.real**2 + zb.imag**2 - 1.0  # (B, N, K_band)
    m, m2 = h.mean(axis=1), (h**2).mean(axis=1)
    N = fs.n_blocks
    return N * np.sum(_unbiased(m**2, m2, N), axis=-1)


def _bispectrum_z(fs: FeatureSpectra, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Block means of h = z1 z2 z3* and of |h|^2 on the bispectral domain, (B, n)."""
    k, _ = fs._bi
    h = z[:, :, k[:, 0]] * z[:, :, k[:, 1]] * np.conj(z[:, :, k[:, 2]])
    return h.mean(axis=1), (h.real**2 + h.imag**2).mean(axis=1)


def _j3_z(fs: FeatureSpectra, z: np.ndarray) -> np.ndarray:
    _, v = fs._bi
    m, m2 = _bispectrum_z(fs, z)
    N = fs.n_blocks
    return N * np.sum(_unbiased(m.real**2 + m.imag**2, m2, N) / v, axis=-1)


def _j4_z(fs: FeatureSpectra, z: np.ndarray) -> np.ndarray:
    data = fs._tri
    # signed layout -K..K with the block index last, as CostData.fourth_order expects
    zs = np.concatenate([np.conj(z[:, :, :0:-1]), z], axis=2)
    zs = np.ascontiguousarray(zs.transpose(0, 2, 1))
    vb, vb2 = data.fourth_order(None, zs, second_moment=True)
    scale = 8 * np.pi**3 * fs.T
    m = vb * scale  # block mean of z1 z2 z3 z4*
    g = data.null_mean
    mean_abs2 = np.abs(m - g) ** 2
    mean_sq = vb2 * scale**2 - 2 * g * m.real + g**2  # block mean of |h|^2
    N = fs.n_blocks
    return N * np.sum(_unbiased(mean_abs2, mean_sq, N) / data.null_var, axis=-1)


_ORDERS = {2: _j2_z, 3: _j3_z, 4: _j4_z}


# ---------------------------------------------------------------------- costs
def j2w(fs: FeatureSpectra, lam, S0, shape: Callable | None = None) -> np.ndarray:
    r"""Well-scaled centred second-order cost
    :math:`J_2^W = N\sum_k \widehat{|E h_k|^2}`, :math:`h = |X|^2/(2\pi T k_2 S_0
    L(\omega_k)) - 1` on the band (:func:`hosid.costs.J2W` for :math:`L = 1`).
    """
    return _map_z(fs, lam, S0, shape, lambda z: _j2_z(fs, z))


def j3w(fs: FeatureSpectra, lam, S0, shape: Callable | None = None) -> np.ndarray:
    r"""Well-scaled centred bispectral cost
    :math:`J_3^W = N\sum_{\mathcal B}\widehat{|E h_b|^2}/v_b`,
    :math:`h = z(\omega_{k_1})z(\omega_{k_2})z^*(\omega_{k_1+k_2})` (module doc).
    """
    return _map_z(fs, lam, S0, shape, lambda z: _j3_z(fs, z))


def j4w(fs: FeatureSpectra, lam, S0, shape: Callable | None = None) -> np.ndarray:
    r"""Well-scaled centred trispectral cost on the principal domain,
    :math:`J_4^W = N\sum_{\mathcal T}\widehat{|E h_t|^2}/v_t`,
    :math:`h = z_1 z_2 z_3 z_4^* - g_t` (:func:`hosid.costs.J4AW` for :math:`L = 1`).
    """
    return _map_z(fs, lam, S0, shape, lambda z: _j4_z(fs, z))


def normalized_bispectrum(
    fs: FeatureSpectra, lam, S0, shape: Callable | None = None
) -> np.ndarray:
    r"""Block mean of :math:`h = z_1 z_2 z_3^*` on :func:`bispectral_domain`,
    shape ``(..., n_domain)``, complex (0 for a Gaussian force).
    """
    n = fs._bi[0].shape[0]

    def fn(z):
        m = _bispectrum_z(fs, z)[0].T  # (n, B)
        return np.concatenate([m.real, m.imag])

    out = _map_z(fs, lam, S0, shape, fn, n_out=2 * n)  # (2n, *batch)
    return np.moveaxis(out[:n] + 1j * out[n:], 0, -1)


def combined(
    fs: FeatureSpectra,
    lam,
    S0,
    *,
    orders: Sequence[int] = (2, 3, 4),
    weights: Sequence[float] | None = None,
    shape: Callable | None = None,
) -> np.ndarray:
    r"""Eq (15): :math:`J = \sum_k w_k J_k^W` over ``orders`` (each of 2, 3, 4),
    unit weights by default.  The inferred force is formed once per batch chunk.
    """
    orders = tuple(int(o) for o in orders)
    if not orders or any(o not in _ORDERS for o in orders):
        raise ValueError(f"orders must be a non-empty selection of 2, 3, 4; got {orders}")
    w = np.ones(len(orders)) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (len(orders),):
        raise ValueError(f"need one weight per order {orders}; got {w.shape}")

    def fn(z):
        return sum(wk * _ORDERS[o](fs, z) for o, wk in zip(orders, w, strict=True))

    return _map_z(fs, lam, S0, shape, fn)
