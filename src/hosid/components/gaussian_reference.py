r"""The Gaussian part of the block trispectrum, exact for the window's leakage (J4B).

For a Gaussian force the tapered block transforms :math:`X_r(k)` are jointly Gaussian,
and by Isserlis' theorem the mean of the block trispectrum of the triple
:math:`t = (k_1, k_2, k_3)`, :math:`k_4 = k_1 + k_2 + k_3`, on signed bins
(:math:`X(-k) = X^*(k)`) is

.. math:: c_8\,G_t = C(k_1, -k_2)\,C(k_3, k_4) + C(k_1, -k_3)\,C(k_2, k_4)
    + C(k_1, k_4)\,C(k_2, -k_3), \qquad C(a, b) = E\,X_r(a)X_r^*(b),

whatever the spectrum's shape within the window's bandwidth.  The bin-value form of
eq 63, :math:`s_as_b\Delta_T(\omega_a + \omega_b)`, is this with
:math:`C(a, b) \approx 2\pi Tk_2\sqrt{s_as_b}\,\rho(a - b)`, which holds where the
spectrum is flat over the window's main lobe: for a second-order peak one bin wide
(half-power half-width) under a Hann window it is off by -17 % to +23 %, at five bins by
at most 5 %.  Each covariance's offset :math:`a - b` is :math:`\mp(k_i + k_j)` for one
pairing; only offsets within the window's reach enter (the bins' correlation
:math:`\rho(d)` of a flat spectrum beyond it is zero: :math:`|d| \le 2` for Hann; for a
second-order peak half a bin wide the exact correlation at offset 3 is at most 1.2 %).

The record's own covariances give :math:`C`: with the inferred force
:math:`X_r = \sum_i\lambda_iY_{ir}` affine in the coefficients,
:math:`\hat C(a, b) = \lambda^\top\bar P(a, b)\lambda`,
:math:`P_r(a, b)_{ij} = Y_{ir}(a)Y^*_{jr}(b)`, and a weighted sum of the :math:`G_t` is
a quartic form in :math:`\lambda`.  Products of two covariances are formed over distinct
blocks (a U-statistic, unbiased for the product of the means; the blocks do not overlap).
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

__all__ = ["GaussianReference"]


class GaussianReference:
    r"""The exact Gaussian reference of a trispectral domain (module docstring).

    Parameters
    ----------
    Ys : ndarray
        ``(F, B, 2K + 1)`` block transforms of the force's features on signed bins
        ``-K..K``.
    dom : ndarray
        ``(n, 4)`` signed triples ``k1, k2, k3, k4``, every entry within ``[-K, K]``.
    reach : int
        Largest offset :math:`|a - b|` of a covariance that enters.
    c8 : float
        The trispectrum's normalisation :math:`8\pi^3T`.
    """

    def __init__(self, Ys: np.ndarray, dom: np.ndarray, reach: int, c8: float):
        F, B, n_bins = Ys.shape
        K = (n_bins - 1) // 2
        D = int(reach)
        self.B, self.F, self.c8 = B, F, float(c8)
        a = np.repeat(np.arange(-K, K + 1), 2 * D + 1)
        b = a - np.tile(np.arange(-D, D + 1), 2 * K + 1)
        ok = np.abs(b) <= K
        a, b = a[ok], b[ok]
        pid = np.full((2 * K + 1, 2 * D + 1), -1)
        pid[a + K, a - b + D] = np.arange(a.size)
        # per-block covariances of every pair (B, n_p, F, F)
        self.P = np.einsum("ibu,jbu->buij", Ys[:, :, a + K], np.conj(Ys[:, :, b + K]))
        self.P_mean = self.P.mean(axis=0)
        k1, k2, k3, k4 = dom.T
        terms = (((k1, -k2), (k3, k4)), ((k1, -k3), (k2, k4)), ((k1, k4), (k2, -k3)))
        rows, us, vs = [], [], []
        for (a1, b1), (a2, b2) in terms:
            off = a1 - b1
            keep = np.abs(off) <= D
            rows.append(np.nonzero(keep)[0])
            us.append(pid[a1[keep] + K, off[keep] + D])
            vs.append(pid[a2[keep] + K, a2[keep] - b2[keep] + D])
        self.rows = np.concatenate(rows)  # the triple of each (pairing, triple) entry
        self.u, self.v = np.concatenate(us), np.concatenate(vs)
        self.n_t, self.n_p = dom.shape[0], a.size
        # the (pairing, triple) entries summed into the dense (u, v) weights
        self._map = sparse.csr_matrix(
            (np.ones(self.rows.size), (self.u * self.n_p + self.v, np.arange(self.rows.size))),
            shape=(self.n_p**2, self.rows.size),
        )

    def _weights(self, e: np.ndarray) -> np.ndarray:
        """``(n_p, n_p)`` weights of the covariance pairs for the triple weights ``e``
        (``(n,)``, complex): the pairings of every triple summed.
        """
        return (self._map @ e[self.rows]).reshape(self.n_p, self.n_p)

    def values(self, lam: np.ndarray) -> np.ndarray:
        r""":math:`G_t` at the coefficients ``lam`` (``(F,)``), from the covariances'
        block means, ``(n,)`` complex.
        """
        c = np.einsum("i,uij,j->u", lam, self.P_mean, lam)
        g = c[self.u] * c[self.v]
        re = np.bincount(self.rows, g.real, self.n_t)
        return (re + 1j * np.bincount(self.rows, g.imag, self.n_t)) / self.c8

    def statistic(self, lam: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r"""The statistic :math:`\mathrm{Re}\sum_t\bar a_{tj}G_t` over three distinct
        blocks (a block's weight never meets its own covariances, and the two covariances
        of a product come from different blocks; module docstring) for per-block triple
        weights ``a`` (``(B, n, J)``, complex): as a quartic form in :math:`\lambda`,
        ``(J, F, F, F, F)``, and its delete-one-block jackknife pseudo-values at the
        coefficients ``lam``, ``(B, J)`` (:math:`\psi_b = BU - (B-1)U_{(-b)}`, the
        triples without block :math:`b` counted by inclusion and exclusion, as
        :func:`hosid.components.base.u_pseudovalues` does for pairs).
        """
        B, F, f2, n_p, J = self.B, self.F, self.F * self.F, self.n_p, a.shape[2]
        P = self.P.reshape(B, n_p, f2)
        S = P.sum(axis=0)
        c = np.einsum("i,buij,j->bu", lam, self.P, lam)  # (B, n_p)
        Cs, CC = c.sum(axis=0), c.T @ c
        quartic = np.empty((J, f2, f2))
        psi = np.empty((B, J))
        for j in range(J):
            EA = self._weights(a[:, :, j].sum(axis=0))
            full = S.T @ EA @ S - np.einsum("bui,buk->ik", P, np.matmul(EA, P))
            cross, own = np.zeros((f2, f2), complex), np.zeros((f2, f2), complex)
            EP_sum = np.zeros((n_p, f2), complex)
            # per block b as the weight: E_b and its products with the covariances
            RE, Ec, cE, ER = (np.empty((B, n_p), complex) for _ in range(4))
            EbCC, EbCs = np.empty(B, complex), np.empty((B, n_p), complex)
            for b in range(B):
                Eb = self._weights(a[b, :, j])
                EP = Eb @ P[b]
                EP_sum += EP
                cross += P[b].T @ (Eb @ S)
                own += P[b].T @ EP
                R = Cs - c[b]
                Ec[b], cE[b], ER[b] = Eb @ c[b], c[b] @ Eb, Eb @ R
                EbCC[b], EbCs[b] = np.vdot(Eb.conj(), CC), Eb @ Cs
                RE[b] = R @ Eb
            cross += S.T @ EP_sum
            quartic[j] = (full - cross + 2.0 * own).real
            R = Cs[None] - c
            as_weight = np.einsum("bu,bu->b", R, ER) - (EbCC - np.einsum("bu,bu->b", c, Ec))
            first = np.einsum("bu,bu->b", c, R @ EA.T - EbCs + Ec)
            first -= np.einsum("bu,bu->b", c, Ec.sum(axis=0)[None] - Ec)
            second = np.einsum("bu,bu->b", R @ EA - RE, c)
            second -= np.einsum("bv,bv->b", cE.sum(axis=0)[None] - cE, c)
            total = as_weight.sum()
            U = total / (B * (B - 1) * (B - 2))
            U_loo = (total - as_weight - first - second) / ((B - 1) * (B - 2) * (B - 3))
            psi[:, j] = (B * U - (B - 1) * U_loo).real
        norm = self.c8 * B * (B - 1) * (B - 2)
        return quartic.reshape(J, F, F, F, F) / norm, psi / self.c8
