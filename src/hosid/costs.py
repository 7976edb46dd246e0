r"""Cost functions J2, J4A, J4B (paper eqs 21/50, 34/59, 38/62-63) and well-scaled forms.

Every cost takes ``theta`` of shape ``(..., 5)`` holding
``(a1, n1, a2, n2, S0)`` and returns an array of shape ``theta.shape[:-1]``, so
that grids, optimizers and emcee's ``vectorize=True`` share one code path.

Notation: :math:`X_r(\omega;\lambda) = \sum_j \lambda_j Y_{jr}(\omega)` is the
inferred force of block :math:`r` (eq 45),

.. math::

    \hat V^a(\omega) = \frac{1}{N}\sum_r \frac{|X_r(\omega)|^2}{2\pi T}, \qquad
    \hat V^b(\omega_1,\omega_2,\omega_3) = \frac{1}{N}\sum_r
        \frac{X_r(\omega_1)X_r(\omega_2)X_r(\omega_3)X_r^*(\omega_1+\omega_2+\omega_3)}{8\pi^3 T}

(eqs 47, 57-58 with the :math:`1/T` applied once).  The literal costs are

.. math::

    J_2 = \sum_\omega (\hat V^a - k_2 S_0)^2 \quad (50), \qquad
    J_4^A = \sum |\hat V^b - S_0^2 \Sigma\Delta_T|^2 \quad (59), \qquad
    J_4^B = \sum |\hat V^c|^2 \quad (62),

with :math:`\Sigma\Delta_T = \Delta_T(\omega_1+\omega_2)+\Delta_T(\omega_1+\omega_3)
+\Delta_T(\omega_2+\omega_3)` and :math:`\hat V^c = \hat V^b - k_2^{-2}[\hat V^a_1
\hat V^a_3\Delta_T(\omega_1+\omega_2) + \hat V^a_3\hat V^a_2\Delta_T(\omega_1+\omega_3)
+ \hat V^a_1\hat V^a_2\Delta_T(\omega_2+\omega_3)]` (eq 63 corrected, cf. eq 36).

The literal costs pull estimates toward a low force level, because the scatter of
a block average grows with its level.  The *well-scaled* forms standardize every
ordinate by its own sampling spread under the model.  With
:math:`z_r(\omega) = X_r(\omega)/\sqrt{2\pi T s(\omega)}`, where
:math:`s = k_2 S_0` (``"A"`` forms) or :math:`s = \hat V^a(\omega)` (``"B"`` forms,
free of :math:`S_0`), the normalized trispectrum
:math:`m = \overline{z_1 z_2 z_3 z_4^*}` has, for a Gaussian white force,
mean :math:`g = \rho(k_1+k_2)^2+\rho(k_1+k_3)^2+\rho(k_2+k_3)^2` and per-block
variance :math:`v` given exactly by Isserlis' theorem with the window's bin
correlation :math:`\rho(k) = \frac{1}{M k_2}\sum_n D_n^2 e^{-2\pi i k n/M}`.
The sampling variance of a block mean also depends on the parameters (a force
with lighter-tailed block products "fits" better), so the squared residuals are
replaced by their unbiased (U-statistic) estimates,
:math:`\widehat{|E h|^2} = (N|\bar h|^2 - \overline{|h|^2})/(N-1)`:

.. math::

    J_2^W = N\sum_\omega \widehat{|E h_\omega|^2},\; h = \frac{|X|^2}{2\pi T k_2 S_0}-1,
    \qquad
    J_4^{W} = N\sum_{\rm domain}\frac{\widehat{|E h_t|^2}}{v_t},\; h = z_1z_2z_3z_4^*-g.

These are *centred*: at the truth their expectation is 0 (not the number of
ordinates), with a spread of order the square root of that number; away from it
they grow like :math:`N` times the squared standardized bias.  They are only
meaningful near a sensible start (far from it the U-statistic rewards dispersed
inferred forces), so the estimators search bounded regions.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from functools import cached_property

import numba
import numpy as np

from .spectra import BlockSpectra, TrispectralDomain, trispectral_domain

__all__ = [
    "COSTS",
    "PARAM_NAMES",
    "CostData",
    "DampingExpansion",
    "evaluate_cost",
    "prepare",
]

PARAM_NAMES = ("a1", "n1", "a2", "n2", "S0")


@numba.njit(cache=True)
def _trispectrum_one(X, pa, pb, ta, tb, out, out2):  # pragma: no cover - compiled
    """Block sums of q_r = X(k1) X(k2) X(k3) X*(k4) and of |q_r|^2 for one force.

    ``X`` is (K, N) with the block index last (contiguous).  Each product is
    split into the pair products A = X(k1) X*(k4) (``pa``) and B = X(k2) X(k3)
    (``pb``), each formed once per distinct pair, so a triple costs one complex
    multiply per block.
    """
    N = X.shape[1]
    na, nb, nt = pa.shape[0], pb.shape[0], ta.shape[0]
    A = np.empty((na, N), dtype=np.complex128)
    B = np.empty((nb, N), dtype=np.complex128)
    for j in range(na):
        for r in range(N):
            A[j, r] = X[pa[j, 0], r] * np.conj(X[pa[j, 1], r])
    for j in range(nb):
        for r in range(N):
            B[j, r] = X[pb[j, 0], r] * X[pb[j, 1], r]
    for t in range(nt):
        a, b = ta[t], tb[t]
        acc = 0.0 + 0.0j
        acc2 = 0.0
        for r in range(N):
            q = A[a, r] * B[b, r]
            acc += q
            acc2 += q.real * q.real + q.imag * q.imag
        out[t] = acc
        out2[t] = acc2


@numba.njit(parallel=True, cache=True)
def _trispectrum(Xt, pa, pb, ta, tb, out, out2):  # pragma: no cover - compiled
    """:func:`_trispectrum_one` for each force of the batch ``Xt`` (P, K, N),
    in parallel over the batch (one parallel region per call: fine-grained
    parallelism inside one force was an order of magnitude slower on a loaded
    2-core machine).
    """
    for p in numba.prange(Xt.shape[0]):
        _trispectrum_one(Xt[p], pa, pb, ta, tb, out[p], out2[p])


def _matchings(items):
    """All perfect matchings of an even-length tuple (105 for 8 items)."""
    if not items:
        yield ()
        return
    a = items[0]
    for i in range(1, len(items)):
        rest = items[1:i] + items[i + 1 :]
        for m in _matchings(rest):
            yield ((a, items[i]), *m)


_M8 = np.array(list(_matchings(tuple(range(8)))))  # (105, 4, 2)


@dataclass(frozen=True)
class CostData:
    """Everything the costs need from a record, prepared once.

    Build with :func:`prepare`.  ``Y`` holds the feature transforms on the signed
    bins ``-k_max .. k_max`` (negative bins are complex conjugates).
    """

    spectra: BlockSpectra
    domain: TrispectralDomain

    @property
    def N(self) -> int:
        """Number of blocks."""
        return self.spectra.n_blocks

    @property
    def T(self) -> float:
        """Block length (s)."""
        return self.spectra.T

    @property
    def k2(self) -> float:
        """Window constant k2 (eq 20)."""
        return self.spectra.window.k2

    @cached_property
    def Ysigned(self) -> np.ndarray:
        """(5, 2 K + 1, N) transforms on signed bins -K..K, block index last."""
        K = self.spectra.k_max
        Yp = self.spectra.Y[:, :, : K + 1]
        Ys = np.concatenate([np.conj(Yp[:, :, :0:-1]), Yp], axis=2)
        return np.ascontiguousarray(Ys.transpose(0, 2, 1))

    @cached_property
    def _band_Y(self) -> np.ndarray:
        return np.ascontiguousarray(self.Ysigned[:, self.band_index, :])

    def _Y_on(self, bins: tuple) -> np.ndarray:
        if bins == tuple(self.band_index):
            return self._band_Y
        return self.Ysigned[:, list(bins), :]

    @cached_property
    def _pairs(self):
        """Distinct pairs (k1, k4) and (k2, k3) of the domain and each triple's pair."""
        idx = self.tri_index
        pa, ta = np.unique(idx[:, [0, 3]], axis=0, return_inverse=True)
        pb, tb = np.unique(idx[:, [1, 2]], axis=0, return_inverse=True)
        return (
            np.ascontiguousarray(pa),
            np.ascontiguousarray(pb),
            np.ascontiguousarray(ta.ravel()),
            np.ascontiguousarray(tb.ravel()),
        )

    @cached_property
    def band_index(self) -> np.ndarray:
        """Positions of the band bins in the signed layout."""
        return self.spectra.band + self.spectra.k_max

    @cached_property
    def tri_index(self) -> np.ndarray:
        """(n, 4) positions of k1, k2, k3, k4 in the signed layout."""
        return np.ascontiguousarray(self.domain.k + self.spectra.k_max).astype(np.int64)

    @cached_property
    def rho(self):
        """Window bin correlation rho(k) as a function of integer k (real, even)."""
        s = self.spectra
        F = np.fft.fft(s.window.samples(s.M) ** 2).real / s.M
        return lambda k: F[np.asarray(k) % s.M] / s.window.k2

    @cached_property
    def null_mean(self) -> np.ndarray:
        """Gaussian mean g of the normalized trispectrum on the domain."""
        k = self.domain.k
        r = self.rho
        return r(k[:, 0] + k[:, 1]) ** 2 + r(k[:, 0] + k[:, 2]) ** 2 + r(k[:, 1] + k[:, 2]) ** 2

    @cached_property
    def null_var(self) -> np.ndarray:
        """Per-block variance v of z1 z2 z3 z4* for a Gaussian white force (Isserlis)."""
        k = self.domain.k
        # signed bins of P = z(k1) z(k2) z(k3) z(-k4) and of conj(P)
        s = np.stack(
            [k[:, 0], k[:, 1], k[:, 2], -k[:, 3], -k[:, 0], -k[:, 1], -k[:, 2], k[:, 3]], 1
        )
        r = self.rho
        total = np.zeros(k.shape[0])
        for m in _M8:
            term = np.ones(k.shape[0])
            for a, b in m:
                term = term * r(s[:, a] + s[:, b])
            total += term
        return np.maximum(total - self.null_mean**2, 1e-12)

    # ------------------------------------------------------------------ spectra
    def inferred_force(self, theta: np.ndarray, bins: np.ndarray | None = None) -> np.ndarray:
        """Eq (45): X_r(omega; lambda) on signed bins, shape (..., 2K+1, N)
        (or on the signed-layout positions ``bins`` only).
        """
        lam = np.asarray(theta, dtype=float)[..., :4, None, None]
        Y = self.Ysigned if bins is None else self._Y_on(tuple(bins))
        X = Y[0] + lam[..., 0, :, :] * Y[1]
        for j in range(1, 4):
            X = X + lam[..., j, :, :] * Y[j + 1]
        return X

    def second_order(self, theta: np.ndarray, X: np.ndarray | None = None) -> np.ndarray:
        """Eq (47)/(51): block-averaged Va on the band, shape (..., K_band)."""
        Xb = (
            self.inferred_force(theta, self.band_index)
            if X is None
            else X[..., self.band_index, :]
        )
        return np.mean(Xb.real**2 + Xb.imag**2, axis=-1) / (2 * np.pi * self.T)

    def band_moments(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r"""Block means of :math:`|X|^2/(2\pi T)` (= Va) and :math:`|X|^4/(2\pi T)^2`
        on the band, each of shape ``(..., K_band)``.
        """
        Xb = self.inferred_force(theta, self.band_index)
        p = (Xb.real**2 + Xb.imag**2) / (2 * np.pi * self.T)
        return p.mean(axis=-1), (p**2).mean(axis=-1)

    def shared_force(self, theta: np.ndarray) -> np.ndarray | None:
        """The inferred force, computed once for costs that need several statistics."""
        return self.inferred_force(theta)

    def fourth_order(
        self, theta: np.ndarray, X: np.ndarray | None = None, second_moment: bool = False
    ):
        """Eq (57)-(58): block-averaged Vb on the domain, shape (..., n_domain).

        With ``second_moment=True`` also the block mean of the squared modulus of
        the per-block products (same scaling squared), for bias corrections.
        """
        X = self.inferred_force(theta) if X is None else X
        batch = X.shape[:-2]
        Xs = np.ascontiguousarray(X.reshape((-1, *X.shape[-2:])))
        out = np.empty((Xs.shape[0], self.domain.size), dtype=complex)
        out2 = np.empty((Xs.shape[0], self.domain.size))
        if Xs.shape[0] == 1:  # no parallel region for a single force
            _trispectrum_one(Xs[0], *self._pairs, out[0], out2[0])
        else:
            _trispectrum(Xs, *self._pairs, out, out2)
        scale = 8 * np.pi**3 * self.T
        vb = (out / (self.N * scale)).reshape((*batch, self.domain.size))
        if not second_moment:
            return vb
        return vb, (out2 / (self.N * scale**2)).reshape((*batch, self.domain.size))

    def _va_signed(self, va: np.ndarray) -> np.ndarray:
        """Map band Va onto the domain's four bins (|k| indexes the band)."""
        kk = np.abs(self.domain.k) - self.spectra.k_min
        return va[..., kk]  # (..., n, 4)


def prepare(spectra: BlockSpectra, domain: str | TrispectralDomain = "principal") -> CostData:
    """Bundle block spectra and a trispectral domain for the costs."""
    if isinstance(domain, str):
        domain = trispectral_domain(spectra, domain)
    return CostData(spectra=spectra, domain=domain)


def _monomials(u: np.ndarray, w: np.ndarray, degree: int) -> np.ndarray:
    """All monomials u^i w^j with i + j <= degree, shape ``(..., (d+1)(d+2)/2)``."""
    return np.stack(
        [u**i * w ** (d - i) for d in range(degree + 1) for i in range(d, -1, -1)], axis=-1
    )


@functools.cache
def _chebyshev_fit():
    """The 9 x 9 Chebyshev grid and the least-squares operators (pinv) per degree."""
    nodes = np.cos(np.pi * (np.arange(9) + 0.5) / 9)
    U, W = np.meshgrid(nodes, nodes, indexing="ij")
    uw = np.column_stack([U.ravel(), W.ravel()])
    return uw, {d: np.linalg.pinv(_monomials(uw[:, 0], uw[:, 1], d)) for d in (2, 4, 8)}


class DampingExpansion:
    r"""The block statistics at fixed stiffness as exact polynomials in the damping.

    With the stiffness held at :math:`(a_2, n_2)` the inferred force (eq 45) is
    affine in the damping, :math:`X_r = F_r + a_1 Y_{1r} + n_1 Y_{2r}`, so every
    block statistic the costs use is a polynomial in :math:`(a_1, n_1)`:
    :math:`V^a` (degree 2), the block mean of :math:`|X|^4` (4), :math:`V^b`
    (eq 57-58, degree 4) and the block mean of :math:`|X_1X_2X_3X_4^*|^2` (8).
    Their coefficients are found once by least squares on a
    :math:`9	imes 9` Chebyshev grid in scaled variables
    :math:`u = a_1/s_a, w = n_1/s_n` (exact up to rounding; checked against the
    direct evaluation at random points on construction), after which a cost
    evaluation is a few small matrix products instead of a pass over all blocks
    and triples.  The object has the interface of :class:`CostData` that the
    costs use; the stiffness entries of ``theta`` are ignored.

    Parameters
    ----------
    data : CostData
    a2, n2 : float
        The stiffness held fixed.
    scale : (s_a, s_n)
        Scales of :math:`a_1` and :math:`n_1` over which the fit is made (the
        prior box); the polynomials are exact everywhere, the scaling only
        keeps the fit well conditioned.
    rtol : float
        Largest accepted relative error of the check.
    """

    def __init__(self, data: CostData, a2: float, n2: float, scale, *, rtol: float = 1e-7):
        self.data = data
        self.stiffness = (float(a2), float(n2))
        self.scale = tuple(float(abs(v)) or 1.0 for v in scale)
        uw, fit = _chebyshev_fit()
        stats = self._direct(uw)
        self.coef = {}
        for name, deg in (("va", 2), ("va2", 4), ("vb", 4), ("vb2", 8)):
            self.coef[name] = fit[deg] @ stats[name]
        test = np.random.default_rng(0).uniform(-1.5, 1.5, size=(4, 2))
        direct = self._direct(test)
        for name, deg in (("va", 2), ("va2", 4), ("vb", 4), ("vb2", 8)):
            approx = _monomials(test[:, 0], test[:, 1], deg) @ self.coef[name]
            err = np.max(np.abs(approx - direct[name])) / np.max(np.abs(direct[name]))
            if not err <= rtol:
                raise FloatingPointError(
                    f"damping expansion of {name} is inaccurate (relative error {err:.1e})"
                )

        self._reduce()

    def _reduce(self) -> None:
        r"""Quadratic forms of the costs' sums over ordinates (module doc of the class).

        With :math:`V^b_t = \phi_4^{\mathsf T} C_t` (:math:`\phi_d` the monomials up to
        degree :math:`d`) and weights :math:`w_t`,
        :math:`\sum_t w_t |V^b_t|^2 = \phi_4^{\mathsf T} Q \phi_4` with
        :math:`Q = \sum_t w_t \operatorname{Re}(\bar C_t C_t^{\mathsf T})`, so the
        literal and A-form costs need no per-ordinate work at all.
        """
        d = self.data
        c = self.coef
        self._vb_split = (np.ascontiguousarray(c["vb"].real), np.ascontiguousarray(c["vb"].imag))
        Cr, Ci = self._vb_split
        Ca = c["va"]
        w = 1.0 / d.null_var
        g = d.null_mean
        gauss = d.domain.gauss
        self._red = {
            "Q2": Ca @ Ca.T,
            "sa": Ca.sum(axis=1),
            "sa2": c["va2"].sum(axis=1),
            "K": Ca.shape[1],
            "Q4w": (Cr * w) @ Cr.T + (Ci * w) @ Ci.T,
            "s8w": c["vb2"] @ w,
            "r4w": Cr @ (w * g),
            "Gw": float(np.sum(w * g**2)),
            "Q4": Cr @ Cr.T + Ci @ Ci.T,
            "r4g": Cr @ gauss,
            "G2": float(np.sum(gauss**2)),
        }

    def fast_cost(self, name: str, theta) -> np.ndarray | None:
        """``J2``, ``J4A``, ``J2W``, ``J4AW`` from the quadratic forms; None for others."""
        th = _theta(theta)
        r = self._red
        N, S0 = self.data.N, th[..., 4]
        if name in ("J2", "J2W"):
            p2 = self._phi(th, 2)
            sva2 = np.einsum("...i,ij,...j->...", p2, r["Q2"], p2)  # sum Va^2
            sva = p2 @ r["sa"]
            s = self.data.k2 * S0
            if name == "J2":  # eq (50)
                return sva2 - 2 * s * sva + r["K"] * s**2
            sva4 = self._phi(th, 4) @ r["sa2"]  # sum of the block means of p^2
            return (
                N
                / (N - 1)
                * (N * sva2 / s**2 - 2 * (N - 1) * sva / s + (N - 1) * r["K"] - sva4 / s**2)
            )
        if name in ("J4A", "J4AW"):
            p4 = self._phi(th, 4)
            if name == "J4A":  # eq (59)
                q = np.einsum("...i,ij,...j->...", p4, r["Q4"], p4)
                return q - 2 * S0**2 * (p4 @ r["r4g"]) + S0**4 * r["G2"]
            T = self.data.T
            c = 8 * np.pi**3 * T / ((2 * np.pi * T) ** 2 * (self.data.k2 * S0) ** 2)
            q = np.einsum("...i,ij,...j->...", p4, r["Q4w"], p4)
            s8 = self._phi(th, 8) @ r["s8w"]
            return (
                N
                / (N - 1)
                * (
                    N * c**2 * q
                    - c**2 * s8
                    - 2 * (N - 1) * c * (p4 @ r["r4w"])
                    + (N - 1) * r["Gw"]
                )
            )
        return None

    def _theta_of(self, uw: np.ndarray) -> np.ndarray:
        th = np.empty((uw.shape[0], 5))
        th[:, 0] = uw[:, 0] * self.scale[0]
        th[:, 1] = uw[:, 1] * self.scale[1]
        th[:, 2:4] = self.stiffness
        th[:, 4] = 1.0
        return th

    def _direct(self, uw: np.ndarray) -> dict:
        th = self._theta_of(uw)
        d = self.data
        va, va2 = d.band_moments(th)
        vb, vb2 = d.fourth_order(th, second_moment=True)
        return {"va": va, "va2": va2, "vb": vb, "vb2": vb2}

    def __getattr__(self, name):
        # N, T, k2, domain, null_mean, null_var, _va_signed, spectra, ...
        return getattr(self.data, name)

    def _phi(self, theta: np.ndarray, degree: int) -> np.ndarray:
        th = np.asarray(theta, dtype=float)
        return _monomials(th[..., 0] / self.scale[0], th[..., 1] / self.scale[1], degree)

    def shared_force(self, theta: np.ndarray) -> None:
        """Not needed: the statistics come from the polynomials."""
        return None

    def second_order(self, theta: np.ndarray, X=None) -> np.ndarray:
        """Va on the band (eq 47), shape ``(..., K_band)``."""
        return self._phi(theta, 2) @ self.coef["va"]

    def band_moments(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """As :meth:`CostData.band_moments`."""
        return self.second_order(theta), self._phi(theta, 4) @ self.coef["va2"]

    def fourth_order(self, theta: np.ndarray, X=None, second_moment: bool = False):
        """As :meth:`CostData.fourth_order`."""
        p4 = self._phi(theta, 4)
        vb = p4 @ self._vb_split[0] + 1j * (p4 @ self._vb_split[1])
        if not second_moment:
            return vb
        return vb, self._phi(theta, 8) @ self.coef["vb2"]


def _theta(theta) -> np.ndarray:
    th = np.asarray(theta, dtype=float)
    if th.shape[-1] != 5:
        raise ValueError(f"theta must have shape (..., 5) = (a1, n1, a2, n2, S0); got {th.shape}")
    return th


# ---------------------------------------------------------------------- literal costs
def J2(theta, data: CostData) -> np.ndarray:
    """Eq (50): sum over the band of (Va - k2 S0)^2."""
    th = _theta(theta)
    va = data.second_order(th)
    return np.sum((va - data.k2 * th[..., 4:5]) ** 2, axis=-1)


def J4A(theta, data: CostData) -> np.ndarray:
    """Eq (34)/(59): sum over the domain of |Vb - S0^2 (sum of Delta_T)|^2."""
    th = _theta(theta)
    vb = data.fourth_order(th)
    wb = th[..., 4:5] ** 2 * data.domain.gauss
    return np.sum(np.abs(vb - wb) ** 2, axis=-1)


def J4B(theta, data: CostData) -> np.ndarray:
    """Eq (62)-(63): sum of |Vc|^2, Gaussian terms built from Va / k2^2 (no S0)."""
    th = _theta(theta)
    X = data.shared_force(th)
    va = data._va_signed(data.second_order(th, X))
    vb = data.fourth_order(th, X)
    d = data.domain.delta
    g = (
        va[..., 0] * va[..., 2] * d[:, 0]
        + va[..., 2] * va[..., 1] * d[:, 1]
        + va[..., 0] * va[..., 1] * d[:, 2]
    )
    return np.sum(np.abs(vb - g / data.k2**2) ** 2, axis=-1)


# ---------------------------------------------------------------------- well-scaled costs
def _unbiased_sq(mean, mean_sq, N):
    r"""Unbiased estimate of :math:`|E h|^2` from the block mean of h and of |h|^2:
    :math:`(N|\bar h|^2 - \overline{|h|^2})/(N-1)`.  Removing the :math:`r = s`
    terms removes the sampling variance that otherwise rewards parameters whose
    inferred force is less variable (the pull toward low force levels).
    """
    return (N * mean - mean_sq) / (N - 1)


def J2W(theta, data: CostData) -> np.ndarray:
    r"""Well-scaled J2: :math:`N\sum_\omega \widehat{|E h|^2}` with
    :math:`h_r = |X_r|^2 / (2\pi T k_2 S_0) - 1`, each ordinate of unit variance.
    """
    th = _theta(theta)
    va, va2 = data.band_moments(th)
    s = data.k2 * th[..., 4:5]
    m = va / s - 1.0  # block mean of h = p - 1, p = |X|^2 / (2 pi T k2 S0)
    m2 = va2 / s**2 - 2.0 * va / s + 1.0  # block mean of h^2
    return data.N * np.sum(_unbiased_sq(m**2, m2, data.N), axis=-1)


def _tri_standardized(th, data: CostData, own_level: bool) -> np.ndarray:
    X = data.shared_force(th)
    vb, vb2 = data.fourth_order(th, X, second_moment=True)
    if own_level:
        s = data._va_signed(data.second_order(th, X))  # (..., n, 4)
        norm = np.sqrt(np.prod(s, axis=-1))
    else:
        norm = (data.k2 * th[..., 4:5]) ** 2
    # m = mean z1 z2 z3 z4*, z = X / sqrt(2 pi T s); h = z1 z2 z3 z4* - g
    c = (8 * np.pi**3 * data.T) / ((2 * np.pi * data.T) ** 2 * norm)
    g = data.null_mean
    m = c * vb
    mean_abs2 = np.abs(m - g) ** 2
    mean_sq = c**2 * vb2 - 2 * g * m.real + g**2  # block mean of |h|^2
    return data.N * np.sum(_unbiased_sq(mean_abs2, mean_sq, data.N) / data.null_var, axis=-1)


def J4AW(theta, data: CostData) -> np.ndarray:
    """Well-scaled J4A: trispectrum normalized by the model level k2 S0, each
    ordinate standardized by its Gaussian sampling variance, variance-bias removed.
    """
    return _tri_standardized(_theta(theta), data, own_level=False)


def J4BW(theta, data: CostData) -> np.ndarray:
    """Well-scaled J4B: as :func:`J4AW` but normalized by the inferred force's own
    Va (free of S0).
    """
    return _tri_standardized(_theta(theta), data, own_level=True)


COSTS = {"J2": J2, "J4A": J4A, "J4B": J4B, "J2W": J2W, "J4AW": J4AW, "J4BW": J4BW}


def evaluate_cost(name: str, theta, data: CostData) -> np.ndarray:
    """Evaluate a cost by name (one of :data:`COSTS`)."""
    try:
        f = COSTS[name]
    except KeyError:
        raise ValueError(f"unknown cost {name!r}: choose from {sorted(COSTS)}") from None
    return f(theta, data)
