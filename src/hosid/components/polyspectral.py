r"""J4A and J4B: the trispectrum of the inferred force (paper eqs 22, 34-38, 57-63).

Per block :math:`r` and triple :math:`t = (k_1, k_2, k_3)` of the trispectral domain
(:mod:`hosid.spectra.domains`, eq 39), with :math:`k_4 = k_1 + k_2 + k_3`,

.. math:: q_{rt}(\theta) = \frac{X_r(\omega_1)X_r(\omega_2)X_r(\omega_3)X_r^*(\omega_4)}
    {8\pi^3T}, \qquad \hat V^b_t = \bar q_t \quad (57\text{-}58),

and for a Gaussian force of spectrum :math:`s(\omega)` (eq 36 with eq 63 corrected)

.. math:: E\,\hat V^b_t = G_t = s_1s_3\Delta_T(\omega_1+\omega_2)
    + s_3s_2\Delta_T(\omega_1+\omega_3) + s_1s_2\Delta_T(\omega_2+\omega_3),

with :math:`s = S_0L(\omega)` for J4A (eqs 34, 59) and the record's own
:math:`s = \hat V^a/k_2` for J4B (eqs 37-38, 62-63; no :math:`S_0`;
``reference="bins"``).  J4B's default (``reference="exact"``) is the Gaussian part
itself, exact for the window's leakage, from the blocks' own covariances between bins
over distinct blocks (:mod:`hosid.components.gaussian_reference`): with the bin values
and the mean weights the equations sat 1.6 standard errors below zero at the truth
(24 paper records of 1000 s: z -1.62, sd 0.56; exact: -0.08, sd 0.63, the jackknife
overstating its variance), and the J4B cost's estimates of 20 paper records of 2000 s
had an rms error of 1.74 in a1 and 0.155 in n1 (exact: 1.46 and 0.131).  J4 is
:math:`\sum_t w_t|\hat V^b_t - G_t|^2`; as for J2 (:mod:`hosid.components.spectral`) its
gradient with frozen weights :math:`d_{tj} = w_t\,\partial(q_t - G_t)/\partial\theta_j`
(:math:`w_t = 1` as printed, or the inverse Gaussian variance of the ordinate,
``form="scaled"``) gives the estimating equations

.. math:: m_j(\theta) = \mathrm{Re}\sum_t d^*_{tj}\,\big(\bar q_t(\theta) - G_t(\theta)\big),

with block-diagonal pairs removed (a U-statistic; same-block weights and residuals
correlate by about one standard error otherwise; the covariance comes from the
jackknife pseudo-values, :func:`hosid.components.base.u_pseudovalues`).  As in the paper's
protocol, J4 gives equations only along the damping coefficients and :math:`S_0` (J4A):
the stiffness comes from the moments and J2.  The force is evaluated at the whole
parameter vector, so the stiffness's uncertainty reaches the damping.

Since :math:`X = \sum_i\lambda_iY_i` is affine in the coefficients, every
:math:`\bar q_t` is a quartic form :math:`\lambda^{\otimes4}\cdot T_t`; the sum over the
domain is contracted once into a :math:`F^4` tensor per equation (compiled kernels of
:mod:`hosid.components._kernels`, one pass over blocks and triples), so evaluating
the equations never touches the blocks again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..model.model import Model
from ..spectra.domains import trispectral_domain
from ..spectra.windows import get_window
from ..state import RecordState
from ._kernels import contract, products
from .base import Moments, feature_ffts, restoration, u_pseudovalues
from .bin_reference import BinReference
from .excitation import Excitation
from .gaussian_reference import GaussianReference
from .spectral import default_band

__all__ = ["J4", "null_variance"]

#: Default upper edge of the trispectral band, in units of the natural frequency (the
#: paper's 8 rad/s at 5 rad/s).
BAND_FACTOR = 1.6


def _matchings(items):
    if not items:
        yield ()
        return
    a = items[0]
    for i in range(1, len(items)):
        rest = items[1:i] + items[i + 1 :]
        for m in _matchings(rest):
            yield ((a, items[i]), *m)


_M8 = np.array(list(_matchings(tuple(range(8)))))  # the 105 pairings of 8 ordinates


def null_variance(k: np.ndarray, rho) -> np.ndarray:
    r"""Per-block variance of :math:`z_1z_2z_3z_4^*` for a Gaussian white force
    (Isserlis over the 105 pairings; :math:`E[z(a)z(b)] = \rho(a+b)` on signed bins).
    """
    s = np.stack([k[:, 0], k[:, 1], k[:, 2], -k[:, 3], -k[:, 0], -k[:, 1], -k[:, 2], k[:, 3]], 1)
    total = np.zeros(k.shape[0])
    for m in _M8:
        term = np.ones(k.shape[0])
        for a, b in m:
            term = term * rho(s[:, a] + s[:, b])
        total += term
    g = rho(k[:, 0] + k[:, 1]) ** 2 + rho(k[:, 0] + k[:, 2]) ** 2 + rho(k[:, 1] + k[:, 2]) ** 2
    return np.maximum(total - g**2, 1e-12)


@lru_cache(maxsize=16)
def _null_variance(k_max: int, domain: str, window: str, m: int) -> np.ndarray:
    win = get_window(window)
    return null_variance(trispectral_domain(k_max, domain), lambda k: win.rho(k, m))


@dataclass(frozen=True)
class J4:
    """The trispectral component (module docstring): ``kind`` ``"A"`` or ``"B"``;
    ``reference`` ``"exact"`` or ``"bins"``, J4B's Gaussian part (J4A's is the model's, in
    bin values).
    """

    kind: str = "A"
    form: str = "scaled"
    domain: str = "principal"
    omega_max: float | None = None
    reference: str = "exact"

    @property
    def name(self) -> str:
        """``"J4A"`` or ``"J4B"``."""
        return f"J4{self.kind}"

    def prepare(self, state: RecordState, model: Model, pilot: np.ndarray) -> Moments:
        """Domain, frozen weights and contracted tensors (module docstring)."""
        if self.kind not in ("A", "B") or self.form not in ("scaled", "printed"):
            raise ValueError(f"unknown J4 kind {self.kind!r} or form {self.form!r}")
        if self.reference not in ("exact", "bins"):
            raise ValueError(f"unknown J4 reference {self.reference!r}")
        L, sc = state.layout, state.scales
        w_max = self.omega_max or min(BAND_FACTOR * sc.omega_n, default_band(state)[1])
        k_max = math.floor(w_max / L.d_omega + 1e-9)
        if k_max < 3:
            raise ValueError(f"the trispectral band up to {w_max:.3g} rad/s holds < 3 bins")
        dom = trispectral_domain(k_max, self.domain)
        th0 = np.asarray(pilot, dtype=float)
        nd = model.n_drift
        s2, _ = restoration(state, model, th0)
        Y = feature_ffts(state, model, s2, np.arange(k_max + 1))  # (F, B, K), F = 1 + nd
        Ys = np.ascontiguousarray(np.concatenate([np.conj(Y[:, :, :0:-1]), Y], axis=2))
        idx = np.ascontiguousarray(dom + k_max, dtype=np.int64)  # signed bins -K..K
        B = Y.shape[1]
        c8 = 8 * math.pi**3 * L.T
        lam0 = np.concatenate([[1.0], th0[:nd]])
        q, dq = products(Ys, idx, lam0, c8)  # (B, n_t), (B, n_t, F - 1)
        exc = Excitation(model, th0, sc.sigma_v, sc.sigma_x)
        if self.kind == "B" and self.reference == "exact":
            ref = _Exact(state, Ys, dom, c8, nd)
        else:
            ref = BinReference(self.kind, state, exc, dom, Y, nd)

        # directions and frozen per-block weights d_tbj
        dirs = [i for i, t in enumerate(model.drift_terms) if t.variable == "v"]
        if self.kind == "A":
            dirs += [exc.i_S0, *exc.shape_indices]
        d = self._directions(dirs, th0, nd, dq, ref.values)
        if self.form == "scaled":
            d = d / _null_variance(k_max, self.domain, state.window.name, L.M)[None, :, None]
        # U-statistic over block pairs: each block weighted by conj(dbar - d_b / B)
        wts = B / (B - 1) * np.conj(d.mean(axis=0)[None] - d / B)  # (B, n_t, J)
        K_all = contract(Ys, idx, np.ascontiguousarray(wts), c8)
        # jackknife pseudo-values: the projection alone (each block's residual times the
        # other blocks' mean weights) drops the degenerate part, which off the planes
        # w_i + w_j = 0 is not small (E[-2 l] of the 3 J4A equations at the truth: 4.8)
        u, K_all, rest = ref.split(d, q, wts.mean(axis=0), th0, K_all)

        def mean(theta):
            th = np.asarray(theta, dtype=float)
            lam = np.concatenate([np.ones((*th.shape[:-1], 1)), th[..., :nd]], axis=-1)
            l2 = lam[..., :, None] * lam[..., None, :]
            l4 = l2[..., :, :, None, None] * l2[..., None, None, :, :]
            main = np.tensordot(l4, K_all, axes=([-4, -3, -2, -1], [1, 2, 3, 4]))
            return main if rest is None else main - rest(th)

        labels = tuple(f"{self.name} d/d{model.param_names[i]}" for i in dirs)
        return Moments(
            component=self.name,
            labels=labels,
            mean=mean,
            influence=u - u.mean(axis=0),
            info={
                "triples": int(dom.shape[0]),
                "band_rad_s": float(k_max * L.d_omega),
                "domain": self.domain,
                "form": self.form,
                "directions": "damping and S0 (J4A) / damping (J4B)",
            },
        )

    def _directions(self, dirs, th0, nd, dq, gaussian) -> np.ndarray:
        r"""The frozen per-block weights :math:`d_{tbj}` along the directions ``dirs``:
        a damping coefficient's product derivative ``dq`` less (J4B) the derivative of
        the Gaussian term ``gaussian(theta)``, the level's and shape's minus that
        derivative (central differences at the pilot ``th0``).
        """
        B, n_t = dq.shape[:2]
        d = np.empty((B, n_t, len(dirs)), dtype=complex)
        for a, i in enumerate(dirs):
            dG = 0.0
            if i >= nd or self.kind == "B":
                h = 1e-6 * (abs(th0[i]) if i >= nd else max(abs(th0[i]), 1e-3))
                tp, tm = th0.copy(), th0.copy()
                tp[i] += h
                tm[i] -= h
                dG = (gaussian(tp) - gaussian(tm)) / (2 * h)
            d[:, :, a] = (dq[:, :, i] - dG) if i < nd else -dG
        return d


class _Exact:
    """J4B's exact Gaussian part (:class:`~hosid.components.gaussian_reference.GaussianReference`)
    at the parameters, with :class:`~hosid.components.bin_reference.BinReference`'s
    ``values`` and ``split``: its products over distinct blocks are in the quartic tensor.
    """

    def __init__(self, state: RecordState, Ys: np.ndarray, dom: np.ndarray, c8: float, nd: int):
        L = state.layout
        reach = max(d for d in range(9) if d == 0 or state.window.rho(d, L.M) > 1e-8)
        self.g, self.nd = GaussianReference(Ys, dom, reach, c8), nd

    def values(self, theta) -> np.ndarray:
        return self.g.values(np.concatenate([[1.0], np.asarray(theta, float)[: self.nd]]))

    def split(self, d, q, e, th0, K_all):
        lam0 = np.concatenate([[1.0], np.asarray(th0, float)[: self.nd]])
        quartic, psi = self.g.statistic(lam0, np.conj(d))
        return u_pseudovalues(d, q) - psi, K_all - quartic, None
