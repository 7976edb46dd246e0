r"""J3: the bispectrum of the inferred force (paper section 6, eq 15).

Per block :math:`r` and pair :math:`t = (k_1, k_2)` of the bispectral domain
(:func:`hosid.spectra.domains.bispectral_domain`; bins :math:`\ge 2`, so that a mean
force, which the Hann window leaks into bins 0 and 1 only, reaches no ordinate),

.. math:: q_{rt}(\theta) = \frac{X_r(\omega_1)X_r(\omega_2)X_r^*(\omega_1+\omega_2)}{4\pi^2T},

whose expectation vanishes for a Gaussian force of any spectrum (an odd moment).  J3 is
:math:`\sum_t w_t|\bar q_t|^2`; as for J2 and J4 its gradient with frozen weights
:math:`d_{tj} = w_t\,\partial q_t/\partial\theta_j` (:math:`w_t = 1` as printed, or the
inverse Gaussian variance of the ordinate, ``form="scaled"``), over block pairs
:math:`r \ne r'`, gives one estimating equation per drift coefficient,

.. math:: m_j(\theta) = \mathrm{Re}\sum_t d^*_{tj}\,\bar q_t(\theta),

a cubic form in :math:`\lambda = (1, \theta_{drift})` contracted once by the compiled
kernels of :mod:`hosid.components._kernels`.  J3 sees only asymmetric effects
(:math:`b_2x^2`, a mean force together with a stiffness nonlinearity): for the paper's
symmetric model its equations carry no information (their expectation is zero for every
:math:`\theta`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..model.model import Model
from ..spectra.domains import bispectral_domain
from ..spectra.windows import get_window
from ..state import RecordState
from ._kernels import contract3, products3
from .base import Moments, feature_ffts, restoration, u_pseudovalues
from .spectral import default_band

__all__ = ["J3", "bispectral_null_variance"]

#: Default upper edge of the bispectral band, in units of the natural frequency.
BAND_FACTOR = 3.0


def bispectral_null_variance(k: np.ndarray, rho) -> np.ndarray:
    r"""Per-block variance of :math:`z_1z_2z_3^*` for a Gaussian white force: Isserlis
    over the 15 pairings of :math:`(z_1, z_2, z_3^*, z_1^*, z_2^*, z_3)`, signed bins
    :math:`(k_1, k_2, -k_3, -k_1, -k_2, k_3)`, :math:`E[z(a)z(b)] = \rho(a + b)`.
    """
    s = np.stack([k[:, 0], k[:, 1], -k[:, 2], -k[:, 0], -k[:, 1], k[:, 2]], axis=1)
    total = np.zeros(k.shape[0])
    for m in _pairings(tuple(range(6))):
        term = np.ones(k.shape[0])
        for a, b in m:
            term = term * rho(s[:, a] + s[:, b])
        total += term
    return np.maximum(total, 1e-12)


def _pairings(items):
    if not items:
        yield ()
        return
    for i in range(1, len(items)):
        rest = items[1:i] + items[i + 1 :]
        for m in _pairings(rest):
            yield ((items[0], items[i]), *m)


@lru_cache(maxsize=16)
def _null_variance(k_max: int, window: str, m: int) -> np.ndarray:
    win = get_window(window)
    return bispectral_null_variance(bispectral_domain(k_max), lambda k: win.rho(k, m))


@dataclass(frozen=True)
class J3:
    """The bispectral component (module docstring)."""

    form: str = "scaled"
    omega_max: float | None = None
    name: str = "J3"

    def prepare(self, state: RecordState, model: Model, pilot: np.ndarray) -> Moments:
        """Domain, frozen weights and the contracted cubic forms (module docstring)."""
        if self.form not in ("scaled", "printed"):
            raise ValueError(f"unknown form {self.form!r}: 'scaled' or 'printed'")
        L, sc = state.layout, state.scales
        w_max = self.omega_max or min(BAND_FACTOR * sc.omega_n, default_band(state)[1])
        k_max = math.floor(w_max / L.d_omega + 1e-9)
        dom = bispectral_domain(k_max)
        if dom.shape[0] < 3:
            raise ValueError(f"the bispectral band up to {w_max:.3g} rad/s holds < 3 pairs")
        th0 = np.asarray(pilot, dtype=float)
        nd = model.n_drift
        s2, _ = restoration(state, model, th0)
        Y = feature_ffts(state, model, s2, np.arange(k_max + 1))  # (F, B, K), F = 1 + nd
        B = Y.shape[1]
        c3 = 4 * math.pi**2 * L.T
        lam0 = np.concatenate([[1.0], th0[:nd]])
        Yc = np.ascontiguousarray(Y)
        idx = np.ascontiguousarray(dom, dtype=np.int64)
        q, d = products3(Yc, idx, lam0, c3)  # d: (B, n, nd), one column per coefficient
        if self.form == "scaled":
            d = d / _null_variance(k_max, state.window.name, L.M)[None, :, None]
        U = B / (B - 1)
        # U-statistic over block pairs: each block weighted by conj(dbar - d_b / B)
        wts = U * np.conj(d.mean(axis=0)[None] - d / B)
        K = contract3(Yc, idx, np.ascontiguousarray(wts), c3)  # (nd, F, F, F)

        def mean(theta):
            th = np.asarray(theta, dtype=float)
            lam = np.concatenate([np.ones((*th.shape[:-1], 1)), th[..., :nd]], axis=-1)
            l3 = lam[..., :, None, None] * lam[..., None, :, None] * lam[..., None, None, :]
            return np.tensordot(l3, K, axes=([-3, -2, -1], [1, 2, 3]))

        u = u_pseudovalues(d, q)
        return Moments(
            component=self.name,
            labels=tuple(f"J3 d/d{model.param_names[i]}" for i in range(nd)),
            mean=mean,
            influence=u - u.mean(axis=0),
            info={"pairs": int(dom.shape[0]), "band_rad_s": float(k_max * L.d_omega),
                  "form": self.form},
        )  # fmt: skip
